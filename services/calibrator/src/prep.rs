//! Input checks and conversion: the drive turned into the compact series the
//! layers work on, with every skipped value listed in a warning.
//!
//! - Wheels: rows with a non-finite rear value are skipped (warning), the rest
//!   become revolution increments per wheel sample; a gap in the wheel stream
//!   breaks it into pieces (the models restart after a break).
//! - GNSS: non-finite rows skipped (warning). No GNSS is an error.
//! - IMU: the yaw rate is integrated to a cumulative angle (gaps noted), the
//!   accelerations kept when both horizontal axes are given.
//! - Streams that stop early or pause are named in warnings.

use crate::report::{Warning, WarningCode};
use crate::{CalibrationConfig, CalibrationError};
use interfaces::drive::{Drive, HeadingSample, WheelSeries};

/// A GNSS fix in local ENU (antenna position).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fix {
    /// Time, s.
    pub t: f64,
    /// East, m.
    pub x: f64,
    /// North, m.
    pub y: f64,
    /// 1-sigma from the data, when given.
    pub sigma: Option<f64>,
}

/// The yaw-rate gyro as a cumulative angle.
#[derive(Debug, Clone, PartialEq)]
pub struct Gyro {
    /// Sample times, s.
    pub t: Vec<f64>,
    /// Trapezoidal integral of the yaw rate from the first sample, rad.
    pub cum: Vec<f64>,
    /// Stretches (start, end) without IMU data longer than the gap threshold;
    /// the integral across them is not trusted.
    pub gaps: Vec<(f64, f64)>,
}

impl Gyro {
    /// The cumulative angle at `t`, `None` outside the data or in a gap.
    pub fn cum_at(&self, t: f64) -> Option<f64> {
        let n = self.t.len();
        if n < 2 || !(t >= self.t[0] && t <= self.t[n - 1]) {
            return None;
        }
        if self.gaps.iter().any(|&(a, b)| t > a && t < b) {
            return None;
        }
        let i = self.t.partition_point(|&s| s <= t).clamp(1, n - 1);
        let (t0, t1) = (self.t[i - 1], self.t[i]);
        let f = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
        Some(self.cum[i - 1] + f * (self.cum[i] - self.cum[i - 1]))
    }

    /// Mean yaw rate between `t0` and `t1`, `None` when not covered.
    pub fn mean_rate(&self, t0: f64, t1: f64) -> Option<f64> {
        if t1 <= t0 || self.gaps.iter().any(|&(a, b)| a < t1 && b > t0) {
            return None;
        }
        Some((self.cum_at(t1)? - self.cum_at(t0)?) / (t1 - t0))
    }
}

/// A horizontal body-frame acceleration sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Accel {
    /// Time, s.
    pub t: f64,
    /// Longitudinal, m/s^2.
    pub ax: f64,
    /// Lateral, m/s^2.
    pub ay: f64,
}

/// The drive in the form the layers use.
#[derive(Debug, Clone, PartialEq)]
pub struct Prepared {
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
    /// Finite GNSS fixes in time order.
    pub fixes: Vec<Fix>,
    /// The yaw-rate gyro, when the drive has an IMU.
    pub gyro: Option<Gyro>,
    /// The gyro's cumulative angle at each wheel time (NaN where not covered).
    pub gyro_at_wheel: Option<Vec<f64>>,
    /// Horizontal accelerations (empty when the IMU has none).
    pub accel: Vec<Accel>,
    /// Finite absolute headings.
    pub headings: Vec<HeadingSample>,
    /// GNSS antenna position in the body frame (x forward, y left) from the rear-axle centre, m.
    pub lever_arm: [f64; 2],
    /// Nominal circumference, m.
    pub nominal_c: f64,
    /// Nominal rear track, m.
    pub track: f64,
    /// Standstill intervals (start, end), s, at least 1 s long.
    pub standstill: Vec<(f64, f64)>,
}

impl Prepared {
    /// True when sample `k` starts a piece (its increment is not a motion).
    pub fn is_piece_start(&self, k: usize) -> bool {
        self.piece_starts.binary_search(&k).is_ok()
    }

    /// Number of wheel samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when there is no wheel sample.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    Some(values[values.len() / 2])
}

/// Check and convert `drive`. Skipped values go into `warnings`.
pub fn prepare(
    drive: &Drive,
    config: &CalibrationConfig,
    warnings: &mut Vec<Warning>,
) -> Result<Prepared, CalibrationError> {
    let _ = config;
    let vehicle = &drive.vehicle;
    if !(vehicle.track_width_m.is_finite() && vehicle.track_width_m > 0.1 && vehicle.track_width_m < 5.0) {
        return Err(CalibrationError::BadVehicle(format!(
            "track_width_m = {} is not a plausible rear track (0.1..5 m)",
            vehicle.track_width_m
        )));
    }
    if !(vehicle.nominal_circumference_m.is_finite()
        && vehicle.nominal_circumference_m > 0.1
        && vehicle.nominal_circumference_m < 10.0)
    {
        return Err(CalibrationError::BadVehicle(format!(
            "nominal_circumference_m = {} is not a plausible circumference (0.1..10 m)",
            vehicle.nominal_circumference_m
        )));
    }
    let lever_arm = [
        vehicle.gnss.antenna_x_m.unwrap_or(0.0),
        vehicle.gnss.antenna_y_m.unwrap_or(0.0),
    ];
    if !lever_arm.iter().all(|v| v.is_finite() && v.abs() < 20.0) {
        return Err(CalibrationError::BadVehicle(format!(
            "[gnss] antenna position ({}, {}) m is not plausible",
            lever_arm[0], lever_arm[1]
        )));
    }

    let (t, dn_rl, dn_rr, piece_starts, wheel_dt) = wheels(drive, warnings)?;
    let fixes = gnss(drive, warnings)?;
    let (gyro, accel) = imu(drive, warnings);
    let headings = heading(drive, warnings);
    check_stream_ends(&t, &fixes, gyro.as_ref(), warnings);

    let gyro_at_wheel = gyro.as_ref().map(|g| {
        let mut out = Vec::with_capacity(t.len());
        let mut gap = 0usize;
        let mut i = 1usize;
        let n = g.t.len();
        for &tk in &t {
            while gap < g.gaps.len() && g.gaps[gap].1 <= tk {
                gap += 1;
            }
            let in_gap = gap < g.gaps.len() && tk > g.gaps[gap].0 && tk < g.gaps[gap].1;
            if n < 2 || tk < g.t[0] || tk > g.t[n - 1] || in_gap {
                out.push(f64::NAN);
                continue;
            }
            while i < n - 1 && g.t[i] < tk {
                i += 1;
            }
            let (t0, t1) = (g.t[i - 1], g.t[i]);
            let f = if t1 > t0 { ((tk - t0) / (t1 - t0)).clamp(0.0, 1.0) } else { 0.0 };
            out.push(g.cum[i - 1] + f * (g.cum[i] - g.cum[i - 1]));
        }
        out
    });

    let standstill = standstill_intervals(&t, &dn_rl, &dn_rr, vehicle.nominal_circumference_m);

    Ok(Prepared {
        t,
        dn_rl,
        dn_rr,
        piece_starts,
        wheel_dt,
        fixes,
        gyro,
        gyro_at_wheel,
        accel,
        headings,
        lever_arm,
        nominal_c: vehicle.nominal_circumference_m,
        track: vehicle.track_width_m,
        standstill,
    })
}

type WheelArrays = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<usize>, f64);

fn wheels(drive: &Drive, warnings: &mut Vec<Warning>) -> Result<WheelArrays, CalibrationError> {
    let samples = &drive.wheels.samples;
    if samples.is_empty() {
        return Err(CalibrationError::NoWheelData);
    }
    let finite_rl = samples.iter().filter(|s| s.rl.is_finite()).count();
    let finite_rr = samples.iter().filter(|s| s.rr.is_finite()).count();
    if finite_rl == 0 {
        return Err(CalibrationError::WheelChannelEmpty {
            wheel: "rl",
            count: samples.len(),
        });
    }
    if finite_rr == 0 {
        return Err(CalibrationError::WheelChannelEmpty {
            wheel: "rr",
            count: samples.len(),
        });
    }
    let bad: Vec<usize> = samples
        .iter()
        .enumerate()
        .filter(|(_, s)| !(s.rl.is_finite() && s.rr.is_finite() && s.t_s.is_finite()))
        .map(|(i, _)| i)
        .collect();
    // Revolutions from the drive's own conversion; rows with a non-finite rear
    // value are removed first so that a NaN rate cannot poison the integral.
    let revs = if bad.is_empty() {
        drive.wheel_revolutions()?
    } else {
        let first = samples[bad[0]].t_s;
        warnings.push(Warning::new(
            WarningCode::NonFiniteSamples,
            format!(
                "wheels: {} of {} rows have a non-finite rl/rr value and were skipped (first at t = {:.3} s)",
                bad.len(),
                samples.len(),
                first
            ),
        ));
        let clean = Drive {
            vehicle: drive.vehicle.clone(),
            wheels: WheelSeries {
                units: drive.wheels.units,
                samples: samples
                    .iter()
                    .filter(|s| s.rl.is_finite() && s.rr.is_finite() && s.t_s.is_finite())
                    .copied()
                    .collect(),
            },
            gnss: None,
            imu: None,
            heading: None,
            truth: None,
            truth_params: None,
        };
        clean.wheel_revolutions()?
    };
    let n = revs.len();
    let mut dts: Vec<f64> = revs.windows(2).map(|w| w[1].t_s - w[0].t_s).collect();
    let wheel_dt = median(&mut dts).unwrap_or(0.01).max(1e-4);
    let gap_threshold = (10.0 * wheel_dt).max(0.5);

    let mut t = Vec::with_capacity(n);
    let mut dn_rl = Vec::with_capacity(n);
    let mut dn_rr = Vec::with_capacity(n);
    let mut piece_starts = vec![0usize];
    let mut gaps = 0usize;
    let mut longest = (0.0f64, 0.0f64);
    let (mut total_rl, mut total_rr) = (0.0f64, 0.0f64);
    for (k, r) in revs.iter().enumerate() {
        t.push(r.t_s);
        if k == 0 {
            dn_rl.push(0.0);
            dn_rr.push(0.0);
            continue;
        }
        let p = &revs[k - 1];
        let dt = r.t_s - p.t_s;
        let (a, b) = (r.rl - p.rl, r.rr - p.rr);
        if dt > gap_threshold || !(a.is_finite() && b.is_finite()) {
            if dt > gap_threshold {
                gaps += 1;
                if dt > longest.0 {
                    longest = (dt, p.t_s);
                }
            }
            piece_starts.push(k);
            dn_rl.push(0.0);
            dn_rr.push(0.0);
        } else {
            total_rl += a.abs();
            total_rr += b.abs();
            dn_rl.push(a);
            dn_rr.push(b);
        }
    }
    if gaps > 0 {
        warnings.push(Warning::new(
            WarningCode::StreamGap,
            format!(
                "wheels: the stream pauses {gaps} time(s) for more than {gap_threshold:.2} s (longest {:.1} s at t = {:.2} s); \
                 the models restart after each pause",
                longest.0, longest.1
            ),
        ));
    }
    let (big, small, big_name, small_name) = if total_rl >= total_rr {
        (total_rl, total_rr, "rl", "rr")
    } else {
        (total_rr, total_rl, "rr", "rl")
    };
    if big < 2.0 {
        return Err(CalibrationError::TooShort {
            distance_m: big * drive.vehicle.nominal_circumference_m,
            needed_m: 50.0,
        });
    }
    if small < 0.05 * big {
        return Err(CalibrationError::WheelStuck {
            wheel: small_name,
            revs: small,
            other: big_name,
            other_revs: big,
        });
    }
    Ok((t, dn_rl, dn_rr, piece_starts, wheel_dt))
}

fn gnss(drive: &Drive, warnings: &mut Vec<Warning>) -> Result<Vec<Fix>, CalibrationError> {
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

fn imu(drive: &Drive, warnings: &mut Vec<Warning>) -> (Option<Gyro>, Vec<Accel>) {
    let Some(rows) = drive.imu.as_ref().filter(|r| !r.is_empty()) else {
        warnings.push(Warning::new(
            WarningCode::NoImu,
            "imu: the drive has no IMU: the heading reference comes from the GNSS course alone, \
             side-slip and gyro calibration are not available"
                .to_string(),
        ));
        return (None, Vec::new());
    };
    let mut t = Vec::with_capacity(rows.len());
    let mut cum = Vec::with_capacity(rows.len());
    let mut accel = Vec::new();
    let mut skipped = 0usize;
    let mut first_bad = None;
    let mut prev: Option<(f64, f64)> = None;
    let mut acc = 0.0;
    let mut dts = Vec::new();
    for r in rows {
        if !(r.t_s.is_finite() && r.gz_rad_s.is_finite()) {
            skipped += 1;
            first_bad.get_or_insert(r.t_s);
            continue;
        }
        if let Some((t0, w0)) = prev {
            if r.t_s <= t0 {
                skipped += 1;
                first_bad.get_or_insert(r.t_s);
                continue;
            }
            dts.push(r.t_s - t0);
            acc += 0.5 * (w0 + r.gz_rad_s) * (r.t_s - t0);
        }
        prev = Some((r.t_s, r.gz_rad_s));
        t.push(r.t_s);
        cum.push(acc);
        if let (Some(ax), Some(ay)) = (r.ax_m_s2, r.ay_m_s2) {
            if ax.is_finite() && ay.is_finite() {
                accel.push(Accel { t: r.t_s, ax, ay });
            }
        }
    }
    if skipped > 0 {
        warnings.push(Warning::new(
            WarningCode::NonFiniteSamples,
            format!(
                "imu: {skipped} of {} rows have a non-finite time or gz_rad_s and were skipped (first at t = {:.3} s)",
                rows.len(),
                first_bad.unwrap_or(f64::NAN)
            ),
        ));
    }
    if t.len() < 10 {
        warnings.push(Warning::new(
            WarningCode::NoImu,
            format!("imu: only {} usable yaw-rate samples: the IMU is ignored", t.len()),
        ));
        return (None, Vec::new());
    }
    let dt = median(&mut dts).unwrap_or(0.01);
    let threshold = (10.0 * dt).max(0.5);
    let mut gaps = Vec::new();
    for w in t.windows(2) {
        if w[1] - w[0] > threshold {
            gaps.push((w[0], w[1]));
        }
    }
    if let Some(longest) = gaps.iter().copied().max_by(|a, b| (a.1 - a.0).total_cmp(&(b.1 - b.0))) {
        warnings.push(Warning::new(
            WarningCode::StreamGap,
            format!(
                "imu: the stream pauses {} time(s) for more than {threshold:.2} s (longest {:.1} s at t = {:.2} s); \
                 the gyro is not used across the pauses",
                gaps.len(),
                longest.1 - longest.0,
                longest.0
            ),
        ));
    }
    (Some(Gyro { t, cum, gaps }), accel)
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
            format!("heading: {skipped} of {} rows are non-finite or out of order and were skipped", rows.len()),
        ));
    }
    out
}

fn check_stream_ends(t: &[f64], fixes: &[Fix], gyro: Option<&Gyro>, warnings: &mut Vec<Warning>) {
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
    if let Some(g) = gyro {
        if let Some(&i1) = g.t.last() {
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

/// Standstill intervals: wheel speed below 0.05 m/s for at least 1 s.
fn standstill_intervals(t: &[f64], dn_rl: &[f64], dn_rr: &[f64], c: f64) -> Vec<(f64, f64)> {
    let n = t.len();
    let mut out = Vec::new();
    if n < 3 {
        return out;
    }
    // Speed over a window of about 0.5 s, from the cumulative distance.
    let mut s = Vec::with_capacity(n);
    let mut acc = 0.0;
    for k in 0..n {
        acc += 0.5 * (dn_rl[k] + dn_rr[k]) * c;
        s.push(acc);
    }
    let mut start: Option<f64> = None;
    let mut j0 = 0usize;
    let mut j1 = 0usize;
    for k in 0..n {
        while t[k] - t[j0] > 0.25 {
            j0 += 1;
        }
        while j1 + 1 < n && t[j1 + 1] - t[k] <= 0.25 {
            j1 += 1;
        }
        let still = if t[j1] > t[j0] {
            ((s[j1] - s[j0]) / (t[j1] - t[j0])).abs() < 0.05
        } else {
            false
        };
        match (still, start) {
            (true, None) => start = Some(t[k]),
            (false, Some(a)) => {
                if t[k - 1] - a >= 1.0 {
                    out.push((a, t[k - 1]));
                }
                start = None;
            }
            _ => {}
        }
    }
    if let Some(a) = start {
        if t[n - 1] - a >= 1.0 {
            out.push((a, t[n - 1]));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gyro_interpolates_and_refuses_gaps() {
        let g = Gyro {
            t: vec![0.0, 1.0, 2.0, 10.0, 11.0],
            cum: vec![0.0, 1.0, 2.0, 3.0, 4.0],
            gaps: vec![(2.0, 10.0)],
        };
        assert!((g.cum_at(0.5).unwrap_or(f64::NAN) - 0.5).abs() < 1e-12);
        assert!(g.cum_at(5.0).is_none());
        assert!(g.cum_at(12.0).is_none());
        assert!(g.mean_rate(1.0, 11.0).is_none());
        assert!((g.mean_rate(0.0, 2.0).unwrap_or(f64::NAN) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn standstill_is_found() {
        let t: Vec<f64> = (0..1000).map(|k| k as f64 * 0.01).collect();
        let dn: Vec<f64> = t.iter().map(|&tk| if (3.0..6.0).contains(&tk) { 0.0 } else { 0.01 }).collect();
        let s = standstill_intervals(&t, &dn, &dn, 2.0);
        assert_eq!(s.len(), 1, "{s:?}");
        assert!((s[0].0 - 3.25).abs() < 0.05 && (s[0].1 - 5.75).abs() < 0.05, "{s:?}");
    }
}
