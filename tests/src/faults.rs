//! The fault suite: the graph of real processes (`sensor-bridge replay`,
//! `calibrator serve --state`, `odometry serve --pose-state`) on a simulated
//! drive with a GNSS outage, with the calibrator and the odometry killed
//! (SIGKILL) at moments drawn from a fixed seed and started again at once.
//!
//! What it measures ([`FaultReport`]):
//! - whether every restarted service came back (published poses again, or
//!   took up its persisted estimate);
//! - the poses lost on the bus (gaps in a publisher's sequence numbers);
//! - every published pose with a position against the simulator's truth:
//!   its Mahalanobis distance in its own position covariance (3 = on its
//!   3-sigma ellipse), worst and count beyond 3, over the whole drive and in
//!   the first [`AFTER_RESTART_S`] of drive time after each restart. A
//!   consistent filter has 1.1 % of its poses beyond (exp(-9/2), two
//!   degrees of freedom): zero over thousands of poses would mean sigmas
//!   too large, not a better filter;
//! - that nothing accepted is lost: the estimate versions on the bus never
//!   go back, and every restarted calibrator starts from the newest version
//!   published before its kill.
//!
//! `tests/tests/fault_kills.rs` runs it short in CI; `cargo bench -p
//! integration-tests --bench fault_kills` runs it over several seeds.

use crate::graph::{Bin, Graph, ProcId};
use interfaces::bus::TopicSubscriber;
use interfaces::drive::{Drive, TruthSample};
use interfaces::wire::{CircumferenceEstimate, Pose, PoseMode};
use simulator::{simulate, Scenario, SimConfig};
use std::time::{Duration, Instant};

/// Drive time after a restart over which its poses are judged, s.
pub const AFTER_RESTART_S: f64 = 10.0;

/// One run of the suite.
#[derive(Debug, Clone, Copy)]
pub struct FaultConfig {
    /// Seed of the drive's noise and of the kill moments.
    pub seed: u64,
    /// The simulated route.
    pub scenario: Scenario,
    /// Kills of the odometry.
    pub odometry_kills: usize,
    /// Kills of the calibrator.
    pub calibrator_kills: usize,
    /// Replay speed, times real time.
    pub speed: f64,
    /// GNSS removed over this share of the drive (start, end fractions).
    pub outage: (f64, f64),
}

/// What one run measured.
#[derive(Debug, Clone, Default)]
pub struct FaultReport {
    /// Drive length, s.
    pub drive_s: f64,
    /// Kills done (odometry, calibrator).
    pub kills: (usize, usize),
    /// Restarted services that came back.
    pub survived: usize,
    /// Restarted services killed again before they were up (not judged).
    pub killed_while_starting: usize,
    /// Poses received.
    pub poses: usize,
    /// Poses lost on the bus (sequence gaps within a publisher).
    pub poses_lost: u64,
    /// Poses with a position judged against the truth.
    pub judged: usize,
    /// Of them, beyond their 3-sigma ellipse.
    pub beyond_3_sigma: usize,
    /// Worst Mahalanobis distance of any pose.
    pub worst_mahalanobis: f64,
    /// Poses with a position within [`AFTER_RESTART_S`] of a restart.
    pub judged_after_restart: usize,
    /// Of them, beyond their 3-sigma ellipse.
    pub beyond_3_sigma_after_restart: usize,
    /// Worst Mahalanobis distance among them, and that pose's error, m.
    pub worst_after_restart: (f64, f64),
    /// The first pose of each restarted odometry: (drive time, mode,
    /// position error m, position 1-sigma m, Mahalanobis distance; 0 for
    /// a `NoFix` pose, which claims nothing).
    pub first_poses: Vec<(f64, PoseMode, f64, f64, f64)>,
    /// Estimate versions on the bus never went back and each restarted
    /// calibrator started from the newest one published before its kill.
    pub estimates_kept: bool,
    /// The estimate versions seen, in order (repeats removed).
    pub versions: Vec<u64>,
    /// Restarted services that did not come back, with their log's end.
    pub not_back: Vec<String>,
}

/// A small deterministic generator for the kill moments (SplitMix64).
struct Rng(u64);

impl Rng {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Target {
    Odometry,
    Calibrator,
}

/// The drive of a run: the scenario's simulation with GNSS removed over
/// the outage.
pub fn fault_drive(config: &FaultConfig) -> Drive {
    let mut drive = simulate(&SimConfig::new(config.scenario, config.seed)).expect("drive");
    let t0 = drive.wheels.samples.first().expect("wheels").t_s;
    let t1 = drive.wheels.samples.last().expect("wheels").t_s;
    let (a, b) = (
        t0 + config.outage.0 * (t1 - t0),
        t0 + config.outage.1 * (t1 - t0),
    );
    if let Some(g) = drive.gnss.as_mut() {
        g.retain(|f| f.t_s < a || f.t_s > b);
    }
    drive
}

/// Run the suite once (see the module docs).
pub fn run_faults(config: &FaultConfig) -> FaultReport {
    let mut g = Graph::new(&format!("fault{}", config.seed));
    let drive = fault_drive(config);
    let folder = g.path("drive");
    drive_io::write_drive(&drive, &folder).expect("write drive");
    let folder = folder.to_str().expect("utf-8").to_string();
    let vehicle = format!("{folder}/vehicle.toml");
    let state = g.path("state.json").to_str().expect("utf-8").to_string();
    let kept = g.path("pose.json").to_str().expect("utf-8").to_string();
    // Short thresholds, so that the calibrator publishes (and persists)
    // estimates within the drive and a kill can fall on one.
    let cal_args = [
        "serve",
        "--vehicle",
        &vehicle,
        "--state",
        &state,
        "--min-distance",
        "300",
        "--min-turn",
        "90",
        "--recalibrate-distance",
        "200",
        "--holdout-window",
        "5",
    ];
    let odo_args = ["serve", "--vehicle", &vehicle, "--pose-state", &kept];

    let bus = g.bus("fault-test");
    let poses_sub: TopicSubscriber<Pose> = bus.subscriber().expect("pose subscriber");
    let estimates_sub: TopicSubscriber<CircumferenceEstimate> =
        bus.subscriber().expect("estimate subscriber");
    let mut cal = g.spawn("calibrator", Bin::Calibrator, &cal_args);
    g.wait_log(cal, "no accepted estimate yet");
    let mut odo = g.spawn("odometry", Bin::Odometry, &odo_args);
    g.wait_log(odo, "serving poses");

    let t0 = drive.wheels.samples.first().expect("wheels").t_s;
    let t1 = drive.wheels.samples.last().expect("wheels").t_s;
    let replay_wall = (t1 - t0) / config.speed;
    let mut rng = Rng(config.seed ^ 0x5EED_FA17);
    let mut kills: Vec<(f64, Target)> = (0..config.odometry_kills)
        .map(|_| Target::Odometry)
        .chain((0..config.calibrator_kills).map(|_| Target::Calibrator))
        .map(|target| ((0.1 + 0.8 * rng.next_f64()) * replay_wall, target))
        .collect();
    kills.sort_by(|a, b| a.0.total_cmp(&b.0));

    let speed = format!("{}", config.speed);
    let replay = g.spawn(
        "replay",
        Bin::SensorBridge,
        &[
            "replay",
            &folder,
            "--speed",
            &speed,
            "--wait-subscribers",
            "2",
            "--linger",
            "0.5",
        ],
    );
    // Poses tagged with their publisher (one per odometry process).
    let mut poses: Vec<(Pose, u128)> = Vec::new();
    let mut versions: Vec<u64> = Vec::new();
    let drain_all = |poses: &mut Vec<(Pose, u128)>, versions: &mut Vec<u64>| {
        while let Ok(Some(p)) = poses_sub.receive_with_publisher() {
            poses.push(p);
        }
        while let Ok(Some(e)) = estimates_sub.receive() {
            if versions.last() != Some(&e.version) {
                versions.push(e.version);
            }
        }
    };
    let start = Instant::now();
    let mut report = FaultReport {
        drive_s: t1 - t0,
        estimates_kept: true,
        ..FaultReport::default()
    };
    // (drive time of the last pose before the kill) per odometry restart.
    let mut restarts_at: Vec<f64> = Vec::new();
    let mut restarted: Vec<(ProcId, Target)> = Vec::new();
    for (at, target) in &kills {
        while start.elapsed().as_secs_f64() < *at && g.is_running(replay) {
            drain_all(&mut poses, &mut versions);
            std::thread::sleep(Duration::from_millis(5));
        }
        if !g.is_running(replay) {
            break;
        }
        drain_all(&mut poses, &mut versions);
        let pause = Duration::from_millis(50 + (450.0 * rng.next_f64()) as u64);
        match target {
            Target::Odometry => {
                if !g.log(odo).contains("serving poses") {
                    // Killed again before it was up: judged as a kill, not
                    // as a restart that failed.
                    restarted.retain(|(id, _)| *id != odo);
                    report.killed_while_starting += 1;
                }
                g.kill(odo);
                report.kills.0 += 1;
                restarts_at.push(poses.last().map_or(t0, |(p, _)| p.header.t_s()));
                std::thread::sleep(pause);
                odo = g.spawn(
                    &format!("odometry-{}", report.kills.0 + 1),
                    Bin::Odometry,
                    &odo_args,
                );
                restarted.push((odo, Target::Odometry));
            }
            Target::Calibrator => {
                if !g.log(cal).contains("estimate") {
                    restarted.retain(|(id, _)| *id != cal);
                    report.killed_while_starting += 1;
                }
                g.kill(cal);
                report.kills.1 += 1;
                let newest = versions.iter().copied().max();
                std::thread::sleep(pause);
                cal = g.spawn(
                    &format!("calibrator-{}", report.kills.1 + 1),
                    Bin::Calibrator,
                    &cal_args,
                );
                let deadline = Instant::now() + crate::graph::WATCHDOG;
                let mut log = g.log(cal);
                while !(log.contains("starting from the persisted estimate")
                    || log.contains("no accepted estimate yet"))
                {
                    assert!(
                        Instant::now() < deadline && g.is_running(cal),
                        "the restarted calibrator did not start:\n{log}"
                    );
                    drain_all(&mut poses, &mut versions);
                    std::thread::sleep(Duration::from_millis(10));
                    log = g.log(cal);
                }
                let started_from = log
                    .split("starting from the persisted estimate v")
                    .nth(1)
                    .and_then(|r| r.split_whitespace().next())
                    .and_then(|v| v.parse::<u64>().ok());
                if started_from < newest {
                    report.estimates_kept = false;
                }
                restarted.push((cal, Target::Calibrator));
            }
        }
    }
    let status = g.wait_exit_with(replay, || drain_all(&mut poses, &mut versions));
    assert!(status.success(), "replay failed:\n{}", g.log(replay));
    let last_ns = interfaces::wire::seconds_to_ns(t1);
    let deadline = Instant::now() + Duration::from_secs(30);
    while Instant::now() < deadline && poses.last().is_none_or(|(p, _)| p.header.t_ns < last_ns) {
        drain_all(&mut poses, &mut versions);
        std::thread::sleep(Duration::from_millis(10));
    }
    eprintln!(
        "fault suite: replay done at {:.1} s wall, last pose at t = {:.2} s (drive ends {t1:.2} s)",
        start.elapsed().as_secs_f64(),
        poses.last().map_or(f64::NAN, |(p, _)| p.header.t_s())
    );
    for (k, (id, target)) in restarted.iter().enumerate() {
        // An instance killed later counts as back if it started serving;
        // the last one of each service must still run.
        let newest = !restarted[k + 1..].iter().any(|(_, t)| t == target);
        let back = (!newest || g.is_running(*id))
            && match target {
                Target::Odometry => g.log(*id).contains("serving poses"),
                Target::Calibrator => {
                    let log = g.log(*id);
                    log.contains("starting from the persisted estimate")
                        || log.contains("no accepted estimate yet")
                }
            };
        report.survived += usize::from(back);
        if !back {
            let log = g.log(*id);
            let tail: Vec<&str> = log.lines().rev().take(6).collect();
            report.not_back.push(format!(
                "{target:?} restart {k}: {}",
                tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
            ));
        }
    }
    if std::env::var_os("FAULT_LOGS").is_some() {
        eprintln!("--- calibrator ---\n{}", g.log(cal));
        eprintln!("--- odometry ---\n{}", g.log(odo));
    }
    report.estimates_kept &= versions.windows(2).all(|w| w[1] >= w[0]);
    report.versions = versions;
    report.poses = poses.len();
    report.poses_lost = poses_sub.lost();
    judge(&mut report, &drive, &poses, &restarts_at);
    report
}

/// Mahalanobis distance of a pose's position error in its covariance.
fn mahalanobis(p: &Pose, e: [f64; 2]) -> f64 {
    let (a, b, c, d) = (
        p.covariance[0],
        p.covariance[1],
        p.covariance[3],
        p.covariance[4],
    );
    let det = a * d - b * c;
    if det.is_nan() || det <= 0.0 {
        return f64::INFINITY;
    }
    let q = (d * e[0] * e[0] - (b + c) * e[0] * e[1] + a * e[1] * e[1]) / det;
    q.max(0.0).sqrt()
}

fn judge(report: &mut FaultReport, drive: &Drive, poses: &[(Pose, u128)], restarts: &[f64]) {
    let truth: &[TruthSample] = drive.truth.as_deref().expect("simulated truth");
    let at = |t: f64| wheelcal_demo::report::truth_at(truth, t);
    let mut previous_publisher = None;
    for (p, publisher) in poses {
        let t = p.header.t_s();
        if previous_publisher.is_some() && previous_publisher != Some(*publisher) {
            let (x, y) = at(t).unwrap_or((f64::NAN, f64::NAN));
            let mode = PoseMode::from_code(p.mode).unwrap_or(PoseMode::NoFix);
            let d = if mode == PoseMode::NoFix {
                0.0
            } else {
                mahalanobis(p, [p.x_m - x, p.y_m - y])
            };
            report.first_poses.push((
                t,
                mode,
                (p.x_m - x).hypot(p.y_m - y),
                p.covariance[0].max(p.covariance[4]).sqrt(),
                d,
            ));
        }
        previous_publisher = Some(*publisher);
        if p.mode == PoseMode::NoFix as u8 {
            continue;
        }
        let Some((x, y)) = at(t) else {
            continue;
        };
        let e = [p.x_m - x, p.y_m - y];
        let d = mahalanobis(p, e);
        report.judged += 1;
        report.beyond_3_sigma += usize::from(d > 3.0);
        report.worst_mahalanobis = report.worst_mahalanobis.max(d);
        let after_restart = restarts.iter().any(|&k| t > k && t <= k + AFTER_RESTART_S);
        if after_restart {
            report.judged_after_restart += 1;
            report.beyond_3_sigma_after_restart += usize::from(d > 3.0);
            if d > report.worst_after_restart.0 {
                report.worst_after_restart = (d, e[0].hypot(e[1]));
            }
        }
    }
}
