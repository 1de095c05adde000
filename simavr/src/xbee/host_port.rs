//! A host serial port on a modelled XBee ([`ModelPort`], with its clock [`ModelClock`]): what a
//! program that drives a radio through `xbee_api::driver` (the embedded-hal-nb serial traits,
//! [`SetBaud`], [`Clock`]) runs on in tests, in simulated time, so that the guard times and
//! timeouts of a real radio search take a fraction of a second.

use std::cell::{RefCell, RefMut};
use std::collections::VecDeque;
use std::rc::Rc;

use embedded_hal_nb::serial::{ErrorKind, ErrorType, Read, Write};
use xbee_api::driver::{Clock, SetBaud, BAUD};

use super::{byte_cycles, XBeeConfig, XBeeCore};
use crate::{cycles_to_ms, ms_to_cycles};

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
/// advances 10 µs; a write takes the byte's time at the host's rate. A clone is another handle
/// on the same port (to look at the radio while a driver owns the port).
#[derive(Clone)]
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

    /// A port on a modelled radio that powers up as `cfg` says at time 0, with the port.
    pub fn radio_at_power_up(cfg: XBeeConfig) -> ModelPort {
        ModelPort::with(Peer::Radio(Box::new(XBeeCore::new(cfg))))
    }

    /// Simulated time so far, cycles at [`crate::F_CPU`].
    pub fn now(&self) -> u64 {
        self.0.borrow().now
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
