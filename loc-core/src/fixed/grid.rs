//! Grid MLE and MMSE in fixed point ([`crate::grid`]'s searches on the same lattice).
//!
//! Costs are `C' = C/K²` in Q.20 log2² units, `u32`, saturating at [`COST_MAX`]; see the module
//! docs of [`crate::fixed`]. The searches mirror [`crate::grid::search_lattice`] step by step
//! (same outcome as the same scan order, same strict `<`, same multi-start ranking, descent and
//! budget), so they make the same decisions whenever the costs order the same way. Exact
//! shortcuts:
//!
//! * a cost evaluation stops as soon as its partial sum reaches the value it must beat (the terms
//!   are non-negative, so the comparison's outcome is already known); the anchors are summed
//!   strongest first, whose term grows fastest, and the coarse stage starts from the cost of a
//!   guessed coarse point, so that this happens early (ties still go where the scan puts them);
//! * the thesis' fine window skips the coarse points inside it: they cost at least as much as the
//!   coarse winner the window starts from, so under a strict `<` they can never win. (The
//!   windowed MMSE evaluates them again, with the window's shifts: they need their weights.)

use super::kernel::{add_term, log2_segment_table, ColumnJob, Portable, TermKernel};
use super::math::{clamp_i64, exp2_neg_q26, sq_shr, square_shift};
use super::refine::observations;
use super::{AreaCm, Measurements, Observations, OnlineParams, PathLoss, PointMm, Refinement};
use crate::grid::{Search, COARSE_DIVS, FINE_DIVS};
use crate::{LocError, MAX_ANCHORS};
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
const LOG2_M2: i64 = 25769201;
/// `log2((1 cm)²)` in lattice units: `log2(50²)`, Q.20 (the model's [`crate::model::MIN_DISTANCE`]).
const LOG2_CLAMP: i32 = 11836024;
/// `5·log10(2)`, Q.30.
const FIVE_LOG10_2_Q30: i64 = 1_616_142_483;
/// `log2(e)`, Q.30.
const LOG2_E_Q30: i64 = 1_549_082_005;

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

/// The position-independent part of the cost, set up once per estimate.
struct Cost {
    n: usize,
    /// Anchor positions in lattice units (1/50 cm).
    ax: [i32; MAX_ANCHORS],
    ay: [i32; MAX_ANCHORS],
    w: [u8; MAX_ANCHORS],
    /// `(z − P0)/K − log2(1 m²)`, Q.20, clamped to ±2^30 (±1024 log2 units).
    rho: [i32; MAX_ANCHORS],
    /// α = 0: the cost does not depend on the position.
    flat: bool,
    /// Lattice steps in lattice units: `W`, `H` (cm).
    width: i32,
    height: i32,
    /// `K` in Q.16 (`|K| ≤ 48.2`).
    k_q16: i64,
}

impl Cost {
    #[inline(never)]
    fn new(obs: &Observations, model: PathLoss, area: AreaCm) -> Cost {
        let model = model.sane();
        // K = 5·log10(2)·α, Q.24.
        let k_q24 = (model.alpha as i64 * FIVE_LOG10_2_Q30) >> 30;
        let mut c = Cost {
            n: obs.len(),
            ax: [0; MAX_ANCHORS],
            ay: [0; MAX_ANCHORS],
            w: [0; MAX_ANCHORS],
            rho: [0; MAX_ANCHORS],
            flat: k_q24 == 0,
            width: area.width as i32,
            height: area.height as i32,
            k_q16: (k_q24 + 128) >> 8,
        };
        // 1/K in Q.32, |1/K| ≤ 2^4 (|α| ≥ 0.042; smaller α only makes the cost flatter).
        let inv_k = if c.flat {
            0
        } else {
            clamp_i64((1i64 << 56) / k_q24, -(1 << 36), 1 << 36)
        };
        for (a, o) in obs.as_slice().iter().enumerate() {
            c.ax[a] = 50 * o.pos.x as i32;
            c.ay[a] = 50 * o.pos.y as i32;
            c.w[a] = o.weight;
            // (z − P0) Q.16 (|·| < 2^26) × 1/K Q.32 → Q.48 → Q.20.
            let r = ((o.z as i64 - model.p0 as i64) * inv_k) >> 28;
            c.rho[a] = clamp_i64(r - LOG2_M2, -(1 << 30), 1 << 30) as i32;
            // Strongest anchor (largest ρ, nearest by its RSSI) first: its term grows fastest
            // away from the winner, so evaluations stop after fewer terms (≈ 10 % fewer on
            // random rooms). A completed cost is the same sum in any order, and one that
            // reaches its bound is set to the bound, so no result depends on the order.
            let mut b = a;
            while b > 0 && c.rho[b] > c.rho[b - 1] {
                c.ax.swap(b, b - 1);
                c.ay.swap(b, b - 1);
                c.w.swap(b, b - 1);
                c.rho.swap(b, b - 1);
                b -= 1;
            }
        }
        c
    }

    /// A coarse point (coarse indices) near the likely winner: the anchors' centroid weighted
    /// by `1/d̂² = 2^ρ` (to a power of two, the strongest anchor's 32 down to 1), snapped to the
    /// coarse grid. Only a starting bound for [`Searcher::coarse`]; any point would be correct.
    #[inline(never)]
    fn guess(&self) -> (usize, usize) {
        // ρ is sorted, largest first (see `Cost::new`).
        let rho = &self.rho[..self.n];
        let top = rho.first().copied().unwrap_or(0);
        // Σw ≤ 2^8; |Σw·x| < 2^29 (lattice units: |x| < 2^21); top − ρ ≤ 2^31 as u32.
        let (mut sw, mut sx, mut sy) = (0i32, 0i32, 0i32);
        for (a, &r) in rho.iter().enumerate() {
            // w = 2^(5 − ⌊top − ρ⌋), or 0.
            let down = top.wrapping_sub(r) as u32 >> 20;
            if down > 5 {
                break;
            }
            let up = 5 - down as u8;
            sw += 1 << up;
            sx += self.ax[a] << up;
            sy += self.ay[a] << up;
        }
        (snap(sx, self.width, sw), snap(sy, self.height, sw))
    }

    /// `C = K²·C'` in Q.8 dB² (saturating) of a cost `c` (Q.20).
    #[inline(never)]
    fn report(&self, c: u32) -> u32 {
        if self.flat {
            return 0;
        }
        // K² Q.32 >> 16 = Q.16 (< 2^28) × c Q.20 (< 2^32) → Q.36 → Q.8.
        let k2 = ((self.k_q16 * self.k_q16) >> 16) as u64;
        ((k2 * c as u64) >> 28).min(u32::MAX as u64) as u32
    }

    /// `(z − P0)²` summed with the weights, Q.8 dB² (the cost when α = 0).
    fn flat_cost(obs: &Observations, model: PathLoss) -> u32 {
        let mut s: u64 = 0;
        for o in obs.as_slice() {
            let r = (o.z as i64 - model.sane().p0 as i64).unsigned_abs() >> 4; // Q.12, < 2^23
            s += ((r * r) >> 16) * o.weight as u64;
        }
        s.min(u32::MAX as u64) as u32
    }
}

/// The coarse index `c ≤ 10` of the weighted mean `s/sw` (lattice units) along a side of `side`
/// cm: `(c − ½)·5·side < s/sw ≤ (c + ½)·5·side`, found by steps (no division).
#[inline(never)]
fn snap(s: i32, side: i32, sw: i32) -> usize {
    // t < 5·2^16·2^8 < 2^27, so v ≤ 21·t < 2^31.
    let t = (RATIO as i32) * side * sw;
    let (mut c, mut v) = (0, t);
    while c < COARSE_DIVS && v < 2 * s {
        c += 1;
        v += 2 * t;
    }
    c
}

/// A rectangle of fine indices (inclusive), with a row/column step.
#[derive(Clone, Copy, Debug)]
struct Window {
    i0: usize,
    i1: usize,
    j0: usize,
    j1: usize,
    step: usize,
}

impl Window {
    /// `± half` fine steps around `(i, j)`, clipped to the lattice.
    fn around(i: usize, j: usize, half: usize) -> Window {
        Window {
            i0: i.saturating_sub(half),
            i1: (i + half).min(FINE_DIVS),
            j0: j.saturating_sub(half),
            j1: (j + half).min(FINE_DIVS),
            step: 1,
        }
    }

    /// The coarse grid.
    const COARSE: Window = Window {
        i0: 0,
        i1: FINE_DIVS,
        j0: 0,
        j1: FINE_DIVS,
        step: RATIO,
    };

    /// Every column, rows `j0 …` (at most [`ROWS`] of them).
    fn band(j0: usize) -> Window {
        Window {
            i0: 0,
            i1: FINE_DIVS,
            j0,
            j1: (j0 + ROWS - 1).min(FINE_DIVS),
            step: 1,
        }
    }

    /// Rows in the window (≤ [`ROWS`]).
    fn rows(&self) -> usize {
        (self.j1 - self.j0) / self.step + 1
    }
}

/// A search window's per-anchor constants. Costs are computed a column at a time: all anchors
/// at once by [`TermKernel::column`] when every square fits 32 bits unshifted (anchors and
/// window within 13.1 m of each other), else anchor by anchor with shifted squares.
struct Stage {
    /// The kernel's job: per anchor `ρ` and the clamp (both also used when shifted), `dy0`,
    /// the step and the weight.
    job: ColumnJob,
    /// Right shift of each anchor's squares (0 up to 13 m from the anchor).
    shift: [u8; MAX_ANCHORS],
    /// Some shift is not 0: the shifted path.
    shifted: bool,
    w: Window,
    /// Rows in the window.
    rows: usize,
}

impl Stage {
    const fn new() -> Stage {
        Stage {
            job: ColumnJob::EMPTY,
            shift: [0; MAX_ANCHORS],
            shifted: false,
            w: Window::COARSE,
            rows: 0,
        }
    }

    /// Sets the stage up for window `w`; `shifts`: given (reused) or chosen for the window.
    #[inline(never)]
    fn init(&mut self, cost: &Cost, w: Window, shifts: Option<&[u8; MAX_ANCHORS]>) {
        self.w = w;
        self.rows = w.rows();
        self.job.n = cost.n as u8;
        self.job.rows = self.rows as u8;
        self.shifted = false;
        let step = cost.height * w.step as i32;
        let (x0, x1) = (cost.width * w.i0 as i32, cost.width * w.i1 as i32);
        let (y0, y1) = (cost.height * w.j0 as i32, cost.height * w.j1 as i32);
        // Below 2^16 whenever the path is unshifted (it spans at most the window).
        self.job.xstep = (cost.width * w.step as i32) as u16;
        let table = log2_segment_table();
        for a in 0..cost.n {
            let s = match shifts {
                Some(s) => s[a],
                None => {
                    let far = |lo: i32, hi: i32, p: i32| {
                        (lo - p).unsigned_abs().max((hi - p).unsigned_abs())
                    };
                    let dx = far(x0, x1, cost.ax[a]);
                    square_shift(dx.max(far(y0, y1, cost.ay[a])))
                }
            };
            self.shift[a] = s;
            self.shifted |= s != 0;
            let sh = (s as i32) << 20;
            let wt = cost.w[a];
            // Field by field: a whole-struct store goes through a copy on AVR.
            let t = &mut self.job.anchors[a];
            t.dx0 = x0 - cost.ax[a];
            t.dy0 = y0 - cost.ay[a];
            t.step = step as u16;
            t.lclamp = LOG2_CLAMP - sh;
            t.rho = cost.rho[a] + sh;
            t.table = table;
            t.w = if (1..=3).contains(&wt) { wt } else { 4 };
        }
    }

    /// The costs of column `i`'s rows into `sums` (rows whose bit is set in `skip` are not
    /// evaluated and get [`INF`]). A row whose sum reaches `min(bound, COST_MAX)` is set to it:
    /// it is then `≥ bound`, which is all a comparison with `bound` needs to know, and with no
    /// bound (`INF`) it is the cost saturated at [`COST_MAX`].
    #[inline(always)]
    fn column<K: TermKernel>(
        &mut self,
        cost: &Cost,
        i: usize,
        bound: u32,
        skip: u16,
        sums: &mut [u32; ROWS],
    ) {
        if self.shifted || cost.flat {
            return self.column_shifted::<K>(cost, i, bound, skip, sums);
        }
        let c = i - self.w.i0;
        // c ≤ 50: an 8-bit division (by a constant: a multiply).
        self.job.col = if self.w.step == 1 {
            c as u8
        } else {
            c as u8 / RATIO as u8
        };
        self.job.bound = bound.min(COST_MAX);
        self.job.skip = skip;
        K::column(&mut sums[..self.rows], &mut self.job);
    }

    /// [`Stage::column`] anchor by anchor with shifted squares, or for a flat cost.
    #[cold]
    #[inline(never)]
    fn column_shifted<K: TermKernel>(
        &mut self,
        cost: &Cost,
        i: usize,
        bound: u32,
        skip: u16,
        sums: &mut [u32; ROWS],
    ) {
        let rows = &mut sums[..self.rows];
        let bound = bound.min(COST_MAX);
        let x = cost.width * i as i32;
        let anchors = &self.job.anchors[..cost.n];
        let mut bit = 1u16;
        for v in rows.iter_mut() {
            *v = if skip & bit != 0 { INF } else { 0 };
            bit <<= 1;
        }
        if cost.flat {
            return;
        }
        let dy_step = cost.height * self.w.step as i32;
        let y0 = cost.height * self.w.j0 as i32;
        for (a, t) in anchors.iter().enumerate() {
            let s = self.shift[a];
            let dx2 = sq_shr(x - cost.ax[a], s);
            let mut dy = y0 - cost.ay[a];
            for sum in rows.iter_mut() {
                if *sum < bound {
                    let v = add_term::<K>(*sum, dx2, sq_shr(dy, s), t.rho, t.lclamp, t.w);
                    *sum = v.min(bound);
                }
                dy += dy_step;
            }
        }
    }
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

/// The searches: one stage and one column of sums, reused by every phase (≈ 0.2 KB).
struct Searcher<'a, K> {
    cost: &'a Cost,
    st: Stage,
    sums: [u32; ROWS],
    evals: usize,
    kernel: PhantomData<K>,
}

impl<'a, K: TermKernel> Searcher<'a, K> {
    fn new(cost: &'a Cost) -> Searcher<'a, K> {
        Searcher {
            cost,
            st: Stage::new(),
            sums: [0; ROWS],
            evals: 0,
            kernel: PhantomData,
        }
    }

    fn run(&mut self, search: Search) -> LatticeMin {
        match search {
            Search::Thesis => self.thesis(),
            Search::MultiStart => self.multi_start(),
            Search::Exhaustive => self.exhaustive(),
        }
    }

    /// Costs of column `i` of the current stage.
    fn column(&mut self, i: usize, bound: u32, skip: u16) {
        self.st
            .column::<K>(self.cost, i, bound, skip, &mut self.sums);
    }

    /// Evaluates column `i` (rows in `skip`, `skipped` of them, left out) and offers its first
    /// smallest cost to `best`: the same outcome as offering every row in order under the
    /// strict `<`. With `before` (column `i` comes before `best`'s in the scan order of the
    /// reference, `i` outer) a tie wins too, as it would have been found first.
    fn column_offer(
        &mut self,
        i: usize,
        skip: u16,
        skipped: usize,
        before: bool,
        best: &mut LatticeMin,
    ) {
        let bound = if before {
            best.cost.saturating_add(1)
        } else {
            best.cost
        };
        self.column(i, bound, skip);
        let rows = self.st.rows;
        self.evals += rows - skipped;
        let (r, c) = if self.st.shifted || bound == INF || self.cost.flat {
            // The kernel's minimum covers only the unshifted path's completed rows (a flat cost
            // runs no kernel); with no bound a saturated cost (COST_MAX) may be the column's
            // best.
            let mut m = (0, INF);
            for (r, &c) in self.sums[..rows].iter().enumerate() {
                if c < m.1 {
                    m = (r, c);
                }
            }
            m
        } else {
            (self.st.job.min_row as usize, self.st.job.min)
        };
        if c < bound {
            let w = &self.st.w;
            *best = LatticeMin {
                i,
                j: w.j0 + r * w.step,
                cost: c,
            };
        }
    }

    /// The thesis' coarse stage: the 11 × 11 coarse grid, with the reference's outcome (`i`
    /// outer, strict `<`); leaves the stage set up for the coarse grid. The coarse point nearest
    /// [`Cost::guess`] is evaluated first: its cost bounds every column's evaluations from the
    /// start (ties go where the reference's scan puts them). (Not inlined: the thesis search and
    /// the windowed MMSE share one copy in flash.)
    #[inline(never)]
    fn coarse(&mut self) -> LatticeMin {
        let (gi, gj) = self.cost.guess();
        self.coarse_from(gi, gj)
    }

    /// [`Searcher::coarse`] starting from coarse point `(gi, gj)` (the same result from any).
    fn coarse_from(&mut self, gi: usize, gj: usize) -> LatticeMin {
        self.st.init(self.cost, Window::COARSE, None);
        self.column(gi * RATIO, INF, !(1 << gj));
        self.evals += 1;
        let mut best = LatticeMin {
            i: gi * RATIO,
            j: gj * RATIO,
            cost: self.sums[gj],
        };
        for i in (0..=FINE_DIVS).step_by(RATIO) {
            // Up to the guess's column a tie comes first in the reference's scan.
            self.column_offer(i, 0, 0, i <= best.i, &mut best);
        }
        best
    }

    /// The coarse stage, then the stage set up for the fine window around its winner; returns
    /// the window and the winner with its cost under the window's shifts (re-evaluated when they
    /// are finer, so that the window compares like with like).
    #[inline(never)]
    fn fine_window(&mut self) -> (Window, LatticeMin) {
        let best = self.coarse();
        let coarse_shift = self.st.shift;
        let w = Window::around(best.i, best.j, RATIO);
        self.st.init(self.cost, w, None);
        let mut start = best;
        if self.st.shift != coarse_shift {
            let rb = best.j - w.j0;
            self.column(best.i, INF, ((1u16 << w.rows()) - 1) & !(1 << rb));
            self.evals += 1;
            start.cost = self.sums[rb];
        }
        (w, start)
    }

    #[inline(never)]
    fn thesis(&mut self) -> LatticeMin {
        let (w, mut fine) = self.fine_window();
        let rows = w.rows();
        // The coarse rows of the window (j a multiple of RATIO).
        let (mut coarse_rows, mut n_coarse) = (0u16, 0);
        let mut r = (RATIO - w.j0 % RATIO) % RATIO;
        while r < rows {
            coarse_rows |= 1 << r;
            n_coarse += 1;
            r += RATIO;
        }
        // i mod RATIO.
        let mut phase = w.i0 % RATIO;
        for i in w.i0..=w.i1 {
            // Coarse points cannot beat the coarse winner the window starts from.
            let (skip, skipped) = if phase == 0 {
                (coarse_rows, n_coarse)
            } else {
                (0, 0)
            };
            self.column_offer(i, skip, skipped, false, &mut fine);
            phase = if phase == RATIO - 1 { 0 } else { phase + 1 };
        }
        fine
    }

    #[inline(never)]
    fn multi_start(&mut self) -> LatticeMin {
        self.st.init(self.cost, Window::COARSE, None);
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
        let shifts = self.st.shift;
        let mut best = top[0];
        let mut spent = (COARSE_DIVS + 1) * (COARSE_DIVS + 1);
        for start in top.iter().filter(|t| t.cost < INF) {
            let end = self.descend(*start, &mut spent, &shifts);
            best.offer(end.i, end.j, end.cost);
        }
        best
    }

    /// Steepest descent over the 8 fine neighbours, exactly as [`crate::grid`]'s `descend`
    /// (same scan order, same skipped points, same budget check before every evaluation).
    fn descend(
        &mut self,
        from: LatticeMin,
        spent: &mut usize,
        shifts: &[u8; MAX_ANCHORS],
    ) -> LatticeMin {
        let mut cur = from;
        let mut prev: Option<(usize, usize)> = None;
        loop {
            let mut next = cur;
            let w = Window::around(cur.i, cur.j, 1);
            self.st.init(self.cost, w, Some(shifts));
            let rows = w.rows();
            for i in w.i0..=w.i1 {
                let (mut skip, mut candidates, mut over) = (0u16, 0, false);
                for r in 0..rows {
                    let j = w.j0 + r;
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
                            next.offer(i, w.j0 + r, self.sums[r]);
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
    #[inline(never)]
    fn exhaustive(&mut self) -> LatticeMin {
        self.st.init(self.cost, Window::COARSE, None);
        let shifts = self.st.shift;
        let mut best = LatticeMin::NONE;
        for j0 in (0..=FINE_DIVS).step_by(ROWS) {
            let w = Window::band(j0);
            self.st.init(self.cost, w, Some(&shifts));
            for i in 0..=FINE_DIVS {
                self.column(i, best.cost.saturating_add(1), 0);
                for r in 0..w.rows() {
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
}

fn check(obs: &Observations) -> Result<(), LocError> {
    if obs.len() < 3 {
        Err(LocError::TooFewAnchors { usable: obs.len() })
    } else {
        Ok(())
    }
}

fn lattice_u8(m: &LatticeMin) -> (u8, u8) {
    (m.i as u8, m.j as u8)
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
    let cost = Cost::new(obs, model, area);
    let mut s = Searcher::<K>::new(&cost);
    let m = s.run(search);
    let min_cost = if cost.flat {
        Cost::flat_cost(obs, model)
    } else {
        cost.report(m.cost)
    };
    Ok(Estimate {
        pos: area.lattice_mm(m.i, m.j),
        lattice: lattice_u8(&m),
        min_cost: min_cost.saturating_add(obs.const_cost),
        estimator: Estimator::Mle(search),
        anchors: obs.len() as u8,
        total_weight: obs.total_weight(),
        evaluations: s.evals as u16,
    })
}

/// Posterior weights `2^(−y)`, `y = (C' − C'ref)·β`, in Q.26, relative to a reference cost that
/// only ever decreases (the sums are rescaled when a lower cost appears).
///
/// With ΔC' in Q.20 and y in Q.16, `y = ΔC'·K²·log2(e)/(32σ²) = ΔC'·B/2^32` where
/// `B = K_q16²·log2(e)·2^11/σ_q8²`. A weight is 0 from `y ≥ 27` (`< 2^−26`), i.e. from
/// `ΔC' ≥ span = 27·2^48/B`; below it `ΔC'` is scaled into 16 bits (`a`) and `y = (a·b) >> 11`
/// with one 32-bit multiply (`a·b < 2^32`; y within `27·2^−16` of exact).
struct Weights {
    /// `C'` excess (Q.20) at or above which a weight is 0.
    span: u32,
    /// σ = 0: only the minimisers count.
    hard: bool,
    /// `a = (ΔC' << left) >> right`, `a < 2^16`.
    left: u8,
    right: u8,
    b: u32,
}

impl Weights {
    /// The weights of `cost` at σ (Q.8 dB); a flat cost's (α = 0) are all equal.
    fn for_cost(cost: &Cost, sigma_q8: u16) -> Weights {
        if cost.flat {
            Weights::new(0, 1)
        } else {
            Weights::new(cost.k_q16, sigma_q8)
        }
    }

    /// For `K` (Q.16) and σ (Q.8 dB).
    #[inline(never)]
    fn new(k_q16: i64, sigma_q8: u16) -> Weights {
        let mut w = Weights {
            span: 1,
            hard: sigma_q8 == 0,
            left: 0,
            right: 0,
            b: 0,
        };
        if w.hard {
            return w;
        }
        // K_q16² (< 2^44) · log2(e) (Q.30), in two parts that stay below 2^59:
        // (K_q16² >> 14)·(log2e_q30 >> 2) = K_q16²·log2e·2^14, so B = that / (8·σ_q8²).
        let k2 = (k_q16 * k_q16) as u64;
        let kl = (k2 >> 14) * (LOG2_E_Q30 as u64 >> 2);
        let big_b = kl / (8 * sigma_q8 as u64 * sigma_q8 as u64);
        if big_b == 0 {
            // σ so large (or K so small) that every weight is 1.
            w.span = INF;
            return w;
        }
        w.span = ((27u64 << 48) / big_b).clamp(1, COST_MAX as u64) as u32;
        // Bring span into [2^15, 2^16): a < 2^16.
        let bits = 32 - w.span.leading_zeros() as i32; // 1..=32
        let sh = bits - 16; // a = ΔC' · 2^−sh
        if sh >= 0 {
            w.right = sh as u8;
        } else {
            w.left = (-sh) as u8;
        }
        // b = B·2^(sh − 21): ((ΔC'·2^−sh)·b) >> 11 = ΔC'·B/2^32.
        let b = if sh >= 21 {
            big_b << (sh - 21)
        } else {
            big_b >> (21 - sh)
        };
        w.b = b.min(u32::MAX as u64) as u32;
        w
    }

    /// Weight (Q.26) of a cost excess `excess < span` over the reference. (Out of line: one
    /// copy of the `2^−y` evaluation in flash.)
    #[inline(never)]
    fn weight(&self, excess: u32) -> u32 {
        if self.hard {
            return if excess == 0 { 1 << 26 } else { 0 };
        }
        let a = (excess << self.left) >> self.right; // < 2^16
        exp2_neg_q26(a.wrapping_mul(self.b) >> 11)
    }

    /// The factor `2^(−y)` (Q.26) that rescales the sums when the reference drops by `drop`.
    fn rescale(&self, drop: u32) -> u32 {
        if self.hard || drop >= self.span {
            0
        } else {
            self.weight(drop)
        }
    }
}

/// `x · f / 2^26` for `x < 2^52`, `f ≤ 2^26`. (Out of line: five call sites of 64-bit code.)
#[inline(never)]
fn scale(x: u64, f: u32) -> u64 {
    (x >> 26) * f as u64 + (((x & ((1 << 26) - 1)) * f as u64) >> 26)
}

/// Posterior-mean position of `obs` under `model` within `area` with shadowing σ (Q.8 dB).
///
/// The posterior mean over all 51 × 51 lattice points, weights `exp(−C/(2σ²))` relative to the
/// smallest cost (computed as `2^(−y)`: integer part a shift, fraction from the flash table; a
/// weight below `2^−26` of the largest is dropped, and the cost evaluation stops there). The thesis
/// search runs first to give a good reference cost. Within 1 cm of [`crate::grid::mmse`].
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
    let cost = Cost::new(obs, model, area);
    let mut srch = Searcher::<K>::new(&cost);
    let first = srch.thesis();
    let wts = Weights::for_cost(&cost, sigma);
    let mut post = Posterior::new(wts, first);
    srch.st.init(&cost, Window::COARSE, None);
    let shifts = srch.st.shift;
    for j0 in (0..=FINE_DIVS).step_by(ROWS) {
        let w = Window::band(j0);
        srch.st.init(&cost, w, Some(&shifts));
        for i in 0..=FINE_DIVS {
            srch.column(i, post.bound(), 0);
            srch.evals += w.rows();
            post.add_column(i, j0, &srch.sums[..w.rows()]);
        }
    }
    Ok(post.estimate(
        obs,
        model,
        &cost,
        area,
        Estimator::Mmse { sigma },
        srch.evals,
    ))
}

/// Windowed posterior-mean position of `obs` under `model` within `area` with shadowing σ
/// (Q.8 dB): [`crate::grid::mmse_window`] in fixed point, the sink's MMSE.
///
/// The thesis' coarse stage picks the coarse winner, then the posterior mean runs over the
/// thesis' fine window around it (≤ 11 × 11 points, the 9 coarse ones among them evaluated again
/// with the window's shifts), weights as in [`mmse`]: at most 243 cost evaluations, as many as
/// the thesis search, but fewer of them stop early (a weight needs the cost up to 27 bits of
/// weight above the smallest, not just whether it beats it): ≈ 2.5× the thesis MLE's cycles on
/// the AVR (module docs). Within 1 cm of the reference on all of `tests/fixed.rs`' 2 074 random
/// trials (worst 3 mm).
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
    check(obs)?;
    let cost = Cost::new(obs, model, area);
    let mut srch = Searcher::<K>::new(&cost);
    // The coarse winner, as the thesis search starts its window: the first reference cost, and
    // the point that keeps the smallest cost on a tie.
    let (w, best) = srch.fine_window();
    let rows = w.rows();
    let wts = Weights::for_cost(&cost, sigma);
    // Σw (≤ 121·2^26 < 2^33), Σw·i and Σw·j (< 2^39): as in `mmse_with`, with far fewer points.
    let mut post = Posterior::new(wts, best);
    for i in w.i0..=w.i1 {
        srch.column(i, post.bound(), 0);
        srch.evals += rows;
        post.add_column(i, w.j0, &srch.sums[..rows]);
    }
    Ok(post.estimate(
        obs,
        model,
        &cost,
        area,
        Estimator::MmseWindow { sigma },
        srch.evals,
    ))
}

/// The sink's two estimates from one search: `[`[`mle_with`]` (Search::Thesis), `[`mmse_window_with`]`]`
/// with the same arguments, bit for bit (the same [`Estimate`]s, evaluation counts included).
///
/// The windowed MMSE's window is the thesis' fine window around the same coarse winner, so the
/// coarse stage runs once and each window column once, for both: its costs are exact up to the
/// MMSE's bound (costs beyond weigh nothing), raised to the MLE's best cost when that is larger
/// (it only can be when the window's shifts differ from the coarse grid's), so every cost that
/// could beat the MLE's best is exact too; the MLE's winner is then the first smallest of the
/// window's non-coarse points (the thesis skips the coarse ones) under the strict `<`, as in
/// the thesis search. Costs ≈ the windowed MMSE's cycles, and one copy of the search code in
/// flash (what `sink-fw` links).
#[inline(never)]
pub fn mle_and_mmse_window_with<K: TermKernel>(
    obs: &Observations,
    model: PathLoss,
    area: AreaCm,
    sigma: u16,
) -> Result<[Estimate; 2], LocError> {
    check(obs)?;
    let cost = Cost::new(obs, model, area);
    let mut srch = Searcher::<K>::new(&cost);
    let (w, start) = srch.fine_window();
    let rows = w.rows();
    let mut mle_evals = srch.evals;
    let mut post = Posterior::new(Weights::for_cost(&cost, sigma), start);
    let mut fine = start;
    // The coarse rows of the window (j a multiple of RATIO), as in `Searcher::thesis`.
    let (mut coarse_rows, mut n_coarse) = (0u16, 0);
    let mut r = (RATIO - w.j0 % RATIO) % RATIO;
    while r < rows {
        coarse_rows |= 1 << r;
        n_coarse += 1;
        r += RATIO;
    }
    let mut phase = w.i0 % RATIO;
    for i in w.i0..=w.i1 {
        srch.column(i, post.bound().max(fine.cost), 0);
        srch.evals += rows;
        post.add_column(i, w.j0, &srch.sums[..rows]);
        let skip = if phase == 0 { coarse_rows } else { 0 };
        mle_evals += rows - if phase == 0 { n_coarse } else { 0 };
        for (r, &c) in srch.sums[..rows].iter().enumerate() {
            if skip & (1 << r) == 0 && c < fine.cost {
                fine = LatticeMin {
                    i,
                    j: w.j0 + r,
                    cost: c,
                };
            }
        }
        phase = if phase == RATIO - 1 { 0 } else { phase + 1 };
    }
    let mle_cost = if cost.flat {
        Cost::flat_cost(obs, model)
    } else {
        cost.report(fine.cost)
    };
    let mle = Estimate {
        pos: area.lattice_mm(fine.i, fine.j),
        lattice: lattice_u8(&fine),
        min_cost: mle_cost.saturating_add(obs.const_cost),
        estimator: Estimator::Mle(Search::Thesis),
        anchors: obs.len() as u8,
        total_weight: obs.total_weight(),
        evaluations: mle_evals as u16,
    };
    let mmse = post.estimate(
        obs,
        model,
        &cost,
        area,
        Estimator::MmseWindow { sigma },
        srch.evals,
    );
    Ok([mle, mmse])
}

/// The MMSE searches' posterior sums: weights relative to a reference cost that only ever
/// decreases (the sums are rescaled when a lower cost appears, see [`Weights`]), and the
/// smallest cost seen.
struct Posterior {
    wts: Weights,
    cref: u32,
    best: LatticeMin,
    /// Σw (< 2^38), Σw·i and Σw·j (< 2^44).
    s: u64,
    sx: u64,
    sy: u64,
}

impl Posterior {
    /// Starting from a lattice point whose cost is the first reference (a search's winner).
    fn new(wts: Weights, start: LatticeMin) -> Posterior {
        Posterior {
            wts,
            cref: start.cost,
            best: start,
            s: 0,
            sx: 0,
            sy: 0,
        }
    }

    /// The bound a column needs: costs from it on weigh nothing.
    fn bound(&self) -> u32 {
        self.cref.saturating_add(self.wts.span)
    }

    /// Adds column `i`'s rows `j0…` with costs `sums`.
    #[inline(never)]
    fn add_column(&mut self, i: usize, j0: usize, sums: &[u32]) {
        // This column's Σw and Σw·j (< 2^30, < 2^36), rescaled with the totals: one loop over
        // the five sums (one call site of the 64-bit `scale` in flash).
        let mut col = [0u64; 2];
        for (r, &c) in sums.iter().enumerate() {
            let j = j0 + r;
            if c >= self.bound() {
                continue;
            }
            if c < self.cref {
                let f = self.wts.rescale(self.cref - c);
                for v in [&mut self.s, &mut self.sx, &mut self.sy]
                    .into_iter()
                    .chain(col.iter_mut())
                {
                    *v = scale(*v, f);
                }
                self.cref = c;
            }
            if c < self.best.cost {
                self.best = LatticeMin { i, j, cost: c };
            }
            let wt = self.wts.weight(c - self.cref);
            col[0] += wt as u64;
            col[1] += (wt * j as u32) as u64; // < 2^26 · 51 < 2^32
        }
        self.s += col[0];
        self.sx += col[0] * i as u64;
        self.sy += col[1];
    }

    /// The estimate: the posterior mean (the smallest cost's lattice point if every weight is
    /// 0) and the smallest cost.
    #[inline(never)]
    fn estimate(
        &self,
        obs: &Observations,
        model: PathLoss,
        cost: &Cost,
        area: AreaCm,
        estimator: Estimator,
        evals: usize,
    ) -> Estimate {
        let (w, h) = (area.width as u64, area.height as u64);
        let pos = if self.s == 0 {
            area.lattice_mm(self.best.i, self.best.j)
        } else {
            // mm = 10·side·(Σw·i/Σw)/50 = side·Σw·i / (5·Σw), rounded; side·Σw·i < 2^60.
            let d = 5 * self.s;
            PointMm {
                x: (((w * self.sx + d / 2) / d).min(10 * w)) as u32,
                y: (((h * self.sy + d / 2) / d).min(10 * h)) as u32,
            }
        };
        let min_cost = if cost.flat {
            Cost::flat_cost(obs, model)
        } else {
            cost.report(self.best.cost)
        };
        Estimate {
            pos,
            lattice: lattice_u8(&self.best),
            min_cost: min_cost.saturating_add(obs.const_cost),
            estimator,
            anchors: obs.len() as u8,
            total_weight: obs.total_weight(),
            evaluations: evals as u16,
        }
    }
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
    fn plain_coarse(cost: &Cost) -> LatticeMin {
        let mut s = Searcher::<Portable>::new(cost);
        s.st.init(cost, Window::COARSE, None);
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
                let cost = Cost::new(o, m, area);
                let want = plain_coarse(&cost);
                for gi in 0..=COARSE_DIVS {
                    for gj in 0..=COARSE_DIVS {
                        let mut s = Searcher::<Portable>::new(&cost);
                        assert_eq!(s.coarse_from(gi, gj), want, "start ({gi}, {gj})");
                    }
                }
                let mut s = Searcher::<Portable>::new(&cost);
                assert_eq!(s.coarse(), want);
            }
        }
    }
}
