//! Layer 2: the EKF on the 2W model (eq. 3-7) and the accumulation of the
//! weighted least squares of eq. (8)-(9); plus the dead-reckoning check of
//! section 4 (the 2W model integrated without fusion).
//!
//! State `x = [x, y, theta]`, input `u = [d_RL, d_RR] = [n_RL c_RL, n_RR c_RR]`
//! with the circumferences of the previous iteration, measurement `y = r_k`,
//! `H = I`. The prediction is eq. (1)-(2) (`vehicle_model::two_wheel`), its
//! Jacobian
//! ```text
//! F = [[1, 0, -ds sin(course)], [0, 1, ds cos(course)], [0, 0, 1]],
//! course = theta + dtheta/2 + beta.
//! ```
//!
//! Our reading of eq. (8)-(9): the row block of sample k is
//! `Y_k = r_k - x^_{k-1}` (the reference now, minus the *filtered* pose one
//! step before) and `Phi_k` the 2W displacement per unit circumference from
//! `x^_{k-1}`, i.e. `Y_k = Phi_k [c_RL, c_RR]^T` says "one model step from
//! the filtered pose lands on the reference". Because `x^_{k-1}` lags the
//! reference when the circumferences are off, the solution overshoots the
//! truth by `(1-G)/G` times the current error (G the Kalman gain), so eq.
//! (11) with `alpha < 1` makes it a convergent fixed-point iteration; as the
//! schedule of eq. (10) raises G the overshoot fades. Rows are taken where the
//! reference is valid and not across a break of the wheel data. With
//! side-slip on, the regressor's direction is `theta^_{k-1} + beta_k`.
//!
//! Outages: the filter predicts through a GNSS outage without updates and
//! restarts on the reference where it comes back (no row at that sample).

use crate::error::CalibrationError;
use crate::reference::Reference;
use crate::series::Series;
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use vehicle_model::two_wheel::{step, wrap_angle, Pose2, TwoWheelParams};

/// Diagonals of the model covariance P and measurement covariance M.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Covariances {
    /// P (eq. 10b), per step: x, y in m^2, theta in rad^2.
    pub p: [f64; 3],
    /// M (eq. 10a): x, y in m^2, theta in rad^2.
    pub m: [f64; 3],
}

/// The covariance schedule of eq. (10) at iteration `i` (1-based).
///
/// Eq. (10b) as printed, `0.1 - q_P i`, is negative from the first iteration
/// for every q_P in the paper's range; we read it as the same relative
/// decrease as the position entries, `0.1 (1 - q_P i / 10)`, and floor every
/// P entry at 5 % of its initial value so that it stays positive.
pub fn schedule(i: usize, q_m: f64, q_p: f64) -> Covariances {
    let i = i as f64;
    let decay = q_m.powf(i);
    let rel = (1.0 - q_p * i / 10.0).max(0.05);
    Covariances {
        p: [10.0 * rel, 10.0 * rel, 0.1 * rel],
        m: [10.0 / decay, 10.0 / decay, 0.1 / decay],
    }
}

/// Normal equations of eq. (9) for one block of rows, for
/// `[c_RL, c_RR, t_R]` (the third unused when the track width is fixed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalBlock {
    /// Phi^T W Phi.
    pub a: Matrix3<f64>,
    /// Phi^T W Y.
    pub b: Vector3<f64>,
    /// Y^T W Y.
    pub yy: f64,
    /// Rows.
    pub rows: usize,
}

impl Default for NormalBlock {
    fn default() -> Self {
        NormalBlock {
            a: Matrix3::zeros(),
            b: Vector3::zeros(),
            yy: 0.0,
            rows: 0,
        }
    }
}

/// One EKF pass: the normal equations, whole and in time blocks.
#[derive(Debug, Clone, PartialEq)]
pub struct EkfPass {
    /// Sum over all rows.
    pub total: NormalBlock,
    /// Per time block (for the jackknife).
    pub blocks: Vec<NormalBlock>,
    /// 2: `[c_RL, c_RR]`; 3: with the track width.
    pub dim: usize,
}

impl NormalBlock {
    /// Solve for the first `dim` parameters, `None` when singular.
    pub fn solve(&self, dim: usize) -> Option<Vector3<f64>> {
        if dim == 2 {
            let a = self.a.fixed_view::<2, 2>(0, 0).into_owned();
            let b = self.b.fixed_view::<2, 1>(0, 0).into_owned();
            return solve2(&a, &b).map(|x| Vector3::new(x[0], x[1], 0.0));
        }
        let scale = self.a.diagonal().amax();
        let chol = (self.a / scale.max(1e-300)).cholesky()?;
        let x = chol.solve(&(self.b / scale.max(1e-300)));
        x.iter().all(|v| v.is_finite()).then_some(x)
    }
}

impl EkfPass {
    /// The weighted least-squares solution of eq. (9).
    pub fn solve(&self) -> Result<Vector3<f64>, CalibrationError> {
        self.total.solve(self.dim).ok_or_else(|| CalibrationError::Numerical {
            stage: "paper least squares (eq. 9)",
            detail: format!(
                "Phi^T W Phi is singular ({} rows): the wheels hardly turn where there is a reference",
                self.total.rows
            ),
        })
    }
}

/// Solve a 2x2 system, `None` when (nearly) singular.
pub fn solve2(a: &Matrix2<f64>, b: &Vector2<f64>) -> Option<Vector2<f64>> {
    let det = a[(0, 0)] * a[(1, 1)] - a[(0, 1)] * a[(1, 0)];
    let scale = a[(0, 0)].abs().max(a[(1, 1)].abs());
    if !(det.is_finite() && scale > 0.0 && det.abs() > 1e-12 * scale * scale) {
        return None;
    }
    let x = Vector2::new(
        (a[(1, 1)] * b[0] - a[(0, 1)] * b[1]) / det,
        (a[(0, 0)] * b[1] - a[(1, 0)] * b[0]) / det,
    );
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Run the EKF over the drive with circumferences `c` and track `track`
/// and accumulate eq. (9).
///
/// With `estimate_track` the heading row, bilinear in `(c, t_R)`, is
/// linearised at the current values: `h(c, t) ~ Phi_theta c - (h0 / t0) t + h0`,
/// so the row becomes `[-n_RL/t0, n_RR/t0, -h0/t0]` with `Y_theta - h0`
/// (with the reference's heading change standing in for h0 in the regressor).
///
/// The filter steps along `grid` (indices of wheel samples, see [`grid`]):
/// `n_{i,k}` are the revolutions between consecutive grid samples.
#[allow(clippy::too_many_arguments)]
pub fn run_pass(
    p: &Series,
    r: &Reference,
    grid: &[usize],
    c: [f64; 2],
    track: f64,
    cov: &Covariances,
    side_slip: bool,
    estimate_track: bool,
    n_blocks: usize,
) -> Result<EkfPass, CalibrationError> {
    let n = grid.len();
    let params = TwoWheelParams {
        c_rl: c[0],
        c_rr: c[1],
        track_width: track,
    };
    let pm = Matrix3::from_diagonal(&Vector3::new(cov.p[0], cov.p[1], cov.p[2]));
    let mm = Matrix3::from_diagonal(&Vector3::new(cov.m[0], cov.m[1], cov.m[2]));
    let w = [1.0, 1.0, 10.0];
    let block_len = n.div_ceil(n_blocks.max(1)).max(1);
    let mut blocks = vec![NormalBlock::default(); n.div_ceil(block_len)];
    let mut x: Option<(Pose2, Matrix3<f64>)> = None;
    for j in 0..n {
        let k = grid[j];
        // A new piece of wheel data, or the reference back after an outage:
        // the filter restarts on the reference (the prediction through the
        // outage would otherwise enter eq. (9) as one huge row).
        if j == 0 || p.is_piece_start(k) || (r.valid[k] && !r.valid[grid[j - 1]]) {
            x = None;
        }
        let Some((pose, sigma)) = x else {
            if r.valid[k] {
                x = Some((
                    Pose2 {
                        x: r.x[k],
                        y: r.y[k],
                        yaw: r.yaw[k],
                    },
                    mm,
                ));
            }
            continue;
        };
        let k_prev = grid[j - 1];
        let (mut n_rl, mut n_rr) = (0.0, 0.0);
        for i in k_prev + 1..=k {
            n_rl += p.dn_rl[i];
            n_rr += p.dn_rr[i];
        }
        let beta = if side_slip { r.beta[k] } else { 0.0 };
        if r.valid[k] {
            // Eq. (8): one row block per sample.
            let dir = pose.yaw + beta;
            let (s, co) = dir.sin_cos();
            let h0 = (n_rr * c[1] - n_rl * c[0]) / track;
            // The track column uses the reference's heading change in place of
            // h0 (equal at the solution): built from the noisy wheel increments
            // it would be an errors-in-variables regressor and bias t_R.
            let third = if estimate_track {
                -(r.yaw[k] - r.yaw[k_prev]) / track
            } else {
                0.0
            };
            let phi = [
                [0.5 * n_rl * co, 0.5 * n_rr * co, 0.0],
                [0.5 * n_rl * s, 0.5 * n_rr * s, 0.0],
                [-n_rl / track, n_rr / track, third],
            ];
            let mut yv = [
                r.x[k] - pose.x,
                r.y[k] - pose.y,
                wrap_angle(r.yaw[k] - pose.yaw),
            ];
            if estimate_track {
                yv[2] -= h0;
            }
            let blk = &mut blocks[j / block_len];
            for row in 0..3 {
                let wy = w[row] * yv[row];
                for i in 0..3 {
                    blk.b[i] += phi[row][i] * wy;
                    for j in i..3 {
                        blk.a[(i, j)] += w[row] * phi[row][i] * phi[row][j];
                    }
                }
                blk.yy += yv[row] * wy;
            }
            blk.rows += 1;
        }
        // Prediction, eq. (4)-(5).
        let (ds, dyaw) = params.increments(n_rl, n_rr);
        let course = pose.yaw + 0.5 * dyaw + beta;
        let pred = step(pose, ds, dyaw, beta);
        let mut f = Matrix3::identity();
        f[(0, 2)] = -ds * course.sin();
        f[(1, 2)] = ds * course.cos();
        let sp = f * sigma * f.transpose() + pm;
        // Innovation, eq. (6)-(7), H = I.
        let (pose, sigma) = if r.valid[k] {
            let s = sp + mm;
            let Some(s_inv) = s.try_inverse() else {
                return Err(CalibrationError::Numerical {
                    stage: "paper EKF (eq. 7)",
                    detail: format!("innovation covariance singular at t = {:.3} s", p.t[k]),
                });
            };
            let g = sp * s_inv;
            let nu = Vector3::new(
                r.x[k] - pred.x,
                r.y[k] - pred.y,
                wrap_angle(r.yaw[k] - pred.yaw),
            );
            let dx = g * nu;
            let upd = Pose2 {
                x: pred.x + dx[0],
                y: pred.y + dx[1],
                yaw: pred.yaw + dx[2],
            };
            let sig = (Matrix3::identity() - g) * sp;
            (upd, 0.5 * (sig + sig.transpose()))
        } else {
            (pred, sp)
        };
        if !(pose.x.is_finite() && pose.y.is_finite() && pose.yaw.is_finite()) {
            return Err(CalibrationError::Numerical {
                stage: "paper EKF",
                detail: format!("non-finite state at t = {:.3} s", p.t[k]),
            });
        }
        x = Some((pose, sigma));
    }
    let mut total = NormalBlock::default();
    for b in &mut blocks {
        for i in 0..3 {
            for j in 0..i {
                b.a[(i, j)] = b.a[(j, i)];
            }
        }
        total.a += b.a;
        total.b += b.b;
        total.yy += b.yy;
        total.rows += b.rows;
    }
    Ok(EkfPass {
        total,
        blocks,
        dim: if estimate_track { 3 } else { 2 },
    })
}

/// The sample grid of the paper's filter: about one wheel sample per
/// `1 / rate_hz` seconds, plus the last sample before and the first of every
/// piece of wheel data.
///
/// The paper leaves the sampling time open. At the wheel rate (100 Hz) the
/// per-step increments of a quantised encoder (e.g. 96 ticks per
/// revolution) carry a noise as large as their left/right difference in a
/// bend, and the heading row of eq. (8) (weight 10) then turns into an
/// errors-in-variables regression that shrinks both circumferences by
/// several percent. At 10 Hz that noise is 100 times smaller relative to the
/// increments.
pub fn grid(p: &Series, rate_hz: f64) -> Vec<usize> {
    let stride = ((1.0 / rate_hz) / p.wheel_dt).round().max(1.0) as usize;
    let mut out = Vec::with_capacity(p.len() / stride + p.piece_starts.len() * 2 + 1);
    let mut last: Option<usize> = None;
    for k in 0..p.len() {
        let next_is_start = k + 1 < p.len() && p.is_piece_start(k + 1);
        let take = match last {
            None => true,
            Some(l) => k - l >= stride || p.is_piece_start(k) || next_is_start || k + 1 == p.len(),
        };
        if take {
            out.push(k);
            last = Some(k);
        }
    }
    out
}

/// Side-slip used when dead-reckoning.
#[derive(Debug, Clone, Copy)]
pub enum Slip<'a> {
    /// beta = 0.
    None,
    /// beta_k given per wheel sample (the layer-1 estimate).
    Series(&'a [f64]),
    /// beta = -k a_y with a_y = v omega from the wheels
    /// ([`Series::lateral_accel`]).
    Gain(f64, &'a [f32]),
}

impl Slip<'_> {
    /// beta at sample k.
    pub fn at(&self, k: usize) -> f64 {
        match self {
            Slip::None => 0.0,
            Slip::Series(b) => b[k],
            Slip::Gain(g, ay) => -g * f64::from(ay[k]),
        }
    }
}

/// Deviation of the pure 2W dead-reckoning from the reference.
#[derive(Debug, Clone, PartialEq)]
pub struct DrDeviation {
    /// Mean distance to the reference over the valid samples, m.
    pub mean_m: f64,
    /// Largest distance, m.
    pub max_m: f64,
    /// Samples compared.
    pub samples: usize,
    /// The track (x, y), thinned to at most `keep` points, when asked for.
    pub track: Vec<[f64; 2]>,
}

/// Integrate the 2W model with `params` over the whole drive without fusion,
/// from the reference pose at the first valid sample (and again after every
/// break of the wheel data), and measure its deviation from the reference
/// (section 4 of the paper).
pub fn dr_deviation(
    p: &Series,
    r: &Reference,
    params: &TwoWheelParams,
    slip: Slip,
    keep: usize,
) -> DrDeviation {
    let n = p.len();
    let stride = if keep == 0 {
        usize::MAX
    } else {
        n.div_ceil(keep).max(1)
    };
    let mut track = Vec::new();
    let mut pose: Option<Pose2> = None;
    let (mut sum, mut max, mut count) = (0.0, 0.0f64, 0usize);
    let mut pieces = p.piece_starts.iter().peekable();
    for k in 0..n {
        if pieces.peek().is_some_and(|&&s| s == k) {
            pieces.next();
            pose = None;
        }
        let cur = match pose {
            None => {
                if !r.valid[k] {
                    continue;
                }
                Pose2 {
                    x: r.x[k],
                    y: r.y[k],
                    yaw: r.yaw[k],
                }
            }
            Some(prev) => {
                let (ds, dyaw) = params.increments(p.dn_rl[k], p.dn_rr[k]);
                let beta = slip.at(k);
                step(prev, ds, dyaw, beta)
            }
        };
        if r.valid[k] {
            let (ex, ey) = (cur.x - r.x[k], cur.y - r.y[k]);
            let d = (ex * ex + ey * ey).sqrt();
            sum += d;
            max = max.max(d);
            count += 1;
        }
        if keep > 0 && k % stride == 0 {
            track.push([cur.x, cur.y]);
        }
        pose = Some(cur);
    }
    DrDeviation {
        mean_m: if count > 0 {
            sum / count as f64
        } else {
            f64::NAN
        },
        max_m: max,
        samples: count,
        track,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schedule_decreases_and_stays_positive() {
        let mut prev = schedule(1, 1.25, 0.7);
        assert!(prev.p.iter().chain(prev.m.iter()).all(|v| *v > 0.0));
        for i in 2..=20 {
            let c = schedule(i, 1.25, 0.7);
            assert!(c.p.iter().chain(c.m.iter()).all(|v| *v > 0.0), "{i}: {c:?}");
            assert!(c.m[0] < prev.m[0] && c.p[0] <= prev.p[0]);
            prev = c;
        }
        // Eq. (10a) exactly.
        let c = schedule(3, 1.5, 0.2);
        assert!((c.m[0] - 10.0 / 1.5f64.powi(3)).abs() < 1e-12);
        assert!((c.m[2] - 0.1 / 1.5f64.powi(3)).abs() < 1e-12);
        assert!((c.p[0] - (10.0 - 0.2 * 3.0)).abs() < 1e-12);
    }

    #[test]
    fn solve2_refuses_singular() {
        let a = Matrix2::new(1.0, 2.0, 2.0, 4.0);
        assert!(solve2(&a, &Vector2::new(1.0, 1.0)).is_none());
        let a = Matrix2::new(2.0, 0.0, 0.0, 4.0);
        let x = solve2(&a, &Vector2::new(2.0, 2.0)).expect("regular");
        assert!((x[0] - 1.0).abs() < 1e-12 && (x[1] - 0.5).abs() < 1e-12);
    }
}
