//! Heading diagnosis: gyro-integrated yaw, wheel-difference yaw and the truth
//! course (finite difference over about 1 s), as CSV.
//!
//! ```text
//! cargo run --release -p odometry --example heading_trace -- DRIVE [EST.json]
//! ```

use anyhow::{bail, Result};
use odometry::dead_reckoning::{DeadReckoner, HeadingMode, OdometerConfig};
use odometry::inputs::{drive_inputs, Input};
use std::path::PathBuf;
use vehicle_model::estimate::OdometryParams;
use vehicle_model::two_wheel::{wrap_angle, Pose2};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        bail!("usage: heading_trace DRIVE [EST.json]");
    };
    let drive = drive_io::read_drive(&PathBuf::from(path))?.drive;
    let params = match args.get(1) {
        Some(p) => drive_io::read_estimate(&PathBuf::from(p))?.params,
        None => OdometryParams::nominal(&drive.vehicle),
    };
    let truth = drive.truth.clone().unwrap_or_default();
    let course_at = |t: f64| -> Option<(f64, f64)> {
        let a = truth.iter().rev().find(|r| r.t_s <= t - 0.5)?;
        let b = truth.iter().find(|r| r.t_s >= t + 0.5)?;
        let (dx, dy) = (b.x_m - a.x_m, b.y_m - a.y_m);
        let v = dx.hypot(dy) / (b.t_s - a.t_s);
        (v > 1.0).then(|| (dy.atan2(dx), v))
    };
    let mk = |h| {
        DeadReckoner::new(
            params,
            OdometerConfig {
                heading: h,
                ..OdometerConfig::default()
            },
            Pose2::default(),
        )
    };
    let (mut gyro, mut wheels) = (mk(HeadingMode::Gyro), mk(HeadingMode::WheelDifference));
    println!("t_s,gyro_yaw,wheel_yaw,truth_course,speed");
    let mut offset: Option<f64> = None;
    for input in drive_inputs(&drive)? {
        match input {
            Input::Imu { t_s, gz_rad_s } => gyro.gyro(t_s, gz_rad_s)?,
            Input::Wheels {
                t_s,
                rl_rev,
                rr_rev,
            } => {
                let g = gyro.wheels(t_s, rl_rev, rr_rev)?;
                let w = wheels.wheels(t_s, rl_rev, rr_rev)?;
                if (t_s * 100.0).round() as i64 % 50 == 0 {
                    if let Some((c, v)) = course_at(t_s) {
                        let off = *offset.get_or_insert(c - g.yaw);
                        println!(
                            "{t_s:.2},{:.4},{:.4},{:.4},{v:.2}",
                            g.yaw + off,
                            w.yaw + off,
                            g.yaw + off + wrap_angle(c - g.yaw - off)
                        );
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}
