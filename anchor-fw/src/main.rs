//! anchor-fw firmware (boot logic comes with the foundation issue).
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}
