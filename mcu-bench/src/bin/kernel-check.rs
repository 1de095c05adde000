//! kernel-check: `uno_board::AvrTerm` (the cost term and its column loop in AVR assembly)
//! against `loc_core::fixed::{portable_term, portable_column}` on the MCU itself: edge cases and
//! 50 000 pseudo-random terms, then 5 000 pseudo-random columns; prints `kernel <checked>
//! <mismatches>` and `column <checked> <mismatches>`, each after its first mismatches (`bad lo
//! carry rho clamp portable avr`, `badcol rows anchors bound portable/avr…`).
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
