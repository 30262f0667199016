//! The filter itself: [`Fusion`], the pose it gives ([`FusedPose`]) and
//! what it counts ([`FusionStats`]); its construction, its accessors, and
//! the store of a new running state that every update ends with.

use super::config::FusionConfig;
use super::error::FusionError;
use super::kalman::symmetrise;
use super::queue::Pending;
use super::scale_check::{Contradiction, ScaleCheck};
use super::state::{all_finite, State, StateMat, StateVec};
use crate::dead_reckoning::Odometer;
use interfaces::drive::VehicleParams;
use interfaces::wire::PoseMode;
use vehicle_model::estimate::OdometryParams;
use vehicle_model::two_wheel::Pose2;

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
    /// Times the filter found itself lost (fixes rejected in a row, see
    /// [`FusionConfig::reset_after_rejected_s`]) and started again from the
    /// fixes: position from the fix, yaw from a recent heading or a new
    /// GNSS baseline.
    pub position_resets: u64,
    /// Times the yaw was taken from the headings after they were rejected
    /// in a row with no fix accepted meanwhile (see
    /// [`FusionConfig::reset_after_rejected_s`]).
    pub yaw_resets: u64,
    /// Times the inputs went stale.
    pub stale: u64,
    /// Gyro bias measurements taken at standstill.
    pub gyro_bias_standstills: u64,
}

/// The EKF with its mode logic. Feed every [`Input`](crate::inputs::Input) in processing order
/// (see [`crate::inputs`]); a pose comes out at every wheel sample.
#[derive(Debug, Clone)]
pub struct Fusion {
    pub(super) config: FusionConfig,
    pub(super) odometer: Odometer,
    /// The circumferences are the nominal guess (no estimate taken yet).
    pub(super) nominal: bool,
    pub(super) estimate_version: u64,
    pub(super) state: State,
    pub(super) pending: Pending,
    /// Last wheel sample (t, rl, rr).
    pub(super) last_wheels: Option<(f64, f64, f64)>,
    pub(super) last_heading: Option<(f64, f64, f64)>,
    pub(super) last_accepted_fix_s: Option<f64>,
    pub(super) first_rejected_fix_s: Option<f64>,
    pub(super) rejected_in_a_row: u32,
    /// Headings rejected in a row, and the time of the first of them.
    pub(super) headings_rejected_in_a_row: u32,
    pub(super) first_rejected_heading_s: Option<f64>,
    /// Distance driven (sum of |ds|) at the first of those headings, m.
    pub(super) travelled_at_rejected_heading_m: f64,
    /// Distance driven since the filter was made, sum of |ds|, m.
    pub(super) travelled_m: f64,
    /// Resumed from a kept pose and no fix accepted since: three fixes
    /// rejected in a row are enough to start again from the fixes (the kept
    /// pose may be from somewhere else).
    pub(super) resumed_unconfirmed: bool,
    /// Time of the last standstill gyro bias measurement, s.
    pub(super) last_standstill_bias_s: Option<f64>,
    pub(super) stats: FusionStats,
    /// The estimate's wheel scale against the fixes.
    pub(super) scale_check: ScaleCheck,
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
            pending: Pending::default(),
            last_wheels: None,
            last_heading: None,
            last_accepted_fix_s: None,
            first_rejected_fix_s: None,
            rejected_in_a_row: 0,
            headings_rejected_in_a_row: 0,
            first_rejected_heading_s: None,
            travelled_at_rejected_heading_m: 0.0,
            travelled_m: 0.0,
            resumed_unconfirmed: false,
            last_standstill_bias_s: None,
            stats: FusionStats::default(),
            scale_check: ScaleCheck::default(),
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

    /// The fixes contradict the estimate in use (see `fusion::scale_check`):
    /// returned once, at the fix that shows it. The filter keeps the
    /// estimate; the caller drops it and switches to the one before
    /// ([`Fusion::set_estimate`], [`Fusion::set_nominal`]).
    pub fn take_contradiction(&mut self) -> Option<Contradiction> {
        self.scale_check.take()
    }

    /// The wheels' scale the fixes measure relative to the estimate in use,
    /// its 1-sigma and the distance it stands on, m; `None` before the
    /// first comparison.
    pub fn measured_scale(&self) -> Option<(f64, f64, f64)> {
        self.scale_check.measured()
    }

    /// Back to the nominal `vehicle.toml` values between two samples (an
    /// estimate dropped with nothing before it), trusted as the nominal
    /// guess (see [`Fusion::nominal`]).
    pub fn set_nominal(&mut self, vehicle: &VehicleParams) {
        self.set_estimate(OdometryParams::nominal(vehicle), 0);
        self.nominal = true;
        let [scale_variance, difference_variance] = self.fresh_consider_variances();
        if let State::Running { p, .. } = &mut self.state {
            p[(super::state::SCALE, super::state::SCALE)] = scale_variance;
            p[(super::state::WHEEL_DIFF, super::state::WHEEL_DIFF)] = difference_variance;
        }
    }

    /// The parameters in use.
    pub fn params(&self) -> &OdometryParams {
        self.odometer.params()
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

    /// Store a running state, symmetrised, unless it is not finite.
    pub(super) fn set_running(
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
}
