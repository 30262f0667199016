//! The simulator's paper scenario (one seed; the ten-seed experiment is the
//! `paper_accuracy` benchmark).

use calibrator::{calibrate, CalibrationConfig, Method, TrackWidthMode};
use simulator::{simulate, Scenario, SimConfig};

#[test]
fn the_paper_scenario_is_calibrated_to_a_millimetre() {
    let drive = simulate(&SimConfig::new(Scenario::Paper, 4)).unwrap();
    let truth = drive.truth_params.clone().unwrap().circumference_m;
    let batch = calibrate(&drive, &CalibrationConfig::default()).unwrap();
    let paper = calibrate(
        &drive,
        &CalibrationConfig {
            method: Method::Paper,
            track_width: TrackWidthMode::Fixed,
            ..CalibrationConfig::default()
        },
    )
    .unwrap();
    for (cal, limit_mm) in [(&batch, 1.5), (&paper, 3.0)] {
        let e_rl = 1000.0 * (cal.circumference_m.rl - truth.rl);
        let e_rr = 1000.0 * (cal.circumference_m.rr - truth.rr);
        assert!(
            e_rl.abs() < limit_mm && e_rr.abs() < limit_mm,
            "{}: errors {e_rl:.2} / {e_rr:.2} mm",
            cal.method
        );
    }
    // The nominal 2.2 m start is more than 20 mm off: both moved far.
    assert!((truth.rl - 2.2).abs() > 0.02);
}
