//! The one error type of the binary formats ([`crate::msg`], [`crate::config`],
//! [`crate::provision`]).

use core::fmt;

/// Why a binary message, config or provisioning frame was rejected (decoding) or could not be
/// written (encoding). Decoders return it for every malformed input and never panic.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Error {
    /// The input ends before the header or before the length the header announces.
    TooShort,
    /// The first byte is not this format's magic byte: not a hoploc message (drop and count it).
    BadMagic,
    /// A hoploc message of a version this build does not speak.
    BadVersion {
        /// The version byte found.
        found: u8,
    },
    /// The kind byte after magic and version names no known message.
    BadKind {
        /// The kind byte found.
        found: u8,
    },
    /// The length byte disagrees with the input's length or with the length its fields imply.
    BadLength,
    /// A field is out of range (or, encoding, the value to encode is).
    BadValue {
        /// Which field.
        field: Field,
    },
    /// The CRC-16 does not match: a corrupt config or provisioning frame.
    BadCrc,
    /// Encoding: the message would exceed the XBee 802.15.4 RF payload
    /// ([`crate::msg::MAX_PAYLOAD`] bytes).
    TooLarge {
        /// The size it would have.
        size: u16,
    },
    /// Encoding: the caller's buffer is shorter than the encoded size.
    BufferTooSmall {
        /// The size needed.
        need: u16,
    },
}

/// The field an [`Error::BadValue`] is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Field {
    /// An anchor id (1…8, and at most the number of anchors where that is known).
    AnchorId,
    /// An agent id (1…255).
    AgentId,
    /// A node id (1…255; an anchor's at most N).
    NodeId,
    /// The number of anchors N (3…8).
    Anchors,
    /// A relay count (0…8).
    RelayCount,
    /// The RSSI an anchor relays about itself (must be 0: not heard).
    SelfRssi,
    /// A testbed channel (1…16).
    Channel,
    /// The number of channels C (1…4).
    ChannelCount,
    /// The same channel twice in a channel list.
    DuplicateChannel,
    /// The report's flags (only the relay bit may be set).
    Flags,
    /// The role byte (0 anchor, 1 agent, 2 sink).
    Role,
    /// The slot length (2…10000 ms).
    SlotLength,
    /// The sink channel (1…16).
    SinkChannel,
    /// The PAN id (0xFFFF is the broadcast PAN).
    PanId,
}

impl Error {
    /// A small number for the error, for a NAK byte or an LED blink count (1…9, never 0x7E).
    pub const fn code(self) -> u8 {
        match self {
            Error::TooShort => 1,
            Error::BadMagic => 2,
            Error::BadVersion { .. } => 3,
            Error::BadKind { .. } => 4,
            Error::BadLength => 5,
            Error::BadValue { .. } => 6,
            Error::BadCrc => 7,
            Error::TooLarge { .. } => 8,
            Error::BufferTooSmall { .. } => 9,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::TooShort => f.write_str("input too short"),
            Error::BadMagic => f.write_str("bad magic byte"),
            Error::BadVersion { found } => write!(f, "unsupported version {found}"),
            Error::BadKind { found } => write!(f, "unknown message kind {found}"),
            Error::BadLength => f.write_str("bad length"),
            Error::BadValue { field } => write!(f, "bad value: {field:?}"),
            Error::BadCrc => f.write_str("bad CRC"),
            Error::TooLarge { size } => write!(f, "{size} bytes exceed the radio payload"),
            Error::BufferTooSmall { need } => write!(f, "buffer too small, need {need} bytes"),
        }
    }
}

impl core::error::Error for Error {}

/// CRC-16/CCITT-FALSE (polynomial 0x1021, initial value 0xFFFF, no reflection, no final XOR;
/// check value of `"123456789"` is 0x29B1), bit by bit: no table, so a few dozen bytes of flash.
pub fn crc16(data: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &b in data {
        crc ^= (b as u16) << 8;
        // A u8 counter: `for _ in 0..8` compiles to a 32-bit one on AVR.
        let mut bit = 8u8;
        while bit != 0 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
            bit -= 1;
        }
    }
    crc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc16_check_value() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
        assert_eq!(crc16(b""), 0xFFFF);
    }

    #[test]
    fn codes_are_distinct_and_small() {
        let all = [
            Error::TooShort,
            Error::BadMagic,
            Error::BadVersion { found: 0 },
            Error::BadKind { found: 0 },
            Error::BadLength,
            Error::BadValue { field: Field::Role },
            Error::BadCrc,
            Error::TooLarge { size: 0 },
            Error::BufferTooSmall { need: 0 },
        ];
        for (i, e) in all.iter().enumerate() {
            assert_eq!(e.code() as usize, i + 1);
        }
    }
}
