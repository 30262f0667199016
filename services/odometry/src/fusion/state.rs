//! The filter's state: the layout of its vector (pose, residual gyro bias
//! and the two consider states), the filter before and after its
//! initialisation, and the finiteness check every step ends with.

use nalgebra::{SMatrix, SVector};
use vehicle_model::two_wheel::Pose2;

/// State: x, y, yaw, residual gyro bias, and two consider states: the
/// distance scale error and the rear wheels' relative circumference error.
pub(super) const N: usize = 6;
/// Index of the distance scale error in the state.
pub(super) const SCALE: usize = 4;
/// Index of the relative circumference error (right minus left, as a
/// fraction) in the state: it turns the wheel-difference heading.
pub(super) const WHEEL_DIFF: usize = 5;
/// The covariance of the state.
pub(super) type StateMat = SMatrix<f64, N, N>;
/// The state.
pub(super) type StateVec = SVector<f64, N>;

// One per filter, on the stack and copied on purpose: boxing the running
// state would put a heap allocation into every update.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum State {
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

/// Every entry of the state and its covariance is finite. (It runs at every
/// wheel sample: a fold over the plain slices, without an early exit, is
/// about 140 instructions against 340 with nalgebra's element iterator.)
pub(super) fn all_finite(x: &StateVec, p: &StateMat) -> bool {
    let finite = |ok: bool, v: &f64| ok & v.is_finite();
    x.as_slice().iter().fold(true, finite) & p.as_slice().iter().fold(true, finite)
}
