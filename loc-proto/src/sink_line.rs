//! The sink's output lines: one per estimate, one per report that gave none, and a periodic
//! status line. Written by sink-fw on its UART (the USB serial), read by `hoploc monitor` and
//! `hoploc replay`; the format is stable.
//!
//! Like the boot lines ([`crate::line`]): ASCII words separated by single spaces, ending in
//! `\r\n`, never `0x7E`. Each line ends with ` *XXXX`, four upper-case hex digits of the
//! CRC-16 ([`crc16`]: CRC-16/CCITT-FALSE, polynomial 0x1021, initial 0xFFFF, no reflection, no
//! final XOR) of every byte before the space that precedes `*`, so a line damaged on the way is
//! detected, not believed.
//!
//! What the check catches, for the damage a serial line does (`sink_line/tests.rs` holds the
//! code to each claim):
//! * one or two flipped bits anywhere in a line, checksum digits included, and every burst of
//!   flipped bits within 16 bits (CRC-16/CCITT has a Hamming distance of 4 for messages far
//!   longer than a line; the test flips every pair of bits of sample lines, samples three, and
//!   every burst at every position);
//! * a byte dropped or duplicated anywhere, and a line cut short anywhere (a truncated line has
//!   no ` *XXXX` of four digits at its end, or the wrong CRC): tested at every position of
//!   sample lines of each kind;
//! * random damage (one to four bits flipped, bytes changed, dropped, duplicated or inserted,
//!   the line cut): about one damaged line in 65 536 carries a matching CRC by chance, and the
//!   parser's checks of the fields (canonical numbers, the kind's count, in range) refuse most
//!   of those too. `random_damage_is_refused` damages 200 000 lines and prints how many were
//!   believed (`cargo test -p loc-proto random_damage -- --nocapture`): none (an 8-bit CRC lets
//!   about 1 in 5 000 of the same damaged lines through).
//!
//! The format is [`SinkLine`]'s `ufmt::uDisplay` (the text before the checksum); its `write`
//! and [`RawReport::write`] write a line onto any `ufmt::uWrite` through a [`Crc16Writer`],
//! which computes the checksum as the text goes by, and [`SinkLine::parse`] and
//! [`SinkOutput::parse`] read it back.
//!
//! | line | fields |
//! |---|---|
//! | `hoploc sink fix 2 417 mle 281 600 282 -4126 4 1 *CA47` | agent, sequence, estimator (`mle`: thesis MLE, `mmse`: windowed MMSE), x and y (cm), α × 100, P0 × 100 (dBm), anchors used, flags |
//! | `hoploc sink nofix 2 418 2 *93A5` | agent, sequence, usable anchors (fewer than 3) |
//! | `hoploc sink status 61 1203 240 3 1 17 480 0 2 *344B` | uptime (s), frames, reports, drops, checksum errors, foreign frames, estimates, repeats, failed transmissions |
//! | `hoploc sink report B50202…7166 *0D00` | the report message as received, in upper-case hex ([`RawReport`]) |
//!
//! The status counters, each since boot: *frames* the sink's radio passed on; *reports* among
//! them; *drops*, reports missing from an agent's sequence numbers; *checksum errors*, hoploc
//! messages that failed their checks (CRC, length, values); *foreign*, frames that are no
//! hoploc message (another device on the PAN; with a network key, also a sender with another
//! key); *estimates*; *repeats*, reports that carried a sequence number of their agent's again
//! (one of its last 16): two agents with one id, or a replay; *failed transmissions*, the
//! reports the agents' radios said they could not deliver (the channel busy or no
//! acknowledgement), as the agents' next reports tell. With the reports count standing still
//! between two status lines (one every 10 s), that tells what stops fixes: see the README's
//! "What goes wrong and what the nodes say".
//!
//! The whole `report` line of that example (agent 2, report 418, four anchors, channels 1 and 12):
//! `hoploc sink report B502023D02A2010482010C00000000E8030000E803E8030000E8033C3D3E3F3D3E3F404748494A4C4D4E4F515253544748494A4C4D4E4F515253547166 *0D00`.
//! The `report` line comes before the report's `fix` or `nofix` line(s). It carries the agent's
//! measurements ([`crate::msg::Report`]: RSSI per anchor and channel, anchor positions,
//! anchor-to-anchor relays), so `hoploc replay` can run every host estimator on a recorded log.
//! It is read with [`SinkOutput::parse`] (which reads every kind), not [`SinkLine::parse`], so a
//! [`SinkLine`] stays a few bytes on the sink's stack.
//!
//! Flags: bit 0 ([`FLAG_FITTED`]): P0 and α were fitted from this report's anchor-to-anchor RSSI
//! (else the smoothed values of earlier reports, or the prior). The sink writes one `fix` line
//! per estimator for each report.

use core::fmt;

use ufmt::{uDisplay, uWrite, uwrite, Formatter};

pub use crate::line::Crc16Writer;
use crate::line::{write_line, Dec, Head, Hex, SignedDec, Word};
use crate::msg::MAX_PAYLOAD;
use crate::Role;

/// Flag: P0 and α were fitted from this report.
pub const FLAG_FITTED: u8 = 1;

/// Which estimator produced a fix.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Estimator {
    /// The thesis' coarse-to-fine MLE.
    Mle,
    /// The posterior mean over the thesis' fine window.
    Mmse,
}

/// A line of the sink.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SinkLine {
    /// An estimate.
    Fix {
        /// The agent.
        agent: u8,
        /// The report's superframe sequence.
        seq: u16,
        /// Which estimator.
        estimator: Estimator,
        /// Position, cm.
        x: i16,
        /// Position, cm.
        y: i16,
        /// α × 100.
        alpha_x100: u16,
        /// P0 × 100, dBm.
        p0_x100: i16,
        /// Anchors used.
        anchors: u8,
        /// [`FLAG_FITTED`] and future flags.
        flags: u8,
    },
    /// A report that gave no estimate.
    NoFix {
        /// The agent.
        agent: u8,
        /// The report's superframe sequence.
        seq: u16,
        /// Usable anchors (fewer than 3).
        usable: u8,
    },
    /// The sink's counters.
    Status {
        /// Seconds since boot.
        uptime_s: u32,
        /// Frames received.
        frames: u32,
        /// Reports decoded.
        reports: u32,
        /// Reports missing from agents' sequences.
        drops: u32,
        /// Frames that failed to decode.
        checksum_errors: u32,
        /// Frames that are not hoploc messages.
        foreign: u32,
        /// Estimates made.
        fixes: u32,
        /// Reports whose sequence number their agent had sent already (one of its last 16).
        repeats: u32,
        /// Reports the agents' radios could not deliver, as their next reports said.
        failed: u32,
    },
}

/// The fields of a `status` line.
pub const STATUS_FIELDS: usize = 9;

/// Longest line [`SinkLine::write`] produces, `\r\n` included (a status line of nine
/// 10-digit counters).
pub const MAX_SINK_LINE: usize = 125;

/// Why [`SinkLine::parse`] rejected a line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SinkLineError {
    /// Not a sink line (another node's line, or noise): safe to skip.
    NotSinkLine,
    /// No ` *XXXX` checksum at the end.
    NoChecksum,
    /// The checksum does not match: the line was damaged.
    BadChecksum {
        /// The checksum the line carries.
        found: u16,
        /// The checksum of its text.
        computed: u16,
    },
    /// An unknown line kind after `hoploc sink`.
    UnknownKind,
    /// Field `index` (0 = the first after the kind) is missing or not a valid number or word.
    BadField {
        /// The field's position.
        index: u8,
    },
    /// More fields than the kind has.
    TooManyFields,
}

impl fmt::Display for SinkLineError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SinkLineError::NotSinkLine => f.write_str("not a hoploc sink line"),
            SinkLineError::NoChecksum => f.write_str("no checksum"),
            SinkLineError::BadChecksum { found, computed } => {
                write!(f, "checksum {found:04X}, text gives {computed:04X}")
            }
            SinkLineError::UnknownKind => f.write_str("unknown sink line kind"),
            SinkLineError::BadField { index } => write!(f, "bad or missing field {index}"),
            SinkLineError::TooManyFields => f.write_str("too many fields"),
        }
    }
}

impl core::error::Error for SinkLineError {}

/// The lines' CRC: CRC-16/CCITT-FALSE (polynomial 0x1021, initial 0xFFFF, no reflection, no
/// final XOR), the same as the node config's and the provisioning frames'; [`Crc16Writer`]
/// computes it as a line is written.
pub use crate::error::crc16;

/// Writes the `status` line of `fields` (those of [`SinkLine::Status`] in its order: the
/// uptime, then the counters): for a writer that keeps them in an array (the sink firmware: one
/// loop, each read as it is written, no line in memory). The same bytes as
/// [`SinkLine::write`] of that line.
pub fn write_status<W: uWrite + ?Sized>(
    fields: &[u32; STATUS_FIELDS],
    out: &mut W,
) -> Result<(), W::Error> {
    write_line(out, true, &StatusFields(fields))
}

/// The `status` line of [`write_status`]'s fields, without its checksum.
struct StatusFields<'a>(&'a [u32; STATUS_FIELDS]);

impl uDisplay for StatusFields<'_> {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
        Head(Role::Sink, Word::STATUS).fmt(f)?;
        for n in self.0 {
            uwrite!(f, " {}", Dec(*n))?;
        }
        Ok(())
    }
}

/// `mle` or `mmse`.
impl uDisplay for Estimator {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
        match self {
            Estimator::Mle => Word::MLE.fmt(f),
            Estimator::Mmse => Word::MMSE.fmt(f),
        }
    }
}

/// The line without its checksum and `\r\n`: the format of the `fix`, `nofix` and `status`
/// lines, field by field. Always inlined: a caller that builds the line it writes (the sink
/// firmware) keeps only that kind's writes.
impl uDisplay for SinkLine {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
        let head = |kind| Head(Role::Sink, kind);
        match *self {
            SinkLine::Fix {
                agent,
                seq,
                estimator,
                x,
                y,
                alpha_x100,
                p0_x100,
                anchors,
                flags,
            } => uwrite!(
                f,
                "{} {} {} {} {} {} {} {} {} {}",
                head(Word::FIX),
                Dec(agent.into()),
                Dec(seq.into()),
                estimator,
                SignedDec(x),
                SignedDec(y),
                Dec(alpha_x100.into()),
                SignedDec(p0_x100),
                Dec(anchors.into()),
                Dec(flags.into())
            ),
            SinkLine::NoFix { agent, seq, usable } => {
                let (agent, seq, usable) = (Dec(agent.into()), Dec(seq.into()), Dec(usable.into()));
                uwrite!(f, "{} {} {} {}", head(Word::NOFIX), agent, seq, usable)
            }
            SinkLine::Status { .. } => {
                StatusFields(&self.status_fields().unwrap_or([0; STATUS_FIELDS])).fmt(f)
            }
        }
    }
}

impl SinkLine {
    /// A `status` line's fields in its order (uptime, frames, reports, drops, checksum errors,
    /// foreign, estimates, repeats, failed); `None` for another line.
    pub fn status_fields(&self) -> Option<[u32; STATUS_FIELDS]> {
        match *self {
            SinkLine::Status {
                uptime_s,
                frames,
                reports,
                drops,
                checksum_errors,
                foreign,
                fixes,
                repeats,
                failed,
            } => Some([
                uptime_s,
                frames,
                reports,
                drops,
                checksum_errors,
                foreign,
                fixes,
                repeats,
                failed,
            ]),
            _ => None,
        }
    }

    /// Writes the line, checksum and `\r\n` included (at most [`MAX_SINK_LINE`] bytes): its
    /// [`uDisplay`] through a [`Crc16Writer`], then ` *XXXX\r\n`. Always inlined, as the
    /// `uDisplay`.
    #[inline(always)]
    pub fn write<W: uWrite + ?Sized>(&self, out: &mut W) -> Result<(), W::Error> {
        write_line(out, true, self)
    }

    /// Reads a line (with or without its `\r\n`). Never panics; any line not starting with
    /// `hoploc sink ` is [`SinkLineError::NotSinkLine`].
    pub fn parse(line: &str) -> Result<SinkLine, SinkLineError> {
        let (kind, words) = checked(line)?;
        let mut fields = Fields { words, index: 0 };
        let parsed = match kind {
            "fix" => SinkLine::Fix {
                agent: fields.num()?,
                seq: fields.num()?,
                estimator: match fields.next()? {
                    "mle" => Estimator::Mle,
                    "mmse" => Estimator::Mmse,
                    _ => return Err(fields.bad()),
                },
                x: fields.num()?,
                y: fields.num()?,
                alpha_x100: fields.num()?,
                p0_x100: fields.num()?,
                anchors: fields.num()?,
                flags: fields.num()?,
            },
            "nofix" => SinkLine::NoFix {
                agent: fields.num()?,
                seq: fields.num()?,
                usable: fields.num()?,
            },
            "status" => SinkLine::Status {
                uptime_s: fields.num()?,
                frames: fields.num()?,
                reports: fields.num()?,
                drops: fields.num()?,
                checksum_errors: fields.num()?,
                foreign: fields.num()?,
                fixes: fields.num()?,
                repeats: fields.num()?,
                failed: fields.num()?,
            },
            _ => return Err(SinkLineError::UnknownKind),
        };
        if fields.words.next().is_some() {
            return Err(SinkLineError::TooManyFields);
        }
        Ok(parsed)
    }
}

/// The kind word and the fields after it of a sink line whose checksum is right (with or
/// without its `\r\n`).
fn checked(line: &str) -> Result<(&str, core::str::Split<'_, char>), SinkLineError> {
    let line = line.strip_suffix('\n').unwrap_or(line);
    let line = line.strip_suffix('\r').unwrap_or(line);
    if !line.starts_with("hoploc sink ") {
        return Err(SinkLineError::NotSinkLine);
    }
    let (text, cs) = line.rsplit_once(" *").ok_or(SinkLineError::NoChecksum)?;
    let found = match cs.as_bytes() {
        [a, b, c, d] => match (unhex(*a), unhex(*b), unhex(*c), unhex(*d)) {
            (Some(a), Some(b), Some(c), Some(d)) => {
                u16::from(a) << 12 | u16::from(b) << 8 | u16::from(c) << 4 | u16::from(d)
            }
            _ => return Err(SinkLineError::NoChecksum),
        },
        _ => return Err(SinkLineError::NoChecksum),
    };
    let computed = crc16(text.as_bytes());
    if found != computed {
        return Err(SinkLineError::BadChecksum { found, computed });
    }
    let mut words = text.split(' ');
    words.next();
    words.next();
    let kind = words.next().ok_or(SinkLineError::UnknownKind)?;
    Ok((kind, words))
}

/// Longest `report` line, `\r\n` included: `hoploc sink report `, two hex digits per byte of
/// the largest message the radio carries, ` *XXXX\r\n`.
pub const MAX_REPORT_LINE: usize = 19 + 2 * MAX_PAYLOAD + 8;

/// A `report` line's message: the bytes of a [`crate::msg::Report`] as the sink received them
/// (decode with [`RawReport::report`]).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct RawReport(heapless::Vec<u8, MAX_PAYLOAD, u8>);

impl RawReport {
    /// The message `msg`, if the radio can carry it (at most [`MAX_PAYLOAD`] bytes, not empty).
    pub fn new(msg: &[u8]) -> Option<RawReport> {
        if msg.is_empty() {
            return None;
        }
        heapless::Vec::from_slice(msg).ok().map(RawReport)
    }

    /// The message bytes.
    pub fn bytes(&self) -> &[u8] {
        &self.0
    }

    /// The report the bytes encode.
    pub fn report(&self) -> Result<crate::msg::Report, crate::Error> {
        crate::msg::Report::decode(self.bytes())
    }

    /// Writes the `report` line of message `msg` (the sink does not build a [`RawReport`]: it
    /// writes the bytes it received): each byte as two upper-case hex digits. At most
    /// [`MAX_REPORT_LINE`] bytes for a message the radio carries.
    pub fn write<W: uWrite + ?Sized>(msg: &[u8], out: &mut W) -> Result<(), W::Error> {
        write_line(out, true, &ReportText(msg))
    }

    /// Reads a `report` line (with or without its `\r\n`); never panics.
    pub fn parse(line: &str) -> Result<RawReport, SinkLineError> {
        match SinkOutput::parse(line)? {
            SinkOutput::Report(r) => Ok(r),
            SinkOutput::Line(_) => Err(SinkLineError::UnknownKind),
        }
    }
}

/// The `report` line of a message, without its checksum: the message as one word of upper-case
/// hex, two digits a byte.
struct ReportText<'a>(&'a [u8]);

impl uDisplay for ReportText<'_> {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
        uwrite!(f, "{} ", Head(Role::Sink, Word::REPORT))?;
        for b in self.0 {
            Hex(*b).fmt(f)?;
        }
        Ok(())
    }
}

/// Any line the sink writes: a [`SinkLine`] or a `report` line.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum SinkOutput {
    /// A `fix`, `nofix` or `status` line.
    Line(SinkLine),
    /// A `report` line.
    Report(RawReport),
}

impl SinkOutput {
    /// Reads any sink line (with or without its `\r\n`). Never panics; a line not starting with
    /// `hoploc sink ` is [`SinkLineError::NotSinkLine`].
    pub fn parse(line: &str) -> Result<SinkOutput, SinkLineError> {
        let (kind, mut words) = checked(line)?;
        if kind != "report" {
            return SinkLine::parse(line).map(SinkOutput::Line);
        }
        let bad = SinkLineError::BadField { index: 0 };
        let word = words.next().ok_or(bad)?.as_bytes();
        if word.len() % 2 != 0 || word.is_empty() {
            return Err(bad);
        }
        let mut bytes = heapless::Vec::new();
        for pair in word.chunks_exact(2) {
            let b = match (unhex(pair[0]), unhex(pair[1])) {
                (Some(h), Some(l)) => h << 4 | l,
                _ => return Err(bad),
            };
            // More than MAX_PAYLOAD bytes do not fit.
            bytes.push(b).map_err(|_| bad)?;
        }
        if words.next().is_some() {
            return Err(SinkLineError::TooManyFields);
        }
        Ok(SinkOutput::Report(RawReport(bytes)))
    }
}

fn unhex(b: u8) -> Option<u8> {
    match b {
        b'0'..=b'9' => Some(b - b'0'),
        b'A'..=b'F' => Some(b - b'A' + 10),
        _ => None,
    }
}

/// The fields after the kind, counted for the error.
struct Fields<'a, I: Iterator<Item = &'a str>> {
    words: I,
    index: u8,
}

impl<'a, I: Iterator<Item = &'a str>> Fields<'a, I> {
    fn bad(&self) -> SinkLineError {
        SinkLineError::BadField {
            index: self.index.saturating_sub(1),
        }
    }

    fn next(&mut self) -> Result<&'a str, SinkLineError> {
        self.index = self.index.saturating_add(1);
        self.words.next().ok_or(self.bad())
    }

    /// A decimal number (no `+`, no leading zeros but `0` itself) that fits `T`.
    fn num<T: core::str::FromStr>(&mut self) -> Result<T, SinkLineError> {
        let w = self.next()?;
        let digits = w.strip_prefix('-').unwrap_or(w);
        let canonical = !digits.is_empty()
            && digits.bytes().all(|b| b.is_ascii_digit())
            && (digits == "0" || !digits.starts_with('0'))
            && w != "-0";
        if !canonical {
            return Err(self.bad());
        }
        w.parse().map_err(|_| self.bad())
    }
}

#[cfg(test)]
mod tests;
