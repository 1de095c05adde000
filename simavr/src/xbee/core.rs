//! [`XBeeCore`]: the sans-IO model of one XBee 802.15.4 radio. Bytes from the host go in with
//! their cycle; bytes to the host, transmissions and counters come out. See the parent module
//! for what is modelled. Its MAC (channel access, acknowledgements, retries) is in the submodule `mac`.

mod mac;

use xbee_api::{
    encode_raw, AtStatus, DecodeError, Decoder, Frame, Mode, ModemStatus, Rssi, TxStatus, ESCAPE,
    MAX_ENCODED, MAX_RF_PAYLOAD, MAX_RF_PAYLOAD_ENCRYPTED, START,
};

pub use self::mac::{
    frame_air_cycles, Cca, FrameKind, MacFields, ACK_AIR_US, ACK_WAIT_US, BACKOFF_PERIOD_US,
    CCA_US, FRAME_OVERHEAD_BYTES, MAX_BE, MAX_CSMA_BACKOFFS, MAX_FRAME_RETRIES, TURNAROUND_US,
};
use self::mac::{MacLayer, MacTimer};
use super::regs::{self, baud_of_bd, Model, Registers, KEY_LEN, NI_MAX, READ_ONLY};
use crate::avr::{ms_to_cycles, UartByte, F_CPU};
use crate::medium::splitmix;
use crate::radio::SeenFrame;

/// Bit times per 8N1 byte as simavr counts them (it adds a parity bit even when parity is off):
/// the model paces its UART the same way, so its byte time compares like for like with
/// [`crate::Avr::uart_cycles_per_byte`].
pub const BIT_TIMES_PER_BYTE: u64 = 11;

/// Cycles (at [`F_CPU`]) per UART byte at `baud`, counted as simavr does
/// ([`BIT_TIMES_PER_BYTE`]).
pub fn byte_cycles(baud: u32) -> u64 {
    let baud = u64::from(baud.max(1));
    (BIT_TIMES_PER_BYTE * u64::from(F_CPU) + baud / 2) / baud
}

/// Best-case time from a TX request to its packet's end, with a `k`-byte RF payload
/// (`docs/design.md`, section 2): 0.928 + 0.032·k ms, the XBee's figure. That is one clear
/// channel assessment ([`CCA_US`]), the turnaround to transmit ([`TURNAROUND_US`]) and the
/// frame on air ([`frame_air_cycles`]: 0.608 + 0.032·k ms). An encrypted packet counts `k` +
/// [`SECURITY_HEADER_BYTES`] bytes.
pub fn time_on_air_ms(k: usize) -> f64 {
    0.928 + 0.032 * k as f64
}

pub use xbee_api::SECURITY_HEADER_BYTES;

/// The S1's serial receive (DI) buffer, bytes: API frames (or transparent-mode data) from the
/// host that the radio has not finished with. Digi's 802.15.4 S1 product manual: "send messages
/// that are smaller than the DI buffer size (202 bytes)"; without CTS flow control (the shields
/// the README names do not connect CTS) what comes beyond it is lost.
pub const DI_BUFFER_BYTES: usize = 202;

/// Channel access before each transmission (see the parent module's docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Csma {
    /// Best case: no backoff and no clear channel assessment. Every attempt goes on air after
    /// the time a CCA and the turnaround take ([`CCA_US`] + [`TURNAROUND_US`]), whatever is on
    /// the channel: the radio never defers and never reports a CCA failure. Acknowledgements
    /// and retries are modelled all the same.
    #[default]
    Off,
    /// The XBee's channel access, IEEE 802.15.4-2003's unslotted CSMA-CA: a random backoff of
    /// 0…2^BE − 1 periods ([`BACKOFF_PERIOD_US`]), BE starting at `RN`, then a CCA; busy, BE
    /// grows by one (up to [`MAX_BE`]) and it backs off again, up to [`MAX_CSMA_BACKOFFS`]
    /// times, after which the attempt fails (TX status 0x02). Backoffs come from a generator
    /// seeded with `seed` (reproducible). On a medium ([`XBeeCore::set_on_medium`]) the
    /// medium judges each CCA against `CA`; alone, every CCA finds the channel clear.
    Random {
        /// Seed of the backoff generator.
        seed: u64,
    },
}

/// How a model radio starts. [`XBeeConfig::default`] is a factory-fresh S1: transparent mode
/// (`AP=0`) at 9600 baud (`BD=3`), channel 0x0C, PAN 0x3332, `MY=0`, `GT` 1 s, `CT` 10 s.
/// These values are the radio's persisted settings (as if written with `WR`): a power cycle
/// ([`XBeeCore::reset`]) comes back to them, or to what `WR` wrote since.
#[derive(Clone, Debug, PartialEq)]
pub struct XBeeConfig {
    /// S1 or S1 Pro (valid `CH` range).
    pub model: Model,
    /// `AP`: 0 transparent, 1 API, 2 API with escaping.
    pub ap: u8,
    /// `BD`: 0…7 (3 = 9600, 6 = 57600).
    pub bd: u32,
    /// `MY`.
    pub my: u16,
    /// `CH`.
    pub ch: u8,
    /// `ID` (PAN id).
    pub id: u16,
    /// `SH:SL`, the radio's 64-bit serial number / address.
    pub sh_sl: u64,
    /// `GT` in ms. Values below the S1's minimum of 2 are accepted here (fast tests).
    pub gt_ms: u16,
    /// `CT` in units of 100 ms.
    pub ct: u16,
    /// `NI`.
    pub ni: String,
    /// `EE`: AES encryption on.
    pub ee: bool,
    /// `KY`: the AES-128 key.
    pub ky: [u8; KEY_LEN],
    /// `RN`: the minimum backoff exponent of the CSMA-CA (factory 0: no backoff before the
    /// first CCA).
    pub rn: u8,
    /// `CA`: the CCA threshold, −dBm (factory 0x2C: −44 dBm).
    pub ca: u8,
    /// `RR`: XBee retries on top of the MAC's, and `RR` + 2 copies of each broadcast when above
    /// 0 (factory 0).
    pub rr: u8,
    /// `MM`: MAC mode (factory 0: Digi mode, with ACKs and duplicate detection).
    pub mm: u8,
    /// `VR`, firmware version.
    pub vr: u16,
    /// `HV`, hardware version.
    pub hv: u16,
    /// From power-up (or reset) until the radio listens and sends its modem status.
    pub power_up_ms: f64,
    /// From the end of a command (frame or `\r`) to the start of its response.
    pub at_latency_ms: f64,
    /// From the end of a received packet to the start of its RX frame.
    pub rx_latency_ms: f64,
    /// Channel access before each transmission.
    pub csma: Csma,
    /// Relative difference of the two sides' byte times beyond which the UARTs do not
    /// understand each other (a real UART tolerates a few %).
    pub baud_tolerance: f64,
    /// From the end of an API `AT CH` frame that sets the channel to its answer: the switch.
    /// The radio hears nothing meanwhile, and a transmit request that reaches it before the
    /// answer is lost (no packet, no status). Default: [`xbee_api::CHANNEL_SWITCH_US`], the worst
    /// case the nodes plan for.
    pub channel_switch_ms: f64,
    /// Any other registers as a previous owner left them (a second-hand radio): `(command,
    /// value)`, persisted, applied after the fields above.
    pub leftovers: Vec<([u8; 2], u32)>,
    /// The level of the radio's `SLEEP_RQ` input (pin 9): high (asserted) on an Arduino XBee
    /// shield, which leaves the pin to the radio's own pull-up (`PR`'s factory value enables
    /// it), so a radio in a pin sleep mode (`SM` 1, 2) sleeps; low on an XBee USB adapter, whose
    /// serial chip drives the pin (DTR) low while the port is open.
    pub sleep_rq: bool,
}

impl Default for XBeeConfig {
    fn default() -> Self {
        XBeeConfig {
            model: Model::S1,
            ap: 0,
            bd: 3,
            my: 0,
            ch: 0x0C,
            id: 0x3332,
            sh_sl: 0x0013_A200_40A1_B2C3,
            gt_ms: 1000,
            ct: 0x64,
            ni: String::new(),
            ee: false,
            ky: [0; KEY_LEN],
            rn: 0,
            ca: 0x2C,
            rr: 0,
            mm: 0,
            vr: 0x10EF,
            hv: 0x180B,
            power_up_ms: 5.0,
            at_latency_ms: 1.0,
            rx_latency_ms: 0.2,
            csma: Csma::Off,
            baud_tolerance: 0.04,
            channel_switch_ms: xbee_api::CHANNEL_SWITCH_US as f64 / 1000.0,
            leftovers: Vec::new(),
            sleep_rq: true,
        }
    }
}

impl XBeeConfig {
    /// A radio as the testbed runs it: API mode `ap` (1 or 2) at 57600 baud (`BD=6`).
    pub fn api(ap: u8) -> Self {
        XBeeConfig {
            ap,
            bd: 6,
            ..XBeeConfig::default()
        }
    }

    /// The register set this configuration persists.
    pub fn registers(&self) -> Registers {
        let mut r = Registers::factory();
        r.set_unchecked(*b"AP", u32::from(self.ap));
        r.set_unchecked(*b"BD", self.bd);
        r.set_unchecked(*b"MY", u32::from(self.my));
        r.set_unchecked(*b"CH", u32::from(self.ch));
        r.set_unchecked(*b"ID", u32::from(self.id));
        r.set_unchecked(*b"GT", u32::from(self.gt_ms.max(1)));
        r.set_unchecked(*b"CT", u32::from(self.ct));
        r.set_ni(self.ni.as_bytes());
        r.set_unchecked(*b"EE", u32::from(self.ee));
        r.set_ky(self.ky);
        r.set_unchecked(*b"RN", u32::from(self.rn));
        r.set_unchecked(*b"CA", u32::from(self.ca));
        r.set_unchecked(*b"RR", u32::from(self.rr));
        r.set_unchecked(*b"MM", u32::from(self.mm));
        for &(cmd, v) in &self.leftovers {
            r.set_unchecked(cmd, v);
        }
        r
    }
}

/// An 802.15.4 address.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Address {
    /// 16-bit short address (0xFFFF: broadcast).
    Short(u16),
    /// 64-bit extended address (0x000000000000FFFF: broadcast).
    Long(u64),
}

impl Address {
    /// True for the broadcast address of either size.
    pub fn is_broadcast(self) -> bool {
        matches!(self, Address::Short(0xFFFF) | Address::Long(0xFFFF))
    }
}

/// How a packet went on air: in the clear (`EE`=0) or encrypted (`EE`=1) with the sender's key.
/// A radio medium hands it to the receivers with the packet ([`XBeeCore::deliver_secured`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Security {
    /// `EE`=0.
    #[default]
    Clear,
    /// `EE`=1.
    Encrypted {
        /// The sender's `KY`.
        key: [u8; KEY_LEN],
        /// The sender's 64-bit serial (`SH:SL`): with `counter`, the packet's nonce.
        source64: u64,
        /// The sender's frame counter: its encrypted packets since it powered up.
        counter: u32,
    },
}

impl Security {
    /// The bytes it adds on air: [`SECURITY_HEADER_BYTES`] when encrypted, else 0.
    pub fn overhead(self) -> usize {
        match self {
            Security::Clear => 0,
            Security::Encrypted { .. } => SECURITY_HEADER_BYTES,
        }
    }
}

/// XORs `buf` with the keystream of `key` for the packet `source64`/`counter`: what AES-CTR
/// (802.15.4 security level 4) does with the key's block cipher, here with a SplitMix64 hash of
/// the key, the nonce and the block index in place of AES (the bytes differ from a real radio's;
/// what matters is that they are the same for the same inputs and look random). Applying it
/// twice with the same key gives the payload back, so a receiver with another key turns the
/// ciphertext into the payload XOR both keystreams: garbage of the payload's length.
fn keystream_xor(buf: &mut [u8], key: &[u8; KEY_LEN], source64: u64, counter: u32) {
    let word = |b: &[u8]| b.iter().fold(0u64, |v, &x| (v << 8) | u64::from(x));
    let k = splitmix(splitmix(word(&key[..8])) ^ word(&key[8..]));
    let nonce = splitmix(splitmix(k ^ source64) ^ u64::from(counter));
    for (i, block) in buf.chunks_mut(8).enumerate() {
        let ks = splitmix(nonce ^ i as u64).to_le_bytes();
        for (b, s) in block.iter_mut().zip(ks) {
            *b ^= s;
        }
    }
}

/// A packet the radio put on air, for a radio medium to deliver: a data frame, or an ACK
/// ([`MacFields::kind`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Transmission {
    /// `CH` it went out on.
    pub channel: u8,
    /// PAN id (`ID`) of the sender.
    pub pan_id: u16,
    /// Source address: `MY`, or the 64-bit serial when `MY` is 0xFFFE/0xFFFF (an ACK carries no
    /// address on air: this is the acknowledging radio's, for the log).
    pub source: Address,
    /// The sender's 64-bit serial (`SH:SL`).
    pub source64: u64,
    /// Destination (an ACK: the source of the frame it acknowledges, for the log).
    pub dest: Address,
    /// TX options (0x01 no ACK, 0x04 broadcast PAN).
    pub options: u8,
    /// RF payload (≤ 100 bytes, ≤ 95 encrypted), as the sender's host gave it (the plaintext;
    /// empty for an ACK).
    pub payload: Vec<u8>,
    /// First cycle on air (after the CCA and the turnaround: [`time_on_air_ms`] counts those
    /// from the request).
    pub start_cycle: u64,
    /// Cycle it is off the air: [`frame_air_cycles`] after the start, of the payload and, when
    /// encrypted, [`SECURITY_HEADER_BYTES`]; [`ACK_AIR_US`] for an ACK.
    pub end_cycle: u64,
    /// Frame id of the API request (0: none, or transparent mode).
    pub frame_id: u8,
    /// What the MAC put in it: data or ACK, sequence number, ACK request, which attempt.
    pub mac: MacFields,
    /// The sender's output power relative to the factory power level (`PL` = 4), dB (≤ 0,
    /// [`Model::power_db`]): a medium adds it to the level the packet has at each receiver.
    pub power_db: i8,
}

impl Transmission {
    /// The 16-bit source address, if the packet carries one.
    pub fn source16(&self) -> Option<u16> {
        match self.source {
            Address::Short(a) => Some(a),
            Address::Long(_) => None,
        }
    }
}

/// A packet arriving at the radio (from a medium, or a test).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RxPacket {
    /// Channel it was sent on.
    pub channel: u8,
    /// PAN id it was sent with.
    pub pan_id: u16,
    /// Sender's address: a short source gives an RX16 (0x81) frame, a long one RX64 (0x80).
    pub source: Address,
    /// Destination address.
    pub dest: Address,
    /// TX options it was sent with (0x04: broadcast PAN).
    pub options: u8,
    /// Received level in dBm (≤ 0).
    pub rssi_dbm: i16,
    /// RF payload.
    pub payload: Vec<u8>,
}

impl RxPacket {
    /// A packet broadcast from 16-bit address `source` on `channel` in PAN `pan_id`.
    pub fn broadcast16(
        channel: u8,
        pan_id: u16,
        source: u16,
        rssi_dbm: i16,
        payload: &[u8],
    ) -> Self {
        RxPacket {
            channel,
            pan_id,
            source: Address::Short(source),
            dest: Address::Short(0xFFFF),
            options: 0,
            rssi_dbm,
            payload: payload.to_vec(),
        }
    }

    /// What a receiver hears of `tx` at level `rssi_dbm`.
    pub fn from_transmission(tx: &Transmission, rssi_dbm: i16) -> Self {
        RxPacket {
            channel: tx.channel,
            pan_id: tx.pan_id,
            source: tx.source,
            dest: tx.dest,
            options: tx.options,
            rssi_dbm,
            payload: tx.payload.clone(),
        }
    }
}

/// Counters of a model radio. Bytes are counted as the radio's UART saw them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct XBeeStats {
    /// Good API frames from the host.
    pub frames_ok: u32,
    /// API frames from the host with a bad checksum.
    pub checksum_errors: u32,
    /// API frames from the host with a bad length or cut short.
    pub bad_frames: u32,
    /// Bytes outside API frames in API mode (text lines, `+++`, garbage).
    pub foreign_bytes: u32,
    /// Frames of types the model does not act on (remote AT, RX types…), or too short.
    pub unsupported_frames: u32,
    /// AT commands handled (API frames and command-mode commands).
    pub at_commands: u32,
    /// Host bytes received while the UART rates did not match (garbled or lost).
    pub garbled_in: u32,
    /// Bytes sent to the host while the UART rates did not match (garbled or lost).
    pub garbled_out: u32,
    /// Host bytes lost while the radio was powering up.
    pub dropped_powering_up: u32,
    /// TX requests refused for a payload over [`XBeeCore::max_payload`] (100 bytes, 95 with
    /// encryption).
    pub oversize_tx: u32,
    /// Data packets put on air (retries included; ACKs apart, in `acks_sent`).
    pub transmissions: u32,
    /// Transmissions that repeated an unacknowledged packet (MAC and XBee retries; a repeated
    /// broadcast's copies are in `repeats`).
    pub retries: u32,
    /// Clear channel assessments that found the channel busy.
    pub cca_busy: u32,
    /// Channel access failures: [`MAX_CSMA_BACKOFFS`] + 1 busy CCAs in a row (as `EC` counts
    /// them).
    pub cca_failures: u32,
    /// Unicasts that got no ACK after every retry (as `EA` counts them).
    pub ack_failures: u32,
    /// ACKs this radio sent.
    pub acks_sent: u32,
    /// ACKs this radio took for its own packets.
    pub acks_received: u32,
    /// Packets passed to the host.
    pub rx_delivered: u32,
    /// Packets not for this radio (other channel, PAN or address, or not powered up).
    pub rx_filtered: u32,
    /// Packets for this radio that it lost (arrived while it was transmitting, or in command
    /// mode), ACKs it waited for among them.
    pub rx_lost: u32,
    /// Retried packets it acknowledged again but did not pass on (duplicate detection).
    pub rx_duplicates: u32,
    /// Packets for this radio that it did not pass on because its `EE` differs from the
    /// sender's (encrypted at one end only).
    pub encryption_mismatch: u32,
    /// Packets passed to the host garbled: both ends encrypt, with different keys (also in
    /// `rx_delivered`; the model knows it, a real radio cannot tell).
    pub rx_wrong_key: u32,
    /// Packets on air while the radio switched channel (lost: it heard nothing).
    pub rx_switching: u32,
    /// Transmit requests that reached the radio while it switched channel (lost: nothing sent,
    /// no status).
    pub tx_lost_switching: u32,
    /// Packets for this radio (its channel, PAN and address) on air while it slept (`SM` 1…5):
    /// its receiver was off.
    pub rx_asleep: u32,
    /// Host bytes lost in pin sleep (`SM` 1, 2 with `SLEEP_RQ` high): the radio takes nothing
    /// from its UART.
    pub dropped_asleep: u32,
    /// Packets for this radio that it did not pass on while it looked for a coordinator to
    /// associate with (`A1` bit 2 on an end device).
    pub rx_associating: u32,
    /// Transmit requests dropped while it looked for a coordinator (no packet, no status).
    pub tx_associating: u32,
    /// Repeated copies of a broadcast put on air (`RR` > 0: `RR` + 2 copies in all; also in
    /// `transmissions`).
    pub repeats: u32,
    /// Host bytes lost because the serial receive buffer ([`DI_BUFFER_BYTES`]) was full.
    pub di_overflow: u32,
    /// The most bytes the serial receive buffer held.
    pub di_peak: u32,
}

#[derive(Debug)]
enum Event {
    /// Power-up finished: listen, send the modem status.
    Ready(ModemStatus),
    /// Put bytes on the UART TX line.
    Output(Vec<u8>),
    /// Switch the UART to a new rate.
    ApplyBaud(u32),
    /// A MAC timer of MAC phase generation `u64`.
    Mac(MacTimer, u64),
    /// A TX status frame for frame id `u8`.
    TxStatus(u8, TxStatus),
    /// An ACK arrives (its end).
    AckIn {
        /// The sequence number it acknowledges.
        seq: u8,
        /// Its channel.
        channel: u8,
        /// Its first cycle on air.
        start: u64,
    },
    /// `GT` after a command-sequence character: did the sequence complete?
    PlusCheck(u64),
    /// `CT` after the last command-mode command.
    CmdTimeout(u64),
    /// `RO` character times after the last transparent-mode byte.
    RoFlush(u64),
    /// `FR`: reset after the response.
    SoftReset,
    /// A packet arrives.
    Deliver(Box<Arrival>),
}

/// A data packet arriving at the radio.
#[derive(Debug)]
struct Arrival {
    packet: RxPacket,
    security: Security,
    /// Its first cycle on air.
    start: u64,
    /// The cycle it ended: its ACK goes on air a turnaround later, whenever the radio gets to
    /// handle it (a firmware node's radio may have run ahead of the medium by then).
    end: u64,
    /// Its MAC sequence number (`None`: handed over without a MAC, by
    /// [`XBeeCore::deliver_secured`]: no ACK, no duplicate detection).
    seq: Option<u8>,
    /// Whether it asks for an ACK.
    ack_request: bool,
}

/// What an AT command answered: OK with a value (empty for sets), or an error.
type AtResult = Result<AtValue, AtStatus>;

#[derive(Debug)]
enum AtValue {
    None,
    Num(u64, u8),
    Str(Vec<u8>),
}

impl AtValue {
    fn api_bytes(&self) -> Vec<u8> {
        match self {
            AtValue::None => Vec::new(),
            AtValue::Num(v, w) => v.to_be_bytes()[8 - *w as usize..].to_vec(),
            AtValue::Str(s) => s.clone(),
        }
    }

    fn text(&self) -> Vec<u8> {
        match self {
            AtValue::None => b"OK\r".to_vec(),
            AtValue::Num(v, _) => format!("{v:X}\r").into_bytes(),
            AtValue::Str(s) => {
                let mut t = s.clone();
                t.push(b'\r');
                t
            }
        }
    }
}

/// A command's parameter: from an API frame (binary, big endian) or a command-mode line (hex
/// text, or the string for `NI`).
#[derive(Clone, Copy)]
enum Param<'a> {
    Binary(&'a [u8]),
    Text(&'a [u8]),
}

impl Param<'_> {
    fn is_empty(&self) -> bool {
        match self {
            Param::Binary(b) | Param::Text(b) => b.is_empty(),
        }
    }

    fn string(&self) -> Vec<u8> {
        match *self {
            Param::Binary(b) => b.to_vec(),
            Param::Text(t) => t
                .iter()
                .copied()
                .skip_while(|&c| c == b' ')
                .collect::<Vec<_>>(),
        }
    }

    /// A 128-bit value (`KY`), if well formed: up to 16 bytes (API) or 32 hex digits (command
    /// mode; optional `0x`, spaces ignored) after leading zeros, right-aligned as a number.
    fn key(&self) -> Option<[u8; KEY_LEN]> {
        let bytes: Vec<u8> = match *self {
            Param::Binary(b) => b.to_vec(),
            Param::Text(t) => {
                let s: Vec<u8> = t.iter().copied().filter(|&c| c != b' ').collect();
                let s = match s.as_slice() {
                    [b'0', b'x' | b'X', rest @ ..] => rest,
                    other => other,
                };
                if s.is_empty() || !s.iter().all(u8::is_ascii_hexdigit) {
                    return None;
                }
                // Hex digits to bytes from the right: an odd count leaves a high nibble of 0.
                let digits: Vec<u8> = s
                    .iter()
                    .map(|&c| (c as char).to_digit(16).unwrap_or(0) as u8)
                    .collect();
                let mut bytes: Vec<u8> = digits
                    .rchunks(2)
                    .map(|p| p.iter().fold(0u8, |v, &d| (v << 4) | d))
                    .collect();
                bytes.reverse();
                bytes
            }
        };
        let first = bytes.iter().position(|&x| x != 0).unwrap_or(bytes.len());
        let sig = &bytes[first..];
        (sig.len() <= KEY_LEN).then(|| {
            let mut key = [0; KEY_LEN];
            key[KEY_LEN - sig.len()..].copy_from_slice(sig);
            key
        })
    }

    /// The number, if well formed (≤ 32 bits).
    fn number(&self) -> Option<u32> {
        match *self {
            Param::Binary(b) => {
                let first = b.iter().position(|&x| x != 0).unwrap_or(b.len());
                let sig = &b[first..];
                (sig.len() <= 4).then(|| sig.iter().fold(0u32, |v, &x| (v << 8) | u32::from(x)))
            }
            Param::Text(t) => {
                let s: Vec<u8> = t.iter().copied().filter(|&c| c != b' ').collect();
                let s = match s.as_slice() {
                    [b'0', b'x' | b'X', rest @ ..] => rest,
                    other => other,
                };
                if s.is_empty() || s.len() > 8 {
                    return None;
                }
                u32::from_str_radix(std::str::from_utf8(s).ok()?, 16).ok()
            }
        }
    }
}

/// Which side's rate makes the other see garbage, and how many bytes get through.
#[derive(Debug, Default)]
struct Garbler {
    acc: f64,
}

impl Garbler {
    /// A byte sent with byte time `tx` read by a UART with byte time `rx`: `None` if lost,
    /// else the garbage it reads. A slower receiver sees about one byte per its own byte time
    /// (the rest run into its frames); a faster one reads one (wrong) byte per start bit.
    fn garble(&mut self, byte: u8, tx: u64, rx: u64) -> Option<u8> {
        self.acc += (tx as f64 / rx as f64).min(1.0);
        if self.acc < 1.0 {
            return None;
        }
        self.acc -= 1.0;
        // 0xF0…0xFF: never a start delimiter, escape, XON/XOFF, '+', 'O', 'K' or '\r'.
        Some(0xF0 | ((byte >> 4) ^ byte ^ 0x05) & 0x0F)
    }
}

/// The model radio, without IO: see the parent module's docs.
#[derive(Debug)]
pub struct XBeeCore {
    cfg: XBeeConfig,
    persisted: Registers,
    active: Registers,
    /// Applied state: what the hardware does now.
    uart_baud: u32,
    api: Option<Mode>,
    channel: u8,
    decoder: Decoder,
    host_cpb: Option<u64>,
    now: u64,
    ready: bool,
    /// Until this cycle the radio switches channel (an API `AT CH`): deaf, and transmit
    /// requests are lost.
    switching_until: u64,
    /// End of the last byte received.
    last_rx_end: u64,
    /// Bumped on every byte received (timers check it to see whether the line stayed quiet).
    activity: u64,
    plus_count: u8,
    /// Command-sequence characters held back in transparent mode.
    held: Vec<u8>,
    cmd_line: Option<Vec<u8>>,
    cmd_gen: u64,
    queued: Vec<([u8; 2], Vec<u8>)>,
    /// `AC` was executed: apply once its response is scheduled.
    apply_requested: bool,
    events: Vec<(u64, u64, Event)>,
    seq: u64,
    tx_line_free: u64,
    garble_in: Garbler,
    garble_out: Garbler,
    outbox: Vec<UartByte>,
    transmissions: Vec<Transmission>,
    /// How each of `transmissions` went on air.
    securities: Vec<Security>,
    /// Encrypted packets sent since power-up (the 802.15.4 frame counter).
    frame_counter: u32,
    /// Recent intervals the radio was switching to transmit or transmitting (half duplex: no
    /// reception, and its own CCAs busy, meanwhile).
    on_air: Vec<(u64, u64)>,
    mac: MacLayer,
    frames: Vec<SeenFrame>,
    frame_start: u64,
    /// Bytes of the API frame being received (in the serial receive buffer).
    frame_bytes: usize,
    tbuf: Vec<u8>,
    rng: u64,
    db: u8,
    stats: XBeeStats,
}

impl XBeeCore {
    /// A radio powered up at cycle 0 (it listens, and in API mode sends its modem status,
    /// [`XBeeConfig::power_up_ms`] later).
    pub fn new(cfg: XBeeConfig) -> Self {
        Self::new_at(cfg, 0)
    }

    /// A radio powered up at cycle `at`.
    pub fn new_at(cfg: XBeeConfig, at: u64) -> Self {
        let persisted = cfg.registers();
        // The radio's own stream (its serial), varied by the seed: never 0 (xorshift).
        let rng = match cfg.csma {
            Csma::Random { seed } => splitmix(seed ^ splitmix(cfg.sh_sl)) | 1,
            Csma::Off => splitmix(cfg.sh_sl) | 1,
        };
        let mut me = XBeeCore {
            active: persisted.clone(),
            persisted,
            uart_baud: 9600,
            api: None,
            channel: cfg.ch,
            decoder: Decoder::new(Mode::Escaped),
            host_cpb: None,
            now: at,
            ready: false,
            switching_until: 0,
            last_rx_end: at,
            activity: 0,
            plus_count: 0,
            held: Vec::new(),
            cmd_line: None,
            cmd_gen: 0,
            queued: Vec::new(),
            apply_requested: false,
            events: Vec::new(),
            seq: 0,
            tx_line_free: at,
            garble_in: Garbler::default(),
            garble_out: Garbler::default(),
            outbox: Vec::new(),
            transmissions: Vec::new(),
            securities: Vec::new(),
            frame_counter: 0,
            on_air: Vec::new(),
            mac: MacLayer::default(),
            frames: Vec::new(),
            frame_start: at,
            frame_bytes: 0,
            tbuf: Vec::new(),
            rng,
            db: 0,
            stats: XBeeStats::default(),
            cfg,
        };
        me.power_up(at, ModemStatus::HARDWARE_RESET);
        me
    }

    /// Power cycle at `at` (not earlier than [`XBeeCore::now`]): the active registers go back
    /// to the persisted ones (what `WR` last wrote), command mode, queued commands, partial
    /// frames and pending output are dropped, and the radio powers up again.
    pub fn reset(&mut self, at: u64) {
        self.advance(at);
        self.power_up(self.now, ModemStatus::HARDWARE_RESET);
    }

    fn power_up(&mut self, at: u64, status: ModemStatus) {
        self.now = self.now.max(at);
        self.active = self.persisted.clone();
        self.ready = false;
        self.events.clear();
        self.cmd_line = None;
        self.cmd_gen += 1;
        self.queued.clear();
        self.apply_requested = false;
        self.plus_count = 0;
        self.held.clear();
        self.tbuf.clear();
        self.frame_counter = 0;
        let dsn = self.next_rand() as u8;
        self.mac.power_up(dsn);
        self.last_rx_end = self.now;
        self.uart_baud = self.active.baud();
        self.api = Mode::from_ap(self.active.ap());
        self.decoder = Decoder::new(self.api.unwrap_or(Mode::Escaped));
        self.frame_bytes = 0;
        self.channel = self.active.ch();
        self.garble_in = Garbler::default();
        self.garble_out = Garbler::default();
        let ready = self.now + ms_to_cycles(self.cfg.power_up_ms);
        self.schedule(ready, Event::Ready(status));
    }

    // ---- inspection ----

    /// The configuration it was made with.
    pub fn config(&self) -> &XBeeConfig {
        &self.cfg
    }
    /// The active registers (what AT queries answer).
    pub fn registers(&self) -> &Registers {
        &self.active
    }
    /// The active registers, mutably: a register set as if by the host, without its range
    /// check and without applying `CH`, `AP` or `BD` (tests: a radio whose settings a firmware
    /// did not fix).
    pub fn registers_mut(&mut self) -> &mut Registers {
        &mut self.active
    }
    /// The persisted registers (what `WR` wrote; a power cycle restores them).
    pub fn persisted(&self) -> &Registers {
        &self.persisted
    }
    /// True while the radio sleeps (`SM` 1…5; 1 and 2 only with `SLEEP_RQ` high, see
    /// [`XBeeConfig::sleep_rq`]): its receiver is off. In pin sleep (`SM` 1, 2) its UART takes
    /// nothing either.
    pub fn is_asleep(&self) -> bool {
        self.asleep()
    }
    /// True while the radio looks for a coordinator to associate with (`A1` bit 2 on an end
    /// device, `CE` 0): it neither sends nor passes on what it hears.
    pub fn is_associating(&self) -> bool {
        self.associating()
    }
    /// The channel the radio is on (applied `CH`).
    pub fn channel(&self) -> u8 {
        self.channel
    }
    /// The API mode in use (`None`: transparent).
    pub fn mode(&self) -> Option<Mode> {
        self.api
    }
    /// The UART rate in use (applied `BD`).
    pub fn uart_baud(&self) -> u32 {
        self.uart_baud
    }
    /// The radio's UART byte time in cycles ([`byte_cycles`] of [`XBeeCore::uart_baud`]).
    pub fn uart_byte_cycles(&self) -> u64 {
        byte_cycles(self.uart_baud)
    }
    /// True while in command mode.
    pub fn in_command_mode(&self) -> bool {
        self.cmd_line.is_some()
    }
    /// True once powered up (listening).
    pub fn is_ready(&self) -> bool {
        self.ready
    }
    /// True if the host's UART rate (as last told) is within tolerance of the radio's.
    pub fn baud_matches(&self) -> bool {
        let own = self.uart_byte_cycles();
        !self.mismatch(self.host_cpb.unwrap_or(own), own)
    }
    /// Last RSSI (`DB`), magnitude in −dBm.
    pub fn last_rssi(&self) -> u8 {
        self.db
    }
    /// Every good API frame received from the host, with its cycles.
    pub fn frames_from_host(&self) -> &[SeenFrame] {
        &self.frames
    }
    /// Packets put on air and not yet taken.
    pub fn transmissions(&self) -> &[Transmission] {
        &self.transmissions
    }
    /// Takes the packets put on air so far.
    pub fn take_transmissions(&mut self) -> Vec<Transmission> {
        self.securities.clear();
        std::mem::take(&mut self.transmissions)
    }
    /// Takes the packets put on air so far, each with how it was encrypted (what a medium
    /// passes to [`XBeeCore::deliver_secured`]).
    pub fn take_transmissions_with_security(&mut self) -> Vec<(Transmission, Security)> {
        let securities = std::mem::take(&mut self.securities);
        std::mem::take(&mut self.transmissions)
            .into_iter()
            .zip(securities)
            .collect()
    }
    /// The most RF payload a TX request may carry now: 100 bytes, 95 with encryption (`EE`=1).
    pub fn max_payload(&self) -> usize {
        if self.active.ee() {
            MAX_RF_PAYLOAD_ENCRYPTED
        } else {
            MAX_RF_PAYLOAD
        }
    }
    /// The counters.
    pub fn stats(&self) -> XBeeStats {
        self.stats
    }
    /// The model's time (cycle of the last input or [`XBeeCore::advance`]).
    pub fn now(&self) -> u64 {
        self.now
    }
    /// The cycle of the next internal event (a response due, a timer), if any: advance to it
    /// to have outputs at their exact times.
    pub fn next_event(&self) -> Option<u64> {
        self.events.iter().map(|e| e.0).min()
    }

    // ---- input ----

    /// Tells the model the host UART's byte time in cycles (as simavr counts it, see
    /// [`BIT_TIMES_PER_BYTE`]). Until it is told, the model assumes the rates match.
    pub fn set_host_byte_cycles(&mut self, cycles: u64) {
        self.host_cpb = Some(cycles.max(1));
    }

    /// [`XBeeCore::set_host_byte_cycles`] for a host at `baud`.
    pub fn set_host_baud(&mut self, baud: u32) {
        self.set_host_byte_cycles(byte_cycles(baud));
    }

    /// A byte from the host whose stop bit ended at cycle `end` (not before [`XBeeCore::now`]).
    pub fn rx_byte(&mut self, end: u64, byte: u8) {
        self.advance(end);
        let t = self.now;
        if !self.ready {
            self.stats.dropped_powering_up += 1;
            return;
        }
        if self.pin_asleep() {
            self.stats.dropped_asleep += 1;
            return;
        }
        let own = self.uart_byte_cycles();
        let host = self.host_cpb.unwrap_or(own);
        let byte = if self.mismatch(host, own) {
            self.stats.garbled_in += 1;
            match self.garble_in.garble(byte, host, own) {
                Some(g) => g,
                None => {
                    // Still line activity: it breaks guard times.
                    self.last_rx_end = t;
                    self.activity += 1;
                    self.plus_count = 0;
                    return;
                }
            }
        } else {
            byte
        };
        self.handle_byte(t, byte, own);
        self.advance(t);
    }

    /// Bytes from the host sent back to back from cycle `start` at the host's rate; returns
    /// the cycle the last one ended.
    pub fn rx_bytes(&mut self, start: u64, bytes: &[u8]) -> u64 {
        let cpb = self.host_cpb.unwrap_or_else(|| self.uart_byte_cycles());
        let mut end = start;
        for &b in bytes {
            end += cpb;
            self.rx_byte(end, b);
        }
        end
    }

    /// A packet sent in the clear arriving at cycle `at` (its end): see
    /// [`XBeeCore::deliver_secured`].
    pub fn deliver(&mut self, packet: RxPacket, at: u64) {
        self.deliver_secured(packet, Security::Clear, at);
    }

    /// A packet sent as `security` says arriving at cycle `at` (its end). It reaches the host
    /// only if the radio is powered up, on `packet.channel`, in its PAN (or the packet used the
    /// broadcast PAN), addressed to it or broadcast, not transmitting while it arrived, not in
    /// command mode, and its `EE` is the sender's: in API mode as an RX16/RX64 frame with the
    /// RSSI byte, in transparent mode as the bare payload. `DB` takes its RSSI. Encrypted with
    /// another key than this radio's `KY`, the payload comes out garbled (see
    /// [`XBeeCore::stats`]: `rx_wrong_key`). It asks for no ACK (a medium hands over data
    /// frames with [`XBeeCore::receive`]).
    pub fn deliver_secured(&mut self, packet: RxPacket, security: Security, at: u64) {
        let air = frame_air_cycles(packet.payload.len() + security.overhead());
        let arrival = Arrival {
            packet,
            security,
            start: at.saturating_sub(air),
            end: at,
            seq: None,
            ack_request: false,
        };
        let at = at.max(self.now);
        self.schedule(at, Event::Deliver(Box::new(arrival)));
    }

    /// A packet another radio put on air, `tx` (its cycles in this radio's time base), arriving
    /// at its end at level `rssi_dbm`, sent as `security` says: what a medium hands over. A
    /// data frame goes as [`XBeeCore::deliver_secured`] says, and when it asks for an ACK and
    /// reaches this radio's host (or is a retry of one that did) the radio acknowledges it
    /// ([`ACK_AIR_US`] on air, [`TURNAROUND_US`] after its end). An ACK ends this radio's wait
    /// for one if it acknowledges the sequence number of the packet it waits for, on its
    /// channel, and it was not transmitting meanwhile.
    pub fn receive(&mut self, tx: &Transmission, rssi_dbm: i16, security: Security) {
        let at = tx.end_cycle.max(self.now);
        let ev = match tx.mac.kind {
            FrameKind::Data => Event::Deliver(Box::new(Arrival {
                packet: RxPacket::from_transmission(tx, rssi_dbm),
                security,
                start: tx.start_cycle,
                end: tx.end_cycle,
                seq: Some(tx.mac.seq),
                ack_request: tx.mac.ack_request,
            })),
            FrameKind::Ack => Event::AckIn {
                seq: tx.mac.seq,
                channel: tx.channel,
                start: tx.start_cycle,
            },
        };
        self.schedule(at, ev);
    }

    /// Runs the model's timers up to cycle `now`.
    pub fn advance(&mut self, now: u64) {
        while let Some(i) = self.due(now) {
            let (t, _, ev) = self.events.swap_remove(i);
            self.now = self.now.max(t);
            self.handle(ev);
        }
        self.now = self.now.max(now);
    }

    /// Takes the bytes put on the UART TX line so far, each with the cycle its start bit goes
    /// out (paced at the radio's rate). With mismatched rates these are what the host reads:
    /// garbage, fewer bytes.
    pub fn take_output(&mut self) -> Vec<UartByte> {
        std::mem::take(&mut self.outbox)
    }

    // ---- internals ----

    fn due(&self, now: u64) -> Option<usize> {
        self.events
            .iter()
            .enumerate()
            .filter(|(_, e)| e.0 <= now)
            .min_by_key(|(_, e)| (e.0, e.1))
            .map(|(i, _)| i)
    }

    fn schedule(&mut self, at: u64, ev: Event) {
        self.seq += 1;
        self.events.push((at.max(self.now), self.seq, ev));
    }

    /// See [`XBeeCore::is_asleep`].
    fn asleep(&self) -> bool {
        match self.active.sm() {
            1 | 2 => self.cfg.sleep_rq,
            3..=5 => true,
            _ => false,
        }
    }

    /// Pin sleep: `SM` 1 or 2 with `SLEEP_RQ` high.
    fn pin_asleep(&self) -> bool {
        matches!(self.active.sm(), 1 | 2) && self.cfg.sleep_rq
    }

    /// See [`XBeeCore::is_associating`].
    fn associating(&self) -> bool {
        self.active.a1() & 0x04 != 0 && self.active.ce() == 0
    }

    fn mismatch(&self, a: u64, b: u64) -> bool {
        (a as f64 / b as f64 - 1.0).abs() > self.cfg.baud_tolerance
    }

    fn gt_cycles(&self) -> u64 {
        ms_to_cycles(f64::from(self.active.gt()))
    }

    fn handle(&mut self, ev: Event) {
        match ev {
            Event::Ready(status) => {
                self.ready = true;
                self.last_rx_end = self.now;
                if self.api.is_some() && !self.pin_asleep() {
                    let f = self.encode(&Frame::ModemStatus { status });
                    self.send_now(&f);
                }
            }
            Event::Output(bytes) => self.send_now(&bytes),
            Event::ApplyBaud(baud) => {
                self.uart_baud = baud;
                self.garble_in = Garbler::default();
                self.garble_out = Garbler::default();
            }
            Event::Mac(timer, gen) => self.mac_timer(timer, gen),
            Event::TxStatus(frame_id, status) => {
                if frame_id != 0 && self.api.is_some() {
                    let f = self.encode(&Frame::TxStatus { frame_id, status });
                    self.send_now(&f);
                }
            }
            Event::AckIn {
                seq,
                channel,
                start,
            } => self.ack_in(seq, channel, start),
            Event::PlusCheck(gen) => {
                if gen != self.activity {
                    return;
                }
                if self.plus_count == 3 {
                    self.plus_count = 0;
                    self.held.clear();
                    if !self.tbuf.is_empty() {
                        self.flush_transparent();
                    }
                    self.cmd_line = Some(Vec::new());
                    self.restart_ct();
                    self.send_now(b"OK\r");
                } else {
                    // The sequence stopped short: the held characters were data.
                    self.plus_count = 0;
                    let held = std::mem::take(&mut self.held);
                    for b in held {
                        self.transparent_byte(self.now, b);
                    }
                }
            }
            Event::CmdTimeout(gen) => {
                if gen == self.cmd_gen && self.cmd_line.is_some() {
                    self.exit_command_mode(self.now);
                }
            }
            Event::RoFlush(gen) => {
                if gen == self.activity && !self.tbuf.is_empty() {
                    self.flush_transparent();
                }
            }
            Event::SoftReset => self.power_up(self.now, ModemStatus::WATCHDOG_RESET),
            Event::Deliver(a) => self.arrive(*a),
        }
    }

    /// Puts bytes on the TX line now (after what is already on it).
    fn send_now(&mut self, bytes: &[u8]) {
        let own = self.uart_byte_cycles();
        let host = self.host_cpb.unwrap_or(own);
        let bad = self.mismatch(host, own);
        for &b in bytes {
            let start = self.now.max(self.tx_line_free);
            self.tx_line_free = start + own;
            let byte = if bad {
                self.stats.garbled_out += 1;
                match self.garble_out.garble(b, own, host) {
                    Some(g) => g,
                    None => continue,
                }
            } else {
                b
            };
            self.outbox.push(UartByte { cycle: start, byte });
        }
    }

    fn send_at(&mut self, at: u64, bytes: Vec<u8>) {
        self.schedule(at, Event::Output(bytes));
    }

    fn encode(&self, frame: &Frame<'_>) -> Vec<u8> {
        let mut buf = [0u8; MAX_ENCODED];
        let n = frame
            .encode(self.api.unwrap_or(Mode::Escaped), &mut buf)
            .unwrap_or(0);
        buf[..n].to_vec()
    }

    fn handle_byte(&mut self, t: u64, b: u8, own: u64) {
        let start = t.saturating_sub(own);
        let silent = start.saturating_sub(self.last_rx_end) >= self.gt_cycles();
        self.last_rx_end = t;
        self.activity += 1;
        if self.cmd_line.is_some() {
            self.command_byte(t, b);
            return;
        }
        let mut is_cc = false;
        if b == self.active.cc() {
            self.plus_count = match self.plus_count {
                _ if silent => 1,
                1 | 2 => self.plus_count + 1,
                _ => 0,
            };
            is_cc = self.plus_count > 0;
            if is_cc {
                let at = t + self.gt_cycles();
                self.schedule(at, Event::PlusCheck(self.activity));
            }
        } else {
            self.plus_count = 0;
        }
        match self.api {
            Some(_) => self.api_byte(t, b, own),
            None if is_cc => self.held.push(b),
            None => {
                let held = std::mem::take(&mut self.held);
                for h in held {
                    self.transparent_byte(t, h);
                }
                self.transparent_byte(t, b);
            }
        }
    }

    // ---- API mode ----

    fn api_byte(&mut self, t: u64, b: u8, own: u64) {
        if self.di_used() >= DI_BUFFER_BYTES {
            self.stats.di_overflow += 1;
            return;
        }
        let was_in_frame = self.decoder.in_frame();
        if !was_in_frame && b != START {
            self.stats.foreign_bytes += 1;
        }
        // Cannot fail: the decoder is polled empty after every byte.
        let _ = self.decoder.push(b);
        let mut frames = Vec::new();
        while let Some(ev) = self.decoder.poll() {
            match ev {
                Ok(raw) => frames.push(raw.data().to_vec()),
                Err(DecodeError::BadChecksum { .. }) => self.stats.checksum_errors += 1,
                Err(DecodeError::BadLength { .. } | DecodeError::Truncated { .. }) => {
                    self.stats.bad_frames += 1
                }
                Err(DecodeError::Garbage { .. }) => {}
            }
        }
        let escaped = self.api == Some(Mode::Escaped);
        let started = b == START && self.decoder.in_frame() && (!was_in_frame || escaped);
        if started {
            self.frame_start = t.saturating_sub(own);
            self.frame_bytes = 0;
        }
        // The buffer holds a frame's bytes as the radio decodes them: without escape bytes.
        if (was_in_frame || started) && !(escaped && b == ESCAPE) {
            self.frame_bytes += 1;
            self.note_di_peak();
        }
        if !self.decoder.in_frame() {
            self.frame_bytes = 0;
        }
        for data in frames {
            self.stats.frames_ok += 1;
            self.frames.push(SeenFrame {
                cycle: self.frame_start,
                end_cycle: t,
                data: data.clone(),
            });
            self.api_frame(t, &data);
        }
    }

    /// Bytes taken in the serial receive buffer: the frame being received, transparent-mode
    /// data not yet packetized, and the TX requests the MAC has not finished with.
    fn di_used(&self) -> usize {
        self.frame_bytes + self.tbuf.len() + self.mac_serial_bytes()
    }

    fn note_di_peak(&mut self) {
        let used = self.di_used() as u32;
        self.stats.di_peak = self.stats.di_peak.max(used);
    }

    fn api_frame(&mut self, t: u64, data: &[u8]) {
        // Delimiter, length and checksum around the frame data.
        let frame_bytes = data.len() + 4;
        match Frame::parse(data) {
            Ok(Frame::AtCommand {
                frame_id,
                command,
                parameter,
            }) => self.api_at(t, frame_id, command, parameter, false),
            Ok(Frame::AtCommandQueue {
                frame_id,
                command,
                parameter,
            }) => self.api_at(t, frame_id, command, parameter, true),
            Ok(Frame::Tx16 {
                frame_id,
                dest,
                options,
                data,
            }) => self.api_tx(
                t,
                frame_id,
                Address::Short(dest),
                options,
                data,
                frame_bytes,
            ),
            Ok(Frame::Tx64 {
                frame_id,
                dest,
                options,
                data,
            }) => self.api_tx(t, frame_id, Address::Long(dest), options, data, frame_bytes),
            _ => self.stats.unsupported_frames += 1,
        }
    }

    fn api_at(&mut self, t: u64, frame_id: u8, command: [u8; 2], parameter: &[u8], queue: bool) {
        self.stats.at_commands += 1;
        let mut reply_at = t + ms_to_cycles(self.cfg.at_latency_ms);
        if command == *b"CH" && !queue && !parameter.is_empty() {
            // A channel change answers once it is in effect; until then the radio is deaf
            // and loses transmit requests.
            reply_at = reply_at.max(t + ms_to_cycles(self.cfg.channel_switch_ms));
            self.switching_until = reply_at;
        }
        let param = Param::Binary(parameter);
        let result = if queue && !param.is_empty() && !is_exec(command) {
            // 0x09: checked now, applied with the next 0x08 or AC.
            self.check_set(command, param).map(|v| {
                self.queued.push((command, v));
                AtValue::None
            })
        } else {
            if !queue {
                self.apply_queued();
            }
            self.command(command, param, reply_at)
        };
        if frame_id != 0 {
            let (status, value) = match &result {
                Ok(v) => (AtStatus::OK, v.api_bytes()),
                Err(s) => (*s, Vec::new()),
            };
            // Encoded in the mode before any AP change: that applies after the response.
            let f = self.encode(&Frame::AtResponse {
                frame_id,
                command,
                status,
                data: &value,
            });
            self.send_at(reply_at, f);
        }
        if !queue || std::mem::take(&mut self.apply_requested) {
            // An 0x08 frame applies changes at once (BD once the response is out).
            self.apply_changes(reply_at);
        }
    }

    /// A TX request frame of `frame_bytes` bytes (its size in the serial receive buffer).
    fn api_tx(
        &mut self,
        t: u64,
        frame_id: u8,
        dest: Address,
        options: u8,
        payload: &[u8],
        frame_bytes: usize,
    ) {
        if t < self.switching_until {
            self.stats.tx_lost_switching += 1;
            return;
        }
        if payload.len() > self.max_payload() {
            self.stats.oversize_tx += 1;
            return;
        }
        self.transmit(t, frame_id, dest, options, payload.to_vec(), frame_bytes);
    }

    /// Hands a packet to the MAC; `serial_bytes` of the serial receive buffer stay taken until
    /// the MAC is done with it.
    fn transmit(
        &mut self,
        t: u64,
        frame_id: u8,
        dest: Address,
        options: u8,
        payload: Vec<u8>,
        serial_bytes: usize,
    ) {
        if self.associating() {
            // An end device that has not found its coordinator sends nothing.
            self.stats.tx_associating += 1;
            return;
        }
        let security = if self.active.ee() {
            let counter = self.frame_counter;
            self.frame_counter = counter.wrapping_add(1);
            Security::Encrypted {
                key: self.active.ky(),
                source64: self.cfg.sh_sl,
                counter,
            }
        } else {
            Security::Clear
        };
        self.mac_request(t, frame_id, dest, options, payload, security, serial_bytes);
    }

    /// This radio's address as a packet's source: `MY`, or the 64-bit serial when `MY` is
    /// 0xFFFE/0xFFFF.
    fn source_address(&self) -> Address {
        let my = self.active.my();
        if my >= 0xFFFE {
            Address::Long(self.cfg.sh_sl)
        } else {
            Address::Short(my)
        }
    }

    fn next_rand(&mut self) -> u64 {
        let mut x = self.rng;
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        self.rng = x;
        x
    }

    fn arrive(&mut self, a: Arrival) {
        let Arrival {
            packet: mut p,
            security,
            start,
            end,
            seq,
            ack_request,
        } = a;
        let my = self.active.my();
        let for_me = match p.dest {
            Address::Short(d) => d == 0xFFFF || (d == my && my < 0xFFFE),
            Address::Long(d) => d == 0xFFFF || d == self.cfg.sh_sl,
        };
        let pan_ok = p.pan_id == self.active.id() || p.pan_id == 0xFFFF || p.options & 0x04 != 0;
        if !self.ready || p.channel != self.channel || !pan_ok || !for_me {
            self.stats.rx_filtered += 1;
            return;
        }
        if self.asleep() {
            self.stats.rx_asleep += 1;
            return;
        }
        if self.associating() {
            self.stats.rx_associating += 1;
            return;
        }
        if start < self.switching_until {
            self.stats.rx_switching += 1;
            return;
        }
        let overlaps = self.on_air.iter().any(|&(s, e)| s < end && e > start);
        if overlaps || self.cmd_line.is_some() {
            self.stats.rx_lost += 1;
            return;
        }
        match security {
            Security::Clear if !self.active.ee() => {}
            Security::Encrypted {
                key,
                source64,
                counter,
            } if self.active.ee() => {
                let own = self.active.ky();
                if key != own {
                    // Encrypted with the sender's key, decrypted with ours.
                    keystream_xor(&mut p.payload, &key, source64, counter);
                    keystream_xor(&mut p.payload, &own, source64, counter);
                    self.stats.rx_wrong_key += 1;
                }
            }
            // Encrypted at one end only: the radio passes nothing on.
            _ => {
                self.stats.encryption_mismatch += 1;
                return;
            }
        }
        if let Some(seq) = seq {
            let broadcast = p.dest.is_broadcast();
            if ack_request && !broadcast {
                self.send_ack(p.source, seq, end);
            }
            // A retry of an acknowledged unicast whose ACK was lost, or a repeated broadcast.
            if (ack_request || broadcast) && self.duplicate(p.source, seq) {
                self.stats.rx_duplicates += 1;
                return;
            }
        }
        let rssi = Rssi::from_dbm(p.rssi_dbm);
        self.db = rssi.raw();
        self.stats.rx_delivered += 1;
        let at = self.now + ms_to_cycles(self.cfg.rx_latency_ms);
        let bytes = if self.api.is_some() {
            let options = if p.dest.is_broadcast() { 0x02 } else { 0 } | (p.options & 0x04);
            let f = match p.source {
                Address::Short(source) => Frame::Rx16 {
                    source,
                    rssi,
                    options,
                    data: &p.payload,
                },
                Address::Long(source) => Frame::Rx64 {
                    source,
                    rssi,
                    options,
                    data: &p.payload,
                },
            };
            self.encode(&f)
        } else {
            p.payload.clone()
        };
        self.send_at(at, bytes);
    }

    // ---- transparent mode ----

    fn transparent_byte(&mut self, t: u64, b: u8) {
        if self.di_used() >= DI_BUFFER_BYTES {
            self.stats.di_overflow += 1;
            return;
        }
        self.tbuf.push(b);
        self.note_di_peak();
        if self.tbuf.len() >= self.max_payload() {
            self.flush_transparent();
            return;
        }
        let ro = u64::from(self.active.ro()) * self.uart_byte_cycles();
        self.schedule(t + ro, Event::RoFlush(self.activity));
    }

    fn flush_transparent(&mut self) {
        let payload = std::mem::take(&mut self.tbuf);
        let d = self.active.dest();
        let dest = if d <= 0xFFFF {
            Address::Short(d as u16)
        } else {
            Address::Long(d)
        };
        let n = payload.len();
        self.transmit(self.now, 0, dest, 0, payload, n);
    }

    // ---- command mode ----

    fn restart_ct(&mut self) {
        self.cmd_gen += 1;
        let at = self.now + ms_to_cycles(100.0 * f64::from(self.active.ct()));
        self.schedule(at, Event::CmdTimeout(self.cmd_gen));
    }

    fn command_byte(&mut self, t: u64, b: u8) {
        let Some(line) = self.cmd_line.as_mut() else {
            return;
        };
        if b != b'\r' {
            if line.len() < 128 {
                line.push(b);
            }
            return;
        }
        let line = std::mem::take(line);
        self.command_line(t, &line);
    }

    fn command_line(&mut self, t: u64, line: &[u8]) {
        self.restart_ct();
        let reply_at = t + ms_to_cycles(self.cfg.at_latency_ms);
        let line = trim(line);
        if line.len() < 2 || !line[..2].eq_ignore_ascii_case(b"AT") {
            self.send_at(reply_at, b"ERROR\r".to_vec());
            return;
        }
        let body = &line[2..];
        if body.is_empty() {
            self.send_at(reply_at, b"OK\r".to_vec());
            return;
        }
        let mut out = Vec::new();
        let mut exit = false;
        for part in body.split(|&c| c == b',') {
            let part = trim(part);
            let Some(&[c0, c1]) = part.get(..2) else {
                out.extend_from_slice(b"ERROR\r");
                break;
            };
            self.stats.at_commands += 1;
            let cmd = [c0.to_ascii_uppercase(), c1.to_ascii_uppercase()];
            match self.command(cmd, Param::Text(&part[2..]), reply_at) {
                Ok(v) => out.extend_from_slice(&v.text()),
                Err(_) => {
                    // The rest of the line is not executed.
                    out.extend_from_slice(b"ERROR\r");
                    break;
                }
            }
            if cmd == *b"CN" {
                exit = true;
                break;
            }
        }
        self.send_at(reply_at, out);
        if exit {
            self.exit_command_mode(reply_at);
        } else if std::mem::take(&mut self.apply_requested) {
            self.apply_changes(reply_at);
        }
    }

    fn exit_command_mode(&mut self, at: u64) {
        self.cmd_line = None;
        self.cmd_gen += 1;
        self.apply_changes(at);
    }

    // ---- registers ----

    /// Executes one AT command (query, set or exec). Sets change the active registers; their
    /// effects wait for [`XBeeCore::apply_changes`]. `reply_at` is when the response starts.
    fn command(&mut self, cmd: [u8; 2], param: Param<'_>, reply_at: u64) -> AtResult {
        if is_exec(cmd) {
            if !param.is_empty() {
                return Err(AtStatus::INVALID_PARAMETER);
            }
            match &cmd {
                b"WR" => self.persisted = self.active.clone(),
                b"RE" => self.active = Registers::factory(),
                b"AC" => {
                    self.apply_queued();
                    self.apply_requested = true;
                }
                b"FR" => {
                    let at = reply_at + ms_to_cycles(2.0) + 4 * self.uart_byte_cycles();
                    self.schedule(at, Event::SoftReset);
                }
                // CN: the caller leaves command mode (in API mode it does nothing).
                _ => {}
            }
            return Ok(AtValue::None);
        }
        if param.is_empty() {
            return self.query(cmd);
        }
        let v = self.check_set(cmd, param)?;
        self.set(cmd, &v);
        Ok(AtValue::None)
    }

    fn query(&self, cmd: [u8; 2]) -> AtResult {
        if cmd == *b"NI" {
            return Ok(AtValue::Str(self.active.ni().to_vec()));
        }
        if cmd == *b"KY" {
            // Write-only: a query answers OK and never the key.
            return Ok(AtValue::None);
        }
        if let Some(s) = regs::spec(cmd) {
            let v = self.active.get(cmd).unwrap_or(s.default);
            return Ok(AtValue::Num(u64::from(v), s.width));
        }
        let Some(&(_, width)) = READ_ONLY.iter().find(|r| r.0 == cmd) else {
            return Err(AtStatus::INVALID_COMMAND);
        };
        let v: u64 = match &cmd {
            b"SH" => self.cfg.sh_sl >> 32,
            b"SL" => self.cfg.sh_sl & 0xFFFF_FFFF,
            b"VR" => u64::from(self.cfg.vr),
            b"HV" => u64::from(self.cfg.hv),
            b"DB" => u64::from(self.db),
            b"EC" => u64::from(self.mac.ec),
            b"EA" => u64::from(self.mac.ea),
            // Active scan found no PANs: no coordinator answers in a hoploc network.
            b"AI" if self.associating() => 0x02,
            _ => 0,
        };
        Ok(AtValue::Num(v, width))
    }

    /// The encoded new value of a set, if the command and value are valid.
    fn check_set(&self, cmd: [u8; 2], param: Param<'_>) -> Result<Vec<u8>, AtStatus> {
        if cmd == *b"NI" {
            let s = param.string();
            if s.len() > NI_MAX || s.iter().any(|c| !c.is_ascii() || c.is_ascii_control()) {
                return Err(AtStatus::INVALID_PARAMETER);
            }
            return Ok(s);
        }
        if cmd == *b"KY" {
            return param
                .key()
                .map(|k| k.to_vec())
                .ok_or(AtStatus::INVALID_PARAMETER);
        }
        if matches!(&cmd, b"EC" | b"EA") {
            // The failure counters: set (to 0) to reset.
            return match param.number() {
                Some(v) if v <= 0xFFFF => Ok(v.to_be_bytes().to_vec()),
                _ => Err(AtStatus::INVALID_PARAMETER),
            };
        }
        if READ_ONLY.iter().any(|r| r.0 == cmd) {
            return Err(AtStatus::ERROR);
        }
        let Some(s) = regs::spec(cmd) else {
            return Err(AtStatus::INVALID_COMMAND);
        };
        let v = param.number().ok_or(AtStatus::INVALID_PARAMETER)?;
        let ok = match &cmd {
            b"CH" => u8::try_from(v).is_ok_and(|c| self.cfg.model.channels().contains(&c)),
            b"BD" => baud_of_bd(v).is_some(),
            _ => (s.min..=s.max).contains(&v),
        };
        if !ok {
            return Err(AtStatus::INVALID_PARAMETER);
        }
        Ok(v.to_be_bytes().to_vec())
    }

    fn set(&mut self, cmd: [u8; 2], v: &[u8]) {
        if cmd == *b"NI" {
            self.active.set_ni(v);
        } else if cmd == *b"KY" {
            let mut key = [0; KEY_LEN];
            key.copy_from_slice(v);
            self.active.set_ky(key);
        } else if matches!(&cmd, b"EC" | b"EA") {
            let n = v.iter().fold(0u32, |a, &b| (a << 8) | u32::from(b)) as u16;
            if cmd == *b"EC" {
                self.mac.ec = n;
            } else {
                self.mac.ea = n;
            }
        } else {
            let n = v.iter().fold(0u32, |a, &b| (a << 8) | u32::from(b));
            self.active.set_unchecked(cmd, n);
        }
    }

    fn apply_queued(&mut self) {
        for (cmd, v) in std::mem::take(&mut self.queued) {
            self.set(cmd, &v);
        }
    }

    /// Makes the active registers take effect: channel and API mode now, the UART rate at
    /// `baud_at` (once the response to the command that applied it is on the line).
    fn apply_changes(&mut self, baud_at: u64) {
        self.channel = self.active.ch();
        let api = Mode::from_ap(self.active.ap());
        if api != self.api {
            self.api = api;
            self.decoder.set_mode(api.unwrap_or(Mode::Escaped));
        }
        let baud = self.active.baud();
        if baud != self.uart_baud {
            self.schedule(baud_at, Event::ApplyBaud(baud));
        }
    }
}

fn is_exec(cmd: [u8; 2]) -> bool {
    matches!(&cmd, b"WR" | b"RE" | b"AC" | b"FR" | b"CN")
}

fn trim(s: &[u8]) -> &[u8] {
    let start = s.iter().position(|&c| c != b' ').unwrap_or(s.len());
    let end = s.iter().rposition(|&c| c != b' ').map_or(start, |e| e + 1);
    &s[start..end.max(start)]
}

/// `data` (frame data, type byte first) encoded as an API frame in `mode`.
pub fn encode_frame(data: &[u8], mode: Mode) -> Vec<u8> {
    let mut buf = [0u8; MAX_ENCODED];
    let n = encode_raw(data, mode, &mut buf).unwrap_or(0);
    buf[..n].to_vec()
}
