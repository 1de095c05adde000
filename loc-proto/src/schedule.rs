//! The TDMA superframe: when each anchor beacons, on which channel, and when each agent
//! reports — the timing every node derives from the same config, defined once.
//!
//! A superframe is, for each channel of the channel list in order, a *channel phase* of `N`
//! slots (slot `k` belongs to anchor `k + 1`), then the *report window*: one sub-slot per agent
//! (agent `a` has sub-slot `a − 1`) on the sink channel. Each channel phase and the report window
//! begin with the time a channel change takes at worst ([`TUNE_US`]): every node switches its
//! radio there and waits for its answer. Every slot starts with a guard time in which nobody
//! transmits; a node transmits at the end of the guard.
//!
//! ```text
//! | ch 1: T A1 A2 … AN | ch 2: T A1 A2 … AN | … | report: T ag1 ag2 … agM |
//!   T: channel change; each slot: [guard | transmit window ...]
//! ```
//!
//! Times are microseconds from the start of the superframe (`u32`): the thesis' 250 ms channel
//! phases with 4 anchors are 62.5 ms slots, which whole milliseconds cannot express.

/// A superframe layout. Build it with [`Schedule::new`], which checks it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Schedule {
    anchors: u8,
    channels: u8,
    agents: u8,
    slot_us: u32,
    report_slot_us: u32,
    guard_us: u32,
    tune_us: u32,
    // Derived in `new` (every node asks for them all the time; on the AVR each would otherwise
    // be a 32-bit multiplication inlined at every use).
    phase_us: u32,
    report_start_us: u32,
    superframe_us: u32,
}

/// Why a layout was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ScheduleError {
    /// Anchors outside 1…8.
    Anchors(u8),
    /// Channels outside 1…4.
    Channels(u8),
    /// Agents outside 0…16.
    Agents(u8),
    /// A slot not longer than the guard time (nothing could be sent), or shorter than 1 ms.
    SlotTooShort,
    /// A slot, report sub-slot or channel change over 67 s (the superframe must fit `u32`
    /// microseconds).
    TooLong,
}

/// Where in the superframe a time falls.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Phase {
    /// Channel phase `channel` (index into the channel list), anchor `anchor`'s slot (1-based).
    Beacon {
        /// Index into the channel list.
        channel: u8,
        /// The anchor owning the slot, 1…N.
        anchor: u8,
        /// Within the slot's guard time: nobody transmits.
        guard: bool,
    },
    /// The report window, agent `agent`'s sub-slot (1-based).
    Report {
        /// The agent owning the sub-slot, 1…M.
        agent: u8,
        /// Within the sub-slot's guard time.
        guard: bool,
    },
}

impl Schedule {
    /// `anchors` (1…8) beacon slots per channel phase for `channels` (1…4) channels, slots of
    /// `slot_us`; then `agents` (0…16) report sub-slots of `report_slot_us`; each slot begins
    /// with `guard_us` of silence.
    pub const fn new(
        anchors: u8,
        channels: u8,
        slot_us: u32,
        agents: u8,
        report_slot_us: u32,
        guard_us: u32,
    ) -> Result<Schedule, ScheduleError> {
        if anchors < 1 || anchors > 8 {
            return Err(ScheduleError::Anchors(anchors));
        }
        if channels < 1 || channels > 4 {
            return Err(ScheduleError::Channels(channels));
        }
        if agents > 16 {
            return Err(ScheduleError::Agents(agents));
        }
        if slot_us <= guard_us || slot_us < 1000 || (agents > 0 && report_slot_us <= guard_us) {
            return Err(ScheduleError::SlotTooShort);
        }
        Schedule {
            anchors,
            channels,
            agents,
            slot_us,
            report_slot_us,
            guard_us,
            tune_us: 0,
            phase_us: 0,
            report_start_us: 0,
            superframe_us: 0,
        }
        .with_tune(0)
    }

    /// The same layout with `tune_us` for the channel change at the start of every channel
    /// phase and of the report window: the first slot of each is that much longer, and its
    /// guard ends that much later.
    pub const fn with_tune(self, tune_us: u32) -> Result<Schedule, ScheduleError> {
        // At most 32 slots, 16 sub-slots and 5 channel changes: with each part at most
        // 1/64 of `u32::MAX` (67 s) the superframe fits, and no 64-bit arithmetic is needed.
        const PART_MAX: u32 = u32::MAX / 64;
        if self.slot_us > PART_MAX || self.report_slot_us > PART_MAX || tune_us > PART_MAX {
            return Err(ScheduleError::TooLong);
        }
        let phase_us = tune_us + self.anchors as u32 * self.slot_us;
        let report_start_us = self.channels as u32 * phase_us;
        let report_us = if self.agents > 0 {
            tune_us + self.agents as u32 * self.report_slot_us
        } else {
            0
        };
        Ok(Schedule {
            tune_us,
            phase_us,
            report_start_us,
            superframe_us: report_start_us + report_us,
            ..self
        })
    }

    /// Anchors per channel phase.
    pub const fn anchors(&self) -> u8 {
        self.anchors
    }

    /// Channels in the list.
    pub const fn channels(&self) -> u8 {
        self.channels
    }

    /// Report sub-slots.
    pub const fn agents(&self) -> u8 {
        self.agents
    }

    /// A beacon slot, µs.
    pub const fn slot_us(&self) -> u32 {
        self.slot_us
    }

    /// The guard time at the start of every slot, µs.
    pub const fn guard_us(&self) -> u32 {
        self.guard_us
    }

    /// The time for a channel change at the start of every channel phase and of the report
    /// window, µs ([`Schedule::with_tune`]).
    pub const fn tune_us(&self) -> u32 {
        self.tune_us
    }

    /// One channel phase, µs.
    pub const fn channel_phase_us(&self) -> u32 {
        self.phase_us
    }

    /// Start of the report window, µs.
    pub const fn report_start_us(&self) -> u32 {
        self.report_start_us
    }

    /// The whole superframe, µs.
    pub const fn superframe_us(&self) -> u32 {
        self.superframe_us
    }

    /// When anchor `anchor` (1…N) transmits in channel phase `channel` (index): the end of its
    /// slot's guard, µs. `None` for an anchor or channel outside the layout.
    pub const fn beacon_at_us(&self, channel: u8, anchor: u8) -> Option<u32> {
        if channel >= self.channels || anchor < 1 || anchor > self.anchors {
            return None;
        }
        Some(
            channel as u32 * self.phase_us
                + self.tune_us
                + (anchor - 1) as u32 * self.slot_us
                + self.guard_us,
        )
    }

    /// When agent `agent` (1…M) sends its report: the end of its sub-slot's guard, µs.
    pub const fn report_at_us(&self, agent: u8) -> Option<u32> {
        if agent < 1 || agent > self.agents {
            return None;
        }
        Some(
            self.report_start_us
                + self.tune_us
                + (agent - 1) as u32 * self.report_slot_us
                + self.guard_us,
        )
    }

    /// Start of channel phase `channel` (index), µs: when every node switches to it.
    pub const fn channel_start_us(&self, channel: u8) -> Option<u32> {
        if channel >= self.channels {
            return None;
        }
        Some(channel as u32 * self.channel_phase_us())
    }

    /// The phase at `t_us` into the superframe (taken modulo the superframe). The time for the
    /// channel change at the start of a channel phase or of the report window belongs to the
    /// first slot's guard.
    pub const fn phase_at(&self, t_us: u32) -> Phase {
        let t = t_us % self.superframe_us();
        let report = self.report_start_us();
        if t < report {
            let channel = t / self.phase_us;
            let (k, guard) = slot_in(
                t - channel * self.phase_us,
                self.tune_us,
                self.slot_us,
                self.guard_us,
            );
            Phase::Beacon {
                channel: channel as u8,
                anchor: k as u8 + 1,
                guard,
            }
        } else {
            let (k, guard) = slot_in(t - report, self.tune_us, self.report_slot_us, self.guard_us);
            Phase::Report {
                agent: k as u8 + 1,
                guard,
            }
        }
    }
}

/// Which slot (0-based) `into` µs into a run of slots of `slot_us` falls in, after `tune_us` for
/// a channel change that the first slot's guard takes in, and whether it is within a guard.
const fn slot_in(into: u32, tune_us: u32, slot_us: u32, guard_us: u32) -> (u32, bool) {
    if into < tune_us + slot_us {
        return (0, into < tune_us + guard_us);
    }
    let after = into - tune_us;
    let k = after / slot_us;
    (k, after - k * slot_us < guard_us)
}

/// Bytes of an `AT CH` frame and of its answer on the UART, at most: 9 each, up to three of
/// them escaped in API mode 2 (frame id, value or status, checksum).
pub const AT_CH_FRAME_MAX_BYTES: u32 = 12;
/// A channel change as the nodes make it, at worst, µs: the `AT CH` frame over the UART, the
/// radio's switch ([`xbee_api::CHANNEL_SWITCH_US`]: its answer comes once the new channel is in
/// effect) and the answer over the UART, every byte counted at [`SLOT_RULE_BYTE_NS`]. A node
/// sends nothing before the answer (the radio may lose a frame that reaches it earlier), so each
/// channel phase and the report window begin with this long for the change
/// ([`Schedule::with_tune`]).
pub const TUNE_US: u32 =
    2 * AT_CH_FRAME_MAX_BYTES * SLOT_RULE_BYTE_NS / 1000 + xbee_api::CHANNEL_SWITCH_US;
/// The silence at the start of every slot, µs: a frame is written at its end. It holds the sync
/// error between two nodes' timelines ([`SYNC_ERROR_US`]) with room to spare; the channel
/// changes have their own time ([`TUNE_US`], at the start of each channel phase and of the
/// report window).
pub const GUARD_US: u32 = 3_000;
/// The most two nodes' timelines are apart, µs: the slot rule leaves it at a slot's end, where a
/// receiver ahead of the sender ends the slot that much earlier than the sender.
pub const SYNC_ERROR_US: u32 = 1_000;
/// Report sub-slots per superframe: agents 1…`REPORT_SUBSLOTS` report, one sub-slot each.
pub const REPORT_SUBSLOTS: u8 = 2;
/// The shortest report sub-slot, µs: it holds a 4-anchor × 2-channel report's way over the
/// agent's UART and the air, with room to spare. Larger reports get longer sub-slots
/// ([`report_slot_us`]).
pub const MIN_REPORT_SLOT_US: u32 = 20_000;
/// What a report sub-slot leaves after the guard, the agent radio's backoff
/// ([`AGENT_BACKOFF_US`]) and the report's way to the sink's MCU ([`packet_latency_us`] and
/// [`SECURITY_US`]); the report is on air well before, and the agent
/// is back on its first channel before the next superframe's first beacon reaches its radio.
const REPORT_MARGIN_US: u32 = 1_000;
/// The agent radio's `RN`, the smallest backoff exponent of its CSMA-CA, set at bring-up: its
/// report waits 0 or 1 backoff period at random before the channel check, and so does each
/// retry. With the factory `RN` = 0 two senders that start within the check's 0.3 ms (two agents
/// with one id, synchronised by the same beacons, or a foreign device) collide on every attempt
/// and the sink hears neither; with 1, one of them defers in half the attempts and both reports
/// get through, so the sink can count the repeat. Anchors and the sink keep 0: a beacon goes on
/// air when its slot says (the slot rule has no room for a backoff), and the sink sends no data.
pub const AGENT_BACKOFF_EXPONENT: u8 = 1;
/// The agent radio's `CA`, the level from which its channel check finds the channel busy, −dBm:
/// −80 dBm, the most sensitive the S1 allows. The factory −44 dBm hears only radios within
/// about a metre, so in a room two senders would not hear each other and would collide instead
/// of one waiting for the other.
pub const AGENT_CCA_THRESHOLD: u8 = 0x50;
/// The longest wait [`AGENT_BACKOFF_EXPONENT`] puts before a report's first channel check, µs:
/// part of what a report sub-slot must hold.
pub const AGENT_BACKOFF_US: u32 = ((1 << AGENT_BACKOFF_EXPONENT) - 1) * xbee_api::BACKOFF_PERIOD_US;
/// One byte on the 57600-baud 8N1 UART between MCU and radio (10 bit times), ns.
pub const UART_BYTE_NS: u32 = 173_611;
/// From the end of a packet on air to the first byte of its RX frame on the receiving radio's
/// UART, µs (the modelled XBee's default; a real S1's is of the same order).
pub const RADIO_RX_LATENCY_US: u32 = 200;

/// How long after its scheduled transmit time a beacon of a network of `anchors` anchors reaches
/// a receiver's MCU, µs: the TX16 frame over the sender's UART (frame delimiter, length, API id,
/// frame id, destination, options and checksum around the payload: 9 + 13 + N bytes), the
/// best-case time on air (0.928 ms + 32 µs per payload byte, `docs/design.md` section 2), the
/// receiving radio's latency, and the RX frame's first byte (the receiver stamps a frame when
/// its 0x7E has arrived, `uno_board::rx_frame_start_us`). Escaped bytes add 174 µs each (rare:
/// positions and RSSI bytes seldom equal 0x11, 0x13, 0x7D or 0x7E).
pub const fn beacon_latency_us(anchors: u8) -> u32 {
    packet_latency_us(crate::msg::Beacon::BASE_LEN as u32 + anchors as u32)
}

/// How long after the sender's MCU starts writing a TX16 frame of a `payload`-byte packet the
/// packet's RX frame starts on the receiver's UART, µs (as [`beacon_latency_us`]).
pub const fn packet_latency_us(payload: u32) -> u32 {
    let frame = payload + 9;
    (frame + 1) * UART_BYTE_NS / 1000 + 928 + 32 * payload + RADIO_RX_LATENCY_US
}

/// One UART byte as the slot rules count it ([`packet_received_us`]), ns: 11 bit times, 10 %
/// over an 8N1 byte. simavr's UART takes that long per byte, and a real radio's UART may leave
/// gaps between the bytes of a frame; the rules hold for both.
pub const SLOT_RULE_BYTE_NS: u32 = UART_BYTE_NS / 10 * 11;

/// What encryption (a network key) adds to a packet's time on air, µs: the 802.15.4 auxiliary
/// security header, at 32 µs a byte. The slot rules count it whether the network encrypts or
/// not, so that every slot holds either way.
pub const SECURITY_US: u32 = 32 * xbee_api::SECURITY_HEADER_BYTES as u32;

/// How long after the sender's MCU starts writing a TX16 frame of a `payload`-byte packet the
/// receiver's MCU has the whole RX16 frame, at the latest, µs: the TX frame over the sender's
/// UART, the time on air (with the encryption's [`SECURITY_US`]) and the receiving radio's
/// latency as in [`packet_latency_us`], then the whole RX frame (the same 9 bytes around the
/// payload) over the receiver's UART, every UART byte counted at [`SLOT_RULE_BYTE_NS`].
pub const fn packet_received_us(payload: u32) -> u32 {
    let uart = 2 * (payload + 9);
    uart * SLOT_RULE_BYTE_NS / 1000 + 928 + 32 * payload + SECURITY_US + RADIO_RX_LATENCY_US
}

/// The guard time of a slot of `slot_us`: [`GUARD_US`], at most a quarter of the slot.
pub const fn guard_us(slot_us: u32) -> u32 {
    if GUARD_US < slot_us / 4 {
        GUARD_US
    } else {
        slot_us / 4
    }
}

/// Whether a slot of `slot_ms` holds a beacon of a network of `anchors` anchors: its guard, then
/// the beacon's way into the receivers' MCUs, whole ([`packet_received_us`]), must end within
/// the slot, [`SYNC_ERROR_US`] before its end. A beacon still on its way when the slot ends is lost where that slot ends a phase:
/// the receivers tune to the next channel, and an agent sends its report without it.
///
/// Nodes check it with a table built from that rule at compile time ([`min_slot_ms`]), which
/// costs the MCU a lookup rather than the arithmetic.
pub const fn slot_fits_beacon(anchors: u8, slot_ms: u16) -> bool {
    slot_ms >= min_slot_ms(anchors)
}

/// Whether the guard of a slot of `slot_us`, then a beacon of `anchors` anchors on its way into
/// the receivers' MCUs, end within the slot: the rule [`slot_fits_beacon`] applies.
const fn beacon_ends_in_slot(anchors: u8, slot_us: u32) -> bool {
    let payload = crate::msg::Beacon::BASE_LEN as u32 + anchors as u32;
    guard_us(slot_us) + packet_received_us(payload) + SYNC_ERROR_US <= slot_us
}

/// The shortest slot of every anchor count up to [`crate::msg::MAX_ANCHORS`], ms (larger counts: the
/// last), by the rule of [`slot_fits_beacon`].
const MIN_SLOT_MS: [u8; crate::msg::MAX_ANCHORS + 1] = {
    let mut t = [0; crate::msg::MAX_ANCHORS + 1];
    let mut n = 0;
    while n < t.len() {
        let mut slot = 1;
        while !beacon_ends_in_slot(n as u8, slot * 1000) {
            slot += 1;
        }
        t[n] = slot as u8;
        n += 1;
    }
    t
};

/// The shortest slot a network of `anchors` anchors can run with, ms ([`slot_fits_beacon`]).
pub const fn min_slot_ms(anchors: u8) -> u16 {
    let n = if (anchors as usize) < MIN_SLOT_MS.len() {
        anchors as usize
    } else {
        MIN_SLOT_MS.len() - 1
    };
    MIN_SLOT_MS[n] as u16
}

/// The report sub-slot of a network of `anchors` × `channels` with slots of `slot_us`: a slot,
/// at least [`MIN_REPORT_SLOT_US`], and long enough for the guard, the largest report an agent
/// sends on its way to the sink, and a margin. The report is taken as its relay matrix whole or
/// a full packet ([`crate::msg::MAX_PAYLOAD`]), whichever is smaller: at most a few bytes more
/// than [`crate::msg::Report::max_size`], and no division for the MCU.
pub const fn report_slot_us(anchors: u8, channels: u8, slot_us: u32) -> u32 {
    let whole = crate::msg::Report::wire_size(anchors as usize, channels as usize, true);
    let size = if whole < crate::msg::MAX_PAYLOAD {
        whole
    } else {
        crate::msg::MAX_PAYLOAD
    } as u32;
    let need =
        GUARD_US + AGENT_BACKOFF_US + packet_latency_us(size) + SECURITY_US + REPORT_MARGIN_US;
    let min = if need > MIN_REPORT_SLOT_US {
        need
    } else {
        MIN_REPORT_SLOT_US
    };
    if slot_us > min {
        slot_us
    } else {
        min
    }
}

impl Schedule {
    /// The superframe every node derives from its config: `anchors` slots of `slot_ms` per
    /// channel, [`REPORT_SUBSLOTS`] report sub-slots ([`report_slot_us`]), the guard of the slot
    /// ([`guard_us`]) and [`TUNE_US`] for each channel change.
    pub const fn for_config(c: &crate::config::Config) -> Result<Schedule, ScheduleError> {
        let slot_us = c.slot_ms as u32 * 1000;
        let channels = c.channels.len() as u8;
        match Schedule::new(
            c.anchors,
            channels,
            slot_us,
            REPORT_SUBSLOTS,
            report_slot_us(c.anchors, channels, slot_us),
            guard_us(slot_us),
        ) {
            Ok(s) => s.with_tune(TUNE_US),
            Err(e) => Err(e),
        }
    }
}

/// Superframes without a beacon after which an anchor is taken as gone (for the master choice).
pub const SILENT_SUPERFRAMES: u8 = 3;

/// A node's copy of the testbed's timeline: where superframe `seq` starts on the local clock,
/// and who the time master is. Anchors and agents follow it the same way: the master
/// is the lowest anchor id heard in the last [`SILENT_SUPERFRAMES`] superframes (or the node
/// itself, for an anchor, if lower), and each of the master's beacons re-aligns the timeline:
/// its transmit time in the schedule, less the radio latency, is taken as exact.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Timeline {
    sched: Schedule,
    latency_us: u32,
    /// This node's anchor id, 0 for an agent or sink.
    own: u8,
    sf_start: u32,
    seq: u16,
    /// Superframes since each anchor was last heard (index id − 1), saturating.
    quiet: [u8; 8],
}

impl Timeline {
    /// A timeline for node `own` (its anchor id, 0 if it is not an anchor) starting at local
    /// time `start_us`; beacons arrive `latency_us` after their transmit time.
    pub const fn new(sched: Schedule, latency_us: u32, own: u8, start_us: u32) -> Timeline {
        Timeline {
            sched,
            latency_us,
            own,
            sf_start: start_us,
            seq: 0,
            quiet: [u8::MAX; 8],
        }
    }

    /// The schedule.
    pub const fn schedule(&self) -> &Schedule {
        &self.sched
    }

    /// The current superframe sequence.
    pub const fn seq(&self) -> u16 {
        self.seq
    }

    /// Starts superframe `seq` at local time `start_us`.
    pub fn restart(&mut self, start_us: u32, seq: u16) {
        self.sf_start = start_us;
        self.seq = seq;
    }

    /// Time into the current superframe at local time `now_us` (≥ the superframe's length when
    /// it is over: then [`Timeline::roll`]).
    pub const fn elapsed_us(&self, now_us: u32) -> u32 {
        now_us.wrapping_sub(self.sf_start)
    }

    /// How long from local time `now_us` until the event `event_us` into the current superframe
    /// (`None`: until the superframe ends), µs; 0 when it is due or the superframe is over.
    pub const fn until_us(&self, now_us: u32, event_us: Option<u32>) -> u32 {
        let sf = self.sched.superframe_us;
        let t = self.elapsed_us(now_us);
        match event_us {
            _ if t >= sf => 0,
            Some(e) => e.saturating_sub(t),
            None => sf - t,
        }
    }

    /// Ends the current superframe: the next one starts where it ends; silence counts grow.
    pub fn roll(&mut self) {
        self.sf_start = self.sf_start.wrapping_add(self.sched.superframe_us());
        self.seq = self.seq.wrapping_add(1);
        for q in &mut self.quiet {
            *q = q.saturating_add(1);
        }
    }

    /// The time master: the lowest anchor id heard in the last [`SILENT_SUPERFRAMES`]
    /// superframes, or this node if it is an anchor with a lower id; 0 if none.
    pub fn master(&self) -> u8 {
        let n = self.sched.anchors().min(8);
        let mut j = 1;
        while j <= n {
            if j == self.own || self.quiet[j as usize - 1] < SILENT_SUPERFRAMES {
                return j;
            }
            j += 1;
        }
        self.own
    }

    /// Whether anchor `id`'s beacon at this `channel` index can be from this testbed.
    pub const fn plausible(&self, id: u8, channel: u8) -> bool {
        id >= 1 && id <= self.sched.anchors() && id != self.own && channel < self.sched.channels()
    }

    /// Anchor `from` was heard. Call before [`Timeline::align`].
    pub fn heard(&mut self, from: u8) {
        if (1..=8).contains(&from) {
            self.quiet[from as usize - 1] = 0;
        }
    }

    /// Takes the timeline of `from`'s beacon of superframe `seq` on channel index `channel`,
    /// received at local time `at_us`. Returns whether the sequence changed.
    pub fn align(&mut self, from: u8, seq: u16, channel: u8, at_us: u32) -> bool {
        let Some(tx) = self.sched.beacon_at_us(channel, from) else {
            return false;
        };
        self.sf_start = at_us.wrapping_sub(self.latency_us).wrapping_sub(tx);
        let changed = seq != self.seq;
        self.seq = seq;
        changed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The thesis: 4 anchors, channels [1, 12], 250 ms channel phases; one agent.
    fn thesis() -> Schedule {
        Schedule::new(4, 2, 62_500, 1, 50_000, 2_000).unwrap()
    }

    #[test]
    fn the_thesis_layout() {
        let s = thesis();
        assert_eq!(s.channel_phase_us(), 250_000);
        assert_eq!(s.report_start_us(), 500_000);
        assert_eq!(s.superframe_us(), 550_000);
        assert_eq!(s.beacon_at_us(0, 1), Some(2_000));
        assert_eq!(s.beacon_at_us(0, 4), Some(189_500));
        assert_eq!(s.beacon_at_us(1, 1), Some(252_000));
        assert_eq!(s.channel_start_us(1), Some(250_000));
        assert_eq!(s.report_at_us(1), Some(502_000));
        assert_eq!(s.beacon_at_us(2, 1), None);
        assert_eq!(s.beacon_at_us(0, 5), None);
        assert_eq!(s.beacon_at_us(0, 0), None);
        assert_eq!(s.report_at_us(2), None);
    }

    #[test]
    fn every_transmit_time_falls_in_its_own_slot_outside_the_guard() {
        for ((n, c, m), tune) in [(1u8, 1u8, 0u8), (3, 4, 2), (8, 4, 16), (4, 2, 1)]
            .into_iter()
            .flat_map(|layout| [(layout, 0), (layout, TUNE_US)])
        {
            let s = Schedule::new(n, c, 25_000, m, 10_000, 1_500)
                .unwrap()
                .with_tune(tune)
                .unwrap();
            let mut seen = 0;
            for ch in 0..c {
                for a in 1..=n {
                    let t = s.beacon_at_us(ch, a).unwrap();
                    let want = Phase::Beacon {
                        channel: ch,
                        anchor: a,
                        guard: false,
                    };
                    assert_eq!(s.phase_at(t), want);
                    // The slot's first microsecond is guard time (the first slot of a phase
                    // begins with the channel change); its last still its own.
                    let first = if a == 1 { tune } else { 0 };
                    let start = t - 1_500 - first;
                    if a == 1 {
                        assert_eq!(s.channel_start_us(ch), Some(start));
                    }
                    assert_eq!(
                        s.phase_at(start),
                        Phase::Beacon {
                            channel: ch,
                            anchor: a,
                            guard: true
                        }
                    );
                    assert_eq!(s.phase_at(start + first + 25_000 - 1), want);
                    seen += 1;
                }
            }
            for a in 1..=m {
                let t = s.report_at_us(a).unwrap();
                assert_eq!(
                    s.phase_at(t),
                    Phase::Report {
                        agent: a,
                        guard: false
                    }
                );
                assert_eq!(
                    s.phase_at(t - 1),
                    Phase::Report {
                        agent: a,
                        guard: true
                    }
                );
                if a == 1 {
                    // The report window begins with the channel change, in agent 1's guard.
                    assert_eq!(t - 1_500 - tune, s.report_start_us());
                    assert_eq!(
                        s.phase_at(s.report_start_us()),
                        Phase::Report {
                            agent: 1,
                            guard: true
                        }
                    );
                }
            }
            let report = if m > 0 { tune + m as u32 * 10_000 } else { 0 };
            assert_eq!(
                s.superframe_us(),
                c as u32 * (tune + n as u32 * 25_000) + report
            );
            assert_eq!(seen, n as usize * c as usize);
            // Time wraps at the superframe.
            assert_eq!(s.phase_at(s.superframe_us()), s.phase_at(0));
        }
    }

    #[test]
    fn no_two_slots_overlap() {
        let s = Schedule::new(8, 4, 3_000, 16, 2_000, 500).unwrap();
        let mut starts: std::vec::Vec<u32> = (0..4)
            .flat_map(|c| (1..=8).map(move |a| (c, a)))
            .map(|(c, a)| s.beacon_at_us(c, a).unwrap())
            .chain((1..=16).map(|a| s.report_at_us(a).unwrap()))
            .collect();
        starts.sort_unstable();
        for w in starts.windows(2) {
            assert!(w[1] - w[0] >= 2_000, "{w:?}");
        }
        assert!(*starts.last().unwrap() < s.superframe_us());
    }

    #[test]
    fn bad_layouts_are_refused() {
        assert_eq!(
            Schedule::new(0, 2, 62_500, 1, 50_000, 2_000),
            Err(ScheduleError::Anchors(0))
        );
        assert_eq!(
            Schedule::new(9, 2, 62_500, 1, 50_000, 2_000),
            Err(ScheduleError::Anchors(9))
        );
        assert_eq!(
            Schedule::new(4, 5, 62_500, 1, 50_000, 2_000),
            Err(ScheduleError::Channels(5))
        );
        assert_eq!(
            Schedule::new(4, 2, 62_500, 17, 50_000, 2_000),
            Err(ScheduleError::Agents(17))
        );
        assert_eq!(
            Schedule::new(4, 2, 2_000, 1, 50_000, 2_000),
            Err(ScheduleError::SlotTooShort)
        );
        assert_eq!(
            Schedule::new(4, 2, 62_500, 1, 2_000, 2_000),
            Err(ScheduleError::SlotTooShort)
        );
        assert_eq!(
            Schedule::new(8, 4, u32::MAX / 16, 0, 0, 0),
            Err(ScheduleError::TooLong)
        );
        // No agents: the report sub-slot length does not matter.
        assert!(Schedule::new(4, 1, 25_000, 0, 0, 1_000).is_ok());
    }

    #[test]
    fn a_timeline_aligns_on_a_beacon_and_picks_the_lowest_live_anchor_as_master() {
        let s = thesis();
        let mut tl = Timeline::new(s, 3_000, 3, 0);
        assert_eq!(tl.master(), 3, "an anchor alone is its own master");
        assert_eq!(
            Timeline::new(s, 3_000, 0, 0).master(),
            0,
            "an agent alone has none"
        );
        // Anchor 2's beacon on channel 1 sent at 252 ms + 62.5 ms into superframe 7.
        tl.heard(2);
        assert!(tl.align(2, 7, 1, 1_000_000));
        assert_eq!(tl.seq(), 7);
        let tx = s.beacon_at_us(1, 2).unwrap();
        assert_eq!(tl.elapsed_us(1_000_000), tx + 3_000);
        assert_eq!(tl.master(), 2);
        assert!(!tl.align(2, 7, 1, 1_000_000));
        // Anchor 2 silent for SILENT_SUPERFRAMES superframes: anchor 3 is master again.
        for _ in 0..SILENT_SUPERFRAMES {
            assert_eq!(tl.master(), 2);
            tl.roll();
        }
        assert_eq!(tl.master(), 3);
        assert_eq!(tl.seq(), 7 + SILENT_SUPERFRAMES as u16);
        // Anchor 1 heard: it is master; impossible senders are not plausible.
        tl.heard(1);
        assert_eq!(tl.master(), 1);
        assert!(!tl.plausible(3, 0) && !tl.plausible(0, 0) && !tl.plausible(5, 0));
        assert!(!tl.plausible(1, 2) && tl.plausible(4, 1));
    }

    #[test]
    fn the_superframe_of_a_config() {
        use crate::config::Config;
        // The default: 4 anchors × 2 channels × 62 ms, two 62 ms report sub-slots, a channel
        // change before each channel phase and the report window.
        let s = Schedule::for_config(&Config::DEFAULT).unwrap();
        let t = TUNE_US;
        assert_eq!(s.superframe_us(), 3 * t + 8 * 62_000 + 2 * 62_000);
        assert_eq!(s.channel_start_us(1), Some(t + 4 * 62_000));
        assert_eq!(s.beacon_at_us(1, 3), Some(2 * t + 6 * 62_000 + GUARD_US));
        assert_eq!(s.report_start_us(), 2 * t + 8 * 62_000);
        assert_eq!(
            s.report_at_us(2),
            Some(3 * t + 8 * 62_000 + 62_000 + GUARD_US)
        );
        assert_eq!(s.agents(), REPORT_SUBSLOTS);
        // Short slots: report sub-slots stay long enough for a report.
        let fast = Config {
            slot_ms: 17,
            ..Config::DEFAULT
        };
        let s = Schedule::for_config(&fast).unwrap();
        assert_eq!(s.guard_us(), GUARD_US);
        assert_eq!(s.tune_us(), TUNE_US);
        assert_eq!(
            s.report_at_us(1),
            Some(2 * TUNE_US + 8 * 17_000 + TUNE_US + GUARD_US)
        );
        assert_eq!(
            s.superframe_us(),
            3 * TUNE_US + 8 * 17_000 + 2 * MIN_REPORT_SLOT_US
        );
        // The guard is at most a quarter of a slot.
        assert_eq!(guard_us(10_000), 2_500);
    }

    /// A slot holds its guard, a beacon's way into the receivers, whole, and the sync error:
    /// 17 ms with 3 or 4 anchors, 18 with 5 to 7, 19 with 8; and a config with a shorter slot
    /// is refused.
    #[test]
    fn a_slot_must_hold_a_beacon() {
        use crate::config::Config;
        for anchors in 3..=8u8 {
            let min = min_slot_ms(anchors);
            let want = match anchors {
                3 | 4 => 17,
                5..=7 => 18,
                _ => 19,
            };
            assert_eq!(min, want, "{anchors}");
            // The whole RX frame: the TX frame's first byte to the RX frame's last, the UART's
            // bytes at 11 bit times; a tenth of a UART byte more per byte than the latency the
            // followers correct for (the RX frame's first byte), and the RX frame's other bytes.
            let payload = crate::msg::Beacon::BASE_LEN as u32 + anchors as u32;
            let frame = payload + 9;
            let whole = beacon_latency_us(anchors)
                + (frame - 1) * UART_BYTE_NS / 1000
                + 2 * frame * (SLOT_RULE_BYTE_NS - UART_BYTE_NS) / 1000
                + SECURITY_US;
            assert!(
                packet_received_us(payload).abs_diff(whole) <= 2,
                "{anchors}"
            );
            let rule = packet_received_us(payload);
            let slot_us = min as u32 * 1000;
            assert!(guard_us(slot_us) + rule + SYNC_ERROR_US <= slot_us);
            let shorter = (min - 1) as u32 * 1000;
            assert!(guard_us(shorter) + rule + SYNC_ERROR_US > shorter);
            let c = Config {
                anchors,
                slot_ms: min,
                ..Config::DEFAULT
            };
            assert_eq!(c.validate(), Ok(()));
            let c = Config {
                slot_ms: min - 1,
                ..c
            };
            assert_eq!(
                c.validate(),
                Err(crate::Error::BadValue {
                    field: crate::error::Field::SlotLength
                })
            );
        }
    }

    /// The table the nodes look the shortest slot up in is the rule itself, for every anchor
    /// count the table has and every slot length a config takes.
    #[test]
    fn the_slot_table_is_the_rule() {
        for anchors in 0..=MIN_SLOT_MS.len() as u8 + 1 {
            for slot_ms in 1..=crate::config::MAX_SLOT_MS {
                let n = anchors.min(MIN_SLOT_MS.len() as u8 - 1);
                assert_eq!(
                    slot_fits_beacon(anchors, slot_ms),
                    beacon_ends_in_slot(n, slot_ms as u32 * 1000),
                    "{anchors} anchors, {slot_ms} ms"
                );
            }
        }
    }

    /// A report sub-slot holds the largest report an agent sends: the guard, the report's way
    /// to the sink's MCU and a margin; the 4 × 2 report keeps the shortest sub-slot.
    #[test]
    fn a_report_sub_slot_holds_the_largest_report() {
        assert_eq!(report_slot_us(4, 2, 10_000), MIN_REPORT_SLOT_US);
        for anchors in 3..=8u8 {
            for channels in 1..=4u8 {
                let size = crate::msg::Report::max_size(anchors.into(), channels.into());
                assert!(size <= crate::msg::MAX_PAYLOAD);
                let sub = report_slot_us(anchors, channels, min_slot_ms(anchors) as u32 * 1000);
                assert!(sub >= MIN_REPORT_SLOT_US);
                let need = GUARD_US
                    + AGENT_BACKOFF_US
                    + packet_latency_us(size as u32)
                    + SECURITY_US
                    + REPORT_MARGIN_US;
                assert!(
                    sub >= need && sub >= MIN_REPORT_SLOT_US,
                    "{anchors}×{channels}"
                );
                // Long slots are report sub-slots as they are.
                assert_eq!(report_slot_us(anchors, channels, 62_000), 62_000);
            }
        }
        // The largest report (8 anchors × 4 channels) needs more than the shortest sub-slot.
        assert!(report_slot_us(8, 4, 10_000) > MIN_REPORT_SLOT_US);
    }

    #[test]
    fn the_beacon_latency_adds_up() {
        // 4 anchors: 19-byte payload, 28-byte frame + the RX frame's delimiter = 29 bytes of
        // UART (5 034 µs), 1 536 µs on air, 200 µs in the receiving radio.
        assert_eq!(
            beacon_latency_us(4),
            29 * 173_611 / 1000 + 928 + 32 * 19 + 200
        );
        assert_eq!(beacon_latency_us(4), 6_770);
        // Each more relayed anchor: one more byte on the UART and on air.
        assert_eq!(beacon_latency_us(5) - beacon_latency_us(4), 173 + 32 + 1);
    }
}
