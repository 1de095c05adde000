//! The hoploc command line.

use std::process::ExitCode;

use clap::Parser;
use hoploc::cli::{self, Cli};

fn main() -> ExitCode {
    match cli::run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hoploc: {e}");
            ExitCode::FAILURE
        }
    }
}
