//! Bad input: a clear error or warning naming the cause, never a panic.

mod common;

use calibrator::{
    calibrate, CalibrationConfig, CalibrationError, Method, TrackWidthMode, WarningCode,
};
use common::{straight_route, Synth};

fn both_methods() -> [CalibrationConfig; 2] {
    [
        CalibrationConfig {
            method: Method::Paper,
            ..CalibrationConfig::default()
        },
        CalibrationConfig::default(),
    ]
}

#[test]
fn a_drive_without_gnss_is_an_error_naming_it() {
    let mut d = Synth::default().drive();
    d.gnss = None;
    for c in both_methods() {
        let e = calibrate(&d, &c).unwrap_err();
        assert_eq!(e, CalibrationError::NoGnss);
        assert!(e.to_string().contains("no GNSS fixes"), "{e}");
    }
    d.gnss = Some(Vec::new());
    assert_eq!(
        calibrate(&d, &CalibrationConfig::default()).unwrap_err(),
        CalibrationError::NoGnss
    );
}

#[test]
fn a_drive_without_a_turn_warns_and_refuses_the_track_width() {
    let s = Synth {
        legs: straight_route(),
        ..Synth::default()
    };
    let d = s.drive();
    for c in both_methods() {
        let cal = calibrate(&d, &c).unwrap();
        let w = cal
            .warnings
            .iter()
            .find(|w| w.code == WarningCode::NoTurn)
            .expect("no-turn warning");
        assert!(
            w.message.contains("turns only") && w.message.contains("track width"),
            "{}",
            w.message
        );
        assert!(!cal.track_width_estimated);
        assert!(cal.has_warning(WarningCode::TrackWidthFixed));
        // The common scale is still determined.
        let mean = 0.5 * (cal.circumference_m.rl + cal.circumference_m.rr);
        assert!((mean - 0.5 * (s.c_rl + s.c_rr)).abs() < 1e-3, "{mean}");
    }
    let e = calibrate(
        &d,
        &CalibrationConfig {
            track_width: TrackWidthMode::Estimate,
            ..CalibrationConfig::default()
        },
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            CalibrationError::Unobservable {
                parameter: "track_width_m",
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("turns only"), "{e}");
}

#[test]
fn nans_are_skipped_with_a_warning_per_stream() {
    let s = Synth::default();
    let mut d = s.drive();
    for i in (500..d.wheels.samples.len()).step_by(1000) {
        d.wheels.samples[i].rl = f64::NAN;
    }
    d.gnss.as_mut().unwrap()[300].x_m = f64::NAN;
    d.imu.as_mut().unwrap()[700].gz_rad_s = f64::INFINITY;
    let cal = calibrate(&d, &CalibrationConfig::default()).unwrap();
    let messages: Vec<&str> = cal
        .warnings
        .iter()
        .filter(|w| w.code == WarningCode::NonFiniteSamples)
        .map(|w| w.message.as_str())
        .collect();
    assert!(
        messages
            .iter()
            .any(|m| m.starts_with("wheels:") && m.contains("non-finite")),
        "{messages:?}"
    );
    assert!(
        messages.iter().any(|m| m.starts_with("gnss: 1 of")),
        "{messages:?}"
    );
    assert!(
        messages.iter().any(|m| m.starts_with("imu: 1 of")),
        "{messages:?}"
    );
    let (e_rl, e_rr) = common::errors_mm(&cal, &s);
    assert!(e_rl.abs() < 0.5 && e_rr.abs() < 0.5, "{e_rl} {e_rr}");
}

#[test]
fn a_missing_wheel_column_is_an_error_naming_the_wheel() {
    let mut d = Synth::default().drive();
    for w in &mut d.wheels.samples {
        w.rr = f64::NAN;
    }
    let e = calibrate(&d, &CalibrationConfig::default()).unwrap_err();
    assert!(
        matches!(e, CalibrationError::WheelChannelEmpty { wheel: "rr", .. }),
        "{e}"
    );
    assert!(
        e.to_string().contains("rr channel has no finite value"),
        "{e}"
    );
}

#[test]
fn a_stuck_wheel_is_an_error_naming_the_wheel() {
    let mut d = Synth::default().drive();
    for w in &mut d.wheels.samples {
        w.rl = 12.0;
    }
    let e = calibrate(&d, &CalibrationConfig::default()).unwrap_err();
    assert!(
        matches!(e, CalibrationError::WheelStuck { wheel: "rl", .. }),
        "{e}"
    );
    assert!(e.to_string().contains("missing, stuck or broken"), "{e}");
}

#[test]
fn a_gnss_stream_that_stops_is_named() {
    let mut d = Synth::default().drive();
    let end = d.wheels.samples.last().unwrap().t_s;
    d.gnss.as_mut().unwrap().retain(|g| g.t_s < 0.6 * end);
    let cal = calibrate(&d, &CalibrationConfig::default()).unwrap();
    let w = cal
        .warnings
        .iter()
        .find(|w| w.code == WarningCode::StreamStops)
        .expect("stream warning");
    assert!(w.message.starts_with("gnss stops at t ="), "{}", w.message);
}

#[test]
fn a_wheel_stream_that_stops_and_resumes_is_named() {
    let mut d = Synth::default().drive();
    d.wheels.samples.retain(|w| !(50.0..62.0).contains(&w.t_s));
    let cal = calibrate(&d, &CalibrationConfig::default()).unwrap();
    let w = cal
        .warnings
        .iter()
        .find(|w| w.code == WarningCode::StreamGap)
        .expect("gap warning");
    assert!(
        w.message.starts_with("wheels: the stream pauses 1 time"),
        "{}",
        w.message
    );
    // The wheels stopping for good, with GNSS going on.
    let mut d = Synth::default().drive();
    let end = d.wheels.samples.last().unwrap().t_s;
    d.wheels.samples.retain(|w| w.t_s < 0.7 * end);
    let cal = calibrate(&d, &CalibrationConfig::default()).unwrap();
    assert!(
        cal.warnings
            .iter()
            .any(|w| w.code == WarningCode::StreamStops && w.message.starts_with("wheels stop at")),
        "{:?}",
        cal.warnings
    );
}

#[test]
fn gnss_outside_the_wheel_data_is_an_error() {
    let mut d = Synth::default().drive();
    for g in d.gnss.as_mut().unwrap() {
        g.t_s += 10_000.0;
    }
    let e = calibrate(&d, &CalibrationConfig::default()).unwrap_err();
    assert!(matches!(e, CalibrationError::NoOverlap { .. }), "{e}");
    assert!(e.to_string().contains("do not overlap"), "{e}");
}

#[test]
fn too_few_fixes_is_an_error() {
    let mut d = Synth::default().drive();
    d.gnss.as_mut().unwrap().truncate(5);
    let e = calibrate(&d, &CalibrationConfig::default()).unwrap_err();
    assert!(
        matches!(e, CalibrationError::TooFewGnss { usable: 5, .. }),
        "{e}"
    );
}

#[test]
fn a_car_that_does_not_move_is_an_error() {
    let s = Synth {
        legs: vec![common::Leg::Stop(60.0)],
        ..Synth::default()
    };
    let e = calibrate(&s.drive(), &CalibrationConfig::default()).unwrap_err();
    assert!(matches!(e, CalibrationError::TooShort { .. }), "{e}");
}

#[test]
fn an_invalid_configuration_names_the_field() {
    let d = Synth::default().drive();
    let e = calibrate(
        &d,
        &CalibrationConfig {
            alpha: 1.5,
            ..CalibrationConfig::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("alpha"), "{e}");
    let e = calibrate(
        &d,
        &CalibrationConfig {
            iterations: 0,
            ..CalibrationConfig::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("iterations"), "{e}");
}

#[test]
fn a_bad_vehicle_toml_is_an_error() {
    let mut d = Synth::default().drive();
    d.vehicle.track_width_m = 0.0;
    let e = calibrate(&d, &CalibrationConfig::default()).unwrap_err();
    assert!(
        e.to_string().starts_with("vehicle.toml: track_width_m"),
        "{e}"
    );
}

#[test]
fn wheel_and_gnss_that_disagree_are_not_a_result() {
    // GNSS from a car ten times as fast as the wheels say.
    let mut d = Synth::default().drive();
    for g in d.gnss.as_mut().unwrap() {
        g.x_m *= 10.0;
        g.y_m *= 10.0;
    }
    for c in both_methods() {
        match calibrate(&d, &c) {
            Err(e) => assert!(
                matches!(
                    e,
                    CalibrationError::Implausible { .. } | CalibrationError::Numerical { .. }
                ),
                "{e}"
            ),
            Ok(cal) => panic!("a result from inconsistent data: {:?}", cal.circumference_m),
        }
    }
}

#[test]
fn garbage_never_panics() {
    use rand::{Rng, SeedableRng};
    let base = Synth::default().drive();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    for round in 0..12 {
        let mut d = base.clone();
        let n = d.wheels.samples.len();
        for _ in 0..200 {
            let i = rng.random_range(0..n);
            match rng.random_range(0..4) {
                0 => d.wheels.samples[i].rl = f64::NAN,
                1 => d.wheels.samples[i].t_s -= 5.0,
                2 => d.wheels.samples[i].rr = 1e12,
                _ => d.wheels.samples[i].rl = -d.wheels.samples[i].rl,
            }
        }
        if round % 3 == 0 {
            d.imu = None;
        }
        if round % 4 == 1 {
            let g = d.gnss.as_mut().unwrap();
            for j in (0..g.len()).step_by(7) {
                g[j].y_m = f64::NAN;
            }
        }
        for c in both_methods() {
            // Either way is fine; a panic is not.
            let _ = calibrate(&d, &c);
        }
    }
}
