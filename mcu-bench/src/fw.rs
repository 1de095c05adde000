//! The firmware side (AVR only): board setup, markers, the printed results, the stop.

use crate::{run, Inputs, Pipeline, Report};
use core::hint::black_box;
use uno_board::{Board, Serial};

/// Writes marker `b` and waits until it has left: the next marker then finds the transmitter
/// idle, so the cycles between two markers are the work between them plus this function's own
/// constant cost (one byte time and the polling), which the empty phase measures.
#[inline(never)]
fn mark(serial: &mut Serial, b: u8) {
    serial.write_byte(b);
    serial.flush_blocking();
}

fn write_u32(serial: &mut Serial, v: u32) {
    let mut buf = [0u8; 10];
    let (mut n, mut k) = (v, buf.len());
    loop {
        k -= 1;
        buf[k] = b'0' + (n % 10) as u8;
        n /= 10;
        if n == 0 {
            break;
        }
    }
    serial.write_bytes(&buf[k..]);
}

fn write_report(serial: &mut Serial, tag: &[u8], r: &Report) {
    serial.write_bytes(tag);
    for v in [r.x, r.y, r.p0, r.alpha] {
        serial.write_byte(b' ');
        write_u32(serial, v);
    }
    serial.write_byte(b'\n');
}

/// Runs the benchmark with `p` and stops: markers, then `\n`, the lines `mle x y p0 alpha` and
/// `mmse x y p0 alpha` (decimal words of [`Report`]) and `end`.
///
/// Interrupts stay off throughout (the 1 ms tick would otherwise add its handler to whichever
/// phase it hits). At the end the MCU sleeps with interrupts off: simavr stops there ("done").
pub fn main<P: Pipeline>(mut p: P) -> ! {
    let Some(board) = Board::take() else {
        uno_board::reset()
    };
    avr_device::interrupt::disable();
    let mut serial = board.serial;
    let inp = black_box(Inputs::BENCH);
    let [mle, mmse] = run(&mut p, &inp, |b| mark(&mut serial, b));
    serial.write_byte(b'\n');
    write_report(&mut serial, b"mle", &mle);
    write_report(&mut serial, b"mmse", &mmse);
    serial.write_bytes(b"end\n");
    serial.flush_blocking();
    loop {
        avr_device::interrupt::disable();
        avr_device::asm::sleep();
    }
}
