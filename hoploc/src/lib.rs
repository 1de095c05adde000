//! The hoploc host tools behind the `hoploc` command line, as a library so the workspace's tests
//! (the `tests` crate) use the same firmware lookup and runs as the command, and benchmarks drive
//! the simulation study ([`study`]) and the testbed's scenarios ([`scenario`], [`testbed`])
//! directly.

pub mod args;
// The command line's doc comments are its `--help` text, with shell examples as indented lines:
// not Rust, so not doctests.
#[cfg(not(doctest))]
pub mod cli;
pub mod demo;
pub mod diagnose;
pub mod experiments;
pub mod firmware;
pub mod fixes;
pub mod footprint;
pub mod framing;
pub mod health;
pub mod monitor;
pub mod out;
pub mod provision;
pub mod radio;
pub mod replay;
pub mod report;
pub mod scenario;
pub mod simulate;
pub mod study;
pub mod tally;
pub mod testbed;
pub mod thesis;
pub mod web;
