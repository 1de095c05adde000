//! The watchdog, reset causes, and software reset.

use super::pac::{CPU, WDT};
use crate::WdtTimeout;
use core::arch::asm;

/// WDTCSR: change enable + system reset enable, the first half of the timed sequence.
const WDCE_WDE: u8 = (1 << 4) | (1 << 3);

/// Writes WDTCSR with the timed sequence (interrupts off, `wdr` first so the new timeout starts
/// from a fresh count).
#[inline(always)]
fn wdtcsr_timed_write(value: u8) {
    avr_device::interrupt::free(|_| {
        // SAFETY: the datasheet's timed sequence: WDCE|WDE, then within four cycles the new value.
        // Two `sts` back to back, interrupts off. WDTCSR is at data address 0x60.
        unsafe {
            asm!(
                "wdr",
                "sts 0x60, {ce}",
                "sts 0x60, {v}",
                ce = in(reg) WDCE_WDE,
                v = in(reg) value,
                options(nostack),
            )
        };
    });
}

/// The watchdog timer (system reset mode).
pub struct Watchdog {
    _wdt: WDT,
}

impl Watchdog {
    /// Reads and clears MCUSR, then turns the watchdog off (WDRF must be cleared first, or WDE
    /// stays forced on after a watchdog reset).
    pub(crate) fn init(wdt: WDT, cpu: &CPU) -> (Watchdog, ResetCause) {
        let cause = ResetCause(cpu.mcusr().read().bits());
        cpu.mcusr().reset();
        wdtcsr_timed_write(0);
        (Watchdog { _wdt: wdt }, cause)
    }

    /// Starts (or re-times) the watchdog: the MCU resets unless [`feed`](Self::feed) is called
    /// within `timeout`.
    pub fn start(&mut self, timeout: WdtTimeout) {
        wdtcsr_timed_write(timeout.wdtcsr_bits());
    }

    /// Restarts the watchdog count.
    #[inline]
    pub fn feed(&mut self) {
        avr_device::asm::wdr();
    }

    /// Turns the watchdog off.
    pub fn stop(&mut self) {
        wdtcsr_timed_write(0);
    }
}

/// Resets the MCU: interrupts off, watchdog at 16 ms, wait. The next boot sees
/// [`ResetCause::watchdog`].
pub fn reset() -> ! {
    avr_device::interrupt::disable();
    wdtcsr_timed_write(WdtTimeout::Ms16.wdtcsr_bits());
    // Spin, not SLEEP: simavr ends the simulation on SLEEP with interrupts disabled.
    loop {
        avr_device::asm::nop();
    }
}

/// The MCUSR flags at boot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ResetCause(pub u8);

impl ResetCause {
    /// Power-on reset (PORF).
    pub fn power_on(self) -> bool {
        self.0 & 1 != 0
    }
    /// External reset: the reset pin, e.g. the bootloader after upload or the reset button (EXTRF).
    pub fn external(self) -> bool {
        self.0 & 2 != 0
    }
    /// Brown-out reset (BORF).
    pub fn brown_out(self) -> bool {
        self.0 & 4 != 0
    }
    /// Watchdog reset (WDRF): a hang, or a panic (see [`reset`]).
    pub fn watchdog(self) -> bool {
        self.0 & 8 != 0
    }
}
