//! The estimate file of a calibration (what `calibrator calibrate --json`
//! writes, what the odometry reads): the calibration, what reading the
//! drive said among its warnings, and the diagnosis's effect terms.

use super::Calibration;
use crate::warnings::{Warning, WarningCode};
use vehicle_model::effects::EffectTerms;
use vehicle_model::estimate_file::EstimateFile;

/// The estimate file of `cal`: `reading` (the warnings of reading the
/// drive) joins its warnings as [`WarningCode::Reading`], `effects` (the
/// terms a diagnosis accepted, when it ran) goes into `effects`.
pub fn estimate_file(
    cal: &Calibration,
    reading: &[String],
    effects: Option<EffectTerms>,
) -> Result<EstimateFile, serde_json::Error> {
    let mut with_reading = cal.clone();
    with_reading.warnings.extend(
        reading
            .iter()
            .map(|w| Warning::new(WarningCode::Reading, w.clone())),
    );
    let mut file = EstimateFile::from_report(&with_reading)?;
    file.effects = effects;
    Ok(file)
}
