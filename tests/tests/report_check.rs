//! The sink's per-report routine in AVR assembly (`uno_board::AvrFit`'s
//! `ReportKernel::report_inputs`), run in simavr by mcu-bench's `report-check` firmware, against
//! its portable twin (`loc_core::fixed::portable_report_inputs`, held to the generic path from
//! `Measurements` by sink-fw's tests) run here on the same reports.

use loc_core::fixed::portable_report_inputs;
use mcu_bench::harness;
use mcu_bench::report_case::{digest, draw, Case, REPORTS, SEED};

/// 3 000 random reports (0–9 anchors, 0–5 channels, relay bytes or not, bytes 0 to 255, rooms,
/// coincident and extreme positions, slices too short) added to random sums and observations:
/// every field of the sums and of the observations equal (by their hashes, the counts and
/// `const_cost`), and the anchors' box widened alike; pairs pushed, observations made,
/// `const_cost` saturated, the 256-sample limit reached, areas widened and reports left alone all
/// among them.
#[test]
fn avr_report_inputs_equal_the_portable_ones() {
    harness::build().expect("bench firmware");
    let mut avr = simavr::Avr::load(harness::elf("report-check")).unwrap();
    while !avr.uart_output_string().contains("end\n") && avr.time_ms() < 600_000.0 {
        avr.run_for_ms(500.0);
    }
    let out = avr.uart_output_string();
    let got: Vec<Vec<u32>> = out
        .lines()
        .filter_map(|l| l.strip_prefix("r "))
        .map(|l| l.split_whitespace().map(|w| w.parse().unwrap()).collect())
        .collect();
    assert_eq!(got.len(), REPORTS as usize, "{out}");
    let mut seed = SEED;
    let mut case = Case {
        buf: [0; 13 + 4 * 8 + 4 * 8 * 8],
        start: 0,
        len: 0,
        n: 0,
        c: 0,
        relay: false,
        stats: Default::default(),
        obs: Default::default(),
        area: Default::default(),
    };
    let (mut bad, mut pairs, mut seen, mut cut, mut alone, mut full) = (0, 0, 0, 0, 0, 0);
    let mut widened = 0;
    for (k, g) in got.iter().enumerate() {
        draw(&mut seed, &mut case);
        let (s0, o0) = (case.stats, case.obs);
        let (mut s, mut o, mut a) = (s0, o0, case.area);
        portable_report_inputs(&case.bytes(), &mut s, &mut o, &mut a);
        let want = digest(&s, &o, &a);
        if g[..] != want[..] {
            bad += 1;
            if bad <= 5 {
                println!(
                    "report {k}: n {} c {} relay {} len {}: want {want:?}, got {g:?}",
                    case.n, case.c, case.relay, case.len
                );
            }
        }
        let heard = case.bytes().size().is_some();
        alone += usize::from(!heard);
        pairs += usize::from(s.len() > s0.len());
        seen += o.len() - o0.len();
        cut += usize::from(s.len() == 256 && s0.len() < 256 && heard);
        full += usize::from(o.const_cost == u32::MAX && o0.const_cost < u32::MAX);
        widened += usize::from(a != case.area);
    }
    println!(
        "reports {REPORTS}, mismatches {bad}, with samples {pairs}, observations {seen}, \
         cut at 256 samples {cut}, const_cost saturated {full}, area widened {widened}, \
         left alone {alone}"
    );
    assert_eq!(bad, 0);
    assert!(pairs >= 1_500, "{pairs}");
    assert!(seen >= 5_000, "{seen}");
    assert!(cut >= 50, "{cut}");
    assert!(full >= 20, "{full}");
    assert!(alone >= 100, "{alone}");
    assert!(widened >= 1_000, "{widened}");
}
