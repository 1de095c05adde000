//! fit-check: `uno_board::AvrFit` (the sink's least-squares P0/α solve in AVR assembly) against
//! `loc_core::fixed::PortableFit` on the MCU itself: pseudo-random calibration sums (rooms,
//! near-equal distances, Σx² = 0, extreme x and bytes, 256 samples), modes, priors and bounds
//! (the thesis', narrow ones that put the optimum outside, reversed, beyond the limits,
//! everything). Prints
//! the first mismatches (`bad mode n p0 alpha sse_hi sse_lo fitted`, the twin's then the
//! assembly's), then `fit <jobs> <mismatches> <fitted 0> <fitted 1> <fitted 2> <on an edge>`
//! and `end`; before that a pair's samples into the sums (`FitKernel::push`): `push <checked> <mismatches> <cut
//! short by the 256-sample limit>` after `badpush x n_portable n_avr k`, and before that the
//! anchor-pair distance (`FitKernel::distance_x`): `dist <checked> <mismatches> <coincident>`
//! after `baddist ax ay bx by`.
//! `tests/tests/fit_check.rs` runs it in simavr. Build: `cargo fw-bench`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    avr::run()
}

#[cfg(target_arch = "avr")]
mod avr {
    use core::hint::black_box;
    use loc_core::fixed::{
        distance_x, portable_push, Bounds, CalStats, FitJob, FitKernel, ParamMode, PathLoss,
        PointCm, PortableFit, ALPHA, DB,
    };
    use mcu_bench::fw::{write_line, write_u32};
    use mcu_bench::rng::Rng;
    use uno_board::AvrFit;

    /// Sums drawn, four jobs each (those with no samples and something to fit are skipped:
    /// `FitJob::new` refuses them): over 10 000 jobs.
    const SUMS: u32 = 2_600;

    /// [`CalStats::push_pair`] as a firmware with one copy of the sums' code has it.
    fn push_pair(s: &mut CalStats, a: PointCm, c: PointCm, b: &[Option<u8>]) {
        if let Some(x) = distance_x(a, c) {
            s.push_at(x, b);
        }
    }

    /// Random sums: a room's anchor pairs, or pushes at random (sometimes extreme, sometimes
    /// nearly equal, sometimes zero) x.
    fn stats(r: &mut Rng) -> CalStats {
        let mut s = CalStats::new();
        let mut bytes = [None; 16];
        let style = r.below(8);
        let pushes = match r.below(6) {
            0 => r.range(1, 2),
            1 => r.range(20, 60),
            _ => r.range(1, 12),
        };
        let x0 = r.range(-30 << 18, 20 << 18);
        for _ in 0..pushes {
            let len = r.range(1, 16) as usize;
            let base = r.range(30, 90) as u8;
            for b in bytes[..len].iter_mut() {
                *b = match r.below(8) {
                    0 => None,
                    1 => Some(r.pick(&[0, 255, 1, 254])),
                    2 => Some(r.bits() as u8),
                    _ => Some(base.wrapping_add(r.below(9) as u8)),
                };
            }
            let b = &bytes[..len];
            match style {
                // Anchors in a room.
                0..=2 => {
                    let p = |r: &mut Rng| {
                        PointCm::new(r.range(0, 2000) as i16, r.range(0, 2000) as i16)
                    };
                    let (a, c) = (p(r), p(r));
                    push_pair(&mut s, a, c, b);
                }
                // Nearly equal distances: α barely identifiable.
                3 => {
                    s.push_at(x0.wrapping_add(r.range(-40, 40)), b);
                }
                // All at x = 0 (Σx² = 0) or one x.
                4 => {
                    s.push_at(if x0 & 1 == 0 { 0 } else { x0 }, b);
                }
                // The extremes.
                5 => {
                    let x = r.pick(&[-(32 << 18), 32 << 18, i32::MIN, i32::MAX, 0, 1, -1]);
                    s.push_at(x, &[Some(r.pick(&[0, 255])); 16][..len]);
                }
                _ => {
                    let p = |r: &mut Rng| PointCm::new(r.bits() as i16, r.bits() as i16);
                    let (a, c) = (p(r), p(r));
                    if r.below(2) == 0 {
                        push_pair(&mut s, a, c, b);
                    } else {
                        s.push_at(r.range(-(33 << 18), 33 << 18), b);
                    }
                }
            }
        }
        s
    }

    /// Mostly plausible, sometimes anything, sometimes an edge.
    fn around(r: &mut Rng, lo: i32, hi: i32, limit: i32) -> i32 {
        match r.below(8) {
            0 => r.bits() as i32,
            1 => r.pick(&[i32::MIN, i32::MAX, 0, -1, 1, -limit, limit]),
            2 => r.range(-limit - 2, limit + 2),
            _ => r.range(lo, hi),
        }
    }

    fn model(r: &mut Rng) -> PathLoss {
        PathLoss {
            p0: around(r, -90 * DB, -10 * DB, 512 * DB),
            alpha: around(r, ALPHA, 6 * ALPHA, 32 * ALPHA),
        }
    }

    fn bounds(r: &mut Rng) -> Bounds {
        match r.below(5) {
            0 => Bounds::THESIS,
            // Everything (clamped to the limits): the optimum is inside.
            4 => Bounds {
                alpha_min: i32::MIN,
                alpha_max: i32::MAX,
                p0_min: i32::MIN,
                p0_max: i32::MAX,
            },
            1 => {
                let (a, p) = (model(r), model(r));
                Bounds {
                    alpha_min: a.alpha,
                    alpha_max: p.alpha,
                    p0_min: a.p0,
                    p0_max: p.p0,
                }
            }
            // Narrow: the optimum is often outside.
            _ => {
                let a = r.range(0, 8 * ALPHA);
                let p = r.range(-100 * DB, 0);
                Bounds {
                    alpha_min: a,
                    alpha_max: a + r.range(0, 2 * ALPHA),
                    p0_min: p,
                    p0_max: p + r.range(0, 10 * DB),
                }
            }
        }
    }

    pub fn run() -> ! {
        let mut serial = mcu_bench::fw::start();
        let mut r = Rng(0x2545_F491);
        let (mut jobs, mut bad) = (0u32, 0u32);
        let mut counts = [0u32; 4];
        for _ in 0..black_box(SUMS) {
            let s = stats(&mut r);
            for _ in 0..4 {
                let mode = match r.below(8) {
                    0 => ParamMode::Fixed,
                    1 => ParamMode::P0Only,
                    _ => ParamMode::P0AndAlpha,
                };
                let (prior, b) = (model(&mut r), bounds(&mut r));
                let Some(mut want) = FitJob::new(&s, mode, prior, &b) else {
                    continue;
                };
                let mut got = want;
                // Different garbage in the outputs: a field left unwritten cannot match.
                got.sse = !want.sse;
                PortableFit::fit(black_box(&mut want));
                AvrFit::fit(black_box(&mut got));
                jobs += 1;
                let w = (want.p0, want.alpha, want.sse, want.fitted);
                if w != (got.p0, got.alpha, got.sse, got.fitted) {
                    bad += 1;
                    if bad <= 5 {
                        serial.write_bytes(b"bad");
                        for j in [&want, &got] {
                            for v in [
                                j.p0 as u32,
                                j.alpha as u32,
                                (j.sse >> 32) as u32,
                                j.sse as u32,
                                j.fitted as u32,
                            ] {
                                serial.write_byte(b' ');
                                write_u32(&mut serial, v);
                            }
                        }
                        serial.write_byte(b'\n');
                    }
                }
                counts[want.fitted as usize & 3] += 1;
                if want.fitted == 2
                    && (want.alpha == want.a_lo
                        || want.alpha == want.a_hi
                        || want.p0 == want.p_lo
                        || want.p0 == want.p_hi)
                {
                    counts[3] += 1;
                }
            }
        }
        // The anchor-pair distance (`FitKernel::distance_x`): coincident, 1 cm, the i16 extremes,
        // small and room-sized offsets, anything.
        let (mut dbad, dn, mut dnone) = (0u32, black_box(20_000u32), 0u32);
        for _ in 0..dn {
            let c = |r: &mut Rng| match r.below(5) {
                0 => r.pick(&[i16::MIN, i16::MAX, 0, -1, 1, i16::MIN + 1, i16::MAX - 1]),
                1 => r.bits() as i16,
                _ => r.range(-300, 2300) as i16,
            };
            let a = PointCm::new(c(&mut r), c(&mut r));
            let b = match r.below(6) {
                0 => a,
                1 => PointCm::new(
                    a.x.wrapping_add(r.range(-2, 2) as i16),
                    a.y.wrapping_add(r.range(-2, 2) as i16),
                ),
                _ => PointCm::new(c(&mut r), c(&mut r)),
            };
            let want = distance_x(black_box(a), b);
            dnone += want.is_none() as u32;
            if AvrFit::distance_x(black_box(a), b) != want {
                dbad += 1;
                if dbad <= 5 {
                    write_line(
                        &mut serial,
                        b"baddist",
                        &[a.x as u32, a.y as u32, b.x as u32, b.y as u32],
                    );
                }
            }
        }
        write_line(&mut serial, b"dist", &[dn, dbad, dnone]);
        // A pair's samples into the sums (`FitKernel::push`): random sums (some full or nearly),
        // x from ±2^23 (extremes, 0, ±1, a room's pairs, anything), bytes 0 (not heard) or not.
        let (mut pbad, pn, mut plimited) = (0u32, black_box(6_000u32), 0u32);
        for _ in 0..pn {
            let mut want = stats(&mut r);
            if r.below(4) == 0 {
                // Up to 10 short of full.
                let fill = [Some(r.pick(&[0u8, 255, 77])); 64];
                let mut more = 256 - r.range(0, 10) as usize - want.len().min(246);
                while more > 0 {
                    let m = more.min(64);
                    want.push_at(r.range(-(20 << 18), 20 << 18), &fill[..m]);
                    more -= m;
                }
            }
            const X: i32 = 1 << 23;
            let x = match r.below(6) {
                0 => r.pick(&[-X, X, X - 1, -X + 1, 0, 1, -1, 255, -256, 65_535, -65_536]),
                1 => r.range(-X, X),
                2 => {
                    let p = |r: &mut Rng| PointCm::new(r.bits() as i16, r.bits() as i16);
                    distance_x(p(&mut r), p(&mut r)).unwrap_or(0)
                }
                _ => r.range(-(30 << 18), 20 << 18),
            };
            let mut bytes = [0u8; 8];
            for b in bytes.iter_mut() {
                *b = match r.below(6) {
                    0 | 1 => 0,
                    2 => r.pick(&[1, 255, 254, 128]),
                    _ => r.bits() as u8,
                };
            }
            let heard = bytes.iter().filter(|&&b| b != 0).count() as u8;
            let mut got = want;
            let k = portable_push(black_box(&mut want), x, &bytes);
            if k < heard {
                plimited += 1;
            }
            if AvrFit::push(black_box(&mut got), x, &bytes) != k || got != want {
                pbad += 1;
                if pbad <= 5 {
                    write_line(
                        &mut serial,
                        b"badpush",
                        &[x as u32, want.len() as u32, got.len() as u32, k as u32],
                    );
                }
            }
        }
        write_line(&mut serial, b"push", &[pn, pbad, plimited]);
        write_line(
            &mut serial,
            b"fit",
            &[jobs, bad, counts[0], counts[1], counts[2], counts[3]],
        );
        mcu_bench::fw::end(&mut serial)
    }
}
