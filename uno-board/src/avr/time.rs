//! The 1 ms tick (Timer0, CTC mode) and monotonic time.

use super::cell::IrqCell;
use super::pac::TC0;

/// Milliseconds since boot, wrapping after ~49.7 days.
static MILLIS: IrqCell<u32> = IrqCell::new(0);

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
    MILLIS.with(|ms| *ms = ms.wrapping_add(1));
}

/// Milliseconds since [`Board::take`](crate::Board::take), wrapping; compare times with
/// `wrapping_sub`. Read atomically (the u32 is four bytes on AVR).
#[inline(never)] // called from many wait loops; inlined it costs ~20 B each
pub fn now_ms() -> u32 {
    MILLIS.with(|ms| *ms)
}

/// Waits at least `ms` milliseconds, sleeping in idle mode between ticks. Interrupts must be
/// enabled (they are after `Board::take`). Does not feed the watchdog.
pub fn delay_ms(ms: u32) {
    let start = now_ms();
    // `now_ms` advances at the next tick, so `> ms` ticks guarantees at least `ms` full
    // milliseconds even if we start just before a tick.
    while now_ms().wrapping_sub(start) <= ms {
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
