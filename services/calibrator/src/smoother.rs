//! The GNSS position smoother, which the clocks (the GNSS alone, for its
//! velocity and the clock offset) and the reference (again after the
//! jumps, and with the lever arm and the accelerations) both run: a Kalman
//! filter on `p'' = a` per axis with an innovation gate, a
//! Rauch-Tung-Striebel smoother, Huber reweighting; between fixes the
//! smoothed states are joined by cubic Hermite curves. Beside the stages.

use crate::error::CalibrationError;

/// Process noise of the position filter without accelerations, m^2/s^3.
pub(crate) const Q_ACCEL_FREE: f64 = 4.0;

/// Process noise of the position filter with IMU accelerations as input, m^2/s^3.
pub(crate) const Q_ACCEL_IMU: f64 = 0.5;

/// Minimum speed for a usable GNSS course, m/s.
pub(crate) const COURSE_MIN_SPEED: f64 = 2.0;

/// A GNSS fix as the later layers use it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefFix {
    /// Time (after any time-offset compensation), s.
    pub t: f64,
    /// Antenna east, m.
    pub x: f64,
    /// Antenna north, m.
    pub y: f64,
    /// 1-sigma, m.
    pub sigma: f64,
    /// Passed the outlier gate.
    pub accepted: bool,
}

/// Symmetric 2x2 covariance of one axis: position, cross, velocity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Cov2 {
    pub(crate) pp: f64,
    pub(crate) pv: f64,
    pub(crate) vv: f64,
}

/// Smoothed position/velocity at the GNSS epochs.
#[derive(Debug, Clone)]
pub(crate) struct PosTrack {
    pub(crate) t: Vec<f64>,
    /// [x, y, vx, vy].
    pub(crate) s: Vec<[f64; 4]>,
    /// Smoothed covariance per axis (shared by x and y).
    pub(crate) cov: Vec<Cov2>,
    pub(crate) accepted: Vec<bool>,
}

impl PosTrack {
    /// Hermite interpolation of position (and velocity) at `t` in [t_j, t_{j+1}].
    pub(crate) fn at(&self, j: usize, t: f64) -> [f64; 4] {
        let n = self.t.len();
        if j + 1 >= n {
            let a = self.s[n - 1];
            let dt = t - self.t[n - 1];
            return [a[0] + a[2] * dt, a[1] + a[3] * dt, a[2], a[3]];
        }
        let (t0, t1) = (self.t[j], self.t[j + 1]);
        let h = t1 - t0;
        if t <= t0 || h <= 0.0 {
            let a = self.s[j];
            let dt = t - t0;
            return [a[0] + a[2] * dt, a[1] + a[3] * dt, a[2], a[3]];
        }
        let s = ((t - t0) / h).min(1.0);
        let (a, b) = (self.s[j], self.s[j + 1]);
        let s2 = s * s;
        let s3 = s2 * s;
        let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
        let h10 = s3 - 2.0 * s2 + s;
        let h01 = -2.0 * s3 + 3.0 * s2;
        let h11 = s3 - s2;
        let d00 = (6.0 * s2 - 6.0 * s) / h;
        let d10 = 3.0 * s2 - 4.0 * s + 1.0;
        let d01 = (-6.0 * s2 + 6.0 * s) / h;
        let d11 = 3.0 * s2 - 2.0 * s;
        [
            h00 * a[0] + h10 * h * a[2] + h01 * b[0] + h11 * h * b[2],
            h00 * a[1] + h10 * h * a[3] + h01 * b[1] + h11 * h * b[3],
            d00 * a[0] + d10 * a[2] + d01 * b[0] + d11 * b[2],
            d00 * a[1] + d10 * a[3] + d01 * b[1] + d11 * b[3],
        ]
    }

    /// Speed at epoch `j`, m/s.
    pub(crate) fn speed(&self, j: usize) -> f64 {
        let s = self.s[j];
        (s[2] * s[2] + s[3] * s[3]).sqrt()
    }
}

/// Kinematic input of one filter interval: position and velocity change
/// explained by the measured acceleration.
pub(crate) type Input = [f64; 4];

/// Huber threshold of the position smoother's reweighting, in units of a
/// fix's residual sigma (the norm of a 2-D residual: about 4 % of normal
/// fixes lie beyond it).
const SMOOTHER_HUBER_K: f64 = 2.5;

/// Reweighting passes of the position smoother at most.
const SMOOTHER_REWEIGHTS: usize = 3;

/// The robust position smoother: [`smooth_pass`] reweighted with Huber
/// weights. Each fix's residual against the smoothed track, over its
/// expected spread (the fix's sigma and the track's), gives its weight
/// (1 within [`SMOOTHER_HUBER_K`], `k / u` beyond: the fix's variance grows
/// with how far out it lies), and the smoother runs again, until the
/// weights settle. Heavy-tailed GNSS errors (multipath, a receiver's
/// wander) pull the track by a bounded amount instead of quadratically;
/// the gate still keeps gross outliers out, and the jump detection
/// (`crate::reference::gnss_jumps`) sets whole offset stretches aside.
pub(crate) fn smooth_positions(
    fixes: &[RefFix],
    z: &[[f64; 2]],
    q: f64,
    gate: f64,
    inputs: Option<&[Input]>,
    set_aside: Option<&[bool]>,
) -> Result<PosTrack, CalibrationError> {
    let n = fixes.len();
    let mut starts: Vec<usize> = (1..n)
        .filter(|&j| fixes[j].t - fixes[j - 1].t > SMOOTHER_SPLIT_GAP_S)
        .collect();
    if starts.is_empty() {
        return smooth_run(fixes, z, q, gate, inputs, set_aside);
    }
    starts.insert(0, 0);
    starts.push(n);
    let mut out = PosTrack {
        t: Vec::with_capacity(n),
        s: Vec::with_capacity(n),
        cov: Vec::with_capacity(n),
        accepted: Vec::with_capacity(n),
    };
    for w in starts.windows(2) {
        let (a, b) = (w[0], w[1]);
        let run = smooth_run(
            &fixes[a..b],
            &z[a..b],
            q,
            gate,
            inputs.map(|i| &i[a..b]),
            set_aside.map(|s| &s[a..b]),
        )?;
        out.t.extend(run.t);
        out.s.extend(run.s);
        out.cov.extend(run.cov);
        out.accepted.extend(run.accepted);
    }
    Ok(out)
}

/// A gap between fixes longer than this, s, splits the smoother into runs
/// smoothed on their own: across it the filter's covariance grows with
/// the gap's cube, nothing of the car's motion on one side constrains the
/// other, and a logger paused for 600 s left the smoothed velocity at
/// 600 m/s for half a minute after it (the 2W fit then diverged). The
/// reference is not valid inside such a gap anyway (`max_gnss_gap_s`).
const SMOOTHER_SPLIT_GAP_S: f64 = 120.0;

/// [`smooth_positions`] of one run without a gap beyond
/// [`SMOOTHER_SPLIT_GAP_S`].
fn smooth_run(
    fixes: &[RefFix],
    z: &[[f64; 2]],
    q: f64,
    gate: f64,
    inputs: Option<&[Input]>,
    set_aside: Option<&[bool]>,
) -> Result<PosTrack, CalibrationError> {
    let mut weights = vec![1.0; fixes.len()];
    let mut track = smooth_pass(fixes, z, q, gate, inputs, set_aside, &weights)?;
    for _ in 0..SMOOTHER_REWEIGHTS {
        let mut changed = 0usize;
        for (j, w) in weights.iter_mut().enumerate() {
            if !track.accepted[j] {
                continue;
            }
            let r = fixes[j].sigma * fixes[j].sigma;
            let d = (z[j][0] - track.s[j][0]).hypot(z[j][1] - track.s[j][1]);
            // The residual's spread taken as the fix's noise plus the
            // track's own uncertainty (an upper bound: fewer fixes are
            // down-weighted than with the exact residual variance).
            let u = d / (r + track.cov[j].pp).max(1e-12).sqrt();
            let new = if u <= SMOOTHER_HUBER_K {
                1.0
            } else {
                SMOOTHER_HUBER_K / u
            };
            if (new - *w).abs() > 0.05 * *w {
                changed += 1;
            }
            *w = new;
        }
        if changed == 0 {
            break;
        }
        track = smooth_pass(fixes, z, q, gate, inputs, set_aside, &weights)?;
    }
    Ok(track)
}

/// One pass of the forward Kalman filter with innovation gate + RTS
/// smoother on `p'' = a`; fix `j`'s variance divided by `weights[j]`.
fn smooth_pass(
    fixes: &[RefFix],
    z: &[[f64; 2]],
    q: f64,
    gate: f64,
    inputs: Option<&[Input]>,
    set_aside: Option<&[bool]>,
    weights: &[f64],
) -> Result<PosTrack, CalibrationError> {
    let n = fixes.len();
    // The kinematic input of the interval ending at fix j: none next to a
    // fix set aside, where a run of predictions would integrate the
    // accelerometer's bias for as long as the jump lasts (the filter
    // bridges it at constant velocity, as it bridges an outage).
    let input_of = |j: usize| -> Input {
        let aside = |k: usize| set_aside.is_some_and(|a| a[k]);
        if aside(j) || (j > 0 && aside(j - 1)) {
            return [0.0; 4];
        }
        inputs.map_or([0.0; 4], |i| i[j])
    };
    let mut xf: Vec<[f64; 4]> = Vec::with_capacity(n);
    let mut pf: Vec<Cov2> = Vec::with_capacity(n);
    let mut pp: Vec<Cov2> = Vec::with_capacity(n);
    let mut accepted = Vec::with_capacity(n);
    let mut rejects_in_row = 0usize;
    let mut last_rejected: Option<(f64, [f64; 2])> = None;
    for j in 0..n {
        let r = fixes[j].sigma * fixes[j].sigma / weights[j].max(1e-6);
        if j == 0 {
            xf.push([z[0][0], z[0][1], 0.0, 0.0]);
            let c = Cov2 {
                pp: r,
                pv: 0.0,
                vv: 400.0,
            };
            pf.push(c);
            pp.push(c);
            accepted.push(true);
            continue;
        }
        let tt = fixes[j].t - fixes[j - 1].t;
        let a = xf[j - 1];
        let u = input_of(j);
        let xp = [
            a[0] + a[2] * tt + u[0],
            a[1] + a[3] * tt + u[1],
            a[2] + u[2],
            a[3] + u[3],
        ];
        let c = pf[j - 1];
        let pred = Cov2 {
            pp: c.pp + 2.0 * tt * c.pv + tt * tt * c.vv + q * tt * tt * tt / 3.0,
            pv: c.pv + tt * c.vv + q * tt * tt / 2.0,
            vv: c.vv + q * tt,
        };
        pp.push(pred);
        if set_aside.is_some_and(|a| a[j]) {
            // Inside a jump (`crate::reference::gnss_jumps`): not a measurement, and
            // not a rejection that could restart the filter on the jump.
            xf.push(xp);
            pf.push(pred);
            accepted.push(false);
            continue;
        }
        let nu = [z[j][0] - xp[0], z[j][1] - xp[1]];
        let s = pred.pp + r;
        let d2 = (nu[0] * nu[0] + nu[1] * nu[1]) / s;
        let mut take = d2 <= gate * gate;
        let mut p_use = pred;
        if !take && rejects_in_row >= 5 {
            // A run of rejections that agree with each other is a jump the
            // filter missed, not outliers: restart on it.
            if let Some((t_prev, z_prev)) = last_rejected {
                let jump = ((z[j][0] - z_prev[0]).powi(2) + (z[j][1] - z_prev[1]).powi(2)).sqrt();
                let speed = (a[2] * a[2] + a[3] * a[3]).sqrt();
                if jump <= (speed + 5.0) * (fixes[j].t - t_prev) + 3.0 * fixes[j].sigma {
                    take = true;
                    p_use = Cov2 {
                        pp: pred.pp + nu[0] * nu[0] + nu[1] * nu[1],
                        pv: pred.pv,
                        vv: pred.vv + 100.0,
                    };
                }
            }
        }
        if take {
            let s = p_use.pp + r;
            let k0 = p_use.pp / s;
            let k1 = p_use.pv / s;
            let nu = [z[j][0] - xp[0], z[j][1] - xp[1]];
            xf.push([
                xp[0] + k0 * nu[0],
                xp[1] + k0 * nu[1],
                xp[2] + k1 * nu[0],
                xp[3] + k1 * nu[1],
            ]);
            pf.push(Cov2 {
                pp: p_use.pp - k0 * p_use.pp,
                pv: p_use.pv - k0 * p_use.pv,
                vv: p_use.vv - k1 * p_use.pv,
            });
            if rejects_in_row > 0 {
                pp[j] = p_use;
            }
            rejects_in_row = 0;
            last_rejected = None;
            accepted.push(true);
        } else {
            xf.push(xp);
            pf.push(pred);
            rejects_in_row += 1;
            last_rejected = Some((fixes[j].t, z[j]));
            accepted.push(false);
        }
    }
    // Rauch-Tung-Striebel backward pass.
    // In place: step j reads the filtered values at j before overwriting them.
    let mut xs = xf;
    let mut ps = pf;
    for j in (0..n.saturating_sub(1)).rev() {
        let tt = fixes[j + 1].t - fixes[j].t;
        let c = ps[j];
        let p1 = pp[j + 1];
        // C = Pf F^T Pp^-1 with F = [[1, tt], [0, 1]].
        let pft = [[c.pp + tt * c.pv, c.pv], [c.pv + tt * c.vv, c.vv]];
        let det = p1.pp * p1.vv - p1.pv * p1.pv;
        if !(det.is_finite() && det > 0.0) {
            return Err(CalibrationError::Numerical {
                stage: "reference position smoother",
                detail: format!(
                    "predicted covariance not positive definite at t = {:.3} s",
                    fixes[j + 1].t
                ),
            });
        }
        let inv = [[p1.vv / det, -p1.pv / det], [-p1.pv / det, p1.pp / det]];
        let g = [
            [
                pft[0][0] * inv[0][0] + pft[0][1] * inv[1][0],
                pft[0][0] * inv[0][1] + pft[0][1] * inv[1][1],
            ],
            [
                pft[1][0] * inv[0][0] + pft[1][1] * inv[1][0],
                pft[1][0] * inv[0][1] + pft[1][1] * inv[1][1],
            ],
        ];
        let a = xs[j];
        let u = input_of(j + 1);
        let xp = [
            a[0] + a[2] * tt + u[0],
            a[1] + a[3] * tt + u[1],
            a[2] + u[2],
            a[3] + u[3],
        ];
        let nx = xs[j + 1];
        for axis in 0..2 {
            let dp = nx[axis] - xp[axis];
            let dv = nx[axis + 2] - xp[axis + 2];
            xs[j][axis] = a[axis] + g[0][0] * dp + g[0][1] * dv;
            xs[j][axis + 2] = a[axis + 2] + g[1][0] * dp + g[1][1] * dv;
        }
        let dpp = ps[j + 1].pp - p1.pp;
        let dpv = ps[j + 1].pv - p1.pv;
        let dvv = ps[j + 1].vv - p1.vv;
        // P += G dP G^T
        let m00 = g[0][0] * dpp + g[0][1] * dpv;
        let m01 = g[0][0] * dpv + g[0][1] * dvv;
        let m10 = g[1][0] * dpp + g[1][1] * dpv;
        let m11 = g[1][0] * dpv + g[1][1] * dvv;
        ps[j] = Cov2 {
            pp: c.pp + m00 * g[0][0] + m01 * g[0][1],
            pv: c.pv + m00 * g[1][0] + m01 * g[1][1],
            vv: c.vv + m10 * g[1][0] + m11 * g[1][1],
        };
    }
    if xs.iter().any(|s| !s.iter().all(|v| v.is_finite())) {
        return Err(CalibrationError::Numerical {
            stage: "reference position smoother",
            detail: "non-finite smoothed state".to_string(),
        });
    }
    Ok(PosTrack {
        t: fixes.iter().map(|f| f.t).collect(),
        s: xs,
        cov: ps,
        accepted,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixes(t0: f64, x0: f64, n: usize, v: f64) -> Vec<RefFix> {
        (0..n)
            .map(|k| {
                let t = t0 + 0.2 * k as f64;
                // A centimetre of noise, deterministic.
                let e = 0.01 * (((k * 7919) % 11) as f64 / 5.0 - 1.0);
                RefFix {
                    t,
                    x: x0 + v * (t - t0) + e,
                    y: 2.0 * e,
                    sigma: 0.02,
                    accepted: true,
                }
            })
            .collect()
    }

    /// A logger paused for 600 s: the fixes after it are smoothed as if
    /// the drive began there (no velocity carried over the gap, none made
    /// up from it), and the car's 5 m/s is what the smoother reads on both
    /// sides.
    #[test]
    fn a_gap_of_minutes_splits_the_smoother() {
        let before = fixes(0.0, 0.0, 300, 5.0);
        let after = fixes(660.0, -150.0, 300, 5.0);
        let all: Vec<RefFix> = before.iter().chain(&after).copied().collect();
        let z: Vec<[f64; 2]> = all.iter().map(|f| [f.x, f.y]).collect();
        let whole = smooth_positions(&all, &z, 1.0, 5.0, None, None).unwrap();
        let za: Vec<[f64; 2]> = after.iter().map(|f| [f.x, f.y]).collect();
        let alone = smooth_positions(&after, &za, 1.0, 5.0, None, None).unwrap();
        assert_eq!(&whole.s[300..], &alone.s[..]);
        for s in &whole.s {
            assert!((s[2] - 5.0).abs() < 0.3 && s[3].abs() < 0.3, "{s:?}");
        }
    }
}
