//! The calibration's sigmas mean what they say (issue 26): under GNSS
//! errors correlated over a minute, on short drives where a jackknife has
//! too few blocks, the circumferences' true error stays within their own
//! sigma as a normal error would. The full sweep is the `sigma_coverage`
//! benchmark; this is its fast corner.

use calibrator::{calibrate, CalibrationConfig};
use simulator::{simulate, EffectSettings, Scenario, SimConfig, VehicleKind};

#[test]
fn the_scale_s_sigma_covers_its_error_under_correlated_gnss() {
    let mut z = Vec::new();
    for seed in 1..=8u64 {
        let mut cfg = SimConfig::new(Scenario::Paper, seed);
        cfg.vehicle = VehicleKind::ALL[(seed as usize) % VehicleKind::ALL.len()];
        cfg.effects = EffectSettings::none();
        // An automotive receiver: 0.3 m white, 1 m wandering over 60 s.
        cfg.sensors.gnss.white_sigma_m = 0.3;
        cfg.sensors.gnss.gm_sigma_m = 1.0;
        cfg.sensors.gnss.gm_tau_s = 60.0;
        let drive = simulate(&cfg).expect("simulated");
        let truth = drive.truth_params.clone().expect("truth");
        let cal = calibrate(&drive, &CalibrationConfig::default()).expect("calibrated");
        let basis = cal.diagnostics.sigma_basis.as_ref().expect("a sigma basis");
        let model = basis.error_model.expect("an error model was fitted");
        // The correlated part is found (the simulated one is 1 m).
        assert!(
            model.iter().all(|a| a.correlated_sigma_m > 0.2),
            "seed {seed}: {}",
            basis.describe()
        );
        let mean = 0.5 * (cal.circumference_m.rl + cal.circumference_m.rr);
        let true_mean = 0.5 * (truth.circumference_m.rl + truth.circumference_m.rr);
        let sigma = cal.sigma_m.mean.expect("a sigma of the scale");
        z.push((mean - true_mean) / sigma);
    }
    let within = |k: f64| z.iter().filter(|v| v.abs() <= k).count();
    // Honest sigmas: about 95 % within 2 sigma, none beyond 3.5 (before
    // the error model, these drives' errors were 5-9 sigma).
    assert!(within(2.0) >= 6, "within 2 sigma: {z:?}");
    assert_eq!(within(3.5), z.len(), "beyond 3.5 sigma: {z:?}");
}
