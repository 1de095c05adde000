//! `hoploc demo`: the emulated testbed (`docs/design.md`, section 8) running a scenario, and the
//! boot timeline.
//!
//! [`run`] (`hoploc demo [SCENARIO]`): the scenario's anchors and agent as their real firmware in
//! simavr on the modelled radio medium ([`crate::testbed`]), the agent moved along its path;
//! every fix of the sink printed live against the truth, then an RMSE/bias table per position
//! and estimator, and plots, CSV and the sink's log in the out dir.
//!
//! [`run_boot`] (`hoploc demo --boot`): the three firmwares boot, each on a factory-fresh XBee,
//! look for their radio in API mode at 57600, find it instead in transparent mode at 9600 baud (as
//! Digi ships it), switch it to API mode 2 at 57600 through command mode (`+++`, `ATAP2`, `ATBD6`,
//! `ATWR`, `ATCN`), then set MY/ID/CH through API frames and read each back.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use loc_proto::sink_line::SinkLine;

use loc_proto::line::{BootLine, ConfigSource, RadioFound};
use simavr::xbee::{baud_of_bd, XBee, XBeeConfig};
use simavr::{ms_to_cycles, Avr};
use xbee_api::driver::Error as RadioError;
use xbee_api::Frame;

use crate::firmware::{self, Role};
use crate::fixes::Algo;
use crate::out::Out;
use crate::scenario::{self, Scenario};
use crate::testbed::{Observed, RunConfig, SinkSource, Testbed};
use crate::web::{AnchorPos, AnchorWatch, Event, Setup, Status, StatusWatch, Web, WebArgs};
use crate::{args as arg, outln};

/// One simulated node: its firmware and its radio.
struct Node {
    role: Role,
    avr: Avr,
    radio: XBee,
    lines_seen: usize,
    frames_seen: usize,
}

/// A frame the firmware sent its radio, in a few words.
pub fn describe(data: &[u8]) -> String {
    match Frame::parse(data) {
        Ok(Frame::AtCommand {
            command, parameter, ..
        }) => {
            let cmd = String::from_utf8_lossy(&command);
            if parameter.is_empty() {
                format!("API AT {cmd}?")
            } else {
                let hex: String = parameter.iter().map(|b| format!("{b:02X}")).collect();
                format!("API AT {cmd}={hex}")
            }
        }
        Ok(Frame::Tx16 { dest, data, .. }) => format!("TX16 to {dest:04X}, {} bytes", data.len()),
        Ok(f) => format!("frame {:#04x}", f.frame_type()),
        Err(e) => format!("malformed frame: {e}"),
    }
}

/// A text line the firmware wrote, in a few words: its boot lines explained, anything else
/// (the command-mode lines `+++`, `ATAP2`… it sends the radio) quoted.
pub fn describe_line(text: &str) -> String {
    match BootLine::parse(text) {
        Ok(BootLine::Boot { .. }) => "boot".to_string(),
        Ok(BootLine::RadioUp {
            found: RadioFound::Api,
            ..
        }) => "radio up: it was already in API mode 2 at 57600".to_string(),
        Ok(BootLine::RadioUp {
            found: RadioFound::Configured { baud },
            ..
        }) => format!(
            "radio up: found in command mode at {baud} baud, now API mode 2 at 57600 (saved)"
        ),
        Ok(BootLine::RadioError { code, attempt, .. }) => format!(
            "radio error {code} on try {attempt} ({}); the LED blinks {code} times, then it retries",
            RadioError::describe_code(code).unwrap_or("unknown error")
        ),
        Ok(BootLine::Provisioned { .. }) => "provisioned: a config was stored in EEPROM".to_string(),
        Ok(BootLine::Config {
            source: ConfigSource::Eeprom,
            id,
            ..
        }) => format!("config from EEPROM: node {id}"),
        Ok(BootLine::Config {
            source: ConfigSource::BuiltIn,
            id,
            ..
        }) => format!("config built in (EEPROM erased): node {id}"),
        Ok(BootLine::ConfigError { code, .. }) => format!(
            "config error {code}: the EEPROM holds a config it must not run with; it waits for `hoploc provision`"
        ),
        Err(_) => format!("sends \"{text}\""),
    }
}

/// Runs the boot timeline for `seconds` of simulated time.
pub fn run_boot(firmware_dir: &Path, seconds: f64) -> Result<(), String> {
    firmware::ensure_built(firmware_dir)?;
    let mut out = Out::stdout();
    let mut nodes = Vec::new();
    for (i, role) in Role::ALL.into_iter().enumerate() {
        let path = firmware::elf(firmware_dir, role);
        let avr = firmware::load(&path, role)?;
        let radio = XBee::new(XBeeConfig {
            sh_sl: 0x0013_A200_4000_0001 + i as u64,
            ..XBeeConfig::default()
        });
        nodes.push(Node {
            role,
            avr,
            radio,
            lines_seen: 0,
            frames_seen: 0,
        });
    }
    outln!(
        out,
        "hoploc demo: {} nodes in simavr, each with a factory-fresh XBee (AP=0, 9600 baud)\n",
        nodes.len()
    );
    outln!(out, "{:>9}  {:<7} event", "time", "node");
    let step = ms_to_cycles(1.0);
    let end = ms_to_cycles(seconds * 1000.0);
    let mut t = 0;
    while t < end && !out.closed() {
        t = (t + step).min(end);
        for n in &mut nodes {
            n.radio.run_until(&mut n.avr, t);
            let mut events: Vec<(f64, String)> = Vec::new();
            for line in &n.radio.text_lines()[n.lines_seen..] {
                events.push((line.ms(), describe_line(&line.text)));
            }
            for f in &n.radio.frames_from_firmware()[n.frames_seen..] {
                events.push((f.ms(), describe(&f.data)));
            }
            n.lines_seen = n.radio.text_lines().len();
            n.frames_seen = n.radio.frames_from_firmware().len();
            events.sort_by(|a, b| a.0.total_cmp(&b.0));
            for (ms, what) in events {
                outln!(out, "{ms:>7.1}ms  {:<7} {what}", n.role.name());
            }
        }
    }
    outln!(out, "\nradios after {seconds} s:");
    outln!(
        out,
        "{:<7} {:>3} {:>7} {:>6} {:>6} {:>4} {:>7} {:>9}",
        "node",
        "AP",
        "baud",
        "MY",
        "ID",
        "CH",
        "frames",
        "stack"
    );
    for n in &nodes {
        let r = n.radio.registers();
        // BD beyond the table (a non-standard rate) shows as its raw value.
        let baud = baud_of_bd(r.bd()).unwrap_or(r.bd());
        let stack = n
            .avr
            .stack_peak()
            .map_or("-".to_string(), |s| format!("{s} B"));
        outln!(
            out,
            "{:<7} {:>3} {:>7} {:>6} {:>6} {:>4} {:>7} {:>9}",
            n.role.name(),
            r.ap(),
            baud,
            format!("{:04X}", r.my()),
            format!("{:04X}", r.id()),
            format!("{:02X}", r.ch()),
            n.radio.stats().frames_ok,
            stack
        );
    }
    Ok(())
}

/// `hoploc demo`'s options.
#[derive(Clone, Debug, clap::Args)]
pub struct Args {
    /// A scenario: a name from scenarios/ (room10, exp1, exp1-chip, exp2, exp3, exp3-fading,
    /// exp3-ideal, and the thesis-length exp1-3a, exp1-4a, exp1-chip-3a, exp1-chip-4a) or
    /// a path to a scenario file (format: scenarios/README.md).
    #[arg(default_value = "room10")]
    pub scenario: String,
    /// Where the sink lines come from: `firmware` reads them off the sink firmware's UART in
    /// simavr (sink-fw, as on a board); `host` is the host sink (the sink firmware's logic,
    /// sink_fw::Sink, run on the host behind a host radio on the sink channel: the same lines,
    /// not the firmware).
    #[arg(long, value_enum, default_value_t = SinkSource::Firmware)]
    pub sink: SinkSource,
    /// The medium's seed [default: the scenario's].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Where the plots (fixes, error over time; SVG and PNG), fixes.csv, table.txt and the
    /// sink's lines (sink.log) go; sink.log and fixes.csv are written as the run goes [default:
    /// target/demo/SCENARIO of the hoploc workspace or the current directory].
    #[arg(long)]
    pub out_dir: Option<PathBuf>,
    /// Simulated seconds to run at most (the scenario is cut short); with --boot the length of
    /// the timeline [default: the whole scenario; with --boot 10; 0.001…31536000].
    #[arg(long, value_parser = arg::seconds)]
    pub seconds: Option<f64>,
    /// Show at most one live fix per this many simulated seconds (every fix is in the table,
    /// the CSV and the plots) [0…86400].
    #[arg(long, default_value_t = 1.0, value_parser = arg::interval)]
    pub live_every: f64,
    /// Network stepping threads (results do not depend on it; on a machine busy with other
    /// work one thread can be faster: the threads meet twice per simulated millisecond)
    /// [1…256].
    #[arg(long, default_value_t = 2, value_parser = arg::threads)]
    pub threads: usize,
    /// Probability of a bit error in each byte on every firmware↔radio UART (e.g. 1e-3)
    /// [0…1].
    #[arg(long, default_value_t = 0.0, value_parser = arg::probability)]
    pub uart_errors: f64,
    /// After the run, every report the sink received located on the host by every algorithm ×
    /// channel refinement of the thesis (MLE, MDS, trilateration/quadlateration; each channel,
    /// Max, Linear avg, Extended), with the sink's online P0/α: README.md with RMSE and MLE
    /// bias tables, bar charts, estimates.csv and, with drift or a long stop, time series,
    /// written into this directory (e.g. `hoploc demo exp1-4a --report exp1-report`).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// The boot timeline instead: the anchor, agent and sink firmware boot, each on a
    /// factory-fresh XBee, and configure it through command mode and API frames.
    #[arg(long, conflicts_with = "web")]
    pub boot: bool,
    /// Directory with anchor-fw.elf, agent-fw.elf and sink-fw.elf [default:
    /// $HOPLOC_FIRMWARE_DIR, else target/avr-none/fw of the hoploc workspace or the current
    /// directory].
    #[arg(long)]
    pub firmware_dir: Option<PathBuf>,
    /// Run at most this many simulated seconds per second of the clock (0: as fast as the
    /// emulation goes) [default: 1 with --web, so the live map moves as boards would; else 0;
    /// 0…1000].
    #[arg(long, value_parser = arg::speed)]
    pub speed: Option<f64>,
    /// The live map (`--web`): its options.
    #[command(flatten)]
    pub web: WebArgs,
}

/// `s` cut to at most `seconds` of simulated time (the stops beyond dropped, the last one
/// shortened).
fn cut(s: &mut Scenario, seconds: f64) -> Result<(), String> {
    let mut left = seconds - s.timing.warmup_s;
    if left <= 0.0 {
        return Err(format!(
            "--seconds {seconds}: the warm-up alone is {} s",
            s.timing.warmup_s
        ));
    }
    let mut path = Vec::new();
    for mut stop in s.agent.path.clone() {
        if left <= 1e-9 {
            break;
        }
        stop.dwell_s = stop.dwell_s.min(left);
        left -= stop.dwell_s;
        path.push(stop);
    }
    s.agent.path = path;
    Ok(())
}

/// `(x, y)` in metres, two decimals.
fn xy(p: [f64; 2]) -> String {
    format!("({:.2}, {:.2})", p[0], p[1])
}

/// Runs `hoploc demo` as `args` say.
pub fn run(args: &Args) -> Result<(), String> {
    let fw_dir = args
        .firmware_dir
        .clone()
        .unwrap_or_else(firmware::default_dir);
    if args.boot {
        return run_boot(&fw_dir, args.seconds.unwrap_or(10.0));
    }
    let path = scenario::find(&args.scenario)?;
    let mut s = Scenario::load(&path).map_err(|e| e.to_string())?;
    if let Some(seed) = args.seed {
        s.seed = seed;
    }
    if let Some(seconds) = args.seconds {
        cut(&mut s, seconds)?;
    }
    let out_dir = args
        .out_dir
        .clone()
        .unwrap_or_else(|| default_out_dir(&s.name));
    std::fs::create_dir_all(&out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    firmware::ensure_built(&fw_dir)?;
    // The sink's log and the fixes are written as they come, a line at a time, so a run that is
    // stopped keeps what it saw.
    let (log_path, csv_path) = (out_dir.join("sink.log"), out_dir.join("fixes.csv"));
    let mut log_file = Appender::create(&log_path)?;
    let mut csv_file = Appender::create(&csv_path)?;
    csv_file.append(crate::fixes::CSV_HEADER)?;
    let mut log_written = 0;
    let mut out = Out::stdout();
    let cfg = RunConfig {
        sink: args.sink,
        threads: args.threads,
        uart_error_rate: args.uart_errors,
    };
    let mut tb = Testbed::new(&s, &fw_dir, &cfg)?;
    let sf = tb.superframe_s();
    let duration = s.duration_s();
    outln!(out, "hoploc demo {}: {}", s.name, s.description);
    outln!(
        out,
        "  {} anchors (anchor-fw) and 1 agent (agent-fw) as real firmware in simavr, {} m × {} m, \
         channels {:?}, {} ms slots: a {:.0} ms superframe, {:.1} fixes/s",
        s.anchors.len(),
        s.area.width_m,
        s.area.height_m,
        s.timing.channels,
        s.timing.slot_ms,
        sf * 1000.0,
        1.0 / sf
    );
    outln!(
        out,
        "  medium: P0 {} dBm, α {}, shadowing σ {} dB, fading σ {} dB, drift {} dB/min, seed {}",
        s.medium.p0_dbm,
        s.medium.alpha,
        s.medium.sigma_db,
        s.medium.fading_sigma_db,
        s.medium.drift_db_per_min,
        s.seed
    );
    outln!(out, "  sink: {}", args.sink.describe());
    {
        outln!(
            out,
            "  MLE-fixed: the host's reference, not a sink line: the MLE of the same report with \
             P0 {} dBm and α {} fixed (no online estimation)",
            s.medium.p0_dbm,
            s.medium.alpha
        );
        outln!(
            out,
            "  MLE-P0only: the host's reference, not a sink line: the f64 MLE of the same report \
             with P0 fitted online from the anchor-to-anchor RSSI and α {} fixed",
            s.medium.alpha
        );
    }
    outln!(
        out,
        "  {duration:.0} s simulated: {} s warm-up (boot, provisioning window, radio bring-up), \
         then {} stops; live: one fix per {} s",
        s.timing.warmup_s,
        s.agent.path.len(),
        args.live_every
    );
    let mut live = match args.web.web {
        true => Some(LiveMap::start(&args.web, &s, sf)?),
        false => None,
    };
    let speed = args.speed.unwrap_or(if live.is_some() { 1.0 } else { 0.0 });
    if let Some(l) = &live {
        outln!(out, "  {}", l.web.banner("until the run ends"));
    }
    if speed > 0.0 {
        outln!(out, "  paced: at most {speed}× real time");
    }
    outln!(out);
    outln!(
        out,
        "{:>8} {:>4} {:>13} {:>13} {:>6} {:>13} {:>6} {:>5} {:>7}  fixed err  P0only err",
        "time",
        "stop",
        "truth (m)",
        "MLE (m)",
        "err",
        "MMSE (m)",
        "err",
        "α",
        "P0",
    );
    let bar = ProgressBar::with_draw_target(
        Some((duration * 1000.0) as u64),
        ProgressDrawTarget::stderr(),
    );
    bar.set_style(
        ProgressStyle::with_template(
            "demo [{elapsed_precise}] {wide_bar} {pos}/{len} simulated ms {msg}",
        )
        .map_err(|e| e.to_string())?,
    );
    let t0 = Instant::now();
    let mut obs: Vec<Observed> = Vec::new();
    let mut last_live = f64::NEG_INFINITY;
    let mut stop_shown = usize::MAX;
    let mut nofix = 0usize;
    let interrupted = |l: &Option<LiveMap>| l.as_ref().is_some_and(|l| l.web.interrupted());
    while !tb.done() && !out.closed() && !interrupted(&live) {
        let new = tb.step(0.25);
        bar.set_position((tb.time_s() * 1000.0) as u64);
        let log = tb.sink_log();
        log_file.append(&log[log_written..])?;
        log_written = log.len();
        // The CSV's rows, the table's and the live map's fixes are the same records.
        for r in crate::fixes::rows(&new) {
            csv_file.append(&crate::fixes::csv_row(&r))?;
            if let Some(l) = &live {
                l.web.fix((&r).into());
            }
        }
        if let Some(l) = &mut live {
            l.step(&tb, &new);
        }
        // A report's MLE and MMSE lines (and the host's reference) come together: one row.
        for pair in new.chunk_by(|a, b| seq_of(&a.line) == seq_of(&b.line)) {
            nofix += pair
                .iter()
                .filter(|o| matches!(o.line, SinkLine::NoFix { .. }))
                .count();
            let fixes = crate::fixes::rows(pair);
            if fixes.is_empty() {
                continue;
            }
            let o = &pair[0];
            let first_of_stop = o.settled && o.stop != stop_shown;
            if !first_of_stop && o.time_s - last_live < args.live_every {
                continue;
            }
            if first_of_stop {
                stop_shown = o.stop;
            }
            last_live = o.time_s;
            let find = |e| fixes.iter().find(|r| r.estimator == e);
            let cell = |r: Option<&crate::fixes::FixRow>| {
                r.map_or(format!("{:>13} {:>6}", "-", "-"), |r| {
                    format!("{:>13} {:>6.2}", xy(r.pos), r.distance())
                })
            };
            let (mle, mmse) = (find(Algo::Mle), find(Algo::Mmse));
            let model = mle.or(mmse).map_or((0.0, 0.0), |r| (r.alpha, r.p0));
            let reference =
                |e, w: usize| find(e).map_or(String::new(), |r| format!(" {:>w$.2}", r.distance()));
            let fixed = format!(
                "{}{}",
                reference(Algo::MleFixed, 10),
                reference(Algo::MleP0Only, 11)
            );
            let note = if o.settled {
                ""
            } else if o.time_s < s.timing.warmup_s + sf {
                "  (warm-up)"
            } else {
                "  (moving)"
            };
            bar.suspend(|| {
                out.line(format_args!(
                    "{:>7.2}s {:>4} {:>13} {} {} {:>5.2} {:>7.2}{fixed}{note}",
                    o.time_s,
                    o.stop + 1,
                    xy(o.truth),
                    cell(mle),
                    cell(mmse),
                    model.0,
                    model.1
                ))
            })?;
        }
        obs.extend(new);
        if args.sink == SinkSource::Firmware
            && tb.time_s() > s.timing.warmup_s + 3.0
            && !obs.iter().any(|o| o.reference.is_none())
        {
            bar.finish_and_clear();
            return Err(format!(
                "the sink firmware wrote no sink line in {:.0} s: is {} a sink firmware that \
                 locates? (`cargo fw` builds it; --sink host runs the sink's logic on the host)",
                tb.time_s(),
                firmware::elf(&fw_dir, Role::Sink).display()
            ));
        }
        if speed > 0.0 {
            let ahead = tb.time_s() / speed - t0.elapsed().as_secs_f64();
            if ahead > 0.0 {
                std::thread::sleep(std::time::Duration::from_secs_f64(ahead));
            }
        }
    }
    // A run ended by Ctrl-C (with --web) is shorter than the scenario.
    let ran = tb.time_s();
    let mut interrupted = false;
    if let Some(l) = live.take() {
        interrupted = l.web.interrupted();
        let why = if interrupted {
            "Ctrl-C"
        } else if out.closed() {
            "the output closed"
        } else {
            "the scenario's end"
        };
        l.web.finish(ran, why);
    }
    let wall = t0.elapsed().as_secs_f64();
    bar.finish_and_clear();
    if interrupted {
        outln!(
            out,
            "\nCtrl-C: stopped at {ran:.1} s of {duration:.0} s simulated"
        );
    }
    let rows = crate::fixes::rows(&obs);
    let stats = crate::fixes::table(&rows, s.agent.path.len());
    let table = crate::fixes::table_text(&stats, &s);
    let reports = rows
        .iter()
        .filter(|r| r.estimator == Algo::Mle && r.time_s >= s.timing.warmup_s)
        .count();
    let counted = (ran - s.timing.warmup_s).max(0.0);
    outln!(
        out,
        "\nRMSE and bias per position and estimator (settled fixes: the superframe after the \
         warm-up and after each move left out):"
    );
    crate::out!(out, "{table}");
    let mut summary = format!(
        "{reports} reports located in {counted:.1} s after the warm-up: {:.2} fixes/s \
         (the superframe allows {:.2}); {nofix} reports without a fix\n",
        if counted > 0.0 {
            reports as f64 / counted
        } else {
            0.0
        },
        1.0 / sf
    );
    if let Some(c) = tb.host_counters() {
        summary += &format!(
            "host sink: {} frames, {} reports, {} missing from the sequence, {} corrupt, {} foreign\n",
            c.frames(),
            c.reports(),
            c.drops(),
            c.checksum_errors(),
            c.foreign()
        );
    } else if let Some(SinkLine::Status {
        uptime_s,
        frames,
        reports,
        drops,
        checksum_errors,
        foreign,
        fixes,
        repeats,
        failed,
        ..
    }) = crate::testbed::last_status(&obs)
    {
        summary += &format!(
            "sink firmware's last status line (at {uptime_s} s): {frames} frames, {reports} \
             reports, {drops} missing from the sequence, {checksum_errors} corrupt, {foreign} \
             foreign, {fixes} fixes, {repeats} repeated, {failed} undelivered\n"
        );
    }
    summary += &format!(
        "emulation: {ran:.1} s simulated in {wall:.2} s: {:.1}× real time ({} threads)\n",
        ran / wall,
        args.threads
    );
    crate::out!(out, "\n{summary}");
    let mut files = crate::fixes::write_plots(&rows, &s, &out_dir)?;
    files.push(csv_path);
    let mut write = |name: &str, text: String| -> Result<(), String> {
        let p = out_dir.join(name);
        std::fs::write(&p, text).map_err(|e| format!("{}: {e}", p.display()))?;
        files.push(p);
        Ok(())
    };
    write(
        "table.txt",
        format!(
            "hoploc demo {} (seed {}, {})\n\n{table}\n{summary}",
            s.name,
            s.seed,
            args.sink.describe()
        ),
    )?;
    log_file.append(&tb.sink_log()[log_written..])?;
    files.push(log_path);
    if let Some(dir) = &args.report {
        let a = crate::thesis::analyze(&s, &obs, &tb.take_reports());
        let command = crate::report::command_line(std::env::args().skip(1));
        files.extend(crate::thesis::write_report(&a, dir, &command)?);
    }
    outln!(out, "\nwritten:");
    for f in files {
        outln!(out, "  {}", f.display());
    }
    Ok(())
}

/// The demo's live map: the server, and what it has sent of the anchors and the sink's counters.
struct LiveMap {
    web: Web,
    /// Reports of the testbed already taken.
    reports: usize,
    health: crate::health::Health,
    anchors: AnchorWatch,
    status: StatusWatch,
}

impl LiveMap {
    /// Serves the live map of scenario `s` (superframe `sf` s) and sends what the run is.
    fn start(args: &WebArgs, s: &Scenario, sf: f64) -> Result<LiveMap, String> {
        let web = Web::start(args, true)?;
        web.send(&Event::Setup(Setup {
            source: "demo",
            title: format!("hoploc demo {}", s.name),
            about: format!(
                "{}; every node's firmware in simavr, simulated time",
                s.description
            ),
            clock: "simulated",
            area: Some([s.area.width_m, s.area.height_m]),
            anchors: s
                .anchors
                .iter()
                .enumerate()
                .map(|(i, a)| AnchorPos {
                    id: i as u8 + 1,
                    x: a.position[0],
                    y: a.position[1],
                })
                .collect(),
            path: s.agent.path.iter().map(|p| p.position).collect(),
            estimators: crate::fixes::ALGOS.map(crate::fixes::name).to_vec(),
            rate: Some(1.0 / sf),
        }));
        Ok(LiveMap {
            web,
            reports: 0,
            health: crate::health::Health::default(),
            anchors: AnchorWatch::new(),
            status: StatusWatch::default(),
        })
    }

    /// After a step that gave `new`: the sink's counters when they changed (its status lines,
    /// or the host sink's), the anchors its new reports heard.
    fn step(&mut self, tb: &Testbed, new: &[Observed]) {
        let mut status: Vec<Status> = new
            .iter()
            .filter_map(|o| Status::of_line(o.time_s, &o.line))
            .collect();
        status.extend(
            tb.host_counters()
                .map(|c| Status::of_counters(tb.time_s(), c)),
        );
        for st in status {
            if let Some(e) = self.status.on(st) {
                self.web.send(&e);
            }
        }
        for (t, r) in &tb.reports()[self.reports..] {
            let health = self.health.on_report(r);
            if let Some(e) = self.anchors.on_report(*t, r, &health, &self.health) {
                self.web.send(&e);
            }
        }
        self.reports = tb.reports().len();
    }
}

/// Where the demo's files go without --out-dir: `target/demo/NAME` of the workspace hoploc runs
/// in ([`firmware::workspace`]), else of the current directory.
pub fn default_out_dir(scenario: &str) -> PathBuf {
    firmware::workspace()
        .unwrap_or_default()
        .join("target/demo")
        .join(scenario)
}

/// A file written a piece at a time, each piece flushed to the disk's cache at once.
struct Appender {
    path: PathBuf,
    file: File,
}

impl Appender {
    /// A new (emptied) file at `path`.
    fn create(path: &Path) -> Result<Appender, String> {
        let file = File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(Appender {
            path: path.to_path_buf(),
            file,
        })
    }

    /// Writes `text` at the end.
    fn append(&mut self, text: &str) -> Result<(), String> {
        self.file
            .write_all(text.as_bytes())
            .and_then(|()| self.file.flush())
            .map_err(|e| format!("{}: {e}", self.path.display()))
    }
}

/// The (agent, sequence) of a fix or nofix line.
fn seq_of(l: &SinkLine) -> Option<(u8, u16)> {
    match *l {
        SinkLine::Fix { agent, seq, .. } | SinkLine::NoFix { agent, seq, .. } => Some((agent, seq)),
        SinkLine::Status { .. } => None,
    }
}
