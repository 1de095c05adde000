//! `ScriptedRadio` against the xbee fixture: AT "CH" query (frame id = attempt, 3 attempts,
//! 50 ms apart), TX16 "ok" to 0x1234 after an AT response, "rx type=.. len=.." lines.

mod common;

use simavr::{cycles_to_ms, frame_data, Avr, Match, ScriptedRadio};
use xbee_api::{Frame, Mode};

const AT_CH_1: [u8; 4] = [0x08, 0x01, b'C', b'H'];
const AT_CH_2: [u8; 4] = [0x08, 0x02, b'C', b'H'];
const AT_CH_3: [u8; 4] = [0x08, 0x03, b'C', b'H'];
/// AT response to frame 1: CH = 0x0C.
const AT_RESP_1: [u8; 6] = [0x88, 0x01, b'C', b'H', 0x00, 0x0C];
const TX_OK: [u8; 7] = [0x01, 0x10, 0x12, 0x34, 0x00, b'o', b'k'];

fn xbee() -> Avr {
    Avr::load(common::fixture("xbee")).expect("load xbee fixture")
}

#[test]
fn expect_then_answer_with_exact_frames_and_times() {
    let mut avr = xbee();
    let tx_ok = Frame::Tx16 {
        frame_id: 0x10,
        dest: 0x1234,
        options: 0,
        data: b"ok",
    };
    let mut radio = ScriptedRadio::new(Mode::Escaped)
        .expect(Match::data(&AT_CH_1), 5.0)
        .reply(&AT_RESP_1, 2.0)
        // Reply (10 bytes) + the firmware's line (17 bytes) + its TX16 (12 bytes) ≈ 7.5 ms.
        .expect(Match::frame(&tx_ok), 10.0);
    radio.run_to_end(&mut avr, 100.0).unwrap();
    radio.run_for_ms(&mut avr, 20.0).unwrap();

    assert_eq!(frame_data(&tx_ok), TX_OK);
    let frames = radio.frames();
    assert_eq!(frames.len(), 2);
    assert_eq!(frames[0].data, AT_CH_1);
    assert_eq!(frames[1].data, TX_OK);
    assert_eq!(radio.texts(), ["xbee test", "rx type=88 len=6"]);
    assert!(radio.decode_errors().is_empty());

    let cpb = avr.uart_cycles_per_byte();
    // The AT frame follows "xbee test\n" (10 bytes) back to back; 8 bytes on the wire.
    let after_line = frames[0].cycle - radio.lines()[0].cycle;
    assert!(
        (10 * cpb..10 * cpb + 200).contains(&after_line),
        "{after_line}"
    );
    // UDRE0 polling adds a few cycles per byte to the UART's pace.
    let on_wire = frames[0].end_cycle - frames[0].cycle;
    assert!((8 * cpb..8 * cpb + 100).contains(&on_wire), "{on_wire}");
    // The reply starts 2 ms after the frame's end and takes 10 bytes; the firmware answers
    // after its line "rx type=88 len=6\n" (17 bytes) has gone out.
    let (reply_at, reply) = &radio.sent()[0];
    assert_eq!(*reply_at, frames[0].end_cycle + 32_000);
    assert_eq!(reply.len(), 10);
    let reply_end = reply_at + 10 * cpb;
    let answer_delay = frames[1].cycle - reply_end;
    assert!(
        (17 * cpb..17 * cpb + 1000).contains(&answer_delay),
        "TX16 {} cycles after the reply ended",
        answer_delay
    );
    let line_ms = radio.lines()[1].ms();
    assert!(line_ms > cycles_to_ms(reply_end) && line_ms < cycles_to_ms(reply_end) + 0.1);
}

#[test]
fn a_radio_that_never_answers_sees_three_attempts() {
    let mut avr = xbee();
    let mut radio = ScriptedRadio::new(Mode::Escaped)
        .expect(Match::data(&AT_CH_1), 5.0)
        .expect(Match::data(&AT_CH_2), 55.0)
        .expect(Match::data(&AT_CH_3), 55.0)
        .expect_silence(100.0);
    radio.run_to_end(&mut avr, 300.0).unwrap();
    let f = radio.frames();
    let gap = f[1].ms() - f[0].ms();
    assert!((49.0..52.0).contains(&gap), "retry after {gap} ms");
    assert_eq!(radio.texts(), ["xbee test", "giving up"]);
}

#[test]
fn garbage_and_bad_checksums_are_rejected_by_the_firmware() {
    let mut avr = xbee();
    let mut bad = vec![0x7E, 0x00, 0x06];
    bad.extend_from_slice(&AT_RESP_1);
    bad.push(0x00); // wrong checksum
    let mut radio = ScriptedRadio::new(Mode::Escaped)
        .expect(Match::data(&AT_CH_1), 5.0)
        .reply_raw(b"\x01\x02garbage", 1.0)
        .reply_raw(&bad, 2.0)
        .expect(Match::data(&AT_CH_2), 55.0);
    radio.run_to_end(&mut avr, 100.0).unwrap();
    assert_eq!(radio.texts(), ["xbee test", "rx bad"]);
}

#[test]
fn unsolicited_frames_at_a_given_time() {
    let mut avr = xbee();
    // RX16 from 0x0001, RSSI -40 dBm, payload "hi".
    let rx16 = [0x81, 0x00, 0x01, 40, 0x00, b'h', b'i'];
    let mut radio = ScriptedRadio::new(Mode::Escaped)
        .expect(Match::data(&AT_CH_1), 5.0)
        .reply(&AT_RESP_1, 0.0)
        .expect(Match::frame_type(0x01), 10.0)
        .send_at(30.0, &rx16)
        .send_at(40.0, &rx16)
        .expect_silence(20.0);
    radio.run_to_end(&mut avr, 100.0).unwrap();
    let lines = radio.lines();
    assert_eq!(radio.texts()[2..], ["rx type=81 len=7", "rx type=81 len=7"]);
    let at = lines[2].ms();
    // Sent at 30 ms: 11 bytes on the wire; RXC0 of the last byte one byte time after its start
    // bit, then the firmware's decode and first UDR0 write.
    let byte_ms = cycles_to_ms(avr.uart_cycles_per_byte());
    let end = 30.0 + 11.0 * byte_ms;
    assert!((end..end + 0.05).contains(&at), "{at} vs {end}");
    assert!((lines[3].ms() - at - 10.0).abs() < 0.01);
}

#[test]
fn a_wrong_frame_fails_with_a_clear_message() {
    let mut avr = xbee();
    let mut radio = ScriptedRadio::new(Mode::Escaped)
        .expect(Match::data(&[0x08, 0x01, b'N', b'I']), 5.0)
        .reply(&AT_RESP_1, 1.0);
    let err = radio.run_to_end(&mut avr, 100.0).unwrap_err();
    let msg = err.to_string();
    println!("{msg}");
    assert_eq!(err.step, 0);
    assert!(
        msg.contains("expected: expect frame [08 01 4e 49]"),
        "{msg}"
    );
    assert!(msg.contains("got:      frame [08 01 43 48]"), "{msg}");
    assert!(msg.contains("AtCommand"), "{msg}");
    assert!(msg.contains("xbee test"), "recent lines shown: {msg}");
    assert!(err.at_ms > 0.5 && err.at_ms < 5.0);
    // The failure sticks.
    assert_eq!(radio.run_for_ms(&mut avr, 1.0).unwrap_err(), err);
}

#[test]
fn a_missed_deadline_fails_with_the_times() {
    let mut avr = xbee();
    let mut radio = ScriptedRadio::new(Mode::Escaped)
        .expect(Match::data(&AT_CH_1), 5.0)
        .expect(
            Match::pred("a TX status frame", |f| f.frame_type() == 0x89),
            20.0,
        );
    let err = radio.run_for_ms(&mut avr, 200.0).unwrap_err();
    let msg = err.to_string();
    println!("{msg}");
    assert_eq!(err.step, 1);
    assert!(msg.contains("a TX status frame within 20 ms"), "{msg}");
    // The firmware's retry comes only 50 ms after its first frame.
    let deadline = radio.frames()[0].end_ms() + 20.0;
    assert!(
        msg.contains(&format!("no frame by {deadline:.3} ms")),
        "{msg}"
    );
    assert!(
        (err.at_ms - deadline).abs() < 0.01,
        "{} vs {deadline}",
        err.at_ms
    );

    // A frame still on the wire at the deadline is late.
    let mut avr = xbee();
    let mut radio = ScriptedRadio::new(Mode::Escaped).expect(Match::data(&AT_CH_1), 3.0);
    let err = radio.run_for_ms(&mut avr, 10.0).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("nothing by the deadline; next was frame [08 01 43 48]"),
        "{msg}"
    );
    assert!((err.at_ms - 3.0).abs() < 0.001, "{msg}");
}

#[test]
fn unexpected_frame_during_silence_fails() {
    let mut avr = xbee();
    let mut radio = ScriptedRadio::new(Mode::Escaped)
        .expect(Match::data(&AT_CH_1), 5.0)
        .expect_silence(60.0);
    let err = radio.run_for_ms(&mut avr, 100.0).unwrap_err();
    assert!(
        err.to_string().contains("expect no frame for 60 ms"),
        "{err}"
    );
    assert!(err.got.contains("08 02 43 48"), "{err}");
}
