//! Performance bounds reported next to the estimators.
//!
//! * [`crlb`]: the Cramér–Rao lower bound for RSS localization with known anchors (Patwari et al.,
//!   IEEE TSP 2003): Fisher information `F = C·b·Σ uᵢuᵢᵀ/dᵢ²`, `b = (10α/(σ·ln 10))²`, `uᵢ` the
//!   unit vector from anchor `i` to the point, `C` the number of channels with independent noise.
//!   The bound on the RMSE of any unbiased estimator is `sqrt(trace(F⁻¹))`. Anchors closer than
//!   [`MIN_DISTANCE`] contribute nothing: the (clamped) model is flat there.
//! * [`mmse_floor`]: the RMSE at a point of the posterior-mean estimator that knows the true model
//!   and σ, i.e. [`crate::grid::mmse`] on the same fine lattice with the Extended refinement over
//!   `C` channels. It is biased estimators' relevant floor (the CRLB does not bind them, and near
//!   the area's edges the posterior mean beats it). No closed form: it is a Monte Carlo average over
//!   noise draws the caller supplies, so the crate needs no RNG and results are reproducible from
//!   the caller's seed.

use crate::grid::{PosteriorAcc, FINE_DIVS};
use crate::model::{Area, PathLoss, Point, MAX_ANCHORS, MIN_DISTANCE};

/// The Fisher information matrix of the position at `point` (see the module docs); all zero for
/// `channels = 0`.
pub fn fisher(
    point: Point,
    anchors: &[Point],
    model: PathLoss,
    sigma: f64,
    channels: usize,
) -> [[f64; 2]; 2] {
    let t = 10.0 * model.alpha / (sigma * core::f64::consts::LN_10);
    let cb = channels as f64 * t * t;
    let mut f = [[0.0; 2]; 2];
    for a in anchors {
        let (dx, dy) = (point.x - a.x, point.y - a.y);
        let d2 = dx * dx + dy * dy;
        if d2 < MIN_DISTANCE * MIN_DISTANCE {
            continue;
        }
        // uuᵀ/d² = (dx, dy)(dx, dy)ᵀ / d⁴.
        let s = cb / (d2 * d2);
        f[0][0] += s * dx * dx;
        f[0][1] += s * dx * dy;
        f[1][1] += s * dy * dy;
    }
    f[1][0] = f[0][1];
    f
}

/// The CRLB on the position RMSE at `point`, metres: `sqrt(trace(F⁻¹))`.
///
/// `None` when `F` is singular (fewer than two anchors in distinct directions, e.g. all anchors
/// collinear with the point), `sigma` is not a positive finite number, or `channels = 0`.
pub fn crlb(
    point: Point,
    anchors: &[Point],
    model: PathLoss,
    sigma: f64,
    channels: usize,
) -> Option<f64> {
    if !(sigma > 0.0 && sigma.is_finite()) || channels == 0 {
        return None;
    }
    let f = fisher(point, anchors, model, sigma, channels);
    let tr = f[0][0] + f[1][1];
    let det = f[0][0] * f[1][1] - f[0][1] * f[1][0];
    // Singular relative to its scale (det = λ₁λ₂ ≤ tr²/4): the smaller eigenvalue is ~0.
    if !(tr > 0.0 && tr.is_finite() && det > 1e-12 * tr * tr) {
        return None;
    }
    // trace(F⁻¹) = trace(F) / det(F) for a 2 × 2 matrix.
    Some(libm::sqrt(tr / det))
}

/// Trials evaluated together: the log-distances of a lattice point are shared by a block.
const BLOCK: usize = 16;

/// The MMSE floor at `point`, metres: the RMSE of the lattice posterior mean (true `model` and
/// `sigma`, `channels` channels with independent noise, uniform prior over `area`) over the trials
/// in `draws`.
///
/// `draws` are standard normal samples, one per anchor per trial: trial `t` uses
/// `draws[t·n .. (t+1)·n]` (`n = anchors.len()`, a trailing partial trial is ignored). A trial's
/// per-anchor dB mean over `C` channels is `p(dᵢ) + σ/√C · draw`, which is exactly distributed as
/// the mean of `C` independent channel draws, and that mean with weight `C` is the whole
/// multichannel posterior (see [`crate::refine`]), so one draw per anchor suffices.
///
/// `None` without a whole trial, with fewer than 3 or more than [`MAX_ANCHORS`] anchors, with
/// `channels = 0`, or with `sigma` not positive and finite.
pub fn mmse_floor(
    point: Point,
    anchors: &[Point],
    model: PathLoss,
    sigma: f64,
    channels: usize,
    area: Area,
    draws: &[f64],
) -> Option<f64> {
    let n = anchors.len();
    if !(3..=MAX_ANCHORS).contains(&n)
        || channels == 0
        || !(sigma > 0.0 && sigma.is_finite())
        || draws.len() < n
    {
        return None;
    }
    let trials = draws.len() / n;
    let w = channels as f64;
    let s = sigma / libm::sqrt(w);
    let k = 5.0 * model.alpha;
    // Per anchor: the noise-free z − P0 at the point.
    let mut r0 = [0.0; MAX_ANCHORS];
    for (r, a) in r0.iter_mut().zip(anchors) {
        *r = model.rssi_at(point.dist(*a)) - model.p0;
    }
    let mut sum_sq = 0.0;
    for block in draws[..trials * n].chunks(BLOCK * n) {
        let bt = block.len() / n;
        let mut r = [[0.0; MAX_ANCHORS]; BLOCK];
        for (rt, dt) in r.iter_mut().zip(block.chunks_exact(n)) {
            for i in 0..n {
                rt[i] = r0[i] + s * dt[i];
            }
        }
        let mut acc = [PosteriorAcc::new(sigma); BLOCK];
        let mut l = [0.0; MAX_ANCHORS];
        for gi in 0..=FINE_DIVS {
            for gj in 0..=FINE_DIVS {
                let p = crate::grid::lattice_point(area, gi, gj);
                for (li, a) in l.iter_mut().zip(anchors) {
                    let (dx, dy) = (p.x - a.x, p.y - a.y);
                    *li = k * libm::log10((dx * dx + dy * dy).max(MIN_DISTANCE * MIN_DISTANCE));
                }
                for (acc_t, rt) in acc[..bt].iter_mut().zip(&r) {
                    let mut c = 0.0;
                    for i in 0..n {
                        let e = rt[i] + l[i];
                        c += w * e * e;
                    }
                    acc_t.add(if c.is_nan() { f64::INFINITY } else { c }, p.x, p.y);
                }
            }
        }
        for a in &acc[..bt] {
            // No finite cost at all (absurd draws): the estimate defaults to the origin, as in
            // `grid::posterior_mean_lattice`.
            let (mx, my, _) = a.mean().unwrap_or((0.0, 0.0, 0.0));
            let (ex, ey) = (mx - point.x, my - point.y);
            sum_sq += ex * ex + ey * ey;
        }
    }
    Some(libm::sqrt(sum_sq / trials as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fisher_is_symmetric_psd() {
        let anchors = [
            Point::new(0.0, 0.0),
            Point::new(10.0, 0.0),
            Point::new(3.0, 8.0),
        ];
        let f = fisher(Point::new(2.0, 7.0), &anchors, PathLoss::THESIS, 2.0, 2);
        assert_eq!(f[0][1], f[1][0]);
        assert!(f[0][0] > 0.0 && f[1][1] > 0.0);
        assert!(f[0][0] * f[1][1] - f[0][1] * f[1][0] > 0.0);
    }

    #[test]
    fn singular_geometry_has_no_bound() {
        // Point on the line through all anchors: no information across it.
        let anchors = [
            Point::new(0.0, 0.0),
            Point::new(5.0, 0.0),
            Point::new(10.0, 0.0),
        ];
        assert_eq!(
            crlb(Point::new(3.0, 0.0), &anchors, PathLoss::THESIS, 2.0, 1),
            None
        );
        assert!(crlb(Point::new(3.0, 1.0), &anchors, PathLoss::THESIS, 2.0, 1).is_some());
        assert_eq!(
            crlb(Point::new(3.0, 1.0), &anchors, PathLoss::THESIS, 0.0, 1),
            None
        );
        assert_eq!(
            crlb(Point::new(3.0, 1.0), &anchors, PathLoss::THESIS, 2.0, 0),
            None
        );
    }
}
