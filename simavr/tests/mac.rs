//! The modelled XBee's 802.15.4 MAC on the network: clear channel assessment against `CA` by
//! level and distance, the CSMA-CA's backoffs, CCA failure, acknowledgements, retries and their
//! timing, duplicate detection, broadcasts, and two senders starting in the same backoff
//! period with and without carrier sense. Host radios on a noise-free medium (−40 dBm at 1 m,
//! α = 3), API mode 2.

use simavr::medium::{Medium, MediumConfig, NodeRadio};
use simavr::ms_to_cycles;
use simavr::network::{Network, NetworkConfig, NodeId, NodeSpec, Outcome, TxRecord};
use simavr::xbee::{
    encode_frame, frame_air_cycles, time_on_air_ms, Address, Csma, FrameKind, MacFields, Model,
    Security, Transmission, XBeeConfig, XBeeCore, ACK_AIR_US, ACK_WAIT_US, BACKOFF_PERIOD_US,
    CCA_US, TURNAROUND_US,
};
use xbee_api::{Decoder, Frame, Mode, TxStatus};

const CH: u8 = 0x0C;

fn us(x: u64) -> u64 {
    ms_to_cycles(x as f64 / 1000.0)
}

fn network(threads: usize) -> Network {
    Network::with_config(
        Medium::new(MediumConfig::noise_free()),
        NetworkConfig {
            threads,
            ..NetworkConfig::default()
        },
    )
}

/// A host radio with 16-bit address `my` at (x, y) m on channel `CH` with the XBee's CSMA-CA
/// (seeded with `seed`), then `tweak`ed; past its power-up, its output taken.
fn radio(
    net: &mut Network,
    my: u16,
    at: [f64; 2],
    seed: u64,
    tweak: impl FnOnce(&mut XBeeConfig),
) -> NodeId {
    let mut spec = NodeSpec::new(format!("r{my}"), NodeRadio::at(at[0], at[1]));
    spec.xbee.my = my;
    spec.xbee.ch = CH;
    spec.xbee.sh_sl = 0x0013_A200_0000_0000 + u64::from(my);
    spec.xbee.csma = Csma::Random { seed };
    tweak(&mut spec.xbee);
    net.add_host_radio(spec)
}

/// Runs past every radio's power-up and drops what they wrote.
fn settle(net: &mut Network, ids: &[NodeId]) {
    net.run_for_ms(10.0);
    for &id in ids {
        net.core_mut(id).take_output();
    }
}

/// Feeds `id` a TX16 request (frame id `fid`) to `dest` with `options` starting at the
/// network's cycle; returns the cycle its last byte ended (the request's time).
fn tx16(net: &mut Network, id: NodeId, fid: u8, dest: u16, options: u8, payload: &[u8]) -> u64 {
    let mut data = vec![0x01, fid];
    data.extend_from_slice(&dest.to_be_bytes());
    data.push(options);
    data.extend_from_slice(payload);
    let bytes = encode_frame(&data, Mode::Escaped);
    let now = net.cycle();
    net.core_mut(id).rx_bytes(now, &bytes)
}

/// The API frames radio `id` wrote since the last call: (cycle of the first byte, frame data).
fn frames(net: &mut Network, id: NodeId) -> Vec<(u64, Vec<u8>)> {
    let mut dec = Decoder::new(Mode::Escaped);
    let mut out = Vec::new();
    let mut start = 0;
    for b in net.core_mut(id).take_output() {
        if b.byte == xbee_api::START {
            start = b.cycle;
        }
        dec.feed(&[b.byte], |f| out.push((start, f.unwrap().data().to_vec())));
    }
    out
}

/// The TX statuses among `frames`: (cycle, frame id, status).
fn statuses(frames: &[(u64, Vec<u8>)]) -> Vec<(u64, u8, TxStatus)> {
    frames
        .iter()
        .filter_map(|(at, d)| match Frame::parse(d) {
            Ok(Frame::TxStatus { frame_id, status }) => Some((*at, frame_id, status)),
            _ => None,
        })
        .collect()
}

/// The payloads of the RX16 frames among `frames`.
fn received(frames: &[(u64, Vec<u8>)]) -> Vec<Vec<u8>> {
    frames
        .iter()
        .filter_map(|(_, d)| match Frame::parse(d) {
            Ok(Frame::Rx16 { data, .. }) => Some(data.to_vec()),
            _ => None,
        })
        .collect()
}

/// An AT query through an 0x08 frame; the value answered.
fn at_query(net: &mut Network, id: NodeId, cmd: &[u8; 2]) -> Vec<u8> {
    let bytes = encode_frame(&[0x08, 0x42, cmd[0], cmd[1]], Mode::Escaped);
    let now = net.cycle();
    net.core_mut(id).rx_bytes(now, &bytes);
    net.run_for_ms(5.0);
    frames(net, id)
        .into_iter()
        .find_map(|(_, d)| match Frame::parse(&d) {
            Ok(Frame::AtResponse { data, .. }) => Some(data.to_vec()),
            _ => None,
        })
        .expect("an AT response")
}

/// Something other than an XBee (or one that ignores the channel) on air on `channel` from
/// `from` to `to` (network cycles, `from` not in the past), sent by node `by`.
fn jam(net: &mut Network, by: NodeId, channel: u8, from: u64, to: u64) {
    assert!(from >= net.cycle());
    let tx = Transmission {
        channel,
        pan_id: 0x1234,
        source: Address::Short(0xBEEF),
        source64: 0,
        dest: Address::Short(0xFFFF),
        options: 0,
        payload: vec![0; 4],
        start_cycle: from,
        end_cycle: to,
        frame_id: 0,
        mac: MacFields::default(),
        power_db: 0,
    };
    net.medium_mut().transmit(by, tx);
}

/// The data records of `from` in `log`.
fn data_from(log: &[TxRecord], from: NodeId) -> Vec<&TxRecord> {
    log.iter()
        .filter(|r| r.from == from && r.tx.mac.kind == FrameKind::Data)
        .collect()
}

fn outcome(r: &TxRecord, node: NodeId) -> Option<Outcome> {
    r.receivers
        .iter()
        .find(|x| x.node == node)
        .map(|x| x.outcome)
}

/// A CCA finds the channel busy when another packet is on air on its channel at the radio with
/// a level at or above `CA` (−dBm). Busy five times in a row: CCA failure, status 0x02, nothing
/// on air, `EC` counts it (and resets); clear: the packet goes on air (here into the jammer).
#[test]
fn cca_is_busy_at_and_above_the_threshold_by_distance_and_channel() {
    // (distance m, the level there, CA, jammer's channel, busy)
    let cases: [(f64, i16, u8, u8, bool); 8] = [
        (1.0, -40, 0x2C, CH, true),
        (1.5, -45, 0x2C, CH, false),
        (1.5, -45, 0x2D, CH, true),
        (1.5, -45, 0x2E, CH, true),
        (20.0, -79, 0x50, CH, true),
        (30.0, -84, 0x50, CH, false),
        (1.0, -40, 0x2C, CH + 1, false),
        (1.0, -40, 0x24, CH, false),
    ];
    for (d, level, ca, channel, busy) in cases {
        let mut net = network(1);
        let jammer = radio(&mut net, 9, [0.0, 0.0], 1, |_| {});
        let s = radio(&mut net, 1, [d, 0.0], 2, |c| c.ca = ca);
        settle(&mut net, &[jammer, s]);
        assert_eq!(
            Medium::quantise(net.medium().mean_level_dbm(jammer, s, CH, 0)),
            level
        );
        let t0 = net.cycle();
        jam(&mut net, jammer, channel, t0, t0 + ms_to_cycles(30.0));
        let request = tx16(&mut net, s, 7, 0xFFFF, 0, b"beacon");
        net.run_for_ms(40.0);
        let st = statuses(&frames(&mut net, s));
        assert_eq!(st.len(), 1, "{d} m, CA {ca:#x}");
        let (at, fid, status) = st[0];
        assert_eq!(fid, 7);
        let stats = net.core(s).stats();
        let sent = data_from(net.log(), s);
        if busy {
            assert_eq!(status, TxStatus::CCA_FAILURE, "{d} m, CA {ca:#x}");
            assert_eq!((stats.cca_busy, stats.cca_failures), (5, 1));
            assert!(sent.is_empty());
            // Five CCAs and the backoffs between them (RN = 0: none before the first).
            let spent = at - request;
            assert!(spent >= 5 * us(CCA_US), "{spent}");
            assert!(
                spent <= 5 * us(CCA_US) + 26 * us(BACKOFF_PERIOD_US),
                "{spent}"
            );
            assert_eq!(at_query(&mut net, s, b"EC"), [0, 1]);
            assert_eq!(at_query(&mut net, s, b"EA"), [0, 0]);
        } else {
            assert_eq!(status, TxStatus::SUCCESS, "{d} m, CA {ca:#x}");
            assert_eq!((stats.cca_busy, stats.cca_failures), (0, 0));
            assert_eq!(sent.len(), 1);
            assert_eq!(sent[0].tx.start_cycle, request + us(CCA_US + TURNAROUND_US));
            assert_eq!(sent[0].collided, channel == CH);
            assert_eq!(at, request + ms_to_cycles(time_on_air_ms(6)));
        }
    }
    // EC resets when set to 0.
    let mut net = network(1);
    let jammer = radio(&mut net, 9, [0.0, 0.0], 1, |_| {});
    let s = radio(&mut net, 1, [1.0, 0.0], 2, |_| {});
    settle(&mut net, &[jammer, s]);
    let t0 = net.cycle();
    jam(&mut net, jammer, CH, t0, t0 + ms_to_cycles(30.0));
    tx16(&mut net, s, 1, 0xFFFF, 0, b"x");
    net.run_for_ms(40.0);
    assert_eq!(at_query(&mut net, s, b"EC"), [0, 1]);
    let set = encode_frame(&[0x08, 0x43, b'E', b'C', 0x00], Mode::Escaped);
    let now = net.cycle();
    net.core_mut(s).rx_bytes(now, &set);
    net.run_for_ms(5.0);
    frames(&mut net, s);
    assert_eq!(at_query(&mut net, s, b"EC"), [0, 0]);
}

/// The backoffs, seeded: on a jammed channel with RN = 0 the five CCAs of a request are
/// separated by 0…2^BE − 1 periods with BE = 1, 2, 3, 4 (0…26 periods in all, 13 on average:
/// 4.8 ms to the CCA failure with the CCAs); on a clear channel with RN = 3 the only backoff is
/// the first, 0…7 periods, uniform. The same seed gives the same times, another seed others.
#[test]
fn backoffs_have_the_csma_ca_distribution_and_follow_the_seed() {
    let jammed = |seed: u64| {
        let mut net = network(1);
        let jammer = radio(&mut net, 9, [0.0, 0.0], 1, |_| {});
        let s = radio(&mut net, 1, [1.0, 0.0], seed, |_| {});
        settle(&mut net, &[jammer, s]);
        let t0 = net.cycle();
        jam(&mut net, jammer, CH, t0, t0 + ms_to_cycles(4000.0));
        let mut spent = Vec::new();
        for i in 0..300u16 {
            let request = tx16(&mut net, s, (i % 255 + 1) as u8, 0xFFFF, 0, b"x");
            net.run_for_ms(12.0);
            let st = statuses(&frames(&mut net, s));
            assert_eq!(st.len(), 1);
            assert_eq!(st[0].2, TxStatus::CCA_FAILURE);
            spent.push(st[0].0 - request);
        }
        assert_eq!(net.core(s).stats().cca_busy, 5 * 300);
        spent
    };
    let a = jammed(11);
    assert_eq!(a, jammed(11));
    assert_ne!(a, jammed(12));
    let period = us(BACKOFF_PERIOD_US);
    let cca = us(CCA_US);
    let periods: Vec<u64> = a
        .iter()
        .map(|&t| {
            assert_eq!((t - 5 * cca) % period, 0, "whole backoff periods");
            (t - 5 * cca) / period
        })
        .collect();
    assert!(periods.iter().all(|&p| p <= 26));
    let mean = periods.iter().sum::<u64>() as f64 / periods.len() as f64;
    // Variance of the sum: (3 + 15 + 63 + 255) / 12 = 28 periods²; standard error over 300
    // requests 0.31 periods.
    assert!((mean - 13.0).abs() < 1.2, "mean {mean} periods");
    assert!(periods.iter().any(|&p| p > 18) && periods.iter().any(|&p| p < 8));
    let mean_ms = a.iter().sum::<u64>() as f64 / a.len() as f64 / 16_000.0;
    eprintln!("CCA failure after {mean_ms:.2} ms on average (RN 0, 300 requests; 4.80 expected)");

    let clear = |seed: u64| {
        let mut net = network(1);
        let s = radio(&mut net, 1, [0.0, 0.0], seed, |c| c.rn = 3);
        settle(&mut net, &[s]);
        let mut first = Vec::new();
        for i in 0..400u16 {
            let request = tx16(&mut net, s, (i % 255 + 1) as u8, 0xFFFF, 0, b"x");
            net.run_for_ms(10.0);
            let log = net.take_log();
            let tx = &data_from(&log, s)[0].tx;
            let backoff = tx.start_cycle - request - us(CCA_US + TURNAROUND_US);
            assert_eq!(backoff % period, 0);
            first.push(backoff / period);
        }
        first
    };
    let b = clear(5);
    assert_eq!(b, clear(5));
    let mut counts = [0usize; 8];
    for &p in &b {
        counts[p as usize] += 1;
    }
    // 50 expected each; the binomial's σ is 6.6.
    assert!(counts.iter().all(|&c| (25..=75).contains(&c)), "{counts:?}");
}

/// A unicast is acknowledged by its receiver after the turnaround; the sender's status follows
/// the ACK's end. The ACK is a packet on the medium, logged after the data.
#[test]
fn a_unicast_is_acknowledged_and_the_status_follows_the_ack() {
    let mut net = network(2);
    let s = radio(&mut net, 1, [0.0, 0.0], 1, |_| {});
    let r = radio(&mut net, 2, [5.0, 0.0], 2, |_| {});
    settle(&mut net, &[s, r]);
    let request = tx16(&mut net, s, 0x21, 2, 0, b"report");
    net.run_for_ms(20.0);
    let end = request + ms_to_cycles(time_on_air_ms(6));
    let st = statuses(&frames(&mut net, s));
    assert_eq!(
        st,
        [(
            end + us(TURNAROUND_US + ACK_AIR_US),
            0x21,
            TxStatus::SUCCESS
        )]
    );
    assert_eq!(received(&frames(&mut net, r)), [b"report".to_vec()]);
    let log = net.log();
    assert_eq!(log.len(), 2);
    let (data, ack) = (&log[0], &log[1]);
    assert_eq!(data.tx.mac.kind, FrameKind::Data);
    assert!(data.tx.mac.ack_request);
    assert_eq!(outcome(data, r), Some(Outcome::Delivered));
    assert_eq!(ack.from, r);
    assert_eq!(ack.tx.mac.kind, FrameKind::Ack);
    assert_eq!(ack.tx.mac.seq, data.tx.mac.seq);
    assert_eq!(ack.tx.start_cycle, end + us(TURNAROUND_US));
    assert_eq!(ack.tx.end_cycle, end + us(TURNAROUND_US + ACK_AIR_US));
    assert_eq!(outcome(ack, s), Some(Outcome::Delivered));
    assert_eq!(net.core(r).stats().acks_sent, 1);
    assert_eq!(net.core(s).stats().acks_received, 1);
    // TX option 0x01: no ACK asked for, none sent; the status when the packet is off the air.
    let request = tx16(&mut net, s, 0x22, 2, 0x01, b"quiet");
    net.run_for_ms(20.0);
    let st = statuses(&frames(&mut net, s));
    assert_eq!(
        st,
        [(
            request + ms_to_cycles(time_on_air_ms(5)),
            0x22,
            TxStatus::SUCCESS
        )]
    );
    assert_eq!(net.log().len(), 3);
    assert!(!net.log()[2].tx.mac.ack_request);
}

/// No ACK (the receiver off, or on another channel): the MAC sends the packet four times in
/// all, each attempt a CSMA (here one clear CCA), the packet and the ACK wait, then status
/// 0x01; `EA` counts it. `RR` = 1 doubles the attempts.
#[test]
fn without_an_ack_the_mac_retries_and_reports_no_ack() {
    for (rr, off) in [(0u8, true), (0, false), (1, true)] {
        let mut net = network(1);
        let s = radio(&mut net, 1, [0.0, 0.0], 1, |c| c.rr = rr);
        let r = radio(&mut net, 2, [3.0, 0.0], 2, |c| c.ch = CH + 1);
        settle(&mut net, &[s, r]);
        if off {
            net.kill(r);
        }
        let payload = [0x5A; 40];
        let request = tx16(&mut net, s, 9, 2, 0, &payload);
        net.run_for_ms(60.0);
        let attempts = 4 * (u64::from(rr) + 1);
        let each = us(CCA_US + TURNAROUND_US) + frame_air_cycles(payload.len()) + us(ACK_WAIT_US);
        let st = statuses(&frames(&mut net, s));
        assert_eq!(
            st,
            [(request + attempts * each, 9, TxStatus::NO_ACK)],
            "RR {rr}, receiver off {off}"
        );
        let log = net.log();
        let sent = data_from(log, s);
        assert_eq!(sent.len() as u64, attempts);
        for (i, x) in sent.iter().enumerate() {
            assert_eq!(x.tx.mac.attempt as usize, i);
            assert_eq!(x.tx.mac.seq, sent[0].tx.mac.seq, "one sequence number");
            assert_eq!(
                x.tx.start_cycle,
                request + i as u64 * each + us(CCA_US + TURNAROUND_US)
            );
        }
        assert!(log.iter().all(|x| x.tx.mac.kind == FrameKind::Data));
        let stats = net.core(s).stats();
        assert_eq!(
            (stats.retries as u64, stats.ack_failures),
            (attempts - 1, 1)
        );
        assert_eq!(at_query(&mut net, s, b"EA"), [0, 1]);
    }
}

/// A retry whose first copy got through (its ACK collided): the receiver acknowledges it again
/// but passes it on once (`MM` 0, the Digi header's duplicate detection); in strict 802.15.4
/// (`MM` 2) it passes it on twice.
#[test]
fn a_retried_packet_is_passed_on_once_in_digi_mode() {
    for mm in [0u8, 2] {
        let mut net = network(1);
        let s = radio(&mut net, 1, [0.0, 0.0], 1, |c| c.mm = mm);
        let r = radio(&mut net, 2, [4.0, 0.0], 2, |c| c.mm = mm);
        let jammer = radio(&mut net, 9, [2.0, 3.0], 3, |_| {});
        settle(&mut net, &[s, r, jammer]);
        let request = tx16(&mut net, s, 3, 2, 0, b"once");
        let end = request + ms_to_cycles(time_on_air_ms(4));
        // Past the packet's end: delivered, its ACK decided; then a burst over the ACK.
        net.run_until(end + us(50));
        jam(&mut net, jammer, CH, end + us(250), end + us(300));
        net.run_for_ms(20.0);
        let st = statuses(&frames(&mut net, s));
        assert_eq!(st.len(), 1);
        assert_eq!(st[0].2, TxStatus::SUCCESS);
        let got = received(&frames(&mut net, r));
        let log = net.log();
        let sent = data_from(log, s);
        assert_eq!(sent.len(), 2, "MM {mm}");
        assert_eq!(outcome(sent[0], r), Some(Outcome::Delivered));
        let acks: Vec<_> = log
            .iter()
            .filter(|x| x.tx.mac.kind == FrameKind::Ack)
            .collect();
        assert_eq!(acks.len(), 2);
        assert!(acks[0].collided);
        assert_eq!(outcome(acks[1], s), Some(Outcome::Delivered));
        if mm == 0 {
            assert_eq!(outcome(sent[1], r), Some(Outcome::Duplicate));
            assert_eq!(got, [b"once".to_vec()]);
            assert_eq!(net.core(r).stats().rx_duplicates, 1);
        } else {
            assert_eq!(outcome(sent[1], r), Some(Outcome::Delivered));
            assert_eq!(got, [b"once".to_vec(), b"once".to_vec()]);
        }
        assert_eq!(net.core(r).stats().acks_sent, 2);
    }
}

/// A broadcast asks for no ACK, is sent once, and its status comes when it is off the air.
#[test]
fn a_broadcast_is_sent_once_without_an_ack() {
    let mut net = network(1);
    let s = radio(&mut net, 1, [0.0, 0.0], 1, |_| {});
    let r = radio(&mut net, 2, [2.0, 0.0], 2, |_| {});
    settle(&mut net, &[s, r]);
    net.kill(r);
    let request = tx16(&mut net, s, 5, 0xFFFF, 0, b"hello all");
    net.run_for_ms(20.0);
    let st = statuses(&frames(&mut net, s));
    assert_eq!(
        st,
        [(
            request + ms_to_cycles(time_on_air_ms(9)),
            5,
            TxStatus::SUCCESS
        )]
    );
    let log = net.log();
    assert_eq!(log.len(), 1);
    assert!(!log[0].tx.mac.ack_request);
    assert_eq!(net.core(s).stats().retries, 0);
}

/// `RR` > 0 repeats a broadcast (`RR` + 2 copies, Digi's S1 manual): each copy goes through
/// channel access after the one before, all are on air (as long as five packets), and a
/// receiver in the factory MAC mode passes the first on and drops the others as duplicates.
#[test]
fn a_broadcast_with_rr_is_repeated_and_its_receivers_pass_on_one_copy() {
    let mut net = network(1);
    let s = radio(&mut net, 1, [0.0, 0.0], 1, |c| c.rr = 3);
    let r = radio(&mut net, 2, [2.0, 0.0], 2, |_| {});
    settle(&mut net, &[s, r]);
    let request = tx16(&mut net, s, 5, 0xFFFF, 0, b"beacon");
    net.run_for_ms(30.0);
    let toa = ms_to_cycles(time_on_air_ms(6));
    assert_eq!(
        statuses(&frames(&mut net, s)),
        [(request + 5 * toa, 5, TxStatus::SUCCESS)],
        "the status after the fifth copy"
    );
    assert_eq!(received(&frames(&mut net, r)), [b"beacon".to_vec()]);
    let log = net.log();
    let sent = data_from(log, s);
    assert_eq!(sent.len(), 5);
    for (i, x) in sent.iter().enumerate() {
        assert_eq!(x.tx.mac.attempt as usize, i);
        assert!(!x.collided);
        // RN 0 on a clear channel: a CCA and the turnaround after the copy before.
        let after = if i == 0 {
            request
        } else {
            sent[i - 1].tx.end_cycle
        };
        assert_eq!(x.tx.start_cycle, after + us(CCA_US + TURNAROUND_US));
        let want = if i == 0 {
            Outcome::Delivered
        } else {
            Outcome::Duplicate
        };
        assert_eq!(outcome(x, r), Some(want));
    }
    assert_eq!(log.len(), 5, "no ACKs");
    let st = net.core(s).stats();
    assert_eq!((st.transmissions, st.repeats, st.retries), (5, 4, 0));
    assert_eq!(net.core(r).stats().rx_duplicates, 4);
}

/// A radio's power level (`PL`) lowers the level its packets have at every receiver by what
/// its model's table takes off (an S1's `PL` 0: 10 dB): the RSSI its receivers report, and what
/// other radios' clear channel assessments compare with `CA`. Its ACKs too.
#[test]
fn a_lower_power_level_lowers_the_level_at_every_receiver() {
    for (pl_s, pl_r, rssi, ack_level, cca_busy) in [(4, 4, 40, -40, true), (0, 2, 50, -44, false)] {
        let mut net = network(1);
        let s = radio(&mut net, 1, [0.0, 0.0], 1, |c| {
            c.leftovers = vec![(*b"PL", pl_s)];
        });
        let r = radio(&mut net, 2, [1.0, 0.0], 2, |c| {
            c.leftovers = vec![(*b"PL", pl_r)];
        });
        let c = radio(&mut net, 3, [0.0, 1.0], 3, |_| {});
        settle(&mut net, &[s, r, c]);
        // A long unicast from s; c asks to send during it (its CCA: −40 or −50 dBm against −44).
        let request = tx16(&mut net, s, 1, 2, 0, &[0x55; 100]);
        net.run_until(request + ms_to_cycles(1.0));
        tx16(&mut net, c, 2, 0xFFFF, 0, b"x");
        net.run_for_ms(30.0);
        let f = frames(&mut net, r);
        let rx = f
            .iter()
            .find_map(|(_, d)| match Frame::parse(d) {
                Ok(Frame::Rx16 { rssi, .. }) => Some(rssi.raw()),
                _ => None,
            })
            .expect("received");
        assert_eq!(rx, rssi, "PL {pl_s}");
        let log = net.log();
        let data = data_from(log, s)[0];
        assert_eq!(data.tx.power_db, Model::S1.power_db(pl_s as u8));
        let at_r = data.receivers.iter().find(|x| x.node == r).unwrap();
        assert_eq!(at_r.rssi_dbm, -i16::from(rssi));
        let ack = log
            .iter()
            .find(|x| x.tx.mac.kind == FrameKind::Ack)
            .expect("an ACK");
        let at_s = ack.receivers.iter().find(|x| x.node == s).unwrap();
        assert_eq!(at_s.rssi_dbm, ack_level);
        assert_eq!(net.core(c).stats().cca_busy > 0, cca_busy, "PL {pl_s}");
    }
}

/// One trial of two senders 1 m apart (each −40 dBm at the other, over the factory CA of
/// −44 dBm) whose packets to `dest` (a receiver 1 m from both, address 3, or broadcast) are
/// requested at the same cycle.
struct Trial {
    /// Of the two, the packets the receiver passed on.
    passed: usize,
    /// Of the two, the ones whose status said success.
    ok: usize,
    /// The first attempts of both went on air overlapping.
    first_collided: bool,
}

fn same_slot(seed: u64, csma: bool, rn: u8, dest: u16) -> Trial {
    let mut net = network(1);
    let set = |c: &mut XBeeConfig| {
        c.rn = rn;
        if !csma {
            c.csma = Csma::Off;
        }
    };
    let a = radio(&mut net, 1, [0.0, 0.0], seed, set);
    let b = radio(&mut net, 2, [1.0, 0.0], seed ^ 0x5555, set);
    let r = radio(&mut net, 3, [0.5, 0.866], seed ^ 0xAAAA, |_| {});
    settle(&mut net, &[a, b, r]);
    // A report-sized payload.
    let payload = [0x11; 60];
    let now = net.cycle();
    let bytes = |fid: u8| {
        let mut d = vec![0x01, fid];
        d.extend_from_slice(&dest.to_be_bytes());
        d.push(0);
        d.extend_from_slice(&payload);
        encode_frame(&d, Mode::Escaped)
    };
    let ea = net.core_mut(a).rx_bytes(now, &bytes(1));
    let eb = net.core_mut(b).rx_bytes(now, &bytes(2));
    assert_eq!(ea, eb);
    net.run_for_ms(80.0);
    let passed = received(&frames(&mut net, r)).len();
    let st: Vec<TxStatus> = statuses(&frames(&mut net, a))
        .into_iter()
        .chain(statuses(&frames(&mut net, b)))
        .map(|x| x.2)
        .collect();
    assert_eq!(st.len(), 2);
    let first = |n: NodeId| data_from(net.log(), n).first().map(|x| x.collided);
    Trial {
        passed,
        ok: st.iter().filter(|&&s| s == TxStatus::SUCCESS).count(),
        first_collided: first(a) == Some(true) && first(b) == Some(true),
    }
}

/// Two senders whose requests come at the same cycle: without carrier sense they go on air
/// together and collide at every retry; with the CSMA-CA (RN = 3, 802.15.4's macMinBE) the one
/// that draws the later backoff finds the other on air and defers, so most pairs get through:
/// broadcasts unless both drew the same backoff (1 in 8), unicasts nearly always (a retry draws
/// again). With the factory RN = 0 there is no backoff to draw: both assess the channel in the
/// same instant, find it clear and collide, at every retry too. Prints the shares.
#[test]
fn same_slot_senders_mostly_get_through_with_carrier_sense_and_collide_without() {
    const TRIALS: u64 = 200;
    let run = |csma: bool, rn: u8, dest: u16| {
        let (mut passed, mut ok, mut first) = (0, 0, 0);
        for seed in 0..TRIALS {
            let t = same_slot(seed * 7919 + 1, csma, rn, dest);
            passed += t.passed;
            ok += t.ok;
            first += usize::from(t.first_collided);
        }
        let pct = |n: usize, of: u64| 100.0 * n as f64 / of as f64;
        let (passed, ok, first) = (
            pct(passed, 2 * TRIALS),
            pct(ok, 2 * TRIALS),
            pct(first, TRIALS),
        );
        let what = if dest == 0xFFFF {
            "broadcasts"
        } else {
            "unicasts"
        };
        let how = if csma {
            format!("CSMA-CA, RN {rn}")
        } else {
            "no carrier sense".to_string()
        };
        eprintln!(
            "same-slot {what}, {how}: {passed:.1} % passed on, {ok:.1} % status success, \
             first attempts collided in {first:.1} % of the pairs"
        );
        (passed, ok, first)
    };
    let (passed, ok, first) = run(true, 3, 3);
    assert!(passed >= 95.0 && ok >= 95.0, "{passed} {ok}");
    assert!(first > 5.0 && first < 20.0, "{first}");
    let (passed, _, first) = run(true, 3, 0xFFFF);
    assert!(passed >= 75.0, "{passed}");
    assert!(first > 5.0 && first < 20.0, "{first}");
    assert_eq!(run(true, 0, 3), (0.0, 0.0, 100.0));
    assert_eq!(run(false, 3, 3), (0.0, 0.0, 100.0));
    let (passed, ok, first) = run(false, 3, 0xFFFF);
    assert_eq!((passed, first), (0.0, 100.0));
    assert_eq!(ok, 100.0, "a broadcast's status says nothing of its fate");
}

/// Unicasts between radios with the CSMA-CA at seeded pseudo-random times, collisions and
/// busy channels included: the log and every radio's output are the same for 1, 2 and 3
/// threads.
#[test]
fn mac_results_do_not_depend_on_the_number_of_threads() {
    let run = |threads: usize| {
        let mut net = network(threads);
        let ids: Vec<NodeId> = (0..6u16)
            .map(|i| {
                radio(
                    &mut net,
                    i + 1,
                    [f64::from(i) * 0.8, 0.0],
                    u64::from(i),
                    |c| c.rn = 1,
                )
            })
            .collect();
        settle(&mut net, &ids);
        let mut x: u64 = 777;
        let mut out = Vec::new();
        for k in 0..300u32 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let who = ids[(x % 6) as usize];
            let dest = if x.is_multiple_of(5) {
                0xFFFF
            } else {
                ((x >> 8) % 6 + 1) as u16
            };
            if net.core(who).tx_queue() == (0, false) {
                tx16(
                    &mut net,
                    who,
                    (k % 200 + 1) as u8,
                    dest,
                    0,
                    &x.to_le_bytes(),
                );
            }
            net.run_for_ms((x >> 16) as f64 % 2.0);
            for &id in &ids {
                out.push(frames(&mut net, id));
            }
        }
        net.run_for_ms(50.0);
        (net.take_log(), out)
    };
    let one = run(1);
    assert!(one.0.iter().any(|r| r.collided));
    assert!(one.0.iter().any(|r| r.tx.mac.kind == FrameKind::Ack));
    assert!(one.0.iter().any(|r| r.tx.mac.attempt > 0));
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
}

/// A radio stepped ahead of the medium (a firmware node's radio runs with its MCU, which may
/// sleep past a packet's end before the medium hands the packet over) acknowledges a turnaround
/// after the packet's end all the same, not a turnaround after it got to handle it: the sender
/// waits only [`ACK_WAIT_US`] for it.
#[test]
fn the_ack_goes_a_turnaround_after_the_packet_even_when_the_radio_ran_ahead() {
    let mut cfg = XBeeConfig::api(2);
    cfg.my = 2;
    cfg.ch = CH;
    let pan_id = cfg.id;
    let mut core = XBeeCore::new_at(cfg, 0);
    core.set_on_medium(true);
    core.advance(ms_to_cycles(50.0));
    assert!(core.is_ready());
    core.take_output();
    for (i, ahead_us) in [0u64, 100, 700, 950].into_iter().enumerate() {
        // Packets 10 ms apart.
        let end = ms_to_cycles(60.0 + 10.0 * i as f64);
        core.advance(end + us(ahead_us));
        let tx = Transmission {
            channel: CH,
            pan_id,
            source: Address::Short(1),
            source64: 0x0013_A200_0000_0001,
            dest: Address::Short(2),
            options: 0,
            payload: b"report".to_vec(),
            start_cycle: end - frame_air_cycles(6),
            end_cycle: end,
            frame_id: 0,
            mac: MacFields {
                kind: FrameKind::Data,
                seq: ahead_us as u8,
                ack_request: true,
                attempt: 0,
            },
            power_db: 0,
        };
        core.receive(&tx, -50, Security::Clear);
        core.advance(end + us(2000));
        let acks = core.take_transmissions();
        assert_eq!(acks.len(), 1, "{ahead_us} µs ahead");
        assert_eq!(acks[0].mac.kind, FrameKind::Ack);
        assert_eq!(acks[0].mac.seq, ahead_us as u8);
        assert_eq!(
            acks[0].start_cycle,
            end + us(TURNAROUND_US),
            "{ahead_us} µs ahead"
        );
    }
}
