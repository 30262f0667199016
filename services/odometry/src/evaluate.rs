//! Offline evaluation: dead-reckoning through simulated GNSS outages.
//!
//! Outages of a given length start every `spacing_s` (10 s) from the first
//! instant covered by both wheels and `truth.csv`, as long as they end inside
//! that coverage. At each outage start the pose is taken from the truth;
//! `start_yaw_source` in the report says which rule applied:
//! - `truth_yaw`: `truth.csv` has `yaw_rad` around the start: position and
//!   yaw interpolated (yaw the shortest way round). Unless that yaw is not
//!   the vehicle's: on straight stretches the course of the truth positions
//!   is the vehicle's yaw, and where `yaw_rad` is off it by more than
//!   [`TRUTH_YAW_OFFSET_LIMIT_RAD`] (median over the straight stretches, see
//!   [`truth_yaw_offset`]), a warning says so and the truth's yaw is not
//!   used (the rules below apply). comma2k19's truth, for one, is the pose of
//!   the windscreen-mounted device, 15 mrad off the car's course;
//! - `truth_track_alignment` (truth without yaw, the usual case of a GNSS
//!   truth): the dead-reckoned track of the last `align_distance_m` (30 m) of
//!   driving before the start is laid onto the truth positions of the same
//!   stretch by the rotation and translation that fit best (2-D Procrustes,
//!   refitted once without truth points more than three times the median
//!   residual off); the start pose is the laid track's pose at the start.
//!   This is what a filter fusing GNSS with this odometry knows when the GNSS
//!   drops out: it uses only data from before the outage, and it averages the
//!   truth's own noise over a long baseline. On the WID drives the RTK truth
//!   jumps by decimetres now and then, and a course from a few truth points is
//!   off by several hundredths of a radian: metres after 30 s;
//! - `truth_track_alignment_after`: the same on the first 30 m after the
//!   start, when the vehicle has not driven 30 m before it (the start of a
//!   drive: it stands, so its heading is the heading it departs with);
//! - `truth_course` (neither window within `align_max_s`): position
//!   interpolated, yaw the course of the truth track at the start, see
//!   [`course_at`]: a least-squares cubic fit x(u), y(u) of the truth
//!   positions against their arc length u within `course_half_window_m`
//!   either side of the start point, yaw = atan2(y'(0), x'(0)), fitted only on
//!   the points where the arc length grew; the window is doubled, up to four
//!   times, where it holds too few points. A cubic, not a quadratic: with the
//!   curvature changing along the window, a quadratic's slope is biased by a
//!   few mrad.
//!
//! The arc length of the truth track grows only when the track has moved more
//! than [`ARC_DEADBAND_M`] from its last counted point, so GNSS jitter while
//! standing adds nothing.
//!
//! The odometer (the same [`DeadReckoner`] as the service's) runs through the
//! whole drive as the service would, so that at each outage start it has what
//! it learned before (wheel offsets at standstill, gyro history); a copy of
//! it is put at the truth pose and dead-reckons to the outage end on the
//! wheels (and gyro), learning at standstills as the service does (wheel
//! offsets, gyro bias). GNSS and heading samples are never read. The score is the distance between the dead-reckoned
//! and the true position at the outage end. `distance_m` is the truth arc
//! length driven during the outage (same dead band), `error_pct` the error in
//! percent of it, given for outages of at least `min_distance_for_pct_m`.
//!
//! Percentiles: the median of an even count is the mean of the two middle
//! values; the 90th percentile interpolates linearly between order statistics
//! (rank 0.9 (n - 1), as numpy's default).

use crate::dead_reckoning::{DeadReckoner, HeadingMode, InputError, OdometerConfig};
use crate::estimate_file::OdometryParams;
use crate::inputs::{drive_inputs, Input};
use crate::two_wheel::{wrap_angle, Pose2};
use interfaces::drive::{Drive, TruthSample, WheelConversionError, WheelRevs};
use nalgebra::{Matrix4, Vector4};
use serde::Serialize;

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

/// Settings of an evaluation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EvaluateConfig {
    /// Length of each outage, s.
    pub outage_s: f64,
    /// Time between the starts of two outages, s.
    pub spacing_s: f64,
    /// Heading mode and gyro settings of the dead-reckoner.
    pub odometer: OdometerConfig,
    /// Half length of the truth track used to fit the course, m.
    pub course_half_window_m: f64,
    /// Largest gap between truth rows to interpolate across, s.
    pub max_truth_gap_s: f64,
    /// Outages shorter than this (truth arc length) get no `error_pct`, m.
    pub min_distance_for_pct_m: f64,
    /// Truth track length before the outage that the start yaw is aligned on, m.
    pub align_distance_m: f64,
    /// Longest time before the outage the alignment may reach back, s.
    pub align_max_s: f64,
    /// The body point `truth.csv` follows, scored at the outage ends: the
    /// rear-axle centre unless set ([`choose_truth_point`] picks it the way
    /// `odometry evaluate` does).
    pub truth_point: TruthPoint,
    /// Keep the dead-reckoned track of every outage in the report.
    pub keep_tracks: bool,
}

impl Default for EvaluateConfig {
    fn default() -> Self {
        EvaluateConfig {
            outage_s: 30.0,
            spacing_s: 10.0,
            odometer: OdometerConfig::default(),
            course_half_window_m: 5.0,
            max_truth_gap_s: 2.0,
            min_distance_for_pct_m: 5.0,
            align_distance_m: 30.0,
            align_max_s: 30.0,
            truth_point: TruthPoint::AXLE,
            keep_tracks: false,
        }
    }
}

/// The result of one simulated outage.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutageResult {
    /// Start of the outage, s.
    pub t_start_s: f64,
    /// Length, s.
    pub length_s: f64,
    /// Truth arc length driven during the outage, m.
    pub distance_m: f64,
    /// Position error at the outage end, m.
    pub error_m: f64,
    /// `error_m` in percent of `distance_m` (absent for short distances).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_pct: Option<f64>,
    /// Yaw the dead-reckoning started from, rad.
    pub start_yaw_rad: f64,
    /// Where the start pose came from: `truth_yaw`, `truth_track_alignment`,
    /// `truth_track_alignment_after` or `truth_course` (see the module docs).
    pub start_yaw_source: &'static str,
    /// Dead-reckoned position of the truth point at the outage end, m (east, north).
    pub end_m: [f64; 2],
    /// True position at the outage end, m (east, north).
    pub truth_end_m: [f64; 2],
    /// Increments that fell back to the wheel difference in gyro mode.
    pub gyro_fallbacks: u64,
    /// Gyro bias the dead-reckoning started with, rad/s: the calibrated one,
    /// or, with standstill learning, combined with the standstills before
    /// the outage.
    pub gyro_bias_rad_s: f64,
    /// Standstill gyro-bias measurements the odometer had taken by the
    /// outage end (those before the outage and during it).
    pub gyro_bias_standstills: u64,
    /// With `keep_tracks`: at every truth row inside the outage, its time,
    /// the dead-reckoned truth point and the truth (east, north).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub track: Vec<TrackPoint>,
}

/// One point of an outage's track.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TrackPoint {
    /// Time, s.
    pub t_s: f64,
    /// Dead-reckoned position of the truth point, m.
    pub dead_reckoned_m: [f64; 2],
    /// True position, m.
    pub truth_m: [f64; 2],
}

/// The parameters an evaluation used, as written to JSON.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ParamsReport {
    /// Rear-left circumference, m.
    pub c_rl_m: f64,
    /// Rear-right circumference, m.
    pub c_rr_m: f64,
    /// Track width, m.
    pub track_width_m: f64,
    /// Gyro bias, rad/s.
    pub gyro_bias_rad_s: f64,
    /// Gyro scale error.
    pub gyro_scale: f64,
}

impl From<&OdometryParams> for ParamsReport {
    fn from(p: &OdometryParams) -> Self {
        ParamsReport {
            c_rl_m: p.two_wheel.c_rl,
            c_rr_m: p.two_wheel.c_rr,
            track_width_m: p.two_wheel.track_width,
            gyro_bias_rad_s: p.gyro_bias_rad_s,
            gyro_scale: p.gyro_scale,
        }
    }
}

/// Everything an evaluation found; serialises to the `--json` output.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EvaluationReport {
    /// One entry per outage, in time order.
    pub outages: Vec<OutageResult>,
    /// Median of `error_m`, m.
    pub median_error_m: f64,
    /// 90th percentile of `error_m`, m.
    pub p90_error_m: f64,
    /// Median of `error_pct` over the outages that have one (`null` if none).
    pub median_error_pct: Option<f64>,
    /// Heading mode: `wheels` or `gyro`.
    pub heading: &'static str,
    /// Parameters used.
    pub params: ParamsReport,
    /// When `truth.csv` has a yaw: its median offset from the course of its
    /// own positions on straight stretches, rad (`null`: no yaw, or too few
    /// straight stretches to tell); see [`truth_yaw_offset`].
    pub truth_yaw_offset_rad: Option<f64>,
    /// Whether the start poses used the truth's yaw where it has one.
    pub truth_yaw_used: bool,
    /// The body point scored against `truth.csv`, and where its position
    /// came from.
    pub truth_point: TruthPoint,
    /// Whether `truth.csv` is the GNSS track itself ([`truth_is_the_gnss_track`]):
    /// then it follows the antenna, and a score at the rear axle includes the
    /// antenna's lever arm.
    pub truth_is_gnss_track: bool,
    /// What was skipped and why.
    pub warnings: Vec<String>,
}

/// Why an evaluation could not run.
#[derive(Debug, thiserror::Error)]
pub enum EvaluateError {
    /// The drive has no `truth.csv`.
    #[error("the drive has no truth.csv: outages cannot be scored")]
    NoTruth,
    /// Gyro heading asked for a drive without `imu.csv`.
    #[error(
        "heading mode gyro needs imu.csv, which the drive does not have (use --heading wheels)"
    )]
    NoImu,
    /// Wheel values cannot be converted to revolutions.
    #[error(transparent)]
    Wheels(#[from] WheelConversionError),
    /// Not even one outage fits in the drive.
    #[error(
        "no {outage_s} s outage fits: wheels and truth overlap only from {from_s} s to {to_s} s"
    )]
    TooShort {
        /// Requested outage length, s.
        outage_s: f64,
        /// Start of the overlap, s.
        from_s: f64,
        /// End of the overlap, s.
        to_s: f64,
    },
    /// Every outage was skipped.
    #[error("every outage was skipped: {0}")]
    NothingScored(String),
    /// A setting is out of range.
    #[error("invalid setting: {0}")]
    Config(String),
}

/// The truth track with its dead-banded arc length.
struct TruthTrack<'a> {
    rows: &'a [TruthSample],
    arc_m: Vec<f64>,
    max_gap_s: f64,
    /// Whether `yaw_at` gives the truth's yaw (false: it is not the vehicle's).
    use_yaw: bool,
}

impl<'a> TruthTrack<'a> {
    fn new(rows: &'a [TruthSample], max_gap_s: f64) -> TruthTrack<'a> {
        TruthTrack {
            rows,
            arc_m: dead_banded_arc_length(rows),
            max_gap_s,
            use_yaw: true,
        }
    }

    /// Index i with rows[i].t <= t <= rows[i+1].t, when the gap there is small enough.
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

    fn position_at(&self, t_s: f64) -> Option<[f64; 2]> {
        let (i, f) = self.bracket(t_s)?;
        let a = &self.rows[i];
        let Some(b) = self.rows.get(i + 1) else {
            return Some([a.x_m, a.y_m]);
        };
        Some([a.x_m + f * (b.x_m - a.x_m), a.y_m + f * (b.y_m - a.y_m)])
    }

    fn arc_at(&self, t_s: f64) -> Option<f64> {
        let (i, f) = self.bracket(t_s)?;
        let a = self.arc_m[i];
        Some(self.arc_m.get(i + 1).map_or(a, |b| a + f * (b - a)))
    }

    fn yaw_at(&self, t_s: f64) -> Option<f64> {
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
fn dead_banded_arc_length(rows: &[TruthSample]) -> Vec<f64> {
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

/// Median and linearly interpolated percentile of unsorted values.
pub fn percentile(values: &[f64], p: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let rank = p.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let lo = rank.floor() as usize;
    let hi = rank.ceil() as usize;
    Some(v[lo] + (rank - lo as f64) * (v[hi] - v[lo]))
}

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

/// Run the outage evaluation of `drive` with `params`.
pub fn evaluate(
    drive: &Drive,
    params: &OdometryParams,
    config: &EvaluateConfig,
) -> Result<EvaluationReport, EvaluateError> {
    if !(config.outage_s > 0.0 && config.spacing_s > 0.0) {
        return Err(EvaluateError::Config(format!(
            "outage ({} s) and spacing ({} s) must be positive",
            config.outage_s, config.spacing_s
        )));
    }
    params
        .validate("odometry parameters")
        .map_err(|e| EvaluateError::Config(e.to_string()))?;
    let truth_rows = drive
        .truth
        .as_deref()
        .filter(|t| !t.is_empty())
        .ok_or(EvaluateError::NoTruth)?;
    if config.odometer.heading == HeadingMode::Gyro && drive.imu.as_ref().is_none_or(Vec::is_empty)
    {
        return Err(EvaluateError::NoImu);
    }
    let revs = drive.wheel_revolutions()?;
    let inputs = drive_inputs(drive)?;
    let mut truth = TruthTrack::new(truth_rows, config.max_truth_gap_s);
    let mut warnings = Vec::new();
    let yaw_offset = truth_yaw_offset(truth_rows, config.max_truth_gap_s);
    if let Some((offset, stretches)) = yaw_offset {
        if offset.abs() > TRUTH_YAW_OFFSET_LIMIT_RAD {
            truth.use_yaw = false;
            warnings.push(format!(
                "truth.csv: yaw_rad is {:+.1} mrad off the course of its own positions (median over \
                 {stretches} straight stretches of {YAW_CHECK_STRETCH_M} m), more than {:.1} mrad: \
                 it is not the vehicle's yaw (a device mounted at an angle?); the start poses come \
                 from the truth track instead",
                offset * 1e3,
                TRUTH_YAW_OFFSET_LIMIT_RAD * 1e3
            ));
        }
    }

    let (Some(w0), Some(w1)) = (revs.first(), revs.last()) else {
        return Err(EvaluateError::TooShort {
            outage_s: config.outage_s,
            from_s: 0.0,
            to_s: 0.0,
        });
    };
    let t_from = w0.t_s.max(truth_rows[0].t_s);
    let t_to = w1.t_s.min(truth_rows[truth_rows.len() - 1].t_s);
    if t_from + config.outage_s > t_to {
        return Err(EvaluateError::TooShort {
            outage_s: config.outage_s,
            from_s: t_from,
            to_s: t_to,
        });
    }
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
                .and_then(|s0| alignment_window(&truth, config, t0, s0))
        };
        windows.push((t0, t1, align));
    }

    // One pass of the odometer over the whole drive, as the service runs it;
    // every outage (and alignment) starts from a copy of it.
    let mut starts: Vec<f64> = windows
        .iter()
        .flat_map(|w| std::iter::once(w.0).chain(w.2.map(|a| a.0)))
        .collect();
    starts.sort_by(f64::total_cmp);
    starts.dedup();
    let (snapshots, background_skipped) =
        snapshots(&revs, &inputs, params, config.odometer, &starts);
    let snapshot_at = |t: f64| -> Result<&Snapshot, String> {
        let i = starts.partition_point(|s| *s < t);
        match snapshots.get(i) {
            Some(Ok(snap)) if starts[i] == t => Ok(snap),
            Some(Err(e)) => Err(e.clone()),
            _ => Err(format!("no odometer state at {t} s")),
        }
    };

    let mut outages = Vec::new();
    if background_skipped > 0 {
        warnings.push(format!(
            "{background_skipped} wheel or IMU samples with bad values or times skipped"
        ));
    }
    for &(t0, t1, align) in &windows {
        let scored = snapshot_at(t0).and_then(|start| {
            let aligned = align.and_then(|(ta, tb)| {
                let from = snapshot_at(ta).ok()?;
                aligned_start(
                    &truth,
                    &revs,
                    &inputs,
                    from,
                    config.truth_point.point_m,
                    ta,
                    tb,
                    t0,
                )
            });
            run_outage(&truth, &revs, &inputs, config, start, aligned, t0, t1)
        });
        match scored {
            Ok(result) => outages.push(result),
            Err(reason) => warnings.push(format!("outage at {t0:.2} s skipped: {reason}")),
        }
    }
    if outages.is_empty() {
        return Err(EvaluateError::NothingScored(warnings.join("; ")));
    }
    let errors: Vec<f64> = outages.iter().map(|o| o.error_m).collect();
    let pcts: Vec<f64> = outages.iter().filter_map(|o| o.error_pct).collect();
    Ok(EvaluationReport {
        median_error_m: percentile(&errors, 0.5).unwrap_or(f64::NAN),
        p90_error_m: percentile(&errors, 0.9).unwrap_or(f64::NAN),
        median_error_pct: percentile(&pcts, 0.5),
        outages,
        heading: config.odometer.heading.name(),
        params: ParamsReport::from(params),
        truth_yaw_offset_rad: yaw_offset.map(|(offset, _)| offset),
        truth_yaw_used: truth.use_yaw && truth_rows.iter().any(|r| r.yaw_rad.is_some()),
        truth_point: config.truth_point,
        truth_is_gnss_track: truth_is_the_gnss_track(drive),
        warnings,
    })
}

/// A GNSS fix and a truth row this close in time are at the same instant, s.
const SAME_INSTANT_S: f64 = 1e-6;
/// A truth row this close to the fix of its instant is at the fix, m.
const SAME_POINT_M: f64 = 1e-3;
/// Fixes with a truth row at their instant needed to call the truth the GNSS track.
const MIN_COINCIDENT_FIXES: usize = 10;

/// How many GNSS fixes have a truth row at their instant, and at how many of
/// those the truth row is at the fix (within 1 mm).
pub fn truth_gnss_coincidence(drive: &Drive) -> (usize, usize) {
    let (Some(truth), Some(gnss)) = (&drive.truth, &drive.gnss) else {
        return (0, 0);
    };
    let (mut same_instant, mut same_point) = (0, 0);
    let mut k = 0;
    for fix in gnss {
        // Both files are in time order (the drive reader checks it).
        while k < truth.len() && truth[k].t_s < fix.t_s - SAME_INSTANT_S {
            k += 1;
        }
        let Some(row) = truth.get(k).filter(|r| r.t_s <= fix.t_s + SAME_INSTANT_S) else {
            continue;
        };
        same_instant += 1;
        if (row.x_m - fix.x_m).hypot(row.y_m - fix.y_m) <= SAME_POINT_M {
            same_point += 1;
        }
    }
    (same_instant, same_point)
}

/// Whether `truth.csv` is the GNSS track itself: at least
/// `MIN_COINCIDENT_FIXES` (10) fixes have a truth row at their instant, and
/// every one of those rows is at its fix. An RTK receiver's track given as
/// the truth (the WID drives) is such a truth: it follows the GNSS antenna,
/// not the rear-axle centre. A truth of the rear axle (the simulator's) or of
/// an INS (comma2k19's) is not.
pub fn truth_is_the_gnss_track(drive: &Drive) -> bool {
    let (same_instant, same_point) = truth_gnss_coincidence(drive);
    same_instant >= MIN_COINCIDENT_FIXES && same_point == same_instant
}

/// Where the scored body point's position comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TruthPointSource {
    /// The rear-axle centre.
    Axle,
    /// Given by the user (`--truth-point X,Y`).
    Given,
    /// The GNSS antenna as `vehicle.toml`'s `[gnss]` measures it.
    MeasuredAntenna,
    /// The GNSS antenna as the estimate's calibration found it.
    EstimatedAntenna,
}

/// The body point scored against `truth.csv`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TruthPoint {
    /// Body-frame position (x forward, y left) from the rear-axle centre, m.
    pub point_m: [f64; 2],
    /// Where it comes from.
    pub source: TruthPointSource,
}

impl TruthPoint {
    /// The rear-axle centre.
    pub const AXLE: TruthPoint = TruthPoint {
        point_m: [0.0, 0.0],
        source: TruthPointSource::Axle,
    };
}

/// How the scored body point is asked for (`odometry evaluate --truth-point`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TruthPointChoice {
    /// The GNSS antenna when `truth.csv` is the GNSS track
    /// ([`truth_is_the_gnss_track`]) and the antenna's position is known,
    /// else the rear-axle centre.
    Auto,
    /// The rear-axle centre.
    Axle,
    /// The GNSS antenna (measured in `vehicle.toml`, else the estimate's).
    Antenna,
    /// A given body point, m.
    At([f64; 2]),
}

impl std::str::FromStr for TruthPointChoice {
    type Err = EvaluateError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let bad = || {
            EvaluateError::Config(format!(
                "truth point `{text}`: expected auto, axle, antenna or X,Y in metres"
            ))
        };
        match text {
            "auto" => Ok(TruthPointChoice::Auto),
            "axle" => Ok(TruthPointChoice::Axle),
            "antenna" => Ok(TruthPointChoice::Antenna),
            xy => {
                let v: Vec<f64> = xy
                    .split(',')
                    .map(|s| s.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| bad())?;
                match v[..] {
                    [x, y] if x.is_finite() && y.is_finite() => Ok(TruthPointChoice::At([x, y])),
                    _ => Err(bad()),
                }
            }
        }
    }
}

/// The body point to score `drive` at, as `choice` asks: the antenna is the
/// one `vehicle.toml` measures (`[gnss] antenna_x_m, antenna_y_m`), else
/// `estimated_antenna` (the estimate's calibration). `Antenna` with neither is
/// an error; `Auto` with neither falls back to the rear axle (the report's
/// `truth_is_gnss_track` then tells that the score includes the lever arm).
pub fn choose_truth_point(
    drive: &Drive,
    choice: TruthPointChoice,
    estimated_antenna: Option<[f64; 2]>,
) -> Result<TruthPoint, EvaluateError> {
    let gnss = &drive.vehicle.gnss;
    let antenna = match (gnss.antenna_x_m, gnss.antenna_y_m) {
        (Some(x), Some(y)) => Some(TruthPoint {
            point_m: [x, y],
            source: TruthPointSource::MeasuredAntenna,
        }),
        _ => estimated_antenna.map(|point_m| TruthPoint {
            point_m,
            source: TruthPointSource::EstimatedAntenna,
        }),
    };
    match choice {
        TruthPointChoice::Axle => Ok(TruthPoint::AXLE),
        TruthPointChoice::At(point_m) => Ok(TruthPoint {
            point_m,
            source: TruthPointSource::Given,
        }),
        TruthPointChoice::Antenna => antenna.ok_or_else(|| {
            EvaluateError::Config(
                "the antenna's position is not known: vehicle.toml has no [gnss] antenna_x_m, \
                 antenna_y_m and the estimate has none (gyro.antenna_m or gnss_antenna_m)"
                    .to_string(),
            )
        }),
        TruthPointChoice::Auto => Ok(match antenna {
            Some(a) if truth_is_the_gnss_track(drive) => a,
            _ => TruthPoint::AXLE,
        }),
    }
}

/// The odometer as it was at one instant: fed every input before it, and the
/// wheel revolutions interpolated at the instant itself.
#[derive(Debug, Clone)]
struct Snapshot {
    dr: DeadReckoner,
    /// Index of the first input after the instant.
    next: usize,
}

/// Run one odometer through the inputs and copy it at each of `times`
/// (sorted). Returns the copies and the number of inputs it had to skip.
fn snapshots(
    revs: &[WheelRevs],
    inputs: &[Input],
    params: &OdometryParams,
    odometer: OdometerConfig,
    times: &[f64],
) -> (Vec<Result<Snapshot, String>>, usize) {
    let mut background = DeadReckoner::new(*params, odometer, Pose2::default());
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
struct Span {
    /// Pose at every wheel sample (the ends included), with its time.
    track: Vec<(f64, Pose2)>,
    /// Input samples skipped as unusable.
    skipped: usize,
    /// Increments in the span that fell back to the wheel difference in gyro mode.
    gyro_fallbacks: u64,
    /// Gyro bias at the start, rad/s.
    gyro_bias_rad_s: f64,
    /// Standstill bias measurements by the end.
    gyro_bias_standstills: u64,
}

fn dead_reckon_span(
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
fn track_position_at(track: &[(f64, Pose2)], t_s: f64, arm: [f64; 2]) -> Option<[f64; 2]> {
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

/// The alignment window `(ta, tb)` for an outage starting at `t0`: the last
/// `align_distance_m` of truth track before `t0` (`tb = t0`), or, when the
/// vehicle has not driven that far before `t0` (a drive's start), the first
/// `align_distance_m` after it (`ta = t0`); within `align_max_s` and without
/// truth gaps longer than `max_truth_gap_s`.
fn alignment_window(
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
fn aligned_start(
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
    let (mut rotation, mut dm, mut gm) = procrustes(&pairs)?;
    let residual = |rotation: f64, dm: [f64; 2], gm: [f64; 2], d: [f64; 2], g: [f64; 2]| {
        let (s, c) = rotation.sin_cos();
        let (dx, dy) = (d[0] - dm[0], d[1] - dm[1]);
        (gm[0] + c * dx - s * dy - g[0]).hypot(gm[1] + s * dx + c * dy - g[1])
    };
    let residuals: Vec<f64> = pairs
        .iter()
        .map(|(d, g)| residual(rotation, dm, gm, *d, *g))
        .collect();
    let limit = (3.0 * percentile(&residuals, 0.5)?).max(0.1);
    let kept: Vec<_> = pairs
        .iter()
        .zip(&residuals)
        .filter(|(_, r)| **r <= limit)
        .map(|(p, _)| *p)
        .collect();
    if kept.len() < pairs.len() {
        (rotation, dm, gm) = procrustes(&kept)?;
    }
    let (t_end, end) = if t0 == ta {
        span.track.first()?
    } else {
        span.track.last()?
    };
    debug_assert!(*t_end == t0);
    let d0 = end.point_at(arm);
    let (s, c) = rotation.sin_cos();
    let (dx, dy) = (d0[0] - dm[0], d0[1] - dm[1]);
    let position = [gm[0] + c * dx - s * dy, gm[1] + s * dx + c * dy];
    Some((position, wrap_angle(end.yaw + rotation)))
}

/// Rotation and centroids laying points `d` onto points `g` (least squares).
fn procrustes(pairs: &[([f64; 2], [f64; 2])]) -> Option<(f64, [f64; 2], [f64; 2])> {
    if pairs.len() < 3 {
        return None;
    }
    let n = pairs.len() as f64;
    let (mut dm, mut gm) = ([0.0; 2], [0.0; 2]);
    for (d, g) in pairs {
        for j in 0..2 {
            dm[j] += d[j] / n;
            gm[j] += g[j] / n;
        }
    }
    let (mut dot, mut cross, mut spread) = (0.0, 0.0, 0.0);
    for (d, g) in pairs {
        let (dx, dy, gx, gy) = (d[0] - dm[0], d[1] - dm[1], g[0] - gm[0], g[1] - gm[1]);
        dot += dx * gx + dy * gy;
        cross += dx * gy - dy * gx;
        spread += dx * dx + dy * dy;
    }
    // A track that did not move has no direction.
    if spread < 1.0 {
        return None;
    }
    let rotation = cross.atan2(dot);
    rotation.is_finite().then_some((rotation, dm, gm))
}

/// One outage from `t0` to `t1`, or why it cannot be scored.
#[allow(clippy::too_many_arguments)]
fn run_outage(
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
    let (start, yaw, yaw_source) = if let Some(y) = truth.yaw_at(t0) {
        (start, y, "truth_yaw")
    } else if let Some((position, y)) = aligned {
        let after = truth.arc_at(t0).is_some_and(|s0| {
            alignment_window(truth, config, t0, s0).is_some_and(|(ta, _)| ta == t0)
        });
        let source = if after {
            "truth_track_alignment_after"
        } else {
            "truth_track_alignment"
        };
        (position, y, source)
    } else {
        (
            start,
            // Widen the window where the truth is sparse (e.g. at a drive's start).
            [1.0, 2.0, 4.0]
                .iter()
                .find_map(|k| {
                    course_at(
                        truth.rows,
                        &truth.arc_m,
                        s0,
                        k * config.course_half_window_m,
                    )
                })
                .ok_or("the truth track does not move enough around the start to give a course")?,
            "truth_course",
        )
    };
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
    let mut track = Vec::new();
    if config.keep_tracks {
        let first = truth.rows.partition_point(|r| r.t_s < t0);
        for r in truth.rows[first..].iter().take_while(|r| r.t_s <= t1) {
            if let Some(d) = track_position_at(&span.track, r.t_s, config.truth_point.point_m) {
                track.push(TrackPoint {
                    t_s: r.t_s,
                    dead_reckoned_m: d,
                    truth_m: [r.x_m, r.y_m],
                });
            }
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::two_wheel::TwoWheelParams;
    use interfaces::drive::{
        GnssAntenna, ImuSample, VehicleParams, WheelSample, WheelSeries, WheelUnit, WheelUnits,
    };

    const C_RL: f64 = 1.83;
    const C_RR: f64 = 1.84;
    const TRACK: f64 = 1.42;

    /// A synthetic drive on a winding path at 8 m/s: true wheels with
    /// circumferences C_RL, C_RR and track TRACK, a perfect gyro, truth at
    /// 5 Hz without yaw.
    fn winding_drive(seconds: f64) -> Drive {
        let mut drive = drive_with_yaw_rate(seconds, |t| 0.25 * (0.2 * t).sin());
        for r in drive.truth.as_mut().unwrap() {
            r.yaw_rad = None;
        }
        drive
    }

    /// A drive at 8 m/s with the given yaw rate; its truth (every 0.2 s)
    /// has the true yaw.
    fn drive_with_yaw_rate(seconds: f64, yaw_rate: impl Fn(f64) -> f64) -> Drive {
        let dt = 0.01;
        let n = (seconds / dt).round() as usize;
        let v = 8.0;
        let (mut x, mut y, mut yaw, mut rl, mut rr) = (0.0, 0.0, 0.3, 0.0, 0.0);
        let mut wheels = Vec::new();
        let mut imu = Vec::new();
        let mut truth = Vec::new();
        for i in 0..=n {
            let t = i as f64 * dt;
            if i > 0 {
                let w = yaw_rate(t - dt / 2.0);
                let ds = v * dt;
                let dyaw = w * dt;
                x += ds * (yaw + dyaw / 2.0).cos();
                y += ds * (yaw + dyaw / 2.0).sin();
                yaw += dyaw;
                rl += (ds - dyaw * TRACK / 2.0) / C_RL;
                rr += (ds + dyaw * TRACK / 2.0) / C_RR;
            }
            wheels.push(WheelSample {
                t_s: t,
                rl,
                rr,
                fl: None,
                fr: None,
            });
            imu.push(ImuSample {
                t_s: t,
                gz_rad_s: yaw_rate(t),
                ax_m_s2: None,
                ay_m_s2: None,
                az_m_s2: None,
                gx_rad_s: None,
                gy_rad_s: None,
            });
            if i % 20 == 0 {
                truth.push(TruthSample {
                    t_s: t,
                    x_m: x,
                    y_m: y,
                    yaw_rad: Some(yaw),
                });
            }
        }
        Drive {
            vehicle: VehicleParams {
                name: None,
                track_width_m: 1.45,
                nominal_circumference_m: 1.85,
                wheelbase_m: None,
                ticks_per_rev: None,
                gnss: GnssAntenna::default(),
            },
            wheels: WheelSeries {
                units: WheelUnits::rear(WheelUnit::Rev),
                samples: wheels,
            },
            gnss: None,
            imu: Some(imu),
            heading: None,
            truth: Some(truth),
            truth_params: None,
        }
    }

    fn true_params() -> OdometryParams {
        OdometryParams {
            two_wheel: TwoWheelParams {
                c_rl: C_RL,
                c_rr: C_RR,
                track_width: TRACK,
            },
            gyro_bias_rad_s: 0.0,
            gyro_scale: 0.0,
        }
    }

    fn config(heading: HeadingMode, outage_s: f64) -> EvaluateConfig {
        EvaluateConfig {
            outage_s,
            odometer: OdometerConfig {
                heading,
                ..OdometerConfig::default()
            },
            ..EvaluateConfig::default()
        }
    }

    #[test]
    fn true_parameters_give_small_errors_in_both_heading_modes() {
        let drive = winding_drive(100.0);
        for heading in [HeadingMode::WheelDifference, HeadingMode::Gyro] {
            let report = evaluate(&drive, &true_params(), &config(heading, 30.0)).unwrap();
            // Starts 0, 10, ..., 70: eight outages of 240 m each.
            assert_eq!(report.outages.len(), 8, "{heading}");
            assert!(report.warnings.is_empty(), "{:?}", report.warnings);
            for o in &report.outages {
                // No driving before the first outage: aligned on the track after its start.
                let expected = if o.t_start_s == 0.0 {
                    "truth_track_alignment_after"
                } else {
                    "truth_track_alignment"
                };
                assert_eq!(o.start_yaw_source, expected);
                assert!((o.distance_m - 240.0).abs() < 1.0, "{o:?}");
                assert_eq!(o.gyro_fallbacks, 0);
            }
            // Only the course fit and discretisation separate the model from the truth.
            assert!(report.p90_error_m < 0.05, "{heading}: {report:?}");
        }
    }

    #[test]
    fn wrong_circumferences_are_worse_than_right_ones() {
        let drive = winding_drive(70.0);
        let good = evaluate(
            &drive,
            &true_params(),
            &config(HeadingMode::WheelDifference, 30.0),
        )
        .unwrap();
        let nominal = OdometryParams::nominal(&drive.vehicle);
        let bad = evaluate(
            &drive,
            &nominal,
            &config(HeadingMode::WheelDifference, 30.0),
        )
        .unwrap();
        // 1 % scale error alone is 2.4 m after 240 m.
        assert!(bad.median_error_m > 2.0, "{bad:?}");
        assert!(
            bad.median_error_m > 10.0 * good.median_error_m,
            "{good:?} {bad:?}"
        );
        let pct = bad.median_error_pct.unwrap();
        assert!(
            (pct - 100.0 * bad.median_error_m / 240.0).abs() < 0.5,
            "{pct}"
        );
    }

    #[test]
    fn alignment_start_pose_shrugs_off_truth_noise_and_jumps() {
        // Truth with +-3 cm of deterministic jitter and, just before every
        // outage start, a 0.8 m sideways jump for two rows (an RTK glitch).
        let mut drive = winding_drive(100.0);
        for (k, r) in drive.truth.as_mut().unwrap().iter_mut().enumerate() {
            let jitter = 0.03 * ((k as f64 * 1.7).sin());
            r.x_m += jitter;
            r.y_m -= jitter;
            let phase = r.t_s % 10.0;
            if (9.5..9.9).contains(&phase) {
                r.y_m += 0.8;
            }
        }
        let report = evaluate(&drive, &true_params(), &config(HeadingMode::Gyro, 30.0)).unwrap();
        for o in &report.outages {
            // A course from the raw points would be off by a few hundredths of
            // a radian here: metres after 240 m.
            assert!(o.error_m < 0.3, "{o:?}");
        }
    }

    #[test]
    fn truth_yaw_is_used_when_present() {
        // Winding all the time: too few straight stretches to check the
        // yaw, so it is taken as it is.
        let drive = drive_with_yaw_rate(40.0, |t| 0.25 * (0.2 * t).sin());
        let report = evaluate(&drive, &true_params(), &config(HeadingMode::Gyro, 30.0)).unwrap();
        assert_eq!(report.truth_yaw_offset_rad, None);
        assert!(report.truth_yaw_used);
        assert_eq!(report.outages[0].start_yaw_source, "truth_yaw");
        assert_eq!(report.outages[0].start_yaw_rad, 0.3);
        // A yaw that does not follow the track at all: found out.
        let mut fixed = drive.clone();
        for r in fixed.truth.as_mut().unwrap() {
            r.yaw_rad = Some(1.0);
        }
        let report = evaluate(&fixed, &true_params(), &config(HeadingMode::Gyro, 30.0)).unwrap();
        assert!(!report.truth_yaw_used);
        assert!(report.truth_yaw_offset_rad.unwrap().abs() > 0.1);
    }

    /// Straight for 10 s, then a 0.2 rad/s turn for 10 s, and again.
    fn straights_and_turns(seconds: f64) -> Drive {
        drive_with_yaw_rate(seconds, |t| if t % 20.0 < 10.0 { 0.0 } else { 0.2 })
    }

    #[test]
    fn a_truth_yaw_off_the_truth_course_is_found_and_not_used() {
        // The vehicle's own yaw: about 0 off, used.
        let drive = straights_and_turns(60.0);
        let rows = drive.truth.as_deref().unwrap();
        let (offset, stretches) = truth_yaw_offset(rows, 2.0).unwrap();
        assert!(offset.abs() < 1e-3, "{offset}");
        // 30 s of straights at 8 m/s: 24 stretches of 10 m, the turns left out.
        assert!((20..=24).contains(&stretches), "{stretches}");
        let report = evaluate(&drive, &true_params(), &config(HeadingMode::Gyro, 30.0)).unwrap();
        assert!(report.truth_yaw_used);
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        assert_eq!(report.outages[0].start_yaw_source, "truth_yaw");
        assert!(report.median_error_m < 0.15, "{}", report.median_error_m);

        // A yaw 15 mrad off (a device mounted at an angle): found, named and
        // replaced by the truth track, so the error stays small (taken as
        // it is, it would put the end of a 240 m outage 3.6 m off).
        let mut skewed = drive.clone();
        for r in skewed.truth.as_mut().unwrap() {
            r.yaw_rad = r.yaw_rad.map(|y| y + 0.015);
        }
        let rows = skewed.truth.as_deref().unwrap();
        let (offset, _) = truth_yaw_offset(rows, 2.0).unwrap();
        assert!((offset - 0.015).abs() < 1e-3, "{offset}");
        let report = evaluate(&skewed, &true_params(), &config(HeadingMode::Gyro, 30.0)).unwrap();
        assert!(!report.truth_yaw_used);
        assert!(
            report
                .warnings
                .iter()
                .any(|w| w.contains("truth.csv: yaw_rad is +15.0 mrad off")),
            "{:?}",
            report.warnings
        );
        assert!(report
            .outages
            .iter()
            .all(|o| o.start_yaw_source.starts_with("truth_track_alignment")));
        assert!(report.median_error_m < 0.15, "{}", report.median_error_m);
    }

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

    #[test]
    fn missing_truth_imu_or_length_are_clear_errors() {
        let mut drive = winding_drive(20.0);
        let msg = evaluate(&drive, &true_params(), &config(HeadingMode::Gyro, 30.0))
            .unwrap_err()
            .to_string();
        assert!(msg.contains("no 30 s outage fits"), "{msg}");
        drive.imu = None;
        let msg = evaluate(&drive, &true_params(), &config(HeadingMode::Gyro, 10.0))
            .unwrap_err()
            .to_string();
        assert!(msg.contains("imu.csv"), "{msg}");
        drive.truth = None;
        let msg = evaluate(
            &drive,
            &true_params(),
            &config(HeadingMode::WheelDifference, 10.0),
        )
        .unwrap_err()
        .to_string();
        assert!(msg.contains("truth.csv"), "{msg}");
    }

    #[test]
    fn truth_gap_skips_the_outage_with_a_warning() {
        let mut drive = winding_drive(70.0);
        // Remove truth between 48 s and 52 s: the outage 20-50 s loses its end.
        drive
            .truth
            .as_mut()
            .unwrap()
            .retain(|r| !(r.t_s > 48.0 && r.t_s < 52.0));
        let report = evaluate(
            &drive,
            &true_params(),
            &config(HeadingMode::WheelDifference, 30.0),
        )
        .unwrap();
        assert_eq!(report.outages.len(), 4, "{report:?}");
        assert_eq!(report.warnings.len(), 1);
        assert!(
            report.warnings[0].contains("20.00 s") && report.warnings[0].contains("end"),
            "{:?}",
            report.warnings
        );
    }

    #[test]
    fn percentiles_interpolate() {
        assert_eq!(percentile(&[3.0, 1.0, 2.0, 4.0], 0.5), Some(2.5));
        let p90 = percentile(&(1..=11).map(f64::from).collect::<Vec<_>>(), 0.9).unwrap();
        assert!((p90 - 10.0).abs() < 1e-12);
        assert_eq!(percentile(&[], 0.5), None);
    }

    const ANTENNA: [f64; 2] = [0.6, -0.3];

    /// The winding drive with an RTK-like truth: truth.csv is the track of an
    /// antenna at ANTENNA, and gnss.csv is the same track (as on the WID
    /// drives); with `gnss_offset_m`, every fix is that far east of it.
    fn antenna_truth_drive(gnss_offset_m: f64) -> Drive {
        let mut drive = drive_with_yaw_rate(120.0, |t| 0.25 * (0.2 * t).sin());
        let truth = drive.truth.as_mut().unwrap();
        for r in truth.iter_mut() {
            let yaw = r.yaw_rad.take().unwrap();
            [r.x_m, r.y_m] = Pose2 {
                x: r.x_m,
                y: r.y_m,
                yaw,
            }
            .point_at(ANTENNA);
        }
        drive.gnss = Some(
            truth
                .iter()
                .map(|r| interfaces::drive::GnssSample {
                    t_s: r.t_s,
                    x_m: r.x_m + gnss_offset_m,
                    y_m: r.y_m,
                    sigma_m: Some(0.02),
                })
                .collect(),
        );
        drive
    }

    #[test]
    fn a_truth_that_is_the_gnss_track_is_scored_at_the_antenna() {
        let drive = antenna_truth_drive(0.0);
        assert_eq!(truth_gnss_coincidence(&drive), (601, 601));
        assert!(truth_is_the_gnss_track(&drive));
        // Auto: the estimate's antenna, since vehicle.toml measures none.
        let point = choose_truth_point(&drive, TruthPointChoice::Auto, Some(ANTENNA)).unwrap();
        assert_eq!(
            point,
            TruthPoint {
                point_m: ANTENNA,
                source: TruthPointSource::EstimatedAntenna
            }
        );
        let at = |truth_point| {
            evaluate(
                &drive,
                &true_params(),
                &EvaluateConfig {
                    truth_point,
                    ..config(HeadingMode::Gyro, 30.0)
                },
            )
            .unwrap()
        };
        let antenna = at(point);
        let axle = at(TruthPoint::AXLE);
        assert!(antenna.truth_is_gnss_track && axle.truth_is_gnss_track);
        assert_eq!(antenna.truth_point, point);
        // The true parameters at the point the truth follows: only the
        // integration's own error. At the rear axle: the lever arm, turned by
        // the heading change of each outage.
        assert!(antenna.median_error_m < 0.05, "{}", antenna.median_error_m);
        assert!(
            axle.median_error_m > 10.0 * antenna.median_error_m.max(0.01),
            "axle {} antenna {}",
            axle.median_error_m,
            antenna.median_error_m
        );
        // No antenna known: Auto falls back to the axle; Antenna is an error.
        assert_eq!(
            choose_truth_point(&drive, TruthPointChoice::Auto, None).unwrap(),
            TruthPoint::AXLE
        );
        let err = choose_truth_point(&drive, TruthPointChoice::Antenna, None).unwrap_err();
        assert!(err.to_string().contains("[gnss]"), "{err}");
    }

    #[test]
    fn a_measured_antenna_wins_and_a_truth_apart_from_the_fixes_stays_at_the_axle() {
        let mut drive = antenna_truth_drive(0.0);
        drive.vehicle.gnss.antenna_x_m = Some(0.5);
        drive.vehicle.gnss.antenna_y_m = Some(-0.25);
        let measured = TruthPoint {
            point_m: [0.5, -0.25],
            source: TruthPointSource::MeasuredAntenna,
        };
        for choice in [TruthPointChoice::Auto, TruthPointChoice::Antenna] {
            assert_eq!(
                choose_truth_point(&drive, choice, Some(ANTENNA)).unwrap(),
                measured
            );
        }
        // Fixes 2 cm off the truth: the truth is not the GNSS track.
        let apart = antenna_truth_drive(0.02);
        assert_eq!(truth_gnss_coincidence(&apart), (601, 0));
        assert!(!truth_is_the_gnss_track(&apart));
        assert_eq!(
            choose_truth_point(&apart, TruthPointChoice::Auto, Some(ANTENNA)).unwrap(),
            TruthPoint::AXLE
        );
        // No fixes at all (a drive with a truth but no gnss.csv).
        assert!(!truth_is_the_gnss_track(&winding_drive(60.0)));
        assert_eq!(
            choose_truth_point(&drive, TruthPointChoice::At([1.0, 0.5]), None).unwrap(),
            TruthPoint {
                point_m: [1.0, 0.5],
                source: TruthPointSource::Given
            }
        );
    }

    #[test]
    fn truth_point_choices_are_read_and_bad_ones_named() {
        let read = |s: &str| s.parse::<TruthPointChoice>();
        assert_eq!(read("auto").unwrap(), TruthPointChoice::Auto);
        assert_eq!(read("axle").unwrap(), TruthPointChoice::Axle);
        assert_eq!(read("antenna").unwrap(), TruthPointChoice::Antenna);
        assert_eq!(
            read(" 0.5, -0.2").unwrap(),
            TruthPointChoice::At([0.5, -0.2])
        );
        for bad in ["0.5", "x,y", "nan,0", "1,2,3", "Antenna"] {
            let err = read(bad).unwrap_err().to_string();
            assert!(err.contains(&format!("`{bad}`")), "{err}");
        }
    }
}
