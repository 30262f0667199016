//! The `calibrator calibrate` binary on a drive folder.

mod common;

use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_calibrator"))
}

#[test]
fn calibrate_prints_the_report_and_writes_json_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let drive_dir = dir.path().join("drive");
    drive_io::write_drive(&common::Synth::default().drive(), &drive_dir).unwrap();
    let json = dir.path().join("cal.json");
    let plots = dir.path().join("plots");
    let out = bin()
        .args(["calibrate"])
        .arg(&drive_dir)
        .arg("--json")
        .arg(&json)
        .arg("--plots")
        .arg(&plots)
        .arg("--compare")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for needle in ["iter", "c_RL", "c_RR - c_RL", "comparison:", "warnings:"] {
        assert!(stdout.contains(needle), "missing {needle} in\n{stdout}");
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(v["circumference_m"]["rl"].as_f64().is_some());
    assert_eq!(v["method"], "batch");
    for f in ["track.svg", "iterations.svg"] {
        let svg = std::fs::read_to_string(plots.join(f)).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("polyline"), "{f}");
    }
}

#[test]
fn calibrate_fails_with_the_cause_on_a_drive_without_gnss() {
    let dir = tempfile::tempdir().unwrap();
    let mut d = common::Synth::default().drive();
    d.gnss = None;
    drive_io::write_drive(&d, dir.path()).unwrap();
    let out = bin().arg("calibrate").arg(dir.path()).output().unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("no GNSS fixes"), "{stderr}");
}

#[test]
fn calibrate_fails_with_the_cause_on_a_missing_folder() {
    let out = bin()
        .args(["calibrate", "/nonexistent/drive"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("cannot read drive /nonexistent/drive"),
        "{stderr}"
    );
}
