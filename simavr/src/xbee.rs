//! A modelled XBee 802.15.4 (Series 1) radio on an [`Avr`]'s UART0, behaving like the real one
//! from the firmware's point of view.
//!
//! Two layers:
//!
//! * [`XBeeCore`] — the radio itself, sans IO: bytes from the host go in with the cycle their
//!   stop bit ended ([`XBeeCore::rx_byte`]), bytes to the host come out with the cycle of their
//!   start bit ([`XBeeCore::take_output`]), packets put on air come out as [`Transmission`]s
//!   ([`XBeeCore::take_transmissions`]) and received packets go in with
//!   [`XBeeCore::deliver`]. Time is simulated cycles at [`crate::F_CPU`]; the core never looks
//!   at a clock, so it is tested on the host and drives the multi-node testbed the same way.
//! * [`XBee`] — the thin attachment to an [`Avr`]: steps the core in slices ending at the
//!   core's next event, feeds it the firmware's UART output, queues its output on the
//!   firmware's RX line at the cycles it asks for, and keeps the firmware's text lines.
//!
//! A radio medium plugs in by putting every radio on it ([`XBeeCore::set_on_medium`]),
//! draining [`XBeeCore::take_transmissions_with_security`] of every node (data packets and
//! ACKs), judging the radios' pending clear channel assessments ([`XBeeCore::pending_cca`],
//! [`XBeeCore::judge_cca`]) in time order, and handing each packet to its receivers with
//! [`XBeeCore::receive`] (the packet and its [`Security`]) at its end cycle.
//! [`crate::network::Network`] does exactly that, with [`crate::medium::Medium`] deciding who
//! hears what. [`XBeeCore::deliver_secured`] hands a radio a packet without a MAC around it
//! (tests).
//!
//! # What is modelled
//!
//! * **Registers** ([`Registers`]): `CH ID DH DL MY RR RN MM NT NO CE SC SD A1 A2 EE PL CA SM ST SP
//!   DP BD NB RO AP PR IU IT IC IR RP CT GT CC` with the S1 ranges and factory defaults, `NI` (≤ 20
//!   printable characters), the write-only AES key `KY` (up to 16 bytes, shorter values
//!   right-aligned like any hex value; a query answers OK and no value, never the key), read-only
//!   `SH SL VR HV DB EC EA AI`, and `WR RE AC FR CN`. Queries answer big endian in the register's
//!   width (`BD` 4 bytes, `CH` 1, `MY` 2…); unknown commands answer status 2 (invalid command),
//!   out-of-range values 3 (invalid parameter; `CH` follows [`Model`]: S1 0x0B…0x1A, S1 Pro
//!   0x0C…0x17), sets of read-only registers 1 (error). There is an active set and a persisted set:
//!   `WR` copies active to persisted, a power cycle ([`XBee::reset`]) or `FR` restores the
//!   persisted set, `RE` loads factory defaults into the active set (`EE` 0, `KY` 0 among them).
//!   `SM`, `A1`, `PL` and `RR` act as the bullets below say; registers without modelled behaviour
//!   (the sleep timers `ST SP DP`, `CE`, `A2`, `SC`, `SD`, `NT`, `NO`, I/O, `PR`, `RP`) are stored
//!   and answered only. `AI` answers 0, or 0x02 while the radio looks for a coordinator (see
//!   *Association*).
//! * **API mode** (`AP`=1, 2): frames decoded with [`xbee_api::Decoder`] in the current mode. 0x08
//!   AT command → 0x88 response with the same frame id ([`XBeeConfig::at_latency_ms`], default 1
//!   ms, after the frame's end; none for frame id 0; a `CH` set: see *Channel switch*) and the
//!   change applied at once: `CH`, `AP` (the response still goes out in the old mode) and `BD` (the
//!   UART switches once the response is on the line). 0x09 is checked and answered but applied only
//!   with the next 0x08 or `AC`. TX16 (0x01) / TX64 (0x00) → a TX request for the MAC (see *Channel
//!   access* and *Acknowledgements*; requests queue behind each other) and, for a frame id ≠ 0, a
//!   0x89 TX status when it is decided: 0x00 success, 0x01 no ACK, 0x02 CCA failure. Payloads over
//!   100 bytes (95 with encryption) are refused: no transmission, no status (counted in
//!   [`XBeeStats::oversize_tx`]). Frames wait in the serial receive buffer (see *Serial receive
//!   buffer*). Modem status 0x8A (hardware reset) goes out [`XBeeConfig::power_up_ms`] (default 5
//!   ms) after power-up; host bytes before then are lost.
//! * **Transparent mode** (`AP`=0): host bytes are RF payload to `DH:DL`, sent (through the same
//!   MAC, without status) after `RO` character times of silence or at 100 bytes (95 with
//!   encryption); received payloads go to the host bare.
//! * **Command mode**: `GT` of silence, three `CC` characters (`+`), each within `GT` of the
//!   previous, `GT` of silence → `OK\r`. Works in API mode too, as on the 802.15.4 firmware
//!   (the bring-up of the `xbee-api` driver relies on it). Any other byte (or garbage from a
//!   mismatched UART) inside the window cancels. Then text lines `AT…\r`: query → uppercase
//!   hex without leading zeros (`NI`: the string) + `\r`; set (hex, optional `0x`, spaces
//!   ignored) → `OK\r`; several commands per line separated by commas
//!   (`ATAP2,BD6,WR,CN\r`), one answer each, stopping at the first `ERROR\r`. As the manual
//!   says, values set in command mode are stored at once (queries see them) but take effect
//!   (`CH`, `AP`, the UART rate `BD`) only on `AC`, `CN` or the `CT` timeout; the answer to the
//!   command that applies them goes out at the old rate. In transparent mode held `+`
//!   characters that turn out not to be a command sequence are sent as data.
//! * **UART rates**: the radio runs at `BD`'s rate as the S1 really runs it ([`BAUD_RATES`]: `BD=7`,
//!   named 115200, is 111 111 bit/s), the firmware at whatever its `UBRR0` gives
//!   ([`Avr::uart_cycles_per_byte`]). When the two byte times differ by more than
//!   [`XBeeConfig::baud_tolerance`] (4 %), both directions are garbled: the receiver gets a
//!   garbage byte (0xF0…0xFF: never a frame delimiter, `+`, `O`, `K` or `\r`) per byte, or
//!   fewer bytes when it is the slower side (about one per its own byte time), counted in
//!   [`XBeeStats::garbled_in`]/[`XBeeStats::garbled_out`]. Byte times are counted as simavr
//!   does (11 bit times per 8N1 byte, [`BIT_TIMES_PER_BYTE`]), so both sides compare like for
//!   like (57600 on the radio vs. `UBRR0`=34 with U2X: 0.8 % apart).
//! * **Channel switch**: an API `AT CH` that sets the channel is answered
//!   [`XBeeConfig::channel_switch_ms`] after the frame's end (default
//!   [`xbee_api::CHANNEL_SWITCH_US`], 2 ms, the worst case the nodes plan for: Digi documents no
//!   figure for the S1 and says to wait for the answer; a user of a later module lost the first
//!   frame sent after `CH`). Until the answer the radio hears nothing
//!   ([`XBeeStats::rx_switching`]) and a transmit request that reaches it is lost: no packet, no
//!   status ([`XBeeStats::tx_lost_switching`]).
//! * **Reception** ([`XBee::deliver`], from a medium [`XBeeCore::receive`]): passed on only if
//!   powered up, on the packet's channel, same PAN (or broadcast PAN), addressed to `MY`/`SH:SL` or
//!   broadcast, awake (see *Sleep*), not looking for a coordinator (see *Association*), not
//!   switching channel, not overlapping the radio's own transmissions or its turnarounds to
//!   transmit (half duplex), not in command mode, with the sender's `EE` (see *Encryption*), and
//!   not a duplicate (see *Acknowledgements*): as RX16 (0x81, 16-bit source) or RX64 (0x80) with
//!   the RSSI byte and options (0x02 address broadcast, 0x04 PAN broadcast)
//!   [`XBeeConfig::rx_latency_ms`] after the packet's end; `DB` keeps the RSSI.
//! * **Channel access** ([`Csma`]): before every transmission (API, transparent mode, each
//!   retry) IEEE 802.15.4-2003's unslotted CSMA-CA, as the S1 runs it: NB = 0, BE = `RN` (the
//!   minimum backoff exponent, 0…3, factory 0: no backoff before the first CCA), a random
//!   backoff of 0…2^BE − 1 periods of 320 µs ([`BACKOFF_PERIOD_US`]), then a clear channel
//!   assessment of 8 symbols (128 µs, [`CCA_US`]). The channel is busy when another radio's
//!   packet on it is on air during the CCA at a level at this radio (the one the medium gives
//!   that packet there) at or above the threshold `CA` (−dBm, 0x24…0x50, factory 0x2C: −44
//!   dBm), or while the radio itself turns around to transmit or sends an ACK (802.15.4: a CCA
//!   with the transmitter on reports busy). Busy: NB + 1, BE = min(BE + 1, 5), back off again;
//!   the fifth busy CCA (macMaxCSMABackoffs = 4 backoffs after the first) ends the attempt:
//!   nothing on air, `EC` + 1, TX status 0x02. Clear: the packet goes on air after the
//!   receive-to-transmit turnaround (12 symbols, 192 µs, [`TURNAROUND_US`]) for 32 µs a byte
//!   of its 19 + k bytes ([`frame_air_cycles`], [`FRAME_OVERHEAD_BYTES`]): a request on a
//!   clear channel with `RN` 0 is off the air the XBee's best case of 0.928 + 0.032·k ms
//!   after it ([`time_on_air_ms`]), and after five CCAs and the longest backoffs (26 periods)
//!   its worst case, 9.76 + 0.032·k ms. The medium judges each CCA on the network
//!   ([`XBeeCore::set_on_medium`], [`XBeeCore::judge_cca`]); a radio alone finds the channel
//!   clear. [`Csma::Off`] (the default) skips backoffs and CCAs: every attempt goes on air 0.32
//!   ms after it starts, whatever is on the channel, the best case.
//! * **Acknowledgements and retries**: a unicast (destination not 0xFFFF) without TX option 0x01,
//!   from a radio in a MAC mode with ACKs (`MM` 0, the factory Digi mode, or 2), asks for an ACK.
//!   Its receiver, if it takes the packet (powered, on the channel, in the PAN, addressed, the
//!   packet neither collided nor too weak nor lost while it transmitted or was in command mode, and
//!   the same `EE`), acknowledges it a turnaround (192 µs) after its end, unless it is transmitting
//!   then: a 5-byte frame, 11 bytes on air with the preamble (352 µs, [`ACK_AIR_US`]), a packet on
//!   the medium like any other (it collides, and it makes other radios' CCAs busy), carrying only
//!   the sequence number: a radio waiting for an ACK of that number on its channel takes it. The
//!   sender waits macAckWaitDuration (54 symbols, 864 µs, [`ACK_WAIT_US`]) after its packet's end;
//!   with the ACK in, status 0x00. Without it the MAC tries again (channel access and all, the same
//!   sequence number) up to macMaxFrameRetries ([`MAX_FRAME_RETRIES`], 3) times, and in the Digi
//!   modes that all over again `RR` times (XBee retries, 0…6, factory 0; also after a CCA failure):
//!   at most 4·(`RR` + 1) transmissions, then status 0x01 and `EA` + 1. A broadcast, or a packet
//!   asking for no ACK, is sent once (a broadcast with `RR` > 0: see *Repeated broadcasts*): status
//!   0x00 when it is off the air (0x02 if the channel access failed). Duplicate detection (the Digi
//!   header's, `MM` 0 and 3): a receiver acknowledges again a packet with the source address and
//!   sequence number of the last it passed on from that source, but does not pass it on
//!   ([`XBeeStats::rx_duplicates`]), and drops a repeated broadcast's copies the same way; strict
//!   802.15.4 (`MM` 2) passes every copy on. Sequence numbers start at random at power-up
//!   (802.15.4's macDSN), one per TX request. Alone (not on a medium) an ideal receiver
//!   acknowledges every such packet: its ACK ends 544 µs after the packet. `EC` and `EA` answer
//!   their counts and reset when set (to 0). The medium's log shows every transmission apart,
//!   retries ([`MacFields::attempt`]) and ACKs ([`FrameKind::Ack`]) included.
//! * **Encryption** (`EE`=1 with the key `KY`; both take effect at once, like `MY`): the S1's
//!   AES-128 encryption without integrity check (802.15.4 security level 4). A packet sent with
//!   it carries [`Security::Encrypted`] (the sender's key, serial and frame counter) beside its
//!   [`Transmission`] ([`XBeeCore::take_transmissions_with_security`]), is on air for the time
//!   of its payload plus the [`SECURITY_HEADER_BYTES`] (5) of the auxiliary security header
//!   (0.16 ms more), and its payload may be at most 95 bytes. A receiver whose `EE` differs
//!   from the sender's passes nothing on ([`XBeeStats::encryption_mismatch`]); one with
//!   another key passes the packet on with its payload garbled: the same length, bytes that
//!   look random, the same for the same keys, payload, sender and frame counter (so seeded runs
//!   reproduce; [`XBeeStats::rx_wrong_key`]); the same key, or no encryption at both ends,
//!   passes it on unchanged. In transparent mode too. A medium delivers with
//!   [`XBeeCore::deliver_secured`] ([`XBeeCore::deliver`] is a packet sent in the clear).
//! * **Repeated broadcasts** (`RR` > 0 in the Digi MAC modes, `MM` 0 and 3): Digi's 802.15.4 S1
//!   product manual, `RR`: "(RR + 2) packets are sent on each broadcast". Each copy goes through
//!   its own channel access once the one before is off the air (the manual gives no spacing; with
//!   [`Csma::Off`] a CCA and a turnaround later), with the request's sequence number and
//!   [`MacFields::attempt`] counting the copies ([`XBeeStats::repeats`]); the TX status follows the
//!   last copy (0x02 if a channel access fails and no `RR` retry is left). Receivers in a Digi mode
//!   pass on the first copy they take and drop the others (duplicate detection), but every copy is
//!   on air: a beacon with `RR` 3 occupies the channel five times as long.
//! * **Output power** (`PL` 0…4, factory 4; Digi's 802.15.4 S1 product manual, `PL`): the S1 sends
//!   at −10, −6, −4, −2, 0 dBm, the S1 Pro at 10, 12, 14, 16, 18 dBm ([`Model`],
//!   [`Model::output_dbm`]). Every packet, ACKs included, carries its power relative to `PL` 4
//!   ([`Transmission::power_db`], [`Model::power_db`]: down to −10 dB on the S1, −8 dB on the Pro),
//!   and a medium adds it to the level the packet has at each receiver: what the receiver reports
//!   as RSSI, whether it is heard at all, and what other radios' CCAs compare with `CA`
//!   ([`crate::medium`]). A medium's `P0` is the level at full power.
//! * **Sleep** (`SM`; Digi's 802.15.4 S1 product manual, sleep modes): a sleeping radio's receiver
//!   is off: it passes on nothing and acknowledges nothing ([`XBeeStats::rx_asleep`],
//!   [`XBeeCore::is_asleep`]). Cyclic sleep (`SM` 4, and 5 with `SLEEP_RQ` high; the reserved 3
//!   taken as one) is taken as asleep throughout, the worst case: the manual has a cyclic sleeper
//!   wake every `SP` to poll a coordinator (none answers in a hoploc network) and sleep again after
//!   `ST` without transmission or reception (Digi's later 802.15.4 manuals: without serial or RF
//!   data), which a node's own traffic might well hold off on a real radio. Its host still reaches
//!   it (the manual has CTS go low at each wake "allowing for communication initiated by the remote
//!   host"; the model wakes it for every byte): AT commands are answered and TX requests sent, as
//!   awake. Pin sleep (`SM` 1 hibernate, 2 doze) sleeps while `SLEEP_RQ` (pin 9) is high
//!   ([`XBeeConfig::sleep_rq`]); the manual: "the module will not respond to either serial or RF
//!   activity while in pin sleep". The Arduino shields the README names leave the pin unconnected,
//!   to the radio's pull-up, so on a node such a radio takes no byte from the firmware from
//!   power-up on ([`XBeeStats::dropped_asleep`]), sends no modem status (the worst case: Digi does
//!   not say whether it goes out before the radio sleeps) and cannot be brought up at all; on an
//!   XBee USB adapter, which drives the pin low, it is awake. `SM` 6 (the manual's sleep
//!   coordinator, kept for older firmware) does not sleep.
//! * **Association** (`A1` bit 2, auto-associate, on an end device, `CE` 0; Digi's 802.15.4 S1
//!   product manual, `A1` and `AI`): the radio looks for a coordinator to associate with and, none
//!   answering in a hoploc network, never associates ([`XBeeCore::is_associating`]): `AI` answers
//!   0x02 (active scan found no PANs), it passes on nothing it hears
//!   ([`XBeeStats::rx_associating`]), and a TX request (API or transparent) puts nothing on air and
//!   gets no status ([`XBeeStats::tx_associating`]): the S1's manual lists no TX status for it
//!   (later 802.15.4 modules answer 0x22, not joined), and none at all is the worst case for a host
//!   that waits for one. The other `A1` bits act only with bit 2.
//! * **Serial receive buffer** ([`DI_BUFFER_BYTES`]: 202 bytes, Digi's 802.15.4 S1 product manual,
//!   "DI buffer"): it holds the API frame being received (without its escape bytes: the radio
//!   unescapes as it decodes), every TX request the MAC has not finished with (a request's frame
//!   stays until its status is decided, the worst case: the manual's data-flow figure puts an RF TX
//!   buffer of no stated size after it), and transparent-mode data not yet sent. AT command frames
//!   are taken at once. A byte that finds it full is lost ([`XBeeStats::di_overflow`]), and the
//!   frame it belonged to with it (a bad frame). The manual's CTS flow control (CTS de-asserted 17
//!   bytes before the buffer is full) is not modelled: the shields the README names do not connect
//!   CTS to the Uno. A host that writes frames faster than the radio sends them (the UART at 57600
//!   fills it slower than a clear channel drains it, so it takes retries or a busy channel) loses
//!   bytes; a hoploc node writes one TX request per slot and its channel changes, and stays under
//!   half of it ([`XBeeStats::di_peak`]; tests/testbed.rs checks every node, the agent whose
//!   unacknowledged reports are retried among them).
//!
//! # Not modelled
//!
//! Of the MAC: the interframe spacing (SIFS/LIFS) after a frame before the radio's next; a CCA
//! compares each packet on air with `CA` alone (energies of overlapping packets are not added up);
//! a CCA failure ends a TX request unless `RR` retries are left (Digi's manuals for later 802.15.4
//! modules retry one three more times, and the S1's mentions CCA failure retries in its Digi mode
//! without saying how many); the XBee retries' own timing (Digi's S1 manual, `RR`: a retry when no
//! ACK came within 200 ms, within a random delay of up to 48 ms; the model starts each at once, as
//! it does a repeated broadcast's next copy); the Digi header's bytes beyond what the best-case
//! figure implies. Of sleep: the timers (`SP`, `ST`, `DP`): a cyclic sleeper never wakes to hear,
//! and sends no polls. Of association: the beacon requests an associating end device's active scans
//! put on air on the channels of `SC`, a coordinator's (`CE` 1) scans at power-up and the `ID` or
//! `CH` that `A2` lets it pick (bring-up leaves `CE` and `A2` alone and sets both after; Digi does
//! not say whether a `CH` set while a coordinator's scan is still under way outlasts it), and
//! indirect messaging (a coordinator with `SP` ≠ 0 holds unicasts for polling end devices). Also
//! not modelled: I/O sampling and remote AT (0x17 frames are counted as unsupported), `ND`/`AS`,
//! non-standard `BD` rates, hardware flow control (CTS, RTS), the serial transmit (DO) buffer's
//! limit, framing error flags on the AVR side (simavr has none: garbage arrives as ordinary bytes).
//! Of encryption: the cipher itself (a hash stands in for AES, so the garbled bytes are not a real
//! radio's), and, as on the real S1, which has neither, no integrity check (CCM* MIC) and no
//! frame-counter replay check.

pub mod core;
mod host_port;
pub mod regs;

use std::collections::VecDeque;

use rand_xoshiro::rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use xbee_api::{Decoder, Mode};

use crate::avr::{ms_to_cycles, Avr, State, UartByte};
use crate::radio::{LineSplitter, SeenFrame, TextLine};

pub use self::core::{
    byte_cycles, encode_frame, frame_air_cycles, time_on_air_ms, Address, Cca, Csma, FrameKind,
    MacFields, RxPacket, Security, Transmission, XBeeConfig, XBeeCore, XBeeStats, ACK_AIR_US,
    ACK_WAIT_US, BACKOFF_PERIOD_US, BIT_TIMES_PER_BYTE, CCA_US, DI_BUFFER_BYTES,
    FRAME_OVERHEAD_BYTES, MAX_BE, MAX_CSMA_BACKOFFS, MAX_FRAME_RETRIES, SECURITY_HEADER_BYTES,
    TURNAROUND_US,
};
pub use self::host_port::{ModelClock, ModelPort};
pub use self::regs::{baud_of_bd, Model, Registers, BAUD_RATES, KEY_LEN};

/// Splits the firmware's raw UART output into text lines, skipping API frames.
#[derive(Debug)]
struct Lines {
    decoder: Decoder,
    text: LineSplitter,
}

impl Lines {
    fn ingest(&mut self, b: UartByte, mode: Mode) {
        if self.decoder.mode() != mode && !self.decoder.in_frame() {
            self.decoder.set_mode(mode);
        }
        let text = !self.decoder.in_frame() && b.byte != xbee_api::START;
        self.text.push(b.cycle, b.byte, text);
        let _ = self.decoder.push(b.byte);
        while self.decoder.poll().is_some() {}
    }
}

/// A modelled XBee on an [`Avr`]'s UART0 (see the module docs). Powered up at cycle 0, with
/// the Avr (a fresh [`Avr`] starts at cycle 0); [`XBee::reset`] power-cycles it.
#[derive(Debug)]
pub struct XBee {
    core: XBeeCore,
    consumed: usize,
    /// Firmware bytes not yet through the UART: (cycle their stop bit ends, byte).
    pending: VecDeque<(u64, u8)>,
    lines: Lines,
    sent: Vec<UartByte>,
    noise: Option<LineNoise>,
}

/// Bit errors on the UART lines between the firmware and the radio (see
/// [`XBee::set_line_errors`]).
#[derive(Debug)]
struct LineNoise {
    rate: f64,
    rng: Xoshiro256PlusPlus,
    flipped: u64,
}

impl LineNoise {
    fn pass(&mut self, byte: u8) -> u8 {
        let u = (self.rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
        if u < self.rate {
            self.flipped += 1;
            byte ^ (1 << (self.rng.next_u64() % 8))
        } else {
            byte
        }
    }
}

impl XBee {
    /// A radio configured by `cfg`, powered up at cycle 0.
    pub fn new(cfg: XBeeConfig) -> Self {
        XBee {
            core: XBeeCore::new(cfg),
            consumed: 0,
            pending: VecDeque::new(),
            lines: Lines {
                decoder: Decoder::new(Mode::Escaped),
                text: LineSplitter::default(),
            },
            sent: Vec::new(),
            noise: None,
        }
    }

    /// Line noise: from now on each byte on either UART line (firmware → radio and radio →
    /// firmware) has one random bit flipped with probability `rate`, from a generator seeded
    /// with `seed` (reproducible). The text lines ([`XBee::text_lines`]) are what the firmware
    /// wrote, [`XBee::sent`] what the radio sent, before the noise. `rate` 0 turns it off.
    pub fn set_line_errors(&mut self, rate: f64, seed: u64) {
        self.noise = (rate > 0.0).then(|| LineNoise {
            rate,
            rng: Xoshiro256PlusPlus::seed_from_u64(seed),
            flipped: 0,
        });
    }

    /// Bytes the line noise has corrupted so far (both directions).
    pub fn line_errors(&self) -> u64 {
        self.noise.as_ref().map_or(0, |n| n.flipped)
    }

    /// The model itself.
    pub fn core(&self) -> &XBeeCore {
        &self.core
    }

    /// The model itself, mutably (e.g. to deliver packets or inspect timers).
    pub fn core_mut(&mut self) -> &mut XBeeCore {
        &mut self.core
    }

    /// Runs `avr` until cycle `target` with the radio attached; returns the core's state (the
    /// run ends early if the core stops).
    pub fn run_until(&mut self, avr: &mut Avr, target: u64) -> State {
        self.pump(avr);
        let mut state = avr.state();
        while avr.cycle() < target && state.is_alive() {
            let now = avr.cycle();
            // Slices of at most one byte time (≥ 16 µs): events land exactly, bytes within a
            // slice of their end.
            let slice = avr.uart_cycles_per_byte().clamp(256, 4000);
            let mut next = target.min(now + slice);
            if let Some(e) = self.core.next_event() {
                next = next.min(e.max(now + 1));
            }
            if let Some(&(end, _)) = self.pending.front() {
                next = next.min(end.max(now + 1));
            }
            state = avr.run_until(next);
            self.pump(avr);
        }
        state
    }

    /// Runs `avr` for `ms` more milliseconds (see [`XBee::run_until`]).
    pub fn run_for_ms(&mut self, avr: &mut Avr, ms: f64) -> State {
        let target = avr.cycle() + ms_to_cycles(ms);
        self.run_until(avr, target)
    }

    /// Moves bytes between the firmware's UART and the model up to the Avr's current cycle.
    fn pump(&mut self, avr: &mut Avr) {
        let cpb = avr.uart_cycles_per_byte();
        self.core.set_host_byte_cycles(cpb);
        let mode = self.core.mode().unwrap_or(Mode::Escaped);
        let out = avr.uart_output();
        if out.len() < self.consumed {
            // Someone took the output: start over on what is there.
            self.consumed = 0;
        }
        for &b in &out[self.consumed..] {
            self.lines.ingest(b, mode);
            self.pending.push_back((b.cycle + cpb, b.byte));
        }
        self.consumed = out.len();
        let now = avr.cycle();
        while let Some(&(end, byte)) = self.pending.front() {
            if end > now {
                break;
            }
            self.pending.pop_front();
            let byte = match &mut self.noise {
                Some(n) => n.pass(byte),
                None => byte,
            };
            self.core.rx_byte(end.max(self.core.now()), byte);
        }
        self.core.advance(now);
        for b in self.core.take_output() {
            let byte = match &mut self.noise {
                Some(n) => n.pass(b.byte),
                None => b.byte,
            };
            avr.uart_send_at(b.cycle, &[byte]);
            self.sent.push(b);
        }
    }

    /// Power-cycles the radio at cycle `at` (see [`XBeeCore::reset`]).
    pub fn reset(&mut self, at: u64) {
        self.core.reset(at);
    }

    /// The active registers.
    pub fn registers(&self) -> &Registers {
        self.core.registers()
    }

    /// The frames the radio decoded from the firmware, with the cycles of their first and last
    /// byte (none while the UART rates do not match).
    pub fn frames_from_firmware(&self) -> &[SeenFrame] {
        self.core.frames_from_host()
    }

    /// The text lines the firmware wrote outside API frames (its boot lines, etc.; the Uno's
    /// USB serial sees them too), from the raw UART output.
    pub fn text_lines(&self) -> &[TextLine] {
        self.lines.text.lines()
    }

    /// The texts of [`XBee::text_lines`].
    pub fn texts(&self) -> Vec<&str> {
        self.text_lines().iter().map(|l| l.text.as_str()).collect()
    }

    /// Every byte the radio put on the firmware's RX line, with its start cycle.
    pub fn sent(&self) -> &[UartByte] {
        &self.sent
    }

    /// Takes the packets the radio put on air so far.
    pub fn take_transmissions(&mut self) -> Vec<Transmission> {
        self.core.take_transmissions()
    }

    /// Takes the packets the radio put on air so far with how each was encrypted (see
    /// [`XBeeCore::take_transmissions_with_security`]).
    pub fn take_transmissions_with_security(&mut self) -> Vec<(Transmission, Security)> {
        self.core.take_transmissions_with_security()
    }

    /// A packet arriving at cycle `at` (see [`XBeeCore::deliver`]).
    pub fn deliver(&mut self, packet: RxPacket, at: u64) {
        self.core.deliver(packet, at);
    }

    /// A packet sent as `security` says arriving at cycle `at` (see
    /// [`XBeeCore::deliver_secured`]).
    pub fn deliver_secured(&mut self, packet: RxPacket, security: Security, at: u64) {
        self.core.deliver_secured(packet, security, at);
    }

    /// The counters.
    pub fn stats(&self) -> XBeeStats {
        self.core.stats()
    }
}
