//! Agents among real anchor state machines ([`anchor_fw::Anchor`]) in an ideal medium on the
//! host: a beacon reaches every node tuned to its channel `LATENCY` after it is sent. The agents'
//! clocks are offset and run 0.3 % slow (anchor clocks are exact here; anchor-fw's own tests
//! drift them).

use super::*;
use anchor_fw::{Action as AnchorAction, Anchor, Heard as AnchorHeard};

/// 4 anchors, two channels, 25 ms slots with a 2 ms guard, two agent sub-slots of 20 ms, and
/// the nodes' time for each channel change (rounded up to the tests' polling step).
fn sched() -> Schedule {
    Schedule::new(4, 2, 25_000, 2, 20_000, 2_000)
        .and_then(|s| s.with_tune(loc_proto::schedule::TUNE_US.next_multiple_of(STEP as u32)))
        .unwrap()
}

fn channels() -> ChannelList {
    ChannelList::new(&[1, 12]).unwrap()
}

const LATENCY: u32 = 3_000;
const STEP: u64 = 100;
const POS: [[i16; 2]; 4] = [[0, 0], [1000, 0], [1000, 1000], [0, 1000]];

/// A report sent: (global time, agent, seq, what it carried).
type Sent = (u64, u8, u16, Report);

/// An agent's local clock at global time `t`: offset, 3000 ppm slow.
fn local(t: u64, off: u32) -> u32 {
    ((t - t * 3 / 1000) as u32).wrapping_add(off)
}

struct Sim {
    t: u64,
    anchors: Vec<(Anchor, Option<u8>, bool)>,
    agents: Vec<(Agent, Option<Tune>, u32)>,
    /// (delivery time, from, seq, channel).
    air: Vec<(u64, u8, u16, u8)>,
    /// Agents waiting for a TX status: (due, agent index, the report's seq).
    status: Vec<(u64, usize, u16)>,
    reports: Vec<Sent>,
    /// Whether the report of sequence number `seq` goes out (its TX status), per agent index.
    delivered: fn(usize, u16) -> bool,
}

impl Sim {
    fn new(agent_offsets: &[u32]) -> Sim {
        let s = sched();
        Sim {
            t: 0,
            anchors: (1..=4)
                .map(|id| (Anchor::new(id, s, LATENCY, 0), None, true))
                .collect(),
            agents: agent_offsets
                .iter()
                .enumerate()
                .map(|(k, &off)| {
                    (
                        Agent::new(k as u8 + 1, s, channels(), LATENCY, off),
                        None,
                        off,
                    )
                })
                .collect(),
            air: Vec::new(),
            status: Vec::new(),
            reports: Vec::new(),
            delivered: |_, _| true,
        }
    }

    fn run(&mut self, until: u64) {
        while self.t < until {
            let due: Vec<_> = self.air.iter().copied().filter(|d| d.0 <= self.t).collect();
            self.air.retain(|d| d.0 > self.t);
            for (_, from, seq, ch) in due {
                let rssi = 50 + from;
                let relay = [60, 61, 62, 63];
                for (a, tuned, alive) in &mut self.anchors {
                    if *alive && *tuned == Some(ch) && a.id() != from {
                        a.on_beacon(AnchorHeard {
                            from,
                            seq,
                            channel: ch,
                            rssi,
                            at_us: self.t as u32,
                        });
                    }
                }
                for (g, tuned, off) in &mut self.agents {
                    if *tuned == Some(Tune::List(ch)) {
                        g.on_beacon(Heard {
                            from,
                            seq,
                            channel: ch,
                            rssi,
                            at_us: local(self.t, *off),
                            pos: POS[from as usize - 1],
                            relay: &relay,
                        });
                    }
                }
            }
            let done: Vec<_> = self
                .status
                .iter()
                .copied()
                .filter(|d| d.0 <= self.t)
                .collect();
            self.status.retain(|d| d.0 > self.t);
            for (_, k, seq) in done {
                let ok = (self.delivered)(k, seq);
                if let Some(Action::Tune(to)) = self.agents[k].0.on_tx_status(ok) {
                    self.agents[k].1 = Some(to);
                }
            }
            for (a, tuned, _) in self.anchors.iter_mut().filter(|a| a.2) {
                while let Some(act) = a.poll(self.t as u32) {
                    match act {
                        AnchorAction::SetChannel(c) => *tuned = Some(c),
                        AnchorAction::SendBeacon { seq, channel } => {
                            self.air
                                .push((self.t + LATENCY as u64, a.id(), seq, channel))
                        }
                    }
                }
            }
            for (k, (g, tuned, off)) in self.agents.iter_mut().enumerate() {
                while let Some(act) = g.poll(local(self.t, *off)) {
                    match act {
                        Action::Tune(to) => *tuned = Some(to),
                        Action::SendReport { seq } => {
                            assert_eq!(
                                *tuned,
                                Some(Tune::Sink),
                                "agent {} reports off the sink channel",
                                k + 1
                            );
                            self.reports.push((self.t, k as u8 + 1, seq, *g.report()));
                            self.status.push((self.t + 2_000, k, seq));
                        }
                    }
                }
            }
            self.t += STEP;
        }
    }
}

#[test]
fn an_agent_waits_for_a_beacon_before_anything() {
    let mut g = Agent::new(1, sched(), channels(), LATENCY, 0);
    assert_eq!(g.poll(0), Some(Action::Tune(Tune::List(0))));
    for t in (0..5_000_000).step_by(1000) {
        assert_eq!(g.poll(t), None);
    }
    assert!(!g.synced());
}

#[test]
fn agents_report_every_superframe_in_their_sub_slots() {
    let s = sched();
    let sf = s.superframe_us() as u64;
    let mut sim = Sim::new(&[12_345, 999_999]);
    sim.run(12 * sf);
    // Anchor 1's channel-0 beacons give each superframe's global start.
    let late = 7 * sf;
    let reports: Vec<_> = sim.reports.iter().filter(|r| r.0 > late).collect();
    assert!(reports.len() >= 8, "{}", reports.len());
    for agent in [1u8, 2] {
        let mine: Vec<_> = reports.iter().filter(|r| r.1 == agent).collect();
        assert!(mine.len() >= 4);
        // One per superframe, consecutive sequences, one superframe apart.
        for w in mine.windows(2) {
            assert_eq!(w[1].2, w[0].2 + 1);
            assert!(
                w[1].0.abs_diff(w[0].0 + sf) <= 1_000,
                "{} {}",
                w[0].0,
                w[1].0
            );
        }
        for r in &mine {
            let c = &r.3;
            assert_eq!(c.seq, r.2);
            for ch in 0..2 {
                assert_eq!(&c.rssi[ch][..4], &[51, 52, 53, 54], "agent {agent} ch {ch}");
                for a in 0..4 {
                    // The relays as sent, less each anchor's entry for itself.
                    let mut want = [60, 61, 62, 63];
                    want[a] = 0;
                    assert_eq!(&c.relay[ch][a][..4], &want);
                }
            }
            assert_eq!(c.positions[..4], POS.map(|[x, y]| Position { x, y }));
            assert_eq!(c.positions[4], Position::default());
            // It encodes with the relay matrix and decodes back to itself.
            let mut buf = [0; 100];
            assert_eq!(c.encode(&mut buf), Ok(61));
            assert_eq!(Report::decode(&buf[..61]), Ok(*c));
        }
    }
    // Agent 2's report is one sub-slot after agent 1's, within the timing error.
    let a1 = reports.iter().find(|r| r.1 == 1).unwrap();
    let a2 = reports.iter().find(|r| r.1 == 2 && r.2 == a1.2).unwrap();
    assert!(a2.0.abs_diff(a1.0 + 20_000) <= 1_000, "{} {}", a1.0, a2.0);
    // Both back on the channel list after their TX status.
    for (g, tuned, _) in &sim.agents {
        assert!(g.synced());
        assert!(matches!(tuned, Some(Tune::List(_))));
    }
}

#[test]
fn a_silent_anchor_is_marked_not_heard() {
    let sf = sched().superframe_us() as u64;
    let mut sim = Sim::new(&[0]);
    sim.anchors[2].2 = false; // anchor 3 off
    sim.run(12 * sf);
    let last = sim.reports.last().unwrap();
    for ch in 0..2 {
        assert_eq!(&last.3.rssi[ch][..4], &[51, 52, 0, 54]);
        assert_eq!(last.3.relay[ch][2], [0; MAX_ANCHORS]);
    }
    assert_eq!(last.3.positions[2], Position::default());
}

#[test]
fn impossible_beacons_are_ignored() {
    let mut g = Agent::new(1, sched(), channels(), LATENCY, 0);
    for (from, channel) in [(0, 0), (5, 0), (1, 2)] {
        g.on_beacon(Heard {
            from,
            seq: 3,
            channel,
            rssi: 50,
            at_us: 0,
            pos: [0, 0],
            relay: &[],
        });
        assert!(!g.synced());
    }
    // A relay longer than the anchors does not overflow.
    g.on_beacon(Heard {
        from: 1,
        seq: 3,
        channel: 0,
        rssi: 50,
        at_us: 0,
        pos: [0, 0],
        relay: &[1; 20],
    });
    assert!(g.synced());
    assert_eq!(g.collecting().relay[0][0], [0, 1, 1, 1, 1, 1, 1, 1]);
}

/// A shell that sleeps [`Agent::wait_us`] between polls acts exactly at the event times, and
/// nothing is due before the wait is over.
#[test]
fn waiting_wait_us_between_polls_misses_nothing() {
    let s = sched();
    let sf = s.superframe_us();
    let mut g = Agent::new(2, s, channels(), LATENCY, 0);
    assert_eq!(g.wait_us(0), 0);
    assert_eq!(g.poll(0), Some(Action::Tune(Tune::List(0))));
    assert_eq!(g.wait_us(0), u32::MAX, "nothing to do before a beacon");
    // Anchor 1's channel-0 beacon of superframe 5, received at 100 ms: the superframe began
    // LATENCY + its transmit time earlier.
    let at = 100_000;
    g.on_beacon(Heard {
        from: 1,
        seq: 5,
        channel: 0,
        rssi: 50,
        at_us: at,
        pos: [0, 0],
        relay: &[0, 0, 0, 0],
    });
    let start = at - LATENCY - s.beacon_at_us(0, 1).unwrap();
    let mut t = at;
    let mut got = Vec::new();
    while t < start + 3 * sf {
        while let Some(act) = g.poll(t) {
            got.push((t - start, act));
        }
        let w = g.wait_us(t);
        assert!(
            w > 0,
            "poll returned None, so something must be ahead at {t}"
        );
        assert_eq!(
            g.poll(t + w - 1),
            None,
            "due before the wait ended ({t} + {w})"
        );
        t += w;
    }
    let mut want = Vec::new();
    for k in 0..3u16 {
        let base = k as u32 * sf;
        if k > 0 {
            want.push((base, Action::Tune(Tune::List(0))));
        }
        want.push((
            base + s.channel_start_us(1).unwrap(),
            Action::Tune(Tune::List(1)),
        ));
        // Agent 2 switches where the report window begins, before agent 1's sub-slot.
        let report = s.report_at_us(2).unwrap();
        want.push((base + s.report_start_us(), Action::Tune(Tune::Sink)));
        want.push((base + report, Action::SendReport { seq: 5 + k }));
    }
    assert_eq!(got, want);
}

/// Each report carries the failed transmissions since the last one that went out: counted
/// from the TX status, back to 0 after a report goes out, at most 7.
#[test]
fn failed_transmissions_ride_in_the_next_report() {
    let mut sim = Sim::new(&[0]);
    // Reports 10…12 fail, 13 goes out; 20…39 all fail.
    sim.delivered = |_, seq| !(10..13).contains(&seq) && !(20..40).contains(&seq);
    sim.run(45 * sched().superframe_us() as u64);
    let failed: Vec<(u16, u8)> = sim.reports.iter().map(|r| (r.2, r.3.failed)).collect();
    let of = |seq: u16| failed.iter().find(|f| f.0 == seq).map(|f| f.1);
    assert_eq!(of(9), Some(0), "{failed:?}");
    assert_eq!(of(10), Some(0));
    assert_eq!(of(12), Some(2));
    assert_eq!(of(13), Some(3));
    assert_eq!(of(14), Some(0));
    assert_eq!(of(25), Some(5));
    assert_eq!(of(28), Some(7));
    assert_eq!(of(39), Some(7));
    assert_eq!(of(40), Some(7));
    assert_eq!(of(41), Some(0));
    // And it encodes.
    let mut buf = [0; 100];
    let last = &sim.reports.iter().find(|r| r.2 == 40).unwrap().3;
    let n = last.encode(&mut buf).unwrap();
    assert_eq!(Report::decode(&buf[..n]).map(|r| r.failed), Ok(7));
}
