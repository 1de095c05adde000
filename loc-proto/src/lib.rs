//! The wire contract of hoploc, defined once: everything one node says to another node or to a
//! person, with an encoder for the firmware and a parser for the host tools.
//!
//! * [`mod@line`]: the text lines every node writes on its UART at boot ([`line::BootLine`]).
//! * [`sink_line`]: the sink's estimate, no-fix and status lines ([`sink_line::SinkLine`]).
//! * [`schedule`]: the TDMA superframe, when each anchor beacons and each agent reports, and the
//!   timeline every node follows.
//! * [`msg`]: the binary radio messages, [`msg::Beacon`] and [`msg::Report`].
//! * [`config`]: the node config as stored in EEPROM ([`config::Config`]).
//! * [`provision`]: the provisioning frame that writes a config over the USB serial, its
//!   streaming parser and the node's ACK/NAK.
//! * `build` (feature `build`, for the firmwares' build scripts): the build-time config from
//!   `HOPLOC_*` variables as Rust source.
//! * [`error`]: their one error type [`Error`], and the CRC-16 of configs and provisioning frames.
//!
//! The sink firmware writes its lines with the same crate.
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(any(test, feature = "build"))]
extern crate std;

#[cfg(feature = "build")]
pub mod build;
pub mod config;
pub mod error;
pub mod line;
pub mod msg;
pub mod provision;
mod role;
pub mod schedule;
pub mod sink_line;

pub use error::Error;
pub use role::Role;

/// The PAN id of a hoploc testbed unless configured otherwise (`ID`; ASCII "32").
pub const DEFAULT_PAN_ID: u16 = 0x3332;

/// The 16-bit broadcast address: anchors broadcast their beacons.
pub const BROADCAST: u16 = 0xFFFF;

/// The XBee `CH` register value of testbed channel `n` (1…16): `CH = 0x0A + n`, so channel 1 is
/// 802.15.4 channel 11 (0x0B) and 16 is 26 (0x1A). `None` outside 1…16. The S1 Pro only has
/// testbed channels 2…13 (0x0C…0x17).
pub const fn xbee_channel(n: u8) -> Option<u8> {
    if n >= 1 && n <= 16 {
        Some(0x0A + n)
    } else {
        None
    }
}

/// The default channel list: testbed channels 1 and 12, as in the thesis (`docs/design.md`,
/// section 2).
pub const DEFAULT_CHANNELS: [u8; 2] = [1, 12];
/// The default sink channel (testbed channel 3).
pub const DEFAULT_SINK_CHANNEL: u8 = 3;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn testbed_channels_map_to_the_xbee_range() {
        assert_eq!(xbee_channel(0), None);
        assert_eq!(xbee_channel(1), Some(0x0B));
        assert_eq!(xbee_channel(3), Some(0x0D));
        assert_eq!(xbee_channel(12), Some(0x16));
        assert_eq!(xbee_channel(16), Some(0x1A));
        assert_eq!(xbee_channel(17), None);
    }
}
