//! The binary messages nodes send each other over the radio: [`Beacon`] (anchor → everyone) and
//! [`Report`] (agent → sink). Each is the whole RF payload of one XBee TX16/RX16 frame.
//!
//! Every message starts with the same 4-byte header and ends with a CRC; multi-byte integers are
//! little endian (the AVR's own order), but for the CRC. A message with a wrong magic, version,
//! length, CRC or kind, or with a field out of its range, is dropped (and counted by the node),
//! never trusted. Decoders never panic on any input, and a decoded message re-encodes to
//! exactly the bytes it came from.
//!
//! The CRC is the message's own check: the 802.15.4 MAC's FCS and the XBee's frame checksum
//! guard the bytes on the air and on the UART, but not what the radio makes of them. With
//! encryption on (a network key), a radio holding another key decrypts a packet into other
//! bytes of the same length and passes them on as a good frame; the CRC rejects them (a
//! random payload passes the magic, version and length bytes and the CRC-16 together about
//! once in 2⁴⁰).
//!
//! | byte | field |
//! |---|---|
//! | 0 | magic [`MAGIC`] (0xB5) |
//! | 1 | version [`VERSION`] (2) |
//! | 2 | kind: 1 beacon, 2 report |
//! | 3 | length of the whole message in bytes, header and CRC included |
//! | … | the kind's fields, below |
//! | last 2 | CRC-16/CCITT-FALSE ([`crate::error::crc16`]) of every byte before it, big endian (so that the CRC of the whole message is 0) |
//!
//! **Beacon** (kind 1), 15 + R bytes (19 with R = 4 relayed anchors, 23 at most):
//!
//! | byte | field |
//! |---|---|
//! | 4 | anchor id (1…8) |
//! | 5–6 | superframe sequence (u16) |
//! | 7 | testbed channel the beacon is sent on (1…16) |
//! | 8–9, 10–11 | anchor position x, y (i16, cm) |
//! | 12 | R, the number of relayed RSSI bytes (0…8) |
//! | 13 … 12+R | byte *j*: RSSI (−dBm, 0 = not heard) this anchor measured from anchor *j*+1 on this channel in the previous superframe; its own entry is 0 |
//!
//! **Report** (kind 2), N anchors (3…8), C channels (1…4):
//!
//! | byte | field |
//! |---|---|
//! | 4 | agent id (1…255) |
//! | 5–6 | superframe sequence (u16) |
//! | 7 | N |
//! | 8 | C in bits 0–2; bits 3–5: the agent's reports since its last one whose transmission failed (0…7, saturating: its radio found the channel busy, or the sink's radio did not acknowledge); bit 7 set: relay rows follow; bit 6 set (with bit 7): only a window of them |
//! | 9 … 8+C | the C testbed channels (1…16, distinct) |
//! | then 4·N | per anchor *i* = 1…N: position x, y (i16, cm; 0, 0 if never heard) |
//! | then C·N | per channel, per anchor: the RSSI byte of its beacon (−dBm, 0 = not heard) |
//! | then 2 | if bits 7 and 6: the window of relay rows sent: its first row *s* and its length *k* (rows numbered *r* = *c*·N + *i* for anchor *i* + 1 on channel number *c*, so 0 ≤ *s* < C·N, 0 ≤ *k* < C·N); the rows *s*, *s* + 1, … *s* + *k* − 1 (modulo C·N) follow, in that order |
//! | then (N−1) per row | if bit 7: per row, anchor *i*'s: per other anchor *j* ≠ *i* (ascending), the RSSI *i* relayed having measured from *j* (0 = not heard or not relayed); the diagonal is not sent. Without bit 6, every row in order *r* = 0 … C·N − 1: the relay matrix |
//!
//! Size, CRC included: 11 + C + 4N + C·N without relay rows; 11 + C + 4N + C·N² with all of
//! them (the relay matrix); 13 + C + 4N + C·N + k·(N−1) with a window of k rows. 4 anchors × 2
//! channels: **61 bytes** (37 without relay). Every message fits 95 bytes ([`MAX_MESSAGE`]),
//! the radio's payload limit with encryption on, so that a network runs the same with or without
//! a key. That admits the whole matrix up to N×C = 4×4 (95 bytes), 5×2 (83), 7×1 (89); beyond,
//! an agent sends as many rows as fit and a different set in each superframe
//! ([`Report::fit_relay`]), so that every row reaches the sink every few superframes: with 8
//! anchors × 4 channels, 2 of the 32 rows (95 bytes), each row every 16 superframes. Every
//! configuration's report fits one packet.
//! [`Report::encode`] returns [`Error::TooLarge`] for a report that does not fit.

use crate::error::{crc16, Error, Field};

/// The first byte of every hoploc radio message.
pub const MAGIC: u8 = 0xB5;
/// The message format version this build writes and reads.
pub const VERSION: u8 = 2;
/// Bytes of the common header (magic, version, kind, length).
pub const HEADER_LEN: usize = 4;
/// Bytes of the CRC that ends every message.
pub const CRC_LEN: usize = 2;
/// The largest RF payload of an XBee 802.15.4 TX frame.
pub const MAX_PAYLOAD: usize = xbee_api::MAX_RF_PAYLOAD;
/// The largest hoploc message: the XBee S1's RF payload limit with encryption on (`EE` = 1;
/// [`MAX_PAYLOAD`] without). Every message fits it, so a network runs the same with or without
/// a network key.
pub const MAX_MESSAGE: usize = xbee_api::MAX_RF_PAYLOAD_ENCRYPTED;
/// The most anchors a network has, and the most channels in a channel list: what the estimator
/// (loc-core) takes, so that every report it can be sent, it can locate.
pub use loc_core::{MAX_ANCHORS, MAX_CHANNELS};
/// The highest testbed channel number.
pub const MAX_CHANNEL: u8 = 16;

/// The kind byte of a [`Beacon`].
pub const KIND_BEACON: u8 = 1;
/// The kind byte of a [`Report`].
pub const KIND_REPORT: u8 = 2;

/// The report flag: relay rows follow.
const RELAY_FLAG: u8 = 0x80;
/// The report flag (with [`RELAY_FLAG`]): only a window of the rows.
const ROWS_FLAG: u8 = 0x40;
/// The report bits of [`Report::failed`].
const FAILED_BITS: u8 = 0x38;
/// The most [`Report::failed`] counts.
pub const MAX_FAILED: u8 = 7;

/// A position in cm.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Position {
    /// x (cm).
    pub x: i16,
    /// y (cm).
    pub y: i16,
}

/// A list of 1…4 distinct testbed channels (1…16), in hop order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ChannelList {
    len: u8,
    // Entries past `len` are 0, so equal lists compare equal.
    list: [u8; MAX_CHANNELS],
}

impl ChannelList {
    /// The list of `channels`, or why it is not one: [`Field::ChannelCount`] if empty or longer
    /// than 4, [`Field::Channel`] outside 1…16, [`Field::DuplicateChannel`]. Always inlined: out
    /// of line its result comes back through memory on AVR; inlined into the config decoder
    /// (each firmware's one caller) it is less flash.
    #[inline(always)]
    pub const fn new(channels: &[u8]) -> Result<ChannelList, Error> {
        if channels.is_empty() || channels.len() > MAX_CHANNELS {
            return Err(bad(Field::ChannelCount));
        }
        let mut list = [0; MAX_CHANNELS];
        let mut i = 0;
        while i < channels.len() {
            let c = channels[i];
            if c < 1 || c > MAX_CHANNEL {
                return Err(bad(Field::Channel));
            }
            let mut j = 0;
            while j < i {
                if list[j] == c {
                    return Err(bad(Field::DuplicateChannel));
                }
                j += 1;
            }
            list[i] = c;
            i += 1;
        }
        Ok(ChannelList {
            len: channels.len() as u8,
            list,
        })
    }

    /// The channels.
    pub fn as_slice(&self) -> &[u8] {
        &self.list[..(self.len as usize).min(MAX_CHANNELS)]
    }

    /// How many channels (1…4).
    pub const fn len(&self) -> usize {
        self.len as usize
    }

    /// Always false: a channel list has at least one channel.
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }
}

pub(crate) const fn bad(field: Field) -> Error {
    Error::BadValue { field }
}

/// Reads fields off a byte slice; running out is [`Error::BadLength`] (the length byte
/// promised more than the fields need or vice versa).
pub(crate) struct Reader<'a> {
    buf: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(buf: &'a [u8]) -> Self {
        Reader { buf, at: 0 }
    }
    pub(crate) fn u8(&mut self) -> Result<u8, Error> {
        let b = *self.buf.get(self.at).ok_or(Error::BadLength)?;
        self.at += 1;
        Ok(b)
    }
    pub(crate) fn u16(&mut self) -> Result<u16, Error> {
        Ok(u16::from_le_bytes([self.u8()?, self.u8()?]))
    }
    pub(crate) fn i16(&mut self) -> Result<i16, Error> {
        Ok(self.u16()? as i16)
    }
    pub(crate) fn position(&mut self) -> Result<Position, Error> {
        Ok(Position {
            x: self.i16()?,
            y: self.i16()?,
        })
    }
    /// The next `n` bytes.
    pub(crate) fn bytes(&mut self, n: u8) -> Result<&'a [u8], Error> {
        let end = self.at + n as usize;
        let b = self.buf.get(self.at..end).ok_or(Error::BadLength)?;
        self.at = end;
        Ok(b)
    }
    /// Fails with [`Error::BadLength`] unless every byte was read.
    pub(crate) fn end(&self) -> Result<(), Error> {
        if self.at == self.buf.len() {
            Ok(())
        } else {
            Err(Error::BadLength)
        }
    }
}

/// Writes fields into a buffer the caller checked is long enough (excess writes are dropped).
pub(crate) struct Writer<'a> {
    buf: &'a mut [u8],
    pub(crate) at: usize,
}

impl<'a> Writer<'a> {
    pub(crate) fn new(buf: &'a mut [u8]) -> Self {
        Writer { buf, at: 0 }
    }
    /// Never inlined: an encoder writes a dozen fields, each inlined copy of the bounds check
    /// would be AVR flash of its own.
    #[inline(never)]
    pub(crate) fn u8(&mut self, b: u8) {
        if let Some(s) = self.buf.get_mut(self.at) {
            *s = b;
        }
        self.at += 1;
    }
    pub(crate) fn u16(&mut self, v: u16) {
        let [a, b] = v.to_le_bytes();
        self.u8(a);
        self.u8(b);
    }
    pub(crate) fn position(&mut self, p: Position) {
        self.u16(p.x as u16);
        self.u16(p.y as u16);
    }
    /// Ends a message: its CRC ([`crc16`] of every byte before it, big endian); returns the
    /// message's length.
    fn end_message(mut self) -> usize {
        let [hi, lo] = self.buf.get(..self.at).map_or(0, crc16).to_be_bytes();
        self.u8(hi);
        self.u8(lo);
        self.at
    }
}

/// Checks `size` (CRC included) against [`MAX_MESSAGE`] and the buffer, and writes the header.
fn start(buf: &mut [u8], kind: u8, size: usize) -> Result<Writer<'_>, Error> {
    if size > MAX_MESSAGE {
        return Err(Error::TooLarge { size: size as u16 });
    }
    if buf.len() < size {
        return Err(Error::BufferTooSmall { need: size as u16 });
    }
    let mut w = Writer::new(buf);
    w.u8(MAGIC);
    w.u8(VERSION);
    w.u8(kind);
    w.u8(size as u8);
    Ok(w)
}

/// Rewrites the CRC of the message in `msg` (its last [`CRC_LEN`] bytes) to match the bytes
/// before it: for tests and tools that edit a message's fields and want the decoders to see
/// the edit rather than a bad CRC. Shorter than the CRC: left as it is.
pub fn seal(msg: &mut [u8]) {
    if let Some(end) = msg.len().checked_sub(CRC_LEN) {
        let [hi, lo] = crc16(&msg[..end]).to_be_bytes();
        msg[end] = hi;
        msg[end + 1] = lo;
    }
}

/// Checks magic, version, length and CRC of a message and returns its kind byte and a reader
/// of its body (after the header, before the CRC).
fn open(buf: &[u8]) -> Result<(u8, Reader<'_>), Error> {
    let [magic, version, kind, len, ..] = *buf else {
        return Err(Error::TooShort);
    };
    if magic != MAGIC {
        return Err(Error::BadMagic);
    }
    if version != VERSION {
        return Err(Error::BadVersion { found: version });
    }
    let len = len as usize;
    if buf.len() < len {
        return Err(Error::TooShort);
    }
    if buf.len() > len || len < HEADER_LEN + CRC_LEN {
        return Err(Error::BadLength);
    }
    if crc16(buf) != 0 {
        return Err(Error::BadCrc);
    }
    let mut r = Reader::new(&buf[..len - CRC_LEN]);
    r.at = HEADER_LEN;
    Ok((kind, r))
}

fn check_channel(c: u8) -> Result<(), Error> {
    if (1..=MAX_CHANNEL).contains(&c) {
        Ok(())
    } else {
        Err(bad(Field::Channel))
    }
}

/// A beacon's relayed RSSI bytes: at most [`MAX_ANCHORS`], its length the beacon's R.
pub type Relay = heapless::Vec<u8, MAX_ANCHORS, u8>;

/// An anchor's beacon. See the [module docs](self) for the layout.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Beacon {
    /// The sending anchor (1…8).
    pub anchor: u8,
    /// The superframe sequence number.
    pub seq: u16,
    /// The testbed channel it was sent on (1…16).
    pub channel: u8,
    /// The anchor's position.
    pub position: Position,
    /// `relay[j]`: the RSSI byte (−dBm, 0 = not heard) this anchor measured from anchor `j + 1`
    /// on `channel` in the previous superframe, for the first R anchors (R = `relay.len()`,
    /// 0…8); the anchor's own entry must be 0.
    pub relay: Relay,
}

impl Beacon {
    /// Bytes of a beacon without relay entries.
    pub const BASE_LEN: usize = 15;
    /// The longest beacon (8 relay entries).
    pub const MAX_LEN: usize = Self::BASE_LEN + MAX_ANCHORS;

    /// The encoded size of this beacon.
    pub fn size(&self) -> usize {
        Self::BASE_LEN + self.relay.len()
    }

    fn validate(&self) -> Result<(), Error> {
        if !(1..=MAX_ANCHORS as u8).contains(&self.anchor) {
            return Err(bad(Field::AnchorId));
        }
        check_channel(self.channel)?;
        if self
            .relay
            .get(self.anchor as usize - 1)
            .is_some_and(|&r| r != 0)
        {
            return Err(bad(Field::SelfRssi));
        }
        Ok(())
    }

    /// Writes the beacon into `buf`; returns the bytes written ([`Beacon::size`]).
    pub fn encode(&self, buf: &mut [u8]) -> Result<usize, Error> {
        self.validate()?;
        let mut w = start(buf, KIND_BEACON, self.size())?;
        w.u8(self.anchor);
        w.u16(self.seq);
        w.u8(self.channel);
        w.position(self.position);
        w.u8(self.relay.len() as u8);
        for &r in &self.relay {
            w.u8(r);
        }
        Ok(w.end_message())
    }

    /// Reads a beacon that is all of `buf`.
    pub fn decode(buf: &[u8]) -> Result<Beacon, Error> {
        match open(buf)? {
            (KIND_BEACON, r) => Self::body(r),
            (found, _) => Err(Error::BadKind { found }),
        }
    }

    fn body(mut r: Reader<'_>) -> Result<Beacon, Error> {
        let anchor = r.u8()?;
        let seq = r.u16()?;
        let channel = r.u8()?;
        let position = r.position()?;
        let count = r.u8()?;
        if count as usize > MAX_ANCHORS {
            return Err(bad(Field::RelayCount));
        }
        // (Fits: at most MAX_ANCHORS bytes.)
        let relay = Relay::from_slice(r.bytes(count)?).map_err(|_| bad(Field::RelayCount))?;
        let b = Beacon {
            anchor,
            seq,
            channel,
            position,
            relay,
        };
        r.end()?;
        b.validate()?;
        Ok(b)
    }
}

/// An agent's report of one superframe to the sink. See the [module docs](self) for the layout.
///
/// Entries for anchors past `anchors` and channels past `channels.len()` are not sent (and
/// decode as 0); so is the relay matrix's diagonal, its rows outside `relay_window` and, without
/// `has_relay`, the whole matrix.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Report {
    /// The reporting agent (1…255).
    pub agent: u8,
    /// The superframe sequence number.
    pub seq: u16,
    /// The number of anchors N (3…8).
    pub anchors: u8,
    /// The channels, in hop order (C = `channels.len()`).
    pub channels: ChannelList,
    /// `positions[i]`: anchor `i + 1`'s position (from its beacons; 0, 0 if never heard).
    pub positions: [Position; MAX_ANCHORS],
    /// `rssi[c][i]`: the RSSI byte (−dBm, 0 = not heard) of anchor `i + 1`'s beacon on channel
    /// `channels[c]`.
    pub rssi: [[u8; MAX_ANCHORS]; MAX_CHANNELS],
    /// Whether relay rows are sent.
    pub has_relay: bool,
    /// Which relay rows are sent (with `has_relay`): `None`, every row (the relay matrix);
    /// `Some((s, k))`, the `k` rows from row `s` on, wrapping around (row `c·N + i` is anchor
    /// `i + 1`'s on channel number `c`; `s` and `k` below C·N).
    pub relay_window: Option<(u8, u8)>,
    /// `relay[c][i][j]`: what anchor `i + 1` relayed on channel `channels[c]` as the RSSI it
    /// measured from anchor `j + 1` (0 = not heard, no beacon from `i + 1`, or a row not sent).
    pub relay: [[[u8; MAX_ANCHORS]; MAX_ANCHORS]; MAX_CHANNELS],
    /// The agent's reports since its last one whose transmission failed (0…[`MAX_FAILED`],
    /// saturating): its radio found the channel busy (CCA failure) or the sink's radio did not
    /// acknowledge. What tells a sink that reports are being lost on the way to it.
    pub failed: u8,
}

impl Report {
    /// An empty report (nothing heard) of `anchors` anchors on `channels`, with the relay matrix.
    pub const fn new(agent: u8, seq: u16, anchors: u8, channels: ChannelList) -> Report {
        Report {
            agent,
            seq,
            anchors,
            channels,
            positions: [Position { x: 0, y: 0 }; MAX_ANCHORS],
            rssi: [[0; MAX_ANCHORS]; MAX_CHANNELS],
            has_relay: true,
            relay_window: None,
            relay: [[[0; MAX_ANCHORS]; MAX_ANCHORS]; MAX_CHANNELS],
            failed: 0,
        }
    }

    /// The encoded size of a report of `anchors` × `channels`, with the whole relay matrix or
    /// without relay rows.
    pub const fn wire_size(anchors: usize, channels: usize, relay: bool) -> usize {
        let per_channel = if relay { anchors * anchors } else { anchors };
        9 + channels + 4 * anchors + channels * per_channel + CRC_LEN
    }

    /// The encoded size of this report (may exceed [`MAX_MESSAGE`]: then it is not sent).
    pub const fn size(&self) -> usize {
        let (n, c) = (self.anchors as usize, self.channels.len());
        match (self.has_relay, self.relay_window) {
            (true, Some((_, k))) => Self::wire_size(n, c, false) + 2 + k as usize * (n - 1),
            (relay, _) => Self::wire_size(n, c, relay),
        }
    }

    /// The largest report of `anchors` × `channels` an agent sends (with as many relay rows as
    /// fit, [`Report::fit_relay`]): at most [`MAX_MESSAGE`].
    pub const fn max_size(anchors: usize, channels: usize) -> usize {
        let full = Self::wire_size(anchors, channels, true);
        if full <= MAX_MESSAGE {
            return full;
        }
        let rows = Self::relay_rows_that_fit(anchors, channels);
        if rows == 0 {
            Self::wire_size(anchors, channels, false)
        } else {
            Self::wire_size(anchors, channels, false) + 2 + rows * (anchors - 1)
        }
    }

    /// The most relay rows a report of `anchors` × `channels` can carry in one packet.
    pub const fn relay_rows_that_fit(anchors: usize, channels: usize) -> usize {
        if Self::wire_size(anchors, channels, true) <= MAX_MESSAGE {
            return anchors * channels;
        }
        let base = Self::wire_size(anchors, channels, false) + 2;
        if base >= MAX_MESSAGE || anchors < 2 {
            return 0;
        }
        (MAX_MESSAGE - base) / (anchors - 1)
    }

    /// Whether relay row `row` (`c·N + i`) is sent.
    pub fn sends_row(&self, row: usize) -> bool {
        let total = self.n() * self.channels.len();
        match (self.has_relay, self.relay_window) {
            (false, _) => false,
            (true, None) => row < total,
            (true, Some((s, k))) => row < total && (row + total - s as usize) % total < k as usize,
        }
    }

    /// Makes the report fit one packet ([`MAX_MESSAGE`]): when the relay matrix does not fit,
    /// keeps a window of as many of its rows as fit ([`Report::relay_rows_that_fit`]), the one
    /// after the previous sequence number's (rows wrapping around), so that successive reports
    /// carry every row in turn; the other rows' bytes are cleared. A report that fits, or one
    /// without relay, is left as it is.
    pub fn fit_relay(&mut self) {
        if !self.has_relay || self.size() <= MAX_MESSAGE {
            return;
        }
        let (n, c) = (self.n(), self.channels.len());
        let total = n * c;
        let keep = Self::relay_rows_that_fit(n, c).min(total - 1);
        if keep == 0 {
            self.has_relay = false;
            return;
        }
        // In 32 bits: `usize` is 16 bits on the MCU, and the window must be the host's.
        let start = (self.seq as u32 * keep as u32 % total as u32) as usize;
        self.relay_window = Some((start as u8, keep as u8));
        for r in 0..total {
            if !self.sends_row(r) {
                self.relay[r / n][r % n] = [0; MAX_ANCHORS];
            }
        }
    }

    fn n(&self) -> usize {
        (self.anchors as usize).min(MAX_ANCHORS)
    }

    fn validate(&self) -> Result<(), Error> {
        if self.agent == 0 {
            return Err(bad(Field::AgentId));
        }
        if !(3..=MAX_ANCHORS as u8).contains(&self.anchors) {
            return Err(bad(Field::Anchors));
        }
        let total = self.n() * self.channels.len();
        if let (true, Some((s, k))) = (self.has_relay, self.relay_window) {
            if s as usize >= total || k as usize >= total {
                return Err(bad(Field::RelayRows));
            }
        }
        if self.failed > MAX_FAILED {
            return Err(bad(Field::Flags));
        }
        // `ChannelList` is valid by construction.
        Ok(())
    }

    /// Writes the report into `buf`; returns the bytes written ([`Report::size`]), or
    /// [`Error::TooLarge`] if it exceeds the radio payload.
    pub fn encode(&self, buf: &mut [u8]) -> Result<usize, Error> {
        self.validate()?;
        let n = self.n();
        let c = self.channels.len();
        let mut w = start(buf, KIND_REPORT, self.size())?;
        let window = if self.has_relay {
            self.relay_window
        } else {
            None
        };
        let some_rows = window.is_some();
        w.u8(self.agent);
        w.u16(self.seq);
        w.u8(self.anchors);
        w.u8(c as u8
            | self.failed << 3
            | if self.has_relay { RELAY_FLAG } else { 0 }
            | if some_rows { ROWS_FLAG } else { 0 });
        for &ch in self.channels.as_slice() {
            w.u8(ch);
        }
        for &p in &self.positions[..n] {
            w.position(p);
        }
        for row in &self.rssi[..c] {
            for &r in &row[..n] {
                w.u8(r);
            }
        }
        if self.has_relay {
            let total = n * c;
            let (s, k) = match window {
                Some((s, k)) => {
                    w.u8(s);
                    w.u8(k);
                    (s as usize, k as usize)
                }
                None => (0, total),
            };
            for r in (s..s + k).map(|r| r % total) {
                for (j, &b) in self.relay[r / n][r % n][..n].iter().enumerate() {
                    if j != r % n {
                        w.u8(b);
                    }
                }
            }
        }
        Ok(w.end_message())
    }

    /// Reads a report that is all of `buf`.
    pub fn decode(buf: &[u8]) -> Result<Report, Error> {
        match open(buf)? {
            (KIND_REPORT, r) => Self::body(r),
            (found, _) => Err(Error::BadKind { found }),
        }
    }

    fn body(mut r: Reader<'_>) -> Result<Report, Error> {
        let agent = r.u8()?;
        let seq = r.u16()?;
        let anchors = r.u8()?;
        let cf = r.u8()?;
        // (Every bit of the byte has a meaning: only the rows flag alone is wrong.)
        if cf & (RELAY_FLAG | ROWS_FLAG) == ROWS_FLAG {
            return Err(bad(Field::Flags));
        }
        let c = (cf & 0x07) as usize;
        if !(1..=MAX_CHANNELS).contains(&c) {
            return Err(bad(Field::ChannelCount));
        }
        let mut list = [0; MAX_CHANNELS];
        for ch in &mut list[..c] {
            *ch = r.u8()?;
        }
        let mut rep = Report::new(agent, seq, anchors, ChannelList::new(&list[..c])?);
        rep.validate()?;
        rep.has_relay = cf & RELAY_FLAG != 0;
        rep.failed = (cf & FAILED_BITS) >> 3;
        let n = rep.n();
        for p in &mut rep.positions[..n] {
            *p = r.position()?;
        }
        for row in &mut rep.rssi[..c] {
            for x in &mut row[..n] {
                *x = r.u8()?;
            }
        }
        let total = n * c;
        let (s, k) = if cf & ROWS_FLAG != 0 {
            let (s, k) = (r.u8()?, r.u8()?);
            // (A window of every row is the relay matrix, which has its own form.)
            if s as usize >= total || k as usize >= total {
                return Err(bad(Field::RelayRows));
            }
            rep.relay_window = Some((s, k));
            (s as usize, k as usize)
        } else {
            (0, total)
        };
        if rep.has_relay {
            for row in (s..s + k).map(|row| row % total) {
                let (i, m) = (row % n, &mut rep.relay[row / n]);
                for (j, x) in m[i][..n].iter_mut().enumerate() {
                    if j != i {
                        *x = r.u8()?;
                    }
                }
            }
        }
        r.end()?;
        Ok(rep)
    }
}

/// What [`relay_size`] finds of a report's layout.
enum Layout {
    /// Its size, and the window of relay rows it sends (every row: 0 and C·N).
    Size(u16, (u8, u8)),
    /// A window outside the relay rows.
    BadWindow,
    /// Too short to hold its window.
    Short,
}

/// A report's layout from its N, C and flags `cf` (all checked but the window) and its `body`
/// (the message without its CRC); the size counts the CRC. In 16 bits (N ≤ 8, C ≤ 4). Always
/// inlined: a sink has one caller of it ([`ReportView::accept`]).
#[inline(always)]
fn relay_size(body: &[u8], n: u8, c: u8, cf: u8) -> Layout {
    let base = (9 + c + 4 * n + c * n) as u16;
    let total = c * n;
    let crc = CRC_LEN as u16;
    if cf & RELAY_FLAG == 0 {
        return Layout::Size(base + crc, (0, 0));
    }
    if cf & ROWS_FLAG == 0 {
        return Layout::Size(base + total as u16 * (n - 1) as u16 + crc, (0, total));
    }
    let Some(&[s, k]) = body.get(base as usize..base as usize + 2) else {
        return Layout::Short;
    };
    if s >= total || k >= total {
        return Layout::BadWindow;
    }
    Layout::Size(base + 2 + k as u16 * (n - 1) as u16 + crc, (s, k))
}

/// Whether `chans` are testbed channels (1…16), none twice: a bit each for the duplicates.
/// Out of line: [`ReportView::accept`] keeps fewer registers across a call than across the loop.
#[inline(never)]
fn distinct_channels(chans: &[u8]) -> bool {
    let mut seen = 0u16;
    for &ch in chans {
        let k = ch.wrapping_sub(1);
        if k >= MAX_CHANNEL || seen & (1 << k) != 0 {
            return false;
        }
        seen |= 1 << k;
    }
    true
}

/// Why a frame is not a report, as a receiver counts it ([`ReportView::accept`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NotReport {
    /// A hoploc message that is not a valid report (length, values).
    Corrupt,
    /// Not a hoploc message, or not a report (wrong magic, version or kind).
    Foreign,
}

impl NotReport {
    /// How [`ReportView::parse`]'s error `e` counts.
    pub fn of(e: Error) -> NotReport {
        match e {
            Error::BadMagic | Error::BadVersion { .. } | Error::BadKind { .. } => {
                NotReport::Foreign
            }
            _ => NotReport::Corrupt,
        }
    }
}

/// A report checked in place: what [`Report::decode`] accepts (the same errors, the same
/// order), its fields read from the bytes on demand. A sink needs only a few of a report's
/// bytes once each; decoding into a whole [`Report`] costs flash and stack on the AVR.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReportView<'a> {
    buf: &'a [u8],
    /// N (3…8), C (1…4).
    n: u8,
    c: u8,
    has_relay: bool,
    /// The window of relay rows sent: its first row and its length (every row: 0 and C·N).
    win: (u8, u8),
    /// The agent and the sequence, as parsed: read with no bounds checks.
    agent: u8,
    seq: u16,
}

impl<'a> ReportView<'a> {
    /// Checks that `buf` (all of it) is a report, as [`Report::decode`] does.
    #[inline(never)]
    pub fn parse(buf: &'a [u8]) -> Result<ReportView<'a>, Error> {
        let (kind, _) = open(buf)?;
        if kind != KIND_REPORT {
            return Err(Error::BadKind { found: kind });
        }
        // Byte by byte as `Report::body` reads them, up to the CRC: running out is `BadLength`.
        let body = &buf[..buf.len() - CRC_LEN];
        let &[agent, s0, s1, anchors, cf] = body.get(4..9).ok_or(Error::BadLength)? else {
            return Err(Error::BadLength);
        };
        // (Every bit of the byte has a meaning: only the rows flag alone is wrong.)
        if cf & (RELAY_FLAG | ROWS_FLAG) == ROWS_FLAG {
            return Err(bad(Field::Flags));
        }
        let c = (cf & 0x07) as usize;
        if !(1..=MAX_CHANNELS).contains(&c) {
            return Err(bad(Field::ChannelCount));
        }
        // `ChannelList::new`'s checks in its order (the count is checked), with a bit per
        // channel for the duplicates: less AVR flash than its nested loops.
        let mut seen = 0u16;
        for &ch in body.get(9..9 + c).ok_or(Error::BadLength)? {
            if !(1..=MAX_CHANNEL).contains(&ch) {
                return Err(bad(Field::Channel));
            }
            let bit = 1 << (ch - 1);
            if seen & bit != 0 {
                return Err(bad(Field::DuplicateChannel));
            }
            seen |= bit;
        }
        if agent == 0 {
            return Err(bad(Field::AgentId));
        }
        if !(3..=MAX_ANCHORS as u8).contains(&anchors) {
            return Err(bad(Field::Anchors));
        }
        let has_relay = cf & RELAY_FLAG != 0;
        // Every field left is a byte string of fixed length (the masks giving the relay
        // rows'): too few or too many bytes is all that can be wrong with them, but for a mask
        // naming an anchor the report does not have.
        let (size, win) = match relay_size(body, anchors, c as u8, cf) {
            Layout::Size(size, win) => (size, win),
            Layout::BadWindow => return Err(bad(Field::RelayRows)),
            Layout::Short => return Err(Error::BadLength),
        };
        if buf.len() != size as usize {
            return Err(Error::BadLength);
        }
        Ok(ReportView {
            buf,
            n: anchors,
            c: c as u8,
            has_relay,
            win,
            agent,
            seq: u16::from_le_bytes([s0, s1]),
        })
    }

    /// What a receiver that only counts rejects needs of [`ReportView::parse`]: the same view
    /// where it gives one, else only whether the frame is [`NotReport::Foreign`] (what `parse`
    /// calls [`Error::BadMagic`], [`Error::BadVersion`] or [`Error::BadKind`]) or
    /// [`NotReport::Corrupt`] (any other error). With no error order to keep, the checks fold
    /// into one condition: the sink firmware's parser, less AVR flash than `parse`.
    #[inline(never)]
    pub fn accept(buf: &'a [u8]) -> Result<ReportView<'a>, NotReport> {
        use NotReport::{Corrupt, Foreign};
        let &[magic, version, kind, len, ..] = buf else {
            return Err(Corrupt);
        };
        if magic != MAGIC || version != VERSION {
            return Err(Foreign);
        }
        // `open`: the length byte is checked (TooShort, BadLength), then the CRC, before the
        // kind.
        if len as usize != buf.len() || crc16(buf) != 0 {
            return Err(Corrupt);
        }
        if kind != KIND_REPORT {
            return Err(Foreign);
        }
        // (The length is at least the header's, and the CRC's by the CRC check.)
        let body = &buf[..buf.len() - CRC_LEN];
        let &[_, _, _, _, agent, s0, s1, anchors, cf, ref channels @ ..] = body else {
            return Err(Corrupt);
        };
        let c = cf & 0x07;
        // (Every bit of the byte has a meaning: only the rows flag alone is wrong.)
        if cf & (RELAY_FLAG | ROWS_FLAG) == ROWS_FLAG
            || !(1..=MAX_CHANNELS as u8).contains(&c)
            || !channels.get(..c as usize).is_some_and(distinct_channels)
            || agent == 0
            || !(3..=MAX_ANCHORS as u8).contains(&anchors)
        {
            return Err(Corrupt);
        }
        let Layout::Size(size, win) = relay_size(body, anchors, c, cf) else {
            return Err(Corrupt);
        };
        if len as u16 != size {
            return Err(Corrupt);
        }
        Ok(ReportView {
            buf,
            n: anchors,
            c,
            has_relay: cf & RELAY_FLAG != 0,
            win,
            agent,
            seq: u16::from_le_bytes([s0, s1]),
        })
    }

    fn at(&self, i: usize) -> u8 {
        self.buf.get(i).copied().unwrap_or(0)
    }

    /// The report's bytes.
    pub fn bytes(&self) -> &'a [u8] {
        self.buf
    }

    /// The reporting agent.
    pub fn agent(&self) -> u8 {
        self.agent
    }

    /// The superframe sequence number.
    pub fn seq(&self) -> u16 {
        self.seq
    }

    /// N, the number of anchors.
    pub fn anchors(&self) -> usize {
        self.n as usize
    }

    /// C, the number of channels.
    pub fn channels(&self) -> usize {
        self.c as usize
    }

    /// Whether relay rows were sent.
    pub fn has_relay(&self) -> bool {
        self.has_relay
    }

    /// The agent's failed transmissions before this report ([`Report::failed`]).
    pub fn failed(&self) -> u8 {
        (self.at(8) & FAILED_BITS) >> 3
    }

    /// Offset of anchor 0's position.
    fn positions_at(&self) -> usize {
        9 + self.channels()
    }

    /// Anchor `i + 1`'s position ([`Report::positions`]).
    pub fn position(&self, i: usize) -> Position {
        let at = self.positions_at() + 4 * i;
        match self.buf.get(at..at + 4) {
            Some(&[x0, x1, y0, y1]) => Position {
                x: i16::from_le_bytes([x0, x1]),
                y: i16::from_le_bytes([y0, y1]),
            },
            _ => Position::default(),
        }
    }

    /// The RSSI byte of anchor `i + 1`'s beacon on channel number `c` ([`Report::rssi`]).
    pub fn rssi(&self, c: usize, i: usize) -> u8 {
        let n = self.anchors();
        self.at(self.positions_at() + 4 * n + c * n + i)
    }

    /// What anchor `i + 1` relayed on channel number `c` as heard from anchor `j + 1`
    /// ([`Report::relay`]): 0 on the diagonal, for a row not sent and without relay rows.
    /// (0 too for `c`, `i` or `j` out of range.)
    pub fn relay(&self, c: usize, i: usize, j: usize) -> u8 {
        let (n, cs) = (self.n, self.c);
        if !self.has_relay || i == j || i >= n as usize || j >= n as usize || c >= cs as usize {
            return 0;
        }
        // In bytes (N ≤ 8, C ≤ 4): 8 × 8-bit products, the offset below 2^9.
        let (c, i, j) = (c as u8, i as u8, j as u8);
        // The row's place in the window: rows from its start on, wrapping around.
        let (total, (start, len)) = (cs * n, self.win);
        let mut row = c * n + i + total - start;
        if row >= total {
            row -= total;
        }
        if row >= len {
            return 0;
        }
        let base = 9 + cs + 4 * n + cs * n + if len < total { 2 } else { 0 };
        let row = row as u16 * (n - 1) as u16;
        self.at(base as usize + row as usize + (j - u8::from(j > i)) as usize)
    }
}

/// Any hoploc radio message, told apart by its kind byte.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
#[allow(clippy::large_enum_variant)] // no_std, no alloc: nothing to box into
pub enum Message {
    /// An anchor's beacon.
    Beacon(Beacon),
    /// An agent's report.
    Report(Report),
}

impl Message {
    /// Reads whichever message `buf` (all of it) holds.
    pub fn decode(buf: &[u8]) -> Result<Message, Error> {
        match open(buf)? {
            (KIND_BEACON, r) => Beacon::body(r).map(Message::Beacon),
            (KIND_REPORT, r) => Report::body(r).map(Message::Report),
            (found, _) => Err(Error::BadKind { found }),
        }
    }

    /// Writes the message into `buf`; returns the bytes written.
    pub fn encode(&self, buf: &mut [u8]) -> Result<usize, Error> {
        match self {
            Message::Beacon(b) => b.encode(buf),
            Message::Report(r) => r.encode(buf),
        }
    }
}

/// Reads whichever message `buf` (all of it) holds: [`Message::decode`].
pub fn decode_any(buf: &[u8]) -> Result<Message, Error> {
    Message::decode(buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn beacon() -> Beacon {
        Beacon {
            anchor: 2,
            seq: 0x0102,
            channel: 12,
            position: Position { x: 300, y: -5 },
            relay: Relay::from_slice(&[61, 0, 70, 0]).unwrap(),
        }
    }

    /// (The CRCs computed bit by bit apart from this crate.)
    const BEACON: [u8; 19] = [
        0xB5, 2, 1, 19, // header
        2, 0x02, 0x01, 12, // anchor, seq, channel
        0x2C, 0x01, 0xFB, 0xFF, // x 300, y -5
        4, 61, 0, 70, 0, // relay
        0x0E, 0x63, // CRC
    ];

    #[test]
    fn beacon_golden_bytes() {
        let mut buf = [0; 32];
        assert_eq!(beacon().encode(&mut buf), Ok(19));
        assert_eq!(buf[..19], BEACON);
        assert_eq!(Beacon::decode(&BEACON), Ok(beacon()));
        assert_eq!(decode_any(&BEACON), Ok(Message::Beacon(beacon())));
    }

    fn report() -> Report {
        let mut r = Report::new(7, 0xBEEF, 4, ChannelList::new(&[1, 12]).unwrap());
        r.positions[1] = Position { x: 500, y: 0 };
        r.positions[3] = Position { x: 0, y: 400 };
        r.rssi[0] = [40, 50, 0, 60, 0, 0, 0, 0];
        r.rssi[1][2] = 77;
        r.relay[0][0][1] = 55; // anchor 1 heard anchor 2 at -55 dBm on channel 1
        r.relay[1][3][2] = 66;
        r
    }

    #[rustfmt::skip]
    const REPORT: [u8; 61] = [
        0xB5, 2, 2, 61, // header
        7, 0xEF, 0xBE, 4, 0x82, 1, 12, // agent, seq, N, C | relay, channels
        0, 0, 0, 0,  0xF4, 0x01, 0, 0,  0, 0, 0, 0,  0, 0, 0x90, 0x01, // positions
        40, 50, 0, 60,  0, 0, 77, 0, // beacon RSSI per channel
        55, 0, 0,  0, 0, 0,  0, 0, 0,  0, 0, 0, // relay, channel 1 (diagonal omitted)
        0, 0, 0,  0, 0, 0,  0, 0, 0,  0, 0, 66, // relay, channel 12
        0x0D, 0x7E, // CRC
    ];

    #[test]
    fn report_golden_bytes() {
        let mut buf = [0; MAX_PAYLOAD];
        assert_eq!(report().encode(&mut buf), Ok(61));
        assert_eq!(buf[..61], REPORT);
        assert_eq!(Report::decode(&REPORT), Ok(report()));
        assert_eq!(decode_any(&REPORT), Ok(Message::Report(report())));
    }

    /// Every configuration's report fits one packet, and successive reports carry every relay
    /// row in turn: all of them within ⌈rows / rows per report⌉ superframes.
    #[test]
    fn every_configuration_fits_and_rotates_through_every_row() {
        for n in 3..=MAX_ANCHORS as u8 {
            for c in 1..=MAX_CHANNELS {
                let list = ChannelList::new(&[1, 2, 3, 4][..c]).unwrap();
                let total = n as usize * c;
                let keep = Report::relay_rows_that_fit(n as usize, c);
                assert!(keep >= 1, "{n}×{c}: no relay row fits");
                let mut seen = [false; MAX_ANCHORS * MAX_CHANNELS];
                for seq in 0..total.div_ceil(keep) as u16 {
                    let mut r = Report::new(1, seq, n, list);
                    r.fit_relay();
                    assert!(r.size() <= MAX_MESSAGE, "{n}×{c}: {} bytes", r.size());
                    assert!(r.has_relay);
                    for (row, s) in seen[..total].iter_mut().enumerate() {
                        *s |= r.sends_row(row);
                    }
                }
                assert!(seen[..total].iter().all(|&s| s), "{n}×{c}");
            }
        }
        // The documented case: 8 × 4, two rows, 95 bytes.
        let mut r = Report::new(1, 0, 8, ChannelList::new(&[1, 2, 3, 4]).unwrap());
        r.fit_relay();
        assert_eq!((Report::relay_rows_that_fit(8, 4), r.size()), (2, 95));
    }

    /// The window is checked as the rest of a report: the rows flag only with the relay flag,
    /// its start and length below the report's rows (every row is the relay matrix's own
    /// form); the view and the sink's check say the same.
    #[test]
    fn relay_windows_are_checked() {
        let mut r = Report::new(3, 9, 4, ChannelList::new(&[1, 12]).unwrap());
        r.relay_window = Some((6, 3));
        // Rows 6, 7 and 0: anchors 3 and 4 on the second channel, anchor 1 on the first.
        for (k, row) in [6, 7, 0].into_iter().enumerate() {
            let (c, i) = (row / 4, row % 4);
            for j in (0..4).filter(|&j| j != i) {
                r.relay[c][i][j] = k as u8 + 1;
            }
        }
        let mut buf = [0; 128];
        let n = r.encode(&mut buf).unwrap();
        assert_eq!(n, 9 + 2 + 16 + 8 + 2 + 3 * 3 + CRC_LEN);
        assert_eq!(Report::decode(&buf[..n]), Ok(r));
        let view = ReportView::parse(&buf[..n]).unwrap();
        assert_eq!(ReportView::accept(&buf[..n]), Ok(view));
        for k in 0..2 {
            for i in 0..4 {
                for j in 0..4 {
                    assert_eq!(view.relay(k, i, j), r.relay[k][i][j], "{k} {i} {j}");
                }
            }
        }
        assert_eq!(view.relay(0, 0, 1), 3);
        let at = 9 + 2 + 16 + 8;
        let wrong = |edit: &dyn Fn(&mut [u8]), want: Error| {
            let mut b = buf;
            edit(&mut b);
            seal(&mut b[..n]);
            assert_eq!(Report::decode(&b[..n]), Err(want));
            assert_eq!(ReportView::parse(&b[..n]), Err(want));
            assert_eq!(ReportView::accept(&b[..n]), Err(NotReport::Corrupt));
        };
        wrong(&|b| b[8] &= !RELAY_FLAG, bad(Field::Flags));
        wrong(&|b| b[at] = 8, bad(Field::RelayRows));
        wrong(&|b| b[at + 1] = 8, bad(Field::RelayRows));
    }

    /// The failed-transmission count rides in the count byte: every value round trips and the
    /// view reads it; past 7 it is refused.
    #[test]
    fn failed_transmissions_are_counted_in_the_report() {
        let mut buf = [0; MAX_PAYLOAD];
        for failed in 0..=MAX_FAILED {
            let r = Report { failed, ..report() };
            let n = r.encode(&mut buf).unwrap();
            assert_eq!(n, REPORT.len());
            assert_eq!(buf[8], 0x82 | failed << 3);
            assert_eq!(Report::decode(&buf[..n]), Ok(r));
            let view = ReportView::parse(&buf[..n]).unwrap();
            assert_eq!(view.failed(), failed);
            assert_eq!(ReportView::accept(&buf[..n]), Ok(view));
        }
        let r = Report {
            failed: MAX_FAILED + 1,
            ..report()
        };
        assert_eq!(r.encode(&mut buf), Err(bad(Field::Flags)));
    }

    #[test]
    fn documented_sizes() {
        assert_eq!(Report::wire_size(4, 2, true), 61);
        assert_eq!(Report::wire_size(4, 2, false), 37);
        assert_eq!(Report::wire_size(4, 4, true), 95);
        assert_eq!(Report::wire_size(5, 2, true), 83);
        assert_eq!(Report::wire_size(7, 1, true), 89);
        assert_eq!(Report::wire_size(8, 1, true), 108);
        assert_eq!(Report::wire_size(8, 4, false), 79);
        assert!(Report::wire_size(5, 3, true) > MAX_MESSAGE);
        assert!(Report::wire_size(6, 2, true) > MAX_MESSAGE);
        assert_eq!(Beacon::MAX_LEN, 23);
    }

    #[test]
    fn too_large_and_small_buffers() {
        let mut r = Report::new(1, 0, 8, ChannelList::new(&[1]).unwrap());
        let mut buf = [0; 128];
        assert_eq!(r.encode(&mut buf), Err(Error::TooLarge { size: 108 }));
        r.has_relay = false;
        assert_eq!(r.encode(&mut buf), Ok(52));
        assert_eq!(
            r.encode(&mut buf[..51]),
            Err(Error::BufferTooSmall { need: 52 })
        );
        assert_eq!(
            beacon().encode(&mut buf[..3]),
            Err(Error::BufferTooSmall { need: 19 })
        );
        // 95 bytes is the most, whatever the radio's own limit.
        let mut r = Report::new(1, 0, 4, ChannelList::new(&[1, 2, 3, 4]).unwrap());
        assert_eq!(r.encode(&mut buf), Ok(MAX_MESSAGE));
        r.anchors = 5;
        assert_eq!(r.encode(&mut buf), Err(Error::TooLarge { size: 135 }));
    }

    #[test]
    fn header_errors() {
        assert_eq!(decode_any(&[]), Err(Error::TooShort));
        assert_eq!(decode_any(&BEACON[..3]), Err(Error::TooShort));
        assert_eq!(decode_any(&BEACON[..18]), Err(Error::TooShort));
        let mut b = BEACON;
        b[0] = 0x7E;
        assert_eq!(decode_any(&b), Err(Error::BadMagic));
        let mut b = BEACON;
        b[1] = 1;
        assert_eq!(decode_any(&b), Err(Error::BadVersion { found: 1 }));
        // A field changed without its CRC: a bad CRC, whatever the field.
        let mut b = BEACON;
        b[2] = 9;
        assert_eq!(decode_any(&b), Err(Error::BadCrc));
        seal(&mut b);
        assert_eq!(decode_any(&b), Err(Error::BadKind { found: 9 }));
        assert_eq!(Report::decode(&BEACON), Err(Error::BadKind { found: 1 }));
        let mut long = [0; 20];
        long[..19].copy_from_slice(&BEACON);
        assert_eq!(decode_any(&long), Err(Error::BadLength));
        long[3] = 20; // says 20, but the fields and the CRC are 19
        seal(&mut long);
        assert_eq!(decode_any(&long), Err(Error::BadLength));
        // Too short for a CRC after the header.
        for len in 0..HEADER_LEN + CRC_LEN {
            let mut m = [MAGIC, VERSION, KIND_BEACON, len as u8, 0, 0];
            seal(&mut m[..len]);
            assert!(decode_any(&m[..len]).is_err());
        }
        // Every single-bit error and every byte changed is a bad CRC.
        for at in 0..BEACON.len() {
            for bit in 0..8 {
                let mut b = BEACON;
                b[at] ^= 1 << bit;
                assert!(decode_any(&b).is_err(), "{at} {bit}");
            }
            for v in 0..=255u8 {
                let mut b = BEACON;
                b[at] = v;
                if v != BEACON[at] && (4..BEACON.len()).contains(&at) {
                    assert_eq!(decode_any(&b), Err(Error::BadCrc), "{at} {v}");
                }
            }
        }
    }

    #[test]
    fn field_errors() {
        let field = |f| Err(Error::BadValue { field: f });
        // Each edit with its CRC made to match.
        let decode_any = |m: &[u8]| {
            let mut m = m.to_vec();
            seal(&mut m);
            decode_any(&m)
        };
        let mut b = BEACON;
        b[4] = 9;
        assert_eq!(decode_any(&b), field(Field::AnchorId));
        let mut b = BEACON;
        b[7] = 17;
        assert_eq!(decode_any(&b), field(Field::Channel));
        let mut b = BEACON;
        b[14] = 1; // anchor 2's own entry
        assert_eq!(decode_any(&b), field(Field::SelfRssi));
        let mut b = BEACON;
        b[12] = 9;
        assert_eq!(decode_any(&b), field(Field::RelayCount));
        let mut r = REPORT;
        r[4] = 0;
        assert_eq!(decode_any(&r), field(Field::AgentId));
        let mut r = REPORT;
        r[7] = 2;
        assert_eq!(decode_any(&r), field(Field::Anchors));
        let mut r = REPORT;
        r[8] = 0x80;
        assert_eq!(decode_any(&r), field(Field::ChannelCount));
        let mut r = REPORT;
        r[8] = 0x42;
        assert_eq!(decode_any(&r), field(Field::Flags));
        let mut r = REPORT;
        r[10] = 1;
        assert_eq!(decode_any(&r), field(Field::DuplicateChannel));
        let mut r = REPORT;
        r[8] = 0x02; // no relay flag: 24 bytes too many
        assert_eq!(decode_any(&r), Err(Error::BadLength));
    }

    #[test]
    fn channel_lists() {
        assert_eq!(ChannelList::new(&[1, 12]).unwrap().as_slice(), &[1, 12]);
        let field = |f| Err(Error::BadValue { field: f });
        assert_eq!(ChannelList::new(&[]), field(Field::ChannelCount));
        assert_eq!(
            ChannelList::new(&[1, 2, 3, 4, 5]),
            field(Field::ChannelCount)
        );
        assert_eq!(ChannelList::new(&[0]), field(Field::Channel));
        assert_eq!(ChannelList::new(&[17]), field(Field::Channel));
        assert_eq!(ChannelList::new(&[5, 1, 5]), field(Field::DuplicateChannel));
    }

    /// `accept` is `parse` with its error counted by `NotReport::of`.
    fn accept_is_parse(v: &[u8]) {
        assert_eq!(
            ReportView::accept(v),
            ReportView::parse(v).map_err(NotReport::of),
            "{v:02x?}"
        );
    }

    /// [`accept_is_parse`] on `v` as it is and with its CRC made to match.
    fn accept_is_parse_sealed(v: &[u8]) {
        accept_is_parse(v);
        let mut v = v.to_vec();
        seal(&mut v);
        accept_is_parse(&v);
    }

    /// Every byte of the golden report at every value (with the length byte as it is and
    /// made to match), every pair of the header and count bytes, every cut and extension;
    /// each with its CRC as it is and made to match.
    #[test]
    fn accept_counts_what_parse_rejects() {
        accept_is_parse(&REPORT);
        assert!(ReportView::accept(&REPORT).is_ok());
        for at in 0..REPORT.len() {
            for b in 0..=255u8 {
                let mut r = REPORT;
                r[at] = b;
                accept_is_parse_sealed(&r);
            }
        }
        for a in 0..9 {
            for b in a + 1..11 {
                for (x, y) in (0..=255u8).flat_map(|x| (0..=255u8).map(move |y| (x, y))) {
                    let mut r = REPORT;
                    r[a] = x;
                    r[b] = y;
                    seal(&mut r);
                    accept_is_parse(&r);
                }
            }
        }
        let mut long = [0u8; 300];
        long[..REPORT.len()].copy_from_slice(&REPORT);
        for n in 0..long.len() {
            accept_is_parse_sealed(&long[..n]);
            let mut v = long;
            v[3] = n as u8;
            accept_is_parse_sealed(&v[..n]);
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(3000))]

        /// Random reports of every size (relay or not), their bytes then edited, cut or
        /// lengthened, the length byte often made to match.
        #[test]
        fn accept_counts_as_parse(
            n in 0u8..=9,
            chans in proptest::collection::vec(0u8..=17, 0..=5),
            cf in proptest::prelude::any::<u8>(),
            agent in 0u8..3,
            body in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..300),
            edits in proptest::collection::vec((0usize..120, proptest::prelude::any::<u8>()), 0..3),
            honest in proptest::prelude::any::<bool>(),
            clean_flags in proptest::prelude::any::<bool>(),
            sealed in proptest::prelude::any::<bool>(),
        ) {
            let cf = if clean_flags { cf & (RELAY_FLAG | 0x07) } else { cf };
            let c = (cf & 0x07) as usize;
            let size = (9 + chans.len() + 4 * n as usize
                + c * if cf & RELAY_FLAG != 0 { n as usize * n as usize } else { n as usize }
                + CRC_LEN)
                .min(body.len());
            let mut v = body[..size].to_vec();
            let head = [MAGIC, VERSION, KIND_REPORT, size as u8, agent, 1, 2, n, cf];
            for (x, &h) in v.iter_mut().zip(head.iter().chain(&chans)) {
                *x = h;
            }
            for &(at, b) in &edits {
                if let Some(x) = v.get_mut(at) {
                    *x = b;
                }
            }
            if honest && v.len() > 3 {
                v[3] = v.len() as u8;
            }
            if sealed {
                seal(&mut v);
            }
            accept_is_parse(&v);
        }
    }

    /// The proptest above reaches reports `accept` takes, not only rejects.
    #[test]
    fn accept_takes_reports_of_every_shape() {
        for (n, c, relay) in [(3, 1, true), (4, 4, true), (8, 4, false), (8, 3, true)] {
            let mut r = Report::new(9, 7, n, ChannelList::new(&[16, 3, 1, 9][..c]).unwrap());
            r.has_relay = relay;
            let mut buf = [0; 256];
            let len = r.size();
            assert_eq!(r.encode(&mut buf).is_ok(), len <= MAX_MESSAGE);
            if len > MAX_MESSAGE {
                // The decoder takes it all the same (8 × 3 with relay: 238 bytes).
                buf[..8].copy_from_slice(&[MAGIC, VERSION, KIND_REPORT, len as u8, 9, 7, 0, n]);
                buf[8] = c as u8 | RELAY_FLAG;
                buf[9..9 + c].copy_from_slice(&[16, 3, 1, 9][..c]);
                seal(&mut buf[..len]);
            }
            accept_is_parse(&buf[..len]);
            let v = ReportView::accept(&buf[..len]).unwrap();
            assert_eq!(
                (v.anchors(), v.channels(), v.has_relay()),
                (n as usize, c, relay)
            );
        }
    }
}
