//! The hoploc command line.

use hoploc::{demo, firmware};

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// hoploc: multichannel RSSI localization testbed for Arduino Uno + XBee radios.
#[derive(Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run every node's real firmware in simavr with modelled XBee radios.
    ///
    /// Builds the firmware first if needed (cargo fw). Example:
    ///
    ///     hoploc demo --seconds 5
    #[command(verbatim_doc_comment)]
    Demo {
        /// Simulated time to run, in seconds.
        #[arg(long, default_value_t = 5.0)]
        seconds: f64,
        /// Directory with anchor-fw.elf, agent-fw.elf and sink-fw.elf
        /// [default: target/avr-none/fw, or $HOPLOC_FIRMWARE_DIR].
        #[arg(long)]
        firmware_dir: Option<PathBuf>,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo {
            seconds,
            firmware_dir,
        } => demo::run(&firmware_dir.unwrap_or_else(firmware::default_dir), seconds),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hoploc: {e}");
            ExitCode::FAILURE
        }
    }
}
