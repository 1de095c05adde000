//! The serial ports and clocks [`super::read`] and [`super::restore`] run on: a real serial
//! port in real time ([`UsbPort`], [`WallClock`]), or the modelled XBee of `simavr` in simulated
//! time ([`ModelPort`], [`ModelClock`]).

use std::cell::{RefCell, RefMut};
use std::collections::VecDeque;
use std::io::{self, Read as _, Write as _};
use std::rc::Rc;
use std::time::{Duration, Instant};

use embedded_hal_nb::serial::{ErrorKind, ErrorType, Read, Write};
use simavr::xbee::{byte_cycles, XBeeConfig, XBeeCore};
use simavr::{cycles_to_ms, ms_to_cycles};
use xbee_api::driver::{Clock, SetBaud, BAUD};

use super::RadioError;

/// A serial port (`serialport`) as the driver's serial traits: 8N1, any rate (`BD=7`'s 111 111
/// bit/s included, where the adapter's UART can make it). A read waits at most the port's read
/// wait for a byte; an I/O error is kept for the message ([`UsbPort::explain`]) and reported to
/// the driver as [`ErrorKind::Other`].
pub struct UsbPort {
    name: String,
    port: Box<dyn serialport::SerialPort>,
    rx: VecDeque<u8>,
    error: Option<String>,
}

impl UsbPort {
    /// Opens `name` at 57600 bit/s; a read waits at most `read_wait` for a byte.
    pub fn open(name: &str, read_wait: Duration) -> Result<UsbPort, RadioError> {
        let port = serialport::new(name, BAUD)
            .timeout(read_wait)
            .open()
            .map_err(|e| RadioError::Open {
                port: name.to_string(),
                reason: e.to_string(),
            })?;
        Ok(UsbPort {
            name: name.to_string(),
            port,
            rx: VecDeque::new(),
            error: None,
        })
    }

    /// `e` for the user: a failed port says its own reason.
    pub fn explain(&self, e: RadioError) -> String {
        match (e, &self.error) {
            (RadioError::Port(_), Some(reason)) => format!("serial port {}: {reason}", self.name),
            (RadioError::Port(reason), None) => format!("serial port {}: {reason}", self.name),
            (e, _) => e.to_string(),
        }
    }

    fn failed(&mut self, e: io::Error) -> nb::Error<ErrorKind> {
        self.error = Some(e.to_string());
        nb::Error::Other(ErrorKind::Other)
    }
}

impl ErrorType for UsbPort {
    type Error = ErrorKind;
}

impl Read<u8> for UsbPort {
    fn read(&mut self) -> nb::Result<u8, ErrorKind> {
        if self.rx.is_empty() {
            let mut buf = [0u8; 256];
            match self.port.read(&mut buf) {
                Ok(n) => self.rx.extend(&buf[..n]),
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::TimedOut
                            | io::ErrorKind::WouldBlock
                            | io::ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(self.failed(e)),
            }
        }
        self.rx.pop_front().ok_or(nb::Error::WouldBlock)
    }
}

impl Write<u8> for UsbPort {
    fn write(&mut self, b: u8) -> nb::Result<(), ErrorKind> {
        self.port.write_all(&[b]).map_err(|e| self.failed(e))
    }

    fn flush(&mut self) -> nb::Result<(), ErrorKind> {
        self.port.flush().map_err(|e| self.failed(e))
    }
}

impl SetBaud for UsbPort {
    /// Waits until what was written is out, switches the rate, and drops what came in at the
    /// old one.
    fn set_baud(&mut self, baud: u32) {
        let r = self
            .port
            .flush()
            .and_then(|()| self.port.set_baud_rate(baud).map_err(io::Error::from))
            .and_then(|()| {
                self.port
                    .clear(serialport::ClearBuffer::Input)
                    .map_err(io::Error::from)
            });
        if let Err(e) = r {
            // The next read or write reports it.
            self.error = Some(format!("switching to {baud} bit/s: {e}"));
        }
        self.rx.clear();
    }
}

/// Milliseconds since it was made, from [`Instant`].
pub struct WallClock(Instant);

impl WallClock {
    /// A clock starting at 0 now.
    pub fn new() -> WallClock {
        WallClock(Instant::now())
    }
}

impl Default for WallClock {
    fn default() -> Self {
        WallClock::new()
    }
}

impl Clock for WallClock {
    fn now_ms(&mut self) -> u32 {
        self.0.elapsed().as_millis() as u32
    }
}

/// Simulated time advanced by every read and every look at the clock: 10 µs.
const STEP_CYCLES: u64 = 160;

/// What is at the other end of a [`ModelPort`].
enum Peer {
    /// A modelled XBee.
    Radio(Box<XBeeCore>),
    /// Nothing: no byte ever comes back.
    Nothing,
    /// Another device writing `text` over and over, whatever the host's rate.
    Babbler {
        text: Vec<u8>,
        next: usize,
        /// Cycle the next byte arrives.
        at: u64,
    },
}

struct Sim {
    peer: Peer,
    /// Simulated time, cycles at `simavr::F_CPU`.
    now: u64,
    baud: u32,
    /// Bytes to the host: (cycle they are read, byte).
    rx: VecDeque<(u64, u8)>,
    bauds: Vec<u32>,
}

impl Sim {
    fn tick(&mut self, dt: u64) {
        self.now += dt;
        let cpb = byte_cycles(self.baud);
        match &mut self.peer {
            Peer::Radio(core) => {
                core.advance(self.now);
                for b in core.take_output() {
                    self.rx.push_back((b.cycle + cpb, b.byte));
                }
            }
            Peer::Nothing => {}
            Peer::Babbler { text, next, at } => {
                while *at <= self.now && !text.is_empty() {
                    self.rx.push_back((*at, text[*next % text.len()]));
                    *next += 1;
                    *at += byte_cycles(BAUD);
                }
            }
        }
    }
}

/// A host serial port on a modelled XBee (`simavr::xbee::XBeeCore`), or on nothing, or on a
/// device that never stops writing: simulated time, so a test runs the guard times and timeouts
/// of a real search in a fraction of a second. Each read and each look at its [`ModelClock`]
/// advances 10 µs; a write takes the byte's time at the host's rate.
pub struct ModelPort(Rc<RefCell<Sim>>);

/// The clock of a [`ModelPort`] ([`ModelPort::clock`]): its simulated milliseconds.
pub struct ModelClock(Rc<RefCell<Sim>>);

impl ModelPort {
    fn with(peer: Peer) -> ModelPort {
        ModelPort(Rc::new(RefCell::new(Sim {
            peer,
            now: 0,
            baud: BAUD,
            rx: VecDeque::new(),
            bauds: Vec::new(),
        })))
    }

    /// A port on a modelled radio that starts as `cfg` says, powered up a while ago (what it
    /// sent at power-up is gone). The radio sits on a USB adapter: its `SLEEP_RQ` is driven
    /// low, so a radio in pin sleep is awake ([`XBeeConfig::sleep_rq`]).
    pub fn radio(cfg: XBeeConfig) -> ModelPort {
        let cfg = XBeeConfig {
            sleep_rq: false,
            ..cfg
        };
        let port = ModelPort::with(Peer::Radio(Box::new(XBeeCore::new(cfg))));
        port.power_cycle();
        port
    }

    /// A port with nothing on it.
    pub fn nothing() -> ModelPort {
        ModelPort::with(Peer::Nothing)
    }

    /// A port on a device that writes `text` over and over, back to back at 57600 bit/s,
    /// whatever rate the host listens at (an Uno's own serial, say).
    pub fn babbler(text: &[u8]) -> ModelPort {
        ModelPort::with(Peer::Babbler {
            text: text.to_vec(),
            next: 0,
            at: 0,
        })
    }

    /// Its clock.
    pub fn clock(&self) -> ModelClock {
        ModelClock(self.0.clone())
    }

    /// The modelled radio, if there is one (to look at its registers, or power-cycle it).
    pub fn core(&self) -> Option<RefMut<'_, XBeeCore>> {
        RefMut::filter_map(self.0.borrow_mut(), |s| match &mut s.peer {
            Peer::Radio(core) => Some(&mut **core),
            _ => None,
        })
        .ok()
    }

    /// Power-cycles the modelled radio now: it comes back with the settings it saved (`WR`).
    pub fn power_cycle(&self) {
        let mut s = self.0.borrow_mut();
        let now = s.now;
        if let Peer::Radio(core) = &mut s.peer {
            core.reset(now);
        }
        s.rx.clear();
        // Past its power-up.
        s.tick(ms_to_cycles(20.0));
    }

    /// Simulated time so far, ms.
    pub fn elapsed_ms(&self) -> f64 {
        cycles_to_ms(self.0.borrow().now)
    }

    /// Every rate the host switched to, in order.
    pub fn bauds(&self) -> Vec<u32> {
        self.0.borrow().bauds.clone()
    }
}

impl ErrorType for ModelPort {
    type Error = ErrorKind;
}

impl Read<u8> for ModelPort {
    fn read(&mut self) -> nb::Result<u8, ErrorKind> {
        let mut s = self.0.borrow_mut();
        s.tick(STEP_CYCLES);
        match s.rx.front() {
            Some(&(at, b)) if at <= s.now => {
                s.rx.pop_front();
                Ok(b)
            }
            _ => Err(nb::Error::WouldBlock),
        }
    }
}

impl Write<u8> for ModelPort {
    fn write(&mut self, b: u8) -> nb::Result<(), ErrorKind> {
        let mut s = self.0.borrow_mut();
        let end = s.now + byte_cycles(s.baud);
        if let Peer::Radio(core) = &mut s.peer {
            core.rx_byte(end, b);
        }
        s.now = end;
        s.tick(0);
        Ok(())
    }

    fn flush(&mut self) -> nb::Result<(), ErrorKind> {
        Ok(())
    }
}

impl SetBaud for ModelPort {
    fn set_baud(&mut self, baud: u32) {
        let mut s = self.0.borrow_mut();
        s.baud = baud;
        s.bauds.push(baud);
        if let Peer::Radio(core) = &mut s.peer {
            core.set_host_baud(baud);
        }
        // What was on its way at the old rate is lost with the switch.
        s.rx.clear();
    }
}

impl Clock for ModelClock {
    fn now_ms(&mut self) -> u32 {
        let mut s = self.0.borrow_mut();
        s.tick(STEP_CYCLES);
        cycles_to_ms(s.now) as u32
    }
}
