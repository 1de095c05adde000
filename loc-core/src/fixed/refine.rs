//! Channel refinements on RSSI bytes ([`crate::refine`] in fixed point).

use super::math::{log2_u32, log2_u33, log2_u64, m8, mul_shr};
#[cfg(doc)]
use super::params::FitKernel;
use super::params::{CalStats, PortableFit};
use super::tables::{decade, decibel};
use super::{AreaCm, ChannelBytes, Measurements, PointCm, DB};
use crate::refine::Refinement;
use crate::{MAX_ANCHORS, MAX_CHANNELS};

/// One observation of the position cost. `repr(C)`: a [`ReportKernel`] in assembly writes it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[repr(C)]
pub struct Obs {
    /// Anchor position.
    pub pos: PointCm,
    /// Refined RSSI, Q.16 dBm.
    pub z: i32,
    /// Weight in the cost (1, or the channel count for [`Refinement::Extended`]; ≤ 4).
    pub weight: u8,
}

/// Up to [`MAX_ANCHORS`] observations. `repr(C)`: a [`ReportKernel`] in assembly writes it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[repr(C)]
pub struct Observations {
    obs: [Obs; MAX_ANCHORS],
    len: usize,
    /// Position-independent part of the cost dropped by folding channels into their dB mean
    /// (`Σ_anchors Σ_c (z_c − z̄)²` for [`Refinement::Extended`], else 0), Q.8 dB², saturating.
    pub const_cost: u32,
}

impl Observations {
    /// No observations.
    pub const fn new() -> Observations {
        Observations {
            obs: [Obs {
                pos: PointCm::new(0, 0),
                z: 0,
                weight: 0,
            }; MAX_ANCHORS],
            len: 0,
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
        match self.obs.get_mut(self.len) {
            Some(slot) => {
                *slot = ob;
                self.len += 1;
                true
            }
            None => false,
        }
    }

    /// The observations.
    pub fn as_slice(&self) -> &[Obs] {
        &self.obs[..self.len.min(MAX_ANCHORS)]
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

/// A report's measurement bytes as the radio message carries them (loc-proto's report: from its
/// first anchor position, at `start`, on): `anchors` positions (x, y: little-endian `i16`, cm), the agent's
/// RSSI bytes channel by channel (`anchors` each), then, with `relay`, per channel and anchor
/// `i` the bytes anchor `i` relayed of the other anchors `j ≠ i` (`anchors − 1` each). 0 bytes:
/// not heard.
#[derive(Clone, Copy, Debug)]
pub struct ReportBytes<'a> {
    /// The bytes (before `start` and after the layout not read).
    pub bytes: &'a [u8],
    /// Where the first position is.
    pub start: u8,
    /// Anchors in use, at most [`MAX_ANCHORS`].
    pub anchors: u8,
    /// Channels in use, at most [`MAX_CHANNELS`].
    pub channels: u8,
    /// Whether the relay bytes are there.
    pub relay: bool,
}

impl ReportBytes<'_> {
    /// The bytes the layout takes, `start` included; `None` beyond [`MAX_ANCHORS`] or [`MAX_CHANNELS`] or when
    /// `bytes` is shorter (then a [`ReportKernel`] adds nothing).
    pub fn size(&self) -> Option<usize> {
        let (n, c) = (self.anchors as usize, self.channels as usize);
        let rows = if self.relay { n } else { 1 };
        let len = self.start as usize + 4 * n + c * n * rows;
        (n <= MAX_ANCHORS && c <= MAX_CHANNELS && self.bytes.len() >= len).then_some(len)
    }
}

/// A report's calibration sums, observations and anchors' extent straight from its bytes: what
/// the sink does per report, [`portable_report_inputs`] here, one AVR assembly routine on the sink
/// (`uno_board::AvrFit`); both leave exactly the same results (`report-check`).
pub trait ReportKernel {
    /// Adds `r`'s samples (every anchor pair `i < j`, both directions' relayed bytes, by
    /// [`CalStats::push_pair_with`]) to `stats` and its anchors' Extended observations (by
    /// [`extended`], the spreads to `const_cost`) to `obs`, and widens `area` to each anchor's
    /// position (x and y below 0 as 0: the sink's anchors' box); nothing when `r` does not hold
    /// its layout ([`ReportBytes::size`]).
    fn report_inputs(
        r: &ReportBytes,
        stats: &mut CalStats,
        obs: &mut Observations,
        area: &mut AreaCm,
    );
}

impl ReportKernel for PortableFit {
    fn report_inputs(
        r: &ReportBytes,
        stats: &mut CalStats,
        obs: &mut Observations,
        area: &mut AreaCm,
    ) {
        portable_report_inputs(r, stats, obs, area)
    }
}

/// [`ReportKernel::report_inputs`]: every pair by [`CalStats::push_pair`] (what
/// [`CalStats::push_pair_with`] adds, whatever the [`FitKernel`]), every anchor by [`extended`]
/// (the definition the assembly one is checked against).
pub fn portable_report_inputs(
    r: &ReportBytes,
    stats: &mut CalStats,
    obs: &mut Observations,
    area: &mut AreaCm,
) {
    if r.size().is_none() {
        return;
    }
    let (n, c) = (r.anchors as usize, r.channels as usize);
    let at = |k: usize| r.bytes.get(r.start as usize + k).copied().unwrap_or(0);
    let pos = |i: usize| {
        let k = 4 * i;
        PointCm::new(
            i16::from_le_bytes([at(k), at(k + 1)]),
            i16::from_le_bytes([at(k + 2), at(k + 3)]),
        )
    };
    let (rssi, relay) = (4 * n, 4 * n + c * n);
    if r.relay {
        for i in 0..n {
            for j in i + 1..n {
                // Anchor i's bytes of j, then j's of i (0: not heard); row (ch, p) holds the
                // anchors q ≠ p in order.
                let mut bytes = [None; 2 * MAX_CHANNELS];
                for (k, b) in bytes.iter_mut().enumerate() {
                    let ch = k % MAX_CHANNELS;
                    let (p, q) = if k < MAX_CHANNELS { (i, j) } else { (j, i) };
                    if ch < c {
                        let v = at(relay + (ch * n + p) * (n - 1) + q - usize::from(q > p));
                        *b = (v != 0).then_some(v);
                    }
                }
                stats.push_pair(pos(i), pos(j), &bytes);
            }
        }
    }
    for i in 0..n {
        let p = pos(i);
        area.width = area.width.max(p.x.max(0) as u16);
        area.height = area.height.max(p.y.max(0) as u16);
        let mut bytes = [0u8; MAX_CHANNELS];
        for (ch, v) in bytes[..c].iter_mut().enumerate() {
            *v = at(rssi + ch * n + i);
        }
        if let Some((z, weight, spread)) = extended(&bytes[..c]) {
            obs.const_cost = obs.const_cost.saturating_add(spread);
            obs.push(Obs { pos: p, z, weight });
        }
    }
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

    /// A report's inputs are those of its anchors' bytes by `observations_of` and of its pairs
    /// by `CalStats::push_pair`, wherever it starts; a slice one byte short (or 9 anchors, or 5
    /// channels) changes nothing.
    #[test]
    fn report_inputs_are_the_pairs_and_the_anchors_bytes() {
        let (n, c) = (4usize, 3usize);
        let mut x = 0x1234_5678u32;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x
        };
        for t in 0..200 {
            let start = t % 11;
            let relay = t % 3 != 0;
            let len = start + 4 * n + c * n * if relay { n } else { 1 };
            let mut buf = [0u8; 11 + 4 * 4 + 3 * 4 * 4];
            for b in buf.iter_mut() {
                *b = match next() % 4 {
                    0 => 0,
                    _ => next() as u8,
                };
            }
            let body = &buf[start..];
            let pos: [PointCm; 4] = core::array::from_fn(|i| {
                let b = &body[4 * i..];
                PointCm::new(
                    i16::from_le_bytes([b[0], b[1]]),
                    i16::from_le_bytes([b[2], b[3]]),
                )
            });
            let heard = |v: u8| (v != 0).then_some(v);
            let rssi: [ChannelBytes; 4] = core::array::from_fn(|i| {
                core::array::from_fn(|ch| {
                    (ch < c).then(|| heard(body[4 * n + ch * n + i])).flatten()
                })
            });
            let mut want_s = CalStats::new();
            if relay {
                let rel = |ch: usize, i: usize, j: usize| {
                    heard(body[4 * n + c * n + (ch * n + i) * (n - 1) + j - usize::from(j > i)])
                };
                for i in 0..n {
                    for j in i + 1..n {
                        let mut b = [None; 8];
                        for ch in 0..c {
                            (b[ch], b[4 + ch]) = (rel(ch, i, j), rel(ch, j, i));
                        }
                        want_s.push_pair(pos[i], pos[j], &b);
                    }
                }
            }
            let want_o = observations_of(&pos, &rssi, c, Refinement::Extended);
            let mut want_a = AreaCm::new(0, 0);
            for p in pos {
                want_a.width = want_a.width.max(p.x.max(0) as u16);
                want_a.height = want_a.height.max(p.y.max(0) as u16);
            }
            let r = ReportBytes {
                bytes: &buf[..len],
                start: start as u8,
                anchors: n as u8,
                channels: c as u8,
                relay,
            };
            let (mut s, mut o, mut a) = (CalStats::new(), Observations::new(), AreaCm::new(0, 0));
            portable_report_inputs(&r, &mut s, &mut o, &mut a);
            assert_eq!((s, o, a), (want_s, want_o, want_a), "{t}");
            for short in [
                ReportBytes {
                    bytes: &buf[..len - 1],
                    ..r
                },
                ReportBytes { anchors: 9, ..r },
                ReportBytes { channels: 5, ..r },
            ] {
                let (mut s, mut o, mut a) =
                    (CalStats::new(), Observations::new(), AreaCm::new(0, 0));
                portable_report_inputs(&short, &mut s, &mut o, &mut a);
                assert_eq!((s, o, a), Default::default());
            }
        }
    }

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
