//! A ROS 2 bag written by a third-party writer (the Python `rosbags`
//! package, `tests/ros2/drive_to_bag.py`) from a real drive folder
//! calibrates to the folder's result.
//!
//! Python is `WHEELCAL_PYTHON`, else `target/python-venv/bin/python` (the
//! CI script installs `rosbags` there). Without it, without the package, or
//! without `../shared/data/real`, the test skips with the reason printed.

use calibrator::{calibrate, CalibrationConfig};
use drive_io::{read_drive, read_drive_with, ReadOptions};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn python_with_rosbags() -> Option<PathBuf> {
    let python = match std::env::var_os("WHEELCAL_PYTHON") {
        Some(p) => PathBuf::from(p),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/python-venv/bin/python"),
    };
    let ok = Command::new(&python)
        .args(["-c", "import rosbags, numpy"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if ok {
        Some(python)
    } else {
        eprintln!(
            "skipped: {} cannot import rosbags (install it: {} -m pip install rosbags, or run .ci/run)",
            python.display(),
            python.display()
        );
        None
    }
}

#[test]
fn a_rosbags_bag_of_a_real_drive_calibrates_as_the_drive_folder() {
    let Some(folder) = drive_io::dev_data::real_drive("wid-trial02") else {
        return;
    };
    let Some(python) = python_with_rosbags() else {
        return;
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let bag = dir.path().join("bag");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/ros2/drive_to_bag.py");
    let status = Command::new(&python)
        .arg(&script)
        .arg(&folder)
        .arg(&bag)
        .arg("1700000000000000000")
        .status()
        .expect("run the bag writer");
    assert!(status.success(), "{} failed", script.display());

    let from_folder = read_drive(&folder).expect("read the folder").drive;
    let options = ReadOptions {
        vehicle: Some(from_folder.vehicle.clone()),
        ..ReadOptions::default()
    };
    // The rosbag2 folder (metadata.yaml + one .mcap) reads as its MCAP file.
    let loaded = read_drive_with(&bag, options).expect("read the bag");
    let from_bag = loaded.drive;
    assert_eq!(from_bag.wheels.units, from_folder.wheels.units);
    assert_eq!(
        from_bag.wheels.samples.len(),
        from_folder.wheels.samples.len()
    );
    for (a, b) in from_bag
        .wheels
        .samples
        .iter()
        .zip(&from_folder.wheels.samples)
    {
        assert_eq!((a.rl, a.rr, a.fl, a.fr), (b.rl, b.rr, b.fl, b.fr));
        // Header stamps are UNIX seconds.
        assert!((a.t_s - 1.7e9 - b.t_s).abs() < 1e-6, "{} {}", a.t_s, b.t_s);
    }
    assert_eq!(
        from_bag.gnss.as_ref().map(Vec::len),
        from_folder.gnss.as_ref().map(Vec::len)
    );
    assert_eq!(
        from_bag.imu.as_ref().map(Vec::len),
        from_folder.imu.as_ref().map(Vec::len)
    );

    let config = CalibrationConfig::default();
    let a = calibrate(&from_folder, &config).expect("calibrate the folder");
    let b = calibrate(&from_bag, &config).expect("calibrate the bag");
    // The stamps are the folder's times plus 1.7e9 s, rounded to the
    // nanosecond and then to a double (about 0.2 us): the same result to
    // within that rounding.
    for (x, y) in [
        (a.circumference_m.rl, b.circumference_m.rl),
        (a.circumference_m.rr, b.circumference_m.rr),
    ] {
        assert!((x - y).abs() < 1e-8 * x, "folder {x}, bag {y}");
    }
    assert!(
        (a.track_width_m - b.track_width_m).abs() < 1e-6,
        "folder {}, bag {}",
        a.track_width_m,
        b.track_width_m
    );
}
