//! Grid MLE and MMSE in fixed point: [`crate::grid`]'s searches on the same lattice.
//!
//! Costs are `C' = C/K²` in Q.20 log2² units, `u32`, saturating at `u32::MAX − 1`; see the
//! module docs of [`crate::fixed`]. The searches mirror [`crate::grid`]'s step by step (same scan
//! order, same strict `<`, same multi-start ranking, descent and budget), so they make the same
//! decisions whenever the costs order the same way. Every cost of a search is computed the same
//! way wherever it is evaluated (one shift per anchor per search, see
//! [`offset_square`](super::offset_square)), so a point costs the same in the coarse grid and in
//! a window. Two exact shortcuts:
//!
//! * a cost evaluation stops as soon as its partial sum reaches the value it must beat (the
//!   terms are non-negative, so the comparison's outcome is already known); the anchors are
//!   summed strongest first, whose term grows fastest, and the coarse stage starts from the cost
//!   of a guessed coarse point, so that this happens early (ties still go where the scan puts
//!   them);
//! * the thesis' fine window skips the coarse points inside it: they cost at least as much as
//!   the coarse winner the window starts from, so under a strict `<` they never win. (The
//!   windowed MMSE evaluates them: they need their weights.)
//!
//! Every window is evaluated a column at a time by a [`ColumnKernel`]; the functions without
//! `_with` use [`Native`] (the assembly one on the ATmega328P, the portable one elsewhere), and
//! the `_with` ones take the kernel as a type parameter.

use super::column::{AnchorTerm, ColumnJob, ColumnKernel, Native, I24};
use super::math::{div_shl, exp2_neg_q26, log2_q20, mul_hi};
use super::refine::observations;
use super::{AreaCm, Measurements, Obs, Observations, OnlineParams, PathLoss, PointMm, Refinement};
use crate::grid::{Search, COARSE_DIVS, FINE_DIVS};
use crate::{LocError, MAX_ANCHORS};
use core::marker::PhantomData;

/// Fine steps per coarse step.
const RATIO: usize = FINE_DIVS / COARSE_DIVS;
/// Rows (and columns) of a search window: ± one coarse step of the thesis' lattice.
pub const WINDOW_ROWS: usize = 2 * RATIO + 1;
/// Rows a column of a search holds: a window's or the coarse grid's, whichever is more.
const COLUMN_ROWS: usize = if WINDOW_ROWS > COARSE_DIVS + 1 {
    WINDOW_ROWS
} else {
    COARSE_DIVS + 1
};
/// Coarse starting points of [`Search::MultiStart`].
const STARTS: usize = 4;
/// Most cost evaluations [`Search::MultiStart`] may spend: the thesis search's worst case.
const BUDGET: usize = (COARSE_DIVS + 1) * (COARSE_DIVS + 1) + WINDOW_ROWS * WINDOW_ROWS;
/// [`COARSE_DIVS`], [`FINE_DIVS`], [`RATIO`] as `u8` (the searches' indices).
const C8: u8 = COARSE_DIVS as u8;
const F8: u8 = FINE_DIVS as u8;
const R8: u8 = RATIO as u8;
/// Evaluations of the coarse stage: the guessed point, then the coarse points.
const COARSE_EVALS: u16 = 1 + (C8 as u16 + 1) * (C8 as u16 + 1);
/// "No cost yet" (every real cost is below it).
const INF: u32 = u32::MAX;
/// Largest real cost.
const COST_MAX: u32 = u32::MAX - 1;

// What the lattice's integer types take: indices in a `u8`, a window's rows and a coarse
// column's in the kernel's 16-bit skip mask, a window's posterior sums in `u32` (weights Q.20).
const _: () = {
    assert!(FINE_DIVS.is_multiple_of(COARSE_DIVS) && RATIO >= 1);
    assert!(FINE_DIVS + RATIO <= 255);
    assert!(COLUMN_ROWS <= 16);
    assert!(((WINDOW_ROWS * WINDOW_ROWS * WINDOW_ROWS) as u64) << 20 < 1 << 32);
};

/// `log2((1 cm)²)` in lattice units (`1/FINE_DIVS` cm), Q.20: the model's 1 cm clamp
/// ([`crate::model::MIN_DISTANCE`]).
pub const LOG2_CLAMP: i32 = log2_q20(FINE_DIVS as u64 * FINE_DIVS as u64);
/// `log2((1 m)²)` in lattice units, Q.20.
pub const LOG2_M2: i32 = log2_q20((100 * FINE_DIVS as u64) * (100 * FINE_DIVS as u64));

/// Which estimator produced a fixed-point fix.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Estimator {
    /// Maximum likelihood with this search.
    Mle(Search),
    /// Posterior mean over the whole lattice with this shadowing σ, Q.8 dB (0: the σ → 0 limit,
    /// the mean of the lattice minimisers).
    Mmse {
        /// σ, Q.8 dB.
        sigma: u16,
    },
    /// Posterior mean over the thesis' fine window around the coarse winner ([`mmse_window`]),
    /// σ as in [`Estimator::Mmse`] (0: the mean of the window's minimisers): the sink's MMSE.
    MmseWindow {
        /// σ, Q.8 dB.
        sigma: u16,
    },
}

/// A fixed-point position estimate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Estimate {
    /// The position, mm (inside the area).
    pub pos: PointMm,
    /// Fine-lattice indices `(i, j)` of the MLE fix (for MMSE: of the smallest cost seen; for the
    /// windowed MMSE: of the window's smallest cost, ties to the coarse winner).
    pub lattice: (u8, u8),
    /// Smallest cost found including the observations' constant part, Q.8 dB², saturating.
    pub min_cost: u32,
    /// The estimator that produced it.
    pub estimator: Estimator,
    /// Anchors used.
    pub anchors: u8,
    /// Scalar measurements behind the cost (sum of the observation weights).
    pub total_weight: u8,
    /// Cost evaluations spent (an evaluation that stopped early counts).
    pub evaluations: u16,
}

impl Estimate {
    /// A placeholder to be overwritten (storage for [`mle_and_mmse_window_into`]): at the
    /// origin, a thesis MLE, all counts 0.
    pub const NONE: Estimate = Estimate {
        pos: PointMm { x: 0, y: 0 },
        lattice: (0, 0),
        min_cost: 0,
        estimator: Estimator::Mle(Search::Thesis),
        anchors: 0,
        total_weight: 0,
        evaluations: 0,
    };
}

/// A lattice point (fine indices) and its cost.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct LatticeMin {
    i: u8,
    j: u8,
    /// Its cost ([`INF`]: none yet).
    cost: u32,
}

impl LatticeMin {
    const NONE: LatticeMin = LatticeMin {
        i: 0,
        j: 0,
        cost: INF,
    };

    /// Takes `(i, j)` if `c` is strictly smaller (ties keep the earlier point).
    #[inline]
    fn offer(&mut self, i: u8, j: u8, c: u32) {
        if c < self.cost {
            *self = LatticeMin { i, j, cost: c };
        }
    }
}

/// Cost evaluations of the thesis search with coarse winner `(i, j)` (fine indices):
/// `[MLE, windowed MMSE]`. The coarse stage spends [`COARSE_EVALS`] (the guess and the coarse
/// points); the window is `(RATIO·n − RATIO + 1)` columns by `(RATIO·m − RATIO + 1)` rows, `n`,
/// `m` the coarse columns and rows in it (3 inside, 2 at a side), and the MLE skips its `n·m`
/// coarse points. (Counted here, not in the loops.)
fn window_evals(i: u8, j: u8) -> [u16; 2] {
    let coarse_in = |c: u8| 1 + u8::from(c > 0) + u8::from(c < F8);
    let (n, m) = (coarse_in(i), coarse_in(j));
    let side = |k: u8| (R8 * k - R8 + 1) as u16;
    let all = COARSE_EVALS + side(n) * side(m);
    [all - (n * m) as u16, all]
}

/// What a search's setup derives from the model and the observations.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Setup {
    /// `|K|`, Q.26 (`K = 5·α·log10 2`); below `2^10` the cost is flat.
    k26: u32,
    /// The cost if flat (α = 0): `Σ w·(z − P0)²`, Q.8 dB², saturating.
    flat_cost: u32,
    /// The observations.
    anchors: u8,
    /// Their weights (wrapping).
    weight: u8,
}

/// `5·log10(2)`, Q.31.
const FIVE_LOG10_2_Q31: u32 = 3_232_284_966;

/// One search's state: the current window, the model's constants, the kernel's job and one
/// column of sums.
struct Grid<K> {
    /// The current window's first column and row (fine indices) and its rows.
    i0: u8,
    j0: u8,
    rows: u8,
    /// Evaluations (counted by the searches that cannot count them up front).
    evals: u16,
    s: Setup,
    job: ColumnJob,
    /// The last column's costs.
    sums: [u32; COLUMN_ROWS],
    kernel: PhantomData<K>,
}

impl<K: ColumnKernel> Grid<K> {
    /// No search yet: callers bind it and [`Grid::setup`] it in place (a grid returned by value
    /// is copied on an 8-bit MCU, and its stack is most of the sink's deepest frame).
    const EMPTY: Grid<K> = Grid {
        i0: 0,
        j0: 0,
        rows: 0,
        evals: 0,
        s: Setup {
            k26: 0,
            flat_cost: 0,
            anchors: 0,
            weight: 0,
        },
        job: ColumnJob::EMPTY,
        sums: [0; COLUMN_ROWS],
        kernel: PhantomData,
    };

    /// The search of `obs` under `model` within `area`, the window at the origin: `ρ` of every
    /// observation, the anchors strongest first, each anchor's shift ([`Grid::place`]).
    #[inline(never)]
    fn setup(&mut self, obs: &Observations, model: PathLoss, area: AreaCm) {
        (self.job.xstep, self.job.ystep) = (area.width, area.height);
        self.observe(obs.as_slice(), model);
    }

    /// `|K|`, the flat cost, the counts, and each observation's `ρ = (z − P0)/K − log2(1 m²)`
    /// (Q.20; `(z − P0)/K` clamped to ±2^30): `k26 = mul_hi(min(|α|, 2^29) << 3, 5·log10 2)`,
    /// `2^30/|K|` by [`div_shl`] (0 if flat), per observation `a = min(|z − P0|, 2^26 − 1) << 6`,
    /// the flat cost plus `w·(a >> 18)²` and `ρ = ±min(mul_hi(a, 2^30/|K|), 2^30) − log2(1 m²)`
    /// (negative when `z < P0` and α ≥ 0, or the reverse). The anchors go into the job sorted by
    /// `ρ`, largest first, ties in observation order. A flat cost ends with no anchors (every
    /// point costs the same).
    fn observe(&mut self, obs: &[Obs], model: PathLoss) {
        let s = &mut self.s;
        // |α| ≤ 32 (2^29 in Q.24): Q.27 fits a u32, and K < 48.2 in Q.26 too. (P0 needs no
        // clamp: |z − P0| is limited below.)
        s.k26 = mul_hi(
            model.alpha.unsigned_abs().min(1 << 29) << 3,
            FIVE_LOG10_2_Q31,
        );
        let flat = s.k26 < 1 << 10;
        // 2^30/|K| (saturating below |K| = 1/4, where only the flatness matters).
        let inv_k = if flat {
            0
        } else {
            div_shl(1 << 30, s.k26 >> 1, 25)
        };
        let obs = &obs[..obs.len().min(MAX_ANCHORS)];
        let mut rho = [0i32; MAX_ANCHORS];
        for (o, r) in obs.iter().zip(&mut rho) {
            let d = o.z.wrapping_sub(model.p0);
            // |z − P0| Q.16 (< 2^26) as Q.22, × 2^30/K → Q.20 (and Q.4 dB for the flat cost).
            let a = d.unsigned_abs().min((1 << 26) - 1) << 6;
            let q = a >> 18;
            s.flat_cost = s.flat_cost.saturating_add(q * q * (o.weight & 7) as u32);
            s.anchors = s.anchors.wrapping_add(1);
            s.weight = s.weight.wrapping_add(o.weight);
            let v = mul_hi(a, inv_k).min(1 << 30) as i32;
            *r = if (d < 0) != (model.alpha < 0) { -v } else { v } - LOG2_M2;
        }
        // Each anchor's place: those with a larger ρ before it, and the earlier ones with an
        // equal ρ (a stable sort, computed as ranks: no slots are moved).
        for (k, o) in obs.iter().enumerate() {
            let mut slot = 0;
            for (m, &r) in rho[..obs.len()].iter().enumerate() {
                if r > rho[k] || (r == rho[k] && m < k) {
                    slot += 1;
                }
            }
            self.place(slot, o, rho[k]);
        }
        self.job.n = if flat { 0 } else { obs.len() as u8 };
    }

    /// Anchor `o` with `ρ = rho` into job slot `slot`: its offsets from the window at the origin
    /// (`−FINE_DIVS·x`, `−FINE_DIVS·y` lattice units), its shift (the fewest bits that bring its
    /// offsets from anywhere in the area below 2^16), then `ρ` and the clamp corrected by the
    /// shift (`log2 d²` drops by `2·shift`), and its weight (1 to 3 kept, anything else 4).
    fn place(&mut self, slot: usize, o: &Obs, rho: i32) {
        const F: i32 = FINE_DIVS as i32;
        let (xm, ym) = (F * self.job.xstep as i32, F * self.job.ystep as i32);
        let (dx0, dy0) = (-F * o.pos.x as i32, -F * o.pos.y as i32);
        let m = (dx0.unsigned_abs().max((dx0 + xm).unsigned_abs()))
            .max(dy0.unsigned_abs().max((dy0 + ym).unsigned_abs()));
        let mut shift = 0;
        while m >> shift > 65534 {
            shift += 1;
        }
        let sh = (shift as i32) << 21;
        let Some(t) = self.job.anchors.get_mut(slot) else {
            return;
        };
        *t = AnchorTerm {
            dx2: 0,
            dx0: I24::new(dx0),
            dy0: I24::new(dy0),
            lclamp: LOG2_CLAMP - sh,
            rho: rho + sh,
            w: if (1..=3).contains(&o.weight) {
                o.weight
            } else {
                4
            },
            shift,
        };
    }

    fn flat(&self) -> bool {
        self.job.n == 0
    }

    /// Moves the window to first column `i0`, first row `j0`, `rows` rows `stride` fine rows
    /// apart: every used anchor's offsets plus the steps, wrapping at 24 bits.
    #[inline(never)]
    fn window(&mut self, i0: u8, j0: u8, stride: u8, rows: u8) {
        // (Indices ≤ FINE_DIVS: the moves fit an i8 times a step; |offsets| < 2^23 anywhere in
        // the area: 24 bits hold them.)
        let dx = self.job.xstep as i32 * i0.wrapping_sub(self.i0) as i8 as i32;
        let dy = self.job.ystep as i32 * j0.wrapping_sub(self.j0) as i8 as i32;
        let n = (self.job.n as usize).min(MAX_ANCHORS);
        for t in &mut self.job.anchors[..n] {
            t.dx0.add(dx);
            t.dy0.add(dy);
        }
        (self.i0, self.j0, self.rows) = (i0, j0, rows);
        self.job.stride = stride;
    }

    /// The window's sums in use.
    fn sums(&self) -> &[u32] {
        &self.sums[..(self.rows as usize).min(COLUMN_ROWS)]
    }

    /// The costs of column `i`'s rows into the sums (rows whose bit is set in `skip` are not
    /// evaluated and get [`INF`]). A row whose sum reaches `min(bound, COST_MAX)` is set to it:
    /// it is then `≥ bound`, which is all a comparison with `bound` needs to know, and with no
    /// bound ([`INF`]) it is the cost saturated at [`COST_MAX`].
    #[inline(never)]
    fn column(&mut self, i: u8, bound: u32, skip: u16) {
        self.job.col = i.wrapping_sub(self.i0);
        self.job.bound = bound.min(COST_MAX);
        self.job.skip = skip;
        let rows = (self.rows as usize).min(COLUMN_ROWS);
        K::column(&mut self.sums[..rows], &mut self.job);
    }

    /// Takes the last column's first smallest cost (column `i`) into `best` if it is below
    /// `bound` (which the column was evaluated with, or a smaller one).
    fn take(&self, i: u8, bound: u32, best: &mut LatticeMin) {
        if self.job.min < bound {
            *best = LatticeMin {
                i,
                j: self.j0.wrapping_add(self.job.min_row),
                cost: self.job.min,
            };
        }
    }

    /// The anchors' centroid weighted by `1/d̂² = 2^ρ` (to a power of two: the first anchor's
    /// 32, then halving per unit of `ρ` below the first's, none from 6 units below on), rounded
    /// to the coarse grid (no anchors: `(0, 0)`); the window at the origin. The coarse stage's
    /// first point: any point gives the same result, a near one gives tighter bounds sooner.
    fn guess(&self) -> (u8, u8) {
        let a = self.job.used();
        // The sort key, ρ before the shift's correction.
        let key = |t: &AnchorTerm| t.rho.wrapping_sub((t.shift as i32) << 21);
        let top = a.first().map_or(0, key);
        // Σw ≤ 2^8; |Σw·x| < 2^29 (|x| < 2^21 lattice units in a search).
        let (mut sw, mut sx, mut sy) = (0i32, 0i32, 0i32);
        for t in a {
            let down = top.wrapping_sub(key(t)) as u32 >> 20;
            if down > 5 {
                break;
            }
            let up = 5 - down;
            sw += 1 << up;
            sx = sx.wrapping_sub(t.dx0.get() << up);
            sy = sy.wrapping_sub(t.dy0.get() << up);
        }
        (snap(sx, self.job.xstep, sw), snap(sy, self.job.ystep, sw))
    }

    /// The thesis' coarse stage: the coarse grid (the window at the origin, stride [`RATIO`])
    /// with the reference's outcome (`i` outer, strict `<`), the coarse point `(gi, gj)`
    /// evaluated first: its cost bounds every column's evaluations from the start (the same
    /// result from any start). Up to the best point's column a tie comes first in the
    /// reference's scan: those columns are bounded one above the best cost.
    fn coarse_from(&mut self, gi: u8, gj: u8) -> LatticeMin {
        self.window(0, 0, R8, C8 + 1);
        self.column(gi * R8, INF, !(1 << gj));
        let mut best = LatticeMin {
            i: gi * R8,
            j: gj * R8,
            cost: self.sums[(gj as usize).min(COARSE_DIVS)],
        };
        let mut i = 0;
        while i <= F8 {
            let bound = if i <= best.i {
                best.cost.saturating_add(1)
            } else {
                best.cost
            };
            self.column(i, bound, 0);
            self.take(i, bound, &mut best);
            i += R8;
        }
        best
    }

    /// [`Grid::coarse_from`] the [`Grid::guess`]. ([`COARSE_EVALS`] evaluations.)
    fn coarse(&mut self) -> LatticeMin {
        let (gi, gj) = self.guess();
        self.coarse_from(gi, gj)
    }

    /// Moves the window to the thesis' fine window (± one coarse step, clipped) around `best`;
    /// returns its last column.
    fn fine_window(&mut self, best: &LatticeMin) -> u8 {
        let (i0, j0) = (best.i.saturating_sub(R8), best.j.saturating_sub(R8));
        let i1 = best.i.saturating_add(R8).min(F8);
        let rows = best.j.saturating_add(R8).min(F8) - j0 + 1;
        self.window(i0, j0, 1, rows);
        i1
    }

    /// The thesis MLE in the fine window around the coarse winner `best`, into `best`: strict
    /// `<` from it, skipping the window's coarse points (they cannot beat it).
    fn fine_mle(&mut self, best: &mut LatticeMin) {
        let i1 = self.fine_window(best);
        // The window's coarse rows (j a multiple of RATIO; `j0` is one).
        let mut coarse = 0u16;
        let mut r = 0;
        while r < self.rows {
            coarse |= 1 << r;
            r += R8;
        }
        let mut i = self.i0;
        while i <= i1 {
            let mask = if i.is_multiple_of(R8) { coarse } else { 0 };
            self.column(i, best.cost, mask);
            self.take(i, best.cost, best);
            i += 1;
        }
    }

    /// The thesis' fine window around the coarse winner `best` with the windowed posterior:
    /// each column evaluated up to the posterior's bound or `best`'s cost if larger, added to
    /// `post`, and its first strictly smaller cost taken into `best`. The same MLE as
    /// [`Grid::fine_mle`] (a coarse point is never strictly below the coarse winner), and every
    /// cost that has a weight exact.
    fn fine_post(&mut self, best: &mut LatticeMin, post: &mut Posterior) {
        let i1 = self.fine_window(best);
        let mut i = self.i0;
        while i <= i1 {
            self.column(i, post.bound().max(best.cost), 0);
            post.add_column(self.sums(), i - self.i0);
            self.take(i, best.cost, best);
            i += 1;
        }
    }

    /// The thesis search; its evaluations into `evals`.
    fn thesis(&mut self) -> LatticeMin {
        let mut best = self.coarse();
        self.evals = window_evals(best.i, best.j)[0];
        self.fine_mle(&mut best);
        best
    }

    fn multi_start(&mut self) -> LatticeMin {
        self.window(0, 0, R8, C8 + 1);
        let mut top = [LatticeMin::NONE; STARTS];
        let mut i = 0;
        while i <= F8 {
            self.column(i, top[STARTS - 1].cost, 0);
            for r in 0..=C8 {
                self.evals += 1;
                let c = self.sums[r as usize];
                if let Some(k) = top.iter().position(|t| c < t.cost) {
                    top.copy_within(k..STARTS - 1, k + 1);
                    top[k] = LatticeMin {
                        i,
                        j: r * R8,
                        cost: c,
                    };
                }
            }
            i += R8;
        }
        let mut best = top[0];
        let mut spent = (COARSE_DIVS + 1) * (COARSE_DIVS + 1);
        for start in top.iter().filter(|t| t.cost < INF) {
            let end = self.descend(*start, &mut spent);
            best.offer(end.i, end.j, end.cost);
        }
        best
    }

    /// Steepest descent over the 8 fine neighbours, exactly as [`crate::grid`]'s `descend`
    /// (same scan order, same skipped points, same budget check before every evaluation).
    fn descend(&mut self, from: LatticeMin, spent: &mut usize) -> LatticeMin {
        let mut cur = from;
        let mut prev: Option<(u8, u8)> = None;
        loop {
            let mut next = cur;
            let (i0, j0) = (cur.i.saturating_sub(1), cur.j.saturating_sub(1));
            let i1 = (cur.i + 1).min(F8);
            let rows = (cur.j + 1).min(F8) - j0 + 1;
            self.window(i0, j0, 1, rows);
            for i in i0..=i1 {
                let (mut skip, mut candidates, mut over) = (0u16, 0, false);
                for r in 0..rows {
                    let j = j0 + r;
                    let known = (i, j) == (cur.i, cur.j)
                        || prev.is_some_and(|(pi, pj)| pi.abs_diff(i) <= 1 && pj.abs_diff(j) <= 1);
                    if known {
                        skip |= 1 << r;
                    } else if *spent + candidates >= BUDGET {
                        // The reference returns at this candidate, before evaluating it.
                        skip |= 1 << r;
                        over = true;
                    } else {
                        candidates += 1;
                    }
                }
                if candidates > 0 {
                    self.column(i, next.cost, skip);
                    for r in 0..rows {
                        if skip & (1 << r) == 0 {
                            *spent += 1;
                            self.evals += 1;
                            next.offer(i, j0 + r, self.sums[r as usize]);
                        }
                    }
                }
                if over {
                    return next;
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

    /// Every lattice point, in bands of [`WINDOW_ROWS`] rows; ties go to the first point in
    /// x-major order, as in the reference's single scan.
    fn exhaustive(&mut self) -> LatticeMin {
        let mut best = LatticeMin::NONE;
        for j0 in (0..=F8).step_by(WINDOW_ROWS) {
            let rows = (j0 + WINDOW_ROWS as u8 - 1).min(F8) - j0 + 1;
            self.window(0, j0, 1, rows);
            for i in 0..=F8 {
                self.column(i, best.cost.saturating_add(1), 0);
                for r in 0..rows {
                    self.evals += 1;
                    let (j, c) = (j0 + r, self.sums[r as usize]);
                    if c < best.cost || (c == best.cost && (i, j) < (best.i, best.j)) {
                        best = LatticeMin { i, j, cost: c };
                    }
                }
            }
        }
        best
    }

    /// The estimate at `best`'s lattice point with its cost, `evals` and `estimator`.
    fn estimate(
        &self,
        obs: &Observations,
        area: AreaCm,
        best: &LatticeMin,
        evals: u16,
        estimator: Estimator,
    ) -> Estimate {
        let cost = if self.flat() {
            self.s.flat_cost
        } else {
            // C = K²·C': K² Q.20 (< 2^32) × C' Q.20 → Q.8.
            mul_hi(best.cost, mul_hi(self.s.k26, self.s.k26))
        };
        Estimate {
            pos: PointMm {
                x: to_mm(area.width, best.i, 0),
                y: to_mm(area.height, best.j, 0),
            },
            lattice: (best.i, best.j),
            min_cost: cost.saturating_add(obs.const_cost),
            estimator,
            anchors: self.s.anchors,
            total_weight: self.s.weight,
            evaluations: evals,
        }
    }
}

/// The coarse index `c ≤ COARSE_DIVS` of the weighted mean `s/sw` (lattice units) along a side
/// of `side` cm: `(c − ½)·RATIO·side < s/sw ≤ (c + ½)·RATIO·side`, found by steps (no division;
/// signed 32-bit comparisons).
fn snap(s: i32, side: u16, sw: i32) -> u8 {
    let t = RATIO as i32 * side as i32 * sw;
    let (mut c, mut v) = (0, t);
    while c < C8 && v < s.wrapping_mul(2) {
        c += 1;
        v += 2 * t;
    }
    c
}

/// Posterior weights `2^(−y)`, `y = (C' − C'ref)·β` in Q.16, relative to a reference cost
/// (see `Posterior`), for the search's `K` and σ.
///
/// With ΔC' in Q.20, `β = K²·log2(e)/(32σ²)·2^−4`. A weight is 0 from `ΔC' ≥ span` (`y ≥ 21`);
/// below it `ΔC'` is scaled below 2^16 (`a = ΔC' >> ra`) and `y = (a·b mod 2^32) >> 11` with one
/// 32-bit multiply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Weights {
    /// `C'` excess (Q.20) at or above which a weight is 0 (1 for σ = 0: only the minimisers).
    pub span: u32,
    /// `β·2^(11 + ra)`.
    pub b: u32,
    /// `a = ΔC' >> ra`, `a < 2^16`.
    pub ra: u8,
}

/// `log2(e)`, Q.31.
const LOG2_E_Q31: u32 = 3_098_164_009;
/// Posterior weights end at `2^−Y_CUT` of the largest (they are Q.20: smaller ones are 0).
const Y_CUT: u32 = 21;

impl Weights {
    /// The weights for `|K|` (Q.26) and σ (Q.8 dB); a flat cost's (`K < 2^−16`) are all equal,
    /// σ = 0's weigh only the minimisers. `y = (a·b) >> 11` is within `Y_CUT·2^−15` of exact
    /// (`a·b ≤ Y_CUT·2^27`).
    #[inline(never)]
    pub fn new(k26: u32, sigma_q8: u16) -> Weights {
        let mut w = Weights {
            span: 1,
            ra: 16,
            b: 0,
        };
        if sigma_q8 == 0 {
            return w;
        }
        w.span = u32::MAX;
        if k26 < 1 << 10 {
            return w;
        }
        // K² normalised (kk ∈ [2^30, 2^32) = K²·2^(20 + 2z)), then p = K²·log2(e)·2^(18 + 2z).
        let (mut kn, mut z) = (k26, 0);
        while kn >> 31 == 0 {
            kn <<= 1;
            z += 1;
        }
        let p = mul_hi(mul_hi(kn, kn), LOG2_E_Q31) >> 1;
        // span = Y_CUT·2^16/β = Y_CUT·σ_q8²·2^(23 + 2z)/p.
        let s2 = sigma_q8 as u32 * sigma_q8 as u32;
        w.span = div_shl(s2, p / Y_CUT, 23 + 2 * z).clamp(1, u32::MAX - 1);
        w.ra = 0;
        while w.span >> w.ra > 0xFFFF {
            w.ra += 1;
        }
        // b = β·2^(11 + ra) = p·2^(4 + ra − 2z)/σ_q8².
        let mut e = 4 + w.ra as i32 - 2 * z as i32;
        let (mut num, mut den) = (p, s2);
        if den >> 31 != 0 {
            den >>= 1;
            e -= 1;
        }
        if e < 0 {
            num = num.checked_shr(-e as u32).unwrap_or(0);
            e = 0;
        }
        w.b = div_shl(num, den, e as u32);
        w
    }

    /// Weight (Q.26) of a cost excess over the reference.
    #[inline(never)]
    pub fn weight(&self, excess: u32) -> u32 {
        if excess >= self.span {
            return 0;
        }
        let a = excess >> self.ra;
        exp2_neg_q26(a.wrapping_mul(self.b) >> 11)
    }
}

/// A window's posterior sums (offsets from its first column and row): weights Q.20 relative to
/// a reference cost `cref` that only ever decreases (the sums are rescaled when a lower cost
/// appears). In a search `Σw < 2^27`, `Σw·c` and `Σw·r < 2^31`: all `u32`.
#[derive(Clone, Copy, Debug)]
struct Posterior {
    /// The reference cost (Q.20): weights are relative to it.
    cref: u32,
    wts: Weights,
    /// `Σw` (Q.20)…
    s: u32,
    /// …`Σw·c`…
    sx: u32,
    /// …and `Σw·r`.
    sy: u32,
}

impl Posterior {
    /// No points yet, reference `cref`.
    fn new(wts: Weights, cref: u32) -> Posterior {
        Posterior {
            cref,
            wts,
            s: 0,
            sx: 0,
            sy: 0,
        }
    }

    /// The bound a column needs: costs from it on weigh nothing.
    fn bound(&self) -> u32 {
        self.cref.saturating_add(self.wts.span)
    }

    /// A window column's costs `sums` at column offset `col`: row `r`'s cost `v` (skipped if at
    /// least [`Posterior::bound`]) weighs `2^−y(v − cref)`; a cost below `cref` first becomes
    /// the reference, the sums so far scaled by the weight of the drop (`mul_hi`, Q.32 factor).
    /// Adds `w`, `w·col` and `w·r` (`w` Q.20).
    #[inline(never)]
    fn add_column(&mut self, sums: &[u32], col: u8) {
        let c = col as u32;
        for (r, &v) in sums.iter().enumerate() {
            if v >= self.bound() {
                continue;
            }
            if v < self.cref {
                // The sums so far, relative to the new reference: × 2^(−y(drop)), Q.32.
                let f = self.wts.weight(self.cref - v).min((1 << 26) - 1) << 6;
                self.s = mul_hi(self.s, f);
                self.sx = mul_hi(self.sx, f);
                self.sy = mul_hi(self.sy, f);
                self.cref = v;
            }
            let wt = self.wts.weight(v - self.cref) >> 6;
            self.s = self.s.wrapping_add(wt);
            self.sx = self.sx.wrapping_add(wt * c);
            self.sy = self.sy.wrapping_add(wt * r as u32);
        }
    }
}

/// `side·(o + f/2^12)/FINE_DIVS` cm in mm, rounded: fine index `o` plus a fraction
/// (`f ≤ WINDOW_ROWS·2^12`) along a side of `side` cm (as [`AreaCm::lattice_mm`] for `f = 0`),
/// from `n = 8·side·(o + f/2^12)` (Q.3, below 2^26).
#[inline(never)]
fn to_mm(side: u16, o: u8, f: u32) -> u32 {
    const D: u32 = 8 * FINE_DIVS as u32;
    let side = side as u32;
    let n = side * o as u32 * 8 + (side.wrapping_mul(f) >> 9);
    (10 * n + D / 2) / D
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
    area: AreaCm,
    search: Search,
) -> Result<Estimate, LocError> {
    mle_with::<Native>(obs, model, area, search)
}

/// [`mle`] with the column kernel `K` (same result).
pub fn mle_with<K: ColumnKernel>(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    search: Search,
) -> Result<Estimate, LocError> {
    check(obs)?;
    let mut g = Grid::<K>::EMPTY;
    g.setup(obs, model, area);
    let m = match search {
        Search::Thesis => g.thesis(),
        Search::MultiStart => g.multi_start(),
        Search::Exhaustive => g.exhaustive(),
    };
    Ok(g.estimate(obs, area, &m, g.evals, Estimator::Mle(search)))
}

/// Posterior-mean position of `obs` under `model` within `area` with shadowing σ (Q.8 dB).
///
/// The posterior mean over all lattice points, weights `exp(−cost/(2σ²))` relative to the
/// smallest cost (computed as `2^(−y)`: integer part a shift, fraction from the flash table; a
/// weight below `2^−20` of the largest is dropped, and the cost evaluation stops there), summed
/// window by window into 64-bit totals. The thesis search runs first to give a good reference
/// cost. Within 1 cm of [`crate::grid::mmse`]. (Host-sized: not for the sink.)
pub fn mmse(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    sigma: u16,
) -> Result<Estimate, LocError> {
    mmse_with::<Native>(obs, model, area, sigma)
}

/// [`mmse`] with the column kernel `K` (same result).
pub fn mmse_with<K: ColumnKernel>(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    sigma: u16,
) -> Result<Estimate, LocError> {
    check(obs)?;
    let mut g = Grid::<K>::EMPTY;
    g.setup(obs, model, area);
    let mut best = g.thesis();
    let wts = Weights::new(g.s.k26, sigma);
    let mut cref = best.cost;
    // Σw (< 2^32), Σw·i and Σw·j (< 2^38), relative to `cref`.
    let (mut s, mut sx, mut sy) = (0u64, 0u64, 0u64);
    const W: u8 = WINDOW_ROWS as u8;
    for j0 in (0..=F8).step_by(WINDOW_ROWS) {
        for i0 in (0..=F8).step_by(WINDOW_ROWS) {
            let rows = (j0 + W - 1).min(F8) - j0 + 1;
            g.window(i0, j0, 1, rows);
            let mut post = Posterior::new(wts, cref);
            for i in i0..=(i0 + W - 1).min(F8) {
                // The smallest cost so far is the reference: costs below it are exact.
                g.column(i, post.bound(), 0);
                g.evals += rows as u16;
                post.add_column(g.sums(), i - i0);
                g.take(i, best.cost, &mut best);
            }
            if post.cref < cref {
                let f = wts.weight(cref - post.cref) as u64;
                for v in [&mut s, &mut sx, &mut sy] {
                    *v = (*v >> 26) * f + (((*v & ((1 << 26) - 1)) * f) >> 26);
                }
                cref = post.cref;
            }
            s += post.s as u64;
            sx += post.sx as u64 + i0 as u64 * post.s as u64;
            sy += post.sy as u64 + j0 as u64 * post.s as u64;
        }
    }
    let mut e = g.estimate(obs, area, &best, g.evals, Estimator::Mmse { sigma });
    if s != 0 {
        // mm = 10·side·(Σw·i/Σw)/FINE_DIVS, rounded.
        let d = FINE_DIVS as u64 * s;
        let f = |side: u16, v: u64| ((10 * side as u64 * v + d / 2) / d) as u32;
        e.pos = PointMm {
            x: f(area.width, sx),
            y: f(area.height, sy),
        };
    }
    Ok(e)
}

/// Windowed posterior-mean position of `obs` under `model` within `area` with shadowing σ
/// (Q.8 dB): [`crate::grid::mmse_window`] in fixed point, the sink's MMSE.
///
/// The thesis' coarse stage picks the coarse winner, then the posterior mean runs over the
/// thesis' fine window around it (the coarse points in it evaluated again), weights as in
/// [`mmse`]: as many cost evaluations as the thesis search, but fewer of them stop early (a
/// weight needs the cost up to 21 bits of weight above the smallest, not just whether it beats
/// it). Its lattice point and cost are the thesis MLE's.
pub fn mmse_window(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    sigma: u16,
) -> Result<Estimate, LocError> {
    mmse_window_with::<Native>(obs, model, area, sigma)
}

/// [`mmse_window`] with the column kernel `K` (same result).
pub fn mmse_window_with<K: ColumnKernel>(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    sigma: u16,
) -> Result<Estimate, LocError> {
    let mut out = [Estimate::NONE; 2];
    mle_and_mmse_window_into::<K>(obs, model, area, sigma, &mut out)?;
    Ok(out[1])
}

/// The sink's two estimates from one search: `[mle (Search::Thesis), mmse_window]` with the
/// same arguments, bit for bit (the same [`Estimate`]s, evaluation counts included).
///
/// The windowed MMSE's window is the thesis' fine window around the same coarse winner, so the
/// coarse stage runs once and each window column once, for both: its costs are exact up to the
/// MMSE's bound (costs beyond weigh nothing), raised to the MLE's best cost when that is larger,
/// so every cost that could beat the MLE's best is exact too; the MLE's winner is then the
/// first strictly smallest from the coarse winner on, as in the thesis search (the window's
/// coarse points, which the thesis skips, never are).
pub fn mle_and_mmse_window(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    sigma: u16,
) -> Result<[Estimate; 2], LocError> {
    let mut out = [Estimate::NONE; 2];
    mle_and_mmse_window_into::<Native>(obs, model, area, sigma, &mut out)?;
    Ok(out)
}

/// [`mle_and_mmse_window`] by the column kernel `K`, into `out` (untouched on an error): the
/// caller's storage, so that a firmware keeps one copy of the results.
#[inline(never)]
pub fn mle_and_mmse_window_into<K: ColumnKernel>(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    sigma: u16,
    out: &mut [Estimate; 2],
) -> Result<(), LocError> {
    check(obs)?;
    let mut g = Grid::<K>::EMPTY;
    g.setup(obs, model, area);
    let mut post = Posterior::new(Weights::new(g.s.k26, sigma), 0);
    let coarse = g.coarse();
    post.cref = coarse.cost;
    let mut best = coarse;
    g.fine_post(&mut best, &mut post);
    let evals = window_evals(coarse.i, coarse.j);
    out[0] = g.estimate(obs, area, &best, evals[0], Estimator::Mle(Search::Thesis));
    // The same lattice point and cost; its own position and evaluations.
    out[1] = out[0];
    out[1].estimator = Estimator::MmseWindow { sigma };
    out[1].evaluations = evals[1];
    if post.s != 0 {
        out[1].pos = PointMm {
            x: to_mm(area.width, g.i0, div_shl(post.sx, post.s, 12)),
            y: to_mm(area.height, g.j0, div_shl(post.sy, post.s, 12)),
        };
    }
    Ok(())
}

/// `obs` located by `estimator`.
pub fn estimate(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    estimator: Estimator,
) -> Result<Estimate, LocError> {
    estimate_with::<Native>(obs, model, area, estimator)
}

/// [`estimate`] with the column kernel `K` (same result).
pub fn estimate_with<K: ColumnKernel>(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    estimator: Estimator,
) -> Result<Estimate, LocError> {
    match estimator {
        Estimator::Mle(search) => mle_with::<K>(obs, model, area, search),
        Estimator::Mmse { sigma } => mmse_with::<K>(obs, model, area, sigma),
        Estimator::MmseWindow { sigma } => mmse_window_with::<K>(obs, model, area, sigma),
    }
}

/// The agent of `m` located: channels combined by `refinement`, then `estimator`.
pub fn locate(
    m: &Measurements,
    refinement: Refinement,
    model: PathLoss,
    area: AreaCm,
    estimator: Estimator,
) -> Result<Estimate, LocError> {
    estimate(&observations(m, refinement), model, area, estimator)
}

/// One whole sink step: P0/α from `m`'s anchor-to-anchor bytes ([`OnlineParams::update`]: fit,
/// then AR(1); a round without calibration samples keeps the current model), then the agent
/// located with the smoothed model. For an MMSE with the fitted σ pass
/// `Estimator::MmseWindow { sigma: params.sigma().unwrap_or(fallback) }` after the update, or call
/// this with an MLE first.
pub fn sink_fix(
    m: &Measurements,
    area: AreaCm,
    params: &mut OnlineParams,
    refinement: Refinement,
    estimator: Estimator,
) -> Result<Estimate, LocError> {
    let stats = super::CalStats::from_measurements(m, None);
    match params.update(&stats) {
        Ok(_) | Err(LocError::NoCalibrationData) => {}
        Err(e) => return Err(e),
    }
    locate(m, refinement, params.current(), area, estimator)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixed::{Obs, PointCm, Portable};
    use std::vec::Vec;

    /// The reference's coarse scan: every coarse point's whole cost, `i` outer, strict `<`.
    fn plain_coarse(obs: &Observations, m: PathLoss, area: AreaCm) -> LatticeMin {
        let mut s = Grid::<Portable>::EMPTY;
        s.setup(obs, m, area);
        s.window(0, 0, R8, C8 + 1);
        let mut best = LatticeMin::NONE;
        for i in (0..=F8).step_by(RATIO) {
            s.column(i, INF, 0);
            for r in 0..=C8 {
                best.offer(i, r * R8, s.sums[r as usize]);
            }
        }
        best
    }

    #[test]
    fn the_lattice_constants_are_the_logs_they_name() {
        let q20 = |x: f64| libm::round(libm::log2(x) * (1 << 20) as f64) as i32;
        let f = FINE_DIVS as f64;
        assert_eq!(LOG2_CLAMP, q20(f * f));
        assert_eq!(LOG2_M2, q20(100.0 * f * 100.0 * f));
    }

    /// [`window_evals`] counts what the reference's thesis search evaluates: the coarse stage,
    /// then every point of the clipped fine window (the MLE: less its coarse ones).
    #[test]
    fn the_window_evaluations_are_counted_points() {
        for ci in 0..=C8 {
            for cj in 0..=C8 {
                let (i, j) = (ci * R8, cj * R8);
                let (mut all, mut coarse) = (0u16, 0u16);
                for wi in i.saturating_sub(R8)..=(i + R8).min(F8) {
                    for wj in j.saturating_sub(R8)..=(j + R8).min(F8) {
                        all += 1;
                        coarse += u16::from(wi % R8 == 0 && wj % R8 == 0);
                    }
                }
                let want = [COARSE_EVALS + all - coarse, COARSE_EVALS + all];
                assert_eq!(window_evals(i, j), want, "({ci}, {cj})");
            }
        }
    }

    fn obs(anchors: &[(i16, i16, i32)]) -> Observations {
        let v: Vec<Obs> = anchors
            .iter()
            .map(|&(x, y, z)| Obs {
                pos: PointCm::new(x, y),
                z: z << 16,
                weight: 2,
            })
            .collect();
        Observations::from_slice(&v)
    }

    #[test]
    fn the_coarse_stage_finds_the_first_minimum_from_any_start() {
        // (The flat model below ties every point.)
        let area = AreaCm::new(1000, 1000);
        let cases = [
            // Mirror-symmetric about x = 5 m: every cost has its twin, ties everywhere.
            obs(&[
                (0, 0, -62),
                (1000, 0, -62),
                (0, 1000, -75),
                (1000, 1000, -75),
            ]),
            obs(&[(0, 0, -50), (1000, 0, -50), (500, 1000, -70)]),
            // Flat in practice: every anchor equally far from everything.
            obs(&[
                (0, 0, -40),
                (1000, 0, -40),
                (1000, 1000, -40),
                (0, 1000, -40),
            ]),
            // Generic.
            obs(&[
                (0, 0, -64),
                (1000, 0, -68),
                (1000, 1000, -66),
                (0, 1000, -60),
            ]),
            obs(&[(-300, 200, -71), (1200, 0, -55), (400, 1500, -80)]),
        ];
        let flat = PathLoss {
            p0: -40 << 16,
            alpha: 0,
        };
        let models = [PathLoss::THESIS, flat];
        for o in &cases {
            for &m in &models {
                let want = plain_coarse(o, m, area);
                for gi in 0..=C8 {
                    for gj in 0..=C8 {
                        let mut s = Grid::<Portable>::EMPTY;
                        s.setup(o, m, area);
                        assert_eq!(s.coarse_from(gi, gj), want, "start ({gi}, {gj})");
                    }
                }
                let mut s = Grid::<Portable>::EMPTY;
                s.setup(o, m, area);
                assert_eq!(s.coarse(), want);
            }
        }
    }

    /// The anchors go into the job strongest (largest ρ) first, ties in observation order, for
    /// every count up to eight: the placement is a stable sort by ρ.
    #[test]
    fn anchors_are_placed_strongest_first_ties_in_order() {
        let area = AreaCm::new(1000, 800);
        let mut seed = 0x9E37_79B9u32;
        let mut next = |n: u32| {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed % n
        };
        for trial in 0..2000 {
            let n = 1 + next(MAX_ANCHORS as u32) as usize;
            let v: Vec<Obs> = (0..n)
                .map(|_| Obs {
                    pos: PointCm::new(next(1200) as i16 - 100, next(1000) as i16 - 100),
                    // Few distinct values: many ties.
                    z: -(40 + next(4) as i32) << 16,
                    weight: 1 + next(4) as u8,
                })
                .collect();
            let mut g = Grid::<Portable>::EMPTY;
            g.setup(&Observations::from_slice(&v), PathLoss::THESIS, area);
            let mut order: Vec<usize> = (0..n).collect();
            // Stronger = larger z = larger ρ for α > 0.
            order.sort_by_key(|&k| core::cmp::Reverse(v[k].z));
            for (slot, &k) in order.iter().enumerate() {
                let t = &g.job.anchors[slot];
                let want = I24::new(-(FINE_DIVS as i32) * v[k].pos.x as i32);
                assert_eq!(t.dx0, want, "trial {trial}, slot {slot}");
            }
        }
    }

    /// The windowed MMSE's incremental sums (a reference that drops, rescaled sums, 32-bit
    /// weights) against the posterior mean of the same window's exact costs with f64 weights:
    /// within 2 mm (the mm rounding, the 2^−y table, weights below 2^−21 dropped; worst ≈ 1 mm).
    #[test]
    fn the_windowed_posterior_is_the_direct_mean_of_the_window() {
        let mut seed = 0x1234_5678u32;
        let mut next = |n: u32| {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed % n
        };
        for t in 0..300 {
            let side = 300 + next(2700) as u16;
            let area = AreaCm::new(side, 300 + next(2700) as u16);
            let anchors: Vec<(i16, i16, i32)> = (0..3 + next(4))
                .map(|_| {
                    let x = next(area.width as u32 + 1) as i16;
                    let y = next(area.height as u32 + 1) as i16;
                    (x, y, -45 - next(40) as i32)
                })
                .collect();
            let o = obs(&anchors);
            let model = PathLoss::from_centi(-4000 - next(1000) as i32, 200 + next(250) as i32);
            let sigma = 64 + next(6 << 8) as u16;
            let got = mmse_window(&o, model, area, sigma).unwrap();
            // The same window, every cost exact (no bound).
            let mut g = Grid::<Portable>::EMPTY;
            g.setup(&o, model, area);
            let c = g.coarse();
            let i1 = g.fine_window(&c);
            let (i0, j0, rows) = (g.i0, g.j0, g.rows);
            let mut costs = Vec::new();
            for i in i0..=i1 {
                g.column(i, INF, 0);
                for r in 0..rows {
                    costs.push((i, j0 + r, g.sums[r as usize] as f64));
                }
            }
            let min = costs.iter().map(|c| c.2).fold(f64::MAX, f64::min);
            // y (log2 units) per Q.20 cost unit: K²·log2(e)/(2σ²) / 2^20.
            let k = 5.0 * core::f64::consts::LOG10_2 * model.alpha as f64 / (1 << 24) as f64;
            let sg = sigma as f64 / 256.0;
            let beta = k * k * core::f64::consts::LOG2_E / (2.0 * sg * sg) / (1 << 20) as f64;
            let (mut s, mut sx, mut sy) = (0.0, 0.0, 0.0);
            for &(i, j, c) in &costs {
                let w = libm::exp2(-(c - min) * beta);
                s += w;
                sx += w * i as f64;
                sy += w * j as f64;
            }
            let x = area.width as f64 * sx / s * 10.0 / FINE_DIVS as f64;
            let y = area.height as f64 * sy / s * 10.0 / FINE_DIVS as f64;
            assert!(
                (got.pos.x as f64 - x).abs() <= 2.0 && (got.pos.y as f64 - y).abs() <= 2.0,
                "trial {t}: {got:?} vs ({x:.1}, {y:.1})"
            );
        }
    }

    /// The sink's one search gives the thesis MLE and the windowed MMSE of their own searches.
    #[test]
    fn one_search_gives_both_estimates() {
        let mut seed = 0xDEAD_BEEFu32;
        let mut next = |n: u32| {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed % n
        };
        for _ in 0..300 {
            let area = AreaCm::new(200 + next(2000) as u16, 200 + next(2000) as u16);
            let anchors: Vec<(i16, i16, i32)> = (0..3 + next(6))
                .map(|_| {
                    let x = next(area.width as u32 + 400) as i16 - 200;
                    let y = next(area.height as u32 + 400) as i16 - 200;
                    (x, y, -40 - next(50) as i32)
                })
                .collect();
            let o = obs(&anchors);
            let model = PathLoss::from_centi(-3000 - next(3000) as i32, next(500) as i32);
            let sigma = next(8 << 8) as u16;
            let [a, b] = mle_and_mmse_window(&o, model, area, sigma).unwrap();
            assert_eq!(a, mle(&o, model, area, Search::Thesis).unwrap());
            let w = mmse_window(&o, model, area, sigma).unwrap();
            assert_eq!(b, w);
        }
    }
}
