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
//! Size first (the sink links this, SPEC §8): the sink's setup and search loops are kernel
//! routines ([`TermKernel::observe`], [`TermKernel::search`]: assembly on AVR, their portable
//! references in [`super::kernel`]), 32-bit arithmetic only on the sink's path, the rest of its
//! path inlined into [`mle_and_mmse_window_into`]. Stack too (the sink locates at its
//! deepest): the grid set up in place, results written into the caller's storage (a by-value
//! struct is a copy on AVR).

use super::kernel::{
    log2_segment_base, portable_coarse_from, Lattice, LatticeMin, Portable, Posterior, TermKernel,
    Weights, WINDOW_ROWS,
};
use super::refine::observations;
use super::{AreaCm, Measurements, Obs, Observations, OnlineParams, PathLoss, PointMm, Refinement};
use crate::grid::{Search, COARSE_DIVS, FINE_DIVS};
use crate::LocError;
use core::marker::PhantomData;

const RATIO: usize = FINE_DIVS / COARSE_DIVS;
/// Rows a search window holds: ± one coarse step.
const ROWS: usize = WINDOW_ROWS;
/// Coarse starting points of [`Search::MultiStart`].
const STARTS: usize = 4;
/// Most cost evaluations [`Search::MultiStart`] may spend: the thesis search's worst case.
const BUDGET: usize = (COARSE_DIVS + 1) * (COARSE_DIVS + 1) + ROWS * ROWS;
/// [`COARSE_DIVS`], [`FINE_DIVS`], [`RATIO`] as `u8` (the searches' indices).
const C8: u8 = COARSE_DIVS as u8;
const F8: u8 = FINE_DIVS as u8;
const R8: u8 = RATIO as u8;
/// Evaluations of the coarse stage: the guessed point, then the 11 × 11 coarse points.
const COARSE_EVALS: u16 = 1 + (C8 as u16 + 1) * (C8 as u16 + 1);
/// "No cost yet" (every real cost is below it).
const INF: u32 = u32::MAX;
/// Largest real cost.
const COST_MAX: u32 = u32::MAX - 1;

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
/// `[MLE, windowed MMSE]`. The coarse stage spends 122 (the guess and the 121
/// coarse points); the window is `5·n − 4` columns by `5·m − 4` rows, `n`, `m` the coarse
/// columns and rows in it (3 inside, 2 at a side), and the MLE skips its `n·m` coarse points.
/// (Counted once here, not in the loops: a counter in the search loops costs flash on AVR.)
pub(crate) fn window_evals(i: u8, j: u8) -> [u16; 2] {
    let coarse_in = |c: u8| 1 + u8::from(c > 0) + u8::from(c < F8);
    let (n, m) = (coarse_in(i), coarse_in(j));
    let all = COARSE_EVALS + (5 * n - 4) as u16 * (5 * m - 4) as u16;
    [all - (n * m) as u16, all]
}

/// One estimate's search: its [`Lattice`] (the model's constants, the kernel's job, one column
/// of sums; 250 bytes on AVR, most of the sink's search stack) and the kernel.
struct Grid<K> {
    l: Lattice,
    kernel: PhantomData<K>,
}

impl<K: TermKernel> Grid<K> {
    /// No anchors, all zero.
    const EMPTY: Self = Grid {
        l: Lattice::EMPTY,
        kernel: PhantomData,
    };

    /// Sets the cost of `obs` up: `ρ = (z − P0)/K − log2(1 m²)` per anchor (Q.20, `(z − P0)/K`
    /// clamped to ±2^30), the anchors strongest (largest `ρ`) first, and each anchor's shift:
    /// the fewest bits that bring its offsets anywhere in the area below 2^16
    /// ([`TermKernel::observe`]). (Callers bind [`Grid::EMPTY`] and set it up in place: a grid
    /// returned by value is copied on AVR, and two 250-byte grids on the stack are too many.
    /// Inlined: a few stores around one call, smaller than a call's argument moves.)
    #[inline(always)]
    fn setup(&mut self, obs: &Observations, model: PathLoss, area: AreaCm) {
        prepare(&mut self.l, model, area);
        K::observe(&mut self.l.job, &mut self.l.s, obs.as_slice());
    }

    fn flat(&self) -> bool {
        self.l.job.n == 0
    }

    /// Moves the window to first column `i0`, first row `j0`, `rows` rows `stride` fine rows
    /// apart.
    #[inline(never)]
    fn window(&mut self, i0: u8, j0: u8, stride: u8, rows: u8) {
        // (Indices ≤ 50: the steps fit an i8. |offsets| < 2^23 anywhere in the area: 24 bits
        // hold them.)
        K::move_window(
            &mut self.l.job,
            i0.wrapping_sub(self.l.i0) as i8,
            j0.wrapping_sub(self.l.j0) as i8,
        );
        (self.l.i0, self.l.j0, self.l.rows) = (i0, j0, rows);
        self.l.job.stride = stride;
    }

    /// The window's sums in use.
    fn sums(&self) -> &[u32] {
        &self.l.sums[..(self.l.rows as usize).min(ROWS)]
    }

    /// The costs of column `i`'s rows into `sums` (rows whose bit is set in `skip` are not
    /// evaluated and get [`INF`]). A row whose sum reaches `min(bound, COST_MAX)` is set to it:
    /// it is then `≥ bound`, which is all a comparison with `bound` needs to know, and with no
    /// bound (`INF`) it is the cost saturated at [`COST_MAX`].
    #[inline(never)]
    fn column(&mut self, i: u8, bound: u32, skip: u16) {
        self.l.job.col = i.wrapping_sub(self.l.i0);
        self.l.job.bound = bound.min(COST_MAX);
        self.l.job.skip = skip;
        let rows = (self.l.rows as usize).min(ROWS);
        K::column(&mut self.l.sums[..rows], &mut self.l.job);
    }

    /// Takes the last column's first smallest cost (column `i`) into `best` if it is below
    /// `bound` (which the column was evaluated with, or a smaller one).
    #[inline(never)]
    fn take(&self, i: u8, bound: u32, best: &mut LatticeMin) {
        if self.l.job.min < bound {
            *best = LatticeMin {
                i,
                j: self.l.j0.wrapping_add(self.l.job.min_row),
                cost: self.l.job.min,
            };
        }
    }

    /// The thesis' coarse stage: the 11 × 11 coarse grid, with the reference's outcome (`i`
    /// outer, strict `<`). The coarse point nearest [`TermKernel::guess`] (the anchors' weighted
    /// centroid) is evaluated first: its cost
    /// bounds every column's evaluations from the start. ([`COARSE_EVALS`] evaluations.)
    #[inline(never)]
    fn coarse(&mut self) -> LatticeMin {
        let (gi, gj) = K::guess(&self.l.job);
        self.coarse_from(gi, gj)
    }

    /// [`Grid::coarse`] starting from coarse point `(gi, gj)` (the same result from any).
    fn coarse_from(&mut self, gi: u8, gj: u8) -> LatticeMin {
        let mut best = LatticeMin::NONE;
        portable_coarse_from::<K>(&mut self.l, gi, gj, &mut best);
        best
    }

    /// The thesis' fine window (± one coarse step, clipped) around the coarse winner `best`:
    /// the thesis MLE (strict `<` from it) into `best` (in place: a returned point is a stack
    /// copy on AVR). It skips the window's coarse points (they cannot beat `start`).
    /// ([`portable_fine_post`] is the same window with the posterior, every point evaluated
    /// up to the posterior's bound or the MLE's, if larger: the same MLE, as a coarse point is
    /// never strictly below `start`.) Evaluations: [`window_evals`].
    #[inline(never)]
    fn fine_mle(&mut self, best: &mut LatticeMin) {
        let (i0, j0) = (best.i.saturating_sub(R8), best.j.saturating_sub(R8));
        let i1 = (best.i + R8).min(F8);
        let rows = (best.j + R8).min(F8) - j0 + 1;
        self.window(i0, j0, 1, rows);
        // The window's coarse rows (j a multiple of RATIO; `j0` is one).
        let mut coarse = 0u16;
        let mut r = 0;
        while r < rows {
            coarse |= 1 << r;
            r += R8;
        }
        let mut i = i0;
        while i <= i1 {
            let mask = if i % R8 == 0 { coarse } else { 0 };
            self.column(i, best.cost, mask);
            self.take(i, best.cost, best);
            i += 1;
        }
    }

    /// The thesis search; its evaluations into `evals`.
    fn thesis(&mut self) -> LatticeMin {
        let mut best = self.coarse();
        self.l.evals = window_evals(best.i, best.j)[0];
        self.fine_mle(&mut best);
        best
    }

    fn multi_start(&mut self) -> LatticeMin {
        self.window(0, 0, R8, C8 + 1);
        let mut top = [LatticeMin::NONE; STARTS];
        for i in (0..=F8).step_by(RATIO) {
            self.column(i, top[STARTS - 1].cost, 0);
            for r in 0..=C8 {
                self.l.evals += 1;
                let c = self.l.sums[r as usize];
                if let Some(k) = top.iter().position(|t| c < t.cost) {
                    top.copy_within(k..STARTS - 1, k + 1);
                    top[k] = LatticeMin {
                        i,
                        j: r * R8,
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
                            self.l.evals += 1;
                            next.offer(i, j0 + r, self.l.sums[r as usize]);
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
        for j0 in (0..=F8).step_by(ROWS) {
            let rows = (j0 + ROWS as u8 - 1).min(F8) - j0 + 1;
            self.window(0, j0, 1, rows);
            for i in 0..=F8 {
                self.column(i, best.cost.saturating_add(1), 0);
                for r in 0..rows {
                    self.l.evals += 1;
                    let (j, c) = (j0 + r, self.l.sums[r as usize]);
                    if c < best.cost || (c == best.cost && (i, j) < (best.i, best.j)) {
                        best = LatticeMin { i, j, cost: c };
                    }
                }
            }
        }
        best
    }

    /// The estimate at `best`'s lattice point with its cost and `evals` into `out` (its
    /// estimator left as it is; in place: a returned estimate is a stack copy on AVR). (Inlined:
    /// the sink calls it once, and its seven arguments cost more moves than its body.)
    #[inline(always)]
    fn finish(
        &self,
        obs: &Observations,
        area: AreaCm,
        best: &LatticeMin,
        evals: u16,
        out: &mut Estimate,
    ) {
        let cost = if self.flat() {
            self.l.s.flat_cost
        } else {
            // C = K²·C': K² Q.20 (< 2^32) × C' Q.20 → Q.8.
            K::mul_hi(best.cost, K::mul_hi(self.l.s.k26, self.l.s.k26))
        };
        out.pos.x = to_mm(area.width, best.i, 0);
        out.pos.y = to_mm(area.height, best.j, 0);
        out.lattice = (best.i, best.j);
        out.min_cost = cost.saturating_add(obs.const_cost);
        out.anchors = self.l.s.anchors;
        out.total_weight = self.l.s.weight;
        out.evaluations = evals;
    }

    /// The estimate of `search` (the grid set up).
    fn estimate(
        &self,
        obs: &Observations,
        area: AreaCm,
        best: &LatticeMin,
        estimator: Estimator,
    ) -> Estimate {
        let mut e = Estimate::NONE;
        self.finish(obs, area, best, self.l.evals, &mut e);
        e.estimator = estimator;
        e
    }
}

/// The sink search's locals in one block (first in its frame, [`SinkFrame`], where AVR reaches
/// them with a displacement, not pointer arithmetic; zeroed memory, not a copy from flash;
/// [`TermKernel::search`] sets the points and the posterior's reference, and
/// [`TermKernel::finish`] reads them). `repr(C)` (on AVR: `best` 0, `post` 12): an assembly
/// kernel reads it by offset.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct SinkLocals {
    /// The coarse winner and the thesis MLE ([`TermKernel::search`]'s `best`).
    pub best: [LatticeMin; 2],
    /// The windowed posterior.
    pub post: Posterior,
}

/// The window's model and steps before its observations are set up (the grid's search and the
/// sink's): the fine steps in lattice units `W`, `H` (cm), the log2 table, P0 and α.
/// |ρ| ≤ 2^30 + 2^25: ρ plus the shift and any log2 d² stays an i32. Strongest anchor first
/// (`place`): its term grows fastest away from the winner, so evaluations stop after fewer
/// terms. A completed cost is the same sum in any order, and one that reaches its bound is set
/// to the bound: no result depends on it.
#[inline(always)]
fn prepare(l: &mut Lattice, model: PathLoss, area: AreaCm) {
    (l.job.xstep, l.job.ystep) = (area.width, area.height);
    l.job.seg_base = log2_segment_base();
    (l.s.p0, l.s.alpha) = (model.p0, model.alpha);
}

/// The sink's search state, one block ([`mle_and_mmse_window_into`]'s frame): its small locals
/// first, within AVR's displacement of a pointer, then the lattice. `repr(C)` (on AVR: `f` 0,
/// `l` 38): an assembly kernel reads it by offset.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct SinkFrame {
    /// The points and the posterior.
    pub f: SinkLocals,
    /// The lattice (prepared: steps, table, model).
    pub l: Lattice,
}

impl SinkFrame {
    /// All zero (zeroed memory, not a copy from flash, initialises it).
    pub const ZERO: SinkFrame = SinkFrame {
        f: SinkLocals::ZERO,
        l: Lattice::EMPTY,
    };
}

/// The reference of [`TermKernel::sink`]: [`TermKernel::observe`] of `obs` on the prepared
/// lattice, [`TermKernel::weights`] for its `|K|` and σ, [`TermKernel::search`], then
/// [`TermKernel::finish`] with `const_cost` into `out`.
pub fn portable_sink<K: TermKernel>(
    fr: &mut SinkFrame,
    obs: &[Obs],
    sigma: u16,
    const_cost: u32,
    out: &mut [Estimate; 2],
) {
    K::observe(&mut fr.l.job, &mut fr.l.s, obs);
    K::weights(fr.l.s.k26, sigma, &mut fr.f.post.wts);
    K::search(&mut fr.l, &mut fr.f.best, &mut fr.f.post);
    K::finish(&fr.l, &fr.f, const_cost, out);
}

/// The reference of [`TermKernel::finish`]: both estimates of the sink's finished search `f`
/// on `l` into `out`, all but their `estimator`: the MLE's (the thesis' lattice point
/// `f.best[1]` in mm, `C = K²·C'` (the flat cost if flat) plus `const_cost` saturating, the
/// counts, `window_evals(f.best[0])[0]`), then the same into `out[1]` with the posterior
/// mean's position (unless it has no weight) and the window's evaluations. The area's sides are
/// the job's steps.
pub fn portable_finish<K: TermKernel>(
    l: &Lattice,
    f: &SinkLocals,
    const_cost: u32,
    out: &mut [Estimate; 2],
) {
    let evals = window_evals(f.best[0].i, f.best[0].j);
    let best = &f.best[1];
    let [mle, mmse] = out;
    let cost = if l.job.n == 0 {
        l.s.flat_cost
    } else {
        // C = K²·C': K² Q.20 (< 2^32) × C' Q.20 → Q.8.
        K::mul_hi(best.cost, K::mul_hi(l.s.k26, l.s.k26))
    };
    let (w, h) = (l.job.xstep, l.job.ystep);
    mle.pos.x = to_mm(w, best.i, 0);
    mle.pos.y = to_mm(h, best.j, 0);
    mle.lattice = (best.i, best.j);
    mle.min_cost = cost.saturating_add(const_cost);
    mle.anchors = l.s.anchors;
    mle.total_weight = l.s.weight;
    mle.evaluations = evals[0];
    // The same lattice point and cost; its own position and evaluations.
    *mmse = *mle;
    let p = &f.post;
    if p.s != 0 {
        mmse.pos.x = to_mm(w, l.i0, K::div_shl(p.sx, p.s, 12));
        mmse.pos.y = to_mm(h, l.j0, K::div_shl(p.sy, p.s, 12));
    }
    mmse.evaluations = evals[1];
}

impl SinkLocals {
    const ZERO: SinkLocals = SinkLocals {
        best: [LatticeMin {
            i: 0,
            j: 0,
            cost: 0,
        }; 2],
        post: Posterior {
            cref: 0,
            wts: Weights::ZERO,
            col: 0,
            s: 0,
            sx: 0,
            sy: 0,
            table: core::ptr::null(),
        },
    };
}

/// `side·(o + f/2^12)/5` rounded: fine index `o` plus a fraction (`f ≤ 10·2^12`) in mm along a
/// side of `side` cm (as [`AreaCm::lattice_mm`] for `f = 0`): `8·side·(…)` in Q.3 is below 2^32.
/// (`side·f` wraps at 32 bits, as the assembly's.)
#[inline(never)]
fn to_mm(side: u16, o: u8, f: u32) -> u32 {
    let side = side as u32;
    (side * o as u32 * 8 + (side.wrapping_mul(f) >> 9) + 20) / 40
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
    Ok(g.estimate(obs, area, &m, Estimator::Mle(search)))
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
    K::weights(g.l.s.k26, sigma, &mut wts);
    let mut cref = best.cost;
    // Σw (< 2^32), Σw·i and Σw·j (< 2^38), relative to `cref`.
    let (mut s, mut sx, mut sy) = (0u64, 0u64, 0u64);
    for j0 in (0..=F8).step_by(ROWS) {
        for i0 in (0..=F8).step_by(ROWS) {
            let rows = (j0 + ROWS as u8 - 1).min(F8) - j0 + 1;
            g.window(i0, j0, 1, rows);
            let mut post = Posterior::new(wts, cref);
            for i in i0..=(i0 + ROWS as u8 - 1).min(F8) {
                // The smallest cost so far is the reference: costs below it are exact.
                g.column(i, post.bound(), 0);
                g.l.evals += rows as u16;
                K::posterior(g.sums(), i - i0, &mut post);
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
    let mut e = g.estimate(obs, area, &best, Estimator::Mmse { sigma });
    if s != 0 {
        // mm = 10·side·(Σw·i/Σw)/50, rounded.
        let f = |side: u16, v: u64| ((side as u64 * v + (5 * s) / 2) / (5 * s)) as u32;
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
    let mut fr = SinkFrame::ZERO;
    prepare(&mut fr.l, model, area);
    K::sink(&mut fr, obs.as_slice(), sigma, obs.const_cost, out);
    out[0].estimator = Estimator::Mle(Search::Thesis);
    out[1].estimator = Estimator::MmseWindow { sigma };
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
        s.window(0, 0, R8, C8 + 1);
        let mut best = LatticeMin::NONE;
        for i in (0..=F8).step_by(RATIO) {
            s.column(i, INF, 0);
            for r in 0..=C8 {
                best.offer(i, r * R8, s.l.sums[r as usize]);
            }
        }
        best
    }

    /// [`window_evals`] counts what the reference's thesis search evaluates: the 122 of the
    /// coarse stage, then every point of the clipped fine window (the MLE: less its coarse ones).
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
            let (i0, j0) = (c.i.saturating_sub(R8), c.j.saturating_sub(R8));
            let i1 = (c.i + R8).min(F8);
            let rows = (c.j + R8).min(F8) - j0 + 1;
            g.window(i0, j0, 1, rows);
            let mut costs = Vec::new();
            for i in i0..=i1 {
                g.column(i, INF, 0);
                for r in 0..rows {
                    costs.push((i, j0 + r, g.l.sums[r as usize] as f64));
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
