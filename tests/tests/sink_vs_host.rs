//! The sink firmware in simavr against the host's `sink_fw::Sink`, on thousands of random
//! reports: everything the firmware writes on its UART once it runs — each report's `report`
//! line, its two `fix` lines or its `nofix` line, and the `status` lines — must equal, byte for
//! byte, the lines the host's sink computes from the same frames in the same order.
//!
//! What it is for: the sink's estimator and report path are compiled by LLVM's AVR backend,
//! which has miscompiled this code before (a copy loop that moved anchor slots, corrupting only
//! reports with many anchors). Such a bug leaves the host's results alone, so any report class
//! the firmware computes differently shows up here as a differing line.
//!
//! The reports cover every class of N = 3…8 anchors × C = 1…4 channels × relay rows or none,
//! the same number of reports per class, each made to fit the 100-byte radio payload as an
//! agent makes it (`Report::fit_relay`: where the relay matrix does not fit, a window of its
//! rows, a different one for each sequence number). Within a class: random
//! channel lists; anchor layouts in a room, around the origin (negative coordinates), across
//! the whole `i16` plane, coincident or collinear; RSSI bytes from a path-loss model (P0, α
//! and noise drawn per run and sometimes per report) or random, or at the edges (1, 255 and
//! their neighbours); anchors and channels missing (0 bytes), single bytes missing; agents 1…255
//! (the sink tracks 1…16) with sequence numbers in order, with gaps, repeated, late, random and
//! wrapping. A few frames are garbage (cut, too long, wrong magic, version, kind, length or
//! header field), which the sink only counts.
//!
//! Two sinks run: one with the built-in config (its room is each report's anchors' bounding
//! box) and one with a config in EEPROM that gives a room (and another sink channel and id).
//!
//! Pacing: each frame is delivered once the lines of the one before are out, so the sink never
//! drops one. No frame is delivered within 300 ms before a status line is due (every 10 s from
//! the first) or 30 ms after, so each status line counts exactly the frames delivered before it.
//!
//! Seeded: the seed is printed, and `HOPLOC_TEST_SEED` reruns another (or a failing) one. A
//! failure names the first differing reports (class, agent, sequence, bytes, expected and
//! written lines) and the count of differing reports per class.

use std::collections::{BTreeMap, HashMap};
use std::fmt;
use std::time::Instant;

use hoploc_tests::boot_configured;
use hoploc_tests::random::{self, anchor_layout, dist_cm, edge_byte, garbage, PathLoss, Rng};
use loc_proto::config::Config;
use loc_proto::msg::{Position, Report, ReportView, MAX_PAYLOAD};
use loc_proto::sink_line::RawReport;
use loc_proto::{xbee_channel, Role};
use simavr::xbee::{Address, RxPacket, XBee};
use simavr::{ms_to_cycles, Avr};

/// The default seed (override with `HOPLOC_TEST_SEED`).
const SEED: u64 = 0x51CE_F00D_2026_1127;
/// Reports per sink, spread evenly over the classes that can be sent.
const REPORTS: usize = 48 * 40;
/// One frame in this many is garbage.
const GARBAGE_ONE_IN: u64 = 25;
/// The sink's status period, ms.
const STATUS_MS: f64 = 10_000.0;
/// No frame is delivered this long before a status line is due, ms (more than a report takes).
const QUIET_BEFORE_STATUS_MS: f64 = 300.0;
/// … nor this long after, ms (the status line is out by then).
const QUIET_AFTER_STATUS_MS: f64 = 30.0;
/// How long a frame's lines may take, ms.
const LINES_DEADLINE_MS: f64 = 1_000.0;

/// The host's sink, which the firmware must equal. Everything that uses `sink_fw::Sink`'s API is
/// in this impl.
struct HostSink(sink_fw::Sink);

impl HostSink {
    /// The sink of a node whose config position is `position` (its room, or none).
    fn new(position: Position) -> HostSink {
        HostSink(sink_fw::Sink::new(sink_fw::room(position)))
    }

    /// The lines the sink writes for a frame it received: a report's `report` line and its
    /// `fix` lines or `nofix` line; none for a frame that is no report (it is only counted).
    fn frame(&mut self, payload: &[u8]) -> Vec<Vec<u8>> {
        let view = match ReportView::accept(payload) {
            Ok(view) => view,
            Err(e) => {
                self.0.on_bad_frame(e.into());
                return Vec::new();
            }
        };
        let r = Report::decode(payload)
            .unwrap_or_else(|e| panic!("accepted but not decoded ({e:?}): {payload:02x?}"));
        let mut lines = vec![line(|v| RawReport::write(view.bytes(), v))];
        match self.0.on_report(&r) {
            Ok(fix) => {
                for l in fix.lines() {
                    lines.push(line(|v| l.write(v)));
                }
            }
            Err(e) => {
                let l = sink_fw::no_fix_line(r.agent, r.seq, e);
                lines.push(line(|v| l.write(v)));
            }
        }
        lines
    }

    /// The `status` line after `secs` more seconds.
    fn status(&mut self, secs: u8) -> Vec<u8> {
        self.0.add_uptime(secs);
        let l = self.0.counters().line();
        line(|v| l.write(v))
    }

    /// The counters so far.
    fn counters(&self) -> sink_fw::Counters {
        *self.0.counters()
    }
}

fn line(write: impl FnOnce(&mut String) -> Result<(), std::convert::Infallible>) -> Vec<u8> {
    let mut v = String::new();
    let Ok(()) = write(&mut v);
    v.into_bytes()
}

/// Anchors × channels × relay matrix.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
struct Class {
    anchors: u8,
    channels: u8,
    relay: bool,
}

impl Class {
    /// Every class: 3…8 anchors × 1…4 channels × relay matrix or not.
    fn all() -> Vec<Class> {
        let mut v = Vec::new();
        for anchors in 3..=8 {
            for channels in 1..=4 {
                for relay in [true, false] {
                    v.push(Class {
                        anchors,
                        channels,
                        relay,
                    });
                }
            }
        }
        v
    }
}

impl fmt::Display for Class {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        let relay = if self.relay { "relay" } else { "no relay" };
        write!(f, "{}×{} {relay}", self.anchors, self.channels)
    }
}

/// The next sequence number of every agent that reported.
#[derive(Default)]
struct Agents(HashMap<u8, u16>);

impl Agents {
    /// An agent (mostly the sink's tracked 1…16, some just past them, any of 1…255) and its next
    /// sequence number: in order mostly, else with a gap, repeated, late, random, half the
    /// sequence space ahead, or about to wrap.
    fn draw(&mut self, rng: &mut Rng) -> (u8, u16) {
        let agent = match rng.below(20) {
            0..=11 => rng.range(1, 16),
            12..=14 => rng.range(17, 24),
            _ => rng.range(1, 255),
        } as u8;
        let Some(&next) = self.0.get(&agent) else {
            let seq = rng.u64() as u16;
            self.0.insert(agent, seq.wrapping_add(1));
            return (agent, seq);
        };
        let seq = match rng.below(20) {
            0..=11 => next,
            12 | 13 => next.wrapping_add(rng.range(1, 5) as u16),
            14 => next.wrapping_sub(1),
            15 => next.wrapping_sub(rng.range(2, 300) as u16),
            16 => rng.u64() as u16,
            17 => next
                .wrapping_add(0x8000)
                .wrapping_add(rng.range(-2, 2) as u16),
            _ => 0xFFFF - rng.below(3) as u16,
        };
        self.0.insert(agent, seq.wrapping_add(1));
        (agent, seq)
    }
}

/// A random report of `class` (see the module docs).
fn draw_report(rng: &mut Rng, class: Class, agents: &mut Agents, base: PathLoss) -> Report {
    let (n, c) = (class.anchors as usize, class.channels as usize);
    let (agent, seq) = agents.draw(rng);
    let mut r = Report::new(agent, seq, class.anchors, random::channels(rng, c));
    r.has_relay = class.relay;
    let (layout, _) = anchor_layout(rng, n);
    let model = if rng.chance(0.8) {
        base
    } else {
        PathLoss::draw(rng)
    };
    // The agent somewhere in (or a little outside) the anchors' box.
    let (lo, hi) = layout[..n]
        .iter()
        .fold(([f64::MAX; 2], [f64::MIN; 2]), |(lo, hi), p| {
            let (x, y) = (f64::from(p.x), f64::from(p.y));
            ([lo[0].min(x), lo[1].min(y)], [hi[0].max(x), hi[1].max(y)])
        });
    let at = [0, 1].map(|k| {
        let w = (hi[k] - lo[k]).max(100.0);
        lo[k] - 0.1 * w + 1.2 * w * rng.unit()
    });
    let missing_anchor = rng.pick(&[0.0, 0.0, 0.1, 0.3, 0.6]);
    let missing_channel = rng.pick(&[0.0, 0.0, 0.15, 0.4]);
    let missing_byte = rng.pick(&[0.0, 0.0, 0.05, 0.2]);
    let odd_byte = rng.pick(&[0.0, 0.0, 0.02, 0.1, 0.5]);
    let zero_position = rng.chance(0.8);
    let gone: Vec<bool> = (0..n).map(|_| rng.chance(missing_anchor)).collect();
    let quiet: Vec<bool> = (0..c).map(|_| rng.chance(missing_channel)).collect();
    let byte = |rng: &mut Rng, d: f64| {
        if rng.chance(missing_byte) {
            0
        } else if rng.chance(odd_byte) {
            if rng.chance(0.5) {
                edge_byte(rng)
            } else {
                rng.range(1, 255) as u8
            }
        } else {
            model.byte(rng, d)
        }
    };
    for i in 0..n {
        if !(gone[i] && zero_position) {
            r.positions[i] = layout[i];
        }
    }
    for (ch, &quiet) in quiet.iter().enumerate() {
        for i in 0..n {
            if quiet || gone[i] {
                continue;
            }
            r.rssi[ch][i] = byte(rng, dist_cm(layout[i], at));
            if class.relay {
                for j in (0..n).filter(|&j| j != i) {
                    let b = layout[j];
                    r.relay[ch][i][j] = byte(rng, dist_cm(layout[i], [b.x.into(), b.y.into()]));
                }
            }
        }
    }
    // One packet, as an agent sends it.
    r.fit_relay();
    r
}

fn encoded(r: &Report) -> Vec<u8> {
    let mut buf = [0; MAX_PAYLOAD];
    let n = r
        .encode(&mut buf)
        .unwrap_or_else(|e| panic!("{e:?}: {r:?}"));
    buf[..n].to_vec()
}

/// Where a group of expected lines comes from.
enum Origin {
    /// Frame `k` (a report of `class`, or garbage that a sink takes for a report).
    Frame {
        k: usize,
        class: Option<Class>,
        payload: Vec<u8>,
    },
    /// Status line `n` (from 1).
    Status(u32),
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self {
            Origin::Frame { k, class, payload } => {
                let what = class.map_or("garbage".to_string(), |c| c.to_string());
                write!(f, "frame {k} ({what}")?;
                if let Ok(v) = ReportView::accept(payload) {
                    write!(f, ", agent {} seq {}", v.agent(), v.seq())?;
                }
                write!(f, "), {} bytes: ", payload.len())?;
                payload.iter().try_for_each(|b| write!(f, "{b:02x}"))
            }
            Origin::Status(n) => write!(f, "status line {n}"),
        }
    }
}

/// A sink firmware in simavr, fed frames, and what the host expects of it.
struct Bench {
    avr: Avr,
    radio: XBee,
    config: Config,
    /// Index into the firmware's UART output of the first byte compared.
    start: usize,
    /// How far the output was scanned for line ends, and how many it had.
    scanned: usize,
    newlines: usize,
    host: HostSink,
    expected: Vec<(Origin, Vec<Vec<u8>>)>,
    expected_lines: usize,
    next_status_ms: f64,
    statuses: u32,
}

impl Bench {
    /// Boots the sink (with `config` in EEPROM, or its built-in config) and runs it until its
    /// first status line, where the comparison starts.
    fn boot(config: Option<Config>) -> Bench {
        let (mut avr, mut radio, up) = boot_configured(Role::Sink, config.as_ref());
        let config = config.unwrap_or(Config::default_for(Role::Sink));
        let is_status = |t: &str| t.starts_with("hoploc sink status");
        let first = loop {
            radio.run_for_ms(&mut avr, 10.0);
            if let Some(l) = radio.text_lines().iter().find(|l| is_status(&l.text)) {
                break l.cycle;
            }
            assert!(
                avr.time_ms() < up + STATUS_MS + 1_000.0,
                "no status line: {:?}",
                radio.texts()
            );
        };
        let start = avr
            .uart_output()
            .iter()
            .position(|b| b.cycle >= first)
            .expect("the status line's bytes");
        let mut bench = Bench {
            avr,
            radio,
            config,
            start,
            scanned: start,
            newlines: 0,
            host: HostSink::new(config.position),
            expected: Vec::new(),
            expected_lines: 0,
            next_status_ms: simavr::cycles_to_ms(first),
            statuses: 0,
        };
        bench.status();
        bench
    }

    /// The host's next status line, expected now.
    fn status(&mut self) {
        self.statuses += 1;
        let l = self.host.status((STATUS_MS / 1000.0) as u8);
        self.expected.push((Origin::Status(self.statuses), vec![l]));
        self.expected_lines += 1;
        self.next_status_ms += STATUS_MS;
    }

    /// Line ends the firmware has written since the start.
    fn firmware_newlines(&mut self) -> usize {
        let out = self.avr.uart_output();
        self.newlines += out[self.scanned..]
            .iter()
            .filter(|b| b.byte == b'\n')
            .count();
        self.scanned = out.len();
        self.newlines
    }

    /// Runs until the firmware has written every line expected so far and `min_ms` has passed.
    fn settle(&mut self, min_ms: f64, what: &dyn Fn() -> String) -> Result<(), String> {
        let deadline = self.avr.time_ms() + LINES_DEADLINE_MS;
        loop {
            self.radio.run_for_ms(&mut self.avr, 2.0);
            let got = self.firmware_newlines();
            if got >= self.expected_lines && self.avr.time_ms() >= min_ms {
                return Ok(());
            }
            if self.avr.time_ms() > deadline {
                return Err(format!(
                    "{} lines written, {} expected, {LINES_DEADLINE_MS} ms after {}",
                    got,
                    self.expected_lines,
                    what()
                ));
            }
        }
    }

    /// Delivers frame `k` (`payload`; a report of `class`, or garbage) a few ms from now, out of
    /// the status lines' way, and runs until its lines are out.
    fn send(
        &mut self,
        rng: &mut Rng,
        k: usize,
        class: Option<Class>,
        payload: Vec<u8>,
    ) -> Result<(), String> {
        let mut at = self.avr.time_ms() + rng.range(1, 20) as f64;
        while at > self.next_status_ms - QUIET_BEFORE_STATUS_MS {
            let after = self.next_status_ms + QUIET_AFTER_STATUS_MS;
            self.status();
            let n = self.statuses;
            self.settle(after, &|| format!("status line {n}"))?;
            at = at.max(self.avr.time_ms() + rng.range(1, 20) as f64);
        }
        let lines = self.host.frame(&payload);
        let agent = ReportView::accept(&payload).map_or(1, |v| v.agent());
        let packet = RxPacket {
            channel: xbee_channel(self.config.sink_channel).expect("the sink channel"),
            pan_id: self.config.pan_id,
            source: Address::Short(Role::Agent.address(agent)),
            dest: Address::Short(Role::Sink.address(self.config.id)),
            options: 0,
            rssi_dbm: -60,
            payload: payload.clone(),
        };
        self.radio.deliver(packet, ms_to_cycles(at));
        // The RX frame over the UART (escapes at most double it), then a little.
        let min_ms = at + (10 + 2 * payload.len()) as f64 * hoploc_tests::UART_BYTE_MS + 3.0;
        self.expected_lines += lines.len();
        if !lines.is_empty() {
            self.expected
                .push((Origin::Frame { k, class, payload }, lines));
        }
        self.settle(min_ms, &|| format!("frame {k}"))
    }

    /// The firmware's lines since the start, grouped as the host's: a status line alone, a
    /// `report` line with the lines up to the next `report` or status line.
    fn firmware_groups(&self) -> Vec<Vec<Vec<u8>>> {
        let bytes: Vec<u8> = self.avr.uart_output()[self.start..]
            .iter()
            .map(|b| b.byte)
            .collect();
        let mut groups: Vec<Vec<Vec<u8>>> = Vec::new();
        let mut alone = true;
        for l in bytes.split_inclusive(|&b| b == b'\n') {
            let status = l.starts_with(b"hoploc sink status");
            if status || l.starts_with(b"hoploc sink report") || alone {
                groups.push(Vec::new());
            }
            alone = status;
            groups.last_mut().expect("a group").push(l.to_vec());
        }
        groups
    }
}

fn text(l: &[u8]) -> String {
    String::from_utf8_lossy(l).trim_end().to_string()
}

/// Runs one sink on `REPORTS` random reports and garbage drawn from `seed`, and compares
/// (`base`: the test's seed, which `HOPLOC_TEST_SEED` sets).
fn run(name: &str, base: u64, seed: u64, config: Option<Config>) {
    let wall = Instant::now();
    let mut rng = Rng::new(seed);
    let classes = Class::all();
    assert_eq!(classes.len(), 48);
    let mut bench = Bench::boot(config);
    let model = PathLoss::draw(&mut rng);
    let mut agents = Agents::default();
    let mut order = Vec::new();
    let mut per_class: BTreeMap<Class, usize> = BTreeMap::new();
    let (mut frames, mut garbage_frames) = (0, 0);
    let mut failure = None;
    for _ in 0..REPORTS {
        if order.is_empty() {
            order = classes.clone();
            rng.shuffle(&mut order);
        }
        let class = order.pop().expect("a class");
        let report = encoded(&draw_report(&mut rng, class, &mut agents, model));
        if rng.below(GARBAGE_ONE_IN) == 0 {
            let g = garbage(&mut rng, &report);
            garbage_frames += 1;
            if let Err(e) = bench.send(&mut rng, frames, None, g) {
                failure = Some(e);
                break;
            }
            frames += 1;
        }
        *per_class.entry(class).or_default() += 1;
        if let Err(e) = bench.send(&mut rng, frames, Some(class), report) {
            failure = Some(e);
            break;
        }
        frames += 1;
    }
    bench.radio.run_for_ms(&mut bench.avr, 300.0);
    // A status line that fell due meanwhile, whole.
    if failure.is_none() && bench.avr.time_ms() > bench.next_status_ms - QUIET_BEFORE_STATUS_MS {
        let after = bench.next_status_ms + QUIET_AFTER_STATUS_MS;
        bench.status();
        if let Err(e) = bench.settle(after, &|| "the last status line".into()) {
            failure = Some(e);
        }
    }
    let got = bench.firmware_groups();
    let counters = bench.host.counters();
    println!(
        "{name}: {}={base:#x}, {frames} frames ({garbage_frames} garbage), {} status lines, \
         {} fixes, {} without, {} missing by sequence; {:.0} s simulated in {:.1} s",
        random::SEED_VAR,
        bench.statuses,
        counters.fixes(),
        counters.no_fixes(),
        counters.drops(),
        bench.avr.time_ms() / 1000.0,
        wall.elapsed().as_secs_f64()
    );
    println!(
        "{name}: reports per class: {}",
        per_class
            .iter()
            .map(|(c, n)| format!("{c}: {n}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    // Compare, group by group.
    let mut report = String::new();
    let mut bad: BTreeMap<String, usize> = BTreeMap::new();
    let mut shown = 0;
    for (k, (origin, want)) in bench.expected.iter().enumerate() {
        let empty = Vec::new();
        let have = got.get(k).unwrap_or(&empty);
        if have == want {
            continue;
        }
        let key = match origin {
            Origin::Frame { class: Some(c), .. } => c.to_string(),
            Origin::Frame { class: None, .. } => "garbage".into(),
            Origin::Status(_) => "status".into(),
        };
        *bad.entry(key).or_default() += 1;
        if shown < 5 {
            shown += 1;
            report += &format!("\n{origin}\n  expected:\n");
            for l in want {
                report += &format!("    {}\n", text(l));
            }
            report += "  written:\n";
            for l in have {
                report += &format!("    {}\n", text(l));
            }
        }
    }
    if got.len() > bench.expected.len() {
        report += &format!(
            "\n{} groups of lines more than expected, the first: {:?}\n",
            got.len() - bench.expected.len(),
            got[bench.expected.len()]
                .iter()
                .map(|l| text(l))
                .collect::<Vec<_>>()
        );
    }
    let differing: usize = bad.values().sum();
    assert!(
        failure.is_none() && differing == 0 && got.len() == bench.expected.len(),
        "{name} ({}={base:#x}): {}{differing} of {} groups of lines differ; per class: {bad:?}\n{report}",
        random::SEED_VAR,
        failure.map_or(String::new(), |e| format!("stopped: {e}; ")),
        bench.expected.len(),
    );
    // The draws reach what they are for.
    assert!(
        per_class.len() == 48 && per_class.values().all(|&n| n >= 30),
        "{per_class:?}"
    );
    assert!(counters.fixes() as usize >= REPORTS / 2, "{counters:?}");
    assert!(counters.no_fixes() >= 50, "{counters:?}");
    assert!(
        counters.drops() > 0 && counters.checksum_errors() > 0 && counters.foreign() > 0,
        "{counters:?}"
    );
    assert!(bench.statuses >= 5, "{}", bench.statuses);
}

/// The sink with its built-in config: the room is each report's anchors' bounding box.
#[test]
fn the_sink_firmware_writes_what_the_host_sink_computes_for_random_reports() {
    let seed = random::seed(SEED);
    run("anchors' box", seed, seed, None);
}

/// The sink with a config in EEPROM: a room of its own (and another id and sink channel).
#[test]
fn a_sink_with_a_room_in_eeprom_writes_what_the_host_sink_computes_for_random_reports() {
    let base = random::seed(SEED);
    let seed = base ^ 0x0E0E_0E0E;
    let mut rng = Rng::new(seed);
    let config = Config {
        role: Role::Sink,
        id: rng.range(1, 255) as u8,
        position: Position {
            x: rng.range(200, 3_000) as i16,
            y: rng.range(200, 3_000) as i16,
        },
        sink_channel: rng.range(1, 16) as u8,
        ..Config::DEFAULT
    };
    assert!(sink_fw::room(config.position).is_some());
    run("room in EEPROM", base, seed, Some(config));
}
