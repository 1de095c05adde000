//! XBee 802.15.4 (Series 1) API frames and a radio driver, for microcontrollers and hosts
//! alike: `no_std`, no allocation, no `unsafe`, and nothing the radio sends can make it panic.
//!
//! It speaks the API frames of Digi's XBee 802.15.4 modules (the "Series 1": S1 and S1 Pro,
//! firmware 10xx) in both API modes, `AP=1` and `AP=2`. Frames of other XBee families
//! (ZigBee, DigiMesh) are not parsed; they come out as [`Frame::Unknown`].
//!
//! # Where to start
//!
//! * **Firmware talking to a radio on a UART:** [`driver::Radio`]. It needs a serial port
//!   (the `embedded-hal-nb` 1.0 serial traits, or another trait family through an adapter of
//!   [`serial`]), a millisecond [`driver::Clock`], and [`driver::SetBaud`] for bring-up. The
//!   [`driver`] module docs say what to implement for each, and show a whole Arduino Uno
//!   firmware on arduino-hal (`examples/arduino_uno.rs`).
//! * **Reading frames from bytes** (a host tool, a log, your own driver): [`Decoder`], one byte
//!   at a time, gives [`RawFrame`]s; [`RawFrame::parse`] gives a typed [`Frame`], and the lean
//!   views ([`RawFrame::rx16`], [`RawFrame::at_response`], [`RawFrame::tx_status`]) read the
//!   common ones without the all-types parser.
//! * **Writing frames:** [`Frame::encode`] into a caller's buffer ([`MAX_ENCODED`] bytes always
//!   fit), or [`encode_raw`] for frame data built by hand.
//!
//! ```
//! use xbee_api::{Decoder, Frame, Mode};
//!
//! // An RX16 frame as the radio sends it in API mode 2: "Hello" from 0x5001 at -41 dBm.
//! let bytes = [0x7E, 0x00, 0x0A, 0x81, 0x50, 0x01, 0x29, 0x00, 0x48, 0x65, 0x6C, 0x6C, 0x6F, 0x10];
//! let mut decoder = Decoder::new(Mode::Escaped);
//! for &b in &bytes {
//!     decoder.push(b).unwrap();
//!     while let Some(event) = decoder.poll() {
//!         let raw = event.unwrap(); // a stream error (bad checksum…) would be an `Err` here
//!         if let Ok(Frame::Rx16 { source, rssi, data, .. }) = raw.parse() {
//!             assert_eq!((source, rssi.dbm(), data), (0x5001, -41, &b"Hello"[..]));
//!         }
//!     }
//! }
//! ```
//!
//! # What is in it
//!
//! * [`Decoder`]: byte-at-a-time, bounded buffer, typed [`DecodeError`]s with counters
//!   ([`DecoderStats`]); resynchronises without losing the next good frame, in both API modes
//!   ([`Mode::Api`] = `AP=1`, [`Mode::Escaped`] = `AP=2`; [`Ap2`] fixes mode 2 at compile time).
//! * [`Frame`]: borrowed, zero-copy views of every 802.15.4 frame type; unknown types come out
//!   as [`Frame::Unknown`].
//! * [`driver`]: sends frames, polls received ones, AT commands matched by frame id with
//!   timeouts, channel switching, and bring-up of a radio found at any baud rate and in any
//!   mode (optionally with AES-128 encryption, [`driver::Encryption`]). Every wait is bounded by
//!   the clock; every failure is a distinct [`driver::Error`].
//! * [`serial`]: adapters from embedded-hal 0.2 and embedded-io serial ports to the driver's.
//!
//! # Cargo features
//!
//! None is on by default; with none, the crate depends on `embedded-hal-nb`, `nb` and
//! `heapless` only, and the adapters cost nothing.
//!
//! | feature | adds |
//! |---|---|
//! | `embedded-hal-02` | `serial::Eh02`: an `embedded-hal` 0.2 serial port (avr-hal's `arduino_hal::Usart`, for one) for the driver |
//! | `embedded-io-06` | `serial::Io06`: an `embedded-io` 0.6 port with `ReadReady` and `WriteReady` |
//! | `embedded-io-07` | `serial::Io07`: the same for `embedded-io` 0.7 |
//!
//! The crate is tested against the worked examples of Digi's manuals and against Digi's own
//! Python library, property-tested and fuzzed (see the README).
#![no_std]
#![cfg_attr(docsrs, feature(doc_cfg))]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod decode;
pub mod driver;
mod encode;
mod frame;
pub mod serial;

pub use decode::{AtResponse, DecodeError, Decoder, DecoderStats, PushError, RawFrame, Rx16};
pub use encode::{encode_raw, encoded_len, EncodeError};
pub use frame::{
    AtStatus, Frame, IoSample, IoSamples, ModemStatus, ParseError, Rssi, TxStatus,
    ADDR16_BROADCAST, ADDR64_BROADCAST,
};

/// Start delimiter of every API frame.
pub const START: u8 = 0x7E;
/// Escape byte in API mode 2: the next byte is XOR-ed with [`ESCAPE_XOR`].
pub const ESCAPE: u8 = 0x7D;
/// The value escaped bytes are XOR-ed with.
pub const ESCAPE_XOR: u8 = 0x20;
/// Software flow control bytes, escaped in API mode 2.
pub const XON: u8 = 0x11;
/// Software flow control bytes, escaped in API mode 2.
pub const XOFF: u8 = 0x13;
/// Largest frame data (type byte to last payload byte) an XBee 802.15.4 radio produces or accepts:
/// a TX64 request or RX64 frame with the maximum 100-byte RF payload (1 + 1 + 8 + 1 + 100).
pub const MAX_FRAME_DATA: usize = 111;
/// Largest RF payload of one 802.15.4 packet.
pub const MAX_RF_PAYLOAD: usize = 100;
/// Largest RF payload of one packet with AES encryption on (`EE`=1): the 802.15.4 auxiliary
/// security header takes 5 bytes of the packet, and the S1 refuses anything longer.
pub const MAX_RF_PAYLOAD_ENCRYPTED: usize = 95;
/// Bytes AES encryption (`EE`=1) adds to every packet on air: the 802.15.4 auxiliary security
/// header of security level 4 (encryption without integrity check, the only level the S1 has),
/// a 4-byte frame counter among them. It is why the RF payload limit drops from
/// [`MAX_RF_PAYLOAD`] to [`MAX_RF_PAYLOAD_ENCRYPTED`], and it makes an encrypted packet 0.16 ms
/// longer on air.
pub const SECURITY_HEADER_BYTES: usize = MAX_RF_PAYLOAD - MAX_RF_PAYLOAD_ENCRYPTED;
/// One backoff period of the 802.15.4 2.4 GHz PHY's CSMA-CA (aUnitBackoffPeriod: 20 symbols of
/// 16 µs), µs. Before each channel check a radio waits 0…2^BE − 1 of them, BE starting at the
/// radio's `RN` (0 on a factory-fresh S1: no wait at all before the first check).
pub const BACKOFF_PERIOD_US: u32 = 320;

/// The longest an S1 is taken to need between an `AT CH` frame's end and its answer, µs: it
/// answers once the new channel is in effect, and a transmit request that reaches it before
/// then may be lost. Digi documents no figure for the S1 (its advice, for later modules, is to
/// wait for the answer). The one measurement found, by an S1 user, is about 9 ms for a whole
/// loop of set channel, query it, send a packet and read its status at 57600 baud, which is
/// about what that loop's UART traffic alone takes: the switch itself is short. 2 ms, twice
/// the 1 ms an S1 takes to answer any AT command in the model, is the worst case the nodes plan
/// for and the modelled radio's default.
pub const CHANNEL_SWITCH_US: u32 = 2_000;
/// Worst-case encoded size of a frame on the wire (every byte after the start escaped).
pub const MAX_ENCODED: usize = 1 + 2 * (2 + MAX_FRAME_DATA + 1);

/// The radio's API mode (`AP` register).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// `AP=1`: API frames without escaping; `0x7E` may occur inside a frame.
    Api,
    /// `AP=2`: API frames with escaping; an unescaped `0x7E` always starts a frame.
    Escaped,
}

impl Mode {
    /// The value of the `AP` register for this mode.
    pub const fn ap(self) -> u8 {
        match self {
            Mode::Api => 1,
            Mode::Escaped => 2,
        }
    }

    /// The mode for an `AP` register value (0, transparent mode, has no frames).
    pub const fn from_ap(ap: u8) -> Option<Mode> {
        match ap {
            1 => Some(Mode::Api),
            2 => Some(Mode::Escaped),
            _ => None,
        }
    }
}

/// The API mode of a [`Decoder`] or [`driver::Radio`]: a [`Mode`] chosen at run time, or
/// [`Ap2`], fixed at compile time.
pub trait ApiMode: Copy {
    /// The mode.
    fn mode(self) -> Mode;

    /// Whether the decoder and the driver keep their counters ([`DecoderStats`] and
    /// [`driver::DriverStats`]); only `Ap2<false>` does not.
    const COUNTS: bool = true;
}

impl ApiMode for Mode {
    #[inline]
    fn mode(self) -> Mode {
        self
    }
}

/// API mode 2 (escaped), fixed at compile time: a decoder or radio of this mode has no mode
/// to look up and no AP=1 code (the re-reading of a broken frame's bytes): less AVR flash for a
/// node, which only ever talks AP=2.
///
/// `Ap2<false>` also keeps no counters: its decoder's and driver's `stats()` stay zero, and
/// everything else (frames, errors, timing) is as with `Ap2` (tested). For firmware that never
/// reads the counters (hoploc's nodes): on the AVR every increment is a call, made on every
/// frame for a counter nobody reads.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Ap2<const COUNTS: bool = true>;

impl<const COUNTS: bool> ApiMode for Ap2<COUNTS> {
    #[inline]
    fn mode(self) -> Mode {
        Mode::Escaped
    }

    const COUNTS: bool = COUNTS;
}

/// True for bytes that API mode 2 escapes.
#[inline]
pub const fn needs_escape(b: u8) -> bool {
    matches!(b, START | ESCAPE | XON | XOFF)
}

/// The API frame checksum of `data` (the frame data, from the type byte on): `0xFF` minus the low
/// byte of the sum.
pub fn checksum(data: &[u8]) -> u8 {
    0xFFu8.wrapping_sub(data.iter().fold(0u8, |s, &b| s.wrapping_add(b)))
}

/// The README's examples run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
