//! The result types: [`Calibration`] (serialised as the calibration JSON),
//! the per-method [`MethodResult`] the estimators return, and their parts.
//!
//! JSON field names are a contract with the odometry and the live service:
//! `circumference_m.rl/.rr`, `sigma_m`, `track_width_m`, `gyro_bias_rad_s`,
//! `gyro_scale`, `method`, `selected_iteration`, `iterations`, `warnings`.

mod assembly;
mod estimate;
pub mod export;
pub mod page;
pub mod plots;
pub mod report;

use crate::clocks::offsets::ClockOffsets;
use crate::fit::gyro::GyroEstimate;
use crate::fit::lm::ModelTrack;
use crate::method::Method;
use crate::reference::TimeOffset;
use crate::warnings::{Warning, WarningCode};
use serde::{Deserialize, Serialize};

pub use crate::fit::MethodResult;
pub use crate::products::{IterationRecord, MethodSummary, RearPair, RearSigma, TRACK_POINTS};
pub use assembly::assemble;
pub use estimate::estimate_file;

/// A fit worse than this many times the GNSS noise is a warning
/// ([`crate::WarningCode::FitWorseThanNoise`]).
pub const FIT_WARN_RATIO: f64 = 10.0;

/// How well the calibrated model explains the drive: its GNSS residual
/// against the GNSS noise of this drive.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FitQuality {
    /// RMS of the GNSS residuals of the model the estimate came from, m.
    pub residual_rms_m: f64,
    /// That model: `2W` or `wheel + gyro`.
    pub model: String,
    /// The GNSS 1-sigma noise compared with, m.
    pub gnss_noise_m: f64,
    /// Where it came from: the receiver's `sigma_m`, the configuration, or
    /// measured on the drive (the fixes' scatter).
    pub gnss_noise_source: String,
    /// `residual_rms_m / gnss_noise_m`.
    pub ratio: f64,
    /// The ratio beyond which the estimate is refused.
    pub limit: f64,
}

/// Facts about the drive and the reference.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Diagnostics {
    /// Wheel data duration, s.
    pub duration_s: f64,
    /// Distance with a valid reference (nominal circumference), m.
    pub distance_m: f64,
    /// Total absolute heading change, degrees.
    pub total_turn_deg: f64,
    /// GNSS fixes in the drive (finite).
    pub gnss_fixes: usize,
    /// Fixes rejected as outliers.
    pub gnss_outliers: usize,
    /// GNSS jumps found against the wheels and set aside (their fixes are
    /// not used).
    #[serde(default)]
    pub gnss_jumps: Vec<crate::reference::gnss_jumps::Jump>,
    /// GNSS outages bridged.
    pub gnss_outages: usize,
    /// GNSS 1-sigma used, m.
    pub gnss_sigma_m: f64,
    /// Whether it was estimated from the fixes.
    pub gnss_sigma_estimated: bool,
    /// Wheel/GNSS time offset, when checked.
    pub time_offset: Option<TimeOffset>,
    /// GNSS antenna position used, body frame from the rear-axle centre, m.
    pub lever_arm_m: [f64; 2],
    /// Layer-1 side-slip gain k (beta = -k a_y), rad per m/s^2.
    pub reference_side_slip_gain: Option<f64>,
    /// Standstill time, s.
    pub standstill_s: f64,
    /// RMS of the GNSS residuals of the batch fit, m.
    pub residual_rms_m: Option<f64>,
    /// Batch segments.
    pub segments: usize,
    /// Offsets subtracted from rate-type wheel channels (rl, rr, in the
    /// channel's unit), measured at standstill.
    pub wheel_rate_offsets: Option<[f64; 2]>,
    /// What the sigmas rest on: the GNSS error model fitted to this drive's
    /// residuals (white and correlated part per axis), or a jackknife.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_basis: Option<crate::sigmas::uncertainty::SigmaBasis>,
}

/// The nominal values the calibration started from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Nominal {
    /// Circumference of every wheel, m.
    pub circumference_m: f64,
    /// Rear track, m.
    pub track_width_m: f64,
}

/// Thinned tracks for the plots (not serialised).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Tracks {
    /// The reference (rear-axle centre).
    pub reference: Vec<[f64; 2]>,
    /// 2W dead-reckoning with the nominal values.
    pub before: Vec<[f64; 2]>,
    /// 2W dead-reckoning with the estimate.
    pub after: Vec<[f64; 2]>,
    /// Accepted GNSS fixes (antenna).
    pub gnss: Vec<[f64; 2]>,
    /// Time of the first wheel sample, s (the report's time axis starts there).
    pub start_s: f64,
    /// The model the estimate came from, per segment, with its GNSS
    /// residuals: the batch fit's segments from their fitted initial poses,
    /// or (the paper's method) the 2W model with the estimate from the
    /// reference pose at each segment's start.
    pub model: ModelTrack,
    /// Whether `model`'s segment poses were fitted (batch) or taken from
    /// the reference (paper).
    pub model_fitted: bool,
    /// Windows of about 1 s driven above 2 m/s with a valid reference:
    /// [heading change of the reference (rad), rear-left revolutions,
    /// rear-right revolutions].
    pub wheel_windows: Vec<[f64; 3]>,
}

/// The calibration result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Effective rear circumferences, m.
    pub circumference_m: RearPair,
    /// Their 1-sigma, m.
    pub sigma_m: RearSigma,
    /// Effective rear track used with them (estimated or nominal), m.
    pub track_width_m: f64,
    /// Whether the track width was estimated.
    pub track_width_estimated: bool,
    /// 1-sigma of the track width, m, when estimated.
    pub sigma_track_width_m: Option<f64>,
    /// Yaw-rate gyro bias, rad/s (`omega_gyro = (1 + gyro_scale) omega + bias`).
    pub gyro_bias_rad_s: Option<f64>,
    /// Yaw-rate gyro scale error (0 = perfect).
    pub gyro_scale: Option<f64>,
    /// The gyro calibration in full.
    pub gyro: Option<GyroEstimate>,
    /// Whether side-slip was in the model.
    pub side_slip: bool,
    /// Side-slip gain k (beta = -k a_y), rad per m/s^2, when fitted.
    pub side_slip_gain_rad_per_m_s2: Option<f64>,
    /// Estimated GNSS antenna position, body frame from the rear-axle centre, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gnss_antenna_m: Option<[f64; 2]>,
    /// Its 1-sigma, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_gnss_antenna_m: Option<[f64; 2]>,
    /// The method that produced the values.
    pub method: Method,
    /// The kept iteration.
    pub selected_iteration: usize,
    /// Per-iteration table (the paper's Fig. 6).
    pub iterations: Vec<IterationRecord>,
    /// Everything skipped, assumed or not determined.
    pub warnings: Vec<Warning>,
    /// Starting values.
    pub nominal: Nominal,
    /// The vehicle the drive was made with (its `vehicle.toml`): the
    /// estimate's identity, compared by whoever applies it to another drive.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vehicle: Option<interfaces::drive::VehicleParams>,
    /// Facts about the drive.
    pub diagnostics: Diagnostics,
    /// The clock offset of every stream against the wheels (determined or
    /// not, and why), and whether it was applied.
    #[serde(default)]
    pub clock_offsets: ClockOffsets,
    /// How well the calibrated model explains the drive (`None`: no fit
    /// residual, e.g. the paper method alone).
    #[serde(default)]
    pub fit_quality: Option<FitQuality>,
    /// Every method run, side by side (when comparing).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub comparison: Vec<MethodSummary>,
    /// Tracks for the plots.
    #[serde(skip)]
    pub tracks: Tracks,
}

impl Calibration {
    /// True when a warning with `code` was raised.
    pub fn has_warning(&self, code: WarningCode) -> bool {
        self.warnings.iter().any(|w| w.code == code)
    }
}
