//! The binary formats (messages, config, provisioning frames): every valid value survives
//! encode → decode, and no input makes a decoder panic; whatever decodes re-encodes to the same
//! bytes.

use loc_proto::config::{self, Config};
use loc_proto::error::crc16;
use loc_proto::msg::{
    decode_any, seal, Beacon, ChannelList, Message, Position, Relay, Report, ReportView,
    MAX_ANCHORS, MAX_CHANNELS, MAX_MESSAGE, MAX_PAYLOAD, VERSION,
};
use loc_proto::provision::{self, ProvisionParser, MAX_FRAME};
use loc_proto::{Error, Role};
use proptest::prelude::*;
use proptest::sample::select;

fn position() -> impl Strategy<Value = Position> {
    (any::<i16>(), any::<i16>()).prop_map(|(x, y)| Position { x, y })
}

fn channels() -> impl Strategy<Value = ChannelList> {
    proptest::sample::subsequence((1..=16u8).collect::<Vec<_>>(), 1..=4)
        .prop_shuffle()
        .prop_map(|c| ChannelList::new(&c).unwrap())
}

fn beacon() -> impl Strategy<Value = Beacon> {
    (
        1..=8u8,
        any::<u16>(),
        1..=16u8,
        position(),
        0..=8u8,
        any::<[u8; 8]>(),
    )
        .prop_map(|(anchor, seq, channel, position, relay_count, mut relay)| {
            for (j, r) in relay.iter_mut().enumerate() {
                if j + 1 == anchor as usize || j >= relay_count as usize {
                    *r = 0;
                }
            }
            Beacon {
                anchor,
                seq,
                channel,
                position,
                relay: Relay::from_slice(&relay[..relay_count as usize]).unwrap(),
            }
        })
}

#[allow(clippy::needless_range_loop)] // three parallel index sets read clearer as ranges
fn report() -> impl Strategy<Value = Report> {
    (
        (1..=255u8, any::<u16>(), 3..=8u8, channels(), 0..=7u8),
        // No relay rows, all of them, or a window of them.
        prop_oneof![
            Just(None),
            Just(Some(None)),
            any::<(u8, u8)>().prop_map(|w| Some(Some(w)))
        ],
        proptest::array::uniform8(position()),
        any::<[[u8; 8]; 4]>(),
        any::<[[[u8; 8]; 8]; 4]>(),
    )
        .prop_map(|((agent, seq, n, ch, failed), rows, pos, rssi, relay)| {
            let mut r = Report::new(agent, seq, n, ch);
            r.failed = failed;
            r.has_relay = rows.is_some();
            let (n, c) = (n as usize, ch.len());
            if let Some(Some((s, k))) = rows {
                let total = (n * c) as u8;
                r.relay_window = Some((s % total, k % total));
            }
            r.positions[..n].copy_from_slice(&pos[..n]);
            for k in 0..c {
                r.rssi[k][..n].copy_from_slice(&rssi[k][..n]);
                if r.has_relay {
                    for i in 0..n {
                        if !r.sends_row(k * n + i) {
                            continue;
                        }
                        for j in 0..n {
                            if i != j {
                                r.relay[k][i][j] = relay[k][i][j];
                            }
                        }
                    }
                }
            }
            r
        })
}

fn config() -> impl Strategy<Value = Config> {
    (
        select(Role::ALL.to_vec()),
        1..=255u8,
        3..=8u8,
        position(),
        config::MIN_SLOT_MS..=config::MAX_SLOT_MS,
        channels(),
        1..=16u8,
        0..0xFFFFu16,
        proptest::option::of(any::<[u8; 16]>().prop_map(config::NetworkKey)),
    )
        .prop_map(
            |(role, id, anchors, position, slot_ms, channels, sink_channel, pan_id, key)| Config {
                // A slot that holds the network's beacons.
                slot_ms: slot_ms.max(loc_proto::schedule::min_slot_ms(anchors)),
                role,
                id: if role == Role::Anchor {
                    (id - 1) % anchors + 1
                } else {
                    id
                },
                anchors,
                position,
                channels,
                sink_channel,
                pan_id,
                key,
            },
        )
}

/// Arbitrary bytes, biased to start like the format so the decoders get past the header.
fn bytes_like(prefix: &'static [u8], max: usize) -> impl Strategy<Value = Vec<u8>> {
    (
        0..=prefix.len(),
        proptest::collection::vec(any::<u8>(), 0..max),
    )
        .prop_map(move |(k, mut v)| {
            for (i, &p) in prefix[..k].iter().enumerate() {
                if i < v.len() {
                    v[i] = p;
                }
            }
            // Often make the length byte honest, and a message's CRC.
            if k >= 3 && v.len() > 3 && v[0] == 0xB5 && v[3] & 1 == 0 {
                v[3] = v.len() as u8;
            }
            if k >= 2 && v.first() == Some(&0xB5) && v.len() % 3 != 0 {
                seal(&mut v);
            }
            v
        })
}

/// `v` parses as a [`ReportView`] exactly when it decodes as a [`Report`] (with the same error
/// otherwise), and then every field the view reads is the report's.
fn view_is_decode(v: &[u8]) -> Result<(), TestCaseError> {
    let view = ReportView::parse(v);
    match Report::decode(v) {
        Err(e) => prop_assert_eq!(view, Err(e)),
        Ok(r) => {
            let view = view.unwrap();
            prop_assert_eq!(view.agent(), r.agent);
            prop_assert_eq!(view.seq(), r.seq);
            prop_assert_eq!(view.anchors(), r.anchors as usize);
            prop_assert_eq!(view.channels(), r.channels.len());
            prop_assert_eq!(view.has_relay(), r.has_relay);
            prop_assert_eq!(view.failed(), r.failed);
            let (n, c) = (view.anchors(), view.channels());
            for i in 0..n {
                prop_assert_eq!(view.position(i), r.positions[i]);
            }
            for k in 0..c.min(MAX_CHANNELS) {
                for i in 0..n {
                    prop_assert_eq!(view.rssi(k, i), r.rssi[k][i]);
                    for j in 0..n {
                        prop_assert_eq!(view.relay(k, i, j), r.relay[k][i][j]);
                    }
                    // Out of range: nothing relayed.
                    prop_assert_eq!(view.relay(k, i, n), 0);
                    prop_assert_eq!(view.relay(k, n, i), 0);
                    prop_assert_eq!(view.relay(c, i, (i + 1) % n), 0);
                }
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn report_views_read_what_reports_decode(r in report()) {
        let mut buf = [0; 256];
        if let Ok(n) = r.encode(&mut buf) {
            view_is_decode(&buf[..n])?;
        }
        // 8 anchors with relay, past the radio payload (the decoder still takes it with up to 3
        // channels; 4 do not fit the length byte).
        let n = Report::wire_size(8, r.channels.len(), true);
        buf[..4].copy_from_slice(&[0xB5, VERSION, 2, n.min(255) as u8]);
        buf[4] = r.agent;
        buf[5..7].copy_from_slice(&r.seq.to_le_bytes());
        buf[7] = 8;
        buf[8] = r.channels.len() as u8 | 0x80;
        for (k, &ch) in r.channels.as_slice().iter().enumerate() {
            buf[9 + k] = ch;
        }
        for (k, b) in buf[9 + r.channels.len()..n.min(255)].iter_mut().enumerate() {
            *b = (k as u8).wrapping_mul(37) ^ r.seq as u8;
        }
        seal(&mut buf[..n.min(255)]);
        view_is_decode(&buf[..n.min(255)])?;
    }

    #[test]
    fn report_views_take_any_bytes_as_decode_does(
        v in prop_oneof![
            bytes_like(&[0xB5, VERSION, 2], 110),
            proptest::collection::vec(any::<u8>(), 0..110),
        ]
    ) {
        view_is_decode(&v)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn beacons_round_trip(b in beacon()) {
        let mut buf = [0; MAX_PAYLOAD];
        let n = b.encode(&mut buf).unwrap();
        prop_assert_eq!(n, b.size());
        prop_assert_eq!(buf[3] as usize, n);
        prop_assert_eq!(Beacon::decode(&buf[..n]), Ok(b.clone()));
        prop_assert_eq!(decode_any(&buf[..n]), Ok(Message::Beacon(b)));
    }

    #[test]
    fn reports_round_trip_or_are_too_large(r in report()) {
        let mut buf = [0; 256];
        match r.encode(&mut buf) {
            Ok(n) => {
                prop_assert!(n <= MAX_MESSAGE);
                prop_assert_eq!(n, r.size());
                prop_assert_eq!(Report::decode(&buf[..n]), Ok(r));
                prop_assert_eq!(decode_any(&buf[..n]), Ok(Message::Report(r)));
            }
            Err(e) => {
                prop_assert!(r.size() > MAX_MESSAGE);
                prop_assert_eq!(e, Error::TooLarge { size: r.size() as u16 });
            }
        }
    }

    /// Whatever its size, a report made to fit ([`Report::fit_relay`]) is one packet, keeps
    /// as many relay rows as fit (all of them when the matrix fits), and round trips.
    #[test]
    fn reports_fit_one_packet(mut r in report()) {
        // The whole matrix, when there is relay.
        let had = r.has_relay;
        r.relay_window = None;
        for k in 0..r.channels.len() {
            for i in 0..r.anchors as usize {
                for j in 0..r.anchors as usize {
                    if i != j && had {
                        r.relay[k][i][j] = (k * 64 + i * 8 + j) as u8 | 1;
                    }
                }
            }
        }
        let before = r;
        r.fit_relay();
        prop_assert!(r.size() <= MAX_MESSAGE, "{} bytes", r.size());
        let (n, c) = (r.anchors as usize, r.channels.len());
        let kept = (0..n * c).filter(|&row| r.sends_row(row)).count();
        let fit = Report::relay_rows_that_fit(n, c);
        if had {
            prop_assert_eq!(r.has_relay, fit > 0);
            if r.has_relay {
                // Every row when the matrix fits, else as many as fit.
                prop_assert_eq!(kept, fit.min(n * c));
            }
            // The rows kept are the matrix's; the others are cleared.
            for k in 0..c {
                for i in 0..n {
                    let sent = r.sends_row(k * n + i);
                    for j in 0..n {
                        let want = if sent { before.relay[k][i][j] } else { 0 };
                        prop_assert_eq!(r.relay[k][i][j], want);
                    }
                }
            }
        } else {
            prop_assert_eq!(r, before);
        }
        let mut buf = [0; 256];
        let len = r.encode(&mut buf).unwrap();
        prop_assert_eq!(Report::decode(&buf[..len]), Ok(r));
        view_is_decode(&buf[..len])?;
    }

    #[test]
    fn configs_round_trip(c in config()) {
        let mut buf = [0; config::MAX_LEN];
        let n = c.to_bytes(&mut buf).unwrap();
        prop_assert_eq!(n, c.size());
        prop_assert_eq!(Config::from_bytes(&buf[..n]), Ok(c));
        prop_assert_eq!(crc16(&buf[..n]), 0);
        let mut f = [0; MAX_FRAME];
        let m = provision::encode(&c, &mut f).unwrap();
        prop_assert_eq!(m, n + 7);
        let mut p = ProvisionParser::new();
        let got: Vec<_> = f[..m].iter().filter_map(|&b| p.push(b)).collect();
        prop_assert_eq!(got, vec![Ok(c)]);
    }

    #[test]
    fn any_bytes_decode_without_panic_and_reencode_exactly(
        v in prop_oneof![
            bytes_like(&[0xB5, VERSION, 1], 26),
            bytes_like(&[0xB5, VERSION, 2], 110),
            proptest::collection::vec(any::<u8>(), 0..110),
        ]
    ) {
        if let Ok(m) = decode_any(&v) {
            let mut buf = [0; 256];
            let n = m.encode(&mut buf).unwrap();
            prop_assert_eq!(&buf[..n], &v[..]);
        }
        if let Ok(b) = Beacon::decode(&v) {
            prop_assert_eq!(decode_any(&v), Ok(Message::Beacon(b)));
        }
        if let Ok(r) = Report::decode(&v) {
            prop_assert_eq!(decode_any(&v), Ok(Message::Report(r)));
        }
    }

    #[test]
    fn any_config_bytes_decode_without_panic_and_reencode_exactly(
        v in prop_oneof![
            bytes_like(&[0xC5, 1], 24),
            proptest::collection::vec(any::<u8>(), 0..24),
        ],
        fix_crc in any::<bool>(),
    ) {
        let mut v = v;
        // Half the time make length and CRC right, so the field checks are reached.
        if fix_crc && v.len() >= config::MIN_LEN {
            let len = v.len().min(config::MAX_LEN);
            v[2] = len as u8;
            let crc = crc16(&v[..len - 2]);
            v[len - 2..len].copy_from_slice(&crc.to_be_bytes());
        }
        if let Ok(c) = Config::from_bytes(&v) {
            let mut buf = [0; config::MAX_LEN];
            let n = c.to_bytes(&mut buf).unwrap();
            prop_assert_eq!(&buf[..n], &v[..n]);
        }
    }

    #[test]
    fn corrupting_one_config_byte_is_caught(c in config(), i in 0usize..22, x in 1..=255u8) {
        let mut buf = [0; config::MAX_LEN];
        let n = c.to_bytes(&mut buf).unwrap();
        let i = i % n;
        buf[i] ^= x;
        prop_assert!(Config::from_bytes(&buf[..n]).is_err());
    }

    #[test]
    fn parser_survives_any_bytes_and_finds_the_next_good_frame(
        garbage in proptest::collection::vec(
            prop_oneof![any::<u8>(), select(b"HLP\x01\x14\x13\xC5".to_vec())], 0..80),
        c in config(),
    ) {
        let mut p = ProvisionParser::new();
        for &b in &garbage {
            if let Some(Ok(found)) = p.push(b) {
                // Garbage can only hold a frame by containing one whole.
                let mut f = [0; MAX_FRAME];
                let m = provision::encode(&found, &mut f).unwrap();
                prop_assert!(garbage.windows(m).any(|w| w == &f[..m]));
            }
        }
        let mut f = [0; MAX_FRAME];
        let m = provision::encode(&c, &mut f).unwrap();
        let got: Vec<_> = f[..m].iter().filter_map(|&b| p.push(b)).collect();
        prop_assert_eq!(got.last(), Some(&Ok(c)));
    }
}

#[test]
fn largest_reports_that_fit() {
    for n in 3..=MAX_ANCHORS {
        for c in 1..=4 {
            let fits = Report::wire_size(n, c, true) <= MAX_MESSAGE;
            assert_eq!(
                fits,
                matches!((n, c), (3, _) | (4, _) | (5, 1..=2) | (6, 1) | (7, 1)),
                "{n}x{c}"
            );
            assert!(
                Report::wire_size(n, c, false) <= MAX_MESSAGE,
                "{n}x{c} without relay"
            );
        }
    }
}

/// The channel checks of [`ReportView::parse`] are [`Report::decode`]'s: every pair of channel
/// bytes in a 3-anchor, 2-channel report, and every count/flag byte.
#[test]
fn report_views_check_channels_as_decode_does() {
    let r = Report::new(7, 513, 3, ChannelList::new(&[1, 2]).unwrap());
    let mut buf = [0; MAX_PAYLOAD];
    let n = r.encode(&mut buf).unwrap();
    for a in 0..=255u8 {
        for b in 0..=255u8 {
            buf[9] = a;
            buf[10] = b;
            seal(&mut buf[..n]);
            view_is_decode(&buf[..n]).unwrap();
        }
    }
    buf[9..11].copy_from_slice(&[3, 4]);
    for cf in 0..=255u8 {
        buf[8] = cf;
        seal(&mut buf[..n]);
        view_is_decode(&buf[..n]).unwrap();
    }
}
