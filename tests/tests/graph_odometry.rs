//! The whole process graph: `sensor-bridge replay`, `calibrator serve` and
//! `odometry serve` as real processes over iceoryx2, each test in its own
//! prefix and root path, every child killed and reaped by the [`Graph`] guard.

use drive_io::write_drive;
use integration_tests::graph::{drain, wait_until, Bin, Graph, ProcId};
use interfaces::bus::{Bus, TopicSubscriber};
use interfaces::drive::Drive;
use interfaces::wire::{Pose, PoseMode};
use simulator::{simulate, Scenario, SimConfig};
use std::path::Path;
use std::time::{Duration, Instant};
use wheelcal_demo::default_drive;
use wheelcal_demo::report::truth_at;

/// The nominal circumferences are expected to be worse than the calibrated
/// ones through the outage by at least this factor (observed: far more).
const OUTAGE_FACTOR: f64 = 5.0;

fn s(p: &Path) -> String {
    p.to_str().expect("utf-8 path").to_string()
}

fn write(g: &Graph, drive: &Drive, name: &str) -> String {
    let dir = g.path(name);
    write_drive(drive, &dir).expect("write drive");
    s(&dir)
}

fn odometry(g: &mut Graph, label: &str, drive: &str, extra: &[&str]) -> ProcId {
    let vehicle = format!("{drive}/vehicle.toml");
    let mut args = vec!["serve", "--vehicle", &vehicle];
    args.extend_from_slice(extra);
    g.spawn(label, Bin::Odometry, &args)
}

fn replay_max(g: &mut Graph, drive: &str, subscribers: &str) -> ProcId {
    replay_max_with(g, drive, subscribers, &[])
}

fn replay_max_with(g: &mut Graph, drive: &str, subscribers: &str, extra: &[&str]) -> ProcId {
    let mut args = vec![
        "replay",
        drive,
        "--max",
        "--wait-subscribers",
        subscribers,
        "--linger",
        "0.5",
    ];
    args.extend_from_slice(extra);
    g.spawn("replay", Bin::SensorBridge, &args)
}

/// Run `replay` to its end while collecting poses; then wait until the pose
/// of the last wheel sample arrived.
fn collect(
    g: &mut Graph,
    replay: ProcId,
    sub: &TopicSubscriber<Pose>,
    last_t_ns: i64,
) -> Vec<Pose> {
    let mut poses = Vec::new();
    let status = g.wait_exit_with(replay, || {
        drain(sub, &mut poses);
    });
    assert!(status.success(), "replay failed:\n{}", g.log(replay));
    wait_until("the pose of the last wheel sample", || {
        drain(sub, &mut poses);
        poses.last().is_some_and(|p| p.header.t_ns >= last_t_ns)
    });
    poses
}

fn last_wheel_t_ns(drive: &Drive) -> i64 {
    let t = drive.wheels.samples.last().expect("wheels").t_s;
    interfaces::wire::seconds_to_ns(t)
}

/// Position error of the last pose inside the outage and the largest inside it.
fn outage_errors(drive: &Drive, poses: &[Pose], outage: (f64, f64)) -> (f64, f64) {
    let truth = drive.truth.as_deref().expect("truth");
    let inside: Vec<f64> = poses
        .iter()
        .filter(|p| p.header.t_s() > outage.0 && p.header.t_s() <= outage.1)
        .filter_map(|p| truth_at(truth, p.header.t_s()).map(|(x, y)| (p.x_m - x).hypot(p.y_m - y)))
        .collect();
    assert!(
        inside.len() > 100,
        "poses inside the outage: {}",
        inside.len()
    );
    (
        *inside.last().expect("poses"),
        inside.iter().cloned().fold(0.0, f64::max),
    )
}

fn seeded_state(path: &Path, version: u64) {
    integration_tests::graph::seeded_calibrator_state(path, version);
}

/// An estimate is published by the calibrator and taken by the odometry; with
/// it the error through a long GNSS outage is lower than with the nominal
/// circumferences by at least [`OUTAGE_FACTOR`].
#[test]
fn estimate_is_picked_up_and_beats_nominal_through_a_gnss_outage() {
    let mut g = Graph::new("pick");
    let (drive, outage) = default_drive(1, 2.2, 90.0).expect("drive");
    let calib_drive = {
        let mut c = SimConfig::new(Scenario::Mixed, 1);
        c.nominal_circumference_m = Some(2.2);
        simulate(&c).expect("calibration drive")
    };
    let calib = write(&g, &calib_drive, "calibration-drive");
    let outage_drive = write(&g, &drive, "outage-drive");
    let state = s(&g.path("state.json"));
    let vehicle = format!("{calib}/vehicle.toml");

    // Phase 1: the calibrator learns from a drive with GNSS.
    let cal = g.spawn(
        "calibrator",
        Bin::Calibrator,
        &["serve", "--vehicle", &vehicle, "--state", &state],
    );
    g.wait_log(cal, "no accepted estimate yet");
    let replay = replay_max(&mut g, &calib, "1");
    assert!(g.wait_exit(replay).success(), "{}", g.log(replay));
    g.wait_log(cal, "PUBLISHED estimate v1");
    g.terminate(cal);
    assert!(g.wait_exit(cal).success());
    let accepted: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&state).expect("state")).expect("json");
    let accepted_version = accepted["version"]
        .as_u64()
        .expect("version in the state file");

    // Phase 2: the calibrator serves what it learnt (and learns no more); the
    // odometry picks it up and crosses the outage with it.
    let cal = g.spawn(
        "calibrator-2",
        Bin::Calibrator,
        &[
            "serve",
            "--vehicle",
            &vehicle,
            "--state",
            &state,
            "--min-distance",
            "1e9",
        ],
    );
    g.wait_log(cal, "starting from the persisted estimate");
    let bus: Bus = g.bus("test");
    let sub = bus.subscriber::<Pose>().expect("pose subscriber");
    let odo = odometry(&mut g, "odometry", &outage_drive, &[]);
    g.wait_log(
        odo,
        &format!("switching estimate v0 -> v{accepted_version}"),
    );
    let replay = replay_max(&mut g, &outage_drive, "2");
    let poses = collect(&mut g, replay, &sub, last_wheel_t_ns(&drive));
    assert_eq!(sub.lost(), 0, "poses lost");
    assert!(poses.iter().all(|p| p.estimate_version == accepted_version));
    let calibrated = outage_errors(&drive, &poses, outage);
    g.terminate(odo);
    assert!(g.wait_exit(odo).success());

    // Phase 3: the same outage with the nominal values.
    let odo = odometry(
        &mut g,
        "odometry-nominal",
        &outage_drive,
        &["--no-bus-estimate"],
    );
    g.wait_log(odo, "odometry");
    let mut poses = Vec::new();
    drain(&sub, &mut poses);
    let replay = replay_max(&mut g, &outage_drive, "2");
    let nominal_poses = collect(&mut g, replay, &sub, last_wheel_t_ns(&drive));
    assert!(nominal_poses.iter().all(|p| p.estimate_version == 0));
    let nominal = outage_errors(&drive, &nominal_poses, outage);
    eprintln!(
        "outage {:.0}..{:.0} s: end error calibrated {:.2} m (max {:.2}), nominal {:.2} m (max {:.2})",
        outage.0, outage.1, calibrated.0, calibrated.1, nominal.0, nominal.1
    );
    assert!(
        nominal.0 > OUTAGE_FACTOR * calibrated.0,
        "end of outage: nominal {:.2} m vs calibrated {:.2} m",
        nominal.0,
        calibrated.0
    );
    assert!(nominal.1 > OUTAGE_FACTOR * calibrated.1);
}

/// An odometry started after the calibrator published still receives the
/// latest estimate (history of one) and uses it from its first pose on.
#[test]
fn late_odometry_receives_the_latest_estimate() {
    let mut g = Graph::new("late");
    let drive = simulate(&SimConfig::new(Scenario::Paper, 2)).expect("drive");
    let folder = write(&g, &drive, "drive");
    let state = g.path("state.json");
    seeded_state(&state, 7);
    let vehicle = format!("{folder}/vehicle.toml");
    let cal = g.spawn(
        "calibrator",
        Bin::Calibrator,
        &[
            "serve",
            "--vehicle",
            &vehicle,
            "--state",
            &s(&state),
            "--min-distance",
            "1e9",
        ],
    );
    g.wait_log(cal, "starting from the persisted estimate v7");
    std::thread::sleep(Duration::from_millis(300)); // well after the publish
    let bus = g.bus("test");
    let sub = bus.subscriber::<Pose>().expect("pose subscriber");
    let odo = odometry(&mut g, "odometry", &folder, &[]);
    g.wait_log(odo, "switching estimate v0 -> v7");
    let replay = replay_max(&mut g, &folder, "2");
    let poses = collect(&mut g, replay, &sub, last_wheel_t_ns(&drive));
    assert!(!poses.is_empty());
    assert!(
        poses.iter().all(|p| p.estimate_version == 7),
        "every pose uses v7; first: {:?}",
        poses.first()
    );
}

/// The same drive replayed twice gives identical pose streams.
#[test]
fn same_drive_replayed_twice_gives_identical_pose_streams() {
    let mut g = Graph::new("det");
    let drive = simulate(&SimConfig::new(Scenario::Paper, 4)).expect("drive");
    let folder = write(&g, &drive, "drive");
    let bus = g.bus("test");
    let sub = bus.subscriber::<Pose>().expect("pose subscriber");
    // Runs 0 and 1 as recorded; run 2 with the fixes (10 Hz) delivered 0.05 s late.
    const FIX_LATE_NS: i64 = 50_000_000;
    let mut runs = Vec::new();
    let mut late_log = String::new();
    for run in 0..3 {
        let odo = odometry(
            &mut g,
            &format!("odometry-{run}"),
            &folder,
            &["--no-bus-estimate"],
        );
        let late: &[&str] = if run == 2 {
            &["--deliver-late", "gnss=0.05"]
        } else {
            &[]
        };
        let replay = replay_max_with(&mut g, &folder, "1", late);
        runs.push(collect(&mut g, replay, &sub, last_wheel_t_ns(&drive)));
        g.terminate(odo);
        assert!(g.wait_exit(odo).success());
        if run == 2 {
            late_log = g.log(odo);
        }
    }
    assert_eq!(
        runs[0].len(),
        drive.wheels.samples.len(),
        "a pose per wheel sample"
    );
    let bits = |p: &Pose| {
        (
            p.header.t_ns,
            p.x_m.to_bits(),
            p.y_m.to_bits(),
            p.yaw_rad.to_bits(),
            p.covariance.map(f64::to_bits),
            p.mode,
            p.estimate_version,
        )
    };
    assert_eq!(runs[0].len(), runs[1].len());
    for (i, (a, b)) in runs[0].iter().zip(&runs[1]).enumerate() {
        // Bit for bit (the sequence numbers restart with each process).
        assert_eq!(a.header.seq, b.header.seq, "pose {i}");
        assert_eq!(bits(a), bits(b), "pose {i}: {a:?} vs {b:?}");
    }
    assert!(runs[0].iter().any(|p| p.mode == PoseMode::Fused as u8));

    // Fixes 0.05 s late: a pose published after every fix up to its time had
    // come is the in-order pose bit for bit, however the wakeups grouped the
    // samples (the odometry goes back for a fix that comes after its poses;
    // how many do depends on the scheduling). The others may lack the
    // newest fix.
    let fixes: Vec<i64> = drive
        .gnss
        .as_deref()
        .expect("gnss")
        .iter()
        .map(|f| interfaces::wire::seconds_to_ns(f.t_s))
        .collect();
    let waiting_for_a_fix = |t: i64| fixes.iter().any(|&f| f <= t && t < f + FIX_LATE_NS);
    assert_eq!(runs[2].len(), runs[0].len());
    let mut complete = 0;
    for (i, (a, b)) in runs[0].iter().zip(&runs[2]).enumerate() {
        if !waiting_for_a_fix(a.header.t_ns) {
            assert_eq!(
                bits(a),
                bits(b),
                "pose {i}: in order {a:?}, late fixes {b:?}"
            );
            complete += 1;
        }
    }
    assert!(complete > runs[0].len() / 3, "{complete} complete poses");
    let taken = late_log
        .lines()
        .find(|l| l.contains("late sample(s) taken in order"))
        .unwrap_or_else(|| panic!("no summary line in the odometry's log:\n{late_log}"));
    assert!(taken.contains(", 0 later than the 1 s window"), "{taken}");
}

/// The calibrator is SIGKILLed in the middle of a drive: the odometry keeps
/// publishing with the last estimate, the bridge is not blocked by the dead
/// subscriber, and a new calibrator starts from the persisted estimate.
#[test]
fn calibrator_killed_mid_drive_and_restarted() {
    let mut g = Graph::new("kill");
    let drive = simulate(&SimConfig::new(Scenario::Paper, 5)).expect("drive");
    let folder = write(&g, &drive, "drive");
    let state = g.path("state.json");
    seeded_state(&state, 3);
    let vehicle = format!("{folder}/vehicle.toml");
    let cal_args = [
        "serve",
        "--vehicle",
        &vehicle,
        "--state",
        &s(&state),
        "--min-distance",
        "1e9",
    ];
    let cal = g.spawn("calibrator", Bin::Calibrator, &cal_args);
    g.wait_log(cal, "starting from the persisted estimate v3");
    let bus = g.bus("test");
    let sub = bus.subscriber::<Pose>().expect("pose subscriber");
    let odo = odometry(&mut g, "odometry", &folder, &[]);
    g.wait_log(odo, "switching estimate v0 -> v3");
    // Paced, so that the kill falls in the middle of the drive (134 s at 20x).
    let replay = g.spawn(
        "replay",
        Bin::SensorBridge,
        &[
            "replay",
            &folder,
            "--speed",
            "20",
            "--wait-subscribers",
            "2",
            "--linger",
            "0.5",
        ],
    );
    let mut poses = Vec::new();
    wait_until("poses of the first part of the drive", || {
        drain(&sub, &mut poses);
        poses.len() > 1000
    });
    g.kill(cal);
    let killed_at_t = poses.last().expect("poses").header.t_s();
    let cal2 = g.spawn("calibrator-2", Bin::Calibrator, &cal_args);
    let status = g.wait_exit_with(replay, || {
        drain(&sub, &mut poses);
    });
    assert!(
        status.success(),
        "replay (must not hang on the dead subscriber):\n{}",
        g.log(replay)
    );
    let last = last_wheel_t_ns(&drive);
    wait_until("the last pose", || {
        drain(&sub, &mut poses);
        poses.last().is_some_and(|p| p.header.t_ns >= last)
    });
    let after: Vec<&Pose> = poses
        .iter()
        .filter(|p| p.header.t_s() > killed_at_t + 1.0)
        .collect();
    assert!(
        after.len() > 1000,
        "the odometry kept publishing: {} poses after the kill",
        after.len()
    );
    assert!(
        after.iter().all(|p| p.estimate_version == 3),
        "with the last estimate"
    );
    assert_eq!(sub.lost(), 0, "no pose lost");
    g.wait_log(cal2, "starting from the persisted estimate v3");
    assert!(
        g.is_running(cal2),
        "the new calibrator runs:\n{}",
        g.log(cal2)
    );
    let odo_log = g.log(odo);
    assert!(
        !odo_log.contains("stale"),
        "the odometry never went stale:\n{odo_log}"
    );
    // The new calibrator is a working subscriber too (it collected samples).
    g.terminate(cal2);
    assert!(g.wait_exit(cal2).success());
    let log = g.log(cal2);
    let collected: u64 = log
        .split("attempt(s), ")
        .nth(1)
        .and_then(|r| r.split(" accepted; ").nth(1))
        .and_then(|r| r.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(
        collected > 0,
        "the restarted calibrator collected wheel samples:\n{log}"
    );
}

/// The bridge dies: the odometry says its inputs went stale, publishes one
/// `NoFix` marker and then nothing it cannot stand behind.
#[test]
fn bridge_dies_and_the_odometry_withholds_its_pose() {
    let mut g = Graph::new("stale");
    let drive = simulate(&SimConfig::new(Scenario::Paper, 6)).expect("drive");
    let folder = write(&g, &drive, "drive");
    let bus = g.bus("test");
    let sub = bus.subscriber::<Pose>().expect("pose subscriber");
    let odo = odometry(
        &mut g,
        "odometry",
        &folder,
        &["--no-bus-estimate", "--stale-after", "0.5"],
    );
    let replay = g.spawn(
        "replay",
        Bin::SensorBridge,
        &["replay", &folder, "--speed", "5", "--wait-subscribers", "1"],
    );
    let mut poses = Vec::new();
    wait_until("fused poses", || {
        drain(&sub, &mut poses);
        poses.iter().any(|p| p.mode == PoseMode::Fused as u8)
    });
    g.kill(replay);
    let log = g.wait_log(odo, "inputs stale");
    assert!(log.contains("withheld"), "{log}");
    wait_until("the NoFix marker", || {
        drain(&sub, &mut poses);
        poses
            .last()
            .is_some_and(|p| p.mode == PoseMode::NoFix as u8)
    });
    let marker = *poses.last().expect("marker");
    assert_eq!(
        (marker.x_m, marker.y_m),
        (0.0, 0.0),
        "the marker carries no position"
    );
    // Nothing after the marker (checked for a while).
    let n = poses.len();
    let start = Instant::now();
    while start.elapsed() < Duration::from_millis(1500) {
        drain(&sub, &mut poses);
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(
        poses.len(),
        n,
        "no pose after the inputs went stale: {:?}",
        &poses[n..]
    );
    assert!(
        g.is_running(odo),
        "the odometry waits for inputs to come back"
    );
}

#[test]
fn the_pose_stream_ends_with_the_wheel_stream() {
    let mut g = Graph::new("posend");
    let mut sim = SimConfig::new(Scenario::Paper, 5);
    sim.duration_s = Some(30.0);
    let drive = simulate(&sim).expect("drive");
    let folder = write(&g, &drive, "drive");
    let bus = g.bus("test");
    let sub = bus.subscriber::<Pose>().expect("pose subscriber");
    let odo = odometry(&mut g, "odometry", &folder, &["--no-bus-estimate"]);
    let replay = replay_max(&mut g, &folder, "1");
    let mut poses = Vec::new();
    let mut ended = false;
    let take = |poses: &mut Vec<Pose>, ended: &mut bool| {
        // The events first: every pose published before the end is queued.
        *ended |= sub.take_events().expect("pose events").end_of_stream;
        while let Some(p) = sub.receive().expect("receive") {
            poses.push(p);
        }
    };
    let status = g.wait_exit_with(replay, || take(&mut poses, &mut ended));
    assert!(status.success(), "replay failed:\n{}", g.log(replay));
    wait_until("the odometry's end of the pose stream", || {
        take(&mut poses, &mut ended);
        ended
    });
    assert_eq!(
        poses.len(),
        drive.wheels.samples.len(),
        "a pose per wheel sample before the end"
    );
    g.terminate(odo);
    assert!(g.wait_exit(odo).success(), "{}", g.log(odo));
}
