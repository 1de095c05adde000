//! The driver through `serial::Io06` and `serial::Io07` (features `embedded-io-06`,
//! `embedded-io-07`), over embedded-io ports: a scripted mock port ([`Port`]) that fails the test
//! if a blocking `read` or `write` is called without its `read_ready`/`write_ready` saying yes
//! (on a real port that call would block), and the scripted fake XBee of `tests/common` seen
//! through the embedded-io traits, for bring-up. Every test runs once per embedded-io version.

mod common;

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use embedded_hal_nb::serial::ErrorKind;
use xbee_api::driver::{
    BringUp, BringUpConfig, Clock, Error, FnClock, Radio, SetBaud, WRITE_TIMEOUT_MS,
};
use xbee_api::serial::{IoError, WithBaud};
use xbee_api::{AtStatus, Frame, Mode, Rssi, TxStatus, MAX_ENCODED};

use common::{FakeClock, FakeSerial, Model};

/// `f` encoded in API mode 2.
fn enc(f: &Frame<'_>) -> Vec<u8> {
    let mut buf = [0u8; MAX_ENCODED];
    let n = f.encode(Mode::Escaped, &mut buf).unwrap();
    buf[..n].to_vec()
}

fn rx16() -> Vec<u8> {
    enc(&Frame::Rx16 {
        source: 0x7E11,
        rssi: Rssi(0x33),
        options: 0,
        data: &[0x7E, 0x7D, b'h', b'i'],
    })
}

/// A clock that goes 1 ms further at every look.
fn clock() -> FnClock<impl FnMut() -> u32> {
    let mut now = 0u32;
    FnClock(move || {
        now += 1;
        now
    })
}

/// The mock port's error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PortError;

impl std::fmt::Display for PortError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("port error")
    }
}

impl std::error::Error for PortError {}

/// What the next look at the receive side finds.
#[derive(Clone, Copy, Debug)]
enum Rx {
    /// A byte: `read_ready` says yes, `read` gives it.
    Byte(u8),
    /// `read_ready` says no, once.
    NotReady,
    /// `read_ready` fails.
    ReadyError,
    /// `read_ready` says yes, `read` fails.
    ReadError,
    /// `read_ready` says yes, `read` gives 0 bytes.
    Zero,
}

/// What the next write attempt finds; with nothing planned the port takes the byte.
#[derive(Clone, Copy, Debug)]
enum Tx {
    /// `write_ready` says no, once.
    NotReady,
    /// `write_ready` fails.
    ReadyError,
    /// `write_ready` says yes, `write` fails.
    WriteError,
    /// `write_ready` says yes, `write` takes 0 bytes.
    Zero,
}

/// A scripted embedded-io port.
#[derive(Default)]
struct Port {
    rx: VecDeque<Rx>,
    tx: VecDeque<Tx>,
    written: Vec<u8>,
    /// `read_ready` said yes and nothing was read since.
    rx_ready: bool,
    /// `write_ready` said yes and nothing was written since.
    tx_ready: bool,
}

impl Port {
    fn new(rx: impl IntoIterator<Item = Rx>, tx: impl IntoIterator<Item = Tx>) -> Self {
        Port {
            rx: rx.into_iter().collect(),
            tx: tx.into_iter().collect(),
            ..Port::default()
        }
    }

    fn read_ready(&mut self) -> Result<bool, PortError> {
        if self.rx_ready {
            return Ok(true);
        }
        match self.rx.front() {
            None => Ok(false),
            Some(Rx::NotReady) => {
                self.rx.pop_front();
                Ok(false)
            }
            Some(Rx::ReadyError) => {
                self.rx.pop_front();
                Err(PortError)
            }
            Some(_) => {
                self.rx_ready = true;
                Ok(true)
            }
        }
    }

    fn read(&mut self, buf: &mut [u8]) -> Result<usize, PortError> {
        assert!(self.rx_ready, "read without read_ready: it would block");
        assert!(!buf.is_empty());
        self.rx_ready = false;
        match self.rx.pop_front() {
            Some(Rx::Byte(b)) => {
                buf[0] = b;
                Ok(1)
            }
            Some(Rx::ReadError) => Err(PortError),
            Some(Rx::Zero) => Ok(0),
            other => unreachable!("{other:?}"),
        }
    }

    fn write_ready(&mut self) -> Result<bool, PortError> {
        match self.tx.front() {
            Some(Tx::NotReady) => {
                self.tx.pop_front();
                Ok(false)
            }
            Some(Tx::ReadyError) => {
                self.tx.pop_front();
                Err(PortError)
            }
            _ => {
                self.tx_ready = true;
                Ok(true)
            }
        }
    }

    fn write(&mut self, buf: &[u8]) -> Result<usize, PortError> {
        assert!(self.tx_ready, "write without write_ready: it would block");
        self.tx_ready = false;
        match self.tx.front() {
            Some(Tx::WriteError) => {
                self.tx.pop_front();
                Err(PortError)
            }
            Some(Tx::Zero) => {
                self.tx.pop_front();
                Ok(0)
            }
            _ => {
                self.written.push(buf[0]);
                Ok(1)
            }
        }
    }
}

fn bytes(b: &[u8]) -> impl Iterator<Item = Rx> + '_ {
    b.iter().map(|&b| Rx::Byte(b))
}

/// The fake XBee's port seen through the embedded-io traits; `read_ready` looks ahead one byte.
struct IoPort {
    serial: FakeSerial,
    ahead: Option<u8>,
}

impl IoPort {
    fn read_ready(&mut self) -> Result<bool, PortError> {
        if self.ahead.is_none() {
            self.ahead = embedded_hal_nb::serial::Read::read(&mut self.serial).ok();
        }
        Ok(self.ahead.is_some())
    }

    fn read(&mut self, buf: &mut [u8]) -> Result<usize, PortError> {
        let b = self.ahead.take().expect("read without read_ready");
        buf[0] = b;
        Ok(1)
    }

    fn write(&mut self, buf: &[u8]) -> Result<usize, PortError> {
        nb::block!(embedded_hal_nb::serial::Write::write(
            &mut self.serial,
            buf[0]
        ))
        .unwrap();
        Ok(1)
    }
}

/// The embedded-io traits of one version for [`Port`] and [`IoPort`], the error's too.
macro_rules! impl_io {
    ($io:ident) => {
        impl $io::Error for PortError {
            fn kind(&self) -> $io::ErrorKind {
                $io::ErrorKind::Other
            }
        }

        impl $io::ErrorType for Port {
            type Error = PortError;
        }
        impl $io::Read for Port {
            fn read(&mut self, buf: &mut [u8]) -> Result<usize, PortError> {
                Port::read(self, buf)
            }
        }
        impl $io::ReadReady for Port {
            fn read_ready(&mut self) -> Result<bool, PortError> {
                Port::read_ready(self)
            }
        }
        impl $io::Write for Port {
            fn write(&mut self, buf: &[u8]) -> Result<usize, PortError> {
                Port::write(self, buf)
            }
            fn flush(&mut self) -> Result<(), PortError> {
                Ok(())
            }
        }
        impl $io::WriteReady for Port {
            fn write_ready(&mut self) -> Result<bool, PortError> {
                Port::write_ready(self)
            }
        }

        impl $io::ErrorType for IoPort {
            type Error = PortError;
        }
        impl $io::Read for IoPort {
            fn read(&mut self, buf: &mut [u8]) -> Result<usize, PortError> {
                IoPort::read(self, buf)
            }
        }
        impl $io::ReadReady for IoPort {
            fn read_ready(&mut self) -> Result<bool, PortError> {
                IoPort::read_ready(self)
            }
        }
        impl $io::Write for IoPort {
            fn write(&mut self, buf: &[u8]) -> Result<usize, PortError> {
                IoPort::write(self, buf)
            }
            fn flush(&mut self) -> Result<(), PortError> {
                Ok(())
            }
        }
        impl $io::WriteReady for IoPort {
            fn write_ready(&mut self) -> Result<bool, PortError> {
                Ok(true)
            }
        }
    };
}

impl_io!(embedded_io_06);
impl_io!(embedded_io_07);

/// The tests, for the adapter `$Io`.
macro_rules! adapter_tests {
    ($module:ident, $Io:ident) => {
        mod $module {
            use super::*;
            use xbee_api::serial::$Io;

            fn radio(port: Port) -> Radio<$Io<Port>, impl Clock> {
                Radio::new($Io(port), clock(), Mode::Escaped)
            }

            fn port<C>(radio: Radio<$Io<Port>, C>) -> Port {
                radio.release().0.into_inner()
            }

            #[test]
            fn send_tx16_waits_until_the_port_is_ready_for_each_byte() {
                let payload = [0x7E, b'h', b'i'];
                let frame = enc(&Frame::Tx16 {
                    frame_id: 1,
                    dest: 0x5001,
                    options: 0,
                    data: &payload,
                });
                // Not ready twice, then a write that takes nothing: the byte is written again.
                let mut radio = radio(Port::new([], [Tx::NotReady, Tx::NotReady, Tx::Zero]));
                assert_eq!(radio.send_tx16(0x5001, &payload), Ok(1));
                let port = port(radio);
                assert_eq!(port.written, frame);
                assert!(port.tx.is_empty());
            }

            #[test]
            fn poll_reads_only_what_is_ready() {
                let frame = rx16();
                let status = enc(&Frame::TxStatus {
                    frame_id: 1,
                    status: TxStatus::NO_ACK,
                });
                // A pause in the middle of the frame, an empty read, then a TX status.
                let mut rx: Vec<Rx> = bytes(&frame[..5]).collect();
                rx.extend([Rx::NotReady, Rx::Zero]);
                rx.extend(bytes(&frame[5..]));
                rx.extend(bytes(&status));
                let mut radio = radio(Port::new(rx, []));
                assert_eq!(radio.poll(|_| ()), None);
                assert_eq!(radio.poll(|_| ()), None);
                let got = radio.poll(|raw| raw.rx16().map(|rx| (rx.source, rx.data.to_vec())));
                assert_eq!(got, Some(Ok(Some((0x7E11, vec![0x7E, 0x7D, b'h', b'i'])))));
                let got = radio.poll(|raw| raw.tx_status());
                assert_eq!(got, Some(Ok(Some((1, TxStatus::NO_ACK)))));
                assert_eq!(radio.poll(|_| ()), None);
                assert_eq!(radio.stats().decoder.frames, 2);
            }

            #[test]
            fn read_errors_are_serial_errors_and_the_next_poll_goes_on() {
                let mut rx = vec![Rx::ReadyError, Rx::ReadError];
                rx.extend(bytes(&rx16()));
                let mut radio = radio(Port::new(rx, []));
                let serial = Some(Err(Error::Serial(ErrorKind::Other)));
                assert_eq!(radio.poll(|_| ()), serial);
                assert_eq!(radio.poll(|_| ()), serial);
                assert_eq!(radio.poll(|raw| raw.rx16().is_some()), Some(Ok(true)));
                assert_eq!(radio.stats().serial_errors, 2);
            }

            #[test]
            fn write_errors_fail_the_send() {
                for tx in [Tx::ReadyError, Tx::WriteError] {
                    let mut radio = radio(Port::new([], [Tx::NotReady, tx]));
                    assert_eq!(
                        radio.send_tx16(0xFFFF, b"x"),
                        Err(Error::Serial(ErrorKind::Other)),
                        "{tx:?}"
                    );
                    assert!(!radio.tx_pending());
                    assert!(port(radio).written.is_empty());
                }
            }

            #[test]
            fn a_port_never_ready_to_write_is_a_write_timeout() {
                let never = vec![Tx::NotReady; 2 * WRITE_TIMEOUT_MS as usize];
                let mut radio = radio(Port::new([], never));
                assert_eq!(radio.send_tx16(0xFFFF, b"x"), Err(Error::WriteTimeout));
                assert!(port(radio).written.is_empty());
            }

            #[test]
            fn at_command_waits_for_its_answer_and_passes_other_frames_on() {
                let mut rx = vec![Rx::NotReady, Rx::NotReady];
                rx.extend(bytes(&rx16()));
                rx.push(Rx::NotReady);
                rx.extend(bytes(&enc(&Frame::AtResponse {
                    frame_id: 1,
                    command: *b"CH",
                    status: AtStatus::OK,
                    data: &[0x0C],
                })));
                let mut radio = radio(Port::new(rx, []));
                let mut others = vec![];
                let value = radio.at_command(*b"CH", &[], 100, |raw| others.push(raw.frame_type()));
                assert_eq!(value.unwrap().as_bytes(), &[0x0C]);
                assert_eq!(others, [0x81]);
                let at = enc(&Frame::AtCommand {
                    frame_id: 1,
                    command: *b"CH",
                    parameter: &[],
                });
                assert_eq!(port(radio).written, at);
            }

            #[test]
            fn at_command_times_out_on_a_silent_port() {
                let mut radio = radio(Port::new([], []));
                assert_eq!(
                    radio.at_command(*b"MY", &[], 20, |_| {}),
                    Err(Error::Timeout { command: *b"MY" })
                );
            }

            #[test]
            fn bring_up_finds_a_fresh_radio_at_9600_with_the_baud_rate_from_a_closure() {
                let m = Rc::new(RefCell::new(Model::new(0, 9600)));
                let port = IoPort {
                    serial: FakeSerial(m.clone()),
                    ahead: None,
                };
                let serial = WithBaud::new($Io(port), |io: &mut $Io<IoPort>, baud| {
                    io.0.serial.set_baud(baud)
                });
                let mut radio = Radio::new(serial, FakeClock(m.clone()), Mode::Escaped);
                let config = BringUpConfig {
                    channel: Some(0x0D),
                    guard_ms: 25, // the model's GT is 20 ms
                    timeout_ms: 50,
                    ..BringUpConfig::new()
                };
                assert_eq!(
                    radio.bring_up(&config),
                    Ok(BringUp::Configured { baud: 9600 })
                );
                {
                    let m = m.borrow();
                    assert_eq!((m.ap, m.baud, m.ch), (2, 57600, 0x0D));
                    assert_eq!(m.host_bauds, [57600, 57600, 9600, 57600]);
                }
                radio.send_tx16(0x0002, b"hi").unwrap();
                radio.set_channel(0x0E, 100, |_| {}).unwrap();
                assert_eq!(m.borrow().ch, 0x0E);
            }

            #[test]
            fn errors_of_the_port_are_kept() {
                use embedded_hal_nb::serial::{Error as _, Read};
                let mut io = $Io(Port::new([Rx::ReadError], []));
                assert_eq!(io.read(), Err(nb::Error::Other(IoError(PortError))));
                assert_eq!(IoError(PortError).kind(), ErrorKind::Other);
                assert_eq!(
                    IoError(PortError).to_string(),
                    "serial I/O error: PortError"
                );
            }
        }
    };
}

adapter_tests!(io06, Io06);
adapter_tests!(io07, Io07);
