//! Sigmas from an error model of the drive's own residuals: one home for
//! "how far can the GNSS errors of this drive move the estimate".
//!
//! GNSS errors are correlated in time (a receiver's wander over tens of
//! seconds), and so is whatever physics the fitted model leaves out. A
//! formal least-squares covariance treats thousands of fixes as independent
//! and is far too small; resampling (a jackknife over blocks or segments)
//! needs many more independent blocks than a drive of minutes has. Here:
//!
//! 1. The fit is linearised ([`Linearisation`]): every fix's gain on the
//!    parameters (the segment poses eliminated), and the map from fix
//!    errors to fit residuals.
//! 2. Each axis's errors are modelled as white noise plus a first-order
//!    Gauss-Markov process ([`ErrorModel`]). Its three numbers are fitted
//!    to the residuals' semivariogram within segments ([`variogram`]). The
//!    fit itself hides part of the error (each segment's pose absorbs its
//!    offset and rotation, the parameters absorb a stretch), which a plain
//!    variogram fit would miss: so the model is matched to the *expected
//!    residual* variogram of each candidate, found by passing simulated
//!    errors of that candidate through the same linearised fit
//!    ([`fit_error_model`]).
//! 3. The covariance is the exact sum over all pairs of fixes of
//!    `K_i C(t_i - t_j) K_j^T` ([`correlated_covariance`]), linear in the
//!    number of fixes through a recursion for the exponential kernel.
//!
//! Nothing here is tuned to a simulator: the model's numbers come from each
//! drive, and a correlation time the drive cannot resolve is extrapolated
//! from the growth it shows (which errs on the large side).

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// A GNSS error model of one axis: white noise plus a first-order
/// Gauss-Markov process, `C(dt) = white [dt = 0] + gm exp(-|dt| / tau)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ErrorModel {
    /// Variance of the white part, m^2.
    pub white_var_m2: f64,
    /// Variance of the correlated part, m^2.
    pub gm_var_m2: f64,
    /// Its correlation time, s.
    pub tau_s: f64,
    /// Longest lag the residuals showed, s: a `tau_s` far beyond it was
    /// not resolved.
    pub max_lag_s: f64,
}

/// Lags of the residual variogram, in fix intervals (a geometric series).
const VARIOGRAM_LAGS: [f64; 16] = [
    1.0, 2.0, 3.0, 5.0, 8.0, 12.0, 18.0, 27.0, 40.0, 60.0, 90.0, 135.0, 200.0, 300.0, 450.0, 675.0,
];
/// Pairs a lag of the variogram needs to count.
const MIN_PAIRS: usize = 30;
/// Simulated error series per candidate correlation time.
const REALISATIONS: usize = 10;
/// Fixes the simulations run on at most (whole segments, evenly spread).
const SIMULATED_FIXES: usize = 4000;
/// Ratio between neighbouring candidate correlation times.
const TAU_STEP: f64 = 2.0;
/// The longest candidate correlation time, in longest lags seen.
const TAU_SPAN: f64 = 30.0;
/// Starting points per lag of the variogram at most (evenly spread).
const VARIOGRAM_STARTS: usize = 4000;

/// Largest number of global parameters a linearised fit may have.
pub const MAX_PARAMS: usize = 6;

/// One fix of a linearised fit (kept compact: a long drive has tens of
/// thousands).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixLin {
    /// Fix time, s.
    pub t: f64,
    /// The fit's residual (east, north), m.
    pub residual_m: [f64; 2],
    /// d(normalised residual)/d(global parameters), east and north rows.
    pub a: [[f32; MAX_PARAMS]; 2],
    /// d(normalised residual)/d(segment pose `x, y, theta`), east and north rows.
    pub b: [[f32; 3]; 2],
    /// Robust (Huber) weight.
    pub w: f32,
    /// The fix's sigma (robust scale included), m.
    pub sigma: f32,
    /// Its segment.
    pub segment: u32,
}

impl FixLin {
    /// Counts in the variogram (not down-weighted as an outlier).
    fn used(&self) -> bool {
        self.w >= 1.0
    }
}

/// One segment of a linearised fit: its pose eliminated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentLin {
    /// The inverse of its pose information `Hll^-1`.
    pub pose_inv: Matrix3<f64>,
    /// How its pose follows the parameters, `Hll^-1 Hgl^T` (`3 x ng`, padded).
    pub follow: [[f64; MAX_PARAMS]; 3],
}

/// A fit linearised at its solution: the fixes (in time order within each
/// segment, the segments in time order), the segments, and the inverse
/// information of the global parameters (segment poses eliminated).
#[derive(Debug, Clone)]
pub struct Linearisation {
    /// Number of global parameters (at most [`MAX_PARAMS`]).
    pub ng: usize,
    /// The fixes.
    pub fixes: Vec<FixLin>,
    /// The segments.
    pub segments: Vec<SegmentLin>,
    /// Inverse information of the global parameters (`ng x ng`).
    pub info_inv: DMatrix<f64>,
}

/// `w / sigma (A - B M)^T` of one fix: its (unscaled) pull on the global
/// parameters per metre of error, columns east and north.
type Pull = [[f64; 2]; MAX_PARAMS];

impl Linearisation {
    fn pull(&self, f: &FixLin) -> Pull {
        let m = &self.segments[f.segment as usize].follow;
        let k = f64::from(f.w) / f64::from(f.sigma);
        let mut out = [[0.0; 2]; MAX_PARAMS];
        for (j, o) in out.iter_mut().enumerate().take(self.ng) {
            for (row, v) in o.iter_mut().enumerate() {
                let bm: f64 = (0..3).map(|l| f64::from(f.b[row][l]) * m[l][j]).sum();
                *v = k * (f64::from(f.a[row][j]) - bm);
            }
        }
        out
    }

    /// Every fix's gain: global parameters per metre of its error
    /// (`info^-1` times its pull), column `axis`.
    fn gains(&self, axis: usize) -> Vec<DVector<f64>> {
        self.fixes
            .iter()
            .map(|f| {
                let p = self.pull(f);
                let v = DVector::from_iterator(self.ng, (0..self.ng).map(|j| p[j][axis]));
                &self.info_inv * v
            })
            .collect()
    }

    /// The residuals the linearised fit leaves of fix errors `e` (east,
    /// north per fix, m; `pulls` from [`Linearisation::pull`]): `e - J
    /// delta(e)`, with the parameters' and poses' least-squares response.
    fn residuals(&self, pulls: &[Pull], e: &[[f64; 2]]) -> Vec<[f64; 2]> {
        let ng = self.ng;
        let mut sum = DVector::<f64>::zeros(ng);
        for (p, ei) in pulls.iter().zip(e) {
            for j in 0..ng {
                sum[j] += p[j][0] * ei[0] + p[j][1] * ei[1];
            }
        }
        let dg = &self.info_inv * sum;
        let mut rhs = vec![Vector3::<f64>::zeros(); self.segments.len()];
        for (f, ei) in self.fixes.iter().zip(e) {
            let k = f64::from(f.w) / f64::from(f.sigma);
            let r = &mut rhs[f.segment as usize];
            for l in 0..3 {
                r[l] += k * (f64::from(f.b[0][l]) * ei[0] + f64::from(f.b[1][l]) * ei[1]);
            }
        }
        let dl: Vec<Vector3<f64>> = self
            .segments
            .iter()
            .zip(&rhs)
            .map(|(s, r)| {
                let mut follow = Vector3::zeros();
                for l in 0..3 {
                    follow[l] = (0..ng).map(|j| s.follow[l][j] * dg[j]).sum();
                }
                s.pose_inv * r - follow
            })
            .collect();
        self.fixes
            .iter()
            .zip(e)
            .map(|(f, ei)| {
                let d = &dl[f.segment as usize];
                let sigma = f64::from(f.sigma);
                let mut out = *ei;
                for (row, o) in out.iter_mut().enumerate() {
                    let mut m: f64 = (0..ng).map(|j| f64::from(f.a[row][j]) * dg[j]).sum();
                    m += (0..3).map(|l| f64::from(f.b[row][l]) * d[l]).sum::<f64>();
                    *o -= sigma * m;
                }
                out
            })
            .collect()
    }

    /// Every k-th segment, so that at most about `max_fixes` fixes remain
    /// (all of them when there are fewer); the segments renumbered.
    fn thinned(&self, max_fixes: usize) -> Linearisation {
        let k = self.fixes.len().div_ceil(max_fixes.max(1)).max(1);
        if k == 1 {
            return self.clone();
        }
        let keep = |s: u32| (s as usize).is_multiple_of(k);
        Linearisation {
            ng: self.ng,
            fixes: self
                .fixes
                .iter()
                .filter(|f| keep(f.segment))
                .map(|f| FixLin {
                    segment: f.segment / k as u32,
                    ..*f
                })
                .collect(),
            segments: self.segments.iter().step_by(k).copied().collect(),
            info_inv: self.info_inv.clone(),
        }
    }

    /// The fixes' indices in time order (segments share boundary times).
    fn time_order(&self) -> Vec<usize> {
        let mut order: Vec<usize> = (0..self.fixes.len()).collect();
        order.sort_by(|&a, &b| self.fixes[a].t.total_cmp(&self.fixes[b].t));
        order
    }

    /// The median interval between fixes, s.
    fn fix_interval(&self) -> Option<f64> {
        let t: Vec<f64> = self.fixes.iter().map(|f| f.t).collect();
        crate::series::median_interval(&t)
    }

    /// One axis of `values` as the variogram's series: per segment, the
    /// used fixes' `(t, value)`.
    fn series(&self, values: &[[f64; 2]], axis: usize) -> Vec<Vec<(f64, f64)>> {
        let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
        for (i, f) in self.fixes.iter().enumerate() {
            if i == 0 || f.segment != self.fixes[i - 1].segment {
                out.push(Vec::new());
            }
            if f.used() {
                if let Some(s) = out.last_mut() {
                    s.push((f.t, values[i][axis]));
                }
            }
        }
        out
    }
}

/// The empirical semivariogram `gamma(lag) = mean((e(t + lag) - e(t))^2) / 2`
/// of residual series (each in time order, `(t, e)`; pairs within a series
/// only), at lags that are multiples of `dt` up to half the longest series:
/// `(mean lag, gamma, pairs)` per lag with enough pairs.
pub fn variogram(series: &[Vec<(f64, f64)>], dt: f64) -> Vec<(f64, f64, usize)> {
    let longest = series
        .iter()
        .filter_map(|s| Some(s.last()?.0 - s.first()?.0))
        .fold(0.0, f64::max);
    let total: usize = series.iter().map(Vec::len).sum();
    let stride = total.div_ceil(VARIOGRAM_STARTS).max(1);
    let mut out = Vec::new();
    for m in VARIOGRAM_LAGS {
        let lag = m * dt;
        if lag > 0.5 * longest {
            break;
        }
        let tol = (0.25 * dt).max(0.1 * lag);
        let (mut sum, mut sum_lag, mut n) = (0.0, 0.0, 0usize);
        for s in series {
            let mut j = 0usize;
            for i in (0..s.len()).step_by(stride) {
                let target = s[i].0 + lag;
                while j < s.len() && s[j].0 < target - tol {
                    j += 1;
                }
                if j < s.len() && (s[j].0 - target).abs() <= tol {
                    let d = s[j].1 - s[i].1;
                    sum += 0.5 * d * d;
                    sum_lag += s[j].0 - s[i].0;
                    n += 1;
                }
            }
        }
        if n >= MIN_PAIRS {
            out.push((sum_lag / n as f64, sum / n as f64, n));
        }
    }
    out
}

/// A small deterministic generator of standard normal numbers (splitmix64
/// and Box-Muller): the simulated errors must not make two runs on the same
/// drive differ.
pub(crate) struct Normal {
    state: u64,
    spare: Option<f64>,
}

impl Normal {
    pub(crate) fn new(seed: u64) -> Normal {
        Normal {
            state: seed,
            spare: None,
        }
    }

    fn uniform(&mut self) -> f64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        // In (0, 1].
        ((z >> 11) as f64 + 1.0) / (1u64 << 53) as f64
    }

    pub(crate) fn next(&mut self) -> f64 {
        if let Some(v) = self.spare.take() {
            return v;
        }
        let (u1, u2) = (self.uniform(), self.uniform());
        let r = (-2.0 * u1.ln()).sqrt();
        let a = std::f64::consts::TAU * u2;
        self.spare = Some(r * a.sin());
        r * a.cos()
    }
}

/// Fit each axis's [`ErrorModel`] to the residuals of `lin`: for each
/// candidate correlation time (a geometric grid from the fix interval to
/// fifty times the longest lag), the expected residual semivariogram of
/// unit white and unit Gauss-Markov errors (simulated errors passed
/// through the linearised fit), then non-negative least squares of the
/// observed semivariogram on those two, in relative error; the best
/// candidate wins. `None` when the residuals show fewer than three lags.
pub fn fit_error_model(lin: &Linearisation) -> Option<[Vec<ErrorModel>; 2]> {
    let dt = lin.fix_interval()?;
    let residuals: Vec<[f64; 2]> = lin.fixes.iter().map(|f| f.residual_m).collect();
    let observed = [
        variogram(&lin.series(&residuals, 0), dt),
        variogram(&lin.series(&residuals, 1), dt),
    ];
    if observed.iter().any(|g| g.len() < 3) {
        return None;
    }
    let max_lag = observed[0].iter().map(|g| g.0).fold(0.0, f64::max);
    // The simulations run on evenly spread segments of a long drive (at
    // most about SIMULATED_FIXES fixes): each segment's pose absorbs what it
    // absorbs whatever the others do, and with many segments the global
    // parameters take little from any one.
    let sim = lin.thinned(SIMULATED_FIXES);
    let n = sim.fixes.len();
    let pulls: Vec<Pull> = sim.fixes.iter().map(|f| sim.pull(f)).collect();
    // Residual semivariograms of simulated unit errors passed through the
    // linearised fit, per realization and axis, at the observed lags.
    let simulate = |make: &dyn Fn(&mut Normal) -> Vec<[f64; 2]>| -> [Vec<Vec<f64>>; 2] {
        let mut out: [Vec<Vec<f64>>; 2] = [Vec::new(), Vec::new()];
        let mut rng = Normal::new(0x5EED_0001);
        for _ in 0..REALISATIONS {
            let e = make(&mut rng);
            let r = sim.residuals(&pulls, &e);
            for axis in 0..2 {
                let g = variogram(&sim.series(&r, axis), dt);
                let row = observed[axis]
                    .iter()
                    .map(|obs| {
                        g.iter()
                            .find(|x| (x.0 - obs.0).abs() <= (0.25 * dt).max(0.1 * obs.0))
                            .map_or(0.0, |v| v.1)
                    })
                    .collect();
                out[axis].push(row);
            }
        }
        out
    };
    let white = simulate(&|rng: &mut Normal| (0..n).map(|_| [rng.next(), rng.next()]).collect());
    let mut candidates: [Vec<Candidate>; 2] = [Vec::new(), Vec::new()];
    let mut tau = 2.0 * dt;
    while tau <= TAU_SPAN * max_lag {
        let gm = simulate(&|rng: &mut Normal| {
            let mut out = Vec::with_capacity(n);
            let mut x = [rng.next(), rng.next()];
            let mut prev_t = sim.fixes.first().map_or(0.0, |f| f.t);
            for t in sim.fixes.iter().map(|f| f.t) {
                let rho = (-(t - prev_t).abs() / tau).exp();
                let s = (1.0 - rho * rho).max(0.0).sqrt();
                x = [rho * x[0] + s * rng.next(), rho * x[1] + s * rng.next()];
                prev_t = t;
                out.push(x);
            }
            out
        });
        for axis in 0..2 {
            let mean = |rows: &Vec<Vec<f64>>, j: usize| {
                rows.iter().map(|r| r[j]).sum::<f64>() / rows.len() as f64
            };
            let lags = observed[axis].len();
            let wm: Vec<f64> = (0..lags).map(|j| mean(&white[axis], j)).collect();
            let gmm: Vec<f64> = (0..lags).map(|j| mean(&gm[axis], j)).collect();
            if let Some((_, w, g)) = nnls2(&observed[axis], &wm, &gmm) {
                // How far the observed semivariogram strays from the
                // model's mean, against how far the model's own realizations
                // stray (the lags move together, so they are compared as a
                // whole): plausible while it strays no more than they do.
                let mean: Vec<f64> = (0..lags).map(|j| w * wm[j] + g * gmm[j]).collect();
                let distance = |row: &dyn Fn(usize) -> f64| -> f64 {
                    (0..lags)
                        .map(|j| ((row(j) - mean[j]) / mean[j].max(1e-300)).powi(2))
                        .sum()
                };
                let obs = distance(&|j| observed[axis][j].1);
                let mut spread: Vec<f64> = (0..REALISATIONS)
                    .map(|r| distance(&|j| w * white[axis][r][j] + g * gm[axis][r][j]))
                    .collect();
                spread.sort_by(f64::total_cmp);
                let chi2 = obs / spread[spread.len() - 1].max(1e-300);
                candidates[axis].push(Candidate {
                    chi2,
                    model: ErrorModel {
                        white_var_m2: w,
                        gm_var_m2: g,
                        tau_s: tau,
                        max_lag_s: max_lag,
                    },
                });
            }
        }
        tau *= TAU_STEP;
    }
    for c in &candidates[0] {
        tracing::trace!(
            tau_s = c.model.tau_s,
            chi2 = c.chi2,
            white_m = c.model.white_var_m2.sqrt(),
            gm_m = c.model.gm_var_m2.sqrt(),
            "error-model candidate (east)"
        );
    }
    let [east, north] = candidates;
    Some([plausible(east)?, plausible(north)?])
}

/// One candidate model with its misfit to the observed semivariogram.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    chi2: f64,
    model: ErrorModel,
}

/// The candidates whose own realizations stray from their mean at least as
/// far as the observed semivariogram does (misfit ratio at most 1), best
/// first; the best alone when none does.
fn plausible(mut c: Vec<Candidate>) -> Option<Vec<ErrorModel>> {
    c.retain(|x| x.chi2.is_finite());
    c.sort_by(|a, b| a.chi2.total_cmp(&b.chi2));
    let first = *c.first()?;
    let mut out: Vec<ErrorModel> = c
        .iter()
        .filter(|x| x.chi2 <= 1.0)
        .map(|x| x.model)
        .collect();
    if out.is_empty() {
        out.push(first.model);
    }
    Some(out)
}

/// Non-negative least squares of `observed = w * white + g * gm` in
/// relative error: `(sse, w, g)`.
pub(crate) fn nnls2(
    observed: &[(f64, f64, usize)],
    white: &[f64],
    gm: &[f64],
) -> Option<(f64, f64, f64)> {
    let rows: Vec<(f64, f64)> = observed
        .iter()
        .zip(white.iter().zip(gm))
        .filter(|(o, _)| o.1 > 0.0)
        .map(|(o, (w, g))| (w / o.1, g / o.1))
        .collect();
    let sse = |w: f64, g: f64| {
        rows.iter()
            .map(|(a, b)| (a * w + b * g - 1.0).powi(2))
            .sum::<f64>()
    };
    let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (a, b) in &rows {
        a11 += a * a;
        a12 += a * b;
        a22 += b * b;
        b1 += a;
        b2 += b;
    }
    let mut candidates = Vec::new();
    let det = a11 * a22 - a12 * a12;
    if det > 1e-12 * a11 * a22 {
        let w = (b1 * a22 - b2 * a12) / det;
        let g = (a11 * b2 - a12 * b1) / det;
        if w >= 0.0 && g >= 0.0 {
            candidates.push((w, g));
        }
    }
    if a11 > 0.0 {
        candidates.push((b1 / a11, 0.0));
    }
    if a22 > 0.0 {
        candidates.push((0.0, b2 / a22));
    }
    candidates
        .into_iter()
        .filter(|(w, g)| w.is_finite() && g.is_finite())
        .map(|(w, g)| (sse(w, g), w, g))
        .min_by(|a, b| a.0.total_cmp(&b.0))
}

/// Covariance of the parameters `x = sum_i K_i e_i` when the fixes' errors
/// follow `models` (east, north; the axes independent):
/// `sum_ij K_i[:, a] C_a(t_i - t_j) K_j[:, a]^T` over both axes, every pair
/// of fixes (across segments too).
pub fn correlated_covariance(
    lin: &Linearisation,
    models: &[ErrorModel; 2],
) -> Option<DMatrix<f64>> {
    let order = lin.time_order();
    Some(
        axis_covariance(lin, &order, &lin.gains(0), &models[0])?
            + axis_covariance(lin, &order, &lin.gains(1), &models[1])?,
    )
}

/// The covariance from the errors of one axis under `m`, given every
/// fix's gain on that axis ([`Linearisation::gains`]). The fixes are taken
/// in time order; the exponential kernel is summed by a recursion, linear
/// in their number.
fn axis_covariance(
    lin: &Linearisation,
    order: &[usize],
    gains: &[DVector<f64>],
    m: &ErrorModel,
) -> Option<DMatrix<f64>> {
    let n = lin.ng;
    let mut c = DMatrix::zeros(n, n);
    let mut f = DVector::<f64>::zeros(n);
    let mut prev: Option<usize> = None;
    for &i in order {
        let v = &gains[i];
        if let Some(p) = prev {
            f += &gains[p];
            f *= (-(lin.fixes[i].t - lin.fixes[p].t).abs() / m.tau_s).exp();
        }
        c.ger(m.white_var_m2 + m.gm_var_m2, v, v, 1.0);
        c.ger(m.gm_var_m2, v, &f, 1.0);
        c.ger(m.gm_var_m2, &f, v, 1.0);
        prev = Some(i);
    }
    c.iter().all(|v| v.is_finite()).then_some(c)
}

/// The covariance under the plausible models of each axis (from
/// [`fit_error_model`], best first): per axis the model that gives the
/// parameters the most variance (summed relative to the best model's), so
/// a correlation time the drive cannot pin down is taken at its least
/// favourable plausible value. Returns the covariance and the models used.
pub fn conservative_covariance(
    lin: &Linearisation,
    plausible: &[Vec<ErrorModel>; 2],
) -> Option<(DMatrix<f64>, [ErrorModel; 2])> {
    let order = lin.time_order();
    let mut total: Option<DMatrix<f64>> = None;
    let mut used = Vec::with_capacity(2);
    for (axis, models) in plausible.iter().enumerate() {
        let gains = lin.gains(axis);
        let best = axis_covariance(lin, &order, &gains, models.first()?)?;
        let n = best.nrows();
        let inflation_of = |c: &DMatrix<f64>| -> f64 {
            (0..n).map(|i| c[(i, i)] / best[(i, i)].max(1e-300)).sum()
        };
        let mut chosen = (inflation_of(&best), best.clone(), models[0]);
        for m in models.iter().skip(1) {
            let c = axis_covariance(lin, &order, &gains, m)?;
            let inflation = inflation_of(&c);
            if inflation > chosen.0 {
                chosen = (inflation, c, *m);
            }
        }
        total = Some(match total {
            Some(t) => t + chosen.1,
            None => chosen.1,
        });
        used.push(chosen.2);
    }
    Some((total?, [used[0], used[1]]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fixes at `t` in segments of `segment_s`, each segment's pose taking
    /// its offset (east, north) and nothing else; one parameter that every
    /// fix measures directly on the east axis when `direct`, else none.
    fn offsets(t: &[f64], segment_s: f64, direct: bool) -> Linearisation {
        let fixes: Vec<FixLin> = t
            .iter()
            .map(|&t| {
                let mut a = [[0.0f32; MAX_PARAMS]; 2];
                a[0][0] = if direct { 1.0 } else { 0.0 };
                FixLin {
                    t,
                    residual_m: [0.0; 2],
                    a,
                    b: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                    w: 1.0,
                    sigma: 1.0,
                    segment: (t / segment_s) as u32,
                }
            })
            .collect();
        let segs = fixes.last().map_or(0, |f| f.segment as usize + 1);
        let segments = (0..segs)
            .map(|s| {
                let c = fixes.iter().filter(|f| f.segment as usize == s).count() as f64;
                SegmentLin {
                    pose_inv: Matrix3::new(1.0 / c, 0.0, 0.0, 0.0, 1.0 / c, 0.0, 0.0, 0.0, 1.0),
                    follow: [[0.0; MAX_PARAMS]; 3],
                }
            })
            .collect();
        Linearisation {
            ng: 1,
            fixes,
            segments,
            info_inv: DMatrix::from_element(1, 1, 1.0),
        }
    }

    #[test]
    fn the_residual_map_removes_the_segment_offset() {
        let t: Vec<f64> = (0..50).map(|i| 0.1 * i as f64).collect();
        let lin = offsets(&t, 100.0, false);
        let pulls: Vec<Pull> = lin.fixes.iter().map(|f| lin.pull(f)).collect();
        let e: Vec<[f64; 2]> = (0..50).map(|i| [3.0 + (i % 2) as f64, -2.0]).collect();
        let r = lin.residuals(&pulls, &e);
        let mean: f64 = r.iter().map(|x| x[0]).sum::<f64>() / 50.0;
        assert!(mean.abs() < 1e-12);
        assert!(r.iter().all(|x| x[1].abs() < 1e-12));
        assert!((r[0][0] + 0.5).abs() < 1e-12 && (r[1][0] - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_simulated_error_model_is_recovered_from_the_residuals() {
        // 20 minutes at 10 Hz in 120 s segments: white 0.3 m, GM 1 m over 30 s.
        let t: Vec<f64> = (0..12_000).map(|i| 0.1 * i as f64).collect();
        let mut lin = offsets(&t, 120.0, false);
        let pulls: Vec<Pull> = lin.fixes.iter().map(|f| lin.pull(f)).collect();
        let mut rng = Normal::new(42);
        let mut gm = [0.0, 0.0];
        let rho = (-0.1f64 / 30.0).exp();
        let s = (1.0 - rho * rho).sqrt();
        let e: Vec<[f64; 2]> = (0..t.len())
            .map(|_| {
                gm = [rho * gm[0] + s * rng.next(), rho * gm[1] + s * rng.next()];
                [0.3 * rng.next() + gm[0], 0.3 * rng.next() + gm[1]]
            })
            .collect();
        let r = lin.residuals(&pulls, &e);
        for (f, r) in lin.fixes.iter_mut().zip(r) {
            f.residual_m = r;
        }
        let m = fit_error_model(&lin).expect("fitted");
        for axis in m.iter().map(|p| p[0]) {
            assert!((axis.white_var_m2.sqrt() - 0.3).abs() < 0.03, "{axis:?}");
            // The correlated part is mostly hidden in the segment offsets;
            // the fit through the residual map still finds it.
            let g = axis.gm_var_m2.sqrt();
            assert!(g > 0.6 && g < 1.6, "{axis:?}");
        }
    }

    #[test]
    fn white_errors_give_the_least_squares_covariance() {
        // One parameter measured directly by n fixes (no poses): its
        // estimate is their mean, variance white / n.
        let n = 400;
        let t: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let mut lin = offsets(&t, 1e9, true);
        for f in &mut lin.fixes {
            f.b = [[0.0; 3]; 2];
        }
        lin.segments[0].pose_inv = Matrix3::zeros();
        lin.info_inv = DMatrix::from_element(1, 1, 1.0 / n as f64);
        let m = ErrorModel {
            white_var_m2: 4.0,
            gm_var_m2: 0.0,
            tau_s: 10.0,
            max_lag_s: 100.0,
        };
        let c = correlated_covariance(&lin, &[m, m]).expect("finite");
        assert!((c[(0, 0)] - 4.0 / n as f64).abs() < 1e-12, "{}", c[(0, 0)]);
        // A fully correlated error does not average out.
        let m = ErrorModel {
            white_var_m2: 0.0,
            gm_var_m2: 4.0,
            tau_s: 1e9,
            max_lag_s: 100.0,
        };
        let c = correlated_covariance(&lin, &[m, m]).expect("finite");
        assert!((c[(0, 0)] - 4.0).abs() < 1e-5, "{}", c[(0, 0)]);
    }
}
