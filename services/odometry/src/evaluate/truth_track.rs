//! The truth track: its position, arc length and yaw at any time
//! (interpolated, not across long gaps), its dead-banded arc length, its
//! course from a cubic fit, and the check that its yaw is the vehicle's.

use interfaces::drive::TruthSample;
use nalgebra::{Matrix4, Vector4};
use stats::percentile;
use vehicle_model::two_wheel::wrap_angle;

/// Track movement below this does not add to the arc length, m.
pub const ARC_DEADBAND_M: f64 = 0.25;

/// A truth yaw further than this from the course of the truth's own
/// positions on straight stretches (median) is not used, rad.
pub const TRUTH_YAW_OFFSET_LIMIT_RAD: f64 = 0.005;
/// Length of a stretch of truth track for the yaw check, m.
pub const YAW_CHECK_STRETCH_M: f64 = 10.0;
/// A stretch is straight when the truth yaw moves less than this along it, rad.
pub const YAW_CHECK_STRAIGHT_RAD: f64 = 0.005;
/// Straight stretches needed before the truth yaw is judged.
pub const YAW_CHECK_MIN_STRETCHES: usize = 5;

/// The truth track with its dead-banded arc length.
pub(super) struct TruthTrack<'a> {
    pub(super) rows: &'a [TruthSample],
    pub(super) arc_m: Vec<f64>,
    max_gap_s: f64,
    /// Whether `yaw_at` gives the truth's yaw (false: it is not the vehicle's).
    pub(super) use_yaw: bool,
}

impl<'a> TruthTrack<'a> {
    /// The track of `rows`, interpolated across gaps up to `max_gap_s`.
    pub(super) fn new(rows: &'a [TruthSample], max_gap_s: f64) -> TruthTrack<'a> {
        TruthTrack {
            rows,
            arc_m: dead_banded_arc_length(rows),
            max_gap_s,
            use_yaw: true,
        }
    }

    /// Index `i` with `rows[i].t <= t <= rows[i+1].t`, when the gap there is
    /// small enough.
    fn bracket(&self, t_s: f64) -> Option<(usize, f64)> {
        let n = self.rows.len();
        if n == 0 || t_s < self.rows[0].t_s || t_s > self.rows[n - 1].t_s {
            return None;
        }
        if n == 1 {
            return Some((0, 0.0));
        }
        let i = self.rows.partition_point(|r| r.t_s <= t_s).clamp(1, n - 1) - 1;
        let (a, b) = (&self.rows[i], &self.rows[i + 1]);
        let gap = b.t_s - a.t_s;
        if gap > self.max_gap_s {
            return None;
        }
        Some((i, ((t_s - a.t_s) / gap).clamp(0.0, 1.0)))
    }

    /// Position at `t_s`, interpolated.
    pub(super) fn position_at(&self, t_s: f64) -> Option<[f64; 2]> {
        let (i, f) = self.bracket(t_s)?;
        let a = &self.rows[i];
        let Some(b) = self.rows.get(i + 1) else {
            return Some([a.x_m, a.y_m]);
        };
        Some([a.x_m + f * (b.x_m - a.x_m), a.y_m + f * (b.y_m - a.y_m)])
    }

    /// Arc length at `t_s`, interpolated.
    pub(super) fn arc_at(&self, t_s: f64) -> Option<f64> {
        let (i, f) = self.bracket(t_s)?;
        let a = self.arc_m[i];
        Some(self.arc_m.get(i + 1).map_or(a, |b| a + f * (b - a)))
    }

    /// The truth's yaw at `t_s` (the shortest way round), unless it has none
    /// or it is not the vehicle's.
    pub(super) fn yaw_at(&self, t_s: f64) -> Option<f64> {
        if !self.use_yaw {
            return None;
        }
        let (i, f) = self.bracket(t_s)?;
        let a = self.rows[i].yaw_rad?;
        let Some(b) = self.rows.get(i + 1) else {
            return Some(a);
        };
        let b = b.yaw_rad?;
        Some(wrap_angle(a + f * wrap_angle(b - a)))
    }
}

/// The truth's yaw minus the course of its own positions, rad: the median
/// over non-overlapping straight stretches of [`YAW_CHECK_STRETCH_M`] of
/// track (straight: the yaw moves less than [`YAW_CHECK_STRAIGHT_RAD`] along
/// it; no gap longer than `max_gap_s`), with the number of stretches. On a
/// straight stretch every body point moves along the vehicle's yaw, so a
/// yaw that is the vehicle's gives about 0. `None` with fewer than
/// [`YAW_CHECK_MIN_STRETCHES`] stretches (or no yaw).
pub fn truth_yaw_offset(rows: &[TruthSample], max_gap_s: f64) -> Option<(f64, usize)> {
    let arc = dead_banded_arc_length(rows);
    let mut offsets = Vec::new();
    let mut i = 0;
    while i < rows.len() {
        let Some(yaw_i) = rows[i].yaw_rad else {
            i += 1;
            continue;
        };
        let Some(j) = (i + 1..rows.len()).find(|&j| arc[j] - arc[i] >= YAW_CHECK_STRETCH_M) else {
            break;
        };
        let straight = rows[i..=j].windows(2).all(|w| {
            w[1].t_s - w[0].t_s <= max_gap_s
                && w[1]
                    .yaw_rad
                    .is_some_and(|y| wrap_angle(y - yaw_i).abs() < YAW_CHECK_STRAIGHT_RAD)
        });
        if !straight {
            i += 1;
            continue;
        }
        let (a, b) = (&rows[i], &rows[j]);
        let course = (b.y_m - a.y_m).atan2(b.x_m - a.x_m);
        let yaw_j = b.yaw_rad.unwrap_or(yaw_i);
        let yaw = yaw_i + 0.5 * wrap_angle(yaw_j - yaw_i);
        offsets.push(wrap_angle(yaw - course));
        i = j;
    }
    if offsets.len() < YAW_CHECK_MIN_STRETCHES {
        return None;
    }
    Some((percentile(&offsets, 0.5)?, offsets.len()))
}

/// Arc length of a track, counting a move only once it is more than
/// [`ARC_DEADBAND_M`] from the last counted point.
pub(super) fn dead_banded_arc_length(rows: &[TruthSample]) -> Vec<f64> {
    let mut out = Vec::with_capacity(rows.len());
    let mut anchor: Option<(f64, f64)> = None;
    let mut s = 0.0;
    for r in rows {
        match anchor {
            None => anchor = Some((r.x_m, r.y_m)),
            Some((ax, ay)) => {
                let d = (r.x_m - ax).hypot(r.y_m - ay);
                if d > ARC_DEADBAND_M {
                    s += d;
                    anchor = Some((r.x_m, r.y_m));
                }
            }
        }
        out.push(s);
    }
    out
}

/// The course of a track at arc length `s0_m` (see the module docs): a
/// least-squares cubic fit of x and y against arc length over
/// `s0_m +- half_window_m`, using only the points where the dead-banded arc
/// length grew (and the first), so that GNSS jitter while standing does not
/// weigh in. `None` when fewer than five points or less than
/// two metres of track lie in the window, or the fit is singular.
pub fn course_at(
    rows: &[TruthSample],
    arc_m: &[f64],
    s0_m: f64,
    half_window_m: f64,
) -> Option<f64> {
    let mut normal = Matrix4::<f64>::zeros();
    let mut rhs_x = Vector4::<f64>::zeros();
    let mut rhs_y = Vector4::<f64>::zeros();
    let (mut count, mut u_min, mut u_max) = (0usize, f64::INFINITY, f64::NEG_INFINITY);
    let mut previous_s = f64::NEG_INFINITY;
    for (r, &s) in rows.iter().zip(arc_m) {
        // Only the points that moved the arc length on (standing jitter skipped).
        if s <= previous_s {
            continue;
        }
        previous_s = s;
        let u = s - s0_m;
        if u.abs() > half_window_m {
            continue;
        }
        let basis = Vector4::new(1.0, u, u * u, u * u * u);
        normal += basis * basis.transpose();
        rhs_x += basis * r.x_m;
        rhs_y += basis * r.y_m;
        count += 1;
        u_min = u_min.min(u);
        u_max = u_max.max(u);
    }
    if count < 5 || u_max - u_min < 2.0 {
        return None;
    }
    let chol = normal.cholesky()?;
    let cx = chol.solve(&rhs_x);
    let cy = chol.solve(&rhs_y);
    let (dx, dy) = (cx[1], cy[1]);
    if !(dx.is_finite() && dy.is_finite()) || dx.hypot(dy) < 1e-6 {
        return None;
    }
    Some(dy.atan2(dx))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn course_fit_follows_a_circle() {
        // Truth on a circle of radius 15 m, counter-clockwise, points every 0.8 m.
        let r = 15.0;
        let rows: Vec<TruthSample> = (0..200)
            .map(|i| {
                let a = i as f64 * 0.8 / r;
                TruthSample {
                    t_s: i as f64,
                    x_m: r * a.sin(),
                    y_m: r * (1.0 - a.cos()),
                    yaw_rad: None,
                }
            })
            .collect();
        let arc = dead_banded_arc_length(&rows);
        let s0 = arc[50];
        let course = course_at(&rows, &arc, s0, 5.0).unwrap();
        let expected = 50.0 * 0.8 / r;
        // Arc length is measured along chords, so u is slightly off: a few mrad at most.
        assert!(
            (wrap_angle(course - expected)).abs() < 2e-3,
            "{course} vs {expected}"
        );
        assert!(course_at(&rows[..2], &arc[..2], 0.0, 5.0).is_none());
    }

    #[test]
    fn standing_jitter_does_not_add_distance() {
        let rows: Vec<TruthSample> = (0..100)
            .map(|i| TruthSample {
                t_s: i as f64,
                x_m: 0.02 * ((i % 3) as f64 - 1.0),
                y_m: 0.0,
                yaw_rad: None,
            })
            .collect();
        assert_eq!(dead_banded_arc_length(&rows).last(), Some(&0.0));
    }
}
