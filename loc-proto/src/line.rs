//! Text lines a node writes on its UART (the USB serial, which the radio shares).
//!
//! Lines are ASCII words separated by single spaces, ending in `\r\n`, and never contain `0x7E`
//! (the radio would take it for the start of an API frame). Every line starts with `hoploc` and the
//! node's role:
//!
//! | line | meaning |
//! |---|---|
//! | `hoploc anchor boot` | the firmware started |
//! | `hoploc anchor radio ok api` | the radio already answered in API mode at 57600 |
//! | `hoploc anchor radio ok 9600` | the radio was found in command mode at 9600 baud and configured |
//! | `hoploc anchor radio error 9 try 2` | bring-up attempt 2 failed with driver error code 9 |
//! | `hoploc anchor provisioned` | a provisioning frame was stored in EEPROM (after its ACK) |
//! | `hoploc anchor config eeprom id 2` | the node runs with the config in its EEPROM, node id 2 |
//! | `hoploc anchor config built-in id 1` | the EEPROM is erased: the node runs with the config it was built with |
//! | `hoploc anchor config error 7` | the EEPROM holds a config the node must not run with; it waits for a provisioning frame |
//!
//! The radio error code is `xbee_api::driver::Error::code` (9: no answer at any baud rate, 10:
//! only garbage), the same number the node blinks on its LED. The config error code is
//! `loc_proto::Error::code` of the stored block (2 bad magic, 3 another layout version, 7 bad
//! CRC, …) or 10 ([`crate::config::WRONG_ROLE`]: a valid config of another role); the node
//! blinks it too.
//!
//! The format is [`BootLine`]'s `ufmt::uDisplay`: the firmware writes lines with
//! [`BootLine::write`] onto any `ufmt::uWrite` (the UART; no `core::fmt`, the words read from a
//! table in flash), the host tools read them with [`BootLine::parse`], which never panics and
//! says what was wrong, and `Display` shows them.

use core::fmt;

use ufmt::{uDisplay, uWrite, uwrite, Formatter};

use crate::Role;

/// Every word of the boot lines and the sink's lines ([`crate::sink_line`]), space separated,
/// indexed by [`Word`]: one table for every line a node writes.
const WORD_LIST: &[u8] =
    b"hoploc anchor agent sink boot radio ok api error try config eeprom built-in id provisioned fix nofix status mle mmse report";

/// [`WORD_LIST`] without its spaces: each word's last byte has bit 7 set instead (lines are
/// ASCII), which saves the table a byte per word.
const fn packed_words<const N: usize>() -> [u8; N] {
    let mut out = [0u8; N];
    let (mut i, mut j) = (0, 0);
    while i < WORD_LIST.len() {
        if WORD_LIST[i] != b' ' {
            let last = i + 1 == WORD_LIST.len() || WORD_LIST[i + 1] == b' ';
            out[j] = WORD_LIST[i] | if last { 0x80 } else { 0 };
            j += 1;
        }
        i += 1;
    }
    assert!(j == N);
    out
}

/// Bytes of [`WORD_LIST`] that are not spaces.
const PACKED_LEN: usize = {
    let (mut i, mut n) = (0, 0);
    while i < WORD_LIST.len() {
        n += (WORD_LIST[i] != b' ') as usize;
        i += 1;
    }
    n
};

avr_progmem::progmem! {
    /// [`WORD_LIST`] packed ([`packed_words`]), in flash on AVR.
    static progmem WORDS: [u8; PACKED_LEN] = packed_words();
}

/// Byte `i` of [`WORDS`]. Out of line: on AVR a flash read goes through a stack slot, whose
/// frame then stays out of [`Word`]'s loop.
#[inline(never)]
fn word_byte(i: u8) -> u8 {
    WORDS.load_at(i as usize)
}

// `ConfigSource`'s `uDisplay` takes `built-in` as the word after `eeprom`.
const _: () = assert!(Word::BUILT_IN.0 == Word::EEPROM.0 + 1);

/// A word of [`WORDS`] by its index, written with ufmt ([`uDisplay`]) from the table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Word(pub(crate) u8);

impl Word {
    pub(crate) const HOPLOC: Word = Word(0);
    // Roles: 1 + Role as u8.
    const BOOT: Word = Word(4);
    const RADIO: Word = Word(5);
    const OK: Word = Word(6);
    const API: Word = Word(7);
    pub(crate) const ERROR: Word = Word(8);
    const TRY: Word = Word(9);
    pub(crate) const CONFIG: Word = Word(10);
    pub(crate) const EEPROM: Word = Word(11);
    pub(crate) const BUILT_IN: Word = Word(12);
    pub(crate) const ID: Word = Word(13);
    pub(crate) const PROVISIONED: Word = Word(14);
    /// `fix`, the first of the sink lines' own words (`fix nofix status mle mmse report`, in
    /// that order).
    pub(crate) const FIX: Word = Word(15);
    pub(crate) const NOFIX: Word = Word(16);
    pub(crate) const STATUS: Word = Word(17);
    pub(crate) const MLE: Word = Word(18);
    pub(crate) const MMSE: Word = Word(19);
    pub(crate) const REPORT: Word = Word(20);
}

/// The word's bytes, read from flash one at a time, each written as a one-byte `str` (the
/// table is ASCII: bit 7 only marks a word's last byte). The words stay in flash because a
/// string literal in a format string would be copied into the MCU's SRAM at boot.
impl uDisplay for Word {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
        word(self.0, f)
    }
}

/// Writes word `k` of [`WORDS`]. Out of line and by value (a `uDisplay` takes its value by
/// reference, through memory on AVR): one copy per writer type, called with a register.
#[inline(never)]
fn word<W: uWrite + ?Sized>(k: u8, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
    // Skip `k` words, then write one. A `u8` position and word count: few registers live
    // across the writes. (An index past the last word panics in `word_byte`'s index check:
    // nothing past the table is read.)
    let mut i = 0u8;
    let mut left = k;
    while left != 0 {
        if word_byte(i) & 0x80 != 0 {
            left -= 1;
        }
        i += 1;
    }
    loop {
        let b = word_byte(i);
        i += 1;
        ascii(b & 0x7F, f)?;
        if b & 0x80 != 0 {
            return Ok(());
        }
    }
}

/// Writes the ASCII byte `b` (below 0x80) as a one-byte `str` from a register: the lines'
/// punctuation and hex digits are written this way, not as string literals, which would be
/// copied into the MCU's SRAM at boot. Out of line: one copy per writer type.
#[inline(never)]
pub(crate) fn ascii<W: uWrite + ?Sized>(b: u8, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
    f.write_str(char::from(b).encode_utf8(&mut [0; 4]))
}

/// A byte as two upper-case hex digits: the sink lines' checksum and a `report` line's
/// message. (ufmt's `{:02X}` links its general hex routine, with padding and `0x` prefixes, for
/// these two digits.)
#[derive(Clone, Copy)]
pub(crate) struct Hex(pub(crate) u8);

impl uDisplay for Hex {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
        hex(self.0, f)
    }
}

/// [`Hex`]'s digits. Out of line and by value (see [`word`]).
#[inline(never)]
fn hex<W: uWrite + ?Sized>(b: u8, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
    let digit = |n: u8| if n < 10 { b'0' + n } else { b'A' + n - 10 };
    ascii(digit(b >> 4), f)?;
    ascii(digit(b & 15), f)
}

/// How every line starts: `hoploc`, the role of the node that writes it, and the line's kind
/// word.
#[derive(Clone, Copy)]
pub(crate) struct Head(pub(crate) Role, pub(crate) Word);

impl uDisplay for Head {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
        head(self.0, self.1 .0, f)
    }
}

/// [`Head`]'s words. Out of line and by value (see [`word`]).
#[inline(never)]
fn head<W: uWrite + ?Sized>(
    role: Role,
    kind: u8,
    f: &mut Formatter<'_, W>,
) -> Result<(), W::Error> {
    uwrite!(f, "{} {} {}", Word::HOPLOC, role, Word(kind))
}

/// A number field of a line, in decimal: ufmt's `u32` decimal, out of line. ufmt's integer
/// formatting is generic over the writer, large on AVR, and inlined where it is used: every
/// number field of every line goes through this one copy instead ([`SignedDec`] too).
#[derive(Clone, Copy)]
pub(crate) struct Dec(pub(crate) u32);

impl uDisplay for Dec {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
        dec(self.0, false, f)
    }
}

/// A signed number field in decimal, `-` first if negative: the sign, then its magnitude through
/// [`Dec`]'s copy of ufmt's decimal (ufmt's own `i16` is a second routine as large).
#[derive(Clone, Copy)]
pub(crate) struct SignedDec(pub(crate) i16);

impl uDisplay for SignedDec {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
        dec(self.0.unsigned_abs().into(), self.0 < 0, f)
    }
}

/// `-` if `negative`, then `n` in ufmt's decimal. Out of line and by value (see [`word`]).
#[inline(never)]
fn dec<W: uWrite + ?Sized>(
    n: u32,
    negative: bool,
    f: &mut Formatter<'_, W>,
) -> Result<(), W::Error> {
    if negative {
        ascii(b'-', f)?;
    }
    n.fmt(f)
}

/// The role's word (`anchor`, `agent`, `sink`): the second word of every line.
impl uDisplay for Role {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
        Word(1 + *self as u8).fmt(f)
    }
}

/// A [`uWrite`] that passes everything on to the writer it wraps and keeps the CRC-16
/// ([`crate::sink_line::crc16`]) of what went through: the sink lines' checksum is computed as
/// the line is written, with no line in memory.
pub struct Crc16Writer<'w, W: ?Sized> {
    out: &'w mut W,
    crc: u16,
}

impl<'w, W: uWrite + ?Sized> Crc16Writer<'w, W> {
    /// A writer to `out`, nothing written yet (the CRC's initial value, 0xFFFF).
    pub fn new(out: &'w mut W) -> Crc16Writer<'w, W> {
        Crc16Writer {
            out,
            crc: crate::error::CRC16_INIT,
        }
    }

    /// The CRC-16 of everything written so far.
    pub fn crc(&self) -> u16 {
        self.crc
    }
}

impl<W: uWrite + ?Sized> uWrite for Crc16Writer<'_, W> {
    type Error = W::Error;

    /// Out of line: every piece of every line is a call here.
    #[inline(never)]
    fn write_str(&mut self, s: &str) -> Result<(), W::Error> {
        self.crc = crate::error::crc16_update(self.crc, s.as_bytes());
        self.out.write_str(s)
    }
}

/// Writes one line onto `out`: `text`, then ` *XXXX` (the CRC-16 of `text`, four upper-case hex
/// digits) if `checked`, then `\r\n`. Every line a node writes, boot or sink, goes through here
/// and through a [`Crc16Writer`] around `out` (a boot line's CRC is not written): one writer
/// type, so a firmware has one copy of ufmt's writers. Always inlined: a caller that writes a
/// line whose kind it knows keeps only that kind's writes, and one call for its end.
#[inline(always)]
pub(crate) fn write_line<W: uWrite + ?Sized>(
    out: &mut W,
    checked: bool,
    text: &impl uDisplay,
) -> Result<(), W::Error> {
    let mut w = Crc16Writer::new(out);
    text.fmt(&mut Formatter::new(&mut w))?;
    end_line(&mut w, checked)
}

/// A line's end: ` *XXXX` (the CRC of what `w` wrote) if `checked`, then `\r\n`. Out of line:
/// one copy per writer type, however many kinds of line a firmware writes.
#[inline(never)]
fn end_line<W: uWrite + ?Sized>(w: &mut Crc16Writer<'_, W>, checked: bool) -> Result<(), W::Error> {
    let crc = w.crc();
    let f = &mut Formatter::new(w);
    if checked {
        ascii(b' ', f)?;
        ascii(b'*', f)?;
        Hex((crc >> 8) as u8).fmt(f)?;
        Hex(crc as u8).fmt(f)?;
    }
    ascii(b'\r', f)?;
    ascii(b'\n', f)
}

/// A `core::fmt` formatter as a [`uWrite`]: [`fmt::Display`] of a line is its [`uDisplay`].
struct FmtWriter<'a, 'b>(&'a mut fmt::Formatter<'b>);

impl uWrite for FmtWriter<'_, '_> {
    type Error = fmt::Error;

    fn write_str(&mut self, s: &str) -> fmt::Result {
        self.0.write_str(s)
    }
}

/// `value`'s [`uDisplay`] through `f`: the [`fmt::Display`] of every line type.
pub(crate) fn display(value: &impl uDisplay, f: &mut fmt::Formatter<'_>) -> fmt::Result {
    let mut w = FmtWriter(f);
    uwrite!(w, "{}", value)
}

/// How the radio was found at boot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RadioFound {
    /// Already in the API mode hoploc uses, at 57600 baud.
    Api,
    /// In command mode at this baud rate; it has been switched to API mode at 57600 (and saved).
    Configured {
        /// The baud rate it answered at.
        baud: u32,
    },
}

/// A line a node writes while it boots.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BootLine {
    /// `hoploc <role> boot`: the firmware started.
    Boot {
        /// The node's role.
        role: Role,
    },
    /// `hoploc <role> radio ok api|<baud>`: the radio is up, `MY`/`ID`/`CH` set and read back.
    RadioUp {
        /// The node's role.
        role: Role,
        /// How the radio was found.
        found: RadioFound,
    },
    /// `hoploc <role> radio error <code> try <attempt>`: bring-up failed; the node blinks `code`
    /// and tries again.
    RadioError {
        /// The node's role.
        role: Role,
        /// `xbee_api::driver::Error::code` of the failure (1…255).
        code: u8,
        /// Which attempt failed, from 1 (saturates at 65535).
        attempt: u16,
    },
    /// `hoploc <role> provisioned`: a provisioning frame was stored (the ACK went first).
    Provisioned {
        /// The node's role.
        role: Role,
    },
    /// `hoploc <role> config eeprom|built-in id <id>`: the config the node runs with.
    Config {
        /// The node's role.
        role: Role,
        /// Where it came from.
        source: ConfigSource,
        /// Its node id.
        id: u8,
    },
    /// `hoploc <role> config error <code>`: the EEPROM holds a config the node must not run with
    /// (`loc_proto::Error::code`, or [`crate::config::WRONG_ROLE`]); the node blinks `code` and
    /// waits for a provisioning frame.
    ConfigError {
        /// The node's role.
        role: Role,
        /// Why (1…10).
        code: u8,
    },
}

/// Where the config a node runs with came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ConfigSource {
    /// Its EEPROM (provisioned, or written by ISP).
    Eeprom,
    /// The firmware's build-time config (the EEPROM is erased).
    BuiltIn,
}

/// Longest line [`BootLine::write`] produces, `\r\n` included
/// (`hoploc anchor radio error 255 try 65535\r\n`).
pub const MAX_BOOT_LINE: usize = 41;

/// Why [`BootLine::parse`] rejected a line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LineError {
    /// Not a hoploc boot line (another line, or noise): safe to skip.
    NotBootLine,
    /// It starts like one (`hoploc <role> boot|radio|provisioned|config`) but its fields are wrong or missing.
    Malformed,
}

impl fmt::Display for LineError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            LineError::NotBootLine => "not a hoploc boot line",
            LineError::Malformed => "malformed hoploc boot line",
        })
    }
}

impl core::error::Error for LineError {}

impl BootLine {
    /// The role of the node that wrote the line.
    pub const fn role(&self) -> Role {
        match *self {
            BootLine::Boot { role }
            | BootLine::RadioUp { role, .. }
            | BootLine::RadioError { role, .. }
            | BootLine::Provisioned { role }
            | BootLine::Config { role, .. }
            | BootLine::ConfigError { role, .. } => role,
        }
    }

    /// Writes the line, `\r\n` included (at most [`MAX_BOOT_LINE`] bytes): its [`uDisplay`],
    /// then `\r\n`. Always inlined, as the `uDisplay`: a firmware writes each line where it
    /// builds it, so only that kind's few calls remain (no line in memory).
    #[inline(always)]
    pub fn write<W: uWrite + ?Sized>(&self, out: &mut W) -> Result<(), W::Error> {
        write_line(out, false, self)
    }

    /// Reads a line (with or without its `\r\n`). Never panics; any other text is
    /// [`LineError::NotBootLine`].
    pub fn parse(line: &str) -> Result<BootLine, LineError> {
        let line = line.strip_suffix('\n').unwrap_or(line);
        let line = line.strip_suffix('\r').unwrap_or(line);
        let mut words = line.split(' ');
        let (Some("hoploc"), Some(role), Some(kind)) = (words.next(), words.next(), words.next())
        else {
            return Err(LineError::NotBootLine);
        };
        let role = Role::from_name(role).ok_or(LineError::NotBootLine)?;
        let rest: [Option<&str>; 5] = core::array::from_fn(|_| words.next());
        let parsed = match (kind, rest) {
            ("boot", [None, ..]) => BootLine::Boot { role },
            ("radio", [Some("ok"), Some("api"), None, ..]) => BootLine::RadioUp {
                role,
                found: RadioFound::Api,
            },
            ("radio", [Some("ok"), Some(baud), None, ..]) => BootLine::RadioUp {
                role,
                found: RadioFound::Configured {
                    baud: number(baud)?,
                },
            },
            ("radio", [Some("error"), Some(code), Some("try"), Some(attempt), None]) => {
                BootLine::RadioError {
                    role,
                    code: number(code)?,
                    attempt: number(attempt)?,
                }
            }
            ("provisioned", [None, ..]) => BootLine::Provisioned { role },
            (
                "config",
                [Some(source @ ("eeprom" | "built-in")), Some("id"), Some(id), None, ..],
            ) => BootLine::Config {
                role,
                source: if source == "eeprom" {
                    ConfigSource::Eeprom
                } else {
                    ConfigSource::BuiltIn
                },
                id: number(id)?,
            },
            ("config", [Some("error"), Some(code), None, ..]) => BootLine::ConfigError {
                role,
                code: number(code)?,
            },
            ("boot" | "radio" | "provisioned" | "config", _) => return Err(LineError::Malformed),
            _ => return Err(LineError::NotBootLine),
        };
        Ok(parsed)
    }
}

/// A decimal number as [`BootLine::write`] writes it: digits only, no sign, no leading zero.
fn number<T: TryFrom<u32>>(s: &str) -> Result<T, LineError> {
    let canonical =
        !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()) && (s == "0" || !s.starts_with('0'));
    if !canonical {
        return Err(LineError::Malformed);
    }
    let n: u32 = s.parse().map_err(|_| LineError::Malformed)?;
    T::try_from(n).map_err(|_| LineError::Malformed)
}

/// The line without its `\r\n`: the format of every boot line, word by word. Always inlined:
/// a firmware writes a line whose variant is known where it writes it, so only that variant's
/// writes remain.
impl uDisplay for BootLine {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
        // The kind word from the variant: a caller that writes one of two lines of a kind (the
        // radio's) gets one copy of the line's start.
        let kind = match *self {
            BootLine::Boot { .. } => Word::BOOT,
            BootLine::RadioUp { .. } | BootLine::RadioError { .. } => Word::RADIO,
            BootLine::Provisioned { .. } => Word::PROVISIONED,
            BootLine::Config { .. } | BootLine::ConfigError { .. } => Word::CONFIG,
        };
        Head(self.role(), kind).fmt(f)?;
        match *self {
            BootLine::Boot { .. } | BootLine::Provisioned { .. } => Ok(()),
            BootLine::RadioUp { found, .. } => uwrite!(f, " {} {}", Word::OK, found),
            BootLine::RadioError { code, attempt, .. } => uwrite!(
                f,
                " {} {} {} {}",
                Word::ERROR,
                Dec(code.into()),
                Word::TRY,
                Dec(attempt.into())
            ),
            BootLine::Config { source, id, .. } => {
                uwrite!(f, " {} {} {}", source, Word::ID, Dec(id.into()))
            }
            BootLine::ConfigError { code, .. } => {
                uwrite!(f, " {} {}", Word::ERROR, Dec(code.into()))
            }
        }
    }
}

/// `api`, or the baud rate in decimal.
impl uDisplay for RadioFound {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
        match *self {
            RadioFound::Api => Word::API.fmt(f),
            RadioFound::Configured { baud } => Dec(baud).fmt(f),
        }
    }
}

/// `eeprom` or `built-in`.
impl uDisplay for ConfigSource {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut Formatter<'_, W>) -> Result<(), W::Error> {
        // `built-in` follows `eeprom` in WORDS.
        Word(Word::EEPROM.0 + (*self == ConfigSource::BuiltIn) as u8).fmt(f)
    }
}

/// The line without its `\r\n`.
impl fmt::Display for BootLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        display(self, f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::{String, ToString};
    use std::vec::Vec;

    fn written(l: &BootLine) -> String {
        let mut s = String::new();
        let Ok(()) = l.write(&mut s);
        s
    }

    #[test]
    fn documented_examples() {
        let cases = [
            (
                BootLine::Boot { role: Role::Anchor },
                "hoploc anchor boot\r\n",
            ),
            (
                BootLine::RadioUp {
                    role: Role::Agent,
                    found: RadioFound::Api,
                },
                "hoploc agent radio ok api\r\n",
            ),
            (
                BootLine::RadioUp {
                    role: Role::Sink,
                    found: RadioFound::Configured { baud: 9600 },
                },
                "hoploc sink radio ok 9600\r\n",
            ),
            (
                BootLine::RadioError {
                    role: Role::Anchor,
                    code: 9,
                    attempt: 2,
                },
                "hoploc anchor radio error 9 try 2\r\n",
            ),
            (
                BootLine::Provisioned { role: Role::Agent },
                "hoploc agent provisioned\r\n",
            ),
            (
                BootLine::Config {
                    role: Role::Anchor,
                    source: ConfigSource::Eeprom,
                    id: 2,
                },
                "hoploc anchor config eeprom id 2\r\n",
            ),
            (
                BootLine::Config {
                    role: Role::Sink,
                    source: ConfigSource::BuiltIn,
                    id: 255,
                },
                "hoploc sink config built-in id 255\r\n",
            ),
            (
                BootLine::ConfigError {
                    role: Role::Anchor,
                    code: 10,
                },
                "hoploc anchor config error 10\r\n",
            ),
        ];
        for (line, text) in cases {
            assert_eq!(written(&line), text);
            assert_eq!(line.to_string(), text.trim_end());
            assert_eq!(BootLine::parse(text), Ok(line));
            assert_eq!(BootLine::parse(text.trim_end()), Ok(line));
        }
    }

    /// The lines' numbers ([`Dec`], [`SignedDec`]: ufmt's decimal) and hex bytes ([`Hex`]) are
    /// `core::fmt`'s, at every width's edges and for every byte.
    #[test]
    fn numbers_match_core_fmt() {
        fn text(n: impl uDisplay) -> String {
            let mut s = String::new();
            let Ok(()) = uwrite!(s, "{}", n);
            s
        }
        for n in [
            0,
            1,
            9,
            10,
            99,
            100,
            101,
            9600,
            57_600,
            115_200,
            999_999_999,
        ]
        .into_iter()
        .chain([1_000_000_000, 4_000_000_001, u32::MAX - 1, u32::MAX])
        {
            assert_eq!(text(Dec(n)), std::format!("{n}"));
            for n in [n as i16, (n as i16).wrapping_neg(), i16::MIN, i16::MAX, -1] {
                assert_eq!(text(SignedDec(n)), std::format!("{n}"));
            }
        }
        for b in 0..=u8::MAX {
            assert_eq!(text(Hex(b)), std::format!("{b:02X}"));
        }
    }

    #[test]
    fn every_word_reads_back_from_the_packed_table() {
        let words: Vec<&[u8]> = WORD_LIST.split(|&b| b == b' ').collect();
        assert_eq!(PACKED_LEN + words.len() - 1, WORD_LIST.len());
        for (k, w) in words.iter().enumerate() {
            let mut s = String::new();
            let Ok(()) = uwrite!(s, "{}", Word(k as u8));
            assert_eq!(s.as_bytes(), *w, "word {k}");
        }
        let index = |name: &[u8]| Word(words.iter().position(|w| *w == name).unwrap() as u8);
        for (word, name) in [
            (Word::HOPLOC, &b"hoploc"[..]),
            (Word::BOOT, b"boot"),
            (Word::RADIO, b"radio"),
            (Word::OK, b"ok"),
            (Word::API, b"api"),
            (Word::ERROR, b"error"),
            (Word::TRY, b"try"),
            (Word::CONFIG, b"config"),
            (Word::EEPROM, b"eeprom"),
            (Word::BUILT_IN, b"built-in"),
            (Word::ID, b"id"),
            (Word::PROVISIONED, b"provisioned"),
            (Word::FIX, b"fix"),
            (Word::NOFIX, b"nofix"),
            (Word::STATUS, b"status"),
            (Word::MLE, b"mle"),
            (Word::MMSE, b"mmse"),
            (Word::REPORT, b"report"),
        ] {
            assert_eq!(word, index(name), "{}", String::from_utf8_lossy(name));
        }
        for role in Role::ALL {
            assert_eq!(Word(1 + role as u8), index(role.name().as_bytes()));
        }
    }

    #[test]
    fn longest_line_fits() {
        let l = BootLine::RadioError {
            role: Role::Anchor,
            code: 255,
            attempt: u16::MAX,
        };
        assert_eq!(written(&l).len(), MAX_BOOT_LINE);
    }

    #[test]
    fn other_text_is_not_a_boot_line() {
        for text in [
            "",
            "hoploc",
            "hoploc anchor",
            "hello world",
            "hoploc robot boot",
            "hoploc sink estimate 1 2 3",
            "\u{7e}\u{0}",
        ] {
            assert_eq!(
                BootLine::parse(text),
                Err(LineError::NotBootLine),
                "{text:?}"
            );
        }
    }

    #[test]
    fn broken_fields_are_malformed() {
        for text in [
            "hoploc anchor boot now",
            "hoploc anchor radio",
            "hoploc anchor radio ok",
            "hoploc anchor radio ok 96OO",
            "hoploc anchor radio ok -1",
            "hoploc anchor radio ok 09600",
            "hoploc anchor radio ok 99999999999",
            "hoploc anchor radio error 256 try 1",
            "hoploc anchor radio error 9 try 65536",
            "hoploc anchor radio error 9 try",
            "hoploc anchor radio error 9 try 1 more",
            "hoploc anchor radio error 9 retry 1",
            "hoploc anchor radio ok api extra",
            "hoploc anchor provisioned now",
            "hoploc anchor config",
            "hoploc anchor config eeprom",
            "hoploc anchor config eeprom id",
            "hoploc anchor config eeprom id 256",
            "hoploc anchor config eeprom id 02",
            "hoploc anchor config eeprom id 2 more",
            "hoploc anchor config flash id 2",
            "hoploc anchor config builtin id 2",
            "hoploc anchor config eeprom 2",
            "hoploc anchor config error",
            "hoploc anchor config error x",
            "hoploc anchor config error 256",
            "hoploc anchor config error 7 more",
        ] {
            assert_eq!(BootLine::parse(text), Err(LineError::Malformed), "{text:?}");
        }
    }
}
