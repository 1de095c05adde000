//! The sink's per-report inputs in AVR assembly: [`AvrFit`]'s [`ReportKernel`].
//!
//! One routine walks a report's bytes: every anchor pair's relayed bytes (both directions)
//! gathered and pushed into `CalStats` with the pair's `x` (the [`AvrFit`] distance and push
//! code, `rcall`ed here: their one copy in the sink), then each anchor's Extended refinement
//! (byte sums in registers, the two rounding divisions by the channel count bit by bit) into
//! `Observations`. It computes exactly [`loc_core::fixed::portable_report_inputs`], which
//! `hoploc-tests` checks in simavr on random reports (`mcu-bench`'s `report-check`).
//!
//! Register plan: the [`Job`] in Y (r29:r28, pushed and restored), the loop counters and the
//! pair's 8 bytes in it (the distance and push code clobber nearly every register); r1 is zero
//! between `mul`s in the pair loop, r2 throughout the observations.

use super::fit::{distance_x_asm, push_asm};
use super::AvrFit;
use core::arch::asm;
use core::mem::{offset_of, size_of};
use loc_core::fixed::{log2_segment_base, CalStats, Obs, Observations, ReportBytes, ReportKernel};

/// What the routine reads through Y (offsets asserted below).
#[repr(C)]
struct Job {
    /// The first position.
    pos: *const u8,
    /// The agent's RSSI bytes (channel by channel).
    rssi: *const u8,
    /// The relayed bytes, null without them.
    relay: *const u8,
    stats: *mut CalStats,
    obs: *mut Observations,
    /// The distance code's log2 table.
    log2: *const u8,
    n: u8,
    c: u8,
    /// The pair loop's anchors.
    i: u8,
    j: u8,
    /// The pair's bytes (`PairBytes`).
    bytes: [u8; 8],
}

const _: () = {
    assert!(offset_of!(Job, pos) == 0);
    assert!(offset_of!(Job, rssi) == 2);
    assert!(offset_of!(Job, relay) == 4);
    assert!(offset_of!(Job, stats) == 6);
    assert!(offset_of!(Job, obs) == 8);
    assert!(offset_of!(Job, log2) == 10);
    assert!(offset_of!(Job, n) == 12);
    assert!(offset_of!(Job, c) == 13);
    assert!(offset_of!(Job, i) == 14);
    assert!(offset_of!(Job, j) == 15);
    assert!(offset_of!(Job, bytes) == 16);
    // What the routine writes: an `Obs` is 9 bytes (pos 0, z 4, weight 8), `len` at 72,
    // `const_cost` at 74.
    assert!(size_of::<Obs>() == 9);
    assert!(offset_of!(Obs, pos) == 0);
    assert!(offset_of!(Obs, z) == 4);
    assert!(offset_of!(Obs, weight) == 8);
    assert!(offset_of!(loc_core::fixed::PointCm, x) == 0);
    assert!(offset_of!(loc_core::fixed::PointCm, y) == 2);
    assert!(size_of::<Observations>() == 78);
};

impl ReportKernel for AvrFit {
    #[inline(never)]
    fn report_inputs(r: &ReportBytes, stats: &mut CalStats, obs: &mut Observations) {
        report_inputs(r, stats, obs)
    }
}

/// [`loc_core::fixed::portable_report_inputs`], exactly; see the module docs.
#[inline(always)]
pub fn report_inputs(r: &ReportBytes, stats: &mut CalStats, obs: &mut Observations) {
    if r.size().is_none() {
        return;
    }
    let (n, c) = (r.anchors, r.channels);
    let pos = r.bytes.as_ptr();
    let rssi = pos.wrapping_add(4 * n as usize);
    let relay = if r.relay {
        rssi.wrapping_add(c as usize * n as usize)
    } else {
        core::ptr::null()
    };
    let mut job = Job {
        pos,
        rssi,
        relay,
        stats,
        obs,
        log2: log2_segment_base(),
        n,
        c,
        i: 0,
        j: 0,
        bytes: [0; 8],
    };
    // SAFETY: `size` checked that `r.bytes` holds the layout (n ≤ 8, c ≤ 4), so every byte read
    // through `pos`, `rssi` and `relay` is within it; the routine writes the `CalStats` and
    // `Observations` (whose offsets are asserted, `len` kept ≤ 8) and the job, reads 6 bytes of
    // the log2 table with `lpm`, pushes and restores Y and otherwise writes only the declared
    // registers, r0, r1 (left at 0), the flags and the stack below SP (its own calls).
    unsafe {
        asm!(
            "push r28",
            "push r29",
            "movw r28, r30",
            // The pairs, with the relay bytes only (without them every byte is 0: no samples).
            "ldd r30, Y+4",
            "ldd r31, Y+5",
            "adiw r30, 0",
            "brne 39f",
            "rjmp 50f",
            "39:",
            "clr r16",
            // i in r16 (Y+14), j in r17 (Y+15)
            "40:",
            "std Y+14, r16",
            "mov r17, r16",
            "41:",
            "inc r17",
            "ldd r18, Y+12",
            "cp r17, r18",
            "brlo 42f",
            "rjmp 48f",
            "42:",
            "std Y+15, r17",
            // per channel n(n − 1) bytes (r20); row (ch, i) from i(n − 1), j's byte at j − 1
            // (r21); row (ch, j) from j(n − 1), i's byte at i (r22)
            "mov r19, r18",
            "dec r19",
            "mul r18, r19",
            "mov r20, r0",
            "mul r16, r19",
            "mov r21, r0",
            "add r21, r17",
            "dec r21",
            "mul r17, r19",
            "mov r22, r0",
            "add r22, r16",
            "clr r1",
            "ldd r23, Y+13",
            "movw r26, r28",
            "adiw r26, 16",
            "ldd r30, Y+4",
            "ldd r31, Y+5",
            "add r30, r21",
            "adc r31, r1",
            "rcall 62f",
            "ldd r30, Y+4",
            "ldd r31, Y+5",
            "add r30, r22",
            "adc r31, r1",
            "rcall 62f",
            // x of positions i (r19:r18, r23:r22) and j (r21:r20, r25:r24)
            "lsl r16",
            "lsl r16",
            "ldd r30, Y+0",
            "ldd r31, Y+1",
            "add r30, r16",
            "adc r31, r1",
            "ld r18, Z",
            "ldd r19, Z+1",
            "ldd r22, Z+2",
            "ldd r23, Z+3",
            "lsl r17",
            "lsl r17",
            "ldd r30, Y+0",
            "ldd r31, Y+1",
            "add r30, r17",
            "adc r31, r1",
            "ld r20, Z",
            "ldd r21, Z+1",
            "ldd r24, Z+2",
            "ldd r25, Z+3",
            "ldd r30, Y+10",
            "ldd r31, Y+11",
            "rcall 60f",
            // coincident: no samples
            "tst r17",
            "breq 47f",
            "movw r20, r22",
            "movw r22, r24",
            "ldd r30, Y+6",
            "ldd r31, Y+7",
            "movw r26, r28",
            "adiw r26, 16",
            "rcall 61f",
            "47:",
            "ldd r16, Y+14",
            "ldd r17, Y+15",
            "rjmp 41b",
            "48:",
            "inc r16",
            "cp r16, r18",
            "brsh 50f",
            "rjmp 40b",
            // The observations: anchor i in r16, n r18, channels left r19, Σb r21:r20,
            // Σb² r24:r22, count r25; r2 zero.
            "50:",
            "clr r2",
            "clr r16",
            "51:",
            "ldd r18, Y+12",
            "cp r16, r18",
            "brlo 52f",
            "rjmp 59f",
            "52:",
            "ldd r30, Y+2",
            "ldd r31, Y+3",
            "add r30, r16",
            "adc r31, r2",
            "ldd r19, Y+13",
            "clr r20",
            "clr r21",
            "clr r22",
            "clr r23",
            "clr r24",
            "clr r25",
            "53:",
            "subi r19, 1",
            "brcs 55f",
            "ld r17, Z",
            "add r30, r18",
            "adc r31, r2",
            "tst r17",
            "breq 53b",
            "inc r25",
            "add r20, r17",
            "adc r21, r2",
            "mul r17, r17",
            "add r22, r0",
            "adc r23, r1",
            "adc r24, r2",
            "rjmp 53b",
            // none heard: no observation
            "55:",
            "tst r25",
            "brne 56f",
            "rjmp 58f",
            // the spread's numerator count·Σb² − (Σb)² (below 2^24) in r12:r10
            "56:",
            "clr r10",
            "clr r11",
            "clr r12",
            "mov r17, r25",
            "57:",
            "add r10, r22",
            "adc r11, r23",
            "adc r12, r24",
            "dec r17",
            "brne 57b",
            "mul r20, r20",
            "sub r10, r0",
            "sbc r11, r1",
            "sbc r12, r2",
            "mul r20, r21",
            "sub r11, r0",
            "sbc r12, r1",
            "sub r11, r0",
            "sbc r12, r1",
            "mul r21, r21",
            "sub r12, r0",
            // Σb in r15:r14, count in r13; spread = (num << 8) / count, rounded
            "movw r14, r20",
            "mov r13, r25",
            "clr r22",
            "mov r23, r10",
            "mov r24, r11",
            "mov r25, r12",
            "mov r19, r13",
            "rcall 63f",
            // const_cost (obs + 74) += spread, saturating
            "ldd r30, Y+8",
            "ldd r31, Y+9",
            "subi r30, 0xB6",
            "sbci r31, 0xFF",
            "ld r0, Z",
            "add r22, r0",
            "ldd r0, Z+1",
            "adc r23, r0",
            "ldd r0, Z+2",
            "adc r24, r0",
            "ldd r0, Z+3",
            "adc r25, r0",
            "brcc 64f",
            "ldi r22, 0xFF",
            "ldi r23, 0xFF",
            "movw r24, r22",
            "64:",
            "st Z, r22",
            "std Z+1, r23",
            "std Z+2, r24",
            "std Z+3, r25",
            // z = −((Σb << 16) / count, rounded)
            "clr r22",
            "clr r23",
            "movw r24, r14",
            "mov r19, r13",
            "rcall 63f",
            "com r25",
            "com r24",
            "com r23",
            "neg r22",
            "sbci r23, 0xFF",
            "sbci r24, 0xFF",
            "sbci r25, 0xFF",
            // pushed if len (obs + 72) < 8
            "sbiw r30, 2",
            "ld r26, Z",
            "ldd r27, Z+1",
            "cpi r26, 8",
            "cpc r27, r2",
            "brsh 58f",
            "adiw r26, 1",
            "st Z, r26",
            "std Z+1, r27",
            // the slot at obs + 9·len = obs + 9·(len + 1) − 9
            "ldi r17, 9",
            "mul r26, r17",
            "ldd r30, Y+8",
            "ldd r31, Y+9",
            "add r30, r0",
            "adc r31, r1",
            "sbiw r30, 9",
            "ldd r26, Y+0",
            "ldd r27, Y+1",
            "mov r17, r16",
            "lsl r17",
            "lsl r17",
            "add r26, r17",
            "adc r27, r2",
            "ldi r17, 4",
            "65:",
            "ld r0, X+",
            "st Z+, r0",
            "dec r17",
            "brne 65b",
            "st Z+, r22",
            "st Z+, r23",
            "st Z+, r24",
            "st Z+, r25",
            "st Z, r13",
            "58:",
            "inc r16",
            "rjmp 51b",
            "59:",
            "pop r29",
            "pop r28",
            "clr r1",
            "rjmp 99f",
            // x of the pair (`distance_x`)
            "60:",
            distance_x_asm!(),
            "ret",
            // the pair's samples into the sums (`push`)
            "61:",
            push_asm!(),
            "ret",
            // 4 bytes to X+ from Z, stride r20, the first r23 (c) of them read, the rest 0
            "62:",
            "ldi r24, 4",
            "mov r25, r23",
            "68:",
            "clr r18",
            "tst r25",
            "breq 69f",
            "dec r25",
            "ld r18, Z",
            "add r30, r20",
            "adc r31, r1",
            "69:",
            "st X+, r18",
            "dec r24",
            "brne 68b",
            "ret",
            // r25:r22 = (r25:r22 + r19/2) / r19 (r19 in 1..=4; r2 zero; r0, r18 clobbered)
            "63:",
            "mov r0, r19",
            "lsr r0",
            "add r22, r0",
            "adc r23, r2",
            "adc r24, r2",
            "adc r25, r2",
            "clr r0",
            "ldi r18, 32",
            "66:",
            "lsl r22",
            "rol r23",
            "rol r24",
            "rol r25",
            "rol r0",
            "cp r0, r19",
            "brlo 67f",
            "sub r0, r19",
            "inc r22",
            "67:",
            "dec r18",
            "brne 66b",
            "ret",
            "99:",
            inout("Z") &mut job as *mut Job => _,
            out("X") _,
            out("r2") _, out("r3") _, out("r4") _, out("r5") _, out("r6") _, out("r7") _,
            out("r8") _, out("r9") _, out("r10") _, out("r11") _, out("r12") _,
            out("r13") _, out("r14") _, out("r15") _, out("r16") _, out("r17") _,
            out("r18") _, out("r19") _, out("r20") _, out("r21") _, out("r22") _,
            out("r23") _, out("r24") _, out("r25") _,
        );
    }
}
