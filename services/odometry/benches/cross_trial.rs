//! Cross-trial outage evaluation on the real WID drives, with parameters from a
//! simple fit of this bench's own (a development stand-in for the calibrator).
//!
//! ```text
//! cargo bench -p odometry --bench cross_trial
//! ```
//!
//! For each WID trial A it fits the odometry parameters on A, then runs
//! `odometry::evaluate` on the other trial B with outages of 30 s and 60 s,
//! for both heading modes, beside the nominal parameters. The fit: Levenberg-
//! Marquardt on the end-position errors of 20 s dead-reckoning stretches
//! started from the truth every 2 s (wheel mode: c_RL, c_RR, track; gyro mode:
//! the mean circumference, gyro bias and scale, keeping c_RL/c_RR from the
//! wheel fit). It uses the truth of trial A: a stand-in for the calibrator,
//! which fits on GNSS instead; the official figures come from the
//! calibrator's JSON (`odometry evaluate --estimate`).
//!
//! Skips with a message when `shared/data/real` is absent.

use nalgebra::{DMatrix, DVector};
use odometry::dead_reckoning::{HeadingMode, OdometerConfig};
use odometry::estimate_file::OdometryParams;
use odometry::evaluate::{evaluate, EvaluateConfig};
use odometry::two_wheel::TwoWheelParams;
use std::path::Path;

const REAL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/real");

fn config(heading: HeadingMode, outage_s: f64, spacing_s: f64) -> EvaluateConfig {
    EvaluateConfig {
        outage_s,
        spacing_s,
        odometer: OdometerConfig {
            heading,
            ..OdometerConfig::default()
        },
        ..EvaluateConfig::default()
    }
}

/// End-position residuals (x and y per stretch) of `params` on `drive`.
fn residuals(drive: &interfaces::drive::Drive, params: &OdometryParams, heading: HeadingMode) -> Option<DVector<f64>> {
    let report = evaluate(drive, params, &config(heading, 20.0, 2.0)).ok()?;
    let mut r = Vec::with_capacity(2 * report.outages.len());
    for o in &report.outages {
        r.push(o.end_m[0] - o.truth_end_m[0]);
        r.push(o.end_m[1] - o.truth_end_m[1]);
    }
    Some(DVector::from_vec(r))
}

/// Levenberg-Marquardt over a parameter vector mapped to `OdometryParams`.
fn fit(
    drive: &interfaces::drive::Drive,
    heading: HeadingMode,
    start: Vec<f64>,
    steps: &[f64],
    to_params: &dyn Fn(&[f64]) -> OdometryParams,
) -> Vec<f64> {
    let mut x = start;
    let mut lambda = 1e-3;
    let Some(mut r) = residuals(drive, &to_params(&x), heading) else {
        return x;
    };
    for _ in 0..30 {
        let mut jac = DMatrix::<f64>::zeros(r.len(), x.len());
        for j in 0..x.len() {
            let mut xp = x.clone();
            xp[j] += steps[j];
            let Some(rp) = residuals(drive, &to_params(&xp), heading) else {
                return x;
            };
            jac.set_column(j, &((rp - &r) / steps[j]));
        }
        let jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * &r;
        let mut improved = false;
        for _ in 0..10 {
            let mut a = jtj.clone();
            for i in 0..x.len() {
                a[(i, i)] *= 1.0 + lambda;
            }
            let Some(delta) = a.lu().solve(&(-&jtr)) else {
                break;
            };
            let xn: Vec<f64> = x.iter().zip(delta.iter()).map(|(a, d)| a + d).collect();
            if let Some(rn) = residuals(drive, &to_params(&xn), heading) {
                if rn.norm_squared() < r.norm_squared() {
                    x = xn;
                    r = rn;
                    lambda = (lambda * 0.3).max(1e-9);
                    improved = true;
                    break;
                }
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    x
}

fn fitted_params(drive: &interfaces::drive::Drive) -> OdometryParams {
    let nominal = OdometryParams::nominal(&drive.vehicle);
    let wheel_params = |v: &[f64]| OdometryParams {
        two_wheel: TwoWheelParams {
            c_rl: v[0],
            c_rr: v[1],
            track_width: v[2],
        },
        ..nominal
    };
    let c = nominal.two_wheel.c_rl;
    let w = fit(
        drive,
        HeadingMode::WheelDifference,
        vec![c, c, nominal.two_wheel.track_width],
        &[1e-4, 1e-4, 1e-4],
        &wheel_params,
    );
    let ratio = w[1] / w[0];
    let gyro_params = |v: &[f64]| OdometryParams {
        two_wheel: TwoWheelParams {
            c_rl: 2.0 * v[0] / (1.0 + ratio),
            c_rr: 2.0 * v[0] * ratio / (1.0 + ratio),
            track_width: w[2],
        },
        gyro_bias_rad_s: v[1],
        gyro_scale: v[2],
    };
    let g = fit(
        drive,
        HeadingMode::Gyro,
        vec![0.5 * (w[0] + w[1]), 0.0, 0.0],
        &[1e-4, 1e-6, 1e-4],
        &gyro_params,
    );
    gyro_params(&g)
}

fn main() {
    let root = Path::new(REAL);
    if !root.join("wid-trial02").is_dir() || !root.join("wid-trial04").is_dir() {
        eprintln!("skipping: {} not found", root.display());
        return;
    }
    let load = |name: &str| match sensor_bridge::read_drive(&root.join(name)) {
        Ok(loaded) => Some(loaded.drive),
        Err(e) => {
            eprintln!("cannot read {name}: {e}");
            None
        }
    };
    let (Some(t02), Some(t04)) = (load("wid-trial02"), load("wid-trial04")) else {
        return;
    };
    let trials = [("wid-trial02", &t02), ("wid-trial04", &t04)];
    let fits: Vec<OdometryParams> = trials.iter().map(|(_, d)| fitted_params(d)).collect();
    for ((name, _), p) in trials.iter().zip(&fits) {
        println!("fit on {name}: {p}");
    }
    println!();
    println!("| fitted on | evaluated on | parameters | heading | outage s | outages | median m | p90 m | median % |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for (i, (eval_name, eval_drive)) in trials.iter().enumerate() {
        let other = 1 - i;
        let candidates = [
            ("nominal", trials[other].0, OdometryParams::nominal(&eval_drive.vehicle)),
            ("bench fit", trials[other].0, fits[other]),
        ];
        for (label, fit_name, params) in candidates {
            for heading in [HeadingMode::WheelDifference, HeadingMode::Gyro] {
                for outage in [30.0, 60.0] {
                    match evaluate(eval_drive, &params, &config(heading, outage, 10.0)) {
                        Ok(r) => println!(
                            "| {} | {eval_name} | {label} | {heading} | {outage} | {} | {:.3} | {:.3} | {} |",
                            if label == "nominal" { "-" } else { fit_name },
                            r.outages.len(),
                            r.median_error_m,
                            r.p90_error_m,
                            r.median_error_pct.map_or("-".to_string(), |p| format!("{p:.2}"))
                        ),
                        Err(e) => println!("| {fit_name} | {eval_name} | {label} | {heading} | {outage} | error: {e} |"),
                    }
                }
            }
        }
    }
}
