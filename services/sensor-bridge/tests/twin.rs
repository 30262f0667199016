//! `sensor-bridge simulate --like`: the twin of a drive is deterministic
//! for a seed, takes a diagnosis's findings as its effects, refuses an
//! unknown one, and follows a real drive's GNSS track (skipped with a
//! printed reason when the real drives are absent).

// Helpers outside #[test] functions unwrap too: a failure is a test failure.
#![allow(clippy::unwrap_used)]

use drive_io::read_drive;
use simulator::twin::polyline_distance;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bridge(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sensor-bridge"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(args: &[&str]) {
    let out = bridge(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A short simulated recording to make twins of.
fn recording(dir: &Path) -> PathBuf {
    let rec = dir.join("rec");
    ok(&[
        "simulate",
        "--scenario",
        "mixed",
        "--duration",
        "120",
        "--seed",
        "4",
        "--out",
        rec.to_str().unwrap(),
    ]);
    rec
}

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let p = e.unwrap().path();
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

#[test]
fn twins_are_byte_identical_for_a_seed_and_differ_for_another() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = recording(tmp.path());
    let out = |name: &str, seed: &str| {
        let o = tmp.path().join(name);
        ok(&[
            "simulate",
            "--like",
            rec.to_str().unwrap(),
            "--seed",
            seed,
            "--out",
            o.to_str().unwrap(),
        ]);
        files(&o)
    };
    let (a, b, c) = (out("a", "7"), out("b", "7"), out("c", "8"));
    assert_eq!(
        a.iter().map(|f| &f.0).collect::<Vec<_>>().len(),
        7,
        "{:?}",
        a.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    assert!(a == b, "the same seed gives the same folder");
    assert!(a != c, "another seed gives another drive");
    let truth =
        String::from_utf8(a.iter().find(|f| f.0 == "truth.toml").unwrap().1.clone()).unwrap();
    assert!(
        truth.contains("twin_of = ") && truth.contains("seed = 7"),
        "{truth}"
    );
}

#[test]
fn effects_from_a_diagnosis_go_into_the_twins_truth_and_unknown_ones_are_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = recording(tmp.path());
    let json = tmp.path().join("diagnosis.json");
    std::fs::write(
        &json,
        r#"{"findings": [{"effect": "gnss_lever_arm", "parameters": {"x_m": 0.5, "y_m": 0.0}, "units": {"x_m": "m"}}],
            "information_limit": {"noise_east": [0.2, 0.8, 40.0], "noise_north": [0.3, 1.0, 60.0]}}"#,
    )
    .unwrap();
    let out = tmp.path().join("twin");
    ok(&[
        "simulate",
        "--like",
        rec.to_str().unwrap(),
        "--effects-from",
        json.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let d = read_drive(&out).unwrap().drive;
    let tp = d.truth_params.unwrap();
    assert_eq!(tp.effects["gnss_lever_arm"]["x_m"], 0.5);
    assert_eq!(tp.effects["gnss_lever_arm"]["y_m"], 0.0);
    let text = std::fs::read_to_string(out.join("truth.toml")).unwrap();
    // The wander: the mean of the two axes' error models; the white part:
    // the recording's own (0.3 m), from its fixes' successive differences.
    let v: toml::Value = toml::from_str(&text).unwrap();
    let gnss = &v["sensors"]["gnss"];
    assert!(
        (gnss["gm_sigma_m"].as_float().unwrap() - 0.9).abs() < 1e-9,
        "{text}"
    );
    assert!(
        (gnss["gm_tau_s"].as_float().unwrap() - 50.0).abs() < 1e-9,
        "{text}"
    );
    let white = gnss["white_sigma_m"].as_float().unwrap();
    assert!(
        (white - 0.3).abs() < 0.03,
        "white {white} against the recording's 0.3 m"
    );

    std::fs::write(
        &json,
        r#"{"findings": [{"effect": "flux_capacitor", "parameters": {"x": 1.0}}]}"#,
    )
    .unwrap();
    let bad = bridge(&[
        "simulate",
        "--like",
        rec.to_str().unwrap(),
        "--effects-from",
        json.to_str().unwrap(),
        "--out",
        tmp.path().join("never").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success());
    assert!(
        err.contains("diagnosis.json")
            && err.contains("findings[0]")
            && err.contains("flux_capacitor"),
        "{err}"
    );
    // --scenario and --like conflict.
    assert!(!bridge(&[
        "simulate",
        "--scenario",
        "mixed",
        "--like",
        "x",
        "--out",
        "y"
    ])
    .status
    .success());
}

#[test]
fn the_twin_of_a_real_drive_follows_its_gnss_track() {
    for name in ["wid-trial02", "wid-trial04"] {
        let Some(real) = drive_io::dev_data::real_drive(name) else {
            return;
        };
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("twin");
        ok(&[
            "simulate",
            "--like",
            real.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        let rec = read_drive(&real).unwrap().drive;
        let twin = read_drive(&out).unwrap().drive;
        let fixes = rec.gnss.clone().unwrap();
        let (xs, ys): (Vec<f64>, Vec<f64>) = fixes.iter().map(|f| (f.x_m, f.y_m)).unzip();
        let truth = twin.truth.clone().unwrap();
        let d: Vec<f64> = truth
            .iter()
            .step_by(10)
            .map(|p| polyline_distance(&xs, &ys, p.x_m, p.y_m))
            .collect();
        let rms = (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt();
        let max = d.iter().fold(0.0f64, |m, v| m.max(*v));
        // At the same time: the twin keeps the recording's timing.
        let same: Vec<f64> = fixes
            .iter()
            .map(|f| {
                let i = truth
                    .partition_point(|p| p.t_s < f.t_s)
                    .min(truth.len() - 1);
                (truth[i].x_m - f.x_m).hypot(truth[i].y_m - f.y_m)
            })
            .collect();
        let rms_t = (same.iter().map(|v| v * v).sum::<f64>() / same.len() as f64).sqrt();
        println!("{name}: twin path vs recorded GNSS track: RMS {rms:.3} m, max {max:.3} m; at the same time RMS {rms_t:.3} m");
        assert!(rms < 2.0 && rms_t < 3.0, "{name}: {rms} m, {rms_t} m");
        assert!((twin.wheel_duration_s() - rec.wheel_duration_s()).abs() < 0.05);
    }
}
