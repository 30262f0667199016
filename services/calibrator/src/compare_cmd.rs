//! The `compare` subcommand: read a recording and a simulation of the same
//! path, diagnose both the same way, print what differs, write the JSON
//! and the page ([`calibrator::diagnose::compare`]).

use anyhow::{Context, Result};
use calibrator::diagnose::compare::{
    compare_draws, Carried, CompareConfig, Comparison, Declared, Summary,
};
use calibrator::diagnose::speed_map::SpeedMapDifference;
use calibrator::diagnose::{compare_pictures as pics, diagnose, DiagnoseConfig, Diagnosis};
use clap::Args;
use interfaces::drive::{toml_value, Drive};
use interfaces::speed_map::SpeedMap;
use interfaces::yaw_wander::YawWander;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Arguments of `calibrator compare`.
#[derive(Debug, Args)]
pub struct CompareArgs {
    /// The recording: a drive folder or MCAP recording.
    pub recording: PathBuf,
    /// The simulation of the same path (any simulator that writes the drive
    /// format or MCAP; e.g. `sensor-bridge simulate --like RECORDING`).
    pub simulation: PathBuf,
    /// Another noise draw of the same simulation (the same physics under
    /// another seed, e.g. `sensor-bridge simulate --like RECORDING --seed
    /// K`), repeatable: the effects' differences read the simulation as
    /// the mean of its draws, so its noise weighs less against the
    /// recording's. Each draw must declare the physics SIMULATION declares
    /// and hold other GNSS fixes.
    #[arg(long, value_name = "SIMULATION")]
    pub draw: Vec<PathBuf>,
    #[command(flatten)]
    pub input: crate::drive_input::DriveInput,
    /// Write the comparison as JSON here (its `findings` are what
    /// `sensor-bridge simulate --like RECORDING --effects-from` reads to
    /// mend the simulation).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the pictures and index.html into this folder.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// The comparison JSON from before a mend: the page and the text show
    /// each channel's distance before and now.
    #[arg(long, value_name = "COMPARISON.json")]
    pub before: Option<PathBuf>,
    /// Block length for both diagnoses, s (default: the recording's, a
    /// twelfth of it, 5-60 s).
    #[arg(long)]
    pub block: Option<f64>,
}

/// What the JSON holds: the comparison and the two paths.
#[derive(serde::Serialize)]
struct Written<'a> {
    recording: String,
    simulation: String,
    /// Further noise draws of the simulation (`--draw`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    draws: Vec<String>,
    #[serde(flatten)]
    comparison: &'a Comparison,
}

/// `calibrator compare RECORDING SIMULATION`.
pub fn run_compare(args: &CompareArgs) -> Result<()> {
    let read = |p: &Path| -> Result<Drive> {
        let loaded = drive_io::cli::accept_truncated(args.input.read(p, false)?, false)
            .with_context(|| format!("cannot read drive {}", p.display()))?;
        for w in &loaded.warnings {
            tracing::warn!("{}: {w}", p.display());
        }
        Ok(loaded.drive)
    };
    if let Some(b) = args.block {
        anyhow::ensure!(b.is_finite() && b >= 2.0, "--block {b}: at least 2 s");
    }
    let before = args.before.as_deref().map(read_earlier).transpose()?;
    let (real, sim) = (read(&args.recording)?, read(&args.simulation)?);
    let mut cfg = DiagnoseConfig {
        block_s: args.block,
        ..DiagnoseConfig::default()
    };
    let dr = diagnose(&real, &cfg)
        .with_context(|| format!("cannot diagnose the recording {}", args.recording.display()))?;
    cfg.block_s = Some(dr.noise.block_s);
    let ds = diagnose(&sim, &cfg).with_context(|| {
        format!(
            "cannot diagnose the simulation {}",
            args.simulation.display()
        )
    })?;
    // The physics the simulation declares (its truth.toml's `[effects]`:
    // a simulator's own statement of what it simulated); the recording's
    // truth is never read.
    let declared: Option<Declared> = sim.truth_params.as_ref().map(|t| t.effects.clone());
    let mut draws = Vec::with_capacity(args.draw.len());
    for path in &args.draw {
        let d = read(path)?;
        check_draw(&sim, &args.simulation, &d, path, &draws)?;
        let dd = diagnose(&d, &cfg)
            .with_context(|| format!("cannot diagnose the simulation's draw {}", path.display()))?;
        draws.push((d, dd));
    }
    let mut all_sims: Vec<&Diagnosis> = vec![&ds];
    all_sims.extend(draws.iter().map(|(_, dd)| dd));
    let declared_map = declared_extra(
        &sim,
        "speed_map",
        SpeedMap::is_valid,
        "edges must ascend, with one value more than edges, all finite",
    )
    .with_context(|| {
        format!(
            "{}: truth.toml's speed_map is not a speed map",
            args.simulation.display()
        )
    })?;
    let declared_wander = declared_extra(
        &sim,
        "yaw_wander",
        YawWander::is_valid,
        "sigma_rad_s must lie within [0, 0.1] and tau_s within [0.01, 10000]",
    )
    .with_context(|| {
        format!(
            "{}: truth.toml's yaw_wander is not a yaw wander",
            args.simulation.display()
        )
    })?;
    let carried = Carried {
        speed_map: declared_map,
        yaw_wander: declared_wander,
    };
    let c = compare_draws(
        &dr,
        &all_sims,
        declared.as_ref(),
        &carried,
        &CompareConfig::default(),
    );
    print!("{}", render_text(&c, before.as_ref()));
    if let Some(path) = &args.json {
        let w = Written {
            recording: args.recording.display().to_string(),
            simulation: args.simulation.display().to_string(),
            draws: args.draw.iter().map(|p| p.display().to_string()).collect(),
            comparison: &c,
        };
        let text = serde_json::to_string_pretty(&w).context("cannot encode the comparison")?;
        std::fs::write(path, text + "\n")
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    if let Some(dir) = &args.plots {
        write_page(args, dir, &c, [&real, &sim], [&dr, &ds], before.as_ref())?;
    }
    Ok(())
}

/// A further noise draw of the simulation is one only when it declares
/// the same physics (its truth.toml's `[effects]` and what it carries
/// beyond them, or no truth.toml where the simulation has none) and its
/// GNSS fixes are not those of the simulation or of an earlier draw: the
/// same draw twice would shrink the simulation's sigma with no new
/// information.
fn check_draw(
    sim: &Drive,
    sim_path: &Path,
    draw: &Drive,
    path: &Path,
    earlier: &[(Drive, Diagnosis)],
) -> Result<()> {
    fn physics(d: &Drive) -> Option<(&Declared, [Option<&toml_value::Value>; 2])> {
        d.truth_params.as_ref().map(|t| {
            (
                &t.effects,
                ["speed_map", "yaw_wander"].map(|k| t.extra.get(k)),
            )
        })
    }
    anyhow::ensure!(
        physics(draw) == physics(sim),
        "--draw {}: it declares other physics than the simulation {} (truth.toml's [effects], speed_map or \
         yaw_wander differ); a draw is the same simulation under another noise seed",
        path.display(),
        sim_path.display()
    );
    if sim.truth_params.is_none() {
        tracing::warn!(
            "--draw {}: neither it nor {} declares its physics (no truth.toml); that they are draws of one \
             simulation is taken on trust",
            path.display(),
            sim_path.display()
        );
    }
    let same = |a: &Drive| a.gnss.is_some() && a.gnss == draw.gnss;
    anyhow::ensure!(
        !same(sim) && !earlier.iter().any(|(d, _)| same(d)),
        "--draw {}: its GNSS fixes are those of {} or of an earlier draw: the same noise draw twice is not a \
         second draw",
        path.display(),
        sim_path.display()
    );
    Ok(())
}

/// What a simulation says it carries under `key` of its truth.toml (our
/// twin writes `speed_map` and `yaw_wander`), checked by `valid`
/// (`rule` says what a valid one is).
fn declared_extra<T: serde::de::DeserializeOwned>(
    sim: &Drive,
    key: &str,
    valid: impl Fn(&T) -> bool,
    rule: &str,
) -> Result<Option<T>> {
    let Some(v) = sim.truth_params.as_ref().and_then(|t| t.extra.get(key)) else {
        return Ok(None);
    };
    let x: T = serde_json::from_value(serde_json::to_value(v)?)?;
    anyhow::ensure!(valid(&x), "{rule}");
    Ok(Some(x))
}

/// An earlier comparison's verdicts and channel distances, from its JSON.
fn read_earlier(path: &Path) -> Result<Summary> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text)
        .with_context(|| format!("{}: not a comparison JSON", path.display()))
}

/// The pictures and the index page.
fn write_page(
    args: &CompareArgs,
    dir: &Path,
    c: &Comparison,
    drives: [&Drive; 2],
    diagnoses: [&Diagnosis; 2],
    before: Option<&Summary>,
) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let draw = "cannot draw the comparison's pictures";
    let fixes = |d: &Drive| -> Vec<[f64; 2]> {
        let g = d.gnss.as_deref().unwrap_or(&[]);
        let step = g.len().div_ceil(2500).max(1);
        g.iter().step_by(step).map(|f| [f.x_m, f.y_m]).collect()
    };
    let mut pictures: Vec<(String, String)> = vec![
        (
            "tracks.svg".into(),
            pics::tracks_svg(&fixes(drives[0]), &fixes(drives[1])).context(draw)?,
        ),
        ("effects.svg".into(), pics::effects_svg(c).context(draw)?),
        (
            "blocks.svg".into(),
            pics::blocks_svg(c, diagnoses[0], diagnoses[1]).context(draw)?,
        ),
    ];
    if let Some(b) = before {
        pictures.push(("mend.svg".into(), pics::mend_svg(b, c).context(draw)?));
    }
    if let Some(m) = &c.speed_map {
        for signal in ["speed", "a_x"] {
            pictures.push((
                format!("speed_map_{signal}.svg"),
                pics::speed_map_svg(m, signal).context(draw)?,
            ));
        }
    }
    if let Some(w) = &c.yaw_wander {
        pictures.push((
            "yaw_wander.svg".into(),
            pics::yaw_wander_svg(w).context(draw)?,
        ));
    }
    for ch in &c.channels {
        pictures.push((
            format!("channel_{}.svg", ch.channel),
            pics::channel_svg(ch, diagnoses[0], diagnoses[1]).context(draw)?,
        ));
    }
    for (name, svg) in &pictures {
        let path = dir.join(name);
        std::fs::write(&path, svg).with_context(|| format!("cannot write {}", path.display()))?;
    }
    let names = [
        args.recording.display().to_string(),
        args.simulation.display().to_string(),
    ];
    let index = dir.join("index.html");
    std::fs::write(
        &index,
        pics::index_html(c, [&names[0], &names[1]], before, &pictures),
    )
    .with_context(|| format!("cannot write {}", index.display()))?;
    println!("wrote {} pictures and {}", pictures.len(), index.display());
    Ok(())
}

/// The comparison as text for the terminal.
fn render_text(c: &Comparison, before: Option<&Summary>) -> String {
    let mut s = String::new();
    let named: Vec<_> = c.named().collect();
    if let Some(why) = &c.effects_missing {
        let _ = writeln!(s, "the effects could not be compared: {why}");
    }
    if c.simulation_draws > 1 {
        let _ = writeln!(
            s,
            "the simulation read as the mean of its {} noise draws",
            c.simulation_draws
        );
    }
    if named.is_empty() {
        let _ = writeln!(s, "physics: no effect differs beyond the noise");
    } else {
        let _ = writeln!(s, "physics the two differ in (Holm's procedure, 5 %):");
        for e in &named {
            let _ = writeln!(s, "  - {}: {}; {}", e.effect, e.verdict.words(), e.evidence);
        }
    }
    for e in c.effects.iter().filter(|e| {
        matches!(
            e.verdict,
            calibrator::diagnose::compare::DifferenceVerdict::Guarded
                | calibrator::diagnose::compare::DifferenceVerdict::Implausible
        )
    }) {
        let _ = writeln!(
            s,
            "  not named: {}: {}; {}",
            e.effect,
            e.verdict.words(),
            e.evidence
        );
    }
    if c.parting.is_empty() {
        let _ = writeln!(
            s,
            "where they part: nowhere beyond the simulation's block-to-block scatter ({} blocks matched)",
            c.matched_blocks
        );
    } else {
        let _ = writeln!(s, "where they part ({} blocks matched):", c.matched_blocks);
        for p in &c.parting {
            let _ = writeln!(
                s,
                "  - {:.0}-{:.0} s: plain-model error {:.2} m on the recording, {:.2} m on the simulation (z {:.1}); {}",
                p.t_start_s, p.t_end_s, p.recording_rms_m, p.simulation_rms_m, p.z, p.manoeuvre
            );
        }
    }
    let _ = writeln!(
        s,
        "residual channels within their noise level: {} of {}; differing beyond the noise (Holm over the channels, 5 %): {}",
        c.channels_within_noise,
        c.channels.len(),
        c.channels_differing
    );
    for ch in &c.channels {
        let was = before
            .and_then(|b| b.channels.iter().find(|x| x.channel == ch.channel))
            .map_or(String::new(), |b| {
                format!(
                    " (before: {} against {}, {})",
                    pics::sig3(b.distance),
                    pics::sig3(b.noise_level),
                    if b.within_noise { "within" } else { "beyond" }
                )
            });
        let _ = writeln!(
            s,
            "  - {}: distance {} {} against a noise level of {} (p {:.3}): {}{}{was}",
            ch.channel,
            pics::sig3(ch.distance),
            ch.unit,
            pics::sig3(ch.noise_level),
            ch.p_value,
            if ch.within_noise { "within" } else { "beyond" },
            if ch.differs { "; differs (Holm)" } else { "" }
        );
    }
    if let Some(m) = &c.speed_map {
        render_speed_map(&mut s, m);
    }
    if let Some(w) = &c.yaw_wander {
        render_yaw_wander(&mut s, w);
    }
    if let Some(b) = before {
        let was: Vec<String> = b.named().map(|e| e.effect.to_string()).collect();
        let _ = writeln!(
            s,
            "before the mend: {} named ({}); now {}",
            was.len(),
            if was.is_empty() {
                "none".into()
            } else {
                was.join(", ")
            },
            named.len()
        );
    }
    if let Some(w) = &c.twin_yaw_wander {
        let _ = writeln!(
            s,
            "the mended simulation's wheels should wander in yaw by {} rad/s at {} s",
            pics::sig3(w.sigma_rad_s),
            pics::sig3(w.tau_s)
        );
    }
    let _ = writeln!(
        s,
        "the mended simulation should carry: {}",
        if c.findings.is_empty() {
            "no effect".to_string()
        } else {
            c.findings
                .iter()
                .map(|f| {
                    let p: Vec<String> = f
                        .parameters
                        .iter()
                        .map(|(k, v)| format!("{k} {}", pics::sig3(*v)))
                        .collect();
                    format!("{} ({})", f.effect, p.join(", "))
                })
                .collect::<Vec<_>>()
                .join("; ")
        }
    );
    s
}

/// The wheels' yaw wander of the two drives, and what the mend does with
/// it.
fn render_yaw_wander(s: &mut String, w: &calibrator::diagnose::yaw_wander::WanderDifference) {
    let one = |m: &calibrator::diagnose::yaw_wander::WanderMeasure| {
        format!(
            "{} rad/s at {} s (white {} rad/sqrt(s))",
            pics::sig3(m.sigma_rad_s),
            pics::sig3(m.tau_s),
            pics::sig3(m.white_rad_sqrt_s)
        )
    };
    let _ = writeln!(
        s,
        "the wheels' yaw wander against the gyro: recording {}, simulation {}; variance difference z {:+.1} (critical {:.1}){}",
        one(&w.recording),
        one(&w.simulation),
        w.z,
        w.z_critical,
        if w.explains {
            "; the course against the wheels differs with it: the mend carries it"
        } else {
            ""
        }
    );
}

/// Where the speed channel parts over speed and acceleration, and whether
/// a named effect speaks for it.
fn render_speed_map(s: &mut String, m: &SpeedMapDifference) {
    let differing: Vec<_> = m.differing().collect();
    if differing.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "the speed channel over speed and acceleration ({} bins differ, Holm 5 %){}:",
        differing.len(),
        if m.unexplained {
            "; no effect named speaks for it: unexplained by the catalogue".to_string()
        } else if m.named_in_channel.is_empty() {
            String::new()
        } else {
            format!("; named in it: {}", m.named_in_channel.join(", "))
        }
    );
    for b in differing {
        let (what, unit) = if b.signal == "speed" {
            ("at", "m/s")
        } else {
            ("at a_x", "m/s^2 (against holding the speed)")
        };
        let _ = writeln!(
            s,
            "  - {what} {:.1} to {:.1} {unit}: the recording's wheels read {:+.2} % against the simulation's (sigma {:.2} %, z {:.1}; {} and {} rows)",
            b.lo,
            b.hi,
            -100.0 * b.difference,
            100.0 * b.sigma,
            b.z,
            b.rows[0],
            b.rows[1]
        );
    }
}
