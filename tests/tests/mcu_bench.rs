//! The MCU estimate benchmark's firmwares compute the right thing (not how fast: that is
//! `cargo bench -p hoploc --bench mcu_estimate`): `est-fixed` and `est-portable` in simavr print
//! exactly what `loc_core::fixed` computes on the host for the same inputs, `est-f32` what the same
//! f32 code computes on the host and a position within one fine lattice step (20 cm) of the fixed
//! path's, and `est-none` runs the same markers; and on the host, the f32 port and the fixed path
//! against loc-core's f64 reference (thesis MLE, windowed MMSE).

use std::sync::OnceLock;

use mcu_bench::harness::{self, Fix, Run};
use mcu_bench::{Inputs, MARKS, N_ANCHORS, N_CHANNELS};

/// `cargo fw-bench`, once per test process (a no-op when the ELFs are current).
static BUILD: OnceLock<Result<(), String>> = OnceLock::new();

/// One fine lattice step of the 10 m room, mm.
const FINE_STEP_MM: f64 = 200.0;

fn run(bin: &str) -> Run {
    if let Err(e) = BUILD.get_or_init(harness::build) {
        panic!("bench firmware: {e}");
    }
    harness::run_elf(&harness::elf(bin)).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn fixed_firmware_equals_host_fixed() {
    let fw = run("est-fixed");
    let host = harness::host_fixed(&Inputs::BENCH);
    assert_eq!(
        fw.reports, host,
        "est-fixed [MLE, MMSE] vs host loc_core::fixed"
    );
    let mle = Fix::of_fixed(&host[0]);
    // Sanity of the inputs: a fit inside the thesis' bounds and a fix inside the room.
    assert!(
        (2.0..=5.0).contains(&mle.alpha) && (-60.0..=-20.0).contains(&mle.p0),
        "{mle:?}"
    );
    assert!(mle.x_mm <= 10_000.0 && mle.y_mm <= 10_000.0, "{mle:?}");
}

/// `est-portable` (the same sequence with the portable column on the MCU) prints exactly what
/// est-fixed and the host print: the kernel changes the cycles, not the results.
#[test]
fn portable_column_firmware_equals_host_fixed() {
    let fw = run("est-portable");
    assert_eq!(fw.reports, harness::host_fixed(&Inputs::BENCH));
}

#[test]
fn f32_firmware_matches_host_f32_and_fixed() {
    let fw = run("est-f32");
    let host = harness::host_f32(&Inputs::BENCH);
    let fixed = harness::host_fixed(&Inputs::BENCH);
    for (k, name) in ["MLE", "MMSE"].iter().enumerate() {
        let (a, h) = (Fix::of_f32(&fw.reports[k]), Fix::of_f32(&host[k]));
        // avr-libc's and std's log10/exp differ in the last bits only.
        assert!(a.dist_mm(&h) < 1.0, "{name}: AVR {a:?} vs host {h:?}");
        assert!(
            (a.p0 - h.p0).abs() < 1e-3 && (a.alpha - h.alpha).abs() < 1e-4,
            "{name}: {a:?} vs {h:?}"
        );
        let f = Fix::of_fixed(&fixed[k]);
        assert!(
            a.dist_mm(&f) <= FINE_STEP_MM,
            "{name}: f32 {a:?} vs fixed {f:?}"
        );
        assert!(
            (a.p0 - f.p0).abs() < 1e-3 && (a.alpha - f.alpha).abs() < 1e-4,
            "{name}: f32 {a:?} vs fixed {f:?}"
        );
    }
    // The MLE is a lattice point: the same one.
    let (a, f) = (Fix::of_f32(&fw.reports[0]), Fix::of_fixed(&fixed[0]));
    assert!(a.dist_mm(&f) < 1.0, "MLE: f32 {a:?} vs fixed {f:?}");
}

#[test]
fn f32_port_matches_the_f64_reference() {
    let f32s = harness::host_f32(&Inputs::BENCH);
    let f64s = harness::host_f64(&Inputs::BENCH);
    for k in 0..2 {
        let (a, r) = (Fix::of_f32(&f32s[k]), f64s[k]);
        assert!(a.dist_mm(&r) < 1.0, "{k}: f32 {a:?} vs f64 {r:?}");
        assert!(
            (a.p0 - r.p0).abs() < 1e-3 && (a.alpha - r.alpha).abs() < 1e-4,
            "{k}: {a:?} vs {r:?}"
        );
    }
}

/// Small deterministic generator (xorshift64 + Box–Muller).
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let u = self.uniform().max(1e-300);
        let v = self.uniform();
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// Random benchmark inputs: a 3–30 m × 3–30 m room, the four anchors anywhere in it, the agent
/// anywhere, P0 ∈ [−50, −30] dBm, α ∈ [2, 4.5], shadowing σ ∈ [0, 6] dB on every byte.
fn random_inputs(rng: &mut Rng) -> Inputs {
    let side = |rng: &mut Rng| 300 + (rng.uniform() * 2700.0) as u16;
    let (w, h) = (side(rng), side(rng));
    let (p0, alpha, sigma) = (
        -50.0 + 20.0 * rng.uniform(),
        2.0 + 2.5 * rng.uniform(),
        6.0 * rng.uniform(),
    );
    let mut inp = Inputs::BENCH;
    inp.area = [w, h];
    for a in inp.anchors.iter_mut() {
        *a = [
            (rng.uniform() * w as f64) as i16,
            (rng.uniform() * h as f64) as i16,
        ];
    }
    let agent = [rng.uniform() * w as f64, rng.uniform() * h as f64];
    let dist = |p: [f64; 2], q: [i16; 2]| {
        ((p[0] - q[0] as f64) / 100.0)
            .hypot((p[1] - q[1] as f64) / 100.0)
            .max(0.01)
    };
    let byte = |d: f64, rng: &mut Rng| {
        let dbm = p0 - 10.0 * alpha * d.log10() + sigma * rng.normal();
        (-dbm).round().clamp(0.0, 250.0) as u8
    };
    for a in 0..N_ANCHORS {
        for c in 0..N_CHANNELS {
            inp.agent[a][c] = byte(dist(agent, inp.anchors[a]), rng);
        }
        for b in 0..N_ANCHORS {
            if a != b {
                let q = inp.anchors[b];
                inp.a2a[a][b] = byte(dist([q[0] as f64, q[1] as f64], inp.anchors[a]), rng);
            }
        }
    }
    inp
}

/// Beyond the one benchmark input: the f32 port's and the fixed path's windowed MMSE (and thesis
/// MLE) against loc-core's f64 `mmse_window` (`grid::mle`) on random inputs, the whole sequence
/// (fit, smoothing, refinement, estimate) on each: within 1 cm on at least 99 % of them.
#[test]
fn ports_match_the_f64_reference_on_random_inputs() {
    const TRIALS: usize = 500;
    let mut rng = Rng(0x4B1D_F00D);
    // [MLE, MMSE] × [f32, fixed]: trials within 1 cm, worst mm.
    let mut within = [[0usize; 2]; 2];
    let mut worst = [[0.0f64; 2]; 2];
    for _ in 0..TRIALS {
        let inp = random_inputs(&mut rng);
        let (f32s, fixed, f64s) = (
            harness::host_f32(&inp),
            harness::host_fixed(&inp),
            harness::host_f64(&inp),
        );
        for k in 0..2 {
            for (p, fix) in [Fix::of_f32(&f32s[k]), Fix::of_fixed(&fixed[k])]
                .into_iter()
                .enumerate()
            {
                let d = fix.dist_mm(&f64s[k]);
                assert!(d.is_finite(), "{inp:?}: {fix:?} vs {:?}", f64s[k]);
                within[k][p] += usize::from(d <= 10.0);
                worst[k][p] = worst[k][p].max(d);
            }
        }
    }
    for (k, name) in ["MLE", "MMSE"].iter().enumerate() {
        for (p, port) in ["f32", "fixed"].iter().enumerate() {
            println!(
                "{name:<4} {port:<5} vs f64: {}/{TRIALS} within 1 cm, worst {:.0} mm",
                within[k][p], worst[k][p]
            );
            assert!(
                within[k][p] * 100 >= TRIALS * 99,
                "{name} {port}: {}/{TRIALS}",
                within[k][p]
            );
        }
    }
}

#[test]
fn baseline_runs_the_same_markers() {
    let none = run("est-none");
    assert_eq!(none.marks.len(), MARKS.len());
    // Every phase of the baseline is empty: each costs about the markers' overhead (one byte
    // time at 57600 baud, 3080 cycles, and the polling) plus the driver's `black_box`es.
    let p = none.phases();
    assert!(p.iter().all(|&c| (3080..3500).contains(&c)), "{p:?}");
}
