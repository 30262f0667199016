//! The outages: where they go, and one outage from its start pose to its
//! score at the end.

use super::alignment::alignment_window;
use super::config::EvaluateConfig;
use super::dead_reckon::{dead_reckon_span, track_position_at, Snapshot};
use super::report::{OutageResult, TrackPoint};
use super::truth_track::{course_at, TruthTrack};
use crate::inputs::Input;
use interfaces::drive::WheelRevs;
use vehicle_model::two_wheel::Pose2;

/// An outage placed: its start and end, s, and the window `(ta, tb)` its
/// start pose is aligned on (see `alignment_window`), if there is one.
pub(super) type PlacedOutage = (f64, f64, Option<(f64, f64)>);

/// The outages of an evaluation: one every `spacing_s` from `t_from` as
/// long as it ends by `t_to`, with an alignment window where the truth has
/// no yaw at the start.
pub(super) fn place_outages(
    truth: &TruthTrack<'_>,
    config: &EvaluateConfig,
    t_from: f64,
    t_to: f64,
) -> Vec<PlacedOutage> {
    let mut windows = Vec::new();
    for k in 0u32.. {
        let t0 = t_from + f64::from(k) * config.spacing_s;
        let t1 = t0 + config.outage_s;
        if t1 > t_to + 1e-9 {
            break;
        }
        let align = if truth.yaw_at(t0).is_some() {
            None
        } else {
            truth
                .arc_at(t0)
                .and_then(|s0| alignment_window(truth, config, t0, s0))
        };
        windows.push((t0, t1, align));
    }
    windows
}

/// One outage from `t0` to `t1`, or why it cannot be scored.
#[allow(clippy::too_many_arguments)]
pub(super) fn run_outage(
    truth: &TruthTrack<'_>,
    revs: &[WheelRevs],
    inputs: &[Input],
    config: &EvaluateConfig,
    start_state: &Snapshot,
    aligned: Option<([f64; 2], f64)>,
    t0: f64,
    t1: f64,
) -> Result<OutageResult, String> {
    let start = truth
        .position_at(t0)
        .ok_or("no truth around the start (gap longer than max_truth_gap_s)")?;
    let end = truth
        .position_at(t1)
        .ok_or("no truth around the end (gap longer than max_truth_gap_s)")?;
    let (s0, s1) = match (truth.arc_at(t0), truth.arc_at(t1)) {
        (Some(a), Some(b)) => (a, b),
        _ => return Err("no truth arc length".into()),
    };
    let (start, yaw, yaw_source) = start_pose(truth, config, aligned, start, t0, s0)?;
    // The rear-axle pose whose truth point is at the truth.
    let arm = Pose2 {
        x: 0.0,
        y: 0.0,
        yaw,
    }
    .point_at(config.truth_point.point_m);
    let pose0 = Pose2 {
        x: start[0] - arm[0],
        y: start[1] - arm[1],
        yaw,
    };
    let span = dead_reckon_span(revs, inputs, start_state, pose0, t0, t1)?;
    if span.skipped > 0 {
        return Err(format!(
            "{} wheel or IMU samples inside it are unusable",
            span.skipped
        ));
    }
    let pose = span
        .track
        .last()
        .map(|(_, p)| *p)
        .ok_or("empty dead-reckoning")?;
    let end_point = pose.point_at(config.truth_point.point_m);
    let track = if config.keep_tracks {
        kept_track(truth, &span.track, config.truth_point.point_m, t0, t1)
    } else {
        Vec::new()
    };
    let error_m = (end_point[0] - end[0]).hypot(end_point[1] - end[1]);
    let distance_m = s1 - s0;
    Ok(OutageResult {
        t_start_s: t0,
        length_s: t1 - t0,
        distance_m,
        error_m,
        error_pct: (distance_m >= config.min_distance_for_pct_m)
            .then(|| 100.0 * error_m / distance_m),
        start_yaw_rad: yaw,
        start_yaw_source: yaw_source,
        end_m: end_point,
        truth_end_m: end,
        gyro_fallbacks: span.gyro_fallbacks,
        gyro_bias_rad_s: span.gyro_bias_rad_s,
        gyro_bias_standstills: span.gyro_bias_standstills,
        track,
    })
}

/// Where an outage at `t0` (truth arc length `s0`) starts: the truth
/// position (`start`) with the truth's yaw; else the pose aligned on the
/// truth track (`aligned`); else the truth position with the course of
/// the truth track. Returns the position, the yaw and where the yaw came
/// from.
fn start_pose(
    truth: &TruthTrack<'_>,
    config: &EvaluateConfig,
    aligned: Option<([f64; 2], f64)>,
    start: [f64; 2],
    t0: f64,
    s0: f64,
) -> Result<([f64; 2], f64, &'static str), String> {
    if let Some(y) = truth.yaw_at(t0) {
        return Ok((start, y, "truth_yaw"));
    }
    if let Some((position, y)) = aligned {
        let after = truth.arc_at(t0).is_some_and(|s0| {
            alignment_window(truth, config, t0, s0).is_some_and(|(ta, _)| ta == t0)
        });
        let source = if after {
            "truth_track_alignment_after"
        } else {
            "truth_track_alignment"
        };
        return Ok((position, y, source));
    }
    // Widen the window where the truth is sparse (e.g. at a drive's start).
    let course = [1.0, 2.0, 4.0]
        .iter()
        .find_map(|k| {
            course_at(
                truth.rows,
                &truth.arc_m,
                s0,
                k * config.course_half_window_m,
            )
        })
        .ok_or("the truth track does not move enough around the start to give a course")?;
    Ok((start, course, "truth_course"))
}

/// The dead-reckoned `track` (at body point `point_m`) beside the truth at
/// every truth row from `t0` to `t1`.
fn kept_track(
    truth: &TruthTrack<'_>,
    track: &[(f64, Pose2)],
    point_m: [f64; 2],
    t0: f64,
    t1: f64,
) -> Vec<TrackPoint> {
    let first = truth.rows.partition_point(|r| r.t_s < t0);
    truth.rows[first..]
        .iter()
        .take_while(|r| r.t_s <= t1)
        .filter_map(|r| {
            track_position_at(track, r.t_s, point_m).map(|d| TrackPoint {
                t_s: r.t_s,
                dead_reckoned_m: d,
                truth_m: [r.x_m, r.y_m],
            })
        })
        .collect()
}
