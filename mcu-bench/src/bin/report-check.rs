//! report-check: `uno_board::AvrFit`'s report routine (`ReportKernel::report_inputs`, the
//! sink's per-report calibration sums and Extended observations in AVR assembly) on
//! `mcu_bench::report_case`'s pseudo-random reports (0–8 anchors, sometimes 9, 1–4 channels,
//! sometimes 0 or 5, relay bytes or not, bytes 0 = not heard to 255, positions in a room,
//! coincident, 1 cm apart or anywhere in `i16`, slices one byte short), added to random sums
//! (some nearly at the 256-sample limit) and observations (some nearly full, `const_cost` near
//! saturation) and areas. Prints one line per report, `r <hash of the sums> <hash of the
//! observations> <samples> <observations> <const_cost> <area>` (`report_case::digest`), then
//! `end`; the host
//! (`tests/tests/report_check.rs`) computes the portable twin on the same reports and compares.
//! Build: `cargo fw-bench`.
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
    use loc_core::fixed::{AreaCm, CalStats, Observations, ReportKernel};
    use mcu_bench::fw::write_u32;
    use mcu_bench::report_case::{digest, draw, Case, REPORTS, SEED};
    use uno_board::AvrFit;

    pub fn run() -> ! {
        let mut serial = mcu_bench::fw::start();
        let mut seed = SEED;
        let mut case = Case {
            buf: [0; 13 + 4 * 8 + 4 * 8 * 8],
            start: 0,
            len: 0,
            n: 0,
            c: 0,
            relay: false,
            stats: CalStats::new(),
            obs: Observations::new(),
            area: AreaCm::new(0, 0),
        };
        for _ in 0..black_box(REPORTS) {
            draw(&mut seed, &mut case);
            let (mut s, mut o, mut a) = (case.stats, case.obs, case.area);
            AvrFit::report_inputs(black_box(&case.bytes()), &mut s, &mut o, &mut a);
            serial.write_byte(b'r');
            for v in digest(&s, &o, &a) {
                serial.write_byte(b' ');
                write_u32(&mut serial, v);
            }
            serial.write_byte(b'\n');
        }
        mcu_bench::fw::end(&mut serial)
    }
}
