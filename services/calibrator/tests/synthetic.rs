//! The calibration on synthetic drives generated from the 2W model itself.

mod common;

use calibrator::{
    calibrate, calibrate_with_progress, CalibrationConfig, Method, TrackWidthMode, WarningCode,
};
use common::{errors_mm, Leg, Synth};

fn config(method: Method) -> CalibrationConfig {
    CalibrationConfig {
        method,
        ..CalibrationConfig::default()
    }
}

#[test]
fn batch_recovers_the_circumferences_on_exact_kinematics() {
    let s = Synth::default();
    let cal = calibrate(&s.drive(), &config(Method::Batch)).unwrap();
    let (e_rl, e_rr) = errors_mm(&cal, &s);
    assert!(
        e_rl.abs() < 0.3 && e_rr.abs() < 0.3,
        "errors {e_rl:.3} / {e_rr:.3} mm"
    );
    assert_eq!(cal.method, Method::Batch);
    // The sigmas are finite and the truth lies within a few of them.
    let (s_rl, s_rr) = (cal.sigma_m.rl.unwrap(), cal.sigma_m.rr.unwrap());
    assert!(
        e_rl.abs() < 4.0 * 1000.0 * s_rl + 0.05,
        "{e_rl} vs sigma {s_rl}"
    );
    assert!(
        e_rr.abs() < 4.0 * 1000.0 * s_rr + 0.05,
        "{e_rr} vs sigma {s_rr}"
    );
    assert!(cal.sigma_m.difference.unwrap() < 0.001);
}

#[test]
fn paper_method_recovers_the_circumferences_and_keeps_the_best_iteration() {
    let s = Synth::default();
    let cal = calibrate(
        &s.drive(),
        &CalibrationConfig {
            track_width: TrackWidthMode::Fixed,
            ..config(Method::Paper)
        },
    )
    .unwrap();
    let (e_rl, e_rr) = errors_mm(&cal, &s);
    assert!(
        e_rl.abs() < 1.5 && e_rr.abs() < 1.5,
        "errors {e_rl:.3} / {e_rr:.3} mm"
    );
    assert_eq!(cal.iterations.len(), 10, "iteration 0 (nominal) and 9 more");
    let kept = cal
        .iterations
        .iter()
        .find(|i| i.n == cal.selected_iteration)
        .unwrap();
    for i in &cal.iterations {
        assert!(
            kept.dr_error_mean_m <= i.dr_error_mean_m,
            "{kept:?} vs {i:?}"
        );
    }
    // The nominal start is far off; the kept iteration much better.
    assert!(cal.iterations[0].dr_error_mean_m > 5.0 * kept.dr_error_mean_m);
}

#[test]
fn the_track_width_is_estimated_as_a_third_parameter() {
    let s = Synth {
        track: 1.60,
        nominal_track: 1.55,
        ..Synth::default()
    };
    for method in [Method::Batch, Method::Paper] {
        let cal = calibrate(
            &s.drive(),
            &CalibrationConfig {
                track_width: TrackWidthMode::Estimate,
                ..config(method)
            },
        )
        .unwrap();
        assert!(cal.track_width_estimated);
        assert!(
            (cal.track_width_m - 1.60).abs() < 0.01,
            "{method}: track {}",
            cal.track_width_m
        );
        let (e_rl, e_rr) = errors_mm(&cal, &s);
        assert!(
            e_rl.abs() < 1.5 && e_rr.abs() < 1.5,
            "{method}: errors {e_rl:.3} / {e_rr:.3} mm"
        );
    }
}

#[test]
fn the_gyro_bias_and_scale_are_estimated_beside() {
    let s = Synth::default();
    let cal = calibrate(&s.drive(), &config(Method::Batch)).unwrap();
    let g = cal.gyro.expect("gyro estimate");
    assert!(
        (g.bias_rad_s - s.gyro_bias).abs() < 2e-4,
        "bias {}",
        g.bias_rad_s
    );
    assert!((g.scale - s.gyro_scale).abs() < 2e-3, "scale {}", g.scale);
    assert_eq!(cal.gyro_bias_rad_s, Some(g.bias_rad_s));
    assert_eq!(cal.gyro_scale, Some(g.scale));
    // The two standstills give the bias directly too.
    let at_rest = g.standstill_bias_rad_s.expect("standstill bias");
    assert!((at_rest - s.gyro_bias).abs() < 1e-3, "{at_rest}");
}

#[test]
fn the_gnss_lever_arm_comes_from_vehicle_toml() {
    let s = Synth {
        lever: [1.5, 0.3],
        ..Synth::default()
    };
    let cal = calibrate(&s.drive(), &config(Method::Batch)).unwrap();
    let (e_rl, e_rr) = errors_mm(&cal, &s);
    assert!(
        e_rl.abs() < 0.5 && e_rr.abs() < 0.5,
        "errors {e_rl:.3} / {e_rr:.3} mm"
    );
    assert_eq!(cal.diagnostics.lever_arm_m, [1.5, 0.3]);
    // Without it in vehicle.toml, it can be estimated.
    let hidden = Synth {
        lever_in_vehicle_toml: false,
        ..s.clone()
    };
    let cal = calibrate(
        &hidden.drive(),
        &CalibrationConfig {
            estimate_lever_arm: true,
            ..config(Method::Batch)
        },
    )
    .unwrap();
    let l = cal.gnss_antenna_m.expect("estimated antenna");
    assert!(
        (l[0] - 1.5).abs() < 0.2 && (l[1] - 0.3).abs() < 0.2,
        "{l:?}"
    );
}

#[test]
fn gnss_outliers_are_gated_and_named() {
    let s = Synth::default();
    let mut drive = s.drive();
    let gnss = drive.gnss.as_mut().unwrap();
    for i in (100..gnss.len()).step_by(97) {
        gnss[i].x_m += 40.0;
    }
    let cal = calibrate(&drive, &config(Method::Batch)).unwrap();
    assert!(
        cal.has_warning(WarningCode::GnssOutliers),
        "{:?}",
        cal.warnings
    );
    assert!(cal.diagnostics.gnss_outliers >= 10);
    let (e_rl, e_rr) = errors_mm(&cal, &s);
    assert!(
        e_rl.abs() < 0.5 && e_rr.abs() < 0.5,
        "errors {e_rl:.3} / {e_rr:.3} mm"
    );
}

#[test]
fn a_gnss_outage_is_bridged() {
    let s = Synth::default();
    let mut drive = s.drive();
    drive
        .gnss
        .as_mut()
        .unwrap()
        .retain(|g| !(60.0..120.0).contains(&g.t_s));
    for method in [Method::Batch, Method::Paper] {
        let cal = calibrate(&drive, &config(method)).unwrap();
        let w = cal
            .warnings
            .iter()
            .find(|w| w.code == WarningCode::GnssOutage)
            .expect("outage warning");
        assert!(w.message.contains("60.0 s"), "{}", w.message);
        let (e_rl, e_rr) = errors_mm(&cal, &s);
        assert!(
            e_rl.abs() < 2.0 && e_rr.abs() < 2.0,
            "{method}: errors {e_rl:.3} / {e_rr:.3} mm"
        );
    }
}

#[test]
fn a_gnss_time_offset_is_found_and_compensated() {
    let s = Synth {
        gnss_late_s: 0.2,
        gnss_sigma: 0.1,
        ..Synth::default()
    };
    let cal = calibrate(&s.drive(), &config(Method::Batch)).unwrap();
    let off = cal.diagnostics.time_offset.expect("time offset");
    assert!((off.gnss_late_s - 0.2).abs() < 0.05, "{off:?}");
    assert!(off.compensated);
    assert!(cal.has_warning(WarningCode::TimeOffset));
    let (e_rl, e_rr) = errors_mm(&cal, &s);
    assert!(
        e_rl.abs() < 0.5 && e_rr.abs() < 0.5,
        "errors {e_rl:.3} / {e_rr:.3} mm"
    );
}

#[test]
fn without_an_imu_the_heading_comes_from_the_gnss_course() {
    let s = Synth {
        imu: false,
        ..Synth::default()
    };
    let cal = calibrate(&s.drive(), &config(Method::Batch)).unwrap();
    assert!(cal.has_warning(WarningCode::NoImu));
    assert!(cal.gyro.is_none() && cal.gyro_bias_rad_s.is_none());
    let (e_rl, e_rr) = errors_mm(&cal, &s);
    assert!(
        e_rl.abs() < 0.5 && e_rr.abs() < 0.5,
        "errors {e_rl:.3} / {e_rr:.3} mm"
    );
}

#[test]
fn compare_runs_both_methods_side_by_side() {
    let s = Synth::default();
    let cal = calibrate(
        &s.drive(),
        &CalibrationConfig {
            compare: true,
            ..CalibrationConfig::default()
        },
    )
    .unwrap();
    let methods: Vec<Method> = cal.comparison.iter().map(|m| m.method).collect();
    assert_eq!(methods, vec![Method::Paper, Method::Batch]);
    let text = calibrator::result::report::render_text(&cal);
    assert!(
        text.contains("comparison:") && text.contains("paper") && text.contains("batch"),
        "{text}"
    );
}

#[test]
fn progress_is_reported_in_order_and_ends_at_one() {
    let s = Synth::default();
    let mut seen = Vec::new();
    calibrate_with_progress(&s.drive(), &CalibrationConfig::default(), &mut |p| {
        seen.push(p.fraction)
    })
    .unwrap();
    assert!(seen.len() >= 4);
    assert!(seen.windows(2).all(|w| w[1] >= w[0]), "{seen:?}");
    assert_eq!(seen.last().copied(), Some(1.0));
}

#[test]
fn the_json_keeps_the_contract_field_names() {
    let s = Synth::default();
    let cal = calibrate(&s.drive(), &CalibrationConfig::default()).unwrap();
    let v: serde_json::Value = serde_json::to_value(&cal).unwrap();
    for path in [
        "/circumference_m/rl",
        "/circumference_m/rr",
        "/sigma_m/rl",
        "/sigma_m/rr",
        "/sigma_m/difference",
        "/track_width_m",
        "/gyro_bias_rad_s",
        "/gyro_scale",
        "/method",
        "/selected_iteration",
        "/iterations/0/n",
        "/iterations/0/circumference_m/rl",
        "/iterations/0/dr_error_mean_m",
        "/iterations/0/dr_error_max_m",
        "/warnings",
    ] {
        assert!(v.pointer(path).is_some(), "missing {path} in {v}");
    }
    assert_eq!(v["method"], "batch");
    // And it reads back.
    let back: calibrator::Calibration = serde_json::from_value(v).unwrap();
    assert_eq!(back.circumference_m, cal.circumference_m);
}

#[test]
fn the_same_drive_gives_the_same_result() {
    let d = Synth::default().drive();
    let a = calibrate(&d, &CalibrationConfig::default()).unwrap();
    let b = calibrate(&d, &CalibrationConfig::default()).unwrap();
    assert_eq!(
        serde_json::to_string(&a).unwrap(),
        serde_json::to_string(&b).unwrap()
    );
}

#[test]
fn encoder_ticks_are_calibrated_too() {
    let s = Synth::default();
    let mut d = s.drive();
    d.vehicle.ticks_per_rev = Some(96.0);
    d.wheels.units = interfaces::drive::WheelUnits::rear(interfaces::drive::WheelUnit::Ticks);
    for w in &mut d.wheels.samples {
        w.rl = (w.rl * 96.0).floor();
        w.rr = (w.rr * 96.0).floor();
    }
    let cal = calibrate(&d, &CalibrationConfig::default()).unwrap();
    let (e_rl, e_rr) = errors_mm(&cal, &s);
    assert!(
        e_rl.abs() < 0.5 && e_rr.abs() < 0.5,
        "errors {e_rl:.3} / {e_rr:.3} mm"
    );
    let _ = Leg::Stop(0.0);
}
