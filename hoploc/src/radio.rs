//! `hoploc radio`: an XBee 802.15.4 (S1) on a USB adapter, read without changing anything,
//! compared with what hoploc expects ([`report`]), and restored.
//!
//! * [`read`] finds the radio at every baud rate the S1 can be set to, at the rate it really
//!   runs ([`xbee_api::driver::BAUD_CODES`]: `BD=7` is 111 111 bit/s), in whatever mode it is:
//!   first an `AP` query in API mode at each rate (a radio in API mode 1 or 2 answers it with its
//!   mode), then command mode at each rate (a guard time of silence, `+++`, a guard time, `OK`),
//!   where it reads the registers with `ATxx` queries and leaves with `ATCN`. It sets nothing
//!   and writes nothing. A radio in transparent mode sends what reaches it on air as data: the
//!   `AP` query at its own rate, and what it makes of the bytes sent at other rates, go out as
//!   a few short packets, as at a node's bring-up.
//! * [`restore`] gives the radio what a node gives it at every boot ([`Radio::bring_up`] with
//!   the role's [`loc_proto::config::radio_settings`]), then the factory value of each register
//!   nodes leave alone that differs from it ([`report::Keeper::Left`]), and with `write` saves it
//!   all (`WR`); before and after, it [`read`]s the radio.
//! * Both are generic over the `embedded-hal-nb` serial traits and a [`Clock`], as the driver
//!   is: [`port::UsbPort`] and [`port::WallClock`] run them on a serial port in real time,
//!   [`port::ModelPort`] on the modelled XBee of `simavr` in simulated time (the tests).

pub mod port;
pub mod report;

use std::fmt;
use std::time::Duration;

use embedded_hal_nb::serial::{Error as _, ErrorType, Read, Write};
use loc_proto::Role;
use xbee_api::driver::{
    baud_of_bd, BringUp, Clock, Error as DriverError, Radio, SetBaud, BAUD_CODES, WRITE_TIMEOUT_MS,
};
use xbee_api::Mode;

use crate::provision::{self, NodeOptions, ProvisionError};
pub use report::{Expectation, Report};

/// How long [`read`] and [`restore`] wait. [`Patience::DEFAULT`] is what a node's bring-up
/// waits ([`xbee_api::driver::BringUpConfig::new`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Patience {
    /// Silence before and after `+++`: more than the radio's guard time `GT` (factory 1 s).
    pub guard_ms: u16,
    /// How long to wait for each answer (an API response, a command-mode line).
    pub timeout_ms: u16,
}

impl Patience {
    /// A node's bring-up's: 1100 ms guard time, 500 ms per answer.
    pub const DEFAULT: Patience = {
        let b = xbee_api::driver::BringUpConfig::new();
        Patience {
            guard_ms: b.guard_ms,
            timeout_ms: b.timeout_ms,
        }
    };
}

impl Default for Patience {
    fn default() -> Self {
        Patience::DEFAULT
    }
}

/// The registers [`read`] reads, in the order [`report::Report`] shows them: the mode and rate,
/// what a node sets at every boot, what nodes leave alone but changes how the radio behaves,
/// and what identifies the radio (see [`report::keeper`]).
pub const REGISTERS: [[u8; 2]; 24] = [
    *b"AP", *b"BD", *b"MY", *b"ID", *b"CH", *b"RN", *b"CA", *b"EE", *b"RR", *b"MM", *b"SM", *b"A1",
    *b"PL", *b"CE", *b"A2", *b"NB", *b"GT", *b"CC", *b"IR", *b"IC", *b"VR", *b"HV", *b"SH", *b"SL",
];

/// Where and how [`read`] found the radio.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Found {
    /// It answered an `AP` query in API mode `mode` at the rate of `BD` value `bd`.
    Api {
        /// The `BD` value of the rate.
        bd: u8,
        /// Its API mode.
        mode: Mode,
    },
    /// It answered `+++` in command mode at the rate of `BD` value `bd` (and no API frame).
    CommandMode {
        /// The `BD` value of the rate.
        bd: u8,
    },
}

impl Found {
    /// The `BD` value of the rate it answered at.
    pub fn bd(self) -> u8 {
        match self {
            Found::Api { bd, .. } | Found::CommandMode { bd } => bd,
        }
    }
}

impl fmt::Display for Found {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let rate = baud_of_bd(self.bd());
        match *self {
            Found::Api { bd, mode } => {
                write!(f, "in API mode {} at {rate} bit/s (BD {bd})", mode.ap())
            }
            Found::CommandMode { bd } => write!(
                f,
                "in command mode at {rate} bit/s (BD {bd}); it answered no API frame"
            ),
        }
    }
}

/// What the radio answered to one register's query.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Answer {
    /// Its value.
    Value(u32),
    /// It refused the query (an error status, or `ERROR` in command mode): a register its
    /// firmware does not have.
    Refused,
    /// No answer in time, or one that is no number.
    Silent,
}

impl Answer {
    /// The value, if it answered one.
    pub fn value(self) -> Option<u32> {
        match self {
            Answer::Value(v) => Some(v),
            _ => None,
        }
    }
}

/// What [`read`] found: how the radio answered, and each of [`REGISTERS`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reading {
    /// Where and how it answered.
    pub found: Found,
    /// Each of [`REGISTERS`], in that order, with its answer.
    pub values: Vec<([u8; 2], Answer)>,
    /// Command mode only: the radio did not answer `ATCN`, so it stays in command mode until
    /// its `CT` timeout (factory 10 s) ends it.
    pub still_in_command_mode: bool,
}

impl Reading {
    /// The answer for register `cmd` (`Silent` for one [`read`] does not read).
    pub fn answer(&self, cmd: [u8; 2]) -> Answer {
        self.values
            .iter()
            .find(|(c, _)| *c == cmd)
            .map_or(Answer::Silent, |&(_, a)| a)
    }

    /// The value of register `cmd`, if the radio answered one.
    pub fn value(&self, cmd: [u8; 2]) -> Option<u32> {
        self.answer(cmd).value()
    }
}

/// Why `hoploc radio` failed. Every variant says what to check.
#[derive(Debug)]
pub enum RadioError {
    /// The config the options describe is not one a node runs with.
    Config(ProvisionError),
    /// The serial port could not be opened.
    Open {
        /// The port's name.
        port: String,
        /// Why.
        reason: String,
    },
    /// The serial port failed while in use (unplugged?).
    Port(String),
    /// Nothing at all came back, at any baud rate, in API or command mode.
    NoResponse,
    /// Bytes came back, but never an answer of a radio, at any baud rate.
    Garbage,
    /// [`restore`]: a step of the radio's bring-up, or setting a register, failed.
    Restore(DriverError),
    /// `--restore`: the radio still differs afterwards in these registers.
    StillDiffers(Vec<[u8; 2]>),
}

impl fmt::Display for RadioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RadioError::Config(e) => write!(f, "{e}"),
            RadioError::Open { port, reason } => write!(f, "serial port {port}: {reason}"),
            RadioError::Port(e) => write!(f, "serial port: {e}"),
            RadioError::NoResponse => f.write_str(
                "no answer from a radio at any baud rate, in API or command mode: is the XBee \
                 seated in the adapter (both rows of pins, turned as the outline shows) and is \
                 this the adapter's port? (A radio in transparent mode with a guard time GT of \
                 1.1 s or more answers neither, here or on a node: Digi's XCTU finds it.)",
            ),
            RadioError::Garbage => f.write_str(
                "bytes came back at some baud rate, but never a radio's answer: is another \
                 device on this port (an Uno's own serial, say), or a radio with parity on \
                 (NB)?",
            ),
            RadioError::Restore(
                e @ DriverError::At {
                    command: [b'C', b'H'],
                    ..
                },
            ) => write!(
                f,
                "restoring the radio: {e}: an XBee S1 Pro has no channel 1 (CH 0x0B): give every \
                 node --channels without 1 (2,12, say)"
            ),
            RadioError::Restore(e) => write!(f, "restoring the radio: {e}"),
            RadioError::StillDiffers(cmds) => write!(
                f,
                "after restoring, the radio still differs in {}",
                report::names(cmds)
            ),
        }
    }
}

impl std::error::Error for RadioError {}

impl From<ProvisionError> for RadioError {
    fn from(e: ProvisionError) -> Self {
        RadioError::Config(e)
    }
}

/// A serial port that notes whether any byte came in.
struct Tap<'a, S> {
    inner: &'a mut S,
    heard: bool,
}

impl<S: ErrorType> ErrorType for Tap<'_, S> {
    type Error = S::Error;
}

impl<S: Read<u8>> Read<u8> for Tap<'_, S> {
    fn read(&mut self) -> nb::Result<u8, S::Error> {
        let r = self.inner.read();
        if r.is_ok() {
            self.heard = true;
        }
        r
    }
}

impl<S: Write<u8>> Write<u8> for Tap<'_, S> {
    fn write(&mut self, b: u8) -> nb::Result<(), S::Error> {
        self.inner.write(b)
    }
    fn flush(&mut self) -> nb::Result<(), S::Error> {
        self.inner.flush()
    }
}

/// The driver's error as [`read`]'s, where it ends the search: the port failed.
fn port_failed(e: DriverError) -> Option<RadioError> {
    match e {
        DriverError::Serial(kind) => Some(RadioError::Port(format!("{kind:?}"))),
        DriverError::WriteTimeout => Some(RadioError::Port(
            "it did not take a byte in time".to_string(),
        )),
        _ => None,
    }
}

/// Finds the radio and reads [`REGISTERS`], changing nothing (see the module docs): API mode at
/// every rate, then command mode at every rate. [`RadioError::NoResponse`] if nothing came back
/// at all, [`RadioError::Garbage`] if bytes did but never an answer.
pub fn read<S, C>(serial: &mut S, clock: &mut C, patience: Patience) -> Result<Reading, RadioError>
where
    S: Read<u8> + Write<u8> + SetBaud,
    C: Clock,
{
    let timeout = u32::from(patience.timeout_ms);
    let mut heard = false;
    for bd in BAUD_CODES {
        serial.set_bd(bd);
        let tap = Tap {
            inner: &mut *serial,
            heard: false,
        };
        // Escaped frames: the `AP` query and its answer hold no byte that needs escaping, so a
        // radio in either API mode takes the query and its answer reads the same.
        let mut radio = Radio::new(tap, &mut *clock, Mode::Escaped);
        let answer = radio.at_command(*b"AP", &[], timeout, |_| {});
        heard |= radio.serial_mut().heard;
        let mode = match answer {
            Ok(v) => match v.as_u32() {
                Some(1) => Mode::Api,
                Some(2) => Mode::Escaped,
                _ => continue,
            },
            Err(e) => match port_failed(e) {
                Some(e) => return Err(e),
                None => continue,
            },
        };
        radio.set_mode(mode);
        let mut values = Vec::with_capacity(REGISTERS.len());
        for cmd in REGISTERS {
            values.push((cmd, query_api(&mut radio, cmd, timeout)?));
        }
        return Ok(Reading {
            found: Found::Api { bd, mode },
            values,
            still_in_command_mode: false,
        });
    }
    for bd in BAUD_CODES {
        serial.set_bd(bd);
        let mut line = Line {
            serial: &mut *serial,
            clock: &mut *clock,
            heard: false,
        };
        let found = line.enter(patience)?;
        heard |= line.heard;
        if !found {
            continue;
        }
        let mut values = Vec::with_capacity(REGISTERS.len());
        for cmd in REGISTERS {
            values.push((cmd, line.query(cmd, patience.timeout_ms)?));
        }
        line.send(b"ATCN\r")?;
        let left = line.reply(patience.timeout_ms)? == Reply::Ok;
        return Ok(Reading {
            found: Found::CommandMode { bd },
            values,
            still_in_command_mode: !left,
        });
    }
    Err(if heard {
        RadioError::Garbage
    } else {
        RadioError::NoResponse
    })
}

/// Queries register `cmd` in API mode (twice if the first gets no answer).
fn query_api<S, C>(
    radio: &mut Radio<S, C, Mode>,
    cmd: [u8; 2],
    timeout: u32,
) -> Result<Answer, RadioError>
where
    S: Read<u8> + Write<u8>,
    C: Clock,
{
    for _ in 0..2 {
        match radio.at_command(cmd, &[], timeout, |_| {}) {
            Ok(v) => return Ok(v.as_u32().map_or(Answer::Silent, Answer::Value)),
            Err(DriverError::At { .. }) => return Ok(Answer::Refused),
            Err(e) => {
                if let Some(e) = port_failed(e) {
                    return Err(e);
                }
            }
        }
    }
    Ok(Answer::Silent)
}

/// A command-mode answer line.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Reply {
    /// `OK`.
    Ok,
    /// `ERROR`.
    Error,
    /// Another line (a query's value).
    Line(String),
    /// Nothing in time.
    Silent,
}

/// The radio's UART in command mode: text lines ending in `\r`.
struct Line<'a, S, C> {
    serial: &'a mut S,
    clock: &'a mut C,
    /// Any byte came in.
    heard: bool,
}

impl<S, C> Line<'_, S, C>
where
    S: Read<u8> + Write<u8>,
    C: Clock,
{
    fn elapsed(&mut self, start: u32) -> u32 {
        self.clock.now_ms().wrapping_sub(start)
    }

    fn read_byte(&mut self) -> Result<Option<u8>, RadioError> {
        match self.serial.read() {
            Ok(b) => {
                self.heard = true;
                Ok(Some(b))
            }
            Err(nb::Error::WouldBlock) => Ok(None),
            Err(nb::Error::Other(e)) => Err(RadioError::Port(format!("{:?}", e.kind()))),
        }
    }

    /// Reads and drops whatever comes for `ms`.
    fn quiet(&mut self, ms: u16) -> Result<(), RadioError> {
        let start = self.clock.now_ms();
        while self.elapsed(start) < u32::from(ms) {
            self.read_byte()?;
        }
        Ok(())
    }

    fn send(&mut self, bytes: &[u8]) -> Result<(), RadioError> {
        for &b in bytes {
            let start = self.clock.now_ms();
            loop {
                match self.serial.write(b) {
                    Ok(()) => break,
                    Err(nb::Error::WouldBlock) if self.elapsed(start) < WRITE_TIMEOUT_MS => {}
                    Err(nb::Error::WouldBlock) => {
                        return Err(RadioError::Port(
                            "it did not take a byte in time".to_string(),
                        ))
                    }
                    Err(nb::Error::Other(e)) => {
                        return Err(RadioError::Port(format!("{:?}", e.kind())))
                    }
                }
            }
        }
        let _ = self.serial.flush();
        Ok(())
    }

    /// The next line within `ms` (without its `\r`; bytes that are no printable ASCII make it
    /// garbage, which no answer matches).
    fn reply(&mut self, ms: u16) -> Result<Reply, RadioError> {
        let start = self.clock.now_ms();
        let mut line = Vec::new();
        while self.elapsed(start) < u32::from(ms) {
            match self.read_byte()? {
                Some(b'\r') => {
                    let text = String::from_utf8_lossy(&line).into_owned();
                    return Ok(match text.as_str() {
                        "OK" => Reply::Ok,
                        "ERROR" => Reply::Error,
                        _ => Reply::Line(text),
                    });
                }
                // A line longer than any answer is noise: keep its end only.
                Some(b) => {
                    if line.len() >= 32 {
                        line.remove(0);
                    }
                    line.push(b);
                }
                None => {}
            }
        }
        Ok(Reply::Silent)
    }

    /// Tries to enter command mode: guard time, `+++`, `OK` within the guard time and the
    /// timeout. True if the radio answered `OK`.
    fn enter(&mut self, patience: Patience) -> Result<bool, RadioError> {
        self.quiet(patience.guard_ms)?;
        self.send(b"+++")?;
        let start = self.clock.now_ms();
        let wait = u32::from(patience.guard_ms) + u32::from(patience.timeout_ms);
        while self.elapsed(start) < wait {
            let left = wait - self.elapsed(start).min(wait);
            match self.reply(left.min(u32::from(u16::MAX)) as u16)? {
                Reply::Ok => return Ok(true),
                // Bytes before the `OK` on its line (garbage from the rate switch) do not
                // count against it.
                Reply::Line(l) if l.ends_with("OK") => return Ok(true),
                Reply::Silent => return Ok(false),
                Reply::Error | Reply::Line(_) => {}
            }
        }
        Ok(false)
    }

    /// Queries `cmd` with `ATxx\r`: its value in hex, `ERROR`, or nothing.
    fn query(&mut self, cmd: [u8; 2], timeout_ms: u16) -> Result<Answer, RadioError> {
        self.send(&[b'A', b'T', cmd[0], cmd[1], b'\r'])?;
        Ok(match self.reply(timeout_ms)? {
            Reply::Line(text) => parse_hex(&text).map_or(Answer::Silent, Answer::Value),
            Reply::Error => Answer::Refused,
            Reply::Ok | Reply::Silent => Answer::Silent,
        })
    }
}

/// A command-mode value: hex digits (up to 8), as the radio answers a query.
fn parse_hex(text: &str) -> Option<u32> {
    let t = text.trim();
    if t.is_empty() || t.len() > 8 || !t.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    u32::from_str_radix(t, 16).ok()
}

/// What [`restore`] did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Restored {
    /// The radio before.
    pub before: Reading,
    /// How the bring-up found it (it writes `AP` and `BD` when it had to change them).
    pub bring_up: BringUp,
    /// The registers nodes leave alone that were set back to their factory value.
    pub factory: Vec<[u8; 2]>,
    /// Whether everything was saved with `WR`.
    pub written: bool,
    /// The radio after.
    pub after: Reading,
}

/// Gives the radio what a node of `expect` gives it at every boot ([`Radio::bring_up`]), then
/// the factory value of each register nodes leave alone that differs, then, with `write`, `WR`;
/// [`read`]s it before and after (a radio that refuses nothing is then as `expect` says:
/// `Report::new(&restored.after, expect).differing()` is empty).
pub fn restore<S, C>(
    serial: &mut S,
    clock: &mut C,
    expect: &Expectation,
    write: bool,
    patience: Patience,
) -> Result<Restored, RadioError>
where
    S: Read<u8> + Write<u8> + SetBaud,
    C: Clock,
{
    let before = read(serial, clock, patience)?;
    let timeout = u32::from(patience.timeout_ms);
    let mut cfg = expect.bring_up;
    cfg.guard_ms = patience.guard_ms;
    cfg.timeout_ms = patience.timeout_ms;
    let mut radio = Radio::new(&mut *serial, &mut *clock, Mode::Escaped);
    let bring_up = radio.bring_up(&cfg).map_err(RadioError::Restore)?;
    let mut factory = Vec::new();
    for (cmd, value) in Report::new(&before, expect).left_alone_differing() {
        radio
            .at_set(cmd, value, timeout, |_| {})
            .map_err(RadioError::Restore)?;
        factory.push(cmd);
    }
    if write {
        radio
            .at_set(*b"WR", &[], timeout, |_| {})
            .map_err(RadioError::Restore)?;
    }
    // The driver's borrows of the port and the clock end here.
    let _ = radio.release();
    let after = read(serial, clock, patience)?;
    Ok(Restored {
        before,
        bring_up,
        factory,
        written: write,
        after,
    })
}

/// `hoploc radio`'s options.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The XBee USB adapter's serial port (an XBee Explorer USB, a Digi XBIB-U…).
    #[arg(long)]
    pub port: String,
    /// Check against the settings a node of this role gives its radio (anchor, agent or sink;
    /// with --id and the node's options, as for `hoploc provision`). Without it: against what
    /// every node gives its radio.
    #[arg(long, value_parser = provision::parse_role, requires = "id")]
    pub role: Option<Role>,
    /// Node id (with --role): 1…N for an anchor, 1…255 for an agent or a sink.
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..), requires = "role")]
    pub id: Option<u8>,
    /// The rest of the node's config (with --role).
    #[command(flatten)]
    pub node: NodeOptions,
    /// Give the radio what a node gives it at every boot: API mode 2 at 57600 (AP, BD: saved
    /// with WR when they change, as a node does), then MY, ID, CH, RN, CA, EE and the key of
    /// the role (with --role), and RR 0, MM 0, SM 0, A1 0, PL 4; and the factory value of each
    /// register nodes leave alone that differs (CE, A2, NB, GT, CC, IR, IC). Reads the radio
    /// before and after.
    #[arg(long)]
    pub restore: bool,
    /// With --restore: save everything in the radio's flash (WR), so that it survives a power
    /// cycle. Nodes set all but the registers they leave alone at every boot anyway, and each
    /// WR wears the radio's flash: use it for a radio that keeps working on the adapter, or for
    /// a register nodes leave alone.
    #[arg(long, requires = "restore")]
    pub write: bool,
}

impl Args {
    /// What the radio is checked against: the role's node, or what every node sets.
    pub fn expectation(&self) -> Result<Expectation, RadioError> {
        match (self.role, self.id) {
            (Some(role), Some(id)) => {
                let config = self.node.config(role, id);
                // The same checks as `hoploc provision`'s, with its messages.
                provision::Provisioner::new(config)?;
                Ok(Expectation::node(config))
            }
            _ => Ok(Expectation::any_role()),
        }
    }
}

/// How long the serial port waits for a byte before a read says there is none.
const READ_WAIT: Duration = Duration::from_millis(2);

/// `hoploc radio`: open the port, read (and with `--restore`, restore) the radio, print the
/// report ([`check`]).
pub fn run(args: &Args) -> Result<(), String> {
    let expect = args.expectation().map_err(|e| e.to_string())?;
    let mut port = port::UsbPort::open(&args.port, READ_WAIT).map_err(|e| e.to_string())?;
    let mut clock = port::WallClock::new();
    eprintln!(
        "looking for the radio on {} (API mode, then command mode, at every baud rate: up to \
         half a minute)...",
        args.port
    );
    let checked = check(&mut port, &mut clock, args, &expect, Patience::DEFAULT)
        .map_err(|e| port.explain(e))?;
    crate::out::Out::stdout().write(format_args!("{}", checked.text))?;
    if checked.still_differs.is_empty() {
        Ok(())
    } else {
        Err(RadioError::StillDiffers(checked.still_differs).to_string())
    }
}

/// What [`check`] found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Checked {
    /// What `hoploc radio` prints: the table, the verdict; with `--restore` before and after.
    pub text: String,
    /// `--restore`: the registers that still differ afterwards.
    pub still_differs: Vec<[u8; 2]>,
}

/// `hoploc radio` on the radio on `serial` (named `args.port`), checked against `expect`:
/// [`read`] it, or with `args.restore` [`restore`] it.
pub fn check<S, C>(
    serial: &mut S,
    clock: &mut C,
    args: &Args,
    expect: &Expectation,
    patience: Patience,
) -> Result<Checked, RadioError>
where
    S: Read<u8> + Write<u8> + SetBaud,
    C: Clock,
{
    use std::fmt::Write as _;
    let mut text = String::new();
    let t = &mut text;
    if !args.restore {
        let reading = read(serial, clock, patience)?;
        let report = Report::new(&reading, expect);
        let _ = writeln!(
            t,
            "radio on {}: found {}; read without changing anything",
            args.port, reading.found
        );
        let _ = writeln!(t, "checked against: {}\n", expect.describe());
        let _ = writeln!(t, "{report}verdict: {}", report.verdict());
        if let Some(fix) = report.fix() {
            let _ = writeln!(t, "fix: {fix}");
        }
        if reading.still_in_command_mode {
            let _ = writeln!(
                t,
                "note: the radio did not answer ATCN: it leaves command mode by itself after \
                 its CT timeout (factory 10 s)"
            );
        }
        return Ok(Checked {
            text,
            still_differs: Vec::new(),
        });
    }
    let restored = restore(serial, clock, expect, args.write, patience)?;
    let before = Report::new(&restored.before, expect);
    let after = Report::new(&restored.after, expect);
    let _ = writeln!(t, "radio on {}: found {}", args.port, restored.before.found);
    let _ = writeln!(t, "checked against: {}\n", expect.describe());
    let _ = writeln!(t, "before:\n{before}verdict: {}\n", before.verdict());
    let _ = writeln!(
        t,
        "restore: {}\n",
        report::describe_restore(&restored, expect)
    );
    let _ = writeln!(t, "after:\n{after}verdict: {}", after.verdict());
    Ok(Checked {
        text,
        still_differs: after.differing(),
    })
}
