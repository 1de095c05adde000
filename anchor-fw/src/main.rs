//! anchor-fw: the hoploc anchor node firmware for the Arduino Uno.
//!
//! For now the boot firmware: write `hoploc anchor boot`, bring the radio up through xbee-api (API
//! mode 2 at 57600; `MY`, `ID`, `CH` from `uno_board::boot_radio_config`, each read back),
//! retrying with an LED error code while it does not answer, then listen. The node logic will
//! live in a host-tested `lib.rs`; this file only wires it to `uno-board`. Build: `cargo fw` (all
//! firmwares) or `cargo fw-run -p anchor-fw`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    uno_board::boot_and_listen(loc_proto::Role::Anchor)
}
