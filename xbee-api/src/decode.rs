//! Byte-at-a-time frame decoder with resynchronisation.
//!
//! Bytes go in with [`Decoder::push`]; frames and errors come out of [`Decoder::poll`]. The
//! decoder keeps the raw bytes of the frame it is reading, so that when that frame fails (bad
//! checksum, bad length, or the line going idle in API mode 1) it can re-read those bytes from the
//! next start delimiter: a frame that began inside a broken one is still found. In API mode 2 an
//! unescaped `0x7E` always starts a new frame, so there it simply restarts.

use core::fmt;

use crate::frame::ty;
use crate::{
    ApiMode, AtStatus, Frame, Mode, ParseError, Rssi, TxStatus, ESCAPE, ESCAPE_XOR, MAX_FRAME_DATA,
    START,
};

/// Length bytes + frame data + checksum, plus one byte of input queue.
const BUF: usize = 2 + MAX_FRAME_DATA + 1 + 1;

/// A stream-level decoding error. Each is counted in [`DecoderStats`]; the decoder has already
/// resynchronised when it reports one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DecodeError {
    /// The checksum byte did not match the frame data.
    BadChecksum {
        /// Checksum computed over the received data.
        computed: u8,
        /// Checksum byte received.
        received: u8,
    },
    /// The length field was 0 or larger than [`MAX_FRAME_DATA`].
    BadLength {
        /// The length received.
        length: u16,
    },
    /// A frame was cut short: a new start delimiter arrived inside it (API mode 2), or the line
    /// went idle before it was complete ([`Decoder::idle`]).
    Truncated {
        /// Bytes received after the start delimiter.
        received: u8,
    },
    /// Bytes outside any frame, reported when the next start delimiter ends them.
    Garbage {
        /// Number of bytes skipped (saturating).
        bytes: u16,
    },
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::BadChecksum { computed, received } => write!(
                f,
                "bad checksum: computed {computed:#04x}, received {received:#04x}"
            ),
            DecodeError::BadLength { length } => {
                write!(f, "bad length {length} (1..={MAX_FRAME_DATA} allowed)")
            }
            DecodeError::Truncated { received } => {
                write!(f, "frame truncated after {received} bytes")
            }
            DecodeError::Garbage { bytes } => write!(f, "{bytes} bytes outside any frame"),
        }
    }
}

impl core::error::Error for DecodeError {}

/// [`Decoder::push`] found its input queue full: call [`Decoder::poll`] until it returns `None`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PushError(pub u8);

impl fmt::Display for PushError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("decoder input full: poll before pushing more")
    }
}

impl core::error::Error for PushError {}

/// Counters of what the decoder has seen. They saturate rather than wrap.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct DecoderStats {
    /// Good frames.
    pub frames: u32,
    /// Frames with a bad checksum.
    pub bad_checksum: u32,
    /// Zero or oversize length fields.
    pub bad_length: u32,
    /// Frames cut short.
    pub truncated: u32,
    /// Bytes outside any frame.
    pub garbage_bytes: u32,
}

/// A frame whose length and checksum were good: its frame data, type byte first.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RawFrame<'a> {
    data: &'a [u8],
}

impl<'a> RawFrame<'a> {
    /// Wraps frame data (type byte first). The decoder guarantees it is not empty.
    pub fn new(data: &'a [u8]) -> Self {
        RawFrame { data }
    }
    /// The frame data, type byte first, checksum excluded.
    pub fn data(&self) -> &'a [u8] {
        self.data
    }
    /// The frame type byte.
    pub fn frame_type(&self) -> u8 {
        self.data.first().copied().unwrap_or(0)
    }
    /// The typed view of this frame; unknown types give [`Frame::Unknown`].
    pub fn parse(&self) -> Result<Frame<'a>, ParseError> {
        Frame::parse(self.data)
    }

    /// The fields of a 0x81 RX16 frame, or `None` for any other frame (or one too short).
    ///
    /// This and [`RawFrame::at_response`] and [`RawFrame::tx_status`] are the lean path for
    /// firmware: each reads only its own type, so a node that needs these three does not link
    /// [`RawFrame::parse`] and its 64-bit address handling. Each agrees with [`RawFrame::parse`] on
    /// every input (property-tested).
    pub fn rx16(&self) -> Option<Rx16<'a>> {
        match *self.data {
            [ty::RX16, hi, lo, rssi, options, ref data @ ..] => Some(Rx16 {
                source: u16::from_be_bytes([hi, lo]),
                rssi: Rssi(rssi),
                options,
                data,
            }),
            _ => None,
        }
    }

    /// The fields of a 0x88 AT command response, or `None` (see [`RawFrame::rx16`]).
    pub fn at_response(&self) -> Option<AtResponse<'a>> {
        match *self.data {
            [ty::AT_RESPONSE, frame_id, c0, c1, status, ref data @ ..] => Some(AtResponse {
                frame_id,
                command: [c0, c1],
                status: AtStatus(status),
                data,
            }),
            _ => None,
        }
    }

    /// The frame id and status of a 0x89 TX status frame, or `None` (see [`RawFrame::rx16`]).
    pub fn tx_status(&self) -> Option<(u8, TxStatus)> {
        match *self.data {
            [ty::TX_STATUS, frame_id, status] => Some((frame_id, TxStatus(status))),
            _ => None,
        }
    }
}

/// The fields of an RX16 frame ([`RawFrame::rx16`]); the same as [`Frame::Rx16`]'s.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rx16<'a> {
    /// Source address.
    pub source: u16,
    /// Signal strength.
    pub rssi: Rssi,
    /// Options (bit 1: address broadcast, bit 2: PAN broadcast).
    pub options: u8,
    /// RF payload.
    pub data: &'a [u8],
}

/// The fields of an AT command response ([`RawFrame::at_response`]); the same as
/// [`Frame::AtResponse`]'s.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AtResponse<'a> {
    /// Frame id of the command.
    pub frame_id: u8,
    /// Two-letter command.
    pub command: [u8; 2],
    /// Status.
    pub status: AtStatus,
    /// Register value (empty for a set command).
    pub data: &'a [u8],
}

/// What one input byte did, or what [`Decoder::poll_len`] found.
///
/// The error itself is kept in the decoder (`Decoder::error`): rustc's AVR calling convention
/// returns anything bigger than two scalars through memory, and this comes back in registers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Step {
    /// Nothing yet (from `poll_len`: no more input).
    Nothing,
    /// A good frame of this many data bytes (type byte included) is in `buf[2..]`.
    Frame(u8),
    /// A stream error, in `Decoder::error`.
    Error,
}

/// Indices of the counters in [`Decoder::counts`] (one array, one increment function: on AVR
/// a saturating `u32` increment is several instructions, better kept in one copy).
const FRAMES: usize = 0;
const BAD_CHECKSUM: usize = 1;
const BAD_LENGTH: usize = 2;
const TRUNCATED: usize = 3;
const GARBAGE_BYTES: usize = 4;

/// Adds one to a counter, saturating. Every counter of the crate (the decoder's and the
/// driver's) goes through this one function.
#[inline(never)]
pub(crate) fn count(counter: &mut u32) {
    // Not `saturating_add` nor `checked_add`, both larger on AVR: store unless it wrapped.
    let n = counter.wrapping_add(1);
    if n != 0 {
        *counter = n;
    }
}

/// Byte-at-a-time API frame decoder: bounded buffer, no allocation, never panics.
///
/// `M` is the API mode: a [`Mode`] chosen at run time (the default), or [`crate::Ap2`], API mode
/// 2 fixed at compile time, for firmware that only ever talks AP=2 and so does not link the
/// AP=1 re-reading.
///
/// ```
/// use xbee_api::{Decoder, Frame, Mode};
/// let mut dec = Decoder::new(Mode::Escaped);
/// let mut frames = 0;
/// for &b in &[0x7E, 0x00, 0x04, 0x08, 0x52, 0x4D, 0x59, 0xFF] {
///     dec.push(b).unwrap();
///     while let Some(ev) = dec.poll() {
///         let frame = ev.unwrap().parse().unwrap();
///         assert!(matches!(frame, Frame::AtCommand { command: [b'M', b'Y'], .. }));
///         frames += 1;
///     }
/// }
/// assert_eq!(frames, 1);
/// ```
#[derive(Clone, Debug)]
// `repr(C)`, small fields first: on AVR a field within 63 bytes of the struct's start is one
// `ldd`/`std` instruction away, one further out needs its address computed first.
#[repr(C)]
pub struct Decoder<M = Mode> {
    mode: M,
    /// `buf[..cur]`: raw (unescaped) bytes of the current frame after its start delimiter;
    /// `buf[ps..pe]`: input not yet processed. Always `cur <= ps <= pe <= BUF`. The indices are
    /// `u8` (`BUF` < 256): the ATmega328P is an 8-bit machine, where each `usize` (16-bit)
    /// index costs twice the instructions.
    cur: u8,
    ps: u8,
    pe: u8,
    in_frame: bool,
    escaped: bool,
    /// `error` is still to be reported (set by [`Decoder::idle`]).
    queued: bool,
    /// (After `queued`: [`Decoder::reset`] clears the fields from `cur` to here, one block.)
    garbage: u16,
    /// The sum of the current frame's bytes after the length (data and checksum), wrapping:
    /// kept as they arrive, so a complete frame is checked without a second pass.
    sum: u8,
    /// The last stream error.
    error: DecodeError,
    buf: [u8; BUF],
    /// Indexed by `FRAMES`, `BAD_CHECKSUM`, `BAD_LENGTH`, `TRUNCATED`, `GARBAGE_BYTES`.
    counts: [u32; 5],
}

impl<M: ApiMode> Decoder<M> {
    /// A decoder for the given API mode.
    pub const fn new(mode: M) -> Self {
        Decoder {
            mode,
            buf: [0; BUF],
            cur: 0,
            ps: 0,
            pe: 0,
            in_frame: false,
            escaped: false,
            garbage: 0,
            queued: false,
            sum: 0,
            error: DecodeError::Garbage { bytes: 0 },
            counts: [0; 5],
        }
    }

    /// The API mode this decoder reads.
    #[inline]
    pub fn mode(&self) -> Mode {
        self.mode.mode()
    }

    /// Drops any partial frame and queued input (the counters stay).
    pub fn reset(&mut self) {
        // Field by field rather than `*self = Decoder::new(mode)`: the buffer's old bytes are
        // never read again, and not clearing it saves the copy.
        self.cur = 0;
        self.ps = 0;
        self.pe = 0;
        self.in_frame = false;
        self.escaped = false;
        self.garbage = 0;
        self.queued = false;
    }

    /// The counters so far.
    pub fn stats(&self) -> DecoderStats {
        let c = &self.counts;
        DecoderStats {
            frames: c[FRAMES],
            bad_checksum: c[BAD_CHECKSUM],
            bad_length: c[BAD_LENGTH],
            truncated: c[TRUNCATED],
            garbage_bytes: c[GARBAGE_BYTES],
        }
    }

    /// True while a frame has started but not ended.
    pub fn in_frame(&self) -> bool {
        self.in_frame
    }

    /// Queues one input byte. Fails only if [`Decoder::poll`] was not called to `None` since the
    /// last push.
    pub fn push(&mut self, byte: u8) -> Result<(), PushError> {
        if self.pe as usize == BUF && self.ps > self.cur {
            self.buf
                .copy_within(self.ps as usize..self.pe as usize, self.cur as usize);
            self.pe -= self.ps - self.cur;
            self.ps = self.cur;
        }
        let slot = self.buf.get_mut(self.pe as usize).ok_or(PushError(byte))?;
        *slot = byte;
        self.pe += 1;
        Ok(())
    }

    /// Processes queued input up to the next frame or error. Call until it returns `None`.
    pub fn poll(&mut self) -> Option<Result<RawFrame<'_>, DecodeError>> {
        match self.poll_len() {
            Step::Nothing => None,
            Step::Frame(len) => Some(Ok(self.frame(len))),
            Step::Error => Some(Err(self.error)),
        }
    }

    /// [`Decoder::poll`] without the borrow: a frame comes out as its length, and
    /// [`Decoder::frame`] reads it (until the next `push` or `poll`); an error is in
    /// [`Decoder::error`]. The driver's wait loops use this, so they need no closure.
    pub(crate) fn poll_len(&mut self) -> Step {
        if core::mem::take(&mut self.queued) {
            return Step::Error;
        }
        while self.ps < self.pe {
            let b = self.buf.get(self.ps as usize).copied().unwrap_or(0);
            self.ps += 1;
            let step = self.step(b);
            if self.ps == self.pe {
                self.ps = self.cur;
                self.pe = self.cur;
            }
            if step != Step::Nothing {
                return step;
            }
        }
        Step::Nothing
    }

    /// The driver's way in: one byte, and what it did. In AP=2 a broken frame is never re-read,
    /// so the input queue is not needed and the byte goes straight to `step` (the queue stays
    /// empty, at `cur`); in AP=1 it is queued behind bytes a failure may have queued for
    /// re-reading, and the queue is processed as [`Decoder::poll_len`] does.
    pub(crate) fn input(&mut self, b: u8) -> Step {
        if self.mode() == Mode::Escaped {
            let step = self.step(b);
            self.ps = self.cur;
            self.pe = self.cur;
            step
        } else {
            // Cannot fail: the driver processes the queue before every byte.
            let _ = self.push(b);
            self.poll_len()
        }
    }

    /// What is waiting before the driver's next byte: the idle report ([`Decoder::idle`]) and,
    /// in AP=1, bytes a failure queued for re-reading. A decoder fed only through
    /// [`Decoder::input`] never has queued bytes in AP=2, so there only the report is looked at.
    pub(crate) fn pending(&mut self) -> Step {
        if self.mode() == Mode::Escaped {
            if core::mem::take(&mut self.queued) {
                Step::Error
            } else {
                Step::Nothing
            }
        } else {
            self.poll_len()
        }
    }

    /// The error [`Decoder::poll_len`] last reported.
    pub(crate) fn error(&self) -> DecodeError {
        self.error
    }

    /// The frame [`Decoder::poll_len`] just reported as `len` bytes long.
    pub(crate) fn frame(&self, len: u8) -> RawFrame<'_> {
        // `len` is at most MAX_FRAME_DATA (the decoder checked it); the `min` spares the
        // slice its bounds check (one compare where `get` takes two and a select).
        RawFrame::new(&self.buf[2..2 + (len as usize).min(MAX_FRAME_DATA)])
    }

    /// [`Decoder::frame`] with `get` (empty for a `len` out of range): what [`crate::driver`]'s
    /// `poll` hands out (in the nodes' receive loops this form is the smaller on AVR).
    pub(crate) fn frame_checked(&self, len: u8) -> RawFrame<'_> {
        RawFrame::new(self.buf.get(2..2 + len as usize).unwrap_or(&[]))
    }

    /// Feeds a slice and hands every frame or error to `f`.
    pub fn feed(&mut self, bytes: &[u8], mut f: impl FnMut(Result<RawFrame<'_>, DecodeError>)) {
        for &b in bytes {
            // Cannot fail: the queue is drained after every byte.
            let _ = self.push(b);
            while let Some(ev) = self.poll() {
                f(ev);
            }
        }
    }

    /// Tells the decoder the line has been idle longer than a frame takes: a partial frame is
    /// reported as truncated (by the next [`Decoder::poll`]) and, in API mode 1, its bytes are
    /// re-read from the next start delimiter so a good frame inside it comes out.
    pub fn idle(&mut self) {
        if self.in_frame && !self.queued {
            self.error = DecodeError::Truncated { received: self.cur };
            self.fail(TRUNCATED);
            self.queued = true;
        }
    }

    #[inline(never)]
    fn step(&mut self, b: u8) -> Step {
        if b == START && (!self.in_frame || self.mode() == Mode::Escaped) {
            let step = if self.in_frame {
                self.error = DecodeError::Truncated { received: self.cur };
                self.fail(TRUNCATED)
            } else if self.garbage > 0 {
                self.error = DecodeError::Garbage {
                    bytes: core::mem::take(&mut self.garbage),
                };
                Step::Error
            } else {
                Step::Nothing
            };
            self.in_frame = true;
            self.escaped = false;
            self.cur = 0;
            self.sum = 0;
            return step;
        }
        if !self.in_frame {
            // Saturating, as `count` does it: store unless it wrapped.
            let n = self.garbage.wrapping_add(1);
            if n != 0 {
                self.garbage = n;
            }
            self.tally(GARBAGE_BYTES);
            return Step::Nothing;
        }
        let b = if self.mode() == Mode::Escaped {
            if self.escaped {
                self.escaped = false;
                b ^ ESCAPE_XOR
            } else if b == ESCAPE {
                self.escaped = true;
                return Step::Nothing;
            } else {
                b
            }
        } else {
            b
        };
        // `cur` is at most MAX_FRAME_DATA + 2 here (the length check below ends every frame by
        // then); the `min` only spares the bounds check its panic path.
        self.buf[(self.cur as usize).min(BUF - 1)] = b;
        self.cur += 1;
        if self.cur < 2 {
            return Step::Nothing;
        }
        if self.cur == 2 {
            let length = u16::from_be_bytes([self.buf[0], self.buf[1]]);
            if length == 0 || length as usize > MAX_FRAME_DATA {
                self.error = DecodeError::BadLength { length };
                return self.fail(BAD_LENGTH);
            }
            return Step::Nothing;
        }
        self.sum = self.sum.wrapping_add(b);
        // The length is 1..=MAX_FRAME_DATA (checked when `cur` was 2): its low byte.
        let len = self.buf[1];
        if self.cur < len + 3 {
            return Step::Nothing;
        }
        // Data and checksum sum to 0xFF in a good frame; `b` is the checksum byte.
        if self.sum != 0xFF {
            let (received, computed) = (b, 0xFF - self.sum.wrapping_sub(b));
            self.error = DecodeError::BadChecksum { computed, received };
            return self.fail(BAD_CHECKSUM);
        }
        self.in_frame = false;
        self.tally(FRAMES);
        Step::Frame(len)
    }

    /// Adds one to counter `i` (if the mode keeps counters, [`ApiMode::COUNTS`]).
    #[inline(always)]
    fn tally(&mut self, i: usize) {
        if M::COUNTS {
            if let Some(c) = self.counts.get_mut(i) {
                count(c);
            }
        }
    }

    /// Counts the error just put in `error` on `counter`, leaves the frame, and in API mode 1
    /// queues the frame's bytes from the next start delimiter for re-reading.
    #[inline(never)]
    fn fail(&mut self, counter: usize) -> Step {
        self.tally(counter);
        self.in_frame = false;
        self.escaped = false;
        if self.mode() == Mode::Api {
            // `u8` indices and a plain scan: half the AVR code of `usize` and `position`.
            let (cur, ps, pe) = (self.cur, self.ps, self.pe);
            let mut k = 0;
            while k < cur && self.buf[k as usize] != START {
                k += 1;
            }
            if k < cur {
                let pending = pe - ps;
                self.buf.copy_within(ps as usize..pe as usize, cur as usize);
                self.buf
                    .copy_within(k as usize..(cur + pending) as usize, 0);
                self.ps = 0;
                self.pe = cur - k + pending;
            }
        }
        self.cur = 0;
        if self.ps == self.pe {
            self.ps = 0;
            self.pe = 0;
        }
        Step::Error
    }
}

impl Decoder<Mode> {
    /// Switches the API mode, dropping any partial frame.
    pub fn set_mode(&mut self, mode: Mode) {
        self.mode = mode;
        self.reset();
    }
}
