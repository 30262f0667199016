//! Do the calibration's sigmas mean what they say (issue 26)? Over simulated
//! drives with no catalogue effects (the vehicle's own physics stay: the
//! driven axle's slip and the tyres' load make the effective circumference,
//! truth path over wheel turns, differ from the static one; both are
//! compared), the share of estimates whose true
//! error lies within 1, 2 and 3 of their own sigma, per parameter and per
//! GNSS noise level. A sigma that is honest covers about 68 / 95 / 99.7 %.
//!
//! `cargo bench -p calibrator --bench sigma_coverage [-- --seeds N]`

#[path = "common/mod.rs"]
mod common;

use calibrator::{calibrate, CalibrationConfig};
use simulator::{simulate, EffectSettings, Scenario, SimConfig, VehicleKind};
use std::collections::BTreeMap;
use vehicle_model::two_wheel::TwoWheelParams;

/// A GNSS of the kind a drive may have: white and Gauss-Markov sigma (m)
/// and the Gauss-Markov time constant (s).
const NOISE: [(&str, f64, f64, f64); 3] = [
    ("rtk (0.02 m white, 0.03 m GM 30 s)", 0.02, 0.03, 30.0),
    ("automotive (0.3 m white, 1 m GM 60 s)", 0.3, 1.0, 60.0),
    ("consumer (0.5 m white, 2.5 m GM 30 s)", 0.5, 2.5, 30.0),
];

/// Scenarios, each with the share of the seeds it runs (the 1 h `long`
/// drive a third of them).
const SCENARIOS: [(Scenario, u64); 3] = [
    (Scenario::Mixed, 1),
    (Scenario::Paper, 1),
    (Scenario::Long, 3),
];

#[derive(Default)]
struct Tally {
    z: Vec<f64>,
    missing: usize,
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seeds: u64 = args
        .iter()
        .position(|a| a == "--seeds")
        .and_then(|i| args.get(i + 1))
        .and_then(|s| s.parse().ok())
        .unwrap_or(9);
    let mut tallies: BTreeMap<(String, &str), Tally> = BTreeMap::new();
    let mut drives = 0;
    let mut floored_drives = 0usize;
    for (noise, white, gm, tau) in NOISE {
        for (scenario, share) in SCENARIOS {
            for seed in 1..=(seeds / share).max(1) {
                let mut cfg = SimConfig::new(scenario, seed);
                cfg.vehicle = VehicleKind::ALL[(seed as usize) % VehicleKind::ALL.len()];
                cfg.effects = EffectSettings::none();
                cfg.sensors.gnss.white_sigma_m = white;
                cfg.sensors.gnss.gm_sigma_m = gm;
                cfg.sensors.gnss.gm_tau_s = tau;
                let drive = match simulate(&cfg) {
                    Ok(d) => d,
                    Err(e) => {
                        println!("{noise} {scenario:?} seed {seed}: simulation failed: {e}");
                        continue;
                    }
                };
                let Some(truth) = drive.truth_params.clone() else {
                    println!("{noise} {scenario:?} seed {seed}: no truth");
                    continue;
                };
                let cal = match calibrate(&drive, &CalibrationConfig::default()) {
                    Ok(c) => c,
                    Err(e) => {
                        println!("{noise} {scenario:?} seed {seed}: calibration refused: {e}");
                        continue;
                    }
                };
                drives += 1;
                let tc = &truth.circumference_m;
                let c = &cal.circumference_m;
                let s = &cal.sigma_m;
                // The effective circumferences: what the wheels roll per
                // turn on this drive (the driven axle's slip and the tyres'
                // deflection make it differ from the static truth), the
                // quantity the data defines and the odometry needs.
                let eff = common::effective_scale(
                    &drive,
                    &TwoWheelParams {
                        c_rl: tc.rl,
                        c_rr: tc.rr,
                        track_width: truth.track_width_m,
                    },
                )
                .unwrap_or(f64::NAN);
                let mut rows: Vec<(&str, f64, Option<f64>)> = vec![
                    ("c_rl vs effective", c.rl - eff * tc.rl, s.rl),
                    ("c_rr vs effective", c.rr - eff * tc.rr, s.rr),
                    (
                        "(c_rl + c_rr) / 2 vs effective",
                        0.5 * (c.rl + c.rr - eff * (tc.rl + tc.rr)),
                        s.mean,
                    ),
                    ("c_rl", c.rl - tc.rl, s.rl),
                    ("c_rr", c.rr - tc.rr, s.rr),
                    ("c_rr - c_rl", (c.rr - c.rl) - (tc.rr - tc.rl), s.difference),
                    (
                        "(c_rl + c_rr) / 2",
                        0.5 * (c.rl + c.rr - tc.rl - tc.rr),
                        s.mean,
                    ),
                ];
                if cal.track_width_estimated {
                    rows.push((
                        "track width",
                        cal.track_width_m - truth.track_width_m,
                        cal.sigma_track_width_m,
                    ));
                }
                for (name, err, sigma) in rows {
                    let t = tallies.entry((noise.to_string(), name)).or_default();
                    match sigma.filter(|v| v.is_finite() && *v > 0.0) {
                        Some(sg) => t.z.push(err / sg),
                        None => t.missing += 1,
                    }
                }
                // The thirds' floor (fit::lm::thirds_floor) says so in the
                // basis (the 2W fit) or in the warning that takes the scale
                // from the wheel + gyro model.
                let floored = cal
                    .diagnostics
                    .sigma_basis
                    .as_ref()
                    .is_some_and(|b| b.method.contains("without each third"))
                    || cal
                        .warnings
                        .iter()
                        .any(|w| w.message.contains("without each third"));
                floored_drives += usize::from(floored);
                println!(
                    "{noise:<40} {:<6} seed {seed} {:<7} c_rl {:+.2} mm (sigma {:.2}), c_rr {:+.2} mm (sigma {:.2}){}{}",
                    format!("{scenario:?}"),
                    cfg.vehicle.name(),
                    1e3 * (c.rl - tc.rl),
                    1e3 * s.rl.unwrap_or(f64::NAN),
                    1e3 * (c.rr - tc.rr),
                    1e3 * s.rr.unwrap_or(f64::NAN),
                    if cal.track_width_estimated {
                        format!(
                            ", track {:+.1} mm (sigma {:.1})",
                            1e3 * (cal.track_width_m - truth.track_width_m),
                            1e3 * cal.sigma_track_width_m.unwrap_or(f64::NAN)
                        )
                    } else {
                        String::new()
                    },
                    if floored { " [sigmas floored by the thirds]" } else { "" }
                );
            }
        }
    }
    println!();
    println!("the thirds of the drive disagreed beyond the sigmas (floor applied) on {floored_drives} of {drives} drives");
    println!(
        "{drives} drives ({} seeds of mixed and paper, {} of long, x {} GNSS noise levels)",
        seeds,
        (seeds / 3).max(1),
        NOISE.len()
    );
    println!();
    println!("| GNSS | parameter | estimates | within 1 sigma | within 2 sigma | within 3 sigma | median abs(error / sigma) | no sigma |");
    println!("|---|---|---|---|---|---|---|---|");
    for ((noise, name), t) in &tallies {
        let n = t.z.len();
        let within =
            |k: f64| 100.0 * t.z.iter().filter(|z| z.abs() <= k).count() as f64 / n.max(1) as f64;
        let mut a: Vec<f64> = t.z.iter().map(|z| z.abs()).collect();
        a.sort_by(f64::total_cmp);
        let med = if a.is_empty() {
            f64::NAN
        } else {
            a[a.len() / 2]
        };
        println!(
            "| {noise} | {name} | {n} | {:.0} % | {:.0} % | {:.0} % | {med:.2} | {} |",
            within(1.0),
            within(2.0),
            within(3.0),
            t.missing
        );
    }
}
