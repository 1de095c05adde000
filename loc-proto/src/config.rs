//! The node config, as stored in EEPROM (from address 0) and carried by a provisioning frame
//! ([`crate::provision`]).
//!
//! 18 + C bytes (C = 1…4 channels; 20 with the default two channels, 22 at most), 16 more with a
//! network key (38 at most). Multi-byte fields are little endian except the CRC, which is big
//! endian so that the CRC over the whole block is 0:
//!
//! | byte | field |
//! |---|---|
//! | 0 | magic [`MAGIC`] (0xC5; an erased EEPROM reads 0xFF) |
//! | 1 | version [`VERSION`] (1) |
//! | 2 | length of the whole block in bytes, CRC included (18 + C, or 34 + C with a key) |
//! | 3 | role: 0 anchor, 1 agent, 2 sink |
//! | 4 | node id (1…255; an anchor's 1…N) |
//! | 5 | N, the number of anchors (3…8) |
//! | 6–7, 8–9 | the anchor's position x, y (i16, cm; 0 for other roles by convention) |
//! | 10–11 | slot length (u16, ms, up to 10000 and at least [`schedule::min_slot_ms`] of N: 17 with 3 or 4 anchors, 18 with 5…7, 19 with 8) |
//! | 12 | sink channel (testbed channel 1…16) |
//! | 13–14 | PAN id (u16, not 0xFFFF) |
//! | 15 | C, the number of channels (1…4), in bits 0–6; bit 7 ([`KEY_FLAG`]) set: a network key follows the channels |
//! | 16 … 15+C | the channels (testbed channels 1…16, distinct, in hop order) |
//! | 16+C … 31+C | with bit 7 of byte 15: the network key ([`NetworkKey`], 16 bytes) |
//! | last 2 | CRC-16/CCITT-FALSE ([`crate::error::crc16`]) of every byte before it, big endian |
//!
//! A config without a key is the same bytes as before keys existed, so EEPROMs written then stay
//! valid.
//!
//! ## The network key
//!
//! With a key, the node turns its radio's AES-128 encryption on (XBee `EE` = 1, `KY` = the key)
//! at every boot; without one it turns it off. Every node of a network must have the same key,
//! or none: a radio with encryption on hears nothing from one with it off (and the other way
//! round), and a radio with another key passes on garbled payloads, which every message's CRC
//! rejects ([`crate::msg`]). What it protects: the content of the packets from anyone without
//! the key, and the sink from reports of a device without the key. What it does not: the XBee
//! 802.15.4 radios encrypt without an integrity check or replay protection, so a device without
//! the key can still replay packets it recorded, or flip bits in them (the CRC catches a
//! random change, not a deliberate one fixed up by someone who knows the plaintext layout), and
//! it can jam the channel. The key is stored in the node's EEPROM in the clear: anyone with the
//! board can read it.
//!
//! Testbed channel *n* is XBee `CH` = 0x0A + *n* ([`crate::xbee_channel`]). Channel 1 (`CH`
//! 0x0B) exists on the XBee S1 but not on the S1 Pro, which only has channels 2…13: a network
//! with an S1 Pro must not list channel 1 (nor 14…16).
//!
//! For a **sink**, `position` is the room size instead: width (x) and height (y) in cm of the
//! area the estimator searches, from (0, 0); (0, 0) means the anchors' bounding box.
//!
//! ## Where a node's config comes from
//!
//! * **Built in**: each firmware is built with a config from the environment of `cargo build` /
//!   `cargo run` ([`from_env`]: `HOPLOC_ID`, `HOPLOC_X`, … listed in [`ENV_VARS`]; unset means
//!   [`Config::default_for`] the role). The firmware also puts its bytes in the ELF's `.eeprom`
//!   section, so an ISP programmer can write them (`avrdude -U eeprom:w:anchor-fw.elf:e`; the
//!   stock bootloader cannot write EEPROM).
//! * **EEPROM** (from address 0): written by a provisioning frame ([`crate::provision`],
//!   `hoploc provision`) or by ISP. At boot [`stored`] decides: a valid config of the node's role
//!   is used; an erased EEPROM (first byte 0xFF) means the built-in config; anything else
//!   (corrupt, another role, another version) is an error the node reports and does not run with.

use core::fmt;
use xbee_api::driver::{BringUpConfig, Encryption, FACTORY_CCA_THRESHOLD};

use crate::error::{crc16, Error, Field};
use crate::msg::{bad, ChannelList, Position, Writer, MAX_ANCHORS, MAX_CHANNEL};
use crate::schedule;
use crate::{Role, DEFAULT_CHANNELS, DEFAULT_PAN_ID, DEFAULT_SINK_CHANNEL};
use ufmt::uWrite;

/// The first byte of a stored config.
pub const MAGIC: u8 = 0xC5;
/// The config layout version this build writes and reads.
pub const VERSION: u8 = 1;
/// The shortest config (one channel).
pub const MIN_LEN: usize = 19;
/// The longest config (four channels and a key).
pub const MAX_LEN: usize = 22 + KEY_LEN;
/// Bytes of a network key.
pub const KEY_LEN: usize = 16;
/// The bit of the channel-count byte that says a network key follows the channels.
pub const KEY_FLAG: u8 = 0x80;

/// A network key: the AES-128 key of the radios' encryption (XBee `KY`; see the
/// [module docs](self)). Its `Debug` does not show the key.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct NetworkKey(pub [u8; KEY_LEN]);

impl fmt::Debug for NetworkKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("NetworkKey(..)")
    }
}

impl NetworkKey {
    /// A key as the tools take it: 32 hex digits (`HOPLOC_KEY`, `hoploc provision --key`).
    pub fn parse(s: &str) -> Option<NetworkKey> {
        let s = s.trim().as_bytes();
        if s.len() != 2 * KEY_LEN || !s.iter().all(u8::is_ascii_hexdigit) {
            return None;
        }
        let mut key = [0; KEY_LEN];
        for (k, pair) in key.iter_mut().zip(s.chunks_exact(2)) {
            let hex = core::str::from_utf8(pair).ok()?;
            *k = u8::from_str_radix(hex, 16).ok()?;
        }
        Some(NetworkKey(key))
    }
}
/// The shortest slot accepted (ms), that of the smallest network: a slot must hold its guard
/// and a beacon's way from the sender's MCU into the receivers' ([`schedule::min_slot_ms`]; with
/// more anchors a beacon is longer, and a config's slot must fit its own).
pub const MIN_SLOT_MS: u16 = schedule::min_slot_ms(3);
/// The longest slot accepted (ms).
pub const MAX_SLOT_MS: u16 = 10_000;
/// The default slot length (ms): 4 anchors × 62 ms ≈ the thesis's 250 ms per channel phase.
pub const DEFAULT_SLOT_MS: u16 = 62;

/// A node's configuration. See the [module docs](self) for the stored layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Config {
    /// Which firmware role the node plays.
    pub role: Role,
    /// The node id (1…255; an anchor's 1…`anchors`). The radio address is
    /// [`Role::address`] of it.
    pub id: u8,
    /// The number of anchors N in the network (3…8).
    pub anchors: u8,
    /// The anchor's position (cm).
    pub position: Position,
    /// The length of one TDMA slot (ms); a channel phase is `anchors` slots.
    pub slot_ms: u16,
    /// The anchor channels, in hop order.
    pub channels: ChannelList,
    /// The channel agents report to the sink on.
    pub sink_channel: u8,
    /// The 802.15.4 PAN id (XBee `ID`).
    pub pan_id: u16,
    /// The network key, if the network encrypts (see the [module docs](self)).
    pub key: Option<NetworkKey>,
}

const fn default_channels() -> ChannelList {
    match ChannelList::new(&DEFAULT_CHANNELS) {
        Ok(c) => c,
        Err(_) => panic!("the default channel list is valid"),
    }
}

impl Config {
    /// The default: anchor 1 of 4 at (0, 0), 62 ms slots, channels [1, 12], sink channel 3,
    /// PAN [`DEFAULT_PAN_ID`].
    pub const DEFAULT: Config = Config {
        role: Role::Anchor,
        id: 1,
        anchors: 4,
        position: Position { x: 0, y: 0 },
        slot_ms: DEFAULT_SLOT_MS,
        channels: default_channels(),
        sink_channel: DEFAULT_SINK_CHANNEL,
        pan_id: DEFAULT_PAN_ID,
        key: None,
    };

    /// The stored size of this config (18 + C, 16 more with a key).
    pub const fn size(&self) -> usize {
        18 + self.channels.len() + if self.key.is_some() { KEY_LEN } else { 0 }
    }

    /// Checks every field (the channel list is valid by construction).
    pub fn validate(&self) -> Result<(), Error> {
        check_fields(
            self.role,
            self.id,
            self.anchors,
            self.slot_ms,
            self.sink_channel,
            self.pan_id,
        )
    }

    /// Writes the config (with its CRC) into `buf`; returns the bytes written ([`Config::size`]).
    pub fn to_bytes(&self, buf: &mut [u8]) -> Result<usize, Error> {
        self.validate()?;
        let size = self.size();
        if buf.len() < size {
            return Err(Error::BufferTooSmall { need: size as u16 });
        }
        let mut w = Writer::new(buf);
        w.u8(MAGIC);
        w.u8(VERSION);
        w.u8(size as u8);
        w.u8(role_code(self.role));
        w.u8(self.id);
        w.u8(self.anchors);
        w.position(self.position);
        w.u16(self.slot_ms);
        w.u8(self.sink_channel);
        w.u16(self.pan_id);
        w.u8(self.channels.len() as u8 | if self.key.is_some() { KEY_FLAG } else { 0 });
        for &c in self.channels.as_slice() {
            w.u8(c);
        }
        if let Some(NetworkKey(key)) = self.key {
            for b in key {
                w.u8(b);
            }
        }
        let crc = crc16(&buf[..size - 2]);
        buf[size - 2..size].copy_from_slice(&crc.to_be_bytes());
        Ok(size)
    }

    /// Reads and validates a config from the start of `buf`; bytes after its length are
    /// ignored (so a whole [`MAX_LEN`]-byte EEPROM block can be passed).
    pub fn from_bytes(buf: &[u8]) -> Result<Config, Error> {
        decode(buf)
    }
}

/// [`Config::from_bytes`] as a node of `role` needs it: `0` for a valid config of `role`, and
/// the config in `out` (`None`: only checked); otherwise the code ([`Error::code`], or
/// [`WRONG_ROLE`] for a valid config of another role) with `out` untouched. The firmware's one
/// config decoder (the EEPROM at boot and every provisioning frame): the answer is one byte in a
/// register and every error return a constant, where a `Result<Config, Error>` comes back
/// through memory on AVR.
pub fn read_into(buf: &[u8], role: Role, out: Option<&mut Config>) -> u8 {
    // The checks of `decode`, in its order as far as the codes differ (every bad field is
    // BadValue, so the field checks go in any order), on the bytes in place: one `u8`
    // range test per field, and the config built only when it is run with.
    let [magic, version, len, ..] = *buf else {
        return Error::TooShort.code();
    };
    if magic != MAGIC {
        return Error::BadMagic.code();
    }
    if version != VERSION {
        return Error::BadVersion { found: 0 }.code();
    }
    if len.wrapping_sub(MIN_LEN as u8) > (MAX_LEN - MIN_LEN) as u8 {
        return Error::BadLength.code();
    }
    let Some(block) = buf.get(..len as usize) else {
        return Error::TooShort.code();
    };
    if crc16(block) != 0 {
        return Error::BadCrc.code();
    }
    let Some(b) = block.first_chunk::<16>() else {
        return Error::TooShort.code();
    };
    let (c, key_len) = channel_count(b[15]);
    if c.wrapping_add(18 + key_len) != len {
        return Error::BadLength.code();
    }
    let Ok(channels) = ChannelList::new(&block[16..16 + c as usize]) else {
        return BAD_VALUE;
    };
    let slot_ms = u16::from_le_bytes([b[10], b[11]]);
    let pan_id = u16::from_le_bytes([b[13], b[14]]);
    let (id, anchors) = (b[4], b[5]);
    if b[3] > 2 {
        return BAD_VALUE;
    }
    if anchors.wrapping_sub(3) > MAX_ANCHORS as u8 - 3 {
        return BAD_VALUE;
    }
    if id == 0 {
        return BAD_VALUE;
    }
    if slot_ms > MAX_SLOT_MS || !schedule::slot_fits_beacon(anchors, slot_ms) {
        return BAD_VALUE;
    }
    if b[12].wrapping_sub(1) > MAX_CHANNEL - 1 {
        return BAD_VALUE;
    }
    if pan_id == 0xFFFF {
        return BAD_VALUE;
    }
    // An anchor's id is at most N: checked on the stored role where it is another (to tell
    // a bad field from a wrong role), on `role` where it is the node's (with the one call of a
    // firmware, a constant: only the anchor checks).
    if b[3] != role_code(role) {
        return if b[3] == 0 && id > anchors {
            BAD_VALUE
        } else {
            WRONG_ROLE
        };
    }
    if role == Role::Anchor && id > anchors {
        return BAD_VALUE;
    }
    if let Some(out) = out {
        *out = Config {
            role,
            id,
            anchors,
            position: Position {
                x: i16::from_le_bytes([b[6], b[7]]),
                y: i16::from_le_bytes([b[8], b[9]]),
            },
            slot_ms,
            channels,
            sink_channel: b[12],
            pan_id,
            key: stored_key(block, c, key_len),
        };
    }
    0
}

/// The channel count C of the channel-count byte `b`, and the bytes of key after the channels.
#[inline(always)]
fn channel_count(b: u8) -> (u8, u8) {
    (
        b & !KEY_FLAG,
        if b & KEY_FLAG != 0 { KEY_LEN as u8 } else { 0 },
    )
}

/// The key of a checked config `block` of `c` channels and `key_len` bytes of key.
fn stored_key(block: &[u8], c: u8, key_len: u8) -> Option<NetworkKey> {
    if key_len == 0 {
        return None;
    }
    block
        .get(16 + c as usize..)
        .and_then(<[u8]>::first_chunk)
        .copied()
        .map(NetworkKey)
}

/// The node's config line: [`BootLine::Config`] (`code` 0: `hoploc <role> config
/// eeprom|built-in id <id>`) or [`BootLine::ConfigError`] (`hoploc <role> config error
/// <code>`), written with [`BootLine::write`] (whose line start and end are shared by the two).
/// Always inlined, as [`BootLine::write`].
///
/// [`BootLine::Config`]: crate::line::BootLine::Config
/// [`BootLine::ConfigError`]: crate::line::BootLine::ConfigError
/// [`BootLine::write`]: crate::line::BootLine::write
#[inline(always)]
pub fn write_config_line<W: uWrite + ?Sized>(
    out: &mut W,
    role: Role,
    code: u8,
    source: crate::line::ConfigSource,
    id: u8,
) -> Result<(), W::Error> {
    use crate::line::BootLine;
    let line = if code == 0 {
        BootLine::Config { role, source, id }
    } else {
        BootLine::ConfigError { role, code }
    };
    line.write(out)
}

/// The code of every bad field ([`Error::BadValue`]).
const BAD_VALUE: u8 = Error::BadValue { field: Field::Role }.code();

/// The decoder behind [`Config::from_bytes`] (typed errors; [`read_into`] is the node's
/// twin that answers with their codes, tested equal on every single-byte change and on fuzz).
fn decode(buf: &[u8]) -> Result<Config, Error> {
    let [magic, version, len, ..] = *buf else {
        return Err(Error::TooShort);
    };
    if magic != MAGIC {
        return Err(Error::BadMagic);
    }
    if version != VERSION {
        return Err(Error::BadVersion { found: version });
    }
    // u8 lengths and offsets: half the code of usize ones on AVR.
    if !(MIN_LEN as u8..=MAX_LEN as u8).contains(&len) {
        return Err(Error::BadLength);
    }
    let Some(block) = buf.get(..len as usize) else {
        return Err(Error::TooShort);
    };
    // The CRC follows the body big endian, so the CRC over the whole block is 0 exactly
    // when it matches (one call, no comparison of the stored bytes).
    if crc16(block) != 0 {
        return Err(Error::BadCrc);
    }
    // Fixed offsets (the length is checked): no reader, and every check reads the block in
    // place before the config is built from it.
    let Some(b) = block.first_chunk::<16>() else {
        return Err(Error::TooShort);
    };
    // C + 18 (+ the key) = len (a C that would wrap around is ≥ 222, never a length's).
    let (c, key_len) = channel_count(b[15]);
    if c.wrapping_add(18 + key_len) != len {
        return Err(Error::BadLength);
    }
    let role = role_of(b[3])?;
    let channels = ChannelList::new(&block[16..16 + c as usize])?;
    let slot_ms = u16::from_le_bytes([b[10], b[11]]);
    let pan_id = u16::from_le_bytes([b[13], b[14]]);
    check_fields(role, b[4], b[5], slot_ms, b[12], pan_id)?;
    Ok(Config {
        role,
        id: b[4],
        anchors: b[5],
        position: Position {
            x: i16::from_le_bytes([b[6], b[7]]),
            y: i16::from_le_bytes([b[8], b[9]]),
        },
        slot_ms,
        channels,
        sink_channel: b[12],
        pan_id,
        key: stored_key(block, c, key_len),
    })
}

/// The checks of [`Config::validate`] on the field values (the channel list is checked by
/// [`ChannelList::new`]). Always inlined: in the decoder they read the stored bytes in place.
#[inline(always)]
fn check_fields(
    role: Role,
    id: u8,
    anchors: u8,
    slot_ms: u16,
    sink_channel: u8,
    pan_id: u16,
) -> Result<(), Error> {
    if !(3..=MAX_ANCHORS as u8).contains(&anchors) {
        return Err(bad(Field::Anchors));
    }
    if id == 0 || (role == Role::Anchor && id > anchors) {
        return Err(bad(Field::NodeId));
    }
    if slot_ms > MAX_SLOT_MS || !schedule::slot_fits_beacon(anchors, slot_ms) {
        return Err(bad(Field::SlotLength));
    }
    if !(1..=MAX_CHANNEL).contains(&sink_channel) {
        return Err(bad(Field::SinkChannel));
    }
    if pan_id == 0xFFFF {
        return Err(bad(Field::PanId));
    }
    Ok(())
}

impl Config {
    /// The default config of `role`: [`Config::DEFAULT`] with that role (node 1).
    pub const fn default_for(role: Role) -> Config {
        Config {
            role,
            ..Config::DEFAULT
        }
    }
}

/// The code of a config that is valid but belongs to another role: a provisioning NAK
/// (`HLN` 10) and a `config error 10` line. The [`Error::code`]s are 1…9.
pub const WRONG_ROLE: u8 = 10;

/// What a node of some role finds in its EEPROM ([`stored`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Stored {
    /// A valid config of this role: run with it.
    Valid(Config),
    /// Erased (the first byte is 0xFF): run with the built-in config.
    Erased,
    /// Anything else: do not run; the code is [`Error::code`] (1…9) or [`WRONG_ROLE`].
    Invalid(u8),
}

/// Decides what the EEPROM block `bytes` (from address 0, at least [`MAX_LEN`] bytes for a
/// four-channel config) means for a node of `role`.
pub fn stored(bytes: &[u8], role: Role) -> Stored {
    if bytes.first() == Some(&0xFF) {
        return Stored::Erased;
    }
    let mut c = Config::DEFAULT;
    match read_into(bytes, role, Some(&mut c)) {
        0 => Stored::Valid(c),
        code => Stored::Invalid(code),
    }
}

/// The environment variables [`from_env`] reads, for `cargo:rerun-if-env-changed`.
pub const ENV_VARS: [&str; 9] = [
    "HOPLOC_ID",
    "HOPLOC_X",
    "HOPLOC_Y",
    "HOPLOC_ANCHORS",
    "HOPLOC_SLOT_MS",
    "HOPLOC_CHANNELS",
    "HOPLOC_SINK_CHANNEL",
    "HOPLOC_PAN",
    "HOPLOC_KEY",
];

/// Why [`from_env`] rejected a variable: which one, and what it should hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EnvError {
    /// The variable, e.g. `HOPLOC_X`.
    pub var: &'static str,
    /// What it must hold, e.g. `an integer -32768…32767 (cm)`.
    pub expected: &'static str,
}

impl fmt::Display for EnvError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "invalid {}: expected {}", self.var, self.expected)
    }
}

impl core::error::Error for EnvError {}

const EXPECT_ID: &str = "a node id 1…255 (an anchor's at most HOPLOC_ANCHORS)";
const EXPECT_POS: &str = "an integer -32768…32767 (cm)";
const EXPECT_ANCHORS: &str = "the number of anchors, 3…8";
const EXPECT_SLOT: &str = "a slot length in ms, up to 10000, that holds a beacon: at least 17 \
     with 3 or 4 anchors, 18 with 5 to 7, 19 with 8 (loc_proto::schedule::min_slot_ms)";
const EXPECT_CHANNELS: &str =
    "1…4 distinct testbed channels 1…16, comma separated, e.g. 1,12 (the S1 Pro has 2…13 only)";
const EXPECT_SINK: &str = "a testbed channel 1…16";
const EXPECT_PAN: &str = "a PAN id, decimal or 0x-hex, not 0xFFFF";
const EXPECT_KEY: &str = "a network key: 32 hex digits (16 bytes), the same on every node";

/// A PAN id as the tools take it: decimal (`13106`) or hex with `0x` (`0x3332`); 0xFFFF (the
/// broadcast PAN) is refused.
pub fn parse_pan(s: &str) -> Option<u16> {
    let s = s.trim();
    let pan = match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(hex) => u16::from_str_radix(hex, 16).ok()?,
        None => s.parse().ok()?,
    };
    (pan != 0xFFFF).then_some(pan)
}

/// A channel list as the tools take it: testbed channels separated by commas (`1,12`).
pub fn parse_channels(s: &str) -> Result<ChannelList, Error> {
    let mut list = [0u8; 4];
    let mut n = 0;
    for part in s.split(',') {
        let c = part.trim().parse().map_err(|_| bad(Field::Channel))?;
        *list.get_mut(n).ok_or(bad(Field::ChannelCount))? = c;
        n += 1;
    }
    ChannelList::new(&list[..n])
}

/// `v` parsed by `parse`; `None` if unset or empty.
fn env_value<V: AsRef<str>, T>(
    v: Option<V>,
    var: &'static str,
    expected: &'static str,
    parse: impl Fn(&str) -> Option<T>,
) -> Result<Option<T>, EnvError> {
    match v.as_ref().map(|v| v.as_ref().trim()) {
        None | Some("") => Ok(None),
        Some(s) => parse(s).map(Some).ok_or(EnvError { var, expected }),
    }
}

/// The config of a `role` firmware from build-time variables ([`ENV_VARS`]), read through
/// `lookup` (in a build script, `|name| std::env::var(name).ok()`):
///
/// | variable | field | example |
/// |---|---|---|
/// | `HOPLOC_ID` | node id | `2` |
/// | `HOPLOC_X`, `HOPLOC_Y` | position in cm (a sink: the room size, 0 0 = the anchors' bounding box) | `700` |
/// | `HOPLOC_ANCHORS` | number of anchors N | `4` |
/// | `HOPLOC_SLOT_MS` | slot length (ms) | `62` |
/// | `HOPLOC_CHANNELS` | anchor channels in hop order | `1,12` |
/// | `HOPLOC_SINK_CHANNEL` | sink channel | `3` |
/// | `HOPLOC_PAN` | PAN id, decimal or `0x` hex | `0x3332` |
/// | `HOPLOC_KEY` | network key, 32 hex digits (unset: no encryption) | `000102030405060708090A0B0C0D0E0F` |
///
/// An unset (or empty) variable keeps the field of [`Config::default_for`] `role`. Values may
/// have surrounding spaces. The first invalid variable is the error, naming it; a config whose
/// fields disagree (an anchor id above N) names the variable to change.
pub fn from_env<V: AsRef<str>>(
    role: Role,
    mut lookup: impl FnMut(&str) -> Option<V>,
) -> Result<Config, EnvError> {
    let mut c = Config::default_for(role);
    macro_rules! var {
        ($var:literal, $expected:expr, $parse:expr) => {
            env_value(lookup($var), $var, $expected, $parse)?
        };
    }
    if let Some(v) = var!("HOPLOC_ID", EXPECT_ID, |s| s.parse().ok()) {
        c.id = v;
    }
    if let Some(v) = var!("HOPLOC_X", EXPECT_POS, |s| s.parse().ok()) {
        c.position.x = v;
    }
    if let Some(v) = var!("HOPLOC_Y", EXPECT_POS, |s| s.parse().ok()) {
        c.position.y = v;
    }
    if let Some(v) = var!("HOPLOC_ANCHORS", EXPECT_ANCHORS, |s| s.parse().ok()) {
        c.anchors = v;
    }
    if let Some(v) = var!("HOPLOC_SLOT_MS", EXPECT_SLOT, |s| s.parse().ok()) {
        c.slot_ms = v;
    }
    if let Some(v) = var!("HOPLOC_CHANNELS", EXPECT_CHANNELS, |s| parse_channels(s)
        .ok())
    {
        c.channels = v;
    }
    if let Some(v) = var!("HOPLOC_SINK_CHANNEL", EXPECT_SINK, |s| s.parse().ok()) {
        c.sink_channel = v;
    }
    if let Some(v) = var!("HOPLOC_PAN", EXPECT_PAN, parse_pan) {
        c.pan_id = v;
    }
    if let Some(v) = var!("HOPLOC_KEY", EXPECT_KEY, NetworkKey::parse) {
        c.key = Some(v);
    }
    c.validate().map_err(|e| {
        let (var, expected) = match e {
            Error::BadValue {
                field: Field::Anchors,
            } => ("HOPLOC_ANCHORS", EXPECT_ANCHORS),
            Error::BadValue {
                field: Field::SlotLength,
            } => ("HOPLOC_SLOT_MS", EXPECT_SLOT),
            Error::BadValue {
                field: Field::SinkChannel,
            } => ("HOPLOC_SINK_CHANNEL", EXPECT_SINK),
            Error::BadValue {
                field: Field::PanId,
            } => ("HOPLOC_PAN", EXPECT_PAN),
            _ => ("HOPLOC_ID", EXPECT_ID),
        };
        EnvError { var, expected }
    })?;
    Ok(c)
}

impl Default for Config {
    fn default() -> Self {
        Config::DEFAULT
    }
}

/// The role byte: 0 anchor, 1 agent, 2 sink.
pub const fn role_code(role: Role) -> u8 {
    match role {
        Role::Anchor => 0,
        Role::Agent => 1,
        Role::Sink => 2,
    }
}

fn role_of(b: u8) -> Result<Role, Error> {
    match b {
        0 => Ok(Role::Anchor),
        1 => Ok(Role::Agent),
        2 => Ok(Role::Sink),
        _ => Err(bad(Field::Role)),
    }
}

/// The radio settings a node with `config` gives its radio at bring-up (besides
/// [`xbee_api::driver::FIXED_SETTINGS`], which every node gives it): `MY` = the role's address of the node id, `ID` = the PAN,
/// `CH` = the first anchor channel (anchors, agents: where the first beacons go) or the sink
/// channel (the sink: where reports come), the channel access (on an agent `RN` =
/// [`crate::schedule::AGENT_BACKOFF_EXPONENT`] and `CA` = [`crate::schedule::AGENT_CCA_THRESHOLD`], so that two senders of one
/// sub-slot take turns rather than collide; on the others `RN` = 0 and the factory `CA`, so that
/// a beacon goes on air when its slot says, whatever a radio came with), and the encryption:
/// on with the network key (`KY`, `EE` = 1) or off (`EE` = 0), never left as a radio had it.
pub fn radio_settings(config: &Config) -> BringUpConfig {
    // Per role in one match: the boot channel, `RN`, `CA`. Channel 0 (no anchor channel) is
    // no testbed channel: `xbee_channel` says `None`.
    let (channel, backoff, cca) = match config.role {
        Role::Sink => (config.sink_channel, 0, FACTORY_CCA_THRESHOLD),
        Role::Anchor => (first_channel(config), 0, FACTORY_CCA_THRESHOLD),
        Role::Agent => (
            first_channel(config),
            crate::schedule::AGENT_BACKOFF_EXPONENT,
            crate::schedule::AGENT_CCA_THRESHOLD,
        ),
    };
    let mut radio = BringUpConfig {
        my: Some(config.role.address(config.id)),
        pan_id: Some(config.pan_id),
        channel: crate::xbee_channel(channel),
        backoff_exponent: Some(backoff),
        cca_threshold: Some(cca),
        encryption: Encryption::Off,
        ..BringUpConfig::new()
    };
    // The key copied once, into its place.
    if let Some(NetworkKey(key)) = &config.key {
        radio.encryption = Encryption::Key(*key);
    }
    radio
}

/// The first anchor channel of `config` (0, no testbed channel, if it has none).
fn first_channel(config: &Config) -> u8 {
    config.channels.as_slice().first().copied().unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{ChannelList, Position};

    #[rustfmt::skip]
    const DEFAULT_BYTES: [u8; 20] = [
        0xC5, 1, 20, // magic, version, length
        0, 1, 4, // anchor, id 1, 4 anchors
        0, 0, 0, 0, // (0, 0)
        62, 0, // slot 62 ms
        3, // sink channel
        0x32, 0x33, // PAN 0x3332
        2, 1, 12, // channels
        0xE1, 0xE3, // CRC-16/CCITT-FALSE of the above
    ];

    fn golden() -> [u8; 20] {
        DEFAULT_BYTES
    }

    #[test]
    fn radio_settings_per_role() {
        for role in [Role::Anchor, Role::Agent, Role::Sink] {
            let c = Config::default_for(role);
            let r = radio_settings(&c);
            assert_eq!(r.my, Some(role.address(1)));
            assert_eq!(r.pan_id, Some(c.pan_id));
            let n = match role {
                Role::Sink => c.sink_channel,
                _ => c.channels.as_slice()[0],
            };
            assert_eq!(r.channel, Some(0x0A + n));
            let access = match role {
                Role::Agent => (
                    crate::schedule::AGENT_BACKOFF_EXPONENT,
                    crate::schedule::AGENT_CCA_THRESHOLD,
                ),
                _ => (0, FACTORY_CCA_THRESHOLD),
            };
            assert_eq!(
                (r.backoff_exponent, r.cca_threshold),
                (Some(access.0), Some(access.1))
            );
            assert_eq!(
                r.encryption,
                Encryption::Off,
                "no key: encryption off, never left"
            );
            let keyed = Config {
                key: Some(NetworkKey([7; 16])),
                ..c
            };
            assert_eq!(radio_settings(&keyed).encryption, Encryption::Key([7; 16]));
        }
    }

    #[test]
    fn default_golden_bytes() {
        let mut buf = [0; MAX_LEN];
        assert_eq!(Config::DEFAULT.to_bytes(&mut buf), Ok(20));
        assert_eq!(buf[..20], golden());
        assert_eq!(Config::from_bytes(&golden()), Ok(Config::DEFAULT));
        // A whole EEPROM block: trailing bytes are ignored.
        assert_eq!(Config::from_bytes(&buf), Ok(Config::DEFAULT));
        assert_eq!(crc16(&golden()), 0, "the CRC over the whole block is 0");
    }

    #[test]
    fn every_single_byte_corruption_is_caught() {
        let good = golden();
        for i in 0..good.len() {
            for bit in 0..8 {
                let mut b = good;
                b[i] ^= 1 << bit;
                assert!(Config::from_bytes(&b).is_err(), "byte {i} bit {bit}");
            }
            for v in 0..=255u8 {
                let mut b = good;
                if b[i] != v {
                    b[i] = v;
                    assert!(Config::from_bytes(&b).is_err(), "byte {i} = {v}");
                }
            }
        }
    }

    fn with(f: impl FnOnce(&mut Config)) -> Result<usize, Error> {
        let mut c = Config::DEFAULT;
        f(&mut c);
        c.to_bytes(&mut [0; MAX_LEN])
    }

    #[test]
    fn field_errors() {
        let field = |f| Err(Error::BadValue { field: f });
        assert_eq!(with(|c| c.id = 0), field(Field::NodeId));
        assert_eq!(with(|c| c.id = 5), field(Field::NodeId));
        assert_eq!(
            with(|c| {
                c.role = Role::Agent;
                c.id = 200
            }),
            Ok(20)
        );
        assert_eq!(with(|c| c.anchors = 2), field(Field::Anchors));
        assert_eq!(with(|c| c.anchors = 9), field(Field::Anchors));
        assert_eq!(with(|c| c.slot_ms = 1), field(Field::SlotLength));
        assert_eq!(with(|c| c.slot_ms = 10_001), field(Field::SlotLength));
        assert_eq!(with(|c| c.sink_channel = 0), field(Field::SinkChannel));
        assert_eq!(with(|c| c.sink_channel = 17), field(Field::SinkChannel));
        assert_eq!(with(|c| c.pan_id = 0xFFFF), field(Field::PanId));
        assert_eq!(
            Config::DEFAULT.to_bytes(&mut [0; 19]),
            Err(Error::BufferTooSmall { need: 20 })
        );
    }

    /// `bytes` with byte `i` set to `v` and the CRC fixed up: reaches the field checks.
    /// The default config with the key 00 01 … 0F (its CRC computed bit by bit apart from this
    /// crate).
    const KEYED_BYTES: [u8; 36] = [
        0xC5, 1, 36, // magic, version, length
        0, 1, 4, // anchor, id 1, 4 anchors
        0, 0, 0, 0, // (0, 0)
        62, 0, // slot 62 ms
        3, // sink channel
        0x32, 0x33, // PAN 0x3332
        0x82, 1, 12, // a key follows; channels
        0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, // the key
        0xF4, 0xD9, // CRC
    ];

    #[test]
    fn keyed_golden_bytes() {
        let keyed = Config {
            key: Some(NetworkKey(core::array::from_fn(|i| i as u8))),
            ..Config::DEFAULT
        };
        let mut buf = [0; MAX_LEN];
        assert_eq!(keyed.to_bytes(&mut buf), Ok(36));
        assert_eq!(buf[..36], KEYED_BYTES);
        assert_eq!(Config::from_bytes(&KEYED_BYTES), Ok(keyed));
        assert_eq!(stored(&KEYED_BYTES, Role::Anchor), Stored::Valid(keyed));
        // The same key parsed as the tools take it; its Debug does not show it.
        let parsed = NetworkKey::parse("000102030405060708090a0B0c0D0e0F");
        assert_eq!(parsed, keyed.key);
        assert_eq!(std::format!("{:?}", keyed.key), "Some(NetworkKey(..))");
        // Every single-byte change of the key is a bad CRC.
        for at in 18..34 {
            let mut b = KEYED_BYTES;
            b[at] ^= 0x5A;
            assert_eq!(Config::from_bytes(&b), Err(Error::BadCrc));
        }
    }

    fn patched(i: usize, v: u8) -> [u8; 20] {
        let mut b = golden();
        b[i] = v;
        let crc = crc16(&b[..18]);
        b[18..].copy_from_slice(&crc.to_be_bytes());
        b
    }

    #[test]
    fn only_the_true_crc_decodes() {
        // `from_bytes` checks the CRC as "CRC over the whole block is 0": every other value of
        // the two CRC bytes must still be BadCrc.
        let mut b = [0u8; MAX_LEN];
        let n = Config::DEFAULT.to_bytes(&mut b).unwrap();
        let good = u16::from_be_bytes([b[n - 2], b[n - 1]]);
        assert_eq!(good, crc16(&b[..n - 2]));
        for v in 0..=u16::MAX {
            b[n - 2..n].copy_from_slice(&v.to_be_bytes());
            let want = if v == good {
                Ok(Config::DEFAULT)
            } else {
                Err(Error::BadCrc)
            };
            assert_eq!(Config::from_bytes(&b[..n]), want, "crc {v:#06x}");
        }
    }

    /// The node's decoder answers as `from_bytes` and the role check do, on every value of every
    /// byte (CRC fixed up, so the field checks are reached), for each role; `out` only changes
    /// on success, and `None` only checks.
    #[test]
    fn read_into_is_from_bytes_then_the_role() {
        // The default config and the keyed one, each byte but the CRC.
        let keyed = |i: usize, v: u8| {
            let mut b = KEYED_BYTES;
            b[i] = v;
            let crc = crc16(&b[..34]);
            b[34..].copy_from_slice(&crc.to_be_bytes());
            b
        };
        let blocks = (0..18)
            .map(|i| (i, false))
            .chain((0..34).map(|i| (i, true)));
        for (i, with_key) in blocks {
            for v in 0..=255u8 {
                let b: &[u8] = if with_key {
                    &keyed(i, v)
                } else {
                    &patched(i, v)
                };
                let want = Config::from_bytes(b);
                for role in Role::ALL {
                    let sentinel = Config::default_for(Role::Sink);
                    let mut out = sentinel;
                    let code = read_into(b, role, Some(&mut out));
                    let expect = match want {
                        Ok(c) if c.role == role => 0,
                        Ok(_) => WRONG_ROLE,
                        Err(e) => e.code(),
                    };
                    assert_eq!(code, expect, "byte {i} = {v} {role:?}");
                    assert_eq!(read_into(b, role, None), expect);
                    if code == 0 {
                        assert_eq!(Ok(out), want);
                    } else {
                        assert_eq!(out, sentinel, "byte {i} = {v} {role:?}");
                    }
                }
            }
        }
    }

    /// `read_into` (the node's decoder, written apart from `decode`) answers as `from_bytes`
    /// and the role check on any bytes: random ones, and random ones with magic, version,
    /// length, channel count and CRC made right so the field checks decide.
    fn read_into_agrees(b: &[u8]) -> Result<(), proptest::test_runner::TestCaseError> {
        let want = Config::from_bytes(b);
        for role in Role::ALL {
            let sentinel = Config::default_for(Role::Sink);
            let mut out = sentinel;
            let expect = match want {
                Ok(c) if c.role == role => 0,
                Ok(_) => WRONG_ROLE,
                Err(e) => e.code(),
            };
            proptest::prop_assert_eq!(read_into(b, role, Some(&mut out)), expect);
            proptest::prop_assert_eq!(read_into(b, role, None), expect);
            if expect == 0 {
                proptest::prop_assert_eq!(Ok(out), want);
            } else {
                proptest::prop_assert_eq!(out, sentinel);
            }
        }
        Ok(())
    }

    /// The 16-bit fields, every value (a one-byte change reaches few values near their
    /// bounds): slot length and PAN id, and every id × N pair.
    #[test]
    fn read_into_is_from_bytes_on_every_u16_field_value() {
        let fixed = |f: &dyn Fn(&mut [u8; 20])| {
            let mut b = golden();
            f(&mut b);
            let crc = crc16(&b[..18]);
            b[18..].copy_from_slice(&crc.to_be_bytes());
            b
        };
        for v in 0..=u16::MAX {
            let [lo, hi] = v.to_le_bytes();
            read_into_agrees(&fixed(&|b| [b[10], b[11]] = [lo, hi])).unwrap();
            read_into_agrees(&fixed(&|b| [b[13], b[14]] = [lo, hi])).unwrap();
            read_into_agrees(&fixed(&|b| [b[4], b[5]] = [lo, hi])).unwrap();
            read_into_agrees(&fixed(&|b| [b[3], b[4]] = [lo, hi])).unwrap();
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(20_000))]
        #[test]
        fn read_into_is_from_bytes_on_fuzz(
            mut v in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..42),
            fix in 0u8..4,
            small in proptest::collection::vec(0u8..20, 16),
        ) {
            if fix != 0 && v.len() >= MIN_LEN {
                let len = v.len().min(MAX_LEN);
                v[0] = MAGIC;
                v[1] = VERSION;
                v[2] = len as u8;
                if fix >= 2 {
                    // Field values near their bounds, so valid configs turn up too.
                    for (i, &x) in small.iter().enumerate().skip(3) {
                        if i + 2 < len && fix == 3 {
                            v[i] = x;
                        }
                    }
                    v[3] %= 4;
                    v[15] = if len > 18 + KEY_LEN {
                        (len - 18 - KEY_LEN) as u8 | KEY_FLAG
                    } else {
                        (len - 18) as u8
                    };
                }
                let crc = crc16(&v[..len - 2]);
                v[len - 2..len].copy_from_slice(&crc.to_be_bytes());
            }
            read_into_agrees(&v)?;
        }
    }

    #[test]
    fn the_config_line_is_the_boot_lines() {
        use crate::line::{BootLine, ConfigSource};
        let text = |w: &dyn Fn(&mut std::string::String)| {
            let mut s = std::string::String::new();
            w(&mut s);
            s.into_bytes()
        };
        for role in Role::ALL {
            for source in [ConfigSource::Eeprom, ConfigSource::BuiltIn] {
                for id in 0..=255u8 {
                    let got = text(&|s| {
                        let Ok(()) = write_config_line(s, role, 0, source, id);
                    });
                    let want = text(&|s| {
                        let Ok(()) = BootLine::Config { role, source, id }.write(s);
                    });
                    assert_eq!(got, want);
                    assert_eq!(
                        BootLine::parse(core::str::from_utf8(&got).unwrap()),
                        Ok(BootLine::Config { role, source, id })
                    );
                }
            }
            for code in 1..=255u8 {
                let got = text(&|s| {
                    let Ok(()) = write_config_line(s, role, code, ConfigSource::Eeprom, 7);
                });
                let want = text(&|s| {
                    let Ok(()) = BootLine::ConfigError { role, code }.write(s);
                });
                assert_eq!(got, want);
            }
        }
    }

    #[test]
    fn decode_errors() {
        let field = |f| Err(Error::BadValue { field: f });
        assert_eq!(Config::from_bytes(&golden()[..2]), Err(Error::TooShort));
        assert_eq!(Config::from_bytes(&golden()[..19]), Err(Error::TooShort));
        assert_eq!(Config::from_bytes(&[0xFF; 22]), Err(Error::BadMagic));
        assert_eq!(
            Config::from_bytes(&patched(1, 2)),
            Err(Error::BadVersion { found: 2 })
        );
        assert_eq!(Config::from_bytes(&patched(2, 39)), Err(Error::BadLength));
        // A length that claims a key the block does not have.
        assert_eq!(Config::from_bytes(&patched(2, 23)), Err(Error::TooShort));
        assert_eq!(
            Config::from_bytes(&patched(15, 0x82)),
            Err(Error::BadLength)
        );
        assert_eq!(Config::from_bytes(&patched(15, 3)), Err(Error::BadLength));
        assert_eq!(Config::from_bytes(&patched(3, 3)), field(Field::Role));
        assert_eq!(
            Config::from_bytes(&patched(17, 1)),
            field(Field::DuplicateChannel)
        );
        assert_eq!(Config::from_bytes(&patched(17, 0)), field(Field::Channel));
        assert_eq!(Config::from_bytes(&patched(4, 0)), field(Field::NodeId));
        let mut b = golden();
        b[19] ^= 1;
        assert_eq!(Config::from_bytes(&b), Err(Error::BadCrc));
    }

    fn env(vars: &[(&str, &str)]) -> impl FnMut(&str) -> Option<&'static str> {
        let owned: std::vec::Vec<(std::string::String, &'static str)> = vars
            .iter()
            .map(|&(k, v)| {
                let v: &'static str = std::boxed::Box::leak(v.into());
                (k.into(), v)
            })
            .collect();
        move |name| owned.iter().find(|(k, _)| k == name).map(|&(_, v)| v)
    }

    #[test]
    fn from_env_unset_is_the_role_default() {
        for role in Role::ALL {
            assert_eq!(from_env(role, env(&[])), Ok(Config::default_for(role)));
            // Empty counts as unset.
            assert_eq!(
                from_env(role, env(&[("HOPLOC_X", ""), ("HOPLOC_PAN", " ")])),
                Ok(Config::default_for(role))
            );
        }
    }

    #[test]
    fn from_env_reads_every_variable() {
        let c = from_env(
            Role::Anchor,
            env(&[
                ("HOPLOC_ID", "2"),
                ("HOPLOC_X", "700"),
                ("HOPLOC_Y", "-5"),
                ("HOPLOC_ANCHORS", "3"),
                ("HOPLOC_SLOT_MS", " 25 "),
                ("HOPLOC_CHANNELS", "5, 9,12"),
                ("HOPLOC_SINK_CHANNEL", "4"),
                ("HOPLOC_PAN", "0x1234"),
                ("HOPLOC_KEY", " 000102030405060708090a0b0c0d0eFF "),
            ]),
        )
        .unwrap();
        assert_eq!(
            c,
            Config {
                role: Role::Anchor,
                id: 2,
                anchors: 3,
                position: Position { x: 700, y: -5 },
                slot_ms: 25,
                channels: ChannelList::new(&[5, 9, 12]).unwrap(),
                sink_channel: 4,
                pan_id: 0x1234,
                key: Some(NetworkKey([
                    0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 0xFF
                ])),
            }
        );
        assert_eq!(c.size(), 18 + 3 + KEY_LEN);
        let sink = from_env(Role::Sink, env(&[("HOPLOC_PAN", "13106")])).unwrap();
        assert_eq!(sink.pan_id, 0x3332);
        assert_eq!(sink.role, Role::Sink);
    }

    #[test]
    fn from_env_names_the_bad_variable() {
        let bad = |role, k, v| from_env(role, env(&[(k, v)])).map_err(|e| e.var);
        for (k, v) in [
            ("HOPLOC_ID", "0"),
            ("HOPLOC_ID", "5"), // anchor 5 of 4
            ("HOPLOC_ID", "256"),
            ("HOPLOC_ID", "one"),
            ("HOPLOC_X", "40000"),
            ("HOPLOC_Y", "1.5"),
            ("HOPLOC_ANCHORS", "2"),
            ("HOPLOC_ANCHORS", "9"),
            ("HOPLOC_SLOT_MS", "1"),
            ("HOPLOC_SLOT_MS", "10001"),
            ("HOPLOC_CHANNELS", ""),
            ("HOPLOC_CHANNELS", "1,1"),
            ("HOPLOC_CHANNELS", "0"),
            ("HOPLOC_CHANNELS", "1,2,3,4,5"),
            ("HOPLOC_CHANNELS", "1;12"),
            ("HOPLOC_CHANNELS", "1,"),
            ("HOPLOC_SINK_CHANNEL", "17"),
            ("HOPLOC_PAN", "0xFFFF"),
            ("HOPLOC_PAN", "65535"),
            ("HOPLOC_PAN", "0x10000"),
            ("HOPLOC_PAN", "3332h"),
            ("HOPLOC_KEY", "0001"),
            ("HOPLOC_KEY", "000102030405060708090a0b0c0d0e0f00"),
            ("HOPLOC_KEY", "000102030405060708090a0b0c0d0eXY"),
            ("HOPLOC_KEY", "+00102030405060708090a0b0c0d0e0f"),
            ("HOPLOC_KEY", "é0102030405060708090a0b0c0d0e0"),
        ] {
            if v.is_empty() {
                continue; // empty = unset
            }
            assert_eq!(bad(Role::Anchor, k, v), Err(k), "{k}={v}");
        }
        // An agent's id is not bounded by N.
        assert_eq!(
            bad(Role::Agent, "HOPLOC_ID", "200"),
            Ok(Config {
                role: Role::Agent,
                id: 200,
                ..Config::DEFAULT
            })
        );
        // Fewer anchors than the anchor id: the message says which variable.
        let e = from_env(
            Role::Anchor,
            env(&[("HOPLOC_ID", "4"), ("HOPLOC_ANCHORS", "3")]),
        )
        .unwrap_err();
        assert_eq!(e.var, "HOPLOC_ID");
        assert_eq!(
            std::format!("{e}"),
            "invalid HOPLOC_ID: expected a node id 1…255 (an anchor's at most HOPLOC_ANCHORS)"
        );
    }

    #[test]
    fn what_the_eeprom_holds() {
        let mut block = [0xFF; 32];
        assert_eq!(stored(&block, Role::Anchor), Stored::Erased);
        let n = Config::DEFAULT.to_bytes(&mut block).unwrap();
        assert_eq!(stored(&block, Role::Anchor), Stored::Valid(Config::DEFAULT));
        assert_eq!(stored(&block, Role::Agent), Stored::Invalid(WRONG_ROLE));
        block[n - 1] ^= 1;
        assert_eq!(stored(&block, Role::Anchor), Stored::Invalid(7));
        assert_eq!(stored(&[0; 32], Role::Anchor), Stored::Invalid(2));
        assert_eq!(stored(&patched(1, 2), Role::Anchor), Stored::Invalid(3));
        assert_eq!(stored(&[], Role::Anchor), Stored::Invalid(1));
    }
}
