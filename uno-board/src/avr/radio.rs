//! The radio at boot: bring it up through the xbee-api driver, say how it went on the UART
//! (`loc_proto::line::BootLine`) and on the LED, and retry until it answers.

use loc_proto::line::{BootLine, RadioFound};
use loc_proto::{xbee_channel, Role, DEFAULT_PAN_ID};
use xbee_api::driver::{BringUp, BringUpConfig, Radio};
use xbee_api::Mode;

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

/// The radio settings until node config lands: node 1 of `role` on the default PAN, on the
/// role's boot channel (`Role::boot_channel`).
pub const fn boot_radio_config(role: Role) -> BringUpConfig {
    BringUpConfig {
        my: Some(role.address(1)),
        pan_id: Some(DEFAULT_PAN_ID),
        channel: xbee_channel(role.boot_channel()),
        ..BringUpConfig::new()
    }
}

/// The boot firmware of every role until its node logic lands: write `hoploc <role> boot`, bring
/// the radio up ([`bring_up_radio`] with [`boot_radio_config`]), then listen with the watchdog
/// running (1 s), draining received frames and toggling the LED once a second.
#[inline(always)] // so `role` is a constant and its settings fold away
pub fn boot_and_listen(role: Role) -> ! {
    let Some(board) = Board::take() else { reset() };
    let Board {
        mut serial,
        mut led,
        mut watchdog,
        ..
    } = board;
    write_line(&mut serial, &BootLine::Boot { role });
    // Built here and lent out: the driver (with its 130-byte decoder) lives once, on this stack.
    let mut radio = Radio::new(serial, SysClock, Mode::Escaped);
    // From a constant table rather than built on the stack: with `role` a constant the driver's
    // reads of it fold away (100 B of flash, measured).
    const CONFIGS: [BringUpConfig; 3] = [
        boot_radio_config(Role::Anchor),
        boot_radio_config(Role::Agent),
        boot_radio_config(Role::Sink),
    ];
    let config = match role {
        Role::Anchor => &CONFIGS[0],
        Role::Agent => &CONFIGS[1],
        Role::Sink => &CONFIGS[2],
    };
    bring_up_radio(&mut radio, &mut led, role, config);
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
