//! Input checks and conversion: the drive turned into the compact series the
//! layers work on, with every skipped value listed in a warning.
//!
//! - Wheels: rows with a non-finite rear value are skipped (warning), the rest
//!   become revolution increments per wheel sample; a gap in the wheel stream
//!   breaks it into pieces (the models restart after a break).
//! - GNSS: non-finite rows skipped (warning). No GNSS is an error.
//! - IMU: the yaw rate is integrated to a cumulative angle, kept at the wheel
//!   times (NaN across pauses of the IMU stream). The accelerations are not
//!   copied: the reference reads them from the drive.
//! - The IMU clock's offset against the wheels is estimated over +-3 s
//!   ([`clocks::imu_offset`]) and, when significant and compensation is on,
//!   subtracted from the IMU time stamps before they are used.
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

use crate::clocks::{self, StreamOffset, CLOCK_SEARCH_S};
use crate::config::{CalibrationConfig, TimeOffsetMode, TrackWidthMode};
use crate::error::CalibrationError;
use crate::warnings::{Warning, WarningCode};
use drive_io::plausibility::{self, Finding};
use interfaces::drive::{Drive, HeadingSample, WheelConversionError, WheelSample, WheelUnit};

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
    /// The yaw-rate gyro's trapezoidal integral at each wheel time, rad (NaN
    /// where the IMU does not cover it); `None` without a usable IMU.
    pub gyro: Option<Vec<f64>>,
    /// True when the IMU has both horizontal accelerations.
    pub has_accel: bool,
    /// Finite absolute headings.
    pub headings: Vec<HeadingSample>,
    /// GNSS antenna position in the body frame (x forward, y left) from the rear-axle centre, m.
    pub lever_arm: [f64; 2],
    /// Whether `vehicle.toml` gives each coordinate of `lever_arm` (measured),
    /// or it is the axle-centre default.
    pub lever_arm_given: [bool; 2],
    /// Nominal circumference, m.
    pub nominal_c: f64,
    /// Nominal rear track, m.
    pub track: f64,
    /// Standstill intervals (start, end), s, at least 1 s long.
    pub standstill: Vec<(f64, f64)>,
    /// Lateral acceleration `v omega` from the wheels with the nominal
    /// values, averaged over 0.5 s (per-step increments of a quantised
    /// encoder are far too noisy for a side-slip model), m/s^2.
    pub lateral_accel: Vec<f32>,
    /// Offsets subtracted from rate-type wheel channels (rl, rr in the
    /// channel's unit) and the standstill seconds they come from.
    pub wheel_offsets: Option<(f64, f64, f64)>,
    /// The IMU clock offset against the wheels, determined or not (and why).
    pub imu_clock: StreamOffset,
    /// Subtracted from the IMU time stamps before use (the IMU offset when
    /// it is compensated, else 0), s. The reference subtracts it from the
    /// accelerations' times too.
    pub imu_shift_s: f64,
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

    /// The gyro's cumulative angle at `t` (linear between wheel times),
    /// `None` without gyro, outside the data or across an IMU pause.
    pub fn gyro_cum_at(&self, t: f64) -> Option<f64> {
        let g = self.gyro.as_ref()?;
        let n = self.t.len();
        if n < 2 || !(t >= self.t[0] && t <= self.t[n - 1]) {
            return None;
        }
        let i = self.t.partition_point(|&s| s <= t).clamp(1, n - 1);
        let (t0, t1) = (self.t[i - 1], self.t[i]);
        let f = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
        let v = g[i - 1] + f * (g[i] - g[i - 1]);
        v.is_finite().then_some(v)
    }

    /// Mean gyro rate between `t0` and `t1`, `None` when not covered.
    pub fn gyro_mean_rate(&self, t0: f64, t1: f64) -> Option<f64> {
        if t1 <= t0 {
            return None;
        }
        let g = self.gyro.as_ref()?;
        let i0 = self.t.partition_point(|&s| s < t0);
        let i1 = self.t.partition_point(|&s| s <= t1);
        if g[i0.min(g.len() - 1)..i1.min(g.len())]
            .iter()
            .any(|v| !v.is_finite())
        {
            return None;
        }
        Some((self.gyro_cum_at(t1)? - self.gyro_cum_at(t0)?) / (t1 - t0))
    }
}

/// The GNSS position noise measured on the fixes `(t, x, y)` (increasing
/// times), m: the MAD of the second differences of equally spaced fixes
/// (variance 6 sigma^2 for white noise), both axes pooled. `None` with
/// fewer than ten differences.
pub(crate) fn gnss_scatter_sigma(fixes: &[(f64, f64, f64)]) -> Option<f64> {
    let mut d = Vec::new();
    for w in fixes.windows(3) {
        let (h0, h1) = (w[1].0 - w[0].0, w[2].0 - w[1].0);
        if h0 <= 0.0 || h1 <= 0.0 || h0 > 1.5 || h1 > 1.5 || (h0 - h1).abs() > 0.25 * h0.max(h1) {
            continue;
        }
        d.push((w[2].1 - 2.0 * w[1].1 + w[0].1).abs());
        d.push((w[2].2 - 2.0 * w[1].2 + w[0].2).abs());
    }
    if d.len() < 10 {
        return None;
    }
    Some(1.4826 * stats::upper_median(&mut d)? / 6f64.sqrt())
}

/// The GNSS position noise measured on the fixes `(t, x, y)` (increasing
/// times) without the drive's dynamics, m: the MAD of the fourth
/// differences of five equally spaced fixes (variance 70 sigma^2 for white
/// noise; any cubic motion, so every constant jerk, cancels), both axes
/// pooled, with how many differences it rests on. `None` with fewer than
/// ten differences. Receivers filter their output, so this short-term
/// scatter is a lower bound of their error, never an overstatement.
pub(crate) fn gnss_scatter_sigma_robust(fixes: &[(f64, f64, f64)]) -> Option<(f64, usize)> {
    let mut d = Vec::new();
    for w in fixes.windows(5) {
        let h: Vec<f64> = w.windows(2).map(|p| p[1].0 - p[0].0).collect();
        let (lo, hi) = h
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
        if lo <= 0.0 || hi > 1.5 || hi - lo > 0.25 * hi {
            continue;
        }
        let diff4 = |k: fn(&(f64, f64, f64)) -> f64| {
            k(&w[0]) - 4.0 * k(&w[1]) + 6.0 * k(&w[2]) - 4.0 * k(&w[3]) + k(&w[4])
        };
        d.push(diff4(|f| f.1).abs());
        d.push(diff4(|f| f.2).abs());
    }
    if d.len() < 10 {
        return None;
    }
    let n = d.len();
    Some((1.4826 * stats::upper_median(&mut d)? / 70f64.sqrt(), n))
}

/// Check and convert `drive`. Skipped values go into `warnings`.
pub fn prepare(
    drive: &Drive,
    config: &CalibrationConfig,
    warnings: &mut Vec<Warning>,
) -> Result<Prepared, CalibrationError> {
    let vehicle = &drive.vehicle;
    vehicle
        .check_plausible()
        .map_err(CalibrationError::BadVehicle)?;
    let lever_arm = [
        vehicle.gnss.antenna_x_m.unwrap_or(0.0),
        vehicle.gnss.antenna_y_m.unwrap_or(0.0),
    ];

    // Counters that wrap are unwrapped and values beyond any car set aside
    // before anything reads them; a rear wheel impossible throughout (a
    // wrong unit, not a glitch) is refused first: it would distort every
    // check after this one. The other findings come after the basic checks
    // (an empty or wholly stuck channel is named as such).
    let (drive, repairs) = plausibility::repaired(drive);
    let drive: &Drive = &drive;
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
            _ => return Err(CalibrationError::ImplausibleInput(f.clone())),
        }
    }
    let findings = plausibility::check(drive);
    let (t, dn_rl, dn_rr, piece_starts, wheel_dt, wheel_offsets) = wheels(drive, warnings)?;
    let fixes = gnss(drive, warnings)?;
    if let Some(f) = findings.iter().find(|f| f.is_error()) {
        return Err(CalibrationError::ImplausibleInput(f.clone()));
    }
    if let (Some(&w0), Some(&w1), Some(g0), Some(g1)) =
        (t.first(), t.last(), fixes.first(), fixes.last())
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
    // A gyro dead for the whole drive has no clock to find.
    let gyro_dead = findings.iter().any(|f| {
        matches!(
            f,
            Finding::ImuStuck {
                field: "gz_rad_s",
                whole_drive: true,
                ..
            }
        )
    });
    let imu_clock = if gyro_dead {
        StreamOffset::not_checked(
            "the IMU's yaw rate is dead or stuck for the whole drive (imu_stuck)",
        )
    } else {
        imu_clock(drive, config, &t, &dn_rl, &dn_rr, warnings)
    };
    let imu_shift_s = if imu_clock.applied {
        imu_clock.offset_s.unwrap_or(0.0)
    } else {
        0.0
    };
    let (mut gyro, mut has_accel, imu_end) = imu(drive, &t, imu_shift_s, warnings);
    for f in &findings {
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
                        gyro = None;
                        "the gyro is dropped: no gyro bias or scale is fitted and no gyro heading is used"
                            .to_string()
                    }
                    ("gz_rad_s", _) => {
                        if let Some(g) = gyro.as_mut() {
                            for (gk, tk) in g.iter_mut().zip(&t) {
                                if *tk > *t_start_s - imu_shift_s && *tk < *t_end_s - imu_shift_s {
                                    *gk = f64::NAN;
                                }
                            }
                        }
                        format!("the gyro is not used from t = {t_start_s:.2} to {t_end_s:.2} s")
                    }
                    _ if has_accel => {
                        has_accel = false;
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
    let headings = heading(drive, warnings);
    check_stream_ends(&t, &fixes, imu_end, warnings);

    let standstill = standstill_intervals(&t, &dn_rl, &dn_rr, vehicle.nominal_circumference_m);
    let lateral_accel = lateral_accel(
        &t,
        &dn_rl,
        &dn_rr,
        vehicle.nominal_circumference_m,
        vehicle.track_width_m,
    );

    Ok(Prepared {
        t,
        dn_rl,
        dn_rr,
        piece_starts,
        wheel_dt,
        fixes,
        gyro,
        has_accel,
        headings,
        lever_arm,
        lever_arm_given: [
            vehicle.gnss.antenna_x_m.is_some(),
            vehicle.gnss.antenna_y_m.is_some(),
        ],
        nominal_c: vehicle.nominal_circumference_m,
        track: vehicle.track_width_m,
        standstill,
        lateral_accel,
        wheel_offsets,
        imu_clock,
        imu_shift_s,
    })
}

/// The largest lag between the wheels' and the gyro's yaw rate that the car
/// itself can cause, s: an IMU offset within it is reported, not applied.
pub const IMU_PHYSICAL_LAG_S: f64 = 0.05;

/// The IMU clock offset against the wheels ([`clocks::imu_offset`]),
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
    let rows: Vec<clocks::ImuRow> = rows
        .iter()
        .map(|r| (r.t_s, r.gz_rad_s, r.ax_m_s2))
        .collect();
    let wheels = clocks::WheelTrack {
        t,
        dn_rl,
        dn_rr,
        circumference_m: drive.vehicle.nominal_circumference_m,
        track_m: drive.vehicle.track_width_m,
    };
    let mut o = clocks::imu_offset(&wheels, &rows, CLOCK_SEARCH_S);
    let ts: Vec<f64> = rows
        .iter()
        .take(10_001)
        .map(|r| r.0)
        .filter(|t| t.is_finite())
        .collect();
    let interval = clocks::median_interval(&ts).unwrap_or(0.01).max(0.005);
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
        _ if o.status == clocks::OffsetStatus::NotDetermined => {
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
    let (k_rl, k_rr) = (scale(units.rl)?, scale(units.rr)?);
    let offsets = rate_offsets(
        samples,
        units,
        k_rl,
        k_rr,
        drive.vehicle.nominal_circumference_m,
    );
    let (o_rl, o_rr) = offsets.map_or((0.0, 0.0), |o| (o.0, o.1));
    // Median sample interval from the first rows (enough to set the gap threshold).
    let mut dts: Vec<f64> = samples
        .windows(2)
        .take(10_000)
        .map(|w| w[1].t_s - w[0].t_s)
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    let wheel_dt = stats::upper_median(&mut dts).unwrap_or(0.01).max(1e-4);
    let gap_threshold = (10.0 * wheel_dt).max(0.5);

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
    if skipped > 0 {
        warnings.push(Warning::new(
            WarningCode::NonFiniteSamples,
            format!(
                "wheels: {skipped} of {} rows have a non-finite time or rl/rr value (or break the time order) and were skipped (first at t = {:.3} s)",
                samples.len(),
                first_bad.unwrap_or(f64::NAN)
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
    Ok((t, dn_rl, dn_rr, piece_starts, wheel_dt, offsets))
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
    let usable = |r: &&interfaces::drive::ImuSample| r.t_s.is_finite() && r.gz_rad_s.is_finite();
    let mut dts: Vec<f64> = rows
        .iter()
        .filter(usable)
        .take(10_000)
        .map(|r| r.t_s)
        .collect::<Vec<_>>()
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    let threshold = (10.0 * stats::upper_median(&mut dts).unwrap_or(0.01)).max(0.5);
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
        has_accel |= r.ax_m_s2.is_some_and(f64::is_finite) && r.ay_m_s2.is_some_and(f64::is_finite);
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
    if skipped > 0 {
        warnings.push(Warning::new(
            WarningCode::NonFiniteSamples,
            format!(
                "imu: {skipped} of {} rows have a non-finite time or gz_rad_s (or break the time order) and were skipped (first at t = {:.3} s)",
                rows.len(),
                first_bad.unwrap_or(f64::NAN)
            ),
        ));
    }
    if used < 10 {
        warnings.push(Warning::new(
            WarningCode::NoImu,
            format!("imu: only {used} usable yaw-rate samples: the IMU is ignored"),
        ));
        return (None, false, None);
    }
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
    (Some(out), has_accel, last_t)
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
