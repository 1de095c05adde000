//! agent-fw: the hoploc agent node firmware for the Arduino Uno.
//!
//! For now the boot firmware: write `hoploc agent boot`, bring the radio up through xbee-api (API
//! mode 2 at 57600; `MY`, `ID`, `CH` below, each read back), retrying with an LED error code while
//! it does not answer, then listen. The node logic will live in a host-tested `lib.rs`; this file
//! only wires it to `uno-board`. Build: `cargo fw` (all firmwares) or `cargo fw-run -p agent-fw`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

#[cfg(target_arch = "avr")]
use loc_proto::{xbee_channel, Role, DEFAULT_PAN_ID};

/// The radio settings until node config lands: agent 1 of the default PAN, on the first channel of the default list (testbed channel 1, CH 0x0B), where the first beacons come.
#[cfg(target_arch = "avr")]
const RADIO: xbee_api::driver::BringUpConfig = xbee_api::driver::BringUpConfig {
    my: Some(Role::Agent.address(1)),
    pan_id: Some(DEFAULT_PAN_ID),
    channel: xbee_channel(loc_proto::DEFAULT_CHANNELS[0]),
    ..xbee_api::driver::BringUpConfig::new()
};

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    uno_board::boot_and_listen(Role::Agent, &RADIO)
}
