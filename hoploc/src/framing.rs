//! The sink's serial output cut into lines, and each line told apart: what `hoploc monitor` and
//! `hoploc replay` read.
//!
//! A serial line loses bytes, flips bits and carries noise, and a board that resets writes half
//! a line. [`Framer`] cuts a byte stream into lines so that one bad stretch costs at most the
//! line it is in:
//! * a line ends at `\n`;
//! * every line a node writes starts with `hoploc `, so wherever `hoploc ` appears inside a
//!   line, the bytes before it are cut off as a line of their own (noise, or a line whose end
//!   was lost): the good line right after noise is found again;
//! * a line longer than any line a node writes ([`MAX_LINE`]) is dropped and counted
//!   ([`Framed::TooLong`]), and the search for `hoploc ` goes on inside it, so a flood of bytes
//!   without a newline never swallows the next good line, and never grows the memory.
//!
//! [`classify`] then says what a line is: a sink line whose checksum holds, a boot line, a
//! damaged sink line (its checksum fails, its fields do not parse, its bytes are not text, or
//! it is so close to a sink line that only damage explains it), or a foreign line (anything
//! else: another device's text, noise).

use loc_proto::line::{BootLine, MAX_BOOT_LINE};
use loc_proto::sink_line::{SinkLineError, SinkOutput, MAX_REPORT_LINE, MAX_SINK_LINE};

/// How every line a node writes starts.
pub const LINE_START: &[u8] = b"hoploc ";

/// The longest line a node writes, `\r\n` included: longer lines are dropped.
pub const MAX_LINE: usize = {
    let mut m = MAX_REPORT_LINE;
    if MAX_SINK_LINE > m {
        m = MAX_SINK_LINE;
    }
    if MAX_BOOT_LINE > m {
        m = MAX_BOOT_LINE;
    }
    m
};

/// What [`Framer::push`] hands out.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Framed {
    /// A line's bytes, without its `\n` (a `\r` before it is kept).
    Line(Vec<u8>),
    /// A line longer than [`MAX_LINE`] was dropped.
    TooLong,
}

/// Cuts bytes into lines (see the module docs). Sans-IO: feed it what the port gave.
#[derive(Clone, Debug, Default)]
pub struct Framer {
    /// The current line (at most [`MAX_LINE`] bytes), or while `overlong`, its last bytes.
    cur: Vec<u8>,
    /// The current line is longer than [`MAX_LINE`]: it is being skipped.
    overlong: bool,
}

impl Framer {
    /// A framer at the start of a line.
    pub fn new() -> Framer {
        Framer::default()
    }

    /// Feeds `bytes`; `out` gets every line (or dropped line) they complete, in order.
    pub fn push(&mut self, bytes: &[u8], mut out: impl FnMut(Framed)) {
        for &b in bytes {
            if b == b'\n' {
                if self.overlong {
                    out(Framed::TooLong);
                } else if !self.cur.is_empty() {
                    out(Framed::Line(std::mem::take(&mut self.cur)));
                }
                self.cur.clear();
                self.overlong = false;
                continue;
            }
            self.cur.push(b);
            let starts_here = self.cur.ends_with(LINE_START)
                && (self.overlong || self.cur.len() > LINE_START.len());
            if starts_here {
                // A line starts here: what came before is a line of its own.
                let start = self.cur.len() - LINE_START.len();
                if self.overlong {
                    out(Framed::TooLong);
                    self.overlong = false;
                } else {
                    out(Framed::Line(self.cur[..start].to_vec()));
                }
                self.cur.drain(..start);
            }
            if self.overlong {
                // Keep only what a `hoploc ` starting here could need.
                if self.cur.len() >= LINE_START.len() {
                    self.cur.drain(..self.cur.len() + 1 - LINE_START.len());
                }
            } else if self.cur.len() > MAX_LINE {
                self.overlong = true;
                self.cur.drain(..self.cur.len() + 1 - LINE_START.len());
            }
        }
    }

    /// Whether the current line is already too long (it will be dropped).
    pub fn overlong(&self) -> bool {
        self.overlong
    }

    /// The end of the input: the unfinished line, if any, as a line (or a dropped one).
    pub fn finish(&mut self) -> Option<Framed> {
        let overlong = std::mem::take(&mut self.overlong);
        let cur = std::mem::take(&mut self.cur);
        if overlong {
            Some(Framed::TooLong)
        } else {
            (!cur.is_empty()).then_some(Framed::Line(cur))
        }
    }
}

/// What a line is.
#[derive(Clone, Debug, PartialEq)]
pub enum Class {
    /// A sink line whose checksum and fields hold.
    Sink(SinkOutput),
    /// A node's boot line (`hoploc sink boot`, …: they carry no checksum).
    Boot(BootLine),
    /// A sink line that was damaged on the way: never believed.
    Damaged(Damage),
    /// Not a hoploc line (another device's text, noise, an empty line).
    Foreign,
}

/// Why a line counts as a damaged sink line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Damage {
    /// It starts as a sink line but its checksum or fields are wrong.
    Line(SinkLineError),
    /// It carries bytes that are not ASCII text (a flipped top bit, a lost byte's neighbour).
    NotText,
    /// Its start is a damaged `hoploc sink ` or it ends with a ` *XXXX` checksum, but it does
    /// not start with `hoploc sink `.
    Start,
}

impl std::fmt::Display for Damage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Damage::Line(e) => write!(f, "{e}"),
            Damage::NotText => f.write_str("bytes that are not text"),
            Damage::Start => f.write_str("a hoploc line damaged at its start or cut short"),
        }
    }
}

/// The start of every sink line.
const SINK_START: &[u8] = b"hoploc sink ";

/// Whether `line` (no `\r\n`) looks like a sink line that was damaged: its first bytes differ
/// from `hoploc sink ` in at most two places, or it starts with `hoploc ` and is no boot line,
/// or it ends with ` *` and four hex digits.
fn looks_like_sink_line(line: &[u8]) -> bool {
    let head = &line[..line.len().min(SINK_START.len())];
    let differ = SINK_START.iter().zip(head).filter(|(a, b)| a != b).count()
        + (SINK_START.len() - head.len());
    let checksum_tail = line.len() >= 6 && {
        let t = &line[line.len() - 6..];
        t[0] == b' ' && t[1] == b'*' && t[2..].iter().all(u8::is_ascii_hexdigit)
    };
    differ <= 2 || line.starts_with(LINE_START) || checksum_tail
}

/// What the line `bytes` is (with or without its `\r\n`).
pub fn classify(bytes: &[u8]) -> Class {
    let line = bytes.strip_suffix(b"\n").unwrap_or(bytes);
    let line = line.strip_suffix(b"\r").unwrap_or(line);
    let Ok(text) = std::str::from_utf8(line) else {
        return if looks_like_sink_line(line) || line.starts_with(SINK_START) {
            Class::Damaged(Damage::NotText)
        } else {
            Class::Foreign
        };
    };
    match SinkOutput::parse(text) {
        Ok(l) => Class::Sink(l),
        Err(SinkLineError::NotSinkLine) => match BootLine::parse(text) {
            Ok(b) => Class::Boot(b),
            Err(_) if looks_like_sink_line(line) => Class::Damaged(Damage::Start),
            Err(_) => Class::Foreign,
        },
        // A sink boot line starts with `hoploc sink ` too, and carries no checksum.
        Err(e) => match BootLine::parse(text) {
            Ok(b) => Class::Boot(b),
            Err(_) => Class::Damaged(Damage::Line(e)),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use loc_proto::sink_line::{Estimator, SinkLine};

    fn fix(seq: u16) -> String {
        let mut s = String::new();
        let Ok(()) = SinkLine::Fix {
            agent: 1,
            seq,
            estimator: Estimator::Mle,
            x: 350,
            y: 200,
            alpha_x100: 300,
            p0_x100: -4000,
            anchors: 4,
            flags: 1,
        }
        .write(&mut s);
        s
    }

    /// Every line `input` gives, fed in pieces of `chunk` bytes, and what `finish` gives.
    fn frame(input: &[u8], chunk: usize) -> Vec<Framed> {
        let mut f = Framer::new();
        let mut out = Vec::new();
        for piece in input.chunks(chunk.max(1)) {
            f.push(piece, |x| out.push(x));
        }
        out.extend(f.finish());
        out
    }

    fn line(s: &str) -> Framed {
        Framed::Line(s.as_bytes().to_vec())
    }

    #[test]
    fn a_good_line_right_after_noise_is_found_again() {
        let good = fix(7);
        for chunk in [1, 3, 64, 4096] {
            let input = format!("\u{0}\u{7f}garbage{good}hoploc sink fix 1 2 ml{good}");
            assert_eq!(
                frame(input.as_bytes(), chunk),
                [
                    line("\u{0}\u{7f}garbage"),
                    line(good.trim_end_matches('\n')),
                    line("hoploc sink fix 1 2 ml"),
                    line(good.trim_end_matches('\n')),
                ],
                "chunks of {chunk}"
            );
        }
    }

    #[test]
    fn a_line_too_long_is_dropped_and_counted_but_not_the_next_good_one() {
        let good = fix(8);
        let good_line = line(good.trim_end_matches('\n'));
        // Bytes without a newline, then a good line glued to them.
        let flood = "x".repeat(10 * MAX_LINE);
        let input = format!("{flood}{good}");
        for chunk in [1, 7, 4096] {
            assert_eq!(
                frame(input.as_bytes(), chunk),
                [Framed::TooLong, good_line.clone()]
            );
        }
        // A sink line made too long by noise inside it; the next line is whole.
        let long = format!("hoploc sink report {}\r\n{good}", "AB".repeat(MAX_LINE));
        assert_eq!(
            frame(long.as_bytes(), 5),
            [Framed::TooLong, good_line.clone()]
        );
        // Exactly the longest line a node writes is kept; one byte more is not.
        let max = format!("{}\n", "y".repeat(MAX_LINE));
        assert_eq!(frame(max.as_bytes(), 9), [line(&"y".repeat(MAX_LINE))]);
        let over = format!("{}\n", "y".repeat(MAX_LINE + 1));
        assert_eq!(frame(over.as_bytes(), 9), [Framed::TooLong]);
        // The framer's memory stays bounded in a flood.
        let mut f = Framer::new();
        for _ in 0..1000 {
            f.push(&[b'z'; 1000], |_| {});
            assert!(f.cur.len() <= MAX_LINE);
        }
        // An unfinished line at the end of the input.
        assert_eq!(frame(b"hoploc sink", 4), [line("hoploc sink")]);
        assert_eq!(frame(flood.as_bytes(), 100), [Framed::TooLong]);
        assert!(frame(b"\r\n\n", 1) == [line("\r")]);
    }

    #[test]
    fn damaged_lines_are_damaged_never_foreign() {
        let good = fix(9);
        assert!(matches!(classify(good.as_bytes()), Class::Sink(_)));
        let damaged = |mutate: &dyn Fn(&mut Vec<u8>)| {
            let mut v = good.clone().into_bytes();
            mutate(&mut v);
            classify(&v)
        };
        // A digit changed: the checksum fails.
        assert!(matches!(
            damaged(&|v| v[20] ^= 0x01),
            Class::Damaged(Damage::Line(SinkLineError::BadChecksum { .. }))
        ));
        // The first bytes damaged: not a sink line's start any more, but close to one.
        for i in [0, 3, 7, 11] {
            assert_eq!(
                damaged(&|v| v[i] ^= 0x04),
                Class::Damaged(Damage::Start),
                "byte {i}"
            );
        }
        assert_eq!(
            damaged(&|v| {
                v.drain(..9);
            }),
            Class::Damaged(Damage::Start)
        );
        // A flipped top bit: not text.
        assert_eq!(damaged(&|v| v[30] |= 0x80), Class::Damaged(Damage::NotText));
        assert_eq!(damaged(&|v| v[2] |= 0x80), Class::Damaged(Damage::NotText));
        // Cut short.
        assert!(matches!(
            classify(&good.as_bytes()[..25]),
            Class::Damaged(Damage::Line(_))
        ));
        // A boot line is a boot line; other text and noise are foreign.
        assert!(matches!(
            classify(b"hoploc sink boot\r\n"),
            Class::Boot(BootLine::Boot { .. })
        ));
        for foreign in [&b"hello world"[..], b"", b"\xff\xfe\x00", b"+++", b"OK\r"] {
            assert_eq!(classify(foreign), Class::Foreign, "{foreign:?}");
        }
        // A damaged boot line of another node is a damaged hoploc line too.
        assert_eq!(
            classify(b"hoploc anchor radio okk api"),
            Class::Damaged(Damage::Start)
        );
    }
}
