//! Every network the node config accepts, end to end in the emulated testbed: 3…8 anchors ×
//! 1…4 channels, each at the thesis' slot lengths (62 ms: experiments 1 and 2's 250 ms channel
//! phases with 4 anchors; 25 ms: experiment 3's periods) and at the shortest slot the config
//! takes for that many anchors (`loc_proto::schedule::min_slot_ms`), with the real anchor,
//! agent and sink firmware in simavr (built by `cargo fw`, which ./test.sh runs first).
//!
//! Each run must give a fix per superframe once the network has settled, every report with its
//! next sequence number, every beacon and report delivered with no collision, and fixes where
//! the agent stands: the agent's report fits one packet in every configuration (where the relay
//! matrix does not, a window of its rows, the next one each superframe).
//!
//! `cargo test -p hoploc --test configurations -- --nocapture` prints a line per run. To look at
//! one case: `HOPLOC_ANCHORS=6 HOPLOC_SLOTS=17,25` (comma-separated ms) narrow the runs, and
//! `HOPLOC_DEBUG=1` prints every sink line, the traffic and every node's UART lines.

use hoploc::firmware;
use hoploc::scenario::Scenario;
use hoploc::testbed::{self, RunConfig, SinkSource, Testbed};
use loc_proto::msg::Report;
use loc_proto::provision::PROVISION_WINDOW_MS;
use loc_proto::schedule::min_slot_ms;
use loc_proto::sink_line::{Estimator, SinkLine};

/// Anchor positions in a 10 m × 10 m room, in id order: the corners, then the sides' middles.
const ANCHORS: [[f64; 2]; 8] = [
    [0.0, 0.0],
    [10.0, 0.0],
    [10.0, 10.0],
    [0.0, 10.0],
    [5.0, 0.0],
    [10.0, 5.0],
    [5.0, 10.0],
    [0.0, 5.0],
];
/// Anchor channels, in hop order (the sink stays on channel 3).
const CHANNELS: [u8; 4] = [1, 12, 6, 16];
/// Where the agent stands, m.
const AGENT: [f64; 2] = [3.6, 6.2];
/// Superframes each run counts fixes over, after the warm-up.
const COUNTED: f64 = 6.0;

/// The scenario of `anchors` × `channels` with `slot_ms` slots, noise-free, as a scenario file
/// (parsed, so the file's checks apply): the warm-up is the provisioning window, the radio
/// bring-up and three superframes to settle.
fn scenario(anchors: usize, channels: usize, slot_ms: u16) -> Scenario {
    let mut text = format!(
        "name = \"{anchors}x{channels}-{slot_ms}ms\"\ndescription = \"configuration test\"\n\
         seed = 1\n[area]\nwidth_m = 10.0\nheight_m = 10.0\n[timing]\nslot_ms = {slot_ms}\n\
         channels = {:?}\nsink_channel = 3\nwarmup_s = 1.0\n[medium]\np0_dbm = -40.0\n\
         alpha = 3.0\nsigma_db = 0.0\nfading_sigma_db = 0.0\nsensitivity_dbm = -92\n",
        &CHANNELS[..channels]
    );
    for p in &ANCHORS[..anchors] {
        text += &format!("[[anchors]]\nposition = [{:?}, {:?}]\n", p[0], p[1]);
    }
    text += &format!(
        "[agent]\npath = [{{ position = [{:?}, {:?}], dwell_s = 1.0 }}]\n",
        AGENT[0], AGENT[1]
    );
    let mut s = Scenario::parse(&text).unwrap_or_else(|e| panic!("{e:?}\n{text}"));
    let sf = testbed::superframe_s(&s).unwrap();
    s.timing.warmup_s = PROVISION_WINDOW_MS as f64 / 1000.0 + 1.5 + 3.0 * sf;
    s.agent.path[0].dwell_s = COUNTED * sf;
    s
}

/// What one run gave.
#[derive(Debug)]
struct Outcome {
    superframe_s: f64,
    fixes: usize,
    worst_m: f64,
}

/// Runs `anchors` × `channels` with `slot_ms` slots and checks it (see the module's doc).
fn run(anchors: usize, channels: usize, slot_ms: u16) -> Outcome {
    let s = scenario(anchors, channels, slot_ms);
    let label = format!("{anchors} anchors × {channels} channels, {slot_ms} ms slots");
    let cfg = RunConfig {
        sink: SinkSource::Firmware,
        ..RunConfig::default()
    };
    let mut tb = Testbed::new(&s, &firmware::default_dir(), &cfg).unwrap();
    let sf = tb.superframe_s();
    let obs = tb.run_to_end();
    if std::env::var_os("HOPLOC_DEBUG").is_some() {
        for o in &obs {
            eprintln!("{:.3} {:?}", o.time_s, o.line);
        }
        eprintln!("{:?}", tb.traffic(0.0));
        for id in 0..tb.network().len() {
            for l in tb.network().lines(id) {
                eprintln!("node {id}: {}", l.text);
            }
        }
    }
    let fixes: Vec<(u16, f64, i16, i16, u8)> = obs
        .iter()
        .filter(|o| o.time_s >= s.timing.warmup_s)
        .filter_map(|o| match o.line {
            SinkLine::Fix {
                estimator: Estimator::Mle,
                seq,
                x,
                y,
                anchors,
                ..
            } if o.reference.is_none() => Some((seq, o.time_s, x, y, anchors)),
            _ => None,
        })
        .collect();
    // A fix per superframe (± the one at each end of the counted stretch), one sequence number
    // after the other, a superframe apart.
    assert!(
        (fixes.len() as f64 - COUNTED).abs() <= 1.0,
        "{label}: {} fixes in {COUNTED} superframes of {sf:.3} s",
        fixes.len()
    );
    for w in fixes.windows(2) {
        assert_eq!(w[1].0, w[0].0.wrapping_add(1), "{label}: a report missing");
        assert!((w[1].1 - w[0].1 - sf).abs() < 0.01, "{label}: {w:?}");
    }
    // Every anchor used; noise-free, the fix within 0.5 m of the agent in x and in y (the
    // sink's model is fitted from integer-dBm anchor-to-anchor RSSI).
    let mut worst = 0.0f64;
    for &(_, _, x, y, used) in &fixes {
        assert_eq!(used as usize, anchors, "{label}");
        let (ex, ey) = (x as f64 / 100.0 - AGENT[0], y as f64 / 100.0 - AGENT[1]);
        worst = worst.max(ex.abs()).max(ey.abs());
    }
    assert!(worst <= 0.5, "{label}: a fix {worst:.2} m off");
    // On the air: every beacon and report delivered, no collision, every slot used once.
    let t = tb.traffic(s.timing.warmup_s).unwrap();
    assert_eq!(t.beacons, t.beacons_delivered, "{label}: {t:?}");
    assert_eq!(t.reports, t.reports_delivered, "{label}: {t:?}");
    assert!(t.reports > 0, "{label}: {t:?}");
    assert_eq!(
        t.collisions + t.missing_slots + t.duplicate_slots,
        0,
        "{label}: {t:?}"
    );
    Outcome {
        superframe_s: sf,
        fixes: fixes.len(),
        worst_m: worst,
    }
}

/// Every anchor count with `channels` channels at the three slot lengths, a table row each.
fn every_anchor_count(channels: usize) {
    firmware::ensure_built(&firmware::default_dir()).unwrap();
    let only: Option<usize> = std::env::var("HOPLOC_ANCHORS")
        .ok()
        .and_then(|v| v.parse().ok());
    for anchors in (3..=8).filter(|n| only.is_none_or(|o| o == *n)) {
        let relay = Report::relay_rows_that_fit(anchors, channels);
        let mut slots = vec![min_slot_ms(anchors as u8), 25, 62];
        if let Ok(v) = std::env::var("HOPLOC_SLOTS") {
            slots = v.split(',').filter_map(|s| s.parse().ok()).collect();
        }
        for slot_ms in slots {
            let o = run(anchors, channels, slot_ms);
            eprintln!(
                "{anchors} × {channels}, {slot_ms:2} ms: superframe {:.3} s, report {} B \
                 ({relay} of {} relay rows), {} fixes, worst {:.2} m",
                o.superframe_s,
                Report::max_size(anchors, channels),
                anchors * channels,
                o.fixes,
                o.worst_m
            );
        }
    }
}

#[test]
fn one_channel() {
    every_anchor_count(1);
}

#[test]
fn two_channels() {
    every_anchor_count(2);
}

#[test]
fn three_channels() {
    every_anchor_count(3);
}

#[test]
fn four_channels() {
    every_anchor_count(4);
}
