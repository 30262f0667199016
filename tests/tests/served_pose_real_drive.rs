//! The served pose on a real drive: the filter of `odometry serve` through GNSS
//! outages, with the GNSS antenna position the calibrator determined against
//! the antenna taken at the rear axle (the odometry before it used calibrated
//! antennas), and the pose's own covariance at the outage ends. Skipped with
//! a message when `../shared/data/real` is absent.

use calibrator::{calibrate, CalibrationConfig};
use odometry::dead_reckoning::{HeadingMode, OdometerConfig};
use odometry::fused_outages::{fused_outages, inside_95, median_error, FusedOutageConfig};
use odometry::fusion::{Fusion, FusionConfig};
use odometry::inputs::drive_inputs;
use vehicle_model::estimate::gnss_lever_arm;
use vehicle_model::estimate::Estimate;

#[test]
fn the_calibrated_antenna_cuts_the_served_error_through_outages_on_wid_trial02() {
    let Some(path) = drive_io::dev_data::real_drive("wid-trial02") else {
        return;
    };
    let drive = drive_io::read_drive(&path).expect("read").drive;
    let truth = drive.truth.clone().expect("WID drives have truth.csv");
    // What `calibrator calibrate --json` writes, read as the odometry reads it.
    let cal = calibrate(&drive, &CalibrationConfig::default()).expect("calibrate");
    let json = serde_json::to_string(&cal).expect("json");
    let estimate = Estimate::from_json_str(&json, "wid-trial02 calibration").expect("estimate");
    let antenna = estimate
        .fusable_antenna()
        .expect("trial02 turns round: its antenna is determined");
    // The RTK antenna sits about half a metre ahead of the rear axle and a
    // third of a metre to the right (the same car's trial04 agrees forward).
    assert!(
        (0.4..0.7).contains(&antenna[0]) && (-0.45..-0.15).contains(&antenna[1]),
        "{antenna:?}"
    );

    let inputs = drive_inputs(&drive).expect("inputs");
    let median = |estimate: Estimate| {
        let (lever_arm_m, measured) = gnss_lever_arm(&drive.vehicle, Some(&estimate));
        let config = FusionConfig {
            odometer: OdometerConfig {
                heading: HeadingMode::Gyro,
                ..OdometerConfig::default()
            },
            lever_arm_m,
            lever_arm_from_estimates: !measured,
            ..FusionConfig::default()
        };
        let outages = fused_outages(
            &inputs,
            &truth,
            &|| Fusion::new(estimate.params, 0, config),
            // The WID truth is the GNSS antenna's track.
            &FusedOutageConfig {
                length_s: 30.0,
                at_antenna: true,
                ..FusedOutageConfig::default()
            },
        )
        .expect("filter");
        assert!(outages.iter().filter(|o| o.counted()).count() >= 8);
        (
            median_error(&outages).expect("scored outages"),
            inside_95(&outages),
        )
    };
    let (with, (inside, counted)) = median(estimate);
    let (without, _) = median(Estimate {
        antenna_m: None,
        ..estimate
    });
    eprintln!("30 s outages through the filter, median at the end: {with:.3} m with the calibrated antenna, {without:.3} m without");
    // Measured: 0.34 m against 1.26 m (0.81 against 1.55 m before the
    // filter's gyro bias kept its standstill and its distance scale).
    assert!(
        with < 0.7 * without,
        "{with:.3} m with the antenna, {without:.3} m without"
    );
    // The covariance published with the pose covers what it does not know:
    // measured 9 of 9 outage ends inside its 95 % ellipse (6 of 9 with white
    // distance noise alone).
    eprintln!("{inside} of {counted} outage ends inside the pose's 95 % ellipse");
    assert!(inside * 10 >= counted * 8, "{inside} of {counted}");
}
