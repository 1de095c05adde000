//! Every boot line survives write → parse and parse → write, and no input makes the parser
//! panic.

use loc_proto::line::{BootLine, ConfigSource, LineError, RadioFound, MAX_BOOT_LINE};
use loc_proto::Role;
use proptest::prelude::*;
use proptest::sample::select;

fn boot_line() -> impl Strategy<Value = BootLine> {
    let role = select(Role::ALL.to_vec());
    prop_oneof![
        role.clone().prop_map(|role| BootLine::Boot { role }),
        (role.clone(), prop::option::of(any::<u32>())).prop_map(|(role, baud)| {
            BootLine::RadioUp {
                role,
                found: baud.map_or(RadioFound::Api, |baud| RadioFound::Configured { baud }),
            }
        }),
        (role.clone(), any::<u8>(), any::<u16>()).prop_map(|(role, code, attempt)| {
            BootLine::RadioError {
                role,
                code,
                attempt,
            }
        }),
        role.clone().prop_map(|role| BootLine::Provisioned { role }),
        (role.clone(), any::<bool>(), any::<u8>()).prop_map(|(role, eeprom, id)| {
            BootLine::Config {
                role,
                source: if eeprom {
                    ConfigSource::Eeprom
                } else {
                    ConfigSource::BuiltIn
                },
                id,
            }
        }),
        (role, any::<u8>()).prop_map(|(role, code)| BootLine::ConfigError { role, code }),
    ]
}

/// A boot line's text as it might arrive: a role and a kind, then mostly the words and numbers
/// of one of the kinds, sometimes a non-canonical or out-of-range number or a stray word.
fn boot_text() -> impl Strategy<Value = String> {
    let number = prop_oneof![
        8 => (0u32..256).prop_map(|n| n.to_string()),
        2 => any::<u32>().prop_map(|n| n.to_string()),
        1 => "(0[0-9]{1,3}|-1|\\+[0-9]|[0-9]{11})",
    ];
    let tail = prop_oneof![
        Just(String::new()),
        number.clone().prop_map(|n| format!(" ok {n}")),
        (number.clone(), number.clone()).prop_map(|(c, a)| format!(" error {c} try {a}")),
        ("(eeprom|built-in|builtin)", number.clone()).prop_map(|(s, id)| format!(" {s} id {id}")),
        number.prop_map(|c| format!(" error {c}")),
        "( ok api| api| now| ok| error| eeprom id)",
    ];
    (
        "(anchor|agent|sink)",
        "(boot|radio|provisioned|config)",
        tail,
    )
        .prop_map(|(role, kind, tail)| format!("hoploc {role} {kind}{tail}"))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    /// Whatever a boot line parses to is written back as exactly its text.
    #[test]
    fn parse_then_write(text in boot_text()) {
        if let Ok(line) = BootLine::parse(&text) {
            let mut written = String::new();
            let Ok(()) = line.write(&mut written);
            prop_assert_eq!(written, format!("{text}\r\n"));
        }
    }

    #[test]
    fn write_then_parse(line in boot_line()) {
        let mut text = String::new();
        let Ok(()) = line.write(&mut text);
        prop_assert!(text.len() <= MAX_BOOT_LINE);
        prop_assert!(text.ends_with("\r\n"));
        prop_assert!(!text.contains('\u{7e}'), "a line must never look like an API frame");
        prop_assert_eq!(BootLine::parse(&text), Ok(line));
        prop_assert_eq!(line.to_string(), text.trim_end());
    }

    #[test]
    fn any_text_parses_or_errs(text in "\\PC{0,60}") {
        match BootLine::parse(&text) {
            Ok(line) => {
                // Whatever parses is exactly what the firmware would have written.
                prop_assert_eq!(line.to_string(), text.trim_end_matches(['\r', '\n']));
            }
            Err(LineError::NotBootLine | LineError::Malformed) => {}
        }
    }

    #[test]
    fn mangled_lines_never_parse_as_something_else(line in boot_line(), cut in 0usize..45, junk in "[ a-z0-9]{0,3}") {
        let text = line.to_string();
        let cut = cut.min(text.len());
        let mangled = format!("{}{}", &text[..cut], junk);
        if let Ok(other) = BootLine::parse(&mangled) {
            prop_assert_eq!(other.to_string(), mangled);
        }
    }
}

/// [`parse_then_write`]'s inputs hold lines of every kind that parse, and lines that do not.
#[test]
fn the_text_strategy_gives_lines_that_parse_and_lines_that_do_not() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let mut runner = TestRunner::deterministic();
    let (mut kinds, mut bad) = ([0; 6], 0);
    for _ in 0..3000 {
        let text = boot_text().new_tree(&mut runner).unwrap().current();
        match BootLine::parse(&text) {
            Ok(BootLine::Boot { .. }) => kinds[0] += 1,
            Ok(BootLine::RadioUp { .. }) => kinds[1] += 1,
            Ok(BootLine::RadioError { .. }) => kinds[2] += 1,
            Ok(BootLine::Provisioned { .. }) => kinds[3] += 1,
            Ok(BootLine::Config { .. }) => kinds[4] += 1,
            Ok(BootLine::ConfigError { .. }) => kinds[5] += 1,
            Err(_) => bad += 1,
        }
    }
    assert!(
        kinds.iter().all(|&n| n > 30) && bad > 300,
        "{kinds:?} parse, {bad} do not"
    );
}
