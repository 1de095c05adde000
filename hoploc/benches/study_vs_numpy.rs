//! The host study's speed (`docs/design.md`, section 9: at least 20× faster): the full thesis
//! study of `hoploc simulate` against the straightforward vectorised numpy implementation of the
//! same study (`bench/numpy_study.py`), in one run.
//!
//! `cargo bench -p hoploc --bench study_vs_numpy` runs both with the thesis settings (known
//! parameters, every estimator, σ = 2 and 4 dB, 100 runs per point, seed 1), prints their times
//! and the speed-up, then compares every RMSE cell numpy computes with the Rust table: the two use
//! different random numbers, so each cell must agree within Monte Carlo noise,
//! `|Δ| ≤ 4·√2·SE` (SE: the Rust cell's standard error of the mean per-point RMSE; numpy's is the
//! same size, so the difference of the two has standard deviation √2·SE). It prints the largest
//! deviation (absolute, relative and in standard errors) and exits non-zero if a cell is off or
//! numpy cannot run. The Rust time covers the whole table set (estimators, CRLB, MMSE floor) on
//! every core; its one-thread time is printed too.

use std::path::PathBuf;
use std::process::{Command, ExitCode};
use std::time::Instant;

use hoploc::study::{self, Config, StudyResult};

/// A Python that imports numpy: `$HOPLOC_NUMPY_PYTHON`, else the first of `python3`,
/// `/usr/bin/python3`, `python` that does (a pyenv `python3` without numpy may shadow Debian's).
fn numpy_python() -> Result<String, String> {
    let candidates: Vec<String> = std::env::var("HOPLOC_NUMPY_PYTHON")
        .into_iter()
        .chain(["python3", "/usr/bin/python3", "python"].map(String::from))
        .collect();
    for py in &candidates {
        let ok = Command::new(py)
            .args(["-c", "import numpy"])
            .output()
            .is_ok_and(|o| o.status.success());
        if ok {
            return Ok(py.clone());
        }
    }
    Err(format!(
        "no Python with numpy among {candidates:?}: install it (Debian: apt-get install \
         python3-numpy; scripts/setup.sh does) or point HOPLOC_NUMPY_PYTHON at one"
    ))
}

struct NumpyCell {
    sigma: f64,
    row: String,
    column: String,
    rmse: f64,
}

fn run_numpy(root: &std::path::Path, cfg: &Config) -> Result<(f64, f64, Vec<NumpyCell>), String> {
    let py = numpy_python()?;
    let out = std::env::temp_dir().join(format!("hoploc-numpy-study-{}.json", std::process::id()));
    let mut cmd = Command::new(&py);
    cmd.arg(root.join("bench/numpy_study.py"))
        .args([
            "--runs",
            &cfg.runs.to_string(),
            "--seed",
            &cfg.seed.to_string(),
        ])
        .arg("--sigma")
        .args(cfg.sigmas.iter().map(|s| s.to_string()))
        // The same lattice as loc-core's.
        .args([
            "--coarse-divs",
            &loc_core::grid::COARSE_DIVS.to_string(),
            "--fine-divs",
            &loc_core::grid::FINE_DIVS.to_string(),
        ])
        .arg("--json")
        .arg(&out);
    let t0 = Instant::now();
    let o = cmd.output().map_err(|e| format!("{py}: {e}"))?;
    let wall = t0.elapsed().as_secs_f64();
    if !o.status.success() {
        return Err(format!(
            "numpy study failed:\n{}\n{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        ));
    }
    let text = std::fs::read_to_string(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let _ = std::fs::remove_file(&out);
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    let secs = v["seconds"].as_f64().ok_or("numpy JSON: no seconds")?;
    let mut cells = Vec::new();
    for (sigma, rows) in v["tables"].as_object().ok_or("numpy JSON: no tables")? {
        for c in rows.as_array().ok_or("numpy JSON: bad table")? {
            cells.push(NumpyCell {
                sigma: sigma.parse().map_err(|_| "numpy JSON: bad σ")?,
                row: c["row"].as_str().ok_or("numpy JSON: row")?.into(),
                column: c["column"].as_str().ok_or("numpy JSON: column")?.into(),
                rmse: c["rmse"].as_f64().ok_or("numpy JSON: rmse")?,
            });
        }
    }
    Ok((secs, wall, cells))
}

fn timed(cfg: &Config) -> Result<(f64, StudyResult), String> {
    let t0 = Instant::now();
    let r = study::run(cfg, &|_| {})?;
    Ok((t0.elapsed().as_secs_f64(), r))
}

fn main() -> ExitCode {
    match bench() {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("study_vs_numpy: {e}");
            ExitCode::FAILURE
        }
    }
}

fn bench() -> Result<bool, String> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(PathBuf::from)
        .ok_or("no workspace root")?;
    // The numpy study leaves the baselines unclipped, so the Rust one does here too.
    let cfg = Config {
        clip: false,
        ..Config::default()
    };
    println!(
        "study: {} × {} m, anchors {:?}, 361 points × {} runs, σ = {:?} dB, {} channels, unclipped baselines, known \
         parameters, estimators {:?}, seed {}",
        cfg.area.width,
        cfg.area.height,
        cfg.anchor_counts,
        cfg.runs,
        cfg.sigmas,
        cfg.channels,
        cfg.algos,
        cfg.seed
    );
    println!("posterior kernel: {:?}", study::Kernel::detect());

    let (rust_s, rust) = timed(&cfg)?;
    println!("rust  ({} threads): {rust_s:8.3} s", cfg.threads);
    let (rust1_s, rust1) = timed(&Config {
        threads: 1,
        ..cfg.clone()
    })?;
    println!("rust  (1 thread):  {rust1_s:8.3} s");
    let identical = rust1 == rust;
    println!(
        "1 thread and {} threads give identical tables: {identical}",
        cfg.threads
    );

    let (numpy_s, numpy_wall, numpy) = run_numpy(&root, &cfg)?;
    println!("numpy (bench/numpy_study.py): {numpy_s:8.3} s (process {numpy_wall:.3} s)");
    let speedup = numpy_s / rust_s;
    println!(
        "speed-up: {speedup:.1}× ({} threads), {:.1}× (1 thread); the target is ≥ 20×: {}",
        cfg.threads,
        numpy_s / rust1_s,
        if speedup >= 20.0 { "met" } else { "NOT met" }
    );

    // Cell by cell.
    let mut compared = 0;
    let mut off = Vec::new();
    let (mut max_abs, mut max_rel, mut max_z) = (0.0f64, 0.0f64, 0.0f64);
    let mut worst = String::new();
    for c in &numpy {
        let table = rust
            .tables
            .iter()
            .find(|t| t.sigma == c.sigma)
            .ok_or_else(|| format!("no Rust table for σ = {}", c.sigma))?;
        let ci = rust
            .columns
            .iter()
            .position(|x| *x == c.column)
            .ok_or_else(|| format!("no Rust column {}", c.column))?;
        let cell = table
            .rows
            .iter()
            .find(|r| r.label == c.row)
            .and_then(|r| r.cells[ci].as_ref())
            .ok_or_else(|| format!("no Rust cell {} {} σ = {}", c.row, c.column, c.sigma))?;
        let se = cell
            .rmse_se
            .ok_or("estimator cell without a standard error")?;
        let d = (cell.rmse - c.rmse).abs();
        let z = d / (2f64.sqrt() * se);
        compared += 1;
        if d > max_abs {
            max_abs = d;
            worst = format!(
                "σ = {} {} {}: rust {:.4} numpy {:.4}",
                c.sigma, c.row, c.column, cell.rmse, c.rmse
            );
        }
        max_rel = max_rel.max(d / c.rmse);
        max_z = max_z.max(z);
        if z > 4.0 {
            off.push(format!(
                "σ = {} {} {}: rust {:.4} ± {:.4}, numpy {:.4} ({z:.1} SE)",
                c.sigma, c.row, c.column, cell.rmse, se, c.rmse
            ));
        }
    }
    println!(
        "tables: {compared} RMSE cells compared; max |Δ| = {max_abs:.4} m ({worst}); \
         max relative {:.2} %; max {max_z:.2} standard errors (limit 4)",
        100.0 * max_rel
    );
    for o in &off {
        println!("  OFF: {o}");
    }
    let pass = off.is_empty() && compared > 0 && identical;
    println!(
        "verdict: tables {}",
        if pass { "agree" } else { "DISAGREE" }
    );
    Ok(pass)
}
