//! mcu-bench: one full sink estimate on the ATmega328P, counted in simavr, and the column
//! kernel's equality harness.
//!
//! The benchmark firmwares run the same sequence on the same inputs (4 anchors × 2 channels in
//! a 10 m × 10 m room), writing one marker byte to the UART at every phase boundary; simavr
//! stamps each byte with the cycle at which the firmware wrote `UDR0`, so the cycles between
//! markers are exact:
//!
//! * `est-fixed`: loc-core's integer path ([`loc_core::fixed`]) as the sink runs it, with the
//!   AVR assembly column kernel ([`fixed`]);
//! * `est-portable`: the same with loc-core's portable column (what the kernel saves);
//! * `est-f32`: the same algorithm in plain `f32` with avr-libc's `log10`/`exp` ([`float`]);
//! * `est-none`: no estimator: the baseline whose phases measure the markers' own cost, and whose
//!   flash and SRAM are subtracted to attribute the rest to the estimator.
//!
//! Each run ([`run`]): one untimed earlier round (calibration + fit, so the AR(1) smoothers take
//! their steady-state path), an empty phase, then two estimates, each phase by phase: calibration
//! statistics of the 6 anchor pairs, the least-squares fit of P0 and α fed to the AR(1) smoothers,
//! the Extended refinement, and then the thesis MLE (first estimate) or the windowed MMSE (second).
//! After the timed part the firmware prints both results (see [`Report`]) and stops.
//!
//! `checkasm` is the kernel's equality harness ([`checkasm`]).
//!
//! `cargo fw-bench` builds the ELFs; `cargo bench -p hoploc --bench mcu_estimate` runs them
//! and prints the tables; `tests/tests/mcu_bench.rs` and `tests/tests/checkasm.rs` check the
//! results against the host.
#![cfg_attr(target_arch = "avr", no_std)]

use core::hint::black_box;

pub mod board;
pub mod checkasm;
pub mod fixed;
pub mod float;
#[cfg(target_arch = "avr")]
pub mod fw;
#[cfg(not(target_arch = "avr"))]
pub mod harness;
pub mod rng;

/// Anchors.
pub const N_ANCHORS: usize = 4;
/// Channels per anchor.
pub const N_CHANNELS: usize = 2;
/// Shadowing σ of the MMSE weights, dB.
pub const SIGMA_DB: u8 = 4;

/// Marker bytes, in the order written (none is `\n`, which ends the timed part).
pub const MARKS: [u8; PHASES.len() + 1] = *b"ABCDEFGHIJ";

/// What each interval between two consecutive [`MARKS`] holds.
pub const PHASES: [Phase; 9] = [
    Phase::new(Variant::None, "empty (marker overhead)"),
    Phase::new(Variant::Mle, "calibration statistics (6 pairs)"),
    Phase::new(Variant::Mle, "least-squares P0/α fit + AR(1)"),
    Phase::new(Variant::Mle, "Extended refinement"),
    Phase::new(Variant::Mle, "thesis MLE search"),
    Phase::new(Variant::Mmse, "calibration statistics (6 pairs)"),
    Phase::new(Variant::Mmse, "least-squares P0/α fit + AR(1)"),
    Phase::new(Variant::Mmse, "Extended refinement"),
    Phase::new(Variant::Mmse, "windowed MMSE"),
];

/// Which estimate a phase belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// Not part of an estimate.
    None,
    /// The estimate ending in the thesis MLE.
    Mle,
    /// The estimate ending in the windowed MMSE.
    Mmse,
}

/// A timed phase.
#[derive(Clone, Copy, Debug)]
pub struct Phase {
    /// The estimate it belongs to.
    pub variant: Variant,
    /// What it does.
    pub name: &'static str,
}

impl Phase {
    const fn new(variant: Variant, name: &'static str) -> Phase {
        Phase { variant, name }
    }
}

/// The inputs of every estimate, in the form the sink receives them (RSSI bytes, −dBm).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Inputs {
    /// Anchor positions, cm.
    pub anchors: [[i16; 2]; N_ANCHORS],
    /// The area `[0, w] × [0, h]`, cm.
    pub area: [u16; 2],
    /// The agent's RSSI bytes per anchor and channel.
    pub agent: [[u8; N_CHANNELS]; N_ANCHORS],
    /// Anchor-to-anchor RSSI bytes on channel 0: anchor `i` heard from anchor `j`; channel `c`
    /// adds `c` (see [`Inputs::a2a_byte`]).
    pub a2a: [[u8; N_ANCHORS]; N_ANCHORS],
}

impl Inputs {
    /// The benchmark's inputs: a 10 m square room with an anchor in each corner.
    pub const BENCH: Inputs = Inputs {
        anchors: [[0, 0], [1000, 0], [1000, 1000], [0, 1000]],
        area: [1000, 1000],
        agent: [[65, 63], [69, 68], [65, 68], [61, 60]],
        a2a: [
            [0, 69, 73, 70],
            [68, 0, 69, 74],
            [73, 70, 0, 69],
            [69, 73, 68, 0],
        ],
    };

    /// Byte of anchor `i` hearing anchor `j` on channel `c`.
    pub fn a2a_byte(&self, i: usize, j: usize, c: usize) -> u8 {
        self.a2a[i][j].wrapping_add(c as u8)
    }
}

/// One estimate's result as four words, printed by the firmware as decimal `u32`s. Their meaning
/// is the pipeline's: see [`fixed::Fixed`] and [`float::F32`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Report {
    /// x of the position.
    pub x: u32,
    /// y of the position.
    pub y: u32,
    /// P0 the estimate used.
    pub p0: u32,
    /// α the estimate used.
    pub alpha: u32,
}

/// An estimator broken into the timed phases.
pub trait Pipeline {
    /// Calibration statistics.
    type Stats;
    /// Refined observations.
    type Obs;
    /// Statistics of the anchor-to-anchor bytes.
    fn calibrate(&mut self, inp: &Inputs) -> Self::Stats;
    /// Fit P0 and α from `stats` and feed the smoothers.
    fn fit(&mut self, stats: &Self::Stats);
    /// The agent's observations (Extended refinement).
    fn refine(&mut self, inp: &Inputs) -> Self::Obs;
    /// Thesis MLE with the smoothed model.
    fn mle(&mut self, obs: &Self::Obs, inp: &Inputs) -> Report;
    /// Windowed MMSE with the smoothed model.
    fn mmse(&mut self, obs: &Self::Obs, inp: &Inputs) -> Report;
}

/// The benchmark sequence (see the crate docs): `mark` is called with each of [`MARKS`] in turn;
/// returns the MLE and the MMSE results.
///
/// Every phase takes its inputs through `black_box` and leaves its result and the pipeline's state
/// in memory before the next marker, so no work is folded into constants or moved across a marker.
pub fn run<P: Pipeline>(p: &mut P, inp: &Inputs, mut mark: impl FnMut(u8)) -> [Report; 2] {
    // The earlier round: from here on the AR(1) smoothers are in their steady state.
    let stats = p.calibrate(black_box(inp));
    p.fit(black_box(&stats));
    black_box(&mut *p);
    mark(MARKS[0]);
    mark(MARKS[1]);
    let mle = estimate(p, inp, &mut mark, &MARKS[2..6], Variant::Mle);
    let mmse = estimate(p, inp, &mut mark, &MARKS[6..10], Variant::Mmse);
    [mle, mmse]
}

#[inline(always)]
fn estimate<P: Pipeline>(
    p: &mut P,
    inp: &Inputs,
    mark: &mut impl FnMut(u8),
    marks: &[u8],
    variant: Variant,
) -> Report {
    let stats = black_box(black_box(&mut *p).calibrate(black_box(inp)));
    black_box(&mut *p);
    mark(marks[0]);
    black_box(&mut *p).fit(black_box(&stats));
    black_box(&mut *p);
    mark(marks[1]);
    let obs = black_box(black_box(&mut *p).refine(black_box(inp)));
    black_box(&mut *p);
    mark(marks[2]);
    let r = match variant {
        Variant::Mmse => black_box(&mut *p).mmse(black_box(&obs), black_box(inp)),
        _ => black_box(&mut *p).mle(black_box(&obs), black_box(inp)),
    };
    let r = black_box(r);
    black_box(&mut *p);
    mark(marks[3]);
    r
}

/// No estimator: every phase returns at once (the `est-none` baseline).
#[derive(Clone, Copy, Debug, Default)]
pub struct Nothing;

impl Pipeline for Nothing {
    type Stats = ();
    type Obs = ();
    fn calibrate(&mut self, _: &Inputs) {}
    fn fit(&mut self, _: &()) {}
    fn refine(&mut self, _: &Inputs) {}
    fn mle(&mut self, _: &(), _: &Inputs) -> Report {
        Report::default()
    }
    fn mmse(&mut self, _: &(), _: &Inputs) -> Report {
        Report::default()
    }
}
