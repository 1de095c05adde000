//! The sink's logic, sans-IO (SPEC §4): per agent report, P0/α from the relayed anchor-to-anchor
//! RSSI (least squares + AR(1)), then the agent located by loc-core's fixed-point path twice —
//! the thesis MLE and the windowed MMSE — and the counters of the status lines.
//!
//! [`Sink`] is fed what the shell decoded ([`Sink::on_report`], [`Sink::on_bad_frame`]) and
//! answers with a [`Fix`] (or why there is none); `main.rs` writes them as loc-proto's sink
//! lines. It is generic over the cost kernel: the AVR assembly one on the Uno, the portable one
//! on the host, with identical results.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

use core::marker::PhantomData;
use loc_core::fixed::{
    mle_with, mmse_window_with, observations, AreaCm, Bounds, Estimate, FitMethod, LocError,
    Measurements, OnlineParams, ParamMode, PathLoss, PointCm, Refinement, Search, TermKernel,
};
use loc_proto::msg::Report;

/// What a [`Report`] measured, for loc-core: anchor positions as the beacons gave them, the
/// agent's RSSI per anchor and channel, and the relayed anchor-to-anchor RSSI (`a2a[i][j][c]`:
/// anchor `i + 1` heard anchor `j + 1`); 0 bytes (not heard) are missing values.
pub fn measurements(r: &Report) -> Measurements {
    let n = (r.anchors as usize).min(loc_core::MAX_ANCHORS);
    let c = r.channels.len().min(loc_core::MAX_CHANNELS);
    let mut pos = [PointCm::default(); loc_core::MAX_ANCHORS];
    for (p, q) in pos.iter_mut().zip(&r.positions[..n]) {
        *p = PointCm::new(q.x, q.y);
    }
    let mut m = Measurements::new(&pos[..n], c);
    let heard = |b: u8| (b != 0).then_some(b);
    for ch in 0..c {
        for i in 0..n {
            m.rssi[i][ch] = heard(r.rssi[ch][i]);
            if r.has_relay {
                for j in 0..n {
                    if i != j {
                        m.a2a[i][j][ch] = heard(r.relay[ch][i][j]);
                    }
                }
            }
        }
    }
    m
}

/// Most agents a sink tracks (report sequence numbers for the drop count).
pub const MAX_AGENTS: usize = 16;
/// The MMSE's σ while the fit has none, Q.8 dB (4 dB, the thesis' larger σ).
pub const DEFAULT_SIGMA: u16 = 4 << 8;

/// What the status line counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Counters {
    /// Frames received.
    pub frames: u32,
    /// Reports decoded.
    pub reports: u32,
    /// Reports missing (gaps in an agent's sequence numbers).
    pub drops: u32,
    /// Frames that failed their checksum or did not decode.
    pub checksum_errors: u32,
    /// Frames that are not hoploc messages (another PAN user, or another kind).
    pub foreign: u32,
    /// Fixes made.
    pub fixes: u32,
    /// Reports that gave no fix.
    pub no_fixes: u32,
}

/// A frame the shell could not take as a report.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BadFrame {
    /// A hoploc message that failed to decode (checksum, length, values).
    Corrupt,
    /// Not a hoploc report.
    Foreign,
}

/// One report's estimates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Fix {
    /// The agent.
    pub agent: u8,
    /// The report's superframe sequence.
    pub seq: u16,
    /// The thesis MLE.
    pub mle: Estimate,
    /// The windowed MMSE.
    pub mmse: Estimate,
    /// The path-loss model both used (after this report's fit and AR(1)).
    pub model: PathLoss,
    /// Whether this report's anchor-to-anchor RSSI gave a fit.
    pub fitted: bool,
}

/// The sink state machine over cost kernel `K`.
#[derive(Clone, Debug)]
pub struct Sink<K> {
    area: AreaCm,
    params: OnlineParams,
    counters: Counters,
    /// Next expected sequence per agent (index agent − 1).
    next_seq: [Option<u16>; MAX_AGENTS],
    kernel: PhantomData<K>,
}

impl<K: TermKernel> Sink<K> {
    /// A sink for the room `area`, estimating P0 and α by least squares within the thesis'
    /// bounds from the thesis' prior.
    pub fn new(area: AreaCm) -> Sink<K> {
        Sink {
            area,
            params: OnlineParams::new(
                ParamMode::P0AndAlpha,
                FitMethod::LeastSquares,
                Bounds::THESIS,
                PathLoss::THESIS,
            ),
            counters: Counters::default(),
            next_seq: [None; MAX_AGENTS],
            kernel: PhantomData,
        }
    }

    /// The counters.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// The current path-loss model.
    pub fn model(&self) -> PathLoss {
        self.params.current()
    }

    /// A frame that is not a usable report.
    pub fn on_bad_frame(&mut self, kind: BadFrame) {
        self.counters.frames += 1;
        match kind {
            BadFrame::Corrupt => self.counters.checksum_errors += 1,
            BadFrame::Foreign => self.counters.foreign += 1,
        }
    }

    /// A decoded report: [`Sink::on_measurements`] of its [`measurements`].
    pub fn on_report(&mut self, r: &Report) -> Result<Fix, LocError> {
        self.on_measurements(r.agent, r.seq, &measurements(r))
    }

    /// Agent `agent`'s report of superframe `seq`, as measurements: fit, smooth, locate.
    pub fn on_measurements(
        &mut self,
        agent: u8,
        seq: u16,
        m: &Measurements,
    ) -> Result<Fix, LocError> {
        self.counters.frames += 1;
        self.counters.reports += 1;
        if let Some(next) = self.next_seq.get_mut((agent as usize).wrapping_sub(1)) {
            if let Some(want) = *next {
                let gap = seq.wrapping_sub(want);
                // A gap of more than half the sequence space is a late or repeated report.
                if gap < 0x8000 {
                    self.counters.drops += gap as u32;
                }
            }
            *next = Some(seq.wrapping_add(1));
        }
        let stats = loc_core::fixed::CalStats::from_measurements(m, None);
        let fitted = self.params.update(&stats).is_ok();
        let model = self.params.current();
        let obs = observations(m, Refinement::Extended);
        let result = mle_with::<K>(&obs, model, self.area, Search::Thesis).and_then(|mle| {
            let sigma = self.params.sigma().unwrap_or(DEFAULT_SIGMA);
            let mmse = mmse_window_with::<K>(&obs, model, self.area, sigma)?;
            Ok(Fix {
                agent,
                seq,
                mle,
                mmse,
                model,
                fitted,
            })
        });
        match result {
            Ok(_) => self.counters.fixes += 1,
            Err(_) => self.counters.no_fixes += 1,
        }
        result
    }
}

#[cfg(test)]
mod tests;
