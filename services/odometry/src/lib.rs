//! Odometry: the 2W model, dead-reckoning through GNSS outages and the fusion
//! that keeps the pose while GNSS is good.
//!
//! - [`two_wheel`]: the paper's 2W model, eq. (1)-(2).
//! - [`cadence`]: when the next wheel sample is due (the serving loop wakes before it).
//! - [`estimate_file`]: odometry parameters from `vehicle.toml`, the
//!   calibrator's JSON or the wire estimate.
//! - [`dead_reckoning`]: the sample-by-sample dead-reckoner (wheel or gyro heading).
//! - [`inputs`]: the odometry's inputs in processing order.
//! - [`evaluate`]: simulated GNSS outages scored against the truth.
//! - [`fusion`]: the EKF and its modes (Fused, DeadReckoning, NoFix).
//! - [`fused_outages`]: GNSS outages through the filter (the served pose).
//! - [`pose_state`]: the last pose, kept across power cycles.
//! - [`rewind`]: samples that arrive late, taken in order by going back.
//! - [`serve`]: the iceoryx2 pose service.

pub mod cadence;
pub mod dead_reckoning;
pub mod estimate_file;
pub mod evaluate;
pub mod fused_outages;
pub mod fusion;
pub mod inputs;
pub mod pose_state;
pub mod rewind;
pub mod serve;
#[cfg(test)]
mod test_drive;
pub mod two_wheel;
