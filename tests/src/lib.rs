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

/// `role`'s firmware on a fresh simulated Uno with a modelled XBee already in API mode 2 at
/// 57600, run until the radio is up: with `config` written into its EEPROM first (as `hoploc
/// provision` stores it), or with the ELF's built-in config for `None` (the ELF's `.eeprom`
/// image of it, as simavr loads it). Returns the time the radio line was written (ms). Panics
/// if the node does not say it runs that config, or if the radio is not up within 1.5 s of the
/// provisioning window.
pub fn boot_configured(
    role: Role,
    config: Option<&loc_proto::config::Config>,
) -> (Avr, simavr::xbee::XBee, f64) {
    use loc_proto::line::{BootLine, ConfigSource};
    let mut avr = boot(role);
    if let Some(c) = config {
        let mut block = [0; loc_proto::config::MAX_LEN];
        let n = c
            .to_bytes(&mut block)
            .unwrap_or_else(|e| panic!("{c:?}: {e:?}"));
        avr.eeprom_write(0, &block[..n])
            .unwrap_or_else(|e| panic!("EEPROM: {e}"));
    }
    let mut radio = simavr::xbee::XBee::new(simavr::xbee::XBeeConfig::api(2));
    let deadline = loc_proto::provision::PROVISION_WINDOW_MS as f64 + 1_500.0;
    let up = loop {
        radio.run_for_ms(&mut avr, 5.0);
        let up = radio
            .text_lines()
            .iter()
            .find(|l| matches!(BootLine::parse(&l.text), Ok(BootLine::RadioUp { .. })))
            .map(|l| l.ms());
        if let Some(up) = up {
            break up;
        }
        assert!(
            avr.time_ms() < deadline,
            "{role:?}: no radio line: {:?}",
            radio.texts()
        );
    };
    // Without a config of ours the EEPROM holds the ELF's `.eeprom` image of the built-in one.
    let id = config.map_or(1, |c| c.id);
    let said = radio
        .text_lines()
        .iter()
        .find_map(|l| match BootLine::parse(&l.text) {
            Ok(BootLine::Config {
                role: r,
                source,
                id: i,
            }) => Some((r, source, i)),
            _ => None,
        });
    assert_eq!(said, Some((role, ConfigSource::Eeprom, id)));
    (avr, radio, up)
}

/// The seeded draws of the randomized tests that hold a firmware in simavr to its host logic
/// (`tests/*_vs_host.rs`): a generator, and the testbed's quantities drawn over all the values
/// the protocol admits, the awkward ones included.
pub mod random {
    use loc_proto::msg::{ChannelList, Position, MAX_ANCHORS};
    use rand_xoshiro::rand_core::{Rng as _, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    /// The variable that overrides a test's seed (decimal, or hex with `0x`), to rerun a failure
    /// or try other draws.
    pub const SEED_VAR: &str = "HOPLOC_TEST_SEED";

    /// `default`, or [`SEED_VAR`]'s value if it is set (panics if that is not a number).
    pub fn seed(default: u64) -> u64 {
        match std::env::var(SEED_VAR) {
            Ok(s) => {
                let s = s.trim();
                let parsed = match s.strip_prefix("0x") {
                    Some(h) => u64::from_str_radix(h, 16),
                    None => s.parse(),
                };
                parsed.unwrap_or_else(|e| panic!("{SEED_VAR}={s}: {e}"))
            }
            Err(_) => default,
        }
    }

    /// A seeded generator (xoshiro256++).
    pub struct Rng(Xoshiro256PlusPlus);

    impl Rng {
        /// The generator of `seed`.
        pub fn new(seed: u64) -> Rng {
            Rng(Xoshiro256PlusPlus::seed_from_u64(seed))
        }

        /// 64 random bits.
        pub fn u64(&mut self) -> u64 {
            self.0.next_u64()
        }

        /// Uniform in `0..n` (`n > 0`).
        pub fn below(&mut self, n: u64) -> u64 {
            ((u128::from(self.u64()) * u128::from(n)) >> 64) as u64
        }

        /// Uniform in `lo..=hi`.
        pub fn range(&mut self, lo: i64, hi: i64) -> i64 {
            lo + self.below((hi - lo + 1) as u64) as i64
        }

        /// A random byte.
        pub fn byte(&mut self) -> u8 {
            self.u64() as u8
        }

        /// Uniform in `[0, 1)`.
        pub fn unit(&mut self) -> f64 {
            (self.u64() >> 11) as f64 / (1u64 << 53) as f64
        }

        /// True with probability `p`.
        pub fn chance(&mut self, p: f64) -> bool {
            self.unit() < p
        }

        /// A standard normal draw (Box–Muller).
        pub fn normal(&mut self) -> f64 {
            let u = 1.0 - self.unit();
            let v = self.unit();
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }

        /// One of `xs` (not empty).
        pub fn pick<T: Copy>(&mut self, xs: &[T]) -> T {
            xs[self.below(xs.len() as u64) as usize]
        }

        /// `xs` in random order.
        pub fn shuffle<T>(&mut self, xs: &mut [T]) {
            for i in (1..xs.len()).rev() {
                xs.swap(i, self.below(i as u64 + 1) as usize);
            }
        }
    }

    /// `c` (1…4) distinct testbed channels (1…16) in random hop order.
    pub fn channels(rng: &mut Rng, c: usize) -> ChannelList {
        let mut all: Vec<u8> = (1..=16).collect();
        rng.shuffle(&mut all);
        ChannelList::new(&all[..c]).expect("1…4 distinct channels of 1…16")
    }

    /// RSSI bytes at the edges of what a radio reports (1 and 255 and their neighbours, the
    /// middle of the byte).
    pub const EDGE_BYTES: [u8; 8] = [1, 2, 3, 127, 128, 253, 254, 255];

    /// A byte of [`EDGE_BYTES`].
    pub fn edge_byte(rng: &mut Rng) -> u8 {
        rng.pick(&EDGE_BYTES)
    }

    /// What kind of layout [`anchor_layout`] drew.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum Layout {
        /// In a room of 3…30 m a side, the first four at its corners.
        Room,
        /// Anywhere within ±30 m of the origin, negative coordinates too.
        Signed,
        /// Anywhere in the `i16` plane (±327 m).
        Far,
        /// A room's, with anchors on top of each other (some, or all).
        Coincident,
        /// On one line.
        Collinear,
    }

    /// Positions (cm) for anchors 1…`n` (the rest 0, 0), of a random [`Layout`].
    pub fn anchor_layout(rng: &mut Rng, n: usize) -> ([Position; MAX_ANCHORS], Layout) {
        let mut p = [Position { x: 0, y: 0 }; MAX_ANCHORS];
        let at = |x: i64, y: i64| Position {
            x: x as i16,
            y: y as i16,
        };
        let kind = rng.pick(&[
            Layout::Room,
            Layout::Room,
            Layout::Signed,
            Layout::Far,
            Layout::Coincident,
            Layout::Collinear,
        ]);
        let (w, h) = (rng.range(300, 3_000), rng.range(300, 3_000));
        // A line along the x axis or the room's diagonal.
        let slope = rng.range(0, 1);
        for (i, q) in p.iter_mut().enumerate().take(n) {
            *q = match kind {
                Layout::Room | Layout::Coincident => match i {
                    0 => at(0, 0),
                    1 => at(w, 0),
                    2 => at(w, h),
                    3 => at(0, h),
                    _ => at(rng.range(0, w), rng.range(0, h)),
                },
                Layout::Signed => at(rng.range(-3_000, 3_000), rng.range(-3_000, 3_000)),
                Layout::Far => at(
                    rng.range(i16::MIN.into(), i16::MAX.into()),
                    rng.range(i16::MIN.into(), i16::MAX.into()),
                ),
                Layout::Collinear => {
                    let t = rng.range(0, 1_000);
                    at(t * w / 1_000, t * h / 1_000 * slope)
                }
            };
        }
        if kind == Layout::Coincident {
            let all = rng.chance(0.2);
            for i in 1..n {
                if all || rng.chance(0.4) {
                    p[i] = p[rng.below(i as u64) as usize];
                }
            }
        }
        rng.shuffle(&mut p[..n]);
        (p, kind)
    }

    /// The distance from `a` to `b`, cm.
    pub fn dist_cm(a: Position, b: [f64; 2]) -> f64 {
        (f64::from(a.x) - b[0]).hypot(f64::from(a.y) - b[1])
    }

    /// A log-distance path-loss model of RSSI bytes (−dBm): `loss_1m + 10·alpha·log10(d / 1 m)`
    /// plus Gaussian noise of `sigma` dB.
    #[derive(Clone, Copy, Debug)]
    pub struct PathLoss {
        /// The byte at 1 m (−P0).
        pub loss_1m: f64,
        /// The path-loss exponent.
        pub alpha: f64,
        /// The noise, dB.
        pub sigma: f64,
    }

    impl PathLoss {
        /// A model with P0 of −20…−70 dBm, α of 1.2…5 and σ of 0, 1, 3 or 6 dB.
        pub fn draw(rng: &mut Rng) -> PathLoss {
            PathLoss {
                loss_1m: rng.range(20, 70) as f64,
                alpha: rng.range(12, 50) as f64 / 10.0,
                sigma: rng.pick(&[0.0, 1.0, 3.0, 6.0]),
            }
        }

        /// The byte heard over `d_cm` (at least 1 cm), within 1…255.
        pub fn byte(&self, rng: &mut Rng, d_cm: f64) -> u8 {
            let db = self.loss_1m
                + 10.0 * self.alpha * (d_cm.max(1.0) / 100.0).log10()
                + self.sigma * rng.normal();
            db.round().clamp(1.0, 255.0) as u8
        }
    }

    /// A frame that is no good message for a receiver, from a good one (`valid`): random bytes,
    /// cut short, one byte too long, a wrong magic, version, kind or length byte, or a header
    /// field changed (which may still decode: the tests decide with the receiver's decoder); half
    /// of them with a CRC that matches.
    pub fn garbage(rng: &mut Rng, valid: &[u8]) -> Vec<u8> {
        let mut v = valid.to_vec();
        match rng.below(8) {
            0 => {
                let n = rng.below(41) as usize;
                v = (0..n).map(|_| rng.byte()).collect();
            }
            1 => v.truncate(rng.below(v.len() as u64) as usize),
            2 => v.push(rng.byte()),
            3 if !v.is_empty() => v[0] ^= 1 + rng.below(255) as u8,
            4 if v.len() > 1 => v[1] ^= 1 + rng.below(255) as u8,
            5 if v.len() > 2 => v[2] = rng.pick(&[0, 1, 2, 3, 0xFF]),
            6 if v.len() > 3 => v[3] ^= 1 + rng.below(255) as u8,
            _ if v.len() > 4 => {
                let i = rng.range(4, (v.len() as i64 - 1).min(12)) as usize;
                let any = rng.byte();
                v[i] = rng.pick(&[0, 1, 2, 3, 5, 8, 9, 0x80, 0xFF, any]);
            }
            _ => v.push(rng.byte()),
        }
        // Half the time with the CRC made to match the edit, so that the checks behind it see
        // the edited fields.
        if rng.below(2) == 0 {
            loc_proto::msg::seal(&mut v);
        }
        v
    }
}

/// A testbed's beacons on the air around one node, drawn at random for the randomized tests of
/// the agent and anchor firmware (`tests/agent_vs_host.rs`, `tests/anchor_vs_host.rs`): every
/// anchor on one timeline, in its slots, with beacons lost, anchors dead or falling silent for a
/// while, odd RSSI and relay bytes, and frames a node must drop or take with care between them.
///
/// So that a node's reaction depends on nothing finer than the schedule (and the firmware and
/// the host logic, fed the same events, must act alike), beacons arrive at their slot times
/// (±0.3 ms) and the extra frames in the middle of a slot, away from the phase starts where a
/// node switches channel and from the report window. Frames that would move a node's timeline
/// if its time master sent them (a beacon claiming another channel of the list, repeats) come
/// only from anchors other than 1, in superframes whose beacon of anchor 1 on the first channel
/// has been delivered (or on anchor 1 itself, once it runs): anchor 1 is then every node's
/// master.
pub mod air {
    use crate::random::{self, anchor_layout, dist_cm, edge_byte, garbage, PathLoss, Rng};
    use loc_proto::config::Config;
    use loc_proto::msg::{Beacon, Position, Relay, MAX_ANCHORS};
    use loc_proto::schedule::Schedule;

    /// A packet on the air for the node.
    #[derive(Clone, Debug)]
    pub struct Air {
        /// When it is off the air (what `XBee::deliver` takes), ms.
        pub at_ms: f64,
        /// The testbed channel it is sent on.
        pub channel: u8,
        /// The level it is heard at, dBm.
        pub rssi_dbm: i16,
        /// The sender's 16-bit address.
        pub source: u16,
        /// The payload.
        pub payload: Vec<u8>,
        /// What it is.
        pub what: &'static str,
    }

    impl Air {
        /// As the node's modelled XBee receives it.
        pub fn packet(&self, pan_id: u16) -> simavr::xbee::RxPacket {
            let ch = loc_proto::xbee_channel(self.channel).expect("a testbed channel");
            simavr::xbee::RxPacket::broadcast16(
                ch,
                pan_id,
                self.source,
                self.rssi_dbm,
                &self.payload,
            )
        }

        /// The RSSI byte of its RX frame.
        pub fn rssi_byte(&self) -> u8 {
            xbee_api::Rssi::from_dbm(self.rssi_dbm).raw()
        }

        /// When its RX frame's start delimiter is through the node's UART (what the node stamps
        /// a frame with), µs.
        pub fn stamp_us(&self) -> u64 {
            let ms = self.at_ms
                + f64::from(loc_proto::schedule::RADIO_RX_LATENCY_US) / 1000.0
                + crate::UART_BYTE_MS;
            (ms * 1000.0).round() as u64
        }
    }

    /// One run's draws.
    #[derive(Clone, Debug)]
    pub struct Plan {
        /// The testbed's config (anchors, channels, slot length, PAN).
        pub config: Config,
        /// The anchors' positions (cm).
        pub layout: [Position; MAX_ANCHORS],
        /// Where the node is (cm), for the RSSI it hears.
        pub node_at: [f64; 2],
        /// The path loss it hears with.
        pub model: PathLoss,
        /// The start of the first superframe, ms.
        pub t0_ms: f64,
        /// Its sequence number.
        pub seq0: u16,
        /// Superframes on the air.
        pub superframes: u16,
        /// The chance that a beacon is lost.
        pub lost: f64,
        /// The chance of an extra frame in a slot.
        pub extra: f64,
        /// The chance that a beacon carries another sequence number than its superframe's.
        pub wrong_seq: f64,
        /// Anchors that never send (bit `id − 1`).
        pub dead: u8,
        /// Superframes (from, to) in which anchor 1 is silent.
        pub silent: (u16, u16),
        /// The anchor under test, which sends nothing here.
        pub own: Option<u8>,
    }

    impl Plan {
        /// A plan for a node run by `config` (the testbed's anchors, channels, slot and PAN),
        /// anchor `own` if it is one, whose first superframe starts at `t0_ms`.
        pub fn draw(
            rng: &mut Rng,
            config: Config,
            own: Option<u8>,
            t0_ms: f64,
            superframes: u16,
        ) -> Plan {
            let n = usize::from(config.anchors);
            let (layout, _) = anchor_layout(rng, n);
            let node_at = match own {
                Some(a) => [
                    layout[usize::from(a) - 1].x.into(),
                    layout[usize::from(a) - 1].y.into(),
                ],
                None => {
                    let p = layout[rng.below(n as u64) as usize];
                    [
                        f64::from(p.x) + rng.range(-500, 500) as f64,
                        f64::from(p.y) + rng.range(-500, 500) as f64,
                    ]
                }
            };
            // Dead anchors: none mostly; never all of them, never the one under test.
            let mut dead = 0u8;
            if rng.chance(0.3) {
                for a in 1..=config.anchors {
                    if Some(a) != own && rng.chance(0.3) {
                        dead |= 1 << (a - 1);
                    }
                }
            }
            let alive =
                (1..=config.anchors).filter(|&a| Some(a) != own && dead & (1 << (a - 1)) == 0);
            if alive.count() == 0 {
                dead = 0;
            }
            // Anchor 1 silent for a while (a takeover and a hand-back) in some runs, never in
            // the first superframes (where the node syncs).
            let silent = if rng.chance(0.3) {
                let from = rng.range(3, i64::from(superframes) / 2) as u16;
                (from, from + rng.range(1, 8) as u16)
            } else {
                (0, 0)
            };
            Plan {
                config,
                layout,
                node_at,
                model: PathLoss::draw(rng),
                t0_ms,
                seq0: if rng.chance(0.3) {
                    0xFFFF - rng.below(4) as u16
                } else {
                    rng.u64() as u16
                },
                superframes,
                lost: rng.pick(&[0.0, 0.05, 0.2, 0.5]),
                extra: rng.pick(&[0.0, 0.1, 0.3]),
                wrong_seq: rng.pick(&[0.0, 0.0, 0.02]),
                dead,
                silent,
                own,
            }
        }

        /// The schedule.
        pub fn schedule(&self) -> Schedule {
            Schedule::for_config(&self.config).expect("a valid config")
        }

        /// The superframe's length, ms.
        pub fn superframe_ms(&self) -> f64 {
            f64::from(self.schedule().superframe_us()) / 1000.0
        }

        /// The end of the last superframe, ms.
        pub fn end_ms(&self) -> f64 {
            self.t0_ms + f64::from(self.superframes) * self.superframe_ms()
        }

        fn sends(&self, a: u8, k: u16) -> bool {
            Some(a) != self.own
                && self.dead & (1 << (a - 1)) == 0
                && !(a == 1 && (self.silent.0..self.silent.1).contains(&k))
        }

        /// A relay row of anchor `a` (`n` bytes, its own 0).
        fn relay(&self, rng: &mut Rng, a: u8, n: usize) -> Relay {
            let mut r = [0; MAX_ANCHORS];
            let me = self.layout[usize::from(a) - 1];
            for (j, b) in r.iter_mut().enumerate().take(n) {
                if j + 1 == usize::from(a) || rng.chance(0.15) {
                    continue;
                }
                let p = self.layout[j];
                *b = if rng.chance(0.05) {
                    edge_byte(rng)
                } else {
                    self.model.byte(rng, dist_cm(me, [p.x.into(), p.y.into()]))
                };
            }
            Relay::from_slice(&r[..n.min(MAX_ANCHORS)]).unwrap_or_default()
        }

        /// The level the node hears anchor `a` at, dBm: from the model, sometimes at or past
        /// the edges of the RSSI byte.
        fn level(&self, rng: &mut Rng, a: u8) -> i16 {
            if rng.chance(0.05) {
                return rng.pick(&[3, 0, -1, -2, -254, -255, -256, -300]);
            }
            -i16::from(
                self.model
                    .byte(rng, dist_cm(self.layout[usize::from(a) - 1], self.node_at)),
            )
        }

        /// Everything on the air, in time order.
        pub fn air(&self, rng: &mut Rng) -> Vec<Air> {
            let s = self.schedule();
            let n = self.config.anchors;
            let list = self.config.channels;
            let guard_ms = f64::from(s.guard_us()) / 1000.0;
            let mut out = Vec::new();
            // The first beacon of the run: the first live anchor's, on the first channel.
            let first = (1..=n).find(|&a| self.sends(a, 0)).expect("a live anchor");
            for k in 0..self.superframes {
                let sf_start = self.t0_ms + f64::from(k) * self.superframe_ms();
                let seq = self.seq0.wrapping_add(k);
                // Anchor 1 under test is its own master once it runs (from its first superframe's
                // beacon on).
                let mut master_heard = self.own == Some(1) && k > 0;
                for c in 0..s.channels() {
                    let channel = list.as_slice()[usize::from(c)];
                    for a in 1..=n {
                        let slot_start = sf_start
                            + f64::from(s.beacon_at_us(c, a).expect("a slot")) / 1000.0
                            - guard_ms;
                        let sure = k == 0 && c == 0 && a == first;
                        if self.sends(a, k) && (sure || !rng.chance(self.lost)) {
                            let mut b = Beacon {
                                anchor: a,
                                seq: if !sure && rng.chance(self.wrong_seq) {
                                    rng.u64() as u16
                                } else {
                                    seq
                                },
                                channel,
                                position: self.layout[usize::from(a) - 1],
                                relay: self.relay(rng, a, n.into()),
                            };
                            if rng.chance(0.02) {
                                b.position = anchor_layout(rng, 1).0[0];
                            }
                            let payload = encode(&b);
                            let tx = slot_start + guard_ms + rng.range(-300, 300) as f64 / 1000.0;
                            out.push(Air {
                                at_ms: crate::rx_frame_delivery(tx, payload.len()),
                                channel,
                                rssi_dbm: self.level(rng, a),
                                source: loc_proto::Role::Anchor.address(a),
                                payload,
                                what: "beacon",
                            });
                            master_heard |= a == 1 && c == 0;
                        }
                        if Some(a) == self.own || !rng.chance(self.extra) {
                            continue;
                        }
                        let at_ms =
                            slot_start + guard_ms + 13.0 + rng.range(0, 4_000) as f64 / 1000.0;
                        let from = rng.range(2, i64::from(n)) as u8;
                        let (payload, what) = self.extra_frame(rng, seq, c, from, master_heard);
                        out.push(Air {
                            at_ms,
                            channel,
                            rssi_dbm: self.level(rng, from),
                            source: loc_proto::Role::Anchor.address(from),
                            payload,
                            what,
                        });
                    }
                }
            }
            out.sort_by(|x, y| x.at_ms.total_cmp(&y.at_ms));
            out
        }

        /// An extra frame in a slot of channel index `c` of superframe `seq`: one a node drops
        /// (garbage; a beacon of an anchor the testbed does not have, or of the node itself; a
        /// beacon on a channel not in the list) or, if anchor 1 is the master
        /// (`master_heard`), a beacon of anchor `from` (2…N) claiming another channel of the
        /// list or repeating itself with other bytes.
        fn extra_frame(
            &self,
            rng: &mut Rng,
            seq: u16,
            c: u8,
            from: u8,
            master_heard: bool,
        ) -> (Vec<u8>, &'static str) {
            let n = self.config.anchors;
            let list = self.config.channels;
            let mut b = Beacon {
                anchor: from,
                seq,
                channel: list.as_slice()[usize::from(c)],
                position: self.layout[usize::from(from) - 1],
                relay: self.relay(rng, from, n.into()),
            };
            let kinds: &[u8] = if master_heard {
                &[0, 1, 2, 3, 4]
            } else {
                &[0, 1, 2]
            };
            match rng.pick(kinds) {
                0 => loop {
                    let g = garbage(rng, &encode(&b));
                    if Beacon::decode(&g).is_err() && g.len() <= 40 {
                        break (g, "garbage");
                    }
                },
                1 => {
                    b.anchor = match self.own {
                        Some(own) if rng.chance(0.5) => own,
                        _ if n < 8 => rng.range(i64::from(n) + 1, 8) as u8,
                        _ => return (encode_unchecked_anchor(&b), "beacon of anchor 9"),
                    };
                    b.relay.iter_mut().for_each(|v| *v = 0);
                    (
                        encode(&b),
                        "beacon of another testbed's anchor or the node's own id",
                    )
                }
                2 => {
                    let off: Vec<u8> = (1..=16)
                        .filter(|ch| !list.as_slice().contains(ch))
                        .collect();
                    b.channel = rng.pick(&off);
                    (encode(&b), "beacon claiming a channel not in the list")
                }
                3 if list.len() > 1 => {
                    let others: Vec<u8> = list
                        .as_slice()
                        .iter()
                        .copied()
                        .filter(|&ch| ch != b.channel)
                        .collect();
                    b.channel = rng.pick(&others);
                    (encode(&b), "beacon claiming another channel of the list")
                }
                _ => {
                    let count = rng.range(0, 8) as usize;
                    b.relay = Relay::from_slice(&[0; MAX_ANCHORS][..count]).unwrap_or_default();
                    for j in 0..count {
                        if j + 1 != usize::from(from) {
                            b.relay[j] = if rng.chance(0.3) {
                                0
                            } else {
                                random::edge_byte(rng).max(rng.byte())
                            };
                        }
                    }
                    (encode(&b), "beacon repeated with other bytes")
                }
            }
        }
    }

    fn encode(b: &Beacon) -> Vec<u8> {
        let mut buf = [0; Beacon::MAX_LEN];
        let n = b
            .encode(&mut buf)
            .unwrap_or_else(|e| panic!("{e:?}: {b:?}"));
        buf[..n].to_vec()
    }

    /// `b`'s bytes with anchor id 9 (no encoder writes it).
    fn encode_unchecked_anchor(b: &Beacon) -> Vec<u8> {
        let mut v = encode(b);
        v[4] = 9;
        v
    }
}
