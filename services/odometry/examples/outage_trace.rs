//! Dead-reckon the outages of `odometry evaluate` and print their tracks
//! beside the truth, as CSV (a diagnosis aid).
//!
//! ```text
//! cargo run --release -p odometry --example outage_trace -- DRIVE OUTAGE_S [gyro|wheels] [EST.json] [T_START]
//! ```
//!
//! Columns: outage start, t_s, dead-reckoned x, y, truth x, y, error. With
//! T_START only the outage starting there.

use anyhow::{bail, Context, Result};
use odometry::dead_reckoning::{HeadingMode, OdometerConfig};
use odometry::evaluate::{evaluate, EvaluateConfig};
use std::path::PathBuf;
use vehicle_model::estimate::OdometryParams;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        bail!("usage: outage_trace DRIVE OUTAGE_S [gyro|wheels] [EST.json] [T_START]");
    }
    let drive = drive_io::read_drive(&PathBuf::from(&args[0]))?.drive;
    let outage_s: f64 = args[1].parse().context("OUTAGE_S")?;
    let heading: HeadingMode = match args.get(2) {
        Some(h) => h.parse().map_err(anyhow::Error::msg)?,
        None => HeadingMode::Gyro,
    };
    let params = match args.get(3).filter(|p| p.as_str() != "-") {
        Some(p) => drive_io::read_estimate(&PathBuf::from(p))?.params,
        None => OdometryParams::nominal(&drive.vehicle),
    };
    let only: Option<f64> = args
        .get(4)
        .map(|t| t.parse())
        .transpose()
        .context("T_START")?;
    let config = EvaluateConfig {
        outage_s,
        odometer: OdometerConfig {
            heading,
            ..OdometerConfig::default()
        },
        keep_tracks: true,
        ..EvaluateConfig::default()
    };
    let report = evaluate(&drive, &params, &config)?;
    println!("t_start_s,t_s,dr_x,dr_y,truth_x,truth_y,error_m,yaw_source");
    for o in &report.outages {
        if only.is_some_and(|t| (t - o.t_start_s).abs() > 0.5) {
            continue;
        }
        for p in &o.track {
            println!(
                "{:.2},{:.2},{:.3},{:.3},{:.3},{:.3},{:.3},{}",
                o.t_start_s,
                p.t_s,
                p.dead_reckoned_m[0],
                p.dead_reckoned_m[1],
                p.truth_m[0],
                p.truth_m[1],
                (p.dead_reckoned_m[0] - p.truth_m[0]).hypot(p.dead_reckoned_m[1] - p.truth_m[1]),
                o.start_yaw_source
            );
        }
    }
    Ok(())
}
