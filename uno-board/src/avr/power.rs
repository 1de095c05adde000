//! Idle sleep between interrupts.

use super::pac::CPU;
use core::arch::asm;

/// Selects idle mode and sets SE once for good: only the SLEEP instruction sleeps, so there is no
/// need to toggle SE around it. In idle mode the CPU stops; timers, the USART and interrupts run.
pub(crate) fn init(cpu: &CPU) {
    cpu.smcr().write(|w| w.sm().idle().se().set_bit());
}

/// Sleeps (idle) until the next interrupt unless `ready()` is true, without losing a wake-up:
/// `ready` is evaluated with interrupts disabled, and `SEI; SLEEP` is atomic on AVR (the
/// instruction after SEI runs before any pending interrupt), so an event that arrives after the
/// check still wakes the CPU. With the 1 ms tick running, the sleep lasts at most 1 ms. Leaves
/// interrupts enabled; returns what `ready` said. Typical: `sleep_unless(rx_pending)`.
#[inline]
pub fn sleep_unless(ready: impl FnOnce() -> bool) -> bool {
    avr_device::interrupt::disable();
    let ready = ready();
    if ready {
        // SAFETY: interrupts were enabled by `Board::take`; this only re-enables them.
        unsafe { avr_device::interrupt::enable() };
    } else {
        // SAFETY: as above; SEI+SLEEP enables interrupts and sleeps atomically.
        unsafe { asm!("sei", "sleep", options(nostack)) };
    }
    ready
}
