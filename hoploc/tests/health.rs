//! The anchor health check end to end: room10's testbed (anchors and agent as firmware in
//! simavr, built by `cargo fw`, which ./test.sh runs first; the host sink) with an anchor that
//! stands elsewhere than its config says, its sink log replayed as `hoploc replay` does.

use hoploc::firmware;
use hoploc::health::HealthEvent;
use hoploc::replay::Replay;
use hoploc::scenario::{self, Scenario};
use hoploc::testbed::{RunConfig, Testbed};
use loc_core::Point;

/// room10 as shipped (its medium: fading σ 3 dB per link and channel, shadowing σ 2 dB) with a
/// fifth anchor in the middle (and the slot five anchors need), the agent at two stops of 6 s; anchor 3 configured at (10, 10)
/// and standing at `anchor_3`.
fn room10_with_a_centre_anchor(anchor_3: [f64; 2]) -> Scenario {
    let mut s = Scenario::load(&scenario::resolve("room10")).unwrap();
    let mut centre = s.anchors[0];
    centre.position = [5.0, 5.0];
    s.anchors.push(centre);
    // Five anchors need a slot a little longer than room10's four.
    s.timing.slot_ms = s.timing.slot_ms.max(loc_proto::schedule::min_slot_ms(5));
    assert_eq!(s.anchors[2].position, [10.0, 10.0]);
    s.anchors[2].true_position = Some(anchor_3);
    s.agent.path.truncate(2);
    for stop in &mut s.agent.path {
        stop.dwell_s = 6.0;
    }
    s
}

/// Runs `s` to its end and replays the sink's log.
fn replay(s: &Scenario) -> Replay {
    let dir = firmware::default_dir();
    firmware::ensure_built(&dir).unwrap();
    let mut tb = Testbed::new(s, &dir, &RunConfig::default()).unwrap();
    tb.run_to_end();
    let mut r = Replay::new(None, None);
    for line in tb.sink_log().lines() {
        r.feed(line);
    }
    assert_eq!(r.counts.damaged + r.counts.bad_reports, 0, "{:?}", r.counts);
    r
}

#[test]
fn a_misplaced_anchor_is_named_from_the_sink_log() {
    // Anchor 3 stands at (6, 6): the radio medium places it there, its config (and so every
    // beacon and report) says (10, 10).
    let r = replay(&room10_with_a_centre_anchor([6.0, 6.0]));
    let flags: Vec<_> = r
        .health_notes
        .iter()
        .filter_map(|n| match n.event {
            HealthEvent::Flagged(f) => Some((n.report, f)),
            HealthEvent::Cleared { .. } => None,
        })
        .collect();
    // One flag, anchor 3's, at the first verdict after the 20 reports it waits for, and never
    // cleared.
    assert_eq!(flags.len(), 1, "{:?}", r.health_notes);
    assert_eq!(r.health_notes.len(), 1, "{:?}", r.health_notes);
    let (report, f) = flags[0];
    assert!((20..=25).contains(&report), "flagged at report {report}");
    assert_eq!(f.id, 3);
    assert_eq!(f.configured, Point::new(10.0, 10.0));
    let off = f.test.estimate.dist(Point::new(6.0, 6.0));
    assert!(off < 1.5, "{f}: {off:.2} m from where it stands");
    // The verdict over the log's last window, in the summary.
    let s = r.summary();
    assert!(
        s.contains("anchor health: FLAGGED anchor 3 configured at (10.00, 10.00) m"),
        "{s}"
    );
    eprintln!("{}", r.health.assess().summary());
}

#[test]
fn the_same_testbed_with_every_anchor_in_place_raises_no_flag() {
    let r = replay(&room10_with_a_centre_anchor([10.0, 10.0]));
    assert!(r.counts.reports >= 50, "{:?}", r.counts);
    assert!(r.health_notes.is_empty(), "{:?}", r.health_notes);
    let s = r.summary();
    assert!(
        s.contains("anchor health: no anchor flagged (50 reports, 10 links)"),
        "{s}"
    );
}
