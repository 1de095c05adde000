//! sink-fw: the hoploc sink firmware for the Arduino Uno.
//!
//! Wiring only (the logic is `sink_fw::Sink`, host-tested): `uno_board::boot` (boot line, node
//! config: provisioning window, then EEPROM or the build-time config of `HOPLOC_*` variables;
//! radio bring-up on the sink channel; watchdog), then the loop — each report the radio hands
//! over goes to the sink, and out on the UART (the USB serial) go its `report` line and its fix
//! lines (or why there is none), as loc-proto's sink lines (written with ufmt onto the UART); a
//! `status` line every [`STATUS_PERIOD_MS`]. Build: `cargo fw` (all firmwares); build and
//! flash: `cargo run` in this directory, or `cargo fw-run -p sink-fw` from the workspace root.
//! Its flash and SRAM: `hoploc footprint`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

/// Time between two status lines, ms.
#[cfg(target_arch = "avr")]
const STATUS_PERIOD_MS: u16 = 10_000;

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

/// The build-time config (`BUILT_IN`) and its `.eeprom` image, from build.rs.
#[cfg(target_arch = "avr")]
mod built_in {
    include!(concat!(env!("OUT_DIR"), "/config.rs"));
}

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    uno_board::boot(loc_proto::Role::Sink, built_in::BUILT_IN, run)
}

/// The node's loop, out of line (on the AVR, far accesses into `main`'s big frame cost code).
#[cfg(target_arch = "avr")]
#[inline(never)]
fn run(node: &mut uno_board::Node) -> ! {
    use loc_proto::msg::ReportView;
    use sink_fw::Sink;
    use uno_board::node::{self, Event};
    use uno_board::prelude::*;
    use uno_board::{now_ms, rx_pending, sleep_unless};
    let uno_board::Node {
        radio,
        led,
        watchdog,
        config,
    } = node;

    let mut sink = Sink::new(sink_fw::room(config.position));
    // The clock's low 16 bits: the loop looks at least once a second (the watchdog's 1 s sees
    // to that), far within their 65 s, and 16-bit arithmetic is half the AVR code.
    let mut last_status = now_ms() as u16;
    loop {
        watchdog.feed();
        // Each packet handled where the driver decoded it: the report read in place, its lines
        // written on the serial port the poll lends beside it.
        while node::poll(radio, |ev, serial| {
            // Fed per packet too: reports arriving faster than the sink handles them keep this
            // loop busy for longer than the watchdog's 1 s.
            watchdog.feed();
            if let Event::Packet { data, .. } = ev {
                match ReportView::accept(data) {
                    Ok(report) => {
                        let Ok(()) = led.toggle();
                        on_report(&mut sink, &report, serial);
                    }
                    Err(e) => sink.on_bad_frame(e.into()),
                }
            }
        })
        .is_some()
        {}
        if (now_ms() as u16).wrapping_sub(last_status) >= STATUS_PERIOD_MS {
            last_status = last_status.wrapping_add(STATUS_PERIOD_MS);
            sink.add_uptime((STATUS_PERIOD_MS / 1000) as u8);
            line(radio.serial_mut(), Line::Status(sink.counters()));
        }
        sleep_unless(rx_pending);
    }
}

// Where the report's code goes: the linker lays out this crate's functions in the order of
// their symbol names, so `glue::on_report` and then `lines::*` come after `run` and `locate`,
// and the many calls from `lines` into loc-proto's line writing (its ufmt writers, one copy for
// the UART) land within `rcall` range (±4 KB), which `--relax` then shortens.
#[cfg(target_arch = "avr")]
use glue::on_report;
#[cfg(target_arch = "avr")]
use lines::{line, Line};

#[cfg(target_arch = "avr")]
mod glue {
    use super::{line, Line};
    use uno_board::Serial;

    /// A report's lines on `uart`: its `report` line (the bytes it came in), then two `fix`
    /// lines or a `nofix` line. Out of line, as [`super::run`].
    #[inline(never)]
    pub fn on_report(
        sink: &mut sink_fw::Sink,
        report: &loc_proto::msg::ReportView,
        uart: &mut Serial,
    ) {
        use loc_proto::sink_line::Estimator;
        let Ok(()) = loc_proto::sink_line::RawReport::write(report.bytes(), uart);
        sink.on_report_with(report, |result| match result {
            Ok(fix) => {
                line(uart, Line::Fix(fix, Estimator::Mle));
                line(uart, Line::Fix(fix, Estimator::Mmse));
            }
            Err(e) => {
                let Ok(()) = sink_fw::no_fix_line(report.agent(), report.seq(), e).write(uart);
            }
        })
    }
}

#[cfg(target_arch = "avr")]
mod lines {
    /// A `fix` or `status` line.
    pub enum Line<'a> {
        /// The `fix` line of an estimator.
        Fix(&'a sink_fw::Fix, loc_proto::sink_line::Estimator),
        /// The `status` line of the counters.
        Status(&'a sink_fw::Counters),
    }

    /// `what` on the UART (the `ufmt::uWrite` every line goes out through, the boot lines' too:
    /// one copy of each of ufmt's writers): each line built and written in one place, so only
    /// its fields' writes remain (no line in memory); both kinds in one function.
    #[inline(never)]
    pub fn line(uart: &mut uno_board::Serial, what: Line<'_>) {
        let Ok(()) = match what {
            Line::Fix(fix, estimator) => fix.line(estimator).write(uart),
            Line::Status(counters) => counters.write_line(uart),
        };
    }
}
