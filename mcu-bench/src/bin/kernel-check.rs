//! kernel-check: `uno_board::AvrTerm` (the cost term, its column loop, the posterior's
//! accumulation and its weights' setup in AVR assembly) against `loc_core::fixed::
//! {portable_term, portable_column, portable_posterior, portable_weights}` on the MCU itself:
//! edge cases and 50 000 pseudo-random terms, then 5 000 pseudo-random columns, 5 000
//! pseudo-random posterior columns and 5 000 pseudo-random weight setups; prints `kernel
//! <checked> <mismatches>`, `column …`, `posterior …` and `weights …`, each after its first
//! mismatches (`bad lo carry rho clamp portable avr`, `badcol rows anchors bound
//! portable/avr…`, `badpost rows span ra b col portable/avr…` for cref, s, sx, sy, `badwts k26
//! sigma span span b b ra ra`).
//! `tests/tests/mcu_bench.rs` runs it in simavr. Build: `cargo fw-bench`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    mcu_bench::fw::kernel_check()
}
