//! `simavr-run FIRMWARE.elf [MS] [--eeprom FILE]`: runs an ATmega328P firmware in simavr for MS
//! milliseconds of simulated time (default 1000) and prints its UART0 output line by line with
//! timestamps, then the final state, stack peak and simulation speed. With `--profile`, it runs
//! instruction by instruction and ends with the cycles spent per function (top 30); with
//! `--profile-phases`, also per phase of the first output line, the phases being split at each
//! byte written (the marker bytes of `mcu-bench`'s firmwares):
//! `simavr-run target/avr-none/fw/est-fixed.elf 100 --profile-phases`.

use std::process::ExitCode;
use std::time::Instant;

use simavr::{cycles_to_ms, Avr};

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let mut elf = None;
    let mut ms = 1000.0;
    let mut eeprom = None;
    let mut profile = false;
    let mut phases = false;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--eeprom" => eeprom = args.next(),
            "--profile" => profile = true,
            "--profile-phases" => (profile, phases) = (true, true),
            "-h" | "--help" => {
                eprintln!("usage: simavr-run FIRMWARE.elf [MS] [--eeprom FILE] [--profile] [--profile-phases]");
                return ExitCode::SUCCESS;
            }
            _ if elf.is_none() => elf = Some(a),
            _ => match a.parse::<f64>() {
                Ok(v) if v > 0.0 => ms = v,
                _ => {
                    eprintln!("bad duration {a:?} (milliseconds)");
                    return ExitCode::FAILURE;
                }
            },
        }
    }
    let Some(elf) = elf else {
        eprintln!(
            "usage: simavr-run FIRMWARE.elf [MS] [--eeprom FILE] [--profile] [--profile-phases]"
        );
        return ExitCode::FAILURE;
    };
    let mut avr = match Avr::load(&elf) {
        Ok(a) => a,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::FAILURE;
        }
    };
    if let Some(f) = eeprom {
        let data = match std::fs::read(&f) {
            Ok(d) => d,
            Err(e) => {
                eprintln!("cannot read {f}: {e}");
                return ExitCode::FAILURE;
            }
        };
        if let Err(e) = avr.eeprom_write(0, &data) {
            eprintln!("{e}");
            return ExitCode::FAILURE;
        }
    }
    let t = Instant::now();
    let target = simavr::ms_to_cycles(ms);
    let mut line: Vec<u8> = Vec::new();
    let mut line_start = 0;
    let mut state = avr.state();
    let mut prof = simavr::Profile::default();
    // Per phase of the first line: (the byte that ended it, its profile).
    let mut split: Vec<(u8, simavr::Profile)> = vec![(0, simavr::Profile::default())];
    let mut first_line = phases;
    while avr.cycle() < target && state.is_alive() {
        let next = target.min(avr.cycle() + simavr::ms_to_cycles(10.0));
        if profile {
            let p = avr.profile_until_output(next, first_line);
            if first_line {
                add(&mut split.last_mut().expect("a phase").1, &p);
            }
            add(&mut prof, &p);
            state = avr.state();
        } else {
            state = avr.run_until(next);
        }
        for b in avr.take_uart_output() {
            if first_line {
                split.last_mut().expect("a phase").0 = b.byte;
                first_line = b.byte != b'\n';
                split.push((0, simavr::Profile::default()));
            }
            if line.is_empty() {
                line_start = b.cycle;
            }
            if b.byte == b'\n' {
                print_line(line_start, &line);
                line.clear();
            } else {
                line.push(b.byte);
            }
        }
    }
    if !line.is_empty() {
        print_line(line_start, &line);
    }
    let wall = t.elapsed().as_secs_f64();
    eprintln!(
        "-- {:?} at {:.3} ms; stack peak {} B; static data {} B; {:.1} simulated MHz",
        state,
        avr.time_ms(),
        avr.stack_peak().map_or("?".into(), |p| p.to_string()),
        avr.static_data_size().map_or("?".into(), |p| p.to_string()),
        avr.cycle() as f64 / wall.max(1e-9) / 1e6
    );
    if phases {
        let mut prev = None;
        for (byte, p) in split.iter_mut().filter(|(b, _)| *b != 0) {
            let from = prev.map_or("reset".to_string(), |b: u8| format!("{:?}", b as char));
            eprintln!("-- phase from {from} to {:?}:", *byte as char);
            print_profile(p, 12);
            prev = Some(*byte);
        }
    }
    if profile {
        eprintln!("-- whole run:");
        print_profile(&mut prof, 30);
    }
    ExitCode::SUCCESS
}

/// Adds `p`'s cycles to `to`'s.
fn add(to: &mut simavr::Profile, p: &simavr::Profile) {
    for (f, c) in &p.functions {
        match to.functions.iter_mut().find(|e| &e.0 == f) {
            Some(e) => e.1 += c,
            None => to.functions.push((f.clone(), *c)),
        }
    }
}

/// The `top` most expensive functions of `p`.
fn print_profile(p: &mut simavr::Profile, top: usize) {
    p.functions.sort_by_key(|f| std::cmp::Reverse(f.1));
    let total = p.total().max(1);
    eprintln!("   cycles per function ({total} in all):");
    for (f, c) in p.functions.iter().take(top) {
        eprintln!("{c:>12} {:5.1} %  {f}", 100.0 * *c as f64 / total as f64);
    }
}

/// Prints a line with its time; bytes that are not printable ASCII (API frames) as `\xNN`.
fn print_line(cycle: u64, bytes: &[u8]) {
    let mut s = String::new();
    for &b in bytes.strip_suffix(b"\r").unwrap_or(bytes) {
        if (0x20..0x7f).contains(&b) {
            s.push(b as char);
        } else {
            s.push_str(&format!("\\x{b:02x}"));
        }
    }
    println!("{:10.3} ms  {s}", cycles_to_ms(cycle));
}
