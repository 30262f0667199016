//! The pose filter of the odometry service: an EKF on the 2W model.
//!
//! State: position x, y of the rear-axle centre (ENU, m), yaw (rad), a
//! residual yaw-rate gyro bias b (rad/s) on top of the calibrated one, and
//! the wheels' distance scale error s, a consider state (Schmidt-Kalman): it
//! stays 0 and is never updated (its row of every gain is zeroed), but its
//! variance ([`FusionConfig::distance_scale_sigma`]) enters the pose
//! covariance through the prediction, so the along-track uncertainty grows
//! with the distance as a scale error's does. Estimating s from the fixes
//! instead was tried and made the outages on wid-trial04 worse (its RTK
//! fixes jump by decimetres; BENCHMARKS.md). A second consider state, the
//! rear wheels' relative circumference error
//! ([`FusionConfig::wheel_difference_sigma`]), does the same for the yaw in
//! wheel heading, which it turns by that fraction of the distance over the
//! track.
//!
//! - Prediction: the increments of the same [`Odometer`] that `odometry
//!   evaluate` dead-reckons with (distance from the calibrated rear wheels,
//!   heading from the wheel difference or the calibrated gyro), stepped with
//!   the 2W model's eq. (1); in gyro heading the residual bias is subtracted
//!   and slowly random-walks. It starts at zero with
//!   [`FusionConfig::initial_gyro_bias_sigma`], or, once a standstill has
//!   measured the bias (before the first fix too), with what the odometer
//!   knows of it ([`Odometer::gyro_bias_variance`]) grown by the walk since.
//!   Without updates the mean is exactly the dead-reckoned pose.
//! - Updates: GNSS positions of the antenna (lever arm from `vehicle.toml`'s
//!   `[gnss] antenna_x_m/antenna_y_m`, else from the estimate, whose
//!   calibration fits it; rotated by the yaw), and absolute
//!   headings. Each innovation is tested against a chi-square gate (2 and 1
//!   degrees of freedom, 99.9 %); a measurement outside it is rejected.
//! - Measurements are applied at their own time: a fix between two wheel
//!   samples waits for the later one, the wheel revolutions are interpolated
//!   at the fix time, the filter predicts to it, updates, and predicts on.
//!
//! Modes ([`PoseMode`]):
//! - `NoFix` until the filter is initialised, and again after the inputs went
//!   stale ([`Fusion::mark_stale`], or a gap between wheel samples longer than
//!   [`FusionConfig::stale_after_s`]): nothing is claimed about the pose.
//! - `Fused` while the last accepted fix is at most
//!   [`FusionConfig::gnss_timeout_s`] old.
//! - `DeadReckoning` otherwise: no fix for that long, or every fix gated out.
//!
//! Initialisation: at the first fix when an absolute heading at most 1 s old
//! is known; otherwise the filter dead-reckons in a local frame from the first
//! fix until the GNSS track has moved [`FusionConfig::init_baseline_m`], and
//! takes the rotation between the local and the GNSS displacement as the yaw
//! (exact on any path when the odometry is right; no standing-still heading
//! is guessed).
//!
//! Fixes rejected for longer than [`FusionConfig::reset_after_rejected_s`]
//! (with at least three in a row) mean the filter has lost itself: the
//! position is reset to the fix, with its covariance inflated.
//!
//! Pure: no clock, no I/O; numerical failure is a [`FusionError`].

use crate::dead_reckoning::{
    BiasObservation, HeadingMode, HeadingSource, Increment, InputError, Odometer, OdometerConfig,
};
use crate::estimate_file::OdometryParams;
use crate::inputs::Input;
use crate::two_wheel::{wrap_angle, Pose2};
use interfaces::drive::VehicleParams;
use interfaces::wire::PoseMode;
use nalgebra::{SMatrix, SVector};

/// State: x, y, yaw, residual gyro bias, and two consider states: the
/// distance scale error and the rear wheels' relative circumference error.
const N: usize = 6;
/// Index of the distance scale error in the state.
const SCALE: usize = 4;
/// Index of the relative circumference error (right minus left, as a
/// fraction) in the state: it turns the wheel-difference heading.
const WHEEL_DIFF: usize = 5;
type StateMat = SMatrix<f64, N, N>;
type StateVec = SVector<f64, N>;

/// Measurements waiting for a wheel sample, at most.
pub const MAX_PENDING: usize = 256;

/// 99.9 % quantile of chi-square with 2 degrees of freedom.
pub const CHI2_2DOF_999: f64 = 13.816;
/// 99.9 % quantile of chi-square with 1 degree of freedom.
pub const CHI2_1DOF_999: f64 = 10.828;

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
    /// guess ([`Fusion::nominal`], until the first estimate arrives): a
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
    /// odometer's bias variance ([`Odometer::gyro_bias_variance`]) grown by
    /// [`FusionConfig::gyro_bias_walk`] since, when that is smaller.
    pub initial_gyro_bias_sigma: f64,
    /// Smallest position 1-sigma of a resumed pose ([`Fusion::resume`]), m.
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

/// A numerical failure of the filter.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FusionError {
    /// An innovation covariance that cannot be inverted.
    #[error("{what} innovation covariance at t = {t_s} s is not positive definite")]
    NotPositiveDefinite {
        /// `gnss`, `heading` or `standstill gyro bias`.
        what: &'static str,
        /// Time of the measurement.
        t_s: f64,
    },
    /// The state or covariance became NaN or infinite.
    #[error("filter state became non-finite at t = {t_s} s after {after}")]
    NonFinite {
        /// Time.
        t_s: f64,
        /// The step that produced it.
        after: &'static str,
    },
    /// A pose to resume from ([`Fusion::resume`]) with a value that is NaN or infinite.
    #[error("the pose to resume from is not finite (position, yaw or covariance)")]
    ResumeNotFinite,
    /// A GNSS antenna position ([`Fusion::set_lever_arm`]) that is NaN or infinite.
    #[error("the GNSS antenna position {0:?} m is not finite")]
    LeverArmNotFinite([f64; 2]),
}

/// What [`Fusion::process`] reports.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProcessError {
    /// The sample is unusable and was skipped; the filter is unchanged.
    #[error(transparent)]
    Input(#[from] InputError),
    /// The filter failed numerically and has been reset to `NoFix`.
    #[error("{0}; the filter was reset")]
    Numerical(#[from] FusionError),
}

/// The filter's pose at a wheel sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FusedPose {
    /// Time of the wheel sample, s.
    pub t_s: f64,
    /// The pose (meaningless in `NoFix`, then all zero).
    pub pose: Pose2,
    /// Covariance of (x, y, yaw), row-major (all zero in `NoFix`).
    pub covariance: [f64; 9],
    /// What the pose stands on.
    pub mode: PoseMode,
    /// Version of the estimate in use (0 = nominal).
    pub estimate_version: u64,
}

/// Counters of what the filter did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FusionStats {
    /// Fixes accepted.
    pub gnss_accepted: u64,
    /// Fixes rejected by the gate.
    pub gnss_rejected: u64,
    /// Headings accepted.
    pub heading_accepted: u64,
    /// Headings rejected by the gate.
    pub heading_rejected: u64,
    /// Measurements dropped because they came too late (or waited too long
    /// for a wheel sample).
    pub dropped_late: u64,
    /// Times the filter was initialised.
    pub initialisations: u64,
    /// Times the position was reset after persistent rejections.
    pub position_resets: u64,
    /// Times the inputs went stale.
    pub stale: u64,
    /// Gyro bias measurements taken at standstill.
    pub gyro_bias_standstills: u64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Measurement {
    Gnss {
        t_s: f64,
        x_m: f64,
        y_m: f64,
        sigma_m: f64,
    },
    Heading {
        t_s: f64,
        yaw_rad: f64,
        sigma_rad: f64,
    },
}

impl Measurement {
    fn t_s(&self) -> f64 {
        match *self {
            Measurement::Gnss { t_s, .. } | Measurement::Heading { t_s, .. } => t_s,
        }
    }

    /// Order at equal times, the same as [`Input::rank`].
    fn rank(&self) -> u8 {
        match self {
            Measurement::Gnss { .. } => 1,
            Measurement::Heading { .. } => 2,
        }
    }
}

// One per filter, on the stack and copied on purpose: boxing the running
// state would put a heap allocation into every update.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
enum State {
    /// Waiting for a first fix (and a baseline to get the yaw).
    Uninitialised {
        /// First fix (x, y, t) and the local dead-reckoned pose at that time.
        anchor: Option<([f64; 3], Pose2)>,
        /// Dead-reckoned pose in a local frame.
        local: Pose2,
    },
    /// Running.
    Running { x: StateVec, p: StateMat },
}

/// The EKF with its mode logic. Feed every [`Input`] in processing order
/// (see [`crate::inputs`]); a pose comes out at every wheel sample.
#[derive(Debug, Clone)]
pub struct Fusion {
    config: FusionConfig,
    odometer: Odometer,
    /// The circumferences are the nominal guess (no estimate taken yet).
    nominal: bool,
    estimate_version: u64,
    state: State,
    pending: Vec<Measurement>,
    /// Last wheel sample (t, rl, rr).
    last_wheels: Option<(f64, f64, f64)>,
    last_heading: Option<(f64, f64, f64)>,
    last_accepted_fix_s: Option<f64>,
    first_rejected_fix_s: Option<f64>,
    rejected_in_a_row: u32,
    /// Time of the last standstill gyro bias measurement, s.
    last_standstill_bias_s: Option<f64>,
    stats: FusionStats,
}

impl Fusion {
    /// A filter in `NoFix`, using `params` (estimate `estimate_version`, 0 = nominal).
    pub fn new(params: OdometryParams, estimate_version: u64, config: FusionConfig) -> Fusion {
        Fusion {
            config,
            odometer: Odometer::new(params, config.odometer),
            nominal: false,
            estimate_version,
            state: State::Uninitialised {
                anchor: None,
                local: Pose2::default(),
            },
            pending: Vec::new(),
            last_wheels: None,
            last_heading: None,
            last_accepted_fix_s: None,
            first_rejected_fix_s: None,
            rejected_in_a_row: 0,
            last_standstill_bias_s: None,
            stats: FusionStats::default(),
        }
    }

    /// A filter on the nominal `vehicle.toml` values (estimate version 0),
    /// trusting the wheels' scale only to
    /// [`FusionConfig::nominal_distance_scale_sigma`] until an estimate arrives.
    pub fn nominal(vehicle: &VehicleParams, config: FusionConfig) -> Fusion {
        let mut fusion = Fusion::new(OdometryParams::nominal(vehicle), 0, config);
        fusion.nominal = true;
        fusion
    }

    /// The parameters in use.
    pub fn params(&self) -> &OdometryParams {
        self.odometer.params()
    }

    /// The gyro bias the filter uses, rad/s: the odometer's (calibrated, and
    /// measured at standstills) plus the residual learned while running.
    pub fn gyro_bias(&self) -> f64 {
        let residual = match self.state {
            State::Running { x, .. } => x[3],
            State::Uninitialised { .. } => 0.0,
        };
        self.odometer.gyro_bias() + residual
    }

    /// Version of the estimate in use.
    pub fn estimate_version(&self) -> u64 {
        self.estimate_version
    }

    /// Counters.
    pub fn stats(&self) -> FusionStats {
        self.stats
    }

    /// The configuration.
    pub fn config(&self) -> &FusionConfig {
        &self.config
    }

    /// The GNSS antenna position in use (body x forward, y left, from the
    /// rear-axle centre), m.
    pub fn lever_arm(&self) -> [f64; 2] {
        self.config.lever_arm_m
    }

    /// The antenna position the filter takes from an estimate or a kept
    /// pose that brings `candidate`: the candidate, unless the antenna is
    /// measured ([`FusionConfig::lever_arm_from_estimates`] false).
    pub fn antenna_to_take(&self, candidate: Option<[f64; 2]>) -> Option<[f64; 2]> {
        candidate.filter(|_| self.config.lever_arm_from_estimates)
    }

    /// Use a new GNSS antenna position. The filter's belief about where the
    /// antenna is stays as it was, so the rear-axle position moves by the
    /// change of the arm (rotated by the yaw): a pose fused with the antenna
    /// assumed at the axle was the antenna's track, and is now the axle's.
    /// A non-finite position is refused.
    pub fn set_lever_arm(&mut self, lever_arm_m: [f64; 2]) -> Result<(), FusionError> {
        if !lever_arm_m.iter().all(|v| v.is_finite()) {
            return Err(FusionError::LeverArmNotFinite(lever_arm_m));
        }
        let State::Running { x, .. } = self.state else {
            self.config.lever_arm_m = lever_arm_m;
            return Ok(());
        };
        let old = self.lever_arm_world(x[2]);
        self.config.lever_arm_m = lever_arm_m;
        let new = self.lever_arm_world(x[2]);
        if let State::Running { x, .. } = &mut self.state {
            x[0] += old[0] - new[0];
            x[1] += old[1] - new[1];
        }
        Ok(())
    }

    /// Switch to a new estimate between two samples: the pose does not move,
    /// the next increments use the new parameters, and the residual gyro bias
    /// starts again from zero (the new estimate carries its own bias).
    /// Returns the parameters replaced.
    pub fn set_estimate(&mut self, params: OdometryParams, version: u64) -> OdometryParams {
        let old = *self.odometer.params();
        self.odometer.set_params(params);
        self.nominal = false;
        self.estimate_version = version;
        let bias_variance = self.fresh_bias_variance(self.last_wheels.map_or(0.0, |w| w.0));
        let [scale_variance, difference_variance] = self.fresh_consider_variances();
        if let State::Running { x, p } = &mut self.state {
            for (k, variance) in [
                (3, bias_variance),
                (SCALE, scale_variance),
                (WHEEL_DIFF, difference_variance),
            ] {
                x[k] = 0.0;
                for i in 0..N {
                    p[(i, k)] = 0.0;
                    p[(k, i)] = 0.0;
                }
                p[(k, k)] = variance;
            }
        }
        old
    }

    /// Start from a pose kept from an earlier run (the car was parked there,
    /// say in a garage, and powers on without GNSS): `Running`, in
    /// `DeadReckoning` until a fix is accepted. The position and yaw
    /// variances are at least [`FusionConfig::resume_sigma_m`] and
    /// [`FusionConfig::resume_yaw_sigma_rad`] squared (what a parked car's
    /// pose may have lost); the residual gyro bias starts from zero.
    pub fn resume(&mut self, pose: Pose2, covariance: &[f64; 9]) -> Result<(), FusionError> {
        let finite = [pose.x, pose.y, pose.yaw]
            .iter()
            .chain(covariance)
            .all(|v| v.is_finite());
        if !finite {
            return Err(FusionError::ResumeNotFinite);
        }
        let mut p = StateMat::zeros();
        for i in 0..3 {
            for j in 0..3 {
                p[(i, j)] = covariance[3 * i + j];
            }
        }
        let floors = [
            self.config.resume_sigma_m.powi(2),
            self.config.resume_sigma_m.powi(2),
            self.config.resume_yaw_sigma_rad.powi(2),
        ];
        for (i, floor) in floors.into_iter().enumerate() {
            p[(i, i)] = p[(i, i)].max(floor);
        }
        p[(3, 3)] = self.config.initial_gyro_bias_sigma.powi(2);
        let [scale_variance, difference_variance] = self.fresh_consider_variances();
        p[(SCALE, SCALE)] = scale_variance;
        p[(WHEEL_DIFF, WHEEL_DIFF)] = difference_variance;
        let x = StateVec::new(pose.x, pose.y, wrap_angle(pose.yaw), 0.0, 0.0, 0.0);
        self.reset();
        self.set_running(x, p, 0.0, "resume")
    }

    /// The inputs went stale (the service saw no wheel sample for too long):
    /// forget the pose; `NoFix` until the filter is initialised again.
    pub fn mark_stale(&mut self) {
        self.stats.stale += 1;
        self.reset();
    }

    /// Back to `NoFix`, keeping the parameters and counters.
    pub fn reset(&mut self) {
        self.state = State::Uninitialised {
            anchor: None,
            local: Pose2::default(),
        };
        self.odometer.restart();
        self.pending.clear();
        self.last_wheels = None;
        self.last_accepted_fix_s = None;
        self.first_rejected_fix_s = None;
        self.rejected_in_a_row = 0;
    }

    /// The mode the filter is in at time `t_s`.
    pub fn mode_at(&self, t_s: f64) -> PoseMode {
        match self.state {
            State::Uninitialised { .. } => PoseMode::NoFix,
            State::Running { .. } => match self.last_accepted_fix_s {
                Some(tf) if t_s - tf <= self.config.gnss_timeout_s => PoseMode::Fused,
                _ => PoseMode::DeadReckoning,
            },
        }
    }

    /// Take one input. Returns the pose after a wheel sample, `None` otherwise.
    /// An [`Input::Estimate`] switches the estimate as [`Fusion::set_estimate`].
    pub fn process(&mut self, input: &Input) -> Result<Option<FusedPose>, ProcessError> {
        match *input {
            Input::Imu { t_s, gz_rad_s } => {
                self.odometer.gyro(t_s, gz_rad_s)?;
                Ok(None)
            }
            Input::Gnss {
                t_s,
                x_m,
                y_m,
                sigma_m,
            } => {
                if !(t_s.is_finite() && x_m.is_finite() && y_m.is_finite()) {
                    return Err(InputError::NonFinite {
                        stream: "gnss",
                        t_s,
                    }
                    .into());
                }
                let sigma = sigma_m
                    .filter(|s| s.is_finite() && *s > 0.0)
                    .unwrap_or(self.config.default_gnss_sigma_m)
                    .max(self.config.min_gnss_sigma_m);
                self.push_pending(Measurement::Gnss {
                    t_s,
                    x_m,
                    y_m,
                    sigma_m: sigma,
                });
                Ok(None)
            }
            Input::Heading {
                t_s,
                yaw_rad,
                sigma_rad,
            } => {
                if !(t_s.is_finite() && yaw_rad.is_finite()) {
                    return Err(InputError::NonFinite {
                        stream: "heading",
                        t_s,
                    }
                    .into());
                }
                let sigma = sigma_rad
                    .filter(|s| s.is_finite() && *s > 0.0)
                    .unwrap_or(self.config.default_heading_sigma_rad);
                self.last_heading = Some((t_s, yaw_rad, sigma));
                self.push_pending(Measurement::Heading {
                    t_s,
                    yaw_rad,
                    sigma_rad: sigma,
                });
                Ok(None)
            }
            Input::Estimate {
                version, estimate, ..
            } => {
                // The antenna first: a bad one leaves the filter as it was.
                if let Some(antenna) = self.antenna_to_take(estimate.fusable_antenna()) {
                    self.set_lever_arm(antenna)?;
                }
                self.set_estimate(estimate.params, version);
                Ok(None)
            }
            Input::Wheels {
                t_s,
                rl_rev,
                rr_rev,
            } => match self.wheels(t_s, rl_rev, rr_rev) {
                Ok(pose) => Ok(Some(pose)),
                Err(ProcessError::Numerical(e)) => {
                    self.reset();
                    Err(ProcessError::Numerical(e))
                }
                Err(e) => Err(e),
            },
        }
    }

    /// The step of a made-up wheel sample 1 ms after the last one, both
    /// wheels a thousandth of a turn further (straight on at 1 rev/s), with
    /// a fix where the filter's antenna is and, once headings have come, a
    /// heading along its yaw: the work of a wheel sample while driving, its
    /// updates included, for [`crate::rewind::RewindingFusion::rehearse`],
    /// which runs it on a copy. `None` before the first wheel sample, or
    /// when the step fails.
    pub(crate) fn rehearse_wheel_sample(&mut self) -> Option<FusedPose> {
        let (t_s, rl_rev, rr_rev) = self.last_wheels?;
        let t_s = t_s + 1e-3;
        if let State::Running { x, .. } = self.state {
            let [ax, ay] = self.lever_arm_world(x[2]);
            let fix = Input::Gnss {
                t_s,
                x_m: x[0] + ax,
                y_m: x[1] + ay,
                sigma_m: None,
            };
            self.process(&fix).ok()?;
            if self.last_heading.is_some() {
                let heading = Input::Heading {
                    t_s,
                    yaw_rad: x[2],
                    sigma_rad: None,
                };
                self.process(&heading).ok()?;
            }
        }
        let sample = Input::Wheels {
            t_s,
            rl_rev: rl_rev + 1e-3,
            rr_rev: rr_rev + 1e-3,
        };
        self.process(&sample).ok().flatten()
    }

    /// Queue a measurement until the wheel sample after it; without wheel
    /// samples the queue keeps only the newest [`MAX_PENDING`].
    fn push_pending(&mut self, m: Measurement) {
        if self.pending.len() >= MAX_PENDING {
            self.pending.remove(0);
            self.stats.dropped_late += 1;
        }
        self.pending.push(m);
    }

    fn wheels(&mut self, t1: f64, rl1: f64, rr1: f64) -> Result<FusedPose, ProcessError> {
        if !(t1.is_finite() && rl1.is_finite() && rr1.is_finite()) {
            return Err(InputError::NonFinite {
                stream: "wheels",
                t_s: t1,
            }
            .into());
        }
        if let Some((t0, _, _)) = self.last_wheels {
            if t1 <= t0 {
                return Err(InputError::OutOfOrder {
                    stream: "wheels",
                    t_s: t1,
                    previous_t_s: t0,
                }
                .into());
            }
            if t1 - t0 > self.config.stale_after_s {
                // The wheels stopped for a while: what happened in between is unknown.
                self.stats.stale += 1;
                self.reset();
            }
        }
        // Measurements up to t1, in time order (a fix before a heading of the
        // same time, as in `crate::inputs`, whatever order they were queued
        // in), each at its own time.
        self.pending
            .sort_by(|a, b| a.t_s().total_cmp(&b.t_s()).then(a.rank().cmp(&b.rank())));
        let due = self.pending.partition_point(|m| m.t_s() <= t1);
        let measurements: Vec<Measurement> = self.pending.drain(..due).collect();
        for m in measurements {
            let tm = m.t_s();
            match self.last_wheels {
                Some((t0, rl0, rr0)) if tm > t0 => {
                    let f = (tm - t0) / (t1 - t0);
                    if tm < t1 {
                        self.advance(tm, rl0 + f * (rl1 - rl0), rr0 + f * (rr1 - rr0))?;
                    } else {
                        self.advance(t1, rl1, rr1)?;
                    }
                }
                Some((t0, _, _)) if t0 - tm > self.config.max_measurement_delay_s => {
                    self.stats.dropped_late += 1;
                    continue;
                }
                None if t1 - tm > self.config.max_measurement_delay_s => {
                    self.stats.dropped_late += 1;
                    continue;
                }
                None => self.advance(t1, rl1, rr1)?,
                Some(_) => {}
            }
            self.measure(&m)?;
        }
        if self.last_wheels.is_none_or(|(t0, _, _)| t0 < t1) {
            self.advance(t1, rl1, rr1)?;
        }
        Ok(self.output(t1))
    }

    /// Feed a wheel sample to the odometer and predict with its increment.
    fn advance(&mut self, t_s: f64, rl: f64, rr: f64) -> Result<(), ProcessError> {
        let increment = self.odometer.wheels(t_s, rl, rr)?;
        self.last_wheels = Some((t_s, rl, rr));
        if let Some(observation) = self.odometer.take_bias_observation() {
            self.stats.gyro_bias_standstills += 1;
            self.last_standstill_bias_s = Some(observation.t_s);
            self.observe_bias(&observation)?;
        }
        if let Some(inc) = increment {
            self.predict(&inc)?;
        }
        Ok(())
    }

    /// Variance of a residual gyro bias that starts from zero at `t_s`: after
    /// a standstill, the odometer's bias variance grown by the bias walk
    /// since (at most [`FusionConfig::initial_gyro_bias_sigma`] squared).
    /// Without this, a standstill before the filter is initialised would be
    /// forgotten, and the first turns, whose GNSS course differs from the
    /// gyro's for a while (side slip, decimetre RTK jumps), would pull a bias
    /// that is in fact well known (wid-trial04: 2.9e-3 rad/s learned against
    /// 7e-5 measured, 10 m off after a 30 s outage).
    fn fresh_bias_variance(&self, t_s: f64) -> f64 {
        let initial = self.config.initial_gyro_bias_sigma.powi(2);
        match self.last_standstill_bias_s {
            None => initial,
            Some(t0) => {
                let walk = self.config.gyro_bias_walk.powi(2) * (t_s - t0).max(0.0);
                (self.odometer.gyro_bias_variance() + walk).min(initial)
            }
        }
    }

    /// Variances of the two consider states (distance scale, relative
    /// circumference error): the nominal guess's, or a calibration's.
    fn fresh_consider_variances(&self) -> [f64; 2] {
        let c = &self.config;
        let sigmas = if self.nominal {
            [
                c.nominal_distance_scale_sigma,
                c.nominal_wheel_difference_sigma,
            ]
        } else {
            [c.distance_scale_sigma, c.wheel_difference_sigma]
        };
        sigmas.map(|s| s * s)
    }

    /// A standstill measured the gyro bias: update the residual bias with it,
    /// then move the residual onto the odometer's new bias, so that the total
    /// (odometer bias + residual) is the filter's estimate, not the odometer's.
    fn observe_bias(&mut self, obs: &BiasObservation) -> Result<(), FusionError> {
        if self.config.odometer.heading != HeadingMode::Gyro {
            return Ok(());
        }
        let State::Running { x, p } = self.state else {
            return Ok(());
        };
        let nu = SVector::<f64, 1>::new(obs.mean_rad_s - obs.bias_before_rad_s - x[3]);
        let mut h = SMatrix::<f64, 1, N>::zeros();
        h[(0, 3)] = 1.0;
        let r = SMatrix::<f64, 1, 1>::new(obs.variance);
        let ph = p * h.transpose();
        let s_mat = h * ph + r;
        let s = s_mat[(0, 0)];
        if !(s.is_finite() && s > 0.0) {
            return Err(FusionError::NotPositiveDefinite {
                what: "standstill gyro bias",
                t_s: obs.t_s,
            });
        }
        let s_inverse = SMatrix::<f64, 1, 1>::new(1.0 / s);
        let (mut x, p) = kalman_update(x, &p, &ph, &s_mat, &s_inverse, &nu);
        x[3] -= obs.bias_after_rad_s - obs.bias_before_rad_s;
        self.set_running(x, p, obs.t_s, "standstill gyro bias update")
    }

    fn predict(&mut self, inc: &Increment) -> Result<(), FusionError> {
        let config = self.config;
        let scale = 1.0 + self.odometer.params().gyro_scale;
        let track = self.odometer.params().two_wheel.track_width;
        match &mut self.state {
            State::Uninitialised { local, .. } => {
                *local = crate::two_wheel::step(*local, inc.ds_m, inc.dyaw_rad, 0.0);
                Ok(())
            }
            State::Running { x, p } => {
                let dt = inc.t1_s - inc.t0_s;
                let gyro = inc.heading_source == HeadingSource::Gyro;
                // d(dyaw)/d(b): the residual bias is subtracted from gyro increments only.
                let dyaw_db = if gyro { -dt / scale } else { 0.0 };
                let dyaw = inc.dyaw_rad + dyaw_db * x[3];
                let course = x[2] + 0.5 * dyaw;
                let (s, c) = course.sin_cos();
                let ds = inc.ds_m;
                // The scale state is always 0 (never estimated): ds as measured.
                x[0] += ds * c;
                x[1] += ds * s;
                x[2] += dyaw;
                // The Jacobian F = I + E: E's rows x, y, yaw over the
                // columns yaw, bias, scale, wheel difference.
                let mut e = [[0.0; 4]; 3];
                e[0][0] = -ds * s;
                e[1][0] = ds * c;
                e[0][1] = -ds * s * 0.5 * dyaw_db;
                e[1][1] = ds * c * 0.5 * dyaw_db;
                e[2][1] = dyaw_db;
                e[0][2] = ds * c;
                e[1][2] = ds * s;
                // A common scale error of both wheels scales their heading
                // difference too; the gyro's heading does not see it.
                e[2][2] = if gyro { 0.0 } else { inc.dyaw_rad };
                // A relative circumference error e turns the wheel-difference
                // heading by e ds / track (and the course of this step by half).
                if !gyro {
                    let dyaw_de = ds / track;
                    e[0][3] = -ds * s * 0.5 * dyaw_de;
                    e[1][3] = ds * c * 0.5 * dyaw_de;
                    e[2][3] = dyaw_de;
                }
                // Noise of (ds, dyaw) mapped into the pose, G diag(.) G^T with
                // G's rows (c, -ds s / 2), (s, ds c / 2), (0, 1); plus the bias walk.
                let sigma_ds = config.distance_noise_frac * ds.abs();
                let sigma_dyaw = if gyro {
                    config.gyro_noise_rad_per_sqrt_s * dt.max(0.0).sqrt()
                } else {
                    config.wheel_yaw_noise_rad_per_m * ds.abs()
                };
                let g = [[c, -0.5 * ds * s], [s, 0.5 * ds * c], [0.0, 1.0]];
                let (var_ds, var_dyaw) = (sigma_ds * sigma_ds, sigma_dyaw * sigma_dyaw);
                let q_pose = std::array::from_fn(|i| {
                    std::array::from_fn(|j| {
                        g[i][0] * g[j][0] * var_ds + g[i][1] * g[j][1] * var_dyaw
                    })
                });
                let q_bias = if config.odometer.heading == HeadingMode::Gyro {
                    config.gyro_bias_walk.powi(2) * dt.max(0.0)
                } else {
                    0.0
                };
                *p = propagate_covariance(p, &e, &q_pose, q_bias);
                if !all_finite(x, p) {
                    return Err(FusionError::NonFinite {
                        t_s: inc.t1_s,
                        after: "prediction",
                    });
                }
                Ok(())
            }
        }
    }

    fn lever_arm_world(&self, yaw: f64) -> [f64; 2] {
        let [lx, ly] = self.config.lever_arm_m;
        let (s, c) = yaw.sin_cos();
        [lx * c - ly * s, lx * s + ly * c]
    }

    fn measure(&mut self, m: &Measurement) -> Result<(), FusionError> {
        match (*m, self.state) {
            (
                Measurement::Gnss {
                    t_s,
                    x_m,
                    y_m,
                    sigma_m,
                },
                State::Uninitialised { anchor, local },
            ) => {
                self.initialise_from_fix(t_s, x_m, y_m, sigma_m, anchor, local);
                Ok(())
            }
            (Measurement::Heading { .. }, State::Uninitialised { .. }) => Ok(()),
            (
                Measurement::Gnss {
                    t_s,
                    x_m,
                    y_m,
                    sigma_m,
                },
                State::Running { .. },
            ) => self.update_gnss(t_s, x_m, y_m, sigma_m),
            (
                Measurement::Heading {
                    t_s,
                    yaw_rad,
                    sigma_rad,
                },
                State::Running { .. },
            ) => self.update_heading(t_s, yaw_rad, sigma_rad),
        }
    }

    fn initialise_from_fix(
        &mut self,
        t_s: f64,
        x_m: f64,
        y_m: f64,
        sigma_m: f64,
        anchor: Option<([f64; 3], Pose2)>,
        local: Pose2,
    ) {
        let lever = self.config.lever_arm_m[0].hypot(self.config.lever_arm_m[1]);
        // With a recent absolute heading, start at once.
        let heading = self
            .last_heading
            .filter(|(th, _, _)| (t_s - th).abs() <= 1.0)
            .map(|(_, yaw, sigma)| (yaw, sigma));
        let yaw_and_sigma = match (heading, anchor) {
            (Some(h), _) => Some(h),
            (None, Some((a, local_a))) => {
                let (gx, gy) = (x_m - a[0], y_m - a[1]);
                let (lx, ly) = (local.x - local_a.x, local.y - local_a.y);
                let baseline = gx.hypot(gy);
                if t_s - a[2] > self.config.reset_after_rejected_s {
                    // Too long since the anchor: start the baseline again.
                    self.state = State::Uninitialised {
                        anchor: Some(([x_m, y_m, t_s], local)),
                        local,
                    };
                    return;
                }
                if baseline >= self.config.init_baseline_m
                    && lx.hypot(ly) >= 0.5 * self.config.init_baseline_m
                {
                    let rotation = gy.atan2(gx) - ly.atan2(lx);
                    let sigma = 2.0 * (sigma_m + lever) / baseline + 0.02;
                    Some((wrap_angle(local.yaw + rotation), sigma))
                } else {
                    None
                }
            }
            (None, None) => {
                self.state = State::Uninitialised {
                    anchor: Some(([x_m, y_m, t_s], local)),
                    local,
                };
                return;
            }
        };
        let Some((yaw, sigma_yaw)) = yaw_and_sigma else {
            return;
        };
        let arm = self.lever_arm_world(yaw);
        let x = StateVec::new(x_m - arm[0], y_m - arm[1], yaw, 0.0, 0.0, 0.0);
        let [scale_variance, difference_variance] = self.fresh_consider_variances();
        let sigma_pos = sigma_m + 0.5 * lever;
        let p = StateMat::from_diagonal(&StateVec::new(
            sigma_pos * sigma_pos,
            sigma_pos * sigma_pos,
            sigma_yaw * sigma_yaw,
            self.fresh_bias_variance(t_s),
            scale_variance,
            difference_variance,
        ));
        self.state = State::Running { x, p };
        self.stats.initialisations += 1;
        self.accept_fix(t_s);
    }

    fn accept_fix(&mut self, t_s: f64) {
        self.last_accepted_fix_s = Some(t_s);
        self.first_rejected_fix_s = None;
        self.rejected_in_a_row = 0;
    }

    fn update_gnss(
        &mut self,
        t_s: f64,
        x_m: f64,
        y_m: f64,
        sigma_m: f64,
    ) -> Result<(), FusionError> {
        let State::Running { x, p } = self.state else {
            return Ok(());
        };
        let [lx, ly] = self.config.lever_arm_m;
        let (s, c) = x[2].sin_cos();
        let predicted = [x[0] + lx * c - ly * s, x[1] + lx * s + ly * c];
        let nu = SVector::<f64, 2>::new(x_m - predicted[0], y_m - predicted[1]);
        let mut h = SMatrix::<f64, 2, N>::zeros();
        h[(0, 0)] = 1.0;
        h[(1, 1)] = 1.0;
        h[(0, 2)] = -lx * s - ly * c;
        h[(1, 2)] = lx * c - ly * s;
        let r = SMatrix::<f64, 2, 2>::identity() * sigma_m * sigma_m;
        let ph = p * h.transpose();
        let s_mat = h * ph + r;
        let chol = s_mat
            .cholesky()
            .ok_or(FusionError::NotPositiveDefinite { what: "gnss", t_s })?;
        let nis = nu.dot(&chol.solve(&nu));
        if !nis.is_finite() {
            return Err(FusionError::NonFinite {
                t_s,
                after: "gnss innovation",
            });
        }
        if nis > self.config.gnss_gate {
            self.stats.gnss_rejected += 1;
            self.rejected_in_a_row += 1;
            let first = *self.first_rejected_fix_s.get_or_insert(t_s);
            if self.rejected_in_a_row >= 3 && t_s - first >= self.config.reset_after_rejected_s {
                self.reset_position(t_s, x_m, y_m, sigma_m);
            }
            return Ok(());
        }
        let (x, p) = kalman_update(x, &p, &ph, &s_mat, &chol.inverse(), &nu);
        self.set_running(x, p, t_s, "gnss update")?;
        self.stats.gnss_accepted += 1;
        self.accept_fix(t_s);
        Ok(())
    }

    fn reset_position(&mut self, t_s: f64, x_m: f64, y_m: f64, sigma_m: f64) {
        if let State::Running { x, p } = &mut self.state {
            let [lx, ly] = self.config.lever_arm_m;
            let (s, c) = x[2].sin_cos();
            x[0] = x_m - (lx * c - ly * s);
            x[1] = y_m - (lx * s + ly * c);
            let var = (sigma_m + 0.5 * lx.hypot(ly)).powi(2);
            for i in 0..N {
                for j in 0..2 {
                    p[(i, j)] = 0.0;
                    p[(j, i)] = 0.0;
                }
            }
            p[(0, 0)] = var;
            p[(1, 1)] = var;
            p[(2, 2)] = p[(2, 2)].max(0.1f64.powi(2));
            self.stats.position_resets += 1;
            self.accept_fix(t_s);
        }
    }

    fn update_heading(
        &mut self,
        t_s: f64,
        yaw_rad: f64,
        sigma_rad: f64,
    ) -> Result<(), FusionError> {
        let State::Running { x, p } = self.state else {
            return Ok(());
        };
        let nu = SVector::<f64, 1>::new(wrap_angle(yaw_rad - x[2]));
        let mut h = SMatrix::<f64, 1, N>::zeros();
        h[(0, 2)] = 1.0;
        let r = SMatrix::<f64, 1, 1>::new(sigma_rad * sigma_rad);
        let ph = p * h.transpose();
        let s_mat = h * ph + r;
        let s = s_mat[(0, 0)];
        if !(s.is_finite() && s > 0.0) {
            return Err(FusionError::NotPositiveDefinite {
                what: "heading",
                t_s,
            });
        }
        if nu[0] * nu[0] / s > self.config.heading_gate {
            self.stats.heading_rejected += 1;
            return Ok(());
        }
        let s_inverse = SMatrix::<f64, 1, 1>::new(1.0 / s);
        let (x, p) = kalman_update(x, &p, &ph, &s_mat, &s_inverse, &nu);
        self.set_running(x, p, t_s, "heading update")?;
        self.stats.heading_accepted += 1;
        Ok(())
    }

    fn set_running(
        &mut self,
        x: StateVec,
        mut p: StateMat,
        t_s: f64,
        after: &'static str,
    ) -> Result<(), FusionError> {
        symmetrise(&mut p);
        if !all_finite(&x, &p) {
            return Err(FusionError::NonFinite { t_s, after });
        }
        self.state = State::Running { x, p };
        Ok(())
    }

    fn output(&self, t_s: f64) -> FusedPose {
        let mode = self.mode_at(t_s);
        let (pose, covariance) = match self.state {
            State::Running { x, p } => {
                let mut cov = [0.0; 9];
                for i in 0..3 {
                    for j in 0..3 {
                        cov[3 * i + j] = p[(i, j)];
                    }
                }
                (
                    Pose2 {
                        x: x[0],
                        y: x[1],
                        yaw: wrap_angle(x[2]),
                    },
                    cov,
                )
            }
            State::Uninitialised { .. } => (Pose2::default(), [0.0; 9]),
        };
        FusedPose {
            t_s,
            pose,
            covariance,
            mode,
            estimate_version: self.estimate_version,
        }
    }
}

/// Every entry of the state and its covariance is finite. (It runs at every
/// wheel sample: a fold over the plain slices, without an early exit, is
/// about 140 instructions against 340 with nalgebra's element iterator.)
fn all_finite(x: &StateVec, p: &StateMat) -> bool {
    let finite = |ok: bool, v: &f64| ok & v.is_finite();
    x.as_slice().iter().fold(true, finite) & p.as_slice().iter().fold(true, finite)
}

/// The predicted covariance `F P F^T + Q` for `F = I + E`, where `e` holds
/// E's only non-zero block (rows x, y, yaw; columns yaw to WHEEL_DIFF), and Q
/// is zero outside the pose block `q_pose` and the bias variance `q_bias`.
/// The same as the dense product up to rounding, in about a quarter of its
/// multiplications (it runs at every wheel sample, on the path to the pose),
/// and symmetric by construction.
fn propagate_covariance(
    p: &StateMat,
    e: &[[f64; 4]; 3],
    q_pose: &[[f64; 3]; 3],
    q_bias: f64,
) -> StateMat {
    // A = F P differs from P in rows 0-2 only.
    let fp: [[f64; N]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| p[(i, j)] + (0..4).map(|k| e[i][k] * p[(2 + k, j)]).sum::<f64>())
    });
    // A F^T differs from A in columns 0-2 only; outside the pose block it is
    // A's rows 0-2 mirrored, and rows and columns 3-5 keep P's values.
    let mut out = *p;
    for (i, row) in fp.iter().enumerate() {
        for j in 3..N {
            out[(i, j)] = row[j];
            out[(j, i)] = row[j];
        }
        for j in i..3 {
            let v = row[j] + (0..4).map(|k| row[2 + k] * e[j][k]).sum::<f64>() + q_pose[i][j];
            out[(i, j)] = v;
            out[(j, i)] = v;
        }
    }
    out[(3, 3)] += q_bias;
    out
}

fn symmetrise(p: &mut StateMat) {
    let t = p.transpose();
    *p = (*p + t) * 0.5;
}

/// Kalman update with gain `K = P H^T S^-1`, where `ph` is `P H^T` and `s`
/// is `H P H^T + R`. The distance scale and the wheel difference are consider
/// states (Schmidt-Kalman): their rows of the gain are zeroed, so they are
/// never estimated and keep their variances, and only widen the pose
/// covariance through the cross terms.
///
/// The covariance is the Joseph form `(I - K H) P (I - K H)^T + K R K^T`,
/// which holds for any gain (so also for the zeroed rows), written out as
/// `P - K B^T - B K^T + K S K^T` with `B = P H^T`: the same up to rounding in
/// under a third of the dense products' multiplications (a wakeup with a GNSS
/// fix and a heading runs two updates on the path to its pose), and symmetric
/// by construction.
fn kalman_update<const M: usize>(
    x: StateVec,
    p: &StateMat,
    ph: &SMatrix<f64, N, M>,
    s: &SMatrix<f64, M, M>,
    s_inverse: &SMatrix<f64, M, M>,
    nu: &SVector<f64, M>,
) -> (StateVec, StateMat) {
    let mut gain = ph * s_inverse;
    gain.row_mut(SCALE).fill(0.0);
    gain.row_mut(WHEEL_DIFF).fill(0.0);
    let x = x + gain * nu;
    let ks = gain * s;
    let mut out = *p;
    for i in 0..N {
        for j in i..N {
            let change: f64 = (0..M)
                .map(|m| (ks[(i, m)] - ph[(i, m)]) * gain[(j, m)] - gain[(i, m)] * ph[(j, m)])
                .sum();
            out[(i, j)] += change;
            out[(j, i)] = out[(i, j)];
        }
    }
    (x, out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate_file::Estimate;
    use crate::two_wheel::TwoWheelParams;

    use crate::test_drive::{C, TRACK};

    fn params() -> OdometryParams {
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

    fn config(heading: HeadingMode) -> FusionConfig {
        FusionConfig {
            odometer: OdometerConfig {
                heading,
                ..OdometerConfig::default()
            },
            ..FusionConfig::default()
        }
    }

    /// The structured prediction equals the dense `F P F^T + Q` (to
    /// rounding) for a full covariance with every correlation non-zero.
    #[test]
    fn the_structured_prediction_is_the_dense_product() {
        // A symmetric positive definite P = L L^T with L full lower-triangular.
        let l = StateMat::from_fn(|i, j| {
            if j <= i {
                0.3 + 0.1 * (i as f64) - 0.07 * (j as f64) + if i == j { 1.0 } else { 0.0 }
            } else {
                0.0
            }
        });
        let p = l * l.transpose();
        let e = [
            [-0.31, 0.02, 0.95, -0.004],
            [0.95, -0.03, 0.31, 0.006],
            [0.0, -0.01, 0.002, 0.66],
        ];
        let q_pose = [[2e-4, 1e-5, -3e-6], [1e-5, 3e-4, 4e-6], [-3e-6, 4e-6, 5e-6]];
        let q_bias = 7e-9;
        let mut f = StateMat::identity();
        let mut q = StateMat::zeros();
        for i in 0..3 {
            for k in 0..4 {
                f[(i, 2 + k)] += e[i][k];
            }
            for j in 0..3 {
                q[(i, j)] = q_pose[i][j];
            }
        }
        q[(3, 3)] = q_bias;
        let dense = f * p * f.transpose() + q;
        let structured = propagate_covariance(&p, &e, &q_pose, q_bias);
        assert_symmetric_and_equal(&structured, &dense, "the dense product");
    }

    /// `fast` is symmetric and equals `dense` to 1e-12 of its largest entry.
    fn assert_symmetric_and_equal(fast: &StateMat, dense: &StateMat, what: &str) {
        for i in 0..N {
            for j in 0..N {
                let (a, b) = (fast[(i, j)], dense[(i, j)]);
                assert!(
                    (a - b).abs() <= 1e-12 * dense.amax(),
                    "({i}, {j}): {a} against {b} from {what}"
                );
                assert_eq!(a, fast[(j, i)], "not symmetric at ({i}, {j})");
            }
        }
    }

    /// The expanded update equals the dense Joseph form
    /// `(I - K H) P (I - K H)^T + K R K^T` (to rounding) with the consider
    /// rows of the gain zeroed, for a GNSS fix with a lever arm and for a
    /// heading, on a full covariance with every correlation non-zero; the
    /// consider states keep their variances and covariance.
    #[test]
    fn the_expanded_update_is_the_joseph_form() {
        fn check<const M: usize>(p: &StateMat, h: SMatrix<f64, M, N>, r: SMatrix<f64, M, M>) {
            let x = StateVec::from_fn(|i, _| 0.1 * i as f64);
            let nu = SVector::<f64, M>::from_fn(|i, _| 0.3 - 0.5 * i as f64);
            let ph = p * h.transpose();
            let s = h * ph + r;
            let s_inverse = s.try_inverse().expect("S is invertible");
            let (x_new, p_new) = kalman_update(x, p, &ph, &s, &s_inverse, &nu);

            let mut gain = ph * s_inverse;
            gain.row_mut(SCALE).fill(0.0);
            gain.row_mut(WHEEL_DIFF).fill(0.0);
            let i_kh = StateMat::identity() - gain * h;
            let joseph = i_kh * p * i_kh.transpose() + gain * r * gain.transpose();
            assert!((x_new - (x + gain * nu)).amax() <= 1e-12);
            assert_symmetric_and_equal(&p_new, &joseph, "the Joseph form");
            for (i, j) in [
                (SCALE, SCALE),
                (SCALE, WHEEL_DIFF),
                (WHEEL_DIFF, WHEEL_DIFF),
            ] {
                assert_eq!(p_new[(i, j)], p[(i, j)], "consider covariance ({i}, {j})");
            }
            // The update took something off the pose's variance.
            assert!(p_new[(0, 0)] < p[(0, 0)] || p_new[(2, 2)] < p[(2, 2)]);
        }
        let l = StateMat::from_fn(|i, j| {
            if j <= i {
                0.2 - 0.05 * (i as f64) + 0.09 * (j as f64) + if i == j { 0.8 } else { 0.0 }
            } else {
                0.0
            }
        });
        let p = l * l.transpose();
        let (s, c) = 0.7f64.sin_cos();
        let (lx, ly) = (1.3, -0.4);
        let mut gnss = SMatrix::<f64, 2, N>::zeros();
        gnss[(0, 0)] = 1.0;
        gnss[(1, 1)] = 1.0;
        gnss[(0, 2)] = -lx * s - ly * c;
        gnss[(1, 2)] = lx * c - ly * s;
        check(&p, gnss, SMatrix::<f64, 2, 2>::identity() * 0.04);
        let mut heading = SMatrix::<f64, 1, N>::zeros();
        heading[(0, 2)] = 1.0;
        check(&p, heading, SMatrix::<f64, 1, 1>::new(1e-3));
    }

    /// Inputs of a drive on a gentle left curve at 10 m/s: wheels and gyro at
    /// 100 Hz, GNSS at 5 Hz (stamped 5 ms after the wheel instant) where
    /// `gnss` lets it through, truth returned too.
    struct Sim {
        inputs: Vec<Input>,
        truth: Vec<(f64, Pose2)>,
    }

    fn simulate(seconds: f64, gnss: &dyn Fn(f64) -> bool, gyro_bias: f64, yaw0: f64) -> Sim {
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

    #[test]
    fn a_resumed_pose_dead_reckons_at_once_and_fuses_when_gnss_comes() {
        // The car stood at the start pose; GNSS only from 10 s on.
        let sim = simulate(20.0, &|t| t >= 10.0, 0.0, 0.4);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        let start = sim.truth[0].1;
        let tiny = [1e-6, 0.0, 0.0, 0.0, 1e-6, 0.0, 0.0, 0.0, 1e-8];
        fusion.resume(start, &tiny).expect("resume");
        let poses = run(&mut fusion, &sim.inputs);
        assert_eq!(poses[0].mode, PoseMode::DeadReckoning);
        // The floors: what a parked car's pose may have lost.
        assert_eq!(poses[0].covariance[0], 0.25);
        assert_eq!(poses[0].covariance[8], 0.02f64.powi(2));
        for (pose, (t, truth)) in poses.iter().zip(&sim.truth) {
            if *t < 10.0 {
                assert_eq!(pose.mode, PoseMode::DeadReckoning, "t = {t}");
                let e = (pose.pose.x - truth.x).hypot(pose.pose.y - truth.y);
                assert!(e < 0.05, "t = {t}: {e} m");
            } else if *t > 10.5 {
                assert_eq!(pose.mode, PoseMode::Fused, "t = {t}");
            }
        }
        assert_eq!(fusion.stats().initialisations, 0);
        assert_eq!(fusion.stats().gnss_rejected, 0);

        // A pose that is not finite is refused, and the filter stays as it was.
        let mut fresh = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        let bad = Pose2 {
            x: f64::NAN,
            ..start
        };
        assert_eq!(fresh.resume(bad, &tiny), Err(FusionError::ResumeNotFinite));
        assert_eq!(fresh.mode_at(0.0), PoseMode::NoFix);
    }

    fn run(fusion: &mut Fusion, inputs: &[Input]) -> Vec<FusedPose> {
        inputs
            .iter()
            .filter_map(|i| fusion.process(i).expect("input accepted"))
            .collect()
    }

    #[test]
    fn no_fix_then_fused_then_dead_reckoning_through_an_outage() {
        let sim = simulate(60.0, &|t| !(30.0..45.0).contains(&t), 0.0, 0.7);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let poses = run(&mut fusion, &sim.inputs);
        assert_eq!(poses.len(), sim.truth.len());
        assert_eq!(poses[0].mode, PoseMode::NoFix);
        let at = |t: f64| ((t / 0.01).round()) as usize;
        // Initialised once the GNSS track moved the baseline (5 m at 10 m/s).
        assert_eq!(poses[at(5.0)].mode, PoseMode::Fused);
        assert_eq!(poses[at(29.0)].mode, PoseMode::Fused);
        assert_eq!(poses[at(31.5)].mode, PoseMode::DeadReckoning);
        assert_eq!(poses[at(44.9)].mode, PoseMode::DeadReckoning);
        assert_eq!(poses[at(46.0)].mode, PoseMode::Fused);
        for &t in &[10.0, 29.0, 44.9, 59.0] {
            let (p, truth) = (poses[at(t)].pose, sim.truth[at(t)].1);
            let err = (p.x - truth.x).hypot(p.y - truth.y);
            assert!(err < 0.5, "t = {t}: error {err} m, {p:?} vs {truth:?}");
            assert!(wrap_angle(p.yaw - truth.yaw).abs() < 0.02, "t = {t}");
        }
        // The covariance grows through the outage and shrinks after it.
        let var = |t: f64| poses[at(t)].covariance[0] + poses[at(t)].covariance[4];
        assert!(
            var(44.9) > 5.0 * var(29.0),
            "{} vs {}",
            var(44.9),
            var(29.0)
        );
        assert!(var(59.0) < var(44.9));
        let s = fusion.stats();
        assert_eq!(s.initialisations, 1);
        assert_eq!(s.gnss_rejected, 0, "{s:?}");
    }

    /// `inputs` with the rear-left and rear-right revolutions divided by
    /// `rl` and `rr`: wheels larger than the parameters say by those factors.
    fn with_larger_wheels(inputs: &[Input], rl: f64, rr: f64) -> Vec<Input> {
        inputs
            .iter()
            .map(|i| match *i {
                Input::Wheels {
                    t_s,
                    rl_rev,
                    rr_rev,
                } => Input::Wheels {
                    t_s,
                    rl_rev: rl_rev / rl,
                    rr_rev: rr_rev / rr,
                },
                other => other,
            })
            .collect()
    }

    #[test]
    fn after_an_outage_on_wheels_half_a_percent_off_the_first_fixes_are_taken() {
        // The calibration says 2.0 m; the wheels are 2.01 m (0.5 %, a scale
        // the WID drives move by between stretches). Gyro heading, 30 s
        // without GNSS: 1.5 m behind along the track at the end. With white
        // distance noise alone (no scale state) the filter claimed about
        // 0.1 m there and gated out every fix for 10 s (52 fixes; 2.8 m off
        // at 65 s) until it reset its position.
        let sim = simulate(80.0, &|t| !(30.0..60.0).contains(&t), 0.0, 0.3);
        let long = with_larger_wheels(&sim.inputs, 1.005, 1.005);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        let poses = run(&mut fusion, &long);
        let at = |t: f64| ((t / 0.01).round()) as usize;
        let err = |t: f64| {
            let (p, truth) = (poses[at(t)].pose, sim.truth[at(t)].1);
            (p.x - truth.x).hypot(p.y - truth.y)
        };
        assert!((1.0..2.0).contains(&err(59.99)), "{}", err(59.99));
        assert_eq!(poses[at(59.99)].mode, PoseMode::DeadReckoning);
        assert_eq!(poses[at(61.0)].mode, PoseMode::Fused);
        assert!(err(61.0) < 0.5, "{}", err(61.0));
        let s = fusion.stats();
        assert_eq!((s.gnss_rejected, s.position_resets), (0, 0), "{s:?}");
    }

    #[test]
    fn a_wheel_heading_through_an_outage_knows_its_wheels_may_differ() {
        // The right wheel is 0.1 % larger than calibrated: in wheel heading
        // the yaw turns by 0.001 ds / track, 0.2 rad over 300 m, and a 30 s
        // outage ends 32 m off. That end is inside the 95 % ellipse of the
        // pose's covariance with the relative circumference error considered
        // (1-sigma 0.1 %; chi-square 3.0), far outside it with white heading
        // noise alone (121).
        let sim = simulate(60.0, &|t| t < 30.0, 0.0, 0.3);
        let uneven = with_larger_wheels(&sim.inputs, 1.0, 1.001);
        let truth = sim.truth.last().expect("truth").1;
        let chi2_at_end = |config: FusionConfig| {
            let mut fusion = Fusion::new(params(), 0, config);
            let end = *run(&mut fusion, &uneven).last().expect("poses");
            assert_eq!(end.mode, PoseMode::DeadReckoning);
            let e = [end.pose.x - truth.x, end.pose.y - truth.y];
            let c = end.covariance;
            let chi2 = crate::fused_outages::position_chi2(e, [c[0], c[1], c[3], c[4]]);
            (e[0].hypot(e[1]), chi2.expect("invertible"))
        };
        let (err, chi2) = chi2_at_end(config(HeadingMode::WheelDifference));
        assert!(err > 20.0, "{err} m");
        assert!(
            chi2 < crate::fused_outages::CHI2_2DOF_95,
            "{chi2} ({err} m)"
        );
        let (_, white) = chi2_at_end(FusionConfig {
            wheel_difference_sigma: 0.0,
            ..config(HeadingMode::WheelDifference)
        });
        assert!(white > 10.0 * crate::fused_outages::CHI2_2DOF_95, "{white}");
    }

    #[test]
    fn dead_reckoning_mean_equals_the_dead_reckoner() {
        // Fixes only for the first 10 s; afterwards the filter mean must follow
        // exactly the dead-reckoner started from the same pose.
        let sim = simulate(40.0, &|t| t < 10.0, 0.0, 0.2);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let split = sim.inputs.iter().position(|i| i.t_s() > 12.0).unwrap();
        let poses = run(&mut fusion, &sim.inputs[..split]);
        let start = poses.last().unwrap();
        let mut dr = crate::dead_reckoning::DeadReckoner::new(
            params(),
            config(HeadingMode::WheelDifference).odometer,
            start.pose,
        );
        // Re-feed the gyro history so that both start from the same state.
        for i in &sim.inputs[..split] {
            match *i {
                Input::Imu { t_s, gz_rad_s } if t_s > 11.0 => dr.gyro(t_s, gz_rad_s).unwrap(),
                Input::Wheels {
                    t_s,
                    rl_rev,
                    rr_rev,
                } if t_s == start.t_s => {
                    dr.wheels(t_s, rl_rev, rr_rev).unwrap();
                }
                _ => {}
            }
        }
        for i in &sim.inputs[split..] {
            let out = fusion.process(i).unwrap();
            let dr_pose = match *i {
                Input::Imu { t_s, gz_rad_s } => {
                    dr.gyro(t_s, gz_rad_s).unwrap();
                    None
                }
                Input::Wheels {
                    t_s,
                    rl_rev,
                    rr_rev,
                } => Some(dr.wheels(t_s, rl_rev, rr_rev).unwrap()),
                _ => None,
            };
            if let (Some(f), Some(d)) = (out, dr_pose) {
                assert_eq!(f.mode, PoseMode::DeadReckoning);
                assert!(
                    (f.pose.x - d.x).hypot(f.pose.y - d.y) < 1e-6,
                    "{f:?} vs {d:?}"
                );
            }
        }
    }

    /// 5 s standing (gyro reading `bias`, no GNSS), then `drive` shifted 5 s later.
    fn stand_then_drive(bias: f64, drive: &Sim) -> Vec<Input> {
        let mut inputs = Vec::new();
        for i in 0..500 {
            let t = f64::from(i) * 0.01;
            inputs.push(Input::Imu {
                t_s: t,
                gz_rad_s: bias,
            });
            inputs.push(Input::Wheels {
                t_s: t,
                rl_rev: 0.0,
                rr_rev: 0.0,
            });
        }
        inputs.extend(drive.inputs.iter().map(|i| match *i {
            Input::Imu { t_s, gz_rad_s } => Input::Imu {
                t_s: t_s + 5.0,
                gz_rad_s,
            },
            Input::Wheels {
                t_s,
                rl_rev,
                rr_rev,
            } => Input::Wheels {
                t_s: t_s + 5.0,
                rl_rev,
                rr_rev,
            },
            Input::Gnss {
                t_s,
                x_m,
                y_m,
                sigma_m,
            } => Input::Gnss {
                t_s: t_s + 5.0,
                x_m,
                y_m,
                sigma_m,
            },
            other => other,
        }));
        inputs
    }

    #[test]
    fn a_standstill_before_the_first_fix_keeps_a_gnss_jump_from_pulling_the_bias() {
        // wid-trial04: the car stood, the filter started at the first fixes,
        // and RTK jumps of 0.6 m sideways for 2 s in a turn soon after taught
        // the residual bias 2.9e-3 rad/s against 7e-5 measured at the
        // standstill: 10 m off after the next 30 s outage instead of 0.1 m.
        // Here: fixes 0.8 m off for 2 s, 5 s after moving off, then an outage
        // from 30 s to 60 s. With the standstill forgotten (residual starting
        // at 1e-3 rad/s) this ended 0.86 m off with the bias 1.6e-4 rad/s
        // wrong; knowing it, 0.03 m.
        let bias = 0.003;
        let sim = simulate(60.0, &|t| t < 30.0, bias, 0.0);
        let mut inputs = stand_then_drive(bias, &sim);
        for input in &mut inputs {
            if let Input::Gnss { t_s, y_m, .. } = input {
                if (10.0..12.0).contains(t_s) {
                    *y_m += 0.8;
                }
            }
        }
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        let poses = run(&mut fusion, &inputs);
        assert_eq!(fusion.stats().gyro_bias_standstills, 1);
        let end = poses.last().expect("poses");
        assert_eq!(end.mode, PoseMode::DeadReckoning);
        let truth = sim.truth.last().expect("truth").1;
        let err = (end.pose.x - truth.x).hypot(end.pose.y - truth.y);
        assert!(err < 0.2, "{err} m off after the outage");
        let bias_err = (fusion.gyro_bias() - bias).abs();
        assert!(bias_err < 3e-5, "bias {bias_err} rad/s off");
    }

    #[test]
    fn a_car_standing_before_it_drives_off_measures_its_gyro_bias() {
        let bias = 0.003;
        let inputs = stand_then_drive(bias, &simulate(30.0, &|_| true, bias, 0.0));
        let moved_off = inputs.partition_point(|i| i.t_s() <= 5.01);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        run(&mut fusion, &inputs[..moved_off]);
        assert_eq!(fusion.stats().gyro_bias_standstills, 1);
        assert!(
            (fusion.gyro_bias() - bias).abs() < 1e-5,
            "{}",
            fusion.gyro_bias()
        );
        run(&mut fusion, &inputs[moved_off..]);
        assert!(
            (fusion.gyro_bias() - bias).abs() < 2e-4,
            "{}",
            fusion.gyro_bias()
        );

        let mut kept = Fusion::new(
            params(),
            0,
            FusionConfig {
                odometer: OdometerConfig {
                    learn_gyro_bias: false,
                    ..config(HeadingMode::Gyro).odometer
                },
                ..config(HeadingMode::Gyro)
            },
        );
        run(&mut kept, &inputs[..moved_off]);
        assert_eq!(kept.stats().gyro_bias_standstills, 0);
        assert_eq!(kept.gyro_bias(), 0.0);
    }

    #[test]
    fn a_standstill_bias_measurement_updates_the_total_bias_once() {
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        // Running, with a residual bias of 2e-4 +- 1e-4 on top of the odometer's 0.
        let mut p = StateMat::identity() * 0.01;
        p[(3, 3)] = 1e-8;
        fusion.state = State::Running {
            x: StateVec::new(0.0, 0.0, 0.0, 2e-4, 0.0, 0.0),
            p,
        };
        // The standstill says 1e-3 +- 1e-4; the odometer moved its own bias to 5e-4.
        let obs = BiasObservation {
            t_s: 1.0,
            mean_rad_s: 1e-3,
            variance: 1e-8,
            bias_before_rad_s: 0.0,
            bias_after_rad_s: 5e-4,
        };
        fusion.observe_bias(&obs).unwrap();
        let State::Running { x, p } = fusion.state else {
            panic!("not running")
        };
        // Equal variances: the total is the mean of 2e-4 and 1e-3, whatever
        // the odometer's bias, and its variance halves.
        assert!((5e-4 + x[3] - 6e-4).abs() < 1e-12, "residual {}", x[3]);
        assert!((p[(3, 3)] - 0.5e-8).abs() < 1e-15, "{}", p[(3, 3)]);
        assert_eq!(
            (x[0], x[1], x[2]),
            (0.0, 0.0, 0.0),
            "uncorrelated: pose unmoved"
        );
        // Wheel heading: the bias is not the filter's business.
        let mut wheels = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        wheels.state = State::Running {
            x: StateVec::zeros(),
            p: StateMat::identity(),
        };
        wheels.observe_bias(&obs).unwrap();
        assert!(matches!(wheels.state, State::Running { x, .. } if x == StateVec::zeros()));
    }

    #[test]
    fn residual_gyro_bias_is_learned_while_fused() {
        let bias = 0.004;
        let sim = simulate(90.0, &|t| t < 60.0, bias, 0.0);
        let mut with = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        let poses = run(&mut with, &sim.inputs);
        let end = poses.last().unwrap();
        let truth = sim.truth.last().unwrap().1;
        let err = (end.pose.x - truth.x).hypot(end.pose.y - truth.y);
        // Unlearned, 0.004 rad/s over 30 s at 10 m/s is about 18 m off.
        assert!(
            err < 3.0,
            "error after a 30 s outage with a learned bias: {err} m"
        );
        let State::Running { x, .. } = with.state else {
            panic!("not running")
        };
        assert!((x[3] - bias).abs() < 0.001, "residual bias {}", x[3]);
    }

    #[test]
    fn nominal_circumferences_8_percent_off_keep_fusing() {
        // The wheels are 2.0 m; vehicle.toml guesses 2.16 m (8 % off, the
        // paper's 2.2 m against 2.04 m).
        let sim = simulate(60.0, &|_| true, 0.0, 0.0);
        let vehicle = VehicleParams {
            name: None,
            track_width_m: TRACK,
            nominal_circumference_m: 2.16,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: Default::default(),
        };
        let cfg = config(HeadingMode::Gyro);
        let mut nominal = Fusion::nominal(&vehicle, cfg);
        let poses = run(&mut nominal, &sim.inputs);
        // Trusting the guess like a calibration instead:
        let mut trusting = Fusion::new(OdometryParams::nominal(&vehicle), 0, cfg);
        let trusting_poses = run(&mut trusting, &sim.inputs);
        let dead = |p: &[FusedPose]| {
            p.iter()
                .filter(|p| p.mode == PoseMode::DeadReckoning)
                .count()
        };
        let (n, t) = (nominal.stats(), trusting.stats());
        assert_eq!((n.gnss_rejected, n.position_resets), (0, 0), "{n:?}");
        assert_eq!(dead(&poses), 0);
        let end = poses.last().unwrap();
        let truth = sim.truth.last().unwrap().1;
        let err = (end.pose.x - truth.x).hypot(end.pose.y - truth.y);
        println!("nominal filter: {err:.2} m from the truth at the end");
        // It lags the fixes along the track (its scale is considered, not
        // estimated), by about a metre here, but follows them.
        assert!(err < 2.0, "{end:?}");
        // A filter trusting the guess like a calibration (0.5 % scale) drifts
        // 0.8 m/s along the track, gates out most fixes and dead-reckons
        // between position resets.
        assert!(t.gnss_rejected > 100 && t.position_resets >= 1, "{t:?}");
        assert!(dead(&trusting_poses) > 1000);
    }

    #[test]
    fn outlier_fixes_are_gated_and_a_lost_filter_resets() {
        let mut sim = simulate(40.0, &|_| true, 0.0, 0.0);
        // One wild fix at 15 s.
        for i in sim.inputs.iter_mut() {
            if let Input::Gnss { t_s, x_m, .. } = i {
                if (*t_s - 15.005).abs() < 1e-9 {
                    *x_m += 50.0;
                }
            }
        }
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let poses = run(&mut fusion, &sim.inputs);
        assert_eq!(fusion.stats().gnss_rejected, 1);
        assert!(poses.iter().all(|p| p.mode != PoseMode::DeadReckoning));
        // Now every fix after 20 s is shifted 30 m: gated at first, then a reset.
        let mut shifted = simulate(50.0, &|_| true, 0.0, 0.0);
        for i in shifted.inputs.iter_mut() {
            if let Input::Gnss { t_s, y_m, .. } = i {
                if *t_s > 20.0 {
                    *y_m += 30.0;
                }
            }
        }
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let poses = run(&mut fusion, &shifted.inputs);
        let s = fusion.stats();
        assert_eq!(s.position_resets, 1, "{s:?}");
        assert!(
            poses[2500].mode == PoseMode::DeadReckoning,
            "fixes gated out: dead-reckoning"
        );
        let last = poses.last().unwrap();
        let truth = shifted.truth.last().unwrap().1;
        assert!(
            (last.pose.y - truth.y - 30.0).abs() < 0.5,
            "follows the fixes after the reset"
        );
        assert_eq!(last.mode, PoseMode::Fused);
    }

    #[test]
    fn heading_initialises_at_the_first_fix_and_wrong_headings_are_gated() {
        let mut sim = simulate(20.0, &|_| true, 0.0, 2.5);
        let heading_at = |t: f64, sim: &Sim| sim.truth[(t / 0.01).round() as usize].1.yaw;
        let mut headings: Vec<Input> = (0..200)
            .map(|k| {
                let t = k as f64 * 0.1;
                let wrong = if k == 100 { 1.0 } else { 0.0 };
                Input::Heading {
                    t_s: t,
                    yaw_rad: wrap_angle(heading_at(t, &sim) + wrong),
                    sigma_rad: Some(0.02),
                }
            })
            .collect();
        sim.inputs.append(&mut headings);
        crate::inputs::sort_inputs(&mut sim.inputs);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let poses = run(&mut fusion, &sim.inputs);
        assert_eq!(poses[0].mode, PoseMode::NoFix, "before the first fix");
        assert_eq!(
            poses[1].mode,
            PoseMode::Fused,
            "heading + fix: initialised at the first fix"
        );
        assert_eq!(fusion.stats().heading_rejected, 1);
        assert!(fusion.stats().heading_accepted > 150);
    }

    #[test]
    fn estimate_switch_does_not_move_the_pose() {
        let sim = simulate(20.0, &|t| t < 10.0, 0.0, 0.0);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let split = sim.inputs.iter().position(|i| i.t_s() > 15.0).unwrap();
        let before = *run(&mut fusion, &sim.inputs[..split]).last().unwrap();
        let mut new = params();
        new.two_wheel.c_rl = 2.02;
        new.two_wheel.c_rr = 2.02;
        let old = fusion.set_estimate(new, 3);
        assert_eq!(old, params());
        let after = run(&mut fusion, &sim.inputs[split..split + 3]);
        let first = after[0];
        assert_eq!(first.estimate_version, 3);
        // One wheel step at 10 m/s with 1 % longer circumferences: 0.101 m.
        let step = (first.pose.x - before.pose.x).hypot(first.pose.y - before.pose.y);
        assert!((step - 0.101).abs() < 1e-6, "{step}");
    }

    #[test]
    fn stale_wheels_go_back_to_no_fix() {
        let sim = simulate(20.0, &|_| true, 0.0, 0.0);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let poses = run(&mut fusion, &sim.inputs[..sim.inputs.len() / 2]);
        assert_eq!(poses.last().unwrap().mode, PoseMode::Fused);
        fusion.mark_stale();
        assert_eq!(fusion.mode_at(10.0), PoseMode::NoFix);
        assert_eq!(fusion.stats().stale, 1);
        // A gap in the wheel samples longer than stale_after_s does the same.
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let gap: Vec<Input> = sim
            .inputs
            .iter()
            .copied()
            .filter(|i| !(matches!(i, Input::Wheels { .. }) && (8.0..9.0).contains(&i.t_s())))
            .collect();
        let poses = run(&mut fusion, &gap);
        let after_gap = poses.iter().find(|p| p.t_s >= 9.0).unwrap();
        assert_eq!(after_gap.mode, PoseMode::NoFix);
        assert_eq!(
            poses.last().unwrap().mode,
            PoseMode::Fused,
            "initialises again"
        );
    }

    /// `sim`'s inputs with its fixes moved to an antenna at `arm` (body x, y).
    fn antenna_fixes(sim: &Sim, arm: [f64; 2]) -> Vec<Input> {
        sim.inputs
            .iter()
            .map(|i| match *i {
                Input::Gnss {
                    t_s,
                    x_m,
                    y_m,
                    sigma_m,
                } => {
                    let k = ((t_s - 0.005) / 0.01).round() as usize;
                    let (s, c) = sim.truth[k].1.yaw.sin_cos();
                    Input::Gnss {
                        t_s,
                        x_m: x_m + arm[0] * c - arm[1] * s,
                        y_m: y_m + arm[0] * s + arm[1] * c,
                        sigma_m,
                    }
                }
                other => other,
            })
            .collect()
    }

    /// Distance of each pose from the truth at its time, m.
    fn errors(sim: &Sim, poses: &[FusedPose]) -> Vec<f64> {
        poses
            .iter()
            .map(|p| {
                let k = (p.t_s / 0.01).round() as usize;
                let truth = sim.truth[k].1;
                (p.pose.x - truth.x).hypot(p.pose.y - truth.y)
            })
            .collect()
    }

    #[test]
    fn lever_arm_is_taken_into_account() {
        // Antenna 1.2 m ahead of the rear axle: fixes are of the antenna.
        let sim = simulate(30.0, &|_| true, 0.0, 0.0);
        let inputs = antenna_fixes(&sim, [1.2, 0.0]);
        let mut cfg = config(HeadingMode::WheelDifference);
        cfg.lever_arm_m = [1.2, 0.0];
        let mut fusion = Fusion::new(params(), 0, cfg);
        let poses = run(&mut fusion, &inputs);
        let (p, truth) = (poses.last().unwrap().pose, sim.truth.last().unwrap().1);
        assert!(
            (p.x - truth.x).hypot(p.y - truth.y) < 0.2,
            "{p:?} vs {truth:?}"
        );
    }

    #[test]
    fn an_estimates_antenna_moves_the_pose_from_the_antenna_track_to_the_axle() {
        // No measured antenna: the filter starts with it at the axle, so its
        // pose is the antenna's track, 1.24 m off. An estimate that carries
        // the calibrated antenna puts the pose on the axle at once.
        let arm = [1.2, 0.3];
        let sim = simulate(30.0, &|_| true, 0.0, 0.0);
        let inputs = antenna_fixes(&sim, arm);
        let split = inputs.iter().position(|i| i.t_s() > 15.0).unwrap();
        let estimate = Input::Estimate {
            t_s: 15.0,
            version: 1,
            estimate: Estimate {
                params: params(),
                sigma_m: None,
                quality_m: None,
                antenna_m: Some(arm),
                antenna_sigma_m: None,
            },
        };
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        let before = run(&mut fusion, &inputs[..split]);
        let before_err = errors(&sim, &before[before.len() - 100..]);
        assert!(
            before_err.iter().all(|e| (e - 1.237).abs() < 0.1),
            "{before_err:?}"
        );
        run(&mut fusion, &[estimate]);
        assert_eq!(fusion.lever_arm(), arm);
        let after = run(&mut fusion, &inputs[split..]);
        // From 1.24 m to at most 0.2 m at once (the yaw the filter learned
        // from the antenna's track is off by the arm's share of the course
        // in turns, which the next fixes mend), then within 5 cm.
        let after_err = errors(&sim, &after);
        let worst = after_err.iter().cloned().fold(0.0, f64::max);
        let tail = &after_err[after_err.len() / 2..];
        let tail_worst = tail.iter().cloned().fold(0.0, f64::max);
        assert!(
            worst < 0.2 && tail_worst < 0.05,
            "worst {worst} m, in the last half {tail_worst} m"
        );
        assert_eq!(fusion.stats().gnss_rejected, 0, "no fix gated by the move");

        // A measured antenna (vehicle.toml) is never replaced by an estimate's.
        let mut cfg = config(HeadingMode::Gyro);
        cfg.lever_arm_m = arm;
        cfg.lever_arm_from_estimates = false;
        let mut fusion = Fusion::new(params(), 0, cfg);
        run(&mut fusion, &inputs[..split]);
        let Input::Estimate {
            estimate: mut e, ..
        } = estimate
        else {
            unreachable!()
        };
        e.antenna_m = Some([0.0, 0.0]);
        run(
            &mut fusion,
            &[Input::Estimate {
                t_s: 15.0,
                version: 1,
                estimate: e,
            }],
        );
        assert_eq!(fusion.lever_arm(), arm);
        // A non-finite antenna is refused and changes nothing.
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        e.antenna_m = Some([f64::NAN, 0.0]);
        let err = fusion
            .process(&Input::Estimate {
                t_s: 0.0,
                version: 2,
                estimate: e,
            })
            .unwrap_err();
        assert!(err.to_string().contains("antenna"), "{err}");
        assert_eq!(
            (fusion.lever_arm(), fusion.estimate_version()),
            ([0.0, 0.0], 0)
        );
    }

    #[test]
    fn non_finite_inputs_are_rejected_without_harm() {
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let err = fusion
            .process(&Input::Gnss {
                t_s: 0.0,
                x_m: f64::NAN,
                y_m: 0.0,
                sigma_m: None,
            })
            .unwrap_err();
        assert!(
            err.to_string().contains("gnss") && err.to_string().contains("non-finite"),
            "{err}"
        );
        assert!(matches!(
            fusion.process(&Input::Wheels {
                t_s: 0.0,
                rl_rev: f64::INFINITY,
                rr_rev: 0.0
            }),
            Err(ProcessError::Input(_))
        ));
    }

    #[test]
    fn broken_covariance_is_a_typed_error_not_a_panic() {
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        fusion.state = State::Running {
            x: StateVec::zeros(),
            p: StateMat::from_element(f64::NAN),
        };
        fusion
            .process(&Input::Gnss {
                t_s: 0.0,
                x_m: 0.0,
                y_m: 0.0,
                sigma_m: None,
            })
            .unwrap();
        let err = fusion
            .process(&Input::Wheels {
                t_s: 0.0,
                rl_rev: 0.0,
                rr_rev: 0.0,
            })
            .unwrap_err();
        assert!(matches!(err, ProcessError::Numerical(_)), "{err}");
        assert_eq!(
            fusion.mode_at(0.0),
            PoseMode::NoFix,
            "reset after the failure"
        );
    }
}
