//! anchor-fw: the hoploc anchor node firmware for the Arduino Uno.
//!
//! For now the boot firmware: write `hoploc anchor boot`, bring the radio up through xbee-api (API
//! mode 2 at 57600; `MY`, `ID`, `CH` below, each read back), retrying with an LED error code while
//! it does not answer, then listen. The node logic will live in a host-tested `lib.rs`; this file
//! only wires it to `uno-board`. Build: `cargo fw` (all firmwares) or `cargo fw-run -p anchor-fw`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

#[cfg(target_arch = "avr")]
use loc_proto::{xbee_channel, Role, DEFAULT_PAN_ID};

/// The radio settings until node config lands: anchor 1 of the default PAN, on the first channel of the default list (testbed channel 1, CH 0x0B), where its first beacon goes.
#[cfg(target_arch = "avr")]
const RADIO: xbee_api::driver::BringUpConfig = xbee_api::driver::BringUpConfig {
    my: Some(Role::Anchor.address(1)),
    pan_id: Some(DEFAULT_PAN_ID),
    channel: xbee_channel(loc_proto::DEFAULT_CHANNELS[0]),
    ..xbee_api::driver::BringUpConfig::new()
};

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    uno_board::boot_and_listen(Role::Anchor, &RADIO)
}
