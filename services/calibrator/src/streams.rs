//! The pure builders of the stages' arrays from a drive's time-stamped
//! streams (shared by the stages): the GNSS fixes, the absolute headings,
//! the gyro integral at the wheel times on a shifted IMU clock, the
//! findings' warnings and the streams' ends. The check stage
//! ([`crate::check`]) runs [`timed`] on the drive as given; the clocks
//! stage ([`crate::clocks`]) runs [`series`] once the IMU's clock is known,
//! and both again on a drive it re-stamped for a clock drift. Every
//! skipped value is listed in a warning.

use crate::config::{CalibrationConfig, TrackWidthMode};
use crate::error::CalibrationError;
use crate::series::{Fix, Series};
use crate::warnings::{Warning, WarningCode};
use drive_io::plausibility::{self, Finding};
use interfaces::drive::{Drive, HeadingSample};

/// The rear wheels as arrays (see [`crate::check`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Wheels {
    /// Wheel sample times, s.
    pub t: Vec<f64>,
    /// Rear-left revolutions since the previous sample (0 at a piece start).
    pub dn_rl: Vec<f64>,
    /// Rear-right revolutions since the previous sample (0 at a piece start).
    pub dn_rr: Vec<f64>,
    /// Indices where a continuous piece of wheel data starts (0 first).
    pub piece_starts: Vec<usize>,
    /// Median wheel sample interval, s.
    pub wheel_dt: f64,
    /// Offsets subtracted from rate-type wheel channels (rl, rr in the
    /// channel's unit) and the standstill seconds they come from.
    pub wheel_offsets: Option<(f64, f64, f64)>,
    /// Standstill intervals (start, end), s, at least 1 s long.
    pub standstill: Vec<(f64, f64)>,
    /// Lateral acceleration `v omega` from the wheels with the nominal
    /// values, averaged over 0.5 s, m/s^2.
    pub lateral_accel: Vec<f32>,
}

/// What the time-stamped streams of a drive give before any clock is
/// known: the plausibility findings and the GNSS fixes.
#[derive(Debug, Clone, PartialEq)]
pub struct Timed {
    /// The findings of [`plausibility::check`] on the drive.
    pub findings: Vec<Finding>,
    /// Finite GNSS fixes in time order.
    pub fixes: Vec<Fix>,
}

/// The checks of `drive`'s time-stamped streams against the wheels `w`:
/// the findings, the GNSS fixes (refused when missing or too few), an
/// implausible finding and a GNSS that does not overlap the wheels refused.
pub fn timed(
    drive: &Drive,
    w: &Wheels,
    warnings: &mut Vec<Warning>,
) -> Result<Timed, CalibrationError> {
    let findings = plausibility::check(drive);
    let fixes = gnss(drive, warnings)?;
    if let Some(f) = findings.iter().find(|f| f.is_error()) {
        return Err(CalibrationError::ImplausibleInput(f.clone()));
    }
    if let (Some(&w0), Some(&w1), Some(g0), Some(g1)) =
        (w.t.first(), w.t.last(), fixes.first(), fixes.last())
    {
        if g1.t < w0 || g0.t > w1 {
            return Err(CalibrationError::NoOverlap {
                wheel_start: w0,
                wheel_end: w1,
                gnss_start: g0.t,
                gnss_end: g1.t,
            });
        }
    }
    Ok(Timed { findings, fixes })
}

/// True when the findings say the gyro is dead for the whole drive (it
/// then has no clock to find).
pub fn gyro_dead(findings: &[Finding]) -> bool {
    findings.iter().any(|f| {
        matches!(
            f,
            Finding::ImuStuck {
                field: "gz_rad_s",
                whole_drive: true,
                ..
            }
        )
    })
}

/// The [`Series`] of `drive` once the IMU's clock against the wheels is
/// known (`imu_shift_s`, subtracted from the IMU times: the IMU's offset
/// where it is applied, else 0): the gyro integral at the wheel times, the findings' warnings,
/// the headings and the streams' ends.
pub fn series(
    drive: &Drive,
    config: &CalibrationConfig,
    w: &Wheels,
    timed: &Timed,
    imu_shift_s: f64,
    warnings: &mut Vec<Warning>,
) -> Series {
    let vehicle = &drive.vehicle;
    let t = &w.t;
    let findings = &timed.findings[..];
    let (mut gyro, mut has_accel, imu_end) = imu(drive, t, imu_shift_s, warnings);
    act_on_findings(
        findings,
        config,
        t,
        imu_shift_s,
        &mut gyro,
        &mut has_accel,
        warnings,
    );
    let headings = heading(drive, warnings);
    check_stream_ends(t, &timed.fixes, imu_end, warnings);
    Series {
        t: w.t.clone(),
        dn_rl: w.dn_rl.clone(),
        dn_rr: w.dn_rr.clone(),
        piece_starts: w.piece_starts.clone(),
        wheel_dt: w.wheel_dt,
        fixes: timed.fixes.clone(),
        gyro,
        has_accel,
        headings,
        lever_arm: [
            vehicle.gnss.antenna_x_m.unwrap_or(0.0),
            vehicle.gnss.antenna_y_m.unwrap_or(0.0),
        ],
        lever_arm_given: [
            vehicle.gnss.antenna_x_m.is_some(),
            vehicle.gnss.antenna_y_m.is_some(),
        ],
        nominal_c: vehicle.nominal_circumference_m,
        track: vehicle.track_width_m,
        standstill: w.standstill.clone(),
        lateral_accel: w.lateral_accel.clone(),
        wheel_offsets: w.wheel_offsets,
        imu_shift_s,
    }
}

/// Act on the plausibility findings: a stuck gyro dropped (the whole drive)
/// or blanked (its stretch), stuck accelerations not used; each finding a
/// warning with what was done.
fn act_on_findings(
    findings: &[Finding],
    config: &CalibrationConfig,
    t: &[f64],
    imu_shift_s: f64,
    gyro: &mut Option<Vec<f64>>,
    has_accel: &mut bool,
    warnings: &mut Vec<Warning>,
) {
    for f in findings {
        match f {
            Finding::ImuStuck {
                field,
                t_start_s,
                t_end_s,
                whole_drive,
                ..
            } => {
                let what = match (*field, *whole_drive) {
                    ("gz_rad_s", true) if gyro.is_some() => {
                        *gyro = None;
                        "the gyro is dropped: no gyro bias or scale is fitted and no gyro heading is used"
                            .to_string()
                    }
                    ("gz_rad_s", _) => {
                        if let Some(g) = gyro.as_mut() {
                            for (gk, tk) in g.iter_mut().zip(t) {
                                if *tk > *t_start_s - imu_shift_s && *tk < *t_end_s - imu_shift_s {
                                    *gk = f64::NAN;
                                }
                            }
                        }
                        format!("the gyro is not used from t = {t_start_s:.2} to {t_end_s:.2} s")
                    }
                    _ if *has_accel => {
                        *has_accel = false;
                        "the IMU accelerations are not used".to_string()
                    }
                    _ => "not used".to_string(),
                };
                warnings.push(Warning::new(WarningCode::ImuStuck, format!("{f}; {what}")));
            }
            Finding::WheelStuck { .. } => {
                warnings.push(Warning::new(WarningCode::WheelStuck, f.to_string()));
            }
            Finding::TrackWidthContradicted { .. } => {
                let what = match config.track_width {
                    TrackWidthMode::Fixed => {
                        "--track-width fixed keeps vehicle.toml's value: the circumferences and the gyro scale \
                         absorb the difference"
                    }
                    TrackWidthMode::Estimate => "the track width is fitted (--track-width estimate)",
                    TrackWidthMode::Auto => {
                        "correct vehicle.toml, or run with --track-width estimate (auto does not believe a fitted \
                         track this far from vehicle.toml's)"
                    }
                };
                warnings.push(Warning::new(
                    WarningCode::TrackWidthContradicted,
                    format!("{f}; {what}"),
                ));
            }
            Finding::WheelPause { .. } => {
                // A pause is always longer than the piece-break threshold of `wheels`.
                warnings.push(Warning::new(
                    WarningCode::WheelPause,
                    format!(
                        "{f}; the wheels are not integrated across it: the drive is cut there, the EKF and the \
                         dead reckoning restart on the reference after it and the batch segments end at it"
                    ),
                ));
            }
            _ => {}
        }
    }
}

pub(crate) fn gnss(
    drive: &Drive,
    warnings: &mut Vec<Warning>,
) -> Result<Vec<Fix>, CalibrationError> {
    let Some(rows) = drive.gnss.as_ref().filter(|g| !g.is_empty()) else {
        return Err(CalibrationError::NoGnss);
    };
    let mut fixes = Vec::with_capacity(rows.len());
    let mut skipped = 0usize;
    let mut first_bad = None;
    let mut bad_sigma = 0usize;
    for r in rows {
        if !(r.t_s.is_finite() && r.x_m.is_finite() && r.y_m.is_finite()) {
            skipped += 1;
            first_bad.get_or_insert(r.t_s);
            continue;
        }
        let sigma = match r.sigma_m {
            Some(s) if s.is_finite() && s > 0.0 => Some(s),
            Some(_) => {
                bad_sigma += 1;
                None
            }
            None => None,
        };
        if fixes.last().is_some_and(|f: &Fix| r.t_s <= f.t) {
            skipped += 1;
            first_bad.get_or_insert(r.t_s);
            continue;
        }
        fixes.push(Fix {
            t: r.t_s,
            x: r.x_m,
            y: r.y_m,
            sigma,
        });
    }
    if skipped > 0 {
        warnings.push(Warning::new(
            WarningCode::NonFiniteSamples,
            format!(
                "gnss: {skipped} of {} fixes have a non-finite time or position (or break the time order) and were skipped (first at t = {:.3} s)",
                rows.len(),
                first_bad.unwrap_or(f64::NAN)
            ),
        ));
    }
    if bad_sigma > 0 {
        warnings.push(Warning::new(
            WarningCode::NonFiniteSamples,
            format!("gnss: {bad_sigma} fixes have a non-finite or non-positive sigma_m; the estimated GNSS noise is used for them"),
        ));
    }
    if fixes.len() < 10 {
        return Err(CalibrationError::TooFewGnss {
            usable: fixes.len(),
            total: rows.len(),
            detail: if skipped > 0 {
                format!(", {skipped} non-finite")
            } else {
                String::new()
            },
            needed: 10,
        });
    }
    Ok(fixes)
}

/// The gyro integral at the wheel times `t`, whether the IMU has
/// accelerations, and the IMU's last time.
fn imu(
    drive: &Drive,
    t: &[f64],
    shift: f64,
    warnings: &mut Vec<Warning>,
) -> (Option<Vec<f64>>, bool, Option<f64>) {
    let Some(rows) = drive.imu.as_ref().filter(|r| !r.is_empty()) else {
        warnings.push(Warning::new(
            WarningCode::NoImu,
            "imu: the drive has no IMU: the heading reference comes from the GNSS course alone, \
             side-slip and gyro calibration are not available"
                .to_string(),
        ));
        return (None, false, None);
    };
    let threshold = imu_gap_threshold(rows);
    let g = GyroAngle::integrate(rows, t, shift, threshold);
    if g.skipped > 0 {
        warnings.push(Warning::new(
            WarningCode::NonFiniteSamples,
            format!(
                "imu: {} of {} rows have a non-finite time or gz_rad_s (or break the time order) and were skipped (first at t = {:.3} s)",
                g.skipped,
                rows.len(),
                g.first_bad.unwrap_or(f64::NAN)
            ),
        ));
    }
    let used = g.used;
    if used < 10 {
        warnings.push(Warning::new(
            WarningCode::NoImu,
            format!("imu: only {used} usable yaw-rate samples: the IMU is ignored"),
        ));
        return (None, false, None);
    }
    let (gaps, longest) = (g.gaps, g.longest);
    if gaps > 0 {
        warnings.push(Warning::new(
            WarningCode::StreamGap,
            format!(
                "imu: the stream pauses {gaps} time(s) for more than {threshold:.2} s (longest {:.1} s at t = {:.2} s); \
                 the gyro is not used across the pauses",
                longest.0, longest.1
            ),
        ));
    }
    (Some(g.angle), g.has_accel, g.last_t)
}

/// Whether an IMU row has a finite time and yaw rate.
fn imu_usable(r: &&interfaces::drive::ImuSample) -> bool {
    r.t_s.is_finite() && r.gz_rad_s.is_finite()
}

/// The IMU pause threshold: ten median intervals of the first usable rows,
/// at least 0.5 s.
fn imu_gap_threshold(rows: &[interfaces::drive::ImuSample]) -> f64 {
    let mut dts: Vec<f64> = rows
        .iter()
        .filter(imu_usable)
        .take(10_000)
        .map(|r| r.t_s)
        .collect::<Vec<_>>()
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    (10.0 * stats::upper_median(&mut dts).unwrap_or(0.01)).max(0.5)
}

/// The gyro's cumulative yaw angle at the wheel times, with what the
/// integration skipped and found.
struct GyroAngle {
    /// Per wheel time, rad (NaN where not covered or across a pause).
    angle: Vec<f64>,
    /// Rows skipped (non-finite, or out of time order), and the first's time.
    skipped: usize,
    first_bad: Option<f64>,
    /// Rows used.
    used: usize,
    /// Pauses longer than the threshold, and the longest with its start.
    gaps: usize,
    longest: (f64, f64),
    /// Whether any used row has both horizontal accelerations.
    has_accel: bool,
    /// The last used row's time on the wheels' clock, s.
    last_t: Option<f64>,
}

impl GyroAngle {
    /// Integrate the yaw rate (trapezoid) over the rows, their times
    /// shifted by `shift` onto the wheels' clock, and interpolate it at the
    /// wheel times `t`.
    fn integrate(
        rows: &[interfaces::drive::ImuSample],
        t: &[f64],
        shift: f64,
        threshold: f64,
    ) -> GyroAngle {
        let usable = imu_usable;
        let mut out = Vec::with_capacity(t.len());
        let mut k = 0usize;
        let mut prev: Option<(f64, f64)> = None; // (time, rate)
        let mut acc = 0.0;
        let mut skipped = 0usize;
        let mut first_bad = None;
        let mut used = 0usize;
        let mut gaps = 0usize;
        let mut longest = (0.0f64, 0.0f64);
        let mut has_accel = false;
        let mut last_t = None;
        for r in rows {
            // The IMU time on the wheels' clock.
            let rt = r.t_s - shift;
            if !usable(&r) || prev.is_some_and(|(t0, _)| rt <= t0) {
                skipped += 1;
                first_bad.get_or_insert(r.t_s);
                continue;
            }
            has_accel |=
                r.ax_m_s2.is_some_and(f64::is_finite) && r.ay_m_s2.is_some_and(f64::is_finite);
            used += 1;
            last_t = Some(rt);
            match prev {
                None => {
                    // Wheel times before the IMU starts are not covered.
                    while k < t.len() && t[k] < rt {
                        out.push(f64::NAN);
                        k += 1;
                    }
                    if k < t.len() && t[k] == rt {
                        out.push(0.0);
                        k += 1;
                    }
                }
                Some((t0, w0)) => {
                    let dt = rt - t0;
                    let next = acc + 0.5 * (w0 + r.gz_rad_s) * dt;
                    let pause = dt > threshold;
                    if pause {
                        gaps += 1;
                        if dt > longest.0 {
                            longest = (dt, t0);
                        }
                    }
                    while k < t.len() && t[k] <= rt {
                        if pause && t[k] > t0 && t[k] < rt {
                            out.push(f64::NAN);
                        } else {
                            let f = (t[k] - t0) / dt;
                            out.push(acc + f * (next - acc));
                        }
                        k += 1;
                    }
                    acc = next;
                }
            }
            prev = Some((rt, r.gz_rad_s));
        }
        out.resize(t.len(), f64::NAN);
        GyroAngle {
            angle: out,
            skipped,
            first_bad,
            used,
            gaps,
            longest,
            has_accel,
            last_t,
        }
    }
}

fn heading(drive: &Drive, warnings: &mut Vec<Warning>) -> Vec<HeadingSample> {
    let Some(rows) = drive.heading.as_ref() else {
        return Vec::new();
    };
    let mut out: Vec<HeadingSample> = Vec::with_capacity(rows.len());
    let mut skipped = 0;
    for r in rows {
        let ok = r.t_s.is_finite()
            && r.yaw_rad.is_finite()
            && r.sigma_rad.is_none_or(|s| s.is_finite() && s > 0.0)
            && out.last().is_none_or(|l| r.t_s > l.t_s);
        if ok {
            out.push(*r);
        } else {
            skipped += 1;
        }
    }
    if skipped > 0 {
        warnings.push(Warning::new(
            WarningCode::NonFiniteSamples,
            format!(
                "heading: {skipped} of {} rows are non-finite or out of order and were skipped",
                rows.len()
            ),
        ));
    }
    out
}

fn check_stream_ends(t: &[f64], fixes: &[Fix], imu_end: Option<f64>, warnings: &mut Vec<Warning>) {
    let (Some(&w0), Some(&w1)) = (t.first(), t.last()) else {
        return;
    };
    let (Some(g0), Some(g1)) = (fixes.first(), fixes.last()) else {
        return;
    };
    let span = (w1 - w0).max(1e-9);
    let slack = (0.02 * span).max(5.0);
    if g1.t < w1 - slack {
        warnings.push(Warning::new(
            WarningCode::StreamStops,
            format!(
                "gnss stops at t = {:.2} s, {:.1} s before the wheel data ends (t = {:.2} s): \
                 the last {:.0} % of the wheel data has no reference",
                g1.t,
                w1 - g1.t,
                w1,
                100.0 * (w1 - g1.t.max(w0)) / span
            ),
        ));
    }
    if g0.t > w0 + slack {
        warnings.push(Warning::new(
            WarningCode::StreamStops,
            format!(
                "gnss starts at t = {:.2} s, {:.1} s after the wheel data (t = {:.2} s): the start has no reference",
                g0.t,
                g0.t - w0,
                w0
            ),
        ));
    }
    if w1 < g1.t - slack {
        warnings.push(Warning::new(
            WarningCode::StreamStops,
            format!(
                "wheels stop at t = {:.2} s, {:.1} s before the GNSS ends (t = {:.2} s): only the overlap is calibrated",
                w1,
                g1.t - w1,
                g1.t
            ),
        ));
    }
    if w0 > g0.t + slack {
        warnings.push(Warning::new(
            WarningCode::StreamStops,
            format!(
                "wheels start at t = {:.2} s, {:.1} s after the GNSS (t = {:.2} s): only the overlap is calibrated",
                w0,
                w0 - g0.t,
                g0.t
            ),
        ));
    }
    {
        if let Some(i1) = imu_end {
            if i1 < w1 - slack {
                warnings.push(Warning::new(
                    WarningCode::StreamStops,
                    format!(
                        "imu stops at t = {i1:.2} s, {:.1} s before the wheel data ends: no gyro after it",
                        w1 - i1
                    ),
                ));
            }
        }
    }
}
