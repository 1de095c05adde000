//! A [`Reading`] next to what hoploc expects ([`Expectation`]): one row per register with the
//! radio's value, hoploc's, ✓ or ✗, and whether a node sets it; a verdict with what each
//! difference does; what [`super::restore`] did.

use std::fmt;

use loc_proto::config::{radio_settings, Config};
use xbee_api::driver::{baud_of_bd, BringUp, BringUpConfig, Encryption, BD, FIXED_SETTINGS};
use xbee_api::{Mode, BACKOFF_PERIOD_US};

use super::{Answer, Reading, Restored, REGISTERS};
use crate::provision;

/// Who gives a register its value on a hoploc node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Keeper {
    /// The node's bring-up sets it at every boot, and saves it (`WR`) when it had to change it:
    /// `AP` and `BD`.
    BootSaved,
    /// The node's bring-up sets it at every boot, without saving it.
    Boot,
    /// Nodes leave it as the radio has it; hoploc expects the factory value (or, for `GT`, one
    /// shorter than a node's guard time). [`super::restore`] sets the factory value.
    Left,
    /// Not a setting: what the radio is (`VR`, `HV`, `SH`, `SL`).
    Info,
}

/// Who gives register `cmd` its value ([`Keeper::Info`] for one [`super::read`] does not set).
pub fn keeper(cmd: [u8; 2]) -> Keeper {
    match &cmd {
        b"AP" | b"BD" => Keeper::BootSaved,
        b"MY" | b"ID" | b"CH" | b"RN" | b"CA" | b"EE" => Keeper::Boot,
        _ if FIXED_SETTINGS.iter().any(|&(c, _)| c == cmd) => Keeper::Boot,
        _ => match LEFT_ALONE.iter().find(|l| l.0 == cmd) {
            Some(_) => Keeper::Left,
            None => Keeper::Info,
        },
    }
}

/// The registers nodes leave alone that change how the radio behaves, each with its factory
/// value as [`super::restore`] sets it (big endian, the register's width):
///
/// * `CE` 0, `A2` 0: not a coordinator (one may pick its own PAN and channel at power-up and
///   answers association requests);
/// * `NB` 0: no parity (the Uno's UART runs 8N1);
/// * `GT` 1000 ms, `CC` `+`: the guard time and command character a node's bring-up needs to
///   reach command mode, when it must change `AP` or `BD`;
/// * `IR` 0, `IC` 0: no I/O samples sent on air.
pub const LEFT_ALONE: [([u8; 2], &[u8]); 7] = [
    (*b"CE", &[0]),
    (*b"A2", &[0]),
    (*b"NB", &[0]),
    (*b"GT", &[0x03, 0xE8]),
    (*b"CC", b"+"),
    (*b"IR", &[0, 0]),
    (*b"IC", &[0]),
];

/// What hoploc expects of one register.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Expected {
    /// This value.
    Is(u32),
    /// A value below this one (`GT`: shorter than a node's guard time, in ms).
    Below(u32),
    /// A value that depends on the node's role and config, not given.
    PerRole,
    /// Nothing: the register says what the radio is.
    Info,
}

impl Expected {
    /// Whether `v` is what is expected (`None`: nothing to check).
    pub fn matches(self, v: u32) -> Option<bool> {
        match self {
            Expected::Is(e) => Some(v == e),
            Expected::Below(e) => Some(v < e),
            Expected::PerRole | Expected::Info => None,
        }
    }
}

/// What a radio is checked against: the settings a node of a config gives its radio
/// ([`radio_settings`]), or, without one, what every node gives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Expectation {
    /// The node's config, if one was given.
    pub config: Option<Config>,
    /// What the node's bring-up sets (without a config: `AP`, `BD` and [`FIXED_SETTINGS`]).
    pub bring_up: BringUpConfig,
}

impl Expectation {
    /// The settings a node with `config` gives its radio.
    pub fn node(config: Config) -> Expectation {
        Expectation {
            config: Some(config),
            bring_up: radio_settings(&config),
        }
    }

    /// What every node gives its radio: API mode 2 at 57600 and [`FIXED_SETTINGS`]; `MY`, `ID`,
    /// `CH`, `RN`, `CA` and `EE` are left as the radio has them.
    pub fn any_role() -> Expectation {
        Expectation {
            config: None,
            bring_up: BringUpConfig::new(),
        }
    }

    /// What the radio is checked against, in a line.
    pub fn describe(&self) -> String {
        match &self.config {
            Some(c) => format!("the radio settings of {}", provision::describe(c)),
            None => "what every hoploc node gives its radio (no --role: MY, ID, CH, RN, CA and \
                     EE depend on the role and are not checked)"
                .to_string(),
        }
    }

    /// What hoploc expects of register `cmd`.
    pub fn expected(&self, cmd: [u8; 2]) -> Expected {
        let b = &self.bring_up;
        let set = |v: Option<u32>| v.map_or(Expected::PerRole, Expected::Is);
        match &cmd {
            b"AP" => Expected::Is(Mode::Escaped.ap().into()),
            b"BD" => Expected::Is(BD.into()),
            b"MY" => set(b.my.map(u32::from)),
            b"ID" => set(b.pan_id.map(u32::from)),
            b"CH" => set(b.channel.map(u32::from)),
            b"RN" => set(b.backoff_exponent.map(u32::from)),
            b"CA" => set(b.cca_threshold.map(u32::from)),
            b"EE" => match b.encryption {
                Encryption::Leave => Expected::PerRole,
                Encryption::Off => Expected::Is(0),
                Encryption::Key(_) => Expected::Is(1),
            },
            b"GT" => Expected::Below(b.guard_ms.into()),
            _ => {
                if let Some(&(_, v)) = FIXED_SETTINGS.iter().find(|(c, _)| *c == cmd) {
                    return Expected::Is(v.into());
                }
                match LEFT_ALONE.iter().find(|l| l.0 == cmd) {
                    Some((_, bytes)) => {
                        Expected::Is(bytes.iter().fold(0, |v, &b| (v << 8) | u32::from(b)))
                    }
                    None => Expected::Info,
                }
            }
        }
    }
}

/// How a register compares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mark {
    /// As hoploc expects: ✓.
    Same,
    /// Not as hoploc expects: ✗.
    Differs,
    /// Nothing to compare with (a role's setting without `--role`, or what the radio is).
    Unchecked,
    /// The radio gave no value.
    Unanswered,
}

/// One register of a [`Report`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Row {
    /// The register.
    pub cmd: [u8; 2],
    /// What the radio answered.
    pub answer: Answer,
    /// What hoploc expects.
    pub expected: Expected,
    /// Who sets it on a node.
    pub keeper: Keeper,
    /// How the two compare.
    pub mark: Mark,
}

/// A [`Reading`] against an [`Expectation`]: a row per register of [`REGISTERS`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Report {
    /// The rows, in the order of [`REGISTERS`].
    pub rows: Vec<Row>,
    expect: Expectation,
}

impl Report {
    /// `reading` against `expect`.
    pub fn new(reading: &Reading, expect: &Expectation) -> Report {
        let rows = REGISTERS
            .iter()
            .map(|&cmd| {
                let answer = reading.answer(cmd);
                let expected = expect.expected(cmd);
                let mark = match (expected, answer) {
                    (Expected::PerRole | Expected::Info, _) => Mark::Unchecked,
                    (_, Answer::Value(v)) if expected.matches(v) == Some(true) => Mark::Same,
                    (_, Answer::Value(_)) => Mark::Differs,
                    _ => Mark::Unanswered,
                };
                Row {
                    cmd,
                    answer,
                    expected,
                    keeper: keeper(cmd),
                    mark,
                }
            })
            .collect();
        Report {
            rows,
            expect: *expect,
        }
    }

    /// The row of register `cmd`.
    pub fn row(&self, cmd: [u8; 2]) -> Option<&Row> {
        self.rows.iter().find(|r| r.cmd == cmd)
    }

    /// The registers that differ from what hoploc expects.
    pub fn differing(&self) -> Vec<[u8; 2]> {
        self.with_mark(Mark::Differs)
    }

    /// The registers the radio gave no value for.
    pub fn unanswered(&self) -> Vec<[u8; 2]> {
        self.with_mark(Mark::Unanswered)
    }

    fn with_mark(&self, mark: Mark) -> Vec<[u8; 2]> {
        self.rows
            .iter()
            .filter(|r| r.mark == mark)
            .map(|r| r.cmd)
            .collect()
    }

    /// The registers nodes leave alone that differ, each with the factory value to set.
    pub fn left_alone_differing(&self) -> Vec<([u8; 2], &'static [u8])> {
        LEFT_ALONE
            .iter()
            .filter(|(cmd, _)| self.row(*cmd).is_some_and(|r| r.mark == Mark::Differs))
            .copied()
            .collect()
    }

    /// One line: what differs and what each difference does, or that nothing does.
    pub fn verdict(&self) -> String {
        let differing: Vec<String> = self
            .rows
            .iter()
            .filter(|r| r.mark == Mark::Differs)
            .filter_map(|r| {
                let v = r.answer.value()?;
                Some(format!(
                    "{}={}: {}",
                    name(r.cmd),
                    short(r.cmd, v),
                    effect(r.cmd, v, r.expected)
                ))
            })
            .collect();
        let mut text = match differing.len() {
            0 => match &self.expect.config {
                Some(c) => format!("as hoploc expects for {} {}", c.role.name(), c.id),
                None => "as every hoploc node expects".to_string(),
            },
            1 => format!(
                "1 setting differs from what hoploc expects: {}",
                differing[0]
            ),
            n => format!(
                "{n} settings differ from what hoploc expects: {}",
                differing.join("; ")
            ),
        };
        let unanswered = self.unanswered();
        if !unanswered.is_empty() {
            text.push_str(&format!("; no answer for {}", names(&unanswered)));
        }
        if self.expect.config.is_none() {
            text.push_str("; MY, ID, CH, RN, CA and EE depend on the role (--role, --id and the node's options check them)");
        } else if matches!(self.expect.bring_up.encryption, Encryption::Key(_)) {
            text.push_str(
                "; the radio never answers its key (KY): whether it is the network's shows only \
                 on air",
            );
        }
        text
    }

    /// What fixes the differences; `None` when nothing differs.
    pub fn fix(&self) -> Option<String> {
        let differing = self.differing();
        if differing.is_empty() {
            return None;
        }
        let (left, boot): (Vec<[u8; 2]>, Vec<[u8; 2]>) = differing
            .iter()
            .partition(|&&cmd| keeper(cmd) == Keeper::Left);
        let mut parts = Vec::new();
        if !boot.is_empty() {
            parts.push(format!("a node sets {} at every boot", names(&boot)));
        }
        if !left.is_empty() {
            parts.push(format!(
                "nodes leave {} as the radio has {}",
                names(&left),
                if left.len() == 1 { "it" } else { "them" }
            ));
        }
        let all = if differing.len() == 1 {
            "it"
        } else {
            "them all"
        };
        let keep = if left.is_empty() {
            ""
        } else {
            " (with --write, for good)"
        };
        Some(format!(
            "{}; the same command with --restore sets {all} now{keep}",
            parts.join("; ")
        ))
    }
}

impl fmt::Display for Report {
    /// The table: register, the radio's value, hoploc's, ✓/✗, who sets it on a node.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let cells: Vec<[String; 5]> = self
            .rows
            .iter()
            .map(|r| {
                let radio = match r.answer {
                    Answer::Value(v) => show(r.cmd, v),
                    Answer::Refused => "refused".to_string(),
                    Answer::Silent => "no answer".to_string(),
                };
                let hoploc = match r.expected {
                    Expected::Is(v) => show(r.cmd, v),
                    Expected::Below(v) => format!("< {v} ms"),
                    Expected::PerRole => "per role".to_string(),
                    Expected::Info => String::new(),
                };
                let mark = match r.mark {
                    Mark::Same => "✓",
                    Mark::Differs => "✗",
                    Mark::Unanswered => "?",
                    Mark::Unchecked if r.keeper == Keeper::Info => "",
                    Mark::Unchecked => "–",
                };
                let node = match r.keeper {
                    Keeper::BootSaved => "sets it at boot, saves it",
                    Keeper::Boot => "sets it at boot",
                    Keeper::Left => "leaves it",
                    Keeper::Info => info(r.cmd),
                };
                [
                    name(r.cmd),
                    radio,
                    hoploc,
                    mark.to_string(),
                    node.to_string(),
                ]
            })
            .collect();
        let header = ["reg", "radio", "hoploc", "ok", "a node"].map(String::from);
        let mut width = [0; 5];
        for row in std::iter::once(&header).chain(&cells) {
            for (w, c) in width.iter_mut().zip(row) {
                *w = (*w).max(c.chars().count());
            }
        }
        for row in std::iter::once(&header).chain(&cells) {
            let line = format!(
                "{:<w0$}  {:<w1$}  {:<w2$}  {:<w3$}  {}",
                row[0],
                row[1],
                row[2],
                row[3],
                row[4],
                w0 = width[0],
                w1 = width[1],
                w2 = width[2],
                w3 = width[3],
            );
            writeln!(f, "{}", line.trim_end())?;
        }
        Ok(())
    }
}

/// A register's two letters.
pub fn name(cmd: [u8; 2]) -> String {
    String::from_utf8_lossy(&cmd).into_owned()
}

/// Register names as a list: `AP`, `AP and BD`, `AP, BD and SM`.
pub fn names(cmds: &[[u8; 2]]) -> String {
    let n: Vec<String> = cmds.iter().map(|&c| name(c)).collect();
    match n.split_last() {
        None => String::new(),
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} and {last}", rest.join(", ")),
    }
}

/// What an `Info` register is.
fn info(cmd: [u8; 2]) -> &'static str {
    match &cmd {
        b"VR" => "firmware version",
        b"HV" => "hardware version",
        b"SH" => "serial number, high half",
        b"SL" => "serial number, low half",
        _ => "",
    }
}

/// Registers shown in hex.
fn is_hex(cmd: [u8; 2]) -> bool {
    matches!(
        &cmd,
        b"MY" | b"ID" | b"CH" | b"CA" | b"CC" | b"IC" | b"VR" | b"HV" | b"SH" | b"SL"
    )
}

/// A value as the verdict names it: `SM=4`, `CH=0x0C`, `GT=2000 ms`.
fn short(cmd: [u8; 2], v: u32) -> String {
    match &cmd {
        b"GT" | b"IR" => format!("{v} ms"),
        b"SH" | b"SL" => format!("0x{v:08X}"),
        b"MY" | b"ID" | b"VR" | b"HV" => format!("0x{v:04X}"),
        _ if is_hex(cmd) => format!("0x{v:02X}"),
        _ => v.to_string(),
    }
}

/// A value as the table shows it, with what it means where that helps.
fn show(cmd: [u8; 2], v: u32) -> String {
    match &cmd {
        b"BD" if v <= 7 => format!("{v} ({} bit/s)", baud_of_bd(v as u8)),
        b"BD" => format!("0x{v:X} (non-standard)"),
        b"CH" => match channel(v) {
            Some(n) => format!("0x{v:02X} (channel {n})"),
            None => format!("0x{v:02X}"),
        },
        b"CA" => format!("0x{v:02X} (-{v} dBm)"),
        b"IR" if v == 0 => "0 (off)".to_string(),
        b"CC" => match char::from_u32(v).filter(char::is_ascii_graphic) {
            Some(c) => format!("0x{v:02X} ('{c}')"),
            None => format!("0x{v:02X}"),
        },
        _ => short(cmd, v),
    }
}

/// The testbed channel (1…16) of a `CH` value.
fn channel(ch: u32) -> Option<u32> {
    (0x0B..=0x1A).contains(&ch).then(|| ch - 0x0A)
}

/// The longest random wait `RN` = `rn` puts before a channel check, ms.
fn backoff_ms(rn: u32) -> f64 {
    ((1u32 << rn.min(5)) - 1) as f64 * f64::from(BACKOFF_PERIOD_US) / 1000.0
}

/// What register `cmd` at `v`, where hoploc expects `expected`, does.
fn effect(cmd: [u8; 2], v: u32, expected: Expected) -> String {
    let e = match expected {
        Expected::Is(e) | Expected::Below(e) => e,
        Expected::PerRole | Expected::Info => return "not what hoploc expects".to_string(),
    };
    match &cmd {
        b"AP" => match v {
            0 => "transparent mode: it sends a node's frames on air as data, and nothing comes \
                  back as frames"
                .to_string(),
            1 => "API mode without escaping: a node's escaped frames are misread".to_string(),
            _ => "not an API mode a node talks".to_string(),
        },
        b"BD" => format!(
            "its UART runs at {}, a node's at {} bit/s",
            if v <= 7 {
                format!("{} bit/s", baud_of_bd(v as u8))
            } else {
                format!("{v} bit/s (non-standard)")
            },
            baud_of_bd(BD)
        ),
        b"MY" => format!("another address than the node's (0x{e:04X}): it sends as another node"),
        b"ID" => format!(
            "another PAN than the network's (0x{e:04X}): it hears none of the network's radios"
        ),
        b"CH" => match (channel(v), channel(e)) {
            (Some(n), Some(m)) => {
                format!("channel {n}: the node starts on channel {m} (0x{e:02X})")
            }
            _ => format!("not a testbed channel: the node starts on 0x{e:02X}"),
        },
        b"RN" if v < e => format!(
            "a shorter random wait before each channel check (up to {:.2} ms, the node's up to \
             {:.2} ms): radios that send at once collide more often",
            backoff_ms(v),
            backoff_ms(e)
        ),
        b"RN" => format!(
            "a longer random wait before each channel check (up to {:.2} ms, the node's up to \
             {:.2} ms): packets go on air later than their slot says",
            backoff_ms(v),
            backoff_ms(e)
        ),
        b"CA" if v > e => format!(
            "its channel check finds the channel busy from -{v} dBm, not -{e} dBm: it holds \
             packets back while weaker radios send"
        ),
        b"CA" => format!(
            "its channel check finds the channel busy only from -{v} dBm, not -{e} dBm: it \
             sends over radios weaker than that"
        ),
        b"EE" if v != 0 => {
            "encryption on: it hears none of an unencrypted network's packets".to_string()
        }
        b"EE" => "encryption off: it hears none of the network's encrypted packets".to_string(),
        b"RR" => format!(
            "up to {v} XBee retries on top of the MAC's three, and every broadcast sent {} \
             times: packets still on air in the next slot",
            v + 2
        ),
        b"MM" => match v {
            1 | 3 => "no ACKs: the agents' reports are never acknowledged or retried".to_string(),
            2 => "802.15.4 without duplicate detection: a retried report reaches the sink twice"
                .to_string(),
            _ => "not a MAC mode the S1 has".to_string(),
        },
        b"SM" if matches!(v, 1 | 2) => "pin sleep: on a node's shield, which leaves its sleep pin \
                                        high, the radio sleeps and takes nothing from the node \
                                        (it cannot be brought up there)"
            .to_string(),
        b"SM" => "the radio sleeps and hears nothing".to_string(),
        b"A1" => "end-device association: one that associates scans the channels and sends \
                  nothing until a coordinator answers"
            .to_string(),
        b"PL" => format!(
            "lower output power (level {v} of 4): every RSSI its packets give is lower, and the \
             P0 fitted from them"
        ),
        b"CE" => "coordinator: with A2 it picks its own PAN and channel at power-up, and it \
                  answers association requests"
            .to_string(),
        b"A2" => "coordinator association options: with CE 1 it scans for a channel or PAN at \
                  power-up"
            .to_string(),
        b"NB" => "parity on: its bytes are not 8N1, and a node's UART misreads them".to_string(),
        b"GT" => format!(
            "a guard time of at least a node's {e} ms: a node cannot reach command mode to set \
             AP and BD"
        ),
        b"CC" => "the command character is not '+': a node cannot reach command mode to set AP \
                  and BD"
            .to_string(),
        b"IR" => format!(
            "it samples its I/O lines every {v} ms and sends the samples on air, where a line \
             is set as an input"
        ),
        b"IC" => "it sends an I/O sample on air when one of these lines changes, where it is \
                  set as an input"
            .to_string(),
        _ => "not what hoploc expects".to_string(),
    }
}

/// What [`super::restore`] did, in a line.
pub fn describe_restore(r: &Restored, expect: &Expectation) -> String {
    let mut parts = Vec::new();
    parts.push(match r.bring_up {
        BringUp::AlreadyApi => {
            "the radio answered in API mode 2 at 57600 bit/s: AP and BD stay".to_string()
        }
        BringUp::Configured { baud } => format!(
            "set AP 2 and BD 6 in command mode at {baud} bit/s and saved them (WR), as a node \
             does"
        ),
    });
    let set: Vec<[u8; 2]> = REGISTERS
        .iter()
        .copied()
        .filter(|&cmd| {
            keeper(cmd) == Keeper::Boot && !matches!(expect.expected(cmd), Expected::PerRole)
        })
        .collect();
    let key = if matches!(expect.bring_up.encryption, Encryption::Key(_)) {
        " (and the key KY)"
    } else {
        ""
    };
    parts.push(format!("set {}{key}, as a node does at boot", names(&set)));
    if !r.factory.is_empty() {
        parts.push(format!(
            "set {} to the factory value (nodes leave {})",
            names(&r.factory),
            if r.factory.len() == 1 { "it" } else { "them" }
        ));
    }
    parts.push(if r.written {
        "saved everything (WR)".to_string()
    } else if r.factory.is_empty() {
        "saved nothing more: the radio keeps these until it loses power, and a node sets them at \
         every boot (--write saves them)"
            .to_string()
    } else {
        format!(
            "saved nothing more: the radio keeps these until it loses power; a node sets all but \
             {} at every boot (--write saves them)",
            names(&r.factory)
        )
    });
    parts.join("; ")
}
