//! Baseline for the xbee-api flash-cost probe (`size-codec`): the same board setup and USART
//! loop, echoing bytes without the codec.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    use core::hint::black_box;
    use uno_board::{rx_pending, sleep_unless, Board};

    let Some(mut board) = Board::take() else {
        uno_board::reset()
    };
    loop {
        while let Some(byte) = board.serial.try_read() {
            board.serial.write_byte(black_box(byte));
        }
        sleep_unless(rx_pending);
    }
}
