//! Typed, borrowed views of the XBee 802.15.4 API frame types.

use core::fmt;

/// 16-bit broadcast address.
pub const ADDR16_BROADCAST: u16 = 0xFFFF;
/// 64-bit broadcast address.
pub const ADDR64_BROADCAST: u64 = 0x0000_0000_0000_FFFF;

/// Received signal strength of an RX frame.
///
/// The radio sends the magnitude of the level in −dBm (a byte of 40 means −40 dBm); [`Rssi::dbm`]
/// gives the signed level, [`Rssi::raw`] the byte as sent.
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Rssi(pub u8);

impl Rssi {
    /// The level in dBm (always ≤ 0).
    pub const fn dbm(self) -> i16 {
        -(self.0 as i16)
    }
    /// The byte as the radio sent it (the magnitude in −dBm).
    pub const fn raw(self) -> u8 {
        self.0
    }
    /// The RSSI byte for a level in dBm; levels above 0 dBm or below −255 dBm are clamped.
    pub const fn from_dbm(dbm: i16) -> Rssi {
        let m = if dbm > 0 {
            0
        } else if dbm < -255 {
            255
        } else {
            -dbm
        };
        Rssi(m as u8)
    }
}

impl fmt::Debug for Rssi {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} dBm", self.dbm())
    }
}

macro_rules! status_byte {
    ($(#[$m:meta])* $name:ident { $($(#[$cm:meta])* $c:ident = $v:expr),* $(,)? }) => {
        $(#[$m])*
        ///
        /// Any byte is kept as it was received, so unknown values survive a round trip.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub struct $name(pub u8);
        impl $name {
            $($(#[$cm])* pub const $c: $name = $name($v);)*
        }
    };
}

status_byte!(
    /// Status of an AT command response.
    AtStatus {
        /// Command accepted.
        OK = 0,
        /// Command failed.
        ERROR = 1,
        /// Unknown command.
        INVALID_COMMAND = 2,
        /// Parameter out of range.
        INVALID_PARAMETER = 3,
        /// Remote command: no response from the remote radio.
        NO_RESPONSE = 4,
    }
);

impl AtStatus {
    /// True when the command was accepted.
    pub const fn is_ok(self) -> bool {
        self.0 == 0
    }
}

status_byte!(
    /// Delivery status of a transmit request.
    TxStatus {
        /// Sent (and acknowledged, for unicast).
        SUCCESS = 0,
        /// Unicast: no MAC acknowledgement after all retries.
        NO_ACK = 1,
        /// Clear channel assessment failed (channel busy).
        CCA_FAILURE = 2,
        /// Coordinator times out of an indirect transmission.
        PURGED = 3,
    }
);

status_byte!(
    /// Modem status events.
    ModemStatus {
        /// Power-up or hardware reset.
        HARDWARE_RESET = 0,
        /// Watchdog timer reset.
        WATCHDOG_RESET = 1,
        /// End device associated.
        ASSOCIATED = 2,
        /// End device disassociated.
        DISASSOCIATED = 3,
        /// Synchronisation lost.
        SYNC_LOST = 4,
        /// Coordinator realignment.
        COORDINATOR_REALIGNMENT = 5,
        /// Coordinator started.
        COORDINATOR_STARTED = 6,
    }
);

/// Frame type bytes of the 802.15.4 firmware.
pub(crate) mod ty {
    pub const TX64: u8 = 0x00;
    pub const TX16: u8 = 0x01;
    pub const AT: u8 = 0x08;
    pub const AT_QUEUE: u8 = 0x09;
    pub const REMOTE_AT: u8 = 0x17;
    pub const RX64: u8 = 0x80;
    pub const RX16: u8 = 0x81;
    pub const RX64_IO: u8 = 0x82;
    pub const RX16_IO: u8 = 0x83;
    pub const AT_RESPONSE: u8 = 0x88;
    pub const TX_STATUS: u8 = 0x89;
    pub const MODEM_STATUS: u8 = 0x8A;
    pub const REMOTE_AT_RESPONSE: u8 = 0x97;
}

/// One API frame of the 802.15.4 firmware, borrowing its variable part from the decoder's buffer
/// (or from the caller, when encoding).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Frame<'a> {
    /// 0x00: transmit to a 64-bit address.
    Tx64 {
        /// Frame id (0: no TX status).
        frame_id: u8,
        /// Destination (0xFFFF: broadcast).
        dest: u64,
        /// Options (0x01 disable ACK, 0x04 broadcast PAN id).
        options: u8,
        /// RF payload.
        data: &'a [u8],
    },
    /// 0x01: transmit to a 16-bit address.
    Tx16 {
        /// Frame id (0: no TX status).
        frame_id: u8,
        /// Destination (0xFFFF: broadcast).
        dest: u16,
        /// Options (0x01 disable ACK, 0x04 broadcast PAN id).
        options: u8,
        /// RF payload.
        data: &'a [u8],
    },
    /// 0x08: AT command, applied at once.
    AtCommand {
        /// Frame id (0: no response).
        frame_id: u8,
        /// Two-letter command.
        command: [u8; 2],
        /// Parameter (empty: query).
        parameter: &'a [u8],
    },
    /// 0x09: AT command, queued until `AC` or a 0x08 command.
    AtCommandQueue {
        /// Frame id (0: no response).
        frame_id: u8,
        /// Two-letter command.
        command: [u8; 2],
        /// Parameter (empty: query).
        parameter: &'a [u8],
    },
    /// 0x17: AT command for a remote radio.
    RemoteAtCommand {
        /// Frame id (0: no response).
        frame_id: u8,
        /// 64-bit destination.
        dest64: u64,
        /// 16-bit destination (0xFFFE: use the 64-bit address).
        dest16: u16,
        /// Command options (0x02: apply changes).
        options: u8,
        /// Two-letter command.
        command: [u8; 2],
        /// Parameter (empty: query).
        parameter: &'a [u8],
    },
    /// 0x80: received from a 64-bit source.
    Rx64 {
        /// Source address.
        source: u64,
        /// Signal strength.
        rssi: Rssi,
        /// Options (bit 1: address broadcast, bit 2: PAN broadcast).
        options: u8,
        /// RF payload.
        data: &'a [u8],
    },
    /// 0x81: received from a 16-bit source.
    Rx16 {
        /// Source address.
        source: u16,
        /// Signal strength.
        rssi: Rssi,
        /// Options (bit 1: address broadcast, bit 2: PAN broadcast).
        options: u8,
        /// RF payload.
        data: &'a [u8],
    },
    /// 0x82: I/O samples from a 64-bit source.
    Rx64Io {
        /// Source address.
        source: u64,
        /// Signal strength.
        rssi: Rssi,
        /// Options.
        options: u8,
        /// Sample data; [`IoSamples::parse`] reads it.
        data: &'a [u8],
    },
    /// 0x83: I/O samples from a 16-bit source.
    Rx16Io {
        /// Source address.
        source: u16,
        /// Signal strength.
        rssi: Rssi,
        /// Options.
        options: u8,
        /// Sample data; [`IoSamples::parse`] reads it.
        data: &'a [u8],
    },
    /// 0x88: response to a local AT command.
    AtResponse {
        /// Frame id of the command.
        frame_id: u8,
        /// Two-letter command.
        command: [u8; 2],
        /// Status.
        status: AtStatus,
        /// Register value (empty for a set command).
        data: &'a [u8],
    },
    /// 0x89: outcome of a transmit request.
    TxStatus {
        /// Frame id of the request.
        frame_id: u8,
        /// Delivery status.
        status: TxStatus,
    },
    /// 0x8A: modem status event.
    ModemStatus {
        /// The event.
        status: ModemStatus,
    },
    /// 0x97: response to a remote AT command.
    RemoteAtResponse {
        /// Frame id of the command.
        frame_id: u8,
        /// 64-bit address of the responder.
        source64: u64,
        /// 16-bit address of the responder.
        source16: u16,
        /// Two-letter command.
        command: [u8; 2],
        /// Status.
        status: AtStatus,
        /// Register value.
        data: &'a [u8],
    },
    /// Any other frame type, kept whole.
    Unknown {
        /// The frame type byte.
        frame_type: u8,
        /// The frame data after the type byte.
        data: &'a [u8],
    },
}

/// A frame of a known type whose data is shorter than its fixed fields.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParseError {
    /// The frame data was empty (no type byte).
    Empty,
    /// The frame data is shorter than the fixed fields of its type.
    TooShort {
        /// The frame type byte.
        frame_type: u8,
        /// Frame data length, type byte included.
        len: usize,
        /// The least legal length for this type.
        min: usize,
    },
    /// A fixed-size frame type (TX status, modem status) with bytes after its last field; they are
    /// not dropped silently, the raw frame keeps them.
    TooLong {
        /// The frame type byte.
        frame_type: u8,
        /// Frame data length, type byte included.
        len: usize,
        /// The length of this type.
        max: usize,
    },
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParseError::Empty => f.write_str("empty frame data"),
            ParseError::TooShort {
                frame_type,
                len,
                min,
            } => write!(
                f,
                "frame type {frame_type:#04x}: {len} bytes, at least {min} needed"
            ),
            ParseError::TooLong {
                frame_type,
                len,
                max,
            } => write!(
                f,
                "frame type {frame_type:#04x}: {len} bytes, at most {max} allowed"
            ),
        }
    }
}

impl core::error::Error for ParseError {}

/// Reads fixed fields off the front of the frame data.
struct Fields<'a>(&'a [u8]);

impl<'a> Fields<'a> {
    #[inline(never)]
    fn u8(&mut self) -> u8 {
        let (b, rest) = self.0.split_first().map_or((0, &[][..]), |(b, r)| (*b, r));
        self.0 = rest;
        b
    }
    fn u16(&mut self) -> u16 {
        u16::from_be_bytes([self.u8(), self.u8()])
    }
    #[inline(never)]
    fn u64(&mut self) -> u64 {
        let mut v = 0u64;
        for _ in 0..8 {
            v = (v << 8) | self.u8() as u64;
        }
        v
    }
    fn cmd(&mut self) -> [u8; 2] {
        [self.u8(), self.u8()]
    }
}

/// Fixed bytes (type byte included) of each known frame type.
const fn fixed_len(frame_type: u8) -> Option<usize> {
    Some(match frame_type {
        ty::TX64 => 11,
        ty::TX16 => 5,
        ty::AT | ty::AT_QUEUE => 4,
        ty::REMOTE_AT => 15,
        ty::RX64 | ty::RX64_IO => 11,
        ty::RX16 | ty::RX16_IO => 5,
        ty::AT_RESPONSE => 5,
        ty::TX_STATUS => 3,
        ty::MODEM_STATUS => 2,
        ty::REMOTE_AT_RESPONSE => 15,
        _ => return None,
    })
}

impl<'a> Frame<'a> {
    /// Reads frame data (type byte first, checksum excluded).
    pub fn parse(frame_data: &'a [u8]) -> Result<Frame<'a>, ParseError> {
        let (&t, body) = frame_data.split_first().ok_or(ParseError::Empty)?;
        let Some(min) = fixed_len(t) else {
            return Ok(Frame::Unknown {
                frame_type: t,
                data: body,
            });
        };
        if frame_data.len() < min {
            return Err(ParseError::TooShort {
                frame_type: t,
                len: frame_data.len(),
                min,
            });
        }
        if matches!(t, ty::TX_STATUS | ty::MODEM_STATUS) && frame_data.len() > min {
            return Err(ParseError::TooLong {
                frame_type: t,
                len: frame_data.len(),
                max: min,
            });
        }
        let rest = &frame_data[min..];
        let mut f = Fields(body);
        Ok(match t {
            ty::TX64 => Frame::Tx64 {
                frame_id: f.u8(),
                dest: f.u64(),
                options: f.u8(),
                data: rest,
            },
            ty::TX16 => Frame::Tx16 {
                frame_id: f.u8(),
                dest: f.u16(),
                options: f.u8(),
                data: rest,
            },
            ty::AT => Frame::AtCommand {
                frame_id: f.u8(),
                command: f.cmd(),
                parameter: rest,
            },
            ty::AT_QUEUE => Frame::AtCommandQueue {
                frame_id: f.u8(),
                command: f.cmd(),
                parameter: rest,
            },
            ty::REMOTE_AT => Frame::RemoteAtCommand {
                frame_id: f.u8(),
                dest64: f.u64(),
                dest16: f.u16(),
                options: f.u8(),
                command: f.cmd(),
                parameter: rest,
            },
            ty::RX64 => Frame::Rx64 {
                source: f.u64(),
                rssi: Rssi(f.u8()),
                options: f.u8(),
                data: rest,
            },
            ty::RX16 => Frame::Rx16 {
                source: f.u16(),
                rssi: Rssi(f.u8()),
                options: f.u8(),
                data: rest,
            },
            ty::RX64_IO => Frame::Rx64Io {
                source: f.u64(),
                rssi: Rssi(f.u8()),
                options: f.u8(),
                data: rest,
            },
            ty::RX16_IO => Frame::Rx16Io {
                source: f.u16(),
                rssi: Rssi(f.u8()),
                options: f.u8(),
                data: rest,
            },
            ty::AT_RESPONSE => Frame::AtResponse {
                frame_id: f.u8(),
                command: f.cmd(),
                status: AtStatus(f.u8()),
                data: rest,
            },
            ty::TX_STATUS => Frame::TxStatus {
                frame_id: f.u8(),
                status: TxStatus(f.u8()),
            },
            ty::MODEM_STATUS => Frame::ModemStatus {
                status: ModemStatus(f.u8()),
            },
            // Only REMOTE_AT_RESPONSE is left: fixed_len() knows no other type.
            _ => Frame::RemoteAtResponse {
                frame_id: f.u8(),
                source64: f.u64(),
                source16: f.u16(),
                command: f.cmd(),
                status: AtStatus(f.u8()),
                data: rest,
            },
        })
    }

    /// The frame type byte.
    pub const fn frame_type(&self) -> u8 {
        match self {
            Frame::Tx64 { .. } => ty::TX64,
            Frame::Tx16 { .. } => ty::TX16,
            Frame::AtCommand { .. } => ty::AT,
            Frame::AtCommandQueue { .. } => ty::AT_QUEUE,
            Frame::RemoteAtCommand { .. } => ty::REMOTE_AT,
            Frame::Rx64 { .. } => ty::RX64,
            Frame::Rx16 { .. } => ty::RX16,
            Frame::Rx64Io { .. } => ty::RX64_IO,
            Frame::Rx16Io { .. } => ty::RX16_IO,
            Frame::AtResponse { .. } => ty::AT_RESPONSE,
            Frame::TxStatus { .. } => ty::TX_STATUS,
            Frame::ModemStatus { .. } => ty::MODEM_STATUS,
            Frame::RemoteAtResponse { .. } => ty::REMOTE_AT_RESPONSE,
            Frame::Unknown { frame_type, .. } => *frame_type,
        }
    }

    /// The frame id, for the types that carry one.
    pub const fn frame_id(&self) -> Option<u8> {
        match *self {
            Frame::Tx64 { frame_id, .. }
            | Frame::Tx16 { frame_id, .. }
            | Frame::AtCommand { frame_id, .. }
            | Frame::AtCommandQueue { frame_id, .. }
            | Frame::RemoteAtCommand { frame_id, .. }
            | Frame::AtResponse { frame_id, .. }
            | Frame::TxStatus { frame_id, .. }
            | Frame::RemoteAtResponse { frame_id, .. } => Some(frame_id),
            _ => None,
        }
    }

    /// The RSSI, for received frames.
    pub const fn rssi(&self) -> Option<Rssi> {
        match *self {
            Frame::Rx64 { rssi, .. }
            | Frame::Rx16 { rssi, .. }
            | Frame::Rx64Io { rssi, .. }
            | Frame::Rx16Io { rssi, .. } => Some(rssi),
            _ => None,
        }
    }

    /// Length of the frame data (type byte included, checksum excluded).
    pub fn data_len(&self) -> usize {
        let variable = match *self {
            Frame::Tx64 { data, .. }
            | Frame::Tx16 { data, .. }
            | Frame::Rx64 { data, .. }
            | Frame::Rx16 { data, .. }
            | Frame::Rx64Io { data, .. }
            | Frame::Rx16Io { data, .. }
            | Frame::AtResponse { data, .. }
            | Frame::RemoteAtResponse { data, .. }
            | Frame::Unknown { data, .. } => data.len(),
            Frame::AtCommand { parameter, .. }
            | Frame::AtCommandQueue { parameter, .. }
            | Frame::RemoteAtCommand { parameter, .. } => parameter.len(),
            Frame::TxStatus { .. } | Frame::ModemStatus { .. } => 0,
        };
        fixed_len(self.frame_type()).unwrap_or(1) + variable
    }
}

/// The fixed fields of a frame (type byte first): at most 15 bytes (remote AT command and
/// response).
pub(crate) struct Header {
    buf: [u8; 15],
    len: u8,
}

impl Header {
    #[inline(never)]
    fn push(&mut self, b: u8) {
        if let Some(slot) = self.buf.get_mut(self.len as usize) {
            *slot = b;
            self.len += 1;
        }
    }
    #[inline(never)]
    fn bytes(&mut self, bs: &[u8]) {
        bs.iter().for_each(|&b| self.push(b));
    }
    #[inline(never)]
    fn u64(&mut self, v: u64) {
        self.bytes(&v.to_be_bytes());
    }
    pub(crate) fn as_bytes(&self) -> &[u8] {
        self.buf.get(..self.len as usize).unwrap_or(&[])
    }

    /// Splits a frame into its fixed fields and its variable part. The one serializer of the
    /// crate: [`Frame::encode`] and the driver's `send` both write these bytes. (A per-byte walk
    /// over the fields through a closure is about twice the AVR flash of this.)
    #[inline(never)]
    pub(crate) fn split<'a>(frame: &Frame<'a>) -> (Header, &'a [u8]) {
        let mut h = Header {
            buf: [0; 15],
            len: 0,
        };
        h.push(frame.frame_type());
        let rest = match *frame {
            Frame::Tx64 {
                frame_id,
                dest,
                options,
                data,
            } => {
                h.push(frame_id);
                h.u64(dest);
                h.push(options);
                data
            }
            Frame::Tx16 {
                frame_id,
                dest,
                options,
                data,
            } => {
                h.push(frame_id);
                h.bytes(&dest.to_be_bytes());
                h.push(options);
                data
            }
            Frame::AtCommand {
                frame_id,
                command,
                parameter,
            }
            | Frame::AtCommandQueue {
                frame_id,
                command,
                parameter,
            } => {
                h.push(frame_id);
                h.bytes(&command);
                parameter
            }
            Frame::RemoteAtCommand {
                frame_id,
                dest64,
                dest16,
                options,
                command,
                parameter,
            } => {
                h.push(frame_id);
                h.u64(dest64);
                h.bytes(&dest16.to_be_bytes());
                h.push(options);
                h.bytes(&command);
                parameter
            }
            Frame::Rx64 {
                source,
                rssi,
                options,
                data,
            }
            | Frame::Rx64Io {
                source,
                rssi,
                options,
                data,
            } => {
                h.u64(source);
                h.push(rssi.0);
                h.push(options);
                data
            }
            Frame::Rx16 {
                source,
                rssi,
                options,
                data,
            }
            | Frame::Rx16Io {
                source,
                rssi,
                options,
                data,
            } => {
                h.bytes(&source.to_be_bytes());
                h.push(rssi.0);
                h.push(options);
                data
            }
            Frame::AtResponse {
                frame_id,
                command,
                status,
                data,
            } => {
                h.push(frame_id);
                h.bytes(&command);
                h.push(status.0);
                data
            }
            Frame::TxStatus { frame_id, status } => {
                h.push(frame_id);
                h.push(status.0);
                &[]
            }
            Frame::ModemStatus { status } => {
                h.push(status.0);
                &[]
            }
            Frame::RemoteAtResponse {
                frame_id,
                source64,
                source16,
                command,
                status,
                data,
            } => {
                h.push(frame_id);
                h.u64(source64);
                h.bytes(&source16.to_be_bytes());
                h.bytes(&command);
                h.push(status.0);
                data
            }
            Frame::Unknown { data, .. } => data,
        };
        (h, rest)
    }
}

/// I/O sample data of an RX64 IO / RX16 IO frame (802.15.4 format: sample count, channel mask,
/// then per sample the digital word if any DIO is enabled and one word per enabled ADC).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IoSamples<'a> {
    count: u8,
    mask: u16,
    samples: &'a [u8],
}

/// One I/O sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct IoSample {
    /// DIO0…DIO8 levels (bit n = DIOn), when any DIO is enabled.
    pub digital: Option<u16>,
    /// ADC0…ADC5 readings (10 bit), for the enabled channels.
    pub analog: [Option<u16>; 6],
}

impl<'a> IoSamples<'a> {
    /// Reads the sample data; `None` when it is shorter than its header announces.
    pub fn parse(data: &'a [u8]) -> Option<IoSamples<'a>> {
        let (&count, rest) = data.split_first()?;
        let mask = u16::from_be_bytes([*rest.first()?, *rest.get(1)?]);
        let s = IoSamples {
            count,
            mask,
            samples: &rest[2..],
        };
        (s.samples.len() >= s.count as usize * s.sample_len()).then_some(s)
    }
    /// Number of samples.
    pub fn count(&self) -> u8 {
        self.count
    }
    /// Channel indicator: bits 0–8 DIO0–8, bits 9–14 ADC0–5.
    pub fn channel_mask(&self) -> u16 {
        self.mask
    }
    fn sample_len(&self) -> usize {
        let dio = if self.mask & 0x01FF != 0 { 2 } else { 0 };
        dio + 2 * ((self.mask >> 9) & 0x3F).count_ones() as usize
    }
    /// The samples in order.
    pub fn iter(&self) -> impl Iterator<Item = IoSample> + 'a {
        let (mask, len) = (self.mask, self.sample_len());
        let body = self.samples;
        (0..self.count as usize).map(move |i| {
            let mut f = Fields(body.get(i * len..).unwrap_or(&[]));
            let mut s = IoSample::default();
            if mask & 0x01FF != 0 {
                s.digital = Some(f.u16() & mask & 0x01FF);
            }
            for (ch, slot) in s.analog.iter_mut().enumerate() {
                if mask & (1 << (9 + ch)) != 0 {
                    *slot = Some(f.u16() & 0x03FF);
                }
            }
            s
        })
    }
}
