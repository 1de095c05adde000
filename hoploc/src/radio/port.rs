//! The serial ports and clocks [`super::read`] and [`super::restore`] run on: a real serial
//! port in real time ([`UsbPort`], [`WallClock`]), or the modelled XBee of `simavr` in simulated
//! time ([`ModelPort`], [`ModelClock`]).

use std::collections::VecDeque;
use std::io::{self, Read as _, Write as _};
use std::time::{Duration, Instant};

use embedded_hal_nb::serial::{ErrorKind, ErrorType, Read, Write};
pub use simavr::xbee::{ModelClock, ModelPort};
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
