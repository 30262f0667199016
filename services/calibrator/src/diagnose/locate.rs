//! Where the model and the recording part ways: the 2W model (plain or with
//! effect terms) dead-reckoned over each block, laid onto the GNSS fixes by
//! the rigid motion that fits best (the block's start pose is unknown), and
//! the position error that is left; and what the car was doing there.

use super::epochs::{Epoch, Epochs};
use interfaces::drive::{GnssSample, WheelRevs};
use vehicle_model::effects::{EffectTerms, StepSignals};
use vehicle_model::two_wheel::{step, Pose2};

/// The 2W model of one evaluation: plain circumferences and track, effect
/// terms, and how the longitudinal-slip term reads the acceleration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Model {
    /// Rear-left circumference, m.
    pub c_rl: f64,
    /// Rear-right circumference, m.
    pub c_rr: f64,
    /// Nominal track, m.
    pub track_m: f64,
    /// Effect terms.
    pub terms: EffectTerms,
    /// Longitudinal slip acts on braking only (-1), driving only (+1) or both (0).
    pub slip_side: i8,
}

/// One block's dead-reckoned track laid onto its fixes.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockTrack {
    /// Fix positions (x, y), m.
    pub gnss: Vec<[f64; 2]>,
    /// Model positions at the fixes after the best rigid motion, m.
    pub model: Vec<[f64; 2]>,
    /// RMS distance between them, m.
    pub rms_m: f64,
}

/// The first epoch at or after `t` (what `partition_point` gives), found by
/// moving `cursor` on from where the previous call left it: a
/// dead-reckoning asks at increasing times, so this is O(1) a step.
fn epoch_index(epochs: &[Epoch], cursor: &mut usize, t: f64) -> usize {
    let mut i = (*cursor).min(epochs.len());
    if i > 0 && epochs[i - 1].t_s >= t {
        i = epochs.partition_point(|e| e.t_s < t);
    }
    while i < epochs.len() && epochs[i].t_s < t {
        i += 1;
    }
    *cursor = i;
    i
}

/// A signal of the epochs, interpolated linearly at `t` (the end value
/// outside, 0 where not finite); `i` is the first epoch at or after `t`
/// ([`epoch_index`]).
fn interp_at(epochs: &[Epoch], i: usize, t: f64, f: impl Fn(&Epoch) -> f64) -> f64 {
    if epochs.is_empty() {
        return 0.0;
    }
    let finite = |v: f64| if v.is_finite() { v } else { 0.0 };
    if i == 0 {
        return finite(f(&epochs[0]));
    }
    if i >= epochs.len() {
        return finite(f(&epochs[epochs.len() - 1]));
    }
    let (a, b) = (&epochs[i - 1], &epochs[i]);
    let u = if b.t_s > a.t_s {
        (t - a.t_s) / (b.t_s - a.t_s)
    } else {
        0.0
    };
    let (fa, fb) = (f(a), f(b));
    if fa.is_finite() && fb.is_finite() {
        fa + u * (fb - fa)
    } else {
        0.0
    }
}

/// Points in the plane (x east, y north), m.
pub type Points = Vec<[f64; 2]>;

/// The fixes of a span and the dead-reckoned model's antenna at each.
#[derive(Debug, Clone, PartialEq)]
pub struct DrPoints {
    /// Fix times, s.
    pub t: Vec<f64>,
    /// Fix positions, m.
    pub gnss: Points,
    /// The model's antenna at each fix (not aligned), m.
    pub model: Points,
}

/// Where the heading of a dead-reckoning comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeadingSource {
    /// The rear wheels' difference (the 2W model).
    Wheels,
    /// The integrated yaw-rate gyro (distance still from the wheels).
    Gyro,
}

/// What dead-reckoning reads: the wheels, the fixes, and the epochs (with
/// the accelerations, grade and gyro heading the effect terms read).
#[derive(Debug, Clone, Copy)]
pub struct Context<'a> {
    /// Wheel revolutions.
    pub revs: &'a [WheelRevs],
    /// GNSS fixes.
    pub gnss: &'a [GnssSample],
    /// The epochs.
    pub ep: &'a Epochs,
}

impl Context<'_> {
    fn gyro_heading(&self, t: f64) -> Option<f64> {
        super::epochs::interp(&self.ep.gyro_t, &self.ep.gyro_psi, t)
    }
}

/// How far beyond a block the wheels are dead-reckoned, s: more than any
/// plausible GNSS latency (the catalogue's range) and its finite-difference
/// step.
pub const DR_MARGIN_S: f64 = 1.0;

/// Dead-reckon `model` from a zero pose over the wheel samples in [t0, t1]
/// and give, for each fix in that span, the fix and the model's antenna
/// there (not aligned). `None` with fewer than three fixes.
pub fn dr_points(
    model: &Model,
    source: HeadingSource,
    cx: &Context<'_>,
    t0: f64,
    t1: f64,
) -> Option<DrPoints> {
    let revs = cx.revs;
    let t_start = revs.first()?.t_s;
    // The wheels are dead-reckoned a margin beyond the block on each side,
    // so that the fixes of the block are the same whatever the latency
    // (a fix at t is placed at t - tau): the position columns are finite
    // differences over the same fixes, and a latency that dropped the
    // block's first fix left its column empty on most blocks.
    let i0 = revs.partition_point(|r| r.t_s < t0 - DR_MARGIN_S);
    let i1 = revs.partition_point(|r| r.t_s <= t1 + DR_MARGIN_S);
    if i1 <= i0 + 1 {
        return None;
    }
    let tau = model.terms.gnss_latency_s;
    let fixes: Vec<&GnssSample> = cx
        .gnss
        .iter()
        .filter(|g| {
            g.t_s >= t0
                && g.t_s <= t1
                && g.t_s - tau >= revs[i0].t_s
                && g.t_s - tau <= revs[i1 - 1].t_s
        })
        .collect();
    if fixes.len() < 3 {
        return None;
    }
    let epochs = &cx.ep.epochs;
    let mut poses = Vec::with_capacity(i1 - i0);
    let mut pose = Pose2::default();
    poses.push((revs[i0].t_s, pose));
    // The gyro's heading is read only when it steers.
    let gyro_at = |t: f64| match source {
        HeadingSource::Gyro => cx.gyro_heading(t),
        HeadingSource::Wheels => None,
    };
    let mut last_gyro = gyro_at(revs[i0].t_s);
    let mut cursor = epochs.partition_point(|e| e.t_s < revs[i0].t_s);
    for k in i0 + 1..i1 {
        let (p, r) = (&revs[k - 1], &revs[k]);
        let dt = r.t_s - p.t_s;
        let (dn_l, dn_r) = (r.rl - p.rl, r.rr - p.rr);
        let gyro_now = gyro_at(r.t_s);
        if dt > 0.0 && dn_l.is_finite() && dn_r.is_finite() {
            let t_mid = 0.5 * (r.t_s + p.t_s);
            let i = epoch_index(epochs, &mut cursor, t_mid);
            let a_x = interp_at(epochs, i, t_mid, |e| e.a_x);
            let a_x = match model.slip_side {
                -1 => a_x.min(0.0),
                1 => a_x.max(0.0),
                _ => a_x,
            };
            let s = StepSignals {
                // Speed and lateral acceleration from the epochs: smooth over
                // the GNSS differencing interval, as the design's columns read
                // them (one wheel step's speed and v w swing with the
                // encoder's quantisation, and the terms are not linear in them).
                v_m_s: interp_at(epochs, i, t_mid, |e| e.v_odo),
                a_x_m_s2: a_x,
                a_y_m_s2: interp_at(epochs, i, t_mid, |e| e.a_y),
                grade: interp_at(epochs, i, t_mid, |e| e.grade),
                t_since_start_s: t_mid - t_start,
            };
            let (ds, dyaw_wheels, beta) =
                model
                    .terms
                    .increments(model.c_rl, model.c_rr, model.track_m, dn_l, dn_r, &s);
            let dyaw = match (source, last_gyro, gyro_now) {
                (HeadingSource::Gyro, Some(a), Some(b)) => {
                    (b - a - model.terms.gyro_bias_rad_s * dt) / (1.0 + model.terms.gyro_scale)
                }
                _ => dyaw_wheels,
            };
            pose = step(pose, ds, dyaw, beta);
        }
        last_gyro = gyro_now;
        poses.push((r.t_s, pose));
    }
    // The pose at the block's first wheel sample is the zero pose: what the
    // margin before it adds is for fixes placed before the block starts
    // only. (Starting the zero pose a margin earlier would turn and shift
    // the block's track by what a kicked model does in the margin; the
    // design projects out a block's rigid motion only to first order, and
    // a heading kick's turn over the margin left its square in the
    // columns: measured, the position channels' left/right nuisance moved
    // by 7 % on a multibody drive.)
    let k0 = poses
        .partition_point(|(tp, _)| *tp < t0)
        .min(poses.len() - 1);
    let origin = poses[k0].1;
    let (so, co) = (-origin.yaw).sin_cos();
    for (_, p) in poses.iter_mut() {
        let (dx, dy) = (p.x - origin.x, p.y - origin.y);
        *p = Pose2 {
            x: co * dx - so * dy,
            y: so * dx + co * dy,
            yaw: p.yaw - origin.yaw,
        };
    }
    let arm = model.terms.lever_arm_m;
    let mut model_pts = Vec::with_capacity(fixes.len());
    let mut gnss_pts = Vec::with_capacity(fixes.len());
    for g in &fixes {
        let t = g.t_s - tau;
        let j = poses
            .partition_point(|(tp, _)| *tp < t)
            .clamp(1, poses.len() - 1);
        let ((ta, pa), (tb, pb)) = (poses[j - 1], poses[j]);
        let u = if tb > ta { (t - ta) / (tb - ta) } else { 0.0 };
        let p = Pose2 {
            x: pa.x + u * (pb.x - pa.x),
            y: pa.y + u * (pb.y - pa.y),
            yaw: pa.yaw + u * (pb.yaw - pa.yaw),
        };
        model_pts.push(p.point_at(arm));
        gnss_pts.push([g.x_m, g.y_m]);
    }
    Some(DrPoints {
        t: fixes.iter().map(|g| g.t_s).collect(),
        gnss: gnss_pts,
        model: model_pts,
    })
}

/// Dead-reckon `model` (wheel heading) over [t0, t1] and lay the track onto
/// the fixes in that span.
pub fn block_track(model: &Model, cx: &Context<'_>, t0: f64, t1: f64) -> Option<BlockTrack> {
    let pts = dr_points(model, HeadingSource::Wheels, cx, t0, t1)?;
    let (aligned, rms) = align(&pts.model, &pts.gnss);
    Some(BlockTrack {
        gnss: pts.gnss,
        model: aligned,
        rms_m: rms,
    })
}

/// The rigid motion (rotation and translation) that lays `a` onto `b` best
/// in the least-squares sense (2D Procrustes), the moved `a` and the RMS.
pub fn align(a: &[[f64; 2]], b: &[[f64; 2]]) -> (Vec<[f64; 2]>, f64) {
    let (moved, rms, _) = align_with_angle(a, b);
    (moved, rms)
}

/// [`align`], also giving the rotation angle, rad.
pub fn align_with_angle(a: &[[f64; 2]], b: &[[f64; 2]]) -> (Vec<[f64; 2]>, f64, f64) {
    let n = a.len().min(b.len());
    let Some(m) = stats::rigid::fit(a.iter().zip(b).map(|(p, q)| (1.0, *p, *q))) else {
        return (Vec::new(), 0.0, 0.0);
    };
    let moved: Vec<[f64; 2]> = a.iter().take(n).map(|p| m.apply(*p)).collect();
    let ss: f64 = moved
        .iter()
        .zip(b)
        .map(|(p, q)| (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2))
        .sum();
    (moved, (ss / n as f64).sqrt(), m.angle)
}

/// What the car does over a span of epochs, in words: corner side or
/// straight, speed, the largest lateral and longitudinal acceleration.
pub fn manoeuvre(epochs: &[&Epoch]) -> String {
    if epochs.is_empty() {
        return "no GNSS".to_string();
    }
    let n = epochs.len() as f64;
    let still = epochs.iter().filter(|e| e.standstill).count() as f64 / n;
    if still > 0.8 {
        return "standstill".to_string();
    }
    let v = epochs.iter().map(|e| e.v_odo).sum::<f64>() / n;
    let turn: f64 = epochs.iter().map(|e| e.w_odo * e.dt_s).sum::<f64>()
        / epochs.iter().map(|e| e.dt_s).sum::<f64>().max(1e-9);
    let ay = epochs
        .iter()
        .map(|e| e.a_y)
        .fold(0.0f64, |m, a| if a.abs() > m.abs() { a } else { m });
    let ax = epochs
        .iter()
        .map(|e| e.a_x)
        .fold(0.0f64, |m, a| if a.abs() > m.abs() { a } else { m });
    let shape = if ay.abs() < 1.0 {
        "straight"
    } else if turn > 0.0 {
        "left corner"
    } else {
        "right corner"
    };
    let mut s = format!("{shape}, {v:.1} m/s, a_y {ay:.1} m/s^2");
    if ax.abs() >= 1.0 {
        let what = if ax > 0.0 { "accelerating" } else { "braking" };
        s.push_str(&format!(", {what} a_x {ax:.1} m/s^2"));
    }
    if still > 0.1 {
        s.push_str(&format!(", standing {:.0} % of the time", 100.0 * still));
    }
    let course = epochs[epochs.len() / 2].course_gnss.to_degrees();
    s.push_str(&format!(", heading {course:.0} deg"));
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_undoes_a_rigid_motion() {
        let a = [[0.0, 0.0], [1.0, 0.0], [2.0, 1.0], [3.0, 3.0]];
        let (s, c) = 0.3f64.sin_cos();
        let b: Vec<[f64; 2]> = a
            .iter()
            .map(|p| [5.0 + c * p[0] - s * p[1], -2.0 + s * p[0] + c * p[1]])
            .collect();
        let (moved, rms) = align(&a, &b);
        assert!(rms < 1e-12, "{rms}");
        assert!((moved[3][0] - b[3][0]).abs() < 1e-12);
    }
}
