//! P0/α estimation from anchor-to-anchor RSSI bytes ([`crate::params`] in fixed point).
//!
//! A calibration sample is `(x, z)` with `x = −10·log10(d / 1 m)` (Q.18, from the exact integer
//! `d²` in cm² and the log2 table: within 4·10⁻⁶ dB; near-equidistant anchors make α sensitive
//! to x, hence the extra bits) and `z` the integer dBm of the byte.
//! [`CalStats`] keeps exact integer sums (`n`, `Σx`, `Σz`, `Σx²`, `Σxz`, `Σz²`), so both fits
//! are exact rational functions of the samples: the least-squares α is one long division
//! (`(n·Σxz − Σx·Σz) / (n·Σx² − (Σx)²)`, 42 fraction bits), P0 another, and the box-constrained
//! optimum follows the reference's four-edge rule. Results: P0 Q.16 dB, α Q.24, residual sum
//! Q.16 dB², σ Q.8 dB (on demand). At most [`MAX_SAMPLES`] samples (8 anchors × 7 × 4 channels =
//! 224 fit), which keeps every product inside `i64`.
//!
//! The sums are laid out for an 8-bit MCU, where a 64-bit multiply or division is a library
//! call and a variable 64-bit shift a loop of 1-bit shifts: a pair's x takes one 64-bit
//! product, its sums only 8 × 8 and 16 × 16 ones (the byte sums in 16/32 bits, the x sums by the
//! sign of x), and an unconstrained fit divides once in 64 bits (α, with the reference's
//! rounding) and once in 32 (P0). `tests` holds every result to the same fit written with plain
//! `i64` sums and `u64` divisions (`fit_reference.rs`).

use super::math::{clamp_i32, clamp_i64, isqrt_u32, log2_q20, log2_u33, m8, sq_u16};
use super::{Measurements, PathLoss, PointCm, ALPHA, ALPHA_LIMIT, DB, P0_LIMIT};
use crate::params::{FitMethod, ParamMode};
use crate::{LocError, MAX_CHANNELS};

/// Most samples a [`CalStats`] takes.
pub const MAX_SAMPLES: u16 = 256;

/// `5·log10(2)`, Q.30.
const FIVE_LOG10_2_Q30: u32 = 1_616_142_483;
/// `log2(1 m²)` in cm², Q.20.
const LOG2_M2_IN_CM2: i32 = log2_q20(100 * 100);

/// `x = −10·log10(d / 1 m)` of the distance between `a` and `b`, Q.18; `None` for coincident
/// anchors (the reference skips distances below 1 cm, and positions are whole cm).
pub fn distance_x(a: PointCm, b: PointCm) -> Option<i32> {
    // Each square < 2^32 (|Δ| ≤ 65535): their sum is a 33-bit value.
    let (lo, carry) = sq_u16(a.x.abs_diff(b.x)).overflowing_add(sq_u16(a.y.abs_diff(b.y)));
    if lo == 0 && !carry {
        return None;
    }
    // −5·log10(d²/1 m²) = −5·log10(2)·(log2 d² − log2 1 m²): Q.30 × Q.20 → Q.18, rounded.
    let l = log2_u33(lo, carry) as i64 - LOG2_M2_IN_CM2 as i64;
    Some(-((FIVE_LOG10_2_Q30 as i64 * l + (1 << 31)) >> 32) as i32)
}

/// Allowed parameter range (inclusive), fixed point. Reversed bounds are used as if sorted; values
/// beyond [`P0_LIMIT`] / [`ALPHA_LIMIT`] are clamped to them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Bounds {
    /// Smallest α, Q.24.
    pub alpha_min: i32,
    /// Largest α, Q.24.
    pub alpha_max: i32,
    /// Smallest P0, Q.16 dBm.
    pub p0_min: i32,
    /// Largest P0, Q.16 dBm.
    pub p0_max: i32,
}

impl Bounds {
    /// The thesis' ranges: α ∈ [2, 5], P0 ∈ [−60, −20] dBm.
    pub const THESIS: Bounds = Bounds {
        alpha_min: 2 * ALPHA,
        alpha_max: 5 * ALPHA,
        p0_min: -60 * DB,
        p0_max: -20 * DB,
    };

    fn alpha(&self) -> (i32, i32) {
        sorted(self.alpha_min, self.alpha_max, ALPHA_LIMIT)
    }

    fn p0(&self) -> (i32, i32) {
        sorted(self.p0_min, self.p0_max, P0_LIMIT)
    }
}

impl Default for Bounds {
    fn default() -> Self {
        Bounds::THESIS
    }
}

fn sorted(a: i32, b: i32, limit: i32) -> (i32, i32) {
    let (a, b) = (clamp_i32(a, -limit, limit), clamp_i32(b, -limit, limit));
    (a.min(b), a.max(b))
}

/// Sufficient statistics of calibration samples, as exact integer sums (`z = −b` for the RSSI
/// byte `b`, so the byte sums are kept; the x sums apart for negative and positive x).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct CalStats {
    n: u16,
    /// Σb (= −Σz), at most 255 · [`MAX_SAMPLES`].
    sb: u16,
    /// Σb² (= Σz²).
    sbb: u32,
    /// Σ|x| over the samples with x ≥ 0, then with x < 0, Q.18 (each below 2^32).
    sx: [u32; 2],
    /// Σx², Q.36.
    sxx: u64,
    /// Σ|x|·b over the samples with x ≥ 0, then with x < 0, Q.18.
    sxb: [u64; 2],
}

impl CalStats {
    /// No samples.
    pub const fn new() -> CalStats {
        CalStats {
            n: 0,
            sb: 0,
            sbb: 0,
            sx: [0; 2],
            sxx: 0,
            sxb: [0; 2],
        }
    }

    /// Adds the samples `bytes` (RSSI bytes, `None` skipped) taken at `x` (Q.18, from
    /// [`distance_x`]; clamped to ±32 dB, i.e. 1.6 mm … 1.6 km). Returns how many were added (none
    /// beyond [`MAX_SAMPLES`]).
    #[inline(never)]
    pub fn push_at(&mut self, x: i32, bytes: &[Option<u8>]) -> usize {
        self.push_x(
            clamp_i32(x, -(32 << 18), 32 << 18),
            bytes.iter().flatten().copied(),
        )
    }

    /// Adds the samples `bytes` of the anchor pair `a`, `b` (skipped, returning 0, when the
    /// anchors coincide).
    #[inline(never)]
    pub fn push_pair(&mut self, a: PointCm, b: PointCm, bytes: &[Option<u8>]) -> usize {
        match distance_x(a, b) {
            Some(x) => self.push_x(x, bytes.iter().flatten().copied()),
            None => 0,
        }
    }

    /// [`CalStats::push_pair`] for a pair's bytes as a report carries them (0: not heard).
    #[inline(never)]
    pub fn push_pair_bytes(&mut self, a: PointCm, b: PointCm, bytes: &[u8]) -> usize {
        match distance_x(a, b) {
            Some(x) => self.push_x(x, bytes.iter().copied().filter(|&b| b != 0)),
            None => 0,
        }
    }

    /// [`CalStats::push_at`] for `|x| ≤ 2^23` ([`distance_x`] stays within ±30 dB).
    #[inline(always)]
    fn push_x(&mut self, x: i32, bytes: impl Iterator<Item = u8>) -> usize {
        let room = MAX_SAMPLES - self.n;
        let (mut k, mut s, mut s2) = (0u16, 0u16, 0u32);
        for b in bytes {
            if k == room {
                break;
            }
            k += 1;
            s += b as u16;
            s2 += m8(b, b) as u32;
        }
        if k == 0 {
            return 0;
        }
        self.n += k;
        self.sb += s;
        self.sbb += s2;
        // |x| ≤ 2^23: x² < 2^46. Plain 64-bit products (per anchor pair, not per sample), but
        // |x|·Σb from two 32-bit ones (a 64-bit product is a library call on an 8-bit MCU).
        let ax = x.unsigned_abs();
        let x2 = ax as u64 * ax as u64;
        self.sxx += k as u64 * x2;
        let side = (x < 0) as usize;
        self.sx[side] += k as u32 * ax;
        let (h, l) = (ax >> 16, ax & 0xFFFF);
        self.sxb[side] += (((h * s as u32) as u64) << 16) + (l * s as u32) as u64;
        k as usize
    }

    /// All anchor-to-anchor samples of `m` (`i ≠ j`, channels in use), or only channel `channel`:
    /// one log per anchor pair.
    pub fn from_measurements(m: &Measurements, channel: Option<usize>) -> CalStats {
        let mut s = CalStats::new();
        let n_ch = m.channels();
        let anchors = m.anchors();
        for i in 0..anchors.len() {
            for j in i + 1..anchors.len() {
                let Some(x) = distance_x(anchors[i], anchors[j]) else {
                    continue;
                };
                // Both directions in one push: one x², one x·Σz per pair.
                let mut bytes = [None; 2 * MAX_CHANNELS];
                for (k, (p, q)) in [(i, j), (j, i)].into_iter().enumerate() {
                    for (c, v) in m.a2a[p][q][..n_ch].iter().enumerate() {
                        if channel.is_none_or(|want| want == c) {
                            bytes[k * MAX_CHANNELS + c] = *v;
                        }
                    }
                }
                s.push_at(x, &bytes);
            }
        }
        s
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.n as usize
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Sum of squared residuals `Σ (z − P0 − α·x)²` under `model`, Q.16 dB².
    pub fn sse(&self, model: PathLoss) -> u64 {
        let m = model.sane();
        self.sse_at(m.p0, m.alpha)
    }

    /// The residual sum at `(p0 Q.16, alpha Q.24)` (both within the limits), Q.16 dB².
    ///
    /// `Σz² − 2·P0·Σz − 2α·Σxz + n·P0² + 2·P0·α·Σx + α²·Σx²` in Q.32, with α rounded to Q.16
    /// (only candidates are compared with it) and `P0·Σx`, `α·Σx²` rounded down to Q.16 (the
    /// Q.32 terms of the definition, each below 2^61, regrouped into three products).
    #[inline(never)]
    fn sse_at(&self, p0: i32, alpha: i32) -> u64 {
        let (p, a) = (p0 as i64, (alpha as i64 + 128) >> 8);
        // P0·Σx and α·Σx², Q.16.
        let p_sx = (p * self.sx()) >> 18;
        let a_sxx = (a * (self.sxx >> 20) as i64) >> 16;
        // Σz² − 2·P0·Σz + n·P0² = Σb² + P0·(2·Σb + n·P0).
        let w = ((self.sb as i64) << 17) + self.n as i64 * p0 as i64;
        // 2·P0·α·Σx + α²·Σx² − 2α·Σxz = α·(2·Σxb + 4·P0Σx + 2·αΣx²) / 2, the half rounded up as
        // the definition's rounded-down −2α·Σxz term.
        let v = self.sxb() + 4 * p_sx + 2 * a_sxx;
        let q32 = ((self.sbb as i64) << 32) + p * w + ((a * v + 1) >> 1);
        (q32.max(0) >> 16) as u64
    }

    /// Σx, Q.18.
    fn sx(&self) -> i64 {
        self.sx[0] as i64 - self.sx[1] as i64
    }

    /// Σx·b (= −Σxz), Q.18.
    fn sxb(&self) -> i64 {
        self.sxb[0] as i64 - self.sxb[1] as i64
    }

    /// `n·Σx² − (Σx)²`, Q.36: `n²` times the variance of x (never negative).
    fn dxx(&self) -> u64 {
        let sx = self.sx().unsigned_abs();
        self.n as u64 * self.sxx - sx * sx
    }

    /// Whether the samples span enough distinct distances to determine α, from `dxx` =
    /// [`CalStats::dxx`]: the reference's `Σ(x − x̄)² > 10⁻⁹·n`, i.e.
    /// `dxx > ⌊n²·2^36/10⁹⌋` (`68.7·n²`: a division only between `64·n²` and `128·n²`).
    fn alpha_identifiable(&self, dxx: u64) -> bool {
        let n2 = self.n as u32 * self.n as u32;
        if dxx <= (n2 << 6) as u64 {
            return false;
        }
        dxx >= (n2 << 7) as u64 || dxx > ((n2 as u64) << 36) / 1_000_000_000
    }

    /// Best P0 (Q.16) for α (Q.24), unconstrained: `(Σz − α·Σx)/n`, rounded; saturated at
    /// `±2^26`, beyond every P0 bound.
    #[inline(never)]
    fn p0_for(&self, alpha: i32) -> i32 {
        let num = -((self.sb as i64) << 16) - ((alpha as i64 * self.sx() + (1 << 25)) >> 26);
        div_n(num, self.n.max(1))
    }

    /// Best α (Q.24) for P0 (Q.16), unconstrained: `(Σxz − P0·Σx)/Σx²`, clamped to
    /// ±[`ALPHA_LIMIT`]; `None` if `Σx² = 0`.
    #[inline(never)]
    fn alpha_for(&self, p0: i32) -> Option<i32> {
        let num = -self.sxb() - ((p0 as i64 * self.sx()) >> 16); // Q.18
        (self.sxx > 0).then(|| div_alpha(num, self.sxx))
    }
}

/// `num·2^42/den` rounded as the reference computed it, clamped to ±[`ALPHA_LIMIT`], for
/// `den ≥ 1` ([`div_scaled`]).
fn div_alpha(num: i64, den: u64) -> i32 {
    div_scaled(num, den, 42 | (ALPHA_LIMIT.trailing_zeros() as u16) << 8)
}

/// `num/n` rounded (`n ∈ [1, 256]`), saturated at `±2^26` (beyond every P0 bound).
fn div_n(num: i64, n: u16) -> i32 {
    div_scaled(num, n as u64, 26 << 8)
}

/// `num·2^s/den` with `sq = s | q << 8`, rounded as the reference computed it, saturated at
/// `±2^q`, for `|num| < 2^62` and `24 ≤ q ≤ 30` (`±2^q` also when `den` shifts to 0): `|num|` is
/// shifted left up to bit 61 (at most `s` places, bit by bit: once per fit), `den` right by the
/// rest of the `s`, then one 64-bit division. `s` and `q` come in one `u16`: as a fourth
/// argument `q` would go on the AVR stack, and LLVM's AVR backend has miscompiled the store of a
/// stack-passed argument in this function (it clobbered the divisor); with three arguments all
/// of them are passed in registers.
#[inline(never)]
fn div_scaled(num: i64, den: u64, sq: u16) -> i32 {
    let [s, q] = sq.to_le_bytes();
    let mut u = num.unsigned_abs();
    let mut r = s;
    while r >= 1 && u >> 61 == 0 {
        u <<= 1;
        r -= 1;
    }
    let d = den >> r;
    // u < 2^62 and d/2 < 2^63: no overflow.
    let u = u + d / 2;
    // The saturation as a bound on the quotient: `u >> q ≥ d` iff `u/d ≥ 2^q` (a variable shift
    // is a loop of 1-bit shifts on AVR; the byte shift by 24 is a move).
    let sat = ((1u8 << (q - 24)) as u32) << 24;
    let v = u.checked_div(d).map_or(sat, |v| v.min(sat as u64) as u32) as i32;
    if num < 0 {
        -v
    } else {
        v
    }
}

/// Result of a fixed-point parameter fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ParamFit {
    /// The fitted (or fixed) model.
    pub model: PathLoss,
    /// Sum of squared residuals of the samples under `model`, Q.16 dB².
    pub sse: u64,
    /// Number of samples.
    pub n: u16,
    /// Parameters fitted (0, 1 or 2).
    pub fitted: u8,
}

impl ParamFit {
    /// The fit of `model`, which is within the limits (a sane prior, or clamped to sane bounds).
    #[inline(never)]
    fn new(stats: &CalStats, model: PathLoss, fitted: u8) -> ParamFit {
        ParamFit {
            model,
            sse: stats.sse_at(model.p0, model.alpha),
            n: stats.n,
            fitted,
        }
    }

    /// Shadowing σ, Q.8 dB (saturating at 255.99 dB): `sqrt(sse / (n − fitted))`, `None` when
    /// `n ≤ fitted`. Computed on demand (one division and one square root).
    pub fn sigma(&self) -> Option<u16> {
        sigma_of(self.sse, self.n.saturating_sub(self.fitted as u16))
    }
}

/// `sqrt(sse/dof)` in Q.8 dB from `sse` in Q.16 dB², saturating; `None` for `dof = 0`.
fn sigma_of(sse: u64, dof: u16) -> Option<u16> {
    (dof > 0).then(|| {
        let v = sse / dof as u64;
        if v > u32::MAX as u64 {
            u16::MAX
        } else {
            isqrt_u32(v as u32).min(u16::MAX as u32) as u16
        }
    })
}

/// Fits the model to `stats` in `mode` with `method` within `bounds`: the same rules as
/// [`crate::params::fit`] (see there), in fixed point. A firmware that only needs one method
/// calls [`fit_least_squares`] or [`fit_grid`] directly (the other is then not linked).
pub fn fit(
    stats: &CalStats,
    mode: ParamMode,
    method: FitMethod,
    prior: PathLoss,
    bounds: &Bounds,
) -> Result<ParamFit, LocError> {
    match method {
        FitMethod::LeastSquares => fit_least_squares(stats, mode, prior, bounds),
        FitMethod::Grid => fit_grid(stats, mode, prior, bounds),
    }
}

/// [`fit`] with [`FitMethod::LeastSquares`]: the exact least-squares optimum on the bounds box
/// (the MCU's method: one long division for α, one for P0).
#[inline(never)]
pub fn fit_least_squares(
    stats: &CalStats,
    mode: ParamMode,
    prior: PathLoss,
    bounds: &Bounds,
) -> Result<ParamFit, LocError> {
    fit_with(stats, mode, prior, bounds, None)
}

/// [`fit`] with [`FitMethod::Grid`]: the thesis' grid (α step 0.1, P0 step 0.5 dB), the
/// brute-force argmin (ties: smallest α, then smallest P0).
#[inline(never)]
pub fn fit_grid(
    stats: &CalStats,
    mode: ParamMode,
    prior: PathLoss,
    bounds: &Bounds,
) -> Result<ParamFit, LocError> {
    fit_with(stats, mode, prior, bounds, Some(grid_search))
}

/// A search over both parameters within the `(α, P0)` bounds, given `n·Σx² − (Σx)²`.
type Search = fn(&CalStats, u64, (i32, i32), (i32, i32)) -> PathLoss;

/// Both methods: nothing fitted ([`ParamMode::Fixed`]), no samples, P0 alone
/// ([`ParamMode::P0Only`], or α not identifiable: α the prior's, clamped to the bounds or on the
/// grid), or both by `grid` (`None`: [`box_least_squares`]). Inlined into the two entry points
/// with `grid` constant, so that the least-squares one links no grid code; one [`ParamFit`] at
/// the end.
#[inline(always)]
fn fit_with(
    stats: &CalStats,
    mode: ParamMode,
    prior: PathLoss,
    bounds: &Bounds,
    grid: Option<Search>,
) -> Result<ParamFit, LocError> {
    let prior = prior.sane();
    if mode == ParamMode::Fixed {
        return Ok(ParamFit::new(stats, prior, 0));
    }
    if stats.is_empty() {
        return Err(LocError::NoCalibrationData);
    }
    // α is the user's fixed value in P0Only mode: not subject to the bounds.
    let mut alpha = prior.alpha;
    if mode == ParamMode::P0AndAlpha {
        let dxx = stats.dxx();
        if stats.alpha_identifiable(dxx) {
            let (a, p) = (bounds.alpha(), bounds.p0());
            let model = match grid {
                Some(search) => search(stats, dxx, a, p),
                None => box_least_squares(stats, dxx, a, p),
            };
            return Ok(ParamFit::new(stats, model, 2));
        }
        let a = bounds.alpha();
        alpha = match grid {
            Some(_) => grid_alpha(alpha, a.0, a.1),
            None => clamp_i32(alpha, a.0, a.1),
        };
    }
    let p = bounds.p0();
    let p0 = stats.p0_for(alpha);
    let p0 = match grid {
        Some(_) => grid_p0(p0, p.0, p.1),
        None => clamp_i32(p0, p.0, p.1),
    };
    Ok(ParamFit::new(stats, PathLoss { p0, alpha }, 1))
}

/// The thesis' grid: for each α step the grid P0 nearest to its optimum, the least error.
fn grid_search(
    stats: &CalStats,
    _dxx: u64,
    (a_lo, a_hi): (i32, i32),
    (p_lo, p_hi): (i32, i32),
) -> PathLoss {
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

/// Whole 0.1 steps of α from `lo` to `hi`. The tolerance (10 units of `10·(hi − lo)` in Q.24)
/// absorbs decimal bounds rounded to Q.24, as the reference's `10⁻⁹` absorbs binary rounding.
fn alpha_steps(lo: i32, hi: i32) -> u32 {
    (((hi as i64 - lo as i64) * 10 + 10) >> 24) as u32
}

/// `lo + k·0.1`, Q.24, each step rounded on its own (no drift: `0.1 = 1 677 721.6 / 2^24`), never
/// above `hi`.
fn alpha_grid(lo: i32, hi: i32, k: u32) -> i32 {
    let k = k.min(1000) as i64;
    (lo as i64 + k * 1_677_721 + (k * 6 + 5) / 10).min(hi as i64) as i32
}

/// The α grid value nearest to `alpha` (clamped to the grid).
fn grid_alpha(alpha: i32, lo: i32, hi: i32) -> i32 {
    let k = ((alpha as i64 - lo as i64) * 10 + (1 << 23)) >> 24;
    alpha_grid(lo, hi, clamp_i64(k, 0, alpha_steps(lo, hi) as i64) as u32)
}

/// The P0 grid value (0.5 dB steps from `lo`) nearest to `p0` (`|p0| ≤ 2^26`; clamped to the
/// grid).
fn grid_p0(p0: i32, lo: i32, hi: i32) -> i32 {
    let steps = (hi - lo) >> 15;
    let k = clamp_i32((p0 - lo + (1 << 14)) >> 15, 0, steps);
    lo + (k << 15)
}

/// The exact least-squares minimiser on the bounds box (as [`crate::params`]'s), `dxx` =
/// [`CalStats::dxx`] (positive).
#[inline(never)]
fn box_least_squares(
    stats: &CalStats,
    dxx: u64,
    (a_lo, a_hi): (i32, i32),
    (p_lo, p_hi): (i32, i32),
) -> PathLoss {
    // α = (n·Σxz − Σx·Σz) / (n·Σx² − (Σx)²): Q.18 / Q.36 → Q.24 takes 2^42.
    let num = stats.sx() * stats.sb as i64 - stats.n as i64 * stats.sxb();
    let alpha = div_alpha(num, dxx);
    let p0 = stats.p0_for(alpha);
    if (a_lo..=a_hi).contains(&alpha) && (p_lo..=p_hi).contains(&p0) {
        return PathLoss { p0, alpha };
    }
    let mut best = PathLoss { p0: 0, alpha: 0 };
    let mut best_sse = u64::MAX;
    for edge in 0..4 {
        let c = match edge {
            // α on an edge, the best P0 for it clamped; then P0 on an edge, the best α clamped.
            0 | 1 => {
                let alpha = if edge == 0 { a_lo } else { a_hi };
                let p0 = clamp_i32(stats.p0_for(alpha), p_lo, p_hi);
                PathLoss { p0, alpha }
            }
            _ => {
                let p0 = if edge == 2 { p_lo } else { p_hi };
                let a = stats.alpha_for(p0).unwrap_or(a_lo);
                PathLoss {
                    p0,
                    alpha: clamp_i32(a, a_lo, a_hi),
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

/// First-order autoregressive smoother `y[n] = a·y[n−1] + b·x[n]`, `y[0] = x[0]`, with Q.16
/// coefficients, on any fixed-point value (P0 Q.16 or α Q.24).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Ar1 {
    /// Weight of the previous output, Q.16.
    pub a: i32,
    /// Weight of the new input, Q.16.
    pub b: i32,
    /// The last output (0 before the first input).
    y: i32,
    /// Whether there has been an input.
    started: bool,
}

impl Default for Ar1 {
    /// The thesis' `a = 0.8, b = 0.2`.
    fn default() -> Self {
        Ar1::THESIS
    }
}

impl Ar1 {
    /// The thesis' `a = 0.8, b = 0.2` (Q.16), no state: [`Ar1::default`].
    pub const THESIS: Ar1 = Ar1::new(52_429, 13_107);

    /// A smoother with Q.16 coefficients `a`, `b` (each clamped to `[−4, 4]`) and no state.
    pub const fn new(a: i32, b: i32) -> Ar1 {
        const L: i32 = 4 << 16;
        let a = if a > L {
            L
        } else if a < -L {
            -L
        } else {
            a
        };
        let b = if b > L {
            L
        } else if b < -L {
            -L
        } else {
            b
        };
        Ar1 {
            a,
            b,
            y: 0,
            started: false,
        }
    }

    /// Feeds `x`, returns the new output: `x` first, then `(a·y + b·x)/2^16` rounded,
    /// saturated to `i32`.
    #[inline(never)]
    pub fn update(&mut self, x: i32) -> i32 {
        let y = if self.started {
            let v = (self.a as i64 * self.y as i64 + self.b as i64 * x as i64 + (1 << 15)) >> 16;
            clamp_i64(v, i32::MIN as i64, i32::MAX as i64) as i32
        } else {
            x
        };
        (self.y, self.started) = (y, true);
        y
    }

    /// Current output, `None` before the first input.
    pub fn value(&self) -> Option<i32> {
        self.started.then_some(self.y)
    }

    /// Forgets the state.
    pub fn reset(&mut self) {
        (self.y, self.started) = (0, false);
    }
}

/// `v` clamped to `[−limit, limit]` ([`Smoothers::current`]'s two clamps share it).
#[inline(never)]
fn within(v: i32, limit: i32) -> i32 {
    clamp_i32(v, -limit, limit)
}

/// What [`OnlineParams`] keeps between fits: the prior, P0's and α's smoothers and the σ of the
/// last fit that had one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct Smoothers {
    /// The (sane) prior's P0, Q.16.
    prior_p0: i32,
    p0: Ar1,
    /// The (sane) prior's α, Q.24.
    prior_alpha: i32,
    alpha: Ar1,
    /// σ of the last fit with `n > fitted`, Q.8 dB (computed when fed: the sink asks each time).
    sigma: u16,
    /// Whether there has been such a fit.
    spread: bool,
}

impl Smoothers {
    /// The smoothed model (the prior for parameters not yet estimated), made sane.
    #[inline(never)]
    fn current(&self) -> PathLoss {
        PathLoss {
            p0: within(self.p0.value().unwrap_or(self.prior_p0), P0_LIMIT),
            alpha: within(self.alpha.value().unwrap_or(self.prior_alpha), ALPHA_LIMIT),
        }
    }

    /// σ of the last fit that had one, Q.8 dB.
    fn sigma(&self) -> Option<u16> {
        self.spread.then_some(self.sigma)
    }

    /// Takes the residual sum `sse` of a fit with `dof` degrees of freedom (none: kept as is).
    fn spread(&mut self, sse: u64, dof: u16) {
        if let Some(sigma) = sigma_of(sse, dof) {
            (self.sigma, self.spread) = (sigma, true);
        }
    }
}

/// Online parameter estimation: a fit per round, smoothed per parameter by [`Ar1`] (as
/// [`crate::params::OnlineParams`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct OnlineParams {
    /// What is estimated.
    pub mode: ParamMode,
    /// How it is fitted.
    pub method: FitMethod,
    /// Parameter range.
    pub bounds: Bounds,
    s: Smoothers,
}

impl OnlineParams {
    /// Starts from `prior` with the default smoothers.
    /// (`const`: a firmware can hold its start state as one constant.)
    pub const fn new(mode: ParamMode, method: FitMethod, bounds: Bounds, prior: PathLoss) -> Self {
        Self::with_smoothers(mode, method, bounds, prior, Ar1::THESIS, Ar1::THESIS)
    }

    /// Starts from `prior` with the given smoothers for P0 and α.
    pub const fn with_smoothers(
        mode: ParamMode,
        method: FitMethod,
        bounds: Bounds,
        prior: PathLoss,
        p0: Ar1,
        alpha: Ar1,
    ) -> Self {
        let prior = prior.sane();
        OnlineParams {
            mode,
            method,
            bounds,
            s: Smoothers {
                prior_p0: prior.p0,
                p0,
                prior_alpha: prior.alpha,
                alpha,
                sigma: 0,
                spread: false,
            },
        }
    }

    /// The smoothed model (the prior for parameters not yet estimated).
    pub fn current(&self) -> PathLoss {
        self.s.current()
    }

    /// σ of the last successful fit that had one (Q.8 dB, [`ParamFit::sigma`]), for an MMSE with
    /// estimated σ.
    pub fn sigma(&self) -> Option<u16> {
        self.s.sigma()
    }

    /// Fits `stats` and feeds the smoothers; returns the raw fit. On error the state is unchanged.
    pub fn update(&mut self, stats: &CalStats) -> Result<ParamFit, LocError> {
        let f = fit(stats, self.mode, self.method, self.current(), &self.bounds)?;
        self.feed(&f);
        Ok(f)
    }

    /// Feeds the smoothers with a fit made elsewhere (e.g. [`fit_least_squares`] with
    /// [`OnlineParams::current`] as the prior, so that only that method is linked).
    pub fn feed(&mut self, f: &ParamFit) {
        if self.mode != ParamMode::Fixed {
            self.s.p0.update(f.model.p0);
        }
        if self.mode == ParamMode::P0AndAlpha {
            self.s.alpha.update(f.model.alpha);
        }
        self.s.spread(f.sse, f.n.saturating_sub(f.fitted as u16));
    }
}

#[cfg(test)]
#[path = "fit_reference.rs"]
mod plain;

#[cfg(test)]
mod tests {
    //! The fit against [`plain`], the same fit with plain 64-bit sums and divisions: every public
    //! result must be bit-identical, on random and extreme inputs.
    use super::*;
    use crate::fixed::{ALPHA, DB};
    use std::{vec, vec::Vec};

    /// xorshift64*.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }

        fn below(&mut self, n: u64) -> u64 {
            self.next() % n
        }

        fn pick<T: Copy>(&mut self, v: &[T]) -> T {
            v[self.below(v.len() as u64) as usize]
        }

        /// A value in `[lo, hi]`.
        fn range(&mut self, lo: i64, hi: i64) -> i64 {
            lo + self.below((hi - lo + 1) as u64) as i64
        }

        /// Mostly plausible, sometimes anything, sometimes an edge.
        fn i32_around(&mut self, typical: (i64, i64), limit: i64) -> i32 {
            match self.below(8) {
                0 => self.next() as i32,
                1 => self.pick(&[i32::MIN, i32::MAX, 0, -1, 1]),
                2 => {
                    self.pick(&[-limit, limit, -limit - 1, limit + 1, -limit + 1, limit - 1]) as i32
                }
                3 => self.range(-limit - 2, limit + 2) as i32,
                _ => self.range(typical.0, typical.1) as i32,
            }
        }
    }

    fn point(r: &mut Rng) -> PointCm {
        match r.below(6) {
            0 => PointCm::new(r.next() as i16, r.next() as i16),
            1 => PointCm::new(
                r.pick(&[i16::MIN, i16::MAX, 0, -1, 1]),
                r.pick(&[i16::MIN, i16::MAX, 0, -1, 1]),
            ),
            2 => PointCm::new(r.range(-3, 3) as i16, r.range(-3, 3) as i16),
            _ => PointCm::new(r.range(-200, 2200) as i16, r.range(-200, 2200) as i16),
        }
    }

    fn bytes(r: &mut Rng) -> Vec<Option<u8>> {
        let len = match r.below(10) {
            0 => r.below(300) as usize,
            1 => 0,
            _ => r.range(1, 8) as usize,
        };
        let style = r.below(5);
        let base = r.next() as u8;
        (0..len)
            .map(|_| {
                if r.below(6) == 0 {
                    return None;
                }
                Some(match style {
                    0 => r.next() as u8,
                    1 => r.pick(&[0, 255]),
                    2 => base,
                    3 => 255,
                    _ => base.wrapping_add(r.below(7) as u8).max(30),
                })
            })
            .collect()
    }

    fn x_value(r: &mut Rng, pool: &[i32]) -> i32 {
        const X_MAX: i64 = 32 << 18;
        match r.below(8) {
            0 => r.next() as i32,
            1 => r.pick(&[i32::MIN, i32::MAX, 0, -X_MAX as i32, X_MAX as i32]),
            2 => r.range(-X_MAX - 5, X_MAX + 5) as i32,
            // Nearly equal distances: α barely identifiable.
            3 | 4 if !pool.is_empty() => r.pick(pool).wrapping_add(r.range(-40, 40) as i32),
            _ => r.range(-30 << 18, 20 << 18) as i32,
        }
    }

    /// Random statistics, built in both implementations side by side (each push compared).
    fn stats_pair(r: &mut Rng) -> (CalStats, plain::CalStats) {
        let (mut s, mut o) = (CalStats::new(), plain::CalStats::default());
        let mut pool = Vec::new();
        let pushes = match r.below(6) {
            0 => r.range(0, 3),
            1 => r.range(40, 120),
            _ => r.range(1, 30),
        };
        if r.below(4) == 0 {
            // A room: anchors up to 20 m apart, bytes from P0 −40 dBm, α 2…5, ±6 dB noise.
            let anchors: Vec<PointCm> = (0..r.range(2, 8))
                .map(|_| PointCm::new(r.range(0, 2000) as i16, r.range(0, 2000) as i16))
                .collect();
            let alpha = r.range(20, 50) as f64 / 10.0;
            for (i, &a) in anchors.iter().enumerate() {
                for &c in &anchors[i + 1..] {
                    let d = libm::hypot((a.x - c.x) as f64, (a.y - c.y) as f64).max(1.0) / 100.0;
                    let b: Vec<Option<u8>> = (0..r.range(1, 8))
                        .map(|_| {
                            let noise = r.range(-600, 600) as f64 / 100.0;
                            let dbm = -40.0 - 10.0 * alpha * libm::log10(d) + noise;
                            (r.below(10) != 0).then_some((-dbm).round().clamp(0.0, 255.0) as u8)
                        })
                        .collect();
                    assert_eq!(s.push_pair(a, c, &b), o.push_pair(a, c, &b));
                }
            }
            return (s, o);
        }
        let extreme = r.below(8) == 0;
        for _ in 0..pushes {
            let mut b = bytes(r);
            if extreme {
                b = vec![Some(r.pick(&[0, 255])); r.range(1, 64) as usize];
            }
            let got = if r.below(2) == 0 && !extreme {
                let (a, c) = (point(r), point(r));
                (s.push_pair(a, c, &b), o.push_pair(a, c, &b))
            } else {
                let x = if extreme {
                    r.pick(&[-(32 << 18), 32 << 18, i32::MIN, i32::MAX, (32 << 18) - 1])
                } else {
                    x_value(r, &pool)
                };
                pool.push(x);
                (s.push_at(x, &b), o.push_at(x, &b))
            };
            assert_eq!(got.0, got.1, "push");
            assert_eq!(s.len(), o.len());
        }
        (s, o)
    }

    fn model(r: &mut Rng) -> PathLoss {
        PathLoss {
            p0: r.i32_around((-90 * DB as i64, -10 * DB as i64), P0_LIMIT as i64),
            alpha: r.i32_around((ALPHA as i64, 6 * ALPHA as i64), ALPHA_LIMIT as i64),
        }
    }

    fn bounds(r: &mut Rng) -> Bounds {
        match r.below(4) {
            0 => Bounds::THESIS,
            1 => {
                let (a, p) = (model(r), model(r));
                Bounds {
                    alpha_min: a.alpha,
                    alpha_max: p.alpha,
                    p0_min: a.p0,
                    p0_max: p.p0,
                }
            }
            2 => {
                let a = r.range(0, 8 * ALPHA as i64) as i32;
                let p = r.range(-100 * DB as i64, 0) as i32;
                Bounds {
                    alpha_min: a,
                    alpha_max: a + r.range(0, 2 * ALPHA as i64) as i32,
                    p0_min: p,
                    p0_max: p + r.range(0, 10 * DB as i64) as i32,
                }
            }
            _ => Bounds {
                alpha_min: r.pick(&[i32::MIN, 0, ALPHA, ALPHA_LIMIT]),
                alpha_max: r.pick(&[i32::MAX, 0, 5 * ALPHA, -ALPHA_LIMIT]),
                p0_min: r.pick(&[i32::MIN, 0, -60 * DB, P0_LIMIT]),
                p0_max: r.pick(&[i32::MAX, 0, -20 * DB, -P0_LIMIT]),
            },
        }
    }

    fn same_fit(new: &Result<ParamFit, LocError>, old: &Result<plain::ParamFit, LocError>) -> bool {
        match (new, old) {
            (Ok(f), Ok(o)) => {
                (f.model, f.sse, f.n, f.fitted, f.sigma())
                    == (o.model, o.sse, o.n, o.fitted, o.sigma)
            }
            (Err(e), Err(g)) => e == g,
            _ => false,
        }
    }

    const MODES: [ParamMode; 3] = [ParamMode::Fixed, ParamMode::P0Only, ParamMode::P0AndAlpha];
    const METHODS: [FitMethod; 2] = [FitMethod::LeastSquares, FitMethod::Grid];

    #[test]
    fn distance_x_is_unchanged() {
        let mut r = Rng(0x1234_5678_9ABC_DEF1);
        for dx in -40i16..=40 {
            for dy in -40i16..=40 {
                let (a, b) = (PointCm::new(0, 0), PointCm::new(dx, dy));
                assert_eq!(distance_x(a, b), plain::distance_x(a, b), "{dx} {dy}");
            }
        }
        for _ in 0..200_000 {
            let (a, b) = (point(&mut r), point(&mut r));
            assert_eq!(distance_x(a, b), plain::distance_x(a, b), "{a:?} {b:?}");
        }
        // push_pair skips the ±32 dB clamp: the extremes are 1 cm (+20 dB) and the diagonal of
        // the i16 square (−29.7 dB).
        let (near, far) = (
            distance_x(PointCm::new(0, 0), PointCm::new(0, 1)).unwrap(),
            distance_x(
                PointCm::new(i16::MIN, i16::MIN),
                PointCm::new(i16::MAX, i16::MAX),
            )
            .unwrap(),
        );
        assert!(near < 21 << 18 && far > -30 << 18, "{near} {far}");
    }

    #[test]
    fn raw_pair_pushes_are_push_pair() {
        // The sink's path (bytes 0 = not heard) against `push_pair`.
        let mut r = Rng(0x0DDB_1A5E_5BAD_5EED);
        for _ in 0..20_000 {
            let (mut s, _) = stats_pair(&mut r);
            let mut t = s;
            // Full or nearly: the 256-sample limit.
            if r.below(4) == 0 {
                let room = MAX_SAMPLES as usize - s.len();
                let fill = vec![Some(77); room.saturating_sub(r.below(6) as usize)];
                s.push_at(-(3 << 18), &fill);
                t = s;
            }
            let (a, c) = (point(&mut r), point(&mut r));
            let mut raw = [0u8; 8];
            for b in raw.iter_mut() {
                let any = r.next() as u8;
                *b = r.pick(&[0, 0, 1, 255, any]);
            }
            let opt = raw.map(|b| (b != 0).then_some(b));
            let k = t.push_pair_bytes(a, c, &raw);
            assert_eq!(k, s.push_pair(a, c, &opt));
            assert_eq!(t, s);
        }
    }

    #[test]
    fn fits_are_unchanged() {
        let mut r = Rng(0x9E37_79B9_7F4A_7C15);
        for case in 0..20_000 {
            let (s, o) = stats_pair(&mut r);
            for _ in 0..4 {
                let m = model(&mut r);
                assert_eq!(s.sse(m), o.sse(m), "case {case}: sse at {m:?} of {o:?}");
            }
            for mode in MODES {
                for method in METHODS {
                    let (prior, b) = (model(&mut r), bounds(&mut r));
                    let new = fit(&s, mode, method, prior, &b);
                    let old = plain::fit(&o, mode, method, prior, &b);
                    assert!(
                        same_fit(&new, &old),
                        "case {case}: {mode:?} {method:?} {prior:?} {b:?} of {o:?}:\n{new:?}\n{old:?}"
                    );
                    let direct = match method {
                        FitMethod::LeastSquares => fit_least_squares(&s, mode, prior, &b),
                        FitMethod::Grid => fit_grid(&s, mode, prior, &b),
                    };
                    assert_eq!(direct, new);
                }
            }
        }
    }

    #[test]
    fn extreme_sums_are_unchanged() {
        const X: i32 = 32 << 18;
        let mut r = Rng(0x5151_5151_A5A5_A5A5);
        for xs in [
            &[X][..],
            &[-X],
            &[X, -X],
            &[-X, X - 1],
            &[X, X - 1],
            &[X, 0],
            &[1, -1],
            &[i32::MAX, i32::MIN],
        ] {
            for b in [0, 1, 254, 255] {
                for split in [1usize, 2, 128, 255, 256, 300] {
                    let (mut s, mut o) = (CalStats::new(), plain::CalStats::default());
                    let mut left = 300;
                    let mut i = 0;
                    while left > 0 {
                        let len = split.min(left);
                        let bytes = vec![Some(b); len];
                        let x = xs[i % xs.len()];
                        assert_eq!(s.push_at(x, &bytes), o.push_at(x, &bytes));
                        left -= len;
                        i += 1;
                    }
                    assert_eq!(s.len(), MAX_SAMPLES as usize);
                    for mode in MODES {
                        for method in METHODS {
                            for _ in 0..3 {
                                let (prior, bounds) = (model(&mut r), bounds(&mut r));
                                let new = fit(&s, mode, method, prior, &bounds);
                                let old = plain::fit(&o, mode, method, prior, &bounds);
                                assert!(
                                    same_fit(&new, &old),
                                    "{xs:?} {b} {split}: {new:?} {old:?}"
                                );
                                let m = model(&mut r);
                                assert_eq!(s.sse(m), o.sse(m));
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn identifiability_threshold_is_unchanged() {
        // Two distances Δ apart (Q.18): n·Σx² − (Σx)² = k1·k2·Δ² crosses ⌊n²·2^36/10⁹⌋.
        for (k1, k2) in [
            (1, 1),
            (1, 2),
            (2, 3),
            (5, 1),
            (28, 100),
            (128, 128),
            (1, 255),
        ] {
            for delta in 0..400 {
                let (mut s, mut o) = (CalStats::new(), plain::CalStats::default());
                let x = -(7 << 18) + 12_345;
                for (k, x) in [(k1, x), (k2, x + delta)] {
                    let bytes = vec![Some(70); k];
                    assert_eq!(s.push_at(x, &bytes), o.push_at(x, &bytes));
                }
                let dxx = s.dxx();
                assert_eq!(dxx, (k1 * k2) as u64 * (delta * delta) as u64);
                let n = (k1 + k2) as i64;
                let want = dxx as i64 > ((n * n) << 36) / 1_000_000_000;
                assert_eq!(s.alpha_identifiable(dxx), want, "{k1} {k2} {delta}");
                for method in METHODS {
                    let prior = PathLoss::THESIS;
                    let new = fit(&s, ParamMode::P0AndAlpha, method, prior, &Bounds::THESIS);
                    let old = plain::fit(&o, ParamMode::P0AndAlpha, method, prior, &Bounds::THESIS);
                    assert!(same_fit(&new, &old), "{k1} {k2} {delta}");
                }
            }
        }
    }

    #[test]
    fn ar1_is_unchanged() {
        let mut r = Rng(0xD1B5_4A32_D192_ED03);
        for _ in 0..20_000 {
            let a = r.i32_around((-(1 << 16), 1 << 16), 4 << 16);
            let b = match r.below(3) {
                // The usual smoothers: complementary weights.
                0 => (1i32 << 16).wrapping_sub(a),
                _ => r.i32_around((-(1 << 16), 1 << 16), 4 << 16),
            };
            let mut s = Ar1::new(a, b);
            let mut y = None;
            for _ in 0..r.range(1, 6) {
                let x = r.i32_around((-(90 << 16), 6 << 24), 1 << 30);
                let want = plain::ar1_update(s.a, s.b, y, x);
                y = Some(want);
                assert_eq!(s.update(x), want, "{s:?} {x}");
                assert_eq!(s.value(), y);
            }
        }
    }

    #[test]
    fn online_params_are_unchanged() {
        let mut r = Rng(0x8BAD_F00D_DEAD_BEEF);
        for _ in 0..400 {
            let (mode, method) = (r.pick(&MODES), r.pick(&METHODS));
            let (b, prior) = (bounds(&mut r), model(&mut r));
            let (pa, pb) = (r.range(0, 1 << 16) as i32, r.range(0, 1 << 16) as i32);
            let (aa, ab) = (r.range(0, 1 << 16) as i32, r.range(0, 1 << 16) as i32);
            let mut on = OnlineParams::with_smoothers(
                mode,
                method,
                b,
                prior,
                Ar1::new(pa, pb),
                Ar1::new(aa, ab),
            );
            let mut o = plain::OnlineParams::new(mode, method, b, prior, (pa, pb), (aa, ab));
            for _ in 0..r.range(1, 5) {
                let (s, so) = stats_pair(&mut r);
                assert!(same_fit(&on.update(&s), &o.update(&so)));
                assert_eq!(on.current(), o.current());
                assert_eq!(on.sigma(), o.sigma);
            }
        }
    }
}
