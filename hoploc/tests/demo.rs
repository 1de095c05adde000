//! `hoploc demo` end to end: the real firmware ELFs (built by `cargo fw`, which ./test.sh runs
//! first) in simavr. `--boot`: each boots on a factory-fresh modelled XBee and configures it.
//! A scenario: the anchors and agent run it, the host sink's fixes become a table and plots.

use std::process::Command;

#[test]
fn demo_brings_every_radio_up_in_simavr() {
    let out = Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .args(["demo", "--boot", "--seconds", "8.5"])
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
            // The factory behaviour back, whatever the radio came with: the last fixed setting.
            pos("API AT PL=04"),
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
    assert!(help.contains("hoploc demo --boot --seconds 10"), "{help}");
    assert!(help.contains("hoploc demo exp3 --seed 7"), "{help}");
    assert!(help.contains("host sink"), "{help}");
    // Every command: its help has an example, an indented line that runs it.
    let commands: Vec<String> = <hoploc::cli::Cli as clap::CommandFactory>::command()
        .get_subcommands()
        .map(|c| c.get_name().to_string())
        .filter(|name| name != "help")
        .collect();
    assert!(
        commands.len() >= 8 && commands.iter().any(|c| c == "radio"),
        "{commands:?}"
    );
    for name in commands {
        let out = Command::new(env!("CARGO_BIN_EXE_hoploc"))
            .args([name.as_str(), "--help"])
            .output()
            .expect("run hoploc");
        let help = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{name}: {help}");
        let example = format!("    hoploc {name}");
        assert!(
            help.lines().any(|l| l.starts_with(&example)),
            "{name}: no example in its help:\n{help}"
        );
    }
}

#[test]
fn a_scenario_run_prints_its_table_and_writes_plots() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("demo-room10");
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .args([
            "demo",
            "room10",
            "--seconds",
            "14",
            "--seed",
            "5",
            "--out-dir",
        ])
        .arg(&dir)
        .output()
        .expect("run hoploc");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "hoploc demo failed:\n{stdout}\n{stderr}"
    );
    // The header names the sink (the firmware, by default), and the seed given.
    assert!(stdout.contains("sink: sink firmware"), "{stdout}");
    assert!(stdout.contains("seed 5"), "{stdout}");
    // The table: a row per stop reached (8 s warm-up + 6 s at stop 1) and estimator, then all.
    let row = |stop: &str, est: &str| {
        stdout
            .lines()
            .find(|l| {
                let w: Vec<&str> = l.split_whitespace().collect();
                w.first() == Some(&stop) && w.contains(&est)
            })
            .unwrap_or_else(|| panic!("no {stop} {est} row:\n{stdout}"))
            .to_string()
    };
    // The host's references are named as not coming from the sink.
    for est in ["MLE-fixed", "MLE-P0only"] {
        assert!(
            stdout.contains(&format!("{est}: the host's reference, not a sink line")),
            "{stdout}"
        );
    }
    for est in ["MLE", "MMSE", "MLE-fixed", "MLE-P0only"] {
        for stop in ["1", "all"] {
            let r = row(stop, est);
            let w: Vec<&str> = r.split_whitespace().collect();
            let i = w.iter().position(|x| *x == est).unwrap();
            let fixes: usize = w[i + 1].parse().unwrap();
            let rmse: f64 = w[i + 2].parse().unwrap();
            // 6 s at 5.1 fixes/s, less the superframe after the warm-up.
            assert!((25..=30).contains(&fixes), "{r}");
            assert!(rmse.is_finite() && rmse < 5.0, "{r}");
        }
    }
    assert!(stdout.contains("fixes/s"), "{stdout}");
    // The sink firmware's own counters, from its last status line.
    assert!(
        stdout.contains("sink firmware's last status line") && stdout.contains("0 missing"),
        "{stdout}"
    );
    assert!(stdout.contains("× real time"), "{stdout}");
    for f in [
        "fixes.svg",
        "fixes.png",
        "error.svg",
        "error.png",
        "fixes.csv",
        "table.txt",
        "sink.log",
    ] {
        let p = dir.join(f);
        let bytes = std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert!(bytes.len() > 100, "{f}: {} bytes", bytes.len());
        match f.rsplit('.').next() {
            Some("png") => assert_eq!(&bytes[1..4], b"PNG", "{f}"),
            Some("svg") => assert!(String::from_utf8_lossy(&bytes).contains("<svg"), "{f}"),
            _ => {}
        }
    }
    // The sink's log holds its lines as the firmware would write them (a report line, then
    // the report's fix lines), and `# truth` lines where the agent moved: it replays.
    let log = std::fs::read_to_string(dir.join("sink.log")).unwrap();
    assert!(log.lines().count() >= 3 * 30);
    let mut kinds = [0usize; 3];
    for l in log.lines() {
        if l.starts_with("# truth ") {
            kinds[0] += 1;
            continue;
        }
        match loc_proto::sink_line::SinkOutput::parse(l) {
            Ok(loc_proto::sink_line::SinkOutput::Report(_)) => kinds[1] += 1,
            Ok(_) => kinds[2] += 1,
            Err(e) => panic!("{l}: {e:?}"),
        }
    }
    assert!(
        kinds[0] >= 1 && kinds[2] >= 2 * kinds[1] && kinds[1] >= 30,
        "{kinds:?}"
    );
    let replay = Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .arg("replay")
        .arg(dir.join("sink.log"))
        .output()
        .expect("run hoploc replay");
    let text = String::from_utf8_lossy(&replay.stdout);
    assert!(replay.status.success(), "{text}");
    assert!(
        text.contains(&format!("{} reports (0 unreadable)", kinds[1])),
        "{text}"
    );
    assert!(text.contains("sink MLE") && text.contains("MDS"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// With `--sink host` the demo runs the sink's logic on the host and says so.
#[test]
fn the_host_sink_is_named_as_such() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("demo-host-sink");
    let out = Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .args([
            "demo",
            "room10",
            "--sink",
            "host",
            "--seconds",
            "10",
            "--out-dir",
        ])
        .arg(&dir)
        .output()
        .expect("run hoploc");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    assert!(stdout.contains("sink: host sink"), "{stdout}");
    assert!(stdout.contains("not the sink firmware"), "{stdout}");
    let _ = std::fs::remove_dir_all(&dir);
}
