//! Every boot line survives write → parse, and no input makes the parser panic.

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

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    #[test]
    fn write_then_parse(line in boot_line()) {
        let mut bytes = Vec::new();
        line.write(|b| bytes.push(b));
        prop_assert!(bytes.len() <= MAX_BOOT_LINE);
        prop_assert!(bytes.ends_with(b"\r\n"));
        prop_assert!(!bytes.contains(&0x7E), "a line must never look like an API frame");
        let text = String::from_utf8(bytes).unwrap();
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
