//! The radio at boot: bring it up through the xbee-api driver, say how it went on the UART
//! (`loc_proto::line::BootLine`) and on the LED, and retry until it answers.

use loc_proto::config::Config;
use loc_proto::line::{BootLine, RadioFound};
use loc_proto::Role;
use xbee_api::driver::{BringUp, BringUpConfig, Radio};
use xbee_api::Mode;

use super::config::{load_config, radio_config};
use super::{now_ms, reset, rx_pending, sleep_unless, Board, Led, Serial, SysClock};
use crate::{WdtTimeout, DEFAULT_BAUD};

/// The radio driver of a node: API mode 2 over USART0, timed by the 1 ms tick.
pub type NodeRadio = Radio<Serial, SysClock>;

/// Writes a boot line on the UART at 57600 (the USB serial reads it; a radio in API mode ignores
/// it, a line never holds 0x7E).
pub fn write_line(serial: &mut Serial, line: &BootLine) {
    line.write(|b| serial.write_byte(b));
}

/// Brings `radio` up (API mode 2 at 57600, `MY`/`ID`/`CH` from `config`), trying until it
/// works. Each failed attempt writes `hoploc <role> radio error <code> try <n>`, blinks `code`
/// on the LED once (5 to 8 s), then tries again; success writes `hoploc <role> radio ok …`.
///
/// The watchdog must be off (it is after `Board::take`): one attempt at a radio that never
/// answers takes about 14 s, longer than the watchdog's longest timeout, and every wait in it is
/// bounded by the tick.
pub fn bring_up_radio(radio: &mut NodeRadio, led: &mut Led, role: Role, config: &BringUpConfig) {
    let mut attempt: u16 = 0;
    loop {
        attempt = attempt.saturating_add(1);
        led.on();
        let result = radio.bring_up(config);
        led.off();
        // A failed search leaves the UART at the last rate it tried; lines go out at 57600.
        let _ = radio.serial_mut().set_baud(DEFAULT_BAUD);
        match result {
            Ok(how) => {
                let found = match how {
                    BringUp::AlreadyApi => RadioFound::Api,
                    BringUp::Configured { baud } => RadioFound::Configured { baud },
                };
                write_line(radio.serial_mut(), &BootLine::RadioUp { role, found });
                return;
            }
            Err(e) => {
                let code = e.code();
                write_line(
                    radio.serial_mut(),
                    &BootLine::RadioError {
                        role,
                        code,
                        attempt,
                    },
                );
                led.blink_code(code);
            }
        }
    }
}

/// The boot firmware of a node until its logic lands: write `hoploc <role> boot`, settle the
/// config ([`load_config`]: the provisioning window, then EEPROM or `built_in`), bring the radio
/// up with it ([`bring_up_radio`] with [`radio_config`]), then listen with the watchdog running
/// (1 s), draining received frames and toggling the LED once a second.
#[inline(always)] // so the role is a constant and its settings fold away
pub fn boot_and_listen(built_in: &Config) -> ! {
    let role = built_in.role;
    let Some(board) = Board::take() else { reset() };
    let Board {
        mut serial,
        mut led,
        mut eeprom,
        mut watchdog,
        ..
    } = board;
    write_line(&mut serial, &BootLine::Boot { role });
    let config = load_config(&mut serial, &mut eeprom, &mut led, built_in);
    // Built here and lent out: the driver (with its 130-byte decoder) lives once, on this stack.
    let mut radio = Radio::new(serial, SysClock, Mode::Escaped);
    bring_up_radio(&mut radio, &mut led, role, &radio_config(&config));
    watchdog.start(WdtTimeout::S1);
    let mut last_blink = now_ms();
    loop {
        watchdog.feed();
        while radio.poll(|_| ()).is_some() {}
        if now_ms().wrapping_sub(last_blink) >= 1000 {
            last_blink = now_ms();
            led.toggle();
        }
        sleep_unless(rx_pending);
    }
}
