//! A debugging aid for the column kernel's harness: prints the host digest of every `checkasm`
//! case (`mcu_bench::checkasm::host_digest`, what the firmware's portable run must match) and the
//! first jobs of the first case with their portable results. `cargo run -p mcu-bench --example hd`.
use loc_core::fixed::{ColumnJob, ColumnKernel, Portable};
use mcu_bench::checkasm::*;
use mcu_bench::rng::Rng;
fn main() {
    for c in CASES.iter() {
        println!("{} {}", c.name, host_digest(c).0);
    }
    let c = &CASES[0];
    let mut r = Rng(c.seed);
    let mut job = ColumnJob::EMPTY;
    for k in 0..3 {
        let rows = (c.gen)(&mut r, &mut job);
        let mut sums = [0u32; 64];
        let j0 = job;
        Portable::column(&mut sums[..rows], &mut job);
        println!(
            "job {k}: rows {rows} {:?}\n  -> {:?} min {} ",
            j0.anchors[0],
            &sums[..rows],
            job.min
        );
    }
}
