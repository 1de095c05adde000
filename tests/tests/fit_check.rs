//! The sink's least-squares solve in AVR assembly (`uno_board::AvrFit`) against its portable
//! twin (`loc_core::fixed::PortableFit`, held to the previous implementation and to f64 by
//! loc-core's tests), both run on the MCU in simavr by mcu-bench's `fit-check` firmware.

use mcu_bench::harness;

/// 20 000 random anchor-pair distances (`FitKernel::distance_x`) and 6 000 random pushes of a
/// pair's samples (`FitKernel::push`) equal (the AR(1) step: `fit_check2.rs`); over 10 000
/// random jobs (all
/// three modes; rooms, near-equal distances, Σx² = 0, extreme sums; thesis, narrow, reversed,
/// out-of-range and unbounded bounds): every result field equal, and the interesting paths all
/// taken (P0 alone, both in the box, both on an edge of it).
#[test]
fn avr_fit_equals_the_portable_one() {
    harness::build().expect("bench firmware");
    let mut avr = simavr::Avr::load(harness::elf("fit-check")).unwrap();
    while !avr.uart_output_string().contains("end\n") && avr.time_ms() < 600_000.0 {
        avr.run_for_ms(500.0);
    }
    let out = avr.uart_output_string();
    // 20 000 random anchor pairs' x (`FitKernel::distance_x`) equal, coincident ones among them.
    let dist = out
        .lines()
        .find_map(|l| l.strip_prefix("dist "))
        .unwrap_or_else(|| panic!("no dist result: {out}"));
    println!("distances, mismatches, coincident: {dist}");
    let d: Vec<u32> = dist
        .split_whitespace()
        .map(|w| w.parse().unwrap())
        .collect();
    assert_eq!(d[..2], [20_000, 0], "{out}");
    assert!(d[2] >= 500, "{dist}");
    // 6 000 random pushes of a pair's bytes (`FitKernel::push`) leave equal sums, hundreds of
    // them cut short by the 256-sample limit.
    let push = out
        .lines()
        .find_map(|l| l.strip_prefix("push "))
        .unwrap_or_else(|| panic!("no push result: {out}"));
    println!("pushes, mismatches, cut short: {push}");
    let p: Vec<u32> = push
        .split_whitespace()
        .map(|w| w.parse().unwrap())
        .collect();
    assert_eq!(p[..2], [6_000, 0], "{out}");
    assert!(p[2] >= 200, "{push}");
    let line = out
        .lines()
        .find_map(|l| l.strip_prefix("fit "))
        .unwrap_or_else(|| panic!("no result: {out}"));
    println!("jobs, mismatches, fitted 0/1/2, on an edge: {line}");
    let v: Vec<u32> = line
        .split_whitespace()
        .map(|w| w.parse().unwrap())
        .collect();
    let [jobs, bad, fixed, p0_only, both, edge] = v[..] else {
        panic!("{line}")
    };
    assert_eq!(bad, 0, "{out}");
    assert!(jobs >= 10_000, "{line}");
    assert_eq!(fixed + p0_only + both, jobs, "{line}");
    assert!(fixed >= 500 && p0_only >= 1_000 && both >= 2_000, "{line}");
    assert!(edge >= 1_000 && both - edge >= 500, "{line}");
}
