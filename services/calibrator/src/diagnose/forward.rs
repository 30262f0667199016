//! The decision's second stage: forward selection given what is found.
//!
//! The first stage ([`super::decide::holm`]) tests every effect with every
//! other effect of its source free. That names an effect against all of
//! its partners at once, and pays for it: where several partners share
//! its fingerprint (a track width beside the load transfer, the side-slip
//! and the latency under the wheels' heading), the all-free sigma is many
//! times the sigma the drive has for it once the effects that are present
//! are known, and an effect the drive plainly shows is missed.
//!
//! The second stage tests each effect the first left, given the effects
//! already in the model (`found`): the fit holds the nuisances, the found
//! effects of its source and the effect itself. To name it against its
//! partners, not by the order of entry, the statistic is the least of its
//! |z| over the fits that add one other effect not found (each partner in
//! turn): an effect that one partner can explain is not named. Steps as
//! Holm's: the largest statistic left against the critical value at
//! `alpha / (m - k)`; when it passes it enters (if the caller's guard
//! lets it) and the rest are tested again given it; the first failure
//! ends the stage.
//!
//! Its level: with nothing found every statistic is at most the effect's
//! |z| alone, so under the drive's error model the stage holds `alpha` on
//! its own; given found effects that are present it tests the rest in the
//! model that holds them. What it cannot hold off is two present effects,
//! neither found, that together mimic a third: the held-out guard and the
//! redraws on each null drive ([`super::montecarlo`], which runs both
//! stages) are what check it.
//!
//! Each effect is tested under the heading source whose fit given the
//! found has the smaller sigma (never by its estimate).
//!
//! Pure: Grams in, decisions out.

use super::limit::{InformationSource, SegmentGram};
use super::select::t_quantile;
use interfaces::effects::Effect;
use serde::Serialize;
use std::collections::BTreeSet;

/// One heading source's effects, with every nuisance of the drive (the
/// segments' poses, the circumferences' scale and left/right difference)
/// profiled out once: fits of a few columns, not of hundreds.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct SourceFits {
    /// Which dead-reckoning.
    pub(super) source: InformationSource,
    /// The full Gram's columns kept (the data column first).
    pub(super) keep: Vec<usize>,
    /// The Gram of the kept columns.
    pub(super) gram: SegmentGram,
    /// The effects this source holds information about, each with its
    /// column in `gram`.
    pub(super) effects: Vec<(Effect, usize)>,
    /// The gyro's bias column, a nuisance of the gyro's scale (under the
    /// gyro's heading only).
    pub(super) gyro_bias: Option<usize>,
}

impl SourceFits {
    fn col(&self, e: Effect) -> Option<usize> {
        self.effects.iter().find(|(x, _)| *x == e).map(|(_, c)| *c)
    }

    /// The test of `e` given `found` on `gram` (this source's, or a
    /// redraw's of the same columns): its z against its least favourable
    /// partner, the sigma of its fit given the found alone, the partner.
    fn test(
        &self,
        gram: &SegmentGram,
        e: Effect,
        found: &BTreeSet<Effect>,
    ) -> Option<(f64, f64, Option<Effect>)> {
        let target = self.col(e)?;
        let mut base = vec![target];
        let add = |c: usize, cols: &mut Vec<usize>| {
            if !cols.contains(&c) {
                cols.push(c);
            }
        };
        if e == Effect::GyroScale {
            if let Some(b) = self.gyro_bias {
                add(b, &mut base);
            }
        }
        for (f, c) in &self.effects {
            if *f != e && found.contains(f) {
                add(*c, &mut base);
            }
        }
        let given = gram.fit(&base)?;
        let sigma = given.sigma();
        let mut z = given.estimate / sigma;
        let mut against = None;
        for (f, c) in &self.effects {
            if *f == e || found.contains(f) || base.contains(c) {
                continue;
            }
            let mut cols = base.clone();
            cols.push(*c);
            // A partner the drive cannot fit beside it explains it alone.
            let zf = gram.fit(&cols).map_or(0.0, |x| x.estimate / x.sigma());
            if !(zf.abs() >= z.abs()) {
                z = if zf.is_finite() { zf } else { 0.0 };
                against = Some(*f);
            }
        }
        (z.is_finite() && sigma.is_finite() && sigma > 0.0).then_some((z, sigma, against))
    }
}

/// One effect's test in the second stage.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ForwardTest {
    /// Catalogue id.
    pub effect: Effect,
    /// Its z given the found, against its least favourable partner.
    pub z: f64,
    /// That partner (none: no partner lowers it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub against: Option<Effect>,
    /// The effects it was tested given (the first stage's and the
    /// second's found before it).
    pub given: Vec<Effect>,
    /// The source it was tested under.
    pub source: InformationSource,
    /// Its step (0 the first).
    pub rank: usize,
    /// The |z| its step asks.
    pub z_critical: f64,
    /// Whether it passes.
    pub significant: bool,
}

/// The test of `e` given `found` under the source with the smaller sigma;
/// `grams[i]` is `sources[i]`'s Gram (the drive's or a redraw's).
fn best_test(
    sources: &[SourceFits],
    grams: &[&SegmentGram],
    e: Effect,
    found: &BTreeSet<Effect>,
) -> Option<(f64, Option<Effect>, InformationSource)> {
    sources
        .iter()
        .zip(grams)
        .filter_map(|(s, g)| s.test(g, e, found).map(|(z, sig, a)| (z, sig, a, s.source)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(z, _, a, s)| (z, a, s))
}

/// The second stage over `candidates` (the effects the first stage left)
/// given `found`, at level `alpha` with `dof` degrees of freedom for the
/// critical values. `admit` is asked of each significant effect whether
/// it enters the model (the caller's guard); one that does is given to
/// every later test. Returns the tests in their order: the significant
/// ones by step, then the rest at the step that failed.
pub(super) fn step_forward(
    sources: &[SourceFits],
    grams: &[&SegmentGram],
    found: &BTreeSet<Effect>,
    candidates: &[Effect],
    alpha: f64,
    dof: f64,
    mut admit: impl FnMut(&ForwardTest) -> bool,
) -> Vec<ForwardTest> {
    let mut found = found.clone();
    let mut left: Vec<Effect> = candidates
        .iter()
        .copied()
        .filter(|e| !found.contains(e))
        .collect();
    let m = left.len();
    let mut out = Vec::new();
    let mut k = 0;
    while !left.is_empty() {
        let z_critical = t_quantile(1.0 - 0.5 * alpha / (m - k) as f64, dof);
        let given: Vec<Effect> = found.iter().copied().collect();
        let mut tests: Vec<ForwardTest> = left
            .iter()
            .filter_map(|&e| {
                best_test(sources, grams, e, &found).map(|(z, against, source)| ForwardTest {
                    effect: e,
                    z,
                    against,
                    given: given.clone(),
                    source,
                    rank: k,
                    z_critical,
                    significant: false,
                })
            })
            .collect();
        tests.sort_by(|a, b| b.z.abs().total_cmp(&a.z.abs()));
        let Some(first) = tests.first_mut() else {
            break;
        };
        if first.z.abs() <= z_critical {
            out.extend(tests);
            break;
        }
        first.significant = true;
        let t = first.clone();
        if admit(&t) {
            found.insert(t.effect);
        }
        left.retain(|e| *e != t.effect);
        out.push(t);
        k += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Gram of `cols` (the data first) over `segments` equal segments.
    fn gram(cols: &[Vec<f64>], segments: usize) -> SegmentGram {
        let n = cols[0].len();
        let seg: Vec<usize> = (0..n).map(|r| r * segments / n).collect();
        SegmentGram::from_rows(cols, &seg, segments)
    }

    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = crate::error_model::Normal::new(seed);
        (0..n).map(|_| rng.next()).collect()
    }

    /// Three effects: `a` and `b` nearly alike (correlation about 0.97),
    /// `c` apart; the data hold `a` at `size` and white noise.
    fn drive(size: f64, seed: u64) -> (SourceFits, SegmentGram) {
        let n = 2400;
        let t: Vec<f64> = (0..n).map(|i| i as f64 / n as f64).collect();
        let a: Vec<f64> = t.iter().map(|x| (9.0 * x).sin()).collect();
        let b: Vec<f64> = t
            .iter()
            .map(|x| (9.0 * x).sin() + 0.25 * (23.0 * x).cos())
            .collect();
        let c: Vec<f64> = t.iter().map(|x| (31.0 * x).cos()).collect();
        let e = noise(n, seed);
        let y: Vec<f64> = a.iter().zip(&e).map(|(a, e)| size * a + e).collect();
        let g = gram(&[y, a, b, c], 12);
        let fits = SourceFits {
            source: InformationSource::PositionsWheelHeading,
            keep: vec![0, 1, 2, 3],
            gram: g.clone(),
            effects: vec![
                (Effect::TrackWidth, 1),
                (Effect::LoadTransferRadius, 2),
                (Effect::SideSlip, 3),
            ],
            gyro_bias: None,
        };
        (fits, g)
    }

    #[test]
    fn an_effect_one_partner_explains_is_not_named_and_a_known_one_frees_the_other() {
        // `a` at 0.3 per row: alone about 10 sigma, beside `b` (which can
        // take most of it) far less.
        let (fits, g) = drive(0.3, 1);
        let none = BTreeSet::new();
        let (z, against, _) = best_test(&[fits.clone()], &[&g], Effect::TrackWidth, &none).unwrap();
        let alone = g.fit(&[1]).unwrap();
        assert!(alone.estimate / alone.sigma() > 8.0, "alone {alone:?}");
        assert!(z.abs() < 0.5 * alone.estimate / alone.sigma(), "z {z}");
        assert_eq!(against, Some(Effect::LoadTransferRadius));
        // Given `c` found (absent here, but found), `a`'s test still
        // weighs `b` against it.
        let c_found: BTreeSet<Effect> = [Effect::SideSlip].into();
        let (z2, against2, _) = best_test(&[fits], &[&g], Effect::TrackWidth, &c_found).unwrap();
        assert_eq!(against2, Some(Effect::LoadTransferRadius));
        assert!((z2 - z).abs() < 0.2 * z.abs().max(1.0), "{z2} vs {z}");
    }

    #[test]
    fn the_stage_names_a_present_effect_and_holds_its_level_on_nulls() {
        // A present effect that its partner cannot mimic fully: `a` at 2.0
        // per row is named, its partner `b` is not.
        let (fits, g) = drive(2.0, 3);
        let t = step_forward(
            &[fits],
            &[&g],
            &BTreeSet::new(),
            &[Effect::TrackWidth, Effect::LoadTransferRadius, Effect::SideSlip],
            0.05,
            11.0,
            |_| true,
        );
        let named: Vec<Effect> = t.iter().filter(|x| x.significant).map(|x| x.effect).collect();
        assert_eq!(named, vec![Effect::TrackWidth], "{t:?}");
        // Nulls: the share of drives with any name stays near or below 5 %.
        let drives = 400;
        let mut any = 0;
        for seed in 0..drives {
            let (fits, g) = drive(0.0, 100 + seed);
            let t = step_forward(
                &[fits],
                &[&g],
                &BTreeSet::new(),
                &[Effect::TrackWidth, Effect::LoadTransferRadius, Effect::SideSlip],
                0.05,
                11.0,
                |_| true,
            );
            any += usize::from(t.iter().any(|x| x.significant));
        }
        let rate = any as f64 / drives as f64;
        assert!(rate < 0.08, "family-wise rate {rate}");
    }
}
