//! The radio driver against a scripted fake XBee (tests/common): exact bytes on the wire,
//! frame-id matching, nothing lost while waiting, bounded timeouts, channel switching order and
//! bring-up from every state a radio can be found in.

mod common;

use common::{at_resp, data, enc, setup, Reply};
use xbee_api::driver::{
    BringUp, BringUpConfig, Encryption, Error, RadioConfig, BAUD_CODES, BAUD_RATES, FIXED_SETTINGS,
};
use xbee_api::{AtStatus, DecodeError, Frame, Mode, Rssi, TxStatus};

const MODES: [Mode; 2] = [Mode::Api, Mode::Escaped];

fn ap_of(mode: Mode) -> u8 {
    mode.ap()
}

/// Frame data of an RX16 frame whose header and payload need escaping.
fn rx16() -> Vec<u8> {
    data(&Frame::Rx16 {
        source: 0x7E11,
        rssi: Rssi(0x13),
        options: 0x02,
        data: &[0x7E, 0x7D, 0x11, 0x13, b'h', b'i'],
    })
}

#[test]
fn send_writes_exactly_the_encoded_frame_in_both_modes() {
    // Digi's own example frame (AP=1), as in the crate README.
    let (m, mut radio) = setup(1, 57600, Mode::Api);
    let hello = Frame::Tx16 {
        frame_id: 1,
        dest: 0x5001,
        options: 0,
        data: b"Hello",
    };
    radio.send(&hello).unwrap();
    assert_eq!(
        m.borrow().wire,
        [0x7E, 0x00, 0x0A, 0x01, 0x01, 0x50, 0x01, 0x00, 0x48, 0x65, 0x6C, 0x6C, 0x6F, 0xB8]
    );

    for mode in MODES {
        let (m, mut radio) = setup(ap_of(mode), 57600, mode);
        // Payload, address and (for id 0x11) frame id all need escaping in AP=2.
        let payload = [0x7E, 0x7D, 0x11, 0x13, 0x00, 0xFF];
        let mut expected = vec![];
        for i in 1..=0x13u8 {
            let id = radio.send_tx16(0x7D13, &payload).unwrap();
            assert_eq!(id, i, "frame ids count from 1");
            expected.extend(enc(
                &Frame::Tx16 {
                    frame_id: id,
                    dest: 0x7D13,
                    options: 0,
                    data: &payload,
                },
                mode,
            ));
        }
        assert_eq!(m.borrow().wire, expected, "{mode:?}");
        assert_eq!(
            m.borrow().frames.len(),
            0x13,
            "the radio decodes every frame"
        );
    }
}

#[test]
fn frame_ids_skip_zero() {
    let (_m, mut radio) = setup(2, 57600, Mode::Escaped);
    let ids: Vec<u8> = (0..300).map(|_| radio.next_frame_id()).collect();
    assert_eq!(ids[0], 1);
    assert_eq!(ids[254], 255);
    assert_eq!(ids[255], 1);
    assert!(!ids.contains(&0));
}

#[test]
fn send_rejects_oversize_frames() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    let big = [0u8; 120];
    // More than 100 bytes of RF payload…
    assert_eq!(
        radio.send_tx16(0xFFFF, &big[..101]),
        Err(Error::TooLong { len: 106 })
    );
    // …or frame data longer than any S1 frame.
    let unknown = Frame::Unknown {
        frame_type: 0x42,
        data: &big[..111],
    };
    assert_eq!(radio.send(&unknown), Err(Error::TooLong { len: 112 }));
    assert!(m.borrow().wire.is_empty());
    // 100 bytes of payload is the most an S1 takes, and goes.
    radio.send_tx16(0xFFFF, &big[..100]).unwrap();
    assert_eq!(m.borrow().frames.len(), 1);
}

#[test]
fn at_command_returns_the_response_with_its_frame_id() {
    for mode in MODES {
        let (m, mut radio) = setup(ap_of(mode), 57600, mode);
        m.borrow_mut().ch = 0x11; // escaped in AP=2
        let mut others = 0;
        let v = radio.at_command(*b"CH", &[], 100, |_| others += 1).unwrap();
        assert_eq!(v.as_bytes(), [0x11]);
        assert_eq!(v.as_u32(), Some(0x11));
        assert_eq!(others, 0);
        assert_eq!(
            m.borrow().wire,
            enc(
                &Frame::AtCommand {
                    frame_id: 1,
                    command: *b"CH",
                    parameter: &[]
                },
                mode
            )
        );
        // A set command answers an empty value.
        let v = radio
            .at_command(*b"CH", &[0x0F], 100, |_| others += 1)
            .unwrap();
        assert!(v.as_bytes().is_empty());
        assert_eq!(v.as_u32(), None);
        assert_eq!(m.borrow().ch, 0x0F);
        assert_eq!(m.borrow().host_frames()[1], "ATCH id=2 [0F]");
    }
}

#[test]
fn at_set_sends_the_command_and_checks_the_status() {
    for mode in MODES {
        let (m, mut radio) = setup(ap_of(mode), 57600, mode);
        let mut others = 0;
        radio.at_set(*b"CH", &[0x0F], 100, |_| others += 1).unwrap();
        assert_eq!(m.borrow().ch, 0x0F);
        assert_eq!(m.borrow().host_frames()[0], "ATCH id=1 [0F]");
        assert_eq!(others, 0);
        // The same frame as `at_command` writes.
        let (m2, mut radio2) = setup(ap_of(mode), 57600, mode);
        radio2.at_command(*b"CH", &[0x0F], 100, |_| ()).unwrap();
        assert_eq!(m.borrow().wire, m2.borrow().wire);
    }
    // An error status is an error; no answer is a timeout.
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().expect(
        None,
        Reply::Frames(vec![at_resp(1, b"CH", AtStatus::INVALID_PARAMETER, &[])]),
    );
    assert_eq!(
        radio.at_set(*b"CH", &[0x30], 100, |_| ()),
        Err(Error::At {
            command: *b"CH",
            status: AtStatus::INVALID_PARAMETER
        })
    );
    m.borrow_mut().expect(None, Reply::Silent);
    assert_eq!(
        radio.at_set(*b"CH", &[0x0C], 50, |_| ()),
        Err(Error::Timeout { command: *b"CH" })
    );
}

#[test]
fn response_with_wrong_frame_id_or_command_goes_to_the_callback() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    let stale = at_resp(99, b"MY", AtStatus::OK, &[0x00, 0x07]);
    let wrong_cmd = at_resp(1, b"ID", AtStatus::OK, &[0x33, 0x32]);
    let right = at_resp(1, b"MY", AtStatus::OK, &[0x12, 0x34]);
    m.borrow_mut().expect(
        Some(data(&Frame::AtCommand {
            frame_id: 1,
            command: *b"MY",
            parameter: &[],
        })),
        Reply::Frames(vec![stale.clone(), wrong_cmd.clone(), right]),
    );
    let mut others = vec![];
    let v = radio
        .at_command(*b"MY", &[], 100, |raw| others.push(raw.data().to_vec()))
        .unwrap();
    assert_eq!(v.as_u32(), Some(0x1234));
    assert_eq!(others, vec![stale, wrong_cmd]);
    assert_eq!(radio.stats().unexpected, 2);
}

/// `Ap2<false>` keeps no counters and otherwise drives the radio as `Mode::Escaped` does: the
/// same bytes on the wire, the same answers and callbacks, the same bring-up.
#[test]
fn ap2_without_counters_drives_the_radio_the_same_and_counts_nothing() {
    use xbee_api::driver::{DriverStats, Radio};
    use xbee_api::Ap2;
    let run = |uncounted: bool| {
        let (m, radio) = setup(2, 57600, Mode::Escaped);
        let (serial, clock) = radio.release();
        let stale = at_resp(99, b"MY", AtStatus::OK, &[0x00, 0x07]);
        let right = at_resp(1, b"MY", AtStatus::OK, &[0x12, 0x34]);
        m.borrow_mut().expect(
            None,
            Reply::Frames(vec![stale.clone(), vec![0x88, 0x05], right]),
        );
        let mut others = vec![];
        let mut on_other = |raw: xbee_api::RawFrame<'_>| others.push(raw.data().to_vec());
        let (v, bring_up, stats) = if uncounted {
            let mut radio = Radio::new(serial, clock, Ap2::<false>);
            let v = radio.at_command(*b"MY", &[], 100, &mut on_other);
            let b = radio.bring_up(&fast_config());
            (v, b, radio.stats())
        } else {
            let mut radio = Radio::new(serial, clock, Mode::Escaped);
            let v = radio.at_command(*b"MY", &[], 100, &mut on_other);
            let b = radio.bring_up(&fast_config());
            (v, b, radio.stats())
        };
        let wire = m.borrow().wire.clone();
        (v, bring_up, others, wire, stats)
    };
    let (v, b, others, wire, stats) = run(false);
    let (v0, b0, others0, wire0, stats0) = run(true);
    assert_eq!(v.unwrap().as_u32(), Some(0x1234));
    assert_eq!(b, Ok(BringUp::AlreadyApi));
    assert_eq!(
        (stats.unexpected, stats.malformed),
        (1, 1),
        "counted with Mode"
    );
    assert_eq!((v0.map(|v| v.as_u32()), b0), (Ok(Some(0x1234)), b));
    assert_eq!((others0, wire0), (others, wire));
    assert_eq!(stats0, DriverStats::default(), "nothing counted");
}

/// A quick bring-up that sets MY, ID and CH.
fn fast_config() -> BringUpConfig {
    BringUpConfig {
        my: Some(0x0007),
        pan_id: Some(0x3332),
        channel: Some(0x0C),
        ..fast()
    }
}

#[test]
fn frames_arriving_during_an_at_command_reach_the_callback_intact() {
    for mode in MODES {
        let (m, mut radio) = setup(ap_of(mode), 57600, mode);
        let status = data(&Frame::ModemStatus {
            status: xbee_api::ModemStatus::HARDWARE_RESET,
        });
        let unknown = vec![0x42, 0x7E, 0x01];
        let short = vec![0x81, 0x00]; // RX16 too short to parse: still delivered
        let short_at = vec![0x88, 0x01, b'I']; // an AT response too short to read: counted
        m.borrow_mut().expect(
            None,
            Reply::Frames(vec![
                rx16(),
                status.clone(),
                unknown.clone(),
                short.clone(),
                short_at.clone(),
                at_resp(1, b"ID", AtStatus::OK, &[0x7E, 0x7D]),
                rx16(),
            ]),
        );
        let mut others = vec![];
        let v = radio
            .at_command(*b"ID", &[], 100, |raw| others.push(raw.data().to_vec()))
            .unwrap();
        assert_eq!(v.as_u32(), Some(0x7E7D));
        assert_eq!(
            others,
            vec![rx16(), status, unknown, short, short_at],
            "{mode:?}"
        );
        assert_eq!(radio.stats().malformed, 1);
        // The RX16 after the response stays for the next poll, whole.
        let got = radio.poll(|raw| raw.data().to_vec());
        assert_eq!(got, Some(Ok(rx16())));
        assert_eq!(radio.poll(|_| ()), None);
    }
}

#[test]
fn at_command_times_out_when_nothing_answers() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().expect(None, Reply::Silent);
    let t0 = m.borrow().now;
    let r = radio.at_command(*b"CH", &[], 50, |_| panic!("no frames"));
    assert_eq!(r, Err(Error::Timeout { command: *b"CH" }));
    let took = m.borrow().now - t0;
    assert!((50..=52).contains(&took), "took {took} ms");
}

#[test]
fn a_late_answer_after_a_timeout_is_not_taken_for_the_next_command() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().at_delay = 80; // slower than the timeout
    assert_eq!(
        radio.at_command(*b"CH", &[], 50, |_| {}),
        Err(Error::Timeout { command: *b"CH" })
    );
    m.borrow_mut().at_delay = 2;
    let mut others = vec![];
    let v = radio
        .at_command(*b"CH", &[], 100, |raw| others.push(raw.data().to_vec()))
        .unwrap();
    assert_eq!(v.as_u32(), Some(0x0C));
    // The first answer (id 1) arrived during the second wait and was passed on.
    assert_eq!(others, vec![at_resp(1, b"CH", AtStatus::OK, &[0x0C])]);
}

#[test]
fn timeouts_work_across_clock_wraparound() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().now = u32::MAX - 10;
    // Answered across the wrap…
    m.borrow_mut().at_delay = 20;
    let v = radio.at_command(*b"CH", &[], 50, |_| {}).unwrap();
    assert_eq!(v.as_u32(), Some(0x0C));
    assert!(m.borrow().now < 100, "the clock wrapped");
    // …and timing out across it.
    m.borrow_mut().now = u32::MAX - 10;
    m.borrow_mut().expect(None, Reply::Silent);
    let r = radio.at_command(*b"CH", &[], 50, |_| {});
    assert_eq!(r, Err(Error::Timeout { command: *b"CH" }));
    assert_eq!(m.borrow().now, (u32::MAX - 10).wrapping_add(50));
}

/// The driver times its waits in 16 bits: a longer timeout waits 65 535 ms, the longest there is.
#[test]
fn timeouts_above_16_bits_wait_65535_ms() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().now = u32::MAX - 10;
    m.borrow_mut().expect(None, Reply::Silent);
    let t0 = m.borrow().now;
    let r = radio.at_command(*b"CH", &[], 100_000, |_| {});
    assert_eq!(r, Err(Error::Timeout { command: *b"CH" }));
    let took = m.borrow().now.wrapping_sub(t0);
    assert!((65_535..=65_537).contains(&took), "took {took} ms");
}

#[test]
fn at_error_status_is_a_typed_error() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    // The model radio refuses channel 0x30…
    assert_eq!(
        radio.at_command(*b"CH", &[0x30], 100, |_| {}),
        Err(Error::At {
            command: *b"CH",
            status: AtStatus::INVALID_PARAMETER
        })
    );
    // …and unknown commands.
    assert_eq!(
        radio.at_command(*b"ZZ", &[], 100, |_| {}),
        Err(Error::At {
            command: *b"ZZ",
            status: AtStatus::INVALID_COMMAND
        })
    );
    // A scripted plain ERROR.
    m.borrow_mut().expect(
        None,
        Reply::Frames(vec![at_resp(3, b"MY", AtStatus::ERROR, &[])]),
    );
    assert_eq!(
        radio.at_command(*b"MY", &[0, 1], 100, |_| {}),
        Err(Error::At {
            command: *b"MY",
            status: AtStatus::ERROR
        })
    );
}

#[test]
fn set_channel_waits_for_outstanding_tx_status_then_sends_ch_and_waits_for_ok() {
    for mode in MODES {
        let (m, mut radio) = setup(ap_of(mode), 57600, mode);
        m.borrow_mut().tx_delay = 30;
        let id1 = radio.send_tx16(0xFFFF, b"beacon").unwrap();
        let id2 = radio.send_tx16(0x0002, b"unicast").unwrap();
        // Frame id 0: no TX status comes, so none is waited for.
        radio
            .send(&Frame::Tx16 {
                frame_id: 0,
                dest: 0xFFFF,
                options: 0,
                data: b"x",
            })
            .unwrap();
        assert!(radio.tx_pending());
        let mut seen = vec![];
        radio
            .set_channel(0x0F, 100, |raw| seen.push(raw.data().to_vec()))
            .unwrap();
        assert!(!radio.tx_pending());
        let st = |frame_id| {
            data(&Frame::TxStatus {
                frame_id,
                status: TxStatus::SUCCESS,
            })
        };
        assert_eq!(
            seen,
            vec![st(id1), st(id2)],
            "TX statuses go to the caller too"
        );
        assert_eq!(m.borrow().ch, 0x0F);
        assert_eq!(
            m.borrow().log,
            vec![
                "-> TX16 id=1",
                "-> TX16 id=2",
                "-> TX16 id=0",
                "<- TXSTATUS id=1 st=0",
                "<- TXSTATUS id=2 st=0",
                "-> ATCH id=3 [0F]",
                "<- RESPCH id=3 st=0",
            ],
            "{mode:?}"
        );
    }
}

#[test]
fn set_channel_with_nothing_outstanding_goes_straight_to_ch() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    radio.set_channel(0x1A, 100, |_| {}).unwrap();
    assert_eq!(m.borrow().host_frames(), vec!["ATCH id=1 [1A]"]);
    assert!(m.borrow().now < 10);
}

#[test]
fn set_channel_gives_up_on_a_lost_tx_status_and_a_retry_proceeds() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().expect(None, Reply::Silent); // the TX status never comes
    radio.send_tx16(0xFFFF, b"lost").unwrap();
    assert_eq!(
        radio.set_channel(0x0D, 40, |_| {}),
        Err(Error::TxStatusTimeout)
    );
    assert_eq!(m.borrow().host_frames(), vec!["TX16 id=1"], "no CH sent");
    radio.set_channel(0x0D, 40, |_| {}).unwrap();
    assert_eq!(m.borrow().ch, 0x0D);
}

#[test]
fn set_channel_reports_a_refused_channel() {
    // Channel 0x0B does not exist on the S1 Pro, which answers INVALID_PARAMETER.
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().expect(
        None,
        Reply::Frames(vec![at_resp(1, b"CH", AtStatus::INVALID_PARAMETER, &[])]),
    );
    assert_eq!(
        radio.set_channel(0x0B, 40, |_| {}),
        Err(Error::At {
            command: *b"CH",
            status: AtStatus::INVALID_PARAMETER
        })
    );
}

#[test]
fn read_config_reads_my_id_ch_ap() {
    for mode in MODES {
        let (m, mut radio) = setup(ap_of(mode), 57600, mode);
        {
            let mut m = m.borrow_mut();
            m.my = 0x0102;
            m.id = 0x7E7D;
            m.ch = 0x13;
        }
        let c = radio.read_config(100, |_| {}).unwrap();
        assert_eq!(
            c,
            RadioConfig {
                my: 0x0102,
                pan_id: 0x7E7D,
                channel: 0x13,
                ap: mode.ap()
            }
        );
        assert_eq!(
            m.borrow().host_frames(),
            vec![
                "ATMY id=1 []",
                "ATID id=2 []",
                "ATCH id=3 []",
                "ATAP id=4 []"
            ]
        );
    }
}

#[test]
fn read_config_rejects_a_malformed_value() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().expect(
        None,
        Reply::Frames(vec![at_resp(1, b"MY", AtStatus::OK, &[1, 2, 3, 4, 5])]),
    );
    assert_eq!(
        radio.read_config(100, |_| {}),
        Err(Error::Unexpected { command: *b"MY" })
    );
}

#[test]
fn poll_hands_frames_to_the_closure_and_reports_stream_errors() {
    for mode in MODES {
        let (m, mut radio) = setup(ap_of(mode), 57600, mode);
        assert_eq!(radio.poll(|_| ()), None);
        {
            let mut m = m.borrow_mut();
            m.emit(b"noise", 0, None);
            let f = rx16();
            m.emit_frame(&f, 0);
            m.emit_frame(&f, 0);
        }
        assert_eq!(
            radio.poll(|_| ()),
            Some(Err(Error::Decode(DecodeError::Garbage { bytes: 5 })))
        );
        let rssi = radio.poll(|raw| raw.parse().unwrap().rssi());
        assert_eq!(rssi, Some(Ok(Some(Rssi(0x13)))));
        let got = radio.poll(|raw| raw.data().to_vec());
        assert_eq!(got, Some(Ok(rx16())));
        assert_eq!(radio.poll(|_| ()), None);
        assert_eq!(radio.stats().decoder.frames, 2);
        assert_eq!(radio.stats().decoder.garbage_bytes, 5);
    }
}

/// `poll_with_serial` hands over the same frames as `poll`, and the serial port beside them:
/// what the closure writes goes out on the UART while the frame is still read in place.
#[test]
fn poll_with_serial_lends_the_port_beside_the_frame() {
    use embedded_hal_nb::serial::Write;
    for mode in MODES {
        let (m, mut radio) = setup(ap_of(mode), 57600, mode);
        {
            let mut m = m.borrow_mut();
            m.emit_frame(&rx16(), 0);
            m.emit(b"noise", 0, None);
            m.emit_frame(&rx16(), 0);
        }
        let got = radio.poll_with_serial(|raw, serial| {
            for &b in b"seen " {
                serial.write(b).unwrap();
            }
            raw.data().to_vec()
        });
        assert_eq!(got, Some(Ok(rx16())), "{mode:?}");
        assert_eq!(m.borrow().wire, b"seen ", "{mode:?}");
        // Stream errors and the idle end as from `poll`; the closure sees only frames.
        assert_eq!(
            radio.poll_with_serial(|_, _| ()),
            Some(Err(Error::Decode(DecodeError::Garbage { bytes: 5 })))
        );
        let got = radio.poll_with_serial(|raw, _| raw.data().to_vec());
        assert_eq!(got, Some(Ok(rx16())), "{mode:?}");
        assert_eq!(radio.poll_with_serial(|_, _| ()), None);
    }
}

#[test]
fn poll_ends_a_frame_that_stalls() {
    for mode in MODES {
        let (m, mut radio) = setup(ap_of(mode), 57600, mode);
        let whole = enc(
            &Frame::Rx16 {
                source: 1,
                rssi: Rssi(40),
                options: 0,
                data: b"abc",
            },
            mode,
        );
        m.borrow_mut().emit(&whole[..6], 0, None);
        let mut events = vec![];
        for _ in 0..100 {
            if let Some(ev) = radio.poll(|_| ()) {
                events.push(ev);
            }
        }
        assert_eq!(
            events,
            vec![Err(Error::Decode(DecodeError::Truncated { received: 5 }))],
            "{mode:?}"
        );
        // And the next frame is read normally.
        m.borrow_mut().emit(&whole, 0, None);
        assert_eq!(radio.poll(|raw| raw.data().len()), Some(Ok(8)));
    }
}

#[test]
fn poll_stops_on_a_babbling_line() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().emit(&[0x55; 1000], 0, None);
    // Returns within its byte budget rather than reading forever.
    assert_eq!(radio.poll(|_| ()), None);
    assert!(m.borrow().now == 0);
}

#[test]
fn a_uart_that_never_takes_a_byte_times_out() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().write_blocked = true;
    assert_eq!(radio.send_tx16(1, b"x"), Err(Error::WriteTimeout));
    assert!(m.borrow().now <= 101);
}

fn fast() -> BringUpConfig {
    BringUpConfig {
        guard_ms: 25, // the model's GT is 20 ms
        timeout_ms: 50,
        ..BringUpConfig::new()
    }
}

#[test]
fn bring_up_of_a_radio_already_in_api_mode_2_sends_one_query() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    assert_eq!(radio.bring_up(&fast()), Ok(BringUp::AlreadyApi));
    let m = m.borrow();
    // One `AP` query, then only the fixed settings.
    assert_fixed_settings(&m.host_frames()[1..]);
    assert!(m.wire.starts_with(&enc(
        &Frame::AtCommand {
            frame_id: 1,
            command: *b"AP",
            parameter: &[]
        },
        Mode::Escaped
    )));
    assert!(m.cmd_lines.is_empty());
    assert_eq!(m.writes, 0);
    assert_eq!(m.host_bauds, vec![57600]);
}

#[test]
fn bring_up_sets_my_id_ch() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().emit_frame(
        &data(&Frame::ModemStatus {
            status: xbee_api::ModemStatus::HARDWARE_RESET,
        }),
        0,
    );
    let cfg = BringUpConfig {
        my: Some(0x0003),
        pan_id: Some(0x1234),
        channel: Some(0x0E),
        ..fast()
    };
    assert_eq!(radio.bring_up(&cfg), Ok(BringUp::AlreadyApi));
    let m = m.borrow();
    assert_eq!(
        m.host_frames(),
        vec![
            "ATAP id=1 []",
            "ATMY id=2 [00, 03]",
            "ATID id=3 [12, 34]",
            "ATCH id=4 [0E]",
            "ATRR id=5 [00]",
            "ATMM id=6 [00]",
            "ATSM id=7 [00]",
            "ATA1 id=8 [00]",
            "ATPL id=9 [04]",
        ]
    );
    assert_eq!((m.my, m.id, m.ch), (3, 0x1234, 0x0E));
    assert_eq!(
        radio.stats().dropped,
        1,
        "the modem status was dropped, and counted"
    );
}

#[test]
fn bring_up_reports_a_setting_the_radio_refuses() {
    // Channel 0x0B on a radio that has no such channel (an S1 Pro): error status 3.
    let (_, mut radio) = setup(2, 57600, Mode::Escaped);
    let cfg = BringUpConfig {
        channel: Some(0x0A),
        ..fast()
    };
    assert_eq!(
        radio.bring_up(&cfg),
        Err(Error::At {
            command: *b"CH",
            status: AtStatus::INVALID_PARAMETER
        })
    );
}

/// A key with bytes API mode 2 escapes.
const KEY: [u8; 16] = [
    0x7E, 0x7D, 0x11, 0x13, 0x00, 0x01, 0x02, 0x03, 0xC0, 0xFF, 0xEE, 0x42, 0x99, 0x88, 0x77, 0x66,
];

#[test]
fn bring_up_sets_the_channel_access_after_ch_and_before_encryption() {
    for mode in MODES {
        let (m, mut radio) = setup(ap_of(mode), 57600, mode);
        let cfg = BringUpConfig {
            channel: Some(0x0E),
            backoff_exponent: Some(1),
            cca_threshold: Some(0x50),
            encryption: Encryption::Off,
            ..fast()
        };
        assert_eq!(radio.bring_up(&cfg), Ok(BringUp::AlreadyApi));
        let m = m.borrow();
        assert_eq!(
            m.host_frames(),
            [
                "ATAP id=1 []",
                "ATCH id=2 [0E]",
                "ATRN id=3 [01]",
                "ATCA id=4 [50]",
                "ATEE id=5 [00]",
                "ATRR id=6 [00]",
                "ATMM id=7 [00]",
                "ATSM id=8 [00]",
                "ATA1 id=9 [00]",
                "ATPL id=10 [04]",
            ],
            "{mode:?}"
        );
        assert_eq!((m.rn, m.ca), (1, 0x50));
    }
    // Left alone by default.
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().rn = 3;
    assert_eq!(radio.bring_up(&fast()), Ok(BringUp::AlreadyApi));
    assert_eq!((m.borrow().rn, m.borrow().ca), (3, 0x2C));
    // A value the radio refuses (`RN` is 0…3) stops bring-up with the command.
    let (_, mut radio) = setup(2, 57600, Mode::Escaped);
    let cfg = BringUpConfig {
        backoff_exponent: Some(4),
        ..fast()
    };
    assert_eq!(
        radio.bring_up(&cfg),
        Err(Error::At {
            command: *b"RN",
            status: AtStatus::INVALID_PARAMETER
        })
    );
}

#[test]
fn bring_up_leaves_encryption_alone_by_default() {
    assert_eq!(BringUpConfig::new().encryption, Encryption::Leave);
    assert_eq!(BringUpConfig::default().encryption, Encryption::Leave);
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().ee = 1;
    let cfg = BringUpConfig {
        channel: Some(0x0E),
        ..fast()
    };
    assert_eq!(radio.bring_up(&cfg), Ok(BringUp::AlreadyApi));
    let m = m.borrow();
    assert_eq!(
        m.host_frames(),
        [
            "ATAP id=1 []",
            "ATCH id=2 [0E]",
            "ATRR id=3 [00]",
            "ATMM id=4 [00]",
            "ATSM id=5 [00]",
            "ATA1 id=6 [00]",
            "ATPL id=7 [04]",
        ]
    );
    assert_eq!((m.ee, &m.ky), (1, &None));
}

#[test]
fn bring_up_turns_encryption_off() {
    for mode in MODES {
        let (m, mut radio) = setup(ap_of(mode), 57600, mode);
        m.borrow_mut().ee = 1;
        let cfg = BringUpConfig {
            my: Some(0x0003),
            encryption: Encryption::Off,
            ..fast()
        };
        assert_eq!(radio.bring_up(&cfg), Ok(BringUp::AlreadyApi));
        let m = m.borrow();
        assert_eq!(
            m.host_frames(),
            [
                "ATAP id=1 []",
                "ATMY id=2 [00, 03]",
                "ATEE id=3 [00]",
                "ATRR id=4 [00]",
                "ATMM id=5 [00]",
                "ATSM id=6 [00]",
                "ATA1 id=7 [00]",
                "ATPL id=8 [04]",
            ]
        );
        assert_eq!((m.ee, &m.ky), (0, &None), "no key sent");
    }
}

#[test]
fn bring_up_sets_the_key_then_turns_encryption_on_after_my_id_ch() {
    for mode in MODES {
        let (m, mut radio) = setup(ap_of(mode), 57600, mode);
        let cfg = BringUpConfig {
            my: Some(0x0003),
            pan_id: Some(0x1234),
            channel: Some(0x0E),
            encryption: Encryption::Key(KEY),
            ..fast()
        };
        assert_eq!(radio.bring_up(&cfg), Ok(BringUp::AlreadyApi));
        let m = m.borrow();
        // KY is write-only: set, never queried.
        assert_eq!(
            m.host_frames(),
            [
                "ATAP id=1 []",
                "ATMY id=2 [00, 03]",
                "ATID id=3 [12, 34]",
                "ATCH id=4 [0E]",
                &format!("ATKY id=5 {KEY:02X?}"),
                "ATEE id=6 [01]",
                "ATRR id=7 [00]",
                "ATMM id=8 [00]",
                "ATSM id=9 [00]",
                "ATA1 id=10 [00]",
                "ATPL id=11 [04]",
            ]
        );
        assert_eq!((m.ee, m.ky.as_deref()), (1, Some(&KEY[..])));
        // The escaped key bytes on the wire decode to the key (the model decoded them).
        assert_eq!(m.frames[4][4..], KEY);
    }
}

#[test]
fn bring_up_stops_at_a_rejected_key_before_ee() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().ky_status = Some(AtStatus::INVALID_PARAMETER);
    let cfg = BringUpConfig {
        encryption: Encryption::Key(KEY),
        ..fast()
    };
    assert_eq!(
        radio.bring_up(&cfg),
        Err(Error::At {
            command: *b"KY",
            status: AtStatus::INVALID_PARAMETER
        })
    );
    let m = m.borrow();
    assert_eq!(
        m.host_frames().last().unwrap(),
        &format!("ATKY id=2 {KEY:02X?}")
    );
    assert_eq!((m.ee, &m.ky), (0, &None), "EE never set");
    // A radio that does not know KY at all (status 2) is an error too.
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().ky_status = Some(AtStatus::INVALID_COMMAND);
    assert_eq!(
        radio.bring_up(&cfg).map_err(|e| e.code()),
        Err(Error::At {
            command: *b"KY",
            status: AtStatus::INVALID_COMMAND
        }
        .code())
    );
}

/// Checks the command-mode session and the radio's final state.
fn assert_configured(m: &common::Model, mode: Mode) {
    assert_eq!(
        m.cmd_lines,
        vec![
            format!("ATAP{}", mode.ap()),
            "ATBD6".into(),
            "ATWR".into(),
            "ATCN".into()
        ]
    );
    assert_eq!(m.ap, mode.ap());
    assert_eq!(m.baud, 57600);
    assert_eq!(m.writes, 1);
    // The frames the host wrote last: the query that confirms the mode in API at 57600, then
    // the fixed settings.
    let frames = m.host_frames();
    let tail = &frames[frames.len() - 6..];
    assert!(tail[0].starts_with("ATAP id="), "{tail:?}");
    assert_fixed_settings(&tail[1..]);
}

/// `frames` are the fixed settings, each set once, in order.
fn assert_fixed_settings(frames: &[String]) {
    assert_eq!(frames.len(), FIXED_SETTINGS.len());
    for (frame, (command, value)) in frames.iter().zip(FIXED_SETTINGS) {
        let name = format!("AT{}", std::str::from_utf8(&command).unwrap());
        assert!(frame.starts_with(&name) && frame.ends_with(&format!("[{value:02X}]")));
    }
}

#[test]
fn bring_up_of_a_radio_in_the_other_api_mode() {
    for (radio_ap, mode) in [(1, Mode::Escaped), (2, Mode::Api)] {
        let (m, mut radio) = setup(radio_ap, 57600, mode);
        assert_eq!(
            radio.bring_up(&fast()),
            Ok(BringUp::Configured { baud: 57600 })
        );
        let m = m.borrow();
        assert_configured(&m, mode);
        assert_eq!(m.host_bauds, vec![57600, 57600, 57600]);
    }
}

#[test]
fn bring_up_of_a_radio_in_transparent_mode_at_57600() {
    let (m, mut radio) = setup(0, 57600, Mode::Escaped);
    assert_eq!(
        radio.bring_up(&fast()),
        Ok(BringUp::Configured { baud: 57600 })
    );
    let m = m.borrow();
    assert_configured(&m, Mode::Escaped);
    // Two AP queries that went on air as transparent data, +++ after the guard time, the four
    // commands, then the confirming query (and the fixed settings: `assert_configured`).
    let query = |id| {
        enc(
            &Frame::AtCommand {
                frame_id: id,
                command: *b"AP",
                parameter: &[],
            },
            Mode::Escaped,
        )
    };
    let mut expected = [query(1), query(2)].concat();
    expected.extend_from_slice(b"+++ATAP2\rATBD6\rATWR\rATCN\r");
    expected.extend(query(3));
    assert_eq!(m.wire[..expected.len()], expected);
}

#[test]
fn bring_up_of_a_fresh_radio_at_9600() {
    let (m, mut radio) = setup(0, 9600, Mode::Escaped);
    let t0 = m.borrow().now;
    assert_eq!(
        radio.bring_up(&fast()),
        Ok(BringUp::Configured { baud: 9600 })
    );
    let m = m.borrow();
    assert_configured(&m, Mode::Escaped);
    assert_eq!(m.host_bauds, vec![57600, 57600, 9600, 57600]);
    assert!(m.now - t0 < 1000, "took {} ms", m.now - t0);
}

#[test]
fn bring_up_finds_a_radio_at_every_rate_of_the_s1() {
    // Every `BD` value, at the rate the S1 really runs it (111 111 for `BD=7`).
    let mut codes = BAUD_CODES;
    codes.sort();
    assert_eq!(codes, [0, 1, 2, 3, 4, 5, 6, 7]);
    assert!(BAUD_RATES.contains(&111_111) && !BAUD_RATES.contains(&115_200));
    for (i, &baud) in BAUD_RATES.iter().enumerate() {
        for ap in [0, 1] {
            let (m, mut radio) = setup(ap, baud, Mode::Escaped);
            assert_eq!(radio.bring_up(&fast()), Ok(BringUp::Configured { baud }));
            let m = m.borrow();
            assert_configured(&m, Mode::Escaped);
            assert_eq!(m.host_bauds.len(), i + 3, "{baud}");
        }
    }
}

#[test]
fn bring_up_of_a_radio_that_never_answers_fails_in_bounded_time() {
    let (m, mut radio) = setup(0, 57600, Mode::Escaped);
    m.borrow_mut().dead = true;
    let cfg = fast();
    assert_eq!(radio.bring_up(&cfg), Err(Error::NoResponse));
    let m = m.borrow();
    let (t, g) = (u32::from(cfg.timeout_ms), u32::from(cfg.guard_ms));
    let bound = 2 * t + 8 * (2 * g + t) + 20;
    assert!(m.now <= bound, "took {} ms, bound {bound}", m.now);
    assert_eq!(m.host_bauds, [&[57600][..], &BAUD_RATES[..]].concat());
    assert_eq!(m.wire.iter().filter(|&&b| b == b'+').count(), 24);
}

#[test]
fn bring_up_of_a_radio_that_answers_garbage() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().babble = true;
    assert_eq!(radio.bring_up(&fast()), Err(Error::Garbage));
    assert_ne!(Error::Garbage.code(), Error::NoResponse.code());
}

#[test]
fn bring_up_reports_a_rejected_command() {
    let (m, mut radio) = setup(0, 57600, Mode::Escaped);
    m.borrow_mut().reject = Some("WR");
    assert_eq!(
        radio.bring_up(&fast()),
        Err(Error::Rejected { command: *b"WR" })
    );
    assert_eq!(m.borrow().cmd_lines, vec!["ATAP2", "ATBD6", "ATWR"]);
}

#[test]
fn bring_up_reports_a_radio_silent_after_configuration() {
    let (m, mut radio) = setup(0, 57600, Mode::Escaped);
    // Answers command mode, but drops every API frame it is sent afterwards.
    for _ in 0..4 {
        m.borrow_mut().expect(None, Reply::Silent);
    }
    assert_eq!(radio.bring_up(&fast()), Err(Error::NotConfirmed));
}

#[test]
fn bring_up_reports_a_radio_in_the_wrong_mode_after_configuration() {
    let (m, mut radio) = setup(0, 57600, Mode::Escaped);
    // Answers command mode, then answers the confirming AP query (frame id 3: the two queries
    // before went on air as transparent data) with the other API mode.
    m.borrow_mut().expect(
        None,
        Reply::Frames(vec![at_resp(3, b"AP", AtStatus::OK, &[1])]),
    );
    assert_eq!(
        radio.bring_up(&fast()),
        Err(Error::Unexpected { command: *b"AP" })
    );
    assert_eq!(m.borrow().cmd_lines.len(), 4);
}

#[test]
fn error_codes_are_distinct() {
    let all = [
        Error::Serial(embedded_hal_nb::serial::ErrorKind::Overrun),
        Error::WriteTimeout,
        Error::Decode(DecodeError::Garbage { bytes: 1 }),
        Error::TooLong { len: 200 },
        Error::Timeout { command: *b"CH" },
        Error::TxStatusTimeout,
        Error::At {
            command: *b"CH",
            status: AtStatus::ERROR,
        },
        Error::Unexpected { command: *b"AP" },
        Error::NoResponse,
        Error::Garbage,
        Error::Rejected { command: *b"AP" },
        Error::NotConfirmed,
    ];
    let mut codes: Vec<u8> = all.iter().map(Error::code).collect();
    codes.sort();
    codes.dedup();
    assert_eq!(codes.len(), all.len());
    for e in all {
        assert!(!e.to_string().is_empty());
        // Every code has a description, and those without payload read like their Display.
        let words = Error::describe_code(e.code()).unwrap();
        if matches!(e, Error::NoResponse | Error::Garbage | Error::NotConfirmed) {
            assert_eq!(words, e.to_string());
        }
    }
    assert_eq!(Error::describe_code(0), None);
    assert_eq!(Error::describe_code(13), None);
}

#[test]
fn send_writes_every_frame_type_as_the_codec_encodes_it() {
    let payload: &[u8] = &[0x7E, 0x7D, 0x11, 0x13, 0x00];
    let frames = [
        Frame::Tx64 {
            frame_id: 0x7E,
            dest: 0x0013_A200_4000_7D11,
            options: 0x04,
            data: payload,
        },
        Frame::Tx16 {
            frame_id: 0x11,
            dest: 0x1313,
            options: 0x01,
            data: payload,
        },
        Frame::AtCommand {
            frame_id: 0x13,
            command: *b"NI",
            parameter: payload,
        },
        Frame::AtCommandQueue {
            frame_id: 5,
            command: *b"CH",
            parameter: &[0x0C],
        },
        Frame::RemoteAtCommand {
            frame_id: 6,
            dest64: 0x0013_A200_4000_7E7E,
            dest16: 0xFFFE,
            options: 0x02,
            command: *b"D0",
            parameter: &[0x05],
        },
        Frame::Rx64 {
            source: 0x7D7D_7D7D_7D7D_7D7D,
            rssi: Rssi(0x7E),
            options: 2,
            data: payload,
        },
        Frame::Rx16 {
            source: 0x7E11,
            rssi: Rssi(40),
            options: 0,
            data: payload,
        },
        Frame::Rx64Io {
            source: 1,
            rssi: Rssi(41),
            options: 0,
            data: &[1, 0x02, 0x00, 0x11, 0x13],
        },
        Frame::Rx16Io {
            source: 2,
            rssi: Rssi(42),
            options: 0,
            data: &[1, 0x02, 0x00, 0x7E, 0x7D],
        },
        Frame::AtResponse {
            frame_id: 7,
            command: *b"MY",
            status: AtStatus::OK,
            data: &[0x7E, 0x7D],
        },
        Frame::TxStatus {
            frame_id: 0x7D,
            status: TxStatus::NO_ACK,
        },
        Frame::ModemStatus {
            status: xbee_api::ModemStatus::HARDWARE_RESET,
        },
        Frame::RemoteAtResponse {
            frame_id: 8,
            source64: 0x0013_A200_4000_1111,
            source16: 0x1313,
            command: *b"SL",
            status: AtStatus::OK,
            data: &[0x40, 0x00, 0x11, 0x13],
        },
        Frame::Unknown {
            frame_type: 0x42,
            data: payload,
        },
        Frame::Unknown {
            frame_type: 0x7E,
            data: &[],
        },
    ];
    for mode in MODES {
        for f in &frames {
            let (m, mut radio) = setup(ap_of(mode), 57600, mode);
            radio.send(f).unwrap();
            assert_eq!(m.borrow().wire, enc(f, mode), "{f:?} {mode:?}");
        }
    }
}

#[test]
fn bring_up_gives_a_second_hand_radio_the_factory_behaviour() {
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    // Left over from another project: XBee retries, 802.15.4 MAC without ACKs, cyclic sleep,
    // end-device association, the lowest output power.
    for (reg, value) in [
        (*b"RR", 3),
        (*b"MM", 1),
        (*b"SM", 4),
        (*b"A1", 4),
        (*b"PL", 0),
    ] {
        m.borrow_mut()
            .fixed
            .iter_mut()
            .find(|f| f.0 == reg)
            .unwrap()
            .1 = value;
    }
    assert_eq!(radio.bring_up(&fast()), Ok(BringUp::AlreadyApi));
    let now: Vec<([u8; 2], u8)> = m.borrow().fixed.iter().map(|f| (f.0, f.1)).collect();
    assert_eq!(now, FIXED_SETTINGS);
    assert_eq!(m.borrow().writes, 0, "set at every boot, never written");
    // A radio that does not know a fixed setting fails bring-up with the command.
    let (m, mut radio) = setup(2, 57600, Mode::Escaped);
    m.borrow_mut().fixed.retain(|f| f.0 != *b"SM");
    assert_eq!(
        radio.bring_up(&fast()),
        Err(Error::At {
            command: *b"SM",
            status: AtStatus::INVALID_COMMAND
        })
    );
}
