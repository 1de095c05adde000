//! The MCU estimate benchmark's firmwares compute the right thing (not how fast: that is
//! `cargo bench -p hoploc --bench mcu_estimate`): `est-fixed` in simavr prints exactly what
//! `loc_core::fixed` computes on the host for the same inputs, `est-f32` what the same f32 code
//! computes on the host and a position within one fine lattice step (20 cm) of the fixed path's,
//! and `est-none` runs the same markers.

use std::sync::OnceLock;

use mcu_bench::harness::{self, Fix, Run};
use mcu_bench::{Inputs, MARKS};

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

#[test]
fn baseline_runs_the_same_markers() {
    let none = run("est-none");
    assert_eq!(none.marks.len(), MARKS.len());
    // Every phase of the baseline is empty: each costs about the markers' overhead (one byte
    // time at 57600 baud, 3080 cycles, and the polling) plus the driver's `black_box`es.
    let p = none.phases();
    assert!(p.iter().all(|&c| (3080..3500).contains(&c)), "{p:?}");
}

/// `uno_board::AvrTerm` (the cost term and the column loop in AVR assembly, what the sink runs)
/// returns exactly `loc_core::fixed::portable_term`'s value on the MCU (edge cases and 50 000
/// random inputs) and leaves exactly `portable_column`'s sums (5 000 random columns).
#[test]
fn avr_cost_kernel_equals_the_portable_one() {
    if let Err(e) = BUILD.get_or_init(harness::build) {
        panic!("bench firmware: {e}");
    }
    let mut avr = simavr::Avr::load(harness::elf("kernel-check")).unwrap();
    while !avr.uart_output_string().contains("end\n") && avr.time_ms() < 20_000.0 {
        avr.run_for_ms(100.0);
    }
    let out = avr.uart_output_string();
    assert!(out.contains("kernel 50000 0\n"), "{out}");
    assert!(out.contains("column 5000 0\n"), "{out}");
}
