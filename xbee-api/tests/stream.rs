//! Stream-level decoder behaviour: garbage, bad checksums, bad lengths, truncation, and the
//! guarantee that the next good frame always comes out.

use xbee_api::{DecodeError, Decoder, Frame, Mode};

/// Decodes a whole stream into (frames as frame data, errors).
fn run(mode: Mode, bytes: &[u8]) -> (Vec<Vec<u8>>, Vec<DecodeError>) {
    let mut dec = Decoder::new(mode);
    let (mut frames, mut errors) = (Vec::new(), Vec::new());
    dec.feed(bytes, |ev| match ev {
        Ok(f) => frames.push(f.data().to_vec()),
        Err(e) => errors.push(e),
    });
    (frames, errors)
}

fn enc(f: &Frame<'_>, mode: Mode) -> Vec<u8> {
    let mut buf = [0u8; xbee_api::MAX_ENCODED];
    let n = f.encode(mode, &mut buf).unwrap();
    buf[..n].to_vec()
}

const AT_MY: &[u8] = &[0x7E, 0x00, 0x04, 0x08, 0x52, 0x4D, 0x59, 0xFF];
const MODES: [Mode; 2] = [Mode::Api, Mode::Escaped];

fn rx16(data: &[u8]) -> Frame<'_> {
    Frame::Rx16 {
        source: 0x7E7D,
        rssi: xbee_api::Rssi(0x11),
        options: 0x13,
        data,
    }
}

#[test]
fn garbage_before_a_frame_is_counted_and_skipped() {
    for mode in MODES {
        let mut s = b"hello\r\n".to_vec();
        s.extend_from_slice(AT_MY);
        let (frames, errors) = run(mode, &s);
        assert_eq!(frames, vec![AT_MY[3..7].to_vec()], "{mode:?}");
        assert_eq!(errors, vec![DecodeError::Garbage { bytes: 7 }]);
    }
}

#[test]
fn bad_checksum_is_reported_and_the_next_frame_survives() {
    for mode in MODES {
        let mut bad = AT_MY.to_vec();
        *bad.last_mut().unwrap() ^= 0x01;
        let mut s = bad.clone();
        s.extend_from_slice(AT_MY);
        let mut dec = Decoder::new(mode);
        let mut frames = 0;
        let mut errors = vec![];
        dec.feed(&s, |ev| match ev {
            Ok(_) => frames += 1,
            Err(e) => errors.push(e),
        });
        assert_eq!(frames, 1, "{mode:?}");
        assert_eq!(
            errors,
            vec![DecodeError::BadChecksum {
                computed: 0xFF,
                received: 0xFE
            }]
        );
        assert_eq!(dec.stats().bad_checksum, 1);
        assert_eq!(dec.stats().frames, 1);
    }
}

#[test]
fn oversize_and_zero_lengths_are_rejected_without_losing_the_next_frame() {
    for mode in MODES {
        for len in [[0x00, 0x00], [0x00, 0x70], [0xFF, 0xFF]] {
            let mut s = vec![0x7E, len[0], len[1], 1, 2, 3];
            s.extend_from_slice(AT_MY);
            let (frames, errors) = run(mode, &s);
            assert_eq!(frames.len(), 1, "{mode:?} {len:?}");
            let length = u16::from_be_bytes(len);
            assert_eq!(errors[0], DecodeError::BadLength { length });
        }
    }
}

#[test]
fn largest_legal_frame_is_accepted() {
    let payload = [0x7Eu8; 100];
    let f = Frame::Tx64 {
        frame_id: 1,
        dest: 0xFFFF,
        options: 0,
        data: &payload,
    };
    assert_eq!(f.data_len(), xbee_api::MAX_FRAME_DATA);
    for mode in MODES {
        let (frames, errors) = run(mode, &enc(&f, mode));
        assert!(errors.is_empty(), "{errors:?}");
        assert_eq!(Frame::parse(&frames[0]).unwrap(), f);
    }
}

#[test]
fn truncated_frame_followed_by_good_one_escaped_mode() {
    let good = enc(&rx16(b"beacon"), Mode::Escaped);
    let mut s = good[..7].to_vec();
    s.extend_from_slice(&good);
    let (frames, errors) = run(Mode::Escaped, &s);
    assert_eq!(errors, vec![DecodeError::Truncated { received: 4 }]);
    assert_eq!(frames.len(), 1);
    assert_eq!(Frame::parse(&frames[0]).unwrap(), rx16(b"beacon"));
}

#[test]
fn truncated_frame_followed_by_good_one_api_mode() {
    // In AP=1 the truncated frame's length swallows the good frame; the decoder re-reads it.
    let good = enc(&rx16(b"beacon"), Mode::Api);
    for cut in 1..good.len() {
        let mut s = good[..cut].to_vec();
        s.extend_from_slice(&good);
        // Trailing bytes let the swallowing frame end; a later good frame must follow too.
        s.extend_from_slice(AT_MY);
        s.extend_from_slice(AT_MY);
        let (frames, errors) = run(Mode::Api, &s);
        assert!(!errors.is_empty(), "cut {cut}");
        assert!(
            frames.contains(&good[3..good.len() - 1].to_vec()),
            "cut {cut}: {frames:?}"
        );
        assert!(
            frames.iter().filter(|f| f[..] == AT_MY[3..7]).count() >= 1,
            "cut {cut}"
        );
    }
}

#[test]
fn idle_line_ends_a_truncated_api_mode_frame_and_recovers_the_inner_one() {
    let mut dec = Decoder::new(Mode::Api);
    let mut s = vec![0x7E, 0x00, 0x20, 0x81];
    s.extend_from_slice(AT_MY);
    let mut frames = 0;
    dec.feed(&s, |ev| {
        ev.unwrap();
        frames += 1;
    });
    assert_eq!(frames, 0);
    dec.idle();
    assert_eq!(
        dec.poll(),
        Some(Err(DecodeError::Truncated { received: 11 }))
    );
    let f = dec.poll().unwrap().unwrap();
    assert_eq!(f.data(), &AT_MY[3..7]);
    assert_eq!(dec.poll(), None);
}

#[test]
fn start_byte_inside_api_mode_frame_data_is_data() {
    let f = rx16(&[0x7E, 0x7E, 0x00, 0x7D, 0x11]);
    let bytes = enc(&f, Mode::Api);
    assert!(bytes[1..].contains(&0x7E));
    let (frames, errors) = run(Mode::Api, &bytes);
    assert!(errors.is_empty());
    assert_eq!(Frame::parse(&frames[0]).unwrap(), f);
}

#[test]
fn escaped_mode_escapes_length_and_checksum() {
    // Frame data of length 0x11 (escaped length byte) whose checksum is 0x7E (escaped checksum).
    // Unknown type 0x42 + 16 bytes = 0x11 bytes; the last byte makes the checksum 0x7E:
    // 0xFF - (0x42 + last) = 0x7E.
    let mut body = [0u8; 16];
    body[15] = 0xFFu8.wrapping_sub(0x7E).wrapping_sub(0x42);
    let f = Frame::Unknown {
        frame_type: 0x42,
        data: &body,
    };
    let bytes = enc(&f, Mode::Escaped);
    assert_eq!(
        &bytes[..4],
        &[0x7E, 0x00, 0x7D, 0x31],
        "length 0x11 escaped"
    );
    assert_eq!(
        &bytes[bytes.len() - 2..],
        &[0x7D, 0x5E],
        "checksum 0x7E escaped"
    );
    let (frames, errors) = run(Mode::Escaped, &bytes);
    assert!(errors.is_empty());
    assert_eq!(Frame::parse(&frames[0]).unwrap(), f);
}

#[test]
fn every_prefix_then_good_frame_yields_the_good_frame() {
    // Whatever broken prefix precedes it, a good frame (followed by a second copy to flush
    // API mode 1's re-reading) always comes out intact.
    for mode in MODES {
        let good = enc(&rx16(&[0x7E, 0x11, 0x13, 0x7D, 9]), mode);
        for cut in 0..good.len() {
            let mut s = good[..cut].to_vec();
            s.extend_from_slice(&good);
            s.extend_from_slice(&good);
            let (frames, _) = run(mode, &s);
            assert!(
                frames.len() >= 2,
                "{mode:?} cut {cut}: {} frames",
                frames.len()
            );
            assert!(frames.iter().all(|f| f[..] == good_data(&good, mode)[..]));
        }
    }
}

fn good_data(encoded: &[u8], mode: Mode) -> Vec<u8> {
    let (frames, _) = run(mode, encoded);
    frames[0].clone()
}

#[test]
fn fixed_size_frames_with_trailing_bytes_are_rejected_not_truncated() {
    // A fuzzer-found case: a fixed-size frame with trailing bytes must not parse with the bytes
    // dropped.
    for data in [&[0x8A, 0x00, 0x01][..], &[0x89, 0x01, 0x00, 0x00][..]] {
        let err = Frame::parse(data).unwrap_err();
        assert!(matches!(err, xbee_api::ParseError::TooLong { len, .. } if len == data.len()));
    }
    assert!(Frame::parse(&[0x8A, 0x00]).is_ok());
}

/// A bad checksum reports the checksum of the data as received and the checksum byte as
/// received, whichever byte after the length was changed (the decoder sums as bytes arrive).
#[test]
fn bad_checksum_reports_what_was_received() {
    let data = [0x81, 0x12, 0x34, 0x28, 0x00, 0x7E, 0x7D, 0x11, 0x13, 0x55];
    for mode in MODES {
        for at in 0..=data.len() {
            for flip in [0x01, 0x80, 0x5A] {
                let mut frame = data.to_vec();
                frame.push(xbee_api::checksum(&data));
                frame[at] ^= flip;
                let (received, body) = frame.split_last().unwrap();
                // The stream as the radio would send it: escaped (AP=2), then a good frame.
                let mut s = vec![xbee_api::START, 0, data.len() as u8];
                for &b in &frame {
                    if mode == Mode::Escaped && xbee_api::needs_escape(b) {
                        s.extend([xbee_api::ESCAPE, b ^ xbee_api::ESCAPE_XOR]);
                    } else {
                        s.push(b);
                    }
                }
                s.extend_from_slice(AT_MY);
                let (frames, errors) = run(mode, &s);
                // (In AP=1 the bytes after the data's 0x7E are then re-read: more errors.)
                assert_eq!(
                    errors.first(),
                    Some(&DecodeError::BadChecksum {
                        computed: xbee_api::checksum(body),
                        received: *received,
                    }),
                    "{mode:?} byte {at} ^ {flip:#04x}"
                );
                assert_eq!(frames.len(), 1, "{mode:?} byte {at} ^ {flip:#04x}");
            }
        }
    }
}
