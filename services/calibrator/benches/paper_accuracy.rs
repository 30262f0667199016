//! The paper's experiment (section 5) on the simulator's `paper` scenario:
//! `cargo bench -p calibrator --bench paper_accuracy`.
//!
//! 10 noise seeds, 9 iterations, side-slip off and on, for
//! - `paper (faithful)`: eq. (3)-(11) with the nominal track width,
//! - `paper + track`: the same loop with the track width as a third
//!   parameter (the default track setting, `auto`),
//! - `batch`: the Levenberg-Marquardt fit (the library default).
//!
//! Reported per method: mean |c error| per wheel against the simulation's
//! true (static) circumferences, and against the *effective* ones (the true
//! circumferences scaled by truth path length / wheel distance, which takes
//! out the driven axle's longitudinal slip); mean dead-reckoning error of the
//! pure 2W model over the whole drive against truth.csv, with the estimate
//! and with the true circumferences and track of the simulation (the paper's
//! "optimal model"); and the paper's own measure, the mean deviation from
//! the reference at the kept iteration.

#[path = "common/mod.rs"]
mod common;

use calibrator::{calibrate, CalibrationConfig, Method, TrackWidthMode};
use simulator::{simulate, Scenario, SimConfig};
use std::time::Instant;
use vehicle_model::two_wheel::TwoWheelParams;

#[derive(Default, Clone)]
struct Acc {
    n: usize,
    err_rl: f64,
    err_rr: f64,
    eff_rl: f64,
    eff_rr: f64,
    dr: f64,
    dr_true: f64,
    dev_ref: f64,
    track: f64,
    seconds: f64,
    failures: usize,
}

fn main() -> anyhow::Result<()> {
    run(
        "simulator defaults: vehicle physics on (side-slip, load transfer, driven-axle slip)",
        &[],
    )?;
    println!();
    run(
        "vehicle physics off: the 2W model is exact, only sensor noise and quantisation remain",
        &[
            "side_slip=off",
            "load_transfer_radius=off",
            "longitudinal_slip=off",
        ],
    )
}

fn run(title: &str, effects_off: &[&str]) -> anyhow::Result<()> {
    let seeds: Vec<u64> = (1..=10).collect();
    let variants: [(&str, Method, TrackWidthMode); 3] = [
        ("paper (faithful)", Method::Paper, TrackWidthMode::Fixed),
        ("paper + track", Method::Paper, TrackWidthMode::Auto),
        ("batch", Method::Batch, TrackWidthMode::Auto),
    ];
    let mut acc = vec![Acc::default(); variants.len() * 2];
    let mut per_seed = Vec::new();
    for &seed in &seeds {
        let mut sim = SimConfig::new(Scenario::Paper, seed);
        for spec in effects_off {
            sim.effects.apply_spec(spec)?;
        }
        let drive = simulate(&sim)?;
        let truth = drive
            .truth_params
            .clone()
            .ok_or_else(|| anyhow::anyhow!("simulated drive without truth_params"))?;
        let tc = truth.circumference_m;
        let true_params = TwoWheelParams {
            c_rl: tc.rl,
            c_rr: tc.rr,
            track_width: truth.track_width_m,
        };
        let (dr_true, _) = common::dr_error_vs_truth(&drive, &true_params)
            .ok_or_else(|| anyhow::anyhow!("no truth to score against"))?;
        let eff = common::effective_scale(&drive, &true_params).unwrap_or(1.0);
        for (vi, (name, method, track)) in variants.iter().enumerate() {
            for (si, side_slip) in [false, true].into_iter().enumerate() {
                let config = CalibrationConfig {
                    method: *method,
                    track_width: *track,
                    side_slip,
                    iterations: 9,
                    ..CalibrationConfig::default()
                };
                let a = &mut acc[vi * 2 + si];
                let t0 = Instant::now();
                let cal = match calibrate(&drive, &config) {
                    Ok(c) => c,
                    Err(e) => {
                        eprintln!("seed {seed} {name} side-slip {side_slip}: {e}");
                        a.failures += 1;
                        continue;
                    }
                };
                a.seconds += t0.elapsed().as_secs_f64();
                let c = cal.circumference_m;
                let est = TwoWheelParams {
                    c_rl: c.rl,
                    c_rr: c.rr,
                    track_width: cal.track_width_m,
                };
                let (dr, _) =
                    common::dr_error_vs_truth(&drive, &est).unwrap_or((f64::NAN, f64::NAN));
                let kept = cal
                    .iterations
                    .iter()
                    .find(|i| i.n == cal.selected_iteration)
                    .map_or(f64::NAN, |i| i.dr_error_mean_m);
                a.n += 1;
                a.err_rl += (c.rl - tc.rl).abs();
                a.err_rr += (c.rr - tc.rr).abs();
                a.eff_rl += (c.rl - tc.rl * eff).abs();
                a.eff_rr += (c.rr - tc.rr * eff).abs();
                a.dr += dr;
                a.dr_true += dr_true;
                a.dev_ref += kept;
                a.track += cal.track_width_m;
                per_seed.push(format!(
                    "| {seed} | {name} | {} | {:+.2} | {:+.2} | {:.4} | {:.2} | {:.2} | {} |",
                    if side_slip { "on" } else { "off" },
                    1000.0 * (c.rl - tc.rl),
                    1000.0 * (c.rr - tc.rr),
                    cal.track_width_m,
                    dr,
                    dr_true,
                    cal.selected_iteration
                ));
            }
        }
    }
    println!(
        "### Paper scenario, {} seeds, 9 iterations; {title}",
        seeds.len()
    );
    println!();
    println!("| method | side-slip | mean abs c error RL / RR (static truth) | vs effective c RL / RR | mean track | DR error, estimate | DR error, true c and track | ratio | deviation from reference (kept iteration) | time per run | failures |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for (vi, (name, _, _)) in variants.iter().enumerate() {
        for si in 0..2 {
            let a = &acc[vi * 2 + si];
            let n = a.n.max(1) as f64;
            println!(
                "| {name} | {} | {:.2} / {:.2} mm | {:.2} / {:.2} mm | {:.4} m | {:.2} m | {:.2} m | {:.2} | {:.2} m | {:.0} ms | {} |",
                if si == 1 { "on" } else { "off" },
                1000.0 * a.err_rl / n,
                1000.0 * a.err_rr / n,
                1000.0 * a.eff_rl / n,
                1000.0 * a.eff_rr / n,
                a.track / n,
                a.dr / n,
                a.dr_true / n,
                a.dr / a.dr_true,
                a.dev_ref / n,
                1000.0 * a.seconds / n,
                a.failures
            );
        }
    }
    if std::env::var_os("PER_SEED").is_some() {
        println!();
        println!("| seed | method | side-slip | c_RL error mm | c_RR error mm | track m | DR error m | DR true m | kept iteration |");
        println!("|---|---|---|---|---|---|---|---|---|");
        for line in per_seed {
            println!("{line}");
        }
    }
    Ok(())
}
