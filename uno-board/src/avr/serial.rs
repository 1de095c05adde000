//! USART0: interrupt-driven RX ring, blocking/non-blocking TX, `embedded-hal-nb` serial traits.

use super::cell::IrqCell;
use super::pac::USART0;
use super::time::Tick;
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

/// What the RX interrupt shares with the main program. `repr(C)`: the handler is assembly
/// (below) and addresses the fields by these offsets.
#[repr(C)]
struct RxState {
    /// Index of the oldest byte in `buf` (offset 0).
    head: u8,
    /// Bytes in `buf`, 0…[`RX_BUFFER_SIZE`] (offset 1).
    len: u8,
    /// The [`RxStats`] counters (offset 2), indexed by `DATA_OVERRUN`, `FRAME_ERROR`,
    /// `RING_FULL`: the handler bumps them through one loop over the bits of what happened.
    counts: [u16; 3],
    /// The ring's bytes (offset 8).
    buf: [u8; RX_BUFFER_SIZE],
}

/// Index in `RxState::counts` (and bit of the handler's event mask): hardware data overruns.
const DATA_OVERRUN: usize = 0;
/// Index in `RxState::counts`: framing errors.
const FRAME_ERROR: usize = 1;
/// Index in `RxState::counts`: ring-full drops.
const RING_FULL: usize = 2;

// The ring's index arithmetic wraps with a mask and its length is a byte.
const _: () = assert!(RX_BUFFER_SIZE.is_power_of_two() && RX_BUFFER_SIZE < 256);
const _: () = assert!(core::mem::offset_of!(RxState, len) == 1);
const _: () = assert!(core::mem::offset_of!(RxState, counts) == 2);
const _: () = assert!(core::mem::offset_of!(RxState, buf) == 8);
const _: () = assert!(DATA_OVERRUN == 0 && FRAME_ERROR == 1 && RING_FULL == 2);

static RX: IrqCell<RxState> = IrqCell::new(RxState {
    head: 0,
    len: 0,
    counts: [0; 3],
    buf: [0; RX_BUFFER_SIZE],
});

/// The tick ([`now_us`](crate::now_us) unconverted, see `Tick`) when the last API frame start
/// delimiter (0x7E) arrived: `repr(C)` `{ ms: u32, count: u8 }`, written by the RX interrupt.
static FRAME_START: IrqCell<Tick> = IrqCell::new(Tick::ZERO);

// USART_RX's body is one `asm!` block: the compiled handler called the counter increment and
// `now_us`, so it saved every call-clobbered register (17 pushes), 240 B with its callees; this
// one calls nothing, so only the six registers the block names are saved. It reads UCSR0A then
// UDR0 (status first: FE0/DOR0 describe the byte at the head of the receive FIFO; reading UDR0
// acknowledges the interrupt), pushes the byte into the ring (or counts it as dropped), bumps
// the saturating counters whose event bits are set (DOR0 bit 3, FE0 bit 4, ring full bit 5 →
// counts[0], [1], [2]), and for a start delimiter stamps the tick as `time::tick` takes it (a
// pending compare match with a small count is counted). Interrupts are off throughout; r0 is
// the scratch register and r1 is 0, as in compiled code. (Not
// naked: a naked function's assembly gets only the base AVR instructions, not even `push`.)
#[avr_device::interrupt(atmega328p)]
fn USART_RX() {
    // SAFETY: reads UCSR0A and UDR0, which the main program never reads, and writes `RX` and
    // `FRAME_START` (and reads `MILLIS`) with interrupts disabled, as `IrqCell` requires; the
    // offsets are the `repr(C)` layouts checked above.
    unsafe {
        core::arch::asm!(
            "lds r24, 0xC0",          // UCSR0A
            "lds r25, 0xC6",          // UDR0
            "andi r24, 0x18",         // DOR0 | FE0
            "ldi r30, lo8({rx})",     // Z: RX
            "ldi r31, hi8({rx})",
            "ld r26, Z",              // head
            "ldd r27, Z+1",           // len
            "cpi r27, {cap}",
            "brlo 1f",
            "ori r24, 0x20",          // ring full
            "rjmp 2f",
            "1:",
            "add r26, r27",           // head + len, wrapped: where the byte goes
            "inc r27",
            "std Z+1, r27",
            "andi r26, {cap}-1",
            "clr r27",
            "subi r26, lo8(-({rx}+8))",
            "sbci r27, hi8(-({rx}+8))",
            "st X, r25",
            "2:",
            "adiw r30, 2",            // Z: counts
            "lsr r24",
            "lsr r24",
            "lsr r24",
            "3:",
            "lsr r24",
            "brcc 4f",
            "ld r26, Z",
            "ldd r27, Z+1",
            "adiw r26, 1",
            "breq 4f",                // was 0xFFFF: saturated
            "st Z, r26",
            "std Z+1, r27",
            "4:",
            "adiw r30, 2",
            "tst r24",
            "brne 3b",
            "cpi r25, 0x7E",
            "brne 6f",
            "in r24, 0x26",           // TCNT0
            "in r25, 0x15",           // TIFR0, after the count
            "bst r25, 1",             // T: OCF0A, a compare match not counted yet...
            "cpi r24, 125",
            "brlo 5f",
            "clt",                    // ...unless the count was read just before it
            "5:",
            "ldi r30, lo8({ms})",
            "ldi r31, hi8({ms})",
            "ld r26, Z",              // MILLIS in r0:r25:r27:r26 (r0: the scratch register)
            "ldd r27, Z+1",
            "ldd r25, Z+2",
            "ldd r0, Z+3",
            "brtc 7f",
            "adiw r26, 1",
            "adc r25, r1",
            "adc r0, r1",
            "7:",
            "ldi r30, lo8({fs})",
            "ldi r31, hi8({fs})",
            "st Z, r26",
            "std Z+1, r27",
            "std Z+2, r25",
            "std Z+3, r0",
            "std Z+4, r24",
            "6:",
            rx = sym RX,
            fs = sym FRAME_START,
            ms = sym super::time::MILLIS,
            cap = const RX_BUFFER_SIZE,
            out("r24") _,
            out("r25") _,
            out("r26") _,
            out("r27") _,
            out("r30") _,
            out("r31") _,
        );
    }
}

/// The local time ([`now_us`](crate::now_us)) at which the last API frame start delimiter
/// (0x7E) arrived, stamped by the RX interrupt at the byte's stop bit. In API mode 2 an
/// unescaped 0x7E always starts a frame, so for a frame just decoded (the main loop drains the
/// ring promptly) this is when the radio began handing it over: a receive time that does not
/// depend on the frame's length or on how late the main loop got to it.
#[inline]
pub fn rx_frame_start_us() -> u32 {
    FRAME_START.with(|t| *t).us()
}

/// True when at least one received byte waits in the ring (for [`sleep_unless`](crate::sleep_unless)).
#[inline]
pub fn rx_pending() -> bool {
    RX.with(|rx| rx.len != 0)
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
        RX.with(|rx| {
            rx.head = 0;
            rx.len = 0;
        });
    }

    /// Bytes waiting in the RX ring.
    pub fn rx_len(&self) -> usize {
        RX.with(|rx| usize::from(rx.len))
    }

    /// Receive counters since boot.
    pub fn rx_stats(&self) -> RxStats {
        let c = RX.with(|rx| rx.counts);
        RxStats {
            ring_full: c[RING_FULL],
            data_overrun: c[DATA_OVERRUN],
            frame_error: c[FRAME_ERROR],
        }
    }

    /// Lost bytes since boot: ring-full drops plus hardware data overruns.
    pub fn overruns(&self) -> u16 {
        self.rx_stats().overruns()
    }

    /// The next received byte, if any. Never inlined: the driver's read loops and the
    /// provisioning window each had their own copy of the critical section.
    #[inline(never)]
    pub fn try_read(&mut self) -> Option<u8> {
        let (left, byte): (u8, u8);
        // SAFETY: the ring's pop with interrupts disabled (SREG saved and restored), as
        // `IrqCell` requires: `len` (offset 1) minus one, and if it was not 0 the byte at
        // `head` (offset 0, advanced and wrapped) of `buf` (offset 8); the `repr(C)` offsets
        // are checked above. One `asm!` block: the compiled pop was 12 B longer.
        unsafe {
            core::arch::asm!(
                "in {sreg}, 0x3f",
                "cli",
                "lds {left}, {rx}+1",
                "subi {left}, 1",     // 0xFF: it was empty
                "brcs 1f",
                "sts {rx}+1, {left}",
                "lds r30, {rx}",
                "mov {byte}, r30",
                "inc {byte}",
                "andi {byte}, {cap}-1",
                "sts {rx}, {byte}",
                "clr r31",
                "subi r30, lo8(-({rx}+8))",
                "sbci r31, hi8(-({rx}+8))",
                "ld {byte}, Z",
                "1:",
                "out 0x3f, {sreg}",
                sreg = out(reg) _,
                left = out(reg_upper) left,
                byte = out(reg_upper) byte,
                rx = sym RX,
                cap = const RX_BUFFER_SIZE,
                out("r30") _,
                out("r31") _,
            );
        }
        if left == 0xFF {
            None
        } else {
            Some(byte)
        }
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
