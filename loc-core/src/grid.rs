//! Position estimation on a grid: the thesis' coarse-to-fine maximum-likelihood search
//! and the posterior-mean (MMSE) estimate.
//!
//! The cost of a position `x` is `C(x) = Σ wᵢ (zᵢ − p(|x − aᵢ|))²` over the
//! [`Observations`] (plus their [`Observations::const_cost`]); under the log-normal model with
//! shadowing σ the likelihood is `exp(−C/(2σ²))`.
//!
//! Every position searched is a point of one *fine lattice*: `(W·i/50, H·j/50)`, `i, j = 0…50`
//! ([`FINE_DIVS`]), so the coarse grid (10 % steps, [`COARSE_DIVS`]) is the fine lattice points with
//! `i, j` multiples of 5, nothing ever leaves the area, and a fixed-point port that indexes the same
//! lattice searches the same positions. Scans run `i` (x) outer, `j` (y) inner, and a
//! strictly smaller cost is needed to replace the best so far: ties go to the first point in scan
//! order.
//!
//! * [`Search::Thesis`]: coarse 11 × 11, then the fine lattice within ± one coarse step (± 5 fine
//!   steps) of the coarse winner, clipped to the area: at most 121 + 121 = 242 cost evaluations.
//! * [`Search::MultiStart`] (an improvement on the thesis search): the same coarse grid, then a
//!   steepest descent over the 8 fine-lattice neighbours from each of the four best coarse points,
//!   the best end point winning; never more than the thesis' 242 evaluations (a descent stops when
//!   the budget is spent). The thesis search fails when the fine minimum's coarse cell is not the
//!   coarse winner's neighbour: near edges and anchors the cost changes fastest, so one coarse
//!   sample represents its cell worst there, and along the edge between two anchors the cost is
//!   often bimodal. Measured on the thesis study's layouts (3 and 4 anchors, σ = 2…6 dB, 1–2
//!   channels, also 6 × 4 m and 30 × 30 m): the thesis search misses the fine-lattice minimum in
//!   0.3–2.1 % of trials, multi-start in 0.006–0.24 %, spending ~201–213 evaluations on average
//!   against ~213–230. (The RMSE barely moves: the missed minima are near-ties.)
//!
//!   What it still misses is the lattice's doing, not the descent's: a descent ends at the first
//!   point none of whose 8 neighbours is strictly cheaper, and the *sampled* cost can have several
//!   such pits along one valley. Close to an anchor the cost's valley is the circle of the
//!   measured distance around it, narrow (off the circle by Δd the term grows like
//!   `(10α/ln 10 · Δd/d)²`, ≈ 136·Δd² per m² at d ≈ 1.1 m, α = 3) and curved across the 2 % lattice,
//!   while the far anchors tilt it only gently along the circle; the lattice points that happen
//!   to lie near the circle become separate pits. Noise-free, 4 anchors at the corners of
//!   10 × 10 m, agent at (0.5, 1.0): the lattice minimum is (0.4, 1.0) (cost 0.260, 1.077 m from
//!   the corner anchor), but (0.8, 0.8) (0.323, 1.131 m) is a pit too, separated by (0.6, 1.0)
//!   (0.326, 1.166 m); the four best coarse points descend to (0, 1.2) and (0.8, 0.8), so the
//!   search returns (0.8, 0.8), 0.36 m from the truth. The same happens at that point's seven
//!   mirror images (8 of the study's 361 points; at σ = 0.01 dB 7–8 of them). A plain full
//!   8-neighbour descent from the same four starts ends at the same points
//!   (`multi_start_misses_are_lattice_pits` in tests/estimator.rs).
//! * [`Search::Exhaustive`]: all 51 × 51 fine points (2 601 evaluations): the true lattice MLE, the
//!   host reference the fast searches are measured against.
//!
//! The MMSE estimate is the posterior mean over the whole fine lattice (a uniform prior over the
//! area): weights `exp(−(C − C_min)/(2σ²))`, accumulated in one pass with a running minimum
//! (log-sum-exp style), so no weight over- or underflows to NaN whatever the RSSI. σ = 0 (or NaN)
//! gives the σ → 0 limit, the mean of the lattice minimisers; σ = ∞ gives the area's centre.
//!
//! That is 2 601 cost evaluations, too many for the sink MCU. The *windowed* MMSE
//! ([`mmse_window`], [`Estimator::MmseWindow`]) is what it can afford at the thesis search's
//! price: the thesis' coarse stage picks the coarse winner `(ic, jc)`, then the posterior mean runs
//! over the thesis' fine window `[ic − 5, ic + 5] × [jc − 5, jc + 5]` (clipped to the lattice)
//! only, with the same weights and accumulator (the coarse points inside the window count with
//! their costs from the coarse stage). It is the full posterior mean truncated to the window: the
//! two agree when the posterior's mass lies inside it (σ small against the cost's curvature around
//! the minimum), and the windowed one is pulled towards the window's centre otherwise (one noisy
//! trial in the 10 m room with 4 anchors: 1 µm apart at σ = 0.5 dB, 9 mm at 1 dB, 0.27 m at
//! 3 dB; see tests/estimator.rs). Its smallest-cost point is the thesis MLE. The fixed-point
//! path ([`crate::fixed`]) and the f32 port of the MCU benchmark (`mcu-bench`) run this same
//! algorithm.

use crate::model::{Area, Measurements, PathLoss, Point, MAX_ANCHORS, MIN_DISTANCE};
use crate::refine::{observations, Observations, Refinement};
use crate::LocError;

/// Coarse grid divisions per side (10 % steps).
pub const COARSE_DIVS: usize = 10;
/// Fine lattice divisions per side (2 % steps).
pub const FINE_DIVS: usize = 50;
/// Fine steps per coarse step.
const RATIO: usize = FINE_DIVS / COARSE_DIVS;

/// Which grid search the MLE uses (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Search {
    /// The thesis: coarse 10 %, then fine 2 % within ± one coarse step of the coarse winner.
    Thesis,
    /// Coarse 10 %, then steepest descent on the fine lattice from the four best coarse points,
    /// within the thesis' worst-case budget of 242 cost evaluations.
    MultiStart,
    /// Every fine lattice point.
    Exhaustive,
}

/// Which estimator produced a fix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Estimator {
    /// Maximum likelihood (least squares) with this search.
    Mle(Search),
    /// Posterior mean over the whole fine lattice with this shadowing σ, dB.
    Mmse {
        /// σ used for the posterior weights.
        sigma: f64,
    },
    /// Posterior mean over the thesis' fine window around the coarse winner ([`mmse_window`]):
    /// the MMSE the sink MCU can afford.
    MmseWindow {
        /// σ used for the posterior weights.
        sigma: f64,
    },
}

/// A position estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// The position (inside the area).
    pub pos: Point,
    /// Smallest cost found (for MMSE: the lattice minimum; for the windowed MMSE: the window's),
    /// including the observations' position-independent part.
    pub min_cost: f64,
    /// The estimator that produced it.
    pub estimator: Estimator,
    /// Anchors used.
    pub anchors: usize,
    /// Scalar measurements behind the cost (sum of the observation weights).
    pub total_weight: f64,
    /// Cost evaluations spent.
    pub evaluations: usize,
}

impl Estimate {
    /// Shadowing σ estimated from the fit's residuals, `sqrt(min_cost / (total_weight − 2))`
    /// (two position coordinates fitted), `None` without a spare degree of freedom. The minimum is
    /// taken over the position, so this is biased low; prefer the anchor-to-anchor estimate
    /// ([`crate::params::ParamFit::sigma`]).
    pub fn sigma_hat(&self) -> Option<f64> {
        (self.total_weight > 2.0).then(|| libm::sqrt(self.min_cost / (self.total_weight - 2.0)))
    }
}

/// A side length usable for the lattice: negative, NaN or infinite sides count as 0.
fn side(s: f64) -> f64 {
    if s.is_finite() && s > 0.0 {
        s
    } else {
        0.0
    }
}

/// Fine lattice point `(i, j)` of `area`.
///
/// Computed as `side · (i / 50)`: the fraction is at most 1 and rounding is monotone, so the point
/// never leaves the area (`side · i / 50` can exceed the side by an ulp).
pub fn lattice_point(area: Area, i: usize, j: usize) -> Point {
    let n = FINE_DIVS as f64;
    Point::new(
        side(area.width) * (i as f64 / n),
        side(area.height) * (j as f64 / n),
    )
}

/// The cost function with its per-observation constants hoisted.
struct Cost {
    pos: [Point; MAX_ANCHORS],
    /// `zᵢ − P0`.
    r: [f64; MAX_ANCHORS],
    w: [f64; MAX_ANCHORS],
    n: usize,
    /// `5·α`: `z − p(d) = (z − P0) + 5α·log10(d²)`.
    k: f64,
}

impl Cost {
    fn new(obs: &Observations, model: PathLoss) -> Cost {
        let mut c = Cost {
            pos: [Point::default(); MAX_ANCHORS],
            r: [0.0; MAX_ANCHORS],
            w: [0.0; MAX_ANCHORS],
            n: obs.len(),
            k: 5.0 * model.alpha,
        };
        for (i, o) in obs.as_slice().iter().enumerate() {
            c.pos[i] = o.pos;
            c.r[i] = o.z - model.p0;
            c.w[i] = o.weight;
        }
        c
    }

    /// `Σ wᵢ (zᵢ − p(dᵢ))²` at `p` (without the constant part); NaN becomes +∞ so that it never
    /// wins a comparison.
    fn at(&self, p: Point) -> f64 {
        let mut s = 0.0;
        for i in 0..self.n {
            let (dx, dy) = (p.x - self.pos[i].x, p.y - self.pos[i].y);
            let d2 = (dx * dx + dy * dy).max(MIN_DISTANCE * MIN_DISTANCE);
            let e = self.r[i] + self.k * libm::log10(d2);
            s += self.w[i] * e * e;
        }
        if s.is_nan() {
            f64::INFINITY
        } else {
            s
        }
    }
}

/// The cost `C(p)` of `obs` under `model` (including [`Observations::const_cost`]).
pub fn cost(obs: &Observations, model: PathLoss, p: Point) -> f64 {
    Cost::new(obs, model).at(p) + obs.const_cost
}

/// Result of a lattice search: the winning fine indices, its cost, evaluations spent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LatticeMin {
    /// Fine index in x.
    pub i: usize,
    /// Fine index in y.
    pub j: usize,
    /// Cost there.
    pub cost: f64,
    /// Cost evaluations spent.
    pub evaluations: usize,
}

/// Runs `search` over the fine lattice with `cost(i, j)` (fine indices); NaN costs never win.
///
/// Exposed so a host driver can evaluate the cost from precomputed tables; [`mle`] is this with the
/// model's cost.
pub fn search_lattice<F: FnMut(usize, usize) -> f64>(search: Search, mut cost: F) -> LatticeMin {
    let mut evals = 0;
    let mut eval = |i: usize, j: usize| {
        evals += 1;
        cost(i, j)
    };
    let mut best = LatticeMin {
        i: 0,
        j: 0,
        cost: f64::INFINITY,
        evaluations: 0,
    };
    match search {
        Search::Exhaustive => {
            for i in 0..=FINE_DIVS {
                for j in 0..=FINE_DIVS {
                    best.offer(i, j, eval(i, j));
                }
            }
        }
        Search::Thesis => {
            for ci in 0..=COARSE_DIVS {
                for cj in 0..=COARSE_DIVS {
                    best.offer(ci * RATIO, cj * RATIO, eval(ci * RATIO, cj * RATIO));
                }
            }
            let mut fine = best;
            Window::around(best.i, best.j, RATIO).scan(|i, j| fine.offer(i, j, eval(i, j)));
            best = fine;
        }
        Search::MultiStart => {
            // The best STARTS coarse points, ranked (ties: scan order).
            let mut top = [best; STARTS];
            for ci in 0..=COARSE_DIVS {
                for cj in 0..=COARSE_DIVS {
                    let (i, j) = (ci * RATIO, cj * RATIO);
                    let c = eval(i, j);
                    if let Some(k) = top.iter().position(|t| c < t.cost) {
                        top.copy_within(k..STARTS - 1, k + 1);
                        top[k] = LatticeMin {
                            i,
                            j,
                            cost: c,
                            ..best
                        };
                    }
                }
            }
            best = top[0];
            let mut spent = (COARSE_DIVS + 1) * (COARSE_DIVS + 1);
            for start in top.iter().filter(|t| t.cost < f64::INFINITY) {
                let end = descend(*start, &mut spent, &mut eval);
                best.offer(end.i, end.j, end.cost);
            }
        }
    }
    best.evaluations = evals;
    best
}

/// Coarse starting points of [`Search::MultiStart`].
const STARTS: usize = 4;
/// Most cost evaluations [`Search::MultiStart`] may spend: the thesis search's worst case.
const BUDGET: usize = (COARSE_DIVS + 1) * (COARSE_DIVS + 1) + (2 * RATIO + 1) * (2 * RATIO + 1);

/// Steepest descent over the 8 fine-lattice neighbours from `from` until no neighbour is strictly
/// better or `spent` reaches [`BUDGET`]. After a move from `p` to `q`, the points of `p`'s 3 × 3
/// block all cost at least `q` (q was their minimum, the rest were ≥ p > q), so only `q`'s
/// neighbours outside that block are evaluated: 3 after a straight move, 5 after a diagonal one.
fn descend<F: FnMut(usize, usize) -> f64>(
    from: LatticeMin,
    spent: &mut usize,
    eval: &mut F,
) -> LatticeMin {
    let mut cur = from;
    let mut prev: Option<(usize, usize)> = None;
    loop {
        let mut next = cur;
        for i in cur.i.saturating_sub(1)..=(cur.i + 1).min(FINE_DIVS) {
            for j in cur.j.saturating_sub(1)..=(cur.j + 1).min(FINE_DIVS) {
                let known = (i, j) == (cur.i, cur.j)
                    || prev.is_some_and(|(pi, pj)| pi.abs_diff(i) <= 1 && pj.abs_diff(j) <= 1);
                if known {
                    continue;
                }
                if *spent >= BUDGET {
                    return next;
                }
                *spent += 1;
                next.offer(i, j, eval(i, j));
            }
        }
        if next.cost < cur.cost {
            prev = Some((cur.i, cur.j));
            cur = next;
        } else {
            return cur;
        }
    }
}

impl LatticeMin {
    /// Takes `(i, j)` if `c` is strictly smaller (so ties keep the earlier point, NaN never wins).
    fn offer(&mut self, i: usize, j: usize, c: f64) {
        if c < self.cost {
            *self = LatticeMin {
                i,
                j,
                cost: c,
                ..*self
            };
        }
    }
}

/// A rectangle of fine indices, clipped to the lattice.
#[derive(Clone, Copy)]
struct Window {
    i0: usize,
    i1: usize,
    j0: usize,
    j1: usize,
}

impl Window {
    fn around(i: usize, j: usize, half: usize) -> Window {
        Window {
            i0: i.saturating_sub(half),
            i1: (i + half).min(FINE_DIVS),
            j0: j.saturating_sub(half),
            j1: (j + half).min(FINE_DIVS),
        }
    }

    fn scan(&self, mut f: impl FnMut(usize, usize)) {
        for i in self.i0..=self.i1 {
            for j in self.j0..=self.j1 {
                f(i, j);
            }
        }
    }
}

/// Streaming posterior-mean accumulator: weights `exp(−(c − c_min)·inv)` relative to the running
/// minimum cost, rescaled when a new minimum appears, so every weight is in `[0, 1]` and the
/// weight sum is `≥ 1` once a finite cost has been seen.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PosteriorAcc {
    inv: f64,
    min: f64,
    s: f64,
    sx: f64,
    sy: f64,
}

impl PosteriorAcc {
    /// For shadowing `sigma`: `inv = 1/(2σ²)`, ∞ for σ = 0 or NaN (the σ → 0 limit).
    pub(crate) fn new(sigma: f64) -> PosteriorAcc {
        let inv = 1.0 / (2.0 * sigma * sigma);
        PosteriorAcc {
            inv: if inv.is_nan() { f64::INFINITY } else { inv },
            min: f64::INFINITY,
            s: 0.0,
            sx: 0.0,
            sy: 0.0,
        }
    }

    /// `exp(−excess·inv)` for `excess ≥ 0`, with `0·∞` read as weight 1 (an equal minimum).
    fn weight(&self, excess: f64) -> f64 {
        if excess <= 0.0 {
            1.0
        } else {
            libm::exp(-excess * self.inv)
        }
    }

    pub(crate) fn add(&mut self, c: f64, x: f64, y: f64) {
        if !c.is_finite() {
            return; // ±∞ or NaN: zero weight
        }
        if c < self.min {
            let scale = if self.min == f64::INFINITY {
                0.0
            } else {
                self.weight(self.min - c)
            };
            self.s = self.s * scale + 1.0;
            self.sx = self.sx * scale + x;
            self.sy = self.sy * scale + y;
            self.min = c;
        } else {
            let w = self.weight(c - self.min);
            self.s += w;
            self.sx += w * x;
            self.sy += w * y;
        }
    }

    /// `(mean x, mean y, min cost)`, `None` if no finite cost was added.
    pub(crate) fn mean(&self) -> Option<(f64, f64, f64)> {
        (self.s >= 1.0).then(|| (self.sx / self.s, self.sy / self.s, self.min))
    }
}

/// The posterior mean over the fine lattice with `cost(i, j)`: returns fractional fine indices
/// `(i, j)` and the minimum cost; the area's corner `(0, 0)` with cost +∞ if no cost was finite.
pub fn posterior_mean_lattice<F: FnMut(usize, usize) -> f64>(
    sigma: f64,
    mut cost: F,
) -> (f64, f64, f64) {
    let mut acc = PosteriorAcc::new(sigma);
    for i in 0..=FINE_DIVS {
        for j in 0..=FINE_DIVS {
            acc.add(cost(i, j), i as f64, j as f64);
        }
    }
    acc.mean().unwrap_or((0.0, 0.0, f64::INFINITY))
}

/// A posterior mean over part of the lattice ([`posterior_mean_window`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindowMean {
    /// The mean's fractional fine index in x.
    pub i: f64,
    /// The mean's fractional fine index in y.
    pub j: f64,
    /// The window's smallest-cost point (ties: the coarse winner, then the first in scan order,
    /// which makes it [`Search::Thesis`]' result) and the cost evaluations spent in all.
    pub min: LatticeMin,
}

/// The windowed posterior mean with `cost(i, j)` (fine indices; see the module docs): the thesis'
/// coarse stage (11 × 11, `i` outer, strict `<`), then weights `exp(−(C − C_min)/(2σ²))` over the
/// fine points within ± one coarse step (± 5 fine steps) of the coarse winner, clipped to the
/// lattice, in scan order (one pass with a running minimum, as [`posterior_mean_lattice`]). The
/// coarse points inside the window are not evaluated again: their coarse costs are kept (so at
/// most 121 + 121 − 9 evaluations). If no cost in the window is finite the mean is the coarse
/// winner (the lattice corner `(0, 0)` when no coarse cost was finite either).
///
/// Exposed so a host driver can evaluate the cost from precomputed tables; [`mmse_window`] is this
/// with the model's cost.
pub fn posterior_mean_window<F: FnMut(usize, usize) -> f64>(sigma: f64, mut cost: F) -> WindowMean {
    let mut evals = 0;
    let mut coarse = [[f64::INFINITY; COARSE_DIVS + 1]; COARSE_DIVS + 1];
    let mut best = LatticeMin {
        i: 0,
        j: 0,
        cost: f64::INFINITY,
        evaluations: 0,
    };
    for (ci, row) in coarse.iter_mut().enumerate() {
        for (cj, kept) in row.iter_mut().enumerate() {
            let (i, j) = (ci * RATIO, cj * RATIO);
            let c = cost(i, j);
            evals += 1;
            *kept = c;
            best.offer(i, j, c);
        }
    }
    // Starting from the coarse winner, a strict `<` gives ties to it: the thesis' fine winner.
    let mut min = best;
    let mut acc = PosteriorAcc::new(sigma);
    Window::around(best.i, best.j, RATIO).scan(|i, j| {
        let c = if i % RATIO == 0 && j % RATIO == 0 {
            coarse[i / RATIO][j / RATIO]
        } else {
            evals += 1;
            cost(i, j)
        };
        min.offer(i, j, c);
        acc.add(c, i as f64, j as f64);
    });
    min.evaluations = evals;
    let (i, j) = acc
        .mean()
        .map_or((best.i as f64, best.j as f64), |(x, y, _)| (x, y));
    WindowMean { i, j, min }
}

/// The point of `area` at fractional fine indices `(fi, fj)` (a convex combination of lattice
/// points: the clamp only absorbs rounding).
fn fractional_point(area: Area, fi: f64, fj: f64) -> Point {
    let (w, h) = (side(area.width), side(area.height));
    let n = FINE_DIVS as f64;
    Point::new((w * fi / n).max(0.0).min(w), (h * fj / n).max(0.0).min(h))
}

fn check(obs: &Observations) -> Result<(), LocError> {
    if obs.len() < 3 {
        Err(LocError::TooFewAnchors { usable: obs.len() })
    } else {
        Ok(())
    }
}

/// Maximum-likelihood position of `obs` under `model` within `area`, by `search`.
pub fn mle(
    obs: &Observations,
    model: PathLoss,
    area: Area,
    search: Search,
) -> Result<Estimate, LocError> {
    check(obs)?;
    let c = Cost::new(obs, model);
    let m = search_lattice(search, |i, j| c.at(lattice_point(area, i, j)));
    Ok(Estimate {
        pos: lattice_point(area, m.i, m.j),
        min_cost: m.cost + obs.const_cost,
        estimator: Estimator::Mle(search),
        anchors: obs.len(),
        total_weight: obs.total_weight(),
        evaluations: m.evaluations,
    })
}

/// Posterior-mean position of `obs` under `model` within `area` with shadowing `sigma` dB
/// (its sign is ignored; 0 or NaN give the σ → 0 limit, see the module docs).
pub fn mmse(
    obs: &Observations,
    model: PathLoss,
    area: Area,
    sigma: f64,
) -> Result<Estimate, LocError> {
    check(obs)?;
    let c = Cost::new(obs, model);
    let (fi, fj, min) = posterior_mean_lattice(sigma, |i, j| c.at(lattice_point(area, i, j)));
    Ok(Estimate {
        pos: fractional_point(area, fi, fj),
        min_cost: min + obs.const_cost,
        estimator: Estimator::Mmse { sigma },
        anchors: obs.len(),
        total_weight: obs.total_weight(),
        evaluations: (FINE_DIVS + 1) * (FINE_DIVS + 1),
    })
}

/// Windowed posterior-mean position of `obs` under `model` within `area` with shadowing `sigma`
/// dB ([`posterior_mean_window`]; `sigma` as in [`mmse`]): the MMSE at the thesis search's cost,
/// the one the sink MCU runs. Its `min_cost` is the thesis MLE's.
pub fn mmse_window(
    obs: &Observations,
    model: PathLoss,
    area: Area,
    sigma: f64,
) -> Result<Estimate, LocError> {
    check(obs)?;
    let c = Cost::new(obs, model);
    let m = posterior_mean_window(sigma, |i, j| c.at(lattice_point(area, i, j)));
    Ok(Estimate {
        pos: fractional_point(area, m.i, m.j),
        min_cost: m.min.cost + obs.const_cost,
        estimator: Estimator::MmseWindow { sigma },
        anchors: obs.len(),
        total_weight: obs.total_weight(),
        evaluations: m.min.evaluations,
    })
}

/// `obs` located by `estimator`.
pub fn estimate(
    obs: &Observations,
    model: PathLoss,
    area: Area,
    estimator: Estimator,
) -> Result<Estimate, LocError> {
    match estimator {
        Estimator::Mle(search) => mle(obs, model, area, search),
        Estimator::Mmse { sigma } => mmse(obs, model, area, sigma),
        Estimator::MmseWindow { sigma } => mmse_window(obs, model, area, sigma),
    }
}

/// The agent of `m` located: channels combined by `refinement`, then `estimator`.
pub fn locate(
    m: &Measurements,
    refinement: Refinement,
    model: PathLoss,
    area: Area,
    estimator: Estimator,
) -> Result<Estimate, LocError> {
    estimate(&observations(m, refinement), model, area, estimator)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lattice_stays_in_the_area() {
        // 5.381717578189269 · 50 / 50 rounds up by an ulp.
        let area = Area::new(7.592107003864331, 5.381717578189269);
        for k in 0..=FINE_DIVS {
            assert!(area.contains(lattice_point(area, k, k)));
        }
        assert_eq!(
            lattice_point(area, FINE_DIVS, FINE_DIVS),
            Point::new(area.width, area.height)
        );
        assert_eq!(
            lattice_point(Area::new(-1.0, f64::NAN), FINE_DIVS, 7),
            Point::new(0.0, 0.0)
        );
    }

    #[test]
    fn posterior_acc_matches_direct_sum() {
        let costs = [5.0, 1.0, 3.0, 0.5, 7.0];
        let sigma = 1.3;
        let mut acc = PosteriorAcc::new(sigma);
        let (mut s, mut sx) = (0.0, 0.0);
        for (k, &c) in costs.iter().enumerate() {
            acc.add(c, k as f64, 0.0);
            let w = libm::exp(-c / (2.0 * sigma * sigma));
            s += w;
            sx += w * k as f64;
        }
        let (mx, my, min) = acc.mean().unwrap();
        assert!((mx - sx / s).abs() < 1e-12);
        assert_eq!((my, min), (0.0, 0.5));
        // σ = 0: the minimiser; ties averaged.
        let mut acc = PosteriorAcc::new(0.0);
        for (k, c) in [2.0, 1.0, 3.0, 1.0].into_iter().enumerate() {
            acc.add(c, k as f64, 0.0);
        }
        assert_eq!(acc.mean().unwrap().0, 2.0);
        // Non-finite costs carry no weight.
        let mut acc = PosteriorAcc::new(1.0);
        acc.add(f64::NAN, 9.0, 9.0);
        acc.add(f64::INFINITY, 9.0, 9.0);
        assert_eq!(acc.mean(), None);
        acc.add(1e300, 4.0, 2.0);
        assert_eq!(acc.mean(), Some((4.0, 2.0, 1e300)));
    }

    #[test]
    fn budgets() {
        let coarse = (COARSE_DIVS + 1) * (COARSE_DIVS + 1);
        let window = (2 * RATIO + 1) * (2 * RATIO + 1);
        let flat = |_: usize, _: usize| 1.0;
        // Flat: the first point wins, its window is clipped at the corner.
        let m = search_lattice(Search::Thesis, flat);
        assert_eq!(
            (m.i, m.j, m.evaluations),
            (0, 0, coarse + (RATIO + 1) * (RATIO + 1))
        );
        // A coarse point inside: the whole window.
        let c = RATIO * (COARSE_DIVS / 2);
        let inner = |i: usize, j: usize| if (i, j) == (c, c) { 0.0 } else { 1.0 };
        assert_eq!(
            search_lattice(Search::Thesis, inner).evaluations,
            coarse + window
        );
        assert_eq!(
            search_lattice(Search::Exhaustive, flat).evaluations,
            (FINE_DIVS + 1) * (FINE_DIVS + 1)
        );
        // The scenarios below are drawn on the thesis' lattice.
        assert_eq!(
            (FINE_DIVS, COARSE_DIVS),
            (50, 10),
            "scenarios for the thesis' lattice"
        );
        // Multi-start never exceeds the thesis' worst case, even on a cost that descends forever.
        let bowl = |i: usize, j: usize| {
            let (x, y) = (i as f64 - 50.0, j as f64 - 50.0);
            x * x + y * y
        };
        let m = search_lattice(Search::MultiStart, bowl);
        assert_eq!((m.i, m.j), (50, 50));
        assert!(m.evaluations > 121 && m.evaluations <= 242, "{m:?}");
        let slope = |i: usize, j: usize| -((i * 7 + j * 3) as f64);
        let m = search_lattice(Search::MultiStart, slope);
        assert!(m.evaluations <= 242, "{m:?}");
        // Descent from the coarse winner (25, 25) to the minimum at (27, 23).
        let tilt = |i: usize, j: usize| {
            let (x, y) = (i as f64 - 27.0, j as f64 - 23.0);
            x * x + y * y
        };
        let m = search_lattice(Search::MultiStart, tilt);
        assert_eq!((m.i, m.j, m.cost), (27, 23, 0.0));
        // 121 coarse + 8 around (25, 25) + 5 after the diagonal move to (26, 24) + 5 after the
        // one to (27, 23), where it stops; then the other three starts, each ≤ 242 in total.
        assert!(m.evaluations > 121 + 18 && m.evaluations <= 242, "{m:?}");
    }

    #[test]
    fn multi_start_finds_a_minimum_the_thesis_misses() {
        assert_eq!(
            (FINE_DIVS, COARSE_DIVS),
            (50, 10),
            "a scenario for the thesis' lattice"
        );
        // Coarse winner (25, 25) sits in a shallow bowl; the global minimum is a basin around
        // (44, 44), four coarse cells from the winner, whose coarse point (45, 45) ranks second.
        let f = |i: usize, j: usize| {
            let (x, y) = (i as f64 - 44.0, j as f64 - 44.0);
            let basin = 0.6 * (x * x + y * y) - 1.0;
            let bowl = if (i, j) == (25, 25) { 0.0 } else { 1.0 };
            basin.min(bowl)
        };
        let t = search_lattice(Search::Thesis, f);
        let ms = search_lattice(Search::MultiStart, f);
        let ex = search_lattice(Search::Exhaustive, f);
        assert_eq!((t.i, t.j, t.cost), (25, 25, 0.0));
        assert_eq!((ms.i, ms.j, ms.cost), (44, 44, -1.0));
        assert_eq!((ex.i, ex.j, ex.cost), (44, 44, -1.0));
    }
}
