//! The wheels' clock against the truth's: an outage scored on a wheel clock
//! that runs late or early against `truth.csv` measures the clock, not the
//! odometry. The speed the wheels give and the speed of the truth track are
//! compared over the whole drive at lags up to [`MAX_LAG_S`]; a lag that
//! explains the difference far beyond the noise (and is at least
//! [`MIN_LAG_S`]) is taken out of the wheels' time stamps before the scoring,
//! with a warning.

use super::truth_track::TruthTrack;
use interfaces::drive::WheelRevs;

/// Lags searched either side, s.
pub const MAX_LAG_S: f64 = 3.0;
/// Step of the lag search, s.
pub const LAG_STEP_S: f64 = 0.01;
/// Smaller lags are left alone: GNSS latency and the truth's own filtering
/// make tens of milliseconds that no clock causes.
pub const MIN_LAG_S: f64 = 0.1;
/// Grid of the speed comparison, s.
const GRID_S: f64 = 0.1;
/// Window of each speed, s (the grid's samples overlap: the effective
/// number of independent ones is the count times GRID_S / WINDOW_S).
const WINDOW_S: f64 = 1.0;
/// How far the best lag must lower the misfit, in chi-square units of the
/// independent samples, before it counts (5 sigma).
const MIN_IMPROVEMENT: f64 = 25.0;

/// Rear-axle revolutions (mean of the two wheels) at `t_s`, interpolated.
fn mean_revs_at(revs: &[WheelRevs], t_s: f64) -> Option<f64> {
    let n = revs.len();
    if n < 2 || !(t_s >= revs[0].t_s && t_s <= revs[n - 1].t_s) {
        return None;
    }
    let i = revs.partition_point(|r| r.t_s <= t_s).clamp(1, n - 1) - 1;
    let (a, b) = (&revs[i], &revs[i + 1]);
    let f = if b.t_s > a.t_s {
        (t_s - a.t_s) / (b.t_s - a.t_s)
    } else {
        0.0
    };
    let v = 0.5 * (a.rl + a.rr) + f * 0.5 * ((b.rl + b.rr) - (a.rl + a.rr));
    v.is_finite().then_some(v)
}

/// The wheels' lag against the truth (`t_wheels = t_truth + lag`), s, when
/// it is significant and at least [`MIN_LAG_S`]; `circumference_m` turns
/// revolutions into metres.
pub(super) fn wheel_clock_lag(
    revs: &[WheelRevs],
    truth: &TruthTrack<'_>,
    circumference_m: f64,
    from_s: f64,
    to_s: f64,
) -> Option<f64> {
    let half = 0.5 * WINDOW_S;
    let truth_speed = |t: f64| Some((truth.arc_at(t + half)? - truth.arc_at(t - half)?) / WINDOW_S);
    let wheel_speed = |t: f64| {
        Some(
            circumference_m * (mean_revs_at(revs, t + half)? - mean_revs_at(revs, t - half)?)
                / WINDOW_S,
        )
    };
    // Wheel speeds on the grid (wheel clock), with the truth's at every lag.
    let steps = ((to_s - from_s - 2.0 * MAX_LAG_S - WINDOW_S) / GRID_S).floor();
    if steps.is_nan() || steps < 100.0 {
        return None;
    }
    let grid: Vec<(f64, f64)> = (0..steps as usize)
        .filter_map(|k| {
            let t = from_s + MAX_LAG_S + half + k as f64 * GRID_S;
            wheel_speed(t).map(|v| (t, v))
        })
        .collect();
    let misfit = |lag: f64| -> Option<(f64, usize)> {
        let (mut sse, mut n) = (0.0, 0usize);
        for &(t, v) in &grid {
            if let Some(vt) = truth_speed(t - lag) {
                sse += (v - vt) * (v - vt);
                n += 1;
            }
        }
        (n >= 100).then_some((sse, n))
    };
    let (sse0, n0) = misfit(0.0)?;
    let lags = (2.0 * MAX_LAG_S / LAG_STEP_S).round() as i64;
    let (best_lag, best_sse, n) = (-lags / 2..=lags / 2)
        .filter_map(|k| {
            let lag = k as f64 * LAG_STEP_S;
            misfit(lag).map(|(sse, n)| (lag, sse * n0 as f64 / n as f64, n))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let variance = best_sse / (n as f64 - 1.0);
    if variance.is_nan() || variance <= 0.0 {
        return None;
    }
    let independent = GRID_S / WINDOW_S;
    let improvement = (sse0 - best_sse) / variance * independent;
    (best_lag.abs() >= MIN_LAG_S && improvement > MIN_IMPROVEMENT).then_some(best_lag)
}
