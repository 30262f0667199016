//! Stage 4, the fits: the paper's method ([`paper`] on the [`ekf`]), the
//! batch fit ([`batch`] with [`lm`]), the wheel + gyro model ([`gyro`]),
//! the track width's plausibility ([`track_width`]) and dead-reckoning
//! errors on held-out data ([`holdout`]).

pub mod batch;
pub mod ekf;
pub mod gyro;
pub mod holdout;
pub mod lm;
pub mod paper;
pub mod track_width;
