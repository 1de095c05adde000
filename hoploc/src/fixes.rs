//! The fixes of a testbed run against the ground truth: the per-position, per-estimator
//! RMSE/bias table of `hoploc demo`, its CSV, and its plots (fixes against the truth; error
//! over time). The estimators are the sink's two (from its lines) and the
//! host's references ([`crate::testbed::Reference`]: fixed parameters, online P0 only).

use std::path::{Path, PathBuf};

use loc_proto::sink_line::{Estimator, SinkLine};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::scenario::Scenario;
use crate::simulate::{register_font, write_png};
use crate::testbed::{Observed, Reference};

/// Where a fix comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Algo {
    /// The sink's thesis MLE (P0/α estimated online).
    Mle,
    /// The sink's windowed MMSE (P0/α estimated online).
    Mmse,
    /// The host's reference: the MLE with P0 and α fixed at the scenario's starting values.
    MleFixed,
    /// The host's reference: the f64 MLE with P0 estimated online, α fixed.
    MleP0Only,
}

/// Every [`Algo`], in table order.
pub const ALGOS: [Algo; 4] = [Algo::Mle, Algo::Mmse, Algo::MleFixed, Algo::MleP0Only];

/// An estimator's name in tables and plots.
pub fn name(a: Algo) -> &'static str {
    match a {
        Algo::Mle => "MLE",
        Algo::Mmse => "MMSE",
        Algo::MleFixed => "MLE-fixed",
        Algo::MleP0Only => "MLE-P0only",
    }
}

/// One fix line of the sink, in metres, with its truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FixRow {
    /// Simulated time, s.
    pub time_s: f64,
    /// Report sequence.
    pub seq: u16,
    /// The agent's stop.
    pub stop: usize,
    /// True position, m.
    pub truth: [f64; 2],
    /// Which estimator.
    pub estimator: Algo,
    /// The fix, m.
    pub pos: [f64; 2],
    /// α the sink used.
    pub alpha: f64,
    /// P0 the sink used, dBm.
    pub p0: f64,
    /// Anchors used.
    pub anchors: u8,
    /// Counted in the statistics (see [`Observed::settled`]).
    pub settled: bool,
}

impl FixRow {
    /// The error vector fix − truth, m.
    pub fn error(&self) -> [f64; 2] {
        [self.pos[0] - self.truth[0], self.pos[1] - self.truth[1]]
    }

    /// The distance to the truth, m.
    pub fn distance(&self) -> f64 {
        let [ex, ey] = self.error();
        ex.hypot(ey)
    }
}

/// The fix lines of `obs` (status and nofix lines left out).
pub fn rows(obs: &[Observed]) -> Vec<FixRow> {
    obs.iter()
        .filter_map(|o| match o.line {
            SinkLine::Fix {
                seq,
                estimator,
                x,
                y,
                alpha_x100,
                p0_x100,
                anchors,
                ..
            } => Some(FixRow {
                time_s: o.time_s,
                seq,
                stop: o.stop,
                truth: o.truth,
                estimator: match (o.reference, estimator) {
                    (Some(Reference::Fixed), _) => Algo::MleFixed,
                    (Some(Reference::P0Only), _) => Algo::MleP0Only,
                    (None, Estimator::Mle) => Algo::Mle,
                    (None, Estimator::Mmse) => Algo::Mmse,
                },
                pos: [x as f64 / 100.0, y as f64 / 100.0],
                alpha: alpha_x100 as f64 / 100.0,
                p0: p0_x100 as f64 / 100.0,
                anchors,
                settled: o.settled,
            }),
            _ => None,
        })
        .collect()
}

/// Statistics of the settled fixes of one stop (or all, `stop: None`) and estimator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stat {
    /// The stop, or `None` for every stop.
    pub stop: Option<usize>,
    /// The estimator.
    pub estimator: Algo,
    /// Settled fixes.
    pub n: usize,
    /// Root mean square distance to the truth, m.
    pub rmse: f64,
    /// Mean error in x and in y, m.
    pub bias: [f64; 2],
    /// Largest distance to the truth, m.
    pub max: f64,
}

impl Stat {
    /// The statistics of `rows` (all assumed settled and of one estimator).
    fn of(stop: Option<usize>, estimator: Algo, rows: &[&FixRow]) -> Stat {
        let n = rows.len();
        let k = n.max(1) as f64;
        let mse = rows.iter().map(|r| r.distance().powi(2)).sum::<f64>() / k;
        let bias = [0, 1].map(|i| rows.iter().map(|r| r.error()[i]).sum::<f64>() / k);
        let max = rows.iter().map(|r| r.distance()).fold(0.0, f64::max);
        Stat {
            stop,
            estimator,
            n,
            rmse: mse.sqrt(),
            bias,
            max,
        }
    }
}

/// The estimators `rows` has, in table order.
pub fn algos(rows: &[FixRow]) -> Vec<Algo> {
    ALGOS
        .into_iter()
        .filter(|a| rows.iter().any(|r| r.estimator == *a))
        .collect()
}

/// Per stop then over all stops, per estimator of `rows`: the statistics of the settled fixes.
pub fn table(rows: &[FixRow], stops: usize) -> Vec<Stat> {
    let mut out = Vec::new();
    for stop in (0..stops).map(Some).chain([None]) {
        for e in algos(rows) {
            let sel: Vec<&FixRow> = rows
                .iter()
                .filter(|r| r.settled && r.estimator == e && stop.is_none_or(|s| r.stop == s))
                .collect();
            out.push(Stat::of(stop, e, &sel));
        }
    }
    out
}

/// The table as text: stop, truth, estimator, fixes, RMSE, bias x and y, max error.
pub fn table_text(stats: &[Stat], s: &Scenario) -> String {
    let mut t = format!(
        "{:<5} {:>13} {:>6} {:<10} {:>5} {:>8} {:>8} {:>8} {:>7}\n",
        "stop", "truth (m)", "orient", "est", "fixes", "RMSE m", "bias x", "bias y", "max m"
    );
    for st in stats {
        let (stop, truth, orient) = match st.stop {
            Some(i) => {
                let p = &s.agent.path[i];
                let o = p.orientation_deg.unwrap_or(s.agent.orientation_deg);
                (
                    (i + 1).to_string(),
                    format!("({:.2}, {:.2})", p.position[0], p.position[1]),
                    format!("{o:.0}°"),
                )
            }
            None => ("all".into(), String::new(), String::new()),
        };
        if st.n == 0 {
            t += &format!(
                "{stop:<5} {truth:>13} {orient:>6} {:<10} {:>5} {:>8} {:>8} {:>8} {:>7}\n",
                name(st.estimator),
                0,
                "-",
                "-",
                "-",
                "-"
            );
        } else {
            t += &format!(
                "{stop:<5} {truth:>13} {orient:>6} {:<10} {:>5} {:>8.3} {:>+8.3} {:>+8.3} {:>7.3}\n",
                name(st.estimator),
                st.n,
                st.rmse,
                st.bias[0],
                st.bias[1],
                st.max
            );
        }
    }
    t
}

/// The header line of [`csv`].
pub const CSV_HEADER: &str =
    "time_s,seq,stop,truth_x_m,truth_y_m,estimator,x_m,y_m,error_m,alpha,p0_dbm,anchors,settled\n";

/// One fix as a line of [`csv`].
pub fn csv_row(r: &FixRow) -> String {
    format!(
        "{:.4},{},{},{},{},{},{},{},{:.3},{},{},{},{}\n",
        r.time_s,
        r.seq,
        r.stop + 1,
        r.truth[0],
        r.truth[1],
        name(r.estimator),
        r.pos[0],
        r.pos[1],
        r.distance(),
        r.alpha,
        r.p0,
        r.anchors,
        r.settled
    )
}

/// Every fix as CSV.
pub fn csv(rows: &[FixRow]) -> String {
    let mut t = String::from(CSV_HEADER);
    for r in rows {
        t += &csv_row(r);
    }
    t
}

/// Colour of stop `i` (the plots' one palette).
fn stop_color(i: usize) -> RGBColor {
    crate::tally::color(i)
}

/// Writes `fixes.svg/png` (per estimator: the settled fixes around each stop's truth, the
/// anchors) and `error.svg/png` (each estimator's distance to the truth over time) into `dir`.
pub fn write_plots(rows: &[FixRow], s: &Scenario, dir: &Path) -> Result<Vec<PathBuf>, String> {
    register_font()?;
    let mut files = Vec::new();
    let aspect = s.area.height_m / s.area.width_m;
    let panel_w = 460u32;
    let panels = algos(rows).len().max(1) as u32;
    let size = (panels * panel_w, (panel_w as f64 * aspect) as u32 + 136);
    let err_size = (3 * panel_w, 360);
    for (stem, size) in [("fixes", size), ("error", err_size)] {
        let svg = dir.join(format!("{stem}.svg"));
        let draw = |root: DrawingArea<SVGBackend, Shift>| {
            if stem == "fixes" {
                draw_fixes(root, rows, s)
            } else {
                draw_error(root, rows, s)
            }
        };
        draw(SVGBackend::new(&svg, size).into_drawing_area())
            .map_err(|e| format!("{}: {e}", svg.display()))?;
        files.push(svg);
        let png = dir.join(format!("{stem}.png"));
        let mut rgb = vec![0u8; 3 * size.0 as usize * size.1 as usize];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
            let r = if stem == "fixes" {
                draw_fixes(root, rows, s)
            } else {
                draw_error(root, rows, s)
            };
            r.map_err(|e| format!("{}: {e}", png.display()))?;
        }
        write_png(&png, size, &rgb).map_err(|e| format!("{}: {e}", png.display()))?;
        files.push(png);
    }
    Ok(files)
}

fn draw_fixes<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    rows: &[FixRow],
    s: &Scenario,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(err)?;
    let root = root
        .titled(
            &format!(
                "{}: settled fixes (dots) against the truth (crosses)",
                s.name
            ),
            ("sans-serif", 18),
        )
        .map_err(err)?;
    // A legend strip: each stop's colour, position and orientation.
    let (legend, root) = root.split_vertically(26);
    let mut x = 10;
    for (i, p) in s.agent.path.iter().enumerate() {
        let o = p.orientation_deg.unwrap_or(s.agent.orientation_deg);
        let text = format!(
            "stop {}: ({:.2}, {:.2}) {o:.0}°",
            i + 1,
            p.position[0],
            p.position[1]
        );
        legend
            .draw(&Circle::new((x, 13), 4, stop_color(i).filled()))
            .map_err(err)?;
        legend
            .draw(&Text::new(
                text.clone(),
                (x + 8, 6),
                ("sans-serif", 12).into_font().color(&BLACK),
            ))
            .map_err(err)?;
        x += 16 + 7 * text.chars().count() as i32;
    }
    let (w, h) = (s.area.width_m, s.area.height_m);
    let m = 0.05 * w.max(h);
    let algos = algos(rows);
    for (area, e) in root.split_evenly((1, algos.len())).iter().zip(algos) {
        let mut chart = ChartBuilder::on(area)
            .caption(name(e), ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(36)
            .build_cartesian_2d(-m..w + m, -m..h + m)
            .map_err(err)?;
        chart
            .configure_mesh()
            .max_light_lines(1)
            .x_desc("x (m)")
            .y_desc("y (m)")
            .label_style(("sans-serif", 12))
            .axis_desc_style(("sans-serif", 12))
            .draw()
            .map_err(err)?;
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(0.0, 0.0), (w, h)],
                BLACK.stroke_width(1),
            )))
            .map_err(err)?;
        chart
            .draw_series(
                s.anchors.iter().map(|a| {
                    TriangleMarker::new((a.position[0], a.position[1]), 7, BLACK.filled())
                }),
            )
            .map_err(err)?;
        chart
            .draw_series(
                rows.iter()
                    .filter(|r| r.settled && r.estimator == e)
                    .map(|r| Circle::new((r.pos[0], r.pos[1]), 2, stop_color(r.stop).filled())),
            )
            .map_err(err)?;
        chart
            .draw_series(s.agent.path.iter().enumerate().map(|(i, p)| {
                Cross::new(
                    (p.position[0], p.position[1]),
                    7,
                    stop_color(i).stroke_width(3),
                )
            }))
            .map_err(err)?;
    }
    root.present().map_err(err)
}

fn draw_error<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    rows: &[FixRow],
    s: &Scenario,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(err)?;
    let root = root
        .titled(
            &format!(
                "{}: distance of each fix to the truth over time (grey: warm-up and moves)",
                s.name
            ),
            ("sans-serif", 18),
        )
        .map_err(err)?;
    let t1 = s.duration_s();
    let ymax = rows
        .iter()
        .map(|r| r.distance())
        .fold(0.5, f64::max)
        .min(s.area.width_m.hypot(s.area.height_m))
        * 1.05;
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(44)
        .build_cartesian_2d(0.0..t1, 0.0..ymax)
        .map_err(err)?;
    chart
        .configure_mesh()
        .max_light_lines(1)
        .x_desc("simulated time (s)")
        .y_desc("error (m)")
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 12))
        .draw()
        .map_err(err)?;
    let colors = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
    ];
    for (e, c) in algos(rows).into_iter().zip(colors) {
        chart
            .draw_series(rows.iter().filter(|r| r.estimator == e).map(|r| {
                let col = if r.settled {
                    c
                } else {
                    RGBColor(170, 170, 170)
                };
                Circle::new((r.time_s, r.distance()), 2, col.filled())
            }))
            .map_err(err)?
            .label(name(e))
            .legend(move |(x, y)| Circle::new((x, y), 3, c.filled()));
    }
    chart
        .configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE)
        .label_font(("sans-serif", 12))
        .draw()
        .map_err(err)?;
    root.present().map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(stop: usize, e: Algo, pos: [f64; 2], settled: bool) -> FixRow {
        FixRow {
            time_s: 0.0,
            seq: 0,
            stop,
            truth: [1.0, 1.0],
            estimator: e,
            pos,
            alpha: 3.0,
            p0: -40.0,
            anchors: 4,
            settled,
        }
    }

    #[test]
    fn rmse_and_bias_of_the_settled_fixes() {
        let rows = [
            row(0, Algo::Mle, [1.3, 1.0], true),
            row(0, Algo::Mle, [1.0, 0.6], true),
            row(0, Algo::Mle, [9.0, 9.0], false),
            row(0, Algo::Mmse, [1.0, 1.0], true),
        ];
        let t = table(&rows, 1);
        assert_eq!(t.len(), 4);
        let mle = t[0];
        assert_eq!((mle.stop, mle.estimator, mle.n), (Some(0), Algo::Mle, 2));
        assert!((mle.rmse - ((0.09 + 0.16) / 2.0f64).sqrt()).abs() < 1e-12);
        assert!((mle.bias[0] - 0.15).abs() < 1e-12 && (mle.bias[1] + 0.2).abs() < 1e-12);
        assert!((mle.max - 0.4).abs() < 1e-12);
        assert_eq!((t[1].n, t[1].rmse), (1, 0.0));
        assert_eq!((t[2].stop, t[2].n), (None, 2));
    }
}
