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
use odometry::evaluate::{evaluate, EvaluateConfig, TruthPoint, TruthPointSource};
use vehicle_model::estimate::OdometryParams;
use vehicle_model::two_wheel::TwoWheelParams;

fn config(heading: HeadingMode, outage_s: f64, spacing_s: f64, arm: [f64; 2]) -> EvaluateConfig {
    EvaluateConfig {
        outage_s,
        spacing_s,
        odometer: OdometerConfig {
            heading,
            ..OdometerConfig::default()
        },
        truth_point: TruthPoint {
            point_m: arm,
            source: TruthPointSource::Given,
        },
        ..EvaluateConfig::default()
    }
}

type Model = (OdometryParams, [f64; 2]);

/// End-position residuals (x and y per stretch) of `params` on `drive`.
fn residuals(
    drive: &interfaces::drive::Drive,
    model: &Model,
    heading: HeadingMode,
) -> Option<DVector<f64>> {
    let report = evaluate(drive, &model.0, &config(heading, 20.0, 2.0, model.1)).ok()?;
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
    to_params: &dyn Fn(&[f64]) -> Model,
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

fn fitted_model(drive: &interfaces::drive::Drive, fit_arm: bool) -> Model {
    let nominal = OdometryParams::nominal(&drive.vehicle);
    let arm = |v: &[f64], k: usize| {
        if fit_arm {
            [v[k], v[k + 1]]
        } else {
            [0.0, 0.0]
        }
    };
    let wheel_model = |v: &[f64]| {
        (
            OdometryParams {
                two_wheel: TwoWheelParams {
                    c_rl: v[0],
                    c_rr: v[1],
                    track_width: v[2],
                },
                ..nominal
            },
            arm(v, 3),
        )
    };
    let c = nominal.two_wheel.c_rl;
    let mut start = vec![c, c, nominal.two_wheel.track_width];
    let mut steps = vec![1e-4, 1e-4, 1e-4];
    if fit_arm {
        start.extend([0.0, 0.0]);
        steps.extend([1e-3, 1e-3]);
    }
    let w = fit(
        drive,
        HeadingMode::WheelDifference,
        start,
        &steps,
        &wheel_model,
    );
    let ratio = w[1] / w[0];
    let gyro_model = |v: &[f64]| {
        (
            OdometryParams {
                two_wheel: TwoWheelParams {
                    c_rl: 2.0 * v[0] / (1.0 + ratio),
                    c_rr: 2.0 * v[0] * ratio / (1.0 + ratio),
                    track_width: w[2],
                },
                gyro_bias_rad_s: v[1],
                gyro_scale: v[2],
            },
            arm(v, 3),
        )
    };
    let mut start = vec![0.5 * (w[0] + w[1]), 0.0, 0.0];
    let mut steps = vec![1e-4, 1e-6, 1e-4];
    if fit_arm {
        start.extend([w[3], w[4]]);
        steps.extend([1e-3, 1e-3]);
    }
    let g = fit(drive, HeadingMode::Gyro, start, &steps, &gyro_model);
    gyro_model(&g)
}

fn main() {
    let root_dir = drive_io::dev_data::real_data_dir();
    let root = root_dir.as_path();
    if !root.join("wid-trial02").is_dir() || !root.join("wid-trial04").is_dir() {
        eprintln!("skipping: {} not found", root.display());
        return;
    }
    let load = |name: &str| match drive_io::read_drive(&root.join(name)) {
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
    // FIT_ARM=1 also fits the truth point (the RTK antenna) in the body frame.
    let fit_arm = std::env::var("FIT_ARM").is_ok_and(|v| v == "1");
    let fits: Vec<Model> = trials
        .iter()
        .map(|(_, d)| fitted_model(d, fit_arm))
        .collect();
    for ((name, _), (p, arm)) in trials.iter().zip(&fits) {
        println!("fit on {name}: {p} truth point {arm:?}");
    }
    println!();
    println!("| fitted on | evaluated on | parameters | heading | outage s | outages | median m | p90 m | median % |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for (i, (eval_name, eval_drive)) in trials.iter().enumerate() {
        let nominal = (OdometryParams::nominal(&eval_drive.vehicle), [0.0, 0.0]);
        let candidates = [
            ("nominal", "-", nominal),
            ("bench fit", trials[1 - i].0, fits[1 - i]),
            ("bench fit (same trial)", trials[i].0, fits[i]),
        ];
        for (label, fit_name, model) in candidates {
            for heading in [HeadingMode::WheelDifference, HeadingMode::Gyro] {
                for outage in [30.0, 60.0] {
                    match evaluate(eval_drive, &model.0, &config(heading, outage, 10.0, model.1)) {
                        Ok(r) => println!(
                            "| {fit_name} | {eval_name} | {label} | {heading} | {outage} | {} | {:.3} | {:.3} | {} |",
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
