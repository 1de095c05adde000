//! The same estimate in plain `f32`: a straightforward port of loc-core's f64 reference
//! ([`loc_core::params`] with [`FitMethod::LeastSquares`](loc_core::params::FitMethod), AR(1),
//! [`loc_core::refine`]'s Extended refinement, [`loc_core::grid`]'s thesis search and windowed
//! MMSE), the yardstick the fixed path must beat by ≥ 25× (`docs/design.md`, section 6).
//!
//! On the AVR, `log10`, `exp` and `sqrt` are avr-libc's (`uno_board::libm`); on the host, std's.
//! It does what the reference does, with three exact economies the fixed path also makes, so the
//! comparison is with a sensible f32 program and not a strawman: one `log10` per anchor pair (not
//! per sample), `log10(d²)` instead of a square root per distance, and the fine window skips the
//! coarse points it contains (under the strict `<` they cannot win).
//!
//! The windowed MMSE ([`loc_core::grid::mmse_window`]): after the coarse stage picks `(ic, jc)`,
//! the posterior mean over the fine indices `[ic − 5, ic + 5] × [jc − 5, jc + 5]` (clipped to the
//! lattice), weights `exp(−(C − C_min)/(2σ²))`, accumulated in one pass relative to the running
//! minimum as the reference does; the coarse points' costs come from the coarse stage.

use crate::{Inputs, Pipeline, Report, N_ANCHORS, N_CHANNELS, SIGMA_DB};

#[cfg(target_arch = "avr")]
use uno_board::libm::{expf, log10f, sqrtf};

#[cfg(not(target_arch = "avr"))]
fn log10f(x: f32) -> f32 {
    x.log10()
}
#[cfg(not(target_arch = "avr"))]
fn expf(x: f32) -> f32 {
    x.exp()
}
#[cfg(not(target_arch = "avr"))]
fn sqrtf(x: f32) -> f32 {
    x.sqrt()
}

/// Coarse divisions per side (the thesis' 10 % steps): loc-core's lattice.
use loc_core::grid::COARSE_DIVS;
/// Fine divisions per side (the thesis' 2 % steps): loc-core's lattice.
use loc_core::grid::FINE_DIVS;
const RATIO: usize = FINE_DIVS / COARSE_DIVS;
/// The model's smallest distance (1 cm), squared, m².
const MIN_D2: f32 = 1e-4;

/// The log-normal model: P0 dBm at 1 m, exponent α.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Model {
    /// dBm.
    pub p0: f32,
    /// α.
    pub alpha: f32,
}

/// The thesis' prior.
pub const THESIS: Model = Model {
    p0: -40.0,
    alpha: 3.0,
};

/// The thesis' bounds: α ∈ [2, 5], P0 ∈ [−60, −20] dBm.
const ALPHA_BOUNDS: (f32, f32) = (2.0, 5.0);
const P0_BOUNDS: (f32, f32) = (-60.0, -20.0);

fn clamp(v: f32, (lo, hi): (f32, f32)) -> f32 {
    v.max(lo).min(hi)
}

/// Calibration samples `(x = −10·log10 d, z)`, Welford-accumulated as the reference does.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CalStats {
    n: u16,
    x_mean: f32,
    z_mean: f32,
    sxx: f32,
    sxz: f32,
    szz: f32,
}

impl CalStats {
    fn push(&mut self, x: f32, z: f32) {
        self.n += 1;
        let inv_n = 1.0 / self.n as f32;
        let dx = x - self.x_mean;
        let dz = z - self.z_mean;
        self.x_mean += dx * inv_n;
        self.z_mean += dz * inv_n;
        self.sxx += dx * (x - self.x_mean);
        self.sxz += dx * (z - self.z_mean);
        self.szz += dz * (z - self.z_mean);
    }

    fn sse(&self, m: Model) -> f32 {
        let off = self.z_mean - m.p0 - m.alpha * self.x_mean;
        (self.szz - 2.0 * m.alpha * self.sxz
            + m.alpha * m.alpha * self.sxx
            + self.n as f32 * off * off)
            .max(0.0)
    }

    fn p0_for(&self, alpha: f32) -> f32 {
        self.z_mean - alpha * self.x_mean
    }

    fn alpha_for(&self, p0: f32) -> Option<f32> {
        let n = self.n as f32;
        let den = self.sxx + n * self.x_mean * self.x_mean;
        (den > 0.0).then(|| (self.sxz + n * self.x_mean * (self.z_mean - p0)) / den)
    }
}

/// A fit: the model, its residual sum and σ (unused by the estimate, computed as the reference's
/// `ParamFit` and the fixed path do).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fit {
    /// Fitted model.
    pub model: Model,
    /// Σ residual², dB².
    pub sse: f32,
    /// σ estimate, dB.
    pub sigma: Option<f32>,
}

/// `params::fit` with `ParamMode::P0AndAlpha`, `FitMethod::LeastSquares`, the thesis' bounds.
fn fit(stats: &CalStats, prior: Model) -> Option<Fit> {
    if stats.n == 0 {
        return None;
    }
    let (model, fitted) = if stats.sxx > 1e-9 * stats.n as f32 {
        (box_least_squares(stats), 2)
    } else {
        // α not identifiable: the prior's (clamped), P0 fitted.
        let alpha = clamp(prior.alpha, ALPHA_BOUNDS);
        let p0 = clamp(stats.p0_for(alpha), P0_BOUNDS);
        (Model { p0, alpha }, 1)
    };
    let sse = stats.sse(model);
    let sigma = (stats.n > fitted).then(|| sqrtf(sse / (stats.n - fitted) as f32));
    Some(Fit { model, sse, sigma })
}

/// The exact least-squares optimum on the bounds box: the free optimum if inside, else the best
/// of the four edges' optima.
fn box_least_squares(s: &CalStats) -> Model {
    let alpha = s.sxz / s.sxx;
    let p0 = s.p0_for(alpha);
    let inside = |v: f32, (lo, hi): (f32, f32)| lo <= v && v <= hi;
    if inside(alpha, ALPHA_BOUNDS) && inside(p0, P0_BOUNDS) {
        return Model { p0, alpha };
    }
    let on_alpha_edge = |alpha: f32| Model {
        p0: clamp(s.p0_for(alpha), P0_BOUNDS),
        alpha,
    };
    let on_p0_edge = |p0: f32| Model {
        p0,
        alpha: clamp(s.alpha_for(p0).unwrap_or(ALPHA_BOUNDS.0), ALPHA_BOUNDS),
    };
    let candidates = [
        on_alpha_edge(ALPHA_BOUNDS.0),
        on_alpha_edge(ALPHA_BOUNDS.1),
        on_p0_edge(P0_BOUNDS.0),
        on_p0_edge(P0_BOUNDS.1),
    ];
    let mut best = candidates[0];
    for c in &candidates[1..] {
        if s.sse(*c) < s.sse(best) {
            best = *c;
        }
    }
    best
}

/// `y[n] = 0.8·y[n−1] + 0.2·x[n]`, `y[0] = x[0]`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Ar1 {
    y: Option<f32>,
}

impl Ar1 {
    fn update(&mut self, x: f32) {
        self.y = Some(match self.y {
            Some(prev) => 0.8 * prev + 0.2 * x,
            None => x,
        });
    }
}

/// One anchor's refined observation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Obs {
    /// Anchor position, m.
    pub x: f32,
    /// Anchor position, m.
    pub y: f32,
    /// dB mean of its channels, dBm.
    pub z: f32,
    /// Channel count.
    pub w: f32,
}

/// The observations and the cost's position-independent part, dB².
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Observations {
    /// One per usable anchor (first `n`).
    pub obs: [Obs; N_ANCHORS],
    /// Usable anchors.
    pub n: usize,
    /// `Σ_anchors Σ_c (z_c − z̄)²`.
    pub const_cost: f32,
}

/// The cost `Σ w (z − P0 + 5α·log10 d²)²` with the per-anchor constants hoisted.
struct Cost {
    ax: [f32; N_ANCHORS],
    ay: [f32; N_ANCHORS],
    r: [f32; N_ANCHORS],
    w: [f32; N_ANCHORS],
    n: usize,
    k: f32,
    /// Fine lattice steps, m.
    step_x: f32,
    step_y: f32,
}

impl Cost {
    fn new(o: &Observations, m: Model, inp: &Inputs) -> Cost {
        let mut c = Cost {
            ax: [0.0; N_ANCHORS],
            ay: [0.0; N_ANCHORS],
            r: [0.0; N_ANCHORS],
            w: [0.0; N_ANCHORS],
            n: o.n,
            k: 5.0 * m.alpha,
            step_x: inp.area[0] as f32 * 0.01 / FINE_DIVS as f32,
            step_y: inp.area[1] as f32 * 0.01 / FINE_DIVS as f32,
        };
        for (a, ob) in o.obs[..o.n].iter().enumerate() {
            c.ax[a] = ob.x;
            c.ay[a] = ob.y;
            c.r[a] = ob.z - m.p0;
            c.w[a] = ob.w;
        }
        c
    }

    /// Cost at fine lattice point `(i, j)`; NaN becomes +∞ so that it never wins.
    fn at(&self, i: usize, j: usize) -> f32 {
        let (px, py) = (self.step_x * i as f32, self.step_y * j as f32);
        let mut s = 0.0;
        for a in 0..self.n {
            let (dx, dy) = (px - self.ax[a], py - self.ay[a]);
            let d2 = (dx * dx + dy * dy).max(MIN_D2);
            let e = self.r[a] + self.k * log10f(d2);
            s += self.w[a] * e * e;
        }
        if s.is_nan() {
            f32::INFINITY
        } else {
            s
        }
    }

    /// The thesis' coarse stage (11 × 11, `i` outer, strict `<`): the winner's fine indices and
    /// cost; `keep` sees every coarse cost.
    fn coarse(&self, mut keep: impl FnMut(usize, usize, f32)) -> (usize, usize, f32) {
        let mut best = (0, 0, f32::INFINITY);
        for ci in 0..=COARSE_DIVS {
            for cj in 0..=COARSE_DIVS {
                let (i, j) = (ci * RATIO, cj * RATIO);
                let c = self.at(i, j);
                keep(ci, cj, c);
                if c < best.2 {
                    best = (i, j, c);
                }
            }
        }
        best
    }
}

/// The fine window `[c − 5, c + 5]` clipped to the lattice.
fn window(c: usize) -> core::ops::RangeInclusive<usize> {
    c.saturating_sub(RATIO)..=(c + RATIO).min(FINE_DIVS)
}

/// The f32 pipeline.
///
/// Its [`Report`]: the `f32::to_bits` of the position's x and y in metres, of P0 (dBm) and of α;
/// all `u32::MAX` with fewer than 3 usable anchors.
#[derive(Clone, Copy, Debug, Default)]
pub struct F32 {
    p0: Ar1,
    alpha: Ar1,
}

impl F32 {
    /// Fresh state: the thesis' prior, no fit yet.
    pub fn new() -> F32 {
        F32::default()
    }

    /// The smoothed model (the prior before the first fit).
    pub fn current(&self) -> Model {
        Model {
            p0: self.p0.y.unwrap_or(THESIS.p0),
            alpha: self.alpha.y.unwrap_or(THESIS.alpha),
        }
    }

    fn report(&self, pos: Option<(f32, f32)>) -> Report {
        let m = self.current();
        match pos {
            Some((x, y)) => Report {
                x: x.to_bits(),
                y: y.to_bits(),
                p0: m.p0.to_bits(),
                alpha: m.alpha.to_bits(),
            },
            None => Report {
                x: u32::MAX,
                y: u32::MAX,
                p0: u32::MAX,
                alpha: u32::MAX,
            },
        }
    }
}

impl Pipeline for F32 {
    type Stats = CalStats;
    type Obs = Observations;

    fn calibrate(&mut self, inp: &Inputs) -> CalStats {
        let mut s = CalStats::default();
        for i in 0..N_ANCHORS {
            for j in i + 1..N_ANCHORS {
                let [xi, yi] = inp.anchors[i];
                let [xj, yj] = inp.anchors[j];
                let dx = (xi as f32 - xj as f32) * 0.01;
                let dy = (yi as f32 - yj as f32) * 0.01;
                let d2 = dx * dx + dy * dy;
                if d2 < MIN_D2 {
                    continue; // coincident anchors
                }
                let x = -5.0 * log10f(d2);
                for c in 0..N_CHANNELS {
                    s.push(x, -(inp.a2a_byte(i, j, c) as f32));
                }
                for c in 0..N_CHANNELS {
                    s.push(x, -(inp.a2a_byte(j, i, c) as f32));
                }
            }
        }
        s
    }

    fn fit(&mut self, stats: &CalStats) {
        if let Some(f) = fit(stats, self.current()) {
            self.p0.update(f.model.p0);
            self.alpha.update(f.model.alpha);
        }
    }

    fn refine(&mut self, inp: &Inputs) -> Observations {
        let mut o = Observations::default();
        for (a, bytes) in inp.agent.iter().enumerate() {
            let mut sum = 0.0;
            for &b in bytes {
                sum += -(b as f32);
            }
            let z = sum / N_CHANNELS as f32;
            for &b in bytes {
                let d = -(b as f32) - z;
                o.const_cost += d * d;
            }
            let [x, y] = inp.anchors[a];
            o.obs[o.n] = Obs {
                x: x as f32 * 0.01,
                y: y as f32 * 0.01,
                z,
                w: N_CHANNELS as f32,
            };
            o.n += 1;
        }
        o
    }

    fn mle(&mut self, obs: &Observations, inp: &Inputs) -> Report {
        if obs.n < 3 {
            return self.report(None);
        }
        let cost = Cost::new(obs, self.current(), inp);
        let (ci, cj, cc) = cost.coarse(|_, _, _| {});
        let mut best = (ci, cj, cc);
        for i in window(ci) {
            for j in window(cj) {
                if i % RATIO == 0 && j % RATIO == 0 {
                    continue; // a coarse point: it cost at least the coarse winner's
                }
                let c = cost.at(i, j);
                if c < best.2 {
                    best = (i, j, c);
                }
            }
        }
        let pos = (cost.step_x * best.0 as f32, cost.step_y * best.1 as f32);
        self.report(Some(pos))
    }

    fn mmse(&mut self, obs: &Observations, inp: &Inputs) -> Report {
        if obs.n < 3 {
            return self.report(None);
        }
        let cost = Cost::new(obs, self.current(), inp);
        let mut coarse = [[0.0f32; COARSE_DIVS + 1]; COARSE_DIVS + 1];
        let (ci, cj, _) = cost.coarse(|a, b, c| coarse[a][b] = c);
        let mut acc = Posterior::new(SIGMA_DB as f32);
        for i in window(ci) {
            for j in window(cj) {
                let c = if i % RATIO == 0 && j % RATIO == 0 {
                    coarse[i / RATIO][j / RATIO]
                } else {
                    cost.at(i, j)
                };
                acc.add(c, i as f32, j as f32);
            }
        }
        let (fi, fj) = acc.mean().unwrap_or((ci as f32, cj as f32));
        self.report(Some((cost.step_x * fi, cost.step_y * fj)))
    }
}

/// Streaming posterior mean: weights `exp(−(c − c_min)/(2σ²))` relative to the running minimum,
/// rescaled when a new minimum appears (the reference's accumulator).
struct Posterior {
    inv: f32,
    min: f32,
    s: f32,
    sx: f32,
    sy: f32,
}

impl Posterior {
    fn new(sigma: f32) -> Posterior {
        Posterior {
            inv: 1.0 / (2.0 * sigma * sigma),
            min: f32::INFINITY,
            s: 0.0,
            sx: 0.0,
            sy: 0.0,
        }
    }

    fn weight(&self, excess: f32) -> f32 {
        if excess <= 0.0 {
            1.0
        } else {
            expf(-excess * self.inv)
        }
    }

    fn add(&mut self, c: f32, x: f32, y: f32) {
        if !c.is_finite() {
            return;
        }
        if c < self.min {
            let scale = if self.min == f32::INFINITY {
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

    fn mean(&self) -> Option<(f32, f32)> {
        (self.s >= 1.0).then(|| (self.sx / self.s, self.sy / self.s))
    }
}
