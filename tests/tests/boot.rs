//! Each node firmware boots in simavr against a scripted XBee (`simavr::ScriptedRadio`), and
//! these tests assert the exact frames it writes and what it says on the UART and the LED.
//! Every node first listens for a provisioning frame for `PROVISION_WINDOW_MS` (2 s) after its
//! boot line, then says which config it runs with (here `config eeprom id 1`: simavr loads the
//! ELF's `.eeprom` section, the built-in config, into the EEPROM), then brings the radio up:
//!
//! * a radio already in API mode 2: `AP` query, then `MY`, `ID`, `CH`, the channel access,
//!   encryption and the fixed settings (`xbee_api::driver::FIXED_SETTINGS`) each set, the
//!   `radio ok api` line, the first channel (`CH`, anchors and agents), then a quiet, listening
//!   node (no watchdog reset);
//! * a radio that never answers: two `AP` queries, `+++` at each of the eight baud rates, the
//!   `radio error 9 try 1` line, error code 9 on the LED, then the next attempt;
//! * a radio that answers garbage (a bad-checksum answer, noise, never `OK`): `radio error 10`,
//!   code 10 on the LED, next attempt.

use hoploc_tests::{boot, led_on};
use loc_proto::line::{BootLine, ConfigSource, RadioFound};
use loc_proto::provision::PROVISION_WINDOW_MS;
use loc_proto::schedule::{AGENT_BACKOFF_EXPONENT, AGENT_CCA_THRESHOLD};
use loc_proto::{xbee_channel, Role, DEFAULT_PAN_ID};
use simavr::{cycles_to_ms, ms_to_cycles, Avr, Match, ScriptedRadio};
use xbee_api::driver::{FACTORY_CCA_THRESHOLD, FIXED_SETTINGS};
use xbee_api::Mode;

/// The settings each firmware gives its radio with its built-in config
/// (`loc_proto::config::radio_settings`): node 1 of its role on the default PAN, on the role's boot channel.
fn settings(role: Role) -> (u16, u8) {
    (role.address(1), xbee_channel(role.boot_channel()).unwrap())
}

fn at(id: u8, cmd: &[u8; 2], param: &[u8]) -> Vec<u8> {
    let mut v = vec![0x08, id, cmd[0], cmd[1]];
    v.extend_from_slice(param);
    v
}

fn at_ok(id: u8, cmd: &[u8; 2], value: &[u8]) -> Vec<u8> {
    let mut v = vec![0x88, id, cmd[0], cmd[1], 0x00];
    v.extend_from_slice(value);
    v
}

fn parsed_lines(radio: &ScriptedRadio) -> Vec<(f64, String)> {
    radio
        .lines()
        .iter()
        .map(|l| (l.ms(), l.text.clone()))
        .collect()
}

/// When the first frame is due: after the provisioning window (and the config line).
const FIRST_FRAME_MS: f64 = PROVISION_WINDOW_MS as f64 + 20.0;

/// The line saying which config the node runs with.
fn config_line(role: Role) -> BootLine {
    BootLine::Config {
        role,
        source: ConfigSource::Eeprom,
        id: 1,
    }
}

/// The registers bring-up sets on a `role` node, in order, with their values: its address, the
/// PAN, its first channel, the channel access (an agent backs off and hears the room, the others
/// send when their slot says), encryption off (the default config has no network key), then the
/// factory value of every other register that changes how the radio sends or receives.
fn registers(role: Role) -> Vec<([u8; 2], Vec<u8>)> {
    let (my, ch) = settings(role);
    let mut regs = vec![
        (*b"MY", my.to_be_bytes().to_vec()),
        (*b"ID", DEFAULT_PAN_ID.to_be_bytes().to_vec()),
        (*b"CH", vec![ch]),
    ];
    if role == Role::Agent {
        regs.push((*b"RN", vec![AGENT_BACKOFF_EXPONENT]));
        regs.push((*b"CA", vec![AGENT_CCA_THRESHOLD]));
    } else {
        regs.push((*b"RN", vec![0]));
        regs.push((*b"CA", vec![FACTORY_CCA_THRESHOLD]));
    }
    regs.push((*b"EE", vec![0]));
    regs.extend(FIXED_SETTINGS.iter().map(|&(cmd, v)| (cmd, vec![v])));
    regs
}

/// The script of a radio that is already in API mode 2 at 57600 and takes every setting.
fn api_radio(role: Role) -> ScriptedRadio {
    let (_, ch) = settings(role);
    let regs = registers(role);
    let mut s = ScriptedRadio::new(Mode::Escaped)
        // The first frame comes right after the config line, when the window is over.
        .expect(Match::data(&at(1, b"AP", &[])), FIRST_FRAME_MS)
        .reply(&at_ok(1, b"AP", &[0x02]), 1.0);
    let mut id = 2;
    for (cmd, value) in &regs {
        s = s
            .expect(Match::data(&at(id, cmd, value)), 10.0)
            .reply(&at_ok(id, cmd, &[]), 1.0);
        id += 1;
    }
    // Then anchors and agents tune to their first channel (without waiting for the answer), and
    // every node listens: no frame for 1.2 s (more than a watchdog period; an anchor beacons
    // after listening for 1 + id superframes, 1.24 s for anchor 1 with the default config).
    if role != Role::Sink {
        s = s.expect(Match::data(&at(id, b"CH", &[ch])), 10.0);
    }
    s.expect_silence(1200.0)
}

fn boots_against_a_radio_in_api_mode(role: Role) {
    let mut avr = boot(role);
    let mut radio = api_radio(role);
    radio
        .run_to_end(&mut avr, PROVISION_WINDOW_MS as f64 + 2000.0)
        .unwrap();
    // The AP query, byte for byte on the wire (AP=2 escaping; nothing to escape here).
    let first = &radio.frames()[0];
    let wire: Vec<u8> = avr
        .uart_output()
        .iter()
        .filter(|b| b.cycle >= first.cycle && b.cycle < first.end_cycle)
        .map(|b| b.byte)
        .collect();
    assert_eq!(wire, [0x7E, 0x00, 0x04, 0x08, 0x01, 0x41, 0x50, 0x65]);
    assert_eq!(
        radio.frames().len(),
        1 + registers(role).len() + usize::from(role != Role::Sink),
        "AP?, then each register set (then the first channel, for anchors and agents)"
    );
    let lines = parsed_lines(&radio);
    let texts: Vec<&str> = lines.iter().map(|(_, t)| t.as_str()).collect();
    assert_eq!(
        texts,
        [
            BootLine::Boot { role }.to_string(),
            config_line(role).to_string(),
            BootLine::RadioUp {
                role,
                found: RadioFound::Api
            }
            .to_string()
        ],
        "one boot (no watchdog reset), one config line, one radio line"
    );
    // The config line closes the window.
    let window = PROVISION_WINDOW_MS as f64;
    assert!((window..window + 20.0).contains(&lines[1].0), "{lines:?}");
    // The radio line follows the last setting's answer.
    assert!(lines[2].0 > radio.frames()[registers(role).len()].end_ms());
    assert!(radio.decode_errors().is_empty());
    // Whole bring-up in well under 100 ms against a radio that answers within 1 ms.
    assert!(lines[2].0 - lines[1].0 < 100.0, "{lines:?}");
}

/// Runs `radio` on `avr` until the script is done, sampling the LED every 5 ms; returns
/// (start ms, length ms) of every time it was on.
fn run_watching_led(avr: &mut Avr, radio: &mut ScriptedRadio, timeout_ms: f64) -> Vec<(f64, f64)> {
    let end = avr.cycle() + ms_to_cycles(timeout_ms);
    let mut pulses = Vec::new();
    let mut on_since: Option<f64> = None;
    while !radio.is_done() {
        assert!(avr.cycle() < end, "script not done after {timeout_ms} ms");
        let next = avr.cycle() + ms_to_cycles(5.0);
        radio.run_until(avr, next).unwrap();
        let now = cycles_to_ms(avr.cycle());
        match (led_on(avr), on_since) {
            (true, None) => on_since = Some(now),
            (false, Some(t)) => {
                pulses.push((t, now - t));
                on_since = None;
            }
            _ => {}
        }
    }
    pulses
}

/// Checks a failed first attempt: `+++` at the eight baud rates, each after the guard time of
/// silence; the error line with `code`; `code` blinks of 200 ms between it and the retry.
fn failed_attempt(role: Role, mut radio: ScriptedRadio, code: u8) {
    let mut avr = boot(role);
    let pulses = run_watching_led(&mut avr, &mut radio, PROVISION_WINDOW_MS as f64 + 40_000.0);
    let lines = parsed_lines(&radio);
    let plus: Vec<f64> = lines
        .iter()
        .filter(|(_, t)| t == "+++")
        .map(|&(ms, _)| ms)
        .collect();
    assert_eq!(plus.len(), 8, "one +++ per baud rate: {lines:?}");
    for pair in plus.windows(2) {
        // Guard (1100 ms) before, guard + timeout (1600 ms) waiting for OK after; up to 25 ms
        // more around the slow rates, where `+++` itself takes 27 ms at 1200 bit/s.
        let gap = pair[1] - pair[0];
        assert!(
            (2695.0..2725.0).contains(&gap),
            "{gap} ms between +++: {lines:?}"
        );
    }
    let error = BootLine::RadioError {
        role,
        code,
        attempt: 1,
    };
    let texts: Vec<&str> = lines.iter().map(|(_, t)| t.as_str()).collect();
    let mut expected = vec![
        BootLine::Boot { role }.to_string(),
        config_line(role).to_string(),
    ];
    expected.extend(std::iter::repeat_n("+++".to_string(), 8));
    expected.push(error.to_string());
    assert_eq!(texts, expected);
    assert_eq!(BootLine::parse(texts[10]), Ok(error));
    let error_ms = lines[10].0;
    // The retry's AP query is the last frame the script expected.
    let retry = radio.frames().last().unwrap().ms();
    let blinks: Vec<_> = pulses
        .iter()
        .filter(|&&(t, _)| t > error_ms && t < retry)
        .collect();
    assert_eq!(blinks.len(), code as usize, "LED pulses {blinks:?}");
    for &&(_, len) in &blinks {
        assert!((195.0..=210.0).contains(&len), "blink of {len} ms");
    }
    // The LED was on for the whole first attempt (about 22.6 s, after the window).
    let window = PROVISION_WINDOW_MS as f64;
    assert!(
        pulses
            .iter()
            .any(|&(t, len)| (window..window + 30.0).contains(&t) && len > 22_000.0),
        "{pulses:?}"
    );
}

fn silent_radio_gives_error_9_and_retries(role: Role) {
    let radio = ScriptedRadio::new(Mode::Escaped)
        .expect(Match::data(&at(1, b"AP", &[])), FIRST_FRAME_MS)
        // Asked twice (a radio still powering up may miss the first), 500 ms apart.
        .expect(Match::data(&at(2, b"AP", &[])), 520.0)
        // Nothing until the second attempt: 8 × (1100 + 1600) ms of command mode, the line, and
        // 9 blinks (9 × 500 + 1500 ms).
        .expect(Match::data(&at(3, b"AP", &[])), 29_000.0);
    failed_attempt(role, radio, 9);
}

fn garbage_radio_gives_error_10_and_retries(role: Role) {
    // An AT response with a bad checksum, then noise, never a valid frame nor `OK\r`.
    let bad_checksum = [0x7E, 0x00, 0x06, 0x88, 0x01, b'A', b'P', 0x00, 0x02, 0x00];
    let mut radio = ScriptedRadio::new(Mode::Escaped)
        .expect(Match::data(&at(1, b"AP", &[])), FIRST_FRAME_MS)
        .reply_raw(&bad_checksum, 1.0)
        .expect(Match::data(&at(2, b"AP", &[])), 520.0)
        .reply_raw(b"\x55\xAA\x00garbage\r\n", 1.0);
    // Noise throughout the command-mode search (every 400 ms, so inside each wait for `OK`).
    for i in 0..56 {
        radio = radio.send_raw_at(
            PROVISION_WINDOW_MS as f64 + 1100.0 + 400.0 * i as f64,
            b"\xF0?\x0FERR\r",
        );
    }
    let radio = radio.expect(Match::data(&at(3, b"AP", &[])), 29_000.0);
    failed_attempt(role, radio, 10);
}

macro_rules! per_role {
    ($scenario:ident: $($name:ident => $role:expr),+) => {
        mod $scenario {
            use super::*;
            $(#[test] fn $name() { super::$scenario($role) })+
        }
    };
}

per_role!(boots_against_a_radio_in_api_mode: anchor => Role::Anchor, agent => Role::Agent, sink => Role::Sink);
per_role!(silent_radio_gives_error_9_and_retries: anchor => Role::Anchor, agent => Role::Agent, sink => Role::Sink);
per_role!(garbage_radio_gives_error_10_and_retries: anchor => Role::Anchor, agent => Role::Agent, sink => Role::Sink);
