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

/// A 3 deg hard-iron sinusoid of the heading, no constant term.
fn sinusoid() -> HeadingBias {
    HeadingBias {
        a_deg: 0.0,
        b_deg: 3.0,
        c_deg: 0.0,
        d_deg: 0.0,
        e_deg: 0.0,
    }
}

fn heading_test(d: &Diagnosis) -> &WaldDecision {
    d.wald
        .iter()
        .find(|w| w.test.effect == Effect::HeadingBias)
        .expect("a Wald test of the heading bias")
}

#[test]
fn a_pure_sinusoid_of_the_heading_is_named_and_a_null_drive_is_not() {
    let sinusoid = sinusoid();
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

#[test]
fn a_sinusoid_is_named_against_a_twin_without_it_and_shown_over_several_drives() {
    use calibrator::diagnose::compare::{compare, Carried, CompareConfig, DifferenceVerdict};
    use calibrator::diagnose::pool::pool;
    let sinusoid = sinusoid();
    let vehicle = VehicleKind::Compact;
    let (a, b) = (
        diagnosed(Some(sinusoid), 1, vehicle),
        diagnosed(Some(sinusoid), 2, vehicle),
    );
    let (null_a, null_b) = (diagnosed(None, 1, vehicle), diagnosed(None, 2, vehicle));

    // The recording with the compass error against a simulation without:
    // the three terms' difference names it, though the constant terms'
    // difference alone is within the noise.
    let c = compare(
        &a,
        &null_a,
        None,
        &Carried::default(),
        &CompareConfig::default(),
    );
    let row = c
        .effects
        .iter()
        .find(|e| e.effect == Effect::HeadingBias)
        .expect("the compass compared");
    eprintln!("{row:?}");
    let critical = row.z_critical.expect("Holm's critical value");
    let constant = row.difference.expect("a difference") / row.sigma.expect("its sigma");
    assert!(constant.abs() < critical, "constant term z {constant}");
    assert_eq!(row.verdict, DifferenceVerdict::Lacking, "{row:?}");
    // What the next twin should carry: the three terms, the sinusoid's
    // 3 deg in its sin term, not the constant term alone.
    let next = c
        .findings
        .iter()
        .find(|f| f.effect == Effect::HeadingBias)
        .expect("the compass in the next twin");
    let b_deg = next.parameters.get("b_deg").copied().expect("its sin term");
    assert!((b_deg - 3.0).abs() < 0.5, "{next:?}");
    assert!(
        next.parameters.get("a_deg").is_some_and(|a| a.abs() < 0.5),
        "{next:?}"
    );
    // The drive against itself: nothing to name.
    let same = compare(&a, &a, None, &Carried::default(), &CompareConfig::default());
    assert!(same.named().all(|e| e.effect != Effect::HeadingBias));

    // Two drives of the car with it: the pooled three terms show it; two
    // without: they do not.
    let info = |d: &Diagnosis| d.information.clone().expect("the drive's information");
    let (ia, ib, na, nb) = (info(&a), info(&b), info(&null_a), info(&null_b));
    let with = pool(&[&ia, &ib]).expect("pooled");
    let h = with
        .effect(Effect::HeadingBias)
        .expect("the compass pooled");
    let terms = h
        .limit
        .joint
        .as_ref()
        .and_then(|j| j.terms.as_ref())
        .expect("its three terms pooled");
    eprintln!("pooled terms {terms:?}");
    assert!((terms.estimate[1] - 3.0).abs() < 4.0 * terms.covariance[1][1].sqrt());
    assert!(with.found().any(|t| t.effect == Effect::HeadingBias));
    let without = pool(&[&na, &nb]).expect("pooled");
    assert!(without.found().all(|t| t.effect != Effect::HeadingBias));
}
