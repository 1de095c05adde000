//! RSSI localization: from the received signal strength of radios at known positions (anchors)
//! to the position of the radio that heard them, on a 2-D area. `no_std`, no allocation; it runs
//! on a host as well as on an 8-bit AVR.
//!
//! It was written for hoploc, a multichannel RSSI indoor-localization testbed of Arduino Unos
//! with XBee 802.15.4 radios, whose sink computes each position with this crate. The estimators
//! follow a localization thesis ("the thesis" in these docs): a coarse-to-fine grid search for
//! the maximum-likelihood position under a log-normal path-loss model whose parameters are
//! re-estimated from the RSSI the anchors measure of each other. Beside them are a multi-start
//! search, the posterior mean and box-constrained least squares.
//!
//! # Where to start
//!
//! Put what the agent (the radio to locate) heard of each anchor into [`Measurements`], and
//! [`grid::locate`] it with a [`PathLoss`] model:
//!
//! ```
//! use loc_core::grid::{self, Estimator, Search};
//! use loc_core::refine::Refinement;
//! use loc_core::{Area, Measurements, PathLoss, Point};
//!
//! // Three anchors at the corners of a 10 m × 10 m room, one channel.
//! let corners = [Point::new(0.0, 0.0), Point::new(10.0, 0.0), Point::new(0.0, 10.0)];
//! let mut m = Measurements::new(&corners, 1);
//! // What the agent heard of each, dBm: here the model's mean level at its distance from (3, 4).
//! let model = PathLoss { p0: -40.0, alpha: 3.0 };
//! let agent = Point::new(3.0, 4.0);
//! for anchor in &mut m.anchors[..3] {
//!     anchor.rssi[0] = Some(model.rssi_at(anchor.pos.dist(agent)));
//! }
//! let area = Area::new(10.0, 10.0);
//! let fix = grid::locate(&m, Refinement::Max, model, area, Estimator::Mle(Search::Thesis)).unwrap();
//! assert!(fix.pos.dist(agent) < 0.2);
//! ```
//!
//! With the anchor-to-anchor RSSI in [`Measurements::a2a`], [`params::estimate`] fits the model's
//! `P0` and `α` first (and [`params::OnlineParams`] smooths the fit over time). The crate's
//! `examples/locate.rs` makes one fix that way, from noisy RSSI on two channels.
//!
//! # What is in it
//!
//! * [`model`]: the log-normal path-loss model ([`PathLoss`]), geometry ([`Point`], [`Area`])
//!   and the measurement set ([`Anchor`], [`Measurements`]).
//! * [`refine`]: how one anchor's channels are combined (single channel, max, linear average,
//!   every channel its own observation).
//! * [`params`]: `P0`/`α` estimation from anchor-to-anchor RSSI (the thesis' grid, exact
//!   box-constrained least squares), AR(1) smoothing, parameter modes.
//! * [`grid`]: the coarse-to-fine grid maximum-likelihood search (the thesis' and a
//!   multi-start one), the posterior mean (MMSE), σ estimate.
//! * [`baselines`]: trilateration, quadlateration, MDS-MAP, for comparison.
//! * [`bounds`]: the Cramér–Rao lower bound and the MMSE floor.
//! * [`fixed`]: the same algorithms in integer arithmetic only, for a microcontroller without a
//!   floating-point unit: the path hoploc's ATmega328P sink runs, tested to agree with the `f64`
//!   reference.
//!
//! # Platforms
//!
//! The crate is `no_std` (its `f64` math comes from `libm`) and has no cargo features. On AVR
//! (`target_arch = "avr"`) the [`fixed`] path keeps its constant tables in flash (through
//! `avr-progmem`) and runs its inner loop as AVR assembly, which needs a nightly compiler
//! (`asm_experimental_arch`); on other targets it uses no unstable feature.
#![no_std]
#![cfg_attr(target_arch = "avr", feature(asm_experimental_arch))]
// `unsafe` only for the AVR column kernel (`fixed::column`'s `avr` module) and the flash
// placement of the table it reads (`fixed::tables`).
#![deny(unsafe_code)]
#![warn(missing_docs)]

#[cfg(test)]
extern crate std;

pub mod baselines;
pub mod bounds;
pub mod fixed;
pub mod grid;
pub mod model;
pub mod params;
pub mod refine;

pub use model::{Anchor, Area, Measurements, PathLoss, Point, MAX_ANCHORS, MAX_CHANNELS};

/// Why an estimate could not be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LocError {
    /// Fewer than three anchors had a usable measurement.
    TooFewAnchors {
        /// How many were usable.
        usable: usize,
    },
    /// The anchors' geometry admits no solution (coincident or collinear anchors for a
    /// closed-form method).
    DegenerateGeometry,
    /// No anchor pair with a known distance and RSSI to estimate path-loss parameters from.
    NoCalibrationData,
}

impl core::fmt::Display for LocError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LocError::TooFewAnchors { usable } => {
                write!(f, "{usable} usable anchors, at least 3 needed")
            }
            LocError::DegenerateGeometry => f.write_str("anchors are coincident or collinear"),
            LocError::NoCalibrationData => {
                f.write_str("no anchor-to-anchor RSSI to estimate the path-loss model from")
            }
        }
    }
}

impl core::error::Error for LocError {}

/// The README's examples run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
