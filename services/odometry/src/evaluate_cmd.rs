//! `odometry evaluate`: dead-reckon through simulated GNSS outages placed
//! along a drive, the pose taken from truth.csv at each outage start, and
//! score the position at each outage end; print the report, write the JSON
//! and the page.

use crate::odometer_args::OdometerArgs;
use anyhow::{Context, Result};
use odometry::evaluate::{
    choose_truth_point, evaluate, EvaluateConfig, EvaluationReport, Parameters, TruthPointChoice,
    TruthPointSource,
};
use odometry::evaluation_page;
use std::path::PathBuf;
use vehicle_model::estimate::MAX_FUSED_ANTENNA_SIGMA_M;

/// Arguments of `odometry evaluate`.
#[derive(Debug, clap::Args)]
pub(crate) struct EvaluateArgs {
    /// Drive folder or MCAP recording (needs truth.csv), or a ROS 2 bag
    /// with --vehicle.
    drive: PathBuf,
    #[command(flatten)]
    input: drive_io::cli::DriveInput,
    /// Estimate written by `calibrator calibrate --json`; without it, the
    /// nominal values of vehicle.toml.
    #[arg(long)]
    estimate: Option<PathBuf>,
    /// Dead-reckon with the 2W model extended by the effects a diagnosis
    /// found: the JSON `calibrator diagnose --json` wrote (its `terms`).
    /// Without it, the effects the estimate carries (`calibrate --diagnose`).
    #[arg(long, value_name = "DIAGNOSIS_JSON")]
    effects: Option<PathBuf>,
    /// Outage length, seconds.
    #[arg(long, default_value_t = 30.0)]
    outage: f64,
    /// Time between outage starts, seconds.
    #[arg(long, default_value_t = 10.0)]
    spacing: f64,
    /// Write the result as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write the evaluation's report into this folder: index.html (one
    /// self-contained page: score, warnings, numbers, figures) and each
    /// figure as an SVG file.
    #[arg(long)]
    plots: Option<PathBuf>,
    /// Dead-reckoning settings.
    #[command(flatten)]
    odometer: OdometerArgs,
    /// The body point truth.csv follows, scored at the outage ends: `auto`
    /// (the GNSS antenna when truth.csv is the GNSS track itself, as an RTK
    /// truth is, and the antenna's position is known; else the rear-axle
    /// centre), `axle`, `antenna` (vehicle.toml's measured `[gnss]`, else
    /// the estimate's calibrated one), or `X,Y` in metres (x forward, y left
    /// of the rear-axle centre).
    #[arg(long, default_value = "auto")]
    truth_point: TruthPointChoice,
}

/// `odometry evaluate`: read the drive and the estimate, evaluate, report.
pub(crate) fn run_evaluate(args: &EvaluateArgs) -> Result<()> {
    let loaded = args
        .input
        .read(&args.drive, false)
        .context("reading --vehicle / --topics")?
        .with_context(|| format!("cannot read drive {}", args.drive.display()))?;
    for w in &loaded.warnings {
        tracing::warn!("{w}");
    }
    let drive = loaded.drive;
    drive
        .vehicle
        .check_plausible()
        .map_err(|e| anyhow::anyhow!("{}: vehicle.toml: {e}", args.drive.display()))?;
    let Parameters {
        params,
        source,
        antenna,
        antenna_sigma,
        effects: estimate_effects,
        clocks,
        other_vehicle,
    } = parameters(args, &drive)?;
    let truth_point =
        choose_truth_point(&drive, args.truth_point, antenna).context("--truth-point")?;
    let config = EvaluateConfig {
        outage_s: args.outage,
        spacing_s: args.spacing,
        odometer: args.odometer.config(),
        truth_point,
        // The diagnosis given, else the terms the estimate carries.
        effects: match &args.effects {
            Some(path) => read_effect_terms(path)?,
            None => estimate_effects,
        },
        clocks,
        keep_tracks: args.plots.is_some(),
        ..EvaluateConfig::default()
    };
    let mut report = evaluate(&drive, &params, &config)
        .with_context(|| format!("cannot evaluate {}", args.drive.display()))?;
    if let Some(w) = other_vehicle {
        tracing::warn!("{w}");
        report.warnings.insert(0, w);
    }
    print_report(
        &report,
        &source,
        &args.drive.display().to_string(),
        antenna_sigma,
    );
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&report).context("cannot serialise the report")?;
        std::fs::write(path, text + "\n")
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(dir) = &args.plots {
        write_page(dir, &report, &drive, &args.drive, &source)?;
    }
    Ok(())
}

/// `--estimate` read and checked against the drive's vehicle, or the nominal values.
fn parameters(args: &EvaluateArgs, drive: &interfaces::drive::Drive) -> Result<Parameters> {
    match &args.estimate {
        Some(path) => {
            let (estimate, made_for) =
                drive_io::read_estimate_with_vehicle(path).context("cannot use the estimate")?;
            Ok(Parameters::of_estimate(
                estimate,
                made_for,
                &path.display().to_string(),
                drive,
                &args.drive.display().to_string(),
            )?)
        }
        None => Ok(Parameters::nominal(drive)),
    }
}

/// The evaluation's page and figures into `dir`.
fn write_page(
    dir: &std::path::Path,
    report: &EvaluationReport,
    drive: &interfaces::drive::Drive,
    path: &std::path::Path,
    source: &str,
) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let truth: Vec<[f64; 2]> = drive
        .truth
        .iter()
        .flatten()
        .map(|t| [t.x_m, t.y_m])
        .collect();
    let figures =
        evaluation_page::figures(report, &truth).context("cannot draw the evaluation's figures")?;
    for f in &figures {
        let file = dir.join(f.file);
        std::fs::write(&file, &f.svg)
            .with_context(|| format!("cannot write {}", file.display()))?;
    }
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().to_string(),
    );
    let page = dir.join("index.html");
    std::fs::write(
        &page,
        evaluation_page::evaluation_html(report, &name, source, &figures),
    )
    .with_context(|| format!("cannot write {}", page.display()))?;
    println!("wrote {} and {} figures", page.display(), figures.len());
    Ok(())
}

/// `antenna_sigma`: the estimate's 1-sigma of its antenna position, m.
fn print_report(
    report: &EvaluationReport,
    source: &str,
    drive: &str,
    antenna_sigma: Option<[f64; 2]>,
) {
    println!("drive      {drive}");
    println!("parameters {source}");
    let p = &report.params;
    println!(
        "           c_rl {:.5} m  c_rr {:.5} m  track {:.4} m  gyro bias {:.6} rad/s  scale {:.5}",
        p.c_rl_m, p.c_rr_m, p.track_width_m, p.gyro_bias_rad_s, p.gyro_scale
    );
    println!("heading    {}", report.heading);
    let [x, y] = report.truth_point.point_m;
    let point = match report.truth_point.source {
        TruthPointSource::Axle => "the rear-axle centre".to_string(),
        TruthPointSource::Given => format!("({x:+.3}, {y:+.3}) m, as given"),
        TruthPointSource::MeasuredAntenna => {
            format!("the GNSS antenna at ({x:+.3}, {y:+.3}) m, measured (vehicle.toml [gnss])")
        }
        TruthPointSource::EstimatedAntenna => {
            let sigma = match antenna_sigma {
                Some([sx, sy]) if sx.max(sy) > MAX_FUSED_ANTENNA_SIGMA_M => format!(
                    ", 1-sigma ({sx:.2}, {sy:.2}) m: poorly determined, the score carries its error"
                ),
                Some([sx, sy]) => format!(", 1-sigma ({sx:.2}, {sy:.2}) m"),
                None => String::new(),
            };
            format!("the GNSS antenna at ({x:+.3}, {y:+.3}) m, calibrated (the estimate){sigma}")
        }
    };
    println!("scored at  {point}");
    if report.truth_is_gnss_track {
        println!(
            "           (truth.csv is the GNSS track itself: it follows the antenna{})",
            if report.truth_point.source == TruthPointSource::Axle {
                ", so a score at the rear axle includes the antenna's lever arm; to compare with \
                 a calibrated run, score both at its antenna: --truth-point X,Y"
            } else {
                ""
            }
        );
    }
    println!();
    println!(
        "  start s  length s  distance m   error m  error %  gyro bias rad/s (standstills)  start pose from"
    );
    for o in &report.outages {
        let pct = o
            .error_pct
            .map_or_else(|| "     -".to_string(), |p| format!("{p:6.2}"));
        println!(
            "  {:7.2}  {:8.1}  {:10.1}  {:8.3}  {pct}   {:12.6} ({:3})             {}",
            o.t_start_s,
            o.length_s,
            o.distance_m,
            o.error_m,
            o.gyro_bias_rad_s,
            o.gyro_bias_standstills,
            o.start_yaw_source
        );
    }
    println!();
    let pct = report
        .median_error_pct
        .map_or_else(|| "-".to_string(), |p| format!("{p:.2} %"));
    println!(
        "median error {:.3} m   p90 {:.3} m   median {pct} of the distance   ({} outages)",
        report.median_error_m,
        report.p90_error_m,
        report.outages.len()
    );
    for w in &report.warnings {
        println!("warning: {w}");
    }
}

/// The effect terms of a diagnosis JSON (`calibrator diagnose --json`).
fn read_effect_terms(path: &std::path::Path) -> Result<vehicle_model::effects::EffectTerms> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read the diagnosis {}", path.display()))?;
    let value: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))?;
    let terms = value
        .get("terms")
        .with_context(|| format!("{}: no `terms` (is it a diagnosis?)", path.display()))?;
    let terms: vehicle_model::effects::EffectTerms = serde_json::from_value(terms.clone())
        .with_context(|| format!("{}: `terms`", path.display()))?;
    let active = terms.active();
    tracing::info!(
        "dead-reckoning with the effect terms of {}: {}",
        path.display(),
        if active.is_empty() {
            "none (the plain 2W model)".to_string()
        } else {
            active.iter().map(|e| e.id()).collect::<Vec<_>>().join(", ")
        }
    );
    Ok(terms)
}
