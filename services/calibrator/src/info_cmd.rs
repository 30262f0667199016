//! `calibrator info`: what a recording holds (the drive summary
//! `sensor-bridge info` prints) and what the calibration finds about its
//! sensors: every stream's clock offset against the wheels with its sigma
//! and its slow drift in ppm with its sigma (or why it is not determined
//! and which manoeuvre would determine it, or which drift the drive is too
//! short to show), the GNSS jumps set aside, and the fit quality, with whether a
//! calibration would be refused for it.

use anyhow::{Context, Result};
use calibrator::result::FitQuality;
use calibrator::{calibrate, CalibrationConfig, ClockOffsets, OffsetStatus, StreamOffset};
use clap::Args;
use drive_io::DriveSummary;
use serde::Serialize;
use std::path::PathBuf;

/// `calibrator info` arguments.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Drive folder or recording (as `calibrate` takes it).
    pub drive: PathBuf,
    #[command(flatten)]
    pub input: crate::drive_input::DriveInput,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// The JSON `calibrator info --json` prints.
#[derive(Debug, Serialize)]
struct InfoJson<'a> {
    drive: &'a DriveSummary,
    clock_offsets: Option<&'a ClockOffsets>,
    gnss_jumps: Option<&'a [calibrator::reference::gnss_jumps::Jump]>,
    fit_quality: Option<&'a FitQuality>,
    /// What the sigmas rest on (the GNSS error model fitted to the drive).
    sigma_basis: Option<&'a calibrator::sigmas::uncertainty::SigmaBasis>,
    /// Why a calibration would be refused (`None`: it would be published).
    refused: Option<String>,
}

fn offset_line(name: &str, o: &StreamOffset) -> String {
    format!("{}\n        drift {}", offset_only(name, o), o.drift)
}

fn offset_only(name: &str, o: &StreamOffset) -> String {
    match (o.status, o.offset_s, o.sigma_s) {
        (OffsetStatus::Determined, Some(v), Some(s)) => format!(
            "{name:<5} {:+.3} s +- {:.3} s against the wheels (from the {}){}",
            v,
            s,
            o.from.as_deref().unwrap_or("?"),
            if o.applied {
                ", applied"
            } else {
                ", too small to apply"
            }
        ),
        _ => format!(
            "{name:<5} {}: {}",
            match o.status {
                OffsetStatus::NotChecked => "not checked",
                _ => "not determined",
            },
            o.reason.as_deref().unwrap_or("no reason given")
        ),
    }
}

/// Run `calibrator info`.
pub fn run_info(args: &InfoArgs) -> Result<()> {
    let loaded = args
        .input
        .read(&args.drive, false)?
        .with_context(|| format!("cannot read drive {}", args.drive.display()))?;
    let summary = DriveSummary::of_loaded(&loaded);
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
    let ok = cal.as_ref().ok();
    // The limit `calibrate` applies, not the one this run switched off.
    let quality = ok.and_then(|c| c.fit_quality.clone()).map(|mut q| {
        q.limit = limit;
        q
    });
    if args.json {
        let out = InfoJson {
            drive: &summary,
            clock_offsets: ok.map(|c| &c.clock_offsets),
            gnss_jumps: ok.map(|c| c.diagnostics.gnss_jumps.as_slice()),
            fit_quality: quality.as_ref(),
            sigma_basis: ok.and_then(|c| c.diagnostics.sigma_basis.as_ref()),
            refused,
        };
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    println!("drive:     {}", args.drive.display());
    print!("{summary}");
    println!();
    match ok {
        Some(c) => {
            println!("clock offsets:");
            println!("  {}", offset_line("gnss", &c.clock_offsets.gnss_s));
            println!("  {}", offset_line("imu", &c.clock_offsets.imu_s));
            let jumps = &c.diagnostics.gnss_jumps;
            println!(
                "gnss jumps set aside: {}{}",
                jumps.len(),
                jumps
                    .iter()
                    .map(|j| format!(
                        "\n  {:.1}..{:.1} s, {:.2} m, {} fixes",
                        j.t_start, j.t_end, j.size_m, j.fixes
                    ))
                    .collect::<String>()
            );
            match &c.fit_quality {
                Some(q) => println!(
                    "fit quality: the {} model fits the GNSS to {:.3} m RMS, {:.1} x the GNSS noise of {:.3} m ({})",
                    q.model, q.residual_rms_m, q.ratio, q.gnss_noise_m, q.gnss_noise_source
                ),
                None => println!("fit quality: no fit residual"),
            }
            if let Some(b) = &c.diagnostics.sigma_basis {
                println!("sigmas from: {}", b.describe());
            }
        }
        None => println!("clock offsets and fit: not available (the calibration was refused)"),
    }
    match refused {
        Some(r) => println!("calibration: refused: {r}"),
        None => println!("calibration: would be published"),
    }
    Ok(())
}
