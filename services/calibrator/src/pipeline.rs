//! The calibration from end to end: [`calibrate`] runs the stages in order,
//! each on the products of those before it: check the drive, align the
//! clocks, build the reference, fit, the sigmas, the result.

use crate::config::CalibrationConfig;
use crate::error::CalibrationError;
use crate::method::Method;
use crate::result::Calibration;
use crate::{check, clocks, fit, reference, result, sigmas};
use interfaces::drive::Drive;
use serde::{Deserialize, Serialize};

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
    let checked = check::drive(drive, config)?;
    let mut aligned = clocks::align(checked, config)?;
    let mut warnings = std::mem::take(&mut aligned.warnings);
    progress(Progress {
        stage: Stage::Reference,
        fraction: 0.1,
    });
    let reference = reference::build(&aligned, config, &mut warnings)?;
    let (paper_share, batch_share) = match (config.method, config.compare) {
        (_, true) => (0.35, 0.35),
        (Method::Paper, false) => (0.7, 0.0),
        (Method::Batch, false) => (0.0, 0.7),
    };
    let fits = fit::run(&aligned, &reference, config, &mut warnings, &mut |step| {
        progress(match step {
            fit::Step::Paper(f) => Progress {
                stage: Stage::Paper,
                fraction: 0.2 + paper_share * f,
            },
            fit::Step::Batch(f) => Progress {
                stage: Stage::Batch,
                fraction: 0.2 + paper_share + batch_share * f,
            },
            fit::Step::Gyro => Progress {
                stage: Stage::Gyro,
                fraction: 0.9,
            },
        })
    })?;
    let sigmas = sigmas::of(&fits, &reference);
    let cal = result::assemble(drive, &aligned, &reference, config, fits, sigmas, warnings)?;
    progress(Progress {
        stage: Stage::Done,
        fraction: 1.0,
    });
    Ok(cal)
}
