//! The integer-only path of the sink MCU (SPEC §5): the reference algorithms of [`crate::refine`],
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
//! The lattice is the reference's ([`crate::grid::lattice_point`]): `(W·i/50, H·j/50)`, which in
//! units of 1/50 cm is the integer `(W·i, H·j)`, so every squared anchor distance `d²` is an exact
//! integer (≤ 46 bits). With `K = 5·α·log10 2` the reference cost is
//! `C = Σ wᵢ (zᵢ − P0 + K·log2(dᵢ² / 1 m²))² = K² · Σ wᵢ (ρᵢ + log2 dᵢ²)²`,
//! `ρᵢ = (zᵢ − P0)/K − log2(1 m²)` (one division per estimate, none per lattice point): the
//! position search compares `C' = C/K²`, in log2 units, which has the same minimisers and the
//! same posterior (the weights' exponent is rescaled by `K²` once).
//!
//! Once per search each anchor gets a shift `h`: the fewest bits that bring its offsets `dx`,
//! `dy` from anywhere in the area below 2^16 once rounded to `2^h` lattice units (`h = 0`
//! within 13.1 m of the anchor; `ρ` and the clamp absorb the `2h`), so every lattice point costs
//! the same wherever the search evaluates it. A window (the coarse grid, the fine window, a
//! descent step's 3 × 3 block) is evaluated a column at a time, anchor by anchor
//! ([`TermKernel::column`]): per column each anchor's `dx²`, per row `dy²` from the row's
//! offset (24-bit, then `|·|` rounded to `2^h`, squared in 32 bits), `d²` one 32-bit add with
//! carry. Then per (anchor, lattice point): `log2` from a 64-segment quadratic table in flash
//! (error < 2.2·10⁻⁶, six 8 × 8 multiplies, constant shifts only), the clamp at the model's
//! 1 cm ([`crate::model::MIN_DISTANCE`]), `u = ρ + log2 d²` (Q.20), `u²` in Q.20 from five
//! 8 × 8 multiplies (`|u|` saturates at 32, i.e. `|z − p| ≥ 32·K` dB, where no estimate lives),
//! the weight, and a saturating 32-bit sum that stops as soon as it cannot beat the point it is
//! compared with (exact: the terms are non-negative; it skips about a third of the terms). The
//! cost is within about 10⁻⁵ dB per observation of the reference's within 13 m of every anchor
//! (farther, the rounding of the offsets adds up to `2^h/d` relative in `d²`), so a lattice
//! decision differs from the f64 one only on a near-tie: of 2 100 random trials in 1–30 m rooms
//! one thesis decision differs (99.95 % within 1 cm; `tests/fixed.rs`).
//!
//! # Map
//!
//! * Refinements ([`observations`], [`observations_of`], [`refine_anchor`]): Single, Max,
//!   LinearAvg (`10^(−k/10)` from two 10-entry tables, the log from the log2 table), Extended (dB
//!   mean, weight = channel count, and `const_cost`).
//! * Path-loss fit ([`CalStats`], [`fit`], [`Ar1`], [`OnlineParams`]): both methods of
//!   [`crate::params::fit`], with the same modes, bounds handling, identifiability rule and σ: the
//!   exact box-constrained least squares ([`fit_least_squares`]: the MCU's method, one solve) and
//!   the thesis' grid ([`fit_grid`]: 31 α steps); AR(1) smoothing in Q.16.
//! * Position ([`mle`] with [`Search::Thesis`], [`Search::MultiStart`] or [`Search::Exhaustive`];
//!   [`mmse`] over the full lattice (host-sized: 64-bit totals), weights `2^(−y)` from a
//!   32-entry table, and [`mmse_window`] over the thesis' fine window only, the sink's MMSE;
//!   [`estimate`], [`locate`]); [`sink_fix`] runs the whole sink step (fit, smoothing,
//!   refinement, estimate).
//! * The sink's two estimates at once ([`mle_and_mmse_window_with`]): the windowed MMSE's window
//!   *is* the thesis' fine window around the same coarse winner, so one coarse stage and one pass
//!   over the window give both the thesis MLE and the windowed MMSE, bit for bit the
//!   [`Estimate`]s of [`mle_with`] (`Search::Thesis`) and [`mmse_window_with`] (tested on
//!   random inputs, evaluation counts included). `sink-fw` runs this, and it links nothing
//!   else of the search: 32-bit arithmetic only (no 64-bit multiply or division), one window
//!   routine, the posterior in `u32` sums (weights Q.20 of the window's ≤ 121 points).
//!
//! Errors are [`LocError`]: fewer than three usable anchors is
//! [`LocError::TooFewAnchors`]; a fit without samples [`LocError::NoCalibrationData`]. Nothing
//! panics or overflows on any input (checked by the debug-build property tests).
//!
//! # On the ATmega328P
//!
//! `cargo bench -p hoploc --bench mcu_estimate` runs the whole sink step (4 anchors × 2
//! channels in a 10 m room) as firmware in simavr (`mcu-bench`), with each search column —
//! rows × anchors, the early exit at the bound and the column's minimum — in AVR assembly
//! ([`TermKernel::column`], `uno_board::AvrTerm`): calibration statistics of the 6 anchor pairs
//! ≈ 10 k cycles (the log, x, the sums in AVR assembly), the sink's least-squares round (fit,
//! both AR(1) smoothers, σ; its multiply and divide written for flash) ≈ 19 k, Extended refinement ≈ 6 k, thesis MLE ≈ 113 k (312 anchor
//! terms of the 932 a full evaluation takes, ≈ 300 cycles each with their row's share of the
//! loop), ≈ 148 k in all (9.3 ms, 26× fewer than the same algorithm in f32): within the 160 k
//! budget (`cargo bench -p hoploc --bench mcu_estimate`). The windowed MMSE (the sink's,
//! [`mmse_window`]) is ≈ 253 k (≈ 288 k for the whole step): its weights need every window cost
//! up to 21 bits of weight below the best, so the early exits hardly ever fire. The sink's search
//! ([`mle_and_mmse_window_into`] with the assembly setup, driver, column, posterior and weights,
//! and the two tables) is ≈ 4.9 KB of flash in `sink-fw` (README, Footprint); its stack,
//! ≈ 0.4 KB below `Sink::locate`, is most of the way from the sink's report handler to its
//! deepest point. Stack peak of `est-fixed` ≈ 1.1 KB.
//!
//! ```ignore
//! // The lean sink step (what a firmware calls; `sink_fix` does the same from a `Measurements`):
//! let mut stats = CalStats::new();
//! for (a, b, bytes) in anchor_pairs { stats.push_pair(a, b, &bytes); } // both directions' bytes
//! if let Ok(f) = fit_least_squares(&stats, params.mode, params.current(), &params.bounds) {
//!     params.feed(&f);
//! }
//! let obs = observations_of(&anchors, &rssi, n_channels, Refinement::Extended);
//! let fix = mle(&obs, params.current(), area, Search::Thesis)?;
//! ```

mod grid;
mod kernel;
// `square`, `sq_shr` and `square_shift` served the position search's old shifted-square path;
// they are left to math.rs' owner (the fit's rework) to remove.
#[allow(dead_code)]
mod math;
mod params;
mod refine;
mod tables;

pub use grid::{
    estimate, estimate_with, locate, mle, mle_and_mmse_window_into, mle_and_mmse_window_with,
    mle_with, mmse, mmse_window, mmse_window_with, mmse_with, portable_finish, portable_sink,
    sink_fix, Estimate, Estimator, SinkFrame, SinkLocals,
};
pub use kernel::{
    div_shl, exp2_segment_table, log2_segment_base, log2_segment_table, mul_hi, offset_square,
    portable_coarse_from, portable_column, portable_fine_post, portable_guess, portable_move,
    portable_observe, portable_place, portable_posterior, portable_search, portable_term,
    portable_weights, AnchorTerm, ColumnJob, Lattice, LatticeMin, Placement, Portable, Posterior,
    Setup, TermKernel, Weights, I24, LOG2_CLAMP, LOG2_M2, SQ_SAT, U_SAT, WINDOW_ROWS,
};
pub use params::{
    distance_x, fit, fit_grid, fit_least_squares, fit_least_squares_with, portable_ar1_update,
    portable_fit, portable_push, portable_step, portable_weigh, Ar1, Bounds, CalStats, FitJob,
    FitKernel, OnlineParams, PairBytes, ParamFit, PortableFit, Smoothers, MAX_SAMPLES,
};
pub use refine::{
    db_mean, extended, linear_avg, max_rssi, observations, observations_of, portable_report_inputs,
    refine_anchor, Obs, Observations, ReportBytes, ReportKernel,
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

    /// Fine lattice point `(i, j)` (`i, j ≤ 50`) in mm, rounded: `(10·W·i/50, 10·H·j/50)`.
    pub fn lattice_mm(self, i: usize, j: usize) -> PointMm {
        let f = |side: u16, k: usize| (side as u32 * k.min(50) as u32 + 2) / 5;
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
