//! `hoploc monitor`: the sink's lines, live, from its USB serial port or stdin.
//!
//! [`Monitor`] is sans-IO: fed one line at a time, it answers with the rows to print — one per
//! report (the MLE and MMSE fixes of the same agent and sequence side by side, with the error
//! against `--truth` when given), one per `status` line, and a note per damaged line — and keeps
//! every fix in a [`Tally`] for the summary table and the plot at the end. The command reads the
//! port (or stdin), prints the rows, saves every line to `--log` for `hoploc replay`, and stops
//! at the end of the input, after `--seconds`, or when the port goes away.

use std::io::{BufRead, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use loc_core::{Area, Point};
use loc_proto::line::BootLine;
use loc_proto::sink_line::{Estimator, SinkLine, SinkLineError, SinkOutput};

use crate::replay::{parse_area, parse_point};
use crate::tally::Tally;

/// `hoploc monitor` options.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// The sink's serial port (e.g. /dev/ttyACM0) [default: read the lines from stdin].
    #[arg(long)]
    pub port: Option<String>,
    /// The port's baud rate (the sink's UART runs at the radio's 57600).
    #[arg(long, default_value_t = 57_600)]
    pub baud: u32,
    /// Save every line received to this file (the input of `hoploc replay`).
    #[arg(long)]
    pub log: Option<PathBuf>,
    /// The agent's true position, metres, to show each fix's error and the RMSE at the end.
    #[arg(long, value_parser = parse_point)]
    pub truth: Option<Point>,
    /// Stop after this many seconds (default: at the end of the input).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Write the plot of the fixes (monitor.svg, monitor.png) into this directory at the end.
    #[arg(long)]
    pub out_dir: Option<PathBuf>,
    /// The room for the plot, metres (`WxH`) [default: the extent of the fixes].
    #[arg(long, value_parser = parse_area)]
    pub area: Option<Area>,
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
    /// Sink lines that failed their checksum or did not parse.
    pub damaged: usize,
    /// Other lines (boot lines, noise).
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
}

impl Monitor {
    /// A monitor; fixes are compared with `truth` when given.
    pub fn new(truth: Option<Point>) -> Monitor {
        Monitor {
            truth,
            ..Monitor::default()
        }
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
        let line = line.trim_end_matches(['\r', '\n']);
        let mut rows = Vec::new();
        match SinkOutput::parse(line) {
            Ok(SinkOutput::Line(SinkLine::Fix {
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
                self.tally.add(
                    self.truth,
                    match estimator {
                        Estimator::Mle => "MLE",
                        Estimator::Mmse => "MMSE",
                    },
                    half.pos,
                );
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
            Ok(SinkOutput::Line(SinkLine::NoFix { agent, seq, usable })) => {
                self.counts.nofixes += 1;
                rows.extend(self.flush());
                rows.push(format!(
                    "{agent:>5} {seq:>6}   no fix: {usable} usable anchors (3 needed)"
                ));
            }
            Ok(SinkOutput::Line(
                s @ SinkLine::Status {
                    uptime_s,
                    frames,
                    reports,
                    drops,
                    checksum_errors,
                    foreign,
                    fixes,
                },
            )) => {
                self.counts.status += 1;
                self.last_status = Some(s);
                rows.extend(self.flush());
                rows.push(format!(
                    "status at {uptime_s} s: {frames} frames, {reports} reports, {drops} dropped, \
                     {checksum_errors} corrupt, {foreign} foreign, {fixes} fixes"
                ));
            }
            Ok(SinkOutput::Report(raw)) => {
                self.counts.reports += 1;
                let events = raw
                    .report()
                    .map_or(Vec::new(), |r| self.health.on_report(&r));
                if !events.is_empty() {
                    rows.extend(self.flush());
                    rows.extend(events.iter().map(|e| e.to_string()));
                }
            }
            // The sink's boot and config lines (`hoploc sink boot`, …) are worth seeing.
            Err(_) if BootLine::parse(line).is_ok() => {
                self.counts.other += 1;
                rows.extend(self.flush());
                rows.push(format!("  {line}"));
            }
            Err(SinkLineError::NotSinkLine) => self.counts.other += 1,
            Err(e) => {
                self.counts.damaged += 1;
                rows.extend(self.flush());
                rows.push(format!("  damaged sink line ({e}), skipped"));
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
            "{} fix lines, {} nofix, {} report lines, {} status, {} damaged sink lines, {} other \
             lines\n",
            c.fixes, c.nofixes, c.reports, c.status, c.damaged, c.other
        );
        if !self.tally.accs.is_empty() {
            s += "\n";
            s += &self.tally.table();
        }
        s
    }
}

/// Runs `hoploc monitor`.
pub fn run(args: &Args) -> Result<(), String> {
    let (name, reader): (String, Box<dyn BufRead>) = match &args.port {
        Some(p) => {
            let port = serialport::new(p, args.baud)
                .timeout(Duration::from_millis(200))
                .open()
                .map_err(|e| format!("{p}: {e}"))?;
            (p.clone(), Box::new(std::io::BufReader::new(port)))
        }
        None => ("stdin".to_string(), Box::new(std::io::stdin().lock())),
    };
    let mut log = match &args.log {
        Some(path) => Some(std::io::BufWriter::new(
            std::fs::File::create(path).map_err(|e| format!("{}: {e}", path.display()))?,
        )),
        None => None,
    };
    let mut mon = Monitor::new(args.truth);
    println!("hoploc monitor: the sink's lines from {name}");
    println!("{}", mon.header());
    let start = Instant::now();
    let deadline = args.seconds.map(Duration::from_secs_f64);
    let mut reader = reader;
    let mut buf = Vec::new();
    loop {
        if deadline.is_some_and(|d| start.elapsed() >= d) {
            break;
        }
        match reader.read_until(b'\n', &mut buf) {
            Ok(0) => break,
            Ok(_) => {}
            // A serial port's read timeout: nothing yet, keep the partial line.
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => {
                println!("{name}: {e}; stopping");
                break;
            }
        }
        if !buf.ends_with(b"\n") {
            continue;
        }
        if let Some(log) = &mut log {
            log.write_all(&buf)
                .and_then(|()| log.flush())
                .map_err(|e| format!("log: {e}"))?;
        }
        // Noise that is not UTF-8 is an "other" line, never a crash.
        let rows = match std::str::from_utf8(&buf) {
            Ok(t) => mon.feed(t),
            Err(_) => {
                mon.counts.other += 1;
                Vec::new()
            }
        };
        for r in rows {
            println!("{r}");
        }
        buf.clear();
    }
    if let Some(r) = mon.flush() {
        println!("{r}");
    }
    println!("\n{}", mon.summary());
    if let Some(dir) = &args.out_dir {
        let area = args.area.unwrap_or_else(|| {
            let pts = mon.tally.accs.values().flat_map(|a| a.fixes.iter());
            let (w, h) = pts.fold((1.0f64, 1.0f64), |(w, h), p| (w.max(p.x), h.max(p.y)));
            Area::new(w, h)
        });
        for f in crate::tally::plot(&mon.tally, area, &[], "hoploc monitor", dir, "monitor")? {
            println!("wrote {}", f.display());
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
        }));
        assert_eq!(
            rows,
            ["status at 61 s: 1203 frames, 240 reports, 3 dropped, 1 corrupt, 17 foreign, 480 fixes"]
        );
        assert!(m.feed("random noise").is_empty());
        assert_eq!(
            m.counts,
            Counts {
                fixes: 4,
                nofixes: 1,
                reports: 0,
                status: 1,
                damaged: 1,
                other: 2,
            }
        );
        let k = crate::tally::truth_key(Some(Point::new(2.0, 3.0)));
        assert_eq!(m.tally.get(k, "MLE").unwrap().len(), 3);
        assert_eq!(m.tally.get(k, "MMSE").unwrap().len(), 1);
        assert!(m.summary().contains("4 fix lines, 1 nofix"));
    }
}
