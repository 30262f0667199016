//! `odometry` command-line entry point: the process side of the pure
//! `odometry` library (files, clock, the bus, arguments).
//!
//! Each subcommand is one variant of [`Command`] dispatching to one module:
//! - [`evaluate_cmd`]: `evaluate`, dead-reckon through simulated GNSS outages
//!   and score them; print the report, write the JSON and the page;
//! - [`serve`]: the pose service over iceoryx2, split by job (flags,
//!   settings, inputs, the kept pose, the loop), with the pose state file;
//! - [`odometer_args`]: the dead-reckoning flags both share.

mod evaluate_cmd;
mod odometer_args;
mod serve;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};

#[derive(Debug, Parser)]
#[command(
    name = "odometry",
    version,
    about = "2W odometry: dead-reckoning evaluation and the pose service"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Dead-reckon through simulated GNSS outages placed every 10 s along a
    /// drive, the pose taken from truth.csv at each outage start, and score
    /// the position at each outage end.
    Evaluate(evaluate_cmd::EvaluateArgs),
    /// Run the pose service over iceoryx2: subscribe to wheels, IMU, GNSS,
    /// heading and the estimate; publish a pose per wheel sample.
    Serve(serve::ServeArgs),
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    interfaces::logging::init();
    match cli.command {
        Command::Evaluate(args) => evaluate_cmd::run_evaluate(&args),
        Command::Serve(args) => {
            serve::run(&args, &serve::Shutdown::new()).context("odometry serve")?;
            Ok(())
        }
    }
}
