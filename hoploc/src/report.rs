//! `hoploc simulate --report DIR`: the study as a Markdown page, `DIR/README.md`, next to its CDF
//! plots (PNG, linked to the SVG) and `study.csv`.
//!
//! The page records the command line and the configuration, shows the RMSE and bias tables and
//! the plots, and says what they show. Every number in that prose is computed here from the
//! results (the winner per σ and anchor count and its margin over the thesis' MLE, MMSE against
//! MLE, the distance to the CRLB and the MMSE floor, the multichannel refinements against single
//! channels, the baselines against MLE), so a rerun with other flags or another seed rewrites the
//! conclusions along with the tables. `hoploc/tests/report.rs` parses the page back and checks
//! each sentence against the page's own tables. Nothing in the page depends on the clock or the
//! machine: the same command gives the same bytes.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::simulate::{self, num, plot_stem};
use crate::study::{Algo, Row, RowKind, StudyResult, Table};

/// The page's file name inside the report directory.
pub const PAGE: &str = "README.md";

/// Writes the page, the plots and `study.csv` into `dir` (created if needed); returns the paths.
/// `command` is the command line to record (see [`command_line`]).
pub fn write(result: &StudyResult, dir: &Path, command: &str) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut files = simulate::write_plots(result, dir)?;
    for (name, body) in [
        ("study.csv", simulate::csv(result)),
        (PAGE, markdown(result, command)),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, body).map_err(|e| format!("{}: {e}", path.display()))?;
        files.push(path);
    }
    Ok(files)
}

/// `hoploc` and `args`, quoted for a POSIX shell where needed (the page shows it verbatim).
pub fn command_line<I: IntoIterator<Item = String>>(args: I) -> String {
    let mut s = String::from("hoploc");
    for a in args {
        let plain = !a.is_empty()
            && a.chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_./=,:+@%".contains(c));
        s.push(' ');
        if plain {
            s.push_str(&a);
        } else {
            let _ = write!(s, "'{}'", a.replace('\'', r"'\''"));
        }
    }
    s
}

/// A length in metres as the tables print it.
fn m(v: f64) -> String {
    format!("{v:.3} m")
}

/// `100·(a − b)/a`: how far `b` is below `a`, in % of `a`.
fn pct_below(a: f64, b: f64) -> f64 {
    100.0 * (a - b) / a
}

/// `b` against a reference `a`: `12.3 % above`, `4.0 % below` or `equal to`.
fn versus(a: f64, b: f64) -> String {
    let p = 100.0 * (b - a) / a;
    if format!("{:.1}", p.abs()) == "0.0" {
        "equal to".into()
    } else if p > 0.0 {
        format!("{p:.1} % above")
    } else {
        format!("{:.1} % below", -p)
    }
}

/// English list: `a`, `a and b`, `a, b and c`.
fn and_list(items: &[String]) -> String {
    match items {
        [] => String::new(),
        [one] => one.clone(),
        [init @ .., last] => format!("{} and {last}", init.join(", ")),
    }
}

/// The thesis' Table 3.1: trilateration with 3 anchors at σ = 4 dB on channel 1, metres. The
/// cell that tells clipped baselines from unclipped ones (unclipped it comes out near 6 m).
pub const THESIS_TRLT3_SIGMA4_CH1_M: f64 = 3.36;

/// The page's section on the thesis' settings: which ones reproduce its tables and why, and
/// how this page's configuration differs from them.
fn thesis_settings(result: &StudyResult) -> Vec<String> {
    let c = &result.config;
    let thesis = crate::study::Config::default();
    let t = thesis.summary(c.points);
    let sigmas: Vec<f64> = result.tables.iter().map(|t| t.sigma).collect();
    let list = |v: &[f64]| {
        let v: Vec<String> = v.iter().map(|x| format!("{} dB", num(*x))).collect();
        v.join(", ")
    };
    let mut differs = Vec::new();
    if (c.width, c.height) != (t.width, t.height) {
        differs.push(format!(
            "the area is {} m × {} m (thesis: {} m × {} m)",
            num(c.width),
            num(c.height),
            num(t.width),
            num(t.height)
        ));
    }
    if c.anchor_counts != t.anchor_counts {
        differs.push(format!(
            "the anchor layouts are {:?} (thesis: {:?})",
            c.anchor_counts, t.anchor_counts
        ));
    }
    if c.runs != t.runs {
        differs.push(format!("{} runs per point (thesis: {})", c.runs, t.runs));
    }
    if sigmas != thesis.sigmas {
        differs.push(format!(
            "σ is {} (thesis: {})",
            list(&sigmas),
            list(&thesis.sigmas)
        ));
    }
    if c.channels != t.channels {
        differs.push(format!("{} channels (thesis: {})", c.channels, t.channels));
    }
    if (c.p0, c.alpha) != (t.p0, t.alpha) {
        differs.push(format!(
            "the truth is P0 = {} dBm, α = {} (thesis: {} dBm, {})",
            num(c.p0),
            num(c.alpha),
            num(t.p0),
            num(t.alpha)
        ));
    }
    if c.params != t.params {
        differs.push(format!(
            "P0, α and σ are not known to the estimators ({}; thesis: known)",
            params_row(result)
        ));
    }
    if c.search != t.search {
        differs.push(format!(
            "the MLE searches with `{}` (thesis: `{}`)",
            c.search, t.search
        ));
    }
    if c.clip != t.clip {
        differs.push("the baselines are not clipped to the area (thesis: clipped)".into());
    }
    let mut out = vec![
        "`hoploc simulate` without flags runs the thesis' study: a 10 m × 10 m area, 3 and 4 \
         corner anchors, 361 agent positions × 100 runs, σ = 2 and 4 dB, two channels with \
         independent noise, P0 = −40 dBm and α = 3 known to the estimators, the thesis' \
         coarse-to-fine MLE search, and the baselines' (trilateration, quadlateration, MDS) \
         estimates clipped to the area. The clipping matters: the thesis' Tables 3.1 and 3.3 \
         are reproduced only with it, because at σ = 4 dB a trilateration often lands metres \
         outside the room and, unclipped (`--no-clip`), counts with its whole error."
            .to_string(),
    ];
    let trlt = result
        .tables
        .iter()
        .find(|t| t.sigma == 4.0)
        .and_then(|t| {
            t.rows
                .iter()
                .find(|r| r.anchors == 3 && r.kind == RowKind::Estimator(Algo::Trlt))
        })
        .and_then(|r| {
            let ci = result.columns.iter().position(|l| l == "Ch1")?;
            View::rmse(r, ci)
        });
    if let Some(v) = trlt {
        out.push(format!(
            "TRLT-3 at σ = 4 dB on channel 1, the cell that tells the two apart: {} here, {} in \
             the thesis' Table 3.1.",
            m(v),
            m(THESIS_TRLT3_SIGMA4_CH1_M)
        ));
    }
    out.push(if differs.is_empty() {
        "This page uses the thesis' settings.".to_string()
    } else {
        format!("This page differs from them: {}.", and_list(&differs))
    });
    out
}

/// The rows of one σ table with `n` anchors, and the column labels.
struct View<'a> {
    table: &'a Table,
    n: usize,
    columns: &'a [String],
}

impl<'a> View<'a> {
    fn row(&self, kind: RowKind) -> Option<&'a Row> {
        self.table
            .rows
            .iter()
            .find(|r| r.anchors == self.n && r.kind == kind)
    }

    fn est(&self, algo: Algo) -> Option<&'a Row> {
        self.row(RowKind::Estimator(algo))
    }

    fn estimators(&self) -> impl Iterator<Item = &'a Row> + '_ {
        self.table
            .rows
            .iter()
            .filter(|r| r.anchors == self.n && matches!(r.kind, RowKind::Estimator(_)))
    }

    fn col(&self, label: &str) -> Option<usize> {
        self.columns.iter().position(|c| c == label)
    }

    /// `(column index, RMSE)` of the row's cells.
    fn cells(row: &Row) -> impl Iterator<Item = (usize, f64)> + '_ {
        row.cells
            .iter()
            .enumerate()
            .filter_map(|(i, c)| c.as_ref().map(|c| (i, c.rmse)))
    }

    fn rmse(row: &Row, ci: usize) -> Option<f64> {
        row.cells.get(ci)?.as_ref().map(|c| c.rmse)
    }

    /// The row's smallest RMSE (first column on ties).
    fn best(row: &Row) -> Option<(usize, f64)> {
        Self::cells(row).fold(None, |b, (i, v)| match b {
            Some((_, bv)) if bv <= v => b,
            _ => Some((i, v)),
        })
    }

    /// Single-channel columns (`Ch1`, `Ch2`, …).
    fn single(&self) -> Vec<usize> {
        (0..self.columns.len())
            .filter(|&i| is_single(&self.columns[i]))
            .collect()
    }
}

fn is_single(label: &str) -> bool {
    label
        .strip_prefix("Ch")
        .is_some_and(|d| !d.is_empty() && d.chars().all(|c| c.is_ascii_digit()))
}

/// The lowest estimator RMSE with `n` anchors: `(row, column, value)`.
fn winner<'a>(v: &View<'a>) -> Option<(&'a Row, usize, f64)> {
    let mut best: Option<(&Row, usize, f64)> = None;
    for r in v.estimators() {
        if let Some((ci, x)) = View::best(r) {
            if best.is_none_or(|(_, _, b)| x < b) {
                best = Some((r, ci, x));
            }
        }
    }
    best
}

/// The "What the study shows" bullets for one σ and anchor count.
fn findings(v: &View) -> Vec<String> {
    let cols = v.columns;
    let mut out = Vec::new();
    let mle = v.est(Algo::Mle);
    let mmse = v.est(Algo::Mmse);

    // Winner and its margin over the thesis' MLE.
    if let Some((row, ci, x)) = winner(v) {
        let mut s = format!("**Lowest RMSE:** {} with {}, {}", row.label, cols[ci], m(x));
        match mle {
            Some(mr) if mr.label == row.label => {
                s.push_str(": the thesis' estimator wins here.");
            }
            Some(mr) => {
                let same = View::rmse(mr, ci);
                let best = View::best(mr);
                let mut parts = Vec::new();
                if let Some(y) = same {
                    parts.push(format!(
                        "{} ({:.1} %) below {} in the same column ({})",
                        m(y - x),
                        pct_below(y, x),
                        mr.label,
                        m(y)
                    ));
                }
                if let Some((bi, y)) = best.filter(|(bi, _)| *bi != ci) {
                    parts.push(format!(
                        "{} ({:.1} %) below {} at its best ({}, {})",
                        m(y - x),
                        pct_below(y, x),
                        mr.label,
                        cols[bi],
                        m(y)
                    ));
                }
                if parts.is_empty() {
                    s.push('.');
                } else {
                    let _ = write!(s, ": {}.", parts.join(", and "));
                }
                if best.is_some_and(|(bi, _)| bi == ci) {
                    let _ = write!(s, " That column is also {}'s best.", mr.label);
                }
            }
            None => s.push('.'),
        }
        out.push(s);
    }

    // MMSE against MLE, column by column.
    if let (Some(a), Some(b)) = (mle, mmse) {
        let diffs: Vec<(usize, f64, f64)> = View::cells(a)
            .filter_map(|(ci, y)| View::rmse(b, ci).map(|x| (ci, y, x)))
            .collect();
        if !diffs.is_empty() {
            let below = diffs.iter().filter(|(_, y, x)| x < y).count();
            let by = |(ci, y, x): (usize, f64, f64)| {
                format!("{} ({:.1} %, {})", m(y - x), pct_below(y, x), cols[ci])
            };
            let lo = diffs
                .iter()
                .copied()
                .min_by(|p, q| (p.1 - p.2).total_cmp(&(q.1 - q.2)));
            let hi = diffs
                .iter()
                .copied()
                .max_by(|p, q| (p.1 - p.2).total_cmp(&(q.1 - q.2)));
            let mut s = format!(
                "**MMSE vs MLE:** {} is below {} in {below} of {} columns",
                b.label,
                a.label,
                diffs.len()
            );
            if let (Some(lo), Some(hi)) = (lo, hi) {
                let _ = write!(s, "; MLE − MMSE ranges from {} to {}", by(lo), by(hi));
            }
            s.push('.');
            out.push(s);
        }
    }

    // MLE and MMSE against the bounds, with every channel (Ext-MCH).
    let crlb = v.row(RowKind::Crlb);
    let floor = v.row(RowKind::MmseFloor);
    if let Some(ci) = v.col("Ext-MCH") {
        let mut parts = Vec::new();
        for r in [mle, mmse].into_iter().flatten() {
            let Some(x) = View::rmse(r, ci) else { continue };
            let mut against = Vec::new();
            if let Some(c) = crlb.and_then(|b| View::rmse(b, ci)) {
                against.push(format!("{} the CRLB ({})", versus(c, x), m(c)));
            }
            if let Some(f) = floor.and_then(|b| View::rmse(b, ci)) {
                against.push(format!("{} the MMSE floor ({})", versus(f, x), m(f)));
            }
            if !against.is_empty() {
                parts.push(format!("{} {} is {}", r.label, m(x), against.join(" and ")));
            }
        }
        if !parts.is_empty() {
            out.push(format!("**Bounds ({}):** {}.", cols[ci], parts.join("; ")));
        }
    }

    // Estimators under the CRLB.
    if let Some(c) = crlb {
        let mut items = Vec::new();
        let mut bias = 0.0f64;
        for r in v.estimators() {
            let both: Vec<(usize, f64, f64)> = View::cells(r)
                .filter_map(|(ci, x)| View::rmse(c, ci).map(|b| (ci, x, b)))
                .collect();
            let under: Vec<usize> = both.iter().filter(|(_, x, b)| x < b).map(|t| t.0).collect();
            if under.is_empty() {
                continue;
            }
            for &ci in &under {
                if let Some(cell) = &r.cells[ci] {
                    bias = bias.max(cell.bias_x.unwrap_or(0.0).max(cell.bias_y.unwrap_or(0.0)));
                }
            }
            let mut item = format!("{} in {} of {} columns", r.label, under.len(), both.len());
            if under.len() < both.len() {
                let name = |v: Vec<usize>| {
                    and_list(&v.into_iter().map(|ci| cols[ci].clone()).collect::<Vec<_>>())
                };
                let over: Vec<usize> = both
                    .iter()
                    .map(|t| t.0)
                    .filter(|ci| !under.contains(ci))
                    .collect();
                if 2 * under.len() <= both.len() {
                    let _ = write!(item, " ({})", name(under));
                } else {
                    let _ = write!(item, " (all but {})", name(over));
                }
            }
            items.push(item);
        }
        out.push(if items.is_empty() {
            "**Below the CRLB:** none of the estimators.".into()
        } else {
            format!(
                "**Below the CRLB:** {}. The CRLB holds only for unbiased estimators, and the \
                 estimators here are biased (their bias, the std over the points of the mean \
                 error, reaches {} in those cells): confined to the area, their estimates near \
                 the walls are pulled inwards.",
                and_list(&items),
                m(bias)
            )
        });
    }

    // Multichannel refinements against the best single channel.
    let single = v.single();
    if single.len() >= 2 {
        let mut parts = Vec::new();
        for r in [mle, mmse].into_iter().flatten() {
            let best = single
                .iter()
                .filter_map(|&ci| View::rmse(r, ci).map(|x| (ci, x)))
                .fold(None, |b: Option<(usize, f64)>, (ci, x)| match b {
                    Some((_, bx)) if bx <= x => b,
                    _ => Some((ci, x)),
                });
            let Some((bi, bx)) = best else { continue };
            let multi: Vec<String> = View::cells(r)
                .filter(|(ci, _)| !single.contains(ci))
                .map(|(ci, x)| format!("{} {} ({:.1} % below)", cols[ci], m(x), pct_below(bx, x)))
                .collect();
            if !multi.is_empty() {
                parts.push(format!(
                    "{} against its best single channel ({} {}): {}",
                    r.label,
                    cols[bi],
                    m(bx),
                    multi.join(", ")
                ));
            }
        }
        if !parts.is_empty() {
            let mut s = format!("**Channels:** {}.", parts.join("; "));
            if let (Some(c), Some(ci)) = (crlb, v.col("Ext-MCH")) {
                if let (Some(one), Some(all)) = (View::rmse(c, single[0]), View::rmse(c, ci)) {
                    let _ = write!(
                        s,
                        " The CRLB itself falls {:.1} % from 1 channel to {}.",
                        pct_below(one, all),
                        single.len()
                    );
                }
            }
            out.push(s);
        }
    }

    // Baselines against MLE.
    if let Some(a) = mle {
        let mut parts = Vec::new();
        for algo in [Algo::Mds, Algo::Trlt, Algo::Quad] {
            let Some(r) = v.est(algo) else { continue };
            let ratios: Vec<(usize, f64)> = View::cells(r)
                .filter_map(|(ci, x)| View::rmse(a, ci).map(|y| (ci, x / y)))
                .collect();
            let (Some(lo), Some(hi)) = (
                ratios.iter().map(|t| t.1).min_by(f64::total_cmp),
                ratios.iter().map(|t| t.1).max_by(f64::total_cmp),
            ) else {
                continue;
            };
            let Some((bi, bx)) = View::best(r) else {
                continue;
            };
            let mut s = format!(
                "{} is {lo:.2}× to {hi:.2}× {}'s RMSE in its {} columns (its best: {}, {})",
                r.label,
                a.label,
                ratios.len(),
                m(bx),
                cols[bi]
            );
            let under: Vec<String> = ratios
                .iter()
                .filter(|t| t.1 < 1.0)
                .map(|t| cols[t.0].clone())
                .collect();
            if !under.is_empty() {
                let _ = write!(s, ", below it with {}", and_list(&under));
            }
            parts.push(s);
        }
        if !parts.is_empty() {
            out.push(format!("**Baselines vs MLE:** {}.", parts.join("; ")));
        }
    }
    out
}

/// Sentences over every σ and anchor count: whether one estimator and column win throughout, and
/// what a fourth anchor buys the MLE.
fn overview(result: &StudyResult) -> Vec<String> {
    let mut out = Vec::new();
    let counts = &result.config.anchor_counts;
    let mut wins = Vec::new();
    let mut margins = Vec::new();
    for t in &result.tables {
        for &n in counts {
            let v = View {
                table: t,
                n,
                columns: &result.columns,
            };
            if let Some((row, ci, x)) = winner(&v) {
                let RowKind::Estimator(algo) = row.kind else {
                    continue;
                };
                wins.push((algo, ci));
                if let Some((_, y)) = v.est(Algo::Mle).and_then(View::best) {
                    margins.push(pct_below(y, x));
                }
            }
        }
    }
    // The most frequent winner (first seen on ties).
    let top = wins
        .iter()
        .map(|w| (w, wins.iter().filter(|x| *x == w).count()))
        .fold(None, |b: Option<(&(Algo, usize), usize)>, (w, k)| match b {
            Some((_, bk)) if bk >= k => b,
            _ => Some((w, k)),
        });
    if let Some((&(algo, ci), k)) = top.filter(|_| wins.len() > 1) {
        let mut s = if k == wins.len() {
            format!("In all {k} cases (σ × anchor layout)")
        } else {
            format!("In {k} of {} cases (σ × anchor layout)", wins.len())
        };
        let _ = write!(
            s,
            " the lowest RMSE is {} with {}",
            algo.label(),
            result.columns[ci]
        );
        let lo = margins.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = margins.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if k == wins.len() && algo != Algo::Mle && margins.len() == wins.len() {
            let _ = write!(
                s,
                ", {lo:.1} % to {hi:.1} % below the thesis' MLE at its best"
            );
        }
        s.push('.');
        out.push(s);
    }
    if counts.contains(&3) && counts.contains(&4) {
        let mut parts = Vec::new();
        for t in &result.tables {
            let rmse = |n: usize| {
                let v = View {
                    table: t,
                    n,
                    columns: &result.columns,
                };
                let ci = v.col("Ext-MCH")?;
                View::rmse(v.est(Algo::Mle)?, ci)
            };
            if let (Some(a), Some(b)) = (rmse(3), rmse(4)) {
                parts.push(format!(
                    "{:.1} % at σ = {} dB ({} → {})",
                    pct_below(a, b),
                    num(t.sigma),
                    m(a),
                    m(b)
                ));
            }
        }
        if !parts.is_empty() {
            out.push(format!(
                "A fourth anchor lowers the MLE's RMSE (Ext-MCH) by {}.",
                and_list(&parts)
            ));
        }
    }
    out
}

fn params_row(result: &StudyResult) -> String {
    use crate::study::ParamSource;
    let c = &result.config;
    match c.params {
        ParamSource::Known => "known to the estimators (true P0, α and σ)".into(),
        ParamSource::Estimated => format!(
            "estimated: P0, α and σ fitted per trial from simulated anchor-to-anchor RSSI ({} fit)",
            c.fit
        ),
        ParamSource::Ar1 => format!(
            "estimated: fitted per trial ({} fit) and AR(1)-smoothed over the runs at a point",
            c.fit
        ),
    }
}

fn search_row(search: &str) -> String {
    match search {
        "thesis" => "thesis: coarse 10 % grid, then 2 % steps within ± one coarse step of the coarse winner".into(),
        "multistart" => "multistart: coarse 10 % grid, then descent on the 2 % lattice from the four best coarse points".into(),
        "exhaustive" => "exhaustive: every point of the 2 % lattice".into(),
        other => other.into(),
    }
}

/// The page.
pub fn markdown(result: &StudyResult, command: &str) -> String {
    let c = &result.config;
    let mut s = String::new();
    let _ = writeln!(s, "# The localization study (`hoploc simulate`)\n");
    let _ = writeln!(
        s,
        "Written by this command (do not edit by hand; from the repository root, \
         `scripts/gen-docs.sh` regenerates every study page):\n"
    );
    let _ = writeln!(s, "```sh\n{command}\n```\n");
    let _ = writeln!(
        s,
        "The tables are also in [study.csv](study.csv) (full precision, with the Monte Carlo \
         standard errors).\n"
    );

    // Configuration.
    let (w, h) = (num(c.width), num(c.height));
    let layouts: Vec<String> = c
        .anchor_counts
        .iter()
        .map(|&n| {
            let pts: Vec<String> = crate::study::anchors(loc_core::Area::new(c.width, c.height), n)
                .iter()
                .map(|p| format!("({}, {})", num(p.x), num(p.y)))
                .collect();
            format!("{n}: {}", pts.join(", "))
        })
        .collect();
    let sigmas: Vec<String> = result
        .tables
        .iter()
        .map(|t| format!("{} dB", num(t.sigma)))
        .collect();
    let _ = writeln!(s, "## Configuration\n");
    let _ = writeln!(s, "| | |\n|---|---|");
    for (k, v) in [
        ("Area", format!("{w} m × {h} m")),
        ("Anchors", layouts.join("; ")),
        (
            "Agent positions × runs",
            format!(
                "{} points (a 19 × 19 grid at {} m × {} m spacing) × {} runs each",
                c.points,
                num(c.width / 20.0),
                num(c.height / 20.0),
                c.runs
            ),
        ),
        ("Shadowing σ", sigmas.join(", ")),
        (
            "Channels",
            format!("{}, with independent noise", c.channels),
        ),
        (
            "Path loss (truth)",
            format!("P0 = {} dBm at 1 m, α = {}", num(c.p0), num(c.alpha)),
        ),
        ("Parameters", params_row(result)),
        ("MLE search", search_row(&c.search)),
        (
            "Baselines clipped to the area",
            if c.clip { "yes" } else { "no" }.into(),
        ),
        ("Seed", c.seed.to_string()),
    ] {
        let _ = writeln!(s, "| {k} | {v} |");
    }
    s.push('\n');

    let _ = writeln!(s, "## The thesis' settings\n");
    for line in thesis_settings(result) {
        let _ = writeln!(s, "{line}\n");
    }

    // What it shows.
    let _ = writeln!(s, "## What the study shows\n");
    let _ = writeln!(
        s,
        "Computed from the tables below (RMSE in metres, lower is better; \"MLE\" is the \
         thesis' estimator).\n"
    );
    for line in overview(result) {
        let _ = writeln!(s, "{line}\n");
    }
    for t in &result.tables {
        for &n in &c.anchor_counts {
            let v = View {
                table: t,
                n,
                columns: &result.columns,
            };
            let _ = writeln!(s, "### σ = {} dB, {n} anchors\n", num(t.sigma));
            for f in findings(&v) {
                let _ = writeln!(s, "- {f}");
            }
            s.push('\n');
        }
    }

    // Tables.
    let _ = writeln!(s, "## RMSE\n");
    let _ = writeln!(
        s,
        "Mean over the {} points of the per-point RMSE over the {} runs, metres. CRLB: C = 1 \
         channel for a single-channel column, C = {} for Max, Linear avg and Ext-MCH.{}\n",
        c.points,
        c.runs,
        c.channels,
        if c.floor {
            " MMSE floor: the posterior mean that knows the true model and σ, on the study's \
             own draws."
        } else {
            ""
        }
    );
    for t in &result.tables {
        let _ = writeln!(s, "### σ = {} dB: mean per-point RMSE (m)\n", num(t.sigma));
        s.push_str(&table(result, t, false));
        let se = t
            .rows
            .iter()
            .flat_map(|r| r.cells.iter().flatten())
            .filter_map(|c| c.rmse_se)
            .fold(0.0f64, f64::max);
        let _ = writeln!(
            s,
            "\nLargest Monte Carlo standard error of a cell: {}.\n",
            m(se)
        );
    }
    let _ = writeln!(s, "## Bias\n");
    let _ = writeln!(
        s,
        "Standard deviation over the points of the per-point mean error, x / y, metres \
         (estimators only).\n"
    );
    for t in &result.tables {
        let _ = writeln!(
            s,
            "### σ = {} dB: bias, std over points of the mean error x / y (m)\n",
            num(t.sigma)
        );
        s.push_str(&table(result, t, true));
        s.push('\n');
    }

    // Plots.
    let _ = writeln!(s, "## Empirical CDFs over the points\n");
    let _ = writeln!(
        s,
        "Per σ and anchor layout: top, the per-point RMSE of each estimator with the bounds \
         (dashed); bottom, the per-point bias magnitude |mean error|; one panel per column. \
         Click a figure for the SVG.\n"
    );
    for t in &result.tables {
        for &n in &c.anchor_counts {
            let stem = plot_stem(t.sigma, n);
            let _ = writeln!(s, "### σ = {} dB, {n} anchors\n", num(t.sigma));
            let _ = writeln!(
                s,
                "[![CDFs at σ = {} dB with {n} anchors]({stem}.png)]({stem}.svg)\n",
                num(t.sigma)
            );
        }
    }

    // How to read it.
    let _ = writeln!(s, "## Reading the tables\n");
    let _ = writeln!(
        s,
        "- Rows: MLE (the thesis' grid maximum likelihood), MMSE (posterior mean over the same \
         lattice, uniform prior over the area), MDS (MDS-MAP), TRLT (trilateration, 3 anchors), \
         QUAD (quadlateration, 4 anchors); the suffix is the anchor count. Columns: one channel \
         (ChN), the per-anchor maximum (Max), the mW average (Linear avg), every channel as its \
         own observation (Ext-MCH; grid estimators only)."
    );
    let _ = writeln!(
        s,
        "- The CRLB bounds the error covariance of unbiased estimators. Every estimator here is \
         confined to the area (or clipped, or pulled by its geometry), hence biased near the \
         walls, so it can be below the CRLB; the MMSE floor is the smallest RMSE any estimator \
         can reach on average over the area under the model."
    );
    if c.params == crate::study::ParamSource::Known && c.floor {
        let _ = writeln!(
            s,
            "- With known parameters the MMSE estimator is the floor's estimator on the same \
             draws: its row equals the MMSE floor (with Ext-MCH; in the Max and Linear avg \
             columns the floor uses the unreduced channels)."
        );
    }
    s
}

/// One Markdown table: RMSE (or bias `x / y` for the estimator rows).
fn table(result: &StudyResult, t: &Table, bias: bool) -> String {
    let mut s = String::from("| |");
    for c in &result.columns {
        let _ = write!(s, " {c} |");
    }
    s.push_str("\n|---|");
    for _ in &result.columns {
        s.push_str("---:|");
    }
    s.push('\n');
    for row in &t.rows {
        if bias && !matches!(row.kind, RowKind::Estimator(_)) {
            continue;
        }
        let _ = write!(s, "| {} |", row.label);
        for cell in &row.cells {
            let v = match (cell, bias) {
                (None, _) => "–".to_string(),
                (Some(c), false) => format!("{:.3}", c.rmse),
                (Some(c), true) => match (c.bias_x, c.bias_y) {
                    (Some(x), Some(y)) => format!("{x:.3} / {y:.3}"),
                    _ => "–".to_string(),
                },
            };
            let _ = write!(s, " {v} |");
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_lines_are_quoted_for_the_shell() {
        let args = [
            "simulate",
            "--report",
            "docs/study",
            "--area",
            "6 x 4",
            "it's",
        ];
        assert_eq!(
            command_line(args.map(String::from)),
            r"hoploc simulate --report docs/study --area '6 x 4' 'it'\''s'"
        );
        assert_eq!(command_line(Vec::<String>::new()), "hoploc");
    }

    #[test]
    fn comparisons_read_right() {
        assert_eq!(versus(1.0, 1.123), "12.3 % above");
        assert_eq!(versus(1.0, 0.96), "4.0 % below");
        assert_eq!(versus(0.706, 0.706), "equal to");
        assert_eq!(pct_below(2.0, 1.5), 25.0);
        assert_eq!(
            and_list(&["a".into(), "b".into(), "c".into()]),
            "a, b and c"
        );
        assert!(is_single("Ch2") && !is_single("Ch") && !is_single("Max"));
    }
}
