//! board-check: uno-board's LED through embedded-hal's pin traits, its `Delay` through
//! `DelayNs`, and its UART receive ring, step by step as `mcu_bench::board` describes;
//! `tests/tests/board.rs` runs it in simavr. Build: `cargo fw-bench`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    use mcu_bench::board::{
        DelayKind, LedStep, DELAYS, FULL_WAIT_MS, LED_STEPS, STREAM_LEN, STREAM_TIMEOUT_MS,
    };
    use uno_board::prelude::*;
    use uno_board::{now_ms, now_us, rx_frame_start_us, Board};

    let Some(board) = Board::take() else {
        uno_board::reset()
    };
    let Board {
        mut serial,
        mut led,
        mut delay,
        ..
    } = board;
    let say = |serial: &mut uno_board::Serial, b: u8| {
        serial.write_byte(b);
        serial.flush_blocking();
    };

    for step in LED_STEPS {
        match step {
            LedStep::High => led.set_high(),
            LedStep::Low => led.set_low(),
            LedStep::Toggle => led.toggle(),
        }
        .ok();
        let high = led.is_set_high().unwrap_or(false);
        let low = led.is_set_low().unwrap_or(false);
        say(&mut serial, b'0' + u8::from(high));
        say(&mut serial, b'0' + u8::from(low));
        delay.delay_ms(1);
    }

    say(&mut serial, b'D');
    for case in [None].into_iter().chain(DELAYS.map(Some)) {
        say(&mut serial, b'<');
        match case {
            None => {}
            Some((DelayKind::Ms, n)) => delay.delay_ms(n),
            Some((DelayKind::Us, n)) => delay.delay_us(n),
            Some((DelayKind::Ns, n)) => delay.delay_ns(n),
        }
        say(&mut serial, b'>');
    }

    say(&mut serial, b'R');
    delay.delay_ms(FULL_WAIT_MS);
    while let Some(b) = serial.try_read() {
        serial.write_byte(b);
    }
    say(&mut serial, b'\n');

    let t = now_us();
    serial.write_bytes(&t.to_le_bytes());
    say(&mut serial, b'S');
    let start = now_ms();
    let mut got = 0;
    while got < STREAM_LEN && now_ms().wrapping_sub(start) < STREAM_TIMEOUT_MS {
        if let Some(b) = serial.try_read() {
            serial.write_byte(b);
            got += 1;
        }
    }
    serial.write_bytes(&rx_frame_start_us().to_le_bytes());
    mcu_bench::fw::end(&mut serial)
}
