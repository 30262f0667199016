//! `odometry evaluate` on the real WID drives (skipped with a message when
//! `shared/data/real` is absent). The figures themselves are measured with
//! the commands in the README; these tests check what the README's choices
//! rest on.

use odometry::dead_reckoning::{HeadingMode, OdometerConfig};
use odometry::evaluate::{
    choose_truth_point, evaluate, truth_gnss_coincidence, truth_is_the_gnss_track, EvaluateConfig,
    EvaluationReport, TruthPoint, TruthPointChoice, TruthPointSource,
};
use vehicle_model::estimate::OdometryParams;

fn run(drive: &interfaces::drive::Drive, heading: HeadingMode) -> EvaluationReport {
    let config = EvaluateConfig {
        outage_s: 30.0,
        odometer: OdometerConfig {
            heading,
            ..OdometerConfig::default()
        },
        ..EvaluateConfig::default()
    };
    evaluate(drive, &OdometryParams::nominal(&drive.vehicle), &config).expect("evaluate")
}

#[test]
fn wid_gyro_heading_beats_wheel_heading_and_every_outage_is_scored() {
    for name in ["wid-trial02", "wid-trial04"] {
        let Some(path) = drive_io::dev_data::real_drive(name) else {
            return;
        };
        let drive = drive_io::read_drive(&path).expect("read drive").drive;
        let wheels = run(&drive, HeadingMode::WheelDifference);
        let gyro = run(&drive, HeadingMode::Gyro);
        for report in [&wheels, &gyro] {
            // 134 s and 140 s of drive: starts every 10 s with 30 s left.
            assert_eq!(report.outages.len(), 11, "{name}: {:?}", report.warnings);
            // Nothing but the reading of a jittered logger's fixes at the
            // receiver's epochs (wid-trial02: 3 ms).
            assert!(
                report
                    .warnings
                    .iter()
                    .all(|w| w.starts_with("gnss: the stamps jitter by")),
                "{name}: {:?}",
                report.warnings
            );
            // Both drives start standing: the first outages are aligned on the
            // track after their start, the others on the track before.
            assert_eq!(
                report.outages[0].start_yaw_source,
                "truth_track_alignment_after"
            );
            assert_eq!(
                report.outages.last().map(|o| o.start_yaw_source),
                Some("truth_track_alignment")
            );
            assert!(report.outages.iter().all(|o| o.gyro_fallbacks == 0));
        }
        // The wheel-rate sensors' differential drift makes the wheel heading
        // much worse than the gyro's (the README's reason for the default).
        assert!(
            gyro.median_error_m * 2.0 < wheels.median_error_m,
            "{name}: gyro {} m, wheels {} m",
            gyro.median_error_m,
            wheels.median_error_m
        );
    }
}

#[test]
fn comma_truth_yaw_is_the_devices_not_the_cars_and_is_not_used() {
    let Some(path) = drive_io::dev_data::real_drive("comma2k19-seg40") else {
        return;
    };
    let drive = drive_io::read_drive(&path).expect("read drive").drive;
    let report = run(&drive, HeadingMode::Gyro);
    // comma's truth is the pose of the windscreen-mounted device: on the
    // highway's straight stretches its yaw is 15.5 mrad off the course of its
    // own positions (the same figure by hand from lat/lon: 15.2 mrad).
    let offset = report.truth_yaw_offset_rad.expect("offset");
    assert!((0.012..0.019).contains(&offset), "{offset}");
    assert!(!report.truth_yaw_used);
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.starts_with("truth.csv: yaw_rad is +15")),
        "{:?}",
        report.warnings
    );
    assert!(report
        .outages
        .iter()
        .all(|o| o.start_yaw_source.starts_with("truth_track_alignment")));
    // The WID truths have no yaw: nothing to check there.
    for name in ["wid-trial02", "wid-trial04"] {
        let Some(path) = drive_io::dev_data::real_drive(name) else {
            return;
        };
        let drive = drive_io::read_drive(&path).expect("read drive").drive;
        let report = run(&drive, HeadingMode::Gyro);
        assert_eq!(report.truth_yaw_offset_rad, None, "{name}");
        assert!(!report.truth_yaw_used, "{name}");
    }
}

/// The WID truth is the RTK receiver's track: every fix has its truth row,
/// at the fix, so `odometry evaluate` scores the antenna there by default.
/// comma2k19's truth is its device's fused pose, not its fixes: scored at
/// the axle.
#[test]
fn the_wid_truth_is_the_gnss_track_and_comma2k19s_is_not() {
    let antenna = Some([0.5, -0.3]);
    for (name, fixes) in [("wid-trial02", 609), ("wid-trial04", 698)] {
        let Some(path) = drive_io::dev_data::real_drive(name) else {
            return;
        };
        let drive = drive_io::read_drive(&path).expect("read drive").drive;
        assert_eq!(truth_gnss_coincidence(&drive), (fixes, fixes), "{name}");
        assert!(truth_is_the_gnss_track(&drive), "{name}");
        let point = choose_truth_point(&drive, TruthPointChoice::Auto, antenna).expect("point");
        assert_eq!(point.source, TruthPointSource::EstimatedAntenna, "{name}");
        assert_eq!(Some(point.point_m), antenna, "{name}");
    }
    let Some(path) = drive_io::dev_data::real_drive("comma2k19-seg40") else {
        return;
    };
    let drive = drive_io::read_drive(&path).expect("read drive").drive;
    // Its fixes (about 11 Hz) fall between the truth's rows (20 Hz): not one
    // shares an instant, let alone a position.
    assert_eq!(truth_gnss_coincidence(&drive), (0, 0));
    assert!(!truth_is_the_gnss_track(&drive));
    assert_eq!(
        choose_truth_point(&drive, TruthPointChoice::Auto, antenna).expect("point"),
        TruthPoint::AXLE
    );
}

/// The drive with every wheel sample stamped `by_s` later.
fn wheels_late(drive: &interfaces::drive::Drive, by_s: f64) -> interfaces::drive::Drive {
    let mut d = drive.clone();
    for s in &mut d.wheels.samples {
        s.t_s += by_s;
    }
    d
}

#[test]
fn a_wheel_clock_off_the_truth_is_found_said_and_taken_out() {
    for name in ["wid-trial02", "wid-trial04"] {
        let Some(path) = drive_io::dev_data::real_drive(name) else {
            return;
        };
        let drive = drive_io::read_drive(&path).expect("read drive").drive;
        let clean = run(&drive, HeadingMode::Gyro);
        let late = run(&wheels_late(&drive, 0.5), HeadingMode::Gyro);
        let said = late
            .warnings
            .iter()
            .find(|w| w.contains("wheels.csv") && w.contains("off truth.csv"))
            .unwrap_or_else(|| panic!("{name}: {:?}", late.warnings));
        println!(
            "{name}: {said}; median {:.3} m (clean drive {:.3} m)",
            late.median_error_m, clean.median_error_m
        );
        assert!(
            (late.median_error_m - clean.median_error_m).abs() < 0.1 * clean.median_error_m,
            "{name}: {} m against {} m",
            late.median_error_m,
            clean.median_error_m
        );
    }
}

#[test]
fn evaluate_reads_a_damaged_drive_as_calibrate_does() {
    let Some(path) = drive_io::dev_data::real_drive("wid-trial04") else {
        return;
    };
    let drive = drive_io::read_drive(&path).expect("read drive").drive;
    let config = EvaluateConfig {
        outage_s: 30.0,
        ..EvaluateConfig::default()
    };
    let params = OdometryParams::nominal(&drive.vehicle);
    let clean = evaluate(&drive, &params, &config).expect("clean");
    // A 1e308 glitch in rl: set aside with a warning naming it, the score
    // as without it.
    let mut glitched = drive.clone();
    glitched.wheels.samples[4000].rl = 1e308;
    let r = evaluate(&glitched, &params, &config).expect("glitched");
    assert!(
        r.warnings
            .iter()
            .any(|w| w.contains("wheels.rl") && w.contains("set aside")),
        "{:?}",
        r.warnings
    );
    assert!((r.median_error_m - clean.median_error_m).abs() < 0.01 * clean.median_error_m);
    // Reversed wheel signs: refused as calibrate refuses them.
    let mut reversed = drive.clone();
    for s in &mut reversed.wheels.samples {
        (s.rl, s.rr) = (-s.rl, -s.rr);
    }
    let e = evaluate(&reversed, &params, &config)
        .unwrap_err()
        .to_string();
    assert!(e.contains("both wheel signs are reversed"), "{e}");
    // A 60 s hole in the wheels: no outage is scored across it.
    let mut holed = drive;
    let (a, b) = (40.0, 100.0);
    holed.wheels.samples.retain(|s| s.t_s < a || s.t_s > b);
    let r = evaluate(&holed, &params, &config).expect("holed");
    assert!(
        r.outages
            .iter()
            .all(|o| o.t_start_s + config.outage_s <= a || o.t_start_s >= b),
        "{:?}",
        r.outages.iter().map(|o| o.t_start_s).collect::<Vec<_>>()
    );
    assert!(
        r.warnings.iter().any(|w| w.contains("pauses")),
        "{:?}",
        r.warnings
    );
}
