//! `calibrator` command-line entry point.
//!
//! Each subcommand is one variant of [`Command`] dispatching to one function.

mod cli;
mod serve_cmd;

use anyhow::Result;
use clap::{Parser, Subcommand};

/// Calibrate a car's rear wheel circumferences from a recorded drive.
#[derive(Parser)]
#[command(name = "calibrator", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Estimate the rear wheel circumferences (and track width, gyro bias and
    /// scale) of a drive folder or MCAP recording; print the report.
    Calibrate(cli::CalibrateArgs),
    /// Live calibration in the process graph: collect the sensor topics,
    /// calibrate on a worker thread, publish estimates that pass the quality gate.
    Serve(serve_cmd::ServeArgs),
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    interfaces::logging::init();
    match cli.command {
        Command::Calibrate(args) => cli::run_calibrate(&args),
        Command::Serve(args) => serve_cmd::run_serve(&args),
    }
}
