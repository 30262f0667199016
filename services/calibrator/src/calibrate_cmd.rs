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
    }
    // A bar only where it helps: drives longer than five minutes.
    let mut bar = Bar {
        shown: false,
        last: -1,
    };
    // A carriage-return bar only on a terminal: a log file or a pipe gets none.
    let show =
        !args.no_progress && drive.wheel_duration_s() > 300.0 && std::io::stderr().is_terminal();
    let result = calibrate_with_progress(&drive, &config, &mut |p| {
        if show {
            bar.update(p)
        }
    });
    if bar.shown {
        eprintln!();
    }
    let cal = result.with_context(|| format!("cannot calibrate {}", args.drive.display()))?;
    print!("{}", report::render_text(&cal));
    if !reading.is_empty() {
        println!("reading the drive:");
        for w in &reading {
            println!("  - {w}");
        }
    }
    let effects = if args.diagnose {
        let d = calibrator::diagnose::diagnose(
            &drive,
            &calibrator::diagnose::DiagnoseConfig::default(),
        )
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
        Some(calibrator::diagnose::terms_beside(
            &d.terms,
            cal.track_width_estimated,
            cal.side_slip,
        ))
    } else {
        None
    };
    if let Some(path) = &args.json {
        // What reading the files said belongs with the result too.
        let mut with_reading = cal.clone();
        with_reading.warnings.extend(
            reading
                .iter()
                .map(|w| calibrator::Warning::new(calibrator::WarningCode::Reading, w.clone())),
        );
        let mut value =
            serde_json::to_value(&with_reading).context("cannot encode the calibration as JSON")?;
        if let (Some(terms), Some(obj)) = (effects, value.as_object_mut()) {
            obj.insert(
                "effects".to_string(),
                serde_json::to_value(terms).context("cannot encode the effect terms")?,
            );
        }
        let text = serde_json::to_string_pretty(&value)
            .context("cannot encode the calibration as JSON")?;
        std::fs::write(path, text + "\n")
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    let provenance = export::Provenance {
        drive: args.drive.display().to_string(),
        version: env!("CARGO_PKG_VERSION").to_string(),
    };
    for (path, text) in [
        (
            &args.export_autoware,
            args.export_autoware
                .as_ref()
                .map(|_| export::autoware_yaml(&cal, &provenance)),
        ),
        (
            &args.export_toml,
            args.export_toml
                .as_ref()
                .map(|_| export::two_wheel_toml(&cal, &provenance)),
        ),
    ] {
        if let (Some(path), Some(text)) = (path, text) {
            std::fs::write(path, text)
                .with_context(|| format!("cannot write {}", path.display()))?;
            println!("wrote {}", path.display());
        }
    }
    if let Some(dir) = &args.plots {
        let name = args.drive.file_name().map_or_else(
            || args.drive.display().to_string(),
            |n| n.to_string_lossy().to_string(),
        );
        write_plots(dir, &cal, &name, &reading)?;
    }
    Ok(())
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
