//! Flash-cost probe for the xbee-api codec: what the decoder and encoder of every frame type add
//! to a firmware (the xbee-api README keeps the measured figures).
//!
//! A real use of the codec on the Uno: bytes from USART0 go into the [`Decoder`], every frame is
//! parsed into a typed [`Frame`] view and re-encoded into a buffer that is written back out.
//! The API mode is hidden behind `black_box`, so the code for both modes (AP=1 and AP=2) is
//! kept. Compare with `size-baseline` (the same loop without the codec):
//! `cargo fw-size-probe && avr-size target/avr-none/fw/size-{baseline,codec}.elf`.
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
    use xbee_api::{Decoder, Mode, MAX_ENCODED};

    let Some(mut board) = Board::take() else {
        uno_board::reset()
    };
    let mode = black_box(Mode::Escaped);
    let mut decoder = Decoder::new(mode);
    let mut out = [0u8; MAX_ENCODED];
    loop {
        while let Some(byte) = board.serial.try_read() {
            let _ = decoder.push(byte);
            while let Some(event) = decoder.poll() {
                match event.map(|raw| raw.parse()) {
                    Ok(Ok(frame)) => {
                        if let Ok(n) = frame.encode(mode, &mut out) {
                            board.serial.write_bytes(out.get(..n).unwrap_or_default());
                        }
                    }
                    Ok(Err(e)) => {
                        black_box(e);
                    }
                    Err(e) => {
                        black_box(e);
                    }
                }
            }
        }
        black_box(decoder.stats());
        sleep_unless(rx_pending);
    }
}
