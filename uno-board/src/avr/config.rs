//! The node config at boot: a provisioning window on the UART, then the config in EEPROM or the
//! firmware's built-in one (`loc_proto::config` says which; `loc_proto::provision` the frame).

use loc_proto::config::{read_into, write_config_line, Config};
use loc_proto::line::ConfigSource;
use loc_proto::provision::{write_answer, ProvisionParser, PROVISION_WINDOW_MS, WRITE_FAILED};
use loc_proto::Role;

use super::{now_ms, rx_pending, sleep_unless, Eeprom, Led, Serial};
use embedded_hal::digital::{OutputPin, StatefulOutputPin};

/// The config a `role` node runs with: `config` holds the firmware's built-in one on entry (of
/// `role`), and the one to run with on return. (`role` apart, a constant: with the one call of
/// each firmware the role folds into the code.)
///
/// 1. For [`PROVISION_WINDOW_MS`] after the call (made right after the boot line), answers
///    provisioning frames on the UART: a valid config of `role` is written to EEPROM
///    (address 0), read back, and acknowledged (`HLA`, then `hoploc <role> provisioned`), which
///    ends the window early; anything else gets its NAK.
/// 2. Then reads the EEPROM: a valid config of `role` is used (`hoploc <role> config eeprom
///    id <id>`); an erased one means the built-in one (`hoploc <role> config built-in id <id>`).
/// 3. Anything else (corrupt, another role, another layout version) is never run with: the node
///    writes `hoploc <role> config error <code>`, blinks `code` on the LED, and goes on answering
///    provisioning frames (so `hoploc provision` can fix it), repeating line and code, until one
///    is stored; then back to 2.
///
/// One loop, one place that answers frames and one that waits: the window, each blink phase
/// and the pause after a round are waits of `ms` milliseconds, sleeping (idle) between received
/// bytes and ticks, so they cost no busy CPU (nor, in simavr, emulation time). The clock's low
/// 16 bits are enough for waits of at most [`PROVISION_WINDOW_MS`] (and 16-bit arithmetic is
/// half the code of 32-bit on AVR).
///
/// The watchdog must be off (it is after `Board::take`). Never inlined: its buffer (the
/// parser's, which the EEPROM block is read into too) leaves the stack before the node's main
/// loop runs.
#[inline(never)]
pub fn load_config(
    serial: &mut Serial,
    eeprom: &mut Eeprom,
    led: &mut Led,
    role: Role,
    config: &mut Config,
) {
    let mut parser = ProvisionParser::new();
    // The blink phases left of a round of an error code: 2·code…0, on 200 ms (even), off
    // 300 ms (odd), the last (0) off 1.5 s. 0 in the window.
    let mut left = 0u8;
    let mut ms = PROVISION_WINDOW_MS;
    let mut start = now_ms() as u16;
    loop {
        let mut stored = false;
        while let Some(byte) = serial.try_read() {
            let Some(mut code) = parser.node_reply(byte, role) else {
                continue;
            };
            // The frame's own config bytes (checked by the parser), written and read back.
            if code == 0 && !eeprom.write_verified(0, parser.config_bytes()) {
                code = WRITE_FAILED;
            }
            let Ok(()) = write_answer(serial, code, role);
            stored |= code == 0;
        }
        if !stored && (now_ms() as u16).wrapping_sub(start) < ms {
            sleep_unless(rx_pending);
            continue;
        }
        if !stored && left != 0 {
            left -= 1;
        } else {
            // The window is over, a config was stored, or a round of the code: what the
            // EEPROM holds now, read into the parser's buffer (its frame, if any, is answered
            // already). Erased (first byte 0xFF) means the built-in config, which `config`
            // still holds (it is only written with a valid one): an erased block is decoded
            // too (BadMagic, `config` untouched), then taken as code 0, so no path has a
            // constant code to specialise and the line below is written in one place.
            let (code, source) = {
                let block = parser.eeprom_block();
                let _ = eeprom.read(0, block);
                let erased = block[0] == 0xFF;
                let code = read_into(block, role, Some(config));
                let source = [ConfigSource::Eeprom, ConfigSource::BuiltIn][erased as usize];
                (code & (erased as u8).wrapping_sub(1), source)
            };
            // One line either way (one round of the code per error line), written in one place.
            let Ok(()) = write_config_line(serial, role, code, source, config.id);
            let Ok(()) = led.set_low();
            if code == 0 {
                return;
            }
            left = 2 * code;
        }
        // From off, each phase of a round but the last flips the LED: on (even), off (odd).
        if left != 0 {
            let Ok(()) = led.toggle();
        }
        ms = if left == 0 {
            1500
        } else if left & 1 == 0 {
            200
        } else {
            300
        };
        start = now_ms() as u16;
    }
}
