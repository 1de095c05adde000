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
/// simavr ends the run ("done"). Inlined: out of line it changed how LLVM laid out the bench's
/// `main` (est-fixed's stack peak +82 B), which the bench measures.
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

/// Runs [`crate::sink::run_sink`] with the AVR cost kernel and stops: the two markers, `\n`, the
/// sink's lines ([`crate::sink::write_lines`]), then `end`.
pub fn sink_main() -> ! {
    let mut serial = start();
    let inp = black_box(Inputs::BENCH);
    let lines = crate::sink::run_sink::<uno_board::AvrTerm>(&inp, |b| mark(&mut serial, b));
    let Ok(()) = crate::sink::write_lines(&lines, &mut serial);
    end(&mut serial)
}

/// The inputs of [`kernel_check`]: every `(d², carry)` edge of the normalisation and the
/// segment table, then xorshift draws over the whole range of each argument.
fn kernel_inputs(i: u32, r: &mut u32) -> (u32, bool, i32, i32) {
    const EDGES: [u32; 12] = [
        0,
        1,
        2,
        3,
        0xFFFF,
        0x1_0000,
        0xFF_FFFF,
        0x100_0000,
        0x7FFF_FFFF,
        0x8000_0000,
        0xFFFF_FFFF,
        2500,
    ];
    let mut next = || xorshift(r);
    if (i as usize) < EDGES.len() * 4 {
        let lo = EDGES[i as usize / 4];
        let rho = [0, -(20 << 20), i32::MIN, i32::MAX][i as usize % 4];
        return (
            lo,
            i.is_multiple_of(3),
            rho,
            11_836_024 - ((i % 5) << 20) as i32,
        );
    }
    let a = next();
    let b = next();
    let c = next();
    // d² spread over all magnitudes; ρ and the clamp around the values a search uses.
    let lo = a >> (b % 32);
    let rho = (c as i32) >> (a % 8);
    let clamp = ((b as i32) >> 6) - (8 << 20);
    (lo, c.is_multiple_of(5), rho, clamp)
}

/// One pseudo-random [`loc_core::fixed::ColumnJob`] (0 to 8 anchors: 0, no terms, 1 to 11 rows 1 to 5 fine
/// rows apart, some skipped, shifts 0 to 7) and garbage in its sums (the kernel must overwrite
/// them): the column's and every row's offsets stay below `2^16` after the anchor's shift, as
/// the searches guarantee, except in one job in 8 (24-bit offsets anywhere: the kernels must
/// still agree).
fn column_inputs(r: &mut u32, sums: &mut [u32; 11], job: &mut loc_core::fixed::ColumnJob) -> usize {
    use loc_core::fixed::{AnchorTerm, I24};
    let mut next = || xorshift(r);
    let (a, b) = (next(), next());
    let rows = 1 + (a % 11) as usize;
    job.seg_base = loc_core::fixed::log2_segment_base();
    job.stride = 1 + ((b >> 8) % 5) as u8;
    let span = (rows - 1) as u32 * job.stride as u32;
    let n = (b % 9) as u8;
    job.bound = match a % 4 {
        0 => u32::MAX,
        1 => next(),
        _ => next() >> (b % 24),
    };
    job.n = n;
    job.rows = rows as u8;
    let x = next();
    job.col = (x % 51) as u8;
    job.xstep = (x >> 8) as u16 % (6_000 << (x % 4));
    let dx_col = job.col as i32 * job.xstep as i32;
    let wild = (b >> 16).is_multiple_of(8);
    // One row step for every anchor: within what the tightest (shift 0) can take.
    job.ystep = (1 + next() % (2 * 65_534 / span.max(1))).min(65_535) as u16;
    for t in job.anchors[..n as usize].iter_mut() {
        let (c, d, e) = (next(), next(), next());
        let shift = if c.is_multiple_of(3) {
            0
        } else {
            ((c >> 8) % 8) as u8
        };
        // Offsets within ±lim round below 2^16.
        let lim = 65_534u32 << shift;
        let dx = (e % (2 * lim + 1)) as i32 - lim as i32;
        let step = job.ystep as u32;
        // Row 0 anywhere such that the last row is still within ±lim.
        let room = 2 * lim - step * span;
        *t = AnchorTerm {
            dx2: d,
            dx0: I24::new(if wild { e as i32 } else { dx - dx_col }),
            dy0: I24::new(if wild {
                d as i32
            } else {
                -(lim as i32) + (d % (room + 1)) as i32
            }),
            lclamp: 11_836_024 - ((c % 5) << 20) as i32,
            rho: (e as i32) >> (c % 8),
            w: 1 + (d % 4) as u8,
            shift,
        };
    }
    let x = next();
    job.skip = match x % 4 {
        0 => x as u16,
        1 => (x >> 16) as u16 & (x as u16),
        _ => 0,
    };
    for v in sums.iter_mut() {
        *v = next();
    }
    rows
}

/// `portable_column` over the portable term, out of line.
#[inline(never)]
fn reference_column(sums: &mut [u32], job: &mut loc_core::fixed::ColumnJob) {
    loc_core::fixed::portable_column::<loc_core::fixed::Portable>(sums, job)
}

/// Whole columns: the assembly loop against the portable one over the portable term; returns
/// (mismatches, columns checked). Out of line, with two jobs, to keep the stack small.
#[inline(never)]
fn column_check(serial: &mut Serial, r: &mut u32) -> (u32, u32) {
    use loc_core::fixed::{ColumnJob, TermKernel};
    let (mut bad, cols) = (0u32, black_box(5_000u32));
    let mut sums = [0u32; 11];
    let mut jw = ColumnJob::EMPTY;
    let mut jg = ColumnJob::EMPTY;
    for _ in 0..cols {
        let rows = column_inputs(r, &mut sums, &mut jw);
        jg.clone_from(&jw);
        // Different garbage in each: a row left unwritten cannot match.
        let (mut want, mut got) = (sums, sums.map(|v| !v));
        reference_column(black_box(&mut want[..rows]), &mut jw);
        uno_board::AvrTerm::column(black_box(&mut got[..rows]), &mut jg);
        let n = jw.n as usize;
        let dx_ok = jw.anchors[..n]
            .iter()
            .zip(&jg.anchors[..n])
            .all(|(w, g)| w.dx2 == g.dx2);
        let min_ok = (jw.min, jw.min_row, jw.skip) == (jg.min, jg.min_row, jg.skip);
        if want[..rows] != got[..rows] || !dx_ok || !min_ok {
            bad += 1;
            if bad <= 5 {
                serial.write_bytes(b"badcol");
                for v in [rows as u32, n as u32, jw.bound] {
                    serial.write_byte(b' ');
                    write_u32(serial, v);
                }
                for (w, g) in want[..rows].iter().zip(&got[..rows]) {
                    serial.write_byte(b' ');
                    write_u32(serial, *w);
                    serial.write_byte(b'/');
                    write_u32(serial, *g);
                }
                serial.write_byte(b'\n');
            }
        }
    }
    (bad, cols)
}

/// One pseudo-random posterior column: weights as a search sets them up (σ = 0's span of 1, a
/// flat cost's unbounded span with `b = 0`, or any span with `ra` the fewest bits that bring it
/// below 2^16, sometimes more up to 16, and `b` anywhere, so that `y` covers every shift, the
/// cut-off at 27 and the wrap of `a·b`), a reference and sums so far anywhere, a column offset
/// (0 to 10, one in 8 any byte) and 0 to 11 costs: at the reference or a little above it (within
/// or beyond the span), below it (a new reference, weighing 1 to nothing), `u32::MAX` (a
/// skipped row) or anything.
fn posterior_inputs(r: &mut u32, sums: &mut [u32; 11]) -> (usize, u8, loc_core::fixed::Posterior) {
    use loc_core::fixed::{Posterior, Weights};
    let mut next = || xorshift(r);
    let (a, b, c) = (next(), next(), next());
    let rows = (a % 12) as usize;
    let wts = match b % 8 {
        0 => Weights {
            span: 1,
            b: 0,
            ra: 16,
        },
        1 => Weights {
            span: u32::MAX,
            b: 0,
            ra: 16,
        },
        _ => {
            let span = (next() >> ((b >> 8) % 32)).max(1);
            let mut ra = 0u32;
            while span >> ra > 0xFFFF {
                ra += 1;
            }
            if (b >> 16).is_multiple_of(4) {
                ra += (b >> 20) % (17 - ra);
            }
            Weights {
                span,
                b: next() >> (c % 32),
                ra: ra as u8,
            }
        }
    };
    let mut post = Posterior::new(wts, next() >> ((c >> 8) % 32));
    let col = if (c >> 16).is_multiple_of(8) {
        (c >> 24) as u8
    } else {
        ((c >> 24) % 11) as u8
    };
    post.s = next() >> ((a >> 8) % 32);
    post.sx = next() >> ((a >> 13) % 32);
    post.sy = next() >> ((a >> 18) % 32);
    for v in sums[..rows].iter_mut() {
        let (x, y) = (next(), next());
        // Excesses (and drops) around the span, on a scale of 2^0 to 2^31.
        let d = y >> (x % 32);
        *v = match (x >> 8) % 8 {
            0 => post.cref,
            1 | 2 => post.cref.saturating_add(d % post.wts.span.max(1)),
            3 => post.cref.saturating_add(d),
            4 | 5 => post.cref.saturating_sub(d),
            6 => u32::MAX,
            _ => y,
        };
    }
    (rows, col, post)
}

/// Whole posterior columns: the assembly routine against `portable_posterior`; returns
/// (mismatches, columns checked).
#[inline(never)]
fn posterior_check(serial: &mut Serial, r: &mut u32) -> (u32, u32) {
    use loc_core::fixed::TermKernel;
    let (mut bad, cols) = (0u32, black_box(5_000u32));
    let mut sums = [0u32; 11];
    for _ in 0..cols {
        let (rows, col, mut want) = posterior_inputs(r, &mut sums);
        let mut got = want;
        loc_core::fixed::portable_posterior(black_box(&sums[..rows]), col, &mut want);
        uno_board::AvrTerm::posterior(black_box(&sums[..rows]), col, &mut got);
        let w = [want.cref, want.s, want.sx, want.sy];
        let g = [got.cref, got.s, got.sx, got.sy];
        if w != g {
            bad += 1;
            if bad <= 5 {
                serial.write_bytes(b"badpost");
                let p = &want;
                for v in [
                    rows as u32,
                    p.wts.span,
                    p.wts.ra as u32,
                    p.wts.b,
                    col as u32,
                ] {
                    serial.write_byte(b' ');
                    write_u32(serial, v);
                }
                for (w, g) in w.iter().zip(&g) {
                    serial.write_byte(b' ');
                    write_u32(serial, *w);
                    serial.write_byte(b'/');
                    write_u32(serial, *g);
                }
                serial.write_byte(b'\n');
            }
        }
    }
    (bad, cols)
}

/// The posterior weights' setup: the assembly routine against `portable_weights` for `|K|`
/// (Q.26) over all magnitudes (flat ones below 2^10 included) and σ anywhere in `u16` (0 and from
/// 181 dB on, where σ² reaches 2^31, included); returns (mismatches, setups checked).
#[inline(never)]
fn weights_check(serial: &mut Serial, r: &mut u32) -> (u32, u32) {
    use loc_core::fixed::{TermKernel, Weights};
    let (mut bad, n) = (0u32, black_box(5_000u32));
    for _ in 0..n {
        let mut next = || xorshift(r);
        let (a, b) = (next(), next());
        let k26 = b >> (a % 32);
        let sigma = match (a >> 8) % 8 {
            0 => 0,
            1 => (b >> 16) as u16 | 0xB500,
            _ => (b >> 16) as u16 >> ((a >> 12) % 16),
        };
        let want = loc_core::fixed::portable_weights(black_box(k26), sigma);
        let mut got = Weights::ZERO;
        uno_board::AvrTerm::weights(black_box(k26), sigma, &mut got);
        if want != got {
            bad += 1;
            if bad <= 5 {
                let (wra, gra) = (want.ra as u32, got.ra as u32);
                write_line(
                    serial,
                    b"badwts",
                    &[
                        k26,
                        sigma as u32,
                        want.span,
                        got.span,
                        want.b,
                        got.b,
                        wra,
                        gra,
                    ],
                );
            }
        }
    }
    (bad, n)
}

/// The searches' division: the assembly `div_shl` against the portable one for `a` and `1 ≤ b <
/// 2^31` over all magnitudes and `e` from 0 to 80 (the searches use up to 65), saturating
/// results included; returns (mismatches, divisions checked).
#[inline(never)]
fn div_check(serial: &mut Serial, r: &mut u32) -> (u32, u32) {
    use loc_core::fixed::TermKernel;
    let (mut bad, n) = (0u32, black_box(5_000u32));
    for _ in 0..n {
        let mut next = || xorshift(r);
        let (x, y, z) = (next(), next(), next());
        let a = x >> (z % 32);
        let b = ((y >> 1) >> ((z >> 8) % 31)).max(1);
        let e = (z >> 16) % 81;
        let want = loc_core::fixed::div_shl(black_box(a), b, e);
        let got = uno_board::AvrTerm::div_shl(black_box(a), b, e);
        if want != got {
            bad += 1;
            if bad <= 5 {
                write_line(serial, b"baddiv", &[a, b, e, want, got]);
            }
        }
    }
    (bad, n)
}

/// The searches' `mul_hi`: the assembly one against the portable one for `a`, `b` over the
/// whole range and over all magnitudes (both extremes included); returns (mismatches, products
/// checked).
#[inline(never)]
fn mul_check(serial: &mut Serial, r: &mut u32) -> (u32, u32) {
    use loc_core::fixed::TermKernel;
    let (mut bad, n) = (0u32, black_box(5_000u32));
    for i in 0..n {
        let mut next = || xorshift(r);
        let (x, y, z) = (next(), next(), next());
        let (a, b) = match i {
            0 => (u32::MAX, u32::MAX),
            1 => (0, u32::MAX),
            // Half over the whole range (the high sums' carries), half over all magnitudes.
            _ if z & 1 == 0 => (x, y),
            _ => (x >> ((z >> 1) % 32), y >> ((z >> 8) % 32)),
        };
        let want = loc_core::fixed::mul_hi(black_box(a), b);
        let got = uno_board::AvrTerm::mul_hi(black_box(a), b);
        if want != got {
            bad += 1;
            if bad <= 5 {
                write_line(serial, b"badmul", &[a, b, want, got]);
            }
        }
    }
    (bad, n)
}

/// The window moves: the assembly `move_window` against [`loc_core::fixed::portable_move`] on
/// random jobs (garbage in every anchor slot, steps of any size, zero and the extremes among
/// them) and column/row moves over the whole `i8` range (the searches use ±50); compares every
/// anchor's bytes; returns (mismatches, moves checked).
#[inline(never)]
fn move_check(serial: &mut Serial, r: &mut u32) -> (u32, u32) {
    use loc_core::fixed::{ColumnJob, TermKernel, I24};
    let (mut bad, n) = (0u32, black_box(5_000u32));
    let mut jw = ColumnJob::EMPTY;
    let mut jg = ColumnJob::EMPTY;
    for i in 0..n {
        let mut next = || xorshift(r);
        let (x, y) = (next(), next());
        (jw.xstep, jw.ystep) = match i % 8 {
            0 => (0, 0),
            1 => (u16::MAX, u16::MAX),
            2 => (x as u16 % 6_001, y as u16 % 6_001),
            _ => (x as u16, y as u16),
        };
        let (di, dj) = match i % 16 {
            3 => (i8::MIN, i8::MIN),
            4 => (i8::MAX, 0),
            5 => (0, i8::MAX),
            _ => ((x >> 16) as i8, (y >> 16) as i8),
        };
        for t in jw.anchors.iter_mut() {
            t.dx0 = I24::new(next() as i32);
            t.dy0 = I24::new(next() as i32);
            t.rho = next() as i32;
        }
        jg.clone_from(&jw);
        loc_core::fixed::portable_move(black_box(&mut jw), di, dj);
        uno_board::AvrTerm::move_window(black_box(&mut jg), di, dj);
        let ok = jw
            .anchors
            .iter()
            .zip(&jg.anchors)
            .all(|(w, g)| (w.dx0, w.dy0, w.rho, w.dx2) == (g.dx0, g.dy0, g.rho, g.dx2))
            && (jw.xstep, jw.ystep) == (jg.xstep, jg.ystep);
        if !ok {
            bad += 1;
            if bad <= 5 {
                let (w, g) = (&jw.anchors[0], &jg.anchors[0]);
                write_line(
                    serial,
                    b"badmove",
                    &[
                        jw.xstep as u32,
                        jw.ystep as u32,
                        di as u32,
                        dj as u32,
                        w.dx0.get() as u32,
                        g.dx0.get() as u32,
                        w.dy0.get() as u32,
                        g.dy0.get() as u32,
                    ],
                );
            }
        }
    }
    (bad, n)
}

/// The setup's anchor placement: the assembly `place` against
/// [`loc_core::fixed::portable_place`] on 700 random jobs of 8 placements each (garbage in every
/// slot, sides 0 to 65 535 cm, anchors anywhere in `i16`, weights any byte, `ρ` over its whole
/// range `±(2^30 + 2^25)` or from 4 values, ties among them); compares `n` and every slot's
/// fields after each placement; returns (mismatches, placements checked).
#[inline(never)]
fn place_check(serial: &mut Serial, r: &mut u32) -> (u32, u32) {
    use loc_core::fixed::{ColumnJob, Placement, TermKernel, I24};
    let (mut bad, mut n) = (0u32, 0u32);
    let mut jw = ColumnJob::EMPTY;
    let mut jg = ColumnJob::EMPTY;
    for i in 0..black_box(700u32) {
        let mut next = || xorshift(r);
        let (x, y) = (next(), next());
        (jw.xstep, jw.ystep) = match i % 8 {
            0 => (0, 0),
            1 => (u16::MAX, u16::MAX),
            2 | 3 => (300 + x as u16 % 2_700, 300 + y as u16 % 2_700),
            _ => (x as u16, y as u16),
        };
        jw.n = 0;
        for t in jw.anchors.iter_mut() {
            t.dx2 = next();
            t.dx0 = I24::new(next() as i32);
            t.dy0 = I24::new(next() as i32);
            t.lclamp = next() as i32;
            t.rho = next() as i32;
            let v = next();
            (t.w, t.shift) = (v as u8, (v >> 8) as u8);
        }
        jg.clone_from(&jw);
        let few = i % 3 == 0;
        for _ in 0..loc_core::MAX_ANCHORS {
            let (a, b, c) = (next(), next(), next());
            let lim = (1u32 << 30) + (1 << 25);
            let rho = if few {
                ((a % 4) as i32 - 2) << 22
            } else {
                (a % (2 * lim + 1)) as i32 - lim as i32
            };
            let (px, py) = if i % 8 == 1 && c % 4 == 1 {
                // Sides 65 535: M = 41 942 or 41 943, m = 50·M just below and at 65 535·2^5
                // (the shift's boundary).
                let v = 23_592 + (b % 2) as i16;
                (v, v)
            } else if c % 4 == 0 {
                (b as i16, (b >> 16) as i16)
            } else {
                // Around the area (anchors may lie outside it).
                let (w, h) = (jw.xstep as u32 + 1, jw.ystep as u32 + 1);
                ((b % w) as i16 - 300, ((b >> 16) % h) as i16 - 300)
            };
            let p = Placement {
                rho,
                x: px,
                y: py,
                weight: (c >> 8) as u8 % if c % 2 == 0 { 6 } else { 255 },
            };
            loc_core::fixed::portable_place(black_box(&mut jw), &p);
            uno_board::AvrTerm::place(black_box(&mut jg), &p);
            n += 1;
            let same = |w: &loc_core::fixed::AnchorTerm, g: &loc_core::fixed::AnchorTerm| {
                (w.dx2, w.dx0, w.dy0, w.lclamp, w.rho, w.w, w.shift)
                    == (g.dx2, g.dx0, g.dy0, g.lclamp, g.rho, g.w, g.shift)
            };
            let ok = jw.n == jg.n && jw.anchors.iter().zip(&jg.anchors).all(|(w, g)| same(w, g));
            if !ok {
                bad += 1;
                if bad <= 5 {
                    let k = jw
                        .anchors
                        .iter()
                        .zip(&jg.anchors)
                        .position(|(w, g)| !same(w, g));
                    let k = k.unwrap_or(0);
                    let (w, g) = (&jw.anchors[k], &jg.anchors[k]);
                    write_line(
                        serial,
                        b"badplace",
                        &[
                            jg.n as u32,
                            k as u32,
                            w.dx0.get() as u32,
                            g.dx0.get() as u32,
                            w.rho as u32,
                            g.rho as u32,
                            (w.w as u32) << 8 | w.shift as u32,
                            (g.w as u32) << 8 | g.shift as u32,
                        ],
                    );
                }
                // One report per job.
                break;
            }
        }
    }
    (bad, n)
}

/// Compares `uno_board::AvrTerm` with `loc_core::fixed::{portable_term, portable_column,
/// portable_posterior, portable_weights, div_shl, mul_hi}`; see `kernel-check`.
pub fn kernel_check() -> ! {
    use loc_core::fixed::{portable_term, TermKernel};
    let mut serial = start();
    let (mut r, mut bad) = (0x9E37_79B9u32, 0u32);
    let n = black_box(50_000u32);
    for i in 0..n {
        let (lo, carry, rho, clamp) = kernel_inputs(i, &mut r);
        let want = portable_term(black_box(lo), carry, rho, clamp);
        let got = uno_board::AvrTerm::term(black_box(lo), carry, rho, clamp);
        if want != got {
            bad += 1;
            if bad <= 5 {
                write_line(
                    &mut serial,
                    b"bad",
                    &[lo, carry as u32, rho as u32, clamp as u32, want, got],
                );
            }
        }
    }
    serial.write_bytes(b"kernel ");
    write_u32(&mut serial, n);
    serial.write_byte(b' ');
    write_u32(&mut serial, bad);
    serial.write_byte(b'\n');
    let (bad, cols) = column_check(&mut serial, &mut r);
    serial.write_bytes(b"column ");
    write_u32(&mut serial, cols);
    serial.write_byte(b' ');
    write_u32(&mut serial, bad);
    serial.write_byte(b'\n');
    let (bad, cols) = posterior_check(&mut serial, &mut r);
    serial.write_bytes(b"posterior ");
    write_u32(&mut serial, cols);
    serial.write_byte(b' ');
    write_u32(&mut serial, bad);
    serial.write_byte(b'\n');
    let (bad, n) = weights_check(&mut serial, &mut r);
    serial.write_bytes(b"weights ");
    write_u32(&mut serial, n);
    serial.write_byte(b' ');
    write_u32(&mut serial, bad);
    serial.write_byte(b'\n');
    let (bad, n) = div_check(&mut serial, &mut r);
    serial.write_bytes(b"div_shl ");
    write_u32(&mut serial, n);
    serial.write_byte(b' ');
    write_u32(&mut serial, bad);
    serial.write_byte(b'\n');
    let (bad, n) = mul_check(&mut serial, &mut r);
    serial.write_bytes(b"mul_hi ");
    write_u32(&mut serial, n);
    serial.write_byte(b' ');
    write_u32(&mut serial, bad);
    serial.write_byte(b'\n');
    let (bad, n) = move_check(&mut serial, &mut r);
    serial.write_bytes(b"move_window ");
    write_u32(&mut serial, n);
    serial.write_byte(b' ');
    write_u32(&mut serial, bad);
    serial.write_byte(b'\n');
    let (bad, n) = place_check(&mut serial, &mut r);
    serial.write_bytes(b"place ");
    write_u32(&mut serial, n);
    serial.write_byte(b' ');
    write_u32(&mut serial, bad);
    serial.write_byte(b'\n');
    end(&mut serial)
}
