//! The provisioning frame: how the host (`hoploc provision`) writes a node's [`Config`] over the
//! USB serial in the first seconds after reset, and the node's one-line binary answer.
//!
//! Frame, L + 7 bytes (27 for a two-channel config, 45 at most: four channels and a key):
//!
//! | byte | field |
//! |---|---|
//! | 0–2 | start delimiter `HLP` (0x48 0x4C 0x50): not 0x7E, so the radio ignores it, and upper case, which no hoploc text line starts with |
//! | 3 | frame version [`VERSION`] (1) |
//! | 4 | L, the length of the config block (19…38) |
//! | 5 … 4+L | the config exactly as stored in EEPROM ([`crate::config`], with its own magic, version, length and CRC) |
//! | 5+L, 6+L | CRC-16/CCITT-FALSE ([`crate::error::crc16`]) of bytes 3 … 4+L, big endian |
//!
//! The node answers every frame it recognised (delimiter, version and length) with 4 bytes:
//!
//! | reply | bytes | meaning |
//! |---|---|---|
//! | ACK | `HLA` 0x01 | the config was valid and has been stored; the 0x01 is [`VERSION`] |
//! | NAK | `HLN` *code* | rejected; *code* is [`Error::code`] (1…9: 3 bad version, 5 bad length, 6 bad field, 7 bad CRC …), 10 ([`WRONG_ROLE`]): a valid config for another role, or 11 ([`WRITE_FAILED`]): the EEPROM did not read back what was written |
//!
//! A node listens for frames during the first [`PROVISION_WINDOW_MS`] after reset (opening the
//! Uno's USB serial resets it), and for as long as its EEPROM holds a config it cannot run with.
//! It answers with [`answer`]: after an ACK it writes `hoploc <role> provisioned` and goes on
//! with the stored config.
//!
//! The node follows its reply with `\r\n`, so its text lines after it start on a line of their
//! own in a terminal; the host takes the 4 bytes. Neither reply contains 0x7E, so the radio, which shares the node's TX line, ignores them.
//! [`ProvisionParser`] finds frames in any byte stream: it skips garbage, and after a corrupt
//! frame rescans the bytes it had taken for that frame, so the next good frame is never lost.

pub use crate::config::WRONG_ROLE;
use crate::config::{read_into, Config, MAX_LEN, MIN_LEN};
use crate::error::{crc16, Error, Field};
use crate::Role;
use ufmt::uWrite;

/// The code of [`Error::BadValue`].
const BAD_VALUE: u8 = Error::BadValue { field: Field::Role }.code();

/// NAK code: the config was valid but reading the EEPROM back after writing it gave other bytes
/// (a worn-out or failing EEPROM).
pub const WRITE_FAILED: u8 = 11;

/// How long a node listens for a provisioning frame after reset, ms (it brings its radio up
/// after). The host sends its frame once it has read the node's `boot` line.
pub const PROVISION_WINDOW_MS: u16 = 2000;

/// The start delimiter of a provisioning frame.
pub const DELIMITER: [u8; 3] = *b"HLP";
/// The provisioning frame version.
pub const VERSION: u8 = 1;
/// The longest frame (a four-channel config).
pub const MAX_FRAME: usize = MAX_LEN + 7;
/// Bytes of a [`Reply`].
pub const REPLY_LEN: usize = 4;

/// Writes the provisioning frame of `config` into `buf`; returns the bytes written
/// (`config.size() + 7`).
pub fn encode(config: &Config, buf: &mut [u8]) -> Result<usize, Error> {
    let size = config.size() + 7;
    if buf.len() < size {
        return Err(Error::BufferTooSmall { need: size as u16 });
    }
    let l = config.to_bytes(&mut buf[5..])?;
    buf[..3].copy_from_slice(&DELIMITER);
    buf[3] = VERSION;
    buf[4] = l as u8;
    let crc = crc16(&buf[3..5 + l]);
    buf[5 + l..7 + l].copy_from_slice(&crc.to_be_bytes());
    Ok(size)
}

/// The node's answer to a provisioning frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Reply {
    /// Stored.
    Ack,
    /// Rejected, with [`Error::code`].
    Nak(u8),
}

impl Reply {
    /// The answer to a parser outcome.
    pub fn to(outcome: &Result<Config, Error>) -> Reply {
        match outcome {
            Ok(_) => Reply::Ack,
            Err(e) => Reply::Nak(e.code()),
        }
    }

    /// The reply of a node's code: 0 is [`Reply::Ack`], any other `Nak(code)`.
    pub const fn of_code(code: u8) -> Reply {
        match code {
            0 => Reply::Ack,
            code => Reply::Nak(code),
        }
    }

    /// The reply's 4 bytes.
    pub const fn bytes(self) -> [u8; REPLY_LEN] {
        match self {
            Reply::Ack => [b'H', b'L', b'A', VERSION],
            Reply::Nak(code) => [b'H', b'L', b'N', code],
        }
    }

    /// The reply in `b`, if it is one.
    pub fn parse(b: &[u8]) -> Option<Reply> {
        match *b {
            [b'H', b'L', b'A', VERSION] => Some(Reply::Ack),
            [b'H', b'L', b'N', code] => Some(Reply::Nak(code)),
            _ => None,
        }
    }
}

/// The node's answer on its UART: the 4 bytes of [`Reply::of_code`]`(code)` (`code` as
/// [`ProvisionParser::node_reply`] gives it, 0 for the ACK) and `\r\n` (its text lines after it then
/// start on a line of their own in a terminal), then after an ACK the line
/// `hoploc <role> provisioned` ([`BootLine::Provisioned`]), all through the writer of the
/// node's lines. The reply is ASCII (`HL`, `A` or `N`, and [`VERSION`] or a code of at most
/// [`WRITE_FAILED`], the codes `node_reply` gives), so each of its bytes is a one-byte `str`;
/// a code from 0x80 on, which no node sends, would lose its bit 7. Always inlined, as
/// [`BootLine::write`].
///
/// [`BootLine::Provisioned`]: crate::line::BootLine::Provisioned
/// [`BootLine::write`]: crate::line::BootLine::write
#[inline(always)]
pub fn write_answer<W: uWrite + ?Sized>(out: &mut W, code: u8, role: Role) -> Result<(), W::Error> {
    crate::line::write_line(out, false, &Reply::of_code(code))?;
    if code == 0 {
        crate::line::BootLine::Provisioned { role }.write(out)?;
    }
    Ok(())
}

/// The reply's 4 bytes, each as a one-byte `str` (see [`write_answer`]).
impl ufmt::uDisplay for Reply {
    #[inline(always)]
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut ufmt::Formatter<'_, W>) -> Result<(), W::Error> {
        for b in self.bytes() {
            crate::line::ascii(b & 0x7F, f)?;
        }
        Ok(())
    }
}

/// What a node of `role` answers to a [`ProvisionParser`] outcome, and the config to store
/// (only with [`Reply::Ack`]): a valid config of another role is `Nak(`[`WRONG_ROLE`]`)`.
pub fn answer(outcome: Result<Config, Error>, role: Role) -> (Reply, Option<Config>) {
    match outcome {
        Ok(c) if c.role == role => (Reply::Ack, Some(c)),
        Ok(_) => (Reply::Nak(WRONG_ROLE), None),
        Err(e) => (Reply::Nak(e.code()), None),
    }
}

/// The parser's buffer: a whole frame, rounded up to a power of two so that an index masked
/// with `BUF - 1` needs no bounds check (on AVR each is a compare and a branch to the panic path).
const BUF: usize = 64;
const _: () = assert!(MAX_FRAME <= BUF && 5 + MAX_LEN <= BUF && BUF.is_power_of_two());

/// The byte at `i` of `b` (masked into the buffer; callers stay below `MAX_FRAME`).
#[inline(always)]
fn at(b: &[u8; BUF], i: u8) -> u8 {
    b[i as usize & (BUF - 1)]
}

/// Finds provisioning frames in a byte stream, one byte at a time, in a buffer of one frame.
#[derive(Clone, Debug)]
#[repr(C)]
pub struct ProvisionParser {
    n: u8,
    errors: u16,
    buf: [u8; BUF],
}

impl Default for ProvisionParser {
    fn default() -> Self {
        Self::new()
    }
}

impl ProvisionParser {
    /// A parser that has seen nothing.
    pub const fn new() -> Self {
        ProvisionParser {
            buf: [0; BUF],
            n: 0,
            errors: 0,
        }
    }

    /// How many broken frames it has reported (saturating).
    pub const fn errors(&self) -> u16 {
        self.errors
    }

    /// The stored bytes of the config in the frame [`ProvisionParser::push`] has just returned
    /// `Some(Ok(_))` for (what to write to EEPROM, without encoding it again); meaningless after
    /// any other result or once the next byte is pushed.
    pub fn config_bytes(&self) -> &[u8] {
        // Clamped into the buffer (no panic path); a frame's L is at most MAX_LEN.
        let l = (self.buf[4] as usize).min(BUF - 5);
        &self.buf[5..5 + l]
    }

    /// The buffer's config area (where a frame's config sits, [`MAX_LEN`] bytes) for the node
    /// to read its EEPROM block into and decode with [`read_into`]: one buffer for both, not a
    /// second one on the stack. Forgets any frame begun (the next byte starts afresh).
    pub fn eeprom_block(&mut self) -> &mut [u8; MAX_LEN] {
        self.n = 0;
        let (_, area) = self.buf.split_at_mut(5);
        match area.first_chunk_mut::<MAX_LEN>() {
            Some(block) => block,
            // 5 + MAX_LEN ≤ BUF (checked below): never taken, and folded away.
            None => unreachable!(),
        }
    }

    /// Feeds one byte. Returns `Some(Ok(config))` at the end of a good frame, `Some(Err(_))` when a
    /// frame (delimiter seen) turns out broken or holds an invalid config, and `None` otherwise
    /// (garbage is skipped silently). Never panics.
    pub fn push(&mut self, byte: u8) -> Option<Result<Config, Error>> {
        let out = self
            .frame::<true>(byte)?
            .and_then(|()| Config::from_bytes(self.config_bytes()));
        Some(out.inspect_err(|e| self.count_invalid(e)))
    }

    /// [`ProvisionParser::push`] and [`answer`] in one: the reply a node of `role` owes at the
    /// end of a recognised frame (on [`Reply::Ack`] the config to store is
    /// [`ProvisionParser::config_bytes`]). The node's path: the frame's config is checked by
    /// [`read_into`] (the decoder the node reads its EEPROM with), and no [`Config`] is built.
    pub fn reply(&mut self, byte: u8, role: Role) -> Option<Reply> {
        self.reply_code::<true>(byte, role).map(Reply::of_code)
    }

    /// [`ProvisionParser::reply`] as the node takes it: the reply's code, 0 for [`Reply::Ack`]
    /// (one byte in a register, no [`Reply`] to build and match; [`write_answer`] writes it),
    /// and without the count of broken frames, which a node never reads (on AVR each count is
    /// a call).
    pub fn node_reply(&mut self, byte: u8, role: Role) -> Option<u8> {
        self.reply_code::<false>(byte, role)
    }

    /// The reply's code (0 for [`Reply::Ack`]), counting broken frames if `COUNT`.
    #[inline(always)]
    fn reply_code<const COUNT: bool>(&mut self, byte: u8, role: Role) -> Option<u8> {
        Some(match self.frame::<COUNT>(byte)? {
            Err(e) => e.code(),
            Ok(()) => {
                let code = read_into(self.config_bytes(), role, None);
                // Only a bad field gets here with the code of a bad value.
                if COUNT && code == BAD_VALUE {
                    self.count();
                }
                code
            }
        })
    }

    /// A whole frame with a good CRC counts as broken too when its config is invalid.
    fn count_invalid(&mut self, e: &Error) {
        if let Error::BadValue { .. } = e {
            self.count();
        }
    }

    /// One more broken frame (saturating). Never inlined: the node's parser counts in two places.
    #[inline(never)]
    fn count(&mut self) {
        // (Less AVR code than `saturating_add`.)
        #[allow(clippy::implicit_saturating_add)]
        if self.errors != u16::MAX {
            self.errors += 1;
        }
    }

    /// Feeds one byte: `Some(Ok(()))` at the end of a frame with a good CRC (its config, valid or
    /// not, is [`ProvisionParser::config_bytes`]), `Some(Err(_))` when a frame turns out broken,
    /// `None` otherwise. Broken frames are counted if `COUNT`.
    #[inline(always)]
    fn frame<const COUNT: bool>(&mut self, byte: u8) -> Option<Result<(), Error>> {
        // `n` < MAX_FRAME here (a frame is complete at MAX_FRAME bytes); the masked indices
        // would keep any other value in bounds too.
        let mut n = self.n;
        self.buf[n as usize & (BUF - 1)] = byte;
        n += 1;
        let mut failed = None;
        // What the first `n` bytes (`n` ≥ 1) are: a frame's beginning (return, more bytes
        // needed), a whole frame with a good CRC (return it), or not a frame: none at all
        // (skip silently) or a broken one (bad version, length or CRC). The delimiter, then
        // the version, one byte at a time as far as they have come. Written as one block of
        // early exits, not a step function returning a verdict to dispatch on: on AVR such a
        // verdict is materialised and then matched again.
        let out = 'scan: loop {
            let broken = 'check: {
                if at(&self.buf, 0) != DELIMITER[0] {
                    break 'check None;
                }
                if n < 2 {
                    break 'scan failed.map(Err);
                }
                if at(&self.buf, 1) != DELIMITER[1] {
                    break 'check None;
                }
                if n < 3 {
                    break 'scan failed.map(Err);
                }
                if at(&self.buf, 2) != DELIMITER[2] {
                    break 'check None;
                }
                if n < 4 {
                    break 'scan failed.map(Err);
                }
                let version = at(&self.buf, 3);
                if version != VERSION {
                    break 'check Some(Error::BadVersion { found: version });
                }
                if n < 5 {
                    break 'scan failed.map(Err);
                }
                let l = at(&self.buf, 4);
                if !(MIN_LEN as u8..=MAX_LEN as u8).contains(&l) {
                    break 'check Some(Error::BadLength);
                }
                if n < l + 7 {
                    break 'scan failed.map(Err);
                }
                // The CRC follows its bytes big endian: the CRC over both is 0 exactly when it
                // matches.
                if crc16(&self.buf[3..l as usize + 7]) != 0 {
                    break 'check Some(Error::BadCrc);
                }
                n = 0;
                break 'scan Some(Ok(()));
            };
            if let Some(e) = broken {
                failed = Some(e);
                if COUNT {
                    self.count();
                }
            }
            // Resynchronise: drop the first byte and look again, so the next frame may start
            // inside what was buffered (bytes up to the next delimiter byte are skipped one at
            // a time, silently).
            n -= 1;
            let mut i = 0;
            while i < n {
                self.buf[i as usize & (BUF - 1)] = at(&self.buf, i + 1);
                i += 1;
            }
            if n == 0 {
                break failed.map(Err);
            }
        };
        self.n = n;
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    #[rustfmt::skip]
    const DEFAULT_FRAME: [u8; 27] = [
        b'H', b'L', b'P', 1, 20,
        0xC5, 1, 20, 0, 1, 4, 0, 0, 0, 0, 62, 0, 3, 0x32, 0x33, 2, 1, 12, 0xE1, 0xE3,
        0xED, 0xA2,
    ];

    fn feed(p: &mut ProvisionParser, bytes: &[u8]) -> Vec<Result<Config, Error>> {
        bytes.iter().filter_map(|&b| p.push(b)).collect()
    }

    #[test]
    fn golden_frame() {
        let mut buf = [0; MAX_FRAME];
        assert_eq!(encode(&Config::DEFAULT, &mut buf), Ok(27));
        assert_eq!(buf[..27], DEFAULT_FRAME);
        let mut p = ProvisionParser::new();
        assert_eq!(feed(&mut p, &DEFAULT_FRAME), [Ok(Config::DEFAULT)]);
        assert_eq!(p.config_bytes(), &DEFAULT_FRAME[5..25]);
        assert_eq!(
            encode(&Config::DEFAULT, &mut buf[..26]),
            Err(Error::BufferTooSmall { need: 27 })
        );
    }

    #[test]
    fn replies() {
        assert_eq!(Reply::Ack.bytes(), *b"HLA\x01");
        assert_eq!(Reply::Nak(7).bytes(), *b"HLN\x07");
        assert_eq!(Reply::to(&Err(Error::BadCrc)), Reply::Nak(7));
        assert_eq!(Reply::to(&Ok(Config::DEFAULT)), Reply::Ack);
        for r in [Reply::Ack, Reply::Nak(1), Reply::Nak(9)] {
            assert_eq!(Reply::parse(&r.bytes()), Some(r));
            assert!(!r.bytes().contains(&0x7E));
        }
        assert_eq!(Reply::parse(b"HLP\x01"), None);
        assert_eq!(Reply::parse(b"HLA"), None);
    }

    #[test]
    fn the_answer_is_the_reply_then_the_boot_line() {
        use crate::line::BootLine;
        // Every code a node answers with: 0 (ACK), `Error::code`'s 1…9, WRONG_ROLE,
        // WRITE_FAILED; and every other ASCII one.
        for role in Role::ALL {
            for code in 0..0x80 {
                let reply = Reply::of_code(code);
                let mut got = std::string::String::new();
                let Ok(()) = write_answer(&mut got, code, role);
                let mut want = reply.bytes().to_vec();
                want.extend_from_slice(b"\r\n");
                if reply == Reply::Ack {
                    let mut line = std::string::String::new();
                    let Ok(()) = BootLine::Provisioned { role }.write(&mut line);
                    want.extend_from_slice(line.as_bytes());
                }
                assert_eq!(got.as_bytes(), want, "{reply:?} {role:?}");
            }
        }
    }

    #[test]
    fn answers_by_role() {
        let anchor = Config::DEFAULT;
        assert_eq!(answer(Ok(anchor), Role::Anchor), (Reply::Ack, Some(anchor)));
        assert_eq!(answer(Ok(anchor), Role::Sink), (Reply::Nak(10), None));
        assert_eq!(
            answer(Err(Error::BadCrc), Role::Anchor),
            (Reply::Nak(7), None)
        );
        assert_eq!(Reply::Nak(WRONG_ROLE).bytes(), *b"HLN\x0A");
    }

    /// `reply` is `push` then `answer`, byte for byte, errors counted alike: on the golden
    /// frame, every one-byte corruption of it, an invalid config with a good CRC, and for each
    /// role (the golden frame's config is an anchor's).
    #[test]
    fn reply_is_push_then_answer() {
        let mut invalid = DEFAULT_FRAME;
        invalid[15] = 0;
        let inner = crc16(&invalid[5..23]);
        invalid[23..25].copy_from_slice(&inner.to_be_bytes());
        let outer = crc16(&invalid[3..25]);
        invalid[25..27].copy_from_slice(&outer.to_be_bytes());
        let mut streams: Vec<Vec<u8>> = [DEFAULT_FRAME, invalid].map(|f| f.to_vec()).into();
        for i in 0..DEFAULT_FRAME.len() {
            let mut bad = DEFAULT_FRAME;
            bad[i] ^= 0x01;
            streams.push([&bad[..], &DEFAULT_FRAME[..]].concat());
        }
        let mut acks = 0;
        for role in [Role::Anchor, Role::Agent, Role::Sink] {
            for s in &streams {
                let (mut a, mut b, mut c) = (
                    ProvisionParser::new(),
                    ProvisionParser::new(),
                    ProvisionParser::new(),
                );
                for &byte in s {
                    let want = a.push(byte).map(|o| answer(o, role).0);
                    // The node's path answers alike (it only does not count).
                    assert_eq!(c.node_reply(byte, role).map(Reply::of_code), want);
                    let got = b.reply(byte, role);
                    assert_eq!(got, want, "{role:?} {s:?}");
                    acks += usize::from(got == Some(Reply::Ack));
                    if got == Some(Reply::Ack) {
                        assert_eq!(b.config_bytes(), &DEFAULT_FRAME[5..25]);
                    }
                }
                assert_eq!(a.errors(), b.errors());
            }
        }
        // The anchor acknowledges the golden frame alone and after each corruption.
        assert_eq!(acks, 1 + DEFAULT_FRAME.len());
    }

    #[test]
    fn garbage_before_and_between() {
        let mut s = Vec::new();
        s.extend_from_slice(b"hoploc anchor boot\r\n\x7E\x00\x05HHLHL");
        s.extend_from_slice(&DEFAULT_FRAME);
        s.extend_from_slice(b"\xFFHL\x00H");
        s.extend_from_slice(&DEFAULT_FRAME);
        let mut p = ProvisionParser::new();
        assert_eq!(feed(&mut p, &s), [Ok(Config::DEFAULT), Ok(Config::DEFAULT)]);
        assert_eq!(p.errors(), 0);
    }

    #[test]
    fn every_corrupt_frame_is_reported_and_the_next_good_one_kept() {
        for i in 0..DEFAULT_FRAME.len() {
            for v in [
                0x00,
                0x48,
                0xFF,
                DEFAULT_FRAME[i] ^ 0x01,
                DEFAULT_FRAME[i] ^ 0x80,
            ] {
                let mut bad = DEFAULT_FRAME;
                bad[i] = v;
                if bad == DEFAULT_FRAME {
                    continue;
                }
                let mut p = ProvisionParser::new();
                let mut got = feed(&mut p, &bad);
                got.extend(feed(&mut p, &DEFAULT_FRAME));
                assert_eq!(got.last(), Some(&Ok(Config::DEFAULT)), "byte {i} = {v:#x}");
                assert!(
                    got[..got.len() - 1].iter().all(|r| r.is_err()),
                    "byte {i} = {v:#x}: {got:?}"
                );
                // Only a broken delimiter makes a frame pass unnoticed as garbage.
                if i >= 3 {
                    assert!(got.len() >= 2, "byte {i} = {v:#x}: {got:?}");
                }
            }
        }
    }

    /// Every length byte: outside 19…22 the frame is broken at once (a NAK 5 for the node),
    /// inside it the parser waits for the rest. And every version byte but 1 is a NAK 3.
    #[test]
    fn every_length_and_version_byte() {
        for v in 0..=255u8 {
            let mut p = ProvisionParser::new();
            let mut q = ProvisionParser::new();
            let header = [b'H', b'L', b'P', 1, v];
            let got: Vec<_> = header.iter().filter_map(|&b| p.push(b)).collect();
            let node: Vec<_> = header
                .iter()
                .filter_map(|&b| q.node_reply(b, Role::Anchor))
                .collect();
            if (MIN_LEN as u8..=MAX_LEN as u8).contains(&v) {
                assert!(got.is_empty() && node.is_empty(), "L = {v}");
            } else {
                assert_eq!(got, [Err(Error::BadLength)], "L = {v}");
                assert_eq!(node, [5], "L = {v}");
            }
            let mut p = ProvisionParser::new();
            let got: Vec<_> = [b'H', b'L', b'P', v]
                .iter()
                .filter_map(|&b| p.push(b))
                .collect();
            if v == VERSION {
                assert!(got.is_empty());
            } else {
                assert_eq!(got, [Err(Error::BadVersion { found: v })]);
            }
        }
    }

    #[test]
    fn truncated_frame_then_good_one() {
        for cut in 1..DEFAULT_FRAME.len() {
            let mut p = ProvisionParser::new();
            let mut got = feed(&mut p, &DEFAULT_FRAME[..cut]);
            got.extend(feed(&mut p, &DEFAULT_FRAME));
            assert_eq!(got.last(), Some(&Ok(Config::DEFAULT)), "cut at {cut}");
        }
    }

    #[test]
    fn good_crc_invalid_config_is_a_typed_error() {
        let mut c = Config::DEFAULT;
        c.slot_ms = 0;
        let mut buf = [0; MAX_FRAME];
        assert!(encode(&c, &mut buf).is_err());
        // Build one by hand: patch the slot and both CRCs.
        let mut f = DEFAULT_FRAME;
        f[15] = 0;
        let inner = crc16(&f[5..23]);
        f[23..25].copy_from_slice(&inner.to_be_bytes());
        let outer = crc16(&f[3..25]);
        f[25..27].copy_from_slice(&outer.to_be_bytes());
        let mut p = ProvisionParser::new();
        assert_eq!(
            feed(&mut p, &f),
            [Err(Error::BadValue {
                field: crate::error::Field::SlotLength
            })]
        );
        assert_eq!(feed(&mut p, &DEFAULT_FRAME), [Ok(Config::DEFAULT)]);
    }
}
