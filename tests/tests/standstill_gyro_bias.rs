//! The gyro bias measured at standstill (a zero angular rate update) against
//! a bias that changed since the calibration: a gyro's bias moves from one
//! power-on to the next (the catalogue's `gyro_bias`, 10-1000 deg/h), so the
//! calibrated value is only a prior for today's drive.

use interfaces::effects::Effect;
use odometry::dead_reckoning::{HeadingMode, OdometerConfig};
use odometry::evaluate::{evaluate, EvaluateConfig, EvaluationReport};
use simulator::{simulate, Scenario, SimConfig};
use vehicle_model::estimate::OdometryParams;
use vehicle_model::two_wheel::TwoWheelParams;

const DEG_H: f64 = std::f64::consts::PI / 180.0 / 3600.0;

fn run(drive: &interfaces::drive::Drive, params: &OdometryParams, learn: bool) -> EvaluationReport {
    let config = EvaluateConfig {
        outage_s: 30.0,
        odometer: OdometerConfig {
            heading: HeadingMode::Gyro,
            learn_gyro_bias: learn,
            ..OdometerConfig::default()
        },
        ..EvaluateConfig::default()
    };
    evaluate(drive, params, &config).expect("evaluate")
}

#[test]
fn a_gyro_bias_changed_since_calibration_is_measured_at_standstill() {
    // Today's bias is 180 deg/h; the calibration (an earlier power-on) said 36.
    let mut sim = SimConfig::new(Scenario::Mixed, 2);
    sim.effects
        .set(Effect::GyroBias, None, 180.0)
        .expect("gyro_bias knob");
    let drive = simulate(&sim).expect("simulate");
    let truth = drive.truth_params.clone().expect("truth.toml");
    let params = OdometryParams {
        two_wheel: TwoWheelParams {
            c_rl: truth.circumference_m.rl,
            c_rr: truth.circumference_m.rr,
            track_width: truth.track_width_m,
        },
        gyro_bias_rad_s: 36.0 * DEG_H,
        gyro_scale: 0.0,
    };
    let learned = run(&drive, &params, true);
    let kept = run(&drive, &params, false);
    println!(
        "median error after 30 s: {:.3} m with the standstill bias, {:.3} m with the calibrated one",
        learned.median_error_m, kept.median_error_m
    );
    // The drive starts standing: every outage after its first stop starts
    // with today's bias, not the calibrated one.
    let later: Vec<_> = learned
        .outages
        .iter()
        .filter(|o| o.gyro_bias_standstills > 0)
        .collect();
    assert!(
        later.len() + 2 >= learned.outages.len(),
        "standstill measurements: {:?}",
        learned
            .outages
            .iter()
            .map(|o| o.gyro_bias_standstills)
            .collect::<Vec<_>>()
    );
    for o in &later {
        let deg_h = o.gyro_bias_rad_s / DEG_H;
        if o.t_start_s > 60.0 {
            assert!(
                (deg_h - 180.0).abs() < 18.0,
                "bias in use {deg_h} deg/h at {o:?}"
            );
        }
    }
    assert!(kept.outages.iter().all(|o| o.gyro_bias_standstills == 0));
    // 144 deg/h left uncorrected is 0.021 rad after 30 s.
    assert!(
        learned.median_error_m < 0.5 * kept.median_error_m,
        "{:.3} m vs {:.3} m",
        learned.median_error_m,
        kept.median_error_m
    );
}
