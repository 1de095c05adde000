//! anchor-fw: the hoploc anchor node firmware for the Arduino Uno.
//!
//! For now the boot skeleton: set the board up, announce the role on the UART, blink, then idle
//! with the watchdog running. The node logic will live in a host-tested `lib.rs`; this file only
//! wires it to `uno-board`. Build: `cargo fw` (all firmwares) or `cargo fw-run -p anchor-fw`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

#[cfg(target_arch = "avr")]
uno_board::avr_progmem::progmem! {
    /// The boot line (no 0x7E: the radio shares the TX line).
    static progmem string BANNER = "hoploc anchor boot\r\n";
}

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    use uno_board::{now_ms, rx_pending, sleep_unless, Board, WdtTimeout};

    let Some(mut board) = Board::take() else {
        uno_board::reset()
    };
    board.serial.write_progmem(&BANNER);
    board.led.blink(2, 100, 100);
    board.watchdog.start(WdtTimeout::S1);
    let mut last_blink = now_ms();
    loop {
        board.watchdog.feed();
        while board.serial.try_read().is_some() {}
        if now_ms().wrapping_sub(last_blink) >= 1000 {
            last_blink = now_ms();
            board.led.toggle();
        }
        sleep_unless(rx_pending);
    }
}
