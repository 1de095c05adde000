//! USART0: interrupt-driven RX ring, blocking/non-blocking TX, `embedded-hal-nb` serial traits.

use super::cell::IrqCell;
use super::pac::USART0;
use crate::ring::Ring;
use crate::{baud, BaudError, RX_BUFFER_SIZE};
use core::convert::Infallible;

/// What this driver writes to UCSR0A: U2X0 (double speed, always on) and UDRE0 (read-only on the
/// chip, where the write is ignored). MPCM0 stays 0; FE0/DOR0/UPE0 must be written 0.
const UCSR0A_BASE: u8 = (1 << 1) | (1 << 5);
/// UCSR0A TXC0: written 1 to clear the transmit-complete flag.
const UCSR0A_TXC0: u8 = 1 << 6;

/// Receive-side counters since boot (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RxStats {
    /// Bytes dropped because the ring was full (the main loop did not drain it in time).
    pub ring_full: u16,
    /// Hardware data overruns (DOR0: a byte was lost because the RX interrupt ran too late,
    /// i.e. interrupts were disabled for more than ~2 byte times).
    pub data_overrun: u16,
    /// Framing errors (FE0: wrong baud rate or line noise); the byte is still delivered.
    pub frame_error: u16,
}

impl RxStats {
    /// All lost bytes: ring-full drops plus hardware overruns.
    pub fn overruns(&self) -> u16 {
        self.ring_full.saturating_add(self.data_overrun)
    }
}

struct RxState {
    ring: Ring<RX_BUFFER_SIZE>,
    stats: RxStats,
}

/// [`now_us`](crate::now_us) when the last API frame start delimiter (0x7E) arrived.
static FRAME_START_US: IrqCell<u32> = IrqCell::new(0);

static RX: IrqCell<RxState> = IrqCell::new(RxState {
    ring: Ring::new(),
    stats: RxStats {
        ring_full: 0,
        data_overrun: 0,
        frame_error: 0,
    },
});

#[avr_device::interrupt(atmega328p)]
fn USART_RX() {
    // SAFETY: the handler only reads UCSR0A and UDR0, which the main program never reads (it reads
    // only the ring); reading UDR0 here is what acknowledges the interrupt.
    let usart = unsafe { &*USART0::ptr() };
    // Status first: FE0/DOR0 describe the byte at the head of the receive FIFO.
    let status = usart.ucsr0a().read();
    let byte = usart.udr0().read().bits();
    RX.with(|rx| {
        if status.dor0().bit_is_set() {
            bump(&mut rx.stats.data_overrun);
        }
        if status.fe0().bit_is_set() {
            bump(&mut rx.stats.frame_error);
        }
        if !rx.ring.push(byte) {
            bump(&mut rx.stats.ring_full);
        }
    });
    if byte == xbee_api::START {
        let now = super::now_us();
        FRAME_START_US.with(|t| *t = now);
    }
}

/// Adds one to a receive counter, saturating. One copy for the three counters (only errors take
/// it, so the RX interrupt's common path does not pay the call).
#[inline(never)]
fn bump(counter: &mut u16) {
    *counter = counter.saturating_add(1);
}

/// The local time ([`now_us`](crate::now_us)) at which the last API frame start delimiter
/// (0x7E) arrived, stamped by the RX interrupt at the byte's stop bit. In API mode 2 an
/// unescaped 0x7E always starts a frame, so for a frame just decoded (the main loop drains the
/// ring promptly) this is when the radio began handing it over: a receive time that does not
/// depend on the frame's length or on how late the main loop got to it.
#[inline]
pub fn rx_frame_start_us() -> u32 {
    FRAME_START_US.with(|t| *t)
}

/// True when at least one received byte waits in the ring (for [`sleep_unless`](crate::sleep_unless)).
#[inline]
pub fn rx_pending() -> bool {
    RX.with(|rx| !rx.ring.is_empty())
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
        // U2X0 before UBRR0: simavr computes its byte time when UBRR0 is written (SPEC §9).
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
    /// Received bytes are kept; call [`clear_rx`](Self::clear_rx) to drop what arrived at the
    /// old rate. Radio bring-up uses [`set_bd`](Self::set_bd), without this one's 32-bit
    /// division.
    pub fn set_baud(&mut self, baud: u32) -> Result<(), BaudError> {
        let ubrr = baud::ubrr_u2x(baud::F_CPU, baud).ok_or(BaudError::Unreachable)?;
        self.set_ubrr(ubrr);
        Ok(())
    }

    /// [`set_baud`](Self::set_baud) for the rate of the XBee's `BD` value `bd`
    /// ([`xbee_api::driver::baud_of_bd`]): 3…7, 9600…115200 bit/s (the rates of [`baud`]),
    /// whose divisors, below 256, come from a 5-byte table worked out at compile time.
    /// Out of line: radio bring-up calls it from three places.
    #[inline(never)]
    pub fn set_bd(&mut self, bd: u8) -> Result<(), BaudError> {
        let ubrr = UBRR_OF_BD
            .get(bd.wrapping_sub(BD_FIRST) as usize)
            .ok_or(BaudError::Unreachable)?;
        self.set_ubrr(u16::from(*ubrr));
        Ok(())
    }

    /// Waits until the bytes written have left, then writes UBRR0 (U2X0 is already set, by
    /// `init`).
    fn set_ubrr(&mut self, ubrr: u16) {
        self.flush_blocking();
        self.usart.ubrr0().write(|w| w.set(ubrr));
    }

    /// Drops every byte waiting in the RX ring.
    pub fn clear_rx(&mut self) {
        RX.with(|rx| rx.ring.clear());
    }

    /// Bytes waiting in the RX ring.
    pub fn rx_len(&self) -> usize {
        RX.with(|rx| rx.ring.len())
    }

    /// Receive counters since boot.
    pub fn rx_stats(&self) -> RxStats {
        RX.with(|rx| rx.stats)
    }

    /// Lost bytes since boot: ring-full drops plus hardware data overruns.
    pub fn overruns(&self) -> u16 {
        self.rx_stats().overruns()
    }

    /// The next received byte, if any. Never inlined: the driver's read loops and the
    /// provisioning window each had their own copy of the critical section.
    #[inline(never)]
    pub fn try_read(&mut self) -> Option<u8> {
        RX.with(|rx| rx.ring.pop())
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
    /// provisioning replies call it from many places, each inlined copy cost ≈ 24 B of flash.
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

    /// Writes a string stored in flash (see [`avr_progmem`](crate::avr_progmem)), blocking.
    pub fn write_progmem<const N: usize>(&mut self, s: &avr_progmem::string::PmString<N>) {
        for b in s.as_bytes().iter() {
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

/// The first `BD` value of [`UBRR_OF_BD`] (9600 bit/s).
const BD_FIRST: u8 = 3;

/// UBRR0 (double speed) for the XBee's `BD` values 3…7: 207, 103, 51, 34, 16.
const UBRR_OF_BD: [u8; 5] = {
    let mut t = [0; 5];
    let mut i = 0;
    while i < t.len() {
        let ubrr = ubrr_or_panic(xbee_api::driver::baud_of_bd(BD_FIRST + i as u8));
        assert!(ubrr < 256);
        t[i] = ubrr as u8;
        i += 1;
    }
    t
};

/// Evaluated at compile time for the default rate.
const fn ubrr_or_panic(baud: u32) -> u16 {
    match baud::ubrr_u2x(baud::F_CPU, baud) {
        Some(u) => u,
        None => panic!("unreachable baud rate"),
    }
}

impl embedded_hal_nb::serial::ErrorType for Serial {
    /// Reads and writes cannot fail; lost bytes are counted in [`RxStats`] instead.
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
    /// (9600…115200) is reachable; an unreachable one leaves the rate unchanged.
    fn set_baud(&mut self, baud: u32) {
        let _ = Serial::set_baud(self, baud);
    }

    /// Through [`Serial::set_bd`]: no 32-bit division.
    fn set_bd(&mut self, bd: u8) {
        let _ = Serial::set_bd(self, bd);
    }
}
