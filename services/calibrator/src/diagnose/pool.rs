//! Several drives of one car: the car's effects (its tyres, geometry and
//! sensors' mounting: [`Scope::Car`]) are shared by every drive, the terms
//! of the day (circumference scale and left/right difference, the gyro's
//! bias, the warm-up, the road's grade, each segment's pose) are each
//! drive's own. Each drive's information about the car's effects, its own
//! terms profiled out ([`super::limit::DriveInformation`]), adds up; the
//! pooled estimate, its sigma (the larger of the Fisher information's and
//! the segments' scatter over every drive's segments), the smallest size
//! the drives together show, and Holm's procedure over the car's effects
//! decide what the car has. Each drive's share of the information says
//! which drive contributed what.
//!
//! Pure: the drives' information in, the pooled verdict out.

use super::decide::{decisive_tests, guard_passes, step_down, WaldDecision, WaldTest};
use super::limit::{
    joint_t, limit_of, partners_of, CoefFit, DriveInformation, EffectLimit, HeadingTerms,
    InformationSource, Joint, Partner, SegmentGram, FAMILY_ALPHA,
};
use interfaces::effects::{Effect, Scope};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use stats::distributions::{chi_square_quantile, t_quantile};

/// One car effect over the drives.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PooledEffect {
    /// The limit, estimate and Wald statistic of the drives together
    /// (alone, and in `joint` with every other car effect of its source).
    #[serde(flatten)]
    pub limit: EffectLimit,
    /// Per drive pooled (in the order given), its share of the information about
    /// the effect (the effect alone, the drive's own terms profiled out).
    pub information_share: Vec<f64>,
    /// Per drive pooled, its own estimate and sigma (reported unit; the
    /// same model as the pooled one), where it holds enough to fit it.
    pub per_drive: Vec<Option<[f64; 2]>>,
    /// Cochran's Q of the drives' estimates about the pooled one, and the
    /// value it may reach at the 5 % level (chi-square, one degree of
    /// freedom fewer than drives with an estimate): a car's effect is the
    /// same on every drive.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heterogeneity: Option<[f64; 2]>,
    /// The held-out guard over the drives: each drive's relative gain of
    /// its aggregate held-out error with the effect, weighed by the
    /// drives' information shares (for a significant effect).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout_gain: Option<f64>,
    /// What the drives say of the car.
    pub verdict: CarVerdict,
}

/// What several drives say of one of the car's effects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CarVerdict {
    /// Holm's procedure calls it significant, its estimate is plausible
    /// and the drives agree on it.
    Found,
    /// Not significant.
    NotShown,
    /// Significant, but the estimate lies outside the table's plausible
    /// range: something else is at work.
    Implausible,
    /// Significant, but the drives disagree beyond their sigmas (Cochran's
    /// Q): not one effect of the car.
    Inconsistent,
    /// Significant, but the drives' aggregate held-out errors do not fall
    /// with it ([`super::decide::guard_passes`], weighed over the drives):
    /// it may soak up a mismatch the model has elsewhere.
    Guarded,
    /// Beyond the critical z alone, not with its partners (`joint.partners`)
    /// free, none of which is found: the drives cannot tell them apart.
    Ambiguous,
}

/// The car's effects over several drives.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PooledLimit {
    /// Drives pooled.
    pub drives: usize,
    /// Segments over all drives.
    pub segments: usize,
    /// The family-wise level (two-sided), shared by the car's effects.
    pub family_alpha: f64,
    /// The |Wald z| a single effect needs at `family_alpha / effects`
    /// (Student t over the segments).
    pub z_critical: f64,
    /// Per car effect with information, in catalogue order.
    pub effects: Vec<PooledEffect>,
    /// Holm's procedure over the car's effects, largest |z| first.
    pub wald: Vec<WaldTest>,
}

impl PooledLimit {
    /// The car effects Holm's procedure calls significant.
    pub fn found(&self) -> impl Iterator<Item = &WaldTest> {
        self.wald.iter().filter(|t| t.significant)
    }

    /// The pooled effect `e`, if the drives hold information about it.
    pub fn effect(&self, e: Effect) -> Option<&PooledEffect> {
        self.effects.iter().find(|p| p.limit.effect == e)
    }
}

/// The car's effects over `drives` (at least one); `None` when the drives'
/// information cannot be pooled (no drive holds any).
pub fn pool(drives: &[&DriveInformation]) -> Option<PooledLimit> {
    let car: Vec<Effect> = Effect::ALL
        .into_iter()
        .filter(|e| e.spec().scope == Scope::Car)
        .collect();
    let sources = [
        InformationSource::PositionsWheelHeading,
        InformationSource::PositionsGyroHeading,
    ];
    let mut fits: Vec<Fits> = Vec::new();
    let mut segments = 0;
    for source in sources {
        let per_drive: Vec<_> = drives
            .iter()
            .filter_map(|d| d.grams.iter().find(|g| g.source == source))
            .collect();
        let Some(first) = per_drive.first() else {
            continue;
        };
        if per_drive.iter().any(|g| g.effects != first.effects) {
            return None;
        }
        let gram = SegmentGram::pooled(per_drive.iter().map(|g| &g.gram))?;
        segments = segments.max(gram.segments());
        let k = first.effects.len();
        for (i, e) in first.effects.iter().enumerate() {
            let c = i + 1;
            if gram.information(c) <= 0.0 {
                continue;
            }
            let alone = gram.fit(&[c]);
            let mut cols = vec![c];
            cols.extend((1..=k).filter(|&j| j != c && gram.information(j) > 0.0));
            let signed: Vec<usize> = cols[1..]
                .iter()
                .copied()
                .filter(|&j| first.effects[j - 1].sign_known())
                .collect();
            let (joint, held) = match gram.fit_within_signs(&cols, &signed) {
                Some((fit, held)) => (Some(fit), held),
                None => (None, Vec::new()),
            };
            let joint_free = if held.is_empty() {
                joint
            } else {
                gram.fit(&cols)
            };
            let others: Vec<(Effect, usize)> = cols[1..]
                .iter()
                .map(|&j| (first.effects[j - 1], j))
                .collect();
            let partners = alone.map_or_else(Vec::new, |a| {
                partners_of(
                    &gram,
                    &[c],
                    &a,
                    &others,
                    pooled_critical(drives_segments(drives)),
                )
            });
            // Each drive's own fit of the same model: the partners held at
            // zero over the drives held there too.
            let free: Vec<usize> = cols.iter().copied().filter(|j| !held.contains(j)).collect();
            let per_drive: Vec<Option<CoefFit>> = drives
                .iter()
                .map(|d| {
                    d.grams
                        .iter()
                        .find(|g| g.source == source)
                        .and_then(|g| g.gram.fit(&free))
                })
                .collect();
            let infos: Vec<f64> = drives
                .iter()
                .map(|d| {
                    d.grams
                        .iter()
                        .find(|g| g.source == source)
                        .map_or(0.0, |g| g.gram.information(c))
                })
                .collect();
            fits.push(Fits {
                effect: *e,
                source,
                alone,
                joint,
                shares: shares(&infos),
                per_drive,
                partners,
                held: held.iter().map(|&j| first.effects[j - 1]).collect(),
                joint_free,
            });
        }
    }
    // An effect both heading sources hold is pooled under the one that
    // knows it better (the smaller sigma of its decisive fit), as each
    // drive's own limit chooses.
    let sigma_of = |f: &Fits| {
        f.joint_free
            .or(f.joint)
            .or(f.alone)
            .map(|c| c.sigma())
            .filter(|s| s.is_finite() && *s > 0.0)
            .unwrap_or(f64::INFINITY)
    };
    let mut kept: Vec<Fits> = Vec::new();
    for f in fits {
        match kept.iter_mut().find(|k| k.effect == f.effect) {
            Some(k) if sigma_of(k) <= sigma_of(&f) => {}
            Some(k) => *k = f,
            None => kept.push(f),
        }
    }
    let mut fits = kept;
    // The heading sensor's bias: independent per drive, weighed by its
    // information.
    let heading: Vec<Option<CoefFit>> = drives.iter().map(|d| d.heading).collect();
    if let Some(h) = inverse_variance(&heading) {
        let infos: Vec<f64> = heading
            .iter()
            .map(|f| f.map_or(0.0, |f| f.sigma().powi(-2)))
            .collect();
        fits.push(Fits {
            effect: Effect::HeadingBias,
            source: InformationSource::HeadingChannel,
            alone: Some(h),
            joint: None,
            shares: shares(&infos),
            per_drive: heading,
            partners: Vec::new(),
            held: Vec::new(),
            joint_free: None,
        });
    }
    if fits.is_empty() {
        return None;
    }
    let dof = segments.saturating_sub(1) as f64;
    let z_critical = pooled_critical(segments);
    let mut effects: Vec<PooledEffect> = fits
        .into_iter()
        .map(|f| {
            let mut limit = limit_of(f.effect, f.alone, z_critical, f.source);
            // The fit with every partner free, once, when a partner was held.
            let free = (!f.held.is_empty())
                .then_some(f.joint_free)
                .flatten()
                .map(|a| Joint::of(f.effect, a, z_critical));
            limit.joint = f.joint.map(|j| Joint {
                partners: f.partners.clone(),
                held_at_zero: f.held.clone(),
                sigma_all_free: free.as_ref().and_then(|a| a.sigma),
                estimate_all_free: free.as_ref().and_then(|a| a.estimate),
                ..Joint::of(f.effect, j, z_critical)
            });
            let p = f.effect.main_fitted();
            let decisive = f.joint.or(f.alone);
            PooledEffect {
                limit,
                information_share: f.shares,
                per_drive: f
                    .per_drive
                    .iter()
                    .map(|d| d.map(|d| [p.to_display(d.estimate), p.to_display(d.sigma()).abs()]))
                    .collect(),
                heterogeneity: decisive.and_then(|c| cochran_q(c.estimate, &f.per_drive)),
                holdout_gain: None,
                verdict: CarVerdict::NotShown,
            }
        })
        .collect();
    // The compass bias's three terms over the drives (their precisions
    // added), tested together as one drive's are.
    if let Some(p) = effects
        .iter_mut()
        .find(|p| p.limit.effect == Effect::HeadingBias)
    {
        if let Some((terms, z)) = pooled_heading_terms(drives, dof) {
            let l = &p.limit;
            p.limit.joint = Some(Joint {
                smallest: l.smallest,
                estimate: l.estimate,
                sigma: l.sigma,
                sigma_fisher: l.sigma_fisher,
                sigma_segments: l.sigma_segments,
                wald_z: Some(z),
                partners: Vec::new(),
                terms: Some(terms),
                held_at_zero: Vec::new(),
                sigma_all_free: None,
                estimate_all_free: None,
            });
        }
    }
    for p in &mut effects {
        p.limit.set_power_at_typical(z_critical);
    }
    effects.sort_by_key(|p| car.iter().position(|e| *e == p.limit.effect));
    let wald = step_down(
        decisive_tests(effects.iter().map(|p| &p.limit)),
        FAMILY_ALPHA,
        dof,
    );
    for p in &mut effects {
        p.verdict = verdict(p, &wald);
    }
    // Shown alone, not beside partners none of which is found: ambiguous.
    let found: Vec<Effect> = effects
        .iter()
        .filter(|p| p.verdict == CarVerdict::Found)
        .map(|p| p.limit.effect)
        .collect();
    for p in &mut effects {
        let partners = p.limit.joint.as_ref().map_or(&[][..], |j| &j.partners[..]);
        if p.verdict == CarVerdict::NotShown
            && !partners.is_empty()
            && !partners.iter().any(|q| found.contains(&q.effect))
        {
            p.verdict = CarVerdict::Ambiguous;
        }
    }
    Some(PooledLimit {
        drives: drives.len(),
        segments,
        family_alpha: FAMILY_ALPHA,
        z_critical,
        wald,
        effects,
    })
}

/// The held-out guard over the drives (each drive's [`WaldDecision`]s, in
/// the order pooled): a found effect stays found only when the drives'
/// relative held-out gains, weighed by their information shares (and for
/// the wheels' heading their signed-rank z, combined by Stouffer's rule),
/// pass [`guard_passes`].
pub fn guard(car: &mut PooledLimit, per_drive: &[&[WaldDecision]]) {
    for p in car
        .effects
        .iter_mut()
        .filter(|p| p.verdict == CarVerdict::Found)
    {
        // Gains weighed by the shares; signed-rank z by Stouffer's rule.
        let (mut num, mut den, mut zn, mut zd) = (0.0, 0.0, 0.0, 0.0);
        for (w, share) in per_drive.iter().zip(&p.information_share) {
            let Some(d) = w.iter().find(|d| d.test.effect == p.limit.effect) else {
                continue;
            };
            if let Some(g) = d.holdout_gain {
                num += share * g;
                den += share;
            }
            if let Some(z) = d.holdout_z {
                zn += share * z;
                zd += share * share;
            }
        }
        let gain = (den > 0.0).then(|| num / den);
        let z = (zd > 0.0).then(|| zn / zd.sqrt());
        p.holdout_gain = gain;
        if !gain.is_some_and(|g| guard_passes(g, z, p.limit.source)) {
            p.verdict = CarVerdict::Guarded;
        }
    }
}

/// The compass bias's three terms pooled over the drives that hold them
/// (inverse-covariance weighed) and their joint |t| over all their blocks;
/// `None` unless at least one drive holds them.
fn pooled_heading_terms(drives: &[&DriveInformation], dof: f64) -> Option<(HeadingTerms, f64)> {
    let mut precision = DMatrix::<f64>::zeros(3, 3);
    let mut weighted = DVector::<f64>::zeros(3);
    let mut blocks = 0;
    for t in drives.iter().filter_map(|d| d.heading_terms.as_ref()) {
        let (theta, cov) = t.matrices();
        let inv = cov.cholesky()?.inverse();
        weighted += &inv * theta;
        precision += inv;
        blocks += t.blocks;
    }
    if blocks == 0 {
        return None;
    }
    let cov = precision.cholesky()?.inverse();
    let theta = &cov * weighted;
    let z = joint_t(&theta, &cov, blocks, dof)?;
    Some((
        HeadingTerms {
            estimate: [theta[0], theta[1], theta[2]],
            covariance: [0, 1, 2].map(|i| [0, 1, 2].map(|j| cov[(i, j)])),
            blocks,
        },
        z,
    ))
}

/// One car effect's fits: pooled alone and jointly, each drive's share
/// and own fit.
struct Fits {
    effect: Effect,
    source: InformationSource,
    alone: Option<CoefFit>,
    joint: Option<CoefFit>,
    shares: Vec<f64>,
    per_drive: Vec<Option<CoefFit>>,
    partners: Vec<Partner>,
    /// The partners held at zero in the joint fit (their sign's bound).
    held: Vec<Effect>,
    /// The joint fit with every partner free whatever its sign: the
    /// heading source is chosen by its sigma.
    joint_free: Option<CoefFit>,
}

/// The verdict on a pooled effect from Holm's procedure, the table's
/// plausible range and the drives' agreement.
fn verdict(p: &PooledEffect, wald: &[WaldTest]) -> CarVerdict {
    let l = &p.limit;
    if !wald.iter().any(|t| t.effect == l.effect && t.significant) {
        return CarVerdict::NotShown;
    }
    let spec = l.effect.main_fitted().spec();
    let shown = |v: f64| l.effect.main_fitted().to_display(v);
    let (lo, hi) = (shown(spec.plausible.0), shown(spec.plausible.1));
    let estimate = l.shown_fit().0.or(l.estimate);
    match (estimate, p.heterogeneity) {
        (Some(e), _) if e < lo.min(hi) || e > lo.max(hi) => CarVerdict::Implausible,
        (_, Some([q, limit])) if q > limit => CarVerdict::Inconsistent,
        _ => CarVerdict::Found,
    }
}

/// Cochran's Q of the drives' estimates about `pooled` and its 5 % point
/// (chi-square), with two drives or more.
fn cochran_q(pooled: f64, per_drive: &[Option<CoefFit>]) -> Option<[f64; 2]> {
    let fits: Vec<&CoefFit> = per_drive.iter().flatten().collect();
    if fits.len() < 2 {
        return None;
    }
    let q: f64 = fits
        .iter()
        .map(|f| ((f.estimate - pooled) / f.sigma()).powi(2))
        .sum();
    let k = (fits.len() - 1) as f64;
    Some([q, chi_square_quantile(0.95, k)])
}

/// The |z| one car effect needs at the family's level split among the
/// car's effects (Student t over `segments`).
fn pooled_critical(segments: usize) -> f64 {
    let car = Effect::ALL
        .iter()
        .filter(|e| e.spec().scope == Scope::Car)
        .count();
    t_quantile(
        1.0 - 0.5 * FAMILY_ALPHA / car as f64,
        segments.saturating_sub(1) as f64,
    )
}

/// The segments of the drives' wheel-heading information (the most any
/// source has).
fn drives_segments(drives: &[&DriveInformation]) -> usize {
    drives
        .iter()
        .map(|d| d.grams.iter().map(|g| g.gram.segments()).max().unwrap_or(0))
        .sum()
}

/// Each value's share of their sum (zeros without any).
fn shares(values: &[f64]) -> Vec<f64> {
    let sum: f64 = values.iter().sum();
    values
        .iter()
        .map(|v| if sum > 0.0 { v / sum } else { 0.0 })
        .collect()
}

/// Independent estimates of one value combined by their information.
fn inverse_variance(fits: &[Option<CoefFit>]) -> Option<CoefFit> {
    let fits: Vec<&CoefFit> = fits.iter().flatten().collect();
    let w: Vec<f64> = fits.iter().map(|f| f.sigma().powi(-2)).collect();
    let total: f64 = w.iter().sum();
    if fits.is_empty() || !(total > 0.0 && total.is_finite()) {
        return None;
    }
    let estimate = fits
        .iter()
        .zip(&w)
        .map(|(f, w)| f.estimate * w)
        .sum::<f64>()
        / total;
    let fisher: f64 = fits.iter().map(|f| f.sigma_fisher.powi(-2)).sum();
    Some(CoefFit {
        estimate,
        sigma_fisher: fisher.powf(-0.5),
        // The combined honest sigma: each drive's weighed in.
        sigma_segments: Some(total.powf(-0.5)),
    })
}
