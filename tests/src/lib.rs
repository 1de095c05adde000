//! Helpers for the firmware-in-simavr tests in `tests/`: the real node ELFs (built by `cargo fw`,
//! built here if missing) and the board's LED as the simulator sees it.

use std::path::PathBuf;
use std::sync::Mutex;

use hoploc::firmware::{self, Role};
use simavr::Avr;

/// Data-space address of PORTB; the Uno's LED is PB5 (D13).
pub const PORTB: usize = 0x25;
/// The LED's bit in PORTB.
pub const LED_BIT: u8 = 1 << 5;

static BUILD: Mutex<()> = Mutex::new(());

/// The ELF of `role`'s firmware (`target/avr-none/fw/<role>-fw.elf`), running `cargo fw` first if
/// it is missing. Panics with the reason if it cannot be had: a firmware test never skips.
pub fn firmware_elf(role: Role) -> PathBuf {
    let _guard = BUILD.lock().unwrap_or_else(|e| e.into_inner());
    let dir = firmware::default_dir();
    firmware::ensure_built(&dir).unwrap_or_else(|e| panic!("firmware: {e}"));
    firmware::elf(&dir, role)
}

/// `role`'s firmware loaded into a fresh simulated Uno.
pub fn boot(role: Role) -> Avr {
    let elf = firmware_elf(role);
    Avr::load(&elf).unwrap_or_else(|e| panic!("{}: {e}", elf.display()))
}

/// Whether the LED is on.
pub fn led_on(avr: &Avr) -> bool {
    avr.data().get(PORTB).is_some_and(|&v| v & LED_BIT != 0)
}

/// The beacons a firmware wrote to its modelled radio: (start of the TX16 frame on the UART in
/// ms, the decoded beacon, the radio's `CH` when the frame ended). Panics on a TX16 frame that
/// is not a broadcast beacon.
pub fn beacons_sent(radio: &simavr::xbee::XBee) -> Vec<(f64, loc_proto::msg::Beacon, u8)> {
    let mut ch = None;
    let mut out = Vec::new();
    for f in radio.frames_from_firmware() {
        match f.data.as_slice() {
            [0x08, _, b'C', b'H', c] => ch = Some(*c),
            [0x01, _, 0xFF, 0xFF, _, payload @ ..] => {
                let b = loc_proto::msg::Beacon::decode(payload)
                    .unwrap_or_else(|e| panic!("{f}: not a beacon: {e:?}"));
                out.push((f.ms(), b, ch.expect("a channel was set before a beacon")));
            }
            [0x01, ..] => panic!("{f}: not a broadcast"),
            _ => {}
        }
    }
    out
}

/// A beacon's payload.
pub fn beacon_packet(anchor: u8, seq: u16, channel: u8, pos: [i16; 2], relay: &[u8]) -> Vec<u8> {
    let b = loc_proto::msg::Beacon {
        anchor,
        seq,
        channel,
        position: loc_proto::msg::Position {
            x: pos[0],
            y: pos[1],
        },
        relay: loc_proto::msg::Relay::from_slice(relay).unwrap(),
    };
    let mut buf = [0; 32];
    let n = b.encode(&mut buf).unwrap();
    buf[..n].to_vec()
}

/// One byte on the 57600-baud UART of real hardware (10 bit times), ms.
pub const UART_BYTE_MS: f64 = loc_proto::schedule::UART_BYTE_NS as f64 / 1e6;

/// When a packet with a `payload_len`-byte payload whose sender's MCU began writing its TX16
/// frame at `tx_ms` is off the air (what `XBee::deliver` takes): the frame over the sender's
/// UART at real-hardware byte times (9 + payload bytes, no escapes), then the best-case time on
/// air.
pub fn rx_frame_delivery(tx_ms: f64, payload_len: usize) -> f64 {
    tx_ms + (9 + payload_len) as f64 * UART_BYTE_MS + simavr::xbee::time_on_air_ms(payload_len)
}

/// Agent 1's reports to a sink, for the sink firmware's tests: four anchors at the corners of a
/// 10 m × 10 m room, RSSI bytes from P0 = −40 dBm, α = 3 with no noise.
pub mod sink_reports {
    use loc_proto::config::Config;
    use loc_proto::msg::{ChannelList, Position, Report};
    use loc_proto::{xbee_channel, Role};
    use simavr::xbee::{Address, RxPacket};

    /// The anchors' positions, cm.
    pub const ANCHORS: [[i16; 2]; 4] = [[0, 0], [1000, 0], [1000, 1000], [0, 1000]];
    /// Every anchor heard.
    pub const ALL: &[usize] = &[0, 1, 2, 3];

    /// The RSSI byte (−dBm, rounded) at `d_cm` under P0 = −40 dBm, α = 3.
    fn byte(d_cm: f64) -> u8 {
        (40.0 + 30.0 * (d_cm / 100.0).max(0.01).log10()).round() as u8
    }

    fn dist(a: [i16; 2], b: [f64; 2]) -> f64 {
        ((a[0] as f64 - b[0]).powi(2) + (a[1] as f64 - b[1]).powi(2)).sqrt()
    }

    /// Agent 1's report of superframe `seq` from `at` (cm), anchors in `heard` only, channels 1
    /// and 12.
    pub fn report(seq: u16, at: [f64; 2], heard: &[usize]) -> Report {
        let mut r = Report::new(1, seq, 4, ChannelList::new(&[1, 12]).unwrap());
        for &i in heard {
            r.positions[i] = Position {
                x: ANCHORS[i][0],
                y: ANCHORS[i][1],
            };
            for c in 0..2 {
                r.rssi[c][i] = byte(dist(ANCHORS[i], at));
                for &j in heard {
                    if i != j {
                        let b = ANCHORS[j];
                        r.relay[c][i][j] = byte(dist(ANCHORS[i], [b[0] as f64, b[1] as f64]));
                    }
                }
            }
        }
        r
    }

    /// `payload` as agent 1's packet to sink 1 on the default config's sink channel.
    pub fn packet(payload: &[u8]) -> RxPacket {
        RxPacket {
            channel: xbee_channel(Config::DEFAULT.sink_channel).unwrap(),
            pan_id: Config::DEFAULT.pan_id,
            source: Address::Short(Role::Agent.address(1)),
            dest: Address::Short(Role::Sink.address(1)),
            options: 0,
            rssi_dbm: -50,
            payload: payload.to_vec(),
        }
    }

    /// `r`'s bytes on the air.
    pub fn encoded(r: &Report) -> Vec<u8> {
        let mut buf = [0; 100];
        let n = r.encode(&mut buf).unwrap();
        buf[..n].to_vec()
    }
}
