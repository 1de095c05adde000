//! Anchors in an ideal medium on the host: every beacon reaches every running anchor tuned to
//! its channel, `LATENCY` after its transmit time; each anchor has its own clock offset and
//! rate (the Uno's ceramic resonator is good to ±0.5 %: here up to ±0.2 %).

use super::*;

/// 4 anchors, channels [1, 12] (two), 25 ms slots with a 2 ms guard, one agent sub-slot, and
/// the nodes' time for each channel change (rounded up to the tests' polling step).
fn sched() -> Schedule {
    Schedule::new(4, 2, 25_000, 1, 20_000, 2_000)
        .and_then(|s| s.with_tune(loc_proto::schedule::TUNE_US.next_multiple_of(STEP)))
        .unwrap()
}

const LATENCY: u32 = 3_000;
/// Simulation step, µs.
const STEP: u32 = 100;
/// Slot timing error allowed: a beacon leaves within 1 ms of its scheduled time.
const SLOT_ERROR: u64 = 1_000;

/// A transmission: (global time, sender, seq, channel index).
type Tx = (u64, u8, u16, u8);

struct Node {
    a: Anchor,
    /// Local clock = global·(1 + ppm·10⁻⁶) + offset.
    offset: u32,
    ppm: i64,
    channel: Option<u8>,
    alive: bool,
}

struct Net {
    nodes: Vec<Node>,
    t: u64,
    txs: Vec<Tx>,
    /// In flight: (delivery global time, heard-from, seq, channel, rssi).
    air: Vec<(u64, u8, u16, u8, u8)>,
    /// Whether a sender's beacons reach the others.
    muted: [bool; 9],
}

impl Net {
    fn new(offsets: &[u32]) -> Net {
        let s = sched();
        let nodes = offsets
            .iter()
            .enumerate()
            .map(|(k, &offset)| Node {
                a: Anchor::new(k as u8 + 1, s, LATENCY, offset),
                offset,
                // Anchor 1 fast, the others slow by different amounts.
                ppm: [1_500, -2_000, -700, 300][k % 4],
                channel: None,
                alive: true,
            })
            .collect();
        Net {
            nodes,
            t: 0,
            txs: Vec::new(),
            air: Vec::new(),
            muted: [false; 9],
        }
    }

    fn local(&self, k: usize) -> u32 {
        let n = &self.nodes[k];
        let t = self.t as i64 + self.t as i64 * n.ppm / 1_000_000;
        (t as u32).wrapping_add(n.offset)
    }

    /// Runs until global time `until` (µs).
    fn run(&mut self, until: u64) {
        while self.t < until {
            // Deliveries due.
            let due: Vec<_> = self.air.iter().copied().filter(|d| d.0 <= self.t).collect();
            self.air.retain(|d| d.0 > self.t);
            for (_, from, seq, ch, rssi) in due {
                for k in 0..self.nodes.len() {
                    let at_us = self.local(k);
                    let n = &mut self.nodes[k];
                    if n.alive && n.a.id() != from && n.channel == Some(ch) {
                        n.a.on_beacon(Heard {
                            from,
                            seq,
                            channel: ch,
                            rssi,
                            at_us,
                        });
                    }
                }
            }
            for k in 0..self.nodes.len() {
                if !self.nodes[k].alive {
                    continue;
                }
                let now = self.local(k);
                while let Some(act) = self.nodes[k].a.poll(now) {
                    match act {
                        Action::SetChannel(c) => self.nodes[k].channel = Some(c),
                        Action::SendBeacon { seq, channel } => {
                            let id = self.nodes[k].a.id();
                            assert_eq!(self.nodes[k].channel, Some(channel), "anchor {id}");
                            self.txs.push((self.t, id, seq, channel));
                            if !self.muted[id as usize] {
                                let rssi = 40 + id;
                                self.air
                                    .push((self.t + LATENCY as u64, id, seq, channel, rssi));
                            }
                        }
                    }
                }
            }
            self.t += STEP as u64;
        }
    }

    /// Restarts node `k` (a reset: fresh state at the current time).
    fn reboot(&mut self, k: usize) {
        let now = self.local(k);
        let n = &mut self.nodes[k];
        n.a = Anchor::new(k as u8 + 1, sched(), LATENCY, now);
        n.channel = None;
        n.alive = true;
    }
}

/// Transmissions after global time `from`: no two closer than a slot less the timing error.
fn assert_no_slot_collisions(txs: &[Tx], from: u64) {
    let mut ts: Vec<_> = txs.iter().filter(|t| t.0 >= from).collect();
    ts.sort();
    for w in ts.windows(2) {
        assert!(
            w[1].0 - w[0].0 >= 25_000 - 2 * SLOT_ERROR,
            "two anchors in one slot: {:?} and {:?}",
            w[0],
            w[1]
        );
    }
}

#[test]
fn a_lone_anchor_listens_then_beacons_in_its_slots() {
    let s = sched();
    let mut a = Anchor::new(1, s, LATENCY, 1_000);
    assert_eq!(a.poll(1_000), Some(Action::SetChannel(0)));
    // Silent while it listens: 2 superframes for anchor 1.
    let sf = s.superframe_us();
    let mut t = 1_000;
    while t < 1_000 + 2 * sf {
        assert_eq!(a.poll(t), None, "at {t}");
        t += STEP;
    }
    // Then its own timeline from the first poll after listening.
    let start = t;
    let mut got = Vec::new();
    while t < start + 3 * sf {
        while let Some(act) = a.poll(t) {
            got.push((t - start, act));
        }
        t += STEP;
    }
    let mut want = Vec::new();
    for seq in 0..3u16 {
        let base = seq as u32 * sf;
        for c in 0..2u8 {
            want.push((base + s.channel_start_us(c).unwrap(), Action::SetChannel(c)));
            want.push((
                base + s.beacon_at_us(c, 1).unwrap(),
                Action::SendBeacon { seq, channel: c },
            ));
        }
    }
    assert_eq!(got, want);
}

/// A shell that sleeps [`Anchor::wait_us`] between polls acts exactly at the event times, and
/// nothing is due before the wait is over.
#[test]
fn waiting_wait_us_between_polls_misses_nothing() {
    let s = sched();
    let sf = s.superframe_us();
    let mut a = Anchor::new(2, s, LATENCY, 5_000);
    let mut t = 5_000u32;
    let mut got = Vec::new();
    while t < 5_000 + 7 * sf {
        while let Some(act) = a.poll(t) {
            got.push((t, act));
        }
        let w = a.wait_us(t);
        assert!(
            w > 0,
            "poll returned None, so something must be ahead at {t}"
        );
        assert_eq!(
            a.poll(t + w - 1),
            None,
            "due before the wait ended ({t} + {w})"
        );
        t += w;
    }
    // Listening ends after 3 superframes (anchor 2): then its slots, on its own timeline.
    let start = 5_000 + 3 * sf;
    let mut want = vec![(5_000, Action::SetChannel(0))];
    for seq in 0..4u16 {
        for c in 0..2u8 {
            let base = start + seq as u32 * sf;
            want.push((base + s.channel_start_us(c).unwrap(), Action::SetChannel(c)));
            want.push((
                base + s.beacon_at_us(c, 2).unwrap(),
                Action::SendBeacon { seq, channel: c },
            ));
        }
    }
    assert_eq!(got, want);
}

#[test]
fn anchors_sync_on_anchor_1_within_a_millisecond() {
    // Clocks far apart.
    let mut net = Net::new(&[0, 777_777, 123_456, 9_999_999]);
    net.run(12 * sched().superframe_us() as u64);
    let s = sched();
    // Anchor 1's beacon on channel 0 of superframe q gives the superframe's global start.
    let starts: Vec<(u16, u64)> = net
        .txs
        .iter()
        .filter(|t| t.1 == 1 && t.3 == 0)
        .map(|t| (t.2, t.0 - s.beacon_at_us(0, 1).unwrap() as u64))
        .collect();
    assert!(starts.len() >= 5);
    let late = starts[2].1;
    let (mut checked, mut worst) = (0, 0);
    for &(t, id, seq, ch) in net.txs.iter().filter(|t| t.0 > late) {
        let start = starts.iter().find(|s| s.0 == seq).map(|s| s.1);
        let Some(start) = start else { continue };
        let want = start + s.beacon_at_us(ch, id).unwrap() as u64;
        assert!(
            t.abs_diff(want) <= SLOT_ERROR,
            "anchor {id} seq {seq} ch {ch}: {t} vs {want}"
        );
        worst = worst.max(t.abs_diff(want));
        checked += 1;
    }
    assert!(checked > 40, "{checked}");
    // Clock drift between two re-alignments (anchor 1's own too: its clock defines the
    // timeline), and the step: well inside the millisecond.
    assert!(worst > 0 && worst <= 600, "worst slot error {worst} µs");
    // Every anchor beacons on both channels, same sequence numbers.
    for id in 1..=4 {
        assert!(net.txs.iter().any(|t| t.1 == id && t.3 == 1 && t.0 > late));
    }
    for n in &net.nodes {
        assert_eq!(n.a.master(), 1);
    }
    assert_no_slot_collisions(&net.txs, late);
}

#[test]
fn the_relay_carries_last_superframes_rssi_per_channel() {
    let mut net = Net::new(&[0, 5_000, 10_000, 20_000]);
    net.run(10 * sched().superframe_us() as u64);
    // Anchor 3 heard 1, 2 and 4 on both channels (rssi 40 + id); not itself.
    for c in 0..2 {
        assert_eq!(net.nodes[2].a.relay(c), &[41, 42, 0, 44]);
    }
    assert_eq!(net.nodes[2].a.relay(2), &[] as &[u8]);
    // The beacon of anchor 3 on channel index 1 (testbed channel 12) carries it, and encodes.
    let channels = loc_proto::msg::ChannelList::new(&[1, 12]).unwrap();
    let pos = Position { x: 1000, y: 1000 };
    let b = net.nodes[2].a.beacon(9, 1, &channels, pos);
    assert_eq!((b.anchor, b.seq, b.channel, b.position), (3, 9, 12, pos));
    assert_eq!(b.relay, [41, 42, 0, 44]);
    let mut buf = [0; Beacon::MAX_LEN];
    let n = b.encode(&mut buf).unwrap();
    assert_eq!(n, 19);
    assert_eq!(Beacon::decode(&buf[..n]), Ok(b));
}

#[test]
fn anchor_2_takes_over_when_anchor_1_falls_silent_and_hands_back() {
    let s = sched();
    let sf = s.superframe_us() as u64;
    let mut net = Net::new(&[0, 40_000, 80_000, 120_000]);
    net.run(10 * sf);
    let t_kill = net.t;
    net.nodes[0].alive = false;
    net.run(t_kill + 8 * sf);
    // Anchor 2 is master and the others follow it; beacons go on.
    for k in 1..4 {
        assert_eq!(net.nodes[k].a.master(), 2, "anchor {}", k + 1);
    }
    let after_kill: Vec<_> = net.txs.iter().filter(|t| t.0 > t_kill + 4 * sf).collect();
    for id in 2..=4 {
        assert!(after_kill.iter().filter(|t| t.1 == id).count() >= 6);
    }
    // Sequence numbers keep counting.
    let seqs: Vec<u16> = after_kill
        .iter()
        .filter(|t| t.1 == 2)
        .map(|t| t.2)
        .collect();
    assert!(seqs.windows(2).all(|w| w[1] == w[0] || w[1] == w[0] + 1));
    // Anchor 1 comes back: it listens, adopts the running timeline and takes master back.
    let t_back = net.t;
    net.reboot(0);
    net.run(t_back + 10 * sf);
    for n in &net.nodes {
        assert_eq!(n.a.master(), 1);
    }
    assert!(net.txs.iter().any(|t| t.1 == 1 && t.0 > t_back));
    // Never two anchors in one slot, through the takeover and the hand-back.
    assert_no_slot_collisions(&net.txs, 3 * sf);
}

#[test]
fn a_missing_anchor_leaves_its_slots_empty_and_the_rest_runs() {
    let s = sched();
    let sf = s.superframe_us() as u64;
    let mut net = Net::new(&[0, 1, 2, 3]);
    net.nodes[2].alive = false; // anchor 3 never boots
    net.run(12 * sf);
    assert!(net.txs.iter().all(|t| t.1 != 3));
    for id in [1, 2, 4] {
        assert!(net.txs.iter().filter(|t| t.1 == id).count() >= 10);
    }
    assert_eq!(net.nodes[1].a.relay(0)[2], 0, "anchor 3 not heard");
    assert_no_slot_collisions(&net.txs, 0);
}

#[test]
fn anchors_switched_on_together_end_on_one_timeline() {
    // Same boot time: the staggered listening lets anchor 1 start first.
    let sf = sched().superframe_us() as u64;
    let mut net = Net::new(&[0, 0, 0, 0]);
    net.run(10 * sf);
    for n in &net.nodes {
        assert_eq!(n.a.mode(), Mode::Running);
        assert_eq!(n.a.master(), 1);
    }
    assert_no_slot_collisions(&net.txs, 0);
}

#[test]
fn foreign_or_impossible_beacons_are_ignored() {
    let s = sched();
    let mut a = Anchor::new(2, s, LATENCY, 0);
    let bad = [
        Heard {
            from: 0,
            seq: 1,
            channel: 0,
            rssi: 50,
            at_us: 10,
        },
        Heard {
            from: 9,
            seq: 1,
            channel: 0,
            rssi: 50,
            at_us: 10,
        },
        Heard {
            from: 2,
            seq: 1,
            channel: 0,
            rssi: 50,
            at_us: 10,
        },
        Heard {
            from: 1,
            seq: 1,
            channel: 7,
            rssi: 50,
            at_us: 10,
        },
    ];
    for b in bad {
        a.on_beacon(b);
        assert!(matches!(a.mode(), Mode::Listening { .. }), "{b:?}");
        assert_eq!(a.master(), 2);
    }
}
