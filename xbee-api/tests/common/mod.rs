//! A scripted fake XBee 802.15.4 radio for host tests of the driver.
//!
//! [`FakeSerial`] and [`FakeClock`] share one [`Model`]. The model:
//! * records every byte the driver writes ([`Model::wire`]), decodes the frames among them with
//!   the crate's own [`Decoder`] ([`Model::frames`]) and logs host and radio frames in order
//!   ([`Model::log`]);
//! * answers each frame from its script ([`Model::expect`]) if one is queued, else like a radio
//!   would (AT queries and sets of `MY`, `ID`, `CH`, `AP`, `BD`, `EE`, `WR`; `KY` sets, its
//!   queries answered without a value; TX status for TX requests);
//! * models transparent command mode (guard time, `+++`, `OK\r`, `AT…\r` lines, `CN` applying
//!   `AP` and `BD`) and baud rates: bytes sent at a rate the other side is not listening at
//!   arrive as garbage (never `0x7E`, `O`, `K` or `\r`);
//! * keeps time: every read that finds nothing advances the clock by 1 ms, so timeouts end
//!   deterministically.
#![allow(dead_code)]

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use embedded_hal_nb::serial::{ErrorKind, ErrorType, Read, Write};
use xbee_api::driver::{Clock, Radio, SetBaud};
use xbee_api::{AtStatus, Decoder, Frame, Mode, TxStatus, MAX_ENCODED};

/// What the radio does with a frame that matched a script rule.
#[derive(Clone, Debug)]
pub enum Reply {
    /// Behave like the model radio.
    Model,
    /// Send these frames (frame data), encoded in the radio's mode.
    Frames(Vec<Vec<u8>>),
    /// Send these bytes as they are.
    Raw(Vec<u8>),
    /// Say nothing.
    Silent,
}

/// The frame data of `f`.
pub fn data(f: &Frame<'_>) -> Vec<u8> {
    let mut buf = [0u8; MAX_ENCODED];
    let n = f.encode(Mode::Api, &mut buf).unwrap();
    buf[3..n - 1].to_vec()
}

/// `f` encoded in `mode`.
pub fn enc(f: &Frame<'_>, mode: Mode) -> Vec<u8> {
    let mut buf = [0u8; MAX_ENCODED];
    let n = f.encode(mode, &mut buf).unwrap();
    buf[..n].to_vec()
}

/// An AT response frame's data.
pub fn at_resp(frame_id: u8, command: &[u8; 2], status: AtStatus, value: &[u8]) -> Vec<u8> {
    data(&Frame::AtResponse {
        frame_id,
        command: *command,
        status,
        data: value,
    })
}

/// A one-line description of frame data, for [`Model::log`].
pub fn describe(d: &[u8]) -> String {
    match Frame::parse(d) {
        Ok(Frame::AtCommand {
            frame_id,
            command,
            parameter,
        }) => format!(
            "AT{} id={frame_id} {parameter:02X?}",
            String::from_utf8_lossy(&command)
        ),
        Ok(Frame::AtResponse {
            frame_id,
            command,
            status,
            ..
        }) => format!(
            "RESP{} id={frame_id} st={}",
            String::from_utf8_lossy(&command),
            status.0
        ),
        Ok(Frame::Tx16 { frame_id, .. }) => format!("TX16 id={frame_id}"),
        Ok(Frame::TxStatus { frame_id, status }) => {
            format!("TXSTATUS id={frame_id} st={}", status.0)
        }
        Ok(Frame::Rx16 { source, .. }) => format!("RX16 from={source:04X}"),
        Ok(f) => format!("type {:#04x}", f.frame_type()),
        Err(e) => format!("bad frame {e}"),
    }
}

struct Out {
    at: u32,
    baud: u32,
    byte: u8,
    /// Logged when the host reads this byte (the last of a frame).
    tag: Option<String>,
}

/// The fake radio's state. Tests read and poke its public fields.
pub struct Model {
    /// Current time (ms); wraps like a real tick counter.
    pub now: u32,
    /// Rate the host UART is set to.
    pub host_baud: u32,
    /// Every `set_baud` call, in order.
    pub host_bauds: Vec<u32>,
    /// The radio's UART rate (`BD`).
    pub baud: u32,
    /// `AP`: 0 transparent, 1 API, 2 API escaped.
    pub ap: u8,
    pub my: u16,
    pub id: u16,
    pub ch: u8,
    /// `EE`: encryption on (1) or off (0).
    pub ee: u8,
    /// `RN`: the CSMA-CA's smallest backoff exponent, 0…3.
    pub rn: u8,
    /// `CA`: the channel check's busy level, −dBm, 0x24…0x50.
    pub ca: u8,
    /// The registers of `xbee_api::driver::FIXED_SETTINGS` (`RR`, `MM`, `SM`, `A1`, `PL`), as
    /// (command, value, largest value).
    pub fixed: Vec<([u8; 2], u8, u8)>,
    /// `KY` as last set (write-only: a query answers no value).
    pub ky: Option<Vec<u8>>,
    /// Answers a `KY` set with this error status (and keeps the old key).
    pub ky_status: Option<AtStatus>,
    /// Radio guard time (`GT`), ms.
    pub gt: u32,
    /// `WR` count.
    pub writes: u32,
    /// Ignores everything.
    pub dead: bool,
    /// Answers every byte it hears with noise.
    pub babble: bool,
    /// Answers this command-mode command with `ERROR`.
    pub reject: Option<&'static str>,
    /// The UART never takes a byte.
    pub write_blocked: bool,
    /// Delay of AT responses and TX status, ms.
    pub at_delay: u32,
    pub tx_delay: u32,
    /// Every byte the host wrote, at any rate.
    pub wire: Vec<u8>,
    /// Frame data of every frame the radio decoded from the host.
    pub frames: Vec<Vec<u8>>,
    /// Command-mode lines received (without `\r`).
    pub cmd_lines: Vec<String>,
    /// `-> …` frames from the host as the radio decodes them, `<- …` radio frames as the host
    /// reads their last byte.
    pub log: Vec<String>,
    /// Scripted answers: (expected frame data, if checked; reply), consumed in order.
    pub script: VecDeque<(Option<Vec<u8>>, Reply)>,
    out: VecDeque<Out>,
    dec: Decoder,
    last_rx: Option<u32>,
    plus: u8,
    ok_at: Option<u32>,
    cmd_mode: bool,
    line: Vec<u8>,
    pending_ap: Option<u8>,
    pending_baud: Option<u32>,
    spins: u32,
}

pub fn bd_to_baud(bd: u32) -> Option<u32> {
    [1200, 2400, 4800, 9600, 19200, 38400, 57600, 111_111]
        .get(bd as usize)
        .copied()
}

fn garble(b: u8) -> u8 {
    0xF0 | (b & 0x0F)
}

impl Model {
    pub fn new(ap: u8, baud: u32) -> Self {
        Model {
            now: 0,
            host_baud: 57600,
            host_bauds: vec![],
            baud,
            ap,
            my: 0,
            id: 0x3332,
            ch: 0x0C,
            ee: 0,
            rn: 0,
            ca: 0x2C,
            fixed: vec![
                (*b"RR", 0, 6),
                (*b"MM", 0, 3),
                (*b"SM", 0, 6),
                (*b"A1", 0, 0x0F),
                (*b"PL", 4, 4),
            ],
            ky: None,
            ky_status: None,
            gt: 20,
            writes: 0,
            dead: false,
            babble: false,
            reject: None,
            write_blocked: false,
            at_delay: 2,
            tx_delay: 10,
            wire: vec![],
            frames: vec![],
            cmd_lines: vec![],
            log: vec![],
            script: VecDeque::new(),
            out: VecDeque::new(),
            dec: Decoder::new(Mode::from_ap(ap).unwrap_or(Mode::Api)),
            last_rx: None,
            plus: 0,
            ok_at: None,
            cmd_mode: false,
            line: vec![],
            pending_ap: None,
            pending_baud: None,
            spins: 0,
        }
    }

    /// Queues a script rule for the next frame the radio decodes.
    pub fn expect(&mut self, frame: Option<Vec<u8>>, reply: Reply) {
        self.script.push_back((frame, reply));
    }

    /// Queues bytes to the host after `delay` ms, at the radio's rate.
    pub fn emit(&mut self, bytes: &[u8], delay: u32, tag: Option<String>) {
        let n = bytes.len();
        for (i, &byte) in bytes.iter().enumerate() {
            self.out.push_back(Out {
                at: self.now.wrapping_add(delay),
                baud: self.baud,
                byte,
                tag: if i + 1 == n { tag.clone() } else { None },
            });
        }
    }

    /// Queues a frame (data) to the host, encoded in the radio's API mode.
    pub fn emit_frame(&mut self, d: &[u8], delay: u32) {
        let mode = Mode::from_ap(self.ap).unwrap_or(Mode::Api);
        let mut buf = [0u8; MAX_ENCODED];
        let n = xbee_api::encode_raw(d, mode, &mut buf).unwrap();
        self.emit(&buf[..n], delay, Some(format!("<- {}", describe(d))));
    }

    /// Frames the host wrote, described.
    pub fn host_frames(&self) -> Vec<String> {
        self.frames.iter().map(|d| describe(d)).collect()
    }

    fn tick(&mut self) {
        if let Some(t) = self.ok_at {
            if self.now.wrapping_sub(t) < u32::MAX / 2 {
                self.ok_at = None;
                self.plus = 0;
                self.cmd_mode = true;
                self.emit(b"OK\r", 0, None);
            }
        }
    }

    fn read(&mut self) -> Option<u8> {
        self.spins = 0;
        self.tick();
        match self.out.front() {
            Some(o) if self.now.wrapping_sub(o.at) < u32::MAX / 2 => {
                let o = self.out.pop_front().unwrap();
                if let Some(tag) = o.tag {
                    self.log.push(tag);
                }
                Some(if o.baud == self.host_baud {
                    o.byte
                } else {
                    garble(o.byte)
                })
            }
            _ => {
                self.now = self.now.wrapping_add(1);
                None
            }
        }
    }

    fn write(&mut self, b: u8) {
        self.wire.push(b);
        if self.dead {
            return;
        }
        if self.babble {
            self.emit(b"?\xF5", 0, None);
            return;
        }
        let silent_for = self.last_rx.map_or(u32::MAX, |t| self.now.wrapping_sub(t));
        self.last_rx = Some(self.now);
        if self.host_baud != self.baud {
            self.plus = 0;
            self.ok_at = None;
            return;
        }
        if self.cmd_mode {
            if b == b'\r' {
                let line = String::from_utf8_lossy(&std::mem::take(&mut self.line)).into_owned();
                self.command(line);
            } else {
                self.line.push(b);
            }
            return;
        }
        if b == b'+' && (self.plus > 0 || silent_for >= self.gt) {
            self.plus += 1;
            self.ok_at = (self.plus == 3).then_some(self.now.wrapping_add(self.gt));
        } else {
            self.plus = 0;
            self.ok_at = None;
        }
        if self.ap == 0 {
            return; // transparent: the bytes go on air
        }
        let _ = self.dec.push(b);
        let mut got = vec![];
        while let Some(ev) = self.dec.poll() {
            if let Ok(raw) = ev {
                got.push(raw.data().to_vec());
            }
        }
        for d in got {
            self.frame(d);
        }
    }

    fn command(&mut self, line: String) {
        self.cmd_lines.push(line.clone());
        let reply = |m: &mut Model, s: &str| m.emit(format!("{s}\r").as_bytes(), 1, None);
        let Some(rest) = line.strip_prefix("AT") else {
            return reply(self, "ERROR");
        };
        let (cmd, param) = rest.split_at(rest.len().min(2));
        if self.reject == Some(cmd) {
            return reply(self, "ERROR");
        }
        let value = if param.is_empty() {
            None
        } else {
            match u32::from_str_radix(param, 16) {
                Ok(v) => Some(v),
                Err(_) => return reply(self, "ERROR"),
            }
        };
        match (cmd, value) {
            ("AP", Some(v @ 0..=2)) => self.pending_ap = Some(v as u8),
            ("AP", None) => return reply(self, &format!("{:X}", self.ap)),
            ("BD", Some(v)) => match bd_to_baud(v) {
                Some(b) => self.pending_baud = Some(b),
                None => return reply(self, "ERROR"),
            },
            ("WR", None) => self.writes += 1,
            ("CN", None) => {
                reply(self, "OK");
                self.cmd_mode = false;
                if let Some(ap) = self.pending_ap.take() {
                    self.ap = ap;
                    self.dec = Decoder::new(Mode::from_ap(ap).unwrap_or(Mode::Api));
                }
                if let Some(b) = self.pending_baud.take() {
                    self.baud = b;
                }
                return;
            }
            _ => return reply(self, "ERROR"),
        }
        reply(self, "OK")
    }

    fn frame(&mut self, d: Vec<u8>) {
        self.log.push(format!("-> {}", describe(&d)));
        self.frames.push(d.clone());
        if let Some((want, reply)) = self.script.pop_front() {
            if let Some(want) = want {
                assert_eq!(describe(&d), describe(&want), "scripted frame");
                assert_eq!(d, want, "scripted frame");
            }
            match reply {
                Reply::Model => {}
                Reply::Frames(fs) => {
                    for f in fs {
                        let delay = self.at_delay;
                        self.emit_frame(&f, delay);
                    }
                    return;
                }
                Reply::Raw(bytes) => {
                    let delay = self.at_delay;
                    self.emit(&bytes, delay, Some("<- raw".into()));
                    return;
                }
                Reply::Silent => return,
            }
        }
        match Frame::parse(&d) {
            Ok(Frame::AtCommand {
                frame_id,
                command,
                parameter,
            }) => {
                let (status, value) = self.at(command, parameter);
                if frame_id != 0 {
                    let r = at_resp(frame_id, &command, status, &value);
                    let delay = self.at_delay;
                    self.emit_frame(&r, delay);
                }
                if let (b"AP", true, Some(&ap)) = (&command, status.is_ok(), parameter.first()) {
                    self.ap = ap;
                    self.dec = Decoder::new(Mode::from_ap(ap).unwrap_or(Mode::Api));
                }
            }
            Ok(Frame::Tx16 { frame_id, .. } | Frame::Tx64 { frame_id, .. }) if frame_id != 0 => {
                let r = data(&Frame::TxStatus {
                    frame_id,
                    status: TxStatus::SUCCESS,
                });
                let delay = self.tx_delay;
                self.emit_frame(&r, delay);
            }
            _ => {}
        }
    }

    fn at(&mut self, command: [u8; 2], p: &[u8]) -> (AtStatus, Vec<u8>) {
        let v = p.iter().fold(0u32, |v, &b| (v << 8) | b as u32);
        let ok = (AtStatus::OK, vec![]);
        let bad = (AtStatus::INVALID_PARAMETER, vec![]);
        match (&command, p.is_empty()) {
            (b"MY", true) => (AtStatus::OK, self.my.to_be_bytes().to_vec()),
            (b"ID", true) => (AtStatus::OK, self.id.to_be_bytes().to_vec()),
            (b"CH", true) => (AtStatus::OK, vec![self.ch]),
            (b"AP", true) => (AtStatus::OK, vec![self.ap]),
            (b"EE", true) => (AtStatus::OK, vec![self.ee]),
            (b"RN", true) => (AtStatus::OK, vec![self.rn]),
            (b"CA", true) => (AtStatus::OK, vec![self.ca]),
            (b"KY", true) => ok,
            (c, true) if self.fixed.iter().any(|f| f.0 == *c) => {
                let f = self.fixed.iter().find(|f| f.0 == *c).unwrap();
                (AtStatus::OK, vec![f.1])
            }
            (c, false) if self.fixed.iter().any(|f| f.0 == *c) => {
                let f = self.fixed.iter_mut().find(|f| f.0 == *c).unwrap();
                if v > u32::from(f.2) {
                    return bad;
                }
                f.1 = v as u8;
                ok
            }
            (b"MY", false) if v <= 0xFFFF => {
                self.my = v as u16;
                ok
            }
            (b"ID", false) if v <= 0xFFFF => {
                self.id = v as u16;
                ok
            }
            (b"CH", false) if (0x0B..=0x1A).contains(&v) => {
                self.ch = v as u8;
                ok
            }
            (b"AP", false) if v <= 2 => ok,
            (b"RN", false) if v <= 3 => {
                self.rn = v as u8;
                ok
            }
            (b"CA", false) if (0x24..=0x50).contains(&v) => {
                self.ca = v as u8;
                ok
            }
            (b"EE", false) if v <= 1 => {
                self.ee = v as u8;
                ok
            }
            (b"KY", false) if p.len() <= 16 => match self.ky_status {
                Some(status) => (status, vec![]),
                None => {
                    self.ky = Some(p.to_vec());
                    ok
                }
            },
            (b"WR", true) => {
                self.writes += 1;
                ok
            }
            (b"MY" | b"ID" | b"CH" | b"AP" | b"EE" | b"KY" | b"RN" | b"CA", false) => bad,
            _ => (AtStatus::INVALID_COMMAND, vec![]),
        }
    }
}

pub type Shared = Rc<RefCell<Model>>;

/// The host side of the radio's UART.
pub struct FakeSerial(pub Shared);

impl ErrorType for FakeSerial {
    type Error = ErrorKind;
}

impl Read<u8> for FakeSerial {
    fn read(&mut self) -> nb::Result<u8, ErrorKind> {
        self.0.borrow_mut().read().ok_or(nb::Error::WouldBlock)
    }
}

impl Write<u8> for FakeSerial {
    fn write(&mut self, b: u8) -> nb::Result<(), ErrorKind> {
        let mut m = self.0.borrow_mut();
        if m.write_blocked {
            m.now = m.now.wrapping_add(1);
            return Err(nb::Error::WouldBlock);
        }
        m.write(b);
        Ok(())
    }
    fn flush(&mut self) -> nb::Result<(), ErrorKind> {
        Ok(())
    }
}

impl SetBaud for FakeSerial {
    fn set_baud(&mut self, baud: u32) {
        let mut m = self.0.borrow_mut();
        m.host_baud = baud;
        m.host_bauds.push(baud);
    }
}

/// The model's clock. Panics if the driver spins on it without touching the UART, which would
/// hang a real radio-less board too.
pub struct FakeClock(pub Shared);

impl Clock for FakeClock {
    fn now_ms(&mut self) -> u32 {
        let mut m = self.0.borrow_mut();
        m.spins += 1;
        assert!(
            m.spins < 100_000,
            "driver spins on the clock without reading the UART"
        );
        m.now
    }
}

pub type TestRadio = Radio<FakeSerial, FakeClock>;

/// A model radio in `AP=ap` at `baud` and a driver for it in `mode`.
pub fn setup(ap: u8, baud: u32, mode: Mode) -> (Shared, TestRadio) {
    let m = Rc::new(RefCell::new(Model::new(ap, baud)));
    let radio = Radio::new(FakeSerial(m.clone()), FakeClock(m.clone()), mode);
    (m, radio)
}
