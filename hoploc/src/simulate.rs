//! `hoploc simulate`: the command around [`crate::study`]: flags, tables (text, CSV, JSON), files
//! and empirical-CDF plots.
//!
//! * Text: per σ, an RMSE table (mean over the points of the per-point RMSE, metres) and a bias
//!   table (standard deviation over the points of the per-point mean error, `x / y`, metres).
//! * CSV: one line per cell, `sigma_db,row,anchors,column,rmse_m,rmse_se_m,bias_x_m,bias_y_m,
//!   failures` (empty where a row has no such figure: the bounds have no bias, the CRLB no
//!   standard error).
//! * JSON: [`StudyResult`] (configuration, columns, and per σ the rows with their cells). No
//!   timing in it, so the same seed gives the same bytes.
//! * Plots (with `--out-dir`): per σ and anchor count one figure, `cdf-sigma<σ>-<n>anchors` as
//!   SVG and PNG: top row the empirical CDF over the points of the per-point RMSE (estimators,
//!   CRLB and MMSE floor), bottom row that of the per-point bias magnitude `|mean error|`, one
//!   panel per column. The PNG's text is drawn with the DejaVu Sans subset embedded from
//!   `hoploc/assets/` (no system fonts needed); the SVG names the font `sans-serif`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use loc_core::grid::Search;
use loc_core::params::FitMethod;
use loc_core::{Area, PathLoss};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::report;
use crate::study::{self, Algo, Config, ParamSource, Row, RowKind, StudyResult};

/// Output format on stdout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// Aligned tables.
    Text,
    /// One line per cell.
    Csv,
    /// The whole result.
    Json,
}

/// How P0 and α are fitted (estimated modes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FitArg {
    /// Exact least squares within the bounds.
    Ls,
    /// The thesis' grid (α step 0.1, P0 step 0.5 dB).
    Grid,
}

/// The MLE's grid search.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SearchArg {
    /// Coarse 10 %, fine 2 % around the coarse winner.
    Thesis,
    /// Coarse 10 %, descent from the four best coarse points (same budget).
    Multistart,
    /// All 51 × 51 fine points.
    Exhaustive,
}

/// The flags of `hoploc simulate`.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Area in metres, `W` (square) or `WxH`; anchors at its corners, the agent on a 19 × 19
    /// interior grid scaled to it [each side above 0, at most 10000 m].
    #[arg(long, default_value = "10", value_parser = parse_area)]
    pub area: Area,
    /// Anchor layouts, comma-separated: 3 (0,0),(W,0),(W,H); 4 adds (0,H).
    #[arg(long, value_delimiter = ',', default_value = "3,4", value_parser = parse_anchor_count)]
    pub anchors: Vec<usize>,
    /// Monte Carlo runs per agent position [1…1000000].
    #[arg(long, default_value_t = 100, value_parser = parse_runs)]
    pub runs: usize,
    /// Shadowing σ values in dB, one table each [each above 0, at most 30].
    #[arg(long, num_args = 1.., default_values_t = [2.0, 4.0], value_parser = parse_sigma)]
    pub sigma: Vec<f64>,
    /// Channels with independent noise [1…4].
    #[arg(long, default_value_t = 2, value_parser = parse_channels)]
    pub channels: usize,
    /// True path-loss exponent α [above 0, at most 10].
    #[arg(long, default_value_t = 3.0, value_parser = parse_alpha)]
    pub alpha: f64,
    /// True received power at 1 m, dBm [−150…30].
    #[arg(long, default_value_t = -40.0, allow_negative_numbers = true, value_parser = parse_p0)]
    pub p0: f64,
    /// What the estimators know: the true P0/α/σ, or fits per trial from simulated
    /// anchor-to-anchor RSSI (ar1: smoothed over the runs at a point).
    #[arg(long, value_enum, default_value_t = ParamSource::Known)]
    pub params: ParamSource,
    /// P0/α fit when estimated: exact least squares in the bounds, or the thesis' grid.
    #[arg(long, value_enum, default_value_t = FitArg::Ls)]
    pub fit: FitArg,
    /// Estimators, comma-separated: MLE, MMSE, TRLT, QUAD, MDS, and MMSE-window (the sink's
    /// windowed MMSE, not in the default).
    #[arg(long, alias = "estimators", value_delimiter = ',', default_value = "MLE,MMSE,TRLT,QUAD,MDS", value_parser = parse_algo)]
    pub estimator: Vec<Algo>,
    /// The MLE's grid search.
    #[arg(long, value_enum, default_value_t = SearchArg::Thesis)]
    pub search: SearchArg,
    /// Leave the baselines' (TRLT, QUAD, MDS) estimates where they fall, outside the area too.
    /// By default they are clipped to the area, as in the thesis' study, whose Tables 3.1 and
    /// 3.3 are reproduced only so.
    /// Example: hoploc simulate --no-clip --estimator TRLT,QUAD,MDS
    #[arg(long)]
    pub no_clip: bool,
    /// Clip the baselines' estimates to the area: the default (accepted for scripts that
    /// still say it).
    #[arg(long, hide = true, conflicts_with = "no_clip")]
    pub clip: bool,
    /// Leave out the MMSE floor rows (with known parameters and the MMSE rows they cost
    /// nothing; otherwise about as much as three MMSE columns).
    #[arg(long)]
    pub no_floor: bool,
    /// Master seed (same seed, same tables, whatever the thread count).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads [default: all cores; 1…256].
    #[arg(long, value_parser = crate::args::threads)]
    pub threads: Option<usize>,
    /// Output on stdout.
    #[arg(long, value_enum, default_value_t = Format::Text)]
    pub format: Format,
    /// Also write study.txt, study.csv, study.json and the CDF plots (SVG, PNG) here.
    #[arg(long)]
    pub out_dir: Option<PathBuf>,
    /// Also write a Markdown page, DIR/README.md, with this command line, the configuration,
    /// the tables, the CDF plots (PNG linked to SVG, written next to it), study.csv, and what
    /// the results show (winner, margins, distance to the bounds), computed from them.
    /// Example: hoploc simulate --report docs/study
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
}

fn parse_area(s: &str) -> Result<Area, String> {
    let num = |v: &str| {
        crate::args::side_m(v).map_err(|e| format!("`{s}`: expected W or WxH in metres: {e}"))
    };
    match s.split_once(['x', 'X', '×']) {
        Some((w, h)) => Ok(Area::new(num(w)?, num(h)?)),
        None => {
            let w = num(s)?;
            Ok(Area::new(w, w))
        }
    }
}

fn parse_anchor_count(s: &str) -> Result<usize, String> {
    crate::args::int_in(s, 3, 4, " anchors (the layouts: 3 or 4)")
}

fn parse_runs(s: &str) -> Result<usize, String> {
    crate::args::int_in(s, 1, 1_000_000, " runs")
}

fn parse_sigma(s: &str) -> Result<f64, String> {
    crate::args::float_in(s, 0.0, 30.0, true, " dB")
}

fn parse_channels(s: &str) -> Result<usize, String> {
    crate::args::int_in(s, 1, loc_core::MAX_CHANNELS, " channels")
}

fn parse_alpha(s: &str) -> Result<f64, String> {
    crate::args::float_in(s, 0.0, 10.0, true, "")
}

fn parse_p0(s: &str) -> Result<f64, String> {
    crate::args::float_in(s, -150.0, 30.0, false, " dBm")
}

fn parse_algo(s: &str) -> Result<Algo, String> {
    Algo::parse(s)
        .ok_or_else(|| format!("`{s}`: expected one of MLE, MMSE, TRLT, QUAD, MDS, MMSE-window"))
}

impl Args {
    /// The study these flags describe.
    pub fn config(&self) -> Config {
        let mut algos = Vec::new();
        for a in &self.estimator {
            if !algos.contains(a) {
                algos.push(*a);
            }
        }
        let mut anchor_counts = Vec::new();
        for n in &self.anchors {
            if !anchor_counts.contains(n) {
                anchor_counts.push(*n);
            }
        }
        Config {
            area: self.area,
            anchor_counts,
            runs: self.runs,
            sigmas: self.sigma.clone(),
            channels: self.channels,
            truth: PathLoss {
                p0: self.p0,
                alpha: self.alpha,
            },
            params: self.params,
            fit: match self.fit {
                FitArg::Ls => FitMethod::LeastSquares,
                FitArg::Grid => FitMethod::Grid,
            },
            algos,
            search: match self.search {
                SearchArg::Thesis => Search::Thesis,
                SearchArg::Multistart => Search::MultiStart,
                SearchArg::Exhaustive => Search::Exhaustive,
            },
            clip: !self.no_clip,
            floor: !self.no_floor,
            seed: self.seed,
            threads: self
                .threads
                .unwrap_or_else(|| Config::default().threads)
                .max(1),
        }
    }
}

/// Runs the command: the study with a progress bar, the tables on stdout, files in `--out-dir`.
pub fn run(args: &Args) -> Result<(), String> {
    let cfg = args.config();
    cfg.validate()?;
    let bar = ProgressBar::with_draw_target(Some(cfg.total_points()), ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template("simulate [{elapsed_precise}] {wide_bar} {pos}/{len} points")
            .map_err(|e| e.to_string())?,
    );
    let t0 = Instant::now();
    let result = study::run(&cfg, &|k| bar.inc(k))?;
    let secs = t0.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let body = match args.format {
        Format::Text => text(&result),
        Format::Csv => csv(&result),
        Format::Json => json(&result)?,
    };
    // A closed stdout (`| head`) ends the printing quietly; the files are still written.
    crate::out::Out::stdout().write(format_args!("{body}"))?;
    eprintln!(
        "hoploc simulate: {secs:.2} s on {} thread{}",
        cfg.threads,
        if cfg.threads == 1 { "" } else { "s" }
    );
    if let Some(dir) = &args.out_dir {
        let files = write_files(&result, dir)?;
        for f in files {
            eprintln!("wrote {}", f.display());
        }
    }
    if let Some(dir) = &args.report {
        let command = report::command_line(std::env::args().skip(1));
        for f in report::write(&result, dir, &command)? {
            eprintln!("wrote {}", f.display());
        }
    }
    Ok(())
}

/// Writes `study.txt`, `study.csv`, `study.json` and the plots into `dir` (created if needed);
/// returns the paths written.
pub fn write_files(result: &StudyResult, dir: &Path) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut files = Vec::new();
    for (name, body) in [
        ("study.txt", text(result)),
        ("study.csv", csv(result)),
        ("study.json", json(result)?),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, body).map_err(|e| format!("{}: {e}", path.display()))?;
        files.push(path);
    }
    files.extend(write_plots(result, dir)?);
    Ok(files)
}

/// A number as the tables print it (`σ = 2`, `2.5`).
pub(crate) fn num(v: f64) -> String {
    let s = format!("{v}");
    s.strip_suffix(".0").map(str::to_owned).unwrap_or(s)
}

fn params_text(result: &StudyResult) -> String {
    let c = &result.config;
    match c.params {
        ParamSource::Known => format!(
            "known parameters (P0 = {} dBm, α = {}, σ)",
            num(c.p0),
            num(c.alpha)
        ),
        ParamSource::Estimated => format!(
            "P0/α/σ fitted per trial from anchor-to-anchor RSSI ({} fit; truth P0 = {} dBm, α = {})",
            c.fit,
            num(c.p0),
            num(c.alpha)
        ),
        ParamSource::Ar1 => format!(
            "P0/α/σ fitted per trial, AR(1)-smoothed over the runs ({} fit; truth P0 = {} dBm, α = {})",
            c.fit,
            num(c.p0),
            num(c.alpha)
        ),
    }
}

/// The aligned text tables.
pub fn text(result: &StudyResult) -> String {
    let c = &result.config;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "hoploc simulate: {} m × {} m, anchors {:?}, {} points × {} runs, {} channel{}, {}, {} search{}, seed {}",
        num(c.width),
        num(c.height),
        c.anchor_counts,
        c.points,
        c.runs,
        c.channels,
        if c.channels == 1 { "" } else { "s" },
        params_text(result),
        c.search,
        if c.clip { ", baselines clipped" } else { ", baselines not clipped" },
        c.seed
    );
    let label_w = result
        .tables
        .iter()
        .flat_map(|t| t.rows.iter().map(|r| r.label.len()))
        .max()
        .unwrap_or(0)
        .max(8);
    let col_w = |label: &str| label.len().max(13);
    for t in &result.tables {
        for (title, bias) in [
            ("mean per-point RMSE (m)", false),
            (
                "bias (m): std over points of the per-point mean error, x / y",
                true,
            ),
        ] {
            let _ = writeln!(s, "\nσ = {} dB: {title}", num(t.sigma));
            let _ = write!(s, "{:label_w$}", "");
            for col in &result.columns {
                let _ = write!(s, "  {:>w$}", col, w = col_w(col));
            }
            s.push('\n');
            for row in &t.rows {
                if bias && !matches!(row.kind, RowKind::Estimator(_)) {
                    continue;
                }
                let _ = write!(s, "{:label_w$}", row.label);
                for (col, cell) in result.columns.iter().zip(&row.cells) {
                    let v = match (cell, bias) {
                        (None, _) => String::new(),
                        (Some(c), false) => format!("{:.3}", c.rmse),
                        (Some(c), true) => match (c.bias_x, c.bias_y) {
                            (Some(x), Some(y)) => format!("{x:.3} / {y:.3}"),
                            _ => String::new(),
                        },
                    };
                    let _ = write!(s, "  {:>w$}", v, w = col_w(col));
                }
                s.push('\n');
            }
        }
    }
    let failures: u64 = result
        .tables
        .iter()
        .flat_map(|t| &t.rows)
        .flat_map(|r| r.cells.iter().flatten())
        .map(|c| c.failures)
        .sum();
    let _ = writeln!(
        s,
        "\nCRLB: C = 1 for a single channel, C = {} (all channels) for Max, Linear avg, Ext-MCH.",
        c.channels
    );
    if c.floor {
        let _ = writeln!(
            s,
            "MMSE floor: the posterior mean knowing the true model and σ, on the study's draws \
             (one channel for ChN, all channels for the others)."
        );
    }
    if failures > 0 {
        let _ = writeln!(
            s,
            "{failures} baseline estimates failed (degenerate geometry) and count at the area's centre."
        );
    }
    s
}

fn opt(v: Option<f64>) -> String {
    v.map(|x| format!("{x}")).unwrap_or_default()
}

/// The CSV: one line per cell (header first).
pub fn csv(result: &StudyResult) -> String {
    let mut s =
        String::from("sigma_db,row,anchors,column,rmse_m,rmse_se_m,bias_x_m,bias_y_m,failures\n");
    for t in &result.tables {
        for row in &t.rows {
            for (col, cell) in result.columns.iter().zip(&row.cells) {
                if let Some(c) = cell {
                    let _ = writeln!(
                        s,
                        "{},{},{},{},{},{},{},{},{}",
                        t.sigma,
                        row.label,
                        row.anchors,
                        col,
                        c.rmse,
                        opt(c.rmse_se),
                        opt(c.bias_x),
                        opt(c.bias_y),
                        c.failures
                    );
                }
            }
        }
    }
    s
}

/// The JSON document.
pub fn json(result: &StudyResult) -> Result<String, String> {
    serde_json::to_string_pretty(result)
        .map(|mut s| {
            s.push('\n');
            s
        })
        .map_err(|e| e.to_string())
}

// ---------------------------------------------------------------------------------------------
// Plots.

/// The font the plots' text is drawn with (a subset of DejaVu Sans: ASCII, Greek, a few math
/// signs; see `hoploc/assets/README.md`).
///
/// Every text size is even: plotters' ab_glyph renderer places each glyph at
/// `(size / 2 + top) as i32`, which truncates towards zero, so with an odd size the glyphs that
/// rise above half the size (capitals, digits) land a pixel low next to the others.
static FONT: &[u8] = include_bytes!("../assets/DejaVuSans-subset.ttf");

pub(crate) fn register_font() -> Result<(), String> {
    static ONCE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *ONCE.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok()
    });
    ok.then_some(())
        .ok_or_else(|| "the embedded plot font does not load".to_string())
}

/// One curve: label, colour, dashed, values.
struct Curve {
    label: String,
    color: RGBColor,
    dashed: bool,
    values: Vec<f64>,
}

fn color(row: &Row) -> (RGBColor, bool) {
    match row.kind {
        RowKind::Estimator(Algo::Mle) => (RGBColor(31, 119, 180), false),
        RowKind::Estimator(Algo::Mmse) => (RGBColor(214, 39, 40), false),
        RowKind::Estimator(Algo::MmseWindow) => (RGBColor(140, 86, 75), false),
        RowKind::Estimator(Algo::Mds) => (RGBColor(44, 160, 44), false),
        RowKind::Estimator(Algo::Trlt) => (RGBColor(255, 127, 14), false),
        RowKind::Estimator(Algo::Quad) => (RGBColor(148, 103, 189), false),
        RowKind::Crlb => (RGBColor(0, 0, 0), true),
        RowKind::MmseFloor => (RGBColor(127, 127, 127), true),
    }
}

/// The step points of the empirical CDF of `v`.
fn ecdf(v: &[f64]) -> Vec<(f64, f64)> {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    s.sort_by(f64::total_cmp);
    let n = s.len() as f64;
    let mut out = Vec::with_capacity(2 * s.len() + 1);
    if let Some(&first) = s.first() {
        out.push((first, 0.0));
    }
    for (k, &x) in s.iter().enumerate() {
        out.push((x, k as f64 / n));
        out.push((x, (k + 1) as f64 / n));
    }
    out
}

/// The file stem of a figure.
pub fn plot_stem(sigma: f64, anchors: usize) -> String {
    format!("cdf-sigma{}-{anchors}anchors", num(sigma).replace('.', "p"))
}

/// Writes one SVG and one PNG per σ and anchor count; returns the paths.
pub fn write_plots(result: &StudyResult, dir: &Path) -> Result<Vec<PathBuf>, String> {
    register_font()?;
    let mut files = Vec::new();
    let ncol = result.columns.len();
    let size = (300 * ncol as u32 + 20, 640);
    let diag = result.config.width.hypot(result.config.height);
    for t in &result.tables {
        for &n in &result.config.anchor_counts {
            let rows: Vec<&Row> = t.rows.iter().filter(|r| r.anchors == n).collect();
            let title = format!(
                "σ = {} dB, {n} anchors, {} runs × {} points: empirical CDF over the points",
                num(t.sigma),
                result.config.runs,
                result.config.points
            );
            let stem = plot_stem(t.sigma, n);
            let svg = dir.join(format!("{stem}.svg"));
            draw(
                SVGBackend::new(&svg, size).into_drawing_area(),
                &title,
                &result.columns,
                &rows,
                diag,
            )
            .map_err(|e| format!("{}: {e}", svg.display()))?;
            files.push(svg);
            let png = dir.join(format!("{stem}.png"));
            let mut rgb = vec![0u8; 3 * size.0 as usize * size.1 as usize];
            draw(
                BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area(),
                &title,
                &result.columns,
                &rows,
                diag,
            )
            .and_then(|()| write_png(&png, size, &rgb))
            .map_err(|e| format!("{}: {e}", png.display()))?;
            files.push(png);
        }
    }
    Ok(files)
}

/// Writes an RGB buffer as a PNG at the best compression (about a fifth of plotters' own
/// encoder's size: the plots are committed in docs/study/).
pub(crate) fn write_png(path: &Path, (w, h): (u32, u32), rgb: &[u8]) -> Result<(), String> {
    let file = std::fs::File::create(path).map_err(|e| e.to_string())?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::Best);
    enc.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
    let mut writer = enc.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(rgb).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())
}

/// Drops the points of a polyline that do not change it at the backend's pixel resolution:
/// repeats of the previous pixel, and middle points of axis-parallel runs. An empirical CDF over
/// 361 points has 723 vertices, most of them inside a pixel or on a straight stretch; without
/// this each SVG is ~5× larger (the PNG is unchanged either way).
fn thin(points: Vec<(f64, f64)>, pixel: impl Fn(&(f64, f64)) -> (i32, i32)) -> Vec<(f64, f64)> {
    let mut out: Vec<((f64, f64), (i32, i32))> = Vec::with_capacity(points.len());
    for p in points {
        let q = pixel(&p);
        if out.last().is_some_and(|&(_, last)| last == q) {
            continue;
        }
        if let [.., (_, a), (_, b)] = out[..] {
            let between = |a: i32, b: i32, c: i32| (a <= b && b <= c) || (a >= b && b >= c);
            let vertical = a.0 == b.0 && b.0 == q.0 && between(a.1, b.1, q.1);
            let horizontal = a.1 == b.1 && b.1 == q.1 && between(a.0, b.0, q.0);
            if vertical || horizontal {
                out.pop();
            }
        }
        out.push((p, q));
    }
    out.into_iter().map(|(p, _)| p).collect()
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    columns: &[String],
    rows: &[&Row],
    diag: f64,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 20)).map_err(err)?;
    let panels = root.split_evenly((2, columns.len()));
    for (k, area) in panels.iter().enumerate() {
        let (bias, ci) = (k >= columns.len(), k % columns.len());
        let curves: Vec<Curve> = rows
            .iter()
            .filter_map(|r| {
                let cell = r.cells.get(ci)?.as_ref()?;
                let values = if bias {
                    &cell.per_point_bias
                } else {
                    &cell.per_point_rmse
                };
                let (color, dashed) = color(r);
                (!values.is_empty()).then(|| Curve {
                    label: r.label.clone(),
                    color,
                    dashed,
                    values: values.clone(),
                })
            })
            .collect();
        // Up to the largest value, but no further than the area's diagonal (baselines without
        // clipping can err by more; their curves then leave the panel on the right).
        let xmax = curves
            .iter()
            .flat_map(|c| c.values.iter().copied())
            .filter(|v| v.is_finite())
            .fold(0.0f64, f64::max)
            .min(diag)
            .max(0.01)
            * 1.02;
        let metric = if bias {
            "per-point |bias| (m)"
        } else {
            "per-point RMSE (m)"
        };
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!("{}: {}", columns[ci], if bias { "bias" } else { "RMSE" }),
                ("sans-serif", 16),
            )
            .margin(8)
            .x_label_area_size(34)
            .y_label_area_size(40)
            .build_cartesian_2d(0.0..xmax, 0.0..1.0)
            .map_err(err)?;
        chart
            .configure_mesh()
            // One light line between labels (plotters' default of up to ten made a tenth of
            // each SVG's bytes and a busy background).
            .max_light_lines(1)
            .x_desc(metric)
            .y_desc("fraction of points")
            .label_style(("sans-serif", 12))
            .axis_desc_style(("sans-serif", 12))
            .x_labels(6)
            .y_labels(6)
            .draw()
            .map_err(err)?;
        for c in &curves {
            let pts = thin(ecdf(&c.values), |p| chart.backend_coord(p));
            let style = c.color.stroke_width(2);
            let anno = if c.dashed {
                chart
                    .draw_series(DashedLineSeries::new(pts, 6, 4, style))
                    .map_err(err)?
            } else {
                chart
                    .draw_series(LineSeries::new(pts, style))
                    .map_err(err)?
            };
            let col = c.color;
            anno.label(c.label.as_str()).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], col.stroke_width(2))
            });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 12))
            .draw()
            .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn area_flag() {
        assert_eq!(parse_area("10"), Ok(Area::new(10.0, 10.0)));
        assert_eq!(parse_area("6x4"), Ok(Area::new(6.0, 4.0)));
        assert_eq!(parse_area("30X20.5"), Ok(Area::new(30.0, 20.5)));
        assert!(parse_area("0").is_err());
        assert!(parse_area("-3x4").is_err());
        assert!(parse_area("ax4").is_err());
        assert!(parse_area("nan").unwrap_err().contains("at most 10000 m"));
        assert!(parse_area("1e9x4").is_err());
    }

    #[test]
    fn ecdf_steps() {
        assert_eq!(
            ecdf(&[2.0, 1.0]),
            [(1.0, 0.0), (1.0, 0.0), (1.0, 0.5), (2.0, 0.5), (2.0, 1.0)]
        );
        assert!(ecdf(&[]).is_empty());
    }

    #[test]
    fn thinning_keeps_the_pixel_path() {
        let px = |p: &(f64, f64)| ((p.0 * 10.0).round() as i32, (p.1 * 10.0).round() as i32);
        // Two points in one pixel, a vertical run of three, a horizontal run of three, a turn.
        let pts = vec![
            (0.0, 0.0),
            (0.01, 0.02),
            (0.0, 0.5),
            (0.0, 1.0),
            (0.5, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
        ];
        assert_eq!(
            thin(pts, px),
            [(0.0, 0.0), (0.0, 1.0), (1.0, 1.0), (1.0, 2.0)]
        );
        // A reversal on one axis is not a straight run: its middle point stays.
        let back = vec![(0.0, 0.0), (0.0, 1.0), (0.0, 0.5)];
        assert_eq!(thin(back.clone(), px), back);
    }

    #[test]
    fn plot_names() {
        assert_eq!(plot_stem(2.0, 3), "cdf-sigma2-3anchors");
        assert_eq!(plot_stem(0.5, 4), "cdf-sigma0p5-4anchors");
    }
}
