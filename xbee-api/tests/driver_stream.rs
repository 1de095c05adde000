//! The driver's receive path against the decoder: a [`Radio`] reading a damaged byte stream
//! (valid frames, truncated and bit-flipped ones, garbage, pauses on the line) hands out the
//! same frames and stream errors, in the same order and with the same counters, as a
//! [`Decoder`] fed the same bytes and told the line went idle at the same pauses. In each API
//! mode chosen at run time ([`Mode`]) and in API mode 2 fixed at compile time ([`Ap2`]), whose
//! decoder skips the input queue; `Ap2<false>` hands out the same and keeps no counters.

use core::convert::Infallible;

use embedded_hal_nb::serial::{ErrorType, Read, Write};
use proptest::prelude::*;
use xbee_api::driver::{Clock, Error, Radio};
use xbee_api::{encode_raw, Ap2, ApiMode, DecodeError, Decoder, DecoderStats, Mode, MAX_ENCODED};

/// A line that gives its bytes one by one, and `WouldBlock` for a while at each pause.
struct Line {
    /// Bytes, each with the number of `WouldBlock` reads before it.
    bytes: Vec<(u8, u32)>,
    pos: usize,
    waited: u32,
    /// `WouldBlock` reads after the last byte.
    tail: u32,
}

impl ErrorType for Line {
    type Error = Infallible;
}

impl Read<u8> for Line {
    fn read(&mut self) -> nb::Result<u8, Infallible> {
        match self.bytes.get(self.pos) {
            Some(&(b, wait)) if self.waited >= wait => {
                self.pos += 1;
                self.waited = 0;
                Ok(b)
            }
            _ => {
                self.waited += 1;
                if self.pos == self.bytes.len() {
                    self.tail += 1;
                }
                Err(nb::Error::WouldBlock)
            }
        }
    }
}

impl Write<u8> for Line {
    fn write(&mut self, _: u8) -> nb::Result<(), Infallible> {
        Ok(())
    }
    fn flush(&mut self) -> nb::Result<(), Infallible> {
        Ok(())
    }
}

/// 7 ms per look: a pause of a few reads is longer than the driver's idle time (20 ms).
struct Ticks(u32);

impl Clock for Ticks {
    fn now_ms(&mut self) -> u32 {
        self.0 = self.0.wrapping_add(7);
        self.0
    }
}

/// A pause long enough for the driver to call the line idle.
const PAUSE: u32 = 8;

type Events = Vec<Result<Vec<u8>, DecodeError>>;

/// What the driver hands out for `chunks` (each followed by a pause if its flag is set).
fn through_radio<M: ApiMode>(mode: M, chunks: &[(Vec<u8>, bool)]) -> (Events, DecoderStats) {
    let mut bytes = Vec::new();
    let mut pause = 0;
    for (chunk, paused) in chunks {
        for &b in chunk {
            bytes.push((b, pause));
            pause = 0;
        }
        if *paused {
            pause = PAUSE;
        }
    }
    let line = Line {
        bytes,
        pos: 0,
        waited: 0,
        tail: 0,
    };
    let mut radio = Radio::new(line, Ticks(0), mode);
    let mut events = Vec::new();
    while radio.serial_mut().tail < 2 * PAUSE {
        match radio.poll(|raw| raw.data().to_vec()) {
            Some(Ok(data)) => events.push(Ok(data)),
            Some(Err(Error::Decode(e))) => events.push(Err(e)),
            Some(Err(e)) => panic!("{e:?}"),
            None => {}
        }
    }
    (events, radio.stats().decoder)
}

/// What a decoder gives for `chunks`, told the line went idle after each paused chunk (and at
/// the end, where the driver sees the line go quiet too) while it is inside a frame.
fn through_decoder(mode: Mode, chunks: &[(Vec<u8>, bool)]) -> (Events, DecoderStats) {
    let mut dec = Decoder::new(mode);
    let mut events = Vec::new();
    let last = chunks.len().saturating_sub(1);
    for (i, (chunk, paused)) in chunks.iter().enumerate() {
        dec.feed(chunk, |ev| events.push(ev.map(|raw| raw.data().to_vec())));
        // In AP=1 the bytes of a frame cut short are re-read, and may hold the start of
        // another: the driver, still seeing a quiet line, ends that one too.
        while (*paused || i == last) && dec.in_frame() {
            dec.idle();
            while let Some(ev) = dec.poll() {
                events.push(ev.map(|raw| raw.data().to_vec()));
            }
        }
    }
    (events, dec.stats())
}

/// A chunk of the stream: a frame (intact, cut short or with one byte changed) or garbage.
fn chunk(mode: Mode) -> impl Strategy<Value = (Vec<u8>, bool)> {
    let byte = prop_oneof![any::<u8>(), Just(0x7E), Just(0x7D), Just(0x11), Just(0x13)];
    (
        prop::collection::vec(byte.clone(), 1..40),
        0u8..4,
        any::<prop::sample::Index>(),
        any::<u8>(),
        any::<bool>(),
        prop::collection::vec(byte, 1..6),
    )
        .prop_map(move |(data, kind, at, flip, paused, garbage)| {
            let mut out = [0u8; MAX_ENCODED];
            let n = encode_raw(&data, mode, &mut out).unwrap();
            let mut frame = out[..n].to_vec();
            match kind {
                0 => {}
                1 => frame.truncate(1 + at.index(n - 1)),
                2 => {
                    let i = at.index(n);
                    frame[i] ^= flip.max(1);
                }
                _ => frame = garbage,
            }
            (frame, paused)
        })
}

fn stream(mode: Mode) -> impl Strategy<Value = Vec<(Vec<u8>, bool)>> {
    prop::collection::vec(chunk(mode), 1..12)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn ap2_driver_reads_as_the_decoder(chunks in stream(Mode::Escaped)) {
        let want = through_decoder(Mode::Escaped, &chunks);
        prop_assert_eq!(&through_radio(Ap2::<true>, &chunks), &want);
        prop_assert_eq!(&through_radio(Mode::Escaped, &chunks), &want);
        // Without counters: the same frames and errors; the counters stay zero.
        let (events, stats) = through_radio(Ap2::<false>, &chunks);
        prop_assert_eq!(&events, &want.0);
        prop_assert_eq!(stats, DecoderStats::default());
    }

    #[test]
    fn ap1_driver_reads_as_the_decoder(chunks in stream(Mode::Api)) {
        prop_assert_eq!(through_radio(Mode::Api, &chunks), through_decoder(Mode::Api, &chunks));
    }
}

/// A corrupt frame never costs the next good one, in [`Ap2`] as in [`Mode::Escaped`]: a frame
/// cut short by the next start delimiter, then a good frame.
#[test]
fn ap2_a_cut_frame_does_not_cost_the_next() {
    let mut out = [0u8; MAX_ENCODED];
    let n = encode_raw(
        &[0x81, 0x00, 0x01, 0x28, 0x00, 0x7E, 0x42],
        Mode::Escaped,
        &mut out,
    )
    .unwrap();
    let good = out[..n].to_vec();
    let chunks = vec![(good[..5].to_vec(), false), (good.clone(), false)];
    let (events, stats) = through_radio(Ap2::<true>, &chunks);
    assert_eq!(
        events,
        vec![
            Err(DecodeError::Truncated { received: 4 }),
            Ok(vec![0x81, 0x00, 0x01, 0x28, 0x00, 0x7E, 0x42]),
        ]
    );
    assert_eq!((stats.frames, stats.truncated), (1, 1));
}
