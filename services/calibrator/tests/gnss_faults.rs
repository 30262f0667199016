//! GNSS as real receivers deliver it (issue 26): jumps are found against the
//! wheels and set aside, so the estimate matches the clean drive's; a drive
//! whose GNSS the calibrated model cannot explain is refused with the
//! reason; every calibration reports its fit quality.

use calibrator::{calibrate, CalibrationConfig, CalibrationError};
use interfaces::drive::Drive;
use simulator::faults::{apply, Fault};
use simulator::{simulate, EffectSettings, Scenario, SimConfig};

/// A mixed drive with RTK-grade GNSS (2 cm white, 3 cm wander) and no
/// unmodelled physics.
fn rtk_drive(seed: u64) -> Drive {
    let mut cfg = SimConfig::new(Scenario::Mixed, seed);
    cfg.effects = EffectSettings::none();
    cfg.sensors.gnss.white_sigma_m = 0.02;
    cfg.sensors.gnss.gm_sigma_m = 0.03;
    cfg.sensors.gnss.gm_tau_s = 30.0;
    simulate(&cfg).expect("simulate")
}

#[test]
fn gnss_jumps_are_set_aside_and_the_estimate_matches_the_clean_drive() {
    let drive = rtk_drive(4);
    let config = CalibrationConfig::default();
    let clean = calibrate(&drive, &config).expect("clean");
    let fault = Fault::GnssJumps {
        count: 4,
        min_m: 0.5,
        max_m: 3.0,
        min_s: 2.0,
        max_s: 20.0,
    };
    let jumped = apply(&drive, &fault, 11).expect("jumps");
    let cal = calibrate(&jumped, &config).expect("with jumps");
    let found = &cal.diagnostics.gnss_jumps;
    assert!(
        found.len() >= 4,
        "the 4 jumps are found: {found:?} (the clean drive: {:?})",
        clean.diagnostics.gnss_jumps
    );
    for (a, b, wheel) in [
        (cal.circumference_m.rl, clean.circumference_m.rl, "rl"),
        (cal.circumference_m.rr, clean.circumference_m.rr, "rr"),
    ] {
        let rel = (a - b).abs() / b;
        assert!(
            rel < 5e-4,
            "c_{wheel} {a:.5} m with jumps against {b:.5} m without: {:.4} %",
            100.0 * rel
        );
    }
    // The fit quality is reported and the jumped fixes do not spoil it.
    let (q0, q) = (
        clean.fit_quality.expect("clean fit quality"),
        cal.fit_quality.expect("fit quality"),
    );
    assert!(q.ratio <= q.limit, "{q:?}");
    assert!(
        q.residual_rms_m < 1.5 * q0.residual_rms_m,
        "{q:?} against {q0:?}"
    );
}

#[test]
fn a_drive_the_model_cannot_explain_is_refused_with_the_reason() {
    let mut drive = rtk_drive(5);
    // The receiver claims 1 cm but wanders by metres over a minute (a
    // multipath canyon it does not know about).
    for f in drive.gnss.as_mut().expect("gnss") {
        let w = 2.0 * std::f64::consts::PI * f.t_s / 60.0;
        f.x_m += 8.0 * w.sin();
        f.y_m += 6.0 * (0.7 * w).cos();
        f.sigma_m = Some(0.01);
    }
    match calibrate(&drive, &CalibrationConfig::default()) {
        Err(e @ CalibrationError::PoorFit { ratio, limit, .. }) => {
            assert!(ratio > limit);
            let text = e.to_string();
            assert!(text.contains("not published"), "{text}");
            assert!(text.contains("times the GNSS noise"), "{text}");
        }
        Err(e) => panic!("refused for another reason: {e}"),
        Ok(c) => panic!("published: fit quality {:?}", c.fit_quality),
    }
}
