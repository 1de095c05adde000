//! Path-loss parameter (P0, α) estimation from anchor-to-anchor RSSI.
//!
//! Anchors know their mutual distances, so every anchor-to-anchor RSSI `a2a[i][j][c]` (`i ≠ j`) is a
//! calibration sample `z = P0 + α·x` with `x = −10·log10(d_ij)`: the model is linear in `(P0, α)`.
//! Samples are summarised in [`CalStats`] (count, means and centred second moments, accumulated
//! with Welford's update so large dBm values lose no precision); both fits work from those alone:
//!
//! * [`FitMethod::Grid`]: the thesis' grid, α in steps of [`ALPHA_STEP`], P0 in steps of
//!   [`P0_STEP`], both within [`Bounds`], minimising the squared error. For each α the best grid P0
//!   is the grid value nearest to the continuous optimum `z̄ − α·x̄` (the error is a symmetric
//!   parabola in P0), so the search is one pass over α and returns the brute-force 2-D argmin
//!   (ties: smallest α, then smallest P0).
//! * [`FitMethod::LeastSquares`]: the exact minimiser of the squared error over the box
//!   `[α_min, α_max] × [P0_min, P0_max]`. If the unconstrained solution lies outside, the
//!   constrained optimum of this convex quadratic lies on the box boundary; each of the four edges
//!   is minimised in closed form (the free variable's 1-D optimum, clamped to its range) and the
//!   best edge wins. So the result is the constrained optimum, not merely a clamped one.
//!
//! When all calibration distances are (nearly) equal, α is not identifiable (any α fits with a
//! matching P0); then α keeps the prior value (clamped to the bounds, on the grid for the grid
//! method) and only P0 is fitted.
//!
//! Anchor pairs closer than [`MIN_DISTANCE`] (coincident anchors) are skipped: the model's clamp
//! there is a numerical guard, not physics. Non-finite RSSI values are skipped too.

use crate::model::{Measurements, PathLoss, MAX_CHANNELS, MIN_DISTANCE};
use crate::LocError;

/// α step of the thesis' grid.
pub const ALPHA_STEP: f64 = 0.1;
/// P0 step of the thesis' grid, dB.
pub const P0_STEP: f64 = 0.5;

/// Which parameters are estimated online.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParamMode {
    /// Neither: the prior model is used as is.
    Fixed,
    /// P0 only, α from the prior (battery droop moves P0, not the environment's α).
    P0Only,
    /// Both P0 and α.
    P0AndAlpha,
}

/// How the parameters are fitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FitMethod {
    /// The thesis' grid ([`ALPHA_STEP`] × [`P0_STEP`]).
    Grid,
    /// Exact least squares constrained to the bounds.
    LeastSquares,
}

/// Allowed parameter range (inclusive). Reversed bounds are used as if sorted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Smallest α.
    pub alpha_min: f64,
    /// Largest α.
    pub alpha_max: f64,
    /// Smallest P0, dBm.
    pub p0_min: f64,
    /// Largest P0, dBm.
    pub p0_max: f64,
}

impl Bounds {
    /// The thesis' ranges: α ∈ [2, 5], P0 ∈ [−60, −20] dBm.
    pub const THESIS: Bounds = Bounds {
        alpha_min: 2.0,
        alpha_max: 5.0,
        p0_min: -60.0,
        p0_max: -20.0,
    };

    fn alpha(&self) -> (f64, f64) {
        sorted(self.alpha_min, self.alpha_max)
    }

    fn p0(&self) -> (f64, f64) {
        sorted(self.p0_min, self.p0_max)
    }
}

impl Default for Bounds {
    fn default() -> Self {
        Bounds::THESIS
    }
}

fn sorted(a: f64, b: f64) -> (f64, f64) {
    if a <= b {
        (a, b)
    } else {
        (b, a)
    }
}

/// `v` limited to `[lo, hi]` (never panics, unlike `f64::clamp` on odd bounds).
fn clamp(v: f64, lo: f64, hi: f64) -> f64 {
    v.max(lo).min(hi)
}

/// Sufficient statistics of calibration samples `(x = −10·log10 d, z)`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CalStats {
    n: usize,
    x_mean: f64,
    z_mean: f64,
    sxx: f64,
    sxz: f64,
    szz: f64,
}

impl CalStats {
    /// No samples.
    pub const fn new() -> CalStats {
        CalStats {
            n: 0,
            x_mean: 0.0,
            z_mean: 0.0,
            sxx: 0.0,
            sxz: 0.0,
            szz: 0.0,
        }
    }

    /// Adds a sample: RSSI `z` dBm at distance `d` metres. Skipped (returns `false`) when `z` or
    /// `d` is not finite or `d < MIN_DISTANCE`.
    pub fn push(&mut self, d: f64, z: f64) -> bool {
        if !(z.is_finite() && d.is_finite() && d >= MIN_DISTANCE) {
            return false;
        }
        let x = -10.0 * libm::log10(d);
        self.n += 1;
        let n = self.n as f64;
        let dx = x - self.x_mean;
        let dz = z - self.z_mean;
        self.x_mean += dx / n;
        self.z_mean += dz / n;
        self.sxx += dx * (x - self.x_mean);
        self.sxz += dx * (z - self.z_mean);
        self.szz += dz * (z - self.z_mean);
        true
    }

    /// All anchor-to-anchor samples of `m` (`i ≠ j`, channels in use), or only channel `channel`.
    pub fn from_measurements(m: &Measurements, channel: Option<usize>) -> CalStats {
        let mut s = CalStats::new();
        let n_ch = m.n_channels.min(MAX_CHANNELS);
        for (i, ai) in m.anchors().iter().enumerate() {
            for (j, aj) in m.anchors().iter().enumerate() {
                if i == j {
                    continue;
                }
                let d = ai.pos.dist(aj.pos);
                for (c, z) in m.a2a[i][j][..n_ch].iter().enumerate() {
                    if let (Some(z), true) = (z, channel.is_none_or(|k| k == c)) {
                        s.push(d, *z);
                    }
                }
            }
        }
        s
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Sum of squared residuals `Σ (z − P0 − α·x)²` under `model`.
    pub fn sse(&self, model: PathLoss) -> f64 {
        self.sse_at(model.p0, model.alpha)
    }

    fn sse_at(&self, p0: f64, alpha: f64) -> f64 {
        let off = self.z_mean - p0 - alpha * self.x_mean;
        // Centred form: exact algebra, ≥ 0 up to rounding.
        (self.szz - 2.0 * alpha * self.sxz + alpha * alpha * self.sxx + self.n as f64 * off * off)
            .max(0.0)
    }

    /// Whether the samples span enough distinct distances to determine α.
    fn alpha_identifiable(&self) -> bool {
        self.sxx > 1e-9 * self.n as f64
    }

    /// Best P0 for a given α (unconstrained): the mean of `z − α·x`.
    fn p0_for(&self, alpha: f64) -> f64 {
        self.z_mean - alpha * self.x_mean
    }

    /// Best α for a given P0 (unconstrained), `None` if every x is 0 (all distances 1 m).
    fn alpha_for(&self, p0: f64) -> Option<f64> {
        let n = self.n as f64;
        let den = self.sxx + n * self.x_mean * self.x_mean;
        (den > 0.0).then(|| (self.sxz + n * self.x_mean * (self.z_mean - p0)) / den)
    }
}

/// Result of a parameter fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamFit {
    /// The fitted (or fixed) model.
    pub model: PathLoss,
    /// Sum of squared residuals of the calibration samples under `model`.
    pub sse: f64,
    /// Number of calibration samples.
    pub n: usize,
    /// Parameters actually fitted (0, 1 or 2): the degrees of freedom taken from `n`.
    pub fitted: usize,
    /// Shadowing σ estimate, dB: `sqrt(sse / (n − fitted))`, `None` when `n ≤ fitted`.
    ///
    /// The `n − fitted` correction makes σ² unbiased for the unconstrained least-squares fit
    /// under the model; after clamping or on the grid the residuals are somewhat larger, so σ is
    /// then slightly overestimated (the safe side for the MMSE weights).
    pub sigma: Option<f64>,
}

impl ParamFit {
    fn new(stats: &CalStats, model: PathLoss, fitted: usize) -> ParamFit {
        let sse = stats.sse(model);
        let sigma = (stats.n > fitted).then(|| libm::sqrt(sse / (stats.n - fitted) as f64));
        ParamFit {
            model,
            sse,
            n: stats.n,
            fitted,
            sigma,
        }
    }
}

/// Fits the model to `stats` in `mode` with `method` within `bounds`.
///
/// `prior` supplies what is not fitted (α in [`ParamMode::P0Only`], everything in
/// [`ParamMode::Fixed`], α when it is not identifiable). [`ParamMode::Fixed`] never fails (σ is
/// then estimated from the residuals if there are samples); the other modes return
/// [`LocError::NoCalibrationData`] without samples.
pub fn fit(
    stats: &CalStats,
    mode: ParamMode,
    method: FitMethod,
    prior: PathLoss,
    bounds: &Bounds,
) -> Result<ParamFit, LocError> {
    if mode == ParamMode::Fixed {
        return Ok(ParamFit::new(stats, prior, 0));
    }
    if stats.is_empty() {
        return Err(LocError::NoCalibrationData);
    }
    let (a_lo, a_hi) = bounds.alpha();
    let fit_p0 = |alpha: f64| match method {
        FitMethod::Grid => grid_p0(stats.p0_for(alpha), bounds),
        FitMethod::LeastSquares => {
            let (lo, hi) = bounds.p0();
            clamp(stats.p0_for(alpha), lo, hi)
        }
    };
    if mode == ParamMode::P0Only || !stats.alpha_identifiable() {
        let alpha = match mode {
            // α is the user's fixed value: not subject to the bounds.
            ParamMode::P0Only => prior.alpha,
            _ => match method {
                FitMethod::Grid => grid_alpha(prior.alpha, bounds),
                FitMethod::LeastSquares => clamp(prior.alpha, a_lo, a_hi),
            },
        };
        let model = PathLoss {
            p0: fit_p0(alpha),
            alpha,
        };
        return Ok(ParamFit::new(stats, model, 1));
    }
    let model = match method {
        FitMethod::Grid => {
            let mut best = (
                f64::INFINITY,
                PathLoss {
                    p0: 0.0,
                    alpha: 0.0,
                },
            );
            for k in 0..=grid_steps(a_lo, a_hi, ALPHA_STEP) {
                let alpha = a_lo + k as f64 * ALPHA_STEP;
                let p0 = fit_p0(alpha);
                let e = stats.sse_at(p0, alpha);
                if e < best.0 || k == 0 {
                    best = (e, PathLoss { p0, alpha });
                }
            }
            best.1
        }
        FitMethod::LeastSquares => box_least_squares(stats, bounds),
    };
    Ok(ParamFit::new(stats, model, 2))
}

/// Fits from all anchor-to-anchor samples of `m` (every channel in use).
pub fn estimate(
    m: &Measurements,
    mode: ParamMode,
    method: FitMethod,
    prior: PathLoss,
    bounds: &Bounds,
) -> Result<ParamFit, LocError> {
    fit(
        &CalStats::from_measurements(m, None),
        mode,
        method,
        prior,
        bounds,
    )
}

/// Number of whole steps of `step` from `lo` to `hi` (a tolerance absorbs decimal steps).
fn grid_steps(lo: f64, hi: f64, step: f64) -> usize {
    let k = libm::floor((hi - lo) / step + 1e-9);
    if k.is_finite() && k > 0.0 {
        // Bounded for sane ranges; an absurd range is cut rather than looping for ages.
        k.min(1_000_000.0) as usize
    } else {
        0
    }
}

/// The P0 grid value nearest to `p0` (clamped to the grid).
fn grid_p0(p0: f64, bounds: &Bounds) -> f64 {
    let (lo, hi) = bounds.p0();
    snap(p0, lo, grid_steps(lo, hi, P0_STEP), P0_STEP)
}

/// The α grid value nearest to `alpha` (clamped to the grid).
fn grid_alpha(alpha: f64, bounds: &Bounds) -> f64 {
    let (lo, hi) = bounds.alpha();
    snap(alpha, lo, grid_steps(lo, hi, ALPHA_STEP), ALPHA_STEP)
}

fn snap(v: f64, lo: f64, steps: usize, step: f64) -> f64 {
    let k = clamp(libm::round((v - lo) / step), 0.0, steps as f64);
    // NaN (from a NaN prior) lands on the first grid value.
    let k = if k.is_nan() { 0.0 } else { k };
    lo + k * step
}

/// The exact least-squares minimiser on the bounds box (see the module docs).
fn box_least_squares(stats: &CalStats, bounds: &Bounds) -> PathLoss {
    let (a_lo, a_hi) = bounds.alpha();
    let (p_lo, p_hi) = bounds.p0();
    let alpha = stats.sxz / stats.sxx;
    let p0 = stats.p0_for(alpha);
    if (a_lo..=a_hi).contains(&alpha) && (p_lo..=p_hi).contains(&p0) {
        return PathLoss { p0, alpha };
    }
    let on_alpha_edge = |alpha: f64| PathLoss {
        p0: clamp(stats.p0_for(alpha), p_lo, p_hi),
        alpha,
    };
    let on_p0_edge = |p0: f64| PathLoss {
        p0,
        alpha: clamp(stats.alpha_for(p0).unwrap_or(a_lo), a_lo, a_hi),
    };
    let candidates = [
        on_alpha_edge(a_lo),
        on_alpha_edge(a_hi),
        on_p0_edge(p_lo),
        on_p0_edge(p_hi),
    ];
    let mut best = candidates[0];
    for c in &candidates[1..] {
        if stats.sse(*c) < stats.sse(best) {
            best = *c;
        }
    }
    best
}

/// First-order autoregressive smoother `y[n] = a·y[n−1] + b·x[n]`, `y[0] = x[0]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ar1 {
    /// Weight of the previous output.
    pub a: f64,
    /// Weight of the new input.
    pub b: f64,
    y: Option<f64>,
}

impl Default for Ar1 {
    /// The thesis' `a = 0.8, b = 0.2`.
    fn default() -> Self {
        Ar1::new(0.8, 0.2)
    }
}

impl Ar1 {
    /// A smoother with coefficients `a`, `b` and no state.
    pub const fn new(a: f64, b: f64) -> Ar1 {
        Ar1 { a, b, y: None }
    }

    /// Feeds `x`, returns the new output (the first input initialises the state).
    pub fn update(&mut self, x: f64) -> f64 {
        let y = match self.y {
            Some(prev) => self.a * prev + self.b * x,
            None => x,
        };
        self.y = Some(y);
        y
    }

    /// Current output, `None` before the first input.
    pub fn value(&self) -> Option<f64> {
        self.y
    }

    /// Forgets the state.
    pub fn reset(&mut self) {
        self.y = None;
    }
}

/// Online parameter estimation: a fit per measurement set, smoothed per parameter by [`Ar1`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OnlineParams {
    /// What is estimated.
    pub mode: ParamMode,
    /// How it is fitted.
    pub method: FitMethod,
    /// Parameter range.
    pub bounds: Bounds,
    prior: PathLoss,
    p0: Ar1,
    alpha: Ar1,
}

impl OnlineParams {
    /// Starts from `prior` with the default smoothers.
    pub fn new(mode: ParamMode, method: FitMethod, bounds: Bounds, prior: PathLoss) -> Self {
        Self::with_smoothers(mode, method, bounds, prior, Ar1::default(), Ar1::default())
    }

    /// Starts from `prior` with the given smoothers for P0 and α.
    pub fn with_smoothers(
        mode: ParamMode,
        method: FitMethod,
        bounds: Bounds,
        prior: PathLoss,
        p0: Ar1,
        alpha: Ar1,
    ) -> Self {
        OnlineParams {
            mode,
            method,
            bounds,
            prior,
            p0,
            alpha,
        }
    }

    /// The smoothed model (the prior for parameters not yet estimated).
    pub fn current(&self) -> PathLoss {
        PathLoss {
            p0: self.p0.value().unwrap_or(self.prior.p0),
            alpha: self.alpha.value().unwrap_or(self.prior.alpha),
        }
    }

    /// Fits `m`'s calibration samples and feeds the smoothers; returns the raw fit (the smoothed
    /// model is [`OnlineParams::current`]). On error the state is unchanged.
    pub fn update(&mut self, m: &Measurements) -> Result<ParamFit, LocError> {
        let stats = CalStats::from_measurements(m, None);
        let f = fit(&stats, self.mode, self.method, self.current(), &self.bounds)?;
        match self.mode {
            ParamMode::Fixed => {}
            ParamMode::P0Only => {
                self.p0.update(f.model.p0);
            }
            ParamMode::P0AndAlpha => {
                self.p0.update(f.model.p0);
                self.alpha.update(f.model.alpha);
            }
        }
        Ok(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(model: PathLoss, ds: &[f64], noise: &[f64]) -> CalStats {
        let mut s = CalStats::new();
        for (i, &d) in ds.iter().enumerate() {
            s.push(d, model.rssi_at(d) + noise[i % noise.len()]);
        }
        s
    }

    #[test]
    fn grid_equals_brute_force() {
        let truth = PathLoss {
            p0: -43.3,
            alpha: 2.77,
        };
        let s = stats(
            truth,
            &[1.0, 2.0, 3.5, 7.0, 9.9],
            &[1.3, -2.0, 0.4, 0.9, -0.1],
        );
        let b = Bounds::THESIS;
        let f = fit(&s, ParamMode::P0AndAlpha, FitMethod::Grid, truth, &b).unwrap();
        let mut best = (f64::INFINITY, 0.0, 0.0);
        for k in 0..=30 {
            for j in 0..=80 {
                let (a, p) = (2.0 + k as f64 * 0.1, -60.0 + j as f64 * 0.5);
                let e = s.sse_at(p, a);
                if e < best.0 {
                    best = (e, a, p);
                }
            }
        }
        assert!((f.model.alpha - best.1).abs() < 1e-9, "{f:?} {best:?}");
        assert!((f.model.p0 - best.2).abs() < 1e-9, "{f:?} {best:?}");
    }

    #[test]
    fn box_least_squares_is_the_constrained_optimum() {
        // Data whose unconstrained fit is far outside the box on both parameters.
        let truth = PathLoss {
            p0: -10.0,
            alpha: 6.5,
        };
        let s = stats(truth, &[1.5, 2.0, 3.0, 5.0], &[0.7, -0.3, 0.2, -0.6]);
        let b = Bounds::THESIS;
        let ls = box_least_squares(&s, &b);
        // Dense scan of the box: nothing beats the closed form.
        let e = s.sse(ls);
        for k in 0..=300 {
            for j in 0..=400 {
                let (a, p) = (2.0 + k as f64 * 0.01, -60.0 + j as f64 * 0.1);
                assert!(s.sse_at(p, a) >= e - 1e-9, "({a}, {p}) beats {ls:?}");
            }
        }
    }

    #[test]
    fn equal_distances_keep_prior_alpha() {
        let truth = PathLoss {
            p0: -45.0,
            alpha: 3.0,
        };
        let s = stats(truth, &[5.0, 5.0, 5.0], &[0.0]);
        let prior = PathLoss {
            p0: -40.0,
            alpha: 3.5,
        };
        for method in [FitMethod::Grid, FitMethod::LeastSquares] {
            let f = fit(&s, ParamMode::P0AndAlpha, method, prior, &Bounds::THESIS).unwrap();
            assert!((f.model.alpha - 3.5).abs() < 1e-12);
            assert_eq!(f.fitted, 1);
            // P0 fits the data with that α: z = −45 − 30·log10 5 = P0 − 35·log10 5.
            let want = -45.0 + 5.0 * libm::log10(5.0);
            let tol = if method == FitMethod::Grid {
                0.25
            } else {
                1e-9
            };
            assert!((f.model.p0 - want).abs() <= tol, "{f:?}");
        }
    }
}
