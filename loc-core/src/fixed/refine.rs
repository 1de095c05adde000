//! Channel refinements on RSSI bytes ([`crate::refine`] in fixed point).

use super::math::{log2_u32, log2_u33, log2_u64, m8, mul_shr};
use super::tables::{decade, decibel};
use super::{ChannelBytes, Measurements, PointCm, DB};
use crate::refine::Refinement;
use crate::{MAX_ANCHORS, MAX_CHANNELS};

/// One observation of the position cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Obs {
    /// Anchor position.
    pub pos: PointCm,
    /// Refined RSSI, Q.16 dBm.
    pub z: i32,
    /// Weight in the cost (1, or the channel count for [`Refinement::Extended`]; ≤ 4).
    pub weight: u8,
}

/// Up to [`MAX_ANCHORS`] observations.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub struct Observations {
    obs: heapless::Vec<Obs, MAX_ANCHORS>,
    /// Position-independent part of the cost dropped by folding channels into their dB mean
    /// (`Σ_anchors Σ_c (z_c − z̄)²` for [`Refinement::Extended`], else 0), Q.8 dB², saturating.
    pub const_cost: u32,
}

impl Observations {
    /// No observations.
    pub const fn new() -> Observations {
        Observations {
            obs: heapless::Vec::new(),
            const_cost: 0,
        }
    }

    /// Observations from a slice (at most [`MAX_ANCHORS`] kept).
    pub fn from_slice(obs: &[Obs]) -> Observations {
        let mut o = Observations::new();
        for &ob in obs {
            o.push(ob);
        }
        o
    }

    /// Appends `ob`; returns `false` (and drops it) when full. Weights above 4 count as 4.
    pub fn push(&mut self, mut ob: Obs) -> bool {
        ob.weight = ob.weight.min(MAX_CHANNELS as u8);
        self.obs.push(ob).is_ok()
    }

    /// The observations.
    pub fn as_slice(&self) -> &[Obs] {
        &self.obs
    }

    /// Number of observations (= usable anchors).
    pub fn len(&self) -> usize {
        self.as_slice().len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Sum of the weights (scalar measurements behind the observations).
    pub fn total_weight(&self) -> u8 {
        self.as_slice().iter().map(|o| o.weight).sum()
    }
}

/// Q.16 dBm of an RSSI byte.
fn dbm(byte: u8) -> i32 {
    -(byte as i32) * DB
}

/// `round(num / d)` for `d ≥ 1`, cheap for the channel counts 1…4 (no division for 1, 2, 4).
fn div_count(num: u32, d: u32) -> u32 {
    match d {
        1 => num,
        2 => (num + 1) >> 1,
        4 => (num + 2) >> 2,
        _ => (num + d / 2) / d.max(1),
    }
}

/// dB mean of the present channels (Q.16 dBm, rounded) and their number (saturating at 255).
pub fn db_mean(rssi: &[Option<u8>]) -> Option<(i32, u8)> {
    let (sum, n) = rssi
        .iter()
        .flatten()
        .fold((0u32, 0u32), |(s, n), &b| (s + b as u32, n + 1));
    if n == 0 {
        return None;
    }
    if sum < 1 << 15 {
        // The usual case (up to 128 channels): one rounding division, none for 1, 2 or 4.
        return Some((-(div_count(sum << 16, n) as i32), n.min(255) as u8));
    }
    // Whole dB and the remainder's fraction: no product beyond 2^32 for any slice length.
    let (q, rem) = (sum / n, sum % n);
    let frac = if n < 1 << 15 {
        div_count(rem << 16, n)
    } else {
        0
    };
    Some((-((q << 16) as i32 + frac as i32), n.min(255) as u8))
}

/// Largest present value, Q.16 dBm.
pub fn max_rssi(rssi: &[Option<u8>]) -> Option<i32> {
    rssi.iter().flatten().min().map(|&b| dbm(b))
}

/// Mean power in mW of the present channels, in Q.16 dBm: `10·log10(mean 10^(z/10))`, relative
/// to the largest value (`10^(−k/10)` for the integer dB gap `k` from two flash tables, the log
/// from the log2 table): within 10⁻⁵ dB of the exact value.
pub fn linear_avg(rssi: &[Option<u8>]) -> Option<i32> {
    let top = *rssi.iter().flatten().min()?;
    let (mut sum, mut n) = (0u64, 0u32);
    for &b in rssi.iter().flatten() {
        let k = (b - top) as usize;
        if k < 100 {
            // 10^(−k/10) = 10^(−(k mod 10)/10) · 10^(−⌊k/10⌋), Q.31.
            sum += (decibel(k % 10) as u64 * decade(k / 10) as u64) >> 31;
        }
        n += 1;
    }
    // sum ≥ 2^31 (the top term): log2(sum / 2^31 / n) ∈ [−2, 0], Q.20.
    let log2_n = match n {
        1 => 0,
        2 => 1 << 20,
        3 => LOG2_3_Q20,
        4 => 2 << 20,
        _ => log2_u32(n) as i64,
    };
    // sum < 2^33 for up to 4 channels (the 33-bit log), any count otherwise.
    let lsum = if sum >> 33 == 0 {
        log2_u33(sum as u32, sum >> 32 != 0)
    } else {
        log2_u64(sum)
    };
    let l = lsum as i64 - (31i64 << 20) - log2_n;
    // 10·log10(2)·l: Q.28 × Q.20 → Q.16.
    Some(dbm(top) + mul_shr(TEN_LOG10_2_Q28, l, 32) as i32)
}

/// `log2(3)`, Q.20.
const LOG2_3_Q20: i64 = 1661954;
/// `10·log10(2)`, Q.28.
const TEN_LOG10_2_Q28: i64 = 808_071_242;

/// One anchor's refined `(z Q.16 dBm, weight)` over its channels in use, `None` if unusable.
pub fn refine_anchor(rssi: &[Option<u8>], refinement: Refinement) -> Option<(i32, u8)> {
    match refinement {
        Refinement::Single(c) => rssi.get(c).copied().flatten().map(|b| (dbm(b), 1)),
        Refinement::Max => max_rssi(rssi).map(|z| (z, 1)),
        Refinement::LinearAvg => linear_avg(rssi).map(|z| (z, 1)),
        Refinement::Extended => db_mean(rssi),
    }
}

/// `Σ_c (z_c − z̄)²` of the present channels, Q.8 dB², saturating: `(n·Σb² − (Σb)²)/n`.
fn spread(rssi: &[Option<u8>]) -> u32 {
    let (mut s, mut s2, mut n) = (0u32, 0u32, 0u32);
    for &b in rssi.iter().flatten() {
        s = s.saturating_add(b as u32);
        s2 = s2.saturating_add(b as u32 * b as u32);
        n += 1;
    }
    if n == 0 || n > 16 {
        return 0; // (never more than MAX_CHANNELS in use)
    }
    // n·Σb² < 16·16·65025 < 2^24: Q.8 fits.
    div_count((n * s2 - s * s) << 8, n)
}

/// The Extended refinement of one anchor's raw radio bytes (`0`: channel not heard; at most
/// [`MAX_CHANNELS`] are read): the dB mean (Q.16 dBm), the channel count and the spread
/// `Σ_c (z_c − z̄)²` (Q.8 dB²) — exactly [`db_mean`] and the spread [`observations_of`] adds to
/// `const_cost`, without `Option` bytes, for the sink, which reads the bytes straight from a
/// report. `None` if no channel was heard.
#[inline(never)]
pub fn extended(bytes: &[u8]) -> Option<(i32, u8, u32)> {
    let (mut s, mut s2, mut n) = (0u16, 0u32, 0u8);
    for &b in &bytes[..bytes.len().min(MAX_CHANNELS)] {
        if b != 0 {
            s += b as u16;
            s2 += m8(b, b) as u32;
            n += 1;
        }
    }
    if n == 0 {
        return None;
    }
    // s ≤ 4·255 < 2^15 (db_mean's usual case); n·Σb² < 4·4·65025 < 2^24. `div_count`'s
    // shortcuts for 1, 2 and 4 give what the plain rounding division gives.
    let (s, n32) = (s as u32, n as u32);
    Some((
        -(div_round(s << 16, n32) as i32),
        n,
        div_round((n32 * s2 - s * s) << 8, n32),
    ))
}

/// `num / d` rounded half up, `d ≥ 1` (one copy for both of [`extended`]'s divisions).
#[inline(never)]
fn div_round(num: u32, d: u32) -> u32 {
    (num + d / 2) / d
}

/// Observations of anchors at `anchors` with the agent's bytes `rssi` (same order; the shorter
/// decides), channels `0..n_channels`, under `refinement`: one per usable anchor, in anchor order.
pub fn observations_of(
    anchors: &[PointCm],
    rssi: &[ChannelBytes],
    n_channels: usize,
    refinement: Refinement,
) -> Observations {
    let n_ch = n_channels.min(MAX_CHANNELS);
    let mut out = Observations::new();
    for (&pos, bytes) in anchors.iter().zip(rssi) {
        let bytes = &bytes[..n_ch];
        if let Some((z, weight)) = refine_anchor(bytes, refinement) {
            if refinement == Refinement::Extended {
                out.const_cost = out.const_cost.saturating_add(spread(bytes));
            }
            out.push(Obs { pos, z, weight });
        }
    }
    out
}

/// The observations of `m` under `refinement`.
pub fn observations(m: &Measurements, refinement: Refinement) -> Observations {
    observations_of(m.anchors(), &m.rssi, m.channels(), refinement)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extended_of_raw_bytes_is_db_mean_and_spread() {
        // Every combination of up to 4 channels over a spread of byte values, 0 = not heard.
        let values = [0u8, 1, 2, 37, 64, 65, 90, 91, 200, 254, 255];
        let mut checked = 0;
        for a in values {
            for b in values {
                for c in values {
                    for d in [0u8, 71, 255] {
                        let raw = [a, b, c, d];
                        let opt: [Option<u8>; 4] = raw.map(|v| (v != 0).then_some(v));
                        let want = db_mean(&opt).map(|(z, w)| (z, w, spread(&opt)));
                        assert_eq!(extended(&raw), want, "{raw:?}");
                        let obs = observations_of(
                            &[PointCm::new(1, 2)],
                            &[[opt[0], opt[1], opt[2], opt[3]]],
                            4,
                            Refinement::Extended,
                        );
                        match want {
                            Some((z, w, sp)) => {
                                assert_eq!(obs.as_slice()[0].z, z);
                                assert_eq!(obs.as_slice()[0].weight, w);
                                assert_eq!(obs.const_cost, sp);
                            }
                            None => assert!(obs.as_slice().is_empty()),
                        }
                        checked += 1;
                    }
                }
            }
        }
        assert_eq!(checked, 11 * 11 * 11 * 3);
        // Bytes past MAX_CHANNELS are not read.
        assert_eq!(extended(&[60, 0, 0, 0, 99]), extended(&[60]));
        assert_eq!(extended(&[]), None);
    }
}
