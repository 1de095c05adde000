//! The scenario runner of the emulated testbed (SPEC §7): a [`Scenario`] as a
//! [`simavr::network::Network`] of real firmware — every anchor runs `anchor-fw` and the agent
//! `agent-fw`, each with its config in EEPROM as `hoploc provision` would write it, on the
//! scenario's medium — with the agent moved along its path, and the sink's output lines
//! ([`SinkLine`]) paired with the ground truth at their time.
//!
//! The lines come from one of two sinks ([`SinkSource`]):
//! * [`SinkSource::Firmware`]: the sink node's firmware (`sink-fw`), its lines read off its
//!   UART as `hoploc monitor` would read them off the USB serial. This is the intended sink;
//!   but while the wired sink does not fit the Uno, `sink-fw` is the boot firmware and writes
//!   no sink lines.
//! * [`SinkSource::Host`]: the host sink, a host radio on the sink channel at the sink's
//!   address whose received reports go through `sink_fw::Sink<loc_core::fixed::Portable>` —
//!   the sink firmware's logic, bit-identical to it, but run on the host, not in simavr.

use std::path::Path;

use loc_core::fixed::{mle_and_mmse_window_with, AreaCm, PathLoss, Portable};
use loc_proto::config::Config;
use loc_proto::msg::{ChannelList, Position, Report};
use loc_proto::schedule::Schedule;
use loc_proto::sink_line::SinkLine;
use loc_proto::Role;
use simavr::medium::{Medium, NodeRadio};
use simavr::network::{Network, NetworkConfig, NodeId, NodeSpec};
use simavr::{cycles_to_ms, ms_to_cycles};
use sink_fw::{BadFrame, Sink};
use xbee_api::{Decoder, Frame, Mode};

use crate::firmware;
use crate::scenario::Scenario;

/// Where the sink lines come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SinkSource {
    /// The host sink: a host radio at the sink's address, its reports through `sink_fw::Sink`
    /// on the host (the firmware's logic, not the firmware).
    Host,
    /// The sink firmware's UART in simavr (needs a sink firmware that writes sink lines).
    Firmware,
}

impl SinkSource {
    /// How the output names it.
    pub fn describe(self) -> &'static str {
        match self {
            SinkSource::Host => {
                "host sink (sink_fw::Sink run on the host behind a host radio; not the sink firmware)"
            }
            SinkSource::Firmware => "sink firmware (sink-fw in simavr, lines from its UART)",
        }
    }
}

/// A sink line with the ground truth when it was written.
#[derive(Clone, Debug, PartialEq)]
pub struct Observed {
    /// Simulated time of the line, s.
    pub time_s: f64,
    /// The line.
    pub line: SinkLine,
    /// Index of the agent's stop ([`crate::scenario::AgentSpec::path`]) at that time.
    pub stop: usize,
    /// The agent's true position then, m.
    pub truth: [f64; 2],
    /// Whether the whole superframe the report measured lies after the warm-up and within this
    /// stop (else the fix mixes two positions or the network's start: left out of statistics).
    pub settled: bool,
    /// Not a sink line but the host's reference, as a `fix` line: the MLE of the same report
    /// with P0 and α fixed at the scenario's starting values, as a sink without online P0/α
    /// estimation would give it (host sink only; experiment 3's comparison).
    pub reference: bool,
}

/// How a run is set up.
#[derive(Clone, Debug)]
pub struct RunConfig {
    /// The sink.
    pub sink: SinkSource,
    /// Stepping threads of the network (2: both cores of the target machine).
    pub threads: usize,
    /// Probability of a bit error in each byte on every firmware↔radio UART (0: none).
    pub uart_error_rate: f64,
}

impl Default for RunConfig {
    fn default() -> Self {
        RunConfig {
            sink: SinkSource::Host,
            threads: 2,
            uart_error_rate: 0.0,
        }
    }
}

/// The host sink's state.
struct HostSink {
    node: NodeId,
    decoder: Decoder,
    sink: Sink<Portable>,
    /// The reference's fixed model and room.
    fixed: (PathLoss, AreaCm),
}

/// A scenario running on the emulated network.
pub struct Testbed {
    scenario: Scenario,
    net: Network,
    agent: NodeId,
    host: Option<HostSink>,
    /// The sink firmware's node and the lines of it already taken.
    fw_sink: Option<(NodeId, usize)>,
    /// Start of each stop (stop 0: 0), s.
    stop_start_s: Vec<f64>,
    stop: usize,
    superframe_s: f64,
}

/// Simulated time `s` seconds in cycles.
fn cycle_of(s: f64) -> u64 {
    ms_to_cycles(s * 1000.0)
}

/// `p` metres as config centimetres.
fn cm(p: [f64; 2]) -> Position {
    Position {
        x: (p[0] * 100.0).round() as i16,
        y: (p[1] * 100.0).round() as i16,
    }
}

/// The config `hoploc provision` would store in a node of `role` of `s`, as EEPROM bytes.
pub fn eeprom(s: &Scenario, role: Role, id: u8, position: Position) -> Result<Vec<u8>, String> {
    let channels = ChannelList::new(&s.timing.channels).map_err(|e| format!("channels: {e:?}"))?;
    let c = Config {
        role,
        id,
        anchors: s.anchors.len() as u8,
        position,
        slot_ms: s.timing.slot_ms,
        channels,
        sink_channel: s.timing.sink_channel,
        pan_id: Config::DEFAULT.pan_id,
    };
    let mut buf = [0; 32];
    let n = c
        .to_bytes(&mut buf)
        .map_err(|e| format!("{} {id} config: {e:?}", role.name()))?;
    Ok(buf[..n].to_vec())
}

/// The superframe of `s`'s nodes, s.
pub fn superframe_s(s: &Scenario) -> Result<f64, String> {
    let c = Config::from_bytes(&eeprom(s, Role::Agent, 1, Position { x: 0, y: 0 })?)
        .map_err(|e| format!("{e:?}"))?;
    let sched = Schedule::for_config(&c).map_err(|e| format!("schedule: {e:?}"))?;
    Ok(sched.superframe_us() as f64 / 1e6)
}

impl Testbed {
    /// Builds the network of `scenario` from the ELFs in `fw_dir` (anchor-fw, agent-fw and,
    /// for [`SinkSource::Firmware`], sink-fw), the agent at its first stop.
    pub fn new(scenario: &Scenario, fw_dir: &Path, cfg: &RunConfig) -> Result<Testbed, String> {
        let s = scenario.clone();
        let mut net = Network::with_config(
            Medium::new(s.medium_config()),
            NetworkConfig {
                threads: cfg.threads.max(1),
                uart_error_rate: cfg.uart_error_rate,
                seed: s.seed,
                ..NetworkConfig::default()
            },
        );
        let serial = |i: usize| 0x0013_A200_4000_0000 + i as u64;
        for (i, a) in s.anchors.iter().enumerate() {
            let mut spec = NodeSpec::new(
                format!("anchor{}", i + 1),
                NodeRadio {
                    antenna: a.antenna.into(),
                    orientation_deg: a.orientation_deg,
                    ..NodeRadio::at(a.position[0], a.position[1])
                },
            );
            spec.eeprom = eeprom(&s, Role::Anchor, i as u8 + 1, cm(a.position))?;
            spec.xbee.sh_sl = serial(i);
            let elf = firmware::elf(fw_dir, Role::Anchor);
            net.add_node(&elf, spec)
                .map_err(|e| format!("{}: {e}", elf.display()))?;
        }
        let first = s.agent.path[0];
        let mut spec = NodeSpec::new(
            "agent1",
            NodeRadio {
                antenna: s.agent.antenna.into(),
                orientation_deg: first.orientation_deg.unwrap_or(s.agent.orientation_deg),
                ..NodeRadio::at(first.position[0], first.position[1])
            },
        );
        spec.eeprom = eeprom(&s, Role::Agent, 1, Position { x: 0, y: 0 })?;
        spec.xbee.sh_sl = serial(10);
        let elf = firmware::elf(fw_dir, Role::Agent);
        let agent = net
            .add_node(&elf, spec)
            .map_err(|e| format!("{}: {e}", elf.display()))?;
        // The sink stands in the middle of the room; the room's size is its config position.
        let middle = NodeRadio::at(s.area.width_m / 2.0, s.area.height_m / 2.0);
        let mut spec = NodeSpec::new("sink1", middle);
        spec.xbee.sh_sl = serial(20);
        let (mut host, mut fw_sink) = (None, None);
        match cfg.sink {
            SinkSource::Host => {
                spec.xbee.my = Role::Sink.address(1);
                spec.xbee.ch = loc_proto::xbee_channel(s.timing.sink_channel)
                    .ok_or("the sink channel has no XBee channel")?;
                spec.xbee.id = Config::DEFAULT.pan_id;
                let node = net.add_host_radio(spec);
                let fixed = PathLoss::from_centi(
                    (s.medium.p0_dbm * 100.0).round() as i32,
                    (s.medium.alpha * 100.0).round() as i32,
                );
                host = Some(HostSink {
                    node,
                    decoder: Decoder::new(Mode::Escaped),
                    sink: Sink::new(Some(s.area_cm())),
                    fixed: (fixed, s.area_cm()),
                });
            }
            SinkSource::Firmware => {
                let room = cm([s.area.width_m, s.area.height_m]);
                spec.eeprom = eeprom(&s, Role::Sink, 1, room)?;
                let elf = firmware::elf(fw_dir, Role::Sink);
                let node = net
                    .add_node(&elf, spec)
                    .map_err(|e| format!("{}: {e}", elf.display()))?;
                fw_sink = Some((node, 0));
            }
        }
        let mut stop_start_s = vec![0.0];
        let mut t = s.timing.warmup_s;
        for stop in &s.agent.path[..s.agent.path.len() - 1] {
            t += stop.dwell_s;
            stop_start_s.push(t);
        }
        Ok(Testbed {
            superframe_s: superframe_s(&s)?,
            scenario: s,
            net,
            agent,
            host,
            fw_sink,
            stop_start_s,
            stop: 0,
        })
    }

    /// The scenario.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// The network.
    pub fn network(&self) -> &Network {
        &self.net
    }

    /// The network, mutably (to power a node off or on: anchors are nodes 0…N−1 in id order,
    /// the agent node N).
    pub fn network_mut(&mut self) -> &mut Network {
        &mut self.net
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f64 {
        self.net.time_ms() / 1000.0
    }

    /// The nodes' superframe (one report, so one fix per agent, each), s.
    pub fn superframe_s(&self) -> f64 {
        self.superframe_s
    }

    /// Whether the scenario's time is up.
    pub fn done(&self) -> bool {
        self.net.cycle() >= cycle_of(self.scenario.duration_s())
    }

    /// The host sink's counters (`None` with the firmware sink).
    pub fn host_counters(&self) -> Option<&sink_fw::Counters> {
        self.host.as_ref().map(|h| h.sink.counters())
    }

    /// Runs up to `seconds` more of simulated time (not past the scenario's end), moving the
    /// agent at the end of each dwell; returns the sink lines written meanwhile, in order.
    pub fn step(&mut self, seconds: f64) -> Vec<Observed> {
        // In cycles: times in seconds do not round-trip exactly through cycles.
        let end = cycle_of((self.time_s() + seconds).min(self.scenario.duration_s()));
        let mut out = Vec::new();
        while self.net.cycle() < end {
            let next_move = self.stop_start_s.get(self.stop + 1).map(|&m| cycle_of(m));
            self.net.run_until(next_move.map_or(end, |m| m.min(end)));
            self.collect(&mut out);
            if next_move.is_some_and(|m| self.net.cycle() >= m) {
                self.stop += 1;
                let stop = self.scenario.agent.path[self.stop];
                let default_deg = self.scenario.agent.orientation_deg;
                let node = self.net.medium_mut().node_mut(self.agent);
                node.position = stop.position;
                node.orientation_deg = stop.orientation_deg.unwrap_or(default_deg);
            }
        }
        out
    }

    /// The sink lines written since the last call, with their truth.
    fn collect(&mut self, out: &mut Vec<Observed>) {
        let mut lines: Vec<(f64, SinkLine, bool)> = Vec::new();
        if let Some(h) = &mut self.host {
            let bytes = self.net.core_mut(h.node).take_output();
            let mut frames: Vec<(u64, Vec<u8>)> = Vec::new();
            let mut start = 0;
            for b in bytes {
                if b.byte == xbee_api::START {
                    start = b.cycle;
                }
                h.decoder.feed(&[b.byte], |f| {
                    if let Ok(f) = f {
                        frames.push((start, f.data().to_vec()));
                    }
                });
            }
            for (cycle, data) in frames {
                let Ok(Frame::Rx16 { data, .. }) = Frame::parse(&data) else {
                    continue; // modem status, TX status: not the sink's business
                };
                let ms = cycles_to_ms(cycle);
                let r = match Report::decode(data) {
                    Ok(r) => r,
                    Err(e) => {
                        h.sink.on_bad_frame(BadFrame::of(e));
                        continue;
                    }
                };
                match h.sink.on_report(&r) {
                    Ok(fix) => lines.extend(fix.lines().map(|l| (ms, l, false))),
                    Err(e) => lines.push((ms, sink_fw::no_fix_line(r.agent, r.seq, e), false)),
                }
                let (model, area) = h.fixed;
                let (_, obs) = sink_fw::report_inputs(&r);
                if let Ok([mle, mmse]) =
                    mle_and_mmse_window_with::<Portable>(&obs, model, area, sink_fw::DEFAULT_SIGMA)
                {
                    let fix = sink_fw::Fix {
                        agent: r.agent,
                        seq: r.seq,
                        mle,
                        mmse,
                        model,
                        fitted: false,
                    };
                    lines.push((ms, fix.lines()[0], true));
                }
            }
        }
        if let Some((node, seen)) = &mut self.fw_sink {
            let all = self.net.lines(*node);
            for l in &all[*seen..] {
                if let Ok(line) = SinkLine::parse(&l.text) {
                    lines.push((l.ms(), line, false));
                }
            }
            *seen = all.len();
        }
        for (ms, line, reference) in lines {
            let t = ms / 1000.0;
            let stop = self.stop_at(t);
            let measured_from = t - self.superframe_s;
            let settled =
                measured_from >= self.scenario.timing.warmup_s.max(self.stop_start_s[stop]);
            out.push(Observed {
                time_s: t,
                line,
                stop,
                truth: self.scenario.agent.path[stop].position,
                settled,
                reference,
            });
        }
    }

    /// The stop the agent was at at time `t` s.
    fn stop_at(&self, t: f64) -> usize {
        self.stop_start_s.iter().rposition(|&s| s <= t).unwrap_or(0)
    }
}
