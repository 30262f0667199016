//! Odometry: the 2W model, dead-reckoning through GNSS outages and the fusion
//! that keeps the pose while GNSS is good.
//!
//! - The 2W model and the estimate contract live in the `vehicle-model` library.
//! - [`cadence`]: when the next wheel sample is due (the serving loop wakes before it).
//! - [`dead_reckoning`]: the sample-by-sample dead-reckoner (wheel or gyro heading).
//! - [`inputs`]: the odometry's inputs in processing order.
//! - [`evaluate`]: simulated GNSS outages scored against the truth.
//! - [`evaluation_page`]: an evaluation's figures and HTML page.
//! - [`fusion`]: the EKF and its modes (Fused, DeadReckoning, NoFix).
//! - [`fused_outages`]: GNSS outages through the filter (the served pose).
//! - [`rewind`]: samples that arrive late, taken in order by going back.
//! - [`kept_pose`]: the pose kept across power cycles, as its file holds it.
//! - [`restart`]: whether a pose kept by an earlier run may be started from.
//!
//! The `odometry` binary holds the process: the `serve` loop over iceoryx2
//! and the pose state file.

pub mod cadence;
pub mod dead_reckoning;
pub mod evaluate;
pub mod evaluation_page;
pub mod fused_outages;
pub mod fusion;
pub mod inputs;
pub mod kept_pose;
pub mod restart;
pub mod rewind;
#[cfg(test)]
mod test_drive;
