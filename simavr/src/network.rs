//! The emulated testbed: N nodes, each a firmware ELF in simavr ([`Avr`]) on a modelled XBee
//! ([`XBee`]), or a bare radio the host drives ([`XBeeCore`], e.g. a PC's XBee or a test's),
//! on one radio [`Medium`].
//!
//! # Lockstep
//!
//! Every node keeps its own simulated clock; [`Network`] advances them together in quanta of at
//! most [`MAX_QUANTUM`] cycles: the shortest time from a radio's decision to send a packet (its
//! clear channel assessment, or the request for a radio that does not sense the channel) to the
//! packet's end, 0.928 ms (the CCA, the turnaround and an empty payload's frame). After each
//! quantum it takes the packets every radio put on air and hands them to the medium, then
//! judges the radios' pending CCAs ([`XBeeCore::pending_cca`]) up to the boundary, earliest
//! first, against the packets on air, handing over each verdict's packet before the next CCA
//! is judged: a radio defers to one that found the channel clear a moment before it. A packet
//! is thus known before any node simulates past its end. The next quantum boundary is also
//! never later than the end of the earliest packet still on air, nor than where a radio's MAC
//! next needs a verdict it is known to wait for ([`XBeeCore::mac_due`]: a pending CCA's end, an
//! ACK wait's end). So when the network stops at a packet's end every packet that starts before
//! that end is known too (collisions are decided exactly, see [`crate::medium`]) and no
//! receiver has passed it: the medium's verdicts are delivered at the packet's exact end cycle
//! (an [`Avr`] may end a run one instruction past its target, so at most a few cycles late),
//! and the ACKs they bring are on the medium before anything can overlap them.
//!
//! A CCA of a request that came within the current quantum is judged at the quantum's end,
//! after its time but with everything it could have detected known: a packet radiates only a
//! turnaround after the CCA that let it on air, so every packet on air during a CCA was
//! decided, and its request made, before the CCA began. The radio waits for the verdict
//! meanwhile (its packet, if any, starts a turnaround after the CCA whatever the radio's clock
//! says); only a CCA failure whose five assessments all fall in that quantum has its TX status
//! late, by under 0.3 ms.
//!
//! # Threads
//!
//! Within a quantum the nodes do not interact, so they are stepped in parallel
//! ([`NetworkConfig::threads`]; each [`Avr`] is `Send`): worker threads live for the whole of a
//! [`Network::run_until`] call, take nodes from a shared counter, and meet the main thread at a
//! barrier (spinning briefly, then sleeping) twice per quantum. Everything between quanta (the medium, deliveries, the log) runs on
//! the main thread in node order, so results are identical for any number of threads.
//!
//! # Power
//!
//! [`Network::kill`] powers a node off at the current cycle: it stops (its simulation is no
//! longer stepped), its packets not yet on air are dropped (one already on air completes), and
//! it hears nothing. [`Network::revive`] powers it on again: the firmware boots from scratch
//! with the EEPROM it had, and the radio comes up with the settings it last saved (`WR`).
//!
//! # UART noise
//!
//! [`NetworkConfig::uart_error_rate`] flips one random bit of a byte with that probability on
//! every firmware↔radio UART, in both directions (seeded per node from
//! [`NetworkConfig::seed`]; see [`XBee::set_line_errors`]).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex};

use crate::avr::{cycles_to_ms, ms_to_cycles, Avr, Error, State};
use crate::medium::{Heard, Medium, NodeRadio};
use crate::radio::TextLine;
use crate::xbee::Security;
use crate::xbee::{time_on_air_ms, FrameKind, Transmission, XBee, XBeeConfig, XBeeCore, CCA_US};

/// The longest quantum: the shortest time from a radio's decision to send to its packet's end (a
/// CCA, the turnaround, an empty payload's frame), 14 848 cycles.
pub const MAX_QUANTUM: u64 = 14_848;

// The quantum argument above relies on it.
const _: () = assert!(MAX_QUANTUM == (0.928 * 16_000.0) as u64);

/// A node's index in its [`Network`] (and its [`Medium`]), in the order nodes were added.
pub type NodeId = usize;

/// How a node is set up.
#[derive(Clone, Debug)]
pub struct NodeSpec {
    /// A name for reports.
    pub name: String,
    /// Position, antenna, drift.
    pub radio: NodeRadio,
    /// How its XBee starts (the testbed's nodes: [`XBeeConfig::api`]`(2)`).
    pub xbee: XBeeConfig,
    /// EEPROM contents written from address 0 before the first boot (empty: erased, 0xFF).
    pub eeprom: Vec<u8>,
}

impl NodeSpec {
    /// A node named `name` placed as `radio`, with an XBee in API mode 2 at 57600 baud.
    pub fn new(name: impl Into<String>, radio: NodeRadio) -> Self {
        NodeSpec {
            name: name.into(),
            radio,
            xbee: XBeeConfig::api(2),
            eeprom: Vec::new(),
        }
    }
}

/// How the network runs.
#[derive(Clone, Debug, PartialEq)]
pub struct NetworkConfig {
    /// Quantum, cycles (clamped to 1…[`MAX_QUANTUM`]).
    pub quantum: u64,
    /// Threads stepping the nodes (1: the calling thread only).
    pub threads: usize,
    /// Probability that a byte on a firmware↔radio UART has one bit flipped (0: none).
    pub uart_error_rate: f64,
    /// Seed of the UART noise.
    pub seed: u64,
}

impl Default for NetworkConfig {
    /// [`MAX_QUANTUM`], as many threads as the machine has cores, no UART noise.
    fn default() -> Self {
        NetworkConfig {
            quantum: MAX_QUANTUM,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            uart_error_rate: 0.0,
            seed: 1,
        }
    }
}

/// What became of a packet at one receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Outcome {
    /// Its radio passed it to the host (an RX frame).
    Delivered,
    /// Heard, but its radio dropped it: another channel, PAN or address, encrypted at one end
    /// only (the two radios' `EE` differ; the receiver counts those apart, in
    /// [`crate::xbee::XBeeStats::encryption_mismatch`]), or its receiver was off: asleep,
    /// looking for a coordinator, switching channel (counted apart too).
    Filtered,
    /// Heard, but its radio lost it: it was transmitting (half duplex) or in command mode.
    Busy,
    /// Heard (a unicast: and acknowledged), but not passed on: a copy of a packet its radio had
    /// passed on already (duplicate detection): a retry whose ACK had been lost, or a repeated
    /// broadcast's copy (`RR` > 0).
    Duplicate,
    /// Below sensitivity.
    TooWeak,
    /// Lost in a collision.
    Collided,
}

/// One receiver of a logged packet. For an ACK, [`Outcome::Delivered`] is the radio that waited
/// for it and took it; [`Outcome::Filtered`] one that did not wait for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RxRecord {
    /// The receiver.
    pub node: NodeId,
    /// The level at the receiver, integer dBm.
    pub rssi_dbm: i16,
    /// What became of it.
    pub outcome: Outcome,
}

/// A packet that went on air, and its fate: a data frame (each transmission of a TX request
/// apart: [`crate::xbee::MacFields::attempt`] counts them) or an ACK
/// ([`crate::xbee::MacFields::kind`]).
#[derive(Clone, Debug, PartialEq)]
pub struct TxRecord {
    /// The medium's sequence number.
    pub seq: u64,
    /// The sender.
    pub from: NodeId,
    /// The packet (cycles on the network's clock).
    pub tx: Transmission,
    /// Lost to a collision at every receiver.
    pub collided: bool,
    /// Every powered node but the sender, in id order.
    pub receivers: Vec<RxRecord>,
}

impl TxRecord {
    /// The receivers whose radio passed the packet to the host, with the RSSI.
    pub fn delivered(&self) -> impl Iterator<Item = (NodeId, i16)> + '_ {
        self.receivers
            .iter()
            .filter(|r| r.outcome == Outcome::Delivered)
            .map(|r| (r.node, r.rssi_dbm))
    }
}

enum Body {
    Firmware {
        avr: Box<Avr>,
        radio: Box<XBee>,
        elf: PathBuf,
    },
    Host(Box<XBeeCore>),
}

struct Node {
    spec: NodeSpec,
    body: Body,
    /// Network cycle = local cycle + offset (a revived firmware starts again at local 0).
    offset: u64,
    powered: bool,
    state: State,
    /// Lines of earlier lives (network cycles).
    old_lines: Vec<TextLine>,
    /// Times revived.
    lives: u64,
}

impl Node {
    /// Runs the node up to network cycle `target`.
    fn step(&mut self, target: u64) {
        if !self.powered {
            return;
        }
        let local = target.saturating_sub(self.offset);
        match &mut self.body {
            Body::Firmware { avr, radio, .. } => {
                if self.state.is_alive() {
                    self.state = radio.run_until(avr, local);
                }
            }
            Body::Host(core) => core.advance(local),
        }
    }

    fn core(&self) -> &XBeeCore {
        match &self.body {
            Body::Firmware { radio, .. } => radio.core(),
            Body::Host(core) => core,
        }
    }

    fn core_mut(&mut self) -> &mut XBeeCore {
        match &mut self.body {
            Body::Firmware { radio, .. } => radio.core_mut(),
            Body::Host(core) => core,
        }
    }

    /// The text lines from the `from`-th on (earlier power cycles' first).
    fn lines_from(&self, from: usize) -> Vec<TextLine> {
        let current: &[TextLine] = match &self.body {
            Body::Firmware { radio, .. } => radio.text_lines(),
            _ => &[],
        };
        let old = self.old_lines.get(from..).unwrap_or(&[]);
        let skip = from.saturating_sub(self.old_lines.len());
        old.iter()
            .cloned()
            .chain(current.iter().skip(skip).map(|l| TextLine {
                cycle: l.cycle + self.offset,
                text: l.text.clone(),
            }))
            .collect()
    }
}

/// The emulated testbed (see the module docs).
pub struct Network {
    cfg: NetworkConfig,
    medium: Medium,
    nodes: Vec<Node>,
    now: u64,
    log: Vec<TxRecord>,
    quanta: u64,
}

impl Network {
    /// An empty network on `medium` (whose nodes it must not already have), default config.
    pub fn new(medium: Medium) -> Self {
        Self::with_config(medium, NetworkConfig::default())
    }

    /// An empty network on `medium` run as `cfg` says.
    pub fn with_config(medium: Medium, cfg: NetworkConfig) -> Self {
        assert!(medium.is_empty(), "the network adds the medium's nodes");
        Network {
            cfg,
            medium,
            nodes: Vec::new(),
            now: 0,
            log: Vec::new(),
            quanta: 0,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &NetworkConfig {
        &self.cfg
    }

    /// Sets the number of stepping threads (results do not depend on it).
    pub fn set_threads(&mut self, threads: usize) {
        self.cfg.threads = threads.max(1);
    }

    /// Adds a node running the firmware `elf`, powered up at the current cycle.
    pub fn add_node(&mut self, elf: impl AsRef<Path>, spec: NodeSpec) -> Result<NodeId, Error> {
        let elf = elf.as_ref().to_path_buf();
        let id = self.nodes.len();
        let mut avr = Avr::load(&elf)?;
        if !spec.eeprom.is_empty() {
            avr.eeprom_write(0, &spec.eeprom)?;
        }
        let mut radio = XBee::new(spec.xbee.clone());
        if let Some((rate, seed)) = self.noise(id, 0) {
            radio.set_line_errors(rate, seed);
        }
        self.push(
            spec,
            Body::Firmware {
                avr: Box::new(avr),
                radio: Box::new(radio),
                elf,
            },
        );
        Ok(id)
    }

    /// Adds a bare radio that the host drives through [`Network::core_mut`] (bytes in with
    /// [`XBeeCore::rx_bytes`], RX frames out with [`XBeeCore::take_output`]), powered up now.
    pub fn add_host_radio(&mut self, spec: NodeSpec) -> NodeId {
        let core = XBeeCore::new_at(spec.xbee.clone(), self.now);
        self.push(spec, Body::Host(Box::new(core)))
    }

    fn push(&mut self, spec: NodeSpec, body: Body) -> NodeId {
        let id = self.medium.add_node(spec.radio);
        debug_assert_eq!(id, self.nodes.len());
        let offset = match body {
            Body::Firmware { .. } => self.now,
            Body::Host(_) => 0,
        };
        let mut node = Node {
            spec,
            body,
            offset,
            powered: true,
            state: State::Running,
            old_lines: Vec::new(),
            lives: 0,
        };
        node.core_mut().set_on_medium(true);
        self.nodes.push(node);
        id
    }

    /// The UART noise of node `id` in its `life`-th life, if any: (rate, seed).
    fn noise(&self, id: NodeId, life: u64) -> Option<(f64, u64)> {
        (self.cfg.uart_error_rate > 0.0).then(|| {
            let seed = self.cfg.seed
                ^ (id as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15)
                ^ life.wrapping_mul(0xD1B5_4A32_D192_ED03);
            (self.cfg.uart_error_rate, seed)
        })
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// True without nodes.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The network's clock, cycles (every powered node has simulated at least this far).
    pub fn cycle(&self) -> u64 {
        self.now
    }

    /// The network's clock, ms.
    pub fn time_ms(&self) -> f64 {
        cycles_to_ms(self.now)
    }

    /// Quanta run so far.
    pub fn quanta(&self) -> u64 {
        self.quanta
    }

    /// The medium.
    pub fn medium(&self) -> &Medium {
        &self.medium
    }

    /// The medium, mutably (move a node, start a drift…).
    pub fn medium_mut(&mut self) -> &mut Medium {
        &mut self.medium
    }

    /// A node's spec.
    pub fn spec(&self, id: NodeId) -> &NodeSpec {
        &self.nodes[id].spec
    }

    /// A node's firmware and radio (`None` for a host radio).
    pub fn firmware(&self, id: NodeId) -> Option<(&Avr, &XBee)> {
        match &self.nodes[id].body {
            Body::Firmware { avr, radio, .. } => Some((avr, radio)),
            Body::Host(_) => None,
        }
    }

    /// A node's firmware and radio, mutably (`None` for a host radio). Their cycles are the
    /// node's own: network cycle − [`Network::offset`].
    pub fn firmware_mut(&mut self, id: NodeId) -> Option<(&mut Avr, &mut XBee)> {
        match &mut self.nodes[id].body {
            Body::Firmware { avr, radio, .. } => Some((avr, radio)),
            Body::Host(_) => None,
        }
    }

    /// A node's radio model.
    pub fn core(&self, id: NodeId) -> &XBeeCore {
        self.nodes[id].core()
    }

    /// A node's radio model, mutably (e.g. to feed a host radio bytes).
    pub fn core_mut(&mut self, id: NodeId) -> &mut XBeeCore {
        self.nodes[id].core_mut()
    }

    /// Network cycle of a node's local cycle 0 (0 unless it was added late or revived).
    pub fn offset(&self, id: NodeId) -> u64 {
        self.nodes[id].offset
    }

    /// Whether a node is powered.
    pub fn is_powered(&self, id: NodeId) -> bool {
        self.nodes[id].powered
    }

    /// A firmware node's simulation state (host radios: always running).
    pub fn state(&self, id: NodeId) -> State {
        self.nodes[id].state
    }

    /// The text lines a node's firmware wrote, over all its lives, on the network's clock.
    pub fn lines(&self, id: NodeId) -> Vec<TextLine> {
        self.nodes[id].lines_from(0)
    }

    /// [`Network::lines`] from the `from`-th line on (for a reader that has taken the first
    /// `from` already: no copy of those).
    pub fn lines_from(&self, id: NodeId, from: usize) -> Vec<TextLine> {
        self.nodes[id].lines_from(from)
    }

    /// Every packet resolved so far, in order of end.
    pub fn log(&self) -> &[TxRecord] {
        &self.log
    }

    /// Takes the log (long runs).
    pub fn take_log(&mut self) -> Vec<TxRecord> {
        std::mem::take(&mut self.log)
    }

    /// Powers a node off now (see the module docs).
    pub fn kill(&mut self, id: NodeId) {
        let node = &mut self.nodes[id];
        if !node.powered {
            return;
        }
        node.powered = false;
        self.medium.cancel_from(id, self.now);
    }

    /// Powers a node on again now: the firmware boots afresh with its EEPROM, the radio with
    /// its saved settings. Fails if the ELF cannot be loaded again.
    pub fn revive(&mut self, id: NodeId) -> Result<(), Error> {
        let now = self.now;
        if self.nodes[id].powered {
            return Ok(());
        }
        self.nodes[id].lives += 1;
        let noise = self.noise(id, self.nodes[id].lives);
        let node = &mut self.nodes[id];
        let lines = node.lines_from(0);
        match &mut node.body {
            Body::Firmware { avr, radio, elf } => {
                let mut fresh = Avr::load(&*elf)?;
                let eeprom = avr.eeprom_read(0, avr.eeprom_size())?;
                fresh.eeprom_write(0, &eeprom)?;
                let mut cfg = radio.core().config().clone();
                let saved = radio.core().persisted();
                cfg.ap = saved.ap();
                cfg.bd = saved.bd();
                cfg.my = saved.my();
                cfg.ch = saved.ch();
                cfg.id = saved.id();
                cfg.gt_ms = saved.gt();
                cfg.ct = saved.ct();
                cfg.ni = String::from_utf8_lossy(saved.ni()).into_owned();
                cfg.ee = saved.ee();
                cfg.ky = saved.ky();
                cfg.rn = saved.rn();
                cfg.ca = saved.ca();
                cfg.rr = saved.rr();
                cfg.mm = saved.mm();
                let mut fresh_radio = XBee::new(cfg);
                fresh_radio.core_mut().set_on_medium(true);
                if let Some((rate, seed)) = noise {
                    fresh_radio.set_line_errors(rate, seed);
                }
                **avr = fresh;
                **radio = fresh_radio;
                node.old_lines = lines;
                node.offset = now;
                node.state = State::Running;
            }
            Body::Host(core) => core.reset(now.max(core.now())),
        }
        node.powered = true;
        Ok(())
    }

    /// Runs for `ms` more milliseconds.
    pub fn run_for_ms(&mut self, ms: f64) {
        self.run_until(self.now + ms_to_cycles(ms));
    }

    /// Runs every node up to network cycle `target`.
    pub fn run_until(&mut self, target: u64) {
        self.run_while(target, |_| true);
    }

    /// Runs until `stop` is true of the network (checked after every quantum) or cycle
    /// `limit`; returns whether `stop` became true.
    pub fn run_until_pred(&mut self, limit: u64, mut stop: impl FnMut(&Network) -> bool) -> bool {
        if stop(self) {
            return true;
        }
        let mut hit = false;
        self.run_while(limit, |net| {
            hit = stop(net);
            !hit
        });
        hit
    }

    /// The next quantum boundary on the way to `target`: at most a quantum on, at the end of
    /// the first packet on air, and where a radio's MAC next needs the medium's verdict
    /// ([`XBeeCore::mac_due`]).
    fn next_boundary(&self, target: u64) -> u64 {
        let q = self.cfg.quantum.clamp(1, MAX_QUANTUM);
        let mut next = (self.now + q).min(target);
        if let Some(e) = self.medium.next_end() {
            next = next.min(e.max(self.now + 1));
        }
        for n in self.nodes.iter().filter(|n| n.powered) {
            if let Some(d) = n.core().mac_due() {
                next = next.min((d + n.offset).max(self.now + 1));
            }
        }
        next
    }

    fn run_while(&mut self, target: u64, mut go_on: impl FnMut(&Network) -> bool) {
        let threads = self.cfg.threads.clamp(1, self.nodes.len().max(1));
        if threads == 1 {
            while self.now < target {
                let next = self.next_boundary(target);
                for n in &mut self.nodes {
                    n.step(next);
                }
                self.finish_quantum(next);
                if !go_on(self) {
                    break;
                }
            }
            return;
        }
        // The nodes go into slots for the workers during a quantum and come back for the
        // exchange (moves of boxes: cheap), so between quanta the network is whole.
        const STOP: u64 = u64::MAX;
        let slots: Vec<Mutex<Option<Node>>> =
            (0..self.nodes.len()).map(|_| Mutex::new(None)).collect();
        let goal = AtomicU64::new(STOP);
        let cursor = AtomicUsize::new(0);
        let barrier = SpinBarrier::new(threads);
        let lock = |i: usize| slots[i].lock().unwrap_or_else(|e| e.into_inner());
        let work = |t: u64| loop {
            let i = cursor.fetch_add(1, Ordering::Relaxed);
            if i >= slots.len() {
                break;
            }
            if let Some(n) = lock(i).as_mut() {
                n.step(t);
            }
        };
        std::thread::scope(|s| {
            for _ in 1..threads {
                s.spawn(|| loop {
                    barrier.wait();
                    let t = goal.load(Ordering::Acquire);
                    if t == STOP {
                        break;
                    }
                    work(t);
                    barrier.wait();
                });
            }
            while self.now < target {
                let next = self.next_boundary(target);
                for (i, n) in self.nodes.drain(..).enumerate() {
                    *lock(i) = Some(n);
                }
                cursor.store(0, Ordering::Relaxed);
                goal.store(next, Ordering::Release);
                barrier.wait();
                work(next);
                barrier.wait();
                for i in 0..slots.len() {
                    self.nodes.extend(lock(i).take());
                }
                self.finish_quantum(next);
                if !go_on(self) {
                    break;
                }
            }
            goal.store(STOP, Ordering::Release);
            barrier.wait();
        });
    }

    /// Single-threaded end of a quantum.
    fn finish_quantum(&mut self, next: u64) {
        let mut nodes = std::mem::take(&mut self.nodes);
        let mut refs: Vec<&mut Node> = nodes.iter_mut().collect();
        self.exchange(&mut refs, next);
        drop(refs);
        self.nodes = nodes;
    }

    /// Between quanta: every node is at `now`. Hand the new packets to the medium, judge the
    /// clear channel assessments up to `now` in time order (each verdict's packet handed over
    /// before the next is judged), then deliver what ended and hand over the ACKs it brought.
    fn exchange(&mut self, nodes: &mut [&mut Node], now: u64) {
        self.now = now;
        self.quanta += 1;
        for (id, node) in nodes.iter_mut().enumerate() {
            if node.powered {
                self.hand_over(id, node);
            }
        }
        self.judge_ccas(nodes, now);
        if self.medium.next_end().is_none_or(|e| e > now) {
            return;
        }
        let powered: Vec<bool> = nodes.iter().map(|n| n.powered).collect();
        for r in self.medium.resolve(now, |n| powered[n]) {
            let receivers = r
                .receptions
                .iter()
                .map(|rx| {
                    let outcome = match rx.heard {
                        Heard::TooWeak => Outcome::TooWeak,
                        Heard::Collided => Outcome::Collided,
                        Heard::Yes => {
                            Self::receive(&mut *nodes[rx.node], &r.tx, rx.rssi_dbm, r.security)
                        }
                    };
                    RxRecord {
                        node: rx.node,
                        rssi_dbm: rx.rssi_dbm,
                        outcome,
                    }
                })
                .collect();
            self.log.push(TxRecord {
                seq: r.seq,
                from: r.from,
                tx: r.tx,
                collided: r.collided,
                receivers,
            });
        }
        // The ACKs of what was delivered.
        for (id, node) in nodes.iter_mut().enumerate() {
            if node.powered {
                self.hand_over(id, node);
            }
        }
    }

    /// Hands the packets node `id` put on air to the medium, on the network's clock.
    fn hand_over(&mut self, id: NodeId, node: &mut Node) {
        let offset = node.offset;
        for (mut tx, security) in node.core_mut().take_transmissions_with_security() {
            tx.start_cycle += offset;
            tx.end_cycle += offset;
            self.medium.transmit_secured(id, tx, security);
        }
    }

    /// Judges every pending CCA that starts by `now`, earliest first (ties: lower node id),
    /// against the packets on air, so that each radio sees the packets of the radios that
    /// found the channel clear before it.
    fn judge_ccas(&mut self, nodes: &mut [&mut Node], now: u64) {
        let cca = ms_to_cycles(CCA_US as f64 / 1000.0);
        loop {
            let next = nodes
                .iter()
                .enumerate()
                .filter(|(_, n)| n.powered)
                .filter_map(|(id, n)| n.core().pending_cca().map(|c| (c.at + n.offset, id, c)))
                .filter(|&(at, ..)| at <= now)
                .min_by_key(|&(at, id, _)| (at, id));
            let Some((at, id, c)) = next else {
                return;
            };
            let busy = self
                .medium
                .channel_busy(id, c.channel, at, at + cca, c.threshold_dbm);
            nodes[id].core_mut().judge_cca(busy);
            self.hand_over(id, &mut *nodes[id]);
        }
    }

    /// Hands `tx` (network cycles) to `node`'s radio at its end and says what became of it.
    fn receive(node: &mut Node, tx: &Transmission, rssi_dbm: i16, security: Security) -> Outcome {
        let offset = node.offset;
        let core = node.core_mut();
        let before = core.stats();
        if offset == 0 {
            core.receive(tx, rssi_dbm, security);
        } else {
            let mut local = tx.clone();
            local.start_cycle = local.start_cycle.saturating_sub(offset);
            local.end_cycle = local.end_cycle.saturating_sub(offset);
            core.receive(&local, rssi_dbm, security);
        }
        let at = tx.end_cycle.saturating_sub(offset);
        core.advance(core.now().max(at));
        let after = core.stats();
        let lost = after.rx_lost > before.rx_lost;
        match tx.mac.kind {
            FrameKind::Data if after.rx_delivered > before.rx_delivered => Outcome::Delivered,
            FrameKind::Data if after.rx_duplicates > before.rx_duplicates => Outcome::Duplicate,
            FrameKind::Ack if after.acks_received > before.acks_received => Outcome::Delivered,
            _ if lost => Outcome::Busy,
            _ => Outcome::Filtered,
        }
    }
}

/// A barrier for the short waits between quanta: spins a little (a quantum's work is tens of
/// microseconds, a futex wake-up costs several), then sleeps on a condition variable (so a busy
/// machine does not lose a core to spinning).
struct SpinBarrier {
    n: usize,
    count: AtomicUsize,
    generation: AtomicUsize,
    lock: Mutex<()>,
    wake: Condvar,
}

impl SpinBarrier {
    const SPINS: u32 = 4000;

    fn new(n: usize) -> Self {
        SpinBarrier {
            n,
            count: AtomicUsize::new(0),
            generation: AtomicUsize::new(0),
            lock: Mutex::new(()),
            wake: Condvar::new(),
        }
    }

    fn wait(&self) {
        let generation = self.generation.load(Ordering::Acquire);
        if self.count.fetch_add(1, Ordering::AcqRel) + 1 == self.n {
            self.count.store(0, Ordering::Relaxed);
            {
                let _held = self.lock.lock().unwrap_or_else(|e| e.into_inner());
                self.generation.fetch_add(1, Ordering::Release);
            }
            self.wake.notify_all();
            return;
        }
        for _ in 0..Self::SPINS {
            if self.generation.load(Ordering::Acquire) != generation {
                return;
            }
            std::hint::spin_loop();
        }
        let mut held = self.lock.lock().unwrap_or_else(|e| e.into_inner());
        while self.generation.load(Ordering::Acquire) == generation {
            held = self.wake.wait(held).unwrap_or_else(|e| e.into_inner());
        }
    }
}

/// Time on air of a `k`-byte payload in cycles.
pub fn time_on_air_cycles(k: usize) -> u64 {
    ms_to_cycles(time_on_air_ms(k))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::medium::{MediumConfig, NodeRadio};
    use crate::xbee::{encode_frame, TURNAROUND_US};
    use xbee_api::{Decoder, Mode};

    /// A host radio `my` at (x, 0) on channel `ch`, API mode 2.
    fn host(net: &mut Network, my: u16, x: f64, ch: u8) -> NodeId {
        let mut spec = NodeSpec::new(format!("r{my}"), NodeRadio::at(x, 0.0));
        spec.xbee.my = my;
        spec.xbee.ch = ch;
        spec.xbee.sh_sl = 0x0013_A200_0000_0000 + u64::from(my);
        net.add_host_radio(spec)
    }

    /// Feeds `id`'s radio a TX16 broadcast of `payload` starting at the network's cycle;
    /// returns the cycle the frame's last byte ended (the packet goes on air then).
    fn send(net: &mut Network, id: NodeId, payload: &[u8]) -> u64 {
        let mut data = vec![0x01, 0x00, 0xFF, 0xFF, 0x00];
        data.extend_from_slice(payload);
        let bytes = encode_frame(&data, Mode::Escaped);
        let now = net.cycle();
        net.core_mut(id).rx_bytes(now, &bytes)
    }

    /// The frames a host radio put on its UART: (cycle of the first byte, frame data).
    fn frames_out(net: &mut Network, id: NodeId) -> Vec<(u64, Vec<u8>)> {
        let mut dec = Decoder::new(Mode::Escaped);
        let mut out = Vec::new();
        let mut start = 0;
        for b in net.core_mut(id).take_output() {
            if b.byte == xbee_api::START {
                start = b.cycle;
            }
            dec.feed(&[b.byte], |f| out.push((start, f.unwrap().data().to_vec())));
        }
        out
    }

    fn noise_free(threads: usize) -> Network {
        Network::with_config(
            Medium::new(MediumConfig::noise_free()),
            NetworkConfig {
                threads,
                ..NetworkConfig::default()
            },
        )
    }

    #[test]
    fn a_packet_arrives_at_its_end_cycle_with_the_mediums_rssi() {
        for threads in [1, 2] {
            let mut net = noise_free(threads);
            let a = host(&mut net, 1, 0.0, 0x0C);
            let b = host(&mut net, 2, 5.0, 0x0C);
            net.run_for_ms(10.0);
            // Modem status from both radios at power-up.
            assert_eq!(frames_out(&mut net, a).len(), 1);
            assert_eq!(frames_out(&mut net, b).len(), 1);
            let request = send(&mut net, a, b"hello");
            net.run_for_ms(10.0);
            let log = net.log();
            assert_eq!(log.len(), 1);
            let r = &log[0];
            // On air after the CCA time and the turnaround; off the air the best case after
            // the request.
            let start = request + ms_to_cycles((CCA_US + TURNAROUND_US) as f64 / 1000.0);
            let end = request + time_on_air_cycles(5);
            assert_eq!((r.from, r.tx.start_cycle, r.tx.end_cycle), (a, start, end));
            assert!(!r.collided);
            // −40 − 30·log10(5) = −60.97 dBm.
            assert_eq!(
                r.receivers,
                [RxRecord {
                    node: b,
                    rssi_dbm: -61,
                    outcome: Outcome::Delivered
                }]
            );
            let got = frames_out(&mut net, b);
            assert_eq!(got.len(), 1, "{got:?}");
            let (at, data) = &got[0];
            // RX16 from 0x0001, RSSI 61, address broadcast, the payload.
            assert_eq!(data.as_slice(), b"\x81\x00\x01\x3d\x02hello");
            assert_eq!(
                *at,
                end + ms_to_cycles(0.2),
                "rx latency after the exact end"
            );
            assert!(
                frames_out(&mut net, a).is_empty(),
                "no TX status for frame id 0"
            );
        }
    }

    #[test]
    fn overlapping_packets_collide_other_channels_and_out_of_range_do_not_hear() {
        let mut net = noise_free(1);
        let a = host(&mut net, 1, 0.0, 0x0C);
        let b = host(&mut net, 2, 1.0, 0x0C);
        let c = host(&mut net, 3, 2.0, 0x0C);
        let d = host(&mut net, 4, 3.0, 0x0D);
        let far = host(&mut net, 5, 100.0, 0x0C);
        net.run_for_ms(10.0);
        // a and b at once: both collide; then c alone.
        send(&mut net, a, b"one");
        send(&mut net, b, b"two");
        net.run_for_ms(5.0);
        send(&mut net, c, b"three");
        net.run_for_ms(5.0);
        let log = net.log();
        assert_eq!(log.len(), 3);
        for r in &log[..2] {
            assert!(r.collided);
            assert!(r
                .receivers
                .iter()
                .all(|x| matches!(x.outcome, Outcome::Collided | Outcome::TooWeak)));
        }
        let r = &log[2];
        assert!(!r.collided);
        let outcome = |n: NodeId| r.receivers.iter().find(|x| x.node == n).unwrap().outcome;
        assert_eq!(outcome(a), Outcome::Delivered);
        assert_eq!(outcome(b), Outcome::Delivered);
        assert_eq!(outcome(d), Outcome::Filtered, "other channel");
        assert_eq!(outcome(far), Outcome::TooWeak);
        assert_eq!(net.core(d).stats().rx_filtered, 1);
    }

    #[test]
    fn a_killed_radio_neither_sends_nor_hears_until_revived() {
        let mut net = noise_free(2);
        let a = host(&mut net, 1, 0.0, 0x0C);
        let b = host(&mut net, 2, 1.0, 0x0C);
        net.run_for_ms(10.0);
        net.kill(b);
        send(&mut net, a, b"x");
        net.run_for_ms(5.0);
        assert_eq!(net.log().len(), 1);
        assert!(net.log()[0].receivers.is_empty());
        net.revive(b).unwrap();
        net.run_for_ms(10.0);
        send(&mut net, a, b"y");
        net.run_for_ms(5.0);
        assert_eq!(net.log()[1].delivered().collect::<Vec<_>>(), [(b, -40)]);
    }

    /// An encrypted broadcast: delivered unchanged with the same key, garbled with another,
    /// filtered where `EE` differs (counted by the receiver); on air 5 bytes longer. The same
    /// run gives the same bytes, whatever the number of threads.
    #[test]
    fn encryption_decides_who_understands_a_packet() {
        const KEY: [u8; 16] = [0xA5; 16];
        let run = |threads: usize| {
            let mut net = noise_free(threads);
            let keys = [Some(KEY), Some(KEY), Some([0x5A; 16]), None];
            let ids: Vec<NodeId> = (0u16..)
                .zip(keys)
                .map(|(i, key)| {
                    let mut spec = NodeSpec::new(format!("r{i}"), NodeRadio::at(f64::from(i), 0.0));
                    spec.xbee.my = i + 1;
                    spec.xbee.sh_sl = 0x0013_A200_0000_0000 + u64::from(i);
                    spec.xbee.ee = key.is_some();
                    spec.xbee.ky = key.unwrap_or_default();
                    net.add_host_radio(spec)
                })
                .collect();
            net.run_for_ms(10.0);
            for &id in &ids {
                frames_out(&mut net, id);
            }
            let start = send(&mut net, ids[0], b"secret beacon");
            net.run_for_ms(10.0);
            let out: Vec<_> = ids[1..]
                .iter()
                .map(|&id| frames_out(&mut net, id))
                .collect();
            (net.take_log(), out, start, ids, net)
        };
        let (log, out, start, ids, net) = run(1);
        assert_eq!(log.len(), 1);
        let r = &log[0];
        assert_eq!(r.tx.end_cycle, start + time_on_air_cycles(13 + 5));
        assert_eq!(
            r.tx.payload, b"secret beacon",
            "the log keeps the plaintext"
        );
        let outcomes: Vec<Outcome> = r.receivers.iter().map(|x| x.outcome).collect();
        assert_eq!(
            outcomes,
            [Outcome::Delivered, Outcome::Delivered, Outcome::Filtered]
        );
        assert_eq!(out[0].len(), 1);
        assert!(out[0][0].1.ends_with(b"secret beacon"));
        assert_eq!(out[1].len(), 1);
        let garbled = &out[1][0].1;
        assert_eq!(garbled.len(), out[0][0].1.len());
        assert_ne!(garbled[5..], out[0][0].1[5..]);
        assert!(out[2].is_empty());
        let stats = |id: NodeId| net.core(id).stats();
        assert_eq!(stats(ids[2]).rx_wrong_key, 1);
        assert_eq!(stats(ids[3]).encryption_mismatch, 1);
        assert_eq!(stats(ids[3]).rx_filtered, 0);
        let (log2, out2, ..) = run(2);
        assert_eq!((log2, out2), (log, out));
    }

    /// Many radios sending at seeded pseudo-random times (collisions included), with shadowing
    /// and fading: the log is the same for 1, 2 and 3 threads.
    #[test]
    fn results_do_not_depend_on_the_number_of_threads() {
        let run = |threads: usize| {
            let mut net = Network::with_config(
                Medium::new(MediumConfig::default()),
                NetworkConfig {
                    threads,
                    ..NetworkConfig::default()
                },
            );
            let ids: Vec<NodeId> = (0..8)
                .map(|i| host(&mut net, i + 1, f64::from(i) * 3.0, 0x0C + (i % 2) as u8))
                .collect();
            net.run_for_ms(10.0);
            let mut x: u64 = 12345;
            for _ in 0..200 {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                let who = ids[(x % 8) as usize];
                if net.core(who).transmissions().is_empty() {
                    send(&mut net, who, &x.to_le_bytes());
                }
                net.run_for_ms((x >> 8) as f64 % 3.0);
            }
            net.run_for_ms(20.0);
            (net.take_log(), net.cycle())
        };
        let one = run(1);
        assert!(one.0.len() > 150, "{}", one.0.len());
        assert!(one.0.iter().any(|r| r.collided));
        assert!(one.0.iter().any(|r| r.delivered().count() > 0));
        assert_eq!(one, run(2));
        assert_eq!(one, run(3));
    }
}
