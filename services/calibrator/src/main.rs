//! `calibrator` command-line entry point: the process side of the pure
//! `calibrator` library (files, clock, threads, the bus, arguments).
//!
//! Each subcommand is one variant of [`Command`] dispatching to one function:
//! - [`calibrate_cmd`]: `calibrate`, read a drive, print the report, write the JSON and
//!   the pictures;
//! - [`compare_cmd`]: `compare`, a recording and a simulation of the same
//!   path diagnosed alike, the physics they differ in, where they part,
//!   how alike their residual channels are;
//! - [`diagnose_car`]: `diagnose`, one drive or several of one car (the
//!   car's effects pooled over them, a page linking each drive's);
//! - [`diagnose_cmd`]: `diagnose` of one drive, print the findings, write
//!   the JSON, the pictures and their index page;
//! - [`info_cmd`]: `info`, the drive summary with the clock offsets, the
//!   GNSS jumps and the fit quality the calibration finds;
//! - [`serve_cmd`]: the arguments of `serve`, turned into a
//!   [`serve::ServeConfig`];
//! - [`serve`]: the live loop over the bus, with its state file.

mod calibrate_cmd;
mod compare_cmd;
mod diagnose_car;
mod diagnose_cmd;
mod drive_input;
mod info_cmd;
mod serve;
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
    Calibrate(calibrate_cmd::CalibrateArgs),
    /// Find the physics the calibrated 2W model leaves out: where the model
    /// and the drive part ways, which catalogue effects explain it (tested on
    /// held-out blocks), the extended model and the fit before and after.
    Diagnose(diagnose_cmd::DiagnoseArgs),
    /// A simulation against a recording of the same path: the physics the
    /// simulation lacks (or has too much of), where the two part, how alike
    /// their residual channels are; the JSON's findings mend the simulation
    /// (`sensor-bridge simulate --like RECORDING --effects-from`).
    Compare(compare_cmd::CompareArgs),
    /// What a recording holds, and what the calibration finds about its
    /// sensors: every stream's clock offset against the wheels, the GNSS
    /// jumps set aside, the fit quality, and whether a calibration would be
    /// refused.
    Info(info_cmd::InfoArgs),
    /// Live calibration in the process graph: collect the sensor topics,
    /// calibrate on a worker thread, publish estimates that pass the quality gate.
    Serve(serve_cmd::ServeArgs),
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    interfaces::logging::init();
    match cli.command {
        Command::Calibrate(args) => calibrate_cmd::run_calibrate(&args),
        Command::Diagnose(args) => diagnose_car::run_diagnose(&args),
        Command::Compare(args) => compare_cmd::run_compare(&args),
        Command::Info(args) => info_cmd::run_info(&args),
        Command::Serve(args) => serve_cmd::run_serve(&args),
    }
}
