//! Each command as the command-line tool runs it, without the printing:
//! the library call, the warnings of reading joined to the result as the
//! tool joins them, and the JSON text the tool's `--json` writes. No
//! Python here: this is what the functions of `lib.rs` run with the GIL
//! released.

use anyhow::{Context, Result};
use calibrator::diagnose::{
    diagnose as run_diagnosis, diagnose_drives as run_diagnoses, terms_beside, DiagnoseConfig,
    DiagnoseError,
};
use calibrator::{calibrate as run_calibration, CalibrationConfig, Warning, WarningCode};
use drive_io::LoadedDrive;
use odometry::evaluate::{choose_truth_point, EvaluateConfig, Parameters, TruthPointChoice};
use std::path::Path;
use vehicle_model::estimate_file::EstimateFile;

/// Read the drive at `path` as the tools read it (their options).
pub(crate) fn read(
    input: &drive_io::cli::DriveInput,
    path: &Path,
    skip_corrupt_chunks: bool,
    allow_truncated: bool,
) -> Result<LoadedDrive> {
    drive_io::cli::accept_truncated(input.read(path, skip_corrupt_chunks)?, allow_truncated)
        .with_context(|| format!("cannot read drive {}", path.display()))
}

/// `calibrator calibrate --json [--diagnose]`: the estimate file's text.
pub(crate) fn calibrate(loaded: &LoadedDrive, name: &str, diagnose: bool) -> Result<String> {
    let drive = &loaded.drive;
    let cal = run_calibration(drive, &CalibrationConfig::default())
        .with_context(|| format!("cannot calibrate {name}"))?;
    let effects = if diagnose {
        let d = run_diagnosis(drive, &DiagnoseConfig::default())
            .with_context(|| format!("cannot diagnose {name}"))?;
        Some(terms_beside(
            &d.terms,
            cal.track_width_estimated,
            cal.side_slip,
        ))
    } else {
        None
    };
    let file = calibrator::result::estimate_file(&cal, &loaded.warnings, effects)
        .context("cannot encode the calibration as JSON")?;
    file.to_json_string()
        .context("cannot encode the calibration as JSON")
}

/// `calibrator diagnose --json [--block S]`: the diagnosis's text.
pub(crate) fn diagnose(loaded: &LoadedDrive, name: &str, block_s: Option<f64>) -> Result<String> {
    if let Some(b) = block_s {
        anyhow::ensure!(b.is_finite() && b >= 2.0, "--block {b}: at least 2 s");
    }
    let cfg = DiagnoseConfig {
        block_s,
        ..DiagnoseConfig::default()
    };
    let mut d =
        run_diagnosis(&loaded.drive, &cfg).with_context(|| format!("cannot diagnose {name}"))?;
    // What reading the files said belongs with the result too.
    d.warnings.extend(
        loaded
            .warnings
            .iter()
            .map(|w| Warning::new(WarningCode::Reading, w.clone())),
    );
    Ok(serde_json::to_string_pretty(&d).context("cannot encode the diagnosis")? + "\n")
}

/// `calibrator diagnose DRIVE DRIVE... --json [--block S]`: several
/// drives of one car, each diagnosed and the car's effects over all of
/// them; the JSON the tool writes (the drives' `paths` beside the
/// diagnosis).
pub(crate) fn diagnose_drives(
    loaded: &[&LoadedDrive],
    names: &[String],
    block_s: Option<f64>,
) -> Result<String> {
    if let Some(b) = block_s {
        anyhow::ensure!(b.is_finite() && b >= 2.0, "--block {b}: at least 2 s");
    }
    let cfg = DiagnoseConfig {
        block_s,
        ..DiagnoseConfig::default()
    };
    let drives: Vec<interfaces::drive::Drive> = loaded.iter().map(|l| l.drive.clone()).collect();
    let mut d = run_diagnoses(&drives, &cfg).map_err(|e| match &e {
        DiagnoseError::Drive { index, .. } => {
            let name = names.get(*index).map_or("?", String::as_str);
            anyhow::anyhow!("cannot diagnose {name}: {e}")
        }
        _ => anyhow::anyhow!("cannot diagnose the drives: {e}"),
    })?;
    for (one, l) in d.drives.iter_mut().zip(loaded) {
        one.warnings.extend(
            l.warnings
                .iter()
                .map(|w| Warning::new(WarningCode::Reading, w.clone())),
        );
    }
    let mut value = serde_json::to_value(&d).context("cannot encode the diagnosis")?;
    if let Some(obj) = value.as_object_mut() {
        obj.insert("paths".to_string(), serde_json::to_value(names)?);
    }
    Ok(serde_json::to_string_pretty(&value).context("cannot encode the diagnosis")? + "\n")
}

/// `calibrator info --json`: the info report's text.
pub(crate) fn info(loaded: &LoadedDrive) -> Result<String> {
    let (report, _) = calibrator::info::info(loaded);
    Ok(serde_json::to_string_pretty(&report)? + "\n")
}

/// `odometry evaluate --json` with the default dead-reckoning and truth
/// point: the evaluation report's text. `estimate` is an estimate file's
/// text and its name; without it, vehicle.toml's nominal values.
pub(crate) fn evaluate(
    loaded: &LoadedDrive,
    name: &str,
    estimate: Option<(&str, &str)>,
    outage_s: f64,
    spacing_s: f64,
) -> Result<String> {
    let drive = &loaded.drive;
    drive
        .vehicle
        .check_plausible()
        .map_err(|e| anyhow::anyhow!("{name}: vehicle.toml: {e}"))?;
    let parameters = match estimate {
        Some((text, source)) => {
            let file =
                EstimateFile::from_json_str(text, source).context("cannot use the estimate")?;
            let est = file.estimate(source).context("cannot use the estimate")?;
            Parameters::of_estimate(est, file.made_for(), source, drive, name)?
        }
        None => Parameters::nominal(drive),
    };
    let truth_point = choose_truth_point(drive, TruthPointChoice::Auto, parameters.antenna)
        .context("--truth-point")?;
    let config = EvaluateConfig {
        outage_s,
        spacing_s,
        truth_point,
        effects: parameters.effects,
        clocks: parameters.clocks,
        keep_tracks: false,
        ..EvaluateConfig::default()
    };
    let mut report = odometry::evaluate::evaluate(drive, &parameters.params, &config)
        .with_context(|| format!("cannot evaluate {name}"))?;
    if let Some(w) = parameters.other_vehicle {
        report.warnings.insert(0, w);
    }
    Ok(serde_json::to_string_pretty(&report).context("cannot serialise the report")? + "\n")
}
