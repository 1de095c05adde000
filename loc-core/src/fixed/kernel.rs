//! The position search's per-(lattice point, anchor) arithmetic, pluggable.
//!
//! Everything else in a search is bookkeeping; this term is evaluated a few hundred times per
//! fix, and LLVM's AVR backend turns it into ≈ 650 cycles (it composes 8 × 8 products into
//! 16/32-bit values with many moves and spills). The trait lets the sink firmware plug in the
//! hand-written AVR version of `uno-board` (`uno_board::AvrTerm`, ≈ 7× fewer cycles) while
//! this crate keeps no `unsafe`. Every implementation must return exactly [`portable_term`]'s
//! value for every input; `uno-board`'s is checked against it in simavr.

use super::math::{log2_fast, sq_q18};
use super::tables;

/// `|u|` at which [`portable_term`] saturates, Q.20: 32 log2 units (`|z − p| ≥ 32·K` dB).
pub const U_SAT: u32 = 32 << 20;
/// The saturated term: `32²` in Q.20, less one (four of them still fit a `u32`).
pub const SQ_SAT: u32 = (1 << 30) - 1;

/// One anchor's squared residual at one lattice point.
pub trait TermKernel {
    /// Exactly [`portable_term`]`(lo, carry, rho, lclamp)`.
    fn term(lo: u32, carry: bool, rho: i32, lclamp: i32) -> u32;
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
