//! [`Avr`]: the column kernel in AVR assembly, for the ATmega328P.
//!
//! It computes exactly [`portable_column`](super::portable_column) (the contract in the
//! [parent module](super)); LLVM's AVR code for that loop composes its 8 × 8 products into 16-
//! and 32-bit values with many moves and spills, and this hand-scheduled version keeps a whole
//! column — rows, anchors, the early exit at the bound — in registers. Every offset, size and
//! limit it uses comes from the Rust definitions through `const` operands, and the log2 table
//! through a `sym` operand: nothing is copied by hand. `mcu-bench`'s `checkasm` firmware holds it
//! to the portable column in simavr, on tables of edge cases and random jobs.
//!
//! Register plan. In: `sums` in X (r27:r26), `job` in Z (r31:r30), `rows` in r20. During the
//! loops: X walks the sums, Y (r29:r28, saved on the stack and restored) holds the job, Z the
//! current anchor; r2 is zero; r21:r18 is the room left below the bound (the row's sum is the
//! bound less the room); r22 the row's fine offset; r23 the anchors left in the row; `d²` and
//! then the term in r15:r12 with the 33rd bit of `d²` in the T flag; r3–r11, r16, r17 scratch;
//! r0/r1 for `mul` (r1 cleared at the end, as the ABI requires); r25:r24 keep Z while the log2
//! table is read. The rows left and the anchors in use live in the job's `scratch` bytes.
//!
//! The routine is one `asm!` block in a function that is neither generic nor inlined, so its
//! text is emitted exactly once and its `.L` labels are unique (a second copy would be an
//! assembler error, not a silent one). It is not module-level assembly (`global_asm!`, naked
//! functions): in a library crate built as LTO bitcode, LLVM parses module-level AVR assembly
//! without the CPU's features and rejects `push`, `mul` and `movw`.

use super::{AnchorTerm, ColumnJob, ColumnKernel, SQ_SAT, U_SAT};
use crate::fixed::tables::{LOG2_SEGMENTS, LOG2_SEG_BYTES, LOG2_SEG_FLASH};
use crate::MAX_ANCHORS;
use core::mem::{offset_of, size_of};

/// The AVR assembly column kernel.
#[derive(Clone, Copy, Debug, Default)]
pub struct Avr;

impl ColumnKernel for Avr {
    #[inline(always)]
    fn column(sums: &mut [u32], job: &mut ColumnJob) {
        column(sums, job)
    }
}

// What the instruction forms need: `ldd`/`std` reach 63 bytes from Y or Z, `adiw` adds at most
// 63; the saturation tests look at the top byte only.
const _: () = {
    assert!(offset_of!(ColumnJob, anchors) <= 63);
    assert!(offset_of!(ColumnJob, scratch) < 63);
    assert!(offset_of!(ColumnJob, min) + 3 <= 63);
    assert!(offset_of!(ColumnJob, bound) + 3 <= 63);
    assert!(size_of::<AnchorTerm>() <= 63);
    assert!(offset_of!(AnchorTerm, rho) + 3 <= 63);
    assert!(offset_of!(AnchorTerm, lclamp) + 3 <= 63);
    assert!(U_SAT.trailing_zeros() >= 24);
    assert!(SQ_SAT == 0x3FFF_FFFF);
    assert!(MAX_ANCHORS < 255);
    // The normalised d²'s top byte is 64 + the segment index (`.Lsegment`).
    assert!(LOG2_SEGMENTS == 64);
};

/// `v = r3:r17:r16 + the 24-bit offset at Z + $field`, then `|v|` rounded to `2^shift` units
/// (the anchor's `shift`, half up, by the `.Lround_shift` subroutine) and squared into r15:r12:
/// a column's `dx²` and a row's `dy²`, the same steps as `offset_square`.
macro_rules! offset_square {
    ($field:literal, $positive:literal) => {
        concat!(
            "ldd r4, Z+{",
            $field,
            "}\n",
            "add r16, r4\n",
            "ldd r4, Z+{",
            $field,
            "}+1\n",
            "adc r17, r4\n",
            "ldd r4, Z+{",
            $field,
            "}+2\n",
            "adc r3, r4\n",
            "sbrs r3, 7\n",
            "rjmp ",
            $positive,
            "\n",
            "com r3\n",
            "com r17\n",
            "neg r16\n",
            "sbci r17, 0xFF\n",
            // r3 + 1 − borrow (r3 takes no immediate).
            "sbc r3, r2\n",
            "inc r3\n",
            $positive,
            ":\n",
            "ldd r5, Z+{AT_SHIFT}\n",
            "cpse r5, r2\n",
            "rcall .Lround_shift\n",
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

/// The column of `job` into `sums` (see the module docs).
#[inline(never)]
#[allow(named_asm_labels)]
fn column(sums: &mut [u32], job: &mut ColumnJob) {
    let rows = sums.len().min(255) as u8;
    // SAFETY: the routine writes `rows` sums from `sums`' start (`rows ≤ sums.len()`), reads and
    // writes only the fields of `*job` (the header, and the first `min(n, MAX_ANCHORS)` anchors,
    // at offsets from `offset_of!`), reads the log2 table in flash with `lpm` at a segment index
    // below 64, and writes only the registers declared below, r0, r1 (left at 0), the flags and
    // Y (saved on the stack and restored).
    unsafe {
        core::arch::asm!(
        "push r28",
        "push r29",
        "clr r2",
        "movw r28, r30",
        // ---- no minimum yet ----
        "ldi r16, 0xFF",
        "std Z+{JOB_MIN}, r16",
        "std Z+{JOB_MIN}+1, r16",
        "std Z+{JOB_MIN}+2, r16",
        "std Z+{JOB_MIN}+3, r16",
        "std Z+{JOB_MIN_ROW}, r2",
        // ---- the rows left and min(n, MAX_ANCHORS) into the scratch bytes ----
        "std Z+{JOB_ROWS_LEFT}, r20",
        "ldd r23, Z+{JOB_N}",
        "cpi r23, {MAX_ANCHORS}+1",
        "brlo .Ln_ok",
        "ldi r23, {MAX_ANCHORS}",
        ".Ln_ok:",
        "std Z+{JOB_N_USED}, r23",
        "tst r23",
        "breq .Lrows",
        // ---- dx² of every anchor: dx = dx0 + col·xstep (24 bits) ----
        "ldd r22, Z+{JOB_COL}",
        "ldd r24, Z+{JOB_XSTEP}",
        "ldd r25, Z+{JOB_XSTEP}+1",
        "adiw r30, {JOB_ANCHORS}",
        ".Ldx_anchor:",
        "mul r22, r24",
        "movw r16, r0",
        "mul r22, r25",
        "add r17, r0",
        "clr r3",
        "adc r3, r1",
        offset_square!("AT_DX0", ".Ldx_positive"),
        "std Z+{AT_DX2}, r12",
        "std Z+{AT_DX2}+1, r13",
        "std Z+{AT_DX2}+2, r14",
        "std Z+{AT_DX2}+3, r15",
        "adiw r30, {AT_SIZE}",
        "dec r23",
        "brne .Ldx_anchor",
        ".Lrows:",
        "ldd r16, Y+{JOB_ROWS_LEFT}",
        "tst r16",
        "brne .Lfirst_row",
        "rjmp .Ldone",
        ".Lfirst_row:",
        "clr r22",
        // ---- the row at fine offset r22: skipped (the next bit of `skip`) → u32::MAX; else the
        // room is the bound ----
        ".Lrow:",
        "movw r30, r28",
        "ldd r16, Z+{JOB_SKIP}",
        "ldd r17, Z+{JOB_SKIP}+1",
        "lsr r17",
        "ror r16",
        "std Z+{JOB_SKIP}, r16",
        "std Z+{JOB_SKIP}+1, r17",
        "brcc .Levaluate",
        "ldi r16, 0xFF",
        "st X+, r16",
        "st X+, r16",
        "st X+, r16",
        "st X+, r16",
        "rjmp .Lnext_row",
        ".Levaluate:",
        "ldd r18, Z+{JOB_BOUND}",
        "ldd r19, Z+{JOB_BOUND}+1",
        "ldd r20, Z+{JOB_BOUND}+2",
        "ldd r21, Z+{JOB_BOUND}+3",
        "ldd r23, Z+{JOB_N_USED}",
        "adiw r30, {JOB_ANCHORS}",
        "tst r23",
        "brne .Lanchor",
        // No anchors: the sum is 0, completed if below the bound.
        "cp r18, r2",
        "cpc r19, r2",
        "cpc r20, r2",
        "cpc r21, r2",
        "breq .Lzero_reached",
        "rjmp .Lcompleted",
        ".Lzero_reached:",
        "rjmp .Lreached",
        // ---- the anchor at Z: dy = dy0 + r22·ystep (24 bits) ----
        ".Lanchor:",
        "ldd r16, Y+{JOB_YSTEP}",
        "mul r22, r16",
        "movw r16, r0",
        "ldd r3, Y+{JOB_YSTEP}+1",
        "mul r22, r3",
        "add r17, r0",
        "clr r3",
        "adc r3, r1",
        offset_square!("AT_DY0", ".Ldy_positive"),
        // ---- d² = dx² + dy² in T:r15:r12 ----
        "ldd r16, Z+{AT_DX2}",
        "add r12, r16",
        "ldd r16, Z+{AT_DX2}+1",
        "adc r13, r16",
        "ldd r16, Z+{AT_DX2}+2",
        "adc r14, r16",
        "ldd r16, Z+{AT_DX2}+3",
        "adc r15, r16",
        "clt",
        "brcc .Lnormalise",
        "set",
        // ---- normalise d² to [2^31, 2^32) in r15:r12, exponent e in r16 ----
        ".Lnormalise:",
        "brtc .Lnorm_32",
        // 33 bits: (2^32 + lo) >> 1, e = 32.
        "sec",
        "ror r15",
        "ror r14",
        "ror r13",
        "ror r12",
        "ldi r16, 32",
        "rjmp .Lsegment",
        ".Lnorm_32:",
        "ldi r16, 31",
        "cp r14, r2",
        "cpc r15, r2",
        "brne .Lnorm_top_word",
        "cp r12, r2",
        "cpc r13, r2",
        "brne .Lnorm_low_word",
        // d² = 0: log2 is taken as 0.
        "clr r3",
        "clr r4",
        "clr r5",
        "clr r16",
        "rjmp .Lclamp",
        ".Lnorm_low_word:",
        "mov r15, r13",
        "mov r14, r12",
        "clr r13",
        "clr r12",
        "subi r16, 16",
        ".Lnorm_top_word:",
        "tst r15",
        "brne .Lnorm_bits",
        "mov r15, r14",
        "mov r14, r13",
        "mov r13, r12",
        "clr r12",
        "subi r16, 8",
        ".Lnorm_bits:",
        "sbrc r15, 7",
        "rjmp .Lsegment",
        ".Lnorm_shift:",
        "lsl r12",
        "rol r13",
        "rol r14",
        "rol r15",
        "dec r16",
        "sbrs r15, 7",
        "rjmp .Lnorm_shift",
        // ---- segment k = top 6 bits below the leading one; t = the 16 bits below them (r14:r13
        // after the shift); r15 = 64 + k ----
        ".Lsegment:",
        "lsr r15",
        "ror r14",
        "ror r13",
        "movw r24, r30",
        "ldi r30, lo8({LOG2_SEG} - {SEG_BYTES}*{LOG2_SEGMENTS})",
        "ldi r31, hi8({LOG2_SEG} - {SEG_BYTES}*{LOG2_SEGMENTS})",
        "ldi r17, {SEG_BYTES}",
        "mul r15, r17",
        "add r30, r0",
        "adc r31, r1",
        // c0 in r5:r4:r3, c1 in r7:r6, c2 in r8
        "lpm r3, Z+",
        "lpm r4, Z+",
        "lpm r5, Z+",
        "lpm r6, Z+",
        "lpm r7, Z+",
        "lpm r8, Z",
        "movw r30, r24",
        // ---- log2 d² = (e << 20) + c0 + t·(c1 − t·c2), Q.20, into r16:r5:r4:r3 ----
        // q = (t1·c2 + (t0·c2 >> 8)) >> 8; i = c1 − q
        "mul r13, r8",
        "mov r17, r1",
        "mul r14, r8",
        "add r0, r17",
        "mov r17, r1",
        "adc r17, r2",
        "sub r6, r17",
        "sbc r7, r2",
        // mid = (t0·i0 >> 8) + t1·i0 + t0·i1 in r11:r9
        "mul r13, r6",
        "mov r9, r1",
        "clr r10",
        "clr r11",
        "mul r14, r6",
        "add r9, r0",
        "adc r10, r1",
        "adc r11, r2",
        "mul r13, r7",
        "add r9, r0",
        "adc r10, r1",
        "adc r11, r2",
        "mul r14, r7",
        "add r3, r0",
        "adc r4, r1",
        "adc r5, r2",
        "add r3, r10",
        "adc r4, r11",
        "adc r5, r2",
        "swap r16",
        "mov r17, r16",
        "andi r17, 0xF0",
        "andi r16, 0x0F",
        "add r5, r17",
        "adc r16, r2",
        // ---- l = max(log2 d², clamp), signed ----
        ".Lclamp:",
        "ldd r6, Z+{AT_LCLAMP}",
        "ldd r7, Z+{AT_LCLAMP}+1",
        "ldd r8, Z+{AT_LCLAMP}+2",
        "ldd r9, Z+{AT_LCLAMP}+3",
        "cp r3, r6",
        "cpc r4, r7",
        "cpc r5, r8",
        "cpc r16, r9",
        "brge .Lresidual",
        "mov r3, r6",
        "mov r4, r7",
        "mov r5, r8",
        "mov r16, r9",
        // ---- u = |ρ + l| ----
        ".Lresidual:",
        "ldd r6, Z+{AT_RHO}",
        "ldd r7, Z+{AT_RHO}+1",
        "ldd r8, Z+{AT_RHO}+2",
        "ldd r9, Z+{AT_RHO}+3",
        "add r3, r6",
        "adc r4, r7",
        "adc r5, r8",
        "adc r16, r9",
        "sbrs r16, 7",
        "rjmp .Lsaturation",
        "com r3",
        "com r4",
        "com r5",
        "com r16",
        "sec",
        "adc r3, r2",
        "adc r4, r2",
        "adc r5, r2",
        "adc r16, r2",
        // ---- |u| ≥ U_SAT: the saturated term ----
        ".Lsaturation:",
        "cpi r16, {U_SAT_TOP}",
        "brlo .Lsquare",
        "ldi r16, {SQ_SAT_LOW}",
        "mov r12, r16",
        "mov r13, r16",
        "mov r14, r16",
        "ldi r16, {SQ_SAT_TOP}",
        "mov r15, r16",
        "rjmp .Lweigh",
        // ---- v = |u| >> 2 (r5:r4:r3); term = v² >> 16 from five products ----
        ".Lsquare:",
        "lsr r16",
        "ror r5",
        "ror r4",
        "ror r3",
        "lsr r16",
        "ror r5",
        "ror r4",
        "ror r3",
        // v2² << 16 + v1²
        "mul r5, r5",
        "mov r14, r0",
        "mov r15, r1",
        "mul r4, r4",
        "mov r12, r0",
        "mov r13, r1",
        // + 2·v1·v2 << 8
        "mul r4, r5",
        "clr r17",
        "lsl r0",
        "rol r1",
        "rol r17",
        "add r13, r0",
        "adc r14, r1",
        "adc r15, r17",
        // + 2·v0·v2
        "mul r3, r5",
        "clr r17",
        "lsl r0",
        "rol r1",
        "rol r17",
        "add r12, r0",
        "adc r13, r1",
        "adc r14, r17",
        "adc r15, r2",
        // + (2·v0·v1) >> 8
        "mul r3, r4",
        "clr r17",
        "lsl r0",
        "rol r1",
        "rol r17",
        "add r12, r1",
        "adc r13, r17",
        "adc r14, r2",
        "adc r15, r2",
        // ---- room −= w·term, a subtraction per unit of weight; at or below 0 the row has
        // reached the bound ----
        ".Lweigh:",
        "ldd r17, Z+{AT_W}",
        ".Lsubtract:",
        "sub r18, r12",
        "sbc r19, r13",
        "sbc r20, r14",
        "sbc r21, r15",
        "brcs .Lreached",
        "breq .Lreached",
        "dec r17",
        "brne .Lsubtract",
        "adiw r30, {AT_SIZE}",
        "dec r23",
        "breq .Lcompleted",
        "rjmp .Lanchor",
        // ---- every anchor added: sum = bound − room ----
        ".Lcompleted:",
        "movw r30, r28",
        "ldd r16, Z+{JOB_BOUND}",
        "sub r16, r18",
        "mov r18, r16",
        "ldd r16, Z+{JOB_BOUND}+1",
        "sbc r16, r19",
        "mov r19, r16",
        "ldd r16, Z+{JOB_BOUND}+2",
        "sbc r16, r20",
        "mov r20, r16",
        "ldd r16, Z+{JOB_BOUND}+3",
        "sbc r16, r21",
        "mov r21, r16",
        // ---- the column's first smallest completed sum ----
        "ldd r16, Z+{JOB_MIN}",
        "cp r18, r16",
        "ldd r16, Z+{JOB_MIN}+1",
        "cpc r19, r16",
        "ldd r16, Z+{JOB_MIN}+2",
        "cpc r20, r16",
        "ldd r16, Z+{JOB_MIN}+3",
        "cpc r21, r16",
        "brsh .Lstore",
        "std Z+{JOB_MIN}, r18",
        "std Z+{JOB_MIN}+1, r19",
        "std Z+{JOB_MIN}+2, r20",
        "std Z+{JOB_MIN}+3, r21",
        "std Z+{JOB_MIN_ROW}, r22",
        "rjmp .Lstore",
        // ---- reached: the row is set to the bound ----
        ".Lreached:",
        "movw r30, r28",
        "ldd r18, Z+{JOB_BOUND}",
        "ldd r19, Z+{JOB_BOUND}+1",
        "ldd r20, Z+{JOB_BOUND}+2",
        "ldd r21, Z+{JOB_BOUND}+3",
        ".Lstore:",
        "st X+, r18",
        "st X+, r19",
        "st X+, r20",
        "st X+, r21",
        // ---- next row ----
        ".Lnext_row:",
        "ldd r16, Z+{JOB_STRIDE}",
        "add r22, r16",
        "ldd r16, Z+{JOB_ROWS_LEFT}",
        "dec r16",
        "std Z+{JOB_ROWS_LEFT}, r16",
        "breq .Ldone",
        "rjmp .Lrow",
        ".Ldone:",
        "pop r29",
        "pop r28",
        "clr r1",
        "rjmp .Lend",
        // ---- r3:r17:r16 >> r5 (≥ 1), rounded half up by the last bit shifted out ----
        ".Lround_shift:",
        "lsr r3",
        "ror r17",
        "ror r16",
        "dec r5",
        "brne .Lround_shift",
        "adc r16, r2",
        "adc r17, r2",
        "ret",
        ".Lend:",
        JOB_BOUND = const offset_of!(ColumnJob, bound),
        JOB_N = const offset_of!(ColumnJob, n),
        JOB_SKIP = const offset_of!(ColumnJob, skip),
        JOB_COL = const offset_of!(ColumnJob, col),
        JOB_STRIDE = const offset_of!(ColumnJob, stride),
        JOB_XSTEP = const offset_of!(ColumnJob, xstep),
        JOB_YSTEP = const offset_of!(ColumnJob, ystep),
        JOB_MIN = const offset_of!(ColumnJob, min),
        JOB_MIN_ROW = const offset_of!(ColumnJob, min_row),
        JOB_ROWS_LEFT = const offset_of!(ColumnJob, scratch),
        JOB_N_USED = const offset_of!(ColumnJob, scratch) + 1,
        JOB_ANCHORS = const offset_of!(ColumnJob, anchors),
        AT_DX2 = const offset_of!(AnchorTerm, dx2),
        AT_DX0 = const offset_of!(AnchorTerm, dx0),
        AT_DY0 = const offset_of!(AnchorTerm, dy0),
        AT_LCLAMP = const offset_of!(AnchorTerm, lclamp),
        AT_RHO = const offset_of!(AnchorTerm, rho),
        AT_W = const offset_of!(AnchorTerm, w),
        AT_SHIFT = const offset_of!(AnchorTerm, shift),
        AT_SIZE = const size_of::<AnchorTerm>(),
        MAX_ANCHORS = const MAX_ANCHORS,
        U_SAT_TOP = const U_SAT >> 24,
        SQ_SAT_LOW = const SQ_SAT & 0xFF,
        SQ_SAT_TOP = const SQ_SAT >> 24,
        SEG_BYTES = const LOG2_SEG_BYTES,
        LOG2_SEGMENTS = const LOG2_SEGMENTS,
        LOG2_SEG = sym LOG2_SEG_FLASH,
        inout("X") sums.as_mut_ptr() => _,
        inout("Z") job as *mut ColumnJob => _,
        inout("r20") rows => _,
        out("r2") _, out("r3") _, out("r4") _, out("r5") _, out("r6") _, out("r7") _,
        out("r8") _, out("r9") _, out("r10") _, out("r11") _, out("r12") _, out("r13") _,
        out("r14") _, out("r15") _, out("r16") _, out("r17") _, out("r18") _, out("r19") _,
        out("r21") _, out("r22") _, out("r23") _, out("r24") _, out("r25") _,
            );
    }
}
