//! Grid MLE and MMSE in fixed point ([`crate::grid`]'s searches on the same lattice).
//!
//! Costs are `C' = C/K²` in Q.20 log2² units, `u32`, saturating at [`COST_MAX`]; see the module
//! docs of [`crate::fixed`]. The searches mirror [`crate::grid::search_lattice`] step by step
//! (same outcome as the same scan order, same strict `<`, same multi-start ranking, descent and
//! budget), so they make the same decisions whenever the costs order the same way. Every cost of
//! a search is computed the same way wherever it is evaluated (one shift per anchor per search,
//! see [`crate::fixed::offset_square`]), so a point costs the same in the coarse grid and in a
//! window. Exact shortcuts:
//!
//! * a cost evaluation stops as soon as its partial sum reaches the value it must beat (the terms
//!   are non-negative, so the comparison's outcome is already known); the anchors are summed
//!   strongest first, whose term grows fastest, and the coarse stage starts from the cost of a
//!   guessed coarse point, so that this happens early (ties still go where the scan puts them);
//! * the thesis' fine window skips the coarse points inside it: they cost at least as much as the
//!   coarse winner the window starts from, so under a strict `<` they can never win. (The
//!   windowed MMSE evaluates them: they need their weights.)
//!
//! Size first (the sink links this, SPEC §8): one window routine for the thesis' window and the
//! sink's one-pass MLE + MMSE, 32-bit arithmetic only on the sink's path, the shared helpers out
//! of line. Stack too (the sink locates at its deepest): the grid set up in place, results
//! written into the caller's storage (a by-value struct is a copy on AVR), the sink's window
//! loop inlined into its one caller (a frame fewer).

use super::kernel::{
    log2_segment_base, ColumnJob, Placement, Portable, Posterior, TermKernel, Weights,
};
use super::refine::observations;
use super::{AreaCm, Measurements, Observations, OnlineParams, PathLoss, PointMm, Refinement};
use crate::grid::{Search, COARSE_DIVS, FINE_DIVS};
use crate::LocError;
use core::marker::PhantomData;

const RATIO: usize = FINE_DIVS / COARSE_DIVS;
/// Rows a search window holds: ± one coarse step.
const ROWS: usize = 2 * RATIO + 1;
/// Coarse starting points of [`Search::MultiStart`].
const STARTS: usize = 4;
/// Most cost evaluations [`Search::MultiStart`] may spend: the thesis search's worst case.
const BUDGET: usize = (COARSE_DIVS + 1) * (COARSE_DIVS + 1) + ROWS * ROWS;
/// "No cost yet" (every real cost is below it).
const INF: u32 = u32::MAX;
/// Largest real cost.
const COST_MAX: u32 = u32::MAX - 1;

/// `log2(1 m²)` in lattice units `(1/50 cm)²`: `log2(5000²)`, Q.20.
const LOG2_M2: i32 = 25_769_201;
/// `5·log10(2)`, Q.31.
const FIVE_LOG10_2_Q31: u32 = 3_232_284_966;

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
    /// A placeholder to be overwritten (the storage of [`mle_and_mmse_window_into`]'s
    /// results): all zero, at the origin, a thesis MLE.
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

/// The coarse index `c ≤ 10` of the weighted mean `s/sw` (lattice units) along a side of `side`
/// cm: `(c − ½)·5·side < s/sw ≤ (c + ½)·5·side`, found by steps (no division).
#[inline(never)]
fn snap(s: i32, side: i32, sw: i32) -> usize {
    // t < 5·2^16·2^8 < 2^27, so v ≤ 21·t < 2^31.
    let t = RATIO as i32 * side * sw;
    let (mut c, mut v) = (0, t);
    while c < COARSE_DIVS && v < 2 * s {
        c += 1;
        v += 2 * t;
    }
    c
}

/// A lattice point and its cost.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct LatticeMin {
    i: usize,
    j: usize,
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
    fn offer(&mut self, i: usize, j: usize, c: u32) {
        if c < self.cost {
            *self = LatticeMin { i, j, cost: c };
        }
    }
}

/// One estimate's search: the position-independent part of the cost (in the kernel's job: per
/// anchor `ρ`, weight, shift, offsets from the current window's origin), one column of sums, the
/// evaluations spent (240 bytes on AVR, most of the sink's search stack). `repr(C)`, the scalars and the job's header first: AVR
/// reaches 63 bytes from a pointer in one instruction, farther fields cost pointer arithmetic.
#[repr(C)]
struct Grid<K> {
    /// The current window's first column and row (fine indices) and its rows.
    i0: usize,
    j0: usize,
    rows: usize,
    evals: usize,
    /// `|K|` in Q.26 (`K = 5·α·log10 2`); below `2^10` the cost is flat (`job.n = 0`).
    k26: u32,
    /// P0, Q.16 dB (sane).
    p0: i32,
    job: ColumnJob,
    sums: [u32; ROWS],
    kernel: PhantomData<K>,
}

impl<K: TermKernel> Grid<K> {
    /// No anchors, all zero.
    const EMPTY: Self = Grid {
        i0: 0,
        j0: 0,
        rows: 0,
        evals: 0,
        k26: 0,
        p0: 0,
        job: ColumnJob::EMPTY,
        sums: [0; ROWS],
        kernel: PhantomData,
    };

    /// Sets the cost of `obs` up: `ρ = (z − P0)/K − log2(1 m²)` per anchor (Q.20, `(z − P0)/K`
    /// clamped to ±2^30), the anchors strongest (largest `ρ`) first, and each anchor's shift: the fewest
    /// bits that bring its offsets anywhere in the area below 2^16.
    /// (Callers bind [`Grid::EMPTY`] and set it up in place: a grid returned by value is
    /// copied on AVR, and two 240-byte grids on the stack are too many.)
    #[inline(never)]
    fn setup(&mut self, obs: &Observations, model: PathLoss, area: AreaCm) {
        // |α| ≤ 32 (ALPHA_LIMIT, 2^29 in Q.24): Q.27 fits a u32; K < 48.2 in Q.26 too. (P0
        // needs no clamp: |z − P0| is limited below.)
        let k26 = K::mul_hi(
            model.alpha.unsigned_abs().min(super::ALPHA_LIMIT as u32) << 3,
            FIVE_LOG10_2_Q31,
        );
        let flat = k26 < 1 << 10;
        // 2^30/|K| (saturating below |K| = 1/4, where only the flatness of the cost matters).
        let inv_k = if flat {
            0
        } else {
            K::div_shl(1 << 30, k26 >> 1, 25)
        };
        let g = self;
        (g.k26, g.p0) = (k26, model.p0);
        // The fine steps in lattice units: `W`, `H` (cm).
        (g.job.xstep, g.job.ystep) = (area.width, area.height);
        g.job.seg_base = log2_segment_base();
        g.job.n = 0;
        for o in obs.as_slice() {
            let d = o.z.wrapping_sub(model.p0);
            // |z − P0| Q.16 (< 2^26) as Q.22, × 2^30/K → Q.20.
            let r = K::mul_hi(d.unsigned_abs().min((1 << 26) - 1) << 6, inv_k).min(1 << 30) as i32;
            let r = if (d < 0) != (model.alpha < 0) { -r } else { r };
            // |ρ| ≤ 2^30 + 2^25: ρ plus the shift and any log2 d² stays an i32. Strongest
            // anchor first: its term grows fastest away from the winner, so evaluations stop
            // after fewer terms. A completed cost is the same sum in any order, and one that
            // reaches its bound is set to the bound: no result depends on it.
            let p = Placement {
                rho: r - LOG2_M2,
                x: o.pos.x,
                y: o.pos.y,
                weight: o.weight,
            };
            K::place(&mut g.job, &p);
        }
        if flat {
            g.job.n = 0;
        }
    }

    /// The fine column step in lattice units: `W` (cm).
    fn width(&self) -> i32 {
        self.job.xstep as i32
    }

    /// The fine row step in lattice units: `H` (cm).
    fn height(&self) -> i32 {
        self.job.ystep as i32
    }

    fn flat(&self) -> bool {
        self.job.n == 0
    }

    /// A coarse point (coarse indices) near the likely winner: the anchors' centroid weighted
    /// by `1/d̂² = 2^ρ` (to a power of two, the strongest anchor's 32 down to 1), rounded to the
    /// coarse grid. Only a starting bound for [`Grid::coarse`]; any point would be correct.
    /// (The window must be at the origin.)
    fn guess(&self) -> (usize, usize) {
        let a = &self.job.anchors[..self.job.n as usize];
        let rho = |k: usize| a[k].rho - ((a[k].shift as i32) << 21);
        // Σw ≤ 2^8; |Σw·x| < 2^29 (|x| < 2^21 lattice units).
        let (mut sw, mut sx, mut sy) = (0i32, 0i32, 0i32);
        for (k, t) in a.iter().enumerate() {
            // w = 2^(5 − ⌊ρ_top − ρ⌋), or 0 (ρ is sorted, largest first).
            let down = rho(0).wrapping_sub(rho(k)) as u32 >> 20;
            if down > 5 {
                break;
            }
            let up = 5 - down;
            sw += 1 << up;
            sx -= t.dx0.get() << up;
            sy -= t.dy0.get() << up;
        }
        (snap(sx, self.width(), sw), snap(sy, self.height(), sw))
    }

    /// Moves the window to first column `i0`, first row `j0`, `rows` rows `stride` fine rows
    /// apart.
    #[inline(never)]
    fn window(&mut self, i0: usize, j0: usize, stride: usize, rows: usize) {
        // (Indices ≤ 50: the steps fit an i8. |offsets| < 2^23 anywhere in the area: 24 bits
        // hold them.)
        K::move_window(
            &mut self.job,
            (i0 as i8).wrapping_sub(self.i0 as i8),
            (j0 as i8).wrapping_sub(self.j0 as i8),
        );
        (self.i0, self.j0, self.rows) = (i0, j0, rows);
        self.job.stride = stride as u8;
    }

    /// The costs of column `i`'s rows into `sums` (rows whose bit is set in `skip` are not
    /// evaluated and get [`INF`]). A row whose sum reaches `min(bound, COST_MAX)` is set to it:
    /// it is then `≥ bound`, which is all a comparison with `bound` needs to know, and with no
    /// bound (`INF`) it is the cost saturated at [`COST_MAX`].
    #[inline(never)]
    fn column(&mut self, i: usize, bound: u32, skip: u16) {
        self.job.col = (i - self.i0) as u8;
        self.job.bound = bound.min(COST_MAX);
        self.job.skip = skip;
        K::column(&mut self.sums[..self.rows], &mut self.job);
    }

    /// Takes the last column's first smallest cost (column `i`) into `best` if it is below
    /// `bound` (which the column was evaluated with, or a smaller one).
    #[inline(never)]
    fn take(&self, i: usize, bound: u32, best: &mut LatticeMin) {
        if self.job.min < bound {
            *best = LatticeMin {
                i,
                j: self.j0 + self.job.min_row as usize,
                cost: self.job.min,
            };
        }
    }

    /// The thesis' coarse stage: the 11 × 11 coarse grid, with the reference's outcome (`i`
    /// outer, strict `<`). The coarse point nearest [`Grid::guess`] is evaluated first: its cost
    /// bounds every column's evaluations from the start.
    #[inline(never)]
    fn coarse(&mut self) -> LatticeMin {
        let (gi, gj) = self.guess();
        self.coarse_from(gi, gj)
    }

    /// [`Grid::coarse`] starting from coarse point `(gi, gj)` (the same result from any).
    fn coarse_from(&mut self, gi: usize, gj: usize) -> LatticeMin {
        self.window(0, 0, RATIO, COARSE_DIVS + 1);
        self.column(gi * RATIO, INF, !(1 << gj));
        self.evals += 1;
        let mut best = LatticeMin {
            i: gi * RATIO,
            j: gj * RATIO,
            cost: self.sums[gj],
        };
        let mut i = 0;
        while i <= FINE_DIVS {
            // Up to the best point's column a tie comes first in the reference's scan.
            let bound = if i <= best.i {
                best.cost.saturating_add(1)
            } else {
                best.cost
            };
            self.column(i, bound, 0);
            self.evals += COARSE_DIVS + 1;
            self.take(i, bound, &mut best);
            i += RATIO;
        }
        best
    }

    /// The thesis' fine window (± one coarse step, clipped) around the coarse winner `best`:
    /// the thesis MLE (strict `<` from it) into `best` (in place: a returned point is a stack
    /// copy on AVR), and the evaluations it spends. Alone it skips
    /// the window's coarse points (they cannot beat `start`); with `POST` it evaluates every
    /// point up to the posterior's bound (or the MLE's, if larger) and adds it to `post`, and
    /// the MLE is the same (a coarse point is never strictly below `start`). (Two copies: the
    /// sink links only the one with `POST`, inlined into [`mle_and_mmse_window_into`]: a frame
    /// fewer on the sink's deepest stack path.)
    #[inline(always)]
    fn fine<const POST: bool>(&mut self, best: &mut LatticeMin, post: &mut Posterior) -> usize {
        let (i0, j0) = (best.i.saturating_sub(RATIO), best.j.saturating_sub(RATIO));
        let i1 = (best.i + RATIO).min(FINE_DIVS);
        let rows = (best.j + RATIO).min(FINE_DIVS) - j0 + 1;
        self.window(i0, j0, 1, rows);
        // The window's coarse rows (j a multiple of RATIO).
        let (mut coarse, mut n_coarse) = (0u16, 0);
        let mut r = (RATIO - j0 % RATIO) % RATIO;
        while r < rows {
            coarse |= 1 << r;
            n_coarse += 1;
            r += RATIO;
        }
        let mut mle_evals = self.evals;
        for i in i0..=i1 {
            let (mask, skipped) = if i % RATIO == 0 {
                (coarse, n_coarse)
            } else {
                (0, 0)
            };
            mle_evals += rows - skipped;
            if POST {
                self.column(i, post.bound().max(best.cost), 0);
                self.evals += rows;
                K::posterior(&self.sums[..rows], (i - i0) as u8, post);
            } else {
                self.column(i, best.cost, mask);
                self.evals += rows - skipped;
            }
            self.take(i, best.cost, best);
        }
        mle_evals
    }

    fn thesis(&mut self) -> LatticeMin {
        let mut best = self.coarse();
        self.fine_mle(&mut best);
        best
    }

    /// [`Grid::fine`] without the posterior, out of line (the MLE searches' copy).
    #[inline(never)]
    fn fine_mle(&mut self, best: &mut LatticeMin) {
        self.fine::<false>(best, &mut Posterior::new(Weights::ZERO, 0));
    }

    fn multi_start(&mut self) -> LatticeMin {
        self.window(0, 0, RATIO, COARSE_DIVS + 1);
        let mut top = [LatticeMin::NONE; STARTS];
        for i in (0..=FINE_DIVS).step_by(RATIO) {
            self.column(i, top[STARTS - 1].cost, 0);
            for r in 0..=COARSE_DIVS {
                self.evals += 1;
                let c = self.sums[r];
                if let Some(k) = top.iter().position(|t| c < t.cost) {
                    top.copy_within(k..STARTS - 1, k + 1);
                    top[k] = LatticeMin {
                        i,
                        j: r * RATIO,
                        cost: c,
                    };
                }
            }
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
        let mut prev: Option<(usize, usize)> = None;
        loop {
            let mut next = cur;
            let (i0, j0) = (cur.i.saturating_sub(1), cur.j.saturating_sub(1));
            let i1 = (cur.i + 1).min(FINE_DIVS);
            let rows = (cur.j + 1).min(FINE_DIVS) - j0 + 1;
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
                            next.offer(i, j0 + r, self.sums[r]);
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

    /// Every lattice point, in bands of [`ROWS`] rows; ties go to the first point in x-major
    /// order, as in the reference's single scan.
    fn exhaustive(&mut self) -> LatticeMin {
        let mut best = LatticeMin::NONE;
        for j0 in (0..=FINE_DIVS).step_by(ROWS) {
            let rows = (j0 + ROWS - 1).min(FINE_DIVS) - j0 + 1;
            self.window(0, j0, 1, rows);
            for i in 0..=FINE_DIVS {
                self.column(i, best.cost.saturating_add(1), 0);
                for r in 0..rows {
                    self.evals += 1;
                    let (j, c) = (j0 + r, self.sums[r]);
                    if c < best.cost || (c == best.cost && (i, j) < (best.i, best.j)) {
                        best = LatticeMin { i, j, cost: c };
                    }
                }
            }
        }
        best
    }

    /// The estimate at `pos` (the lattice point of `best` if `None`) with `best`'s cost.
    fn finish(
        &self,
        obs: &Observations,
        area: AreaCm,
        pos: Option<PointMm>,
        best: LatticeMin,
        estimator: Estimator,
        evals: usize,
    ) -> Estimate {
        let cost = if self.flat() {
            // α = 0: `Σ w·(z − P0)²`, Q.4 dB residuals (< 2^14) squared into Q.8 dB², w ≤ 4.
            let mut s = 0u32;
            for o in obs.as_slice() {
                let r = (o.z.wrapping_sub(self.p0).unsigned_abs() >> 12).min(0x3FFF);
                s = s.saturating_add(r * r * (o.weight & 7) as u32);
            }
            s
        } else {
            // C = K²·C': K² Q.20 (< 2^32) × C' Q.20 → Q.8.
            K::mul_hi(best.cost, K::mul_hi(self.k26, self.k26))
        };
        Estimate {
            pos: pos.unwrap_or(PointMm {
                x: to_mm(area.width, best.i, 0),
                y: to_mm(area.height, best.j, 0),
            }),
            lattice: (best.i as u8, best.j as u8),
            min_cost: cost.saturating_add(obs.const_cost),
            estimator,
            anchors: obs.len() as u8,
            total_weight: obs.total_weight(),
            evaluations: evals as u16,
        }
    }
}

/// `side·(o + f/2^12)/5` rounded: fine index `o` plus a fraction (`f ≤ 10·2^12`) in mm along a
/// side of `side` cm (as [`AreaCm::lattice_mm`] for `f = 0`): `8·side·(…)` in Q.3 is below 2^32.
#[inline(never)]
fn to_mm(side: u16, o: usize, f: u32) -> u32 {
    let side = side as u32;
    (side * o as u32 * 8 + ((side * f) >> 9) + 20) / 40
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
    mle_with::<Portable>(obs, model, area, search)
}

/// [`mle`] with the cost kernel `K` (e.g. the AVR one of `uno-board`; same result).
pub fn mle_with<K: TermKernel>(
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
    Ok(g.finish(obs, area, None, m, Estimator::Mle(search), g.evals))
}

impl Posterior {
    /// The posterior mean of a window whose first point is `(i0, j0)`, mm, into `pos` (left
    /// as it is if no weight; in place: a returned point is a stack copy on AVR).
    fn mean<K: TermKernel>(&self, area: AreaCm, i0: usize, j0: usize, pos: &mut PointMm) {
        if self.s == 0 {
            return;
        }
        pos.x = mean_mm::<K>(area.width, i0, self.sx, self.s);
        pos.y = mean_mm::<K>(area.height, j0, self.sy, self.s);
    }
}

/// One coordinate of a posterior mean, mm: first index `o` plus the mean offset `Σw·k/Σw` (Q.12,
/// ≤ 10 steps) along a side of `side` cm. (Out of line: one copy for both coordinates.)
#[inline(never)]
fn mean_mm<K: TermKernel>(side: u16, o: usize, swk: u32, sw: u32) -> u32 {
    to_mm(side, o, K::div_shl(swk, sw, 12))
}

/// Posterior-mean position of `obs` under `model` within `area` with shadowing σ (Q.8 dB).
///
/// The posterior mean over all 51 × 51 lattice points, weights `exp(−C/(2σ²))` relative to the
/// smallest cost (computed as `2^(−y)`: integer part a shift, fraction from the flash table; a
/// weight below `2^−20` of the largest is dropped, and the cost evaluation stops there), summed
/// window by window (11 × 11) into 64-bit totals. The thesis search runs first to give a good
/// reference cost. Within 1 cm of [`crate::grid::mmse`]. (Host-sized: not for the sink.)
pub fn mmse(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    sigma: u16,
) -> Result<Estimate, LocError> {
    mmse_with::<Portable>(obs, model, area, sigma)
}

/// [`mmse`] with the cost kernel `K` (same result).
pub fn mmse_with<K: TermKernel>(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    sigma: u16,
) -> Result<Estimate, LocError> {
    check(obs)?;
    let mut g = Grid::<K>::EMPTY;
    g.setup(obs, model, area);
    let mut best = g.thesis();
    let mut wts = Weights::ZERO;
    K::weights(g.k26, sigma, &mut wts);
    let mut cref = best.cost;
    // Σw (< 2^32), Σw·i and Σw·j (< 2^38), relative to `cref`.
    let (mut s, mut sx, mut sy) = (0u64, 0u64, 0u64);
    for j0 in (0..=FINE_DIVS).step_by(ROWS) {
        for i0 in (0..=FINE_DIVS).step_by(ROWS) {
            let rows = (j0 + ROWS - 1).min(FINE_DIVS) - j0 + 1;
            g.window(i0, j0, 1, rows);
            let mut post = Posterior::new(wts, cref);
            for i in i0..=(i0 + ROWS - 1).min(FINE_DIVS) {
                // The smallest cost so far is the reference: costs below it are exact.
                g.column(i, post.bound(), 0);
                g.evals += rows;
                K::posterior(&g.sums[..rows], (i - i0) as u8, &mut post);
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
    let pos = (s != 0).then(|| {
        // mm = 10·side·(Σw·i/Σw)/50, rounded.
        let f = |side: u16, v: u64| ((side as u64 * v + (5 * s) / 2) / (5 * s)) as u32;
        PointMm {
            x: f(area.width, sx),
            y: f(area.height, sy),
        }
    });
    Ok(g.finish(obs, area, pos, best, Estimator::Mmse { sigma }, g.evals))
}

/// Windowed posterior-mean position of `obs` under `model` within `area` with shadowing σ
/// (Q.8 dB): [`crate::grid::mmse_window`] in fixed point, the sink's MMSE.
///
/// The thesis' coarse stage picks the coarse winner, then the posterior mean runs over the
/// thesis' fine window around it (≤ 11 × 11 points, the coarse ones among them evaluated again),
/// weights as in [`mmse`]: at most 242 cost evaluations, as many as the thesis search, but fewer
/// of them stop early (a weight needs the cost up to 21 bits of weight above the smallest, not
/// just whether it beats it). Its lattice point and cost are the thesis MLE's.
pub fn mmse_window(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    sigma: u16,
) -> Result<Estimate, LocError> {
    mmse_window_with::<Portable>(obs, model, area, sigma)
}

/// [`mmse_window`] with the cost kernel `K` (same result).
pub fn mmse_window_with<K: TermKernel>(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    sigma: u16,
) -> Result<Estimate, LocError> {
    mle_and_mmse_window_with::<K>(obs, model, area, sigma).map(|[_, mmse]| mmse)
}

/// The sink's two estimates from one search: `[`[`mle_with`]` (Search::Thesis), `[`mmse_window_with`]`]`
/// with the same arguments, bit for bit (the same [`Estimate`]s, evaluation counts included).
///
/// The windowed MMSE's window is the thesis' fine window around the same coarse winner, so the
/// coarse stage runs once and each window column once, for both: its costs are exact up to the
/// MMSE's bound (costs beyond weigh nothing), raised to the MLE's best cost when that is larger,
/// so every cost that could beat the MLE's best is exact too; the MLE's winner is then the
/// first strictly smallest from the coarse winner on, as in the thesis search (the window's
/// coarse points, which the thesis skips, never are). Costs ≈ the windowed MMSE's cycles, and
/// one copy of the search code in flash (what `sink-fw` links, as [`mle_and_mmse_window_into`]).
pub fn mle_and_mmse_window_with<K: TermKernel>(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    sigma: u16,
) -> Result<[Estimate; 2], LocError> {
    let mut out = [Estimate::NONE; 2];
    mle_and_mmse_window_into::<K>(obs, model, area, sigma, &mut out)?;
    Ok(out)
}

/// [`mle_and_mmse_window_with`] into `out` (untouched on an error): the caller's storage, no
/// returned pair (on AVR a by-value result is a stack copy).
#[inline(never)]
pub fn mle_and_mmse_window_into<K: TermKernel>(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    sigma: u16,
    out: &mut [Estimate; 2],
) -> Result<(), LocError> {
    check(obs)?;
    let mut g = Grid::<K>::EMPTY;
    g.setup(obs, model, area);
    let mut best = g.coarse();
    let mut post = Posterior::new(Weights::ZERO, best.cost);
    K::weights(g.k26, sigma, &mut post.wts);
    let mle_evals = g.fine::<true>(&mut best, &mut post);
    let [mle, mmse] = out;
    *mle = g.finish(
        obs,
        area,
        None,
        best,
        Estimator::Mle(Search::Thesis),
        mle_evals,
    );
    // The same lattice point and cost; its own position, estimator and evaluations.
    *mmse = *mle;
    post.mean::<K>(area, g.i0, g.j0, &mut mmse.pos);
    mmse.estimator = Estimator::MmseWindow { sigma };
    mmse.evaluations = g.evals as u16;
    Ok(())
}

/// `obs` located by `estimator`.
pub fn estimate(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    estimator: Estimator,
) -> Result<Estimate, LocError> {
    estimate_with::<Portable>(obs, model, area, estimator)
}

/// [`estimate`] with the cost kernel `K` (same result).
pub fn estimate_with<K: TermKernel>(
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
    use crate::fixed::{Obs, PointCm};
    use std::vec::Vec;

    /// The reference's coarse scan: every coarse point's whole cost, `i` outer, strict `<`.
    fn plain_coarse(obs: &Observations, m: PathLoss, area: AreaCm) -> LatticeMin {
        let mut s = Grid::<Portable>::EMPTY;
        s.setup(obs, m, area);
        s.window(0, 0, RATIO, COARSE_DIVS + 1);
        let mut best = LatticeMin::NONE;
        for i in (0..=FINE_DIVS).step_by(RATIO) {
            s.column(i, INF, 0);
            for r in 0..=COARSE_DIVS {
                best.offer(i, r * RATIO, s.sums[r]);
            }
        }
        best
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
                for gi in 0..=COARSE_DIVS {
                    for gj in 0..=COARSE_DIVS {
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
            let (i0, j0) = (c.i.saturating_sub(RATIO), c.j.saturating_sub(RATIO));
            let i1 = (c.i + RATIO).min(FINE_DIVS);
            let rows = (c.j + RATIO).min(FINE_DIVS) - j0 + 1;
            g.window(i0, j0, 1, rows);
            let mut costs = Vec::new();
            for i in i0..=i1 {
                g.column(i, INF, 0);
                for r in 0..rows {
                    costs.push((i, j0 + r, g.sums[r] as f64));
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
            let x = area.width as f64 * sx / s / 5.0;
            let y = area.height as f64 * sy / s / 5.0;
            assert!(
                (got.pos.x as f64 - x).abs() <= 2.0 && (got.pos.y as f64 - y).abs() <= 2.0,
                "trial {t}: {got:?} vs ({x:.1}, {y:.1})"
            );
        }
    }
}
