//! Offline evaluation: dead-reckoning through simulated GNSS outages.
//!
//! Outages of a given length start every `spacing_s` (10 s) from the first
//! instant covered by both wheels and `truth.csv`, as long as they end inside
//! that coverage. At each outage start the pose is taken from the truth;
//! `start_yaw_source` in the report says which rule applied:
//! - `truth_yaw`: `truth.csv` has `yaw_rad` around the start: position and
//!   yaw interpolated (yaw the shortest way round). Unless that yaw is not
//!   the vehicle's: on straight stretches the course of the truth positions
//!   is the vehicle's yaw, and where `yaw_rad` is off it by more than
//!   [`TRUTH_YAW_OFFSET_LIMIT_RAD`] (median over the straight stretches, see
//!   [`truth_yaw_offset`]), a warning says so and the truth's yaw is not
//!   used (the rules below apply). comma2k19's truth, for one, is the pose of
//!   the windscreen-mounted device, 15 mrad off the car's course;
//! - `truth_track_alignment` (truth without yaw, the usual case of a GNSS
//!   truth): the dead-reckoned track of the last `align_distance_m` (30 m) of
//!   driving before the start is laid onto the truth positions of the same
//!   stretch by the rotation and translation that fit best (2-D Procrustes,
//!   refitted once without truth points more than three times the median
//!   residual off); the start pose is the laid track's pose at the start.
//!   This is what a filter fusing GNSS with this odometry knows when the GNSS
//!   drops out: it uses only data from before the outage, and it averages the
//!   truth's own noise over a long baseline. On the WID drives the RTK truth
//!   jumps by decimetres now and then, and a course from a few truth points is
//!   off by several hundredths of a radian: metres after 30 s;
//! - `truth_track_alignment_after`: the same on the first 30 m after the
//!   start, when the vehicle has not driven 30 m before it (the start of a
//!   drive: it stands, so its heading is the heading it departs with);
//! - `truth_course` (neither window within `align_max_s`): position
//!   interpolated, yaw the course of the truth track at the start, see
//!   [`course_at`]: a least-squares cubic fit x(u), y(u) of the truth
//!   positions against their arc length u within `course_half_window_m`
//!   either side of the start point, yaw = atan2(y'(0), x'(0)), fitted only on
//!   the points where the arc length grew; the window is doubled, up to four
//!   times, where it holds too few points. A cubic, not a quadratic: with the
//!   curvature changing along the window, a quadratic's slope is biased by a
//!   few mrad.
//!
//! The arc length of the truth track grows only when the track has moved more
//! than [`ARC_DEADBAND_M`] from its last counted point, so GNSS jitter while
//! standing adds nothing.
//!
//! The odometer (the same [`DeadReckoner`](crate::dead_reckoning::DeadReckoner)
//! as the service's) runs through the
//! whole drive as the service would, so that at each outage start it has what
//! it learned before (wheel offsets at standstill, gyro history); a copy of
//! it is put at the truth pose and dead-reckons to the outage end on the
//! wheels (and gyro), learning at standstills as the service does (wheel
//! offsets, gyro bias). GNSS and heading samples are never read. The score is the distance between the dead-reckoned
//! and the true position at the outage end. `distance_m` is the truth arc
//! length driven during the outage (same dead band), `error_pct` the error in
//! percent of it, given for outages of at least `min_distance_for_pct_m`.
//!
//! Percentiles: the median of an even count is the mean of the two middle
//! values; the 90th percentile interpolates linearly between order statistics
//! (rank 0.9 (n - 1), as numpy's default).
//!
//! The parts, each in its own file:
//! - `config`, `error`, `report`: the settings, the failures, and what an
//!   evaluation reports;
//! - `truth_point`: the body point the truth follows, and whether the truth
//!   is the GNSS track;
//! - `truth_track`: the truth track read at any time, its arc length, its
//!   course, and the check of its yaw;
//! - `dead_reckon`: the odometer through the drive, copied at the instants
//!   asked for, and dead-reckoning from a copy;
//! - `alignment`: the start pose from the dead-reckoned track laid onto the
//!   truth;
//! - `outage`: where the outages go, and one outage from its start pose to
//!   its score;
//! - `percentile` (from `stats`): the median and the 90th percentile;
//! - `parameters`: what is dead-reckoned with, an estimate's checked
//!   against the drive's vehicle or the nominal values;
//! - `run`: [`evaluate`], a drive from its checks to its report.

mod alignment;
mod config;
mod dead_reckon;
mod error;
mod outage;
mod parameters;
mod report;
mod run;
#[cfg(test)]
mod test_drives;
mod truth_point;
mod truth_track;
mod wheel_clock;

pub use config::EvaluateConfig;
pub use error::EvaluateError;
pub use parameters::{NotThisVehicle, Parameters};
pub use report::{EvaluationReport, OutageResult, ParamsReport, TrackPoint};
pub use run::evaluate;
pub use stats::percentile;
pub use truth_point::{
    choose_truth_point, truth_gnss_coincidence, truth_is_the_gnss_track, TruthPoint,
    TruthPointChoice, TruthPointSource,
};
pub use truth_track::{
    course_at, truth_yaw_offset, ARC_DEADBAND_M, TRUTH_YAW_OFFSET_LIMIT_RAD,
    YAW_CHECK_MIN_STRETCHES, YAW_CHECK_STRAIGHT_RAD, YAW_CHECK_STRETCH_M,
};
