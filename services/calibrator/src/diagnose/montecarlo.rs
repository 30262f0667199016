//! The false-alarm rate proven on the drive itself (issue 37, item 2): the
//! drive's GNSS errors redrawn from its own refitted error model (white
//! plus Gauss-Markov per axis, per heading source: the dead-reckoning's
//! errors from the recorded, quantised inputs are in it), the fingerprints
//! and nuisances those of the recorded inputs, and the decision of
//! [`super::decide`] run on each redraw: the share of redraws in which
//! Holm's procedure calls any effect significant is the family-wise
//! false-alarm rate on this drive, to be held at the nominal 5 %.
//!
//! It checks the statistics (the sigmas, the critical values, Holm's
//! procedure) against the drive's own error model; it cannot check the
//! error model itself (a model mismatch the redraws do not hold is what
//! the held-out guard is for). The heading sensor's bias, tested on its
//! own channel, is redrawn there: the channel's errors as an AR(1) series
//! of the drive's own scale and lag-1 correlation, its three terms tested
//! jointly as on the drive, in the same Holm family.
//!
//! Pure: the drive's data in, a rate out.

use super::decide::step_down;
use super::information::{InformationError, PositionNoise};
use super::limit::{gauss_markov, whitened, RedrawBasis, FAMILY_ALPHA};
use crate::error_model::Normal;
use interfaces::effects::Effect;
use serde::Serialize;
use std::collections::BTreeMap;

/// The false-alarm rate of the Wald decision on redraws of a drive.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NullRate {
    /// Redraws.
    pub draws: usize,
    /// Redraws in which Holm's procedure called any effect significant.
    pub rejections: usize,
    /// `rejections / draws`.
    pub rate: f64,
    /// Its binomial sigma at the nominal level.
    pub sigma: f64,
    /// The nominal family-wise level.
    pub family_alpha: f64,
    /// Per effect, the redraws in which it was called.
    pub per_effect: BTreeMap<Effect, usize>,
}

/// The seed of the false-alarm redraws (the same numbers every run).
pub(super) const NULL_SEED: u64 = 0x37_0002;

/// `draws` redraws of the drive's GNSS errors from each heading source's
/// error model, on the information limit's whitened columns, each tested
/// as the diagnosis tests the drive (seeded: the same numbers for the same
/// seed).
pub(super) fn run(
    basis: &RedrawBasis,
    draws: usize,
    seed: u64,
) -> Result<NullRate, InformationError> {
    let (all_t, segment_sizes) = (&basis.all_t[..], &basis.segment_sizes[..]);
    let n = all_t.len();
    let dof = segment_sizes.len().saturating_sub(1) as f64;
    let mut rng = Normal::new(seed);
    let mut rejections = 0;
    let mut per_effect: BTreeMap<Effect, usize> = BTreeMap::new();
    for _ in 0..draws {
        // Per effect, the test under the heading source with the smaller
        // sigma, as the drive's own limit chooses.
        let mut tests: BTreeMap<Effect, (f64, bool, f64)> = BTreeMap::new();
        for p in &basis.sources {
            let err = redraw(&mut rng, all_t, &p.noise);
            let col: Vec<[f64; 2]> = (0..n).map(|i| [err[i], err[n + i]]).collect();
            let w0 = whitened(all_t, &p.noise, &[col])?;
            let Some(w0) = w0.first() else {
                continue;
            };
            let g = p.gram.with_data(w0, &p.w, segment_sizes);
            for set in &p.sets {
                let (e, cols, n_alone) = (&set.effect, &set.cols, &set.n_alone);
                let within = g.fit_within_signs(cols, &set.signed);
                // The source is chosen by the sigma with every effect free
                // (as the drive's own limit chooses), the z is the fit's
                // within the signs.
                let free = match &within {
                    Some((_, held)) if !held.is_empty() => g.fit(cols),
                    Some((f, _)) => Some(*f),
                    None => None,
                };
                let fit = within
                    .map(|(f, _)| (f, free.map_or(f.sigma(), |a| a.sigma())))
                    .or_else(|| g.fit(&cols[..*n_alone]).map(|f| (f, f.sigma())));
                if let Some((f, sigma)) = fit {
                    let z = f.estimate / f.sigma();
                    let better = tests.get(e).is_none_or(|t| sigma < t.2);
                    if z.is_finite() && better {
                        tests.insert(*e, (z, cols.len() > *n_alone, sigma));
                    }
                }
            }
        }
        let mut tests: Vec<(Effect, f64, bool)> = tests
            .into_iter()
            .map(|(e, (z, joint, _))| (e, z, joint))
            .collect();
        if let Some((z, joint)) = basis.heading.as_ref().and_then(|h| h.z(&mut rng)) {
            tests.push((Effect::HeadingBias, z, joint));
        }
        let called: Vec<Effect> = step_down(tests, FAMILY_ALPHA, dof)
            .into_iter()
            .filter(|t| t.significant)
            .map(|t| t.effect)
            .collect();
        if !called.is_empty() {
            rejections += 1;
        }
        for e in called {
            *per_effect.entry(e).or_default() += 1;
        }
    }
    let d = draws.max(1) as f64;
    Ok(NullRate {
        draws,
        rejections,
        rate: rejections as f64 / d,
        sigma: (FAMILY_ALPHA * (1.0 - FAMILY_ALPHA) / d).sqrt(),
        family_alpha: FAMILY_ALPHA,
        per_effect,
    })
}

/// GNSS errors at `t`, east then north, white plus Gauss-Markov per axis.
fn redraw(rng: &mut Normal, t: &[f64], noise: &[PositionNoise; 2]) -> Vec<f64> {
    let n = t.len();
    let mut out = vec![0.0; 2 * n];
    for (axis, nz) in noise.iter().enumerate() {
        let gm = gauss_markov(rng, t, n, nz.gm_tau_s.max(1e-6));
        for i in 0..n {
            out[axis * n + i] = nz.white_sigma_m * rng.next() + nz.gm_sigma_m * gm[axis * n + i];
        }
    }
    out
}
