//! The agent firmware in simavr against the host's `agent_fw::Agent`, on random testbeds: the
//! reports it sends to the sink must equal, byte for byte and in order, the reports the host's
//! agent logic makes from the same beacons at the same times, and it must tune its radio to the
//! same channels in the same order.
//!
//! What it is for: the agent's report assembly (which anchor's bytes go in which slot of the
//! report, the relay rows, the report's encoding) is compiled by LLVM's AVR backend, which has
//! miscompiled this project's code before; such a bug leaves the host's results alone.
//!
//! Every N = 3…8 anchors × C = 1…4 channels, configured through a config in the agent's EEPROM
//! (agent 1 or 2, random channel lists, sink channel and slot length), runs twice, each time 20
//! superframes of a random testbed (`hoploc_tests::air`): anchors anywhere, beacons lost,
//! anchors dead or falling silent (another one is then the time master), RSSI at and past the
//! edges of the byte, relay bytes missing or at the edges, beacons with another sequence number
//! or position, and between them garbage, beacons of anchors the testbed does not have, on
//! channels not in the list, claiming another channel of the list, and repeats with other
//! relay bytes. Where the relay matrix does not fit the 100-byte radio payload (5 anchors × 3–4
//! channels, 6 and 7 anchors × 2–4, 8 anchors × 1–4), every report carries a window of its rows,
//! a different one in each superframe: every class sends a report every superframe.
//!
//! Seeded: the seed is printed, and `HOPLOC_TEST_SEED` reruns another (or a failing) one.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use agent_fw::{Action, Agent, Heard, Tune};
use hoploc_tests::air::{Air, Plan};
use hoploc_tests::boot_configured;
use hoploc_tests::random::{self, Rng};
use loc_proto::config::Config;
use loc_proto::msg::{Beacon, Report, MAX_PAYLOAD};
use loc_proto::schedule::{beacon_latency_us, Schedule};
use loc_proto::{xbee_channel, Role};
use simavr::ms_to_cycles;

/// The default seed (override with `HOPLOC_TEST_SEED`).
const SEED: u64 = 0xA6E7_F00D_2026_1127;
/// Runs per anchors × channels, and superframes per run.
const RUNS: usize = 2;
const SUPERFRAMES: u16 = 20;

/// The host's agent, which the firmware must equal: `agent_fw::Agent` with the shell of
/// agent-fw's `main.rs` around it (tune, encode and send the report, decode beacons and map
/// their channel, the TX status), on the radio's channel as it tunes it.
struct HostAgent {
    agent: Agent,
    config: Config,
    now_us: u64,
    /// The testbed channel the radio is on.
    tuned: Option<u8>,
    /// When the TX status of the report in flight comes back, µs.
    tx_status_us: Option<u64>,
    out: Vec<Event>,
}

impl HostAgent {
    fn new(config: Config, now_us: u64) -> HostAgent {
        let sched = Schedule::for_config(&config).expect("a valid config");
        let latency = beacon_latency_us(config.anchors);
        HostAgent {
            agent: Agent::new(config.id, sched, config.channels, latency, now_us as u32),
            config,
            now_us,
            tuned: None,
            tx_status_us: None,
            out: Vec::new(),
        }
    }

    fn act(&mut self, action: Action) {
        match action {
            Action::Tune(Tune::List(c)) => {
                if let Some(&n) = self.config.channels.as_slice().get(usize::from(c)) {
                    self.tune(n);
                }
            }
            Action::Tune(Tune::Sink) => self.tune(self.config.sink_channel),
            Action::SendReport { .. } => {
                let mut buf = [0u8; MAX_PAYLOAD];
                if let Ok(n) = self.agent.report().encode(&mut buf) {
                    self.out.push(Event::Report(buf[..n].to_vec()));
                    // The TX16 frame over the UART, the packet on air, the status back.
                    let ms = (10 + n) as f64 * hoploc_tests::UART_BYTE_MS
                        + simavr::xbee::time_on_air_ms(n)
                        + 2.0;
                    self.tx_status_us = Some(self.now_us + (ms * 1000.0) as u64);
                }
            }
        }
    }

    fn tune(&mut self, n: u8) {
        self.tuned = Some(n);
        self.out.push(Event::Tune(n));
    }

    /// Runs the agent's timers up to `until_us`.
    fn advance(&mut self, until_us: u64) {
        for _ in 0..100_000 {
            let wait = self.agent.wait_us(self.now_us as u32);
            let mut next = if wait == u32::MAX {
                u64::MAX
            } else {
                self.now_us + u64::from(wait)
            };
            if let Some(t) = self.tx_status_us {
                next = next.min(t);
            }
            if next > until_us {
                self.now_us = until_us;
                return;
            }
            self.now_us = next;
            if self.tx_status_us.is_some_and(|t| t <= next) {
                self.tx_status_us = None;
                if let Some(a) = self.agent.on_tx_status(true) {
                    self.act(a);
                }
            }
            while let Some(a) = self.agent.poll(self.now_us as u32) {
                self.act(a);
            }
        }
        panic!("the host agent does not get past {} µs", self.now_us);
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
            self.agent.on_beacon(Heard {
                from: b.anchor,
                seq: b.seq,
                channel: c as u8,
                rssi: a.rssi_byte().max(1),
                at_us: at as u32,
                pos: [b.position.x, b.position.y],
                relay: &b.relay,
            });
        }
    }
}

/// What an agent does with its radio.
#[derive(Clone, Debug, PartialEq)]
enum Event {
    /// Tune to this testbed channel.
    Tune(u8),
    /// Send this report to the sink.
    Report(Vec<u8>),
}

/// The host agent's doings for `air`, booted at `up_ms`, up to `stop_ms`.
fn host(config: Config, up_ms: f64, air: &[Air], stop_ms: f64) -> Vec<Event> {
    let mut h = HostAgent::new(config, (up_ms * 1000.0) as u64);
    h.advance((up_ms * 1000.0) as u64);
    for a in air {
        h.air(a);
    }
    h.advance((stop_ms * 1000.0) as u64);
    h.out
}

/// One run: the firmware's output and the host's.
struct Run {
    class: (u8, u8),
    seed: u64,
    plan: Plan,
    air: Vec<Air>,
    firmware: Vec<Event>,
    host: Vec<Event>,
}

impl Run {
    fn reports(&self) -> impl Iterator<Item = Report> + '_ {
        self.firmware.iter().filter_map(|e| match e {
            Event::Report(r) => Report::decode(r).ok(),
            _ => None,
        })
    }
}

/// The RSSI and relay bytes a report says were heard (not 0).
fn heard(r: &Report) -> (usize, usize) {
    let (n, c) = (usize::from(r.anchors), r.channels.len());
    let rssi = r.rssi[..c]
        .iter()
        .flat_map(|row| &row[..n])
        .filter(|&&b| b != 0)
        .count();
    let relay = r.relay[..c]
        .iter()
        .flat_map(|m| m[..n].iter().flat_map(|row| &row[..n]))
        .filter(|&&b| b != 0)
        .count();
    (rssi, relay)
}

fn run(n: u8, c: u8, superframes: u16, seed: u64) -> Run {
    let mut rng = Rng::new(seed);
    let mut sink_channel = rng.range(1, 16) as u8;
    let channels = random::channels(&mut rng, c.into());
    while channels.as_slice().contains(&sink_channel) {
        sink_channel = rng.range(1, 16) as u8;
    }
    let config = Config {
        role: Role::Agent,
        id: rng.range(1, 2) as u8,
        anchors: n,
        slot_ms: rng.range(35, 60) as u16,
        channels,
        sink_channel,
        ..Config::DEFAULT
    };
    let (mut avr, mut radio, up) = boot_configured(Role::Agent, Some(&config));
    let sf = f64::from(Schedule::for_config(&config).unwrap().superframe_us()) / 1000.0;
    let t0 = up + 20.0 + sf * rng.unit();
    let plan = Plan::draw(&mut rng, config, None, t0, superframes);
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
    let sink = Role::Sink.address(1).to_be_bytes();
    let mut firmware = Vec::new();
    for f in radio.frames_from_firmware().iter().filter(|f| f.ms() > up) {
        match f.data.as_slice() {
            [0x08, _, b'C', b'H', ch] => firmware.push(Event::Tune(testbed_channel(*ch))),
            [0x01, _, d0, d1, _, payload @ ..] => {
                assert_eq!([*d0, *d1], sink, "a report to the sink: {f}");
                firmware.push(Event::Report(payload.to_vec()));
            }
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

/// What differs between two reports' payloads.
fn diff(want: &[u8], got: &[u8]) -> String {
    let (Ok(w), Ok(g)) = (Report::decode(want), Report::decode(got)) else {
        return format!("expected {want:02x?}\n    got {got:02x?}");
    };
    let mut d = Vec::new();
    if (w.agent, w.seq, w.anchors, w.channels, w.has_relay)
        != (g.agent, g.seq, g.anchors, g.channels, g.has_relay)
    {
        d.push(format!(
            "header: expected agent {} seq {} N {} channels {:?} relay {}, got agent {} seq {} N {} channels {:?} relay {}",
            w.agent, w.seq, w.anchors, w.channels.as_slice(), w.has_relay,
            g.agent, g.seq, g.anchors, g.channels.as_slice(), g.has_relay
        ));
    }
    for i in 0..8 {
        if w.positions[i] != g.positions[i] {
            d.push(format!(
                "position of anchor {}: expected {:?}, got {:?}",
                i + 1,
                w.positions[i],
                g.positions[i]
            ));
        }
        for c in 0..4 {
            if w.rssi[c][i] != g.rssi[c][i] {
                d.push(format!(
                    "RSSI of anchor {} on channel index {c}: expected {}, got {}",
                    i + 1,
                    w.rssi[c][i],
                    g.rssi[c][i]
                ));
            }
            for j in 0..8 {
                if w.relay[c][i][j] != g.relay[c][i][j] {
                    d.push(format!(
                        "relay of anchor {} about {} on channel index {c}: expected {}, got {}",
                        i + 1,
                        j + 1,
                        w.relay[c][i][j],
                        g.relay[c][i][j]
                    ));
                }
            }
        }
    }
    d.truncate(12);
    d.join("\n    ")
}

/// Where the firmware first did otherwise than the host, or `None`.
fn compare(r: &Run) -> Option<String> {
    let (f, h) = (&r.firmware, &r.host);
    let k = (0..f.len().max(h.len())).find(|&k| f.get(k) != h.get(k))?;
    let nth = h[..k.min(h.len())]
        .iter()
        .filter(|e| matches!(e, Event::Report(_)))
        .count();
    let what = match (h.get(k), f.get(k)) {
        (Some(Event::Report(w)), Some(Event::Report(g))) => {
            format!("report {nth} differs:\n    {}", diff(w, g))
        }
        (want, got) => format!("expected {want:02x?}, got {got:02x?}"),
    };
    Some(format!(
        "event {k} of {} (host: {}), after {nth} reports: {what}",
        f.len(),
        h.len()
    ))
}

#[test]
fn the_agent_firmware_reports_what_the_host_agent_makes_of_random_beacons() {
    let wall = Instant::now();
    let seed = random::seed(SEED);
    let mut rng = Rng::new(seed);
    let mut jobs = Vec::new();
    for n in 3..=8u8 {
        for c in 1..=4u8 {
            for _ in 0..RUNS {
                jobs.push((n, c, SUPERFRAMES, rng.u64()));
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
                let Some(&(n, c, superframes, seed)) = jobs.get(k) else {
                    break;
                };
                let r = run(n, c, superframes, seed);
                done.lock().unwrap().push((k, r));
            });
        }
    });
    let mut runs = done.into_inner().unwrap();
    runs.sort_by_key(|(k, _)| *k);
    // Per class: reports, RSSI bytes heard in them, relay bytes heard, tunes, packets on the air.
    let mut per_class: BTreeMap<(u8, u8), [usize; 5]> = BTreeMap::new();
    let mut failures = String::new();
    let mut failed = 0;
    for (_, r) in &runs {
        let e = per_class.entry(r.class).or_default();
        let mut reports = 0;
        for rep in r.reports() {
            let (rssi, relay) = heard(&rep);
            reports += 1;
            e[1] += rssi;
            e[2] += relay;
        }
        e[0] += reports;
        e[3] += r.firmware.len() - reports;
        e[4] += r.air.len();
        if let Some(why) = compare(r) {
            failed += 1;
            if failed <= 3 {
                let _ = write!(
                    failures,
                    "\n{}×{} run seed {:#x}: {why}  plan: {:?}\n",
                    r.class.0, r.class.1, r.seed, r.plan
                );
            }
        }
    }
    println!(
        "agent: HOPLOC_TEST_SEED={seed:#x}, {} runs in {:.1} s",
        runs.len(),
        wall.elapsed().as_secs_f64()
    );
    for ((n, c), [reports, rssi, relay, tunes, air]) in &per_class {
        let size = Report::max_size((*n).into(), (*c).into());
        println!(
            "agent {n}×{c}: {reports} reports of up to {size} bytes ({rssi} RSSI and {relay} relay \
             bytes heard), {tunes} tunes, {air} packets on the air"
        );
    }
    assert!(
        failed == 0,
        "{failed} of {} runs differ (HOPLOC_TEST_SEED={seed:#x}):{failures}",
        runs.len()
    );
    // Every class was compared on many reports, with bytes heard in them.
    assert_eq!(per_class.len(), 24);
    for ((n, c), [reports, rssi, relay, ..]) in &per_class {
        assert!(
            *reports >= 30 && *rssi >= *reports && *relay >= *reports,
            "{n}×{c}: {reports} reports, {rssi} RSSI bytes, {relay} relay bytes"
        );
    }
}
