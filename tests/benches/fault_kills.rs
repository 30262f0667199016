//! The fault suite, long: `cargo bench -p integration-tests --bench
//! fault_kills -- [--seeds N] [--first-seed S] [--odometry-kills K] [--calibrator-kills K]
//! [--speed F]`. Each seed simulates the paper's drive with a GNSS outage
//! over 45-75 % of it, replays it through the graph of real processes, and
//! kills the odometry and the calibrator at moments drawn from the seed
//! (see `integration_tests::faults`). Prints one line per seed and the
//! totals, for BENCHMARKS.md.

use integration_tests::faults::{run_faults, FaultConfig, AFTER_RESTART_S};
use simulator::Scenario;

fn arg<T: std::str::FromStr>(args: &[String], name: &str, default: T) -> T {
    args.iter()
        .position(|a| a == name)
        .and_then(|k| args.get(k + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seeds: u64 = arg(&args, "--seeds", 10);
    let odometry_kills: usize = arg(&args, "--odometry-kills", 4);
    let calibrator_kills: usize = arg(&args, "--calibrator-kills", 2);
    let speed: f64 = arg(&args, "--speed", 10.0);
    println!(
        "seed | kills odo/cal | back | poses | lost | after restart: judged, beyond 3 sigma, worst d (error m) | all: judged, beyond 3 sigma, worst d | versions | kept"
    );
    let mut totals = (
        0usize, 0usize, 0usize, 0u64, 0usize, 0usize, 0.0f64, 0usize, 0usize,
    );
    let mut all_kept = true;
    let mut killed_starting = 0usize;
    let first: u64 = arg(&args, "--first-seed", 1);
    for seed in first..first + seeds {
        let config = FaultConfig {
            seed,
            scenario: Scenario::Paper,
            odometry_kills,
            calibrator_kills,
            speed,
            outage: (0.45, 0.75),
        };
        let r = run_faults(&config);
        let back = format!(
            "{} (+{} killed while starting)",
            r.survived, r.killed_while_starting
        );
        println!(
            "{seed} | {}/{} | {} | {} | {} | {}, {}, {:.2} ({:.2} m) | {}, {}, {:.2} | {:?} | {}",
            r.kills.0,
            r.kills.1,
            back,
            r.poses,
            r.poses_lost,
            r.judged_after_restart,
            r.beyond_3_sigma_after_restart,
            r.worst_after_restart.0,
            r.worst_after_restart.1,
            r.judged,
            r.beyond_3_sigma,
            r.worst_mahalanobis,
            r.versions,
            r.estimates_kept
        );
        for line in &r.not_back {
            println!("    not back: {line}");
        }
        for (t, mode, e, sigma, d) in &r.first_poses {
            println!("    first pose after a restart: t = {t:.1} s, {mode:?}, error {e:.2} m, sigma {sigma:.2} m, Mahalanobis {d:.2}");
        }
        totals.0 += r.kills.0 + r.kills.1;
        totals.1 += r.survived;
        killed_starting += r.killed_while_starting;
        totals.2 += r.poses;
        totals.3 += r.poses_lost;
        totals.4 += r.judged_after_restart;
        totals.5 += r.beyond_3_sigma_after_restart;
        totals.6 = totals.6.max(r.worst_after_restart.0);
        totals.7 += r.judged;
        totals.8 += r.beyond_3_sigma;
        all_kept &= r.estimates_kept;
    }
    println!(
        "total: {} kills; {} restarts came back ({killed_starting} more were killed again while starting, before they could); {} poses, {} lost; in the {AFTER_RESTART_S} s after restarts {} poses judged, {} beyond their 3-sigma ellipse (worst Mahalanobis {:.2}); over the whole drives {} judged, {} beyond ({:.2} %); estimates kept: {all_kept}",
        totals.0,
        totals.1,
        totals.2,
        totals.3,
        totals.4,
        totals.5,
        totals.6,
        totals.7,
        totals.8,
        100.0 * totals.8 as f64 / totals.7.max(1) as f64
    );
}
