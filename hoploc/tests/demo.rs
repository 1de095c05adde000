//! `hoploc demo` end to end: the real firmware ELFs (built by `cargo fw`, which ./test.sh runs
//! first) boot in simavr, each on a factory-fresh modelled XBee, and configure it.

use std::process::Command;

#[test]
fn demo_brings_every_radio_up_in_simavr() {
    let out = Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .args(["demo", "--seconds", "8.5"])
        .output()
        .expect("run hoploc");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "hoploc demo failed:\n{stdout}\n{stderr}"
    );
    let events = |role: &str| -> Vec<String> {
        stdout
            .lines()
            .filter_map(|l| {
                let mut w = l.split_whitespace();
                let _time = w.next()?;
                (w.next()? == role).then(|| w.collect::<Vec<_>>().join(" "))
            })
            .collect()
    };
    for (role, my, ch) in [
        ("anchor", "0001", "0B"),
        ("agent", "0101", "0B"),
        ("sink", "0201", "0D"),
    ] {
        let ev = events(role);
        let pos = |what: &str| {
            ev.iter()
                .position(|e| e == what)
                .unwrap_or_else(|| panic!("{role}: no \"{what}\" in {ev:#?}"))
        };
        // In order: boot, the config (simavr loads the ELF's `.eeprom` section: the built-in
        // config), command mode, then the API settings, then the radio line.
        let order = [
            pos("boot"),
            pos("config from EEPROM: node 1"),
            pos("sends \"ATAP2\""),
            pos("sends \"ATCN\""),
            pos("API AT AP?"),
            pos(&format!("API AT MY={my}")),
            pos("API AT ID=3332"),
            pos(&format!("API AT CH={ch}")),
            pos("API AT CH?"),
            pos("radio up: found in command mode at 9600 baud, now API mode 2 at 57600 (saved)"),
        ];
        assert!(order.windows(2).all(|w| w[0] < w[1]), "{role}: {ev:#?}");
        // The radio ends configured: AP=2 at 57600 with the node's MY, the PAN id and channel.
        let row = stdout
            .lines()
            .find(|l| l.starts_with(role) && l.contains("57600"))
            .unwrap_or_else(|| panic!("no register row for {role}:\n{stdout}"));
        let cols: Vec<&str> = row.split_whitespace().collect();
        assert_eq!(cols[1..6], ["2", "57600", my, "3332", ch], "{row}");
    }
}

#[test]
fn every_command_has_help_with_an_example() {
    let out = Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .args(["demo", "--help"])
        .output()
        .expect("run hoploc");
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(help.contains("hoploc demo --seconds 10"), "{help}");
}
