//! A network key in the emulated testbed: room10 with every node provisioned with one key (the
//! real anchor, agent and sink firmware in simavr, the sink's fixes from its UART). The nodes turn
//! their radios' encryption on at boot; a device without the key, or with another one, sending
//! well-formed reports to the sink cannot put one into it: a radio with encryption off is not
//! heard by an encrypting one (and the other way round), and one with another key is passed on
//! garbled, which the messages' CRC rejects.

use hoploc::firmware;
use hoploc::scenario::{self, Scenario};
use hoploc::testbed::{self, RunConfig, SinkSource, Testbed, SERIAL_BASE};
use loc_proto::config::{Config, NetworkKey};
use loc_proto::msg::{ChannelList, Position, Report, MAX_MESSAGE};
use loc_proto::sink_line::SinkLine;
use loc_proto::Role;
use simavr::medium::NodeRadio;
use simavr::network::NodeSpec;
use xbee_api::{Frame, Mode};

const KEY: &str = "2B7E151628AED2A6ABF7158809CF4F3C";
const OTHER_KEY: &str = "000102030405060708090A0B0C0D0E0F";

/// room10, noise-free, one 10 s stop, every node with `key`.
fn keyed_room10(key: Option<&str>) -> Scenario {
    let mut s = Scenario::load(&scenario::resolve("room10")).unwrap();
    s.medium.sigma_db = 0.0;
    s.medium.fading_sigma_db = 0.0;
    s.agent.path.truncate(1);
    s.agent.path[0].dwell_s = 10.0;
    s.timing.network_key = key.map(str::to_string);
    s
}

/// The MLE fixes of `agent` after the warm-up.
fn fixes_of(obs: &[testbed::Observed], agent: u8, warmup_s: f64) -> usize {
    obs.iter()
        .filter(|o| o.is_sink_mle() && o.time_s >= warmup_s)
        .filter(|o| matches!(o.line, SinkLine::Fix { agent: a, .. } if a == agent))
        .count()
}

/// The reports the sink counted missing from the agents' sequences, by its last status line.
fn drops(obs: &[testbed::Observed]) -> u32 {
    match testbed::last_status(obs) {
        Some(SinkLine::Status { drops, .. }) => drops,
        _ => panic!("no status line"),
    }
}

/// Agent 1's report of every superframe after the warm-up (`want` of them, the first and last
/// cut by the run's ends) was located, or counted missing by the sink: the intruder's packets (a unicast every 100 ms that nobody
/// acknowledges, so each is sent four times) now and then keep the agent's channel check busy
/// past its last try, a few in a run.
fn assert_located_or_missed(ours: usize, drops: u32, want: f64) {
    let seen = ours as f64 + f64::from(drops);
    assert!(
        seen >= want.floor() - 1.0 && ours as f64 <= want + 1.0 && drops <= 3,
        "{ours} fixes of agent 1 and {drops} reports missing, want {want:.1} superframes"
    );
}

/// A device on the sink channel that is no node of the testbed: a host radio (at 5 m, 6 m) with
/// encryption on with `key` or off, sending a well-formed report (agent 2, every anchor heard,
/// a valid CRC) to the sink's address every 100 ms of the run; also returns how many of its
/// packets went on air after the warm-up without a collision.
fn run_with_intruder(key: Option<&str>) -> (Testbed, Vec<testbed::Observed>, usize) {
    let s = keyed_room10(Some(KEY));
    let dir = firmware::default_dir();
    firmware::ensure_built(&dir).unwrap();
    let cfg = RunConfig {
        sink: SinkSource::Firmware,
        ..RunConfig::default()
    };
    let mut tb = Testbed::new(&s, &dir, &cfg).unwrap();
    let mut spec = NodeSpec::new("intruder", NodeRadio::at(5.0, 6.0));
    spec.xbee.ch = loc_proto::xbee_channel(s.timing.sink_channel).unwrap();
    spec.xbee.id = Config::DEFAULT.pan_id;
    spec.xbee.my = 0x2002;
    spec.xbee.sh_sl = SERIAL_BASE + 30;
    if let Some(k) = key.and_then(NetworkKey::parse) {
        spec.xbee.ee = true;
        spec.xbee.ky = k.0;
    }
    let intruder = tb.network_mut().add_host_radio(spec);
    let (mut seq, mut obs) = (0, Vec::new());
    while !tb.done() {
        let mut r = Report::new(2, seq, 4, ChannelList::new(&[1, 12]).unwrap());
        for (i, p) in s.anchors.iter().enumerate() {
            r.positions[i] = Position {
                x: (p.position[0] * 100.0) as i16,
                y: (p.position[1] * 100.0) as i16,
            };
            r.rssi[0][i] = 60;
            r.rssi[1][i] = 61;
        }
        let mut payload = [0; MAX_MESSAGE];
        let n = r.encode(&mut payload).unwrap();
        let mut frame = [0u8; 128];
        let tx = Frame::Tx16 {
            frame_id: 1,
            dest: Role::Sink.address(1),
            options: 0,
            data: &payload[..n],
        };
        let len = tx.encode(Mode::Escaped, &mut frame).unwrap();
        let net = tb.network_mut();
        let now = net.cycle();
        net.core_mut(intruder).rx_bytes(now, &frame[..len]);
        seq += 1;
        obs.extend(tb.step(0.1));
    }
    // Its packets on air once the network has settled, not lost to a collision.
    let from = simavr::ms_to_cycles(s.timing.warmup_s * 1000.0);
    let sent = tb
        .network()
        .log()
        .iter()
        .filter(|r| r.from == intruder && !r.collided && r.tx.start_cycle >= from)
        .count();
    (tb, obs, sent)
}

/// Every node of a keyed network runs with its radio encrypting, and the fixes come at the
/// superframe rate as without a key; the device without the key sends its reports, and the
/// sink's radio passes none of them on.
#[test]
fn a_keyed_network_runs_and_a_sender_without_the_key_is_not_heard() {
    let (tb, obs, sent) = run_with_intruder(None);
    let s = tb.scenario().clone();
    let sf = tb.superframe_s();
    let net = tb.network();
    let nodes = tb.nodes().clone();
    let key = s.timing.key().unwrap().0;
    for id in nodes
        .anchors
        .iter()
        .copied()
        .chain([nodes.agent, nodes.sink])
    {
        let core = net.core(id);
        assert!(core.registers().ee(), "node {id}: encryption off");
        assert_eq!(core.registers().ky(), key, "node {id}");
        assert_eq!(core.stats().rx_wrong_key, 0, "node {id}");
    }
    let want = (s.duration_s() - s.timing.warmup_s) / sf;
    let ours = fixes_of(&obs, 1, s.timing.warmup_s);
    let drops = drops(&obs);
    assert_located_or_missed(ours, drops, want);
    assert_eq!(fixes_of(&obs, 2, 0.0), 0, "the intruder was located");
    // Its reports went on air, and the sink's radio dropped each of them.
    let dropped = net.core(nodes.sink).stats().encryption_mismatch as usize;
    assert!(
        sent > 50 && dropped >= sent,
        "{sent} sent, {dropped} dropped"
    );
    eprintln!(
        "keyed room10: {ours} fixes of agent 1 in {want:.0} superframes; {sent} reports of a \
         sender without the key, {dropped} dropped by the sink's radio"
    );
}

/// A sender with another key: the sink's radio passes its reports on garbled, and the sink
/// takes none of them for a report (each counted as a frame that is not one).
#[test]
fn a_sender_with_another_key_cannot_put_a_report_into_the_sink() {
    let (mut tb, obs, sent) = run_with_intruder(Some(OTHER_KEY));
    // Every report the sink wrote a `report` line for is agent 1's.
    let received = tb.take_reports();
    assert!(!received.is_empty() && received.iter().all(|(_, r)| r.agent == 1));
    let s = tb.scenario().clone();
    let sf = tb.superframe_s();
    let sink = tb.nodes().sink;
    let want = (s.duration_s() - s.timing.warmup_s) / sf;
    let ours = fixes_of(&obs, 1, s.timing.warmup_s);
    assert_located_or_missed(ours, drops(&obs), want);
    assert_eq!(fixes_of(&obs, 2, 0.0), 0, "the intruder was located");
    let garbled = tb.network().core(sink).stats().rx_wrong_key as usize;
    assert!(
        sent > 50 && garbled >= sent,
        "{sent} sent, {garbled} garbled"
    );
    // The sink counted each as a frame that is not a report.
    let Some(SinkLine::Status {
        frames,
        reports,
        checksum_errors,
        foreign,
        ..
    }) = testbed::last_status(&obs)
    else {
        panic!("no status line")
    };
    assert_eq!(frames, reports + checksum_errors + foreign);
    // (The last status line comes before the run's end: 10 s of uptime.)
    assert!(
        checksum_errors + foreign >= 50,
        "{garbled} garbled, {checksum_errors} corrupt + {foreign} foreign by the last status"
    );
    eprintln!(
        "keyed room10 with a sender keyed otherwise: {ours} fixes of agent 1; {garbled} garbled \
         frames at the sink, {checksum_errors} counted corrupt, {foreign} foreign"
    );
}
