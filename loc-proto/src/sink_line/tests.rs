use super::*;
use proptest::prelude::*;
use std::string::{String, ToString};

fn text(l: &SinkLine) -> String {
    let mut s = String::new();
    let Ok(()) = l.write(&mut s);
    assert!(s.len() <= MAX_SINK_LINE, "{}", s.len());
    assert!(!s.contains('\u{7e}'));
    s
}

const FIX: SinkLine = SinkLine::Fix {
    agent: 2,
    seq: 417,
    estimator: Estimator::Mle,
    x: 281,
    y: 600,
    alpha_x100: 282,
    p0_x100: -4126,
    anchors: 4,
    flags: 1,
};
const NOFIX: SinkLine = SinkLine::NoFix {
    agent: 2,
    seq: 418,
    usable: 2,
};
const STATUS: SinkLine = SinkLine::Status {
    uptime_s: 61,
    frames: 1203,
    reports: 240,
    drops: 3,
    checksum_errors: 1,
    foreign: 17,
    fixes: 480,
    repeats: 0,
    failed: 2,
};

#[test]
fn golden_lines() {
    // The module docs show these three lines.
    assert_eq!(
        text(&FIX),
        "hoploc sink fix 2 417 mle 281 600 282 -4126 4 1 *CA47\r\n"
    );
    assert_eq!(text(&NOFIX), "hoploc sink nofix 2 418 2 *93A5\r\n");
    assert_eq!(
        text(&STATUS),
        "hoploc sink status 61 1203 240 3 1 17 480 0 2 *344B\r\n"
    );
    for l in [FIX, NOFIX, STATUS] {
        assert_eq!(SinkLine::parse(&text(&l)), Ok(l));
    }
}

#[test]
fn the_crc_is_crc_16_ccitt_false() {
    assert_eq!(crc16(b"123456789"), 0x29B1);
    assert_eq!(crc16(&[]), 0xFFFF);
}

proptest! {
    /// [`crc16`] is the `crc` crate's CRC-16/IBM-3740 (another name of CRC-16/CCITT-FALSE).
    #[test]
    fn the_crc_matches_an_independent_implementation(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        let reference = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740);
        prop_assert_eq!(crc16(&bytes), reference.checksum(&bytes));
    }
}

#[test]
fn the_longest_line_fits() {
    let l = SinkLine::Status {
        uptime_s: u32::MAX,
        frames: u32::MAX,
        reports: u32::MAX,
        drops: u32::MAX,
        checksum_errors: u32::MAX,
        foreign: u32::MAX,
        fixes: u32::MAX,
        repeats: u32::MAX,
        failed: u32::MAX,
    };
    assert_eq!(text(&l).len(), MAX_SINK_LINE);
}

#[test]
fn damage_is_detected() {
    let good = text(&FIX);
    // A digit changed.
    let bad = good.replace("281", "251");
    assert!(matches!(
        SinkLine::parse(&bad),
        Err(SinkLineError::BadChecksum { .. })
    ));
    // Two digits swapped (an XOR would not see it), a word dropped.
    let swapped = good.replace("281", "218");
    assert!(matches!(
        SinkLine::parse(&swapped),
        Err(SinkLineError::BadChecksum { .. })
    ));
    let dropped = good.replace(" 4 1 ", " 1 ");
    assert!(matches!(
        SinkLine::parse(&dropped),
        Err(SinkLineError::BadChecksum { .. })
    ));
    // Checksum missing or malformed.
    assert_eq!(
        SinkLine::parse("hoploc sink fix 2 417 mle 281 600 282 -4126 4 1"),
        Err(SinkLineError::NoChecksum)
    );
    assert_eq!(
        SinkLine::parse("hoploc sink nofix 2 418 2 *93A"),
        Err(SinkLineError::NoChecksum)
    );
    assert_eq!(
        SinkLine::parse("hoploc sink nofix 2 418 2 *93A5A"),
        Err(SinkLineError::NoChecksum)
    );
    assert_eq!(
        SinkLine::parse("hoploc sink nofix 2 418 2 *93a5"),
        Err(SinkLineError::NoChecksum)
    );
    assert_eq!(
        SinkLine::parse("hoploc sink nofix 2 418 2 *93g5"),
        Err(SinkLineError::NoChecksum)
    );
    assert_eq!(
        SinkLine::parse("hoploc anchor boot"),
        Err(SinkLineError::NotSinkLine)
    );
    assert_eq!(SinkLine::parse(""), Err(SinkLineError::NotSinkLine));
}

/// `text` with a correct checksum.
fn signed(text: &str) -> String {
    let cs = crc16(text.as_bytes());
    std::format!("{text} *{cs:04X}")
}

#[test]
fn bad_fields_say_which() {
    let cases = [
        (
            "hoploc sink fix 2 417 mle 281 600 282 -4126 4",
            SinkLineError::BadField { index: 8 },
        ),
        (
            "hoploc sink fix 2 417 ml 281 600 282 -4126 4 1",
            SinkLineError::BadField { index: 2 },
        ),
        (
            "hoploc sink fix 256 417 mle 281 600 282 -4126 4 1",
            SinkLineError::BadField { index: 0 },
        ),
        (
            "hoploc sink fix 2 417 mle 281 600 282 -4126 4 01",
            SinkLineError::BadField { index: 8 },
        ),
        (
            "hoploc sink fix 2 417 mle +281 600 282 -4126 4 1",
            SinkLineError::BadField { index: 3 },
        ),
        (
            "hoploc sink fix 2 417 mle -0 600 282 -4126 4 1",
            SinkLineError::BadField { index: 3 },
        ),
        ("hoploc sink nofix 2 418 2 9", SinkLineError::TooManyFields),
        (
            "hoploc sink nofix 2 418",
            SinkLineError::BadField { index: 2 },
        ),
        (
            "hoploc sink nofix 2  418 2",
            SinkLineError::BadField { index: 1 },
        ),
        ("hoploc sink fixes 2 418 2", SinkLineError::UnknownKind),
        (
            "hoploc sink status 1 2 3 4 5 6 -7",
            SinkLineError::BadField { index: 6 },
        ),
    ];
    for (t, e) in cases {
        assert_eq!(SinkLine::parse(&signed(t)), Err(e), "{t}");
    }
}

fn any_line() -> impl Strategy<Value = SinkLine> {
    prop_oneof![
        (
            any::<u8>(),
            any::<u16>(),
            any::<bool>(),
            any::<i16>(),
            any::<i16>(),
            any::<u16>(),
            any::<i16>(),
            any::<u8>(),
            any::<u8>()
        )
            .prop_map(
                |(agent, seq, m, x, y, alpha_x100, p0_x100, anchors, flags)| SinkLine::Fix {
                    agent,
                    seq,
                    estimator: if m { Estimator::Mmse } else { Estimator::Mle },
                    x,
                    y,
                    alpha_x100,
                    p0_x100,
                    anchors,
                    flags,
                }
            ),
        (any::<u8>(), any::<u16>(), any::<u8>()).prop_map(|(agent, seq, usable)| SinkLine::NoFix {
            agent,
            seq,
            usable
        }),
        proptest::array::uniform9(any::<u32>()).prop_map(|v| SinkLine::Status {
            uptime_s: v[0],
            frames: v[1],
            reports: v[2],
            drops: v[3],
            checksum_errors: v[4],
            foreign: v[5],
            fixes: v[6],
            repeats: v[7],
            failed: v[8],
        }),
    ]
}

proptest! {
    #[test]
    fn write_then_parse_is_the_identity(l in any_line()) {
        prop_assert_eq!(SinkLine::parse(&text(&l)), Ok(l));
    }

    #[test]
    fn any_one_byte_change_is_caught_or_harmless(l in any_line(), at in any::<prop::sample::Index>(), to in any::<u8>()) {
        let mut v = text(&l).into_bytes();
        let i = at.index(v.len() - 2); // not the \r\n
        if v[i] == to { return Ok(()); }
        v[i] = to;
        if let Ok(s) = std::str::from_utf8(&v) {
            // Never the same line with other values: either rejected or, if the change kept
            // the text and checksum consistent (impossible for one byte), identical.
            let r = SinkLine::parse(s);
            prop_assert!(r.is_err(), "{:?} from {:?}", r, s);
        }
    }


    #[test]
    fn parsing_never_panics(s in ".{0,120}") {
        let _ = SinkLine::parse(&s);
        let _ = SinkLine::parse(&std::format!("hoploc sink {s}"));
    }
}

/// A report of agent 2, superframe 418: 4 anchors on channels 1 and 12, with relays.
fn sample_report() -> crate::msg::Report {
    use crate::msg::{ChannelList, Position, Report};
    let mut r = Report::new(2, 418, 4, ChannelList::new(&[1, 12]).unwrap());
    let corners = [(0, 0), (1000, 0), (1000, 1000), (0, 1000)];
    for (i, &(x, y)) in corners.iter().enumerate() {
        r.positions[i] = Position { x, y };
        for c in 0..2 {
            r.rssi[c][i] = 60 + (i + c) as u8;
            for j in 0..4 {
                if i != j {
                    r.relay[c][i][j] = 70 + (i * 4 + j) as u8;
                }
            }
        }
    }
    r
}

fn report_text(msg: &[u8]) -> String {
    let mut s = String::new();
    let Ok(()) = RawReport::write(msg, &mut s);
    assert!(s.len() <= MAX_REPORT_LINE, "{}", s.len());
    assert!(!s.contains('\u{7e}'));
    s
}

#[test]
fn report_lines_carry_the_message_both_ways() {
    let r = sample_report();
    let mut buf = [0; MAX_PAYLOAD];
    let n = r.encode(&mut buf).unwrap();
    let line = report_text(&buf[..n]);
    // The hex of the message bytes, upper case, between the kind and the checksum.
    let hex: String = buf[..n].iter().map(|b| std::format!("{b:02X}")).collect();
    assert!(
        line.starts_with(&std::format!("hoploc sink report {hex} *")),
        "{line}"
    );
    assert!(line.ends_with("\r\n"));
    let raw = RawReport::parse(&line).unwrap();
    assert_eq!(raw.bytes(), &buf[..n]);
    assert_eq!(raw.report(), Ok(r));
    assert_eq!(
        SinkOutput::parse(&line),
        Ok(SinkOutput::Report(raw.clone()))
    );
    assert_eq!(RawReport::new(&buf[..n]), Some(raw));
    // SinkLine::parse reads the three small kinds only; SinkOutput::parse reads them too.
    assert_eq!(SinkLine::parse(&line), Err(SinkLineError::UnknownKind));
    assert_eq!(SinkOutput::parse(&text(&FIX)), Ok(SinkOutput::Line(FIX)));
    assert_eq!(
        RawReport::parse(&text(&FIX)),
        Err(SinkLineError::UnknownKind)
    );
    // The longest message gives the longest line.
    assert_eq!(report_text(&[0xFF; MAX_PAYLOAD]).len(), MAX_REPORT_LINE);
    assert_eq!(RawReport::new(&[]), None);
    assert_eq!(RawReport::new(&[0; MAX_PAYLOAD + 1]), None);
}

#[test]
fn bad_report_lines_are_rejected() {
    let cases = [
        ("hoploc sink report", SinkLineError::BadField { index: 0 }),
        ("hoploc sink report 4", SinkLineError::BadField { index: 0 }),
        (
            "hoploc sink report 4G",
            SinkLineError::BadField { index: 0 },
        ),
        (
            "hoploc sink report 4a",
            SinkLineError::BadField { index: 0 },
        ),
        ("hoploc sink report 48 00", SinkLineError::TooManyFields),
    ];
    for (t, e) in cases {
        assert_eq!(SinkOutput::parse(&signed(t)), Err(e), "{t}");
    }
    let long = std::format!("hoploc sink report {}", "00".repeat(MAX_PAYLOAD + 1));
    assert_eq!(
        SinkOutput::parse(&signed(&long)),
        Err(SinkLineError::BadField { index: 0 })
    );
    // Damage is caught by the checksum.
    let line = report_text(&[0x48, 0x01, 0x02]);
    let damaged = line.replacen("0102", "0201", 1);
    assert!(matches!(
        SinkOutput::parse(&damaged),
        Err(SinkLineError::BadChecksum { .. })
    ));
    // A well-formed line whose bytes are not a report: the line reads, the report does not.
    assert!(RawReport::parse(&line).unwrap().report().is_err());
}

proptest! {
    #[test]
    fn report_lines_round_trip(msg in proptest::collection::vec(any::<u8>(), 1..=MAX_PAYLOAD)) {
        let raw = RawReport::parse(&report_text(&msg)).unwrap();
        prop_assert_eq!(raw.bytes(), &msg[..]);
    }

    #[test]
    fn parsing_any_output_never_panics(s in ".{0,240}") {
        let _ = SinkOutput::parse(&s);
        let _ = SinkOutput::parse(&std::format!("hoploc sink report {s}"));
    }
}

#[test]
fn golden_report_line() {
    // The module docs show this line: agent 2's report 418 of `sample_report`.
    let r = sample_report();
    let mut buf = [0; MAX_PAYLOAD];
    let n = r.encode(&mut buf).unwrap();
    assert_eq!(
        report_text(&buf[..n]),
        "hoploc sink report B502023D02A2010482010C00000000E8030000E803E8030000E8033C3D3E3F3D3E3F\
         404748494A4C4D4E4F515253544748494A4C4D4E4F515253547166 *0D00\r\n"
    );
}

/// A field as a line might carry it: mostly numbers that fit any field, sometimes a number of
/// another width, a word, or a non-canonical or out-of-range number.
fn field_text() -> impl Strategy<Value = String> {
    prop_oneof![
        30 => (0u32..256).prop_map(|n| n.to_string()),
        3 => (-33_000i32..70_000).prop_map(|n| n.to_string()),
        2 => any::<u32>().prop_map(|n| n.to_string()),
        1 => "(mle|mmse|ml|MLE)",
        1 => "(0[0-9]{1,3}|-0|\\+[0-9]|-|[0-9]{11}|1e3|0x1)",
    ]
}

/// The text before the checksum of a sink line as it might arrive: a kind and, mostly, as many
/// fields as it has (a `fix` line's estimator word mostly in its place).
fn line_body() -> impl Strategy<Value = String> {
    let fields = |n| proptest::collection::vec(field_text(), n);
    prop_oneof![
        (fields(9), "(mle|mmse)", 0..8).prop_map(|(mut f, e, keep)| {
            if keep != 0 {
                f[2] = e;
            }
            std::format!("fix {}", f.join(" "))
        }),
        fields(3).prop_map(|f| std::format!("nofix {}", f.join(" "))),
        fields(STATUS_FIELDS).prop_map(|f| std::format!("status {}", f.join(" "))),
        (
            "(fix|nofix|status)",
            proptest::collection::vec(field_text(), 0..14)
        )
            .prop_map(|(k, f)| std::format!("{k} {}", f.join(" "))),
    ]
    .prop_map(|body| std::format!("hoploc sink {body}"))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    /// Whatever a sink line parses to is written back as exactly its text: the parser accepts
    /// only what the writer writes (canonical numbers, the kind's fields in order, in range).
    #[test]
    fn parse_then_write_is_the_identity(body in line_body()) {
        let line = std::format!("{}\r\n", signed(&body));
        if let Ok(l) = SinkLine::parse(&line) {
            prop_assert_eq!(text(&l), line);
        }
    }

    /// The same for `report` lines: a hex word that parses is written back as itself.
    #[test]
    fn report_parse_then_write_is_the_identity(word in "[0-9A-Fa-f]{0,12}|[0-9A-F]{2,200}") {
        let line = std::format!("{}\r\n", signed(&std::format!("hoploc sink report {word}")));
        if let Ok(SinkOutput::Report(r)) = SinkOutput::parse(&line) {
            prop_assert_eq!(report_text(r.bytes()), line);
        }
    }

    /// The CRC writer passes every piece through unchanged and its CRC is [`crc16`] of them.
    #[test]
    fn the_crc_writer_is_transparent(pieces in proptest::collection::vec(".{0,8}", 0..8)) {
        let mut out = String::new();
        let mut w = Crc16Writer::new(&mut out);
        for p in &pieces {
            let Ok(()) = ufmt::uWrite::write_str(&mut w, p);
        }
        let crc = w.crc();
        prop_assert_eq!(&out, &pieces.concat());
        prop_assert_eq!(crc, crc16(out.as_bytes()));
    }
}

/// [`parse_then_write_is_the_identity`]'s inputs hold lines that parse, of every kind, often
/// enough to test the writer, and lines that do not.
#[test]
fn the_line_strategy_gives_lines_that_parse_and_lines_that_do_not() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let mut runner = TestRunner::deterministic();
    let (mut kinds, mut bad) = ([0; 3], 0);
    for _ in 0..3000 {
        let body = line_body().new_tree(&mut runner).unwrap().current();
        match SinkLine::parse(&signed(&body)) {
            Ok(SinkLine::Fix { .. }) => kinds[0] += 1,
            Ok(SinkLine::NoFix { .. }) => kinds[1] += 1,
            Ok(SinkLine::Status { .. }) => kinds[2] += 1,
            Err(_) => bad += 1,
        }
    }
    assert!(
        kinds.iter().all(|&n| n > 100) && bad > 300,
        "{kinds:?} parse, {bad} do not"
    );
}

/// Whether the host would believe `damaged` (bytes without the line end) as a line other than
/// `good`: it is UTF-8 (else no host parser sees it) and parses to another line.
fn believed(good: &SinkOutput, damaged: &[u8]) -> bool {
    std::str::from_utf8(damaged)
        .ok()
        .and_then(|t| SinkOutput::parse(t).ok())
        .is_some_and(|l| l != *good)
}

/// The sample lines the damage tests take apart: one of each kind, the `report` line of
/// [`sample_report`], sixty random lines of every kind and four report lines of other lengths
/// (without `\r\n`).
fn sample_lines() -> std::vec::Vec<String> {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let mut buf = [0; MAX_PAYLOAD];
    let n = sample_report().encode(&mut buf).unwrap();
    let mut lines = std::vec![
        text(&FIX),
        text(&NOFIX),
        text(&STATUS),
        report_text(&buf[..n])
    ];
    let mut runner = TestRunner::deterministic();
    for _ in 0..60 {
        lines.push(text(&any_line().new_tree(&mut runner).unwrap().current()));
    }
    for len in [1, 7, 40, MAX_PAYLOAD] {
        lines.push(report_text(&std::vec![0xA5; len]));
    }
    lines
        .into_iter()
        .map(|l| l.trim_end_matches(['\r', '\n']).to_string())
        .collect()
}

/// The damage a serial line does, class by class, on every position of the sample lines: one,
/// two or three flipped bits, a burst of flipped bits within 16 bits, a byte dropped or
/// duplicated, the line cut short. None of these is ever believed.
#[test]
fn serial_damage_is_never_believed() {
    let lines = sample_lines();
    let mut checked = 0u64;
    for (k, line) in lines.iter().enumerate() {
        let good = SinkOutput::parse(line).unwrap();
        let bytes = line.as_bytes();
        let bits = bytes.len() * 8;
        let flip = |v: &mut [u8], bit: usize| v[bit / 8] ^= 0x80 >> (bit % 8);
        let mut check = |v: &[u8], what: &dyn Fn() -> String| {
            checked += 1;
            assert!(!believed(&good, v), "{line:?}: {} believed", what());
        };
        for i in 0..bytes.len() {
            // A byte dropped; a byte duplicated; the line cut short before byte i.
            let mut v = bytes.to_vec();
            v.remove(i);
            check(&v, &|| std::format!("byte {i} dropped"));
            let mut v = bytes.to_vec();
            v.insert(i, bytes[i]);
            check(&v, &|| std::format!("byte {i} duplicated"));
            check(&bytes[..i], &|| std::format!("cut at {i}"));
        }
        // Bursts within 16 bits: the first and last bit flipped, patterns between (every
        // pattern of bursts up to 8 bits on the first four lines; a sample otherwise).
        let patterns: u32 = if k < 4 { 1 << 6 } else { 2 };
        for start in 0..bits {
            for len in 1..=16.min(bits - start) {
                let inner = if len <= 2 {
                    1
                } else {
                    patterns.min(1 << (len - 2))
                };
                for p in 0..inner {
                    let mut v = bytes.to_vec();
                    flip(&mut v, start);
                    if len > 1 {
                        flip(&mut v, start + len - 1);
                    }
                    for b in 0..len.saturating_sub(2) {
                        if p >> b & 1 != 0 {
                            flip(&mut v, start + 1 + b);
                        }
                    }
                    check(&v, &|| {
                        std::format!("burst at bit {start}, {len} bits, {p:b}")
                    });
                }
            }
        }
        // Any two bits, and a sample of three, on the first three lines.
        if k < 3 {
            for a in 0..bits {
                for b in a + 1..bits {
                    let mut v = bytes.to_vec();
                    flip(&mut v, a);
                    flip(&mut v, b);
                    check(&v, &|| std::format!("bits {a} and {b} flipped"));
                }
            }
        }
        if k < 3 {
            // Three bits: every third bit for each pair of a sample of first bits.
            for a in (0..bits).step_by(13) {
                for b in a + 1..bits {
                    for c in (b + 1..bits).step_by(11) {
                        let mut v = bytes.to_vec();
                        flip(&mut v, a);
                        flip(&mut v, b);
                        flip(&mut v, c);
                        check(&v, &|| std::format!("bits {a}, {b}, {c} flipped"));
                    }
                }
            }
        }
    }
    std::println!("{checked} damaged lines, none believed");
}

/// Random damage, several changes per line (bits flipped, bytes changed, dropped, duplicated,
/// inserted, the line cut short): the share believed is the false-accept rate of the check
/// together with the parser's field checks. It prints it; it fails above 1 in 10 000 (a CRC-8
/// lets about 1 in 5 000 through).
#[test]
fn random_damage_is_refused() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    // A small xorshift: the same damage on every run.
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut rand = move |n: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as usize
    };
    let mut runner = TestRunner::deterministic();
    let mut buf = [0; MAX_PAYLOAD];
    let (mut damaged, mut accepted) = (0u64, 0u64);
    const LINES: u64 = 200_000;
    while damaged < LINES {
        let line = if rand(8) == 0 {
            let len = 1 + rand(MAX_PAYLOAD);
            for b in &mut buf[..len] {
                *b = rand(256) as u8;
            }
            report_text(&buf[..len])
        } else {
            text(&any_line().new_tree(&mut runner).unwrap().current())
        };
        let line = line.trim_end_matches(['\r', '\n']);
        let good = SinkOutput::parse(line).unwrap();
        let mut v = line.as_bytes().to_vec();
        for _ in 0..1 + rand(4) {
            if v.is_empty() {
                break;
            }
            let i = rand(v.len());
            match rand(6) {
                0 => v[i] ^= 1 << rand(8),
                1 => v[i] = rand(128) as u8,
                2 => {
                    v.remove(i);
                }
                3 => v.insert(i, v[i]),
                4 => v.insert(i, rand(128) as u8),
                _ => v.truncate(i),
            }
        }
        if v == line.as_bytes() {
            continue;
        }
        damaged += 1;
        accepted += believed(&good, &v) as u64;
    }
    let rate = accepted as f64 / damaged as f64;
    std::println!(
        "random damage: {accepted} of {damaged} damaged lines believed ({:.5} %)",
        100.0 * rate
    );
    assert!(rate <= 1e-4, "{accepted} of {damaged} believed");
}
