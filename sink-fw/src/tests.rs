//! The sink on noise-free reports from the path-loss model (P0 = −40 dBm, α = 3).

use super::*;
use loc_core::fixed::{PointCm, Search};

const ANCHORS: [(i16, i16); 4] = [(0, 0), (1000, 0), (1000, 1000), (0, 1000)];

/// The RSSI byte (−dBm, rounded) at `d_cm` under P0 = −40 dBm, α = 3.
fn byte(d_cm: f64) -> u8 {
    let p = -40.0 - 30.0 * (d_cm / 100.0).max(0.01).log10();
    (-p).round() as u8
}

fn dist(a: (i16, i16), b: (f64, f64)) -> f64 {
    ((a.0 as f64 - b.0).powi(2) + (a.1 as f64 - b.1).powi(2)).sqrt()
}

/// A report of an agent at `at` (cm), two channels, every anchor heard unless in `missing`.
fn report(at: (f64, f64), missing: &[usize]) -> Measurements {
    let pos: Vec<PointCm> = ANCHORS.iter().map(|&(x, y)| PointCm::new(x, y)).collect();
    let mut m = Measurements::new(&pos, 2);
    for (i, &a) in ANCHORS.iter().enumerate() {
        if missing.contains(&i) {
            continue;
        }
        for c in 0..2 {
            m.rssi[i][c] = Some(byte(dist(a, at)));
        }
        for (j, &b) in ANCHORS.iter().enumerate() {
            if i != j && !missing.contains(&j) {
                for c in 0..2 {
                    m.a2a[i][j][c] = Some(byte(dist(a, (b.0 as f64, b.1 as f64))));
                }
            }
        }
    }
    m
}

fn sink() -> Sink {
    Sink::new(Some(AreaCm::new(1000, 1000)))
}

#[test]
fn a_noise_free_report_is_located_within_a_fine_step() {
    let mut s = sink();
    for (k, at) in [
        (300.0, 600.0),
        (500.0, 500.0),
        (850.0, 120.0),
        (50.0, 950.0),
    ]
    .into_iter()
    .enumerate()
    {
        let f = s.on_measurements(1, k as u16, &report(at, &[])).unwrap();
        assert!(f.fitted);
        for e in f.estimates {
            // mm against cm. The bytes are whole dB: ±0.5 dB is ±3.8 % of a distance at
            // α = 3, up to 30 cm at 8 m, so two fine steps (2 × 20 cm) is the bound here.
            let err = ((e.pos.x as f64 / 10.0 - at.0).powi(2)
                + (e.pos.y as f64 / 10.0 - at.1).powi(2))
            .sqrt();
            assert!(err <= 40.0, "{at:?}: {e:?} ({err:.0} cm)");
            assert_eq!(e.anchors, 4);
        }
    }
    // Each report's fit moved the smoothed model off the prior, within the thesis' bounds.
    // (Corner anchors see only 10 m and 14.1 m: whole-dB bytes leave α uncertain by ±0.7,
    // which P0 absorbs; the fixes above are what matters.)
    let m = s.model();
    assert_ne!(m, PathLoss::THESIS);
    assert!((-60 << 16..=-20 << 16).contains(&m.p0), "{m:?}");
    assert!((2 << 24..=5 << 24).contains(&m.alpha), "{m:?}");
    assert_eq!(s.counters().fixes(), 4);
}

#[test]
fn the_fix_is_loc_cores_with_the_smoothed_model() {
    let mut s = sink();
    let m = report((420.0, 310.0), &[]);
    let f = s.on_measurements(2, 0, &m).unwrap();
    let obs = observations(&m, Refinement::Extended);
    let want = loc_core::fixed::mle(&obs, f.model, AreaCm::new(1000, 1000), Search::Thesis);
    assert_eq!(Ok(*f.mle()), want);
}

#[test]
fn three_anchors_still_fix_and_two_do_not() {
    let mut s = sink();
    let f = s
        .on_measurements(1, 0, &report((300.0, 300.0), &[3]))
        .unwrap();
    assert_eq!(f.mle().anchors, 3);
    let e = s.on_measurements(1, 1, &report((300.0, 300.0), &[2, 3]));
    assert_eq!(e, Err(LocError::TooFewAnchors { usable: 2 }));
    assert_eq!((s.counters().fixes(), s.counters().no_fixes()), (1, 1));
}

#[test]
fn gaps_in_an_agents_sequence_count_as_drops() {
    let mut s = sink();
    let m = report((500.0, 500.0), &[]);
    for seq in [5u16, 6, 9, 9, 10, 12] {
        let _ = s.on_measurements(3, seq, &m);
    }
    // 7, 8 and 11 missing; the repeated 9 is no drop, but a repeat.
    assert_eq!(s.counters().drops(), 3);
    assert_eq!(s.counters().repeats(), 1);
    // Across the wrap: 0 missing.
    for seq in [65535u16, 1] {
        let _ = s.on_measurements(5, seq, &m);
    }
    assert_eq!(s.counters().drops(), 4);
    // A report from far in the past (more than half the sequence space back) is no drop either.
    let _ = s.on_measurements(5, 40_000, &m);
    assert_eq!(s.counters().drops(), 4);
    // Another agent has its own sequence; an agent id out of range is located but not tracked.
    let _ = s.on_measurements(4, 100, &m);
    let _ = s.on_measurements(0, 1, &m);
    let _ = s.on_measurements(200, 1, &m);
    assert_eq!(s.counters().drops(), 4);
    assert_eq!(s.counters().reports(), 12);
}

/// Two senders with one agent id (both sending the superframe's sequence number) show as
/// repeats, not as drops; a sequence number far back is the anchors' timeline starting over
/// (counted as nothing, and followed from there); a replayed old report within the window is a
/// repeat too. The agents' failed transmissions add up.
#[test]
fn repeats_restarts_and_failures_are_counted() {
    let mut s = sink();
    let m = report((500.0, 500.0), &[]);
    // Two agents with id 1, each reporting superframes 100…109.
    for seq in 100u16..110 {
        let _ = s.on_measurements(1, seq, &m);
        let _ = s.on_measurements(1, seq, &m);
    }
    let c = *s.counters();
    assert_eq!((c.reports(), c.drops(), c.repeats()), (20, 0, 10));
    // The anchors reset: the sequence starts again at 0; then 1, 2.
    for seq in [0u16, 1, 2] {
        let _ = s.on_measurements(1, seq, &m);
    }
    assert_eq!((s.counters().drops(), s.counters().repeats()), (0, 10));
    // A replay of report 0 (3 back) and of one 17 back: a repeat, then a restart.
    let _ = s.on_measurements(1, 0, &m);
    assert_eq!(s.counters().repeats(), 11);
    let _ = s.on_measurements(1, 3u16.wrapping_sub(REPEAT_WINDOW + 1), &m);
    assert_eq!((s.counters().drops(), s.counters().repeats()), (0, 11));
    // Failed transmissions, as reports say them.
    let chans = loc_proto::msg::ChannelList::new(&[1, 12]).unwrap();
    let mut r = loc_proto::msg::Report::new(2, 7, 4, chans);
    r.failed = 3;
    let _ = s.on_report(&r);
    r.seq = 8;
    r.failed = 7;
    let _ = s.on_report(&r);
    assert_eq!(s.counters().failed(), 10);
}

#[test]
fn bad_frames_are_counted_and_change_nothing() {
    let mut s = sink();
    let before = s.model();
    s.on_bad_frame(BadFrame::Corrupt);
    s.on_bad_frame(BadFrame::Foreign);
    s.on_bad_frame(BadFrame::Foreign);
    let c = s.counters();
    assert_eq!(
        (c.frames(), c.checksum_errors(), c.foreign(), c.reports()),
        (3, 1, 2, 0)
    );
    assert_eq!(s.model(), before);
    // A good report right after is located.
    assert!(s
        .on_measurements(1, 0, &report((700.0, 400.0), &[]))
        .is_ok());
}

#[test]
fn a_report_without_anchor_to_anchor_rssi_keeps_the_model() {
    let mut s = sink();
    let mut m = report((700.0, 400.0), &[]);
    m.a2a = [[[None; 4]; 8]; 8];
    let f = s.on_measurements(1, 0, &m).unwrap();
    assert!(!f.fitted);
    assert_eq!(f.model, PathLoss::THESIS);
}

#[test]
fn a_report_off_the_wire_gives_the_same_fix_as_its_measurements() {
    use loc_proto::msg::{ChannelList, Position};
    let m = report((620.0, 280.0), &[1]);
    let mut r = Report::new(7, 3, 4, ChannelList::new(&[1, 12]).unwrap());
    for (i, &(x, y)) in ANCHORS.iter().enumerate() {
        r.positions[i] = Position { x, y };
        for c in 0..2 {
            r.rssi[c][i] = m.rssi[i][c].unwrap_or(0);
            for j in 0..4 {
                r.relay[c][i][j] = m.a2a[i][j][c].unwrap_or(0);
            }
        }
    }
    let mut buf = [0; 100];
    let len = r.encode(&mut buf).unwrap();
    let back = Report::decode(&buf[..len]).unwrap();
    assert_eq!(measurements(&back), m);
    let (mut a, mut b) = (sink(), sink());
    let fa = a.on_report(&back).unwrap();
    assert_eq!(
        (fa.agent, fa.seq, fa.mle().anchors),
        (7, 3, 3),
        "anchor 2 not heard"
    );
    assert_eq!(Ok(fa), b.on_measurements(7, 3, &m));
}

#[test]
fn fixes_and_failures_become_sink_lines_that_parse_back() {
    use loc_proto::sink_line::{Estimator, SinkLine};
    let mut s = sink();
    let f = s
        .on_measurements(5, 77, &report((300.0, 600.0), &[]))
        .unwrap();
    let [mle, mmse] = f.lines();
    let SinkLine::Fix {
        agent,
        seq,
        estimator,
        x,
        y,
        alpha_x100,
        p0_x100,
        anchors,
        flags,
    } = mle
    else {
        panic!("{mle:?}")
    };
    assert_eq!(
        (agent, seq, estimator, anchors, flags),
        (5, 77, Estimator::Mle, 4, 1)
    );
    assert_eq!(
        (x as u32, y as u32),
        ((f.mle().pos.x + 5) / 10, (f.mle().pos.y + 5) / 10)
    );
    let alpha = f.model.alpha as f64 / 16_777_216.0;
    let p0 = f.model.p0 as f64 / 65_536.0;
    assert!(
        (alpha_x100 as f64 / 100.0 - alpha).abs() <= 0.005,
        "{alpha_x100} {alpha}"
    );
    assert!(
        (p0_x100 as f64 / 100.0 - p0).abs() <= 0.005,
        "{p0_x100} {p0}"
    );
    assert!(matches!(
        mmse,
        SinkLine::Fix {
            estimator: Estimator::Mmse,
            ..
        }
    ));
    let e = s
        .on_measurements(5, 78, &report((300.0, 600.0), &[0, 1]))
        .unwrap_err();
    let nofix = no_fix_line(5, 78, e);
    assert_eq!(
        nofix,
        SinkLine::NoFix {
            agent: 5,
            seq: 78,
            usable: 2
        }
    );
    s.add_uptime(5);
    s.add_uptime(7);
    let status = s.counters().line();
    assert!(matches!(
        status,
        SinkLine::Status {
            uptime_s: 12,
            reports: 2,
            fixes: 1,
            ..
        }
    ));
    for l in [mle, mmse, nofix, status] {
        let mut text = std::string::String::new();
        let Ok(()) = l.write(&mut text);
        assert_eq!(SinkLine::parse(&text), Ok(l));
    }
}

/// [`report_inputs`] (what `on_report` runs) gives exactly the calibration statistics and
/// observations of the generic path from [`measurements`], and `on_report` the same fixes and
/// counters as `on_measurements`, on random reports: 1–8 anchors anywhere (coincident ones
/// too), 1–4 channels, bytes 0 (not heard) to 255, with and without the relay matrix.
#[test]
fn reports_go_the_same_way_as_their_measurements() {
    use loc_proto::msg::{ChannelList, Position};
    let mut x = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move |n: u64| {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x % n
    };
    let (mut a, mut b) = (sink(), sink());
    let (mut fixes, mut views) = (0, 0);
    for t in 0..3000u16 {
        let anchors = 1 + next(8) as u8;
        let chans = [1, 12, 3, 16];
        let list = ChannelList::new(&chans[..1 + next(4) as usize]).unwrap();
        let mut r = Report::new(1 + next(3) as u8, t, anchors, list);
        r.has_relay = next(5) != 0;
        let near = next(2) == 0;
        for p in r.positions.iter_mut() {
            *p = if near {
                Position {
                    x: next(1200) as i16 - 100,
                    y: next(1200) as i16 - 100,
                }
            } else {
                Position {
                    x: next(65536) as u16 as i16,
                    y: next(65536) as u16 as i16,
                }
            };
        }
        let byte = |next: &mut dyn FnMut(u64) -> u64| match next(10) {
            0 => 0,
            1 => 255,
            _ => 40 + next(60) as u8,
        };
        for c in 0..4 {
            for i in 0..8 {
                r.rssi[c][i] = byte(&mut next);
                for j in 0..8 {
                    r.relay[c][i][j] = byte(&mut next);
                }
            }
        }
        let m = measurements(&r);
        let (stats, obs) = report_inputs(&r);
        let mut area = AreaCm::new(0, 0);
        report_inputs_into(
            &r,
            &mut CalStats::new(),
            &mut Observations::new(),
            &mut area,
        );
        assert_eq!(stats, CalStats::from_measurements(&m, None), "report {t}");
        assert_eq!(obs, observations(&m, Refinement::Extended), "report {t}");
        assert_eq!(area, anchors_box(&m.anchors[..m.n_anchors]), "report {t}");
        let fa = a.on_report(&r);
        assert_eq!(fa, b.on_measurements(r.agent, r.seq, &m), "report {t}");
        // Off the wire, read in place (what the firmware does): the same inputs.
        let mut buf = [0; 256];
        if (3..=8).contains(&anchors) {
            if let Ok(n) = r.encode(&mut buf) {
                let view = loc_proto::msg::ReportView::parse(&buf[..n]).unwrap();
                assert_eq!(report_inputs(&view), (stats, obs), "report {t}");
                let mut a = AreaCm::new(0, 0);
                report_inputs_into(
                    &view,
                    &mut CalStats::new(),
                    &mut Observations::new(),
                    &mut a,
                );
                assert_eq!(a, area, "report {t}");
                views += 1;
            }
        }
        fixes += usize::from(fa.is_ok());
        assert_eq!(a.counters(), b.counters());
        assert_eq!(a.model(), b.model());
    }
    assert!(fixes > 1000, "{fixes}");
    assert!(views > 500, "{views}");
}

/// `centi` is the plain 64-bit rounding, on the edges and across the whole range of α
/// (Q.24) and P0 (Q.16) a sink can hold.
#[test]
fn hundredths_are_the_64_bit_rounding() {
    let want = |v: i32, q: u32| ((v as i64 * 100 + (1 << (q - 1))) >> q) as i32;
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    for k in 0..200_000u32 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let v = match k {
            0 => loc_core::fixed::ALPHA_LIMIT,
            1 => -loc_core::fixed::P0_LIMIT,
            2 => 1 << 30,
            3 => -(1 << 30),
            4..=1000 => k as i32 - 500,
            _ => (x as i32) >> 1 >> (x >> 59),
        };
        for q in [16, 24] {
            assert_eq!(centi(v, q), want(v, q), "{v} {q}");
        }
    }
}

/// `cm` is the rounded, saturating conversion it stands for, on the edges and across `u32`.
#[test]
fn centimetres_round_half_up_and_saturate() {
    let want = |mm: u32| (mm.saturating_add(5) / 10).min(i16::MAX as u32) as i16;
    let edges = [0, 4, 5, 14, 15, 327_664, 327_665, 327_669, 327_670, 1 << 20];
    let mut x = 0x2545_F491_4F6C_DD1Du64;
    for k in 0..200_000u32 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let mm = match k {
            0..=9 => edges[k as usize],
            10 => u32::MAX - 4,
            11 => u32::MAX,
            _ => (x as u32) >> (x >> 59),
        };
        assert_eq!(cm(mm), want(mm), "{mm}");
    }
}

/// The config's position is the room: positive sizes as given, (0, 0) (or anything not
/// positive) the anchors' bounding box from the origin.
#[test]
fn the_configs_position_is_the_room_or_the_anchors_box() {
    use loc_proto::msg::Position;
    assert_eq!(
        room(Position { x: 800, y: 650 }),
        Some(AreaCm::new(800, 650))
    );
    assert_eq!(
        room(Position { x: 1, y: 32767 }),
        Some(AreaCm::new(1, 32767))
    );
    for (x, y) in [(0, 0), (0, 500), (500, 0), (-3, 500), (500, -1)] {
        assert_eq!(room(Position { x, y }), None, "{x}, {y}");
    }
    let p = |x, y| PointCm::new(x, y);
    assert_eq!(anchors_box(&[]), AreaCm::new(0, 0));
    assert_eq!(
        anchors_box(&[p(0, 0), p(1000, 20), p(-50, 900), p(300, -7)]),
        AreaCm::new(1000, 900)
    );
}

/// A sink without a room locates each report in its anchors' bounding box: the same fixes as a
/// sink given that box, both from reports and from measurements.
#[test]
fn a_sink_without_a_room_uses_each_reports_anchors_box() {
    use loc_proto::msg::{ChannelList, Position};
    let mut boxed = Sink::new(None);
    let mut given = sink();
    let mut other = Sink::new(Some(AreaCm::new(2000, 1000)));
    let at = (620.0, 280.0);
    let m = report(at, &[]);
    let f = boxed.on_measurements(1, 1, &m).unwrap();
    assert_eq!(Ok(f), given.on_measurements(1, 1, &m));
    assert_ne!(Ok(f), other.on_measurements(1, 1, &m), "the area matters");
    // From a report whose anchors span 1500 × 600 cm only.
    let mut r = Report::new(1, 2, 4, ChannelList::new(&[1, 12]).unwrap());
    let corners = [(0, 0), (1500, 0), (1500, 600), (0, 600)];
    for (i, &(x, y)) in corners.iter().enumerate() {
        r.positions[i] = Position { x, y };
        for c in 0..2 {
            r.rssi[c][i] = byte(dist((x, y), (1200.0, 100.0)));
        }
    }
    let mut in_box = Sink::new(Some(AreaCm::new(1500, 600)));
    let mut from_m = Sink::new(None);
    let got = Sink::new(None).on_report(&r).unwrap();
    assert_eq!(Ok(got), in_box.on_report(&r));
    assert_eq!(Ok(got), from_m.on_measurements(1, 2, &measurements(&r)));
    assert!(
        got.mle().pos.x <= 15_000 && got.mle().pos.y <= 6_000,
        "{got:?}"
    );
    assert!(got.mle().pos.x > 10_000, "{got:?}");
}

/// Frames loc-proto rejects: not hoploc's (magic), or a version or kind this build does not
/// speak, are foreign; anything else is corrupt.
#[test]
fn decode_errors_are_foreign_or_corrupt() {
    use loc_proto::error::Field;
    assert_eq!(BadFrame::of(Error::BadMagic), BadFrame::Foreign);
    assert_eq!(
        BadFrame::of(Error::BadVersion { found: 9 }),
        BadFrame::Foreign
    );
    assert_eq!(
        BadFrame::of(Error::BadKind { found: 0x7F }),
        BadFrame::Foreign
    );
    assert_eq!(BadFrame::of(Error::TooShort), BadFrame::Corrupt);
    assert_eq!(BadFrame::of(Error::BadLength), BadFrame::Corrupt);
    assert_eq!(BadFrame::of(Error::BadCrc), BadFrame::Corrupt);
    assert_eq!(
        BadFrame::of(Error::BadValue {
            field: Field::Anchors
        }),
        BadFrame::Corrupt
    );
    // Through the decoder.
    assert_eq!(
        Report::decode(b"not a hoploc message").map_err(BadFrame::of),
        Err(BadFrame::Foreign)
    );
    let r = Report::new(1, 1, 4, loc_proto::msg::ChannelList::new(&[1]).unwrap());
    let mut buf = [0; 100];
    let n = r.encode(&mut buf).unwrap();
    assert!(Report::decode(&buf[..n]).is_ok());
    assert_eq!(
        Report::decode(&buf[..n - 1]).map_err(BadFrame::of),
        Err(BadFrame::Corrupt)
    );
    // The firmware's parser (`ReportView::accept`) counts each error as `BadFrame::of` does.
    use loc_proto::msg::NotReport;
    for e in [
        Error::BadMagic,
        Error::BadVersion { found: 9 },
        Error::BadKind { found: 0x7F },
        Error::TooShort,
        Error::BadLength,
        Error::BadCrc,
        Error::BadValue {
            field: Field::Anchors,
        },
    ] {
        assert_eq!(BadFrame::from(NotReport::of(e)), BadFrame::of(e), "{e:?}");
    }
    assert_eq!(
        ReportView::accept(b"not a hoploc message").map_err(BadFrame::from),
        Err(BadFrame::Foreign)
    );
    assert_eq!(
        ReportView::accept(&buf[..n - 1]).map_err(BadFrame::from),
        Err(BadFrame::Corrupt)
    );
}

/// The firmware's `status` line, written counter by counter ([`Counters::write_line`]), is the
/// built line's bytes ([`Counters::line`], whose format loc-proto's golden tests pin), for
/// counters across the whole `u32` range.
#[test]
fn status_lines_written_in_place_are_the_built_ones() {
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        // Short and long numbers alike: 0…9, then up to 32 bits.
        match x % 4 {
            0 => (x >> 8) as u32 % 10,
            1 => u32::MAX - (x >> 8) as u32 % 3,
            _ => (x >> (8 + x % 24)) as u32,
        }
    };
    for _ in 0..2000 {
        let c = Counters(core::array::from_fn(|_| next()));
        let (mut built, mut direct) = (std::string::String::new(), std::string::String::new());
        let Ok(()) = c.line().write(&mut built);
        let Ok(()) = c.write_line(&mut direct);
        assert_eq!(direct, built);
    }
}
