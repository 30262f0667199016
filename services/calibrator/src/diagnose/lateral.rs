//! The load transfer read through its own estimate.
//!
//! The diagnosis reads the lateral acceleration from the wheels' own yaw
//! rate, which a load transfer bends by 1 + 2 k_z v^2 / t
//! ([`vehicle_model::effects::lateral_acceleration_from_wheels`]). Read
//! plainly, a fit finds k_z / (1 + 2 k_z v^2 / t): confidently low. Once the
//! load transfer is accepted, the epochs are read through the estimate, the
//! two columns that read a_y are recomputed ([`design::rebuild_lateral`]),
//! the block statistics are updated at those columns
//! ([`BlockStats::with_columns_changed`]) and the fit is repeated until the
//! estimate settles. Given a_y the fit is linear in k_z, so the fixed point
//! is the self-consistent estimate. The test that accepted the effect is the
//! one at k_z = 0 and is not repeated here.

use super::design::{self, BasePoints, Design, DesignSettings};
use super::epochs::Epochs;
use super::locate::{self, Model};
use super::select::BlockStats;
use interfaces::drive::{GnssSample, WheelRevs};
use nalgebra::DVector;

/// Refits at most (the fixed point contracts by 2 k_z v^2 / (t + 2 k_z
/// v^2) per step: about 0.4 at 33 m/s for a typical k_z; each step
/// recomputes only the two columns that read a_y).
const STEPS: usize = 12;

/// One refit: the k_z a_y was read through, the estimate and its sigma
/// that came back.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// k_z the epochs' a_y was read through.
    pub k_in: f64,
    /// The load transfer's estimate with a_y so read.
    pub k_out: f64,
    /// Its sigma.
    pub sigma: f64,
}

impl Step {
    /// Whether reading a_y through `k_in` gave back a load transfer within
    /// a quarter of its sigma of it. The fixed point lies within r / (1 - r)
    /// of that step (r the contraction, under 0.4 at typical sizes): within
    /// a sixth of a sigma.
    pub fn settled(&self) -> bool {
        (self.k_out - self.k_in).abs() < 0.25 * self.sigma
    }
}

/// What the drive is read from, unchanged by the refits.
pub struct Inputs<'a> {
    /// The epochs with a_y read through a given k_z.
    pub epochs_at: &'a dyn Fn(f64) -> Epochs,
    /// The plain model's dead-reckonings the design was built with.
    pub base_points: &'a BasePoints,
    /// The design's settings.
    pub settings: &'a DesignSettings,
    /// Epochs set aside (GNSS jumps).
    pub excluded: &'a [bool],
    /// Wheel revolutions.
    pub revs: &'a [WheelRevs],
    /// GNSS fixes.
    pub gnss: &'a [GnssSample],
    /// The plain model (it reads no a_y).
    pub plain: &'a Model,
    /// The nominal track, m.
    pub track_m: f64,
}

/// The epochs, design and statistics after the refits, the fit of the
/// model's columns on them, and the refits made.
pub struct Read {
    /// The epochs, a_y read through the last k_z.
    pub ep: Epochs,
    /// The design built on them.
    pub design: Design,
    /// Its block statistics.
    pub stats: BlockStats,
    /// The coefficients of the model's columns and their jackknife sigmas
    /// on `stats` (`None` if the fit failed).
    pub fit: Option<(DVector<f64>, DVector<f64>)>,
    /// The plain reading first (`k_in` 0), then each refit.
    pub steps: Vec<Step>,
}

/// The evidence's sentence on the refits `steps` (the plain reading
/// first; `None` without a refit).
pub fn evidence(steps: &[Step]) -> Option<String> {
    let (first, last) = (steps.first()?, steps.last()?);
    let n = steps.len().checked_sub(1).filter(|n| *n > 0)?;
    Some(format!(
        "a_y read through the estimate (the load transfer bends the wheels' \
         yaw rate): k_z {:.3e} with the plain v w, {:.3e} after {n} refit{}{}",
        first.k_out,
        last.k_out,
        if n == 1 { "" } else { "s" },
        if last.settled() { "" } else { " (not settled)" },
    ))
}

/// The model's columns `cols` fitted on `stats`; where the load transfer
/// is among them (its column `col`), with a_y read through its estimate
/// until it settles.
pub fn read_through_estimate(
    inputs: &Inputs<'_>,
    ep: Epochs,
    design: Design,
    stats: BlockStats,
    cols: &[usize],
    col: Option<usize>,
) -> Read {
    let fit_all = |s: &BlockStats| s.fit_with_sigmas(cols);
    let k_of = |f: &(DVector<f64>, DVector<f64>)| -> Option<(f64, f64)> {
        let i = cols.iter().position(|&x| Some(x) == col)?;
        let (b, s) = (f.0[i], f.1[i]);
        (b.is_finite() && s.is_finite()).then_some((b, s))
    };
    let mut now = Read {
        fit: fit_all(&stats),
        ep,
        design,
        stats,
        steps: Vec::new(),
    };
    let Some(first) = now.fit.as_ref().and_then(k_of) else {
        return now;
    };
    now.steps.push(Step {
        k_in: 0.0,
        k_out: first.0,
        sigma: first.1,
    });
    let mut k = start(&now.ep, first.0, inputs.track_m);
    // Plain iterates since the last jump, for Aitken's.
    let mut run = vec![k];
    for _ in 0..STEPS {
        let ep2 = (inputs.epochs_at)(k);
        let Some((d2, s2, _)) = reread(inputs, &now.design, &now.stats, &ep2) else {
            break;
        };
        let Some(f2) = fit_all(&s2) else {
            break;
        };
        let Some(next) = k_of(&f2) else {
            break;
        };
        let step = Step {
            k_in: k,
            k_out: next.0,
            sigma: next.1,
        };
        tracing::debug!(
            k_z_in = step.k_in,
            k_z_out = step.k_out,
            sigma = step.sigma,
            "load transfer: a_y read through the estimate"
        );
        now.ep = ep2;
        now.design = d2;
        now.stats = s2;
        now.fit = Some(f2);
        now.steps.push(step);
        if step.settled() {
            break;
        }
        // The iteration contracts geometrically: once three iterates show
        // the ratio, jump to the limit (Aitken).
        run.push(next.0);
        k = next.0;
        if let [.., a, b, c] = run[..] {
            let r = (c - b) / (b - a);
            if r.is_finite() && r > 0.0 && r < 0.95 {
                k = c + (c - b) * r / (1.0 - r);
                run = vec![k];
            }
        }
    }
    now
}

/// An effect that reads a_y, estimated under the gyro's reading of a_y
/// beside the wheels'.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FormSpread {
    /// The design column.
    pub column: usize,
    /// Its coefficient with a_y read from the wheels (through the load
    /// transfer's estimate where there is one): the published one.
    pub wheels: f64,
    /// Its coefficient with a_y read from the gyro.
    pub gyro: f64,
}

impl FormSpread {
    /// The model-form uncertainty of the published (wheels') reading: the
    /// difference of the two readings over sqrt 2. Under the catalogue's
    /// linear form the two estimate the same coefficient (the gyro's rate
    /// is the yaw rate the wheels' is bent from), and the noise moves them
    /// together (the same fixes, the same design but for the columns that
    /// read a_y). Where they differ, the form does not hold exactly: taking
    /// each reading's form error as an independent draw of spread tau, the
    /// difference has spread tau sqrt 2, so one difference estimates tau as
    /// |d| / sqrt 2. The coefficient is not known to better than that,
    /// however small the noise's sigma.
    pub fn sigma(&self) -> f64 {
        (self.wheels - self.gyro).abs() / std::f64::consts::SQRT_2
    }
}

/// The model's columns `cols` that read a_y, fitted again with a_y read
/// from the gyro (`gyro_ep`, [`super::epochs::with_gyro_lateral`]) on the
/// design and statistics `read` ended with; empty where no model column
/// reads a_y or a fit fails. The design's other columns stay as they were.
pub fn gyro_reading(
    inputs: &Inputs<'_>,
    read: &Read,
    gyro_ep: &Epochs,
    cols: &[usize],
) -> Vec<FormSpread> {
    let Some((beta, _)) = read.fit.as_ref() else {
        return Vec::new();
    };
    let Some((_, s2, changed)) = reread(inputs, &read.design, &read.stats, gyro_ep) else {
        return Vec::new();
    };
    if !cols.iter().any(|c| changed.contains(c)) {
        return Vec::new();
    }
    let Some(beta_g) = s2.fit(cols, |_| true) else {
        return Vec::new();
    };
    cols.iter()
        .enumerate()
        .filter(|(_, c)| changed.contains(c))
        .filter(|(i, _)| beta[*i].is_finite() && beta_g[*i].is_finite())
        .map(|(i, &column)| FormSpread {
            column,
            wheels: beta[i],
            gyro: beta_g[i],
        })
        .collect()
}

/// The design and its block statistics again with a_y as the epochs `ep`
/// read it: only the columns that read a_y are recomputed
/// ([`design::rebuild_lateral`]) and only their statistics updated; with
/// the indices of the columns that changed. `None` if the candidates or
/// rows came out otherwise (the selection's indices would not hold).
fn reread(
    inputs: &Inputs<'_>,
    old: &Design,
    stats: &BlockStats,
    ep: &Epochs,
) -> Option<(Design, BlockStats, Vec<usize>)> {
    let cx = locate::Context {
        revs: inputs.revs,
        gnss: inputs.gnss,
        ep,
    };
    let d2 = design::rebuild_lateral(
        old,
        inputs.base_points,
        ep,
        inputs.settings,
        inputs.excluded,
        &cx,
        inputs.plain,
    );
    if d2.candidates != old.candidates || d2.rows != old.rows {
        return None;
    }
    let changed: Vec<usize> = (0..d2.columns.len())
        .filter(|&c| d2.columns.get(c) != old.columns.get(c))
        .collect();
    let s2 = stats.with_columns_changed(&d2, &changed);
    Some((d2, s2, changed))
}

/// Where the plain reading's shrinkage puts the estimate: the plain fit
/// finds k0 = k / (1 + k x) with x = 2 v^2 / t averaged where the
/// fingerprint's information is (weights (v a_y)^2), so k = k0 / (1 - k0 x).
fn start(ep: &Epochs, k0: f64, track_m: f64) -> f64 {
    let (sw, swx) = ep
        .epochs
        .iter()
        .filter(|e| !e.standstill && e.a_y.is_finite())
        .fold((0.0, 0.0), |(a, b), e| {
            let w = (e.v_odo * e.a_y).powi(2);
            (a + w, b + w * 2.0 * e.v_odo * e.v_odo / track_m)
        });
    let shrink = if sw > 0.0 { k0 * swx / sw } else { 0.0 };
    if shrink.is_finite() && shrink.abs() < 0.5 {
        k0 / (1.0 - shrink)
    } else {
        k0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_is_settled_within_a_quarter_sigma_and_not_beyond() {
        let s = |k_in: f64, k_out: f64| Step {
            k_in,
            k_out,
            sigma: 1e-5,
        };
        assert!(s(5.0e-4, 5.02e-4).settled());
        assert!(!s(5.0e-4, 5.03e-4).settled());
        assert!(!s(0.0, 5.0e-4).settled());
    }

    #[test]
    fn the_evidence_counts_the_refits_and_says_when_they_did_not_settle() {
        let plain = Step {
            k_in: 0.0,
            k_out: 3.0e-4,
            sigma: 1e-5,
        };
        assert_eq!(evidence(&[plain]), None);
        let settled = Step {
            k_in: 5.0e-4,
            k_out: 5.01e-4,
            sigma: 1e-5,
        };
        let text = evidence(&[plain, settled]).unwrap_or_default();
        assert!(
            text.contains("3.000e-4 with the plain v w, 5.010e-4 after 1 refit"),
            "{text}"
        );
        assert!(!text.contains("not settled"), "{text}");
        let moving = Step {
            k_in: 4.0e-4,
            k_out: 4.5e-4,
            sigma: 1e-5,
        };
        let text = evidence(&[plain, moving, moving]).unwrap_or_default();
        assert!(text.contains("after 2 refits (not settled)"), "{text}");
    }
}
