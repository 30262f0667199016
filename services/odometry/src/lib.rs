//! Odometry: the 2W model, dead-reckoning through GNSS outages and the fusion
//! that keeps the pose while GNSS is good.

pub mod two_wheel;
