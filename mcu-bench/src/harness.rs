//! The host side: building the bench firmwares, running them in simavr, reading their markers and
//! results, and the host's own answers for the same inputs (used by
//! `hoploc/benches/mcu_estimate.rs` and `tests/tests/mcu_bench.rs`).

use std::path::{Path, PathBuf};
use std::process::Command;

use simavr::{Avr, State};

use crate::{float, run, Inputs, Report, MARKS, N_ANCHORS, N_CHANNELS, SIGMA_DB};

/// The firmwares, baseline first.
pub const BINS: [&str; 6] = [
    "est-none",
    "est-fixed",
    "est-f32",
    "est-portable",
    "checkasm",
    "board-check",
];
/// The benchmark variants among [`BINS`] (`checkasm` is the kernel's equality harness,
/// `board-check` uno-board's checks).
pub const ESTIMATES: [&str; 4] = ["est-none", "est-fixed", "est-f32", "est-portable"];

/// Simulated time after which a run that has not stopped counts as hung.
const RUN_LIMIT_MS: f64 = 20_000.0;

/// The workspace root (this crate's parent directory).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// Where the ELFs are: `HOPLOC_FIRMWARE_DIR`, else where `cargo fw-bench` puts them
/// (`$CARGO_TARGET_DIR/avr-none/fw`, by default `target/avr-none/fw`).
pub fn elf_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("HOPLOC_FIRMWARE_DIR") {
        return PathBuf::from(dir);
    }
    let target = std::env::var_os("CARGO_TARGET_DIR").map_or_else(
        || workspace_root().join("target"),
        |t| workspace_root().join(t),
    );
    target.join("avr-none/fw")
}

/// The ELF of firmware `bin` (one of [`BINS`]).
pub fn elf(bin: &str) -> PathBuf {
    elf_dir().join(format!("{bin}.elf"))
}

/// Makes sure the ELFs are there and current: runs `cargo fw-bench` (a quick no-op when nothing
/// changed) unless `HOPLOC_FIRMWARE_DIR` points elsewhere, where they must already exist.
pub fn build() -> Result<(), String> {
    if std::env::var_os("HOPLOC_FIRMWARE_DIR").is_some() {
        return match BINS.iter().map(|b| elf(b)).find(|p| !p.exists()) {
            Some(p) => Err(format!("{} is missing", p.display())),
            None => Ok(()),
        };
    }
    let status = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
        .arg("fw-bench")
        .current_dir(workspace_root())
        .status()
        .map_err(|e| format!("could not run cargo fw-bench: {e}"))?;
    if !status.success() {
        return Err("cargo fw-bench failed".into());
    }
    Ok(())
}

/// What one firmware run gave.
#[derive(Clone, Debug)]
pub struct Run {
    /// The firmware.
    pub elf: PathBuf,
    /// Cycle of each marker of [`MARKS`] (the cycle it was written to `UDR0`).
    pub marks: Vec<u64>,
    /// The MLE and MMSE results.
    pub reports: [Report; 2],
    /// Flash bytes (`.text` + `.data` initialisers).
    pub flash: usize,
    /// Static data bytes (`.data` + `.bss`).
    pub static_sram: usize,
    /// Stack peak, bytes.
    pub stack_peak: usize,
}

impl Run {
    /// Cycles of each phase of [`PHASES`](crate::PHASES) (between consecutive markers, overhead
    /// included).
    pub fn phases(&self) -> Vec<u64> {
        self.marks.windows(2).map(|w| w[1] - w[0]).collect()
    }
}

/// Runs `elf` in simavr until it stops and parses what it wrote.
pub fn run_elf(elf: &Path) -> Result<Run, String> {
    let err = |e: simavr::Error| format!("{}: {e}", elf.display());
    let mut avr = Avr::load(elf).map_err(err)?;
    let mut state = State::Running;
    while state.is_alive() && avr.time_ms() < RUN_LIMIT_MS {
        state = avr.run_for_ms(50.0);
    }
    if state != State::Done {
        return Err(format!(
            "{}: did not stop ({state:?} at {:.0} ms); output: {:?}",
            elf.display(),
            avr.time_ms(),
            avr.uart_output_string()
        ));
    }
    let out = avr.uart_output();
    let nl = out
        .iter()
        .position(|b| b.byte == b'\n')
        .ok_or_else(|| format!("{}: no results: {out:?}", elf.display()))?;
    let got: Vec<u8> = out[..nl].iter().map(|b| b.byte).collect();
    if got != MARKS {
        return Err(format!(
            "{}: markers {:?}, expected {:?}",
            elf.display(),
            String::from_utf8_lossy(&got),
            String::from_utf8_lossy(&MARKS)
        ));
    }
    let text: String = out[nl + 1..].iter().map(|b| b.byte as char).collect();
    let reports = parse_reports(&text).map_err(|e| format!("{}: {e}", elf.display()))?;
    let need = |v: Option<usize>, what: &str| {
        v.ok_or_else(|| format!("{}: no {what} (symbols missing)", elf.display()))
    };
    Ok(Run {
        elf: elf.to_path_buf(),
        marks: out[..nl].iter().map(|b| b.cycle).collect(),
        reports,
        flash: need(avr.flash_size(), "flash size")?,
        static_sram: need(avr.static_data_size(), "static data size")?,
        stack_peak: need(avr.stack_peak(), "stack peak")?,
    })
}

/// Parses `mle x y p0 alpha\nmmse x y p0 alpha\nend\n`.
pub fn parse_reports(text: &str) -> Result<[Report; 2], String> {
    let mut lines = text.lines();
    let mut one = |tag: &str| -> Result<Report, String> {
        let line = lines.next().unwrap_or("");
        let mut words = line.split(' ');
        if words.next() != Some(tag) {
            return Err(format!("expected a {tag:?} line, got {line:?}"));
        }
        let v: Vec<u32> = words
            .map(|w| {
                w.parse()
                    .map_err(|_| format!("bad number {w:?} in {line:?}"))
            })
            .collect::<Result<_, _>>()?;
        match v[..] {
            [x, y, p0, alpha] => Ok(Report { x, y, p0, alpha }),
            _ => Err(format!("expected 4 numbers in {line:?}")),
        }
    };
    let r = [one("mle")?, one("mmse")?];
    match lines.next() {
        Some("end") => Ok(r),
        other => Err(format!("expected \"end\", got {other:?}")),
    }
}

/// A result in common units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fix {
    /// Position, mm.
    pub x_mm: f64,
    /// Position, mm.
    pub y_mm: f64,
    /// P0 the estimate used, dBm.
    pub p0: f64,
    /// α the estimate used.
    pub alpha: f64,
}

impl Fix {
    /// From a [`crate::fixed::Fixed`] report.
    pub fn of_fixed(r: &Report) -> Fix {
        Fix {
            x_mm: r.x as f64,
            y_mm: r.y as f64,
            p0: r.p0 as i32 as f64 / 65536.0,
            alpha: r.alpha as i32 as f64 / 16_777_216.0,
        }
    }

    /// From a [`float::F32`] report.
    pub fn of_f32(r: &Report) -> Fix {
        let f = |w: u32| f32::from_bits(w) as f64;
        Fix {
            x_mm: f(r.x) * 1000.0,
            y_mm: f(r.y) * 1000.0,
            p0: f(r.p0),
            alpha: f(r.alpha),
        }
    }

    /// Distance to `o`'s position, mm.
    pub fn dist_mm(&self, o: &Fix) -> f64 {
        (self.x_mm - o.x_mm).hypot(self.y_mm - o.y_mm)
    }
}

/// The fixed path's answers on the host, computed independently of [`crate::fixed`]'s lean
/// sequence: a [`loc_core::fixed::Measurements`], an earlier round's
/// [`OnlineParams::update`](loc_core::fixed::OnlineParams::update), then
/// [`loc_core::fixed::sink_fix`] with the MLE and with [`crate::fixed::MMSE`].
pub fn host_fixed(inp: &Inputs) -> [Report; 2] {
    use loc_core::fixed::{
        sink_fix, AreaCm, CalStats, Estimator, Measurements, PointCm, Refinement, Search,
    };
    let anchors = inp.anchors.map(|[x, y]| PointCm::new(x, y));
    let mut m = Measurements::new(&anchors, N_CHANNELS);
    for a in 0..N_ANCHORS {
        for c in 0..N_CHANNELS {
            m.rssi[a][c] = Some(inp.agent[a][c]);
            for b in (0..N_ANCHORS).filter(|&b| b != a) {
                m.a2a[a][b][c] = Some(inp.a2a_byte(a, b, c));
            }
        }
    }
    let area = AreaCm::new(inp.area[0], inp.area[1]);
    let mut fx = crate::fixed::Fixed::<loc_core::fixed::Portable>::new();
    let _ = fx.params.update(&CalStats::from_measurements(&m, None));
    let mut one = |est: Estimator| {
        let e = sink_fix(&m, area, &mut fx.params, Refinement::Extended, est);
        fx.report(e)
    };
    [one(Estimator::Mle(Search::Thesis)), one(crate::fixed::MMSE)]
}

/// The f32 pipeline run on the host (std's `log10`/`exp` instead of avr-libc's).
pub fn host_f32(inp: &Inputs) -> [Report; 2] {
    run(&mut float::F32::new(), inp, |_| {})
}

/// loc-core's f64 reference for the same sequence (an earlier round, then two estimates with
/// the AR(1)-smoothed least-squares model): the thesis MLE ([`loc_core::grid::mle`]) and the
/// windowed MMSE ([`loc_core::grid::mmse_window`], σ = [`SIGMA_DB`]).
pub fn host_f64(inp: &Inputs) -> [Fix; 2] {
    use loc_core::grid::{self, Search};
    use loc_core::params::{Bounds, FitMethod, OnlineParams, ParamMode};
    use loc_core::refine::{observations, Refinement};
    use loc_core::{Area, Measurements, PathLoss, Point};
    let pos: Vec<Point> = inp
        .anchors
        .iter()
        .map(|&[x, y]| Point::new(x as f64 / 100.0, y as f64 / 100.0))
        .collect();
    let mut m = Measurements::new(&pos, N_CHANNELS);
    for a in 0..N_ANCHORS {
        for c in 0..N_CHANNELS {
            m.anchors[a].rssi[c] = Some(-(inp.agent[a][c] as f64));
            for b in (0..N_ANCHORS).filter(|&b| b != a) {
                m.a2a[a][b][c] = Some(-(inp.a2a_byte(a, b, c) as f64));
            }
        }
    }
    let area = Area::new(inp.area[0] as f64 / 100.0, inp.area[1] as f64 / 100.0);
    let mut params = OnlineParams::new(
        ParamMode::P0AndAlpha,
        FitMethod::LeastSquares,
        Bounds::THESIS,
        PathLoss::THESIS,
    );
    let _ = params.update(&m);
    let obs = observations(&m, Refinement::Extended);
    let fix = |p: Point, model: PathLoss| Fix {
        x_mm: p.x * 1000.0,
        y_mm: p.y * 1000.0,
        p0: model.p0,
        alpha: model.alpha,
    };
    let _ = params.update(&m);
    let model = params.current();
    let mle = grid::mle(&obs, model, area, Search::Thesis)
        .map_or(Point::new(f64::NAN, f64::NAN), |e| e.pos);
    let mle = fix(mle, model);
    let _ = params.update(&m);
    let model = params.current();
    let mmse = grid::mmse_window(&obs, model, area, SIGMA_DB as f64)
        .map_or(Point::new(f64::NAN, f64::NAN), |e| e.pos);
    let mmse = fix(mmse, model);
    [mle, mmse]
}

/// One case of a `checkasm` run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CheckCase {
    /// The case's name.
    pub name: String,
    /// Jobs checked.
    pub jobs: u32,
    /// Jobs whose results differed.
    pub mismatches: u32,
    /// The digest of the portable column's results on the MCU.
    pub portable: u32,
    /// The digest of the kernel's.
    pub kernel: u32,
}

/// What a `checkasm` run gave.
#[derive(Clone, Debug)]
pub struct CheckRun {
    /// The table's cases, in order.
    pub cases: Vec<CheckCase>,
    /// The first mismatches, as printed.
    pub mismatches: Vec<String>,
    /// The timed case and its jobs per loop.
    pub bench: (String, u32),
    /// Cycles of the timed loops: portable column, kernel, generator alone (each one marker's
    /// overhead included).
    pub loops: [u64; 3],
}

impl CheckRun {
    /// Cycles per column call of the portable column and of the kernel, net of the generator.
    pub fn per_call(&self) -> (f64, f64) {
        let jobs = self.bench.1.max(1) as f64;
        let [p, k, g] = self.loops;
        (
            p.saturating_sub(g) as f64 / jobs,
            k.saturating_sub(g) as f64 / jobs,
        )
    }
}

/// Runs the `checkasm` ELF `elf` in simavr until it stops and parses its lines.
pub fn run_checkasm(elf: &Path) -> Result<CheckRun, String> {
    let err = |e: simavr::Error| format!("{}: {e}", elf.display());
    let mut avr = Avr::load(elf).map_err(err)?;
    let mut state = State::Running;
    while state.is_alive() && avr.time_ms() < 20.0 * RUN_LIMIT_MS {
        state = avr.run_for_ms(100.0);
    }
    let text = avr.uart_output_string();
    if state != State::Done {
        return Err(format!(
            "{}: did not stop ({state:?} at {:.0} ms): {text:?}",
            elf.display(),
            avr.time_ms()
        ));
    }
    let bad = |what: &str| format!("{}: {what} in {text:?}", elf.display());
    let (mut cases, mut mismatches, mut bench) = (Vec::new(), Vec::new(), None);
    let out = avr.uart_output();
    let mut at = 0;
    for line in text.split_inclusive('\n') {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.first().copied() {
            Some("case") => {
                let num = |k: usize| words.get(k).and_then(|w| w.parse::<u32>().ok());
                match (words.get(1), num(2), num(3), num(4), num(5)) {
                    (Some(n), Some(jobs), Some(mismatches), Some(portable), Some(kernel)) => cases
                        .push(CheckCase {
                            name: n.to_string(),
                            jobs,
                            mismatches,
                            portable,
                            kernel,
                        }),
                    _ => return Err(bad("a bad case line")),
                }
            }
            Some("mismatch") => mismatches.push(line.trim_end().to_string()),
            Some("bench") => {
                let jobs = words.get(2).and_then(|w| w.parse().ok());
                bench = Some((words.get(1).unwrap_or(&"").to_string(), jobs.unwrap_or(0)));
                at += line.len();
                break;
            }
            _ => return Err(bad("an unexpected line")),
        }
        at += line.len();
    }
    let bench = bench.ok_or_else(|| bad("no bench line"))?;
    let marks: Vec<u64> = out
        .get(at..at + 4)
        .filter(|m| m.iter().all(|b| b.byte == b'A'))
        .ok_or_else(|| bad("no bench markers"))?
        .iter()
        .map(|b| b.cycle)
        .collect();
    if text.get(at + 4..) != Some("\nend\n") {
        return Err(bad("no end after the bench markers"));
    }
    Ok(CheckRun {
        cases,
        mismatches,
        bench,
        loops: [
            marks[1] - marks[0],
            marks[2] - marks[1],
            marks[3] - marks[2],
        ],
    })
}
