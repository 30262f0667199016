//! What `calibrator info --json` reports about a drive: the drive summary,
//! and what a calibration run without its fit refusal finds about the
//! sensors (clock offsets, GNSS jumps, fit quality, what the sigmas rest
//! on), with why a calibration would be refused. The binary prints it; the
//! Python package returns it.

use crate::reference::gnss_jumps::Jump;
use crate::result::FitQuality;
use crate::sigmas::uncertainty::SigmaBasis;
use crate::{calibrate, Calibration, CalibrationConfig, ClockOffsets};
use drive_io::{DriveSummary, LoadedDrive};
use serde::Serialize;

/// The report of `calibrator info --json` (its field names are the JSON's).
#[derive(Debug, Clone, Serialize)]
pub struct InfoReport {
    /// What the drive holds: streams, rates, gaps, GNSS outages.
    pub drive: DriveSummary,
    /// Every stream's clock against the wheels (`None`: no calibration).
    pub clock_offsets: Option<ClockOffsets>,
    /// The GNSS jumps set aside.
    pub gnss_jumps: Option<Vec<Jump>>,
    /// How well the model fits, with the limit `calibrate` applies.
    pub fit_quality: Option<FitQuality>,
    /// What the sigmas rest on (the GNSS error model fitted to the drive).
    pub sigma_basis: Option<SigmaBasis>,
    /// Why a calibration would be refused (`None`: it would be published).
    pub refused: Option<String>,
}

/// The info report of a read drive, and the calibration it ran (without
/// the fit refusal; `None` when even that refused the drive).
pub fn info(loaded: &LoadedDrive) -> (InfoReport, Option<Calibration>) {
    let summary = DriveSummary::of_loaded(loaded);
    // Calibrate without the fit refusal, to report the offsets and the fit
    // of a drive that would be refused, and say so.
    let config = CalibrationConfig {
        max_fit_ratio: f64::INFINITY,
        ..CalibrationConfig::default()
    };
    let limit = CalibrationConfig::default().max_fit_ratio;
    let cal = calibrate(&loaded.drive, &config);
    let refused = match &cal {
        Err(e) => Some(e.to_string()),
        Ok(c) => c.fit_quality.as_ref().filter(|q| q.ratio > limit).map(|q| {
            format!(
                "the fit is {:.1} times the GNSS noise, beyond {limit:.0}: calibrate refuses it",
                q.ratio
            )
        }),
    };
    let ok = cal.ok();
    // The limit `calibrate` applies, not the one this run switched off.
    let quality = ok
        .as_ref()
        .and_then(|c| c.fit_quality.clone())
        .map(|mut q| {
            q.limit = limit;
            q
        });
    let report = InfoReport {
        drive: summary,
        clock_offsets: ok.as_ref().map(|c| c.clock_offsets.clone()),
        gnss_jumps: ok.as_ref().map(|c| c.diagnostics.gnss_jumps.clone()),
        fit_quality: quality,
        sigma_basis: ok.as_ref().and_then(|c| c.diagnostics.sigma_basis.clone()),
        refused,
    };
    (report, ok)
}
