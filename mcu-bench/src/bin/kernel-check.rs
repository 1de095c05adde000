//! kernel-check: `uno_board::AvrTerm` (the cost term, its column loop, the posterior's
//! accumulation, its weights' setup and the searches' division and high product in AVR
//! assembly) against `loc_core::fixed::{portable_term, portable_column, portable_posterior,
//! portable_weights, div_shl, mul_hi}` on the MCU itself: edge cases and 50 000 pseudo-random
//! terms, then 5 000 of each of the others (columns, posterior columns, weight setups,
//! divisions, products, window moves against `portable_move`, anchor placements against `portable_place`); prints `kernel <checked> <mismatches>`, `column …`, `posterior …`,
//! `weights …`, `div_shl …` and `mul_hi …`, each after its first mismatches (`bad lo carry rho
//! clamp portable avr`, `badcol rows anchors bound portable/avr…`, `badpost rows span ra b col
//! portable/avr…` for cref, s, sx, sy, `badwts k26 sigma span span b b ra ra`, `baddiv a b e
//! portable avr`, `badmul a b portable avr`, `badmove xstep ystep di dj dx0 dx0 dy0 dy0`, `move_window …`, `badplace n slot dx0 dx0 rho rho w·256+shift w·256+shift`,
//! `place …`).
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
