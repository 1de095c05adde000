//! Four anchors and an agent, each its real firmware with its own EEPROM config, on one emulated
//! network with a noise-free medium (`simavr::network`): the anchors find one timeline and
//! beacon in their own slots (never two in one slot), the agent reports every superframe, and
//! when anchor 1 is powered off anchor 2 takes over on the same slots, and hands back when
//! anchor 1 returns (`loc_proto::schedule::Timeline`).

use hoploc_tests::firmware_elf;
use loc_proto::config::Config;
use loc_proto::msg::{Beacon, Position, Report};
use loc_proto::schedule::{Schedule, SILENT_SUPERFRAMES};
use loc_proto::Role;
use simavr::cycles_to_ms;
use simavr::medium::{Medium, MediumConfig, NodeRadio};
use simavr::network::{Network, NodeSpec, TxRecord};
use simavr::xbee::DI_BUFFER_BYTES;

const CORNERS: [[i16; 2]; 4] = [[0, 0], [1000, 0], [1000, 1000], [0, 1000]];
/// Slot timing error allowed between two anchors, ms: the firmware's 1 ms (asserted with
/// real-hardware UART timing in tests/anchor.rs and tests/agent.rs), plus what simavr's UART adds
/// here: it counts 11 bit times per byte (`simavr::Avr::uart_cycles_per_byte`), 192.5 µs at the
/// AVR's 57 143 baud against the 173.6 µs the beacon latency assumes, over the 26-byte TX frame
/// and the RX frame's delimiter (0.51 ms).
const SLOT_ERROR_MS: f64 = 1.0 + 27.0 * (0.1925 - 0.1736);

fn config(role: Role, id: u8, position: [i16; 2]) -> Vec<u8> {
    let c = Config {
        role,
        id,
        position: Position {
            x: position[0],
            y: position[1],
        },
        ..Config::DEFAULT
    };
    let mut buf = [0; 32];
    let n = c.to_bytes(&mut buf).unwrap();
    buf[..n].to_vec()
}

/// Nodes 0…3: anchors 1…4 at the corners; node 4: agent 1 at (3 m, 6 m).
fn testbed() -> Network {
    let mut net = Network::new(Medium::new(MediumConfig::noise_free()));
    for (i, p) in CORNERS.iter().enumerate() {
        let mut spec = NodeSpec::new(
            format!("anchor{}", i + 1),
            NodeRadio::at(p[0] as f64 / 100.0, p[1] as f64 / 100.0),
        );
        spec.eeprom = config(Role::Anchor, i as u8 + 1, *p);
        spec.xbee.sh_sl += i as u64;
        net.add_node(firmware_elf(Role::Anchor), spec).unwrap();
    }
    let mut spec = NodeSpec::new("agent1", NodeRadio::at(3.0, 6.0));
    spec.eeprom = config(Role::Agent, 1, [0, 0]);
    spec.xbee.sh_sl += 9;
    net.add_node(firmware_elf(Role::Agent), spec).unwrap();
    net
}

/// The anchors' beacons in `log`: (air start ms, sender node, beacon).
fn beacons(log: &[TxRecord]) -> Vec<(f64, usize, Beacon)> {
    log.iter()
        .filter_map(|r| {
            Beacon::decode(&r.tx.payload)
                .ok()
                .map(|b| (cycles_to_ms(r.tx.start_cycle), r.from, b))
        })
        .collect()
}

/// No two packets on air at once, and every beacon is in its anchor's slot of the timeline
/// that anchor `reference`'s beacons of the same superframe give.
fn check_slots(log: &[TxRecord], s: &Schedule) {
    assert!(log.iter().all(|r| !r.collided), "a collision");
    let b = beacons(log);
    let slot = s.slot_us() as f64 / 1000.0;
    for (t, _, x) in &b {
        // Any other anchor's beacon of the same superframe and channel fixes the timeline.
        for (u, _, y) in &b {
            if y.seq == x.seq && y.channel == x.channel && y.anchor != x.anchor {
                let want = (x.anchor as f64 - y.anchor as f64) * slot;
                assert!(
                    (t - u - want).abs() <= SLOT_ERROR_MS,
                    "anchor {} vs {} in superframe {}: {} ms apart, want {want}",
                    x.anchor,
                    y.anchor,
                    x.seq,
                    t - u
                );
            }
        }
    }
}

#[test]
fn four_anchors_share_one_timeline_and_the_agent_reports_every_superframe() {
    let s = Schedule::for_config(&Config::DEFAULT).unwrap();
    let sf = s.superframe_us() as f64 / 1000.0;
    let mut net = testbed();
    // Provisioning window, bring-up, anchor 4 listening 5 superframes: all up within 7 s.
    net.run_for_ms(7_000.0);
    let _ = net.take_log();
    net.run_for_ms(10.0 * sf);
    let log = net.take_log();
    check_slots(&log, &s);
    let b = beacons(&log);
    for anchor in 1..=4u8 {
        let n = b.iter().filter(|(_, _, x)| x.anchor == anchor).count();
        assert!(n >= 19, "anchor {anchor}: {n} beacons in 10 superframes");
    }
    // One report per superframe, consecutive, with every anchor heard on both channels at the
    // medium's level for its distance. (No sink here acknowledges them: the agent's radio sends
    // each four times; its first transmission counts.)
    let reports: Vec<Report> = log
        .iter()
        .filter(|r| r.tx.mac.attempt == 0)
        .filter_map(|r| Report::decode(&r.tx.payload).ok())
        .collect();
    assert!(reports.len() >= 9, "{}", reports.len());
    for w in reports.windows(2) {
        assert_eq!(w[1].seq, w[0].seq.wrapping_add(1));
    }
    let medium = net.medium();
    for r in &reports[1..] {
        for (i, corner) in CORNERS.iter().enumerate() {
            let want = -Medium::quantise(medium.mean_level_dbm(i, 4, 0x0B, 0));
            for c in 0..2 {
                assert_eq!(r.rssi[c][i] as i16, want, "anchor {} ch {c}", i + 1);
            }
            assert_eq!(
                r.positions[i],
                Position {
                    x: corner[0],
                    y: corner[1]
                }
            );
        }
    }
    // One frame per slot never fills a radio's serial receive buffer, not even the agent's,
    // whose unacknowledged reports keep its radio busy with retries while it writes its channel
    // changes: each stays under half of it.
    for id in 0..net.len() {
        let st = net.core(id).stats();
        eprintln!("node {id}: serial receive buffer peak {} bytes", st.di_peak);
        assert_eq!(st.di_overflow, 0, "node {id}");
        assert!(
            (st.di_peak as usize) < DI_BUFFER_BYTES / 2,
            "node {id}: {} bytes",
            st.di_peak
        );
    }
}

#[test]
fn anchor_2_takes_over_when_anchor_1_is_off_and_hands_back() {
    let s = Schedule::for_config(&Config::DEFAULT).unwrap();
    let sf = s.superframe_us() as f64 / 1000.0;
    let mut net = testbed();
    net.run_for_ms(7_000.0);
    let _ = net.take_log();
    net.kill(0);
    let killed = net.time_ms();
    net.run_for_ms(8.0 * sf);
    let off = net.take_log();
    net.revive(0).unwrap();
    net.run_for_ms(3_000.0 + 8.0 * sf);
    let back = net.take_log();
    // Without anchor 1: the others go on, in their slots, and stay in step with each other.
    check_slots(&off, &s);
    let b = beacons(&off);
    assert!(b.iter().all(|(_, _, x)| x.anchor != 1));
    // Anchor 2 beacons on once the others have taken anchor 1 as gone.
    let after_silence = killed + (SILENT_SUPERFRAMES + 1) as f64 * sf;
    assert!(b
        .iter()
        .any(|(t, _, x)| *t > after_silence && x.anchor == 2));
    // Anchor 1 back: after its listening it beacons again in slot 1, no collision anywhere.
    check_slots(&back, &s);
    let b = beacons(&back);
    assert!(b.iter().filter(|(_, _, x)| x.anchor == 1).count() >= 8);
}
