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
//! blinks it too. The firmware writes lines with
//! [`BootLine::write`] (no `core::fmt`, words read from flash); the host tools read them with
//! [`BootLine::parse`], which never panics and says what was wrong.

use core::fmt;

use crate::Role;

/// Every word of the boot lines and the sink's lines ([`crate::sink_line`]), space separated;
/// [`Word`] and `sink_line`'s word numbers index it. One table, one writer ([`Out`]) for every
/// line a node writes.
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
/// frame then stays out of [`Out::word`]'s loop.
#[inline(never)]
fn word_byte(i: u8) -> u8 {
    WORDS.load_at(i as usize)
}

/// Indices into [`WORDS`].
#[derive(Clone, Copy)]
#[repr(u8)]
enum Word {
    Hoploc = 0,
    // Roles: 1 + Role as u8.
    Boot = 4,
    Radio = 5,
    Ok = 6,
    Api = 7,
    Error = 8,
    Try = 9,
    Config = 10,
    Eeprom = 11,
    BuiltIn = 12,
    Id = 13,
    Provisioned = 14,
}

/// [`WORDS`] index of `sink` (1 + [`Role::Sink`]), the sink lines' second word.
pub(crate) const WORD_SINK: u8 = 1 + Role::Sink as u8;
/// [`WORDS`] index of `fix`, the first of the sink lines' own words (`fix nofix status mle mmse
/// report`, in that order).
pub(crate) const WORD_FIX: u8 = 15;

// `BootLine::write` takes `built-in` as the word after `eeprom`.
const _: () = assert!(Word::BuiltIn as u8 == Word::Eeprom as u8 + 1);
const _: () = assert!(Word::Provisioned as u8 + 1 == WORD_FIX);

/// A line on its way out: each byte goes to `out` and into the running CRC-8 that sink lines
/// end with ([`crate::sink_line::crc8`]). Every line a node writes, boot or sink, goes through
/// these few out-of-line methods: on AVR one copy of each per writer type (a firmware writes
/// every line with one, so one copy), called with a value or two. Generic, not `dyn`: the
/// writer's call folds in, and no vtable sits in SRAM.
pub(crate) struct Out<W> {
    out: W,
    crc: u8,
}

impl<W: FnMut(u8)> Out<W> {
    /// A line to `out`, nothing written yet.
    pub(crate) fn new(out: W) -> Out<W> {
        Out { out, crc: 0 }
    }

    /// Writes `b`. (crc8 from state `crc` over `b` is crc8 of `crc ^ b` from 0.) A `u8` bit
    /// count: an untyped `0..8` is an `i32` loop on AVR.
    #[inline(never)]
    pub(crate) fn byte(&mut self, b: u8) {
        let mut c = self.crc ^ b;
        for _ in 0..8u8 {
            c = (c << 1) ^ if c & 0x80 != 0 { 0x07 } else { 0 };
        }
        self.crc = c;
        (self.out)(b);
    }

    /// `hoploc`, word `second` (the role, or `sink`) and word `kind`: how every line starts.
    #[inline(never)]
    pub(crate) fn head(&mut self, second: u8, kind: u8) {
        self.word(Word::Hoploc as u8);
        self.word(second);
        self.word(kind);
    }

    /// A space (none before word 0, `hoploc`, which starts every line) and word `k` of
    /// [`WORDS`]. One `u8` position and one `u8` word count: few registers live across `byte`.
    #[inline(never)]
    pub(crate) fn word(&mut self, k: u8) {
        if k != 0 {
            self.byte(b' ');
        }
        // Skip k words, then write one (a k past the last word panics in word_byte's index
        // check: nothing past the table is read).
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
            self.byte(b & 0x7F);
            if b & 0x80 != 0 {
                return;
            }
        }
    }

    /// A space and `n` in decimal.
    #[inline(never)]
    pub(crate) fn num(&mut self, n: u32) {
        self.field(n, false);
    }

    /// A space and `n` in decimal: [`Out::num`] for the fields of 16 bits or fewer (most of
    /// them), whose callers then pass two bytes, not four.
    #[inline(never)]
    pub(crate) fn num16(&mut self, n: u16) {
        self.field(n.into(), false);
    }

    /// A space and `n` in decimal, `-` first if negative.
    #[inline(never)]
    pub(crate) fn signed(&mut self, n: i16) {
        self.field(n.unsigned_abs().into(), n < 0);
    }

    /// A space, `-` if `neg`, and `n` in decimal: every number field of every line. The digits
    /// before the last by recursion (at most ten levels deep), the deepest level writing the
    /// space and sign first, then the last (so nothing else is kept across the calls). One
    /// 32-bit division per digit: the remainder `n − 10·q` is below 10, so its low 8 bits (one
    /// hardware multiply on AVR) are all of it.
    #[inline(never)]
    fn field(&mut self, n: u32, neg: bool) {
        let q = n / 10;
        if q != 0 {
            self.field(q, neg);
        } else {
            self.byte(b' ');
            if neg {
                self.byte(b'-');
            }
        }
        self.byte(b'0' + (n as u8).wrapping_sub((q as u8).wrapping_mul(10)));
    }

    /// The 4-bit `n` as an upper-case hex digit. Out of line: four callers.
    #[inline(never)]
    fn hex_digit(&mut self, n: u8) {
        self.byte(if n < 10 { b'0' + n } else { b'A' + n - 10 });
    }

    /// A space and `bytes` as one word of upper-case hex digits.
    pub(crate) fn hex(&mut self, bytes: &[u8]) {
        self.byte(b' ');
        for &b in bytes {
            self.hex_digit(b >> 4);
            self.hex_digit(b & 15);
        }
    }

    /// The line's end: ` *XX` (the CRC-8 of every byte so far, in hex) if `checked`, then
    /// `\r\n`.
    #[inline(always)]
    pub(crate) fn end(&mut self, checked: bool) {
        if checked {
            self.end_checked();
        } else {
            self.end_plain();
        }
    }

    /// ` *XX` (the CRC-8 of every byte so far, in hex), then `\r\n`: the sink lines' end.
    #[inline(never)]
    fn end_checked(&mut self) {
        let c = self.crc;
        self.byte(b' ');
        self.byte(b'*');
        self.hex_digit(c >> 4);
        self.hex_digit(c & 15);
        self.end_plain();
    }

    /// `\r\n`: the boot lines' end.
    #[inline(never)]
    fn end_plain(&mut self) {
        self.byte(b'\r');
        self.byte(b'\n');
    }
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

    /// Writes the line, `\r\n` included, one byte at a time (at most [`MAX_BOOT_LINE`] bytes).
    ///
    /// Word by word through the one line writer (`Out`). Always inlined: a firmware writes
    /// each line where it builds it, so only that kind's few calls remain (no line in memory).
    #[inline(always)]
    pub fn write(&self, out: impl FnMut(u8)) {
        use Word::*;
        let mut o = Out::new(out);
        // The kind word first, from the variant: a caller that writes one of two lines of a kind
        // (the radio's) gets one copy of the line's start.
        let kind = match *self {
            BootLine::Boot { .. } => Boot,
            BootLine::RadioUp { .. } | BootLine::RadioError { .. } => Radio,
            BootLine::Provisioned { .. } => Provisioned,
            BootLine::Config { .. } | BootLine::ConfigError { .. } => Config,
        };
        o.head(1 + self.role() as u8, kind as u8);
        match *self {
            BootLine::Boot { .. } | BootLine::Provisioned { .. } => {}
            BootLine::RadioUp { found, .. } => {
                o.word(Ok as u8);
                match found {
                    RadioFound::Api => o.word(Api as u8),
                    RadioFound::Configured { baud } => o.num(baud),
                }
            }
            BootLine::RadioError { code, attempt, .. } => {
                o.word(Error as u8);
                o.num16(code.into());
                o.word(Try as u8);
                o.num16(attempt);
            }
            BootLine::Config { source, id, .. } => {
                // `built-in` follows `eeprom` in WORDS.
                o.word(Eeprom as u8 + (source == ConfigSource::BuiltIn) as u8);
                o.word(Id as u8);
                o.num16(id.into());
            }
            BootLine::ConfigError { code, .. } => {
                o.word(Error as u8);
                o.num16(code.into());
            }
        }
        o.end(false);
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

/// The line without its `\r\n`.
impl fmt::Display for BootLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut buf = [0u8; MAX_BOOT_LINE];
        let mut n = 0;
        self.write(|b| {
            if let Some(slot) = buf.get_mut(n) {
                *slot = b;
                n += 1;
            }
        });
        let text = buf.get(..n.saturating_sub(2)).unwrap_or(&[]);
        f.write_str(core::str::from_utf8(text).map_err(|_| fmt::Error)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::{String, ToString};
    use std::vec::Vec;

    fn written(l: &BootLine) -> String {
        let mut v = Vec::new();
        l.write(|b| v.push(b));
        String::from_utf8(v).unwrap()
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

    #[test]
    fn decimals_match_core_fmt() {
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
            let mut v = Vec::new();
            Out::new(|b| v.push(b)).num(n);
            assert_eq!(String::from_utf8(v).unwrap(), std::format!(" {n}"));
            for n in [n as u16, u16::MAX] {
                let mut v = Vec::new();
                Out::new(|b| v.push(b)).num16(n);
                assert_eq!(String::from_utf8(v).unwrap(), std::format!(" {n}"));
            }
            for n in [n as i16, (n as i16).wrapping_neg(), i16::MIN, i16::MAX, -1] {
                let mut v = Vec::new();
                Out::new(|b| v.push(b)).signed(n);
                assert_eq!(String::from_utf8(v).unwrap(), std::format!(" {n}"));
            }
        }
    }

    #[test]
    fn every_word_reads_back_from_the_packed_table() {
        let words: Vec<&[u8]> = WORD_LIST.split(|&b| b == b' ').collect();
        assert_eq!(PACKED_LEN + words.len() - 1, WORD_LIST.len());
        for (k, w) in words.iter().enumerate() {
            let mut v = Vec::new();
            Out::new(|b| v.push(b)).word(k as u8);
            let want = [if k == 0 { &b""[..] } else { b" " }, w].concat();
            assert_eq!(v, want, "word {k}");
        }
        assert_eq!(
            WORD_FIX as usize,
            words.iter().position(|w| w == b"fix").unwrap()
        );
        assert_eq!(
            WORD_SINK as usize,
            words.iter().position(|w| w == b"sink").unwrap()
        );
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
