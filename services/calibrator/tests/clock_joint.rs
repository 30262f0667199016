//! Clock offsets solved over every pair of streams (issue 35, item 6): on a
//! short drive at near-constant speed whose wheel clock is 0.5 s off both
//! the GNSS and the IMU, the wheels-GNSS pair alone does not determine the
//! GNSS offset; the wheels-IMU (yaw rate) and IMU-GNSS (course rate against
//! the gyro) pairs close the chain, and the offset is applied.

#![allow(clippy::expect_used, clippy::unwrap_used, clippy::print_stdout)]

use calibrator::{calibrate, Calibration, CalibrationConfig, ClockStream, OffsetStatus};
use interfaces::drive::Drive;
use simulator::{simulate, Scenario, SimConfig};

/// `d` between `t0` and `t1` (every stream).
fn cut(d: &Drive, t0: f64, t1: f64) -> Drive {
    let mut d = d.clone();
    let inside = |t: f64| t >= t0 && t <= t1;
    d.wheels.samples.retain(|s| inside(s.t_s));
    if let Some(g) = d.gnss.as_mut() {
        g.retain(|s| inside(s.t_s));
    }
    if let Some(g) = d.imu.as_mut() {
        g.retain(|s| inside(s.t_s));
    }
    if let Some(g) = d.heading.as_mut() {
        g.retain(|s| inside(s.t_s));
    }
    if let Some(g) = d.truth.as_mut() {
        g.retain(|s| inside(s.t_s));
    }
    d
}

/// The wheels' stamps `s` seconds late (against both GNSS and IMU).
fn wheels_late(d: &Drive, s: f64) -> Drive {
    let mut d = d.clone();
    for w in &mut d.wheels.samples {
        w.t_s += s;
    }
    d
}

fn rel_err(a: &Calibration, b: &Calibration) -> f64 {
    let e = |x: f64, y: f64| ((x - y) / y).abs();
    e(a.circumference_m.rl, b.circumference_m.rl).max(e(a.circumference_m.rr, b.circumference_m.rr))
}

#[test]
fn the_gnss_offset_is_found_through_the_imu_on_a_short_drive_at_constant_speed() {
    // 90 s of the paper's course at 60 km/h: the GNSS speed hardly varies,
    // the course rate against the wheels' yaw rate alone has sigma 0.12 s.
    let d = cut(
        &simulate(&SimConfig::new(Scenario::Paper, 2)).expect("simulate"),
        20.0,
        110.0,
    );
    let config = CalibrationConfig::default();
    let clean = calibrate(&d, &config).expect("clean");
    let cal = calibrate(&wheels_late(&d, 0.5), &config).expect("shifted");
    let pair = |base, later| {
        cal.clock_offsets
            .pairs
            .iter()
            .find(|p| p.base == base && p.later == later)
            .expect("pair reported")
            .offset
            .clone()
    };
    let direct = pair(ClockStream::Wheels, ClockStream::Gnss);
    let imu = pair(ClockStream::Wheels, ClockStream::Imu);
    println!("wheels-gnss {direct:?}\nwheels-imu {imu:?}");
    assert_eq!(direct.status, OffsetStatus::NotDetermined, "{direct:?}");
    assert_eq!(imu.status, OffsetStatus::Determined, "{imu:?}");
    let g = &cal.clock_offsets.gnss_s;
    println!("gnss {g:?}");
    assert_eq!(g.status, OffsetStatus::Determined, "{g:?}");
    let (off, sigma) = (g.offset_s.unwrap(), g.sigma_s.unwrap());
    // Wheels 0.5 s late: the GNSS is 0.5 s early against them.
    assert!((off + 0.5).abs() <= 2.0 * sigma, "{g:?}");
    assert!(g.applied, "{g:?}");
    assert!(g.from.as_deref().unwrap().contains("wheels-imu"), "{g:?}");
    let e = rel_err(&cal, &clean);
    println!("circumference {:.4} % off the unshifted drive's", 100.0 * e);
    // Uncompensated (today's main) it is 0.023 %; compensated 0.006 %.
    assert!(
        e < 1e-4,
        "circumference {:.4} % off the unshifted drive's",
        100.0 * e
    );
    // Reported in the JSON beside the offsets, and in the text report.
    let json = serde_json::to_value(&cal).unwrap();
    assert_eq!(json["clock_offsets"]["pairs"].as_array().unwrap().len(), 3);
    assert!(calibrator::result::report::render_text(&cal).contains("clock pair"));
}

#[test]
fn a_cut_of_wid_trial02_half_a_second_off_keeps_its_gnss_offset_and_circumference() {
    let Some(path) = drive_io::dev_data::real_drive("wid-trial02") else {
        return;
    };
    let d = cut(&drive_io::read_drive(&path).expect("read").drive, 0.0, 90.0);
    let config = CalibrationConfig::default();
    let clean = calibrate(&d, &config).expect("clean");
    let cal = calibrate(&wheels_late(&d, 0.5), &config).expect("shifted");
    let (g0, g) = (&clean.clock_offsets.gnss_s, &cal.clock_offsets.gnss_s);
    println!("clean {g0:?}\nshifted {g:?}");
    for p in &cal.clock_offsets.pairs {
        println!("{:?}-{:?}: {:?}", p.base, p.later, p.offset);
    }
    // The speed varies enough on this cut: the wheels' pairs with the GNSS
    // and the IMU are determined, and the combination moves with the shift.
    // The IMU-GNSS pair (course rate against the gyro) reads about -0.10 s:
    // the course of the antenna, 0.49 m ahead of the rear axle, leads the
    // heading by l_x / v (0.109 s weighted by this drive's turns), a lead
    // its sigma now includes, so it stays weak, not a wrong offset.
    let status = |base, later| {
        cal.clock_offsets
            .pairs
            .iter()
            .find(|p| p.base == base && p.later == later)
            .expect("pair reported")
            .offset
            .clone()
    };
    assert_eq!(
        status(ClockStream::Wheels, ClockStream::Gnss).status,
        OffsetStatus::Determined
    );
    assert_eq!(
        status(ClockStream::Wheels, ClockStream::Imu).status,
        OffsetStatus::Determined
    );
    let imu_gnss = status(ClockStream::Imu, ClockStream::Gnss);
    let [lag, sigma] = imu_gnss
        .weak
        .or_else(|| imu_gnss.offset_s.zip(imu_gnss.sigma_s).map(|(o, s)| [o, s]))
        .expect("the IMU-GNSS pair fitted");
    assert!(lag.abs() <= 2.0 * sigma, "{imu_gnss:?}");
    let (o0, o) = (g0.offset_s.unwrap(), g.offset_s.unwrap());
    let s = g.sigma_s.unwrap().hypot(g0.sigma_s.unwrap());
    assert!((o - o0 + 0.5).abs() <= 2.0 * s, "{g0:?} {g:?}");
    assert!(g.applied, "{g:?}");
    let e = rel_err(&cal, &clean);
    println!("circumference {:.4} % off the unshifted cut's", 100.0 * e);
    assert!(e < 1e-4, "{:.4} %", 100.0 * e);
}
