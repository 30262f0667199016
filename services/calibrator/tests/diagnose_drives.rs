//! Several drives of one car (issue 37, item 4): the car's effects pooled
//! over the drives, each drive's own terms profiled out; checked on
//! simulated drives whose truth is known and on the real WID trials.

use calibrator::diagnose::pool::{CarVerdict, PooledEffect};
use calibrator::diagnose::{diagnose_drives, DiagnoseConfig, DrivesDiagnosis};
use interfaces::effects::Effect;
use simulator::{simulate, EffectSettings, Scenario, SimConfig, VehicleKind};
use std::path::Path;

fn drive(seed: u64, vehicle: VehicleKind, antenna_x_m: Option<f64>) -> interfaces::drive::Drive {
    let mut cfg = SimConfig::new(Scenario::Mixed, seed);
    cfg.vehicle = vehicle;
    cfg.effects = EffectSettings::none();
    if let Some(x) = antenna_x_m {
        cfg.effects
            .set(
                Effect::GnssLeverArm,
                Some(interfaces::effects::Param::LeverArmX),
                x,
            )
            .expect("set the antenna");
    }
    simulate(&cfg).expect("simulate")
}

fn car_effect(d: &DrivesDiagnosis, e: Effect) -> &PooledEffect {
    d.car
        .as_ref()
        .unwrap_or_else(|| panic!("no car: {:?}", d.car_missing))
        .effect(e)
        .unwrap_or_else(|| panic!("{e} missing"))
}

#[test]
fn the_car_s_antenna_is_found_over_two_drives_with_the_information_added() {
    // Two drives of one van, other seeds (other routes and noise), the
    // antenna 0.6 m ahead of the rear axle on both (vehicle.toml says 0).
    let drives = [
        drive(4, VehicleKind::Van, Some(0.6)),
        drive(5, VehicleKind::Van, Some(0.6)),
    ];
    let d = diagnose_drives(&drives, &DiagnoseConfig::default()).expect("diagnose");
    assert_eq!(d.drives.len(), 2);
    assert_eq!(d.pooled, vec![0, 1]);
    let car = d.car.as_ref().expect("car");
    assert_eq!(car.drives, 2);
    let p = car_effect(&d, Effect::GnssLeverArm);
    assert_eq!(p.verdict, CarVerdict::Found, "{p:?}");
    let j = p.limit.joint.as_ref().expect("joint");
    let (est, sigma) = (j.estimate.expect("estimate"), j.sigma.expect("sigma"));
    assert!(
        (est - 0.6).abs() <= 3.0 * sigma,
        "{est} ± {sigma} against 0.6 m"
    );
    // The information adds up: the pooled sigma is below each drive's own.
    for own in p.per_drive.iter().flatten() {
        assert!(
            sigma < own[1],
            "pooled {sigma} against a drive's {}",
            own[1]
        );
    }
    let shares: f64 = p.information_share.iter().sum();
    assert!((shares - 1.0).abs() < 1e-9, "{:?}", p.information_share);
    assert!(
        p.information_share.iter().all(|s| *s > 0.05),
        "{:?}",
        p.information_share
    );
    // Only the car's effects are pooled: the terms of the day are each
    // drive's own.
    for e in [Effect::GyroBias, Effect::RadiusDrift, Effect::RoadGrade] {
        assert!(car.effect(e).is_none(), "{e} pooled");
    }
    // The drives agree on it.
    let [q, limit] = p.heterogeneity.expect("two drives with an estimate");
    assert!(q <= limit, "Cochran's Q {q} beyond {limit}");
}

#[test]
fn two_drives_with_nothing_left_out_find_nothing_of_the_car() {
    let drives = [
        drive(6, VehicleKind::Saloon, None),
        drive(7, VehicleKind::Saloon, None),
    ];
    let d = diagnose_drives(&drives, &DiagnoseConfig::default()).expect("diagnose");
    let car = d.car.as_ref().expect("car");
    let found: Vec<Effect> = car
        .effects
        .iter()
        .filter(|p| p.verdict == CarVerdict::Found)
        .map(|p| p.limit.effect)
        .collect();
    assert!(found.is_empty(), "found on a null car: {found:?}");
    // Every car effect the drives hold information about has a size they
    // would show.
    assert!(car.effects.len() >= 7, "{}", car.effects.len());
    assert!(car
        .effects
        .iter()
        .filter(|p| p.limit.effect != Effect::HeadingBias)
        .all(|p| p.limit.smallest.is_some()));
}

#[test]
fn one_drive_that_cannot_be_diagnosed_is_named() {
    let mut short = drive(8, VehicleKind::Compact, None);
    // A minute of it: too short for the blocks.
    let t0 = short.wheels.samples.first().map_or(0.0, |w| w.t_s);
    short.wheels.samples.retain(|w| w.t_s < t0 + 8.0);
    if let Some(g) = short.gnss.as_mut() {
        g.retain(|f| f.t_s < t0 + 8.0);
    }
    let drives = [drive(9, VehicleKind::Compact, None), short];
    let err = diagnose_drives(&drives, &DiagnoseConfig::default()).expect_err("refused");
    let text = err.to_string();
    assert!(text.starts_with("drive 2 of 2:"), "{text}");
}

#[test]
fn the_wid_trials_together_list_the_car_and_agree_with_calibrate_on_the_antenna() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/real");
    let paths = [root.join("wid-trial02"), root.join("wid-trial04")];
    if !paths.iter().all(|p| p.exists()) {
        eprintln!(
            "skipped: the real WID drives are not at {} (../shared is absent)",
            root.display()
        );
        return;
    }
    let drives: Vec<interfaces::drive::Drive> = paths
        .iter()
        .map(|p| drive_io::read_drive(p).expect("read").drive)
        .collect();
    let d = diagnose_drives(&drives, &DiagnoseConfig::default()).expect("diagnose");
    let car = d.car.as_ref().expect("car");
    // Per car effect, the size the two drives together could show.
    for p in &car.effects {
        if p.limit.effect != Effect::HeadingBias {
            assert!(p.limit.smallest.is_some(), "{:?}", p.limit.effect);
        }
    }
    // The antenna: the pooled estimate (every other car effect free) and
    // calibrate's own on wid-trial02 agree within 2 sigma of the two.
    let cfg = calibrator::CalibrationConfig {
        estimate_lever_arm: true,
        ..calibrator::CalibrationConfig::default()
    };
    let cal = calibrator::calibrate(&drives[0], &cfg).expect("calibrate");
    let (x, sx) = (
        cal.gnss_antenna_m.expect("calibrate estimates the antenna")[0],
        cal.sigma_gnss_antenna_m.expect("its sigma")[0],
    );
    let p = car_effect(&d, Effect::GnssLeverArm);
    let j = p.limit.joint.as_ref().expect("joint");
    let (est, sigma) = (j.estimate.expect("estimate"), j.sigma.expect("sigma"));
    assert!(
        (est - x).abs() <= 2.0 * sigma.hypot(sx),
        "pooled {est} ± {sigma} m against calibrate's {x} ± {sx} m"
    );
}

#[test]
fn the_command_diagnoses_a_folder_of_drives_with_json_text_and_pages() {
    let dir = tempfile::tempdir().expect("tempdir");
    let folder = dir.path().join("car");
    for (i, seed) in [4, 5].into_iter().enumerate() {
        drive_io::write_drive(
            &drive(seed, VehicleKind::Van, Some(0.6)),
            &folder.join(format!("drive-{i}")),
        )
        .expect("write");
    }
    let json = dir.path().join("car.json");
    let plots = dir.path().join("plots");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_calibrator"))
        .arg("diagnose")
        .arg(&folder)
        .arg("--json")
        .arg(&json)
        .arg("--plots")
        .arg(&plots)
        .arg("--no-progress")
        .output()
        .expect("run");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("the car over 2 drives"), "{stdout}");
    assert!(
        stdout.contains("drive-0") && stdout.contains("drive-1"),
        "{stdout}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("json")).expect("parse");
    assert_eq!(v["paths"].as_array().map(Vec::len), Some(2));
    assert_eq!(v["drives"].as_array().map(Vec::len), Some(2));
    let antenna = v["car"]["effects"]
        .as_array()
        .and_then(|a| a.iter().find(|e| e["effect"] == "gnss_lever_arm"))
        .expect("the antenna in the car's table");
    assert_eq!(antenna["verdict"], "found", "{antenna}");
    let index = std::fs::read_to_string(plots.join("index.html")).expect("index");
    assert!(index.contains("gnss_lever_arm") && index.contains("drive-1/index.html"));
    // A figure per car effect: each drive beside all of them together.
    assert!(
        index.matches("<svg").count() >= 7,
        "{}",
        index.matches("<svg").count()
    );
    assert!(plots.join("drive-1").join("index.html").is_file());
    // A folder that holds no drive is refused with its name.
    let empty = dir.path().join("empty");
    std::fs::create_dir_all(&empty).expect("mkdir");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_calibrator"))
        .arg("diagnose")
        .arg(&empty)
        .arg("--no-progress")
        .output()
        .expect("run");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("empty"),
        "{stderr}"
    );
}
