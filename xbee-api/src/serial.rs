//! Serial ports for the [driver](crate::driver): what [`Radio`](crate::driver::Radio) needs, and
//! adapters from the serial traits HALs implement.
//!
//! The driver reads and writes one byte at a time and never waits on the port itself: a read
//! that finds nothing, or a write the port cannot take yet, must return
//! [`nb::Error::WouldBlock`] at once, and the driver bounds every wait with its
//! [`Clock`](crate::driver::Clock). That is the `embedded-hal-nb` 1.0 serial traits,
//! [`Read<u8>`](embedded_hal_nb::serial::Read) + [`Write<u8>`](embedded_hal_nb::serial::Write).
//! A HAL whose UART implements another trait family goes through one of the newtypes here,
//! each behind an opt-in cargo feature (off by default; with the features off this module holds
//! only [`WithBaud`], which costs nothing unless used):
//!
//! | the HAL's serial port implements | wrap it in | cargo feature |
//! |---|---|---|
//! | `embedded-hal-nb` 1.0 `serial::{Read<u8>, Write<u8>}` | nothing: it plugs in as it is | — |
//! | `embedded-hal` 0.2 `serial::{Read<u8>, Write<u8>}` (avr-hal's `arduino_hal::Usart`, for one) | `Eh02` | `embedded-hal-02` |
//! | `embedded-io` 0.6 `Read + ReadReady + Write + WriteReady` | `Io06` | `embedded-io-06` |
//! | `embedded-io` 0.7 `Read + ReadReady + Write + WriteReady` | `Io07` | `embedded-io-07` |
//!
//! Why a newtype: Rust's orphan rule forbids implementing a trait of one crate (here
//! `embedded-hal-nb`'s) for a type of another (the HAL's UART) in a third (the firmware). So the
//! impl lives on a wrapper type of this crate, and the firmware wraps its UART:
//! `Radio::new(Eh02(usart), clock, mode)`.
//!
//! `embedded-io`'s `Read` and `Write` block until they have moved at least one byte, so `Io06`
//! and `Io07` ask `ReadReady`/`WriteReady` first and answer `WouldBlock` when the port is not
//! ready; a port without those two traits cannot be driven without blocking and is not
//! supported.
//!
//! [`Radio::bring_up`](crate::driver::Radio::bring_up) also changes the UART's baud rate while
//! it looks for the radio, through [`SetBaud`]. A HAL's UART cannot implement that trait either
//! (same orphan rule): [`WithBaud`] adds it from a closure, around any of the above.
//! `Eh02`, `Io06` and `Io07` also pass [`SetBaud`] on when what they wrap implements it (a
//! firmware's own serial type, say).

use embedded_hal_nb::serial::{ErrorType, Read, Write};

use crate::driver::SetBaud;

/// A serial port with [`SetBaud`] from a closure, for a port that does not implement it itself
/// (a HAL's type, which the firmware's crate may not implement this crate's trait for).
///
/// `set_baud(&mut serial, baud)` must switch the UART to `baud` bit/s, 8N1; the driver calls it
/// only during [`Radio::bring_up`](crate::driver::Radio::bring_up), after the radio has answered
/// its last command (the UART has nothing left to send). Reads and writes go to `S` unchanged.
///
/// ```
/// use embedded_hal_nb::serial::{ErrorKind, ErrorType, Read, Write};
/// use xbee_api::driver::SetBaud;
/// use xbee_api::serial::WithBaud;
///
/// # struct Uart { baud: u32 }
/// # impl Uart { fn reconfigure(&mut self, baud: u32) { self.baud = baud } }
/// # impl ErrorType for Uart { type Error = ErrorKind; }
/// # impl Read<u8> for Uart { fn read(&mut self) -> nb::Result<u8, ErrorKind> { Err(nb::Error::WouldBlock) } }
/// # impl Write<u8> for Uart {
/// #     fn write(&mut self, _: u8) -> nb::Result<(), ErrorKind> { Ok(()) }
/// #     fn flush(&mut self) -> nb::Result<(), ErrorKind> { Ok(()) }
/// # }
/// // `Uart` is some HAL's UART (it implements the embedded-hal-nb serial traits).
/// let mut serial = WithBaud::new(Uart { baud: 9600 }, |uart: &mut Uart, baud| uart.reconfigure(baud));
/// serial.set_bd(6); // what bring-up does: BD=6 is 57600 bit/s
/// assert_eq!(serial.serial().baud, 57_600);
/// ```
#[derive(Clone, Copy, Debug)]
pub struct WithBaud<S, F> {
    serial: S,
    set_baud: F,
}

impl<S, F> WithBaud<S, F>
where
    F: FnMut(&mut S, u32),
{
    /// `serial`, whose baud rate `set_baud(&mut serial, baud)` changes.
    pub const fn new(serial: S, set_baud: F) -> Self {
        WithBaud { serial, set_baud }
    }
}

impl<S, F> WithBaud<S, F> {
    /// The serial port.
    pub const fn serial(&self) -> &S {
        &self.serial
    }

    /// The serial port, e.g. to write text between frames.
    pub fn serial_mut(&mut self) -> &mut S {
        &mut self.serial
    }

    /// The serial port and the closure back.
    pub fn release(self) -> (S, F) {
        (self.serial, self.set_baud)
    }
}

impl<S, F> SetBaud for WithBaud<S, F>
where
    F: FnMut(&mut S, u32),
{
    fn set_baud(&mut self, baud: u32) {
        (self.set_baud)(&mut self.serial, baud)
    }
}

impl<S: ErrorType, F> ErrorType for WithBaud<S, F> {
    type Error = S::Error;
}

impl<S: Read<u8>, F> Read<u8> for WithBaud<S, F> {
    #[inline]
    fn read(&mut self) -> nb::Result<u8, S::Error> {
        self.serial.read()
    }
}

impl<S: Write<u8>, F> Write<u8> for WithBaud<S, F> {
    #[inline]
    fn write(&mut self, word: u8) -> nb::Result<(), S::Error> {
        self.serial.write(word)
    }

    #[inline]
    fn flush(&mut self) -> nb::Result<(), S::Error> {
        self.serial.flush()
    }
}

#[cfg(feature = "embedded-hal-02")]
pub use eh02::{Eh02, Eh02Error};

#[cfg(feature = "embedded-hal-02")]
mod eh02 {
    use core::fmt;

    use embedded_hal_02::serial as v02;
    use embedded_hal_nb::serial::{self as v1, ErrorKind};

    use crate::driver::SetBaud;

    /// An `embedded-hal` 0.2 serial port (`serial::Read<u8>` + `serial::Write<u8>`) as the
    /// `embedded-hal-nb` 1.0 one [`Radio`](crate::driver::Radio) takes. Feature
    /// `embedded-hal-02`.
    ///
    /// The two families have the same non-blocking shape (`nb::Result`, `WouldBlock` when the
    /// port is not ready), so each read and write goes straight through; only the errors are
    /// wrapped ([`Eh02Error`]). The one port must both read and write (the driver owns it
    /// whole): avr-hal's `arduino_hal::Usart` is such a port, its `split` halves are not.
    ///
    /// ```ignore
    /// let usart = arduino_hal::Usart::new(dp.USART0, pins.d0, pins.d1.into_output(), Baudrate::new(57_600));
    /// let mut radio = Radio::new(Eh02(usart), FnClock(millis), Mode::Escaped);
    /// ```
    ///
    /// The crate's `examples/arduino_uno.rs` is a whole arduino-hal firmware with it (see
    /// [`driver`](crate::driver#a-firmware-on-arduino-hal)).
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
    pub struct Eh02<S>(pub S);

    impl<S> Eh02<S> {
        /// The port back.
        pub fn into_inner(self) -> S {
            self.0
        }
    }

    /// An error of an [`Eh02`] port: the wrapped port's read or write error. Its
    /// [`kind`](v1::Error::kind) is [`ErrorKind::Other`] (the 0.2 traits have no error kinds);
    /// the driver reports it as [`Error::Serial`](crate::driver::Error::Serial).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum Eh02Error<R, W> {
        /// From `serial::Read::read`.
        Read(R),
        /// From `serial::Write::write` or `flush`.
        Write(W),
    }

    impl<R: fmt::Debug, W: fmt::Debug> v1::Error for Eh02Error<R, W> {
        fn kind(&self) -> ErrorKind {
            ErrorKind::Other
        }
    }

    impl<R: fmt::Debug, W: fmt::Debug> fmt::Display for Eh02Error<R, W> {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            match self {
                Eh02Error::Read(e) => write!(f, "serial read error: {e:?}"),
                Eh02Error::Write(e) => write!(f, "serial write error: {e:?}"),
            }
        }
    }

    impl<R: fmt::Debug, W: fmt::Debug> core::error::Error for Eh02Error<R, W> {}

    type ErrorOf<S> = Eh02Error<<S as v02::Read<u8>>::Error, <S as v02::Write<u8>>::Error>;

    impl<S> v1::ErrorType for Eh02<S>
    where
        S: v02::Read<u8> + v02::Write<u8>,
        <S as v02::Read<u8>>::Error: fmt::Debug,
        <S as v02::Write<u8>>::Error: fmt::Debug,
    {
        type Error = ErrorOf<S>;
    }

    impl<S> v1::Read<u8> for Eh02<S>
    where
        S: v02::Read<u8> + v02::Write<u8>,
        <S as v02::Read<u8>>::Error: fmt::Debug,
        <S as v02::Write<u8>>::Error: fmt::Debug,
    {
        #[inline]
        fn read(&mut self) -> nb::Result<u8, ErrorOf<S>> {
            v02::Read::read(&mut self.0).map_err(|e| e.map(Eh02Error::Read))
        }
    }

    impl<S> v1::Write<u8> for Eh02<S>
    where
        S: v02::Read<u8> + v02::Write<u8>,
        <S as v02::Read<u8>>::Error: fmt::Debug,
        <S as v02::Write<u8>>::Error: fmt::Debug,
    {
        #[inline]
        fn write(&mut self, word: u8) -> nb::Result<(), ErrorOf<S>> {
            v02::Write::write(&mut self.0, word).map_err(|e| e.map(Eh02Error::Write))
        }

        #[inline]
        fn flush(&mut self) -> nb::Result<(), ErrorOf<S>> {
            v02::Write::flush(&mut self.0).map_err(|e| e.map(Eh02Error::Write))
        }
    }

    impl<S: SetBaud> SetBaud for Eh02<S> {
        fn set_baud(&mut self, baud: u32) {
            self.0.set_baud(baud)
        }
        fn set_bd(&mut self, bd: u8) {
            self.0.set_bd(bd)
        }
    }
}

/// An error of an `embedded-io` port ([`Io06`] or [`Io07`]): the wrapped port's error. Its
/// [`kind`](embedded_hal_nb::serial::Error::kind) is
/// [`ErrorKind::Other`](embedded_hal_nb::serial::ErrorKind::Other) (`embedded-io`'s error kinds
/// are not a UART's); the driver reports it as
/// [`Error::Serial`](crate::driver::Error::Serial).
#[cfg(any(feature = "embedded-io-06", feature = "embedded-io-07"))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct IoError<E>(pub E);

#[cfg(any(feature = "embedded-io-06", feature = "embedded-io-07"))]
impl<E: core::fmt::Debug> embedded_hal_nb::serial::Error for IoError<E> {
    fn kind(&self) -> embedded_hal_nb::serial::ErrorKind {
        embedded_hal_nb::serial::ErrorKind::Other
    }
}

#[cfg(any(feature = "embedded-io-06", feature = "embedded-io-07"))]
impl<E: core::fmt::Debug> core::fmt::Display for IoError<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "serial I/O error: {:?}", self.0)
    }
}

#[cfg(any(feature = "embedded-io-06", feature = "embedded-io-07"))]
impl<E: core::fmt::Debug> core::error::Error for IoError<E> {}

/// The adapter from one `embedded-io` version: the traits of 0.6 and 0.7 have the same shape.
#[cfg(any(feature = "embedded-io-06", feature = "embedded-io-07"))]
macro_rules! io_adapter {
    ($io:ident, $Name:ident, $feature:literal, $version:literal) => {
        #[doc = concat!(
            "An `embedded-io` ", $version, " port (`Read + ReadReady + Write + WriteReady`) as the \
             `embedded-hal-nb` 1.0 serial port [`Radio`](crate::driver::Radio) takes. Feature \
             `", $feature, "`.\n\n",
            "A read asks `read_ready` first and answers `WouldBlock` if nothing has come, else \
             reads one byte; a write asks `write_ready` first and answers `WouldBlock` if the \
             port cannot take a byte yet, else writes it. `read` returning 0 bytes (end of \
             stream, which a UART does not have) and `write` taking 0 are `WouldBlock` too, so \
             the driver's timeouts end the wait. `flush` is `embedded-io`'s, which blocks until \
             the port has sent everything (the driver never calls it). Errors, the readiness \
             checks' included, come out as [`IoError`]."
        )]
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
        pub struct $Name<S>(pub S);

        impl<S> $Name<S> {
            /// The port back.
            pub fn into_inner(self) -> S {
                self.0
            }
        }

        impl<S: $io::ErrorType> embedded_hal_nb::serial::ErrorType for $Name<S> {
            type Error = IoError<S::Error>;
        }

        impl<S: $io::Read + $io::ReadReady> embedded_hal_nb::serial::Read<u8> for $Name<S> {
            #[inline]
            fn read(&mut self) -> nb::Result<u8, IoError<S::Error>> {
                if !self.0.read_ready().map_err(|e| nb::Error::Other(IoError(e)))? {
                    return Err(nb::Error::WouldBlock);
                }
                let mut byte = [0];
                match self.0.read(&mut byte) {
                    Ok(0) => Err(nb::Error::WouldBlock),
                    Ok(_) => Ok(byte[0]),
                    Err(e) => Err(nb::Error::Other(IoError(e))),
                }
            }
        }

        impl<S: $io::Write + $io::WriteReady> embedded_hal_nb::serial::Write<u8> for $Name<S> {
            #[inline]
            fn write(&mut self, word: u8) -> nb::Result<(), IoError<S::Error>> {
                if !self.0.write_ready().map_err(|e| nb::Error::Other(IoError(e)))? {
                    return Err(nb::Error::WouldBlock);
                }
                match self.0.write(&[word]) {
                    Ok(0) => Err(nb::Error::WouldBlock),
                    Ok(_) => Ok(()),
                    Err(e) => Err(nb::Error::Other(IoError(e))),
                }
            }

            #[inline]
            fn flush(&mut self) -> nb::Result<(), IoError<S::Error>> {
                self.0.flush().map_err(|e| nb::Error::Other(IoError(e)))
            }
        }

        impl<S: SetBaud> SetBaud for $Name<S> {
            fn set_baud(&mut self, baud: u32) {
                self.0.set_baud(baud)
            }
            fn set_bd(&mut self, bd: u8) {
                self.0.set_bd(bd)
            }
        }
    };
}

#[cfg(feature = "embedded-io-06")]
io_adapter!(embedded_io_06, Io06, "embedded-io-06", "0.6");
#[cfg(feature = "embedded-io-07")]
io_adapter!(embedded_io_07, Io07, "embedded-io-07", "0.7");
