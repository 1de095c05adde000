//! The anchor firmware in simavr on a modelled XBee that is already in API mode 2 at 57600: the
//! exact beacons it puts on air, on which channel, and when (slot timing error ≤ 1 ms), with
//! beacons of other anchors delivered to its radio as a medium would.
//!
//! The firmware runs its built-in config (built without `HOPLOC_*` variables): anchor 1 of 4,
//! channels [1, 12], 62 ms slots (`Schedule::for_config`: 620 ms superframes).

use hoploc_tests::{beacon_packet, beacons_sent, boot, rx_frame_delivery};
use loc_proto::config::Config;
use loc_proto::line::BootLine;
use loc_proto::schedule::{beacon_latency_us, Schedule};
use loc_proto::{xbee_channel, Role};
use simavr::xbee::{XBee, XBeeConfig};
use simavr::{ms_to_cycles, Avr};

/// Slot timing error allowed, ms.
const SLOT_ERROR_MS: f64 = 1.0;

fn sched() -> Schedule {
    Schedule::for_config(&Config::DEFAULT).unwrap()
}

fn us(t: u32) -> f64 {
    t as f64 / 1000.0
}

/// Boots the anchor on an API-mode radio; returns the time the radio was up (ms).
fn booted() -> (Avr, XBee, f64) {
    let mut avr = boot(Role::Anchor);
    let mut radio = XBee::new(XBeeConfig::api(2));
    // The provisioning window (2 s), then the bring-up: run until the radio line, so that
    // what the tests deliver after is still ahead.
    let deadline = loc_proto::provision::PROVISION_WINDOW_MS as f64 + 700.0;
    let up = loop {
        radio.run_for_ms(&mut avr, 5.0);
        let up = radio
            .text_lines()
            .iter()
            .find(|l| BootLine::parse(&l.text).is_ok_and(|b| matches!(b, BootLine::RadioUp { .. })))
            .map(|l| l.ms());
        if let Some(up) = up {
            break up;
        }
        assert!(avr.time_ms() < deadline, "the radio came up");
    };
    let r = radio.registers();
    assert_eq!(r.get(*b"MY"), Some(Role::Anchor.address(1) as u32));
    assert_eq!(r.get(*b"ID"), Some(Config::DEFAULT.pan_id as u32));
    (avr, radio, up)
}

#[test]
fn anchor_1_alone_listens_then_beacons_in_its_slots_on_both_channels() {
    let s = sched();
    let sf = us(s.superframe_us());
    let (mut avr, mut radio, up) = booted();
    radio.run_for_ms(&mut avr, 2.0 * sf + 6.0 * sf);
    let sent = beacons_sent(&radio);
    // Listening first: 1 + id = 2 superframes without a transmission.
    let first = sent[0].0;
    assert!(first >= up + 2.0 * sf, "{first} {up}");
    // …then its first slot: the channel change and the guard, a few ms after listening ends.
    let slot_ms = us(s.beacon_at_us(0, 1).unwrap());
    assert!(first < up + 2.0 * sf + slot_ms + 7.0, "{first} {up}");
    assert!(sent.len() >= 10, "{}", sent.len());
    let on_air = radio.take_transmissions();
    assert_eq!(on_air.len(), sent.len());
    for (k, (t, b, ch)) in sent.iter().enumerate() {
        let (seq, c) = ((k / 2) as u16, (k % 2) as u8);
        let channel = Config::DEFAULT.channels.as_slice()[c as usize];
        // Exactly what it should say…
        assert_eq!(b.anchor, 1);
        assert_eq!((b.seq, b.channel), (seq, channel));
        assert_eq!(b.position, Config::DEFAULT.position);
        assert_eq!(b.relay, [0, 0, 0, 0], "nobody heard");
        // …on that channel (the radio's CH when it went on air, and the packet's)…
        assert_eq!(*ch, xbee_channel(channel).unwrap());
        assert_eq!(on_air[k].channel, *ch);
        assert_eq!(on_air[k].dest, simavr::xbee::Address::Short(0xFFFF));
        // …in its slot: the schedule's offset from the first beacon, within 1 ms.
        let want = first + seq as f64 * sf + us(s.beacon_at_us(c, 1).unwrap())
            - us(s.beacon_at_us(0, 1).unwrap());
        assert!(
            (t - want).abs() <= SLOT_ERROR_MS,
            "beacon {k}: {t} vs {want}"
        );
    }
}

/// While it listens, anchor 1 hears anchor 2 (seq 40…): it takes that timeline, corrected for
/// the radio latency, and beacons in slot 1 of it with the sequence going on; the RSSI it heard
/// from anchor 2 on channel 1 comes back in its channel-1 beacons' relay of the next superframe.
/// Foreign packets and broken beacons on the air change nothing.
#[test]
fn anchor_1_takes_the_timeline_it_hears_and_relays_the_rssi() {
    let s = sched();
    let sf = us(s.superframe_us());
    let (mut avr, mut radio, up) = booted();
    // Anchor 2's timeline: superframe 40 starts at t0 (its MCU's clock, as a medium sees it).
    let t0 = up + 300.0;
    let ch1 = xbee_channel(1).unwrap();
    let mut deliveries = Vec::new();
    for k in 0..8u16 {
        let tx = t0 + k as f64 * sf + us(s.beacon_at_us(0, 2).unwrap());
        let payload = beacon_packet(2, 40 + k, 1, [700, 0], &[61, 0, 0, 0]);
        deliveries.push((rx_frame_delivery(tx, payload.len()), ch1, 55, payload));
        // Noise on the same channel between the slots: not hoploc, and a beacon cut short.
        let junk = b"not a hoploc message".to_vec();
        deliveries.push((rx_frame_delivery(tx + 20.0, junk.len()), ch1, 50, junk));
        let mut cut = beacon_packet(3, 40 + k, 1, [700, 700], &[0, 0, 0, 0]);
        cut.truncate(9);
        deliveries.push((rx_frame_delivery(tx + 40.0, cut.len()), ch1, 50, cut));
    }
    for (at, ch, rssi, payload) in deliveries {
        let p = simavr::xbee::RxPacket::broadcast16(ch, 0x3332, 2, -rssi, &payload);
        radio.deliver(p, ms_to_cycles(at));
    }
    radio.run_until(&mut avr, ms_to_cycles(t0 + 7.0 * sf));
    let sent = beacons_sent(&radio);
    assert!(sent.len() >= 10, "{}", sent.len());
    // Its first beacon is in superframe 40 (heard during listening) or 41.
    let seq0 = sent[0].1.seq;
    assert!(seq0 == 40 || seq0 == 41, "{seq0}");
    for (t, b, _) in &sent {
        let k = b.seq - 40;
        let c = Config::DEFAULT
            .channels
            .as_slice()
            .iter()
            .position(|&c| c == b.channel)
            .unwrap();
        let want = t0 + k as f64 * sf + us(s.beacon_at_us(c as u8, 1).unwrap());
        assert!(
            (t - want).abs() <= SLOT_ERROR_MS,
            "seq {} ch {}: {t} vs {want} (latency {} µs)",
            b.seq,
            b.channel,
            beacon_latency_us(4)
        );
        // The relay: anchor 2 at 55 on channel 1 from the superframe after it was heard.
        if b.channel == 1 && b.seq > seq0 {
            assert_eq!(b.relay, [0, 55, 0, 0], "seq {}", b.seq);
        } else if b.channel == 12 {
            assert_eq!(b.relay, [0, 0, 0, 0]);
        }
    }
}
