//! search-check2: the sink's search driver, `uno_board::AvrTerm::search` (AVR assembly), against
//! `loc_core::fixed::portable_search::<AvrTerm>` (the same kernels under both: only the driver
//! differs) on the MCU itself, on 2 000 lattices set up from random searches' inputs (those of
//! `search-check`); prints `baddriver <trial> <part>` for its first mismatches, then `driver
//! <checked> <mismatches>`, then `end`. (A firmware of its own: `search-check` is full.)
//! `tests/tests/search_check.rs` runs it in simavr. Build: `cargo fw-bench`.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

#[cfg(target_arch = "avr")]
#[path = "common/search_inputs.rs"]
mod search_inputs;
#[cfg(target_arch = "avr")]
use search_inputs::search_inputs;

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    use core::hint::black_box;
    let mut serial = mcu_bench::fw::start();
    let mut r = 0x7F4A_7C15u32;
    let line = mcu_bench::fw::write_line;
    // ---- the search driver (the same kernels under both) ----
    let (mut bad, n) = (0u32, black_box(2_000u32));
    for t in 0..n {
        let (want, got) = driver_pair(t, &mut r);
        if !want {
            bad += 1;
            if bad <= 5 {
                line(&mut serial, b"baddriver", &[t, got]);
            }
        }
    }
    line(&mut serial, b"driver", &[n, bad]);
    mcu_bench::fw::end(&mut serial)
}

/// Driver trial `t`: a lattice set up for [`search_inputs`]`(t)`'s observations (its window
/// origin then set anywhere in the lattice, which both must move from alike), searched by
/// `loc_core::fixed::portable_search::<AvrTerm>` and by `AvrTerm::search` (the same kernels:
/// only the driver differs); `(equal, first differing part)`: best points, posterior sums,
/// window, sums, the job's header and every anchor's offsets.
#[cfg(target_arch = "avr")]
#[inline(never)]
fn driver_pair(t: u32, r: &mut u32) -> (bool, u32) {
    use core::hint::black_box;
    use loc_core::fixed::{log2_segment_base, Lattice, LatticeMin, Posterior, TermKernel, Weights};
    use uno_board::AvrTerm;
    let (obs, model, area, sigma) = search_inputs(t, r);
    let mut a = Lattice::EMPTY;
    (a.job.xstep, a.job.ystep) = (area.width, area.height);
    a.job.seg_base = log2_segment_base();
    (a.s.p0, a.s.alpha) = (model.p0, model.alpha);
    AvrTerm::observe(&mut a.job, &mut a.s, obs.as_slice());
    let x = mcu_bench::fw::xorshift(r);
    if t % 2 == 1 {
        (a.i0, a.j0) = ((x % 51) as u8, ((x >> 8) % 51) as u8);
    }
    let mut pa = Posterior::new(Weights::ZERO, 0);
    AvrTerm::weights(a.s.k26, sigma, &mut pa.wts);
    let (mut b, mut pb) = (a, pa);
    let none = LatticeMin {
        i: x as u8,
        j: (x >> 8) as u8,
        cost: x,
    };
    let (mut ba, mut bb) = ([none; 2], [none; 2]);
    loc_core::fixed::portable_search::<AvrTerm>(&mut a, &mut ba, &mut pa);
    AvrTerm::search(black_box(&mut b), &mut bb, &mut pb);
    let parts = [
        ba == bb,
        (pa.cref, pa.s, pa.sx, pa.sy) == (pb.cref, pb.s, pb.sx, pb.sy),
        (a.i0, a.j0, a.rows) == (b.i0, b.j0, b.rows),
        a.sums == b.sums,
        (
            a.job.bound,
            a.job.min,
            a.job.min_row,
            a.job.col,
            a.job.stride,
            a.job.skip,
        ) == (
            b.job.bound,
            b.job.min,
            b.job.min_row,
            b.job.col,
            b.job.stride,
            b.job.skip,
        ),
        a.job
            .anchors
            .iter()
            .zip(&b.job.anchors)
            .all(|(p, q)| (p.dx0, p.dy0) == (q.dx0, q.dy0)),
    ];
    match parts.iter().position(|&ok| !ok) {
        None => (true, 0),
        Some(k) => (false, k as u32),
    }
}
