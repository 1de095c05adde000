//! `hoploc radio` against the modelled XBee (`simavr::xbee::XBeeCore`, behind
//! `hoploc::radio::port::ModelPort`, in simulated time): a radio is found at any rate and in any
//! mode and read without a change, what differs from what hoploc expects is reported, `restore`
//! fixes it (and saves it only with `write`); no radio and garbage are typed errors; and the
//! command line refuses bad options with a clear message, never a panic.

use std::process::{Command, Output};

use clap::Parser;
use hoploc::radio::port::ModelPort;
use hoploc::radio::report::{Expected, Mark};
use hoploc::radio::{read, restore, Expectation, Found, Patience, RadioError, Report};
use loc_proto::config::Config;
use loc_proto::Role;
use simavr::xbee::{Registers, XBeeConfig};
use xbee_api::driver::BringUp;
use xbee_api::Mode;

/// A node's config: `role` `id`, the defaults otherwise.
fn node(role: Role, id: u8) -> Expectation {
    Expectation::node(Config {
        id,
        ..Config::default_for(role)
    })
}

/// The model's active and saved registers.
fn registers(port: &ModelPort) -> (Registers, Registers) {
    let core = port.core().expect("a radio");
    (core.registers().clone(), core.persisted().clone())
}

/// Every API frame the host sent the radio was an AT query (no parameter, so nothing set).
fn only_queries(port: &ModelPort) {
    let core = port.core().unwrap();
    for f in core.frames_from_host() {
        assert_eq!(f.data[0], 0x08, "{:02X?}", f.data);
        assert_eq!(f.data.len(), 4, "a set command: {:02X?}", f.data);
    }
}

fn differing(report: &Report) -> Vec<String> {
    report
        .differing()
        .iter()
        .map(|c| String::from_utf8_lossy(c).into_owned())
        .collect()
}

/// A radio that kept a previous owner's settings: in API mode at 57600, with the address and
/// channel of anchor 1, and every setting nodes fix at boot (and one they leave) changed.
fn second_hand() -> XBeeConfig {
    XBeeConfig {
        my: 0x0001,
        ch: 0x0B,
        leftovers: vec![
            (*b"RR", 3),
            (*b"MM", 1),
            (*b"SM", 4),
            (*b"A1", 4),
            (*b"PL", 0),
            (*b"EE", 1),
            (*b"CE", 1),
        ],
        ..XBeeConfig::api(2)
    }
}

#[test]
fn a_factory_radio_is_found_in_command_mode_and_read_without_a_change() {
    let mut port = ModelPort::radio(XBeeConfig::default());
    let before = registers(&port);
    let mut clock = port.clock();
    let reading = read(&mut port, &mut clock, Patience::DEFAULT).expect("found");
    assert_eq!(reading.found, Found::CommandMode { bd: 3 });
    assert!(!reading.still_in_command_mode);
    assert_eq!(reading.value(*b"AP"), Some(0));
    assert_eq!(reading.value(*b"BD"), Some(3));
    assert_eq!(reading.value(*b"GT"), Some(1000));
    assert_eq!(reading.value(*b"SL"), Some(0x40A1_B2C3));
    // Nothing changed: not a register, not the saved set, and it left command mode.
    assert_eq!(registers(&port), before);
    let core = port.core().unwrap();
    assert!(!core.in_command_mode());
    assert_eq!(core.mode(), None, "still transparent");
    assert_eq!(core.uart_baud(), 9600);
    // In transparent mode what reached it went on air as data: the `AP` query at 9600, and
    // garbage at the other rates.
    assert!(core.transmissions().iter().any(|t| t
        .payload
        .ends_with(&[0x7E, 0x00, 0x04, 0x08, 0x01, b'A', b'P', 0x65])));
    drop(core);

    // Without a role: AP and BD differ, the fixed settings and those nodes leave are as
    // expected, the role's are not checked.
    let report = Report::new(&reading, &Expectation::any_role());
    assert_eq!(differing(&report), ["AP", "BD"]);
    for cmd in [*b"MY", *b"ID", *b"CH", *b"RN", *b"CA", *b"EE"] {
        let row = report.row(cmd).unwrap();
        assert_eq!(
            (row.expected, row.mark),
            (Expected::PerRole, Mark::Unchecked)
        );
    }
    for cmd in [
        *b"RR", *b"MM", *b"SM", *b"A1", *b"PL", *b"CE", *b"A2", *b"NB", *b"GT",
    ] {
        assert_eq!(report.row(cmd).unwrap().mark, Mark::Same, "{cmd:?}");
    }
    let verdict = report.verdict();
    assert!(verdict.starts_with("2 settings differ"), "{verdict}");
    assert!(verdict.contains("AP=0: transparent mode"), "{verdict}");
    assert!(
        verdict.contains("BD=3: its UART runs at 9600 bit/s"),
        "{verdict}"
    );
    assert!(verdict.contains("depend on the role"), "{verdict}");
    let table = report.to_string();
    let ap = table.lines().find(|l| l.starts_with("AP ")).unwrap();
    assert!(
        ap.contains('✗') && ap.contains("sets it at boot, saves it"),
        "{table}"
    );

    // As anchor 2: its address and channel differ too.
    let report = Report::new(&reading, &node(Role::Anchor, 2));
    assert_eq!(differing(&report), ["AP", "BD", "MY", "CH"]);
    let fix = report.fix().unwrap();
    assert!(
        fix.starts_with("a node sets AP, BD, MY and CH at every boot"),
        "{fix}"
    );
    eprintln!("simulated {:.1} s\n{table}", port.elapsed_ms() / 1000.0);
}

#[test]
fn a_second_hand_radio_shows_each_leftover_and_restore_fixes_them() {
    let mut port = ModelPort::radio(second_hand());
    let mut clock = port.clock();
    let before = registers(&port);
    let anchor1 = node(Role::Anchor, 1);
    let reading = read(&mut port, &mut clock, Patience::DEFAULT).expect("found");
    assert_eq!(
        reading.found,
        Found::Api {
            bd: 6,
            mode: Mode::Escaped
        }
    );
    assert_eq!(registers(&port), before, "reading changed the radio");
    only_queries(&port);
    let report = Report::new(&reading, &anchor1);
    assert_eq!(
        differing(&report),
        ["EE", "RR", "MM", "SM", "A1", "PL", "CE"]
    );
    let verdict = report.verdict();
    for effect in [
        "7 settings differ",
        "EE=1: encryption on",
        "RR=3: up to 3 XBee retries",
        "MM=1: no ACKs",
        "SM=4: the radio sleeps and hears nothing",
        "A1=4: end-device association",
        "PL=0: lower output power",
        "CE=1: coordinator",
    ] {
        assert!(verdict.contains(effect), "{effect}: {verdict}");
    }
    let fix = report.fix().unwrap();
    assert!(
        fix.contains("a node sets EE, RR, MM, SM, A1 and PL at every boot")
            && fix.contains("nodes leave CE as the radio has it")
            && fix.contains("(with --write, for good)"),
        "{fix}"
    );

    // Restored without --write: the radio is as anchor 1 expects, its flash untouched (AP and
    // BD were right already), so a power cycle brings the leftovers back.
    let restored =
        restore(&mut port, &mut clock, &anchor1, false, Patience::DEFAULT).expect("restored");
    assert_eq!(restored.bring_up, BringUp::AlreadyApi);
    assert_eq!(restored.factory, [*b"CE"]);
    assert!(Report::new(&restored.after, &anchor1)
        .differing()
        .is_empty());
    {
        let core = port.core().unwrap();
        let r = core.registers();
        for (cmd, v) in [
            ("RR", 0),
            ("MM", 0),
            ("SM", 0),
            ("A1", 0),
            ("PL", 4),
            ("EE", 0),
            ("CE", 0),
        ] {
            let cmd = [cmd.as_bytes()[0], cmd.as_bytes()[1]];
            assert_eq!(r.get(cmd), Some(v), "{cmd:?}");
        }
        assert_eq!(core.persisted(), &before.1, "written without --write");
    }
    port.power_cycle();
    let again = read(&mut port, &mut clock, Patience::DEFAULT).unwrap();
    assert_eq!(
        Report::new(&again, &anchor1).differing().len(),
        7,
        "the leftovers are back after a power cycle"
    );

    // With --write: saved, so they survive a power cycle.
    let restored =
        restore(&mut port, &mut clock, &anchor1, true, Patience::DEFAULT).expect("restored");
    assert!(restored.written);
    {
        let core = port.core().unwrap();
        assert_eq!(core.persisted(), core.registers());
    }
    port.power_cycle();
    let after = read(&mut port, &mut clock, Patience::DEFAULT).unwrap();
    let report = Report::new(&after, &anchor1);
    assert!(report.differing().is_empty(), "{report}");
    assert_eq!(report.verdict(), "as hoploc expects for anchor 1");
    assert_eq!(report.fix(), None);
    eprintln!("simulated {:.1} s", port.elapsed_ms() / 1000.0);
}

/// A radio left in pin sleep (`SM` 1) sleeps on a node's shield, which leaves its sleep pin
/// high, and no node can bring it up; on a USB adapter, which drives the pin low, it is awake:
/// read, reported and restored for good.
#[test]
fn a_radio_in_pin_sleep_is_awake_on_the_adapter_and_restore_clears_it() {
    let mut port = ModelPort::radio(XBeeConfig {
        my: 0x0001,
        ch: 0x0B,
        leftovers: vec![(*b"SM", 1)],
        ..XBeeConfig::api(2)
    });
    let mut clock = port.clock();
    assert!(!port.core().unwrap().is_asleep());
    let anchor1 = node(Role::Anchor, 1);
    let reading = read(&mut port, &mut clock, Patience::DEFAULT).expect("found");
    let report = Report::new(&reading, &anchor1);
    assert_eq!(differing(&report), ["SM"]);
    let verdict = report.verdict();
    assert!(
        verdict.contains("SM=1: pin sleep: on a node's shield"),
        "{verdict}"
    );
    let restored =
        restore(&mut port, &mut clock, &anchor1, true, Patience::DEFAULT).expect("restored");
    assert!(restored.written);
    assert_eq!(port.core().unwrap().persisted().sm(), 0);
}

#[test]
fn restore_brings_a_factory_radio_to_api_mode_and_saves_only_ap_and_bd() {
    let mut port = ModelPort::radio(XBeeConfig::default());
    let mut clock = port.clock();
    let agent = node(Role::Agent, 2);
    let restored =
        restore(&mut port, &mut clock, &agent, false, Patience::DEFAULT).expect("restored");
    assert_eq!(restored.before.found, Found::CommandMode { bd: 3 });
    assert_eq!(restored.bring_up, BringUp::Configured { baud: 9600 });
    assert!(restored.factory.is_empty());
    assert_eq!(
        restored.after.found,
        Found::Api {
            bd: 6,
            mode: Mode::Escaped
        }
    );
    let core = port.core().unwrap();
    let (r, p) = (core.registers(), core.persisted());
    // The agent's settings (address 0x0102, channel 1, RN 1, CA 0x50) are active; only AP and
    // BD are saved, as a node's bring-up saves them.
    assert_eq!((r.my(), r.ch(), r.rn(), r.ca()), (0x0102, 0x0B, 1, 0x50));
    assert_eq!((p.ap(), p.bd()), (2, 6));
    assert_eq!((p.my(), p.ch(), p.rn(), p.ca()), (0, 0x0C, 0, 0x2C));
    drop(core);
    let text = hoploc::radio::report::describe_restore(&restored, &agent);
    assert!(
        text.starts_with("set AP 2 and BD 6 in command mode at 9600 bit/s and saved them (WR)"),
        "{text}"
    );
    assert!(
        text.contains("set MY, ID, CH, RN, CA, EE, RR, MM, SM, A1 and PL, as a node does at boot"),
        "{text}"
    );
    assert!(text.contains("saved nothing more"), "{text}");
    eprintln!("simulated {:.1} s", port.elapsed_ms() / 1000.0);
}

#[test]
fn a_radio_left_at_bd7_is_found_at_111111_bit_per_s() {
    for (ap, found) in [
        (
            2,
            Found::Api {
                bd: 7,
                mode: Mode::Escaped,
            },
        ),
        (
            1,
            Found::Api {
                bd: 7,
                mode: Mode::Api,
            },
        ),
        (0, Found::CommandMode { bd: 7 }),
    ] {
        let mut port = ModelPort::radio(XBeeConfig {
            ap,
            bd: 7,
            // AP=1: a value with bytes AP=2 would escape comes back unescaped.
            my: 0x7E11,
            ..XBeeConfig::default()
        });
        let mut clock = port.clock();
        let before = registers(&port);
        let reading = read(&mut port, &mut clock, Patience::DEFAULT).expect("found");
        assert_eq!(reading.found, found);
        assert_eq!(reading.value(*b"BD"), Some(7));
        assert_eq!(reading.value(*b"MY"), Some(0x7E11));
        assert_eq!(registers(&port), before);
        assert_eq!(port.bauds().last(), Some(&111_111));
        let report = Report::new(&reading, &Expectation::any_role());
        let table = report.to_string();
        assert!(
            table
                .lines()
                .any(|l| l.starts_with("BD ") && l.contains("7 (111111 bit/s)")),
            "{table}"
        );
    }
}

#[test]
fn no_radio_is_a_typed_error() {
    let mut port = ModelPort::nothing();
    let mut clock = port.clock();
    let e = read(&mut port, &mut clock, Patience::DEFAULT).unwrap_err();
    assert!(matches!(e, RadioError::NoResponse), "{e:?}");
    assert!(
        e.to_string()
            .contains("no answer from a radio at any baud rate"),
        "{e}"
    );
    // Every rate tried, API mode and then command mode.
    assert_eq!(port.bauds().len(), 16);
    let e = restore(
        &mut port,
        &mut clock,
        &Expectation::any_role(),
        true,
        Patience::DEFAULT,
    )
    .unwrap_err();
    assert!(matches!(e, RadioError::NoResponse), "{e:?}");
}

#[test]
fn garbage_on_the_line_is_a_typed_error() {
    let mut port = ModelPort::babbler(b"hoploc anchor boot\r\nOKAY\r\n\x7E\x00\x05garbage\r\n");
    let mut clock = port.clock();
    let e = read(&mut port, &mut clock, Patience::DEFAULT).unwrap_err();
    assert!(matches!(e, RadioError::Garbage), "{e:?}");
    assert!(e.to_string().contains("never a radio's answer"), "{e}");
}

// ---- the command line ----

fn hoploc(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hoploc"))
        .args(args)
        .output()
        .expect("run hoploc")
}

#[test]
fn help_has_examples() {
    let out = hoploc(&["radio", "--help"]);
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    for text in [
        "    hoploc radio --port /dev/ttyUSB0\n",
        "hoploc radio --port /dev/ttyUSB0 --role anchor --id 2",
        "--restore --write",
        "WR wears the radio's flash",
        "--channels",
        "--key",
    ] {
        assert!(help.contains(text), "{text}: {help}");
    }
}

#[test]
fn bad_options_and_ports_are_clear_errors_never_a_panic() {
    // (arguments, exit code, what the message says)
    let cases: [(&[&str], i32, &str); 9] = [
        (&["radio"], 2, "--port"),
        (
            &["radio", "--port", "x", "--role", "robot"],
            2,
            "not a role",
        ),
        (&["radio", "--port", "x", "--role", "anchor"], 2, "--id"),
        (&["radio", "--port", "x", "--id", "2"], 2, "--role"),
        (&["radio", "--port", "x", "--pan", "0x1234"], 2, "--role"),
        (&["radio", "--port", "x", "--write"], 2, "--restore"),
        (
            &[
                "radio",
                "--port",
                "/nonexistent/tty",
                "--role",
                "anchor",
                "--id",
                "9",
            ],
            1,
            "--id: an anchor's id is 1…N",
        ),
        (
            &["radio", "--port", "/nonexistent/tty"],
            1,
            "serial port /nonexistent/tty",
        ),
        (
            &["radio", "--port", "/dev/null", "--restore"],
            1,
            "serial port /dev/null",
        ),
    ];
    for (args, code, says) in cases {
        let out = hoploc(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

/// `hoploc radio` with `args` (after `--port model`) on `port`: what it prints.
fn run_on(port: &mut ModelPort, args: &[&str]) -> hoploc::radio::Checked {
    let mut line = vec!["hoploc", "radio", "--port", "model"];
    line.extend_from_slice(args);
    let cli = hoploc::cli::Cli::try_parse_from(&line).expect("parses");
    let hoploc::cli::Command::Radio(args) = cli.command else {
        panic!("not `hoploc radio`");
    };
    let expect = args.expectation().expect("a valid config");
    let mut clock = port.clock();
    hoploc::radio::check(port, &mut clock, &args, &expect, Patience::DEFAULT).expect("checked")
}

#[test]
fn the_command_prints_the_table_the_verdict_and_the_fix() {
    let mut port = ModelPort::radio(second_hand());
    let out = run_on(&mut port, &["--role", "anchor", "--id", "1"]);
    eprintln!("{}", out.text);
    let text = &out.text;
    assert!(text.starts_with(
        "radio on model: found in API mode 2 at 57600 bit/s (BD 6); read without changing anything\n\
         checked against: the radio settings of anchor 1 at (0, 0) cm"
    ), "{text}");
    let sm = text.lines().find(|l| l.starts_with("SM ")).unwrap();
    assert_eq!(
        sm.split_whitespace().collect::<Vec<_>>(),
        ["SM", "4", "0", "✗", "sets", "it", "at", "boot"]
    );
    assert!(text.contains("\nverdict: 7 settings differ"), "{text}");
    assert!(
        text.contains("the same command with --restore sets them all now (with --write, for good)"),
        "{text}"
    );

    let out = run_on(
        &mut port,
        &["--role", "anchor", "--id", "1", "--restore", "--write"],
    );
    eprintln!("{}", out.text);
    assert!(out.still_differs.is_empty());
    let text = &out.text;
    for part in [
        "\nbefore:\n",
        "\nverdict: 7 settings differ",
        "\nrestore: the radio answered in API mode 2 at 57600 bit/s: AP and BD stay; set MY, ID, \
         CH, RN, CA, EE, RR, MM, SM, A1 and PL, as a node does at boot; set CE to the factory \
         value (nodes leave it); saved everything (WR)\n",
        "\nafter:\n",
        "\nverdict: as hoploc expects for anchor 1\n",
    ] {
        assert!(text.contains(part), "{part}: {text}");
    }
}

#[test]
fn an_s1_pro_refuses_channel_1_and_restore_says_so() {
    let mut port = ModelPort::radio(XBeeConfig {
        model: simavr::xbee::Model::S1Pro,
        ..XBeeConfig::api(2)
    });
    let mut clock = port.clock();
    let e = restore(
        &mut port,
        &mut clock,
        &node(Role::Anchor, 1),
        false,
        Patience::DEFAULT,
    )
    .unwrap_err();
    assert!(matches!(e, RadioError::Restore(_)), "{e:?}");
    assert!(e.to_string().contains("S1 Pro has no channel 1"), "{e}");
    // With channels it has, it is restored.
    let anchor = Expectation::node(Config {
        channels: loc_proto::msg::ChannelList::new(&[2, 12]).unwrap(),
        ..Config::default_for(Role::Anchor)
    });
    let restored = restore(&mut port, &mut clock, &anchor, false, Patience::DEFAULT).unwrap();
    assert!(Report::new(&restored.after, &anchor).differing().is_empty());
    assert_eq!(restored.after.value(*b"CH"), Some(0x0C));
}

#[test]
fn registers_nodes_leave_alone_are_reported_and_restored_to_factory() {
    let mut port = ModelPort::radio(XBeeConfig {
        gt_ms: 2000,
        leftovers: vec![(*b"CC", u32::from(b'*')), (*b"IR", 100), (*b"A2", 6)],
        ..XBeeConfig::api(2)
    });
    let mut clock = port.clock();
    let any = Expectation::any_role();
    let reading = read(&mut port, &mut clock, Patience::DEFAULT).unwrap();
    let report = Report::new(&reading, &any);
    assert_eq!(differing(&report), ["A2", "GT", "CC", "IR"]);
    let verdict = report.verdict();
    for effect in [
        "A2=6: coordinator association options",
        "GT=2000 ms: a guard time of at least a node's 1100 ms",
        "CC=0x2A: the command character is not '+'",
        "IR=100 ms: it samples its I/O lines every 100 ms",
    ] {
        assert!(verdict.contains(effect), "{effect}: {verdict}");
    }
    let restored = restore(&mut port, &mut clock, &any, false, Patience::DEFAULT).unwrap();
    assert_eq!(restored.factory, [*b"A2", *b"GT", *b"CC", *b"IR"]);
    let r = &restored.after;
    assert_eq!(
        [b"A2", b"GT", b"CC", b"IR"].map(|c| r.value(*c)),
        [Some(0), Some(1000), Some(0x2B), Some(0)]
    );
    // Not saved: a power cycle brings them back.
    port.power_cycle();
    let again = read(&mut port, &mut clock, Patience::DEFAULT).unwrap();
    assert_eq!(
        differing(&Report::new(&again, &any)),
        ["A2", "GT", "CC", "IR"]
    );
}
