//! search-check: the sink's search with `uno_board::AvrTerm` against the portable one, on the
//! MCU itself. First `AvrTerm::guess` (AVR assembly) against `loc_core::fixed::portable_guess`
//! on 20 000 jobs: half set up as a search sets them up (random observations placed by
//! `portable_place`: sorted keys, real shifts), half garbage (any `n`, keys in any order, any
//! shift byte, any offsets and sides, 0 and the extremes among them); prints `badguess n xstep
//! ystep portable avr` for its first mismatches, then `guess <checked> <mismatches>`. Then `AvrTerm::observe` against
//! `portable_observe` on 10 000 random observation sets (`observe_inputs`); prints `badobserve
//! <i> …` for its first mismatches, then `observe <checked> <mismatches>`. Then
//! `mle_and_mmse_window_into` with `AvrTerm` against the same with `Portable` on 150 random
//! searches (3 to 8 anchors inside and outside the area, rooms of 1 to 65 m and a corner-sized
//! one, flat (α = 0, tiny), negative and thesis-like models, σ = 0, 1, 65 535 and random; every
//! field of both estimates, errors included); prints `badsearch <trial>` for its first
//! mismatches, then `search <checked> <mismatches>`, then `end`. `tests/tests/search_check.rs`
//! runs it in simavr (and `search-check2`, the search driver). Build: `cargo fw-bench`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    use core::hint::black_box;
    use loc_core::fixed::{ColumnJob, Placement, TermKernel, I24};
    use mcu_bench::fw::xorshift;
    let mut serial = mcu_bench::fw::start();
    let mut r = 0x2545_F491u32;
    let line = mcu_bench::fw::write_line;
    // ---- guess ----
    let (mut bad, n) = (0u32, black_box(20_000u32));
    let mut job = ColumnJob::EMPTY;
    for i in 0..n {
        let mut next = || xorshift(&mut r);
        let (x, y) = (next(), next());
        (job.xstep, job.ystep) = match i % 8 {
            0 => (0, 0),
            1 => (u16::MAX, u16::MAX),
            2 => (1 + x as u16 % 300, 1 + y as u16 % 300),
            _ => (100 + x as u16 % 6_400, 100 + y as u16 % 6_400),
        };
        if i % 2 == 0 {
            // As a search sets it up.
            job.n = 0;
            for _ in 0..3 + next() % 6 {
                let (px, py) = (next(), next());
                let p = Placement {
                    rho: match px % 4 {
                        0 => (py as i32 >> 1) - (1 << 30),
                        1 => -(25 << 20) + (py % (8 << 20)) as i32,
                        _ => -(25 << 20) + (py % (40 << 20)) as i32,
                    },
                    x: match px % 5 {
                        0 => (px >> 16) as i16,
                        1 => 0,
                        2 => job.xstep as i16,
                        _ => ((px >> 16) % (job.xstep as u32 + 1)) as i16,
                    },
                    y: match py % 5 {
                        0 => (py >> 16) as i16,
                        1 => 0,
                        2 => job.ystep as i16,
                        _ => ((py >> 16) % (job.ystep as u32 + 1)) as i16,
                    },
                    weight: (px >> 8) as u8 % 5,
                };
                loc_core::fixed::portable_place(&mut job, &p);
            }
        } else {
            job.n = match i % 7 {
                0 => 0,
                1 => 255,
                _ => (x >> 8) as u8 % 10,
            };
            for t in job.anchors.iter_mut() {
                t.dx0 = I24::new(next() as i32);
                t.dy0 = I24::new(next() as i32);
                let k = next();
                // Keys close together (weights from 32 down) or anywhere.
                t.rho = if k % 3 == 0 {
                    k as i32
                } else {
                    (k % (8 << 20)) as i32
                };
                t.shift = (k >> 24) as u8 % if k % 5 == 0 { 255 } else { 8 };
            }
        }
        let want = loc_core::fixed::portable_guess(black_box(&job));
        let got = uno_board::AvrTerm::guess(black_box(&job));
        if want != got {
            bad += 1;
            if bad <= 5 {
                let v = [
                    job.n as u32,
                    job.xstep as u32,
                    job.ystep as u32,
                    (want.0 as u32) << 8 | want.1 as u32,
                    (got.0 as u32) << 8 | got.1 as u32,
                ];
                line(&mut serial, b"badguess", &v);
            }
        }
    }
    line(&mut serial, b"guess", &[n, bad]);
    // ---- observe ----
    let (mut bad, n) = (0u32, black_box(10_000u32));
    for i in 0..n {
        let (mut want_job, mut want_s, all, len) = observe_inputs(i, &mut r);
        let obs = &all[..len as usize];
        let (mut got_job, mut got_s) = (want_job, want_s);
        loc_core::fixed::portable_observe::<loc_core::fixed::Portable>(
            &mut want_job,
            &mut want_s,
            black_box(obs),
        );
        uno_board::AvrTerm::observe(&mut got_job, &mut got_s, black_box(obs));
        let same_anchors = want_job.anchors.iter().zip(&got_job.anchors).all(|(a, b)| {
            (a.dx0, a.dy0, a.lclamp, a.rho, a.w, a.shift)
                == (b.dx0, b.dy0, b.lclamp, b.rho, b.w, b.shift)
        });
        if want_s != got_s || want_job.n != got_job.n || !same_anchors {
            bad += 1;
            if bad <= 5 {
                let v = [
                    i,
                    want_s.flat_cost,
                    got_s.flat_cost,
                    want_job.anchors[0].rho as u32,
                    got_job.anchors[0].rho as u32,
                ];
                line(&mut serial, b"badobserve", &v);
            }
        }
    }
    line(&mut serial, b"observe", &[n, bad]);
    // ---- the sink's whole search ----
    let (mut bad, n) = (0u32, black_box(150u32));
    for t in 0..n {
        let search = search_inputs(t, &mut r);
        let (obs, model, area, sigma) = black_box(search);
        let mut want = [loc_core::fixed::Estimate::NONE; 2];
        let mut got = want;
        let w = loc_core::fixed::mle_and_mmse_window_into::<loc_core::fixed::Portable>(
            &obs, model, area, sigma, &mut want,
        );
        let g = loc_core::fixed::mle_and_mmse_window_into::<uno_board::AvrTerm>(
            &obs, model, area, sigma, &mut got,
        );
        if w != g || want != got {
            bad += 1;
            if bad <= 5 {
                line(&mut serial, b"badsearch", &[t]);
            }
        }
    }
    line(&mut serial, b"search", &[n, bad]);
    mcu_bench::fw::end(&mut serial)
}

/// Observation job `i`'s inputs: a job with `xstep`, `ystep` of any size and 0 to 5 anchors
/// already in it (garbage: `observe` starts from `n = 0`), a [`loc_core::fixed::Setup`] with
/// any `P0` and α (0, tiny, negative, as a search has it, the extremes among them), garbage in
/// its outputs, sums near saturation or wrapping, and 1 to 8 observations with any `z` (near
/// `P0` or anywhere), position and weight byte.
#[cfg(target_arch = "avr")]
#[inline(never)]
fn observe_inputs(
    i: u32,
    r: &mut u32,
) -> (
    loc_core::fixed::ColumnJob,
    loc_core::fixed::Setup,
    [loc_core::fixed::Obs; loc_core::MAX_ANCHORS],
    u8,
) {
    use loc_core::fixed::{ColumnJob, Obs, Placement, PointCm, Setup};
    use mcu_bench::fw::xorshift;
    let mut next = || xorshift(r);
    let mut job = ColumnJob::EMPTY;
    (job.xstep, job.ystep) = (1 + next() as u16 % 6_500, next() as u16);
    let pre = next() % 6;
    for _ in 0..pre {
        let (a, b) = (next(), next());
        let p = Placement {
            rho: a as i32 >> (b % 8),
            x: b as i16,
            y: (b >> 16) as i16,
            weight: a as u8,
        };
        loc_core::fixed::portable_place(&mut job, &p);
    }
    let (a, b, c) = (next(), next(), next());
    let s = Setup {
        p0: match i % 5 {
            0 => i32::MIN,
            1 => i32::MAX,
            2 => a as i32,
            _ => -((a % (90 << 16)) as i32),
        },
        alpha: match i % 7 {
            0 => 0,
            1 => i32::MIN,
            2 => (b % 1_000) as i32 - 500,
            3 => b as i32,
            4 => -2 * loc_core::fixed::ALPHA,
            _ => loc_core::fixed::ALPHA + (b % (4 * loc_core::fixed::ALPHA as u32)) as i32,
        },
        k26: a,
        flat_cost: if c & 2 == 0 { c } else { u32::MAX - (c >> 20) },
        anchors: (c >> 8) as u8,
        weight: (c >> 16) as u8,
    };
    let mut obs = [Obs::default(); loc_core::MAX_ANCHORS];
    let len = 1 + next() % 8;
    for o in &mut obs[..len as usize] {
        let (x, y) = (next(), next());
        *o = Obs {
            pos: PointCm::new(x as i16, (x >> 16) as i16),
            z: if y % 3 == 0 {
                y as i32
            } else {
                s.p0.wrapping_add((y >> 4) as i32 >> (y % 16))
            },
            weight: (y >> 8) as u8,
        };
    }
    (job, s, obs, len as u8)
}

#[cfg(target_arch = "avr")]
#[path = "common/search_inputs.rs"]
mod search_inputs;
#[cfg(target_arch = "avr")]
use search_inputs::search_inputs;
