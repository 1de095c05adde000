//! `hoploc simulate` end to end: accuracy at tiny noise, determinism (seed, thread count), the
//! CSV/JSON outputs parse back with the right rows and columns, the plots are real SVG/PNG files,
//! the estimated-parameter modes, and the help text. Small runs keep this quick in debug builds.

use std::path::PathBuf;
use std::process::Command;

use hoploc::study::{self, Algo, Config, ParamSource, RowKind, StudyResult};
use loc_core::grid::{self, Search};
use loc_core::refine::{Obs, Observations};
use loc_core::Point;

const COLUMNS: [&str; 5] = ["Ch1", "Ch2", "Max", "Linear avg", "Ext-MCH"];

fn hoploc(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .args(args)
        .output()
        .expect("run hoploc");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn ok(args: &[&str]) -> String {
    let (success, stdout, stderr) = hoploc(args);
    assert!(success, "hoploc {args:?} failed:\n{stdout}\n{stderr}");
    stdout
}

fn tmp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hoploc-simulate-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn small(sigmas: &[f64], algos: &[Algo]) -> Config {
    Config {
        runs: 1,
        sigmas: sigmas.to_vec(),
        algos: algos.to_vec(),
        ..Config::default()
    }
}

fn cell<'a>(r: &'a StudyResult, sigma: usize, row: &str, col: &str) -> &'a study::Cell {
    let ci = r.columns.iter().position(|c| c == col).expect("column");
    r.tables[sigma]
        .rows
        .iter()
        .find(|x| x.label == row)
        .unwrap_or_else(|| panic!("row {row}"))
        .cells[ci]
        .as_ref()
        .unwrap_or_else(|| panic!("cell {row} {col}"))
}

/// The error at `p` of the noise-free exhaustive lattice MLE (loc-core directly).
fn noise_free_mle_error(cfg: &Config, n: usize, p: Point) -> f64 {
    let anchors = study::anchors(cfg.area, n);
    let obs: Vec<Obs> = anchors
        .iter()
        .map(|&pos| Obs {
            pos,
            z: cfg.truth.rssi_at(p.dist(pos)),
            weight: 1.0,
        })
        .collect();
    let est = grid::mle(
        &Observations::from_slice(&obs),
        cfg.truth,
        cfg.area,
        Search::Exhaustive,
    )
    .unwrap();
    est.pos.dist(p)
}

#[test]
fn tiny_noise_lands_on_the_lattice_neighbours() {
    let fine = 10.0 / 50.0;
    let step = fine * 2f64.sqrt(); // one fine step in x and in y
    for search in [Search::Exhaustive, Search::Thesis, Search::MultiStart] {
        // MMSE does not depend on the search: once is enough.
        let algos: &[Algo] = if search == Search::Exhaustive {
            &[Algo::Mle, Algo::Mmse]
        } else {
            &[Algo::Mle]
        };
        let cfg = Config {
            search,
            floor: false,
            ..small(&[0.01], algos)
        };
        let r = study::run(&cfg, &|_| {}).unwrap();
        for row in &r.tables[0].rows {
            if !matches!(row.kind, RowKind::Estimator(_)) {
                continue;
            }
            for (col, c) in r.columns.iter().zip(&row.cells) {
                let c = c.as_ref().unwrap();
                assert_eq!(c.per_point_rmse.len(), 361);
                let within = c
                    .per_point_rmse
                    .iter()
                    .filter(|e| **e <= step + 1e-9)
                    .count();
                // Under noise-free RSSI the cost is not isotropic: beside an anchor a tangential
                // error costs little, so with three anchors the lattice minimiser itself can sit
                // a step or two away at a few points there; and the fast searches can stop short
                // of it. Nearly everywhere the estimate is a lattice neighbour of the truth.
                assert!(
                    within >= 361 * 95 / 100,
                    "{search:?} {} {col}: only {within} of 361 points within one fine step",
                    row.label
                );
                assert!(c.rmse < 0.15, "{search:?} {} {col}: {}", row.label, c.rmse);
            }
        }
    }
    // With 10⁻⁴ dB of noise the exhaustive search finds the noise-free lattice MLE at every
    // point (at 0.01 dB near-ties between lattice points, cost gaps of ~0.005, can flip).
    let cfg = Config {
        search: Search::Exhaustive,
        floor: false,
        ..small(&[1e-4], &[Algo::Mle])
    };
    let r = study::run(&cfg, &|_| {}).unwrap();
    let pts = study::points(cfg.area);
    for row in r.tables[0]
        .rows
        .iter()
        .filter(|r| r.label.starts_with("MLE"))
    {
        for (col, c) in r.columns.iter().zip(&row.cells) {
            let off: Vec<Point> = pts
                .iter()
                .zip(&c.as_ref().unwrap().per_point_rmse)
                .filter(|(p, e)| (**e - noise_free_mle_error(&cfg, row.anchors, **p)).abs() > 1e-6)
                .map(|(p, _)| *p)
                .collect();
            assert!(off.is_empty(), "{} {col}: {off:?}", row.label);
        }
    }
}

#[test]
fn same_seed_same_json_whatever_the_thread_count() {
    let args = |threads: &str, seed: &str| {
        ok(&[
            "simulate",
            "--runs",
            "1",
            "--sigma",
            "3",
            "--anchors",
            "3",
            "--format",
            "json",
            "--threads",
            threads,
            "--seed",
            seed,
        ])
    };
    let a = args("1", "7");
    assert_eq!(a, args("1", "7"), "same seed, same output");
    assert_eq!(a, args("2", "7"), "thread count changes nothing");
    assert_ne!(a, args("2", "8"), "another seed, other numbers");
}

#[test]
fn csv_json_and_plots_parse_back() {
    let dir = tmp_dir("files");
    let stdout = ok(&[
        "simulate",
        "--runs",
        "1",
        "--sigma",
        "2",
        "4",
        "--format",
        "csv",
        "--out-dir",
        dir.to_str().unwrap(),
    ]);
    // CSV on stdout equals the file.
    let csv = std::fs::read_to_string(dir.join("study.csv")).unwrap();
    assert_eq!(stdout, csv);
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(
        header,
        [
            "sigma_db",
            "row",
            "anchors",
            "column",
            "rmse_m",
            "rmse_se_m",
            "bias_x_m",
            "bias_y_m",
            "failures"
        ]
    );
    let rows: Vec<Vec<String>> = lines
        .map(|l| l.split(',').map(str::to_owned).collect())
        .collect();
    assert!(rows.iter().all(|r| r.len() == 9));
    // Per σ: 3 anchors: MLE, MMSE (5 columns), MDS, TRLT (4), CRLB, floor (5);
    // 4 anchors: the same with QUAD.
    let per_layout = 5 + 5 + 4 + 4 + 5 + 5;
    assert_eq!(rows.len(), 2 * 2 * per_layout);
    let labels: Vec<&str> = {
        let mut v: Vec<&str> = Vec::new();
        for r in rows.iter().filter(|r| r[0] == "2") {
            if !v.contains(&r[1].as_str()) {
                v.push(&r[1]);
            }
        }
        v
    };
    assert_eq!(
        labels,
        [
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
            "MMSE-floor-4"
        ]
    );
    for r in &rows {
        assert!(COLUMNS.contains(&r[3].as_str()), "{r:?}");
        let rmse: f64 = r[4].parse().unwrap();
        assert!(rmse > 0.0 && rmse < 20.0, "{r:?}");
        let is_estimator = !(r[1].starts_with("CRLB") || r[1].starts_with("MMSE-floor"));
        assert_eq!(r[6].is_empty(), !is_estimator, "{r:?}");
        assert_eq!(r[5].is_empty(), r[1].starts_with("CRLB"), "{r:?}");
        if r[1].starts_with("MDS") || r[1].starts_with("TRLT") || r[1].starts_with("QUAD") {
            assert_ne!(r[3], "Ext-MCH");
        }
    }

    // JSON: the same tables.
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("study.json")).unwrap()).unwrap();
    assert_eq!(json["columns"], serde_json::json!(COLUMNS));
    assert_eq!(json["config"]["runs"], 1);
    assert_eq!(json["config"]["points"], 361);
    let tables = json["tables"].as_array().unwrap();
    assert_eq!(tables.len(), 2);
    assert_eq!(tables[1]["sigma"], 4.0);
    let jrows = tables[0]["rows"].as_array().unwrap();
    let jlabels: Vec<&str> = jrows.iter().map(|r| r["label"].as_str().unwrap()).collect();
    assert_eq!(jlabels, labels);
    for r in jrows {
        let cells = r["cells"].as_array().unwrap();
        assert_eq!(cells.len(), 5);
        let baseline = ["MDS", "TRLT", "QUAD"]
            .iter()
            .any(|b| r["label"].as_str().unwrap().starts_with(b));
        assert_eq!(cells[4].is_null(), baseline, "{r}");
    }
    // A JSON cell equals its CSV line.
    let mle = &jrows[0]["cells"][2];
    let line = rows
        .iter()
        .find(|r| r[0] == "2" && r[1] == "MLE-3" && r[3] == "Max")
        .unwrap();
    assert_eq!(
        mle["rmse"].as_f64().unwrap(),
        line[4].parse::<f64>().unwrap()
    );
    assert_eq!(
        mle["bias_y"].as_f64().unwrap(),
        line[7].parse::<f64>().unwrap()
    );

    // Text and plots.
    let text = std::fs::read_to_string(dir.join("study.txt")).unwrap();
    assert!(text.contains("σ = 4 dB: mean per-point RMSE (m)"), "{text}");
    for sigma in ["2", "4"] {
        for n in [3, 4] {
            let stem = format!("cdf-sigma{sigma}-{n}anchors");
            let svg = std::fs::read_to_string(dir.join(format!("{stem}.svg"))).unwrap();
            assert!(svg.contains("<svg") && svg.contains("MLE-"), "{stem}.svg");
            assert!(
                svg.contains("<polyline") || svg.contains("<path"),
                "{stem}.svg"
            );
            let png = std::fs::read(dir.join(format!("{stem}.png"))).unwrap();
            assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"), "{stem}.png");
            assert!(png.len() > 10_000, "{stem}.png: {} bytes", png.len());
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn estimated_parameters_approach_known_at_small_noise() {
    let algos = [Algo::Mle, Algo::Mmse, Algo::Trlt];
    let base = Config {
        anchor_counts: vec![3],
        runs: 3,
        ..small(&[0.05], &algos)
    };
    let known = study::run(&base, &|_| {}).unwrap();
    for params in [ParamSource::Estimated, ParamSource::Ar1] {
        let est = study::run(
            &Config {
                params,
                ..base.clone()
            },
            &|_| {},
        )
        .unwrap();
        for row in ["MLE-3", "MMSE-3", "TRLT-3"] {
            for col in ["Ch1", "Max", "Linear avg"] {
                let (k, e) = (cell(&known, 0, row, col), cell(&est, 0, row, col));
                assert!(
                    (k.rmse - e.rmse).abs() < 0.03,
                    "{params:?} {row} {col}: known {} vs estimated {}",
                    k.rmse,
                    e.rmse
                );
            }
        }
        // The bounds do not depend on what the estimators know.
        assert_eq!(
            cell(&known, 0, "CRLB-3", "Ch1").rmse,
            cell(&est, 0, "CRLB-3", "Ch1").rmse
        );
    }
    // At the thesis' σ estimation costs accuracy: one channel's 6 anchor pairs hardly pin α.
    let noisy = Config {
        anchor_counts: vec![3],
        floor: false,
        ..small(&[4.0], &[Algo::Mle])
    };
    let k = study::run(&noisy, &|_| {}).unwrap();
    let e = study::run(
        &Config {
            params: ParamSource::Estimated,
            ..noisy
        },
        &|_| {},
    )
    .unwrap();
    assert!(cell(&e, 0, "MLE-3", "Ch1").rmse > cell(&k, 0, "MLE-3", "Ch1").rmse);
}

#[test]
fn known_parameters_floor_is_the_mmse_row_and_bounds_order() {
    let r = study::run(&small(&[4.0], &[Algo::Mle, Algo::Mmse]), &|_| {}).unwrap();
    for n in [3, 4] {
        let mmse = |c| cell(&r, 0, &format!("MMSE-{n}"), c).rmse;
        let floor = |c| cell(&r, 0, &format!("MMSE-floor-{n}"), c).rmse;
        let crlb = |c| cell(&r, 0, &format!("CRLB-{n}"), c).rmse;
        assert_eq!(floor("Ch1"), mmse("Ch1"));
        assert_eq!(floor("Ch2"), mmse("Ch2"));
        for c in ["Max", "Linear avg", "Ext-MCH"] {
            assert_eq!(floor(c), mmse("Ext-MCH"));
        }
        // Two channels carry twice the information: the bound shrinks by √2.
        assert!((crlb("Ch1") / crlb("Ext-MCH") - 2f64.sqrt()).abs() < 1e-12);
    }
    // Without the MMSE rows the floor is computed, and equals them (same kernel, same draws).
    let f = study::run(&small(&[4.0], &[Algo::Mle]), &|_| {}).unwrap();
    for n in [3, 4] {
        for c in COLUMNS {
            let label = format!("MMSE-floor-{n}");
            assert_eq!(
                cell(&f, 0, &label, c).rmse,
                cell(&r, 0, &label, c).rmse,
                "{label} {c}"
            );
        }
    }
}

#[test]
fn area_and_channels_flags() {
    let json = ok(&[
        "simulate",
        "--runs",
        "1",
        "--sigma",
        "2",
        "--area",
        "30x20",
        "--channels",
        "3",
        "--estimator",
        "MLE,QUAD",
        "--anchors",
        "4",
        "--search",
        "multistart",
        "--clip",
        "--no-floor",
        "--format",
        "json",
    ]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(
        v["columns"],
        serde_json::json!(["Ch1", "Ch2", "Ch3", "Max", "Linear avg", "Ext-MCH"])
    );
    assert_eq!(v["config"]["width"], 30.0);
    assert_eq!(v["config"]["height"], 20.0);
    assert_eq!(v["config"]["search"], "multistart");
    assert_eq!(v["config"]["clip"], true);
    let labels: Vec<&str> = v["tables"][0]["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["label"].as_str().unwrap())
        .collect();
    assert_eq!(labels, ["MLE-4", "QUAD-4", "CRLB-4"]);
    assert_eq!(v["config"]["floor"], false);
    // Clipped baselines stay in the area: no error beyond its diagonal.
    let quad = &v["tables"][0]["rows"][1]["cells"][0]["rmse"];
    assert!(quad.as_f64().unwrap() <= 30f64.hypot(20.0));
}

/// What a user gets by asking for the thesis' study (`hoploc simulate`, no flags) reproduces
/// the thesis' Table 3.1 where clipping decides it: TRLT-3 at σ = 4 dB on channel 1 within
/// three Monte Carlo standard errors of the thesis' 3.36 m (the thesis' own run had its noise
/// too: at most 0.1 m apart). `--no-clip` leaves trilaterations outside the room, and the cell
/// comes out far above it; `--clip` is still accepted and changes nothing.
#[test]
fn the_default_study_is_the_thesis_and_clips_the_baselines() {
    let trlt = |extra: &[&str]| {
        let mut args = vec![
            "simulate",
            "--sigma",
            "4",
            "--anchors",
            "3",
            "--estimator",
            "TRLT",
            "--no-floor",
            "--format",
            "json",
        ];
        args.extend_from_slice(extra);
        let v: serde_json::Value = serde_json::from_str(&ok(&args)).unwrap();
        let c = &v["tables"][0]["rows"][0]["cells"][0];
        assert_eq!(v["tables"][0]["rows"][0]["label"], "TRLT-3");
        (
            v["config"]["clip"].as_bool().unwrap(),
            c["rmse"].as_f64().unwrap(),
            c["rmse_se"].as_f64().unwrap(),
        )
    };
    let thesis = hoploc::report::THESIS_TRLT3_SIGMA4_CH1_M;
    let (clip, rmse, se) = trlt(&[]);
    assert!(clip);
    assert!(
        (rmse - thesis).abs() <= (3.0 * se).max(0.1),
        "{rmse:.3} ± {se:.3} m against the thesis' {thesis} m"
    );
    assert_eq!(trlt(&["--clip"]), (true, rmse, se));
    let (clip, unclipped, _) = trlt(&["--no-clip"]);
    assert!(!clip);
    assert!(unclipped > 1.5 * thesis, "{unclipped:.3} m unclipped");
    let (ok, _, err) = hoploc(&["simulate", "--clip", "--no-clip"]);
    assert!(!ok && err.contains("cannot be used with"), "{err}");
}

#[test]
fn windowed_mmse_only_on_request() {
    // The thesis study's estimators (and so the committed docs/study pages) are unchanged.
    assert_eq!(
        Config::default().algos,
        [Algo::Mle, Algo::Mmse, Algo::Mds, Algo::Trlt, Algo::Quad]
    );
    assert_eq!(Algo::parse("mmse-window"), Some(Algo::MmseWindow));
    let json = ok(&[
        "simulate",
        "--runs",
        "1",
        "--sigma",
        "1",
        "--anchors",
        "4",
        "--estimator",
        "mmse-window,MMSE",
        "--no-floor",
        "--format",
        "json",
    ]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let rows = v["tables"][0]["rows"].as_array().unwrap();
    let labels: Vec<&str> = rows.iter().map(|r| r["label"].as_str().unwrap()).collect();
    assert_eq!(labels, ["MMSE-4", "MMSE-window-4", "CRLB-4"]);
    assert_eq!(rows[1]["kind"]["estimator"], "MMSE-window");
    // At σ = 1 dB the posterior mostly fits in the thesis window: the two are close (but the
    // windowed one is not the full posterior mean).
    let cells = |r: usize| rows[r]["cells"].as_array().unwrap();
    assert_eq!(cells(1).len(), 5);
    for (c, (full, win)) in cells(0).iter().zip(cells(1)).enumerate() {
        let (full, win) = (
            full["rmse"].as_f64().unwrap(),
            win["rmse"].as_f64().unwrap(),
        );
        assert!(
            (full - win).abs() < 0.1 * full,
            "column {c}: {full} vs {win}"
        );
    }
}

#[test]
fn bad_flags_are_refused_with_a_reason() {
    for (args, want) in [
        (vec!["--channels", "9"], "channels"),
        (vec!["--runs", "0"], "runs"),
        (vec!["--sigma", "0"], "above 0 and at most 30 dB"),
        (vec!["--anchors", "5"], "anchor"),
        (vec!["--area", "ten"], "WxH"),
        (vec!["--estimator", "KNN"], "MLE, MMSE"),
    ] {
        let mut a = vec!["simulate"];
        a.extend(args);
        let (success, _, stderr) = hoploc(&a);
        assert!(!success, "{a:?} succeeded");
        assert!(stderr.contains(want), "{a:?}: {stderr}");
    }
}

#[test]
fn help_shows_examples_and_the_flags() {
    let help = ok(&["simulate", "--help"]);
    for want in [
        "Examples:",
        "    hoploc simulate --runs 20 --sigma 3 --params estimated",
        "--area",
        "--params",
        "--estimator",
        "--search",
        "--out-dir",
        "--seed",
    ] {
        assert!(help.contains(want), "missing {want:?} in:\n{help}");
    }
    assert!(ok(&["--help"]).contains("simulate"));
}
