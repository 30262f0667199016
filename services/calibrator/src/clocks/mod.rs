//! Stage 2, the clocks: [`align`] puts every stream of the checked drive
//! on the wheels' clock. The IMU's offset against the wheels
//! ([`offsets::imu_offset`]) is found and, where applied, taken off the
//! IMU times before the gyro is integrated; the streams' slow drifts
//! ([`drift`]) are looked for and, where applied, the streams are
//! re-stamped and their arrays built again by the shared builders
//! ([`crate::streams`]). Last, the GNSS's offset ([`gnss`]): its noise, the
//! fixes smoothed alone, the offset over every pair of streams, applied
//! where compensated.
//!
//! - [`offsets`]: the clock offsets of the streams against the wheels (pure
//!   functions on arrays);
//! - [`drift`]: their slow drift, from offsets in windows along the drive;
//! - [`gnss`]: the GNSS's noise and clock offset.

pub(crate) mod drift;
pub(crate) mod gnss;
pub(crate) mod offsets;

use crate::check::Checked;
use crate::clocks::offsets::{ClockDrift, OffsetStatus, StreamOffset, CLOCK_SEARCH_S};
use crate::config::{CalibrationConfig, TimeOffsetMode};
use crate::error::CalibrationError;
use crate::series::Series;
use crate::streams::{self, Timed, Wheels};
use crate::warnings::{Warning, WarningCode};
use interfaces::drive::Drive;
use std::borrow::Cow;

/// The drive on the wheels' clock: what stage 2 hands on.
#[derive(Debug, Clone)]
pub struct Aligned<'a> {
    /// The drive (re-stamped where a drift is applied); the reference reads
    /// the IMU accelerations from it (less `series.imu_shift_s`).
    pub drive: Cow<'a, Drive>,
    /// The arrays, every stream on the wheels' clock.
    pub series: Series,
    /// The IMU clock offset against the wheels, determined or not (and why).
    pub imu_clock: StreamOffset,
    /// The GNSS and IMU clock drifts.
    pub drifts: Drifts,
    /// The GNSS on the wheels' clock: its noise, the fixes smoothed alone,
    /// its clock offset.
    pub gnss: gnss::Gnss,
    /// The warnings so far.
    pub warnings: Vec<Warning>,
}

/// Put every stream of `checked` on the wheels' clock: the IMU offset, the
/// drifts (a drive re-stamped for one is converted again), the arrays, the
/// GNSS offset.
pub fn align<'a>(
    checked: Checked<'a>,
    config: &CalibrationConfig,
) -> Result<Aligned<'a>, CalibrationError> {
    let Checked {
        drive,
        wheels,
        timed,
        mut warnings,
        wheel_warnings,
    } = checked;
    let (mut imu_clock, mut series) =
        on_wheel_clock(&drive, config, &wheels, &timed, &mut warnings);
    // The streams' slow clock drift: where it is significant (and the
    // offsets are compensated), the streams are put on the wheels' clock
    // rate and converted again (their constant offsets are then those at
    // the drift's reference time). The re-stamp leaves the wheels as they
    // are: their arrays and warnings are kept.
    let drifts = clock_drifts(&series, &imu_clock, &drive, config);
    let (drive, timed) = match restamp(&drive, &drifts) {
        Some(d) => {
            warnings.truncate(wheel_warnings);
            let timed = streams::timed(&d, &wheels, &mut warnings)?;
            (imu_clock, series) = on_wheel_clock(&d, config, &wheels, &timed, &mut warnings);
            (Cow::Owned(d), timed)
        }
        None => (drive, timed),
    };
    drift_warnings(&drifts, &mut warnings);
    let gnss = gnss::align(&series, &imu_clock, config, &mut warnings)?;
    if let Some(s) = follow_gnss(&mut imu_clock, &gnss.clock, &mut warnings) {
        series = streams::series(&drive, config, &wheels, &timed, s, &mut Vec::new());
    }
    Ok(Aligned {
        drive,
        series,
        imu_clock,
        drifts,
        gnss,
        warnings,
    })
}

/// [`align`] with the constant offsets only (no drift looked for): the
/// arrays of a drive as the hold-out scores and the benches read them.
pub fn align_offsets<'a>(
    checked: Checked<'a>,
    config: &CalibrationConfig,
) -> Result<Aligned<'a>, CalibrationError> {
    let Checked {
        drive,
        wheels,
        timed,
        mut warnings,
        ..
    } = checked;
    let (mut imu_clock, mut series) =
        on_wheel_clock(&drive, config, &wheels, &timed, &mut warnings);
    let off = ClockDrift::not_checked("drift not looked for");
    let gnss = gnss::align(&series, &imu_clock, config, &mut warnings)?;
    if let Some(s) = follow_gnss(&mut imu_clock, &gnss.clock, &mut warnings) {
        series = streams::series(&drive, config, &wheels, &timed, s, &mut Vec::new());
    }
    Ok(Aligned {
        drive,
        series,
        imu_clock,
        drifts: Drifts {
            gnss: off.clone(),
            imu: off,
        },
        gnss,
        warnings,
    })
}

/// The IMU's clock and the arrays with the IMU on the wheels' clock.
fn on_wheel_clock(
    drive: &Drive,
    config: &CalibrationConfig,
    wheels: &Wheels,
    timed: &Timed,
    warnings: &mut Vec<Warning>,
) -> (StreamOffset, Series) {
    // A gyro dead for the whole drive has no clock to find.
    let imu_clock = if streams::gyro_dead(&timed.findings) {
        StreamOffset::not_checked(
            "the IMU's yaw rate is dead or stuck for the whole drive (imu_stuck)",
        )
    } else {
        imu_clock(
            drive,
            config,
            &wheels.t,
            &wheels.dn_rl,
            &wheels.dn_rr,
            warnings,
        )
    };
    let imu_shift_s = imu_clock.applied_shift_s();
    let series = streams::series(drive, config, wheels, timed, imu_shift_s, warnings);
    (imu_clock, series)
}

/// The largest lag between the wheels' and the gyro's yaw rate that the car
/// itself can cause, s: an IMU offset within it is reported, not applied.
pub const IMU_PHYSICAL_LAG_S: f64 = 0.05;

/// Where the IMU's applied offset and the GNSS's agree within
/// [`IMU_PHYSICAL_LAG_S`], both streams say the same thing: the wheels'
/// clock moved against both. The IMU's own offset then carries the
/// wheels' physical lag behind the gyro (tens of milliseconds that the
/// drive without the clock fault keeps: wid-trial02's -30 ms), and taking
/// it off with the clock's shift puts the gyro that much away from where
/// the same drive on a good clock has it (its 30 s outages' median error
/// 0.225 -> 0.44 m). The IMU is moved by the GNSS's offset instead: its
/// stamps follow the wheels' clock correction and keep their physical
/// lag. Only where the GNSS offset is applied and known to better than
/// half that band ([`IMU_FOLLOWS_GNSS_SIGMA_S`]), no drift is applied to
/// either, and the two agree; the IMU's own offset stays in the report
/// (`offset_s`), the shift applied in `applied_s`, and a warning says so.
/// Returns the IMU's new shift, s, when it moved.
pub fn imu_follows_gnss(imu: &StreamOffset, gnss: &StreamOffset) -> Option<f64> {
    if !(imu.applied && gnss.applied)
        || imu.drift.applied
        || gnss.drift.applied
        || gnss.applied_s.is_some()
    {
        return None;
    }
    let (i, g, sg) = (imu.offset_s?, gnss.offset_s?, gnss.sigma_s?);
    let agree = (i - g).abs() < IMU_PHYSICAL_LAG_S;
    (agree && sg < IMU_FOLLOWS_GNSS_SIGMA_S && g.is_finite()).then_some(g)
}

/// The largest sigma of a GNSS clock offset the IMU follows
/// ([`imu_follows_gnss`]), s: half of [`IMU_PHYSICAL_LAG_S`], so that the
/// GNSS's offset is known better than the lag it stands in for.
pub const IMU_FOLLOWS_GNSS_SIGMA_S: f64 = 0.5 * IMU_PHYSICAL_LAG_S;

/// [`imu_follows_gnss`] applied to `imu` (its `applied_s` set, a warning
/// pushed); the IMU's new shift when it moved.
fn follow_gnss(
    imu: &mut StreamOffset,
    gnss: &StreamOffset,
    warnings: &mut Vec<Warning>,
) -> Option<f64> {
    let shift = imu_follows_gnss(imu, gnss)?;
    let own = imu.offset_s.unwrap_or(0.0);
    imu.applied_s = Some(shift);
    warnings.push(Warning::new(
        WarningCode::TimeOffset,
        format!(
            "the IMU and the GNSS are both about {:.0} ms {} than the wheels: the wheels' clock \
             moved; the IMU's stamps are shifted by the GNSS's {:+.0} ms, not by their own \
             {:+.0} ms, which carry the wheels' physical lag behind the gyro (within {:.0} ms)",
            1000.0 * shift.abs(),
            if shift > 0.0 { "later" } else { "earlier" },
            1000.0 * shift,
            1000.0 * own,
            1000.0 * IMU_PHYSICAL_LAG_S
        ),
    ));
    Some(shift)
}

/// The IMU clock offset against the wheels ([`offsets::imu_offset`]),
/// marked applied when it is significant (beyond 3 sigma and one IMU sample
/// interval) and `config` compensates; warnings say what was found.
fn imu_clock(
    drive: &Drive,
    config: &CalibrationConfig,
    t: &[f64],
    dn_rl: &[f64],
    dn_rr: &[f64],
    warnings: &mut Vec<Warning>,
) -> StreamOffset {
    if config.time_offset == TimeOffsetMode::Off {
        return StreamOffset::not_checked("time offset check switched off");
    }
    let Some(rows) = drive.imu.as_ref().filter(|r| !r.is_empty()) else {
        return StreamOffset::not_checked("the drive has no IMU");
    };
    let rows: Vec<offsets::ImuRow> = rows
        .iter()
        .map(|r| (r.t_s, r.gz_rad_s, r.ax_m_s2))
        .collect();
    let wheels = offsets::WheelTrack {
        t,
        dn_rl,
        dn_rr,
        circumference_m: drive.vehicle.nominal_circumference_m,
        track_m: drive.vehicle.track_width_m,
    };
    let mut o = offsets::imu_offset(&wheels, &rows, CLOCK_SEARCH_S);
    let ts: Vec<f64> = rows
        .iter()
        .take(10_001)
        .map(|r| r.0)
        .filter(|t| t.is_finite())
        .collect();
    let interval = offsets::median_interval(&ts).unwrap_or(0.01).max(0.005);
    // The wheels' yaw rate trails the gyro's physically too (tyre relaxation,
    // the rate taken over a window of wheel samples): tens of milliseconds
    // that no clock causes. Below IMU_PHYSICAL_LAG_S an offset is reported
    // but not applied (on wid-trial02, -30 +- 5 ms: applying it moved the
    // fitted antenna by 0.1 m).
    match (o.significant(interval.max(IMU_PHYSICAL_LAG_S)), o.sigma_s) {
        (Some(off), Some(sigma)) => {
            o.applied = config.time_offset == TimeOffsetMode::Compensate;
            warnings.push(Warning::new(
                WarningCode::TimeOffset,
                format!(
                    "imu time stamps are {:.0} ms {} than the wheels' (sigma {:.0} ms, from the {}){}",
                    1000.0 * off.abs(),
                    if off > 0.0 { "later" } else { "earlier" },
                    1000.0 * sigma,
                    o.from.as_deref().unwrap_or("yaw rate"),
                    if o.applied {
                        "; the IMU times were shifted to match"
                    } else {
                        "; not compensated"
                    }
                ),
            ));
        }
        _ if o.status == offsets::OffsetStatus::NotDetermined => {
            warnings.push(Warning::new(
                WarningCode::TimeOffset,
                format!(
                    "the wheel/IMU time offset could not be determined within +-{CLOCK_SEARCH_S:.1} s ({}); it is not checked",
                    o.reason.as_deref().unwrap_or("no reason")
                ),
            ));
        }
        _ => {}
    }
    o
}

/// The GNSS and IMU clock drifts against the wheels.
#[derive(Debug, Clone, PartialEq)]
pub struct Drifts {
    /// The GNSS's (and the absolute heading's) clock drift.
    pub gnss: ClockDrift,
    /// The IMU's clock drift.
    pub imu: ClockDrift,
}

/// A clock drift that could not be looked for, because `reason`.
fn drift_not_determined(reason: String) -> ClockDrift {
    ClockDrift {
        status: OffsetStatus::NotDetermined,
        reason: Some(reason),
        ..ClockDrift::default()
    }
}

/// Every stream's drift ([`clock_drift`]), marked applied where it is
/// significant and `config` compensates the clocks.
fn clock_drifts(
    p: &Series,
    imu_clock: &StreamOffset,
    drive: &Drive,
    config: &CalibrationConfig,
) -> Drifts {
    if config.time_offset == TimeOffsetMode::Off {
        let off = ClockDrift::not_checked("time offset check switched off");
        return Drifts {
            gnss: off.clone(),
            imu: off,
        };
    }
    let (Some(&t0), Some(&t1)) = (p.t.first(), p.t.last()) else {
        let none = ClockDrift::not_checked("no wheel samples");
        return Drifts {
            gnss: none.clone(),
            imu: none,
        };
    };
    let t_ref = 0.5 * (t0 + t1);
    let spans = drift::windows(t0, t1);
    let wheels = offsets::WheelTrack {
        t: &p.t,
        dn_rl: &p.dn_rl,
        dn_rr: &p.dn_rr,
        circumference_m: p.nominal_c,
        track_m: p.track,
    };
    let apply = |mut d: ClockDrift| {
        d.applied = drift::significant(&d) && config.time_offset == TimeOffsetMode::Compensate;
        d
    };
    let gnss = if p.fixes.is_empty() {
        ClockDrift::not_checked("the drive has no GNSS")
    } else {
        let fixes: Vec<(f64, f64, f64)> = p.fixes.iter().map(|f| (f.t, f.x, f.y)).collect();
        let mut given: Vec<f64> = p.fixes.iter().filter_map(|f| f.sigma).collect();
        let motion = drift::gnss_motion(&fixes, stats::upper_median(&mut given));
        let (whole, tries) = drift::gnss_windows(&wheels, &motion, &spans);
        if whole.status == OffsetStatus::Determined {
            apply(drift::judge(tries, (t0, t1), t_ref, &whole))
        } else {
            drift_not_determined(format!(
                "the offset is not determined over the whole drive ({})",
                whole.reason.as_deref().unwrap_or("no reason")
            ))
        }
    };
    let imu = match (drive.imu.as_deref(), imu_clock) {
        (None | Some([]), _) => ClockDrift::not_checked("the drive has no IMU"),
        (Some(rows), whole) => match (whole.status, whole.offset_s) {
            (OffsetStatus::Determined, Some(centre)) => {
                // One copy, the rows with a finite time (imu_windows
                // takes them so).
                let rows: Vec<offsets::ImuRow> = rows
                    .iter()
                    .filter(|r| r.t_s.is_finite())
                    .map(|r| (r.t_s, r.gz_rad_s, r.ax_m_s2))
                    .collect();
                let tries = drift::imu_windows(&wheels, &rows, &spans, centre);
                apply(drift::judge(tries, (t0, t1), t_ref, whole))
            }
            _ => drift_not_determined(
                "the IMU offset is not determined over the whole drive".to_string(),
            ),
        },
    };
    Drifts { gnss, imu }
}

/// The drive with every stream whose drift is applied put on the wheels'
/// clock rate (GNSS and heading by the GNSS's drift, the IMU by its own);
/// `None` when no drift is applied.
fn restamp(drive: &Drive, d: &Drifts) -> Option<Drive> {
    let (g, i) = (d.gnss.applied_rate(), d.imu.applied_rate());
    if g.is_none() && i.is_none() {
        return None;
    }
    let mut out = drive.clone();
    if let (Some(r), Some(t_ref)) = (g, d.gnss.ref_t_s) {
        for s in out.gnss.iter_mut().flatten() {
            s.t_s = drift::undrift(s.t_s, r, t_ref);
        }
        for s in out.heading.iter_mut().flatten() {
            s.t_s = drift::undrift(s.t_s, r, t_ref);
        }
    }
    if let (Some(r), Some(t_ref)) = (i, d.imu.ref_t_s) {
        for s in out.imu.iter_mut().flatten() {
            s.t_s = drift::undrift(s.t_s, r, t_ref);
        }
    }
    Some(out)
}

/// A warning per significant drift.
fn drift_warnings(d: &Drifts, warnings: &mut Vec<Warning>) {
    for (name, x) in [("gnss", &d.gnss), ("imu", &d.imu)] {
        if let (true, Some(ppm), Some(sigma)) = (drift::significant(x), x.drift_ppm, x.sigma_ppm) {
            warnings.push(Warning::new(
                WarningCode::TimeOffset,
                format!(
                    "the {name} clock drifts {ppm:+.0} ppm against the wheels' (sigma {sigma:.0} ppm, from {} windows){}",
                    x.windows.len(),
                    if x.applied {
                        "; its times were corrected for it, the offset is the one at the middle of the drive"
                    } else {
                        "; not compensated"
                    }
                ),
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn offset(o: f64, sigma: f64, applied: bool) -> StreamOffset {
        StreamOffset::for_test(o, sigma, "yaw rate", applied)
    }

    #[test]
    fn the_imu_follows_the_gnss_only_where_both_say_the_wheels_clock_moved() {
        // wid-trial02 with its wheel clock 1.5 s early: IMU +1.470, GNSS +1.506 +- 0.012.
        let (imu, gnss) = (offset(1.470, 0.013, true), offset(1.506, 0.012, true));
        assert_eq!(imu_follows_gnss(&imu, &gnss), Some(1.506));
        let mut moved = imu.clone();
        let mut w = Vec::new();
        assert_eq!(follow_gnss(&mut moved, &gnss, &mut w), Some(1.506));
        assert_eq!(
            (moved.offset_s, moved.applied_s),
            (Some(1.470), Some(1.506))
        );
        assert_eq!(moved.applied_shift_s(), 1.506);
        assert_eq!(w.len(), 1);
        // An IMU clock of its own (the two 0.34 s apart): its own offset.
        assert_eq!(
            imu_follows_gnss(&offset(-0.330, 0.005, true), &offset(0.006, 0.012, true)),
            None
        );
        // A GNSS offset known to 54 ms only (wid-trial04): no better than the lag.
        assert_eq!(imu_follows_gnss(&imu, &offset(1.494, 0.054, true)), None);
        // Either not applied, or a drift applied: nothing moves.
        assert_eq!(imu_follows_gnss(&offset(0.03, 0.005, false), &gnss), None);
        assert_eq!(imu_follows_gnss(&imu, &offset(1.506, 0.012, false)), None);
        let mut drifting = gnss.clone();
        drifting.drift.applied = true;
        assert_eq!(imu_follows_gnss(&imu, &drifting), None);
        assert_eq!(offset(0.03, 0.005, false).applied_shift_s(), 0.0);
    }
}
