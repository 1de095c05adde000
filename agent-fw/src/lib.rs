//! The agent's logic, sans-IO (`docs/design.md`, section 4): follow the anchors' timeline, collect
//! every beacon's RSSI, position and relay per anchor and channel, and send one report per
//! superframe in its own report sub-slot on the sink channel.
//!
//! [`Agent`] is fed the node's microsecond clock ([`Agent::poll`]), the beacons its radio
//! receives ([`Agent::on_beacon`]) and the radio's TX status ([`Agent::on_tx_status`]), and
//! answers with [`Action`]s. `main.rs` only wires it to `uno-board` and the radio driver.
//!
//! * **Sync.** It listens on the first channel until it hears an anchor, then follows the
//!   testbed's [`Timeline`]: re-aligned by every beacon of the time master. It never transmits
//!   before that.
//! * **Superframe.** At each channel phase start it tunes to the phase's channel. At the start of
//!   its report sub-slot (agent `a` has sub-slot `a`) it tunes to the sink channel, and at the
//!   end of the sub-slot's guard it sends the report of the superframe's beacons
//!   ([`Agent::report`]); the TX status (or the next phase) tunes it back.
//! * **Not heard** is RSSI 0 (and position 0, 0 for an anchor not heard at all): a report says
//!   what was missed, it never repeats an old value. The report is loc-proto's
//!   [`Report`], with the relay matrix.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

use loc_proto::msg::{ChannelList, Position, Report, MAX_FAILED};
use loc_proto::schedule::{Schedule, Timeline};

pub use loc_proto::msg::{MAX_ANCHORS, MAX_CHANNELS};

/// Where the radio should listen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Tune {
    /// The channel at this index of the channel list.
    List(u8),
    /// The sink channel.
    Sink,
}

/// What the agent asks its shell to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Action {
    /// Switch the radio's channel.
    Tune(Tune),
    /// Send [`Agent::report`] (superframe `seq`, a [`Report`]) to the sink, then report the TX
    /// status.
    SendReport {
        /// Superframe sequence.
        seq: u16,
    },
}

/// A beacon the radio received, decoded by the shell.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Heard<'a> {
    /// The sender's anchor id.
    pub from: u8,
    /// Its superframe sequence.
    pub seq: u16,
    /// The channel index it was sent on.
    pub channel: u8,
    /// Received signal strength, −dBm (never 0).
    pub rssi: u8,
    /// The local clock when the shell received it, µs.
    pub at_us: u32,
    /// The sender's position, cm.
    pub pos: [i16; 2],
    /// The RSSI the sender heard from anchors 1…N on this channel (0: not heard).
    pub relay: &'a [u8],
}

/// The agent state machine.
#[derive(Clone, Debug)]
pub struct Agent {
    id: u8,
    tl: Timeline,
    synced: bool,
    tuned: bool,
    /// Next event: `c < C` tune to channel `c`, `C` tune to the sink, `C + 1` send the report.
    next_ev: u8,
    /// A report is out, waiting for its TX status.
    awaiting: bool,
    /// Reports whose TX status said failed since the last that went out (saturating at
    /// [`MAX_FAILED`]): carried by the next report ([`Report::failed`]).
    failed: u8,
    /// What this superframe's beacons said so far: the next report. (There is no copy of the
    /// report being sent: the shell encodes it when asked, and a second `Report` would not fit
    /// the Uno's SRAM budget next to the radio driver.)
    cur: Report,
}

impl Agent {
    /// Agent `id` (1…M of `sched`'s report sub-slots) of a testbed hopping over `channels`
    /// (`sched`'s channels), booting at local time `now_us`; beacons arrive `latency_us` after
    /// their transmit time.
    pub fn new(
        id: u8,
        sched: Schedule,
        channels: ChannelList,
        latency_us: u32,
        now_us: u32,
    ) -> Agent {
        Agent {
            id,
            tl: Timeline::new(sched, latency_us, 0, now_us),
            synced: false,
            tuned: false,
            next_ev: 0,
            awaiting: false,
            failed: 0,
            cur: Report::new(id, 0, sched.anchors(), channels),
        }
    }

    /// Whether it follows the testbed's timeline yet.
    pub fn synced(&self) -> bool {
        self.synced
    }

    /// The report to send on [`Action::SendReport`]: what the superframe's beacons said (read it
    /// before the next [`Agent::poll`] or beacon; it is the same as [`Agent::collecting`]).
    pub fn report(&self) -> &Report {
        &self.cur
    }

    /// What has been collected so far in this superframe.
    pub fn collecting(&self) -> &Report {
        &self.cur
    }

    /// Time of event `k`, µs into the superframe.
    fn event_time(&self, k: u8) -> Option<u32> {
        let s = self.tl.schedule();
        let c = s.channels();
        let report = s.report_at_us(self.id);
        if k < c {
            s.channel_start_us(k)
        } else if k == c {
            // Every agent switches to the sink channel where the report window begins, in the
            // time the window leaves for that.
            report.map(|_| s.report_start_us())
        } else if k == c + 1 {
            report
        } else {
            None
        }
    }

    fn new_superframe(&mut self) {
        self.next_ev = 0;
        self.cur = Report::new(
            self.cur.agent,
            self.tl.seq(),
            self.cur.anchors,
            self.cur.channels,
        );
    }

    /// Failed transmissions since the last report that went out.
    pub fn failed(&self) -> u8 {
        self.failed
    }

    /// What to do at local time `now_us`: call it often (at least once per guard time) and
    /// until it returns `None`.
    pub fn poll(&mut self, now_us: u32) -> Option<Action> {
        if !self.synced {
            if !self.tuned {
                self.tuned = true;
                return Some(Action::Tune(Tune::List(0)));
            }
            return None;
        }
        let s = *self.tl.schedule();
        loop {
            let t = self.tl.elapsed_us(now_us);
            if t >= s.superframe_us() {
                self.tl.roll();
                self.new_superframe();
                continue;
            }
            let time = self.event_time(self.next_ev)?;
            if time > t {
                return None;
            }
            let k = self.next_ev;
            self.next_ev += 1;
            if k < s.channels() {
                return Some(Action::Tune(Tune::List(k)));
            }
            if k == s.channels() {
                return Some(Action::Tune(Tune::Sink));
            }
            // The report: only less than a guard time late (never into the next sub-slot).
            if t - time < s.guard_us().max(1) {
                self.awaiting = true;
                // One packet whatever the testbed's size: as many relay rows as fit, others in
                // the next superframes.
                self.cur.fit_relay();
                self.cur.failed = self.failed;
                return Some(Action::SendReport { seq: self.cur.seq });
            }
        }
    }

    /// How long the shell may wait from local time `now_us` before [`Agent::poll`] has something
    /// to do, µs (0: poll now; `u32::MAX` while it waits for a first beacon).
    pub fn wait_us(&self, now_us: u32) -> u32 {
        if !self.synced {
            return if self.tuned { u32::MAX } else { 0 };
        }
        self.tl.until_us(now_us, self.event_time(self.next_ev))
    }

    /// The radio reported the report's transmission (`ok` or not: the channel busy, or no
    /// acknowledgement from the sink's radio), counted for the next report: back to the channel
    /// list.
    pub fn on_tx_status(&mut self, ok: bool) -> Option<Action> {
        if !self.awaiting {
            return None;
        }
        self.awaiting = false;
        self.failed = if ok {
            0
        } else {
            (self.failed + 1).min(MAX_FAILED)
        };
        Some(Action::Tune(Tune::List(0)))
    }

    /// A beacon was received.
    pub fn on_beacon(&mut self, b: Heard) {
        if !self.tl.plausible(b.from, b.channel) {
            return;
        }
        self.tl.heard(b.from);
        if !self.synced || b.from == self.tl.master() {
            let changed = self.tl.align(b.from, b.seq, b.channel, b.at_us);
            let t = self.tl.elapsed_us(b.at_us);
            if !self.synced || changed {
                self.new_superframe();
            }
            self.synced = true;
            // Events up to now are past.
            self.next_ev = 0;
            while self.event_time(self.next_ev).is_some_and(|e| e <= t) {
                self.next_ev += 1;
            }
        }
        let (c, a) = (b.channel as usize, b.from as usize - 1);
        self.cur.rssi[c][a] = b.rssi;
        self.cur.positions[a] = Position {
            x: b.pos[0],
            y: b.pos[1],
        };
        let row = &mut self.cur.relay[c][a];
        for (slot, &v) in row.iter_mut().zip(b.relay) {
            *slot = v;
        }
        // What an anchor says of itself is not a measurement (and is not sent).
        row[a] = 0;
    }
}

#[cfg(test)]
mod tests;
