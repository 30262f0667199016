//! Dead-reckon one outage and print the track beside the truth, as CSV.
//!
//! ```text
//! cargo run --release -p odometry --example outage_trace -- DRIVE T_START LENGTH [gyro|wheels] [EST.json]
//! ```
//!
//! Columns: t_s, dead-reckoned x, y, yaw, truth x, y (interpolated), distance
//! between them. A diagnosis aid for `odometry evaluate`.

use anyhow::{bail, Context, Result};
use odometry::dead_reckoning::{HeadingMode, OdometerConfig};
use odometry::estimate_file::{Estimate, OdometryParams};
use odometry::evaluate::{evaluate, EvaluateConfig};
use std::path::PathBuf;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        bail!("usage: outage_trace DRIVE T_START LENGTH [gyro|wheels] [EST.json]");
    }
    let drive = sensor_bridge::read_drive(&PathBuf::from(&args[0]))?.drive;
    let t_start: f64 = args[1].parse().context("T_START")?;
    let length: f64 = args[2].parse().context("LENGTH")?;
    let heading: HeadingMode = match args.get(3) {
        Some(h) => h.parse().map_err(anyhow::Error::msg)?,
        None => HeadingMode::Gyro,
    };
    let params = match args.get(4) {
        Some(p) => Estimate::load(&PathBuf::from(p))?.params,
        None => OdometryParams::nominal(&drive.vehicle),
    };
    // Shift the drive so that the evaluation's first outage starts at T_START,
    // then trace with growing outage lengths.
    let mut cut = drive.clone();
    cut.wheels.samples.retain(|s| s.t_s >= t_start);
    if let Some(t) = cut.truth.as_mut() {
        t.retain(|s| s.t_s >= t_start - 10.0);
    }
    println!("t_s,dr_x,dr_y,truth_x,truth_y,error_m,start_yaw");
    let steps = (length / 0.5).round() as usize;
    for k in 1..=steps {
        let outage = k as f64 * 0.5;
        let config = EvaluateConfig {
            outage_s: outage,
            spacing_s: 1e9,
            odometer: OdometerConfig {
                heading,
                ..OdometerConfig::default()
            },
            ..EvaluateConfig::default()
        };
        let report = evaluate(&cut, &params, &config)?;
        let o = &report.outages[0];
        println!(
            "{:.2},{:.3},{:.3},{:.3},{:.3},{:.3},{:.4}",
            o.t_start_s + outage,
            o.end_m[0],
            o.end_m[1],
            o.truth_end_m[0],
            o.truth_end_m[1],
            o.error_m,
            o.start_yaw_rad
        );
    }
    Ok(())
}
