//! `hoploc monitor`: the sink's lines, live, from its USB serial port or stdin.
//!
//! [`Monitor`] is sans-IO: fed one line at a time, it answers with the rows to print — one per
//! report (the MLE and MMSE fixes of the same agent and sequence side by side, with the error
//! against `--truth` when given), one per `status` line, and a note per damaged line — and keeps
//! every fix in a [`Tally`] for the summary table and the plot at the end. The command reads the
//! port (or stdin), cuts the bytes into lines with [`crate::framing`] (a good line right after
//! noise is found again; a line too long is dropped and counted), prints the rows, saves every
//! line to `--log` for `hoploc replay`, and stops at the end of the input, when the port goes
//! away, or at `--seconds` whatever the input does: the port is read on a thread of its own, so a
//! silent port, or bytes that never end a line, do not hold the deadline up.

use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use loc_core::{Area, Point};
use loc_proto::sink_line::{Estimator, SinkLine, SinkOutput};

use crate::framing::{classify, Class, Framed, Framer};
use crate::out::Out;
use crate::replay::{parse_area, parse_point};
use crate::tally::Tally;
use crate::web::{Event, Feed, Fix, Setup, Status, Web, WebArgs};
use crate::{args, outln};

/// `hoploc monitor` options.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// The sink's serial port (e.g. /dev/ttyACM0) [default: read the lines from stdin].
    #[arg(long)]
    pub port: Option<String>,
    /// The port's baud rate (the sink's UART runs at the radio's 57600) [300…4000000].
    #[arg(long, default_value_t = 57_600, value_parser = args::baud)]
    pub baud: u32,
    /// Save every line received to this file (the input of `hoploc replay`).
    #[arg(long)]
    pub log: Option<PathBuf>,
    /// The agent's true position, metres, to show each fix's error and the RMSE at the end.
    #[arg(long, value_parser = parse_point)]
    pub truth: Option<Point>,
    /// Stop after this many seconds, whatever the input does (default: at the end of the
    /// input) [0.001…31536000, a year].
    #[arg(long, value_parser = args::seconds)]
    pub seconds: Option<f64>,
    /// Write the plot of the fixes (monitor.svg, monitor.png) into this directory at the end.
    #[arg(long)]
    pub out_dir: Option<PathBuf>,
    /// The room for the plot and the live map, metres (`WxH`) [default: the extent of the
    /// fixes; the live map: of the anchors].
    #[arg(long, value_parser = parse_area)]
    pub area: Option<Area>,
    /// The live map (`--web`): its options.
    #[command(flatten)]
    pub web: WebArgs,
}

/// The line counts of a session.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// `fix` lines.
    pub fixes: usize,
    /// `nofix` lines.
    pub nofixes: usize,
    /// `report` lines.
    pub reports: usize,
    /// `status` lines.
    pub status: usize,
    /// Sink lines that failed their checksum or did not parse, or whose bytes show damage
    /// ([`crate::framing::classify`]).
    pub damaged: usize,
    /// Lines longer than any line a node writes, dropped.
    pub too_long: usize,
    /// Other lines (boot lines, noise, other devices' text).
    pub other: usize,
}

/// A fix line's fields, kept until its report's other estimator arrives.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Half {
    agent: u8,
    seq: u16,
    estimator: Estimator,
    pos: Point,
    alpha: f64,
    p0: f64,
    anchors: u8,
    flags: u8,
}

/// The live state of a monitored sink.
#[derive(Clone, Debug, Default)]
pub struct Monitor {
    truth: Option<Point>,
    pending: Option<Half>,
    /// Every fix by estimator (`MLE`, `MMSE`).
    pub tally: Tally,
    /// What the lines were.
    pub counts: Counts,
    /// The last `status` line.
    pub last_status: Option<SinkLine>,
    /// The anchor health check over the `report` lines: a row when its verdict changes.
    pub health: crate::health::Health,
    /// The live map's events, when it is shown ([`Monitor::live`]), and the time of the lines
    /// fed ([`Monitor::set_clock`]).
    live: Option<Feed>,
    clock: f64,
}

impl Monitor {
    /// A monitor; fixes are compared with `truth` when given.
    pub fn new(truth: Option<Point>) -> Monitor {
        Monitor {
            truth,
            ..Monitor::default()
        }
    }

    /// The same monitor, also making the live map's events of what it is fed: each fix line
    /// it tallies, the anchors the reports hear, the counters of the status lines
    /// ([`Monitor::take_events`]).
    pub fn live(self) -> Monitor {
        Monitor {
            live: Some(Feed::default()),
            ..self
        }
    }

    /// The time, s, of the lines fed from now on (the live map's events carry it).
    pub fn set_clock(&mut self, t: f64) {
        self.clock = t;
    }

    /// The live map's events since the last call (none without [`Monitor::live`]).
    pub fn take_events(&mut self) -> Vec<Event> {
        self.live.as_mut().map_or(Vec::new(), Feed::take)
    }

    /// The header of the rows [`Monitor::feed`] prints.
    pub fn header(&self) -> String {
        let err = if self.truth.is_some() {
            "  err MLE  err MMSE"
        } else {
            ""
        };
        format!(
            "agent    seq   MLE x,y (m)      MMSE x,y (m)      α     P0 dBm  anchors  P0/α{err}"
        )
    }

    /// One line from the sink; returns the rows to print (none for a report line, or for a fix
    /// line waiting for its report's other estimator).
    pub fn feed(&mut self, line: &str) -> Vec<String> {
        self.feed_bytes(line.as_bytes())
    }

    /// One framed piece of the sink's output ([`crate::framing::Framer`]): a line, or a line
    /// that was too long. Returns the rows to print.
    pub fn feed_framed(&mut self, framed: &Framed) -> Vec<String> {
        match framed {
            Framed::Line(bytes) => self.feed_bytes(bytes),
            Framed::TooLong => {
                self.counts.too_long += 1;
                let mut rows: Vec<String> = self.flush().into_iter().collect();
                rows.push("  line too long (noise?), dropped".to_string());
                rows
            }
        }
    }

    /// One line from the sink as bytes (any bytes: noise that is not text is counted, as a
    /// damaged sink line when it shows one). Returns the rows to print.
    pub fn feed_bytes(&mut self, line: &[u8]) -> Vec<String> {
        let mut rows = Vec::new();
        match classify(line) {
            Class::Sink(SinkOutput::Line(SinkLine::Fix {
                agent,
                seq,
                estimator,
                x,
                y,
                alpha_x100,
                p0_x100,
                anchors,
                flags,
            })) => {
                self.counts.fixes += 1;
                let half = Half {
                    agent,
                    seq,
                    estimator,
                    pos: Point::new(x as f64 / 100.0, y as f64 / 100.0),
                    alpha: alpha_x100 as f64 / 100.0,
                    p0: p0_x100 as f64 / 100.0,
                    anchors,
                    flags,
                };
                let est = match estimator {
                    Estimator::Mle => "MLE",
                    Estimator::Mmse => "MMSE",
                };
                // The table's record and the live map's are the same fix.
                self.tally.add(self.truth, est, half.pos);
                if let Some(l) = &mut self.live {
                    l.fix(Fix {
                        t: self.clock,
                        seq,
                        est,
                        x: half.pos.x,
                        y: half.pos.y,
                        alpha: half.alpha,
                        p0: half.p0,
                        anchors,
                        truth: self.truth.map(|t| [t.x, t.y]),
                        settled: true,
                    });
                }
                match self.pending.take() {
                    Some(p) if p.agent == agent && p.seq == seq && p.estimator != estimator => {
                        rows.push(self.row(&[p, half]));
                    }
                    Some(p) => {
                        rows.push(self.row(&[p]));
                        self.pending = Some(half);
                    }
                    None => self.pending = Some(half),
                }
                return rows;
            }
            Class::Sink(SinkOutput::Line(SinkLine::NoFix { agent, seq, usable })) => {
                self.counts.nofixes += 1;
                rows.extend(self.flush());
                rows.push(format!(
                    "{agent:>5} {seq:>6}   no fix: {usable} usable anchors (3 needed)"
                ));
            }
            Class::Sink(SinkOutput::Line(
                s @ SinkLine::Status {
                    uptime_s,
                    frames,
                    reports,
                    drops,
                    checksum_errors,
                    foreign,
                    fixes,
                    repeats,
                    failed,
                },
            )) => {
                self.counts.status += 1;
                let warnings = crate::diagnose::status_warnings(self.last_status.as_ref(), &s);
                if let Some(l) = &mut self.live {
                    l.status(Status::of_line(self.clock, &s).map(|st| Status {
                        damaged: Some(self.counts.damaged),
                        ..st
                    }));
                }
                self.last_status = Some(s);
                rows.extend(self.flush());
                rows.push(format!(
                    "status at {uptime_s} s: {frames} frames, {reports} reports, {drops} dropped, \
                     {checksum_errors} corrupt, {foreign} foreign, {fixes} fixes, {repeats} \
                     repeated, {failed} undelivered"
                ));
                rows.extend(warnings);
            }
            Class::Sink(SinkOutput::Report(raw)) => {
                self.counts.reports += 1;
                let report = raw.report().ok();
                let events = report.map_or(Vec::new(), |r| self.health.on_report(&r));
                if let (Some(l), Some(r)) = (&mut self.live, report) {
                    l.report(self.clock, &r, &events, &self.health);
                }
                if !events.is_empty() {
                    rows.extend(self.flush());
                    rows.extend(events.iter().map(|e| e.to_string()));
                }
            }
            // The sink's boot and config lines (`hoploc sink boot`, …) are worth seeing.
            Class::Boot(b) => {
                self.counts.other += 1;
                rows.extend(self.flush());
                rows.push(format!("  {b}"));
            }
            Class::Foreign => self.counts.other += 1,
            Class::Damaged(why) => {
                self.counts.damaged += 1;
                rows.extend(self.flush());
                rows.push(format!("  damaged sink line ({why}), skipped"));
            }
        }
        rows
    }

    /// The row of a fix still waiting for its other half, if any.
    pub fn flush(&mut self) -> Option<String> {
        self.pending.take().map(|p| self.row(&[p]))
    }

    fn row(&self, halves: &[Half]) -> String {
        let h = halves[0];
        let find = |e: Estimator| halves.iter().find(|x| x.estimator == e);
        let pos = |x: Option<&Half>| match x {
            Some(x) => format!("({:5.2}, {:5.2})", x.pos.x, x.pos.y),
            None => format!("{:^14}", "-"),
        };
        let (mle, mmse) = (find(Estimator::Mle), find(Estimator::Mmse));
        let mut s = format!(
            "{:>5} {:>6}   {}   {}   {:4.2}  {:7.2}  {:>7}  {}",
            h.agent,
            h.seq,
            pos(mle),
            pos(mmse),
            h.alpha,
            h.p0,
            h.anchors,
            if h.flags & loc_proto::sink_line::FLAG_FITTED != 0 {
                "fitted"
            } else {
                "kept  "
            }
        );
        if let Some(t) = self.truth {
            let err = |x: Option<&Half>| match x {
                Some(x) => format!("{:6.2} m", x.pos.dist(t)),
                None => format!("{:>8}", "-"),
            };
            s += &format!("  {}  {}", err(mle), err(mmse));
        }
        s
    }

    /// The summary at the end: the counts, the last status, the fixes' table.
    pub fn summary(&self) -> String {
        let c = &self.counts;
        let mut s = format!(
            "{} fix lines, {} nofix, {} report lines, {} status, {} damaged sink lines, {} too \
             long, {} other lines\n",
            c.fixes, c.nofixes, c.reports, c.status, c.damaged, c.too_long, c.other
        );
        if !self.tally.accs.is_empty() {
            s += "\n";
            s += &self.tally.table();
        }
        s
    }
}

/// What the port's reader thread hands over: bytes, the end of the input, or a read error.
enum Input {
    Bytes(Vec<u8>),
    End,
    Error(std::io::Error),
}

/// Reads `reader` on a thread of its own, chunk by chunk, into a bounded channel: the session
/// waits on the channel with its deadline, so no read can hold it up. A read timeout (a serial
/// port with nothing to say) is not the end. The thread ends at the end of the input, on an
/// error, or when the session has gone (a thread blocked in a read ends with the process).
fn spawn_reader(mut reader: Box<dyn Read + Send>) -> Receiver<Input> {
    let (tx, rx) = mpsc::sync_channel(64);
    std::thread::spawn(move || {
        let mut buf = vec![0u8; 4096];
        loop {
            let msg = match reader.read(&mut buf) {
                Ok(0) => Input::End,
                Ok(n) => Input::Bytes(buf[..n].to_vec()),
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::TimedOut
                            | std::io::ErrorKind::WouldBlock
                            | std::io::ErrorKind::Interrupted
                    ) =>
                {
                    continue
                }
                Err(e) => Input::Error(e),
            };
            let last = !matches!(msg, Input::Bytes(_));
            if tx.send(msg).is_err() || last {
                return;
            }
        }
    });
    rx
}

/// Why a monitoring session ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ended {
    /// The input ended (or the port went away).
    Input,
    /// The input failed to read.
    Error,
    /// `--seconds` passed.
    Deadline,
    /// The reader of the output went.
    Output,
    /// Ctrl-C (with the live map, which catches it).
    Interrupted,
}

impl Ended {
    /// In words, for the live map.
    pub fn describe(self) -> &'static str {
        match self {
            Ended::Input => "the end of the input",
            Ended::Error => "a read error",
            Ended::Deadline => "--seconds passed",
            Ended::Output => "the output closed",
            Ended::Interrupted => "Ctrl-C",
        }
    }
}

/// How often a session with the live map looks at Ctrl-C while its input is silent.
const TICK: Duration = Duration::from_millis(100);

/// A monitoring session: `reader`'s lines through `mon` until the input ends, `deadline` (from
/// now) passes, `out`'s reader goes, or Ctrl-C with `web`; rows on `out`, every line into `log`,
/// the live map's events to `web`. `name` names the input in messages.
pub fn session<W: Write>(
    reader: Box<dyn Read + Send>,
    name: &str,
    deadline: Option<Duration>,
    mon: &mut Monitor,
    mut log: Option<&mut dyn Write>,
    out: &mut Out<W>,
    web: Option<&Web>,
) -> Result<Ended, String> {
    let start = Instant::now();
    let input = spawn_reader(reader);
    let mut framer = Framer::new();
    let mut show = |framed: Framed, mon: &mut Monitor, out: &mut Out<W>| -> Result<(), String> {
        if let (Some(log), Framed::Line(bytes)) = (log.as_mut(), &framed) {
            log.write_all(bytes)
                .and_then(|()| log.write_all(b"\n"))
                .and_then(|()| log.flush())
                .map_err(|e| format!("log: {e}"))?;
        }
        mon.set_clock(start.elapsed().as_secs_f64());
        for r in mon.feed_framed(&framed) {
            outln!(out, "{r}");
        }
        if let Some(w) = web {
            for e in mon.take_events() {
                w.send(&e);
            }
        }
        Ok(())
    };
    loop {
        if out.closed() {
            return Ok(Ended::Output);
        }
        if web.is_some_and(|w| w.interrupted()) {
            return Ok(Ended::Interrupted);
        }
        // With the live map the wait is cut into ticks, to see Ctrl-C.
        let tick = web.map(|_| TICK);
        let left = deadline.map(|d| d.saturating_sub(start.elapsed()));
        let msg = match (left, tick) {
            (Some(left), _) if left.is_zero() => Err(RecvTimeoutError::Timeout),
            (None, None) => input.recv().map_err(|_| RecvTimeoutError::Disconnected),
            (left, tick) => {
                let wait = left.into_iter().chain(tick).min().unwrap_or(TICK);
                match input.recv_timeout(wait) {
                    Err(RecvTimeoutError::Timeout) if left.is_none_or(|l| wait < l) => continue,
                    m => m,
                }
            }
        };
        match msg {
            Ok(Input::Bytes(bytes)) => {
                let mut framed = Vec::new();
                framer.push(&bytes, |f| framed.push(f));
                for f in framed {
                    show(f, mon, out)?;
                }
            }
            Ok(Input::End) | Err(RecvTimeoutError::Disconnected) => break,
            Ok(Input::Error(e)) => {
                outln!(out, "{name}: {e}; stopping");
                if let Some(f) = framer.finish() {
                    show(f, mon, out)?;
                }
                return Ok(Ended::Error);
            }
            // The deadline: a line being dropped as too long counts; a line cut here is ours.
            Err(RecvTimeoutError::Timeout) => {
                if framer.overlong() {
                    show(Framed::TooLong, mon, out)?;
                }
                return Ok(Ended::Deadline);
            }
        }
    }
    if let Some(f) = framer.finish() {
        show(f, mon, out)?;
    }
    Ok(Ended::Input)
}

/// Runs `hoploc monitor`.
pub fn run(args: &Args) -> Result<(), String> {
    let (name, reader): (String, Box<dyn Read + Send>) = match &args.port {
        Some(p) => {
            let port = serialport::new(p, args.baud)
                .timeout(Duration::from_millis(200))
                .open()
                .map_err(|e| format!("{p}: {e}"))?;
            (p.clone(), Box::new(port))
        }
        None => ("stdin".to_string(), Box::new(std::io::stdin())),
    };
    let mut log = match &args.log {
        Some(path) => Some(std::io::BufWriter::new(
            std::fs::File::create(path).map_err(|e| format!("{}: {e}", path.display()))?,
        )),
        None => None,
    };
    let deadline = match args.seconds {
        Some(s) => Some(Duration::try_from_secs_f64(s).map_err(|e| format!("--seconds {s}: {e}"))?),
        None => None,
    };
    let mut mon = Monitor::new(args.truth);
    let mut out = Out::stdout();
    outln!(out, "hoploc monitor: the sink's lines from {name}");
    let web = if args.web.web {
        let w = Web::start(&args.web, true)?;
        w.send(&Event::Setup(Setup {
            source: "monitor",
            title: "hoploc monitor".into(),
            about: format!("the sink's lines from {name}; seconds since the start"),
            clock: "wall",
            area: args.area.map(|a| [a.width, a.height]),
            anchors: Vec::new(),
            path: args.truth.map(|t| vec![[t.x, t.y]]).unwrap_or_default(),
            estimators: vec!["MLE", "MMSE"],
            rate: None,
        }));
        outln!(out, "{}", w.banner("until the input ends or Ctrl-C"));
        mon = mon.live();
        Some(w)
    } else {
        None
    };
    let start = Instant::now();
    outln!(out, "{}", mon.header());
    let ended = session(
        reader,
        &name,
        deadline,
        &mut mon,
        log.as_mut().map(|l| l as &mut dyn Write),
        &mut out,
        web.as_ref(),
    )?;
    if let Some(w) = web {
        w.finish(start.elapsed().as_secs_f64(), ended.describe());
    }
    if out.closed() {
        return Ok(());
    }
    if ended == Ended::Interrupted {
        outln!(out, "Ctrl-C: stopped");
    }
    if let Some(r) = mon.flush() {
        outln!(out, "{r}");
    }
    outln!(out, "\n{}", mon.summary());
    if let Some(dir) = &args.out_dir {
        let area = args.area.unwrap_or_else(|| {
            let pts = mon.tally.accs.values().flat_map(|a| a.fixes.iter());
            let (w, h) = pts.fold((1.0f64, 1.0f64), |(w, h), p| (w.max(p.x), h.max(p.y)));
            Area::new(w, h)
        });
        for f in crate::tally::plot(&mon.tally, area, &[], "hoploc monitor", dir, "monitor")? {
            outln!(out, "wrote {}", f.display());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(l: SinkLine) -> String {
        let mut s = String::new();
        let Ok(()) = l.write(&mut s);
        s
    }

    fn fix(seq: u16, estimator: Estimator, x: i16, y: i16) -> String {
        text(SinkLine::Fix {
            agent: 1,
            seq,
            estimator,
            x,
            y,
            alpha_x100: 282,
            p0_x100: -4126,
            anchors: 4,
            flags: 1,
        })
    }

    #[test]
    fn rows_pair_the_estimators_and_say_what_went_wrong() {
        let mut m = Monitor::new(Some(Point::new(2.0, 3.0)));
        assert!(m.feed("hoploc sink boot\r\n")[0].contains("hoploc sink boot"));
        assert!(m.feed(&fix(7, Estimator::Mle, 200, 340)).is_empty());
        let rows = m.feed(&fix(7, Estimator::Mmse, 230, 300));
        assert_eq!(rows.len(), 1);
        let r = &rows[0];
        assert!(
            r.contains("( 2.00,  3.40)") && r.contains("( 2.30,  3.00)"),
            "{r}"
        );
        assert!(
            r.contains("2.82") && r.contains("-41.26") && r.contains("fitted"),
            "{r}"
        );
        assert!(r.contains("  0.40 m    0.30 m"), "{r}");
        // A fix whose partner was lost is shown alone when the next report's arrives.
        assert!(m.feed(&fix(8, Estimator::Mle, 200, 300)).is_empty());
        let rows = m.feed(&fix(9, Estimator::Mle, 200, 300));
        assert_eq!(rows.len(), 1);
        assert!(rows[0].contains("     8 "), "{}", rows[0]);
        assert!(rows[0].contains(&format!("{:^14}", "-")), "{}", rows[0]);
        let rows = m.feed(&text(SinkLine::NoFix {
            agent: 1,
            seq: 10,
            usable: 2,
        }));
        assert_eq!(rows.len(), 2, "{rows:?}");
        assert!(rows[1].contains("no fix: 2 usable anchors"));
        let damaged = fix(11, Estimator::Mle, 200, 300).replace("200", "201");
        assert!(m.feed(&damaged)[0].contains("damaged sink line (checksum"));
        let rows = m.feed(&text(SinkLine::Status {
            uptime_s: 61,
            frames: 1203,
            reports: 240,
            drops: 3,
            checksum_errors: 1,
            foreign: 17,
            fixes: 480,
            repeats: 0,
            failed: 0,
        }));
        assert_eq!(rows.len(), 4, "{rows:?}");
        assert_eq!(
            rows[0],
            "status at 61 s: 1203 frames, 240 reports, 3 dropped, 1 corrupt, 17 foreign, 480 \
             fixes, 0 repeated, 0 undelivered"
        );
        // The first status line: what its counters say since boot.
        assert!(rows[1].contains("17 frames") && rows[2].contains("1 damaged"));
        assert!(rows[3].contains("3 reports missing"));
        assert!(m.feed("random noise").is_empty());
        assert_eq!(
            m.counts,
            Counts {
                fixes: 4,
                nofixes: 1,
                reports: 0,
                status: 1,
                damaged: 1,
                too_long: 0,
                other: 2,
            }
        );
        let k = crate::tally::truth_key(Some(Point::new(2.0, 3.0)));
        assert_eq!(m.tally.get(k, "MLE").unwrap().len(), 3);
        assert_eq!(m.tally.get(k, "MMSE").unwrap().len(), 1);
        assert!(m.summary().contains("4 fix lines, 1 nofix"));
    }
}
