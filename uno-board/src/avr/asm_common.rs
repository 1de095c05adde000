//! Assembly text shared by several `asm!` routines (inlined where used: `asm!` blocks cannot
//! share local subroutines, see `cost_term`), so each sequence is written once.

/// The log2 table's segment `k` (r15 = 64 + k) for [`log2_interpolate_asm`]: `Z` (the table's
/// base less 384 on entry) to its 6-byte row, `c0` into r5:r4:r3, `c1` into r7:r6, `c2` into r8
/// (clobbers r0, r1, r17, Z).
macro_rules! log2_segment_asm {
    () => {
        concat!(
            "ldi r17, 6\n",
            "mul r15, r17\n",
            "add r30, r0\n",
            "adc r31, r1\n",
            "lpm r3, Z+\n",
            "lpm r4, Z+\n",
            "lpm r5, Z+\n",
            "lpm r6, Z+\n",
            "lpm r7, Z+\n",
            "lpm r8, Z\n",
        )
    };
}

/// log2 of a normalised `n` from its table segment (quadratic): with the segment's `c0`
/// (r5:r4:r3), `c1` (r7:r6) and `c2` (r8), the position in the segment `t` (r14:r13, a 16-bit
/// fraction) and the exponent `e` (r16), `(e << 20) + c0 + t·(c1 − t·c2)` in Q.20 into
/// r16:r5:r4:r3 (r2 = 0; clobbers r0, r1, r6, r7, r9–r11, r17). Used by the column kernel
/// (`cost_term`) and the pair distance (`fit`): the same log as `loc_core::fixed::log2_u33`.
macro_rules! log2_interpolate_asm {
    () => {
        concat!(
            // q = (t1·c2 + (t0·c2 >> 8)) >> 8; i = c1 − q
            "mul r13, r8\n",
            "mov r17, r1\n",
            "mul r14, r8\n",
            "add r0, r17\n",
            "mov r17, r1\n",
            "adc r17, r2\n",
            "sub r6, r17\n",
            "sbc r7, r2\n",
            // mid = (t0·i0 >> 8) + t1·i0 + t0·i1 in r11:r9
            "mul r13, r6\n",
            "mov r9, r1\n",
            "clr r10\n",
            "clr r11\n",
            "mul r14, r6\n",
            "add r9, r0\n",
            "adc r10, r1\n",
            "adc r11, r2\n",
            "mul r13, r7\n",
            "add r9, r0\n",
            "adc r10, r1\n",
            "adc r11, r2\n",
            // log2 d² = (e << 20) + c0 + t1·i1 + (mid >> 8), Q.20, in r16:r5:r4:r3
            "mul r14, r7\n",
            "add r3, r0\n",
            "adc r4, r1\n",
            "adc r5, r2\n",
            "add r3, r10\n",
            "adc r4, r11\n",
            "adc r5, r2\n",
            "swap r16\n",
            "mov r17, r16\n",
            "andi r17, 0xF0\n",
            "andi r16, 0x0F\n",
            "add r5, r17\n",
            "adc r16, r2\n",
        )
    };
}

/// r25:r22 = r19:r18 × r21:r20, unsigned, inputs kept (r2 = 0; clobbers r0, r1), then `ret`:
/// the body of a local 16 × 16 → 32-bit multiply subroutine (`rcall`ed within one `asm!` block).
macro_rules! mul16_ret_asm {
    () => {
        concat!(
            "mul r18, r20\n",
            "movw r22, r0\n",
            "mul r19, r21\n",
            "movw r24, r0\n",
            "mul r18, r21\n",
            "add r23, r0\n",
            "adc r24, r1\n",
            "adc r25, r2\n",
            "mul r19, r20\n",
            "add r23, r0\n",
            "adc r24, r1\n",
            "adc r25, r2\n",
            "ret\n",
        )
    };
}
