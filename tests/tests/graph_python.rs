//! The Python example subscriber (`examples/python/pose_subscriber.py`, with
//! the `iceoryx2` package from PyPI) reads poses published from Rust: the
//! wire types hold across languages.
//!
//! Python is found (or `iceoryx2==0.10.0` installed into
//! `target/python-venv`) by [`python_with`]. Without Python, or when the
//! install fails, the test skips with the reason printed.

use integration_tests::graph::{wait_until, Graph, WATCHDOG};
use integration_tests::python::python_with;
use interfaces::bus::Bus;
use interfaces::wire::{Header, Pose, PoseMode};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const COUNT: u64 = 5;

fn python_with_iceoryx2() -> Result<PathBuf, String> {
    python_with("iceoryx2", "iceoryx2==0.10.0")
}

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

#[test]
fn python_subscriber_reads_poses_published_from_rust() {
    let python = match python_with_iceoryx2() {
        Ok(p) => p,
        Err(why) => {
            eprintln!("SKIPPED: no Python with the iceoryx2 package ({why})");
            return;
        }
    };
    let g = Graph::new("py");
    let script =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/python/pose_subscriber.py");
    let bus: Bus = g.bus("rust-publisher");
    let mut publisher = bus.publisher::<Pose>().expect("pose publisher");

    let mut cmd = Command::new(&python);
    cmd.arg(&script)
        .args(["--json", "--count", &COUNT.to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    for (k, v) in g.settings.env() {
        cmd.env(k, v);
    }
    let mut child = cmd.spawn().expect("start python");
    struct Reap(std::process::Child);
    impl Drop for Reap {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    let stdout = child.stdout.take().expect("stdout");
    let mut child = Reap(child);

    // Publish once the Python subscriber exists (and has attached).
    wait_until("the Python subscriber", || publisher.subscriber_count() > 0);
    publisher.announce().expect("announce");
    std::thread::sleep(Duration::from_millis(300));
    for i in 0..COUNT {
        publisher.publish(pose(i)).expect("publish");
    }

    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let start = Instant::now();
    let mut lines = Vec::new();
    while lines.len() < COUNT as usize {
        let left = WATCHDOG.saturating_sub(start.elapsed());
        match rx.recv_timeout(left) {
            Ok(l) => lines.push(l),
            Err(_) => {
                let _ = child.0.kill();
                let out = child.0.wait_with_output_lossy();
                panic!(
                    "watchdog/EOF: got {} of {COUNT} lines; stderr: {out}",
                    lines.len()
                );
            }
        }
    }
    for (i, line) in lines.iter().enumerate() {
        let v: serde_json::Value = serde_json::from_str(line).expect("json line");
        let p = pose(i as u64);
        assert_eq!(v["seq"], i as u64, "{line}");
        assert_eq!(v["t_ns"], p.header.t_ns);
        assert_eq!(v["x_m"].as_f64(), Some(p.x_m));
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
        let mode = if i.is_multiple_of(2) {
            "fused"
        } else {
            "dead_reckoning"
        };
        assert_eq!(v["mode"], mode);
    }
    let status = child.0.wait().expect("wait python");
    assert!(status.success(), "python exited with {status}");
}

#[test]
fn python_subscriber_ends_when_the_pose_stream_ends() {
    let python = match python_with_iceoryx2() {
        Ok(p) => p,
        Err(why) => {
            eprintln!("SKIPPED: no Python with the iceoryx2 package ({why})");
            return;
        }
    };
    let g = Graph::new("pyend");
    let script =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/python/pose_subscriber.py");
    let bus: Bus = g.bus("rust-publisher");
    let mut publisher = bus.publisher::<Pose>().expect("pose publisher");
    // No --count: only the end of the stream stops it.
    let mut cmd = Command::new(&python);
    cmd.arg(&script)
        .arg("--json")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    for (k, v) in g.settings.env() {
        cmd.env(k, v);
    }
    let child = cmd.spawn().expect("start python");
    struct Reap(std::process::Child);
    impl Drop for Reap {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    let mut child = Reap(child);
    wait_until("the Python subscriber", || publisher.subscriber_count() > 0);
    publisher.announce().expect("announce");
    std::thread::sleep(Duration::from_millis(300));
    for i in 0..COUNT {
        publisher.publish(pose(i)).expect("publish");
    }
    publisher.end_of_stream().expect("end of stream");
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.0.try_wait().expect("poll python") {
            break s;
        }
        if start.elapsed() > WATCHDOG {
            let _ = child.0.kill();
            let out = child.0.wait_with_output_lossy();
            panic!("the subscriber did not end with the stream; stderr: {out}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success(), "python exited with {status}");
    let mut out = String::new();
    let mut err = String::new();
    use std::io::Read;
    child
        .0
        .stdout
        .take()
        .expect("stdout")
        .read_to_string(&mut out)
        .expect("stdout");
    child
        .0
        .stderr
        .take()
        .expect("stderr")
        .read_to_string(&mut err)
        .expect("stderr");
    assert_eq!(
        out.lines().count(),
        COUNT as usize,
        "every pose before the end: {out}"
    );
    assert!(
        err.contains(&format!("pose stream ended after {COUNT} poses")),
        "{err}"
    );
}

trait WaitLossy {
    fn wait_with_output_lossy(&mut self) -> String;
}

impl WaitLossy for std::process::Child {
    fn wait_with_output_lossy(&mut self) -> String {
        use std::io::Read;
        let mut s = String::new();
        if let Some(mut e) = self.stderr.take() {
            let _ = e.read_to_string(&mut s);
        }
        let _ = self.wait();
        s
    }
}
