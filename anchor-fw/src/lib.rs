//! The anchor's logic, sans-IO (`docs/design.md`, section 4): TDMA slots, channel hopping, sync on
//! the time master with latency correction, takeover and hand-back, and the anchor-to-anchor RSSI
//! relay.
//!
//! [`Anchor`] is fed the node's microsecond clock ([`Anchor::poll`]) and the beacons its radio
//! receives ([`Anchor::on_beacon`]), and answers with [`Action`]s: switch channel, send a beacon.
//! `main.rs` only wires it to `uno-board` and the radio driver; every rule below is tested on the
//! host.
//!
//! * **Boot.** An anchor first listens on the first channel (its first action) for `1 + id`
//!   superframes (staggered, so that anchors switched on together do not all start their own
//!   timelines). If it hears an anchor, it takes that anchor's timeline; if not, it starts its
//!   own.
//! * **Timeline.** Superframe `seq` starts at `sf_start`; at each channel phase start the anchor
//!   switches channel, and in its own slot (after the guard) it beacons, unless it is already
//!   later than the guard into its slot (it then skips: it never transmits outside its slot).
//! * **Master.** The time master is the lowest id heard in the last [`SILENT_SUPERFRAMES`]
//!   superframes, or the anchor itself if that is lower: normally anchor 1. Every beacon of the
//!   master re-aligns the timeline (its transmit time in the master's schedule, less the radio
//!   latency) and the sequence. When the master falls silent, the next lowest takes over and
//!   simply keeps the timeline running; when a lower anchor returns, it has listened first and
//!   adopted that same timeline, so the hand-back moves no slot.
//! * **Relay.** The RSSI of every anchor heard on every channel in a superframe is carried, for
//!   that channel, by this anchor's beacons of the next superframe ([`Anchor::relay`]).
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

use loc_proto::msg::{Beacon, ChannelList, Position, Relay};
pub use loc_proto::schedule::SILENT_SUPERFRAMES;
use loc_proto::schedule::{Schedule, Timeline};

pub use loc_proto::msg::{MAX_ANCHORS, MAX_CHANNELS};
/// What the anchor asks its shell to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Action {
    /// Switch the radio to the channel at this index of the channel list.
    SetChannel(u8),
    /// Broadcast a beacon: this anchor, superframe `seq`, on the channel at index `channel`,
    /// relaying [`Anchor::relay`]`(channel)`.
    SendBeacon {
        /// Superframe sequence.
        seq: u16,
        /// Index into the channel list.
        channel: u8,
    },
}

/// A beacon the radio received, decoded by the shell.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Heard {
    /// The sender's anchor id.
    pub from: u8,
    /// Its superframe sequence.
    pub seq: u16,
    /// The channel index it says it was sent on.
    pub channel: u8,
    /// Received signal strength, −dBm (the RX16 frame's byte; never 0).
    pub rssi: u8,
    /// The local clock when the shell received it, µs.
    pub at_us: u32,
}

/// Where the anchor is in its life.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Listening before it may transmit; until the clock reaches `until_us`.
    Listening {
        /// End of the listening time (local clock, µs).
        until_us: u32,
    },
    /// Running a timeline.
    Running,
}

/// The anchor state machine.
#[derive(Clone, Debug)]
pub struct Anchor {
    id: u8,
    tl: Timeline,
    mode: Mode,
    /// The listening channel has been asked for.
    tuned: bool,
    /// Next event of the superframe: `2·c` switch to channel `c`, `2·c + 1` beacon on it.
    next_ev: u8,
    /// Channels beaconed on in this superframe (bit per channel index).
    sent: u8,
    cur: [[u8; MAX_ANCHORS]; MAX_CHANNELS],
    prev: [[u8; MAX_ANCHORS]; MAX_CHANNELS],
}

impl Anchor {
    /// Anchor `id` (1…N of `sched`), booting at local time `now_us`; beacons arrive
    /// `latency_us` after their transmit time.
    pub fn new(id: u8, sched: Schedule, latency_us: u32, now_us: u32) -> Anchor {
        let listen = sched.superframe_us().saturating_mul(1 + id as u32);
        Anchor {
            id,
            tl: Timeline::new(sched, latency_us, id, now_us),
            mode: Mode::Listening {
                until_us: now_us.wrapping_add(listen),
            },
            tuned: false,
            next_ev: 0,
            sent: 0,
            cur: [[0; MAX_ANCHORS]; MAX_CHANNELS],
            prev: [[0; MAX_ANCHORS]; MAX_CHANNELS],
        }
    }

    /// The anchor's id.
    pub fn id(&self) -> u8 {
        self.id
    }

    /// Its mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// The current superframe sequence.
    pub fn seq(&self) -> u16 {
        self.tl.seq()
    }

    /// The time master ([`Timeline::master`]).
    pub fn master(&self) -> u8 {
        self.tl.master()
    }

    /// The RSSI bytes (−dBm, 0: not heard) this anchor measured from anchors 1…N on the channel
    /// at index `channel` in the previous superframe: what its beacons carry.
    pub fn relay(&self, channel: u8) -> &[u8] {
        let n = (self.tl.schedule().anchors() as usize).min(MAX_ANCHORS);
        match self.prev.get(channel as usize) {
            Some(row) if channel < self.tl.schedule().channels() => &row[..n],
            _ => &[],
        }
    }

    /// The beacon for [`Action::SendBeacon`] `{ seq, channel }`: this anchor at `position`, on
    /// the testbed channel `channels[channel]`, relaying [`Anchor::relay`]`(channel)`.
    pub fn beacon(
        &self,
        seq: u16,
        channel: u8,
        channels: &ChannelList,
        position: Position,
    ) -> Beacon {
        Beacon {
            anchor: self.id,
            seq,
            channel: channels
                .as_slice()
                .get(channel as usize)
                .copied()
                .unwrap_or(0),
            position,
            // (`relay` is at most MAX_ANCHORS bytes: it always fits.)
            relay: Relay::from_slice(self.relay(channel)).unwrap_or_default(),
        }
    }

    /// Time of event `k` of the superframe, µs from its start.
    fn event_time(&self, k: u8) -> Option<u32> {
        let (c, s) = (k / 2, self.tl.schedule());
        if k & 1 == 0 {
            s.channel_start_us(c)
        } else {
            s.beacon_at_us(c, self.id)
        }
    }

    /// Closes the superframe: relays and the timeline roll.
    fn end_superframe(&mut self) {
        self.tl.roll();
        self.next_ev = 0;
        self.sent = 0;
        self.prev = self.cur;
        self.cur = [[0; MAX_ANCHORS]; MAX_CHANNELS];
    }

    /// What to do at local time `now_us`: call it often (at least once per guard time) and
    /// until it returns `None`.
    pub fn poll(&mut self, now_us: u32) -> Option<Action> {
        if let Mode::Listening { until_us } = self.mode {
            if !self.tuned {
                self.tuned = true;
                return Some(Action::SetChannel(0));
            }
            if (now_us.wrapping_sub(until_us) as i32) < 0 {
                return None;
            }
            // Nobody heard: our own timeline, from now.
            self.mode = Mode::Running;
            self.tl.restart(now_us, 0);
            self.next_ev = 0;
            self.sent = 0;
        }
        let sf = self.tl.schedule().superframe_us();
        loop {
            let t = self.tl.elapsed_us(now_us);
            if t >= sf {
                self.end_superframe();
                continue;
            }
            let time = self.event_time(self.next_ev)?;
            if time > t {
                return None;
            }
            let k = self.next_ev;
            self.next_ev += 1;
            let c = k / 2;
            if k & 1 == 0 {
                return Some(Action::SetChannel(c));
            }
            // Our slot: once, and only less than a guard time late.
            if self.sent & (1 << c) == 0 && t - time < self.tl.schedule().guard_us().max(1) {
                self.sent |= 1 << c;
                return Some(Action::SendBeacon {
                    seq: self.tl.seq(),
                    channel: c,
                });
            }
        }
    }

    /// How long the shell may wait from local time `now_us` before [`Anchor::poll`] has
    /// something to do, µs (0: poll now). Beacons arriving meanwhile change nothing that is due
    /// earlier, so a shell can sleep this long unless the radio wakes it.
    pub fn wait_us(&self, now_us: u32) -> u32 {
        match self.mode {
            Mode::Listening { .. } if !self.tuned => 0,
            Mode::Listening { until_us } => (until_us.wrapping_sub(now_us) as i32).max(0) as u32,
            Mode::Running => self.tl.until_us(now_us, self.event_time(self.next_ev)),
        }
    }

    /// A beacon was received.
    pub fn on_beacon(&mut self, b: Heard) {
        if !self.tl.plausible(b.from, b.channel) {
            return;
        }
        self.tl.heard(b.from);
        if let Mode::Listening { .. } = self.mode {
            self.align(b);
            self.mode = Mode::Running;
        } else if b.from == self.tl.master() {
            self.align(b);
        }
        self.cur[b.channel as usize][b.from as usize - 1] = b.rssi;
    }

    /// Takes `b`'s sender's timeline ([`Timeline::align`]).
    fn align(&mut self, b: Heard) {
        if self.tl.align(b.from, b.seq, b.channel, b.at_us) {
            // A different superframe (first sync, or after a gap): its events from scratch.
            self.prev = self.cur;
            self.cur = [[0; MAX_ANCHORS]; MAX_CHANNELS];
            self.sent = 0;
        }
        // Events up to now are past (beacons already sent stay marked in `sent`).
        let t = self.tl.elapsed_us(b.at_us);
        self.next_ev = 0;
        while self.event_time(self.next_ev).is_some_and(|e| e <= t) {
            self.next_ev += 1;
        }
    }
}

#[cfg(test)]
mod tests;
