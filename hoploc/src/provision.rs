//! `hoploc provision`: write a node's config into its EEPROM over the Uno's USB serial.
//!
//! Opening the port resets the Uno; its firmware writes `hoploc <role> boot` and then listens for
//! a provisioning frame for `loc_proto::provision::PROVISION_WINDOW_MS`. The host waits for that
//! line, checks the role, sends the frame (`loc_proto::provision::encode`) and waits for the ACK
//! (`HLA`) or NAK (`HLN` code). A node whose EEPROM holds a config it must not run with keeps
//! listening, so the same command fixes it.
//!
//! The exchange is a sans-IO [`Provisioner`] (bytes in, bytes to send out, a result), driven
//! either by [`drive`] over any `Read + Write` port in real time, or by a test over the firmware
//! in simavr in simulated time.

use std::fmt;
use std::io::{self, Read, Write};
use std::time::{Duration, Instant};

use loc_proto::config::{self, Config, NetworkKey, WRONG_ROLE};
use loc_proto::line::{BootLine, MAX_BOOT_LINE};
use loc_proto::msg::{ChannelList, Position};
use loc_proto::provision::{encode, Reply, MAX_FRAME, REPLY_LEN, WRITE_FAILED};
use loc_proto::Role;

/// How long to wait for the boot line after opening the port (the Uno's bootloader runs about
/// 1 s after the reset before it starts the firmware).
pub const BOOT_TIMEOUT: Duration = Duration::from_secs(5);
/// How long to wait for the ACK/NAK after sending the frame (an EEPROM write takes ~70 ms).
pub const REPLY_TIMEOUT: Duration = Duration::from_secs(2);

/// Why provisioning failed.
#[derive(Debug)]
pub enum ProvisionError {
    /// The config given on the command line is not valid (which field).
    InvalidConfig(loc_proto::Error),
    /// The slot is too short for a beacon of the network (`loc_proto::schedule::min_slot_ms`).
    SlotTooShort {
        /// The slot given, ms.
        slot_ms: u16,
        /// The network's anchors.
        anchors: u8,
    },
    /// The serial port could not be opened or used.
    Io(io::Error),
    /// No `hoploc <role> boot` line came in time: not a hoploc firmware, or the port does not
    /// reset the board (press its reset button while the command waits).
    NoBootLine,
    /// The node is another role's firmware: nothing was sent.
    WrongNode {
        /// The role its boot line names.
        found: Role,
        /// The role of the config.
        want: Role,
    },
    /// The node refused the config (its NAK code).
    Nak(u8),
    /// The frame was sent but no ACK/NAK came in time (the window may have closed: retry).
    NoReply,
}

/// What a NAK code means (the codes of `loc_proto::Error::code`, `WRONG_ROLE`, `WRITE_FAILED`).
pub fn nak_meaning(code: u8) -> &'static str {
    match code {
        1 => "frame too short",
        2 => "bad magic byte",
        3 => "the node speaks another config version (update its firmware or hoploc)",
        5 => "bad length",
        6 => "a field is out of range",
        7 => "bad CRC (the frame was corrupted on the way)",
        WRONG_ROLE => "the config is for another role than the node's firmware",
        WRITE_FAILED => "the EEPROM did not read back what was written (failing EEPROM?)",
        _ => "unknown code",
    }
}

impl fmt::Display for ProvisionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ProvisionError::InvalidConfig(loc_proto::Error::BadValue { field }) => {
                write!(f, "invalid config: {}", field_range(*field))
            }
            ProvisionError::InvalidConfig(e) => write!(f, "invalid config: {e}"),
            ProvisionError::SlotTooShort { slot_ms, anchors } => write!(
                f,
                "invalid config: a {slot_ms} ms slot cannot hold a beacon of {anchors} anchors \
                 (its guard and the beacon's way over the UARTs and the air): at least {} ms",
                loc_proto::schedule::min_slot_ms(*anchors)
            ),
            ProvisionError::Io(e) => write!(f, "serial port: {e}"),
            ProvisionError::NoBootLine => write!(
                f,
                "no `hoploc <role> boot` line within {} s: is a hoploc firmware on the board? \
                 (if the port does not reset it, press its reset button while this waits)",
                BOOT_TIMEOUT.as_secs()
            ),
            ProvisionError::WrongNode { found, want } => write!(
                f,
                "the node runs the {} firmware, not the {} one: nothing was sent",
                found.name(),
                want.name()
            ),
            ProvisionError::Nak(code) => {
                write!(
                    f,
                    "the node refused the config: NAK {code} ({})",
                    nak_meaning(*code)
                )
            }
            ProvisionError::NoReply => write!(
                f,
                "no answer within {} s of sending the frame (retry)",
                REPLY_TIMEOUT.as_secs()
            ),
        }
    }
}

impl std::error::Error for ProvisionError {}

/// The option behind a config field the node would refuse, and the values it takes.
pub fn field_range(field: loc_proto::error::Field) -> &'static str {
    use loc_proto::error::Field;
    match field {
        Field::AnchorId | Field::NodeId => {
            "--id: an anchor's id is 1…N (N = --anchors), an agent's or a sink's 1…255"
        }
        Field::AgentId => "--id: an agent's id is 1…255",
        Field::Anchors => "--anchors: 3…8",
        Field::Channel | Field::ChannelCount | Field::DuplicateChannel => {
            "--channels: 1…4 distinct channels 1…16"
        }
        Field::SlotLength => {
            "--slot-ms: up to 10000, and at least 17 with 3 or 4 anchors, 18 with 5…7, 19 with 8"
        }
        Field::SinkChannel => "--sink-channel: 1…16",
        Field::PanId => "--pan: any PAN id but 0xFFFF",
        Field::Role => "--role: anchor, agent or sink",
        Field::RelayCount | Field::SelfRssi | Field::Flags | Field::RelayRows => {
            "a field out of range"
        }
    }
}

impl From<io::Error> for ProvisionError {
    fn from(e: io::Error) -> Self {
        ProvisionError::Io(e)
    }
}

/// Where the exchange is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    AwaitBoot,
    AwaitReply,
    Done,
}

/// The host side of provisioning, sans IO: feed it what the node writes ([`Provisioner::receive`]),
/// send what it returns, call [`Provisioner::timed_out`] when the current wait is over.
#[derive(Debug)]
pub struct Provisioner {
    config: Config,
    frame: Vec<u8>,
    phase: Phase,
    /// Bytes of the current text line (before the frame is sent) or of the reply (after).
    pending: Vec<u8>,
    /// Every complete text line the node wrote.
    lines: Vec<String>,
    result: Option<Result<(), ProvisionError>>,
}

impl Provisioner {
    /// A provisioner for `config` (validated and encoded here).
    pub fn new(config: Config) -> Result<Provisioner, ProvisionError> {
        let mut buf = [0u8; MAX_FRAME];
        let slot_too_short = |e| match e {
            loc_proto::Error::BadValue {
                field: loc_proto::error::Field::SlotLength,
            } if config.slot_ms <= loc_proto::config::MAX_SLOT_MS => ProvisionError::SlotTooShort {
                slot_ms: config.slot_ms,
                anchors: config.anchors,
            },
            e => ProvisionError::InvalidConfig(e),
        };
        let n = encode(&config, &mut buf).map_err(slot_too_short)?;
        Ok(Provisioner {
            config,
            frame: buf[..n].to_vec(),
            phase: Phase::AwaitBoot,
            pending: Vec::new(),
            lines: Vec::new(),
            result: None,
        })
    }

    /// The provisioning frame.
    pub fn frame(&self) -> &[u8] {
        &self.frame
    }

    /// Whether the frame has been handed out (the wait is for the reply now).
    pub fn sent(&self) -> bool {
        self.phase != Phase::AwaitBoot
    }

    /// The text lines the node wrote so far.
    pub fn lines(&self) -> &[String] {
        &self.lines
    }

    /// The outcome, once there is one.
    pub fn result(&self) -> Option<&Result<(), ProvisionError>> {
        self.result.as_ref()
    }

    /// Takes the outcome, once there is one.
    pub fn take_result(&mut self) -> Option<Result<(), ProvisionError>> {
        self.result.take()
    }

    fn finish(&mut self, r: Result<(), ProvisionError>) {
        self.phase = Phase::Done;
        self.result = Some(r);
    }

    /// Feeds bytes the node wrote; returns the bytes to send it now (the frame, right after its
    /// boot line), if any.
    pub fn receive(&mut self, bytes: &[u8]) -> Option<Vec<u8>> {
        let mut send = None;
        for &b in bytes {
            match self.phase {
                Phase::Done => {}
                Phase::AwaitBoot => {
                    if b != b'\n' {
                        // A line longer than any boot line is noise: only its end is kept, so
                        // bytes that never end a line cannot grow the memory.
                        if self.pending.len() >= MAX_BOOT_LINE {
                            self.pending.remove(0);
                        }
                        self.pending.push(b);
                        continue;
                    }
                    let line = String::from_utf8_lossy(&self.pending).trim().to_string();
                    self.pending.clear();
                    let boot = BootLine::parse(&line);
                    self.lines.push(line);
                    if let Ok(BootLine::Boot { role }) = boot {
                        if role != self.config.role {
                            self.finish(Err(ProvisionError::WrongNode {
                                found: role,
                                want: self.config.role,
                            }));
                        } else {
                            self.phase = Phase::AwaitReply;
                            send = Some(self.frame.clone());
                        }
                    }
                }
                Phase::AwaitReply => {
                    self.pending.push(b);
                    if self.pending.len() > REPLY_LEN {
                        self.pending.remove(0);
                    }
                    match Reply::parse(&self.pending) {
                        Some(Reply::Ack) => self.finish(Ok(())),
                        Some(Reply::Nak(code)) => self.finish(Err(ProvisionError::Nak(code))),
                        None => {}
                    }
                }
            }
        }
        send
    }

    /// The current wait is over: no boot line, or no reply.
    pub fn timed_out(&mut self) {
        match self.phase {
            Phase::AwaitBoot => self.finish(Err(ProvisionError::NoBootLine)),
            Phase::AwaitReply => self.finish(Err(ProvisionError::NoReply)),
            Phase::Done => {}
        }
    }
}

/// Runs `prov` over `port` in real time: reads (a read timeout is fine), sends the frame when it
/// asks, and times out after [`BOOT_TIMEOUT`] without the boot line or [`REPLY_TIMEOUT`] without
/// the reply. `on_line` sees every text line the node writes.
pub fn drive<P: Read + Write>(
    port: &mut P,
    prov: &mut Provisioner,
    boot_timeout: Duration,
    reply_timeout: Duration,
) -> Result<(), ProvisionError> {
    let mut deadline = Instant::now() + boot_timeout;
    let mut buf = [0u8; 256];
    loop {
        if let Some(r) = prov.take_result() {
            return r;
        }
        if Instant::now() >= deadline {
            prov.timed_out();
            continue;
        }
        let n = match port.read(&mut buf) {
            Ok(n) => n,
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock
                ) =>
            {
                0
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => 0,
            Err(e) => return Err(e.into()),
        };
        if let Some(frame) = prov.receive(&buf[..n]) {
            port.write_all(&frame)?;
            port.flush()?;
            deadline = Instant::now() + reply_timeout;
        }
    }
}

/// `hoploc provision`'s options.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The Uno's serial port (opening it resets the board).
    #[arg(long)]
    pub port: String,
    /// The firmware on the board: anchor, agent or sink.
    #[arg(long, value_parser = parse_role)]
    pub role: Role,
    /// Node id: 1…N for an anchor, 1…255 for an agent or a sink.
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..))]
    pub id: u8,
    /// The rest of the node's config.
    #[command(flatten)]
    pub node: NodeOptions,
}

/// A node's config options besides its role and id, with their defaults: `hoploc provision`'s,
/// and `hoploc radio`'s for the settings a node of that config gives its radio. Each needs
/// `--role` (which `provision` always has).
#[derive(clap::Args, Debug)]
pub struct NodeOptions {
    /// Position x in cm (anchors; for a sink the room width, 0 = the anchors' bounding box).
    #[arg(
        long,
        default_value_t = 0,
        allow_negative_numbers = true,
        requires = "role"
    )]
    pub x: i16,
    /// Position y in cm (anchors; for a sink the room height, 0 = the anchors' bounding box).
    #[arg(
        long,
        default_value_t = 0,
        allow_negative_numbers = true,
        requires = "role"
    )]
    pub y: i16,
    /// Number of anchors N in the network (3…8).
    #[arg(long, default_value_t = Config::DEFAULT.anchors, requires = "role",
          value_parser = clap::value_parser!(u8).range(3..=loc_proto::msg::MAX_ANCHORS as i64))]
    pub anchors: u8,
    /// TDMA slot length in ms (up to 10000; at least 17 with 3 or 4 anchors, 18 with 5…7, 19
    /// with 8: a slot must hold a beacon).
    #[arg(long, default_value_t = Config::DEFAULT.slot_ms, requires = "role",
          value_parser = clap::value_parser!(u16)
              .range(i64::from(config::MIN_SLOT_MS)..=i64::from(config::MAX_SLOT_MS)))]
    pub slot_ms: u16,
    /// Anchor channels in hop order, testbed channels 1…16 (channel n = 802.15.4 channel 10+n).
    /// Channel 1 does not exist on the XBee S1 Pro (2…13 only).
    #[arg(long, default_value = "1,12", value_parser = parse_channels, requires = "role")]
    pub channels: ChannelList,
    /// The agents' report channel to the sink (testbed channel 1…16).
    #[arg(long, default_value_t = Config::DEFAULT.sink_channel, requires = "role",
          value_parser = clap::value_parser!(u8).range(1..=i64::from(loc_proto::msg::MAX_CHANNEL)))]
    pub sink_channel: u8,
    /// PAN id, decimal or 0x-hex (not 0xFFFF).
    #[arg(long, default_value = "0x3332", value_parser = parse_pan, requires = "role")]
    pub pan: u16,
    /// Network key: 32 hex digits, the same on every node of the network. The node turns its
    /// radio's AES-128 encryption on with it; without --key, off. Keeps devices without the key
    /// out, but the XBee encrypts without an integrity check or replay protection (see
    /// docs/design.md). The key is stored in the board's EEPROM in the clear.
    #[arg(long, value_parser = parse_key, requires = "role")]
    pub key: Option<NetworkKey>,
}

fn parse_key(s: &str) -> Result<NetworkKey, String> {
    NetworkKey::parse(s).ok_or_else(|| {
        format!(
            "`{}…`: expected a network key of 32 hex digits (16 bytes)",
            s.chars().take(4).collect::<String>()
        )
    })
}

/// `--role`: anchor, agent or sink.
pub fn parse_role(s: &str) -> Result<Role, String> {
    Role::from_name(s).ok_or_else(|| format!("`{s}` is not a role: anchor, agent or sink"))
}

fn parse_channels(s: &str) -> Result<ChannelList, String> {
    config::parse_channels(s).map_err(|e| {
        format!("`{s}`: {e}; expected 1…4 distinct channels 1…16, comma separated (e.g. 1,12)")
    })
}

fn parse_pan(s: &str) -> Result<u16, String> {
    config::parse_pan(s)
        .ok_or_else(|| format!("`{s}`: expected a PAN id, decimal or 0x-hex, not 0xFFFF"))
}

impl Args {
    /// The config the options describe (not yet validated).
    pub fn config(&self) -> Config {
        self.node.config(self.role, self.id)
    }
}

impl NodeOptions {
    /// The config of node `id` of `role` with these options (not yet validated).
    pub fn config(&self, role: Role, id: u8) -> Config {
        Config {
            role,
            id,
            anchors: self.anchors,
            position: Position {
                x: self.x,
                y: self.y,
            },
            slot_ms: self.slot_ms,
            channels: self.channels,
            sink_channel: self.sink_channel,
            pan_id: self.pan,
            key: self.key,
        }
    }
}

/// One line describing `c`.
pub fn describe(c: &Config) -> String {
    let channels: Vec<String> = c.channels.as_slice().iter().map(u8::to_string).collect();
    let pos = if c.role == Role::Sink { "room" } else { "at" };
    format!(
        "{} {} {pos} ({}, {}) cm, {} anchors, {} ms slots, channels {}, sink channel {}, PAN {:#06x}, {}",
        c.role.name(),
        c.id,
        c.position.x,
        c.position.y,
        c.anchors,
        c.slot_ms,
        channels.join(","),
        c.sink_channel,
        c.pan_id,
        if c.key.is_some() {
            "encrypted (network key set)"
        } else {
            "not encrypted"
        }
    )
}

/// `hoploc provision`: open the port at 57600, provision, say how it went.
pub fn run(args: &Args) -> Result<(), ProvisionError> {
    let config = args.config();
    let mut prov = Provisioner::new(config)?;
    let mut port = serialport::new(&args.port, 57_600)
        .timeout(Duration::from_millis(20))
        .open()
        .map_err(|e| ProvisionError::Io(io::Error::other(format!("{}: {e}", args.port))))?;
    eprintln!("waiting for the node to boot on {}...", args.port);
    drive(&mut port, &mut prov, BOOT_TIMEOUT, REPLY_TIMEOUT)?;
    crate::out::Out::stdout()
        .line(format_args!("provisioned: {}", describe(&config)))
        .map_err(|e| ProvisionError::Io(io::Error::other(e)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn anchor2() -> Config {
        Config {
            id: 2,
            position: Position { x: 700, y: 0 },
            ..Config::DEFAULT
        }
    }

    #[test]
    fn sends_the_frame_after_the_boot_line_and_takes_the_ack() {
        let mut p = Provisioner::new(anchor2()).unwrap();
        assert_eq!(p.receive(b"\x00garbage\r\nhoploc anchor bo"), None);
        let frame = p.receive(b"ot\r\n").expect("the frame");
        assert_eq!(frame.len(), 27);
        assert_eq!(&frame[..3], b"HLP");
        assert!(p.result().is_none());
        assert_eq!(p.receive(b"HL"), None);
        assert!(p.result().is_none());
        p.receive(b"A\x01hoploc anchor provisioned\r\n");
        assert!(matches!(p.take_result(), Some(Ok(()))));
    }

    #[test]
    fn a_flood_without_newlines_keeps_little_and_the_boot_line_still_counts() {
        let mut p = Provisioner::new(anchor2()).unwrap();
        for _ in 0..1000 {
            assert_eq!(p.receive(&[b'x'; 1000]), None);
            assert!(p.pending.len() <= MAX_BOOT_LINE);
        }
        // The noise ends the line before the boot line; the boot line after it is read.
        assert_eq!(p.receive(b"\r\n"), None);
        assert!(p.receive(b"hoploc anchor boot\r\n").is_some());
    }

    #[test]
    fn an_invalid_config_names_the_option_and_its_range() {
        let e = Provisioner::new(Config { id: 9, ..anchor2() }).unwrap_err();
        assert!(e.to_string().contains("--id: an anchor's id is 1…N"), "{e}");
    }

    #[test]
    fn nak_wrong_node_and_timeouts_are_typed() {
        let mut p = Provisioner::new(anchor2()).unwrap();
        p.receive(b"hoploc anchor boot\r\nHLN\x0A");
        assert!(matches!(
            p.take_result(),
            Some(Err(ProvisionError::Nak(10)))
        ));

        let mut p = Provisioner::new(anchor2()).unwrap();
        assert_eq!(p.receive(b"hoploc sink boot\r\n"), None);
        assert!(matches!(
            p.take_result(),
            Some(Err(ProvisionError::WrongNode {
                found: Role::Sink,
                want: Role::Anchor
            }))
        ));

        let mut p = Provisioner::new(anchor2()).unwrap();
        p.receive(b"hoploc anchor radio ok api\r\n");
        p.timed_out();
        assert!(matches!(
            p.take_result(),
            Some(Err(ProvisionError::NoBootLine))
        ));

        let mut p = Provisioner::new(anchor2()).unwrap();
        p.receive(b"hoploc anchor boot\r\nHLX\x01");
        p.timed_out();
        assert!(matches!(
            p.take_result(),
            Some(Err(ProvisionError::NoReply))
        ));

        let bad = Config {
            id: 9,
            ..Config::DEFAULT
        };
        assert!(matches!(
            Provisioner::new(bad),
            Err(ProvisionError::InvalidConfig(_))
        ));
        // A slot too short for the network's beacons: refused before anything is sent, saying
        // how long a slot it needs.
        let short = Config {
            anchors: 7,
            slot_ms: 14,
            ..Config::DEFAULT
        };
        let Err(e) = Provisioner::new(short) else {
            panic!("a 14 ms slot for 7 anchors is accepted");
        };
        assert!(matches!(
            e,
            ProvisionError::SlotTooShort {
                slot_ms: 14,
                anchors: 7
            }
        ));
        assert!(e.to_string().contains("at least 18 ms"), "{e}");
    }

    /// A port that answers like a node: the boot line at once, the ACK once the frame is in.
    struct FakeNode {
        out: Vec<u8>,
        got: Vec<u8>,
    }

    impl Read for FakeNode {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            if self.out.is_empty() {
                return Err(io::ErrorKind::TimedOut.into());
            }
            let n = self.out.len().min(buf.len());
            buf[..n].copy_from_slice(&self.out[..n]);
            self.out.drain(..n);
            Ok(n)
        }
    }

    impl Write for FakeNode {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            self.got.extend_from_slice(buf);
            let mut parser = loc_proto::provision::ProvisionParser::new();
            for &b in &self.got {
                if let Some(r) = parser.push(b) {
                    let (reply, _) = loc_proto::provision::answer(r, Role::Anchor);
                    self.out.extend_from_slice(&reply.bytes());
                }
            }
            Ok(buf.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn drive_over_a_port() {
        let mut node = FakeNode {
            out: b"hoploc anchor boot\r\n".to_vec(),
            got: Vec::new(),
        };
        let mut p = Provisioner::new(anchor2()).unwrap();
        let r = drive(
            &mut node,
            &mut p,
            Duration::from_secs(1),
            Duration::from_secs(1),
        );
        assert!(r.is_ok(), "{r:?}");
        assert_eq!(node.got, p.frame());

        // A silent port: the boot timeout.
        let mut node = FakeNode {
            out: Vec::new(),
            got: Vec::new(),
        };
        let mut p = Provisioner::new(anchor2()).unwrap();
        let r = drive(
            &mut node,
            &mut p,
            Duration::from_millis(50),
            Duration::from_secs(1),
        );
        assert!(matches!(r, Err(ProvisionError::NoBootLine)), "{r:?}");
        assert!(node.got.is_empty());
    }
}
