//! The hoploc host tools behind the `hoploc` command line, as a library so the workspace's tests
//! (the `tests` crate) use the same firmware lookup and runs as the command.

pub mod demo;
pub mod firmware;
pub mod footprint;
