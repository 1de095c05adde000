//! `hoploc replay`: a recorded sink log run through every host estimator.
//!
//! The sink writes a `report` line (the agent's report message, loc-proto's
//! [`loc_proto::sink_line::RawReport`]) before the `fix` lines of each report, so a log holds
//! the raw measurements. [`Replay`] reads a log line by line (sans-IO: the command feeds it a
//! file or stdin) and, per report, does what the sink does on the host in `f64` — a
//! least-squares P0/α fit of the relayed anchor-to-anchor RSSI smoothed by AR(1) over the log,
//! the Extended refinement — then locates the agent with every host algorithm: the thesis MLE,
//! the windowed and the full-lattice MMSE, the MLE with the thesis' fixed P0 = −40 dBm and α = 3,
//! trilateration, quadlateration and MDS-MAP; the sink's own `fix` lines are tallied next to
//! them (`sink MLE`, `sink MMSE`).
//!
//! Ground truth comes from `--truth X,Y` or from `# truth X Y` lines in the log (metres; the demo
//! writes them when the agent moves; `# truth none` clears it). Any other line — boot lines,
//! comments, noise — is counted and skipped; a damaged sink line (bad checksum, or bytes that
//! show damage: [`crate::framing::classify`]) is counted, never believed. The log is cut into
//! lines as `hoploc monitor` cuts the port's bytes ([`crate::framing::Framer`]): a good line
//! right after noise is found again, and a line too long is dropped and counted.
//!
//! The reports also go through the anchor health check ([`crate::health`]): whether each
//! anchor's anchor-to-anchor RSSI agrees with its configured position. The summary lists every
//! change of its verdict (an anchor flagged or cleared, with the report it came at) and its
//! verdict over the log's last window, with a row per anchor.

use std::io::Read;
use std::path::PathBuf;

use loc_core::baselines::Baseline;
use loc_core::grid::{self, Search};
use loc_core::params::{Bounds, FitMethod, OnlineParams, ParamMode};
use loc_core::refine::{observations, Refinement};
use loc_core::{Area, Measurements, PathLoss, Point, MAX_ANCHORS, MAX_CHANNELS};
use loc_proto::msg::Report;
use loc_proto::sink_line::{Estimator, SinkLine, SinkOutput};

use crate::framing::{classify, Class, Framed, Framer};
use crate::health::{Health, HealthConfig, HealthEvent};
use crate::out::Out;
use crate::outln;
use crate::tally::Tally;
use crate::web::{Event, Feed, Fix, Setup, Status, Web, WebArgs};

/// σ of the MMSE estimates while no fit gave one, dB (the sink's default, the thesis' larger σ).
pub const DEFAULT_SIGMA_DB: f64 = 4.0;

/// The host algorithms, in table order.
pub const HOST_ALGOS: [&str; 7] = [
    "MLE",
    "MMSE-win",
    "MMSE",
    "MLE-fixed",
    "TRLT-3",
    "QUAD-4",
    "MDS",
];

/// `hoploc replay` options.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// The sink log (`-`: stdin), e.g. saved by `hoploc monitor --log`.
    pub log: PathBuf,
    /// The agent's true position, metres, for the whole log (`# truth X Y` lines in the log
    /// override it from where they appear).
    #[arg(long, value_parser = parse_point)]
    pub truth: Option<Point>,
    /// The room, metres (`WxH`) [default: each report's anchors' bounding box, as the sink].
    #[arg(long, value_parser = parse_area)]
    pub area: Option<Area>,
    /// Write the fixes-versus-truth plot (replay.svg, replay.png) into this directory.
    #[arg(long)]
    pub out_dir: Option<PathBuf>,
    /// The anchor health check's assumption: σ of a link's static error on one channel, dB
    /// (the fading of the room; the emulated testbed's is 3). Smaller flags smaller offsets,
    /// and more false alarms in a room with more multipath.
    #[arg(long, default_value_t = HealthConfig::default().fading_db, value_parser = parse_fading)]
    pub health_fading_db: f64,
    /// The live map (`--web`): its options. The replay is over at once; the page serves the
    /// whole log until Ctrl-C.
    #[command(flatten)]
    pub web: WebArgs,
}

/// A σ in dB: 0…30.
fn parse_fading(s: &str) -> Result<f64, String> {
    crate::args::float_in(s, 0.0, 30.0, false, " dB")
}

/// `X,Y` in metres, each within ±[`crate::args::MAX_METRES`].
pub fn parse_point(s: &str) -> Result<Point, String> {
    let (x, y) = s
        .split_once(',')
        .ok_or_else(|| format!("`{s}`: expected X,Y in metres, e.g. 3.5,2"))?;
    Ok(Point::new(
        crate::args::coordinate_m(x)?,
        crate::args::coordinate_m(y)?,
    ))
}

/// `WxH` in metres, both above 0 and at most [`crate::args::MAX_METRES`].
pub fn parse_area(s: &str) -> Result<Area, String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{s}`: expected WxH in metres, e.g. 7x7"))?;
    Ok(Area::new(crate::args::side_m(w)?, crate::args::side_m(h)?))
}

/// What the log held besides reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LineCounts {
    /// `report` lines.
    pub reports: usize,
    /// `report` lines whose bytes are not a valid report.
    pub bad_reports: usize,
    /// `fix` lines.
    pub fixes: usize,
    /// `nofix` lines.
    pub nofixes: usize,
    /// `status` lines.
    pub status: usize,
    /// Sink lines that failed their checksum or did not parse, or whose bytes show damage.
    pub damaged: usize,
    /// Lines longer than any line a node writes, dropped.
    pub too_long: usize,
    /// Lines that are not sink lines (boot lines, comments, noise).
    pub other: usize,
}

/// The agent's measurements of `r` in `f64` (dBm = −byte, 0 = not heard; metres).
pub fn measurements(r: &Report) -> Measurements {
    let n = (r.anchors as usize).min(MAX_ANCHORS);
    let c = r.channels.len().min(MAX_CHANNELS);
    let pos: Vec<Point> = r.positions[..n]
        .iter()
        .map(|p| Point::new(p.x as f64 / 100.0, p.y as f64 / 100.0))
        .collect();
    let mut m = Measurements::new(&pos, c);
    let dbm = |b: u8| (b != 0).then_some(-(b as f64));
    for ch in 0..c {
        for i in 0..n {
            m.anchors[i].rssi[ch] = dbm(r.rssi[ch][i]);
            if r.has_relay {
                for j in 0..n {
                    if i != j {
                        m.a2a[i][j][ch] = dbm(r.relay[ch][i][j]);
                    }
                }
            }
        }
    }
    m
}

/// The anchors' bounding box from the origin (the sink's room when it has none configured).
pub fn bounding_area(anchors: &[Point]) -> Area {
    let w = anchors.iter().map(|a| a.x).fold(0.0, f64::max);
    let h = anchors.iter().map(|a| a.y).fold(0.0, f64::max);
    Area::new(w.max(0.01), h.max(0.01))
}

/// A change of the anchor health check's verdict, and the report it came with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HealthNote {
    /// The report's number in the log (the first is 1).
    pub report: usize,
    /// Its agent.
    pub agent: u8,
    /// Its sequence number.
    pub seq: u16,
    /// What changed.
    pub event: HealthEvent,
}

impl std::fmt::Display for HealthNote {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "report {} (agent {}, seq {}): {}",
            self.report, self.agent, self.seq, self.event
        )
    }
}

/// A log being replayed.
#[derive(Clone, Debug)]
pub struct Replay {
    params: OnlineParams,
    sigma: Option<f64>,
    area: Option<Area>,
    truth: Option<Point>,
    /// Every algorithm's fixes by truth.
    pub tally: Tally,
    /// What the lines were.
    pub counts: LineCounts,
    /// The anchors of the last report (metres).
    pub anchors: Vec<Point>,
    /// The room of the last report.
    pub last_area: Option<Area>,
    /// The anchor health check over the reports.
    pub health: Health,
    /// Every change of its verdict, in order.
    pub health_notes: Vec<HealthNote>,
    /// The live map's events, when it is shown ([`Replay::live`]).
    live: Option<Feed>,
}

impl Replay {
    /// A replay with the room `area` (`None`: each report's anchors' bounding box) and the truth
    /// `truth` until a `# truth` line says otherwise.
    pub fn new(area: Option<Area>, truth: Option<Point>) -> Replay {
        // The table lists the host algorithms first, in their fixed order.
        let tally = Tally {
            order: HOST_ALGOS.iter().map(|s| s.to_string()).collect(),
            ..Tally::default()
        };
        Replay {
            params: OnlineParams::new(
                ParamMode::P0AndAlpha,
                FitMethod::LeastSquares,
                Bounds::THESIS,
                PathLoss::THESIS,
            ),
            sigma: None,
            area,
            truth,
            tally,
            counts: LineCounts::default(),
            anchors: Vec::new(),
            last_area: None,
            health: Health::default(),
            health_notes: Vec::new(),
            live: None,
        }
    }

    /// The same replay, also making the live map's events of what it tallies: each fix, host
    /// or sink, as it goes into the table, at the number of the report it belongs to; the
    /// anchors the reports hear; the status lines' counters ([`Replay::take_events`]).
    pub fn live(self) -> Replay {
        Replay {
            live: Some(Feed::default()),
            ..self
        }
    }

    /// The live map's events since the last call (none without [`Replay::live`]).
    pub fn take_events(&mut self) -> Vec<Event> {
        self.live.as_mut().map_or(Vec::new(), Feed::take)
    }

    /// The same with the anchor health check's settings `cfg`.
    pub fn with_health(self, cfg: HealthConfig) -> Replay {
        Replay {
            health: Health::new(cfg),
            ..self
        }
    }

    /// The current truth.
    pub fn truth(&self) -> Option<Point> {
        self.truth
    }

    /// One line of the log.
    pub fn feed(&mut self, line: &str) {
        self.feed_bytes(line.as_bytes())
    }

    /// One line of the log as bytes (any bytes: noise that is not text is counted).
    pub fn feed_bytes(&mut self, line: &[u8]) {
        if let Some(rest) = line.strip_prefix(b"# truth") {
            match std::str::from_utf8(rest).ok().and_then(parse_truth_words) {
                Some(truth) => self.truth = truth,
                None => self.counts.other += 1,
            }
            return;
        }
        match classify(line) {
            Class::Sink(SinkOutput::Report(raw)) => match raw.report() {
                Ok(r) => {
                    self.counts.reports += 1;
                    self.on_report(&r);
                }
                Err(_) => self.counts.bad_reports += 1,
            },
            Class::Sink(SinkOutput::Line(SinkLine::Fix {
                estimator,
                seq,
                x,
                y,
                alpha_x100,
                p0_x100,
                anchors,
                ..
            })) => {
                self.counts.fixes += 1;
                let algo = match estimator {
                    Estimator::Mle => "sink MLE",
                    Estimator::Mmse => "sink MMSE",
                };
                let p = Point::new(x as f64 / 100.0, y as f64 / 100.0);
                self.tally.add(self.truth, algo, p);
                if let Some(l) = &mut self.live {
                    l.fix(Fix {
                        t: self.counts.reports as f64,
                        seq,
                        est: algo,
                        x: p.x,
                        y: p.y,
                        alpha: f64::from(alpha_x100) / 100.0,
                        p0: f64::from(p0_x100) / 100.0,
                        anchors,
                        truth: self.truth.map(|t| [t.x, t.y]),
                        settled: true,
                    });
                }
            }
            Class::Sink(SinkOutput::Line(SinkLine::NoFix { .. })) => self.counts.nofixes += 1,
            Class::Sink(SinkOutput::Line(line @ SinkLine::Status { .. })) => {
                self.counts.status += 1;
                if let Some(l) = &mut self.live {
                    l.status(Status::of_line(self.counts.reports as f64, &line));
                }
            }
            Class::Boot(_) | Class::Foreign => self.counts.other += 1,
            Class::Damaged(_) => self.counts.damaged += 1,
        }
    }

    /// One framed piece of the log: a line, or a line too long.
    pub fn feed_framed(&mut self, framed: &Framed) {
        match framed {
            Framed::Line(bytes) => {
                let line = bytes.strip_suffix(b"\r").unwrap_or(bytes);
                self.feed_bytes(line)
            }
            Framed::TooLong => self.counts.too_long += 1,
        }
    }

    /// A report: fit and smooth P0/α as the sink does, then every host algorithm; then the
    /// anchor health check.
    fn on_report(&mut self, r: &Report) {
        let events = self.health.on_report(r);
        for &event in &events {
            self.health_notes.push(HealthNote {
                report: self.counts.reports,
                agent: r.agent,
                seq: r.seq,
                event,
            });
        }
        let t = self.counts.reports as f64;
        if let Some(l) = &mut self.live {
            l.report(t, r, &events, &self.health);
        }
        let m = measurements(r);
        let fit = self.params.update(&m);
        if let Some(s) = fit.ok().and_then(|f| f.sigma) {
            self.sigma = Some(s);
        }
        let model = self.params.current();
        let sigma = self.sigma.unwrap_or(DEFAULT_SIGMA_DB);
        self.anchors = m.anchors().iter().map(|a| a.pos).collect();
        let area = self.area.unwrap_or_else(|| bounding_area(&self.anchors));
        self.last_area = Some(area);
        let obs = observations(&m, Refinement::Extended);
        let truth = self.truth;
        let used = obs.as_slice().len() as u8;
        // The table's record and the live map's are the same fix.
        let mut add = |algo: &'static str, model: PathLoss, p: Option<Point>| {
            if let Some(p) = p {
                self.tally.add(truth, algo, p);
                if let Some(l) = &mut self.live {
                    l.fix(Fix {
                        t,
                        seq: r.seq,
                        est: algo,
                        x: p.x,
                        y: p.y,
                        alpha: model.alpha,
                        p0: model.p0,
                        anchors: used,
                        truth: truth.map(|t| [t.x, t.y]),
                        settled: true,
                    });
                }
            }
        };
        let pos = |e: Result<grid::Estimate, _>| e.ok().map(|e| e.pos);
        add(
            "MLE",
            model,
            pos(grid::mle(&obs, model, area, Search::Thesis)),
        );
        add(
            "MMSE-win",
            model,
            pos(grid::mmse_window(&obs, model, area, sigma)),
        );
        add("MMSE", model, pos(grid::mmse(&obs, model, area, sigma)));
        add(
            "MLE-fixed",
            PathLoss::THESIS,
            pos(grid::mle(&obs, PathLoss::THESIS, area, Search::Thesis)),
        );
        let anchors: Vec<Point> = obs.as_slice().iter().map(|o| o.pos).collect();
        let dists: Vec<f64> = obs.as_slice().iter().map(|o| model.distance(o.z)).collect();
        for (algo, b) in [
            ("TRLT-3", Baseline::Trilateration),
            ("QUAD-4", Baseline::Quadlateration),
            ("MDS", Baseline::MdsMap),
        ] {
            add(algo, model, b.estimate(&anchors, &dists, Some(area)).ok());
        }
    }

    /// The text summary: line counts, the table, the overall RMSE per algorithm.
    pub fn summary(&self) -> String {
        let c = &self.counts;
        let mut s = format!(
            "{} reports ({} unreadable), {} sink fix lines, {} nofix, {} status, {} damaged sink \
             lines, {} too long, {} other lines\n\n",
            c.reports, c.bad_reports, c.fixes, c.nofixes, c.status, c.damaged, c.too_long, c.other
        );
        s += &self.tally.table();
        let overall: Vec<String> = self
            .tally
            .overall()
            .into_iter()
            .filter_map(|(a, n, r)| r.map(|r| format!("{a} {r:.3} m ({n})")))
            .collect();
        if !overall.is_empty() {
            s += &format!("\nRMSE over every position: {}\n", overall.join(", "));
        }
        if c.reports > 0 {
            s += "\n";
            for n in &self.health_notes {
                s += &format!("{n}\n");
            }
            s += &self.health.assess().summary();
        }
        s
    }
}

/// The words after `# truth`: `X Y` in metres, each within ±[`crate::args::MAX_METRES`]
/// (`Some(Some(p))`), `none` (`Some(None)`), or anything else (`None`).
fn parse_truth_words(rest: &str) -> Option<Option<Point>> {
    let w: Vec<&str> = rest.split_whitespace().collect();
    match w[..] {
        ["none"] => Some(None),
        [x, y] => {
            let x = crate::args::coordinate_m(x).ok()?;
            let y = crate::args::coordinate_m(y).ok()?;
            Some(Some(Point::new(x, y)))
        }
        _ => None,
    }
}

/// Runs `hoploc replay`.
pub fn run(args: &Args) -> Result<(), String> {
    let mut replay = Replay::new(args.area, args.truth).with_health(HealthConfig {
        fading_db: args.health_fading_db,
        ..HealthConfig::default()
    });
    let name = args.log.display().to_string();
    let mut out = Out::stdout();
    let web = if args.web.web {
        let w = Web::start(&args.web, true)?;
        w.send(&Event::Setup(Setup {
            source: "replay",
            title: "hoploc replay".into(),
            about: format!(
                "{name} through every host estimator, next to the sink's fixes; t counts reports"
            ),
            clock: "log",
            area: args.area.map(|a| [a.width, a.height]),
            anchors: Vec::new(),
            path: args.truth.map(|t| vec![[t.x, t.y]]).unwrap_or_default(),
            estimators: HOST_ALGOS
                .iter()
                .copied()
                .chain(["sink MLE", "sink MMSE"])
                .collect(),
            rate: None,
        }));
        outln!(out, "{}", w.banner("until Ctrl-C"));
        replay = replay.live();
        Some(w)
    } else {
        None
    };
    let publish = |replay: &mut Replay| {
        if let Some(w) = &web {
            for e in replay.take_events() {
                w.send(&e);
            }
        }
    };
    let mut reader: Box<dyn Read> = if name == "-" {
        Box::new(std::io::stdin().lock())
    } else {
        let f = std::fs::File::open(&args.log).map_err(|e| format!("{name}: {e}"))?;
        Box::new(f)
    };
    // Lines are read as bytes: a log with noise that is not UTF-8 loses only those lines.
    let mut framer = Framer::new();
    let mut buf = vec![0u8; 64 * 1024];
    loop {
        let n = match reader.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(format!("{name}: {e}")),
        };
        framer.push(&buf[..n], |f| replay.feed_framed(&f));
        publish(&mut replay);
    }
    if let Some(f) = framer.finish() {
        replay.feed_framed(&f);
    }
    publish(&mut replay);
    out.write(format_args!("{}", replay.summary()))?;
    if replay.counts.reports == 0 {
        outln!(
            out,
            "\n(no report lines: the host algorithms need the sink's `report` lines; the sink's \
             own fixes are tallied above)"
        );
    }
    if let Some(dir) = &args.out_dir {
        let area = replay
            .area
            .or(replay.last_area)
            .unwrap_or(Area::new(1.0, 1.0));
        let files = crate::tally::plot(
            &replay.tally,
            area,
            &replay.anchors,
            &format!("hoploc replay: {name}"),
            dir,
            "replay",
        )?;
        for f in files {
            outln!(out, "wrote {}", f.display());
        }
    }
    if let Some(w) = web {
        outln!(out, "\nthe live map shows the whole log: Ctrl-C stops it");
        w.serve_until_interrupted(replay.counts.reports as f64, "the end of the log");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use loc_proto::msg::{ChannelList, Position};
    use loc_proto::sink_line::RawReport;

    const CORNERS: [(i16, i16); 4] = [(0, 0), (700, 0), (700, 700), (0, 700)];

    /// The RSSI byte at `d` metres under P0 = −40 dBm, α = 3 (noise-free, rounded).
    fn byte(d: f64) -> u8 {
        (40.0 + 30.0 * d.max(0.01).log10()).round() as u8
    }

    fn report(seq: u16, at: Point) -> Report {
        let mut r = Report::new(1, seq, 4, ChannelList::new(&[1, 12]).unwrap());
        let pos = |i: usize| Point::new(CORNERS[i].0 as f64 / 100.0, CORNERS[i].1 as f64 / 100.0);
        for (i, &(x, y)) in CORNERS.iter().enumerate() {
            r.positions[i] = Position { x, y };
            for c in 0..2 {
                r.rssi[c][i] = byte(pos(i).dist(at));
                for j in 0..4 {
                    if i != j {
                        r.relay[c][i][j] = byte(pos(i).dist(pos(j)));
                    }
                }
            }
        }
        r
    }

    fn report_line(r: &Report) -> String {
        let mut buf = [0; loc_proto::msg::MAX_PAYLOAD];
        let n = r.encode(&mut buf).unwrap();
        let mut s = String::new();
        let Ok(()) = RawReport::write(&buf[..n], &mut s);
        s
    }

    fn line(l: SinkLine) -> String {
        let mut s = String::new();
        let Ok(()) = l.write(&mut s);
        s
    }

    #[test]
    fn a_log_gives_every_algorithm_per_truth_position() {
        let a = Point::new(2.0, 5.0);
        let b = Point::new(3.5, 3.5);
        let mut log = vec![
            "hoploc sink boot".to_string(),
            "# truth 2.0 5.0".to_string(),
        ];
        for seq in 0..5 {
            log.push(report_line(&report(seq, a)));
            log.push(line(SinkLine::Fix {
                agent: 1,
                seq,
                estimator: Estimator::Mle,
                x: 210,
                y: 490,
                alpha_x100: 300,
                p0_x100: -4000,
                anchors: 4,
                flags: 1,
            }));
        }
        log.push("# truth 3.5 3.5".to_string());
        for seq in 5..8 {
            log.push(report_line(&report(seq, b)));
        }
        // Damage: a changed digit in a report line; a line cut short; a malformed truth line.
        let damaged = report_line(&report(8, b)).replacen("01", "02", 1);
        log.push(damaged);
        log.push("hoploc sink status 1 2".to_string());
        log.push("# truth somewhere".to_string());
        log.push(line(SinkLine::NoFix {
            agent: 1,
            seq: 9,
            usable: 2,
        }));

        let mut r = Replay::new(None, None);
        for l in &log {
            r.feed(l);
        }
        assert_eq!(
            r.counts,
            LineCounts {
                reports: 8,
                bad_reports: 0,
                fixes: 5,
                nofixes: 1,
                status: 0,
                damaged: 2,
                too_long: 0,
                other: 2,
            }
        );
        // The room is the anchors' bounding box. The bytes are the thesis model's levels,
        // rounded: with the thesis' P0/α the MLE is within one fine step (2 % of 7 m) per axis of the
        // truth. The fit sees two relay distances only (7 m, 9.9 m) in whole dB, which gives
        // α ≈ 3.3, so the estimators on the fitted model are off by up to a few decimetres.
        assert_eq!(r.last_area, Some(Area::new(7.0, 7.0)));
        for (t, p) in [(a, 5), (b, 3)] {
            let k = crate::tally::truth_key(Some(t));
            for algo in HOST_ALGOS {
                let acc = r.tally.get(k, algo).unwrap_or_else(|| panic!("{algo}"));
                assert_eq!(acc.len(), p, "{algo}");
                let rmse = acc.rmse(t).unwrap();
                let tol = if algo == "MLE-fixed" {
                    0.14 * 2f64.sqrt()
                } else {
                    0.6
                };
                assert!(rmse <= tol, "{algo} at {t:?}: {rmse}");
            }
        }
        // The sink's own fixes at the first position: (2.10, 4.90) against (2, 5).
        let sink = r
            .tally
            .get(crate::tally::truth_key(Some(a)), "sink MLE")
            .unwrap();
        assert!((sink.rmse(a).unwrap() - 0.02f64.sqrt()).abs() < 1e-9);
        let s = r.summary();
        assert!(
            s.contains("8 reports (0 unreadable), 5 sink fix lines"),
            "{s}"
        );
        assert!(s.contains("(2.00, 5.00)  MLE"), "{s}");
        assert!(s.contains("(3.50, 3.50)  MDS"), "{s}");
        assert!(s.contains("RMSE over every position: MLE "), "{s}");
    }

    #[test]
    fn fits_follow_the_reports() {
        // With P0 = −46 dBm in the data (the thesis' prior is −40), the AR(1) fit moves toward
        // it, and the MLE with the fitted model beats the one with fixed parameters.
        let t = Point::new(2.0, 3.5);
        let mut r = Replay::new(Some(Area::new(7.0, 7.0)), Some(t));
        for seq in 0..30 {
            let mut rep = report(seq, t);
            for c in 0..2 {
                for i in 0..4 {
                    rep.rssi[c][i] += 6;
                    for j in 0..4 {
                        if i != j {
                            rep.relay[c][i][j] += 6;
                        }
                    }
                }
            }
            r.feed(&report_line(&rep));
        }
        // Two relay distances only (7 m and 9.9 m) with whole-dB bytes leave P0 and α traded
        // off against each other, but the fitted model predicts the levels the data have.
        let model = r.params.current();
        for d in [7.0, 7.0 * 2f64.sqrt()] {
            let want = -(byte(d) as f64) - 6.0;
            let got = model.rssi_at(d);
            assert!(
                (got - want).abs() < 0.8,
                "{d} m: {got} vs {want} ({model:?})"
            );
        }
        let k = crate::tally::truth_key(Some(t));
        let fitted = r.tally.get(k, "MLE").unwrap().rmse(t).unwrap();
        let fixed = r.tally.get(k, "MLE-fixed").unwrap().rmse(t).unwrap();
        assert!(
            fitted < 0.2 && fixed > 0.5,
            "fitted {fitted}, fixed {fixed}"
        );
    }

    #[test]
    fn a_misplaced_anchor_is_flagged_in_the_summary() {
        use crate::health::synthetic::Room;
        // room10's corners and a fifth anchor in the middle; anchor 3, configured at (10, 10),
        // stands at (7, 7). A room with little multipath (fading σ 1 dB per channel), which
        // the check is told.
        let layout = [
            (0.0, 0.0),
            (10.0, 0.0),
            (10.0, 10.0),
            (0.0, 10.0),
            (5.0, 5.0),
        ];
        let mut room = Room::new(&layout).moved(2, (7.0, 7.0));
        room.fading_db = 1.0;
        let cfg = HealthConfig {
            fading_db: 1.0,
            ..HealthConfig::default()
        };
        let mut r = Replay::new(None, None).with_health(cfg);
        r.feed("hoploc sink boot");
        for rep in room.reports(40, 1) {
            r.feed(&report_line(&rep));
        }
        assert_eq!(r.counts.reports, 40);
        // Flagged at the first verdict: 20 reports.
        assert_eq!(r.health_notes.len(), 1, "{:?}", r.health_notes);
        let n = r.health_notes[0];
        assert_eq!((n.report, n.agent, n.seq), (20, 1, 19));
        let s = r.summary();
        assert!(
            s.contains("report 20 (agent 1, seq 19): anchor health: FLAGGED anchor 3 configured at (10.00, 10.00) m"),
            "{s}"
        );
        assert!(s.contains("\nanchor health: FLAGGED anchor 3"), "{s}");
        // The same room with anchor 3 where it is configured: no note, and the verdict says so.
        room.truth = room.configured.clone();
        let mut r = Replay::new(None, None).with_health(cfg);
        for rep in room.reports(40, 1) {
            r.feed(&report_line(&rep));
        }
        assert!(r.health_notes.is_empty());
        assert!(
            r.summary()
                .contains("anchor health: no anchor flagged (40 reports, 10 links)"),
            "{}",
            r.summary()
        );
        // A log without report lines has no health section.
        let mut r = Replay::new(None, None);
        r.feed("hoploc sink boot");
        assert!(!r.summary().contains("anchor health"));
    }

    #[test]
    fn arguments_parse_or_say_why() {
        assert_eq!(parse_point("3.5, 2").unwrap(), Point::new(3.5, 2.0));
        assert!(parse_point("3.5").unwrap_err().contains("X,Y"));
        assert!(parse_point("a,2").unwrap_err().contains("`a`"));
        assert!(parse_point("nan,2").unwrap_err().contains("-10000…10000 m"));
        assert!(parse_point("1,inf").unwrap_err().contains("-10000…10000 m"));
        assert_eq!(parse_area("7x6").unwrap(), Area::new(7.0, 6.0));
        assert!(parse_area("7x0").unwrap_err().contains("above 0"));
        assert!(parse_area("1e6x7").unwrap_err().contains("at most 10000 m"));
        assert!(parse_area("7").unwrap_err().contains("WxH"));
        assert_eq!(parse_fading("1.5").unwrap(), 1.5);
        assert!(
            parse_fading("-1").unwrap_err().contains("0…30 dB"),
            "{:?}",
            parse_fading("-1")
        );
        assert!(parse_fading("inf").is_err());
    }
}
