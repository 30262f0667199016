//! Tuning of a calibration: [`CalibrationConfig`] and its modes, with the
//! range check.

use crate::error::CalibrationError;
use crate::method::Method;
use serde::{Deserialize, Serialize};

/// Whether the effective rear track width is estimated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrackWidthMode {
    /// Keep `vehicle.toml`'s `track_width_m`.
    Fixed,
    /// Estimate it as a third parameter (batch method only); a drive that
    /// cannot determine it is an error.
    Estimate,
    /// Estimate it (batch method) when the drive turns enough, else keep the
    /// nominal value and say so in a warning.
    Auto,
}

/// What to do with the time offset between the wheel and GNSS clocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeOffsetMode {
    /// Do not look at it.
    Off,
    /// Estimate it and warn when it is significant.
    Check,
    /// Estimate it, warn, and shift the GNSS time stamps by it when it is
    /// significant.
    Compensate,
}

/// Tuning of the calibration. [`Default`] gives the recommended setting.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationConfig {
    /// The estimator whose result is returned.
    pub method: Method,
    /// Also run the other method and attach its summary (side by side).
    pub compare: bool,
    /// Side-slip in eq. (1): off is beta = 0 (the paper's first results); on
    /// uses the layer-1 estimate (paper method) or a fitted side-slip gain
    /// (batch method).
    pub side_slip: bool,
    /// Iterations of the paper's loop (the paper: 9).
    pub iterations: usize,
    /// Step ratio alpha of eq. (11), `0 < alpha <= 1`.
    pub alpha: f64,
    /// q_M of eq. (10a), `1 <= q_M <= 1.5` in the paper.
    pub q_m: f64,
    /// q_P of eq. (10b), `0.2 <= q_P <= 0.7` in the paper.
    pub q_p: f64,
    /// Step rate of the paper's filter and least squares (its 1/dt), Hz; the
    /// wheel increments are summed over each step (see `ekf::grid`).
    pub paper_rate_hz: f64,
    /// Effective track width handling.
    pub track_width: TrackWidthMode,
    /// Estimate the yaw-rate gyro's bias and scale beside the circumferences.
    pub estimate_gyro: bool,
    /// Wheel/GNSS time offset handling.
    pub time_offset: TimeOffsetMode,
    /// GNSS 1-sigma horizontal noise, m; `None`: the `sigma_m` column, or an
    /// estimate from the fixes themselves.
    pub gnss_sigma_m: Option<f64>,
    /// Outlier gate on the GNSS innovations, in sigmas.
    pub outlier_gate_sigma: f64,
    /// A stretch without GNSS longer than this (s) is an outage: no reference
    /// there, the models bridge it.
    pub max_gnss_gap_s: f64,
    /// Length (s) of the batch method's segments, each with its own initial pose.
    pub segment_length_s: f64,
    /// Use the IMU's accelerations in the position reference (`p'' = a`).
    pub use_imu_acceleration: bool,
    /// Estimate the GNSS antenna position (body frame) in the batch fit,
    /// starting from `vehicle.toml`'s `[gnss]` values (or the axle centre).
    pub estimate_lever_arm: bool,
    /// Refuse the estimate when the calibrated model fits the GNSS worse
    /// than this many times the GNSS noise (`Calibration::fit_quality`;
    /// beyond [`crate::result::FIT_WARN_RATIO`] it is a warning): the
    /// drive then holds physics or faults the model does not explain, and
    /// its circumferences absorb them. 100: the residual's variance ten
    /// thousand times what the noise explains. (An RTK drive of the
    /// simulator's vehicle, whose side-slip and load transfer the 2W model
    /// leaves out, fits to about 80x its 3.6 cm and still calibrates within
    /// a millimetre: the ratio alone is no verdict on the circumferences.)
    /// Infinity: never refuse (the diagnosis, which looks for that
    /// physics, calibrates so).
    #[serde(default = "default_max_fit_ratio")]
    pub max_fit_ratio: f64,
    /// Start from these rear circumferences `[c_RL, c_RR]`, m (an earlier
    /// estimate), instead of `vehicle.toml`'s nominal one; the plausibility
    /// checks still measure against the nominal value.
    #[serde(default)]
    pub initial_circumference_m: Option<[f64; 2]>,
}

fn default_max_fit_ratio() -> f64 {
    100.0
}

impl Default for CalibrationConfig {
    fn default() -> Self {
        CalibrationConfig {
            method: Method::Batch,
            compare: false,
            side_slip: false,
            iterations: 9,
            alpha: 0.5,
            q_m: 1.25,
            q_p: 0.45,
            paper_rate_hz: 10.0,
            track_width: TrackWidthMode::Auto,
            estimate_gyro: true,
            time_offset: TimeOffsetMode::Compensate,
            gnss_sigma_m: None,
            outlier_gate_sigma: 5.0,
            max_gnss_gap_s: 2.0,
            segment_length_s: 120.0,
            use_imu_acceleration: true,
            estimate_lever_arm: false,
            max_fit_ratio: default_max_fit_ratio(),
            initial_circumference_m: None,
        }
    }
}

impl CalibrationConfig {
    /// Check the ranges; the error names the field.
    pub fn validate(&self) -> Result<(), CalibrationError> {
        let bad = |field: &'static str, reason: String| {
            Err(CalibrationError::InvalidConfig { field, reason })
        };
        if self.max_fit_ratio.is_nan() || self.max_fit_ratio < 1.0 {
            return bad(
                "max_fit_ratio",
                format!(
                    "{} must be at least 1 (infinity: never refuse)",
                    self.max_fit_ratio
                ),
            );
        }
        if self.iterations == 0 || self.iterations > 1000 {
            return bad(
                "iterations",
                format!("{} is not in 1..=1000", self.iterations),
            );
        }
        if !(self.alpha > 0.0 && self.alpha <= 1.0) {
            return bad("alpha", format!("{} is not in (0, 1]", self.alpha));
        }
        if !(self.q_m.is_finite() && self.q_m >= 1.0) {
            return bad("q_m", format!("{} must be >= 1 (eq. 10a)", self.q_m));
        }
        if !(self.paper_rate_hz.is_finite()
            && self.paper_rate_hz > 0.0
            && self.paper_rate_hz <= 1000.0)
        {
            return bad(
                "paper_rate_hz",
                format!("{} is not in (0, 1000] Hz", self.paper_rate_hz),
            );
        }
        if !(self.q_p.is_finite() && self.q_p >= 0.0) {
            return bad("q_p", format!("{} must be >= 0 (eq. 10b)", self.q_p));
        }
        if let Some(s) = self.gnss_sigma_m {
            if !(s.is_finite() && s > 0.0) {
                return bad("gnss_sigma_m", format!("{s} is not a positive number"));
            }
        }
        if !(self.outlier_gate_sigma.is_finite() && self.outlier_gate_sigma >= 2.0) {
            return bad(
                "outlier_gate_sigma",
                format!("{} must be >= 2", self.outlier_gate_sigma),
            );
        }
        if !(self.max_gnss_gap_s.is_finite() && self.max_gnss_gap_s > 0.0) {
            return bad(
                "max_gnss_gap_s",
                format!("{} must be positive", self.max_gnss_gap_s),
            );
        }
        if let Some(c) = self.initial_circumference_m {
            if !c.iter().all(|v| v.is_finite() && *v > 0.1 && *v < 10.0) {
                return bad(
                    "initial_circumference_m",
                    format!("{c:?} is not a pair of circumferences of 0.1-10 m"),
                );
            }
        }
        if !(self.segment_length_s.is_finite() && self.segment_length_s >= 5.0) {
            return bad(
                "segment_length_s",
                format!("{} must be >= 5 s", self.segment_length_s),
            );
        }
        Ok(())
    }
}
