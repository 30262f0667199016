//! What the filter's tests share: the parameters and configuration they
//! run with, a simulated drive on a gentle curve, and a run of a filter
//! over inputs.

use super::config::FusionConfig;
use super::filter::{FusedPose, Fusion};
use crate::dead_reckoning::{HeadingMode, OdometerConfig};
use crate::inputs::Input;
use crate::test_drive::{C, TRACK};
use vehicle_model::estimate::OdometryParams;
use vehicle_model::two_wheel::{Pose2, TwoWheelParams};

pub(super) fn params() -> OdometryParams {
    OdometryParams {
        two_wheel: TwoWheelParams {
            c_rl: C,
            c_rr: C,
            track_width: TRACK,
        },
        gyro_bias_rad_s: 0.0,
        gyro_scale: 0.0,
    }
}

pub(super) fn config(heading: HeadingMode) -> FusionConfig {
    FusionConfig {
        odometer: OdometerConfig {
            heading,
            ..OdometerConfig::default()
        },
        ..FusionConfig::default()
    }
}

/// Inputs of a drive on a gentle left curve at 10 m/s: wheels and gyro at
/// 100 Hz, GNSS at 5 Hz (stamped 5 ms after the wheel instant) where
/// `gnss` lets it through, truth returned too.
pub(super) struct Sim {
    pub(super) inputs: Vec<Input>,
    pub(super) truth: Vec<(f64, Pose2)>,
}

pub(super) fn simulate(seconds: f64, gnss: &dyn Fn(f64) -> bool, gyro_bias: f64, yaw0: f64) -> Sim {
    let curve = crate::test_drive::Curve {
        seconds,
        speed_m_s: 10.0,
        yaw_rate: |t| 0.1 * (0.3 * t).sin(),
        start: Pose2 {
            x: 100.0,
            y: -50.0,
            yaw: yaw0,
        },
        gyro_bias,
        fix_offset_s: 0.005,
        fix_error_m: 0.0,
        fix_sigma_m: 0.3,
    };
    let (inputs, truth) = crate::test_drive::simulate(&curve, gnss);
    Sim { inputs, truth }
}

pub(super) fn run(fusion: &mut Fusion, inputs: &[Input]) -> Vec<FusedPose> {
    inputs
        .iter()
        .filter_map(|i| fusion.process(i).expect("input accepted"))
        .collect()
}
