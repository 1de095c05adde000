//! The fixed-point pipeline: the sink's sequence of loc-core calls ([`loc_core::fixed`]), with
//! the search's column kernel `K`: `Fixed<Native>` is what the sink runs (the AVR assembly
//! column on the MCU, the portable one on the host, with the same results: `checkasm`),
//! `Fixed<Portable>` the same with the portable column on the MCU too.

use crate::{Inputs, Pipeline, Report, N_ANCHORS, N_CHANNELS, SIGMA_DB};
use core::marker::PhantomData;
use loc_core::fixed::{
    estimate_with, fit_least_squares, mle_with, mmse_window_with, observations_of, AreaCm, Bounds,
    CalStats, ChannelBytes, ColumnKernel, Estimator, FitMethod, Native, Observations, OnlineParams,
    ParamMode, PathLoss, PointCm, Refinement, Search,
};

/// The MMSE variant the fixed path runs: the windowed posterior mean
/// ([`loc_core::fixed::mmse_window`]: the thesis' coarse stage, then the posterior mean over its
/// fine window), σ = [`SIGMA_DB`] in Q.8 dB. The same estimator as [`crate::float`]'s and
/// [`loc_core::grid::mmse_window`], which the harness checks; the full-lattice
/// `Estimator::Mmse` would evaluate all 2 601 lattice points.
pub const MMSE: Estimator = Estimator::MmseWindow {
    sigma: (SIGMA_DB as u16) << 8,
};

/// Whether [`MMSE`] is the windowed estimator of [`crate::float`] (the bench says so when not).
pub const MMSE_IS_WINDOWED: bool = matches!(MMSE, Estimator::MmseWindow { .. });

/// [`loc_core::fixed`] with P0 and α estimated by least squares within the thesis' bounds, AR(1)
/// smoothed from the thesis' prior.
///
/// Its [`Report`]: position in mm, P0 Q.16 dBm and α Q.24 (as `i32` bits); all `u32::MAX` if
/// the estimate failed.
#[derive(Clone, Copy, Debug)]
pub struct Fixed<K = Native> {
    /// The online parameter state.
    pub params: OnlineParams,
    kernel: PhantomData<K>,
}

impl<K> Default for Fixed<K> {
    fn default() -> Self {
        Fixed::new()
    }
}

impl<K> Fixed<K> {
    /// Fresh state: the thesis' prior, no fit yet.
    pub fn new() -> Fixed<K> {
        Fixed {
            params: OnlineParams::new(
                ParamMode::P0AndAlpha,
                FitMethod::LeastSquares,
                Bounds::THESIS,
                PathLoss::THESIS,
            ),
            kernel: PhantomData,
        }
    }

    /// The [`Report`] of `e` with the current P0/α (all `u32::MAX` if the estimate failed).
    pub(crate) fn report(
        &self,
        e: Result<loc_core::fixed::Estimate, loc_core::LocError>,
    ) -> Report {
        let m = self.params.current();
        match e {
            Ok(e) => Report {
                x: e.pos.x,
                y: e.pos.y,
                p0: m.p0 as u32,
                alpha: m.alpha as u32,
            },
            Err(_) => Report {
                x: u32::MAX,
                y: u32::MAX,
                p0: u32::MAX,
                alpha: u32::MAX,
            },
        }
    }
}

fn anchors(inp: &Inputs) -> [PointCm; N_ANCHORS] {
    inp.anchors.map(|[x, y]| PointCm::new(x, y))
}

fn area(inp: &Inputs) -> AreaCm {
    AreaCm::new(inp.area[0], inp.area[1])
}

impl<K: ColumnKernel> Pipeline for Fixed<K> {
    type Stats = CalStats;
    type Obs = Observations;

    fn calibrate(&mut self, inp: &Inputs) -> CalStats {
        let a = anchors(inp);
        let mut stats = CalStats::new();
        for i in 0..N_ANCHORS {
            for j in i + 1..N_ANCHORS {
                // Both directions' bytes as a report carries them (0: not heard), one distance
                // (one log) per pair.
                let mut bytes = [0; 2 * loc_core::MAX_CHANNELS];
                for c in 0..N_CHANNELS {
                    bytes[c] = inp.a2a_byte(i, j, c);
                    bytes[loc_core::MAX_CHANNELS + c] = inp.a2a_byte(j, i, c);
                }
                stats.push_pair_bytes(a[i], a[j], &bytes);
            }
        }
        stats
    }

    /// The sink's round (`sink_fw::Sink`): the least-squares fit from the current model, fed to
    /// the smoothers.
    fn fit(&mut self, stats: &CalStats) {
        let p = &self.params;
        if let Ok(f) = fit_least_squares(stats, p.mode, p.current(), &p.bounds) {
            self.params.feed(&f);
        }
    }

    fn refine(&mut self, inp: &Inputs) -> Observations {
        let mut rssi: [ChannelBytes; N_ANCHORS] = Default::default();
        for (r, bytes) in rssi.iter_mut().zip(&inp.agent) {
            for (slot, &b) in r.iter_mut().zip(bytes) {
                *slot = Some(b);
            }
        }
        observations_of(&anchors(inp), &rssi, N_CHANNELS, Refinement::Extended)
    }

    fn mle(&mut self, obs: &Observations, inp: &Inputs) -> Report {
        let e = mle_with::<K>(obs, self.params.current(), area(inp), Search::Thesis);
        self.report(e)
    }

    fn mmse(&mut self, obs: &Observations, inp: &Inputs) -> Report {
        // What a sink runs: the windowed MMSE alone (through `estimate_with` every estimator
        // would be linked in).
        let e = match MMSE {
            Estimator::MmseWindow { sigma } => {
                mmse_window_with::<K>(obs, self.params.current(), area(inp), sigma)
            }
            other => estimate_with::<K>(obs, self.params.current(), area(inp), other),
        };
        self.report(e)
    }
}
