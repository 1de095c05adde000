//! The UART's receive ring (uno-board `serial`: the RX interrupt's push and `try_read`'s pop)
//! with a backlog: the sink firmware in simavr on a modelled XBee gets a second report while it
//! is still busy with the first (its lines over the UART and the estimate), so the
//! second report's whole frame waits in the 128-byte ring and is read from it in one go, its
//! read index passing the ring's wrap points with bytes still waiting. Both reports must come
//! out intact: their `report` lines hold their very bytes, and their fixes are what the host
//! computes. (The other firmware tests drain the ring byte by byte as it fills, or tolerate
//! lost reports, so a ring that wraps its read and write indices differently passed them.)

use hoploc_tests::boot;
use hoploc_tests::sink_reports::{encoded, packet, report, ALL};
use loc_proto::msg::Position;
use loc_proto::sink_line::{RawReport, SinkLine, SinkOutput};
use loc_proto::Role;
use simavr::ms_to_cycles;
use simavr::xbee::{XBee, XBeeConfig};
use sink_fw::Sink;

#[test]
fn a_report_waiting_in_the_ring_while_the_sink_is_busy_comes_out_intact() {
    let mut avr = boot(Role::Sink);
    let mut radio = XBee::new(XBeeConfig::api(2));
    // The 2 s provisioning window, then the radio bring-up.
    radio.run_for_ms(&mut avr, 2_700.0);
    // Pairs of reports 20 ms apart (the first's frame takes ≈ 12 ms on the line), the pairs
    // 300 ms apart: each pair's second frame waits whole in the ring. Eight pairs, so the ring's
    // indices start each backlog at a different place.
    let mut reports = Vec::new();
    for k in 0..8u16 {
        let t = 3_000.0 + 300.0 * f64::from(k);
        for (n, dt) in [(0u16, 0.0), (1, 20.0)] {
            let r = report(
                2 * k + n,
                [200.0 + 70.0 * f64::from(k), 300.0 + 50.0 * f64::from(n)],
                ALL,
            );
            radio.deliver(packet(&encoded(&r)), ms_to_cycles(t + dt));
            reports.push(r);
        }
    }
    radio.run_for_ms(&mut avr, 6_000.0);
    let outputs: Vec<SinkOutput> = radio
        .text_lines()
        .iter()
        .filter_map(|l| SinkOutput::parse(&l.text).ok())
        .collect();
    let raws: Vec<Vec<u8>> = outputs
        .iter()
        .filter_map(|o| match o {
            SinkOutput::Report(r) => Some(RawReport::bytes(r).to_vec()),
            _ => None,
        })
        .collect();
    assert_eq!(raws, reports.iter().map(encoded).collect::<Vec<_>>());
    let mut host = Sink::new(sink_fw::room(Position { x: 0, y: 0 }));
    let want: Vec<SinkLine> = reports
        .iter()
        .flat_map(|r| host.on_report(r).unwrap().lines())
        .collect();
    let fixes: Vec<SinkLine> = outputs
        .iter()
        .filter_map(|o| match o {
            SinkOutput::Line(l) if !matches!(l, SinkLine::Status { .. }) => Some(*l),
            _ => None,
        })
        .collect();
    assert_eq!(fixes, want);
}
