//! The LED on D13 (PB5).

use super::pac::PORTB;
use super::time::delay_ms;

/// The on-board LED ("L", D13 = PB5). Owns port B.
pub struct Led {
    port: PORTB,
}

impl Led {
    pub(crate) fn init(port: PORTB) -> Led {
        port.portb().modify(|_, w| w.pb5().clear_bit());
        port.ddrb().modify(|_, w| w.pb5().set_bit());
        Led { port }
    }

    /// LED on.
    pub fn on(&mut self) {
        self.port.portb().modify(|_, w| w.pb5().set_bit());
    }

    /// LED off.
    pub fn off(&mut self) {
        self.port.portb().modify(|_, w| w.pb5().clear_bit());
    }

    /// Toggles the LED (writing 1 to PINB5 flips PB5 atomically).
    pub fn toggle(&mut self) {
        self.port.pinb().write(|w| w.pb5().set_bit());
    }

    /// Sets the LED.
    pub fn set(&mut self, on: bool) {
        if on {
            self.on()
        } else {
            self.off()
        }
    }

    /// `n` blinks (`on_ms` on, `off_ms` off), blocking. Feeds the watchdog between phases.
    pub fn blink(&mut self, n: u8, on_ms: u16, off_ms: u16) {
        for _ in 0..n {
            self.on();
            avr_device::asm::wdr();
            delay_ms(on_ms);
            self.off();
            avr_device::asm::wdr();
            delay_ms(off_ms);
        }
    }

    /// One round of an error code: `code` short blinks (200 ms on, 300 ms off), then a 1.5 s pause.
    /// Call it in a loop to show the code forever. Feeds the watchdog.
    pub fn blink_code(&mut self, code: u8) {
        self.blink(code, 200, 300);
        avr_device::asm::wdr();
        delay_ms(1500);
        avr_device::asm::wdr();
    }
}
