//! Position fixes against ground truth: per (truth position, algorithm) accumulators, the
//! RMSE/bias table and the fixes-versus-truth scatter plot that `hoploc replay`, `hoploc monitor`
//! and the demo print and draw.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use loc_core::{Area, Point};
use plotters::prelude::*;

/// One algorithm's fixes at one truth position (or with no truth known).
#[derive(Clone, Debug, Default)]
pub struct Acc {
    /// The fixes, metres.
    pub fixes: Vec<Point>,
}

impl Acc {
    /// Number of fixes.
    pub fn len(&self) -> usize {
        self.fixes.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.fixes.is_empty()
    }

    /// The mean fix.
    pub fn mean(&self) -> Option<Point> {
        let n = self.fixes.len() as f64;
        (n > 0.0).then(|| {
            let (sx, sy) = self
                .fixes
                .iter()
                .fold((0.0, 0.0), |(sx, sy), p| (sx + p.x, sy + p.y));
            Point::new(sx / n, sy / n)
        })
    }

    /// Root mean square distance to `truth`, metres.
    pub fn rmse(&self, truth: Point) -> Option<f64> {
        let n = self.fixes.len() as f64;
        (n > 0.0).then(|| {
            let s: f64 = self.fixes.iter().map(|p| p.dist(truth).powi(2)).sum();
            (s / n).sqrt()
        })
    }

    /// Root mean square distance to the mean fix (the spread), metres.
    pub fn spread(&self) -> Option<f64> {
        self.mean().and_then(|m| self.rmse(m))
    }
}

/// A truth position as a map key (millimetres; `None`: unknown).
pub type TruthKey = Option<(i64, i64)>;

/// The key of `truth`.
pub fn truth_key(truth: Option<Point>) -> TruthKey {
    truth.map(|t| ((t.x * 1000.0).round() as i64, (t.y * 1000.0).round() as i64))
}

fn key_point(k: (i64, i64)) -> Point {
    Point::new(k.0 as f64 / 1000.0, k.1 as f64 / 1000.0)
}

/// Fixes of every algorithm, grouped by the truth at the time.
#[derive(Clone, Debug, Default)]
pub struct Tally {
    /// `(truth, algorithm label) → fixes`, in truth then label order.
    pub accs: BTreeMap<(TruthKey, String), Acc>,
    /// Algorithm labels in the order they were first seen (table and legend order).
    pub order: Vec<String>,
}

impl Tally {
    /// Adds `fix` of `algo` while the truth was `truth`.
    pub fn add(&mut self, truth: Option<Point>, algo: &str, fix: Point) {
        if !self.order.iter().any(|a| a == algo) {
            self.order.push(algo.to_string());
        }
        self.accs
            .entry((truth_key(truth), algo.to_string()))
            .or_default()
            .fixes
            .push(fix);
    }

    /// The truth positions seen (`None` first if fixes came without one).
    pub fn truths(&self) -> Vec<TruthKey> {
        let mut v: Vec<TruthKey> = self.accs.keys().map(|(t, _)| *t).collect();
        v.dedup();
        v
    }

    /// The accumulator of `algo` at `truth`.
    pub fn get(&self, truth: TruthKey, algo: &str) -> Option<&Acc> {
        self.accs.get(&(truth, algo.to_string()))
    }

    /// The table: per truth position and algorithm, the number of fixes, the RMSE and the bias
    /// (mean error in x and y) in metres; without a truth, the mean fix and its spread.
    pub fn table(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{:<13} {:<12} {:>6} {:>8} {:>8} {:>8} {:>8} {:>8}",
            "truth (m)", "algorithm", "fixes", "RMSE m", "bias x", "bias y", "mean x", "mean y"
        );
        for t in self.truths() {
            for algo in &self.order {
                let Some(acc) = self.get(t, algo) else {
                    continue;
                };
                let Some(mean) = acc.mean() else { continue };
                match t {
                    Some(k) => {
                        let p = key_point(k);
                        let rmse = acc.rmse(p).unwrap_or(f64::NAN);
                        let _ = writeln!(
                            out,
                            "{:<13} {:<12} {:>6} {:>8.3} {:>+8.3} {:>+8.3} {:>8.3} {:>8.3}",
                            format!("({:.2}, {:.2})", p.x, p.y),
                            algo,
                            acc.len(),
                            rmse,
                            mean.x - p.x,
                            mean.y - p.y,
                            mean.x,
                            mean.y
                        );
                    }
                    None => {
                        let _ = writeln!(
                            out,
                            "{:<13} {:<12} {:>6} {:>8} {:>8} {:>8} {:>8.3} {:>8.3}   spread {:.3} m",
                            "unknown",
                            algo,
                            acc.len(),
                            "-",
                            "-",
                            "-",
                            mean.x,
                            mean.y,
                            acc.spread().unwrap_or(f64::NAN)
                        );
                    }
                }
            }
        }
        out
    }

    /// Per algorithm over every truth position: fixes and RMSE (`None` if no fix had a truth).
    pub fn overall(&self) -> Vec<(String, usize, Option<f64>)> {
        self.order
            .iter()
            .map(|algo| {
                let (mut n, mut s) = (0usize, 0.0);
                for ((t, a), acc) in &self.accs {
                    if let (Some(k), true) = (t, a == algo) {
                        let p = key_point(*k);
                        n += acc.len();
                        s += acc.fixes.iter().map(|f| f.dist(p).powi(2)).sum::<f64>();
                    }
                }
                (algo.clone(), n, (n > 0).then(|| (s / n as f64).sqrt()))
            })
            .collect()
    }
}

/// A colour per algorithm or stop (by legend position): the plots' one palette.
pub(crate) fn color(k: usize) -> RGBColor {
    const C: [RGBColor; 10] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
    ];
    C[k % C.len()]
}

/// Draws the fixes of every algorithm in `tally` over the room `area` with the `anchors`
/// (squares) and the truth positions (black crosses); writes `<stem>.svg` and `<stem>.png` into
/// `dir` and returns their paths.
pub fn plot(
    tally: &Tally,
    area: Area,
    anchors: &[Point],
    title: &str,
    dir: &Path,
    stem: &str,
) -> Result<Vec<PathBuf>, String> {
    crate::simulate::register_font()?;
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let size = (900, 820);
    let svg = dir.join(format!("{stem}.svg"));
    draw(
        SVGBackend::new(&svg, size).into_drawing_area(),
        tally,
        area,
        anchors,
        title,
    )
    .map_err(|e| format!("{}: {e}", svg.display()))?;
    let png = dir.join(format!("{stem}.png"));
    let mut rgb = vec![0u8; 3 * size.0 as usize * size.1 as usize];
    draw(
        BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area(),
        tally,
        area,
        anchors,
        title,
    )
    .map_err(|e| e.to_string())
    .and_then(|()| crate::simulate::write_png(&png, size, &rgb))
    .map_err(|e| format!("{}: {e}", png.display()))?;
    Ok(vec![svg, png])
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    tally: &Tally,
    area: Area,
    anchors: &[Point],
    title: &str,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    // The room with a margin of 10 % (fixes may be clipped to the room, anchors may lie outside).
    let (mut x0, mut y0, mut x1, mut y1) = (0.0f64, 0.0f64, area.width, area.height);
    for a in anchors {
        x0 = x0.min(a.x);
        y0 = y0.min(a.y);
        x1 = x1.max(a.x);
        y1 = y1.max(a.y);
    }
    let m = 0.1 * (x1 - x0).max(y1 - y0).max(1.0);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(x0 - m..x1 + m, y0 - m..y1 + m)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .light_line_style(TRANSPARENT)
        .label_style(("sans-serif", 16))
        .draw()
        .map_err(e)?;
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(0.0, 0.0), (area.width, area.height)],
            BLACK.mix(0.6).stroke_width(1),
        )))
        .map_err(e)?;
    for (k, algo) in tally.order.iter().enumerate() {
        let c = color(k);
        let pts: Vec<(f64, f64)> = tally
            .accs
            .iter()
            .filter(|((_, a), _)| a == algo)
            .flat_map(|(_, acc)| acc.fixes.iter().map(|p| (p.x, p.y)))
            .collect();
        chart
            .draw_series(
                pts.iter()
                    .map(move |&p| Circle::new(p, 3, c.mix(0.5).filled())),
            )
            .map_err(e)?
            .label(algo.clone())
            .legend(move |(x, y)| Circle::new((x, y), 4, c.filled()));
    }
    chart
        .draw_series(anchors.iter().map(|a| {
            Rectangle::new(
                [(a.x - 0.08, a.y - 0.08), (a.x + 0.08, a.y + 0.08)],
                BLACK.filled(),
            )
        }))
        .map_err(e)?
        .label("anchor")
        .legend(|(x, y)| Rectangle::new([(x - 4, y - 4), (x + 4, y + 4)], BLACK.filled()));
    let truths: Vec<Point> = tally
        .truths()
        .into_iter()
        .flatten()
        .map(key_point)
        .collect();
    chart
        .draw_series(
            truths
                .iter()
                .map(|t| Cross::new((t.x, t.y), 9, BLACK.stroke_width(3))),
        )
        .map_err(e)?
        .label("truth")
        .legend(|(x, y)| Cross::new((x, y), 5, BLACK.stroke_width(2)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 16))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rmse_bias_and_table() {
        let mut t = Tally::default();
        let truth = Some(Point::new(2.0, 3.0));
        t.add(truth, "MLE", Point::new(2.0, 4.0));
        t.add(truth, "MLE", Point::new(2.0, 2.0));
        t.add(truth, "MMSE", Point::new(3.0, 3.0));
        t.add(None, "MLE", Point::new(1.0, 1.0));
        t.add(None, "MLE", Point::new(1.0, 3.0));
        let k = truth_key(truth);
        let mle = t.get(k, "MLE").unwrap();
        assert_eq!(mle.rmse(Point::new(2.0, 3.0)), Some(1.0));
        assert_eq!(mle.mean(), Some(Point::new(2.0, 3.0)));
        assert_eq!(
            t.get(k, "MMSE").unwrap().rmse(Point::new(2.0, 3.0)),
            Some(1.0)
        );
        assert_eq!(t.get(None, "MLE").unwrap().spread(), Some(1.0));
        let table = t.table();
        assert!(
            table.contains("(2.00, 3.00)  MLE               2    1.000   +0.000   +0.000"),
            "{table}"
        );
        assert!(
            table.contains("(2.00, 3.00)  MMSE              1    1.000   +1.000   +0.000"),
            "{table}"
        );
        assert!(
            table.contains("unknown       MLE               2"),
            "{table}"
        );
        assert!(table.contains("spread 1.000 m"), "{table}");
        let overall = t.overall();
        assert_eq!(overall[0], ("MLE".to_string(), 2, Some(1.0)));
        assert_eq!(overall[1], ("MMSE".to_string(), 1, Some(1.0)));
    }

    #[test]
    fn plots_are_written() {
        let dir = std::env::temp_dir().join(format!("hoploc-fixes-{}", std::process::id()));
        let mut t = Tally::default();
        t.add(Some(Point::new(2.0, 3.0)), "MLE", Point::new(2.1, 3.2));
        let files = plot(
            &t,
            Area::new(7.0, 7.0),
            &[
                Point::new(0.0, 0.0),
                Point::new(7.0, 0.0),
                Point::new(7.0, 7.0),
            ],
            "test",
            &dir,
            "fixes",
        )
        .unwrap();
        for f in &files {
            assert!(
                std::fs::metadata(f).unwrap().len() > 1000,
                "{}",
                f.display()
            );
        }
        let svg = std::fs::read_to_string(&files[0]).unwrap();
        assert!(svg.contains("MLE") && svg.contains("truth") && svg.contains("anchor"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
