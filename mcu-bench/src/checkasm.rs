//! The column kernel's equality harness, in the spirit of dav1d's checkasm: one table of input
//! classes ([`CASES`]), each a generator of [`ColumnJob`]s drawn from its own seed; the
//! `checkasm` firmware runs every job through the portable column and the AVR kernel on the MCU
//! and compares everything the contract defines (every row's sum, the minimum and its row, every
//! used anchor's `dx²`), then times both on a search-like class. The same generators run on the
//! host ([`host_digest`]), so `tests/tests/checkasm.rs` also holds the MCU's portable results to
//! the host's: a miscompiled reference cannot agree with a miscompiled kernel unnoticed.
//!
//! The classes cover the kernel's whole contract (`loc_core::fixed::column`): 0 to 64 rows (a
//! search uses at most `WINDOW_ROWS`), any stride, steps and column offset, 0 to 12 anchors
//! (beyond [`MAX_ANCHORS`] they count as [`MAX_ANCHORS`]), weights 1 to 4, shifts 0 to 15, any
//! 24-bit offsets, ρ and clamp, every bound from 0 to `u32::MAX`, any skip mask; and the term's
//! edges (every power of two of `d²` and its neighbours, the 33rd bit, `d² = 0`, the saturation).
//! To add a kernel or a class, add a row to the table.

use crate::rng::Rng;
use loc_core::fixed::column::{AnchorTerm, I24};
use loc_core::fixed::{ColumnJob, LOG2_CLAMP, WINDOW_ROWS};
use loc_core::grid::FINE_DIVS;
use loc_core::MAX_ANCHORS;

/// Rows the harness's sum buffers hold (the largest job it draws).
pub const MAX_ROWS: usize = 64;

/// One class of jobs: `count` jobs from `gen`, seeded with `seed`.
#[derive(Clone, Copy)]
pub struct Case {
    /// Its name in the firmware's output.
    pub name: &'static str,
    /// Jobs drawn.
    pub count: u32,
    /// The generator's seed.
    pub seed: u32,
    /// Draws a job into `job` (every field set) and returns its row count (≤ [`MAX_ROWS`]).
    pub gen: fn(&mut Rng, &mut ColumnJob) -> usize,
}

/// The table: what the firmware checks, in this order.
pub const CASES: [Case; 5] = [
    Case {
        name: "term-edges",
        count: 4_096,
        seed: 0x0000_0001,
        gen: term_edges,
    },
    Case {
        name: "term-random",
        count: 20_000,
        seed: 0x9E37_79B9,
        gen: term_random,
    },
    Case {
        name: "search",
        count: 6_000,
        seed: 0x2545_F491,
        gen: search_like,
    },
    Case {
        name: "wild",
        count: 4_000,
        seed: 0x5EED_C0DE,
        gen: wild,
    },
    Case {
        name: "bounds",
        count: 4_000,
        seed: 0x0BAD_F00D,
        gen: bounds,
    },
];

/// The class the firmware times (portable against assembly), and how many of its jobs.
pub const BENCH_CASE: usize = 2;
/// Jobs of [`BENCH_CASE`] per timed loop.
pub const BENCH_JOBS: u32 = 500;

/// The job's fixed fields at their neutral values, every anchor slot zero.
fn blank(job: &mut ColumnJob) {
    *job = ColumnJob::EMPTY;
}

/// One anchor whose offsets put `d²` (row 0, column 0) at `dx² + dy²` for the given 24-bit
/// offsets.
fn anchor(dx0: i32, dy0: i32, rho: i32, lclamp: i32, w: u8, shift: u8) -> AnchorTerm {
    AnchorTerm {
        dx2: 0,
        dx0: I24::new(dx0),
        dy0: I24::new(dy0),
        lclamp,
        rho,
        w,
        shift,
    }
}

/// One row, one anchor: the term's edges. The offsets walk every power of two of `d²` and its
/// neighbours (with and without the 33rd bit), ρ the saturation's edges and the extremes, the
/// clamp around 1 cm and its extremes.
fn term_edges(r: &mut Rng, job: &mut ColumnJob) -> usize {
    blank(job);
    let k = r.bits();
    // Offsets (after a shift of 0) up to 2^16 − 1 in magnitude: d² up to 2^33 − 2^18.
    let mag = |e: u32, d: i32| ((1i32 << (e % 17)) + d).clamp(0, 0xFFFF);
    let (ex, ey) = (k % 17, (k >> 5) % 17);
    let (dx, dy) = (
        mag(ex, (k >> 10) as i32 % 3 - 1),
        mag(ey, (k >> 12) as i32 % 3 - 1),
    );
    let sign = |b: u32, v: i32| if b & 1 == 0 { v } else { -v };
    let dx = if k >> 14 & 3 == 0 {
        0
    } else {
        sign(k >> 16, dx)
    };
    let dy = if k >> 17 & 3 == 0 {
        0
    } else {
        sign(k >> 19, dy)
    };
    let rho = match (k >> 20) % 8 {
        0 => 0,
        1 => i32::MIN,
        2 => i32::MAX,
        3 => (32 << 20) - 1 - ((r.bits() % 64) << 20) as i32,
        4 => -(32 << 20) + (r.bits() % (64 << 20)) as i32,
        5 => -((r.bits() % (40 << 20)) as i32),
        6 => (r.bits() as i32) >> (r.bits() % 31),
        _ => -(r.bits() as i32 >> 2),
    };
    let lclamp = match (k >> 23) % 4 {
        0 => LOG2_CLAMP,
        1 => i32::MIN,
        2 => i32::MAX,
        _ => r.bits() as i32 >> (r.bits() % 31),
    };
    job.n = 1;
    job.anchors[0] = anchor(dx, dy, rho, lclamp, 1 + (k >> 26) as u8 % 4, 0);
    job.bound = if k >> 28 == 0 { r.bits() } else { u32::MAX };
    job.stride = 1;
    1
}

/// One row, one anchor, anything: random offsets, shifts, ρ, clamp, weight, column offset and
/// steps.
fn term_random(r: &mut Rng, job: &mut ColumnJob) -> usize {
    blank(job);
    let (a, b, c) = (r.bits(), r.bits(), r.bits());
    job.n = 1;
    job.col = (a >> 24) as u8;
    job.xstep = b as u16;
    job.ystep = (b >> 16) as u16;
    job.stride = (a >> 16) as u8;
    job.bound = match a % 4 {
        0 => u32::MAX,
        1 => u32::MAX - 1,
        _ => r.bits() >> ((a >> 8) % 32),
    };
    let shift = if c % 3 == 0 { 0 } else { ((c >> 2) % 16) as u8 };
    job.anchors[0] = anchor(
        r.bits() as i32 >> ((c >> 8) % 9),
        r.bits() as i32 >> ((c >> 12) % 9),
        r.bits() as i32 >> ((c >> 16) % 32),
        LOG2_CLAMP - (((c >> 21) % 64) << 20) as i32 + (r.bits() % 3) as i32 - 1,
        1 + (c >> 27) as u8 % 4,
        shift,
    );
    1
}

/// What a search builds: 1 to `WINDOW_ROWS` rows 1 or more fine rows apart, 0 to
/// [`MAX_ANCHORS`] anchors whose offsets stay below 2^16 after their shift over the whole
/// column, bounds from a cost-like value to none, some rows skipped.
fn search_like(r: &mut Rng, job: &mut ColumnJob) -> usize {
    blank(job);
    let (a, b) = (r.bits(), r.bits());
    let rows = 1 + (a % WINDOW_ROWS as u32) as usize;
    job.stride = 1 + ((b >> 8) % 5) as u8;
    let span = (rows - 1) as u32 * job.stride as u32;
    let n = (b % (MAX_ANCHORS as u32 + 1)) as u8;
    job.bound = match a % 4 {
        0 => u32::MAX,
        1 => r.bits(),
        _ => r.bits() >> (b % 24),
    };
    job.n = n;
    let x = r.bits();
    job.col = (x % (FINE_DIVS as u32 + 1)) as u8;
    job.xstep = (x >> 8) as u16 % (6_000 << (x % 4));
    let dx_col = job.col as i32 * job.xstep as i32;
    // One row step for every anchor: within what the tightest (shift 0) can take.
    job.ystep = (1 + r.bits() % (2 * 65_534 / span.max(1))).min(65_535) as u16;
    for t in job.anchors[..n as usize].iter_mut() {
        let (c, d, e) = (r.bits(), r.bits(), r.bits());
        let shift = if c % 3 == 0 { 0 } else { ((c >> 8) % 8) as u8 };
        // Offsets within ±lim round below 2^16.
        let lim = 65_534u32 << shift;
        let dx = (e % (2 * lim + 1)) as i32 - lim as i32;
        let room = 2 * lim - job.ystep as u32 * span;
        *t = anchor(
            dx - dx_col,
            -(lim as i32) + (d % (room + 1)) as i32,
            (e as i32) >> (c % 8),
            LOG2_CLAMP - ((c % 5) << 20) as i32,
            1 + (d % 4) as u8,
            shift,
        );
    }
    let x = r.bits();
    job.skip = match x % 4 {
        0 => x as u16,
        1 => (x >> 16) as u16 & (x as u16),
        _ => 0,
    };
    rows
}

/// Anything the contract allows: 0 to [`MAX_ROWS`] rows, any stride (the row offset wraps at a
/// byte), 0 to 12 anchors, any 24-bit offsets, shifts 0 to 15, any ρ and clamp, any steps, bound
/// and skip mask.
fn wild(r: &mut Rng, job: &mut ColumnJob) -> usize {
    blank(job);
    let (a, b) = (r.bits(), r.bits());
    // (In u32: `usize` is 16 bits on the MCU, and the draws must be the host's.)
    let rows = match a % 8 {
        0 => 0,
        1 => 17 + (a >> 8) % (MAX_ROWS as u32 - 16),
        _ => (a >> 8) % 17,
    } as usize;
    job.n = (b % 13) as u8;
    job.stride = (b >> 8) as u8;
    job.col = (b >> 16) as u8;
    job.xstep = r.bits() as u16;
    job.ystep = r.bits() as u16;
    job.bound = r.bits() >> ((a >> 12) % 32);
    job.skip = r.bits() as u16;
    for t in job.anchors.iter_mut() {
        let c = r.bits();
        *t = anchor(
            r.bits() as i32,
            r.bits() as i32,
            r.bits() as i32 >> (c % 32),
            r.bits() as i32 >> ((c >> 5) % 32),
            1 + (c >> 10) as u8 % 4,
            ((c >> 12) % 16) as u8,
        );
    }
    rows
}

/// The bound's edges on search-like jobs: 0, 1, the exact cost of a row and its neighbours,
/// `u32::MAX − 1` and `u32::MAX`.
fn bounds(r: &mut Rng, job: &mut ColumnJob) -> usize {
    let rows = search_like(r, job);
    let k = r.bits();
    job.bound = match k % 6 {
        0 => 0,
        1 => 1,
        2 => u32::MAX - 1,
        3 => u32::MAX,
        // A row's own cost (from a portable pass with no bound), less one, or one more.
        _ => {
            let mut sums = [0u32; WINDOW_ROWS];
            let mut probe = *job;
            probe.bound = u32::MAX;
            probe.skip = 0;
            loc_core::fixed::column::portable_column(&mut sums[..rows], &mut probe);
            let v = sums[((k >> 4) % rows as u32) as usize];
            v.wrapping_add((k >> 12) % 3).wrapping_sub(1)
        }
    };
    rows
}

/// FNV-1a over what a column computed: the sums, the minimum and its row, the used anchors'
/// `dx²`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Digest(pub u32);

impl Digest {
    /// The empty digest.
    pub const NEW: Digest = Digest(0x811C_9DC5);

    fn byte(&mut self, b: u8) {
        self.0 = (self.0 ^ b as u32).wrapping_mul(0x0100_0193);
    }

    fn word(&mut self, w: u32) {
        for b in w.to_le_bytes() {
            self.byte(b);
        }
    }

    /// Adds one column's results.
    pub fn add(&mut self, sums: &[u32], job: &ColumnJob) {
        for &s in sums {
            self.word(s);
        }
        self.word(job.min);
        self.byte(job.min_row);
        for t in job.used() {
            self.word(t.dx2);
        }
    }
}

/// Whether two runs of the same job computed the same: every sum, the minimum, its row and the
/// used anchors' `dx²`.
pub fn same(want: &[u32], w: &ColumnJob, got: &[u32], g: &ColumnJob) -> bool {
    want == got
        && (w.min, w.min_row) == (g.min, g.min_row)
        && w.used().iter().zip(g.used()).all(|(a, b)| a.dx2 == b.dx2)
}

/// The digest of case `case`'s jobs through `column`, as the firmware computes it (each job's
/// sums start as garbage the kernel must overwrite).
pub fn digest_of(case: &Case, column: fn(&mut [u32], &mut ColumnJob)) -> Digest {
    let mut r = Rng(case.seed);
    let mut d = Digest::NEW;
    let mut job = ColumnJob::EMPTY;
    let mut sums = [0u32; MAX_ROWS];
    for _ in 0..case.count {
        let rows = (case.gen)(&mut r, &mut job);
        sums.fill(0xA5A5_A5A5);
        column(&mut sums[..rows], &mut job);
        d.add(&sums[..rows], &job);
    }
    d
}

/// [`digest_of`] every case with the portable column, on the host.
#[cfg(not(target_arch = "avr"))]
pub fn host_digest(case: &Case) -> Digest {
    use loc_core::fixed::{ColumnKernel, Portable};
    digest_of(case, Portable::column)
}
