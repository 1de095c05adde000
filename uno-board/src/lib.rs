//! Board layer for the Arduino Uno (ATmega328P @ 16 MHz) over [`avr-device`], in the manner of
//! avr-hal's board crates: the peripherals the hoploc nodes use, set up once by `Board::take`.
//!
//! * `Serial`: USART0 (pins D0/D1, the XBee and the USB serial) at 57600 8N1 by default,
//!   interrupt-driven RX into a [`RX_BUFFER_SIZE`]-byte ring, blocking or non-blocking TX,
//!   `Serial::set_baud` for radio bring-up; it implements the `embedded-hal-nb` 1.0 serial
//!   traits and `xbee_api::driver::SetBaud`, which is all `xbee-api`'s driver needs.
//! * Timer0: a 1 ms tick and the clocks `now_ms` and `now_us`; `Delay` (embedded-hal 1.0
//!   `DelayNs`) and `SysClock` (`xbee_api::driver::Clock`).
//! * `Led` on D13, an embedded-hal 1.0 `OutputPin` and `StatefulOutputPin`, and
//!   `blink_code` for error codes.
//! * `Eeprom` (1 KB), `Watchdog` and `reset`; `sleep_unless` (idle mode, interrupts
//!   keep running).
//! * State shared with the interrupt handlers lives in `avr_device::interrupt::Mutex`es and is
//!   touched inside critical sections only.
//!
//! On top of the board, what every node does at boot, in one routine, `boot`: the boot line,
//! the node config (`load_config`: the provisioning window on the UART, then the config in
//! EEPROM or the firmware's built-in one, or a config error the node does not run with), the
//! radio bring-up (`bring_up_radio`: the xbee-api driver on `Serial`, the
//! `loc_proto::line::BootLine` lines, the LED error code and the retry), the watchdog; and
//! `node`, what the node loops do with the radio.
//!
//! Also here: `libm` (safe wrappers of avr-libc's `f32` `log10`/`exp`/`sqrt`, for the f32
//! benchmark in `mcu-bench`). With the default `panic-reset` feature the crate provides the
//! `#[panic_handler]`: reset through the watchdog, no formatting.
//!
//! Everything AVR-specific is behind `cfg(target_arch = "avr")` (so these docs, built for the host,
//! name those items without linking them): on the host the crate only has its portable, unit-tested
//! parts ([`baud`], [`WdtTimeout`], [`eeprom_range`]), so the workspace builds and tests there.
//!
//! `unsafe` in uno-board is only for: register access from interrupt handlers, the timed write
//! sequences (watchdog, EEPROM) and `SEI; SLEEP` in inline assembly, and the calls into
//! avr-libc's float math (`libm`). Each use carries a `SAFETY` comment.
//!
//! [`avr-device`]: https://docs.rs/avr-device
#![no_std]
#![cfg_attr(target_arch = "avr", feature(asm_experimental_arch, abi_avr_interrupt))]
#![warn(missing_docs)]

pub mod baud;

#[cfg(target_arch = "avr")]
mod avr;
#[cfg(target_arch = "avr")]
pub use avr::*;

/// Bytes the USART RX ring holds (≈ 22 ms of traffic at 57600 baud).
pub const RX_BUFFER_SIZE: usize = 128;

/// The default USART0 rate: the XBee's `BD=6`.
pub const DEFAULT_BAUD: u32 = 57_600;

/// Size of the ATmega328P's EEPROM in bytes.
pub const EEPROM_SIZE: u16 = 1024;

/// Checks that `len` bytes starting at `addr` lie inside the EEPROM.
pub const fn eeprom_range(addr: u16, len: usize) -> Result<(), EepromError> {
    if len > EEPROM_SIZE as usize || addr as usize > EEPROM_SIZE as usize - len {
        Err(EepromError::OutOfRange)
    } else {
        Ok(())
    }
}

/// EEPROM access errors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EepromError {
    /// The address range does not lie within the 1 KB EEPROM.
    OutOfRange,
}

/// Errors of `Serial::set_baud` (see [`baud`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BaudError {
    /// The rate cannot be produced from 16 MHz by the 12-bit divisor.
    Unreachable,
}

/// Watchdog timeouts (the WDP3..0 prescaler; nominal at the 128 kHz watchdog oscillator, which
/// varies with voltage and temperature).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum WdtTimeout {
    /// 16 ms
    Ms16 = 0,
    /// 32 ms
    Ms32 = 1,
    /// 64 ms
    Ms64 = 2,
    /// 125 ms
    Ms125 = 3,
    /// 250 ms
    Ms250 = 4,
    /// 500 ms
    Ms500 = 5,
    /// 1 s
    S1 = 6,
    /// 2 s
    S2 = 7,
    /// 4 s
    S4 = 8,
    /// 8 s
    S8 = 9,
}

impl WdtTimeout {
    /// WDTCSR value with WDE set and this prescaler (WDP3 is bit 5, WDP2..0 are bits 2..0).
    pub const fn wdtcsr_bits(self) -> u8 {
        let p = self as u8;
        WDTCSR_WDE | ((p & 0x08) << 2) | (p & 0x07)
    }
}

/// WDTCSR: watchdog system reset enable.
const WDTCSR_WDE: u8 = 1 << 3;

/// Timer0 compare value for a 1 ms tick: 16 MHz / 64 / (249 + 1) = 1000 Hz.
pub const TICK_OCR0A: u8 = 249;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_is_one_millisecond() {
        assert_eq!(baud::F_CPU / 64 / (TICK_OCR0A as u32 + 1), 1000);
    }

    #[test]
    fn eeprom_bounds() {
        assert_eq!(eeprom_range(0, 1024), Ok(()));
        assert_eq!(eeprom_range(1023, 1), Ok(()));
        assert_eq!(eeprom_range(1024, 0), Ok(()));
        assert_eq!(eeprom_range(1024, 1), Err(EepromError::OutOfRange));
        assert_eq!(eeprom_range(1, 1024), Err(EepromError::OutOfRange));
        assert_eq!(eeprom_range(0, 5000), Err(EepromError::OutOfRange));
        assert_eq!(eeprom_range(u16::MAX, 1), Err(EepromError::OutOfRange));
    }

    #[test]
    fn watchdog_prescaler_bits() {
        assert_eq!(WdtTimeout::Ms16.wdtcsr_bits(), 0x08);
        assert_eq!(WdtTimeout::S1.wdtcsr_bits(), 0x0E);
        assert_eq!(WdtTimeout::S4.wdtcsr_bits(), 0x28);
        assert_eq!(WdtTimeout::S8.wdtcsr_bits(), 0x29);
    }
}
