//! The node config at boot: a provisioning window on the UART, then the config in EEPROM or the
//! firmware's built-in one (`loc_proto::config` says which; `loc_proto::provision` the frame).

use loc_proto::config::{stored, Config, Stored, MAX_LEN};
use loc_proto::line::{BootLine, ConfigSource};
use loc_proto::provision::{ProvisionParser, Reply, PROVISION_WINDOW_MS, WRITE_FAILED};
use loc_proto::{xbee_channel, Role};
use xbee_api::driver::BringUpConfig;

use super::{now_ms, rx_pending, sleep_unless, write_line, Eeprom, Led, Serial};

/// The radio settings of `config`: `MY` = the role's address of the node id, `ID` = the PAN,
/// `CH` = the first anchor channel (anchors, agents: where the first beacons go) or the sink
/// channel (the sink: where reports come).
pub fn radio_config(config: &Config) -> BringUpConfig {
    let channel = match config.role {
        Role::Sink => Some(config.sink_channel),
        Role::Anchor | Role::Agent => config.channels.as_slice().first().copied(),
    };
    BringUpConfig {
        my: Some(config.role.address(config.id)),
        pan_id: Some(config.pan_id),
        channel: channel.and_then(xbee_channel),
        ..BringUpConfig::new()
    }
}

/// [`serve`] for `ms` milliseconds, sleeping (idle) between received bytes and ticks: the window
/// costs no busy CPU (nor, in simavr, emulation time). Returns whether a config was stored.
/// The clock's low 16 bits are enough for waits of at most [`PROVISION_WINDOW_MS`] (and 16-bit
/// arithmetic is half the code of 32-bit on AVR).
fn serve_for(
    serial: &mut Serial,
    eeprom: &mut Eeprom,
    parser: &mut ProvisionParser,
    role: Role,
    ms: u16,
) -> bool {
    let start = now_ms() as u16;
    while (now_ms() as u16).wrapping_sub(start) < ms {
        if serve(serial, eeprom, parser, role) {
            return true;
        }
        sleep_unless(rx_pending);
    }
    false
}

/// Answers every provisioning frame received so far: a valid config of `role` is written to
/// EEPROM (address 0), read back, and acknowledged (`HLA`, then `hoploc <role> provisioned`);
/// anything else gets its NAK. Returns whether a config was stored.
fn serve(
    serial: &mut Serial,
    eeprom: &mut Eeprom,
    parser: &mut ProvisionParser,
    role: Role,
) -> bool {
    let mut stored_one = false;
    while let Some(byte) = serial.try_read() {
        let Some(mut reply) = parser.reply(byte, role) else {
            continue;
        };
        if reply == Reply::Ack {
            // The frame's own config bytes (checked by the parser), written and read back.
            let bytes = parser.config_bytes();
            let ok = eeprom.write(0, bytes).is_ok()
                && (0..).zip(bytes).all(|(a, &b)| eeprom.read_byte(a) == Ok(b));
            if !ok {
                reply = Reply::Nak(WRITE_FAILED);
            }
        }
        serial.write_bytes(&reply.bytes());
        // Ends the reply's terminal line: the lines that follow start on their own.
        serial.write_byte(b'\r');
        serial.write_byte(b'\n');
        if reply == Reply::Ack {
            write_line(serial, &BootLine::Provisioned { role });
            stored_one = true;
        }
    }
    stored_one
}

/// The config a `role` node runs with.
///
/// 1. For [`PROVISION_WINDOW_MS`] after the call (made right after the boot line), answers
///    provisioning frames on the UART (a stored one ends the window early).
/// 2. Then reads the EEPROM: a valid config of `role` is used (`hoploc <role> config eeprom id
///    <id>`); an erased one means `built_in` (`hoploc <role> config built-in id <id>`).
/// 3. Anything else (corrupt, another role, another layout version) is never run with: the node
///    writes `hoploc <role> config error <code>`, blinks `code` on the LED, and goes on answering
///    provisioning frames (so `hoploc provision` can fix it), repeating line and code, until one
///    is stored; then back to 2.
///
/// The watchdog must be off (it is after `Board::take`). Never inlined: its buffers (the
/// parser's 29 bytes, the EEPROM block) leave the stack before the node's main loop runs.
#[inline(never)]
pub fn load_config(
    serial: &mut Serial,
    eeprom: &mut Eeprom,
    led: &mut Led,
    built_in: &Config,
) -> Config {
    let role = built_in.role;
    let mut parser = ProvisionParser::new();
    serve_for(serial, eeprom, &mut parser, role, PROVISION_WINDOW_MS);
    loop {
        let (config, source) = match read_stored(eeprom, role) {
            Stored::Valid(c) => (c, ConfigSource::Eeprom),
            Stored::Erased => (*built_in, ConfigSource::BuiltIn),
            Stored::Invalid(code) => {
                // One round of the code per line, answering frames all along.
                'wait: loop {
                    write_line(serial, &BootLine::ConfigError { role, code });
                    // Phases 0…2·code: on 200 ms (even), off 300 ms (odd), the last off 1.5 s.
                    let mut phase = 0u8;
                    loop {
                        let last = phase == 2 * code;
                        let on = !last && phase & 1 == 0;
                        led.set(on);
                        let ms = if last {
                            1500
                        } else if on {
                            200
                        } else {
                            300
                        };
                        if serve_for(serial, eeprom, &mut parser, role, ms) {
                            led.off();
                            break 'wait;
                        }
                        if last {
                            break;
                        }
                        phase += 1;
                    }
                }
                continue;
            }
        };
        write_line(
            serial,
            &BootLine::Config {
                role,
                source,
                id: config.id,
            },
        );
        return config;
    }
}

/// What the EEPROM holds for a node of `role` ([`stored`]).
fn read_stored(eeprom: &Eeprom, role: Role) -> Stored {
    let mut block = [0xFF; MAX_LEN];
    let _ = eeprom.read(0, &mut block);
    stored(&block, role)
}
