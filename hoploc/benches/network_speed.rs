//! Emulation speed of the testbed (SPEC §8: a 6-node network ≥ 2× real time on 2 cores; how it
//! scales to 25 nodes): the node firmwares (anchors, agents, a sink, in that mix) in simavr on
//! modelled XBees and the default radio medium, `SECONDS` of simulated time, with 1 and 2
//! threads. Prints simulated time / wall time (× real time); not a timed test.
//!
//! `cargo bench -p hoploc --bench network_speed` (builds the firmwares first if needed);
//! `HOPLOC_BENCH_SECONDS` overrides the simulated seconds (default 5).

use std::time::Instant;

use hoploc::firmware::{self, Role};
use simavr::medium::{Medium, MediumConfig, NodeRadio};
use simavr::network::{Network, NetworkConfig, NodeSpec};

fn network(nodes: usize, threads: usize) -> Network {
    let dir = firmware::default_dir();
    firmware::ensure_built(&dir).expect("firmware");
    let mut net = Network::with_config(
        Medium::new(MediumConfig::default()),
        NetworkConfig {
            threads,
            ..NetworkConfig::default()
        },
    );
    for i in 0..nodes {
        // One sink, one agent per four nodes, anchors for the rest, on a 5 m grid.
        let role = match i {
            0 => Role::Sink,
            i if i % 4 == 1 => Role::Agent,
            _ => Role::Anchor,
        };
        let pos = NodeRadio::at((i % 5) as f64 * 5.0, (i / 5) as f64 * 5.0);
        let mut spec = NodeSpec::new(format!("{}{i}", role.name()), pos);
        spec.xbee.sh_sl = 0x0013_A200_4000_0000 + i as u64;
        net.add_node(firmware::elf(&dir, role), spec)
            .expect("firmware loads");
    }
    net
}

fn main() {
    let seconds: f64 = std::env::var("HOPLOC_BENCH_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5.0);
    println!("network_speed: {seconds} s simulated per run (boot, bring-up, then the node loops)");
    println!(
        "{:>5} {:>7} {:>8} {:>10} {:>8} {:>8}",
        "nodes", "threads", "wall s", "× real", "packets", "quanta"
    );
    for nodes in [6, 25] {
        for threads in [1, 2] {
            let mut net = network(nodes, threads);
            let t0 = Instant::now();
            net.run_for_ms(seconds * 1000.0);
            let wall = t0.elapsed().as_secs_f64();
            println!(
                "{nodes:>5} {threads:>7} {wall:>8.2} {:>10.2} {:>8} {:>8}",
                seconds / wall,
                net.log().len(),
                net.quanta()
            );
        }
    }
}
