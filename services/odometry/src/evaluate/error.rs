//! Why an evaluation could not run.

use interfaces::drive::WheelConversionError;

/// Why an evaluation could not run.
#[derive(Debug, thiserror::Error)]
pub enum EvaluateError {
    /// The drive has no `truth.csv`.
    #[error("the drive has no truth.csv: outages cannot be scored")]
    NoTruth,
    /// Gyro heading asked for a drive without `imu.csv`.
    #[error(
        "heading mode gyro needs imu.csv, which the drive does not have (use --heading wheels)"
    )]
    NoImu,
    /// Wheel values cannot be converted to revolutions.
    #[error(transparent)]
    Wheels(#[from] WheelConversionError),
    /// Not even one outage fits in the drive.
    #[error(
        "no {outage_s} s outage fits: wheels and truth overlap only from {from_s} s to {to_s} s"
    )]
    TooShort {
        /// Requested outage length, s.
        outage_s: f64,
        /// Start of the overlap, s.
        from_s: f64,
        /// End of the overlap, s.
        to_s: f64,
    },
    /// Every outage was skipped.
    #[error("every outage was skipped: {0}")]
    NothingScored(String),
    /// The drive holds what no car can do (reversed or exchanged wheel
    /// signs, a wheel stuck over much of the drive, a wheel impossible
    /// throughout): refused as the calibrator refuses it.
    #[error("{0}; the drive cannot be evaluated as it is")]
    Implausible(drive_io::plausibility::Finding),
    /// Gyro heading asked for a drive whose gyro is dead for the whole drive.
    #[error("{0}: heading mode gyro cannot use it (use --heading wheels)")]
    DeadGyro(drive_io::plausibility::Finding),
    /// A setting is out of range.
    #[error("invalid setting: {0}")]
    Config(String),
}
