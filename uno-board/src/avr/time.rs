//! The 1 ms tick (Timer0, CTC mode) and monotonic time: [`now_ms`], and [`now_us`] with the
//! timer's 4 µs resolution for the TDMA slots (the thesis' 62.5 ms slots need sub-ms timing).

use super::cell::IrqCell;
use super::pac::TC0;

/// Milliseconds since boot, wrapping after ~49.7 days.
pub(super) static MILLIS: IrqCell<u32> = IrqCell::new(0);

/// Timer0: CTC (top = OCR0A), clock/64 = 250 kHz, OCR0A = 249 → compare match every 1 ms.
pub(crate) fn init(tc0: &TC0) {
    tc0.tccr0a().write(|w| w.wgm0().ctc());
    tc0.ocr0a().write(|w| w.set(crate::TICK_OCR0A));
    tc0.tcnt0().write(|w| w.set(0));
    tc0.timsk0().write(|w| w.ocie0a().set_bit());
    tc0.tccr0b().write(|w| w.cs0().prescale_64());
}

// `MILLIS += 1` as one `asm!` block through Z: the compiled increment (`lds`/`sts` of each byte
// and a critical section the handler does not need) was 16 B longer.
#[avr_device::interrupt(atmega328p)]
fn TIMER0_COMPA() {
    // SAFETY: interrupts are off in the handler (no nesting), so this is the only access to
    // `MILLIS` while it runs, as `IrqCell` requires; r1 is 0 (the handler's prologue clears it).
    unsafe {
        core::arch::asm!(
            "ldi r30, lo8({ms})",
            "ldi r31, hi8({ms})",
            "ld r24, Z",
            "ldd r25, Z+1",
            "ldd r26, Z+2",
            "ldd r27, Z+3",
            "adiw r24, 1",
            "adc r26, r1",
            "adc r27, r1",
            "st Z, r24",
            "std Z+1, r25",
            "std Z+2, r26",
            "std Z+3, r27",
            ms = sym MILLIS,
            out("r24") _,
            out("r25") _,
            out("r26") _,
            out("r27") _,
            out("r30") _,
            out("r31") _,
        );
    }
}

/// Milliseconds since [`Board::take`](crate::Board::take), wrapping; compare times with
/// `wrapping_sub`. Read atomically (the u32 is four bytes on AVR).
#[inline(never)] // called from many wait loops; inlined it costs ~20 B each
pub fn now_ms() -> u32 {
    MILLIS.with(|ms| *ms)
}

/// Microseconds since [`Board::take`](crate::Board::take), wrapping after ~71.6 minutes (compare
/// with `wrapping_sub`), in steps of 4 µs (Timer0 counts at 250 kHz, 0…249 per millisecond).
///
/// Safe with interrupts disabled (and so from interrupt handlers): a compare match whose tick
/// interrupt has not run yet is seen in TIFR0 and counted.
#[inline(never)]
pub fn now_us() -> u32 {
    avr_device::interrupt::free(|_| tick()).us()
}

/// An instant of the tick as the hardware shows it: the millisecond count (a compare match whose
/// interrupt is pending already counted) and Timer0's count into that millisecond. The RX
/// interrupt (assembly, in `serial`) stamps frames with one, as [`tick`] takes it, and leaves the
/// 32-bit multiply of [`Tick::us`] to whoever reads the stamp. `repr(C)`: `ms` at offset 0,
/// `count` at 4.
#[derive(Clone, Copy)]
#[repr(C)]
pub(crate) struct Tick {
    ms: u32,
    count: u8,
}

impl Tick {
    /// A `Tick` that is [`now_us`] 0.
    pub(crate) const ZERO: Tick = Tick { ms: 0, count: 0 };

    /// The instant in microseconds, as [`now_us`] gives it. One out-of-line copy of the
    /// conversion for [`now_us`] and `rx_frame_start_us`.
    #[inline(never)]
    pub(crate) fn us(self) -> u32 {
        self.ms
            .wrapping_mul(1000)
            .wrapping_add(u32::from(self.count) * 4)
    }
}

/// The tick now. Interrupts must be disabled.
#[inline(always)]
fn tick() -> Tick {
    // SAFETY: reads of TCNT0 and TIFR0 only; nothing else reads or clears OCF0A except the
    // hardware when TIMER0_COMPA runs, which cannot happen while interrupts are disabled.
    let tc0 = unsafe { &*TC0::ptr() };
    let count = tc0.tcnt0().read().bits();
    let pending = tc0.tifr0().read().ocf0a().bit_is_set();
    let ms = MILLIS.with(|ms| *ms);
    // The flag read after the count: a set flag with a small count means the count is in the
    // next millisecond already; a count read just before the match (near 249) is not.
    let ms = if pending && count < 125 {
        ms.wrapping_add(1)
    } else {
        ms
    };
    Tick { ms, count }
}

/// Waits at least `ms` milliseconds, sleeping in idle mode between ticks. Interrupts must be
/// enabled (they are after `Board::take`). Does not feed the watchdog. 16 bits (the clock's low
/// 16 bits, up to 65 534 ms): half the AVR code of 32-bit arithmetic.
pub fn delay_ms(ms: u16) {
    // 65 535 would wait forever: no 16-bit difference exceeds it.
    let ms = ms.min(u16::MAX - 1);
    let start = now_ms() as u16;
    // `now_ms` advances at the next tick, so `> ms` ticks guarantees at least `ms` full
    // milliseconds even if we start just before a tick.
    while (now_ms() as u16).wrapping_sub(start) <= ms {
        super::power::sleep_idle();
    }
}

/// A handle on the millisecond clock (for code generic over a clock, e.g. the radio driver).
#[derive(Clone, Copy, Debug, Default)]
pub struct SysClock;

impl SysClock {
    /// Same as [`now_ms`].
    #[inline]
    pub fn now_ms(&self) -> u32 {
        now_ms()
    }
}

/// The radio driver's clock.
impl xbee_api::driver::Clock for SysClock {
    #[inline]
    fn now_ms(&mut self) -> u32 {
        now_ms()
    }
}
