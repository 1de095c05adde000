use super::synthetic::Room;
use super::*;

/// The 10 m room's corners (room10's anchors).
const ROOM10: [(f64, f64); 4] = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)];

/// room10's corners and an anchor in the middle.
const ROOM10_CENTRE: [(f64, f64); 5] = [
    (0.0, 0.0),
    (10.0, 0.0),
    (10.0, 10.0),
    (0.0, 10.0),
    (5.0, 5.0),
];

/// The check's verdict on `count` reports of `room` (`seed`), assuming the room's fading.
fn assess(room: &Room, count: usize, seed: u64) -> Assessment {
    let mut h = Health::new(HealthConfig {
        fading_db: room.fading_db,
        ..HealthConfig::default()
    });
    for r in room.reports(count, seed) {
        h.push(&r);
    }
    h.assess()
}

/// `room` with fading σ `fading_db` on each of its channels.
fn with_fading(mut room: Room, fading_db: f64) -> Room {
    room.fading_db = fading_db;
    room
}

#[test]
fn a_correct_layout_raises_no_alarm_in_200_rooms() {
    // The emulated testbed's medium (fading σ 3 dB per link and channel, shadowing σ 2 dB),
    // room10's four corners and two channels: 200 rooms, each its own fading.
    let room = Room::new(&ROOM10);
    let mut alarms = Vec::new();
    let mut scores = Vec::new();
    for seed in 0..200 {
        let a = assess(&room, 50, seed);
        assert_eq!(a.no_verdict, None, "room {seed}");
        assert_eq!((a.reports, a.links), (50, 6), "room {seed}");
        // Every anchor is judged, and its test places it near its configured position more
        // often than not: the check looks, it does not just stay quiet.
        for c in &a.anchors {
            let t = c.test.unwrap_or_else(|| panic!("room {seed}: {c:?}"));
            scores.push(t.score);
        }
        if !a.flags.is_empty() {
            alarms.push((seed, a.flags));
        }
    }
    assert!(alarms.is_empty(), "false alarms: {alarms:?}");
    // The scores are the χ²-like statistic of the docs: mostly small, never all zero.
    scores.sort_by(f64::total_cmp);
    let median = scores[scores.len() / 2];
    assert!(median > 0.1 && median < 4.0, "median score {median}");
}

#[test]
fn a_correct_five_anchor_layout_raises_no_alarm_in_200_rooms() {
    let room = Room::new(&ROOM10_CENTRE);
    let alarms: Vec<(u64, Vec<Flag>)> = (0..200)
        .map(|seed| (seed, assess(&room, 50, seed).flags))
        .filter(|(_, f)| !f.is_empty())
        .collect();
    assert!(alarms.is_empty(), "false alarms: {alarms:?}");
}

/// Anchor 3 (configured at (10, 10)) standing at `to` in 100 rooms of 5 anchors with fading σ
/// 1.5 dB per channel: the rooms that flag it, those that flag another anchor, and the
/// distances between where its links place it and where it stands (ascending).
fn flags_of_anchor_3(to: (f64, f64)) -> (usize, usize, Vec<f64>) {
    let room = with_fading(Room::new(&ROOM10_CENTRE), 1.5).moved(2, to);
    let truth = Point::new(to.0, to.1);
    let (mut right, mut wrong, mut errors) = (0, 0, Vec::new());
    for seed in 0..100 {
        let a = assess(&room, 50, seed);
        wrong += usize::from(a.flags.iter().any(|f| f.id != 3));
        if let Some(f) = a.flags.iter().find(|f| f.id == 3) {
            assert_eq!(f.configured, Point::new(10.0, 10.0));
            right += 1;
            errors.push(f.test.estimate.dist(truth));
            // The size: the offset is the distance from the configured position to the
            // estimate, and the residual is in dB of the anchor's links.
            assert!((f.test.offset_m - f.test.estimate.dist(f.configured)).abs() < 1e-9);
            assert!(f.test.residual_db > 1.0, "room {seed}: {f}");
        }
    }
    errors.sort_by(f64::total_cmp);
    (right, wrong, errors)
}

#[test]
fn an_anchor_moved_4_m_is_flagged_with_its_id_and_where_it_stands() {
    // Five anchors, fading σ 1.5 dB per link and channel: a room with less multipath than the
    // emulated testbed's (its rates are the bench's). Anchor 3 moved 4 m from its corner,
    // towards the centre and along the wall.
    for to in [
        (10.0 - 4.0 / 2f64.sqrt(), 10.0 - 4.0 / 2f64.sqrt()),
        (10.0, 6.0),
    ] {
        let (right, wrong, errors) = flags_of_anchor_3(to);
        assert!(
            right >= 90,
            "moved to {to:?}: flagged in {right} of 100 rooms"
        );
        // A moved anchor spoils its neighbours' links too: now and then one of them fits
        // the links better moved than the right one (see the module docs).
        assert!(
            wrong <= 3,
            "moved to {to:?}: another anchor flagged in {wrong} rooms"
        );
        // Where its links place it: within 1.5 m of where it stands in 9 flags of 10 (so the
        // offset reported is 4 ± 1.5 m), and never more than 3 m away.
        let p90 = errors[errors.len() * 9 / 10];
        let max = errors[errors.len() - 1];
        eprintln!(
            "moved to ({:.2}, {:.2}): anchor 3 flagged in {right} of 100 rooms, another in \
             {wrong}; its estimate within {p90:.2} m of where it stands in 9 flags of 10, \
             {max:.2} m at most",
            to.0, to.1
        );
        assert!(p90 <= 1.5 && max <= 3.0, "moved to {to:?}: {errors:.2?}");
    }
}

#[test]
fn half_a_metre_is_below_the_detection_limit() {
    // The same rooms, anchor 3 moved 0.5 m: as quiet as the correct layout. The change it
    // makes to its links (about 0.65 dB on a 10 m link) is a fraction of their static error.
    for to in [(9.65, 9.65), (10.0, 9.5)] {
        let (right, wrong, _) = flags_of_anchor_3(to);
        assert_eq!((right, wrong), (0, 0), "moved to {to:?}");
    }
    // With no noise at all the links do show a smaller move: 0.8 m scores above the
    // threshold, but a flag needs the estimate 1 m away at least ([`HealthConfig::min_offset_m`]).
    let mut room = with_fading(Room::new(&ROOM10_CENTRE), 0.0).moved(2, (10.0, 9.2));
    room.shadow_db = 0.0;
    let mut h = Health::new(HealthConfig {
        fading_db: 0.0,
        ..HealthConfig::default()
    });
    for r in room.reports(50, 1) {
        h.push(&r);
    }
    let a = h.assess();
    assert!(a.flags.is_empty(), "{:?}", a.flags);
    let t = a.anchors[2].test.unwrap();
    assert!(t.score > 20.0 && t.offset_m < 1.0, "{t:?}");
    let h = Health {
        cfg: HealthConfig {
            min_offset_m: 0.5,
            ..*h.config()
        },
        ..h
    };
    assert_eq!(
        h.assess().flags.iter().map(|f| f.id).collect::<Vec<_>>(),
        [3]
    );
}

#[test]
fn three_anchors_name_no_anchor() {
    // Three links, two model parameters and two coordinates of the moved anchor: any anchor
    // moved fits exactly, so none can be named, however far one is off.
    let tri = [(0.0, 0.0), (10.0, 0.0), (0.0, 10.0)];
    for room in [
        with_fading(Room::new(&tri), 0.0),
        with_fading(Room::new(&tri), 0.0).moved(2, (6.0, 6.0)),
        Room::new(&tri).moved(2, (6.0, 6.0)),
    ] {
        let a = assess(&room, 50, 1);
        assert_eq!(a.no_verdict, Some(NoVerdict::TooFewLinks), "{a:?}");
        assert!(a.flags.is_empty());
        assert_eq!(a.anchors.len(), 3);
        assert!(a.anchors.iter().all(|c| c.links == 2 && c.test.is_none()));
    }
    // What is left is the layout as a whole: with no noise, the moved anchor makes the three
    // links disagree with the fitted model, the correct layout does not.
    let rms = |room: Room| assess(&room, 50, 1).links_rms_db.unwrap();
    let quiet = with_fading(Room::new(&tri), 0.0);
    let (correct, moved) = (rms(quiet.clone()), rms(quiet.moved(2, (6.0, 6.0))));
    assert!(correct < 0.3 && moved > 1.0, "{correct} dB, {moved} dB");
}

#[test]
fn missing_relay_bytes_leave_links_out_not_the_verdict() {
    let moved = with_fading(Room::new(&ROOM10_CENTRE), 1.5).moved(2, (7.0, 7.0));
    let check = |reports: &[Report]| {
        let mut h = Health::new(HealthConfig {
            fading_db: 1.5,
            ..HealthConfig::default()
        });
        for r in reports {
            h.push(r);
        }
        h.assess()
    };
    let full = check(&moved.reports(50, 3));
    assert_eq!(full.links, 10);
    assert_eq!(full.flags.iter().map(|f| f.id).collect::<Vec<_>>(), [3]);

    // A third of the relay bytes lost at random: the same verdict.
    let mut lossy = moved.reports(50, 3);
    let mut k = 0u32;
    for r in &mut lossy {
        for row in r.relay.iter_mut().flatten() {
            for b in row.iter_mut() {
                k = k.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                if (k >> 16).is_multiple_of(3) {
                    *b = 0;
                }
            }
        }
    }
    let a = check(&lossy);
    assert_eq!(a.links, 10);
    assert_eq!(a.flags.iter().map(|f| f.id).collect::<Vec<_>>(), [3]);
    let (fa, fb) = (full.flags[0].test, a.flags[0].test);
    assert!(fa.estimate.dist(fb.estimate) < 1.0, "{fa:?} {fb:?}");

    // Link 1–2 heard in only 20 of 50 reports: left out, the rest judged.
    let mut rare = moved.reports(50, 3);
    for r in &mut rare[..30] {
        for m in &mut r.relay {
            (m[0][1], m[1][0]) = (0, 0);
        }
    }
    let a = check(&rare);
    assert_eq!(a.links, 9);
    assert_eq!(a.anchors[0].links, 3);
    assert_eq!(a.flags.iter().map(|f| f.id).collect::<Vec<_>>(), [3]);

    // Anchor 5 relays nothing and no anchor hears it (the agent does): its four links are
    // gone, it is not judged, and the four others are enough to name anchor 3.
    let mut deaf = moved.reports(50, 3);
    for r in &mut deaf {
        for m in &mut r.relay {
            m[4] = [0; MAX_ANCHORS];
            for row in m.iter_mut() {
                row[4] = 0;
            }
        }
    }
    let a = check(&deaf);
    assert_eq!(a.links, 6);
    assert_eq!(a.anchors[4].links, 0);
    assert_eq!(a.anchors[4].test, None);
    assert_eq!(a.flags.iter().map(|f| f.id).collect::<Vec<_>>(), [3]);
    // With four anchors, one of them deaf: three anchors' links, no verdict.
    let mut four = with_fading(Room::new(&ROOM10), 1.5).reports(50, 3);
    for r in &mut four {
        for m in &mut r.relay {
            m[3] = [0; MAX_ANCHORS];
            for row in m.iter_mut() {
                row[3] = 0;
            }
        }
    }
    assert_eq!(check(&four).no_verdict, Some(NoVerdict::TooFewLinks));

    // Reports without the relay matrix: nothing to judge, and they count for nothing.
    let mut bare = moved.reports(50, 3);
    for r in &mut bare {
        r.has_relay = false;
    }
    let a = check(&bare);
    assert_eq!(
        a.no_verdict,
        Some(NoVerdict::TooFewReports { have: 0, need: 20 })
    );
    assert_eq!(a.links, 0);
    assert!(a.flags.is_empty());
}

#[test]
fn an_anchor_the_agent_has_not_heard_has_no_position() {
    // Anchor 2's beacons never reach the agent: the reports carry (0, 0) for it and nothing
    // it relayed. Its position is unknown, so its links are not used, whatever others relay.
    let mut reports = with_fading(Room::new(&ROOM10_CENTRE), 1.5).reports(40, 5);
    for r in &mut reports {
        r.positions[1] = loc_proto::msg::Position { x: 0, y: 0 };
        for c in 0..r.channels.len() {
            r.rssi[c][1] = 0;
            r.relay[c][1] = [0; MAX_ANCHORS];
        }
    }
    let mut h = Health::default();
    for r in &reports {
        h.push(r);
    }
    let a = h.assess();
    assert_eq!(a.anchors.len(), 4);
    assert!(a.anchors.iter().all(|c| c.id != 2));
    assert_eq!(a.links, 6);
    assert_eq!(a.no_verdict, None);
}

#[test]
fn a_verdict_waits_for_enough_reports_and_a_new_layout_restarts_the_window() {
    let room = with_fading(Room::new(&ROOM10_CENTRE), 1.5).moved(2, (7.0, 7.0));
    let reports = room.reports(60, 2);
    let mut h = Health::new(HealthConfig {
        fading_db: 1.5,
        ..HealthConfig::default()
    });
    for r in &reports[..19] {
        h.push(r);
    }
    let a = h.assess();
    assert_eq!(
        a.no_verdict,
        Some(NoVerdict::TooFewReports { have: 19, need: 20 })
    );
    assert!(a.flags.is_empty());
    // The anchors' table is there already.
    assert_eq!(a.anchors.len(), 5);
    h.push(&reports[19]);
    assert_eq!(
        h.assess().flags.iter().map(|f| f.id).collect::<Vec<_>>(),
        [3]
    );
    // The window keeps the last 50.
    for r in &reports[20..] {
        h.push(r);
    }
    assert_eq!(h.assess().reports, 50);
    // Anchor 3 re-provisioned with where it stands: a new window, and once it is full, no
    // flag.
    let fixed = Room {
        configured: room.truth.clone(),
        ..room.clone()
    };
    let after = fixed.reports(20, 2);
    h.push(&after[0]);
    assert_eq!(h.assess().reports, 1);
    for r in &after[1..] {
        h.push(r);
    }
    let a = h.assess();
    assert_eq!((a.reports, a.no_verdict), (20, None));
    assert!(a.flags.is_empty(), "{:?}", a.flags);
    // Another channel list: a new window too.
    let mut three = room.clone();
    three.channels = 3;
    h.push(&three.reports(1, 2)[0]);
    assert_eq!(h.assess().reports, 1);
}

#[test]
fn on_report_says_when_a_flag_is_raised_and_when_it_clears() {
    let room = with_fading(Room::new(&ROOM10_CENTRE), 1.5).moved(2, (7.0, 7.0));
    let fixed = Room {
        configured: room.truth.clone(),
        ..room.clone()
    };
    let mut h = Health::new(HealthConfig {
        fading_db: 1.5,
        ..HealthConfig::default()
    });
    let mut events = Vec::new();
    for (k, r) in room
        .reports(60, 2)
        .iter()
        .chain(&fixed.reports(60, 2))
        .enumerate()
    {
        for e in h.on_report(r) {
            events.push((k, e));
        }
    }
    // Flagged once the window has 20 reports (assessed every 5th), cleared once the new
    // window (anchor 3 re-provisioned at report 60) has 20.
    assert_eq!(events.len(), 2, "{events:?}");
    let (k, HealthEvent::Flagged(f)) = events[0] else {
        panic!("{events:?}")
    };
    assert_eq!((k, f.id), (19, 3));
    assert_eq!(events[1], (79, HealthEvent::Cleared { id: 3 }));
    assert!(h.flagged().is_empty());
    assert!(events[0]
        .1
        .to_string()
        .starts_with("anchor health: FLAGGED anchor 3"));
}

#[test]
fn on_line_reads_report_lines_and_ignores_the_rest() {
    use loc_proto::sink_line::RawReport;
    let room = with_fading(Room::new(&ROOM10_CENTRE), 1.5).moved(2, (7.0, 7.0));
    let mut h = Health::new(HealthConfig {
        fading_db: 1.5,
        ..HealthConfig::default()
    });
    let mut flagged = Vec::new();
    for r in room.reports(20, 2) {
        let mut buf = [0; loc_proto::msg::MAX_PAYLOAD];
        let n = r.encode(&mut buf).unwrap();
        let mut line = String::new();
        let Ok(()) = RawReport::write(&buf[..n], &mut line);
        // Other lines and a damaged copy of the report line change nothing.
        for other in ["hoploc sink boot", "noise", &line.replacen("B5", "B6", 1)] {
            assert!(h.on_line(other).is_empty());
        }
        flagged.extend(h.on_line(&line));
    }
    assert_eq!(flagged.len(), 1, "{flagged:?}");
    assert!(matches!(
        flagged[0],
        HealthEvent::Flagged(Flag { id: 3, .. })
    ));
}

#[test]
fn the_summary_names_the_flag_and_tables_every_anchor() {
    let room = with_fading(Room::new(&ROOM10_CENTRE), 1.5).moved(2, (7.0, 7.0));
    let s = assess(&room, 50, 2).summary();
    assert!(
        s.starts_with("anchor health: FLAGGED anchor 3 configured at (10.00, 10.00) m"),
        "{s}"
    );
    assert!(
        s.contains("model of 10 links at the configured positions"),
        "{s}"
    );
    assert_eq!(s.lines().count(), 2 + 1 + 5, "{s}");
    let quiet = assess(&with_fading(Room::new(&ROOM10), 1.5), 50, 2).summary();
    assert!(
        quiet.starts_with("anchor health: no anchor flagged (50 reports, 6 links)"),
        "{quiet}"
    );
    let tri = assess(&Room::new(&[(0.0, 0.0), (10.0, 0.0), (0.0, 10.0)]), 50, 2).summary();
    assert!(tri.contains("no anchor can be judged"), "{tri}");
    assert_eq!(tri.matches("not judged: too few links").count(), 3, "{tri}");
}

#[test]
fn odd_reports_never_panic() {
    // Positions at the i16 extremes, every byte 255 or 1, one anchor everywhere, a room
    // without any noise (its links fit exactly, so ΔSSE is 0): verdicts or none, never a panic
    // or a NaN.
    let mut rooms = vec![
        Room::new(&[(-327.68, -327.68), (327.67, 327.67), (0.0, 0.0), (1.0, 0.0)]),
        Room::new(&[(1.0, 1.0); 8]),
        Room::new(&ROOM10),
        Room::new(&ROOM10),
    ];
    rooms[2].model = PathLoss {
        p0: 100.0,
        alpha: 0.1,
    };
    (rooms[3].fading_db, rooms[3].shadow_db) = (0.0, 0.0);
    for room in &rooms {
        let mut h = Health::new(HealthConfig {
            fading_db: 0.0,
            min_reports: 1,
            ..HealthConfig::default()
        });
        for r in room.reports(5, 1) {
            let _ = h.on_report(&r);
        }
        let a = h.assess();
        for c in &a.anchors {
            if let Some(t) = c.test {
                assert!(t.score.is_finite() && t.offset_m.is_finite(), "{c:?}");
            }
        }
    }
}

#[test]
fn the_monitor_shows_a_row_when_an_anchor_is_flagged() {
    use loc_proto::sink_line::RawReport;
    // The monitor's check has the default settings (the emulated testbed's fading); the room
    // has little multipath, anchor 3 stands at (6, 6).
    let room = with_fading(Room::new(&ROOM10_CENTRE), 1.0).moved(2, (6.0, 6.0));
    let mut mon = crate::monitor::Monitor::new(None);
    let mut rows = Vec::new();
    for r in room.reports(25, 1) {
        let mut buf = [0; loc_proto::msg::MAX_PAYLOAD];
        let n = r.encode(&mut buf).unwrap();
        let mut line = String::new();
        let Ok(()) = RawReport::write(&buf[..n], &mut line);
        rows.extend(mon.feed(&line));
    }
    assert_eq!(mon.counts.reports, 25);
    assert_eq!(rows.len(), 1, "{rows:?}");
    assert!(
        rows[0].starts_with("anchor health: FLAGGED anchor 3 configured at (10.00, 10.00) m"),
        "{rows:?}"
    );
    assert_eq!(mon.health.flagged(), [3]);
}
