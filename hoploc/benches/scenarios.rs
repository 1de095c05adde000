//! Every scenario of scenarios/ on the emulated testbed with the host sink (`hoploc demo`'s
//! run without its output): simulated seconds per wall second (× real time) with 1 and 2
//! stepping threads, and the sink's fixes per second after the warm-up against what the
//! superframe allows. Prints its figures; not a timed test.
//!
//! `cargo bench -p hoploc --bench scenarios` (builds the firmware first if needed);
//! `HOPLOC_BENCH_SECONDS` cuts each scenario to that much simulated time (default: whole).

use std::time::Instant;

use hoploc::firmware;
use hoploc::scenario::{self, Scenario};
use hoploc::testbed::{RunConfig, SinkSource, Testbed};

fn main() {
    let cap: Option<f64> = std::env::var("HOPLOC_BENCH_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok());
    let dir = firmware::default_dir();
    firmware::ensure_built(&dir).expect("firmware");
    println!("scenarios: each scenario's anchors and agent in simavr, host sink");
    println!(
        "{:<10} {:>5} {:>7} {:>8} {:>7} {:>9} {:>8} {:>8}",
        "scenario", "nodes", "threads", "sim s", "wall s", "× real", "fixes/s", "allowed"
    );
    for path in scenario::shipped() {
        let mut s = Scenario::load(&path).expect("scenario");
        if let Some(cap) = cap {
            let mut left = cap - s.timing.warmup_s;
            s.agent.path.retain_mut(|stop| {
                let keep = left > 1e-9;
                stop.dwell_s = stop.dwell_s.min(left.max(0.0));
                left -= stop.dwell_s;
                keep
            });
        }
        for threads in [1, 2] {
            let cfg = RunConfig {
                sink: SinkSource::Host,
                threads,
                ..RunConfig::default()
            };
            let mut tb = Testbed::new(&s, &dir, &cfg).expect("testbed");
            let t0 = Instant::now();
            let fixes = tb
                .run_to_end()
                .iter()
                .filter(|o| o.is_sink_mle() && o.time_s >= s.timing.warmup_s)
                .count();
            let wall = t0.elapsed().as_secs_f64();
            let sim = tb.time_s();
            println!(
                "{:<10} {:>5} {threads:>7} {sim:>8.1} {wall:>7.2} {:>9.1} {:>8.2} {:>8.2}",
                s.name,
                tb.network().len(),
                sim / wall,
                fixes as f64 / (sim - s.timing.warmup_s),
                1.0 / tb.superframe_s()
            );
        }
    }
}
