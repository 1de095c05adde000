//! The modelled XBee: the sans-IO core on the host (exact response bytes and times), the
//! `xbee-api` driver's bring-up against it, and the Avr attachment with a C fixture.

mod common;

use simavr::xbee::{
    byte_cycles, encode_frame, time_on_air_ms, Address, Csma, FrameKind, Model, ModelClock,
    ModelPort, RxPacket, Security, XBee, XBeeConfig, XBeeCore, ACK_AIR_US, CCA_US, DI_BUFFER_BYTES,
    SECURITY_HEADER_BYTES, TURNAROUND_US,
};
use simavr::{ms_to_cycles, Avr, UartByte};
use xbee_api::driver::{BringUp, BringUpConfig, Encryption, Radio};
use xbee_api::{Decoder, Mode};

fn ms(x: f64) -> u64 {
    ms_to_cycles(x)
}

fn us(x: u64) -> u64 {
    ms_to_cycles(x as f64 / 1000.0)
}

/// From a TX request to its packet on air, the channel clear: a CCA and the turnaround.
fn lead() -> u64 {
    us(CCA_US + TURNAROUND_US)
}

/// A host on the model's UART: sends bytes back to back at its own rate, collects output.
struct Host {
    core: XBeeCore,
    baud: u32,
    /// Cycle the host's TX line is free.
    t: u64,
    out: Vec<UartByte>,
}

impl Host {
    fn new(cfg: XBeeConfig) -> Host {
        let baud = simavr::xbee::baud_of_bd(cfg.bd).unwrap();
        let mut core = XBeeCore::new(cfg);
        core.set_host_baud(baud);
        let mut h = Host {
            core,
            baud,
            t: 0,
            out: Vec::new(),
        };
        // Past the power-up; the modem status (API mode) is in `out`.
        h.run_to(ms(10.0));
        h
    }

    fn set_baud(&mut self, baud: u32) {
        self.baud = baud;
        self.core.set_host_baud(baud);
    }

    /// Sends bytes starting at `at` (or when the line is free); returns the last byte's end.
    fn send_at(&mut self, at: u64, bytes: &[u8]) -> u64 {
        let start = at.max(self.t);
        self.run_to(start);
        let end = self.core.rx_bytes(start, bytes);
        self.t = end;
        self.collect();
        end
    }

    fn send(&mut self, bytes: &[u8]) -> u64 {
        self.send_at(self.t, bytes)
    }

    fn frame(&mut self, data: &[u8], mode: Mode) -> u64 {
        self.send(&encode_frame(data, mode))
    }

    fn run_to(&mut self, t: u64) {
        self.core.advance(t);
        self.t = self.t.max(t);
        self.collect();
    }

    fn run_ms(&mut self, x: f64) {
        self.run_to(self.t + ms(x));
    }

    fn collect(&mut self) {
        self.out.extend(self.core.take_output());
    }

    fn take(&mut self) -> Vec<UartByte> {
        std::mem::take(&mut self.out)
    }

    fn take_bytes(&mut self) -> Vec<u8> {
        self.take().iter().map(|b| b.byte).collect()
    }
}

fn bytes(out: &[UartByte]) -> Vec<u8> {
    out.iter().map(|b| b.byte).collect()
}

/// Frame data of every frame in `out`.
fn frames(out: &[u8], mode: Mode) -> Vec<Vec<u8>> {
    let mut d = Decoder::new(mode);
    let mut v = Vec::new();
    d.feed(out, |r| {
        if let Ok(raw) = r {
            v.push(raw.data().to_vec())
        }
    });
    v
}

const MODES: [Mode; 2] = [Mode::Api, Mode::Escaped];

// ---- power-up ----

#[test]
fn modem_status_at_power_up_in_api_mode_only() {
    for mode in MODES {
        let mut core = XBeeCore::new(XBeeConfig::api(mode.ap()));
        core.advance(ms(4.9));
        assert!(core.take_output().is_empty(), "nothing before power-up");
        core.advance(ms(5.0));
        let out = core.take_output();
        assert_eq!(bytes(&out), [0x7E, 0x00, 0x02, 0x8A, 0x00, 0x75]);
        assert_eq!(out[0].cycle, ms(5.0));
        // Paced at 57600 (BD=6), 11 bit times per byte as simavr counts.
        assert_eq!(out[1].cycle - out[0].cycle, byte_cycles(57_600));
    }
    let mut core = XBeeCore::new(XBeeConfig::default());
    core.advance(ms(100.0));
    assert!(
        core.take_output().is_empty(),
        "transparent mode: no modem status"
    );
}

#[test]
fn bytes_before_power_up_are_lost() {
    let mut core = XBeeCore::new(XBeeConfig::api(2));
    core.set_host_baud(57_600);
    core.rx_bytes(
        ms(1.0),
        &encode_frame(&[0x08, 0x01, b'C', b'H'], Mode::Escaped),
    );
    core.advance(ms(20.0));
    assert_eq!(core.stats().dropped_powering_up, 8);
    assert_eq!(
        frames(&bytes(&core.take_output()), Mode::Escaped),
        [vec![0x8A, 0x00]]
    );
}

// ---- API mode AT commands ----

#[test]
fn at_query_answers_big_endian_in_the_register_width_with_exact_bytes() {
    for mode in MODES {
        let cfg = XBeeConfig {
            sh_sl: 0x0013_A200_4012_3456,
            ..XBeeConfig::api(mode.ap())
        };
        let mut h = Host::new(cfg);
        assert_eq!(h.take_bytes(), [0x7E, 0x00, 0x02, 0x8A, 0x00, 0x75]);
        // Exact bytes on the wire: CH = 0x0C (1 byte).
        let end = h.frame(&[0x08, 0x52, b'C', b'H'], mode);
        h.run_ms(5.0);
        let out = h.take();
        assert_eq!(
            bytes(&out),
            [0x7E, 0x00, 0x06, 0x88, 0x52, 0x43, 0x48, 0x00, 0x0C, 0x8E]
        );
        assert_eq!(out[0].cycle, end + ms(1.0), "1 ms after the frame's end");
        let cases: [(&[u8; 2], &[u8]); 9] = [
            (b"MY", &[0x00, 0x00]),
            (b"ID", &[0x33, 0x32]),
            (b"BD", &[0, 0, 0, 6]),
            (b"AP", &[mode.ap()]),
            (b"SH", &[0x00, 0x13, 0xA2, 0x00]),
            (b"SL", &[0x40, 0x12, 0x34, 0x56]),
            (b"VR", &[0x10, 0xEF]),
            (b"GT", &[0x03, 0xE8]),
            (b"NI", &[]),
        ];
        for (i, (cmd, value)) in cases.iter().enumerate() {
            let id = i as u8 + 1;
            h.frame(&[0x08, id, cmd[0], cmd[1]], mode);
            h.run_ms(5.0);
            let mut expect = vec![0x88, id, cmd[0], cmd[1], 0x00];
            expect.extend_from_slice(value);
            assert_eq!(frames(&h.take_bytes(), mode), [expect], "{mode:?} {cmd:?}");
        }
    }
}

#[test]
fn at_set_applies_and_answers_ok_escaping_in_ap2() {
    let mut h = Host::new(XBeeConfig::api(2));
    h.take();
    // MY = 0x7E11: the query answer needs escaping in AP=2.
    h.frame(&[0x08, 0x07, b'M', b'Y', 0x7E, 0x11], Mode::Escaped);
    h.run_ms(5.0);
    assert_eq!(
        h.take_bytes(),
        [0x7E, 0x00, 0x05, 0x88, 0x07, 0x4D, 0x59, 0x00, 0xCA]
    );
    assert_eq!(h.core.registers().my(), 0x7E11);
    h.frame(&[0x08, 0x08, b'M', b'Y'], Mode::Escaped);
    h.run_ms(5.0);
    // 88 08 4D 59 00 7E 11: sum 0x1C5, checksum 0xFF - 0xC5 = 0x3A.
    assert_eq!(
        h.take_bytes(),
        [0x7E, 0x00, 0x07, 0x88, 0x08, 0x4D, 0x59, 0x00, 0x7D, 0x5E, 0x7D, 0x31, 0x3A]
    );
    // CH applies at once.
    h.frame(&[0x08, 0x09, b'C', b'H', 0x15], Mode::Escaped);
    h.run_ms(5.0);
    assert_eq!(h.core.channel(), 0x15);
    // NI takes a string.
    h.frame(&[0x08, 0x0A, b'N', b'I', b'n', b'1'], Mode::Escaped);
    h.frame(&[0x08, 0x0B, b'N', b'I'], Mode::Escaped);
    h.run_ms(5.0);
    let f = frames(&h.take_bytes(), Mode::Escaped);
    assert_eq!(f[2], [0x88, 0x0B, b'N', b'I', 0x00, b'n', b'1']);
}

#[test]
fn frame_id_zero_gets_no_response_but_still_applies() {
    for mode in MODES {
        let mut h = Host::new(XBeeConfig::api(mode.ap()));
        h.take();
        h.frame(&[0x08, 0x00, b'M', b'Y', 0x12, 0x34], mode);
        h.frame(&[0x08, 0x00, b'C', b'H'], mode);
        h.run_ms(20.0);
        assert!(h.take().is_empty());
        assert_eq!(h.core.registers().my(), 0x1234);
        assert_eq!(h.core.stats().frames_ok, 2);
    }
}

#[test]
fn invalid_values_and_commands_answer_error_statuses() {
    let query = |model: Model, cmd: &[u8]| {
        let mut h = Host::new(XBeeConfig {
            model,
            ..XBeeConfig::api(2)
        });
        h.take();
        let mut d = vec![0x08, 0x01];
        d.extend_from_slice(cmd);
        h.frame(&d, Mode::Escaped);
        h.run_ms(5.0);
        let f = frames(&h.take_bytes(), Mode::Escaped);
        assert_eq!(f.len(), 1);
        (f[0][4], h.core.registers().ch())
    };
    // Status 3: invalid parameter; the register keeps its value.
    assert_eq!(query(Model::S1, b"CH\x0B"), (0, 0x0B));
    assert_eq!(query(Model::S1, b"CH\x1A"), (0, 0x1A));
    assert_eq!(query(Model::S1, b"CH\x1B"), (3, 0x0C));
    assert_eq!(query(Model::S1, b"CH\x0A"), (3, 0x0C));
    assert_eq!(
        query(Model::S1Pro, b"CH\x0B"),
        (3, 0x0C),
        "no channel 0x0B on the Pro"
    );
    assert_eq!(query(Model::S1Pro, b"CH\x17"), (0, 0x17));
    assert_eq!(query(Model::S1Pro, b"CH\x18"), (3, 0x0C));
    assert_eq!(query(Model::S1, b"AP\x03").0, 3);
    assert_eq!(query(Model::S1, b"BD\x08").0, 3);
    assert_eq!(query(Model::S1, b"MY\x01\x00\x00").0, 3, "wider than MY");
    // Status 2: unknown command; 1: read-only register.
    assert_eq!(query(Model::S1, b"ZZ").0, 2);
    assert_eq!(query(Model::S1, b"SH\x01").0, 1);
}

#[test]
fn queued_parameters_apply_with_the_next_at_command_or_ac() {
    let mut h = Host::new(XBeeConfig::api(2));
    h.take();
    h.frame(&[0x09, 0x01, b'C', b'H', 0x0D], Mode::Escaped);
    h.frame(&[0x09, 0x02, b'M', b'Y', 0x00, 0x05], Mode::Escaped);
    h.run_ms(5.0);
    assert_eq!(h.core.registers().ch(), 0x0C, "queued, not applied");
    assert_eq!(h.core.registers().my(), 0);
    assert_eq!(
        frames(&h.take_bytes(), Mode::Escaped),
        [
            vec![0x88, 0x01, b'C', b'H', 0x00],
            vec![0x88, 0x02, b'M', b'Y', 0x00]
        ]
    );
    h.frame(&[0x08, 0x03, b'A', b'C'], Mode::Escaped);
    h.run_ms(5.0);
    assert_eq!(h.core.registers().ch(), 0x0D);
    assert_eq!(h.core.channel(), 0x0D);
    assert_eq!(h.core.registers().my(), 5);
    // An invalid queued value is refused at once.
    h.take();
    h.frame(&[0x09, 0x04, b'C', b'H', 0x30], Mode::Escaped);
    h.run_ms(5.0);
    assert_eq!(frames(&h.take_bytes(), Mode::Escaped)[0][4], 3);
}

#[test]
fn ap_change_takes_effect_after_the_response() {
    let mut h = Host::new(XBeeConfig::api(2));
    h.take();
    h.frame(&[0x08, 0x01, b'A', b'P', 0x01], Mode::Escaped);
    h.run_ms(5.0);
    assert_eq!(h.core.mode(), Some(Mode::Api));
    assert_eq!(
        frames(&h.take_bytes(), Mode::Escaped),
        [vec![0x88, 0x01, b'A', b'P', 0x00]]
    );
    // MY = 0x7D7E unescaped in AP=1.
    h.frame(&[0x08, 0x02, b'M', b'Y', 0x7D, 0x7E], Mode::Api);
    h.frame(&[0x08, 0x03, b'M', b'Y'], Mode::Api);
    h.run_ms(5.0);
    let out = h.take_bytes();
    assert_eq!(
        frames(&out, Mode::Api)[1],
        [0x88, 0x03, b'M', b'Y', 0x00, 0x7D, 0x7E]
    );
    assert!(out.windows(2).any(|w| w == [0x7D, 0x7E]), "not escaped");
}

#[test]
fn bd_change_switches_the_uart_after_the_response() {
    let mut h = Host::new(XBeeConfig::api(2));
    h.take();
    h.frame(&[0x08, 0x01, b'B', b'D', 0x03], Mode::Escaped);
    h.run_ms(5.0);
    let out = h.take();
    // The response still at 57600…
    assert_eq!(
        frames(&bytes(&out), Mode::Escaped),
        [vec![0x88, 0x01, b'B', b'D', 0x00]]
    );
    assert_eq!(out[1].cycle - out[0].cycle, byte_cycles(57_600));
    assert_eq!(h.core.uart_baud(), 9600);
    // …then the host at 57600 is not understood, and does not understand.
    h.frame(&[0x08, 0x02, b'C', b'H'], Mode::Escaped);
    h.run_ms(10.0);
    assert!(frames(&h.take_bytes(), Mode::Escaped).is_empty());
    assert!(h.core.stats().garbled_in > 0);
    h.set_baud(9600);
    h.run_ms(2000.0);
    h.frame(&[0x08, 0x03, b'C', b'H'], Mode::Escaped);
    h.run_ms(30.0);
    let out = h.take();
    assert_eq!(
        frames(&bytes(&out), Mode::Escaped),
        [vec![0x88, 0x03, b'C', b'H', 0x00, 0x0C]]
    );
    assert_eq!(out[1].cycle - out[0].cycle, byte_cycles(9600));
}

// ---- transmit ----

/// A unicast asks for an ACK; alone, the radio gets it from an ideal receiver: the status
/// follows the ACK, a turnaround and the ACK's time on air after the packet.
#[test]
fn tx16_goes_on_air_and_tx_status_follows_its_ack() {
    for mode in MODES {
        let mut h = Host::new(XBeeConfig {
            my: 0x0042,
            ch: 0x0E,
            ..XBeeConfig::api(mode.ap())
        });
        h.take();
        let payload = b"0123456789";
        let mut d = vec![0x01, 0x33, 0x12, 0x34, 0x00];
        d.extend_from_slice(payload);
        let end = h.frame(&d, mode);
        h.run_ms(10.0);
        let out = h.take();
        assert_eq!(
            frames(&bytes(&out), mode),
            [vec![0x89, 0x33, 0x00]],
            "{mode:?}"
        );
        let toa = ms(time_on_air_ms(10));
        assert_eq!(toa, ms(1.248));
        assert_eq!(
            out[0].cycle,
            end + toa + us(TURNAROUND_US + ACK_AIR_US),
            "status when the ACK is in"
        );
        assert_eq!(h.core.stats().acks_received, 1);
        let txs = h.core.take_transmissions();
        assert_eq!(txs.len(), 1);
        let tx = &txs[0];
        assert_eq!(tx.channel, 0x0E);
        assert_eq!(tx.pan_id, 0x3332);
        assert_eq!(tx.source, Address::Short(0x0042));
        assert_eq!(tx.source16(), Some(0x0042));
        assert_eq!(tx.dest, Address::Short(0x1234));
        assert_eq!(tx.payload, payload);
        assert_eq!((tx.start_cycle, tx.end_cycle), (end + lead(), end + toa));
        assert_eq!(tx.frame_id, 0x33);
        assert_eq!(tx.mac.kind, FrameKind::Data);
        assert!(tx.mac.ack_request);
        assert_eq!(tx.mac.attempt, 0);
    }
}

#[test]
fn tx_frame_id_zero_tx64_queueing_and_oversize_payloads() {
    let mut h = Host::new(XBeeConfig::api(2));
    h.take();
    let end1 = h.frame(&[0x01, 0x00, 0xFF, 0xFF, 0x00, b'a'], Mode::Escaped);
    let mut tx64 = vec![0x00, 0x05];
    tx64.extend_from_slice(&0x0013_A200_0000_0001u64.to_be_bytes());
    tx64.push(0x01);
    tx64.extend_from_slice(&[0x55; 100]);
    h.frame(&tx64, Mode::Escaped);
    // 101 bytes: refused.
    let mut big = vec![0x01, 0x06, 0xFF, 0xFF, 0x00];
    big.extend_from_slice(&[0x55; 101]);
    h.frame(&big, Mode::Escaped);
    h.run_ms(20.0);
    assert_eq!(
        frames(&h.take_bytes(), Mode::Escaped),
        [vec![0x89, 0x05, 0x00]],
        "no status for frame id 0 nor for the refused frame"
    );
    let txs = h.core.take_transmissions();
    assert_eq!(txs.len(), 2);
    assert_eq!(txs[0].end_cycle, end1 + ms(time_on_air_ms(1)));
    assert_eq!(txs[1].dest, Address::Long(0x0013_A200_0000_0001));
    assert_eq!(txs[1].options, 0x01);
    assert_eq!(txs[1].payload.len(), 100);
    assert!(txs[1].start_cycle >= txs[0].end_cycle, "one at a time");
    assert_eq!(h.core.stats().oversize_tx, 1);
}

/// Alone every CCA is clear: the first backoff, 0…2^RN − 1 periods, is the only delay.
#[test]
fn csma_backoff_delays_within_eight_backoff_periods_reproducibly() {
    let run = |seed, rn| {
        let mut h = Host::new(XBeeConfig {
            csma: Csma::Random { seed },
            rn,
            ..XBeeConfig::api(2)
        });
        let mut delays = Vec::new();
        for i in 0..20u8 {
            let end = h.frame(&[0x01, i + 1, 0xFF, 0xFF, 0x00, i], Mode::Escaped);
            h.run_ms(20.0);
            let tx = h.core.take_transmissions().pop().unwrap();
            delays.push(tx.start_cycle - end - lead());
        }
        delays
    };
    let a = run(7, 3);
    assert_eq!(a, run(7, 3));
    assert_ne!(a, run(8, 3));
    assert!(a.iter().all(|&d| d <= ms(7.0 * 0.32) && d % ms(0.32) == 0));
    assert!(a.iter().any(|&d| d > 0));
    // The factory RN = 0: no backoff before the first CCA.
    assert!(run(7, 0).iter().all(|&d| d == 0));
}

// ---- receive ----

#[test]
fn delivered_packets_reach_the_host_only_on_the_radios_channel() {
    for mode in MODES {
        let mut h = Host::new(XBeeConfig {
            ch: 0x0B,
            my: 0x0002,
            ..XBeeConfig::api(mode.ap())
        });
        h.take();
        let at = ms(20.0);
        h.core
            .deliver(RxPacket::broadcast16(0x0B, 0x3332, 0x1234, -40, b"hi"), at);
        h.core.deliver(
            RxPacket::broadcast16(0x16, 0x3332, 0x1234, -41, b"no"),
            at + ms(5.0),
        );
        h.run_to(ms(40.0));
        let out = h.take();
        assert_eq!(
            frames(&bytes(&out), mode),
            [vec![0x81, 0x12, 0x34, 40, 0x02, b'h', b'i']]
        );
        assert_eq!(out[0].cycle, at + ms(0.2));
        assert_eq!(h.core.last_rssi(), 40);
        assert_eq!(h.core.stats().rx_filtered, 1);
        // Switch to 0x16: now that channel is heard; unicast to MY, and to someone else.
        h.frame(&[0x08, 0x01, b'C', b'H', 0x16], mode);
        h.run_ms(5.0);
        let t = h.t;
        let mut p = RxPacket::broadcast16(0x16, 0x3332, 0x7E7D, -77, &[0x7E]);
        p.dest = Address::Short(0x0002);
        h.core.deliver(p.clone(), t + ms(1.0));
        p.dest = Address::Short(0x0003);
        h.core.deliver(p.clone(), t + ms(3.0));
        p.dest = Address::Short(0x0002);
        p.pan_id = 0x1111;
        h.core.deliver(p.clone(), t + ms(5.0));
        // 64-bit source → RX64.
        let mut p64 = RxPacket::broadcast16(0x16, 0x3332, 0, -60, b"x");
        p64.source = Address::Long(0x0013_A200_0000_0009);
        h.core.deliver(p64, t + ms(7.0));
        h.run_ms(20.0);
        let f = frames(&h.take_bytes(), mode);
        assert_eq!(f.len(), 3, "{f:x?}");
        assert_eq!(f[1], [0x81, 0x7E, 0x7D, 77, 0x00, 0x7E]);
        let mut rx64 = vec![0x80];
        rx64.extend_from_slice(&0x0013_A200_0000_0009u64.to_be_bytes());
        rx64.extend_from_slice(&[60, 0x02, b'x']);
        assert_eq!(f[2], rx64);
        // DB answers the last RSSI.
        h.frame(&[0x08, 0x02, b'D', b'B'], mode);
        h.run_ms(5.0);
        assert_eq!(
            frames(&h.take_bytes(), mode),
            [vec![0x88, 0x02, b'D', b'B', 0x00, 60]]
        );
    }
}

#[test]
fn transparent_mode_sends_after_ro_and_passes_payloads_bare() {
    let mut h = Host::new(XBeeConfig {
        bd: 6,
        ..XBeeConfig::default()
    });
    let end = h.send(b"hello");
    h.run_ms(5.0);
    let txs = h.core.take_transmissions();
    assert_eq!(txs.len(), 1);
    assert_eq!(txs[0].payload, b"hello");
    assert_eq!(txs[0].dest, Address::Short(0));
    assert_eq!(
        txs[0].start_cycle,
        end + 3 * byte_cycles(57_600) + lead(),
        "RO = 3 characters"
    );
    h.core
        .deliver(RxPacket::broadcast16(0x0C, 0x3332, 1, -50, b"abc"), h.t);
    h.run_ms(5.0);
    assert_eq!(h.take_bytes(), b"abc");
    // 250 bytes in one go: 100 + 100 + 50.
    h.send(&[b'z'; 250]);
    h.run_ms(5.0);
    let lens: Vec<usize> = h
        .core
        .take_transmissions()
        .iter()
        .map(|t| t.payload.len())
        .collect();
    assert_eq!(lens, [100, 100, 50]);
}

// ---- command mode ----

fn transparent(gt_ms: u16) -> Host {
    Host::new(XBeeConfig {
        gt_ms,
        ..XBeeConfig::default()
    })
}

#[test]
fn command_mode_needs_guard_times_around_plus_plus_plus() {
    let gt = ms(100.0);
    // Proper: silence, +++, silence → OK exactly GT after the last '+'.
    let mut h = transparent(100);
    h.run_to(ms(200.0));
    let end = h.send(b"+++");
    h.run_to(end + gt - 1);
    assert!(h.take().is_empty());
    h.run_to(end + gt + ms(5.0));
    let out = h.take();
    assert_eq!(bytes(&out), b"OK\r");
    assert_eq!(out[0].cycle, end + gt);
    assert!(h.core.in_command_mode());
    assert!(
        h.core.take_transmissions().is_empty(),
        "+++ is not sent as data"
    );

    // Too early: a byte 30 ms before the "+++".
    let mut h = transparent(100);
    h.run_to(ms(200.0));
    h.send(b"x");
    h.send_at(ms(230.0), b"+++");
    h.run_to(ms(600.0));
    assert!(h.take().is_empty());
    assert!(!h.core.in_command_mode());

    // A byte right after the "+++" cancels it; the held '+' go out as data.
    let mut h = transparent(100);
    h.run_to(ms(200.0));
    let end = h.send(b"+++");
    h.send_at(end + ms(50.0), b"y");
    h.run_to(ms(600.0));
    assert!(h.take().is_empty());
    let data: Vec<u8> = h
        .core
        .take_transmissions()
        .into_iter()
        .flat_map(|t| t.payload)
        .collect();
    assert_eq!(data, b"+++y");

    // The '+' too far apart (more than GT between them).
    let mut h = transparent(100);
    h.run_to(ms(200.0));
    h.send(b"+");
    h.send_at(ms(350.0), b"+");
    h.send_at(ms(500.0), b"+");
    h.run_to(ms(900.0));
    assert!(h.take().is_empty());
    assert_eq!(
        h.core
            .take_transmissions()
            .iter()
            .map(|t| t.payload.clone())
            .collect::<Vec<_>>(),
        [b"+".to_vec(), b"+".to_vec(), b"+".to_vec()]
    );
}

fn enter_command_mode(h: &mut Host) {
    let t = h.t + ms(f64::from(h.core.registers().gt()) + 10.0);
    let end = h.send_at(t, b"+++");
    h.run_to(end + ms(f64::from(h.core.registers().gt()) + 5.0));
    assert_eq!(h.take_bytes(), b"OK\r");
}

#[test]
fn command_mode_queries_sets_errors_and_the_bring_up_sequence() {
    let mut h = transparent(50);
    enter_command_mode(&mut h);
    let ask = |h: &mut Host, line: &[u8]| {
        h.send(line);
        h.run_ms(10.0);
        String::from_utf8(h.take_bytes()).unwrap()
    };
    assert_eq!(ask(&mut h, b"ATCH\r"), "C\r");
    assert_eq!(ask(&mut h, b"ATID\r"), "3332\r");
    assert_eq!(ask(&mut h, b"ATMY\r"), "0\r");
    assert_eq!(ask(&mut h, b"ATVR\r"), "10EF\r");
    assert_eq!(ask(&mut h, b"AT\r"), "OK\r");
    assert_eq!(ask(&mut h, b"ATXX\r"), "ERROR\r");
    assert_eq!(ask(&mut h, b"ATCH1B\r"), "ERROR\r");
    assert_eq!(ask(&mut h, b"ATCH 0x1a\r"), "OK\r");
    assert_eq!(ask(&mut h, b"ATCH\r"), "1A\r");
    assert_eq!(h.core.channel(), 0x0C, "applied only on CN/AC");
    assert_eq!(ask(&mut h, b"ATNI node one\r"), "OK\r");
    assert_eq!(ask(&mut h, b"ATNI\r"), "node one\r");
    assert_eq!(ask(&mut h, b"hello\r"), "ERROR\r");
    // A line stops at its first error.
    assert_eq!(ask(&mut h, b"ATMY5,CH99,MY6\r"), "OK\rERROR\r");
    assert_eq!(h.core.registers().my(), 5);

    // The bring-up sequence: one OK each; AP, BD and CH apply after the last OK.
    let end = h.send(b"ATAP2,BD6,WR,CN\r");
    h.run_ms(10.0);
    let out = h.take();
    assert_eq!(bytes(&out), b"OK\rOK\rOK\rOK\r");
    assert_eq!(out[0].cycle, end + ms(1.0));
    assert_eq!(
        out[11].cycle - out[10].cycle,
        byte_cycles(9600),
        "still at 9600"
    );
    assert!(!h.core.in_command_mode());
    assert_eq!(h.core.mode(), Some(Mode::Escaped));
    assert_eq!(h.core.uart_baud(), 57_600);
    assert_eq!(h.core.channel(), 0x1A);
    assert_eq!(h.core.persisted().ap(), 2);
    assert_eq!(h.core.persisted().bd(), 6);
    // Now it speaks API at 57600.
    h.set_baud(57_600);
    h.frame(&[0x08, 0x01, b'A', b'P'], Mode::Escaped);
    h.run_ms(5.0);
    assert_eq!(
        frames(&h.take_bytes(), Mode::Escaped),
        [vec![0x88, 0x01, b'A', b'P', 0x00, 0x02]]
    );
}

#[test]
fn command_mode_times_out_after_ct_and_applies_changes() {
    let mut h = transparent(50);
    enter_command_mode(&mut h);
    h.send(b"ATCT2\r");
    h.run_ms(5.0);
    assert_eq!(h.take_bytes(), b"OK\r");
    let end = h.send(b"ATBD6\r");
    h.run_ms(5.0);
    assert_eq!(h.take_bytes(), b"OK\r");
    h.run_to(end + ms(199.0));
    assert!(h.core.in_command_mode());
    assert_eq!(h.core.uart_baud(), 9600);
    h.run_to(end + ms(201.0));
    assert!(!h.core.in_command_mode());
    assert_eq!(h.core.uart_baud(), 57_600);
    assert_eq!(h.core.persisted().bd(), 3, "not written");
}

#[test]
fn command_mode_works_in_api_mode_too() {
    let mut h = Host::new(XBeeConfig {
        gt_ms: 50,
        ..XBeeConfig::api(1)
    });
    h.take();
    enter_command_mode(&mut h);
    h.send(b"ATAP\r");
    h.run_ms(5.0);
    assert_eq!(h.take_bytes(), b"1\r");
}

// ---- baud rates, persistence ----

#[test]
fn mismatched_baud_rates_garble_both_directions() {
    // The radio at 57600, the host at 9600 (the host is the slower receiver).
    let mut h = Host::new(XBeeConfig::api(2));
    h.take();
    h.set_baud(9600);
    assert!(!h.core.baud_matches());
    h.frame(&[0x08, 0x01, b'C', b'H'], Mode::Escaped);
    h.core
        .deliver(RxPacket::broadcast16(0x0C, 0x3332, 1, -40, &[0u8; 60]), h.t);
    h.run_ms(50.0);
    let out = h.take_bytes();
    let s = h.core.stats();
    assert_eq!(s.frames_ok, 0);
    assert_eq!(s.garbled_in, 8);
    assert_eq!(s.rx_delivered, 1);
    assert_eq!(
        s.garbled_out, 69,
        "the RX frame's 69 bytes went out garbled"
    );
    assert!(
        !out.is_empty() && out.len() < 69,
        "the slow side sees fewer bytes"
    );
    assert!(
        out.iter().all(|&b| b >= 0xF0),
        "garbage, never a frame: {out:x?}"
    );
    // Within the tolerance (UBRR 34 with U2X is 0.8 % off 57600): understood.
    let mut h = Host::new(XBeeConfig::api(2));
    h.core.set_host_byte_cycles(3080);
    assert!(h.core.baud_matches());
    h.frame(&[0x08, 0x01, b'C', b'H'], Mode::Escaped);
    h.run_ms(5.0);
    assert_eq!(h.core.stats().frames_ok, 1);
}

#[test]
fn wr_and_power_cycle_restore_the_written_values() {
    let mut h = Host::new(XBeeConfig::api(2));
    h.frame(&[0x08, 0x01, b'M', b'Y', 0x00, 0x07], Mode::Escaped);
    h.frame(&[0x08, 0x02, b'W', b'R'], Mode::Escaped);
    h.frame(&[0x08, 0x03, b'M', b'Y', 0x00, 0x09], Mode::Escaped);
    h.frame(&[0x08, 0x04, b'C', b'H', 0x11], Mode::Escaped);
    h.run_ms(5.0);
    assert_eq!(h.core.registers().my(), 9);
    assert_eq!(h.core.persisted().my(), 7);
    h.take();
    let t = h.t + ms(1.0);
    h.core.reset(t);
    h.run_to(t + ms(10.0));
    let out = h.take();
    assert_eq!(bytes(&out), [0x7E, 0x00, 0x02, 0x8A, 0x00, 0x75]);
    assert_eq!(out[0].cycle, t + ms(5.0));
    assert_eq!(h.core.registers().my(), 7);
    assert_eq!(h.core.registers().ch(), 0x0C);
    assert_eq!(h.core.channel(), 0x0C);
    // FR: OK, then a reset with modem status "watchdog reset".
    h.frame(&[0x08, 0x05, b'F', b'R'], Mode::Escaped);
    h.run_ms(20.0);
    assert_eq!(
        frames(&h.take_bytes(), Mode::Escaped),
        [vec![0x88, 0x05, b'F', b'R', 0x00], vec![0x8A, 0x01]]
    );
    // RE loads factory defaults (AP=0, BD=3): applied after the response.
    h.frame(&[0x08, 0x06, b'R', b'E'], Mode::Escaped);
    h.run_ms(5.0);
    assert_eq!(h.core.mode(), None);
    assert_eq!(h.core.uart_baud(), 9600);
    assert_eq!(h.core.persisted().ap(), 2);
}

// ---- encryption: EE and KY ----

/// A key with bytes API mode 2 escapes (0x7E, 0x7D, 0x11, 0x13).
const KEY: [u8; 16] = [
    0x7E, 0x7D, 0x11, 0x13, 0x00, 0x01, 0x02, 0x03, 0xC0, 0xFF, 0xEE, 0x42, 0x99, 0x88, 0x77, 0x66,
];

/// Sends AT command `cmd` with `param` in an 0x08 frame with frame id `id`; returns the
/// response's frame data.
fn at(h: &mut Host, mode: Mode, id: u8, cmd: &[u8; 2], param: &[u8]) -> Vec<u8> {
    h.take();
    let mut d = vec![0x08, id, cmd[0], cmd[1]];
    d.extend_from_slice(param);
    h.frame(&d, mode);
    h.run_ms(5.0);
    let f = frames(&h.take_bytes(), mode);
    assert_eq!(f.len(), 1, "{f:x?}");
    f[0].clone()
}

#[test]
fn ee_takes_0_or_1_and_ky_up_to_16_bytes_that_a_query_never_answers() {
    for mode in MODES {
        let mut h = Host::new(XBeeConfig::api(mode.ap()));
        // EE: factory 0; 0 and 1 taken, anything else status 3 (invalid parameter).
        assert_eq!(at(&mut h, mode, 1, b"EE", &[]), [0x88, 1, b'E', b'E', 0, 0]);
        assert_eq!(at(&mut h, mode, 2, b"EE", &[1]), [0x88, 2, b'E', b'E', 0]);
        assert_eq!(at(&mut h, mode, 3, b"EE", &[]), [0x88, 3, b'E', b'E', 0, 1]);
        assert_eq!(at(&mut h, mode, 4, b"EE", &[2]), [0x88, 4, b'E', b'E', 3]);
        assert_eq!(
            at(&mut h, mode, 5, b"EE", &[0, 0, 1, 0]),
            [0x88, 5, b'E', b'E', 3]
        );
        assert!(h.core.registers().ee(), "a refused value changes nothing");
        // KY: 16 bytes taken; the query answers OK without a value.
        assert_eq!(at(&mut h, mode, 6, b"KY", &KEY), [0x88, 6, b'K', b'Y', 0]);
        assert_eq!(h.core.registers().ky(), KEY);
        assert_eq!(at(&mut h, mode, 7, b"KY", &[]), [0x88, 7, b'K', b'Y', 0]);
        // 17 bytes: refused, unless the first is a leading zero.
        let mut long = vec![0x01];
        long.extend_from_slice(&[0x55; 16]);
        assert_eq!(at(&mut h, mode, 8, b"KY", &long), [0x88, 8, b'K', b'Y', 3]);
        assert_eq!(h.core.registers().ky(), KEY);
        long[0] = 0;
        assert_eq!(at(&mut h, mode, 9, b"KY", &long), [0x88, 9, b'K', b'Y', 0]);
        assert_eq!(h.core.registers().ky(), [0x55; 16]);
        // Shorter values are right-aligned, as the radio takes any hex value.
        assert_eq!(
            at(&mut h, mode, 10, b"KY", &[0x12, 0x34]),
            [0x88, 10, b'K', b'Y', 0]
        );
        let mut short = [0; 16];
        short[14..].copy_from_slice(&[0x12, 0x34]);
        assert_eq!(h.core.registers().ky(), short);
        // A queued KY (0x09) applies with the next 0x08, like any register.
        h.frame(&[0x09, 11, b'K', b'Y', 0x77], mode);
        h.run_ms(5.0);
        assert_eq!(h.core.registers().ky(), short, "queued, not applied");
        at(&mut h, mode, 12, b"AC", &[]);
        let mut k77 = [0; 16];
        k77[15] = 0x77;
        assert_eq!(h.core.registers().ky(), k77);
        // The key stays out of the registers' Debug output too.
        let shown = format!("{:?}", h.core.registers());
        assert!(shown.contains("\"KY\": \"(set)\""), "{shown}");
        assert!(!shown.contains("77"), "{shown}");
    }
}

#[test]
fn ee_and_ky_in_command_mode() {
    let mut h = transparent(50);
    enter_command_mode(&mut h);
    let ask = |h: &mut Host, line: &[u8]| {
        h.send(line);
        h.run_ms(10.0);
        String::from_utf8(h.take_bytes()).unwrap()
    };
    assert_eq!(ask(&mut h, b"ATEE\r"), "0\r");
    assert_eq!(ask(&mut h, b"ATEE1\r"), "OK\r");
    assert_eq!(ask(&mut h, b"ATEE\r"), "1\r");
    assert_eq!(ask(&mut h, b"ATEE2\r"), "ERROR\r");
    assert_eq!(ask(&mut h, b"ATKY\r"), "OK\r", "no key, not even 0");
    assert_eq!(
        ask(&mut h, b"ATKY 0x7e7d1113 00010203 C0FFEE42 99887766\r"),
        "OK\r"
    );
    assert_eq!(h.core.registers().ky(), KEY);
    assert_eq!(ask(&mut h, b"ATKY\r"), "OK\r");
    // An odd number of digits is a number like any other: right-aligned.
    assert_eq!(ask(&mut h, b"ATKY123\r"), "OK\r");
    let mut k = [0; 16];
    k[14..].copy_from_slice(&[0x01, 0x23]);
    assert_eq!(h.core.registers().ky(), k);
    // 33 significant digits, or not hex: refused, the key stays. Leading zeros do not count.
    let f32 = "F".repeat(32);
    assert_eq!(ask(&mut h, format!("ATKY1{f32}\r").as_bytes()), "ERROR\r");
    assert_eq!(ask(&mut h, b"ATKY12G4\r"), "ERROR\r");
    assert_eq!(h.core.registers().ky(), k);
    assert_eq!(ask(&mut h, format!("ATKY000{f32}\r").as_bytes()), "OK\r");
    assert_eq!(h.core.registers().ky(), [0xFF; 16]);
    // Several per line, as the others.
    assert_eq!(ask(&mut h, b"ATKY1,EE0,KY\r"), "OK\rOK\rOK\r");
    assert!(!h.core.registers().ee());
}

#[test]
fn wr_re_and_fr_keep_or_reset_ee_and_ky_like_the_other_registers() {
    let mut h = Host::new(XBeeConfig::api(2));
    let m = Mode::Escaped;
    at(&mut h, m, 1, b"EE", &[1]);
    at(&mut h, m, 2, b"KY", &KEY);
    at(&mut h, m, 3, b"WR", &[]);
    at(&mut h, m, 4, b"KY", &[0x01]);
    at(&mut h, m, 5, b"EE", &[0]);
    assert!(h.core.persisted().ee());
    assert_eq!(h.core.persisted().ky(), KEY);
    assert_eq!(h.core.registers().ky()[15], 0x01);
    // A power cycle restores what WR wrote.
    let t = h.t + ms(1.0);
    h.core.reset(t);
    h.run_to(t + ms(10.0));
    assert!(h.core.registers().ee());
    assert_eq!(h.core.registers().ky(), KEY);
    // RE: factory defaults, EE 0 and KY 0 (the persisted set keeps the key until a WR).
    at(&mut h, m, 6, b"RE", &[]);
    assert!(!h.core.registers().ee());
    assert_eq!(h.core.registers().ky(), [0; 16]);
    assert_eq!(h.core.persisted().ky(), KEY);
    // FR: back to the persisted set (RE set AP 0, so this is the last API exchange).
    let mut h = Host::new(XBeeConfig {
        ee: true,
        ky: KEY,
        ..XBeeConfig::api(2)
    });
    at(&mut h, m, 1, b"EE", &[0]);
    at(&mut h, m, 2, b"KY", &[0x02]);
    at(&mut h, m, 3, b"FR", &[]);
    h.run_ms(20.0);
    assert!(h.core.registers().ee());
    assert_eq!(h.core.registers().ky(), KEY);
}

/// A radio in API mode 2 with encryption as given (`None`: `EE`=0).
fn secured(key: Option<[u8; 16]>, sh_sl: u64) -> Host {
    Host::new(XBeeConfig {
        ee: key.is_some(),
        ky: key.unwrap_or_default(),
        sh_sl,
        ..XBeeConfig::api(2)
    })
}

/// A TX16 broadcast request of `payload` with frame id `id`.
fn tx16(id: u8, payload: &[u8]) -> Vec<u8> {
    let mut d = vec![0x01, id, 0xFF, 0xFF, 0x00];
    d.extend_from_slice(payload);
    d
}

#[test]
fn encryption_limits_payloads_to_95_bytes_and_adds_5_bytes_of_air_time() {
    for (key, limit) in [(None, 100), (Some(KEY), 95)] {
        let mut h = secured(key, 0x0013_A200_0000_0001);
        h.take();
        assert_eq!(h.core.max_payload(), limit);
        let end = h.frame(&tx16(1, &vec![0x55; limit]), Mode::Escaped);
        // One byte over: refused exactly like 101 bytes without encryption.
        h.frame(&tx16(2, &vec![0x55; limit + 1]), Mode::Escaped);
        h.run_ms(20.0);
        let out = h.take();
        assert_eq!(frames(&bytes(&out), Mode::Escaped), [vec![0x89, 1, 0x00]]);
        assert_eq!(h.core.stats().oversize_tx, 1);
        assert_eq!(h.core.stats().transmissions, 1);
        let txs = h.core.take_transmissions_with_security();
        assert_eq!(txs.len(), 1);
        let (tx, security) = &txs[0];
        assert_eq!(tx.payload.len(), limit);
        // Either way the packet is 100 bytes long on air: 95 of payload + 5 of header.
        let toa = ms(time_on_air_ms(100));
        assert_eq!((tx.start_cycle, tx.end_cycle), (end + lead(), end + toa));
        assert_eq!(out[0].cycle, end + toa, "TX status when off the air");
        match key {
            None => assert_eq!(*security, Security::Clear),
            Some(k) => assert_eq!(
                *security,
                Security::Encrypted {
                    key: k,
                    source64: 0x0013_A200_0000_0001,
                    counter: 0
                }
            ),
        }
    }
    // A short encrypted packet: 10 bytes of payload are on air as 15, 1.408 ms.
    let mut h = secured(Some(KEY), 1);
    let end = h.frame(&tx16(0, b"0123456789"), Mode::Escaped);
    h.frame(&tx16(0, b"x"), Mode::Escaped);
    h.run_ms(10.0);
    assert_eq!(SECURITY_HEADER_BYTES, 5);
    let txs = h.core.take_transmissions_with_security();
    assert_eq!(txs[0].0.end_cycle - end, ms(1.408));
    assert_eq!(
        txs[0].0.end_cycle - txs[0].0.start_cycle,
        ms(time_on_air_ms(15)) - lead()
    );
    // The frame counter numbers the encrypted packets.
    let counters: Vec<_> = txs
        .iter()
        .map(|(_, s)| match s {
            Security::Encrypted { counter, .. } => *counter,
            Security::Clear => u32::MAX,
        })
        .collect();
    assert_eq!(counters, [0, 1]);
    // Transparent mode packetizes at 95 bytes with encryption.
    let mut h = Host::new(XBeeConfig {
        bd: 6,
        ee: true,
        ..XBeeConfig::default()
    });
    h.send(&[b'z'; 250]);
    h.run_ms(10.0);
    let lens: Vec<usize> = h
        .core
        .take_transmissions()
        .iter()
        .map(|t| t.payload.len())
        .collect();
    assert_eq!(lens, [95, 95, 60]);
}

/// What a receiver with encryption `rx` outputs (RX16 frame data, or bare bytes in transparent
/// mode) of `payload` sent by a radio with encryption `tx`, and its counters.
fn receive(
    tx: Option<[u8; 16]>,
    rx: Option<[u8; 16]>,
    ap: u8,
    payload: &[u8],
) -> (Vec<Vec<u8>>, simavr::xbee::XBeeStats) {
    let mut sender = secured(tx, 0x0013_A200_0000_0001);
    sender.frame(&tx16(0, payload), Mode::Escaped);
    sender.run_ms(10.0);
    let mut receiver = Host::new(XBeeConfig {
        ap,
        ee: rx.is_some(),
        ky: rx.unwrap_or_default(),
        ..XBeeConfig::api(2)
    });
    receiver.take();
    for (t, security) in sender.core.take_transmissions_with_security() {
        let packet = RxPacket::from_transmission(&t, -50);
        receiver.core.deliver_secured(packet, security, t.end_cycle);
    }
    receiver.run_ms(20.0);
    let out = receiver.take_bytes();
    let got = match ap {
        0 if out.is_empty() => vec![],
        0 => vec![out],
        _ => frames(&out, Mode::Escaped),
    };
    (got, receiver.core.stats())
}

#[test]
fn a_receiver_hears_an_encrypted_packet_only_with_ee_set_and_the_same_key() {
    let other: [u8; 16] = core::array::from_fn(|i| i as u8);
    let payload: Vec<u8> = (0..40u8).map(|i| b'a' + i % 26).collect();
    let mut rx16 = vec![0x81, 0x00, 0x00, 50, 0x02];
    rx16.extend_from_slice(&payload);
    for ap in [2, 0] {
        let clear = if ap == 0 {
            payload.clone()
        } else {
            rx16.clone()
        };
        // No encryption at either end, or the same key: unchanged.
        for (tx, rx) in [(None, None), (Some(KEY), Some(KEY))] {
            let (got, stats) = receive(tx, rx, ap, &payload);
            assert_eq!(
                got,
                std::slice::from_ref(&clear),
                "{tx:?} → {rx:?}, AP={ap}"
            );
            assert_eq!((stats.rx_delivered, stats.rx_wrong_key), (1, 0));
        }
        // Encrypted at one end only: nothing, counted.
        for (tx, rx) in [(None, Some(KEY)), (Some(KEY), None)] {
            let (got, stats) = receive(tx, rx, ap, &payload);
            assert!(got.is_empty(), "{tx:?} → {rx:?}, AP={ap}: {got:x?}");
            assert_eq!((stats.rx_delivered, stats.encryption_mismatch), (0, 1));
            assert_eq!((stats.rx_filtered, stats.rx_lost), (0, 0));
        }
        // Other keys: the packet comes out, its payload garbled to the same length.
        let (got, stats) = receive(Some(KEY), Some(other), ap, &payload);
        assert_eq!(got.len(), 1);
        assert_eq!((stats.rx_delivered, stats.rx_wrong_key), (1, 1));
        let garbled = &got[0];
        assert_eq!(garbled.len(), clear.len());
        let body = &garbled[garbled.len() - payload.len()..];
        assert_eq!(
            garbled[..garbled.len() - payload.len()],
            clear[..clear.len() - payload.len()],
            "the header (source, RSSI, options) as usual"
        );
        let same = body.iter().zip(&payload).filter(|(a, b)| a == b).count();
        assert!(same <= 3, "{same} of 40 bytes unchanged: {body:x?}");
        // Looks random: spread over the byte range, not just letters.
        assert!(
            body.iter().any(|&b| b >= 0x80) && body.iter().any(|&b| b < 0x40),
            "{body:x?}"
        );
        // The same inputs give the same bytes; another key or payload other ones.
        assert_eq!(receive(Some(KEY), Some(other), ap, &payload).0, got);
        assert_ne!(receive(Some(KEY), Some([0x33; 16]), ap, &payload).0, got);
        assert_ne!(receive(Some([0x33; 16]), Some(other), ap, &payload).0, got);
        let mut changed = payload.clone();
        changed[0] ^= 1;
        let got2 = receive(Some(KEY), Some(other), ap, &changed).0;
        assert_ne!(got2, got);
        // CTR-like: a payload byte changed changes that one output byte.
        let at = got[0].len() - payload.len();
        assert_ne!(got2[0][at], got[0][at]);
        assert_eq!(
            (&got2[0][..at], &got2[0][at + 1..]),
            (&got[0][..at], &got[0][at + 1..])
        );
    }
    // Empty payloads stay empty.
    let (got, _) = receive(Some(KEY), Some(other), 2, b"");
    assert_eq!(got, [vec![0x81, 0x00, 0x00, 50, 0x02]]);
}

#[test]
fn the_frame_counter_makes_each_packet_garble_differently_and_restarts_at_power_up() {
    let other = [0x33; 16];
    let mut sender = secured(Some(KEY), 7);
    for _ in 0..2 {
        sender.frame(&tx16(0, &[0u8; 16]), Mode::Escaped);
        sender.run_ms(5.0);
    }
    let t = sender.t;
    sender.core.reset(t);
    sender.run_ms(10.0);
    sender.frame(&tx16(0, &[0u8; 16]), Mode::Escaped);
    sender.run_ms(5.0);
    let mut receiver = secured(Some(other), 8);
    receiver.take();
    let txs = sender.core.take_transmissions_with_security();
    assert_eq!(txs.len(), 3);
    for (t, security) in txs {
        let at = t.end_cycle.max(receiver.t);
        receiver
            .core
            .deliver_secured(RxPacket::from_transmission(&t, -40), security, at);
        receiver.run_to(at + ms(5.0));
    }
    let got = frames(&receiver.take_bytes(), Mode::Escaped);
    assert_eq!(got.len(), 3);
    assert_ne!(got[0], got[1], "counters 0 and 1");
    assert_eq!(got[0], got[2], "counter 0 again after the power cycle");
}

#[test]
fn a_revived_firmware_node_comes_back_with_the_ee_and_ky_its_radio_wrote() {
    use simavr::{Medium, MediumConfig, Network, NodeRadio, NodeSpec};
    let mut net = Network::new(Medium::new(MediumConfig::noise_free()));
    let spec = NodeSpec::new("n", NodeRadio::at(0.0, 0.0));
    let id = net.add_node(common::fixture("xbee_model"), spec).unwrap();
    // Past the fixture's own exchange; then EE, KY and WR on its radio's line.
    net.run_for_ms(50.0);
    let mut line = Vec::new();
    for d in [
        &b"\x08\x00EE\x01"[..],
        &[&b"\x08\x00KY"[..], &KEY].concat(),
        b"\x08\x00WR",
    ] {
        line.extend(encode_frame(d, Mode::Escaped));
    }
    let now = net.cycle() - net.offset(id);
    net.core_mut(id).rx_bytes(now, &line);
    net.run_for_ms(10.0);
    assert_eq!(net.core(id).persisted().ky(), KEY);
    net.kill(id);
    net.run_for_ms(1.0);
    net.revive(id).unwrap();
    net.run_for_ms(10.0);
    let r = net.core(id).registers();
    assert!(r.ee());
    assert_eq!(r.ky(), KEY);
}

// ---- the xbee-api driver against the model ----

/// The driver on a host port to a modelled radio that powers up with it (`simavr::xbee::
/// ModelPort`); the port handle comes back to look at the radio.
fn driver_on(cfg: XBeeConfig) -> (ModelPort, Radio<ModelPort, ModelClock>) {
    let port = ModelPort::radio_at_power_up(cfg);
    let radio = Radio::new(port.clone(), port.clock(), Mode::Escaped);
    (port, radio)
}

#[test]
fn driver_bring_up_configures_a_factory_radio() {
    let (sim, mut radio) = driver_on(XBeeConfig {
        gt_ms: 100,
        ..XBeeConfig::default()
    });
    let cfg = BringUpConfig {
        my: Some(0x0001),
        pan_id: Some(0x4242),
        channel: Some(0x0B),
        guard_ms: 150,
        timeout_ms: 200,
        ..BringUpConfig::new()
    };
    let how = radio.bring_up(&cfg).expect("bring-up");
    assert_eq!(how, BringUp::Configured { baud: 9600 });
    let core = sim.core().unwrap();
    let r = core.registers();
    assert_eq!(
        (r.ap(), r.bd(), r.my(), r.id(), r.ch()),
        (2, 6, 1, 0x4242, 0x0B)
    );
    assert_eq!(core.mode(), Some(Mode::Escaped));
    assert_eq!(core.uart_baud(), 57_600);
    assert_eq!(core.channel(), 0x0B);
    assert_eq!((core.persisted().ap(), core.persisted().bd()), (2, 6));
    drop(core);
    assert_eq!(sim.bauds()[..2], [57_600, 57_600], "tried 57600 first");

    // Once written, a power cycle comes back in API mode at 57600: bring-up is quick.
    sim.power_cycle();
    let how = radio.bring_up(&cfg).expect("second bring-up");
    assert_eq!(how, BringUp::AlreadyApi);
    // The driver and the model agree on TX and AT exchanges.
    let id = radio.send_tx16(0xFFFF, b"beacon").unwrap();
    radio.wait_tx_status(100, |_| {}).unwrap();
    let txs = sim.core().unwrap().take_transmissions();
    assert_eq!(txs.last().unwrap().payload, b"beacon");
    assert_eq!(txs.last().unwrap().frame_id, id);
    radio.set_channel(0x0D, 100, |_| {}).unwrap();
    assert_eq!(sim.core().unwrap().channel(), 0x0D);
    let rc = radio.read_config(100, |_| {}).unwrap();
    assert_eq!((rc.my, rc.pan_id, rc.channel, rc.ap), (1, 0x4242, 0x0D, 2));
}

#[test]
fn driver_bring_up_of_a_radio_in_ap1_at_57600() {
    let (sim, mut radio) = driver_on(XBeeConfig {
        gt_ms: 100,
        ..XBeeConfig::api(1)
    });
    let cfg = BringUpConfig {
        guard_ms: 150,
        timeout_ms: 200,
        ..BringUpConfig::new()
    };
    assert_eq!(
        radio.bring_up(&cfg).unwrap(),
        BringUp::Configured { baud: 57_600 }
    );
    assert_eq!(sim.core().unwrap().mode(), Some(Mode::Escaped));
}

#[test]
fn driver_bring_up_sets_the_models_key_and_ee() {
    let (sim, mut radio) = driver_on(XBeeConfig {
        gt_ms: 100,
        ..XBeeConfig::api(2)
    });
    let cfg = BringUpConfig {
        channel: Some(0x0D),
        encryption: Encryption::Key(KEY),
        guard_ms: 150,
        timeout_ms: 200,
        ..BringUpConfig::new()
    };
    assert_eq!(radio.bring_up(&cfg).unwrap(), BringUp::AlreadyApi);
    {
        let core = sim.core().unwrap();
        assert!(core.registers().ee());
        assert_eq!(core.registers().ky(), KEY);
        assert!(!core.persisted().ee(), "not written");
    }
    // Encrypted from now on: 95 bytes go, 96 are refused (no TX status: the wait times out).
    radio.send_tx16(0xFFFF, &[0x55; 95]).unwrap();
    radio.wait_tx_status(100, |_| {}).unwrap();
    radio.send_tx16(0xFFFF, &[0x55; 96]).unwrap();
    assert_eq!(
        radio.wait_tx_status(100, |_| {}),
        Err(xbee_api::driver::Error::TxStatusTimeout)
    );
    let txs = sim.core().unwrap().take_transmissions_with_security();
    assert_eq!(txs.len(), 1);
    assert!(matches!(txs[0].1, Security::Encrypted { key: KEY, .. }));
    // Off again.
    let off = BringUpConfig {
        encryption: Encryption::Off,
        ..cfg
    };
    assert_eq!(radio.bring_up(&off).unwrap(), BringUp::AlreadyApi);
    assert!(!sim.core().unwrap().registers().ee());
}

// ---- on an Avr, with the C fixture ----

fn fixture() -> Avr {
    Avr::load(common::fixture("xbee_model")).expect("load xbee_model fixture")
}

#[test]
fn avr_firmware_gets_modem_status_at_response_and_tx_status() {
    let mut avr = fixture();
    let mut radio = XBee::new(XBeeConfig {
        my: 0x0007,
        ..XBeeConfig::api(2)
    });
    radio.run_for_ms(&mut avr, 40.0);
    assert_eq!(
        radio.texts(),
        ["boot", "rx 8a 00", "rx 88 01 43 48 00 0c", "rx 89 10 00",]
    );
    let f = radio.frames_from_firmware().to_vec();
    assert_eq!(f.len(), 2);
    assert_eq!(f[0].data, [0x08, 0x01, b'C', b'H']);
    assert_eq!(f[1].data, [0x01, 0x10, 0x12, 0x34, 0x00, b'o', b'k']);
    // The AT response's first byte reaches the RX line 1 ms after the query's last byte.
    let input = avr.uart_input();
    let resp = input
        .iter()
        .find(|b| b.cycle > f[0].end_cycle && b.byte == 0x7E)
        .unwrap();
    let late = resp.cycle - (f[0].end_cycle + ms(1.0));
    assert!(late < 100, "{late} cycles late");
    let txs = radio.take_transmissions();
    assert_eq!(txs.len(), 1);
    assert_eq!(txs[0].payload, b"ok");
    assert_eq!(txs[0].source, Address::Short(0x0007));
    assert_eq!(txs[0].start_cycle, f[1].end_cycle + lead());
    let s = radio.stats();
    assert_eq!((s.frames_ok, s.checksum_errors), (2, 0));
    // "boot\n" went out before the radio was up; the three "rx …" lines reach it.
    assert_eq!(s.dropped_powering_up, 5);
    assert_eq!(s.foreign_bytes, 9 + 21 + 12);
    assert_eq!(avr.uart_rx_dropped(), 0);
}

#[test]
fn avr_firmware_receives_delivered_packets_on_its_channel() {
    let mut avr = fixture();
    let mut radio = XBee::new(XBeeConfig::api(2));
    radio.run_for_ms(&mut avr, 40.0);
    let at = avr.cycle() + ms(1.0);
    radio.deliver(
        RxPacket::broadcast16(0x0C, 0x3332, 0xBEEF, -55, b"\x7e!"),
        at,
    );
    radio.deliver(RxPacket::broadcast16(0x0D, 0x3332, 0xBEEF, -56, b"no"), at);
    radio.run_for_ms(&mut avr, 20.0);
    assert_eq!(radio.texts()[4..], ["rx 81 be ef 37 02 7e 21"]);
}

#[test]
fn avr_firmware_at_the_wrong_baud_rate_sees_garbage() {
    let mut avr = fixture();
    avr.eeprom_write(0, &[1]).unwrap(); // the fixture then runs its UART at 9600
    let mut radio = XBee::new(XBeeConfig::api(2));
    radio.run_for_ms(&mut avr, 60.0);
    assert!(radio.frames_from_firmware().is_empty());
    let s = radio.stats();
    assert!(s.garbled_in > 0 && s.garbled_out > 0, "{s:?}");
    assert_eq!(s.frames_ok, 0);
    assert_eq!(radio.texts(), ["boot"], "no frame came through either way");
    assert!(radio.sent().iter().all(|b| b.byte >= 0xF0));
}

/// An API `AT CH` that sets the channel is answered once the switch is done
/// (`channel_switch_ms`, the nodes' worst case by default); meanwhile the radio hears nothing,
/// and a TX request that reaches it is lost: no packet, no status.
#[test]
fn a_channel_change_answers_after_the_switch_and_loses_what_comes_before() {
    assert_eq!(
        XBeeConfig::default().channel_switch_ms,
        xbee_api::CHANNEL_SWITCH_US as f64 / 1000.0
    );
    for switch_ms in [2.0, 9.0] {
        let mut h = Host::new(XBeeConfig {
            channel_switch_ms: switch_ms,
            ..XBeeConfig::api(2)
        });
        h.take();
        let end = h.frame(&[0x08, 0x01, b'C', b'H', 0x0D], Mode::Escaped);
        // A TX request right behind it, and a packet on the new channel during the switch.
        h.frame(&[0x01, 0x02, 0xFF, 0xFF, 0x00, b'x'], Mode::Escaped);
        let during = end + ms(switch_ms / 2.0);
        h.core
            .deliver(RxPacket::broadcast16(0x0D, 0x3332, 7, -50, b"lost"), during);
        h.run_ms(switch_ms + 20.0);
        let out = h.take();
        let answer = out.iter().find(|b| b.byte == 0x7E).expect("an answer");
        let waited = answer.cycle - end;
        assert!(
            waited >= ms(switch_ms) && waited < ms(switch_ms) + ms(0.1),
            "{switch_ms} ms: answered after {waited} cycles"
        );
        let f = frames(&bytes(&out), Mode::Escaped);
        assert_eq!(f, [vec![0x88, 0x01, b'C', b'H', 0x00]], "no status, no RX");
        assert!(h.core.take_transmissions().is_empty());
        let st = h.core.stats();
        assert_eq!((st.tx_lost_switching, st.rx_switching), (1, 1));
        // After the answer: both work on the new channel.
        h.frame(&[0x01, 0x03, 0xFF, 0xFF, 0x00, b'y'], Mode::Escaped);
        let t = h.t + ms(5.0);
        h.core
            .deliver(RxPacket::broadcast16(0x0D, 0x3332, 7, -50, b"heard"), t);
        h.run_ms(20.0);
        let f = frames(&h.take_bytes(), Mode::Escaped);
        assert_eq!(f.len(), 2, "{f:02x?}");
        assert_eq!(f[0][..3], [0x89, 0x03, 0x00]);
        assert_eq!(f[1][0], 0x81);
        let txs = h.core.take_transmissions();
        assert_eq!((txs.len(), txs[0].channel), (1, 0x0D));
    }
}

// ---- settings a previous owner may have left: PL, RR, SM, A1 ----

/// A radio with the registers `leftovers` (as a second-hand radio keeps them), API mode 2.
fn left_with(leftovers: &[([u8; 2], u32)], tweak: impl FnOnce(&mut XBeeConfig)) -> Host {
    let mut cfg = XBeeConfig {
        leftovers: leftovers.to_vec(),
        ..XBeeConfig::api(2)
    };
    tweak(&mut cfg);
    let mut h = Host::new(cfg);
    h.take();
    h
}

/// A TX16 request of `payload` to `dest` with frame id `id`.
fn tx16_to(id: u8, dest: u16, payload: &[u8]) -> Vec<u8> {
    let mut d = vec![0x01, id];
    d.extend_from_slice(&dest.to_be_bytes());
    d.push(0x00);
    d.extend_from_slice(payload);
    d
}

/// `PL` sets every packet's output power (Digi's S1 manual: −10, −6, −4, −2, 0 dBm on the S1,
/// 10…18 dBm on the S1 Pro): each carries its power relative to `PL` 4, data and ACKs alike.
#[test]
fn pl_sets_the_power_every_packet_carries_relative_to_pl_4() {
    for (model, want) in [
        (Model::S1, [-10, -6, -4, -2, 0]),
        (Model::S1Pro, [-8, -6, -4, -2, 0]),
    ] {
        for (pl, &want) in want.iter().enumerate() {
            let mut h = left_with(&[(*b"PL", pl as u32)], |c| {
                c.model = model;
                c.ch = 0x0C;
            });
            h.frame(&tx16(1, b"beacon"), Mode::Escaped);
            h.run_ms(10.0);
            let txs = h.core.take_transmissions();
            assert_eq!(txs.len(), 1);
            assert_eq!(txs[0].power_db, want, "{model:?} PL {pl}");
            assert_eq!(model.power_db(pl as u8), want);
        }
    }
    assert_eq!(
        (Model::S1.output_dbm(0), Model::S1Pro.output_dbm(4)),
        (-10, 18)
    );
    // An ACK goes out at its sender's power level too.
    let mut sender = left_with(&[], |c| c.my = 1);
    sender.core.set_on_medium(true);
    sender.frame(&tx16_to(1, 2, b"report"), Mode::Escaped);
    sender.run_ms(5.0);
    let data = sender.core.take_transmissions().remove(0);
    let mut receiver = left_with(&[(*b"PL", 1)], |c| c.my = 2);
    receiver.core.receive(&data, -50, Security::Clear);
    receiver.run_ms(5.0);
    let ack = receiver.core.take_transmissions().remove(0);
    assert_eq!(ack.mac.kind, FrameKind::Ack);
    assert_eq!(ack.power_db, -6);
}

/// `RR` > 0 repeats every broadcast: `RR` + 2 copies in all (Digi's S1 manual, `RR`), each
/// with its own channel access after the one before is off the air, the TX status after the
/// last. Receivers in a Digi MAC mode pass on the first copy they get and drop the others
/// (duplicate detection); strict 802.15.4 (`MM` 2) sends one copy.
#[test]
fn rr_repeats_every_broadcast_and_receivers_pass_on_one_copy() {
    for (rr, mm, copies) in [(0, 0, 1), (1, 0, 3), (3, 0, 5), (6, 3, 8), (3, 2, 1)] {
        let mut h = left_with(&[(*b"RR", rr), (*b"MM", mm)], |c| c.my = 7);
        let end = h.frame(&tx16(9, b"beacon"), Mode::Escaped);
        h.run_ms(40.0);
        let txs = h.core.take_transmissions();
        assert_eq!(txs.len(), copies, "RR {rr} MM {mm}");
        let air = ms(time_on_air_ms(6)) - lead();
        for (i, tx) in txs.iter().enumerate() {
            assert_eq!(tx.mac.attempt as usize, i);
            assert_eq!(tx.mac.seq, txs[0].mac.seq, "one sequence number");
            assert!(!tx.mac.ack_request);
            // Csma::Off: each copy goes on air a CCA and a turnaround after the one before.
            assert_eq!(tx.start_cycle, end + lead() + i as u64 * (air + lead()));
        }
        let out = h.take();
        assert_eq!(
            frames(&bytes(&out), Mode::Escaped),
            [vec![0x89, 9, 0x00]],
            "one status"
        );
        assert_eq!(out[0].cycle, txs.last().unwrap().end_cycle);
        let st = h.core.stats();
        assert_eq!(
            (st.transmissions, st.repeats, st.retries),
            (copies as u32, copies as u32 - 1, 0)
        );
        // A receiver in the factory MAC mode passes one on; in strict 802.15.4 every copy.
        for (rx_mm, passed) in [(0, 1), (2, copies)] {
            let mut r = left_with(&[(*b"MM", rx_mm)], |c| c.my = 8);
            for tx in &txs {
                r.core.receive(tx, -50, Security::Clear);
                r.run_to(tx.end_cycle.max(r.t) + ms(0.01));
            }
            r.run_ms(5.0);
            let got = frames(&r.take_bytes(), Mode::Escaped);
            assert_eq!(got.len(), passed, "RR {rr}, receiver MM {rx_mm}");
            let dups = r.core.stats().rx_duplicates as usize;
            assert_eq!(dups, copies - passed);
            assert!(r.core.take_transmissions().is_empty(), "no ACKs");
        }
    }
    // A unicast is acknowledged: sent once, as before.
    let mut h = left_with(&[(*b"RR", 3)], |_| {});
    h.frame(&tx16_to(1, 2, b"report"), Mode::Escaped);
    h.run_ms(20.0);
    assert_eq!(h.core.take_transmissions().len(), 1);
}

/// A broadcast for `h`'s radio: on its channel, in its PAN.
fn packet_for(h: &Host) -> RxPacket {
    let r = h.core.registers();
    RxPacket::broadcast16(r.ch(), r.id(), 0x0042, -50, b"heard")
}

/// Delivers a packet for `h` and says whether its host got it.
fn hears(h: &mut Host) -> bool {
    h.take();
    let at = h.t + ms(1.0);
    let p = packet_for(h);
    h.core.deliver(p, at);
    h.run_ms(10.0);
    frames(&h.take_bytes(), Mode::Escaped)
        .iter()
        .any(|f| f[0] == 0x81)
}

/// Sends a broadcast TX request; returns (packets on air, the status frames).
fn sends(h: &mut Host, id: u8) -> (usize, Vec<Vec<u8>>) {
    h.take();
    h.frame(&tx16(id, b"beacon"), Mode::Escaped);
    h.run_ms(10.0);
    let f = frames(&h.take_bytes(), Mode::Escaped);
    let status = f.into_iter().filter(|f| f[0] == 0x89).collect();
    (h.core.take_transmissions().len(), status)
}

/// `SM` ≠ 0 (Digi's S1 manual, sleep modes): a sleeping radio's receiver is off. A cyclic
/// sleeper (`SM` 4, 5; 3 is reserved, taken as one) hears nothing, but its host still talks
/// to it: AT commands are answered and TX requests sent. In pin sleep (`SM` 1, 2) with
/// `SLEEP_RQ` high, as an Arduino shield leaves it, the radio takes nothing from its UART
/// either, not even at power-up; with the pin driven low (a USB adapter) it is awake. `SM` 6,
/// the sleep coordinator, does not sleep.
#[test]
fn a_sleeping_radio_hears_nothing_and_in_pin_sleep_takes_nothing_from_its_host() {
    for sm in 3..=5 {
        let mut h = left_with(&[(*b"SM", sm)], |_| {});
        assert!(h.core.is_asleep());
        assert!(!hears(&mut h), "SM {sm}");
        assert_eq!(h.core.stats().rx_asleep, 1);
        assert_eq!(sends(&mut h, 3), (1, vec![vec![0x89, 3, 0x00]]), "SM {sm}");
        assert_eq!(
            at(&mut h, Mode::Escaped, 4, b"SM", &[]),
            [0x88, 4, b'S', b'M', 0, sm as u8]
        );
        // Sleep off: it hears again.
        assert_eq!(
            at(&mut h, Mode::Escaped, 5, b"SM", &[0]),
            [0x88, 5, b'S', b'M', 0]
        );
        assert!(hears(&mut h));
    }
    for sm in [1, 2] {
        // Pin sleep on a shield: nothing from the radio, not even its modem status.
        let mut core = XBeeCore::new(XBeeConfig {
            leftovers: vec![(*b"SM", sm)],
            ..XBeeConfig::api(2)
        });
        core.set_host_baud(57_600);
        core.advance(ms(10.0));
        assert!(core.take_output().is_empty(), "SM {sm}: no modem status");
        let query = encode_frame(&[0x08, 0x01, b'S', b'M'], Mode::Escaped);
        core.rx_bytes(ms(10.0), &query);
        core.deliver(RxPacket::broadcast16(0x0C, 0x3332, 1, -50, b"x"), ms(20.0));
        core.advance(ms(40.0));
        assert!(
            core.take_output().is_empty(),
            "SM {sm}: no answer, nothing heard"
        );
        let st = core.stats();
        assert_eq!((st.dropped_asleep, st.rx_asleep), (query.len() as u32, 1));
        // On an adapter that drives SLEEP_RQ low: awake.
        let mut h = left_with(&[(*b"SM", sm)], |c| c.sleep_rq = false);
        assert!(!h.core.is_asleep());
        assert!(hears(&mut h));
        assert_eq!(
            at(&mut h, Mode::Escaped, 2, b"SM", &[]),
            [0x88, 2, b'S', b'M', 0, sm as u8]
        );
    }
    let mut h = left_with(&[(*b"SM", 6)], |_| {});
    assert!(hears(&mut h), "the sleep coordinator is awake");
}

/// `A1` bit 2 (Digi's S1 manual, end device association): an end device looks for a
/// coordinator to associate with and, none answering in a hoploc network, never finds one:
/// `AI` answers 0x02 (active scan found no PANs), it passes on nothing it hears, and a TX
/// request puts nothing on air and gets no status (Digi's S1 manual gives none for it; the
/// worst case). A coordinator (`CE` 1) does not associate.
#[test]
fn an_end_device_looking_for_a_coordinator_neither_sends_nor_passes_on() {
    let mut h = left_with(&[(*b"A1", 4)], |_| {});
    assert!(h.core.is_associating());
    assert_eq!(
        at(&mut h, Mode::Escaped, 1, b"AI", &[]),
        [0x88, 1, b'A', b'I', 0, 0x02]
    );
    assert_eq!(sends(&mut h, 2), (0, vec![]), "no packet, no status");
    assert!(!hears(&mut h));
    let st = h.core.stats();
    assert_eq!((st.tx_associating, st.rx_associating), (1, 1));
    // The other bits alone do nothing.
    at(&mut h, Mode::Escaped, 3, b"A1", &[0x0B]);
    assert_eq!(
        at(&mut h, Mode::Escaped, 4, b"AI", &[]),
        [0x88, 4, b'A', b'I', 0, 0]
    );
    assert_eq!(sends(&mut h, 5), (1, vec![vec![0x89, 5, 0x00]]));
    assert!(hears(&mut h));
    let mut coordinator = left_with(&[(*b"A1", 4), (*b"CE", 1)], |_| {});
    assert!(!coordinator.core.is_associating());
    assert_eq!(sends(&mut coordinator, 6), (1, vec![vec![0x89, 6, 0x00]]));
}

/// The S1's serial receive buffer holds [`DI_BUFFER_BYTES`] (Digi's S1 manual) of frames the
/// radio has not finished with; without flow control what comes beyond is lost. A radio that
/// retries a unicast nobody acknowledges (`RR` 2: twelve transmissions) still holds its frame
/// when the host writes the next one: that frame's tail beyond the buffer is lost, and the
/// frame with it. The same frames once the first is done go through.
#[test]
fn a_host_that_writes_faster_than_the_radio_sends_loses_what_overflows_its_buffer() {
    assert_eq!(DI_BUFFER_BYTES, 202);
    let big = |id| tx16_to(id, 2, &[0x55; 100]);
    assert_eq!(encode_frame(&big(1), Mode::Escaped).len(), 109);
    for back_to_back in [true, false] {
        let mut h = left_with(&[(*b"RR", 2)], |_| {});
        // On a medium that carries no ACK: every transmission waits in vain.
        h.core.set_on_medium(true);
        h.frame(&big(1), Mode::Escaped);
        if !back_to_back {
            h.run_ms(100.0);
        }
        h.frame(&big(2), Mode::Escaped);
        h.run_ms(100.0);
        // A third frame once the first is done finds room (the cut one is dropped).
        h.frame(&big(3), Mode::Escaped);
        h.run_ms(100.0);
        let st = h.core.stats();
        let f = frames(&h.take_bytes(), Mode::Escaped);
        if back_to_back {
            assert_eq!(st.di_overflow, 16);
            assert_eq!((st.frames_ok, st.bad_frames), (2, 1));
            assert_eq!(f, [vec![0x89, 1, 0x01], vec![0x89, 3, 0x01]]);
        } else {
            assert_eq!(st.di_overflow, 0);
            assert_eq!(st.frames_ok, 3);
            assert_eq!(f.len(), 3);
        }
        assert_eq!(st.transmissions, 12 * f.len() as u32);
    }
}
