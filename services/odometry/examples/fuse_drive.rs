//! Run the service's filter offline over a drive and summarise it: modes,
//! gated fixes, and the position error against truth.csv where there is one.
//!
//! ```text
//! cargo run --release -p odometry --example fuse_drive -- DRIVE [gyro|wheels] [EST.json]
//! ```

use anyhow::{bail, Result};
use interfaces::wire::PoseMode;
use odometry::dead_reckoning::{HeadingMode, OdometerConfig};
use odometry::estimate_file::Estimate;
use odometry::fusion::{Fusion, FusionConfig};
use odometry::inputs::drive_inputs;
use std::path::PathBuf;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        bail!("usage: fuse_drive DRIVE [gyro|wheels] [EST.json]");
    };
    let drive = sensor_bridge::read_drive(&PathBuf::from(path))?.drive;
    let heading: HeadingMode = match args.get(1) {
        Some(h) => h.parse().map_err(anyhow::Error::msg)?,
        None => HeadingMode::Gyro,
    };
    let estimate = args
        .get(2)
        .map(|p| Estimate::load(&PathBuf::from(p)))
        .transpose()?;
    let config = FusionConfig {
        odometer: OdometerConfig {
            heading,
            ..OdometerConfig::default()
        },
        lever_arm_m: [
            drive.vehicle.gnss.antenna_x_m.unwrap_or(0.0),
            drive.vehicle.gnss.antenna_y_m.unwrap_or(0.0),
        ],
        ..FusionConfig::default()
    };
    // Tuning experiments: FUSION_DS (distance noise fraction; FUSION_DS_NOMINAL
    // with the nominal circumferences), FUSION_MINSIG
    // (smallest GNSS sigma, m), FUSION_GYRO (angle random walk, rad/sqrt(s)).
    let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<f64>().ok());
    let mut config = config;
    if let Some(v) = env("FUSION_DS") {
        config.distance_noise_frac = v;
    }
    if let Some(v) = env("FUSION_DS_NOMINAL") {
        config.nominal_distance_noise_frac = v;
    }
    if let Some(v) = env("FUSION_MINSIG") {
        config.min_gnss_sigma_m = v;
    }
    if let Some(v) = env("FUSION_GYRO") {
        config.gyro_noise_rad_per_sqrt_s = v;
    }
    let mut fusion = match &estimate {
        Some(e) => Fusion::new(e.params, 0, config),
        None => Fusion::nominal(&drive.vehicle, config),
    };
    let params = *fusion.params();
    let truth = drive.truth.clone().unwrap_or_default();
    let mut counts = [0usize; 3];
    let mut errors = Vec::new();
    let mut ti = 0usize;
    let verbose = std::env::var("FUSION_VERBOSE").is_ok();
    for input in drive_inputs(&drive)? {
        let before = fusion.stats();
        let out = fusion.process(&input)?;
        let after = fusion.stats();
        if verbose
            && (after.gnss_rejected > before.gnss_rejected
                || after.position_resets > before.position_resets)
        {
            println!(
                "t = {:.2}: fix rejected (resets {})",
                input.t_s(),
                after.position_resets
            );
        }
        if let Some(pose) = out {
            counts[pose.mode as usize] += 1;
            // Error at truth rows (nearest wheel sample within 5 ms).
            while ti < truth.len() && truth[ti].t_s < pose.t_s - 0.005 {
                ti += 1;
            }
            if let Some(r) = truth.get(ti) {
                if (r.t_s - pose.t_s).abs() <= 0.005 && pose.mode != PoseMode::NoFix {
                    errors.push((pose.mode, (pose.pose.x - r.x_m).hypot(pose.pose.y - r.y_m)));
                }
            }
        }
    }
    let s = fusion.stats();
    println!("heading {heading}, parameters {params}");
    println!(
        "poses: NoFix {}, Fused {}, DeadReckoning {}",
        counts[0], counts[1], counts[2]
    );
    println!("{s:?}");
    for mode in [PoseMode::Fused, PoseMode::DeadReckoning] {
        let mut e: Vec<f64> = errors
            .iter()
            .filter(|(m, _)| *m == mode)
            .map(|(_, e)| *e)
            .collect();
        e.sort_by(f64::total_cmp);
        if !e.is_empty() {
            println!(
                "{mode:?}: error vs truth median {:.3} m, p90 {:.3} m, max {:.3} m ({} points)",
                e[e.len() / 2],
                e[(e.len() * 9) / 10],
                e[e.len() - 1],
                e.len()
            );
        }
    }
    Ok(())
}
