//! The XBee 802.15.4 (S1) configuration registers: names, natural widths, ranges, defaults.

use std::collections::BTreeMap;
use std::fmt;

/// Which radio: the channel range differs (S1 Pro has no testbed channel 1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Model {
    /// XBee 802.15.4 S1: `CH` 0x0B…0x1A.
    #[default]
    S1,
    /// XBee-PRO 802.15.4 S1: `CH` 0x0C…0x17 (no testbed channel 1, `CH` = 0x0B).
    S1Pro,
}

impl Model {
    /// The valid `CH` values.
    pub fn channels(self) -> std::ops::RangeInclusive<u8> {
        match self {
            Model::S1 => 0x0B..=0x1A,
            Model::S1Pro => 0x0C..=0x17,
        }
    }

    /// The output power at power level `PL` (0…4, higher values taken as 4), dBm: the S1's
    /// −10, −6, −4, −2, 0 dBm, the S1 Pro's 10, 12, 14, 16, 18 dBm (Digi's 802.15.4 S1 product
    /// manual, `PL` command).
    pub fn output_dbm(self, pl: u8) -> i8 {
        let table = match self {
            Model::S1 => [-10, -6, -4, -2, 0],
            Model::S1Pro => [10, 12, 14, 16, 18],
        };
        table[usize::from(pl.min(4))]
    }

    /// The output power at power level `PL` relative to the factory `PL` = 4, dB (≤ 0): what a
    /// lower level takes off every packet's level at its receivers.
    pub fn power_db(self, pl: u8) -> i8 {
        self.output_dbm(pl) - self.output_dbm(4)
    }
}

/// The rates the S1's UART really runs at for `BD` 0…7 (bit/s): `BD=7`, named 115200, is
/// 111 111 bit/s (Digi's S1 manual), so a host at 115200 (the Uno's nearest divisor gives
/// 117 647) does not understand a radio left at `BD=7`.
pub const BAUD_RATES: [u32; 8] = [1200, 2400, 4800, 9600, 19_200, 38_400, 57_600, 111_111];

const _: () = {
    let mut bd = 0;
    while bd < BAUD_RATES.len() {
        assert!(BAUD_RATES[bd] == xbee_api::driver::baud_of_bd(bd as u8));
        bd += 1;
    }
};

/// The baud rate of a `BD` value (0…7), if valid.
pub fn baud_of_bd(bd: u32) -> Option<u32> {
    BAUD_RATES.get(bd as usize).copied()
}

/// One numeric register: name, width of its value in API responses (bytes, big endian), range
/// and factory default.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Spec {
    pub cmd: [u8; 2],
    pub width: u8,
    pub min: u32,
    pub max: u32,
    pub default: u32,
}

const fn s(cmd: &[u8; 2], width: u8, min: u32, max: u32, default: u32) -> Spec {
    Spec {
        cmd: *cmd,
        width,
        min,
        max,
        default,
    }
}

/// The writable numeric registers the model knows (802.15.4 firmware 10Ex names). `CH`'s range
/// here is the S1's; [`Model::S1Pro`] narrows it.
pub(crate) const REGISTERS: &[Spec] = &[
    // Networking and addressing.
    s(b"CH", 1, 0x0B, 0x1A, 0x0C),
    s(b"ID", 2, 0, 0xFFFF, 0x3332),
    s(b"DH", 4, 0, 0xFFFF_FFFF, 0),
    s(b"DL", 4, 0, 0xFFFF_FFFF, 0),
    s(b"MY", 2, 0, 0xFFFF, 0),
    s(b"RR", 1, 0, 6, 0),
    s(b"RN", 1, 0, 3, 0),
    s(b"MM", 1, 0, 3, 0),
    s(b"NT", 1, 0x01, 0xFC, 0x19),
    s(b"NO", 1, 0, 1, 0),
    s(b"CE", 1, 0, 1, 0),
    s(b"SC", 2, 0, 0xFFFF, 0x1FFE),
    s(b"SD", 1, 0, 0x0F, 4),
    s(b"A1", 1, 0, 0x0F, 0),
    s(b"A2", 1, 0, 0x0F, 0),
    // Security (the key `KY` is kept apart: 128 bits, write-only).
    s(b"EE", 1, 0, 1, 0),
    // RF interfacing.
    s(b"PL", 1, 0, 4, 4),
    s(b"CA", 1, 0x24, 0x50, 0x2C),
    // Sleep (`SM` acts, see the module docs; the timers are stored only).
    s(b"SM", 1, 0, 6, 0),
    s(b"ST", 2, 1, 0xFFFF, 0x1388),
    s(b"SP", 2, 0, 0x68B0, 0),
    s(b"DP", 2, 1, 0x68B0, 0x3E8),
    // Serial interfacing.
    s(b"BD", 4, 0, 7, 3),
    s(b"NB", 1, 0, 4, 0),
    s(b"RO", 1, 0, 0xFF, 3),
    s(b"AP", 1, 0, 2, 0),
    s(b"PR", 1, 0, 0xFF, 0xFF),
    // I/O (accepted and stored, not modelled).
    s(b"IU", 1, 0, 1, 1),
    s(b"IT", 1, 1, 0xFF, 1),
    s(b"IC", 1, 0, 0xFF, 0),
    s(b"IR", 2, 0, 0xFFFF, 0),
    // Diagnostics / command mode options.
    s(b"RP", 1, 0, 0xFF, 0x28),
    s(b"CT", 2, 2, 0xFFFF, 0x64),
    s(b"GT", 2, 2, 0x0CE4, 0x3E8),
    s(b"CC", 1, 0, 0xFF, 0x2B),
];

/// Read-only registers and their widths (values come from the radio's state).
pub(crate) const READ_ONLY: &[([u8; 2], u8)] = &[
    (*b"SH", 4),
    (*b"SL", 4),
    (*b"VR", 2),
    (*b"HV", 2),
    (*b"DB", 1),
    (*b"EC", 2),
    (*b"EA", 2),
    (*b"AI", 1),
];

/// Longest node identifier (`NI`).
pub const NI_MAX: usize = 20;

/// Length of the AES-128 key `KY`, bytes.
pub const KEY_LEN: usize = 16;

pub(crate) fn spec(cmd: [u8; 2]) -> Option<&'static Spec> {
    REGISTERS.iter().find(|s| s.cmd == cmd)
}

/// A set of register values: the active set (what the radio uses) or the persisted set (what
/// `WR` saved and a power cycle restores). Numeric registers by their two-letter name, plus `NI`
/// and the AES key `KY`.
#[derive(Clone, PartialEq, Eq)]
pub struct Registers {
    values: BTreeMap<[u8; 2], u32>,
    ni: Vec<u8>,
    ky: [u8; KEY_LEN],
}

impl Default for Registers {
    fn default() -> Self {
        Registers::factory()
    }
}

impl fmt::Debug for Registers {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut m = f.debug_map();
        for (k, v) in &self.values {
            m.entry(&String::from_utf8_lossy(k), &format_args!("{v:#X}"));
        }
        m.entry(&"NI", &String::from_utf8_lossy(&self.ni));
        // The key stays out of logs, as the radio keeps it from queries.
        let ky = if self.ky == [0; KEY_LEN] {
            "0"
        } else {
            "(set)"
        };
        m.entry(&"KY", &ky);
        m.finish()
    }
}

impl Registers {
    /// Factory defaults (`RE`): transparent mode, 9600 baud, channel 0x0C, PAN 0x3332, MY 0,
    /// no encryption (`EE` 0, `KY` 0).
    pub fn factory() -> Registers {
        Registers {
            values: REGISTERS.iter().map(|s| (s.cmd, s.default)).collect(),
            ni: Vec::new(),
            ky: [0; KEY_LEN],
        }
    }

    /// The value of numeric register `cmd` (e.g. `*b"CH"`), if the model knows it.
    pub fn get(&self, cmd: [u8; 2]) -> Option<u32> {
        self.values.get(&cmd).copied()
    }

    /// Sets numeric register `cmd` without range checks (for configuring a model; AT commands
    /// check ranges). Unknown names are ignored.
    pub fn set_unchecked(&mut self, cmd: [u8; 2], v: u32) {
        if let Some(slot) = self.values.get_mut(&cmd) {
            *slot = v;
        }
    }

    fn num(&self, cmd: &[u8; 2]) -> u32 {
        self.values.get(cmd).copied().unwrap_or(0)
    }

    /// `CH`.
    pub fn ch(&self) -> u8 {
        self.num(b"CH") as u8
    }
    /// `ID` (PAN id).
    pub fn id(&self) -> u16 {
        self.num(b"ID") as u16
    }
    /// `MY` (16-bit source address; 0xFFFE/0xFFFF: use the 64-bit address).
    pub fn my(&self) -> u16 {
        self.num(b"MY") as u16
    }
    /// `DH:DL`, the transparent-mode destination.
    pub fn dest(&self) -> u64 {
        (u64::from(self.num(b"DH")) << 32) | u64::from(self.num(b"DL"))
    }
    /// `AP`: 0 transparent, 1 API, 2 API with escaping.
    pub fn ap(&self) -> u8 {
        self.num(b"AP") as u8
    }
    /// `BD`: 0…7 (see [`BAUD_RATES`]).
    pub fn bd(&self) -> u32 {
        self.num(b"BD")
    }
    /// The baud rate `BD` selects.
    pub fn baud(&self) -> u32 {
        baud_of_bd(self.bd()).unwrap_or(9600)
    }
    /// `GT`: guard time in ms.
    pub fn gt(&self) -> u16 {
        self.num(b"GT") as u16
    }
    /// `CT`: command mode timeout in units of 100 ms.
    pub fn ct(&self) -> u16 {
        self.num(b"CT") as u16
    }
    /// `RO`: transparent-mode packetization timeout in character times.
    pub fn ro(&self) -> u8 {
        self.num(b"RO") as u8
    }
    /// `CC`: the command sequence character (`+`).
    pub fn cc(&self) -> u8 {
        self.num(b"CC") as u8
    }
    /// `MM`: MAC mode (0 Digi mode: 802.15.4 with the XBee's header, ACKs and duplicate
    /// detection; 1 802.15.4 without ACKs; 2 802.15.4 with ACKs; 3 Digi mode without ACKs).
    pub fn mm(&self) -> u8 {
        self.num(b"MM") as u8
    }
    /// `RN`: the CSMA-CA's minimum backoff exponent (802.15.4's macMinBE), 0…3.
    pub fn rn(&self) -> u8 {
        self.num(b"RN") as u8
    }
    /// `RR`: XBee retries of an unacknowledged unicast, on top of the MAC's three, 0…6; above 0
    /// every broadcast goes out `RR` + 2 times.
    pub fn rr(&self) -> u8 {
        self.num(b"RR") as u8
    }
    /// `CA`: the clear channel assessment's threshold, −dBm.
    pub fn ca(&self) -> u8 {
        self.num(b"CA") as u8
    }
    /// `CE`: coordinator enable.
    pub fn ce(&self) -> u8 {
        self.num(b"CE") as u8
    }
    /// `A1`: end-device association options (bit 2: associate with a coordinator).
    pub fn a1(&self) -> u8 {
        self.num(b"A1") as u8
    }
    /// `SM`: sleep mode (0 no sleep, 1 pin hibernate, 2 pin doze, 3 reserved, 4 cyclic sleep
    /// remote, 5 cyclic sleep remote with pin wake-up, 6 sleep coordinator).
    pub fn sm(&self) -> u8 {
        self.num(b"SM") as u8
    }
    /// `PL`: power level, 0…4 (see [`Model::output_dbm`]).
    pub fn pl(&self) -> u8 {
        self.num(b"PL") as u8
    }
    /// `EE`: AES encryption enabled.
    pub fn ee(&self) -> bool {
        self.num(b"EE") != 0
    }
    /// `KY`: the AES-128 key (the model's view: the radio never answers it to a query).
    pub fn ky(&self) -> [u8; KEY_LEN] {
        self.ky
    }
    /// `NI`: node identifier.
    pub fn ni(&self) -> &[u8] {
        &self.ni
    }
    pub(crate) fn set_ni(&mut self, ni: &[u8]) {
        self.ni = ni.to_vec();
    }
    pub(crate) fn set_ky(&mut self, ky: [u8; KEY_LEN]) {
        self.ky = ky;
    }
}
