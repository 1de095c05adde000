//! The integer-only path of the sink MCU: the reference algorithms of [`crate::refine`],
//! [`crate::params`] and [`crate::grid`] on the MCU's own inputs, with no `f32`/`f64` anywhere and
//! the constant tables in flash on AVR.
//!
//! # Inputs and number formats
//!
//! | quantity | type | format |
//! |---|---|---|
//! | RSSI | `Option<u8>` | the XBee byte: the level's magnitude in −dBm (`None`: not heard) |
//! | anchor position | [`PointCm`] | `i16` centimetres (anchors may lie outside the area) |
//! | area | [`AreaCm`] | `u16` centimetres: `[0, width] × [0, height]` |
//! | position estimate | [`PointMm`] | `u32` millimetres (rounded to the nearest) |
//! | dB values (refined `z`, P0, bounds) | `i32` | Q.16 dB: `1 dB =` [`DB`] |
//! | path-loss exponent α | `i32` | Q.24: `α = 1 is` [`ALPHA`] |
//! | σ (MMSE, fitted σ) | `u16` | Q.8 dB |
//! | costs ([`Estimate::min_cost`], `const_cost`) | `u32` | Q.8 dB², saturating |
//! | fit residual [`ParamFit::sse`] | `u64` | Q.16 dB² |
//!
//! # How the cost is computed
//!
//! The lattice is the reference's ([`crate::grid::lattice_point`]): `(W·i/F, H·j/F)` with
//! `F =` [`crate::grid::FINE_DIVS`], which in lattice units of `1/F` cm is the integer
//! `(W·i, H·j)`, so every squared anchor distance `d²` is an exact integer. With
//! `K = 5·α·log10 2` the reference cost is
//! `C = Σ wᵢ (zᵢ − P0 + K·log2(dᵢ² / 1 m²))² = K² · Σ wᵢ (ρᵢ + log2 dᵢ²)²`,
//! `ρᵢ = (zᵢ − P0)/K − log2(1 m²)` (one division per estimate, none per lattice point): the
//! position search compares `C' = C/K²`, in log2 units, which has the same minimisers and the
//! same posterior (the weights' exponent is rescaled by `K²` once).
//!
//! Once per search each anchor gets a shift `h`: the fewest bits that bring its offsets `dx`,
//! `dy` from anywhere in the area below 2^16 once rounded to `2^h` lattice units (`h = 0`
//! within 13.1 m of the anchor; `ρ` and the clamp absorb the `2h`), so every lattice point costs
//! the same wherever the search evaluates it. A window (the coarse grid, the fine window, a
//! descent step's 3 × 3 block) is evaluated a column at a time ([`mod@column`]): per column
//! each anchor's `dx²`, per row `dy²`, `d²` one 32-bit add with carry. Then per (anchor, lattice
//! point): `log2` from a 64-segment quadratic table in flash (error < 2.2·10⁻⁶, six 8 × 8
//! multiplies, constant shifts only), the clamp at the model's 1 cm
//! ([`crate::model::MIN_DISTANCE`]), `u = ρ + log2 d²` (Q.20), `u²` in Q.20 from five 8 × 8
//! multiplies (`|u|` saturates at 32, i.e. `|z − p| ≥ 32·K` dB, where no estimate lives), the
//! weight, and a saturating 32-bit sum that stops as soon as it cannot beat the point it is
//! compared with (exact: the terms are non-negative). The cost is within about 10⁻⁵ dB per
//! observation of the reference's within 13 m of every anchor (farther, the rounding of the
//! offsets adds up to `2^h/d` relative in `d²`), so a lattice decision differs from the f64 one
//! only on a near-tie (`tests/fixed.rs` measures how often).
//!
//! # Map
//!
//! * Refinements ([`observations`], [`observations_of`], [`refine_anchor`], [`extended`]):
//!   Single, Max, LinearAvg (`10^(−k/10)` from two 10-entry tables, the log from the log2
//!   table), Extended (dB mean, weight = channel count, and `const_cost`).
//! * Path-loss fit ([`CalStats`], [`fit`], [`Ar1`], [`OnlineParams`]): both methods of
//!   [`crate::params::fit`], with the same modes, bounds handling, identifiability rule and σ:
//!   the exact box-constrained least squares ([`fit_least_squares`]: the MCU's method, one
//!   solve) and the thesis' grid ([`fit_grid`]); AR(1) smoothing in Q.16.
//! * Position ([`mle`] with [`Search::Thesis`], [`Search::MultiStart`] or [`Search::Exhaustive`];
//!   [`mmse`] over the full lattice (host-sized: 64-bit totals), weights `2^(−y)` from a
//!   32-entry table, and [`mmse_window`] over the thesis' fine window only, the sink's MMSE;
//!   [`estimate`], [`locate`]); [`sink_fix`] runs the whole sink step (fit, smoothing,
//!   refinement, estimate).
//! * The sink's two estimates at once ([`mle_and_mmse_window`]): the windowed MMSE's window
//!   *is* the thesis' fine window around the same coarse winner, so one coarse stage and one pass
//!   over the window give both the thesis MLE and the windowed MMSE, bit for bit the
//!   [`Estimate`]s of [`mle`] (`Search::Thesis`) and [`mmse_window`]; only 32-bit arithmetic
//!   (the posterior in `u32` sums, weights Q.20).
//! * The search's column ([`mod@column`]): the one piece with a hand-written twin. Every search
//!   takes its [`ColumnKernel`] as a type parameter (`mle_with::<Portable>`); the functions
//!   without `_with` use [`Native`]: on the ATmega328P the AVR assembly kernel `column::Avr`,
//!   which is held equal to [`Portable`] in simavr, elsewhere [`Portable`] itself. Everything
//!   else is the same Rust on the host and on the sink.
//!
//! Errors are [`LocError`]: fewer than three usable anchors is
//! [`LocError::TooFewAnchors`]; a fit without samples [`LocError::NoCalibrationData`]. Nothing
//! panics or overflows on any input (checked by the debug-build property tests).
//!
//! # On the ATmega328P
//!
//! `cargo bench -p hoploc --bench mcu_estimate` runs the sink step (4 anchors × 2 channels in a
//! 10 m room) as firmware in simavr (`mcu-bench`) and prints its cycles phase by phase, against
//! the same algorithm in `f32`; the README keeps the measured figures.
//!
//! ```
//! use loc_core::fixed::*;
//! // Three anchors of a 10 m room, the agent's RSSI bytes on two channels (−dBm), and the
//! // anchor-to-anchor bytes they relayed (here: one pair).
//! let anchors = [PointCm::new(0, 0), PointCm::new(1000, 0), PointCm::new(0, 1000)];
//! let mut stats = CalStats::new();
//! stats.push_pair_bytes(anchors[0], anchors[1], &[70, 71, 0, 0, 69, 72, 0, 0]);
//! let mut params = OnlineParams::new(
//!     ParamMode::P0AndAlpha,
//!     FitMethod::LeastSquares,
//!     Bounds::THESIS,
//!     PathLoss::THESIS,
//! );
//! if let Ok(f) = fit_least_squares(&stats, params.mode, params.current(), &params.bounds) {
//!     params.feed(&f);
//! }
//! let rssi: [ChannelBytes; 3] = [
//!     [Some(62), Some(63), None, None],
//!     [Some(68), Some(66), None, None],
//!     [Some(67), Some(69), None, None],
//! ];
//! let obs = observations_of(&anchors, &rssi, 2, Refinement::Extended);
//! let fix = mle(&obs, params.current(), AreaCm::new(1000, 1000), Search::Thesis).unwrap();
//! assert!(fix.pos.x <= 10_000 && fix.pos.y <= 10_000);
//! ```

pub mod column;
mod math;
mod params;
mod refine;
mod search;
mod tables;

#[cfg(target_arch = "avr")]
pub use column::Avr;
pub use column::{ColumnJob, ColumnKernel, Native, Portable};
pub use math::{div_shl, log2_q20, mul_hi};
pub use params::{
    distance_x, fit, fit_grid, fit_least_squares, Ar1, Bounds, CalStats, OnlineParams, ParamFit,
    MAX_SAMPLES,
};
pub use refine::{
    db_mean, extended, linear_avg, max_rssi, observations, observations_of, refine_anchor, Obs,
    Observations,
};
pub use search::{
    estimate, estimate_with, locate, mle, mle_and_mmse_window, mle_and_mmse_window_into, mle_with,
    mmse, mmse_window, mmse_window_with, mmse_with, sink_fix, Estimate, Estimator, Weights,
    LOG2_CLAMP, LOG2_M2, WINDOW_ROWS,
};

pub use crate::grid::Search;
pub use crate::params::{FitMethod, ParamMode};
pub use crate::refine::Refinement;
pub use crate::LocError;
use crate::{MAX_ANCHORS, MAX_CHANNELS};

/// One dB in the Q.16 dB format.
pub const DB: i32 = 1 << 16;
/// α = 1 in the Q.24 format.
pub const ALPHA: i32 = 1 << 24;
/// Largest |P0| (and P0 bound) the fixed path accepts, Q.16 dB: 512 dB. Larger values are
/// clamped (they keep every intermediate inside its integer type).
pub const P0_LIMIT: i32 = 512 * DB;
/// Largest |α| (and α bound) the fixed path accepts, Q.24: 32. Larger values are clamped.
pub const ALPHA_LIMIT: i32 = 32 * ALPHA;

/// A point in centimetres (anchor positions).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct PointCm {
    /// x, cm.
    pub x: i16,
    /// y, cm.
    pub y: i16,
}

impl PointCm {
    /// `(x, y)` cm.
    pub const fn new(x: i16, y: i16) -> PointCm {
        PointCm { x, y }
    }
}

/// A position estimate in millimetres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct PointMm {
    /// x, mm.
    pub x: u32,
    /// y, mm.
    pub y: u32,
}

/// The localization area `[0, width] × [0, height]` cm.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct AreaCm {
    /// Extent in x, cm.
    pub width: u16,
    /// Extent in y, cm.
    pub height: u16,
}

impl AreaCm {
    /// A `width` × `height` cm area.
    pub const fn new(width: u16, height: u16) -> AreaCm {
        AreaCm { width, height }
    }

    /// Fine lattice point `(i, j)` (`i, j ≤ F`, [`crate::grid::FINE_DIVS`]) in mm, rounded:
    /// `(10·W·i/F, 10·H·j/F)`.
    pub fn lattice_mm(self, i: usize, j: usize) -> PointMm {
        const F: u32 = crate::grid::FINE_DIVS as u32;
        let f = |side: u16, k: usize| (10 * side as u32 * (k as u32).min(F) + F / 2) / F;
        PointMm {
            x: f(self.width, i),
            y: f(self.height, j),
        }
    }
}

/// The log-normal path-loss model in fixed point: `p(d) = P0 − 10·α·log10(d / 1 m)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PathLoss {
    /// Received power at 1 m, Q.16 dBm.
    pub p0: i32,
    /// Path-loss exponent α, Q.24.
    pub alpha: i32,
}

impl PathLoss {
    /// The thesis' defaults: P0 = −40 dBm, α = 3.
    pub const THESIS: PathLoss = PathLoss {
        p0: -40 * DB,
        alpha: 3 * ALPHA,
    };

    /// From P0 in hundredths of a dB and α in hundredths (`from_centi(-4050, 275)`: −40.5 dBm,
    /// α = 2.75).
    pub const fn from_centi(p0_centi_db: i32, alpha_centi: i32) -> PathLoss {
        PathLoss {
            p0: ((p0_centi_db as i64 * DB as i64) / 100) as i32,
            alpha: ((alpha_centi as i64 * ALPHA as i64) / 100) as i32,
        }
    }

    /// The model with P0 and α clamped to [`P0_LIMIT`] and [`ALPHA_LIMIT`].
    pub const fn sane(self) -> PathLoss {
        PathLoss {
            p0: math::clamp_i32(self.p0, -P0_LIMIT, P0_LIMIT),
            alpha: math::clamp_i32(self.alpha, -ALPHA_LIMIT, ALPHA_LIMIT),
        }
    }
}

/// The agent's RSSI bytes from one anchor, per channel.
pub type ChannelBytes = [Option<u8>; MAX_CHANNELS];

/// What one fixed-point estimate works from (the MCU twin of [`crate::Measurements`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Measurements {
    /// Number of anchors in use (≤ [`MAX_ANCHORS`]).
    pub n_anchors: usize,
    /// Number of channels in use (≤ [`MAX_CHANNELS`]).
    pub n_channels: usize,
    /// Anchor positions (first `n_anchors` used).
    pub anchors: [PointCm; MAX_ANCHORS],
    /// The agent's RSSI bytes per anchor and channel.
    pub rssi: [ChannelBytes; MAX_ANCHORS],
    /// Anchor-to-anchor RSSI bytes: `a2a[i][j][c]`, anchor `i` heard from anchor `j`.
    pub a2a: [[ChannelBytes; MAX_ANCHORS]; MAX_ANCHORS],
}

impl Measurements {
    /// Anchors at `positions` (at most [`MAX_ANCHORS`], extra ignored), `n_channels` channels,
    /// nothing heard yet.
    pub fn new(positions: &[PointCm], n_channels: usize) -> Measurements {
        let mut anchors = [PointCm::default(); MAX_ANCHORS];
        for (a, &p) in anchors.iter_mut().zip(positions) {
            *a = p;
        }
        Measurements {
            n_anchors: positions.len().min(MAX_ANCHORS),
            n_channels: n_channels.min(MAX_CHANNELS),
            anchors,
            rssi: [[None; MAX_CHANNELS]; MAX_ANCHORS],
            a2a: [[[None; MAX_CHANNELS]; MAX_ANCHORS]; MAX_ANCHORS],
        }
    }

    /// The anchor positions in use.
    pub fn anchors(&self) -> &[PointCm] {
        &self.anchors[..self.n_anchors.min(MAX_ANCHORS)]
    }

    /// Channels in use (at most [`MAX_CHANNELS`]).
    pub fn channels(&self) -> usize {
        self.n_channels.min(MAX_CHANNELS)
    }
}
