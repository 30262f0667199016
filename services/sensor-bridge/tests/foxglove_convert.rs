//! `sensor-bridge convert` writes Foxglove's well-known schemas beside the
//! drive's own channels (not with `--no-foxglove`): GNSS as
//! `foxglove.LocationFix` in the CSV's own degrees, truth as
//! `foxglove.PoseInFrame` and `foxglove.FrameTransform`, loading warnings
//! as `foxglove.Log`; and the recording reads back as the drive either way.
//! (Field-by-field checks against the published schemas: drive-io's
//! `tests/foxglove.rs`.)

// Helpers outside #[test] functions unwrap too: a failure is a test failure.
#![allow(clippy::unwrap_used)]

use drive_io::{
    read_drive, FOXGLOVE_LOCATION_TOPIC, FOXGLOVE_LOG_TOPIC, FOXGLOVE_TF_TOPIC,
    FOXGLOVE_TRUTH_POSE_TOPIC,
};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

/// A drive folder in lat/lon with an unknown column (a loading warning).
fn write_folder(dir: &Path) -> Vec<(f64, f64)> {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(
        dir.join("vehicle.toml"),
        "track_width_m = 1.5\nnominal_circumference_m = 2.0\n",
    )
    .unwrap();
    let mut wheels = String::from("t_s,rl_rad_s,rr_rad_s\n");
    for i in 0..200 {
        wheels.push_str(&format!("{},10.0,10.2\n", i as f64 * 0.01));
    }
    std::fs::write(dir.join("wheels.csv"), wheels).unwrap();
    let fixes: Vec<(f64, f64)> = (0..10)
        .map(|i| (52.52 + 1e-5 * i as f64, 13.405 + 2e-5 * i as f64))
        .collect();
    let mut gnss = String::from("t_s,lat_deg,lon_deg,sigma_m,extra\n");
    let mut truth = String::from("t_s,lat_deg,lon_deg,yaw_rad\n");
    for (i, (lat, lon)) in fixes.iter().enumerate() {
        gnss.push_str(&format!("{},{lat:.9},{lon:.9},0.3,1\n", i as f64 * 0.2));
        truth.push_str(&format!("{},{lat:.9},{lon:.9},0.5\n", i as f64 * 0.2));
    }
    std::fs::write(dir.join("gnss.csv"), gnss).unwrap();
    std::fs::write(dir.join("truth.csv"), truth).unwrap();
    fixes
}

fn convert(args: &[&Path], flags: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_sensor-bridge"))
        .arg("convert")
        .args(flags)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Messages by topic, with their schema names.
fn channels(path: &Path) -> BTreeMap<String, (String, Vec<Value>)> {
    let bytes = std::fs::read(path).unwrap();
    let mut out: BTreeMap<String, (String, Vec<Value>)> = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m.channel.schema.as_ref().unwrap().name.clone();
        let entry = out
            .entry(m.channel.topic.clone())
            .or_insert_with(|| (schema, Vec::new()));
        entry.1.push(serde_json::from_slice(&m.data).unwrap());
    }
    out
}

#[test]
fn convert_writes_foxglove_channels_by_default_and_not_with_no_foxglove() {
    let tmp = tempfile::tempdir().unwrap();
    let folder = tmp.path().join("drive");
    let fixes = write_folder(&folder);
    let with = tmp.path().join("with.mcap");
    let without = tmp.path().join("without.mcap");
    convert(&[&folder, &with], &[]);
    convert(&[&folder, &without], &["--no-foxglove"]);

    let ch = channels(&with);
    let (schema, locations) = &ch[FOXGLOVE_LOCATION_TOPIC];
    assert_eq!(schema, "foxglove.LocationFix");
    assert_eq!(locations.len(), fixes.len());
    for (fix, (lat, lon)) in locations.iter().zip(&fixes) {
        assert!(
            (fix["latitude"].as_f64().unwrap() - lat).abs() < 1e-8,
            "{fix}"
        );
        assert!(
            (fix["longitude"].as_f64().unwrap() - lon).abs() < 1e-8,
            "{fix}"
        );
        assert_eq!(fix["position_covariance"][0].as_f64(), Some(0.3 * 0.3));
    }
    assert_eq!(ch[FOXGLOVE_TRUTH_POSE_TOPIC].0, "foxglove.PoseInFrame");
    assert_eq!(ch[FOXGLOVE_TRUTH_POSE_TOPIC].1.len(), fixes.len());
    assert_eq!(ch[FOXGLOVE_TF_TOPIC].0, "foxglove.FrameTransform");
    assert_eq!(ch[FOXGLOVE_TF_TOPIC].1.len(), fixes.len());
    let (schema, logs) = &ch[FOXGLOVE_LOG_TOPIC];
    assert_eq!(schema, "foxglove.Log");
    assert!(
        logs.iter()
            .any(|l| l["message"].as_str().unwrap().contains("extra")),
        "{logs:?}"
    );

    let plain = channels(&without);
    assert!(plain.values().all(|(s, _)| !s.starts_with("foxglove.")));
    for (topic, own) in &plain {
        assert_eq!(&ch[topic], own, "{topic}");
    }

    // Both read back as the drive folder does, without a warning.
    let original = read_drive(&folder).unwrap().drive;
    for path in [&with, &without] {
        let back = read_drive(path).unwrap();
        assert!(back.warnings.is_empty(), "{:?}", back.warnings);
        assert!(back.drive == original);
    }
}

#[test]
fn a_truncated_recording_converts_only_with_allow_truncated_and_its_log_names_the_damage() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("drive");
    write_folder(&folder);
    let mcap = dir.path().join("drive.mcap");
    convert(&[&folder, &mcap], &[]);
    let bytes = std::fs::read(&mcap).unwrap();
    std::fs::write(&mcap, &bytes[..bytes.len() * 7 / 10]).unwrap();
    let out_path = dir.path().join("again.mcap");
    // Without the option: refused, and the message says the option exists.
    let out = Command::new(env!("CARGO_BIN_EXE_sensor-bridge"))
        .arg("convert")
        .arg(&mcap)
        .arg(&out_path)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(stderr.contains("--allow-truncated"), "{stderr}");
    // With it: what was read before the damage, and the damage is named in
    // the converted recording's log (it was dropped before).
    convert(&[&mcap, &out_path], &["--allow-truncated"]);
    let logs = read_drive(&out_path).unwrap();
    let recorded = std::fs::read(&out_path).unwrap();
    let text = String::from_utf8_lossy(&recorded);
    assert!(
        text.contains("only what was read before the damage"),
        "no log of the damage; reading warnings: {:?}",
        logs.warnings
    );
}
