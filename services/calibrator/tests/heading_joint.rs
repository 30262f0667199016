//! The compass's bias is tested on its three terms jointly: a heading
//! error that is a pure sinusoid of the heading (hard iron, no constant)
//! is named by the Wald decision, and a drive without one is not.

use calibrator::diagnose::decide::WaldDecision;
use calibrator::diagnose::{diagnose, DiagnoseConfig, Diagnosis};
use interfaces::effects::Effect;
use simulator::{simulate, EffectSettings, HeadingBias, Scenario, SimConfig, VehicleKind};

fn diagnosed(bias: Option<HeadingBias>, seed: u64, vehicle: VehicleKind) -> Diagnosis {
    let mut cfg = SimConfig::new(Scenario::Mixed, seed);
    cfg.vehicle = vehicle;
    cfg.effects = EffectSettings::none();
    cfg.effects.heading_bias = bias;
    let drive = simulate(&cfg).expect("simulate");
    diagnose(&drive, &DiagnoseConfig::default()).expect("diagnose")
}

fn heading_test(d: &Diagnosis) -> &WaldDecision {
    d.wald
        .iter()
        .find(|w| w.test.effect == Effect::HeadingBias)
        .expect("a Wald test of the heading bias")
}

#[test]
fn a_pure_sinusoid_of_the_heading_is_named_and_a_null_drive_is_not() {
    let sinusoid = HeadingBias {
        a_deg: 0.0,
        b_deg: 3.0,
        c_deg: 0.0,
        d_deg: 0.0,
        e_deg: 0.0,
    };
    // Every drive first (their figures printed), then the verdicts.
    let mut checks = Vec::new();
    for (seed, vehicle) in [(1, VehicleKind::Compact), (2, VehicleKind::Saloon)] {
        let d = diagnosed(Some(sinusoid), seed, vehicle);
        let t = heading_test(&d).test.clone();
        let smallest = d
            .information_limit
            .as_ref()
            .and_then(|l| l.effects.iter().find(|e| e.effect == Effect::HeadingBias))
            .and_then(|h| h.shown_smallest());
        eprintln!("sinusoid seed {seed}: {t:?}, smallest {smallest:?} deg");
        let null = diagnosed(None, seed, vehicle);
        let n = heading_test(&null).test.clone();
        eprintln!("null seed {seed}: {n:?}");
        checks.push((seed, t, smallest, n));
    }
    for (seed, t, smallest, n) in checks {
        assert!(t.significant, "seed {seed}: {t:?}");
        // The size shown is finite, and 3 deg is beyond it.
        assert!(
            smallest.is_some_and(|s| s < 3.0),
            "seed {seed}: {smallest:?}"
        );
        assert!(n.z.abs() < n.z_critical, "seed {seed}: {n:?}");
    }
}
