//! The watchdog and software reset.

use super::pac::{CPU, WDT};
use super::BlockAddr;
use crate::WdtTimeout;
use core::arch::asm;

/// WDTCSR: change enable + system reset enable, the first half of the timed sequence.
const WDCE_WDE: u8 = (1 << 4) | (1 << 3);

/// Writes WDTCSR with the timed sequence (interrupts off, `wdr` first so the new timeout starts
/// from a fresh count).
#[inline(always)]
fn wdtcsr_timed_write(value: u8) {
    avr_device::interrupt::free(|_| {
        // SAFETY: the datasheet's timed sequence: WDCE|WDE, then within four cycles the new
        // value; two `sts` back to back, interrupts off. WDTCSR is the first (and only) register
        // of the PAC's WDT block.
        unsafe {
            asm!(
                "wdr",
                "sts {wdtcsr}, {ce}",
                "sts {wdtcsr}, {v}",
                wdtcsr = const <WDT as BlockAddr>::ADDR,
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
    /// Clears MCUSR, then turns the watchdog off (WDRF must be cleared first, or WDE stays forced
    /// on after a watchdog reset).
    pub(crate) fn init(wdt: WDT, cpu: &CPU) -> Watchdog {
        cpu.mcusr().reset();
        wdtcsr_timed_write(0);
        Watchdog { _wdt: wdt }
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
}

/// Resets the MCU: interrupts off, watchdog at 16 ms, wait.
pub fn reset() -> ! {
    avr_device::interrupt::disable();
    wdtcsr_timed_write(WdtTimeout::Ms16.wdtcsr_bits());
    // Spin, not SLEEP: simavr ends the simulation on SLEEP with interrupts disabled.
    loop {
        avr_device::asm::nop();
    }
}
