//! fit-check2: `uno_board::AvrFit`'s whole online round (`FitKernel::step`: current model, solve,
//! both AR(1) smoothers fed, σ, new model; one AVR routine) against `loc_core::fixed`'s
//! `portable_step` on the MCU itself, through `OnlineParams::step_with` on equal copies:
//! pseudo-random smoothers (weights up to ±4, so outputs run beyond the limits and saturate),
//! priors (anywhere, the limits), bounds, all three modes, sums (empty, one sample, rooms,
//! extreme bytes and x: σ saturating at 0xFFFF), several rounds per state. Prints the first
//! mismatches (`badstep round mode`), then `step <rounds> <mismatches> <no fit> <σ saturated>
//! <α fed> <clamped>` and `end`; before that the AR(1) step alone (`FitKernel::ar1_update`):
//! `weigh <checked> <mismatches>` after its first mismatches (`badweigh a b first x portable
//! avr`). `tests/tests/fit_check2.rs` runs it in simavr. Build:
//! `cargo fw-bench`.
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
        portable_ar1_update, Ar1, Bounds, CalStats, FitJob, FitKernel, FitMethod, OnlineParams,
        ParamMode, PathLoss, PortableFit, ALPHA, ALPHA_LIMIT, DB, P0_LIMIT,
    };
    use mcu_bench::fw::write_line;
    use mcu_bench::rng::Rng;
    use uno_board::AvrFit;

    /// Smoother states drawn (1 to 6 rounds each): over 10 000 rounds.
    const STATES: u32 = 2_900;

    /// Random sums: none, one sample, or pushes at room-like, nearly equal or extreme x with
    /// plausible or extreme bytes.
    fn stats(r: &mut Rng) -> CalStats {
        let mut s = CalStats::new();
        let mut bytes = [None; 16];
        let pushes = match r.below(8) {
            0 => 0,
            1 => 1,
            2 => r.range(20, 40),
            _ => r.range(1, 10),
        };
        let x0 = r.range(-30 << 18, 20 << 18);
        let base = r.range(30, 90) as u8;
        for _ in 0..pushes {
            let len = r.range(1, 16) as usize;
            for b in bytes[..len].iter_mut() {
                *b = match r.below(8) {
                    0 => None,
                    1 => Some(r.pick(&[0, 255, 1, 254])),
                    _ => Some(base.wrapping_add(r.below(9) as u8)),
                };
            }
            let x = match r.below(4) {
                0 => x0.wrapping_add(r.range(-40, 40)),
                1 => r.pick(&[-(32 << 18), 32 << 18, 0, 1, -1]),
                _ => r.range(-(30 << 18), 30 << 18),
            };
            s.push_at(x, &bytes[..len]);
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
            p0: around(r, -90 * DB, -10 * DB, P0_LIMIT),
            alpha: around(r, ALPHA, 6 * ALPHA, ALPHA_LIMIT),
        }
    }

    fn bounds(r: &mut Rng) -> Bounds {
        match r.below(4) {
            0 | 1 => Bounds::THESIS,
            2 => {
                let (a, p) = (model(r), model(r));
                Bounds {
                    alpha_min: a.alpha,
                    alpha_max: p.alpha,
                    p0_min: a.p0,
                    p0_max: p.p0,
                }
            }
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

    /// A smoother with the weights `Ar1::new` allows (±4 in Q.16), mostly the thesis'.
    fn ar1(r: &mut Rng) -> Ar1 {
        let mut w = || match r.below(4) {
            0 => r.pick(&[-(4 << 16), 4 << 16, 0, 1, -1, 1 << 16]),
            1 => r.range(-(5 << 16), 5 << 16),
            _ => r.pick(&[52_429, 13_107]),
        };
        Ar1::new(w(), w())
    }

    pub fn run() -> ! {
        let mut serial = mcu_bench::fw::start();
        let mut r = Rng(0x1F2E_3D4C);
        let (mut rounds, mut bad) = (0u32, 0u32);
        let mut counts = [0u32; 4];
        for _ in 0..black_box(STATES) {
            let mode = match r.below(6) {
                0 => ParamMode::Fixed,
                1 => ParamMode::P0Only,
                _ => ParamMode::P0AndAlpha,
            };
            let (prior, b) = (model(&mut r), bounds(&mut r));
            let (p, a) = (ar1(&mut r), ar1(&mut r));
            let mut want =
                OnlineParams::with_smoothers(mode, FitMethod::LeastSquares, b, prior, p, a);
            let mut got = want;
            for round in 0..r.range(1, 6) {
                let s = stats(&mut r);
                let mut wj = FitJob::for_step(&s, mode, &b);
                let mut gj = wj;
                // Different garbage in the outputs: a field left unwritten cannot match (`sse`
                // is one only when there is a fit).
                (gj.p0, gj.alpha) = (!wj.p0, !wj.alpha);
                if mode == ParamMode::Fixed || !s.is_empty() {
                    gj.sse = !wj.sse;
                }
                let wf = want.step_with::<PortableFit>(black_box(&mut wj));
                let gf = got.step_with::<AvrFit>(black_box(&mut gj));
                rounds += 1;
                let w = (wf, wj.p0, wj.alpha, wj.sse, wj.fitted);
                if w != (gf, gj.p0, gj.alpha, gj.sse, gj.fitted) || want != got {
                    bad += 1;
                    if bad <= 5 {
                        write_line(&mut serial, b"badstep", &[round as u32, mode as u32]);
                    }
                    // Go on from equal states.
                    got = want;
                }
                counts[0] += !wf as u32;
                counts[1] += (want.sigma() == Some(u16::MAX)) as u32;
                counts[2] += (wf && mode == ParamMode::P0AndAlpha) as u32;
                counts[3] += (wj.p0.abs() == P0_LIMIT || wj.alpha.abs() == ALPHA_LIMIT) as u32;
            }
        }
        // The AR(1) step on a fresh or a started smoother, with the weights `Ar1::new` allows
        // (±4 in Q.16) and any values.
        let (mut wbad, wn) = (0u32, black_box(20_000u32));
        for _ in 0..wn {
            let mut w = || match r.below(4) {
                0 => r.pick(&[-(4 << 16), 4 << 16, 0, 1, -1, 1 << 16, 52_429, 13_107]),
                _ => r.range(-(5 << 16), 5 << 16),
            };
            let mut want = Ar1::new(w(), w());
            let mut v = || match r.below(4) {
                0 => r.pick(&[i32::MIN, i32::MAX, 0, -1, 1, -(90 << 16), 3 << 24]),
                1 => r.bits() as i32,
                _ => r.range(-(100 << 16), 6 << 24),
            };
            let (first, x) = (v(), v());
            if r.below(8) != 0 {
                portable_ar1_update(&mut want, first);
            }
            let mut got = want;
            let y = portable_ar1_update(black_box(&mut want), x);
            if AvrFit::ar1_update(black_box(&mut got), x) != y || got != want {
                wbad += 1;
                if wbad <= 5 {
                    write_line(
                        &mut serial,
                        b"badweigh",
                        &[
                            want.a as u32,
                            want.b as u32,
                            first as u32,
                            x as u32,
                            y as u32,
                            got.value().unwrap_or(0) as u32,
                        ],
                    );
                }
            }
        }
        write_line(&mut serial, b"weigh", &[wn, wbad]);
        write_line(
            &mut serial,
            b"step",
            &[rounds, bad, counts[0], counts[1], counts[2], counts[3]],
        );
        mcu_bench::fw::end(&mut serial)
    }
}
