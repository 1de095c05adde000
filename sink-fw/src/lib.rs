//! The sink's logic, sans-IO: per agent report, P0/α from the relayed anchor-to-anchor RSSI
//! (least squares + AR(1)), then the agent located by loc-core's fixed-point path twice — the
//! thesis MLE and the windowed MMSE — and the counters of the status lines.
//!
//! [`Sink`] is fed what the shell decoded ([`Sink::on_report`], [`Sink::on_bad_frame`]) and
//! answers with a [`Fix`] (or why there is none); `main.rs` writes them as loc-proto's sink
//! lines. It runs the same `loc_core::fixed` code on the host and on the Uno (where the search's
//! column is loc-core's AVR kernel), so the host computes exactly the lines the firmware writes.
//!
//! Per report: [`Sink::on_report`] takes the calibration statistics and the Extended
//! observations straight from the report ([`report_inputs`], through [`ReportData`]'s
//! accessors: a [`ReportView`] over the packet's bytes in the firmware, so no decoded [`Report`]
//! is built), fits P0/α by least squares, and gets both estimates from one search
//! (`loc_core::fixed::mle_and_mmse_window_into`: the MMSE's window is the thesis' fine window,
//! so the coarse stage and the window run once). The results are those of the generic path,
//! [`Sink::on_measurements`] (thesis MLE, then windowed MMSE), bit for bit (`tests`).
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

use loc_core::fixed::{
    extended, fit_least_squares, mle_and_mmse_window_into, mul_hi, observations, AreaCm, Bounds,
    CalStats, Estimate, FitMethod, LocError, Measurements, Native, Obs, Observations, OnlineParams,
    ParamMode, PathLoss, PointCm, Refinement,
};
use loc_proto::msg::{NotReport, Position, Report, ReportView};
use loc_proto::sink_line::{write_status, Estimator, SinkLine, FLAG_FITTED};
use loc_proto::Error;

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

/// What [`Sink::on_report`] reads of a report: a decoded [`Report`] (host, tests) or a
/// [`ReportView`] over its bytes (the firmware: no copy of the report).
pub trait ReportData {
    /// The reporting agent.
    fn agent(&self) -> u8;
    /// The superframe sequence number.
    fn seq(&self) -> u16;
    /// The agent's failed transmissions before this report ([`Report::failed`]).
    fn failed(&self) -> u8;
    /// The anchors in use, at most [`loc_core::MAX_ANCHORS`].
    fn anchors(&self) -> usize;
    /// The channels in use, at most [`loc_core::MAX_CHANNELS`].
    fn channels(&self) -> usize;
    /// Anchor `i + 1`'s position.
    fn position(&self, i: usize) -> PointCm;
    /// The RSSI byte of anchor `i + 1`'s beacon on channel number `c`.
    fn rssi(&self, c: usize, i: usize) -> u8;
    /// The relayed byte anchor `i + 1` heard from `j + 1` on channel number `c`, 0 without the
    /// relay matrix.
    fn relay(&self, c: usize, i: usize, j: usize) -> u8;
}

impl ReportData for Report {
    fn agent(&self) -> u8 {
        self.agent
    }
    fn seq(&self) -> u16 {
        self.seq
    }
    fn failed(&self) -> u8 {
        self.failed
    }
    fn anchors(&self) -> usize {
        (self.anchors as usize).min(loc_core::MAX_ANCHORS)
    }
    fn channels(&self) -> usize {
        self.channels.len().min(loc_core::MAX_CHANNELS)
    }
    fn position(&self, i: usize) -> PointCm {
        PointCm::new(self.positions[i].x, self.positions[i].y)
    }
    fn rssi(&self, c: usize, i: usize) -> u8 {
        self.rssi[c][i]
    }
    fn relay(&self, c: usize, i: usize, j: usize) -> u8 {
        if self.has_relay {
            self.relay[c][i][j]
        } else {
            0
        }
    }
}

impl ReportData for ReportView<'_> {
    fn agent(&self) -> u8 {
        ReportView::agent(self)
    }
    fn seq(&self) -> u16 {
        ReportView::seq(self)
    }
    fn failed(&self) -> u8 {
        ReportView::failed(self)
    }
    fn anchors(&self) -> usize {
        ReportView::anchors(self).min(loc_core::MAX_ANCHORS)
    }
    fn channels(&self) -> usize {
        ReportView::channels(self).min(loc_core::MAX_CHANNELS)
    }
    fn position(&self, i: usize) -> PointCm {
        let p = ReportView::position(self, i);
        PointCm::new(p.x, p.y)
    }
    fn rssi(&self, c: usize, i: usize) -> u8 {
        ReportView::rssi(self, c, i)
    }
    fn relay(&self, c: usize, i: usize, j: usize) -> u8 {
        ReportView::relay(self, c, i, j)
    }
}

/// Most agents a sink tracks (report sequence numbers for the drop count).
pub const MAX_AGENTS: usize = 16;
/// The MMSE's σ while the fit has none, Q.8 dB (4 dB, the thesis' larger σ).
pub const DEFAULT_SIGMA: u16 = 4 << 8;

/// What the status line shows (the uptime, then the counters) and `no_fixes`, which it does
/// not: one array in the line's order, written in one loop, each counter bumped by its index.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Counters([u32; SHOWN + 1]);

/// [`Counters`]' indices.
const UPTIME: usize = 0;
const FRAMES: usize = 1;
const REPORTS: usize = 2;
const DROPS: usize = 3;
const CHECKSUM_ERRORS: usize = 4;
const FOREIGN: usize = 5;
const FIXES: usize = 6;
const REPEATS: usize = 7;
const FAILED: usize = 8;
const NO_FIXES: usize = 9;
/// How many of [`Counters`] the status line shows (all but `no_fixes`).
const SHOWN: usize = loc_proto::sink_line::STATUS_FIELDS;
/// How far back a report's sequence number counts as a repeat of its agent's rather than a
/// restart of the anchors' sequence.
pub const REPEAT_WINDOW: u16 = 16;

impl Counters {
    /// Seconds since boot, as the shell told the sink ([`Sink::add_uptime`]).
    pub fn uptime_s(&self) -> u32 {
        self.0[UPTIME]
    }
    /// Frames received.
    pub fn frames(&self) -> u32 {
        self.0[FRAMES]
    }
    /// Reports decoded.
    pub fn reports(&self) -> u32 {
        self.0[REPORTS]
    }
    /// Reports missing (gaps in an agent's sequence numbers).
    pub fn drops(&self) -> u32 {
        self.0[DROPS]
    }
    /// Frames that failed their checksum or did not decode.
    pub fn checksum_errors(&self) -> u32 {
        self.0[CHECKSUM_ERRORS]
    }
    /// Frames that are not hoploc messages (another PAN user, or another kind).
    pub fn foreign(&self) -> u32 {
        self.0[FOREIGN]
    }
    /// Fixes made.
    pub fn fixes(&self) -> u32 {
        self.0[FIXES]
    }
    /// Reports whose sequence number their agent had sent already (one of its last
    /// [`REPEAT_WINDOW`]): two agents with one id, or a replay.
    pub fn repeats(&self) -> u32 {
        self.0[REPEATS]
    }
    /// The agents' failed transmissions, as their reports said ([`ReportData::failed`]).
    pub fn failed(&self) -> u32 {
        self.0[FAILED]
    }
    /// Reports that gave no fix.
    pub fn no_fixes(&self) -> u32 {
        self.0[NO_FIXES]
    }
}

/// A frame the shell could not take as a report.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BadFrame {
    /// A hoploc message that failed to decode (checksum, length, values).
    Corrupt,
    /// Not a hoploc report.
    Foreign,
}

impl BadFrame {
    /// Why loc-proto could not decode a frame: not a hoploc message or not a kind this build
    /// speaks ([`Error::BadMagic`], [`Error::BadVersion`], [`Error::BadKind`]) is
    /// [`BadFrame::Foreign`]; anything else (checksum, length, values) is [`BadFrame::Corrupt`].
    pub fn of(e: Error) -> BadFrame {
        match e {
            Error::BadMagic | Error::BadVersion { .. } | Error::BadKind { .. } => BadFrame::Foreign,
            _ => BadFrame::Corrupt,
        }
    }
}

/// [`ReportView::accept`]'s reject, counted as [`BadFrame::of`] its error from
/// [`ReportView::parse`] (the firmware's parser).
impl From<NotReport> for BadFrame {
    fn from(r: NotReport) -> BadFrame {
        match r {
            NotReport::Corrupt => BadFrame::Corrupt,
            NotReport::Foreign => BadFrame::Foreign,
        }
    }
}

/// The room of a sink whose config `position` is `p` (a sink's position is the room's size, cm:
/// see `loc_proto::config`): `Some` area `[0, x] × [0, y]` when both are positive, else `None` —
/// the room is then the anchors' bounding box from the origin, per report ([`anchors_box`]).
pub fn room(p: Position) -> Option<AreaCm> {
    (p.x > 0 && p.y > 0).then(|| AreaCm::new(p.x as u16, p.y as u16))
}

/// The anchors' bounding box from the origin: `[0, max x] × [0, max y]` cm over `anchors`
/// (negative coordinates count as 0).
pub fn anchors_box(anchors: &[PointCm]) -> AreaCm {
    let mut a = AreaCm::new(0, 0);
    for &p in anchors {
        widen(&mut a, p);
    }
    a
}

/// `a` widened to take in `p` (negative coordinates count as 0).
fn widen(a: &mut AreaCm, p: PointCm) {
    a.width = a.width.max(p.x.max(0) as u16);
    a.height = a.height.max(p.y.max(0) as u16);
}

/// One report's estimates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Fix {
    /// The agent.
    pub agent: u8,
    /// The report's superframe sequence.
    pub seq: u16,
    /// The thesis MLE, then the windowed MMSE, which the search writes in place
    /// ([`Sink::on_report_with`]).
    pub estimates: [Estimate; 2],
    /// The path-loss model both used (after this report's fit and AR(1)).
    pub model: PathLoss,
    /// Whether this report's anchor-to-anchor RSSI gave a fit.
    pub fitted: bool,
}

impl Fix {
    /// A fix to be filled in ([`Sink::on_report_with`]).
    pub const NONE: Fix = Fix {
        agent: 0,
        seq: 0,
        estimates: [Estimate::NONE; 2],
        model: PathLoss { p0: 0, alpha: 0 },
        fitted: false,
    };

    /// The thesis MLE.
    pub fn mle(&self) -> &Estimate {
        &self.estimates[0]
    }

    /// The windowed MMSE.
    pub fn mmse(&self) -> &Estimate {
        &self.estimates[1]
    }

    /// The two `fix` lines (MLE, then MMSE) of loc-proto's [`SinkLine`]: cm rounded from mm,
    /// α and P0 in hundredths, rounded.
    pub fn lines(&self) -> [SinkLine; 2] {
        [self.line(Estimator::Mle), self.line(Estimator::Mmse)]
    }

    /// The `fix` line of `estimator`.
    pub fn line(&self, estimator: Estimator) -> SinkLine {
        let e = match estimator {
            Estimator::Mle => self.mle(),
            Estimator::Mmse => self.mmse(),
        };
        SinkLine::Fix {
            agent: self.agent,
            seq: self.seq,
            estimator,
            x: cm(e.pos.x),
            y: cm(e.pos.y),
            alpha_x100: centi(self.model.alpha.max(0), 24) as u16,
            p0_x100: centi(self.model.p0, 16) as i16,
            anchors: e.anchors,
            flags: if self.fitted { FLAG_FITTED } else { 0 },
        }
    }
}

/// Millimetres as whole centimetres, rounded (half up), saturating at `i16::MAX`: clamped
/// first (from 327 665 mm on the result is 32 767), so neither the sum nor the quotient needs a
/// check.
#[inline(never)]
fn cm(mm: u32) -> i16 {
    ((mm.min(327_665) + 5) / 10) as i16
}

/// `v·100 / 2^q` rounded (half up), `16 ≤ q ≤ 31`, for `|v| ≤ 2^30`, by the search's
/// [`mul_hi`] (the firmware links no other 32-bit multiply for it). With `b = 200·2^16`
/// (`bl = 0`) `mul_hi(a, b) = ⌊a·200 / 2^16⌋` exactly; `a = v + 2^31` is unsigned and adds
/// `200·2^15` to that. Then `n = ⌊200·v / 2^q⌋ + 100·2^(32−q)` (nested floors),
/// `⌊(n + 1) / 2⌋ = ⌊100·v / 2^q + 1/2⌋ + 100·2^(31−q)` (the offset is even), and the offset
/// goes. (A sink's α is within [`loc_core::fixed::ALPHA_LIMIT`] and its P0 within
/// [`loc_core::fixed::P0_LIMIT`], both below 2^30.)
fn centi(v: i32, q: u32) -> i32 {
    let n = mul_hi((v as u32) ^ (1 << 31), 200 << 16) >> (q - 16);
    ((n + 1) >> 1) as i32 - (100 << (31 - q))
}

/// The `nofix` line of agent `agent`'s report `seq` that failed with `e`.
pub fn no_fix_line(agent: u8, seq: u16, e: LocError) -> SinkLine {
    let usable = match e {
        LocError::TooFewAnchors { usable } => usable.min(u8::MAX as usize) as u8,
        _ => 0,
    };
    SinkLine::NoFix { agent, seq, usable }
}

impl Counters {
    /// Writes [`Counters::line`] onto `out`, the fields in a loop.
    pub fn write_line<W: ufmt::uWrite + ?Sized>(&self, out: &mut W) -> Result<(), W::Error> {
        let shown: &[u32; SHOWN] = self.0.first_chunk().unwrap_or(&[0; SHOWN]);
        write_status(shown, out)
    }

    /// The `status` line.
    pub fn line(&self) -> SinkLine {
        SinkLine::Status {
            uptime_s: self.uptime_s(),
            frames: self.frames(),
            reports: self.reports(),
            drops: self.drops(),
            checksum_errors: self.checksum_errors(),
            foreign: self.foreign(),
            fixes: self.fixes(),
            repeats: self.repeats(),
            failed: self.failed(),
        }
    }
}

/// The sink state machine.
#[derive(Clone, Debug)]
pub struct Sink {
    /// The room, or `None`: each report's anchors' bounding box.
    area: Option<AreaCm>,
    params: OnlineParams,
    counters: Counters,
    /// Next expected sequence per agent (index agent − 1), valid where `seen`.
    next_seq: [u16; MAX_AGENTS],
    /// Whether agent `k + 1` has reported.
    seen: [bool; MAX_AGENTS],
}

/// The sink's model at start: P0 and α by least squares within the thesis' bounds, from the
/// thesis' prior.
const START: OnlineParams = OnlineParams::new(
    ParamMode::P0AndAlpha,
    FitMethod::LeastSquares,
    Bounds::THESIS,
    PathLoss::THESIS,
);

impl Sink {
    /// A sink for the room `area` (`None`: each report's anchors' bounding box, [`anchors_box`];
    /// see [`room`]), estimating P0 and α by least squares within the thesis' bounds from the
    /// thesis' prior.
    pub fn new(area: Option<AreaCm>) -> Sink {
        Sink {
            area,
            params: START,
            counters: Counters::default(),
            next_seq: [0; MAX_AGENTS],
            seen: [false; MAX_AGENTS],
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

    /// `secs` more seconds since boot, for the status line's uptime.
    pub fn add_uptime(&mut self, secs: u8) {
        Self::add(&mut self.counters.0[UPTIME], secs.into());
    }

    /// `c + n` (one copy of the 32-bit addition for every counter).
    #[inline(never)]
    fn add(c: &mut u32, n: u16) {
        *c = c.wrapping_add(n as u32);
    }

    /// `c + 1`.
    fn bump(c: &mut u32) {
        Self::add(c, 1);
    }

    /// A frame that is not a usable report.
    pub fn on_bad_frame(&mut self, kind: BadFrame) {
        Self::bump(&mut self.counters.0[FRAMES]);
        Self::bump(
            &mut self.counters.0[match kind {
                BadFrame::Corrupt => CHECKSUM_ERRORS,
                BadFrame::Foreign => FOREIGN,
            }],
        );
    }

    /// A decoded report: as [`Sink::on_measurements`] of its [`measurements`] (the same
    /// result, `tests` checks), with the calibration statistics and the observations taken
    /// straight from the report.
    pub fn on_report(&mut self, r: &impl ReportData) -> Result<Fix, LocError> {
        self.on_report_with(r, |result| result.copied())
    }

    /// [`Sink::on_report`], its result handed to `then` (the firmware writes its lines from
    /// the fix where the search left it: no copies).
    pub fn on_report_with<T>(
        &mut self,
        r: &impl ReportData,
        then: impl FnOnce(Result<&Fix, LocError>) -> T,
    ) -> T {
        let mut fix = Fix::NONE;
        let result = {
            let (mut stats, mut obs) = (CalStats::new(), Observations::new());
            // `anchors_box` of the report's positions, from the same pass over it.
            let mut anchors = AreaCm::new(0, 0);
            report_inputs_into(r, &mut stats, &mut obs, &mut anchors);
            let area = self.area.unwrap_or(anchors);
            self.count(r.agent(), r.seq(), r.failed());
            self.locate(r.agent(), r.seq(), area, &stats, &obs, &mut fix)
        };
        then(result.map(|()| &fix))
    }

    /// Agent `agent`'s report of superframe `seq`, as measurements: fit, smooth, locate.
    pub fn on_measurements(
        &mut self,
        agent: u8,
        seq: u16,
        m: &Measurements,
    ) -> Result<Fix, LocError> {
        let stats = CalStats::from_measurements(m, None);
        let obs = observations(m, Refinement::Extended);
        let area = self
            .area
            .unwrap_or_else(|| anchors_box(&m.anchors[..m.n_anchors]));
        let mut fix = Fix::NONE;
        self.count(agent, seq, 0);
        self.locate(agent, seq, area, &stats, &obs, &mut fix)
            .map(|()| fix)
    }

    /// The counters of agent `agent`'s report `seq`, which says `failed` transmissions failed
    /// before it: a frame, a report; the reports missing before it (a sequence
    /// number past the next expected one); a repeat (one of the agent's last
    /// [`REPEAT_WINDOW`] sequence numbers again: another sender with its id, or a replay); a
    /// sequence number further back is the anchors' timeline starting over (they were reset)
    /// and counts as nothing. Out of line: one copy for both paths.
    #[inline(never)]
    fn count(&mut self, agent: u8, seq: u16, failed: u8) {
        let c = &mut self.counters.0;
        Self::bump(&mut c[FRAMES]);
        Self::bump(&mut c[REPORTS]);
        Self::add(&mut c[FAILED], failed.into());
        let k = agent.wrapping_sub(1) as usize;
        if let (Some(next), Some(seen)) = (self.next_seq.get_mut(k), self.seen.get_mut(k)) {
            let gap = seq.wrapping_sub(*next);
            if *seen && gap < 0x8000 {
                Self::add(&mut c[DROPS], gap);
            } else if *seen && next.wrapping_sub(seq) <= REPEAT_WINDOW {
                Self::bump(&mut c[REPEATS]);
                return;
            }
            *seen = true;
            *next = seq.wrapping_add(1);
        }
    }

    /// The least-squares fit of `stats` fed to the AR(1) smoothers, then both estimates of
    /// `obs` from one search, into `fix`.
    #[inline(never)]
    fn locate(
        &mut self,
        agent: u8,
        seq: u16,
        area: AreaCm,
        stats: &CalStats,
        obs: &Observations,
        fix: &mut Fix,
    ) -> Result<(), LocError> {
        // The least-squares fit from the current model, fed to the smoothers (a round without
        // samples keeps the model).
        let p = &self.params;
        let fitted = match fit_least_squares(stats, p.mode, p.current(), &p.bounds) {
            Ok(f) => {
                self.params.feed(&f);
                true
            }
            Err(_) => false,
        };
        let model = self.params.current();
        let sigma = self.params.sigma().unwrap_or(DEFAULT_SIGMA);
        (fix.agent, fix.seq, fix.model, fix.fitted) = (agent, seq, model, fitted);
        let result =
            mle_and_mmse_window_into::<Native>(obs, model, area, sigma, &mut fix.estimates);
        Self::bump(
            &mut self.counters.0[match result {
                Ok(_) => FIXES,
                Err(_) => NO_FIXES,
            }],
        );
        result
    }
}

/// What [`Sink::on_report`] works from, straight from the report's bytes: the calibration
/// statistics of every anchor pair (both directions' relayed bytes, as
/// [`CalStats::from_measurements`] of [`measurements`]) and the agent's observations under the
/// Extended refinement (as [`observations`]).
pub fn report_inputs(r: &impl ReportData) -> (CalStats, Observations) {
    let (mut stats, mut obs, mut area) = (CalStats::new(), Observations::new(), AreaCm::new(0, 0));
    report_inputs_into(r, &mut stats, &mut obs, &mut area);
    (stats, obs)
}

/// [`report_inputs`] added to `stats` and `obs`, and `area` widened to every anchor's
/// position ([`anchors_box`]), in place: every anchor pair's relayed bytes (both directions)
/// into `stats`, each anchor's Extended refinement into `obs`.
pub fn report_inputs_into(
    r: &impl ReportData,
    stats: &mut CalStats,
    obs: &mut Observations,
    area: &mut AreaCm,
) {
    let n = r.anchors();
    let c = r.channels();
    // Without the relay matrix every byte is 0 (not heard): no samples.
    for i in 0..n {
        for j in i + 1..n {
            let mut bytes = [0; 2 * loc_core::MAX_CHANNELS];
            for ch in 0..c {
                bytes[ch] = r.relay(ch, i, j);
                bytes[loc_core::MAX_CHANNELS + ch] = r.relay(ch, j, i);
            }
            stats.push_pair_bytes(r.position(i), r.position(j), &bytes);
        }
    }
    for i in 0..n {
        widen(area, r.position(i));
        let mut bytes = [0u8; loc_core::MAX_CHANNELS];
        for (ch, v) in bytes[..c].iter_mut().enumerate() {
            *v = r.rssi(ch, i);
        }
        if let Some((z, weight, spread)) = extended(&bytes) {
            obs.const_cost = obs.const_cost.saturating_add(spread);
            obs.push(Obs {
                pos: r.position(i),
                z,
                weight,
            });
        }
    }
}

#[cfg(test)]
mod tests;
