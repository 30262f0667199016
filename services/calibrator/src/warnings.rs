//! Warnings: everything a calibration skipped, assumed or could not
//! determine, each with a stable [`WarningCode`] and a message naming the
//! cause.

use serde::{Deserialize, Serialize};

/// What a warning is about (stable, for programs and tests).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WarningCode {
    /// Rows with NaN/inf values were skipped.
    NonFiniteSamples,
    /// A stream pauses.
    StreamGap,
    /// A stream starts late or stops early.
    StreamStops,
    /// No IMU.
    NoImu,
    /// GNSS fixes rejected as outliers.
    GnssOutliers,
    /// The receiver's `sigma_m` is far below the scatter of its fixes; the
    /// scatter is used.
    GnssSigmaUnderstated,
    /// GNSS jumps found against the wheels and set aside.
    GnssJumps,
    /// The calibrated model fits the GNSS far worse than its noise.
    FitWorseThanNoise,
    /// GNSS outages (bridged).
    GnssOutage,
    /// The wheel/GNSS time offset.
    TimeOffset,
    /// Side-slip requested but not available.
    SideSlipUnavailable,
    /// The drive has no turn.
    NoTurn,
    /// c_RL and c_RR are not separated.
    DifferenceUnobservable,
    /// The common scale is poorly determined.
    ScaleUnobservable,
    /// The track width is poorly determined.
    TrackWidthUnobservable,
    /// The track width was kept at the nominal value.
    TrackWidthFixed,
    /// The estimated track width is implausible.
    TrackWidthImplausible,
    /// The gyro bias/scale could not be estimated.
    GyroUnobservable,
    /// The gyro scale was held at 0.
    GyroScaleUnobservable,
    /// The paper's loop was still improving at its last iteration.
    NotConverged,
    /// The methods compared disagree beyond their sigmas.
    MethodsDisagree,
    /// Batch segments were left out.
    SegmentsDropped,
    /// The common scale comes from the wheel + gyro model, not the 2W fit.
    ScaleFromGyroModel,
    /// The GNSS antenna position is poorly determined by the drive.
    AntennaUnobservable,
    /// What reading the drive's files said (a damaged chunk left out, an
    /// unknown column, a last line without its line end, ...).
    Reading,
    /// An encoder tick counter wraps around; it was unwrapped.
    CounterWrapped,
    /// Wheel values beyond any car (a logger glitch) were set aside; the
    /// rest of the channel is used.
    WheelSamplesSetAside,
    /// The GNSS stamps jitter about the receiver's regular epochs; the
    /// fixes were read at their epochs.
    GnssStampsOnEpochs,
    /// An IMU value is exactly constant while the wheels show motion (a
    /// dead or stuck sensor); it was not used where stuck.
    ImuStuck,
    /// One rear wheel stands still over a stretch while the other rolls on.
    WheelStuck,
    /// `vehicle.toml`'s track width contradicts the track the wheels and
    /// the gyro agree on (`drive_io::plausibility`).
    TrackWidthContradicted,
    /// The wheel stream pauses far longer than its sample interval (a hole
    /// in the drive); the models restart after it.
    WheelPause,
}

/// A warning: a stable code and a message naming the cause.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Warning {
    /// What it is about.
    pub code: WarningCode,
    /// Human-readable, names the channel/parameter and the cause.
    pub message: String,
}

impl Warning {
    /// A warning.
    pub fn new(code: WarningCode, message: String) -> Warning {
        Warning { code, message }
    }
}
