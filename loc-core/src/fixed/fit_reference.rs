//! Test reference: the fixed-point fit written plainly (`i64` sums, `u64` divisions), so that
//! `params::tests` can assert that every public result of the MCU-shaped fit in `params.rs` is
//! bit-identical to it.

use crate::fixed::{Bounds, PathLoss, PointCm, ALPHA_LIMIT, P0_LIMIT};
use crate::params::{FitMethod, ParamMode};
use crate::LocError;

pub const MAX_SAMPLES: u16 = 256;
const FIVE_LOG10_2_Q30: i64 = 1_616_142_483;
const LOG2_M2_IN_CM2: i64 = 13933176;

fn clamp_i32(v: i32, lo: i32, hi: i32) -> i32 {
    v.max(lo).min(hi)
}

fn clamp_i64(v: i64, lo: i64, hi: i64) -> i64 {
    v.max(lo).min(hi)
}

fn mul_shr(a: i64, b: i64, s: u32) -> i64 {
    let p = a * b;
    (p + (1 << (s - 1))) >> s
}

fn square(v: i32) -> u64 {
    let a = v.unsigned_abs() as u64;
    a * a
}

fn isqrt_u32(x: u32) -> u32 {
    let mut r = (x as f64).sqrt() as u32;
    while r as u64 * r as u64 > x as u64 {
        r -= 1;
    }
    while (r as u64 + 1) * (r as u64 + 1) <= x as u64 {
        r += 1;
    }
    r
}

/// The log2 of the reference: the MCU fit's own table evaluation, so the comparison tests the
/// sums and divisions around it.
fn log2_u33(lo: u32, carry: bool) -> i32 {
    crate::fixed::math::log2_fast(lo, carry)
}

pub fn distance_x(a: PointCm, b: PointCm) -> Option<i32> {
    let dx2 = square(a.x as i32 - b.x as i32) as u32;
    let (lo, carry) = dx2.overflowing_add(square(a.y as i32 - b.y as i32) as u32);
    if lo == 0 && !carry {
        return None;
    }
    let l = log2_u33(lo, carry) as i64 - LOG2_M2_IN_CM2;
    Some(-mul_shr(FIVE_LOG10_2_Q30, l, 32) as i32)
}

fn sorted(a: i32, b: i32, limit: i32) -> (i32, i32) {
    let (a, b) = (clamp_i32(a, -limit, limit), clamp_i32(b, -limit, limit));
    (a.min(b), a.max(b))
}

fn bounds_alpha(b: &Bounds) -> (i32, i32) {
    sorted(b.alpha_min, b.alpha_max, ALPHA_LIMIT)
}

fn bounds_p0(b: &Bounds) -> (i32, i32) {
    sorted(b.p0_min, b.p0_max, P0_LIMIT)
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CalStats {
    n: u16,
    sx: i64,
    sz: i64,
    sxx: i64,
    sxz: i64,
    szz: i64,
}

impl CalStats {
    pub fn push_at(&mut self, x: i32, bytes: &[Option<u8>]) -> usize {
        let x = clamp_i32(x, -(32 << 18), 32 << 18);
        let (mut k, mut s, mut s2) = (0u16, 0i32, 0i32);
        for &b in bytes.iter().flatten() {
            if self.n + k >= MAX_SAMPLES {
                break;
            }
            let z = -(b as i32);
            k += 1;
            s += z;
            s2 += z * z;
        }
        self.n += k;
        let x2 = square(x) as i64;
        for _ in 0..k {
            self.sx += x as i64;
            self.sxx += x2;
        }
        self.sz += s as i64;
        self.sxz += x as i64 * s as i64;
        self.szz += s2 as i64;
        k as usize
    }

    pub fn push_pair(&mut self, a: PointCm, b: PointCm, bytes: &[Option<u8>]) -> usize {
        match distance_x(a, b) {
            Some(x) => self.push_at(x, bytes),
            None => 0,
        }
    }

    pub fn len(&self) -> usize {
        self.n as usize
    }

    pub fn sse(&self, model: PathLoss) -> u64 {
        let m = model.sane();
        self.sse_at(m.p0, m.alpha)
    }

    fn sse_at(&self, p0: i32, alpha: i32) -> u64 {
        let (p, a) = (p0 as i64, (alpha as i64 + 128) >> 8);
        let n = self.n as i64;
        let p_sx = (p * self.sx) >> 18;
        let a_sxx = (a * (self.sxx >> 20)) >> 16;
        let q32 = (self.szz << 32) - ((p * self.sz) << 17) - ((a * self.sxz) >> 1)
            + n * p * p
            + 2 * p_sx * a
            + a_sxx * a;
        (q32.max(0) >> 16) as u64
    }

    fn dxx(&self) -> i64 {
        self.n as i64 * self.sxx - self.sx * self.sx
    }

    fn alpha_identifiable(&self) -> bool {
        let n = self.n as i64;
        self.dxx() > ((n * n) << 36) / 1_000_000_000
    }

    fn p0_for(&self, alpha: i32) -> i64 {
        let num = (self.sz << 16) - ((alpha as i64 * self.sx + (1 << 25)) >> 26);
        div_q(num, (self.n as i64).max(1), 0)
    }

    fn alpha_for(&self, p0: i32) -> Option<i64> {
        let num = self.sxz - ((p0 as i64 * self.sx) >> 16);
        (self.sxx > 0).then(|| div_q(num, self.sxx, 42))
    }
}

fn div_q(num: i64, den: i64, q: u32) -> i64 {
    const SAT: u64 = 1 << 40;
    let (n, d) = (num.unsigned_abs(), den.max(1) as u64);
    let a = q.min(n.leading_zeros().saturating_sub(2));
    let d = d >> (q - a);
    if d == 0 {
        return if num < 0 { -(SAT as i64) } else { SAT as i64 };
    }
    let v = (((n << a) + d / 2) / d).min(SAT) as i64;
    if num < 0 {
        -v
    } else {
        v
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParamFit {
    pub model: PathLoss,
    pub sse: u64,
    pub n: u16,
    pub fitted: u8,
    pub sigma: Option<u16>,
}

impl ParamFit {
    fn new(stats: &CalStats, model: PathLoss, fitted: u8) -> ParamFit {
        let sse = stats.sse(model);
        let dof = stats.n.saturating_sub(fitted as u16) as u32;
        let sigma = (dof > 0).then(|| {
            let v = sse / dof as u64;
            if v > u32::MAX as u64 {
                u16::MAX
            } else {
                isqrt_u32(v as u32).min(u16::MAX as u32) as u16
            }
        });
        ParamFit {
            model,
            sse,
            n: stats.n,
            fitted,
            sigma,
        }
    }
}

pub fn fit(
    stats: &CalStats,
    mode: ParamMode,
    method: FitMethod,
    prior: PathLoss,
    bounds: &Bounds,
) -> Result<ParamFit, LocError> {
    if let Some(r) = fit_one_or_none(stats, mode, method, prior, bounds) {
        return r;
    }
    let (a, p) = (bounds_alpha(bounds), bounds_p0(bounds));
    let model = match method {
        FitMethod::LeastSquares => box_least_squares(stats, a, p),
        FitMethod::Grid => grid_search(stats, a, p),
    };
    Ok(ParamFit::new(stats, model, 2))
}

fn grid_search(stats: &CalStats, (a_lo, a_hi): (i32, i32), (p_lo, p_hi): (i32, i32)) -> PathLoss {
    let mut best = (u64::MAX, PathLoss { p0: 0, alpha: 0 });
    for k in 0..=alpha_steps(a_lo, a_hi) {
        let alpha = alpha_grid(a_lo, a_hi, k);
        let p0 = grid_p0(stats.p0_for(alpha), p_lo, p_hi);
        let e = stats.sse_at(p0, alpha);
        if e < best.0 || k == 0 {
            best = (e, PathLoss { p0, alpha });
        }
    }
    best.1
}

fn fit_one_or_none(
    stats: &CalStats,
    mode: ParamMode,
    method: FitMethod,
    prior: PathLoss,
    bounds: &Bounds,
) -> Option<Result<ParamFit, LocError>> {
    let prior = prior.sane();
    if mode == ParamMode::Fixed {
        return Some(Ok(ParamFit::new(stats, prior, 0)));
    }
    if stats.n == 0 {
        return Some(Err(LocError::NoCalibrationData));
    }
    if mode == ParamMode::P0AndAlpha && stats.alpha_identifiable() {
        return None;
    }
    let ((a_lo, a_hi), (p_lo, p_hi)) = (bounds_alpha(bounds), bounds_p0(bounds));
    let grid = method == FitMethod::Grid;
    let alpha = match mode {
        ParamMode::P0Only => prior.alpha,
        _ if grid => grid_alpha(prior.alpha, a_lo, a_hi),
        _ => clamp_i32(prior.alpha, a_lo, a_hi),
    };
    let p0 = stats.p0_for(alpha);
    let p0 = if grid {
        grid_p0(p0, p_lo, p_hi)
    } else {
        clamp_i64(p0, p_lo as i64, p_hi as i64) as i32
    };
    Some(Ok(ParamFit::new(stats, PathLoss { p0, alpha }, 1)))
}

fn alpha_steps(lo: i32, hi: i32) -> u32 {
    (((hi as i64 - lo as i64) * 10 + 10) >> 24) as u32
}

fn alpha_grid(lo: i32, hi: i32, k: u32) -> i32 {
    let k = k.min(1000) as i64;
    (lo as i64 + k * 1_677_721 + (k * 6 + 5) / 10).min(hi as i64) as i32
}

fn grid_alpha(alpha: i32, lo: i32, hi: i32) -> i32 {
    let k = ((alpha as i64 - lo as i64) * 10 + (1 << 23)) >> 24;
    alpha_grid(lo, hi, clamp_i64(k, 0, alpha_steps(lo, hi) as i64) as u32)
}

fn grid_p0(p0: i64, lo: i32, hi: i32) -> i32 {
    let steps = (hi as i64 - lo as i64) >> 15;
    let k = clamp_i64((p0 - lo as i64 + (1 << 14)) >> 15, 0, steps);
    (lo as i64 + (k << 15)) as i32
}

fn box_least_squares(
    stats: &CalStats,
    (a_lo, a_hi): (i32, i32),
    (p_lo, p_hi): (i32, i32),
) -> PathLoss {
    let n = stats.n as i64;
    let num = n * stats.sxz - stats.sx * stats.sz;
    let alpha = div_q(num, stats.dxx(), 42);
    let alpha = clamp_i64(alpha, -(ALPHA_LIMIT as i64), ALPHA_LIMIT as i64) as i32;
    let p0 = stats.p0_for(alpha);
    if (a_lo..=a_hi).contains(&alpha) && (p_lo as i64..=p_hi as i64).contains(&p0) {
        return PathLoss {
            p0: p0 as i32,
            alpha,
        };
    }
    let mut best = PathLoss { p0: 0, alpha: 0 };
    let mut best_sse = u64::MAX;
    for edge in 0..4 {
        let c = match edge {
            0 | 1 => {
                let alpha = if edge == 0 { a_lo } else { a_hi };
                let p0 = clamp_i64(stats.p0_for(alpha), p_lo as i64, p_hi as i64) as i32;
                PathLoss { p0, alpha }
            }
            _ => {
                let p0 = if edge == 2 { p_lo } else { p_hi };
                let a = stats.alpha_for(p0).unwrap_or(a_lo as i64);
                PathLoss {
                    p0,
                    alpha: clamp_i64(a, a_lo as i64, a_hi as i64) as i32,
                }
            }
        };
        let e = stats.sse_at(c.p0, c.alpha);
        if e < best_sse {
            (best, best_sse) = (c, e);
        }
    }
    best
}

/// `Ar1::update` written plainly (one rounded `i64` sum, clamped): `(a, b, y)` → the new `y`.
pub fn ar1_update(a: i32, b: i32, y: Option<i32>, x: i32) -> i32 {
    match y {
        Some(prev) => {
            let v = (a as i64 * prev as i64 + b as i64 * x as i64 + (1 << 15)) >> 16;
            clamp_i64(v, i32::MIN as i64, i32::MAX as i64) as i32
        }
        None => x,
    }
}

/// `OnlineParams` written plainly (default smoothers), for the state comparison.
#[derive(Clone, Copy, Debug)]
pub struct OnlineParams {
    pub mode: ParamMode,
    pub method: FitMethod,
    pub bounds: Bounds,
    pub prior: PathLoss,
    pub p0: (i32, i32, Option<i32>),
    pub alpha: (i32, i32, Option<i32>),
    pub sigma: Option<u16>,
}

impl OnlineParams {
    pub fn new(
        mode: ParamMode,
        method: FitMethod,
        bounds: Bounds,
        prior: PathLoss,
        p0: (i32, i32),
        alpha: (i32, i32),
    ) -> Self {
        OnlineParams {
            mode,
            method,
            bounds,
            prior: prior.sane(),
            p0: (p0.0, p0.1, None),
            alpha: (alpha.0, alpha.1, None),
            sigma: None,
        }
    }

    pub fn current(&self) -> PathLoss {
        PathLoss {
            p0: self.p0.2.unwrap_or(self.prior.p0),
            alpha: self.alpha.2.unwrap_or(self.prior.alpha),
        }
        .sane()
    }

    pub fn update(&mut self, stats: &CalStats) -> Result<ParamFit, LocError> {
        let f = fit(stats, self.mode, self.method, self.current(), &self.bounds)?;
        let step =
            |s: &mut (i32, i32, Option<i32>), x: i32| s.2 = Some(ar1_update(s.0, s.1, s.2, x));
        match self.mode {
            ParamMode::Fixed => {}
            ParamMode::P0Only => step(&mut self.p0, f.model.p0),
            ParamMode::P0AndAlpha => {
                step(&mut self.p0, f.model.p0);
                step(&mut self.alpha, f.model.alpha);
            }
        }
        self.sigma = f.sigma.or(self.sigma);
        Ok(f)
    }
}
