//! The driver through `serial::Eh02` (feature `embedded-hal-02`), over embedded-hal 0.2 serial
//! ports: embedded-hal-mock's mock, where every read, write and `WouldBlock` is an expected
//! transaction in order (so these show exactly what passes through the adapter each way), and
//! the scripted fake XBee of `tests/common` seen through the 0.2 traits (so bring-up runs
//! against a radio that has to be found in command mode at another baud rate).

mod common;

use std::cell::RefCell;
use std::rc::Rc;

use embedded_hal_02::serial as v02;
use embedded_hal_mock::eh0::serial::{Mock, Transaction as T};
use embedded_hal_mock::eh0::MockError;
use embedded_hal_nb::serial::ErrorKind;
use xbee_api::driver::{
    BringUp, BringUpConfig, Clock, Error, FnClock, Radio, SetBaud, BAUD, FIXED_SETTINGS,
    WRITE_TIMEOUT_MS,
};
use xbee_api::serial::{Eh02, Eh02Error, WithBaud};
use xbee_api::{AtStatus, Frame, Mode, Rssi, TxStatus, MAX_ENCODED};

use common::{FakeClock, FakeSerial, Model};

/// `f` encoded in API mode 2.
fn enc(f: &Frame<'_>) -> Vec<u8> {
    let mut buf = [0u8; MAX_ENCODED];
    let n = f.encode(Mode::Escaped, &mut buf).unwrap();
    buf[..n].to_vec()
}

fn at(frame_id: u8, command: &[u8; 2], parameter: &[u8]) -> Vec<u8> {
    enc(&Frame::AtCommand {
        frame_id,
        command: *command,
        parameter,
    })
}

fn at_ok(frame_id: u8, command: &[u8; 2], data: &[u8]) -> Vec<u8> {
    enc(&Frame::AtResponse {
        frame_id,
        command: *command,
        status: AtStatus::OK,
        data,
    })
}

/// An RX16 frame whose header and payload need escaping.
fn rx16() -> Vec<u8> {
    enc(&Frame::Rx16 {
        source: 0x7E11,
        rssi: Rssi(0x33),
        options: 0,
        data: &[0x7E, 0x7D, b'h', b'i'],
    })
}

fn would_block() -> nb::Error<MockError> {
    nb::Error::WouldBlock
}

fn io_error() -> nb::Error<MockError> {
    nb::Error::Other(MockError::Io(std::io::ErrorKind::Other))
}

/// A clock that goes 1 ms further at every look.
fn clock() -> FnClock<impl FnMut() -> u32> {
    let mut now = 0u32;
    FnClock(move || {
        now += 1;
        now
    })
}

type MockRadio<C> = Radio<Eh02<Mock<u8>>, C>;

fn radio(expected: &[T<u8>]) -> MockRadio<impl Clock> {
    Radio::new(Eh02(Mock::new(expected)), clock(), Mode::Escaped)
}

/// Checks that the mock saw every expected transaction.
fn done<C>(radio: MockRadio<C>) {
    radio.release().0.into_inner().done();
}

#[test]
fn send_tx16_writes_the_frame_and_retries_a_byte_on_would_block() {
    let frame = enc(&Frame::Tx16 {
        frame_id: 1,
        dest: 0x5001,
        options: 0,
        data: &[0x7E, b'h', b'i'],
    });
    // The port refuses the fourth byte twice, then takes it.
    let mut expected = vec![T::write_many(&frame[..3])];
    expected.push(T::write_error(frame[3], would_block()));
    expected.push(T::write_error(frame[3], would_block()));
    expected.push(T::write_many(&frame[3..]));
    let mut radio = radio(&expected);
    assert_eq!(radio.send_tx16(0x5001, &[0x7E, b'h', b'i']), Ok(1));
    assert!(radio.tx_pending());
    done(radio);
}

#[test]
fn poll_hands_over_a_frame_then_none_on_would_block() {
    let status = enc(&Frame::TxStatus {
        frame_id: 1,
        status: TxStatus::SUCCESS,
    });
    let expected = [
        T::write_many(enc(&Frame::Tx16 {
            frame_id: 1,
            dest: 0xFFFF,
            options: 0,
            data: b"b",
        })),
        T::read_many(rx16()),
        T::read_many(status),
        T::read_error(would_block()),
    ];
    let mut radio = radio(&expected);
    radio.send_tx16(0xFFFF, b"b").unwrap();
    let got = radio.poll(|raw| {
        raw.rx16()
            .map(|rx| (rx.source, rx.rssi.dbm(), rx.data.to_vec()))
    });
    assert_eq!(
        got,
        Some(Ok(Some((0x7E11, -0x33, vec![0x7E, 0x7D, b'h', b'i']))))
    );
    // The TX status frees the request.
    assert_eq!(
        radio.poll(|raw| raw.tx_status()),
        Some(Ok(Some((1, TxStatus::SUCCESS))))
    );
    assert!(!radio.tx_pending());
    assert_eq!(radio.poll(|_| ()), None);
    done(radio);
}

#[test]
fn a_read_error_is_a_serial_error_and_the_next_poll_goes_on() {
    let expected = [T::read_error(io_error()), T::read_many(rx16())];
    let mut radio = radio(&expected);
    assert_eq!(
        radio.poll(|_| ()),
        Some(Err(Error::Serial(ErrorKind::Other)))
    );
    assert_eq!(radio.stats().serial_errors, 1);
    assert_eq!(radio.poll(|raw| raw.rx16().is_some()), Some(Ok(true)));
    done(radio);
}

#[test]
fn a_write_error_fails_the_send() {
    let frame = at(1, b"CH", &[]);
    let expected = [
        T::write_many(&frame[..2]),
        T::write_error(frame[2], io_error()),
    ];
    let mut radio = radio(&expected);
    assert_eq!(
        radio.at_command(*b"CH", &[], 100, |_| {}),
        Err(Error::Serial(ErrorKind::Other))
    );
    assert_eq!(radio.stats().serial_errors, 1);
    done(radio);
}

#[test]
fn a_port_that_never_takes_a_byte_is_a_write_timeout() {
    // `clock()` goes 1 ms further at each look: the write's start, then one look per refusal.
    let expected: Vec<_> = (0..WRITE_TIMEOUT_MS)
        .map(|_| T::write_error(0x7E, would_block()))
        .collect();
    let mut radio = radio(&expected);
    assert_eq!(radio.send_tx16(0xFFFF, b"x"), Err(Error::WriteTimeout));
    assert!(!radio.tx_pending());
    done(radio);
}

#[test]
fn at_command_waits_through_would_block_and_passes_other_frames_on() {
    let mut expected = vec![T::write_many(at(1, b"CH", &[]))];
    expected.extend([T::read_error(would_block()), T::read_error(would_block())]);
    // A beacon arrives before the answer: it goes to `on_other`.
    expected.push(T::read_many(rx16()));
    expected.push(T::read_error(would_block()));
    expected.push(T::read_many(at_ok(1, b"CH", &[0x0C])));
    let mut radio = radio(&expected);
    let mut others = vec![];
    let value = radio.at_command(*b"CH", &[], 100, |raw| others.push(raw.frame_type()));
    assert_eq!(value.unwrap().as_bytes(), &[0x0C]);
    assert_eq!(others, [0x81]);
    done(radio);
}

#[test]
fn at_command_times_out_on_a_silent_port() {
    let frame = at(1, b"MY", &[]);
    // One look at the clock per byte written; then each wait round reads once (`WouldBlock`),
    // looks at the clock for the idle line and once more for the timeout: 2 ms a round.
    let timeout = 10;
    let mut expected = vec![T::write_many(frame)];
    expected.extend((0..timeout / 2).map(|_| T::read_error(would_block())));
    let mut radio = radio(&expected);
    assert_eq!(
        radio.at_command(*b"MY", &[], timeout, |_| {}),
        Err(Error::Timeout { command: *b"MY" })
    );
    done(radio);
}

#[test]
fn bring_up_of_a_radio_in_api_mode_with_the_baud_rate_from_a_closure() {
    let config = BringUpConfig {
        my: Some(0x0001),
        pan_id: Some(0x3332),
        channel: Some(0x0C),
        ..BringUpConfig::new()
    };
    // `AP` first: the radio answers 2, already in API mode 2. Then each register, answered OK.
    let mut expected = vec![
        T::write_many(at(1, b"AP", &[])),
        T::read_many(at_ok(1, b"AP", &[2])),
    ];
    let mut sets: Vec<([u8; 2], Vec<u8>)> = vec![
        (*b"MY", vec![0x00, 0x01]),
        (*b"ID", vec![0x33, 0x32]),
        (*b"CH", vec![0x0C]),
    ];
    sets.extend(FIXED_SETTINGS.iter().map(|&(c, v)| (c, vec![v])));
    for (id, (command, value)) in (2..).zip(&sets) {
        expected.push(T::write_many(at(id, command, value)));
        expected.push(T::read_many(at_ok(id, command, &[])));
    }
    let bauds = Rc::new(RefCell::new(vec![]));
    let serial = WithBaud::new(Eh02(Mock::new(&expected)), {
        let bauds = bauds.clone();
        move |_: &mut Eh02<Mock<u8>>, baud| bauds.borrow_mut().push(baud)
    });
    let mut radio = Radio::new(serial, clock(), Mode::Escaped);
    assert_eq!(radio.bring_up(&config), Ok(BringUp::AlreadyApi));
    assert_eq!(*bauds.borrow(), [BAUD]);
    radio.release().0.release().0.into_inner().done();
}

/// The fake XBee's port seen through the embedded-hal 0.2 traits, as a HAL's would be; it also
/// changes its rate itself, so `Eh02` passes `SetBaud` on.
struct V02Port(FakeSerial);

impl v02::Read<u8> for V02Port {
    type Error = ErrorKind;
    fn read(&mut self) -> nb::Result<u8, ErrorKind> {
        embedded_hal_nb::serial::Read::read(&mut self.0)
    }
}

impl v02::Write<u8> for V02Port {
    type Error = ErrorKind;
    fn write(&mut self, b: u8) -> nb::Result<(), ErrorKind> {
        embedded_hal_nb::serial::Write::write(&mut self.0, b)
    }
    fn flush(&mut self) -> nb::Result<(), ErrorKind> {
        embedded_hal_nb::serial::Write::flush(&mut self.0)
    }
}

impl SetBaud for V02Port {
    fn set_baud(&mut self, baud: u32) {
        self.0.set_baud(baud)
    }
}

#[test]
fn bring_up_finds_a_fresh_radio_at_9600_then_sends_and_polls() {
    // A radio as it leaves the factory: transparent mode (AP=0) at 9600.
    let m = Rc::new(RefCell::new(Model::new(0, 9600)));
    let serial = Eh02(V02Port(FakeSerial(m.clone())));
    let mut radio = Radio::new(serial, FakeClock(m.clone()), Mode::Escaped);
    let config = BringUpConfig {
        my: Some(0x0007),
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
        assert_eq!((m.ap, m.baud, m.my), (2, 57600, 0x0007));
        assert_eq!(m.host_bauds, [57600, 57600, 9600, 57600]);
    }
    let id = radio.send_tx16(0xFFFF, b"beacon").unwrap();
    radio.wait_tx_status(100, |_| {}).unwrap();
    assert!(!radio.tx_pending());
    assert_eq!(
        m.borrow().host_frames().last().unwrap(),
        &format!("TX16 id={id}")
    );
    assert_eq!(
        radio.read_config(100, |_| {}).map(|c| (c.my, c.ap)),
        Ok((0x0007, 2))
    );
}

#[test]
fn errors_of_the_0_2_port_are_kept() {
    use embedded_hal_nb::serial::{Error as _, Read};
    let mut port = Eh02(Mock::new(&[T::read_error(io_error())]));
    let e = port.read().unwrap_err();
    assert_eq!(
        e,
        nb::Error::Other(Eh02Error::Read(MockError::Io(std::io::ErrorKind::Other)))
    );
    if let nb::Error::Other(e) = e {
        assert_eq!(e.kind(), ErrorKind::Other);
        assert_eq!(e.to_string(), "serial read error: Io(Other)");
    }
    port.0.done();
}
