//! The radio at boot: bring it up through the xbee-api driver, say how it went on the UART
//! (`loc_proto::line::BootLine`) and on the LED, and retry until it answers.

use core::convert::Infallible;

use loc_proto::line::{BootLine, RadioFound};
use loc_proto::Role;
use xbee_api::driver::{BringUp, BringUpConfig, Radio};
use xbee_api::Ap2;

use super::{blink_code, Delay, Led, Serial, SysClock};
use embedded_hal::digital::OutputPin;

/// The radio driver of a node: API mode 2 over USART0, timed by the 1 ms tick, without the
/// driver's and decoder's counters (`Ap2<false>`: no node reads them).
pub type NodeRadio = Radio<Serial, SysClock, Ap2<false>>;

/// Writes a boot line on the UART at 57600 (the USB serial reads it; a radio in API mode ignores
/// it, a line never holds 0x7E). Always inlined, as [`BootLine::write`]: each caller keeps its line's few calls.
#[inline(always)]
pub fn write_line(serial: &mut Serial, line: &BootLine) {
    let Ok(()) = line.write(serial);
}

/// The UART as the writer of loc-proto's text lines (`ufmt::uwrite!`): each `str` goes out byte
/// by byte, blocking. Every line a firmware writes goes through this one writer type (the sink's
/// lines through loc-proto's CRC-16 adapter around it), so ufmt's code is monomorphised once.
impl ufmt::uWrite for Serial {
    type Error = Infallible;

    fn write_str(&mut self, s: &str) -> Result<(), Infallible> {
        self.write_bytes(s.as_bytes());
        Ok(())
    }
}

/// Brings `radio` up (API mode 2 at 57600, `MY`/`ID`/`CH` from `config`), trying until it
/// works. Each failed attempt writes `hoploc <role> radio error <code> try <n>`, blinks `code`
/// on the LED once (5 to 8 s), then tries again; success writes `hoploc <role> radio ok …`.
///
/// The watchdog must be off (it is after `Board::take`; [`boot`](crate::boot) starts it after
/// this): one attempt at a radio that never
/// answers takes about 23 s, longer than the watchdog's longest timeout, and every wait in it is
/// bounded by the tick.
pub fn bring_up_radio(radio: &mut NodeRadio, led: &mut Led, role: Role, config: &BringUpConfig) {
    let mut attempt: u16 = 0;
    loop {
        attempt = attempt.saturating_add(1);
        let Ok(()) = led.set_high();
        let result = radio.bring_up(config);
        let Ok(()) = led.set_low();
        // A failed search leaves the UART at the last rate it tried; lines go out at 57600.
        radio.serial_mut().set_bd(xbee_api::driver::BD);
        // One line either way, written in one place: one copy of its start and end. (Error
        // codes are 1…12, never 0.)
        let (line, code) = match result {
            Ok(how) => (
                BootLine::RadioUp {
                    role,
                    found: match how {
                        BringUp::AlreadyApi => RadioFound::Api,
                        BringUp::Configured { baud } => RadioFound::Configured { baud },
                    },
                },
                0,
            ),
            Err(e) => {
                let code = e.code();
                (
                    BootLine::RadioError {
                        role,
                        code,
                        attempt,
                    },
                    code,
                )
            }
        };
        write_line(radio.serial_mut(), &line);
        if code == 0 {
            return;
        }
        blink_code(led, &mut Delay, code);
    }
}
