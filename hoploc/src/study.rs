//! The Monte Carlo study behind `hoploc simulate`: the thesis' localization study on the
//! loc-core f64 reference estimators, fast enough to rerun at will.
//!
//! # The study
//!
//! * Area `W × H` (thesis: 10 m × 10 m); anchors at `(0,0)`, `(W,0)`, `(W,H)` and, for four,
//!   `(0,H)`; the agent at every point `(W·(k+1)/20, H·(m+1)/20)`, `k, m = 0…18` (361 points,
//!   point index `19·k + m`: x-major); `runs` trials per point; `C` channels (default 2) with
//!   independent `N(0, σ²)` shadowing per anchor and channel; true model `P0`, `α`.
//! * Columns: every single channel (`Ch1`, `Ch2`, …), `Max`, `Linear avg` and `Ext-MCH`
//!   ([`loc_core::refine::Refinement`]); rows per anchor count `n`: `MLE-n`, `MMSE-n`,
//!   (on request: `MMSE-window-n`, the sink's windowed MMSE), `MDS-n`, `TRLT-3` (three anchors)
//!   or `QUAD-n` (four or more), then the bounds `CRLB-n` and `MMSE-floor-n` (unless
//!   [`Config::floor`] is off). The baselines work on distances, so they
//!   have no `Ext-MCH` cell.
//! * Metric per cell: the per-point RMSE over the runs, averaged over the points; its Monte Carlo
//!   standard error ([`Cell::rmse_se`]); the bias, the standard deviation over the points of the
//!   per-point mean error in x and in y (population standard deviation, as numpy's `std`).
//!
//! # Parameters the estimators use ([`ParamSource`])
//!
//! * `Known`: the true `P0`, `α` and σ (the thesis).
//! * `Estimated`: per trial, every ordered anchor pair also measures RSSI on every channel with
//!   the same shadowing; each column fits `P0` and `α` ([`loc_core::params::fit`], P0 and α, the
//!   thesis' bounds α ∈ [2, 5], P0 ∈ [−60, −20] dBm) to the anchor-to-anchor samples *refined like
//!   the column's agent data* (`Ch1` fits channel 1's samples, `Max` the per-pair maximum over
//!   the channels, `Linear avg` the per-pair mW mean, `Ext-MCH` every channel's sample), so a
//!   refinement's bias (the maximum of two draws is ≈ 0.56 σ high) is calibrated away as a real
//!   sink applying one refinement to all its RSSI would; the MMSE uses the fit's residual σ
//!   ([`loc_core::params::ParamFit::sigma`]).
//! * `Ar1`: the same fits smoothed over the runs at a point (the runs are a time series) by
//!   [`loc_core::params::Ar1`] (a = 0.8, b = 0.2) per parameter, σ included; each fit takes the
//!   smoothed model as its prior.
//!
//! # The bounds
//!
//! * `CRLB-n`: the mean over the points of [`loc_core::bounds::crlb`] (true model and σ). The
//!   channel count `C` is the number of channels the column's data comes from: 1 for `ChN`, all
//!   `C` for `Max`, `Linear avg` and `Ext-MCH`. (Max and Linear avg compress the channels to one
//!   value per anchor; its Fisher information lies between one channel's and all channels', and
//!   only the all-channel figure is a bound for every estimator on that data.)
//! * `MMSE-floor-n`: the per-point RMSE of the posterior mean that knows the true model and σ
//!   ([`loc_core::bounds::mmse_floor`]'s estimator) on the study's own draws, averaged over the
//!   points: for `ChN` on channel N's draws (one channel), for `Max`, `Linear avg`, `Ext-MCH` on
//!   all channels (the per-anchor dB mean with weight `C`, which is the whole multichannel
//!   posterior). It is computed by this module's lattice kernel (see below); in `Known` mode the
//!   `MMSE` rows *are* that estimator on the same draws, so when they are computed the floor is
//!   taken from them (`ChN` from `ChN`, the rest from `Ext-MCH`). The unit tests check the kernel
//!   against [`loc_core::bounds::mmse_floor`] on the same draws.
//!
//! # Speed and exactness
//!
//! Every position any estimator evaluates is a point of loc-core's fine lattice
//! ([`loc_core::grid::lattice_point`], 51 × 51), so per anchor layout this module tabulates
//! `log10(d²)` from each anchor to each lattice point once. The cost of a lattice point is then
//! `Σ wᵢ (zᵢ − P0 + 5α·log10 d²)²`, evaluated in exactly loc-core's operation order, so:
//!
//! * the MLE is [`loc_core::grid::search_lattice`] on that table: bit-identical to
//!   [`loc_core::grid::mle`] for any model (tested);
//! * the MMSE is the posterior mean over the same 2 601 lattice points, computed in vectorisable
//!   passes over fixed 8-point lanes instead of [`loc_core::grid::posterior_mean_lattice`]'s
//!   streaming scalar pass with `libm::exp` (which made the MMSE alone slower than the whole
//!   numpy study's budget): (1) the costs — with equal weights, as every study column has, in the
//!   expanded form `k²·Σ Lᵢ² + Σ 2k·rᵢ·Lᵢ` (`L = log10 d²`, `Σ Lᵢ²` tabulated, the constant
//!   `Σ rᵢ²` dropped), `N + 1` multiply-adds per point — and their minimum; (2) the weights
//!   `2^(−(c − c_min)·log2(e)/2σ²)` by a branch-free polynomial `exp2` (relative error < 3e-14),
//!   skipping 8-point chunks whose weights are all below `2^-72` (their total is under 1e-18 of
//!   the weight sum), and the weighted index sums. The estimate agrees with
//!   [`loc_core::grid::mmse`] to 1e-12 m (tested over random trials, areas and models). On x86-64
//!   the kernel is also compiled for AVX2 and AVX-512F and picked at run time
//!   ([`Kernel::detect`]); no FMA is enabled and rustc never contracts `a·b + c`, so each lane
//!   does the same IEEE operations in the same order on every path and the results are
//!   bit-identical (tested);
//! * the windowed MMSE is [`loc_core::grid::posterior_mean_window`] on the tabulated cost (at most
//!   233 points, no kernel needed): bit-identical to [`loc_core::grid::mmse_window`] (tested);
//! * the baselines are [`loc_core::baselines::Baseline::estimate`] on the distance estimates
//!   [`PathLoss::distance`].
//!
//! # Random numbers and determinism
//!
//! Each (σ, anchor count, point) has its own xoshiro256++ streams ([`rand_xoshiro`]), seeded by
//! SplitMix64-mixing `(seed, σ's bits, anchor count, point index, stream)`: stream 0 draws the
//! agent's noise (per run: anchor-major, then channel), stream 1 the anchor-to-anchor noise, so
//! the `Known` and `Estimated` studies see the same agent noise. Normal draws are Box–Muller on
//! [`libm`] (the same numbers on every platform). Points are spread over threads, but every
//! point's result depends only on its own streams and the reduction over points runs in point
//! order, so the tables are identical whatever the thread count.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use loc_core::baselines::Baseline;
use loc_core::grid::{self, Search, FINE_DIVS};
use loc_core::model::MIN_DISTANCE;
use loc_core::params::{self, Ar1, Bounds as ParamBounds, CalStats, FitMethod, ParamMode};
use loc_core::refine::{self, Refinement};
use loc_core::{Area, PathLoss, Point, MAX_ANCHORS, MAX_CHANNELS};
use rand_xoshiro::rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::Serialize;

/// Agent positions per side: `k = 0…18`.
pub const POINTS_PER_SIDE: usize = 19;
/// Fine lattice points per side.
const SIDE: usize = FINE_DIVS + 1;
/// Fine lattice points.
const LATTICE: usize = SIDE * SIDE;
/// Lanes of the posterior kernel's reductions (fixed, so the summation order never depends on
/// the SIMD width).
const LANES: usize = 8;
/// Lattice size padded to whole lanes; padding costs are +∞ (zero weight).
const PADDED: usize = LATTICE.div_ceil(LANES) * LANES;

/// A position estimator of the study.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum Algo {
    /// Grid maximum likelihood ([`loc_core::grid::mle`]).
    #[serde(rename = "MLE")]
    Mle,
    /// Lattice posterior mean ([`loc_core::grid::mmse`]).
    #[serde(rename = "MMSE")]
    Mmse,
    /// Posterior mean over the thesis' fine window, the sink's MMSE
    /// ([`loc_core::grid::mmse_window`]); not in [`Algo::DEFAULT`].
    #[serde(rename = "MMSE-window")]
    MmseWindow,
    /// MDS-MAP.
    #[serde(rename = "MDS")]
    Mds,
    /// Trilateration (three anchors).
    #[serde(rename = "TRLT")]
    Trlt,
    /// Quadlateration (four or more anchors).
    #[serde(rename = "QUAD")]
    Quad,
}

impl Algo {
    /// Every estimator, in table order.
    pub const ALL: [Algo; 6] = [
        Algo::Mle,
        Algo::Mmse,
        Algo::MmseWindow,
        Algo::Mds,
        Algo::Trlt,
        Algo::Quad,
    ];

    /// The estimators of the thesis study (`hoploc simulate`'s default): all but the windowed
    /// MMSE, an MCU economy that is selected explicitly.
    pub const DEFAULT: [Algo; 5] = [Algo::Mle, Algo::Mmse, Algo::Mds, Algo::Trlt, Algo::Quad];

    /// The table label's stem.
    pub const fn label(self) -> &'static str {
        match self {
            Algo::Mle => "MLE",
            Algo::Mmse => "MMSE",
            Algo::MmseWindow => "MMSE-window",
            Algo::Mds => "MDS",
            Algo::Trlt => "TRLT",
            Algo::Quad => "QUAD",
        }
    }

    /// `MLE`, `mmse`, `mmse-window`, … (case-insensitive).
    pub fn parse(s: &str) -> Option<Algo> {
        Algo::ALL
            .into_iter()
            .find(|a| a.label().eq_ignore_ascii_case(s.trim()))
    }

    /// Whether the estimator has a row with `n` anchors (TRLT with three, QUAD with four or more,
    /// the rest always).
    pub const fn applies(self, n: usize) -> bool {
        match self {
            Algo::Trlt => n == 3,
            Algo::Quad => n >= 4,
            _ => true,
        }
    }

    const fn baseline(self) -> Option<Baseline> {
        match self {
            Algo::Mds => Some(Baseline::MdsMap),
            Algo::Trlt => Some(Baseline::Trilateration),
            Algo::Quad => Some(Baseline::Quadlateration),
            _ => None,
        }
    }
}

/// Which path-loss parameters (and σ) the estimators use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum ParamSource {
    /// The true model and σ.
    Known,
    /// Fitted per trial from simulated anchor-to-anchor RSSI.
    Estimated,
    /// Fitted per trial, AR(1)-smoothed over the runs at a point.
    Ar1,
}

/// One column: a channel refinement.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Column {
    /// Table label: `Ch1`, …, `Max`, `Linear avg`, `Ext-MCH`.
    pub label: String,
    /// The refinement.
    #[serde(skip)]
    pub refinement: Refinement,
}

impl Column {
    /// The columns for `channels` channels.
    pub fn all(channels: usize) -> Vec<Column> {
        let mut v: Vec<Column> = (0..channels)
            .map(|c| Column {
                label: format!("Ch{}", c + 1),
                refinement: Refinement::Single(c),
            })
            .collect();
        for (label, refinement) in [
            ("Max", Refinement::Max),
            ("Linear avg", Refinement::LinearAvg),
            ("Ext-MCH", Refinement::Extended),
        ] {
            v.push(Column {
                label: label.into(),
                refinement,
            });
        }
        v
    }

    /// Channels the column's data comes from (the CRLB's `C`).
    fn channels(&self, all: usize) -> usize {
        match self.refinement {
            Refinement::Single(_) => 1,
            _ => all,
        }
    }
}

/// What to simulate.
#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// The area (anchors at its corners).
    pub area: Area,
    /// Anchor layouts to study: 3 and/or 4 anchors.
    pub anchor_counts: Vec<usize>,
    /// Trials per point.
    pub runs: usize,
    /// Shadowing σ values, dB (one table each).
    pub sigmas: Vec<f64>,
    /// Channels with independent noise (1…4).
    pub channels: usize,
    /// The true model.
    pub truth: PathLoss,
    /// What the estimators know.
    pub params: ParamSource,
    /// How parameters are fitted when they are estimated.
    pub fit: FitMethod,
    /// Estimators to run (the bounds rows are always there).
    pub algos: Vec<Algo>,
    /// The MLE's grid search.
    pub search: Search,
    /// Clip the baselines' estimates to the area (the thesis did: its Tables 3.1 and 3.3 are
    /// reproduced only so; unclipped, a trilateration that lands metres outside the room counts
    /// with its full error).
    pub clip: bool,
    /// Compute the MMSE floor rows (free with known parameters and the MMSE rows selected;
    /// otherwise about the cost of three MMSE columns).
    pub floor: bool,
    /// Master seed.
    pub seed: u64,
    /// Worker threads (≥ 1); the results do not depend on it.
    pub threads: usize,
}

impl Default for Config {
    /// The thesis study: 10 m × 10 m, 3 and 4 anchors, 100 runs, σ = 2 and 4 dB, two channels,
    /// P0 = −40 dBm, α = 3 known, the [`Algo::DEFAULT`] estimators, the thesis search, the
    /// baselines clipped to the area, seed 1.
    fn default() -> Self {
        Config {
            area: Area::new(10.0, 10.0),
            anchor_counts: vec![3, 4],
            runs: 100,
            sigmas: vec![2.0, 4.0],
            channels: 2,
            truth: PathLoss::THESIS,
            params: ParamSource::Known,
            fit: FitMethod::LeastSquares,
            algos: Algo::DEFAULT.to_vec(),
            search: Search::Thesis,
            clip: true,
            floor: true,
            seed: 1,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        }
    }
}

impl Config {
    /// Checks the configuration; the message says what is wrong.
    pub fn validate(&self) -> Result<(), String> {
        let a = self.area;
        if !(a.width > 0.0 && a.width.is_finite() && a.height > 0.0 && a.height.is_finite()) {
            return Err(format!(
                "area {} × {} m: both sides must be positive",
                a.width, a.height
            ));
        }
        if self.anchor_counts.is_empty() || self.anchor_counts.iter().any(|n| !(3..=4).contains(n))
        {
            return Err("anchor counts must be 3 and/or 4".into());
        }
        if self.runs == 0 {
            return Err("runs must be at least 1".into());
        }
        if self.sigmas.is_empty() || self.sigmas.iter().any(|s| !(*s > 0.0 && s.is_finite())) {
            return Err("every σ must be a positive number of dB".into());
        }
        if !(1..=MAX_CHANNELS).contains(&self.channels) {
            return Err(format!("channels must be 1…{MAX_CHANNELS}"));
        }
        if !(self.truth.p0.is_finite() && self.truth.alpha > 0.0 && self.truth.alpha.is_finite()) {
            return Err("the model needs a finite P0 and a positive α".into());
        }
        if self.algos.is_empty() {
            return Err("no estimator selected".into());
        }
        if self.threads == 0 {
            return Err("threads must be at least 1".into());
        }
        Ok(())
    }

    /// The columns of the tables.
    pub fn columns(&self) -> Vec<Column> {
        Column::all(self.channels)
    }
}

/// The anchors of an `n`-anchor layout in `area`.
pub fn anchors(area: Area, n: usize) -> Vec<Point> {
    let (w, h) = (area.width, area.height);
    [
        Point::new(0.0, 0.0),
        Point::new(w, 0.0),
        Point::new(w, h),
        Point::new(0.0, h),
    ][..n.min(4)]
        .to_vec()
}

/// The agent positions, x-major.
pub fn points(area: Area) -> Vec<Point> {
    let n = (POINTS_PER_SIDE + 1) as f64;
    let mut v = Vec::with_capacity(POINTS_PER_SIDE * POINTS_PER_SIDE);
    for k in 0..POINTS_PER_SIDE {
        for m in 0..POINTS_PER_SIDE {
            v.push(Point::new(
                area.width * (k + 1) as f64 / n,
                area.height * (m + 1) as f64 / n,
            ));
        }
    }
    v
}

/// What a row holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RowKind {
    /// An estimator's errors.
    Estimator(Algo),
    /// The Cramér–Rao lower bound.
    Crlb,
    /// The MMSE floor.
    MmseFloor,
}

/// One cell of a table.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Cell {
    /// Mean over the points of the per-point RMSE, metres (for CRLB: of the per-point bound).
    pub rmse: f64,
    /// Monte Carlo standard error of `rmse` (delta method on each point's mean squared error);
    /// `None` for the CRLB.
    pub rmse_se: Option<f64>,
    /// Standard deviation over the points of the per-point mean x error, metres (estimators only).
    pub bias_x: Option<f64>,
    /// The same in y.
    pub bias_y: Option<f64>,
    /// Trials whose baseline estimate failed (counted at the area's centre).
    pub failures: u64,
    /// Per-point RMSE (or bound), point order.
    #[serde(skip)]
    pub per_point_rmse: Vec<f64>,
    /// Per-point bias magnitude `|mean error|`, point order (estimators only, else empty).
    #[serde(skip)]
    pub per_point_bias: Vec<f64>,
}

/// One row: an estimator or a bound with one anchor layout.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Row {
    /// `MLE-3`, `CRLB-4`, `MMSE-floor-3`, …
    pub label: String,
    /// What it is.
    pub kind: RowKind,
    /// Anchors.
    pub anchors: usize,
    /// One per column; `None` where the row has no such column (baselines: Ext-MCH).
    pub cells: Vec<Option<Cell>>,
}

/// The tables of one σ.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Table {
    /// Shadowing σ, dB.
    pub sigma: f64,
    /// Rows in order.
    pub rows: Vec<Row>,
}

/// The study's description, as recorded with its results.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Area width, m.
    pub width: f64,
    /// Area height, m.
    pub height: f64,
    /// Anchor layouts.
    pub anchor_counts: Vec<usize>,
    /// Agent positions.
    pub points: usize,
    /// Trials per point.
    pub runs: usize,
    /// Channels.
    pub channels: usize,
    /// True P0, dBm.
    pub p0: f64,
    /// True α.
    pub alpha: f64,
    /// What the estimators know.
    pub params: ParamSource,
    /// Fit method when estimated (`ls` or `grid`).
    pub fit: String,
    /// MLE search.
    pub search: String,
    /// Baselines clipped.
    pub clip: bool,
    /// MMSE floor rows computed.
    pub floor: bool,
    /// Master seed.
    pub seed: u64,
}

/// Everything the study found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StudyResult {
    /// What was simulated.
    pub config: Summary,
    /// Column labels.
    pub columns: Vec<String>,
    /// One per σ, in the configured order.
    pub tables: Vec<Table>,
}

/// `name` of a search (`thesis`, `multistart`, `exhaustive`).
pub fn search_name(s: Search) -> &'static str {
    match s {
        Search::Thesis => "thesis",
        Search::MultiStart => "multistart",
        Search::Exhaustive => "exhaustive",
    }
}

/// `name` of a fit method (`ls`, `grid`).
pub fn fit_name(f: FitMethod) -> &'static str {
    match f {
        FitMethod::LeastSquares => "ls",
        FitMethod::Grid => "grid",
    }
}

// ---------------------------------------------------------------------------------------------
// Random numbers.

/// SplitMix64's output function (Steele, Lea, Flood 2014).
fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The seed of one stream: `(seed, σ, anchors, point, stream)` mixed.
pub fn stream_seed(seed: u64, sigma: f64, anchors: usize, point: usize, stream: u64) -> u64 {
    [sigma.to_bits(), anchors as u64, point as u64, stream]
        .into_iter()
        .fold(splitmix(seed), |h, v| splitmix(h ^ v))
}

/// Standard normal draws by Box–Muller on a xoshiro256++ stream.
pub struct Normal {
    rng: Xoshiro256PlusPlus,
    spare: Option<f64>,
}

impl Normal {
    /// A stream seeded with `seed` (see [`stream_seed`]).
    pub fn new(seed: u64) -> Normal {
        Normal {
            rng: Xoshiro256PlusPlus::seed_from_u64(seed),
            spare: None,
        }
    }

    /// Uniform in (0, 1]: 53 random bits.
    fn uniform(&mut self) -> f64 {
        ((self.rng.next_u64() >> 11) + 1) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// The next N(0, 1) draw.
    pub fn draw(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        let r = libm::sqrt(-2.0 * libm::log(self.uniform()));
        let (s, c) = libm::sincos(2.0 * std::f64::consts::PI * self.uniform());
        self.spare = Some(r * s);
        r * c
    }
}

// ---------------------------------------------------------------------------------------------
// The lattice tables and the posterior kernel.

/// Per anchor layout: `log10(d²)` from every anchor to every fine lattice point (loc-core's
/// clamp at [`MIN_DISTANCE`]), anchor-major, padded to `PADDED`.
pub struct Lattice {
    area: Area,
    n: usize,
    log_d2: Vec<f64>,
    /// `Σᵢ log10(dᵢ²)²` per lattice point (+∞ in the padding).
    sum_sq: Vec<f64>,
    /// Fine index i of each lattice point (x), as f64.
    fi: Vec<f64>,
    /// Fine index j (y).
    fj: Vec<f64>,
}

impl Lattice {
    /// The tables of `anchors` in `area` (at most [`MAX_ANCHORS`] anchors are used).
    pub fn new(area: Area, anchors: &[Point]) -> Lattice {
        let n = anchors.len().min(MAX_ANCHORS);
        let mut log_d2 = vec![0.0; n * PADDED];
        let (mut fi, mut fj) = (vec![0.0; PADDED], vec![0.0; PADDED]);
        let mut sum_sq = vec![f64::INFINITY; PADDED];
        for i in 0..SIDE {
            for j in 0..SIDE {
                let g = i * SIDE + j;
                let p = grid::lattice_point(area, i, j);
                for (a, anchor) in anchors[..n].iter().enumerate() {
                    // Exactly loc-core's `Cost::at`.
                    let (dx, dy) = (p.x - anchor.x, p.y - anchor.y);
                    let d2 = (dx * dx + dy * dy).max(MIN_DISTANCE * MIN_DISTANCE);
                    log_d2[a * PADDED + g] = libm::log10(d2);
                }
                fi[g] = i as f64;
                fj[g] = j as f64;
                sum_sq[g] = (0..n).map(|a| log_d2[a * PADDED + g].powi(2)).sum();
            }
        }
        Lattice {
            area,
            n,
            log_d2,
            sum_sq,
            fi,
            fj,
        }
    }

    /// The cost at lattice point `g` (`i·51 + j`), loc-core's expression and order; NaN → +∞.
    #[inline]
    fn cost(&self, obs: &Obs, g: usize) -> f64 {
        let mut s = 0.0;
        for a in 0..self.n {
            let e = obs.r[a] + obs.k * self.log_d2[a * PADDED + g];
            s += obs.w[a] * e * e;
        }
        if s.is_nan() {
            f64::INFINITY
        } else {
            s
        }
    }

    /// The MLE by `search`: loc-core's [`grid::search_lattice`] on the tabulated cost.
    pub fn mle(&self, obs: &Obs, search: Search) -> Point {
        let m = match self.n {
            3 => self.search::<3>(obs, search),
            4 => self.search::<4>(obs, search),
            _ => grid::search_lattice(search, |i, j| self.cost(obs, i * SIDE + j)),
        };
        grid::lattice_point(self.area, m.i, m.j)
    }

    /// [`Lattice::cost`] unrolled for `N` anchors (the same operations in the same order).
    fn search<const N: usize>(&self, obs: &Obs, search: Search) -> grid::LatticeMin {
        let l: [&[f64]; N] = std::array::from_fn(|a| &self.log_d2[a * PADDED..(a + 1) * PADDED]);
        grid::search_lattice(search, |i, j| {
            let g = i * SIDE + j;
            let mut s = 0.0;
            for ((la, r), w) in l.iter().zip(&obs.r).zip(&obs.w) {
                let e = r + obs.k * la[g];
                s += w * e * e;
            }
            if s.is_nan() {
                f64::INFINITY
            } else {
                s
            }
        })
    }

    /// The posterior mean with shadowing `sigma` (the MMSE estimate), `scratch` ≥ `PADDED`
    /// long. Falls back to loc-core's streaming [`grid::posterior_mean_lattice`] where the fast
    /// kernel does not apply (σ = 0, no finite cost).
    pub fn mmse(&self, obs: &Obs, sigma: f64, kernel: Kernel, scratch: &mut [f64]) -> Point {
        let inv = 1.0 / (2.0 * sigma * sigma);
        let fast = if inv.is_finite() {
            kernel.run(self, obs, inv, scratch)
        } else {
            None
        };
        let (fi, fj) = fast.unwrap_or_else(|| {
            let (fi, fj, _) =
                grid::posterior_mean_lattice(sigma, |i, j| self.cost(obs, i * SIDE + j));
            (fi, fj)
        });
        self.fractional_point(fi, fj)
    }

    /// The windowed posterior mean with shadowing `sigma` (the sink's MMSE): loc-core's
    /// [`grid::posterior_mean_window`] on the tabulated cost.
    pub fn mmse_window(&self, obs: &Obs, sigma: f64) -> Point {
        let m = grid::posterior_mean_window(sigma, |i, j| self.cost(obs, i * SIDE + j));
        self.fractional_point(m.i, m.j)
    }

    /// The point at fractional fine indices, as `loc_core::grid::mmse` computes it.
    fn fractional_point(&self, fi: f64, fj: f64) -> Point {
        let (w, h) = (self.area.width, self.area.height);
        let n = FINE_DIVS as f64;
        Point::new((w * fi / n).max(0.0).min(w), (h * fj / n).max(0.0).min(h))
    }
}

/// The observations of one trial under one model: `rᵢ = zᵢ − P0`, weights, `k = 5α`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Obs {
    r: [f64; MAX_ANCHORS],
    w: [f64; MAX_ANCHORS],
    k: f64,
}

impl Obs {
    /// From refined `(z, weight)` per anchor (in the lattice's anchor order) and a model.
    pub fn new(zw: &[(f64, f64)], model: PathLoss) -> Obs {
        let mut o = Obs {
            k: 5.0 * model.alpha,
            ..Obs::default()
        };
        for (a, &(z, w)) in zw.iter().take(MAX_ANCHORS).enumerate() {
            o.r[a] = z - model.p0;
            o.w[a] = w;
        }
        o
    }
}

/// `2^y` for `y ≤ 0`, relative error < 3e-14 (measured 1.6e-14); 0 below −1022 (where `2^y` is
/// under 2.3e-308, nothing next to a weight sum ≥ 1). Branch-free so it vectorises: `y = k + f`,
/// `k` the nearest integer (the 1.5·2^52 shift trick, which also leaves `k + 1023` in the low
/// mantissa bits, so `2^k` is a shift away), `|f| ≤ ½` exactly, and `2^f = (e^(f·ln2/2))²` with
/// the exponential by its degree-9 Taylor polynomial (`|f·ln2/2| ≤ 0.174`: truncation 7e-15,
/// doubled by the square). A degree-12 polynomial without the square is exact to 2e-16 but costs
/// 12 % more time in the MMSE; the weights' 1e-14 error moves the estimate by ~1e-13 m.
#[inline(always)]
fn exp2_neg(y: f64) -> f64 {
    const SHIFT: f64 = 6_755_399_441_055_744.0 + 1023.0;
    const LN2: f64 = std::f64::consts::LN_2;
    let yc = y.max(-1022.0);
    let t = yc + SHIFT;
    let k = t - SHIFT;
    let scale = f64::from_bits(t.to_bits() << 52);
    let f = yc - k;
    // 2^f = (e^(f·ln2/2))², the square of a degree-9 Taylor polynomial in f with coefficients
    // (ln 2 / 2)^n / n!.
    const C: [f64; 10] = {
        let mut c = [1.0; 10];
        let mut n = 1;
        while n < 10 {
            c[n] = c[n - 1] * (LN2 / 2.0) / n as f64;
            n += 1;
        }
        c
    };
    let mut p = C[9];
    let mut n = 9;
    while n > 0 {
        n -= 1;
        p = p * f + C[n];
    }
    let p = p * p;
    let e = p * scale;
    if y < -1022.0 {
        0.0
    } else {
        e
    }
}

/// Weights `2^y` below this (`y` in bits, `2^-72` ≈ 2e-22) are dropped a whole lane-chunk at a
/// time: with the largest weight 1, the 2 601 of them change the weight sum by under 6e-19 of
/// itself, below its rounding. Near the posterior's mode nothing is dropped; far from it (small
/// σ, points beside an anchor) whole chunks of neighbouring lattice points skip the polynomial.
const NEGLIGIBLE_LOG2: f64 = -72.0;

/// Equal-weight costs over the weight, less `Σ rᵢ²`, for `N` anchors in one pass:
/// `k²·Σ Lᵢ² + Σ bᵢ·Lᵢ` with `bᵢ = 2k·rᵢ` (the padding's `Σ Lᵢ²` is +∞).
#[inline(always)]
fn costs_equal<const N: usize>(lat: &Lattice, b: &[f64; MAX_ANCHORS], kk: f64, c: &mut [f64]) {
    let c = &mut c[..PADDED];
    let q = &lat.sum_sq[..PADDED];
    let l: [&[f64]; N] = std::array::from_fn(|a| &lat.log_d2[a * PADDED..(a + 1) * PADDED]);
    for (g, cg) in c.iter_mut().enumerate() {
        let mut v = kk * q[g];
        for a in 0..N {
            v += b[a] * l[a][g];
        }
        *cg = v;
    }
}

/// The posterior mean over the lattice in fractional fine indices, `None` if no cost is finite.
#[inline(always)]
fn posterior_impl(lat: &Lattice, obs: &Obs, inv: f64, c: &mut [f64]) -> Option<(f64, f64)> {
    let c = &mut c[..PADDED];
    let n = lat.n;
    let w0 = obs.w[0];
    let scale = if n > 0 && obs.w[..n].iter().all(|&w| w == w0) && w0 > 0.0 && w0.is_finite() {
        // Pass 1, equal weights (every column of the study): the cost over the weight,
        // `Σ (rᵢ + k·Lᵢ)² = Σ rᵢ² + Σ 2k·rᵢ·Lᵢ + k²·Σ Lᵢ²`, without the constant `Σ rᵢ²` (only the
        // excess over the minimum matters): n + 1 multiply-adds per point with `Σ Lᵢ²` tabulated.
        let k = obs.k;
        let mut b = [0.0; MAX_ANCHORS];
        for (ba, r) in b.iter_mut().zip(&obs.r[..n]) {
            *ba = 2.0 * k * r;
        }
        match n {
            3 => costs_equal::<3>(lat, &b, k * k, c),
            4 => costs_equal::<4>(lat, &b, k * k, c),
            _ => {
                for (cg, &q) in c.iter_mut().zip(&lat.sum_sq) {
                    *cg = k * k * q;
                }
                for (a, &ba) in b[..n].iter().enumerate() {
                    let l = &lat.log_d2[a * PADDED..(a + 1) * PADDED];
                    for (cg, &lg) in c.iter_mut().zip(l) {
                        *cg += ba * lg;
                    }
                }
            }
        }
        w0
    } else {
        // Pass 1, general weights: per lattice point the same sum in the same order as
        // `Lattice::cost` (`0 + t₀` is `t₀` exactly, as `t ≥ 0` or NaN).
        for a in 0..n {
            let (r, w, k) = (obs.r[a], obs.w[a], obs.k);
            let l = &lat.log_d2[a * PADDED..(a + 1) * PADDED];
            if a == 0 {
                for (cg, &lg) in c.iter_mut().zip(l) {
                    let e = r + k * lg;
                    *cg = w * e * e;
                }
            } else {
                for (cg, &lg) in c.iter_mut().zip(l) {
                    let e = r + k * lg;
                    *cg += w * e * e;
                }
            }
        }
        1.0
    };
    // Padding → +∞ (the equal-weight table has it already), NaN → +∞, and the minimum in 8 lanes.
    for cg in &mut c[LATTICE..] {
        *cg = f64::INFINITY;
    }
    let mut lanes = [f64::INFINITY; LANES];
    for chunk in c.chunks_exact_mut(LANES) {
        for (m, v) in lanes.iter_mut().zip(chunk) {
            if v.is_nan() {
                *v = f64::INFINITY;
            }
            *m = if *v < *m { *v } else { *m };
        }
    }
    let min = lanes
        .iter()
        .fold(f64::INFINITY, |m, &v| if v < m { v } else { m });
    if !min.is_finite() {
        return None;
    }
    // Pass 2: the weights `2^((c − min)·scale·(−log2(e)/2σ²))`, a chunk of lanes at a time, and
    // the weighted index sums, 8 lanes.
    let neg = -inv * scale * std::f64::consts::LOG2_E;
    let (mut s, mut sx, mut sy) = ([0.0; LANES], [0.0; LANES], [0.0; LANES]);
    for ((wc, xi), yj) in c
        .chunks_exact_mut(LANES)
        .zip(lat.fi.chunks_exact(LANES))
        .zip(lat.fj.chunks_exact(LANES))
    {
        let mut y = [0.0; LANES];
        let mut keep = false;
        for l in 0..LANES {
            y[l] = (wc[l] - min) * neg;
            keep |= y[l] >= NEGLIGIBLE_LOG2;
        }
        // NaN-free here: costs are finite or +∞, the minimum finite.
        if !keep {
            continue;
        }
        for l in 0..LANES {
            let w = exp2_neg(y[l]);
            s[l] += w;
            sx[l] += w * xi[l];
            sy[l] += w * yj[l];
        }
    }
    let sum = |v: [f64; LANES]| v.iter().sum::<f64>();
    let s = sum(s);
    Some((sum(sx) / s, sum(sy) / s))
}

fn posterior_portable(lat: &Lattice, obs: &Obs, inv: f64, c: &mut [f64]) -> Option<(f64, f64)> {
    posterior_impl(lat, obs, inv, c)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn posterior_avx2(lat: &Lattice, obs: &Obs, inv: f64, c: &mut [f64]) -> Option<(f64, f64)> {
    posterior_impl(lat, obs, inv, c)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn posterior_avx512(lat: &Lattice, obs: &Obs, inv: f64, c: &mut [f64]) -> Option<(f64, f64)> {
    posterior_impl(lat, obs, inv, c)
}

/// Which compiled version of the posterior kernel runs (all give identical results).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// Baseline instruction set.
    Portable,
    /// AVX2 (x86-64, detected at run time).
    Avx2,
    /// AVX-512F (x86-64, detected at run time).
    Avx512,
}

impl Kernel {
    /// The widest version this CPU runs; `HOPLOC_KERNEL=portable` or `avx2` in the environment
    /// forces a narrower one (to measure them: the results are the same).
    pub fn detect() -> Kernel {
        match std::env::var("HOPLOC_KERNEL").as_deref() {
            Ok("portable") => return Kernel::Portable,
            Ok("avx2") if Kernel::available().contains(&Kernel::Avx2) => return Kernel::Avx2,
            _ => {}
        }
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                return Kernel::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                return Kernel::Avx2;
            }
        }
        Kernel::Portable
    }

    /// Every version this CPU runs.
    pub fn available() -> Vec<Kernel> {
        let mut v = vec![Kernel::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                v.push(Kernel::Avx2);
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                v.push(Kernel::Avx512);
            }
        }
        v
    }

    fn run(self, lat: &Lattice, obs: &Obs, inv: f64, c: &mut [f64]) -> Option<(f64, f64)> {
        match self {
            Kernel::Portable => posterior_portable(lat, obs, inv, c),
            // SAFETY: these variants are only constructed by `detect`/`available` after the
            // CPU feature was detected at run time.
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2 => unsafe { posterior_avx2(lat, obs, inv, c) },
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512 => unsafe { posterior_avx512(lat, obs, inv, c) },
            #[cfg(not(target_arch = "x86_64"))]
            _ => posterior_portable(lat, obs, inv, c),
        }
    }
}

/// Scratch space for [`Lattice::mmse`].
pub fn scratch() -> Vec<f64> {
    vec![0.0; PADDED]
}

// ---------------------------------------------------------------------------------------------
// Per-point accumulation.

/// Error sums of one cell at one point.
#[derive(Clone, Copy, Debug, Default)]
struct Acc {
    n: u64,
    sx: f64,
    sy: f64,
    s2: f64,
    s4: f64,
    failures: u64,
}

impl Acc {
    fn add(&mut self, est: Point, truth: Point) {
        let (ex, ey) = (est.x - truth.x, est.y - truth.y);
        let e2 = ex * ex + ey * ey;
        self.n += 1;
        self.sx += ex;
        self.sy += ey;
        self.s2 += e2;
        self.s4 += e2 * e2;
    }
}

/// One point's figures for one cell.
#[derive(Clone, Copy, Debug)]
struct PointStat {
    rmse: f64,
    /// Variance of `rmse` as an estimate (delta method).
    var: f64,
    mean_x: f64,
    mean_y: f64,
    failures: u64,
}

impl PointStat {
    fn of(a: &Acc) -> PointStat {
        let n = a.n.max(1) as f64;
        let m2 = a.s2 / n;
        let var_m2 = (a.s4 / n - m2 * m2).max(0.0) / n;
        PointStat {
            rmse: m2.sqrt(),
            var: if m2 > 0.0 { var_m2 / (4.0 * m2) } else { 0.0 },
            mean_x: a.sx / n,
            mean_y: a.sy / n,
            failures: a.failures,
        }
    }
}

/// The study of one (σ, layout): what is computed, and the per-point work.
struct Job<'a> {
    cfg: &'a Config,
    cols: &'a [Column],
    lat: &'a Lattice,
    anchors: &'a [Point],
    sigma: f64,
    /// Estimator rows of this layout.
    algos: Vec<Algo>,
    kernel: Kernel,
    /// Whether the floor is taken from the MMSE rows (known parameters).
    floor_from_mmse: bool,
    /// Whether the floor is computed here (its own kernel calls).
    floor_own: bool,
}

/// Everything one point contributes.
struct PointOut {
    /// `[row][column]`, `None` where the row has no such column.
    est: Vec<Vec<Option<PointStat>>>,
    floor: Vec<PointStat>,
    crlb: Vec<Option<f64>>,
}

/// Ordered anchor pairs `(i, j, d_ij)`, `i ≠ j`.
fn pairs(anchors: &[Point]) -> Vec<(usize, usize, f64)> {
    let mut v = Vec::new();
    for (i, a) in anchors.iter().enumerate() {
        for (j, b) in anchors.iter().enumerate() {
            if i != j {
                v.push((i, j, a.dist(*b)));
            }
        }
    }
    v
}

/// The per-column parameter state of `Ar1` mode.
#[derive(Clone, Copy)]
struct Smoothed {
    p0: Ar1,
    alpha: Ar1,
    sigma: Ar1,
}

impl Job<'_> {
    fn run_point(&self, p: usize, truth: Point) -> PointOut {
        let cfg = self.cfg;
        let (n, nc, ncol) = (self.anchors.len(), cfg.channels, self.cols.len());
        let sigma = self.sigma;
        let mut agent = Normal::new(stream_seed(cfg.seed, sigma, n, p, 0));
        let mut a2a_rng = Normal::new(stream_seed(cfg.seed, sigma, n, p, 1));
        let mean: Vec<f64> = self
            .anchors
            .iter()
            .map(|a| cfg.truth.rssi_at(truth.dist(*a)))
            .collect();
        let pairs = pairs(self.anchors);
        let mean_a2a: Vec<f64> = pairs
            .iter()
            .map(|&(_, _, d)| cfg.truth.rssi_at(d))
            .collect();
        let mut acc = vec![vec![Acc::default(); ncol]; self.algos.len()];
        let mut floor_acc = vec![Acc::default(); ncol];
        let mut smooth = vec![
            Smoothed {
                p0: Ar1::default(),
                alpha: Ar1::default(),
                sigma: Ar1::default(),
            };
            ncol
        ];
        let mut scratch = scratch();
        let mut z = [[None; MAX_CHANNELS]; MAX_ANCHORS];
        let mut a2a = vec![[None; MAX_CHANNELS]; pairs.len()];
        let clip = cfg.clip.then_some(cfg.area);
        let centre = Point::new(cfg.area.width / 2.0, cfg.area.height / 2.0);
        let need_floor = self.floor_own;
        for _run in 0..cfg.runs {
            for (za, m) in z.iter_mut().zip(&mean) {
                for zc in &mut za[..nc] {
                    *zc = Some(m + sigma * agent.draw());
                }
            }
            if cfg.params != ParamSource::Known {
                for (v, m) in a2a.iter_mut().zip(&mean_a2a) {
                    for vc in &mut v[..nc] {
                        *vc = Some(m + sigma * a2a_rng.draw());
                    }
                }
            }
            for (ci, col) in self.cols.iter().enumerate() {
                let mut zw = [(0.0, 0.0); MAX_ANCHORS];
                for (o, za) in zw.iter_mut().zip(&z[..n]) {
                    // Every channel is present, so every anchor is usable.
                    *o = refine::refine_anchor(&za[..nc], col.refinement).unwrap_or((0.0, 0.0));
                }
                let zw = &zw[..n];
                let (model, sig) = match cfg.params {
                    ParamSource::Known => (cfg.truth, sigma),
                    _ => self.fit(col, &pairs, &a2a, &mut smooth[ci], sigma),
                };
                let obs = Obs::new(zw, model);
                for (ri, algo) in self.algos.iter().enumerate() {
                    let a = &mut acc[ri][ci];
                    match algo {
                        Algo::Mle => a.add(self.lat.mle(&obs, cfg.search), truth),
                        Algo::Mmse => {
                            a.add(self.lat.mmse(&obs, sig, self.kernel, &mut scratch), truth)
                        }
                        Algo::MmseWindow => a.add(self.lat.mmse_window(&obs, sig), truth),
                        _ => {
                            if col.refinement == Refinement::Extended {
                                continue;
                            }
                            let mut d = [0.0; MAX_ANCHORS];
                            for (di, &(zi, _)) in d.iter_mut().zip(zw) {
                                *di = model.distance(zi);
                            }
                            let b = algo.baseline().expect("baseline row");
                            let est = match b.estimate(self.anchors, &d[..n], clip) {
                                Ok(e) => e,
                                Err(_) => {
                                    a.failures += 1;
                                    centre
                                }
                            };
                            a.add(est, truth);
                        }
                    }
                }
            }
            if need_floor {
                self.floor_trial(&z[..n], truth, &mut floor_acc, &mut scratch);
            }
        }
        let est: Vec<Vec<Option<PointStat>>> = acc
            .iter()
            .zip(&self.algos)
            .map(|(row, algo)| {
                row.iter()
                    .zip(self.cols)
                    .map(|(a, col)| {
                        let na =
                            algo.baseline().is_some() && col.refinement == Refinement::Extended;
                        (!na).then(|| PointStat::of(a))
                    })
                    .collect()
            })
            .collect();
        let floor = if !self.cfg.floor {
            Vec::new()
        } else if self.floor_from_mmse {
            let ri = self
                .algos
                .iter()
                .position(|a| *a == Algo::Mmse)
                .expect("MMSE row");
            let ext = ncol - 1;
            self.cols
                .iter()
                .enumerate()
                .map(|(ci, col)| {
                    let src = if matches!(col.refinement, Refinement::Single(_)) {
                        ci
                    } else {
                        ext
                    };
                    est[ri][src].expect("MMSE cell")
                })
                .collect()
        } else {
            floor_acc.iter().map(PointStat::of).collect()
        };
        let crlb = self
            .cols
            .iter()
            .map(|col| {
                loc_core::bounds::crlb(truth, self.anchors, cfg.truth, sigma, col.channels(nc))
            })
            .collect();
        PointOut { est, floor, crlb }
    }

    /// The model and σ a column's estimators use this trial (estimated modes).
    fn fit(
        &self,
        col: &Column,
        pairs: &[(usize, usize, f64)],
        a2a: &[[Option<f64>; MAX_CHANNELS]],
        state: &mut Smoothed,
        sigma: f64,
    ) -> (PathLoss, f64) {
        let nc = self.cfg.channels;
        let mut stats = CalStats::new();
        for (&(_, _, d), v) in pairs.iter().zip(a2a) {
            let v = &v[..nc];
            if col.refinement == Refinement::Extended {
                for z in v.iter().flatten() {
                    stats.push(d, *z);
                }
            } else if let Some((z, _)) = refine::refine_anchor(v, col.refinement) {
                stats.push(d, z);
            }
        }
        let ar1 = self.cfg.params == ParamSource::Ar1;
        let prior = if ar1 {
            PathLoss {
                p0: state.p0.value().unwrap_or(self.cfg.truth.p0),
                alpha: state.alpha.value().unwrap_or(self.cfg.truth.alpha),
            }
        } else {
            self.cfg.truth
        };
        let Ok(f) = params::fit(
            &stats,
            ParamMode::P0AndAlpha,
            self.cfg.fit,
            prior,
            &ParamBounds::THESIS,
        ) else {
            // Unreachable here (every pair is heard); keep the prior.
            return (prior, sigma);
        };
        let s = f.sigma.filter(|s| *s > 0.0).unwrap_or(sigma);
        if ar1 {
            let model = PathLoss {
                p0: state.p0.update(f.model.p0),
                alpha: state.alpha.update(f.model.alpha),
            };
            (model, state.sigma.update(s))
        } else {
            (f.model, s)
        }
    }

    /// One trial of the MMSE floor: the posterior mean with the true model and σ on each single
    /// channel, and on all channels (dB mean, weight C) for the multichannel columns.
    fn floor_trial(
        &self,
        z: &[[Option<f64>; MAX_CHANNELS]],
        truth: Point,
        acc: &mut [Acc],
        scratch: &mut [f64],
    ) {
        let nc = self.cfg.channels;
        let mut all: Option<Point> = None;
        for (ci, col) in self.cols.iter().enumerate() {
            let refinement = match col.refinement {
                Refinement::Single(c) => Refinement::Single(c),
                _ => Refinement::Extended,
            };
            if refinement == Refinement::Extended {
                if let Some(p) = all {
                    acc[ci].add(p, truth);
                    continue;
                }
            }
            let mut zw = [(0.0, 0.0); MAX_ANCHORS];
            for (o, za) in zw.iter_mut().zip(z) {
                *o = refine::refine_anchor(&za[..nc], refinement).unwrap_or((0.0, 0.0));
            }
            let obs = Obs::new(&zw[..z.len()], self.cfg.truth);
            let p = self.lat.mmse(&obs, self.sigma, self.kernel, scratch);
            if refinement == Refinement::Extended {
                all = Some(p);
            }
            acc[ci].add(p, truth);
        }
    }
}

/// Mean and population standard deviation.
fn mean_std(v: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = v.clone().count().max(1) as f64;
    let m = v.clone().sum::<f64>() / n;
    let var = v.map(|x| (x - m) * (x - m)).sum::<f64>() / n;
    (m, var.sqrt())
}

fn estimator_cell(stats: &[PointStat]) -> Cell {
    let p = stats.len().max(1) as f64;
    let (rmse, _) = mean_std(stats.iter().map(|s| s.rmse));
    let (_, bias_x) = mean_std(stats.iter().map(|s| s.mean_x));
    let (_, bias_y) = mean_std(stats.iter().map(|s| s.mean_y));
    Cell {
        rmse,
        rmse_se: Some(stats.iter().map(|s| s.var).sum::<f64>().sqrt() / p),
        bias_x: Some(bias_x),
        bias_y: Some(bias_y),
        failures: stats.iter().map(|s| s.failures).sum(),
        per_point_rmse: stats.iter().map(|s| s.rmse).collect(),
        per_point_bias: stats.iter().map(|s| s.mean_x.hypot(s.mean_y)).collect(),
    }
}

/// Runs the study. `progress` is called with the number of points just finished (from any
/// worker thread); there are `sigmas × anchor layouts × 361` in all ([`Config::total_points`]).
pub fn run(cfg: &Config, progress: &(dyn Fn(u64) + Sync)) -> Result<StudyResult, String> {
    cfg.validate()?;
    let cols = cfg.columns();
    let pts = points(cfg.area);
    let kernel = Kernel::detect();
    let layouts: Vec<(Vec<Point>, Lattice)> = cfg
        .anchor_counts
        .iter()
        .map(|&n| {
            let a = anchors(cfg.area, n);
            let lat = Lattice::new(cfg.area, &a);
            (a, lat)
        })
        .collect();
    let mut jobs = Vec::new();
    for &sigma in &cfg.sigmas {
        for (a, lat) in &layouts {
            let algos: Vec<Algo> = Algo::ALL
                .into_iter()
                .filter(|x| cfg.algos.contains(x) && x.applies(a.len()))
                .collect();
            let floor_from_mmse = cfg.params == ParamSource::Known && algos.contains(&Algo::Mmse);
            let floor_own = cfg.floor && !floor_from_mmse;
            jobs.push(Job {
                cfg,
                cols: &cols,
                lat,
                anchors: a,
                sigma,
                algos,
                kernel,
                floor_from_mmse,
                floor_own,
            });
        }
    }
    let total = jobs.len() * pts.len();
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<PointOut>>> = Mutex::new((0..total).map(|_| None).collect());
    std::thread::scope(|s| {
        for _ in 0..cfg.threads.min(total) {
            s.spawn(|| loop {
                let t = next.fetch_add(1, Ordering::Relaxed);
                if t >= total {
                    break;
                }
                let (j, p) = (t / pts.len(), t % pts.len());
                let out = jobs[j].run_point(p, pts[p]);
                results.lock().expect("no worker panicked")[t] = Some(out);
                progress(1);
            });
        }
    });
    let mut results = results.into_inner().map_err(|_| "a worker panicked")?;
    let mut tables = Vec::new();
    for (si, &sigma) in cfg.sigmas.iter().enumerate() {
        let mut rows = Vec::new();
        for li in 0..layouts.len() {
            let j = si * layouts.len() + li;
            let job = &jobs[j];
            let n = job.anchors.len();
            let outs: Vec<PointOut> = results[j * pts.len()..(j + 1) * pts.len()]
                .iter_mut()
                .map(|o| o.take().expect("every point ran"))
                .collect();
            for (ri, algo) in job.algos.iter().enumerate() {
                let cells = (0..cols.len())
                    .map(|ci| {
                        let stats: Option<Vec<PointStat>> =
                            outs.iter().map(|o| o.est[ri][ci]).collect();
                        stats.map(|s| estimator_cell(&s))
                    })
                    .collect();
                rows.push(Row {
                    label: format!("{}-{n}", algo.label()),
                    kind: RowKind::Estimator(*algo),
                    anchors: n,
                    cells,
                });
            }
            let crlb_cells = (0..cols.len())
                .map(|ci| {
                    let v: Vec<f64> = outs.iter().filter_map(|o| o.crlb[ci]).collect();
                    (!v.is_empty()).then(|| Cell {
                        rmse: v.iter().sum::<f64>() / v.len() as f64,
                        rmse_se: None,
                        bias_x: None,
                        bias_y: None,
                        failures: 0,
                        per_point_rmse: v,
                        per_point_bias: Vec::new(),
                    })
                })
                .collect();
            rows.push(Row {
                label: format!("CRLB-{n}"),
                kind: RowKind::Crlb,
                anchors: n,
                cells: crlb_cells,
            });
            if cfg.floor {
                let floor_cells = (0..cols.len())
                    .map(|ci| {
                        let stats: Vec<PointStat> = outs.iter().map(|o| o.floor[ci]).collect();
                        let mut c = estimator_cell(&stats);
                        c.bias_x = None;
                        c.bias_y = None;
                        c.per_point_bias.clear();
                        Some(c)
                    })
                    .collect();
                rows.push(Row {
                    label: format!("MMSE-floor-{n}"),
                    kind: RowKind::MmseFloor,
                    anchors: n,
                    cells: floor_cells,
                });
            }
        }
        tables.push(Table { sigma, rows });
    }
    Ok(StudyResult {
        config: cfg.summary(pts.len()),
        columns: cols.iter().map(|c| c.label.clone()).collect(),
        tables,
    })
}

impl Config {
    /// What the results record of this configuration, with `points` agent positions.
    pub fn summary(&self, points: usize) -> Summary {
        let cfg = self;
        Summary {
            width: cfg.area.width,
            height: cfg.area.height,
            anchor_counts: cfg.anchor_counts.clone(),
            points,
            runs: cfg.runs,
            channels: cfg.channels,
            p0: cfg.truth.p0,
            alpha: cfg.truth.alpha,
            params: cfg.params,
            fit: fit_name(cfg.fit).into(),
            search: search_name(cfg.search).into(),
            clip: cfg.clip,
            floor: cfg.floor,
            seed: cfg.seed,
        }
    }
    /// How many (σ, layout, point) units of work [`run`] reports through `progress`.
    pub fn total_points(&self) -> u64 {
        (self.sigmas.len() * self.anchor_counts.len() * POINTS_PER_SIDE * POINTS_PER_SIDE) as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use loc_core::refine::{Obs as CoreObs, Observations};

    fn core_obs(anchors: &[Point], zw: &[(f64, f64)]) -> Observations {
        let v: Vec<CoreObs> = anchors
            .iter()
            .zip(zw)
            .map(|(&pos, &(z, weight))| CoreObs { pos, z, weight })
            .collect();
        Observations::from_slice(&v)
    }

    /// Random trials: noisy RSSI at random points of a few areas, odd models included.
    /// Area, anchors, refined `(z, weight)` per anchor, model, σ.
    type Trial = (Area, Vec<Point>, Vec<(f64, f64)>, PathLoss, f64);

    fn trials() -> Vec<Trial> {
        let mut rng = Normal::new(42);
        let mut v = Vec::new();
        for (k, area) in [
            Area::new(10.0, 10.0),
            Area::new(6.0, 4.0),
            Area::new(30.0, 30.0),
        ]
        .into_iter()
        .enumerate()
        {
            for n in [3, 4] {
                let a = anchors(area, n);
                for t in 0..40 {
                    let u = |r: &mut Normal| 0.5 + 0.3 * r.draw().clamp(-1.6, 1.6);
                    let p = Point::new(area.width * u(&mut rng), area.height * u(&mut rng));
                    let sigma = [0.5, 2.0, 4.0, 8.0][t % 4];
                    let w = if t % 3 == 0 { 2.0 } else { 1.0 };
                    let zw = a
                        .iter()
                        .map(|x| (PathLoss::THESIS.rssi_at(p.dist(*x)) + sigma * rng.draw(), w))
                        .collect();
                    let model = if k == 1 {
                        PathLoss {
                            p0: -43.5,
                            alpha: 2.6,
                        }
                    } else {
                        PathLoss::THESIS
                    };
                    v.push((area, a.clone(), zw, model, sigma));
                }
            }
        }
        v
    }

    #[test]
    fn mle_is_loc_cores_bit_for_bit() {
        for (area, a, zw, model, _) in trials() {
            let lat = Lattice::new(area, &a);
            let obs = Obs::new(&zw, model);
            for search in [Search::Thesis, Search::MultiStart, Search::Exhaustive] {
                let want = grid::mle(&core_obs(&a, &zw), model, area, search).unwrap();
                assert_eq!(lat.mle(&obs, search), want.pos, "{search:?}");
            }
        }
    }

    #[test]
    fn mmse_matches_loc_core() {
        let mut scratch = scratch();
        let mut worst = 0.0f64;
        for (area, a, zw, model, sigma) in trials() {
            let lat = Lattice::new(area, &a);
            let obs = Obs::new(&zw, model);
            let want = grid::mmse(&core_obs(&a, &zw), model, area, sigma)
                .unwrap()
                .pos;
            for kernel in Kernel::available() {
                let got = lat.mmse(&obs, sigma, kernel, &mut scratch);
                worst = worst.max(got.dist(want));
            }
        }
        assert!(worst < 1e-10, "worst {worst}");
    }

    #[test]
    fn mmse_window_is_loc_cores_bit_for_bit() {
        for (area, a, zw, model, sigma) in trials() {
            let lat = Lattice::new(area, &a);
            let obs = Obs::new(&zw, model);
            for s in [sigma, 0.0, f64::INFINITY] {
                let want = grid::mmse_window(&core_obs(&a, &zw), model, area, s)
                    .unwrap()
                    .pos;
                assert_eq!(lat.mmse_window(&obs, s), want, "σ = {s}");
            }
        }
    }

    #[test]
    fn every_kernel_gives_identical_bits() {
        let mut scratch = scratch();
        for (area, a, zw, model, sigma) in trials() {
            let lat = Lattice::new(area, &a);
            let obs = Obs::new(&zw, model);
            let inv = 1.0 / (2.0 * sigma * sigma);
            let base = Kernel::Portable.run(&lat, &obs, inv, &mut scratch);
            for kernel in Kernel::available() {
                assert_eq!(
                    kernel.run(&lat, &obs, inv, &mut scratch),
                    base,
                    "{kernel:?}"
                );
            }
        }
    }

    #[test]
    fn mmse_fallbacks() {
        let area = Area::new(10.0, 10.0);
        let a = anchors(area, 3);
        let lat = Lattice::new(area, &a);
        let zw = [(-60.0, 1.0), (-65.0, 1.0), (-70.0, 1.0)];
        let obs = Obs::new(&zw, PathLoss::THESIS);
        let mut scratch = scratch();
        // σ = 0: loc-core's σ → 0 limit (the minimiser).
        let want = grid::mmse(&core_obs(&a, &zw), PathLoss::THESIS, area, 0.0).unwrap();
        assert_eq!(
            lat.mmse(&obs, 0.0, Kernel::detect(), &mut scratch),
            want.pos
        );
        // No finite cost: the corner, as loc-core.
        let bad = Obs::new(&[(f64::NAN, 1.0); 3], PathLoss::THESIS);
        assert_eq!(
            lat.mmse(&bad, 2.0, Kernel::detect(), &mut scratch),
            Point::new(0.0, 0.0)
        );
    }

    #[test]
    fn fast_exp2_is_accurate() {
        let mut worst = 0.0f64;
        let mut y = 0.0;
        while y > -1022.0 {
            let (a, b) = (exp2_neg(y), libm::exp2(y));
            worst = worst.max(((a - b) / b).abs());
            y -= 0.000_931_3;
        }
        assert!(worst < 3e-14, "relative error {worst}");
        assert_eq!(exp2_neg(0.0), 1.0);
        assert_eq!(exp2_neg(-0.0), 1.0);
        assert_eq!(exp2_neg(-3.0), 0.125);
        assert_eq!(exp2_neg(-1022.5), 0.0);
        assert_eq!(exp2_neg(f64::NEG_INFINITY), 0.0);
    }

    #[test]
    fn floor_kernel_matches_loc_core_mmse_floor() {
        // The study's floor at a point, with draws taken from the study's own stream, equals
        // loc-core's mmse_floor on the same draws.
        let area = Area::new(10.0, 10.0);
        let truth = PathLoss::THESIS;
        for n in [3, 4] {
            let a = anchors(area, n);
            let lat = Lattice::new(area, &a);
            let mut scratch = scratch();
            for (p, sigma, channels) in [
                (Point::new(0.5, 0.5), 2.0, 1),
                (Point::new(4.5, 7.0), 4.0, 2),
                (Point::new(9.5, 2.0), 2.0, 2),
            ] {
                let mut rng = Normal::new(7);
                let trials = 30;
                let draws: Vec<f64> = (0..trials * n).map(|_| rng.draw()).collect();
                let want =
                    loc_core::bounds::mmse_floor(p, &a, truth, sigma, channels, area, &draws)
                        .unwrap();
                let s = sigma / (channels as f64).sqrt();
                let mut acc = Acc::default();
                for t in draws.chunks(n) {
                    let zw: Vec<(f64, f64)> = a
                        .iter()
                        .zip(t)
                        .map(|(x, d)| (truth.rssi_at(p.dist(*x)) + s * d, channels as f64))
                        .collect();
                    let est =
                        lat.mmse(&Obs::new(&zw, truth), sigma, Kernel::detect(), &mut scratch);
                    acc.add(est, p);
                }
                let got = PointStat::of(&acc).rmse;
                assert!((got - want).abs() < 1e-9, "{got} vs {want}");
            }
        }
    }

    #[test]
    fn seeds_differ_per_stream() {
        let s = stream_seed(1, 2.0, 3, 0, 0);
        assert_ne!(s, stream_seed(1, 2.0, 3, 0, 1));
        assert_ne!(s, stream_seed(1, 2.0, 3, 1, 0));
        assert_ne!(s, stream_seed(1, 2.0, 4, 0, 0));
        assert_ne!(s, stream_seed(1, 4.0, 3, 0, 0));
        assert_ne!(s, stream_seed(2, 2.0, 3, 0, 0));
        // Normal draws: mean ≈ 0, variance ≈ 1.
        let mut r = Normal::new(s);
        let v: Vec<f64> = (0..200_000).map(|_| r.draw()).collect();
        let (m, sd) = mean_std(v.iter().copied());
        assert!(m.abs() < 0.01 && (sd - 1.0).abs() < 0.01, "{m} {sd}");
    }

    #[test]
    fn points_and_anchors_scale_with_the_area() {
        let p = points(Area::new(10.0, 10.0));
        assert_eq!(p.len(), 361);
        assert_eq!(p[0], Point::new(0.5, 0.5));
        assert_eq!(p[1], Point::new(0.5, 1.0));
        assert_eq!(p[360], Point::new(9.5, 9.5));
        let p = points(Area::new(30.0, 20.0));
        assert_eq!(p[19], Point::new(3.0, 1.0));
        assert_eq!(
            anchors(Area::new(30.0, 20.0), 4),
            [
                Point::new(0.0, 0.0),
                Point::new(30.0, 0.0),
                Point::new(30.0, 20.0),
                Point::new(0.0, 20.0)
            ]
        );
    }

    #[test]
    fn validation_names_the_problem() {
        let ok = Config::default();
        assert_eq!(ok.validate(), Ok(()));
        let bad = |f: fn(&mut Config)| {
            let mut c = Config::default();
            f(&mut c);
            c.validate().unwrap_err()
        };
        assert!(bad(|c| c.runs = 0).contains("runs"));
        assert!(bad(|c| c.sigmas = vec![0.0]).contains("σ"));
        assert!(bad(|c| c.channels = 5).contains("channels"));
        assert!(bad(|c| c.anchor_counts = vec![5]).contains("anchor"));
        assert!(bad(|c| c.area = Area::new(-1.0, 3.0)).contains("area"));
        assert!(bad(|c| c.algos.clear()).contains("estimator"));
    }
}
