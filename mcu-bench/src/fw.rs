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

pub use crate::rng::xorshift;

/// The board's UART, with interrupts off for the whole run (the 1 ms tick would otherwise add
/// its handler to whatever the firmware measures or checks): how every bench and check firmware
/// starts. Inlined, as [`end`]: the bench measures its `main`'s layout.
#[inline(always)]
pub fn start() -> Serial {
    let Some(board) = Board::take() else {
        uno_board::reset()
    };
    avr_device::interrupt::disable();
    board.serial
}

/// Writes `end`, waits until it has left and stops: the MCU sleeps with interrupts off, where
/// simavr ends the run ("done"). Inlined: out of line it changes how LLVM lays out the bench's
/// `main` (and so est-fixed's stack peak, which the bench measures).
#[inline(always)]
pub fn end(serial: &mut Serial) -> ! {
    serial.write_bytes(b"end\n");
    serial.flush_blocking();
    loop {
        avr_device::interrupt::disable();
        avr_device::asm::sleep();
    }
}

/// `v` in decimal on `serial`.
pub fn write_u32(serial: &mut Serial, v: u32) {
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

/// The line `tag v0 v1 …` (decimal) and `\n` on `serial`: how the check firmwares report.
pub fn write_line(serial: &mut Serial, tag: &[u8], vals: &[u32]) {
    serial.write_bytes(tag);
    for &v in vals {
        serial.write_byte(b' ');
        write_u32(serial, v);
    }
    serial.write_byte(b'\n');
}

fn write_report(serial: &mut Serial, tag: &[u8], r: &Report) {
    write_line(serial, tag, &[r.x, r.y, r.p0, r.alpha]);
}

/// Runs the benchmark with `p` and stops: markers, then `\n`, the lines `mle x y p0 alpha` and
/// `mmse x y p0 alpha` (decimal words of [`Report`]) and `end`.
///
/// Interrupts stay off throughout (the 1 ms tick would otherwise add its handler to whichever
/// phase it hits). At the end the MCU sleeps with interrupts off: simavr stops there ("done").
pub fn main<P: Pipeline>(mut p: P) -> ! {
    let mut serial = start();
    let inp = black_box(Inputs::BENCH);
    let [mle, mmse] = run(&mut p, &inp, |b| mark(&mut serial, b));
    serial.write_byte(b'\n');
    write_report(&mut serial, b"mle", &mle);
    write_report(&mut serial, b"mmse", &mmse);
    end(&mut serial)
}

/// The column kernel's equality harness ([`crate::checkasm`]): for every case of the table, its
/// jobs through the portable column and the AVR kernel, the line `case <name> <jobs>
/// <mismatches> <portable digest> <kernel digest>` (after at most three `mismatch <name> <job>
/// <rows> <anchors> <bound> <row> <portable> <kernel>` lines); then the line `bench <name>
/// <jobs>` and four markers around three timed loops over the bench case's jobs (portable
/// column, kernel, the generator alone), `\n` and `end`.
pub fn checkasm() -> ! {
    use crate::checkasm::{same, Digest, BENCH_CASE, BENCH_JOBS, CASES, MAX_ROWS};
    use crate::rng::Rng;
    use loc_core::fixed::{Avr, ColumnJob, ColumnKernel, Portable};
    let mut serial = start();
    let mut want = [0u32; MAX_ROWS];
    let mut got = [0u32; MAX_ROWS];
    let mut jw = ColumnJob::EMPTY;
    for case in black_box(&CASES) {
        let (mut r, mut bad) = (Rng(case.seed), 0u32);
        let (mut dp, mut da) = (Digest::NEW, Digest::NEW);
        for k in 0..case.count {
            let rows = (case.gen)(&mut r, &mut jw);
            let mut jg = jw;
            // The host's garbage in the reference's sums, another in the kernel's: a row it
            // leaves unwritten cannot match.
            want.fill(0xA5A5_A5A5);
            got.fill(0x5A5A_5A5A);
            Portable::column(black_box(&mut want[..rows]), &mut jw);
            Avr::column(black_box(&mut got[..rows]), &mut jg);
            dp.add(&want[..rows], &jw);
            da.add(&got[..rows], &jg);
            if !same(&want[..rows], &jw, &got[..rows], &jg) {
                bad += 1;
                if bad <= 3 {
                    let row = (0..rows).find(|&i| want[i] != got[i]).unwrap_or(0);
                    serial.write_bytes(b"mismatch ");
                    serial.write_bytes(case.name.as_bytes());
                    write_line(
                        &mut serial,
                        b"",
                        &[
                            k,
                            rows as u32,
                            jw.n as u32,
                            jw.bound,
                            row as u32,
                            want.get(row).copied().unwrap_or(jw.min),
                            got.get(row).copied().unwrap_or(jg.min),
                        ],
                    );
                }
            }
        }
        serial.write_bytes(b"case ");
        serial.write_bytes(case.name.as_bytes());
        write_line(&mut serial, b"", &[case.count, bad, dp.0, da.0]);
    }
    let case = &CASES[BENCH_CASE];
    serial.write_bytes(b"bench ");
    serial.write_bytes(case.name.as_bytes());
    write_line(&mut serial, b"", &[BENCH_JOBS]);
    let mut timed = |serial: &mut Serial, run: &mut dyn FnMut(&mut [u32], &mut ColumnJob)| {
        let mut r = Rng(case.seed);
        for _ in 0..black_box(BENCH_JOBS) {
            let rows = (case.gen)(&mut r, &mut jw);
            run(black_box(&mut want[..rows]), black_box(&mut jw));
        }
        mark(serial, b'A');
    };
    mark(&mut serial, b'A');
    timed(&mut serial, &mut |s, j| Portable::column(s, j));
    timed(&mut serial, &mut |s, j| Avr::column(s, j));
    timed(&mut serial, &mut |s, j| {
        black_box((s, j));
    });
    serial.write_byte(b'\n');
    end(&mut serial)
}
