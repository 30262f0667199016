//! What goes wrong in the filter: a numerical failure, or an input it
//! cannot take.

use crate::dead_reckoning::InputError;

/// A numerical failure of the filter.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FusionError {
    /// An innovation covariance that cannot be inverted.
    #[error("{what} innovation covariance at t = {t_s} s is not positive definite")]
    NotPositiveDefinite {
        /// `gnss`, `heading` or `standstill gyro bias`.
        what: &'static str,
        /// Time of the measurement.
        t_s: f64,
    },
    /// The state or covariance became NaN or infinite.
    #[error("filter state became non-finite at t = {t_s} s after {after}")]
    NonFinite {
        /// Time.
        t_s: f64,
        /// The step that produced it.
        after: &'static str,
    },
    /// A pose to resume from (`Fusion::resume`) with a value that is NaN or infinite.
    #[error("the pose to resume from is not finite (position, yaw or covariance)")]
    ResumeNotFinite,
    /// A GNSS antenna position (`Fusion::set_lever_arm`) that is NaN or infinite.
    #[error("the GNSS antenna position {0:?} m is not finite")]
    LeverArmNotFinite([f64; 2]),
}

/// What `Fusion::process` reports.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProcessError {
    /// The sample is unusable and was skipped; the filter is unchanged.
    #[error(transparent)]
    Input(#[from] InputError),
    /// The filter failed numerically and has been reset to `NoFix`.
    #[error("{0}; the filter was reset")]
    Numerical(#[from] FusionError),
}
