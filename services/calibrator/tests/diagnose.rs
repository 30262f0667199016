//! The fast part of the concealed-effect suite (the whole sweep is the
//! `diagnose_suite` benchmark): simulated drives with an effect the diagnosis
//! is not told about, a drive with none, a drive too short to decide, the
//! real drives, and the command line.

use calibrator::diagnose::{diagnose, DiagnoseConfig, DiagnoseError};
use interfaces::effects::{Effect, Param};
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

/// A `mixed` drive of the saloon with a load transfer of `k_z` alone.
fn load_transfer_drive(seed: u64, k_z: f64) -> interfaces::drive::Drive {
    let mut cfg = SimConfig::new(Scenario::Mixed, seed);
    cfg.vehicle = VehicleKind::Saloon;
    cfg.effects = EffectSettings::none();
    cfg.effects.load_transfer_radius = Some(simulator::LoadTransferRadius { k_z });
    simulate(&cfg).expect("simulate")
}

/// The value of `param` the simulator put into `drive`.
fn truth(drive: &interfaces::drive::Drive, param: Param) -> f64 {
    drive
        .truth_params
        .as_ref()
        .and_then(|t| t.effect_param(param))
        .expect("truth")
}

#[test]
fn a_drive_with_nothing_left_out_gives_no_findings() {
    for (seed, vehicle) in [(1, VehicleKind::Saloon), (2, VehicleKind::Van)] {
        let d = diagnose(&drive_with(None, seed, vehicle), &DiagnoseConfig::default())
            .expect("diagnose");
        assert!(
            d.findings.is_empty(),
            "seed {seed}: {:?}",
            d.findings.iter().map(|f| f.effect).collect::<Vec<_>>()
        );
        assert_eq!(d.fit.before, d.fit.after);
        // Every effect tested says how large it would have to be. A track
        // error of the typical 2 % is found on every suite drive, so this
        // drive must say it would show one of that size or less.
        for n in &d.not_accepted {
            assert!(n.detectable.is_some(), "{n:?}");
        }
        let tw = d
            .not_accepted
            .iter()
            .find(|n| n.effect == Effect::TrackWidth)
            .and_then(|n| n.detectable.clone())
            .expect("track width tested");
        let smallest = tw.smallest.expect("a size that shows");
        assert!(smallest > 0.0 && smallest <= tw.typical, "{tw:?}");
    }
}

#[test]
fn a_concealed_track_width_is_found_named_and_sized_and_the_fit_improves() {
    let drive = drive_with(Some(Effect::TrackWidth), 3, VehicleKind::Compact);
    let truth = truth(&drive, Param::TrackRel);
    let d = diagnose(&drive, &DiagnoseConfig::default()).expect("diagnose");
    let ids: Vec<Effect> = d.findings.iter().map(|f| f.effect).collect();
    assert_eq!(ids, vec![Effect::TrackWidth], "{d:#?}");
    let f = &d.findings[0];
    let rel = f.parameter(Param::TrackRel).expect("rel");
    let sigma = f.sigma(Param::TrackRel).expect("rel sigma");
    assert!(
        (rel - truth).abs() < 0.25 * truth,
        "rel {rel} against {truth}"
    );
    assert!(
        sigma > 0.0 && (rel - truth).abs() < 4.0 * sigma + 0.002,
        "{rel} ± {sigma}"
    );
    assert!(
        f.holdout_rmse_after_m < 0.8 * f.holdout_rmse_before_m,
        "{f:?}"
    );
    assert!(d.fit.after.holdout_position_rmse_m < 0.8 * d.fit.before.holdout_position_rmse_m);
    // The JSON has the documented shape.
    let json = serde_json::to_value(&d).expect("json");
    for key in [
        "findings",
        "ambiguous",
        "unexplained",
        "mismatch_segments",
        "fit",
    ] {
        assert!(json.get(key).is_some(), "{key}");
    }
    assert_eq!(json["findings"][0]["effect"], "track_width");
    assert!(json["fit"]["before"]["holdout_position_rmse_m"].is_number());
}

#[test]
fn a_gnss_antenna_away_from_the_axle_is_found() {
    let d = diagnose(
        &drive_with(Some(Effect::GnssLeverArm), 1, VehicleKind::Saloon),
        &DiagnoseConfig::default(),
    )
    .expect("diagnose");
    let f = d
        .findings
        .iter()
        .find(|f| f.effect == Effect::GnssLeverArm)
        .unwrap_or_else(|| panic!("{d:#?}"));
    // Truth: 1.2 m forward.
    assert!(
        (f.parameter(Param::LeverArmX).expect("x_m") - 1.2).abs() < 0.3,
        "{f:?}"
    );
}

/// Our simulator's seed-3 compact drive with a side-slip and an antenna
/// 1.2 m ahead of the axle: corners at similar speeds, so the two are
/// barely told apart. The antenna is decided under the wheels' heading,
/// where the held-out guard asks most blocks to gain, and its gain sits in
/// the corners of a few (signed-rank z about 1.1): it was refused there at
/// a joint Wald z of 11. The gyro's heading shows it as well, and a bias of
/// the wheels' heading (what the ranks guard against) is not in that
/// reading, so it faces the gyro's guard: both effects are found.
#[test]
fn an_antenna_the_gyros_heading_shows_too_is_not_refused_for_its_ranks() {
    use calibrator::diagnose::decide::{guard_source, WaldOutcome, WHEEL_HEADING_GUARD_Z};
    use calibrator::diagnose::limit::InformationSource;
    use calibrator::diagnose::DecidedBy;
    let mut cfg = SimConfig::new(Scenario::Mixed, 3);
    cfg.vehicle = VehicleKind::Compact;
    cfg.effects = EffectSettings::none();
    cfg.effects.switch_on(Effect::SideSlip);
    cfg.effects.switch_on(Effect::GnssLeverArm);
    let drive = simulate(&cfg).expect("simulate");
    let d = diagnose(&drive, &DiagnoseConfig::default()).expect("diagnose");
    let found: Vec<Effect> = d.findings.iter().map(|f| f.effect).collect();
    assert_eq!(found.len(), 2, "{found:?}");
    let f = |e: Effect| {
        d.findings
            .iter()
            .find(|f| f.effect == e)
            .unwrap_or_else(|| panic!("{e} not found: {found:?}"))
    };
    // What the change is about: the antenna's held-out gain is shared by
    // too few blocks for the ranks, and the gyro's reading vouches for it.
    let antenna = f(Effect::GnssLeverArm);
    assert_eq!(antenna.decided_by, DecidedBy::Wald);
    let w = d
        .wald
        .iter()
        .find(|w| w.test.effect == Effect::GnssLeverArm)
        .expect("its Wald test");
    assert_eq!(w.outcome, WaldOutcome::Accepted);
    assert!(w.holdout_z.expect("ranks") < WHEEL_HEADING_GUARD_Z, "{w:?}");
    let limit = d.information_limit.as_ref().expect("limit");
    let l = limit
        .effects
        .iter()
        .find(|l| l.effect == Effect::GnssLeverArm)
        .expect("antenna's limit");
    assert_eq!(l.source, InformationSource::PositionsWheelHeading);
    assert_eq!(
        guard_source(limit, &w.test),
        InformationSource::PositionsGyroHeading
    );
    // The sizes. The side-slip is within 2 sigma of the truth; its sigma
    // has the linear form's part (it reads a_y), not the two readings'.
    // The antenna's finding (the held-out design's fit with the side-slip
    // beside it) is 0.96 m against 1.2; the positions alone read 1.09 m,
    // and the two readings' spread takes its sigma from 0.08 to 0.12 m,
    // which puts the truth at 2 sigma: asserted within 25 % and with
    // that part in its sigma.
    let slip = f(Effect::SideSlip);
    assert!(slip.reading_sigmas.is_empty(), "{slip:?}");
    assert!(!slip.form_sigmas.is_empty(), "{slip:?}");
    let part = antenna
        .reading_sigmas
        .get("x_m")
        .copied()
        .expect("x_m's part");
    let total = antenna.sigma(Param::LeverArmX).expect("sigma");
    assert!(part > 0.0 && part < total, "{part} of {total}");
    let (k, s) = (
        slip.parameter(Param::SideSlipGain).expect("k_beta"),
        slip.sigma(Param::SideSlipGain).expect("sigma"),
    );
    assert!(
        (k - truth(&drive, Param::SideSlipGain)).abs() < 2.0 * s,
        "{k} ± {s}"
    );
    let x = antenna.parameter(Param::LeverArmX).expect("x_m");
    let x_true = truth(&drive, Param::LeverArmX);
    assert!((x - x_true).abs() < 0.25 * x_true, "{x} against {x_true}");
    // And the held-out positions are predicted better with both.
    assert!(
        d.fit.after.holdout_position_rmse_m < d.fit.before.holdout_position_rmse_m,
        "{:?}",
        d.fit
    );
}

#[test]
fn a_load_transfer_is_sized_through_its_own_lateral_acceleration_not_confidently_low() {
    // The diagnosis reads a_y from the wheels' yaw rate, which the load
    // transfer itself bends by 2 k_z v^2 / t (73 % at 33 m/s). Read plainly,
    // the estimate came out 0.60x the truth with a sigma that did not
    // cover it (pull -6 on every seed). Read through the estimate, it must
    // land near the truth and the held-out error must drop the more for it.
    let truth = 5.25e-4;
    // Seed 5 is the one whose noise sigma alone left the widest pull (4.0).
    for seed in [2, 5] {
        let d = diagnose(
            &load_transfer_drive(seed, truth),
            &DiagnoseConfig::default(),
        )
        .expect("diagnose");
        let ids: Vec<Effect> = d.findings.iter().map(|f| f.effect).collect();
        assert_eq!(ids, vec![Effect::LoadTransferRadius], "seed {seed}: {d:#?}");
        let f = &d.findings[0];
        let k = f.parameter(Param::LoadTransferGain).expect("k_z");
        let sigma = f.sigma(Param::LoadTransferGain).expect("k_z sigma");
        assert!(
            (k - truth).abs() < 0.08 * truth,
            "seed {seed}: k_z {k} ± {sigma} against {truth}"
        );
        // Measured 3-5 % high on six seeds: the simulator's load transfer
        // acts through lagged suspension loads, not the instantaneous
        // linear form. The noise's sigma alone left pulls of 1.7-4.0; the
        // form's part (the estimate with a_y read from the gyro instead)
        // must make the published sigma cover it.
        let form = f
            .form_sigmas
            .get(Param::LoadTransferGain.spec().name)
            .copied()
            .expect("a form sigma: the drive has a gyro that follows the wheels");
        assert!(
            form > 0.0 && form < sigma,
            "seed {seed}: form {form}, sigma {sigma}"
        );
        let noise = (sigma * sigma - form * form).sqrt();
        assert!(
            (k - truth).abs() < 2.5 * sigma,
            "seed {seed}: k_z {k} ± {sigma} (noise part {noise}) against {truth}"
        );
        assert!(
            f.evidence.contains("a_y read through the estimate")
                && f.evidence.contains("read from the gyro instead"),
            "{}",
            f.evidence
        );
        // 15 m plain; 3.0 m with the estimate read plainly; about 1.4 m now.
        assert!(
            f.holdout_rmse_after_m < 0.15 * f.holdout_rmse_before_m,
            "seed {seed}: {} -> {}",
            f.holdout_rmse_before_m,
            f.holdout_rmse_after_m
        );
    }
}

#[test]
fn the_papers_future_work_effect_is_named_or_called_ambiguous_never_mistaken() {
    // The paper's course is driven near 60 km/h throughout, so load transfer
    // (v^2 w) and a track error (w) are nearly collinear there: the diagnosis
    // may name load transfer (with its size) or call the pair ambiguous, but
    // never report another effect.
    let mut cfg = SimConfig::new(Scenario::Paper, 1);
    cfg.effects = EffectSettings::none();
    cfg.effects.load_transfer_radius = Some(simulator::LoadTransferRadius { k_z: 5e-4 });
    let d = diagnose(
        &simulate(&cfg).expect("simulate"),
        &DiagnoseConfig::default(),
    )
    .expect("diagnose");
    let ids: Vec<Effect> = d.findings.iter().map(|f| f.effect).collect();
    assert!(
        ids.iter().all(|e| *e == Effect::LoadTransferRadius),
        "{ids:?}"
    );
    match d.findings.first() {
        Some(f) => {
            let k = f.parameter(Param::LoadTransferGain).expect("k_z");
            assert!((k - 5e-4).abs() < 0.3 * 5e-4, "k_z {k}");
            assert!(f.holdout_rmse_after_m < 0.8 * f.holdout_rmse_before_m);
        }
        None => {
            let amb = d
                .ambiguous
                .iter()
                .find(|a| a.effects.contains(&Effect::LoadTransferRadius))
                .unwrap_or_else(|| panic!("{d:#?}"));
            assert!(amb.effects.contains(&Effect::TrackWidth));
            assert!(
                amb.separate_by.contains("slowly and fast"),
                "{}",
                amb.separate_by
            );
        }
    }
}

#[test]
fn a_drive_too_short_is_refused_with_what_it_lacks() {
    let mut drive = drive_with(None, 1, VehicleKind::Saloon);
    drive.wheels.samples.retain(|s| s.t_s < 4.0);
    if let Some(g) = drive.gnss.as_mut() {
        g.retain(|s| s.t_s < 4.0);
    }
    match diagnose(&drive, &DiagnoseConfig::default()) {
        Err(DiagnoseError::TooShort(why)) => assert!(why.contains("at least"), "{why}"),
        Err(DiagnoseError::Calibration(e)) => {
            // The plain calibration refuses first: as clear.
            assert!(!e.to_string().is_empty());
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn the_real_drives_are_diagnosed() {
    for name in ["wid-trial02", "wid-trial04", "comma2k19-seg40"] {
        let Some(path) = drive_io::dev_data::real_drive(name) else {
            continue;
        };
        let drive = drive_io::read_drive(&path).expect("read").drive;
        let d = diagnose(&drive, &DiagnoseConfig::default()).expect(name);
        assert!(d.noise.blocks >= 4, "{name}");
        assert!(
            d.fit.after.holdout_position_rmse_m <= d.fit.before.holdout_position_rmse_m + 1e-12
        );
        // RTK or u-blox noise, measured from the fixes themselves.
        assert!(
            d.noise.gnss_sigma_m < 0.5,
            "{name}: {}",
            d.noise.gnss_sigma_m
        );
        // Every finding's margin against a rival partner carries the
        // held-out blocks' check, the finding's own gain as it entered.
        for f in &d.findings {
            for m in f.partners.iter().filter(|m| m.partner_alone_z.abs() > 1.96) {
                let [own, _] = m.holdout_gains.expect("the held-out check");
                assert!((own - f.holdout_channel_gain).abs() < 1e-12, "{name}");
            }
        }
        if name == "comma2k19-seg40" {
            // A highway drive whose fixes come 60-90 ms late by three
            // readings independent of the diagnosis. Its "longitudinal
            // slip" (named at joint z 8.9 over the latency) was the
            // latency's fingerprint taken over 4 ms, the CAN wheel speeds'
            // steps in it (errors in variables, `limit::LATENCY_STEP_S`):
            // no slip is named, and the latency alone reads within those
            // readings.
            assert!(
                !d.findings
                    .iter()
                    .any(|f| f.effect == Effect::LongitudinalSlip),
                "{:?}",
                d.findings.iter().map(|f| f.effect).collect::<Vec<_>>()
            );
            let l = d.information_limit.as_ref().expect("limit");
            let tau = l
                .effects
                .iter()
                .find(|e| e.effect == Effect::GnssLatency)
                .and_then(|e| e.estimate)
                .expect("latency");
            assert!((0.06..=0.1).contains(&tau), "{tau}");
        }
    }
}

#[test]
fn the_command_writes_json_pictures_and_an_index_page() {
    let dir = tempfile::tempdir().expect("tempdir");
    let drive_dir = dir.path().join("drive");
    drive_io::write_drive(
        &drive_with(Some(Effect::TrackWidth), 3, VehicleKind::Compact),
        &drive_dir,
    )
    .expect("write");
    let json = dir.path().join("d.json");
    let plots = dir.path().join("plots");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_calibrator"))
        .arg("diagnose")
        .arg(&drive_dir)
        .arg("--json")
        .arg(&json)
        .arg("--plots")
        .arg(&plots)
        .output()
        .expect("run");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("track_width"), "{stdout}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("json")).expect("parse");
    assert_eq!(v["findings"][0]["effect"], "track_width");
    // What the drive could show of every effect: in the JSON, the text and
    // the page.
    let limit = &v["information_limit"]["effects"];
    assert_eq!(
        limit.as_array().map(Vec::len),
        Some(Effect::ALL.len()),
        "{limit}"
    );
    assert!(limit[4]["effect"] == "track_width" && limit[4]["smallest"].is_number());
    assert!(stdout.contains("what this drive could show"), "{stdout}");
    let index = std::fs::read_to_string(plots.join("index.html")).expect("index");
    assert!(index.contains("track_width") && index.contains("<svg"));
    assert!(index.contains("the information limit"));
    assert!(plots.join("residual_track_width.svg").is_file());
    assert!(plots.join("tracks.svg").is_file());
}

#[test]
fn a_gnss_jump_is_reported_unexplained_not_forced_onto_an_effect() {
    // A multipath jump no catalogue effect describes: 4 m east for 3 s.
    let mut drive = drive_with(None, 2, VehicleKind::Van);
    let gnss = drive.gnss.as_mut().expect("gnss");
    let t0 = gnss[gnss.len() / 2].t_s;
    for g in gnss.iter_mut().filter(|g| g.t_s >= t0 && g.t_s < t0 + 3.0) {
        g.x_m += 4.0;
    }
    let d = diagnose(&drive, &DiagnoseConfig::default()).expect("diagnose");
    assert!(
        d.findings.is_empty(),
        "{:?}",
        d.findings.iter().map(|f| f.effect).collect::<Vec<_>>()
    );
    let jump = d
        .unexplained
        .iter()
        .find(|u| u.correlates_with.contains("GNSS jump"))
        .unwrap_or_else(|| panic!("{:#?}", d.unexplained));
    assert!(
        jump.t_start_s <= t0 + 3.0 && jump.t_end_s >= t0 - 1.0,
        "{jump:?} against {t0}"
    );
}

/// The live service's attempt with a diagnosis: the wheel-side terms of what
/// the diagnosis accepts travel with the estimate; without one they do not.
#[test]
fn a_live_attempt_with_a_diagnosis_carries_the_accepted_terms() {
    use calibrator::live::attempt;
    use calibrator::CalibrationConfig;
    let drive = drive_with(Some(Effect::TrackWidth), 3, VehicleKind::Compact);
    let truth = truth(&drive, Param::TrackRel);
    let nominal = vehicle_model::two_wheel::TwoWheelParams {
        c_rl: drive.vehicle.nominal_circumference_m,
        c_rr: drive.vehicle.nominal_circumference_m,
        track_width: drive.vehicle.track_width_m,
    };
    // The track kept at vehicle.toml's value: the diagnosis's term carries it.
    let cal = CalibrationConfig {
        track_width: calibrator::TrackWidthMode::Fixed,
        ..CalibrationConfig::default()
    };
    let dc = DiagnoseConfig::default();
    let with = attempt(&drive, &nominal, &cal, 0.3, 15.0, Some(&dc)).expect("attempt");
    let found = with.diagnosis.clone().expect("asked").expect("diagnosed");
    assert!(found.contains(&Effect::TrackWidth), "{found:?}");
    let rel = with.estimate.effects.track_rel;
    assert!(
        (rel - truth).abs() < 0.3 * truth,
        "rel {rel} against {truth}"
    );
    let without = attempt(&drive, &nominal, &cal, 0.3, 15.0, None).expect("attempt");
    assert!(without.diagnosis.is_none() && without.estimate.effects.is_plain());
    // Same circumferences either way: the diagnosis does not move the fit.
    assert_eq!(
        with.estimate.circumference_m,
        without.estimate.circumference_m
    );
    // A calibration that estimates the track itself keeps it; the
    // diagnosis's track term is not applied a second time.
    let fitted = attempt(
        &drive,
        &nominal,
        &CalibrationConfig::default(),
        0.3,
        15.0,
        Some(&dc),
    )
    .expect("attempt");
    let t = fitted.estimate.track_width_m / nominal.track_width - 1.0;
    assert!(
        (t - truth).abs() < 0.3 * truth,
        "fitted track {t} against {truth}"
    );
    assert_eq!(fitted.estimate.effects.track_rel, 0.0);
}

#[test]
fn the_gyros_reading_of_the_lateral_acceleration_is_the_one_the_wheels_bend() {
    // The second reading of a_y that the load transfer's model-form sigma
    // comes from: v (gz - bias), which no wheel-radius effect bends. With a
    // load transfer of k_z the wheels' v w is larger by 2 k_z v^2 / t; read
    // through k_z it is the gyro's again.
    use calibrator::diagnose::epochs;
    let k_z = 5.25e-4;
    let drive = load_transfer_drive(1, k_z);
    let truth = drive.truth_params.clone().expect("truth");
    let (c_rl, c_rr) = (truth.circumference_m.rl, truth.circumference_m.rr);
    let t = drive.vehicle.track_width_m;
    let revs = drive.wheel_revolutions().expect("revs");
    let at = |k: f64| epochs::build(&drive, &revs, c_rl, c_rr, t, 0.05, k);
    let (plain, through) = (at(0.0), at(k_z));
    let gyro = epochs::with_gyro_lateral(&plain, &revs, c_rl, c_rr, t)
        .expect("the simulated gyro follows the wheels");
    // Fast corners, where the bend is 20-70 %.
    let fast: Vec<usize> = (0..plain.epochs.len())
        .filter(|&i| {
            let (p, g) = (&plain.epochs[i], &gyro.epochs[i]);
            p.v_odo > 12.0 && g.a_y.abs() > 1.5 && p.a_y.is_finite() && g.a_y.is_finite()
        })
        .collect();
    assert!(fast.len() > 50, "{} fast corner epochs", fast.len());
    // The wheels' excess over the gyro's reading against 2 v^2 / t: slope k_z.
    let (sxy, sxx) = fast.iter().fold((0.0, 0.0), |(a, b), &i| {
        let (p, g) = (&plain.epochs[i], &gyro.epochs[i]);
        let x = 2.0 * p.v_odo * p.v_odo / t;
        (a + x * (p.a_y / g.a_y - 1.0), b + x * x)
    });
    let slope = sxy / sxx;
    assert!(
        (slope - k_z).abs() < 0.15 * k_z,
        "the wheels' a_y exceeds the gyro's as k_z = {slope:.3e} (truth {k_z:.1e})"
    );
    // Read through k_z, the wheels' a_y is the gyro's within a few percent.
    let mut ratios: Vec<f64> = fast
        .iter()
        .map(|&i| through.epochs[i].a_y / gyro.epochs[i].a_y)
        .collect();
    ratios.sort_by(f64::total_cmp);
    let median = ratios[ratios.len() / 2];
    assert!((median - 1.0).abs() < 0.03, "median ratio {median}");
}

#[test]
fn the_course_and_speed_channels_compare_a_chord_with_a_chord() {
    // The GNSS course over an interval is the direction of the
    // displacement, which in a corner being entered or left differs from
    // the heading at the middle fix by about w_dot T^2 / 6. Read against
    // that heading, the residual followed the yaw acceleration and put a
    // track error of +0.3-0.4 % (4 sigma) into the course channel of
    // drives with none. Against the wheels' own displacement over the same
    // interval (`course_odo`), nothing of it is left. The GNSS speed is the
    // chord's length over the interval, shorter than the wheels' arc by
    // (w T)^2 / 6 in a corner; against the wheels' chord (`v_chord`) that
    // is gone too.
    use calibrator::diagnose::epochs;
    let drive = drive_with(None, 5, VehicleKind::Van);
    let truth = drive.truth_params.clone().expect("truth");
    let (c_rl, c_rr) = (truth.circumference_m.rl, truth.circumference_m.rr);
    let revs = drive.wheel_revolutions().expect("revs");
    let ep = epochs::build(
        &drive,
        &revs,
        c_rl,
        c_rr,
        drive.vehicle.track_width_m,
        0.05,
        0.0,
    );
    let moving: Vec<&epochs::Epoch> = ep
        .epochs
        .iter()
        .filter(|e| e.v_odo > 5.0 && e.w_dot.is_finite())
        .collect();
    assert!(moving.len() > 1000, "{} moving epochs", moving.len());
    // Slope of a residual on w_dot, and its standard error (the residual's
    // drive-long trend and offset out by centring).
    let slope_on =
        |x: &dyn Fn(&epochs::Epoch) -> f64, res: &dyn Fn(&epochs::Epoch) -> f64| -> (f64, f64) {
            let n = moving.len() as f64;
            let (mx, my) = moving
                .iter()
                .fold((0.0, 0.0), |(a, b), e| (a + x(e) / n, b + res(e) / n));
            let (mut sxx, mut sxy) = (0.0, 0.0);
            for e in &moving {
                sxx += (x(e) - mx).powi(2);
                sxy += (x(e) - mx) * (res(e) - my);
            }
            let k = sxy / sxx;
            let ss: f64 = moving
                .iter()
                .map(|e| (res(e) - my - k * (x(e) - mx)).powi(2))
                .sum();
            (k, (ss / (n - 2.0) / sxx).sqrt())
        };
    let slope = |res: &dyn Fn(&epochs::Epoch) -> f64| slope_on(&|e| e.w_dot, res);
    let wrap = vehicle_model::two_wheel::wrap_angle;
    let (k_tangent, s_tangent) = slope(&|e| wrap(e.course_gnss - e.psi_odo));
    let (k_chord, s_chord) = slope(&|e| wrap(e.course_gnss - e.course_odo));
    let w2 = |e: &epochs::Epoch| e.w_odo * e.w_odo;
    let (k_arc, s_arc) = slope_on(&w2, &|e| e.v_gnss / e.v_odo - 1.0);
    let (k_vchord, s_vchord) = slope_on(&w2, &|e| e.v_gnss / e.v_chord - 1.0);
    eprintln!(
        "speed residual on w^2: arc {k_arc:.4} ± {s_arc:.4} s^2, chord {k_vchord:.4} ± {s_vchord:.4} s^2"
    );
    assert!(
        k_arc < -4.0 * s_arc,
        "against the arc the speed falls short in corners: {k_arc} ± {s_arc} s^2"
    );
    // What is left (+0.02 s^2 on this drive above 5 m/s, +0.08 above
    // 12 m/s) is not the chord's: the difference of the two slopes, the
    // chord's own T^2 / 6, is the same 0.17 s^2 in both speed ranges, so
    // the rest is the drive's (not traced).
    assert!(
        k_vchord.abs() < 0.2 * k_arc.abs(),
        "against the chord it does not: {k_vchord} ± {s_vchord} s^2 (arc {k_arc})"
    );
    eprintln!(
        "course residual on w_dot: middle heading {k_tangent:.4} ± {s_tangent:.4} s^2, \
         chord {k_chord:.4} ± {s_chord:.4} s^2"
    );
    assert!(
        k_tangent > 4.0 * s_tangent,
        "against the middle heading the residual follows w_dot: {k_tangent} ± {s_tangent} s^2"
    );
    assert!(
        k_chord.abs() < 3.0 * s_chord && k_chord.abs() < 0.2 * k_tangent,
        "against the chord it does not: {k_chord} ± {s_chord} s^2 (middle heading {k_tangent})"
    );
}

#[test]
fn a_latency_moves_the_dead_reckoned_points_of_every_block_never_drops_a_fix() {
    // The position columns are finite differences of the dead-reckoned
    // points at the same fixes. When a fix at t was placed at t - tau only
    // if the block's wheels reached back that far, a latency kick dropped
    // the block's first fix on most blocks and their latency column was
    // left empty: on a drive with low-noise GNSS the positions then put the
    // latency into an antenna offset and a slip.
    use calibrator::diagnose::{epochs, locate};
    use vehicle_model::effects::EffectTerms;
    let drive = drive_with(Some(Effect::GnssLatency), 2, VehicleKind::Van);
    let truth = drive.truth_params.clone().expect("truth");
    let (c_rl, c_rr) = (truth.circumference_m.rl, truth.circumference_m.rr);
    let track = drive.vehicle.track_width_m;
    let revs = drive.wheel_revolutions().expect("revs");
    let ep = epochs::build(&drive, &revs, c_rl, c_rr, track, 0.05, 0.0);
    let gnss = drive.gnss.as_deref().unwrap_or(&[]);
    let cx = locate::Context {
        revs: &revs,
        gnss,
        ep: &ep,
    };
    let model = |tau: f64| locate::Model {
        c_rl,
        c_rr,
        track_m: track,
        terms: EffectTerms {
            gnss_latency_s: tau,
            ..EffectTerms::default()
        },
        slip_side: 0,
    };
    let t0 = revs.first().map_or(0.0, |r| r.t_s);
    let block_s = 42.0;
    let mut blocks = 0;
    // Blocks inside the drive (the first and last have no wheels beyond
    // the drive's ends to place a late fix with).
    for b in 1..11 {
        // Block starts that fall between two fixes.
        let (a, z) = (
            t0 + 0.03 + b as f64 * block_s,
            t0 + 0.03 + (b + 1) as f64 * block_s,
        );
        for source in [locate::HeadingSource::Wheels, locate::HeadingSource::Gyro] {
            let Some(p0) = locate::dr_points(&model(0.0), source, &cx, a, z) else {
                continue;
            };
            for tau in [0.08, 0.25, -0.08] {
                let p1 = locate::dr_points(&model(tau), source, &cx, a, z).expect("points");
                assert_eq!(p0.t, p1.t, "block {b}, tau {tau}: the same fixes");
            }
            blocks += 1;
        }
    }
    assert!(blocks >= 18, "{blocks} blocks dead-reckoned");
}
