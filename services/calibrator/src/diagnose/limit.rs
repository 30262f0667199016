//! What a drive could show: for every effect of the table, the smallest
//! size the recording reveals with 90 % power at the family's level, from
//! the Fisher information of its GNSS positions under the drive's own
//! error model (issue 37, the information limit), and the Wald statistic of
//! the effect at that limit.
//!
//! The fingerprint of an effect is the derivative of the dead-reckoned
//! antenna positions at the fix times with respect to its main parameter
//! (central differences of the effect-aware model, [`super::locate::dr_points`]),
//! turned into the GNSS frame by each segment's placement. The nuisances are
//! what a fit re-estimates anyway: each segment's pose (the dead-reckoning
//! starts afresh in every segment), the circumferences' common scale and
//! left/right difference, and for the gyro's scale the gyro's bias. The GNSS
//! error of each axis is white plus Gauss-Markov, with the numbers the
//! calibration fitted to this drive's residuals; [`super::information`]
//! whitens exactly and profiles the nuisances out.
//!
//! The heading sensor's bias does not move a position: its information comes
//! from the heading channel (heading sensor against the GNSS course), whose
//! serial correlation is taken into account by the effective number of
//! independent rows of an AR(1) series. Its three terms (constant, sin and
//! cos of the course) are tested together: a compass error that is a pure
//! sinusoid of the heading has no constant term to show.
//!
//! Pure: the drive's data in, numbers out.

use super::design::{Channel, Design};
use super::information::{profiled_estimate, whiten, InformationError, PositionNoise};
use super::locate::{align_with_angle, dr_points, Context, HeadingSource, Model};
use crate::error_model::{nnls2, variogram, Normal};
use interfaces::effects::{Effect, Param, Scope};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use stats::distributions::{
    bisect, f_sf, noncentral_chi3_cdf, normal_cdf, normal_quantile, t_equivalent, t_quantile,
};
use std::collections::BTreeMap;

/// The family-wise level the limit is given at (two-sided, shared by the
/// twelve effects by Bonferroni).
pub const FAMILY_ALPHA: f64 = 0.05;
/// The power the limit is given at.
pub const POWER: f64 = 0.9;

/// Where the information about an effect comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum InformationSource {
    /// The GNSS positions against the wheels' dead-reckoning.
    PositionsWheelHeading,
    /// The GNSS positions against the dead-reckoning with the gyro's heading.
    PositionsGyroHeading,
    /// The heading sensor against the GNSS course.
    HeadingChannel,
}

impl InformationSource {
    /// In words.
    pub fn describe(self) -> &'static str {
        match self {
            InformationSource::PositionsWheelHeading => "GNSS positions, wheel heading",
            InformationSource::PositionsGyroHeading => "GNSS positions, gyro heading",
            InformationSource::HeadingChannel => "heading sensor against GNSS course",
        }
    }
}

/// One effect's information limit on this drive.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EffectLimit {
    /// Catalogue id.
    pub effect: Effect,
    /// Its main parameter's name (the table's).
    pub parameter: &'static str,
    /// Its unit (as reported).
    pub unit: &'static str,
    /// The catalogue's typical size, reported unit.
    pub typical: f64,
    /// The smallest size this drive shows with 90 % power at the family's
    /// level, reported unit; absent when the drive holds no information
    /// about it (no such manoeuvre).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smallest: Option<f64>,
    /// `smallest / typical`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub relative_to_typical: Option<f64>,
    /// Where the information comes from.
    pub source: InformationSource,
    /// What `estimate` and `sigma` are of: the parameter, or its square
    /// for a term that acts through its square (road grade's gain).
    pub estimate_of: String,
    /// The parameter's estimate from this drive alone (linearised at the
    /// plain model, the nuisances profiled out), reported unit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimate: Option<f64>,
    /// Its sigma, reported unit: the larger of `sigma_fisher` and
    /// `sigma_segments`. The smallest size shown is computed from it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma: Option<f64>,
    /// The sigma the Fisher information under the error model gives.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_fisher: Option<f64>,
    /// The sigma the segments' own scatter gives (a cluster-robust
    /// sandwich over segments): where the error model is wrong, this one
    /// is.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_segments: Option<f64>,
    /// The Wald statistic `estimate / sigma`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wald_z: Option<f64>,
    /// The same with every other effect of its source free too (those
    /// whose sign the physics fixes held at zero where their fit falls
    /// below it: [`Joint::held_at_zero`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joint: Option<Joint>,
    /// The joint fit under the other heading source, for an effect both
    /// see (the one not decided under): a second reading of the same
    /// fixes whose dead-reckoning errors are the other sensor's. The
    /// held-out guard of an effect decided under the wheels' heading reads
    /// it ([`super::decide::guard_source`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub other_source: Option<OtherSource>,
    /// The chance this drive shows an effect of the catalogue's typical
    /// size: the power of the decision's test there (the Wald test with
    /// every other effect of its source free where it has that fit, else
    /// alone) at the strictest critical z of Holm's procedure
    /// (Bonferroni's), from [`EffectLimit::power_at`]; for the compass
    /// bias, whose three terms are tested together, read from that test's
    /// smallest size as if it were one term's (an approximation). Absent
    /// where the drive holds no information about the effect.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub power_at_typical: Option<f64>,
}

/// An effect's joint fit under the heading source it is not decided
/// under.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct OtherSource {
    /// That source.
    pub source: InformationSource,
    /// The joint estimate there, reported unit.
    pub estimate: f64,
    /// Its sigma, reported unit.
    pub sigma: f64,
    /// `estimate / sigma`.
    pub wald_z: f64,
}

impl OtherSource {
    fn of(l: &EffectLimit) -> Option<OtherSource> {
        let j = l.joint.as_ref()?;
        Some(OtherSource {
            source: l.source,
            estimate: j.estimate?,
            sigma: j.sigma?,
            wald_z: j.wald_z?,
        })
    }
}

impl EffectLimit {
    /// The estimate and sigma to show (reported unit): with every other
    /// effect of its source free where that fit exists, else alone.
    pub fn shown_fit(&self) -> (Option<f64>, Option<f64>) {
        match &self.joint {
            Some(j) => (j.estimate, j.sigma),
            None => (self.estimate, self.sigma),
        }
    }

    /// The smallest size shown: with every other effect free where known,
    /// else alone.
    pub fn shown_smallest(&self) -> Option<f64> {
        self.joint
            .as_ref()
            .and_then(|j| j.smallest)
            .or(self.smallest)
    }

    /// The chance that the test whose smallest size shown is
    /// [`EffectLimit::shown_smallest`] (90 % power at `z_critical`, two
    /// sided) calls an effect of `size` (reported unit): the effect's
    /// sigma is that size over `z_critical + z_0.9` (for a term that acts
    /// through its square, the square's sigma, so the distance in sigmas
    /// goes with the size squared). `None` without information.
    pub fn power_at(&self, size: f64, z_critical: f64) -> Option<f64> {
        let smallest = self
            .shown_smallest()
            .filter(|v| *v > 0.0 && v.is_finite())?;
        let k = z_critical + normal_quantile(POWER);
        let ratio = size.abs() / smallest;
        let distance = if self.estimate_of.ends_with("^2") {
            k * ratio * ratio
        } else {
            k * ratio
        };
        Some(normal_cdf(distance - z_critical) + normal_cdf(-distance - z_critical))
    }

    /// Sets [`EffectLimit::power_at_typical`] for the critical z of the
    /// limit's family.
    pub(super) fn set_power_at_typical(&mut self, z_critical: f64) {
        self.power_at_typical = self.power_at(self.typical, z_critical);
    }
}

/// An effect's limit, estimate and Wald statistic with every other effect
/// of its source fitted alongside.
///
/// The heading sensor's bias has no partners in its channel: its joint
/// fit is its three terms (constant, sin and cos of the course) tested
/// together. There `wald_z` is the |t| (the decision's degrees of freedom)
/// of the same p-value as their joint Wald statistic, signed as their
/// largest term's z; `smallest` is the size any one of the three terms
/// alone is shown from with 90 % power by that joint test (the largest
/// over the terms); `estimate` and `sigma` stay the constant term's (the
/// sin and cos terms profiled out), as in the effect's own fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Joint {
    /// The smallest size shown with 90 % power, reported unit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smallest: Option<f64>,
    /// The estimate, reported unit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimate: Option<f64>,
    /// Its sigma, reported unit (as [`EffectLimit::sigma`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma: Option<f64>,
    /// The Fisher information's sigma.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_fisher: Option<f64>,
    /// The segments' scatter's sigma.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_segments: Option<f64>,
    /// `estimate / sigma` (the heading bias: its three terms' joint
    /// test, as said above).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wald_z: Option<f64>,
    /// Where the effect alone is beyond the critical z and is not with
    /// every other effect free: the effects beside which (each alone) it
    /// no longer is, those the drive cannot tell it from.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub partners: Vec<Partner>,
    /// The compass bias's three terms, tested together (only for it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub terms: Option<HeadingTerms>,
    /// The partners whose sign the physics fixes and whose fit here fell
    /// below zero: held at zero, their physical bound, in this fit
    /// ([`SegmentGram::fit_within_signs`]).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub held_at_zero: Vec<Effect>,
    /// The sigma with every other effect free whatever its sign (reported
    /// unit), where partners are held: the heading source an effect is
    /// decided under is chosen by it ([`decisive_sigma`]), so that the
    /// choice never follows the estimates.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_all_free: Option<f64>,
    /// The estimate of that fit (reported unit), where partners are held:
    /// a held partner whose fit fell below zero by a model mismatch rather
    /// than by noise pulls the effect's estimate with it (on our
    /// simulator's seed-2 compact track drive by 3 of its sigmas), so the
    /// estimate to compare with a truth is this one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimate_all_free: Option<f64>,
}

/// An effect the drive cannot tell another from.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Partner {
    /// Catalogue id.
    pub effect: Effect,
    /// By how much fitting it alongside inflates the other's variance.
    pub vif: f64,
}

/// The effects (`others`: each with its column) beside which the first of
/// `base`, beyond `z_critical` alone (`alone`), no longer is, with the
/// variance inflation each causes, largest first; empty when it is not
/// beyond alone.
pub(super) fn partners_of(
    gram: &SegmentGram,
    base: &[usize],
    alone: &CoefFit,
    others: &[(Effect, usize)],
    z_critical: f64,
) -> Vec<Partner> {
    if (alone.estimate / alone.sigma()).abs() <= z_critical {
        return Vec::new();
    }
    let mut out: Vec<Partner> = others
        .iter()
        .filter_map(|&(effect, c)| {
            let mut cols = base.to_vec();
            cols.push(c);
            let f = gram.fit(&cols)?;
            ((f.estimate / f.sigma()).abs() <= z_critical).then(|| Partner {
                effect,
                vif: (f.sigma() / alone.sigma()).powi(2),
            })
        })
        .collect();
    out.sort_by(|a, b| b.vif.total_cmp(&a.vif));
    out
}

impl Joint {
    pub(super) fn of(effect: Effect, fit: CoefFit, z_critical: f64) -> Joint {
        let l = limit_of(
            effect,
            Some(fit),
            z_critical,
            InformationSource::PositionsWheelHeading,
        );
        Joint {
            smallest: l.smallest,
            estimate: l.estimate,
            sigma: l.sigma,
            sigma_fisher: l.sigma_fisher,
            sigma_segments: l.sigma_segments,
            wald_z: l.wald_z,
            partners: Vec::new(),
            terms: None,
            held_at_zero: Vec::new(),
            sigma_all_free: None,
            estimate_all_free: None,
        }
    }
}

/// The information limit of a drive.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InformationLimit {
    /// The family-wise level (two-sided), shared by the effects.
    pub family_alpha: f64,
    /// The per-effect level (`family_alpha / effects`).
    pub alpha_per_effect: f64,
    /// The power.
    pub power: f64,
    /// The |Wald z| a single effect needs at the per-effect level: the
    /// Student t quantile with one degree of freedom fewer than segments
    /// (the sigma leans on the segments' own scatter, which a handful of
    /// segments knows only roughly).
    pub z_critical: f64,
    /// Segments the dead-reckoning restarts in, and their length, s.
    pub segments: usize,
    /// Segment length, s.
    pub segment_s: f64,
    /// Fixes used.
    pub fixes: usize,
    /// Whether the error model was refitted to the residual with every
    /// effect in (else the calibration's, fitted with none, is used).
    pub noise_refitted: bool,
    /// The GNSS error model of the east axis the information is computed
    /// under: white sigma (m), Gauss-Markov sigma (m), its time (s).
    pub noise_east: [f64; 3],
    /// North axis, as `noise_east`.
    pub noise_north: [f64; 3],
    /// The error model (east, north) under the gyro's heading, whose
    /// dead-reckoning errors differ from the wheels'.
    pub noise_gyro_heading: [[f64; 3]; 2],
    /// The calibration's error model of the east axis (plain model's
    /// residuals), as `noise_east`, when it fitted one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibration_noise_east: Option<[f64; 3]>,
    /// North axis, as `calibration_noise_east`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibration_noise_north: Option<[f64; 3]>,
    /// Per effect, in catalogue order.
    pub effects: Vec<EffectLimit>,
}

/// What the limit is computed from.
#[derive(Debug, Clone, Copy)]
pub struct LimitInput<'a> {
    /// The drive's wheels, fixes and epochs.
    pub cx: &'a Context<'a>,
    /// The plain calibrated model.
    pub base: &'a Model,
    /// Segments, [t0, t1) s, in time order.
    pub spans: &'a [(f64, f64)],
    /// The GNSS error of the east and north axes the calibration fitted to
    /// the plain model's residuals, if it did (used when the residual with
    /// every effect in shows too few lags for a model of its own).
    pub noise: Option<[PositionNoise; 2]>,
    /// The diagnosis's design (for the heading channel).
    pub design: &'a Design,
}

/// One stacked column: per fix, east and north.
type Col = Vec<[f64; 2]>;

/// A perturbation of the plain model.
#[derive(Debug, Clone, Copy)]
enum Kick {
    /// Both circumferences by a relative step.
    Scale,
    /// Their left/right difference by a relative step.
    LeftRight,
    /// One effect parameter (with another set alongside).
    Term(Param, Option<(Param, f64)>),
    /// One effect parameter that acts through its square (road grade's
    /// gain: cos(g x) ~ 1 - g^2 x^2 / 2): the step is in the square.
    Squared(Param),
}

impl Kick {
    fn param(self) -> Option<Param> {
        match self {
            Kick::Term(p, _) | Kick::Squared(p) => Some(p),
            Kick::Scale | Kick::LeftRight => None,
        }
    }
}

fn perturbed(base: &Model, kick: Kick, h: f64) -> Model {
    let mut m = *base;
    match kick {
        Kick::Scale => {
            m.c_rl *= 1.0 + h;
            m.c_rr *= 1.0 + h;
        }
        Kick::LeftRight => {
            m.c_rl *= 1.0 - h;
            m.c_rr *= 1.0 + h;
        }
        Kick::Term(p, with) => {
            m.terms.set(p, m.terms.get(p) + h);
            if let Some((q, v)) = with {
                m.terms.set(q, v);
            }
        }
        Kick::Squared(p) => {
            let square = m.terms.get(p).powi(2) + h;
            m.terms.set(p, square.max(0.0).sqrt());
        }
    }
    m
}

/// The dead-reckoning of one heading source over every segment, and the
/// fingerprints of perturbations in the GNSS frame.
struct Source<'a> {
    input: &'a LimitInput<'a>,
    heading: HeadingSource,
    /// Per segment: fix times kept, the placement angle, the model points.
    segments: Vec<(Vec<f64>, f64, Vec<[f64; 2]>)>,
}

impl<'a> Source<'a> {
    fn new(input: &'a LimitInput<'a>, heading: HeadingSource, times: &[Vec<f64>]) -> Source<'a> {
        let mut segments = Vec::new();
        for (&(t0, t1), keep) in input.spans.iter().zip(times) {
            let Some(p) = dr_points(input.base, heading, input.cx, t0, t1) else {
                segments.push((Vec::new(), 0.0, Vec::new()));
                continue;
            };
            let (model, gnss) = pick(&p.t, &p.model, &p.gnss, keep);
            let (_, _, angle) = align_with_angle(&model, &gnss);
            segments.push((keep.clone(), angle, model));
        }
        Source {
            input,
            heading,
            segments,
        }
    }

    /// The derivative of the placed positions with respect to `kick`.
    fn fingerprint(&self, kick: Kick, h: f64) -> Col {
        let mut out = Vec::new();
        for (&(t0, t1), (keep, angle, _)) in self.input.spans.iter().zip(&self.segments) {
            if keep.is_empty() {
                continue;
            }
            let at = |sign: f64| {
                let m = perturbed(self.input.base, kick, sign * h);
                dr_points(&m, self.heading, self.input.cx, t0, t1)
                    .map(|p| pick(&p.t, &p.model, &p.gnss, keep).0)
            };
            let (s, c) = angle.sin_cos();
            // A squared term is stepped one way from the plain model (its
            // square cannot go below zero there).
            let (plus, minus, span) = if matches!(kick, Kick::Squared(_)) {
                (at(1.0), at(0.0), h)
            } else {
                (at(1.0), at(-1.0), 2.0 * h)
            };
            match (plus, minus) {
                (Some(a), Some(b)) if a.len() == keep.len() && b.len() == keep.len() => {
                    for (p, q) in a.iter().zip(&b) {
                        let (dx, dy) = ((p[0] - q[0]) / span, (p[1] - q[1]) / span);
                        out.push([c * dx - s * dy, s * dx + c * dy]);
                    }
                }
                _ => out.extend(std::iter::repeat_n([0.0, 0.0], keep.len())),
            }
        }
        out
    }

    /// Each segment's pose (east, north, rotation) as columns, with the
    /// index of the segment (among those with fixes) each belongs to.
    fn poses(&self, total: usize) -> Vec<(usize, Col)> {
        let mut cols = Vec::new();
        let mut at = 0;
        for (seg, (_, angle, model)) in self
            .segments
            .iter()
            .filter(|(keep, _, _)| !keep.is_empty())
            .enumerate()
        {
            let (s, c) = angle.sin_cos();
            let mut east = vec![[0.0; 2]; total];
            let mut north = vec![[0.0; 2]; total];
            let mut rot = vec![[0.0; 2]; total];
            for (k, m) in model.iter().enumerate() {
                east[at + k] = [1.0, 0.0];
                north[at + k] = [0.0, 1.0];
                // d/d(angle) of R(angle) m.
                rot[at + k] = [-s * m[0] - c * m[1], c * m[0] - s * m[1]];
            }
            at += model.len();
            cols.extend([(seg, east), (seg, north)]);
            // A segment that hardly moves has no rotation to speak of (and
            // its column would be a translation's).
            if spread(model) >= MIN_SPREAD_M {
                cols.push((seg, rot));
            }
        }
        cols
    }

    /// The fixes' residual after each segment's placement, stacked.
    fn residual(&self) -> Col {
        let mut out = Vec::new();
        for (&(t0, t1), (keep, _, _)) in self.input.spans.iter().zip(&self.segments) {
            if keep.is_empty() {
                continue;
            }
            if let Some(p) = dr_points(self.input.base, self.heading, self.input.cx, t0, t1) {
                let (model, gnss) = pick(&p.t, &p.model, &p.gnss, keep);
                let (moved, _, _) = align_with_angle(&model, &gnss);
                out.extend(
                    moved
                        .iter()
                        .zip(&gnss)
                        .map(|(m, g)| [g[0] - m[0], g[1] - m[1]]),
                );
            }
        }
        out
    }
}

/// The smallest spread of a segment's points for its rotation to be a
/// nuisance of its own, m.
const MIN_SPREAD_M: f64 = 1.0;

/// The largest distance of the points from their mean, m.
fn spread(points: &[[f64; 2]]) -> f64 {
    let n = points.len().max(1) as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(x, y), p| (x + p[0] / n, y + p[1] / n));
    points
        .iter()
        .map(|p| (p[0] - mx).hypot(p[1] - my))
        .fold(0.0, f64::max)
}

/// The points of `t` that are in `keep` (both sorted), model and fix.
fn pick(
    t: &[f64],
    model: &[[f64; 2]],
    gnss: &[[f64; 2]],
    keep: &[f64],
) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
    let mut m = Vec::with_capacity(keep.len());
    let mut g = Vec::with_capacity(keep.len());
    let mut j = 0;
    for (i, &ti) in t.iter().enumerate() {
        while j < keep.len() && keep[j] < ti {
            j += 1;
        }
        if j < keep.len() && keep[j] == ti {
            m.push(model[i]);
            g.push(gnss[i]);
        }
    }
    (m, g)
}

/// The fix times every perturbation sees: those of the segment's span
/// [t0, t1) that the plain model and the latency's steps all reach.
fn common_times(input: &LimitInput<'_>, h_latency: f64) -> Vec<Vec<f64>> {
    input
        .spans
        .iter()
        .map(|&(t0, t1)| {
            let times =
                |m: &Model, src| dr_points(m, src, input.cx, t0, t1).map_or_else(Vec::new, |p| p.t);
            let mut keep: Vec<f64> = times(input.base, HeadingSource::Wheels)
                .into_iter()
                .filter(|t| *t < t1)
                .collect();
            let kick = Kick::Term(Param::GnssLatency, None);
            for sign in [1.0, -1.0] {
                let m = perturbed(input.base, kick, sign * h_latency);
                for src in [HeadingSource::Wheels, HeadingSource::Gyro] {
                    let other = times(&m, src);
                    keep.retain(|t| other.binary_search_by(|x| x.total_cmp(t)).is_ok());
                }
            }
            let gyro = times(input.base, HeadingSource::Gyro);
            keep.retain(|t| gyro.binary_search_by(|x| x.total_cmp(t)).is_ok());
            if keep.len() < 3 {
                keep.clear();
            }
            keep
        })
        .collect()
}

/// Whiten stacked columns per axis (east with `noise[0]`, north with
/// `noise[1]`) and flatten: east values, then north values.
pub(super) fn whitened(
    times: &[f64],
    noise: &[PositionNoise; 2],
    cols: &[Col],
) -> Result<Vec<Vec<f64>>, InformationError> {
    let n = times.len();
    let mut axes: [Vec<Vec<f64>>; 2] = [Vec::new(), Vec::new()];
    for (axis, out) in axes.iter_mut().enumerate() {
        *out = cols
            .iter()
            .map(|c| c.iter().map(|v| v[axis]).collect())
            .collect();
        let mut refs: Vec<&mut [f64]> = out.iter_mut().map(|v| v.as_mut_slice()).collect();
        whiten(times, &noise[axis], &mut refs)?;
    }
    let [east, north] = axes;
    Ok(east
        .into_iter()
        .zip(north)
        .map(|(mut e, nn)| {
            debug_assert_eq!(e.len(), n);
            e.extend(nn);
            e
        })
        .collect())
}

/// The effect's main parameter and what is set alongside it.
fn main_kick(effect: Effect) -> Kick {
    let p = effect.main_fitted();
    match effect {
        // The drift's form needs its time constant: the catalogue's typical.
        Effect::RadiusDrift => Kick::Term(
            p,
            Some((
                Param::DriftTimeConstant,
                Param::DriftTimeConstant.spec().typical,
            )),
        ),
        Effect::RoadGrade => Kick::Squared(p),
        _ => Kick::Term(p, None),
    }
}

/// One heading source's columns, before whitening: the residual, the
/// circumferences' scale (and left/right difference under the wheels'
/// heading), its effects' fingerprints, the segments' poses (and the gyro's
/// bias under the gyro's heading).
struct Columns {
    heading: HeadingSource,
    effects: Vec<Effect>,
    /// The effects this source tests: the first `owned` of `effects` (the
    /// rest are fitted beside them, free).
    owned: usize,
    cols: Vec<Col>,
    first_effect: usize,
    /// The segment of each pose column (they follow the effects).
    pose_segment: Vec<usize>,
    gyro_bias: bool,
}

impl Columns {
    fn build(input: &LimitInput<'_>, heading: HeadingSource, times: &[Vec<f64>]) -> Columns {
        let total: usize = times.iter().map(Vec::len).sum();
        let src = Source::new(input, heading, times);
        let wheels = matches!(heading, HeadingSource::Wheels);
        let gyro = |e: &Effect| matches!(e, Effect::GyroBias | Effect::GyroScale);
        let mut effects: Vec<Effect> = Effect::ALL
            .into_iter()
            .filter(|e| {
                if wheels {
                    !gyro(e) && *e != Effect::HeadingBias
                } else {
                    gyro(e)
                }
            })
            .collect();
        // Under the gyro's heading the wheels' effects on the distance, the
        // course and the antenna still move the positions: they are fitted
        // beside the gyro's (else a side-slip would pass for a gyro scale),
        // and tested here too. Each effect is then decided under the heading
        // that knows it better ([`keep_better`]): where the wheels' heading
        // wanders (tyres beyond the model), the gyro's dead-reckoning shows
        // an antenna or a latency with a fraction of the sigma.
        if !wheels {
            effects.extend(
                Effect::ALL
                    .into_iter()
                    .filter(|e| !gyro(e) && !matches!(e, Effect::HeadingBias | Effect::TrackWidth)),
            );
        }
        let owned = effects.len();
        let mut cols: Vec<Col> = vec![src.residual()];
        cols.push(src.fingerprint(Kick::Scale, 1e-4));
        // The left/right difference turns the wheels' heading; under the
        // gyro's heading it moves nothing to first order.
        if wheels {
            cols.push(src.fingerprint(Kick::LeftRight, 1e-4));
        }
        // The antenna's lateral offset: a nuisance of every fit (its
        // forward offset is the effect tested, the lateral one would else
        // stay in the residual and lean on whatever turns with the car).
        let lateral = Param::LeverArmY;
        cols.push(src.fingerprint(Kick::Term(lateral, None), step_of(lateral)));
        let first_effect = cols.len();
        for e in &effects {
            let kick = main_kick(*e);
            let h = match kick {
                // The square's step: the typical size's square.
                Kick::Squared(p) => p.spec().typical.powi(2),
                _ => kick.param().map_or(1e-4, step_of),
            };
            cols.push(src.fingerprint(kick, h));
        }
        let poses = src.poses(total);
        let pose_segment = poses.iter().map(|(seg, _)| *seg).collect();
        cols.extend(poses.into_iter().map(|(_, c)| c));
        if !wheels {
            let p = Param::GyroBias;
            cols.push(src.fingerprint(Kick::Term(p, None), step_of(p)));
        }
        Columns {
            heading,
            effects,
            owned,
            cols,
            first_effect,
            pose_segment,
            gyro_bias: !wheels,
        }
    }

    /// Per effect: the columns of its fit with every other effect of the
    /// source free (the effect first, then its nuisances, then the other
    /// effects the drive holds information about), and how many of them
    /// make its fit alone.
    fn column_sets(&self, w: &[Vec<f64>], gram: &SegmentGram) -> Vec<JointSet> {
        let n_eff = self.effects.len();
        let first_pose = self.first_effect + n_eff;
        let mut nuisances: Vec<usize> = (1..self.first_effect).collect();
        nuisances.extend(first_pose..first_pose + self.pose_segment.len());
        self.effects[..self.owned]
            .iter()
            .enumerate()
            .map(|(k, e)| {
                let target = self.first_effect + k;
                let mut cols = vec![target];
                cols.extend(&nuisances);
                if *e == Effect::GyroScale && self.gyro_bias {
                    cols.push(w.len() - 1);
                }
                let n_alone = cols.len();
                // Every other effect of this source free as well (those the
                // drive holds no information about left out: they are
                // singular).
                for j in self.first_effect..first_pose {
                    let duplicate =
                        self.gyro_bias && w[j] == w[w.len() - 1] && cols.contains(&(w.len() - 1));
                    if j != target && !duplicate && gram.total[(j, j)] > 0.0 {
                        cols.push(j);
                    }
                }
                let signed = cols[n_alone..]
                    .iter()
                    .copied()
                    .filter(|&c| self.effects[c - self.first_effect].sign_known())
                    .collect();
                JointSet {
                    effect: *e,
                    cols,
                    n_alone,
                    signed,
                }
            })
            .collect()
    }

    /// The effects' limits under `noise`: each effect alone with the
    /// nuisances, and with every other effect of the source free too. The
    /// sigma is the larger of the Fisher information's and a delete-one-
    /// segment sandwich's (the error model is a model: where the drive's
    /// own scatter of the estimate is larger, that is the honest one).
    fn limits(
        &self,
        gram: &SegmentGram,
        sets: &[JointSet],
        z_critical: f64,
    ) -> (Vec<EffectLimit>, SourceGram) {
        let source = match self.heading {
            HeadingSource::Wheels => InformationSource::PositionsWheelHeading,
            HeadingSource::Gyro => InformationSource::PositionsGyroHeading,
        };
        let mut out = Vec::new();
        for set in sets {
            let (e, cols, n_alone) = (set.effect, &set.cols, set.n_alone);
            let alone = gram.fit(&cols[..n_alone]);
            let joint = gram.fit_within_signs(cols, &set.signed);
            let mut l = limit_of(e, alone, z_critical, source);
            let free = joint
                .as_ref()
                .filter(|(_, held)| !held.is_empty())
                .and_then(|_| gram.fit(cols))
                .map(|f| Joint::of(e, f, z_critical));
            l.joint = joint.map(|(fit, held)| Joint {
                sigma_all_free: free.as_ref().and_then(|f| f.sigma),
                estimate_all_free: free.as_ref().and_then(|f| f.estimate),
                held_at_zero: held
                    .iter()
                    .map(|&c| self.effects[c - self.first_effect])
                    .collect(),
                ..Joint::of(e, fit, z_critical)
            });
            if let (Some(a), Some(j)) = (alone, l.joint.as_mut()) {
                let base: Vec<usize> = cols[..n_alone].to_vec();
                let others: Vec<(Effect, usize)> = cols[n_alone..]
                    .iter()
                    .map(|&c| (self.effects[c - self.first_effect], c))
                    .collect();
                j.partners = partners_of(gram, &base, &a, &others, z_critical);
            }
            out.push(l);
        }
        // What the drive tells of the car: its effects of the day (the
        // gyro's bias, the warm-up) profiled out with the nuisances.
        let car: Vec<usize> = (0..self.owned)
            .filter(|&k| self.effects[k].spec().scope == Scope::Car)
            .collect();
        let mut keep = vec![0];
        keep.extend(car.iter().map(|k| self.first_effect + k));
        let gram = SourceGram {
            source,
            effects: car.iter().map(|&k| self.effects[k]).collect(),
            gram: gram.profiled(&keep),
        };
        (out, gram)
    }
}

/// A model's fit of one coefficient: its estimate, its Fisher sigma and the
/// segments' scatter's (model units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct CoefFit {
    pub(super) estimate: f64,
    pub(super) sigma_fisher: f64,
    pub(super) sigma_segments: Option<f64>,
}

impl CoefFit {
    /// The honest sigma: the larger of the two.
    pub(super) fn sigma(&self) -> f64 {
        self.sigma_fisher.max(self.sigma_segments.unwrap_or(0.0))
    }
}

/// The Gram matrix of whitened columns (the data first), per segment and
/// in total: every sub-model's least squares and its sandwich over
/// segments come from it without touching the rows again.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct SegmentGram {
    per_segment: Vec<DMatrix<f64>>,
    total: DMatrix<f64>,
}

impl SegmentGram {
    fn new(w: &[Vec<f64>], segment_sizes: &[usize]) -> SegmentGram {
        let m = w.len();
        let n: usize = segment_sizes.iter().sum();
        let mut per_segment = vec![DMatrix::zeros(m, m); segment_sizes.len()];
        // Rows: the east values of every fix, then the north values.
        let mut row = 0;
        for _axis in 0..2 {
            for (seg, size) in segment_sizes.iter().enumerate() {
                let g = &mut per_segment[seg];
                let rows = row..row + size;
                for a in 0..m {
                    let wa = &w[a][rows.clone()];
                    if wa.iter().all(|v| *v == 0.0) {
                        continue;
                    }
                    for b in a..m {
                        g[(a, b)] += wa
                            .iter()
                            .zip(&w[b][rows.clone()])
                            .map(|(x, y)| x * y)
                            .sum::<f64>();
                    }
                }
                row += size;
            }
        }
        debug_assert_eq!(row, 2 * n);
        let mut total = DMatrix::zeros(m, m);
        for g in &mut per_segment {
            g.fill_lower_triangle_with_upper_triangle();
            total += &*g;
        }
        SegmentGram { per_segment, total }
    }

    /// The fit of the first of `cols`, with the segments' own scatter of
    /// it: the cluster-robust (sandwich) variance over segments,
    /// `k / (k - 1) sum_s (v' g_s)^2` with `v` the first row of the
    /// inverse normal matrix and `g_s` the segment's score at the fit.
    pub(super) fn fit(&self, cols: &[usize]) -> Option<CoefFit> {
        let a = DMatrix::from_fn(cols.len(), cols.len(), |i, j| {
            self.total[(cols[i], cols[j])]
        });
        let b = DVector::from_fn(cols.len(), |i, _| self.total[(cols[i], 0)]);
        let chol = a.cholesky()?;
        let theta = chol.solve(&b);
        let mut e0 = DVector::zeros(cols.len());
        e0[0] = 1.0;
        let v = chol.solve(&e0);
        let (estimate, inv00) = (theta[0], v[0]);
        if !(inv00 > 0.0 && estimate.is_finite()) {
            return None;
        }
        let k = self.per_segment.len();
        let sigma_segments = (k >= 4).then(|| {
            let sum: f64 = self
                .per_segment
                .iter()
                .map(|g| v.dot(&segment_score(g, cols, &theta)).powi(2))
                .sum();
            (k as f64 / (k as f64 - 1.0) * sum).sqrt()
        });
        Some(CoefFit {
            estimate,
            sigma_fisher: inv00.sqrt(),
            sigma_segments,
        })
    }
}

/// A segment's score at the fit `theta` of `cols` (its Gram `g`, the data
/// in row and column 0): `X_s' y_s - X_s' X_s theta`.
fn segment_score(g: &DMatrix<f64>, cols: &[usize], theta: &DVector<f64>) -> DVector<f64> {
    DVector::from_fn(cols.len(), |i, _| {
        g[(cols[i], 0)]
            - cols
                .iter()
                .enumerate()
                .map(|(j, c)| g[(cols[i], *c)] * theta[j])
                .sum::<f64>()
    })
}

/// A model's fit of all its coefficients: the estimates, the inverse
/// normal matrix (the Fisher covariance) and, over four segments or more,
/// the segments' sandwich covariance (model units).
#[derive(Debug, Clone, PartialEq)]
struct MultiFit {
    theta: DVector<f64>,
    inverse: DMatrix<f64>,
    sandwich: Option<DMatrix<f64>>,
}

impl MultiFit {
    /// The fit of the first `p` coefficients alone, the others profiled
    /// out: their estimates and the leading block of each covariance.
    fn leading(&self, p: usize) -> MultiFit {
        let p = p.min(self.theta.len());
        MultiFit {
            theta: self.theta.rows(0, p).into_owned(),
            inverse: self.inverse.view((0, 0), (p, p)).into_owned(),
            sandwich: self
                .sandwich
                .as_ref()
                .map(|s| s.view((0, 0), (p, p)).into_owned()),
        }
    }
}

impl SegmentGram {
    /// The fit of every one of `cols` (as [`SegmentGram::fit`]), with the
    /// full covariances: `k / (k - 1) sum_s A^-1 g_s g_s' A^-1`.
    fn fit_all(&self, cols: &[usize]) -> Option<MultiFit> {
        let a = DMatrix::from_fn(cols.len(), cols.len(), |i, j| {
            self.total[(cols[i], cols[j])]
        });
        let b = DVector::from_fn(cols.len(), |i, _| self.total[(cols[i], 0)]);
        let chol = a.cholesky()?;
        let theta = chol.solve(&b);
        let inverse = chol.inverse();
        if theta.iter().any(|t| !t.is_finite()) {
            return None;
        }
        let k = self.per_segment.len();
        let sandwich = (k >= 4).then(|| {
            let mut meat = DMatrix::zeros(cols.len(), cols.len());
            for g in &self.per_segment {
                let u = &inverse * segment_score(g, cols, &theta);
                meat += &u * u.transpose();
            }
            meat * (k as f64 / (k as f64 - 1.0))
        });
        Some(MultiFit {
            theta,
            inverse,
            sandwich,
        })
    }
}

impl SegmentGram {
    /// The fit of the first of `cols` with the others free, save those of
    /// `signed` (columns whose sign the physics fixes, non-negative) that
    /// the fit puts below zero: those are held at zero, their bound, the
    /// most negative (in its own z) first, one at a time, refitting after
    /// each, until every free one of them is at zero or above; the fit and
    /// the columns held. A least squares within the physics' signs: a
    /// partner the data wants of the impossible sign holds none of the
    /// effect, and left free it would take the sign's worth of the data
    /// from the effect tested (a negative side-slip passing for an
    /// antenna's offset). The false-alarm redraws decide the same way.
    pub(super) fn fit_within_signs(
        &self,
        cols: &[usize],
        signed: &[usize],
    ) -> Option<(CoefFit, Vec<usize>)> {
        let mut cols = cols.to_vec();
        let mut held = Vec::new();
        if !signed.is_empty() {
            while let Some(all) = self.fit_all(&cols) {
                let worst = (1..cols.len())
                    .filter(|&i| signed.contains(&cols[i]))
                    .map(|i| (i, all.theta[i] / all.inverse[(i, i)].sqrt()))
                    .filter(|(_, z)| *z < 0.0)
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                match worst {
                    Some((i, _)) => held.push(cols.remove(i)),
                    None => break,
                }
            }
        }
        Some((self.fit(&cols)?, held))
    }

    /// The Gram of the columns `keep` (the data column 0 first), every
    /// other column profiled out over the whole drive (Frisch-Waugh: each
    /// segment's rows of `keep` less their fit on the others), in the order
    /// of `keep`. Columns without information are left out of the fit.
    pub(super) fn profiled(&self, keep: &[usize]) -> SegmentGram {
        let m = self.total.nrows();
        let others: Vec<usize> = (0..m)
            .filter(|c| !keep.contains(c) && self.total[(*c, *c)] > 0.0)
            .collect();
        let (k, o) = (keep.len(), others.len());
        // T maps the kept columns to their residuals on the others.
        let mut t = DMatrix::zeros(m, k);
        for (j, &c) in keep.iter().enumerate() {
            t[(c, j)] = 1.0;
        }
        if o > 0 {
            let g_oo = DMatrix::from_fn(o, o, |i, j| self.total[(others[i], others[j])]);
            let g_ok = DMatrix::from_fn(o, k, |i, j| self.total[(others[i], keep[j])]);
            let scale = (0..o).map(|i| g_oo[(i, i)]).fold(0.0, f64::max);
            if let Ok(inv) = g_oo.pseudo_inverse(1e-12 * scale) {
                let a = inv * g_ok;
                for (i, &c) in others.iter().enumerate() {
                    for j in 0..k {
                        t[(c, j)] = -a[(i, j)];
                    }
                }
            }
        }
        let per_segment: Vec<DMatrix<f64>> = self
            .per_segment
            .iter()
            .map(|g| t.transpose() * g * &t)
            .collect();
        let mut total = DMatrix::zeros(k, k);
        for g in &per_segment {
            total += g;
        }
        SegmentGram { per_segment, total }
    }

    /// Several drives' Grams of the same columns as one: their segments
    /// side by side, their information summed.
    pub(super) fn pooled<'g>(
        grams: impl IntoIterator<Item = &'g SegmentGram>,
    ) -> Option<SegmentGram> {
        let mut out: Option<SegmentGram> = None;
        for g in grams {
            match &mut out {
                None => out = Some(g.clone()),
                Some(o) if o.total.shape() == g.total.shape() => {
                    o.total += &g.total;
                    o.per_segment.extend(g.per_segment.iter().cloned());
                }
                Some(_) => return None,
            }
        }
        out
    }

    /// The Gram of columns (the data first) whose rows belong to the
    /// segments `segment_of_row` (each below `segments`); segments without
    /// rows are left out.
    fn from_rows(cols: &[Vec<f64>], segment_of_row: &[usize], segments: usize) -> SegmentGram {
        let m = cols.len();
        let mut per_segment = vec![DMatrix::zeros(m, m); segments];
        let mut seen = vec![false; segments];
        for (r, &seg) in segment_of_row.iter().enumerate() {
            let Some(g) = per_segment.get_mut(seg) else {
                continue;
            };
            seen[seg] = true;
            for a in 0..m {
                for b in 0..m {
                    g[(a, b)] += cols[a][r] * cols[b][r];
                }
            }
        }
        let per_segment: Vec<DMatrix<f64>> = per_segment
            .into_iter()
            .zip(seen)
            .filter_map(|(g, s)| s.then_some(g))
            .collect();
        let mut total = DMatrix::zeros(m, m);
        for g in &per_segment {
            total += g;
        }
        SegmentGram { per_segment, total }
    }

    /// The same Gram with another data column `w0` (whitened, rows as
    /// [`SegmentGram::new`]'s) in place of column 0 of `w`.
    pub(super) fn with_data(
        &self,
        w0: &[f64],
        w: &[Vec<f64>],
        segment_sizes: &[usize],
    ) -> SegmentGram {
        let m = w.len();
        let mut per_segment = self.per_segment.clone();
        for g in &mut per_segment {
            for b in 0..m {
                g[(0, b)] = 0.0;
            }
        }
        // Rows: the east values of every fix, then the north values.
        let mut row = 0;
        for _axis in 0..2 {
            for (g, size) in per_segment.iter_mut().zip(segment_sizes) {
                let rows = row..row + size;
                let d = &w0[rows.clone()];
                g[(0, 0)] += d.iter().map(|x| x * x).sum::<f64>();
                for b in 1..m {
                    g[(0, b)] += d
                        .iter()
                        .zip(&w[b][rows.clone()])
                        .map(|(x, y)| x * y)
                        .sum::<f64>();
                }
                row += size;
            }
        }
        let mut total = DMatrix::zeros(m, m);
        for g in &mut per_segment {
            for b in 1..m {
                g[(b, 0)] = g[(0, b)];
            }
            total += &*g;
        }
        SegmentGram { per_segment, total }
    }

    /// Segments.
    pub(super) fn segments(&self) -> usize {
        self.per_segment.len()
    }

    /// The information of column `c` with nothing else fitted.
    pub(super) fn information(&self, c: usize) -> f64 {
        self.total[(c, c)]
    }
}

/// What one drive tells of the car's effects of one information source:
/// the data column first, then the effects, the drive's own nuisances and
/// effects of the day profiled out.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct SourceGram {
    pub(super) source: InformationSource,
    pub(super) effects: Vec<Effect>,
    pub(super) gram: SegmentGram,
}

/// What a drive tells of its car, for pooling with other drives of it
/// ([`super::pool`]): per source, the car's effects with the drive's own
/// terms profiled out; the heading sensor's bias from its channel.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveInformation {
    pub(super) grams: Vec<SourceGram>,
    pub(super) heading: Option<CoefFit>,
    /// The compass bias's three terms, for their joint test over drives.
    pub(super) heading_terms: Option<HeadingTerms>,
}

/// The finite-difference step of a parameter: 5 % of its typical size;
/// the GNSS latency's [`LATENCY_STEP_S`].
fn step_of(p: Param) -> f64 {
    if p == Param::GnssLatency {
        return LATENCY_STEP_S;
    }
    0.05 * p.spec().typical.abs().max(1e-9)
}

/// The GNSS latency's finite-difference step, s. Its fingerprint is the
/// dead-reckoning read earlier and later by the step: the car's velocity
/// over twice the step. Over a step of a few milliseconds (5 % of the
/// typical latency) that velocity is one or two wheel samples' worth of
/// encoder ticks: at 96 ticks per revolution and 15 m/s, about seven
/// ticks per 10 ms sample, so 15 % noise on every fix's fingerprint. The
/// GNSS error's Gauss-Markov part is whitened by what is nearly a
/// difference between consecutive fixes, which keeps that noise and takes
/// the smooth true signal down to its changes: a regressor with noise of
/// its own (errors in variables) and the estimate shrinks toward zero. On
/// a 30-minute simulated drive with a 0.16 s latency and 1 m of wander it
/// was read at 0.33x alone and 0.07x beside its partners, the slip and the
/// antenna named in its place; with 100 000 ticks per revolution at 0.98x.
/// A quarter of a second either way averages 50 wheel samples at 100 Hz;
/// the latency's own signal changes over seconds (its second-order term,
/// step^2 / 6 times the jerk, is negligible).
const LATENCY_STEP_S: f64 = 0.25;

/// The information limit of every effect on this drive.
pub fn information_limit(input: &LimitInput<'_>) -> Result<InformationLimit, InformationError> {
    limit_and_information(input, false).map(|(l, _, _)| l)
}

/// One heading source's fixed parts, as the information limit computed
/// them: the noise to redraw from, the whitened columns, their Gram and
/// the fits' columns per effect.
pub(super) struct RedrawSource {
    pub(super) noise: [PositionNoise; 2],
    pub(super) w: Vec<Vec<f64>>,
    pub(super) gram: SegmentGram,
    pub(super) sets: Vec<JointSet>,
}

/// One effect's fits on a heading source: `cols` holds the effect's column
/// first, then its nuisances (the first `n_alone` make its fit alone), then
/// every other effect of the source; `signed` lists those others whose
/// sign the physics fixes ([`Effect::sign_known`]), held at zero in the
/// joint fit where they fall below it ([`SegmentGram::fit_within_signs`]).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct JointSet {
    pub(super) effect: Effect,
    pub(super) cols: Vec<usize>,
    pub(super) n_alone: usize,
    pub(super) signed: Vec<usize>,
}

/// What the false-alarm redraws ([`super::montecarlo`]) reuse of the
/// limit's computation: each heading source's whitened columns and error
/// model, at the fix times of the segments.
pub struct RedrawBasis {
    pub(super) sources: Vec<RedrawSource>,
    pub(super) all_t: Vec<f64>,
    pub(super) segment_sizes: Vec<usize>,
    /// The heading channel's, when the drive has a heading sensor.
    pub(super) heading: Option<HeadingRedraw>,
}

/// [`information_limit`], with what the drive tells of the car's effects
/// for pooling it with other drives of the same car ([`super::pool`]),
/// and with `keep_redraw_basis` the whitened columns the false-alarm
/// redraws reuse ([`super::montecarlo`]).
pub fn limit_and_information(
    input: &LimitInput<'_>,
    keep_redraw_basis: bool,
) -> Result<(InformationLimit, DriveInformation, Option<RedrawBasis>), InformationError> {
    let alpha = FAMILY_ALPHA / Effect::ALL.len() as f64;
    let times = common_times(input, step_of(Param::GnssLatency));
    let all_t: Vec<f64> = times.iter().flatten().copied().collect();
    if all_t.len() < 10 {
        return Err(InformationError::BadData(format!(
            "{} fixes in segments the dead-reckoning reaches; at least 10",
            all_t.len()
        )));
    }
    let segment_sizes: Vec<usize> = times.iter().map(Vec::len).filter(|n| *n > 0).collect();
    let z_critical = t_quantile(
        1.0 - 0.5 * alpha,
        segment_sizes.len().saturating_sub(1) as f64,
    );
    let mut limits = BTreeMap::new();
    let mut noises = Vec::new();
    let mut grams = Vec::new();
    let mut redraw_from = Vec::new();
    for heading in [HeadingSource::Wheels, HeadingSource::Gyro] {
        let src = Columns::build(input, heading, &times);
        // The calibration's error model was fitted to the plain model's
        // residuals, which hold every effect the plain model leaves out:
        // refit it to what is left once every effect of this source is in
        // (the dead-reckoning's own errors, wheel or gyro, included).
        let refit = refit_noise(&times, &src);
        let noise = refit.or(input.noise).ok_or_else(|| {
            InformationError::BadNoise(
                "the residuals show too few lags for a GNSS error model, and the calibration fitted none"
                    .into(),
            )
        })?;
        if src.cols.iter().any(|c| c.len() != all_t.len()) {
            return Err(InformationError::BadData(
                "the segments' fixes and fingerprints disagree in number".into(),
            ));
        }
        let w = whitened(&all_t, &noise, &src.cols)?;
        let gram = SegmentGram::new(&w, &segment_sizes);
        let sets = src.column_sets(&w, &gram);
        let (ls, source_gram) = src.limits(&gram, &sets, z_critical);
        for l in ls {
            keep_better(&mut limits, l);
        }
        grams.push(source_gram);
        noises.push((noise, refit.is_some()));
        if keep_redraw_basis {
            redraw_from.push(RedrawSource {
                noise,
                w,
                gram,
                sets,
            });
        }
    }
    let (noise, refitted) = noises[0];
    // Without a heading sensor the drive holds nothing about its bias.
    let dof = segment_sizes.len().saturating_sub(1) as f64;
    let (heading, heading_joint) = heading_channel(input.design, dof, alpha);
    let mut heading_limit = limit_of(
        Effect::HeadingBias,
        heading,
        z_critical,
        InformationSource::HeadingChannel,
    );
    // The three terms tested together decide; the estimate and sigma shown
    // stay the constant term's.
    if heading_limit.wald_z.is_some() {
        let shown = |v: f64| Effect::HeadingBias.main_fitted().to_display(v).abs();
        heading_limit.joint = heading_joint.map(|j| Joint {
            smallest: Some(shown(j.smallest)),
            estimate: heading_limit.estimate,
            sigma: heading_limit.sigma,
            sigma_fisher: heading_limit.sigma_fisher,
            sigma_segments: heading_limit.sigma_segments,
            wald_z: Some(j.z),
            partners: Vec::new(),
            terms: Some(j.terms),
            held_at_zero: Vec::new(),
            sigma_all_free: None,
            estimate_all_free: None,
        });
    }
    limits.insert(Effect::HeadingBias, heading_limit);
    for l in limits.values_mut() {
        l.set_power_at_typical(z_critical);
    }
    let arr = |n: &PositionNoise| [n.white_sigma_m, n.gm_sigma_m, n.gm_tau_s];
    let limit = InformationLimit {
        family_alpha: FAMILY_ALPHA,
        alpha_per_effect: alpha,
        power: POWER,
        z_critical,
        segments: times.iter().filter(|t| !t.is_empty()).count(),
        segment_s: input.spans.first().map_or(0.0, |(a, b)| b - a),
        fixes: all_t.len(),
        noise_refitted: refitted,
        noise_east: arr(&noise[0]),
        noise_north: arr(&noise[1]),
        noise_gyro_heading: [arr(&noises[1].0[0]), arr(&noises[1].0[1])],
        calibration_noise_east: input.noise.map(|n| arr(&n[0])),
        calibration_noise_north: input.noise.map(|n| arr(&n[1])),
        effects: Effect::ALL
            .iter()
            .filter_map(|e| limits.remove(e))
            .collect(),
    };
    let basis = keep_redraw_basis.then(|| RedrawBasis {
        sources: redraw_from,
        all_t,
        segment_sizes,
        heading: HeadingRedraw::new(input.design, dof, alpha),
    });
    let heading_terms = limit
        .effects
        .iter()
        .find(|e| e.effect == Effect::HeadingBias)
        .and_then(|e| e.joint.as_ref())
        .and_then(|j| j.terms.clone());
    Ok((
        limit,
        DriveInformation {
            grams,
            heading,
            heading_terms,
        },
        basis,
    ))
}

/// The sigma an effect's limit is decided with: its joint fit's where it
/// has one, else its own; infinite without either.
pub(super) fn decisive_sigma(l: &EffectLimit) -> f64 {
    l.joint
        .as_ref()
        .and_then(|j| j.sigma_all_free.or(j.sigma))
        .or(l.sigma)
        .filter(|s| s.is_finite() && *s > 0.0)
        .unwrap_or(f64::INFINITY)
}

/// Keeps in `limits` the limit of `l`'s effect with the smaller decisive
/// sigma: an effect both heading sources see is decided under the one that
/// knows it better. Chosen by the sigma, never by the estimate, so the
/// choice does not favour a finding; the false-alarm redraws
/// ([`super::montecarlo`]) choose the same way on every draw.
/// The one not kept is remembered in the kept one's
/// [`EffectLimit::other_source`].
fn keep_better(limits: &mut BTreeMap<Effect, EffectLimit>, mut l: EffectLimit) {
    match limits.get_mut(&l.effect) {
        Some(old) if decisive_sigma(old) <= decisive_sigma(&l) => {
            old.other_source = OtherSource::of(&l);
        }
        Some(old) => {
            l.other_source = OtherSource::of(old);
            *old = l;
        }
        None => {
            limits.insert(l.effect, l);
        }
    }
}

/// Realisations of simulated errors per candidate model.
const REALISATIONS: usize = 4;

/// The GNSS error model (white plus Gauss-Markov per axis) of the residual
/// left when every effect and nuisance of `cols` (the first column the
/// residual, the rest regressors) is fitted jointly by least squares. The
/// joint fit hides part of the error (each segment's pose absorbs its
/// offset and rotation), so the observed semivariogram is matched to the
/// expected residual semivariogram of unit white and unit Gauss-Markov
/// errors passed through the same fit, for a grid of correlation times; the
/// best match wins. `None` when the residual shows fewer than three lags.
///
/// The segments' poses are local to their segment, so they are projected
/// out segment by segment (three columns each) and only the few global
/// columns go through a QR decomposition: linear in the drive's length.
fn refit_noise(times: &[Vec<f64>], src: &Columns) -> Option<[PositionNoise; 2]> {
    let fit = JointFit::new(times, src)?;
    let n = fit.n;
    let mut gaps: Vec<f64> = times
        .iter()
        .flat_map(|s| s.windows(2).map(|w| w[1] - w[0]))
        .collect();
    let dt = stats::median(&mut gaps).filter(|d| *d > 0.0)?;
    let r = DVector::from_fn(2 * n, |i, _| stacked(&fit.cols[0], i, n));
    let e = fit.residual(&r);
    let observed = [
        variogram(&fit.series(&e, 0), dt),
        variogram(&fit.series(&e, 1), dt),
    ];
    if observed.iter().any(|g| g.len() < 3) {
        return None;
    }
    let max_lag = observed[0].iter().map(|g| g.0).fold(0.0, f64::max);
    let all_t: Vec<f64> = times.iter().flatten().copied().collect();
    let white = fit.simulate(&observed, dt, &|rng| {
        DVector::from_fn(2 * n, |_, _| rng.next())
    });
    let mut best: [Option<(f64, PositionNoise)>; 2] = [None, None];
    let mut tau = 2.0 * dt;
    while tau <= 30.0 * max_lag {
        let gm = fit.simulate(&observed, dt, &|rng| gauss_markov(rng, &all_t, n, tau));
        for axis in 0..2 {
            if let Some((sse, w, g)) = nnls2(&observed[axis], &white[axis], &gm[axis]) {
                if best[axis].is_none_or(|(b, _)| sse < b) {
                    let total = (w + g).sqrt();
                    best[axis] = Some((
                        sse,
                        PositionNoise {
                            // A white floor of 5 % of the total keeps the
                            // model whitenable (a little less information,
                            // never more).
                            white_sigma_m: w.sqrt().max(0.05 * total),
                            gm_sigma_m: g.sqrt(),
                            gm_tau_s: tau,
                        },
                    ));
                }
            }
        }
        tau *= 2.0;
    }
    let [e, nn] = best;
    Some([e?.1, nn?.1])
}

/// Row `i` of column `c` stacked east over north (`n` rows each).
fn stacked(c: &Col, i: usize, n: usize) -> f64 {
    if i < n {
        c[i][0]
    } else {
        c[i - n][1]
    }
}

/// Unit Gauss-Markov errors of correlation time `tau` at the times
/// `all_t`, east then north (`n` each).
pub(super) fn gauss_markov(rng: &mut Normal, all_t: &[f64], n: usize, tau: f64) -> DVector<f64> {
    let mut v = DVector::zeros(2 * n);
    for axis in 0..2 {
        let mut x = rng.next();
        let mut prev = all_t[0];
        for (k, t) in all_t.iter().enumerate() {
            let rho = (-(t - prev).abs() / tau).exp();
            x = rho * x + (1.0 - rho * rho).max(0.0).sqrt() * rng.next();
            prev = *t;
            v[axis * n + k] = x;
        }
    }
    v
}

/// The joint least-squares fit of [`refit_noise`] as a projection: what
/// of an error vector (east over north) is left after the fit.
struct JointFit<'a> {
    times: &'a [Vec<f64>],
    cols: &'a [Col],
    /// Rows per axis.
    n: usize,
    /// Rows of each segment (east; north is the same plus n) and its poses.
    segments: Vec<(std::ops::Range<usize>, Vec<usize>)>,
    /// Orthonormal basis of the global columns, poses projected out.
    q: DMatrix<f64>,
}

impl<'a> JointFit<'a> {
    /// The fit of the columns of `src` (`None` without rows).
    fn new(times: &'a [Vec<f64>], src: &'a Columns) -> Option<JointFit<'a>> {
        let cols = &src.cols;
        let n = cols.first()?.len();
        let first_pose = src.first_effect + src.effects.len();
        let pose_end = first_pose + src.pose_segment.len();
        let global: Vec<usize> = (1..first_pose).chain(pose_end..cols.len()).collect();
        // Rows of each segment (east; north is the same plus n) and its poses.
        let mut segments: Vec<(std::ops::Range<usize>, Vec<usize>)> = Vec::new();
        let mut at = 0;
        for (k, size) in times.iter().map(Vec::len).filter(|l| *l > 0).enumerate() {
            let poses = (first_pose..pose_end)
                .filter(|c| src.pose_segment[c - first_pose] == k)
                .collect();
            segments.push((at..at + size, poses));
            at += size;
        }
        let mut fit = JointFit {
            times,
            cols,
            n,
            segments,
            q: DMatrix::zeros(0, 0),
        };
        let mut g = DMatrix::from_fn(2 * n, global.len(), |i, j| stacked(&cols[global[j]], i, n));
        for mut c in g.column_iter_mut() {
            let mut v = DVector::from_column_slice(c.as_slice());
            fit.without_poses(&mut v);
            c.copy_from(&v);
        }
        fit.q = g.qr().q();
        Some(fit)
    }

    /// v less its least-squares fit on each segment's own poses.
    fn without_poses(&self, v: &mut DVector<f64>) {
        let (cols, n) = (self.cols, self.n);
        for (rows, poses) in &self.segments {
            let idx: Vec<usize> = rows.clone().chain(rows.start + n..rows.end + n).collect();
            let p = DMatrix::from_fn(idx.len(), poses.len(), |i, j| {
                stacked(&cols[poses[j]], idx[i], n)
            });
            let y = DVector::from_fn(idx.len(), |i, _| v[idx[i]]);
            let Some(chol) = (p.transpose() * &p).cholesky() else {
                continue;
            };
            let fitted = &p * chol.solve(&(p.transpose() * &y));
            for (i, r) in idx.iter().enumerate() {
                v[*r] -= fitted[i];
            }
        }
    }

    /// What of `e` the joint fit leaves.
    fn residual(&self, e: &DVector<f64>) -> DVector<f64> {
        let mut v = e.clone();
        self.without_poses(&mut v);
        let proj = &self.q * (self.q.transpose() * &v);
        v - proj
    }

    /// One axis of `v` as time series, one per non-empty segment.
    fn series(&self, v: &DVector<f64>, axis: usize) -> Vec<Vec<(f64, f64)>> {
        let mut at = axis * self.n;
        self.times
            .iter()
            .filter(|s| !s.is_empty())
            .map(|s| {
                let out = s.iter().enumerate().map(|(k, t)| (*t, v[at + k])).collect();
                at += s.len();
                out
            })
            .collect()
    }

    /// The mean residual semivariogram of simulated errors (`make`), per
    /// axis, at the `observed` lags.
    fn simulate(
        &self,
        observed: &[Vec<(f64, f64, usize)>; 2],
        dt: f64,
        make: &dyn Fn(&mut Normal) -> DVector<f64>,
    ) -> [Vec<f64>; 2] {
        let mut rng = Normal::new(0x5EED_0037);
        let mut out = [vec![0.0; observed[0].len()], vec![0.0; observed[1].len()]];
        for _ in 0..REALISATIONS {
            let res = self.residual(&make(&mut rng));
            for (axis, row) in out.iter_mut().enumerate() {
                let g = variogram(&self.series(&res, axis), dt);
                for (o, obs) in row.iter_mut().zip(&observed[axis]) {
                    *o += g
                        .iter()
                        .find(|x| (x.0 - obs.0).abs() <= (0.25 * dt).max(0.1 * obs.0))
                        .map_or(0.0, |v| v.1)
                        / REALISATIONS as f64;
                }
            }
        }
        out
    }
}

/// The limit of one effect from its profiled information and estimate
/// (model units).
pub(super) fn limit_of(
    effect: Effect,
    fit: Option<CoefFit>,
    z_critical: f64,
    source: InformationSource,
) -> EffectLimit {
    let p = effect.main_fitted();
    let spec = p.spec();
    let squared = matches!(main_kick(effect), Kick::Squared(_));
    let shown = |v: f64| p.to_display(v).abs();
    // The information is about the square of a squared term: its smallest
    // size is the root of the square's.
    let z_power = normal_quantile(POWER);
    let size_fit = fit.map_or(f64::INFINITY, |f| (z_critical + z_power) * f.sigma());
    let size = if squared { size_fit.sqrt() } else { size_fit };
    // An information below what the numbers resolve is none.
    let fit = fit.filter(|_| size.is_finite() && size < 1e6 * spec.typical.abs());
    EffectLimit {
        effect,
        parameter: spec.name,
        unit: spec.unit,
        typical: shown(spec.typical),
        smallest: fit.map(|_| shown(size)),
        relative_to_typical: fit.map(|_| size / spec.typical.abs()),
        source,
        estimate_of: if squared {
            format!("{}^2", spec.name)
        } else {
            spec.name.to_string()
        },
        estimate: fit.map(|f| p.to_display(f.estimate)),
        sigma: fit.map(|f| shown(f.sigma())),
        sigma_fisher: fit.map(|f| shown(f.sigma_fisher)),
        sigma_segments: fit.and_then(|f| f.sigma_segments.map(shown)),
        wald_z: fit.map(|f| f.estimate / f.sigma()),
        joint: None,
        other_source: None,
        power_at_typical: None,
    }
}

/// The heading bias's three terms tested together on the heading channel
/// (model units): the equivalent Wald z of their joint test and the
/// smallest size it shows (see [`heading_channel`]).
#[derive(Debug, Clone, PartialEq)]
struct HeadingJoint {
    z: f64,
    smallest: f64,
    /// The three terms, the covariance the statistic used, the blocks.
    terms: HeadingTerms,
}

/// The compass bias's three terms (constant, sin and cos of the course)
/// as one drive's heading channel fits them, reported unit: what a
/// comparison of two drives or the pooling of several tests jointly.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeadingTerms {
    /// The three estimates.
    pub estimate: [f64; 3],
    /// Their covariance (the larger of the Fisher one and the blocks'
    /// sandwich, in the sense of the statistic).
    pub covariance: [[f64; 3]; 3],
    /// The blocks the sandwich is over.
    pub blocks: usize,
}

/// The |t| with `dof` degrees of freedom of the joint Wald test of
/// `theta` under `cov` estimated from `k` blocks (Hotelling's reference,
/// as [`heading_channel`]'s), signed as the largest term's own z; `None`
/// with too few blocks or a singular covariance.
pub(super) fn joint_t(theta: &DVector<f64>, cov: &DMatrix<f64>, k: usize, dof: f64) -> Option<f64> {
    let p = theta.len();
    if k < p + 2 {
        return None;
    }
    let inv = cov.clone().cholesky()?.inverse();
    let w = (theta.transpose() * &inv * theta)[(0, 0)];
    let (pf, kf) = (p as f64, k as f64);
    let z = t_equivalent(f_sf(w * (kf - pf) / (pf * (kf - 1.0)), pf, kf - pf), dof);
    let sign = (0..p)
        .map(|i| theta[i] / cov[(i, i)].sqrt())
        .max_by(|a, b| a.abs().total_cmp(&b.abs()))
        .map_or(1.0, f64::signum);
    (w.is_finite() && z.is_finite()).then_some(sign * z)
}

impl HeadingTerms {
    /// The estimates and covariance as matrices, reported unit.
    pub(super) fn matrices(&self) -> (DVector<f64>, DMatrix<f64>) {
        (
            DVector::from_column_slice(&self.estimate),
            DMatrix::from_fn(3, 3, |i, j| self.covariance[i][j]),
        )
    }
}

/// The heading bias from the heading channel (heading sensor against the
/// GNSS course), the rows' serial correlation counted by the AR(1)
/// effective sample size.
///
/// First its constant term (the sin and cos terms profiled out): its
/// profiled information and estimate. Then its three terms (constant, sin
/// and cos of the course) together, with `dof` the degrees of freedom of
/// the Student t the decision's critical values come from and `alpha` the
/// per-effect level:
///
/// - the Wald statistic `W = beta' C^-1 beta` of the three coefficients
///   `beta`, with `C` the larger covariance in the sense of the statistic:
///   `W` is the smaller of the Fisher information's (lag-1 factor
///   included) and the blocks' sandwich's;
/// - its p-value from Hotelling's reference for a covariance estimated
///   from `k` blocks: `W (k - 3) / (3 (k - 1))` is F(3, k - 3) (for one
///   term this is the t with k - 1 degrees of freedom the other effects'
///   z is held against);
/// - the |t| with `dof` degrees of freedom of the same two-sided p-value,
///   signed as the term whose own `beta_i / sqrt(C_ii)` is the largest in
///   size: Holm's procedure treats it as every other effect's z;
/// - its smallest size: the size that any one of the three terms alone
///   (the others zero) reaches the joint test's critical value with 90 %
///   power at, the largest over the three terms (the power of the chi-square
///   with three degrees of freedom and noncentrality `s^2 (C^-1)_ii`, at the
///   critical `W` of Hotelling's reference).
///
/// The joint test needs at least five blocks (else `None` for it: the
/// constant term alone decides).
fn heading_channel(d: &Design, dof: f64, alpha: f64) -> (Option<CoefFit>, Option<HeadingJoint>) {
    match heading_rows(d) {
        Some(h) => heading_test(&h, &h.y, dof, alpha),
        None => (None, None),
    }
}

/// The heading channel's rows as the test weighs them: the data, the
/// regressors (the bias's three terms first, then the free ones), each
/// row's square-rooted weight and block.
#[derive(Debug, Clone)]
pub(super) struct HeadingRows {
    y: Vec<f64>,
    x: Vec<Vec<f64>>,
    sqrt_w: Vec<f64>,
    block: Vec<usize>,
    blocks: usize,
}

/// The heading channel's rows of the design; `None` without a heading
/// sensor or with fewer than ten rows.
fn heading_rows(d: &Design) -> Option<HeadingRows> {
    let cand = d
        .candidates
        .iter()
        .find(|c| c.effect == Effect::HeadingBias && c.params.len() >= 3)?;
    let rows: Vec<usize> = (0..d.rows.len())
        .filter(|&i| d.rows[i].0 == Channel::Heading && d.w[i] > 0.0)
        .collect();
    if rows.len() < 10 {
        return None;
    }
    // The bias's three terms, then what else turns the GNSS course
    // against the car's heading in this channel, fitted free beside them:
    // the side-slip (a_y), the GNSS latency and a longitudinal antenna
    // offset (the yaw rate). Without them a car that corners more one way
    // than the other shows its tyres' mean side-slip as a compass bias.
    let mut terms: Vec<usize> = cand.params[..3].iter().map(|p| p.column).collect();
    // (The side-slip's variant on the gyro's channels only is the same
    // column here: left out.)
    for c in d.candidates.iter().filter(|c| {
        matches!(
            c.effect,
            Effect::SideSlip | Effect::GnssLatency | Effect::GnssLeverArm
        ) && !c.seen_by_gyro()
    }) {
        for &k in &c.columns {
            if !terms.contains(&k) && rows.iter().any(|&i| d.columns[k][i] != 0.0) {
                terms.push(k);
            }
        }
    }
    let sqrt_w: Vec<f64> = rows.iter().map(|&i| d.w[i].sqrt()).collect();
    let weighted =
        |v: &[f64]| -> Vec<f64> { rows.iter().zip(&sqrt_w).map(|(&i, s)| v[i] * s).collect() };
    Some(HeadingRows {
        y: weighted(&d.y),
        x: terms.iter().map(|&c| weighted(&d.columns[c])).collect(),
        block: rows.iter().map(|&i| d.rows[i].2).collect(),
        sqrt_w,
        blocks: d.blocks,
    })
}

/// [`heading_channel`]'s fits of the data `y` (weighted, as `h.y`) on the
/// rows `h`: the same for the drive and for each false-alarm redraw.
fn heading_test(
    h: &HeadingRows,
    y: &[f64],
    dof: f64,
    alpha: f64,
) -> (Option<CoefFit>, Option<HeadingJoint>) {
    let Ok((info, estimate)) = profiled_estimate(&h.x[0], &h.x[1..], y) else {
        return (None, None);
    };
    let mut cols = vec![y.to_vec()];
    cols.extend(h.x.iter().cloned());
    let gram = SegmentGram::from_rows(&cols, &h.block, h.blocks);
    let all: Vec<usize> = (1..cols.len()).collect();
    let multi = gram.fit_all(&all);
    // The residual after every term (unweighted), and its lag-1
    // correlation.
    let theta: Vec<f64> = multi.as_ref().map_or_else(
        || {
            let mut t = vec![0.0; h.x.len()];
            t[0] = estimate;
            t
        },
        |m| m.theta.iter().copied().collect(),
    );
    let resid: Vec<f64> = (0..y.len())
        .map(|i| (y[i] - h.x.iter().zip(&theta).map(|(c, t)| t * c[i]).sum::<f64>()) / h.sqrt_w[i])
        .collect();
    let rho = lag1(&resid).clamp(0.0, 0.99);
    let factor = (1.0 - rho) / (1.0 + rho);
    let info = info * factor;
    // The blocks' own scatter of the estimate: a heading residual that
    // wanders slower than one lag (a mean side-slip in the corners of one
    // stretch) shows there and not in the lag-1 correlation.
    let sigma_segments = gram.fit(&all).and_then(|f| f.sigma_segments);
    let alone = (info > 0.0).then(|| CoefFit {
        estimate,
        sigma_fisher: info.powf(-0.5),
        sigma_segments,
    });
    // The three terms' own covariance: the top-left block of the full fit's
    // (the free terms profiled out).
    let joint = multi
        .map(|m| m.leading(3))
        .and_then(|m| joint_test(&m, factor, gram.segments(), dof, alpha));
    (alone, joint)
}

/// The heading channel's false-alarm redraw: what [`heading_test`] needs
/// and the drive's residual's scale and lag-1 correlation (weighted
/// units) to draw AR(1) errors from.
#[derive(Debug, Clone)]
pub(super) struct HeadingRedraw {
    rows: HeadingRows,
    sigma: f64,
    rho: f64,
    dof: f64,
    alpha: f64,
}

impl HeadingRedraw {
    /// The redraw basis of the drive's heading channel, `None` without one.
    fn new(d: &Design, dof: f64, alpha: f64) -> Option<HeadingRedraw> {
        let rows = heading_rows(d)?;
        let mut cols = vec![rows.y.clone()];
        cols.extend(rows.x.iter().cloned());
        let gram = SegmentGram::from_rows(&cols, &rows.block, rows.blocks);
        let all: Vec<usize> = (1..cols.len()).collect();
        let theta = gram.fit_all(&all)?.theta;
        let r: Vec<f64> = (0..rows.y.len())
            .map(|i| {
                rows.y[i]
                    - rows
                        .x
                        .iter()
                        .zip(theta.iter())
                        .map(|(c, t)| t * c[i])
                        .sum::<f64>()
            })
            .collect();
        let n = r.len() as f64;
        let sigma = (r.iter().map(|v| v * v).sum::<f64>() / (n - all.len() as f64).max(1.0)).sqrt();
        let rho = lag1(&r).clamp(0.0, 0.99);
        (sigma > 0.0).then_some(HeadingRedraw {
            rows,
            sigma,
            rho,
            dof,
            alpha,
        })
    }

    /// One redraw's decisive z for the heading bias (the joint test's,
    /// else the constant term's alone): the channel's errors drawn as an
    /// AR(1) series of the drive's scale and lag-1 correlation, tested as
    /// the drive is.
    pub(super) fn z(&self, rng: &mut Normal) -> Option<(f64, bool)> {
        let innovation = self.sigma * (1.0 - self.rho * self.rho).sqrt();
        let mut e = self.sigma * rng.next();
        let y: Vec<f64> = (0..self.rows.y.len())
            .map(|i| {
                if i > 0 {
                    e = self.rho * e + innovation * rng.next();
                }
                e
            })
            .collect();
        let (alone, joint) = heading_test(&self.rows, &y, self.dof, self.alpha);
        match (joint, alone) {
            (Some(j), _) => Some((j.z, true)),
            (None, Some(a)) => Some((a.estimate / a.sigma(), false)),
            (None, None) => None,
        }
        .filter(|(z, _)| z.is_finite())
    }
}

/// The joint test of every coefficient of `m` (see [`heading_channel`]):
/// the Fisher covariance is `m`'s divided by `factor`, the sandwich is over
/// `k` blocks.
fn joint_test(m: &MultiFit, factor: f64, k: usize, dof: f64, alpha: f64) -> Option<HeadingJoint> {
    let p = m.theta.len();
    if k < p + 2 || factor <= 0.0 {
        return None;
    }
    let fisher = &m.inverse / factor;
    let candidates = std::iter::once(fisher).chain(m.sandwich.clone());
    // Per covariance: its inverse and the statistic; the smaller statistic
    // (the larger covariance) wins.
    let (precision, _, cov) = candidates
        .filter_map(|c| {
            let inv = c.clone().cholesky()?.inverse();
            let w = (m.theta.transpose() * &inv * &m.theta)[(0, 0)];
            w.is_finite().then_some((inv, w, c))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let (pf, kf) = (p as f64, k as f64);
    let to_f = (kf - pf) / (pf * (kf - 1.0));
    let p_value = |w: f64| f_sf(w * to_f, pf, kf - pf);
    let z = joint_t(&m.theta, &cov, k, dof)?;
    // The critical statistic at `alpha`, then the noncentrality the chi
    // with three degrees of freedom reaches it with at the power.
    let w_critical = bisect(0.0, 1e4, |w| p_value(w) > alpha);
    let r = w_critical.sqrt();
    let mu = bisect(0.0, r + 20.0, |mu| 1.0 - noncentral_chi3_cdf(r, mu) < POWER);
    let smallest = (0..p)
        .map(|i| mu / precision[(i, i)].max(f64::MIN_POSITIVE).sqrt())
        .fold(0.0, f64::max);
    let shown = Effect::HeadingBias.main_fitted().to_display(1.0);
    let terms = (p == 3).then(|| HeadingTerms {
        estimate: [0, 1, 2].map(|i| shown * m.theta[i]),
        covariance: [0, 1, 2].map(|i| [0, 1, 2].map(|j| shown * shown * cov[(i, j)])),
        blocks: k,
    })?;
    smallest
        .is_finite()
        .then_some(HeadingJoint { z, smallest, terms })
}

fn lag1(x: &[f64]) -> f64 {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let var: f64 = x.iter().map(|v| (v - mean).powi(2)).sum();
    if var <= 0.0 {
        return 0.0;
    }
    let cov: f64 = x.windows(2).map(|w| (w[0] - mean) * (w[1] - mean)).sum();
    cov / var
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::information::{detectable_size, profiled_estimate};

    /// A small deterministic sequence of standard normal numbers.
    fn normals(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = crate::error_model::Normal::new(seed);
        (0..n).map(|_| rng.next()).collect()
    }

    /// The power at a size is what a test on the effect's estimate does:
    /// 90 % at the smallest size shown, the level where there is none, and
    /// the share of draws beyond the critical z elsewhere, for a term that
    /// acts directly and for one that acts through its square.
    #[test]
    fn the_power_at_a_size_is_the_tests_rejection_rate() {
        let zc = 3.4;
        for (effect, sigma) in [(Effect::GnssLatency, 0.02), (Effect::RoadGrade, 0.3)] {
            let fit = CoefFit {
                estimate: 0.0,
                sigma_fisher: sigma,
                sigma_segments: None,
            };
            let l = limit_of(
                effect,
                Some(fit),
                zc,
                InformationSource::PositionsGyroHeading,
            );
            let squared = l.estimate_of.ends_with("^2");
            assert_eq!(squared, effect == Effect::RoadGrade);
            let smallest = l.shown_smallest().unwrap();
            let at = |size: f64| l.power_at(size, zc).unwrap();
            assert!(
                (at(smallest) - POWER).abs() < 1e-3,
                "{effect:?}: {}",
                at(smallest)
            );
            let level = 2.0 * (1.0 - normal_cdf(zc));
            assert!((at(0.0) - level).abs() < 1e-12);
            // Draws of the estimate about a size between: how often the
            // Wald test calls it.
            let p = effect.main_fitted();
            let size = 0.7 * smallest;
            let model = size / p.to_display(1.0).abs();
            let mean = if squared { model * model } else { model };
            let draws = normals(40_000, 37);
            let called = draws
                .iter()
                .filter(|z| ((mean + sigma * *z) / sigma).abs() > zc)
                .count() as f64
                / draws.len() as f64;
            let want = at(size);
            assert!(want > 0.05 && want < 0.95, "{effect:?}: {want}");
            assert!(
                (called - want).abs() < 4.0 * (want * (1.0 - want) / draws.len() as f64).sqrt(),
                "{effect:?}: simulated {called}, computed {want}"
            );
        }
    }

    #[test]
    fn the_gram_fit_is_the_profiled_least_squares() {
        // Columns: data, target, two nuisances; 4 segments of 50 rows per
        // axis.
        let n = 200;
        let x: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.37).sin()).collect();
        let a: Vec<f64> = (0..2 * n).map(|i| 1.0 + (i % 7) as f64).collect();
        let b: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.05).cos()).collect();
        let e = normals(2 * n, 7);
        let y: Vec<f64> = (0..2 * n)
            .map(|i| 0.3 * x[i] + 2.0 * a[i] - b[i] + 0.1 * e[i])
            .collect();
        let w = vec![y.clone(), x.clone(), a.clone(), b.clone()];
        let gram = SegmentGram::new(&w, &[50, 50, 50, 50]);
        let fit = gram.fit(&[1, 2, 3]).expect("fit");
        let (info, est) = profiled_estimate(&x, &[a, b], &y).expect("profiled");
        assert!((fit.estimate - est).abs() < 1e-9, "{} {est}", fit.estimate);
        assert!((fit.sigma_fisher - info.powf(-0.5)).abs() < 1e-9);
        assert!((fit.estimate - 0.3).abs() < 5.0 * fit.sigma_fisher);
    }

    #[test]
    fn a_partner_of_the_sign_physics_forbids_is_held_at_zero_and_no_other() {
        // Columns: data, the effect tested, a partner that shares most of
        // its fingerprint (the antenna and a side-slip at one speed), a
        // second partner apart from both. The data holds the effect and
        // none of either partner; a partner's estimate falls below zero by
        // the noise and its correlation with the effect.
        let n = 400;
        let x: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.11).sin()).collect();
        let e = normals(2 * n, 41);
        let p: Vec<f64> = (0..2 * n).map(|i| x[i] + 0.3 * e[i]).collect();
        let q: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.023).cos()).collect();
        let noise = normals(2 * n, 42);
        let make = |partner: f64| -> SegmentGram {
            let y: Vec<f64> = (0..2 * n)
                .map(|i| 0.5 * x[i] + partner * p[i] + 0.2 * noise[i])
                .collect();
            SegmentGram::new(&[y, x.clone(), p.clone(), q.clone()], &[100; 4])
        };
        // The partner's true size below zero: the free fit puts it there,
        // the fit within the signs holds it at zero and fits the rest.
        let g = make(-0.2);
        let free = g.fit(&[1, 2, 3]).expect("free fit");
        let (within, held) = g.fit_within_signs(&[1, 2, 3], &[2]).expect("fit");
        assert_eq!(held, vec![2]);
        let without = g.fit(&[1, 3]).expect("fit without the partner");
        assert!((within.estimate - without.estimate).abs() < 1e-12);
        assert!(
            within.sigma_fisher < 0.5 * free.sigma_fisher,
            "{within:?} {free:?}"
        );
        // Unsigned, nothing is held: the free fit.
        let (same, none) = g.fit_within_signs(&[1, 2, 3], &[]).expect("fit");
        assert!(none.is_empty());
        assert_eq!(same, free);
        // The partner present with its physical sign: left free, the
        // effect's estimate the free fit's, near the truth.
        let g = make(0.3);
        let (fit, held) = g.fit_within_signs(&[1, 2, 3], &[2, 3]).expect("fit");
        assert!(held.is_empty(), "{held:?}");
        assert_eq!(Some(fit), g.fit(&[1, 2, 3]));
        assert!((fit.estimate - 0.5).abs() < 3.0 * fit.sigma(), "{fit:?}");
    }

    #[test]
    fn the_segments_sigma_agrees_with_the_fisher_sigma_on_white_noise_and_sees_more_when_there_is_more(
    ) {
        // Unit white noise: the Fisher sigma is right, and the sandwich over
        // 12 segments lands near it (its own spread is about 20 %).
        let segments = 12;
        let per = 100;
        let n = segments * per;
        let x: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.11).sin()).collect();
        let ones = vec![1.0; 2 * n];
        let mut ratios = Vec::new();
        for seed in 1..=20 {
            let y = normals(2 * n, seed);
            let w = vec![y, x.clone(), ones.clone()];
            let gram = SegmentGram::new(&w, &vec![per; segments]);
            let fit = gram.fit(&[1, 2]).expect("fit");
            ratios.push(fit.sigma_segments.expect("segments") / fit.sigma_fisher);
        }
        let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
        assert!((0.8..1.2).contains(&mean), "{ratios:?}");
        // Noise 3x what the whitening assumed: the sandwich sees it, the
        // Fisher sigma cannot, and the reported sigma is the larger.
        let y: Vec<f64> = normals(2 * n, 99).iter().map(|v| 3.0 * v).collect();
        let w = vec![y, x, ones];
        let fit = SegmentGram::new(&w, &vec![per; segments])
            .fit(&[1, 2])
            .expect("fit");
        let j = fit.sigma_segments.expect("segments");
        assert!(j > 2.0 * fit.sigma_fisher, "{fit:?}");
        assert_eq!(fit.sigma(), j);
    }

    #[test]
    fn the_joint_test_sees_a_sinusoid_the_constant_term_cannot() {
        // Three terms over 10 blocks of 100 rows: a constant, sin and cos
        // of a heading that turns; the data a pure sin term plus noise.
        let (blocks, per) = (10, 100);
        let n = blocks * per;
        let psi: Vec<f64> = (0..n).map(|i| i as f64 * 0.05).collect();
        let e = normals(n, 5);
        let y: Vec<f64> = (0..n).map(|i| 0.6 * psi[i].sin() + e[i]).collect();
        let cols = vec![
            y,
            vec![1.0; n],
            psi.iter().map(|p| p.sin()).collect(),
            psi.iter().map(|p| p.cos()).collect(),
        ];
        let block: Vec<usize> = (0..n).map(|i| i / per).collect();
        let gram = SegmentGram::from_rows(&cols, &block, blocks);
        let m = gram.fit_all(&[1, 2, 3]).expect("fit");
        let alone = gram.fit(&[1, 2, 3]).expect("alone");
        assert!((alone.estimate / alone.sigma()).abs() < 3.0, "{alone:?}");
        let alpha = FAMILY_ALPHA / 12.0;
        let j = joint_test(&m, 1.0, blocks, 9.0, alpha).expect("joint");
        assert!(j.z > t_quantile(1.0 - 0.5 * alpha, 9.0), "{j:?}");
        assert!(j.smallest < 0.6, "{j:?}");
        // Without the sinusoid the joint z stays small.
        let null: Vec<f64> = normals(n, 6);
        let mut cols = cols;
        cols[0] = null;
        let m = SegmentGram::from_rows(&cols, &block, blocks)
            .fit_all(&[1, 2, 3])
            .expect("fit");
        let j = joint_test(&m, 1.0, blocks, 9.0, alpha).expect("joint");
        assert!(j.z.abs() < 3.0, "{j:?}");
    }

    #[test]
    fn the_heading_channels_redraws_hold_the_level_and_a_planted_bias_shows() {
        // Twelve blocks of 60 rows: the course sweeps round twice, a_y
        // (a free term) wanders on its own; the errors are AR(1) of 0.01
        // rad, the rows weighed by their inverse variance as the design's
        // are (weighted rows have unit scale).
        let (n, blocks) = (720, 12);
        let course: Vec<f64> = (0..n)
            .map(|i| i as f64 * 4.0 * std::f64::consts::PI / n as f64)
            .collect();
        let ay: Vec<f64> = (0..n).map(|i| (i as f64 * 0.07).sin()).collect();
        let (sigma, rho): (f64, f64) = (0.01, 0.5);
        let s = 1.0 / sigma;
        let x = vec![
            vec![s; n],
            course.iter().map(|c| s * c.sin()).collect(),
            course.iter().map(|c| s * c.cos()).collect(),
            ay.iter().map(|a| s * a).collect(),
        ];
        let mut rng = crate::error_model::Normal::new(3);
        let mut e = 0.0;
        let y: Vec<f64> = (0..n)
            .map(|_| {
                e = rho * e + (1.0 - rho * rho).sqrt() * rng.next();
                e
            })
            .collect();
        let rows = HeadingRows {
            y: y.clone(),
            x,
            sqrt_w: vec![s; n],
            block: (0..n).map(|i| i * blocks / n).collect(),
            blocks,
        };
        let (dof, alpha) = ((blocks - 1) as f64, 0.1);
        let redraw = HeadingRedraw {
            rows: rows.clone(),
            sigma: 1.0,
            rho,
            dof,
            alpha,
        };
        // At the level alpha: the share of redraws beyond its critical |t|
        // stays at or below alpha (the sigma is the larger of two, so the
        // test may be conservative, never liberal beyond the scatter).
        let critical = t_quantile(1.0 - 0.5 * alpha, dof);
        let draws = 400;
        let beyond = (0..draws)
            .filter_map(|_| redraw.z(&mut rng))
            .filter(|(z, joint)| *joint && z.abs() > critical)
            .count();
        let rate = beyond as f64 / draws as f64;
        let binomial = (alpha * (1.0 - alpha) / draws as f64).sqrt();
        assert!(rate <= alpha + 2.5 * binomial, "rate {rate}");
        // A 0.01 rad constant bias (the noise's own size, over 720 rows)
        // is far beyond it, with the free term in the fit.
        let planted: Vec<f64> = y.iter().map(|v| v + 0.01 * s).collect();
        let (alone, joint) = heading_test(&rows, &planted, dof, alpha);
        let joint = joint.expect("the joint test runs on twelve blocks");
        assert!(joint.z > 3.0 * critical, "joint z {}", joint.z);
        let alone = alone.expect("the constant term's fit");
        assert!(
            (alone.estimate - 0.01).abs() < 4.0 * alone.sigma(),
            "{alone:?}"
        );
    }

    #[test]
    fn an_effect_is_decided_under_the_source_with_the_smaller_sigma_whatever_its_estimate() {
        let fit = |estimate: f64, sigma: f64| CoefFit {
            estimate,
            sigma_fisher: sigma,
            sigma_segments: Some(0.5 * sigma),
        };
        let limit = |estimate: f64, sigma: f64, source| {
            let mut l = limit_of(
                Effect::GnssLeverArm,
                Some(fit(estimate, sigma)),
                3.6,
                source,
            );
            l.joint = Some(Joint::of(Effect::GnssLeverArm, fit(estimate, sigma), 3.6));
            l
        };
        let mut limits = BTreeMap::new();
        // The wheels' heading: a large estimate with a large sigma.
        keep_better(
            &mut limits,
            limit(2.0, 0.5, InformationSource::PositionsWheelHeading),
        );
        // The gyro's: a smaller estimate, known four times better.
        keep_better(
            &mut limits,
            limit(0.3, 0.125, InformationSource::PositionsGyroHeading),
        );
        let kept = &limits[&Effect::GnssLeverArm];
        assert_eq!(kept.source, InformationSource::PositionsGyroHeading);
        assert!((decisive_sigma(kept) - 0.125).abs() < 1e-12);
        // The one displaced is remembered as the other source's reading.
        let other = kept.other_source.expect("the wheels' fit is kept beside");
        assert_eq!(other.source, InformationSource::PositionsWheelHeading);
        assert!((other.wald_z - 4.0).abs() < 1e-9, "{other:?}");
        // Another limit with a larger |z| but a larger sigma does not
        // displace it: the choice never looks at the estimate.
        keep_better(
            &mut limits,
            limit(9.0, 0.2, InformationSource::PositionsWheelHeading),
        );
        assert_eq!(
            limits[&Effect::GnssLeverArm].source,
            InformationSource::PositionsGyroHeading
        );
        // Without a sigma the limit yields to any with one.
        let mut none = limit_of(
            Effect::GnssLeverArm,
            None,
            3.6,
            InformationSource::PositionsWheelHeading,
        );
        none.joint = None;
        assert!(decisive_sigma(&none).is_infinite());
    }

    #[test]
    fn a_squared_term_reports_the_root_of_its_limit() {
        let fit = CoefFit {
            estimate: 0.0,
            sigma_fisher: 0.01,
            sigma_segments: None,
        };
        let alpha = FAMILY_ALPHA / 12.0;
        let z_critical = normal_quantile(1.0 - 0.5 * alpha);
        let l = limit_of(
            Effect::RoadGrade,
            Some(fit),
            z_critical,
            InformationSource::PositionsWheelHeading,
        );
        let size_of_square = detectable_size(1e4, alpha, POWER);
        let smallest = l.smallest.expect("a limit");
        assert!((smallest - size_of_square.sqrt()).abs() < 1e-12, "{l:?}");
        assert_eq!(l.estimate_of, "gain^2");
        // No information: no limit, no estimate.
        let none = limit_of(
            Effect::TrackWidth,
            None,
            z_critical,
            InformationSource::PositionsWheelHeading,
        );
        assert!(none.smallest.is_none() && none.estimate.is_none());
    }
}
