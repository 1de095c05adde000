//! The position search's inner loop in AVR assembly: [`AvrTerm`].
//!
//! `loc_core::fixed` evaluates `w·(ρ + max(log2 d², clamp))²` a few hundred times per fix, a
//! column of rows at a time. LLVM's AVR backend spends ≈ 650 cycles on one term (its 8 × 8 →
//! 16/32-bit products cost many moves and spills) and as much again on the loops around it;
//! this hand-scheduled version keeps a whole column — rows, anchors, the early exit at the bound
//! — in registers. It computes exactly [`loc_core::fixed::portable_column`] and
//! [`loc_core::fixed::portable_term`]: the same normalisation, the same 64-segment quadratic
//! from the same flash table ([`loc_core::fixed::log2_segment_table`]), the same clamp,
//! saturation and five-product square, the same weights and bound, which `hoploc-tests` checks
//! in simavr on every edge case and 50 000 random terms and 5 000 random columns
//! (`tests/tests/mcu_bench.rs`).
//!
//! The windowed MMSE's routines are here too, for flash more than cycles ([`posterior`],
//! [`weights`], [`div_shl_c`], [`mul_hi`]: ≈ 1.1 KB for ≈ 2.4 KB of LLVM's code); each computes
//! exactly its `loc_core::fixed` reference, which the same simavr test checks on 5 000 random
//! inputs each.
//!
//! Register plan (explicit, so both entry points share one instruction text, [`term_body!`]):
//! `d²` in r15:r12 with its 33rd bit in the T flag, the term in r15:r12; the [`AnchorTerm`] in
//! `Z` (the body reads `lclamp`, `ρ` and the table address at their offsets, and restores `Z`
//! from r25:r24 after the table reads); r2 is a zero register, r3–r11, r16, r17 scratch; r0/r1
//! for `mul` (r1 cleared at the end, as the ABI requires). The column loop adds: X walks the
//! sums, r21:r18 the room left below the bound, r22 the row's fine offset, r23 the anchors left, and the job's
//! address in Y (r29:r28, saved on the stack).

use core::arch::asm;
use core::mem::{offset_of, size_of};
use loc_core::fixed::{
    exp2_segment_table, log2_segment_base, AnchorTerm, ColumnJob, Estimate, Lattice, LatticeMin,
    Obs, Placement, PointMm, Posterior, Setup, SinkFrame, SinkLocals, TermKernel, Weights,
};

// The offsets the assembly reads (AVR has no padding).
const _: () = {
    assert!(offset_of!(AnchorTerm, dx2) == 0);
    assert!(offset_of!(AnchorTerm, dx0) == 4);
    assert!(offset_of!(AnchorTerm, dy0) == 7);
    assert!(offset_of!(AnchorTerm, lclamp) == 10);
    assert!(offset_of!(AnchorTerm, rho) == 14);
    assert!(offset_of!(AnchorTerm, w) == 18);
    assert!(offset_of!(AnchorTerm, shift) == 19);
    assert!(size_of::<AnchorTerm>() == 20);
    assert!(offset_of!(ColumnJob, bound) == 0);
    assert!(offset_of!(ColumnJob, n) == 4);
    assert!(offset_of!(ColumnJob, rows) == 5);
    assert!(offset_of!(ColumnJob, min) == 6);
    assert!(offset_of!(ColumnJob, min_row) == 10);
    assert!(offset_of!(ColumnJob, skip) == 11);
    assert!(offset_of!(ColumnJob, col) == 13);
    assert!(offset_of!(ColumnJob, xstep) == 14);
    assert!(offset_of!(ColumnJob, stride) == 16);
    assert!(offset_of!(ColumnJob, end) == 17);
    assert!(offset_of!(ColumnJob, seg_base) == 18);
    assert!(offset_of!(ColumnJob, ystep) == 20);
    assert!(offset_of!(ColumnJob, anchors) == 22);
    assert!(size_of::<ColumnJob>() == 22 + 20 * loc_core::MAX_ANCHORS);
    assert!(offset_of!(Placement, rho) == 0);
    assert!(offset_of!(Placement, x) == 4);
    assert!(offset_of!(Placement, y) == 6);
    assert!(offset_of!(Placement, weight) == 8);
    assert!(loc_core::fixed::LOG2_CLAMP == 0x00B4_9A78);
    assert!(offset_of!(Posterior, cref) == 0);
    assert!(offset_of!(Posterior, wts) == 4);
    assert!(offset_of!(loc_core::fixed::Weights, span) == 0);
    assert!(offset_of!(loc_core::fixed::Weights, b) == 4);
    assert!(offset_of!(loc_core::fixed::Weights, ra) == 8);
    assert!(offset_of!(Posterior, col) == 13);
    assert!(offset_of!(Posterior, s) == 14);
    assert!(offset_of!(LatticeMin, i) == 0);
    assert!(offset_of!(LatticeMin, j) == 1);
    assert!(offset_of!(LatticeMin, cost) == 2);
    assert!(offset_of!(Lattice, i0) == 0);
    assert!(offset_of!(Lattice, j0) == 1);
    assert!(offset_of!(Lattice, rows) == 2);
    assert!(offset_of!(Lattice, job) + offset_of!(ColumnJob, stride) < 64);
    assert!(offset_of!(Setup, p0) == 0);
    assert!(offset_of!(Setup, alpha) == 4);
    assert!(offset_of!(Setup, k26) == 8);
    assert!(offset_of!(Setup, flat_cost) == 12);
    assert!(offset_of!(Setup, anchors) == 16);
    assert!(offset_of!(Setup, weight) == 17);
    // `finish`: best[1] at 6 (its cost at 8), k26 then flat_cost, PointMm's y after x, every
    // field it reaches within 63 bytes (the copy's size an 8-bit count).
    assert!(offset_of!(SinkLocals, best) == 0 && size_of::<LatticeMin>() == 6);
    assert!(offset_of!(Setup, flat_cost) == offset_of!(Setup, k26) + 4);
    assert!(offset_of!(PointMm, x) == 0 && offset_of!(PointMm, y) == 4);
    assert!(offset_of!(SinkLocals, post) + offset_of!(Posterior, sy) + 3 < 64);
    assert!(offset_of!(Lattice, job) + offset_of!(ColumnJob, ystep) + 1 < 64);
    assert!(2 * size_of::<Estimate>() < 64);
    assert!(offset_of!(Estimate, pos) + 8 <= size_of::<Estimate>());
};

/// The AVR kernel for `loc_core::fixed::{mle_with, mmse_with, estimate_with}`.
#[derive(Clone, Copy, Debug, Default)]
pub struct AvrTerm;

impl TermKernel for AvrTerm {
    #[inline(never)]
    fn term(lo: u32, carry: bool, rho: i32, lclamp: i32) -> u32 {
        term(lo, carry, rho, lclamp)
    }

    #[inline(never)]
    fn column(sums: &mut [u32], job: &mut ColumnJob) {
        column(sums, job)
    }

    #[inline(never)]
    fn posterior(sums: &[u32], col: u8, post: &mut Posterior) {
        post.col = col;
        posterior(sums, post)
    }

    #[inline(never)]
    fn weights(k26: u32, sigma_q8: u16, out: &mut Weights) {
        weights(k26, sigma_q8, out)
    }

    #[inline(always)]
    fn div_shl(a: u32, b: u32, e: u32) -> u32 {
        div_shl_c(a, b, e as u8)
    }

    #[inline(never)]
    fn mul_hi(a: u32, b: u32) -> u32 {
        mul_hi(a, b)
    }

    #[inline(never)]
    fn move_window(job: &mut ColumnJob, di: i8, dj: i8) {
        move_window(job, di, dj)
    }

    #[inline(never)]
    fn place(job: &mut ColumnJob, p: &Placement) {
        place(job, p)
    }

    #[inline(never)]
    fn observe(job: &mut ColumnJob, s: &mut Setup, obs: &[Obs]) {
        observe(job, s, obs)
    }

    #[inline(never)]
    fn search(l: &mut Lattice, best: &mut [LatticeMin; 2], post: &mut Posterior) {
        search(l, best, post)
    }

    #[inline(never)]
    fn finish(l: &Lattice, f: &SinkLocals, const_cost: u32, out: &mut [Estimate; 2]) {
        finish(l, f, const_cost, out)
    }

    #[inline(never)]
    fn sink(fr: &mut SinkFrame, obs: &[Obs], sigma: u16, const_cost: u32, out: &mut [Estimate; 2]) {
        sink(fr, obs, sigma, const_cost, out)
    }

    #[inline(never)]
    fn guess(job: &ColumnJob) -> (u8, u8) {
        let g = guess(job);
        (g as u8, (g >> 8) as u8)
    }
}

/// `(ρ + max(log2 n, clamp))²` (Q.20, saturated) of `n` = r15:r12 plus `2^32·T` (the T flag),
/// into r15:r12, for the [`AnchorTerm`] at `Z`.
macro_rules! term_body {
    () => {
        concat!(
            // ---- normalise n = d² to [2^31, 2^32), exponent e ----
            "brtc 10f\n",
            // 33-bit input: n = (2^32 + lo) >> 1, e = 32.
            "sec\n",
            "ror r15\n",
            "ror r14\n",
            "ror r13\n",
            "ror r12\n",
            "ldi r16, 32\n",
            "rjmp 14f\n",
            "10:\n",
            "ldi r16, 31\n",
            "cp r14, r2\n",
            "cpc r15, r2\n",
            "brne 11f\n",
            "cp r12, r2\n",
            "cpc r13, r2\n",
            "brne 12f\n",
            // d² = 0: log = 0.
            "clr r3\n",
            "clr r4\n",
            "clr r5\n",
            "clr r16\n",
            "rjmp 20f\n",
            "12:\n",
            "mov r15, r13\n",
            "mov r14, r12\n",
            "clr r13\n",
            "clr r12\n",
            "subi r16, 16\n",
            "11:\n",
            "tst r15\n",
            "brne 13f\n",
            "mov r15, r14\n",
            "mov r14, r13\n",
            "mov r13, r12\n",
            "clr r12\n",
            "subi r16, 8\n",
            // r15 ≠ 0 here: shift until its top bit is set.
            "13:\n",
            "sbrc r15, 7\n",
            "rjmp 14f\n",
            "15:\n",
            "lsl r12\n",
            "rol r13\n",
            "rol r14\n",
            "rol r15\n",
            "dec r16\n",
            "sbrs r15, 7\n",
            "rjmp 15b\n",
            // ---- segment k = n >> 25 & 63, position t = n >> 9 (n2:n1 after the shift) ----
            "14:\n",
            "lsr r15\n",
            "ror r14\n",
            "ror r13\n",
            // n3 = 64 + k: Z = (table − 384) + 6·n3, the base from Y+18 (the anchor pointer
            // waits in r25:r24).
            "movw r24, r30\n",
            "ldd r30, Y+18\n",
            "ldd r31, Y+19\n",
            log2_segment_asm!(),
            "movw r30, r24\n",
            // log2 d² (Q.20) in r16:r5:r4:r3
            log2_interpolate_asm!(),
            // ---- l = max(log, clamp) (signed) ----
            "20:\n",
            "ldd r6, Z+10\n",
            "ldd r7, Z+11\n",
            "ldd r8, Z+12\n",
            "ldd r9, Z+13\n",
            "cp r3, r6\n",
            "cpc r4, r7\n",
            "cpc r5, r8\n",
            "cpc r16, r9\n",
            "brge 21f\n",
            "mov r3, r6\n",
            "mov r4, r7\n",
            "mov r5, r8\n",
            "mov r16, r9\n",
            // ---- u = |ρ + l| ----
            "21:\n",
            "ldd r6, Z+14\n",
            "ldd r7, Z+15\n",
            "ldd r8, Z+16\n",
            "ldd r9, Z+17\n",
            "add r3, r6\n",
            "adc r4, r7\n",
            "adc r5, r8\n",
            "adc r16, r9\n",
            "sbrs r16, 7\n",
            "rjmp 22f\n",
            "com r3\n",
            "com r4\n",
            "com r5\n",
            "com r16\n",
            "sec\n",
            "adc r3, r2\n",
            "adc r4, r2\n",
            "adc r5, r2\n",
            "adc r16, r2\n",
            // ---- |u| ≥ 32 << 20: the saturated term ----
            "22:\n",
            "cpi r16, 2\n",
            "brlo 23f\n",
            "ldi r16, 0xFF\n",
            "mov r12, r16\n",
            "mov r13, r16\n",
            "mov r14, r16\n",
            "ldi r16, 0x3F\n",
            "mov r15, r16\n",
            "rjmp 30f\n",
            // ---- v = |u| >> 2 (c0c:c0b:c0a); term = v² >> 16 from five products ----
            "23:\n",
            "lsr r16\n",
            "ror r5\n",
            "ror r4\n",
            "ror r3\n",
            "lsr r16\n",
            "ror r5\n",
            "ror r4\n",
            "ror r3\n",
            // v2² << 16 + v1².
            "mul r5, r5\n",
            "mov r14, r0\n",
            "mov r15, r1\n",
            "mul r4, r4\n",
            "mov r12, r0\n",
            "mov r13, r1\n",
            // + 2·v1·v2 << 8.
            "mul r4, r5\n",
            "clr r17\n",
            "lsl r0\n",
            "rol r1\n",
            "rol r17\n",
            "add r13, r0\n",
            "adc r14, r1\n",
            "adc r15, r17\n",
            // + 2·v0·v2.
            "mul r3, r5\n",
            "clr r17\n",
            "lsl r0\n",
            "rol r1\n",
            "rol r17\n",
            "add r12, r0\n",
            "adc r13, r1\n",
            "adc r14, r17\n",
            "adc r15, r2\n",
            // + (2·v0·v1) >> 8.
            "mul r3, r4\n",
            "clr r17\n",
            "lsl r0\n",
            "rol r1\n",
            "rol r17\n",
            "add r12, r1\n",
            "adc r13, r17\n",
            "adc r14, r2\n",
            "adc r15, r2\n",
            "30:\n",
        )
    };
}

/// `v = r3:r17:r16 + the 24-bit value at Z+$o0 (bytes $o0, $o1, $o2)`, then `|v|` rounded to
/// `2^shift` units (the anchor's `shift`, half up; below 2^16 then) squared into r15:r12: a
/// column's dx² and a row's dy², the same steps ([`loc_core::fixed::offset_square`]).
macro_rules! offset_abs_square {
    ($o0:literal, $o1:literal, $o2:literal) => {
        concat!(
            "ldd r4, Z+",
            $o0,
            "\n",
            "add r16, r4\n",
            "ldd r4, Z+",
            $o1,
            "\n",
            "adc r17, r4\n",
            "ldd r4, Z+",
            $o2,
            "\n",
            "adc r3, r4\n",
            "sbrs r3, 7\n",
            "rjmp 9f\n",
            "com r3\n",
            "com r17\n",
            "neg r16\n",
            "sbci r17, 0xFF\n",
            // r3 + 1 − borrow (r3 is not an immediate register).
            "sbc r3, r2\n",
            "inc r3\n",
            "9:\n",
            // A shift: the subroutine at 45 (4 cycles when there is none).
            "ldd r5, Z+19\n",
            "cpse r5, r2\n",
            "rcall 45f\n",
            "mul r16, r16\n",
            "movw r12, r0\n",
            "mul r17, r17\n",
            "movw r14, r0\n",
            "mul r16, r17\n",
            "clr r3\n",
            "lsl r0\n",
            "rol r1\n",
            "rol r3\n",
            "add r13, r0\n",
            "adc r14, r1\n",
            "adc r15, r3\n",
        )
    };
}

/// [`loc_core::fixed::portable_term`], exactly; see the module docs.
#[inline(always)]
pub fn term(lo: u32, carry: bool, rho: i32, lclamp: i32) -> u32 {
    let t = AnchorTerm {
        lclamp,
        rho,
        ..AnchorTerm::NONE
    };
    // The body reads the table's base at Y+18, as in a `ColumnJob`.
    let base = log2_segment_base();
    let y = (&base as *const *const u8).cast::<u8>().wrapping_sub(18);
    let [mut n0, mut n1, mut n2, mut n3] = lo.to_le_bytes();
    // SAFETY: the assembly reads `t` (20 bytes, at the offsets asserted above) through Z, the
    // table base through Y (`base`, at Y+18) and 6 bytes of the log2 table (64 × 6 bytes in
    // flash, index < 64 by construction) with `lpm`; it writes only the registers declared
    // here, r0, r1 (left at 0 as the ABI requires), the flags and Y (saved on the stack and
    // restored).
    unsafe {
        asm!(
            "push r28",
            "push r29",
            "movw r28, r26",
            "clr r2",
            "clt",
            "tst r22",
            "breq 1f",
            "set",
            "1:",
            term_body!(),
            "pop r29",
            "pop r28",
            "clr r1",
            inout("r12") n0,
            inout("r13") n1,
            inout("r14") n2,
            inout("r15") n3,
            in("r22") carry as u8,
            inout("X") y => _,
            inout("Z") &t as *const AnchorTerm => _,
            out("r2") _, out("r3") _, out("r4") _, out("r5") _, out("r6") _, out("r7") _,
            out("r8") _, out("r9") _, out("r10") _, out("r11") _, out("r16") _, out("r17") _,
            out("r24") _, out("r25") _,
            options(readonly),
        );
    }
    u32::from_le_bytes([n0, n1, n2, n3])
}

/// [`loc_core::fixed::portable_column`], exactly (for `sums.len() ≤ 255`); see the module
/// docs. All of it in the assembly, no anchors (`n = 0`: every row not skipped costs 0) and no
/// rows included: the Rust around an `asm!` block is what costs flash here.
pub fn column(sums: &mut [u32], job: &mut ColumnJob) {
    let rows = sums.len().min(255) as u8;
    // SAFETY: X walks the first `rows` (0 to 255) sums, each written once (the row loop counts
    // them down in `job.rows`); Z points at `job` (its address also kept in Y, whose value is
    // saved on the stack and restored before the end; nothing here uses the frame): the loop
    // reads its bound, its skip mask (shifting it in place) and its first `min(n, MAX_ANCHORS)`
    // anchors (that count kept in `job.end`) and writes their `dx2`; `lpm` reads 6 bytes of the
    // log2 table per term as in [`term`]. Only the declared registers, r0, r1 (left at 0), the
    // flags, Y (restored) and four stack bytes (Y, a return address) are written (and the job's
    // `min`, `min_row`, `skip`, `rows`, `end` and `dx2` fields).
    unsafe {
        asm!(
            "clr r2",
            "push r28",
            "push r29",
            "movw r28, r30",
            // ---- no minimum yet ----
            "ldi r16, 0xFF",
            "std Z+6, r16",
            "std Z+7, r16",
            "std Z+8, r16",
            "std Z+9, r16",
            "std Z+10, r2",
            // ---- rows left in `rows`; n (at most MAX_ANCHORS) in `end` ----
            "std Z+5, r24",
            "ldd r23, Z+4",
            "cpi r23, {n1}",
            "brlo 47f",
            "ldi r23, {n}",
            "47:",
            "std Z+17, r23",
            "tst r23",
            "breq 48f",
            // ---- dx² of every anchor: dx = dx0 + col·xstep (24 bits) ----
            "ldd r22, Z+13",
            "ldd r24, Z+14",
            "ldd r25, Z+15",
            "adiw r30, 22",
            "8:",
            "mul r22, r24",
            "movw r16, r0",
            "mul r22, r25",
            "add r17, r0",
            "clr r3",
            "adc r3, r1",
            offset_abs_square!(4, 5, 6),
            "std Z+0, r12",
            "std Z+1, r13",
            "std Z+2, r14",
            "std Z+3, r15",
            "adiw r30, 20",
            "dec r23",
            "brne 8b",
            "48:",
            "ldd r16, Y+5",
            "tst r16",
            "brne 49f",
            "rjmp 38f",
            "49:",
            "clr r22",
            // ---- row at fine offset r22: skipped (the next bit of `skip`) → u32::MAX; else
            // room = bound ----
            "1:",
            "movw r30, r28",
            "ldd r16, Z+11",
            "ldd r17, Z+12",
            "lsr r17",
            "ror r16",
            "std Z+11, r16",
            "std Z+12, r17",
            "brcc 2f",
            "ldi r16, 0xFF",
            "st X+, r16",
            "st X+, r16",
            "st X+, r16",
            "st X+, r16",
            "rjmp 37f",
            "2:",
            "ldd r18, Z+0",
            "ldd r19, Z+1",
            "ldd r20, Z+2",
            "ldd r21, Z+3",
            "ldd r23, Z+17",
            "adiw r30, 22",
            "tst r23",
            "brne 5f",
            // No anchors: the sum 0, completed if below the bound.
            "cp r18, r2",
            "cpc r19, r2",
            "cpc r20, r2",
            "cpc r21, r2",
            "breq 50f",
            "rjmp 3f",
            "50:",
            "rjmp 35f",
            // ---- anchor at Z: dy = dy0 + r22·step (24 bits) ----
            "5:",
            "ldd r16, Y+20",
            "mul r22, r16",
            "movw r16, r0",
            "ldd r3, Y+21",
            "mul r22, r3",
            "add r17, r0",
            "clr r3",
            "adc r3, r1",
            offset_abs_square!(7, 8, 9),
            // ---- d² = dx² + dy² in T:r15:r12 ----
            "ldd r16, Z+0",
            "add r12, r16",
            "ldd r16, Z+1",
            "adc r13, r16",
            "ldd r16, Z+2",
            "adc r14, r16",
            "ldd r16, Z+3",
            "adc r15, r16",
            "clt",
            "brcc 7f",
            "set",
            "7:",
            term_body!(),
            // ---- room −= w·term; at or below 0 the row has reached the bound ----
            "ldd r17, Z+18",
            "31:",
            "sub r18, r12",
            "sbc r19, r13",
            "sbc r20, r14",
            "sbc r21, r15",
            "brcs 35f",
            "breq 35f",
            "dec r17",
            "brne 31b",
            "adiw r30, 20",
            "dec r23",
            "breq 3f",
            "rjmp 5b",
            // ---- every anchor added: sum = bound − room ----
            "3:",
            "movw r30, r28",
            "ldd r16, Z+0",
            "sub r16, r18",
            "mov r18, r16",
            "ldd r16, Z+1",
            "sbc r16, r19",
            "mov r19, r16",
            "ldd r16, Z+2",
            "sbc r16, r20",
            "mov r20, r16",
            "ldd r16, Z+3",
            "sbc r16, r21",
            "mov r21, r16",
            // ---- the column's first smallest completed sum ----
            "ldd r16, Z+6",
            "cp r18, r16",
            "ldd r16, Z+7",
            "cpc r19, r16",
            "ldd r16, Z+8",
            "cpc r20, r16",
            "ldd r16, Z+9",
            "cpc r21, r16",
            "brsh 36f",
            "std Z+6, r18",
            "std Z+7, r19",
            "std Z+8, r20",
            "std Z+9, r21",
            "std Z+10, r22",
            "rjmp 36f",
            // ---- reached: the row is set to the bound ----
            "35:",
            "movw r30, r28",
            "ldd r18, Z+0",
            "ldd r19, Z+1",
            "ldd r20, Z+2",
            "ldd r21, Z+3",
            "36:",
            "st X+, r18",
            "st X+, r19",
            "st X+, r20",
            "st X+, r21",
            // ---- next row ----
            "37:",
            "ldd r16, Z+16",
            "add r22, r16",
            "ldd r16, Z+5",
            "dec r16",
            "std Z+5, r16",
            "breq 38f",
            "rjmp 1b",
            "38:",
            "pop r29",
            "pop r28",
            "clr r1",
            "rjmp 46f",
            // ---- r3:r17:r16 >> r5 (≥ 1), rounded by the last bit shifted out ----
            "45:",
            "lsr r3",
            "ror r17",
            "ror r16",
            "dec r5",
            "brne 45b",
            "adc r16, r2",
            "adc r17, r2",
            "ret",
            "46:",
            n = const loc_core::MAX_ANCHORS,
            n1 = const loc_core::MAX_ANCHORS + 1,
            inout("X") sums.as_mut_ptr() => _,
            inout("Z") &mut *job as *mut ColumnJob => _,
            inout("r24") rows => _,
            out("r2") _, out("r3") _, out("r4") _, out("r5") _, out("r6") _, out("r7") _,
            out("r8") _, out("r9") _, out("r10") _, out("r11") _, out("r12") _,
            out("r13") _, out("r14") _, out("r15") _, out("r16") _, out("r17") _,
            out("r18") _, out("r19") _, out("r20") _, out("r21") _, out("r22") _,
            out("r23") _, out("r25") _,
        );
    }
}

/// [`posterior`]'s instruction text (also a local subroutine of [`search`]'s and [`sink`]'s).
macro_rules! posterior_body {
    () => {
        concat!(
            "push r28\n",
            "push r29\n",
            "movw r28, r30\n",
            "clr r2\n",
            // Row −1 done: no rows, no work.
            "clr r3\n",
            "dec r3\n",
            "rjmp 9f\n",
            // ---- row r3: v = its cost; u32::MAX (a skipped row) weighs nothing ----
            "1:\n",
            "ld r22, X+\n",
            "ld r23, X+\n",
            "ld r24, X+\n",
            "ld r25, X+\n",
            "mov r0, r22\n",
            "and r0, r23\n",
            "and r0, r24\n",
            "and r0, r25\n",
            "inc r0\n",
            "breq 9f\n",
            // ---- e = v − cref ----
            "ldd r18, Y+0\n",
            "ldd r19, Y+1\n",
            "ldd r20, Y+2\n",
            "ldd r21, Y+3\n",
            "sub r22, r18\n",
            "sbc r23, r19\n",
            "sbc r24, r20\n",
            "sbc r25, r21\n",
            "brcc 5f\n",
            // ---- v < cref: v (= cref + e) the new reference, the sums so far × f, the
            // weight of the drop −e as a Q.32 factor: min(W, 2^26 − 1) << 6 ----
            "add r18, r22\n",
            "adc r19, r23\n",
            "adc r20, r24\n",
            "adc r21, r25\n",
            "std Y+0, r18\n",
            "std Y+1, r19\n",
            "std Y+2, r20\n",
            "std Y+3, r21\n",
            "com r25\n",
            "com r24\n",
            "com r23\n",
            "neg r22\n",
            "sbci r23, 0xFF\n",
            "sbci r24, 0xFF\n",
            "sbci r25, 0xFF\n",
            "rcall 40f\n",
            // W << 6 = ((m << 16) >> (int − 1)) with the low 6 bits cleared; for int = 0,
            // m << 17, which overflows only for W = 2^26 (then (2^26 − 1) << 6).
            "subi r16, 1\n",
            "brcc 2f\n",
            "lsl r24\n",
            "rol r25\n",
            "brcc 3f\n",
            "ldi r22, 0xC0\n",
            "ldi r23, 0xFF\n",
            "ldi r24, 0xFF\n",
            "ldi r25, 0xFF\n",
            "rjmp 3f\n",
            "2:\n",
            "rcall 50f\n",
            "andi r22, 0xC0\n",
            "3:\n",
            "movw r12, r22\n",
            "movw r14, r24\n",
            "movw r30, r28\n",
            "adiw r30, 14\n",
            "rcall 70f\n",
            "rcall 70f\n",
            "rcall 70f\n",
            "clr r22\n",
            "clr r23\n",
            "movw r24, r22\n",
            // ---- w = W >> 6 (Q.20; none: next row); s += w, sx += w·col, sy += w·row ----
            "5:\n",
            "rcall 40f\n",
            "tst r25\n",
            "breq 9f\n",
            "subi r16, -11\n",
            "rcall 50f\n",
            "movw r30, r28\n",
            "adiw r30, 14\n",
            "ldi r17, 1\n",
            "rcall 80f\n",
            "ldd r17, Y+13\n",
            "rcall 80f\n",
            "mov r17, r3\n",
            "rcall 80f\n",
            // ---- next row ----
            "9:\n",
            "inc r3\n",
            "cp r3, r4\n",
            "brsh 10f\n",
            "rjmp 1b\n",
            "10:\n",
            "pop r29\n",
            "pop r28\n",
            "clr r1\n",
            "rjmp 99f\n",
            // ---- 40: the weight of the excess r25:r22: 0 from span on ----
            "40:\n",
            "ldd r18, Y+4\n",
            "ldd r19, Y+5\n",
            "ldd r20, Y+6\n",
            "ldd r21, Y+7\n",
            "cp r22, r18\n",
            "cpc r23, r19\n",
            "cpc r24, r20\n",
            "cpc r25, r21\n",
            "brsh 48f\n",
            // a = e >> ra (< 2^16); P = a·b mod 2^32 in r25:r22
            "ldd r16, Y+12\n",
            "rcall 50f\n",
            "movw r18, r22\n",
            "ldd r20, Y+10\n",
            "ldd r21, Y+11\n",
            "rcall 60f\n",
            "movw r30, r22\n",
            "ldd r20, Y+8\n",
            "ldd r21, Y+9\n",
            "rcall 60f\n",
            "add r24, r30\n",
            "adc r25, r31\n",
            // y = P >> 11: int = P >> 27 (from 27 on: no weight)
            "mov r16, r25\n",
            "lsr r16\n",
            "lsr r16\n",
            "lsr r16\n",
            "cpi r16, 27\n",
            "brsh 48f\n",
            // P << 2: the fraction × 2^5 in r24:r23 (bits 6..10 cleared), 4·segment from r25
            "lsl r23\n",
            "rol r24\n",
            "rol r25\n",
            "lsl r23\n",
            "rol r24\n",
            "rol r25\n",
            "andi r23, 0xE0\n",
            "andi r25, 0x1F\n",
            "lsl r25\n",
            "lsl r25\n",
            "ldd r30, Y+{pt0}\n",
            "ldd r31, Y+{pt1}\n",
            "add r30, r25\n",
            "adc r31, r2\n",
            "lpm r14, Z+\n",
            "lpm r15, Z+\n",
            "lpm r20, Z+\n",
            "lpm r21, Z\n",
            "mov r18, r23\n",
            "mov r19, r24\n",
            "rcall 60f\n",
            // m = v − (d·frac >> 11)
            "sub r14, r24\n",
            "sbc r15, r25\n",
            "movw r24, r14\n",
            "clr r22\n",
            "clr r23\n",
            "ret\n",
            "48:\n",
            "clr r16\n",
            "clr r22\n",
            "clr r23\n",
            "movw r24, r22\n",
            "ret\n",
            // ---- 50: r25:r22 >>= r16 (bytes, then bits) ----
            "50:\n",
            "cpi r16, 8\n",
            "brlo 51f\n",
            "mov r22, r23\n",
            "mov r23, r24\n",
            "mov r24, r25\n",
            "clr r25\n",
            "subi r16, 8\n",
            "rjmp 50b\n",
            "51:\n",
            "subi r16, 1\n",
            "brcs 52f\n",
            "lsr r25\n",
            "ror r24\n",
            "ror r23\n",
            "ror r22\n",
            "rjmp 51b\n",
            "52:\n",
            "ret\n",
            // ---- 60: r25:r22 = r19:r18 × r21:r20 (inputs kept) ----
            "60:\n",
            mul16_ret_asm!(),
            // ---- 70: u32 at Z = ah·fh + (ah·fl >> 16) + (al·fh >> 16), f = r15:r12 ----
            "70:\n",
            "ld r18, Z\n",
            "ldd r19, Z+1\n",
            "movw r20, r14\n",
            "rcall 60b\n",
            "movw r16, r24\n",
            "clr r11\n",
            "ldd r18, Z+2\n",
            "ldd r19, Z+3\n",
            "movw r20, r12\n",
            "rcall 60b\n",
            "add r16, r24\n",
            "adc r17, r25\n",
            "adc r11, r2\n",
            "movw r20, r14\n",
            "rcall 60b\n",
            "add r22, r16\n",
            "adc r23, r17\n",
            "adc r24, r11\n",
            "adc r25, r2\n",
            "st Z+, r22\n",
            "st Z+, r23\n",
            "st Z+, r24\n",
            "st Z+, r25\n",
            "ret\n",
            // ---- 80: u32 at Z += r24:r22 × r17 ----
            "80:\n",
            "ld r18, Z\n",
            "ldd r19, Z+1\n",
            "ldd r20, Z+2\n",
            "ldd r21, Z+3\n",
            "mul r22, r17\n",
            "add r18, r0\n",
            "adc r19, r1\n",
            "adc r20, r2\n",
            "adc r21, r2\n",
            "mul r23, r17\n",
            "add r19, r0\n",
            "adc r20, r1\n",
            "adc r21, r2\n",
            "mul r24, r17\n",
            "add r20, r0\n",
            "adc r21, r1\n",
            "st Z+, r18\n",
            "st Z+, r19\n",
            "st Z+, r20\n",
            "st Z+, r21\n",
            "ret\n",
            "99:\n",
        )
    };
}

/// [`loc_core::fixed::portable_posterior`]`(sums, post.col, post)`, exactly (for `sums.len() ≤
/// 255`, and weights as the searches set them up: `span >> ra < 2^16`, `ra ≤ 16`): one routine
/// instead of ≈ 1.2 KB of LLVM's AVR code for the row loop, `2^−y` and the rescaling.
///
/// Register plan: the [`Posterior`] in Y (saved on the stack; its `col` the column offset), X
/// walks the sums, r3 the row, r4 the rows (the exp2 table's flash address from `post.table`,
/// set here), r2 zero; a cost, excess or weight in r25:r22. Subroutines: 40 the weight's
/// mantissa `m` (r25:r24, r23:r22 cleared; 0: no weight) and shift `int` (r16), so that the
/// Q.26 weight is `(m << 16) >> (int + 5)` (`2^−y` as `exp2_neg_q26`: `y = (a·b mod 2^32) >>
/// 11`, its segment from the flash table, the fraction's product `d·frac >> 11` as
/// `(d·(frac << 5)) >> 16`); 50 r25:r22 >>= r16; 60 r25:r22 = r19:r18 × r21:r20; 70 `mul_hi`
/// of the `u32` at Z by r15:r12 in place (Z += 4); 80 the `u32` at Z += r24:r22 × r17 (Z += 4).
pub fn posterior(sums: &[u32], post: &mut Posterior) {
    let rows = sums.len().min(255) as u8;
    post.table = exp2_segment_table();
    // SAFETY: X reads the first `rows` (0 to 255) sums; Y (saved on the stack and restored)
    // points at `post`, whose `cref`, `s`, `sx` and `sy` are written (through Z = Y + 13) and
    // whose other fields are read; `lpm` reads 4 bytes of the exp2 table (32 × 4 bytes in flash,
    // at `post.table`, segment < 32 by construction). Only the declared registers, r0, r1 (left
    // at 0), the flags, Y (restored) and four stack bytes (Y, then a return address at a time)
    // are written.
    unsafe {
        asm!(
            posterior_body!(),
            inout("X") sums.as_ptr() => _,
            inout("Z") post as *mut Posterior => _,
            inout("r4") rows => _,
            pt0 = const offset_of!(Posterior, table),
            pt1 = const offset_of!(Posterior, table) + 1,
            out("r2") _, out("r3") _, out("r11") _, out("r12") _, out("r13") _,
            out("r14") _, out("r15") _, out("r16") _, out("r17") _, out("r18") _,
            out("r19") _, out("r20") _, out("r21") _, out("r22") _, out("r23") _,
            out("r24") _, out("r25") _,
        );
    }
}

/// [`weights`]' instruction text (also in [`sink`]'s).
macro_rules! weights_body {
    () => {
        concat!(
            "push r28\n",
            "push r29\n",
            "movw r28, r30\n",
            "clr r2\n",
            // ---- b = 0, ra = 16; span 1 for σ = 0 (done), else u32::MAX ----
            "ldi r16, 16\n",
            "std Y+8, r16\n",
            "std Y+4, r2\n",
            "std Y+5, r2\n",
            "std Y+6, r2\n",
            "std Y+7, r2\n",
            "ldi r16, 0xFF\n",
            "ldi r17, 0xFF\n",
            "cp r20, r2\n",
            "cpc r21, r2\n",
            "brne 1f\n",
            "ldi r16, 1\n",
            "ldi r17, 0\n",
            "1:\n",
            "std Y+0, r16\n",
            "std Y+1, r17\n",
            "std Y+2, r17\n",
            "std Y+3, r17\n",
            "brne 11f\n",
            "rjmp 90f\n",
            "11:\n",
            // ---- a flat cost (K < 2^10 in Q.26): done ----
            "cpi r23, 4\n",
            "cpc r24, r2\n",
            "cpc r25, r2\n",
            "brsh 12f\n",
            "rjmp 90f\n",
            "12:\n",
            // ---- σ² into b's bytes ----
            "movw r8, r22\n",
            "movw r10, r24\n",
            "movw r18, r20\n",
            "rcall 60f\n",
            "std Y+4, r22\n",
            "std Y+5, r23\n",
            "std Y+6, r24\n",
            "std Y+7, r25\n",
            // ---- kn = K << z, top bit set ----
            "clr r17\n",
            "2:\n",
            "sbrc r11, 7\n",
            "rjmp 3f\n",
            "lsl r8\n",
            "rol r9\n",
            "rol r10\n",
            "rol r11\n",
            "inc r17\n",
            "rjmp 2b\n",
            "3:\n",
            // ---- p = mul_hi(mul_hi(kn, kn), log2(e) Q.31) >> 1 ----
            "movw r12, r8\n",
            "movw r14, r10\n",
            "rcall 70f\n",
            "movw r8, r22\n",
            "movw r10, r24\n",
            "ldi r18, 0x29\n",
            "ldi r19, 0x3B\n",
            "ldi r20, 0xAA\n",
            "ldi r21, 0xB8\n",
            "movw r12, r18\n",
            "movw r14, r20\n",
            "rcall 70f\n",
            "lsr r25\n",
            "ror r24\n",
            "ror r23\n",
            "ror r22\n",
            "movw r8, r22\n",
            "movw r10, r24\n",
            // ---- span = div_shl(σ², p / 21, 23 + 2z), clamped to [1, u32::MAX − 1] ----
            "ldi r18, 21\n",
            "ldi r19, 0\n",
            "ldi r20, 0\n",
            "ldi r21, 0\n",
            "call __udivmodsi4\n",
            "ldd r22, Y+4\n",
            "ldd r23, Y+5\n",
            "ldd r24, Y+6\n",
            "ldd r25, Y+7\n",
            "mov r16, r17\n",
            "lsl r16\n",
            "subi r16, -23\n",
            "call {div}\n",
            "cp r22, r2\n",
            "cpc r23, r2\n",
            "cpc r24, r2\n",
            "cpc r25, r2\n",
            "brne 4f\n",
            "inc r22\n",
            "4:\n",
            "mov r0, r22\n",
            "and r0, r23\n",
            "and r0, r24\n",
            "and r0, r25\n",
            "inc r0\n",
            "brne 5f\n",
            "dec r22\n",
            "5:\n",
            "std Y+0, r22\n",
            "std Y+1, r23\n",
            "std Y+2, r24\n",
            "std Y+3, r25\n",
            // ---- ra: the bits of span >> 16 ----
            "clr r16\n",
            "6:\n",
            "cp r24, r2\n",
            "cpc r25, r2\n",
            "breq 7f\n",
            "lsr r25\n",
            "ror r24\n",
            "inc r16\n",
            "rjmp 6b\n",
            "7:\n",
            "std Y+8, r16\n",
            // ---- e = 4 + ra − 2z; den = σ² (halved, e − 1, from 2^31 on) ----
            "subi r16, -4\n",
            "sub r16, r17\n",
            "sub r16, r17\n",
            "ldd r18, Y+4\n",
            "ldd r19, Y+5\n",
            "ldd r20, Y+6\n",
            "ldd r21, Y+7\n",
            "sbrs r21, 7\n",
            "rjmp 8f\n",
            "lsr r21\n",
            "ror r20\n",
            "ror r19\n",
            "ror r18\n",
            "dec r16\n",
            "8:\n",
            // ---- b = div_shl(p >> −e, den, 0) for e < 0 (0 from 32 bits on), else
            // div_shl(p, den, e) ----
            "movw r22, r8\n",
            "movw r24, r10\n",
            "tst r16\n",
            "brpl 10f\n",
            "9:\n",
            "lsr r25\n",
            "ror r24\n",
            "ror r23\n",
            "ror r22\n",
            "inc r16\n",
            "brne 9b\n",
            "10:\n",
            "call {div}\n",
            "std Y+4, r22\n",
            "std Y+5, r23\n",
            "std Y+6, r24\n",
            "std Y+7, r25\n",
            "90:\n",
            "pop r29\n",
            "pop r28\n",
            "clr r1\n",
            "rjmp 99f\n",
            // ---- 60: r25:r22 = r19:r18 × r21:r20 (inputs kept) ----
            "60:\n",
            mul16_ret_asm!(),
            // ---- 70: r25:r22 = ah·fh + (ah·fl >> 16) + (al·fh >> 16), a = r11:r8, f =
            // r15:r12 (h in r27:r26, its carry in r30) ----
            "70:\n",
            "movw r18, r8\n",
            "movw r20, r14\n",
            "rcall 60b\n",
            "movw r26, r24\n",
            "clr r30\n",
            "movw r18, r10\n",
            "movw r20, r12\n",
            "rcall 60b\n",
            "add r26, r24\n",
            "adc r27, r25\n",
            "adc r30, r2\n",
            "movw r20, r14\n",
            "rcall 60b\n",
            "add r22, r26\n",
            "adc r23, r27\n",
            "adc r24, r30\n",
            "adc r25, r2\n",
            "ret\n",
            "99:\n",
        )
    };
}

/// [`loc_core::fixed::portable_weights`], exactly: 386 bytes of flash for LLVM's 712.
///
/// Register plan: the [`Weights`] in Y (saved on the stack; `b`'s bytes hold σ² until `b` is
/// known), `k26 << z` then `p` in r11:r8, `z` in r17, r2 zero. Subroutines: 60 r25:r22 = r19:r18
/// × r21:r20; 70 r25:r22 = `mul_hi(r11:r8, r15:r12)` (the same three products as `mul_hi`); and
/// [`div_shl_c`] (the C ABI; it writes only r0, r1 (left 0), X, Z and r25:r22).
pub fn weights(k26: u32, sigma_q8: u16, w: &mut Weights) {
    let [k0, k1, k2, k3] = k26.to_le_bytes();
    let [s0, s1] = sigma_q8.to_le_bytes();
    // SAFETY: Y (saved on the stack and restored) points at `*w` (9 bytes, the offsets asserted
    // above), the only memory written; `__udivmodsi4` (libgcc, linked by every firmware) writes
    // only r18–r27, r30, r31 and r1 (left 0). Only the declared registers, r0, r1 (left at 0),
    // the flags, Y (restored) and four stack bytes (Y, then return addresses) are written.
    unsafe {
        asm!(
            weights_body!(),
            inout("Z") w as *mut Weights => _,
            inout("r22") k0 => _,
            inout("r23") k1 => _,
            inout("r24") k2 => _,
            inout("r25") k3 => _,
            inout("r20") s0 => _,
            inout("r21") s1 => _,
            out("r2") _, out("r8") _, out("r9") _, out("r10") _, out("r11") _,
            out("r12") _, out("r13") _, out("r14") _, out("r15") _, out("r16") _,
            out("r17") _, out("r18") _, out("r19") _, out("X") _,
            div = sym div_shl_c,
        );
    }
}

/// [`loc_core::fixed::div_shl`]`(a, b, e)`, exactly (for `b < 2^31`): one restoring division of
/// `a·2^e` by `b`, the remainder in Z:X, 32 steps (the quotient `a / b`, counted in r1) then
/// `e` more (counted in r0), each first checking that the quotient's top bit is clear (else
/// `u32::MAX`). The C ABI (`a` r25:r22, `b` r21:r18, `e` r16; the result in r25:r22), naked: it
/// writes only r0, r1 (left 0: both loops count it down to 0), X, Z, r25:r22 and the flags, and
/// [`weights`]' assembly calls it too. (Naked: an `asm!` block's bytes would be reassembled into
/// a `u32` by ≈ 25 moves. Base instructions only: a naked function's assembly does not get the
/// ATmega328P's `movw` and `mul`.)
#[unsafe(naked)]
pub extern "C" fn div_shl_c(a: u32, b: u32, e: u8) -> u32 {
    core::arch::naked_asm!(
        "mov r0, r16",
        "ldi r26, 32",
        "mov r1, r26",
        "clr r26",
        "clr r27",
        "clr r30",
        "clr r31",
        // ---- a step: the 32 of a / b, then e more, each checking the quotient first ----
        "1:",
        "tst r1",
        "brne 2f",
        "tst r0",
        "breq 4f",
        "sbrc r25, 7",
        "rjmp 3f",
        "dec r0",
        "inc r1",
        // ---- (remainder:quotient) << 1; the remainder reaches b: subtract, quotient bit ----
        "2:",
        "lsl r22",
        "rol r23",
        "rol r24",
        "rol r25",
        "rol r26",
        "rol r27",
        "rol r30",
        "rol r31",
        "cp r26, r18",
        "cpc r27, r19",
        "cpc r30, r20",
        "cpc r31, r21",
        "brlo 5f",
        "sub r26, r18",
        "sbc r27, r19",
        "sbc r30, r20",
        "sbc r31, r21",
        "ori r22, 1",
        "5:",
        "dec r1",
        "rjmp 1b",
        "3:",
        "ldi r22, 0xFF",
        "ldi r23, 0xFF",
        "ldi r24, 0xFF",
        "ldi r25, 0xFF",
        "4:",
        "ret",
    )
}

/// [`loc_core::fixed::mul_hi`]`(a, b)`, exactly: `ah·bh + (ah·bl >> 16) + (al·bh >> 16)`, each
/// 16 × 16 product from four `mul`s, in the argument registers and X, Z (no register to save).
pub fn mul_hi(a: u32, b: u32) -> u32 {
    let (mut lo, mut hi) = (a as u16, (a >> 16) as u16);
    // SAFETY: registers only (the declared ones, r0, r1 (left 0) and the flags).
    unsafe {
        asm!(
            "clr r27",
            // ---- h1 = (al·bh) >> 16 in r31:r30 ----
            "mul r23, r21",
            "movw r30, r0",
            "mul r22, r20",
            "mov r26, r1",
            "mul r22, r21",
            "add r26, r0",
            "adc r30, r1",
            "adc r31, r27",
            "mul r23, r20",
            "add r26, r0",
            "adc r30, r1",
            "adc r31, r27",
            // ---- h2 = (ah·bl) >> 16 in r23:r22 (al's) ----
            "mul r25, r19",
            "movw r22, r0",
            "mul r24, r18",
            "mov r26, r1",
            "mul r24, r19",
            "add r26, r0",
            "adc r22, r1",
            "adc r23, r27",
            "mul r25, r18",
            "add r26, r0",
            "adc r22, r1",
            "adc r23, r27",
            // ---- h = h1 + h2 (17 bits: r26:r31:r30) ----
            "clr r26",
            "add r30, r22",
            "adc r31, r23",
            "adc r26, r27",
            // ---- ah·bh in r23:r22:r19:r18 (bl's), plus h ----
            "mul r24, r20",
            "movw r18, r0",
            "mul r25, r21",
            "movw r22, r0",
            "mul r24, r21",
            "add r19, r0",
            "adc r22, r1",
            "adc r23, r27",
            "mul r25, r20",
            "add r19, r0",
            "adc r22, r1",
            "adc r23, r27",
            "add r18, r30",
            "adc r19, r31",
            "adc r22, r26",
            "adc r23, r27",
            "movw r24, r22",
            "movw r22, r18",
            "clr r1",
            inout("r23r22") lo,
            inout("r25r24") hi,
            inout("r19r18") b as u16 => _,
            in("r21r20") (b >> 16) as u16,
            out("X") _, out("Z") _,
            options(pure, nomem, nostack),
        );
    }
    (hi as u32) << 16 | lo as u32
}

/// [`loc_core::fixed::portable_move`]`(job, di, dj)`, exactly: `di·xstep` and `dj·ystep` (signed
/// 8 × unsigned 16 bits, two `mulsu` each, kept to 24 bits) added to every anchor slot's
/// 24-bit `dx0` and `dy0` (≈ 70 bytes for LLVM's ≈ 330).
pub fn move_window(job: &mut ColumnJob, di: i8, dj: i8) {
    // SAFETY: writes only the job's anchors (through Z, within the `&mut`); registers declared,
    // r1 cleared at the end.
    unsafe {
        asm!(
            // ---- dx = di·xstep in r26:r25:r24 ----
            "ldd r18, Z+14",
            "ldd r19, Z+15",
            "mulsu r22, r18",
            "movw r24, r0",
            "clr r26",
            "sbrc r25, 7",
            "com r26",
            "mulsu r22, r19",
            "add r25, r0",
            "adc r26, r1",
            // ---- dy = dj·ystep in r27:r17:r16 ----
            "ldd r18, Z+20",
            "ldd r19, Z+21",
            "mulsu r20, r18",
            "movw r16, r0",
            "clr r27",
            "sbrc r17, 7",
            "com r27",
            "mulsu r20, r19",
            "add r17, r0",
            "adc r27, r1",
            "clr r1",
            // ---- every anchor: dx0 (offset 4) += dx, dy0 (7) += dy ----
            "adiw r30, 26",
            "ldi r18, {n}",
            "2:",
            "ld r0, Z",
            "add r0, r24",
            "st Z+, r0",
            "ld r0, Z",
            "adc r0, r25",
            "st Z+, r0",
            "ld r0, Z",
            "adc r0, r26",
            "st Z+, r0",
            "ld r0, Z",
            "add r0, r16",
            "st Z+, r0",
            "ld r0, Z",
            "adc r0, r17",
            "st Z+, r0",
            "ld r0, Z",
            "adc r0, r27",
            "st Z+, r0",
            "adiw r30, 14",
            "dec r18",
            "brne 2b",
            n = const loc_core::MAX_ANCHORS,
            inout("Z") job as *mut ColumnJob => _,
            in("r22") di,
            in("r20") dj,
            out("r16") _, out("r17") _, out("r18") _, out("r19") _,
            out("r24") _, out("r25") _, out("X") _,
            options(nostack),
        );
    }
}

/// [`loc_core::fixed::portable_place`]`(job, p)`, exactly: the farthest offset `50·M`, `M` the
/// largest of `|0 − x|`, `|W − x|`, `|0 − y|`, `|H − y|` (17 bits, one local subroutine), its
/// shift, the insertion (20-byte slot copies, the key `ρ − shift·2^21` rebuilt from each
/// slot), then the new slot's fields (≈ 240 bytes for most of LLVM's ≈ 1.5 KB `Grid::setup`).
pub fn place(job: &mut ColumnJob, p: &Placement) {
    // SAFETY: reads `p` (X) and writes the job's first `n + 1` anchors and `n` (Z, within the
    // `&mut`; `n < MAX_ANCHORS` is the caller's contract, as for the portable one, which would
    // panic); registers declared, r1 cleared; 2 bytes of stack for the local `rcall`.
    unsafe {
        asm!(
            // ---- inputs: ρ r5:r2, x r17:r16, y r19:r18, w r21 (1..=3 kept, else 4) ----
            "ld r2, X+",
            "ld r3, X+",
            "ld r4, X+",
            "ld r5, X+",
            "ld r16, X+",
            "ld r17, X+",
            "ld r18, X+",
            "ld r19, X+",
            "ld r21, X",
            "subi r21, 1",
            "cpi r21, 3",
            "brcs 2f",
            "ldi r21, 3",
            "2:",
            "subi r21, 0xFF",
            // ---- W r7:r6, H r9:r8; n r20, stored n + 1; Z = &anchors[n − 1] ----
            "ldd r6, Z+14",
            "ldd r7, Z+15",
            "ldd r8, Z+20",
            "ldd r9, Z+21",
            "ldd r20, Z+4",
            "mov r22, r20",
            "inc r22",
            "std Z+4, r22",
            "ldi r22, 20",
            "mul r20, r22",
            "add r30, r0",
            "adc r31, r1",
            "adiw r30, 2",
            // ---- M = max |s − c| in r14:r12 ----
            "clr r12",
            "clr r13",
            "clr r14",
            "clr r26",
            "clr r27",
            "movw r10, r16",
            "rcall 7f",
            "movw r26, r6",
            "rcall 7f",
            "movw r10, r18",
            "movw r26, r8",
            "rcall 7f",
            "clr r26",
            "clr r27",
            "rcall 7f",
            // ---- m = 50·M in r24:r22 (< 2^23) ----
            "ldi r25, 50",
            "mul r12, r25",
            "movw r22, r0",
            "clr r24",
            "mul r13, r25",
            "add r23, r0",
            "adc r24, r1",
            "mul r14, r25",
            "add r24, r0",
            "clr r1",
            // ---- shift r10: halve m while m ≥ 65535 ----
            "clr r10",
            "ldi r25, 0xFF",
            "3:",
            "cpi r22, 0xFF",
            "cpc r23, r25",
            "cpc r24, r1",
            "brcs 4f",
            "lsr r24",
            "ror r23",
            "ror r22",
            "inc r10",
            "rjmp 3b",
            "4:",
            // ---- insertion: while b > 0 and ρ > key(anchors[b − 1]) move that slot up ----
            "5:",
            "tst r20",
            "breq 6f",
            "ldd r22, Z+14",
            "ldd r23, Z+15",
            "ldd r24, Z+16",
            "ldd r25, Z+17",
            "ldd r26, Z+19",
            "swap r26",
            "clr r27",
            "lsl r26",
            "rol r27",
            "sub r24, r26",
            "sbc r25, r27",
            "cp r22, r2",
            "cpc r23, r3",
            "cpc r24, r4",
            "cpc r25, r5",
            "brge 6f",
            "ldi r27, 20",
            "8:",
            "ld r0, Z+",
            "std Z+19, r0",
            "dec r27",
            "brne 8b",
            "sbiw r30, 40",
            "dec r20",
            "rjmp 5b",
            "6:",
            "adiw r30, 20",
            // ---- the slot: dx0 = −50·x, dy0 = −50·y (24 bits) ----
            "ldi r20, 50",
            "mul r16, r20",
            "movw r22, r0",
            "clr r24",
            "mulsu r17, r20",
            "add r23, r0",
            "adc r24, r1",
            "com r24",
            "com r23",
            "neg r22",
            "sbci r23, 0xFF",
            "sbci r24, 0xFF",
            "std Z+4, r22",
            "std Z+5, r23",
            "std Z+6, r24",
            "mul r18, r20",
            "movw r22, r0",
            "clr r24",
            "mulsu r19, r20",
            "add r23, r0",
            "adc r24, r1",
            "com r24",
            "com r23",
            "neg r22",
            "sbci r23, 0xFF",
            "sbci r24, 0xFF",
            "std Z+7, r22",
            "std Z+8, r23",
            "std Z+9, r24",
            "clr r1",
            // ---- shift·2^21 = (shift << 5) in bytes 2, 3: ρ + it, LOG2_CLAMP − it ----
            "mov r22, r10",
            "swap r22",
            "clr r23",
            "lsl r22",
            "rol r23",
            "add r4, r22",
            "adc r5, r23",
            "std Z+14, r2",
            "std Z+15, r3",
            "std Z+16, r4",
            "std Z+17, r5",
            "ldi r24, 0x78",
            "std Z+10, r24",
            "ldi r24, 0x9A",
            "std Z+11, r24",
            "ldi r24, 0xB4",
            "clr r25",
            "sub r24, r22",
            "sbc r25, r23",
            "std Z+12, r24",
            "std Z+13, r25",
            "std Z+18, r21",
            "std Z+19, r10",
            "rjmp 9f",
            // ---- subroutine: M = max(M, |s − c|), s = r27:r26 (u16), c = r11:r10 (i16) ----
            "7:",
            "movw r22, r26",
            "clr r24",
            "clr r25",
            "sbrc r11, 7",
            "com r25",
            "sub r22, r10",
            "sbc r23, r11",
            "sbc r24, r25",
            "sbrs r24, 7",
            "rjmp 2f",
            "com r24",
            "com r23",
            "neg r22",
            "sbci r23, 0xFF",
            "sbci r24, 0xFF",
            "2:",
            "cp r12, r22",
            "cpc r13, r23",
            "cpc r14, r24",
            "brcc 2f",
            "movw r12, r22",
            "mov r14, r24",
            "2:",
            "ret",
            "9:",
            inout("Z") job as *mut ColumnJob => _,
            inout("X") p as *const Placement => _,
            out("r2") _, out("r3") _, out("r4") _, out("r5") _, out("r6") _, out("r7") _,
            out("r8") _, out("r9") _, out("r10") _, out("r11") _, out("r12") _,
            out("r13") _, out("r14") _, out("r16") _, out("r17") _, out("r18") _,
            out("r19") _, out("r20") _, out("r21") _, out("r22") _, out("r23") _,
            out("r24") _, out("r25") _,
        );
    }
}

/// [`guess`]'s instruction text (also a local subroutine of [`sink`]'s).
macro_rules! guess_body {
    () => {
        concat!(
            "push r30\n",
            "push r31\n",
            "clr r6\n",
            "clr r7\n",
            "movw r8, r6\n",
            "movw r10, r6\n",
            "movw r12, r6\n",
            "movw r14, r6\n",
            "ldd r21, Z+4\n",
            "cpi r21, {n1}\n",
            "brlo 1f\n",
            "ldi r21, {n}\n",
            "1:\n",
            "tst r21\n",
            "brne 8f\n",
            "rjmp 9f\n",
            "8:\n",
            "adiw r30, 22\n",
            "set\n",
            // ---- one anchor: key = ρ − (shift << 21) in r19:r16 ----
            "2:\n",
            "ldd r16, Z+14\n",
            "ldd r17, Z+15\n",
            "ldd r18, Z+16\n",
            "ldd r19, Z+17\n",
            "ldd r20, Z+19\n",
            "mov r23, r20\n",
            "lsr r23\n",
            "lsr r23\n",
            "lsr r23\n",
            "swap r20\n",
            "andi r20, 0xF0\n",
            "lsl r20\n",
            "sub r18, r20\n",
            "sbc r19, r23\n",
            // The first anchor's key is the top.
            "brtc 3f\n",
            "movw r2, r16\n",
            "movw r4, r18\n",
            "clt\n",
            "3:\n",
            // ---- down = (top − key) >> 20 (unsigned); stop from 6 ----
            "movw r24, r2\n",
            "movw r26, r4\n",
            "sub r24, r16\n",
            "sbc r25, r17\n",
            "sbc r26, r18\n",
            "sbc r27, r19\n",
            "cpi r26, 0x60\n",
            "cpc r27, r1\n",
            "brlo 6f\n",
            "rjmp 9f\n",
            "6:\n",
            "swap r26\n",
            "andi r26, 0x0F\n",
            "ldi r22, 5\n",
            "sub r22, r26\n",
            // ---- x = dx0 (r19:r16), y = dy0 (r27:r24), w = 1, all << up ----
            "ldd r16, Z+4\n",
            "ldd r17, Z+5\n",
            "ldd r18, Z+6\n",
            "clr r19\n",
            "sbrc r18, 7\n",
            "com r19\n",
            "ldd r24, Z+7\n",
            "ldd r25, Z+8\n",
            "ldd r26, Z+9\n",
            "clr r27\n",
            "sbrc r26, 7\n",
            "com r27\n",
            "ldi r20, 1\n",
            "rjmp 5f\n",
            "4:\n",
            "lsl r20\n",
            "lsl r16\n",
            "rol r17\n",
            "rol r18\n",
            "rol r19\n",
            "lsl r24\n",
            "rol r25\n",
            "rol r26\n",
            "rol r27\n",
            "5:\n",
            "subi r22, 1\n",
            "brcc 4b\n",
            // ---- Σw += w, Σx −= x, Σy −= y ----
            "add r14, r20\n",
            "adc r15, r1\n",
            "sub r6, r16\n",
            "sbc r7, r17\n",
            "sbc r8, r18\n",
            "sbc r9, r19\n",
            "sub r10, r24\n",
            "sbc r11, r25\n",
            "sbc r12, r26\n",
            "sbc r13, r27\n",
            "adiw r30, 20\n",
            "dec r21\n",
            "breq 9f\n",
            "rjmp 2b\n",
            // ---- snap both coordinates ----
            "9:\n",
            "pop r31\n",
            "pop r30\n",
            "ldd r20, Z+14\n",
            "ldd r21, Z+15\n",
            "movw r16, r6\n",
            "movw r18, r8\n",
            "rcall 70f\n",
            "ldd r20, Z+20\n",
            "ldd r21, Z+21\n",
            "mov r30, r24\n",
            "movw r16, r10\n",
            "movw r18, r12\n",
            "rcall 70f\n",
            "mov r25, r24\n",
            "mov r24, r30\n",
            "clr r1\n",
            "rjmp 79f\n",
            // ---- c of s = r19:r16 along side r21:r20, Σw r15:r14 ----
            "70:\n",
            // m = 5·Σw (≤ 1280) in r23:r22
            "movw r22, r14\n",
            "lsl r22\n",
            "rol r23\n",
            "lsl r22\n",
            "rol r23\n",
            "add r22, r14\n",
            "adc r23, r15\n",
            // t = side·m in r5:r2
            "mul r20, r22\n",
            "movw r2, r0\n",
            "mul r21, r23\n",
            "movw r4, r0\n",
            "clr r25\n",
            "mul r20, r23\n",
            "add r3, r0\n",
            "adc r4, r1\n",
            "adc r5, r25\n",
            "mul r21, r22\n",
            "add r3, r0\n",
            "adc r4, r1\n",
            "adc r5, r25\n",
            // 2s in r19:r16, v = t in r9:r6, c = 0
            "lsl r16\n",
            "rol r17\n",
            "rol r18\n",
            "rol r19\n",
            "movw r6, r2\n",
            "movw r8, r4\n",
            "clr r24\n",
            "71:\n",
            "cpi r24, 10\n",
            "brsh 72f\n",
            "cp r6, r16\n",
            "cpc r7, r17\n",
            "cpc r8, r18\n",
            "cpc r9, r19\n",
            "brge 72f\n",
            "inc r24\n",
            "add r6, r2\n",
            "adc r7, r3\n",
            "adc r8, r4\n",
            "adc r9, r5\n",
            "add r6, r2\n",
            "adc r7, r3\n",
            "adc r8, r4\n",
            "adc r9, r5\n",
            "rjmp 71b\n",
            "72:\n",
            "ret\n",
            "79:\n",
        )
    };
}

/// [`loc_core::fixed::portable_guess`]`(job)`, exactly, as `i | j << 8`: per anchor the sort key
/// `ρ − 2^21·shift` against the first's (stop from 6 units below), the weight's exponent, the
/// 24-bit offsets sign-extended and doubled with the weight, the 32-bit sums; then both
/// coordinates' steps through one local subroutine (`t = 5·side·Σw` from four `mul`s, `c` up
/// while `c < 10` and `v < 2s`, signed). ≈ 200 bytes for ≈ 550 of LLVM's.
///
/// Register plan: Z the anchor (the job's address on the stack), r21 anchors left, r5:r2 the
/// first key, r9:r6 `Σw·x` (negated), r13:r10 `Σw·y` (negated), r15:r14 `Σw`, r19:r16 and
/// r27:r24 the anchor's key, difference, `x` and `y`, r20 `w`, r22 its exponent. Subroutine 70:
/// `c` (r24) of `s` = r19:r16, `side` = r21:r20, `Σw` = r15:r14 (r9:r2, r16–r19, r22–r25 and
/// r0, r1 clobbered).
pub fn guess(job: &ColumnJob) -> u16 {
    let g: u16;
    // SAFETY: reads the job (through Z, within the `&`); pushes and pops two bytes and calls a
    // local subroutine; registers declared, r1 cleared at the end.
    unsafe {
        asm!(
            guess_body!(),
            n = const loc_core::MAX_ANCHORS,
            n1 = const loc_core::MAX_ANCHORS + 1,
            inout("Z") job as *const ColumnJob => _,
            out("r25r24") g,
            out("r2") _, out("r3") _, out("r4") _, out("r5") _, out("r6") _, out("r7") _,
            out("r8") _, out("r9") _, out("r10") _, out("r11") _, out("r12") _,
            out("r13") _, out("r14") _, out("r15") _, out("r16") _, out("r17") _,
            out("r18") _, out("r19") _, out("r20") _, out("r21") _, out("r22") _,
            out("r23") _, out("X") _,
        );
    }
    g
}

/// [`observe`]'s instruction text (also in [`sink`]'s).
macro_rules! observe_body {
    () => {
        concat!(
            "movw r2, r24\n",
            "movw r4, r22\n",
            "movw r6, r20\n",
            "mov r8, r18\n",
            // ---- r14 = α < 0; |α| clamped to 2^29, << 3, in r25:r22 ----
            "movw r30, r4\n",
            "ldd r22, Z+4\n",
            "ldd r23, Z+5\n",
            "ldd r24, Z+6\n",
            "ldd r25, Z+7\n",
            "mov r14, r25\n",
            "lsl r14\n",
            "clr r14\n",
            "rol r14\n",
            "sbrs r25, 7\n",
            "rjmp 11f\n",
            "com r25\n",
            "com r24\n",
            "com r23\n",
            "neg r22\n",
            "sbci r23, 0xFF\n",
            "sbci r24, 0xFF\n",
            "sbci r25, 0xFF\n",
            "11:\n",
            "cpi r25, 0x20\n",
            "brlo 12f\n",
            "ldi r25, 0x20\n",
            "ldi r24, 0\n",
            "ldi r23, 0\n",
            "ldi r22, 0\n",
            "12:\n",
            "ldi r16, 3\n",
            "13:\n",
            "lsl r22\n",
            "rol r23\n",
            "rol r24\n",
            "rol r25\n",
            "dec r16\n",
            "brne 13b\n",
            // ---- k26 = mul_hi(·, 5·log10 2 Q.31) ----
            "ldi r18, {c0}\n",
            "ldi r19, {c1}\n",
            "ldi r20, {c2}\n",
            "ldi r21, {c3}\n",
            "call {mul_hi}\n",
            "movw r30, r4\n",
            "std Z+8, r22\n",
            "std Z+9, r23\n",
            "std Z+10, r24\n",
            "std Z+11, r25\n",
            // ---- inv_k = div_shl(2^30, k26 >> 1, 25), 0 if flat (k26 < 2^10) ----
            "clr r10\n",
            "clr r11\n",
            "movw r12, r10\n",
            "ldi r16, 4\n",
            "cp r23, r16\n",
            "cpc r24, r1\n",
            "cpc r25, r1\n",
            "brlo 15f\n",
            "movw r18, r22\n",
            "movw r20, r24\n",
            "lsr r21\n",
            "ror r20\n",
            "ror r19\n",
            "ror r18\n",
            "ldi r22, 0\n",
            "ldi r23, 0\n",
            "ldi r24, 0\n",
            "ldi r25, 0x40\n",
            "ldi r16, 25\n",
            "call {div}\n",
            "movw r10, r22\n",
            "movw r12, r24\n",
            // ---- job.n = 0 ----
            "15:\n",
            "movw r30, r2\n",
            "std Z+4, r1\n",
            "tst r8\n",
            "brne 1f\n",
            "rjmp 19f\n",
            // ---- one observation: w, y, x pushed; z in r25:r22; next observation ----
            "1:\n",
            "movw r30, r6\n",
            "ldd r16, Z+{ow}\n",
            "push r16\n",
            "ldd r17, Z+{oy1}\n",
            "push r17\n",
            "ldd r17, Z+{oy}\n",
            "push r17\n",
            "ldd r17, Z+{ox1}\n",
            "push r17\n",
            "ldd r17, Z+{ox}\n",
            "push r17\n",
            "ldd r22, Z+{oz}\n",
            "ldd r23, Z+{oz1}\n",
            "ldd r24, Z+{oz2}\n",
            "ldd r25, Z+{oz3}\n",
            "adiw r30, {size}\n",
            "movw r6, r30\n",
            // ---- anchors += 1, weight += w; r9 = w & 7 ----
            "movw r30, r4\n",
            "ldd r0, Z+16\n",
            "inc r0\n",
            "std Z+16, r0\n",
            "ldd r0, Z+17\n",
            "add r0, r16\n",
            "std Z+17, r0\n",
            "andi r16, 7\n",
            "mov r9, r16\n",
            // ---- d = z − P0; r15 = r14, complemented if d < 0; |d| ----
            "ldd r0, Z+0\n",
            "sub r22, r0\n",
            "ldd r0, Z+1\n",
            "sbc r23, r0\n",
            "ldd r0, Z+2\n",
            "sbc r24, r0\n",
            "ldd r0, Z+3\n",
            "sbc r25, r0\n",
            "mov r15, r14\n",
            "sbrs r25, 7\n",
            "rjmp 2f\n",
            "com r15\n",
            "com r25\n",
            "com r24\n",
            "com r23\n",
            "neg r22\n",
            "sbci r23, 0xFF\n",
            "sbci r24, 0xFF\n",
            "sbci r25, 0xFF\n",
            // ---- a = min(|d|, 2^26 − 1) << 6 ----
            "2:\n",
            "cpi r25, 4\n",
            "brlo 3f\n",
            "ldi r22, 0xC0\n",
            "ldi r23, 0xFF\n",
            "ldi r24, 0xFF\n",
            "ldi r25, 0xFF\n",
            "rjmp 5f\n",
            "3:\n",
            "ldi r16, 6\n",
            "4:\n",
            "lsl r22\n",
            "rol r23\n",
            "rol r24\n",
            "rol r25\n",
            "dec r16\n",
            "brne 4b\n",
            // ---- q = a >> 18 in r17:r16, q² in r21:r18 ----
            "5:\n",
            "movw r16, r24\n",
            "lsr r17\n",
            "ror r16\n",
            "lsr r17\n",
            "ror r16\n",
            "mul r16, r16\n",
            "movw r18, r0\n",
            "mul r17, r17\n",
            "movw r20, r0\n",
            "mul r16, r17\n",
            "lsl r0\n",
            "rol r1\n",
            "add r19, r0\n",
            "adc r20, r1\n",
            "clr r1\n",
            "adc r21, r1\n",
            // ---- flat (r27:r26:r17:r16) += q², r9 times, saturating ----
            "ldd r16, Z+12\n",
            "ldd r17, Z+13\n",
            "ldd r26, Z+14\n",
            "ldd r27, Z+15\n",
            "rjmp 7f\n",
            "6:\n",
            "add r16, r18\n",
            "adc r17, r19\n",
            "adc r26, r20\n",
            "adc r27, r21\n",
            "brcc 7f\n",
            "ldi r16, 0xFF\n",
            "ldi r17, 0xFF\n",
            "movw r26, r16\n",
            "7:\n",
            "dec r9\n",
            "brpl 6b\n",
            "std Z+12, r16\n",
            "std Z+13, r17\n",
            "std Z+14, r26\n",
            "std Z+15, r27\n",
            // ---- r = min(mul_hi(a, inv_k), 2^30) ----
            "movw r18, r10\n",
            "movw r20, r12\n",
            "call {mul_hi}\n",
            "cpi r25, 0x40\n",
            "brlo 8f\n",
            "ldi r25, 0x40\n",
            "ldi r24, 0\n",
            "ldi r23, 0\n",
            "ldi r22, 0\n",
            // ---- ρ = ±r − log2(1 m²) pushed; place(job, SP + 1); the 9 bytes popped ----
            "8:\n",
            "sbrs r15, 0\n",
            "rjmp 9f\n",
            "com r25\n",
            "com r24\n",
            "com r23\n",
            "neg r22\n",
            "sbci r23, 0xFF\n",
            "sbci r24, 0xFF\n",
            "sbci r25, 0xFF\n",
            "9:\n",
            "subi r22, {m0}\n",
            "sbci r23, {m1}\n",
            "sbci r24, {m2}\n",
            "sbci r25, {m3}\n",
            "push r25\n",
            "push r24\n",
            "push r23\n",
            "push r22\n",
            "in r22, 0x3d\n",
            "in r23, 0x3e\n",
            "subi r22, 0xFF\n",
            "sbci r23, 0xFF\n",
            "movw r24, r2\n",
            "call {place}\n",
            "ldi r16, 9\n",
            "10:\n",
            "pop r0\n",
            "dec r16\n",
            "brne 10b\n",
            "dec r8\n",
            "breq 19f\n",
            "rjmp 1b\n",
            // ---- a flat cost (inv_k = 0): job.n = 0 ----
            "19:\n",
            "or r10, r11\n",
            "or r10, r12\n",
            "or r10, r13\n",
            "brne 20f\n",
            "movw r30, r2\n",
            "std Z+4, r1\n",
            "20:\n",
        )
    };
}

/// [`loc_core::fixed::portable_observe`]`(job, s, obs)`, exactly: first `|K|` (`mul_hi`,
/// called), its inverse (`div_shl_c`, called) and `job.n = 0`; then per observation its
/// [`Placement`] pushed on the stack as it is found (weight, `y`, `x`, then `ρ`: the bytes in
/// order above the stack pointer), the counts, `d = z − P0` and `|d|` clamped and scaled (`a`,
/// the argument of `mul_hi`; `q = a >> 18`), the flat cost plus `(w & 7)` saturating
/// additions of `q²`, then `ρ` from `mul_hi` (called), clamped, signed and less `log2(1 m²)`,
/// and [`AvrTerm`]'s `place` called on the pushed placement (then popped).
///
/// Register plan: r3:r2 the job, r5:r4 `s`, r7:r6 the next observation, r8 observations left,
/// r9 the weight's `w & 7` (a count), r13:r10 `inv_k`, r14 1 if α < 0, r15 bit 0 set when `ρ`
/// changes sign (all kept across the calls, which follow the ABI: r1 zero, r2–r17 preserved);
/// r25:r22 `d`, then `a`, then `ρ`.
pub fn observe(job: &mut ColumnJob, s: &mut Setup, obs: &[Obs]) {
    // SAFETY: reads `obs` (Z, `obs.len()` items of `size_of::<Obs>()` bytes at the offsets
    // `offset_of!` gives) and `s`, writes `s` (Z, within the `&mut`, at the offsets asserted
    // above) and `job.n`; the job's anchors only through the called `place`, whose contract
    // (`obs.len() ≤ MAX_ANCHORS`) is the caller's, as for the portable one. The stack: 9 bytes
    // pushed per observation and popped, and the calls (their return addresses and saves),
    // which follow the ABI; every register they or this code may change is declared; r1 is
    // zero at the end.
    unsafe {
        asm!(
            observe_body!(),
            oz = const offset_of!(Obs, z),
            oz1 = const offset_of!(Obs, z) + 1,
            oz2 = const offset_of!(Obs, z) + 2,
            oz3 = const offset_of!(Obs, z) + 3,
            ox = const offset_of!(Obs, pos) + offset_of!(loc_core::fixed::PointCm, x),
            ox1 = const offset_of!(Obs, pos) + offset_of!(loc_core::fixed::PointCm, x) + 1,
            oy = const offset_of!(Obs, pos) + offset_of!(loc_core::fixed::PointCm, y),
            oy1 = const offset_of!(Obs, pos) + offset_of!(loc_core::fixed::PointCm, y) + 1,
            ow = const offset_of!(Obs, weight),
            size = const size_of::<Obs>(),
            m0 = const loc_core::fixed::LOG2_M2 & 0xFF,
            m1 = const (loc_core::fixed::LOG2_M2 >> 8) & 0xFF,
            m2 = const (loc_core::fixed::LOG2_M2 >> 16) & 0xFF,
            m3 = const (loc_core::fixed::LOG2_M2 >> 24) & 0xFF,
            c0 = const 0x26,
            c1 = const 0xC1,
            c2 = const 0xA8,
            c3 = const 0xC0,
            div = sym div_shl_c,
            mul_hi = sym <AvrTerm as TermKernel>::mul_hi,
            place = sym <AvrTerm as TermKernel>::place,
            inout("r25r24") job as *mut ColumnJob => _,
            inout("r23r22") s as *mut Setup => _,
            inout("r21r20") obs.as_ptr() => _,
            inout("r18") obs.len() as u8 => _,
            out("r2") _, out("r3") _, out("r4") _, out("r5") _, out("r6") _, out("r7") _,
            out("r8") _, out("r9") _, out("r10") _, out("r11") _, out("r12") _,
            out("r13") _, out("r14") _, out("r15") _, out("r16") _, out("r17") _,
            out("r19") _, out("r26") _, out("r27") _, out("r30") _, out("r31") _,
        );
    }
}

/// [`search`]'s instruction text (also in [`sink`]'s).
macro_rules! search_body {
    () => {
        concat!(
            "movw r2, r24\n",
            "movw r4, r22\n",
            "movw r6, r20\n",
            // ---- (gi, gj) = guess(job) in r19:r18: i = 5·gi in r8, gj in r14 ----
            "mov r8, r18\n",
            "lsl r8\n",
            "lsl r8\n",
            "add r8, r18\n",
            "mov r14, r19\n",
            // ---- the window: moved to (0, 0), 11 rows, stride 5 ----
            "movw r30, r2\n",
            "ld r22, Z\n",
            "neg r22\n",
            "ldd r20, Z+1\n",
            "neg r20\n",
            "st Z, r1\n",
            "std Z+1, r1\n",
            "ldi r24, 11\n",
            "std Z+2, r24\n",
            "ldi r24, 5\n",
            "std Z+{stride}, r24\n",
            "movw r24, r2\n",
            "adiw r24, {job}\n",
            "call {mv}\n",
            // ---- the guessed point's column, the other rows skipped, no bound ----
            "ldi r16, 1\n",
            "clr r17\n",
            "mov r0, r14\n",
            "rjmp 2f\n",
            "1:\n",
            "lsl r16\n",
            "rol r17\n",
            "2:\n",
            "dec r0\n",
            "brpl 1b\n",
            "com r16\n",
            "com r17\n",
            "ldi r18, 0xFF\n",
            "ldi r19, 0xFF\n",
            "movw r20, r18\n",
            "rcall 80f\n",
            // ---- best[0] = (5·gi, 5·gj, sums[gj]) ----
            "mov r24, r14\n",
            "lsl r24\n",
            "lsl r24\n",
            "movw r30, r2\n",
            "subi r30, {ns0}\n",
            "sbci r31, {ns1}\n",
            "add r30, r24\n",
            "adc r31, r1\n",
            "ld r18, Z\n",
            "ldd r19, Z+1\n",
            "ldd r20, Z+2\n",
            "ldd r21, Z+3\n",
            "add r24, r14\n",
            "movw r30, r4\n",
            "st Z, r8\n",
            "std Z+1, r24\n",
            "std Z+2, r18\n",
            "std Z+3, r19\n",
            "std Z+4, r20\n",
            "std Z+5, r21\n",
            // ---- the coarse columns i = 0, 5, …, 50 ----
            "clr r8\n",
            "3:\n",
            "movw r30, r4\n",
            "ld r24, Z\n",
            "ldd r10, Z+2\n",
            "ldd r11, Z+3\n",
            "ldd r12, Z+4\n",
            "ldd r13, Z+5\n",
            "cp r24, r8\n",
            "brcs 4f\n",
            // Up to the best's column: one above its cost (saturating).
            "sec\n",
            "adc r10, r1\n",
            "adc r11, r1\n",
            "adc r12, r1\n",
            "adc r13, r1\n",
            "brcc 4f\n",
            "sbc r10, r1\n",
            "sbc r11, r1\n",
            "sbc r12, r1\n",
            "sbc r13, r1\n",
            "4:\n",
            "movw r18, r10\n",
            "movw r20, r12\n",
            "clr r16\n",
            "clr r17\n",
            "rcall 80f\n",
            "rcall 85f\n",
            "ldi r24, 5\n",
            "add r8, r24\n",
            "ldi r24, 51\n",
            "cp r8, r24\n",
            "brcs 3b\n",
            // ---- post.cref and best[1] = best[0]; r5:r4 = &best[1] ----
            "movw r30, r4\n",
            "movw r26, r6\n",
            "ldi r24, 6\n",
            "5:\n",
            "ld r0, Z+\n",
            "std Z+5, r0\n",
            "dec r24\n",
            "brne 5b\n",
            "ldd r18, Z+2\n",
            "ldd r19, Z+3\n",
            "ldd r20, Z+4\n",
            "ldd r21, Z+5\n",
            "st X+, r18\n",
            "st X+, r19\n",
            "st X+, r20\n",
            "st X, r21\n",
            "movw r4, r30\n",
            // ---- the fine window: i0 r18, j0 r19, i1 r9 (from r24), rows r25 ----
            "ld r24, Z\n",
            "ldd r25, Z+1\n",
            "mov r18, r24\n",
            "subi r18, 5\n",
            "brcc 6f\n",
            "clr r18\n",
            "6:\n",
            "mov r19, r25\n",
            "subi r19, 5\n",
            "brcc 7f\n",
            "clr r19\n",
            "7:\n",
            "subi r24, 0xFB\n",
            "cpi r24, 51\n",
            "brlo 8f\n",
            "ldi r24, 50\n",
            "8:\n",
            "subi r25, 0xFB\n",
            "cpi r25, 51\n",
            "brlo 9f\n",
            "ldi r25, 50\n",
            "9:\n",
            "sub r25, r19\n",
            "inc r25\n",
            "mov r8, r18\n",
            "mov r9, r24\n",
            // ---- moved by (i0, j0) from the origin; l.i0, l.j0, l.rows; stride 1 ----
            "movw r30, r2\n",
            "mov r22, r18\n",
            "mov r20, r19\n",
            "st Z, r18\n",
            "std Z+1, r19\n",
            "std Z+2, r25\n",
            "ldi r24, 1\n",
            "std Z+{stride}, r24\n",
            "movw r24, r2\n",
            "adiw r24, {job}\n",
            "call {mv}\n",
            // ---- a fine column: bound = max(cref + span (saturating), best.cost) ----
            "10:\n",
            "movw r30, r6\n",
            "ld r18, Z\n",
            "ldd r19, Z+1\n",
            "ldd r20, Z+2\n",
            "ldd r21, Z+3\n",
            "ldd r0, Z+4\n",
            "add r18, r0\n",
            "ldd r0, Z+5\n",
            "adc r19, r0\n",
            "ldd r0, Z+6\n",
            "adc r20, r0\n",
            "ldd r0, Z+7\n",
            "adc r21, r0\n",
            "brcc 11f\n",
            "ldi r18, 0xFF\n",
            "ldi r19, 0xFF\n",
            "movw r20, r18\n",
            "11:\n",
            "movw r30, r4\n",
            "ldd r10, Z+2\n",
            "ldd r11, Z+3\n",
            "ldd r12, Z+4\n",
            "ldd r13, Z+5\n",
            "cp r18, r10\n",
            "cpc r19, r11\n",
            "cpc r20, r12\n",
            "cpc r21, r13\n",
            "brcc 12f\n",
            "movw r18, r10\n",
            "movw r20, r12\n",
            "12:\n",
            "clr r16\n",
            "clr r17\n",
            "rcall 80f\n",
            // ---- posterior(sums[..rows], i − i0, post) (the local subroutine 96: r2–r4 kept);
            // take below best.cost ----
            "movw r30, r2\n",
            "ld r0, Z\n",
            "mov r20, r8\n",
            "sub r20, r0\n",
            "push r2\n",
            "push r3\n",
            "push r4\n",
            "ldd r4, Z+2\n",
            "movw r26, r2\n",
            "subi r26, {ns0}\n",
            "sbci r27, {ns1}\n",
            "movw r30, r6\n",
            "std Z+{pcol}, r20\n",
            "rcall 96f\n",
            "pop r4\n",
            "pop r3\n",
            "pop r2\n",
            "movw r30, r4\n",
            "ldd r10, Z+2\n",
            "ldd r11, Z+3\n",
            "ldd r12, Z+4\n",
            "ldd r13, Z+5\n",
            "rcall 85f\n",
            "inc r8\n",
            "cp r9, r8\n",
            "brcs 99f\n",
            "rjmp 10b\n",
            // ---- 80: column r8, bound min(r21:r18, 2^32 − 2), skip r17:r16 ----
            "80:\n",
            "ldi r22, 0xFF\n",
            "cp r18, r22\n",
            "cpc r19, r22\n",
            "cpc r20, r22\n",
            "cpc r21, r22\n",
            "brne 81f\n",
            "ldi r18, 0xFE\n",
            "81:\n",
            "movw r30, r2\n",
            "std Z+{b0}, r18\n",
            "std Z+{b1}, r19\n",
            "std Z+{b2}, r20\n",
            "std Z+{b3}, r21\n",
            "std Z+{sk0}, r16\n",
            "std Z+{sk1}, r17\n",
            "ld r0, Z\n",
            "mov r24, r8\n",
            "sub r24, r0\n",
            "std Z+{col}, r24\n",
            "ldd r22, Z+2\n",
            "clr r23\n",
            "movw r24, r2\n",
            "subi r24, {ns0}\n",
            "sbci r25, {ns1}\n",
            "movw r20, r2\n",
            "subi r20, {nj0}\n",
            "sbci r21, {nj1}\n",
            "jmp {column}\n",
            // ---- 85: job.min < r13:r10 → best = (r8, j0 + job.min_row, job.min) ----
            "85:\n",
            "movw r30, r2\n",
            "ldd r18, Z+{mn0}\n",
            "ldd r19, Z+{mn1}\n",
            "ldd r20, Z+{mn2}\n",
            "ldd r21, Z+{mn3}\n",
            "ldd r22, Z+{minrow}\n",
            "ldd r23, Z+1\n",
            "cp r18, r10\n",
            "cpc r19, r11\n",
            "cpc r20, r12\n",
            "cpc r21, r13\n",
            "brcc 86f\n",
            "movw r30, r4\n",
            "st Z, r8\n",
            "add r22, r23\n",
            "std Z+1, r22\n",
            "std Z+2, r18\n",
            "std Z+3, r19\n",
            "std Z+4, r20\n",
            "std Z+5, r21\n",
            "86:\n",
            "ret\n",
            "99:\n",
        )
    };
}

/// [`loc_core::fixed::portable_search`]`(l, best, post)`, exactly: [`guess`] called; the
/// coarse stage (the window moved to the origin by [`AvrTerm`]'s `move_window`, stride 5; the
/// guessed point's column with the other rows skipped, then the 11 columns, each bounded one
/// above the best cost up to the best's column) into `best[0]`; `post.cref` and `best[1]` from
/// it; then the fine window (corner, end and rows from the winner, saturating, clipped at 50)
/// column by column: its bound (`cref + span` saturating, `best[1].cost` if larger),
/// `posterior` called, the minimum taken if strictly below `best[1].cost`. Two local
/// subroutines: 80 (a column: its bound capped at `u32::MAX − 1`, skip, offset, then a tail
/// jump to [`AvrTerm`]'s `column`) and 85 (take the column's minimum below r13:r10).
///
/// Register plan: r3:r2 the lattice, r5:r4 the best point being searched for, r7:r6 `post`,
/// r8 the column `i`, r9 the last one, r13:r10 the bound of a take, r14 the guessed row
/// (all kept across the calls, which follow the ABI).
pub fn search(l: &mut Lattice, best: &mut [LatticeMin; 2], post: &mut Posterior) {
    post.table = exp2_segment_table();
    // SAFETY: reads and writes `*l` (its window fields, the job's header: offsets from
    // `offset_of!`, all below 64; the sums' first 11) and `*best` (12 bytes) and `post.cref`
    // (X, Z, within the `&mut`s); the job's anchors, the sums and `*post` otherwise only
    // through the called `guess`, `move_window`, `column` and `posterior` (the sums as the
    // slice `l.sums[..l.rows]`, `l.rows ≤ 11` as set here). The calls use the stack and follow
    // the ABI; every register they or this code may change is declared; r1 is zero throughout.
    unsafe {
        asm!(
            // ---- guess(job) into r19:r18, the arguments kept ----
            "push r20",
            "push r21",
            "push r22",
            "push r23",
            "push r24",
            "push r25",
            "adiw r24, {job}",
            "call {guess}",
            "movw r18, r24",
            "pop r25",
            "pop r24",
            "pop r23",
            "pop r22",
            "pop r21",
            "pop r20",
            search_body!(),
            "rjmp 98f",
            "96:",
            posterior_body!(),
            "ret",
            "98:",
            job = const offset_of!(Lattice, job),
            stride = const offset_of!(Lattice, job) + offset_of!(ColumnJob, stride),
            b0 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, bound),
            b1 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, bound) + 1,
            b2 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, bound) + 2,
            b3 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, bound) + 3,
            sk0 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, skip),
            sk1 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, skip) + 1,
            col = const offset_of!(Lattice, job) + offset_of!(ColumnJob, col),
            mn0 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, min),
            mn1 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, min) + 1,
            mn2 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, min) + 2,
            mn3 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, min) + 3,
            minrow = const offset_of!(Lattice, job) + offset_of!(ColumnJob, min_row),
            ns0 = const (offset_of!(Lattice, sums) as u16).wrapping_neg() & 0xFF,
            ns1 = const (offset_of!(Lattice, sums) as u16).wrapping_neg() >> 8,
            nj0 = const (offset_of!(Lattice, job) as u16).wrapping_neg() & 0xFF,
            nj1 = const (offset_of!(Lattice, job) as u16).wrapping_neg() >> 8,
            guess = sym guess,
            mv = sym <AvrTerm as TermKernel>::move_window,
            column = sym <AvrTerm as TermKernel>::column,
            pcol = const offset_of!(Posterior, col),
            pt0 = const offset_of!(Posterior, table),
            pt1 = const offset_of!(Posterior, table) + 1,
            inout("r25r24") l as *mut Lattice => _,
            inout("r23r22") best as *mut [LatticeMin; 2] => _,
            inout("r21r20") post as *mut Posterior => _,
            out("r2") _, out("r3") _, out("r4") _, out("r5") _, out("r6") _, out("r7") _,
            out("r8") _, out("r9") _, out("r10") _, out("r11") _, out("r12") _,
            out("r13") _, out("r14") _, out("r16") _, out("r17") _, out("r18") _,
            out("r19") _, out("r26") _, out("r27") _, out("r30") _, out("r31") _,
        );
    }
}

/// [`finish`]'s instruction text (also in [`sink`]'s).
macro_rules! finish_body {
    () => {
        concat!(
            "push r28\n",
            "push r29\n",
            "movw r2, r24\n",
            "movw r4, r22\n",
            "movw r6, r20\n",
            "movw r8, r16\n",
            "movw r10, r18\n",
            "clr r12\n",
            // ---- cost r17:r14: flat (n = 0), else mul_hi(best[1].cost, mul_hi(k26, k26)) ----
            "movw r30, r2\n",
            "adiw r30, {k26}\n",
            "ld r22, Z+\n",
            "ld r23, Z+\n",
            "ld r24, Z+\n",
            "ld r25, Z+\n",
            "ld r14, Z+\n",
            "ld r15, Z+\n",
            "ld r16, Z+\n",
            "ld r17, Z+\n",
            "ldd r0, Z+{n_rel}\n",
            "tst r0\n",
            "breq 1f\n",
            "movw r18, r22\n",
            "movw r20, r24\n",
            "call {mul_hi}\n",
            "movw r18, r22\n",
            "movw r20, r24\n",
            "movw r30, r4\n",
            "ldd r22, Z+8\n",
            "ldd r23, Z+9\n",
            "ldd r24, Z+10\n",
            "ldd r25, Z+11\n",
            "call {mul_hi}\n",
            "movw r14, r22\n",
            "movw r16, r24\n",
            // ---- min_cost = cost + const_cost, saturating ----
            "1:\n",
            "add r14, r8\n",
            "adc r15, r9\n",
            "adc r16, r10\n",
            "adc r17, r11\n",
            "brcc 2f\n",
            "ldi r16, 0xFF\n",
            "ldi r17, 0xFF\n",
            "movw r14, r16\n",
            "2:\n",
            "movw r30, r6\n",
            "adiw r30, {mc}\n",
            "st Z+, r14\n",
            "st Z+, r15\n",
            "st Z+, r16\n",
            "st Z+, r17\n",
            // ---- anchors, total weight, lattice point ----
            "movw r30, r2\n",
            "ldd r16, Z+{anc}\n",
            "ldd r17, Z+{wt}\n",
            "movw r30, r4\n",
            "ldd r18, Z+6\n",
            "ldd r19, Z+7\n",
            "movw r30, r6\n",
            "std Z+{oanc}, r16\n",
            "std Z+{owt}, r17\n",
            "std Z+{ola0}, r18\n",
            "std Z+{ola1}, r19\n",
            // ---- evaluations: all = 122 + (5n − 4)(5m − 4) in r13, the MLE's all − n·m ----
            "movw r30, r4\n",
            "ld r24, Z\n",
            "rcall 60f\n",
            "mov r17, r16\n",
            "mov r18, r19\n",
            "ldd r24, Z+1\n",
            "rcall 60f\n",
            "mul r17, r16\n",
            "mov r21, r0\n",
            "mul r18, r19\n",
            "mov r13, r0\n",
            "clr r1\n",
            "ldi r20, {ce}\n",
            "add r13, r20\n",
            "mov r20, r13\n",
            "sub r20, r21\n",
            "movw r30, r6\n",
            "std Z+{oev0}, r20\n",
            "std Z+{oev1}, r12\n",
            // ---- the MLE's position: to_mm(W, best[1].i, 0), to_mm(H, best[1].j, 0) ----
            "movw r28, r6\n",
            "adiw r28, {px}\n",
            "movw r30, r4\n",
            "ldd r26, Z+6\n",
            "rcall 64f\n",
            "movw r30, r4\n",
            "ldd r26, Z+7\n",
            "rcall 63f\n",
            // ---- out[1] = out[0]; its evaluations ----
            "movw r30, r6\n",
            "movw r26, r6\n",
            "adiw r26, {esize}\n",
            "ldi r24, {esize}\n",
            "3:\n",
            "ld r0, Z+\n",
            "st X+, r0\n",
            "dec r24\n",
            "brne 3b\n",
            "movw r30, r6\n",
            "std Z+{mev0}, r13\n",
            // ---- the posterior mean's position, if Σw ≠ 0 ----
            "movw r30, r4\n",
            "adiw r30, {ps}\n",
            "ld r8, Z+\n",
            "ld r9, Z+\n",
            "ld r10, Z+\n",
            "ld r11, Z+\n",
            "mov r0, r8\n",
            "or r0, r9\n",
            "or r0, r10\n",
            "or r0, r11\n",
            "breq 9f\n",
            // Z at Σw·c (after Σw).
            "movw r28, r6\n",
            "adiw r28, {mpx}\n",
            "rcall 66f\n",
            "movw r30, r2\n",
            "ld r26, Z\n",
            "rcall 68f\n",
            "movw r30, r4\n",
            "adiw r30, {sy}\n",
            "rcall 66f\n",
            "movw r30, r2\n",
            "ldd r26, Z+1\n",
            "rcall 67f\n",
            "9:\n",
            "pop r29\n",
            "pop r28\n",
            "rjmp 99f\n",
            // ---- 60: coarse indices in the window of winner r24: n = 1 + (r24 > 0) + (r24 <
            // 50) in r16, 5n − 4 in r19 ----
            "60:\n",
            "ldi r16, 1\n",
            "tst r24\n",
            "breq 61f\n",
            "inc r16\n",
            "61:\n",
            "cpi r24, {f8}\n",
            "brsh 62f\n",
            "inc r16\n",
            "62:\n",
            "mov r19, r16\n",
            "lsl r19\n",
            "lsl r19\n",
            "add r19, r16\n",
            "subi r19, 4\n",
            "ret\n",
            // ---- 66: f = div_shl(the u32 at Z, Σw, 12) in r19:r16 ----
            "66:\n",
            "ld r22, Z+\n",
            "ld r23, Z+\n",
            "ld r24, Z+\n",
            "ld r25, Z+\n",
            "movw r18, r8\n",
            "movw r20, r10\n",
            "ldi r16, 12\n",
            "call {div}\n",
            "movw r16, r22\n",
            "movw r18, r24\n",
            "ret\n",
            // ---- 63, 67: along H (63: f = 0); 64, 68: along W (64: f = 0); then 70 ----
            "63:\n",
            "clr r16\n",
            "clr r17\n",
            "movw r18, r16\n",
            "67:\n",
            "movw r30, r2\n",
            "ldd r20, Z+{ys0}\n",
            "ldd r21, Z+{ys1}\n",
            "rjmp 70f\n",
            "64:\n",
            "clr r16\n",
            "clr r17\n",
            "movw r18, r16\n",
            "68:\n",
            "movw r30, r2\n",
            "ldd r20, Z+{xs0}\n",
            "ldd r21, Z+{xs1}\n",
            // ---- 70: (8·side·o + (side·f mod 2^32 >> 9) + 20) / 40 at Y+, side r21:r20, o
            // r26, f r19:r16 ----
            "70:\n",
            "mul r20, r16\n",
            "movw r22, r0\n",
            "mul r20, r18\n",
            "movw r24, r0\n",
            "mul r20, r17\n",
            "add r23, r0\n",
            "adc r24, r1\n",
            "adc r25, r12\n",
            "mul r21, r16\n",
            "add r23, r0\n",
            "adc r24, r1\n",
            "adc r25, r12\n",
            "mul r21, r17\n",
            "add r24, r0\n",
            "adc r25, r1\n",
            "mul r20, r19\n",
            "add r25, r0\n",
            "mul r21, r18\n",
            "add r25, r0\n",
            "lsr r25\n",
            "ror r24\n",
            "ror r23\n",
            "mul r20, r26\n",
            "movw r16, r0\n",
            "clr r18\n",
            "clr r19\n",
            "mul r21, r26\n",
            "add r17, r0\n",
            "adc r18, r1\n",
            "ldi r27, 3\n",
            "71:\n",
            "lsl r16\n",
            "rol r17\n",
            "rol r18\n",
            "rol r19\n",
            "dec r27\n",
            "brne 71b\n",
            "add r16, r23\n",
            "adc r17, r24\n",
            "adc r18, r25\n",
            "adc r19, r12\n",
            "subi r16, 0xEC\n",
            "sbci r17, 0xFF\n",
            "sbci r18, 0xFF\n",
            "sbci r19, 0xFF\n",
            "movw r22, r16\n",
            "movw r24, r18\n",
            "ldi r18, 40\n",
            "ldi r19, 0\n",
            "ldi r20, 0\n",
            "ldi r21, 0\n",
            "clr r1\n",
            "call __udivmodsi4\n",
            "st Y+, r18\n",
            "st Y+, r19\n",
            "st Y+, r20\n",
            "st Y+, r21\n",
            "ret\n",
            "99:\n",
        )
    };
}

/// [`loc_core::fixed::portable_finish`]`::<AvrTerm>(l, f, const_cost, out)`, exactly: the cost
/// (`mul_hi` twice, called; the flat cost if `n = 0`) plus `const_cost` saturating, the counts,
/// the window's evaluations (`122 + (5n − 4)(5m − 4)`, less `n·m` for the MLE: `n`, `m` the
/// coarse columns and rows in the window, 2 or 3, subroutine 60), the MLE's position, the
/// estimate copied, then the posterior mean's (`div_shl_c`, called) if it has a weight. Each
/// position through subroutine 70: `(8·side·o + (side·f mod 2^32 >> 9) + 20) / 40` (libgcc's
/// `__udivmodsi4`) stored at `Y+`. (≈ 300 bytes for LLVM's ≈ 700.)
///
/// Register plan: r3:r2 `l`, r5:r4 `f`, r7:r6 `out`, r11:r8 `const_cost` then `Σw`, r12 zero,
/// r13 the window's evaluations; Y the position being written (saved on the stack). The calls
/// follow the ABI (r2–r17 and Y kept).
pub fn finish(l: &Lattice, f: &SinkLocals, const_cost: u32, out: &mut [Estimate; 2]) {
    // SAFETY: reads `*l` and `*f` and writes `*out` (through Y, Z, X: offsets from
    // `offset_of!`, asserted below 64 and within the structs); the calls (`mul_hi`,
    // `div_shl_c`, `__udivmodsi4`) write only registers declared here (and r1, left 0). Y is
    // saved on the stack and restored; the stack holds it and return addresses.
    unsafe {
        asm!(
            finish_body!(),
            k26 = const offset_of!(Lattice, s) + offset_of!(Setup, k26),
            n_rel = const offset_of!(Lattice, job) + offset_of!(ColumnJob, n)
                - (offset_of!(Lattice, s) + offset_of!(Setup, k26) + 8),
            anc = const offset_of!(Lattice, s) + offset_of!(Setup, anchors),
            wt = const offset_of!(Lattice, s) + offset_of!(Setup, weight),
            xs0 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, xstep),
            xs1 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, xstep) + 1,
            ys0 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, ystep),
            ys1 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, ystep) + 1,
            ps = const offset_of!(SinkLocals, post) + offset_of!(Posterior, s),
            sy = const offset_of!(SinkLocals, post) + offset_of!(Posterior, sy),
            mc = const offset_of!(Estimate, min_cost),
            oanc = const offset_of!(Estimate, anchors),
            owt = const offset_of!(Estimate, total_weight),
            ola0 = const offset_of!(Estimate, lattice) + offset_of!((u8, u8), 0),
            ola1 = const offset_of!(Estimate, lattice) + offset_of!((u8, u8), 1),
            oev0 = const offset_of!(Estimate, evaluations),
            oev1 = const offset_of!(Estimate, evaluations) + 1,
            mev0 = const size_of::<Estimate>() + offset_of!(Estimate, evaluations),
            px = const offset_of!(Estimate, pos),
            mpx = const size_of::<Estimate>() + offset_of!(Estimate, pos),
            esize = const size_of::<Estimate>(),
            ce = const 122,
            f8 = const 50,
            mul_hi = sym <AvrTerm as TermKernel>::mul_hi,
            div = sym div_shl_c,
            inout("r25r24") l as *const Lattice => _,
            inout("r23r22") f as *const SinkLocals => _,
            inout("r21r20") out as *mut [Estimate; 2] => _,
            inout("r19r18") (const_cost >> 16) as u16 => _,
            inout("r17r16") const_cost as u16 => _,
            out("r2") _, out("r3") _, out("r4") _, out("r5") _, out("r6") _,
            out("r7") _, out("r8") _, out("r9") _, out("r10") _, out("r11") _, out("r12") _,
            out("r13") _, out("r14") _, out("r15") _, out("X") _, out("Z") _,
        );
    }
}

/// [`loc_core::fixed::portable_sink`]`::<AvrTerm>(fr, obs, sigma, const_cost, out)`, exactly:
/// [`observe`], [`weights`], [`search`] and [`finish`] as one routine, their instruction texts
/// one after the other (each takes its inputs in its registers and leaves nothing the next
/// needs in them), one register save for the four instead of four (≈ 200 bytes of the sink's
/// flash). `fr` in Y for the whole (saved on the stack); `out`, `const_cost` and σ pushed
/// while `observe` runs, popped where `weights` and `finish` take them.
pub fn sink(fr: &mut SinkFrame, obs: &[Obs], sigma: u16, const_cost: u32, out: &mut [Estimate; 2]) {
    let [c0, c1, c2, c3] = const_cost.to_le_bytes();
    fr.f.post.table = exp2_segment_table();
    let frp = &mut *fr as *mut SinkFrame;
    // SAFETY: as for the four routines (each reads and writes its part of `*fr`, `obs` and
    // `*out` at the offsets asserted or given by `offset_of!`, `obs.len() ≤ MAX_ANCHORS` the
    // caller's contract as for the portable one); the glue reads `*fr` through Y (its `k26`;
    // the job, setup, points and posterior addresses from it). The stack: Y and 8 bytes pushed
    // and popped here, the four routines' own use and the calls, which follow the ABI; every
    // register they or this code may change is declared; r1 is zero at the end.
    unsafe {
        asm!(
            "push r28",
            "push r29",
            "movw r28, r16",
            "push r8",
            "push r9",
            "push r10",
            "push r11",
            "push r12",
            "push r13",
            "push r14",
            "push r15",
            observe_body!(),
            // ---- weights(l.s.k26, σ, &f.post.wts) ----
            "pop r21",
            "pop r20",
            "ldd r22, Y+{fk0}",
            "ldd r23, Y+{fk1}",
            "ldd r24, Y+{fk2}",
            "ldd r25, Y+{fk3}",
            "movw r30, r28",
            "adiw r30, {fw}",
            weights_body!(),
            // ---- guess(&l.job) into r19:r18 (subroutine 97); search(l, &f.best, &f.post) ----
            "movw r30, r28",
            "adiw r30, {fj}",
            "rcall 97f",
            "movw r18, r24",
            "movw r24, r28",
            "adiw r24, {fl}",
            "movw r22, r28",
            "movw r20, r28",
            "subi r20, {nfp0}",
            "sbci r21, {nfp1}",
            search_body!(),
            // ---- finish(l, f, const_cost, out) ----
            "pop r19",
            "pop r18",
            "pop r17",
            "pop r16",
            "pop r21",
            "pop r20",
            "movw r24, r28",
            "adiw r24, {fl}",
            "movw r22, r28",
            finish_body!(),
            "pop r29",
            "pop r28",
            "rjmp 98f",
            "97:",
            guess_body!(),
            "ret",
            "96:",
            posterior_body!(),
            "ret",
            "98:",
            // glue
            fj = const offset_of!(SinkFrame, l) + offset_of!(Lattice, job),
            n = const loc_core::MAX_ANCHORS,
            n1 = const loc_core::MAX_ANCHORS + 1,
            fk0 = const offset_of!(SinkFrame, l) + offset_of!(Lattice, s) + offset_of!(Setup, k26),
            fk1 = const offset_of!(SinkFrame, l) + offset_of!(Lattice, s) + offset_of!(Setup, k26) + 1,
            fk2 = const offset_of!(SinkFrame, l) + offset_of!(Lattice, s) + offset_of!(Setup, k26) + 2,
            fk3 = const offset_of!(SinkFrame, l) + offset_of!(Lattice, s) + offset_of!(Setup, k26) + 3,
            fw = const offset_of!(SinkFrame, f) + offset_of!(SinkLocals, post) + offset_of!(Posterior, wts),
            fl = const offset_of!(SinkFrame, l),
            nfp0 = const ((offset_of!(SinkFrame, f) + offset_of!(SinkLocals, post)) as u16).wrapping_neg() & 0xFF,
            nfp1 = const ((offset_of!(SinkFrame, f) + offset_of!(SinkLocals, post)) as u16).wrapping_neg() >> 8,
            // observe
            oz = const offset_of!(Obs, z),
            oz1 = const offset_of!(Obs, z) + 1,
            oz2 = const offset_of!(Obs, z) + 2,
            oz3 = const offset_of!(Obs, z) + 3,
            ox = const offset_of!(Obs, pos) + offset_of!(loc_core::fixed::PointCm, x),
            ox1 = const offset_of!(Obs, pos) + offset_of!(loc_core::fixed::PointCm, x) + 1,
            oy = const offset_of!(Obs, pos) + offset_of!(loc_core::fixed::PointCm, y),
            oy1 = const offset_of!(Obs, pos) + offset_of!(loc_core::fixed::PointCm, y) + 1,
            ow = const offset_of!(Obs, weight),
            size = const size_of::<Obs>(),
            m0 = const loc_core::fixed::LOG2_M2 & 0xFF,
            m1 = const (loc_core::fixed::LOG2_M2 >> 8) & 0xFF,
            m2 = const (loc_core::fixed::LOG2_M2 >> 16) & 0xFF,
            m3 = const (loc_core::fixed::LOG2_M2 >> 24) & 0xFF,
            c0 = const 0x26,
            c1 = const 0xC1,
            c2 = const 0xA8,
            c3 = const 0xC0,
            place = sym <AvrTerm as TermKernel>::place,
            // search
            job = const offset_of!(Lattice, job),
            stride = const offset_of!(Lattice, job) + offset_of!(ColumnJob, stride),
            b0 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, bound),
            b1 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, bound) + 1,
            b2 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, bound) + 2,
            b3 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, bound) + 3,
            sk0 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, skip),
            sk1 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, skip) + 1,
            col = const offset_of!(Lattice, job) + offset_of!(ColumnJob, col),
            mn0 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, min),
            mn1 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, min) + 1,
            mn2 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, min) + 2,
            mn3 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, min) + 3,
            minrow = const offset_of!(Lattice, job) + offset_of!(ColumnJob, min_row),
            ns0 = const (offset_of!(Lattice, sums) as u16).wrapping_neg() & 0xFF,
            ns1 = const (offset_of!(Lattice, sums) as u16).wrapping_neg() >> 8,
            nj0 = const (offset_of!(Lattice, job) as u16).wrapping_neg() & 0xFF,
            nj1 = const (offset_of!(Lattice, job) as u16).wrapping_neg() >> 8,
            mv = sym <AvrTerm as TermKernel>::move_window,
            column = sym <AvrTerm as TermKernel>::column,
            pcol = const offset_of!(Posterior, col),
            pt0 = const offset_of!(Posterior, table),
            pt1 = const offset_of!(Posterior, table) + 1,
            // finish
            k26 = const offset_of!(Lattice, s) + offset_of!(Setup, k26),
            n_rel = const offset_of!(Lattice, job) + offset_of!(ColumnJob, n)
                - (offset_of!(Lattice, s) + offset_of!(Setup, k26) + 8),
            anc = const offset_of!(Lattice, s) + offset_of!(Setup, anchors),
            wt = const offset_of!(Lattice, s) + offset_of!(Setup, weight),
            xs0 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, xstep),
            xs1 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, xstep) + 1,
            ys0 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, ystep),
            ys1 = const offset_of!(Lattice, job) + offset_of!(ColumnJob, ystep) + 1,
            ps = const offset_of!(SinkLocals, post) + offset_of!(Posterior, s),
            sy = const offset_of!(SinkLocals, post) + offset_of!(Posterior, sy),
            mc = const offset_of!(Estimate, min_cost),
            oanc = const offset_of!(Estimate, anchors),
            owt = const offset_of!(Estimate, total_weight),
            ola0 = const offset_of!(Estimate, lattice) + offset_of!((u8, u8), 0),
            ola1 = const offset_of!(Estimate, lattice) + offset_of!((u8, u8), 1),
            oev0 = const offset_of!(Estimate, evaluations),
            oev1 = const offset_of!(Estimate, evaluations) + 1,
            mev0 = const size_of::<Estimate>() + offset_of!(Estimate, evaluations),
            px = const offset_of!(Estimate, pos),
            mpx = const size_of::<Estimate>() + offset_of!(Estimate, pos),
            esize = const size_of::<Estimate>(),
            ce = const 122,
            f8 = const 50,
            // shared
            mul_hi = sym <AvrTerm as TermKernel>::mul_hi,
            div = sym div_shl_c,
            inout("r25r24") &mut fr.l.job as *mut ColumnJob => _,
            inout("r23r22") &mut fr.l.s as *mut Setup => _,
            inout("r21r20") obs.as_ptr() => _,
            inout("r18") obs.len() as u8 => _,
            inout("r17r16") frp => _,
            inout("r15r14") sigma => _,
            inout("r13") c3 => _,
            inout("r12") c2 => _,
            inout("r11") c1 => _,
            inout("r10") c0 => _,
            inout("r9r8") out as *mut [Estimate; 2] => _,
            out("r2") _, out("r3") _, out("r4") _, out("r5") _, out("r6") _, out("r7") _,
            out("r19") _, out("X") _, out("Z") _,
        );
    }
}
