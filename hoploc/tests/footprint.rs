//! `hoploc footprint` on the real firmware ELFs (built by `cargo fw`, which ./test.sh runs
//! first): every firmware is measured, its scenarios ran as documented, and the verdict and the
//! exit status follow the figures. Whether a firmware is within its budget is the command's
//! verdict (a benchmark that prints its figures), which `.ci/run` turns into a failed build.

use std::process::Command;

use hoploc::firmware::{self, Role};
use hoploc::footprint::{self, Footprint, FLASH_BUDGET, SRAM_BUDGET};

#[test]
fn every_firmware_is_measured() {
    let dir = firmware::default_dir();
    firmware::ensure_built(&dir).unwrap();
    let rows = footprint::measure_all(&dir).unwrap();
    assert_eq!(rows.len(), 3);
    for r in &rows {
        let name = firmware::crate_name(r.role);
        // The factory-radio run really brought the radio up through command mode.
        assert_eq!(
            r.factory_lines,
            [
                format!("hoploc {} boot", r.role.name()),
                format!("hoploc {} config eeprom id 1", r.role.name()),
                format!("hoploc {} radio ok 9600", r.role.name())
            ],
            "{name}"
        );
        // Plausible figures: a firmware with the driver is several KB; the stack was used.
        assert!(r.flash > 4096 && r.flash <= 32 * 1024, "{name}: {r:?}");
        assert!(
            r.static_sram > 0 && r.stack_factory > 64 && r.stack_silent > 64,
            "{r:?}"
        );
        assert!(r.sram() < 2048, "{name}: {r:?}");
    }
}

#[test]
fn the_command_prints_the_table_and_the_verdict_follows_the_figures() {
    let out = Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .arg("footprint")
        .output()
        .expect("run hoploc");
    let stdout = String::from_utf8_lossy(&out.stdout);
    // One row per firmware, its verdict from its own figures; the exit status says whether all
    // are within budget.
    let rows = footprint::measure_all(&firmware::default_dir()).unwrap();
    for r in &rows {
        let fw = firmware::crate_name(r.role);
        let verdict = if r.within_budget() {
            "| yes |"
        } else {
            "| **NO** |"
        };
        assert!(
            stdout
                .lines()
                .any(|l| l.starts_with(&format!("| {fw} |")) && l.ends_with(verdict)),
            "{fw}: {stdout}"
        );
    }
    assert_eq!(
        out.status.success(),
        rows.iter().all(Footprint::within_budget),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The verdict follows the figures.
    let over = Footprint {
        role: Role::Sink,
        flash: FLASH_BUDGET + 1,
        static_sram: 100,
        stack_factory: 300,
        stack_silent: 200,
        factory_lines: vec![],
    };
    assert!(!over.within_budget());
    assert_eq!(over.sram(), 400);
    let sram_over = Footprint {
        flash: 1000,
        stack_silent: SRAM_BUDGET,
        ..over.clone()
    };
    assert!(!sram_over.within_budget());
    let table = footprint::table(&[over, sram_over]);
    assert_eq!(table.matches("| **NO** |").count(), 2, "{table}");
}

#[test]
fn help_has_an_example() {
    let out = Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .args(["footprint", "--help"])
        .output()
        .expect("run hoploc");
    assert!(String::from_utf8_lossy(&out.stdout).contains("    hoploc footprint"));
}
