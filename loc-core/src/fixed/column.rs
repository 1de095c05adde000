//! The position search's hot loop: the costs of one column of lattice points.
//!
//! A search evaluates its windows a column at a time: for every row of the column, the sum over
//! the anchors of `w·(ρ + max(log2 d², clamp))²`, stopped as soon as it reaches a bound (the
//! point can then no longer win). That sum is nearly all of an estimate's cycles, so it is the
//! one piece of the estimator with a hand-written twin: [`Portable`] is the definition, and on
//! the ATmega328P `Avr` runs the same arithmetic in AVR assembly (`column/avr.rs`), kept
//! equal to it by one table-driven harness (`mcu-bench`'s `checkasm` firmware, run in simavr by
//! `tests/tests/checkasm.rs`). Everything around it, including the searches that call it, is the
//! same Rust on the host and on the sink.
//!
//! # The contract
//!
//! [`ColumnKernel::column`]`(sums, job)` fills `sums` (one row each, at most 255) for column
//! offset `job.col`, and sets `job.min`/`job.min_row` and every used anchor's `dx2`. For each row
//! `r` (fine row offset `o = r·stride`):
//!
//! * a row whose bit is set in `job.skip` (rows 0…15) is not evaluated and gets `u32::MAX`;
//! * otherwise the anchors `0..job.n` are summed in order, each term
//!   `w·term(dx² + dy², ρ, clamp)` ([`term`], saturating `u32` sum), with
//!   `dx² = offset_square(dx0 + col·xstep, shift)` and `dy² = offset_square(dy0 + o·ystep,
//!   shift)` ([`offset_square`], 24-bit offsets); as soon as the sum reaches `job.bound` the row
//!   is set to the bound and its other anchors are skipped;
//! * `job.min` is the first smallest sum below the bound that was completed (`u32::MAX` if
//!   none), `job.min_row` its fine row offset (0 if none).
//!
//! Inputs the kernels must agree on: `n ≤` [`MAX_ANCHORS`] (more count as [`MAX_ANCHORS`]), every
//! used anchor's `w` in 1…4 and `shift` ≤ 15, any offsets, `ρ`, clamp, bound, steps and stride.
//! The searches only ever build such jobs ([`crate::fixed`]'s setup clamps weights to 1…4 and
//! picks shifts ≤ 8). `job.skip` and `job.scratch` are the kernels' to use: their values after a
//! call are not part of the result.

use super::math::{log2_fast, sq16, sq_q18};
use crate::MAX_ANCHORS;

#[cfg(target_arch = "avr")]
#[allow(unsafe_code)]
mod avr;
#[cfg(target_arch = "avr")]
pub use avr::Avr;

/// `|u|` at which [`term`] saturates, Q.20: 32 log2 units (`|z − p| ≥ 32·K` dB).
pub const U_SAT: u32 = 32 << 20;
/// The saturated term: `32²` in Q.20, less one (four of them still fit a `u32`).
pub const SQ_SAT: u32 = (1 << 30) - 1;

/// Computes one column of a search window (see the [module docs](self) for the contract).
pub trait ColumnKernel {
    /// The costs of `job`'s column into `sums` (one per row, at most 255 rows), `job.min` and
    /// `job.min_row`, every used anchor's `dx2`.
    fn column(sums: &mut [u32], job: &mut ColumnJob);
}

/// The definition: plain Rust, used on the host and as the reference of every other kernel.
#[derive(Clone, Copy, Debug, Default)]
pub struct Portable;

impl ColumnKernel for Portable {
    #[inline(never)]
    fn column(sums: &mut [u32], job: &mut ColumnJob) {
        portable_column(sums, job)
    }
}

/// The kernel the searches use by default: [`Avr`] on the ATmega328P, [`Portable`] elsewhere.
#[cfg(target_arch = "avr")]
pub type Native = Avr;
/// The kernel the searches use by default: `Avr` on the ATmega328P, [`Portable`] elsewhere.
#[cfg(not(target_arch = "avr"))]
pub type Native = Portable;

/// A 24-bit two's-complement integer, 3 bytes little endian: an [`AnchorTerm`]'s offsets.
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

    /// `self + v`, wrapping at 24 bits.
    #[inline(always)]
    pub fn add(&mut self, v: i32) {
        *self = I24::new(self.get().wrapping_add(v));
    }
}

/// One anchor of a [`ColumnJob`]: its offsets from the window's first lattice point, in lattice
/// units, and its part of the cost.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AnchorTerm {
    /// `dx²` of the column being evaluated (shifted): written by the kernel.
    pub dx2: u32,
    /// `dx` of the window's column 0; column offset `c`'s is `dx0 + c·xstep`.
    pub dx0: I24,
    /// `dy` of the window's row 0; fine row offset `o`'s is `dy0 + o·ystep`.
    pub dy0: I24,
    /// `log2` of the 1 cm clamp, Q.20, less `2·shift`.
    pub lclamp: i32,
    /// The anchor's `ρ = (z − P0)/K − log2(1 m²)`, Q.20, plus `2·shift`.
    pub rho: i32,
    /// The anchor's weight, 1 to 4.
    pub w: u8,
    /// `dx` and `dy` are `|·|` rounded to `2^shift` units before they are squared.
    pub shift: u8,
}

impl AnchorTerm {
    /// No anchor (a placeholder for unused slots).
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

/// One column of a search window for [`ColumnKernel::column`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ColumnJob {
    /// Rows whose sum reaches it stop there (they cannot win any more).
    pub bound: u32,
    /// Anchors in use (0: every row not skipped costs 0).
    pub n: u8,
    /// Rows not to evaluate: bit `r` for row `r` (rows from 16 on are all evaluated).
    pub skip: u16,
    /// The column's offset from the window's first column, fine lattice steps.
    pub col: u8,
    /// Fine rows from one row of the column to the next (1: the fine lattice, 5: the coarse).
    pub stride: u8,
    /// Fine column step, lattice units.
    pub xstep: u16,
    /// Fine row step, lattice units.
    pub ystep: u16,
    /// Output: the first smallest sum completed below the bound (`u32::MAX` if none)…
    pub min: u32,
    /// …and its fine row offset (`row·stride`).
    pub min_row: u8,
    /// The kernels' workspace (the AVR kernel's loop counters).
    pub scratch: [u8; 2],
    /// The anchors, in evaluation order.
    pub anchors: [AnchorTerm; MAX_ANCHORS],
}

impl ColumnJob {
    /// No anchors, every field zero.
    pub const EMPTY: ColumnJob = ColumnJob {
        bound: 0,
        n: 0,
        skip: 0,
        col: 0,
        stride: 0,
        xstep: 0,
        ystep: 0,
        min: 0,
        min_row: 0,
        scratch: [0; 2],
        anchors: [AnchorTerm::NONE; MAX_ANCHORS],
    };

    /// The anchors in use.
    pub fn used(&self) -> &[AnchorTerm] {
        &self.anchors[..(self.n as usize).min(MAX_ANCHORS)]
    }
}

/// [`Portable`]'s column: the contract of the [module docs](self), written out.
#[inline(always)]
pub fn portable_column(sums: &mut [u32], job: &mut ColumnJob) {
    let n = (job.n as usize).min(MAX_ANCHORS);
    let dx = job.col as i32 * job.xstep as i32;
    for a in &mut job.anchors[..n] {
        a.dx2 = offset_square(a.dx0.get().wrapping_add(dx), a.shift);
    }
    (job.min, job.min_row) = (u32::MAX, 0);
    let mut skip = job.skip;
    let mut off = 0u8;
    for sum in sums.iter_mut().take(255) {
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
            let (lo, carry) = a.dx2.overflowing_add(offset_square(dy, a.shift));
            s = s.saturating_add(weighted(term(lo, carry, a.rho, a.lclamp), a.w));
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

/// `w·t` for the term `t < 2^30` and a weight `w` in 1…4.
#[inline(always)]
fn weighted(t: u32, w: u8) -> u32 {
    match w {
        1 => t,
        2 => t << 1,
        3 => t + (t << 1),
        _ => t << 2,
    }
}

/// `min((ρ + max(log2 d², clamp))², 32²)` in Q.20 for the squared distance
/// `d² = lo + 2^32·carry` (shifted lattice units), `ρ` and the clamp in Q.20.
///
/// `log2` is the 64-segment quadratic of the flash table (error < 2.2·10⁻⁶; `log2 0` is taken as
/// 0, below any clamp in use); `|ρ + l|` saturates at [`U_SAT`] (the term is then [`SQ_SAT`]);
/// otherwise the square is formed from `|u| >> 2` (Q.18) with five 8 × 8 products, within 2 ulp
/// below the exact value.
#[inline(always)]
pub fn term(lo: u32, carry: bool, rho: i32, lclamp: i32) -> u32 {
    let l = log2_fast(lo, carry).max(lclamp);
    let u = rho.wrapping_add(l).unsigned_abs();
    if u >= U_SAT {
        SQ_SAT
    } else {
        sq_q18(u >> 2)
    }
}

/// `|v|` rounded to `2^shift` units (half up), squared: `v` taken as a 24-bit value, the rounded
/// magnitude as 16 bits (`shift ≤ 15`).
#[inline(always)]
pub fn offset_square(v: i32, shift: u8) -> u32 {
    let a = ((v << 8) >> 8).unsigned_abs();
    let r = if shift == 0 {
        a
    } else {
        let s = (shift & 15) as u32;
        (a >> s) + ((a >> (s - 1)) & 1)
    };
    sq16((r & 0xFFFF) as i32)
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
            let got = term(lo, carry, rho, clamp) as f64;
            let want = exact(lo, carry, rho, clamp);
            assert!(
                (got - want).abs() <= 4.0 + want * 1e-5,
                "{lo}: {got} vs {want}"
            );
        }
        // The clamp: any d² below it gives the clamp's term.
        let clamp = 11_836_024; // log2(2500) in Q.20
        assert_eq!(term(0, false, -clamp, clamp), 0);
        assert_eq!(term(7, false, -clamp, clamp), 0);
        // Saturation: |u| ≥ 32 log2 units.
        assert_eq!(term(1 << 20, false, 20 << 20, 0), SQ_SAT);
        assert_eq!(term(1, false, i32::MIN, 0), SQ_SAT);
        assert!(term(1 << 20, false, 11 << 20, 0) < SQ_SAT);
    }

    #[test]
    fn offsets_are_rounded_then_squared() {
        assert_eq!(offset_square(-3, 0), 9);
        assert_eq!(offset_square(1000, 0), 1_000_000);
        // 24-bit: bit 23 is the sign.
        assert_eq!(offset_square(1 << 23, 8), (1 << 15) * (1 << 15));
        // Half up: 5/2 → 3, 4/2 → 2, −5/2 → 3.
        assert_eq!(offset_square(5, 1), 9);
        assert_eq!(offset_square(4, 1), 4);
        assert_eq!(offset_square(-5, 1), 9);
    }

    /// The contract's rules on a small hand-made job: skipped rows, the bound, the minimum.
    #[test]
    fn a_column_follows_the_contract() {
        let mut job = ColumnJob::EMPTY;
        (job.xstep, job.ystep, job.stride, job.col) = (10, 10, 1, 2);
        job.n = 1;
        job.anchors[0] = AnchorTerm {
            dx0: I24::new(-20),
            dy0: I24::new(-30),
            lclamp: 0,
            rho: 0,
            w: 2,
            ..AnchorTerm::NONE
        };
        job.bound = u32::MAX - 1;
        job.skip = 0b10;
        let mut sums = [0u32; 6];
        Portable::column(&mut sums, &mut job);
        // Column 2: dx = 0; row 3: dy = 0 (log2 0 = 0, term 0): the minimum.
        assert_eq!(job.anchors[0].dx2, 0);
        assert_eq!(sums[1], u32::MAX);
        assert_eq!(sums[3], 0);
        assert_eq!((job.min, job.min_row), (0, 3));
        for r in [0, 2, 4, 5] {
            let dy = -30 + 10 * r as i32;
            let want = 2 * term(offset_square(dy, 0), false, 0, 0);
            assert_eq!(sums[r], want, "row {r}");
        }
        // A lower bound: the rows that reach it are set to it, the others keep their cost.
        let before = sums;
        job.bound = sums[2].min(sums[4]);
        job.skip = 0b10;
        Portable::column(&mut sums, &mut job);
        for r in [0, 2, 3, 4, 5] {
            let want = if before[r] >= job.bound {
                job.bound
            } else {
                before[r]
            };
            assert_eq!(sums[r], want, "row {r}");
        }
        assert_eq!((job.min, job.min_row), (0, 3));
    }
}
