//! The WID cross-trial figures as a test: each trial calibrated with the
//! defaults (`calibrator calibrate A --json`), read back as the odometry
//! reads the estimate, and the other trial dead-reckoned through 30 s and
//! 60 s GNSS outages with the gyro's heading as `odometry evaluate B
//! --estimate A.json --outage N --heading gyro` does (scored at the
//! antenna the calibration of A found). The goal of BENCHMARKS.md (at most
//! 0.5 m after 30 s, 2 m after 60 s, medians) holds in three of the four
//! cells; the fourth (trial04 -> trial02 after 30 s, 0.64 m) is held to
//! where it stands with a margin, so that a change in the calibration that
//! moves a poorly determined fit elsewhere is caught here and not only by
//! `cargo bench -p integration-tests --bench cross_trial` (a rigid
//! placement of the fit's segment starts once moved trial04's gyro terms
//! and the 60 s cell from 1.55 to 3.50 m). Skipped with a message when
//! `../shared/data/real` is absent.

use calibrator::{calibrate, CalibrationConfig};
use integration_tests::outages::as_estimate;
use odometry::dead_reckoning::{HeadingMode, OdometerConfig};
use odometry::evaluate::{choose_truth_point, evaluate, EvaluateConfig, TruthPointChoice};

#[test]
fn one_wid_trial_calibrates_the_other_within_the_goal() {
    let (Some(p02), Some(p04)) = (
        drive_io::dev_data::real_drive("wid-trial02"),
        drive_io::dev_data::real_drive("wid-trial04"),
    ) else {
        return;
    };
    let drives = [p02, p04].map(|p| drive_io::read_drive(&p).expect("read").drive);
    let estimates = drives.each_ref().map(|d| {
        let cal = calibrate(d, &CalibrationConfig::default()).expect("calibrated");
        as_estimate(&cal, "calibration").expect("estimate")
    });
    // (calibrated on, evaluated on, outage s, the median's bound m).
    let cells = [
        (0, 1, 30.0, 0.5),
        (0, 1, 60.0, 2.0),
        (1, 0, 30.0, 0.75),
        (1, 0, 60.0, 2.0),
    ];
    for (i, j, outage_s, bound) in cells {
        let point = choose_truth_point(&drives[j], TruthPointChoice::Auto, estimates[i].antenna_m)
            .expect("truth point");
        let config = EvaluateConfig {
            outage_s,
            odometer: OdometerConfig {
                heading: HeadingMode::Gyro,
                ..OdometerConfig::default()
            },
            truth_point: point,
            ..EvaluateConfig::default()
        };
        let report = evaluate(&drives[j], &estimates[i].params, &config).expect("evaluated");
        assert!(
            report.outages.len() >= 5,
            "{i} -> {j}: only {} outages",
            report.outages.len()
        );
        assert!(
            report.median_error_m <= bound,
            "calibrated on trial {i}, evaluated on trial {j}, {outage_s} s outages: median {:.2} m > {bound} m",
            report.median_error_m
        );
    }
}
