//! Issue 35 item 4, live: `odometry serve --pose-state` stopped, the car
//! driven on for a minute the odometry never saw, then the whole sensor
//! stack restarted with its clock reset (the new run's time stamps start
//! before the kept pose's) but its wheel counters going on, inside a tunnel
//! (no GNSS for the first 40 s). Before the restart compared the wheel counts
//! under a clock that went back, the kept pose was resumed as it was: poses
//! hundreds of metres off with a sigma of about a metre until GNSS came back.
//! Now every pose in the tunnel must hold the truth inside its own 3 sigma
//! (or none is published): a pose is never confidently wrong.
//!
//! Real processes (`sensor-bridge replay`, `odometry serve`) over iceoryx2,
//! real files (the kept pose, the drive folders).

use drive_io::write_drive;
use integration_tests::graph::{drain, wait_until, Bin, Graph};
use interfaces::bus::TopicSubscriber;
use interfaces::drive::Drive;
use interfaces::wire::Pose;
use simulator::{simulate, Scenario, SimConfig};
use wheelcal_demo::report::truth_at;

/// End of the first run, drive s.
const FIRST_END_S: f64 = 150.0;
/// Start of the second run, drive s: the car drove on meanwhile.
const SECOND_START_S: f64 = 210.0;
/// The second run's clock starts here, s (before the kept pose's time).
const RESET_T0_S: f64 = 1.0;
/// No GNSS for this long after the second run's start, s.
const TUNNEL_S: f64 = 40.0;

/// The part of `drive` from `from_s` to `to_s`, its time stamps shifted by
/// `shift_s`, the wheel counters as recorded (they go on), GNSS dropped
/// before `gnss_from_s` (in the new time).
fn part(drive: &Drive, from_s: f64, to_s: f64, shift_s: f64, gnss_from_s: f64) -> Drive {
    let inside = |t: f64| t >= from_s && t <= to_s;
    let mut out = drive.clone();
    out.wheels.samples.retain(|s| inside(s.t_s));
    out.wheels.samples.iter_mut().for_each(|s| s.t_s += shift_s);
    if let Some(v) = out.gnss.as_mut() {
        v.retain(|s| inside(s.t_s));
        v.iter_mut().for_each(|s| s.t_s += shift_s);
        v.retain(|s| s.t_s >= gnss_from_s);
    }
    if let Some(v) = out.imu.as_mut() {
        v.retain(|s| inside(s.t_s));
        v.iter_mut().for_each(|s| s.t_s += shift_s);
    }
    if let Some(v) = out.heading.as_mut() {
        v.retain(|s| inside(s.t_s));
        v.iter_mut().for_each(|s| s.t_s += shift_s);
    }
    if let Some(v) = out.truth.as_mut() {
        v.retain(|s| inside(s.t_s));
        v.iter_mut().for_each(|s| s.t_s += shift_s);
    }
    out
}

fn replay_to_end(
    g: &mut Graph,
    folder: &str,
    sub: &TopicSubscriber<Pose>,
    last_t_s: f64,
) -> Vec<Pose> {
    let replay = g.spawn(
        "replay",
        Bin::SensorBridge,
        &[
            "replay",
            folder,
            "--max",
            "--wait-subscribers",
            "1",
            "--linger",
            "0.5",
        ],
    );
    let mut poses = Vec::new();
    let status = g.wait_exit_with(replay, || {
        drain(sub, &mut poses);
    });
    assert!(status.success(), "replay failed:\n{}", g.log(replay));
    let last_ns = interfaces::wire::seconds_to_ns(last_t_s);
    wait_until("the pose of the last wheel sample", || {
        drain(sub, &mut poses);
        poses.last().is_some_and(|p| p.header.t_ns >= last_ns)
    });
    poses
}

#[test]
fn a_restart_with_a_reset_clock_inside_a_tunnel_is_never_confidently_wrong() {
    let mut g = Graph::new("restarttunnel");
    let mut sim = SimConfig::new(Scenario::Mixed, 4);
    sim.duration_s = Some(SECOND_START_S + 120.0);
    let drive = simulate(&sim).expect("drive");
    let first = part(&drive, 0.0, FIRST_END_S, 0.0, f64::NEG_INFINITY);
    let shift = RESET_T0_S - SECOND_START_S;
    let second = part(
        &drive,
        SECOND_START_S,
        f64::INFINITY,
        shift,
        RESET_T0_S + TUNNEL_S,
    );
    let dir1 = g.path("first");
    let dir2 = g.path("second");
    write_drive(&first, &dir1).expect("write first");
    write_drive(&second, &dir2).expect("write second");
    let (dir1, dir2) = (
        dir1.to_str().expect("utf-8").to_string(),
        dir2.to_str().expect("utf-8").to_string(),
    );
    let kept = g.path("kept-pose.json");
    let kept = kept.to_str().expect("utf-8").to_string();
    let vehicle = format!("{dir1}/vehicle.toml");
    let odo_args = [
        "serve",
        "--vehicle",
        &vehicle,
        "--pose-state",
        &kept,
        "--no-bus-estimate",
    ];
    let bus = g.bus("test");
    let sub: TopicSubscriber<Pose> = bus.subscriber().expect("pose subscriber");

    // First run: with GNSS to its end, then a clean stop (its last word).
    let odo = g.spawn("odometry-1", Bin::Odometry, &odo_args);
    let last1 = first.wheels.samples.last().expect("wheels").t_s;
    let poses1 = replay_to_end(&mut g, &dir1, &sub, last1);
    assert!(!poses1.is_empty());
    g.terminate(odo);
    assert!(g.wait_exit(odo).success(), "{}", g.log(odo));
    assert!(
        std::path::Path::new(&kept).exists(),
        "no kept pose:\n{}",
        g.log(odo)
    );

    // Second run: the clock went back, the counters went on, no GNSS.
    let odo = g.spawn("odometry-2", Bin::Odometry, &odo_args);
    let last2 = second.wheels.samples.last().expect("wheels").t_s;
    let poses2 = replay_to_end(&mut g, &dir2, &sub, last2);
    let log = g.log(odo);
    g.terminate(odo);
    assert!(g.wait_exit(odo).success(), "{}", g.log(odo));

    let truth = second.truth.as_deref().expect("truth");
    let tunnel: Vec<(f64, f64, f64)> = poses2
        .iter()
        .filter(|p| p.header.t_s() < RESET_T0_S + TUNNEL_S)
        .filter_map(|p| {
            let (x, y) = truth_at(truth, p.header.t_s())?;
            let err = (p.x_m - x).hypot(p.y_m - y);
            // The 1-sigma of the position along the error's direction.
            let (ux, uy) = ((p.x_m - x) / err.max(1e-12), (p.y_m - y) / err.max(1e-12));
            let c = &p.covariance;
            let var = ux * ux * c[0] + 2.0 * ux * uy * c[1] + uy * uy * c[4];
            Some((p.header.t_s(), err, var.max(0.0).sqrt()))
        })
        .collect();
    let worst = tunnel
        .iter()
        .map(|&(_, e, s)| e / s.max(1e-12))
        .fold(0.0, f64::max);
    let moved_m = {
        let at = |t: f64| truth_at(drive.truth.as_deref().expect("truth"), t).expect("truth");
        let (a, b) = (at(FIRST_END_S), at(SECOND_START_S));
        (a.0 - b.0).hypot(a.1 - b.1)
    };
    println!(
        "tunnel poses: {}, car moved {moved_m:.0} m unseen; first: error {:.1} m sigma {:.1} m; \
         worst error/sigma {worst:.2}",
        tunnel.len(),
        tunnel.first().map_or(f64::NAN, |p| p.1),
        tunnel.first().map_or(f64::NAN, |p| p.2),
    );
    assert!(
        moved_m > 100.0,
        "the car must have moved far while unseen ({moved_m:.0} m)"
    );
    // Either the kept pose was refused (no pose until GNSS) or it was carried
    // over with the doubt of the unseen path: never confidently wrong.
    assert!(
        worst <= 3.0,
        "a tunnel pose off by {worst:.1} of its own sigma:\n{log}"
    );
    if tunnel.is_empty() {
        assert!(log.contains("refus"), "no pose and no reason:\n{log}");
    } else {
        // It said why it trusted the kept pose this far.
        assert!(log.contains("clock went back"), "{log}");
    }
}
