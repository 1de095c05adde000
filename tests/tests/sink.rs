//! The sink firmware in simavr on a modelled XBee (API mode 2 at 57600, sink channel 3): the
//! reports of agent 1 delivered as a medium would, and the lines it writes
//! (`loc_proto::sink_line`): two `fix` lines per report (MLE, MMSE) equal to what the host computes
//! with the same logic, `nofix` when too few anchors were heard, and a `status` line counting
//! frames, drops by sequence gaps, corrupt and foreign frames.
//!
//! The firmware runs the build-time default config as the sink: its room is the anchors'
//! bounding box (10 m × 10 m here). Before each report's fix lines it writes the report's bytes
//! as a `report` line (what `hoploc replay` reads).

use hoploc_tests::boot;
use hoploc_tests::sink_reports::{encoded, packet, report, ALL};
use loc_proto::config::Config;
use loc_proto::line::BootLine;
use loc_proto::msg::Position;
use loc_proto::sink_line::{Estimator, RawReport, SinkLine, SinkOutput};
use loc_proto::{xbee_channel, Role};
use simavr::ms_to_cycles;
use simavr::xbee::{XBee, XBeeConfig};
use sink_fw::Sink;

#[test]
fn the_sink_writes_a_fix_per_report_and_counts_what_it_could_not_use() {
    let mut avr = boot(Role::Sink);
    let mut radio = XBee::new(XBeeConfig::api(2));
    // The 2 s provisioning window, then the radio bring-up.
    radio.run_for_ms(&mut avr, 2_700.0);
    assert_eq!(
        radio.registers().get(*b"MY"),
        Some(Role::Sink.address(1) as u32)
    );
    assert_eq!(
        radio.registers().get(*b"CH"),
        Some(xbee_channel(Config::DEFAULT.sink_channel).unwrap() as u32)
    );
    // Reports 7, 8, 10 (9 lost), one with two anchors only (11), a foreign packet and a
    // broken report between them.
    let reports = [
        report(7, [300.0, 600.0], ALL),
        report(8, [500.0, 500.0], ALL),
        report(10, [850.0, 120.0], ALL),
        report(11, [500.0, 500.0], &[0, 2]),
    ];
    let mut at = 3_000.0;
    let mut delivered = Vec::new();
    for (k, r) in reports.iter().enumerate() {
        radio.deliver(packet(&encoded(r)), ms_to_cycles(at));
        delivered.push(at);
        at += 150.0;
        if k == 1 {
            radio.deliver(packet(b"not a hoploc message"), ms_to_cycles(at));
            at += 150.0;
            let mut broken = encoded(&reports[0]);
            broken.truncate(30);
            radio.deliver(packet(&broken), ms_to_cycles(at));
            at += 150.0;
        }
    }
    radio.run_for_ms(&mut avr, 10_000.0);
    let outputs: Vec<(f64, SinkOutput)> = radio
        .text_lines()
        .iter()
        .filter_map(|l| SinkOutput::parse(&l.text).ok().map(|s| (l.ms(), s)))
        .collect();
    // A report line with the report's very bytes before each report's fix lines.
    let raws: Vec<RawReport> = outputs
        .iter()
        .filter_map(|(_, o)| match o {
            SinkOutput::Report(r) => Some(r.clone()),
            _ => None,
        })
        .collect();
    let want_raw: Vec<Vec<u8>> = reports.iter().map(encoded).collect();
    assert_eq!(
        raws.iter().map(|r| r.bytes().to_vec()).collect::<Vec<_>>(),
        want_raw
    );
    for (k, (_, o)) in outputs.iter().enumerate() {
        if let SinkOutput::Report(_) = o {
            assert!(
                matches!(
                    outputs.get(k + 1),
                    Some((
                        _,
                        SinkOutput::Line(SinkLine::Fix { .. } | SinkLine::NoFix { .. })
                    ))
                ),
                "a report line is followed by its fix lines"
            );
        }
    }
    let lines: Vec<(f64, SinkLine)> = outputs
        .iter()
        .filter_map(|(t, o)| match o {
            SinkOutput::Line(l) => Some((*t, *l)),
            _ => None,
        })
        .collect();
    // What the same logic computes on the host, line for line.
    let mut host = Sink::new(sink_fw::room(Position { x: 0, y: 0 }));
    let mut want = Vec::new();
    for r in &reports {
        match host.on_report(r) {
            Ok(fix) => want.extend(fix.lines()),
            Err(e) => want.push(sink_fw::no_fix_line(r.agent, r.seq, e)),
        }
    }
    let fixes: Vec<&SinkLine> = lines
        .iter()
        .map(|(_, l)| l)
        .filter(|l| !matches!(l, SinkLine::Status { .. }))
        .collect();
    assert_eq!(fixes, want.iter().collect::<Vec<_>>());
    assert!(
        matches!(want[6], SinkLine::NoFix { usable: 2, .. }),
        "{:?}",
        want[6]
    );
    // Each report's fix lines come out within 80 ms of its delivery: its report line (≈ 25 ms
    // of UART at 57600) and the estimate come in between.
    for (k, &t) in delivered.iter().take(3).enumerate() {
        let first = lines[2 * k].0;
        assert!(first > t && first < t + 80.0, "report {k}: {t} -> {first}");
    }
    // The status line 10 s after the sink started: 6 frames, 4 reports, 1 dropped (9), 1 corrupt, 1 foreign.
    let status: Vec<&SinkLine> = lines
        .iter()
        .map(|(_, l)| l)
        .filter(|l| matches!(l, SinkLine::Status { .. }))
        .collect();
    assert_eq!(
        status,
        [&SinkLine::Status {
            uptime_s: 10,
            frames: 6,
            reports: 4,
            drops: 1,
            checksum_errors: 1,
            foreign: 1,
            fixes: 3,
            repeats: 0,
            failed: 0,
        }]
    );
}

/// Reports arriving faster than the sink can handle them (each takes its lines over the UART
/// and the estimate) for 3 s: the sink neither resets (its watchdog has 1 s) nor stalls;
/// it locates what it can, counts the rest as missing, and the next report after the burst
/// gets its fix at once.
#[test]
fn a_burst_of_reports_faster_than_the_sink_neither_resets_nor_stalls_it() {
    let mut avr = boot(Role::Sink);
    let mut radio = XBee::new(XBeeConfig::api(2));
    radio.run_for_ms(&mut avr, 2_700.0);
    let (burst, period_ms) = (60u16, 50.0);
    for seq in 0..burst {
        let r = report(seq, [300.0 + f64::from(seq), 600.0], ALL);
        radio.deliver(
            packet(&encoded(&r)),
            ms_to_cycles(3_000.0 + period_ms * f64::from(seq)),
        );
    }
    let after = 3_000.0 + period_ms * f64::from(burst) + 1_000.0;
    radio.deliver(
        packet(&encoded(&report(burst, [500.0, 500.0], ALL))),
        ms_to_cycles(after),
    );
    radio.run_for_ms(&mut avr, 10_000.0);
    let texts: Vec<(f64, String)> = radio
        .text_lines()
        .iter()
        .map(|l| (l.ms(), l.text.clone()))
        .collect();
    // Once up: one config line (after a reset the boot line can drown in the radio's bytes,
    // the config line cannot).
    let starts = texts
        .iter()
        .filter(|(_, t)| matches!(BootLine::parse(t), Ok(BootLine::Config { .. })))
        .count();
    assert_eq!(starts, 1, "the sink restarted");
    let lines: Vec<(f64, SinkLine)> = texts
        .iter()
        .filter_map(|(t, l)| match SinkOutput::parse(l) {
            Ok(SinkOutput::Line(s)) => Some((*t, s)),
            _ => None,
        })
        .collect();
    let located: Vec<u16> = lines
        .iter()
        .filter_map(|(_, l)| match l {
            SinkLine::Fix {
                seq,
                estimator: Estimator::Mle,
                ..
            } => Some(*seq),
            _ => None,
        })
        .collect();
    // It keeps locating through the burst (at least one report per 100 ms of the 3 s), in order.
    assert!(
        located.len() >= 30,
        "{} reports located: {located:?}",
        located.len()
    );
    assert!(located.windows(2).all(|w| w[0] < w[1]), "{located:?}");
    // The report after the burst: its fix within 80 ms.
    let last = lines
        .iter()
        .find(|(_, l)| matches!(l, SinkLine::Fix { seq, .. } if *seq == burst))
        .unwrap_or_else(|| panic!("no fix for the report after the burst: {located:?}"));
    assert!(
        last.0 > after && last.0 < after + 80.0,
        "{} ms after {after}",
        last.0
    );
    // The status line counts every report it decoded and the ones it missed.
    let Some(&(
        _,
        SinkLine::Status {
            reports,
            drops,
            fixes,
            ..
        },
    )) = lines
        .iter()
        .rfind(|(_, l)| matches!(l, SinkLine::Status { .. }))
    else {
        panic!("no status line")
    };
    assert_eq!(fixes, reports, "every decoded report located");
    assert_eq!(reports as usize, located.len());
    assert!(
        drops > 0 && reports + drops <= u32::from(burst) + 1,
        "{reports} reports, {drops} missing"
    );
    eprintln!("burst of {burst} reports {period_ms} ms apart: {reports} located, {drops} missing by sequence");
}
