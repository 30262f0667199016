//! The twin loop of issue 38 with the real binaries, as the README shows it:
//! `sensor-bridge simulate --like` a recording, `calibrator compare` the
//! two, the comparison's findings mend the twin, compared again. The
//! "recording" is a simulated drive with an antenna 0.6 m ahead of the
//! rear axle that its vehicle.toml does not declare; the twin is told
//! nothing of it.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use integration_tests::graph::{bin, Bin};
use std::path::Path;
use std::process::Command;

fn run(b: Bin, args: &[&str]) -> String {
    let out = Command::new(bin(b)).args(args).output().expect("run");
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{} {}: {text}{}",
        b.name(),
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

fn named(json: &Path) -> Vec<String> {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
    v["effects"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["verdict"] == "lacking" || e["verdict"] == "excess")
        .map(|e| e["effect"].as_str().unwrap().to_string())
        .collect()
}

fn record(dir: &Path, name: &str, seed: &str, effects: &[&str]) -> String {
    let out = dir.join(name).display().to_string();
    let mut args = vec![
        "simulate",
        "--scenario",
        "mixed",
        "--duration",
        "600",
        "--no-default-effects",
        "--seed",
        seed,
        "--out",
        &out,
    ];
    for e in effects {
        args.extend(["--effect", e]);
    }
    run(Bin::SensorBridge, &args);
    out
}

#[test]
fn a_concealed_antenna_is_named_against_the_twin_and_gone_after_the_mend() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    let rec = record(dir.path(), "rec", "1", &["gnss_lever_arm.x_m=0.6"]);

    run(
        Bin::SensorBridge,
        &["simulate", "--like", &rec, "--seed", "1", "--out", &p("t0")],
    );
    let text = run(
        Bin::Calibrator,
        &[
            "compare",
            &rec,
            &p("t0"),
            "--json",
            &p("c1.json"),
            "--plots",
            &p("page"),
        ],
    );
    assert_eq!(
        named(Path::new(&p("c1.json"))),
        vec!["gnss_lever_arm"],
        "{text}"
    );
    assert!(Path::new(&p("page")).join("index.html").is_file());

    run(
        Bin::SensorBridge,
        &[
            "simulate",
            "--like",
            &rec,
            "--effects-from",
            &p("c1.json"),
            "--seed",
            "2",
            "--out",
            &p("t1"),
        ],
    );
    let truth = std::fs::read_to_string(Path::new(&p("t1")).join("truth.toml")).unwrap();
    assert!(truth.contains("[effects.gnss_lever_arm]"), "{truth}");
    let text = run(
        Bin::Calibrator,
        &[
            "compare",
            &rec,
            &p("t1"),
            "--json",
            &p("c2.json"),
            "--before",
            &p("c1.json"),
        ],
    );
    assert!(named(Path::new(&p("c2.json"))).is_empty(), "{text}");
    assert!(
        text.contains("before the mend: 1 named (gnss_lever_arm); now 0"),
        "{text}"
    );
}

#[test]
fn a_null_recording_against_its_twin_names_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    let rec = record(dir.path(), "rec", "3", &[]);
    run(
        Bin::SensorBridge,
        &["simulate", "--like", &rec, "--seed", "1", "--out", &p("t0")],
    );
    let text = run(
        Bin::Calibrator,
        &["compare", &rec, &p("t0"), "--json", &p("c.json")],
    );
    assert!(named(Path::new(&p("c.json"))).is_empty(), "{text}");
}
