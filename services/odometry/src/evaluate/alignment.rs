//! The start pose of an outage from the truth track (see the module docs
//! of `evaluate`): the dead-reckoned track of a window before (or, at a
//! drive's start, after) the start laid onto the truth of the same stretch.

use super::config::EvaluateConfig;
use super::dead_reckon::{dead_reckon_span, track_position_at, Snapshot};
use super::truth_track::TruthTrack;
use crate::inputs::Input;
use interfaces::drive::WheelRevs;
use stats::percentile;
use vehicle_model::two_wheel::{wrap_angle, Pose2};

/// The alignment window `(ta, tb)` for an outage starting at `t0`: the last
/// `align_distance_m` of truth track before `t0` (`tb = t0`), or, when the
/// vehicle has not driven that far before `t0` (a drive's start), the first
/// `align_distance_m` after it (`ta = t0`); within `align_max_s` and without
/// truth gaps longer than `max_truth_gap_s`.
pub(super) fn alignment_window(
    truth: &TruthTrack<'_>,
    config: &EvaluateConfig,
    t0: f64,
    s0: f64,
) -> Option<(f64, f64)> {
    let rows = truth.rows;
    let no_gap = |from: usize, to: usize| {
        rows[from..=to]
            .windows(2)
            .all(|w| w[1].t_s - w[0].t_s <= config.max_truth_gap_s)
    };
    let first = rows.partition_point(|r| r.t_s < t0 - config.align_max_s);
    let after_t0 = rows.partition_point(|r| r.t_s <= t0);
    if let Some(i) = (first..after_t0)
        .rev()
        .find(|&i| s0 - truth.arc_m[i] >= config.align_distance_m)
    {
        return (after_t0 > 0 && no_gap(i, after_t0.min(rows.len() - 1)))
            .then_some((rows[i].t_s, t0));
    }
    let last = rows.partition_point(|r| r.t_s <= t0 + config.align_max_s);
    let j = (after_t0..last).find(|&j| truth.arc_m[j] - s0 >= config.align_distance_m)?;
    (after_t0 > 0 && no_gap(after_t0 - 1, j)).then_some((t0, rows[j].t_s))
}

/// The start pose (truth-point position and yaw at `t0`) that best lays the
/// dead-reckoned track from `ta` to `tb` onto the truth of the same stretch
/// (see the module docs). 2-D Procrustes, refitted once without the truth
/// points more than three times the median residual (and 0.1 m) off.
#[allow(clippy::too_many_arguments)]
pub(super) fn aligned_start(
    truth: &TruthTrack<'_>,
    revs: &[WheelRevs],
    inputs: &[Input],
    from: &Snapshot,
    arm: [f64; 2],
    ta: f64,
    tb: f64,
    t0: f64,
) -> Option<([f64; 2], f64)> {
    let span = dead_reckon_span(revs, inputs, from, Pose2::default(), ta, tb).ok()?;
    let first = truth.rows.partition_point(|r| r.t_s < ta);
    let mut pairs = Vec::new();
    for r in truth.rows[first..].iter().take_while(|r| r.t_s <= tb) {
        if let Some(d) = track_position_at(&span.track, r.t_s, arm) {
            pairs.push((d, [r.x_m, r.y_m]));
        }
    }
    let mut motion = procrustes(&pairs)?;
    let residuals: Vec<f64> = pairs
        .iter()
        .map(|(d, g)| {
            let p = motion.apply(*d);
            (p[0] - g[0]).hypot(p[1] - g[1])
        })
        .collect();
    let limit = (3.0 * percentile(&residuals, 0.5)?).max(0.1);
    let kept: Vec<_> = pairs
        .iter()
        .zip(&residuals)
        .filter(|(_, r)| **r <= limit)
        .map(|(p, _)| *p)
        .collect();
    if kept.len() < pairs.len() {
        motion = procrustes(&kept)?;
    }
    let (t_end, end) = if t0 == ta {
        span.track.first()?
    } else {
        span.track.last()?
    };
    debug_assert!(*t_end == t0);
    let position = motion.apply(end.point_at(arm));
    let rotation = motion.angle;
    Some((position, wrap_angle(end.yaw + rotation)))
}

/// The rigid motion laying points `d` onto points `g` (least squares);
/// `None` for fewer than three pairs or a track that did not move (under
/// 1 m^2 of spread in all).
fn procrustes(pairs: &[([f64; 2], [f64; 2])]) -> Option<stats::rigid::Rigid2> {
    if pairs.len() < 3 {
        return None;
    }
    let m = stats::rigid::fit(pairs.iter().map(|(d, g)| (1.0, *d, *g)))?;
    (m.spread_m2 * pairs.len() as f64 >= 1.0).then_some(m)
}
