//! Stage 1, the check: [`drive`] checks the drive and turns what does not
//! depend on any stream's clock into arrays ([`Checked`]), with every
//! skipped value listed in a warning. The IMU's arrays wait for its clock
//! (stage 2, [`crate::clocks::align`]), which builds them with the shared
//! builders of [`crate::streams`].
//!
//! - Wheels: rows with a non-finite rear value are skipped (warning), the rest
//!   become revolution increments per wheel sample; a gap in the wheel stream
//!   breaks it into pieces (the models restart after a break).
//! - GNSS: non-finite rows skipped (warning). No GNSS is an error.
//! - IMU: the yaw rate is integrated to a cumulative angle, kept at the wheel
//!   times (NaN across pauses of the IMU stream). The accelerations are not
//!   copied: the reference reads them from the drive.
//! - The IMU clock's offset against the wheels is estimated by the clocks
//!   stage (`crate::clocks`) and, when significant and compensation is on,
//!   subtracted from the IMU time stamps before the gyro is integrated.
//! - Streams that stop early or pause are named in warnings.
//! - Physics ([`drive_io::plausibility`]): wheel tick counters that wrap are
//!   unwrapped (warning); wheel rates beyond any car, reversed or exchanged
//!   wheel signs and a wheel stuck over much of the drive are errors
//!   ([`CalibrationError::ImplausibleInput`]); a gyro that is exactly
//!   constant while the wheels turn is dropped (or not used where stuck),
//!   stuck accelerations likewise, each with a warning saying so. A track
//!   width the wheels and the gyro contradict and a pause of the wheel
//!   stream (far longer than its sample interval) are warnings: the track
//!   can be fitted, and nothing is integrated across a pause (it is a piece
//!   break, see below; the EKF, the dead reckoning and the batch segments
//!   restart on the reference after it).
//!
//! Memory: a 1 h drive at 100 Hz has 360 000 wheel rows; everything here is
//! a handful of `f64` per wheel sample, built in one pass over the drive.
//! The wheel conversion is therefore done here, streaming, with the same
//! rules as [`Drive::wheel_revolutions`] (which materialises 56 bytes per
//! row); a unit test checks that the two agree.

use crate::config::CalibrationConfig;
use crate::error::CalibrationError;
use crate::streams::{self, Timed, Wheels};
use crate::warnings::{Warning, WarningCode};
use drive_io::plausibility::{self, Finding};
use interfaces::drive::{Drive, WheelConversionError, WheelSample, WheelUnit};
use std::borrow::Cow;

/// The checked drive: what stage 1 hands to the clocks stage.
#[derive(Debug, Clone)]
pub struct Checked<'a> {
    /// The drive with its wheel counters unwrapped and impossible wheel
    /// samples set aside (the streams on their own clocks).
    pub drive: Cow<'a, Drive>,
    /// The rear wheels as arrays, standstills and lateral acceleration.
    pub wheels: Wheels,
    /// The findings and the GNSS fixes.
    pub timed: Timed,
    /// The warnings so far.
    pub warnings: Vec<Warning>,
    /// How many of `warnings` come from the wheels and the vehicle alone
    /// (a re-stamp of the other streams keeps them).
    pub wheel_warnings: usize,
}

/// Check `drive` and convert what needs no clock: the vehicle, the
/// repairs, the wheels, the GNSS fixes, the findings (refusals are errors).
pub fn drive<'a>(
    drive: &'a Drive,
    config: &CalibrationConfig,
) -> Result<Checked<'a>, CalibrationError> {
    let _ = config;
    let mut warnings = Vec::new();
    let vehicle = &drive.vehicle;
    vehicle
        .check_plausible()
        .map_err(CalibrationError::BadVehicle)?;

    // Counters that wrap are unwrapped and values beyond any car set aside
    // before anything reads them; a rear wheel impossible throughout (a
    // wrong unit, not a glitch) is refused first: it would distort every
    // check after this one. The other findings come after the basic checks
    // (an empty or wholly stuck channel is named as such).
    let (drive, repairs) = plausibility::repaired(drive);
    for f in &repairs {
        match f {
            Finding::CounterWrapped { .. } => {
                warnings.push(Warning::new(WarningCode::CounterWrapped, f.to_string()));
            }
            Finding::WheelSamplesSetAside { .. } => {
                warnings.push(Warning::new(
                    WarningCode::WheelSamplesSetAside,
                    f.to_string(),
                ));
            }
            Finding::GnssStampsOnEpochs { .. } => {
                warnings.push(Warning::new(WarningCode::GnssStampsOnEpochs, f.to_string()));
            }
            _ => return Err(CalibrationError::ImplausibleInput(f.clone())),
        }
    }
    let (t, dn_rl, dn_rr, piece_starts, wheel_dt, wheel_offsets) = wheels(&drive, &mut warnings)?;
    let wheel_warnings = warnings.len();
    let standstill = standstill_intervals(&t, &dn_rl, &dn_rr, vehicle.nominal_circumference_m);
    let lateral_accel = lateral_accel(
        &t,
        &dn_rl,
        &dn_rr,
        vehicle.nominal_circumference_m,
        vehicle.track_width_m,
    );
    let wheels = Wheels {
        t,
        dn_rl,
        dn_rr,
        piece_starts,
        wheel_dt,
        wheel_offsets,
        standstill,
        lateral_accel,
    };
    let timed = streams::timed(&drive, &wheels, &mut warnings)?;
    Ok(Checked {
        drive,
        wheels,
        timed,
        warnings,
        wheel_warnings,
    })
}

/// `v omega` over a centred window of 0.5 s, from the wheels (running
/// window sums, no extra arrays).
fn lateral_accel(t: &[f64], dn_rl: &[f64], dn_rr: &[f64], c: f64, track: f64) -> Vec<f32> {
    let n = t.len();
    let mut out = Vec::with_capacity(n);
    // Window (j0, j1]: the increments after j0 up to j1.
    let (mut j0, mut j1) = (0usize, 0usize);
    let (mut l, mut r) = (0.0, 0.0);
    for k in 0..n {
        while j1 + 1 < n && t[j1 + 1] - t[k] <= 0.25 {
            j1 += 1;
            l += dn_rl[j1];
            r += dn_rr[j1];
        }
        while t[k] - t[j0] > 0.25 {
            j0 += 1;
            l -= dn_rl[j0];
            r -= dn_rr[j0];
        }
        let dt = t[j1] - t[j0];
        if dt <= 0.0 {
            out.push(0.0);
            continue;
        }
        let v = 0.5 * c * (l + r) / dt;
        let w = c * (r - l) / (track * dt);
        out.push((v * w) as f32);
    }
    out
}

type WheelArrays = (
    Vec<f64>,
    Vec<f64>,
    Vec<f64>,
    Vec<usize>,
    f64,
    Option<(f64, f64, f64)>,
);

/// Offsets of rate-type wheel channels (`_rad_s`, `_m_s`): the mean reading
/// of each rear wheel while the car stands (both below 0.03 m/s for at
/// least 1 s; 2 s in total needed), in the channel's own unit, and the
/// seconds used. Wheel-hub gyros read a few hundredths of rad/s at rest,
/// which integrates to a slow, speed-independent distance and heading
/// drift. Counting channels (`_rev`, `_ticks`) have no offset.
fn rate_offsets(
    samples: &[WheelSample],
    units: interfaces::drive::WheelUnits,
    k_rl: f64,
    k_rr: f64,
    c: f64,
) -> Option<(f64, f64, f64)> {
    if !(units.rl.is_rate() && units.rr.is_rate()) {
        return None;
    }
    let still = |s: &WheelSample| {
        s.rl.is_finite()
            && s.rr.is_finite()
            && (s.rl * k_rl * c).abs() < 0.03
            && (s.rr * k_rr * c).abs() < 0.03
    };
    let (mut sum_l, mut sum_r, mut n, mut total_t) = (0.0, 0.0, 0usize, 0.0);
    let mut run: Option<(f64, f64, f64, usize)> = None; // start, sum_l, sum_r, count
    let mut last_t = f64::NAN;
    let mut close = |run: &mut Option<(f64, f64, f64, usize)>, end: f64| {
        if let Some((t0, l, r, m)) = run.take() {
            if end - t0 >= 1.0 && m > 0 {
                sum_l += l;
                sum_r += r;
                n += m;
                total_t += end - t0;
            }
        }
    };
    for s in samples {
        if !s.t_s.is_finite() {
            continue;
        }
        if still(s) {
            let r = run.get_or_insert((s.t_s, 0.0, 0.0, 0));
            r.1 += s.rl;
            r.2 += s.rr;
            r.3 += 1;
        } else {
            close(&mut run, last_t);
        }
        last_t = s.t_s;
    }
    close(&mut run, last_t);
    (total_t >= 2.0 && n > 0).then(|| (sum_l / n as f64, sum_r / n as f64, total_t))
}

/// The rear wheels checked and integrated into revolution increments per
/// row (zero across pauses, which start pieces), with the sample interval
/// and the standstill rate offsets.
fn wheels(drive: &Drive, warnings: &mut Vec<Warning>) -> Result<WheelArrays, CalibrationError> {
    let samples = &drive.wheels.samples;
    check_channels(samples)?;
    let units = drive.wheels.units;
    let (k_rl, k_rr) = unit_scales(drive)?;
    let offsets = rate_offsets(
        samples,
        units,
        k_rl,
        k_rr,
        drive.vehicle.nominal_circumference_m,
    );
    let (o_rl, o_rr) = offsets.map_or((0.0, 0.0), |o| (o.0, o.1));
    let wheel_dt = median_interval(samples);
    let gap_threshold = (10.0 * wheel_dt).max(0.5);
    let w = Integrated::of(samples, units, [k_rl, k_rr], [o_rl, o_rr], gap_threshold);
    w.warn(samples.len(), gap_threshold, warnings);
    check_both_turn(
        w.total_rl,
        w.total_rr,
        drive.vehicle.nominal_circumference_m,
    )?;
    Ok((w.t, w.dn_rl, w.dn_rr, w.piece_starts, wheel_dt, offsets))
}

/// Refuse a drive without wheel rows, or with a rear channel that has no
/// finite value.
fn check_channels(samples: &[WheelSample]) -> Result<(), CalibrationError> {
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
    Ok(())
}

/// The factors from each rear channel's unit to revolutions (per second
/// for a rate): rl, rr.
fn unit_scales(drive: &Drive) -> Result<(f64, f64), CalibrationError> {
    let units = drive.wheels.units;
    let scale = |unit: WheelUnit| -> Result<f64, CalibrationError> {
        Ok(match unit {
            WheelUnit::Rev => 1.0,
            WheelUnit::Ticks => match drive.vehicle.ticks_per_rev {
                Some(tpr) if tpr > 0.0 => 1.0 / tpr,
                _ => return Err(WheelConversionError::MissingTicksPerRev.into()),
            },
            WheelUnit::RadS => 1.0 / std::f64::consts::TAU,
            WheelUnit::MS => 1.0 / drive.vehicle.nominal_circumference_m,
        })
    };
    Ok((scale(units.rl)?, scale(units.rr)?))
}

/// Median sample interval from the first rows (enough to set the gap
/// threshold), s; 0.01 s when none is known, at least 0.1 ms.
fn median_interval(samples: &[WheelSample]) -> f64 {
    let mut dts: Vec<f64> = samples
        .windows(2)
        .take(10_000)
        .map(|w| w[1].t_s - w[0].t_s)
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    stats::upper_median(&mut dts).unwrap_or(0.01).max(1e-4)
}

/// The wheel rows integrated into revolution increments, with the pieces
/// between pauses and what was skipped.
struct Integrated {
    t: Vec<f64>,
    dn_rl: Vec<f64>,
    dn_rr: Vec<f64>,
    piece_starts: Vec<usize>,
    /// Pauses longer than the gap threshold.
    gaps: usize,
    /// The longest pause and the time it starts, s.
    longest: (f64, f64),
    /// Absolute revolutions turned, rl and rr.
    total_rl: f64,
    total_rr: f64,
    /// Rows skipped (non-finite, or out of time order), and the first's time.
    skipped: usize,
    first_bad: Option<f64>,
}

impl Integrated {
    /// Integrate the rows: a rate by the trapezoid (less its standstill
    /// `offset`), a count by its difference, both times the unit's factor
    /// `k` (rl, rr); an increment over a pause longer than `gap_threshold`
    /// is zero and starts a new piece.
    fn of(
        samples: &[WheelSample],
        units: interfaces::drive::WheelUnits,
        k: [f64; 2],
        offset: [f64; 2],
        gap_threshold: f64,
    ) -> Integrated {
        let [k_rl, k_rr] = k;
        let [o_rl, o_rr] = offset;
        let n = samples.len();
        let mut t = Vec::with_capacity(n);
        let mut dn_rl = Vec::with_capacity(n);
        let mut dn_rr = Vec::with_capacity(n);
        let mut piece_starts = vec![0usize];
        let mut gaps = 0usize;
        let mut longest = (0.0f64, 0.0f64);
        let (mut total_rl, mut total_rr) = (0.0f64, 0.0f64);
        let mut skipped = 0usize;
        let mut first_bad = None;
        let mut prev: Option<&WheelSample> = None;
        for s in samples {
            if !(s.rl.is_finite() && s.rr.is_finite() && s.t_s.is_finite()) {
                // Skipped: a rate is integrated across it from its neighbours,
                // as `wheel_revolutions` does on the cleaned rows.
                skipped += 1;
                first_bad.get_or_insert(s.t_s);
                continue;
            }
            let Some(p) = prev else {
                t.push(s.t_s);
                dn_rl.push(0.0);
                dn_rr.push(0.0);
                prev = Some(s);
                continue;
            };
            let dt = s.t_s - p.t_s;
            if dt.is_nan() || dt <= 0.0 {
                skipped += 1;
                first_bad.get_or_insert(s.t_s);
                continue;
            }
            let inc = |unit: WheelUnit, k: f64, a: f64, b: f64, offset: f64| {
                if unit.is_rate() {
                    (0.5 * (a + b) - offset) * k * dt
                } else {
                    (b - a) * k
                }
            };
            let a = inc(units.rl, k_rl, p.rl, s.rl, o_rl);
            let b = inc(units.rr, k_rr, p.rr, s.rr, o_rr);
            t.push(s.t_s);
            if dt > gap_threshold {
                gaps += 1;
                if dt > longest.0 {
                    longest = (dt, p.t_s);
                }
                piece_starts.push(t.len() - 1);
                dn_rl.push(0.0);
                dn_rr.push(0.0);
            } else {
                total_rl += a.abs();
                total_rr += b.abs();
                dn_rl.push(a);
                dn_rr.push(b);
            }
            prev = Some(s);
        }
        Integrated {
            t,
            dn_rl,
            dn_rr,
            piece_starts,
            gaps,
            longest,
            total_rl,
            total_rr,
            skipped,
            first_bad,
        }
    }

    /// Warn of the rows skipped and of the pauses (`rows`: the rows read).
    fn warn(&self, rows: usize, gap_threshold: f64, warnings: &mut Vec<Warning>) {
        let (skipped, gaps, longest) = (self.skipped, self.gaps, self.longest);
        if skipped > 0 {
            warnings.push(Warning::new(
                WarningCode::NonFiniteSamples,
                format!(
                    "wheels: {skipped} of {} rows have a non-finite time or rl/rr value (or break the time order) and were skipped (first at t = {:.3} s)",
                    rows,
                    self.first_bad.unwrap_or(f64::NAN)
                ),
            ));
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
    }
}

/// Refuse a drive whose busier rear wheel turned less than 2 revolutions,
/// or whose other rear wheel turned less than 5 % of that (stuck).
fn check_both_turn(
    total_rl: f64,
    total_rr: f64,
    nominal_circumference_m: f64,
) -> Result<(), CalibrationError> {
    let (big, small, big_name, small_name) = if total_rl >= total_rr {
        (total_rl, total_rr, "rl", "rr")
    } else {
        (total_rr, total_rl, "rr", "rl")
    };
    if big < 2.0 {
        return Err(CalibrationError::TooShort {
            distance_m: big * nominal_circumference_m,
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
    Ok(())
}

/// Standstill intervals: wheel speed below 0.05 m/s for at least 1 s.
fn standstill_intervals(t: &[f64], dn_rl: &[f64], dn_rr: &[f64], c: f64) -> Vec<(f64, f64)> {
    let n = t.len();
    let mut out = Vec::new();
    if n < 3 {
        return out;
    }
    // Speed over a centred window of about 0.5 s (running sum of increments).
    let (mut j0, mut j1) = (0usize, 0usize);
    let mut sum = 0.0;
    let mut start: Option<f64> = None;
    for k in 0..n {
        while j1 + 1 < n && t[j1 + 1] - t[k] <= 0.25 {
            j1 += 1;
            sum += 0.5 * (dn_rl[j1] + dn_rr[j1]) * c;
        }
        while t[k] - t[j0] > 0.25 {
            j0 += 1;
            sum -= 0.5 * (dn_rl[j0] + dn_rr[j0]) * c;
        }
        let still = t[j1] > t[j0] && (sum / (t[j1] - t[j0])).abs() < 0.05;
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
    use crate::series::Series;
    use crate::warnings::WarningCode;

    /// The checked drive on the wheels' clock (stage 1 and the clocks
    /// without drift), as the calibration's arrays.
    fn prepare(
        d: &Drive,
        config: &CalibrationConfig,
        w: &mut Vec<Warning>,
    ) -> Result<Series, CalibrationError> {
        let a = crate::clocks::align_offsets(super::drive(d, config)?, config)?;
        w.extend(a.warnings);
        Ok(a.series)
    }
    use interfaces::drive::{GnssAntenna, GnssSample, VehicleParams, WheelSeries, WheelUnits};

    fn drive(unit: WheelUnit, rows: Vec<(f64, f64, f64)>) -> Drive {
        Drive {
            vehicle: VehicleParams {
                name: None,
                track_width_m: 1.5,
                nominal_circumference_m: 2.0,
                wheelbase_m: None,
                ticks_per_rev: Some(48.0),
                gnss: GnssAntenna::default(),
            },
            wheels: WheelSeries {
                units: WheelUnits::rear(unit),
                samples: rows
                    .into_iter()
                    .map(|(t_s, rl, rr)| WheelSample {
                        t_s,
                        rl,
                        rr,
                        fl: None,
                        fr: None,
                    })
                    .collect(),
            },
            gnss: Some(
                (0..20)
                    .map(|i| GnssSample {
                        t_s: i as f64,
                        x_m: i as f64,
                        y_m: 0.0,
                        sigma_m: None,
                    })
                    .collect(),
            ),
            imu: None,
            heading: None,
            truth: None,
            truth_params: None,
        }
    }

    #[test]
    fn the_streaming_conversion_matches_wheel_revolutions() {
        for unit in WheelUnit::ALL {
            let rows: Vec<(f64, f64, f64)> = (0..2000)
                .map(|i| {
                    let t = i as f64 * 0.01;
                    let (a, b) = (5.0 + (t * 0.7).sin(), 5.2 + (t * 0.3).cos());
                    if unit.is_rate() {
                        (t, a, b)
                    } else {
                        // Counts below 100 rev/s (faster is refused as no car's wheel).
                        (t, (4.0 * a * t).floor(), (4.0 * b * t).floor())
                    }
                })
                .collect();
            let d = drive(unit, rows);
            let mut w = Vec::new();
            let p = prepare(&d, &CalibrationConfig::default(), &mut w).expect("prepare");
            let revs = d.wheel_revolutions().expect("revolutions");
            let (mut a, mut b) = (0.0, 0.0);
            for k in 0..p.len() {
                a += p.dn_rl[k];
                b += p.dn_rr[k];
                assert!((a - (revs[k].rl - revs[0].rl)).abs() < 1e-9, "{unit:?} {k}");
                assert!((b - (revs[k].rr - revs[0].rr)).abs() < 1e-9, "{unit:?} {k}");
            }
            assert!(p.wheel_offsets.is_none());
        }
    }

    #[test]
    fn rate_offsets_at_standstill_are_subtracted() {
        // 3 s standing with hub-gyro offsets, then driving.
        let rows: Vec<(f64, f64, f64)> = (0..1000)
            .map(|i| {
                let t = i as f64 * 0.01;
                let drive = if t < 3.0 { 0.0 } else { 20.0 };
                (t, drive - 0.02, drive + 0.01)
            })
            .collect();
        let d = drive(WheelUnit::RadS, rows);
        let mut w = Vec::new();
        let p = prepare(&d, &CalibrationConfig::default(), &mut w).expect("prepare");
        let (o_rl, o_rr, secs) = p.wheel_offsets.expect("offsets");
        assert!((o_rl + 0.02).abs() < 1e-9 && (o_rr - 0.01).abs() < 1e-9 && secs > 2.5);
        let standing: f64 = p.dn_rl[..250].iter().sum();
        assert!(standing.abs() < 1e-12, "{standing}");
    }

    /// Wheels turning left and right (rad/s), rows of (t, rl, rr).
    fn weaving_rows() -> Vec<(f64, f64, f64)> {
        (0..2000)
            .map(|i| {
                let t = i as f64 * 0.01;
                (t, 5.0 - t.sin(), 5.0 + t.sin())
            })
            .collect()
    }

    #[test]
    fn a_dead_gyro_is_dropped_with_a_warning() {
        let mut d = drive(WheelUnit::RadS, weaving_rows());
        d.imu = Some(
            (0..2000)
                .map(|i| interfaces::drive::ImuSample {
                    t_s: i as f64 * 0.01,
                    gz_rad_s: 0.0,
                    ax_m_s2: None,
                    ay_m_s2: None,
                    az_m_s2: None,
                    gx_rad_s: None,
                    gy_rad_s: None,
                })
                .collect(),
        );
        let mut w = Vec::new();
        let p = prepare(&d, &CalibrationConfig::default(), &mut w).expect("prepare");
        assert!(p.gyro.is_none(), "no gyro fit from a dead gyro");
        let stuck = w
            .iter()
            .find(|w| w.code == WarningCode::ImuStuck)
            .unwrap_or_else(|| panic!("{w:?}"));
        assert!(
            stuck.message.contains("gz_rad_s") && stuck.message.contains("the gyro is dropped"),
            "{}",
            stuck.message
        );
    }

    #[test]
    fn an_impossible_wheel_sample_is_set_aside_with_a_warning() {
        let rows = weaving_rows();
        let clean = prepare(
            &drive(WheelUnit::RadS, rows.clone()),
            &CalibrationConfig::default(),
            &mut Vec::new(),
        )
        .expect("clean drive");
        let mut glitched = rows;
        glitched[700].1 = 1e308;
        let mut w = Vec::new();
        let p = prepare(
            &drive(WheelUnit::RadS, glitched),
            &CalibrationConfig::default(),
            &mut w,
        )
        .expect("one glitch costs its sample, not the drive");
        assert_eq!(
            p.len(),
            clean.len() - 1,
            "exactly the glitched row is set aside"
        );
        let set_aside = w
            .iter()
            .find(|w| w.code == WarningCode::WheelSamplesSetAside)
            .unwrap_or_else(|| panic!("{w:?}"));
        assert!(
            set_aside.message.contains("wheels.rl")
                && set_aside.message.contains("t = 7 s")
                && set_aside.message.contains("1 of"),
            "{}",
            set_aside.message
        );
    }

    #[test]
    fn a_wheel_impossible_throughout_is_refused() {
        // Every value 1000 times too large: a wrong unit, not a glitch.
        let rows: Vec<_> = weaving_rows()
            .into_iter()
            .map(|(t, l, r)| (t, 1000.0 * l + 1e4, r))
            .collect();
        let d = drive(WheelUnit::RadS, rows);
        let e = prepare(&d, &CalibrationConfig::default(), &mut Vec::new()).unwrap_err();
        assert!(
            matches!(
                e,
                CalibrationError::ImplausibleInput(Finding::ImpossibleWheelRate { .. })
            ),
            "{e}"
        );
        assert!(e.to_string().contains("wheels.rl"), "{e}");
    }

    #[test]
    fn opposed_wheels_are_refused() {
        let rows = weaving_rows()
            .into_iter()
            .map(|(t, l, r)| (t, l, -r))
            .collect();
        let d = drive(WheelUnit::RadS, rows);
        let e = prepare(&d, &CalibrationConfig::default(), &mut Vec::new()).unwrap_err();
        assert!(
            matches!(
                e,
                CalibrationError::ImplausibleInput(Finding::WheelsOpposed { .. })
            ),
            "{e}"
        );
    }

    #[test]
    fn a_wrapping_counter_is_unwrapped_with_a_warning() {
        let rows: Vec<(f64, f64, f64)> = (0..2000)
            .map(|i| {
                let t = i as f64 * 0.01;
                (t, (100.0 * t).floor(), (101.0 * t).floor())
            })
            .collect();
        let wrapped = rows
            .iter()
            .map(|&(t, a, b)| (t, (a + 200.0) % 256.0, (b + 200.0) % 256.0))
            .collect();
        let config = CalibrationConfig::default();
        let mut w = Vec::new();
        let p = prepare(&drive(WheelUnit::Ticks, wrapped), &config, &mut w).expect("prepare");
        assert!(
            w.iter().any(|w| w.code == WarningCode::CounterWrapped),
            "{w:?}"
        );
        let q = prepare(&drive(WheelUnit::Ticks, rows), &config, &mut Vec::new()).expect("prepare");
        assert_eq!(p.dn_rl, q.dn_rl);
        assert_eq!(p.dn_rr, q.dn_rr);
    }

    #[test]
    fn a_contradicting_track_width_is_a_warning() {
        // The car's track is 1.5 / 1.3 m; vehicle.toml says 1.5 m (30 % too wide).
        let true_track = 1.5 / 1.3;
        let mut d = drive(WheelUnit::RadS, weaving_rows());
        d.imu = Some(
            (0..2000)
                .map(|i| {
                    let t = i as f64 * 0.01;
                    // (v_r - v_l) / B with v = omega_wheel c / 2 pi.
                    let gz = 2.0 * t.sin() * 2.0 / std::f64::consts::TAU / true_track;
                    interfaces::drive::ImuSample {
                        t_s: t,
                        gz_rad_s: gz,
                        ax_m_s2: None,
                        ay_m_s2: None,
                        az_m_s2: None,
                        gx_rad_s: None,
                        gy_rad_s: None,
                    }
                })
                .collect(),
        );
        let mut w = Vec::new();
        prepare(&d, &CalibrationConfig::default(), &mut w).expect("prepare");
        let found = w
            .iter()
            .find(|w| w.code == WarningCode::TrackWidthContradicted)
            .unwrap_or_else(|| panic!("{w:?}"));
        assert!(
            found
                .message
                .contains("vehicle.toml's track_width_m = 1.5 m contradicts the drive: the wheels and the gyro agree on 1.15"),
            "{}",
            found.message
        );
        // The right track: no such warning.
        d.vehicle.track_width_m = true_track;
        let mut w = Vec::new();
        prepare(&d, &CalibrationConfig::default(), &mut w).expect("prepare");
        assert!(
            !w.iter()
                .any(|w| w.code == WarningCode::TrackWidthContradicted),
            "{w:?}"
        );
    }

    #[test]
    fn a_ten_minute_pause_is_a_warning_and_a_piece_break() {
        let rows = weaving_rows()
            .into_iter()
            .map(|(t, l, r)| (if t >= 10.0 { t + 600.0 } else { t }, l, r))
            .collect();
        let mut d = drive(WheelUnit::RadS, rows);
        if let Some(g) = d.gnss.as_mut() {
            for (i, f) in g.iter_mut().enumerate() {
                if i >= 10 {
                    f.t_s += 600.0;
                }
            }
        }
        let mut w = Vec::new();
        let p = prepare(&d, &CalibrationConfig::default(), &mut w).expect("prepare");
        let pause = w
            .iter()
            .find(|w| w.code == WarningCode::WheelPause)
            .unwrap_or_else(|| panic!("{w:?}"));
        assert!(
            pause.message.contains("pauses for 600.0 s at t = 9.99")
                && pause.message.contains("not integrated across it"),
            "{}",
            pause.message
        );
        // Nothing is integrated across it: a piece starts after the pause.
        assert_eq!(p.piece_starts, vec![0, 1000]);
        assert_eq!((p.dn_rl[1000], p.dn_rr[1000]), (0.0, 0.0));
    }

    #[test]
    fn standstill_is_found() {
        let t: Vec<f64> = (0..1000).map(|k| k as f64 * 0.01).collect();
        let dn: Vec<f64> = t
            .iter()
            .map(|&tk| if (3.0..6.0).contains(&tk) { 0.0 } else { 0.01 })
            .collect();
        let s = standstill_intervals(&t, &dn, &dn, 2.0);
        assert_eq!(s.len(), 1, "{s:?}");
        assert!(
            (s[0].0 - 3.25).abs() < 0.05 && (s[0].1 - 5.75).abs() < 0.05,
            "{s:?}"
        );
    }
}
