//! Speed of the calibration: `cargo bench -p calibrator --bench speed`.
//!
//! The simulator's `long` scenario (the mixed city/highway loop driven round
//! and round, 100 Hz wheels, 100 Hz IMU, 10 Hz GNSS) for 10 min, 1 h and
//! 4 h; for each: the wall time of `calibrate` (median of a few runs, one
//! thread) for the paper method (9 iterations) and the batch method, and the
//! peak resident memory. The drive is simulated first; its `truth.csv` rows
//! are dropped before calibrating (the calibration never reads them and a
//! recorded drive has none), so the memory figures are those of a user's
//! drive in memory plus the calibration.
//!
//! Run one size alone (a fresh process, so VmHWM is that size's peak):
//! `cargo bench -p calibrator --bench speed -- 3600`.

#[path = "common/mod.rs"]
mod common;

use calibrator::{calibrate, CalibrationConfig, Method};
use simulator::{simulate, Scenario, SimConfig};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let sizes: Vec<f64> = if args.is_empty() {
        vec![600.0, 3600.0, 14400.0]
    } else {
        args.iter().filter_map(|a| a.parse().ok()).collect()
    };
    if sizes.len() > 1 {
        // Each size in its own process, so that the peak memory is its own.
        let exe = std::env::current_exe().expect("bench executable");
        println!("| drive | wheel samples | method | time (median of 3) | ms per drive-minute | peak RSS before / after calibrate (drive resident) |");
        println!("|---|---|---|---|---|---|");
        for s in sizes {
            let out = std::process::Command::new(&exe)
                .arg(s.to_string())
                .output()
                .expect("run bench child");
            print!("{}", String::from_utf8_lossy(&out.stdout));
            eprint!("{}", String::from_utf8_lossy(&out.stderr));
        }
        return;
    }
    let duration = sizes[0];
    let mut sim = SimConfig::new(Scenario::Long, 7);
    sim.duration_s = Some(duration);
    let mut drive = simulate(&sim).expect("simulate");
    drive.truth = None;
    let n = drive.wheels.samples.len();
    let before = common::peak_memory_mb().unwrap_or(f64::NAN);
    let resident = common::resident_memory_mb().unwrap_or(f64::NAN);
    eprintln!("  drive in memory: resident {resident:.0} MB (simulator peak {before:.0} MB)");
    for method in [Method::Paper, Method::Batch] {
        let config = CalibrationConfig {
            method,
            iterations: 9,
            ..CalibrationConfig::default()
        };
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..3 {
            let t0 = Instant::now();
            let cal = calibrate(&drive, &config).expect("calibrate");
            times.push(t0.elapsed().as_secs_f64());
            last = Some(cal);
        }
        times.sort_by(f64::total_cmp);
        let after = common::peak_memory_mb().unwrap_or(f64::NAN);
        let cal = last.expect("ran");
        println!(
            "| {:.0} min | {} | {} | {:.3} s | {:.1} | {:.0} MB / {:.0} MB ({:.0} MB) |",
            duration / 60.0,
            n,
            method,
            times[1],
            1000.0 * times[1] / (duration / 60.0),
            before,
            after,
            resident
        );
        eprintln!(
            "  ({} {:.0} min: c_RL {:.5} c_RR {:.5} track {:.4}, {} warnings)",
            method,
            duration / 60.0,
            cal.circumference_m.rl,
            cal.circumference_m.rr,
            cal.track_width_m,
            cal.warnings.len()
        );
    }
}
