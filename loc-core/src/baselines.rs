//! Host baseline algorithms: trilateration, quadlateration and MDS-MAP.
//!
//! The baselines work on anchor positions and **distance estimates** in metres (the caller turns
//! RSSI into distance with [`PathLoss::distance`](crate::PathLoss::distance)), so they are
//! independent of the channel refinements. All three share one signature,
//! `fn(anchors: &[Point], dists: &[f64]) -> Result<Point, LocError>`, and [`Baseline::estimate`]
//! dispatches to them with optional clipping to the area.
//!
//! # Input handling (common to all three)
//!
//! * `anchors[i]` pairs with `dists[i]`; if the slices differ in length the extra entries of the
//!   longer one are ignored.
//! * A **negative** distance is treated as `0` (the agent is at that anchor): the sign carries no
//!   information and a distance estimate can only err towards it by noise.
//! * An anchor whose distance or position is **not finite** (NaN, ±∞) is *unusable* and skipped,
//!   as if it had not been heard.
//! * Each method then takes the first usable anchors it needs, in order: [`trilaterate`] the first
//!   three, [`quadlaterate`] the first four, [`mds_map`] all of them (at most [`MAX_ANCHORS`]).
//!   With fewer than three usable anchors every method returns [`LocError::TooFewAnchors`] with the
//!   number of usable anchors.
//! * Anchors that are coincident or collinear (within the relative tolerance [`DEGENERATE_TOL`])
//!   give [`LocError::DegenerateGeometry`], and so does any computation whose result would not be
//!   finite (e.g. distances so large that their squares overflow). The functions never panic and
//!   never return a NaN or infinite point.
//!
//! # Clipping
//!
//! The plain functions return the unconstrained estimate, which may lie outside the localization
//! area. [`Baseline::estimate`] takes `clip: Option<Area>`: with `Some(area)` the estimate is moved
//! to the nearest point of the area ([`Area::clip`]); with `None` it is returned as is. An area
//! with a negative or NaN side contains no point, so clipping to it gives
//! [`LocError::DegenerateGeometry`] rather than a point outside it.

use crate::model::{Area, Point, MAX_ANCHORS};
use crate::LocError;

/// Relative tolerance of the degeneracy tests: three anchors are treated as collinear (or
/// coincident) when twice their triangle's area is at most `DEGENERATE_TOL · L²`, `L` the longest
/// side (i.e. when the triangle is flat relative to its own size, whatever the unit). For MDS-MAP
/// the anchors are degenerate when *every* triple of them is, or when the Procrustes fit cannot
/// tell a rotation from a reflection (its cross-covariance's singular values `σ₁ ≥ σ₂` have
/// `σ₂ ≤ DEGENERATE_TOL · σ₁`).
pub const DEGENERATE_TOL: f64 = 1e-9;

/// Size of the MDS matrix: the anchors plus the agent.
const MDS_N: usize = MAX_ANCHORS + 1;

/// Most Jacobi sweeps (a 9×9 matrix converges in well under 15; this only bounds the loop when
/// the input is not finite).
const MAX_SWEEPS: usize = 64;

/// A baseline estimator, as the thesis' tables name them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Baseline {
    /// [`trilaterate`]: the first three usable anchors (TRLT-3).
    Trilateration,
    /// [`quadlaterate`]: the first four usable anchors (QUAD-4).
    Quadlateration,
    /// [`mds_map`]: all usable anchors (MDS-3, MDS-4, …).
    MdsMap,
}

impl Baseline {
    /// Every baseline, in table order.
    pub const ALL: [Baseline; 3] = [
        Baseline::Trilateration,
        Baseline::Quadlateration,
        Baseline::MdsMap,
    ];

    /// The table label's stem (`TRLT`, `QUAD`, `MDS`; the tables append the anchor count).
    pub const fn label(self) -> &'static str {
        match self {
            Baseline::Trilateration => "TRLT",
            Baseline::Quadlateration => "QUAD",
            Baseline::MdsMap => "MDS",
        }
    }

    /// How many usable anchors the method uses at most (`None`: all, up to [`MAX_ANCHORS`]).
    pub const fn anchors_used(self) -> Option<usize> {
        match self {
            Baseline::Trilateration => Some(3),
            Baseline::Quadlateration => Some(4),
            Baseline::MdsMap => None,
        }
    }

    /// The estimate of this method from `anchors` and the distance estimates `dists` (metres),
    /// clipped to `clip` when given (see the [module docs](self) for input handling and clipping).
    pub fn estimate(
        self,
        anchors: &[Point],
        dists: &[f64],
        clip: Option<Area>,
    ) -> Result<Point, LocError> {
        let p = match self {
            Baseline::Trilateration => trilaterate(anchors, dists),
            Baseline::Quadlateration => quadlaterate(anchors, dists),
            Baseline::MdsMap => mds_map(anchors, dists),
        }?;
        clip_to(p, clip)
    }
}

/// `p` clipped to `clip` (if any); an area with a negative or NaN side → degenerate.
fn clip_to(p: Point, clip: Option<Area>) -> Result<Point, LocError> {
    match clip {
        None => Ok(p),
        // `>=` is false for NaN; `Area::clip` would panic on such an area.
        Some(a) if a.width >= 0.0 && a.height >= 0.0 => Ok(a.clip(p)),
        Some(_) => Err(LocError::DegenerateGeometry),
    }
}

/// Trilateration: the agent position from the first three usable anchors and their distances.
///
/// Subtracting the first circle equation `|x − a₁|² = d₁²` from the other two gives the linear
/// system `2 (aᵢ − a₁)·(x − a₁) = |aᵢ − a₁|² + d₁² − dᵢ²`, `i = 2, 3`, solved directly (Cramer's
/// rule, in coordinates relative to `a₁`). With exact distances this is the exact position; with
/// noisy ones it is the point where the two radical axes meet (it need not lie on any circle).
///
/// Errors: fewer than three usable anchors → [`LocError::TooFewAnchors`]; collinear or coincident
/// anchors (see [`DEGENERATE_TOL`]) or a non-finite result → [`LocError::DegenerateGeometry`].
pub fn trilaterate(anchors: &[Point], dists: &[f64]) -> Result<Point, LocError> {
    let (sel, taken, usable) = select::<3>(anchors, dists);
    if taken < 3 {
        return Err(LocError::TooFewAnchors { usable });
    }
    solve3(sel[0], sel[1], sel[2])
}

/// Quadlateration: the mean of the 3-anchor trilaterations of the first four usable anchors.
///
/// A degenerate triple (three of the four collinear or coincident) is skipped and the mean is
/// taken over the remaining solutions (so with exact distances the result is still exact; under
/// noise it averages fewer solutions). Only if every triple is degenerate is the result
/// [`LocError::DegenerateGeometry`]. With exactly three usable anchors there is a single triple and
/// the result equals [`trilaterate`]; fewer → [`LocError::TooFewAnchors`].
pub fn quadlaterate(anchors: &[Point], dists: &[f64]) -> Result<Point, LocError> {
    let (sel, taken, usable) = select::<4>(anchors, dists);
    if taken < 3 {
        return Err(LocError::TooFewAnchors { usable });
    }
    let (mut sx, mut sy, mut count) = (0.0, 0.0, 0u32);
    for i in 0..taken {
        for j in i + 1..taken {
            for k in j + 1..taken {
                if let Ok(p) = solve3(sel[i], sel[j], sel[k]) {
                    sx += p.x;
                    sy += p.y;
                    count += 1;
                }
            }
        }
    }
    if count == 0 {
        return Err(LocError::DegenerateGeometry);
    }
    let n = f64::from(count);
    finite(Point::new(sx / n, sy / n))
}

/// MDS-MAP: classical multidimensional scaling of the anchors and the agent, fitted onto the
/// anchors.
///
/// 1. The `(n+1)×(n+1)` squared-distance matrix of the `n` usable anchors (at most
///    [`MAX_ANCHORS`]; anchor-to-anchor distances exact, from the positions) and the agent
///    (anchor-to-agent distances: `dists`), scaled by the largest distance so nothing overflows.
/// 2. Double centering, `B = −½ J D⁽²⁾ J`, and its eigen-decomposition by cyclic Jacobi rotations
///    (fixed 9×9 arrays, no allocation).
/// 3. Relative coordinates from the two largest eigenpairs: `vₖ · sqrt(max(λₖ, 0))`.
/// 4. A Procrustes fit with scale, rotation **or reflection**, and translation mapping the
///    relative anchor coordinates onto the true anchor positions (least squares, closed form: the
///    polar factor of the 2×2 cross-covariance), applied to the agent's relative coordinate.
///
/// With exact distances the result is the exact position. Errors: fewer than three usable anchors
/// → [`LocError::TooFewAnchors`]; all anchors collinear or coincident, an embedding that leaves
/// the fit ambiguous (e.g. inconsistent distances collapsing it to a line), or a non-finite
/// result → [`LocError::DegenerateGeometry`].
pub fn mds_map(anchors: &[Point], dists: &[f64]) -> Result<Point, LocError> {
    let (sel, n, usable) = select::<MAX_ANCHORS>(anchors, dists);
    if n < 3 {
        return Err(LocError::TooFewAnchors { usable });
    }
    let sel = &sel[..n];
    if !any_proper_triangle(sel) {
        return Err(LocError::DegenerateGeometry);
    }

    // Scale so that the largest distance is 1 (squares then cannot overflow).
    let mut scale = 0.0f64;
    for (i, &(pi, di)) in sel.iter().enumerate() {
        scale = scale.max(di);
        for &(pj, _) in &sel[i + 1..] {
            scale = scale.max(pi.dist(pj));
        }
    }
    if !(scale > 0.0 && scale.is_finite()) {
        return Err(LocError::DegenerateGeometry);
    }

    // Squared distances; index n is the agent.
    let m = n + 1;
    let mut b = [[0.0f64; MDS_N]; MDS_N];
    for i in 0..n {
        for j in 0..n {
            let d = sel[i].0.dist(sel[j].0) / scale;
            b[i][j] = d * d;
        }
        let d = sel[i].1 / scale;
        b[i][n] = d * d;
        b[n][i] = d * d;
    }
    // Double centering: b_ij ← −½ (d²_ij − r_i − r_j + g), r the row means, g the grand mean.
    let mut r = [0.0f64; MDS_N];
    for (ri, row) in r.iter_mut().zip(&b).take(m) {
        *ri = row[..m].iter().sum::<f64>() / m as f64;
    }
    let g = r[..m].iter().sum::<f64>() / m as f64;
    for i in 0..m {
        for j in 0..m {
            b[i][j] = -0.5 * (b[i][j] - r[i] - r[j] + g);
        }
    }

    let (eval, evec) = jacobi_eigen(&mut b, m);
    // The two largest eigenvalues.
    let (mut k1, mut k2) = (0, 1);
    if eval[k2] > eval[k1] {
        core::mem::swap(&mut k1, &mut k2);
    }
    for k in 2..m {
        if eval[k] > eval[k1] {
            k2 = k1;
            k1 = k;
        } else if eval[k] > eval[k2] {
            k2 = k;
        }
    }
    let (s1, s2) = (libm::sqrt(eval[k1].max(0.0)), libm::sqrt(eval[k2].max(0.0)));
    let rel = |i: usize| (evec[i][k1] * s1, evec[i][k2] * s2);

    let fit = procrustes(sel, rel)?;
    let (ax, ay) = rel(n);
    finite(fit.apply(ax, ay))
}

/// The first `K` usable `(position, distance)` pairs (negative distances → 0), how many were
/// taken, and how many usable pairs there are in all.
fn select<const K: usize>(anchors: &[Point], dists: &[f64]) -> ([(Point, f64); K], usize, usize) {
    let mut sel = [(Point::default(), 0.0); K];
    let (mut taken, mut usable) = (0, 0);
    for (&p, &d) in anchors.iter().zip(dists) {
        if !(p.x.is_finite() && p.y.is_finite() && d.is_finite()) {
            continue;
        }
        if taken < K {
            sel[taken] = (p, d.max(0.0));
            taken += 1;
        }
        usable += 1;
    }
    (sel, taken, usable)
}

/// `Ok(p)` if both coordinates are finite, else degenerate.
fn finite(p: Point) -> Result<Point, LocError> {
    if p.x.is_finite() && p.y.is_finite() {
        Ok(p)
    } else {
        Err(LocError::DegenerateGeometry)
    }
}

/// Whether the triangle `a b c` is proper: twice its area exceeds `DEGENERATE_TOL · L²`.
fn proper_triangle(a: Point, b: Point, c: Point) -> bool {
    let (ux, uy) = (b.x - a.x, b.y - a.y);
    let (vx, vy) = (c.x - a.x, c.y - a.y);
    let (wx, wy) = (c.x - b.x, c.y - b.y);
    let l2 = (ux * ux + uy * uy)
        .max(vx * vx + vy * vy)
        .max(wx * wx + wy * wy);
    // NaN-safe: a NaN or infinite comparison is not "proper".
    (ux * vy - uy * vx).abs() > DEGENERATE_TOL * l2 && l2.is_finite()
}

/// Whether some three of the anchors form a proper triangle.
fn any_proper_triangle(sel: &[(Point, f64)]) -> bool {
    let n = sel.len();
    (0..n).any(|i| {
        (i + 1..n).any(|j| (j + 1..n).any(|k| proper_triangle(sel[i].0, sel[j].0, sel[k].0)))
    })
}

/// The trilateration of three `(anchor, distance)` pairs.
fn solve3(a1: (Point, f64), a2: (Point, f64), a3: (Point, f64)) -> Result<Point, LocError> {
    let ((p1, d1), (p2, d2), (p3, d3)) = (a1, a2, a3);
    if !proper_triangle(p1, p2, p3) {
        return Err(LocError::DegenerateGeometry);
    }
    // Relative to p1: u = x − p1, bᵢ = pᵢ − p1; bᵢ·u = ½ (|bᵢ|² + d₁² − dᵢ²).
    let (b2x, b2y) = (p2.x - p1.x, p2.y - p1.y);
    let (b3x, b3y) = (p3.x - p1.x, p3.y - p1.y);
    let r2 = 0.5 * (b2x * b2x + b2y * b2y + (d1 - d2) * (d1 + d2));
    let r3 = 0.5 * (b3x * b3x + b3y * b3y + (d1 - d3) * (d1 + d3));
    let det = b2x * b3y - b2y * b3x;
    let ux = (r2 * b3y - r3 * b2y) / det;
    let uy = (b2x * r3 - b3x * r2) / det;
    finite(Point::new(p1.x + ux, p1.y + uy))
}

/// A similarity transform `x ↦ c_to + s·R·(x − c_from)`.
struct Similarity {
    /// Centroid of the relative coordinates.
    from: (f64, f64),
    /// Centroid of the anchor positions.
    to: (f64, f64),
    /// `s·R`, row-major.
    sr: [[f64; 2]; 2],
}

impl Similarity {
    fn apply(&self, x: f64, y: f64) -> Point {
        let (dx, dy) = (x - self.from.0, y - self.from.1);
        Point::new(
            self.to.0 + self.sr[0][0] * dx + self.sr[0][1] * dy,
            self.to.1 + self.sr[1][0] * dx + self.sr[1][1] * dy,
        )
    }
}

/// The least-squares similarity (scale, rotation or reflection, translation) mapping `rel(i)`
/// onto `sel[i].0` over the anchors.
///
/// With centred coordinates `xᵢ` (relative) and `yᵢ` (true) and the cross-covariance
/// `C = Σ yᵢ xᵢᵀ`, the best orthogonal `R` maximises `tr(RᵀC)`: it is the polar factor of `C`. A
/// 2×2 matrix splits uniquely into a scaled rotation `[[p, −q], [q, p]]` plus a scaled reflection
/// `[[r, t], [t, −r]]`; with `h₁ = |(p, q)|`, `h₂ = |(r, t)|` its singular values are `h₁ + h₂` and
/// `|h₁ − h₂|`, and the polar factor is the normalised rotation part if `h₁ > h₂` (det +1), the
/// normalised reflection part if `h₂ > h₁` (det −1). Then `tr(RᵀC) = 2·max(h₁, h₂)` and the scale
/// is `s = tr(RᵀC) / Σ|xᵢ|²`. `h₁ ≈ h₂` (a rank-deficient `C`: either configuration collinear)
/// leaves the reflection undetermined → degenerate.
fn procrustes(
    sel: &[(Point, f64)],
    rel: impl Fn(usize) -> (f64, f64),
) -> Result<Similarity, LocError> {
    let n = sel.len() as f64;
    let (mut fx, mut fy, mut tx, mut ty) = (0.0, 0.0, 0.0, 0.0);
    for (i, &(p, _)) in sel.iter().enumerate() {
        let (x, y) = rel(i);
        fx += x;
        fy += y;
        tx += p.x;
        ty += p.y;
    }
    let (fx, fy, tx, ty) = (fx / n, fy / n, tx / n, ty / n);
    let mut c = [[0.0f64; 2]; 2];
    let mut sxx = 0.0;
    for (i, &(p, _)) in sel.iter().enumerate() {
        let (x, y) = rel(i);
        let (xc, yc) = ([x - fx, y - fy], [p.x - tx, p.y - ty]);
        for (row, &yv) in c.iter_mut().zip(&yc) {
            for (e, &xv) in row.iter_mut().zip(&xc) {
                *e += yv * xv;
            }
        }
        sxx += xc[0] * xc[0] + xc[1] * xc[1];
    }
    let (p, q) = (0.5 * (c[0][0] + c[1][1]), 0.5 * (c[1][0] - c[0][1]));
    let (r, t) = (0.5 * (c[0][0] - c[1][1]), 0.5 * (c[0][1] + c[1][0]));
    let (h1, h2) = (libm::hypot(p, q), libm::hypot(r, t));
    // NaN-safe: fails unless the small singular value is clearly non-zero.
    if !((h1 - h2).abs() > DEGENERATE_TOL * (h1 + h2) && sxx > 0.0) {
        return Err(LocError::DegenerateGeometry);
    }
    // s·R = (2·h / sxx) · (part / h) = part · 2 / sxx.
    let k = 2.0 / sxx;
    let sr = if h1 > h2 {
        [[p * k, -q * k], [q * k, p * k]]
    } else {
        [[r * k, t * k], [t * k, -r * k]]
    };
    Ok(Similarity {
        from: (fx, fy),
        to: (tx, ty),
        sr,
    })
}

/// Eigen-decomposition of the symmetric leading `m×m` block of `a` by cyclic Jacobi rotations.
///
/// Returns the eigenvalues (unsorted) and the eigenvectors as the columns of the second array
/// (`v[i][k]`: component `i` of eigenvector `k`); `a` is overwritten (diagonalised). Stops when
/// the off-diagonal mass is below `1e-30` of the total (squared), or after [`MAX_SWEEPS`] sweeps.
fn jacobi_eigen(a: &mut [[f64; MDS_N]; MDS_N], m: usize) -> ([f64; MDS_N], [[f64; MDS_N]; MDS_N]) {
    let m = m.min(MDS_N);
    let mut v = [[0.0f64; MDS_N]; MDS_N];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for _ in 0..MAX_SWEEPS {
        let (mut off, mut total) = (0.0f64, 0.0f64);
        for (i, row) in a.iter().enumerate().take(m) {
            for (j, &e) in row.iter().enumerate().take(m) {
                total += e * e;
                if i != j {
                    off += e * e;
                }
            }
        }
        // Also stops on non-finite input (`total` finite implies `off` finite).
        if !total.is_finite() || off <= 1e-30 * total {
            break;
        }
        for p in 0..m {
            for q in p + 1..m {
                let apq = a[p][q];
                if apq == 0.0 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * apq);
                let sign = if theta >= 0.0 { 1.0 } else { -1.0 };
                let t = sign / (theta.abs() + libm::hypot(theta, 1.0));
                let c = 1.0 / libm::sqrt(t * t + 1.0);
                let s = t * c;
                // A ← A·J (columns p, q), then Jᵀ·A (rows p, q); V ← V·J.
                for row in a.iter_mut().take(m) {
                    let (kp, kq) = (row[p], row[q]);
                    row[p] = c * kp - s * kq;
                    row[q] = s * kp + c * kq;
                }
                let (rp, rq) = (a[p], a[q]);
                for (k, (&pk, &qk)) in rp.iter().zip(&rq).enumerate().take(m) {
                    a[p][k] = c * pk - s * qk;
                    a[q][k] = s * pk + c * qk;
                }
                a[p][q] = 0.0;
                a[q][p] = 0.0;
                for row in v.iter_mut().take(m) {
                    let (kp, kq) = (row[p], row[q]);
                    row[p] = c * kp - s * kq;
                    row[q] = s * kp + c * kq;
                }
            }
        }
    }
    let mut eval = [0.0f64; MDS_N];
    for (k, e) in eval.iter_mut().enumerate().take(m) {
        *e = a[k][k];
    }
    (eval, v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic symmetric matrix.
    #[allow(clippy::needless_range_loop)] // symmetric fill: a[i][j] and a[j][i]
    fn sym(m: usize, seed: u64) -> [[f64; MDS_N]; MDS_N] {
        let mut s = seed;
        let mut a = [[0.0; MDS_N]; MDS_N];
        for i in 0..m {
            for j in i..m {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let x = (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
                a[i][j] = x;
                a[j][i] = x;
            }
        }
        a
    }

    #[test]
    fn jacobi_diagonalises_and_vectors_are_orthonormal() {
        for m in 1..=MDS_N {
            for seed in 0..5 {
                let a0 = sym(m, seed);
                let mut a = a0;
                let (eval, v) = jacobi_eigen(&mut a, m);
                for k in 0..m {
                    // A v = λ v
                    for i in 0..m {
                        let av: f64 = (0..m).map(|j| a0[i][j] * v[j][k]).sum();
                        assert!((av - eval[k] * v[i][k]).abs() < 1e-12, "m={m} k={k} i={i}");
                    }
                    // orthonormal columns
                    for l in 0..m {
                        let dot: f64 = (0..m).map(|i| v[i][k] * v[i][l]).sum();
                        let want = if k == l { 1.0 } else { 0.0 };
                        assert!((dot - want).abs() < 1e-12);
                    }
                }
                // trace preserved
                let tr: f64 = (0..m).map(|i| a0[i][i]).sum();
                let se: f64 = eval[..m].iter().sum();
                assert!((tr - se).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn jacobi_handles_repeated_and_zero_eigenvalues() {
        // diag(2, 2, 0) rotated: eigenvalues 2, 2, 0.
        let mut a = [[0.0; MDS_N]; MDS_N];
        a[0][0] = 2.0;
        a[1][1] = 1.0;
        a[2][2] = 1.0;
        a[1][2] = 1.0;
        a[2][1] = 1.0;
        let (eval, _) = jacobi_eigen(&mut a, 3);
        let mut e = [eval[0], eval[1], eval[2]];
        e.sort_by(f64::total_cmp);
        assert!((e[0]).abs() < 1e-15 && (e[1] - 2.0).abs() < 1e-15 && (e[2] - 2.0).abs() < 1e-15);
    }

    #[test]
    fn jacobi_stops_on_non_finite_input() {
        let mut a = sym(5, 1);
        a[1][2] = f64::NAN;
        a[2][1] = f64::NAN;
        let _ = jacobi_eigen(&mut a, 5);
    }

    #[test]
    fn procrustes_recovers_a_reflection() {
        // True anchors; relative coordinates are the mirror image (x ↦ −x), halved and shifted.
        let sel = [
            (Point::new(0.0, 0.0), 0.0),
            (Point::new(4.0, 0.0), 0.0),
            (Point::new(1.0, 3.0), 0.0),
        ];
        let rel = |i: usize| (-sel[i].0.x * 0.5 + 7.0, sel[i].0.y * 0.5 - 1.0);
        let f = procrustes(&sel, rel).unwrap();
        // det(sR) < 0, and it maps rel back onto the anchors.
        let det = f.sr[0][0] * f.sr[1][1] - f.sr[0][1] * f.sr[1][0];
        assert!((det + 4.0).abs() < 1e-12, "det {det}");
        for (i, &(p, _)) in sel.iter().enumerate() {
            let (x, y) = rel(i);
            assert!(f.apply(x, y).dist(p) < 1e-12);
        }
    }
}
