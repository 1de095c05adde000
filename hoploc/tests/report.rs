//! `hoploc simulate --report DIR`: the page is written with the command line, the configuration,
//! the RMSE and bias tables with the right rows and columns, and plots that exist; and every
//! computed sentence of "What the study shows" agrees with the page's own tables, read back from
//! the Markdown (the winner is the smallest printed estimator cell, margins and percentages follow
//! from the printed values within rounding, counts are the counts). A tampered page fails the same
//! check, so the check can fail. Few runs keep this quick in debug builds.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Printed values are rounded to 3 decimals: each is within this of the true value.
const HALF: f64 = 0.0005;

fn hoploc(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .args(args)
        .output()
        .expect("run hoploc");
    assert!(
        out.status.success(),
        "hoploc {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn tmp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hoploc-report-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

macro_rules! ensure {
    ($cond:expr, $($fmt:tt)+) => {{
        let ok: bool = $cond;
        if !ok {
            return Err(format!($($fmt)+));
        }
    }};
}

/// One printed table: column labels, and per row label its cells (`None` for `–`).
#[derive(Debug, Default, Clone)]
struct MdTable {
    columns: Vec<String>,
    rows: Vec<(String, Vec<Option<String>>)>,
}

impl MdTable {
    fn value(&self, row: &str, col: &str) -> Option<f64> {
        let ci = self.columns.iter().position(|c| c == col)?;
        let (_, cells) = self.rows.iter().find(|(r, _)| r == row)?;
        cells[ci].as_deref().and_then(|v| v.parse().ok())
    }

    fn labels(&self) -> Vec<&str> {
        self.rows.iter().map(|(r, _)| r.as_str()).collect()
    }

    /// `(column, value)` of a row's printed cells.
    fn row_values(&self, row: &str) -> Vec<(String, f64)> {
        self.columns
            .iter()
            .filter_map(|c| self.value(row, c).map(|v| (c.clone(), v)))
            .collect()
    }
}

/// The page cut into what the checks need.
#[derive(Debug, Default)]
struct Page {
    command: String,
    config: BTreeMap<String, String>,
    /// Per σ label (`2`, `4`): the RMSE table.
    rmse: BTreeMap<String, MdTable>,
    /// Per σ label: the bias table (cells `x / y`).
    bias: BTreeMap<String, MdTable>,
    /// Overview sentences of "What the study shows".
    overview: Vec<String>,
    /// Per (σ label, anchors): the bullets.
    findings: BTreeMap<(String, usize), Vec<String>>,
    /// Link targets of the images and their wrapping links.
    links: Vec<String>,
}

fn parse_table(lines: &[&str]) -> MdTable {
    let cells = |l: &str| -> Vec<String> {
        l.trim()
            .trim_matches('|')
            .split('|')
            .map(|c| c.trim().to_string())
            .collect()
    };
    let mut t = MdTable::default();
    let mut it = lines.iter().take_while(|l| l.starts_with('|'));
    if let Some(h) = it.next() {
        t.columns = cells(h).into_iter().skip(1).collect();
    }
    it.next(); // |---|
    for l in it {
        let mut c = cells(l);
        let label = c.remove(0);
        t.rows.push((
            label,
            c.into_iter().map(|v| (v != "–").then_some(v)).collect(),
        ));
    }
    t
}

fn parse_page(md: &str) -> Page {
    let lines: Vec<&str> = md.lines().collect();
    let mut p = Page::default();
    let mut section = "";
    let mut sub = String::new();
    let mut k = 0;
    while k < lines.len() {
        let l = lines[k];
        if l == "```sh" {
            p.command = lines[k + 1].to_string();
        }
        if let Some(s) = l.strip_prefix("## ") {
            section = s;
            sub.clear();
        } else if let Some(s) = l.strip_prefix("### ") {
            sub = s.to_string();
        } else if section == "Configuration" && l.starts_with("| ") {
            let c: Vec<&str> = l.trim_matches('|').split('|').map(str::trim).collect();
            p.config.insert(c[0].to_string(), c[1].to_string());
        } else if section == "What the study shows" {
            if sub.is_empty() && !l.is_empty() && !l.starts_with("Computed from") {
                p.overview.push(l.to_string());
            } else if let Some(b) = l.strip_prefix("- ") {
                let (sigma, rest) = sub
                    .strip_prefix("σ = ")
                    .and_then(|s| s.split_once(" dB, "))
                    .expect("σ heading");
                let n: usize = rest.trim_end_matches(" anchors").parse().unwrap();
                p.findings
                    .entry((sigma.to_string(), n))
                    .or_default()
                    .push(b.to_string());
            }
        } else if l.starts_with('|') && (section == "RMSE" || section == "Bias") {
            let sigma = sub
                .strip_prefix("σ = ")
                .and_then(|s| s.split_once(" dB"))
                .expect("table heading")
                .0
                .to_string();
            let t = parse_table(&lines[k..]);
            k += t.rows.len() + 1;
            if section == "RMSE" {
                p.rmse.insert(sigma, t);
            } else {
                p.bias.insert(sigma, t);
            }
        }
        let mut rest = l;
        while let Some(i) = rest.find("](") {
            let tail = &rest[i + 2..];
            let end = tail.find(')').unwrap();
            p.links.push(tail[..end].to_string());
            rest = &tail[end..];
        }
        k += 1;
    }
    p
}

/// The number that ends `s` (after trimming `suffix`), e.g. `"… 0.706 m"` → 0.706.
fn num_end(s: &str, suffix: &str) -> Result<f64, String> {
    let s = s.trim().strip_suffix(suffix).unwrap_or(s).trim();
    let start = s
        .rfind(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
        .map_or(0, |i| i + s[i..].chars().next().unwrap().len_utf8());
    s[start..]
        .parse()
        .map_err(|_| format!("no number at the end of {s:?}"))
}

/// The first number in `s` and what follows it.
fn num_start(s: &str) -> Result<(f64, &str), String> {
    let s = s.trim_start();
    let end = s
        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
        .unwrap_or(s.len());
    let v = s[..end]
        .parse()
        .map_err(|_| format!("no number at the start of {s:?}"))?;
    Ok((v, &s[end..]))
}

fn between<'a>(s: &'a str, a: &str, b: &str) -> Result<&'a str, String> {
    let i = s.find(a).ok_or_else(|| format!("{a:?} not in {s:?}"))? + a.len();
    let j = s[i..]
        .find(b)
        .ok_or_else(|| format!("{b:?} not after {a:?} in {s:?}"))?;
    Ok(&s[i..i + j])
}

/// Min and max of `f(a, b)` over the printed values' rounding boxes (f monotone in each).
fn range(a: f64, b: f64, f: impl Fn(f64, f64) -> f64) -> (f64, f64) {
    let v = [
        f(a - HALF, b - HALF),
        f(a - HALF, b + HALF),
        f(a + HALF, b - HALF),
        f(a + HALF, b + HALF),
    ];
    (
        v.iter().copied().fold(f64::INFINITY, f64::min),
        v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    )
}

/// `claimed` (printed with `half` rounding) is a possible `f(a, b)` for the printed `a`, `b`.
fn agrees(claimed: f64, half: f64, a: f64, b: f64, f: impl Fn(f64, f64) -> f64) -> bool {
    let (lo, hi) = range(a, b, f);
    claimed >= lo - half - 1e-9 && claimed <= hi + half + 1e-9
}

fn pct_below(a: f64, b: f64) -> f64 {
    100.0 * (a - b) / a
}

/// `x` is the smallest of `all` as printed (ties allowed).
fn is_min(x: f64, all: impl IntoIterator<Item = f64>) -> bool {
    all.into_iter().all(|v| x <= v)
}

/// Checks "m (p %)" claims of the form `D m (P %) below ROW …` against `a` (reference) and
/// `b` (the winner).
fn check_margin(text: &str, a: f64, b: f64) -> Result<(), String> {
    let (d, rest) = num_start(text)?;
    let p = num_start(between(rest, "(", "%")?)?.0;
    ensure!(
        agrees(d, HALF, a, b, |a, b| a - b),
        "{text:?}: {d} m is not {a} − {b}"
    );
    ensure!(
        agrees(p, 0.05, a, b, pct_below),
        "{text:?}: {p} % is not 100·({a} − {b})/{a}"
    );
    Ok(())
}

/// `P % above|below the NAME (V m)` or `equal to the NAME (V m)` for `x` against the bound.
fn check_versus(text: &str, x: f64, bound: f64) -> Result<(), String> {
    let rel = |a: f64, b: f64| 100.0 * (b - a) / a;
    if text.starts_with("equal to") {
        ensure!(
            agrees(0.0, 0.05, bound, x, rel),
            "{text:?}: {x} is not equal to {bound}"
        );
        return Ok(());
    }
    let (p, rest) = num_start(text)?;
    let signed = if rest.trim_start().starts_with("% above") {
        p
    } else if rest.trim_start().starts_with("% below") {
        -p
    } else {
        return Err(format!("{text:?}: neither above nor below"));
    };
    ensure!(
        agrees(signed, 0.05, bound, x, rel),
        "{text:?}: {x} against {bound} is not {signed} %"
    );
    Ok(())
}

/// Every check of the page against its own tables. `Err` names the first disagreement.
fn check_page(p: &Page) -> Result<(), String> {
    ensure!(!p.findings.is_empty(), "no findings");
    let mut winners = Vec::new();
    for ((sigma, n), bullets) in &p.findings {
        let t = p
            .rmse
            .get(sigma)
            .ok_or(format!("no RMSE table for σ = {sigma}"))?;
        let bias = p
            .bias
            .get(sigma)
            .ok_or(format!("no bias table for σ = {sigma}"))?;
        let suffix = format!("-{n}");
        let est_rows: Vec<&str> = t
            .labels()
            .into_iter()
            .filter(|r| {
                r.ends_with(&suffix) && !r.starts_with("CRLB") && !r.starts_with("MMSE-floor")
            })
            .collect();
        let mle = format!("MLE-{n}");
        let mmse = format!("MMSE-{n}");
        let crlb = format!("CRLB-{n}");
        let floor = format!("MMSE-floor-{n}");
        let all_est: Vec<f64> = est_rows
            .iter()
            .flat_map(|r| t.row_values(r).into_iter().map(|c| c.1))
            .collect();
        let bullet = |key: &str| {
            bullets
                .iter()
                .find(|b| b.starts_with(&format!("**{key}:**")))
        };

        // Lowest RMSE.
        let b = bullet("Lowest RMSE").ok_or("no Lowest RMSE bullet")?;
        let row = between(b, ":** ", " with ")?;
        let col = between(b, " with ", ", ")?;
        let v = num_start(between(b, &format!("{col}, "), " m")?)?.0;
        ensure!(
            est_rows.contains(&row),
            "{b:?}: {row} is not an estimator row with {n} anchors"
        );
        ensure!(
            t.value(row, col) == Some(v),
            "{b:?}: the table has {:?}",
            t.value(row, col)
        );
        ensure!(
            is_min(v, all_est.iter().copied()),
            "{b:?}: {v} is not the smallest of {all_est:?}"
        );
        winners.push((
            sigma.clone(),
            *n,
            row.split('-').next().unwrap().to_string(),
            col.to_string(),
            v,
        ));
        if let Some(i) = b.find(&format!("below {mle} in the same column (")) {
            let y = t.value(&mle, col).ok_or("no MLE cell")?;
            let claimed_y = num_start(b[i..].split_once('(').unwrap().1)?.0;
            ensure!(claimed_y == y, "{b:?}: MLE {claimed_y} vs table {y}");
            let start = b[..i].rfind(": ").ok_or("margin")? + 2;
            check_margin(&b[start..i], y, v)?;
        }
        if let Some(i) = b.find(&format!("below {mle} at its best (")) {
            let inner = between(&b[i..], "(", ")")?;
            let (bc, by) = inner.split_once(", ").ok_or("best cell")?;
            let by = num_end(by, "m")?;
            let mle_vals = t.row_values(&mle);
            ensure!(t.value(&mle, bc) == Some(by), "{b:?}: MLE best {bc} {by}");
            ensure!(
                is_min(by, mle_vals.iter().map(|c| c.1)),
                "{b:?}: {by} is not MLE's smallest"
            );
            let start = b[..i]
                .rfind(", and ")
                .map(|k| k + 6)
                .or_else(|| b[..i].rfind(": ").map(|k| k + 2))
                .ok_or("margin")?;
            check_margin(&b[start..i], by, v)?;
        }
        if b.contains("the thesis' estimator wins here") {
            ensure!(row == mle, "{b:?}: says MLE wins but names {row}");
        }

        // MMSE vs MLE.
        if let Some(b) = bullet("MMSE vs MLE") {
            let (k, rest) = num_start(between(b, &format!("below {mle} in "), " columns")?)?;
            let m = num_end(rest, "")?;
            let pairs: Vec<(String, f64, f64)> = t
                .row_values(&mle)
                .into_iter()
                .filter_map(|(c, y)| t.value(&mmse, &c).map(|x| (c, y, x)))
                .collect();
            ensure!(
                m as usize == pairs.len(),
                "{b:?}: {} common columns",
                pairs.len()
            );
            let strict = pairs.iter().filter(|(_, y, x)| x < y).count();
            let loose = pairs.iter().filter(|(_, y, x)| x <= y).count();
            ensure!(
                (strict..=loose).contains(&(k as usize)),
                "{b:?}: MMSE is below in {strict}..={loose} columns"
            );
            let diffs: Vec<f64> = pairs.iter().map(|(_, y, x)| y - x).collect();
            for (which, part) in [
                ("from", between(b, "ranges from ", " to ")?),
                ("to", b.rsplit_once(" to ").ok_or("to")?.1),
            ] {
                let c = between(part, "%, ", ")")?;
                let (_, y, x) = pairs
                    .iter()
                    .find(|p| p.0 == c)
                    .ok_or(format!("{b:?}: column {c}"))?;
                check_margin(part, *y, *x)?;
                let d = y - x;
                let tol = 2.0 * HALF + 1e-9;
                let extreme = if which == "from" {
                    diffs.iter().all(|e| d <= e + tol)
                } else {
                    diffs.iter().all(|e| d >= e - tol)
                };
                ensure!(extreme, "{b:?}: {c} is not the {which} end of {diffs:?}");
            }
        }

        // Bounds.
        if let Some(b) = bullet("Bounds (Ext-MCH)") {
            for part in b
                .split_once(":** ")
                .unwrap()
                .1
                .trim_end_matches('.')
                .split("; ")
            {
                let (row, rest) = part.split_once(' ').unwrap();
                let (x, rest) = num_start(rest)?;
                ensure!(
                    t.value(row, "Ext-MCH") == Some(x),
                    "{part:?}: table {:?}",
                    t.value(row, "Ext-MCH")
                );
                let rest = rest
                    .trim_start()
                    .strip_prefix("m is ")
                    .ok_or(format!("{part:?}"))?;
                for claim in rest.split(" and ") {
                    let (name, bound_row) = if claim.contains("the CRLB") {
                        ("the CRLB", &crlb)
                    } else {
                        ("the MMSE floor", &floor)
                    };
                    let bv = t
                        .value(bound_row, "Ext-MCH")
                        .ok_or(format!("no {bound_row}"))?;
                    ensure!(
                        num_start(between(claim, &format!("{name} ("), " m")?)?.0 == bv,
                        "{claim:?}: {bound_row} is {bv}"
                    );
                    check_versus(claim, x, bv)?;
                }
            }
        }

        // Below the CRLB.
        if let Some(b) = bullet("Below the CRLB") {
            let mut named = Vec::new();
            if !b.contains("none of the estimators") {
                let list = between(b, ":** ", ". ")?;
                for row in &est_rows {
                    let Some(i) = list.find(&format!("{row} in ")) else {
                        continue;
                    };
                    let item = &list[i + row.len() + 4..];
                    let (k, rest) = num_start(item)?;
                    let m = num_start(rest.trim_start().strip_prefix("of").ok_or("of")?)?.0;
                    let after = rest.split_once("columns").ok_or("columns")?.1;
                    // `(Ch1 and Ch2)` or `(all but Max)`: the columns under (or not under) it.
                    let cols = after
                        .strip_prefix(" (")
                        .map(|a| a.split_once(')').unwrap().0);
                    named.push((
                        row.to_string(),
                        k as usize,
                        m as usize,
                        cols.map(str::to_string),
                    ));
                }
                ensure!(!named.is_empty(), "{b:?}: no row named");
                let claimed_bias = num_start(between(b, "reaches ", " m")?)?.0;
                let mut max_bias = 0.0f64;
                let (mut any, mut attained) = (false, false);
                for (row, ..) in &named {
                    for (c, x) in t.row_values(row) {
                        let cb = t.value(&crlb, &c).unwrap();
                        let cell = bias.rows.iter().find(|r| &r.0 == row).unwrap().1
                            [bias.columns.iter().position(|k| *k == c).unwrap()]
                        .clone()
                        .unwrap();
                        let (bx, by) = cell.split_once(" / ").unwrap();
                        let worst = bx.parse::<f64>().unwrap().max(by.parse().unwrap());
                        if x < cb {
                            max_bias = max_bias.max(worst);
                            any = true;
                        }
                        if x <= cb && worst == claimed_bias {
                            attained = true;
                        }
                    }
                }
                ensure!(any || attained, "{b:?}: no cell is below the CRLB");
                ensure!(
                    claimed_bias >= max_bias,
                    "{b:?}: bias {claimed_bias} < {max_bias}"
                );
                ensure!(
                    attained,
                    "{b:?}: no cell below the CRLB has bias {claimed_bias}"
                );
            }
            for row in &est_rows {
                let pairs: Vec<(f64, f64)> = t
                    .row_values(row)
                    .into_iter()
                    .filter_map(|(c, x)| t.value(&crlb, &c).map(|cb| (x, cb)))
                    .collect();
                let strict = pairs.iter().filter(|(x, cb)| x < cb).count();
                let loose = pairs.iter().filter(|(x, cb)| x <= cb).count();
                match named.iter().find(|(r, ..)| r == row) {
                    Some((_, k, m, cols)) => {
                        ensure!(
                            *m == pairs.len(),
                            "{b:?}: {row} has {} columns",
                            pairs.len()
                        );
                        ensure!(
                            (strict..=loose).contains(k) && *k > 0,
                            "{b:?}: {row} below in {strict}..={loose}"
                        );
                        ensure!(cols.is_some() == (*k < *m), "{b:?}: {row}: column list");
                        if let (Some(cols), true) = (cols, strict == loose) {
                            let under: Vec<String> = t
                                .row_values(row)
                                .into_iter()
                                .filter(|(c, x)| t.value(&crlb, c).is_some_and(|cb| *x < cb))
                                .map(|c| c.0)
                                .collect();
                            let over: Vec<String> = t
                                .row_values(row)
                                .into_iter()
                                .filter(|(c, x)| t.value(&crlb, c).is_some_and(|cb| *x > cb))
                                .map(|c| c.0)
                                .collect();
                            let (listed, want) = match cols.strip_prefix("all but ") {
                                Some(rest) => (rest, over),
                                None => (cols.as_str(), under),
                            };
                            let listed: Vec<String> = listed
                                .split(" and ")
                                .flat_map(|x| x.split(", "))
                                .map(str::to_string)
                                .collect();
                            ensure!(
                                listed == want,
                                "{b:?}: {row}: {listed:?}, the table says {want:?}"
                            );
                        }
                    }
                    None => ensure!(
                        strict == 0,
                        "{b:?}: {row} is below the CRLB in {strict} columns but not named"
                    ),
                }
            }
        }

        // Channels.
        if let Some(b) = bullet("Channels") {
            let body = b.split_once(":** ").unwrap().1;
            let (rows_part, crlb_part) = body
                .split_once(". The CRLB itself falls ")
                .unwrap_or((body, ""));
            for part in rows_part.trim_end_matches('.').split("; ") {
                let (row, rest) = part
                    .split_once(" against its best single channel (")
                    .ok_or(format!("{part:?}"))?;
                let (single, multi) = rest.split_once("): ").ok_or(format!("{part:?}"))?;
                let (sc, sv) = single.split_once(' ').unwrap();
                let sv = num_end(sv, "m")?;
                let singles: Vec<f64> = t
                    .row_values(row)
                    .into_iter()
                    .filter(|(c, _)| c.starts_with("Ch"))
                    .map(|c| c.1)
                    .collect();
                ensure!(
                    t.value(row, sc) == Some(sv) && is_min(sv, singles),
                    "{part:?}: best single channel"
                );
                for item in multi.split(", ") {
                    // `Linear avg 0.984 m (25.7 % below)`
                    let (label_value, rest) = item.split_once(" (").ok_or(format!("{item:?}"))?;
                    let (c, v) = label_value
                        .trim_end_matches(" m")
                        .rsplit_once(' ')
                        .ok_or(format!("{item:?}"))?;
                    let v: f64 = v.parse().map_err(|_| format!("{item:?}"))?;
                    ensure!(
                        t.value(row, c) == Some(v),
                        "{item:?}: table {:?}",
                        t.value(row, c)
                    );
                    let p = num_start(rest)?.0;
                    ensure!(
                        agrees(p, 0.05, sv, v, pct_below),
                        "{item:?}: {p} % below {sv}"
                    );
                }
            }
            if !crlb_part.is_empty() {
                let p = num_start(crlb_part)?.0;
                let (one, all) = (
                    t.value(&crlb, "Ch1").unwrap(),
                    t.value(&crlb, "Ext-MCH").unwrap(),
                );
                ensure!(
                    agrees(p, 0.05, one, all, pct_below),
                    "{b:?}: CRLB {one} → {all}"
                );
            }
        }

        // Baselines.
        if let Some(b) = bullet("Baselines vs MLE") {
            for part in b
                .split_once(":** ")
                .unwrap()
                .1
                .trim_end_matches('.')
                .split("; ")
            {
                let (row, rest) = part.split_once(" is ").unwrap();
                let (lo, rest) = num_start(rest)?;
                let hi = num_start(rest.trim_start_matches("× to "))?.0;
                let ratios: Vec<(f64, f64)> = t
                    .row_values(row)
                    .into_iter()
                    .filter_map(|(c, x)| t.value(&mle, &c).map(|y| (y, x)))
                    .collect();
                let k = num_start(between(part, "in its ", " columns")?)?.0;
                ensure!(
                    k as usize == ratios.len(),
                    "{part:?}: {} columns",
                    ratios.len()
                );
                let ratio = |y: f64, x: f64| x / y;
                let lo_ok = ratios.iter().any(|&(y, x)| agrees(lo, 0.005, y, x, ratio))
                    && ratios
                        .iter()
                        .all(|&(y, x)| range(y, x, ratio).1 >= lo - 0.005);
                let hi_ok = ratios.iter().any(|&(y, x)| agrees(hi, 0.005, y, x, ratio))
                    && ratios
                        .iter()
                        .all(|&(y, x)| range(y, x, ratio).0 <= hi + 0.005);
                ensure!(lo_ok && hi_ok, "{part:?}: ratios {ratios:?}");
                let below: Vec<String> = t
                    .row_values(row)
                    .into_iter()
                    .filter(|(c, x)| t.value(&mle, c).is_some_and(|y| *x < y))
                    .map(|c| c.0)
                    .collect();
                match part.split_once(", below it with ") {
                    Some((_, list)) => {
                        let listed: Vec<&str> =
                            list.split(" and ").flat_map(|x| x.split(", ")).collect();
                        ensure!(
                            listed.iter().all(|c| t.value(row, c) <= t.value(&mle, c)),
                            "{part:?}: {below:?}"
                        );
                        ensure!(
                            below.iter().all(|c| listed.contains(&c.as_str())),
                            "{part:?}: {below:?}"
                        );
                    }
                    None => ensure!(below.is_empty(), "{part:?}: below MLE in {below:?}"),
                }
                let best = between(part, "(its best: ", ")")?;
                let (bv, bc) = best.split_once(" m, ").unwrap();
                let bv: f64 = bv.parse().unwrap();
                ensure!(
                    t.value(row, bc) == Some(bv)
                        && is_min(bv, t.row_values(row).into_iter().map(|c| c.1)),
                    "{part:?}: best"
                );
            }
        }
    }

    // Overview: a common winner and the fourth anchor.
    for s in &p.overview {
        if let Some(rest) = s.strip_prefix("In all ") {
            let (k, _) = num_start(rest)?;
            let who = between(s, "the lowest RMSE is ", " with ")?;
            let tail = s.split_once(" with ").unwrap().1;
            let col = &tail[..tail.find([',', '.']).unwrap()];
            ensure!(
                k as usize == winners.len(),
                "{s:?}: {} cases",
                winners.len()
            );
            let mut margins = Vec::new();
            for (sigma, n, w, c, v) in &winners {
                let t = &p.rmse[sigma];
                ensure!(
                    t.value(&format!("{who}-{n}"), col) == Some(*v),
                    "{s:?}: σ {sigma}, {n} anchors: the lowest is {w} {c}"
                );
                let best_mle = t
                    .row_values(&format!("MLE-{n}"))
                    .into_iter()
                    .map(|c| c.1)
                    .fold(f64::INFINITY, f64::min);
                margins.push(range(best_mle, *v, pct_below));
            }
            if let Ok(r) = between(s, ", ", " below the thesis' MLE") {
                let (lo, rest) = num_start(r)?;
                let hi = num_start(rest.trim_start_matches(" % to "))?.0;
                ensure!(
                    margins.iter().all(|m| m.1 >= lo - 0.05 && m.0 <= hi + 0.05)
                        && margins.iter().any(|m| m.0 <= lo + 0.05 && m.1 >= lo - 0.05)
                        && margins.iter().any(|m| m.0 <= hi + 0.05 && m.1 >= hi - 0.05),
                    "{s:?}: margins {margins:?}"
                );
            }
        }
        if s.starts_with("A fourth anchor") {
            for part in s.split(" at σ = ").skip(1) {
                let sigma = part.split_once(' ').unwrap().0;
                let t = &p.rmse[sigma];
                let (a, b) = (
                    t.value("MLE-3", "Ext-MCH").unwrap(),
                    t.value("MLE-4", "Ext-MCH").unwrap(),
                );
                let arrow = between(part, "(", ")")?;
                let (ca, cb) = arrow.split_once(" → ").unwrap();
                ensure!(
                    num_end(ca, "m")? == a && num_end(cb, "m")? == b,
                    "{s:?}: {arrow}"
                );
            }
            let first = between(s, "by ", " %")?;
            let sigma0 = between(s, " at σ = ", " dB")?;
            let t = &p.rmse[sigma0];
            let (a, b) = (
                t.value("MLE-3", "Ext-MCH").unwrap(),
                t.value("MLE-4", "Ext-MCH").unwrap(),
            );
            ensure!(
                agrees(num_start(first)?.0, 0.05, a, b, pct_below),
                "{s:?}: {first} %"
            );
        }
    }
    Ok(())
}

/// The structure of a page: tables with these columns and rows, plots that exist.
fn check_structure(
    p: &Page,
    dir: &Path,
    columns: &[&str],
    rows: &[&str],
    sigmas: &[&str],
    anchors: &[usize],
) {
    assert_eq!(p.rmse.len(), sigmas.len());
    for s in sigmas {
        let t = &p.rmse[*s];
        assert_eq!(t.columns, columns, "σ = {s}");
        assert_eq!(t.labels(), rows, "σ = {s}");
        for (r, cells) in &t.rows {
            assert_eq!(cells.len(), columns.len(), "{r}");
            for c in cells.iter().flatten() {
                let v: f64 = c.parse().unwrap_or_else(|_| panic!("{r}: {c}"));
                assert!(v > 0.0 && v < 50.0, "{r}: {v}");
            }
            // Baselines work on distances: no Ext-MCH cell.
            let baseline = ["MDS", "TRLT", "QUAD"].iter().any(|b| r.starts_with(b));
            assert_eq!(cells.last().unwrap().is_none(), baseline, "{r}");
        }
        let b = &p.bias[*s];
        assert_eq!(b.columns, columns);
        let est: Vec<&str> = rows
            .iter()
            .copied()
            .filter(|r| !r.starts_with("CRLB") && !r.starts_with("MMSE-floor"))
            .collect();
        assert_eq!(b.labels(), est);
        for (r, cells) in &b.rows {
            for c in cells.iter().flatten() {
                let (x, y) = c.split_once(" / ").unwrap_or_else(|| panic!("{r}: {c}"));
                assert!(
                    x.parse::<f64>().is_ok() && y.parse::<f64>().is_ok(),
                    "{r}: {c}"
                );
            }
        }
        for n in anchors {
            assert!(
                p.findings.contains_key(&(s.to_string(), *n)),
                "σ = {s}, {n} anchors"
            );
        }
    }
    assert!(!p.links.is_empty());
    let mut pngs = 0;
    for l in &p.links {
        assert!(
            !l.contains("://") && !l.starts_with('/'),
            "{l}: not relative"
        );
        let f = dir.join(l);
        let bytes = std::fs::read(&f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        if l.ends_with(".png") {
            assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "{l}");
            pngs += 1;
        } else if l.ends_with(".svg") {
            assert!(String::from_utf8_lossy(&bytes).contains("<svg"), "{l}");
        }
    }
    assert_eq!(pngs, sigmas.len() * anchors.len());
}

/// Changes `md` by `f` at the first line starting with `prefix` (and containing `needle`).
fn edit_line(md: &str, prefix: &str, needle: &str, f: impl Fn(&str) -> String) -> Option<String> {
    let line = md
        .lines()
        .find(|l| l.starts_with(prefix) && l.contains(needle))?;
    let new = f(line);
    (new != line).then(|| md.replacen(line, &new, 1))
}

/// `line` with the number that starts right after the first `marker` changed by `f`.
fn bump(line: &str, marker: &str, f: impl Fn(f64) -> f64, decimals: usize) -> String {
    let Some(i) = line.find(marker).map(|i| i + marker.len()) else {
        return line.to_string();
    };
    let Ok((v, rest)) = num_start(&line[i..]) else {
        return line.to_string();
    };
    format!("{}{:.*}{rest}", &line[..i], decimals, f(v))
}

/// Wrong pages: each tampered copy of a page that passes must fail [`check_page`].
fn assert_tampers_fail(md: &str) {
    let mut tampers: Vec<(&str, Option<String>)> = Vec::new();
    // A baseline's Ch1 cell made the smallest of the first table: the winner named is wrong.
    tampers.push((
        "winner",
        edit_line(md, "| MDS-", "", |l| {
            let mut c: Vec<&str> = l.trim_matches('|').split('|').map(str::trim).collect();
            c[1] = "0.001";
            format!("| {} |", c.join(" | "))
        }),
    ));
    // The first bound's direction flipped.
    tampers.push((
        "bound direction",
        edit_line(md, "- **Bounds (Ext-MCH):**", "the CRLB", |l| {
            if l.contains("% below the CRLB") {
                l.replacen("% below the CRLB", "% above the CRLB", 1)
            } else {
                l.replacen("% above the CRLB", "% below the CRLB", 1)
            }
        }),
    ));
    tampers.push((
        "bound percentage",
        edit_line(md, "- **Bounds (Ext-MCH):**", "", |l| {
            bump(l, " m is ", |v| v + 1.0, 1)
        }),
    ));
    tampers.push((
        "winner's margin",
        edit_line(md, "- **Lowest RMSE:**", " below MLE-", |l| {
            bump(l, " m: ", |v| v + 0.01, 3)
        }),
    ));
    tampers.push((
        "winner's percentage",
        edit_line(md, "- **Lowest RMSE:**", " below MLE-", |l| {
            bump(l, " m (", |v| v + 1.0, 1)
        }),
    ));
    tampers.push((
        "MMSE count",
        edit_line(md, "- **MMSE vs MLE:**", "", |l| {
            bump(
                l,
                "below MLE-3 in ",
                |v| if v > 0.0 { v - 1.0 } else { 1.0 },
                0,
            )
        }),
    ));
    tampers.push((
        "MMSE range end",
        edit_line(md, "- **MMSE vs MLE:**", "", |l| {
            bump(l, "ranges from ", |v| v + 0.01, 3)
        }),
    ));
    tampers.push((
        "CRLB count",
        edit_line(md, "- **Below the CRLB:**", "", |l| {
            if l.contains("none of the estimators") {
                l.replacen(
                    "none of the estimators.",
                    "MLE-3 in 1 of 5 columns (Ch1). x",
                    1,
                )
            } else {
                bump(l, " in ", |v| v + 1.0, 0)
            }
        }),
    ));
    tampers.push((
        "channel value",
        edit_line(md, "- **Channels:**", "", |l| {
            bump(l, "Max ", |v| v + 0.01, 3)
        }),
    ));
    tampers.push((
        "baseline ratio",
        edit_line(md, "- **Baselines vs MLE:**", "", |l| {
            bump(l, " is ", |v| v + 0.1, 2)
        }),
    ));
    tampers.push((
        "fourth anchor",
        edit_line(md, "A fourth anchor", "", |l| {
            bump(l, " by ", |v| v + 1.0, 1)
        }),
    ));
    // MLE and MMSE rows of the first RMSE table swapped: the prose no longer fits.
    tampers.push(("swapped rows", {
        let mle = md.lines().find(|l| l.starts_with("| MLE-3 |"));
        let mmse = md.lines().find(|l| l.starts_with("| MMSE-3 |"));
        mle.zip(mmse).map(|(a, b)| {
            let swap = |l: &str, from: &str, to: &str| l.replacen(from, to, 1);
            md.replacen(a, "@@A@@", 1)
                .replacen(b, &swap(a, "| MLE-3 |", "| MMSE-3 |"), 1)
                .replacen("@@A@@", &swap(b, "| MMSE-3 |", "| MLE-3 |"), 1)
        })
    }));
    let mut applied = 0;
    for (what, bad) in tampers {
        let Some(bad) = bad else { continue };
        applied += 1;
        assert!(
            check_page(&parse_page(&bad)).is_err(),
            "the check passed a page with a wrong {what}"
        );
    }
    assert!(applied >= 10, "only {applied} tampers applied");
}

#[test]
fn report_page_has_tables_plots_and_findings_that_match_them() {
    let dir = tmp_dir("default");
    let d = dir.to_str().unwrap();
    let stdout = hoploc(&["simulate", "--runs", "2", "--seed", "7", "--report", d]);
    assert!(
        stdout.contains("mean per-point RMSE"),
        "the text tables still go to stdout"
    );
    let md = std::fs::read_to_string(dir.join("README.md")).unwrap();
    let p = parse_page(&md);
    assert_eq!(
        p.command,
        format!("hoploc simulate --runs 2 --seed 7 --report {d}")
    );
    assert_eq!(p.config["Seed"], "7");
    assert!(p.config["Agent positions × runs"].contains("361 points"));
    assert!(p.config["Agent positions × runs"].contains("× 2 runs"));
    assert_eq!(p.config["Shadowing σ"], "2 dB, 4 dB");
    assert!(p.config["Parameters"].starts_with("known"));
    assert!(p.config["Path loss (truth)"].contains("α = 3"));
    check_structure(
        &p,
        &dir,
        &["Ch1", "Ch2", "Max", "Linear avg", "Ext-MCH"],
        &[
            "MLE-3",
            "MMSE-3",
            "MDS-3",
            "TRLT-3",
            "CRLB-3",
            "MMSE-floor-3",
            "MLE-4",
            "MMSE-4",
            "MDS-4",
            "QUAD-4",
            "CRLB-4",
            "MMSE-floor-4",
        ],
        &["2", "4"],
        &[3, 4],
    );
    // Every bullet kind is there for every case, and the findings agree with the tables.
    for ((s, n), b) in &p.findings {
        for key in [
            "Lowest RMSE",
            "MMSE vs MLE",
            "Bounds (Ext-MCH)",
            "Below the CRLB",
            "Channels",
            "Baselines vs MLE",
        ] {
            assert!(
                b.iter().any(|x| x.starts_with(&format!("**{key}:**"))),
                "σ {s}, {n}: no {key}"
            );
        }
    }
    assert!(
        p.overview.iter().any(|s| s.starts_with("A fourth anchor")),
        "{:?}",
        p.overview
    );
    check_page(&p).unwrap();
    assert_tampers_fail(&md);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn same_command_same_page_and_plots() {
    let run = |name: &str| {
        let dir = tmp_dir(name);
        hoploc(&[
            "simulate",
            "--runs",
            "1",
            "--sigma",
            "2",
            "--anchors",
            "4",
            "--estimator",
            "MLE,QUAD",
            "--no-floor",
            "--report",
            dir.to_str().unwrap(),
        ]);
        let md = std::fs::read_to_string(dir.join("README.md"))
            .unwrap()
            .replace(dir.to_str().unwrap(), "DIR");
        let png = std::fs::read(dir.join("cdf-sigma2-4anchors.png")).unwrap();
        let svg = std::fs::read(dir.join("cdf-sigma2-4anchors.svg")).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        (md, png, svg)
    };
    let (a, b) = (run("same-a"), run("same-b"));
    assert_eq!(a.0, b.0);
    assert!(a.1 == b.1 && a.2 == b.2, "plots differ");
    check_page(&parse_page(&a.0)).unwrap();
}

#[test]
fn report_with_estimated_parameters_and_fewer_rows() {
    // Estimated parameters, three channels, one layout, no floor, no MMSE: the page adapts and
    // still agrees with itself.
    let dir = tmp_dir("estimated");
    hoploc(&[
        "simulate",
        "--runs",
        "2",
        "--sigma",
        "3",
        "--anchors",
        "4",
        "--channels",
        "3",
        "--params",
        "estimated",
        "--estimator",
        "MLE,QUAD,MDS",
        "--no-floor",
        "--report",
        dir.to_str().unwrap(),
    ]);
    let md = std::fs::read_to_string(dir.join("README.md")).unwrap();
    let p = parse_page(&md);
    assert!(
        p.config["Parameters"].starts_with("estimated"),
        "{:?}",
        p.config
    );
    check_structure(
        &p,
        &dir,
        &["Ch1", "Ch2", "Ch3", "Max", "Linear avg", "Ext-MCH"],
        &["MLE-4", "MDS-4", "QUAD-4", "CRLB-4"],
        &["3"],
        &[4],
    );
    let b = &p.findings[&("3".to_string(), 4)];
    assert!(
        !b.iter().any(|x| x.starts_with("**MMSE vs MLE:**")),
        "{b:?}"
    );
    assert!(b.iter().any(|x| x.contains("from 1 channel to 3")), "{b:?}");
    check_page(&p).unwrap();
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn help_documents_the_report_flag() {
    let help = hoploc(&["simulate", "--help"]);
    assert!(help.contains("--report <DIR>"), "{help}");
    assert!(
        help.contains("hoploc simulate --report docs/study"),
        "{help}"
    );
}

#[test]
fn committed_study_pages_agree_with_themselves() {
    // docs/study/ is generated by scripts/gen-docs.sh: the thesis study (known parameters) and
    // the estimated-parameter study; each page's prose must match its tables, its plots must be
    // there, and it must say which command wrote it.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/study");
    for (sub, command, params) in [
        ("", "hoploc simulate --report docs/study", "known"),
        (
            "estimated",
            "hoploc simulate --params estimated --report docs/study/estimated",
            "estimated",
        ),
    ] {
        let dir = root.join(sub);
        let md = std::fs::read_to_string(dir.join("README.md"))
            .unwrap_or_else(|e| panic!("{}: {e} (run scripts/gen-docs.sh)", dir.display()));
        let p = parse_page(&md);
        assert_eq!(p.command, command);
        assert_eq!(p.config["Seed"], "1");
        assert!(p.config["Agent positions × runs"].contains("361 points"));
        assert!(p.config["Agent positions × runs"].contains("× 100 runs"));
        assert!(p.config["Parameters"].starts_with(params));
        // Both are the thesis' study with clipped baselines; the estimated one says it differs
        // in its parameters, and nothing else.
        assert_eq!(p.config["Baselines clipped to the area"], "yes");
        let settings = between(&md, "## The thesis' settings\n", "\n## ").unwrap();
        if params == "known" {
            assert!(settings.contains("This page uses the thesis' settings."));
        } else {
            let d = between(settings, "This page differs from them: ", ".\n").unwrap();
            assert!(
                d.starts_with("P0, α and σ are not known") && !d.contains(" and the "),
                "{d}"
            );
        }
        check_structure(
            &p,
            &dir,
            &["Ch1", "Ch2", "Max", "Linear avg", "Ext-MCH"],
            &[
                "MLE-3",
                "MMSE-3",
                "MDS-3",
                "TRLT-3",
                "CRLB-3",
                "MMSE-floor-3",
                "MLE-4",
                "MMSE-4",
                "MDS-4",
                "QUAD-4",
                "CRLB-4",
                "MMSE-floor-4",
            ],
            &["2", "4"],
            &[3, 4],
        );
        check_page(&p).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        assert_tampers_fail(&md);
    }
}
