//! The agent firmware in simavr on a modelled XBee (API mode 2 at 57600), with the beacons of
//! four scripted anchors delivered to its radio as a medium would: the exact reports it sends
//! to the sink, on which channel and when (slot timing error ≤ 1 ms).
//!
//! The firmware runs the build-time default config as agent 1: 4 anchors, channels [1, 12],
//! 62 ms slots, sink channel 3 (`Schedule::for_config`: 620 ms superframes, report sub-slot 1
//! at 496 ms).

use hoploc_tests::{beacon_packet, boot, rx_frame_delivery};
use loc_proto::config::Config;
use loc_proto::msg::{Position, Report};
use loc_proto::schedule::Schedule;
use loc_proto::{xbee_channel, Role};
use simavr::ms_to_cycles;
use simavr::xbee::{Address, RxPacket, XBee, XBeeConfig};

const SLOT_ERROR_MS: f64 = 1.0;
const POS: [[i16; 2]; 4] = [[0, 0], [1000, 0], [1000, 1000], [0, 1000]];

fn us(t: u32) -> f64 {
    t as f64 / 1000.0
}

/// RSSI byte of anchor `a` (1…4) on channel index `c`: distinct per pair.
fn rssi(a: u8, c: u8) -> u8 {
    40 + 10 * a + c
}

/// What anchor `a` relays on channel index `c`: it heard anchor `j` at 60 + 4a + j (not itself).
fn relay(a: u8, c: u8) -> Vec<u8> {
    (1..=4u8)
        .map(|j| if j == a { 0 } else { 60 + 4 * a + j + c })
        .collect()
}

#[test]
fn the_agent_reports_every_superframe_in_its_sub_slot_and_marks_what_it_missed() {
    let cfg = Config::DEFAULT;
    let s = Schedule::for_config(&cfg).unwrap();
    let sf = us(s.superframe_us());
    let mut avr = boot(Role::Agent);
    let mut radio = XBee::new(XBeeConfig::api(2));
    // The provisioning window, then the bring-up.
    let up = loc_proto::provision::PROVISION_WINDOW_MS as f64 + 700.0;
    radio.run_for_ms(&mut avr, up);
    assert_eq!(
        radio.registers().get(*b"MY"),
        Some(Role::Agent.address(1) as u32)
    );
    // The anchors' timeline: superframe 100 starts at t0. Anchor 4 is silent on channel 12.
    let t0 = up + 100.0;
    let superframes = 6u16;
    for k in 0..superframes {
        for c in 0..2u8 {
            let ch = cfg.channels.as_slice()[c as usize];
            for a in 1..=4u8 {
                if a == 4 && c == 1 {
                    continue;
                }
                let tx = t0 + k as f64 * sf + us(s.beacon_at_us(c, a).unwrap());
                let p = beacon_packet(a, 100 + k, ch, POS[a as usize - 1], &relay(a, c));
                let at = rx_frame_delivery(tx, p.len());
                let packet = RxPacket::broadcast16(
                    xbee_channel(ch).unwrap(),
                    cfg.pan_id,
                    a as u16,
                    -(rssi(a, c) as i16),
                    &p,
                );
                radio.deliver(packet, ms_to_cycles(at));
            }
        }
    }
    radio.run_until(&mut avr, ms_to_cycles(t0 + superframes as f64 * sf));
    let reports: Vec<_> = radio
        .frames_from_firmware()
        .iter()
        .filter(|f| f.frame_type() == 0x01)
        .map(|f| (f.ms(), f.clone()))
        .collect();
    let on_air = radio.take_transmissions();
    assert_eq!(on_air.len(), reports.len());
    // Heard from superframe 100 on: a report in each (the first may be partial).
    assert!(
        reports.len() >= superframes as usize - 1,
        "{}",
        reports.len()
    );
    let sink_ch = xbee_channel(cfg.sink_channel).unwrap();
    for ((t, f), tx) in reports.iter().zip(&on_air) {
        // To the sink, on the sink channel.
        assert_eq!(&f.data[2..4], &Role::Sink.address(1).to_be_bytes());
        assert_eq!(tx.dest, Address::Short(Role::Sink.address(1)));
        assert_eq!(tx.channel, sink_ch);
        let r = Report::decode(&f.data[5..]).unwrap();
        assert_eq!(r.agent, 1);
        let k = r.seq - 100;
        // In report sub-slot 1, within 1 ms.
        let want = t0 + k as f64 * sf + us(s.report_at_us(1).unwrap());
        assert!(
            (t - want).abs() <= SLOT_ERROR_MS,
            "seq {}: {t} vs {want}",
            r.seq
        );
        if k == 0 {
            continue;
        }
        // Everything heard, as heard; anchor 4 on channel 12 marked not heard.
        assert_eq!((r.anchors, r.channels), (4, cfg.channels));
        for a in 1..=4u8 {
            let i = a as usize - 1;
            assert_eq!(
                r.positions[i],
                Position {
                    x: POS[i][0],
                    y: POS[i][1]
                }
            );
            for c in 0..2u8 {
                let (want_rssi, want_relay) = if a == 4 && c == 1 {
                    (0, vec![0; 4])
                } else {
                    (rssi(a, c), relay(a, c))
                };
                assert_eq!(r.rssi[c as usize][i], want_rssi, "anchor {a} ch {c}");
                assert_eq!(
                    &r.relay[c as usize][i][..4],
                    &want_relay[..],
                    "anchor {a} ch {c}"
                );
            }
        }
    }
    // The channel plan around a report: tune to the sink where the report window begins, report
    // after the window's channel change and the sub-slot's guard, back to channel 1 after the
    // TX status, and to each anchor channel at its phase.
    let tunes: Vec<(f64, u8)> = radio
        .frames_from_firmware()
        .iter()
        .filter_map(|f| match f.data.as_slice() {
            [0x08, _, b'C', b'H', c] => Some((f.ms(), *c)),
            _ => None,
        })
        .collect();
    let (t_rep, _) = reports[1];
    let to_sink = tunes.iter().rev().find(|(t, _)| *t < t_rep).unwrap();
    assert_eq!(to_sink.1, sink_ch);
    let after = us(s.report_at_us(1).unwrap() - s.report_start_us());
    assert!((t_rep - to_sink.0 - after).abs() <= SLOT_ERROR_MS);
    let back = tunes.iter().find(|(t, _)| *t > t_rep).unwrap();
    assert_eq!(back.1, xbee_channel(1).unwrap());
    assert!(
        back.0 - t_rep < 20.0,
        "back on channel 1 {} ms after",
        back.0 - t_rep
    );
}
