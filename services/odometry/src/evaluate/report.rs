//! What an evaluation reports: every outage's score and the summary over
//! them, as written to JSON.

use super::truth_point::TruthPoint;
use serde::Serialize;
use vehicle_model::estimate::OdometryParams;

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
    /// straight stretches to tell); see
    /// [`truth_yaw_offset`](super::truth_track::truth_yaw_offset).
    pub truth_yaw_offset_rad: Option<f64>,
    /// Whether the start poses used the truth's yaw where it has one.
    pub truth_yaw_used: bool,
    /// The body point scored against `truth.csv`, and where its position
    /// came from.
    pub truth_point: TruthPoint,
    /// Whether `truth.csv` is the GNSS track itself
    /// ([`truth_is_the_gnss_track`](super::truth_point::truth_is_the_gnss_track)):
    /// then it follows the antenna, and a score at the rear axle includes the
    /// antenna's lever arm.
    pub truth_is_gnss_track: bool,
    /// What was skipped and why.
    pub warnings: Vec<String>,
}
