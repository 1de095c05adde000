//! The radio medium of the emulated testbed (`docs/design.md`, section 8), sans IO: it is told the
//! packets that go on air ([`Medium::transmit`]) and, once every node has simulated up to a
//! packet's end, says who heard it at which level ([`Medium::resolve`]). It never looks at a clock;
//! time is simulated cycles at [`crate::F_CPU`], as everywhere in this crate. [`crate::network`]
//! drives it with real firmwares.
//!
//! # The model
//!
//! The level a packet from node `a` has at node `b`, in dBm, is
//!
//! ```text
//! P0 + PL_a + drift(t) − 10·α·log10(d / d0) + G_a(θ_ab − φ_a) + G_b(θ_ba − φ_b) + F_ab(ch) + S
//! ```
//!
//! * `P0` ([`MediumConfig::p0_dbm`], −40 dBm) at `d0` = 1 m and the path-loss exponent `α`
//!   ([`MediumConfig::alpha`], 3) are the estimator's log-normal shadowing model
//!   (`docs/design.md`, section 5), for a sender at the factory power level. `d` is the
//!   distance in metres, at least [`MediumConfig::min_distance_m`] (co-located nodes).
//! * `PL_a`: the sender's output power relative to the factory power level, carried by each
//!   packet ([`Transmission::power_db`]: 0 at `PL` 4, −10 dB at an S1's `PL` 0), ACKs
//!   included. [`Medium::mean_level_dbm`] and [`Medium::level_dbm`] leave it out (they are the
//!   link's); [`Medium::packet_level_dbm`] adds it.
//! * `drift(t)`: battery droop lowers the *sender's* TX power linearly in time,
//!   [`MediumConfig::drift_db_per_min`] for every node plus [`NodeRadio::drift_db_per_min`] of
//!   the sender, counted from [`MediumConfig::drift_start_ms`] and taken at the packet's start
//!   (the thesis' experiment 3; negative rates lower the level).
//! * Antenna gains ([`Medium::antenna_gain_db`]): `θ_ab` is the bearing of `b` seen from `a`
//!   (degrees, counter-clockwise from +x), `φ_a` the orientation of `a`. A pattern is a sum of
//!   the first three azimuth harmonics, `G(θ) = Σ a_k·cos(kθ − ψ_k)`, so it has zero mean over
//!   azimuth and `P0` is the azimuth-averaged level. The odd harmonics make the front differ
//!   from the back, the even ones make the pattern differ from its own mirror image: with odd
//!   harmonics alone two antennas pointing the same way would cancel on every link
//!   (`G(θ) + G(θ + 180°) = 0`), which no real antenna pair does. Each kind has a nominal
//!   pattern ([`Antenna::harmonics`]): isotropic 0 dB; wire (the whip, nearly omnidirectional
//!   in azimuth, its ripple from the board and the shield) 3 dB peak to peak, strongest towards
//!   its orientation, 1.6 dB weaker behind; chip 11 dB peak to peak, one lobe towards its
//!   orientation and the deepest point at about 225° (where the thesis measured the chip
//!   antenna's largest RSSI difference from 0°). Every unit is its own: with
//!   [`MediumConfig::antenna_unit_variation`] each node's harmonics differ from the nominal
//!   ones by a factor `1 + N(0, UNIT_AMPLITUDE_SIGMA²)` in amplitude and `N(0,
//!   UNIT_PHASE_SIGMA_DEG²)` in phase, drawn once per node ([`UNIT_AMPLITUDE_SIGMA`],
//!   [`UNIT_PHASE_SIGMA_DEG`]).
//! * `F_ab(ch)`: a static offset per link and channel, N(0, [`MediumConfig::fading_sigma_db`]²),
//!   the same both ways (a → b and b → a) and for the whole run: frequency-selective multipath,
//!   which is what makes several channels worth measuring.
//! * `S`: per packet and receiver, N(0, [`MediumConfig::sigma_db`]²), independent between
//!   receivers and packets: shadowing noise.
//!
//! The receiver reports the level rounded to an integer dBm (and at most 0 dBm); a packet whose
//! rounded level is below [`MediumConfig::sensitivity_dbm`] (−92 dBm) is not heard.
//!
//! **Collisions**: two packets on the same channel whose times on air overlap (one starts before
//! the other ends; touching intervals do not overlap) are both lost at every receiver, however
//! strong either is (no capture effect). Packets on different channels never interfere. The
//! rule covers every pair: a packet hit by a later one is lost too, so [`Medium::resolve`] may
//! only decide a packet once every transmission that starts before its end is known (the
//! network guarantees it: nothing starts sooner than it is handed over).
//!
//! ACKs are packets like any other (they collide and are collided with).
//!
//! **Clear channel assessment** ([`Medium::channel_busy`]): a radio's CCA finds the channel busy
//! when another node's packet on its channel is on air during it at a level at that radio (the
//! packet's own draw for that receiver, rounded as above) at or above the radio's threshold;
//! each packet is compared alone (overlapping packets' energies are not added up), and below
//! sensitivity counts like any other level.
//!
//! What the medium does *not* decide is left to the receiving radio ([`crate::XBeeCore`]): it
//! drops packets on another channel than its own, of another PAN or address, encrypted at one
//! end only, or arriving while it transmits (half duplex), is in command mode, sleeps or looks
//! for a coordinator, and copies it passed on already. The medium carries each packet's
//! [`Security`] to it.
//!
//! # Randomness
//!
//! Every random draw is a pure function of [`MediumConfig::seed`] and what it is for (fading:
//! the unordered node pair and the channel; shadowing: the packet's sequence number and the
//! receiver), so results do not depend on the order in which things are asked, only on the
//! seed and the order of [`Medium::transmit`] calls. Draws are Box–Muller on xoshiro256++
//! ([`rand_xoshiro`]) streams seeded by a SplitMix64 hash of those keys.

use rand_xoshiro::rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

use crate::avr::cycles_to_ms;
use crate::xbee::{Security, Transmission};

/// An antenna kind and its nominal gain pattern over azimuth (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Antenna {
    /// 0 dB in every direction.
    #[default]
    Isotropic,
    /// The XBee's whip: nearly omnidirectional, 3 dB peak to peak.
    Wire,
    /// The XBee's chip antenna: 11 dB peak to peak, strongest towards the orientation, weakest
    /// at about 225°.
    Chip,
}

/// Relative σ of a unit's harmonic amplitudes around its kind's nominal ones.
pub const UNIT_AMPLITUDE_SIGMA: f64 = 0.15;
/// σ of a unit's harmonic phases around its kind's nominal ones, degrees.
pub const UNIT_PHASE_SIGMA_DEG: f64 = 10.0;

/// Harmonics of a pattern: `(a_k dB, ψ_k degrees)` for k = 1, 2, 3.
pub type Harmonics = [(f64, f64); 3];

impl Antenna {
    /// The nominal pattern's harmonics `(a_k dB, ψ_k degrees)`, k = 1, 2, 3: `G(θ) = Σ
    /// a_k·cos(kθ − ψ_k)`.
    pub fn harmonics(self) -> Harmonics {
        match self {
            Antenna::Isotropic => [(0.0, 0.0); 3],
            Antenna::Wire => [(0.5, 0.0), (1.1, 0.0), (0.3, 0.0)],
            Antenna::Chip => [(5.25, 0.0), (1.5, 330.0), (1.0, 150.0)],
        }
    }

    /// Peak-to-peak ripple of the nominal pattern over azimuth, dB (sampled every 0.1°).
    pub fn ripple_db(self) -> f64 {
        let (min, max) = (0..3600).fold((f64::MAX, f64::MIN), |(lo, hi), k| {
            let g = self.gain_db(f64::from(k) / 10.0);
            (lo.min(g), hi.max(g))
        });
        max - min
    }

    /// An upper bound of any unit's gain in any direction, dB: the harmonics' amplitudes at
    /// three σ of unit variation, added up.
    pub fn max_gain_db(self) -> f64 {
        self.harmonics()
            .iter()
            .map(|&(a, _)| a * (1.0 + 3.0 * UNIT_AMPLITUDE_SIGMA))
            .sum()
    }

    /// The nominal gain in dB towards `azimuth_deg`, measured from the antenna's orientation
    /// (counter-clockwise). Zero mean over a full turn.
    pub fn gain_db(self, azimuth_deg: f64) -> f64 {
        pattern_db(&self.harmonics(), azimuth_deg)
    }
}

/// `Σ a_k·cos(kθ − ψ_k)` in dB, `θ` = `azimuth_deg`.
fn pattern_db(h: &Harmonics, azimuth_deg: f64) -> f64 {
    h.iter()
        .zip(1u32..)
        .map(|(&(a, psi), k)| {
            if a == 0.0 {
                0.0
            } else {
                a * (f64::from(k) * azimuth_deg - psi).to_radians().cos()
            }
        })
        .sum()
}

/// Where a node is and how its antenna points.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NodeRadio {
    /// Position (x, y) in metres.
    pub position: [f64; 2],
    /// Orientation of the antenna pattern, degrees counter-clockwise from +x.
    pub orientation_deg: f64,
    /// Antenna kind.
    pub antenna: Antenna,
    /// This node's own TX power drift (battery droop), dB per minute, on top of
    /// [`MediumConfig::drift_db_per_min`].
    pub drift_db_per_min: f64,
}

impl NodeRadio {
    /// An isotropic node at `(x, y)` metres, no drift.
    pub fn at(x: f64, y: f64) -> Self {
        NodeRadio {
            position: [x, y],
            ..NodeRadio::default()
        }
    }
}

/// Parameters of the medium (see the module docs for the model).
#[derive(Clone, Debug, PartialEq)]
pub struct MediumConfig {
    /// Level at 1 m of a sender at the factory power level (`PL` 4), dBm.
    pub p0_dbm: f64,
    /// Path-loss exponent.
    pub alpha: f64,
    /// Per-packet shadowing σ, dB.
    pub sigma_db: f64,
    /// σ of the static per-link per-channel fading offset, dB.
    pub fading_sigma_db: f64,
    /// Packets whose rounded level is below this are lost, dBm.
    pub sensitivity_dbm: i16,
    /// Distances are at least this, m.
    pub min_distance_m: f64,
    /// TX power drift of every node, dB per minute (negative: droop).
    pub drift_db_per_min: f64,
    /// Drift starts at this time, ms.
    pub drift_start_ms: f64,
    /// Every antenna is its own unit: its pattern's harmonics differ from its kind's nominal
    /// ones (see the module docs). Off, every antenna has its kind's nominal pattern.
    pub antenna_unit_variation: bool,
    /// Seed of every random draw.
    pub seed: u64,
}

impl Default for MediumConfig {
    /// P0 −40 dBm, α 3, σ 2 dB, fading σ 3 dB, sensitivity −92 dBm, no drift, antennas as
    /// units, seed 1.
    fn default() -> Self {
        MediumConfig {
            p0_dbm: -40.0,
            alpha: 3.0,
            sigma_db: 2.0,
            fading_sigma_db: 3.0,
            sensitivity_dbm: -92,
            min_distance_m: 0.1,
            drift_db_per_min: 0.0,
            drift_start_ms: 0.0,
            antenna_unit_variation: true,
            seed: 1,
        }
    }
}

impl MediumConfig {
    /// The default path loss without any randomness: no shadowing, no fading, every antenna
    /// its kind's nominal pattern.
    pub fn noise_free() -> Self {
        MediumConfig {
            sigma_db: 0.0,
            fading_sigma_db: 0.0,
            antenna_unit_variation: false,
            ..MediumConfig::default()
        }
    }
}

/// Id of a node in a [`Medium`] (its index, in the order of [`Medium::add_node`]).
pub type RadioId = usize;

/// What became of a packet at one receiver, as far as the medium decides.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Heard {
    /// Above sensitivity and not collided: handed to the receiver's radio.
    Yes,
    /// Below sensitivity.
    TooWeak,
    /// Lost in a collision.
    Collided,
}

/// A packet's fate at one receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Reception {
    /// The receiver.
    pub node: RadioId,
    /// The level it had there, integer dBm (≤ 0).
    pub rssi_dbm: i16,
    /// Heard or why not.
    pub heard: Heard,
}

/// A packet the medium has decided on.
#[derive(Clone, Debug, PartialEq)]
pub struct Resolved {
    /// Sequence number (order of [`Medium::transmit`], from 0).
    pub seq: u64,
    /// The sender.
    pub from: RadioId,
    /// The packet (cycles in the medium's time base).
    pub tx: Transmission,
    /// How it was encrypted.
    pub security: Security,
    /// True if another packet on its channel overlapped it.
    pub collided: bool,
    /// One entry per listening node other than the sender, in id order.
    pub receptions: Vec<Reception>,
}

#[derive(Clone, Debug)]
struct Pending {
    seq: u64,
    from: RadioId,
    tx: Transmission,
    security: Security,
}

/// The medium: nodes and the packets on air (see the module docs).
#[derive(Clone, Debug)]
pub struct Medium {
    cfg: MediumConfig,
    nodes: Vec<NodeRadio>,
    /// Per node, its unit's variation of each harmonic: (amplitude factor, phase offset °).
    units: Vec<Harmonics>,
    /// Transmissions not yet resolved.
    pending: Vec<Pending>,
    /// Resolved transmissions that may still overlap a pending one: (channel, start, end).
    history: Vec<(u8, u64, u64)>,
    seq: u64,
}

/// SplitMix64's finaliser.
pub(crate) fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A standard normal draw that is a pure function of `seed` and `key`.
fn normal(seed: u64, key: &[u64]) -> f64 {
    let h = key.iter().fold(splitmix(seed), |h, &k| splitmix(h ^ k));
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(h);
    let mut uniform = || ((rng.next_u64() >> 11) + 1) as f64 * (1.0 / (1u64 << 53) as f64);
    let r = (-2.0 * uniform().ln()).sqrt();
    r * (2.0 * std::f64::consts::PI * uniform()).cos()
}

const KEY_FADING: u64 = 0xFAD1;
const KEY_UNIT: u64 = 0xA27E;
const KEY_SHADOW: u64 = 0x5AAD;

impl Medium {
    /// An empty medium.
    pub fn new(cfg: MediumConfig) -> Self {
        Medium {
            cfg,
            nodes: Vec::new(),
            units: Vec::new(),
            pending: Vec::new(),
            history: Vec::new(),
            seq: 0,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &MediumConfig {
        &self.cfg
    }

    /// The configuration, mutably (e.g. to start a drift mid-run).
    pub fn config_mut(&mut self) -> &mut MediumConfig {
        &mut self.cfg
    }

    /// Adds a node; returns its id.
    pub fn add_node(&mut self, node: NodeRadio) -> RadioId {
        let id = self.nodes.len();
        let mut unit = [(1.0, 0.0); 3];
        for (k, (amp, psi)) in unit.iter_mut().enumerate() {
            let key = |what: u64| [KEY_UNIT, id as u64, k as u64, what];
            *amp = (1.0 + UNIT_AMPLITUDE_SIGMA * normal(self.cfg.seed, &key(0))).max(0.0);
            *psi = UNIT_PHASE_SIGMA_DEG * normal(self.cfg.seed, &key(1));
        }
        self.nodes.push(node);
        self.units.push(unit);
        id
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// True without nodes.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// A node's placement.
    pub fn node(&self, id: RadioId) -> &NodeRadio {
        &self.nodes[id]
    }

    /// A node's placement, mutably (move or turn it; applies to packets resolved afterwards).
    pub fn node_mut(&mut self, id: RadioId) -> &mut NodeRadio {
        &mut self.nodes[id]
    }

    /// Distance between two nodes, m (at least [`MediumConfig::min_distance_m`]).
    pub fn distance_m(&self, a: RadioId, b: RadioId) -> f64 {
        let (p, q) = (self.nodes[a].position, self.nodes[b].position);
        (q[0] - p[0])
            .hypot(q[1] - p[1])
            .max(self.cfg.min_distance_m)
    }

    /// Gain of `a`'s antenna towards `b`, dB.
    pub fn antenna_gain_db(&self, a: RadioId, b: RadioId) -> f64 {
        let (na, nb) = (&self.nodes[a], &self.nodes[b]);
        if na.antenna == Antenna::Isotropic {
            return 0.0;
        }
        let bearing = (nb.position[1] - na.position[1])
            .atan2(nb.position[0] - na.position[0])
            .to_degrees();
        pattern_db(&self.unit_harmonics(a), bearing - na.orientation_deg)
    }

    /// Node `a`'s own pattern: its kind's nominal harmonics, varied as a unit when
    /// [`MediumConfig::antenna_unit_variation`] is on (drawn from the seed and the node's id
    /// when it was added, so a node keeps its unit whatever else happens, also when it is
    /// turned or given another antenna kind).
    pub fn unit_harmonics(&self, a: RadioId) -> Harmonics {
        let mut h = self.nodes[a].antenna.harmonics();
        if self.cfg.antenna_unit_variation {
            for ((amp, psi), (f, d)) in h.iter_mut().zip(self.units[a]) {
                *amp *= f;
                *psi += d;
            }
        }
        h
    }

    /// The static fading offset of the link {a, b} on `channel` (the same both ways), dB.
    pub fn fading_db(&self, a: RadioId, b: RadioId, channel: u8) -> f64 {
        if self.cfg.fading_sigma_db == 0.0 {
            return 0.0;
        }
        let (lo, hi) = (a.min(b) as u64, a.max(b) as u64);
        self.cfg.fading_sigma_db * normal(self.cfg.seed, &[KEY_FADING, lo, hi, u64::from(channel)])
    }

    /// Drift of `from`'s TX power at `cycle`, dB.
    pub fn drift_db(&self, from: RadioId, cycle: u64) -> f64 {
        let rate = self.cfg.drift_db_per_min + self.nodes[from].drift_db_per_min;
        if rate == 0.0 {
            return 0.0;
        }
        let minutes = (cycles_to_ms(cycle) - self.cfg.drift_start_ms).max(0.0) / 60_000.0;
        rate * minutes
    }

    /// The mean level (everything but the per-packet shadowing) of a packet from `from` at
    /// `to` on `channel` starting at `cycle`, dBm.
    pub fn mean_level_dbm(&self, from: RadioId, to: RadioId, channel: u8, cycle: u64) -> f64 {
        let d = self.distance_m(from, to);
        self.cfg.p0_dbm + self.drift_db(from, cycle) - 10.0 * self.cfg.alpha * d.log10()
            + self.antenna_gain_db(from, to)
            + self.antenna_gain_db(to, from)
            + self.fading_db(from, to, channel)
    }

    /// The level packet `seq` from `from` on `channel` starting at `cycle` has at `to`, with
    /// its shadowing draw, dBm (not rounded).
    pub fn level_dbm(&self, seq: u64, from: RadioId, to: RadioId, channel: u8, cycle: u64) -> f64 {
        let mut level = self.mean_level_dbm(from, to, channel, cycle);
        if self.cfg.sigma_db != 0.0 {
            level += self.cfg.sigma_db * normal(self.cfg.seed, &[KEY_SHADOW, seq, to as u64]);
        }
        level
    }

    /// The level packet `seq` from `from`, `tx`, has at `to`: [`Medium::level_dbm`] on its
    /// channel at its start, plus its sender's power level ([`Transmission::power_db`]), dBm
    /// (not rounded).
    pub fn packet_level_dbm(&self, seq: u64, from: RadioId, to: RadioId, tx: &Transmission) -> f64 {
        self.level_dbm(seq, from, to, tx.channel, tx.start_cycle) + f64::from(tx.power_db)
    }

    /// A level as the radio reports it: rounded to integer dBm, at most 0.
    pub fn quantise(level_dbm: f64) -> i16 {
        level_dbm.round().clamp(-200.0, 0.0) as i16
    }

    /// A packet `from` put on air in the clear (its cycles in the medium's time base); returns
    /// its sequence number. Packets must be handed over before any packet they overlap is
    /// resolved (the network hands each over no later than it starts, or, judged by a CCA
    /// after the fact, before the next packet end).
    pub fn transmit(&mut self, from: RadioId, tx: Transmission) -> u64 {
        self.transmit_secured(from, tx, Security::Clear)
    }

    /// [`Medium::transmit`] of a packet sent as `security` says.
    pub fn transmit_secured(&mut self, from: RadioId, tx: Transmission, security: Security) -> u64 {
        let seq = self.seq;
        self.seq += 1;
        self.pending.push(Pending {
            seq,
            from,
            tx,
            security,
        });
        seq
    }

    /// Whether a clear channel assessment by `node` on `channel` over cycles `from`…`to` finds
    /// the channel busy: a packet of another node on that channel is on air during it at a
    /// level at `node` (with its shadowing draw there, rounded to integer dBm as the radio
    /// measures) of at least `threshold_dbm`. Packets already resolved ended before; the node's
    /// own are its radio's business (a radio that transmits finds the channel busy).
    pub fn channel_busy(
        &self,
        node: RadioId,
        channel: u8,
        from: u64,
        to: u64,
        threshold_dbm: i16,
    ) -> bool {
        self.pending
            .iter()
            .filter(|p| p.from != node && p.tx.channel == channel)
            .filter(|p| p.tx.start_cycle < to && p.tx.end_cycle > from)
            .any(|p| {
                let level = self.packet_level_dbm(p.seq, p.from, node, &p.tx);
                Self::quantise(level) >= threshold_dbm
            })
    }

    /// The earliest end cycle of the packets not yet resolved.
    pub fn next_end(&self) -> Option<u64> {
        self.pending.iter().map(|p| p.tx.end_cycle).min()
    }

    /// Packets handed over and not yet resolved.
    pub fn pending(&self) -> usize {
        self.pending.len()
    }

    /// Drops the pending packets of `from` that start at or after `cycle` (a node powered off
    /// before they went on air); returns how many.
    pub fn cancel_from(&mut self, from: RadioId, cycle: u64) -> usize {
        let before = self.pending.len();
        self.pending
            .retain(|p| p.from != from || p.tx.start_cycle < cycle);
        before - self.pending.len()
    }

    /// Decides every pending packet that ended by `now`, in order of end (then sequence): its
    /// collisions and, for each node `listening(node)` says is listening (powered), other than
    /// the sender, the level and whether it is heard. Every packet starting before `now` must
    /// have been handed over (see [`Medium::transmit`]).
    pub fn resolve(&mut self, now: u64, listening: impl Fn(RadioId) -> bool) -> Vec<Resolved> {
        let mut done: Vec<Pending> = Vec::new();
        let mut i = 0;
        while i < self.pending.len() {
            if self.pending[i].tx.end_cycle <= now {
                done.push(self.pending.swap_remove(i));
            } else {
                i += 1;
            }
        }
        done.sort_by_key(|p| (p.tx.end_cycle, p.seq));
        let mut out = Vec::with_capacity(done.len());
        for p in &done {
            let (ch, s, e) = (p.tx.channel, p.tx.start_cycle, p.tx.end_cycle);
            let hits = |c: u8, s2: u64, e2: u64| c == ch && s2 < e && s < e2;
            let collided =
                self.pending.iter().chain(done.iter()).any(|q| {
                    q.seq != p.seq && hits(q.tx.channel, q.tx.start_cycle, q.tx.end_cycle)
                }) || self.history.iter().any(|&(c, s2, e2)| hits(c, s2, e2));
            let receptions = (0..self.nodes.len())
                .filter(|&n| n != p.from && listening(n))
                .map(|n| {
                    let rssi_dbm = Self::quantise(self.packet_level_dbm(p.seq, p.from, n, &p.tx));
                    let heard = if rssi_dbm < self.cfg.sensitivity_dbm {
                        Heard::TooWeak
                    } else if collided {
                        Heard::Collided
                    } else {
                        Heard::Yes
                    };
                    Reception {
                        node: n,
                        rssi_dbm,
                        heard,
                    }
                })
                .collect();
            out.push(Resolved {
                seq: p.seq,
                from: p.from,
                tx: p.tx.clone(),
                security: p.security,
                collided,
                receptions,
            });
        }
        self.history.extend(
            done.iter()
                .map(|p| (p.tx.channel, p.tx.start_cycle, p.tx.end_cycle)),
        );
        // Keep only what a pending packet can still overlap.
        match self.pending.iter().map(|p| p.tx.start_cycle).min() {
            Some(first) => self.history.retain(|&(_, _, e)| e > first),
            None => self.history.clear(),
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::avr::ms_to_cycles;
    use crate::xbee::{time_on_air_ms, Address, MacFields};

    fn packet(channel: u8, start: u64, len: usize) -> Transmission {
        Transmission {
            channel,
            pan_id: 0x3332,
            source: Address::Short(1),
            source64: 1,
            dest: Address::Short(0xFFFF),
            options: 0,
            payload: vec![0; len],
            start_cycle: start,
            end_cycle: start + ms_to_cycles(time_on_air_ms(len)),
            frame_id: 0,
            mac: MacFields::default(),
            power_db: 0,
        }
    }

    /// Levels at node 1 of `n` packets from node 0 at distance `d`.
    fn levels(cfg: MediumConfig, d: f64, n: usize, channel: u8) -> Vec<i16> {
        let mut m = Medium::new(cfg);
        m.add_node(NodeRadio::at(0.0, 0.0));
        m.add_node(NodeRadio::at(d, 0.0));
        let mut out = Vec::new();
        for k in 0..n as u64 {
            // One after the other: no collisions.
            m.transmit(0, packet(channel, k * 20_000, 10));
            for r in m.resolve(k * 20_000 + 19_999, |_| true) {
                assert!(!r.collided);
                out.push(r.receptions[0].rssi_dbm);
            }
        }
        out
    }

    fn mean_sd(v: &[f64]) -> (f64, f64) {
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, var.sqrt())
    }

    #[test]
    fn noise_free_levels_follow_the_path_loss_model_exactly() {
        let cfg = MediumConfig::noise_free();
        // −40 − 30·log10(d): 1 m −40, 10 m −70, 2 m −49.03 → −49.
        assert_eq!(levels(cfg.clone(), 1.0, 3, 0x0B), [-40; 3]);
        assert_eq!(levels(cfg.clone(), 10.0, 3, 0x0B), [-70; 3]);
        assert_eq!(levels(cfg, 2.0, 1, 0x0B), [-49]);
    }

    #[test]
    fn same_seed_same_levels_other_seed_other_levels() {
        let cfg = MediumConfig::default();
        let a = levels(cfg.clone(), 5.0, 200, 0x0B);
        assert_eq!(a, levels(cfg.clone(), 5.0, 200, 0x0B));
        let other = MediumConfig { seed: 2, ..cfg };
        assert_ne!(a, levels(other, 5.0, 200, 0x0B));
    }

    #[test]
    fn shadowing_has_the_configured_mean_and_sigma() {
        // No fading: the mean is the path loss; σ = 4 dB (rounding adds 1/12 dB² of variance).
        let cfg = MediumConfig {
            sigma_db: 4.0,
            fading_sigma_db: 0.0,
            seed: 7,
            ..MediumConfig::default()
        };
        let v: Vec<f64> = levels(cfg, 4.0, 20_000, 0x0B)
            .into_iter()
            .map(f64::from)
            .collect();
        let (mean, sd) = mean_sd(&v);
        let want = -40.0 - 30.0 * 4f64.log10();
        // Standard error of the mean 4/√20000 = 0.028 dB; of σ about 0.02 dB.
        assert!((mean - want).abs() < 0.12, "{mean} vs {want}");
        let want_sd = (16.0f64 + 1.0 / 12.0).sqrt();
        assert!((sd - want_sd).abs() < 0.1, "{sd} vs {want_sd}");
    }

    #[test]
    fn fading_is_static_per_link_and_channel_symmetric_and_has_its_sigma() {
        let cfg = MediumConfig {
            fading_sigma_db: 3.0,
            ..MediumConfig::default()
        };
        let mut m = Medium::new(cfg);
        for i in 0..60 {
            m.add_node(NodeRadio::at(i as f64, 0.0));
        }
        assert_eq!(m.fading_db(3, 7, 0x0B), m.fading_db(7, 3, 0x0B));
        assert_eq!(m.fading_db(3, 7, 0x0B), m.fading_db(3, 7, 0x0B));
        assert_ne!(m.fading_db(3, 7, 0x0B), m.fading_db(3, 7, 0x16));
        assert_ne!(m.fading_db(3, 7, 0x0B), m.fading_db(3, 8, 0x0B));
        // The mean level is symmetric too (isotropic antennas), and static over time.
        assert_eq!(
            m.mean_level_dbm(3, 7, 0x0B, 0),
            m.mean_level_dbm(7, 3, 0x0B, ms_to_cycles(60_000.0))
        );
        let mut v = Vec::new();
        for a in 0..60 {
            for b in a + 1..60 {
                v.push(m.fading_db(a, b, 0x0B));
            }
        }
        // 1770 links: the sample σ is within ±0.2 dB of 3 (≈ 4 standard errors).
        let (mean, sd) = mean_sd(&v);
        assert!(mean.abs() < 0.3, "{mean}");
        assert!((sd - 3.0).abs() < 0.2, "{sd}");
        // Shadowing on top: packets of one link scatter around the static mean.
        let noisy = MediumConfig {
            sigma_db: 2.0,
            fading_sigma_db: 3.0,
            ..MediumConfig::default()
        };
        let v: Vec<f64> = levels(noisy.clone(), 3.0, 5000, 0x0B)
            .into_iter()
            .map(f64::from)
            .collect();
        let mut m = Medium::new(noisy);
        m.add_node(NodeRadio::at(0.0, 0.0));
        m.add_node(NodeRadio::at(3.0, 0.0));
        let (mean, _) = mean_sd(&v);
        let want = m.mean_level_dbm(0, 1, 0x0B, 0);
        assert!((mean - want).abs() < 0.15, "{mean} vs {want}");
    }

    #[test]
    fn antenna_patterns_have_their_ripple_and_zero_mean() {
        for (a, lo, hi) in [
            (Antenna::Isotropic, 0.0, 0.0),
            (Antenna::Wire, 2.9, 3.2),
            (Antenna::Chip, 10.8, 11.4),
        ] {
            let r = a.ripple_db();
            assert!((lo..=hi).contains(&r), "{a:?}: {r}");
            let g: Vec<f64> = (0..3600).map(|k| a.gain_db(k as f64 / 10.0)).collect();
            assert!(g.iter().sum::<f64>().abs() / 3600.0 < 1e-9);
            assert!(g.iter().all(|&v| v <= a.max_gain_db() + 1e-9));
        }
        // Chip: strongest towards its orientation, weakest near 225°, the back (180°) between.
        let chip = |az: f64| Antenna::Chip.gain_db(az);
        let deepest = (0..3600)
            .map(|k| k as f64 / 10.0)
            .min_by(|&x, &y| chip(x).total_cmp(&chip(y)))
            .unwrap();
        assert!((215.0..=235.0).contains(&deepest), "{deepest}");
        assert!((0..3600).all(|k| chip(k as f64 / 10.0) <= chip(0.0) + 1e-9));
        assert!(chip(180.0) > chip(deepest) + 1.0 && chip(180.0) < chip(0.0) - 5.0);
        // Wire: nearly omnidirectional, its front above its back.
        let wire = |az: f64| Antenna::Wire.gain_db(az);
        assert!(wire(0.0) - wire(180.0) > 1.0);
        // Both ends count: a chip node turned to 90° seen from three sides, and the receiver's
        // pattern too.
        let mut m = Medium::new(MediumConfig::noise_free());
        m.add_node(NodeRadio {
            antenna: Antenna::Chip,
            orientation_deg: 90.0,
            ..NodeRadio::at(0.0, 0.0)
        });
        m.add_node(NodeRadio::at(0.0, 1.0));
        m.add_node(NodeRadio::at(0.0, -1.0));
        m.add_node(NodeRadio::at(1.0, 0.0));
        for (to, az) in [(1, 0.0), (2, 180.0), (3, 270.0)] {
            let want = -40.0 + chip(az);
            assert!(
                (m.mean_level_dbm(0, to, 0x0B, 0) - want).abs() < 1e-9,
                "{to}"
            );
            assert!(
                (m.mean_level_dbm(to, 0, 0x0B, 0) - want).abs() < 1e-9,
                "{to}"
            );
        }
    }

    /// Two antennas of one kind pointing the same way: the link's gain `G(θ) + G(θ + 180°)`
    /// is not 0 everywhere (it is with a pattern of odd harmonics only), and varies with the
    /// bearing by several dB for chip antennas.
    #[test]
    fn equal_orientations_do_not_cancel() {
        for (a, min_spread) in [(Antenna::Wire, 1.0), (Antenna::Chip, 4.0)] {
            let link: Vec<f64> = (0..360)
                .map(|k| a.gain_db(k as f64) + a.gain_db(k as f64 + 180.0))
                .collect();
            let lo = link.iter().cloned().fold(f64::MAX, f64::min);
            let hi = link.iter().cloned().fold(f64::MIN, f64::max);
            assert!(hi - lo >= min_spread, "{a:?}: {lo}…{hi}");
        }
    }

    /// With unit variation every antenna is its own: two chip nodes' patterns differ, each
    /// stays within its kind's bound and keeps zero mean, the draws follow the seed, and a
    /// node keeps its unit when turned. Off, every antenna is nominal.
    #[test]
    fn every_antenna_is_its_own_unit() {
        let pattern = |m: &Medium, id: RadioId| -> Vec<f64> {
            let h = m.unit_harmonics(id);
            (0..360).map(|k| pattern_db(&h, k as f64)).collect()
        };
        let chips = |cfg: MediumConfig| {
            let mut m = Medium::new(cfg);
            for i in 0..4 {
                m.add_node(NodeRadio {
                    antenna: Antenna::Chip,
                    ..NodeRadio::at(i as f64, 0.0)
                });
            }
            m
        };
        let m = chips(MediumConfig::default());
        let p: Vec<Vec<f64>> = (0..4).map(|i| pattern(&m, i)).collect();
        for i in 0..4 {
            assert!(p[i].iter().sum::<f64>().abs() / 360.0 < 1e-9);
            assert!(p[i].iter().all(|&v| v.abs() <= Antenna::Chip.max_gain_db()));
            for j in 0..i {
                let diff = p[i].iter().zip(&p[j]).map(|(a, b)| (a - b).abs());
                assert!(diff.fold(0.0, f64::max) > 0.3, "units {i} and {j} alike");
            }
        }
        // The same seed, the same units; another seed, others.
        assert_eq!(pattern(&chips(MediumConfig::default()), 2), p[2]);
        let other = chips(MediumConfig {
            seed: 7,
            ..MediumConfig::default()
        });
        assert_ne!(pattern(&other, 2), p[2]);
        // Turned, a node keeps its unit.
        let mut turned = chips(MediumConfig::default());
        turned.node_mut(2).orientation_deg = 45.0;
        assert_eq!(pattern(&turned, 2), p[2]);
        // Off: nominal.
        let nominal = chips(MediumConfig {
            antenna_unit_variation: false,
            ..MediumConfig::default()
        });
        let want: Vec<f64> = (0..360).map(|k| Antenna::Chip.gain_db(k as f64)).collect();
        assert_eq!(pattern(&nominal, 1), want);
    }

    #[test]
    fn packets_below_sensitivity_are_lost() {
        let cfg = MediumConfig::noise_free();
        // −40 − 30·log10(d) = −92 at d = 10^(52/30) = 54.1 m: −91.96 rounds to −92 (heard),
        // at 55 m −92.2 rounds to −92 too; at 56 m −92.45 → −92; 57 m −92.68 → −93 (lost).
        let mut m = Medium::new(cfg);
        m.add_node(NodeRadio::at(0.0, 0.0));
        m.add_node(NodeRadio::at(54.0, 0.0));
        m.add_node(NodeRadio::at(57.0, 0.0));
        m.transmit(0, packet(0x0B, 0, 10));
        let r = m.resolve(u64::MAX, |_| true);
        let rx = &r[0].receptions;
        assert_eq!(rx.len(), 2);
        assert_eq!(
            (rx[0].node, rx[0].rssi_dbm, rx[0].heard),
            (1, -92, Heard::Yes)
        );
        assert_eq!(
            (rx[1].node, rx[1].rssi_dbm, rx[1].heard),
            (2, -93, Heard::TooWeak)
        );
    }

    #[test]
    fn overlapping_packets_on_one_channel_collide_and_others_do_not() {
        let mut m = Medium::new(MediumConfig::noise_free());
        for x in [0.0, 1.0, 2.0, 3.0] {
            m.add_node(NodeRadio::at(x, 0.0));
        }
        let a = packet(0x0B, 0, 10);
        let end_a = a.end_cycle;
        // b starts on a's last cycle: overlaps. c starts when a ends: touches, no overlap.
        // d overlaps a but on another channel.
        let b = packet(0x0B, end_a - 1, 10);
        let c = packet(0x0B, 2 * end_a, 10);
        let c_end = c.end_cycle;
        let touching = packet(0x0B, c_end, 4);
        let d = packet(0x16, 100, 10);
        m.transmit(0, a);
        m.transmit(1, b);
        m.transmit(3, d);
        // Nothing is decided before its end.
        assert!(m.resolve(end_a - 1, |_| true).is_empty());
        let r = m.resolve(end_a, |_| true);
        assert_eq!(r.len(), 1);
        assert!(r[0].collided);
        assert!(r[0].receptions.iter().all(|x| x.heard == Heard::Collided));
        let r = m.resolve(c_end - 1, |_| true);
        // b (hit by a, already resolved) and d.
        assert_eq!(r.len(), 2);
        let (b_r, d_r) = if r[0].from == 1 {
            (&r[0], &r[1])
        } else {
            (&r[1], &r[0])
        };
        assert!(b_r.collided);
        assert!(!d_r.collided);
        assert!(d_r.receptions.iter().all(|x| x.heard == Heard::Yes));
        m.transmit(2, c);
        m.transmit(1, touching);
        let r = m.resolve(u64::MAX, |_| true);
        assert_eq!(r.len(), 2);
        assert!(r.iter().all(|x| !x.collided), "{r:?}");
        // Listening filter: sender and powered-off nodes get no entry.
        m.transmit(0, packet(0x0B, 10 * end_a, 1));
        let r = m.resolve(u64::MAX, |n| n != 2);
        let nodes: Vec<_> = r[0].receptions.iter().map(|x| x.node).collect();
        assert_eq!(nodes, [1, 3]);
    }

    #[test]
    fn drift_lowers_the_senders_level_linearly_from_its_start() {
        let cfg = MediumConfig {
            drift_db_per_min: -0.5,
            drift_start_ms: 60_000.0,
            ..MediumConfig::noise_free()
        };
        let mut m = Medium::new(cfg);
        m.add_node(NodeRadio::at(0.0, 0.0));
        m.add_node(NodeRadio {
            drift_db_per_min: -1.0,
            ..NodeRadio::at(1.0, 0.0)
        });
        let at = |min: f64| ms_to_cycles(min * 60_000.0);
        assert_eq!(m.mean_level_dbm(0, 1, 0x0B, at(0.5)), -40.0);
        assert!((m.mean_level_dbm(0, 1, 0x0B, at(3.0)) - -41.0).abs() < 1e-9);
        // Node 1 droops at −1.5 dB/min (its own −1 on top): its packets, not node 0's.
        assert!((m.mean_level_dbm(1, 0, 0x0B, at(3.0)) - -43.0).abs() < 1e-9);
        m.transmit(1, packet(0x0B, at(5.0), 10));
        let r = m.resolve(u64::MAX, |_| true);
        assert_eq!(r[0].receptions[0].rssi_dbm, -46);
    }
}
