//! `odometry evaluate --plots` on a short simulated drive writes its page:
//! the figures inline with their axes and units, and the numbers of the
//! JSON.

use simulator::{simulate, Scenario, SimConfig};
use std::process::Command;

#[test]
fn evaluate_with_plots_writes_a_page_whose_numbers_are_the_jsons() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut sim = SimConfig::new(Scenario::Mixed, 7);
    sim.duration_s = Some(150.0);
    let drive = simulate(&sim).expect("simulate");
    let drive_dir = dir.path().join("drive");
    drive_io::write_drive(&drive, &drive_dir).expect("write drive");
    let json = dir.path().join("eval.json");
    let plots = dir.path().join("report");
    let out = Command::new(env!("CARGO_BIN_EXE_odometry"))
        .arg("evaluate")
        .arg(&drive_dir)
        .arg("--json")
        .arg(&json)
        .arg("--plots")
        .arg(&plots)
        .output()
        .expect("run odometry");
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("json")).expect("JSON");
    let outages = v["outages"].as_array().expect("outages");
    assert!(outages.len() >= 5, "{} outages", outages.len());
    let html = std::fs::read_to_string(plots.join("index.html")).expect("index.html");
    assert!(html.starts_with("<!DOCTYPE html>"));
    for f in ["outage_errors.svg", "outage_end_errors.svg", "track.svg"] {
        let svg = std::fs::read_to_string(plots.join(f)).expect("figure file");
        assert!(svg.starts_with("<svg"), "{f}");
    }
    assert_eq!(html.matches("<svg").count(), 3, "three figures inline");
    for axis in [
        "time since the outage start, s",
        "position error, m",
        "position error at the outage end, m",
        "east, m",
        "north, m",
    ] {
        assert!(html.contains(axis), "no axis `{axis}` on the page");
    }
    // One line per outage in the error figure: as many polylines of the
    // outages' colour as outages (the band and the median are drawn apart).
    let errors = std::fs::read_to_string(plots.join("outage_errors.svg")).expect("figure");
    let per_outage = errors
        .split("<polyline")
        .skip(1)
        .filter(|p| p.contains("stroke=\"#0072B2\"") && p.contains("stroke-width=\"1\""))
        .count();
    assert_eq!(per_outage, outages.len(), "one line per outage");
    let cell = |name: &str| -> String {
        let row = format!("<td>{name}</td><td class=\"n\">");
        let at = html.find(&row).unwrap_or_else(|| panic!("no row `{name}`")) + row.len();
        let end = at + html[at..].find('<').expect("cell end");
        html[at..end].to_string()
    };
    let median = v["median_error_m"].as_f64().expect("median");
    let p90 = v["p90_error_m"].as_f64().expect("p90");
    assert_eq!(cell("median position error, m"), format!("{median:.3}"));
    assert_eq!(cell("90th percentile, m"), format!("{p90:.3}"));
    assert_eq!(cell("outages"), outages.len().to_string());
    let rl = v["params"]["c_rl_m"].as_f64().expect("c_rl");
    assert_eq!(cell("c_RL, m"), format!("{rl:.5}"));
}

/// An estimate file as `calibrator calibrate --json` writes it, made for
/// `vehicle`.
fn estimate_for(vehicle: &interfaces::drive::VehicleParams) -> String {
    serde_json::json!({
        "circumference_m": {"rl": vehicle.nominal_circumference_m, "rr": vehicle.nominal_circumference_m},
        "track_width_m": vehicle.track_width_m,
        "nominal": {"circumference_m": vehicle.nominal_circumference_m, "track_width_m": vehicle.track_width_m},
        "vehicle": vehicle,
    })
    .to_string()
}

#[test]
fn an_estimate_made_for_another_vehicle_is_said_plainly() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut sim = SimConfig::new(Scenario::Mixed, 3);
    sim.duration_s = Some(90.0);
    let drive = simulate(&sim).expect("simulate");
    let drive_dir = dir.path().join("drive");
    drive_io::write_drive(&drive, &drive_dir).expect("write drive");
    let run = |estimate: &str, extra: &[&std::ffi::OsStr]| -> (String, serde_json::Value) {
        let est = dir.path().join("est.json");
        std::fs::write(&est, estimate).expect("write estimate");
        let json = dir.path().join("eval.json");
        let out = Command::new(env!("CARGO_BIN_EXE_odometry"))
            .arg("evaluate")
            .arg(&drive_dir)
            .arg("--estimate")
            .arg(&est)
            .arg("--json")
            .arg(&json)
            .args(extra)
            .output()
            .expect("run odometry");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v = serde_json::from_str(&std::fs::read_to_string(&json).expect("json")).expect("JSON");
        (String::from_utf8_lossy(&out.stderr).to_string(), v)
    };
    // Made for this vehicle: nothing to say.
    let (stderr, v) = run(&estimate_for(&drive.vehicle), &[]);
    assert!(!stderr.contains("another vehicle"), "{stderr}");
    assert!(!v["warnings"].to_string().contains("another vehicle"));
    // Made for a van: said on stderr and in the report's warnings.
    let mut van = drive.vehicle.clone();
    van.name = Some("delivery van".to_string());
    van.track_width_m += 0.2;
    let (stderr, v) = run(&estimate_for(&van), &[]);
    let w = v["warnings"][0].as_str().expect("a warning");
    assert!(
        w.contains("another vehicle") && w.contains("rear track"),
        "{w}"
    );
    assert!(stderr.contains("another vehicle"), "{stderr}");
    // A pipe, not a terminal: the log carries no colour codes.
    assert!(!stderr.contains('\u{1b}'), "ANSI escape in {stderr:?}");
    // --vehicle, as `calibrate` takes it: the van's parameters replace the
    // drive's own, and the van's estimate fits them (without --vehicle the
    // same estimate was warned about above).
    let mut van_drive = drive.clone();
    van_drive.vehicle = van.clone();
    let van_dir = dir.path().join("van");
    drive_io::write_drive(&van_drive, &van_dir).expect("write van drive");
    let vehicle_arg = std::ffi::OsString::from("--vehicle");
    let (stderr, v) = run(
        &estimate_for(&van),
        &[
            vehicle_arg.as_os_str(),
            van_dir.join("vehicle.toml").as_os_str(),
        ],
    );
    assert!(!stderr.contains("another vehicle"), "{stderr}");
    assert!(!v["warnings"].to_string().contains("another vehicle"));
}
