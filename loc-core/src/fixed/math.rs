//! Integer kernels: log2, exp2, squares, square root, clamps.
//!
//! Everything here is exact integer arithmetic on fixed-point numbers; the comments give each
//! value's format (`Q.n`: an integer scaled by `2^n`).

use super::tables::{exp2_seg, log2_seg};

/// 8 × 8 → 16 multiply: one `mul` instruction on AVR (a 32-bit multiply is a library call
/// there), the building block of every product in the inner loops.
#[inline(always)]
pub(crate) fn m8(a: u8, b: u8) -> u16 {
    a as u16 * b as u16
}

/// `a²` for a 16-bit `a` (three 8 × 8 multiplies). Out of line: `distance_x`'s two squares share
/// one copy.
#[inline(never)]
pub(crate) fn sq_u16(a: u16) -> u32 {
    let [a0, a1] = a.to_le_bytes();
    (m8(a0, a0) as u32 | (m8(a1, a1) as u32) << 16) + ((m8(a0, a1) as u32) << 9)
}

/// `log2(x)` in Q.20 for `x ≥ 1` (`x = 0` gives 0; callers never pass it).
pub(crate) fn log2_u32(x: u32) -> i32 {
    log2_u33(x, false)
}

/// `log2(lo + 2^32·carry)` in Q.20 (`0` for `0`): the out-of-line copy for everything but the
/// position search's inner loop, bit for bit [`log2_fast`] with one copy of the table evaluation
/// (the carry folded into the normalisation instead of [`log2_carry`]'s second copy).
#[inline(never)]
pub(crate) fn log2_u33(lo: u32, carry: bool) -> i32 {
    // With a carry the value is 2^32 + lo: its top 32 bits (the dropped lowest bit is 2^−32 of
    // it), exponent 32.
    let (mut n, mut e) = (lo, 31i32);
    if carry {
        (n, e) = ((lo >> 1) | 1 << 31, 32);
    } else {
        if lo == 0 {
            return 0;
        }
        if n < 1 << 16 {
            n <<= 16;
            e -= 16;
        }
        if n < 1 << 24 {
            n <<= 8;
            e -= 8;
        }
        while n < 1 << 31 {
            n <<= 1;
            e -= 1;
        }
    }
    (e << 20) + log2_mantissa(n) as i32
}

/// `log2(lo + 2^32·carry)` in Q.20 (`0` for `0`), for the sum of two `u32` squares.
///
/// Normalises with byte moves and at most 7 single-bit shifts, then evaluates the segment
/// quadratic of the flash table on the 16 bits below the 6 segment bits, with six 8 × 8
/// multiplies. Every shift has a constant count (on AVR a variable count is a loop). Error below
/// `2.2·10⁻⁶` (2.3 ulp) over the whole range; `tests::log2_is_accurate` checks it.
#[inline(always)]
pub(crate) fn log2_fast(lo: u32, carry: bool) -> i32 {
    if carry {
        return log2_carry(lo);
    }
    if lo == 0 {
        return 0;
    }
    let (mut n, mut e) = (lo, 31i32);
    if n < 1 << 16 {
        n <<= 16;
        e -= 16;
    }
    if n < 1 << 24 {
        n <<= 8;
        e -= 8;
    }
    while n < 1 << 31 {
        n <<= 1;
        e -= 1;
    }
    (e << 20) + log2_mantissa(n) as i32
}

/// `log2(2^32 + lo)` in Q.20 (out of line: rare, and kept apart so that the common path's shifts
/// stay constant).
#[cold]
#[inline(never)]
fn log2_carry(lo: u32) -> i32 {
    // The dropped lowest bit is 2^−32 of the value.
    (32 << 20) + log2_mantissa((lo >> 1) | 1 << 31) as i32
}

/// `log2(n / 2^31)` in Q.20 for a normalised `n ∈ [2^31, 2^32)`: in `[0, 2^20]`.
#[inline(always)]
fn log2_mantissa(n: u32) -> u32 {
    let k = ((n >> 25) & 63) as usize;
    // Position in the segment, Q.16: the 16 bits below the segment bits.
    let [t0, t1] = ((n >> 9) as u16).to_le_bytes();
    let [c0a, c0b, c0c, c1a, c1b, c2] = log2_seg(k);
    // c2·t (Q.20), then c1 − c2·t.
    let q = (m8(t1, c2) + (m8(t0, c2) >> 8)) >> 8;
    let [i0, i1] = (u16::from_le_bytes([c1a, c1b]) - q).to_le_bytes();
    // t·(c1 − c2·t), Q.20 (the t0·i0 product only feeds the rounding).
    let mid = m8(t1, i0) as u32 + m8(t0, i1) as u32 + (m8(t0, i0) >> 8) as u32;
    u32::from_le_bytes([c0a, c0b, c0c, 0]) + m8(t1, i1) as u32 + (mid >> 8)
}

/// `log2(x)` in Q.20 for any `x ≥ 1` (`0` for `0`). Not for inner loops.
pub(crate) fn log2_u64(mut x: u64) -> i32 {
    let mut e = 0;
    while x >> 33 != 0 {
        x >>= 1;
        e += 1 << 20;
    }
    e + log2_u33(x as u32, x >> 32 != 0)
}

/// `v² >> 16` for `v < 2^23` (a Q.18 value squared into Q.20), from five 8 × 8 multiplies,
/// within 2 ulp below the exact value.
#[inline(always)]
pub(crate) fn sq_q18(v: u32) -> u32 {
    let [v0, v1, v2, _] = v.to_le_bytes();
    // v² = v2²·2^32 + 2·v1·v2·2^24 + (v1² + 2·v0·v2)·2^16 + 2·v0·v1·2^8 + v0².
    ((m8(v2, v2) as u32) << 16)
        + ((m8(v1, v2) as u32) << 9)
        + m8(v1, v1) as u32
        + ((m8(v0, v2) as u32) << 1)
        + ((m8(v0, v1) as u32) << 1 >> 8)
}

/// `2^(−y)` for `y ≥ 0` in Q.16, as a weight in Q.26 (`2^26` for `y = 0`, `0` from `y ≥ 27`).
///
/// Linear interpolation in the 32-entry flash table: relative error below `1.3·10^−4`.
#[inline]
pub(crate) fn exp2_neg_q26(y: u32) -> u32 {
    let int = y >> 16;
    if int >= 27 {
        return 0;
    }
    let f = y & 0xFFFF;
    let [v, d] = exp2_seg((f >> 11) as usize);
    // Q.15 mantissa in (16384, 32768], then Q.26 = mantissa << 11 >> int, by constant shifts.
    let mut w = ((v as u32) - ((d as u32 * (f & 0x7FF)) >> 11)) << 11;
    if int & 16 != 0 {
        w >>= 16;
    }
    if int & 8 != 0 {
        w >>= 8;
    }
    if int & 4 != 0 {
        w >>= 4;
    }
    if int & 2 != 0 {
        w >>= 2;
    }
    if int & 1 != 0 {
        w >>= 1;
    }
    w
}

/// `v²` for `|v| < 2^16` (one 16 × 16 → 32 multiply; callers guarantee the range).
#[inline(always)]
pub(crate) fn sq16(v: i32) -> u32 {
    let a = v.unsigned_abs();
    a.wrapping_mul(a)
}

/// `⌊a·b / 2^32⌋`, within 2 below, from three 16 × 16 products (no 64-bit arithmetic).
#[inline(never)]
pub fn mul_hi(a: u32, b: u32) -> u32 {
    let (ah, al, bh, bl) = (a >> 16, a & 0xFFFF, b >> 16, b & 0xFFFF);
    ah * bh + ((ah * bl) >> 16) + ((al * bh) >> 16)
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

/// `log2(x)` in Q.20, rounded to the nearest, for `x ≥ 1`, at compile time: the constants of
/// the lattice and the fit are written as the logarithms they are. The fraction's bits come
/// from repeated squaring of the mantissa in Q.62 (24 of them, then rounded to 20); the
/// squarings' truncations stay far below the rounding (`tests` compares with f64).
pub const fn log2_q20(x: u64) -> i32 {
    let e = 63 - x.leading_zeros();
    let mut m = ((x as u128) << 62) >> e;
    let (mut frac, mut i) = (0u32, 0);
    while i < 24 {
        m = (m * m) >> 62;
        frac <<= 1;
        if m >= 2 << 62 {
            m >>= 1;
            frac |= 1;
        }
        i += 1;
    }
    ((e << 20) + ((frac + 8) >> 4)) as i32
}

/// `⌊√x⌋` (bit by bit; no table, no division).
pub(crate) fn isqrt_u32(x: u32) -> u32 {
    let mut rem = x;
    let mut root: u32 = 0;
    let mut bit: u32 = 1 << 30;
    while bit > rem {
        bit >>= 2;
    }
    while bit != 0 {
        if rem >= root + bit {
            rem -= root + bit;
            root = (root >> 1) + bit;
        } else {
            root >>= 1;
        }
        bit >>= 2;
    }
    root
}

/// `v` limited to `[lo, hi]` (never panics: `lo > hi` gives `hi`).
#[inline]
pub(crate) const fn clamp_i32(v: i32, lo: i32, hi: i32) -> i32 {
    // `v.max(lo).min(hi)`, spelled out to be `const`.
    let v = if v < lo { lo } else { v };
    if v > hi {
        hi
    } else {
        v
    }
}

/// `v` limited to `[lo, hi]` (never panics: `lo > hi` gives `hi`).
#[inline]
pub(crate) fn clamp_i64(v: i64, lo: i64, hi: i64) -> i64 {
    v.max(lo).min(hi)
}

/// `(a · b) >> s` rounded, for products that fit `i64`.
#[inline]
pub(crate) fn mul_shr(a: i64, b: i64, s: u32) -> i64 {
    let p = a * b;
    (p + (1 << (s - 1))) >> s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exact_log2(x: u64) -> f64 {
        libm::log2(x as f64) * (1u64 << 20) as f64
    }

    #[test]
    fn log2_is_accurate() {
        let mut worst: f64 = 0.0;
        // Powers, their neighbours, and a dense pseudo-random sweep.
        let mut probe = |x: u64| {
            let got = log2_u64(x);
            if let Ok(small) = u32::try_from(x) {
                assert_eq!(got, log2_u32(small), "{x}");
            }
            worst = worst.max((got as f64 - exact_log2(x)).abs());
        };
        for s in 0..63 {
            for d in [-1i64, 0, 1] {
                let v = (1u64 << s) as i64 + d;
                if v >= 1 {
                    probe(v as u64);
                }
            }
        }
        let mut r: u64 = 0x9E37_79B9_7F4A_7C15;
        for _ in 0..200_000 {
            r ^= r << 13;
            r ^= r >> 7;
            r ^= r << 17;
            probe((r >> (r % 40)).max(1));
        }
        assert!(worst < 2.4, "worst log2 error {worst} ulp of Q.20");
        assert!(log2_u32(1).abs() <= 1);
        assert!((log2_u32(1 << 20) - (20 << 20)).abs() <= 1);
        // The out-of-line copy is the inline one, bit for bit.
        let mut r: u64 = 0x2545_F491_4F6C_DD1D;
        for _ in 0..200_000 {
            r ^= r << 13;
            r ^= r >> 7;
            r ^= r << 17;
            let (lo, carry) = ((r >> (r % 32)) as u32, r & 1 != 0);
            assert_eq!(log2_u33(lo, carry), log2_fast(lo, carry), "{lo} {carry}");
        }
        for (lo, carry) in [
            (0, false),
            (0, true),
            (1, false),
            (u32::MAX, false),
            (u32::MAX, true),
        ] {
            assert_eq!(log2_u33(lo, carry), log2_fast(lo, carry), "{lo} {carry}");
        }
        // The 33-bit form.
        for v in [0u64, 1, 12345, 1 << 32, (1 << 32) + 7, (1 << 33) - 1] {
            let (lo, carry) = (v as u32, v >> 32 != 0);
            if v > 0 {
                let err = (log2_u33(lo, carry) as f64 - exact_log2(v)).abs();
                assert!(err < 2.5, "{v}: {err}");
            }
        }
    }

    #[test]
    fn exp2_is_accurate() {
        for y in (0..30u32 << 16).step_by(997) {
            let want = libm::exp2(-(y as f64) / 65536.0) * (1u64 << 26) as f64;
            let got = exp2_neg_q26(y) as f64;
            if y >> 16 >= 27 {
                assert_eq!(got, 0.0);
            } else {
                assert!(
                    (got - want).abs() <= 1.3e-4 * want + 1.0,
                    "{y}: {got} vs {want}"
                );
            }
        }
        assert_eq!(exp2_neg_q26(0), 1 << 26);
    }

    #[test]
    fn squares_and_roots() {
        for x in [
            0u32,
            1,
            2,
            3,
            4,
            99,
            100,
            101,
            65535,
            65536,
            u32::MAX >> 2,
            u32::MAX,
        ] {
            let r = isqrt_u32(x) as u64;
            let x = x as u64;
            assert!(r * r <= x && (r + 1) * (r + 1) > x, "{x}");
        }
        assert_eq!(sq16(-65535), 65535 * 65535);
        for v in [
            0u32,
            1,
            255,
            256,
            65535,
            65536,
            1 << 22,
            (1 << 23) - 1,
            5_432_101,
        ] {
            let exact = (v as u64 * v as u64) >> 16;
            let got = sq_q18(v) as u64;
            assert!(got <= exact && exact - got <= 2, "{v}: {got} vs {exact}");
        }
        assert_eq!(mul_shr(3, 5, 1), 8);
    }

    #[test]
    fn compile_time_logs_are_rounded_logs() {
        for x in [
            1u64,
            2,
            3,
            7,
            10,
            2500,
            10_000,
            25_000_000,
            1 << 40,
            u64::MAX,
        ] {
            let want = libm::round(libm::log2(x as f64) * (1 << 20) as f64) as i32;
            assert_eq!(log2_q20(x), want, "{x}");
        }
        let mut r: u64 = 0x9E37_79B9_7F4A_7C15;
        for _ in 0..20_000 {
            r ^= r << 13;
            r ^= r >> 7;
            r ^= r << 17;
            let x = (r >> (r % 50)).max(1);
            let exact = libm::log2(x as f64) * (1 << 20) as f64;
            // Away from a rounding tie (which f64 cannot settle), the nearest Q.20 value.
            if (exact - libm::floor(exact) - 0.5).abs() > 1e-3 {
                assert_eq!(log2_q20(x), libm::round(exact) as i32, "{x}");
            }
        }
    }

    #[test]
    fn high_products_and_shifted_quotients() {
        let mut r: u64 = 0x2545_F491_4F6C_DD1D;
        for _ in 0..100_000 {
            r ^= r << 13;
            r ^= r >> 7;
            r ^= r << 17;
            let (a, b) = (r as u32, (r >> 32) as u32);
            let exact = ((a as u64 * b as u64) >> 32) as u32;
            let got = mul_hi(a, b);
            assert!(got <= exact && exact - got <= 2, "{a} {b}");
            let (d, e) = ((b >> (r % 31)).max(1) & 0x7FFF_FFFF, (r >> 59) as u32);
            let d = d.max(1);
            let want = ((a as u128) << e) / d as u128;
            assert_eq!(
                div_shl(a, d, e) as u128,
                want.min(u32::MAX as u128),
                "{a} {d} {e}"
            );
        }
    }

    #[test]
    fn byte_products_are_exact() {
        for a in 0..=u16::MAX {
            assert_eq!(sq_u16(a), a as u32 * a as u32, "{a}");
        }
    }
}
