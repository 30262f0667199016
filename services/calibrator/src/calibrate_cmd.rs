//! The `calibrate` subcommand: read the drive, run the pure library, print
//! the report, write the JSON and the pictures.

use anyhow::{Context, Result};
use calibrator::result::{export, page, plots, report};
use calibrator::{
    calibrate_with_progress, CalibrationConfig, Method, Progress, TimeOffsetMode, TrackWidthMode,
};
use clap::{Args, ValueEnum};
use std::io::{IsTerminal as _, Write as _};
use std::path::{Path, PathBuf};
use vehicle_model::effects::EffectTerms;
use vehicle_model::estimate_file::EstimateFile;

/// `--method`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// The paper's iterative EKF + weighted least squares.
    Paper,
    /// Levenberg-Marquardt fit of the 2W model to the GNSS fixes (default).
    Batch,
}

/// `--track-width`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TrackArg {
    /// Keep vehicle.toml's value.
    Fixed,
    /// Estimate it (batch); an error when the drive cannot determine it.
    Estimate,
    /// Estimate it when the drive turns enough (batch).
    Auto,
}

/// `--time-offset`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OffsetArg {
    /// Do not check.
    Off,
    /// Estimate and warn.
    Check,
    /// Estimate, warn and compensate.
    Compensate,
}

/// Arguments of `calibrator calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// Drive folder or MCAP recording (ours, compressed or not, or a ROS 2
    /// bag with --vehicle).
    pub drive: PathBuf,
    #[command(flatten)]
    pub input: crate::drive_input::DriveInput,
    /// Write the calibration JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the calibration's report into this folder: index.html (one
    /// self-contained page: result, warnings, numbers, figures) and each
    /// figure as an SVG file.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// Write the result as an Autoware-style ROS 2 parameter file here
    /// (speed_scale_factor, angular_velocity_offset_z).
    #[arg(long, value_name = "FILE")]
    pub export_autoware: Option<PathBuf>,
    /// Write the 2W model's parameters as TOML here.
    #[arg(long, value_name = "FILE")]
    pub export_toml: Option<PathBuf>,
    /// Start from the circumferences of an earlier estimate (the JSON of
    /// `calibrate --json`) instead of vehicle.toml's nominal value; an
    /// estimate made for another vehicle is said so.
    #[arg(long, value_name = "EST.json")]
    pub initial: Option<PathBuf>,
    /// Estimator.
    #[arg(long, value_enum)]
    pub method: Option<MethodArg>,
    /// Also run the other method and print both side by side.
    #[arg(long)]
    pub compare: bool,
    /// Side-slip in the model (paper: the layer-1 estimate; batch: a fitted gain).
    #[arg(long)]
    pub side_slip: bool,
    /// Iterations of the paper's loop.
    #[arg(long)]
    pub iterations: Option<usize>,
    /// Step ratio alpha of eq. (11).
    #[arg(long)]
    pub alpha: Option<f64>,
    /// q_M of eq. (10a).
    #[arg(long)]
    pub q_m: Option<f64>,
    /// q_P of eq. (10b).
    #[arg(long)]
    pub q_p: Option<f64>,
    /// Effective track width handling.
    #[arg(long, value_enum)]
    pub track_width: Option<TrackArg>,
    /// Do not estimate the gyro bias and scale.
    #[arg(long)]
    pub no_gyro: bool,
    /// Wheel/GNSS time offset handling.
    #[arg(long, value_enum)]
    pub time_offset: Option<OffsetArg>,
    /// GNSS 1-sigma noise, m (default: sigma_m column or estimated).
    #[arg(long)]
    pub gnss_sigma: Option<f64>,
    /// Batch segment length, s.
    #[arg(long)]
    pub segment_length: Option<f64>,
    /// Do not use the IMU accelerations in the position reference.
    #[arg(long)]
    pub no_imu_accel: bool,
    /// Estimate the GNSS antenna position in the batch fit.
    #[arg(long)]
    pub estimate_lever_arm: bool,
    /// No progress bar.
    #[arg(long)]
    pub no_progress: bool,
    /// Also diagnose the drive (`calibrator diagnose`) and put the effect
    /// terms it accepts into the JSON (`effects`), where the odometry takes
    /// them from.
    #[arg(long)]
    pub diagnose: bool,
    /// Read a damaged MCAP recording by leaving out each chunk whose records
    /// fail their CRC (a warning names each one) instead of refusing it.
    #[arg(long)]
    pub skip_corrupt_chunks: bool,
    /// Calibrate what a truncated MCAP recording holds before its damage
    /// (a warning names the damage) instead of refusing it.
    #[arg(long)]
    pub allow_truncated: bool,
}

impl CalibrateArgs {
    /// The library configuration these arguments ask for.
    pub fn config(&self) -> CalibrationConfig {
        let mut c = CalibrationConfig::default();
        if let Some(m) = self.method {
            c.method = match m {
                MethodArg::Paper => Method::Paper,
                MethodArg::Batch => Method::Batch,
            };
        }
        c.compare = self.compare;
        c.side_slip = self.side_slip;
        if let Some(v) = self.iterations {
            c.iterations = v;
        }
        if let Some(v) = self.alpha {
            c.alpha = v;
        }
        if let Some(v) = self.q_m {
            c.q_m = v;
        }
        if let Some(v) = self.q_p {
            c.q_p = v;
        }
        if let Some(t) = self.track_width {
            c.track_width = match t {
                TrackArg::Fixed => TrackWidthMode::Fixed,
                TrackArg::Estimate => TrackWidthMode::Estimate,
                TrackArg::Auto => TrackWidthMode::Auto,
            };
        }
        c.estimate_gyro = !self.no_gyro;
        if let Some(o) = self.time_offset {
            c.time_offset = match o {
                OffsetArg::Off => TimeOffsetMode::Off,
                OffsetArg::Check => TimeOffsetMode::Check,
                OffsetArg::Compensate => TimeOffsetMode::Compensate,
            };
        }
        c.gnss_sigma_m = self.gnss_sigma;
        if let Some(v) = self.segment_length {
            c.segment_length_s = v;
        }
        if self.no_imu_accel {
            c.use_imu_acceleration = false;
        }
        c.estimate_lever_arm = self.estimate_lever_arm;
        c
    }
}

/// A text progress bar on standard error.
struct Bar {
    shown: bool,
    last: i32,
}

impl Bar {
    fn update(&mut self, p: Progress) {
        let pct = (100.0 * p.fraction).round() as i32;
        if pct == self.last {
            return;
        }
        self.last = pct;
        let filled = (pct / 4).clamp(0, 25) as usize;
        let stage = serde_json::to_string(&p.stage).unwrap_or_default();
        let mut err = std::io::stderr();
        let _ = write!(
            err,
            "\r[{}{}] {:3}% {:<12}",
            "#".repeat(filled),
            " ".repeat(25 - filled),
            pct,
            stage.trim_matches('"')
        );
        let _ = err.flush();
        self.shown = true;
    }
}

/// Run `calibrator calibrate`.
pub fn run_calibrate(args: &CalibrateArgs) -> Result<()> {
    let loaded = drive_io::cli::accept_truncated(
        args.input.read(&args.drive, args.skip_corrupt_chunks)?,
        args.allow_truncated,
    )
    .with_context(|| format!("cannot read drive {}", args.drive.display()))?;
    for w in &loaded.warnings {
        tracing::warn!("{w}");
    }
    let drive = loaded.drive;
    let mut config = args.config();
    let mut reading: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    if let Some(path) = &args.initial {
        start_from(args, path, &drive, &mut config, &mut reading)?;
    }
    let cal = calibrate_showing_progress(args, &drive, &config)?;
    print!("{}", report::render_text(&cal));
    if !reading.is_empty() {
        println!("reading the drive:");
        for w in &reading {
            println!("  - {w}");
        }
    }
    let effects = if args.diagnose {
        Some(diagnose_effects(args, &drive, &cal)?)
    } else {
        None
    };
    if let Some(path) = &args.json {
        write_estimate_file(path, &estimate_file(&cal, &reading, effects)?)?;
        println!("wrote {}", path.display());
    }
    write_exports(args, &cal)?;
    if let Some(dir) = &args.plots {
        let name = args.drive.file_name().map_or_else(
            || args.drive.display().to_string(),
            |n| n.to_string_lossy().to_string(),
        );
        write_plots(dir, &cal, &name, &reading)?;
    }
    Ok(())
}

/// Start the fit from the estimate file at `path` (--initial): its
/// circumferences into `config`; a warning (logged and kept in `reading`)
/// when it was made for another vehicle.
fn start_from(
    args: &CalibrateArgs,
    path: &Path,
    drive: &interfaces::drive::Drive,
    config: &mut CalibrationConfig,
    reading: &mut Vec<String>,
) -> Result<()> {
    let (estimate, made_for) = drive_io::read_estimate_with_vehicle(path)
        .with_context(|| format!("--initial {}", path.display()))?;
    if let Some(w) = made_for.and_then(|v| {
        vehicle_model::estimate_vehicle::other_vehicle_warning(
            &v,
            &drive.vehicle,
            &path.display().to_string(),
            &args.drive.display().to_string(),
        )
    }) {
        tracing::warn!("{w}");
        reading.push(w);
    }
    let tw = estimate.params.two_wheel;
    config.initial_circumference_m = Some([tw.c_rl, tw.c_rr]);
    Ok(())
}

/// Calibrate, with a progress bar on a terminal for drives longer than
/// five minutes (unless --no-progress).
fn calibrate_showing_progress(
    args: &CalibrateArgs,
    drive: &interfaces::drive::Drive,
    config: &CalibrationConfig,
) -> Result<calibrator::Calibration> {
    // A bar only where it helps: drives longer than five minutes.
    let mut bar = Bar {
        shown: false,
        last: -1,
    };
    // A carriage-return bar only on a terminal: a log file or a pipe gets none.
    let show =
        !args.no_progress && drive.wheel_duration_s() > 300.0 && std::io::stderr().is_terminal();
    let result = calibrate_with_progress(drive, config, &mut |p| {
        if show {
            bar.update(p)
        }
    });
    if bar.shown {
        eprintln!();
    }
    result.with_context(|| format!("cannot calibrate {}", args.drive.display()))
}

/// Diagnose the drive (--diagnose) and print what it found: the effects'
/// terms for the JSON, less what the calibration fitted itself.
fn diagnose_effects(
    args: &CalibrateArgs,
    drive: &interfaces::drive::Drive,
    cal: &calibrator::Calibration,
) -> Result<EffectTerms> {
    let d = calibrator::diagnose::diagnose(drive, &calibrator::diagnose::DiagnoseConfig::default())
        .with_context(|| format!("cannot diagnose {}", args.drive.display()))?;
    let found: Vec<&str> = d.findings.iter().map(|f| f.effect.id()).collect();
    println!(
        "diagnosis: {}",
        if found.is_empty() {
            "no effect beyond the noise".to_string()
        } else {
            format!(
                "{} (the terms go into the JSON's `effects`)",
                found.join(", ")
            )
        }
    );
    // What the calibration fitted itself stays with it.
    Ok(calibrator::diagnose::terms_beside(
        &d.terms,
        cal.track_width_estimated,
        cal.side_slip,
    ))
}

/// Write the Autoware and TOML exports asked for.
fn write_exports(args: &CalibrateArgs, cal: &calibrator::Calibration) -> Result<()> {
    let provenance = export::Provenance {
        drive: args.drive.display().to_string(),
        version: env!("CARGO_PKG_VERSION").to_string(),
    };
    for (path, text) in [
        (
            &args.export_autoware,
            args.export_autoware
                .as_ref()
                .map(|_| export::autoware_yaml(cal, &provenance)),
        ),
        (
            &args.export_toml,
            args.export_toml
                .as_ref()
                .map(|_| export::two_wheel_toml(cal, &provenance)),
        ),
    ] {
        if let (Some(path), Some(text)) = (path, text) {
            std::fs::write(path, text)
                .with_context(|| format!("cannot write {}", path.display()))?;
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}

/// The estimate file of `cal` (what `--json` writes): the calibration,
/// what reading the drive said among its warnings, and the effect terms of
/// the diagnosis when it ran (`effects`).
fn estimate_file(
    cal: &calibrator::Calibration,
    reading: &[String],
    effects: Option<EffectTerms>,
) -> Result<EstimateFile> {
    calibrator::result::estimate_file(cal, reading, effects)
        .context("cannot encode the calibration as JSON")
}

/// Write `file` to `path`.
fn write_estimate_file(path: &Path, file: &EstimateFile) -> Result<()> {
    let text = file
        .to_json_string()
        .context("cannot encode the calibration as JSON")?;
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

fn write_plots(
    dir: &Path,
    cal: &calibrator::Calibration,
    drive: &str,
    reading: &[String],
) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let figures = plots::figures(cal).context("cannot draw the calibration's figures")?;
    for f in &figures {
        let path = dir.join(f.file);
        std::fs::write(&path, &f.svg)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    let path = dir.join("index.html");
    std::fs::write(&path, page::calibration_html(cal, drive, &figures, reading))
        .with_context(|| format!("cannot write {}", path.display()))?;
    println!("wrote {} and {} figures", path.display(), figures.len());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use calibrator::{calibrate, Calibration};
    use simulator::{simulate, Scenario, SimConfig};
    use vehicle_model::effects::WheelEffects;
    use vehicle_model::estimate::StreamClocks;
    use vehicle_model::estimate_vehicle::EstimateVehicle;

    /// The estimate file as `--json` wrote it before it had a type: the
    /// calibration's JSON with `effects` patched in.
    fn untyped_writer(
        cal: &Calibration,
        reading: &[String],
        effects: Option<EffectTerms>,
    ) -> String {
        let mut with_reading = cal.clone();
        with_reading.warnings.extend(
            reading
                .iter()
                .map(|w| calibrator::Warning::new(calibrator::WarningCode::Reading, w.clone())),
        );
        let mut value = serde_json::to_value(&with_reading).expect("encoded");
        if let (Some(terms), Some(obj)) = (effects, value.as_object_mut()) {
            obj.insert(
                "effects".to_string(),
                serde_json::to_value(terms).expect("encoded"),
            );
        }
        serde_json::to_string_pretty(&value).expect("encoded") + "\n"
    }

    /// The clocks the odometry must apply: the offsets and drifts the
    /// calibration applied.
    fn applied_clocks(cal: &Calibration) -> StreamClocks {
        let offset = |o: &calibrator::StreamOffset| o.applied_shift_s();
        let drift = |o: &calibrator::StreamOffset| match (
            o.drift.applied,
            o.drift.drift_ppm,
            o.drift.ref_t_s,
        ) {
            (true, Some(p), Some(r)) => (p, r),
            _ => (0.0, 0.0),
        };
        let (g, i) = (&cal.clock_offsets.gnss_s, &cal.clock_offsets.imu_s);
        StreamClocks {
            gnss_late_s: offset(g),
            imu_late_s: offset(i),
            gnss_drift_ppm: drift(g).0,
            imu_drift_ppm: drift(i).0,
            gnss_ref_t_s: drift(g).1,
            imu_ref_t_s: drift(i).1,
        }
    }

    #[test]
    fn the_estimate_file_written_here_is_what_the_odometry_reads() {
        let mut sim = SimConfig::new(Scenario::Paper, 3);
        sim.duration_s = Some(600.0);
        let drive = simulate(&sim).expect("simulated");
        let cal = calibrate(&drive, &CalibrationConfig::default()).expect("calibrated");
        let reading = vec!["wheels.csv: 2 rows skipped".to_string()];
        let terms = EffectTerms {
            k_beta: 4e-3,
            k_z: 5e-5,
            track_rel: 0.02,
            drift_d: -1e-3,
            drift_time_constant_s: 600.0,
            gnss_latency_s: 0.08,
            ..EffectTerms::default()
        };
        let dir = tempfile::tempdir().expect("a temporary folder");
        for effects in [Some(terms), None] {
            let path = dir.path().join("est.json");
            let file = estimate_file(&cal, &reading, effects).expect("an estimate file");
            write_estimate_file(&path, &file).expect("written");
            // The odometry's reader (`odometry evaluate --estimate`, `serve --estimate`).
            let (est, made_for) = drive_io::read_estimate_with_vehicle(&path).expect("read");
            let p = est.params;
            assert_eq!(
                (p.two_wheel.c_rl, p.two_wheel.c_rr, p.two_wheel.track_width),
                (
                    cal.circumference_m.rl,
                    cal.circumference_m.rr,
                    cal.track_width_m
                )
            );
            assert_eq!(p.gyro_bias_rad_s, cal.gyro_bias_rad_s.unwrap_or(0.0));
            assert_eq!(p.gyro_scale, cal.gyro_scale.unwrap_or(0.0));
            assert_eq!(est.sigma_m, cal.sigma_m.rl.zip(cal.sigma_m.rr));
            let gyro = cal.gyro.as_ref();
            assert_eq!(
                est.antenna_m,
                gyro.map(|g| g.antenna_m).or(cal.gnss_antenna_m)
            );
            assert_eq!(
                est.antenna_sigma_m,
                gyro.map(|g| g.sigma_antenna_m).or(cal.sigma_gnss_antenna_m)
            );
            assert_eq!(est.clocks, applied_clocks(&cal));
            assert_eq!(
                est.effects,
                effects.map(WheelEffects::from).unwrap_or_default()
            );
            assert_eq!(made_for, Some(EstimateVehicle::of(&drive.vehicle)));
            // The file on disk is, byte for byte, what the untyped writer wrote.
            let text = std::fs::read_to_string(&path).expect("read back");
            assert_eq!(text, untyped_writer(&cal, &reading, effects));
            // And it reads back into the same type unchanged.
            let again = EstimateFile::from_json_str(&text, "est.json").expect("parsed");
            assert_eq!(again, file);
        }
    }
}
