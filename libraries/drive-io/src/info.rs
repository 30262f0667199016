//! The `info` summary of a drive: duration, distance, the rate and gaps of
//! every stream, the GNSS outages, and the physically impossible or broken
//! values [`plausibility::findings`] finds (after unwrapping counter wraps).
//!
//! Rules (also in the README):
//! - a stream's *rate* is 1 / its median sample interval;
//! - a *gap* in a stream is an interval longer than [`GAP_FACTOR`] times the
//!   stream's median interval;
//! - a *GNSS outage* is a stretch without fixes longer than
//!   max([`GNSS_OUTAGE_MIN_S`], [`GAP_FACTOR`] × median GNSS interval): between
//!   two fixes, or between the wheel data's start/end and the first/last fix.

use super::LoadedDrive;
use crate::plausibility::{self, FindingSummary, Severity};
use interfaces::drive::{Drive, Wheel};
use serde::Serialize;
use std::fmt;

/// An interval longer than this many median intervals is a gap.
pub const GAP_FACTOR: f64 = 5.0;
/// A GNSS outage lasts at least this long, s.
pub const GNSS_OUTAGE_MIN_S: f64 = 1.0;

/// A stretch of time, s.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GapSummary {
    /// Last sample before the gap (or the drive's start), s.
    pub start_s: f64,
    /// First sample after the gap (or the drive's end), s.
    pub end_s: f64,
    /// `end_s - start_s`, s.
    pub duration_s: f64,
}

/// Figures of one stream.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StreamSummary {
    /// `wheels`, `gnss`, `imu`, `heading` or `truth`.
    pub name: String,
    /// Number of samples.
    pub samples: usize,
    /// Time of the first sample, s (`None` when empty).
    pub first_s: Option<f64>,
    /// Time of the last sample, s.
    pub last_s: Option<f64>,
    /// Median interval between samples, s.
    pub median_interval_s: Option<f64>,
    /// 1 / median interval, Hz.
    pub rate_hz: Option<f64>,
    /// Longest interval, s.
    pub max_interval_s: Option<f64>,
    /// Intervals longer than [`GAP_FACTOR`] × median.
    pub gaps: usize,
    /// Total time spent in those gaps, s.
    pub gap_time_s: f64,
}

/// The `info` summary of a drive.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DriveSummary {
    /// Vehicle name from `vehicle.toml`.
    pub name: Option<String>,
    /// Earliest sensor time (wheels, GNSS, IMU, heading), s.
    pub start_s: f64,
    /// Latest sensor time, s.
    pub end_s: f64,
    /// `end_s - start_s`, s.
    pub duration_s: f64,
    /// Path length through the GNSS fixes, m.
    pub distance_gnss_m: Option<f64>,
    /// Path length of the rear-axle centre from the rear wheels with the
    /// nominal circumference, m (`None` when the wheels cannot be turned into
    /// revolutions).
    pub distance_wheels_m: Option<f64>,
    /// Path length through the truth positions, m.
    pub distance_truth_m: Option<f64>,
    /// Wheel columns, e.g. `rl_rad_s, rr_rad_s`.
    pub wheel_columns: Vec<String>,
    /// Track width and nominal circumference from `vehicle.toml`, m.
    pub track_width_m: f64,
    /// Nominal circumference, m.
    pub nominal_circumference_m: f64,
    /// One entry per stream present.
    pub streams: Vec<StreamSummary>,
    /// Stretches without GNSS (see the module rules); empty without GNSS.
    pub gnss_outages: Vec<GapSummary>,
    /// Threshold used for the outages, s.
    pub gnss_outage_threshold_s: Option<f64>,
    /// True when the drive has truth parameters (`truth.toml`).
    pub has_truth_params: bool,
    /// Physically impossible or broken values ([`plausibility::findings`]).
    pub findings: Vec<FindingSummary>,
    /// Warnings from loading (filled by [`DriveSummary::with_warnings`]).
    pub warnings: Vec<String>,
}

impl DriveSummary {
    /// The summary with the loading warnings attached.
    pub fn with_warnings(mut self, warnings: &[String]) -> DriveSummary {
        self.warnings = warnings.to_vec();
        self
    }

    /// Summary of a loaded drive, its warnings included.
    pub fn of_loaded(loaded: &LoadedDrive) -> DriveSummary {
        summarize(&loaded.drive).with_warnings(&loaded.warnings)
    }
}

fn stream(name: &str, times: &[f64]) -> StreamSummary {
    let mut intervals: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    let max_interval_s = intervals.iter().copied().reduce(f64::max);
    let med = stats::median(&mut intervals.clone());
    let (gaps, gap_time_s) = match med {
        Some(m) => {
            let long: Vec<f64> = intervals
                .drain(..)
                .filter(|d| *d > GAP_FACTOR * m)
                .collect();
            (long.len(), long.iter().fold(0.0, |a, b| a + b))
        }
        None => (0, 0.0),
    };
    StreamSummary {
        name: name.to_string(),
        samples: times.len(),
        first_s: times.first().copied(),
        last_s: times.last().copied(),
        median_interval_s: med,
        rate_hz: med.filter(|m| *m > 0.0).map(|m| 1.0 / m),
        max_interval_s,
        gaps,
        gap_time_s,
    }
}

fn path_length(points: impl Iterator<Item = (f64, f64)>) -> f64 {
    let mut total = 0.0;
    let mut previous: Option<(f64, f64)> = None;
    for p in points {
        if let Some(q) = previous {
            total += (p.0 - q.0).hypot(p.1 - q.1);
        }
        previous = Some(p);
    }
    total
}

/// Summarise a drive (pure: no I/O).
pub fn summarize(drive: &Drive) -> DriveSummary {
    let wheel_t: Vec<f64> = drive.wheels.samples.iter().map(|s| s.t_s).collect();
    let gnss_t: Option<Vec<f64>> = drive
        .gnss
        .as_ref()
        .map(|g| g.iter().map(|s| s.t_s).collect());
    let streams = stream_summaries(drive, &wheel_t, gnss_t.as_deref());
    let (start_s, end_s) = sensor_span(&streams);
    // The wheels as the calibrator reads them (glitches set aside).
    let vehicle = drive.vehicle.check_plausible();
    let (repaired, repairs) = plausibility::repaired(drive);
    let (gnss_outages, gnss_outage_threshold_s) = match &gnss_t {
        Some(t) => {
            let (outages, threshold) = gnss_outages(t, &wheel_t);
            (outages, Some(threshold))
        }
        None => (Vec::new(), None),
    };
    DriveSummary {
        name: drive.vehicle.name.clone(),
        start_s,
        end_s,
        duration_s: end_s - start_s,
        distance_gnss_m: drive
            .gnss
            .as_ref()
            .map(|g| path_length(g.iter().map(|s| (s.x_m, s.y_m)))),
        distance_wheels_m: wheel_distance(drive, &repaired),
        distance_truth_m: drive
            .truth
            .as_ref()
            .map(|g| path_length(g.iter().map(|s| (s.x_m, s.y_m)))),
        wheel_columns: wheel_columns(drive),
        track_width_m: drive.vehicle.track_width_m,
        nominal_circumference_m: drive.vehicle.nominal_circumference_m,
        streams,
        gnss_outages,
        gnss_outage_threshold_s,
        has_truth_params: drive.truth_params.is_some(),
        findings: vehicle
            .err()
            .map(|e| FindingSummary {
                severity: Severity::Error,
                message: format!("vehicle.toml: {e}; the calibrator and the odometry refuse it"),
            })
            .into_iter()
            // What plausibility::findings gives, without repairing twice.
            .chain(
                repairs
                    .into_iter()
                    .chain(plausibility::check(&repaired))
                    .map(|f| f.summary()),
            )
            .collect(),
        warnings: Vec::new(),
    }
}

/// One summary per stream the drive has: the wheels (times `wheel_t`),
/// GNSS (`gnss_t`), IMU, heading and truth.
fn stream_summaries(drive: &Drive, wheel_t: &[f64], gnss_t: Option<&[f64]>) -> Vec<StreamSummary> {
    let imu_t: Option<Vec<f64>> = drive
        .imu
        .as_ref()
        .map(|g| g.iter().map(|s| s.t_s).collect());
    let heading_t: Option<Vec<f64>> = drive
        .heading
        .as_ref()
        .map(|g| g.iter().map(|s| s.t_s).collect());
    let truth_t: Option<Vec<f64>> = drive
        .truth
        .as_ref()
        .map(|g| g.iter().map(|s| s.t_s).collect());
    let mut streams = vec![stream("wheels", wheel_t)];
    for (name, t) in [
        ("gnss", gnss_t),
        ("imu", imu_t.as_deref()),
        ("heading", heading_t.as_deref()),
        ("truth", truth_t.as_deref()),
    ] {
        if let Some(t) = t {
            streams.push(stream(name, t));
        }
    }
    streams
}

/// The first and last time of any sensor stream (the truth is none), s.
fn sensor_span(streams: &[StreamSummary]) -> (f64, f64) {
    let sensor = streams.iter().filter(|s| s.name != "truth");
    let start_s = sensor
        .clone()
        .filter_map(|s| s.first_s)
        .reduce(f64::min)
        .unwrap_or(0.0);
    let end_s = sensor
        .filter_map(|s| s.last_s)
        .reduce(f64::max)
        .unwrap_or(0.0);
    (start_s, end_s)
}

/// The distance of the rear wheels' mean of the `repaired` drive at the
/// nominal circumference, m; none from a circumference that is not
/// positive.
fn wheel_distance(drive: &Drive, repaired: &Drive) -> Option<f64> {
    let c = drive.vehicle.nominal_circumference_m;
    let wheel_revs = (c.is_finite() && c > 0.0)
        .then(|| repaired.wheel_revolutions().ok())
        .flatten();
    wheel_revs.map(|revs| {
        let mut total = 0.0;
        let mut previous: Option<f64> = None;
        for r in revs {
            let mean = 0.5 * (r.rl + r.rr);
            if let Some(p) = previous {
                total += (mean - p).abs();
            }
            previous = Some(mean);
        }
        total * drive.vehicle.nominal_circumference_m
    })
}

/// The GNSS outages of fixes at times `t` over the wheels' span (`wheel_t`):
/// gaps longer than the threshold (a multiple of the median interval, at
/// least [`GNSS_OUTAGE_MIN_S`]), also before the first fix and after the
/// last; and the threshold, s.
fn gnss_outages(t: &[f64], wheel_t: &[f64]) -> (Vec<GapSummary>, f64) {
    let gnss_summary = stream("gnss", t);
    let threshold = gnss_summary
        .median_interval_s
        .map_or(GNSS_OUTAGE_MIN_S, |m| {
            (GAP_FACTOR * m).max(GNSS_OUTAGE_MIN_S)
        });
    let mut gnss_outages = Vec::new();
    let mut push = |a: f64, b: f64| {
        if b - a > threshold {
            gnss_outages.push(GapSummary {
                start_s: a,
                end_s: b,
                duration_s: b - a,
            });
        }
    };
    match (t.first(), t.last(), wheel_t.first(), wheel_t.last()) {
        (Some(&f), Some(&l), Some(&ws), Some(&we)) => {
            push(ws, f);
            for w in t.windows(2) {
                push(w[0], w[1]);
            }
            push(l, we);
        }
        (Some(_), Some(_), _, _) => t.windows(2).for_each(|w| push(w[0], w[1])),
        // No fix at all: the whole drive is one outage.
        _ => {
            if let (Some(&ws), Some(&we)) = (wheel_t.first(), wheel_t.last()) {
                gnss_outages.push(GapSummary {
                    start_s: ws,
                    end_s: we,
                    duration_s: we - ws,
                });
            }
        }
    }
    (gnss_outages, threshold)
}

/// The wheel columns, as `wheels.csv` names them.
fn wheel_columns(drive: &Drive) -> Vec<String> {
    Wheel::ALL
        .iter()
        .filter_map(|&w| {
            drive
                .wheels
                .units
                .of(w)
                .map(|u| format!("{}_{}", w.prefix(), u.suffix()))
        })
        .collect()
}

fn opt(v: Option<f64>, decimals: usize) -> String {
    v.map_or("-".to_string(), |x| format!("{x:.decimals$}"))
}

impl fmt::Display for DriveSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "vehicle:   {}",
            self.name.as_deref().unwrap_or("(unnamed)")
        )?;
        writeln!(
            f,
            "           track {} m, nominal circumference {} m, wheels: {}",
            self.track_width_m,
            self.nominal_circumference_m,
            self.wheel_columns.join(", ")
        )?;
        writeln!(
            f,
            "duration:  {:.1} s (t = {:.3} .. {:.3} s)",
            self.duration_s, self.start_s, self.end_s
        )?;
        let km = |d: Option<f64>| d.map_or("-".to_string(), |m| format!("{:.3} km", m / 1000.0));
        writeln!(
            f,
            "distance:  GNSS {}, wheels {} (rear mean x nominal circumference), truth {}",
            km(self.distance_gnss_m),
            km(self.distance_wheels_m),
            km(self.distance_truth_m)
        )?;
        if self.has_truth_params {
            writeln!(f, "truth.toml: present")?;
        }
        writeln!(f)?;
        writeln!(
            f,
            "{:<8} {:>8} {:>10} {:>10} {:>9} {:>11} {:>9} {:>5} {:>8}",
            "stream",
            "samples",
            "first_s",
            "last_s",
            "rate_Hz",
            "median_dt_s",
            "max_dt_s",
            "gaps",
            "gap_s"
        )?;
        for s in &self.streams {
            writeln!(
                f,
                "{:<8} {:>8} {:>10} {:>10} {:>9} {:>11} {:>9} {:>5} {:>8.2}",
                s.name,
                s.samples,
                opt(s.first_s, 3),
                opt(s.last_s, 3),
                opt(s.rate_hz, 1),
                opt(s.median_interval_s, 4),
                opt(s.max_interval_s, 3),
                s.gaps,
                s.gap_time_s
            )?;
        }
        writeln!(
            f,
            "(a gap is an interval longer than {GAP_FACTOR} x the stream's median interval)"
        )?;
        writeln!(f)?;
        match self.gnss_outage_threshold_s {
            None => writeln!(f, "GNSS outages: no GNSS in this drive")?,
            Some(th) => {
                writeln!(
                    f,
                    "GNSS outages (no fix for more than {th:.2} s = max({GNSS_OUTAGE_MIN_S} s, {GAP_FACTOR} x median interval)): {}",
                    self.gnss_outages.len()
                )?;
                for g in &self.gnss_outages {
                    writeln!(
                        f,
                        "  {:>10.3} .. {:>10.3} s  ({:.2} s)",
                        g.start_s, g.end_s, g.duration_s
                    )?;
                }
            }
        }
        writeln!(f)?;
        if self.findings.is_empty() {
            writeln!(f, "plausibility: nothing physically impossible found")?;
        } else {
            writeln!(f, "plausibility ({}):", self.findings.len())?;
            for p in &self.findings {
                let what = match p.severity {
                    Severity::Error => "error (the calibrator refuses this drive)",
                    Severity::Warning => "warning",
                };
                writeln!(f, "  {what}: {}", p.message)?;
            }
        }
        if !self.warnings.is_empty() {
            writeln!(f)?;
            writeln!(f, "warnings ({}):", self.warnings.len())?;
            for w in &self.warnings {
                writeln!(f, "  {w}")?;
            }
        }
        Ok(())
    }
}
