//! `calibrator info`: what a recording holds (the drive summary
//! `sensor-bridge info` prints) and what the calibration finds about its
//! sensors: every stream's clock offset against the wheels with its sigma
//! and its slow drift in ppm with its sigma (or why it is not determined
//! and which manoeuvre would determine it, or which drift the drive is too
//! short to show), the GNSS jumps set aside, and the fit quality, with whether a
//! calibration would be refused for it.

use anyhow::{Context, Result};
use calibrator::{OffsetStatus, StreamOffset};
use clap::Args;
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
            match (o.applied, o.applied_s) {
                (true, Some(a)) => format!(", applied as {a:+.3} s (the GNSS's)"),
                (true, None) => ", applied".to_string(),
                _ => ", too small to apply".to_string(),
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
    let (info, cal) = calibrator::info::info(&loaded);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
        return Ok(());
    }
    let (summary, refused, ok) = (&info.drive, info.refused.clone(), cal.as_ref());
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
