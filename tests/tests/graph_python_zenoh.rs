//! The Python example subscriber over Zenoh
//! (`examples/python/zenoh_pose_subscriber.py`, with the `eclipse-zenoh`
//! package from PyPI) reads poses and the latest estimate that a `gateway`
//! sends from a graph, decoded with the same Python types as the iceoryx2
//! example (`wheelcal_wire.py`).
//!
//! Python is found (or `eclipse-zenoh==1.10.2` installed into
//! `target/python-venv`) by [`python_with`]; without it the test skips with
//! the reason printed.

use integration_tests::graph::{free_tcp_endpoint, Bin, Graph, WATCHDOG};
use integration_tests::python::python_with;
use interfaces::bus::Bus;
use interfaces::wire::{CircumferenceEstimate, Header, ModelExtension, Pose, PoseMode};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const COUNT: usize = 5;

fn pose(i: u64) -> Pose {
    let mut covariance = [0.0; 9];
    for (j, c) in covariance.iter_mut().enumerate() {
        *c = 0.01 * (j as f64 + 1.0) + i as f64;
    }
    Pose {
        header: Header {
            t_ns: 1_000_000_000 * i as i64 - 5,
            seq: 0,
        },
        x_m: 10.5 + i as f64,
        y_m: -3.25,
        yaw_rad: 0.125 * i as f64,
        covariance,
        estimate_version: 2,
        mode: if i.is_multiple_of(2) {
            PoseMode::Fused as u8
        } else {
            PoseMode::DeadReckoning as u8
        },
        _pad: [0; 7],
    }
}

fn estimate() -> CircumferenceEstimate {
    let mut e = CircumferenceEstimate {
        header: Header::from_seconds(321.5, 0),
        version: 9,
        c_rl_m: 2.0437,
        c_rr_m: 2.0412,
        sigma_rl_m: 0.0011,
        sigma_rr_m: 0.0012,
        track_width_m: 1.58,
        gyro_bias_rad_s: -0.002,
        gyro_scale: 0.001,
        quality_m: 0.75,
        extension_count: 1,
        ..CircumferenceEstimate::default()
    };
    e.extensions[0] = ModelExtension {
        effect_code: 3,
        param_count: 2,
        params: [0.25, -0.5, 0.0, 0.0],
    };
    e
}

#[test]
fn python_subscriber_reads_poses_and_the_latest_estimate_over_zenoh() {
    let python = match python_with("zenoh", "eclipse-zenoh==1.10.2") {
        Ok(p) => p,
        Err(why) => {
            eprintln!("SKIPPED: no Python with the eclipse-zenoh package ({why})");
            return;
        }
    };
    let mut g = Graph::new("pyzenoh");
    let endpoint = free_tcp_endpoint();
    let bus: Bus = g.bus("rust-publisher");
    let mut poses = bus.publisher::<Pose>().expect("pose publisher");
    let mut estimates = bus
        .publisher::<CircumferenceEstimate>()
        .expect("estimate publisher");
    let gw = g.spawn(
        "gateway",
        Bin::Gateway,
        &[
            "--out",
            "pose,estimate",
            "--listen",
            &endpoint,
            "--no-wait-peer",
        ],
    );
    g.wait_log(gw, "forwarding");
    // Published long before the Python client starts: it asks for the latest.
    estimates.publish(estimate()).expect("publish estimate");
    let start = Instant::now();
    while start.elapsed() < Duration::from_millis(500) {
        estimates.update_connections().expect("history");
        std::thread::sleep(Duration::from_millis(20));
    }

    let script =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/python/zenoh_pose_subscriber.py");
    let mut child = Command::new(&python)
        .arg(&script)
        .args([
            "--connect",
            &endpoint,
            "--json",
            "--count",
            &COUNT.to_string(),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start python");
    struct Reap(std::process::Child);
    impl Drop for Reap {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    let stdout = child.stdout.take().expect("stdout");
    let stderr = child.stderr.take().expect("stderr");
    let mut child = Reap(child);
    let (tx, rx) = std::sync::mpsc::channel();
    let err_tx = tx.clone();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(Ok(line)).is_err() {
                break;
            }
        }
    });
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if err_tx.send(Err(line)).is_err() {
                break;
            }
        }
    });

    // Poses from when the client listens, until it has its COUNT (the first
    // may go out before its subscription reached the gateway).
    let mut listening = false;
    let mut i = 0u64;
    let mut lines = Vec::new();
    let mut stderr_lines = Vec::new();
    let start = Instant::now();
    while lines
        .iter()
        .filter(|l: &&String| l.contains("\"pose\""))
        .count()
        < COUNT
    {
        assert!(
            start.elapsed() < WATCHDOG,
            "watchdog: {} lines: {lines:?}; stderr: {stderr_lines:?}",
            lines.len()
        );
        match rx.recv_timeout(Duration::from_millis(50)) {
            Ok(Ok(line)) => lines.push(line),
            Ok(Err(line)) => {
                listening |= line.starts_with("listening on");
                stderr_lines.push(line);
            }
            Err(_) => {}
        }
        if listening {
            poses.publish(pose(i % 1000)).expect("publish pose");
            i += 1;
        }
        assert!(g.is_running(gw), "the gateway stopped:\n{}", g.log(gw));
    }
    let status = child.0.wait().expect("wait python");
    assert!(
        status.success(),
        "python exited with {status}; stderr: {stderr_lines:?}"
    );
    assert!(
        !stderr_lines.iter().any(|l| l.starts_with("rejected")),
        "{stderr_lines:?}"
    );

    let mut seen_estimate = false;
    let mut seen_poses = 0;
    for line in &lines {
        let v: serde_json::Value = serde_json::from_str(line).expect("json line");
        match v["topic"].as_str() {
            Some("estimate") => {
                let e = estimate();
                assert_eq!(v["version"], 9, "{line}");
                assert_eq!(v["t_ns"], e.header.t_ns);
                assert_eq!(v["c_rl_m"].as_f64(), Some(e.c_rl_m));
                assert_eq!(v["c_rr_m"].as_f64(), Some(e.c_rr_m));
                assert_eq!(v["sigma_rr_m"].as_f64(), Some(e.sigma_rr_m));
                assert_eq!(v["gyro_bias_rad_s"].as_f64(), Some(e.gyro_bias_rad_s));
                assert_eq!(v["quality_m"].as_f64(), Some(e.quality_m));
                assert_eq!(
                    v["extensions"],
                    serde_json::json!([{ "effect_code": 3, "params": [0.25, -0.5] }])
                );
                seen_estimate = true;
            }
            Some("pose") => {
                // Which pose it is: x_m = 10.5 + i.
                let x = v["x_m"].as_f64().expect("x_m");
                let k = (x - 10.5).round() as u64;
                let p = pose(k);
                assert_eq!(v["t_ns"], p.header.t_ns, "{line}");
                assert_eq!(v["y_m"].as_f64(), Some(p.y_m));
                assert_eq!(v["yaw_rad"].as_f64(), Some(p.yaw_rad));
                let cov: Vec<f64> = v["covariance"]
                    .as_array()
                    .expect("covariance")
                    .iter()
                    .map(|c| c.as_f64().expect("number"))
                    .collect();
                assert_eq!(cov, p.covariance.to_vec());
                assert_eq!(v["estimate_version"], 2);
                let mode = if k.is_multiple_of(2) {
                    "fused"
                } else {
                    "dead_reckoning"
                };
                assert_eq!(v["mode"], mode);
                seen_poses += 1;
            }
            other => panic!("unexpected topic {other:?}: {line}"),
        }
    }
    assert!(seen_estimate, "the latest estimate came: {lines:?}");
    assert_eq!(seen_poses, COUNT);
}
