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
//! 2. [`fit::ekf`]: the EKF on the 2W model with `d = n c` as inputs and
//!    `r_k` as measurement, covariances by the decreasing schedule of eq.
//!    (10), and the 2W dead-reckoning check.
//! 3. [`fit::paper`]: the weighted least squares of eq. (8)-(9), the step of
//!    eq. (11), and the per-iteration dead-reckoning check that keeps the
//!    best iteration.
//!
//! The calibration runs as stages (`docs/design/calibration-stages.md`),
//! each a folder with one entry point taking the products of those above
//! it; `pipeline.rs` runs them in order ([`calibrate`]):
//! 1. [`check`]: `check::drive`, the drive checked, repaired and converted
//!    to arrays (no IMU array yet: it waits for the IMU's clock);
//! 2. [`clocks`]: `clocks::align`, every stream on the wheels' clock (the
//!    IMU offset, the drifts, the re-stamped arrays, the GNSS's noise and
//!    offset over every pair of streams);
//! 3. [`reference`](mod@reference): `reference::build`, the reference poses,
//!    headings, GNSS jumps and outliers, side-slip;
//! 4. [`fit`]: `fit::run`, the paper's method, the batch fit, the wheel +
//!    gyro model and the choice of the scale;
//! 5. [`sigmas`]: `sigmas::of`, what the sigmas leave undetermined (the
//!    error model the fits' sigmas rest on lives here too);
//! 6. [`result`]: `result::assemble`, the [`Calibration`]; its text report,
//!    page, plots and exports.
//!
//! Beside the stages, used by any of them and using none (inside the
//! crate; their public types are re-exported here or by the stages):
//! `config`, `error`, `error_model` (the GNSS error model of the fits'
//! residuals, which the fits and the diagnosis use), `method`, `products` (the circumferences, sigmas and
//! per-iteration table as types), `series` (the arrays every stage reads),
//! `smoother` (the GNSS position smoother), `streams` (building the arrays
//! from a drive's streams) and `warnings`. Beside the driver: [`live`]
//! (when a drive collected so far supports publishing an estimate) and
//! [`diagnose`] (which physics the calibrated model leaves out; uses
//! [`calibrate`]).
//!
//! ```no_run
//! # fn demo(drive: &interfaces::drive::Drive) -> Result<(), calibrator::CalibrationError> {
//! let cal = calibrator::calibrate(drive, &calibrator::CalibrationConfig::default())?;
//! println!("c_RL = {:.4} m, c_RR = {:.4} m", cal.circumference_m.rl, cal.circumference_m.rr);
//! # Ok(()) }
//! ```

// The shared modules, beside the stages.
pub(crate) mod config;
pub(crate) mod error;
pub mod error_model;
pub(crate) mod method;
pub(crate) mod products;
pub(crate) mod series;
pub(crate) mod smoother;
pub(crate) mod streams;
pub(crate) mod warnings;

// The stages, in the order they run; each uses only those above it.
pub mod check;
pub mod clocks;
pub mod fit;
pub mod reference;
pub mod result;
pub mod sigmas;

// The driver, and what stays beside the stages.
pub mod diagnose;
pub mod info;
pub mod live;
pub(crate) mod pipeline;

pub use clocks::offsets::{ClockOffsets, ClockStream, OffsetStatus, PairOffset, StreamOffset};
pub use config::{CalibrationConfig, TimeOffsetMode, TrackWidthMode};
pub use error::CalibrationError;
pub use method::Method;
pub use pipeline::{calibrate, calibrate_with_progress, Progress, Stage};
pub use result::{
    Calibration, Diagnostics, IterationRecord, MethodSummary, RearPair, RearSigma, Tracks,
};
pub use warnings::{Warning, WarningCode};
