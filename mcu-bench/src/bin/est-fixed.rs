//! est-fixed: loc-core's fixed-point sink estimate; see the mcu-bench crate docs.
//! Build: `cargo fw-bench`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    mcu_bench::fw::main(mcu_bench::fixed::Fixed::<loc_core::fixed::Native>::new())
}
