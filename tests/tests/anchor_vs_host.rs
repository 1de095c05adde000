//! The anchor firmware in simavr against the host's `anchor_fw::Anchor`, on random testbeds: the
//! beacons it puts on the air (with the RSSI it relays) must equal, byte for byte and in order,
//! the beacons the host's anchor logic makes from the same beacons of the other anchors at the
//! same times, and it must tune its radio to the same channels in the same order around them.
//!
//! What it is for: the anchor's relay bookkeeping (which anchor's RSSI goes in which byte, per
//! channel, one superframe later) and the beacon's encoding are compiled by LLVM's AVR backend,
//! which has miscompiled this project's code before; such a bug leaves the host's results alone.
//!
//! Every N = 3…8 anchors × C = 1…4 channels, configured through a config in the anchor's EEPROM
//! (a random id of 1…N at a random position, channel list and slot length), runs twice, each
//! time 16 superframes of a random testbed (`hoploc_tests::air`) around it, as in the agent's test —
//! beacons lost, anchors dead or falling silent (anchor 1's silence hands the timeline to the
//! next, maybe to this one), RSSI at and past the edges of the byte, beacons with another
//! sequence number or position, garbage, beacons with its own id or of anchors the testbed does
//! not have, on channels not in the list or claiming another channel of the list, and repeats.
//!
//! Seeded: the seed is printed, and `HOPLOC_TEST_SEED` reruns another (or a failing) one.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use anchor_fw::{Action, Anchor, Heard};
use hoploc_tests::air::{Air, Plan};
use hoploc_tests::boot_configured;
use hoploc_tests::random::{self, Rng};
use loc_proto::config::Config;
use loc_proto::msg::Beacon;
use loc_proto::schedule::{beacon_latency_us, Schedule};
use loc_proto::{xbee_channel, Role};
use simavr::ms_to_cycles;

/// The default seed (override with `HOPLOC_TEST_SEED`).
const SEED: u64 = 0xA1C4_F00D_2026_1127;
/// Runs per anchors × channels.
const RUNS_PER_CLASS: usize = 2;
/// Superframes per run.
const SUPERFRAMES: u16 = 16;

/// What an anchor does with its radio.
#[derive(Clone, Debug, PartialEq)]
enum Event {
    /// Tune to this testbed channel.
    Tune(u8),
    /// Broadcast this beacon.
    Beacon(Vec<u8>),
}

/// The host's anchor, which the firmware must equal: `anchor_fw::Anchor` with the shell of
/// anchor-fw's `main.rs` around it (tune, build, encode and send the beacon, decode beacons and
/// map their channel), on the radio's channel as it tunes it.
struct HostAnchor {
    anchor: Anchor,
    config: Config,
    now_us: u64,
    /// The testbed channel the radio is on.
    tuned: Option<u8>,
    out: Vec<Event>,
}

impl HostAnchor {
    fn new(config: Config, now_us: u64) -> HostAnchor {
        let sched = Schedule::for_config(&config).expect("a valid config");
        let latency = beacon_latency_us(config.anchors);
        HostAnchor {
            anchor: Anchor::new(config.id, sched, latency, now_us as u32),
            config,
            now_us,
            tuned: None,
            out: Vec::new(),
        }
    }

    fn act(&mut self, action: Action) {
        let channels = self.config.channels;
        match action {
            Action::SetChannel(c) => {
                if let Some(&n) = channels.as_slice().get(usize::from(c)) {
                    self.tuned = Some(n);
                    self.out.push(Event::Tune(n));
                }
            }
            Action::SendBeacon { seq, channel } => {
                let b = self
                    .anchor
                    .beacon(seq, channel, &channels, self.config.position);
                let mut buf = [0u8; Beacon::MAX_LEN];
                if let Ok(n) = b.encode(&mut buf) {
                    self.out.push(Event::Beacon(buf[..n].to_vec()));
                }
            }
        }
    }

    /// Runs the anchor's timers up to `until_us`.
    fn advance(&mut self, until_us: u64) {
        for _ in 0..100_000 {
            let next = self.now_us + u64::from(self.anchor.wait_us(self.now_us as u32));
            if next > until_us {
                self.now_us = until_us;
                return;
            }
            self.now_us = next;
            while let Some(a) = self.anchor.poll(self.now_us as u32) {
                self.act(a);
            }
        }
        panic!("the host anchor does not get past {} µs", self.now_us);
    }

    /// A packet on the air: what the radio passes on if it is on that channel.
    fn air(&mut self, a: &Air) {
        let at = a.stamp_us();
        self.advance(at);
        if self.tuned != Some(a.channel) {
            return;
        }
        let Ok(b) = Beacon::decode(&a.payload) else {
            return;
        };
        let list = self.config.channels;
        if let Some(c) = list.as_slice().iter().position(|&c| c == b.channel) {
            self.anchor.on_beacon(Heard {
                from: b.anchor,
                seq: b.seq,
                channel: c as u8,
                rssi: a.rssi_byte().max(1),
                at_us: at as u32,
            });
        }
    }
}

/// The host anchor's doings for `air`, booted at `up_ms`, up to `stop_ms`.
fn host(config: Config, up_ms: f64, air: &[Air], stop_ms: f64) -> Vec<Event> {
    let mut h = HostAnchor::new(config, (up_ms * 1000.0) as u64);
    h.advance((up_ms * 1000.0) as u64);
    for a in air {
        h.air(a);
    }
    h.advance((stop_ms * 1000.0) as u64);
    h.out
}

/// One run: the firmware's doings and the host's.
struct Run {
    class: (u8, u8),
    seed: u64,
    plan: Plan,
    air: Vec<Air>,
    firmware: Vec<Event>,
    host: Vec<Event>,
}

impl Run {
    fn beacons(&self) -> impl Iterator<Item = Beacon> + '_ {
        self.firmware.iter().filter_map(|e| match e {
            Event::Beacon(b) => Beacon::decode(b).ok(),
            _ => None,
        })
    }
}

fn run(n: u8, c: u8, seed: u64) -> Run {
    let mut rng = Rng::new(seed);
    let own = rng.range(1, i64::from(n)) as u8;
    let config = Config {
        role: Role::Anchor,
        id: own,
        anchors: n,
        slot_ms: rng.range(35, 45) as u16,
        channels: random::channels(&mut rng, c.into()),
        ..Config::DEFAULT
    };
    // The plan first (it places the anchors, this one too), its start once the node is up.
    let mut plan = Plan::draw(&mut rng, config, Some(own), 0.0, SUPERFRAMES);
    plan.config.position = plan.layout[usize::from(own) - 1];
    let config = plan.config;
    let (mut avr, mut radio, up) = boot_configured(Role::Anchor, Some(&config));
    plan.t0_ms = up + 20.0 + plan.superframe_ms() * rng.unit();
    let air = plan.air(&mut rng);
    // Each packet handed to the radio shortly before it is due (the model's queue is scanned at
    // every step of the simulation: keeping it short keeps the run fast).
    for a in &air {
        radio.run_until(&mut avr, ms_to_cycles(a.at_ms - 1.0));
        radio.deliver(a.packet(config.pan_id), ms_to_cycles(a.at_ms));
    }
    // Up to just before the next superframe: its first tune is not compared.
    let stop = plan.end_ms() - 1.0;
    radio.run_until(&mut avr, ms_to_cycles(stop));
    let mut firmware = Vec::new();
    for f in radio.frames_from_firmware().iter().filter(|f| f.ms() > up) {
        match f.data.as_slice() {
            [0x08, _, b'C', b'H', ch] => firmware.push(Event::Tune(testbed_channel(*ch))),
            [0x01, _, 0xFF, 0xFF, _, payload @ ..] => {
                firmware.push(Event::Beacon(payload.to_vec()))
            }
            [0x01, ..] => panic!("not a broadcast: {f}"),
            _ => {}
        }
    }
    let host = host(config, up, &air, stop);
    Run {
        class: (n, c),
        seed,
        plan,
        air,
        firmware,
        host,
    }
}

/// The testbed channel of XBee channel `ch` (0 if none).
fn testbed_channel(ch: u8) -> u8 {
    (1..=16).find(|&n| xbee_channel(n) == Some(ch)).unwrap_or(0)
}

/// Where the firmware first did otherwise than the host, or `None`.
fn compare(r: &Run) -> Option<String> {
    let (f, h) = (&r.firmware, &r.host);
    let k = (0..f.len().max(h.len())).find(|&k| f.get(k) != h.get(k))?;
    let shown = |e: Option<&Event>| match e {
        Some(Event::Beacon(b)) => match Beacon::decode(b) {
            Ok(b) => format!("{b:?}"),
            Err(e) => format!("{b:02x?} ({e:?})"),
        },
        other => format!("{other:?}"),
    };
    Some(format!(
        "event {k} of {} (host: {}): expected {}\n    got {}",
        f.len(),
        h.len(),
        shown(h.get(k)),
        shown(f.get(k))
    ))
}

#[test]
fn the_anchor_firmware_beacons_what_the_host_anchor_makes_of_random_beacons() {
    let wall = Instant::now();
    let seed = random::seed(SEED);
    let mut rng = Rng::new(seed);
    let mut jobs = Vec::new();
    for n in 3..=8u8 {
        for c in 1..=4u8 {
            for _ in 0..RUNS_PER_CLASS {
                jobs.push((n, c, rng.u64()));
            }
        }
    }
    // Two runs at a time (the machines this runs on have two cores or more).
    let next = AtomicUsize::new(0);
    let done = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(&(n, c, seed)) = jobs.get(k) else {
                    break;
                };
                let r = run(n, c, seed);
                done.lock().unwrap().push((k, r));
            });
        }
    });
    let mut runs = done.into_inner().unwrap();
    runs.sort_by_key(|(k, _)| *k);
    let mut failures = String::new();
    let mut failed = 0;
    let (mut beacons, mut relayed) = (0, 0);
    for (_, r) in &runs {
        let (b, heard) = r.beacons().fold((0, 0), |(b, h), x| {
            (b + 1, h + x.relay.iter().filter(|&&v| v != 0).count())
        });
        beacons += b;
        relayed += heard;
        println!(
            "anchor {} of {}×{}: {b} beacons, {heard} RSSI bytes relayed, {} packets on the air",
            r.plan.config.id,
            r.class.0,
            r.class.1,
            r.air.len()
        );
        if let Some(why) = compare(r) {
            failed += 1;
            if failed <= 3 {
                let _ = write!(
                    failures,
                    "\nanchor {} of {}×{}, run seed {:#x}: {why}\n  plan: {:?}\n",
                    r.plan.config.id, r.class.0, r.class.1, r.seed, r.plan
                );
            }
        }
    }
    println!(
        "anchor: HOPLOC_TEST_SEED={seed:#x}, {} runs of {SUPERFRAMES} superframes in {:.1} s: {beacons} beacons, {relayed} RSSI bytes relayed",
        runs.len(),
        wall.elapsed().as_secs_f64()
    );
    assert!(
        failed == 0,
        "{failed} of {} runs differ (HOPLOC_TEST_SEED={seed:#x}):{failures}",
        runs.len()
    );
    let mut per_class: BTreeMap<(u8, u8), usize> = BTreeMap::new();
    for (_, r) in &runs {
        *per_class.entry(r.class).or_default() += r.beacons().count();
    }
    assert!(
        per_class.values().all(|&b| b >= 20),
        "beacons per class: {per_class:?}"
    );
    assert!(
        relayed >= beacons,
        "{relayed} RSSI bytes in {beacons} beacons"
    );
}
