//! The drive's information limit (issue 37): what each effect's Fisher
//! information under the drive's own error model (and the drive's own
//! scatter over segments) says the drive could show,
//! checked against simulated drives whose truth is known.

use calibrator::diagnose::limit::{EffectLimit, InformationLimit};
use calibrator::diagnose::{diagnose, DiagnoseConfig};
use interfaces::effects::Effect;
use simulator::{simulate, EffectSettings, Scenario, SimConfig, VehicleKind};

fn drive_with(effect: Option<Effect>, seed: u64, vehicle: VehicleKind) -> interfaces::drive::Drive {
    let mut cfg = SimConfig::new(Scenario::Mixed, seed);
    cfg.vehicle = vehicle;
    cfg.effects = EffectSettings::none();
    if let Some(e) = effect {
        cfg.effects.switch_on(e);
    }
    simulate(&cfg).expect("simulate")
}

fn limit_of(drive: &interfaces::drive::Drive) -> InformationLimit {
    let d = diagnose(drive, &DiagnoseConfig::default()).expect("diagnose");
    d.information_limit
        .unwrap_or_else(|| panic!("no limit: {:?}", d.information_limit_missing))
}

fn effect(l: &InformationLimit, e: Effect) -> &EffectLimit {
    l.effects
        .iter()
        .find(|x| x.effect == e)
        .unwrap_or_else(|| panic!("{e} missing"))
}

#[test]
fn a_concealed_effect_is_estimated_within_its_sigma_and_shows_at_the_limit() {
    // One drive per effect, each another seed and car: the estimate with
    // every other effect of its source free covers the truth within 3
    // sigma, and is beyond the family's critical z.
    let cases = [
        (Effect::TrackWidth, 2, VehicleKind::Compact),
        (Effect::GnssLeverArm, 1, VehicleKind::Van),
        (Effect::LoadTransferRadius, 2, VehicleKind::Compact),
        (Effect::SideSlip, 3, VehicleKind::Saloon),
    ];
    for (e, seed, vehicle) in cases {
        let drive = drive_with(Some(e), seed, vehicle);
        let truth = drive
            .truth_params
            .as_ref()
            .and_then(|t| t.effect_param(e.main_fitted()))
            .expect("truth");
        let l = limit_of(&drive);
        let x = effect(&l, e);
        let j = x.joint.as_ref().expect("joint fit");
        let (est, sigma, z) = (
            j.estimate.expect("estimate"),
            j.sigma.expect("sigma"),
            j.wald_z.expect("z"),
        );
        // The estimate with every partner free, whatever its sign, is the
        // one to hold against a truth (partners held at zero may pull it:
        // `Joint::estimate_all_free`).
        let (free_est, free_sigma) = (
            j.estimate_all_free.unwrap_or(est),
            j.sigma_all_free.unwrap_or(sigma),
        );
        assert!(
            (free_est - truth).abs() <= 3.0 * free_sigma,
            "{e}: {free_est} ± {free_sigma} against the truth {truth} (held at zero: {:?})",
            j.held_at_zero
        );
        assert!(
            z.abs() > l.z_critical,
            "{e}: z {z} against {}",
            l.z_critical
        );
        // The sigma is never below the Fisher information's.
        assert!(sigma >= j.sigma_fisher.expect("fisher") * (1.0 - 1e-12));
        // And the size it shows is below the typical one here.
        assert!(x.relative_to_typical.expect("relative") < 1.5, "{x:?}");
        // The chance of showing a typical one: above 90 % exactly where
        // the size shown (every other effect free) is under the typical.
        for y in &l.effects {
            let (Some(p), Some(shown)) = (y.power_at_typical, y.shown_smallest()) else {
                assert!(y.shown_smallest().is_none(), "{}: no power", y.effect);
                continue;
            };
            assert!((0.0..=1.0).contains(&p), "{}: {p}", y.effect);
            assert_eq!(
                p > 0.9,
                shown < y.typical,
                "{}: {p}, {shown} against {}",
                y.effect,
                y.typical
            );
        }
    }
}

#[test]
fn on_drives_with_nothing_left_out_no_effect_passes_the_family_level() {
    // The family-wise level is 5 % per drive: of three null drives at most
    // one may show an effect beyond the critical z, and none far beyond.
    let mut drives_with_a_discovery = Vec::new();
    for (seed, vehicle) in [
        (1, VehicleKind::Saloon),
        (2, VehicleKind::Van),
        (3, VehicleKind::Compact),
    ] {
        let l = limit_of(&drive_with(None, seed, vehicle));
        assert_eq!(l.effects.len(), Effect::ALL.len(), "{l:?}");
        let beyond: Vec<(Effect, f64)> = l
            .effects
            .iter()
            .filter_map(|x| Some((x.effect, x.joint.as_ref()?.wald_z?)))
            .filter(|(_, z)| z.abs() >= l.z_critical)
            .collect();
        for (e, z) in &beyond {
            assert!(z.abs() < 4.0, "seed {seed}: {e} z {z}");
        }
        if !beyond.is_empty() {
            drives_with_a_discovery.push((seed, beyond));
        }
        // Every effect the positions carry has a limit on a mixed drive
        // (the flat route shows road grade's only through its speed and
        // acceleration, so it may have one or not).
        for x in l.effects.iter().filter(|x| x.effect != Effect::RoadGrade) {
            assert!(x.smallest.is_some(), "seed {seed}: {x:?}");
        }
        // The error model was refitted to what is left with every effect in.
        assert!(l.noise_refitted);
    }
    assert!(
        drives_with_a_discovery.len() <= 1,
        "{drives_with_a_discovery:?}"
    );
}

#[test]
fn the_wald_decision_holds_its_level_on_redraws_of_a_null_drive() {
    // Issue 37, item 2: the drive's GNSS errors redrawn from its own
    // fitted error model, the recorded (quantised) inputs kept, the
    // decision run on each redraw: the share with any effect called stays
    // at or below the nominal 5 % (allowing 2.5 binomial sigmas).
    let drive = drive_with(None, 11, VehicleKind::Saloon);
    let cfg = DiagnoseConfig {
        null_draws: 300,
        ..DiagnoseConfig::default()
    };
    let d = diagnose(&drive, &cfg).expect("diagnose");
    let r = d.null_false_alarm.expect("the redraws ran");
    assert_eq!(r.draws, 300);
    assert!(
        r.rate <= r.family_alpha + 2.5 * r.sigma,
        "false-alarm rate {} on {} redraws ({:?})",
        r.rate,
        r.draws,
        r.per_effect
    );
    let called: usize = r.per_effect.values().sum();
    assert!(called >= r.rejections, "{r:?}");
    // Without asking, none is computed.
    let plain = diagnose(&drive, &DiagnoseConfig::default()).expect("diagnose");
    assert!(plain.null_false_alarm.is_none());
}

#[test]
fn a_latency_under_wandering_gnss_is_read_whole() {
    // The latency's fingerprint is the dead-reckoning read earlier and
    // later: over a step of a few milliseconds that is the encoder's ticks
    // of one wheel sample, noise the Gauss-Markov whitening (nearly a
    // difference between fixes) keeps while it takes the smooth signal down
    // to its changes. With such a step this drive's 0.16 s was read at
    // 0.016 s beside its partners (0.071 s alone).
    let mut cfg = SimConfig::new(Scenario::Mixed, 1);
    cfg.vehicle = VehicleKind::Saloon;
    cfg.effects = EffectSettings::none();
    cfg.effects
        .set(Effect::GnssLatency, None, 0.16)
        .expect("latency");
    cfg.sensors.gnss.white_sigma_m = 0.02;
    cfg.sensors.gnss.gm_sigma_m = 1.0;
    let drive = simulate(&cfg).expect("simulate");
    let l = limit_of(&drive);
    let x = effect(&l, Effect::GnssLatency);
    let (alone, alone_sigma) = (x.estimate.expect("estimate"), x.sigma.expect("sigma"));
    assert!(
        (alone - 0.16).abs() <= 3.0 * alone_sigma,
        "alone {alone} ± {alone_sigma} against 0.16"
    );
    let j = x.joint.as_ref().expect("joint fit");
    let (free, free_sigma) = (
        j.estimate_all_free.or(j.estimate).expect("estimate"),
        j.sigma_all_free.or(j.sigma).expect("sigma"),
    );
    assert!(
        (free - 0.16).abs() <= 3.0 * free_sigma,
        "with every effect free {free} ± {free_sigma} against 0.16"
    );
}
