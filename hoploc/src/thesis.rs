//! The thesis' per-experiment evaluation of a testbed run: every report the sink received,
//! located on the host by every algorithm × channel refinement of the thesis' Chapter 4
//! (trilateration with 3 anchors or quadlateration with 4, MDS-MAP, the MLE; channel by channel,
//! Max RSSI, linear average and, for the MLE, Extended multichannel), with tables of RMSE per
//! position, the MLE's bias per refinement, bar charts, a CSV of every estimate and, for a run
//! with drift or a long stop, time series (`hoploc demo SCENARIO --report DIR`).
//!
//! Every algorithm that needs a path-loss model uses the P0/α the sink itself used for that
//! report (its online fit from the anchor-to-anchor RSSI, read off its MLE `fix` line), so the
//! baselines and the MLE see the same model. Two more MLE rows show other models for the same
//! reports: `MLE-const` (P0/α fixed at the scenario's starting values) and, under the last
//! refinement only, `MLE-P0only` (the testbed's reference with P0 fitted online and α fixed,
//! [`crate::testbed::Reference::P0Only`]). The MLE is `loc_core::grid::mle` with the thesis'
//! coarse-to-fine search on `loc_core::refine::observations` of the report, the estimator the
//! study's lattice reproduces bit for bit (`hoploc/src/study.rs`); the baselines are
//! `loc_core::baselines` on the distances the model gives, clipped to the room as the MLE's grid
//! is.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use loc_core::baselines::Baseline;
use loc_core::grid::{self, Search};
use loc_core::refine::{observations, Refinement};
use loc_core::{Area, PathLoss, Point};
use loc_proto::msg::Report;
use loc_proto::sink_line::SinkLine;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::scenario::Scenario;
use crate::simulate::{register_font, write_png};
use crate::testbed::{Observed, Reference};

/// Label of the MLE with the sink's online P0/α.
pub const MLE: &str = "MLE";
/// Label of the MLE with P0/α fixed at the scenario's starting values.
pub const MLE_CONST: &str = "MLE-const";
/// Label of the testbed's P0-only reference (P0 fitted online, α fixed).
pub const MLE_P0: &str = "MLE-P0only";
/// Label of MDS-MAP.
pub const MDS: &str = "MDS";
/// Label of the Extended multichannel refinement.
pub const EXT: &str = "Ext-MCH";

/// One estimate of one report.
#[derive(Clone, Debug, PartialEq)]
pub struct Est {
    /// Simulated time of the report, s.
    pub time_s: f64,
    /// Report sequence.
    pub seq: u16,
    /// The agent's stop.
    pub stop: usize,
    /// The true position, m.
    pub truth: [f64; 2],
    /// Whether the report measured one stop after the warm-up (only these count).
    pub settled: bool,
    /// Algorithm label (`MLE`, `MDS`, `TRLT-3`, `QUAD-4`, `MLE-const`, `MLE-P0only`).
    pub algo: String,
    /// Refinement label (`Ch1`, `Ch12`, `Max`, `Linear avg`, `Ext-MCH`).
    pub refinement: String,
    /// The estimate, m.
    pub pos: [f64; 2],
    /// P0 of the model used, dBm.
    pub p0: f64,
    /// α of the model used.
    pub alpha: f64,
}

impl Est {
    /// Distance to the truth, m.
    pub fn error(&self) -> f64 {
        (self.pos[0] - self.truth[0]).hypot(self.pos[1] - self.truth[1])
    }
}

/// What one report showed over time: the sink's model and the anchor-to-anchor RSSI.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// Simulated time, s.
    pub time_s: f64,
    /// The sink's P0, dBm.
    pub p0: f64,
    /// The sink's α.
    pub alpha: f64,
    /// Per anchor pair ([`Analysis::pairs`]): the mean RSSI over both directions and every
    /// channel heard, dBm (`None`: not heard).
    pub a2a: Vec<Option<f64>>,
}

/// A run's estimates.
#[derive(Clone, Debug)]
pub struct Analysis {
    /// The scenario.
    pub scenario: Scenario,
    /// Refinement labels, in column order.
    pub refinements: Vec<String>,
    /// Algorithm labels, in row order.
    pub algos: Vec<String>,
    /// Anchor pairs `(i, j)`, 1-based ids, of [`Sample::a2a`].
    pub pairs: Vec<(usize, usize)>,
    /// Every estimate.
    pub ests: Vec<Est>,
    /// One sample per located report.
    pub samples: Vec<Sample>,
    /// Reports received without a sink MLE fix (not located here either).
    pub unlocated: usize,
}

/// The refinements of `channels` (testbed channel numbers): one per channel, then Max, Linear
/// avg and Extended with more than one channel.
pub fn refinements(channels: &[u8]) -> Vec<(String, Refinement)> {
    let mut v: Vec<(String, Refinement)> = channels
        .iter()
        .enumerate()
        .map(|(i, c)| (format!("Ch{c}"), Refinement::Single(i)))
        .collect();
    if channels.len() > 1 {
        v.push(("Max".into(), Refinement::Max));
        v.push(("Linear avg".into(), Refinement::LinearAvg));
        v.push((EXT.into(), Refinement::Extended));
    }
    v
}

/// The lateration baseline of `n` anchors and its label.
pub fn lateration(n: usize) -> (Baseline, String) {
    if n >= 4 {
        (Baseline::Quadlateration, "QUAD-4".into())
    } else {
        (Baseline::Trilateration, "TRLT-3".into())
    }
}

/// The estimates of every report in `reports` (as [`crate::testbed::Testbed::take_reports`]
/// gives them) with the sink's lines `obs` of the same run.
pub fn analyze(s: &Scenario, obs: &[Observed], reports: &[(f64, Report)]) -> Analysis {
    let refs = refinements(&s.timing.channels);
    let (lat, lat_label) = lateration(s.anchors.len());
    let mut algos = vec![
        MLE.to_string(),
        MDS.to_string(),
        lat_label.clone(),
        MLE_CONST.to_string(),
    ];
    let has_p0 = obs.iter().any(|o| o.reference == Some(Reference::P0Only));
    if has_p0 {
        algos.push(MLE_P0.to_string());
    }
    // The sink's MLE line (with its truth) and the P0-only reference of each report.
    let mut sink: HashMap<(u8, u16), &Observed> = HashMap::new();
    let mut p0only: HashMap<(u8, u16), [f64; 2]> = HashMap::new();
    for o in obs {
        if let SinkLine::Fix {
            agent, seq, x, y, ..
        } = o.line
        {
            if o.is_sink_mle() {
                sink.insert((agent, seq), o);
            } else if o.reference == Some(Reference::P0Only) {
                p0only.insert((agent, seq), [x as f64 / 100.0, y as f64 / 100.0]);
            }
        }
    }
    let area = Area::new(s.area.width_m, s.area.height_m);
    let constant = PathLoss {
        p0: s.medium.p0_dbm,
        alpha: s.medium.alpha,
    };
    let n = s.anchors.len();
    let pairs: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i + 1, j + 1)))
        .collect();
    let mut a = Analysis {
        scenario: s.clone(),
        refinements: refs.iter().map(|r| r.0.clone()).collect(),
        algos,
        pairs: pairs.clone(),
        ests: Vec::new(),
        samples: Vec::new(),
        unlocated: 0,
    };
    for (t, r) in reports {
        let Some(o) = sink.get(&(r.agent, r.seq)) else {
            a.unlocated += 1;
            continue;
        };
        let SinkLine::Fix {
            alpha_x100,
            p0_x100,
            ..
        } = o.line
        else {
            continue;
        };
        let model = PathLoss {
            p0: p0_x100 as f64 / 100.0,
            alpha: alpha_x100 as f64 / 100.0,
        };
        let m = crate::replay::measurements(r);
        let mut push = |algo: &str, refinement: &str, p: Point, model: PathLoss| {
            a.ests.push(Est {
                time_s: *t,
                seq: r.seq,
                stop: o.stop,
                truth: o.truth,
                settled: o.settled,
                algo: algo.to_string(),
                refinement: refinement.to_string(),
                pos: [p.x, p.y],
                p0: model.p0,
                alpha: model.alpha,
            });
        };
        for (label, refinement) in &refs {
            let ob = observations(&m, *refinement);
            for (algo, model) in [(MLE, model), (MLE_CONST, constant)] {
                if let Ok(e) = grid::mle(&ob, model, area, Search::Thesis) {
                    push(algo, label, e.pos, model);
                }
            }
            if *refinement == Refinement::Extended {
                continue;
            }
            let anchors: Vec<Point> = ob.as_slice().iter().map(|o| o.pos).collect();
            let dists: Vec<f64> = ob.as_slice().iter().map(|o| model.distance(o.z)).collect();
            for (b, algo) in [(Baseline::MdsMap, MDS), (lat, lat_label.as_str())] {
                if let Ok(p) = b.estimate(&anchors, &dists, Some(area)) {
                    push(algo, label, p, model);
                }
            }
        }
        if let Some(p) = p0only.get(&(r.agent, r.seq)) {
            let last = &refs[refs.len() - 1].0;
            push(MLE_P0, last, Point::new(p[0], p[1]), model);
        }
        let a2a = pairs
            .iter()
            .map(|&(i, j)| {
                let (i, j) = (i - 1, j - 1);
                let v: Vec<f64> = (0..m.n_channels)
                    .flat_map(|c| [m.a2a[i][j][c], m.a2a[j][i][c]])
                    .flatten()
                    .collect();
                (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
            })
            .collect();
        a.samples.push(Sample {
            time_s: *t,
            p0: model.p0,
            alpha: model.alpha,
            a2a,
        });
    }
    a
}

/// RMSE, bias and count of some estimates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stat {
    /// How many.
    pub n: usize,
    /// Root mean square distance to the truth, m.
    pub rmse: f64,
    /// Mean error in x and y, m.
    pub bias: [f64; 2],
}

impl Stat {
    /// Of `ests` (none: `None`).
    pub fn of<'a>(ests: impl Iterator<Item = &'a Est>) -> Option<Stat> {
        let (mut n, mut sq, mut bx, mut by) = (0usize, 0.0, 0.0, 0.0);
        for e in ests {
            n += 1;
            sq += e.error().powi(2);
            bx += e.pos[0] - e.truth[0];
            by += e.pos[1] - e.truth[1];
        }
        (n > 0).then(|| {
            let k = n as f64;
            Stat {
                n,
                rmse: (sq / k).sqrt(),
                bias: [bx / k, by / k],
            }
        })
    }

    /// The bias' length, m.
    pub fn bias_len(&self) -> f64 {
        self.bias[0].hypot(self.bias[1])
    }
}

/// One table row: a label pair and a value per position (`None`: no estimate).
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Algorithm.
    pub algo: String,
    /// Refinement.
    pub refinement: String,
    /// Per position, rounded to the printed 3 decimals.
    pub cells: Vec<Option<f64>>,
}

/// A scenario's tables as the pages print them (values rounded to 3 decimals, so what is
/// judged is what is printed).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Tables {
    /// The agent's positions, column order.
    pub positions: Vec<[f64; 2]>,
    /// RMSE (m) per algorithm × refinement.
    pub rmse: Vec<Row>,
    /// The MLE's bias length (m) per refinement (algorithm `MLE`).
    pub bias: Vec<Row>,
    /// Settled estimates per position of the MLE's first refinement.
    pub counts: Vec<usize>,
}

/// `v` rounded to 3 decimals.
fn r3(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

impl Tables {
    /// The tables of `a`'s settled estimates.
    pub fn of(a: &Analysis) -> Tables {
        let positions: Vec<[f64; 2]> = a.scenario.agent.path.iter().map(|p| p.position).collect();
        let cell = |algo: &str, refinement: &str, k: usize| {
            Stat::of(a.ests.iter().filter(|e| {
                e.settled && e.stop == k && e.algo == algo && e.refinement == refinement
            }))
        };
        let mut t = Tables {
            positions: positions.clone(),
            ..Tables::default()
        };
        for algo in &a.algos {
            for refinement in &a.refinements {
                let cells: Vec<Option<Stat>> = (0..positions.len())
                    .map(|k| cell(algo, refinement, k))
                    .collect();
                if cells.iter().all(Option::is_none) {
                    continue;
                }
                t.rmse.push(Row {
                    algo: algo.clone(),
                    refinement: refinement.clone(),
                    cells: cells.iter().map(|c| c.map(|c| r3(c.rmse))).collect(),
                });
                if algo == MLE {
                    t.bias.push(Row {
                        algo: algo.clone(),
                        refinement: refinement.clone(),
                        cells: cells.iter().map(|c| c.map(|c| r3(c.bias_len()))).collect(),
                    });
                }
            }
        }
        t.counts = (0..positions.len())
            .map(|k| cell(MLE, &a.refinements[0], k).map_or(0, |c| c.n))
            .collect();
        t
    }

    /// The RMSE of `algo` with `refinement` at position `k`.
    pub fn rmse_at(&self, algo: &str, refinement: &str, k: usize) -> Option<f64> {
        find(&self.rmse, algo, refinement, k)
    }

    /// The MLE's bias length with `refinement` at position `k`.
    pub fn bias_at(&self, refinement: &str, k: usize) -> Option<f64> {
        find(&self.bias, MLE, refinement, k)
    }

    /// The index of the position `p` (within 1 cm).
    pub fn position(&self, p: [f64; 2]) -> Option<usize> {
        self.positions
            .iter()
            .position(|q| (q[0] - p[0]).abs() < 0.01 && (q[1] - p[1]).abs() < 0.01)
    }

    /// The refinements of `algo`'s rows, in order.
    pub fn refinements_of(&self, algo: &str) -> Vec<String> {
        self.rmse
            .iter()
            .filter(|r| r.algo == algo)
            .map(|r| r.refinement.clone())
            .collect()
    }
}

fn find(rows: &[Row], algo: &str, refinement: &str, k: usize) -> Option<f64> {
    rows.iter()
        .find(|r| r.algo == algo && r.refinement == refinement)
        .and_then(|r| r.cells.get(k).copied().flatten())
}

/// `(x, y)` with two decimals.
pub fn xy(p: [f64; 2]) -> String {
    format!("({:.2}, {:.2})", p[0], p[1])
}

/// A value as the tables print it (`–` for none).
pub fn cell(v: Option<f64>) -> String {
    v.map_or("–".to_string(), |v| format!("{v:.3}"))
}

/// The Markdown of `t`: the RMSE table, then the MLE's bias table; each under a `####` heading
/// that [`parse_tables`] finds again.
pub fn tables_markdown(t: &Tables) -> String {
    let mut s = String::new();
    let head: Vec<String> = t.positions.iter().map(|p| xy(*p)).collect();
    for (title, note, rows) in [
        ("RMSE (m)", "", &t.rmse),
        (
            "MLE bias (m)",
            "The length of the mean error vector of the MLE (sink's P0/α) per refinement.\n\n",
            &t.bias,
        ),
    ] {
        let _ = writeln!(
            s,
            "#### {title}\n\n{note}| algorithm | refinement | {} |\n|---|---|{}",
            head.join(" | "),
            "---:|".repeat(head.len())
        );
        for r in rows {
            let cells: Vec<String> = r.cells.iter().map(|c| cell(*c)).collect();
            let _ = writeln!(
                s,
                "| {} | {} | {} |",
                r.algo,
                r.refinement,
                cells.join(" | ")
            );
        }
        s.push('\n');
    }
    s.pop();
    let counts: Vec<String> = t.counts.iter().map(|c| c.to_string()).collect();
    let _ = writeln!(
        s,
        "\nSettled estimates per position and row: {}.",
        counts.join(", ")
    );
    s
}

/// The tables [`tables_markdown`] printed, read back from `text` (the first of each).
pub fn parse_tables(text: &str) -> Result<Tables, String> {
    let mut t = Tables::default();
    let mut section = 0;
    for line in text.lines() {
        let line = line.trim();
        if line == "#### RMSE (m)" {
            section = 1;
            continue;
        }
        if line == "#### MLE bias (m)" {
            section = 2;
            continue;
        }
        if section == 0 || !line.starts_with('|') {
            if let Some(rest) = line.strip_prefix("Settled estimates per position and row: ") {
                t.counts = rest
                    .trim_end_matches('.')
                    .split(", ")
                    .map(|c| c.parse().map_err(|_| format!("count {c:?}")))
                    .collect::<Result<_, _>>()?;
                break;
            }
            continue;
        }
        let cells: Vec<&str> = line.trim_matches('|').split('|').map(str::trim).collect();
        if cells.len() < 3 || cells[0].starts_with("---") {
            continue;
        }
        if cells[0] == "algorithm" {
            if section == 1 {
                t.positions = cells[2..]
                    .iter()
                    .map(|c| parse_xy(c).ok_or(format!("position {c:?}")))
                    .collect::<Result<_, _>>()?;
            }
            continue;
        }
        let values = cells[2..]
            .iter()
            .map(|c| {
                if *c == "–" {
                    Ok(None)
                } else {
                    c.parse::<f64>()
                        .map(Some)
                        .map_err(|_| format!("value {c:?}"))
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        let row = Row {
            algo: cells[0].to_string(),
            refinement: cells[1].to_string(),
            cells: values,
        };
        if section == 1 {
            t.rmse.push(row);
        } else {
            t.bias.push(row);
        }
    }
    Ok(t)
}

fn parse_xy(s: &str) -> Option<[f64; 2]> {
    let (x, y) = s.strip_prefix('(')?.strip_suffix(')')?.split_once(", ")?;
    Some([x.parse().ok()?, y.parse().ok()?])
}

/// The CSV header of [`csv`].
pub const CSV_HEADER: &str =
    "time_s,seq,stop,truth_x,truth_y,settled,algorithm,refinement,x,y,error_m,p0_dbm,alpha\n";

/// Every estimate as CSV.
pub fn csv(a: &Analysis) -> String {
    let mut s = String::from(CSV_HEADER);
    for e in &a.ests {
        let _ = writeln!(
            s,
            "{:.3},{},{},{},{},{},{},{},{:.2},{:.2},{:.3},{:.2},{:.2}",
            e.time_s,
            e.seq,
            e.stop + 1,
            e.truth[0],
            e.truth[1],
            e.settled,
            e.algo,
            e.refinement,
            e.pos[0],
            e.pos[1],
            e.error(),
            e.p0,
            e.alpha
        );
    }
    s
}

/// Whether a run gets time series: drift, or a stop of at least a minute (experiment 3).
pub fn has_series(s: &Scenario) -> bool {
    s.medium.drift_db_per_min != 0.0 || s.agent.path.iter().any(|p| p.dwell_s >= 60.0)
}

/// The per-scenario page's text (tables, plots, what was computed how).
pub fn scenario_markdown(a: &Analysis, t: &Tables, command: &str) -> String {
    let s = &a.scenario;
    let mut md = String::new();
    let _ = writeln!(md, "# {}: every algorithm × refinement\n", s.name);
    let _ = writeln!(md, "{}\n", s.description);
    let _ = writeln!(md, "Written by `{command}`.\n");
    let _ = writeln!(
        md,
        "Every report the sink received was located on the host by the MLE (the thesis' \
         coarse-to-fine grid, `loc_core::grid::mle`), MDS-MAP and {} on the channel refinements \
         {}; each with the P0/α the sink used for that report (its online fit from the \
         anchor-to-anchor RSSI). `{MLE_CONST}` is the MLE with P0 {} dBm and α {} fixed{}. \
         Only settled reports count (the whole superframe at one stop, after the warm-up); \
         `estimates.csv` has every estimate. {} reports received had no sink fix.\n",
        lateration(s.anchors.len()).1,
        a.refinements.join(", "),
        s.medium.p0_dbm,
        s.medium.alpha,
        if a.algos.iter().any(|x| x == MLE_P0) {
            format!(
                "; `{MLE_P0}` the testbed's reference with P0 fitted online and α fixed \
                 (Extended refinement)"
            )
        } else {
            String::new()
        },
        a.unlocated
    );
    md += &tables_markdown(t);
    let _ = writeln!(
        md,
        "\n[![RMSE per position](rmse.png)](rmse.svg)\n\n[![MLE bias](bias.png)](bias.svg)"
    );
    if has_series(s) {
        let _ = writeln!(md, "\n[![Over time](series.png)](series.svg)");
    }
    md
}

/// Draws `$root => $body` into `$dir/$stem.svg` and `.png`; the paths.
macro_rules! both {
    ($dir:expr, $stem:expr, $size:expr, |$root:ident| $body:expr) => {{
        let size: (u32, u32) = $size;
        let svg = $dir.join(format!("{}.svg", $stem));
        {
            let $root = SVGBackend::new(&svg, size).into_drawing_area();
            $body.map_err(|e: String| format!("{}: {e}", svg.display()))?;
        }
        let png = $dir.join(format!("{}.png", $stem));
        let mut rgb = vec![0u8; 3 * size.0 as usize * size.1 as usize];
        {
            let $root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
            $body.map_err(|e: String| format!("{}: {e}", png.display()))?;
        }
        write_png(&png, size, &rgb).map_err(|e| format!("{}: {e}", png.display()))?;
        [svg, png]
    }};
}

/// Writes `README.md`, `estimates.csv`, `rmse.svg/png`, `bias.svg/png` and, with
/// [`has_series`], `series.svg/png` into `dir` (created if needed); returns the paths.
pub fn write_report(a: &Analysis, dir: &Path, command: &str) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    register_font()?;
    let t = Tables::of(a);
    let mut files = Vec::new();
    let n = t.positions.len().max(1) as u32;
    let bars = (a.refinements.len() as u32).max(1);
    let w = (n * bars * 26 + n * 30 + 120).max(700);
    let panels: Vec<String> = vec![
        MLE.to_string(),
        MDS.to_string(),
        lateration(a.scenario.anchors.len()).1,
    ];
    let title = format!(
        "{}: RMSE per position, algorithm and refinement",
        a.scenario.name
    );
    files.extend(both!(
        dir,
        "rmse",
        (w, 240 * panels.len() as u32 + 60),
        |root| draw_bars(root, &title, &t, &t.rmse, &panels, "RMSE (m)")
    ));
    let title = format!("{}: the MLE's bias per refinement", a.scenario.name);
    let mle = [MLE.to_string()];
    files.extend(both!(dir, "bias", (w, 340), |root| draw_bars(
        root,
        &title,
        &t,
        &t.bias,
        &mle,
        "|bias| (m)"
    )));
    if has_series(&a.scenario) {
        files.extend(both!(dir, "series", (1100, 900), |root| draw_series(
            root, a
        )));
    }
    for (name, body) in [
        ("estimates.csv", csv(a)),
        ("README.md", scenario_markdown(a, &t, command)),
    ] {
        let p = dir.join(name);
        std::fs::write(&p, body).map_err(|e| format!("{}: {e}", p.display()))?;
        files.push(p);
    }
    Ok(files)
}

/// The plots' palette.
const COLORS: [RGBColor; 7] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
    RGBColor(127, 127, 127),
];

/// One panel per algorithm of `panels`: per position a group of bars, one per refinement.
fn draw_bars<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    t: &Tables,
    rows: &[Row],
    panels: &[String],
    ylabel: &str,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 18)).map_err(err)?;
    let refs: Vec<String> = {
        let mut v: Vec<String> = Vec::new();
        for r in rows {
            if !v.contains(&r.refinement) {
                v.push(r.refinement.clone());
            }
        }
        v
    };
    // Headroom above the tallest bar for each group's position label and the legend.
    let top = rows
        .iter()
        .flat_map(|r| r.cells.iter().flatten())
        .fold(0.5f64, |m, v| m.max(*v));
    let ymax = top * 1.8;
    let npos = t.positions.len().max(1);
    let group = refs.len() as f64 + 1.0;
    for (area, algo) in root.split_evenly((panels.len(), 1)).iter().zip(panels) {
        let mut chart = ChartBuilder::on(area)
            .caption(algo, ("sans-serif", 15))
            .margin(8)
            .x_label_area_size(20)
            .y_label_area_size(44)
            .build_cartesian_2d(0.0..npos as f64 * group, 0.0..ymax)
            .map_err(err)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .max_light_lines(1)
            .x_label_formatter(&|_| String::new())
            .x_desc("agent position (above each group of bars)")
            .y_desc(ylabel)
            .label_style(("sans-serif", 12))
            .axis_desc_style(("sans-serif", 12))
            .draw()
            .map_err(err)?;
        // Each group's position, above its tallest bar.
        let tallest = |k: usize| {
            rows.iter()
                .filter(|r| &r.algo == algo)
                .filter_map(|r| r.cells.get(k).copied().flatten())
                .fold(0.0f64, f64::max)
        };
        chart
            .draw_series((0..t.positions.len()).map(|k| {
                Text::new(
                    xy(t.positions[k]),
                    (
                        k as f64 * group + 0.1,
                        tallest(k) + 0.04 * ymax + 0.06 * ymax,
                    ),
                    ("sans-serif", 12).into_font(),
                )
            }))
            .map_err(err)?;
        for (ri, refinement) in refs.iter().enumerate() {
            let Some(row) = rows
                .iter()
                .find(|r| &r.algo == algo && &r.refinement == refinement)
            else {
                continue;
            };
            let c = COLORS[ri % COLORS.len()];
            chart
                .draw_series(row.cells.iter().enumerate().filter_map(|(k, v)| {
                    let x0 = k as f64 * group + ri as f64;
                    v.map(|v| Rectangle::new([(x0 + 0.1, 0.0), (x0 + 0.9, v)], c.filled()))
                }))
                .map_err(err)?
                .label(refinement.as_str())
                .legend(move |(x, y)| Rectangle::new([(x, y - 4), (x + 8, y + 4)], c.filled()));
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 12).map_err(err)?;
    }
    root.present().map_err(err)
}

/// One panel of [`draw_series`]: each series' points as small dots in its colour, over `x`
/// and `y`, with a legend.
fn scatter_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    caption: &str,
    y_desc: &str,
    (x, y): (std::ops::Range<f64>, std::ops::Range<f64>),
    series: &[(String, Vec<(f64, f64)>)],
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 14))
        .margin(8)
        .x_label_area_size(24)
        .y_label_area_size(44)
        .build_cartesian_2d(x, y)
        .map_err(err)?;
    chart
        .configure_mesh()
        .max_light_lines(1)
        .y_desc(y_desc)
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 12))
        .draw()
        .map_err(err)?;
    for (k, (label, points)) in series.iter().enumerate() {
        let c = COLORS[k % COLORS.len()];
        chart
            .draw_series(points.iter().map(|&p| Circle::new(p, 1, c.filled())))
            .map_err(err)?
            .label(label.as_str())
            .legend(move |(x, y)| Circle::new((x, y), 3, c.filled()));
    }
    draw_legend(&mut chart, SeriesLabelPosition::MiddleRight, 11).map_err(err)?;
    Ok(())
}

/// Three panels over time: the anchor-to-anchor RSSI, each algorithm's error (the last
/// refinement; the baselines the last they have), the sink's P0 and α.
fn draw_series<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, a: &Analysis) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(err)?;
    let root = root
        .titled(
            &format!("{}: over time (after the warm-up)", a.scenario.name),
            ("sans-serif", 18),
        )
        .map_err(err)?;
    let panels = root.split_evenly((3, 1));
    let t0 = a.scenario.timing.warmup_s;
    let t1 = a.scenario.duration_s();
    let samples: Vec<&Sample> = a.samples.iter().filter(|s| s.time_s >= t0).collect();
    // Anchor-to-anchor RSSI.
    let vals = samples.iter().flat_map(|s| s.a2a.iter().flatten());
    let (lo, hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
        (l.min(*v), h.max(*v))
    });
    let (lo, hi) = if lo.is_finite() {
        (lo - 1.0, hi + 1.0)
    } else {
        (-100.0, 0.0)
    };
    let series: Vec<(String, Vec<(f64, f64)>)> = a
        .pairs
        .iter()
        .enumerate()
        .map(|(k, (i, j))| {
            let points = samples
                .iter()
                .filter_map(|s| s.a2a[k].map(|v| (s.time_s, v)))
                .collect();
            (format!("anchors {i}–{j}"), points)
        })
        .collect();
    scatter_panel(
        &panels[0],
        "anchor-to-anchor RSSI (mean over both directions and channels)",
        "RSSI (dBm)",
        (t0..t1, lo..hi),
        &series,
    )?;
    // Error per algorithm.
    let last = a.refinements.last().cloned().unwrap_or_default();
    let base_last = a
        .refinements
        .iter()
        .rfind(|r| r.as_str() != EXT)
        .cloned()
        .unwrap_or_default();
    let series: Vec<(String, &str)> = a
        .algos
        .iter()
        .map(|al| {
            let r = if al == MDS || al.starts_with("TRLT") || al.starts_with("QUAD") {
                base_last.as_str()
            } else {
                last.as_str()
            };
            (al.clone(), r)
        })
        .collect();
    let emax = a
        .ests
        .iter()
        .filter(|e| e.time_s >= t0)
        .map(Est::error)
        .fold(1.0, f64::max)
        * 1.05;
    let points: Vec<(String, Vec<(f64, f64)>)> = series
        .iter()
        .map(|(algo, refinement)| {
            let points = a
                .ests
                .iter()
                .filter(|e| e.time_s >= t0 && &e.algo == algo && e.refinement == *refinement)
                .map(|e| (e.time_s, e.error()))
                .collect();
            (format!("{algo} ({refinement})"), points)
        })
        .collect();
    scatter_panel(
        &panels[1],
        "error of each algorithm (sink's P0/α unless named)",
        "error (m)",
        (t0..t1, 0.0..emax),
        &points,
    )?;
    // P0 and α.
    let (plo, phi) = samples
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), s| {
            (l.min(s.p0), h.max(s.p0))
        });
    let (plo, phi) = if plo.is_finite() {
        (plo - 1.0, phi + 1.0)
    } else {
        (-60.0, -20.0)
    };
    let amax = samples.iter().map(|s| s.alpha).fold(1.0, f64::max) + 0.5;
    let mut chart = ChartBuilder::on(&panels[2])
        .caption(
            "the sink's fitted P0 (left) and α (right)",
            ("sans-serif", 14),
        )
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(44)
        .right_y_label_area_size(44)
        .build_cartesian_2d(t0..t1, plo..phi)
        .map_err(err)?
        .set_secondary_coord(t0..t1, 0.0..amax);
    chart
        .configure_mesh()
        .max_light_lines(1)
        .x_desc("simulated time (s)")
        .y_desc("P0 (dBm)")
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 12))
        .draw()
        .map_err(err)?;
    chart
        .configure_secondary_axes()
        .y_desc("α")
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 12))
        .draw()
        .map_err(err)?;
    let (cp, ca) = (COLORS[0], COLORS[1]);
    chart
        .draw_series(LineSeries::new(
            samples.iter().map(|s| (s.time_s, s.p0)),
            cp.stroke_width(2),
        ))
        .map_err(err)?
        .label("P0")
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 12, y)], cp.stroke_width(2)));
    chart
        .draw_secondary_series(LineSeries::new(
            samples.iter().map(|s| (s.time_s, s.alpha)),
            ca.stroke_width(2),
        ))
        .map_err(err)?
        .label("α")
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 12, y)], ca.stroke_width(2)));
    draw_legend(&mut chart, SeriesLabelPosition::MiddleRight, 11).map_err(err)?;
    root.present().map_err(err)
}

/// The legend of `chart`'s labelled series at `position`: black border, white background, a
/// `font_px` sans-serif font (one look for every chart of the report).
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
    font_px: u32,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    chart
        .configure_series_labels()
        .position(position)
        .border_style(BLACK)
        .background_style(WHITE)
        .label_font(("sans-serif", font_px))
        .draw()
}
