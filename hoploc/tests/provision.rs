//! `hoploc provision` from the command line: its help has an example, bad options and bad ports
//! are typed errors with a non-zero exit. (The exchange itself is tested against the firmware in
//! simavr: tests/tests/provision.rs.)

use std::process::{Command, Output};

fn hoploc(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .args(args)
        .output()
        .expect("run hoploc")
}

#[test]
fn help_has_an_example() {
    let out = hoploc(&["provision", "--help"]);
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(
        help.contains("hoploc provision --port /dev/ttyACM0 --role anchor --id 2 --x 700 --y 0"),
        "{help}"
    );
    for opt in [
        "--anchors",
        "--slot-ms",
        "--channels",
        "--sink-channel",
        "--pan",
    ] {
        assert!(help.contains(opt), "{opt}: {help}");
    }
}

#[test]
fn bad_options_are_refused_before_opening_anything() {
    let base = [
        "provision",
        "--port",
        "/nonexistent/tty",
        "--role",
        "anchor",
    ];
    for (extra, says) in [
        (&["--id", "2", "--channels", "1,1"][..], "--channels"),
        (&["--id", "2", "--channels", "0"][..], "--channels"),
        (&["--id", "2", "--pan", "0xFFFF"][..], "--pan"),
        (&["--id", "2", "--x", "99999"][..], "--x"),
        (&["--id", "x"][..], "--id"),
    ] {
        let mut args = base.to_vec();
        args.extend_from_slice(extra);
        let out = hoploc(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
    let out = hoploc(&[
        "provision",
        "--port",
        "/dev/null",
        "--role",
        "robot",
        "--id",
        "1",
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a role"));
    // Valid syntax, invalid config: anchor 5 of 4.
    let out = hoploc(&[
        "provision",
        "--port",
        "/nonexistent/tty",
        "--role",
        "anchor",
        "--id",
        "5",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("invalid config") && err.contains("--id: an anchor's id is 1…N"),
        "{err}"
    );
}

#[test]
fn a_missing_port_is_a_clear_error() {
    let out = hoploc(&[
        "provision",
        "--port",
        "/nonexistent/tty",
        "--role",
        "anchor",
        "--id",
        "2",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("serial port") && err.contains("/nonexistent/tty"),
        "{err}"
    );
}
