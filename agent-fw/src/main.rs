//! agent-fw: the hoploc agent node firmware for the Arduino Uno.
//!
//! For now the boot skeleton: set the board up, announce the role on the UART, blink, then idle
//! with the watchdog running. The node logic will live in a host-tested `lib.rs`; this file only
//! wires it to `uno-board`. Build: `cargo fw` (all firmwares) or `cargo fw-run -p agent-fw`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

#[cfg(target_arch = "avr")]
uno_board::avr_progmem::progmem! {
    /// The boot line (no 0x7E: the radio shares the TX line).
    static progmem string BANNER = "hoploc agent boot\r\n";
}

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    uno_board::boot_and_idle(&BANNER)
}
