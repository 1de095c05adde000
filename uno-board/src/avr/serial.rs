//! USART0: interrupt-driven RX ring, blocking/non-blocking TX, `embedded-hal-nb` serial traits.

use super::pac::USART0;
use super::time::{self, Tick};
use crate::{baud, BaudError, RX_BUFFER_SIZE};
use avr_device::interrupt::{self, Mutex};
use core::cell::Cell;
use core::convert::Infallible;

/// What this driver writes to UCSR0A: U2X0 (double speed, always on) and UDRE0 (read-only on the
/// chip, where the write is ignored). MPCM0 stays 0; FE0/DOR0/UPE0 must be written 0.
const UCSR0A_BASE: u8 = (1 << 1) | (1 << 5);
/// UCSR0A TXC0: written 1 to clear the transmit-complete flag.
const UCSR0A_TXC0: u8 = 1 << 6;

/// The bytes received and not read yet: the RX interrupt appends, [`Serial::try_read`] takes
/// the oldest, each inside a critical section (the ring lives in a [`Mutex`]). When it is full,
/// a new byte is dropped: the bytes already waiting are kept whole.
struct RxRing {
    /// Index of the oldest byte in `buf`.
    head: Cell<u8>,
    /// Bytes waiting, 0…[`RX_BUFFER_SIZE`].
    len: Cell<u8>,
    buf: [Cell<u8>; RX_BUFFER_SIZE],
}

// The indices wrap with a mask and the length is a byte.
const _: () = assert!(RX_BUFFER_SIZE.is_power_of_two() && RX_BUFFER_SIZE < 256);

impl RxRing {
    const fn new() -> RxRing {
        RxRing {
            head: Cell::new(0),
            len: Cell::new(0),
            buf: [const { Cell::new(0) }; RX_BUFFER_SIZE],
        }
    }

    /// Appends `byte`, or drops it when the ring is full.
    #[inline(always)]
    fn push(&self, byte: u8) {
        let len = self.len.get();
        if usize::from(len) < RX_BUFFER_SIZE {
            let at = usize::from(self.head.get().wrapping_add(len)) % RX_BUFFER_SIZE;
            self.buf[at].set(byte);
            self.len.set(len + 1);
        }
    }

    /// Takes the oldest byte, if any.
    #[inline(always)]
    fn pop(&self) -> Option<u8> {
        let len = self.len.get();
        if len == 0 {
            return None;
        }
        let head = usize::from(self.head.get()) % RX_BUFFER_SIZE;
        self.head.set(((head + 1) % RX_BUFFER_SIZE) as u8);
        self.len.set(len - 1);
        Some(self.buf[head].get())
    }
}

static RX: Mutex<RxRing> = Mutex::new(RxRing::new());

/// The tick when the last API frame start delimiter (0x7E) arrived, stamped by the RX interrupt
/// (see [`rx_frame_start_us`]).
static FRAME_START: Mutex<Cell<Tick>> = Mutex::new(Cell::new(Tick::ZERO));

/// The XBee API frame start delimiter.
const FRAME_DELIMITER: u8 = 0x7E;

// A received byte: into the ring, and for a frame start delimiter the tick as it arrived.
#[avr_device::interrupt(atmega328p)]
fn USART_RX() {
    // SAFETY: reads UDR0 (reading takes the byte and acknowledges the interrupt), which only this
    // handler reads; `Serial` owns USART0 but never reads UDR0.
    let usart = unsafe { &*USART0::ptr() };
    let byte = usart.udr0().read().bits();
    interrupt::free(|cs| {
        RX.borrow(cs).push(byte);
        if byte == FRAME_DELIMITER {
            FRAME_START.borrow(cs).set(time::tick(cs));
        }
    });
}

/// The local time ([`now_us`](crate::now_us)) at which the last API frame start delimiter
/// (0x7E) arrived, stamped by the RX interrupt at the byte's stop bit. In API mode 2 an
/// unescaped 0x7E always starts a frame, so for a frame just decoded (the main loop drains the
/// ring promptly) this is when the radio began handing it over: a receive time that does not
/// depend on the frame's length or on how late the main loop got to it.
#[inline]
pub fn rx_frame_start_us() -> u32 {
    interrupt::free(|cs| FRAME_START.borrow(cs).get()).us()
}

/// True when at least one received byte waits in the ring (for [`sleep_unless`](crate::sleep_unless)).
#[inline]
pub fn rx_pending() -> bool {
    interrupt::free(|cs| RX.borrow(cs).len.get() != 0)
}

/// USART0 on D0/D1, 8N1, always in double-speed mode (U2X0); see [`baud`] for the divisors.
pub struct Serial {
    usart: USART0,
    /// A byte was written since the last completed flush.
    tx_pending: bool,
}

impl Serial {
    /// Called with interrupts still disabled (from `Board::take`).
    pub(crate) fn init(usart: USART0) -> Serial {
        // Off first, in case the bootloader left it running.
        usart.ucsr0b().reset();
        usart.ucsr0c().write(|w| {
            w.umsel0()
                .usart_async()
                .upm0()
                .disabled()
                .usbs0()
                .stop1()
                .ucsz0()
                .chr8()
        });
        // U2X0 before UBRR0: simavr computes its byte time when UBRR0 is written.
        // SAFETY: a valid UCSR0A value (see `UCSR0A_BASE`).
        usart.ucsr0a().write(|w| unsafe { w.bits(UCSR0A_BASE) });
        usart
            .ubrr0()
            .write(|w| w.set(const { ubrr_or_panic(crate::DEFAULT_BAUD) }));
        usart
            .ucsr0b()
            .write(|w| w.rxen0().set_bit().txen0().set_bit().udrie0().set_bit());
        // Debian's simavr 1.6 clears UDRE0 on a UCSR0A write and raises it again when UDRIE0 gets
        // enabled; on the chip (and in newer simavr) UDRE0 is simply still set. UDRIE0 is on only
        // while interrupts are disabled, so no UDRE interrupt is ever taken.
        usart
            .ucsr0b()
            .write(|w| w.rxen0().set_bit().txen0().set_bit().rxcie0().set_bit());
        Serial {
            usart,
            tx_pending: false,
        }
    }

    /// Changes the bit rate: waits until the bytes already written have left, then switches.
    /// Received bytes are kept (the radio driver skips what arrived at the old rate as it reads).
    /// Radio bring-up uses [`set_bd`](Self::set_bd), without this one's 32-bit division.
    pub fn set_baud(&mut self, baud: u32) -> Result<(), BaudError> {
        let ubrr = baud::ubrr_u2x(baud::F_CPU, baud).ok_or(BaudError::Unreachable)?;
        self.set_ubrr(ubrr);
        Ok(())
    }

    /// [`set_baud`](Self::set_baud) for the rate the S1 runs at with `BD` value `bd`
    /// ([`xbee_api::driver::baud_of_bd`]: 1200…57600 bit/s, and 111 111 for `BD=7`), without
    /// the division ([`ubrr_of_bd`]). Out of line: radio bring-up calls it from three places.
    #[inline(never)]
    pub fn set_bd(&mut self, bd: u8) {
        self.set_ubrr(ubrr_of_bd(bd));
    }

    /// Waits until the bytes written have left, then writes UBRR0 (U2X0 is already set, by
    /// `init`).
    fn set_ubrr(&mut self, ubrr: u16) {
        self.flush_blocking();
        self.usart.ubrr0().write(|w| w.set(ubrr));
    }

    /// The next received byte, if any. Never inlined: the driver's read loops and the
    /// provisioning window share one copy of the critical section.
    #[inline(never)]
    pub fn try_read(&mut self) -> Option<u8> {
        interrupt::free(|cs| RX.borrow(cs).pop())
    }

    /// Writes `byte` if the transmit buffer is free; `false` if it is busy.
    #[inline]
    pub fn try_write(&mut self, byte: u8) -> bool {
        if self.usart.ucsr0a().read().udre0().bit_is_clear() {
            return false;
        }
        // Writing 1 clears TXC0, so `flush` can tell when this byte has left.
        // SAFETY: a valid UCSR0A value (see `UCSR0A_BASE`).
        self.usart
            .ucsr0a()
            .write(|w| unsafe { w.bits(UCSR0A_BASE | UCSR0A_TXC0) });
        self.usart.udr0().write(|w| w.set(byte));
        self.tx_pending = true;
        true
    }

    /// Writes `byte`, waiting for room in the transmit buffer. Never inlined: text lines and
    /// provisioning replies call it from many places, and each inlined copy would be flash of its
    /// own.
    #[inline(never)]
    pub fn write_byte(&mut self, byte: u8) {
        while !self.try_write(byte) {}
    }

    /// Writes all of `bytes`, blocking.
    pub fn write_bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_byte(b);
        }
    }

    /// True once every written byte has left the shift register.
    pub fn tx_done(&mut self) -> bool {
        if self.tx_pending && self.usart.ucsr0a().read().txc0().bit_is_set() {
            self.tx_pending = false;
        }
        !self.tx_pending
    }

    /// Waits until every written byte has left the shift register.
    pub fn flush_blocking(&mut self) {
        while !self.tx_done() {}
    }
}

/// UBRR0 (double speed) for the XBee's `BD` value `bd` (0…7, a larger one as 7), at the rate
/// the S1 really runs it ([`xbee_api::driver::baud_of_bd`]): for 1200 · 2^`bd` bit/s (0…5)
/// 2 000 000 / (1200 · 2^`bd`) − 1 ≈ 1667 / 2^`bd` − 1, a shift (no division on the MCU), then
/// 34 for 57600 and 17 for the S1's 111 111. Checked at compile time: every `BD` value's rate
/// within 0.8 % of the radio's.
const fn ubrr_of_bd(bd: u8) -> u16 {
    match bd {
        0..=5 => (1667u16 >> bd) - 1,
        6 => 34,
        _ => 17,
    }
}

const _: () = {
    let mut bd = 0;
    while bd <= 8 {
        let baud = xbee_api::driver::baud_of_bd(bd);
        let err = baud::error_permille(baud::F_CPU, baud, ubrr_of_bd(bd));
        assert!(-8 <= err && err <= 8);
        bd += 1;
    }
};

/// Evaluated at compile time for the default rate.
const fn ubrr_or_panic(baud: u32) -> u16 {
    match baud::ubrr_u2x(baud::F_CPU, baud) {
        Some(u) => u,
        None => panic!("unreachable baud rate"),
    }
}

impl embedded_hal_nb::serial::ErrorType for Serial {
    /// Reads and writes cannot fail. A byte that arrives with the ring full is dropped; the
    /// radio driver then rejects the frame it belonged to (length or checksum).
    type Error = Infallible;
}

impl embedded_hal_nb::serial::Read<u8> for Serial {
    #[inline]
    fn read(&mut self) -> nb::Result<u8, Infallible> {
        self.try_read().ok_or(nb::Error::WouldBlock)
    }
}

impl embedded_hal_nb::serial::Write<u8> for Serial {
    #[inline]
    fn write(&mut self, word: u8) -> nb::Result<(), Infallible> {
        if self.try_write(word) {
            Ok(())
        } else {
            Err(nb::Error::WouldBlock)
        }
    }

    #[inline]
    fn flush(&mut self) -> nb::Result<(), Infallible> {
        if self.tx_done() {
            Ok(())
        } else {
            Err(nb::Error::WouldBlock)
        }
    }
}

/// Radio bring-up (`xbee_api::driver::Radio::bring_up`) probes the XBee at several rates.
impl xbee_api::driver::SetBaud for Serial {
    /// Switches USART0 to `baud` (after the pending bytes have left). Every rate the driver tries
    /// (1200…57600 and 111 111) is reachable; an unreachable one leaves the rate unchanged.
    fn set_baud(&mut self, baud: u32) {
        let _ = Serial::set_baud(self, baud);
    }

    /// Through [`Serial::set_bd`]: no 32-bit division.
    fn set_bd(&mut self, bd: u8) {
        Serial::set_bd(self, bd);
    }
}
