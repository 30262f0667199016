//! Clocks that drift: a simulated 30 min drive whose wheel clock runs fast
//! by 200 ppm. The GNSS and IMU offsets against the wheels drift by -200
//! ppm; the drift is found within its sigmas, applied, and the
//! circumferences come out as on the clean drive. The clean drive shows no
//! significant drift, and a short drive says which drift it cannot see.

#![allow(clippy::expect_used, clippy::unwrap_used)]

use calibrator::{calibrate, Calibration, CalibrationConfig, OffsetStatus, TimeOffsetMode};
use interfaces::drive::Drive;
use simulator::faults::{apply, Fault};
use simulator::{simulate, Scenario, SimConfig};

fn long_drive() -> Drive {
    let mut c = SimConfig::new(Scenario::Long, 1);
    c.duration_s = Some(1800.0);
    simulate(&c).expect("simulate")
}

/// One line of what a calibration found of a stream's drift (the
/// figures BENCHMARKS.md quotes, seen with `-- --nocapture`).
fn print_drift(what: &str, c: &Calibration) {
    for (name, o) in [
        ("gnss", &c.clock_offsets.gnss_s),
        ("imu", &c.clock_offsets.imu_s),
    ] {
        let x = &o.drift;
        println!(
            "{what}: {name} drift {:+.0} +- {:.0} ppm (visible from {:.0} ppm), applied {}, offset {:+.3} +- {:.3} s",
            x.drift_ppm.unwrap_or(f64::NAN),
            x.sigma_ppm.unwrap_or(f64::NAN),
            x.detectable_ppm.unwrap_or(f64::NAN),
            x.applied,
            o.offset_s.unwrap_or(f64::NAN),
            o.sigma_s.unwrap_or(f64::NAN),
        );
    }
}

fn rel_err(a: &Calibration, b: &Calibration) -> f64 {
    let e = |x: f64, y: f64| ((x - y) / y).abs();
    e(a.circumference_m.rl, b.circumference_m.rl).max(e(a.circumference_m.rr, b.circumference_m.rr))
}

#[test]
fn a_wheel_clock_drift_of_200_ppm_is_found_applied_and_reported() {
    let d = long_drive();
    let config = CalibrationConfig::default();
    let clean = calibrate(&d, &config).unwrap();
    print_drift("clean", &clean);
    for o in [&clean.clock_offsets.gnss_s, &clean.clock_offsets.imu_s] {
        let x = &o.drift;
        assert_eq!(x.status, OffsetStatus::Determined, "{x:?}");
        assert!(!x.applied, "{x:?}");
        let (ppm, sigma) = (x.drift_ppm.unwrap(), x.sigma_ppm.unwrap());
        assert!(ppm.abs() <= 3.0 * sigma, "{x:?}");
        assert!(
            x.reason.as_deref().unwrap().contains("not significant"),
            "{x:?}"
        );
    }

    let ppm = 200.0;
    let drifted = apply(&d, &Fault::WheelClockDrift { ppm }, 1).unwrap();
    // The wheels gain `ppm`: the other streams' offsets against them fall.
    let expected = -ppm / (1.0 + ppm * 1e-6);
    let cal = calibrate(&drifted, &config).unwrap();
    print_drift("wheels +200 ppm", &cal);
    for o in [&cal.clock_offsets.gnss_s, &cal.clock_offsets.imu_s] {
        let x = &o.drift;
        assert_eq!(x.status, OffsetStatus::Determined, "{x:?}");
        assert!(x.applied && x.reason.is_none(), "{x:?}");
        let (found, sigma) = (x.drift_ppm.unwrap(), x.sigma_ppm.unwrap());
        assert!((found - expected).abs() < 3.0 * sigma, "{x:?}");
        assert!(sigma < 50.0, "{x:?}");
        // The offset is the one at the middle of the drive: the wheels are
        // 900 s * 200 ppm = 0.18 s late there.
        let off = o.offset_s.unwrap();
        assert!(
            (off + 0.18).abs() < 4.0 * o.sigma_s.unwrap() + 0.02,
            "{o:?}"
        );
    }
    let e = rel_err(&cal, &clean);
    println!(
        "wheels +200 ppm: c {:.4} % off the clean drive's",
        100.0 * e
    );
    assert!(
        e < 1e-4,
        "circumference {:.4} % off the clean drive's",
        100.0 * e
    );
    assert!(cal
        .warnings
        .iter()
        .any(|w| w.message.contains("clock drifts")));

    // Without compensation the drift is found but not applied, and the
    // circumferences are further off the clean drive's.
    let check = CalibrationConfig {
        time_offset: TimeOffsetMode::Check,
        ..CalibrationConfig::default()
    };
    let unapplied = calibrate(&drifted, &check).unwrap();
    print_drift("wheels +200 ppm, not compensated", &unapplied);
    println!(
        "wheels +200 ppm, not compensated: c {:.4} % off the clean drive's",
        100.0 * rel_err(&unapplied, &clean)
    );
    assert!(!unapplied.clock_offsets.imu_s.drift.applied);
    assert_eq!(
        unapplied.clock_offsets.imu_s.drift.status,
        OffsetStatus::Determined
    );

    // Reported in the JSON.
    let json = serde_json::to_value(&cal).unwrap();
    let g = &json["clock_offsets"]["gnss_s"]["drift"];
    assert_eq!(g["status"], "determined");
    assert!(g["drift_ppm"].as_f64().unwrap() < -100.0);
    assert!(g["sigma_ppm"].as_f64().unwrap() > 0.0);
    assert_eq!(g["applied"], true);
    assert_eq!(g["windows"].as_array().unwrap().len(), 8);
}

#[test]
fn a_short_drive_says_which_drift_it_cannot_see() {
    // The paper course: about 2.5 min.
    let d = simulate(&SimConfig::new(Scenario::Paper, 1)).expect("simulate");
    let cal = calibrate(&d, &CalibrationConfig::default()).unwrap();
    for o in [&cal.clock_offsets.gnss_s, &cal.clock_offsets.imu_s] {
        let x = &o.drift;
        assert!(!x.applied, "{x:?}");
        assert_ne!(x.status, OffsetStatus::NotChecked, "{x:?}");
        let r = x.reason.as_deref().unwrap();
        assert!(
            r.contains("min long") && r.contains("cannot be seen"),
            "{r}"
        );
        assert!(x.detectable_ppm.unwrap() > 0.0, "{x:?}");
    }
}
