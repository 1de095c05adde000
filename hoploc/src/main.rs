//! The hoploc command line.

use hoploc::{demo, firmware, footprint};

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
    ///     hoploc demo --seconds 8
    #[command(verbatim_doc_comment)]
    Demo {
        /// Simulated time to run, in seconds.
        #[arg(long, default_value_t = 8.0)]
        seconds: f64,
        /// Directory with anchor-fw.elf, agent-fw.elf and sink-fw.elf
        /// [default: target/avr-none/fw, or $HOPLOC_FIRMWARE_DIR].
        #[arg(long)]
        firmware_dir: Option<PathBuf>,
    },
    /// Print each firmware's flash, static SRAM and stack peak (measured in simavr) against the
    /// budgets: 16 KB flash, static SRAM + stack ≤ 1.5 KB. Fails if one is over.
    ///
    /// The stack peak is the deepest of two runs per firmware: boot with a factory-fresh radio
    /// (full command-mode bring-up, then traffic) and boot with no radio (failed bring-up, LED
    /// error code, retry). Example:
    ///
    ///     hoploc footprint
    #[command(verbatim_doc_comment)]
    Footprint {
        /// Directory with the firmware ELFs [default: target/avr-none/fw, or $HOPLOC_FIRMWARE_DIR].
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
        Command::Footprint { firmware_dir } => {
            footprint::run(&firmware_dir.unwrap_or_else(firmware::default_dir))
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hoploc: {e}");
            ExitCode::FAILURE
        }
    }
}
