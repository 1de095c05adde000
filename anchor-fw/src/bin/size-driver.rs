//! Flash-cost probe for the xbee-api driver as a node uses it: radio bring-up at boot, switch
//! channel, then read every received RX16 frame (the lean `RawFrame::rx16` view) and answer each
//! with a TX16 broadcast of its payload (waiting for the TX status). Over `uno-board`'s `Serial`
//! (which implements the embedded-hal-nb traits and `SetBaud`) and `SysClock` (`Clock`). Compare
//! with `size-baseline`.
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
    use xbee_api::driver::{BringUpConfig, Radio};
    use xbee_api::{Mode, MAX_RF_PAYLOAD};

    let Some(board) = Board::take() else {
        uno_board::reset()
    };
    let mut radio = Radio::new(board.serial, board.clock, Mode::Escaped);
    let _ = black_box(radio.bring_up(&BringUpConfig::new()));
    let _ = black_box(radio.set_channel(black_box(0x0B), 500, |f| {
        black_box(f);
    }));
    let mut payload = [0u8; MAX_RF_PAYLOAD];
    loop {
        let mut echo = 0usize;
        while let Some(event) = radio.poll(|raw| match raw.rx16() {
            Some(rx) => {
                black_box(rx.rssi.dbm());
                let n = rx.data.len().min(payload.len());
                payload[..n].copy_from_slice(&rx.data[..n]);
                n
            }
            None => 0,
        }) {
            if let Ok(n) = event {
                echo = n;
            }
            if echo > 0 {
                let _ = black_box(radio.send_tx16(0xFFFF, &payload[..echo]));
                let _ = radio.wait_tx_status(100, |f| {
                    black_box(f);
                });
                echo = 0;
            }
        }
        black_box(radio.stats());
        sleep_unless(rx_pending);
    }
}
