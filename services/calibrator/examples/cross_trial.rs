//! Real drives: calibrate on one WID trial, dead-reckon the other through
//! GNSS outages (odometry::evaluate), and the comma2k19 common scale against
//! its truth.
//!
//! `cargo run --release -p calibrator --example cross_trial [DATA_DIR]`
//! (default `../shared/data/real` from the workspace root).

use anyhow::{Context, Result};
use calibrator::{calibrate, CalibrationConfig, Method};
use interfaces::drive::Drive;
use odometry::dead_reckoning::{HeadingMode, OdometerConfig};
use odometry::estimate_file::OdometryParams;
use odometry::evaluate::{evaluate, EvaluateConfig};
use odometry::two_wheel::TwoWheelParams;
use std::path::PathBuf;

fn load(dir: &std::path::Path, name: &str) -> Result<Drive> {
    Ok(sensor_bridge::read_drive(&dir.join(name))
        .with_context(|| format!("reading {name}"))?
        .drive)
}

/// Common scale only: reference distance over mean wheel revolutions.
fn scale_only(drive: &Drive) -> Result<f64> {
    let config = CalibrationConfig::default();
    let mut w = Vec::new();
    let p = calibrator::prep::prepare(drive, &config, &mut w)?;
    let r = calibrator::reference::build(&p, drive, &config, &mut w)?;
    let (mut dist, mut revs) = (0.0, 0.0);
    for k in 1..p.len() {
        if r.valid[k] && r.valid[k - 1] && !p.is_piece_start(k) {
            dist += (r.x[k] - r.x[k - 1]).hypot(r.y[k] - r.y[k - 1]);
            revs += 0.5 * (p.dn_rl[k] + p.dn_rr[k]);
        }
    }
    Ok(dist / revs)
}

fn params(c_rl: f64, c_rr: f64, track: f64, bias: f64, scale: f64) -> OdometryParams {
    OdometryParams {
        two_wheel: TwoWheelParams {
            c_rl,
            c_rr,
            track_width: track,
        },
        gyro_bias_rad_s: bias,
        gyro_scale: scale,
    }
}

fn main() -> Result<()> {
    let dir = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../../shared/data/real"
            ))
        });
    if !dir.exists() {
        eprintln!("skipped: {} does not exist", dir.display());
        return Ok(());
    }
    let trials = ["wid-trial02", "wid-trial04"];
    let drives: Vec<Drive> = trials
        .iter()
        .map(|t| load(&dir, t))
        .collect::<Result<_>>()?;
    let mut estimates = Vec::new();
    for (name, d) in trials.iter().zip(&drives) {
        for method in [Method::Batch, Method::Paper] {
            let cal = calibrate(
                d,
                &CalibrationConfig {
                    method,
                    ..CalibrationConfig::default()
                },
            )?;
            println!(
                "{name} {method}: c_RL {:.5} (sigma {:.2} mm) c_RR {:.5} (sigma {:.2} mm) track {:.4} gyro bias {:?} scale {:?}",
                cal.circumference_m.rl,
                1000.0 * cal.sigma_m.rl.unwrap_or(f64::NAN),
                cal.circumference_m.rr,
                1000.0 * cal.sigma_m.rr.unwrap_or(f64::NAN),
                cal.track_width_m,
                cal.gyro_bias_rad_s,
                cal.gyro_scale
            );
            if method == Method::Batch {
                estimates.push(cal);
            }
        }
    }
    let (a, b) = (&estimates[0], &estimates[1]);
    println!(
        "cross-trial agreement (batch): c_RL {:+.2} mm, c_RR {:+.2} mm, mean {:+.2} mm, difference {:+.2} mm, track {:+.1} mm",
        1000.0 * (a.circumference_m.rl - b.circumference_m.rl),
        1000.0 * (a.circumference_m.rr - b.circumference_m.rr),
        500.0 * (a.circumference_m.rl + a.circumference_m.rr - b.circumference_m.rl - b.circumference_m.rr),
        1000.0 * ((a.circumference_m.rr - a.circumference_m.rl) - (b.circumference_m.rr - b.circumference_m.rl)),
        1000.0 * (a.track_width_m - b.track_width_m)
    );
    println!();
    println!("| calibrated on | evaluated on | parameters | heading | outage | median error | p90 error | median % of distance |");
    println!("|---|---|---|---|---|---|---|---|");
    for (i, j) in [(0usize, 1usize), (1, 0)] {
        let cal = &estimates[i];
        let target = &drives[j];
        let v = &drives[i].vehicle;
        let scale = scale_only(&drives[i])?;
        let sets = [
            (
                "nominal",
                params(
                    v.nominal_circumference_m,
                    v.nominal_circumference_m,
                    v.track_width_m,
                    0.0,
                    0.0,
                ),
            ),
            (
                "scale-only",
                params(scale, scale, v.track_width_m, 0.0, 0.0),
            ),
            (
                "calibrated",
                params(
                    cal.circumference_m.rl,
                    cal.circumference_m.rr,
                    cal.track_width_m,
                    cal.gyro_bias_rad_s.unwrap_or(0.0),
                    cal.gyro_scale.unwrap_or(0.0),
                ),
            ),
        ];
        for heading in [HeadingMode::WheelDifference, HeadingMode::Gyro] {
            for outage in [30.0, 60.0] {
                for (label, prm) in &sets {
                    let config = EvaluateConfig {
                        outage_s: outage,
                        odometer: OdometerConfig {
                            heading,
                            ..OdometerConfig::default()
                        },
                        ..EvaluateConfig::default()
                    };
                    match evaluate(target, prm, &config) {
                        Ok(rep) => println!(
                            "| {} | {} | {label} | {heading} | {outage:.0} s | {:.2} m | {:.2} m | {} |",
                            trials[i],
                            trials[j],
                            rep.median_error_m,
                            rep.p90_error_m,
                            rep.median_error_pct.map_or("-".to_string(), |p| format!("{p:.2} %"))
                        ),
                        Err(e) => println!("| {} | {} | {label} | {heading} | {outage:.0} s | {e} | | |", trials[i], trials[j]),
                    }
                }
            }
        }
    }
    // comma2k19: the common scale against its truth.
    let comma = load(&dir, "comma2k19-seg40")?;
    let cal = calibrate(&comma, &CalibrationConfig::default())?;
    let truth = comma.truth.as_ref().context("comma truth")?;
    let revs = comma.wheel_revolutions()?;
    let (t0, t1) = (
        truth[0].t_s.max(revs[0].t_s),
        truth[truth.len() - 1].t_s.min(revs[revs.len() - 1].t_s),
    );
    let mut len = 0.0;
    for w in truth.windows(2) {
        if w[0].t_s >= t0 && w[1].t_s <= t1 {
            len += (w[1].x_m - w[0].x_m).hypot(w[1].y_m - w[0].y_m);
        }
    }
    let at = |t: f64| {
        let i = revs.partition_point(|r| r.t_s < t).min(revs.len() - 1);
        0.5 * (revs[i].rl + revs[i].rr)
    };
    let truth_scale = len / (at(t1) - at(t0));
    let mean = 0.5 * (cal.circumference_m.rl + cal.circumference_m.rr);
    println!();
    println!(
        "comma2k19-seg40: calibrated mean circumference {mean:.5} m (sigma {:.2} mm) vs truth-track scale {truth_scale:.5} m: {:+.2} mm ({:+.3} %)",
        1000.0 * cal.sigma_m.mean.unwrap_or(f64::NAN),
        1000.0 * (mean - truth_scale),
        100.0 * (mean - truth_scale) / truth_scale
    );
    for w in &cal.warnings {
        println!("  comma warning: {}", w.message);
    }
    Ok(())
}
