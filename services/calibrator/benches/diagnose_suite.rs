//! The concealed-effect suite of `calibrator diagnose` (issue 23): simulated
//! drives with effects the diagnosis is not told about, scored against the
//! simulator's truth.
//!
//! `cargo bench -p calibrator --bench diagnose_suite [-- --seeds N] [--quick] [--scale K] [--only] [--held-out-only] [--null-draws N] [--duration S]`
//!
//! `--scale K` puts every single effect in at K times the simulator's
//! typical size (the pairs, the paper case and the null drives as ever);
//! `--only` runs the single effects alone (no pairs, no paper case). Both
//! answer "from what size on does the diagnosis find it on these drives".
//!
//! Cases (the `mixed` scenario unless said otherwise, seeds 1..=N, the three
//! vehicles in turn):
//! - every catalogue effect alone at its typical magnitude;
//! - pairs that are easy to confuse;
//! - null drives: only the vehicle's inherent tyre physics (side-slip, load
//!   transfer, longitudinal slip at their defaults, documented in the
//!   truth), which the scoring allows to be found;
//! - the paper's future-work effect (load-dependent radius in corners) on
//!   the `paper` scenario.
//!
//! Per effect: detection (found), attribution (found under its own id, no
//! other id found), the recovered coefficient against truth, the held-out
//! position RMSE before and after; the false-discovery rate on null drives;
//! and the time per drive.

use calibrator::diagnose::{diagnose, DiagnoseConfig, Diagnosis};
use interfaces::effects::{Effect, Param};
use simulator::{simulate, EffectSettings, Scenario, SimConfig, VehicleKind};
use stats::distributions::normal_cdf;
use std::collections::BTreeMap;
use std::time::Instant;

/// The inherent tyre physics of every simulated car.
const INHERENT: [Effect; 3] = [
    Effect::SideSlip,
    Effect::LoadTransferRadius,
    Effect::LongitudinalSlip,
];

struct Case {
    label: String,
    scenario: Scenario,
    vehicle: VehicleKind,
    seed: u64,
    effects: EffectSettings,
    truth: Vec<Effect>,
    allowed: Vec<Effect>,
}

#[derive(Default)]
struct Tally {
    drives: usize,
    detected: usize,
    attributed: usize,
    false_ids: usize,
    coef_err: Vec<f64>,
    /// Findings: |estimate - truth| / the published sigma, and the same
    /// over the noise's part of it alone (the sigma without its model-form
    /// part, `Finding::form_sigmas`).
    coef_pull: Vec<(f64, f64)>,
    rmse_before: Vec<f64>,
    rmse_after: Vec<f64>,
    confused_with: BTreeMap<String, usize>,
    ambiguous: usize,
    /// Undetected drives: the smallest size the drive would have shown, as a
    /// multiple of the simulated one (`None`: not even 64x the typical).
    needed: Vec<Option<f64>>,
}

/// The information limit of the drives of one effect (the diagnosis's
/// `information_limit`), sizes as multiples of the simulated one.
#[derive(Default)]
struct LimitTally {
    drives: usize,
    /// The smallest size shown, the effect alone with the nuisances.
    alone: Vec<f64>,
    /// The same with every other effect of its source free.
    joint: Vec<f64>,
    /// The held-out test's detectable size, where it reported one.
    test: Vec<f64>,
    /// Drives where the joint Wald statistic is beyond the critical z.
    found: usize,
    /// Drives where another effect (not simulated, not allowed) is.
    wrong: usize,
    /// Joint estimate / truth, and |estimate - truth| / sigma.
    ratio: Vec<f64>,
    pull: Vec<f64>,
    /// Per drive, the power of the joint Wald test at the simulated size
    /// (its critical z in Holm's order): with the decision's sigma, and
    /// with the Fisher information's sigma alone.
    power: Vec<(f64, f64)>,
    /// Drives where the product named it (a finding).
    named: usize,
}

/// The chance that a two-sided Wald test at `z_critical` calls an effect of
/// true `size` whose estimate has `sigma`: what the drive's information
/// gives a test that decides on it, at the size it holds.
fn power_at(size: f64, sigma: f64, z_critical: f64) -> f64 {
    let d = size.abs() / sigma;
    normal_cdf(d - z_critical) + normal_cdf(-d - z_critical)
}

fn median_of(v: &[f64]) -> Option<f64> {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied()
}

/// The parameter an effect is scored by, in the diagnosis and in the
/// truth: the simulator's main parameter when the diagnosis reports it too,
/// else the diagnosis's main one (road grade: the gain on the measured
/// slope, 1 being the slope as simulated), and whether the diagnosis's
/// value is such a gain on the truth's.
fn main_param(e: Effect) -> (Param, Param, bool) {
    let truth = e.main_simulated();
    if e.spec().fitted.contains(&truth) {
        (truth, truth, false)
    } else {
        (e.main_fitted(), truth, true)
    }
}

fn cases(seeds: u64, quick: bool, scale: f64, only: bool) -> Vec<Case> {
    let vehicles = VehicleKind::ALL;
    let mut out = Vec::new();
    let mk = |label: String, scenario, seed: u64, on: &[Effect], base: EffectSettings| {
        let mut effects = base;
        for e in on {
            effects.switch_on(*e);
        }
        Case {
            label,
            scenario,
            vehicle: vehicles[(seed as usize) % vehicles.len()],
            seed,
            effects,
            truth: on.to_vec(),
            allowed: Vec::new(),
        }
    };
    let effects: Vec<Effect> = if quick {
        vec![Effect::TrackWidth, Effect::GnssLeverArm, Effect::GyroBias]
    } else {
        Effect::ALL.to_vec()
    };
    for seed in 1..=seeds {
        for e in &effects {
            let mut case = mk(
                e.id().to_string(),
                Scenario::Mixed,
                seed,
                &[*e],
                EffectSettings::none(),
            );
            if scale != 1.0 {
                let p = e.main_simulated();
                let v = p.spec().simulated;
                if case.effects.set(*e, Some(p), v * scale).is_err() {
                    println!("{}: cannot scale {} by {scale}", e.id(), p.spec().name);
                    continue;
                }
                case.label = format!("{} x{scale}", e.id());
            }
            out.push(case);
        }
        if !quick && !only {
            for (a, b) in [
                (Effect::SideSlip, Effect::GnssLeverArm),
                (Effect::LoadTransferRadius, Effect::TrackWidth),
                (Effect::SpeedRadiusGrowth, Effect::RadiusDrift),
                (Effect::LongitudinalSlip, Effect::GnssLatency),
            ] {
                out.push(mk(
                    format!("{a}+{b}"),
                    Scenario::Mixed,
                    seed,
                    &[a, b],
                    EffectSettings::none(),
                ));
            }
            let mut paper = mk(
                "paper: load_transfer_radius".into(),
                Scenario::Paper,
                seed,
                &[Effect::LoadTransferRadius],
                EffectSettings::none(),
            );
            paper.effects.load_transfer_radius = Some(simulator::LoadTransferRadius { k_z: 5e-4 });
            out.push(paper);
        }
        if only {
            continue;
        }
        let mut null = mk(
            "null (inherent physics)".into(),
            Scenario::Mixed,
            seed,
            &[],
            EffectSettings::default(),
        );
        null.allowed = INHERENT.to_vec();
        out.push(null);
        out.push(mk(
            "null (none at all)".into(),
            Scenario::Mixed,
            seed,
            &[],
            EffectSettings::none(),
        ));
    }
    out
}

fn truth_value(case: &Case, param: Param) -> Option<f64> {
    case.effects.get(param)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = args.iter().any(|a| a == "--quick");
    let seeds = args
        .iter()
        .position(|a| a == "--seeds")
        .and_then(|i| args.get(i + 1))
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    let num = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .and_then(|s| s.parse::<f64>().ok())
    };
    let scale = num("--scale").unwrap_or(1.0);
    let only = args.iter().any(|a| a == "--only");
    // Only the held-out test decides (as before Holm's procedure on the
    // joint Wald statistics joined it): for the before/after figures.
    let diagnose_cfg = DiagnoseConfig {
        wald_decision: !args.iter().any(|a| a == "--held-out-only"),
        ..DiagnoseConfig::default()
    };
    // The Wald decision's false-alarm rate on redraws of each null drive's
    // GNSS errors from its own error model (issue 37, item 2).
    let null_draws: usize = args
        .iter()
        .position(|a| a == "--null-draws")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    let mut redraws = (0usize, 0usize);
    // `--duration S`: the mixed scenario's cases driven as the `long`
    // scenario (the same city and ring road, round and round) for S
    // seconds: how the named share grows with the drive's length.
    let duration = num("--duration");
    let cases = cases(seeds, quick, scale, only);
    println!(
        "{} drives ({} seeds{}{})",
        cases.len(),
        seeds,
        if quick { ", quick" } else { "" },
        duration.map_or(String::new(), |d| format!(
            ", the mixed cases as the long scenario for {d:.0} s"
        ))
    );
    let mut tallies: BTreeMap<String, Tally> = BTreeMap::new();
    let mut null_drives = 0usize;
    let mut null_false = 0usize;
    let mut times = Vec::new();
    let mut limit_tallies: BTreeMap<String, LimitTally> = BTreeMap::new();
    // Null drives with the information limit, and those where the joint
    // Wald rule names an effect beyond the allowed ones.
    let mut limit_null = (0usize, 0usize);
    for case in &cases {
        let mut cfg = match duration {
            Some(d) if case.scenario == Scenario::Mixed => {
                let mut c = SimConfig::new(Scenario::Long, case.seed);
                c.duration_s = Some(d);
                c
            }
            _ => SimConfig::new(case.scenario, case.seed),
        };
        cfg.vehicle = case.vehicle;
        cfg.effects = case.effects;
        let drive = match simulate(&cfg) {
            Ok(d) => d,
            Err(e) => {
                println!("{}: simulation failed: {e}", case.label);
                continue;
            }
        };
        let t0 = Instant::now();
        let this_cfg = DiagnoseConfig {
            null_draws: if case.truth.is_empty() { null_draws } else { 0 },
            ..diagnose_cfg.clone()
        };
        let d: Diagnosis = match diagnose(&drive, &this_cfg) {
            Ok(d) => d,
            Err(e) => {
                println!("{} seed {}: diagnosis failed: {e}", case.label, case.seed);
                continue;
            }
        };
        times.push((t0.elapsed().as_secs_f64(), drive.wheel_duration_s()));
        let found: Vec<Effect> = d.findings.iter().map(|f| f.effect).collect();
        let extra: Vec<Effect> = found
            .iter()
            .copied()
            .filter(|e| !case.truth.contains(e) && !case.allowed.contains(e))
            .collect();
        let amb: Vec<Effect> = d.ambiguous.iter().flat_map(|a| a.effects.clone()).collect();
        println!(
            "{:<40} seed {} {:<7} found [{}] ambiguous [{}] pos RMSE {:.3} -> {:.3} m",
            case.label,
            case.seed,
            case.vehicle.name(),
            found.iter().map(|e| e.id()).collect::<Vec<_>>().join(", "),
            amb.iter().map(|e| e.id()).collect::<Vec<_>>().join(", "),
            d.fit.before.holdout_position_rmse_m,
            d.fit.after.holdout_position_rmse_m
        );
        if let Some(r) = &d.null_false_alarm {
            println!(
                "    redraws of its GNSS errors: {} of {} with an effect called ({:.1} % against {:.0} %)",
                r.rejections,
                r.draws,
                100.0 * r.rate,
                100.0 * r.family_alpha
            );
            redraws.0 += r.draws;
            redraws.1 += r.rejections;
        }
        if let Some(l) = &d.information_limit {
            let beyond: Vec<Effect> = l
                .effects
                .iter()
                .filter(|x| {
                    x.joint
                        .as_ref()
                        .and_then(|j| j.wald_z)
                        .is_some_and(|z| z.abs() >= l.z_critical)
                })
                .map(|x| x.effect)
                .collect();
            let wrong = beyond
                .iter()
                .any(|e| !case.truth.contains(e) && !case.allowed.contains(e));
            if case.truth.is_empty() {
                limit_null.0 += 1;
                limit_null.1 += usize::from(wrong);
            }
            for e in &case.truth {
                let Some(x) = l.effects.iter().find(|x| x.effect == *e) else {
                    continue;
                };
                let key = if case.truth.len() > 1 || case.scenario != Scenario::Mixed {
                    format!("{} [{}]", e.id(), case.label)
                } else {
                    e.id().to_string()
                };
                let t = limit_tallies.entry(key).or_default();
                t.drives += 1;
                t.found += usize::from(beyond.contains(e));
                t.named += usize::from(d.findings.iter().any(|f| f.effect == *e));
                t.wrong += usize::from(wrong);
                let (dp, tp, relative) = main_param(*e);
                // Sizes against the simulated one (a relative parameter's 1
                // is the simulated size); none where the limit is of another
                // parameter than the simulated one.
                let Some(sim) = truth_value(case, tp).filter(|v| *v != 0.0) else {
                    continue;
                };
                if dp != e.main_fitted() {
                    continue;
                }
                let rel = |v: f64| if relative { v } else { v / sim.abs() };
                t.alone.extend(x.smallest.map(rel));
                let j = x.joint.as_ref();
                t.joint.extend(j.and_then(|j| j.smallest).map(rel));
                if let Some((sg, sf)) = j.and_then(|j| Some((j.sigma?, j.sigma_fisher?))) {
                    if !relative {
                        let zc = d
                            .wald
                            .iter()
                            .find(|w| w.test.effect == *e)
                            .map_or(l.z_critical, |w| w.test.z_critical);
                        t.power.push((power_at(sim, sg, zc), power_at(sim, sf, zc)));
                    }
                }
                if let Some((v, sg)) = j.and_then(|j| Some((j.estimate?, j.sigma?))) {
                    if !relative {
                        t.ratio.push(v / sim);
                        t.pull.push((v - sim).abs() / sg);
                    }
                }
                if let Some(v) = d
                    .not_accepted
                    .iter()
                    .find(|n| n.effect == *e)
                    .and_then(|n| n.detectable.as_ref()?.smallest)
                {
                    t.test.push(rel(v));
                }
            }
        }
        if case.truth.is_empty() {
            null_drives += 1;
            if !extra.is_empty() {
                null_false += 1;
            }
            continue;
        }
        for e in &case.truth {
            let key = if case.truth.len() > 1 || case.scenario != Scenario::Mixed {
                format!("{} [{}]", e.id(), case.label)
            } else {
                e.id().to_string()
            };
            let t = tallies.entry(key).or_default();
            t.drives += 1;
            if !found.contains(e) {
                // How much of it this drive would have needed.
                let (_, tp, relative) = main_param(*e);
                let sim = truth_value(case, tp);
                let need = d
                    .not_accepted
                    .iter()
                    .find(|n| n.effect == *e)
                    .and_then(|n| n.detectable.clone());
                if let (Some(sim), Some(need)) = (sim, need) {
                    t.needed.push(need.smallest.map(|v| {
                        if relative {
                            // The gain on the slope: 1 is the simulated slope.
                            v
                        } else {
                            v / sim
                        }
                    }));
                }
            }
            if amb.contains(e) {
                t.ambiguous += 1;
            }
            if let Some(f) = d.findings.iter().find(|f| f.effect == *e) {
                t.detected += 1;
                if extra.is_empty() {
                    t.attributed += 1;
                }
                let (dp, tp, relative) = main_param(*e);
                if let (Some(v), Some(truth)) = (f.parameter(dp), truth_value(case, tp)) {
                    let est = if relative { v * truth } else { v };
                    t.coef_err.push(if truth != 0.0 {
                        (est - truth) / truth
                    } else {
                        est
                    });
                    if let Some(sg) = f.sigma(dp).filter(|s| *s > 0.0) {
                        let part = |m: &BTreeMap<String, f64>| {
                            m.get(dp.spec().name).copied().unwrap_or(0.0)
                        };
                        let (form, reading) = (part(&f.form_sigmas), part(&f.reading_sigmas));
                        let noise = (sg * sg - form * form - reading * reading).max(0.0).sqrt();
                        let scale = if relative { truth.abs() } else { 1.0 };
                        let off = (est - truth).abs();
                        t.coef_pull
                            .push((off / (sg * scale), off / (noise * scale)));
                    }
                }
            }
            for x in &extra {
                *t.confused_with.entry(x.id().to_string()).or_default() += 1;
            }
            t.false_ids += usize::from(!extra.is_empty());
            t.rmse_before.push(d.fit.before.holdout_position_rmse_m);
            t.rmse_after.push(d.fit.after.holdout_position_rmse_m);
        }
    }
    println!();
    println!("| effect | drives | detected | attributed | ambiguous | median rel. coef. error | findings within 2 sigma: published (noise part alone) | held-out pos. RMSE before -> after (mean) | other ids found | undetected: size needed (median, x simulated) |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (k, t) in &tallies {
        let mut errs = t.coef_err.clone();
        errs.sort_by(f64::total_cmp);
        let med = if errs.is_empty() {
            "-".to_string()
        } else {
            format!("{:+.0} %", 100.0 * errs[errs.len() / 2])
        };
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        let conf: Vec<String> = t
            .confused_with
            .iter()
            .map(|(k, n)| format!("{k} x{n}"))
            .collect();
        let needed = if t.needed.is_empty() {
            String::new()
        } else {
            let mut v: Vec<f64> = t
                .needed
                .iter()
                .map(|x| x.unwrap_or(f64::INFINITY))
                .collect();
            v.sort_by(f64::total_cmp);
            let m = v[v.len() / 2];
            format!(
                "{} ({} drives)",
                if m.is_finite() {
                    format!("{m:.1}x")
                } else {
                    "> 64x typical".to_string()
                },
                v.len()
            )
        };
        let covered = if t.coef_pull.is_empty() {
            "-".to_string()
        } else {
            let within =
                |f: fn(&(f64, f64)) -> f64| t.coef_pull.iter().filter(|p| f(p) < 2.0).count();
            format!(
                "{}/{n} ({}/{n})",
                within(|p| p.0),
                within(|p| p.1),
                n = t.coef_pull.len()
            )
        };
        println!(
            "| {k} | {} | {:.0} % | {:.0} % | {} | {med} | {covered} | {:.3} -> {:.3} m ({:+.0} %) | {} | {needed} |",
            t.drives,
            100.0 * t.detected as f64 / t.drives as f64,
            100.0 * t.attributed as f64 / t.drives as f64,
            t.ambiguous,
            mean(&t.rmse_before),
            mean(&t.rmse_after),
            100.0 * (mean(&t.rmse_after) / mean(&t.rmse_before) - 1.0),
            conf.join(", ")
        );
    }
    println!();
    println!(
        "null drives: {null_drives}, with a false discovery: {null_false} ({:.0} %)",
        100.0 * null_false as f64 / null_drives.max(1) as f64
    );
    if redraws.0 > 0 {
        let rate = redraws.1 as f64 / redraws.0 as f64;
        println!(
            "redraws of the null drives' GNSS errors from their own error models: {} of {} with an effect called by Holm's procedure: {:.2} % ± {:.2} % (nominal 5 %)",
            redraws.1,
            redraws.0,
            100.0 * rate,
            100.0 * (rate * (1.0 - rate) / redraws.0 as f64).sqrt()
        );
    }
    println!();
    println!("The information limit (`information_limit` of the diagnosis): medians over the drives, sizes as multiples of the simulated one.");
    println!();
    println!("| effect | drives | limit alone | limit, every effect free | held-out test needs | joint Wald: found | expected from the drives' information (Fisher's sigma alone) | the product found | wrong names | estimate / truth | abs(estimate - truth) / sigma |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    // Sums over the rows with a size: expected, its variance, expected
    // with Fisher's sigma, found by the joint Wald rule, named, drives.
    let mut totals = (0.0, 0.0, 0.0, 0, 0, 0);
    let x = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}x"));
    let plain = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
    for (k, t) in &limit_tallies {
        let expected = if t.power.is_empty() {
            "-".to_string()
        } else {
            let e: f64 = t.power.iter().map(|p| p.0).sum();
            let var: f64 = t.power.iter().map(|p| p.0 * (1.0 - p.0)).sum();
            let ef: f64 = t.power.iter().map(|p| p.1).sum();
            totals.0 += e;
            totals.1 += var;
            totals.2 += ef;
            totals.3 += t.found;
            totals.4 += t.named;
            totals.5 += t.drives;
            let of = if t.power.len() == t.drives {
                String::new()
            } else {
                format!(" (of {})", t.power.len())
            };
            format!("{e:.1} ± {:.1}{of} ({ef:.1})", var.sqrt())
        };
        println!(
            "| {k} | {} | {} | {} | {} ({}) | {}/{} | {expected} | {}/{} | {} | {} | {} |",
            t.drives,
            x(median_of(&t.alone)),
            x(median_of(&t.joint)),
            x(median_of(&t.test)),
            t.test.len(),
            t.found,
            t.drives,
            t.named,
            t.drives,
            t.wrong,
            plain(median_of(&t.ratio)),
            plain(median_of(&t.pull))
        );
    }
    println!(
        "| rows with a size, together | {} | | | | {}/{} | {:.1} ± {:.1} ({:.1}) | {}/{} | | | |",
        totals.5,
        totals.3,
        totals.5,
        totals.0,
        totals.1.sqrt(),
        totals.2,
        totals.4,
        totals.5
    );
    println!();
    println!("Expected from the drives' information: the sum over the drives of the power of the joint Wald test at the simulated size, |z| beyond the effect's critical z in Holm's order, with the joint sigma the decision uses (the larger of Fisher's under the refitted error model and the segments' scatter); ± the binomial spread; in brackets the same with Fisher's sigma alone. A row whose found count sits within that spread of the expected misses what its drives' information misses; one well below it loses what the data hold. Rows whose size is a gain on a measured signal (road grade) have none.");
    println!();
    println!(
        "joint Wald rule on null drives: {} of {} with an effect beyond the critical z (allowed physics aside)",
        limit_null.1, limit_null.0
    );
    let per_min: Vec<f64> = times.iter().map(|(s, d)| s / (d / 60.0)).collect();
    let total: f64 = times.iter().map(|t| t.0).sum();
    println!(
        "diagnosis time: {:.2} s per drive on average ({:.3} s per minute of drive), {:.0} s in all",
        total / times.len().max(1) as f64,
        per_min.iter().sum::<f64>() / per_min.len().max(1) as f64,
        total
    );
}
