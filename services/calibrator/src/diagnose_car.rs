//! `calibrator diagnose DRIVE DRIVE...`: several drives of one car, each
//! diagnosed on its own and the car's effects over all of them together;
//! the text, the JSON and the pages. One drive goes to [`crate::diagnose_cmd`].

use crate::diagnose_cmd::DiagnoseArgs;
use crate::diagnose_cmd::{config, read_drive, reading_warnings, render_text, write_pictures};
use anyhow::{Context, Result};
use calibrator::diagnose::pool::{CarVerdict, PooledLimit};
use calibrator::diagnose::{diagnose_drives, DrivesDiagnosis};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Run `calibrator diagnose`: one drive, or several of one car.
pub fn run_diagnose(args: &DiagnoseArgs) -> Result<()> {
    let paths = drive_paths(&args.drives)?;
    if let [one] = paths.as_slice() {
        crate::diagnose_cmd::run_one(args, one)
    } else {
        run(args, &paths)
    }
}

/// The drives `paths` name: as given, or, for one folder that is not a
/// drive (no `vehicle.toml`) but holds drive folders, those, sorted.
pub fn drive_paths(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let [one] = paths else {
        return Ok(paths.to_vec());
    };
    if !one.is_dir() || one.join("vehicle.toml").exists() || one.join("metadata.yaml").exists() {
        return Ok(paths.to_vec());
    }
    let mut drives: Vec<PathBuf> = std::fs::read_dir(one)
        .with_context(|| format!("cannot list {}", one.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("vehicle.toml").exists())
        .collect();
    drives.sort();
    anyhow::ensure!(
        !drives.is_empty(),
        "{}: neither a drive folder (no vehicle.toml) nor a folder of drive folders",
        one.display()
    );
    Ok(drives)
}

/// What `--json` writes: the drives' paths beside the diagnosis.
#[derive(Serialize)]
struct Written<'a> {
    paths: Vec<String>,
    #[serde(flatten)]
    diagnosis: &'a DrivesDiagnosis,
}

/// Diagnose several drives of one car.
pub fn run(args: &DiagnoseArgs, paths: &[PathBuf]) -> Result<()> {
    let cfg = config(args)?;
    let mut drives = Vec::new();
    let mut warnings = Vec::new();
    for p in paths {
        let loaded = read_drive(args, p)?;
        drives.push(loaded.drive);
        warnings.push(loaded.warnings);
    }
    let mut d = diagnose_drives(&drives, &cfg).map_err(|e| match &e {
        calibrator::diagnose::DiagnoseError::Drive { index, .. } => {
            anyhow::anyhow!("cannot diagnose {}: {e}", paths[*index].display())
        }
        _ => anyhow::anyhow!("cannot diagnose the drives: {e}"),
    })?;
    for (one, w) in d.drives.iter_mut().zip(&warnings) {
        one.warnings.extend(reading_warnings(w));
    }
    let names: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
    for (one, name) in d.drives.iter().zip(&names) {
        println!("== {name} ==");
        print!("{}", render_text(one));
        println!();
    }
    print!("{}", car_text(&d, &names));
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&Written {
            paths: names.clone(),
            diagnosis: &d,
        })
        .context("cannot encode the diagnosis")?;
        std::fs::write(path, text + "\n")
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    if let Some(dir) = &args.plots {
        write_pages(dir, &d, &names)?;
    }
    Ok(())
}

/// The car's effects over the drives, as text.
pub fn car_text(d: &DrivesDiagnosis, names: &[String]) -> String {
    let mut s = String::new();
    let Some(car) = &d.car else {
        let _ = writeln!(
            s,
            "the car over {} drives: not known ({})",
            d.drives.len(),
            d.car_missing.as_deref().unwrap_or("no information")
        );
        return s;
    };
    let _ = writeln!(
        s,
        "the car over {} drives ({} segments; Holm's procedure at a family-wise {:.0} %, \
         Bonferroni's |z| {:.1}):",
        car.drives,
        car.segments,
        100.0 * car.family_alpha,
        car.z_critical
    );
    for line in car_rows(car, d, names) {
        let _ = writeln!(s, "  {line}");
    }
    for why in &d.left_out {
        let _ = writeln!(s, "  left out: {why}");
    }
    s
}

/// One line per car effect: verdict, estimate and sigma, Wald z with
/// Holm's critical value, the smallest size the drives together show, and
/// each drive's share of the information.
fn car_rows(car: &PooledLimit, d: &DrivesDiagnosis, names: &[String]) -> Vec<String> {
    car.effects
        .iter()
        .map(|p| {
            let l = &p.limit;
            let test = car.wald.iter().find(|t| t.effect == l.effect);
            let (est, sig) = l.shown_fit();
            let shares: Vec<String> = p
                .information_share
                .iter()
                .zip(&p.per_drive)
                .zip(&d.pooled)
                .map(|((share, own), &i)| {
                    let name = names.get(i).map_or("?", |n| short(n));
                    match own {
                        Some([e, s]) => format!("{name} {:.0} % ({e:.2e} ± {s:.1e})", 100.0 * share),
                        None => format!("{name} {:.0} %", 100.0 * share),
                    }
                })
                .collect();
            let partners = l.joint.as_ref().map_or(&[][..], |j| &j.partners[..]);
            let ambiguity = if p.verdict == CarVerdict::Ambiguous {
                format!(
                    "; shown alone (z {:+.1}) but not told from {} (separate by: {})",
                    l.wald_z.unwrap_or(f64::NAN),
                    partners
                        .iter()
                        .map(|q| q.effect.to_string())
                        .collect::<Vec<_>>()
                        .join(", "),
                    partners
                        .iter()
                        .map(|q| l.effect.separate_from(q.effect))
                        .collect::<Vec<_>>()
                        .join("; ")
                )
            } else {
                String::new()
            };
            format!(
                "{:<22} {:<12} {} = {} ± {} {}; z {} (Holm {}); shows from {}{}; information (own estimate): {}{ambiguity}",
                l.effect.to_string(),
                match p.verdict {
                    CarVerdict::Found => "FOUND",
                    CarVerdict::NotShown => "not shown",
                    CarVerdict::Implausible => "implausible",
                    CarVerdict::Inconsistent => "inconsistent",
                    CarVerdict::Ambiguous => "ambiguous",
                    CarVerdict::Guarded => "guarded",
                },
                l.estimate_of,
                num(est),
                num(sig),
                l.unit,
                test.map_or("-".into(), |t| format!("{:+.1}", t.z)),
                test.map_or("-".into(), |t| format!("{:.1}", t.z_critical)),
                l.shown_smallest()
                    .map_or("-".into(), |v| format!("{} {}", num(Some(v)), l.unit)),
                l.power_at_typical
                    .map_or(String::new(), |p| format!(", a typical one with probability {p:.2}")),
                shares.join(", ")
            )
        })
        .collect()
}

/// A number for the table, or a dash.
fn num(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.2e}"))
}

/// The last component of a path.
fn short(path: &str) -> &str {
    Path::new(path)
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or(path)
}

/// Each drive's pages in a folder of its own, and an index page with the
/// car's table linking to them.
fn write_pages(dir: &Path, d: &DrivesDiagnosis, names: &[String]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut links = Vec::new();
    for (i, (one, name)) in d.drives.iter().zip(names).enumerate() {
        let sub = format!("drive-{}", i + 1);
        write_pictures(&dir.join(&sub), one)?;
        links.push((sub, name.clone()));
    }
    let index = dir.join("index.html");
    let short_names: Vec<String> = names.iter().map(|n| short(n).to_string()).collect();
    let html = calibrator::diagnose::pool_pictures::car_html(d, &short_names, &links)
        .context("cannot draw the car's pictures")?;
    std::fs::write(&index, html).with_context(|| format!("cannot write {}", index.display()))?;
    println!("wrote {}", index.display());
    Ok(())
}
