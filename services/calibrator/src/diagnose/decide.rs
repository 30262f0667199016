//! The decision on the likelihood: which effects the drive's positions
//! show beyond their own error model, with the family-wise error held by
//! Holm's step-down procedure over the effects' Wald statistics.
//!
//! Each effect's statistic is its joint Wald z from the information limit
//! ([`super::limit`]): the effect's estimate over its sigma with every
//! other effect of its information source free, so that an effect is named
//! against its partners (a GNSS latency against a side-slip) by the
//! likelihood, not by the order in which they entered. The sigma is the
//! larger of the Fisher information's under the drive's refitted GNSS error
//! model and the segments' own scatter, and the critical values are Student
//! t quantiles over the segments (the scatter of a dozen segments knows its
//! own size only roughly).
//!
//! Holm's procedure: sort the `m` statistics by size; the k-th largest
//! (k from 0) is significant when it and every larger one exceed the
//! two-sided critical value at `alpha / (m - k)`. It holds the family-wise
//! error at `alpha` whatever the dependence between the statistics, and is
//! never less powerful than Bonferroni.
//!
//! What the statistics cannot say, the guard says ([`guard_passes`]): an
//! effect the Wald test names enters the model only when it also lowers
//! the aggregate held-out error of the residual channels (the caller's
//! block cross-validation, summed over the blocks), so that a fingerprint
//! that merely soaks up a model mismatch elsewhere, and predicts the
//! blocks it was not fitted on worse, is not published as physics. The
//! guard judges the aggregate, not how many blocks win: an effect's gain
//! lives in the few blocks that hold its manoeuvre. One exception: an
//! effect decided on the dead-reckoning with the wheels' heading must also
//! gain on most blocks (signed-rank z above the one-sided 5 % point).
//! There the heading itself is modelled, and tyre physics beyond the
//! catalogue's forms turns it alike in every segment: the segments'
//! scatter cannot see such a bias, the aggregate gain is a sliver, and the
//! blocks' ranks are what tells it from an effect. Unless the gyro's
//! heading, which carries no such bias, shows the effect too: an effect
//! decided under the wheels' heading whose joint fit under the gyro's
//! heading is significant at the same critical z and of the same sign
//! faces the gyro's guard ([`guard_source`]).
//!
//! Pure: the limit in, the decisions out.

use super::design::{Candidate, Design};
use super::limit::{EffectLimit, InformationLimit, InformationSource};
use super::select::{gain, BlockStats, Gain};
use super::{model_columns, Ambiguous, How, Rejected, Selection};
use interfaces::effects::Effect;
use serde::Serialize;
use stats::distributions::t_quantile;

/// One effect's Wald test in Holm's order.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WaldTest {
    /// Catalogue id.
    pub effect: Effect,
    /// The Wald z the decision uses (joint where the limit has it).
    pub z: f64,
    /// Whether `z` is the joint one (every other effect of its source
    /// free) or the effect alone (its source has no partners).
    pub joint: bool,
    /// Its rank by |z| (0 the largest).
    pub rank: usize,
    /// The |z| Holm's procedure asks of this rank.
    pub z_critical: f64,
    /// Whether Holm's procedure calls it significant.
    pub significant: bool,
}

/// Holm's step-down procedure over the effects of `limit` with a Wald
/// statistic, at the limit's family-wise level; the tests in the order of
/// their |z|, largest first.
pub fn holm(limit: &InformationLimit) -> Vec<WaldTest> {
    let dof = limit.segments.saturating_sub(1) as f64;
    step_down(decisive_tests(&limit.effects), limit.family_alpha, dof)
}

/// The statistic each effect is decided on: `(effect, z, joint)`, the
/// joint Wald z where the limit has one, else the effect's alone.
pub(super) fn decisive_tests<'a>(
    limits: impl IntoIterator<Item = &'a EffectLimit>,
) -> Vec<(Effect, f64, bool)> {
    limits
        .into_iter()
        .filter_map(|e| match e.joint.as_ref().and_then(|j| j.wald_z) {
            Some(z) => Some((e.effect, z, true)),
            None => e.wald_z.map(|z| (e.effect, z, false)),
        })
        .filter(|(_, z, _)| z.is_finite())
        .collect()
}

/// Holm's procedure on `(effect, z, joint)`, in the order of |z|,
/// largest first.
pub(super) fn step_down(
    mut tests: Vec<(Effect, f64, bool)>,
    alpha: f64,
    dof: f64,
) -> Vec<WaldTest> {
    tests.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    let m = tests.len();
    let mut still = true;
    tests
        .iter()
        .enumerate()
        .map(|(k, &(effect, z, joint))| {
            let level = alpha / (m - k) as f64;
            let z_critical = t_quantile(1.0 - 0.5 * level, dof);
            still = still && z.abs() > z_critical;
            WaldTest {
                effect,
                z,
                joint,
                rank: k,
                z_critical,
                significant: still,
            }
        })
        .collect()
}

/// The held-out guard: adding the effect lowers the aggregate held-out
/// error of the residual channels (`holdout_gain`, the relative change of
/// the blocks' summed held-out error, positive); for an effect decided
/// under the wheels' heading, its gains' signed-rank z over the blocks
/// (`holdout_z`) is above [`WHEEL_HEADING_GUARD_Z`] as well (see the
/// module's text). A veto on what the Wald test called, not a second
/// test: the decision's level is Holm's.
pub fn guard_passes(holdout_gain: f64, holdout_z: Option<f64>, source: InformationSource) -> bool {
    let ranks = match source {
        InformationSource::PositionsWheelHeading => {
            holdout_z.is_some_and(|z| z > WHEEL_HEADING_GUARD_Z)
        }
        InformationSource::PositionsGyroHeading | InformationSource::HeadingChannel => true,
    };
    holdout_gain > 0.0 && ranks
}

/// The source whose guard the effect of Wald test `t` faces: the one it
/// was decided under, except an effect decided under the wheels' heading
/// that the gyro's heading shows as well (its joint fit there beyond the
/// test's critical z, of the same sign as the test's): it faces the gyro's
/// guard, the aggregate held-out gain without the ranks. The ranks guard
/// against a bias of the wheels' heading itself (tyre physics beyond the
/// catalogue's forms, alike in every segment); a reading of the same fixes
/// with the gyro's heading does not carry it. On our simulator's seed-3
/// drive with a side-slip and an antenna the antenna was called at Wald z
/// 11 under the wheels' heading and refused for its ranks (z 1.1): its
/// gain sits in the corners of a few blocks.
pub fn guard_source(limit: &InformationLimit, t: &WaldTest) -> InformationSource {
    let Some(l) = limit.effects.iter().find(|l| l.effect == t.effect) else {
        return InformationSource::PositionsWheelHeading;
    };
    match l.other_source {
        Some(o)
            if l.source == InformationSource::PositionsWheelHeading
                && o.source == InformationSource::PositionsGyroHeading
                && o.wald_z.abs() > t.z_critical
                && o.wald_z.signum() == t.z.signum() =>
        {
            o.source
        }
        _ => l.source,
    }
}

/// The signed-rank z the blocks' held-out gains need for an effect
/// decided under the wheels' heading: one-sided 5 %.
pub const WHEEL_HEADING_GUARD_Z: f64 = 1.6448536269514722;

/// What became of an effect's Wald test in the diagnosis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum WaldOutcome {
    /// Holm's procedure does not call it significant.
    NotSignificant,
    /// The held-out test had already accepted it.
    AlreadyFound,
    /// Significant, and the guard agrees: it entered the model.
    Accepted,
    /// Significant, but the held-out guard ([`guard_passes`]) refuses
    /// it: the fingerprint may soak up a mismatch the model has elsewhere.
    Guarded,
    /// Significant, but its coefficient lies outside the plausible range.
    Implausible,
    /// Significant, but the residual channels have no column for it on
    /// this drive (the manoeuvre it needs is missing from them).
    NoModel,
    /// Beyond the critical z alone, but not with its partners free, and
    /// none of them found: the drive cannot tell them apart (reported in
    /// `ambiguous` with the manoeuvre that would).
    Ambiguous,
}

impl WaldOutcome {
    /// In words.
    pub fn describe(self) -> &'static str {
        match self {
            WaldOutcome::NotSignificant => "not significant",
            WaldOutcome::AlreadyFound => "significant; found by the held-out test",
            WaldOutcome::Accepted => "significant; found",
            WaldOutcome::Guarded => "significant; refused by the held-out guard",
            WaldOutcome::Implausible => "significant; implausible size",
            WaldOutcome::NoModel => "significant; no residual column on this drive",
            WaldOutcome::Ambiguous => "ambiguous with its partners",
        }
    }
}

/// An effect's Wald test and what the diagnosis made of it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WaldDecision {
    /// The test.
    #[serde(flatten)]
    pub test: WaldTest,
    /// What became of it.
    pub outcome: WaldOutcome,
    /// The relative change of the aggregate held-out error of the residual
    /// channels when it is added (positive: lower): the guard's, or for an
    /// effect it did not judge, against the final model.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout_gain: Option<f64>,
    /// The signed-rank z of that gain over the blocks.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout_z: Option<f64>,
    /// The t statistic of the blocks' gains (their mean over its standard
    /// error).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout_t: Option<f64>,
}

/// The variant of `effect` whose addition to the model `base` gains most
/// on held-out blocks, and its gain; `None` without a candidate. A variant
/// fitted on the gyro's channels alone ([`Candidate::seen_by_gyro`]) is tried only
/// for an effect decided under the gyro's heading (`source`).
fn best_variant(
    design: &Design,
    stats: &BlockStats,
    base: &[usize],
    effect: Effect,
    source: InformationSource,
) -> Option<(usize, Gain)> {
    let current = stats.cv_errors(base);
    let gyro = source == InformationSource::PositionsGyroHeading;
    design
        .candidates
        .iter()
        .enumerate()
        .filter(|(_, c)| c.effect == effect && (gyro || !c.seen_by_gyro()))
        .map(|(i, c)| {
            let mut cols = base.to_vec();
            cols.extend(c.columns.iter().copied());
            (i, gain(&current, &stats.cv_errors(&cols)))
        })
        .max_by(|a, b| a.1.relative.total_cmp(&b.1.relative))
}

/// Adds to the held-out selection `sel` every effect Holm's procedure
/// calls significant that the guard lets in (a positive aggregate held-out
/// gain over the model so far, a plausible coefficient), in the order of
/// their |z|; an effect the held-out test found ambiguous with partners and
/// the joint test names is named (its ambiguity dropped). Returns what
/// became of every test.
pub(super) fn apply(
    design: &Design,
    stats: &BlockStats,
    sel: &mut Selection,
    tests: &[WaldTest],
    limit: &InformationLimit,
) -> Vec<WaldDecision> {
    let mut out = Vec::new();
    // Refused by the guard one at a time: (index in `out`, the variant tried).
    let mut guarded: Vec<(usize, usize)> = Vec::new();
    for t in tests {
        let decided = |outcome, g: Option<Gain>| WaldDecision {
            test: t.clone(),
            outcome,
            holdout_gain: g.map(|g| g.relative),
            holdout_z: g.map(|g| g.z),
            holdout_t: g.map(|g| g.t),
        };
        let accepted_effect = |sel: &Selection| {
            sel.accepted
                .iter()
                .any(|&i| design.candidates[i].effect == t.effect)
        };
        if !t.significant {
            out.push(decided(WaldOutcome::NotSignificant, None));
            continue;
        }
        if accepted_effect(sel) {
            out.push(decided(WaldOutcome::AlreadyFound, None));
            continue;
        }
        if sel.rejected.iter().any(|r| r.effect == t.effect) {
            out.push(decided(WaldOutcome::Implausible, None));
            continue;
        }
        let source = source_of(limit, t.effect);
        let base = model_columns(design, &sel.accepted);
        let best = best_variant(design, stats, &base, t.effect, source);
        let Some((ci, g)) = best else {
            out.push(decided(WaldOutcome::NoModel, None));
            continue;
        };
        if !guard_passes(g.relative, Some(g.z), guard_source(limit, t)) {
            guarded.push((out.len(), ci));
            out.push(decided(WaldOutcome::Guarded, Some(g)));
            continue;
        }
        let bad = implausible(stats, &base, &design.candidates[ci]);
        if !bad.is_empty() {
            sel.rejected.push(Rejected {
                effect: t.effect,
                reason: format!(
                    "its joint Wald z = {:.1} passes Holm's {:.1} but {}",
                    t.z,
                    t.z_critical,
                    bad.join("; ")
                ),
            });
            out.push(decided(WaldOutcome::Implausible, Some(g)));
            continue;
        }
        sel.accepted.push(ci);
        sel.gains.push(g);
        sel.thresholds.push(t.z_critical);
        sel.how.push(How::Wald(t.clone()));
        sel.ambiguous.retain(|a| !a.effects.contains(&t.effect));
        sel.last_round.retain(|n| n.effect != t.effect);
        sel.untestable.retain(|(e, _)| *e != t.effect);
        out.push(decided(WaldOutcome::Accepted, Some(g)));
    }
    enter_together(design, stats, sel, &mut out, &guarded, limit);
    // The guard of every other effect against the final model: what
    // pooling over drives weighs ([`super::pool`]).
    let base = model_columns(design, &sel.accepted);
    for d in out.iter_mut().filter(|d| d.holdout_z.is_none()) {
        let entered = sel
            .accepted
            .iter()
            .position(|&i| design.candidates[i].effect == d.test.effect);
        let g = match entered {
            // Found: the gain it entered with.
            Some(k) => sel.gains.get(k).copied(),
            None => best_variant(
                design,
                stats,
                &base,
                d.test.effect,
                source_of(limit, d.test.effect),
            )
            .map(|(_, g)| g),
        };
        if let Some(g) = g {
            d.holdout_gain = Some(g.relative);
            d.holdout_z = Some(g.z);
            d.holdout_t = Some(g.t);
        }
    }
    // Effects shown alone but not beside partners none of which is found.
    for d in out
        .iter_mut()
        .filter(|d| d.outcome == WaldOutcome::NotSignificant)
    {
        let Some(partners) = limit
            .effects
            .iter()
            .find(|l| l.effect == d.test.effect)
            .and_then(|l| l.joint.as_ref())
            .map(|j| &j.partners)
            .filter(|p| !p.is_empty())
        else {
            continue;
        };
        let found = |e: Effect| {
            sel.accepted
                .iter()
                .any(|&i| design.candidates[i].effect == e)
                || sel.ambiguous.iter().any(|a| a.effects.contains(&e))
        };
        if found(d.test.effect) || partners.iter().any(|p| found(p.effect)) {
            continue;
        }
        let e = d.test.effect;
        sel.ambiguous.push(Ambiguous {
            effects: std::iter::once(e)
                .chain(partners.iter().map(|p| p.effect))
                .collect(),
            vif: partners.iter().map(|p| p.vif).fold(0.0, f64::max),
            separate_by: partners
                .iter()
                .map(|p| e.separate_from(p.effect))
                .collect::<Vec<_>>()
                .join("; "),
        });
        d.outcome = WaldOutcome::Ambiguous;
    }
    out
}

/// The source `effect` was decided under in `limit` (the wheels' heading
/// when it has none there).
fn source_of(limit: &InformationLimit, effect: Effect) -> InformationSource {
    limit
        .effects
        .iter()
        .find(|l| l.effect == effect)
        .map_or(InformationSource::PositionsWheelHeading, |l| l.source)
}

/// The effects Holm's procedure calls significant and the guard refused
/// one at a time (`guarded`: index in `out`, the variant tried), tried
/// together: the Wald test called each significant with the others free,
/// so the guard judges the model it spoke of. Partners a drive barely
/// tells apart (a side-slip and an antenna's offset in corners taken at
/// similar speeds) each predict the held-out blocks worse alone, the one
/// soaking up the other's fingerprint, and better together. The set
/// passes [`guard_passes`] as one (the ranks asked when any of it is
/// decided under the wheels' heading); each member must add to the set's
/// gain (the set without it gains less) and keep a plausible coefficient
/// beside the others. All enter, or none.
fn enter_together(
    design: &Design,
    stats: &BlockStats,
    sel: &mut Selection,
    out: &mut [WaldDecision],
    guarded: &[(usize, usize)],
    limit: &InformationLimit,
) {
    if guarded.len() < 2 {
        return;
    }
    let wheels = guarded.iter().any(|&(k, _)| {
        guard_source(limit, &out[k].test) == InformationSource::PositionsWheelHeading
    });
    let source = if wheels {
        InformationSource::PositionsWheelHeading
    } else {
        InformationSource::PositionsGyroHeading
    };
    let base = model_columns(design, &sel.accepted);
    let members: Vec<usize> = guarded.iter().map(|&(_, ci)| ci).collect();
    let Some(g) = together(design, stats, &base, &members, source) else {
        return;
    };
    for &(k, ci) in guarded {
        let d = &mut out[k];
        d.outcome = WaldOutcome::Accepted;
        d.holdout_gain = Some(g.relative);
        d.holdout_z = Some(g.z);
        d.holdout_t = Some(g.t);
        let effect = d.test.effect;
        sel.accepted.push(ci);
        sel.gains.push(g);
        sel.thresholds.push(d.test.z_critical);
        sel.how.push(How::Wald(d.test.clone()));
        sel.ambiguous.retain(|a| !a.effects.contains(&effect));
        sel.last_round.retain(|n| n.effect != effect);
        sel.untestable.retain(|(e, _)| *e != effect);
    }
}

/// The held-out gain of the candidates `members` added together to the
/// model `base`, when the set passes the guard as one (under `source`),
/// every member adds to it (the set without it gains less) and keeps a
/// plausible coefficient beside the others; else `None`.
fn together(
    design: &Design,
    stats: &BlockStats,
    base: &[usize],
    members: &[usize],
    source: InformationSource,
) -> Option<Gain> {
    let current = stats.cv_errors(base);
    let with = |skip: Option<usize>| {
        let mut cols = base.to_vec();
        for (k, &ci) in members.iter().enumerate() {
            if Some(k) != skip {
                cols.extend(design.candidates[ci].columns.iter().copied());
            }
        }
        cols
    };
    let g = gain(&current, &stats.cv_errors(&with(None)));
    if !guard_passes(g.relative, Some(g.z), source) {
        return None;
    }
    for (k, &ci) in members.iter().enumerate() {
        let others = with(Some(k));
        if gain(&current, &stats.cv_errors(&others)).relative >= g.relative
            || !implausible(stats, &others, &design.candidates[ci]).is_empty()
        {
            return None;
        }
    }
    Some(g)
}

/// The parameters of `cand` whose coefficient, fitted with `base` on all
/// blocks, lies outside the plausible range, in words.
pub(super) fn implausible(stats: &BlockStats, base: &[usize], cand: &Candidate) -> Vec<String> {
    let mut cols = base.to_vec();
    cols.extend(cand.columns.iter().copied());
    let Some(beta) = stats.fit(&cols, |_| true) else {
        return Vec::new();
    };
    cand.params
        .iter()
        .filter_map(|p| {
            let i = cols.iter().position(|&c| c == p.column)?;
            let v = beta[i];
            (v < p.range.0 || v > p.range.1).then(|| {
                format!(
                    "{} = {:.4e} {} lies outside the plausible {:.1e}..{:.1e}",
                    p.name, v, p.unit, p.range.0, p.range.1
                )
            })
        })
        .collect()
}

/// A found effect against one of its catalogue partners (an effect the
/// catalogue lists as confusable with it, either way round): each alone
/// under the information source the found effect was decided under, and
/// the partner's fit with every other effect of that source free, the
/// found one included. The name is chosen by the joint likelihood
/// ([`holm`]); this says by how much the two one-effect explanations
/// differ, and what would settle it where the margin is thin.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PartnerMargin {
    /// The partner.
    pub effect: Effect,
    /// The found effect alone (the nuisances profiled out), its Wald z.
    pub found_alone_z: f64,
    /// The partner alone under the same source, its Wald z.
    pub partner_alone_z: f64,
    /// `found_alone_z^2 - partner_alone_z^2`: twice the log-likelihood
    /// ratio of the found effect alone against the partner alone, each one
    /// parameter on the same fixes (positive: the fixes prefer the found
    /// effect).
    pub margin: f64,
    /// The partner's estimate, sigma (reported unit) and z with every
    /// other effect free, where the fit exists.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub partner_joint: Option<[f64; 3]>,
    /// The manoeuvre that would tell the two apart.
    pub separate_by: String,
    /// The held-out blocks' relative gain with the found effect and with
    /// the partner instead, each added to the model the found effect
    /// entered ([`holdout_against_partners`]): a check on the name that
    /// does not rest on the error model.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout_gains: Option<[f64; 2]>,
}

/// Fills each margin's [`PartnerMargin::holdout_gains`]: the held-out gain
/// of `effect` (`found_gain`, the gain it entered with) and of the partner
/// instead (its best variant), both added to the model `base` the found
/// effect entered.
pub(super) fn holdout_against_partners(
    design: &Design,
    stats: &BlockStats,
    base: &[usize],
    limit: &InformationLimit,
    found_gain: f64,
    margins: &mut [PartnerMargin],
) {
    for m in margins.iter_mut() {
        let source = source_of(limit, m.effect);
        if let Some((_, g)) = best_variant(design, stats, base, m.effect, source) {
            m.holdout_gains = Some([found_gain, g.relative]);
        }
    }
}

/// `effect`'s margins against its catalogue partners in `limit`: those
/// whose fit alone exists under the source `effect` is decided under.
pub fn partner_margins(effect: Effect, limit: &InformationLimit) -> Vec<PartnerMargin> {
    let Some(own) = limit.effects.iter().find(|l| l.effect == effect) else {
        return Vec::new();
    };
    let Some(own_z) = own.wald_z.filter(|z| z.is_finite()) else {
        return Vec::new();
    };
    limit
        .effects
        .iter()
        .filter(|l| {
            l.effect != effect
                && effect.partner_manoeuvre(l.effect).is_some()
                && l.source == own.source
        })
        .filter_map(|l| {
            let z = l.wald_z.filter(|z| z.is_finite())?;
            let partner_joint = l
                .joint
                .as_ref()
                .and_then(|j| Some([j.estimate?, j.sigma?, j.wald_z?]));
            Some(PartnerMargin {
                effect: l.effect,
                found_alone_z: own_z,
                partner_alone_z: z,
                margin: own_z * own_z - z * z,
                partner_joint,
                separate_by: effect.separate_from(l.effect),
                holdout_gains: None,
            })
        })
        .collect()
}

/// The margins in words, for a finding's evidence: only partners that
/// alone would pass a two-sided 5 % test (|z| above 1.96), a rival worth
/// naming; `None` when there is none.
pub fn margins_in_words(
    margins: &[PartnerMargin],
    unit_of: &dyn Fn(Effect) -> String,
) -> Option<String> {
    let words: Vec<String> = margins
        .iter()
        .filter(|m| m.partner_alone_z.abs() > 1.96)
        .map(|m| {
            let joint = m.partner_joint.map_or(String::new(), |[e, s, z]| {
                format!(
                    "; {} with it free {e:.3e} ± {s:.1e} {} (z {z:.1})",
                    m.effect,
                    unit_of(m.effect)
                )
            });
            let held_out = m.holdout_gains.map_or(String::new(), |[a, b]| {
                format!(
                    "; the held-out blocks gain {:.1} % with it and {:.1} % with {} instead{}",
                    100.0 * a,
                    100.0 * b,
                    m.effect,
                    if b >= a {
                        ": they do not bear the name out, which rests on the error model's \
                         likelihood alone"
                    } else {
                        ""
                    }
                )
            });
            format!(
                "named over {} (a catalogue partner) by a likelihood margin of {:.0} in \
                 chi-square: alone z {:.1} against {:.1}{joint}{held_out}; what would tell \
                 them apart: {}",
                m.effect, m.margin, m.found_alone_z, m.partner_alone_z, m.separate_by
            )
        })
        .collect();
    (!words.is_empty()).then(|| words.join("; "))
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::design::{Channel, SEEN_BY_GYRO};
    use super::*;

    fn sorted(zs: &[f64]) -> Vec<(Effect, f64, bool)> {
        let mut v: Vec<(Effect, f64, bool)> = zs
            .iter()
            .zip(Effect::ALL)
            .map(|(z, e)| (e, *z, true))
            .collect();
        v.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
        v
    }

    /// Two course channels, twelve blocks: the gyro's course shows a
    /// side-slip of `k` (course = heading - k a_y), the wheels' course the
    /// opposite, as tyres that turn the wheels' heading beyond the model
    /// do; white noise on both.
    fn two_headings(k: f64) -> Design {
        use super::super::design::Param;
        use interfaces::effects::Param as EffectParam;
        let mut rng = crate::error_model::Normal::new(11);
        let (mut rows, mut y, mut whole, mut gyro_only) = (vec![], vec![], vec![], vec![]);
        for b in 0..12 {
            for i in 0..200 {
                let a_y = 3.0 * ((i as f64) * 0.07 + b as f64).sin();
                for ch in [Channel::CourseGyro, Channel::CourseWheel] {
                    let sign = if ch == Channel::CourseGyro { 1.0 } else { -1.0 };
                    rows.push((ch, i, b));
                    y.push(-sign * k * a_y + 0.002 * rng.next());
                    whole.push(-a_y);
                    gyro_only.push(if ch == Channel::CourseGyro { -a_y } else { 0.0 });
                }
            }
        }
        let cand = |variant: &str, c: usize| Candidate {
            effect: Effect::SideSlip,
            variant: variant.to_string(),
            columns: vec![c],
            params: vec![Param::of(EffectParam::SideSlipGain, c)],
        };
        twelve_blocks(
            rows,
            y,
            vec![whole, gyro_only],
            vec!["side_slip".into(), "side_slip (gyro heading)".into()],
            vec![cand("", 0), cand(SEEN_BY_GYRO, 1)],
        )
    }

    /// A design of twelve 60 s blocks with unit weights and no nuisance.
    fn twelve_blocks(
        rows: Vec<(Channel, usize, usize)>,
        y: Vec<f64>,
        columns: Vec<Vec<f64>>,
        column_names: Vec<String>,
        candidates: Vec<Candidate>,
    ) -> Design {
        let n = rows.len();
        Design {
            rows,
            y,
            w: vec![1.0; n],
            columns,
            column_names,
            nuisance: Vec::new(),
            candidates,
            untestable: Vec::new(),
            blocks: 12,
            block_s: 60.0,
            channel_sigma: Vec::new(),
            whitening: Vec::new(),
        }
    }

    #[test]
    fn a_side_slip_the_gyro_shows_is_judged_on_the_gyros_channels_only_when_decided_there() {
        let d = two_headings(0.003);
        let stats = BlockStats::new(&d);
        // Decided under the gyro's heading: the variant on its channels
        // gains, and its coefficient is the gyro's side-slip.
        let (ci, g) = best_variant(
            &d,
            &stats,
            &[],
            Effect::SideSlip,
            InformationSource::PositionsGyroHeading,
        )
        .unwrap();
        assert_eq!(d.candidates[ci].variant, SEEN_BY_GYRO);
        assert!(g.relative > 0.3 && g.z > 2.0, "{g:?}");
        let beta = stats.fit(&d.candidates[ci].columns, |_| true).unwrap();
        assert!((beta[0] - 0.003).abs() < 1e-4, "{beta}");
        // The whole column's coefficient is the two channels' compromise
        // (about zero here): it gains nothing.
        let whole = stats.fit(&[0], |_| true).unwrap();
        assert!(whole[0].abs() < 2e-4, "{whole}");
        // Decided under the wheels' heading, the variant is not offered.
        let (ci, g) = best_variant(
            &d,
            &stats,
            &[],
            Effect::SideSlip,
            InformationSource::PositionsWheelHeading,
        )
        .unwrap();
        assert!(d.candidates[ci].variant.is_empty());
        assert!(g.relative < 0.01, "{g:?}");
    }

    /// One course channel, twelve blocks: two effects whose fingerprints
    /// the drive barely tells apart (`b` is `a` plus a fifth of another
    /// signal), present with opposite coefficients, and a third column of
    /// nothing the data holds.
    fn partners() -> Design {
        use super::super::design::Param;
        use interfaces::effects::Param as EffectParam;
        let mut rng = crate::error_model::Normal::new(23);
        let (mut rows, mut y, mut a, mut b, mut c) = (vec![], vec![], vec![], vec![], vec![]);
        for blk in 0..12 {
            for i in 0..200 {
                let u = ((i as f64) * 0.05 + blk as f64).sin();
                let v = ((i as f64) * 0.13 + 2.0 * blk as f64).cos();
                rows.push((Channel::CourseGyro, i, blk));
                a.push(u);
                b.push(u + 0.2 * v);
                c.push(rng.next());
                y.push(0.01 * u - 0.01 * (u + 0.2 * v) + 0.0002 * rng.next());
            }
        }
        let cand = |effect: Effect, p: EffectParam, col: usize| Candidate {
            effect,
            variant: String::new(),
            columns: vec![col],
            params: vec![Param::of(p, col)],
        };
        twelve_blocks(
            rows,
            y,
            vec![a, b, c],
            vec!["a".into(), "b".into(), "c".into()],
            vec![
                cand(Effect::GnssLeverArm, EffectParam::LeverArmX, 0),
                cand(Effect::GyroScale, EffectParam::GyroScale, 1),
                cand(Effect::TrackWidth, EffectParam::TrackRel, 2),
            ],
        )
    }

    #[test]
    fn partners_refused_one_at_a_time_enter_together_and_nothing_rides_along() {
        use InformationSource::*;
        let d = partners();
        let stats = BlockStats::new(&d);
        let current = stats.cv_errors(&[]);
        // One at a time, neither is worth much: `a` alone explains nothing
        // of the data, `b` alone a sliver.
        let a = gain(&current, &stats.cv_errors(&[0]));
        let b = gain(&current, &stats.cv_errors(&[1]));
        assert!(a.relative < 0.05 && b.relative < 0.2, "{a:?} {b:?}");
        // Together they explain the data, under either heading's guard.
        for source in [PositionsGyroHeading, PositionsWheelHeading] {
            let g = together(&d, &stats, &[], &[0, 1], source).expect("the pair enters");
            assert!(g.relative > 0.9 && g.z > 2.0, "{g:?}");
        }
        // A member the set does not need is refused, and takes the set
        // with it (all or none); so is a set without the pair.
        assert!(together(&d, &stats, &[], &[0, 1, 2], PositionsGyroHeading).is_none());
        assert!(together(&d, &stats, &[], &[0, 2], PositionsGyroHeading).is_none());
    }

    #[test]
    fn the_guard_asks_the_ranks_only_under_the_wheels_heading() {
        use InformationSource::*;
        // A gain in the aggregate that few blocks share (signed-rank z 1.1).
        let (gain, z) = (0.004, Some(1.1));
        assert!(guard_passes(gain, z, PositionsGyroHeading));
        assert!(guard_passes(gain, z, HeadingChannel));
        assert!(!guard_passes(gain, z, PositionsWheelHeading));
        assert!(guard_passes(gain, Some(2.0), PositionsWheelHeading));
        // A loss is refused everywhere, however the blocks rank.
        for source in [PositionsGyroHeading, HeadingChannel, PositionsWheelHeading] {
            assert!(!guard_passes(-0.001, Some(3.0), source));
        }
        assert!(!guard_passes(0.01, None, PositionsWheelHeading));
    }

    /// A drive's limit holding one effect decided under the wheels'
    /// heading at joint z `z`, and its joint fit under the gyro's heading
    /// at `z_gyro` (none where `None`).
    pub(in super::super) fn wheels_decided(
        effect: Effect,
        z: f64,
        z_gyro: Option<f64>,
    ) -> InformationLimit {
        use super::super::limit::{limit_of, CoefFit, Joint, OtherSource};
        let fit = CoefFit {
            estimate: z * 0.1,
            sigma_fisher: 0.1,
            sigma_segments: None,
        };
        let mut l = limit_of(
            effect,
            Some(fit),
            3.6,
            InformationSource::PositionsWheelHeading,
        );
        l.joint = Some(Joint::of(effect, fit, 3.6));
        l.other_source = z_gyro.map(|z| OtherSource {
            source: InformationSource::PositionsGyroHeading,
            estimate: z * 0.2,
            sigma: 0.2,
            wald_z: z,
        });
        InformationLimit {
            family_alpha: 0.05,
            alpha_per_effect: 0.05 / 12.0,
            power: 0.9,
            z_critical: 3.6,
            segments: 12,
            segment_s: 60.0,
            fixes: 7200,
            noise_refitted: true,
            noise_east: [1.0; 3],
            noise_north: [1.0; 3],
            noise_gyro_heading: [[1.0; 3]; 2],
            calibration_noise_east: None,
            calibration_noise_north: None,
            effects: vec![l],
        }
    }

    /// A slip found beside a latency the fixes also show alone: the margin
    /// is the difference of the two squares, the partner's joint fit and
    /// the manoeuvre that separates them come with it; an effect the
    /// catalogue does not list beside it (the antenna, the track) and a
    /// partner under another source are left out.
    #[test]
    fn a_finding_reports_its_margin_against_its_catalogue_partners() {
        let mut limit = wheels_decided(Effect::LongitudinalSlip, 16.0, None);
        let latency = wheels_decided(Effect::GnssLatency, 10.0, None).effects[0].clone();
        let antenna = wheels_decided(Effect::GnssLeverArm, 12.0, None).effects[0].clone();
        let track = wheels_decided(Effect::TrackWidth, 30.0, None).effects[0].clone();
        limit.effects.extend([latency, antenna, track]);
        let m = partner_margins(Effect::LongitudinalSlip, &limit);
        assert_eq!(m.len(), 1, "{m:?}");
        assert_eq!(m[0].effect, Effect::GnssLatency);
        assert!(
            (m[0].margin - (16.0 * 16.0 - 10.0 * 10.0)).abs() < 1e-6,
            "{}",
            m[0].margin
        );
        assert!(m[0].partner_joint.is_some());
        assert!(m[0].separate_by.contains("corners"), "{}", m[0].separate_by);
        let words = margins_in_words(&m, &|_| "s".to_string()).expect("a rival worth naming");
        assert!(
            words.contains("gnss_latency") && words.contains("156"),
            "{words}"
        );
        // The held-out blocks' check on the name, worded where it is known.
        let mut held = m.clone();
        held[0].holdout_gains = Some([0.190, 0.200]);
        let words = margins_in_words(&held, &|_| "s".to_string()).expect("worded");
        assert!(
            words.contains("19.0 % with it and 20.0 % with gnss_latency")
                && words.contains("do not bear the name out"),
            "{words}"
        );
        held[0].holdout_gains = Some([0.073, 0.036]);
        let words = margins_in_words(&held, &|_| "s".to_string()).expect("worded");
        assert!(
            words.contains("7.3 % with it") && !words.contains("do not bear"),
            "{words}"
        );
        // Either way round: the latency's margin against the slip is negative.
        let back = partner_margins(Effect::GnssLatency, &limit);
        assert!(back
            .iter()
            .any(|b| b.effect == Effect::LongitudinalSlip && b.margin < 0.0));
        // A partner too weak alone to be a rival is kept, not worded.
        limit.effects[1].wald_z = Some(1.0);
        let m = partner_margins(Effect::LongitudinalSlip, &limit);
        assert_eq!(m.len(), 1);
        assert!(margins_in_words(&m, &|_| String::new()).is_none());
        // A partner decided under another source has no margin here.
        limit.effects[1].source = InformationSource::PositionsGyroHeading;
        assert!(partner_margins(Effect::LongitudinalSlip, &limit).is_empty());
    }

    #[test]
    fn an_effect_the_gyros_heading_shows_too_faces_the_gyros_guard() {
        use InformationSource::*;
        let test = |effect: Effect, z: f64| WaldTest {
            effect,
            z,
            joint: true,
            rank: 0,
            z_critical: 3.6,
            significant: true,
        };
        let e = Effect::GnssLeverArm;
        let t = test(e, 11.3);
        // Shown under both headings, the same sign: the aggregate's guard.
        let both = wheels_decided(e, 11.3, Some(11.5));
        assert_eq!(guard_source(&both, &t), PositionsGyroHeading);
        // A gain few blocks share now passes (it did not under the ranks).
        assert!(guard_passes(0.025, Some(1.1), guard_source(&both, &t)));
        // Not beyond the critical z there, of the other sign, or never
        // fitted there (the track width): the ranks are asked.
        for other in [Some(3.0), Some(-11.5), None] {
            let l = wheels_decided(e, 11.3, other);
            assert_eq!(guard_source(&l, &t), PositionsWheelHeading, "{other:?}");
            assert!(!guard_passes(0.025, Some(1.1), guard_source(&l, &t)));
        }
        let track = wheels_decided(Effect::TrackWidth, -4.0, None);
        assert_eq!(
            guard_source(&track, &test(Effect::TrackWidth, -4.0)),
            PositionsWheelHeading
        );
    }

    #[test]
    fn holm_steps_down_and_stops_at_the_first_failure() {
        // Twelve statistics, 11 degrees of freedom: the first critical value
        // is Bonferroni's (about 3.6), each next one smaller.
        let zs = [9.0, -5.0, 3.5, 3.4, 0.5, 0.1, 0.2, 0.3, 0.4, -0.6, 0.7, 0.8];
        let t = step_down(sorted(&zs), 0.05, 11.0);
        let crit: Vec<f64> = t.iter().map(|x| x.z_critical).collect();
        assert!(crit.windows(2).all(|w| w[0] > w[1]), "{crit:?}");
        assert!((crit[0] - t_quantile(1.0 - 0.025 / 12.0, 11.0)).abs() < 1e-12);
        // 3.5 is below Bonferroni's critical value (about 3.6) but above
        // the third step's (about 3.49): Holm calls it, Bonferroni would not.
        assert!(crit[0] > 3.5 && crit[2] < 3.5 && crit[3] > 3.4, "{crit:?}");
        let significant: Vec<bool> = t.iter().map(|x| x.significant).collect();
        assert_eq!(&significant[..4], &[true, true, true, false]);
        // Once one fails, none after it is significant.
        assert!(significant[3..].iter().all(|s| !s));
        assert_eq!(t[1].z, -5.0, "sorted by |z|, the sign kept");
    }

    #[test]
    fn holm_holds_the_family_wise_level_on_independent_nulls() {
        // Twelve independent null statistics (Student t with 11 dof drawn
        // as normal over the root of a scaled chi-square): the share of
        // families with any rejection stays near 5 %, never far above.
        let mut rng = crate::error_model::Normal::new(7);
        let families = 4000;
        let dof = 11usize;
        let mut any = 0;
        for _ in 0..families {
            let zs: Vec<f64> = (0..12)
                .map(|_| {
                    let z = rng.next();
                    let chi: f64 = (0..dof).map(|_| rng.next().powi(2)).sum::<f64>();
                    z / (chi / dof as f64).sqrt()
                })
                .collect();
            if step_down(sorted(&zs), 0.05, dof as f64)
                .iter()
                .any(|t| t.significant)
            {
                any += 1;
            }
        }
        let rate = any as f64 / families as f64;
        // Binomial sigma at 5 % over 4000 families is 0.34 %.
        assert!(rate < 0.065 && rate > 0.02, "family-wise rate {rate}");
    }
}
