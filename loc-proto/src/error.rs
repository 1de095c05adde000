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
    /// The report's flags (only the relay bits may be set, the rows bit only with the relay bit).
    Flags,
    /// The role byte (0 anchor, 1 agent, 2 sink).
    Role,
    /// The slot length (up to 10000 ms, and long enough for a beacon of the network:
    /// `schedule::min_slot_ms`).
    SlotLength,
    /// The sink channel (1…16).
    SinkChannel,
    /// The PAN id (0xFFFF is the broadcast PAN).
    PanId,
    /// A report's relay rows (a row of an anchor the report does not have).
    RelayRows,
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
/// check value of `"123456789"` is 0x29B1), a byte at a time without a table: the byte-wise
/// form of the bit loop (x = the top byte ^ the data byte, folded once by its high nibble; then
/// crc = crc << 8 ^ x << 12 ^ x << 5 ^ x): little flash and no inner loop.
#[inline(never)]
pub fn crc16(data: &[u8]) -> u16 {
    crc16_update(CRC16_INIT, data)
}

/// [`crc16`]'s initial value.
pub const CRC16_INIT: u16 = 0xFFFF;

/// The CRC-16 of [`crc16`] after `crc` (the CRC so far) and `data`: `crc16` of a message
/// written in pieces (the sink lines' [`crate::line::Crc16Writer`]). One out-of-line copy for
/// both uses.
#[inline(never)]
pub fn crc16_update(mut crc: u16, data: &[u8]) -> u16 {
    // On the two bytes apart (8-bit shifts only): hi' = lo ^ x << 4 ^ x >> 3, lo' = x << 5 ^ x.
    for &b in data {
        let [lo, hi] = crc.to_le_bytes();
        let mut x = hi ^ b;
        x ^= x >> 4;
        crc = u16::from_le_bytes([(x << 5) ^ x, lo ^ (x << 4) ^ (x >> 3)]);
    }
    crc
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bit-by-bit definition, for comparison.
    fn crc16_bitwise(data: &[u8]) -> u16 {
        let mut crc: u16 = 0xFFFF;
        for &b in data {
            crc ^= (b as u16) << 8;
            for _ in 0..8 {
                crc = if crc & 0x8000 != 0 {
                    (crc << 1) ^ 0x1021
                } else {
                    crc << 1
                };
            }
        }
        crc
    }

    #[test]
    fn crc16_is_the_bitwise_crc() {
        // Every one- and two-byte input, 65 536 three-byte ones, and a long one.
        for a in 0..=255u8 {
            assert_eq!(crc16(&[a]), crc16_bitwise(&[a]));
            for b in 0..=255u8 {
                assert_eq!(crc16(&[a, b]), crc16_bitwise(&[a, b]), "{a} {b}");
                assert_eq!(crc16(&[a, b, a ^ 0x5A]), crc16_bitwise(&[a, b, a ^ 0x5A]));
            }
        }
        let long: std::vec::Vec<u8> = (0..300u32).map(|i| (i * 73 % 251) as u8).collect();
        assert_eq!(crc16(&long), crc16_bitwise(&long));
    }

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
