//! Radio driver: an XBee 802.15.4 radio on a serial port.
//!
//! [`Radio`] needs three things from the firmware around it:
//!
//! * **A serial port** implementing the `embedded-hal-nb` 1.0 serial traits, [`Read`] +
//!   [`Write`] of `u8`: non-blocking, a read that finds nothing or a write the UART cannot take
//!   yet answers `WouldBlock` at once. A port that implements another trait family goes
//!   through an adapter of [`crate::serial`]: embedded-hal 0.2 (avr-hal's `arduino_hal::Usart`)
//!   through `Eh02`, embedded-io 0.6 or 0.7 through `Io06` or `Io07` (each behind a cargo
//!   feature of the same name, see [`crate::serial`]).
//! * **A millisecond [`Clock`]**, which bounds every wait.
//! * **[`SetBaud`]** on the serial port, for [`Radio::bring_up`] only.
//!
//! # What to implement
//!
//! ## The clock
//!
//! [`Clock::now_ms`] returns a free-running count of milliseconds from any origin; it may wrap
//! at `u32::MAX` (the driver only ever looks at differences). What the driver asks of it:
//!
//! * **It advances on its own.** The driver's waits (an AT response, a TX status, the UART
//!   taking a byte, bring-up's guard times) spin on the clock and the UART, so the count must
//!   come from a timer interrupt or a free-running hardware counter, not from the main loop.
//!   A clock that stands still turns a silent radio into a wait that never ends.
//! * **Milliseconds, finely enough.** A wait ends when `now − start ≥ timeout`, so a clock that
//!   ticks every `t` ms ends waits up to `t` ms early or late; the shortest wait the driver
//!   times is [`IDLE_MS`] (20 ms, the gap after which a half-received frame is given up).
//!   hoploc's boards tick every 1 ms.
//!
//! A function is a clock through [`FnClock`], `FnClock(millis)` or `FnClock(|| timer.ms())`; a
//! timer type can also implement the trait itself, and `&mut C` is a clock if `C` is one.
//! arduino-hal has no millisecond count: the example below makes one from timer TC0's
//! compare-match interrupt, as avr-hal's own `uno-millis` example does.
//!
//! ## The baud rate
//!
//! [`Radio::bring_up`] finds a radio whatever it was left with: it tries the XBee's baud rates
//! ([`BAUD_RATES`]: 57600 first, then the factory 9600, then the others down to 1200 and up to
//! 111 111, the S1's real rate for `BD=7`), and leaves the radio at 57600. For that it changes
//! the host UART's rate through [`SetBaud::set_baud`], which switches the UART to that rate,
//! 8N1, and is called only once the UART has nothing left to send. A rate the UART cannot reach
//! closely enough (within about 2 %) may be left unchanged: the radio is then not found at that
//! rate, only at the others. [`SetBaud::set_bd`] can be overridden with a table of the UART's
//! divisors per `BD` value where computing a divisor is dear (no 32-bit division on the AVR).
//!
//! A HAL's UART type cannot implement this crate's trait in the firmware's crate (Rust's orphan
//! rule), so [`WithBaud`](crate::serial::WithBaud) adds it from a closure:
//! `WithBaud::new(port, |port, baud| /* set the divisor */)`.
//!
//! A firmware whose radio is already set to API mode 2 at 57600 (with Digi's XCTU, say) can do
//! without bring-up, and so without [`SetBaud`]: [`Radio::new`], then [`Radio::at_set`] for
//! the registers it needs (`MY`, `ID`, `CH`).
//!
//! # A firmware on arduino-hal
//!
//! The crate's `examples/arduino_uno.rs`, below, is a whole firmware for an Arduino Uno on
//! avr-hal's `arduino-hal`: a millisecond timer, the UART through
//! `Eh02` (feature `embedded-hal-02`) and [`WithBaud`](crate::serial::WithBaud),
//! bring-up, a beacon sent every second, and received frames polled. avr-hal is not on
//! crates.io, so this crate's tests build the example against a host stand-in for the few
//! arduino-hal and avr-device items it uses (`examples/avr-stand-in/`, same names and trait
//! shapes: its `Usart` implements the embedded-hal 0.2 serial traits, as arduino-hal's does);
//! for the Uno, the same file builds against the real crates (see its header).
//!
//! ```ignore
#![doc = include_str!("../examples/arduino_uno.rs")]
//! ```
//!
//! # Serial ports it is known to work with
//!
//! | serial port | traits | how |
//! |---|---|---|
//! | hoploc's `uno_board` `Serial` (ATmega328P USART0, interrupt-driven receive ring) | `embedded-hal-nb` 1.0 | directly: hoploc's node firmwares, tested in simavr |
//! | avr-hal's `arduino_hal::Usart` (avr-hal at commit `e5c8f37`, 2026-01; avr-device 0.8.1) | `embedded-hal` 0.2 | through `Eh02` + [`WithBaud`](crate::serial::WithBaud): `examples/arduino_uno.rs`, built against it for `avr-none` with nightly-2026-05-19 and run in simavr on hoploc's modelled S1 (bring-up of a factory-fresh radio found at 9600, then a beacon a second); checked by hand, CI builds the example against the stand-in only |
//! | embedded-hal-mock 0.11's `eh0::serial::Mock` | `embedded-hal` 0.2 | through `Eh02`: `tests/adapter_eh02.rs` |
//! | embedded-io 0.6 and 0.7 ports with `ReadReady` and `WriteReady` | `embedded-io` | through `Io06` / `Io07`: `tests/adapter_io.rs`, over a scripted port |
//!
//! Other HALs have not been tried. One whose UART implements one of these trait families
//! (with `ReadReady`/`WriteReady` for embedded-io: without them a read blocks until a byte
//! comes, which the driver cannot use) plugs in the same way.
//!
//! # How it works
//!
//! What it does, and why it is shaped this way:
//!
//! * **No buffers beyond the decoder.** Frames are escaped and written byte by byte straight to
//!   the UART ([`Radio::send`]), so the driver needs no TX buffer: its whole state is one
//!   [`Decoder`] plus a few frame ids, timestamps and counters, which matters on a 2 KB-SRAM
//!   ATmega328P.
//! * **Nothing blocks forever.** Every wait (AT response, TX status, guard times, a UART that
//!   will not take a byte) is bounded by the [`Clock`]; [`Radio::poll`] returns as soon as the
//!   UART has nothing more. A wait's `timeout_ms` counts at most 65 535 ms (a larger one waits
//!   that long): the driver times its waits on the clock's low 16 bits, half the AVR code.
//! * **Nothing received is lost.** While the driver waits for an AT response or a TX status,
//!   every other frame (beacons arriving at the same time, say) goes to the caller's `on_other`
//!   callback, unparsed ([`RawFrame`]) so even a frame this crate cannot parse gets through.
//! * **Frame ids are matched.** An AT response counts only with the frame id *and* command of
//!   the request; a late answer to an earlier, timed-out command goes to `on_other`.
//! * **Received frames are handed to a closure**, `radio.poll(|raw| ...)`, rather than returned
//!   as a borrow: the closure's result comes back by value, so the caller can act on it
//!   (send a reply, switch channel) right after. (Returning a frame borrowed from the decoder out
//!   of a read loop is the case today's borrow checker rejects.)
//! * **Lean on flash.** AT commands and TX16 requests are written from a few header bytes, and
//!   answers are matched through [`RawFrame::at_response`]/[`RawFrame::tx_status`], so a node
//!   that reads its frames with [`RawFrame::rx16`] never links the all-types [`Frame::parse`]
//!   (the crate README has the measured AVR flash of each piece).
//! * **Typed, distinct errors** ([`Error::code`]) so firmware can blink a code when bring-up
//!   fails.
//!
//! # Example
//!
//! Generic over the serial port and the clock, as a library on top of the driver would be:
//!
//! ```no_run
//! use embedded_hal_nb::serial::{Read, Write};
//! use xbee_api::driver::{BringUpConfig, Clock, Radio, SetBaud};
//! use xbee_api::{Frame, Mode};
//!
//! fn run<S, C>(serial: S, clock: C) -> Result<(), xbee_api::driver::Error>
//! where
//!     S: Read<u8> + Write<u8> + SetBaud,
//!     C: Clock,
//! {
//!     let mut radio = Radio::new(serial, clock, Mode::Escaped);
//!     // Finds the radio at any baud rate the S1 has, in any mode, and leaves it in AP=2 at 57600.
//!     let config = BringUpConfig {
//!         my: Some(0x0001),
//!         pan_id: Some(0x3332),
//!         channel: Some(0x0C), // testbed channel 2 (CH = 0x0A + n)
//!         ..BringUpConfig::new()
//!     };
//!     radio.bring_up(&config)?;
//!     radio.send_tx16(0xFFFF, b"hello")?;
//!     loop {
//!         // Frames come to the closure; what it returns comes back here by value.
//!         match radio.poll(|raw| raw.parse().ok().and_then(|f| f.rssi())) {
//!             Some(Ok(Some(rssi))) => { let _ = rssi.dbm(); }
//!             Some(Ok(None)) => {}                      // a frame without RSSI
//!             Some(Err(_e)) => {}                       // line noise: counted in stats()
//!             None => break,                            // nothing more for now
//!         }
//!     }
//!     // Waits for the TX status of the frame sent above, then switches to channel 0x0D.
//!     radio.set_channel(0x0D, 200, |_other_frame| {})?;
//!     Ok(())
//! }
//! ```

use core::fmt;

use embedded_hal_nb::serial::{Error as _, ErrorKind, Read, Write};

use crate::decode::{count, Step};
use crate::frame::ty::{AT as AT_COMMAND, AT_RESPONSE, TX16, TX64};
use crate::frame::Header;
use crate::{
    needs_escape, ApiMode, AtStatus, DecodeError, Decoder, DecoderStats, Frame, Mode, RawFrame,
    ESCAPE, ESCAPE_XOR, MAX_FRAME_DATA, MAX_RF_PAYLOAD, START,
};

/// A free-running millisecond clock. It may wrap: the driver only ever compares
/// `now.wrapping_sub(start)`, so a `u32` tick counter works across its overflow. It must
/// advance on its own (a timer interrupt or a hardware counter): the driver's waits spin on
/// it. See [the module docs](self#the-clock).
pub trait Clock {
    /// Milliseconds since an arbitrary origin.
    fn now_ms(&mut self) -> u32;
}

impl<C: Clock + ?Sized> Clock for &mut C {
    fn now_ms(&mut self) -> u32 {
        (**self).now_ms()
    }
}

/// A [`Clock`] made of a closure, e.g. `FnClock(|| board.millis())`.
pub struct FnClock<F>(pub F);

impl<F: FnMut() -> u32> Clock for FnClock<F> {
    fn now_ms(&mut self) -> u32 {
        (self.0)()
    }
}

/// Changes the host UART's baud rate; needed only by [`Radio::bring_up`], which looks for a radio
/// at several rates. The driver calls it only after the radio has answered its last command, so
/// the UART has nothing left to send.
///
/// Implement it on a serial type of the firmware's own; for a HAL's UART type (which the
/// firmware's crate may not implement this trait for), [`WithBaud`](crate::serial::WithBaud)
/// adds it from a closure. The adapters of [`crate::serial`] pass it on from what they wrap.
/// See [the module docs](self#the-baud-rate) for what bring-up asks of it.
pub trait SetBaud {
    /// Switches the UART to `baud` bit/s, 8N1.
    fn set_baud(&mut self, baud: u32);

    /// Switches the UART to the rate of the XBee's `BD` value `bd` ([`baud_of_bd`]); the driver
    /// calls only this. By default [`SetBaud::set_baud`] of that rate; a UART can override it
    /// with a table of its divisors (on the AVR: no 32-bit division).
    fn set_bd(&mut self, bd: u8) {
        self.set_baud(baud_of_bd(bd));
    }
}

impl<B: SetBaud + ?Sized> SetBaud for &mut B {
    fn set_baud(&mut self, baud: u32) {
        (**self).set_baud(baud)
    }
    fn set_bd(&mut self, bd: u8) {
        (**self).set_bd(bd)
    }
}

/// The rate an S1 really runs its UART at for `BD` value `bd`, bit/s: 1200 · 2^`bd` for 0…5,
/// 57600 for 6, and for 7 (named 115200) 111 111, the rate Digi's S1 manual gives for it: the
/// S1 divides its clock by whole numbers, and 115200 is out of its reach (a host at 115200 is
/// 3.6 % off, beyond what two UARTs tolerate together). A larger `bd` gives 111 111 too.
pub const fn baud_of_bd(bd: u8) -> u32 {
    match bd {
        0..=5 => 1200 << bd,
        6 => 57_600,
        _ => BD7_BAUD,
    }
}

/// The S1's real rate for `BD=7` (115200 by name), bit/s.
pub const BD7_BAUD: u32 = 111_111;

/// The baud rate hoploc runs the radio at (`BD=6`).
pub const BAUD: u32 = 57_600;

/// The `BD` value of [`BAUD`].
pub const BD: u8 = 6;

/// The `BD` values [`Radio::bring_up`] tries, in order: hoploc's own (57600, `BD=6`) first,
/// then the factory default (9600, `BD=3`), then the others: every value 0…7 once
/// ([`baud_code`]).
pub const BAUD_CODES: [u8; 8] = {
    let mut codes = [0; 8];
    let mut k = 0;
    while k < codes.len() {
        codes[k] = baud_code(k as u8);
        k += 1;
    }
    codes
};

/// The `k`-th `BD` value bring-up tries: 6, 3, 0, 5, 2, 7, 4, 1 (steps of 5 modulo 8 from 6,
/// which visit every value once; worked out rather than read from a table, for AVR flash).
pub const fn baud_code(k: u8) -> u8 {
    BD.wrapping_add(k.wrapping_mul(5)) & 7
}

/// The rates of [`BAUD_CODES`], in the same order (as the S1 runs them: [`baud_of_bd`]).
pub const BAUD_RATES: [u32; 8] = {
    let mut rates = [0; 8];
    let mut i = 0;
    while i < BAUD_CODES.len() {
        rates[i] = baud_of_bd(BAUD_CODES[i]);
        i += 1;
    }
    rates
};

const _: () = {
    // Every `BD` value 0…7 once.
    let mut seen = 0u8;
    let mut i = 0;
    while i < BAUD_CODES.len() {
        seen |= 1 << BAUD_CODES[i];
        i += 1;
    }
    assert!(seen == 0xFF);
    assert!(BAUD_CODES[0] == BD && baud_of_bd(BD) == BAUD);
    // The factory default second.
    assert!(BAUD_CODES[1] == 3);
};

/// The factory `CA` (clear channel assessment threshold), −dBm: −44 dBm.
pub const FACTORY_CCA_THRESHOLD: u8 = 0x2C;

/// Settings [`Radio::bring_up`] gives every radio, whatever it came with: the factory value of
/// each register (other than those [`BringUpConfig`] names) that changes how the radio sends or
/// receives, so that a second-hand radio behaves like a new one. `(command, value)`, one byte
/// each.
///
/// * `RR` 0: no XBee retries on top of the MAC's three (with `RR` > 0 Digi's S1 manual has
///   every broadcast sent `RR` + 2 times, which would keep a beacon on air into the next slot).
/// * `MM` 0: Digi's MAC mode, with acknowledgements and duplicate detection (1 and 3 send
///   unicasts without ACK, 2 passes duplicates on).
/// * `SM` 0: no sleep (a sleeping radio hears nothing).
/// * `A1` 0: no end-device association (one that looks for a coordinator scans channels and
///   sends nothing until it finds one).
/// * `PL` 4: full output power (a lower level shifts every RSSI an anchor's packets give).
///
/// Left alone, with the reason: `CE`/`A2` (a coordinator that may pick its own `ID` and `CH` at
/// power-up; bring-up sets both afterwards), `DH`/`DL`/`RO` (transparent mode only), I/O lines
/// and sampling (`D0`…`D8`, `IR`, `IC`: nothing samples while the lines are off, as from the
/// factory), `NB` (parity: a radio with parity on cannot be talked to at 8N1 to begin with).
pub const FIXED_SETTINGS: [([u8; 2], u8); 5] = [
    (*b"RR", 0),
    (*b"MM", 0),
    (*b"SM", 0),
    (*b"A1", 0),
    (*b"PL", 4),
];

/// How long a frame may stall mid-way before the driver tells the decoder the line went idle
/// ([`Decoder::idle`]). The radio sends a frame's bytes back to back, so a gap this long means
/// the rest is lost.
pub const IDLE_MS: u32 = 20;

/// How long the UART may refuse a byte before [`Error::WriteTimeout`].
pub const WRITE_TIMEOUT_MS: u32 = 100;

/// Largest AT response value [`AtValue`] keeps (`NI`, the longest 802.15.4 register, is 20).
pub const AT_VALUE_MAX: usize = 20;

/// How many transmit requests awaiting a TX status the driver tracks exactly.
const TRACKED: usize = 4;

/// Most bytes one [`Radio::poll`] reads without finding a frame, so a babbling line cannot hold
/// the caller.
const POLL_BUDGET: u16 = 256;

/// What went wrong. Every variant is distinct (see [`Error::code`]) so a failure can be told
/// apart from a blinking LED.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Error {
    /// The UART reported an error (overrun, framing…).
    Serial(ErrorKind),
    /// The UART refused a byte for [`WRITE_TIMEOUT_MS`].
    WriteTimeout,
    /// A stream error on the way in; the decoder has already resynchronised. Only
    /// [`Radio::poll`] reports these; waits count them in [`DriverStats::decoder`] and go on.
    Decode(DecodeError),
    /// The frame data is longer than a radio accepts ([`MAX_FRAME_DATA`]), or a TX request's
    /// payload longer than [`MAX_RF_PAYLOAD`].
    TooLong {
        /// Frame data length, type byte included.
        len: usize,
    },
    /// No response to an AT command in time.
    Timeout {
        /// The command.
        command: [u8; 2],
    },
    /// Transmit requests were still waiting for their TX status when the time ran out. The
    /// driver forgets them, so a retry goes ahead.
    TxStatusTimeout,
    /// The radio answered an AT command with an error status.
    At {
        /// The command.
        command: [u8; 2],
        /// The status it answered.
        status: AtStatus,
    },
    /// The radio's answer was not the expected value (a setting that did not stick, or a value
    /// of the wrong size).
    Unexpected {
        /// The command.
        command: [u8; 2],
    },
    /// Bring-up: nothing at all came back, at any baud rate.
    NoResponse,
    /// Bring-up: bytes came back, but never a valid answer, at any baud rate.
    Garbage,
    /// Bring-up: the radio answered `ERROR` to a command-mode command.
    Rejected {
        /// The command.
        command: [u8; 2],
    },
    /// Bring-up: the radio took the command-mode configuration but then did not answer in API
    /// mode at 57600.
    NotConfirmed,
}

impl Error {
    /// A small distinct number per variant (1…12), e.g. for an LED blink code.
    pub const fn code(&self) -> u8 {
        match self {
            Error::Serial(_) => 1,
            Error::WriteTimeout => 2,
            Error::Decode(_) => 3,
            Error::TooLong { .. } => 4,
            Error::Timeout { .. } => 5,
            Error::TxStatusTimeout => 6,
            Error::At { .. } => 7,
            Error::Unexpected { .. } => 8,
            Error::NoResponse => 9,
            Error::Garbage => 10,
            Error::Rejected { .. } => 11,
            Error::NotConfirmed => 12,
        }
    }
}

impl Error {
    /// What an [`Error::code`] means, in a few words (for a person reading a node's boot line or
    /// counting LED blinks); `None` for a number no error has.
    pub const fn describe_code(code: u8) -> Option<&'static str> {
        Some(match code {
            1 => "serial port error",
            2 => "serial port did not take a byte in time",
            3 => "stream error",
            4 => "frame too long",
            5 => "no response to an AT command",
            6 => "TX status still outstanding",
            7 => "AT command answered with an error status",
            8 => "unexpected answer to an AT command",
            9 => "no response from the radio at any baud rate",
            10 => "no valid answer from the radio at any baud rate",
            11 => "radio rejected a command-mode command",
            12 => "radio configured but silent in API mode",
            _ => return None,
        })
    }
}

/// Shows a two-letter command.
struct Cmd([u8; 2]);

impl fmt::Display for Cmd {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for &b in &self.0 {
            let c = if b.is_ascii_graphic() { b as char } else { '?' };
            fmt::Write::write_char(f, c)?;
        }
        Ok(())
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::Serial(k) => write!(f, "serial error: {k}"),
            Error::WriteTimeout => f.write_str("serial port did not take a byte in time"),
            Error::Decode(e) => write!(f, "{e}"),
            Error::TooLong { len } => {
                write!(f, "frame data of {len} bytes (at most {MAX_FRAME_DATA})")
            }
            Error::Timeout { command } => write!(f, "no response to AT{}", Cmd(command)),
            Error::TxStatusTimeout => f.write_str("TX status still outstanding"),
            Error::At { command, status } => {
                write!(f, "AT{} failed with status {}", Cmd(command), status.0)
            }
            Error::Unexpected { command } => write!(f, "unexpected answer to AT{}", Cmd(command)),
            Error::NoResponse => f.write_str("no response from the radio at any baud rate"),
            Error::Garbage => f.write_str("no valid answer from the radio at any baud rate"),
            Error::Rejected { command } => write!(f, "radio rejected AT{}", Cmd(command)),
            Error::NotConfirmed => f.write_str("radio configured but silent in API mode"),
        }
    }
}

impl core::error::Error for Error {}

/// The value of an AT response, copied out of the decoder's buffer (so the decoder can go on
/// reading while the caller looks at it). Numeric registers are big endian.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct AtValue(heapless::Vec<u8, AT_VALUE_MAX, u8>);

impl AtValue {
    /// Copies `data`, keeping at most [`AT_VALUE_MAX`] bytes.
    pub fn new(data: &[u8]) -> AtValue {
        let kept = &data[..data.len().min(AT_VALUE_MAX)];
        // (Fits: at most AT_VALUE_MAX bytes.)
        AtValue(heapless::Vec::from_slice(kept).unwrap_or_default())
    }
    /// The value bytes (empty after a set command).
    pub fn as_bytes(&self) -> &[u8] {
        &self.0
    }
    /// The value as a big-endian number of 1 to 4 bytes.
    pub fn as_u32(&self) -> Option<u32> {
        be_u32(self.as_bytes())
    }
}

/// `bytes` as a big-endian number of 1 to 4 bytes, if it is below 65 536 (what the driver's own
/// queries need: every register it reads is 8 or 16 bits; 16-bit arithmetic is half the AVR
/// code of 32-bit). Always inlined: its one firmware caller is `at_dyn` (less AVR flash than out
/// of line).
#[inline(always)]
fn be_u16(bytes: &[u8]) -> Option<u16> {
    if !(1..=4).contains(&bytes.len()) {
        return None;
    }
    let mut v = 0u16;
    for &b in bytes {
        if v > 0xFF {
            return None;
        }
        v = (v << 8) | u16::from(b);
    }
    Some(v)
}

/// `bytes` as a big-endian number of 1 to 4 bytes.
fn be_u32(bytes: &[u8]) -> Option<u32> {
    (1..=4)
        .contains(&bytes.len())
        .then(|| bytes.iter().fold(0u32, |v, &x| (v << 8) | x as u32))
}

/// A public wait's `timeout_ms` as the driver keeps it: 16 bits, at most 65 535 ms (on AVR
/// 16-bit arithmetic is half the code of 32-bit).
fn ms16(timeout_ms: u32) -> u16 {
    timeout_ms.min(u16::MAX.into()) as u16
}

/// The settings [`Radio::read_config`] reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RadioConfig {
    /// `MY`: 16-bit source address.
    pub my: u16,
    /// `ID`: PAN id.
    pub pan_id: u16,
    /// `CH`: channel, 0x0B…0x1A (the S1 Pro only has 0x0C…0x17).
    pub channel: u8,
    /// `AP`: 0 transparent, 1 API, 2 API with escaping.
    pub ap: u8,
}

/// What [`Radio::bring_up`] does with the radio's AES-128 encryption (`EE`, `KY`). With
/// encryption on, only radios with the same key understand each other: one whose `EE` differs
/// hears nothing, one with another key gets garbled payloads; and a packet carries at most
/// [`crate::MAX_RF_PAYLOAD_ENCRYPTED`] (95) bytes, not [`MAX_RF_PAYLOAD`] (100).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Encryption {
    /// Leaves `EE` and `KY` as they are.
    #[default]
    Leave,
    /// Turns encryption off: `EE`=0.
    Off,
    /// Sets the key `KY` (which the radio never answers a query with), then turns encryption
    /// on: `EE`=1.
    Key([u8; 16]),
}

/// What [`Radio::bring_up`] should leave the radio with, and how patient to be.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BringUpConfig {
    /// `MY` to set, if any.
    pub my: Option<u16>,
    /// `ID` (PAN id) to set, if any.
    pub pan_id: Option<u16>,
    /// `CH` to set, if any: 0x0B…0x1A on the S1; channel 0x0B does not exist on the S1 Pro
    /// (0x0C…0x17), which answers it with an error.
    pub channel: Option<u8>,
    /// `RN` to set, if any: the smallest backoff exponent of the radio's CSMA-CA (0…3). With
    /// `RN` = 0 (the factory value) a transmission goes out without a random wait before its
    /// first channel check, and so does each retry: two radios that start sending within the
    /// check's 0.3 ms collide on every attempt. `RN` = n waits 0…2^n − 1 backoff periods
    /// ([`crate::BACKOFF_PERIOD_US`]) first, at most (2^n − 1) × 0.32 ms.
    pub backoff_exponent: Option<u8>,
    /// `CA` to set, if any: the level from which the channel check finds the channel busy, in
    /// −dBm (0x24…0x50). The factory 0x2C (−44 dBm) hears only radios within about a metre.
    pub cca_threshold: Option<u8>,
    /// Encryption (`EE`, `KY`) to set, after the others.
    pub encryption: Encryption,
    /// Silence before and after `+++`. Must exceed the radio's `GT` (default 1000 ms).
    /// (16 bits: bring-up's waits are timed in 16-bit arithmetic, half the AVR code.)
    pub guard_ms: u16,
    /// How long to wait for each answer (API AT response, or `OK` in command mode). The answer
    /// to `+++` is awaited `guard_ms + timeout_ms` (at most 65 535 ms).
    pub timeout_ms: u16,
}

impl BringUpConfig {
    /// Sets nothing (encryption: [`Encryption::Leave`]); guard time 1100 ms (the radio's
    /// default `GT` is 1000 ms), 500 ms timeouts.
    pub const fn new() -> Self {
        BringUpConfig {
            my: None,
            pan_id: None,
            channel: None,
            backoff_exponent: None,
            cca_threshold: None,
            encryption: Encryption::Leave,
            guard_ms: 1100,
            timeout_ms: 500,
        }
    }
}

impl Default for BringUpConfig {
    fn default() -> Self {
        Self::new()
    }
}

/// How [`Radio::bring_up`] found the radio.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BringUp {
    /// It already answered in the configured API mode at 57600.
    AlreadyApi,
    /// It was configured (`AP`, `BD=6`, `WR`) in command mode, found at `baud`.
    Configured {
        /// The baud rate it answered at.
        baud: u32,
    },
}

/// Counters of the driver, for diagnostics. They saturate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct DriverStats {
    /// The decoder's counters (good frames, checksum/length/truncation errors, garbage bytes).
    pub decoder: DecoderStats,
    /// AT responses that matched no waiting command (wrong frame id or command, too late).
    pub unexpected: u32,
    /// AT responses (0x88) that arrived while waiting but were too short to read.
    pub malformed: u32,
    /// Frames thrown away during [`Radio::bring_up`], which has no one to give them to.
    pub dropped: u32,
    /// Serial errors reported by the UART.
    pub serial_errors: u32,
}

/// An XBee 802.15.4 radio on serial port `S`, timed by clock `C`, in API mode `M`: a [`Mode`]
/// (the default; [`Radio::set_mode`] can change it) or [`crate::Ap2`], fixed at compile time.
// `repr(C)`, small fields first, the decoder's buffer and the counters last: see `Decoder`.
#[repr(C)]
pub struct Radio<S, C, M = Mode> {
    /// What went wrong, when an inner step returned [`Failed`].
    error: Error,
    /// Last frame id handed out (0 before the first).
    last_id: u8,
    /// Bytes were read since the clock was last looked at.
    rx_since_check: bool,
    /// Frame ids of transmit requests still waiting for their TX status (0: free slot).
    pending_tx: [u8; TRACKED],
    /// When bytes were last seen, for [`IDLE_MS`]: the clock's low 16 bits (16-bit arithmetic
    /// is half the AVR code; a poll gap of a multiple of 65.5 s mid-frame would only delay the
    /// idle report by at most [`IDLE_MS`]).
    last_rx_ms: u16,
    serial: S,
    clock: C,
    decoder: Decoder<M>,
    unexpected: u32,
    malformed: u32,
    dropped: u32,
    serial_errors: u32,
}

/// An inner step of the driver failed; what went wrong is in `Radio::error`.
///
/// Why not return [`Error`] itself: rustc's AVR calling convention returns every value that
/// is not one or two scalars through memory, and `Result<_, Error>` is such a value. With the
/// error kept in the driver, `Result<(), Failed>`, `Result<u32, Failed>` and the like come back
/// in registers: on the ATmega328P no stack slot is written and read back at every `?`.
#[derive(Clone, Copy, Debug)]
struct Failed;

/// What [`Radio::next_frame`] found.
#[derive(Clone, Copy)]
enum Next {
    /// A frame of this length: [`Decoder::frame`] reads it.
    Frame(u8),
    /// Nothing more for now.
    Idle,
    /// A stream error, in [`Decoder::error`] (the decoder has resynchronised).
    Decode,
    /// A UART error, in `Radio::error`.
    Serial,
}

impl<S, C, M: ApiMode> Radio<S, C, M> {
    /// A driver for a radio in API mode `mode` (the mode [`Radio::bring_up`] will also set).
    pub fn new(serial: S, clock: C, mode: M) -> Self {
        Radio {
            serial,
            clock,
            decoder: Decoder::new(mode),
            last_id: 0,
            pending_tx: [0; TRACKED],
            last_rx_ms: 0,
            rx_since_check: false,
            unexpected: 0,
            malformed: 0,
            dropped: 0,
            serial_errors: 0,
            error: Error::NoResponse,
        }
    }

    /// Adds one to a driver counter (if the mode keeps counters, [`ApiMode::COUNTS`]).
    #[inline(always)]
    fn tally(counter: &mut u32) {
        if M::COUNTS {
            count(counter);
        }
    }

    /// Records `error` for the caller of the public method to pick up.
    #[inline(never)]
    fn fail(&mut self, error: Error) -> Failed {
        self.error = error;
        Failed
    }

    /// The public face of an inner result.
    fn public<T>(&self, result: Result<T, Failed>) -> Result<T, Error> {
        result.map_err(|Failed| self.error)
    }

    /// The API mode frames are written and read in.
    pub fn mode(&self) -> Mode {
        self.decoder.mode()
    }

    /// The counters so far.
    pub fn stats(&self) -> DriverStats {
        DriverStats {
            decoder: self.decoder.stats(),
            unexpected: self.unexpected,
            malformed: self.malformed,
            dropped: self.dropped,
            serial_errors: self.serial_errors,
        }
    }

    /// A fresh frame id: 1…255, wrapping, never 0 (0 asks the radio for no answer).
    pub fn next_frame_id(&mut self) -> u8 {
        // `max(1)` of the wrapped sum: one compare (`checked_add`'s `Option` takes two).
        self.last_id = self.last_id.wrapping_add(1).max(1);
        self.last_id
    }

    /// True while a transmit request sent with a nonzero frame id still waits for its TX status.
    pub fn tx_pending(&self) -> bool {
        // The four slots as one number: on AVR four loads and an `or`, not a loop.
        u32::from_ne_bytes(self.pending_tx) != 0
    }

    /// The serial port, e.g. for the board layer to write text lines between frames.
    pub fn serial_mut(&mut self) -> &mut S {
        &mut self.serial
    }

    /// The clock.
    pub fn clock_mut(&mut self) -> &mut C {
        &mut self.clock
    }

    /// Gives the serial port and the clock back.
    pub fn release(self) -> (S, C) {
        (self.serial, self.clock)
    }

    fn track_tx(&mut self, id: u8) {
        if id == 0 {
            return;
        }
        // A free slot, else (more than TRACKED outstanding) reuse one: that request is then
        // no longer waited for.
        // (`u8` indices: `usize` arithmetic is twice the AVR code.)
        let mut free = id % TRACKED as u8;
        for (i, &slot) in (0u8..).zip(self.pending_tx.iter()) {
            if slot == id {
                return;
            }
            if slot == 0 {
                free = i;
            }
        }
        if let Some(slot) = self.pending_tx.get_mut(usize::from(free)) {
            *slot = id;
        }
    }
}

impl<S, C> Radio<S, C, Mode> {
    /// Switches the API mode (after the radio's `AP` was changed), dropping any partial frame.
    pub fn set_mode(&mut self, mode: Mode) {
        self.decoder.set_mode(mode);
    }
}

/// Clears the slot of a TX status frame's id.
fn note_tx_status(pending: &mut [u8; TRACKED], raw: RawFrame<'_>) {
    if let Some((id, _)) = raw.tx_status() {
        for slot in pending.iter_mut().filter(|s| **s == id) {
            *slot = 0;
        }
    }
}

impl<S, C, M> Radio<S, C, M>
where
    S: Read<u8> + Write<u8>,
    C: Clock,
    M: ApiMode,
{
    /// Writes `frame`, encoded in the radio's mode. A TX64/TX16 request with a nonzero frame id
    /// is remembered until its TX status arrives (see [`Radio::wait_tx_status`]).
    pub fn send(&mut self, frame: &Frame<'_>) -> Result<(), Error> {
        let (header, rest) = Header::split(frame);
        let result = self.send_parts(header.as_bytes(), rest);
        self.public(result)
    }

    /// Writes one byte, waiting at most [`WRITE_TIMEOUT_MS`] for the UART to take it.
    #[inline(never)]
    fn write_byte(&mut self, b: u8) -> Result<(), Failed> {
        // The clock read once per byte even when the UART takes it at once: simpler code than
        // reading it only once the UART is busy, and a byte takes 174 µs on the line anyway.
        let start = self.now16();
        loop {
            match self.serial.write(b) {
                Ok(()) => return Ok(()),
                Err(nb::Error::Other(e)) => return Err(self.fail(Error::Serial(e.kind()))),
                Err(nb::Error::WouldBlock) => {
                    if self.elapsed(start) >= WRITE_TIMEOUT_MS as u16 {
                        return Err(self.fail(Error::WriteTimeout));
                    }
                }
            }
        }
    }

    /// Writes the frame whose data is `head` (type byte first) followed by `rest`. [`Radio::send`]
    /// and the lean senders ([`Radio::send_tx16`], [`Radio::at_command`]) all end here; the
    /// latter build their few header bytes themselves, so firmware that only uses them does not
    /// link the serializer for every frame type. Not forced out of line: where several senders
    /// use it LLVM keeps one copy anyway, and where only `at_dyn` does (the sink's boot) it
    /// folds in, which is less AVR flash.
    fn send_parts(&mut self, head: &[u8], rest: &[u8]) -> Result<(), Failed> {
        let len = head.len() + rest.len();
        // A TX64/TX16 request's frame id (0: no TX status wanted).
        let tx_id = match *head {
            [TX64 | TX16, id, ..] => Some(id),
            _ => None,
        };
        if len > MAX_FRAME_DATA || (tx_id.is_some() && rest.len() > MAX_RF_PAYLOAD) {
            return Err(self.fail(Error::TooLong { len }));
        }
        if let Err(e) = self.write_frame(len as u8, head, rest) {
            if let Error::Serial(_) = self.error {
                Self::tally(&mut self.serial_errors);
            }
            return Err(e);
        }
        if let Some(id) = tx_id {
            self.track_tx(id);
        }
        Ok(())
    }

    /// Writes start delimiter, length, frame data (`head` then `rest`) and checksum.
    fn write_frame(&mut self, len: u8, head: &[u8], rest: &[u8]) -> Result<(), Failed> {
        // The start delimiter is never escaped; the length bytes are, like any other. The
        // length's high byte is 0: `len` is at most MAX_FRAME_DATA.
        self.write_byte(START)?;
        self.put(0)?;
        self.put(len)?;
        let sum = self.put_all(head, 0)?;
        let sum = self.put_all(rest, sum)?;
        self.put(0xFF - sum)
    }

    /// Writes `bytes` (escaped as [`Radio::put`] does) and returns `sum` plus their sum. One
    /// out-of-line loop for both parts of a frame: a `chain` iterator, or a loop over the two
    /// slices, is a state machine with 16-bit index arithmetic on AVR.
    #[inline(never)]
    fn put_all(&mut self, bytes: &[u8], mut sum: u8) -> Result<u8, Failed> {
        for &b in bytes {
            sum = sum.wrapping_add(b);
            self.put(b)?;
        }
        Ok(sum)
    }

    /// Writes `b`, escaped if the radio is in API mode 2.
    #[inline(never)]
    fn put(&mut self, b: u8) -> Result<(), Failed> {
        if self.decoder.mode() == Mode::Escaped && needs_escape(b) {
            self.write_byte(ESCAPE)?;
            self.write_byte(b ^ ESCAPE_XOR)
        } else {
            self.write_byte(b)
        }
    }

    /// Sends `data` to 16-bit address `dest` (0xFFFF: broadcast) with a fresh frame id, which it
    /// returns: the radio answers with a TX status of that id.
    pub fn send_tx16(&mut self, dest: u16, data: &[u8]) -> Result<u8, Error> {
        let frame_id = self.next_frame_id();
        let [d0, d1] = dest.to_be_bytes();
        let result = self.send_parts(&[TX16, frame_id, d0, d1, 0], data);
        self.public(result.map(|()| frame_id))
    }

    /// Reads what the UART has until a frame is complete, and hands that frame to `f`.
    ///
    /// * `Some(Ok(r))`: a frame arrived; `r` is what `f` returned for it.
    /// * `Some(Err(e))`: a stream error ([`Error::Decode`], counted and resynchronised) or a
    ///   UART error; call again.
    /// * `None`: nothing more for now (the UART is empty, or 256 bytes went by without a frame).
    ///
    /// At most one frame per call; bytes after it stay in the UART for the next call. TX status
    /// frames are noted (see [`Radio::tx_pending`]) and still handed to `f`.
    pub fn poll<R>(&mut self, f: impl FnOnce(RawFrame<'_>) -> R) -> Option<Result<R, Error>> {
        self.poll_with_serial(|frame, _| f(frame))
    }

    /// [`Radio::poll`], with the serial port lent to `f` beside the frame: `f` can write (a line
    /// on a UART the radio shares, a reply) while it reads the frame in the driver's buffer, so
    /// the frame need not be copied out first.
    pub fn poll_with_serial<R>(
        &mut self,
        f: impl FnOnce(RawFrame<'_>, &mut S) -> R,
    ) -> Option<Result<R, Error>> {
        match self.next_frame() {
            Next::Frame(len) => Some(Ok(f(self.decoder.frame_checked(len), &mut self.serial))),
            Next::Idle => None,
            // The decode error is built here, not in `next_frame`: the waits that ignore it
            // (and a caller that drops it) then never copy it.
            Next::Decode => Some(Err(Error::Decode(self.decoder.error()))),
            Next::Serial => Some(Err(self.error)),
        }
    }

    /// The driver's inner loop, with one code path for every caller: [`Radio::poll`] without
    /// the closure. A frame comes out as its length; [`Decoder::frame`] reads it.
    #[inline(never)]
    fn next_frame(&mut self) -> Next {
        let mut budget = POLL_BUDGET;
        // What is left from before: an idle report, or (AP=1) bytes queued for re-reading.
        let mut step = self.decoder.pending();
        loop {
            match step {
                Step::Frame(len) => {
                    note_tx_status(&mut self.pending_tx, self.decoder.frame(len));
                    return Next::Frame(len);
                }
                Step::Error => return Next::Decode,
                Step::Nothing => {}
            }
            let Some(left) = budget.checked_sub(1) else {
                return Next::Idle;
            };
            budget = left;
            step = match self.serial.read() {
                Ok(b) => {
                    self.rx_since_check = true;
                    self.decoder.input(b)
                }
                Err(nb::Error::WouldBlock) => {
                    let now = self.clock.now_ms() as u16;
                    if core::mem::take(&mut self.rx_since_check) {
                        self.last_rx_ms = now;
                        return Next::Idle;
                    }
                    if !self.decoder.in_frame()
                        || now.wrapping_sub(self.last_rx_ms) < IDLE_MS as u16
                    {
                        return Next::Idle;
                    }
                    // The rest of the frame is not coming: let the decoder report it and, in
                    // AP=1, re-read a frame that started inside it.
                    self.decoder.idle();
                    self.decoder.pending()
                }
                Err(nb::Error::Other(e)) => {
                    Self::tally(&mut self.serial_errors);
                    self.error = Error::Serial(e.kind());
                    return Next::Serial;
                }
            };
        }
    }

    /// The clock's low 16 bits: the driver's waits take at most 65 535 ms ([`ms16`]) and look at
    /// the clock without a long gap, and 16-bit arithmetic is half the AVR code.
    fn now16(&mut self) -> u16 {
        self.clock.now_ms() as u16
    }

    /// Milliseconds since `start` ([`Radio::now16`], wrapping).
    fn elapsed(&mut self, start: u16) -> u16 {
        self.now16().wrapping_sub(start)
    }

    /// Sends AT command `command` (with `parameter`; empty to query) in a 0x08 frame with a fresh
    /// frame id, and waits up to `timeout_ms` for the 0x88 response with the same frame id and
    /// command. Every other frame that arrives meanwhile goes to `on_other`.
    ///
    /// Returns the response value (empty for a set command), or [`Error::At`] if the radio
    /// answered with an error status, or [`Error::Timeout`].
    pub fn at_command(
        &mut self,
        command: [u8; 2],
        parameter: &[u8],
        timeout_ms: u32,
        mut on_other: impl FnMut(RawFrame<'_>),
    ) -> Result<AtValue, Error> {
        let mut value = AtValue::new(&[]);
        let result = self.at_dyn(
            command,
            parameter,
            ms16(timeout_ms),
            Some(&mut on_other),
            Some(&mut value),
        );
        self.public(result.map(|_| value))
    }

    /// [`Radio::at_command`] without the value: sends `command` (with `parameter`) and waits up
    /// to `timeout_ms` for its response, which must have an OK status; every other frame goes
    /// to `on_other`. For setting a register, where the value is empty anyway: no [`AtValue`]
    /// is built or copied (on AVR a firmware that never asks for a value links less).
    pub fn at_set(
        &mut self,
        command: [u8; 2],
        parameter: &[u8],
        timeout_ms: u32,
        mut on_other: impl FnMut(RawFrame<'_>),
    ) -> Result<(), Error> {
        let result = self.at_dyn(
            command,
            parameter,
            ms16(timeout_ms),
            Some(&mut on_other),
            None,
        );
        self.public(result.map(|_| ()))
    }

    /// [`Radio::at_command`] for every caller: the value is copied to `value` if given, and
    /// returned as a number if it is one of 1 to 4 bytes below 65 536 ([`be_u16`]).
    /// Without `on_other` (bring-up), other frames are dropped and counted in `dropped`.
    #[inline(never)]
    fn at_dyn(
        &mut self,
        command: [u8; 2],
        parameter: &[u8],
        timeout_ms: u16,
        mut on_other: Option<&mut dyn FnMut(RawFrame<'_>)>,
        value: Option<&mut AtValue>,
    ) -> Result<Option<u16>, Failed> {
        let id = self.next_frame_id();
        let [c0, c1] = command;
        self.send_parts(&[AT_COMMAND, id, c0, c1], parameter)?;
        let start = self.now16();
        loop {
            match self.next_frame() {
                Next::Frame(len) => {
                    let raw = self.decoder.frame(len);
                    match raw.at_response() {
                        Some(r) if r.frame_id == id && r.command == command => {
                            if !r.status.is_ok() {
                                let status = r.status;
                                return Err(self.fail(Error::At { command, status }));
                            }
                            if let Some(value) = value {
                                *value = AtValue::new(r.data);
                            }
                            return Ok(be_u16(r.data));
                        }
                        Some(_) => Self::tally(&mut self.unexpected),
                        None if raw.frame_type() == AT_RESPONSE => Self::tally(&mut self.malformed),
                        None => {}
                    }
                    match on_other.as_mut() {
                        Some(f) => f(raw),
                        None => Self::tally(&mut self.dropped),
                    }
                }
                Next::Serial => return Err(Failed),
                Next::Idle | Next::Decode => {}
            }
            if self.elapsed(start) >= timeout_ms {
                return Err(self.fail(Error::Timeout { command }));
            }
        }
    }

    /// Waits up to `timeout_ms` until every transmit request sent with a nonzero frame id has
    /// had its TX status, handing every frame that arrives (TX statuses included) to
    /// `on_other`. On [`Error::TxStatusTimeout`] the outstanding requests are forgotten.
    pub fn wait_tx_status(
        &mut self,
        timeout_ms: u32,
        mut on_other: impl FnMut(RawFrame<'_>),
    ) -> Result<(), Error> {
        let result = self.wait_tx_dyn(ms16(timeout_ms), &mut on_other);
        self.public(result)
    }

    fn wait_tx_dyn(
        &mut self,
        timeout_ms: u16,
        on_other: &mut dyn FnMut(RawFrame<'_>),
    ) -> Result<(), Failed> {
        let start = self.now16();
        while self.tx_pending() {
            match self.next_frame() {
                Next::Frame(len) => on_other(self.decoder.frame(len)),
                Next::Serial => return Err(Failed),
                Next::Idle | Next::Decode => {}
            }
            if self.tx_pending() && self.elapsed(start) >= timeout_ms {
                self.pending_tx = [0; TRACKED];
                return Err(self.fail(Error::TxStatusTimeout));
            }
        }
        Ok(())
    }

    /// Switches the radio to channel `channel` (the XBee `CH` value, 0x0B…0x1A; the S1 Pro has
    /// only 0x0C…0x17). First waits for the TX status of every frame still being sent, because
    /// changing channel mid-transmission would lose it; then sends `CH` and waits for the OK.
    /// `timeout_ms` bounds each of the two waits; frames arriving meanwhile go to `on_other`.
    pub fn set_channel(
        &mut self,
        channel: u8,
        timeout_ms: u32,
        mut on_other: impl FnMut(RawFrame<'_>),
    ) -> Result<(), Error> {
        let t = ms16(timeout_ms);
        let result = self
            .wait_tx_dyn(t, &mut on_other)
            .and_then(|()| self.at_dyn(*b"CH", &[channel], t, Some(&mut on_other), None));
        self.public(result.map(|_| ()))
    }

    /// Reads `MY`, `ID`, `CH` and `AP` (each query bounded by `timeout_ms`).
    pub fn read_config(
        &mut self,
        timeout_ms: u32,
        mut on_other: impl FnMut(RawFrame<'_>),
    ) -> Result<RadioConfig, Error> {
        let result = self.read_config_dyn(ms16(timeout_ms), &mut on_other);
        self.public(result)
    }

    /// Queries a register that must be a number no larger than `max`.
    fn query(
        &mut self,
        command: [u8; 2],
        max: u16,
        timeout_ms: u16,
        on_other: Option<&mut dyn FnMut(RawFrame<'_>)>,
    ) -> Result<u16, Failed> {
        match self.at_dyn(command, &[], timeout_ms, on_other, None)? {
            Some(v) if v <= max => Ok(v),
            _ => Err(self.fail(Error::Unexpected { command })),
        }
    }

    fn read_config_dyn(
        &mut self,
        timeout_ms: u16,
        on_other: &mut dyn FnMut(RawFrame<'_>),
    ) -> Result<RadioConfig, Failed> {
        Ok(RadioConfig {
            my: self.query(*b"MY", 0xFFFF, timeout_ms, Some(&mut *on_other))?,
            pan_id: self.query(*b"ID", 0xFFFF, timeout_ms, Some(&mut *on_other))?,
            channel: self.query(*b"CH", 0xFF, timeout_ms, Some(&mut *on_other))? as u8,
            ap: self.query(*b"AP", 0xFF, timeout_ms, Some(&mut *on_other))? as u8,
        })
    }

    /// Reads and discards input for `ms`; true if any came (or the UART reported errors).
    fn quiet(&mut self, ms: u16) -> bool {
        !matches!(self.listen(ms, false), Reply::Silent)
    }

    /// Command mode: reads up to `ms` for a line `OK\r` (anything before it on the line is
    /// ignored) or `ERROR\r`.
    fn expect_ok(&mut self, ms: u16) -> Reply {
        self.listen(ms, true)
    }

    /// Reads for `ms`; if `lines`, returns as soon as `OK\r` or `ERROR\r` came.
    #[inline(never)]
    fn listen(&mut self, ms: u16, lines: bool) -> Reply {
        // The clock's low 16 bits: bring-up waits are below 65.5 s (and 16-bit arithmetic is
        // half the code of 32-bit on AVR).
        let start = self.clock.now_ms() as u16;
        // How much of `ERROR\r` and of `OK\r` the last bytes read match. Neither has a proper
        // prefix that is also a suffix, so on a mismatch the match restarts from the byte itself.
        let (mut error, mut ok) = (0, 0);
        let mut heard = false;
        while (self.clock.now_ms() as u16).wrapping_sub(start) < ms {
            match self.serial.read() {
                Ok(b) => {
                    heard = true;
                    if lines && advance(&mut error, b"ERROR\r", b) {
                        return Reply::Error;
                    }
                    if lines && advance(&mut ok, b"OK\r", b) {
                        return Reply::Ok;
                    }
                }
                Err(nb::Error::WouldBlock) => {}
                Err(nb::Error::Other(_)) => heard = true,
            }
        }
        if heard {
            Reply::Garbage
        } else {
            Reply::Silent
        }
    }

    /// Queries `AP` in API mode: the radio's mode if it answered.
    fn query_ap(&mut self, timeout_ms: u16) -> Option<u16> {
        // Twice: a radio still starting up may miss the first. (A `u8` count: an untyped range
        // is `i32`, four registers on AVR.)
        for _ in 0..2u8 {
            if let Ok(ap) = self.at_dyn(*b"AP", &[], timeout_ms, None, None) {
                return ap;
            }
        }
        None
    }
}

/// What [`Radio::bring_up`] configures in command mode, line by line, each answered `OK\r`:
/// the API mode (the digit at [`AP_DIGIT`] is replaced by the driver's mode), 57600 baud, write
/// to non-volatile memory, leave command mode.
const COMMAND_MODE_LINES: &[u8; 22] = b"ATAP2\rATBD6\rATWR\rATCN\r";
/// Index of the `AP` value in [`COMMAND_MODE_LINES`].
const AP_DIGIT: usize = 4;

/// Advances the match `progress` of `pattern` (which has no proper prefix that is also a
/// suffix) by `b`; true when the pattern is complete (it then starts over). Inlined: with
/// constant patterns it folds to a few compares (less AVR flash than one shared copy).
fn advance(progress: &mut u8, pattern: &[u8], b: u8) -> bool {
    *progress = if pattern.get(*progress as usize) == Some(&b) {
        *progress + 1
    } else {
        u8::from(pattern.first() == Some(&b))
    };
    if *progress as usize == pattern.len() {
        *progress = 0;
        return true;
    }
    false
}

/// A command-mode answer.
enum Reply {
    Ok,
    Error,
    Garbage,
    Silent,
}

impl<S, C, M> Radio<S, C, M>
where
    S: Read<u8> + Write<u8> + SetBaud,
    C: Clock,
    M: ApiMode,
{
    /// Radio bring-up: makes sure the radio talks API mode [`Radio::mode`] at 57600 baud, then
    /// sets `MY`, `ID`, `CH`, `RN` and `CA` as `config` asks, then encryption
    /// ([`BringUpConfig::encryption`]: [`Encryption::Off`] sets `EE`=0, [`Encryption::Key`] sets
    /// `KY` and then `EE`=1), then the [`FIXED_SETTINGS`]. Each must be answered with status OK
    /// (the radio answers a value it does not take with an error status: [`Error::At`]). None
    /// of these is written to the radio's non-volatile memory (`WR`): bring-up sets them at
    /// every boot, so a radio's flash is written only when its mode or baud rate had to change
    /// (below).
    ///
    /// 1. At 57600, query `AP` in API mode. If the radio answers with our mode: done
    ///    ([`BringUp::AlreadyApi`]), the usual case, taking milliseconds.
    /// 2. Otherwise (transparent mode, the other API mode, another baud rate), for each of
    ///    [`BAUD_RATES`]: keep silent for the guard time, send `+++`, and if `OK\r` comes back
    ///    (after the radio's own guard time), send `ATAPn\r`, `ATBD6\r`, `ATWR\r`, `ATCN\r`,
    ///    each answered `OK\r`. `WR` makes it stick, so this happens once per radio.
    /// 3. Back at 57600, confirm with an `AP` query ([`BringUp::Configured`]).
    ///
    /// A radio that never answers costs about `8 × (2 × guard_ms + timeout_ms)` plus the API
    /// queries, then [`Error::NoResponse`] (or [`Error::Garbage`] if bytes came back but never
    /// a valid answer). Frames received during bring-up are dropped (counted in
    /// [`DriverStats::dropped`]).
    pub fn bring_up(&mut self, config: &BringUpConfig) -> Result<BringUp, Error> {
        let result = self.bring_up_dyn(config);
        self.public(result)
    }

    /// [`Radio::bring_up`]'s body. Not forced out of line: it has one caller, and inlined
    /// (with the command-mode step) it is less AVR flash.
    fn bring_up_dyn(&mut self, cfg: &BringUpConfig) -> Result<BringUp, Failed> {
        let ap = u16::from(self.mode().ap());
        // Steps 1 and 3 are the same query: once before configuring, once after.
        let mut how = BringUp::AlreadyApi;
        loop {
            self.serial.set_bd(BD);
            self.decoder.reset();
            let answer = self.query_ap(cfg.timeout_ms);
            if answer == Some(ap) {
                break;
            }
            if let BringUp::Configured { .. } = how {
                return Err(self.fail(match answer {
                    Some(_) => Error::Unexpected { command: *b"AP" },
                    None => Error::NotConfirmed,
                }));
            }
            how = BringUp::Configured {
                baud: self.configure_in_command_mode(cfg)?,
            };
        }
        // The config's six registers, then the fixed settings, as data through one loop: one
        // copy of the set.
        for i in 0..6 + FIXED_SETTINGS.len() as u8 {
            let (command, value) = match i {
                0 => (*b"MY", cfg.my),
                1 => (*b"ID", cfg.pan_id),
                2 => (*b"CH", cfg.channel.map(u16::from)),
                3 => (*b"RN", cfg.backoff_exponent.map(u16::from)),
                4 => (*b"CA", cfg.cca_threshold.map(u16::from)),
                // `KY` before `EE`=1.
                5 => match cfg.encryption {
                    Encryption::Leave => continue,
                    Encryption::Off => (*b"EE", Some(0)),
                    Encryption::Key(ref key) => {
                        self.at_dyn(*b"KY", key, cfg.timeout_ms, None, None)?;
                        (*b"EE", Some(1))
                    }
                },
                _ => {
                    let (command, value) = FIXED_SETTINGS[usize::from(i - 6)];
                    (command, Some(u16::from(value)))
                }
            };
            let Some(value) = value else { continue };
            // All but `MY` and `ID` are one byte.
            let bytes = value.to_be_bytes();
            let param = if i >= 2 { &bytes[1..] } else { &bytes[..] };
            // The radio answers a value it does not take with an error status (`Error::At`).
            self.at_dyn(command, param, cfg.timeout_ms, None, None)?;
        }
        Ok(how)
    }

    /// Step 2 of [`Radio::bring_up`]: the baud rate the radio was found at. (Inlined into its
    /// one caller: less AVR flash than out of line.)
    fn configure_in_command_mode(&mut self, cfg: &BringUpConfig) -> Result<u32, Failed> {
        let mut heard = false;
        for k in 0..BAUD_CODES.len() as u8 {
            let bd = baud_code(k);
            self.serial.set_bd(bd);
            heard |= self.quiet(cfg.guard_ms);
            for &b in b"+++" {
                self.write_byte(b)?;
            }
            match self.expect_ok(cfg.guard_ms.saturating_add(cfg.timeout_ms)) {
                Reply::Ok => {}
                Reply::Silent => continue,
                Reply::Garbage | Reply::Error => {
                    heard = true;
                    continue;
                }
            }
            // Each line is answered `OK\r`; the `AP` digit is the driver's mode.
            let (mut command, mut column) = ([0; 2], 0u8);
            for (i, &b) in COMMAND_MODE_LINES.iter().enumerate() {
                let b = if i == AP_DIGIT {
                    b'0' + self.mode().ap()
                } else {
                    b
                };
                self.write_byte(b)?;
                // The command: the two letters after `AT`.
                match column {
                    2 => command[0] = b,
                    3 => command[1] = b,
                    _ => {}
                }
                column += 1;
                if b != b'\r' {
                    continue;
                }
                column = 0;
                match self.expect_ok(cfg.timeout_ms) {
                    Reply::Ok => {}
                    Reply::Error => return Err(self.fail(Error::Rejected { command })),
                    Reply::Garbage | Reply::Silent => {
                        return Err(self.fail(Error::Timeout { command }))
                    }
                }
            }
            return Ok(baud_of_bd(bd));
        }
        Err(self.fail(if heard {
            Error::Garbage
        } else {
            Error::NoResponse
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::{baud_of_bd, be_u16, be_u32, AtValue, AT_VALUE_MAX};

    /// `BD` 0…7 are the XBee 802.15.4's rates (its manual's table).
    #[test]
    fn baud_of_bd_is_the_xbee_table() {
        // BD=7 is named 115200; the S1 runs it at 111 111.
        let table = [1200, 2400, 4800, 9600, 19_200, 38_400, 57_600, 111_111];
        for (bd, &baud) in (0u8..).zip(table.iter()) {
            assert_eq!(baud_of_bd(bd), baud);
        }
        assert_eq!(baud_of_bd(8), 111_111);
    }

    /// An AT value keeps the first [`AT_VALUE_MAX`] bytes of a response, all of a shorter one.
    #[test]
    fn at_values_keep_up_to_their_capacity() {
        let data: [u8; AT_VALUE_MAX + 3] = core::array::from_fn(|i| i as u8 + 1);
        for n in 0..=data.len() {
            let v = AtValue::new(&data[..n]);
            assert_eq!(v.as_bytes(), &data[..n.min(AT_VALUE_MAX)], "{n}");
        }
        assert_eq!(AtValue::new(&[0x12, 0x34]).as_u32(), Some(0x1234));
        assert_eq!(AtValue::new(&[]).as_u32(), None);
    }

    /// `be_u16` is `be_u32` where that fits in 16 bits, and `None` elsewhere: every length 0…5
    /// over bytes that probe each position's zero/nonzero cases.
    #[test]
    fn be_u16_is_be_u32_below_65536() {
        let probe = [0x00, 0x01, 0x7F, 0xFF];
        let mut checked = 0;
        for len in 0..=5u32 {
            for mut k in 0..probe.len().pow(len) {
                let mut buf = [0u8; 5];
                for b in &mut buf[..len as usize] {
                    *b = probe[k % probe.len()];
                    k /= probe.len();
                }
                let bytes = &buf[..len as usize];
                let want = be_u32(bytes).and_then(|v| u16::try_from(v).ok());
                assert_eq!(be_u16(bytes), want, "{bytes:02X?}");
                checked += 1;
            }
        }
        assert_eq!(checked, 1 + 4 + 16 + 64 + 256 + 1024);
    }
}
