//! The real drives of ../shared/data/real (skipped with a printed reason
//! when the folder is absent).

mod common;

use calibrator::{calibrate, CalibrationConfig, WarningCode};

fn load(name: &str) -> Option<interfaces::drive::Drive> {
    let path = drive_io::dev_data::real_drive(name)?;
    match drive_io::read_drive(&path) {
        Ok(loaded) => Some(loaded.drive),
        Err(e) => panic!("cannot read {name}: {e}"),
    }
}

#[test]
fn the_two_wid_trials_give_circumferences_that_agree() {
    let (Some(a), Some(b)) = (load("wid-trial02"), load("wid-trial04")) else {
        return;
    };
    let ca = calibrate(&a, &CalibrationConfig::default()).unwrap();
    let cb = calibrate(&b, &CalibrationConfig::default()).unwrap();
    for c in [&ca, &cb] {
        // The README: a fit of the effective rear circumference gives roughly 1.83-1.84 m.
        for v in [c.circumference_m.rl, c.circumference_m.rr] {
            assert!((1.81..1.86).contains(&v), "{:?}", c.circumference_m);
        }
        assert!(
            (1.30..1.60).contains(&c.track_width_m),
            "{}",
            c.track_width_m
        );
        assert!(
            c.diagnostics.wheel_rate_offsets.is_some(),
            "hub-gyro wheel rates read an offset at rest"
        );
    }
    // trial02 turns round (a U-turn) and pins its antenna to centimetres;
    // trial04 turns gently and cannot separate the lateral offset: it says so.
    assert!(
        !ca.has_warning(WarningCode::AntennaUnobservable),
        "{:?}",
        ca.warnings
    );
    assert!(
        cb.has_warning(WarningCode::AntennaUnobservable),
        "{:?}",
        cb.warnings
    );
    let mean = |c: &calibrator::Calibration| 0.5 * (c.circumference_m.rl + c.circumference_m.rr);
    let d = (mean(&ca) - mean(&cb)).abs();
    assert!(
        d < 0.005,
        "trial02 and trial04 disagree by {:.2} mm",
        1000.0 * d
    );
}

#[test]
fn a_measured_antenna_position_is_kept_where_the_drive_cannot_tell() {
    let Some(mut d) = load("wid-trial04") else {
        return;
    };
    // As if measured on the car (the value trial02, which turns round, finds).
    let measured = [0.51, -0.31];
    d.vehicle.gnss.antenna_x_m = Some(measured[0]);
    d.vehicle.gnss.antenna_y_m = Some(measured[1]);
    let cal = calibrate(&d, &CalibrationConfig::default()).unwrap();
    assert!(
        !cal.has_warning(WarningCode::AntennaUnobservable),
        "{:?}",
        cal.warnings
    );
    let g = cal.gyro.as_ref().expect("gyro estimate");
    for ((estimated, sigma), given) in g.antenna_m.iter().zip(g.sigma_antenna_m).zip(measured) {
        assert!(
            (estimated - given).abs() < 0.1 && sigma <= 0.05,
            "antenna {:?} +- {:?}",
            g.antenna_m,
            g.sigma_antenna_m
        );
    }
}

#[test]
fn the_nearly_straight_comma_drive_pins_the_common_scale_and_says_so() {
    let Some(d) = load("comma2k19-seg40") else {
        return;
    };
    let cal = calibrate(&d, &CalibrationConfig::default()).unwrap();
    assert!(cal.has_warning(WarningCode::NoTurn), "{:?}", cal.warnings);
    assert!(cal.has_warning(WarningCode::TrackWidthFixed));
    // The truth track's length over the mean wheel revolutions.
    let truth = d.truth.as_ref().unwrap();
    let revs = d.wheel_revolutions().unwrap();
    let (t0, t1) = (
        truth[0].t_s.max(revs[0].t_s),
        truth[truth.len() - 1].t_s.min(revs[revs.len() - 1].t_s),
    );
    let len: f64 = truth
        .windows(2)
        .filter(|w| w[0].t_s >= t0 && w[1].t_s <= t1)
        .map(|w| (w[1].x_m - w[0].x_m).hypot(w[1].y_m - w[0].y_m))
        .sum();
    let at = |t: f64| {
        let i = revs.partition_point(|r| r.t_s < t).min(revs.len() - 1);
        0.5 * (revs[i].rl + revs[i].rr)
    };
    let scale = len / (at(t1) - at(t0));
    let mean = 0.5 * (cal.circumference_m.rl + cal.circumference_m.rr);
    // The figure BENCHMARKS.md quotes: `cargo test --release -p calibrator
    // --test real_data -- --nocapture comma`.
    println!(
        "comma2k19: calibrated mean circumference {mean:.5} m, truth scale {scale:.5} m, \
         difference {:+.2} mm ({:+.3} %)",
        (mean - scale) * 1e3,
        (mean / scale - 1.0) * 100.0
    );
    assert!(
        (mean / scale - 1.0).abs() < 0.003,
        "mean {mean:.5} vs truth scale {scale:.5}"
    );
}
