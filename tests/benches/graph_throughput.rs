//! Throughput of the whole graph: a 1 h drive replayed with `--max` through
//! `sensor-bridge replay`, `calibrator serve` and `odometry serve` (real
//! processes), with this process subscribing to the poses.
//!
//! Reported: samples published per second (the bridge's own figure), the
//! time until the pose of the last wheel sample arrived, and samples lost,
//! counted by sequence numbers in every subscriber: the calibrator and the
//! odometry (their summaries at SIGTERM) and the poses here.
//!
//! `cargo bench -p integration-tests --bench graph_throughput [-- SECONDS]`
//! (drive length, default 3600 s).

use drive_io::write_drive;
use integration_tests::graph::{drain, wait_until, Bin, Graph};
use interfaces::wire::Pose;
use simulator::{simulate, Scenario, SimConfig};
use std::time::Instant;

fn number_after(log: &str, before: &str, after: &str) -> Option<f64> {
    let i = log.rfind(before)? + before.len();
    let rest = &log[i..];
    let j = rest.find(after)?;
    rest[..j].split_whitespace().last()?.parse().ok()
}

fn main() {
    let seconds: f64 = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(3600.0);
    let mut g = Graph::new("thr");
    let mut config = SimConfig::new(Scenario::Long, 1);
    config.duration_s = Some(seconds);
    let t = Instant::now();
    let drive = simulate(&config).expect("simulate");
    eprintln!(
        "simulated {seconds:.0} s in {:.1} s",
        t.elapsed().as_secs_f64()
    );
    let folder = g.path("drive");
    write_drive(&drive, &folder).expect("write");
    let folder_s = folder.to_str().expect("utf-8").to_string();
    let vehicle = format!("{folder_s}/vehicle.toml");
    let state = g.path("state.json");
    let samples = drive.wheels.samples.len()
        + drive.gnss.as_ref().map_or(0, Vec::len)
        + drive.imu.as_ref().map_or(0, Vec::len)
        + drive.heading.as_ref().map_or(0, Vec::len);

    let cal = g.spawn(
        "calibrator",
        Bin::Calibrator,
        &[
            "serve",
            "--vehicle",
            &vehicle,
            "--state",
            state.to_str().expect("utf-8"),
        ],
    );
    let odo = g.spawn("odometry", Bin::Odometry, &["serve", "--vehicle", &vehicle]);
    let bus = g.bus("bench");
    let sub = bus.subscriber::<Pose>().expect("poses");
    g.wait_log(cal, "no accepted estimate yet");
    let start = Instant::now();
    let replay = g.spawn(
        "replay",
        Bin::SensorBridge,
        &[
            "replay",
            &folder_s,
            "--max",
            "--wait-subscribers",
            "2",
            "--progress",
            "600",
        ],
    );
    let mut poses: Vec<Pose> = Vec::new();
    let mut count = 0usize;
    let mut last_t = i64::MIN;
    let mut first_pose: Option<Instant> = None;
    let status = g.wait_exit_with(replay, || {
        drain(&sub, &mut poses);
        if !poses.is_empty() && first_pose.is_none() {
            first_pose = Some(Instant::now());
        }
        count += poses.len();
        if let Some(p) = poses.last() {
            last_t = p.header.t_ns;
        }
        poses.clear();
    });
    assert!(status.success(), "replay:\n{}", g.log(replay));
    let last_wheel =
        interfaces::wire::seconds_to_ns(drive.wheels.samples.last().expect("wheels").t_s);
    wait_until("the last pose", || {
        drain(&sub, &mut poses);
        count += poses.len();
        if let Some(p) = poses.last() {
            last_t = p.header.t_ns;
        }
        poses.clear();
        last_t >= last_wheel
    });
    let end_to_end = first_pose.map_or(f64::NAN, |f| f.elapsed().as_secs_f64());
    let with_startup = start.elapsed().as_secs_f64();
    g.terminate(cal);
    g.terminate(odo);
    let _ = g.wait_exit(cal);
    let _ = g.wait_exit(odo);
    let replay_log = g.log(replay);
    let cal_log = g.log(cal);
    let odo_log = g.log(odo);
    let published =
        number_after(&replay_log, "bridge: published", "samples in").unwrap_or(f64::NAN);
    let wall = number_after(&replay_log, "samples in", " s (").unwrap_or(f64::NAN);
    let cal_lost = number_after(&cal_log, "wheel samples collected,", "lost on the bus");
    let odo_lost = number_after(&odo_log, "estimate switch(es),", "samples lost on the bus");
    let accepted = number_after(&cal_log, "attempt(s),", "accepted");
    println!(
        "graph throughput: {seconds:.0} s drive, {samples} sensor samples ({} wheel)",
        drive.wheels.samples.len()
    );
    println!(
        "  bridge --max: {published:.0} samples in {wall:.2} s = {:.0} samples/s (1 subscriber set: calibrator + odometry)",
        published / wall
    );
    println!(
        "  first to last pose received: {end_to_end:.2} s = {:.0} sensor samples/s end to end \
         ({with_startup:.2} s including the bridge's start, drive loading and subscriber wait)",
        samples as f64 / end_to_end
    );
    println!(
        "  poses received: {count} (wheel samples {}), lost by sequence number: {}",
        drive.wheels.samples.len(),
        sub.lost()
    );
    // A pose beyond one per wheel sample is a stale-input marker (the
    // odometry got no wheel sample for its stale time): say so, not hide it.
    let stale = odo_log.matches("inputs stale").count();
    println!("  odometry stale-input markers: {stale}");
    println!(
        "  lost by sequence number: calibrator {}, odometry {}; calibrator accepted {} estimate(s)",
        cal_lost.map_or("?".to_string(), |v| format!("{v:.0}")),
        odo_lost.map_or("?".to_string(), |v| format!("{v:.0}")),
        accepted.map_or("?".to_string(), |v| format!("{v:.0}")),
    );
}
