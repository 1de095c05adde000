//! The `hoploc` command line's arguments ([`Cli`]) and the dispatch to the commands: a library
//! module, so tests parse command lines exactly as the binary does.
//!
//! The commands' doc comments are their `--help` text; its examples are shell lines, indented.
#![allow(rustdoc::invalid_rust_codeblocks)]

use std::path::PathBuf;

use clap::{Parser, Subcommand};

use crate::{demo, experiments, firmware, footprint, monitor, provision, radio, replay, simulate};

/// hoploc: multichannel RSSI localization testbed for Arduino Uno + XBee radios.
#[derive(Parser, Debug)]
#[command(version, about, after_help = WHERE)]
pub struct Cli {
    /// The command.
    #[command(subcommand)]
    pub command: Command,
}

/// Where hoploc finds scenarios and firmware (the help's last paragraph).
pub const WHERE: &str = "Where hoploc looks:
  the hoploc workspace: the first directory, from the current one upwards, with a Cargo.toml
    holding [workspace] and a scenarios/ directory;
  scenarios: a path given (anything with a / or ending in .toml), else scenarios/NAME.toml of
    the workspace, else of the current directory;
  firmware: --firmware-dir, else $HOPLOC_FIRMWARE_DIR, else target/avr-none/fw of the workspace
    (built there with cargo fw if missing), else of the current directory;
  the demo's files: --out-dir, else target/demo/SCENARIO of the workspace, else of the current
    directory.";

/// The commands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Run a testbed scenario on every node's real firmware in simavr with modelled XBee radios.
    ///
    /// The scenario's anchors (anchor-fw), agent (agent-fw) and sink (sink-fw) run in simavr on
    /// the modelled radio medium, each with its config in EEPROM; the agent moves along the
    /// scenario's path. The sink firmware's lines give its fixes, shown live against the truth;
    /// at the end an RMSE/bias table per position and estimator (the sink's MLE and MMSE, and
    /// the host's references of the same reports: MLE-fixed with P0/α fixed, MLE-P0only with
    /// P0 fitted and α fixed), and plots, CSV and the sink's log in the out dir. --sink host
    /// runs the sink's logic on the host instead (the same lines, faster). --web serves a live
    /// map of the run in the browser (its address printed; 127.0.0.1 only unless --web-bind),
    /// the run paced at real time unless --speed. Builds the firmware first if needed (cargo
    /// fw, in the hoploc workspace). Scenarios: scenarios/ of the workspace (see the end of
    /// `hoploc --help` for where hoploc looks).
    /// Examples:
    ///
    ///     hoploc demo                          # room10: 10 m × 10 m, 4 anchors, 5.1 fixes/s
    ///     hoploc demo --web                    # and a live map: open the address it prints
    ///     hoploc demo exp3 --web --web-port 8080 --speed 4
    ///     hoploc demo exp3 --seed 7 --out-dir exp3-plots
    ///     hoploc demo exp1 --seconds 30 --live-every 0.5
    ///     hoploc demo --boot --seconds 10      # the firmware booting, as a timeline
    ///     hoploc demo exp1-4a --sink host --report exp1-4a-report   # every algorithm × refinement
    #[command(verbatim_doc_comment)]
    Demo(demo::Args),
    /// Run the thesis' Chapter 4 experiments on the emulated testbed and write one page that
    /// puts each of the thesis' findings next to what the emulation shows.
    ///
    /// Runs experiment 1 (wire and chip antennas, 3 and 4 anchors: exp1-3a, exp1-4a,
    /// exp1-chip-3a, exp1-chip-4a), experiment 2 (3 and 4 anchors, the agent's chip antenna at 0°
    /// and at 225°: exp2-3a, exp2-4a, exp2-3a-225, exp2-4a-225) and experiment 3 (exp3); locates every report the sink
    /// received with every algorithm × channel refinement (as `hoploc demo --report`), and
    /// writes DIR/README.md (findings with their criteria, ✓ or ✗, and the tables) and one
    /// directory per run. The same command gives the same page. Examples:
    ///
    ///     hoploc experiments --report docs/experiments
    ///     hoploc experiments --report /tmp/quick --estimates 30 --only exp1-3a,exp1-chip-3a
    #[command(verbatim_doc_comment)]
    Experiments(experiments::Args),
    /// Print each firmware's flash, static SRAM and stack peak (measured in simavr) against the
    /// budgets: 28 672 B flash, static SRAM + stack ≤ 1 536 B. Fails if one is over.
    ///
    /// The stack peak is the deepest of two runs per firmware: boot with a factory-fresh radio
    /// (full command-mode bring-up, then traffic) and boot with no radio (failed bring-up, LED
    /// error code, retry). Example:
    ///
    ///     hoploc footprint
    #[command(verbatim_doc_comment)]
    Footprint {
        /// Directory with the firmware ELFs [default: $HOPLOC_FIRMWARE_DIR, else
        /// target/avr-none/fw of the hoploc workspace or the current directory].
        #[arg(long)]
        firmware_dir: Option<PathBuf>,
    },
    /// Run the thesis' Monte Carlo localization study on the host estimators.
    ///
    /// A 10 m × 10 m area (--area), anchors at its corners (3 and 4), the agent at 19 × 19
    /// points, 100 runs per point, σ = 2 and 4 dB, two channels with independent noise,
    /// P0 = −40 dBm and α = 3 known (or fitted per trial: --params estimated|ar1).
    /// Rows MLE, MMSE, MDS, TRLT-3/QUAD-4 with CRLB and MMSE floor; columns Ch1, Ch2, Max,
    /// Linear avg, Ext-MCH. Per σ: the mean per-point RMSE and the bias (std over points of
    /// the per-point mean error in x and y). Same seed, same tables on any thread count.
    /// Examples:
    ///
    ///     hoploc simulate
    ///     hoploc simulate --runs 20 --sigma 3 --params estimated --estimator MLE,MMSE
    ///     hoploc simulate --area 30x20 --search multistart --format csv --out-dir study/
    ///     hoploc simulate --report docs/study     # the docs page: docs/study/README.md + plots
    #[command(verbatim_doc_comment)]
    Simulate(simulate::Args),
    /// Write a node's config into its EEPROM over the Uno's USB serial.
    ///
    /// Opening the port resets the board; its firmware listens for a provisioning frame for
    /// 2 s after the `hoploc <role> boot` line, stores a valid config of its role, and answers
    /// ACK or NAK (a node whose EEPROM holds a bad config keeps listening). The node uses the new
    /// config at once and at every boot after (`hoploc <role> config eeprom id <id>`).
    /// Unset options take the defaults shown. Example:
    ///
    ///     hoploc provision --port /dev/ttyACM0 --role anchor --id 2 --x 700 --y 0
    ///     hoploc provision --port /dev/ttyACM1 --role sink --id 1 --channels 1,12 --pan 0x3332
    #[command(verbatim_doc_comment)]
    Provision(provision::Args),
    /// Read an XBee 802.15.4 (S1) on a USB adapter, show what differs from what hoploc expects,
    /// and restore it.
    ///
    /// Finds the radio at every baud rate the S1 can be set to (1200…111 111 bit/s: BD=7 runs
    /// at 111 111, not 115200) without changing anything: an AP query in API mode at each rate,
    /// then command mode at each rate (+++ between guard times, ATxx queries, ATCN). Up to half a
    /// minute when the radio is not in API mode. A radio in transparent mode sends what reaches
    /// it on air: the search goes out as a few short packets, as at a node's boot. Prints each
    /// register that changes how the radio behaves, next to what hoploc expects, ✓ or ✗, and
    /// whether a node sets it at every boot or leaves it, then a verdict with what each
    /// difference does. With --role, --id and the node's options (those of `hoploc provision`)
    /// it checks against that node's settings; without, against what every node gives its radio
    /// (MY, ID, CH, RN, CA and EE depend on the role).
    ///
    /// --restore gives the radio what a node gives it at every boot (API mode 2 at 57600, saved
    /// with WR when they change, as a node does; the rest not saved), and the factory value of
    /// each register nodes leave alone that differs; --write saves it all (WR). Nodes set all
    /// but the registers they leave alone at every boot anyway, and each WR wears the radio's
    /// flash. Examples:
    ///
    ///     hoploc radio --port /dev/ttyUSB0
    ///     hoploc radio --port /dev/ttyUSB0 --role anchor --id 2 --x 700 --y 0
    ///     hoploc radio --port /dev/ttyUSB0 --role agent --id 1 --restore
    ///     hoploc radio --port /dev/ttyUSB0 --role sink --id 1 --channels 2,12 --restore --write
    #[command(verbatim_doc_comment)]
    Radio(radio::Args),
    /// Show the sink's lines live: one row per report (MLE and MMSE fixes, α, P0, anchors),
    /// status lines with a warning for what their counters say is wrong (two agents with one
    /// id, undelivered reports, foreign frames, no report for a status period), damaged lines,
    /// a row when the anchor health check flags an anchor whose relayed RSSI contradicts its
    /// configured position; a table of the fixes at the end.
    ///
    /// Reads the sink's USB serial port, or stdin. Save the lines with --log to replay them
    /// later. --web serves a live map of the fixes in the browser (its address printed;
    /// 127.0.0.1 only unless --web-bind) until the input ends, --seconds pass, or Ctrl-C, which
    /// then ends the session as its end would, with the summary. Examples:
    ///
    ///     hoploc monitor --port /dev/ttyACM0 --log sink.log
    ///     hoploc monitor --port /dev/ttyACM0 --truth 3.5,3.5 --seconds 60 --out-dir plots/
    ///     hoploc monitor --port /dev/ttyACM0 --web --truth 3.5,3.5 --area 7x7
    ///     hoploc monitor --port /dev/ttyACM0 --web --web-bind 0.0.0.0 --web-port 8080  # anyone on the network can watch
    ///     cat sink.log | hoploc monitor
    #[command(verbatim_doc_comment)]
    Monitor(monitor::Args),
    /// Rerun a recorded sink log through every host estimator.
    ///
    /// Per `report` line of the log: the least-squares P0/α fit with AR(1), then MLE, windowed
    /// and full MMSE, MLE with the thesis' fixed P0/α, trilateration, quadlateration, MDS-MAP;
    /// the sink's own fixes next to them. RMSE and bias per truth position and algorithm
    /// (truth from --truth or `# truth X Y` lines in the log), and a plot. Then the anchor
    /// health check: an anchor whose relayed RSSI contradicts its configured position is
    /// flagged, with where its links place it. --web shows every fix of the log, host and sink,
    /// on the live map (see `hoploc demo --help`), served until Ctrl-C. Examples:
    ///
    ///     hoploc replay sink.log --truth 3.5,3.5
    ///     hoploc replay sink.log --area 7x7 --out-dir replay/
    ///     hoploc replay sink.log --area 7x7 --web       # the log on the live map, until Ctrl-C
    #[command(verbatim_doc_comment)]
    Replay(replay::Args),
}

/// Runs the command `cli` describes.
pub fn run(cli: Cli) -> Result<(), String> {
    match cli.command {
        Command::Demo(args) => demo::run(&args),
        Command::Experiments(args) => experiments::run(&args),
        Command::Footprint { firmware_dir } => {
            footprint::run(&firmware_dir.unwrap_or_else(firmware::default_dir))
        }
        Command::Simulate(args) => simulate::run(&args),
        Command::Provision(args) => provision::run(&args).map_err(|e| e.to_string()),
        Command::Radio(args) => radio::run(&args),
        Command::Monitor(args) => monitor::run(&args),
        Command::Replay(args) => replay::run(&args),
    }
}
