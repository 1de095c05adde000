//! `hoploc demo`: every node's real firmware in simavr, each on a modelled factory-fresh XBee.
//!
//! Until the emulated testbed lands this shows what exists end to end: the three firmwares boot,
//! look for their radio in API mode at 57600, find it instead in transparent mode at 9600 baud (as
//! Digi ships it), switch it to API mode 2 at 57600 through command mode (`+++`, `ATAP2`, `ATBD6`,
//! `ATWR`, `ATCN`), then set MY/ID/CH through API frames and read each back.

use std::path::Path;

use loc_proto::line::{BootLine, ConfigSource, RadioFound};
use simavr::xbee::{baud_of_bd, XBee, XBeeConfig};
use simavr::{ms_to_cycles, Avr};
use xbee_api::driver::Error as RadioError;
use xbee_api::Frame;

use crate::firmware::{self, Role};

/// One simulated node: its firmware and its radio.
struct Node {
    role: Role,
    avr: Avr,
    radio: XBee,
    lines_seen: usize,
    frames_seen: usize,
}

/// A frame the firmware sent its radio, in a few words.
pub fn describe(data: &[u8]) -> String {
    match Frame::parse(data) {
        Ok(Frame::AtCommand {
            command, parameter, ..
        }) => {
            let cmd = String::from_utf8_lossy(&command);
            if parameter.is_empty() {
                format!("API AT {cmd}?")
            } else {
                let hex: String = parameter.iter().map(|b| format!("{b:02X}")).collect();
                format!("API AT {cmd}={hex}")
            }
        }
        Ok(Frame::Tx16 { dest, data, .. }) => format!("TX16 to {dest:04X}, {} bytes", data.len()),
        Ok(f) => format!("frame {:#04x}", f.frame_type()),
        Err(e) => format!("malformed frame: {e}"),
    }
}

/// A text line the firmware wrote, in a few words: its boot lines explained, anything else
/// (the command-mode lines `+++`, `ATAP2`… it sends the radio) quoted.
pub fn describe_line(text: &str) -> String {
    match BootLine::parse(text) {
        Ok(BootLine::Boot { .. }) => "boot".to_string(),
        Ok(BootLine::RadioUp {
            found: RadioFound::Api,
            ..
        }) => "radio up: it was already in API mode 2 at 57600".to_string(),
        Ok(BootLine::RadioUp {
            found: RadioFound::Configured { baud },
            ..
        }) => format!(
            "radio up: found in command mode at {baud} baud, now API mode 2 at 57600 (saved)"
        ),
        Ok(BootLine::RadioError { code, attempt, .. }) => format!(
            "radio error {code} on try {attempt} ({}); the LED blinks {code} times, then it retries",
            RadioError::describe_code(code).unwrap_or("unknown error")
        ),
        Ok(BootLine::Provisioned { .. }) => "provisioned: a config was stored in EEPROM".to_string(),
        Ok(BootLine::Config {
            source: ConfigSource::Eeprom,
            id,
            ..
        }) => format!("config from EEPROM: node {id}"),
        Ok(BootLine::Config {
            source: ConfigSource::BuiltIn,
            id,
            ..
        }) => format!("config built in (EEPROM erased): node {id}"),
        Ok(BootLine::ConfigError { code, .. }) => format!(
            "config error {code}: the EEPROM holds a config it must not run with; it waits for `hoploc provision`"
        ),
        Err(_) => format!("sends \"{text}\""),
    }
}

/// Runs the demo for `seconds` of simulated time.
pub fn run(firmware_dir: &Path, seconds: f64) -> Result<(), String> {
    firmware::ensure_built(firmware_dir)?;
    let mut nodes = Vec::new();
    for (i, role) in Role::ALL.into_iter().enumerate() {
        let path = firmware::elf(firmware_dir, role);
        let avr = Avr::load(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        let radio = XBee::new(XBeeConfig {
            sh_sl: 0x0013_A200_4000_0001 + i as u64,
            ..XBeeConfig::default()
        });
        nodes.push(Node {
            role,
            avr,
            radio,
            lines_seen: 0,
            frames_seen: 0,
        });
    }
    println!(
        "hoploc demo: {} nodes in simavr, each with a factory-fresh XBee (AP=0, 9600 baud)\n",
        nodes.len()
    );
    println!("{:>9}  {:<7} event", "time", "node");
    let step = ms_to_cycles(1.0);
    let end = ms_to_cycles(seconds * 1000.0);
    let mut t = 0;
    while t < end {
        t = (t + step).min(end);
        for n in &mut nodes {
            n.radio.run_until(&mut n.avr, t);
            let mut events: Vec<(f64, String)> = Vec::new();
            for line in &n.radio.text_lines()[n.lines_seen..] {
                events.push((line.ms(), describe_line(&line.text)));
            }
            for f in &n.radio.frames_from_firmware()[n.frames_seen..] {
                events.push((f.ms(), describe(&f.data)));
            }
            n.lines_seen = n.radio.text_lines().len();
            n.frames_seen = n.radio.frames_from_firmware().len();
            events.sort_by(|a, b| a.0.total_cmp(&b.0));
            for (ms, what) in events {
                println!("{ms:>7.1}ms  {:<7} {what}", n.role.name());
            }
        }
    }
    println!("\nradios after {seconds} s:");
    println!(
        "{:<7} {:>3} {:>7} {:>6} {:>6} {:>4} {:>7} {:>9}",
        "node", "AP", "baud", "MY", "ID", "CH", "frames", "stack"
    );
    for n in &nodes {
        let r = n.radio.registers();
        // BD beyond the table (a non-standard rate) shows as its raw value.
        let baud = baud_of_bd(r.bd()).unwrap_or(r.bd());
        let stack = n
            .avr
            .stack_peak()
            .map_or("-".to_string(), |s| format!("{s} B"));
        println!(
            "{:<7} {:>3} {:>7} {:>6} {:>6} {:>4} {:>7} {:>9}",
            n.role.name(),
            r.ap(),
            baud,
            format!("{:04X}", r.my()),
            format!("{:04X}", r.id()),
            format!("{:02X}", r.ch()),
            n.radio.stats().frames_ok,
            stack
        );
    }
    Ok(())
}
