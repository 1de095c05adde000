//! The sink's search with the AVR kernels (`uno_board::AvrTerm`: the column, posterior,
//! weights, window, observation, placement, starting-point and search-driver routines in
//! assembly) against the portable one, both run on the MCU in simavr by mcu-bench's
//! `search-check` and `search-check2` firmwares.

use mcu_bench::harness;

/// The numbers after `tag` on its line of `out`.
fn counts(out: &str, tag: &str) -> Vec<u32> {
    let line = out
        .lines()
        .find_map(|l| l.strip_prefix(tag))
        .unwrap_or_else(|| panic!("no {tag} line: {out}"));
    line.split_whitespace()
        .map(|w| w.parse().unwrap())
        .collect()
}

/// 20 000 random jobs (half as a search sets them up, half garbage) give the same coarse start
/// (`AvrTerm::guess` = `portable_guess`), 10 000 random observation sets give the same setup
/// (`AvrTerm::observe` = `portable_observe`: every anchor slot and sum), and 150 random whole sink searches
/// (`mle_and_mmse_window_into`: flat, negative and thesis-like models, area corners, anchors
/// outside, 3 to 8 anchors, σ edge values) give the same two estimates, every field.
#[test]
fn avr_search_equals_the_portable_one() {
    harness::build().expect("bench firmware");
    let mut avr = simavr::Avr::load(harness::elf("search-check")).unwrap();
    while !avr.uart_output_string().contains("end\n") && avr.time_ms() < 900_000.0 {
        avr.run_for_ms(500.0);
    }
    let out = avr.uart_output_string();
    println!("{out}");
    assert_eq!(counts(&out, "guess "), [20_000, 0], "{out}");
    assert_eq!(counts(&out, "observe "), [10_000, 0], "{out}");
    assert_eq!(counts(&out, "search "), [150, 0], "{out}");
}

/// 2 000 random lattices give the same search with the assembly driver as with the portable
/// one over the same kernels (`AvrTerm::search` = `portable_search::<AvrTerm>`: best points,
/// posterior sums, window, sums, the job's header and offsets).
#[test]
fn avr_search_driver_equals_the_portable_one() {
    harness::build().expect("bench firmware");
    let mut avr = simavr::Avr::load(harness::elf("search-check2")).unwrap();
    while !avr.uart_output_string().contains("end\n") && avr.time_ms() < 900_000.0 {
        avr.run_for_ms(500.0);
    }
    let out = avr.uart_output_string();
    println!("{out}");
    assert_eq!(counts(&out, "driver "), [2_000, 0], "{out}");
}
