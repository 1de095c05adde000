//! The scenario runner of the emulated testbed (`docs/design.md`, section 8): a [`Scenario`] as a
//! [`simavr::network::Network`] of real firmware — every anchor runs `anchor-fw` and the agent
//! `agent-fw`, each with its config in EEPROM as `hoploc provision` would write it, on the
//! scenario's medium — with the agent moved along its path, and the sink's output lines
//! ([`SinkLine`]) paired with the ground truth at their time.
//!
//! The lines come from one of two sinks ([`SinkSource`]):
//! * [`SinkSource::Firmware`]: the sink node's firmware (`sink-fw`), its lines read off its
//!   UART as `hoploc monitor` would read them off the USB serial: the testbed as on boards.
//! * [`SinkSource::Host`]: the host sink, a host radio on the sink channel at the sink's
//!   address whose received reports go through `sink_fw::Sink` —
//!   the sink firmware's logic, bit-identical to it, but run on the host, not in simavr
//!   (`hoploc/tests/testbed.rs` checks that both write the same lines).
//!
//! Either way the host adds its references of every report the sink received (the firmware's
//! `report` lines carry them): [`Reference`].

use std::path::Path;

use loc_core::fixed::{mle_and_mmse_window, AreaCm, PathLoss};
use loc_core::grid::{self, Search};
use loc_core::params::{Bounds, FitMethod, OnlineParams, ParamMode};
use loc_core::refine::{observations, Refinement};
use loc_core::Area;
use loc_proto::config::Config;
use loc_proto::msg::{Beacon, ChannelList, Position, Report};
use loc_proto::schedule::Schedule;
use loc_proto::sink_line::{Estimator, RawReport, SinkLine, SinkOutput, FLAG_FITTED};
use loc_proto::Role;
use simavr::medium::{Medium, NodeRadio};
use simavr::network::{Network, NetworkConfig, NodeId, NodeSpec, Outcome, TxRecord};
use simavr::xbee::Csma;
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
    /// Not a sink line but one of the host's references, as a `fix` line (experiment 3's
    /// comparison); `None` for the sink's lines.
    pub reference: Option<Reference>,
}

/// The last `status` line among `obs` (the sink's counters at that time), if any.
pub fn last_status(obs: &[Observed]) -> Option<SinkLine> {
    obs.iter()
        .map(|o| o.line)
        .rfind(|l| matches!(l, SinkLine::Status { .. }))
}

impl Observed {
    /// Whether this is the sink's own MLE `fix` line (one per located report), not a host
    /// reference.
    pub fn is_sink_mle(&self) -> bool {
        self.reference.is_none()
            && matches!(
                self.line,
                SinkLine::Fix {
                    estimator: Estimator::Mle,
                    ..
                }
            )
    }
}

/// The host's reference fixes of each report the host sink receives: other ways the same
/// report could have been located, next to the sink's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Reference {
    /// The sink's MLE (fixed point) with P0 and α fixed at the scenario's starting values, as
    /// a sink without online P0/α estimation would give it.
    Fixed,
    /// The f64 MLE (`loc_core::grid`, Extended refinement, the thesis search) with P0 fitted
    /// online from the anchor-to-anchor RSSI (least squares within the thesis bounds, AR(1)
    /// smoothed) and α fixed at the scenario's starting value: `ParamMode::P0Only`, the mode
    /// that follows battery droop without trying to identify α from few anchor distances.
    P0Only,
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
    sink: Sink,
}

/// The host's references of every report the sink received (either sink: the firmware's
/// `report` lines carry the reports too).
struct References {
    /// The reference's fixed model and room.
    fixed: (PathLoss, AreaCm),
    /// Every report received (time s, report), until [`Testbed::take_reports`].
    reports: Vec<(f64, Report)>,
    /// The [`Reference::P0Only`] estimator's parameters and room.
    p0_only: (OnlineParams, Area),
}

impl References {
    /// Report `r` received at `ms`: kept, and its reference fixes added to `lines`.
    fn add(&mut self, ms: f64, r: Report, lines: &mut Vec<(f64, SinkLine, Option<Reference>)>) {
        let (model, area) = self.fixed;
        let (_, obs) = sink_fw::report_inputs(&r);
        if let Ok([mle, mmse]) = mle_and_mmse_window(&obs, model, area, sink_fw::DEFAULT_SIGMA) {
            let fix = sink_fw::Fix {
                agent: r.agent,
                seq: r.seq,
                estimates: [mle, mmse],
                model,
                fitted: false,
            };
            lines.push((ms, fix.lines()[0], Some(Reference::Fixed)));
        }
        if let Some(line) = p0_only_fix(&mut self.p0_only, &r) {
            lines.push((ms, line, Some(Reference::P0Only)));
        }
        self.reports.push((ms / 1000.0, r));
    }
}

/// A scenario running on the emulated network.
pub struct Testbed {
    scenario: Scenario,
    net: Network,
    nodes: ScenarioNodes,
    agent: NodeId,
    host: Option<HostSink>,
    refs: References,
    /// The sink firmware's node and the lines of it already taken.
    fw_sink: Option<(NodeId, usize)>,
    /// Start of each stop (stop 0: 0), s.
    stop_start_s: Vec<f64>,
    stop: usize,
    superframe_s: f64,
    /// The sink's output as `hoploc monitor --log` would save it (every sink line, `report`
    /// lines included), with `# truth X Y` lines where the agent moved: `hoploc replay` input.
    log: String,
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
        key: s.timing.key(),
    };
    let mut buf = [0; loc_proto::config::MAX_LEN];
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

/// The [`Reference::P0Only`] fix of `r` as a `fix` line (its P0 fit first, as the sink does);
/// `None` when it gives none (fewer than 3 anchors heard).
fn p0_only_fix((params, area): &mut (OnlineParams, Area), r: &Report) -> Option<SinkLine> {
    let m = crate::replay::measurements(r);
    // A report without a usable calibration sample keeps the model as it was.
    let _ = params.update(&m);
    let model = params.current();
    let e = grid::mle(
        &observations(&m, Refinement::Extended),
        model,
        *area,
        Search::Thesis,
    )
    .ok()?;
    Some(SinkLine::Fix {
        agent: r.agent,
        seq: r.seq,
        estimator: Estimator::Mle,
        x: (e.pos.x * 100.0).round() as i16,
        y: (e.pos.y * 100.0).round() as i16,
        alpha_x100: (model.alpha * 100.0).round() as u16,
        p0_x100: (model.p0 * 100.0).round() as i16,
        anchors: e.anchors as u8,
        flags: FLAG_FITTED,
    })
}

/// Serial numbers (`SH:SL`) of a testbed's radios start here: anchor `i` (0-based) gets
/// `+ i`, the agent `+ 10`, further agents `+ 10 + id − 1`, the sink `+ 20`.
pub const SERIAL_BASE: u64 = 0x0013_A200_4000_0000;

/// The nodes [`add_scenario`] added.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ScenarioNodes {
    /// The anchors, in id order.
    pub anchors: Vec<NodeId>,
    /// The agent (id 1).
    pub agent: NodeId,
    /// The sink: a host radio ([`SinkSource::Host`]) or the sink firmware.
    pub sink: NodeId,
}

/// Adds `s`'s anchors, its agent (id 1) at its first stop and its sink to `net`, every
/// firmware node with the config `hoploc provision` would store; radios placed at `origin` +
/// the scenario's positions (several scenarios on disjoint channels can share one medium: the
/// nodes' configs keep the room's own coordinates), with the XBee's CSMA-CA (backoffs seeded
/// from the scenario's seed and each radio's serial). An anchor's radio stands at
/// [`crate::scenario::AnchorSpec::radio_position`], its config holds its configured position.
/// Serial numbers from `serial_base`.
pub fn add_scenario(
    net: &mut Network,
    s: &Scenario,
    fw_dir: &Path,
    sink: SinkSource,
    origin: [f64; 2],
    serial_base: u64,
) -> Result<ScenarioNodes, String> {
    let at = |p: [f64; 2]| NodeRadio::at(origin[0] + p[0], origin[1] + p[1]);
    firmware::check(&firmware::elf(fw_dir, Role::Anchor), Role::Anchor)?;
    firmware::check(&firmware::elf(fw_dir, Role::Agent), Role::Agent)?;
    if sink == SinkSource::Firmware {
        firmware::check(&firmware::elf(fw_dir, Role::Sink), Role::Sink)?;
    }
    let mut anchors = Vec::new();
    for (i, a) in s.anchors.iter().enumerate() {
        let mut spec = NodeSpec::new(
            format!("anchor{}", i + 1),
            NodeRadio {
                antenna: a.antenna.into(),
                orientation_deg: a.orientation_deg,
                ..at(a.radio_position())
            },
        );
        spec.eeprom = eeprom(s, Role::Anchor, i as u8 + 1, cm(a.position))?;
        spec.xbee.sh_sl = serial_base + i as u64;
        spec.xbee.csma = Csma::Random { seed: s.seed };
        let elf = firmware::elf(fw_dir, Role::Anchor);
        anchors.push(
            net.add_node(&elf, spec)
                .map_err(|e| format!("{}: {e}", elf.display()))?,
        );
    }
    let agent = add_agent(net, s, fw_dir, 1, origin, serial_base)?;
    // The sink stands in the middle of the room; the room's size is its config position.
    let mut spec = NodeSpec::new("sink1", at([s.area.width_m / 2.0, s.area.height_m / 2.0]));
    spec.xbee.sh_sl = serial_base + 20;
    spec.xbee.csma = Csma::Random { seed: s.seed };
    let sink = match sink {
        SinkSource::Host => {
            spec.xbee.my = Role::Sink.address(1);
            spec.xbee.ch = loc_proto::xbee_channel(s.timing.sink_channel)
                .ok_or("the sink channel has no XBee channel")?;
            spec.xbee.id = Config::DEFAULT.pan_id;
            // Encryption as the sink firmware would set it from its config.
            if let Some(key) = s.timing.key() {
                spec.xbee.ee = true;
                spec.xbee.ky = key.0;
            }
            net.add_host_radio(spec)
        }
        SinkSource::Firmware => {
            let room = cm([s.area.width_m, s.area.height_m]);
            spec.eeprom = eeprom(s, Role::Sink, 1, room)?;
            let elf = firmware::elf(fw_dir, Role::Sink);
            net.add_node(&elf, spec)
                .map_err(|e| format!("{}: {e}", elf.display()))?
        }
    };
    Ok(ScenarioNodes {
        anchors,
        agent,
        sink,
    })
}

/// Adds agent `id` of `s` (report sub-slot `id`) at the first stop of `s`'s path (+ `origin`),
/// running `agent-fw` with its config; serial `serial_base + 10 + id − 1`, CSMA-CA as
/// [`add_scenario`]'s radios.
pub fn add_agent(
    net: &mut Network,
    s: &Scenario,
    fw_dir: &Path,
    id: u8,
    origin: [f64; 2],
    serial_base: u64,
) -> Result<NodeId, String> {
    let first = s.agent.path[0];
    let mut spec = NodeSpec::new(
        format!("agent{id}"),
        NodeRadio {
            antenna: s.agent.antenna.into(),
            orientation_deg: first.orientation_deg.unwrap_or(s.agent.orientation_deg),
            ..NodeRadio::at(origin[0] + first.position[0], origin[1] + first.position[1])
        },
    );
    spec.eeprom = eeprom(s, Role::Agent, id, Position { x: 0, y: 0 })?;
    spec.xbee.sh_sl = serial_base + 10 + u64::from(id.max(1) - 1);
    spec.xbee.csma = Csma::Random { seed: s.seed };
    let elf = firmware::elf(fw_dir, Role::Agent);
    net.add_node(&elf, spec)
        .map_err(|e| format!("{}: {e}", elf.display()))
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
        let nodes = add_scenario(&mut net, &s, fw_dir, cfg.sink, [0.0, 0.0], SERIAL_BASE)?;
        let (agent, mut host, mut fw_sink) = (nodes.agent, None, None);
        let fixed = PathLoss::from_centi(
            (s.medium.p0_dbm * 100.0).round() as i32,
            (s.medium.alpha * 100.0).round() as i32,
        );
        let refs = References {
            fixed: (fixed, s.area_cm()),
            reports: Vec::new(),
            p0_only: (
                OnlineParams::new(
                    ParamMode::P0Only,
                    FitMethod::LeastSquares,
                    Bounds::THESIS,
                    loc_core::PathLoss {
                        p0: s.medium.p0_dbm,
                        alpha: s.medium.alpha,
                    },
                ),
                Area::new(s.area.width_m, s.area.height_m),
            ),
        };
        match cfg.sink {
            SinkSource::Host => {
                host = Some(HostSink {
                    node: nodes.sink,
                    decoder: Decoder::new(Mode::Escaped),
                    sink: Sink::new(Some(s.area_cm())),
                });
            }
            SinkSource::Firmware => fw_sink = Some((nodes.sink, 0)),
        }
        let mut stop_start_s = vec![0.0];
        let mut t = s.timing.warmup_s;
        for stop in &s.agent.path[..s.agent.path.len() - 1] {
            t += stop.dwell_s;
            stop_start_s.push(t);
        }
        let first = s.agent.path[0].position;
        Ok(Testbed {
            log: truth_line(first),
            refs,
            superframe_s: superframe_s(&s)?,
            scenario: s,
            net,
            nodes,
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

    /// The scenario's nodes in [`Testbed::network`].
    pub fn nodes(&self) -> &ScenarioNodes {
        &self.nodes
    }

    /// The beacon and report traffic in the network's TX log from `from_s` s on ([`traffic`]).
    pub fn traffic(&self, from_s: f64) -> Result<Traffic, String> {
        let s = &self.scenario;
        let c = Config::from_bytes(&eeprom(s, Role::Agent, 1, Position { x: 0, y: 0 })?)
            .map_err(|e| format!("{e:?}"))?;
        let sched = Schedule::for_config(&c).map_err(|e| format!("schedule: {e:?}"))?;
        Ok(traffic(
            self.net.log(),
            &self.nodes.anchors,
            self.nodes.agent,
            self.nodes.sink,
            &sched,
            &s.timing.channels,
            cycle_of(from_s),
        ))
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

    /// The reports the sink received since the last call (time s, report), in order (from the
    /// firmware sink's `report` lines, or the host sink's radio): for host-side analyses of the
    /// same reports.
    pub fn take_reports(&mut self) -> Vec<(f64, Report)> {
        std::mem::take(&mut self.refs.reports)
    }

    /// The reports the sink received so far and not taken (time s, report), in order.
    pub fn reports(&self) -> &[(f64, Report)] {
        &self.refs.reports
    }

    /// The agent's stop at time `t` s, its true position, and whether a report sent then
    /// measured a whole superframe after the warm-up within that stop (see [`Observed`]).
    pub fn truth_at(&self, t: f64) -> (usize, [f64; 2], bool) {
        let stop = self.stop_at(t);
        let measured_from = t - self.superframe_s;
        let settled = measured_from >= self.scenario.timing.warmup_s.max(self.stop_start_s[stop]);
        (stop, self.scenario.agent.path[stop].position, settled)
    }

    /// The host sink's counters (`None` with the firmware sink).
    pub fn host_counters(&self) -> Option<&sink_fw::Counters> {
        self.host.as_ref().map(|h| h.sink.counters())
    }

    /// Runs the rest of the scenario ([`Testbed::step`] to its end); returns the sink lines
    /// written meanwhile, in order.
    pub fn run_to_end(&mut self) -> Vec<Observed> {
        self.step(self.scenario.duration_s() - self.time_s())
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
                self.log += &truth_line(stop.position);
            }
        }
        out
    }

    /// The sink's log so far: every sink line as written (the host sink writes the same lines
    /// as the firmware: a `report` line, then the fix lines), with `# truth X Y` lines (metres)
    /// at the start and at every move of the agent, so `hoploc replay` can score it.
    pub fn sink_log(&self) -> &str {
        &self.log
    }

    /// The sink lines written since the last call, with their truth.
    fn collect(&mut self, out: &mut Vec<Observed>) {
        let mut lines: Vec<(f64, SinkLine, Option<Reference>)> = Vec::new();
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
                let Ok(()) = RawReport::write(data, &mut self.log);
                let written = match h.sink.on_report(&r) {
                    Ok(fix) => fix.lines().to_vec(),
                    Err(e) => vec![sink_fw::no_fix_line(r.agent, r.seq, e)],
                };
                for l in written {
                    let Ok(()) = l.write(&mut self.log);
                    lines.push((ms, l, None));
                }
                self.refs.add(ms, r, &mut lines);
            }
        }
        if let Some((node, seen)) = &mut self.fw_sink {
            let new = self.net.lines_from(*node, *seen);
            *seen += new.len();
            for l in &new {
                match SinkOutput::parse(&l.text) {
                    Ok(SinkOutput::Line(line)) => lines.push((l.ms(), line, None)),
                    Ok(SinkOutput::Report(raw)) => {
                        if let Ok(r) = raw.report() {
                            self.refs.add(l.ms(), r, &mut lines);
                        }
                    }
                    Err(_) => continue,
                }
                self.log += &l.text;
                self.log += "\r\n";
            }
        }
        for (ms, line, reference) in lines {
            let t = ms / 1000.0;
            let (stop, truth, settled) = self.truth_at(t);
            out.push(Observed {
                time_s: t,
                line,
                stop,
                truth,
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

/// The log annotation `hoploc replay` reads: the agent is at `p` (metres) from here on.
fn truth_line(p: [f64; 2]) -> String {
    format!("# truth {} {}\n", p[0], p[1])
}

/// One anchor's beacon as the TX log shows it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct LoggedBeacon {
    seq: u16,
    anchor: u8,
    /// Index into the channel list.
    channel: u8,
    start_cycle: u64,
}

/// Beacon and report traffic of one testbed, counted from the network's TX log
/// ([`simavr::network::TxRecord`] with its per-receiver outcomes): the testbed's delivery figures.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Traffic {
    /// Beacons the anchors put on air.
    pub beacons: usize,
    /// Of these, the ones the agent's radio passed to its MCU.
    pub beacons_delivered: usize,
    /// Lost because the agent's radio was on another channel (or out of the PAN): by the
    /// schedule it should have been on the beacon's channel, so these count as lost.
    pub beacons_filtered: usize,
    /// Lost because the agent's radio was transmitting or in command mode.
    pub beacons_busy: usize,
    /// Lost below the agent's sensitivity.
    pub beacons_too_weak: usize,
    /// Lost to a collision.
    pub beacons_collided: usize,
    /// Beacons with no record for the agent (agent powered off).
    pub beacons_unheard: usize,
    /// Reports the agent put on air (a report its radio sent again for want of an ACK counts
    /// once).
    pub reports: usize,
    /// Of these, the ones the sink's radio passed on (at whichever attempt).
    pub reports_delivered: usize,
    /// Transmissions of reports beyond each one's first (retries: no ACK from the sink's
    /// radio).
    pub report_retries: usize,
    /// Packets of any kind, from any node, that collided.
    pub collisions: usize,
    /// Superframes whose every slot was checked (the window's whole superframes: those between
    /// the first and the last sequence number seen).
    pub superframes: usize,
    /// (superframe, channel, anchor) slots of those superframes without a beacon.
    pub missing_slots: usize,
    /// Beacons beyond the first in a (superframe, channel, anchor) slot.
    pub duplicate_slots: usize,
    /// Worst spread of a superframe's beacons around the schedule, µs: per superframe, each
    /// beacon's start on air minus its slot's offset gives the superframe's start as that
    /// anchor saw it; this is the largest max − min of those (0: every anchor on one timeline,
    /// to the cycle).
    pub worst_spread_us: f64,
}

impl Traffic {
    /// Beacons delivered to the agent / beacons sent (1 when none were sent).
    pub fn beacon_delivery(&self) -> f64 {
        ratio(self.beacons_delivered, self.beacons)
    }

    /// Reports delivered to the sink / reports sent (1 when none were sent).
    pub fn report_delivery(&self) -> f64 {
        ratio(self.reports_delivered, self.reports)
    }
}

fn ratio(a: usize, b: usize) -> f64 {
    if b == 0 {
        1.0
    } else {
        a as f64 / b as f64
    }
}

/// Counts `log`'s traffic of one testbed: the beacons of `anchors` (nodes, any order) on the
/// channels of `sched`/`channels` (testbed channel numbers, hop order) as received by `agent`,
/// the reports of `agent` as received by `sink`, and the timeline of the beacons' sequence
/// numbers. Only packets starting at or after `from_cycle` count. Anything else on air (other
/// testbeds, other agents) counts only in [`Traffic::collisions`] when it is from these nodes.
/// Assumes fewer than 2¹⁵ superframes in the window (sequence numbers are 16 bits).
pub fn traffic(
    log: &[TxRecord],
    anchors: &[NodeId],
    agent: NodeId,
    sink: NodeId,
    sched: &Schedule,
    channels: &[u8],
    from_cycle: u64,
) -> Traffic {
    let mut t = Traffic::default();
    let mut beacons: Vec<LoggedBeacon> = Vec::new();
    let outcome = |r: &TxRecord, node: NodeId| {
        r.receivers
            .iter()
            .find(|x| x.node == node)
            .map(|x| x.outcome)
    };
    for r in log.iter().filter(|r| r.tx.start_cycle >= from_cycle) {
        let ours = r.from == agent || anchors.contains(&r.from);
        if ours && r.collided {
            t.collisions += 1;
        }
        if anchors.contains(&r.from) {
            let Ok(b) = Beacon::decode(&r.tx.payload) else {
                continue;
            };
            t.beacons += 1;
            match outcome(r, agent) {
                Some(Outcome::Delivered) => t.beacons_delivered += 1,
                // A broadcast is never a duplicate.
                Some(Outcome::Filtered | Outcome::Duplicate) => t.beacons_filtered += 1,
                Some(Outcome::Busy) => t.beacons_busy += 1,
                Some(Outcome::TooWeak) => t.beacons_too_weak += 1,
                Some(Outcome::Collided) => t.beacons_collided += 1,
                None => t.beacons_unheard += 1,
            }
            if let Some(ch) = channels.iter().position(|&c| c == b.channel) {
                beacons.push(LoggedBeacon {
                    seq: b.seq,
                    anchor: b.anchor,
                    channel: ch as u8,
                    start_cycle: r.tx.start_cycle,
                });
            }
        } else if r.from == agent && Report::decode(&r.tx.payload).is_ok() {
            if r.tx.mac.attempt == 0 {
                t.reports += 1;
            } else {
                t.report_retries += 1;
            }
            if outcome(r, sink) == Some(Outcome::Delivered) {
                t.reports_delivered += 1;
            }
        }
    }
    check_timeline(&mut t, &beacons, sched);
    t
}

/// The timeline part of [`traffic`]: slots used once each, and the spread around the schedule.
fn check_timeline(t: &mut Traffic, beacons: &[LoggedBeacon], sched: &Schedule) {
    use std::collections::BTreeMap;
    let Some(first) = beacons.first() else {
        return;
    };
    // Sequence numbers relative to the first beacon's (wrapping), so a wrap is no gap.
    let rel = |seq: u16| seq.wrapping_sub(first.seq) as i16 as i64;
    let mut by_seq: BTreeMap<i64, Vec<&LoggedBeacon>> = BTreeMap::new();
    for b in beacons {
        by_seq.entry(rel(b.seq)).or_default().push(b);
    }
    let (lo, hi) = match (by_seq.keys().next(), by_seq.keys().next_back()) {
        (Some(&lo), Some(&hi)) => (lo, hi),
        _ => return,
    };
    let cycles_per_us = ms_to_cycles(1.0) as f64 / 1000.0;
    for seq in lo + 1..hi {
        t.superframes += 1;
        let got = by_seq.get(&seq).map_or(&[][..], |v| v.as_slice());
        let mut starts: Vec<f64> = Vec::new();
        for ch in 0..sched.channels() {
            for anchor in 1..=sched.anchors() {
                let n = got
                    .iter()
                    .filter(|b| b.channel == ch && b.anchor == anchor)
                    .count();
                if n == 0 {
                    t.missing_slots += 1;
                }
                t.duplicate_slots += n.saturating_sub(1);
            }
        }
        for b in got {
            if let Some(at) = sched.beacon_at_us(b.channel, b.anchor) {
                starts.push(b.start_cycle as f64 / cycles_per_us - f64::from(at));
            }
        }
        let (min, max) = starts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        if max >= min {
            t.worst_spread_us = t.worst_spread_us.max(max - min);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use simavr::network::RxRecord;
    use simavr::xbee::{Address, MacFields, Transmission};

    const ANCHORS: [NodeId; 4] = [0, 1, 2, 3];
    const AGENT: NodeId = 4;
    const SINK: NodeId = 5;
    const CHANNELS: [u8; 2] = [1, 12];

    fn sched() -> Schedule {
        Schedule::new(4, 2, 20_000, 2, 20_000, 3_000).unwrap()
    }

    fn us(t: f64) -> u64 {
        (t * ms_to_cycles(1.0) as f64 / 1000.0).round() as u64
    }

    /// A packet from `from` at `start_us` with `payload`, received by the agent and the sink
    /// as given, the rest filtered.
    fn record(
        from: NodeId,
        start_us: f64,
        payload: Vec<u8>,
        agent: Option<Outcome>,
        sink: Outcome,
    ) -> TxRecord {
        let receivers = (0..6)
            .filter(|&n| n != from)
            .filter_map(|n| {
                let outcome = match n {
                    AGENT => agent?,
                    SINK => sink,
                    _ => Outcome::Filtered,
                };
                Some(RxRecord {
                    node: n,
                    rssi_dbm: -60,
                    outcome,
                })
            })
            .collect();
        TxRecord {
            seq: 0,
            from,
            tx: Transmission {
                channel: 0x0B,
                pan_id: 0x3332,
                source: Address::Short(0),
                source64: 0,
                dest: Address::Short(0xFFFF),
                options: 0,
                payload,
                start_cycle: us(start_us),
                end_cycle: us(start_us + 1500.0),
                frame_id: 0,
                mac: MacFields::default(),
                power_db: 0,
            },
            collided: agent == Some(Outcome::Collided),
            receivers,
        }
    }

    fn beacon(anchor: u8, seq: u16, channel: u8) -> Vec<u8> {
        let b = Beacon {
            anchor,
            seq,
            channel,
            position: Position { x: 0, y: 0 },
            relay: loc_proto::msg::Relay::from_slice(&[0; 4]).unwrap(),
        };
        let mut buf = [0; 64];
        let n = b.encode(&mut buf).unwrap();
        buf[..n].to_vec()
    }

    fn report(seq: u16) -> Vec<u8> {
        let r = Report::new(1, seq, 4, ChannelList::new(&CHANNELS).unwrap());
        let mut buf = [0; 128];
        let n = r.encode(&mut buf).unwrap();
        buf[..n].to_vec()
    }

    /// Five superframes (sequence numbers 65534 … 2, across the wrap) of 4 anchors × 2
    /// channels and one report each, with known faults; before them a superframe that
    /// `from_cycle` leaves out.
    fn log() -> Vec<TxRecord> {
        let s = sched();
        let sf = f64::from(s.superframe_us());
        let mut log = Vec::new();
        // Left out: before the window.
        for a in 1..=4u8 {
            log.push(record(
                ANCHORS[a as usize - 1],
                f64::from(s.beacon_at_us(0, a).unwrap()),
                beacon(a, 65533, 1),
                Some(Outcome::TooWeak),
                Outcome::Filtered,
            ));
        }
        for k in 0..5u16 {
            let seq = 65534u16.wrapping_add(k);
            let t0 = sf * f64::from(k + 1);
            for (ch, &channel) in CHANNELS.iter().enumerate() {
                for a in 1..=4u8 {
                    // Superframe 0 (whole: the third checked) misses anchor 3 on channel 1.
                    if seq == 0 && ch == 0 && a == 3 {
                        continue;
                    }
                    let late = if a == 1 { 0.0 } else { 500.0 };
                    let at = t0 + f64::from(s.beacon_at_us(ch as u8, a).unwrap()) + late;
                    let agent = match (k, ch, a) {
                        (1, 1, 2) => Outcome::Filtered,
                        (2, 0, 4) => Outcome::Busy,
                        (3, 1, 1) => Outcome::Collided,
                        _ => Outcome::Delivered,
                    };
                    let from = ANCHORS[a as usize - 1];
                    log.push(record(
                        from,
                        at,
                        beacon(a, seq, channel),
                        Some(agent),
                        Outcome::Filtered,
                    ));
                }
            }
            // Superframe 1 (checked) has anchor 2's channel-12 beacon twice, 800 µs off.
            if seq == 1 {
                let at = t0 + f64::from(s.beacon_at_us(1, 2).unwrap()) + 800.0;
                log.push(record(
                    1,
                    at,
                    beacon(2, seq, 12),
                    Some(Outcome::Delivered),
                    Outcome::Filtered,
                ));
            }
            let sink = if k == 4 {
                Outcome::TooWeak
            } else {
                Outcome::Delivered
            };
            let at = t0 + f64::from(s.report_at_us(1).unwrap());
            log.push(record(AGENT, at, report(seq), None, sink));
            // Superframe 1's report again: its ACK was lost, the sink's radio had it already.
            if seq == 1 {
                let mut retry = record(AGENT, at + 3000.0, report(seq), None, Outcome::Duplicate);
                retry.tx.mac.attempt = 1;
                log.push(retry);
            }
        }
        // Another testbed's collided packet: not ours.
        let mut other = record(
            6,
            sf * 3.0,
            vec![1, 2, 3],
            Some(Outcome::Collided),
            Outcome::Filtered,
        );
        other.collided = true;
        log.push(other);
        log
    }

    #[test]
    fn traffic_counts_a_synthetic_log() {
        let s = sched();
        let from = us(f64::from(s.superframe_us()) - 1.0);
        let t = traffic(&log(), &ANCHORS, AGENT, SINK, &s, &CHANNELS, from);
        // 5 × 8 beacons, one missing, one doubled.
        assert_eq!(t.beacons, 40);
        assert_eq!(t.beacons_delivered, 37);
        assert_eq!(
            (t.beacons_filtered, t.beacons_busy, t.beacons_collided),
            (1, 1, 1)
        );
        assert_eq!((t.beacons_too_weak, t.beacons_unheard), (0, 0));
        assert_eq!((t.reports, t.reports_delivered), (5, 4));
        assert_eq!(t.report_retries, 1, "the retry is no other report");
        assert_eq!(
            t.collisions, 1,
            "the other testbed's collision is not counted"
        );
        // Sequence numbers 65534 … 2: 65535, 0 and 1 are whole superframes.
        assert_eq!(t.superframes, 3);
        assert_eq!((t.missing_slots, t.duplicate_slots), (1, 1));
        assert!(
            (t.worst_spread_us - 800.0).abs() < 0.1,
            "{}",
            t.worst_spread_us
        );
        assert!((t.beacon_delivery() - 37.0 / 40.0).abs() < 1e-12);
        assert!((t.report_delivery() - 0.8).abs() < 1e-12);
    }

    #[test]
    fn an_agent_missing_from_the_receivers_is_counted_as_unheard() {
        let s = sched();
        let mut log = log();
        for r in &mut log {
            r.receivers.retain(|x| x.node != AGENT);
        }
        let t = traffic(&log, &ANCHORS, AGENT, SINK, &s, &CHANNELS, 0);
        assert_eq!(t.beacons, 44);
        assert_eq!((t.beacons_delivered, t.beacons_unheard), (0, 44));
        assert_eq!(t.beacon_delivery(), 0.0);
        // One more whole superframe now (65534), and the spread of the early one (0) counts.
        assert_eq!(t.superframes, 4);
    }

    #[test]
    fn an_empty_log_is_no_traffic() {
        let t = traffic(&[], &ANCHORS, AGENT, SINK, &sched(), &CHANNELS, 0);
        assert_eq!(t, Traffic::default());
        assert_eq!((t.beacon_delivery(), t.report_delivery()), (1.0, 1.0));
    }
}
