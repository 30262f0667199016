//! Calibrator: the paper's iterative estimation of the rear wheel
//! circumferences, and better estimators beside it.
//!
//! The library is pure: a [`Drive`](interfaces::drive::Drive) and a
//! [`CalibrationConfig`] go in, a [`Calibration`] (estimate, sigmas,
//! per-iteration table, warnings, tracks for plots) comes out. No files, no
//! clock, no threads: time comes with the data. The `calibrator` binary
//! reads drives, writes JSON and pictures, and runs the live service.
//!
//! Layers (Fazekas, Németh, Gáspár, sections 2-4):
//! 1. [`reference`](mod@reference): GNSS/IMU Kalman fusion (`p'' = a`,
//!    heading from the yaw rate fused with the GNSS course or an absolute
//!    heading) and a KF side-slip estimate, giving the reference poses `r_k`.
//! 2. [`ekf`]: the EKF on the 2W model with `d = n c` as inputs and `r_k` as
//!    measurement, covariances by the decreasing schedule of eq. (10), and
//!    the 2W dead-reckoning check.
//! 3. [`paper`]: the weighted least squares of eq. (8)-(9), the step of
//!    eq. (11), and the per-iteration dead-reckoning check that keeps the best
//!    iteration.
//!
//! Modules, each with one job (a module uses only those listed above it, so
//! the imports form no cycle):
//! - [`method`]: which estimator produces the result;
//! - [`error`]: why a drive could not be calibrated;
//! - [`config`]: the tuning of a calibration and its range check;
//! - [`warnings`]: the warning codes and messages;
//! - [`clocks`]: the clock offsets of the streams against the wheels
//!   (pure functions on arrays);
//! - [`clock_drift`]: their slow drift, from offsets in windows along the
//!   drive (pure; [`pipeline`] applies it);
//! - [`prep`]: checking the drive and converting it to the arrays the layers
//!   use;
//! - [`reference`](mod@reference), [`ekf`]: layers 1 and 2 (above);
//! - [`uncertainty`]: sigmas (block jackknife) and observability warnings;
//! - [`lm`]: the Levenberg-Marquardt fitter of a dead-reckoning model to the
//!   GNSS fixes in segments;
//! - [`gyro`]: the yaw-rate gyro's bias and scale (a model for [`lm`]);
//! - [`result`]: the result types ([`Calibration`], the per-method result);
//! - [`track_width`]: whether the track width is estimated, and whether an
//!   estimate of it is plausible;
//! - [`paper`]: layer 3 and the paper's loop;
//! - [`batch`]: the 2W model fitted with [`lm`] over the whole drive;
//! - [`pipeline`]: [`calibrate`], the stages in order, and putting the
//!   result together;
//! - [`report`]: the readable text report;
//! - [`plots`]: the figures of a calibration (SVG text, drawn by the
//!   `report` library);
//! - [`export`]: the calibration in other stacks' forms (an Autoware-style
//!   parameter file, the 2W parameters as TOML);
//! - [`page`]: the calibration's HTML page (the figures, the warnings, the
//!   numbers);
//! - [`holdout`]: dead-reckoning errors of parameter sets on held-out data;
//! - [`live`]: when a drive collected so far supports publishing an estimate
//!   (coverage, attempt on all but a held-out tail, quality gate);
//! - [`diagnose`]: which physics the calibrated model leaves out, its
//!   terms, and the fit before and after on held-out blocks (uses
//!   [`calibrate`]).
//!
//! ```no_run
//! # fn demo(drive: &interfaces::drive::Drive) -> Result<(), calibrator::CalibrationError> {
//! let cal = calibrator::calibrate(drive, &calibrator::CalibrationConfig::default())?;
//! println!("c_RL = {:.4} m, c_RR = {:.4} m", cal.circumference_m.rl, cal.circumference_m.rr);
//! # Ok(()) }
//! ```

// The shared modules, beside the stages.
pub mod config;
pub mod error;
pub mod method;
pub mod series;
pub mod streams;
pub mod warnings;

// The stages, in the order they run; each uses only those above it.
pub mod check;
pub mod clocks;
pub mod fit;
pub mod reference;
pub mod result;
pub mod sigmas;

// The driver, and what stays beside the stages.
pub mod diagnose;
pub mod live;
pub mod pipeline;

pub use clocks::offsets::{ClockOffsets, ClockStream, OffsetStatus, PairOffset, StreamOffset};
pub use config::{CalibrationConfig, TimeOffsetMode, TrackWidthMode};
pub use error::CalibrationError;
pub use method::Method;
pub use pipeline::{calibrate, calibrate_with_progress, Progress, Stage};
pub use result::{
    Calibration, Diagnostics, IterationRecord, MethodSummary, RearPair, RearSigma, Tracks,
};
pub use warnings::{Warning, WarningCode};
