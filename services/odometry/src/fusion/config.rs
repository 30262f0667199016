//! The tuning of the filter.

use super::kalman::{CHI2_1DOF_999, CHI2_2DOF_999};
use crate::dead_reckoning::OdometerConfig;

/// Tuning of the filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FusionConfig {
    /// Dead-reckoning heading source and gyro settings.
    pub odometer: OdometerConfig,
    /// GNSS antenna in the body frame from the rear-axle centre (x forward, y left), m.
    pub lever_arm_m: [f64; 2],
    /// Take the antenna position from estimates that carry one (the
    /// calibrator fits it): true unless `lever_arm_m` was measured
    /// (`vehicle.toml`'s `[gnss]`), which then always wins.
    pub lever_arm_from_estimates: bool,
    /// Without an accepted fix for longer than this, the mode is DeadReckoning, s.
    pub gnss_timeout_s: f64,
    /// GNSS 1-sigma used when a fix gives none, m.
    pub default_gnss_sigma_m: f64,
    /// Smallest GNSS 1-sigma believed, m: time offsets and lever-arm errors the
    /// filter does not model are of this size even with an RTK fix.
    pub min_gnss_sigma_m: f64,
    /// Heading 1-sigma used when a heading sample gives none, rad.
    pub default_heading_sigma_rad: f64,
    /// Chi-square gate of GNSS innovations (2 degrees of freedom).
    pub gnss_gate: f64,
    /// Chi-square gate of heading innovations (1 degree of freedom).
    pub heading_gate: f64,
    /// A gap between wheel samples longer than this makes the inputs stale, s.
    pub stale_after_s: f64,
    /// GNSS displacement needed to initialise the yaw without a heading, m.
    pub init_baseline_m: f64,
    /// Reset the position after fixes were rejected for this long, s.
    pub reset_after_rejected_s: f64,
    /// Measurements older than the filter by more than this are dropped, s.
    pub max_measurement_delay_s: f64,
    /// Wheel distance white noise, fraction of each step's distance
    /// (1-sigma). The wheels' scale error is the consider state below.
    pub distance_noise_frac: f64,
    /// 1-sigma of the scale error s of calibrated wheels (their distance is
    /// (1 + s) times what they say). On the WID drives the scale moves by
    /// about 0.5 % between stretches of a few hundred metres (tyre
    /// temperature, road). A scale error is not white noise: its position
    /// error grows with the distance, not with its square root, and without
    /// it the covariance after an outage claimed centimetres along the track
    /// where the pose was decimetres off. It is a consider state: it widens
    /// the covariance but is never estimated (see the module docs).
    pub distance_scale_sigma: f64,
    /// The same while the circumferences are the nominal `vehicle.toml`
    /// guess (`Fusion::nominal`, until the first estimate arrives): a
    /// tyre-size guess can be several percent off (the paper's 2.2 m for
    /// 2.04 m, 8 %), and a filter that trusted it like a calibration would
    /// gate out good fixes.
    pub nominal_distance_scale_sigma: f64,
    /// 1-sigma of the rear wheels' relative circumference error with a
    /// calibration (right minus left, as a fraction of the circumference):
    /// in wheel heading it turns the heading by that fraction of the
    /// distance over the track, a yaw error that grows with the distance.
    /// A consider state like the scale. The two WID calibrations of the same
    /// car differ by 0.08 % in it; at 0.1 % the wheel-heading covariance
    /// holds 31 of 34 outage ends on them in its 95 % ellipse (BENCHMARKS.md).
    pub wheel_difference_sigma: f64,
    /// The same while the circumferences are the nominal guess (both wheels
    /// the same tyre-size value).
    pub nominal_wheel_difference_sigma: f64,
    /// Wheel-difference heading noise, rad per metre driven (1-sigma).
    pub wheel_yaw_noise_rad_per_m: f64,
    /// Gyro angle random walk, rad/sqrt(s).
    pub gyro_noise_rad_per_sqrt_s: f64,
    /// Random walk of the residual gyro bias, rad/s/sqrt(s).
    pub gyro_bias_walk: f64,
    /// Initial 1-sigma of the residual gyro bias before any standstill has
    /// measured the bias, rad/s. After one, the residual starts with the
    /// odometer's bias variance
    /// ([`Odometer::gyro_bias_variance`](crate::dead_reckoning::Odometer::gyro_bias_variance))
    /// grown by [`FusionConfig::gyro_bias_walk`] since, when that is smaller.
    pub initial_gyro_bias_sigma: f64,
    /// Smallest position 1-sigma of a resumed pose (`Fusion::resume`), m.
    pub resume_sigma_m: f64,
    /// Smallest yaw 1-sigma of a resumed pose, rad.
    pub resume_yaw_sigma_rad: f64,
}

impl Default for FusionConfig {
    fn default() -> Self {
        FusionConfig {
            odometer: OdometerConfig::default(),
            lever_arm_m: [0.0, 0.0],
            lever_arm_from_estimates: true,
            gnss_timeout_s: 1.0,
            default_gnss_sigma_m: 2.0,
            min_gnss_sigma_m: 0.15,
            default_heading_sigma_rad: 0.05,
            gnss_gate: CHI2_2DOF_999,
            heading_gate: CHI2_1DOF_999,
            stale_after_s: 0.5,
            init_baseline_m: 5.0,
            reset_after_rejected_s: 10.0,
            max_measurement_delay_s: 0.2,
            distance_noise_frac: 0.02,
            distance_scale_sigma: 0.005,
            nominal_distance_scale_sigma: 0.1,
            wheel_difference_sigma: 0.001,
            nominal_wheel_difference_sigma: 0.005,
            wheel_yaw_noise_rad_per_m: 0.003,
            gyro_noise_rad_per_sqrt_s: 0.002,
            gyro_bias_walk: 2e-5,
            initial_gyro_bias_sigma: 1e-3,
            resume_sigma_m: 0.5,
            resume_yaw_sigma_rad: 0.02,
        }
    }
}
