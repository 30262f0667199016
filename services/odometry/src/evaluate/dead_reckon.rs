//! The odometer through the drive, as the service runs it: copied at the
//! instants an outage or an alignment starts, and dead-reckoning from such a
//! copy on the wheels (and gyro) alone.

use crate::dead_reckoning::{DeadReckoner, HeadingMode, InputError, OdometerConfig};
use crate::inputs::Input;
use interfaces::drive::WheelRevs;
use vehicle_model::estimate::OdometryParams;
use vehicle_model::two_wheel::Pose2;

/// Rear-wheel revolutions interpolated linearly at `t_s` (inside the series).
fn revs_at(revs: &[WheelRevs], t_s: f64) -> Option<(f64, f64)> {
    let n = revs.len();
    if n == 0 || t_s < revs[0].t_s || t_s > revs[n - 1].t_s {
        return None;
    }
    if n == 1 {
        return Some((revs[0].rl, revs[0].rr));
    }
    let i = revs.partition_point(|r| r.t_s <= t_s).clamp(1, n - 1) - 1;
    let (a, b) = (&revs[i], &revs[i + 1]);
    let f = ((t_s - a.t_s) / (b.t_s - a.t_s)).clamp(0.0, 1.0);
    Some((a.rl + f * (b.rl - a.rl), a.rr + f * (b.rr - a.rr)))
}

/// The odometer as it was at one instant: fed every input before it, and the
/// wheel revolutions interpolated at the instant itself.
#[derive(Debug, Clone)]
pub(super) struct Snapshot {
    dr: DeadReckoner,
    /// Index of the first input after the instant.
    next: usize,
}

/// Run one odometer through the inputs and copy it at each of `times`
/// (sorted). Returns the copies and the number of inputs it had to skip.
pub(super) fn snapshots(
    revs: &[WheelRevs],
    inputs: &[Input],
    params: &OdometryParams,
    odometer: OdometerConfig,
    effects: vehicle_model::effects::EffectTerms,
    times: &[f64],
) -> (Vec<Result<Snapshot, String>>, usize) {
    let mut background = DeadReckoner::new(*params, odometer, Pose2::default());
    background.set_effects(effects);
    let mut skipped = 0usize;
    let mut i = 0usize;
    let mut out = Vec::with_capacity(times.len());
    for &t in times {
        // Everything strictly before t, and the IMU at t (wheels come last at a time).
        while let Some(input) = inputs.get(i) {
            let ti = input.t_s();
            if ti > t || (ti == t && matches!(input, Input::Wheels { .. })) {
                break;
            }
            if feed(&mut background, input, odometer.heading).is_err() {
                skipped += 1;
            }
            i += 1;
        }
        let mut dr = background.clone();
        let result = match revs_at(revs, t) {
            Some((rl, rr)) => dr.wheels(t, rl, rr).map_err(|e| e.to_string()).map(|_| {
                // Skip a wheel sample exactly at t: the copy has it already.
                let next = i + inputs[i..].partition_point(|x| x.t_s() <= t);
                Snapshot { dr, next }
            }),
            None => Err(format!("no wheel data at {t} s")),
        };
        out.push(result);
    }
    (out, skipped)
}

/// Feed one input to a dead-reckoner (GNSS, heading and estimates are not its business).
fn feed(dr: &mut DeadReckoner, input: &Input, heading: HeadingMode) -> Result<(), InputError> {
    match *input {
        Input::Imu { t_s, gz_rad_s } if heading == HeadingMode::Gyro => dr.gyro(t_s, gz_rad_s),
        Input::Wheels {
            t_s,
            rl_rev,
            rr_rev,
        } => dr.wheels(t_s, rl_rev, rr_rev).map(|_| ()),
        _ => Ok(()),
    }
}

/// Dead-reckoning from a snapshot at `t0` to `t1`, starting at `pose0`.
pub(super) struct Span {
    /// Pose at every wheel sample (the ends included), with its time.
    pub(super) track: Vec<(f64, Pose2)>,
    /// Input samples skipped as unusable.
    pub(super) skipped: usize,
    /// Increments in the span that fell back to the wheel difference in gyro mode.
    pub(super) gyro_fallbacks: u64,
    /// Gyro bias at the start, rad/s.
    pub(super) gyro_bias_rad_s: f64,
    /// Standstill bias measurements by the end.
    pub(super) gyro_bias_standstills: u64,
}

/// Dead-reckon from the snapshot `start` (at `t0`), put at `pose0`, to `t1`.
pub(super) fn dead_reckon_span(
    revs: &[WheelRevs],
    inputs: &[Input],
    start: &Snapshot,
    pose0: Pose2,
    t0: f64,
    t1: f64,
) -> Result<Span, String> {
    let wheels_end = revs_at(revs, t1).ok_or("no wheel data at the end")?;
    let mut dr = start.dr.clone();
    dr.set_pose(pose0);
    let heading = dr.odometer().config().heading;
    let fallbacks_before = dr.odometer().stats().gyro_fallbacks;
    let gyro_bias_rad_s = dr.odometer().gyro_bias();
    let mut track = vec![(t0, pose0)];
    let mut skipped = 0usize;
    for input in &inputs[start.next.min(inputs.len())..] {
        let t = input.t_s();
        if t > t1 || (t == t1 && matches!(input, Input::Wheels { .. })) {
            break;
        }
        if feed(&mut dr, input, heading).is_err() {
            skipped += 1;
        } else if matches!(input, Input::Wheels { .. }) {
            track.push((t, dr.pose()));
        }
    }
    let pose = dr
        .wheels(t1, wheels_end.0, wheels_end.1)
        .map_err(|e| e.to_string())?;
    track.push((t1, pose));
    Ok(Span {
        track,
        skipped,
        gyro_fallbacks: dr.odometer().stats().gyro_fallbacks - fallbacks_before,
        gyro_bias_rad_s,
        gyro_bias_standstills: dr.odometer().stats().gyro_bias_updates,
    })
}

/// Position of a dead-reckoned track at `t_s`, interpolated linearly.
pub(super) fn track_position_at(
    track: &[(f64, Pose2)],
    t_s: f64,
    arm: [f64; 2],
) -> Option<[f64; 2]> {
    let n = track.len();
    if n == 0 || t_s < track[0].0 || t_s > track[n - 1].0 {
        return None;
    }
    if n == 1 {
        return Some(track[0].1.point_at(arm));
    }
    let i = track.partition_point(|(t, _)| *t <= t_s).clamp(1, n - 1) - 1;
    let ((ta, a), (tb, b)) = (track[i], track[i + 1]);
    let (a, b) = (a.point_at(arm), b.point_at(arm));
    let f = if tb > ta { (t_s - ta) / (tb - ta) } else { 0.0 };
    Some([a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])])
}
