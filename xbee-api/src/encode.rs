//! Frame encoder: writes API frames into a caller's buffer, in either API mode.

use core::fmt;

use crate::{needs_escape, Frame, Mode, ESCAPE, ESCAPE_XOR, START};

/// Why a frame could not be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EncodeError {
    /// The output buffer is too small; `needed` bytes would have fitted it.
    BufferTooSmall {
        /// Bytes the encoded frame needs.
        needed: usize,
    },
    /// The frame data does not fit the 16-bit length field.
    TooLong,
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EncodeError::BufferTooSmall { needed } => {
                write!(f, "output buffer too small: {needed} bytes needed")
            }
            EncodeError::TooLong => f.write_str("frame data longer than 65535 bytes"),
        }
    }
}

impl core::error::Error for EncodeError {}

/// Writes bytes after the start delimiter, escaping in API mode 2, and sums the frame data.
struct Writer<'b> {
    out: &'b mut [u8],
    pos: usize,
    escape: bool,
    sum: u8,
}

impl Writer<'_> {
    fn put(&mut self, b: u8) {
        if self.escape && needs_escape(b) {
            self.raw(ESCAPE);
            self.raw(b ^ ESCAPE_XOR);
        } else {
            self.raw(b);
        }
    }
    fn raw(&mut self, b: u8) {
        // Writes past the end only advance `pos`, so the caller learns the size it needs.
        if let Some(slot) = self.out.get_mut(self.pos) {
            *slot = b;
        }
        self.pos += 1;
    }
    fn data(&mut self, b: u8) {
        self.sum = self.sum.wrapping_add(b);
        self.put(b);
    }
}

/// Writes a frame whose data is `parts` concatenated.
fn encode_parts(mode: Mode, parts: [&[u8]; 2], out: &mut [u8]) -> Result<usize, EncodeError> {
    let len = u16::try_from(parts[0].len() + parts[1].len()).map_err(|_| EncodeError::TooLong)?;
    let mut w = Writer {
        out,
        pos: 0,
        escape: mode == Mode::Escaped,
        sum: 0,
    };
    w.raw(START);
    for b in len.to_be_bytes() {
        w.put(b);
    }
    for &b in parts[0].iter().chain(parts[1]) {
        w.data(b);
    }
    w.put(0xFF - w.sum);
    if w.pos > w.out.len() {
        return Err(EncodeError::BufferTooSmall { needed: w.pos });
    }
    Ok(w.pos)
}

impl Frame<'_> {
    /// Encodes the frame into `out` and returns the number of bytes written.
    ///
    /// On [`EncodeError::BufferTooSmall`] the buffer may hold a partial frame; the error gives the
    /// size that fits. [`crate::MAX_ENCODED`] always fits a frame the radio accepts.
    pub fn encode(&self, mode: Mode, out: &mut [u8]) -> Result<usize, EncodeError> {
        let (header, rest) = crate::frame::Header::split(self);
        encode_parts(mode, [header.as_bytes(), rest], out)
    }
}

/// Encodes frame data given as raw bytes (type byte first), e.g. a frame type this crate does not
/// name.
pub fn encode_raw(frame_data: &[u8], mode: Mode, out: &mut [u8]) -> Result<usize, EncodeError> {
    encode_parts(mode, [frame_data, &[]], out)
}

/// The number of bytes [`Frame::encode`] writes for `frame` in `mode`.
pub fn encoded_len(frame: &Frame<'_>, mode: Mode) -> usize {
    match frame.encode(mode, &mut []) {
        Ok(n) | Err(EncodeError::BufferTooSmall { needed: n }) => n,
        Err(EncodeError::TooLong) => 0,
    }
}
