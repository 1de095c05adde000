//! `hoploc demo` end to end: the real firmware ELFs (built by `cargo fw`, which ./test.sh runs
//! first) boot in simavr and the demo reports every node.

use std::process::Command;

#[test]
fn demo_boots_every_node_in_simavr() {
    let out = Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .args(["demo", "--seconds", "0.3"])
        .output()
        .expect("run hoploc");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "hoploc demo failed:\n{stdout}\n{stderr}"
    );
    for role in ["anchor", "agent", "sink"] {
        assert!(
            stdout.contains(&format!("uart \"hoploc {role} boot\"")),
            "no boot line from {role}:\n{stdout}"
        );
    }
    assert!(stdout.contains("radios after 0.3 s:"), "{stdout}");
}

#[test]
fn every_command_has_help_with_an_example() {
    let out = Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .args(["demo", "--help"])
        .output()
        .expect("run hoploc");
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(help.contains("hoploc demo --seconds"), "{help}");
}
