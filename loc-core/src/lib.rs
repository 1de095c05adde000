//! Localization core of hoploc (`docs/design.md`, section 5): everything between "RSSI values per
//! anchor and channel" and "a position".
//!
//! * [`model`]: the log-normal path-loss model, geometry ([`Point`], [`Area`]) and the
//!   measurement set ([`Anchor`], [`Measurements`]).
//! * [`refine`]: channel refinements (single channel, Max, Linear average, Extended multichannel).
//! * [`params`]: P0/α estimation from anchor-to-anchor RSSI (grid and exact least squares), AR(1)
//!   smoothing, parameter modes.
//! * [`grid`]: coarse-to-fine grid MLE and the posterior-mean (MMSE) estimate, σ estimate.
//! * [`baselines`]: trilateration, quadlateration, MDS-MAP (host reference algorithms).
//! * [`bounds`]: the Cramér–Rao lower bound and the MMSE floor.
//! * [`fixed`]: the integer-only path of the sink MCU (same algorithms, tables in flash on AVR).
//!
//! This is the f64 reference the host study uses. The crate is `no_std` (math from `libm`).
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
