//! Emulation speed of the testbed (the target: a 6-node network ≥ 2× real time on 2 cores; how it
//! scales to 25 nodes), on proper testbeds built as `hoploc demo` builds them
//! ([`hoploc::testbed::add_scenario`]: every node with its own config in EEPROM):
//! * 6 nodes: room10 — 4 anchors, the agent and the sink firmware;
//! * 25 nodes: four room10 testbeds side by side (12 m apart) on disjoint channels
//!   ({1, 12} sink 3, {2, 13} sink 4, {5, 14} sink 6, {7, 15} sink 8) in one medium, and a
//!   second agent (id 2, report sub-slot 2) in the first.
//!
//! `SECONDS` of simulated time from power-up, with 1 and 2 stepping threads; prints simulated
//! time / wall time (× real time), packets on air, collisions and the machine's load average
//! (`/proc/loadavg`) before each run: the machine may be shared, and then the threads' barrier
//! spins make 2 threads slower than 1. Not a timed test.
//!
//! `cargo bench -p hoploc --bench network_speed` (builds the firmwares first if needed);
//! `HOPLOC_BENCH_SECONDS` overrides the simulated seconds (default 10).

use std::time::Instant;

use hoploc::firmware;
use hoploc::scenario::{self, Scenario};
use hoploc::testbed::{self, SinkSource, SERIAL_BASE};
use simavr::medium::Medium;
use simavr::network::{Network, NetworkConfig};

/// Channels (anchor channels, sink channel) of the four testbeds of the 25-node network.
const CHANNELS: [([u8; 2], u8); 4] = [([1, 12], 3), ([2, 13], 4), ([5, 14], 6), ([7, 15], 8)];

/// `testbeds` room10 testbeds (1 or 4) in one network, plus a second agent when there are 4.
fn network(testbeds: usize, threads: usize) -> Network {
    let dir = firmware::default_dir();
    firmware::ensure_built(&dir).expect("firmware");
    let room10 = Scenario::load(&scenario::resolve("room10")).expect("room10");
    let mut net = Network::with_config(
        Medium::new(room10.medium_config()),
        NetworkConfig {
            threads,
            seed: room10.seed,
            ..NetworkConfig::default()
        },
    );
    for (k, &(channels, sink)) in CHANNELS.iter().take(testbeds).enumerate() {
        let mut s = room10.clone();
        s.timing.channels = channels.to_vec();
        s.timing.sink_channel = sink;
        let origin = [12.0 * k as f64, 0.0];
        let serial = SERIAL_BASE + 0x100 * k as u64;
        testbed::add_scenario(&mut net, &s, &dir, SinkSource::Firmware, origin, serial)
            .expect("testbed");
        if testbeds > 1 && k == 0 {
            testbed::add_agent(&mut net, &s, &dir, 2, origin, serial).expect("agent 2");
        }
    }
    net
}

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "?".into())
}

fn main() {
    let seconds: f64 = std::env::var("HOPLOC_BENCH_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10.0);
    println!(
        "network_speed: room10 testbeds (sink firmware), {seconds} s simulated per run from \
         power-up; {} cores",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    println!(
        "{:>5} {:>7} {:>8} {:>8} {:>8} {:>6}  load avg (1, 5, 15 min) before",
        "nodes", "threads", "wall s", "× real", "packets", "coll"
    );
    for testbeds in [1, 4] {
        for threads in [1, 2] {
            let mut net = network(testbeds, threads);
            let before = load();
            let t0 = Instant::now();
            net.run_for_ms(seconds * 1000.0);
            let wall = t0.elapsed().as_secs_f64();
            println!(
                "{:>5} {threads:>7} {wall:>8.2} {:>8.2} {:>8} {:>6}  {before}",
                net.len(),
                seconds / wall,
                net.log().len(),
                net.log().iter().filter(|r| r.collided).count(),
            );
        }
    }
}
