//! Anchor health: does each anchor's anchor-to-anchor RSSI agree with its configured position?
//!
//! Every report carries the anchors' configured positions and the RSSI each anchor measured
//! from every other (the relay matrix, per channel). An anchor configured at one place but
//! standing at another biases every fix without a word from the sink, which trusts the
//! positions. [`Health`] reads the reports (sans-IO: [`Health::push`] per report and
//! [`Health::assess`] when a verdict is wanted, or [`Health::on_report`] for both) and names an
//! anchor whose links contradict its position. `hoploc replay` prints every change of its
//! verdict and its verdict at the end of the log; `hoploc monitor` calls [`Health::on_report`]
//! per `report` line and prints a row when the verdict changes.
//!
//! # The rule
//!
//! 1. **Link levels.** Over a sliding window of [`HealthConfig::window`] reports, each ordered
//!    anchor pair and channel gets the mean of its relayed RSSI, and each link (unordered pair)
//!    the mean of its directions and channels. Averaging removes the per-packet noise; what
//!    stays is the link's static error (multipath fading per channel, antenna patterns), which
//!    no amount of waiting removes: that is the noise the rule must tolerate. A link heard in
//!    fewer than half of the window's reports with a relay matrix is left out (near the
//!    sensitivity only the strongest packets arrive, and their mean is biased high), and so is
//!    a link to an anchor no report has given a position for (one the agent has not heard).
//! 2. **Model.** The path-loss model (P0, α) is fitted to the links at their configured lengths
//!    by loc-core's least-squares fit within the thesis bounds ([`loc_core::params::fit`], as
//!    the sink fits it); `SSE₀` is the sum of its squared residuals, dB².
//! 3. **Each anchor moved.** For each anchor *k* the same fit is made with *k* placed at every
//!    point of loc-core's fine lattice ([`loc_core::grid::search_lattice`], exhaustive) over
//!    the anchors' bounding box widened by [`HealthConfig::margin`] on every side, P0 and α
//!    refitted at each point, then on a ten times finer lattice around the best point. That
//!    point, `p̂ₖ`, is where *k*'s links place it; `SSE₁ₖ` is the fit's squared residuals there.
//!    `ΔSSEₖ = SSE₀ − SSE₁ₖ ≥ 0` is how much better the links fit with *k* at `p̂ₖ`: under
//!    Gaussian link errors of variance σ², `ΔSSEₖ / σ²` is the generalised likelihood ratio
//!    statistic of "*k* stands elsewhere", about χ² with 2 degrees of freedom when it does not.
//!    That ratio is the anchor's *score*.
//! 4. **Decision.** The anchor with the largest `ΔSSEₖ` is flagged when its score exceeds
//!    [`HealthConfig::threshold`] and `p̂ₖ` is at least [`HealthConfig::min_offset_m`] from its
//!    configured position. σ² is the link error the rule assumes, [`HealthConfig::fading_db`]²
//!    over the number of channels (a link's level averages its channels' independent fading),
//!    raised to the residual error of the fit with the anchor moved, `SSE₁ₖ / (L − 4)` over the
//!    `L` links, when that is larger: a room whose links scatter more than assumed raises its
//!    own bar. Once an anchor is flagged its links are dropped and the rule runs again on the
//!    others, so several anchors can be named when enough remain.
//!
//! Only one anchor is flagged per round because a misplaced anchor spoils its neighbours'
//! links too: each neighbour shares one link with it, and moving the neighbour explains part of
//! that link's error, while moving the misplaced anchor explains all of its links.
//!
//! An anchor is judged when it has at least 3 links and at least 3 links do not involve it
//! (with fewer, moving it fits its links exactly and there is nothing left to test). So 4
//! anchors are the fewest that can name one, and 4 name at most one.
//!
//! **3 anchors**: three links and a model of two parameters leave one degree of freedom.
//! Moving any one anchor changes two of the three links, and a fit with its position free (two
//! more unknowns) matches the three links exactly whichever anchor it is: no anchor can be
//! named, and [`Assessment::no_verdict`] says so. [`Assessment::links_rms_db`] still shows how
//! far the links disagree with the layout as a whole.
//!
//! # What it reports
//!
//! Per anchor ([`AnchorCheck`]): its links, `p̂ₖ` and its distance from the configured position
//! (metres), the RMS residual in dB of its links at its configured position under the model
//! fitted with it at `p̂ₖ`, and the score. A flag ([`Flag`]) names the anchor with those
//! figures. No verdict is given before [`HealthConfig::min_reports`] reports with a relay
//! matrix, and a new window starts when the anchor count, the channels or an anchor's
//! configured position change.
//!
//! # False alarms and the detection limit
//!
//! The rule's noise is each link's static error, so its false alarms are a property of the
//! room, not of time: a room whose fading happens to mimic a moved anchor keeps it flagged for
//! as long as nothing changes, and one that does not never flags. When the rule's σ matches the
//! room, the chance that a room flags an anchor is about the number of anchors times
//! `exp(−threshold / 2)`, a few in 10⁴ with the default threshold; a room with more multipath
//! than assumed raises the residual part of σ, which keeps most of it quiet, not all. The unit
//! tests count false alarms on synthetic rooms; `cargo bench -p hoploc --bench anchor_health`
//! measures them and the detection rates (the figures are in the README).
//!
//! The signal is small beside that noise. A link of length `d` changes by about
//! `10·α/ln 10 · δ/d` dB when one end moves by `δ` along it, and the refitted P0 (and α) take up
//! the part of the change that all links share: with 4 anchors half of the links involve the
//! moved one. So with 4 corner anchors, 2 channels and the emulated testbed's fading, even a
//! corner anchor standing more than 5 m inside the room misfits its links less than the fading
//! alone does in a fair share of correct rooms, and is seldom flagged; a fifth anchor, more
//! channels or a room with less multipath make it clear. Half a metre is below the limit in
//! every one of them. When the rule flags an anchor it is the misplaced one but for a few per
//! cent of rooms, where a neighbour of it fits the links better moved.
//!
//! An assessment refits the model at every lattice point for every anchor, so
//! [`Health::on_report`] makes one every [`HealthConfig::every`] reports, not per report.

use std::collections::VecDeque;
use std::fmt;

use loc_core::grid::{lattice_point, search_lattice, Search, FINE_DIVS};
use loc_core::params::{fit, Bounds, CalStats, FitMethod, ParamFit, ParamMode};
use loc_core::{Area, PathLoss, Point, MAX_ANCHORS, MAX_CHANNELS};
use loc_proto::msg::{ChannelList, Report};
use loc_proto::sink_line::SinkOutput;

pub mod synthetic;

/// The rule's settings (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HealthConfig {
    /// Reports the link levels are averaged over.
    pub window: usize,
    /// Reports with a relay matrix needed before any verdict.
    pub min_reports: usize,
    /// σ of a link's static error on one channel that the rule assumes, dB (the emulated
    /// testbed's fading by default).
    pub fading_db: f64,
    /// Score above which the worst anchor is flagged.
    pub threshold: f64,
    /// Smallest distance between the estimated and the configured position that is flagged, m.
    pub min_offset_m: f64,
    /// The search area's margin around the anchors' bounding box, as a fraction of its longer
    /// side.
    pub margin: f64,
    /// [`Health::on_report`] assesses every this many reports.
    pub every: usize,
}

impl Default for HealthConfig {
    fn default() -> Self {
        HealthConfig {
            window: 50,
            min_reports: 20,
            fading_db: 3.0,
            threshold: 20.0,
            min_offset_m: 1.0,
            margin: 0.3,
            every: 5,
        }
    }
}

/// Smallest σ² of a link's level, dB²: a level is read in whole dBm, and with no noise to
/// dither it the mean keeps the rounding (uniform over ±0.5 dB).
const MIN_SIGMA2: f64 = 1.0 / 12.0;

/// One anchor's check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnchorCheck {
    /// The anchor's id (1…8).
    pub id: u8,
    /// Its configured position, m.
    pub configured: Point,
    /// Its links in the window.
    pub links: usize,
    /// What the test found; `None` when it cannot be judged (too few links, see the module
    /// docs).
    pub test: Option<AnchorTest>,
}

/// The test of one anchor (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnchorTest {
    /// Where its links place it, m.
    pub estimate: Point,
    /// Distance from the configured position to the estimate, m.
    pub offset_m: f64,
    /// RMS residual of its links at the configured position under the model fitted with it at
    /// the estimate, dB.
    pub residual_db: f64,
    /// `ΔSSE / σ²`.
    pub score: f64,
}

/// A flagged anchor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Flag {
    /// The anchor's id (1…8).
    pub id: u8,
    /// Its configured position, m.
    pub configured: Point,
    /// The test that flagged it.
    pub test: AnchorTest,
}

impl fmt::Display for Flag {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (c, e) = (self.configured, self.test.estimate);
        write!(
            f,
            "anchor {} configured at ({:.2}, {:.2}) m, its links place it at ({:.2}, {:.2}) m: \
             {:.1} m away, {:.1} dB RMS residual, score {:.0}",
            self.id, c.x, c.y, e.x, e.y, self.test.offset_m, self.test.residual_db, self.test.score
        )
    }
}

/// Why an assessment gives no verdict.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoVerdict {
    /// Fewer than [`HealthConfig::min_reports`] reports with a relay matrix in the window.
    TooFewReports {
        /// Reports with a relay matrix in the window.
        have: usize,
        /// Needed.
        need: usize,
    },
    /// No anchor can be judged: fewer than 4 anchors with enough links (see the module docs).
    TooFewLinks,
}

impl fmt::Display for NoVerdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NoVerdict::TooFewReports { have, need } => {
                write!(f, "{have} of {need} reports with anchor-to-anchor RSSI")
            }
            NoVerdict::TooFewLinks => f.write_str(
                "no anchor can be judged: it takes 4 anchors with at least 3 links heard each",
            ),
        }
    }
}

/// The anchors' health over the current window.
#[derive(Clone, Debug, PartialEq)]
pub struct Assessment {
    /// Reports with a relay matrix in the window.
    pub reports: usize,
    /// Links with a level.
    pub links: usize,
    /// The model fitted to every link at the configured positions (`None` without links).
    pub model: Option<PathLoss>,
    /// RMS residual of every link under that model, dB (`None` without links).
    pub links_rms_db: Option<f64>,
    /// Every anchor whose position is known, in id order, as the rule's first round (every
    /// link in) judged it.
    pub anchors: Vec<AnchorCheck>,
    /// The flagged anchors, in the order the rule found them.
    pub flags: Vec<Flag>,
    /// Why there is no verdict, if there is none (then `flags` is empty).
    pub no_verdict: Option<NoVerdict>,
}

impl Assessment {
    /// The verdict and a row per anchor, for a report.
    pub fn summary(&self) -> String {
        let mut s = match self.no_verdict {
            Some(why) => format!("anchor health: no verdict ({why})\n"),
            None if self.flags.is_empty() => format!(
                "anchor health: no anchor flagged ({} reports, {} links)\n",
                self.reports, self.links
            ),
            None => self
                .flags
                .iter()
                .map(|f| format!("anchor health: FLAGGED {f}\n"))
                .collect(),
        };
        if let (Some(m), Some(rms)) = (self.model, self.links_rms_db) {
            s += &format!(
                "  model of {} links at the configured positions: P0 {:.1} dBm, α {:.2}, \
                 {:.1} dB RMS residual\n",
                self.links, m.p0, m.alpha, rms
            );
        }
        if !self.anchors.is_empty() {
            s += "  anchor  configured (m)    links  placed by its links (m)   offset  residual  score\n";
        }
        for a in &self.anchors {
            let c = a.configured;
            s += &format!("  {:>6}  ({:6.2}, {:6.2})  {:>5}", a.id, c.x, c.y, a.links);
            s += &match a.test {
                Some(t) => format!(
                    "  ({:6.2}, {:6.2})          {:5.1} m  {:5.1} dB  {:5.1}\n",
                    t.estimate.x, t.estimate.y, t.offset_m, t.residual_db, t.score
                ),
                None => "  not judged: too few links\n".to_string(),
            };
        }
        s
    }
}

/// A change of verdict, from [`Health::on_report`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HealthEvent {
    /// An anchor is newly flagged.
    Flagged(Flag),
    /// An anchor flagged before is not any more.
    Cleared {
        /// The anchor's id.
        id: u8,
    },
}

impl fmt::Display for HealthEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HealthEvent::Flagged(flag) => write!(f, "anchor health: FLAGGED {flag}"),
            HealthEvent::Cleared { id } => {
                write!(f, "anchor health: anchor {id} no longer flagged")
            }
        }
    }
}

/// One report's relay matrix, as sent (−dBm, 0 = not heard).
type Relay = [[[u8; MAX_ANCHORS]; MAX_ANCHORS]; MAX_CHANNELS];

/// The health check over a stream of reports.
#[derive(Clone, Debug)]
pub struct Health {
    cfg: HealthConfig,
    /// The layout the window belongs to: anchor count and channels.
    layout: Option<(u8, ChannelList)>,
    /// Each anchor's configured position, from the reports that heard it.
    positions: [Option<Point>; MAX_ANCHORS],
    /// The window: each report's relay matrix (`None` for a report without one).
    window: VecDeque<Option<Box<Relay>>>,
    /// Reports since [`Health::on_report`] last assessed.
    since: usize,
    /// The anchors flagged at [`Health::on_report`]'s last verdict.
    flagged: Vec<u8>,
    /// Whether [`Health::on_report`]'s last assessment gave a verdict.
    judged: bool,
}

impl Default for Health {
    fn default() -> Self {
        Health::new(HealthConfig::default())
    }
}

impl Health {
    /// A check with settings `cfg`.
    pub fn new(cfg: HealthConfig) -> Health {
        Health {
            cfg,
            layout: None,
            positions: [None; MAX_ANCHORS],
            window: VecDeque::new(),
            since: 0,
            flagged: Vec::new(),
            judged: false,
        }
    }

    /// The settings.
    pub fn config(&self) -> &HealthConfig {
        &self.cfg
    }

    /// Takes report `r` into the window. Another anchor count or channel list than the
    /// window's, or an anchor at another configured position, starts a new window.
    pub fn push(&mut self, r: &Report) {
        let n = (r.anchors as usize).min(MAX_ANCHORS);
        let c = r.channels.len().min(MAX_CHANNELS);
        if self.layout != Some((r.anchors, r.channels)) {
            self.layout = Some((r.anchors, r.channels));
            self.positions = [None; MAX_ANCHORS];
            self.window.clear();
        }
        for i in 0..n {
            // A report gives the position of an anchor whose beacon the agent heard.
            let heard = (0..c).any(|ch| {
                r.rssi[ch][i] != 0 || (r.has_relay && r.relay[ch][i][..n].iter().any(|&b| b != 0))
            });
            if !heard {
                continue;
            }
            let p = Point::new(
                f64::from(r.positions[i].x) / 100.0,
                f64::from(r.positions[i].y) / 100.0,
            );
            if self.positions[i].is_some_and(|q| q != p) {
                self.window.clear();
            }
            self.positions[i] = Some(p);
        }
        let relay = r.has_relay.then(|| {
            let mut m: Box<Relay> = Box::new([[[0; MAX_ANCHORS]; MAX_ANCHORS]; MAX_CHANNELS]);
            for (ch, rows) in m.iter_mut().enumerate().take(c) {
                for (i, row) in rows.iter_mut().enumerate().take(n) {
                    row[..n].copy_from_slice(&r.relay[ch][i][..n]);
                    // What an anchor says of itself is not a measurement.
                    row[i] = 0;
                }
            }
            m
        });
        self.window.push_back(relay);
        while self.window.len() > self.cfg.window.max(1) {
            self.window.pop_front();
        }
    }

    /// Pushes `r`; every [`HealthConfig::every`] reports assesses the window and returns what
    /// changed since the last verdict (anchors newly flagged, anchors cleared): the hook for a
    /// loop that sees one report at a time. An assessment without a verdict (a window still
    /// filling) changes nothing.
    pub fn on_report(&mut self, r: &Report) -> Vec<HealthEvent> {
        self.push(r);
        self.since += 1;
        if self.since < self.cfg.every.max(1) {
            return Vec::new();
        }
        self.since = 0;
        let a = self.assess();
        self.judged = a.no_verdict.is_none();
        if !self.judged {
            return Vec::new();
        }
        let now: Vec<u8> = a.flags.iter().map(|f| f.id).collect();
        let mut events: Vec<HealthEvent> = a
            .flags
            .iter()
            .filter(|f| !self.flagged.contains(&f.id))
            .map(|f| HealthEvent::Flagged(*f))
            .collect();
        events.extend(
            self.flagged
                .iter()
                .filter(|id| !now.contains(id))
                .map(|&id| HealthEvent::Cleared { id }),
        );
        self.flagged = now;
        events
    }

    /// [`Health::on_report`] for a line of the sink: a `report` line's report, or nothing
    /// (any other line, a damaged one, a report that does not decode).
    pub fn on_line(&mut self, line: &str) -> Vec<HealthEvent> {
        match SinkOutput::parse(line.trim_end_matches(['\r', '\n'])) {
            Ok(SinkOutput::Report(raw)) => match raw.report() {
                Ok(r) => self.on_report(&r),
                Err(_) => Vec::new(),
            },
            _ => Vec::new(),
        }
    }

    /// The anchors flagged at [`Health::on_report`]'s last verdict.
    pub fn flagged(&self) -> &[u8] {
        &self.flagged
    }

    /// Whether [`Health::on_report`]'s last assessment gave a verdict (a window with enough
    /// reports and links); [`Health::flagged`] is that verdict.
    pub fn judged(&self) -> bool {
        self.judged
    }

    /// The window's reports with a relay matrix, and its links.
    #[allow(clippy::needless_range_loop)] // a link is [i][j] and [j][i] together
    fn links(&self) -> (usize, Vec<Link>) {
        let Some((n, channels)) = self.layout else {
            return (0, Vec::new());
        };
        let n = (n as usize).min(MAX_ANCHORS);
        let c = channels.len().min(MAX_CHANNELS);
        let reports = self.window.iter().flatten().count();
        // Per ordered pair and channel: the sum of the levels and their count; per link: the
        // reports that heard it at all.
        let mut sum = [[[0.0f64; MAX_CHANNELS]; MAX_ANCHORS]; MAX_ANCHORS];
        let mut count = [[[0u32; MAX_CHANNELS]; MAX_ANCHORS]; MAX_ANCHORS];
        let mut heard = [[0usize; MAX_ANCHORS]; MAX_ANCHORS];
        for m in self.window.iter().flatten() {
            for i in 0..n {
                for j in i + 1..n {
                    let mut any = false;
                    for ch in 0..c {
                        for (a, b) in [(i, j), (j, i)] {
                            let v = m[ch][a][b];
                            if v != 0 {
                                sum[a][b][ch] -= f64::from(v);
                                count[a][b][ch] += 1;
                                any = true;
                            }
                        }
                    }
                    heard[i][j] += usize::from(any);
                }
            }
        }
        let mut links = Vec::new();
        for i in 0..n {
            for j in i + 1..n {
                let (Some(pi), Some(pj)) = (self.positions[i], self.positions[j]) else {
                    continue;
                };
                if heard[i][j] == 0 || 2 * heard[i][j] < reports {
                    continue;
                }
                let means: Vec<f64> = (0..c)
                    .flat_map(|ch| [(i, j, ch), (j, i, ch)])
                    .filter(|&(a, b, ch)| count[a][b][ch] > 0)
                    .map(|(a, b, ch)| sum[a][b][ch] / f64::from(count[a][b][ch]))
                    .collect();
                links.push(Link {
                    a: i,
                    b: j,
                    d: pi.dist(pj),
                    level: means.iter().sum::<f64>() / means.len() as f64,
                });
            }
        }
        (reports, links)
    }

    /// The verdict over the current window (the rule is in the module docs).
    pub fn assess(&self) -> Assessment {
        let (reports, links) = self.links();
        let channels = self
            .layout
            .map_or(1, |(_, c)| c.len().clamp(1, MAX_CHANNELS));
        let mut out = Assessment {
            reports,
            links: links.len(),
            model: None,
            links_rms_db: None,
            anchors: Vec::new(),
            flags: Vec::new(),
            no_verdict: None,
        };
        if let Some(f) = fit_links(links.iter().map(|l| (l.d, l.level))) {
            out.model = Some(f.model);
            out.links_rms_db = Some((f.sse / f.n.max(1) as f64).sqrt());
        }
        let known: Vec<(usize, Point)> = self
            .positions
            .iter()
            .enumerate()
            .filter_map(|(i, p)| p.map(|p| (i, p)))
            .collect();
        let ctx = Context {
            area: search_area(&known, self.cfg.margin),
            positions: &self.positions,
            sigma2: (self.cfg.fading_db * self.cfg.fading_db / channels as f64).max(MIN_SIGMA2),
            cfg: &self.cfg,
        };
        let mut active = links;
        // A round flags an anchor with links and drops them, so at most one round per anchor.
        for first in (0..=known.len()).map(|r| r == 0) {
            let round = ctx.judge(&active, &known);
            if first {
                out.anchors = round.checks;
                if round.judged == 0 {
                    out.no_verdict = Some(NoVerdict::TooFewLinks);
                }
            }
            let Some(f) = round.flag else { break };
            let k = usize::from(f.id.saturating_sub(1));
            active.retain(|l| l.a != k && l.b != k);
            out.flags.push(f);
        }
        if reports < self.cfg.min_reports {
            out.flags.clear();
            out.no_verdict = Some(NoVerdict::TooFewReports {
                have: reports,
                need: self.cfg.min_reports,
            });
        }
        out
    }
}

/// A link's window level at its configured length.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Link {
    /// Its anchors' indices (0-based), `a < b`.
    a: usize,
    b: usize,
    /// Configured length, m.
    d: f64,
    /// Mean level, dBm.
    level: f64,
}

/// loc-core's least-squares fit of P0 and α (the sink's: the thesis' prior and bounds).
fn fit_stats(s: &CalStats) -> Option<ParamFit> {
    fit(
        s,
        ParamMode::P0AndAlpha,
        FitMethod::LeastSquares,
        PathLoss::THESIS,
        &Bounds::THESIS,
    )
    .ok()
}

/// [`fit_stats`] of (distance m, level dBm) samples.
fn fit_links(samples: impl IntoIterator<Item = (f64, f64)>) -> Option<ParamFit> {
    let mut s = CalStats::new();
    for (d, z) in samples {
        s.push(d, z);
    }
    fit_stats(&s)
}

/// The area searched for a moved anchor: the known anchors' bounding box widened by `margin`
/// of its longer side on every side, as its origin and a loc-core [`Area`] from there.
fn search_area(known: &[(usize, Point)], margin: f64) -> (Point, Area) {
    let Some(&(_, first)) = known.first() else {
        return (Point::default(), Area::new(1.0, 1.0));
    };
    let (mut lo, mut hi) = (first, first);
    for &(_, p) in known {
        lo = Point::new(lo.x.min(p.x), lo.y.min(p.y));
        hi = Point::new(hi.x.max(p.x), hi.y.max(p.y));
    }
    let side = (hi.x - lo.x).max(hi.y - lo.y).max(1.0);
    let m = side * margin.clamp(0.0, 10.0);
    (
        Point::new(lo.x - m, lo.y - m),
        Area::new(hi.x - lo.x + 2.0 * m, hi.y - lo.y + 2.0 * m),
    )
}

/// What every round of the rule shares.
struct Context<'a> {
    /// The search area: origin and extent.
    area: (Point, Area),
    positions: &'a [Option<Point>; MAX_ANCHORS],
    /// The assumed σ² of a link's level, dB².
    sigma2: f64,
    cfg: &'a HealthConfig,
}

/// One round of the rule.
struct Round {
    checks: Vec<AnchorCheck>,
    /// Anchors judged.
    judged: usize,
    flag: Option<Flag>,
}

impl Context<'_> {
    /// The rule's round over `links`: every known anchor judged, the worst flagged if the
    /// decision says so.
    fn judge(&self, links: &[Link], known: &[(usize, Point)]) -> Round {
        let mut round = Round {
            checks: Vec::new(),
            judged: 0,
            flag: None,
        };
        let f0 = fit_links(links.iter().map(|l| (l.d, l.level)));
        // The anchor with the largest ΔSSE so far (the best fit with one anchor moved), and it.
        let mut worst: Option<(f64, Flag)> = None;
        for &(k, configured) in known {
            let mine = links.iter().filter(|l| l.a == k || l.b == k).count();
            let mut check = AnchorCheck {
                id: k as u8 + 1,
                configured,
                links: mine,
                test: None,
            };
            if let (Some(f0), true) = (f0, mine >= 3 && links.len() - mine >= 3) {
                let (test, delta) = self.test(k, configured, links, &f0);
                check.test = Some(test);
                round.judged += 1;
                if worst.is_none_or(|(d, _)| delta > d) {
                    let flag = Flag {
                        id: check.id,
                        configured,
                        test,
                    };
                    worst = Some((delta, flag));
                }
            }
            round.checks.push(check);
        }
        round.flag = worst.map(|(_, f)| f).filter(|f| {
            f.test.score > self.cfg.threshold && f.test.offset_m >= self.cfg.min_offset_m
        });
        round
    }

    /// Anchor `k` (configured at `configured`) moved: its test and its ΔSSE. `f0` is the fit of
    /// `links` at the configured positions.
    fn test(
        &self,
        k: usize,
        configured: Point,
        links: &[Link],
        f0: &ParamFit,
    ) -> (AnchorTest, f64) {
        let mut others = CalStats::new();
        // The other end of each of k's links, and the link's level.
        let mut ends: Vec<(Point, f64)> = Vec::new();
        for l in links {
            if l.a == k || l.b == k {
                let other = if l.a == k { l.b } else { l.a };
                if let Some(p) = self.positions[other] {
                    ends.push((p, l.level));
                }
            } else {
                others.push(l.d, l.level);
            }
        }
        let with_k_at = |p: Point| {
            let mut s = others;
            for &(q, z) in &ends {
                s.push(p.dist(q), z);
            }
            fit_stats(&s)
        };
        let sse_at = |p: Point| with_k_at(p).map_or(f64::INFINITY, |f| f.sse);
        let (origin, area) = self.area;
        let point = |i: usize, j: usize| {
            let p = lattice_point(area, i, j);
            Point::new(origin.x + p.x, origin.y + p.y)
        };
        let m = search_lattice(Search::Exhaustive, |i, j| sse_at(point(i, j)));
        let (mut best, mut sse1) = (point(m.i, m.j), m.cost);
        // A ten times finer lattice over the best point's neighbourhood.
        let step = (
            area.width / FINE_DIVS as f64 / 10.0,
            area.height / FINE_DIVS as f64 / 10.0,
        );
        let centre = best;
        for di in -10..=10 {
            for dj in -10..=10 {
                let p = Point::new(
                    centre.x + f64::from(di) * step.0,
                    centre.y + f64::from(dj) * step.1,
                );
                let e = sse_at(p);
                if e < sse1 {
                    (best, sse1) = (p, e);
                }
            }
        }
        // Where it is configured is a candidate too: ΔSSE ≥ 0.
        if sse1 >= f0.sse {
            (best, sse1) = (configured, f0.sse);
        }
        let model = with_k_at(best).map_or(f0.model, |f| f.model);
        let residual_db = (ends
            .iter()
            .map(|&(q, z)| (z - model.rssi_at(configured.dist(q))).powi(2))
            .sum::<f64>()
            / ends.len().max(1) as f64)
            .sqrt();
        let dof = links.len().saturating_sub(4);
        let sigma2 = if dof > 0 {
            self.sigma2.max(sse1 / dof as f64)
        } else {
            self.sigma2
        };
        let delta = f0.sse - sse1;
        let test = AnchorTest {
            estimate: best,
            offset_m: best.dist(configured),
            residual_db,
            score: delta / sigma2,
        };
        (test, delta)
    }
}

#[cfg(test)]
mod tests;
