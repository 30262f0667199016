//! A wheel clock that moved against the GNSS and the IMU. The calibration
//! finds both offsets; where one of them carries a physical lag besides
//! the clock's shift, the stream is moved by the other's, so the
//! dead-reckoning through 30 s outages matches the drive on a good clock
//! (as the fault suite scores it: `cargo bench -p integration-tests
//! --bench fault_suite`):
//! - on a real drive (wid-trial02) the IMU's offset carries the wheels'
//!   lag behind the gyro, and the IMU follows the GNSS
//!   (`calibrator::clocks::imu_follows_gnss`); skipped with a message when
//!   `../shared/data/real` is absent;
//! - on the simulated paper course (constant speed) the GNSS's offset rests
//!   on the course rate, which carries the tyres' side-slip lag, and the
//!   GNSS follows the IMU (`calibrator::clocks::gnss::gnss_follows_imu`).

use calibrator::{calibrate, Calibration, CalibrationConfig};
use integration_tests::outages::{as_estimate, outage_errors};
use interfaces::drive::Drive;
use odometry::evaluate::{choose_truth_point, TruthPointChoice};
use simulator::faults::{apply, Fault};
use simulator::{simulate, Scenario, SimConfig};
use vehicle_model::estimate::Estimate;

fn estimate(cal: &Calibration) -> Estimate {
    as_estimate(cal, "calibration").expect("estimate")
}

/// The median 30 s outage error of the clean drive with its estimate and
/// of the faulted drive with its own, both scored at the clean drive's
/// truth point from its first wheel sample on.
fn clean_and_faulted_outages(
    drive: &Drive,
    clean_est: &Estimate,
    faulted: &Drive,
    est: &Estimate,
) -> (f64, f64) {
    let t0 = drive.wheels.samples.first().map_or(0.0, |w| w.t_s);
    let point =
        choose_truth_point(drive, TruthPointChoice::Auto, clean_est.antenna_m).expect("point");
    let median = |d: &Drive, e: &Estimate| {
        let errors = outage_errors(d, e, point, t0).expect("outages");
        assert!(errors.len() >= 5, "only {} outages scored", errors.len());
        errors[errors.len() / 2]
    };
    (median(drive, clean_est), median(faulted, est))
}

#[test]
fn a_moved_wheel_clock_puts_the_imu_on_the_gnss_correction_on_wid_trial02() {
    let Some(path) = drive_io::dev_data::real_drive("wid-trial02") else {
        return;
    };
    let drive = drive_io::read_drive(&path).expect("read").drive;
    let config = CalibrationConfig::default();
    let clean = calibrate(&drive, &config).expect("clean");
    let clean_est = estimate(&clean);
    // On a good clock the IMU's -30 ms against the wheels is the wheels'
    // physical lag and is left alone.
    assert!(
        !clean.clock_offsets.imu_s.applied,
        "{:?}",
        clean.clock_offsets.imu_s
    );
    assert_eq!(clean_est.clocks.imu_late_s, 0.0);

    let shift = -1.5;
    let faulted = apply(&drive, &Fault::WheelClockShift { s: shift }, 100).expect("fault");
    let cal = calibrate(&faulted, &config).expect("faulted");
    let (g, i) = (&cal.clock_offsets.gnss_s, &cal.clock_offsets.imu_s);
    let (g_off, i_off) = (
        g.offset_s.expect("gnss offset"),
        i.offset_s.expect("imu offset"),
    );
    // Both streams see the wheels 1.5 s early, the IMU 30 ms less so.
    assert!(g.applied && i.applied, "{g:?} {i:?}");
    assert!((g_off + shift).abs() < 0.03, "gnss {g_off}");
    assert!(
        (i_off + shift).abs() > 0.02,
        "imu {i_off}: the physical lag should show"
    );
    // The IMU is moved by the GNSS's offset, its own kept in the report.
    assert_eq!(i.applied_s, Some(g_off));
    let est = estimate(&cal);
    assert_eq!(est.clocks.imu_late_s, g_off);
    assert_eq!(est.clocks.gnss_late_s, g_off);
    assert!(
        cal.warnings
            .iter()
            .any(|w| w.message.contains("the wheels' clock moved")),
        "{:?}",
        cal.warnings
    );

    // Through 30 s outages it dead-reckons as the drive on a good clock
    // does (with the IMU's own offset it was 0.44 m against 0.225 m).
    let (clean_m, faulted_m) = clean_and_faulted_outages(&drive, &clean_est, &faulted, &est);
    println!(
        "median outage error: clean {clean_m:.3} m, wheel clock {shift:+.1} s {faulted_m:.3} m"
    );
    assert!(faulted_m <= 1.1 * clean_m, "{faulted_m} against {clean_m}");
}

#[test]
fn a_moved_wheel_clock_moves_the_gnss_by_the_imu_where_its_offset_rests_on_the_course_rate() {
    // The paper course at constant speed, as the fault suite draws it.
    let mut sim = SimConfig::new(Scenario::Paper, 1);
    // The truth on the GNSS clock, as a recording's (the fault suite's way).
    sim.effects
        .switch_off(interfaces::effects::Effect::GnssLatency);
    let drive = simulate(&sim).expect("simulate");
    let config = CalibrationConfig::default();
    let clean = calibrate(&drive, &config).expect("clean");
    let clean_est = estimate(&clean);
    // On a good clock the course rate's side-slip lag is not significant.
    assert!(
        !clean.clock_offsets.gnss_s.applied,
        "{:?}",
        clean.clock_offsets.gnss_s
    );

    let shift = -1.5;
    let faulted = apply(&drive, &Fault::WheelClockShift { s: shift }, 100).expect("fault");
    let cal = calibrate(&faulted, &config).expect("faulted");
    let (g, i) = (&cal.clock_offsets.gnss_s, &cal.clock_offsets.imu_s);
    let (g_off, i_off) = (
        g.offset_s.expect("gnss offset"),
        i.offset_s.expect("imu offset"),
    );
    assert!(g.applied && i.applied, "{g:?} {i:?}");
    // The course rate's offset carries the side-slip lag (tens of ms).
    assert!((g_off + shift).abs() > 0.04, "gnss {g_off}");
    assert!((i_off + shift).abs() < 0.02, "imu {i_off}");
    assert_eq!(g.applied_s, Some(i_off));
    assert_eq!(i.applied_s, None);
    let est = estimate(&cal);
    assert_eq!(est.clocks.gnss_late_s, i_off);
    // The circumferences as on a good clock, and the outages too (1.32 m
    // against 5.6 m with the course rate's offset applied).
    let rel = |a: f64, b: f64| ((a - b) / b).abs();
    assert!(rel(cal.circumference_m.rl, clean.circumference_m.rl) < 5e-5);
    let (clean_m, faulted_m) = clean_and_faulted_outages(&drive, &clean_est, &faulted, &est);
    println!(
        "median outage error: clean {clean_m:.3} m, wheel clock {shift:+.1} s {faulted_m:.3} m"
    );
    assert!(faulted_m <= 1.1 * clean_m, "{faulted_m} against {clean_m}");
}
