//! The LED on D13 (PB5) as an embedded-hal output pin, and the error-code blinker.

use super::pac::PORTB;
use core::convert::Infallible;
use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{ErrorType, OutputPin, StatefulOutputPin};

/// The on-board LED ("L", D13 = PB5), an output pin through embedded-hal's [`OutputPin`] and
/// [`StatefulOutputPin`]; none of its operations can fail. Owns port B.
pub struct Led {
    port: PORTB,
}

impl Led {
    /// PB5 as an output, low (LED off).
    pub(crate) fn init(port: PORTB) -> Led {
        port.portb().modify(|_, w| w.pb5().clear_bit());
        port.ddrb().modify(|_, w| w.pb5().set_bit());
        Led { port }
    }
}

impl ErrorType for Led {
    type Error = Infallible;
}

impl OutputPin for Led {
    /// LED off.
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.port.portb().modify(|_, w| w.pb5().clear_bit());
        Ok(())
    }

    /// LED on.
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.port.portb().modify(|_, w| w.pb5().set_bit());
        Ok(())
    }
}

impl StatefulOutputPin for Led {
    fn is_set_high(&mut self) -> Result<bool, Infallible> {
        Ok(self.port.portb().read().pb5().bit_is_set())
    }

    fn is_set_low(&mut self) -> Result<bool, Infallible> {
        Ok(self.port.portb().read().pb5().bit_is_clear())
    }

    /// Flips the LED in one write (writing 1 to PINB5 toggles PB5).
    fn toggle(&mut self) -> Result<(), Infallible> {
        self.port.pinb().write(|w| w.pb5().set_bit());
        Ok(())
    }
}

/// One round of error code `code` on `led`: `code` short blinks (200 ms on, 300 ms off), then a
/// 1.5 s pause. Call it in a loop to show the code for good. Leaves the LED off.
pub fn blink_code(
    led: &mut impl OutputPin<Error = Infallible>,
    delay: &mut impl DelayNs,
    code: u8,
) {
    for _ in 0..code {
        let Ok(()) = led.set_high();
        delay.delay_ms(200);
        let Ok(()) = led.set_low();
        delay.delay_ms(300);
    }
    delay.delay_ms(1500);
}
