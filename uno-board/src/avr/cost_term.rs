//! The position search's cost term in AVR assembly: [`AvrTerm`].
//!
//! `loc_core::fixed` evaluates `(ρ + max(log2 d², clamp))²` a few hundred times per fix; LLVM's
//! AVR backend spends ≈ 650 cycles on it (its 8 × 8 → 16/32-bit products cost many moves and
//! spills), this hand-scheduled version ≈ 100. It computes exactly
//! [`loc_core::fixed::portable_term`] — the same normalisation, the same 64-segment quadratic
//! from the same flash table ([`loc_core::fixed::log2_segment_table`]), the same clamp,
//! saturation and five-product square — which `hoploc-tests` checks in simavr on every edge case
//! and 50 000 random inputs (`tests/tests/mcu_bench.rs`).

use core::arch::asm;
use loc_core::fixed::{log2_segment_table, TermKernel};

/// The AVR kernel for `loc_core::fixed::{mle_with, mmse_with, estimate_with}`.
#[derive(Clone, Copy, Debug, Default)]
pub struct AvrTerm;

impl TermKernel for AvrTerm {
    #[inline(never)]
    fn term(lo: u32, carry: bool, rho: i32, lclamp: i32) -> u32 {
        term(lo, carry, rho, lclamp)
    }
}

/// See the module docs. Register use: `d²` and the result in four bytes, the table in `Z`, the
/// clamp and `ρ` read through `X`, twelve scratch registers; `r0`/`r1` for `mul` (r1 cleared).
#[inline(always)]
pub fn term(lo: u32, carry: bool, rho: i32, lclamp: i32) -> u32 {
    let consts: [i32; 2] = [lclamp, rho];
    let [mut n0, mut n1, mut n2, mut n3] = lo.to_le_bytes();
    let table = log2_segment_table() as u16;
    let ptr = consts.as_ptr() as u16;
    // SAFETY: the assembly reads the 8 bytes of `consts` through X and 6 bytes of the log2
    // table (64 × 6 bytes in flash, index < 64 by construction) through Z with `lpm`; it writes
    // only its register operands, r0, and r1 (left at 0 as the ABI requires) and the flags.
    unsafe {
        asm!(
            // A zero register of our own: r1 holds products below.
            "clr {zr}",
            // ---- normalise n = d² to [2^31, 2^32), exponent e ----
            "tst {cy}",
            "breq 10f",
            // 33-bit input: n = (2^32 + lo) >> 1, e = 32.
            "sec",
            "ror {n3}",
            "ror {n2}",
            "ror {n1}",
            "ror {n0}",
            "ldi {e}, 32",
            "rjmp 14f",
            "10:",
            "ldi {e}, 31",
            "cp {n2}, r1",
            "cpc {n3}, r1",
            "brne 11f",
            "cp {n0}, r1",
            "cpc {n1}, r1",
            "brne 12f",
            // d² = 0: log = 0.
            "clr {c0a}",
            "clr {c0b}",
            "clr {c0c}",
            "clr {e}",
            "rjmp 20f",
            "12:",
            "mov {n3}, {n1}",
            "mov {n2}, {n0}",
            "clr {n1}",
            "clr {n0}",
            "subi {e}, 16",
            "11:",
            "tst {n3}",
            "brne 13f",
            "mov {n3}, {n2}",
            "mov {n2}, {n1}",
            "mov {n1}, {n0}",
            "clr {n0}",
            "subi {e}, 8",
            "13:",
            "sbrc {n3}, 7",
            "rjmp 14f",
            "lsl {n0}",
            "rol {n1}",
            "rol {n2}",
            "rol {n3}",
            "dec {e}",
            "rjmp 13b",
            // ---- segment k = n >> 25 & 63, position t = n >> 9 (n2:n1 after the shift) ----
            "14:",
            "lsr {n3}",
            "ror {n2}",
            "ror {n1}",
            // n3 = 64 + k: Z = table + 6·n3 − 384.
            "ldi {x}, 6",
            "mul {n3}, {x}",
            "add r30, r0",
            "adc r31, r1",
            "subi r30, 0x80",
            "sbci r31, 0x01",
            "lpm {c0a}, Z+",
            "lpm {c0b}, Z+",
            "lpm {c0c}, Z+",
            "lpm {c1a}, Z+",
            "lpm {c1b}, Z+",
            "lpm {c2}, Z",
            // q = (t1·c2 + (t0·c2 >> 8)) >> 8; i = c1 − q (in c1b:c1a).
            "mul {n1}, {c2}",
            "mov {x}, r1",
            "mul {n2}, {c2}",
            "add r0, {x}",
            "mov {x}, r1",
            "adc {x}, {zr}",
            "sub {c1a}, {x}",
            "sbc {c1b}, {zr}",
            // mid = (t0·i0 >> 8) + t1·i0 + t0·i1 (17 bits in m2:m1:m0).
            "mul {n1}, {c1a}",
            "mov {m0}, r1",
            "clr {m1}",
            "clr {m2}",
            "mul {n2}, {c1a}",
            "add {m0}, r0",
            "adc {m1}, r1",
            "adc {m2}, {zr}",
            "mul {n1}, {c1b}",
            "add {m0}, r0",
            "adc {m1}, r1",
            "adc {m2}, {zr}",
            // mantissa = c0 + t1·i1 + (mid >> 8).
            "mul {n2}, {c1b}",
            "add {c0a}, r0",
            "adc {c0b}, r1",
            "adc {c0c}, {zr}",
            "add {c0a}, {m1}",
            "adc {c0b}, {m2}",
            "adc {c0c}, {zr}",
            // log = (e << 20) + mantissa, in e:c0c:c0b:c0a.
            "swap {e}",
            "mov {x}, {e}",
            "andi {x}, 0xF0",
            "andi {e}, 0x0F",
            "add {c0c}, {x}",
            "adc {e}, {zr}",
            // ---- l = max(log, clamp) (signed) ----
            "20:",
            "ld {c1a}, X+",
            "ld {c1b}, X+",
            "ld {c2}, X+",
            "ld {m0}, X+",
            "cp {c0a}, {c1a}",
            "cpc {c0b}, {c1b}",
            "cpc {c0c}, {c2}",
            "cpc {e}, {m0}",
            "brge 21f",
            "mov {c0a}, {c1a}",
            "mov {c0b}, {c1b}",
            "mov {c0c}, {c2}",
            "mov {e}, {m0}",
            // ---- u = |ρ + l| ----
            "21:",
            "ld {c1a}, X+",
            "ld {c1b}, X+",
            "ld {c2}, X+",
            "ld {m0}, X+",
            "add {c0a}, {c1a}",
            "adc {c0b}, {c1b}",
            "adc {c0c}, {c2}",
            "adc {e}, {m0}",
            "sbrs {e}, 7",
            "rjmp 22f",
            "com {c0a}",
            "com {c0b}",
            "com {c0c}",
            "com {e}",
            "sec",
            "adc {c0a}, {zr}",
            "adc {c0b}, {zr}",
            "adc {c0c}, {zr}",
            "adc {e}, {zr}",
            // ---- |u| ≥ 32 << 20: the saturated term ----
            "22:",
            "cpi {e}, 2",
            "brlo 23f",
            "ldi {e}, 0xFF",
            "mov {n0}, {e}",
            "mov {n1}, {e}",
            "mov {n2}, {e}",
            "ldi {e}, 0x3F",
            "mov {n3}, {e}",
            "rjmp 30f",
            // ---- v = |u| >> 2 (c0c:c0b:c0a); term = v² >> 16 from five products ----
            "23:",
            "lsr {e}",
            "ror {c0c}",
            "ror {c0b}",
            "ror {c0a}",
            "lsr {e}",
            "ror {c0c}",
            "ror {c0b}",
            "ror {c0a}",
            // v2² << 16 + v1².
            "mul {c0c}, {c0c}",
            "mov {n2}, r0",
            "mov {n3}, r1",
            "mul {c0b}, {c0b}",
            "mov {n0}, r0",
            "mov {n1}, r1",
            // + 2·v1·v2 << 8.
            "mul {c0b}, {c0c}",
            "clr {x}",
            "lsl r0",
            "rol r1",
            "rol {x}",
            "add {n1}, r0",
            "adc {n2}, r1",
            "adc {n3}, {x}",
            // + 2·v0·v2.
            "mul {c0a}, {c0c}",
            "clr {x}",
            "lsl r0",
            "rol r1",
            "rol {x}",
            "add {n0}, r0",
            "adc {n1}, r1",
            "adc {n2}, {x}",
            "adc {n3}, {zr}",
            // + (2·v0·v1) >> 8.
            "mul {c0a}, {c0b}",
            "clr {x}",
            "lsl r0",
            "rol r1",
            "rol {x}",
            "add {n0}, r1",
            "adc {n1}, {x}",
            "adc {n2}, {zr}",
            "adc {n3}, {zr}",
            "30:",
            "clr r1",
            n0 = inout(reg) n0,
            n1 = inout(reg) n1,
            n2 = inout(reg) n2,
            n3 = inout(reg) n3,
            cy = in(reg) carry as u8,
            zr = out(reg) _,
            e = out(reg_upper) _,
            x = out(reg_upper) _,
            c0a = out(reg) _,
            c0b = out(reg) _,
            c0c = out(reg) _,
            c1a = out(reg) _,
            c1b = out(reg) _,
            c2 = out(reg) _,
            m0 = out(reg) _,
            m1 = out(reg) _,
            m2 = out(reg) _,
            inout("Z") table => _,
            inout("X") ptr => _,
            options(readonly, nostack),
        );
    }
    u32::from_le_bytes([n0, n1, n2, n3])
}
