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
//! own channel, is not redrawn.
//!
//! Pure: the drive's data in, a rate out.

use super::decide::step_down;
use super::information::{InformationError, PositionNoise};
use super::limit::{
    common_times, gauss_markov, refit_noise, step_of, whitened, Columns, LimitInput, SegmentGram,
    FAMILY_ALPHA,
};
use super::locate::HeadingSource;
use crate::error_model::Normal;
use interfaces::effects::{Effect, Param};
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

/// One heading source's fixed parts: the whitened columns, their Gram, the
/// noise to redraw from and the fits' columns per effect.
struct Prepared {
    noise: [PositionNoise; 2],
    w: Vec<Vec<f64>>,
    gram: SegmentGram,
    sets: Vec<(Effect, Vec<usize>, usize)>,
}

/// `draws` redraws of the drive's GNSS errors from its refitted error
/// model, each tested as the diagnosis tests the drive (seeded: the same
/// numbers for the same seed).
pub fn null_rejection_rate(
    input: &LimitInput<'_>,
    draws: usize,
    seed: u64,
) -> Result<NullRate, InformationError> {
    let times = common_times(input, step_of(Param::GnssLatency));
    let all_t: Vec<f64> = times.iter().flatten().copied().collect();
    let segment_sizes: Vec<usize> = times.iter().map(Vec::len).filter(|n| *n > 0).collect();
    if all_t.len() < 10 || segment_sizes.len() < 2 {
        return Err(InformationError::BadData(format!(
            "{} fixes in {} segments; at least 10 in 2",
            all_t.len(),
            segment_sizes.len()
        )));
    }
    let mut sources = Vec::new();
    for heading in [HeadingSource::Wheels, HeadingSource::Gyro] {
        let src = Columns::build(input, heading, &times);
        let noise = refit_noise(&times, &src).or(input.noise).ok_or_else(|| {
            InformationError::BadNoise("no GNSS error model to redraw from".into())
        })?;
        let w = whitened(&all_t, &noise, &src.cols)?;
        let gram = SegmentGram::new(&w, &segment_sizes);
        let sets = src.column_sets(&w, &gram);
        sources.push(Prepared {
            noise,
            w,
            gram,
            sets,
        });
    }
    let n = all_t.len();
    let dof = segment_sizes.len().saturating_sub(1) as f64;
    let mut rng = Normal::new(seed);
    let mut rejections = 0;
    let mut per_effect: BTreeMap<Effect, usize> = BTreeMap::new();
    for _ in 0..draws {
        let mut tests: Vec<(Effect, f64, bool)> = Vec::new();
        for p in &sources {
            let err = redraw(&mut rng, &all_t, &p.noise);
            let col: Vec<[f64; 2]> = (0..n).map(|i| [err[i], err[n + i]]).collect();
            let w0 = whitened(&all_t, &p.noise, &[col])?;
            let Some(w0) = w0.first() else {
                continue;
            };
            let g = p.gram.with_data(w0, &p.w, &segment_sizes);
            for (e, cols, n_alone) in &p.sets {
                let fit = g.fit(cols).or_else(|| g.fit(&cols[..*n_alone]));
                if let Some(f) = fit {
                    let z = f.estimate / f.sigma();
                    if z.is_finite() {
                        tests.push((*e, z, cols.len() > *n_alone));
                    }
                }
            }
        }
        tests.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
        let called: Vec<Effect> = step_down(&tests, FAMILY_ALPHA, dof)
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
