//! The node firmwares together on one emulated network (`simavr::network`): boot in parallel,
//! each bringing its modelled radio up; the same results with 1 and 2 threads; a node powered
//! off and on again reboots; UART noise is counted.

use hoploc_tests::firmware_elf;
use loc_proto::line::{BootLine, ConfigSource, RadioFound};
use loc_proto::{xbee_channel, Role, DEFAULT_PAN_ID};
use simavr::medium::{Antenna, Medium, MediumConfig, NodeRadio};
use simavr::ms_to_cycles;
use simavr::network::{Network, NetworkConfig, NodeSpec};

/// Anchor, agent, sink, anchor: at the corners of a 7 m square, chip antennas, default medium.
fn testbed(threads: usize, uart_error_rate: f64) -> Network {
    let mut net = Network::with_config(
        Medium::new(MediumConfig::default()),
        NetworkConfig {
            threads,
            uart_error_rate,
            ..NetworkConfig::default()
        },
    );
    let nodes = [
        (Role::Anchor, 0.0, 0.0),
        (Role::Agent, 3.5, 3.5),
        (Role::Sink, 7.0, 0.0),
        (Role::Anchor, 7.0, 7.0),
    ];
    for (i, (role, x, y)) in nodes.into_iter().enumerate() {
        let mut spec = NodeSpec::new(
            format!("{}{i}", role.name()),
            NodeRadio {
                antenna: Antenna::Chip,
                orientation_deg: 45.0 * i as f64,
                ..NodeRadio::at(x, y)
            },
        );
        spec.xbee.sh_sl = 0x0013_A200_4000_0000 + i as u64;
        net.add_node(firmware_elf(role), spec).unwrap();
    }
    net
}

/// Each firmware first listens 2 s for a provisioning frame, then brings its radio up (API mode
/// already, a few tens of ms); up within this.
const RADIO_UP_MS: f64 = loc_proto::provision::PROVISION_WINDOW_MS as f64 + 300.0;

fn role_of(net: &Network, id: usize) -> Role {
    Role::from_name(
        net.spec(id)
            .name
            .trim_end_matches(|c: char| c.is_ascii_digit()),
    )
    .unwrap()
}

fn boot_lines(net: &Network, id: usize) -> Vec<(f64, BootLine)> {
    net.lines(id)
        .iter()
        .filter_map(|l| BootLine::parse(&l.text).ok().map(|b| (l.ms(), b)))
        .collect()
}

#[test]
fn four_firmwares_boot_together_and_bring_their_radios_up() {
    let mut net = testbed(2, 0.0);
    net.run_for_ms(RADIO_UP_MS);
    for id in 0..net.len() {
        let role = role_of(&net, id);
        let lines = boot_lines(&net, id);
        assert_eq!(
            lines.iter().map(|(_, b)| *b).collect::<Vec<_>>(),
            [
                BootLine::Boot { role },
                BootLine::Config {
                    role,
                    source: ConfigSource::Eeprom,
                    id: 1
                },
                BootLine::RadioUp {
                    role,
                    found: RadioFound::Api
                }
            ],
            "node {id}"
        );
        assert!(lines[2].0 > 5.0, "after the radio's power-up: {lines:?}");
        let r = net.core(id).registers();
        assert_eq!(r.ap(), 2);
        assert_eq!(r.my(), role.address(1));
        assert_eq!(r.id(), DEFAULT_PAN_ID);
        // Anchors and agents tune to their first channel after the bring-up, the sink stays.
        assert_eq!(r.ch(), xbee_channel(role.boot_channel()).unwrap());
        assert!(net.state(id).is_alive());
    }
}

/// 4.3 s: boot, provisioning window, radio bring-up, listening, then both anchors (both anchor 1 with the default config) beacon in
/// the same slot and collide. Lines, radio traffic and the medium's log are identical for 1
/// and 2 threads.
#[test]
fn a_network_run_is_the_same_with_one_and_two_threads() {
    let run = |threads| {
        let mut net = testbed(threads, 0.0);
        net.run_for_ms(4300.0);
        let lines: Vec<_> = (0..net.len()).map(|id| net.lines(id)).collect();
        let sent: Vec<_> = (0..net.len())
            .map(|id| net.firmware(id).unwrap().1.sent().to_vec())
            .collect();
        (net.take_log(), lines, sent, net.cycle())
    };
    let one = run(1);
    assert!(!one.0.is_empty(), "the anchors beaconed");
    assert!(one.0.iter().any(|r| r.collided), "two anchor 1s collide");
    assert_eq!(one, run(2));
}

#[test]
fn a_node_powered_off_and_on_boots_again_with_its_radio() {
    let mut net = testbed(2, 0.0);
    net.run_for_ms(RADIO_UP_MS);
    net.kill(0);
    net.run_for_ms(300.0);
    assert_eq!(boot_lines(&net, 0).len(), 3, "nothing while off");
    net.revive(0).unwrap();
    let back = net.cycle();
    assert_eq!(net.offset(0), back);
    net.run_for_ms(RADIO_UP_MS);
    let lines = boot_lines(&net, 0);
    assert_eq!(lines.len(), 6, "{lines:?}");
    assert!(matches!(lines[3].1, BootLine::Boot { .. }));
    let back_ms = simavr::cycles_to_ms(back);
    assert!(
        lines[3].0 >= back_ms && lines[3].0 < back_ms + 1.0,
        "{lines:?}"
    );
    assert!(matches!(lines[5].1, BootLine::RadioUp { .. }));
    assert!(lines[5].0 > back_ms + 5.0, "{lines:?}");
    assert_eq!(net.cycle(), back + ms_to_cycles(RADIO_UP_MS));
    // Reading on from any line gives the rest, across the two lives.
    let all = net.lines(0);
    for from in 0..=all.len() + 1 {
        let rest = net.lines_from(0, from);
        assert_eq!(rest.len(), all.len().saturating_sub(from), "from {from}");
        for (a, b) in rest.iter().zip(all.iter().skip(from)) {
            assert_eq!((a.cycle, &a.text), (b.cycle, &b.text), "from {from}");
        }
    }
    // The others went on meanwhile: one life each.
    assert_eq!(boot_lines(&net, 3).len(), 3);
}

/// A bit error in one UART byte in a hundred on every firmware↔radio line: errors happen,
/// reproducibly.
#[test]
fn uart_noise_is_seeded() {
    let run = || {
        let mut net = testbed(2, 1e-2);
        net.run_for_ms(RADIO_UP_MS);
        (0..net.len())
            .map(|id| net.firmware(id).unwrap().1.line_errors())
            .collect::<Vec<_>>()
    };
    let errors = run();
    assert!(errors.iter().sum::<u64>() > 0, "{errors:?}");
    assert_eq!(errors, run());
}
