//! `hoploc footprint`: what each node firmware costs the ATmega328P, measured on the real ELFs.
//!
//! * flash: `.text` + `.data` initialisers (the `__data_load_end` symbol), against the 28 KiB
//!   budget (the Uno's application area is 32 256 B, the rest of its 32 KB being the
//!   bootloader: the budget leaves a user at least 3.5 KB for code of their own);
//! * static SRAM: `.data` + `.bss`;
//! * stack peak: measured in simavr by painting free SRAM at load and scanning it after the run,
//!   the deepest of two boot-and-run scenarios, each on a fresh core:
//!   1. **factory radio**: a modelled XBee as Digi ships it (transparent mode, 9600 baud), so the
//!      whole command-mode bring-up runs, then [`LISTEN_PACKETS`] RX16 packets of the node's
//!      traffic arrive while it runs ([`traffic`]: reports for the sink, so every one goes
//!      through its estimator; beacons for anchors and agents);
//!   2. **no radio**: nothing answers, so one full failed bring-up (every baud rate), the error
//!      line, the LED code, and the start of the retry run.
//!
//! Static SRAM + stack peak must stay within 1.5 KB of the 2 KB (the rest is headroom for the
//! interrupt frames that sampling may miss and for a user's own additions).

use std::path::Path;

use loc_proto::Role;
use simavr::xbee::{RxPacket, XBee, XBeeConfig};
use simavr::{ms_to_cycles, Avr};

use crate::firmware;
use crate::outln;

/// Flash budget per firmware: 28 KiB of the Uno's 32 256 B application area.
pub const FLASH_BUDGET: usize = 28 * 1024;
/// Static SRAM + stack peak budget per firmware, of the ATmega328P's 2 KB.
pub const SRAM_BUDGET: usize = 1536;
/// Simulated time of the factory-radio scenario: the provisioning window (2 s), bring-up (≈ 6 s)
/// and listening.
pub const FACTORY_RUN_MS: f64 = 11_000.0;
/// Simulated time of the no-radio scenario: the provisioning window (2 s), one failed bring-up
/// (≈ 22.6 s), the error code (≈ 6 s), and the start of the next attempt.
pub const SILENT_RUN_MS: f64 = 33_000.0;
/// Packets delivered to the listening node in the factory-radio scenario.
pub const LISTEN_PACKETS: usize = 20;

/// One firmware's figures.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Footprint {
    /// The node role (and so the firmware).
    pub role: Role,
    /// Flash bytes (`.text` + `.data`).
    pub flash: usize,
    /// Static SRAM bytes (`.data` + `.bss`).
    pub static_sram: usize,
    /// Deepest stack in the factory-radio scenario, bytes.
    pub stack_factory: usize,
    /// Deepest stack in the no-radio scenario, bytes.
    pub stack_silent: usize,
    /// Boot lines the factory-radio run printed (to show the scenario did what it says).
    pub factory_lines: Vec<String>,
}

impl Footprint {
    /// The deeper of the two scenarios' stack peaks.
    pub fn stack_peak(&self) -> usize {
        self.stack_factory.max(self.stack_silent)
    }

    /// Static SRAM + stack peak.
    pub fn sram(&self) -> usize {
        self.static_sram + self.stack_peak()
    }

    /// Whether both budgets hold.
    pub fn within_budget(&self) -> bool {
        self.flash <= FLASH_BUDGET && self.sram() <= SRAM_BUDGET
    }
}

fn stack_of(avr: &Avr) -> Result<usize, String> {
    avr.stack_peak()
        .ok_or_else(|| format!("{}: no static-data symbols", avr.firmware().display()))
}

/// Packet `i` of what a node of `role` hears in the factory-radio scenario: (source address,
/// payload). The sink gets agent 1's reports (4 anchors at the corners of a 10 m room, 2
/// channels, relays; levels varied per packet, so the fit and the searches take varied
/// paths); anchors and agents get anchor 2's beacons on the default config's first channel.
pub fn traffic(role: Role, i: usize) -> (u16, Vec<u8>) {
    use loc_proto::config::Config;
    use loc_proto::msg::{Beacon, ChannelList, Position, Relay, Report, MAX_PAYLOAD};
    let corners = [(0, 0), (1000, 0), (1000, 1000), (0, 1000)];
    let mut buf = [0u8; MAX_PAYLOAD];
    let level = |k: usize| 55 + ((i * 7 + k * 5) % 25) as u8;
    match role {
        Role::Sink => {
            let channels = ChannelList::new(&[1, 12]).expect("valid channels");
            let mut r = Report::new(1, i as u16, 4, channels);
            for (a, &(x, y)) in corners.iter().enumerate() {
                r.positions[a] = Position { x, y };
                for c in 0..2 {
                    r.rssi[c][a] = level(a + 4 * c);
                    for b in 0..4 {
                        if a != b {
                            r.relay[c][a][b] = level(8 + a * 4 + b + c);
                        }
                    }
                }
            }
            let n = r.encode(&mut buf).expect("a 4 × 2 report fits");
            (Role::Agent.address(1), buf[..n].to_vec())
        }
        Role::Anchor | Role::Agent => {
            let b = Beacon {
                anchor: 2,
                seq: i as u16,
                channel: Config::DEFAULT.channels.as_slice()[0],
                position: Position { x: 1000, y: 0 },
                relay: Relay::from_slice(&[level(0), 0, level(1), level(2)]).expect("4 fit"),
            };
            let n = b.encode(&mut buf).expect("a beacon fits");
            (Role::Anchor.address(2), buf[..n].to_vec())
        }
    }
}

/// Measures `role`'s firmware in `dir` (see the module docs).
pub fn measure(dir: &Path, role: Role) -> Result<Footprint, String> {
    let elf = firmware::elf(dir, role);
    // Scenario 1: a factory-fresh radio, then traffic while listening.
    let mut avr = firmware::load(&elf, role)?;
    let flash = avr
        .flash_size()
        .ok_or_else(|| format!("{}: no __data_load_end/_etext symbol", elf.display()))?;
    let static_sram = avr
        .static_data_size()
        .ok_or_else(|| format!("{}: no static-data symbols", elf.display()))?;
    let mut radio = XBee::new(XBeeConfig::default());
    let listen_from = FACTORY_RUN_MS - 2000.0;
    radio.run_until(&mut avr, ms_to_cycles(listen_from));
    let (ch, pan) = (radio.registers().ch(), radio.registers().id());
    for i in 0..LISTEN_PACKETS {
        let at = avr.cycle() + ms_to_cycles(1.0 + 50.0 * i as f64);
        let (source, payload) = traffic(role, i);
        radio.deliver(RxPacket::broadcast16(ch, pan, source, -60, &payload), at);
    }
    radio.run_until(&mut avr, ms_to_cycles(FACTORY_RUN_MS));
    let factory_lines = radio
        .text_lines()
        .iter()
        .filter(|l| loc_proto::line::BootLine::parse(&l.text).is_ok())
        .map(|l| l.text.clone())
        .collect();
    let stack_factory = stack_of(&avr)?;
    // Scenario 2: no radio at all.
    let mut avr = firmware::load(&elf, role)?;
    avr.run_until(ms_to_cycles(SILENT_RUN_MS));
    let stack_silent = stack_of(&avr)?;
    Ok(Footprint {
        role,
        flash,
        static_sram,
        stack_factory,
        stack_silent,
        factory_lines,
    })
}

/// Measures every firmware, two at a time (one per core).
pub fn measure_all(dir: &Path) -> Result<Vec<Footprint>, String> {
    std::thread::scope(|s| {
        let jobs: Vec<_> = Role::ALL
            .into_iter()
            .map(|role| s.spawn(move || measure(dir, role)))
            .collect();
        jobs.into_iter()
            .map(|j| {
                j.join()
                    .unwrap_or_else(|_| Err("measurement panicked".into()))
            })
            .collect()
    })
}

/// The figures as a Markdown table (also readable as plain text).
pub fn table(rows: &[Footprint]) -> String {
    let mut out = String::new();
    out.push_str(
        "| firmware | flash | static SRAM | stack peak (factory radio / no radio) | static + stack | within budget |\n",
    );
    out.push_str("|---|---:|---:|---:|---:|---|\n");
    for r in rows {
        out.push_str(&format!(
            "| {} | {} B ({:.1} % of {} B) | {} B | {} B ({} / {}) | {} B ({:.0} % of {} B) | {} |\n",
            firmware::crate_name(r.role),
            r.flash,
            100.0 * r.flash as f64 / FLASH_BUDGET as f64,
            FLASH_BUDGET,
            r.static_sram,
            r.stack_peak(),
            r.stack_factory,
            r.stack_silent,
            r.sram(),
            100.0 * r.sram() as f64 / SRAM_BUDGET as f64,
            SRAM_BUDGET,
            if r.within_budget() { "yes" } else { "**NO**" },
        ));
    }
    out
}

/// `hoploc footprint`: measure, print, and fail if a budget is exceeded.
pub fn run(dir: &Path) -> Result<(), String> {
    firmware::ensure_built(dir)?;
    eprintln!(
        "measuring {} firmwares in simavr ({} s factory radio + {} s no radio each)...",
        Role::ALL.len(),
        FACTORY_RUN_MS / 1000.0,
        SILENT_RUN_MS / 1000.0
    );
    let rows = measure_all(dir)?;
    let mut out = crate::out::Out::stdout();
    out.write(format_args!("{}", table(&rows)))?;
    outln!(
        out,
        "\nbudgets: flash ≤ {} B (of the Uno's 32 256); static SRAM + stack peak ≤ {} B (of 2048).",
        FLASH_BUDGET,
        SRAM_BUDGET
    );
    for r in &rows {
        outln!(
            out,
            "{} with a factory radio: {}",
            firmware::crate_name(r.role),
            r.factory_lines.join(" / ")
        );
    }
    let over: Vec<_> = rows
        .iter()
        .filter(|r| !r.within_budget())
        .map(|r| firmware::crate_name(r.role))
        .collect();
    if over.is_empty() {
        Ok(())
    } else {
        Err(format!("over budget: {}", over.join(", ")))
    }
}
