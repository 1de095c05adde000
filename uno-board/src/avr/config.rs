//! The node config at boot: a provisioning window on the UART, then the config in EEPROM or the
//! firmware's built-in one (`loc_proto::config` says which; `loc_proto::provision` the frame).

use loc_proto::config::{read_into, Config, MAX_LEN};
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

/// The provisioning window: for `ms` milliseconds answers every provisioning frame received,
/// sleeping (idle) between received bytes and ticks, so the window costs no busy CPU (nor, in
/// simavr, emulation time). A valid config of `role` is written to EEPROM (address 0), read
/// back, and acknowledged (`HLA`, then `hoploc <role> provisioned`); anything else gets its NAK.
/// Returns whether a config was stored (once the bytes received so far are answered). `scratch`
/// takes the decoded config of a frame (meaningless to the caller).
///
/// The clock's low 16 bits are enough for waits of at most [`PROVISION_WINDOW_MS`] (and 16-bit
/// arithmetic is half the code of 32-bit on AVR).
fn serve_for(
    serial: &mut Serial,
    eeprom: &mut Eeprom,
    parser: &mut ProvisionParser,
    scratch: &mut Config,
    role: Role,
    ms: u16,
) -> bool {
    let start = now_ms() as u16;
    let mut stored_one = false;
    loop {
        while let Some(byte) = serial.try_read() {
            let Some(mut reply) = parser.reply_into(byte, role, scratch) else {
                continue;
            };
            // The frame's own config bytes (checked by the parser), written and read back.
            if reply == Reply::Ack && !eeprom.write_verified(0, parser.config_bytes()) {
                reply = Reply::Nak(WRITE_FAILED);
            }
            write_reply(serial, reply);
            if reply == Reply::Ack {
                write_line(serial, &BootLine::Provisioned { role });
                stored_one = true;
            }
        }
        if stored_one || (now_ms() as u16).wrapping_sub(start) >= ms {
            return stored_one;
        }
        sleep_unless(rx_pending);
    }
}

/// Writes `reply`, then `\r\n`: the lines that follow start on their own in a terminal. Never
/// inlined: one copy for ACK and NAK.
#[inline(never)]
fn write_reply(serial: &mut Serial, reply: Reply) {
    // Byte by byte: a `[u8; 4]` on the stack would cost a frame.
    let [h, l, kind, code] = reply.bytes();
    serial.write_byte(h);
    serial.write_byte(l);
    serial.write_byte(kind);
    serial.write_byte(code);
    serial.write_byte(b'\r');
    serial.write_byte(b'\n');
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
    let mut config = *built_in;
    serve_for(
        serial,
        eeprom,
        &mut parser,
        &mut config,
        role,
        PROVISION_WINDOW_MS,
    );
    loop {
        let mut block = [0xFF; MAX_LEN];
        let _ = eeprom.read(0, &mut block);
        // An erased EEPROM (first byte 0xFF) means the built-in config.
        let (code, source) = if block[0] == 0xFF {
            config = *built_in;
            (0, ConfigSource::BuiltIn)
        } else {
            (read_into(&block, role, &mut config), ConfigSource::Eeprom)
        };
        if code == 0 {
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
                if serve_for(serial, eeprom, &mut parser, &mut config, role, ms) {
                    led.off();
                    break 'wait;
                }
                if last {
                    break;
                }
                phase += 1;
            }
        }
    }
}
