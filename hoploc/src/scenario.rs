//! Testbed scenarios: a room, its anchors, the agent's path, the TDMA timing and the
//! radio medium, read from a TOML file of `scenarios/` (documented field by field in
//! `scenarios/README.md`). [`Scenario::load`] reads and checks one; every error names the file,
//! the field and the problem.

use std::fmt;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use simavr::medium::{Antenna, MediumConfig};

/// A testbed scenario.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short name (the file's stem by convention).
    pub name: String,
    /// One line on what it reproduces.
    pub description: String,
    /// Seed of every random draw of the medium.
    pub seed: u64,
    /// The room.
    pub area: Area,
    /// TDMA timing and channels.
    pub timing: Timing,
    /// The radio medium.
    pub medium: MediumSpec,
    /// The anchors, in id order (anchor 1 first).
    pub anchors: Vec<AnchorSpec>,
    /// The agent and its path.
    pub agent: AgentSpec,
}

/// The room `[0, width] × [0, height]`, metres.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Area {
    /// Extent in x, m.
    pub width_m: f64,
    /// Extent in y, m.
    pub height_m: f64,
}

/// The nodes' TDMA timing (`loc_proto::schedule`).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Timing {
    /// One beacon slot, ms (a channel phase is one slot per anchor).
    pub slot_ms: u16,
    /// The anchor channels (testbed channels 1…16), in hop order.
    pub channels: Vec<u8>,
    /// The sink channel.
    #[serde(default = "default_sink_channel")]
    pub sink_channel: u8,
    /// Simulated time before the agent's first stop counts (boot, provisioning window, radio
    /// bring-up, anchors finding the timeline), s.
    #[serde(default = "default_warmup")]
    pub warmup_s: f64,
    /// The network key every node is provisioned with (32 hex digits): the radios encrypt
    /// (`loc_proto::config::NetworkKey`). None: no encryption.
    #[serde(default)]
    pub network_key: Option<String>,
}

impl Timing {
    /// The network key, if set and valid (the scenario's checks refuse an invalid one).
    pub fn key(&self) -> Option<loc_proto::config::NetworkKey> {
        self.network_key
            .as_deref()
            .and_then(loc_proto::config::NetworkKey::parse)
    }
}

fn default_sink_channel() -> u8 {
    loc_proto::config::Config::DEFAULT.sink_channel
}

fn default_warmup() -> f64 {
    8.0
}

/// The medium's parameters ([`simavr::medium`]'s model).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MediumSpec {
    /// Level at 1 m, dBm.
    pub p0_dbm: f64,
    /// Path-loss exponent α.
    pub alpha: f64,
    /// Per-packet shadowing σ, dB.
    pub sigma_db: f64,
    /// σ of the static per-link per-channel fading, dB.
    pub fading_sigma_db: f64,
    /// Packets below this level are lost, dBm.
    pub sensitivity_dbm: i16,
    /// Every node's TX power drift (battery droop: negative), dB per minute.
    #[serde(default)]
    pub drift_db_per_min: f64,
    /// When the drift starts, s of simulated time.
    #[serde(default)]
    pub drift_start_s: f64,
    /// Every wire or chip antenna is its own unit, its pattern varied around its kind's
    /// (`simavr::medium`'s model; default true). False: every antenna has its kind's nominal
    /// pattern (for runs whose levels must be exact).
    #[serde(default = "yes")]
    pub antenna_unit_variation: bool,
}

fn yes() -> bool {
    true
}

/// Antenna kinds of a scenario file.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum AntennaKind {
    /// 0 dB everywhere.
    #[default]
    Isotropic,
    /// The XBee whip (nearly omnidirectional, 3 dB ripple).
    Wire,
    /// The XBee chip antenna (11 dB ripple, one lobe, weakest at about 225°).
    Chip,
}

impl AnchorSpec {
    /// Where the anchor stands: [`AnchorSpec::true_position`], else its configured position.
    pub fn radio_position(&self) -> [f64; 2] {
        self.true_position.unwrap_or(self.position)
    }
}

impl From<AntennaKind> for Antenna {
    fn from(k: AntennaKind) -> Antenna {
        match k {
            AntennaKind::Isotropic => Antenna::Isotropic,
            AntennaKind::Wire => Antenna::Wire,
            AntennaKind::Chip => Antenna::Chip,
        }
    }
}

/// One anchor.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AnchorSpec {
    /// (x, y), m: its configured position (what its config holds and its beacons carry).
    pub position: [f64; 2],
    /// Where it actually stands, (x, y) m, when that is not its configured position: the
    /// medium places its radio here (a misplaced or misconfigured anchor).
    #[serde(default)]
    pub true_position: Option<[f64; 2]>,
    /// Antenna kind.
    #[serde(default)]
    pub antenna: AntennaKind,
    /// Antenna orientation, degrees counter-clockwise from +x.
    #[serde(default)]
    pub orientation_deg: f64,
}

/// The agent.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AgentSpec {
    /// Antenna kind.
    #[serde(default)]
    pub antenna: AntennaKind,
    /// Antenna orientation where a stop does not give one, degrees.
    #[serde(default)]
    pub orientation_deg: f64,
    /// Where it stands, in order.
    pub path: Vec<Stop>,
}

/// One stop of the agent.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Stop {
    /// (x, y), m.
    pub position: [f64; 2],
    /// How long it stays, s.
    pub dwell_s: f64,
    /// Antenna orientation here, degrees (default: the agent's).
    pub orientation_deg: Option<f64>,
}

/// Why a scenario file was rejected: the file, the field (a dotted path such as
/// `anchors[2].position`, empty for the file as a whole) and the problem.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ScenarioError {
    /// The file.
    pub file: PathBuf,
    /// The field.
    pub field: String,
    /// What is wrong.
    pub problem: String,
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.field.is_empty() {
            write!(f, "{}: {}", self.file.display(), self.problem)
        } else {
            write!(
                f,
                "{}: field `{}`: {}",
                self.file.display(),
                self.field,
                self.problem
            )
        }
    }
}

impl std::error::Error for ScenarioError {}

/// Anchors closer than this (m) are on one spot; anchors all within this of one line are on
/// a line (the medium's shortest distance).
pub const MIN_ANCHOR_SPACING_M: f64 = 0.1;

/// The directory of the scenario files shipped with hoploc: `scenarios/` of the workspace
/// hoploc runs in ([`crate::firmware::workspace`]), else of the current directory.
pub fn dir() -> PathBuf {
    crate::firmware::workspace()
        .unwrap_or_default()
        .join("scenarios")
}

/// A scenario by name (`room10` → `scenarios/room10.toml` of [`dir`]) or by path (anything with
/// a `/` or ending in `.toml`).
pub fn resolve(name_or_path: &str) -> PathBuf {
    if name_or_path.contains('/') || name_or_path.ends_with(".toml") {
        PathBuf::from(name_or_path)
    } else {
        dir().join(format!("{name_or_path}.toml"))
    }
}

/// [`resolve`], and if a name gives no file, an error that says where hoploc looked.
pub fn find(name_or_path: &str) -> Result<PathBuf, String> {
    let path = resolve(name_or_path);
    if path.exists() || name_or_path.contains('/') || name_or_path.ends_with(".toml") {
        return Ok(path);
    }
    let names: Vec<String> = shipped()
        .iter()
        .filter_map(|p| p.file_stem()?.to_str().map(str::to_string))
        .collect();
    let place = match crate::firmware::workspace() {
        Some(ws) => format!("the hoploc workspace at {}", ws.display()),
        None => "the current directory (no hoploc workspace above it)".to_string(),
    };
    Err(format!(
        "no scenario `{name_or_path}`: {} does not exist (scenarios/ of {place}); {}give a \
         scenario file's path, or run hoploc in the hoploc source tree",
        path.display(),
        if names.is_empty() {
            String::new()
        } else {
            format!("there: {}; ", names.join(", "))
        }
    ))
}

/// Every `*.toml` in [`dir`], sorted.
pub fn shipped() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir())
        .map(|d| {
            d.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "toml"))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

impl Scenario {
    /// Reads and checks the scenario file `path`.
    pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|e| ScenarioError {
            file: path.to_path_buf(),
            field: String::new(),
            problem: format!("cannot read it: {e}"),
        })?;
        Scenario::parse(&text).map_err(|(field, problem)| ScenarioError {
            file: path.to_path_buf(),
            field,
            problem,
        })
    }

    /// Parses and checks a scenario's TOML text; errors are (field, problem).
    pub fn parse(text: &str) -> Result<Scenario, (String, String)> {
        let de = toml::Deserializer::parse(text).map_err(|e| {
            (
                String::new(),
                format!("not valid TOML: {}", e.message().trim()),
            )
        })?;
        let s: Scenario = serde_path_to_error::deserialize(de).map_err(|e| {
            let mut field = e.path().to_string();
            if field == "." {
                field.clear();
            }
            let problem = e.into_inner().message().trim().to_string();
            // A missing field's path is its table's: name the field itself.
            if let Some(name) = problem
                .strip_prefix("missing field `")
                .and_then(|r| r.strip_suffix('`'))
            {
                field = if field.is_empty() {
                    name.to_string()
                } else {
                    format!("{field}.{name}")
                };
            }
            (field, problem)
        })?;
        s.check()?;
        Ok(s)
    }

    /// The checks serde cannot make: ranges, and what the firmware's config accepts.
    fn check(&self) -> Result<(), (String, String)> {
        let bad = |field: &str, problem: String| Err((field.to_string(), problem));
        let (w, h) = (self.area.width_m, self.area.height_m);
        for (f, v) in [("area.width_m", w), ("area.height_m", h)] {
            if !(v > 0.0 && v <= 300.0) {
                return bad(f, format!("{v} is not within (0, 300] m"));
            }
        }
        let inside = |p: [f64; 2]| (0.0..=w).contains(&p[0]) && (0.0..=h).contains(&p[1]);
        let finite = |field: &str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                bad(field, format!("{v} is not a finite number"))
            }
        };
        for (i, a) in self.anchors.iter().enumerate() {
            finite(
                &format!("anchors[{i}].position"),
                a.position[0] + a.position[1],
            )?;
            finite(&format!("anchors[{i}].orientation_deg"), a.orientation_deg)?;
        }
        finite("agent.orientation_deg", self.agent.orientation_deg)?;
        for (i, stop) in self.agent.path.iter().enumerate() {
            finite(
                &format!("agent.path[{i}].position"),
                stop.position[0] + stop.position[1],
            )?;
            if let Some(o) = stop.orientation_deg {
                finite(&format!("agent.path[{i}].orientation_deg"), o)?;
            }
        }
        let n = self.anchors.len();
        if !(3..=loc_proto::msg::MAX_ANCHORS).contains(&n) {
            return bad(
                "anchors",
                format!(
                    "{n} anchors; the network takes 3…{}",
                    loc_proto::msg::MAX_ANCHORS
                ),
            );
        }
        for (i, a) in self.anchors.iter().enumerate() {
            if !inside(a.position) {
                return bad(
                    &format!("anchors[{i}].position"),
                    format!("{:?} is outside the {w} m × {h} m area", a.position),
                );
            }
            if let Some(p) = a.true_position.filter(|&p| !inside(p)) {
                return bad(
                    &format!("anchors[{i}].true_position"),
                    format!("{p:?} is outside the {w} m × {h} m area"),
                );
            }
        }
        self.check_geometry()?;
        let t = &self.timing;
        let (lo, hi) = (
            loc_proto::config::MIN_SLOT_MS,
            loc_proto::config::MAX_SLOT_MS,
        );
        if !(lo..=hi).contains(&t.slot_ms) {
            return bad(
                "timing.slot_ms",
                format!("{} is not within {lo}…{hi}", t.slot_ms),
            );
        }
        let n = self.anchors.len().min(u8::MAX as usize) as u8;
        if !loc_proto::schedule::slot_fits_beacon(n, t.slot_ms) {
            return bad(
                "timing.slot_ms",
                format!(
                    "{} ms cannot hold a beacon of {n} anchors: a slot needs its guard and the \
                     beacon's way over the UARTs and the air, at least {} ms",
                    t.slot_ms,
                    loc_proto::schedule::min_slot_ms(n)
                ),
            );
        }
        if t.channels.is_empty() || t.channels.len() > 4 {
            return bad(
                "timing.channels",
                format!("{} channels; the network hops over 1…4", t.channels.len()),
            );
        }
        let max = loc_proto::msg::MAX_CHANNEL;
        for (i, &c) in t.channels.iter().enumerate() {
            if !(1..=max).contains(&c) {
                return bad(
                    &format!("timing.channels[{i}]"),
                    format!("channel {c} is not within 1…{max}"),
                );
            }
            if t.channels[..i].contains(&c) {
                return bad(
                    &format!("timing.channels[{i}]"),
                    format!("channel {c} is listed twice"),
                );
            }
        }
        if !(1..=max).contains(&t.sink_channel) {
            return bad(
                "timing.sink_channel",
                format!("channel {} is not within 1…{max}", t.sink_channel),
            );
        }
        if t.channels.contains(&t.sink_channel) {
            return bad(
                "timing.sink_channel",
                format!("channel {} is also an anchor channel", t.sink_channel),
            );
        }
        let year = crate::args::MAX_SECONDS;
        if !(t.warmup_s >= 0.0 && t.warmup_s <= year) {
            return bad(
                "timing.warmup_s",
                format!("{} is not within 0…{year} s", t.warmup_s),
            );
        }
        if t.network_key.is_some() && t.key().is_none() {
            return bad(
                "timing.network_key",
                "not a network key: 32 hex digits (16 bytes)".to_string(),
            );
        }
        let m = &self.medium;
        if !(m.alpha > 0.0 && m.alpha <= 10.0) {
            return bad("medium.alpha", format!("{} is not within (0, 10]", m.alpha));
        }
        for (f, v, hi, unit) in [
            ("medium.sigma_db", m.sigma_db, 30.0, "dB"),
            ("medium.fading_sigma_db", m.fading_sigma_db, 30.0, "dB"),
            ("medium.drift_start_s", m.drift_start_s, year, "s"),
        ] {
            if !(v >= 0.0 && v <= hi) {
                return bad(f, format!("{v} is not within 0…{hi} {unit}"));
            }
        }
        if !(-150.0..=30.0).contains(&m.p0_dbm) {
            return bad(
                "medium.p0_dbm",
                format!("{} is not within −150…30 dBm", m.p0_dbm),
            );
        }
        if !(-150..=0).contains(&m.sensitivity_dbm) {
            return bad(
                "medium.sensitivity_dbm",
                format!("{} is not within −150…0 dBm", m.sensitivity_dbm),
            );
        }
        if !(-60.0..=60.0).contains(&m.drift_db_per_min) {
            return bad(
                "medium.drift_db_per_min",
                format!("{} is not within −60…60 dB per minute", m.drift_db_per_min),
            );
        }
        if self.agent.path.is_empty() {
            return bad("agent.path", "the agent has no stop".into());
        }
        for (i, s) in self.agent.path.iter().enumerate() {
            if !inside(s.position) {
                return bad(
                    &format!("agent.path[{i}].position"),
                    format!("{:?} is outside the {w} m × {h} m area", s.position),
                );
            }
            if !(s.dwell_s > 0.0 && s.dwell_s <= year) {
                return bad(
                    &format!("agent.path[{i}].dwell_s"),
                    format!("{} is not > 0 and at most {year} s", s.dwell_s),
                );
            }
        }
        if self.duration_s() > year {
            return bad(
                "agent.path",
                format!(
                    "the run would last {} s, more than a year",
                    self.duration_s()
                ),
            );
        }
        self.check_hearing()
    }

    /// Anchors far enough apart, not all on one line: else positions on either side of the
    /// line (or around the one spot) give the same RSSI, and no estimator can tell them apart.
    fn check_geometry(&self) -> Result<(), (String, String)> {
        let p: Vec<[f64; 2]> = self.anchors.iter().map(|a| a.position).collect();
        let dist = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
        for i in 0..p.len() {
            for j in 0..i {
                if dist(p[i], p[j]) < MIN_ANCHOR_SPACING_M {
                    return Err((
                        format!("anchors[{i}].position"),
                        format!(
                            "{:?} is on the spot of anchors[{j}] ({:?}, less than {} m away): \
                             anchors must stand apart",
                            p[i], p[j], MIN_ANCHOR_SPACING_M
                        ),
                    ));
                }
            }
        }
        // The largest distance of an anchor from the line through two others.
        let mut widest = 0.0f64;
        for i in 0..p.len() {
            for j in 0..i {
                for k in 0..p.len() {
                    let (a, b, c) = (p[i], p[j], p[k]);
                    let cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
                    widest = widest.max(cross.abs() / dist(a, b));
                }
            }
        }
        if widest < MIN_ANCHOR_SPACING_M {
            return Err((
                "anchors".to_string(),
                format!(
                    "every anchor is on one line (within {MIN_ANCHOR_SPACING_M} m): a position \
                     and its mirror image across the line give the same RSSI"
                ),
            ));
        }
        Ok(())
    }

    /// The best level a packet can arrive with from `a` to `b`, dBm: the mean path loss at
    /// their distance, plus three standard deviations of shadowing and fading together, plus
    /// both antennas' largest gain ([`Antenna::max_gain_db`], any unit; drift left out).
    pub fn best_level_dbm(&self, a: [f64; 2], b: [f64; 2], antennas: [AntennaKind; 2]) -> f64 {
        let m = &self.medium;
        let min_d = MediumConfig::default().min_distance_m;
        let d = (a[0] - b[0]).hypot(a[1] - b[1]).max(min_d);
        let spread = 3.0 * m.sigma_db.hypot(m.fading_sigma_db);
        let peak = |k: AntennaKind| Antenna::from(k).max_gain_db();
        m.p0_dbm - 10.0 * m.alpha * d.log10() + spread + peak(antennas[0]) + peak(antennas[1])
    }

    /// At every stop of the agent, at least 3 anchors can be heard and the sink (in the
    /// middle of the room) can hear the agent, at the best level the medium gives
    /// ([`Scenario::best_level_dbm`]): else no report, or no fix, can come from there.
    fn check_hearing(&self) -> Result<(), (String, String)> {
        let m = &self.medium;
        let sens = f64::from(m.sensitivity_dbm);
        let agent = self.agent.antenna;
        let sink = [self.area.width_m / 2.0, self.area.height_m / 2.0];
        for (i, stop) in self.agent.path.iter().enumerate() {
            let heard = self
                .anchors
                .iter()
                .filter(|a| {
                    self.best_level_dbm(a.position, stop.position, [a.antenna, agent]) >= sens
                })
                .count();
            if heard < 3 {
                return Err((
                    format!("agent.path[{i}].position"),
                    format!(
                        "{:?}: the agent can hear {heard} of the {} anchors here even at their \
                         best level (P0 {} dBm, α {}, 3σ of shadowing and fading, the antennas' \
                         peak gain) against a sensitivity of {} dBm; a fix needs 3",
                        stop.position,
                        self.anchors.len(),
                        m.p0_dbm,
                        m.alpha,
                        m.sensitivity_dbm
                    ),
                ));
            }
            let to_sink = self.best_level_dbm(stop.position, sink, [agent, AntennaKind::Isotropic]);
            if to_sink < sens {
                return Err((
                    format!("agent.path[{i}].position"),
                    format!(
                        "{:?}: the sink, in the middle of the room at {sink:?}, cannot hear the \
                         agent here even at its best level ({to_sink:.1} dBm against a \
                         sensitivity of {} dBm)",
                        stop.position, m.sensitivity_dbm
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The medium's configuration (seeded with [`Scenario::seed`]).
    pub fn medium_config(&self) -> MediumConfig {
        let m = &self.medium;
        MediumConfig {
            p0_dbm: m.p0_dbm,
            alpha: m.alpha,
            sigma_db: m.sigma_db,
            fading_sigma_db: m.fading_sigma_db,
            sensitivity_dbm: m.sensitivity_dbm,
            drift_db_per_min: m.drift_db_per_min,
            drift_start_ms: m.drift_start_s * 1000.0,
            antenna_unit_variation: m.antenna_unit_variation,
            seed: self.seed,
            ..MediumConfig::default()
        }
    }

    /// Simulated time of the whole run: warm-up and every stop, s.
    pub fn duration_s(&self) -> f64 {
        self.timing.warmup_s + self.agent.path.iter().map(|s| s.dwell_s).sum::<f64>()
    }

    /// The room in cm, as the sink takes it.
    pub fn area_cm(&self) -> loc_core::fixed::AreaCm {
        loc_core::fixed::AreaCm::new(
            (self.area.width_m * 100.0).round() as u16,
            (self.area.height_m * 100.0).round() as u16,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
name = "t"
description = "a test"
seed = 7
area = { width_m = 10.0, height_m = 10.0 }
timing = { slot_ms = 62, channels = [1, 12] }
medium = { p0_dbm = -40.0, alpha = 3.0, sigma_db = 2.0, fading_sigma_db = 3.0, sensitivity_dbm = -92 }
[[anchors]]
position = [0.0, 0.0]
[[anchors]]
position = [10.0, 0.0]
antenna = "chip"
orientation_deg = 135.0
[[anchors]]
position = [10.0, 10.0]
[agent]
antenna = "wire"
path = [ { position = [5.0, 5.0], dwell_s = 10.0 }, { position = [2.0, 3.0], dwell_s = 5.0, orientation_deg = 225.0 } ]
"#;

    #[test]
    fn a_good_file_loads_with_its_defaults() {
        let s = Scenario::parse(GOOD).unwrap();
        assert_eq!(s.anchors.len(), 3);
        assert_eq!(s.anchors[1].antenna, AntennaKind::Chip);
        assert_eq!(s.anchors[0].antenna, AntennaKind::Isotropic);
        // An anchor stands where it is configured unless the file says otherwise.
        assert_eq!(s.anchors[2].true_position, None);
        assert_eq!(s.anchors[2].radio_position(), [10.0, 10.0]);
        let moved = GOOD.replacen(
            "position = [10.0, 10.0]",
            "position = [10.0, 10.0]\ntrue_position = [6.0, 6.0]",
            1,
        );
        let m = Scenario::parse(&moved).unwrap();
        assert_eq!(m.anchors[2].position, [10.0, 10.0]);
        assert_eq!(m.anchors[2].radio_position(), [6.0, 6.0]);
        assert_eq!(s.timing.sink_channel, 3);
        assert_eq!(s.timing.warmup_s, 8.0);
        assert_eq!(s.agent.path[1].orientation_deg, Some(225.0));
        assert_eq!(s.duration_s(), 23.0);
        assert_eq!(s.medium_config().seed, 7);
        assert_eq!(s.area_cm(), loc_core::fixed::AreaCm::new(1000, 1000));
    }

    /// `GOOD` with `from` replaced by `to`: the error's field and a word of its problem.
    fn error(from: &str, to: &str) -> (String, String) {
        assert!(GOOD.contains(from), "{from}");
        Scenario::parse(&GOOD.replacen(from, to, 1)).unwrap_err()
    }

    #[test]
    fn bad_files_name_the_field_and_the_problem() {
        let cases = [
            ("seed = 7", "seed = \"x\"", "seed", "invalid type"),
            ("seed = 7", "", "seed", "missing field"),
            (
                "seed = 7",
                "seed = 7\ncolour = 1",
                "colour",
                "unknown field",
            ),
            (
                "antenna = \"chip\"",
                "antenna = \"horn\"",
                "anchors[1].antenna",
                "unknown variant",
            ),
            ("slot_ms = 62", "slot_ms = 1", "timing.slot_ms", "within"),
            ("[1, 12]", "[1, 17]", "timing.channels[1]", "channel 17"),
            (
                "[1, 12]",
                "[3, 12]",
                "timing.sink_channel",
                "also an anchor",
            ),
            (
                "[10.0, 10.0]",
                "[10.0, 10.5]",
                "anchors[2].position",
                "outside",
            ),
            (
                "position = [10.0, 10.0]",
                "position = [10.0, 10.0]\ntrue_position = [6.0, -0.1]",
                "anchors[2].true_position",
                "outside",
            ),
            (
                "position = [10.0, 10.0]",
                "position = [10.0, 10.0]\ntrue_position = [6.0]",
                "anchors[2].true_position",
                "invalid length",
            ),
            (
                "dwell_s = 5.0",
                "dwell_s = 0.0",
                "agent.path[1].dwell_s",
                "> 0",
            ),
            (
                "[2.0, 3.0]",
                "[-2.0, 3.0]",
                "agent.path[1].position",
                "outside",
            ),
            ("width_m = 10.0", "width_m = -1.0", "area.width_m", "within"),
            ("alpha = 3.0", "alpha = 0.0", "medium.alpha", "within"),
            ("seed = 7", "seed = = 7", "", "not valid TOML"),
            // Values that cannot work.
            (
                "position = [0.0, 0.0]",
                "position = [nan, 0.0]",
                "anchors[0].position",
                "finite",
            ),
            (
                "[2.0, 3.0]",
                "[2.0, inf]",
                "agent.path[1].position",
                "finite",
            ),
            (
                "orientation_deg = 135.0",
                "orientation_deg = nan",
                "anchors[1].orientation_deg",
                "finite",
            ),
            (
                "dwell_s = 5.0",
                "dwell_s = inf",
                "agent.path[1].dwell_s",
                "at most",
            ),
            (
                "sigma_db = 2.0",
                "sigma_db = nan",
                "medium.sigma_db",
                "0…30 dB",
            ),
            (
                "p0_dbm = -40.0",
                "p0_dbm = -inf",
                "medium.p0_dbm",
                "−150…30 dBm",
            ),
            (
                "sensitivity_dbm = -92",
                "sensitivity_dbm = 5",
                "medium.sensitivity_dbm",
                "−150…0 dBm",
            ),
            (
                "sigma_db = 2.0",
                "sigma_db = 2.0, drift_db_per_min = nan",
                "medium.drift_db_per_min",
                "−60…60",
            ),
            (
                "[10.0, 0.0]",
                "[0.05, 0.0]",
                "anchors[1].position",
                "on the spot of anchors[0]",
            ),
            ("[10.0, 10.0]", "[7.0, 0.0]", "anchors", "on one line"),
            // Nothing is heard: a sensitivity above every level in the room.
            (
                "sensitivity_dbm = -92",
                "sensitivity_dbm = -40",
                "agent.path[0].position",
                "can hear 0 of the 3 anchors",
            ),
            // A path loss too steep for the room: the anchors are too far away.
            (
                "alpha = 3.0",
                "alpha = 10.0",
                "agent.path[0].position",
                "a fix needs 3",
            ),
        ];
        for (from, to, field, problem) in cases {
            let (f, p) = error(from, to);
            assert_eq!(f, field, "{to}: {p}");
            assert!(p.contains(problem), "{to}: {p}");
        }
        // Too few anchors.
        let two = GOOD.replacen("[[anchors]]\nposition = [0.0, 0.0]\n", "", 1);
        assert_eq!(Scenario::parse(&two).unwrap_err().0, "anchors");
    }

    #[test]
    fn the_sink_must_hear_the_agent() {
        // Anchors and agent in one corner of a large room, the sink in its middle.
        let far = GOOD
            .replace(
                "width_m = 10.0, height_m = 10.0",
                "width_m = 300.0, height_m = 300.0",
            )
            .replace("[10.0, 0.0]", "[5.0, 0.0]")
            .replace("[10.0, 10.0]", "[5.0, 5.0]")
            .replace("[5.0, 5.0], dwell_s", "[2.0, 2.0], dwell_s");
        let (field, problem) = Scenario::parse(&far).unwrap_err();
        assert_eq!(field, "agent.path[0].position");
        assert!(problem.contains("the sink"), "{problem}");
    }

    #[test]
    fn a_load_error_names_the_file() {
        let e = Scenario::load(Path::new("/nonexistent/x.toml")).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("/nonexistent/x.toml: cannot read"),
            "{e}"
        );
    }

    #[test]
    fn every_shipped_scenario_loads() {
        let files = shipped();
        for name in ["exp1", "exp2", "exp3", "exp3-ideal", "room10"] {
            assert!(files.contains(&resolve(name)), "{name} missing: {files:?}");
        }
        for f in files {
            let s = Scenario::load(&f).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(
                Some(s.name.as_str()),
                f.file_stem().and_then(|x| x.to_str())
            );
        }
    }
}
