//! Channel refinements: how one anchor's per-channel RSSI becomes what the position
//! estimators see.
//!
//! Every refinement turns an anchor into at most one [`Obs`] (position, value `z`, weight `w`); the
//! estimators minimise `Σ wᵢ (zᵢ − p(|x − aᵢ|))²`. For [`Refinement::Extended`] that single
//! observation is the per-anchor dB mean with the number of channels as weight, because
//! `Σ_c (z_c − p)² = n·(z̄ − p)² + Σ_c (z_c − z̄)²`: the second term does not depend on the position,
//! so the argmin and the posterior are those of the full multichannel cost. The dropped term is kept
//! in [`Observations::const_cost`] so reported costs equal the full cost.
//!
//! Missing channels (`None`) and non-finite values are skipped; an anchor with no usable channel
//! yields no observation. Only the first `n_channels` channels of a [`Measurements`] count.

use crate::model::{Measurements, Point, MAX_ANCHORS};

/// How an anchor's channels are combined.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Refinement {
    /// Only this channel (index into the anchor's channels); the anchor is unusable without it.
    Single(usize),
    /// The largest RSSI over the channels (fading only ever lowers the received power much).
    Max,
    /// The mean in mW, back to dBm.
    LinearAvg,
    /// Every channel is its own observation (implemented as the dB mean weighted by the count).
    Extended,
}

/// One observation the position cost is built from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Obs {
    /// Anchor position.
    pub pos: Point,
    /// Refined RSSI, dBm.
    pub z: f64,
    /// Weight in the cost (1, or the channel count for [`Refinement::Extended`]).
    pub weight: f64,
}

/// Up to [`MAX_ANCHORS`] observations, without allocation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observations {
    obs: [Obs; MAX_ANCHORS],
    len: usize,
    /// Position-independent part of the cost dropped by folding channels into a mean
    /// (`Σ_anchors Σ_c (z_c − z̄)²` for [`Refinement::Extended`], else 0).
    pub const_cost: f64,
}

impl Default for Observations {
    fn default() -> Self {
        Observations::new()
    }
}

impl Observations {
    /// No observations.
    pub const fn new() -> Observations {
        Observations {
            obs: [Obs {
                pos: Point::new(0.0, 0.0),
                z: 0.0,
                weight: 0.0,
            }; MAX_ANCHORS],
            len: 0,
            const_cost: 0.0,
        }
    }

    /// Observations from a slice (at most [`MAX_ANCHORS`] are kept, the rest ignored).
    pub fn from_slice(obs: &[Obs]) -> Observations {
        let mut o = Observations::new();
        for &ob in obs {
            o.push(ob);
        }
        o
    }

    /// Appends `ob`; returns `false` (and drops it) when full.
    pub fn push(&mut self, ob: Obs) -> bool {
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
        &self.obs[..self.len]
    }

    /// Number of observations (= usable anchors).
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Sum of the weights: the number of scalar measurements behind the observations.
    pub fn total_weight(&self) -> f64 {
        self.as_slice().iter().map(|o| o.weight).sum()
    }
}

/// Usable (present and finite) values among `rssi`.
fn usable(rssi: &[Option<f64>]) -> impl Iterator<Item = f64> + '_ {
    rssi.iter().filter_map(|&v| v.filter(|z| z.is_finite()))
}

/// Mean in dB of the usable channels and how many there were (`None` if none).
pub fn db_mean(rssi: &[Option<f64>]) -> Option<(f64, usize)> {
    let (sum, n) = usable(rssi).fold((0.0, 0usize), |(s, n), z| (s + z, n + 1));
    (n > 0).then(|| (sum / n as f64, n))
}

/// Largest usable value.
pub fn max_rssi(rssi: &[Option<f64>]) -> Option<f64> {
    usable(rssi).reduce(f64::max)
}

/// Mean power in mW of the usable channels, in dBm: `10·log10(mean 10^(z/10))`.
///
/// Computed relative to the largest value so that no term under- or overflows, whatever the dBm.
pub fn linear_avg(rssi: &[Option<f64>]) -> Option<f64> {
    let top = max_rssi(rssi)?;
    let (sum, n) = usable(rssi).fold((0.0, 0usize), |(s, n), z| {
        (s + libm::pow(10.0, (z - top) / 10.0), n + 1)
    });
    // sum ≥ 1 (the top term), so the log is finite.
    Some(top + 10.0 * libm::log10(sum / n as f64))
}

/// One anchor's refined `(z, weight)` over `rssi` (its channels in use), `None` if unusable.
pub fn refine_anchor(rssi: &[Option<f64>], refinement: Refinement) -> Option<(f64, f64)> {
    match refinement {
        Refinement::Single(c) => rssi
            .get(c)
            .copied()
            .flatten()
            .filter(|z| z.is_finite())
            .map(|z| (z, 1.0)),
        Refinement::Max => max_rssi(rssi).map(|z| (z, 1.0)),
        Refinement::LinearAvg => linear_avg(rssi).map(|z| (z, 1.0)),
        Refinement::Extended => db_mean(rssi).map(|(z, n)| (z, n as f64)),
    }
}

/// The observations of `m` under `refinement`: one per usable anchor, in anchor order.
pub fn observations(m: &Measurements, refinement: Refinement) -> Observations {
    let n_ch = m.n_channels.min(crate::model::MAX_CHANNELS);
    let mut out = Observations::new();
    for a in m.anchors() {
        let rssi = &a.rssi[..n_ch];
        if let Some((z, weight)) = refine_anchor(rssi, refinement) {
            if refinement == Refinement::Extended {
                out.const_cost += usable(rssi).map(|v| (v - z) * (v - z)).sum::<f64>();
            }
            out.push(Obs {
                pos: a.pos,
                z,
                weight,
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_avg_of_two() {
        let v = linear_avg(&[Some(-40.0), Some(-50.0)]).unwrap();
        let want = 10.0 * libm::log10((1e-4 + 1e-5) / 2.0);
        assert!((v - want).abs() < 1e-12, "{v} vs {want}");
        assert!((v - -42.596_373_105_057_56).abs() < 1e-9);
        // Extreme values neither underflow nor lose the larger one.
        let v = linear_avg(&[Some(-3000.0), Some(-3010.0)]).unwrap();
        assert!((v - (-3000.0 + 10.0 * libm::log10(1.1 / 2.0))).abs() < 1e-9);
    }

    #[test]
    fn skips_missing_and_non_finite() {
        let r = [None, Some(-60.0), Some(f64::NAN), Some(-70.0)];
        assert_eq!(db_mean(&r), Some((-65.0, 2)));
        assert_eq!(max_rssi(&r), Some(-60.0));
        assert_eq!(refine_anchor(&r, Refinement::Single(0)), None);
        assert_eq!(refine_anchor(&r, Refinement::Single(2)), None);
        assert_eq!(refine_anchor(&r, Refinement::Single(9)), None);
        assert_eq!(refine_anchor(&r, Refinement::Single(3)), Some((-70.0, 1.0)));
        assert_eq!(refine_anchor(&r, Refinement::Extended), Some((-65.0, 2.0)));
        assert_eq!(refine_anchor(&[None, None], Refinement::Max), None);
    }

    #[test]
    fn observations_full_is_bounded() {
        let mut o = Observations::new();
        let ob = Obs {
            pos: Point::new(1.0, 2.0),
            z: -50.0,
            weight: 2.0,
        };
        for _ in 0..MAX_ANCHORS {
            assert!(o.push(ob));
        }
        assert!(!o.push(ob));
        assert_eq!(o.len(), MAX_ANCHORS);
        assert_eq!(o.total_weight(), 2.0 * MAX_ANCHORS as f64);
    }
}
