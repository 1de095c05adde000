//! Property tests of the frame codec.
//!
//! * Every frame type round-trips (`decode(encode(f)) == f`) in both API modes, through the
//!   byte-at-a-time [`Decoder`] and through [`Frame::parse`], with payloads up to the largest legal
//!   size and escape-worthy bytes (0x7E, 0x7D, 0x11, 0x13) drawn often.
//! * Arbitrary byte streams never panic the decoder, and its counters agree with what it reported.
//! * Streams of valid frames mixed with corrupted ones (truncated, bit-flipped) and garbage: in
//!   `AP=2` every intact frame is recovered; in `AP=1` every intact frame is recovered once the
//!   decoder is told the line went idle, or once enough further bytes follow — unless the
//!   corruption happened to form a frame with a valid checksum that swallowed it, which `AP=1`
//!   cannot tell from a real frame.
//! * Pushing several bytes before polling gives the same events as pushing one byte at a time.
//! * The lean views of a raw frame (`rx16`, `at_response`, `tx_status`) agree with `Frame::parse`.

use proptest::prelude::*;
use proptest::sample::select;
use xbee_api::{
    AtResponse, AtStatus, DecodeError, Decoder, Frame, IoSamples, Mode, ModemStatus, RawFrame,
    Rssi, Rx16, TxStatus, MAX_ENCODED, MAX_FRAME_DATA, MAX_RF_PAYLOAD,
};

// ---------------------------------------------------------------------------------------------
// Owned frames and their strategies
// ---------------------------------------------------------------------------------------------

/// An owned mirror of [`Frame`], so that proptest can generate and shrink frames.
#[derive(Clone, Debug)]
enum Owned {
    Tx64(u8, u64, u8, Vec<u8>),
    Tx16(u8, u16, u8, Vec<u8>),
    At(u8, [u8; 2], Vec<u8>),
    AtQueue(u8, [u8; 2], Vec<u8>),
    RemoteAt(u8, u64, u16, u8, [u8; 2], Vec<u8>),
    Rx64(u64, u8, u8, Vec<u8>),
    Rx16(u16, u8, u8, Vec<u8>),
    Rx64Io(u64, u8, u8, Vec<u8>),
    Rx16Io(u16, u8, u8, Vec<u8>),
    AtResponse(u8, [u8; 2], u8, Vec<u8>),
    TxStatus(u8, u8),
    ModemStatus(u8),
    RemoteAtResponse(u8, u64, u16, [u8; 2], u8, Vec<u8>),
    Unknown(u8, Vec<u8>),
}

impl Owned {
    fn frame(&self) -> Frame<'_> {
        match self {
            Owned::Tx64(frame_id, dest, options, data) => Frame::Tx64 {
                frame_id: *frame_id,
                dest: *dest,
                options: *options,
                data,
            },
            Owned::Tx16(frame_id, dest, options, data) => Frame::Tx16 {
                frame_id: *frame_id,
                dest: *dest,
                options: *options,
                data,
            },
            Owned::At(frame_id, command, parameter) => Frame::AtCommand {
                frame_id: *frame_id,
                command: *command,
                parameter,
            },
            Owned::AtQueue(frame_id, command, parameter) => Frame::AtCommandQueue {
                frame_id: *frame_id,
                command: *command,
                parameter,
            },
            Owned::RemoteAt(frame_id, dest64, dest16, options, command, parameter) => {
                Frame::RemoteAtCommand {
                    frame_id: *frame_id,
                    dest64: *dest64,
                    dest16: *dest16,
                    options: *options,
                    command: *command,
                    parameter,
                }
            }
            Owned::Rx64(source, rssi, options, data) => Frame::Rx64 {
                source: *source,
                rssi: Rssi(*rssi),
                options: *options,
                data,
            },
            Owned::Rx16(source, rssi, options, data) => Frame::Rx16 {
                source: *source,
                rssi: Rssi(*rssi),
                options: *options,
                data,
            },
            Owned::Rx64Io(source, rssi, options, data) => Frame::Rx64Io {
                source: *source,
                rssi: Rssi(*rssi),
                options: *options,
                data,
            },
            Owned::Rx16Io(source, rssi, options, data) => Frame::Rx16Io {
                source: *source,
                rssi: Rssi(*rssi),
                options: *options,
                data,
            },
            Owned::AtResponse(frame_id, command, status, data) => Frame::AtResponse {
                frame_id: *frame_id,
                command: *command,
                status: AtStatus(*status),
                data,
            },
            Owned::TxStatus(frame_id, status) => Frame::TxStatus {
                frame_id: *frame_id,
                status: TxStatus(*status),
            },
            Owned::ModemStatus(status) => Frame::ModemStatus {
                status: ModemStatus(*status),
            },
            Owned::RemoteAtResponse(frame_id, source64, source16, command, status, data) => {
                Frame::RemoteAtResponse {
                    frame_id: *frame_id,
                    source64: *source64,
                    source16: *source16,
                    command: *command,
                    status: AtStatus(*status),
                    data,
                }
            }
            Owned::Unknown(frame_type, data) => Frame::Unknown {
                frame_type: *frame_type,
                data,
            },
        }
    }
}

/// The frame type bytes this crate names; anything else is `Unknown`.
const KNOWN_TYPES: [u8; 13] = [
    0x00, 0x01, 0x08, 0x09, 0x17, 0x80, 0x81, 0x82, 0x83, 0x88, 0x89, 0x8A, 0x97,
];

/// A byte, with the four bytes that API mode 2 escapes drawn often.
fn byte() -> impl Strategy<Value = u8> {
    prop_oneof![
        3 => any::<u8>(),
        2 => select(vec![0x7E, 0x7D, 0x11, 0x13]),
        1 => select(vec![0x00, 0xFF, 0xFE, 0x20, 0x5E]),
    ]
}

fn bytes(max: usize) -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        4 => prop::collection::vec(byte(), 0..=max),
        1 => Just(Vec::new()),
        1 => prop::collection::vec(byte(), max..=max),
    ]
}

fn u16_() -> impl Strategy<Value = u16> {
    prop_oneof![
        3 => (byte(), byte()).prop_map(|(a, b)| u16::from_be_bytes([a, b])),
        1 => select(vec![0xFFFF, 0xFFFE, 0x0000, 0x7E7D, 0x1113]),
    ]
}

fn u64_() -> impl Strategy<Value = u64> {
    prop_oneof![
        3 => prop::array::uniform8(byte()).prop_map(u64::from_be_bytes),
        1 => select(vec![0xFFFF, 0, u64::MAX, 0x0013_A200_4052_2BAA, 0x7E7D_1113_7E7D_1113]),
    ]
}

fn cmd() -> impl Strategy<Value = [u8; 2]> {
    prop_oneof![
        3 => prop::array::uniform2(select(b"ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789".to_vec())),
        1 => prop::array::uniform2(byte()),
    ]
}

/// Room for the variable part of a frame type whose fixed part is `fixed` bytes.
const fn room(fixed: usize) -> usize {
    MAX_FRAME_DATA - fixed
}

/// Any frame of any type whose frame data fits [`MAX_FRAME_DATA`]. RF payloads go up to
/// [`MAX_RF_PAYLOAD`] (TX64/RX64 then fill the 111 bytes exactly); AT parameters, responses, IO
/// data and unknown frames up to the rest of the 111 bytes.
fn frame() -> impl Strategy<Value = Owned> {
    let rf = MAX_RF_PAYLOAD;
    prop_oneof![
        (byte(), u64_(), byte(), bytes(rf.min(room(11))))
            .prop_map(|(a, b, c, d)| Owned::Tx64(a, b, c, d)),
        (byte(), u16_(), byte(), bytes(rf.min(room(5))))
            .prop_map(|(a, b, c, d)| Owned::Tx16(a, b, c, d)),
        (byte(), cmd(), bytes(room(4))).prop_map(|(a, b, c)| Owned::At(a, b, c)),
        (byte(), cmd(), bytes(room(4))).prop_map(|(a, b, c)| Owned::AtQueue(a, b, c)),
        (byte(), u64_(), u16_(), byte(), cmd(), bytes(room(15)))
            .prop_map(|(a, b, c, d, e, f)| Owned::RemoteAt(a, b, c, d, e, f)),
        (u64_(), byte(), byte(), bytes(rf.min(room(11))))
            .prop_map(|(a, b, c, d)| Owned::Rx64(a, b, c, d)),
        (u16_(), byte(), byte(), bytes(rf.min(room(5))))
            .prop_map(|(a, b, c, d)| Owned::Rx16(a, b, c, d)),
        (u64_(), byte(), byte(), bytes(room(11)))
            .prop_map(|(a, b, c, d)| Owned::Rx64Io(a, b, c, d)),
        (u16_(), byte(), byte(), bytes(room(5))).prop_map(|(a, b, c, d)| Owned::Rx16Io(a, b, c, d)),
        (byte(), cmd(), byte(), bytes(room(5)))
            .prop_map(|(a, b, c, d)| Owned::AtResponse(a, b, c, d)),
        (byte(), byte()).prop_map(|(a, b)| Owned::TxStatus(a, b)),
        byte().prop_map(Owned::ModemStatus),
        (byte(), u64_(), u16_(), cmd(), byte(), bytes(room(15)))
            .prop_map(|(a, b, c, d, e, f)| Owned::RemoteAtResponse(a, b, c, d, e, f)),
        (
            any::<u8>().prop_filter("unknown type", |t| !KNOWN_TYPES.contains(t)),
            bytes(room(1))
        )
            .prop_map(|(a, b)| Owned::Unknown(a, b)),
    ]
}

fn mode() -> impl Strategy<Value = Mode> {
    select(vec![Mode::Api, Mode::Escaped])
}

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

fn encode(f: &Frame<'_>, mode: Mode) -> Vec<u8> {
    let mut buf = [0u8; MAX_ENCODED];
    let n = f
        .encode(mode, &mut buf)
        .expect("MAX_ENCODED fits every legal frame");
    buf[..n].to_vec()
}

/// One decoder event, owned.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Ev {
    Frame(Vec<u8>),
    Error(DecodeError),
}

/// Drains the decoder's pending events into `out`.
fn drain(dec: &mut Decoder, out: &mut Vec<Ev>) {
    while let Some(ev) = dec.poll() {
        out.push(match ev {
            Ok(raw) => {
                // Whatever comes out must parse or fail cleanly, never panic.
                let _ = raw.parse();
                Ev::Frame(raw.data().to_vec())
            }
            Err(e) => Ev::Error(e),
        });
    }
}

/// Feeds `bytes` one at a time (push, then poll until `None`).
fn feed_bytewise(dec: &mut Decoder, bytes: &[u8], out: &mut Vec<Ev>) {
    for &b in bytes {
        dec.push(b).expect("push after a full drain never fails");
        drain(dec, out);
    }
}

/// After the input: tells the decoder the line went idle (repeatedly: in AP=1 a failed frame's
/// bytes are re-read and may hold another partial frame), draining after each.
fn idle_until_quiet(dec: &mut Decoder, out: &mut Vec<Ev>) {
    for _ in 0..=MAX_FRAME_DATA + 3 {
        if !dec.in_frame() {
            return;
        }
        dec.idle();
        drain(dec, out);
    }
    panic!("decoder still in a frame after repeated idle()");
}

fn frames_of(events: &[Ev]) -> Vec<Vec<u8>> {
    events
        .iter()
        .filter_map(|e| match e {
            Ev::Frame(d) => Some(d.clone()),
            Ev::Error(_) => None,
        })
        .collect()
}

/// Checks the decoder's counters against the events it reported.
fn check_stats(dec: &Decoder, events: &[Ev], input_len: usize) -> Result<(), TestCaseError> {
    let s = dec.stats();
    let count = |p: fn(&DecodeError) -> bool| {
        events
            .iter()
            .filter(|e| matches!(e, Ev::Error(err) if p(err)))
            .count() as u32
    };
    let frames = events.iter().filter(|e| matches!(e, Ev::Frame(_))).count() as u32;
    prop_assert_eq!(s.frames, frames, "frames counter");
    prop_assert_eq!(
        s.bad_checksum,
        count(|e| matches!(e, DecodeError::BadChecksum { .. })),
        "bad_checksum counter"
    );
    prop_assert_eq!(
        s.bad_length,
        count(|e| matches!(e, DecodeError::BadLength { .. })),
        "bad_length counter"
    );
    prop_assert_eq!(
        s.truncated,
        count(|e| matches!(e, DecodeError::Truncated { .. })),
        "truncated counter"
    );
    // Garbage is reported when the next start delimiter ends it, so the counter may be ahead of
    // the reports by the trailing garbage; a byte is garbage at most once.
    let reported: u32 = events
        .iter()
        .map(|e| match e {
            Ev::Error(DecodeError::Garbage { bytes }) => u32::from(*bytes),
            _ => 0,
        })
        .sum();
    prop_assert!(
        reported <= s.garbage_bytes,
        "garbage reported {reported} > counted"
    );
    prop_assert!(
        s.garbage_bytes as usize <= input_len,
        "more garbage than input"
    );
    for e in events {
        match e {
            Ev::Error(DecodeError::BadLength { length }) => {
                prop_assert!(*length == 0 || usize::from(*length) > MAX_FRAME_DATA)
            }
            Ev::Error(DecodeError::BadChecksum { computed, received }) => {
                prop_assert_ne!(computed, received)
            }
            Ev::Frame(d) => prop_assert!(!d.is_empty() && d.len() <= MAX_FRAME_DATA),
            _ => {}
        }
    }
    Ok(())
}

/// True when `needle` occurs in `hay` in order (other items may come in between).
fn is_subsequence(needle: &[Vec<u8>], hay: &[Vec<u8>]) -> bool {
    let mut it = hay.iter();
    needle.iter().all(|n| it.any(|h| h == n))
}

/// How one frame of a test stream is damaged.
#[derive(Clone, Debug)]
enum Damage {
    /// Sent whole.
    Intact,
    /// Only the first `n` bytes (modulo the length) are sent.
    Truncate(usize),
    /// Bit `bit` of byte `pos` (modulo the length, never the start byte) is flipped.
    Flip(usize, u8),
    /// Random bytes are sent before the frame, which is then sent whole.
    GarbageBefore(Vec<u8>),
}

fn damage() -> impl Strategy<Value = Damage> {
    prop_oneof![
        4 => Just(Damage::Intact),
        2 => any::<usize>().prop_map(Damage::Truncate),
        2 => (any::<usize>(), 0u8..8).prop_map(|(p, b)| Damage::Flip(p, b)),
        2 => prop::collection::vec(byte(), 1..40).prop_map(Damage::GarbageBefore),
    ]
}

/// Builds the stream; returns it and the frame data of every frame sent whole, in order.
fn build_stream(items: &[(Owned, Damage)], mode: Mode) -> (Vec<u8>, Vec<Vec<u8>>) {
    let mut stream = Vec::new();
    let mut intact = Vec::new();
    for (f, d) in items {
        let frame = f.frame();
        let wire = encode(&frame, mode);
        let mut data = Vec::new();
        frame_data(&frame, &mut data);
        match d {
            Damage::Intact => {
                stream.extend_from_slice(&wire);
                intact.push(data);
            }
            Damage::Truncate(n) => stream.extend_from_slice(&wire[..n % wire.len()]),
            Damage::Flip(pos, bit) => {
                let mut w = wire.clone();
                let p = 1 + pos % (w.len() - 1);
                w[p] ^= 1 << bit;
                stream.extend_from_slice(&w);
            }
            Damage::GarbageBefore(g) => {
                stream.extend_from_slice(g);
                stream.extend_from_slice(&wire);
                intact.push(data);
            }
        }
    }
    (stream, intact)
}

/// The frame data of a frame (type byte first, no checksum), via an AP=1 encoding.
fn frame_data(f: &Frame<'_>, out: &mut Vec<u8>) {
    let wire = encode(f, Mode::Api);
    out.extend_from_slice(&wire[3..wire.len() - 1]);
}

// ---------------------------------------------------------------------------------------------
// Properties
// ---------------------------------------------------------------------------------------------

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// decode(encode(f)) == f for every frame type, in both modes, through the byte-at-a-time
    /// decoder and through `Frame::parse`.
    #[test]
    fn roundtrip_every_type_both_modes(f in frame(), mode in mode()) {
        let frame = f.frame();
        let wire = encode(&frame, mode);
        prop_assert_eq!(wire.len(), xbee_api::encoded_len(&frame, mode));
        prop_assert!(frame.data_len() <= MAX_FRAME_DATA);
        prop_assert_eq!(wire[0], 0x7E);

        // Wire-format invariants.
        match mode {
            Mode::Api => {
                prop_assert_eq!(usize::from(u16::from_be_bytes([wire[1], wire[2]])), frame.data_len());
                prop_assert_eq!(wire.len(), frame.data_len() + 4);
            }
            Mode::Escaped => {
                // Nothing escapable is left after the start byte.
                prop_assert!(wire[1..].iter().all(|b| ![0x7E, 0x11, 0x13].contains(b)));
                prop_assert!(wire.last() != Some(&0x7D));
            }
        }

        // Through the decoder, one byte at a time.
        let mut dec = Decoder::new(mode);
        let mut events = Vec::new();
        feed_bytewise(&mut dec, &wire, &mut events);
        prop_assert_eq!(events.len(), 1, "events {:?}", events);
        let Ev::Frame(data) = &events[0] else {
            return Err(TestCaseError::fail(format!("not a frame: {:?}", events)));
        };
        prop_assert_eq!(data.len(), frame.data_len());
        prop_assert_eq!(data[0], frame.frame_type());
        let parsed = Frame::parse(data).expect("parses");
        prop_assert_eq!(parsed, frame);
        prop_assert!(!dec.in_frame());
        check_stats(&dec, &events, wire.len())?;

        // The typed accessors agree with the variant.
        prop_assert_eq!(parsed.frame_id(), frame.frame_id());
        prop_assert_eq!(parsed.rssi(), frame.rssi());

        // Through `Decoder::feed` as well.
        let mut dec = Decoder::new(mode);
        let mut fed = Vec::new();
        dec.feed(&wire, |ev| fed.push(ev.map(|r| r.data().to_vec())));
        prop_assert_eq!(fed, vec![Ok(data.clone())]);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Frames back to back, and the same frames re-encoded in the other mode, decode in order.
    #[test]
    fn roundtrip_streams(fs in prop::collection::vec(frame(), 1..8), mode in mode()) {
        let mut stream = Vec::new();
        let mut expected = Vec::new();
        for f in &fs {
            stream.extend_from_slice(&encode(&f.frame(), mode));
            let mut d = Vec::new();
            frame_data(&f.frame(), &mut d);
            expected.push(d);
        }
        let mut dec = Decoder::new(mode);
        let mut events = Vec::new();
        feed_bytewise(&mut dec, &stream, &mut events);
        prop_assert!(events.iter().all(|e| matches!(e, Ev::Frame(_))), "{:?}", events);
        prop_assert_eq!(frames_of(&events), expected.clone());
        for (d, f) in expected.iter().zip(&fs) {
            prop_assert_eq!(Frame::parse(d).unwrap(), f.frame());
        }
        check_stats(&dec, &events, stream.len())?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Arbitrary bytes never panic the decoder (with `idle()` at arbitrary points) and its
    /// counters stay consistent with its reports; every frame it emits parses or fails cleanly.
    #[test]
    fn random_bytes_never_panic(
        bytes in prop::collection::vec(byte(), 0..512),
        idles in prop::collection::vec(any::<usize>(), 0..4),
        mode in mode(),
    ) {
        let mut dec = Decoder::new(mode);
        let mut events = Vec::new();
        for (i, &b) in bytes.iter().enumerate() {
            dec.push(b).expect("push after a full drain never fails");
            drain(&mut dec, &mut events);
            if idles.iter().any(|k| !bytes.is_empty() && k % bytes.len() == i) {
                dec.idle();
                drain(&mut dec, &mut events);
            }
        }
        idle_until_quiet(&mut dec, &mut events);
        check_stats(&dec, &events, bytes.len())?;
        // IoSamples on arbitrary data: no panic either.
        let io = IoSamples::parse(&bytes);
        if let Some(io) = io {
            prop_assert!(io.iter().count() == usize::from(io.count()));
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Valid frames mixed with truncated and bit-flipped frames and garbage. AP=2: every intact
    /// frame comes out, in order, as the bytes arrive. AP=1: every intact frame comes out once the
    /// line goes idle, unless the damage formed a frame with a valid checksum (AP=1 cannot tell
    /// such a frame from a real one).
    #[test]
    fn intact_frames_survive_corruption(
        items in prop::collection::vec((frame(), damage()), 1..10),
        mode in mode(),
    ) {
        let (stream, intact) = build_stream(&items, mode);
        let mut dec = Decoder::new(mode);
        let mut events = Vec::new();
        feed_bytewise(&mut dec, &stream, &mut events);
        if mode == Mode::Escaped {
            // No idle needed: an unescaped 0x7E always starts a new frame.
            prop_assert!(
                is_subsequence(&intact, &frames_of(&events)),
                "intact {:02X?}\nemitted {:02X?}", intact, frames_of(&events)
            );
        }
        idle_until_quiet(&mut dec, &mut events);
        let emitted = frames_of(&events);
        let bogus = emitted.iter().any(|e| !intact.contains(e));
        if mode == Mode::Escaped || !bogus {
            prop_assert!(
                is_subsequence(&intact, &emitted),
                "{:?}: intact {:02X?}\nemitted {:02X?}", mode, intact, emitted
            );
        }
        if mode == Mode::Api && !bogus {
            // Without bogus frames, AP=1 emits exactly the intact frames.
            prop_assert_eq!(&emitted, &intact);
        }
        check_stats(&dec, &events, stream.len())?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// AP=1 without `idle()`: enough bytes after the damage (here 2 × 114 bytes that hold no start
    /// delimiter) complete every pending partial frame, so the intact frames come out.
    #[test]
    fn ap1_recovers_when_followed_by_enough_bytes(
        items in prop::collection::vec((frame(), damage()), 1..8),
        filler in any::<u8>().prop_filter("no start byte", |b| *b != 0x7E),
    ) {
        let (mut stream, intact) = build_stream(&items, Mode::Api);
        stream.extend(std::iter::repeat_n(filler, 2 * (MAX_FRAME_DATA + 3)));
        let mut dec = Decoder::new(Mode::Api);
        let mut events = Vec::new();
        feed_bytewise(&mut dec, &stream, &mut events);
        let emitted = frames_of(&events);
        if !emitted.iter().any(|e| !intact.contains(e)) {
            prop_assert_eq!(&emitted, &intact);
        }
        prop_assert!(!dec.in_frame());
        check_stats(&dec, &events, stream.len())?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Pushing several bytes before polling (until the input queue is full) gives exactly the
    /// events of pushing one byte at a time, idle included.
    #[test]
    fn chunked_push_equals_bytewise(
        items in prop::collection::vec((frame(), damage()), 1..6),
        chunks in prop::collection::vec(1usize..300, 1..20),
        mode in mode(),
    ) {
        let (stream, _) = build_stream(&items, mode);
        let mut dec = Decoder::new(mode);
        let mut reference = Vec::new();
        feed_bytewise(&mut dec, &stream, &mut reference);
        idle_until_quiet(&mut dec, &mut reference);

        let mut dec = Decoder::new(mode);
        let mut events = Vec::new();
        let mut rest = &stream[..];
        let mut i = 0;
        while !rest.is_empty() {
            let n = chunks[i % chunks.len()].min(rest.len());
            i += 1;
            for &b in &rest[..n] {
                if let Err(e) = dec.push(b) {
                    prop_assert_eq!(e.0, b);
                    drain(&mut dec, &mut events);
                    // After a full drain there is always room for one byte.
                    prop_assert!(dec.push(b).is_ok(), "push failed after a drain");
                }
            }
            drain(&mut dec, &mut events);
            rest = &rest[n..];
        }
        idle_until_quiet(&mut dec, &mut events);
        prop_assert_eq!(&events, &reference);
        check_stats(&dec, &events, stream.len())?;
    }
}

// ---------------------------------------------------------------------------------------------
// Boundaries
// ---------------------------------------------------------------------------------------------

/// Frame data of exactly MAX_FRAME_DATA decodes; one byte more is a bad length, and the frame that
/// follows still comes out (both modes).
#[test]
fn max_frame_data_boundary() {
    for mode in [Mode::Api, Mode::Escaped] {
        let max = Frame::Unknown {
            frame_type: 0x42,
            data: &[0x7E; MAX_FRAME_DATA - 1],
        };
        // (No 0x7E inside: in AP=1 each would be re-read as a start and give more errors.)
        let over = Frame::Unknown {
            frame_type: 0x42,
            data: &[0x55; MAX_FRAME_DATA],
        };
        let next = Frame::ModemStatus {
            status: ModemStatus::HARDWARE_RESET,
        };
        let mut stream = encode(&max, mode);
        stream.extend(encode(&over, mode));
        stream.extend(encode(&next, mode));
        let mut dec = Decoder::new(mode);
        let mut events = Vec::new();
        feed_bytewise(&mut dec, &stream, &mut events);
        idle_until_quiet(&mut dec, &mut events);
        let frames = frames_of(&events);
        assert_eq!(
            frames.first().map(Vec::len),
            Some(MAX_FRAME_DATA),
            "{mode:?}"
        );
        assert_eq!(frames.last(), Some(&vec![0x8A, 0x00]), "{mode:?}");
        assert!(events.contains(&Ev::Error(DecodeError::BadLength { length: 112 })));
        assert_eq!(dec.stats().bad_length, 1);
        // Zero length is bad too.
        let mut dec = Decoder::new(mode);
        let mut events = Vec::new();
        let mut s = vec![0x7E, 0x00, 0x00];
        s.extend(encode(&next, mode));
        feed_bytewise(&mut dec, &s, &mut events);
        assert_eq!(
            events,
            vec![
                Ev::Error(DecodeError::BadLength { length: 0 }),
                Ev::Frame(vec![0x8A, 0x00])
            ]
        );
    }
}

/// What the full parse says the lean views ([`RawFrame::rx16`], [`RawFrame::at_response`],
/// [`RawFrame::tx_status`]) must return for `data`.
fn views_by_parse(
    data: &[u8],
) -> (
    Option<Rx16<'_>>,
    Option<AtResponse<'_>>,
    Option<(u8, TxStatus)>,
) {
    match Frame::parse(data) {
        Ok(Frame::Rx16 {
            source,
            rssi,
            options,
            data,
        }) => (
            Some(Rx16 {
                source,
                rssi,
                options,
                data,
            }),
            None,
            None,
        ),
        Ok(Frame::AtResponse {
            frame_id,
            command,
            status,
            data,
        }) => (
            None,
            Some(AtResponse {
                frame_id,
                command,
                status,
                data,
            }),
            None,
        ),
        Ok(Frame::TxStatus { frame_id, status }) => (None, None, Some((frame_id, status))),
        _ => (None, None, None),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    /// The lean views agree with `Frame::parse` on every frame of every type...
    #[test]
    fn lean_views_agree_with_parse_on_frames(f in frame()) {
        let mut data = Vec::new();
        frame_data(&f.frame(), &mut data);
        let raw = RawFrame::new(&data);
        prop_assert_eq!((raw.rx16(), raw.at_response(), raw.tx_status()), views_by_parse(&data));
    }

    /// ...and on arbitrary bytes, including truncated and overlong frames of their types.
    #[test]
    fn lean_views_agree_with_parse_on_any_bytes(
        t in select(vec![0x81u8, 0x88, 0x89, 0x80, 0x8A, 0x00]),
        body in bytes(12),
    ) {
        let mut data = vec![t];
        data.extend(body);
        let raw = RawFrame::new(&data);
        prop_assert_eq!((raw.rx16(), raw.at_response(), raw.tx_status()), views_by_parse(&data));
    }
}
