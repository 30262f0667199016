//! The vehicle model that the calibrator, the odometry and the tests share:
//! one home for the 2W odometry model and for the estimate that carries its
//! parameters between the services.
//!
//! - [`two_wheel`]: the paper's two-wheel (2W) model, eq. (1)-(2): the pose
//!   increment from the rear wheels' rotations, the circumferences and the
//!   track width; dead-reckoning over a drive.
//! - [`effects`]: the 2W model extended with the physics-catalogue effects
//!   (side-slip, load transfer, speed growth, slip, track, drift, grade and
//!   the sensor terms): the terms the diagnosis fits and the odometry applies.
//! - [`estimate`]: the odometry parameters and where they come from
//!   (`vehicle.toml`'s nominal values, the calibrator's JSON, the wire
//!   [`CircumferenceEstimate`](interfaces::wire::CircumferenceEstimate)),
//!   with the model extensions the calibrator fitted.
//! - [`estimate_file`]: the estimate file, one serde type that the
//!   calibrator writes (`calibrate --json`) and the odometry reads.
//! - [`estimate_vehicle`]: the vehicle an estimate was made for, and how
//!   it differs from a drive's (the warning when one is applied to another).
//! - [`estimate_gate`]: what an estimate from the bus must satisfy before the
//!   odometry applies it (plausible values, one publisher, increasing
//!   versions, bounded steps).
//!
//! Pure: data in, results out.

pub mod effects;
pub mod estimate;
pub mod estimate_file;
pub mod estimate_gate;
pub mod estimate_vehicle;
pub mod two_wheel;
