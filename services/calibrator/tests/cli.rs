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
    for f in [
        "residuals.svg",
        "track.svg",
        "wheel_ratio.svg",
        "iterations.svg",
        "iterations_circumference.svg",
    ] {
        let svg = std::fs::read_to_string(plots.join(f)).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("polyline"), "{f}");
    }
    // One page with every figure inline, its axes titled with their units.
    let html = std::fs::read_to_string(plots.join("index.html")).unwrap();
    assert!(html.starts_with("<!DOCTYPE html>"));
    assert_eq!(html.matches("<figure").count(), 5, "five figures inline");
    assert_eq!(html.matches("<svg").count(), 5);
    for axis in [
        "time since the start of the drive, s",
        "GNSS fix minus model (antenna), m",
        "east, m",
        "north, m",
        "yaw rate / speed (reference heading change per metre), 1/m",
        "wheel-speed ratio v_RR/v_RL over the 2W model ratio, minus 1, %",
        "deviation from the reference, m",
        "mm",
    ] {
        assert!(html.contains(axis), "no axis `{axis}` on the page");
    }
    // The numbers on the page are the JSON's.
    let cell = |name: &str| -> f64 {
        let row = format!("<td>{name}</td><td class=\"n\">");
        let at = html.find(&row).unwrap_or_else(|| panic!("no row `{name}`")) + row.len();
        let end = at + html[at..].find('<').unwrap();
        html[at..end].parse().unwrap()
    };
    let rl = v["circumference_m"]["rl"].as_f64().unwrap();
    let rr = v["circumference_m"]["rr"].as_f64().unwrap();
    assert!((cell("rear-left circumference c_RL, m") - rl).abs() <= 0.5e-5);
    assert!((cell("rear-right circumference c_RR, m") - rr).abs() <= 0.5e-5);
    let rms = v["diagnostics"]["residual_rms_m"].as_f64().unwrap();
    let segments = v["diagnostics"]["segments"].as_u64().unwrap();
    let rms_row = format!("GNSS residual RMS of the fit, m ({segments} segments)");
    assert!((cell(&rms_row) - rms).abs() <= 0.5e-3);
    // The residual figure's caption states the same RMS: its residuals are the fit's.
    assert!(
        html.contains(&format!("RMS {rms:.3} m")),
        "residual RMS not {rms:.3}"
    );
    // Every warning of the JSON is on the page, in its words.
    for w in v["warnings"].as_array().unwrap() {
        let text = w["message"].as_str().unwrap();
        assert!(
            html.contains(&report::escape(text)),
            "warning missing: {text}"
        );
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

#[test]
fn calibrate_exports_an_autoware_parameter_file_and_the_2w_toml() {
    let dir = tempfile::tempdir().unwrap();
    let drive_dir = dir.path().join("drive");
    drive_io::write_drive(&common::Synth::default().drive(), &drive_dir).unwrap();
    let (json, yaml, toml_path) = (
        dir.path().join("cal.json"),
        dir.path().join("autoware.param.yaml"),
        dir.path().join("two_wheel.toml"),
    );
    let out = bin()
        .arg("calibrate")
        .arg(&drive_dir)
        .arg("--json")
        .arg(&json)
        .arg("--export-autoware")
        .arg(&yaml)
        .arg("--export-toml")
        .arg(&toml_path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rl = v["circumference_m"]["rl"].as_f64().unwrap();
    let rr = v["circumference_m"]["rr"].as_f64().unwrap();
    let nominal = v["nominal"]["circumference_m"].as_f64().unwrap();

    // The YAML: a ROS 2 parameter file whose factor is the mean over the nominal.
    let text = std::fs::read_to_string(&yaml).unwrap();
    assert!(
        text.contains(&format!("of the drive {}", drive_dir.display())),
        "{text}"
    );
    assert!(text.contains(&format!("wheelcal {}", env!("CARGO_PKG_VERSION"))));
    assert!(text.contains("/**:\n  ros__parameters:\n"), "{text}");
    let value = |key: &str| -> f64 {
        let line = text
            .lines()
            .find(|l| l.trim_start().starts_with(&format!("{key}:")))
            .unwrap_or_else(|| panic!("no {key} in\n{text}"));
        line.split(':').nth(1).unwrap().trim().parse().unwrap()
    };
    let factor = value("speed_scale_factor");
    assert!(
        (factor - 0.5 * (rl + rr) / nominal).abs() < 1e-6,
        "{factor}"
    );
    if let Some(bias) = v["gyro_bias_rad_s"].as_f64() {
        assert!((value("angular_velocity_offset_z") - bias).abs() < 1e-8);
    } else {
        assert!(!text.contains("angular_velocity_offset_z:"));
    }

    // The TOML parses and holds the JSON's values.
    let t: toml::Value = std::fs::read_to_string(&toml_path)
        .unwrap()
        .parse()
        .unwrap();
    let tw = &t["two_wheel"];
    assert!((tw["c_rl_m"].as_float().unwrap() - rl).abs() < 1e-6);
    assert!((tw["c_rr_m"].as_float().unwrap() - rr).abs() < 1e-6);
    let track = v["track_width_m"].as_f64().unwrap();
    assert!((tw["track_width_m"].as_float().unwrap() - track).abs() < 1e-5);
    let sigma = v["sigma_m"]["rl"].as_f64().unwrap();
    let s = tw["sigma"]["c_rl_m"].as_float().unwrap();
    assert!((s / sigma - 1.0).abs() < 1e-3, "{s} vs {sigma}");
    // The JSON carries the vehicle it was made for.
    assert!(v["vehicle"]["nominal_circumference_m"].as_f64().is_some());
}

#[test]
fn calibrate_starts_from_an_earlier_estimate_and_says_when_it_is_another_cars() {
    let dir = tempfile::tempdir().unwrap();
    let drive_dir = dir.path().join("drive");
    drive_io::write_drive(&common::Synth::default().drive(), &drive_dir).unwrap();
    let run = |extra: &[&std::path::Path], json: &std::path::Path| -> (String, serde_json::Value) {
        let mut cmd = bin();
        cmd.arg("calibrate").arg(&drive_dir).arg("--json").arg(json);
        if let Some(initial) = extra.first() {
            cmd.arg("--initial").arg(initial);
        }
        let out = cmd.output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v = serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
        (String::from_utf8_lossy(&out.stdout).to_string(), v)
    };
    let first = dir.path().join("first.json");
    let (_, a) = run(&[], &first);
    let (stdout, b) = run(&[&first], &dir.path().join("second.json"));
    assert!(!stdout.contains("another vehicle"), "{stdout}");
    // It started from the earlier estimate ...
    let start = &b["iterations"][0]["circumference_m"];
    for w in ["rl", "rr"] {
        assert_eq!(start[w], a["circumference_m"][w], "{w}");
        // ... and ends where the nominal start ended, well within a sigma.
        let (x, y) = (
            a["circumference_m"][w].as_f64().unwrap(),
            b["circumference_m"][w].as_f64().unwrap(),
        );
        let sigma = a["sigma_m"][w].as_f64().unwrap();
        assert!(
            (x - y).abs() < 0.1 * sigma,
            "{w}: {x} vs {y} (sigma {sigma})"
        );
    }
    // An estimate of another car: used, and said so.
    let mut other = a.clone();
    let track = other["vehicle"]["track_width_m"].as_f64().unwrap();
    other["vehicle"]["track_width_m"] = serde_json::json!(track + 0.3);
    let other_path = dir.path().join("other.json");
    std::fs::write(&other_path, other.to_string()).unwrap();
    let (stdout, _) = run(&[&other_path], &dir.path().join("third.json"));
    assert!(
        stdout.contains("was made for another vehicle") && stdout.contains("the rear track is"),
        "{stdout}"
    );
}

#[test]
fn a_truncated_recording_is_calibrated_with_allow_truncated_and_says_so_in_the_json() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("drive.mcap");
    drive_io::write_drive(&common::Synth::default().drive(), &mcap).unwrap();
    let bytes = std::fs::read(&mcap).unwrap();
    std::fs::write(&mcap, &bytes[..bytes.len() * 7 / 10]).unwrap();
    // Without the option: refused, and the message says the option exists.
    let out = bin().arg("calibrate").arg(&mcap).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("--allow-truncated"), "{stderr}");
    // With it: calibrated on what was read, the damage in the JSON.
    let json = dir.path().join("cal.json");
    let out = bin()
        .arg("calibrate")
        .arg(&mcap)
        .arg("--allow-truncated")
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let warnings = v["warnings"].as_array().unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w["code"] == "reading" && w["message"].as_str().unwrap().contains("truncated")),
        "{warnings:?}"
    );
}
