//! Calibrator: the paper's iterative estimation of the rear wheel
//! circumferences, and better estimators beside it.
//!
//! The library is pure: a [`Drive`] and a [`CalibrationConfig`] go in, a
//! [`Calibration`] (estimate, sigmas, per-iteration table, warnings, tracks
//! for plots) comes out. No I/O, no clock: time comes with the data.
//!
//! Layers (Fazekas, Németh, Gáspár, sections 2-4):
//! 1. [`reference`]: GNSS/IMU Kalman fusion (`p'' = a`, heading from the yaw
//!    rate fused with the GNSS course or an absolute heading) and a KF
//!    side-slip estimate, giving the reference poses `r_k`.
//! 2. [`ekf`]: the EKF on the 2W model with `d = n c` as inputs and `r_k` as
//!    measurement, covariances by the decreasing schedule of eq. (10).
//! 3. [`paper`]: the weighted least squares of eq. (8)-(9), the step of
//!    eq. (11), and the per-iteration dead-reckoning check that keeps the best
//!    iteration.
//!
//! Beside them: [`batch`], a Levenberg-Marquardt fit of the 2W model over the
//! whole drive against the GNSS fixes (segments with their own initial pose),
//! optionally with the effective track width and a side-slip gain;
//! [`gyro`], the yaw-rate gyro's bias and scale; [`uncertainty`], the sigmas
//! and observability warnings; [`report`], the result types and the text
//! report; [`plots`], SVG pictures.
//!
//! ```no_run
//! # fn demo(drive: &interfaces::drive::Drive) -> Result<(), calibrator::CalibrationError> {
//! let cal = calibrator::calibrate(drive, &calibrator::CalibrationConfig::default())?;
//! println!("c_RL = {:.4} m, c_RR = {:.4} m", cal.circumference_m.rl, cal.circumference_m.rr);
//! # Ok(()) }
//! ```

pub mod batch;
pub mod ekf;
pub mod gyro;
pub mod paper;
pub mod plots;
pub mod prep;
pub mod reference;
pub mod report;
pub mod serve;
pub mod uncertainty;

use interfaces::drive::{Drive, WheelConversionError};
use serde::{Deserialize, Serialize};

pub use report::{
    Calibration, Diagnostics, IterationRecord, MethodSummary, RearPair, RearSigma, Tracks, Warning,
    WarningCode,
};

/// Which estimator produces the result.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The paper's iterative EKF + weighted least squares (eq. 3-11).
    Paper,
    /// Levenberg-Marquardt fit of the 2W model to the GNSS fixes over the
    /// whole drive, in segments with their own initial pose.
    Batch,
}

impl Method {
    /// The name used on the command line and in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            Method::Paper => "paper",
            Method::Batch => "batch",
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

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
    /// wheel increments are summed over each step (see [`ekf::grid`]).
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
        }
    }
}

impl CalibrationConfig {
    /// Check the ranges; the error names the field.
    pub fn validate(&self) -> Result<(), CalibrationError> {
        let bad = |field: &'static str, reason: String| {
            Err(CalibrationError::InvalidConfig { field, reason })
        };
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
        if !(self.segment_length_s.is_finite() && self.segment_length_s >= 5.0) {
            return bad(
                "segment_length_s",
                format!("{} must be >= 5 s", self.segment_length_s),
            );
        }
        Ok(())
    }
}

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
    /// The estimate left the physically plausible range.
    #[error("{method} estimate is implausible: {detail}")]
    Implausible {
        /// Method.
        method: Method,
        /// What.
        detail: String,
    },
}

/// Stage of a running calibration, for progress reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    /// Checking and converting the input.
    Prepare,
    /// Layer 1: the GNSS/IMU reference.
    Reference,
    /// The paper's iterations.
    Paper,
    /// The batch fit.
    Batch,
    /// Gyro bias and scale.
    Gyro,
    /// Sigmas and observability.
    Uncertainty,
    /// Finished.
    Done,
}

/// A progress report: the stage and the overall fraction done (0..=1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Current stage.
    pub stage: Stage,
    /// Overall fraction done, 0..=1.
    pub fraction: f64,
}

/// Calibrate the rear wheel circumferences of `drive`.
pub fn calibrate(
    drive: &Drive,
    config: &CalibrationConfig,
) -> Result<Calibration, CalibrationError> {
    calibrate_with_progress(drive, config, &mut |_| {})
}

/// [`calibrate`], reporting progress through `progress`.
pub fn calibrate_with_progress(
    drive: &Drive,
    config: &CalibrationConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<Calibration, CalibrationError> {
    config.validate()?;
    progress(Progress {
        stage: Stage::Prepare,
        fraction: 0.0,
    });
    let mut warnings = Vec::new();
    let prepared = prep::prepare(drive, config, &mut warnings)?;
    progress(Progress {
        stage: Stage::Reference,
        fraction: 0.1,
    });
    let reference = reference::build(&prepared, drive, config, &mut warnings)?;
    let (paper_share, batch_share) = match (config.method, config.compare) {
        (_, true) => (0.35, 0.35),
        (Method::Paper, false) => (0.7, 0.0),
        (Method::Batch, false) => (0.0, 0.7),
    };
    let mut done = 0.2;
    let mut paper_result = None;
    if config.method == Method::Paper || config.compare {
        let start = done;
        let r = paper::run(&prepared, &reference, config, &mut warnings, &mut |f| {
            progress(Progress {
                stage: Stage::Paper,
                fraction: start + paper_share * f,
            })
        })?;
        done += paper_share;
        paper_result = Some(r);
    }
    let mut batch_result = None;
    if config.method == Method::Batch || config.compare {
        let start = done;
        let r = batch::run(&prepared, &reference, config, &mut warnings, &mut |f| {
            progress(Progress {
                stage: Stage::Batch,
                fraction: start + batch_share * f,
            })
        })?;
        batch_result = Some(r);
    }
    progress(Progress {
        stage: Stage::Gyro,
        fraction: 0.9,
    });
    let cal = report::assemble(
        &prepared,
        &reference,
        config,
        paper_result,
        batch_result,
        warnings,
    )?;
    progress(Progress {
        stage: Stage::Done,
        fraction: 1.0,
    });
    Ok(cal)
}
