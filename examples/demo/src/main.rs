//! `wheelcal-demo`: the whole process graph on a built-in drive.
//!
//! `cargo run --release -p wheelcal-demo` builds the service binaries it
//! starts (calibrator, odometry) and runs the demo; Ctrl-C stops every process.

use anyhow::{Context, Result};
use clap::Parser;
use std::path::PathBuf;
use wheelcal_demo::{run, DemoOptions};

/// Start bridge, calibrator and odometry on a simulated drive whose wheels
/// start miscalibrated, with a long GNSS outage in its second half; show what
/// happens; end with the dead-reckoning error during the outage with nominal
/// against calibrated circumferences and a picture of the tracks.
#[derive(Debug, Parser)]
#[command(name = "wheelcal-demo", version, about)]
struct Cli {
    /// Output directory (drive, estimate.json, demo-result.json, tracks.svg).
    #[arg(long, default_value = "wheelcal-demo")]
    out: PathBuf,
    /// Replay speed, times real time (the drive is about 8.5 minutes).
    #[arg(long, default_value_t = 10.0)]
    speed: f64,
    /// Simulator seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Length of the GNSS outage in the second half, s.
    #[arg(long, default_value_t = 90.0)]
    outage: f64,
    /// Nominal circumference in vehicle.toml (the paper's initial guess), m.
    #[arg(long, default_value_t = 2.2)]
    nominal: f64,
    /// Start from the calibrator's estimate of an earlier run.
    #[arg(long)]
    keep_state: bool,
}

/// Make sure the sibling binaries exist and are fresh when run through cargo.
fn build_siblings(bin_dir: &std::path::Path) -> Result<()> {
    let Ok(cargo) = std::env::var("CARGO") else {
        return Ok(());
    };
    let release = bin_dir.file_name().is_some_and(|n| n == "release");
    let mut cmd = std::process::Command::new(cargo);
    cmd.args(["build", "-q", "--bin", "calibrator", "--bin", "odometry"]);
    if release {
        cmd.arg("--release");
    }
    if let Some(target) = bin_dir.parent() {
        cmd.env("CARGO_TARGET_DIR", target);
    }
    let status = cmd
        .status()
        .context("running cargo build for calibrator and odometry")?;
    anyhow::ensure!(
        status.success(),
        "cargo build of calibrator and odometry failed"
    );
    Ok(())
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    interfaces::logging::init();
    let exe = std::env::current_exe().context("locating this executable")?;
    let bin_dir = exe.parent().map(PathBuf::from).unwrap_or_default();
    build_siblings(&bin_dir)?;
    run(&DemoOptions {
        out_dir: cli.out,
        speed: cli.speed,
        seed: cli.seed,
        outage_s: cli.outage,
        nominal_circumference_m: cli.nominal,
        keep_state: cli.keep_state,
        bin_dir,
    })
}
