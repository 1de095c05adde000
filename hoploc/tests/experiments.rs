//! `hoploc experiments --report`: the committed page `docs/experiments/README.md` agrees with
//! itself (each ✓/✗ is what its criterion gives on the page's own printed tables; a tampered
//! verdict is caught), and a shorter real run of the testbed still reproduces the findings the
//! page marks ✓ that the short run can judge: experiment 3 with 150 estimates per stop (19 s
//! per stop instead of 90 s, so less droop), which judges F6 and F7.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::Command;

use hoploc::experiments::{self, evaluate, parse_page, verdict};

fn page_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../docs/experiments/README.md")
}

/// Mismatches between the printed verdicts and the verdicts the page's tables give.
fn check(text: &str) -> Result<(), String> {
    let (tables, printed) = parse_page(text)?;
    let computed = evaluate(&tables);
    if printed.len() != computed.len() {
        return Err(format!(
            "{} verdicts printed, {} findings",
            printed.len(),
            computed.len()
        ));
    }
    for ((id, v), f) in printed.iter().zip(&computed) {
        if id != f.id || v != verdict(f.verdict) {
            return Err(format!(
                "{id}: printed {v}, the tables give {} {}",
                f.id,
                verdict(f.verdict)
            ));
        }
    }
    Ok(())
}

#[test]
fn the_pages_verdicts_follow_from_its_own_tables() {
    let text = std::fs::read_to_string(page_path()).expect("docs/experiments/README.md");
    check(&text).unwrap();
    let (tables, printed) = parse_page(&text).unwrap();
    // Every run of the page has its tables and its own page with plots and the CSV.
    for run in experiments::RUNS {
        let t = tables.get(run).unwrap_or_else(|| panic!("{run} missing"));
        assert!(!t.rmse.is_empty() && !t.bias.is_empty(), "{run}");
        let dir = page_path().parent().unwrap().join(run);
        for f in [
            "README.md",
            "estimates.csv",
            "rmse.png",
            "rmse.svg",
            "bias.png",
        ] {
            assert!(dir.join(f).exists(), "{}", dir.join(f).display());
        }
    }
    assert!(page_path()
        .parent()
        .unwrap()
        .join("exp3/series.png")
        .exists());
    // A flipped verdict is caught.
    let (id, v) = &printed[0];
    let flipped = if v == "✓" { "✗" } else { "✓" };
    let row = text
        .lines()
        .find(|l| l.starts_with(&format!("| {id} |")))
        .unwrap();
    let tampered = text.replacen(
        row,
        &row.replacen(&format!("| {v} |"), &format!("| {flipped} |"), 1),
        1,
    );
    assert!(
        check(&tampered).is_err(),
        "a flipped verdict went unnoticed"
    );
}

/// The verdicts of a page.
fn verdicts(text: &str) -> BTreeMap<String, String> {
    parse_page(text).unwrap().1.into_iter().collect()
}

/// The page's findings come from runs of experiments 1 and 3 (experiment 2 has none): those
/// runs again, as the page ran them (the scenario files' 150 estimates per position), must
/// reproduce every finding the page marks reproduced.
#[test]
fn the_runs_again_reproduce_what_the_page_reproduces() {
    let dir = std::env::temp_dir().join(format!("hoploc-experiments-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .args(["experiments", "--report"])
        .arg(&dir)
        .args(["--only", "exp1-3a,exp1-4a,exp1-chip-3a,exp1-chip-4a,exp3"])
        .output()
        .expect("run hoploc");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let again = std::fs::read_to_string(dir.join("README.md")).unwrap();
    check(&again).unwrap();
    let committed = verdicts(&std::fs::read_to_string(page_path()).unwrap());
    let now = verdicts(&again);
    // Every finding is judged (none needs a run left out).
    let judged: Vec<(&String, &String)> = now.iter().filter(|(_, v)| *v != "–").collect();
    assert_eq!(judged.len(), committed.len(), "{again}");
    for (id, v) in judged {
        if committed.get(id).map(String::as_str) == Some("✓") {
            assert_eq!(
                v, "✓",
                "{id} is reproduced on the page but not by the runs again:\n{again}"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
