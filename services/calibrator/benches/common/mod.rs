//! Scoring helpers shared by the benchmarks and examples (not part of the library).

#![allow(dead_code)]

use interfaces::drive::{Drive, TruthSample};
use vehicle_model::two_wheel::{dead_reckon, Pose2, TwoWheelParams};

/// Truth position (and yaw) at `t`, interpolated linearly.
pub fn truth_at(truth: &[TruthSample], t: f64) -> Option<(f64, f64, Option<f64>)> {
    let n = truth.len();
    if n < 2 || t < truth[0].t_s || t > truth[n - 1].t_s {
        return None;
    }
    let i = truth.partition_point(|s| s.t_s <= t).clamp(1, n - 1);
    let (a, b) = (truth[i - 1], truth[i]);
    let f = if b.t_s > a.t_s {
        (t - a.t_s) / (b.t_s - a.t_s)
    } else {
        0.0
    };
    let yaw = match (a.yaw_rad, b.yaw_rad) {
        (Some(ya), Some(yb)) => Some(ya + f * vehicle_model::two_wheel::wrap_angle(yb - ya)),
        _ => None,
    };
    Some((
        a.x_m + f * (b.x_m - a.x_m),
        a.y_m + f * (b.y_m - a.y_m),
        yaw,
    ))
}

/// Mean and max distance between the pure 2W dead-reckoning with `params`
/// (started from the true pose at the first wheel sample) and the truth,
/// over the whole drive.
pub fn dr_error_vs_truth(drive: &Drive, params: &TwoWheelParams) -> Option<(f64, f64)> {
    let truth = drive.truth.as_ref()?;
    let revs = drive.wheel_revolutions().ok()?;
    let first = revs
        .iter()
        .position(|r| truth_at(truth, r.t_s).and_then(|t| t.2).is_some())?;
    let (x, y, yaw) = truth_at(truth, revs[first].t_s)?;
    let track = dead_reckon(Pose2 { x, y, yaw: yaw? }, &revs[first..], params);
    let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0usize);
    for (r, p) in revs[first..].iter().zip(&track) {
        if let Some((tx, ty, _)) = truth_at(truth, r.t_s) {
            let d = (p.x - tx).hypot(p.y - ty);
            sum += d;
            max = max.max(d);
            n += 1;
        }
    }
    (n > 0).then(|| (sum / n as f64, max))
}

/// Truth path length over the wheel distance with `params`: the factor that
/// turns the static circumferences into the effective ones (driven-axle
/// slip and the like make the wheels turn a little more than they roll).
pub fn effective_scale(drive: &Drive, params: &TwoWheelParams) -> Option<f64> {
    let truth = drive.truth.as_ref()?;
    let revs = drive.wheel_revolutions().ok()?;
    let (first, last) = (revs.first()?, revs.last()?);
    let mut len = 0.0;
    for w in truth.windows(2) {
        if w[0].t_s >= first.t_s && w[1].t_s <= last.t_s {
            len += (w[1].x_m - w[0].x_m).hypot(w[1].y_m - w[0].y_m);
        }
    }
    let dist = 0.5 * ((last.rl - first.rl) * params.c_rl + (last.rr - first.rr) * params.c_rr);
    (dist > 0.0).then(|| len / dist)
}

/// Peak resident memory of this process so far (VmHWM), MB.
pub fn peak_memory_mb() -> Option<f64> {
    status_mb("VmHWM:")
}

/// Resident memory of this process now (VmRSS), MB.
pub fn resident_memory_mb() -> Option<f64> {
    status_mb("VmRSS:")
}

fn status_mb(key: &str) -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with(key))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}
