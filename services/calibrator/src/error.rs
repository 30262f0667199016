//! Why a drive could not be calibrated: [`CalibrationError`].

use crate::method::Method;
use interfaces::drive::WheelConversionError;

/// Why a drive could not be calibrated. Every message names the cause.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrationError {
    /// A configuration value is out of range.
    #[error("invalid configuration: {field}: {reason}")]
    InvalidConfig {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// `vehicle.toml` values that cannot be used.
    #[error("vehicle.toml: {0}")]
    BadVehicle(String),
    /// No wheel samples at all.
    #[error("wheels: the drive has no wheel samples")]
    NoWheelData,
    /// A rear wheel channel has no usable value.
    #[error("wheels: the {wheel} channel has no finite value ({count} rows): the column is missing or empty")]
    WheelChannelEmpty {
        /// `rl` or `rr`.
        wheel: &'static str,
        /// Rows in the drive.
        count: usize,
    },
    /// One rear wheel never turns while the other does.
    #[error(
        "wheels: the {wheel} wheel turns {revs:.2} revolutions while the {other} wheel turns {other_revs:.1}: \
         the {wheel} channel is missing, stuck or broken"
    )]
    WheelStuck {
        /// The wheel that does not turn.
        wheel: &'static str,
        /// Its revolutions.
        revs: f64,
        /// The other rear wheel.
        other: &'static str,
        /// Its revolutions.
        other_revs: f64,
    },
    /// The drive holds physically impossible values (a wheel faster than
    /// any car's, wheel signs reversed, a wheel stuck over much of the
    /// drive); the finding names the stream, the time and the value.
    #[error("{0}")]
    ImplausibleInput(drive_io::plausibility::Finding),
    /// The wheel values cannot be turned into revolutions.
    #[error("wheels: {0}")]
    WheelUnits(#[from] WheelConversionError),
    /// The drive has no GNSS.
    #[error("gnss: the drive has no GNSS fixes (gnss.csv missing or empty): the calibration needs positions to compare the wheels with")]
    NoGnss,
    /// Too few GNSS fixes survive the checks.
    #[error("gnss: only {usable} usable fixes ({total} in the drive{detail}); at least {needed} are needed")]
    TooFewGnss {
        /// Usable fixes.
        usable: usize,
        /// Fixes in the drive.
        total: usize,
        /// Why the others were dropped.
        detail: String,
        /// Minimum.
        needed: usize,
    },
    /// The wheel data and the GNSS do not overlap in time.
    #[error("wheels (t = {wheel_start:.2}..{wheel_end:.2} s) and gnss (t = {gnss_start:.2}..{gnss_end:.2} s) do not overlap in time")]
    NoOverlap {
        /// First wheel time.
        wheel_start: f64,
        /// Last wheel time.
        wheel_end: f64,
        /// First GNSS time.
        gnss_start: f64,
        /// Last GNSS time.
        gnss_end: f64,
    },
    /// The car hardly moves where there is GNSS.
    #[error("the drive covers only {distance_m:.1} m with GNSS reference; at least {needed_m:.0} m are needed")]
    TooShort {
        /// Distance driven with reference, m.
        distance_m: f64,
        /// Minimum, m.
        needed_m: f64,
    },
    /// The wheels drove far enough but the GNSS reference is valid over too
    /// little of it: the detail says which fixes were lost and why.
    #[error("the GNSS reference covers only {distance_m:.1} m of the {wheel_distance_m:.0} m the wheels drove (at least {needed_m:.0} m are needed): {detail}")]
    ReferenceTooShort {
        /// Distance driven with reference, m.
        distance_m: f64,
        /// Distance the wheels drove (nominal circumference), m.
        wheel_distance_m: f64,
        /// Minimum, m.
        needed_m: f64,
        /// Which fixes were rejected or set aside, how far apart the rest are.
        detail: String,
    },
    /// No GNSS course (nor absolute heading) to reference the heading: the
    /// detail counts the fixes by why their course was not used.
    #[error("no GNSS course to reference the heading: {detail}")]
    NoCourse {
        /// What was rejected and why, and what is left.
        detail: String,
    },
    /// A parameter the configuration demands cannot be estimated on this drive.
    #[error("{parameter} cannot be estimated on this drive: {reason}")]
    Unobservable {
        /// The parameter.
        parameter: &'static str,
        /// Why.
        reason: String,
    },
    /// A numerical step failed (singular system, non-finite values).
    #[error("numerical failure in {stage}: {detail}")]
    Numerical {
        /// Where.
        stage: &'static str,
        /// What.
        detail: String,
    },
    /// The calibrated model explains the drive far worse than the GNSS noise.
    #[error(
        "the calibrated model fits the GNSS to {residual_rms_m:.3} m RMS, {ratio:.1} times the GNSS noise of {noise_m:.3} m ({noise_source}), beyond the limit of {limit:.0}: the drive holds physics or faults the model does not explain (see the warnings), so its circumferences would absorb them; not published"
    )]
    PoorFit {
        /// The fit's residual RMS, m.
        residual_rms_m: f64,
        /// The GNSS noise it is compared with, m.
        noise_m: f64,
        /// Where that noise came from (`FitQuality::gnss_noise_source`).
        noise_source: String,
        /// Their ratio.
        ratio: f64,
        /// The configured limit.
        limit: f64,
    },
    /// The estimate left the physically plausible range.
    #[error("{method} estimate is implausible: {detail}")]
    Implausible {
        /// Method.
        method: Method,
        /// What.
        detail: String,
    },
}
