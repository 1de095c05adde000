//! The command line against a new user and a hostile tester: numbers that cannot work are
//! refused with their range, `monitor` keeps its deadline whatever its input does and finds a
//! good line again after noise, a closed output pipe ends a command quietly, bad firmware files
//! are named with their problem, the binary finds scenarios and firmware from where it runs, and
//! an interrupted demo keeps what it saw.
//!
//! The tests that run firmware use the ELFs of `cargo fw` (./test.sh builds them first).

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use clap::Parser;
use hoploc::cli::{Cli, Command as Cmd};
use hoploc::firmware::{self, Role};
use hoploc::framing::Framer;
use hoploc::monitor::Monitor;
use hoploc::replay::Replay;
use loc_proto::sink_line::{Estimator, SinkLine};
use proptest::prelude::*;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_hoploc")
}

/// A fresh temporary directory, removed with everything in it when dropped (a test's copies
/// of the binary are large).
struct TempDir(PathBuf);

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn tmp(name: &str) -> TempDir {
    let d = std::env::temp_dir().join(format!("hoploc-robust-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    TempDir(d)
}

fn fix_line(seq: u16) -> String {
    let mut s = String::new();
    let Ok(()) = SinkLine::Fix {
        agent: 1,
        seq,
        estimator: Estimator::Mle,
        x: 350,
        y: 200,
        alpha_x100: 300,
        p0_x100: -4000,
        anchors: 4,
        flags: 1,
    }
    .write(&mut s);
    s
}

// ------------------------------------------------------------------------------------------
// 1. Numbers on the command line.

/// A number as a user or a fuzzer might type it.
fn number_text() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("nan".to_string()),
        Just("NaN".to_string()),
        Just("inf".to_string()),
        Just("-inf".to_string()),
        Just("infinity".to_string()),
        Just("1e308".to_string()),
        Just("1e309".to_string()),
        Just("-0".to_string()),
        Just("0".to_string()),
        Just("".to_string()),
        Just("18446744073709551616".to_string()),
        Just("0x10".to_string()),
        any::<f64>().prop_map(|v| v.to_string()),
        any::<i64>().prop_map(|v| v.to_string()),
        (-1e6f64..1e6).prop_map(|v| format!("{v}")),
        (0u32..100).prop_map(|v| v.to_string()),
        (0.0f64..2.0).prop_map(|v| format!("{v:.4}")),
        "[ -~]{0,12}",
    ]
}

/// A command line with `value` as the value of one of the numeric options.
fn command_line() -> impl Strategy<Value = (Vec<String>, String)> {
    let options: Vec<(&str, &str)> = vec![
        ("demo", "--seconds"),
        ("demo", "--live-every"),
        ("demo", "--threads"),
        ("demo", "--uart-errors"),
        ("demo", "--seed"),
        ("demo", "--speed"),
        ("demo", "--web-port"),
        ("demo", "--web-bind"),
        ("experiments", "--estimates"),
        ("experiments", "--threads"),
        ("monitor", "--seconds"),
        ("monitor", "--baud"),
        ("monitor", "--truth"),
        ("monitor", "--area"),
        ("monitor", "--web-port"),
        ("monitor", "--web-bind"),
        ("replay", "--truth"),
        ("replay", "--area"),
        ("replay", "--web-port"),
        ("simulate", "--area"),
        ("simulate", "--anchors"),
        ("simulate", "--runs"),
        ("simulate", "--sigma"),
        ("simulate", "--channels"),
        ("simulate", "--alpha"),
        ("simulate", "--p0"),
        ("simulate", "--threads"),
        ("simulate", "--seed"),
        ("provision", "--id"),
        ("provision", "--x"),
        ("provision", "--anchors"),
        ("provision", "--slot-ms"),
        ("provision", "--sink-channel"),
        ("provision", "--pan"),
        ("provision", "--channels"),
        ("radio", "--id"),
        ("radio", "--anchors"),
        ("radio", "--sink-channel"),
        ("radio", "--pan"),
        ("radio", "--channels"),
    ];
    (
        proptest::sample::select(options),
        number_text(),
        number_text(),
    )
        .prop_map(|((cmd, flag), a, b)| {
            // Points and areas take two numbers.
            let value = match flag {
                "--truth" => format!("{a},{b}"),
                "--area" if cmd != "simulate" => format!("{a}x{b}"),
                _ => a,
            };
            let mut line = vec!["hoploc".to_string(), cmd.to_string()];
            if cmd == "replay" {
                line.push("log".into());
            }
            if cmd == "experiments" {
                line.extend(["--report", "dir"].map(String::from));
            }
            if cmd == "provision" || cmd == "radio" {
                line.extend(["--port", "/dev/null", "--role", "anchor"].map(String::from));
                if flag != "--id" {
                    line.extend(["--id", "1"].map(String::from));
                }
            }
            if flag.starts_with("--web-") {
                line.push("--web".into());
            }
            line.push(format!("{flag}={value}"));
            (line, value)
        })
}

fn in_range(v: f64, lo: f64, hi: f64) -> bool {
    v.is_finite() && lo <= v && v <= hi
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    /// Whatever number is given, parsing never panics, and what is accepted is finite and
    /// within the documented range (a refusal is clap's error, exit code 2).
    #[test]
    fn every_number_is_checked((line, value) in command_line()) {
        let parsed = Cli::try_parse_from(&line);
        let Ok(cli) = parsed else {
            let e = parsed.unwrap_err();
            prop_assert!(e.exit_code() == 2, "{line:?}: {e}");
            return Ok(());
        };
        match cli.command {
            Cmd::Demo(a) => {
                prop_assert!(a.seconds.is_none_or(|s| in_range(s, 0.001, 365.0 * 86_400.0)), "{value}");
                prop_assert!(in_range(a.live_every, 0.0, 86_400.0), "{value}");
                prop_assert!((1..=256).contains(&a.threads), "{value}");
                prop_assert!(in_range(a.uart_errors, 0.0, 1.0), "{value}");
                prop_assert!(a.speed.is_none_or(|s| in_range(s, 0.0, 1000.0)), "{value}");
            }
            Cmd::Experiments(a) => {
                prop_assert!((1..=256).contains(&a.threads), "{value}");
                prop_assert!(a.estimates.is_none_or(|n| (1..=100_000).contains(&n)), "{value}");
            }
            Cmd::Monitor(a) => {
                prop_assert!(a.seconds.is_none_or(|s| in_range(s, 0.001, 365.0 * 86_400.0)), "{value}");
                prop_assert!((300..=4_000_000).contains(&a.baud), "{value}");
                if let Some(t) = a.truth {
                    prop_assert!(in_range(t.x, -1e4, 1e4) && in_range(t.y, -1e4, 1e4), "{value}");
                }
                if let Some(r) = a.area {
                    prop_assert!(r.width > 0.0 && in_range(r.width, 0.0, 1e4), "{value}");
                    prop_assert!(r.height > 0.0 && in_range(r.height, 0.0, 1e4), "{value}");
                }
            }
            Cmd::Replay(a) => {
                if let Some(t) = a.truth {
                    prop_assert!(in_range(t.x, -1e4, 1e4) && in_range(t.y, -1e4, 1e4), "{value}");
                }
                if let Some(r) = a.area {
                    prop_assert!(r.width > 0.0 && r.width <= 1e4 && r.height > 0.0 && r.height <= 1e4, "{value}");
                }
            }
            Cmd::Simulate(a) => {
                // Everything the study checks holds for whatever the parsers accept.
                prop_assert_eq!(a.config().validate(), Ok(()), "{}", value);
                prop_assert!(a.area.width <= 1e4 && a.area.height <= 1e4, "{value}");
                prop_assert!((1..=1_000_000).contains(&a.runs), "{value}");
                prop_assert!(a.sigma.iter().all(|&s| in_range(s, 0.0, 30.0) && s > 0.0), "{value}");
                prop_assert!(in_range(a.p0, -150.0, 30.0), "{value}");
                prop_assert!(a.alpha > 0.0 && a.alpha <= 10.0, "{value}");
                prop_assert!(a.threads.is_none_or(|t| (1..=256).contains(&t)), "{value}");
            }
            Cmd::Provision(a) => {
                prop_assert!(a.id >= 1, "{value}");
                prop_assert!((3..=8).contains(&a.node.anchors), "{value}");
                prop_assert!((2..=10_000).contains(&a.node.slot_ms), "{value}");
                prop_assert!((1..=16).contains(&a.node.sink_channel), "{value}");
                prop_assert!(a.node.pan != 0xFFFF, "{value}");
            }
            Cmd::Radio(a) => {
                prop_assert!(a.id.is_some_and(|id| id >= 1), "{value}");
                prop_assert!((3..=8).contains(&a.node.anchors), "{value}");
                prop_assert!((1..=16).contains(&a.node.sink_channel), "{value}");
                prop_assert!(a.node.pan != 0xFFFF, "{value}");
            }
            Cmd::Footprint { .. } => {}
        }
    }

    /// Any bytes through the framer into the monitor and the replay: no panic, every line
    /// counted once.
    #[test]
    fn any_input_is_counted_never_a_panic(
        chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..300), 0..20),
    ) {
        let mut framer = Framer::new();
        let mut mon = Monitor::new(None);
        let mut replay = Replay::new(None, None);
        let mut framed = Vec::new();
        for c in &chunks {
            framer.push(c, |f| framed.push(f));
        }
        framed.extend(framer.finish());
        for f in &framed {
            let _ = mon.feed_framed(f);
            replay.feed_framed(f);
        }
        let c = mon.counts;
        let seen = c.fixes + c.nofixes + c.reports + c.status + c.damaged + c.too_long + c.other;
        prop_assert_eq!(seen, framed.len());
        let _ = mon.summary();
        let _ = replay.summary();
    }
}

/// The binary refuses values that cannot work: exit code non-zero, the range in the message.
#[test]
fn the_binary_refuses_values_that_cannot_work() {
    for (args, want) in [
        (&["monitor", "--seconds", "NaN"][..], "0.001…31536000 s"),
        (&["monitor", "--seconds", "1e300"], "0.001…31536000 s"),
        (&["monitor", "--seconds=-1"], "0.001…31536000 s"),
        (&["demo", "--uart-errors", "1.5"], "0…1"),
        (&["demo", "--seconds", "inf"], "0.001…31536000 s"),
        (&["demo", "--live-every", "nan"], "0…86400 s"),
        (&["demo", "--threads", "0"], "1…256"),
        (&["simulate", "--alpha", "inf"], "above 0 and at most 10"),
        (&["simulate", "--p0", "nan"], "-150…30 dBm"),
        (&["replay", "-", "--truth", "nan,1"], "-10000…10000 m"),
        (
            &["provision", "--port", "x", "--role", "anchor", "--id", "0"],
            "1..=255",
        ),
        (
            &[
                "provision",
                "--port",
                "x",
                "--role",
                "anchor",
                "--id",
                "1",
                "--anchors",
                "9",
            ],
            "3..=8",
        ),
    ] {
        let out = Command::new(bin())
            .args(args)
            .stdin(Stdio::null())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(want), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

// ------------------------------------------------------------------------------------------
// 2. `monitor`'s deadline and its lines.

/// Runs `hoploc monitor --seconds 1` with its stdin fed by `feed` (on a thread, which may go
/// on writing for ever), and returns how long it took and what it printed.
fn monitor_with(
    feed: impl FnOnce(std::process::ChildStdin) + Send + 'static,
) -> (Duration, String) {
    let t0 = Instant::now();
    let mut child = Command::new(bin())
        .args(["monitor", "--seconds", "1"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stdin = child.stdin.take().unwrap();
    std::thread::spawn(move || feed(stdin));
    // Read what it prints as it goes (a pipe nobody reads would block its writes).
    let mut stdout = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stdout.read_to_string(&mut text);
        text
    });
    // Bounded wait: a monitor that ignores its deadline is killed, and the test fails.
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t0.elapsed() > Duration::from_secs(20) {
            child.kill().unwrap();
            panic!("monitor --seconds 1 still running after 20 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let took = t0.elapsed();
    let stdout = reader.join().unwrap();
    assert!(status.success(), "{stdout}");
    (took, stdout)
}

#[test]
fn monitor_keeps_its_deadline_on_a_silent_input() {
    let (took, out) = monitor_with(|stdin| {
        // Open and silent for longer than the deadline.
        std::thread::sleep(Duration::from_secs(30));
        drop(stdin);
    });
    assert!(took < Duration::from_secs(4), "{took:?}");
    assert!(out.contains("0 fix lines"), "{out}");
}

#[test]
fn monitor_keeps_its_deadline_on_bytes_without_a_newline() {
    let (took, out) = monitor_with(|mut stdin| {
        let junk = [b'x'; 4096];
        while stdin.write_all(&junk).is_ok() {}
    });
    assert!(took < Duration::from_secs(4), "{took:?}");
    // The flood is one line too long, dropped and counted.
    assert!(out.contains("1 too long"), "{out}");
}

#[test]
fn monitor_keeps_its_deadline_in_a_flood_of_lines() {
    let (took, out) = monitor_with(|mut stdin| {
        let line = fix_line(1);
        let block = line.repeat(100);
        while stdin.write_all(block.as_bytes()).is_ok() {}
    });
    assert!(took < Duration::from_secs(4), "{took:?}");
    assert!(out.contains("fix lines"), "{out}");
}

#[test]
fn monitor_finds_good_lines_after_noise_and_counts_damage_as_damage() {
    let good: Vec<String> = (0..6).map(fix_line).collect();
    let mut damaged = good[3].clone().into_bytes();
    damaged[1] ^= 0x20; // `hOploc sink …`: its start damaged
    let mut input = Vec::new();
    input.extend_from_slice(b"\x00\xff\x13noise");
    input.extend_from_slice(good[0].as_bytes()); // glued to the noise
    input.extend_from_slice(&vec![b'#'; 2000]); // a line too long...
    input.extend_from_slice(good[1].as_bytes()); // ...and the good line right after it
    input.extend_from_slice(b"hoploc sink fix 1 2 ml"); // cut short: its end lost
    input.extend_from_slice(good[2].as_bytes());
    input.extend_from_slice(&damaged);
    input.extend_from_slice(b"OK\r\n+++\r\n"); // another device's text
    input.extend_from_slice(good[4].as_bytes());
    let mut v = good[5].clone().into_bytes();
    v[30] |= 0x80; // not text any more
    input.extend_from_slice(&v);
    let mut child = Command::new(bin())
        .args(["monitor"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(&input).unwrap();
    let out = child.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains(
            "4 fix lines, 0 nofix, 0 report lines, 0 status, 3 damaged sink lines, 1 too long, \
             3 other lines"
        ),
        "{text}"
    );
}

// ------------------------------------------------------------------------------------------
// 3. A closed output pipe.

/// Runs hoploc with `args`, its stdin from `stdin_file` (or nothing), its stdout a pipe whose
/// reader is closed at once: the command must end quietly (exit 0, no panic message).
fn with_closed_stdout(args: &[&str], stdin_file: Option<&Path>) {
    let mut cmd = Command::new(bin());
    cmd.args(args).stdout(Stdio::piped()).stderr(Stdio::piped());
    match stdin_file {
        Some(f) => cmd.stdin(std::fs::File::open(f).unwrap()),
        None => cmd.stdin(Stdio::null()),
    };
    let mut child = cmd.spawn().unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    assert_eq!(out.status.code(), Some(0), "{args:?}: {stderr}");
}

/// A sink log of `n` fix lines.
fn log_file(dir: &Path, n: u16) -> PathBuf {
    let p = dir.join("sink.log");
    let text: String = (0..n).map(fix_line).collect();
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_closed_output_pipe_ends_replay_monitor_simulate_and_demo_quietly() {
    let dir = tmp("pipe");
    let log = log_file(&dir, 20_000);
    let log_s = log.to_str().unwrap();
    with_closed_stdout(&["replay", log_s], None);
    with_closed_stdout(&["replay", "-"], Some(&log));
    with_closed_stdout(&["monitor"], Some(&log));
    with_closed_stdout(
        &[
            "simulate",
            "--runs",
            "1",
            "--sigma",
            "2",
            "--estimator",
            "MLE",
            "--no-floor",
        ],
        None,
    );
    with_closed_stdout(&["demo", "--boot", "--seconds", "3"], None);
}

// ------------------------------------------------------------------------------------------
// 6. Firmware files.

#[test]
fn bad_firmware_files_are_named_with_their_problem() {
    let fw = firmware::default_dir();
    let sink = std::fs::read(firmware::elf(&fw, Role::Sink)).expect("cargo fw first");
    let dir = tmp("elf");
    let cases: [(&str, Vec<u8>, &str); 4] = [
        ("truncated", sink[..sink.len() / 3].to_vec(), "truncated"),
        ("empty", Vec::new(), "empty"),
        ("script", b"#!/bin/sh\necho hi\n".to_vec(), "not an ELF"),
        (
            "other-role",
            sink.clone(),
            "the sink firmware, not the anchor",
        ),
    ];
    for (name, bytes, want) in cases {
        let d = dir.join(name);
        std::fs::create_dir_all(&d).unwrap();
        for role in Role::ALL {
            std::fs::write(firmware::elf(&d, role), &bytes).unwrap();
        }
        let anchor = firmware::elf(&d, Role::Anchor);
        let e = firmware::check(&anchor, Role::Anchor).unwrap_err();
        assert!(
            e.contains(&anchor.display().to_string()) && e.contains(want),
            "{e}"
        );
        // The command says so too, and fails.
        let out = Command::new(bin())
            .args(["footprint", "--firmware-dir", d.to_str().unwrap()])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {stderr}");
        assert!(stderr.contains(want), "{name}: {stderr}");
        assert!(stderr.contains("anchor-fw.elf"), "{name}: {stderr}");
    }
    for role in Role::ALL {
        assert_eq!(firmware::check(&firmware::elf(&fw, role), role), Ok(()));
    }
}

// ------------------------------------------------------------------------------------------
// 7. Where the binary looks, and 8. what an interrupted demo leaves.

/// A hoploc workspace of its own in a temporary directory: a `Cargo.toml` with `[workspace]`,
/// room10 as `scenarios/short.toml` (its path cut to one short stop), the firmware in
/// `target/avr-none/fw`; and a copy of the binary outside it.
fn fake_workspace(name: &str) -> (TempDir, PathBuf, PathBuf) {
    let root = tmp(name);
    let ws = root.join("ws");
    std::fs::create_dir_all(ws.join("scenarios")).unwrap();
    std::fs::create_dir_all(ws.join("deep/er")).unwrap();
    std::fs::write(ws.join("Cargo.toml"), "[workspace]\nmembers = []\n").unwrap();
    let real = firmware::workspace().expect("the tests run in the hoploc workspace");
    let room = std::fs::read_to_string(real.join("scenarios/room10.toml")).unwrap();
    let short = room.replace("name = \"room10\"", "name = \"short\"");
    std::fs::write(ws.join("scenarios/short.toml"), short).unwrap();
    let fw = ws.join("target/avr-none/fw");
    std::fs::create_dir_all(&fw).unwrap();
    for role in Role::ALL {
        std::fs::copy(
            firmware::elf(&firmware::default_dir(), role),
            firmware::elf(&fw, role),
        )
        .unwrap();
    }
    let exe = root.join("bin/hoploc");
    std::fs::create_dir_all(exe.parent().unwrap()).unwrap();
    std::fs::copy(bin(), &exe).unwrap();
    (root, ws, exe)
}

#[test]
fn the_binary_finds_scenarios_and_firmware_from_where_it_runs() {
    let (_root, ws, exe) = fake_workspace("where");
    // From a directory deep inside the workspace: its scenario, its firmware, its target/.
    let out = Command::new(&exe)
        .args([
            "demo",
            "short",
            "--sink",
            "host",
            "--seconds",
            "9",
            "--threads",
            "1",
        ])
        .current_dir(ws.join("deep/er"))
        .env_remove("HOPLOC_FIRMWARE_DIR")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stdout}\n{stderr}");
    assert!(stdout.contains("hoploc demo short"), "{stdout}");
    let log = ws.join("target/demo/short/sink.log");
    assert!(log.exists(), "{stdout}");
    // Outside any workspace: a clear error saying where it looked, nothing of the build's.
    let outside = ws.parent().unwrap().join("bin");
    let out = Command::new(&exe)
        .args(["demo", "short", "--sink", "host"])
        .current_dir(&outside)
        .env_remove("HOPLOC_FIRMWARE_DIR")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("no scenario `short`"), "{stderr}");
    assert!(stderr.contains("no hoploc workspace"), "{stderr}");
    let build_dir = env!("CARGO_MANIFEST_DIR");
    assert!(!stderr.contains(build_dir), "{stderr}");
    // The help says where it looks.
    let help = Command::new(&exe).arg("--help").output().unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(help.contains("Where hoploc looks"), "{help}");
}

#[test]
fn an_interrupted_demo_keeps_what_it_saw() {
    let (_root, ws, exe) = fake_workspace("killed");
    let out_dir = ws.join("out");
    let mut child = Command::new(&exe)
        .args([
            "demo",
            "short",
            "--sink",
            "host",
            "--threads",
            "1",
            "--out-dir",
        ])
        .arg(&out_dir)
        .current_dir(&ws)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Wait until the first fixes are on disk (the warm-up is 8 s of simulated time), then
    // stop the demo half-way.
    let csv = out_dir.join("fixes.csv");
    let t0 = Instant::now();
    let fixes = |p: &Path| {
        std::fs::read_to_string(p)
            .map(|t| t.lines().count().saturating_sub(1))
            .unwrap_or(0)
    };
    while fixes(&csv) < 12 {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the demo ended before it was stopped"
        );
        assert!(t0.elapsed() < Duration::from_secs(120), "no fix on disk");
        std::thread::sleep(Duration::from_millis(50));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    // What it saw is on disk: the sink's log replays, the CSV has its rows.
    assert!(
        !out_dir.join("table.txt").exists(),
        "the demo was not stopped half-way"
    );
    let log = std::fs::read(out_dir.join("sink.log")).unwrap();
    let mut replay = Replay::new(None, None);
    let mut framer = Framer::new();
    framer.push(&log, |f| replay.feed_framed(&f));
    if let Some(f) = framer.finish() {
        replay.feed_framed(&f);
    }
    assert!(replay.counts.reports >= 2, "{:?}", replay.counts);
    assert!(replay.counts.fixes >= 2, "{:?}", replay.counts);
    assert_eq!(replay.counts.damaged, 0, "{:?}", replay.counts);
    let csv_text = std::fs::read_to_string(&csv).unwrap();
    assert!(csv_text.starts_with("time_s,seq,stop,"), "{csv_text}");
}
