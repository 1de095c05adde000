//! checkasm: the column kernel's equality harness on the MCU (see `mcu_bench::checkasm`);
//! `tests/tests/checkasm.rs` runs it in simavr. Build: `cargo fw-bench`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    mcu_bench::fw::checkasm()
}
