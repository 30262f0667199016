//! The odometry's check of the estimate in use against the GNSS fixes
//! (`odometry::fusion::Fusion::take_contradiction`) on the real drives:
//! the calibrator's estimate of each drive is never contradicted, and the
//! same estimate made 7 % too large (issue 35 item 3's plausible lie) is.
//! Skipped with a message when `../shared/data/real` is absent.

use calibrator::{calibrate, CalibrationConfig};
use odometry::dead_reckoning::{HeadingMode, OdometerConfig};
use odometry::fusion::{Contradiction, Fusion, FusionConfig};
use odometry::inputs::drive_inputs;
use vehicle_model::estimate::{gnss_lever_arm, Estimate};

/// Every contradiction the filter reports over the drive, acting on none,
/// and the scale it measured at the end (scale, sigma, distance).
fn contradictions(
    inputs: &[odometry::inputs::Input],
    estimate: &Estimate,
    config: FusionConfig,
) -> (Vec<Contradiction>, Option<(f64, f64, f64)>) {
    let mut fusion = Fusion::new(estimate.params, 1, config);
    fusion.set_effects(estimate.effects.into());
    let mut found = Vec::new();
    for input in inputs {
        // Unusable samples are skipped as the service skips them.
        let _ = fusion.process(input);
        found.extend(fusion.take_contradiction());
    }
    (found, fusion.measured_scale())
}

#[test]
fn the_calibrated_estimate_is_never_contradicted_on_the_real_drives_and_a_lie_is() {
    let mut checked = 0;
    for name in ["wid-trial02", "wid-trial04", "comma2k19-seg40"] {
        let Some(path) = drive_io::dev_data::real_drive(name) else {
            continue;
        };
        let drive = drive_io::read_drive(&path).expect("read").drive;
        let cal = calibrate(&drive, &CalibrationConfig::default()).expect("calibrate");
        let json = serde_json::to_string(&cal).expect("json");
        let estimate = Estimate::from_json_str(&json, name).expect("estimate");
        let inputs = drive_inputs(&drive).expect("inputs");
        let (lever_arm_m, measured) = gnss_lever_arm(&drive.vehicle, Some(&estimate));
        for heading in [HeadingMode::Gyro, HeadingMode::WheelDifference] {
            let config = FusionConfig {
                odometer: OdometerConfig {
                    heading,
                    ..OdometerConfig::default()
                },
                lever_arm_m,
                lever_arm_from_estimates: !measured,
                ..FusionConfig::default()
            };
            let (found, measured_scale) = contradictions(&inputs, &estimate, config);
            let (scale, sigma, distance) = measured_scale.expect("windows closed");
            println!(
                "{name} {heading}: calibrated estimate, fixes measure its scale at {scale:.4} +- \
                 {sigma:.4} over {distance:.0} m; {} contradiction(s)",
                found.len()
            );
            assert!(found.is_empty(), "{name} {heading}: {found:?}");
            let mut lie = estimate;
            lie.params.two_wheel.c_rl *= 1.07;
            lie.params.two_wheel.c_rr *= 1.07;
            let (found, _) = contradictions(&inputs, &lie, config);
            let first = found
                .first()
                .unwrap_or_else(|| panic!("{name}: the lie stands"));
            let t0 = inputs.first().map_or(0.0, |i| i.t_s());
            println!(
                "{name} {heading}: 7 % lie contradicted {:.1} s into the drive: scale {:.4} +- {:.4} \
                 over {:.0} m",
                first.t_s - t0,
                first.measured_scale,
                first.measured_sigma,
                first.distance_m
            );
            assert!(
                (first.measured_scale * 1.07 - scale).abs() < 0.02,
                "{first:?}"
            );
        }
        checked += 1;
    }
    if checked == 0 {
        eprintln!("skipped: no real drive under ../shared/data/real");
    }
}
