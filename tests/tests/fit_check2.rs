//! The sink's whole online round in AVR assembly (`uno_board::AvrFit`'s `FitKernel::step`:
//! current model, solve, AR(1) smoothers, σ) against its portable twin
//! (`loc_core::fixed::portable_step`, held to `fit_least_squares` + `OnlineParams::feed` by
//! loc-core's tests), both run on the MCU in simavr by mcu-bench's `fit-check2` firmware.

use mcu_bench::harness;

/// 20 000 random AR(1) steps alone equal, and over 10 000 random rounds on evolving states (all three modes; empty, small and extreme sums;
/// weights up to ±4, so smoothed outputs beyond the limits): the state, the job and the flag
/// equal, and the interesting paths all taken (no fit, σ saturated, α fed, a model clamped to a
/// limit).
#[test]
fn avr_step_equals_the_portable_one() {
    harness::build().expect("bench firmware");
    let mut avr = simavr::Avr::load(harness::elf("fit-check2")).unwrap();
    while !avr.uart_output_string().contains("end\n") && avr.time_ms() < 600_000.0 {
        avr.run_for_ms(500.0);
    }
    let out = avr.uart_output_string();
    // 20 000 random AR(1) steps (`FitKernel::ar1_update`) alone equal.
    assert!(out.contains("weigh 20000 0\n"), "{out}");
    let line = out
        .lines()
        .find_map(|l| l.strip_prefix("step "))
        .unwrap_or_else(|| panic!("no result: {out}"));
    println!("rounds, mismatches, no fit, σ saturated, α fed, clamped: {line}");
    let v: Vec<u32> = line
        .split_whitespace()
        .map(|w| w.parse().unwrap())
        .collect();
    let [rounds, bad, none, saturated, alpha, clamped] = v[..] else {
        panic!("{line}")
    };
    assert_eq!(bad, 0, "{out}");
    assert!(rounds >= 10_000, "{line}");
    assert!(none >= 300 && saturated >= 100, "{line}");
    assert!(alpha >= 3_000 && clamped >= 100, "{line}");
}
