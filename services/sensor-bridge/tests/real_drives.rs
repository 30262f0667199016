//! The three real drives in `shared/data/real`: they load, round-trip through
//! MCAP bit-identical, and `info` gives sensible figures. Skipped with a
//! printed reason when the folder is absent.

// Helpers outside #[test] functions unwrap too: a failure is a test failure.
#![allow(clippy::unwrap_used)]

use drive_io::{read_drive, summarize, write_drive};
use std::path::PathBuf;
use std::process::Command;

const DRIVES: [&str; 3] = ["wid-trial02", "wid-trial04", "comma2k19-seg40"];

fn real_dir() -> Option<PathBuf> {
    let dir = drive_io::dev_data::real_data_dir();
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "SKIPPED: {} is absent (the real drives are not in this checkout)",
            dir.display()
        );
        None
    }
}

#[test]
fn real_drives_round_trip_through_mcap_bit_identical() {
    let Some(real) = real_dir() else { return };
    let out = tempfile::tempdir().unwrap();
    for name in DRIVES {
        let original = read_drive(&real.join(name)).unwrap();
        assert!(
            original.warnings.is_empty(),
            "{name}: {:?}",
            original.warnings
        );
        let d = &original.drive;
        assert!(
            d.gnss.is_some() && d.imu.is_some() && d.truth.is_some(),
            "{name}"
        );
        // lat/lon input: the origin used is recorded (the first fix).
        assert!(d.vehicle.gnss.origin_lat_deg.is_some(), "{name}");
        let first = d.gnss.as_ref().unwrap()[0];
        assert_eq!((first.x_m, first.y_m), (0.0, 0.0), "{name}");

        let mcap = out.path().join(format!("{name}.mcap"));
        write_drive(d, &mcap).unwrap();
        let from_mcap = read_drive(&mcap).unwrap();
        assert!(
            from_mcap.warnings.is_empty(),
            "{name}: {:?}",
            from_mcap.warnings
        );
        assert!(from_mcap.drive == *d, "{name}: MCAP round trip differs");

        let folder = out.path().join(name);
        write_drive(&from_mcap.drive, &folder).unwrap();
        let back = read_drive(&folder).unwrap();
        assert!(back.drive == *d, "{name}: folder -> MCAP -> folder differs");
        // Bit-identical, -0.0 included.
        assert_eq!(format!("{:?}", back.drive), format!("{d:?}"), "{name}");
    }
}

#[test]
fn info_figures_of_the_real_drives_are_sensible() {
    let Some(real) = real_dir() else { return };
    // (name, duration range s, GNSS distance range m, wheel rate Hz, GNSS rate Hz)
    let expected = [
        ("wid-trial02", (130.0, 138.0), (450.0, 600.0), 100.0, 5.0),
        ("wid-trial04", (140.0, 150.0), (450.0, 650.0), 100.0, 5.0),
        ("comma2k19-seg40", (58.0, 62.0), (900.0, 1100.0), 89.0, 10.0),
    ];
    for (name, duration, distance, wheel_hz, gnss_hz) in expected {
        let s = summarize(&read_drive(&real.join(name)).unwrap().drive);
        assert!(
            s.duration_s > duration.0 && s.duration_s < duration.1,
            "{name}: {}",
            s.duration_s
        );
        let gnss_m = s.distance_gnss_m.unwrap();
        assert!(
            gnss_m > distance.0 && gnss_m < distance.1,
            "{name}: {gnss_m}"
        );
        // The nominal circumference is a guess: within 10 % of the GNSS path.
        let wheels_m = s.distance_wheels_m.unwrap();
        assert!(
            (wheels_m / gnss_m - 1.0).abs() < 0.1,
            "{name}: wheels {wheels_m} vs GNSS {gnss_m}"
        );
        let rate = |stream: &str| {
            s.streams
                .iter()
                .find(|x| x.name == stream)
                .unwrap()
                .rate_hz
                .unwrap()
        };
        assert!(
            (rate("wheels") / wheel_hz - 1.0).abs() < 0.05,
            "{name}: {}",
            rate("wheels")
        );
        assert!(
            (rate("gnss") / gnss_hz - 1.0).abs() < 0.05,
            "{name}: {}",
            rate("gnss")
        );
        assert_eq!(s.streams.len(), 4, "{name}: wheels, gnss, imu, truth");
        // Outages are real stretches without fixes, longer than the threshold.
        for o in &s.gnss_outages {
            assert!(
                o.duration_s > s.gnss_outage_threshold_s.unwrap(),
                "{name}: {o:?}"
            );
        }
    }
}

#[test]
fn cli_info_and_convert_work_on_the_real_drives() {
    let Some(real) = real_dir() else { return };
    let exe = env!("CARGO_BIN_EXE_sensor-bridge");
    let out = tempfile::tempdir().unwrap();
    for name in DRIVES {
        let drive = real.join(name);
        let output = Command::new(exe).arg("info").arg(&drive).output().unwrap();
        let text = String::from_utf8_lossy(&output.stdout);
        assert!(
            output.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&output.stderr)
        );
        for part in [
            "duration:",
            "distance:",
            "wheels",
            "gnss",
            "imu",
            "GNSS outages",
        ] {
            assert!(text.contains(part), "{name}: `{part}` missing from\n{text}");
        }
        let json = Command::new(exe)
            .args(["info", "--json"])
            .arg(&drive)
            .output()
            .unwrap();
        let v: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
        assert!(v["duration_s"].as_f64().unwrap() > 50.0, "{name}: {v}");

        let mcap = out.path().join(format!("{name}.mcap"));
        let status = Command::new(exe)
            .arg("convert")
            .arg(&drive)
            .arg(&mcap)
            .status()
            .unwrap();
        assert!(status.success(), "{name}: convert to MCAP");
        let back = out.path().join(name);
        let status = Command::new(exe)
            .arg("convert")
            .arg(&mcap)
            .arg(&back)
            .status()
            .unwrap();
        assert!(status.success(), "{name}: convert back");
        assert!(
            read_drive(&back).unwrap().drive == read_drive(&drive).unwrap().drive,
            "{name}"
        );
    }
}
