//! The position search's per-(lattice point, anchor) arithmetic, pluggable.
//!
//! Everything else in a search is bookkeeping; this term is evaluated a few hundred times per
//! fix, and LLVM's AVR backend turns it into ≈ 650 cycles (it composes 8 × 8 products into
//! 16/32-bit values with many moves and spills). The trait lets the sink firmware plug in the
//! hand-written AVR version of `uno-board` (`uno_board::AvrTerm`, ≈ 7× fewer cycles) while
//! this crate keeps no `unsafe`. Every implementation must return exactly [`portable_term`]'s
//! value for every input; `uno-board`'s is checked against it in simavr.
//!
//! The same plug serves the sink's flash: the windowed MMSE's accumulation
//! ([`TermKernel::posterior`]: `2^−y` weights, rescaling, sums), its weights' setup
//! ([`TermKernel::weights`]) and the searches' division and high product
//! ([`TermKernel::div_shl`], [`TermKernel::mul_hi`]) are ≈ 2.4 KB of LLVM's AVR code as Rust and
//! ≈ 1.1 KB as `uno-board`'s assembly; the Rust here ([`portable_posterior`],
//! [`portable_weights`], [`div_shl`], [`mul_hi`]) is the reference every implementation must
//! equal, bit for bit.

use super::grid::{portable_finish, portable_sink, Estimate, SinkFrame, SinkLocals};
use super::math::{exp2_neg_q26, log2_fast, sq16, sq_q18};
use super::refine::Obs;
use super::tables;
use crate::grid::{COARSE_DIVS, FINE_DIVS};
use crate::MAX_ANCHORS;

/// `|u|` at which [`portable_term`] saturates, Q.20: 32 log2 units (`|z − p| ≥ 32·K` dB).
pub const U_SAT: u32 = 32 << 20;
/// The saturated term: `32²` in Q.20, less one (four of them still fit a `u32`).
pub const SQ_SAT: u32 = (1 << 30) - 1;

/// One anchor's squared residual at one lattice point.
pub trait TermKernel {
    /// Exactly [`portable_term`]`(lo, carry, rho, lclamp)`.
    fn term(lo: u32, carry: bool, rho: i32, lclamp: i32) -> u32;

    /// The costs of a column's rows, all anchors: exactly [`portable_column`]`::<Self>(sums,
    /// job)` (the default). A kernel overrides it to keep the whole loop in registers: on AVR
    /// the loop's bookkeeping costs LLVM more than the terms themselves.
    #[inline(always)]
    fn column(sums: &mut [u32], job: &mut ColumnJob)
    where
        Self: Sized,
    {
        portable_column::<Self>(sums, job)
    }

    /// A window column's costs `sums` (at most 255 rows) at column offset `col` added to the
    /// posterior sums `post`: exactly [`portable_posterior`]`(sums, col, post)` (the default). A
    /// kernel overrides it to keep the weights' arithmetic in registers: in Rust it is ≈ 1.2 KB
    /// of AVR flash.
    #[inline(always)]
    fn posterior(sums: &[u32], col: u8, post: &mut Posterior)
    where
        Self: Sized,
    {
        portable_posterior(sums, col, post)
    }

    /// The posterior weights for `|K|` (Q.26) and σ (Q.8 dB) into `out`: exactly
    /// [`portable_weights`]`(k26, sigma_q8)` (the default). (In place: on AVR a returned struct
    /// is a stack copy.)
    #[inline(always)]
    fn weights(k26: u32, sigma_q8: u16, out: &mut Weights)
    where
        Self: Sized,
    {
        *out = portable_weights(k26, sigma_q8)
    }

    /// Moves a search window by `di` columns and `dj` rows: every anchor's offsets (all
    /// [`MAX_ANCHORS`], in use or not) plus `di·xstep`, `dj·ystep`, 24-bit wrapping: exactly
    /// [`portable_move`]`(job, di, dj)` (the default). A kernel overrides it: LLVM spends
    /// ≈ 330 bytes of AVR flash on this loop.
    #[inline(always)]
    fn move_window(job: &mut ColumnJob, di: i8, dj: i8)
    where
        Self: Sized,
    {
        portable_move(job, di, dj)
    }

    /// Adds anchor `p` to a search's job (`job.n < MAX_ANCHORS` in use, `n` counts it): its
    /// offsets, shift, weight, `ρ` and clamp, in place among the anchors strongest first:
    /// exactly [`portable_place`]`(job, p)` (the default). A kernel overrides it: in LLVM's
    /// `Grid::setup` this is most of ≈ 1.5 KB of AVR flash (the loop body twice).
    #[inline(always)]
    fn place(job: &mut ColumnJob, p: &Placement)
    where
        Self: Sized,
    {
        portable_place(job, p)
    }

    /// A search's observations set up (`job`'s window at the origin, its steps set): `|K|`
    /// and its inverse, each observation's `ρ`, sign and clamp, the flat cost, the counts, and
    /// the anchor placed in `job` ([`TermKernel::place`]): exactly
    /// [`portable_observe`]`::<Self>(job, s, obs)` (the default; `obs.len() ≤ MAX_ANCHORS`). A kernel overrides it: LLVM's AVR loop is most of ≈ 900 bytes of `Grid::setup`.
    #[inline(always)]
    fn observe(job: &mut ColumnJob, s: &mut Setup, obs: &[Obs])
    where
        Self: Sized,
    {
        portable_observe::<Self>(job, s, obs)
    }

    /// The sink's search: the thesis' coarse stage from [`TermKernel::guess`] into `best[0]`,
    /// then the fine window around it with the windowed posterior (`post`'s weights set, its
    /// reference the coarse winner's cost) into `best[1]`: exactly
    /// [`portable_search`]`::<Self>(l, best, post)` (the default). A kernel overrides it: LLVM
    /// spends ≈ 1 KB of AVR flash on these loops and their helpers.
    #[inline(always)]
    fn search(l: &mut Lattice, best: &mut [LatticeMin; 2], post: &mut Posterior)
    where
        Self: Sized,
    {
        portable_search::<Self>(l, best, post)
    }

    /// Both estimates of the sink's finished search (`f` from [`TermKernel::search`] on `l`)
    /// into `out`, all but their `estimator`: exactly [`portable_finish`]`::<Self>(l, f,
    /// const_cost, out)` (the default). A kernel overrides it: LLVM spends ≈ 700 bytes of AVR
    /// flash on it (32-bit products and divisions, far frame slots).
    #[inline(always)]
    fn finish(l: &Lattice, f: &SinkLocals, const_cost: u32, out: &mut [Estimate; 2])
    where
        Self: Sized,
    {
        portable_finish::<Self>(l, f, const_cost, out)
    }

    /// The sink's whole search on `fr`'s prepared lattice: exactly [`portable_sink`]`::<Self>(fr,
    /// obs, sigma, const_cost, out)` (the default: observe, weights, search, finish;
    /// `obs.len() ≤ MAX_ANCHORS`). A kernel overrides it to run the four as one routine (on AVR
    /// one register save and one call instead of four).
    #[inline(always)]
    fn sink(fr: &mut SinkFrame, obs: &[Obs], sigma: u16, const_cost: u32, out: &mut [Estimate; 2])
    where
        Self: Sized,
    {
        portable_sink::<Self>(fr, obs, sigma, const_cost, out)
    }

    /// A search's coarse starting point (coarse indices, each ≤ 10) for `job` with its window
    /// at the origin: exactly [`portable_guess`]`(job)` (the default). A kernel overrides it:
    /// LLVM spends ≈ 550 bytes of AVR flash on it (variable shifts, 32-bit sums).
    #[inline(always)]
    fn guess(job: &ColumnJob) -> (u8, u8)
    where
        Self: Sized,
    {
        portable_guess(job)
    }

    /// `⌊a·2^e / b⌋` for `1 ≤ b < 2^31` and `e ≤ 255`, saturating: exactly [`div_shl`]`(a, b,
    /// e)` (the default; the searches' one division).
    #[inline(always)]
    fn div_shl(a: u32, b: u32, e: u32) -> u32
    where
        Self: Sized,
    {
        div_shl(a, b, e)
    }

    /// `⌊a·b / 2^32⌋` within 2 below: exactly [`mul_hi`]`(a, b)` (the default).
    #[inline(always)]
    fn mul_hi(a: u32, b: u32) -> u32
    where
        Self: Sized,
    {
        mul_hi(a, b)
    }
}

/// A 24-bit two's-complement integer, 3 bytes little endian: an [`AnchorTerm`]'s offsets (the
/// kernels use 24 bits of them; a fourth byte per offset would be 16 bytes of a search's stack).
#[repr(transparent)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct I24(pub [u8; 3]);

impl I24 {
    /// 0.
    pub const ZERO: I24 = I24([0; 3]);

    /// The low 24 bits of `v`.
    #[inline(always)]
    pub const fn new(v: i32) -> I24 {
        let b = v.to_le_bytes();
        I24([b[0], b[1], b[2]])
    }

    /// The value, sign-extended.
    #[inline(always)]
    pub const fn get(self) -> i32 {
        let [a, b, c] = self.0;
        ((c as i8 as i32) << 16) | ((b as i32) << 8) | a as i32
    }

    /// `self + v`, wrapping at 24 bits (no sign extension needed).
    #[inline(always)]
    pub fn add(&mut self, v: i32) {
        let [a, b, c] = self.0;
        *self = I24::new(u32::from_le_bytes([a, b, c, 0]).wrapping_add(v as u32) as i32);
    }
}

/// One anchor of a [`ColumnJob`]. Its offsets `dx`, `dy` from the lattice point (24-bit
/// values: `|·| < 2^23` lattice units) are rounded to multiples of `2^shift` before they are
/// squared, so that each square fits 32 bits (`shift` is 0 within 13.1 m of the anchor).
///
/// `repr(C)`: assembly kernels read it by offset (on AVR, where nothing is padded: `dx2` 0,
/// `dx0` 4, `dy0` 7, `lclamp` 10, `rho` 14, `w` 18, `shift` 19; 20 bytes: eight of them are
/// most of a search's stack).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct AnchorTerm {
    /// `dx²` of the column (shifted): scratch, the kernel computes it.
    pub dx2: u32,
    /// `dx` of the window's column 0, lattice units; column offset `c`'s is `dx0 + c·xstep`.
    pub dx0: I24,
    /// `dy` of the window's row 0, lattice units; fine row offset `o`'s is `dy0 + o·ystep`
    /// ([`ColumnJob::ystep`]).
    pub dy0: I24,
    /// `log2` of the 1 cm clamp, Q.20, less `2·shift`.
    pub lclamp: i32,
    /// The anchor's `ρ`, Q.20, plus `2·shift`.
    pub rho: i32,
    /// The anchor's weight, 1 to 4.
    pub w: u8,
    /// `dx` and `dy` are `|·|` rounded to `2^shift` units (0 to 7).
    pub shift: u8,
}

impl AnchorTerm {
    /// No anchor (a placeholder for unused slots; all zero, so that zeroed memory, not a copy
    /// from flash, initialises it).
    pub const NONE: AnchorTerm = AnchorTerm {
        dx2: 0,
        dx0: I24::ZERO,
        dy0: I24::ZERO,
        lclamp: 0,
        rho: 0,
        w: 0,
        shift: 0,
    };
}

/// A column of a search window, for [`TermKernel::column`] (on AVR: `bound` at offset 0, `n`
/// 4, `rows` 5, `min` 6, `min_row` 10, `skip` 11, `col` 13, `xstep` 14, `stride` 16, `end` 17,
/// `seg_base` 18, `ystep` 20, the anchors from 22).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct ColumnJob {
    /// Rows whose sum reaches it stop there (they cannot win any more).
    pub bound: u32,
    /// Anchors in use (0 to [`MAX_ANCHORS`]; 0: every row costs 0).
    pub n: u8,
    /// Rows of the column (kernels may set it from the slice length; the searches do).
    pub rows: u8,
    /// Output: the smallest sum the kernel completed below the bound (`u32::MAX` if none)…
    pub min: u32,
    /// …and its first row, as a fine row offset (`row·stride`).
    pub min_row: u8,
    /// Rows not to evaluate (bit `r` for row `r`, rows from 16 on are all evaluated): they get
    /// `u32::MAX`. Scratch: kernels may consume it.
    pub skip: u16,
    /// The column's fine offset from the window's first.
    pub col: u8,
    /// Fine column step, lattice units.
    pub xstep: u16,
    /// Fine rows from one row of the column to the next (1: the fine lattice, 5: the coarse).
    pub stride: u8,
    /// Scratch for kernels.
    pub end: u8,
    /// [`log2_segment_base`], for kernels that read the table directly.
    pub seg_base: *const u8,
    /// Fine row step, lattice units (the same for every anchor: one copy, not one per anchor).
    pub ystep: u16,
    /// The anchors, in evaluation order.
    pub anchors: [AnchorTerm; MAX_ANCHORS],
}

impl ColumnJob {
    /// No rows, no anchors, stride 0 (set it before use; all zero, so that zeroed memory, not
    /// a copy from flash, initialises it).
    pub const EMPTY: ColumnJob = ColumnJob {
        bound: 0,
        n: 0,
        rows: 0,
        min: 0,
        min_row: 0,
        skip: 0,
        col: 0,
        xstep: 0,
        stride: 0,
        end: 0,
        seg_base: core::ptr::null(),
        ystep: 0,
        anchors: [AnchorTerm::NONE; MAX_ANCHORS],
    };
}

/// Posterior weights `2^(−y)`, `y = (C' − C'ref)·β` in Q.16, relative to a reference cost that
/// only ever decreases (the sums are rescaled when a lower cost appears); the search sets them
/// up for its σ and `K`.
///
/// With ΔC' in Q.20, `β = K²·log2(e)/(32σ²)·2^−4`. A weight is 0 from `ΔC' ≥ span` (`y ≥ 21`);
/// below it `ΔC'` is scaled below 2^16 (`a = ΔC' >> ra`) and `y = (a·b mod 2^32) >> 11` with one
/// 32-bit multiply. `repr(C)` (on AVR: `span` 0, `b` 4, `ra` 8): an assembly kernel reads it by
/// offset. Every weight needs `span >> ra < 2^16` and `ra ≤ 16` (what the search sets).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Weights {
    /// `C'` excess (Q.20) at or above which a weight is 0 (1 for σ = 0: only the minimisers).
    pub span: u32,
    /// `β·2^(11 + ra)`.
    pub b: u32,
    /// `a = ΔC' >> ra`, `a < 2^16`.
    pub ra: u8,
}

impl Weights {
    /// All zero: storage for [`TermKernel::weights`] (zeroed memory, not a copy from flash).
    pub const ZERO: Weights = Weights {
        span: 0,
        b: 0,
        ra: 0,
    };

    /// Weight (Q.26) of a cost excess over the reference. (Out of line: one copy of the
    /// `2^−y` evaluation in flash.)
    #[inline(never)]
    pub fn weight(&self, excess: u32) -> u32 {
        if excess >= self.span {
            return 0;
        }
        let a = excess >> self.ra;
        exp2_neg_q26(a.wrapping_mul(self.b) >> 11)
    }
}

/// `log2(e)`, Q.31.
const LOG2_E_Q31: u32 = 3_098_164_009;
/// Posterior weights end at `2^−Y_CUT` of the largest (they are Q.20: smaller ones are 0).
const Y_CUT: u32 = 21;

/// The reference of [`TermKernel::weights`]: the [`Weights`] for `|K|` (Q.26) and σ (Q.8 dB);
/// a flat cost's (`K < 2^−16`) are all equal, σ = 0's weigh only the minimisers.
///
/// A weight is 0 from `y ≥ Y_CUT` (21), i.e. from `ΔC' ≥ span`; below it `ΔC'` is scaled below
/// 2^16 (`a`) and `y = (a·b) >> 11` with one 32-bit multiply (`a·b ≤ Y_CUT·2^27`; y within
/// `Y_CUT·2^−15` of exact).
#[inline(never)]
pub fn portable_weights(k26: u32, sigma_q8: u16) -> Weights {
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
    // b = β·2^(11 + ra) = p·2^(4 + ra − 2z)/σ_q8² (a·b ≤ Y_CUT·2^27 below span).
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

/// `⌊a·2^e / b⌋` for `1 ≤ b < 2^31`, saturating at `u32::MAX` (one 32-bit division, then a bit
/// per step).
#[inline(never)]
pub fn div_shl(a: u32, b: u32, e: u32) -> u32 {
    let (mut q, mut r) = (a / b, a % b);
    for _ in 0..e {
        if q >> 31 != 0 {
            return u32::MAX;
        }
        q <<= 1;
        r <<= 1;
        if r >= b {
            r -= b;
            q |= 1;
        }
    }
    q
}

/// A window's posterior sums (≤ 11 × 11 points, offsets from its first column and row), for
/// [`TermKernel::posterior`]: weights Q.20 relative to a reference cost `cref` that only ever
/// decreases. In a search Σw < 2^27, Σw·c and Σw·r < 2^31: all `u32` (they wrap otherwise).
///
/// `repr(C)` (on AVR: `cref` 0, `wts` 4, `col` 13, `s` 14, `sx` 18, `sy` 22, `table` 26; 28
/// bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct Posterior {
    /// The reference cost (Q.20): weights are relative to it.
    pub cref: u32,
    /// The weights.
    pub wts: Weights,
    /// Scratch for kernels (the AVR one keeps the call's column offset here).
    pub col: u8,
    /// `Σw` (Q.20)…
    pub s: u32,
    /// …`Σw·c`…
    pub sx: u32,
    /// …and `Σw·r`.
    pub sy: u32,
    /// [`exp2_segment_table`], for kernels that read the table directly (the AVR one: there a
    /// field, not an argument, lets the search call it as a local subroutine).
    pub table: *const [u16; 2],
}

impl Posterior {
    /// No points yet, reference `cref`.
    pub fn new(wts: Weights, cref: u32) -> Posterior {
        Posterior {
            cref,
            wts,
            col: 0,
            s: 0,
            sx: 0,
            sy: 0,
            table: exp2_segment_table(),
        }
    }

    /// The bound a column needs: costs from it on weigh nothing.
    pub fn bound(&self) -> u32 {
        self.cref.saturating_add(self.wts.span)
    }
}

/// The reference of [`TermKernel::posterior`]: row `r`'s cost `v` (skipped if at least
/// [`Posterior::bound`]) weighs `2^−y(v − cref)`; a cost below `cref` first becomes the
/// reference, the sums so far scaled by the weight of the drop (`mul_hi`, Q.32 factor). Adds
/// `w`, `w·col` and `w·r` (`w` Q.20).
#[inline(always)]
pub fn portable_posterior(sums: &[u32], col: u8, post: &mut Posterior) {
    let c = col as u32;
    for (r, &v) in sums.iter().enumerate() {
        if v >= post.bound() {
            continue;
        }
        if v < post.cref {
            // The sums so far, relative to the new reference: × 2^(−y(drop)), Q.32.
            let f = post.wts.weight(post.cref - v).min((1 << 26) - 1) << 6;
            // (Three calls, not a loop over an array of references: no array on the stack.)
            post.s = mul_hi(post.s, f);
            post.sx = mul_hi(post.sx, f);
            post.sy = mul_hi(post.sy, f);
            post.cref = v;
        }
        let wt = post.wts.weight(v - post.cref) >> 6;
        post.s = post.s.wrapping_add(wt);
        post.sx = post.sx.wrapping_add(wt * c);
        post.sy = post.sy.wrapping_add(wt * r as u32);
    }
}

/// `⌊a·b / 2^32⌋`, within 2 below, from three 16 × 16 products (no 64-bit arithmetic).
#[inline(never)]
pub fn mul_hi(a: u32, b: u32) -> u32 {
    let (ah, al, bh, bl) = (a >> 16, a & 0xFFFF, b >> 16, b & 0xFFFF);
    ah * bh + ((ah * bl) >> 16) + ((al * bh) >> 16)
}

/// Address of the exp2 segment table (32 segments × 2 `u16`, little endian: `2^(−k/32)` Q.15
/// and the difference to the next): on AVR a flash address, to be read with `lpm`.
pub fn exp2_segment_table() -> *const [u16; 2] {
    tables::exp2_seg_table()
}

/// `|v|` rounded to `2^shift` units (half up), squared, as the kernels do it: `v` taken as a
/// 24-bit value, the rounded magnitude as 16 bits.
#[inline(always)]
pub fn offset_square(v: i32, shift: u8) -> u32 {
    let a = ((v << 8) >> 8).unsigned_abs();
    let r = if shift == 0 {
        a
    } else {
        (a >> shift) + ((a >> (shift - 1)) & 1)
    };
    sq16((r & 0xFFFF) as i32)
}

/// `log2((1 cm)²)` in lattice units: `log2(50²)`, Q.20 (the model's
/// [`crate::model::MIN_DISTANCE`]).
pub const LOG2_CLAMP: i32 = 11_836_024;

/// One anchor for [`TermKernel::place`]. `repr(C)` (on AVR: `rho` 0, `x` 4, `y` 6, `weight` 8):
/// an assembly kernel reads it by offset.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Placement {
    /// `ρ = (z − P0)/K − log2(1 m²)`, Q.20, before the shift's correction (the sort key).
    pub rho: i32,
    /// Anchor position, cm.
    pub x: i16,
    /// Anchor position, cm.
    pub y: i16,
    /// Observation weight (1 to 3 kept, anything else is 4).
    pub weight: u8,
}

/// `log2(1 m²)` in lattice units `(1/50 cm)²`: `log2(5000²)`, Q.20.
pub const LOG2_M2: i32 = 25_769_201;

/// Rows a search window holds: ± one coarse step of the thesis' lattice.
pub const WINDOW_ROWS: usize = 2 * (FINE_DIVS / COARSE_DIVS) + 1;

/// A lattice point (fine indices) and its cost. `repr(C)` (on AVR: `i` 0, `j` 1, `cost` 2).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LatticeMin {
    /// Fine column.
    pub i: u8,
    /// Fine row.
    pub j: u8,
    /// Its cost (`u32::MAX`: none yet).
    pub cost: u32,
}

/// A search's state: its window, the model's constants ([`Setup`]), the kernel's job and one
/// column of sums. `repr(C)`, the scalars and the job's header first: AVR reaches 63 bytes from
/// a pointer in one instruction, farther fields cost pointer arithmetic; an assembly kernel
/// reads it by offset. Indices are `u8` (≤ 50): on AVR every `usize` is a register pair.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct Lattice {
    /// The current window's first column and row (fine indices) and its rows.
    pub i0: u8,
    /// See `i0`.
    pub j0: u8,
    /// See `i0`.
    pub rows: u8,
    /// Evaluations (the host's multi-start, exhaustive and full MMSE searches count here).
    pub evals: u16,
    /// The model in, and what [`TermKernel::observe`] sums and derives.
    pub s: Setup,
    /// The kernel's job: per anchor `ρ`, weight, shift, offsets from the window's origin.
    pub job: ColumnJob,
    /// The last column's costs.
    pub sums: [u32; WINDOW_ROWS],
}

impl Lattice {
    /// No anchors, all zero.
    pub const EMPTY: Lattice = Lattice {
        i0: 0,
        j0: 0,
        rows: 0,
        evals: 0,
        s: Setup::ZERO,
        job: ColumnJob::EMPTY,
        sums: [0; WINDOW_ROWS],
    };
}

/// The reference of [`TermKernel::search`]: the coarse stage from [`TermKernel::guess`]'s
/// point ([`portable_coarse_from`]) into `best[0]`, `post`'s reference its cost, then
/// [`portable_fine_post`] from it into `best[1]`.
pub fn portable_search<K: TermKernel>(
    l: &mut Lattice,
    best: &mut [LatticeMin; 2],
    post: &mut Posterior,
) {
    let (gi, gj) = K::guess(&l.job);
    portable_coarse_from::<K>(l, gi, gj, &mut best[0]);
    post.cref = best[0].cost;
    best[1] = best[0];
    portable_fine_post::<K>(l, &mut best[1], post);
}

/// Column `i` of `l`'s window into its sums (rows whose bit is set in `skip` are not
/// evaluated), evaluations stopped at `min(bound, u32::MAX − 1)`.
fn column_of<K: TermKernel>(l: &mut Lattice, i: u8, bound: u32, skip: u16) {
    l.job.col = i.wrapping_sub(l.i0);
    l.job.bound = bound.min(u32::MAX - 1);
    l.job.skip = skip;
    let rows = (l.rows as usize).min(WINDOW_ROWS);
    K::column(&mut l.sums[..rows], &mut l.job);
}

/// The thesis' coarse stage into `best`: the 11 × 11 coarse grid (the window moved to the
/// origin, stride 5) with the reference's outcome (`i` outer, strict `<`), coarse point `(gi,
/// gj)` (each ≤ 10) evaluated first: its cost bounds every column's evaluations from the start
/// (the same result from any). Up to the best point's column a tie comes first in the
/// reference's scan: those columns are bounded one above the best cost.
pub fn portable_coarse_from<K: TermKernel>(l: &mut Lattice, gi: u8, gj: u8, best: &mut LatticeMin) {
    const R: u8 = (FINE_DIVS / COARSE_DIVS) as u8;
    K::move_window(
        &mut l.job,
        0u8.wrapping_sub(l.i0) as i8,
        0u8.wrapping_sub(l.j0) as i8,
    );
    (l.i0, l.j0, l.rows) = (0, 0, COARSE_DIVS as u8 + 1);
    l.job.stride = R;
    column_of::<K>(l, gi * R, u32::MAX, !(1 << gj));
    *best = LatticeMin {
        i: gi * R,
        j: gj * R,
        cost: l.sums[(gj as usize).min(COARSE_DIVS)],
    };
    let mut i = 0;
    while i <= FINE_DIVS as u8 {
        let bound = if i <= best.i {
            best.cost.saturating_add(1)
        } else {
            best.cost
        };
        column_of::<K>(l, i, bound, 0);
        if l.job.min < bound {
            *best = LatticeMin {
                i,
                j: l.j0.wrapping_add(l.job.min_row),
                cost: l.job.min,
            };
        }
        i += R;
    }
}

/// The fine stage of [`portable_search`]: the thesis' fine window (± one coarse step,
/// clipped) around the coarse winner `best`, each column evaluated up to the posterior's bound
/// or `best`'s cost if larger (capped at `u32::MAX − 1`), added to `post`, and its first
/// strictly smaller cost taken into `best` (the window moved there first: stride 1).
pub fn portable_fine_post<K: TermKernel>(
    l: &mut Lattice,
    best: &mut LatticeMin,
    post: &mut Posterior,
) {
    const R: u8 = (FINE_DIVS / COARSE_DIVS) as u8;
    let (i0, j0) = (best.i.saturating_sub(R), best.j.saturating_sub(R));
    let i1 = best.i.wrapping_add(R).min(FINE_DIVS as u8);
    let rows = best.j.wrapping_add(R).min(FINE_DIVS as u8).wrapping_sub(j0) + 1;
    K::move_window(
        &mut l.job,
        i0.wrapping_sub(l.i0) as i8,
        j0.wrapping_sub(l.j0) as i8,
    );
    (l.i0, l.j0, l.rows) = (i0, j0, rows);
    l.job.stride = 1;
    let rows = (rows as usize).min(WINDOW_ROWS);
    let mut i = i0;
    while i <= i1 {
        column_of::<K>(l, i, post.bound().max(best.cost), 0);
        K::posterior(&l.sums[..rows], i - i0, post);
        if l.job.min < best.cost {
            *best = LatticeMin {
                i,
                j: l.j0.wrapping_add(l.job.min_row),
                cost: l.job.min,
            };
        }
        i += 1;
    }
}

/// `5·log10(2)`, Q.31.
const FIVE_LOG10_2_Q31: u32 = 3_232_284_966;

/// A search's setup over its observations, for [`TermKernel::observe`]: its inputs (`P0`, α)
/// and outputs (`|K|`, the flat cost, the counts). `repr(C)` (on AVR: `p0` 0, `alpha` 4, `k26`
/// 8, `flat_cost` 12, `anchors` 16, `weight` 17): an assembly kernel reads it by offset.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Setup {
    /// Input: P0, Q.16 dBm.
    pub p0: i32,
    /// Input: α, Q.24 (its magnitude clamped to 32).
    pub alpha: i32,
    /// Output: `|K|`, Q.26 (`K = 5·α·log10 2`); below `2^10` the cost is flat.
    pub k26: u32,
    /// Sum: the cost if flat (α = 0), `Σ w·(z − P0)²`, Q.8 dB², saturating (`w` is `weight & 7`).
    pub flat_cost: u32,
    /// Sum: the observations.
    pub anchors: u8,
    /// Sum: their weights (wrapping).
    pub weight: u8,
}

impl Setup {
    /// All zero (zeroed memory, not a copy from flash, initialises it).
    pub const ZERO: Setup = Setup {
        p0: 0,
        alpha: 0,
        k26: 0,
        flat_cost: 0,
        anchors: 0,
        weight: 0,
    };
}

/// The reference of [`TermKernel::observe`]: `k26 = mul_hi(min(|α|, 2^29) << 3, 5·log10 2
/// (Q.31))`, `inv_k = div_shl(2^30, k26 >> 1, 25)` (0 if flat: `k26 < 2^10`), `job.n = 0`; then
/// per observation `d = z − P0` (wrapping) and `a = min(|d|, 2^26 − 1) << 6`; the flat cost
/// plus `(w & 7)·q²`, `q = a >> 18` (`|d|` in Q.4 dB, at most `2^14 − 1`, squared into Q.8
/// dB²), saturating; `ρ = ±min(mul_hi(a, inv_k), 2^30) − log2(1 m²)` (Q.20, negative when
/// `d < 0` and α ≥ 0 or the reverse); then [`TermKernel::place`]. A flat cost ends with
/// `job.n = 0` (every point costs the same).
pub fn portable_observe<K: TermKernel>(job: &mut ColumnJob, s: &mut Setup, obs: &[Obs]) {
    // |α| ≤ 32 (2^29 in Q.24): Q.27 fits a u32; K < 48.2 in Q.26 too. (P0 needs no clamp:
    // |z − P0| is limited below.)
    s.k26 = K::mul_hi(s.alpha.unsigned_abs().min(1 << 29) << 3, FIVE_LOG10_2_Q31);
    let flat = s.k26 < 1 << 10;
    // 2^30/|K| (saturating below |K| = 1/4, where only the flatness of the cost matters).
    let inv_k = if flat {
        0
    } else {
        K::div_shl(1 << 30, s.k26 >> 1, 25)
    };
    job.n = 0;
    for o in obs {
        let d = o.z.wrapping_sub(s.p0);
        let ad = d.unsigned_abs();
        // |z − P0| Q.16 (< 2^26) as Q.22, × 2^30/K → Q.20 (and Q.4 dB for the flat cost).
        let a = ad.min((1 << 26) - 1) << 6;
        let q = a >> 18;
        s.flat_cost = s.flat_cost.saturating_add(q * q * (o.weight & 7) as u32);
        s.anchors = s.anchors.wrapping_add(1);
        s.weight = s.weight.wrapping_add(o.weight);
        let r = K::mul_hi(a, inv_k).min(1 << 30) as i32;
        let r = if (d < 0) != (s.alpha < 0) { -r } else { r };
        let p = Placement {
            rho: r - LOG2_M2,
            x: o.pos.x,
            y: o.pos.y,
            weight: o.weight,
        };
        K::place(job, &p);
    }
    if flat {
        job.n = 0;
    }
}

/// The reference of [`TermKernel::place`]: `p` goes after the anchors whose sort key (`ρ`
/// before the shift's correction) is at least its `ρ` (the ones below move up a slot, whole);
/// `dx0 = −50·x`, `dy0 = −50·y` (lattice units, the window at the origin); the shift: the fewest
/// bits that bring the farthest offsets (from the area's sides `xstep`, `ystep` cm) below
/// 2^16; then `ρ` and the clamp corrected by the shift (`log2 d²` drops by `2·shift`).
pub fn portable_place(job: &mut ColumnJob, p: &Placement) {
    let n = job.n as usize;
    job.n += 1;
    let key = |t: &AnchorTerm| t.rho - ((t.shift as i32) << 21);
    let anchors = &mut job.anchors;
    let mut b = n;
    while b > 0 && p.rho > key(&anchors[b - 1]) {
        anchors[b] = anchors[b - 1];
        b -= 1;
    }
    let (xm, ym) = (50 * job.xstep as i32, 50 * job.ystep as i32);
    let t = &mut anchors[b];
    let (dx0, dy0) = (-50 * p.x as i32, -50 * p.y as i32);
    (t.dx0, t.dy0) = (I24::new(dx0), I24::new(dy0));
    let m = (dx0.unsigned_abs().max((dx0 + xm).unsigned_abs()))
        .max(dy0.unsigned_abs().max((dy0 + ym).unsigned_abs()));
    t.shift = 0;
    while m >> t.shift > 65534 {
        t.shift += 1;
    }
    let sh = (t.shift as i32) << 21;
    t.rho = p.rho + sh;
    t.lclamp = LOG2_CLAMP - sh;
    t.w = if (1..=3).contains(&p.weight) {
        p.weight
    } else {
        4
    };
}

/// The reference of [`TermKernel::guess`]: the anchors' centroid weighted by `1/d̂² = 2^ρ` (to
/// a power of two: the first anchor's 32, then halving per unit of sort key `ρ − 2^21·shift`
/// below the first's, none from 6 units below on: the anchors are sorted by it, largest first),
/// `(−Σw·dx0, −Σw·dy0)/Σw` in lattice units (the window at the origin), rounded to the coarse
/// grid of steps `5·xstep`, `5·ystep` (no anchors: `(0, 0)`). A search's first bound; any
/// point would give the same result.
pub fn portable_guess(job: &ColumnJob) -> (u8, u8) {
    let a = &job.anchors[..(job.n as usize).min(MAX_ANCHORS)];
    let key = |t: &AnchorTerm| t.rho.wrapping_sub((t.shift as i32) << 21);
    let top = a.first().map_or(0, key);
    // Σw ≤ 2^8; |Σw·x| < 2^29 (|x| < 2^21 lattice units in a search; 24-bit offsets in general
    // wrap like the assembly's 32-bit sums).
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
    (snap(sx, job.xstep, sw), snap(sy, job.ystep, sw))
}

/// The coarse index `c ≤ 10` of the weighted mean `s/sw` (lattice units) along a side of `side`
/// cm: `(c − ½)·5·side < s/sw ≤ (c + ½)·5·side`, found by steps (no division; signed 32-bit
/// comparisons of `2s` with `(2c + 1)·5·side·sw < 2^31`).
fn snap(s: i32, side: u16, sw: i32) -> u8 {
    let t = 5 * side as i32 * sw;
    let (mut c, mut v) = (0, t);
    while c < 10 && v < s.wrapping_mul(2) {
        c += 1;
        v += 2 * t;
    }
    c
}

/// The reference of [`TermKernel::move_window`]: `dx0 += di·xstep`, `dy0 += dj·ystep` for every
/// anchor slot, wrapping at 24 bits.
pub fn portable_move(job: &mut ColumnJob, di: i8, dj: i8) {
    let dx = job.xstep as i32 * di as i32;
    let dy = job.ystep as i32 * dj as i32;
    for t in &mut job.anchors {
        t.dx0.add(dx);
        t.dy0.add(dy);
    }
}

/// The reference of [`TermKernel::column`]: every row's cost from scratch, column offset `col`.
/// Rows in `job.skip` get `u32::MAX`; for every other row the anchors' weighted terms
/// `w·term(dx² + dy², ρ, clamp)` (squares from [`offset_square`]) are added in order to 0, and
/// a row whose sum reaches `job.bound` is set to the bound and the rest of its anchors are
/// skipped (its exact cost no longer matters; with the bound at `u32::MAX − 1` that is the cost
/// saturated there). Fills every `dx2`, and `min`/`min_row` with the first smallest completed
/// sum below the bound (what a search offers) and its fine row offset.
#[inline(always)]
pub fn portable_column<K: TermKernel>(sums: &mut [u32], job: &mut ColumnJob) {
    let n = (job.n as usize).min(MAX_ANCHORS);
    let dx = job.col as i32 * job.xstep as i32;
    for a in &mut job.anchors[..n] {
        a.dx2 = offset_square(a.dx0.get().wrapping_add(dx), a.shift);
    }
    (job.min, job.min_row) = (u32::MAX, 0);
    let mut skip = job.skip;
    let mut off = 0u8;
    for sum in sums.iter_mut() {
        let skipped = skip & 1 != 0;
        skip >>= 1;
        let o = off;
        off = off.wrapping_add(job.stride);
        if skipped {
            *sum = u32::MAX;
            continue;
        }
        let mut s = 0u32;
        for a in &job.anchors[..n] {
            let dy = a.dy0.get().wrapping_add(o as i32 * job.ystep as i32);
            s = add_term::<K>(s, a.dx2, offset_square(dy, a.shift), a.rho, a.lclamp, a.w);
            if s >= job.bound {
                s = job.bound;
                break;
            }
        }
        if s < job.bound && s < job.min {
            (job.min, job.min_row) = (s, o);
        }
        *sum = s;
    }
    job.skip = skip;
}

/// `sum` plus one anchor's weighted term `w·(ρ + max(log2 d², clamp))²` (Q.20, saturating) for
/// `d² = dx2 + dy2` (33 bits); `w` outside 1..=3 counts as 4.
#[inline(always)]
pub(crate) fn add_term<K: TermKernel>(
    sum: u32,
    dx2: u32,
    dy2: u32,
    rho: i32,
    lclamp: i32,
    w: u8,
) -> u32 {
    let (lo, carry) = dx2.overflowing_add(dy2);
    // Below 2^30 − 1, so w·sq fits.
    let sq = K::term(lo, carry, rho, lclamp);
    let t = match w {
        1 => sq,
        2 => sq << 1,
        3 => sq + (sq << 1),
        _ => sq << 2,
    };
    sum.saturating_add(t)
}

/// The portable kernel: plain Rust, used on the host and by default.
#[derive(Clone, Copy, Debug, Default)]
pub struct Portable;

impl TermKernel for Portable {
    #[inline(always)]
    fn term(lo: u32, carry: bool, rho: i32, lclamp: i32) -> u32 {
        portable_term(lo, carry, rho, lclamp)
    }
}

/// `min((ρ + max(log2 d², clamp))², 32²)` in Q.20 for the squared distance
/// `d² = lo + 2^32·carry` (shifted lattice units), `ρ` and the clamp in Q.20.
///
/// `log2` is the 64-segment quadratic of [`log2_segment_table`] (error < 2.2·10⁻⁶; `log2 0` is
/// taken as 0, below any clamp in use); `|ρ + l|` saturates at [`U_SAT`] (the term is then
/// [`SQ_SAT`]); otherwise the square is formed from `|u| >> 2` (Q.18) with five 8 × 8 products,
/// within 2 ulp below the exact value.
#[inline(always)]
pub fn portable_term(lo: u32, carry: bool, rho: i32, lclamp: i32) -> u32 {
    let l = log2_fast(lo, carry).max(lclamp);
    let u = rho.wrapping_add(l).unsigned_abs();
    if u >= U_SAT {
        SQ_SAT
    } else {
        sq_q18(u >> 2)
    }
}

/// Address of the log2 segment table (64 segments × 6 bytes: `c0` 3 bytes, `c1` 2, `c2` 1,
/// little endian, Q.20): on AVR a flash address, to be read with `lpm`.
pub fn log2_segment_table() -> *const [u8; 6] {
    tables::log2_seg_table()
}

/// [`log2_segment_table`] less 384 bytes (never dereferenced as such): segment `k` of a
/// normalised `d²` whose top byte is `64 + k` starts at `6·(64 + k)` from it, one add fewer per
/// term in an assembly kernel.
pub fn log2_segment_base() -> *const u8 {
    log2_segment_table().cast::<u8>().wrapping_sub(6 * 64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exact(lo: u32, carry: bool, rho: i32, lclamp: i32) -> f64 {
        let d2 = lo as f64 + if carry { 4294967296.0 } else { 0.0 };
        let l = if d2 == 0.0 {
            0.0
        } else {
            libm::log2(d2) * 1048576.0
        };
        let u = rho as f64 + l.max(lclamp as f64);
        (u * u / 1048576.0).min(SQ_SAT as f64)
    }

    #[test]
    fn the_term_is_the_clamped_saturated_square() {
        // Within a few ulp of the exact value (log2 error × 2|u| plus the square's 2 ulp).
        for (lo, carry, rho, clamp) in [
            (1u32, false, 0i32, 0i32),
            (2500, false, -(10 << 20), 11_836_024),
            (1 << 30, false, -(30 << 20), 0),
            (123_456_789, true, -(31 << 20), 0),
            (4_000_000, false, -(22 << 20), 0),
        ] {
            let got = portable_term(lo, carry, rho, clamp) as f64;
            let want = exact(lo, carry, rho, clamp);
            assert!(
                (got - want).abs() <= 4.0 + want * 1e-5,
                "{lo}: {got} vs {want}"
            );
        }
        // The clamp: any d² below it gives the clamp's term.
        let clamp = 11_836_024; // log2(2500) in Q.20
        assert_eq!(portable_term(0, false, -clamp, clamp), 0);
        assert_eq!(portable_term(7, false, -clamp, clamp), 0);
        // Saturation: |u| ≥ 32 log2 units.
        assert_eq!(portable_term(1 << 20, false, 20 << 20, 0), SQ_SAT);
        assert_eq!(portable_term(1, false, i32::MIN, 0), SQ_SAT);
        assert!(portable_term(1 << 20, false, 11 << 20, 0) < SQ_SAT);
    }
}
