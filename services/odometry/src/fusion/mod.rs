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
//! - Prediction: the increments of the same
//!   [`Odometer`](crate::dead_reckoning::Odometer) that `odometry
//!   evaluate` dead-reckons with (distance from the calibrated rear wheels,
//!   heading from the wheel difference or the calibrated gyro), stepped with
//!   the 2W model's eq. (1); in gyro heading the residual bias is subtracted
//!   and slowly random-walks. It starts at zero with
//!   [`FusionConfig::initial_gyro_bias_sigma`], or, once a standstill has
//!   measured the bias (before the first fix too), with what the odometer
//!   knows of it
//!   ([`Odometer::gyro_bias_variance`](crate::dead_reckoning::Odometer::gyro_bias_variance))
//!   grown by the walk since.
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
//! Modes ([`PoseMode`](interfaces::wire::PoseMode)):
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
//! (with at least three in a row; after a resumed pose, any three in a row)
//! mean the filter has lost itself, its yaw as much as its position (a wrong
//! yaw makes every later fix look wrong): it starts again from the fixes,
//! at once with a recent heading, else `NoFix` until the GNSS track gives
//! the yaw over a baseline. Headings rejected in a row for that long, with
//! no fix accepted meanwhile, give the yaw instead, and the position's
//! covariance grows by what the wrong yaw may have swept.
//!
//! Pure: no clock, no I/O; numerical failure is a [`FusionError`].
//!
//! The parts, each in its own file:
//! - `state`: the state vector's layout and the filter before and after its
//!   initialisation;
//! - `kalman`: the Kalman maths on that layout (the predicted covariance,
//!   the update with the consider states, the chi-square quantiles and the
//!   chi-square of an error against its covariance);
//! - `config`, `error`: the tuning and the failures;
//! - `filter`: [`Fusion`] itself, its outputs and counters;
//! - `queue`: measurements waiting for the wheel sample after them;
//! - `lever_arm`: the GNSS antenna's position on the body;
//! - `bias`: the residual gyro bias and the standstill measurements of it;
//! - `estimate`: a new estimate, and the consider states' variances;
//! - `modes`: `NoFix`, `Fused` and `DeadReckoning`, initialisation, a
//!   resumed pose, stale inputs;
//! - `predict`: the prediction on the odometer's increments;
//! - `measure`: the GNSS and heading updates, their gates and the reset of
//!   a lost filter;
//! - `process`: one input in, a pose out at every wheel sample;
//! - `rehearsal`: the work of a made-up wheel sample, run on a copy;
//! - `scale_check`: whether the fixes contradict the estimate's wheel scale
//!   ([`Fusion::take_contradiction`]).

mod bias;
mod config;
mod error;
mod estimate;
mod filter;
mod kalman;
mod lever_arm;
mod measure;
mod modes;
mod predict;
mod process;
mod queue;
mod rehearsal;
mod scale_check;
mod state;
#[cfg(test)]
mod test_support;

pub use config::FusionConfig;
pub use error::{FusionError, ProcessError};
pub use filter::{FusedPose, Fusion, FusionStats};
pub use kalman::{position_chi2, CHI2_1DOF_999, CHI2_2DOF_95, CHI2_2DOF_999};
pub use queue::MAX_PENDING;
pub use scale_check::{Contradiction, CHI2_1DOF_1E6};
