//! Timer0 as the board's clock: a 1 ms tick (CTC mode), [`now_ms`], [`now_us`] with the timer's
//! 4 µs resolution (the TDMA slots need sub-ms timing), and [`Delay`], the embedded-hal delay.

use super::pac::TC0;
use avr_device::interrupt::{self, CriticalSection, Mutex};
use core::cell::Cell;
use embedded_hal::delay::DelayNs;

/// Milliseconds since boot, wrapping after ~49.7 days; the tick interrupt counts it.
static MILLIS: Mutex<Cell<u32>> = Mutex::new(Cell::new(0));

/// Timer0: CTC (top = OCR0A), clock/64 = 250 kHz, OCR0A = 249 → compare match every 1 ms.
pub(crate) fn init(tc0: &TC0) {
    tc0.tccr0a().write(|w| w.wgm0().ctc());
    tc0.ocr0a().write(|w| w.set(crate::TICK_OCR0A));
    tc0.tcnt0().write(|w| w.set(0));
    tc0.timsk0().write(|w| w.ocie0a().set_bit());
    tc0.tccr0b().write(|w| w.cs0().prescale_64());
}

#[avr_device::interrupt(atmega328p)]
fn TIMER0_COMPA() {
    interrupt::free(|cs| {
        let ms = MILLIS.borrow(cs);
        ms.set(ms.get().wrapping_add(1));
    });
}

/// Milliseconds since [`Board::take`](crate::Board::take), wrapping; compare times with
/// `wrapping_sub`. Read atomically (the u32 is four bytes on AVR).
#[inline(never)] // called from many wait loops
pub fn now_ms() -> u32 {
    interrupt::free(|cs| MILLIS.borrow(cs).get())
}

/// Microseconds since [`Board::take`](crate::Board::take), wrapping after ~71.6 minutes (compare
/// with `wrapping_sub`), in steps of 4 µs (Timer0 counts at 250 kHz, 0…249 per millisecond).
///
/// Safe with interrupts disabled (and so from interrupt handlers): a compare match whose tick
/// interrupt has not run yet is seen in TIFR0 and counted.
#[inline(never)]
pub fn now_us() -> u32 {
    interrupt::free(tick).us()
}

/// An instant of the tick as the hardware shows it: the millisecond count (a compare match whose
/// interrupt is pending already counted) and Timer0's count into that millisecond. The RX
/// interrupt stamps frames with one and leaves the 32-bit multiply of [`Tick::us`] to whoever
/// reads the stamp.
#[derive(Clone, Copy)]
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

/// The tick now, inside a critical section (the compare-match flag must not be cleared by the
/// tick interrupt between the reads).
#[inline(always)]
pub(crate) fn tick(cs: CriticalSection<'_>) -> Tick {
    // SAFETY: reads of TCNT0 and TIFR0 only (no side effects); Timer0 is configured once, by
    // `init`, and nothing else writes it.
    let tc0 = unsafe { &*TC0::ptr() };
    let count = tc0.tcnt0().read().bits();
    let pending = tc0.tifr0().read().ocf0a().bit_is_set();
    let ms = MILLIS.borrow(cs).get();
    // The flag read after the count: a set flag with a small count means the count is in the
    // next millisecond already; a count read just before the match (near 249) is not.
    let ms = if pending && count < 125 {
        ms.wrapping_add(1)
    } else {
        ms
    };
    Tick { ms, count }
}

/// The board's delay: [`DelayNs`] on Timer0.
///
/// Every delay waits at least what it is asked. `delay_ms` sleeps (idle) between ticks, and is
/// at most one tick (1 ms) longer than asked; `delay_us` and `delay_ns` poll [`now_us`] (4 µs
/// steps) and are a few µs longer (`delay_ns` rounds up to whole µs, and by up to 0.7 % more). Interrupts must be enabled (they are after
/// [`Board::take`](crate::Board::take)): the tick counts the time. None of them feeds the
/// watchdog.
#[derive(Clone, Copy, Debug, Default)]
pub struct Delay;

impl Delay {
    /// A delay on the board's clock (it is running once `Board::take` returned).
    pub const fn new() -> Delay {
        Delay
    }
}

/// Longest wait of [`spin_us`]: differences of the µs clock stay far from its wrap.
const SPIN_MAX_US: u32 = 1 << 30;

/// Waits until at least `us` µs (at most [`SPIN_MAX_US`]) have passed, polling [`now_us`].
fn spin_us(us: u32) {
    let start = now_us();
    // The first reading may lag the true start by up to one 4 µs step: `us + 4` counted µs are
    // at least `us` real ones.
    while now_us().wrapping_sub(start) < us + 4 {}
}

impl DelayNs for Delay {
    fn delay_ns(&mut self, ns: u32) {
        // At least `ns / 1000` µs without a 32-bit division (a slow library call on the AVR):
        // 1/1024 + 1/32768 > 1/1000, and the 2 covers what the shifts drop.
        self.delay_us((ns >> 10) + (ns >> 15) + 2);
    }

    fn delay_us(&mut self, mut us: u32) {
        while us > SPIN_MAX_US {
            spin_us(SPIN_MAX_US);
            us -= SPIN_MAX_US;
        }
        spin_us(us);
    }

    /// Inlined, so that a constant `ms` picks its wait at compile time.
    #[inline]
    fn delay_ms(&mut self, ms: u32) {
        // Most waits fit the clock's low 16 bits, and 16-bit arithmetic is half the AVR code of
        // 32-bit.
        match u16::try_from(ms) {
            Ok(ms) if ms < u16::MAX => wait_ms(ms),
            _ => wait_ms_long(ms),
        }
    }
}

/// Waits at least `ms` ms (`ms` < `u16::MAX`), sleeping (idle) between ticks.
#[inline(never)]
fn wait_ms(ms: u16) {
    let start = now_ms() as u16;
    // `now_ms` advances at the next tick, which may come at once: `ms + 1` ticks are at least
    // `ms` whole milliseconds. Checked and slept on without a lost wake-up, so the wait ends at
    // the tick that completes it.
    while !super::power::sleep_unless(|| (now_ms() as u16).wrapping_sub(start) > ms) {}
}

/// [`wait_ms`] for any `ms`.
#[inline(never)]
fn wait_ms_long(ms: u32) {
    // u32::MAX would wait forever: no difference of the clock exceeds it.
    let ms = ms.min(u32::MAX - 1);
    let start = now_ms();
    while !super::power::sleep_unless(|| now_ms().wrapping_sub(start) > ms) {}
}

/// A handle on the millisecond clock (for code generic over a clock, e.g. the radio driver).
#[derive(Clone, Copy, Debug, Default)]
pub struct SysClock;

/// The radio driver's clock.
impl xbee_api::driver::Clock for SysClock {
    #[inline]
    fn now_ms(&mut self) -> u32 {
        now_ms()
    }
}
