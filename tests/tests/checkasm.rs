//! The AVR column kernel equals loc-core's portable column on the MCU (`checkasm`, see
//! `mcu_bench::checkasm`): every case of the table ran all its jobs with no mismatch, and the
//! MCU's results have the digest the host's portable column gives on the same jobs (so a
//! miscompiled reference on the MCU cannot hide a wrong kernel), and the timed loops ran.

use mcu_bench::checkasm::{host_digest, BENCH_CASE, BENCH_JOBS, CASES};
use mcu_bench::harness;

#[test]
fn the_avr_column_kernel_equals_the_portable_column() {
    harness::build().unwrap_or_else(|e| panic!("bench firmware: {e}"));
    let run = harness::run_checkasm(&harness::elf("checkasm")).unwrap_or_else(|e| panic!("{e}"));
    assert!(run.mismatches.is_empty(), "{:#?}", run.mismatches);
    let names: Vec<&str> = run.cases.iter().map(|c| c.name.as_str()).collect();
    let want: Vec<&str> = CASES.iter().map(|c| c.name).collect();
    assert_eq!(names, want, "the firmware ran another table");
    for (got, case) in run.cases.iter().zip(&CASES) {
        assert_eq!(got.jobs, case.count, "{}", case.name);
        assert_eq!(got.mismatches, 0, "{}", case.name);
        let host = host_digest(case).0;
        assert_eq!(
            got.portable, host,
            "{}: the MCU's portable column differs from the host's",
            case.name
        );
        assert_eq!(
            got.kernel, host,
            "{}: the AVR kernel differs from the host's portable column",
            case.name
        );
    }
    assert_eq!(run.bench, (CASES[BENCH_CASE].name.to_string(), BENCH_JOBS));
    let (portable, kernel) = run.per_call();
    assert!(
        kernel > 0.0 && kernel < portable,
        "kernel {kernel} vs portable {portable} cycles per column"
    );
}
