//! The `diagnose` subcommand: read the drive, run the pure diagnosis, print
//! what it found, write the JSON and the pictures with their index page.

use anyhow::{Context, Result};
use calibrator::diagnose::decide::WaldOutcome;
use calibrator::diagnose::{
    diagnose_with_progress, pictures, DiagnoseConfig, DiagnoseStage, Diagnosis,
};
use clap::Args;
use std::fmt::Write as _;
use std::io::{IsTerminal as _, Write as _};
use std::path::{Path, PathBuf};

/// Arguments of `calibrator diagnose`.
#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// Drive folder or MCAP recording (ours, compressed or not, or a ROS 2
    /// bag with --vehicle). Several drives of one car (or one folder of
    /// drive folders) are diagnosed each on its own and together: the
    /// car's effects pooled over them.
    #[arg(required = true, num_args = 1..)]
    pub drives: Vec<PathBuf>,
    #[command(flatten)]
    pub input: crate::drive_input::DriveInput,
    /// Write the diagnosis JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the pictures and index.html into this folder.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// Block length for the held-out tests, s (default: a twelfth of the drive, 5-60 s).
    #[arg(long)]
    pub block: Option<f64>,
    /// No progress display.
    #[arg(long)]
    pub no_progress: bool,
    /// Only the held-out test decides (without Holm's procedure on the
    /// joint Wald statistics): for comparisons.
    #[arg(long)]
    pub held_out_only: bool,
    /// Measure the Wald decision's false-alarm rate on N redraws of the
    /// drive's GNSS errors from its own error model (`null_false_alarm`).
    #[arg(long, default_value_t = 0)]
    pub null_draws: usize,
    /// Read a damaged MCAP recording by leaving out each chunk whose records
    /// fail their CRC (a warning names each one) instead of refusing it.
    #[arg(long)]
    pub skip_corrupt_chunks: bool,
    /// Diagnose what a truncated MCAP recording holds before its damage
    /// (a warning names the damage) instead of refusing it.
    #[arg(long)]
    pub allow_truncated: bool,
}

/// The settings `args` ask for.
pub fn config(args: &DiagnoseArgs) -> Result<DiagnoseConfig> {
    if let Some(b) = args.block {
        anyhow::ensure!(b.is_finite() && b >= 2.0, "--block {b}: at least 2 s");
    }
    Ok(DiagnoseConfig {
        block_s: args.block,
        wald_decision: !args.held_out_only,
        null_draws: args.null_draws,
        ..DiagnoseConfig::default()
    })
}

/// Read one drive as `args` say, with what reading it warned of.
pub fn read_drive(args: &DiagnoseArgs, path: &Path) -> Result<drive_io::LoadedDrive> {
    let loaded = drive_io::cli::accept_truncated(
        args.input.read(path, args.skip_corrupt_chunks)?,
        args.allow_truncated,
    )
    .with_context(|| format!("cannot read drive {}", path.display()))?;
    for w in &loaded.warnings {
        tracing::warn!("{w}");
    }
    Ok(loaded)
}

/// What reading a drive warned of, as the diagnosis's warnings.
pub fn reading_warnings(loaded: &[String]) -> impl Iterator<Item = calibrator::Warning> + '_ {
    loaded
        .iter()
        .map(|w| calibrator::Warning::new(calibrator::WarningCode::Reading, w.clone()))
}

/// `calibrator diagnose DRIVE`: one drive.
pub fn run_one(args: &DiagnoseArgs, path: &Path) -> Result<()> {
    let loaded = read_drive(args, path)?;
    let drive = loaded.drive;
    let cfg = config(args)?;
    // A carriage-return progress line only on a terminal.
    let show =
        !args.no_progress && drive.wheel_duration_s() > 300.0 && std::io::stderr().is_terminal();
    let mut shown = false;
    let result = diagnose_with_progress(&drive, &cfg, &mut |stage, fraction| {
        if show {
            let name = match stage {
                DiagnoseStage::Calibrate => "calibrating the plain model",
                DiagnoseStage::Channels => "residual channels",
                DiagnoseStage::Select => "testing the catalogue effects",
                DiagnoseStage::Fit => "held-out fit before and after",
                DiagnoseStage::Done => "done",
            };
            let mut err = std::io::stderr();
            let _ = write!(err, "\r{:3.0}% {name:<32}", 100.0 * fraction);
            let _ = err.flush();
            shown = true;
        }
    });
    if shown {
        eprintln!();
    }
    let mut d = result.with_context(|| format!("cannot diagnose {}", path.display()))?;
    // What reading the files said belongs with the result too.
    d.warnings.extend(reading_warnings(&loaded.warnings));
    print!("{}", render_text(&d));
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&d).context("cannot encode the diagnosis")?;
        std::fs::write(path, text + "\n")
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    if let Some(dir) = &args.plots {
        write_pictures(dir, &d)?;
    }
    Ok(())
}

/// The drive's pictures and their index page, into `dir`.
pub fn write_pictures(dir: &Path, d: &Diagnosis) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let draw = "cannot draw the diagnosis's pictures";
    let mut pictures: Vec<(String, String)> = vec![
        (
            "tracks.svg".to_string(),
            pictures::tracks_svg(&d.tracks).context(draw)?,
        ),
        (
            "block_errors.svg".to_string(),
            pictures::block_errors_svg(&d.tracks).context(draw)?,
        ),
    ];
    for p in &d.residual_plots {
        pictures.push((
            format!("residual_{}.svg", p.effect),
            pictures::residual_svg(p).context(draw)?,
        ));
    }
    for (name, svg) in &pictures {
        let path = dir.join(name);
        std::fs::write(&path, svg).with_context(|| format!("cannot write {}", path.display()))?;
    }
    let index = dir.join("index.html");
    std::fs::write(&index, pictures::index_html(d, &pictures))
        .with_context(|| format!("cannot write {}", index.display()))?;
    println!("wrote {} pictures and {}", pictures.len(), index.display());
    Ok(())
}

/// The diagnosis as text for the terminal.
pub fn render_text(d: &Diagnosis) -> String {
    let mut s = String::new();
    write_model_and_noise(&mut s, d);
    write_findings(&mut s, d);
    write_other_effects(&mut s, d);
    write_fit(&mut s, d);
    information_text(&mut s, d);
    s
}

/// The plain 2W model, the warnings of reading the drive, the noise.
fn write_model_and_noise(s: &mut String, d: &Diagnosis) {
    let _ = writeln!(
        s,
        "plain 2W model: c_RL {:.4} m, c_RR {:.4} m, track {:.3} m (vehicle.toml)",
        d.base_model.c_rl_m, d.base_model.c_rr_m, d.base_model.track_width_m
    );
    if !d.warnings.is_empty() {
        let _ = writeln!(s, "read with warnings:");
        for w in &d.warnings {
            let code = serde_json::to_string(&w.code).unwrap_or_default();
            let _ = writeln!(s, "  - [{}] {}", code.trim_matches('"'), w.message);
        }
    }
    let _ = writeln!(
        s,
        "noise: GNSS {:.3} m (1 sigma), {} blocks of {:.0} s{}",
        d.noise.gnss_sigma_m,
        d.noise.blocks,
        d.noise.block_s,
        if d.noise.gnss_jumps > 0 {
            format!(", {} epochs set aside as GNSS jumps", d.noise.gnss_jumps)
        } else {
            String::new()
        }
    );
}

/// The effects accepted, with their parameters and held-out gain.
fn write_findings(s: &mut String, d: &Diagnosis) {
    if d.findings.is_empty() {
        let _ = writeln!(
            s,
            "findings: none beyond the noise: the plain 2W model explains this drive"
        );
    } else {
        let _ = writeln!(s, "findings:");
        for f in &d.findings {
            let params: Vec<String> = f
                .parameters
                .iter()
                .map(|(k, v)| {
                    let sig = f.sigmas.get(k).copied().unwrap_or(f64::NAN);
                    let unit = f.units.get(k).map_or("", |u| u.as_str());
                    format!("{k} = {v:.4e} ± {sig:.1e} {unit}")
                })
                .collect();
            let _ = writeln!(
                s,
                "  {}{}: {}; held-out position RMSE {:.3} -> {:.3} m",
                f.effect,
                if f.variant.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", f.variant)
                },
                params.join(", "),
                f.holdout_rmse_before_m,
                f.holdout_rmse_after_m
            );
            let _ = writeln!(s, "    {}", f.evidence);
        }
    }
}

/// The effects ambiguous, unexplained stretches, mismatching segments, the
/// effects rejected, not accepted (with what this drive could detect) and
/// not testable.
fn write_other_effects(s: &mut String, d: &Diagnosis) {
    for a in &d.ambiguous {
        let ids: Vec<&str> = a.effects.iter().map(|e| e.id()).collect();
        let _ = writeln!(
            s,
            "ambiguous: {} (VIF {:.0}); separate by {}",
            ids.join(" / "),
            a.vif,
            a.separate_by
        );
    }
    for u in &d.unexplained {
        let _ = writeln!(
            s,
            "unexplained: {:.1}-{:.1} s at ({:.0}, {:.0}) m in {}: {}",
            u.t_start_s, u.t_end_s, u.x_m, u.y_m, u.channel, u.correlates_with
        );
    }
    for m in &d.mismatch_segments {
        let _ = writeln!(
            s,
            "mismatch: {:.1}-{:.1} s, {:.3} m RMS: {}",
            m.t_start_s, m.t_end_s, m.rms_m, m.manoeuvre
        );
    }
    for r in &d.rejected {
        let _ = writeln!(s, "rejected {}: {}", r.effect, r.reason);
    }
    if !d.not_accepted.is_empty() {
        let parts: Vec<String> = d
            .not_accepted
            .iter()
            .map(|n| {
                format!(
                    "{} {:+.1} % (z {:.1})",
                    n.effect,
                    100.0 * n.holdout_gain,
                    n.z
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "tested, not accepted (held-out gain, signed-rank z; needed z > {:.2}): {}",
            d.not_accepted[0].z_threshold,
            parts.join(", ")
        );
        for n in &d.not_accepted {
            let text = n.detectable_text();
            if !text.is_empty() {
                let _ = writeln!(s, "  {}: this drive {}", n.effect, text);
            }
        }
    }
    for u in &d.untestable {
        let _ = writeln!(s, "not testable here: {} (needs {})", u.effect, u.needs);
    }
}

/// The held-out fit before and after.
fn write_fit(s: &mut String, d: &Diagnosis) {
    let (b, a) = (&d.fit.before, &d.fit.after);
    let _ = writeln!(
        s,
        "held-out fit, before -> after: position RMSE {:.3} -> {:.3} m, heading RMSE {:.4} -> {:.4} rad, \
         speed RMSE {:.4} -> {:.4}, residual lag-1 autocorrelation {:.2} -> {:.2}",
        b.holdout_position_rmse_m,
        a.holdout_position_rmse_m,
        b.holdout_heading_rmse_rad,
        a.holdout_heading_rmse_rad,
        b.holdout_speed_rmse_rel,
        a.holdout_speed_rmse_rel,
        b.residual_lag1_autocorr,
        a.residual_lag1_autocorr
    );
}

/// What the drive could show of each effect (the information limit),
/// beside the size the held-out test needs where it said one.
fn information_text(s: &mut String, d: &Diagnosis) {
    let Some(l) = &d.information_limit else {
        if let Some(why) = &d.information_limit_missing {
            let _ = writeln!(s, "information limit: not known ({why})");
        }
        return;
    };
    let noise = |n: &[f64; 3]| format!("{:.2} m white + {:.2} m over {:.1} s", n[0], n[1], n[2]);
    let _ = writeln!(
        s,
        "what this drive could show (90 % power at a family-wise level of {:.0} %; GNSS error with every \
         effect in: east {}, north {}; {} segments of {:.0} s):",
        100.0 * l.family_alpha,
        noise(&l.noise_east),
        noise(&l.noise_north),
        l.segments,
        l.segment_s
    );
    for e in &l.effects {
        let shows = match (e.smallest, e.relative_to_typical) {
            (Some(v), Some(r)) => format!(
                "from {} = {v:.2e} {} ({r:.2}x typical)",
                e.parameter, e.unit
            ),
            _ => "nothing: the drive holds no information about it".to_string(),
        };
        let joint = e
            .joint
            .as_ref()
            .and_then(|j| j.smallest)
            .map(|v| format!("; with every other effect free {:.2}x", v / e.typical))
            .unwrap_or_default();
        let test = d
            .not_accepted
            .iter()
            .find(|n| n.effect == e.effect)
            .and_then(|n| n.detectable.as_ref())
            .map(|det| match det.smallest {
                Some(v) => format!("; the held-out test needs {:.2}x", v / det.typical),
                None => "; the held-out test does not show it at 64x".to_string(),
            })
            .unwrap_or_default();
        let alone = match (e.estimate, e.sigma, e.wald_z) {
            (Some(v), Some(sg), Some(z)) => {
                format!(" [{}: {v:.2e} ± {sg:.1e}, z {z:.1}]", e.source.describe())
            }
            _ => format!(" [{}]", e.source.describe()),
        };
        let power = e
            .power_at_typical
            .map(|p| format!("; a typical one shown with probability {:.2}", p))
            .unwrap_or_default();
        let _ = writeln!(s, "  {}: {shows}{joint}{power}{test}{alone}", e.effect);
    }
    let called: Vec<String> = d
        .wald
        .iter()
        .filter(|w| w.test.significant || w.outcome == WaldOutcome::Ambiguous)
        .map(|w| {
            format!(
                "{} z {:+.1} against {:.1}: {}",
                w.test.effect,
                w.test.z,
                w.test.z_critical,
                w.outcome.describe()
            )
        })
        .collect();
    if let Some(r) = &d.null_false_alarm {
        let _ = writeln!(
            s,
            "false alarms on {} redraws of this drive's GNSS errors from its own error model: {} \
             ({:.1} % against the nominal {:.0} %, binomial sigma {:.1} %)",
            r.draws,
            r.rejections,
            100.0 * r.rate,
            100.0 * r.family_alpha,
            100.0 * r.sigma
        );
    }
    let _ = writeln!(
        s,
        "Holm's procedure on the joint Wald z (family-wise {:.0} %): {}",
        100.0 * l.family_alpha,
        if called.is_empty() {
            "no effect significant".to_string()
        } else {
            called.join("; ")
        }
    );
}
