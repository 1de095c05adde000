//! The radio's 802.15.4 MAC as [`XBeeCore`] runs it: channel access (unslotted CSMA-CA with
//! clear channel assessment), acknowledgements, retries and duplicate detection. What it models
//! and the figures it follows are in the docs of [`crate::xbee`].
//!
//! One TX request at a time, the others queued: each goes through attempts, an attempt being a
//! channel access (backoffs and CCAs) and, if the channel is clear, the packet on air and, when
//! it asks for one, the wait for its ACK. Alone the radio decides every CCA itself (the channel
//! is clear) and an ideal receiver acknowledges; on a medium ([`XBeeCore::set_on_medium`]) the
//! medium judges each CCA ([`XBeeCore::pending_cca`], [`XBeeCore::judge_cca`]) and carries the
//! ACKs ([`XBeeCore::receive`]).

use std::collections::VecDeque;

use xbee_api::TxStatus;

use super::{Address, Csma, Event, Security, Transmission, XBeeCore};
use crate::avr::F_CPU;

/// One symbol of the 2.4 GHz PHY (O-QPSK, 62.5 ksymbol/s, two symbols a byte), µs.
const SYMBOL_US: u64 = 16;
/// One backoff period (aUnitBackoffPeriod, 20 symbols), µs.
pub const BACKOFF_PERIOD_US: u64 = xbee_api::BACKOFF_PERIOD_US as u64;
const _: () = assert!(BACKOFF_PERIOD_US == 20 * SYMBOL_US);
/// A clear channel assessment (8 symbols), µs.
pub const CCA_US: u64 = 8 * SYMBOL_US;
/// Receive-to-transmit turnaround (aTurnaroundTime, 12 symbols), µs: after a clear CCA before
/// the packet, after a received packet before its ACK.
pub const TURNAROUND_US: u64 = 12 * SYMBOL_US;
/// An ACK on air, µs: its 5-byte frame (frame control, sequence number, FCS) after the
/// preamble, the start-of-frame delimiter and the length byte, 11 bytes of 2 symbols.
pub const ACK_AIR_US: u64 = 11 * 2 * SYMBOL_US;
/// How long a sender waits for an ACK after its packet's end (macAckWaitDuration, 54 symbols),
/// µs.
pub const ACK_WAIT_US: u64 = 54 * SYMBOL_US;
/// Busy CCAs of one channel access after the first before it fails (macMaxCSMABackoffs): five
/// busy CCAs in all.
pub const MAX_CSMA_BACKOFFS: u8 = 4;
/// The largest backoff exponent (aMaxBE).
pub const MAX_BE: u8 = 5;
/// MAC retries of an unacknowledged packet (aMaxFrameRetries): four transmissions in all, per
/// XBee retry (`RR`).
pub const MAX_FRAME_RETRIES: u8 = 3;
/// Bytes a data frame has on air besides its payload: what the XBee's best-case figure
/// ([`super::time_on_air_ms`]) leaves after one CCA and the turnaround, 0.608 ms at 32 µs a
/// byte. The preamble, delimiter and length byte and a MAC header and checksum with 16-bit
/// addresses make 17 of them.
pub const FRAME_OVERHEAD_BYTES: usize = 19;

/// Cycles of `us` microseconds.
const fn cycles(us: u64) -> u64 {
    us * F_CPU as u64 / 1_000_000
}

/// Cycles a data frame with a `k`-byte payload (security header included) is on air:
/// ([`FRAME_OVERHEAD_BYTES`] + `k`) bytes of 32 µs.
pub fn frame_air_cycles(k: usize) -> u64 {
    cycles(2 * SYMBOL_US * (FRAME_OVERHEAD_BYTES + k) as u64)
}

/// What a packet on air is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum FrameKind {
    /// A data frame (an API TX request, a transparent-mode packet).
    #[default]
    Data,
    /// An acknowledgement.
    Ack,
}

/// The MAC's side of a packet on air.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct MacFields {
    /// Data or ACK.
    pub kind: FrameKind,
    /// The 802.15.4 data sequence number: one per TX request (its retries keep it); an ACK
    /// carries the one it acknowledges.
    pub seq: u8,
    /// The frame asks for an ACK: a unicast without TX option 0x01, from a radio in a MAC mode
    /// with ACKs (`MM` 0 or 2).
    pub ack_request: bool,
    /// Which transmission of its TX request it is: 0 the first, n its n-th retry (or, for a
    /// broadcast with `RR` > 0, its n-th repeated copy).
    pub attempt: u8,
}

/// A clear channel assessment waiting for a medium's verdict ([`XBeeCore::pending_cca`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Cca {
    /// Its first cycle; it lasts [`CCA_US`].
    pub at: u64,
    /// The channel it listens on.
    pub channel: u8,
    /// The level at and above which another packet on air makes the channel busy, dBm
    /// (`CA`).
    pub threshold_dbm: i16,
}

/// A TX request the MAC is sending or has queued.
#[derive(Debug)]
struct Outgoing {
    frame_id: u8,
    dest: Address,
    options: u8,
    payload: Vec<u8>,
    security: Security,
    seq: u8,
    ack_request: bool,
    /// Copies to put on air when it asks for no ACK: 1, or a broadcast's `RR` + 2.
    copies: u8,
    /// Bytes it takes in the serial receive buffer until the MAC is done with it.
    serial_bytes: usize,
    /// Transmissions so far.
    sent: u8,
    /// MAC retries since the request or the last XBee retry.
    mac_retries: u8,
    /// XBee retries (`RR`) so far.
    xbee_retries: u8,
}

/// Where the current request is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Phase {
    /// No request.
    #[default]
    Idle,
    /// Channel access: the CCA at `at` on `channel` is next, after `nb` busy ones, with
    /// backoff exponent `be`.
    Access {
        at: u64,
        channel: u8,
        nb: u8,
        be: u8,
    },
    /// The packet is on air.
    Sending,
    /// The packet is off the air; its ACK may come until `deadline`.
    AwaitAck { deadline: u64 },
}

/// A MAC timer (valid for the phase generation it was set in).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum MacTimer {
    /// The packet is off the air.
    TxEnd,
    /// The wait for the ACK is over.
    AckTimeout,
    /// Alone: the ACK an ideal receiver sends has arrived.
    IdealAck,
}

/// The MAC's state.
#[derive(Debug, Default)]
pub(super) struct MacLayer {
    queue: VecDeque<Outgoing>,
    current: Option<Outgoing>,
    phase: Phase,
    /// Bumped at every change of phase: timers of an earlier one are stale.
    gen: u64,
    /// The next data sequence number.
    dsn: u8,
    /// Duplicate detection: the sequence number last passed on from each source.
    last_seq: VecDeque<(Address, u8)>,
    /// A medium judges the CCAs and carries the ACKs.
    on_medium: bool,
    /// `EC`: channel access failures (saturating).
    pub(super) ec: u16,
    /// `EA`: unicasts without an ACK after every retry (saturating).
    pub(super) ea: u16,
}

/// Sources duplicate detection remembers.
const DUPLICATE_SOURCES: usize = 32;

impl MacLayer {
    /// Power-up: nothing queued or under way, counters at 0, the sequence numbers from `dsn`
    /// (random, as 802.15.4's macDSN starts).
    pub(super) fn power_up(&mut self, dsn: u8) {
        *self = MacLayer {
            gen: self.gen + 1,
            dsn,
            on_medium: self.on_medium,
            ..MacLayer::default()
        };
    }
}

impl XBeeCore {
    /// Puts the radio on a medium (`true`: what [`crate::network::Network`] does with its
    /// radios) or takes it off. On a medium, the medium judges the radio's clear channel
    /// assessments ([`XBeeCore::pending_cca`], [`XBeeCore::judge_cca`]) and carries the ACKs
    /// both ways ([`XBeeCore::receive`]). Alone (the default), every CCA finds the channel
    /// clear and every packet that asks for an ACK gets one from an ideal receiver:
    /// [`TURNAROUND_US`] + [`ACK_AIR_US`] after its end.
    pub fn set_on_medium(&mut self, on: bool) {
        self.mac.on_medium = on;
    }

    /// Whether a medium judges the CCAs and carries the ACKs ([`XBeeCore::set_on_medium`]).
    pub fn on_medium(&self) -> bool {
        self.mac.on_medium
    }

    /// The clear channel assessment the radio waits for a verdict on ([`XBeeCore::judge_cca`]),
    /// if any: on a medium, with [`Csma::Random`]. It waits however far the radio runs past
    /// it; the verdict decides what happened from its time on.
    pub fn pending_cca(&self) -> Option<Cca> {
        match self.mac.phase {
            Phase::Access { at, channel, .. } => Some(Cca {
                at,
                channel,
                threshold_dbm: -i16::from(self.active.ca()),
            }),
            _ => None,
        }
    }

    /// The medium's verdict on the pending CCA ([`XBeeCore::pending_cca`]): `busy` if another
    /// radio's packet was on air during it at or above the threshold. The radio itself also
    /// finds the channel busy while it switches to transmit or transmits an ACK (802.15.4: a
    /// CCA while the transmitter is on reports busy). Clear, the packet goes on air after the
    /// turnaround; busy, the radio backs off for the next CCA or, after
    /// [`MAX_CSMA_BACKOFFS`] + 1 busy ones, gives up (TX status 0x02). Without a pending CCA it
    /// does nothing.
    pub fn judge_cca(&mut self, busy: bool) {
        let Phase::Access {
            at,
            channel,
            nb,
            be,
        } = self.mac.phase
        else {
            return;
        };
        let end = at + cycles(CCA_US);
        let busy = busy || self.on_air.iter().any(|&(s, e)| s < end && e > at);
        if !busy {
            self.go_on_air(end + cycles(TURNAROUND_US), channel);
            return;
        }
        self.stats.cca_busy += 1;
        if nb >= MAX_CSMA_BACKOFFS {
            self.access_failed(end);
            return;
        }
        let be = (be + 1).min(MAX_BE);
        let next = end + self.backoff(be);
        self.set_phase(Phase::Access {
            at: next,
            channel,
            nb: nb + 1,
            be,
        });
    }

    /// The cycle up to which a medium may run the radio before it must judge its next MAC
    /// decision: the end of its pending CCA, or the end of its wait for an ACK (then it
    /// retries, with a CCA the medium must judge in time). `None` alone or with nothing under
    /// way.
    pub fn mac_due(&self) -> Option<u64> {
        match self.mac.phase {
            Phase::Access { at, .. } => Some(at + cycles(CCA_US)),
            Phase::AwaitAck { deadline } if self.mac.on_medium => Some(deadline),
            _ => None,
        }
    }

    /// TX requests queued behind the one under way, and whether one is under way.
    pub fn tx_queue(&self) -> (usize, bool) {
        (self.mac.queue.len(), self.mac.current.is_some())
    }

    /// Bytes of the serial receive buffer the TX requests under way and queued take.
    pub(super) fn mac_serial_bytes(&self) -> usize {
        let cur = self.mac.current.as_ref().map_or(0, |c| c.serial_bytes);
        cur + self.mac.queue.iter().map(|o| o.serial_bytes).sum::<usize>()
    }

    /// A TX request at `t`: queued, and started when the radio has finished the ones before.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn mac_request(
        &mut self,
        t: u64,
        frame_id: u8,
        dest: Address,
        options: u8,
        payload: Vec<u8>,
        security: Security,
        serial_bytes: usize,
    ) {
        let digi = matches!(self.active.mm(), 0 | 3);
        let ack_request =
            !dest.is_broadcast() && options & 0x01 == 0 && !matches!(self.active.mm(), 1 | 3);
        // Digi's S1 manual (`RR`): with `RR` > 0, `RR` + 2 packets go out on each broadcast.
        let rr = self.active.rr();
        let copies = if dest.is_broadcast() && digi && rr > 0 {
            rr + 2
        } else {
            1
        };
        let seq = self.mac.dsn;
        self.mac.dsn = seq.wrapping_add(1);
        self.mac.queue.push_back(Outgoing {
            frame_id,
            dest,
            options,
            payload,
            security,
            seq,
            ack_request,
            copies,
            serial_bytes,
            sent: 0,
            mac_retries: 0,
            xbee_retries: 0,
        });
        if self.mac.current.is_none() {
            self.start_next(t);
        }
    }

    pub(super) fn mac_timer(&mut self, timer: MacTimer, gen: u64) {
        if gen != self.mac.gen {
            return;
        }
        let now = self.now;
        match timer {
            MacTimer::TxEnd => {
                let Some(cur) = self.mac.current.as_ref() else {
                    return;
                };
                if !cur.ack_request {
                    if cur.sent < cur.copies {
                        // The next copy of a repeated broadcast: channel access and all.
                        self.begin_attempt(now);
                    } else {
                        self.complete(now, TxStatus::SUCCESS);
                    }
                    return;
                }
                let deadline = now + cycles(ACK_WAIT_US);
                self.set_phase(Phase::AwaitAck { deadline });
                if self.mac.on_medium {
                    self.schedule(deadline, Event::Mac(MacTimer::AckTimeout, self.mac.gen));
                } else {
                    let at = now + cycles(TURNAROUND_US + ACK_AIR_US);
                    self.schedule(at, Event::Mac(MacTimer::IdealAck, self.mac.gen));
                }
            }
            MacTimer::AckTimeout => self.no_ack(now),
            MacTimer::IdealAck => {
                self.stats.acks_received += 1;
                self.complete(now, TxStatus::SUCCESS);
            }
        }
    }

    /// An ACK for `seq` on `channel`, on air from `start` to now.
    pub(super) fn ack_in(&mut self, seq: u8, channel: u8, start: u64) {
        let Phase::AwaitAck { deadline } = self.mac.phase else {
            return;
        };
        let waits = self.mac.current.as_ref().is_some_and(|c| c.seq == seq);
        if !waits || channel != self.channel || self.now > deadline {
            return;
        }
        if self.on_air.iter().any(|&(s, e)| s < self.now && e > start) {
            self.stats.rx_lost += 1;
            return;
        }
        self.stats.acks_received += 1;
        self.complete(self.now, TxStatus::SUCCESS);
    }

    /// Acknowledges a data frame from `source` with sequence number `seq` that ended at cycle
    /// `data_end`: the ACK goes on air the turnaround after it, unless the radio is
    /// transmitting then.
    pub(super) fn send_ack(&mut self, source: Address, seq: u8, data_end: u64) {
        let start = data_end + cycles(TURNAROUND_US);
        let end = start + cycles(ACK_AIR_US);
        if self.on_air.iter().any(|&(s, e)| s < end && e > data_end) {
            return;
        }
        self.note_on_air(data_end, end);
        self.transmissions.push(Transmission {
            channel: self.channel,
            pan_id: self.active.id(),
            source: self.source_address(),
            source64: self.cfg.sh_sl,
            dest: source,
            options: 0,
            payload: Vec::new(),
            start_cycle: start,
            end_cycle: end,
            frame_id: 0,
            mac: MacFields {
                kind: FrameKind::Ack,
                seq,
                ack_request: false,
                attempt: 0,
            },
            power_db: self.cfg.model.power_db(self.active.pl()),
        });
        self.securities.push(Security::Clear);
        self.stats.acks_sent += 1;
    }

    /// Duplicate detection of an acknowledged frame from `source` with sequence number `seq`:
    /// true if it is the one last passed on from that source (a retry whose ACK was lost). Only
    /// in the Digi MAC modes (`MM` 0, 3), whose header the S1 detects duplicates with; strict
    /// 802.15.4 (`MM` 1, 2) passes every copy on.
    pub(super) fn duplicate(&mut self, source: Address, seq: u8) -> bool {
        if !matches!(self.active.mm(), 0 | 3) {
            return false;
        }
        let last = &mut self.mac.last_seq;
        if let Some(i) = last.iter().position(|&(a, _)| a == source) {
            if last[i].1 == seq {
                return true;
            }
            last.remove(i);
        } else if last.len() >= DUPLICATE_SOURCES {
            last.pop_front();
        }
        last.push_back((source, seq));
        false
    }

    // ---- internals ----

    fn set_phase(&mut self, phase: Phase) {
        self.mac.phase = phase;
        self.mac.gen += 1;
    }

    /// A random backoff of 0…2^`be` − 1 periods, cycles.
    fn backoff(&mut self, be: u8) -> u64 {
        let periods = self.next_rand() % (1u64 << be);
        periods * cycles(BACKOFF_PERIOD_US)
    }

    fn start_next(&mut self, t: u64) {
        self.mac.current = self.mac.queue.pop_front();
        if self.mac.current.is_some() {
            self.begin_attempt(t);
        } else {
            self.set_phase(Phase::Idle);
        }
    }

    /// A channel access for the current request from `t` on.
    fn begin_attempt(&mut self, t: u64) {
        let channel = self.channel;
        match self.cfg.csma {
            Csma::Off => self.go_on_air(t + cycles(CCA_US + TURNAROUND_US), channel),
            Csma::Random { .. } => {
                let be = self.active.rn().min(MAX_BE);
                let at = t + self.backoff(be);
                if self.mac.on_medium {
                    self.set_phase(Phase::Access {
                        at,
                        channel,
                        nb: 0,
                        be,
                    });
                } else {
                    self.go_on_air(at + cycles(CCA_US + TURNAROUND_US), channel);
                }
            }
        }
    }

    /// The current request's packet on air from `start` on `channel`.
    fn go_on_air(&mut self, start: u64, channel: u8) {
        let source = self.source_address();
        let pan_id = self.active.id();
        let power_db = self.cfg.model.power_db(self.active.pl());
        let Some(cur) = self.mac.current.as_mut() else {
            return;
        };
        let end = start + frame_air_cycles(cur.payload.len() + cur.security.overhead());
        let attempt = cur.sent;
        cur.sent = cur.sent.saturating_add(1);
        let tx = Transmission {
            channel,
            pan_id,
            source,
            source64: self.cfg.sh_sl,
            dest: cur.dest,
            options: cur.options,
            payload: cur.payload.clone(),
            start_cycle: start,
            end_cycle: end,
            frame_id: cur.frame_id,
            mac: MacFields {
                kind: FrameKind::Data,
                seq: cur.seq,
                ack_request: cur.ack_request,
                attempt,
            },
            power_db,
        };
        let security = cur.security;
        if attempt > 0 {
            if cur.ack_request {
                self.stats.retries += 1;
            } else {
                self.stats.repeats += 1;
            }
        }
        self.note_on_air(start - cycles(TURNAROUND_US), end);
        self.transmissions.push(tx);
        self.securities.push(security);
        self.stats.transmissions += 1;
        self.set_phase(Phase::Sending);
        self.schedule(end, Event::Mac(MacTimer::TxEnd, self.mac.gen));
    }

    /// The radio switches to transmit or transmits from `start` to `end`.
    fn note_on_air(&mut self, start: u64, end: u64) {
        let now = self.now;
        self.on_air
            .retain(|&(_, e)| e + cycles(50_000) > now.min(start));
        self.on_air.push((start, end));
    }

    /// An XBee retry (`RR`, Digi MAC modes only) for the current request, if one is left.
    fn xbee_retry(&mut self) -> bool {
        let rr = self.active.rr();
        let digi = matches!(self.active.mm(), 0 | 3);
        match self.mac.current.as_mut() {
            Some(cur) if digi && cur.xbee_retries < rr => {
                cur.xbee_retries += 1;
                cur.mac_retries = 0;
                true
            }
            _ => false,
        }
    }

    /// The channel access ended busy at `at`.
    fn access_failed(&mut self, at: u64) {
        self.stats.cca_failures += 1;
        self.mac.ec = self.mac.ec.saturating_add(1);
        if self.xbee_retry() {
            self.begin_attempt(at);
        } else {
            self.complete(at, TxStatus::CCA_FAILURE);
        }
    }

    /// No ACK by `at`: retry, or give up.
    fn no_ack(&mut self, at: u64) {
        let mac_retry = match self.mac.current.as_mut() {
            Some(cur) if cur.mac_retries < MAX_FRAME_RETRIES => {
                cur.mac_retries += 1;
                true
            }
            _ => false,
        };
        if mac_retry || self.xbee_retry() {
            self.begin_attempt(at);
            return;
        }
        self.stats.ack_failures += 1;
        self.mac.ea = self.mac.ea.saturating_add(1);
        self.complete(at, TxStatus::NO_ACK);
    }

    /// The current request is over at `at` with `status` (a TX status frame in API mode for a
    /// frame id ≠ 0); the next one starts.
    fn complete(&mut self, at: u64, status: TxStatus) {
        if let Some(cur) = self.mac.current.take() {
            if self.api.is_some() && cur.frame_id != 0 {
                self.schedule(at, Event::TxStatus(cur.frame_id, status));
            }
        }
        self.start_next(at);
    }
}
