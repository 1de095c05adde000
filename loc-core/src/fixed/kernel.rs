//! The position search's per-(lattice point, anchor) arithmetic, pluggable.
//!
//! Everything else in a search is bookkeeping; this term is evaluated a few hundred times per
//! fix, and LLVM's AVR backend turns it into ≈ 650 cycles (it composes 8 × 8 products into
//! 16/32-bit values with many moves and spills). The trait lets the sink firmware plug in the
//! hand-written AVR version of `uno-board` (`uno_board::AvrTerm`, ≈ 7× fewer cycles) while
//! this crate keeps no `unsafe`. Every implementation must return exactly [`portable_term`]'s
//! value for every input; `uno-board`'s is checked against it in simavr.

use super::math::{log2_fast, log2_floor, sq16, sq_q18, LOG2_SEG_SPAN};
use super::tables;
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
}

/// One anchor of a [`ColumnJob`]: the unshifted case, where `|dx|` and every row's `|dy|` are
/// below `2^16` lattice units (13.1 m).
///
/// `repr(C)`: assembly kernels read it by offset (on AVR, where nothing is padded: `dx2` 0,
/// `adx` 4, `dy0` 6, `step` 10, `lclamp` 12, `rho` 16, `table` 20, `w` 22, `far` 23, `near` 27;
/// 31 bytes).
///
/// `far` and `near` are the ring test: a row whose `log2_floor(d²)` (the exponent and the
/// segment's start, known before any product) is at least `far` or at most `near` is set to the
/// bound at once. The search derives them from the bound so that such a row's term alone would
/// reach it ([`ring`]); [`AnchorTerm::NONE`]'s never reject.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct AnchorTerm {
    /// `dx²` of the column: scratch, the kernel computes it from `adx`.
    pub dx2: u32,
    /// `|dx|` of the column, lattice units.
    pub adx: u16,
    /// `dy` of row 0, lattice units; row `r`'s is `dy0 + r·step` (`|dy| < 2^16` on every row).
    pub dy0: i32,
    /// Row step, lattice units.
    pub step: u16,
    /// `log2` of the 1 cm clamp, Q.20.
    pub lclamp: i32,
    /// The anchor's `ρ`, Q.20.
    pub rho: i32,
    /// [`log2_segment_table`], for kernels that read it directly.
    pub table: *const [u8; 6],
    /// The anchor's weight, 1 to 4.
    pub w: u8,
    /// Ring test: reject from this `log2_floor(d²)` up (Q.20)…
    pub far: i32,
    /// …and from this one down.
    pub near: i32,
}

impl AnchorTerm {
    /// No anchor (a placeholder for unused slots).
    pub const NONE: AnchorTerm = AnchorTerm {
        dx2: 0,
        adx: 0,
        dy0: 0,
        step: 0,
        lclamp: 0,
        rho: 0,
        table: core::ptr::null(),
        w: 1,
        far: i32::MAX,
        near: i32::MIN,
    };
}

/// The ring test's thresholds `(far, near)` for an anchor with `ρ`, clamp `lclamp` and weight
/// `w` (1 to 4) under `bound`: every `d² > 0` with `log2_floor(d²) ≥ far` or `≤ near` has
/// `w·term(d²) ≥ bound`, so its row reaches the bound whatever the other anchors add.
///
/// With `T = ⌈bound/2^s⌉ ≥ ⌈bound/w⌉` (`s` = 0, 1, 1, 2 for `w` = 1…4: no division) and
/// `U = 3 + r·2^10` for some `r ≥ √(T+3)` (`sqrt_above`: no loop), every `|u| ≥ U` has `term ≥ T` (the square is at most 2 ulp
/// low and `|u| >> 2` drops at most 3/4; saturated terms are `SQ_SAT ≥ T`). Far: `log2 ≥
/// log2_floor ≥ U − ρ`. Near: `log2 ≤ log2_floor + LOG2_SEG_SPAN ≤ −U − ρ`, and the clamp must
/// not lift it (`lclamp ≤ −U − ρ`). `T > SQ_SAT`: no threshold.
pub fn ring(bound: u32, rho: i32, lclamp: i32, w: u8) -> (i32, i32) {
    ring_around(ring_radius(bound, w), rho, lclamp)
}

/// `U` of [`ring`] for `bound` and weight `w` (the square root, shared by the anchors of equal
/// weight); `None`: no threshold.
pub fn ring_radius(bound: u32, w: u8) -> Option<i32> {
    let s = match w {
        1 => 0,
        2 | 3 => 1,
        _ => 2,
    };
    let t = (bound >> s) + (bound & ((1 << s) - 1) != 0) as u32;
    if t > SQ_SAT {
        return None;
    }
    // Below 2^26.
    Some(3 + (sqrt_above(t + 3) << 10) as i32)
}

/// A cheap `r ≥ √x` (within 25 %), `x ≥ 1`: one Newton step from the power of two above the
/// root, whose division is a shift (the arithmetic–geometric mean keeps it above the root).
fn sqrt_above(x: u32) -> u32 {
    let k = (33 - x.leading_zeros()) / 2; // 2^k ≥ √x
    (((1u32 << k) + (x >> k) + 1) >> 1) + 1
}

/// [`ring`]'s `(far, near)` from its radius `u` ([`ring_radius`]).
pub fn ring_around(u: Option<i32>, rho: i32, lclamp: i32) -> (i32, i32) {
    let Some(u) = u else {
        return (i32::MAX, i32::MIN);
    };
    let far = u.saturating_sub(rho);
    let top = (-u).saturating_sub(rho);
    let near = if lclamp <= top {
        top.saturating_sub(LOG2_SEG_SPAN)
    } else {
        i32::MIN
    };
    (far, near)
}

/// A column of a search window, for [`TermKernel::column`] (on AVR: `bound` at offset 0, `n`
/// 4, `rows` 5, `min` 6, `min_row` 10, the anchors from 11).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct ColumnJob {
    /// Rows whose sum reaches it stop there (they cannot win any more).
    pub bound: u32,
    /// Anchors in use (1 to [`MAX_ANCHORS`]).
    pub n: u8,
    /// Rows of the column (kernels may set it from the slice length; the searches do).
    pub rows: u8,
    /// Output: the smallest sum the kernel completed below the bound (`u32::MAX` if none)…
    pub min: u32,
    /// …and its first row.
    pub min_row: u8,
    /// The anchors, in evaluation order.
    pub anchors: [AnchorTerm; MAX_ANCHORS],
}

/// The reference of [`TermKernel::column`]. For every row whose sum is below `job.bound`, the
/// anchors' weighted terms `w·term(dx² + dy², ρ, clamp)` are added in order; a row whose sum
/// reaches the bound is set to the bound and the rest of its anchors are skipped (its exact
/// cost no longer matters); so is a row that fails an anchor's ring test (`far`/`near`, checked
/// before its term when `d² > 0`). Rows not below the bound are left alone. Fills every `dx2`, and
/// `min`/`min_row` with the first smallest completed sum (what a search offers).
#[inline(always)]
pub fn portable_column<K: TermKernel>(sums: &mut [u32], job: &mut ColumnJob) {
    let n = (job.n as usize).min(MAX_ANCHORS);
    for a in &mut job.anchors[..n] {
        a.dx2 = sq16(a.adx as i32);
    }
    (job.min, job.min_row) = (u32::MAX, 0);
    for (r, sum) in sums.iter_mut().enumerate() {
        if *sum >= job.bound {
            continue;
        }
        let mut s = *sum;
        for a in &job.anchors[..n] {
            let dy = a.dy0.wrapping_add((r as i32).wrapping_mul(a.step as i32));
            let dy2 = sq16(dy);
            let (lo, carry) = a.dx2.overflowing_add(dy2);
            if lo != 0 || carry {
                let l = log2_floor(lo, carry);
                if l >= a.far || l <= a.near {
                    s = job.bound;
                    break;
                }
            }
            s = add_term::<K>(s, a.dx2, dy2, a.rho, a.lclamp, a.w);
            if s >= job.bound {
                s = job.bound;
                break;
            }
        }
        if s < job.bound && s < job.min {
            (job.min, job.min_row) = (s, r as u8);
        }
        *sum = s;
    }
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

    /// The ring test only ever rejects rows that would have reached the bound anyway: with
    /// `ring`'s thresholds every completed row keeps its exact sum and every other row is at
    /// or above the bound, on random columns around anchors; and it does reject (most rows).
    #[test]
    fn the_ring_test_changes_no_decision() {
        let mut x = 0x2545_F491u32;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x
        };
        let (mut rejected, mut rows_seen) = (0, 0);
        for _ in 0..3000 {
            let n = 3 + (next() % 6) as usize;
            let mut job = ColumnJob {
                bound: 0,
                n: n as u8,
                rows: 11,
                min: 0,
                min_row: 0,
                anchors: [AnchorTerm::NONE; MAX_ANCHORS],
            };
            // A true point on the column (row `rt`, off it by `ox` across), anchors around it,
            // and ρ from the true distances plus noise: costs as a search meets them.
            let (rt, ox) = ((next() % 11) as i32, (next() % 3000) as f64);
            let step = 200 + next() % 5000;
            for a in job.anchors[..n].iter_mut() {
                *a = AnchorTerm {
                    adx: (next() % 60_000) as u16,
                    dy0: (next() % 5_000) as i32 - (next() % 60_000) as i32,
                    step: step as u16,
                    lclamp: 11_836_024,
                    w: 1 + (next() % 4) as u8,
                    ..AnchorTerm::NONE
                };
                // Keep every |dy| below 2^16.
                let last = a.dy0 + 10 * a.step as i32;
                if last >= 1 << 16 {
                    a.dy0 -= last - (1 << 16) + 1;
                }
                let dy = (a.dy0 + rt * a.step as i32) as f64;
                let d2 = (a.adx as f64 + ox).powi(2) + dy * dy;
                let noise = (next() % 600_000) as f64 - 300_000.0;
                a.rho = (-(d2.max(1.0).log2() * 1048576.0) + noise) as i32;
            }
            // A bound near the column's smallest cost, as a search has.
            let mut plain = [0u32; 11];
            job.bound = u32::MAX;
            portable_column::<Portable>(&mut plain, &mut job);
            let m = *plain.iter().min().unwrap();
            job.bound = m.saturating_add(m >> (next() % 6));
            let mut without = [0u32; 11];
            portable_column::<Portable>(&mut without, &mut job);
            for a in job.anchors[..n].iter_mut() {
                (a.far, a.near) = ring(job.bound, a.rho, a.lclamp, a.w);
            }
            let mut with = [0u32; 11];
            portable_column::<Portable>(&mut with, &mut job);
            // Reached rows are left at the bound either way: identical sums.
            assert_eq!(with, without);
            // The ring does work: rows the first anchor's test alone rejects.
            let a = &job.anchors[0];
            for r in 0..11 {
                rows_seen += 1;
                let dy = a.dy0 + r * a.step as i32;
                let (lo, carry) = sq16(a.adx as i32).overflowing_add(sq16(dy));
                let l = log2_floor(lo, carry);
                rejected += (l >= a.far || l <= a.near) as usize;
            }
        }
        assert!(rejected * 5 > rows_seen, "{rejected} of {rows_seen}");
    }

    #[test]
    fn sqrt_above_is_above_and_close() {
        let mut x = 1u32;
        while x < u32::MAX / 3 {
            let r = sqrt_above(x) as f64;
            let s = (x as f64).sqrt();
            assert!(r >= s && r <= 1.25 * s + 2.0, "{x}: {r} vs {s}");
            x = x * 3 / 2 + 1;
        }
        assert!(sqrt_above(u32::MAX) as f64 >= (u32::MAX as f64).sqrt());
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
