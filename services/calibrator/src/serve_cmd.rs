//! `calibrator serve`: command-line glue around [`crate::serve::run`].
//!
//! Joins the graph named by `WHEELCAL_IOX_PREFIX` / `WHEELCAL_IOX_ROOT`.

use crate::serve::{run, ServeConfig};
use anyhow::{Context, Result};
use clap::Args;
use interfaces::bus::Bus;
use interfaces::drive::VehicleParams;
use std::path::{Path, PathBuf};

/// Arguments of `calibrator serve`.
#[derive(Args, Debug)]
pub struct ServeArgs {
    /// Vehicle parameters: a vehicle.toml, or a drive (folder or .mcap) to
    /// take them from. The bus does not carry them.
    #[arg(long, value_name = "PATH")]
    pub vehicle: PathBuf,
    /// Keep the last accepted estimate in this JSON file and start from it.
    #[arg(long, value_name = "FILE", default_value = "wheelcal-estimate.json")]
    pub state: PathBuf,
    /// Do not read or write a state file.
    #[arg(long, conflicts_with = "state")]
    pub no_state: bool,
    /// Distance to collect before the first attempt, m.
    #[arg(long, value_name = "M", default_value_t = 1500.0)]
    pub min_distance: f64,
    /// Turning (sum of absolute heading change) before the first attempt, degrees.
    #[arg(long, value_name = "DEG", default_value_t = 360.0)]
    pub min_turn: f64,
    /// GNSS fixes before the first attempt.
    #[arg(long, value_name = "N", default_value_t = 100)]
    pub min_fixes: usize,
    /// New distance between attempts, m.
    #[arg(long, value_name = "M", default_value_t = 1500.0)]
    pub recalibrate_distance: f64,
    /// Fraction of the collected drive (its end) held out to judge a result.
    #[arg(long, value_name = "F", default_value_t = 0.3)]
    pub holdout: f64,
    /// Dead-reckoning window on the held-out data, s.
    #[arg(long, value_name = "S", default_value_t = 15.0)]
    pub holdout_window: f64,
    /// Largest accepted 1-sigma of a circumference, mm.
    #[arg(long, value_name = "MM", default_value_t = 5.0)]
    pub max_sigma_mm: f64,
    /// Estimator: batch or paper.
    #[arg(long, value_name = "METHOD", default_value = "batch")]
    pub method: String,
    /// Stop once the sensor stream has ended and no attempt is running.
    #[arg(long)]
    pub exit_on_end: bool,
    /// Also diagnose each attempt's drive (`calibrator diagnose`) and send
    /// the wheel-side terms of the effects it accepts with the estimate
    /// (the odometry applies them; about 1 s per 10 minutes of drive).
    #[arg(long)]
    pub diagnose: bool,
}

/// Vehicle parameters from a vehicle.toml or a drive; warnings to the log.
fn load_vehicle(path: &Path) -> Result<VehicleParams> {
    let loaded = drive_io::read_vehicle(path)
        .with_context(|| format!("reading vehicle parameters from {}", path.display()))?;
    for warning in &loaded.warnings {
        tracing::warn!("calibrator: {warning}");
    }
    Ok(loaded.vehicle)
}

/// Run `calibrator serve`.
pub fn run_serve(args: &ServeArgs) -> Result<()> {
    let mut cfg = ServeConfig::new(load_vehicle(&args.vehicle)?);
    cfg.min_distance_m = args.min_distance;
    cfg.min_turn_deg = args.min_turn;
    cfg.min_gnss_fixes = args.min_fixes;
    cfg.recalibrate_distance_m = args.recalibrate_distance;
    cfg.holdout_fraction = args.holdout;
    cfg.holdout_window_s = args.holdout_window;
    cfg.max_sigma_m = args.max_sigma_mm * 1e-3;
    cfg.exit_on_end = args.exit_on_end;
    cfg.diagnose = args.diagnose;
    cfg.state_file = (!args.no_state).then(|| args.state.clone());
    cfg.calibration.method = match args.method.as_str() {
        "batch" => calibrator::Method::Batch,
        "paper" => calibrator::Method::Paper,
        other => anyhow::bail!("--method {other}: expected batch or paper"),
    };
    cfg.validate().context("checking the settings")?;
    let bus = Bus::from_env("calibrator").context("joining the iceoryx2 graph")?;
    let summary = run(&bus, &cfg).context("calibrator service")?;
    tracing::info!(
        "calibrator: stopped after {} attempt(s), {} accepted; {} wheel samples collected, {} lost on the bus",
        summary.attempts,
        summary.accepted,
        summary.wheel_samples,
        summary.lost.iter().sum::<u64>()
    );
    Ok(())
}
