//! The GNSS clock: the fixes' noise and their clock offset against the
//! wheels. The offset is found on the fixes smoothed alone
//! ([`crate::smoother`], weighted with their sigmas, so the noise comes
//! first): the GNSS speed against the wheel speed, or the course rate
//! against the wheels' yaw rate, over +-[`CLOCK_SEARCH_S`], and combined
//! over every pair of streams (wheels-GNSS, wheels-IMU, IMU-GNSS) with
//! [`offsets::solve_offsets`]; where significant (and compensated) the
//! GNSS times are shifted and the fixes smoothed again. The reference
//! starts from what [`align`] gives.

use crate::clocks::offsets::{self, ClockStream, PairOffset, StreamOffset, CLOCK_SEARCH_S};
use crate::config::{CalibrationConfig, TimeOffsetMode};
use crate::error::CalibrationError;
use crate::series::{Fix, Series};
use crate::smoother::{smooth_positions, PosTrack, RefFix, COURSE_MIN_SPEED, Q_ACCEL_FREE};
use crate::warnings::{Warning, WarningCode};
use serde::{Deserialize, Serialize};
use vehicle_model::two_wheel::wrap_angle;

/// The GNSS on the wheels' clock: what stage 2 hands on of it.
#[derive(Debug, Clone)]
pub struct Gnss {
    /// The GNSS 1-sigma used for fixes without their own, m.
    pub sigma_m: f64,
    /// True when `sigma_m` was estimated from the fixes.
    pub sigma_estimated: bool,
    /// The receiver's claimed sigma when the fixes' scatter refuted it.
    pub claim: Option<SigmaClaim>,
    /// The fixes with their sigmas, on the wheels' clock where the offset
    /// was compensated (none gated yet).
    pub fixes: Vec<RefFix>,
    /// The antenna positions of the fixes, m.
    pub antenna: Vec<[f64; 2]>,
    /// The fixes smoothed alone (no heading, no accelerations), after the
    /// compensation.
    pub(crate) alone: PosTrack,
    /// The wheel/GNSS time offset, when checked and determinable.
    pub time_offset: Option<TimeOffset>,
    /// The GNSS clock offset against the wheels, determined or not (and
    /// why): every pair of streams combined ([`offsets::solve_offsets`]).
    pub clock: StreamOffset,
    /// The pairs of streams compared for it.
    pub pairs: Vec<PairOffset>,
}

/// The GNSS of `p` on the wheels' clock: its noise (configured, the
/// receiver's or measured, with the check of the receiver's claim), the
/// fixes smoothed alone, the clock offset from their speed or course rate
/// and over every pair of streams (with the IMU's, `imu_clock`), applied
/// where significant and `config.time_offset` compensates.
pub fn align(
    p: &Series,
    imu_clock: &StreamOffset,
    config: &CalibrationConfig,
    warnings: &mut Vec<Warning>,
) -> Result<Gnss, CalibrationError> {
    let (gnss_sigma_m, estimated, claim, floor) = gnss_sigma(p, config, warnings);
    let mut fixes = ref_fixes(p, config, gnss_sigma_m, floor);
    let gate = config.outlier_gate_sigma;
    let antenna: Vec<[f64; 2]> = fixes.iter().map(|f| [f.x, f.y]).collect();

    // Pass 1: GNSS alone, for the course and the time offset.
    let mut pass1 = smooth_positions(&fixes, &antenna, Q_ACCEL_FREE, gate, None, None)?;
    let mut time_offset = None;
    let mut clock = StreamOffset::not_checked("time offset check switched off");
    let mut clock_pairs_found = Vec::new();
    if config.time_offset != TimeOffsetMode::Off {
        let rates = course_rates(&pass1);
        let direct = estimate_time_offset(p, &pass1, &rates);
        clock_pairs_found = clock_pairs(imu_clock, &direct, gnss_imu_pair(p, &rates));
        clock = joint_gnss_offset(&direct, &clock_pairs_found);
        if let (Some(tau), Some(sigma)) = (clock.offset_s, clock.sigma_s) {
            let compensate = apply_offset(&mut clock, tau, sigma, config, warnings);
            if compensate {
                let shift = match gnss_follows_imu(&clock, &direct, imu_clock) {
                    Some(s) => {
                        clock.applied_s = Some(s);
                        warnings.push(Warning::new(
                            WarningCode::TimeOffset,
                            format!(
                                "the GNSS offset rests on the course rate, whose lag behind the yaw \
                                 rate (the tyres' side-slip) rides on it; beyond the IMU's {:+.0} ms \
                                 (sigma {:.0} ms, from the yaw rate) it adds {:+.0} ms, within its own \
                                 3 sigma: the wheels' clock moved, and the GNSS times are shifted by \
                                 the IMU's offset",
                                1000.0 * s,
                                1000.0 * imu_clock.sigma_s.unwrap_or(f64::NAN),
                                1000.0 * (tau - s),
                            ),
                        ));
                        s
                    }
                    None => tau,
                };
                for f in &mut fixes {
                    f.t -= shift;
                }
                pass1 = smooth_positions(&fixes, &antenna, Q_ACCEL_FREE, gate, None, None)?;
            }
            time_offset = Some(TimeOffset {
                gnss_late_s: tau,
                sigma_s: sigma,
                compensated: compensate,
            });
        } else {
            warnings.push(Warning::new(
                WarningCode::TimeOffset,
                format!(
                    "the wheel/GNSS time offset could not be determined within +-{CLOCK_SEARCH_S:.1} s ({}); it is not checked",
                    clock.reason.as_deref().unwrap_or("no reason")
                ),
            ));
        }
    }
    Ok(Gnss {
        sigma_m: gnss_sigma_m,
        sigma_estimated: estimated,
        claim,
        fixes,
        antenna,
        alone: pass1,
        time_offset,
        clock,
        pairs: clock_pairs_found,
    })
}

/// The GNSS noise: the configured sigma, the fixes' own (median, when every
/// fix has one; not below the scatter the fixes show), or estimated from
/// the scatter (at least 0.3 m). With whether it was estimated, the check
/// of the receiver's claimed sigma, and the floor of a fix's own sigma (the
/// scatter measured, 0 without a check).
fn gnss_sigma(
    p: &Series,
    config: &CalibrationConfig,
    warnings: &mut Vec<Warning>,
) -> (f64, bool, Option<SigmaClaim>, f64) {
    let (gnss_sigma_m, estimated) = match config.gnss_sigma_m {
        Some(s) => (s, false),
        None => {
            let given: Vec<f64> = p.fixes.iter().filter_map(|f| f.sigma).collect();
            if given.len() == p.fixes.len() {
                let mut g = given;
                g.sort_by(f64::total_cmp);
                (g[g.len() / 2], false)
            } else {
                // Receivers filter their output, so the short-term scatter
                // understates the error: never below 0.3 m when estimated.
                (estimate_gnss_sigma(&p.fixes).unwrap_or(1.0).max(0.3), true)
            }
        }
    };
    // A receiver's sigma_m below the scatter its own fixes show is not
    // believed: the larger is used.
    let claim = match config.gnss_sigma_m {
        Some(_) => None,
        None => check_claimed_sigma(&p.fixes, warnings),
    };
    let floor = claim.map_or(0.0, |c| c.measured_m);
    let gnss_sigma_m = if estimated {
        gnss_sigma_m
    } else {
        gnss_sigma_m.max(floor)
    };
    (gnss_sigma_m, estimated, claim, floor)
}

/// The fixes for the reference, each with its sigma: the configured one,
/// its own (at least 1 cm and the `floor`), or the drive's `gnss_sigma_m`.
fn ref_fixes(p: &Series, config: &CalibrationConfig, gnss_sigma_m: f64, floor: f64) -> Vec<RefFix> {
    let sigma_of = |f: &Fix| -> f64 {
        match (config.gnss_sigma_m, f.sigma) {
            (Some(s), _) => s,
            (None, Some(s)) => s.max(0.01).max(floor),
            (None, None) => gnss_sigma_m,
        }
    };
    p.fixes
        .iter()
        .map(|f| RefFix {
            t: f.t,
            x: f.x,
            y: f.y,
            sigma: sigma_of(f),
            accepted: true,
        })
        .collect()
}

/// Whether the GNSS clock's offset `tau` (sigma `sigma`) is compensated:
/// when significant and the mode compensates. Warns of a significant
/// offset; marks `clock` applied or not.
fn apply_offset(
    clock: &mut StreamOffset,
    tau: f64,
    sigma: f64,
    config: &CalibrationConfig,
    warnings: &mut Vec<Warning>,
) -> bool {
    let significant = clock.significant(0.015).is_some();
    let compensate = significant && config.time_offset == TimeOffsetMode::Compensate;
    if significant {
        warnings.push(Warning::new(
            WarningCode::TimeOffset,
            format!(
                "gnss time stamps are {:.0} ms {} than the wheels' (sigma {:.0} ms, from the {}){}",
                1000.0 * tau.abs(),
                if tau > 0.0 { "later" } else { "earlier" },
                1000.0 * sigma,
                clock.from.as_deref().unwrap_or("speed"),
                if compensate {
                    "; the GNSS times were shifted to match"
                } else {
                    "; not compensated"
                }
            ),
        ));
    }
    clock.applied = compensate;
    compensate
}

/// The shift for the GNSS stamps where its offset rests on the course rate
/// (no speed pair determined it) and the IMU's yaw rate reads the same
/// clock more sharply: the course rate lags the yaw rate by the tyres'
/// side-slip (about [`SLIP_GAIN_TYPICAL`] v: 85 ms on the simulated paper
/// course), which a drive on a good clock leaves unapplied as not
/// significant, but which rides along once a moved wheel clock makes the
/// whole offset significant (the paper course with its wheel clock 1.5 s
/// off: 1.587 s applied, its 30 s outages' median error 1.32 -> 5.6 m).
/// Where the GNSS's offset beyond the IMU's is within its own 3 sigma, the
/// IMU's offset is the wheels' clock's shift and the GNSS is moved by it.
/// Both applied, the IMU's from its yaw rate and sharper than the GNSS's,
/// no drift on either; else `None`.
pub fn gnss_follows_imu(
    gnss: &StreamOffset,
    direct: &StreamOffset,
    imu: &StreamOffset,
) -> Option<f64> {
    let by_course = direct.from.as_deref() != Some("speed");
    let yaw = imu.from.as_deref() == Some("yaw rate");
    if !(by_course && yaw && gnss.applied && imu.applied) || gnss.drift.applied || imu.drift.applied
    {
        return None;
    }
    let (g, sg, i, si) = (gnss.offset_s?, gnss.sigma_s?, imu.offset_s?, imu.sigma_s?);
    let within = (g - i).abs() <= 3.0 * sg;
    (within && si < sg && i.is_finite()).then_some(i)
}

/// A typical side-slip gain k (beta = -k a_y), rad per m/s^2: the course
/// rate lags the yaw rate by about k v, a systematic error of the GNSS time
/// offset found from the course rate.
const SLIP_GAIN_TYPICAL: f64 = 0.005;

/// A typical distance of the GNSS antenna ahead of the rear axle, m (the
/// catalogue's `gnss_lever_arm` spans 0.1-2 m): the antenna's course leads
/// the body's heading by about l_x / v (its velocity turns with l_x w), a
/// systematic error of the time offset found from the course rate when the
/// antenna has not been calibrated yet. On wid-trial02, whose antenna the
/// calibration puts 0.49 m ahead, the lead weighted by the turns is 0.109 s
/// and the IMU-GNSS pair reads -0.11 +- 0.06 s where the speed gives 0.00.
const ANTENNA_AHEAD_TYPICAL_M: f64 = 0.5;

/// The estimated wheel/GNSS time offset.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TimeOffset {
    /// GNSS stamps late by this much relative to the wheels, s.
    pub gnss_late_s: f64,
    /// Its 1-sigma, s.
    pub sigma_s: f64,
    /// Whether the GNSS time stamps were shifted by it.
    pub compensated: bool,
}

/// GNSS noise from the fixes ([`crate::series::gnss_scatter_sigma`]).
pub(crate) fn estimate_gnss_sigma(fixes: &[Fix]) -> Option<f64> {
    let points: Vec<(f64, f64, f64)> = fixes.iter().map(|f| (f.t, f.x, f.y)).collect();
    crate::series::gnss_scatter_sigma(&points)
}

/// A claimed GNSS sigma is refuted when the fixes scatter more than this
/// many times the claim: the measured scatter ([`crate::series::gnss_scatter_sigma_robust`])
/// is a lower bound of the error, and with at least
/// [`CLAIM_MIN_DIFFERENCES`] differences its MAD is known to about 15 %
/// (1.1 / sqrt(n)), so twice the claim is 6 of its sigmas away.
pub const CLAIM_FACTOR: f64 = 2.0;

/// Fourth differences the check of a claimed sigma needs.
pub const CLAIM_MIN_DIFFERENCES: usize = 50;

/// A receiver's `sigma_m` the fixes' own scatter refutes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SigmaClaim {
    /// The median claimed sigma, m.
    pub claimed_m: f64,
    /// The scatter measured on the fixes, m (used instead).
    pub measured_m: f64,
}

/// The receiver's claimed sigma (median of the fixes' `sigma_m`) against
/// the scatter of the fixes themselves; `Some` with a warning naming
/// `sigma_m` when the scatter exceeds [`CLAIM_FACTOR`] times the claim.
fn check_claimed_sigma(fixes: &[Fix], warnings: &mut Vec<Warning>) -> Option<SigmaClaim> {
    let mut given: Vec<f64> = fixes.iter().filter_map(|f| f.sigma).collect();
    let claimed_m = stats::upper_median(&mut given)?;
    let points: Vec<(f64, f64, f64)> = fixes
        .iter()
        .filter(|f| f.sigma.is_some())
        .map(|f| (f.t, f.x, f.y))
        .collect();
    let (measured_m, n) = crate::series::gnss_scatter_sigma_robust(&points)?;
    if n < CLAIM_MIN_DIFFERENCES || measured_m <= CLAIM_FACTOR * claimed_m {
        return None;
    }
    warnings.push(Warning::new(
        WarningCode::GnssSigmaUnderstated,
        format!(
            "gnss.csv sigma_m claims {claimed_m:.2} m (median of {} fixes) but the fixes scatter {measured_m:.2} m from one to the next (fourth differences, which the drive's motion does not reach): the receiver understates its noise; its fixes are weighted with {measured_m:.2} m instead (set gnss_sigma_m to override)",
            given.len()
        ),
    ));
    Some(SigmaClaim {
        claimed_m,
        measured_m,
    })
}

/// Estimate the GNSS clock offset against the wheels over
/// +-[`CLOCK_SEARCH_S`] with [`offsets::fit_lag`]: the speed of the smoothed
/// GNSS track against the wheel speed at shifted times, `sum (v_gnss(t) - k
/// v_wheel(t - tau))^2` (k absorbs the unknown circumference; coarse grid,
/// then the fine grid and parabola near its minimum); where the speed hardly
/// changes, the GNSS course rate against the wheels' yaw rate (its sigma
/// includes the side-slip lag `SLIP_GAIN_TYPICAL v`). Not
/// determined (with the reason and the manoeuvre that would determine it)
/// when neither does.
fn estimate_time_offset(p: &Series, track: &PosTrack, rates: &CourseRates) -> StreamOffset {
    let h = 0.25;
    let n = p.len();
    if n < 3 {
        return StreamOffset::not_determined("too few wheel samples".to_string());
    }
    // Wheel speed and yaw rate over +-h at every wheel time (f32 to keep a
    // long drive small).
    let inc: Vec<f64> = (0..n)
        .map(|k| 0.5 * (p.dn_rl[k] + p.dn_rr[k]) * p.nominal_c)
        .collect();
    // Unsigned, as the GNSS speed is (a drive may reverse).
    let speed: Vec<f32> = offsets::windowed_rate(&p.t, &inc, h)
        .into_iter()
        .map(f32::abs)
        .collect();
    let inc: Vec<f64> = (0..n)
        .map(|k| (p.dn_rr[k] - p.dn_rl[k]) * p.nominal_c / p.track)
        .collect();
    let yaw_rate = offsets::windowed_rate(&p.t, &inc, h);
    drop(inc);
    let speeds: Vec<(f64, f64)> = (0..track.t.len())
        .filter(|&j| track.accepted[j])
        .map(|j| (track.t[j], track.speed(j)))
        .filter(|(_, v)| *v > 1.0)
        .collect();
    let fit = |obs: &[(f64, f64)], v: &[f32], intercept: bool| {
        offsets::fit_lag(
            obs,
            &offsets::Sampled { t: &p.t, v },
            CLOCK_SEARCH_S,
            2.0 * h,
            intercept,
        )
    };
    let by_speed = fit(&speeds, &speed, false);
    if let Ok(f) = offsets::judge(by_speed, CLOCK_SEARCH_S) {
        // Determined by the speed: the course rate is not needed.
        return offsets::StreamOffset::determined(&f, "speed");
    }
    let by_course = fit(&rates.obs, &yaw_rate, true).map(|mut f| {
        f.sigma_s = f.sigma_s.hypot(rates.slip_lag_s);
        f
    });
    let tries = vec![("speed", by_speed), ("course rate", by_course)];
    offsets::first_determined(
        tries,
        CLOCK_SEARCH_S,
        "speed changes (accelerating and braking) or turns with GNSS",
    )
}

/// The GNSS course rate at the accepted epochs of the smoothed track (both
/// neighbours accepted and faster than [`COURSE_MIN_SPEED`]), for the clock
/// offsets against the wheels' and the gyro's yaw rates.
struct CourseRates {
    /// (GNSS time, course rate rad/s).
    obs: Vec<(f64, f64)>,
    /// The course leads or lags the heading by the side-slip's response,
    /// about k v (beta = -k a_y): a systematic lag the fit cannot see at
    /// constant speed, added to the sigma of an offset found from it, s;
    /// with the lead of an antenna ahead of the axle (about l_x / v, see
    /// [`ANTENNA_AHEAD_TYPICAL_M`]) beside it.
    slip_lag_s: f64,
}

fn course_rates(track: &PosTrack) -> CourseRates {
    let mut obs = Vec::new();
    let mut course_speed = 0.0;
    let mut inverse_speed = 0.0;
    let m = track.t.len();
    for j in 1..m.saturating_sub(1) {
        if !(track.accepted[j - 1] && track.accepted[j] && track.accepted[j + 1]) {
            continue;
        }
        let (a, b) = (track.s[j - 1], track.s[j + 1]);
        let dt = track.t[j + 1] - track.t[j - 1];
        if track.speed(j - 1) > COURSE_MIN_SPEED
            && track.speed(j + 1) > COURSE_MIN_SPEED
            && dt > 0.0
        {
            let d = wrap_angle(b[3].atan2(b[2]) - a[3].atan2(a[2]));
            obs.push((track.t[j], d / dt));
            course_speed += track.speed(j);
            inverse_speed += 1.0 / track.speed(j).max(COURSE_MIN_SPEED);
        }
    }
    let n = obs.len().max(1) as f64;
    let slip_lag_s =
        (SLIP_GAIN_TYPICAL * course_speed / n).hypot(ANTENNA_AHEAD_TYPICAL_M * inverse_speed / n);
    CourseRates { obs, slip_lag_s }
}

/// The GNSS clock against the IMU's: the GNSS course rate against the
/// gyro's yaw rate (as prepared: on the IMU clock less `p.imu_shift_s`),
/// by [`offsets::fit_lag`]; its sigma includes the side-slip lag. The pair
/// that closes the chain wheels-IMU-GNSS when the GNSS's speed and course
/// do not determine its offset against the wheels directly (a drive at
/// near-constant speed whose wheel yaw rate is too coarse).
fn gnss_imu_pair(p: &Series, rates: &CourseRates) -> StreamOffset {
    let h = 0.25;
    let Some(gyro) = p.gyro.as_ref() else {
        return StreamOffset::not_checked("the drive has no usable gyro");
    };
    let (t, g): (Vec<f64>, Vec<f64>) =
        p.t.iter()
            .zip(gyro)
            .filter(|(_, g)| g.is_finite())
            .map(|(t, g)| (*t, *g))
            .unzip();
    if t.len() < 3 {
        return StreamOffset::not_determined("the gyro covers too few wheel samples".to_string());
    }
    let inc: Vec<f64> = std::iter::once(0.0)
        .chain(g.windows(2).map(|w| w[1] - w[0]))
        .collect();
    let yaw_rate = offsets::windowed_rate(&t, &inc, h);
    let fit = offsets::fit_lag(
        &rates.obs,
        &offsets::Sampled {
            t: &t,
            v: &yaw_rate,
        },
        CLOCK_SEARCH_S,
        2.0 * h,
        true,
    )
    .map(|mut f| {
        // Against the IMU's own clock.
        f.lag_s -= p.imu_shift_s;
        f.sigma_s = f.sigma_s.hypot(rates.slip_lag_s);
        f
    });
    offsets::first_determined(
        [("course rate against the gyro", fit)],
        CLOCK_SEARCH_S,
        "turns with GNSS",
    )
}

/// The pairs of streams compared (wheels-GNSS, wheels-IMU, IMU-GNSS), the
/// wheels-IMU pair's sigma widened by the lag the car itself puts between
/// the wheels' and the gyro's yaw rates ([`crate::clocks::IMU_PHYSICAL_LAG_S`]).
fn clock_pairs(
    imu_clock: &StreamOffset,
    direct: &StreamOffset,
    gnss_imu: StreamOffset,
) -> Vec<PairOffset> {
    let mut imu = imu_clock.clone();
    if let Some(s) = imu.sigma_s.as_mut() {
        *s = s.hypot(crate::clocks::IMU_PHYSICAL_LAG_S);
    }
    vec![
        PairOffset {
            base: ClockStream::Wheels,
            later: ClockStream::Gnss,
            offset: direct.clone(),
        },
        PairOffset {
            base: ClockStream::Wheels,
            later: ClockStream::Imu,
            offset: imu,
        },
        PairOffset {
            base: ClockStream::Imu,
            later: ClockStream::Gnss,
            offset: gnss_imu,
        },
    ]
}

/// The GNSS offset against the wheels over every pair ([`offsets::solve_offsets`]):
/// determined when the combination is (within [`offsets::MAX_OFFSET_SIGMA_S`]),
/// else the direct pair's result with why the chain did not help.
fn joint_gnss_offset(direct: &StreamOffset, pairs: &[PairOffset]) -> StreamOffset {
    match offsets::solve_offsets(pairs, ClockStream::Gnss) {
        Ok(j) if j.sigma_s <= offsets::MAX_OFFSET_SIGMA_S => StreamOffset {
            status: offsets::OffsetStatus::Determined,
            offset_s: Some(j.offset_s),
            sigma_s: Some(j.sigma_s),
            from: Some(if j.direct {
                direct.from.clone().unwrap_or(j.path)
            } else {
                j.path
            }),
            applied: false,
            applied_s: None,
            reason: None,
            drift: direct.drift.clone(),
            weak: None,
        },
        Ok(j) if direct.status != offsets::OffsetStatus::Determined => {
            let mut o = direct.clone();
            o.reason = Some(format!(
                "{}; through {}: sigma {:.2} s",
                o.reason.as_deref().unwrap_or("not determined"),
                j.path,
                j.sigma_s
            ));
            o
        }
        Err(why) if direct.status != offsets::OffsetStatus::Determined => {
            let mut o = direct.clone();
            o.reason = Some(format!(
                "{}; {why}",
                o.reason.as_deref().unwrap_or("not determined")
            ));
            o
        }
        _ => direct.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn offset(o: f64, sigma: f64, from: &str, applied: bool) -> StreamOffset {
        StreamOffset::for_test(o, sigma, from, applied)
    }

    #[test]
    fn the_gnss_follows_the_imu_only_where_its_offset_rests_on_the_course_rate() {
        // The paper course with its wheel clock 1.5 s off.
        let gnss = offset(1.587, 0.074, "wheels-gnss (course rate) + ...", true);
        let course = offset(1.59, 0.08, "course rate", true);
        let imu = offset(1.497, 0.009, "yaw rate", true);
        assert_eq!(gnss_follows_imu(&gnss, &course, &imu), Some(1.497));
        // Determined by the speed (comma2k19's 86 ms latency): its own.
        let speed = offset(1.587, 0.015, "speed", true);
        assert_eq!(
            gnss_follows_imu(&speed, &speed, &offset(1.482, 0.016, "yaw rate", true)),
            None
        );
        // Beyond its own 3 sigma of the IMU's: a latency of its own.
        assert_eq!(
            gnss_follows_imu(&gnss, &course, &offset(1.30, 0.009, "yaw rate", true)),
            None
        );
        // The IMU from its acceleration, or no sharper, or not applied: its own.
        assert_eq!(
            gnss_follows_imu(
                &gnss,
                &course,
                &offset(1.497, 0.009, "longitudinal acceleration", true)
            ),
            None
        );
        assert_eq!(
            gnss_follows_imu(&gnss, &course, &offset(1.497, 0.09, "yaw rate", true)),
            None
        );
        assert_eq!(
            gnss_follows_imu(&gnss, &course, &offset(1.497, 0.009, "yaw rate", false)),
            None
        );
    }
}
