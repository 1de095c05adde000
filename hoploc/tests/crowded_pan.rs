//! What stops fixes on a crowded or hostile sink channel, and what the sink says about it, in
//! the emulated testbed: room10 with the real anchor, agent and sink firmware in simavr (every
//! radio with the XBee's CSMA-CA), plus a second agent with the same id, a device of the same
//! PAN that is no hoploc node, or a jammer. Each test reads the sink's status lines as
//! `hoploc monitor` does and checks the warnings it would print
//! ([`hoploc::diagnose::status_warnings`]).

use hoploc::diagnose;
use hoploc::firmware;
use hoploc::scenario::{self, Scenario};
use hoploc::testbed::{self, Observed, RunConfig, SinkSource, Testbed, SERIAL_BASE};
use loc_proto::config::Config;
use loc_proto::msg::{ChannelList, Position, Report, MAX_MESSAGE};
use loc_proto::sink_line::SinkLine;
use loc_proto::Role;
use simavr::medium::NodeRadio;
use simavr::network::{NodeId, NodeSpec};
use simavr::xbee::Csma;
use xbee_api::{Frame, Mode};

/// room10, noise-free, the agent at its first stop for `seconds`.
fn room10(seconds: f64) -> Scenario {
    let mut s = Scenario::load(&scenario::resolve("room10")).unwrap();
    s.medium.sigma_db = 0.0;
    s.medium.fading_sigma_db = 0.0;
    s.agent.path.truncate(1);
    s.agent.path[0].dwell_s = seconds;
    s
}

/// room10's testbed with the sink firmware.
fn testbed(s: &Scenario) -> Testbed {
    let dir = firmware::default_dir();
    firmware::ensure_built(&dir).unwrap();
    let cfg = RunConfig {
        sink: SinkSource::Firmware,
        ..RunConfig::default()
    };
    Testbed::new(s, &dir, &cfg).unwrap()
}

/// A host radio at (5, 6) m on the sink channel: PAN `pan`, address `my`, channel access
/// `csma`.
fn add_device(tb: &mut Testbed, name: &str, pan: u16, my: u16, csma: Csma) -> NodeId {
    let s = tb.scenario().clone();
    let mut spec = NodeSpec::new(name, NodeRadio::at(5.0, 6.0));
    spec.xbee.ch = loc_proto::xbee_channel(s.timing.sink_channel).unwrap();
    spec.xbee.id = pan;
    spec.xbee.my = my;
    spec.xbee.sh_sl = SERIAL_BASE + 30;
    spec.xbee.csma = csma;
    tb.network_mut().add_host_radio(spec)
}

/// Hands `device`'s radio a TX request of `payload` to `dest`, now.
fn send(tb: &mut Testbed, device: NodeId, dest: u16, payload: &[u8]) {
    let mut frame = [0u8; 256];
    let tx = Frame::Tx16 {
        frame_id: 1,
        dest,
        options: 0,
        data: payload,
    };
    let len = tx.encode(Mode::Escaped, &mut frame).unwrap();
    let net = tb.network_mut();
    let now = net.cycle();
    net.core_mut(device).rx_bytes(now, &frame[..len]);
}

/// The MLE fixes of `agent` from `from_s` on.
fn fixes_of(obs: &[Observed], agent: u8, from_s: f64) -> usize {
    obs.iter()
        .filter(|o| o.is_sink_mle() && o.time_s >= from_s)
        .filter(|o| matches!(o.line, SinkLine::Fix { agent: a, .. } if a == agent))
        .count()
}

/// The sink's status lines, in order.
fn status_lines(obs: &[Observed]) -> Vec<SinkLine> {
    obs.iter()
        .map(|o| o.line)
        .filter(|l| matches!(l, SinkLine::Status { .. }))
        .collect()
}

/// Every warning `hoploc monitor` prints for these status lines.
fn warnings(status: &[SinkLine]) -> Vec<String> {
    let mut out = Vec::new();
    let mut before = None;
    for now in status {
        out.extend(diagnose::status_warnings(before, now));
        before = Some(now);
    }
    out
}

fn warns(w: &[String], what: &str) -> bool {
    w.iter().any(|w| w.contains(what))
}

/// Two agents with one id (both id 1, two metres apart) report in the same sub-slot, with the
/// same sequence numbers (both count the anchors' superframes). Their radios' backoff and
/// channel check (`RN`, `CA` as bring-up sets them on an agent) let both reports through in
/// most superframes, and the sink counts the second of each pair as a repeat; the monitor's
/// warning names two agents with one id. (With the factory `RN` = 0 and `CA` = −44 dBm the two
/// collide on every attempt, and the sink hears neither.)
#[test]
fn two_agents_with_one_id_show_as_repeats_and_a_warning() {
    let s = room10(11.0);
    let mut tb = testbed(&s);
    let dir = firmware::default_dir();
    // The second agent id 1, at (3, 6) m, with its own serial number, switched on a while
    // after the first (two boards never start on the same microsecond).
    let twin_on_s = 2.3456;
    let mut obs = tb.step(twin_on_s);
    testbed::add_agent(
        tb.network_mut(),
        &s,
        &dir,
        1,
        [-2.0, 1.0],
        SERIAL_BASE + 100,
    )
    .unwrap();
    let sf = tb.superframe_s();
    obs.extend(tb.run_to_end());
    let status = status_lines(&obs);
    let Some(&SinkLine::Status {
        uptime_s,
        reports,
        repeats,
        checksum_errors,
        ..
    }) = status.last()
    else {
        panic!("no status line")
    };
    // Superframes of the status line's uptime with both agents synchronised (a second after
    // the second one's start).
    let superframes = (f64::from(uptime_s) - twin_on_s - 1.0) / sf;
    assert!(
        f64::from(repeats) >= superframes / 2.0,
        "{repeats} repeats in {superframes:.0} superframes"
    );
    assert_eq!(checksum_errors, 0);
    let w = warnings(&status);
    assert!(warns(&w, "two agents with one id"), "{w:?}");
    eprintln!(
        "two agents with id 1: {reports} reports, {repeats} repeats in {superframes:.0} \
         superframes by {uptime_s} s; {} fixes of agent 1; warnings: {w:?}",
        fixes_of(&obs, 1, s.timing.warmup_s)
    );
}

/// Without a second agent the same run counts no repeat and warns of nothing: the repeats of
/// the test above are the second agent's.
#[test]
fn one_agent_alone_shows_no_repeat_and_no_warning() {
    let s = room10(11.0);
    let mut tb = testbed(&s);
    let obs = tb.run_to_end();
    let status = status_lines(&obs);
    let Some(&SinkLine::Status {
        repeats, failed, ..
    }) = status.last()
    else {
        panic!("no status line")
    };
    assert_eq!((repeats, failed), (0, 0));
    assert_eq!(warnings(&status), Vec::<String>::new());
}

/// A device of the same PAN that is no hoploc node (a sensor sending 40-byte text readings to
/// the sink's address 20 times a second, with carrier sense): the sink counts its frames as
/// foreign, not as damaged; the agent's fixes go on at the superframe rate; the monitor warns
/// of frames that are no hoploc report.
#[test]
fn a_foreign_device_on_the_sink_channel_is_counted_and_the_fixes_go_on() {
    let s = room10(11.0);
    let mut tb = testbed(&s);
    let seed = s.seed;
    let dev = add_device(
        &mut tb,
        "sensor",
        Config::DEFAULT.pan_id,
        0x3003,
        Csma::Random { seed },
    );
    let (mut sent, mut obs) = (0usize, Vec::new());
    while !tb.done() {
        let reading = format!(
            "temperature={:>5.1} humidity={:>4.1} n={sent:08}",
            21.5, 40.0
        );
        send(&mut tb, dev, Role::Sink.address(1), reading.as_bytes());
        sent += 1;
        obs.extend(tb.step(0.05));
    }
    let sf = tb.superframe_s();
    let status = status_lines(&obs);
    let Some(&SinkLine::Status {
        uptime_s,
        foreign,
        checksum_errors,
        ..
    }) = status.last()
    else {
        panic!("no status line")
    };
    // 20 readings a second until the status line, after the sink's boot (about a second).
    let offered = 20.0 * (f64::from(uptime_s) - 1.0);
    assert!(
        f64::from(foreign) >= 0.9 * offered,
        "{foreign} foreign of about {offered:.0} readings"
    );
    assert_eq!(checksum_errors, 0, "foreign frames counted as damaged");
    let want = (s.duration_s() - s.timing.warmup_s) / sf;
    let ours = fixes_of(&obs, 1, s.timing.warmup_s);
    assert!(
        ours as f64 >= 0.9 * want,
        "{ours} fixes in {want:.0} superframes"
    );
    let w = warnings(&status);
    assert!(warns(&w, "no hoploc report"), "{w:?}");
    assert!(!warns(&w, "damaged"), "{w:?}");
    eprintln!(
        "a foreign sensor at 20 frames/s: {foreign} foreign frames by {uptime_s} s, {ours} fixes \
         in {want:.0} superframes; warnings: {w:?}"
    );
}

/// A device that sends well-formed reports of an agent 2 ten times a second (no network key):
/// the sink cannot tell it from an agent and locates it, but it does not crowd out agent 1,
/// whose fixes go on at the superframe rate.
#[test]
fn a_device_sending_reports_does_not_crowd_out_the_agent() {
    let s = room10(11.0);
    let mut tb = testbed(&s);
    let dev = add_device(
        &mut tb,
        "reporter",
        Config::DEFAULT.pan_id,
        0x2002,
        Csma::Random { seed: s.seed },
    );
    let (mut seq, mut obs) = (0u16, Vec::new());
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
        send(&mut tb, dev, Role::Sink.address(1), &payload[..n]);
        seq = seq.wrapping_add(1);
        obs.extend(tb.step(0.1));
    }
    let sf = tb.superframe_s();
    let want = (s.duration_s() - s.timing.warmup_s) / sf;
    let ours = fixes_of(&obs, 1, s.timing.warmup_s);
    let theirs = fixes_of(&obs, 2, s.timing.warmup_s);
    assert!(
        ours as f64 >= 0.9 * want,
        "{ours} fixes in {want:.0} superframes"
    );
    assert!(
        theirs > 0,
        "the other device's reports never reached the sink"
    );
    eprintln!(
        "a device sending agent 2's reports at 10/s: {ours} fixes of agent 1 in {want:.0} \
         superframes, {theirs} of 'agent 2'"
    );
}

/// A jammer on the sink channel (a radio of another PAN sending 90-byte broadcasts back to
/// back without carrier sense) for three seconds: the agent's radio finds the channel busy or
/// gets no ACK, its reports fail, and it says so in the next report that gets through; the
/// sink's status line counts the failed transmissions (nothing damaged, nothing foreign: the
/// sink's radio drops another PAN's frames) and the monitor warns of a busy channel. After the
/// jam the fixes come back.
#[test]
fn a_jammed_sink_channel_shows_as_failed_transmissions() {
    let s = room10(11.0);
    let mut tb = testbed(&s);
    let jammer = add_device(&mut tb, "jammer", 0x0BAD, 0x0BAD, Csma::Off);
    // From 4 to 7 s: the sink's first status line (at 10 s of uptime) comes after it.
    let (jam_from, jam_to) = (4.0, 7.0);
    let mut obs = tb.step(jam_from);
    // Broadcasts small enough that two requests fit the jammer radio's serial buffer
    // (`simavr::xbee::DI_BUFFER_BYTES`): the one on air and the one waiting.
    let noise = [0x55u8; 90];
    while tb.time_s() < jam_to {
        // The radio queues one request behind the other: keep one waiting.
        send(&mut tb, jammer, 0xFFFF, &noise);
        obs.extend(tb.step(0.004));
    }
    obs.extend(tb.run_to_end());
    let sf = tb.superframe_s();
    let status = status_lines(&obs);
    let Some(&SinkLine::Status {
        failed,
        foreign,
        checksum_errors,
        ..
    }) = status.last()
    else {
        panic!("no status line")
    };
    assert!(failed > 0, "{status:?}");
    assert_eq!((foreign, checksum_errors), (0, 0), "{status:?}");
    let w = warnings(&status);
    assert!(warns(&w, "sink channel is busy"), "{w:?}");
    // Fixes during the jam are few, after it they come at the superframe rate again.
    let during = fixes_of(&obs, 1, jam_from + sf) - fixes_of(&obs, 1, jam_to);
    let after_from = jam_to + 2.0 * sf;
    let after = fixes_of(&obs, 1, after_from);
    let want_after = (s.duration_s() - after_from) / sf;
    assert!(
        after as f64 >= 0.9 * want_after,
        "{after} fixes after the jam in {want_after:.0} superframes"
    );
    eprintln!(
        "a 3 s jam: {during} fixes during it ({:.0} superframes), {after} in {want_after:.0} \
         after; status failed {failed}; warnings: {w:?}",
        (jam_to - jam_from) / sf
    );
}
