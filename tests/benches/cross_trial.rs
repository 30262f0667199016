//! The official cross-trial figures on the real WID drives: exactly what a
//! user does with the two command-line tools.
//!
//! ```text
//! cargo bench -p calibrator --bench cross_trial [-- DATA_DIR]
//! ```
//!
//! For each WID trial A: calibrate A with `CalibrationConfig::default()` (what
//! `calibrator calibrate A --json EST.json` runs), write the calibration as
//! the CLI's JSON and read it back with `vehicle_model::estimate::Estimate`
//! (what `odometry evaluate --estimate EST.json` reads), then evaluate the
//! other trial B with `odometry::evaluate` and the CLI's default
//! `EvaluateConfig` (outages every 10 s, pose from the truth before the
//! outage, error at its end) for 30 s and 60 s outages and both heading
//! modes, beside the nominal `vehicle.toml` values and a scale-only fit
//! (one common circumference: GNSS reference distance over wheel
//! revolutions, nominal track, an ideal gyro). The same numbers come from
//!
//! ```text
//! calibrator calibrate DATA/wid-trial02 --json cal02.json
//! odometry evaluate DATA/wid-trial04 --estimate cal02.json --outage 30 --heading gyro
//! ```
//!
//! (and likewise for each row). Skips with a message when the data folder is
//! absent. Default data folder: `../shared/data/real` beside the workspace.

use anyhow::{Context, Result};
use calibrator::{calibrate, Calibration, CalibrationConfig};
use interfaces::drive::Drive;
use odometry::dead_reckoning::{HeadingMode, OdometerConfig};
use odometry::evaluate::{
    choose_truth_point, evaluate, EvaluateConfig, TruthPoint, TruthPointChoice, TruthPointSource,
};
use std::path::{Path, PathBuf};
use vehicle_model::estimate::{Estimate, OdometryParams};
use vehicle_model::two_wheel::TwoWheelParams;

const TRIALS: [&str; 2] = ["wid-trial02", "wid-trial04"];

fn load(dir: &Path, name: &str) -> Result<Drive> {
    Ok(drive_io::read_drive(&dir.join(name))
        .with_context(|| format!("reading {name}"))?
        .drive)
}

/// The calibration as `odometry evaluate --estimate` sees it: through the
/// CLI's JSON text.
fn as_estimate(cal: &Calibration, name: &str) -> Result<Estimate> {
    let text = serde_json::to_string_pretty(cal).context("encoding the calibration")?;
    Ok(Estimate::from_json_str(&text, name)?)
}

/// Common scale only: GNSS reference distance over mean rear wheel revolutions.
fn scale_only(drive: &Drive) -> Result<f64> {
    let config = CalibrationConfig::default();
    let a = calibrator::clocks::align_offsets(calibrator::check::drive(drive, &config)?, &config)?;
    let mut w = a.warnings.clone();
    let r = calibrator::reference::build(&a, &config, &mut w)?;
    let p = &a.series;
    let (mut dist, mut revs) = (0.0, 0.0);
    for k in 1..p.len() {
        if r.valid[k] && r.valid[k - 1] && !p.is_piece_start(k) {
            dist += (r.x[k] - r.x[k - 1]).hypot(r.y[k] - r.y[k - 1]);
            revs += 0.5 * (p.dn_rl[k] + p.dn_rr[k]);
        }
    }
    Ok(dist / revs)
}

fn params(c_rl: f64, c_rr: f64, track_width: f64) -> OdometryParams {
    OdometryParams {
        two_wheel: TwoWheelParams {
            c_rl,
            c_rr,
            track_width,
        },
        gyro_bias_rad_s: 0.0,
        gyro_scale: 0.0,
    }
}

fn main() -> Result<()> {
    let dir = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with('-'))
        .map(PathBuf::from)
        .unwrap_or_else(drive_io::dev_data::real_data_dir);
    if !TRIALS.iter().all(|t| dir.join(t).exists()) {
        eprintln!(
            "cross_trial skipped: the WID drives are not under {}",
            dir.display()
        );
        return Ok(());
    }
    let drives: Vec<Drive> = TRIALS
        .iter()
        .map(|t| load(&dir, t))
        .collect::<Result<_>>()?;

    let mut estimates = Vec::new();
    for (name, drive) in TRIALS.iter().zip(&drives) {
        let cal = calibrate(drive, &CalibrationConfig::default())
            .with_context(|| format!("calibrating {name}"))?;
        let full = as_estimate(&cal, name)?;
        let est = full.params;
        println!(
            "{name}: c_RL {:.5} c_RR {:.5} m (sigma mean {:.2} mm, difference {:.2} mm), track {:.4} m{}, gyro bias {:+.2e} rad/s scale {:+.5}, GNSS residual {:.3} m",
            est.two_wheel.c_rl,
            est.two_wheel.c_rr,
            1000.0 * cal.sigma_m.mean.unwrap_or(f64::NAN),
            1000.0 * cal.sigma_m.difference.unwrap_or(f64::NAN),
            est.two_wheel.track_width,
            if cal.track_width_estimated { " (estimated)" } else { " (nominal)" },
            est.gyro_bias_rad_s,
            est.gyro_scale,
            cal.diagnostics.residual_rms_m.unwrap_or(f64::NAN),
        );
        for w in &cal.warnings {
            println!("  warning [{:?}]: {}", w.code, w.message);
        }
        println!(
            "  antenna (wheel + gyro model): {:?} m",
            full.antenna_m.map(|a| [
                (a[0] * 1000.0).round() / 1000.0,
                (a[1] * 1000.0).round() / 1000.0
            ])
        );
        estimates.push(full);
    }
    let antennas: Vec<Option<[f64; 2]>> = estimates.iter().map(|e| e.antenna_m).collect();
    let estimates: Vec<OdometryParams> = estimates.iter().map(|e| e.params).collect();
    let (a, b) = (&estimates[0].two_wheel, &estimates[1].two_wheel);
    println!(
        "agreement (trial02 - trial04): c_RL {:+.2} mm, c_RR {:+.2} mm, mean {:+.2} mm ({:+.3} %), difference {:+.2} mm, track {:+.1} mm, gyro scale {:+.5}",
        1000.0 * (a.c_rl - b.c_rl),
        1000.0 * (a.c_rr - b.c_rr),
        500.0 * (a.c_rl + a.c_rr - b.c_rl - b.c_rr),
        100.0 * (a.c_rl + a.c_rr - b.c_rl - b.c_rr) / (b.c_rl + b.c_rr),
        1000.0 * ((a.c_rr - a.c_rl) - (b.c_rr - b.c_rl)),
        1000.0 * (a.track_width - b.track_width),
        estimates[0].gyro_scale - estimates[1].gyro_scale,
    );
    println!();
    println!("Scored where `odometry evaluate` scores by default (`--truth-point auto`): the WID truth.csv");
    println!("is the GNSS track itself (every fix's row coincides with it), so it follows the antenna, and");
    println!("the score is at the antenna position the calibration of the other trial found. The nominal and");
    println!("scale-only rows are scored at that same point (`--truth-point X,Y`), so the columns compare");
    println!(
        "like with like. One column scores the calibrated run at the rear-axle centre instead"
    );
    println!("(`--truth-point axle`): against an antenna track that adds the lever arm. The last column keeps");
    println!("the calibrated gyro bias instead of measuring it at standstill (`--no-standstill-gyro-bias`).");
    println!();
    println!("| calibrated on → evaluated on | heading | outage | nominal | scale-only | calibrated | calibrated, scored at the rear axle | calibrated, gyro bias kept |");
    println!("|---|---|---|---|---|---|---|---|");
    let mut goal = Vec::new();
    for (i, j) in [(0usize, 1usize), (1, 0)] {
        let v = &drives[i].vehicle;
        let scale = scale_only(&drives[i])?;
        let sets = [
            params(
                v.nominal_circumference_m,
                v.nominal_circumference_m,
                v.track_width_m,
            ),
            params(scale, scale, v.track_width_m),
            estimates[i],
        ];
        // What `odometry evaluate B --estimate cal_A.json` scores at.
        let point = choose_truth_point(&drives[j], TruthPointChoice::Auto, antennas[i])?;
        for heading in [HeadingMode::WheelDifference, HeadingMode::Gyro] {
            for outage_s in [30.0, 60.0] {
                // The CLI's configuration (`odometry evaluate --outage N --heading H`).
                let config = EvaluateConfig {
                    outage_s,
                    odometer: OdometerConfig {
                        heading,
                        ..OdometerConfig::default()
                    },
                    truth_point: point,
                    ..EvaluateConfig::default()
                };
                let axle_config = EvaluateConfig {
                    truth_point: TruthPoint::AXLE,
                    ..config
                };
                let kept_bias_config = EvaluateConfig {
                    odometer: OdometerConfig {
                        learn_gyro_bias: false,
                        ..config.odometer
                    },
                    ..config
                };
                let mut cells = Vec::new();
                let runs = [
                    (&sets[0], &config),
                    (&sets[1], &config),
                    (&sets[2], &config),
                    (&sets[2], &axle_config),
                    (&sets[2], &kept_bias_config),
                ];
                for (k, (prm, cfg)) in runs.into_iter().enumerate() {
                    let cell = match evaluate(&drives[j], prm, cfg) {
                        Ok(rep) => {
                            if (k == 2 || k == 3) && heading == HeadingMode::Gyro {
                                goal.push((i, j, outage_s, rep.truth_point, rep.median_error_m));
                            }
                            format!(
                                "{:.2} m (p90 {:.2} m, {})",
                                rep.median_error_m,
                                rep.p90_error_m,
                                rep.median_error_pct
                                    .map_or("-".to_string(), |p| format!("{p:.2} %"))
                            )
                        }
                        Err(e) => format!("error: {e}"),
                    };
                    cells.push(cell);
                }
                println!(
                    "| {} → {} | {heading} | {outage_s:.0} s | {} |",
                    TRIALS[i],
                    TRIALS[j],
                    cells.join(" | ")
                );
            }
        }
    }
    println!();
    println!("goal (gyro heading, calibrated, median): <= 0.5 m after 30 s, <= 2 m after 60 s");
    for (i, j, outage_s, point, median) in goal {
        let limit = if outage_s < 45.0 { 0.5 } else { 2.0 };
        let [x, y] = point.point_m;
        println!(
            "  {} → {} {outage_s:.0} s, scored at {}: {median:.2} m {}",
            TRIALS[i],
            TRIALS[j],
            match point.source {
                TruthPointSource::Axle => "the rear axle".to_string(),
                _ => format!("the antenna ({x:+.2}, {y:+.2}) m, the CLI default"),
            },
            if median <= limit { "met" } else { "MISSED" }
        );
    }
    Ok(())
}
