//! Constant tables of the fixed-point path (592 bytes in all) and their accessors.
//!
//! On AVR the tables live in flash (`avr-progmem`: read with `lpm`, never copied to SRAM); on
//! every other target they are plain statics. The accessors are the only way the rest of
//! [`crate::fixed`] reads them, so both builds run the same arithmetic on the same numbers.
//!
//! | table | entries | bytes | content |
//! |---|---|---|---|
//! | `LOG2_SEG` | 64 × 6 `u8` | 384 | `log2(1 + (k + t)/64)`, `t ∈ [0, 1)`: a quadratic `c0 + c1·t − c2·t²` per segment (Chebyshev-node interpolant), `c0` (3 bytes), `c1` (2 bytes), `c2` (1 byte), all Q.20, little endian |
//! | `EXP2_SEG` | 32 × 2 `u16` | 128 | `2^(−k/32)` in Q.15 and the difference to the next entry |
//! | `DECIBEL` | 10 `u32` | 40 | `10^(−k/10)`, `k = 0…9`, in Q.31 |
//! | `DECADE` | 10 `u32` | 40 | `10^(−q)`, `q = 0…9`, in Q.31 |
//!
//! `tests::tables_match_their_definitions` recomputes every entry in f64 (host only).

/// Segments of [`log2_seg`].
pub(crate) const LOG2_SEGMENTS: usize = 64;
/// Bytes per segment of [`log2_seg`]: `c0` (3), `c1` (2), `c2` (1).
pub(crate) const LOG2_SEG_BYTES: usize = 6;

const LOG2_SEG_DATA: [[u8; LOG2_SEG_BYTES]; LOG2_SEGMENTS] = [
    [0, 0, 0, 84, 92, 182],
    [159, 91, 0, 232, 90, 176],
    [215, 181, 0, 136, 89, 171],
    [180, 14, 1, 50, 88, 166],
    [64, 102, 1, 230, 86, 161],
    [133, 188, 1, 163, 85, 157],
    [140, 17, 2, 106, 84, 152],
    [94, 101, 2, 58, 83, 148],
    [4, 184, 2, 18, 82, 144],
    [134, 9, 3, 242, 80, 140],
    [236, 89, 3, 218, 79, 136],
    [62, 169, 3, 202, 78, 133],
    [131, 247, 3, 192, 77, 129],
    [194, 68, 4, 190, 76, 126],
    [2, 145, 4, 194, 75, 123],
    [74, 220, 4, 204, 74, 120],
    [159, 38, 5, 221, 73, 117],
    [7, 112, 5, 244, 72, 114],
    [137, 184, 5, 16, 72, 111],
    [42, 0, 6, 50, 71, 108],
    [239, 70, 6, 89, 70, 106],
    [222, 140, 6, 133, 69, 103],
    [251, 209, 6, 182, 68, 101],
    [76, 22, 7, 236, 67, 99],
    [213, 89, 7, 38, 67, 97],
    [155, 156, 7, 101, 66, 94],
    [162, 222, 7, 168, 65, 92],
    [238, 31, 8, 240, 64, 90],
    [131, 96, 8, 59, 64, 88],
    [101, 160, 8, 138, 63, 87],
    [153, 223, 8, 221, 62, 85],
    [33, 30, 9, 52, 62, 83],
    [2, 92, 9, 142, 61, 81],
    [63, 153, 9, 235, 60, 80],
    [218, 213, 9, 76, 60, 78],
    [217, 17, 10, 176, 59, 76],
    [61, 77, 10, 23, 59, 75],
    [9, 136, 10, 130, 58, 73],
    [65, 194, 10, 239, 57, 72],
    [232, 251, 10, 95, 57, 71],
    [1, 53, 11, 210, 56, 69],
    [141, 109, 11, 71, 56, 68],
    [144, 165, 11, 191, 55, 67],
    [13, 221, 11, 58, 55, 65],
    [5, 20, 12, 183, 54, 64],
    [124, 74, 12, 54, 54, 63],
    [115, 128, 12, 184, 53, 62],
    [238, 181, 12, 60, 53, 61],
    [237, 234, 12, 195, 52, 60],
    [116, 31, 13, 75, 52, 59],
    [133, 83, 13, 214, 51, 58],
    [33, 135, 13, 98, 51, 57],
    [75, 186, 13, 241, 50, 56],
    [4, 237, 13, 130, 50, 55],
    [79, 31, 14, 20, 50, 54],
    [45, 81, 14, 168, 49, 53],
    [160, 130, 14, 62, 49, 52],
    [170, 179, 14, 214, 48, 51],
    [77, 228, 14, 112, 48, 50],
    [138, 20, 15, 11, 48, 50],
    [100, 68, 15, 168, 47, 49],
    [219, 115, 15, 70, 47, 48],
    [241, 162, 15, 230, 46, 47],
    [167, 209, 15, 135, 46, 47],
];

const EXP2_SEG_DATA: [[u16; 2]; 32] = [
    [32768, 702],
    [32066, 687],
    [31379, 673],
    [30706, 658],
    [30048, 643],
    [29405, 631],
    [28774, 616],
    [28158, 604],
    [27554, 590],
    [26964, 578],
    [26386, 565],
    [25821, 553],
    [25268, 542],
    [24726, 530],
    [24196, 518],
    [23678, 508],
    [23170, 496],
    [22674, 486],
    [22188, 475],
    [21713, 466],
    [21247, 455],
    [20792, 445],
    [20347, 436],
    [19911, 427],
    [19484, 418],
    [19066, 408],
    [18658, 400],
    [18258, 391],
    [17867, 383],
    [17484, 375],
    [17109, 366],
    [16743, 359],
];

const DECIBEL_DATA: [u32; 10] = [
    2147483648, 1705806895, 1354970580, 1076291389, 854928639, 679093957, 539423504, 428479319,
    340353221, 270352174,
];

const DECADE_DATA: [u32; 10] = [
    2147483648, 214748365, 21474836, 2147484, 214748, 21475, 2147, 215, 21, 2,
];

/// The log2 table in flash, where the AVR column kernel (`column/avr.rs`) reads it by its
/// symbol; Rust reads it through [`LOG2_SEG`].
#[cfg(target_arch = "avr")]
#[allow(unsafe_code)]
#[link_section = ".progmem.data"]
pub(crate) static LOG2_SEG_FLASH: [[u8; LOG2_SEG_BYTES]; LOG2_SEGMENTS] = LOG2_SEG_DATA;

#[cfg(target_arch = "avr")]
// SAFETY: `LOG2_SEG_FLASH` is in the progmem section (its `link_section`), as `ProgMem` needs.
#[allow(unsafe_code)]
static LOG2_SEG: avr_progmem::wrapper::ProgMem<[[u8; LOG2_SEG_BYTES]; LOG2_SEGMENTS]> =
    unsafe { avr_progmem::wrapper::ProgMem::new(core::ptr::addr_of!(LOG2_SEG_FLASH)) };

#[cfg(target_arch = "avr")]
avr_progmem::progmem! {
    static progmem EXP2_SEG: [[u16; 2]; 32] = EXP2_SEG_DATA;
    static progmem DECIBEL: [u32; 10] = DECIBEL_DATA;
    static progmem DECADE: [u32; 10] = DECADE_DATA;
}

#[cfg(not(target_arch = "avr"))]
mod plain {
    pub(super) static LOG2_SEG: [[u8; super::LOG2_SEG_BYTES]; super::LOG2_SEGMENTS] =
        super::LOG2_SEG_DATA;
    pub(super) static EXP2_SEG: [[u16; 2]; 32] = super::EXP2_SEG_DATA;
    pub(super) static DECIBEL: [u32; 10] = super::DECIBEL_DATA;
    pub(super) static DECADE: [u32; 10] = super::DECADE_DATA;
}

/// Segment `k` (`< 64`) of the log2 table: `c0` (3 bytes), `c1` (2 bytes), `c2`, little endian.
#[inline(always)]
pub(crate) fn log2_seg(k: usize) -> [u8; LOG2_SEG_BYTES] {
    #[cfg(target_arch = "avr")]
    {
        LOG2_SEG.load_at(k)
    }
    #[cfg(not(target_arch = "avr"))]
    {
        plain::LOG2_SEG[k]
    }
}

/// Segment `k` (`< 32`) of the exp2 table: `[2^(−k/32) Q.15, difference to the next]`.
#[inline(always)]
pub(crate) fn exp2_seg(k: usize) -> [u16; 2] {
    #[cfg(target_arch = "avr")]
    {
        EXP2_SEG.load_at(k)
    }
    #[cfg(not(target_arch = "avr"))]
    {
        plain::EXP2_SEG[k]
    }
}

/// `10^(−k/10)` in Q.31 for `k < 10`.
pub(crate) fn decibel(k: usize) -> u32 {
    #[cfg(target_arch = "avr")]
    {
        DECIBEL.load_at(k)
    }
    #[cfg(not(target_arch = "avr"))]
    {
        plain::DECIBEL[k]
    }
}

/// `10^(−q)` in Q.31 for `q < 10`.
pub(crate) fn decade(q: usize) -> u32 {
    #[cfg(target_arch = "avr")]
    {
        DECADE.load_at(q)
    }
    #[cfg(not(target_arch = "avr"))]
    {
        plain::DECADE[q]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_match_their_definitions() {
        for k in 0..LOG2_SEGMENTS {
            // Chebyshev nodes of the segment and the quadratic through them.
            let f = |t: f64| libm::log2(1.0 + (k as f64 + t) / LOG2_SEGMENTS as f64);
            let q20 = (1u32 << 20) as f64;
            let ts: [f64; 3] = core::array::from_fn(|i| {
                0.5 + 0.5 * libm::cos((2 * i + 1) as f64 * core::f64::consts::PI / 6.0)
            });
            let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
            for i in 0..3 {
                let o: [f64; 2] = match i {
                    0 => [ts[1], ts[2]],
                    1 => [ts[0], ts[2]],
                    _ => [ts[0], ts[1]],
                };
                let den = (ts[i] - o[0]) * (ts[i] - o[1]);
                let y = f(ts[i]);
                c += y / den;
                b -= y * (o[0] + o[1]) / den;
                a += y * o[0] * o[1] / den;
            }
            let r = log2_seg(k);
            // c0 carries a +0.4 ulp bias that centres the truncations of the evaluation.
            let c0 = u32::from_le_bytes([r[0], r[1], r[2], 0]) as f64;
            assert_eq!(c0, libm::round(a * q20 + 0.4), "c0[{k}]");
            let c1 = u16::from_le_bytes([r[3], r[4]]) as f64;
            assert_eq!(c1, libm::round(b * q20), "c1[{k}]");
            assert_eq!(r[5] as f64, libm::round(-c * q20), "c2[{k}]");
        }
        let e = |k: usize| libm::round(libm::exp2(-(k as f64) / 32.0) * 32768.0);
        for k in 0..32 {
            let [v, d] = exp2_seg(k);
            assert_eq!(v as f64, e(k));
            assert_eq!(d as f64, e(k) - e(k + 1));
        }
        let q31 = (1u64 << 31) as f64;
        for k in 0..10 {
            assert_eq!(
                decibel(k) as f64,
                libm::round(libm::pow(10.0, -(k as f64) / 10.0) * q31)
            );
            assert_eq!(
                decade(k) as f64,
                libm::round(libm::pow(10.0, -(k as f64)) * q31)
            );
        }
    }
}
