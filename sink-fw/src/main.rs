//! sink-fw: the hoploc sink node firmware for the Arduino Uno.
//!
//! For now the boot firmware: write `hoploc sink boot`, settle the node config (provisioning
//! window, then EEPROM or the build-time config of `HOPLOC_*` variables, see
//! `loc_proto::config::from_env`), bring the radio up through xbee-api (API mode 2 at 57600; `MY`,
//! `ID`, `CH` from `uno_board::radio_config`, each read back), retrying with an LED error code
//! while it does not answer, then listen. The node logic will
//! live in a host-tested `lib.rs`; this file only wires it to `uno-board`. Build: `cargo fw` (all
//! firmwares) or `cargo fw-run -p sink-fw`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

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
    uno_board::boot_and_listen(&built_in::BUILT_IN)
}
