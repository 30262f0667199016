//! Odometry: the 2W model, dead-reckoning through GNSS outages and the fusion
//! that keeps the pose while GNSS is good.

pub mod dead_reckoning;
pub mod estimate_file;
pub mod evaluate;
pub mod fusion;
pub mod inputs;
pub mod serve;
pub mod two_wheel;
