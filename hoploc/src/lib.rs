//! The hoploc host tools behind the `hoploc` command line, as a library so the workspace's tests
//! (the `tests` crate) use the same firmware lookup and runs as the command, and benchmarks drive
//! the simulation study ([`study`]) and the testbed's scenarios ([`scenario`], [`testbed`])
//! directly.

pub mod demo;
pub mod firmware;
pub mod fixes;
pub mod footprint;
pub mod health;
pub mod monitor;
pub mod provision;
pub mod replay;
pub mod report;
pub mod scenario;
pub mod simulate;
pub mod study;
pub mod tally;
pub mod testbed;
