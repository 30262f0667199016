//! The Levenberg-Marquardt fitter of a dead-reckoning model to the GNSS
//! fixes over the whole drive: one fitter for the batch method (the 2W
//! model) and the gyro calibration (wheel distance, gyro heading).
//!
//! The drive is cut into segments (at every break of the wheel data, and of
//! the model's own data); each segment has its own initial pose
//! `(x0, y0, theta0)`, all share the model's global parameters. Within a
//! segment the model is integrated from its initial pose exactly as the
//! odometry will run it (eq. 1-2), and the predicted antenna position
//! `p + R(theta) l` (lever arm `l` from `vehicle.toml`, or fitted) is compared
//! with every accepted GNSS fix. The model enters through a [`StepModel`]:
//! one step's centre distance and heading change with their derivatives by
//! the global parameters.
//!
//! Solving: Gauss-Newton with Levenberg-Marquardt damping, the per-segment
//! poses eliminated by a Schur complement (cost linear in the drive length),
//! Huber weights on the fixes. The fit starts on short segments (the model's
//! heading drifts little there, so the nominal parameters are a good enough
//! start) and lengthens them to the configured length, each stage starting
//! from the last ([`stages`]).
//!
//! Uncertainty: an error model of the residuals ([`crate::error_model`]:
//! white + Gauss-Markov per axis, fitted through the linearised fit, the
//! exact covariance over every pair of fixes), with the formal covariance
//! (residual variance and its lag-1 autocorrelation) as a floor. Where the
//! error model cannot be fitted (too few lags), a jackknife over contiguous
//! blocks of fixes and over whole segments takes its place.

use crate::error::CalibrationError;
use crate::error_model::{
    conservative_covariance, fit_error_model, ErrorModel, FixLin, Linearisation, SegmentLin,
};
use crate::fit::jackknife::jackknife_covariance;
use crate::products::{SigmaBasis, Sigmas};
use crate::reference::{RefFix, Reference};
use crate::series::Series;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use vehicle_model::two_wheel::Pose2;

/// Drive time (s) the early, short-segment stages look at.
const EARLY_STAGE_S: f64 = 600.0;

/// Points kept of a fitted model's track for the report.
pub const REPORT_POINTS: usize = 3000;

/// Largest number of global parameters of any model.
pub const MAX_GLOBAL: usize = crate::error_model::MAX_PARAMS;

/// One step of a dead-reckoning model with its parameter derivatives.
pub trait StepModel {
    /// Number of global parameters.
    fn n_global(&self) -> usize;
    /// Centre distance and heading change of step `k` (from sample k-1 to k)
    /// and their derivatives by the global parameters `g`; `None` where the
    /// model has no data (the segment must not span it).
    fn increments(
        &self,
        k: usize,
        g: &[f64],
        d_ds: &mut [f64; MAX_GLOBAL],
        d_dyaw: &mut [f64; MAX_GLOBAL],
    ) -> Option<(f64, f64)>;
    /// Side-slip: the parameter index of the gain `k` (beta = -k a_y), or a
    /// fixed gain.
    fn slip(&self) -> SlipGain;
    /// Prior pseudo-observations: (parameter index, value, sigma).
    fn priors(&self) -> Vec<(usize, f64, f64)> {
        Vec::new()
    }
    /// Index of the GNSS antenna's body x among the parameters (body y
    /// follows), when the lever arm is estimated.
    fn lever_index(&self) -> Option<usize> {
        None
    }
    /// The parameters that set the distance scale (the circumferences, or
    /// a common distance factor): those whose sigmas take the thirds'
    /// floor where the drive's thirds disagree ([`Fit::thirds`]).
    fn scale_params(&self) -> &'static [usize] {
        &[0, 1]
    }
}

/// How a model handles side-slip.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SlipGain {
    /// beta = 0.
    Off,
    /// A fixed gain, rad per m/s^2.
    Fixed(f64),
    /// The gain is global parameter number `.0`.
    Parameter(usize),
}

/// A segment: wheel samples `k0..k1` and the accepted fixes in its time span.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// First wheel sample (the initial pose is at its time).
    pub k0: usize,
    /// One past the last wheel sample.
    pub k1: usize,
    /// Indices into the accepted-fix list.
    pub fixes: std::ops::Range<usize>,
}

/// Cut the drive into segments of about `length_s`, at every piece start and
/// wherever `breaks(k)` says the model has no step k. Neighbouring segments
/// share their boundary sample. Segments with fewer than 8 fixes or under
/// 20 m are dropped (counted in the return value).
pub fn make_segments(
    p: &Series,
    fixes: &[RefFix],
    length_s: f64,
    breaks: &dyn Fn(usize) -> bool,
) -> (Vec<Segment>, usize) {
    let n = p.len();
    let mut raw = Vec::new();
    let mut k0 = 0usize;
    for k in 1..n {
        if p.is_piece_start(k) || breaks(k) {
            raw.push((k0, k));
            k0 = k;
        } else if p.t[k] - p.t[k0] >= length_s {
            raw.push((k0, k + 1));
            k0 = k;
        }
    }
    raw.push((k0, n));
    let mut out = Vec::new();
    let mut dropped = 0usize;
    for (a, b) in raw {
        if b < a + 2 {
            continue;
        }
        let (t0, t1) = (p.t[a], p.t[b - 1]);
        let f = fixes.partition_point(|x| x.t < t0);
        let e = fixes.partition_point(|x| x.t <= t1);
        let dist: f64 = (a + 1..b)
            .map(|k| 0.5 * (p.dn_rl[k] + p.dn_rr[k]).abs() * p.nominal_c)
            .sum();
        if e >= f + 8 && dist >= 20.0 {
            out.push(Segment {
                k0: a,
                k1: b,
                fixes: f..e,
            });
        } else {
            dropped += 1;
        }
    }
    (out, dropped)
}

/// Accumulated normal equations of one segment (or one block of it).
#[derive(Debug, Clone, PartialEq)]
struct Acc {
    hgg: DMatrix<f64>,
    hgl: DMatrix<f64>,
    hll: Matrix3<f64>,
    bg: DVector<f64>,
    bl: Vector3<f64>,
}

impl Acc {
    fn new(ng: usize) -> Acc {
        Acc {
            hgg: DMatrix::zeros(ng, ng),
            hgl: DMatrix::zeros(ng, 3),
            hll: Matrix3::zeros(),
            bg: DVector::zeros(ng),
            bl: Vector3::zeros(),
        }
    }

    fn sub(&self, o: &Acc) -> Acc {
        Acc {
            hgg: &self.hgg - &o.hgg,
            hgl: &self.hgl - &o.hgl,
            hll: self.hll - o.hll,
            bg: &self.bg - &o.bg,
            bl: self.bl - o.bl,
        }
    }
}

/// Result of evaluating one segment.
struct SegEval {
    cost: f64,
    acc: Option<Acc>,
    /// Per-block accumulators (for the jackknife), when asked.
    blocks: Vec<Acc>,
    /// Normalised residuals in time order (for the scale and autocorrelation).
    residuals: Vec<[f64; 2]>,
    /// Sum of squared residuals in metres.
    sum_sq_m: f64,
    /// With `record_every`: the model's rear-axle track, thinned.
    track: Vec<[f64; 2]>,
    /// With `record_every`: every fix's time and residual (east, north), m.
    residuals_m: Vec<[f64; 3]>,
    /// With `record_rows`: every fix's linearisation (segment index 0).
    rows: Vec<FixLin>,
}

/// Settings of one evaluation.
struct EvalSettings {
    lever: [f64; 2],
    /// Robust scale multiplying every fix sigma.
    scale: f64,
    jacobian: bool,
    /// Fixes per jackknife block (0: no blocks).
    block_fixes: usize,
    /// Keep every this many samples of the model's track and the residuals
    /// in metres (0: keep nothing).
    record_every: usize,
    /// Keep every fix's linearisation ([`FixLin`]).
    record_rows: bool,
}

impl EvalSettings {
    /// A plain evaluation at the fixes' own sigmas: no Jacobian, no
    /// blocks, nothing recorded.
    fn plain(lever: [f64; 2]) -> EvalSettings {
        EvalSettings {
            lever,
            scale: 1.0,
            jacobian: false,
            block_fixes: 0,
            record_every: 0,
            record_rows: false,
        }
    }
}

const HUBER_K: f64 = 3.0;

/// sin and cos of a small angle by their series (exact to ~1e-13 below
/// 0.05 rad), the library functions above that.
#[inline]
fn small_sin_cos(a: f64) -> (f64, f64) {
    if a.abs() < 0.05 {
        let a2 = a * a;
        (
            a * (1.0 - a2 / 6.0 * (1.0 - a2 / 20.0 * (1.0 - a2 / 42.0))),
            1.0 - a2 / 2.0 * (1.0 - a2 / 12.0 * (1.0 - a2 / 30.0)),
        )
    } else {
        a.sin_cos()
    }
}

fn huber(u: f64) -> (f64, f64) {
    // (cost, IRLS weight)
    if u <= HUBER_K {
        (0.5 * u * u, 1.0)
    } else {
        (HUBER_K * (u - 0.5 * HUBER_K), HUBER_K / u)
    }
}

/// Integrate `model` over `seg` from `pose0` and compare with the fixes.
#[allow(clippy::needless_range_loop)] // small fixed-size numeric kernels read best indexed
fn eval_segment<M: StepModel>(
    model: &M,
    g: &[f64],
    seg: &Segment,
    pose0: [f64; 3],
    fixes: &[RefFix],
    s: &EvalSettings,
    p: &Series,
) -> SegEval {
    let ng = model.n_global();
    let mut acc = s.jacobian.then(|| Acc::new(ng));
    let mut blocks = Vec::new();
    let mut block = (s.jacobian && s.block_fixes > 0).then(|| Acc::new(ng));
    let mut in_block = 0usize;
    let mut cost = 0.0;
    let mut residuals = Vec::with_capacity(seg.fixes.len());
    let mut sum_sq_m = 0.0;
    let mut track = Vec::new();
    let mut residuals_m = Vec::new();
    let mut rows = Vec::new();
    let mut pose = Pose2 {
        x: pose0[0],
        y: pose0[1],
        yaw: pose0[2],
    };
    // The heading as a unit vector, turned step by step (no sin/cos per step).
    let (mut sh, mut ch) = pose0[2].sin_cos();
    // Derivatives of x, y, yaw by the global parameters.
    let mut dx = [0.0; MAX_GLOBAL];
    let mut dy = [0.0; MAX_GLOBAL];
    let mut dth = [0.0; MAX_GLOBAL];
    let mut prev = (pose, dx, dy, dth);
    let mut fi = seg.fixes.start;
    let slip = model.slip();
    let (gain, gain_index) = match slip {
        SlipGain::Off => (0.0, None),
        SlipGain::Fixed(v) => (v, None),
        SlipGain::Parameter(i) => (g[i], Some(i)),
    };
    let (mut d_ds, mut d_dyaw) = ([0.0; MAX_GLOBAL], [0.0; MAX_GLOBAL]);
    let lever_index = model.lever_index();
    let [lx, ly] = match lever_index {
        Some(i) => [g[i], g[i + 1]],
        None => s.lever,
    };
    for k in seg.k0..seg.k1 {
        if k > seg.k0 {
            // The state before the step, kept only where a fix falls in
            // it (the fixes are interpolated between the two).
            if fi < seg.fixes.end && fixes[fi].t <= p.t[k] {
                prev = (pose, dx, dy, dth);
            }
            let Some((ds, dyaw)) = model.increments(k, g, &mut d_ds, &mut d_dyaw) else {
                break;
            };
            // a_y is data here (smoothed, nominal values), so beta depends on
            // the parameters only through the gain.
            let ay = f64::from(p.lateral_accel[k]);
            let beta = -gain * ay;
            // Eq. (1): course = theta + dtheta/2 + beta.
            let (sa, ca) = small_sin_cos(0.5 * dyaw + beta);
            let (sc, cc) = (sh * ca + ch * sa, ch * ca - sh * sa);
            if s.jacobian {
                for j in 0..ng {
                    let dbeta = if gain_index == Some(j) { -ay } else { 0.0 };
                    let dcourse = dth[j] + 0.5 * d_dyaw[j] + dbeta;
                    dx[j] += d_ds[j] * cc - ds * sc * dcourse;
                    dy[j] += d_ds[j] * sc + ds * cc * dcourse;
                    dth[j] += d_dyaw[j];
                }
            }
            pose = Pose2 {
                x: pose.x + ds * cc,
                y: pose.y + ds * sc,
                yaw: pose.yaw + dyaw,
            };
            let (sd, cd) = small_sin_cos(dyaw);
            (sh, ch) = (sh * cd + ch * sd, ch * cd - sh * sd);
            if (k - seg.k0).is_multiple_of(64) {
                let norm = (sh * sh + ch * ch).sqrt();
                (sh, ch) = (sh / norm, ch / norm);
            }
        }
        // Fixes in (t[k-1], t[k]] (or exactly at t[k0]).
        while fi < seg.fixes.end && fixes[fi].t <= p.t[k] {
            let f = &fixes[fi];
            fi += 1;
            if !f.accepted {
                continue;
            }
            let frac = if k > seg.k0 && p.t[k] > p.t[k - 1] {
                ((f.t - p.t[k - 1]) / (p.t[k] - p.t[k - 1])).clamp(0.0, 1.0)
            } else {
                1.0
            };
            let lerp = |a: f64, b: f64| a + frac * (b - a);
            let (pp, pdx, pdy, pdth) = &prev;
            let px = lerp(pp.x, pose.x);
            let py = lerp(pp.y, pose.y);
            let pth = lerp(pp.yaw, pose.yaw);
            let (st, ct) = pth.sin_cos();
            let ax = px + ct * lx - st * ly;
            let ay_ = py + st * lx + ct * ly;
            let sigma = f.sigma * s.scale;
            let r = [(f.x - ax) / sigma, (f.y - ay_) / sigma];
            let u = (r[0] * r[0] + r[1] * r[1]).sqrt();
            let (c, w) = huber(u);
            cost += c;
            residuals.push(r);
            sum_sq_m += (f.x - ax).powi(2) + (f.y - ay_).powi(2);
            if s.record_every > 0 {
                residuals_m.push([f.t, f.x - ax, f.y - ay_]);
            }
            if let Some(a) = acc.as_mut() {
                // d(antenna)/d(yaw)
                let rx = -st * lx - ct * ly;
                let ry = ct * lx - st * ly;
                let mut jg = [[0.0; MAX_GLOBAL]; 2];
                for j in 0..ng {
                    let dthj = lerp(pdth[j], dth[j]);
                    jg[0][j] = (lerp(pdx[j], dx[j]) + rx * dthj) / sigma;
                    jg[1][j] = (lerp(pdy[j], dy[j]) + ry * dthj) / sigma;
                }
                if let Some(i) = lever_index {
                    // antenna = p + R(theta) l
                    jg[0][i] += ct / sigma;
                    jg[1][i] += st / sigma;
                    jg[0][i + 1] -= st / sigma;
                    jg[1][i + 1] += ct / sigma;
                }
                let jl = [
                    [1.0 / sigma, 0.0, (-(py - pose0[1]) + rx) / sigma],
                    [0.0, 1.0 / sigma, ((px - pose0[0]) + ry) / sigma],
                ];
                // The curvature rows: the fix's two rows with its IRLS
                // weight.
                let curv = [(w, jg[0], jl[0]), (w, jg[1], jl[1])];
                let add = |t: &mut Acc| {
                    for row in 0..2 {
                        for i in 0..ng {
                            t.bg[i] += w * jg[row][i] * r[row];
                        }
                        for i in 0..3 {
                            t.bl[i] += w * jl[row][i] * r[row];
                        }
                    }
                    for (wc, cg, cl) in &curv {
                        for i in 0..ng {
                            for j in 0..ng {
                                t.hgg[(i, j)] += wc * cg[i] * cg[j];
                            }
                            for j in 0..3 {
                                t.hgl[(i, j)] += wc * cg[i] * cl[j];
                            }
                        }
                        for i in 0..3 {
                            for j in 0..3 {
                                t.hll[(i, j)] += wc * cl[i] * cl[j];
                            }
                        }
                    }
                };
                add(a);
                if s.record_rows {
                    let narrow = |v: f64| v as f32;
                    rows.push(FixLin {
                        t: f.t,
                        residual_m: [f.x - ax, f.y - ay_],
                        a: jg.map(|r| r.map(narrow)),
                        b: jl.map(|r| r.map(narrow)),
                        w: w as f32,
                        sigma: sigma as f32,
                        segment: 0,
                    });
                }
                if let Some(b) = block.as_mut() {
                    add(b);
                    in_block += 1;
                    if in_block >= s.block_fixes {
                        blocks.push(std::mem::replace(b, Acc::new(ng)));
                        in_block = 0;
                    }
                }
            }
        }
        if s.record_every > 0 && ((k - seg.k0).is_multiple_of(s.record_every) || k + 1 == seg.k1) {
            track.push([pose.x, pose.y]);
        }
    }
    if let Some(b) = block {
        if in_block > 0 {
            blocks.push(b);
        }
    }
    SegEval {
        cost,
        acc,
        blocks,
        residuals,
        sum_sq_m,
        track,
        residuals_m,
        rows,
    }
}

/// Solve the damped reduced system; returns the global step and each
/// segment's pose step.
fn solve_step(
    accs: &[Acc],
    ng: usize,
    lambda: f64,
    priors: &[(usize, f64, f64)],
    g: &[f64],
) -> Option<(DVector<f64>, Vec<Vector3<f64>>, f64)> {
    let mut s = DMatrix::zeros(ng, ng);
    let mut rhs = DVector::zeros(ng);
    let mut inv_ll = Vec::with_capacity(accs.len());
    for a in accs {
        s += &a.hgg;
        rhs += &a.bg;
    }
    for &(i, value, sigma) in priors {
        let w = 1.0 / (sigma * sigma);
        s[(i, i)] += w;
        rhs[i] += w * (value - g[i]);
    }
    for i in 0..ng {
        s[(i, i)] += lambda * s[(i, i)].max(1e-12);
    }
    for a in accs {
        let mut hll = a.hll;
        for i in 0..3 {
            hll[(i, i)] += lambda * hll[(i, i)].max(1e-12);
        }
        let inv = hll.try_inverse()?;
        let hgl_inv = &a.hgl * DMatrix::from_iterator(3, 3, inv.iter().copied());
        s -= &hgl_inv * a.hgl.transpose();
        rhs -= &hgl_inv * DVector::from_iterator(3, a.bl.iter().copied());
        inv_ll.push(inv);
    }
    let chol = s.clone().cholesky()?;
    let dg = chol.solve(&rhs);
    if !dg.iter().all(|v| v.is_finite()) {
        return None;
    }
    // The step in units of the parameters' (unit-scale) sigmas.
    let inv = chol.inverse();
    let ratio = (0..ng)
        .map(|i| dg[i].abs() / inv[(i, i)].max(1e-300).sqrt())
        .fold(0.0, f64::max);
    let mut dl = Vec::with_capacity(accs.len());
    for (a, inv) in accs.iter().zip(&inv_ll) {
        let t = a.hgl.transpose() * &dg;
        let v = a.bl - Vector3::new(t[0], t[1], t[2]);
        dl.push(inv * v);
    }
    Some((dg, dl, ratio))
}

/// Outcome of a fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    /// Global parameters.
    pub g: Vec<f64>,
    /// Formal covariance of the global parameters (residual variance and
    /// autocorrelation included).
    pub formal: DMatrix<f64>,
    /// Block-jackknife covariance, when there were enough blocks.
    pub jackknife: Option<DMatrix<f64>>,
    /// The delete-a-third jackknife's covariance of the circumferences
    /// ([`thirds_floor`]), kept only where the drive's thirds disagree
    /// beyond the other sources' sigmas: a floor under them.
    pub thirds: Option<DMatrix<f64>>,
    /// Covariance from the error model fitted to the residuals
    /// ([`crate::sigmas::uncertainty::correlated_covariance`]), when it could be fitted.
    pub correlated: Option<DMatrix<f64>>,
    /// The error model (east, north) fitted to the residuals.
    pub error_model: Option<[ErrorModel; 2]>,
    /// RMS of the 2-D position residuals, m.
    pub residual_rms_m: f64,
    /// Segments used.
    pub segments: usize,
    /// Segments dropped (too few fixes or too short).
    pub dropped_segments: usize,
    /// The parameters at the end of each stage, with its segment length (s).
    pub steps: Vec<(f64, Vec<f64>)>,
    /// The fitted model's track and residuals (the last stage's segments).
    pub model_track: ModelTrack,
}

/// A model's track over the segments of a fit, each from its own initial
/// pose, and its residuals against the accepted GNSS fixes: what the
/// report draws as "the model the estimate came from".
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelTrack {
    /// The rear-axle centre per segment (east, north), m, thinned.
    pub parts: Vec<Vec<[f64; 2]>>,
    /// Every accepted fix in a segment: time (s), and fix minus the model's
    /// antenna position (east, north), m.
    pub residuals: Vec<[f64; 3]>,
}

impl ModelTrack {
    fn from_evals(evals: &mut [SegEval]) -> ModelTrack {
        let mut out = ModelTrack::default();
        for e in evals {
            out.parts.push(std::mem::take(&mut e.track));
            out.residuals.append(&mut e.residuals_m);
        }
        out
    }

    /// RMS of the residuals' length, m (`None` without residuals).
    pub fn residual_rms_m(&self) -> Option<f64> {
        (!self.residuals.is_empty()).then(|| {
            let ss: f64 = self
                .residuals
                .iter()
                .map(|r| r[1] * r[1] + r[2] * r[2])
                .sum();
            (ss / self.residuals.len() as f64).sqrt()
        })
    }
}

/// `model` with the parameters `g` dead-reckoned over segments of about
/// `length_s`, each started from the reference pose at its start (no
/// fitting): the track of a model that was not fitted segment-wise (the
/// paper's method), on the same footing as the batch fit's.
pub fn anchored_track<M: StepModel>(
    model: &M,
    g: &[f64],
    p: &Series,
    r: &Reference,
    length_s: f64,
) -> ModelTrack {
    let fixes: Vec<RefFix> = r.fixes.iter().filter(|f| f.accepted).copied().collect();
    let (segs, _) = make_segments(p, &fixes, length_s, &|_| false);
    let settings = EvalSettings {
        record_every: p.len().div_ceil(REPORT_POINTS).max(1),
        ..EvalSettings::plain(p.lever_arm)
    };
    let mut evals: Vec<SegEval> = segs
        .iter()
        .map(|s| {
            let pose = [r.x[s.k0], r.y[s.k0], r.yaw[s.k0]];
            eval_segment(model, g, s, pose, &fixes, &settings, p)
        })
        .collect();
    ModelTrack::from_evals(&mut evals)
}

/// The end of a fit stage: segments, their poses, segments dropped, robust scale.
type StageEnd = (Vec<Segment>, Vec<[f64; 3]>, usize, f64);

/// Fit `model` to the accepted fixes: stages of segment lengths, LM in each.
pub fn fit<M: StepModel>(
    model: &M,
    p: &Series,
    r: &Reference,
    g0: &[f64],
    stage_lengths: &[f64],
    breaks: &dyn Fn(usize) -> bool,
    progress: &mut dyn FnMut(f64),
) -> Result<Fit, CalibrationError> {
    let ng = model.n_global();
    let fixes: Vec<RefFix> = r.fixes.iter().filter(|f| f.accepted).copied().collect();
    let priors = model.priors();
    let mut g = g0.to_vec();
    let mut steps = Vec::new();
    let mut last: Option<StageEnd> = None;
    for (stage, &len) in stage_lengths.iter().enumerate() {
        let last_stage = stage + 1 == stage_lengths.len();
        let (mut segs, dropped) = make_segments(p, &fixes, len, breaks);
        if segs.is_empty() {
            return Err(CalibrationError::TooShort {
                distance_m: r.distance_m,
                needed_m: 50.0,
            });
        }
        if !last_stage {
            // The early stages only bring the parameters near: on a long drive
            // about 10 minutes of segments, spread over it, are enough.
            let total: f64 = segs.iter().map(|s| p.t[s.k1 - 1] - p.t[s.k0]).sum();
            let every = (total / EARLY_STAGE_S).ceil().max(1.0) as usize;
            segs = segs.into_iter().step_by(every).collect();
        }
        let mut poses: Vec<[f64; 3]> = segs
            .iter()
            .map(|s| [r.x[s.k0], r.y[s.k0], r.yaw[s.k0]])
            .collect();
        let mut settings = EvalSettings::plain(p.lever_arm);
        let mut lambda = 1e-3;
        let eval_all = |g: &[f64], poses: &[[f64; 3]], s: &EvalSettings| -> (f64, Vec<SegEval>) {
            let mut total = 0.0;
            let mut out = Vec::with_capacity(segs.len());
            for (seg, pose) in segs.iter().zip(poses) {
                let e = eval_segment(model, g, seg, *pose, &fixes, s, p);
                total += e.cost;
                out.push(e);
            }
            total += prior_cost(&priors, g);
            (total, out)
        };
        // Robust scale from the residuals at the start of the stage.
        settings.scale = robust_scale(&eval_all(&g, &poses, &settings).1);
        settings.jacobian = true;
        let tolerance = if last_stage { 1e-8 } else { 1e-5 };
        let step_tolerance = if last_stage { 1e-3 } else { 0.1 };
        let (mut cost, mut evals) = eval_all(&g, &poses, &settings);
        for it in 0..40 {
            let accs: Vec<Acc> = evals.iter().filter_map(|e| e.acc.clone()).collect();
            let mut accepted = false;
            let mut converged = false;
            while lambda < 1e10 {
                let Some((dg, dl, ratio)) = solve_step(&accs, ng, lambda, &priors, &g) else {
                    lambda *= 10.0;
                    continue;
                };
                let g_new: Vec<f64> = g.iter().zip(dg.iter()).map(|(a, d)| a + d).collect();
                let poses_new: Vec<[f64; 3]> = poses
                    .iter()
                    .zip(&dl)
                    .map(|(q, d)| [q[0] + d[0], q[1] + d[1], q[2] + d[2]])
                    .collect();
                // The trial carries its Jacobian: accepted, it is the next linearisation.
                let (cost_new, evals_new) = eval_all(&g_new, &poses_new, &settings);
                if cost_new.is_finite() && cost_new <= cost {
                    let rel = (cost - cost_new) / cost.max(1e-300);
                    g = g_new;
                    poses = poses_new;
                    cost = cost_new;
                    evals = evals_new;
                    lambda = (lambda / 3.0).max(1e-12);
                    accepted = true;
                    // Done when the cost stalls or the step is a small
                    // fraction of the parameters' sigmas.
                    converged = rel < tolerance || ratio < step_tolerance;
                    break;
                }
                lambda *= 5.0;
            }
            if !accepted || converged {
                break;
            }
            if it % 4 == 3 {
                // Re-estimate the robust scale as the fit improves (a change
                // under 2 % is not worth a new cost function).
                let scale = robust_scale(&evals);
                if (scale / settings.scale - 1.0).abs() > 0.02 {
                    settings.scale = scale;
                    (cost, evals) = eval_all(&g, &poses, &settings);
                }
            }
        }
        if !g.iter().all(|v| v.is_finite()) {
            return Err(CalibrationError::Numerical {
                stage: "batch fit",
                detail: "non-finite parameters".to_string(),
            });
        }
        steps.push((len, g.clone()));
        progress((stage + 1) as f64 / stage_lengths.len() as f64);
        last = Some((segs, poses, dropped, settings.scale));
    }
    let Some((segs, poses, dropped, scale)) = last else {
        return Err(CalibrationError::InvalidConfig {
            field: "segment_length_s",
            reason: "no fit stage".to_string(),
        });
    };
    covariance(model, p, &fixes, &segs, &poses, &g, scale, dropped, steps)
}

fn prior_cost(priors: &[(usize, f64, f64)], g: &[f64]) -> f64 {
    priors
        .iter()
        .map(|&(i, v, s)| 0.5 * ((g[i] - v) / s).powi(2))
        .sum()
}

/// Robust scale of normalised residuals (>= 1: never trust the fixes more than their sigma).
fn robust_scale(evals: &[SegEval]) -> f64 {
    let mut u: Vec<f64> = evals
        .iter()
        .flat_map(|e| {
            e.residuals
                .iter()
                .map(|r| (r[0] * r[0] + r[1] * r[1]).sqrt())
        })
        .collect();
    if u.len() < 10 {
        return 1.0;
    }
    u.sort_by(f64::total_cmp);
    // Median of a 2-D standard normal norm is sqrt(2 ln 2) = 1.1774.
    (u[u.len() / 2] / 1.1774).max(1.0)
}

/// The fit's covariances at its solution `g` (formal, jackknife,
/// error-model) and its track and residual, from the segments evaluated
/// once more with the Jacobians.
#[allow(clippy::too_many_arguments)]
fn covariance<M: StepModel>(
    model: &M,
    p: &Series,
    fixes: &[RefFix],
    segs: &[Segment],
    poses: &[[f64; 3]],
    g: &[f64],
    scale: f64,
    dropped: usize,
    steps: Vec<(f64, Vec<f64>)>,
) -> Result<Fit, CalibrationError> {
    let ng = model.n_global();
    let total_fixes: usize = segs.iter().map(|s| s.fixes.len()).sum();
    // About 40 blocks over the drive, at least 5 fixes each.
    let block_fixes = (total_fixes / 40).max(5);
    let settings = EvalSettings {
        lever: p.lever_arm,
        scale,
        jacobian: true,
        block_fixes,
        record_every: p.len().div_ceil(REPORT_POINTS).max(1),
        record_rows: true,
    };
    let mut evals: Vec<SegEval> = segs
        .iter()
        .zip(poses)
        .map(|(s, pose)| eval_segment(model, g, s, *pose, fixes, &settings, p))
        .collect();
    let sums = ResidualSums::of(&evals);
    let n_res = sums.n_res;
    let n_params = ng + 3 * segs.len();
    let dof = (2 * n_res).saturating_sub(n_params).max(1);
    let chi2 = sums.sum_sq / dof as f64;
    let inflation = sums.inflation();
    let accs: Vec<Acc> = evals.iter().filter_map(|e| e.acc.clone()).collect();
    let Some((info, _)) = reduced(model, &accs) else {
        return Err(CalibrationError::Numerical {
            stage: "batch covariance",
            detail: "a segment's pose information is singular".to_string(),
        });
    };
    let Some(info_inv) = info.clone().try_inverse() else {
        return Err(CalibrationError::Unobservable {
            parameter: "the batch model parameters",
            reason: "the information matrix is singular (the drive does not excite them)"
                .to_string(),
        });
    };
    let formal = &info_inv * (chi2.max(1e-12) * inflation);
    let (correlated, error_model) = match error_model_covariance(&mut evals, &accs, &info_inv, ng) {
        Some((c, m)) => (Some(c), Some(m)),
        None => (None, None),
    };
    let jackknife = jackknife(model, &evals, &accs);
    let thirds = thirds(model, &evals, &accs).and_then(|t| {
        let other = correlated.as_ref().or(jackknife.as_ref());
        thirds_floor(t, &formal, other, model.scale_params())
    });
    let model_track = ModelTrack::from_evals(&mut evals);
    Ok(Fit {
        model_track,
        g: g.to_vec(),
        formal,
        jackknife,
        thirds,
        correlated,
        error_model,
        residual_rms_m: (sums.sum_sq_m / n_res.max(1) as f64).sqrt(),
        segments: segs.len(),
        dropped_segments: dropped,
        steps,
    })
}

/// Sums over the normalised residuals of all segments.
struct ResidualSums {
    /// Sum of squares of the normalised residuals.
    sum_sq: f64,
    /// Residuals (2-D each).
    n_res: usize,
    /// Lag-1 products of neighbouring residuals within a segment.
    lag_num: f64,
    /// Squares, for the lag-1 correlation.
    lag_den: f64,
    /// Sum of squares of the residuals in metres.
    sum_sq_m: f64,
}

impl ResidualSums {
    fn of(evals: &[SegEval]) -> ResidualSums {
        let mut sum_sq = 0.0;
        let mut n_res = 0usize;
        let (mut lag_num, mut lag_den) = (0.0, 0.0);
        let mut sum_sq_m = 0.0;
        for e in evals {
            sum_sq_m += e.sum_sq_m;
            for (i, r) in e.residuals.iter().enumerate() {
                sum_sq += r[0] * r[0] + r[1] * r[1];
                n_res += 1;
                if i > 0 {
                    let q = e.residuals[i - 1];
                    lag_num += r[0] * q[0] + r[1] * q[1];
                }
                lag_den += r[0] * r[0] + r[1] * r[1];
            }
        }
        ResidualSums {
            sum_sq,
            n_res,
            lag_num,
            lag_den,
            sum_sq_m,
        }
    }

    /// The variance inflation of the residuals' lag-1 correlation rho
    /// (clamped to 0..0.95): (1 + rho) / (1 - rho).
    fn inflation(&self) -> f64 {
        let rho = if self.lag_den > 0.0 {
            (self.lag_num / self.lag_den).clamp(0.0, 0.95)
        } else {
            0.0
        };
        (1.0 + rho) / (1.0 - rho)
    }
}

/// The global parameters' reduced normal equations (information and
/// right-hand side, the segments' poses eliminated, the priors added) of
/// the segments' accumulations `accs`; `None` when a pose's information is
/// singular.
fn reduced(model: &dyn StepModel, accs: &[Acc]) -> Option<(DMatrix<f64>, DVector<f64>)> {
    let ng = model.n_global();
    let mut s = DMatrix::zeros(ng, ng);
    let mut rhs = DVector::zeros(ng);
    for a in accs {
        s += &a.hgg;
        rhs += &a.bg;
        let inv = a.hll.try_inverse()?;
        let hgl_inv = &a.hgl * DMatrix::from_iterator(3, 3, inv.iter().copied());
        s -= &hgl_inv * a.hgl.transpose();
        rhs -= &hgl_inv * DVector::from_iterator(3, a.bl.iter().copied());
    }
    for &(i, _, sigma) in &model.priors() {
        s[(i, i)] += 1.0 / (sigma * sigma);
    }
    Some((s, rhs))
}

/// The solution's step with `accs` (`None` when singular).
fn solve_reduced(model: &dyn StepModel, accs: &[Acc]) -> Option<DVector<f64>> {
    let (s, rhs) = reduced(model, accs)?;
    s.lu().solve(&rhs)
}

/// The linearised jackknife covariance: of the blocks of fixes left out,
/// and of the whole segments left out, the larger by the circumferences'
/// variance.
fn jackknife(model: &dyn StepModel, evals: &[SegEval], accs: &[Acc]) -> Option<DMatrix<f64>> {
    // Linearised block jackknife: leave each block of fixes out.
    let mut estimates = Vec::new();
    for (si, e) in evals.iter().enumerate() {
        for b in &e.blocks {
            let mut left = accs.to_vec();
            let rest = left[si].sub(b);
            let singular =
                rest.hll.try_inverse().is_none() || rest.hll.trace() < 1e-9 * left[si].hll.trace();
            if singular {
                left.remove(si);
            } else {
                left[si] = rest;
            }
            if let Some(d) = solve_reduced(model, &left) {
                estimates.push(d);
            }
        }
    }
    let blocks = jackknife_covariance(&estimates).filter(|c| c.iter().all(|v| v.is_finite()));
    // Blocks of fixes are shorter than the GNSS error's correlation time
    // (a Gauss-Markov error of tens of seconds moves neighbouring blocks
    // together), so leaving one out underestimates the spread. Each segment
    // has its own pose and spans minutes: leaving whole segments out sees
    // the correlated error; the larger of the two (by the circumferences'
    // variance) is kept.
    let mut by_segment = Vec::new();
    for si in 0..accs.len() {
        let mut left = accs.to_vec();
        left.remove(si);
        if let Some(d) = solve_reduced(model, &left) {
            by_segment.push(d);
        }
    }
    let segments = jackknife_covariance(&by_segment).filter(|c| c.iter().all(|v| v.is_finite()));
    let scale_var = |c: &DMatrix<f64>| c[(0, 0)] + c[(1, 1)];
    match (blocks, segments) {
        (Some(b), Some(s)) if scale_var(&s) > scale_var(&b) => Some(s),
        (Some(b), _) => Some(b),
        (None, s) => s,
    }
}

/// The delete-a-third jackknife: the drive's blocks of fixes in time
/// order cut into three runs, the fit (linearised at its solution) repeated
/// without each, and the spread of the three as the covariance,
/// `(3-1)/3 sum (x_k - mean)(x_k - mean)^T`. Three runs, not more: each
/// must be longer than the GNSS error's correlation time, or the runs move
/// together and the spread is too small (as the block jackknife's is).
/// `None` for fewer than three blocks or a run whose removal leaves the
/// fit singular.
fn thirds(model: &dyn StepModel, evals: &[SegEval], accs: &[Acc]) -> Option<DMatrix<f64>> {
    let all: Vec<(usize, usize)> = evals
        .iter()
        .enumerate()
        .flat_map(|(si, e)| (0..e.blocks.len()).map(move |b| (si, b)))
        .collect();
    if all.len() < 3 || accs.len() != evals.len() {
        return None;
    }
    let mut estimates = Vec::with_capacity(3);
    for k in 0..3 {
        let mut left = accs.to_vec();
        for &(si, b) in &all[k * all.len() / 3..(k + 1) * all.len() / 3] {
            left[si] = left[si].sub(&evals[si].blocks[b]);
        }
        // A segment left with (next to) none of its fixes goes.
        let kept: Vec<Acc> = left
            .into_iter()
            .zip(accs)
            .filter(|(a, whole)| {
                a.hll.try_inverse().is_some() && a.hll.trace() >= 1e-9 * whole.hll.trace()
            })
            .map(|(a, _)| a)
            .collect();
        estimates.push(solve_reduced(model, &kept)?);
    }
    jackknife_covariance(&estimates).filter(|c| c.iter().all(|v| v.is_finite()))
}

/// The delete-a-third spread's variance over the other sources' at which
/// the thirds are taken to disagree: under an honest error model the
/// spread of three is about its variance times chi-square with 2 degrees of
/// freedom over 2, whose 95 % point is 5.99 / 2.
pub const THIRDS_DISAGREE_RATIO: f64 = 3.0;

/// The thirds' covariance as a floor, for the parameters that set the
/// distance scale (`scale`: the circumferences, or a common distance
/// factor) only and only where the thirds disagree beyond the other
/// sources ([`THIRDS_DISAGREE_RATIO`]); every other row and column zero.
/// `None` where nothing is kept.
///
/// Why gated: with two degrees of freedom the spread of three scatters
/// (a factor of 3 between drives of one car is common), and a floor kept on
/// every drive scattered honest drives' sigmas so far that a fleet's wear
/// trend weighted by them came out 3.5 of its sigmas off (the thirteenth
/// session, reverted). Kept where the thirds disagree, it catches what the
/// error model cannot: a stretch of correlated GNSS error longer than its
/// fit can pin down, or physics the model leaves out acting on one part of
/// the drive (comma2k19's thirds calibrated apart read 2.2236, 2.2181 and
/// 2.2233 m against the error model's 0.55 mm). Why the circumferences
/// only: a parameter whose information sits in one stretch of the drive,
/// the antenna's and the track's in its turns, is barely determined
/// without that third, and the spread would be that third's absence
/// rather than the estimate's error (wid-trial02's one U-turn put the
/// antenna's lateral sigma over the 0.1 m the odometry fuses it at).
fn thirds_floor(
    thirds: DMatrix<f64>,
    formal: &DMatrix<f64>,
    other: Option<&DMatrix<f64>>,
    scale: &[usize],
) -> Option<DMatrix<f64>> {
    let keep: Vec<bool> = (0..thirds.nrows())
        .map(|i| {
            if !scale.contains(&i) {
                return false;
            }
            thirds[(i, i)] / base_variance(formal, other, i) > THIRDS_DISAGREE_RATIO
        })
        .collect();
    if !keep.iter().any(|&k| k) {
        return None;
    }
    let mut c = thirds;
    for i in 0..c.nrows() {
        for j in 0..c.ncols() {
            if !(keep[i] && keep[j]) {
                c[(i, j)] = 0.0;
            }
        }
    }
    Some(c)
}

/// The variance of parameter `i` from the sources beside the thirds (the
/// formal covariance and `other`, the error model's or the jackknife's),
/// the larger; never zero.
fn base_variance(formal: &DMatrix<f64>, other: Option<&DMatrix<f64>>, i: usize) -> f64 {
    other
        .map_or(0.0, |c| c[(i, i)])
        .max(formal[(i, i)])
        .max(f64::MIN_POSITIVE)
}

/// The covariance of the global parameters from an error model of the
/// residuals ([`crate::error_model`]): the fit linearised at its solution,
/// the model fitted through it, the covariance under the least favourable
/// plausible model. Takes the evaluations' recorded rows.
fn error_model_covariance(
    evals: &mut [SegEval],
    accs: &[Acc],
    info_inv: &DMatrix<f64>,
    ng: usize,
) -> Option<(DMatrix<f64>, [ErrorModel; 2])> {
    let mut lin = Linearisation {
        ng,
        fixes: Vec::new(),
        segments: Vec::with_capacity(accs.len()),
        info_inv: info_inv.clone(),
    };
    for (si, (e, a)) in evals.iter_mut().zip(accs).enumerate() {
        let pose_inv = a.hll.try_inverse()?;
        // Hll^-1 Hgl^T: how the segment's pose follows the parameters.
        let m = DMatrix::from_iterator(3, 3, pose_inv.iter().copied()) * a.hgl.transpose();
        let mut follow = [[0.0; MAX_GLOBAL]; 3];
        for (l, row) in follow.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate().take(ng) {
                *v = m[(l, j)];
            }
        }
        lin.segments.push(SegmentLin { pose_inv, follow });
        lin.fixes
            .extend(std::mem::take(&mut e.rows).into_iter().map(|mut f| {
                f.segment = si as u32;
                f
            }));
    }
    let plausible = fit_error_model(&lin)?;
    conservative_covariance(&lin, &plausible)
}

impl Fit {
    /// The covariances the sigmas come from: the formal one (a floor), the
    /// error model's where it could be fitted, else the jackknife's, and
    /// the thirds' where they disagree (a floor too).
    fn sigma_sources(&self) -> [Option<&DMatrix<f64>>; 3] {
        [
            Some(&self.formal),
            self.correlated.as_ref().or(self.jackknife.as_ref()),
            self.thirds.as_ref(),
        ]
    }

    /// Sigmas: the largest of the sources' values, entry by entry.
    pub fn sigmas(&self) -> Sigmas {
        self.sigma_sources()
            .iter()
            .flatten()
            .fold(Sigmas::from_covariance(&self.formal), |s, c| {
                s.max(Sigmas::from_covariance(c))
            })
    }

    /// The variance of parameter `i`: the largest of the sources'.
    pub fn variance(&self, i: usize) -> f64 {
        self.sigma_sources()
            .iter()
            .flatten()
            .map(|c| c[(i, i)].max(0.0))
            .fold(0.0, f64::max)
    }

    /// Whether parameter `i`'s sigma is the thirds' spread: kept only
    /// where it exceeds the other sources ([`thirds_floor`]), it is then
    /// the largest.
    pub fn floored_by_thirds(&self, i: usize) -> bool {
        self.thirds.as_ref().is_some_and(|t| t[(i, i)] > 0.0)
    }

    /// What the sigmas rest on, for the result.
    pub fn sigma_basis(&self) -> SigmaBasis {
        let mut basis = match (&self.correlated, &self.error_model) {
            (Some(_), Some(m)) => SigmaBasis::error_model(m),
            _ => SigmaBasis::jackknife(self.jackknife.is_some()),
        };
        if let Some(t) = &self.thirds {
            let other = self.sigma_sources()[1];
            let ratio = (0..t.nrows())
                .filter(|&i| self.floored_by_thirds(i))
                .map(|i| (t[(i, i)] / base_variance(&self.formal, other, i)).sqrt())
                .fold(0.0, f64::max);
            basis.method = format!(
                "{}; the scale's sigmas raised up to {ratio:.1}x to the spread of the drive \
                 calibrated without each third of it, which disagree beyond them",
                basis.method
            );
        }
        basis
    }
}

/// Stage lengths: from 10 s segments, four times longer each stage, up to `final_len`.
pub fn stages(final_len: f64) -> Vec<f64> {
    let mut out = Vec::new();
    let mut l = 10.0;
    while l * 1.5 < final_len {
        out.push(l);
        l *= 4.0;
    }
    out.push(final_len);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_thirds_floor_only_the_scale_and_only_where_they_disagree() {
        // Three parameters: two circumferences and a track; the error
        // model's variances 1, 1, 1 (formal 0.5 each).
        let formal = DMatrix::from_diagonal_element(3, 3, 0.5);
        let model = DMatrix::from_diagonal_element(3, 3, 1.0);
        // The thirds agree within chance (ratio 2.5 < 3): no floor.
        let agree = DMatrix::from_diagonal_element(3, 3, 2.5);
        assert!(thirds_floor(agree, &formal, Some(&model), &[0, 1]).is_none());
        // They disagree (ratio 4) on the circumferences and on the track:
        // the floor keeps the circumferences' block, not the track's.
        let mut apart = DMatrix::from_diagonal_element(3, 3, 4.0);
        apart[(0, 1)] = 3.0;
        apart[(1, 0)] = 3.0;
        apart[(0, 2)] = 1.0;
        apart[(2, 0)] = 1.0;
        let c = thirds_floor(apart, &formal, Some(&model), &[0, 1]).expect("a floor");
        assert_eq!((c[(0, 0)], c[(1, 1)], c[(0, 1)]), (4.0, 4.0, 3.0));
        assert_eq!((c[(2, 2)], c[(0, 2)], c[(2, 0)]), (0.0, 0.0, 0.0));
        // Measured against the larger source: the formal one where it is.
        let big_formal = DMatrix::from_diagonal_element(3, 3, 2.0);
        let apart = DMatrix::from_diagonal_element(3, 3, 4.0);
        assert!(thirds_floor(apart, &big_formal, Some(&model), &[0, 1]).is_none());
        // A model whose scale is one parameter (the gyro model's distance
        // factor, index 2) floors that one only.
        let apart = DMatrix::from_diagonal_element(3, 3, 4.0);
        let c = thirds_floor(apart, &formal, Some(&model), &[2]).expect("a floor");
        assert_eq!((c[(0, 0)], c[(1, 1)], c[(2, 2)]), (0.0, 0.0, 4.0));
    }

    #[test]
    fn small_sin_cos_is_accurate() {
        for a in [-0.3, -0.049, -1e-3, 0.0, 2e-4, 0.02, 0.0499, 0.7] {
            let (s, c) = small_sin_cos(a);
            assert!(
                (s - a.sin()).abs() < 1e-13 && (c - a.cos()).abs() < 1e-13,
                "{a}"
            );
        }
    }
}
