//! A host stand-in for the items of arduino-hal (avr-hal) and avr-device that
//! `examples/arduino_uno.rs` uses, so that the example compiles where avr-hal cannot be fetched
//! (it is not on crates.io) and on a host target. Same paths, names and signatures as the real
//! crates for what the example calls; what matters to `xbee-api` has the real trait shape:
//! [`arduino_hal::Usart`] implements the embedded-hal 0.2 `serial::Read<u8>` and
//! `serial::Write<u8>` with `Infallible` errors, and has the inherent blocking `flush`. Nothing
//! here touches hardware: reads find nothing, writes go nowhere, the clock stands still.

/// The stand-in for `arduino_hal` (board `arduino-uno`).
pub mod arduino_hal {
    use core::convert::Infallible;

    use embedded_hal_02::serial;

    /// The Uno's 16 MHz clock.
    pub struct DefaultClock;

    /// A CPU clock rate.
    pub trait Clock {
        /// Hz.
        const FREQ: u32;
    }

    impl Clock for DefaultClock {
        const FREQ: u32 = 16_000_000;
    }

    /// The MCU's peripherals the example takes.
    #[allow(non_snake_case)]
    pub struct Peripherals {
        pub USART0: pac::USART0,
        pub TC0: pac::TC0,
    }

    impl Peripherals {
        pub fn take() -> Option<Self> {
            Some(Peripherals {
                USART0: pac::USART0 { _private: () },
                TC0: pac::TC0 { _private: () },
            })
        }
    }

    /// avr-device's ATmega328P register blocks (the few the example uses).
    pub mod pac {
        pub struct USART0 {
            pub(super) _private: (),
        }

        impl USART0 {
            /// # Safety
            /// As avr-device's: the caller must not let two owners use the registers at once.
            pub unsafe fn steal() -> Self {
                USART0 { _private: () }
            }
        }

        pub struct TC0 {
            pub(super) _private: (),
        }

        /// One register: `write` takes the closure svd2rust's writers take.
        pub struct Reg;

        impl Reg {
            pub fn write(&self, f: impl FnOnce(&mut W) -> &mut W) {
                f(&mut W);
            }
        }

        /// A register writer with the fields the example sets.
        pub struct W;

        impl W {
            pub fn set(&mut self, _value: u8) -> &mut W {
                self
            }
            pub fn wgm0(&mut self) -> Field<'_> {
                Field(self)
            }
            pub fn cs0(&mut self) -> Field<'_> {
                Field(self)
            }
            pub fn ocie0a(&mut self) -> Field<'_> {
                Field(self)
            }
        }

        /// A field writer with the values the example writes.
        pub struct Field<'a>(&'a mut W);

        impl<'a> Field<'a> {
            pub fn ctc(self) -> &'a mut W {
                self.0
            }
            pub fn prescale_64(self) -> &'a mut W {
                self.0
            }
            pub fn set_bit(self) -> &'a mut W {
                self.0
            }
        }

        impl TC0 {
            pub fn tccr0a(&self) -> &Reg {
                &Reg
            }
            pub fn tccr0b(&self) -> &Reg {
                &Reg
            }
            pub fn ocr0a(&self) -> &Reg {
                &Reg
            }
            pub fn timsk0(&self) -> &Reg {
                &Reg
            }
        }
    }

    /// Pins and their modes.
    pub mod port {
        use core::marker::PhantomData;

        pub mod mode {
            use core::marker::PhantomData;

            pub struct AnyInput;
            pub struct Floating;
            pub struct Input<IMODE = AnyInput>(PhantomData<IMODE>);
            pub struct Output;
        }

        pub struct Pin<MODE, PIN>(PhantomData<(MODE, PIN)>);

        impl<MODE, PIN> Pin<MODE, PIN> {
            pub(crate) fn new() -> Self {
                Pin(PhantomData)
            }
            pub fn into_output(self) -> Pin<mode::Output, PIN> {
                Pin::new()
            }
        }

        impl<PIN> Pin<mode::Output, PIN> {
            pub fn set_high(&mut self) {}
            pub fn set_low(&mut self) {}
        }
    }

    /// The Uno's pins the example uses.
    pub struct Pins {
        pub d0: port::Pin<port::mode::Input<port::mode::Floating>, hal::port::PD0>,
        pub d1: port::Pin<port::mode::Input<port::mode::Floating>, hal::port::PD1>,
        pub d13: port::Pin<port::mode::Input<port::mode::Floating>, hal::port::PB5>,
    }

    impl Pins {
        pub fn with_mcu_pins(_dp: &Peripherals) -> Self {
            Pins {
                d0: port::Pin::new(),
                d1: port::Pin::new(),
                d13: port::Pin::new(),
            }
        }
    }

    macro_rules! pins {
        ($p:expr) => {
            $crate::avr_stand_in::arduino_hal::Pins::with_mcu_pins(&$p)
        };
    }
    pub(crate) use pins;

    /// atmega-hal.
    pub mod hal {
        pub mod port {
            pub struct PB5;
            pub struct PD0;
            pub struct PD1;
        }

        pub mod usart {
            use super::super::{pac, port::mode, port::Pin, usart::Usart};

            pub type Usart0<CLOCK> = Usart<
                pac::USART0,
                Pin<mode::Input, super::port::PD0>,
                Pin<mode::Output, super::port::PD1>,
                CLOCK,
            >;
        }
    }

    /// The USART driver.
    pub mod usart {
        use core::marker::PhantomData;

        use super::{pac, port::mode, port::Pin, Clock};

        /// The UBRR divisor and U2X bit of a baud rate, as avr-hal computes them.
        pub struct Baudrate<CLOCK> {
            pub ubrr: u16,
            pub u2x: bool,
            pub _clock: PhantomData<CLOCK>,
        }

        impl<CLOCK: Clock> Baudrate<CLOCK> {
            pub fn new(baud: u32) -> Baudrate<CLOCK> {
                let mut ubrr = (CLOCK::FREQ / 4 / baud - 1) / 2;
                let mut u2x = true;
                if ubrr > 4095 {
                    u2x = false;
                    ubrr = (CLOCK::FREQ / 8 / baud - 1) / 2;
                }
                Baudrate {
                    ubrr: ubrr as u16,
                    u2x,
                    _clock: PhantomData,
                }
            }
        }

        /// The MCU marker avr-hal's traits carry.
        pub struct Atmega;

        /// avr-hal's low-level USART trait, implemented by the register block.
        pub trait UsartOps<H, RX, TX> {
            fn raw_init<CLOCK>(&mut self, baudrate: Baudrate<CLOCK>);
        }

        impl
            UsartOps<
                Atmega,
                Pin<mode::Input, super::hal::port::PD0>,
                Pin<mode::Output, super::hal::port::PD1>,
            > for pac::USART0
        {
            fn raw_init<CLOCK>(&mut self, baudrate: Baudrate<CLOCK>) {
                // The real one writes these to UBRR0 and UCSR0A.
                let _ = (baudrate.ubrr, baudrate.u2x);
            }
        }

        /// The USART driver, generic over the register block, the pins and the clock.
        pub struct Usart<USART, RX, TX, CLOCK> {
            _p: USART,
            _pins: PhantomData<(RX, TX, CLOCK)>,
        }

        impl<USART, RXPIN, TXPIN, CLOCK>
            Usart<USART, Pin<mode::Input, RXPIN>, Pin<mode::Output, TXPIN>, CLOCK>
        where
            USART: UsartOps<Atmega, Pin<mode::Input, RXPIN>, Pin<mode::Output, TXPIN>>,
        {
            pub fn new<IMODE>(
                mut p: USART,
                _rx: Pin<mode::Input<IMODE>, RXPIN>,
                _tx: Pin<mode::Output, TXPIN>,
                baudrate: Baudrate<CLOCK>,
            ) -> Self {
                p.raw_init(baudrate);
                Usart {
                    _p: p,
                    _pins: PhantomData,
                }
            }
        }

        impl<USART, RX, TX, CLOCK> Usart<USART, RX, TX, CLOCK> {
            /// Blocks until everything written has been sent.
            pub fn flush(&mut self) {}
        }
    }

    /// arduino-hal's `Usart`: avr-hal's, with the board's clock.
    pub type Usart<USART, RX, TX> = usart::Usart<USART, RX, TX, DefaultClock>;

    impl<USART, RX, TX, CLOCK> serial::Read<u8> for usart::Usart<USART, RX, TX, CLOCK> {
        type Error = Infallible;
        fn read(&mut self) -> nb::Result<u8, Infallible> {
            Err(nb::Error::WouldBlock)
        }
    }

    impl<USART, RX, TX, CLOCK> serial::Write<u8> for usart::Usart<USART, RX, TX, CLOCK> {
        type Error = Infallible;
        fn write(&mut self, _byte: u8) -> nb::Result<(), Infallible> {
            Ok(())
        }
        fn flush(&mut self) -> nb::Result<(), Infallible> {
            Ok(())
        }
    }

    pub fn delay_ms(_ms: u32) {}
}

/// The stand-in for `avr_device`.
pub mod avr_device {
    pub mod interrupt {
        use core::marker::PhantomData;

        /// Proof of being inside [`free`].
        #[derive(Clone, Copy)]
        pub struct CriticalSection<'cs>(PhantomData<&'cs ()>);

        /// Data shared with interrupt handlers, reachable only inside [`free`].
        pub struct Mutex<T>(T);

        impl<T> Mutex<T> {
            pub const fn new(value: T) -> Self {
                Mutex(value)
            }
            pub fn borrow<'cs>(&'cs self, _cs: CriticalSection<'cs>) -> &'cs T {
                &self.0
            }
        }

        // SAFETY: `borrow` needs a `CriticalSection`, which only `free` gives out, one thread at a
        // time (it holds `LOCK`).
        unsafe impl<T: Send> Sync for Mutex<T> {}

        static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

        /// Runs `f` with interrupts off (here: under a lock).
        pub fn free<F: FnOnce(CriticalSection<'_>) -> R, R>(f: F) -> R {
            let _guard = LOCK.lock().unwrap_or_else(|e| e.into_inner());
            f(CriticalSection(PhantomData))
        }

        /// Turns interrupts on.
        ///
        /// # Safety
        /// As avr-device's: not inside [`free`].
        pub unsafe fn enable() {}
    }
}
