//! Provisioning against the real firmware in simavr, on a modelled XBee already in API mode 2:
//! `hoploc provision`'s [`Provisioner`] talks to the node's UART in simulated time (as the Uno's
//! USB serial would), the node stores the config in EEPROM, answers, and runs with it — at once
//! and after a reset (the ELF reloaded with the EEPROM kept). A corrupt EEPROM is never run with;
//! a frame for another role is refused.
//!
//! simavr loads the ELF's `.eeprom` section into the EEPROM (as `avrdude -U eeprom:w:fw.elf:e`
//! would), so a freshly loaded node holds its built-in config; the tests that need a board
//! flashed through the bootloader (EEPROM never written) erase it first.

use hoploc::provision::{ProvisionError, Provisioner};
use hoploc_tests::{boot, firmware_elf, led_on};
use loc_proto::config::{Config, MAX_LEN, WRONG_ROLE};
use loc_proto::line::{BootLine, ConfigSource, RadioFound};
use loc_proto::msg::Position;
use loc_proto::provision::{encode, PROVISION_WINDOW_MS};
use loc_proto::Role;
use simavr::xbee::{XBee, XBeeConfig};
use simavr::{ms_to_cycles, Avr};

fn anchor2() -> Config {
    Config {
        id: 2,
        position: Position { x: 700, y: 0 },
        ..Config::DEFAULT
    }
}

fn erased(role: Role) -> Avr {
    let mut avr = boot(role);
    avr.eeprom_write(0, &[0xFF; 1024]).unwrap();
    avr
}

fn lines(radio: &XBee) -> Vec<BootLine> {
    radio
        .texts()
        .iter()
        .filter_map(|t| BootLine::parse(t).ok())
        .collect()
}

/// Runs `prov` against the node in 1 ms steps (its bytes to the node go on the UART's RX line as
/// soon as it asks), until it has a result or `timeout_ms` passes; returns the time it ended.
fn provision(avr: &mut Avr, radio: &mut XBee, prov: &mut Provisioner, timeout_ms: f64) -> f64 {
    let mut seen = 0;
    let end = avr.cycle() + ms_to_cycles(timeout_ms);
    while prov.result().is_none() {
        if avr.cycle() >= end {
            prov.timed_out();
            break;
        }
        radio.run_until(avr, avr.cycle() + ms_to_cycles(1.0));
        let out: Vec<u8> = avr.uart_output()[seen..].iter().map(|b| b.byte).collect();
        seen = avr.uart_output().len();
        if let Some(frame) = prov.receive(&out) {
            avr.uart_send(&frame);
        }
    }
    avr.time_ms()
}

/// The UART output as bytes (text, replies and API frames together).
fn output(avr: &Avr) -> Vec<u8> {
    avr.uart_output().iter().map(|b| b.byte).collect()
}

fn contains(hay: &[u8], needle: &[u8]) -> bool {
    hay.windows(needle.len()).any(|w| w == needle)
}

#[test]
fn the_elf_carries_the_built_in_config_in_its_eeprom_section() {
    // simavr loads the `.eeprom` section, so this is also what an ISP-flashed board holds.
    for role in Role::ALL {
        let avr = Avr::load(firmware_elf(role)).unwrap();
        let mut want = [0u8; MAX_LEN];
        let n = Config::default_for(role).to_bytes(&mut want).unwrap();
        assert_eq!(avr.eeprom_read(0, n).unwrap(), want[..n], "{role:?}");
        assert_eq!(
            avr.eeprom_read(n, 4).unwrap(),
            [0xFF; 4],
            "{role:?}: the rest is erased"
        );
    }
}

#[test]
fn provisioning_an_erased_anchor_then_it_runs_with_the_new_config_also_after_a_reset() {
    let mut avr = erased(Role::Anchor);
    let mut radio = XBee::new(XBeeConfig::api(2));
    let mut prov = Provisioner::new(anchor2()).unwrap();
    let done = provision(&mut avr, &mut radio, &mut prov, 3000.0);
    assert!(matches!(prov.result(), Some(Ok(()))), "{:?}", prov.result());
    // Inside the window (the frame goes right after the boot line; ~70 ms of EEPROM writes).
    assert!(done < PROVISION_WINDOW_MS as f64, "{done} ms");
    let mut want = [0u8; MAX_LEN];
    let n = anchor2().to_bytes(&mut want).unwrap();
    assert_eq!(avr.eeprom_read(0, n).unwrap(), want[..n]);

    // It goes on with the stored config at once: MY = anchor 2 on the radio.
    radio.run_for_ms(&mut avr, 300.0);
    let role = Role::Anchor;
    assert_eq!(
        lines(&radio),
        [
            BootLine::Boot { role },
            BootLine::Provisioned { role },
            BootLine::Config {
                role,
                source: ConfigSource::Eeprom,
                id: 2
            },
            BootLine::RadioUp {
                role,
                found: RadioFound::Api
            },
        ]
    );
    assert_eq!(radio.registers().get(*b"MY"), Some(2));

    // Power-cycle: the same ELF, the EEPROM kept, a fresh radio; nobody provisions.
    let ee = avr.eeprom_read(0, 1024).unwrap();
    let mut avr = boot(Role::Anchor);
    avr.eeprom_write(0, &ee).unwrap();
    let mut radio = XBee::new(XBeeConfig::api(2));
    radio.run_for_ms(&mut avr, PROVISION_WINDOW_MS as f64 + 300.0);
    assert_eq!(
        lines(&radio),
        [
            BootLine::Boot { role },
            BootLine::Config {
                role,
                source: ConfigSource::Eeprom,
                id: 2
            },
            BootLine::RadioUp {
                role,
                found: RadioFound::Api
            },
        ]
    );
    assert_eq!(radio.registers().get(*b"MY"), Some(2));
    assert_eq!(radio.registers().get(*b"ID"), Some(0x3332));
}

#[test]
fn an_erased_node_runs_with_its_built_in_config_after_the_window() {
    let mut avr = erased(Role::Sink);
    let mut radio = XBee::new(XBeeConfig::api(2));
    radio.run_for_ms(&mut avr, PROVISION_WINDOW_MS as f64 + 300.0);
    let role = Role::Sink;
    let texts = radio.text_lines();
    assert_eq!(
        lines(&radio),
        [
            BootLine::Boot { role },
            BootLine::Config {
                role,
                source: ConfigSource::BuiltIn,
                id: 1
            },
            BootLine::RadioUp {
                role,
                found: RadioFound::Api
            },
        ]
    );
    // The config line comes when the window closes, not before.
    let config_ms = texts[1].ms();
    assert!(
        (PROVISION_WINDOW_MS as f64..PROVISION_WINDOW_MS as f64 + 20.0).contains(&config_ms),
        "{config_ms}"
    );
    assert_eq!(
        radio.registers().get(*b"MY"),
        Some(Role::Sink.address(1) as u32)
    );
    // The sink's radio is on the sink channel.
    assert_eq!(radio.registers().get(*b"CH"), Some(0x0D));
    assert_eq!(avr.eeprom_read(0, 1).unwrap(), [0xFF], "nothing written");
}

#[test]
fn a_frame_for_another_role_is_refused_and_nothing_is_stored() {
    let mut avr = erased(Role::Anchor);
    let mut radio = XBee::new(XBeeConfig::api(2));
    radio.run_for_ms(&mut avr, 100.0);
    assert_eq!(lines(&radio), [BootLine::Boot { role: Role::Anchor }]);
    let sink = Config::default_for(Role::Sink);
    let mut frame = [0u8; 32];
    let n = encode(&sink, &mut frame).unwrap();
    avr.uart_send(&frame[..n]);
    radio.run_for_ms(&mut avr, 50.0);
    assert!(contains(&output(&avr), &[b'H', b'L', b'N', WRONG_ROLE]));
    assert!(!contains(&output(&avr), b"HLA"));
    assert_eq!(avr.eeprom_read(0, 4).unwrap(), [0xFF; 4]);
    // The window runs out: the built-in config.
    radio.run_for_ms(&mut avr, PROVISION_WINDOW_MS as f64);
    assert!(lines(&radio).contains(&BootLine::Config {
        role: Role::Anchor,
        source: ConfigSource::BuiltIn,
        id: 1
    }));

    // The host side never sends an anchor's firmware a sink config.
    let mut avr = erased(Role::Anchor);
    let mut radio = XBee::new(XBeeConfig::api(2));
    let mut prov = Provisioner::new(sink).unwrap();
    provision(&mut avr, &mut radio, &mut prov, 500.0);
    assert!(
        matches!(
            prov.result(),
            Some(Err(ProvisionError::WrongNode {
                found: Role::Anchor,
                want: Role::Sink
            }))
        ),
        "{:?}",
        prov.result()
    );
}

#[test]
fn a_corrupt_eeprom_is_never_run_with_and_provisioning_fixes_it() {
    let mut block = [0u8; MAX_LEN];
    let n = anchor2().to_bytes(&mut block).unwrap();
    block[n - 1] ^= 0x01; // bad CRC
    let mut avr = boot(Role::Anchor);
    avr.eeprom_write(0, &block[..n]).unwrap();
    let mut radio = XBee::new(XBeeConfig::api(2));
    let mut led_samples = Vec::new();
    for _ in 0..(PROVISION_WINDOW_MS as usize + 12_000) / 10 {
        radio.run_for_ms(&mut avr, 10.0);
        led_samples.push(led_on(&avr));
    }
    let error = BootLine::ConfigError {
        role: Role::Anchor,
        code: 7,
    };
    let got = lines(&radio);
    assert_eq!(got[0], BootLine::Boot { role: Role::Anchor });
    assert!(got.len() >= 2, "{got:?}");
    assert!(got[1..].iter().all(|l| *l == error), "{got:?}");
    // The radio was never brought up: not a single API frame from the firmware.
    assert!(radio.frames_from_firmware().is_empty());
    // The LED blinks 7 times per round (200 ms on, 300 ms off, then 1.5 s dark): every group of
    // blinks between two dark pauses is 7 long.
    let rises: Vec<usize> = (1..led_samples.len())
        .filter(|&i| !led_samples[i - 1] && led_samples[i])
        .collect();
    let mut groups = vec![1];
    for w in rises.windows(2) {
        if w[1] - w[0] > 100 {
            groups.push(1);
        } else {
            *groups.last_mut().unwrap() += 1;
        }
    }
    assert!(groups.len() >= 2, "{groups:?}");
    assert!(
        groups[..groups.len() - 1].iter().all(|&g| g == 7),
        "{groups:?}"
    );
    // And the timing (10 ms samples, a sample either way): each blink is on for 200 ms and
    // starts 500 ms after the one before; a round's last blink starts 2 s before the next
    // round's first (on 200, off 300, then the 1.5 s pause; the line between costs ~5 ms).
    for &r in rises.iter().filter(|&&r| r + 22 < led_samples.len()) {
        let on = led_samples[r..].iter().take_while(|&&on| on).count();
        assert!((19..=21).contains(&on), "on for {on} samples at {r}");
    }
    for w in rises.windows(2) {
        let gap = w[1] - w[0];
        assert!(
            (49..=51).contains(&gap) || (199..=202).contains(&gap),
            "{gap} samples between blinks at {}",
            w[0]
        );
    }
    assert!(led_samples[..PROVISION_WINDOW_MS as usize / 10 - 1]
        .iter()
        .all(|on| !on));

    // `hoploc provision` resets the board; here the node is not reset: it still listens.
    let mut frame = [0u8; 32];
    let m = encode(&anchor2(), &mut frame).unwrap();
    avr.uart_send(&frame[..m]);
    radio.run_for_ms(&mut avr, 300.0);
    assert!(contains(&output(&avr), b"HLA\x01"));
    assert_eq!(avr.eeprom_read(0, n).unwrap(), {
        let mut good = [0u8; MAX_LEN];
        anchor2().to_bytes(&mut good).unwrap();
        good[..n].to_vec()
    });
    let got = lines(&radio);
    let tail = &got[got.len() - 3..];
    assert_eq!(
        tail,
        [
            BootLine::Provisioned { role: Role::Anchor },
            BootLine::Config {
                role: Role::Anchor,
                source: ConfigSource::Eeprom,
                id: 2
            },
            BootLine::RadioUp {
                role: Role::Anchor,
                found: RadioFound::Api
            },
        ]
    );
    assert_eq!(radio.registers().get(*b"MY"), Some(2));
}

#[test]
fn another_roles_config_in_eeprom_is_an_error_too() {
    let mut block = [0u8; MAX_LEN];
    let n = Config::default_for(Role::Agent)
        .to_bytes(&mut block)
        .unwrap();
    let mut avr = boot(Role::Sink);
    avr.eeprom_write(0, &block[..n]).unwrap();
    let mut radio = XBee::new(XBeeConfig::api(2));
    radio.run_for_ms(&mut avr, PROVISION_WINDOW_MS as f64 + 500.0);
    assert_eq!(
        lines(&radio),
        [
            BootLine::Boot { role: Role::Sink },
            BootLine::ConfigError {
                role: Role::Sink,
                code: WRONG_ROLE
            }
        ]
    );
    assert!(radio.frames_from_firmware().is_empty());
}
