//! Physically impossible or broken values in a drive, found on the
//! in-memory [`Drive`] (pure functions; the readers keep values as given so
//! that conversions stay lossless, and refuse only what the format forbids:
//! a NaN or infinite value is already an error on reading).
//!
//! Thresholds come from physics, never from a particular data set:
//! - no car's wheel turns faster than [`MAX_CAR_SPEED_M_S`] over its
//!   circumference (and at least [`MAX_WHEEL_REV_PER_S`] is allowed);
//! - a car cannot turn about a point between its rear wheels, so the rear
//!   wheels never turn in opposite directions over a drive, and one rear
//!   wheel cannot stand still while the other rolls on;
//! - a circumference mismatch of a few per cent bends the wheels' path by at
//!   most [`MAX_CIRCUMFERENCE_MISMATCH`] / track; a sharper bend is a turn;
//! - the effective track differs from the physical one by tyre slip and
//!   scrub (a few per cent): a track the wheels and the gyro put more than
//!   [`TRACK_CONTRADICTION_REL`] (and [`TRACK_CONTRADICTION_SIGMAS`] of its
//!   own uncertainty) away from `vehicle.toml`'s contradicts the drive
//!   ([`Finding::TrackWidthContradicted`], see there for the method);
//! - a wheel stream that stops for more than [`PAUSE_FACTOR`] of its own
//!   sample intervals and more than [`PAUSE_MIN_S`] is a pause in the drive
//!   ([`Finding::WheelPause`]), not a late sample.
//!
//! [`unwrap_wheel_counters`] repairs encoder counters that wrap (8, 16 or
//! 32 bit), [`set_aside_impossible`] sets aside wheel values beyond any car
//! (a logger glitch costs its samples, not the drive; [`repaired`] does
//! both); [`check`] reports the rest as [`Finding`]s, each an error or a
//! warning ([`Finding::severity`]).

use interfaces::drive::{Drive, ImuSample, Wheel, WheelSample, WheelUnit};
use std::borrow::Cow;
use std::f64::consts::{FRAC_PI_2, TAU};

mod gnss_epochs;
mod set_aside;
pub use gnss_epochs::{gnss_on_epochs, MIN_JITTER_S, MIN_SCATTER_GAIN};
pub use set_aside::{set_aside_impossible, MAX_SET_ASIDE_SHARE, SPIKE_LOOKAHEAD};

/// Fastest plausible car, m/s.
pub const MAX_CAR_SPEED_M_S: f64 = 100.0;
/// The wheel rate always allowed, rev/s (100 m/s on a 1 m wheel); with a
/// smaller nominal circumference the limit is [`MAX_CAR_SPEED_M_S`] / c.
pub use interfaces::drive::MAX_WHEEL_REV_PER_S;
/// Largest relative circumference difference between the rear wheels that
/// tyres explain; a sharper bend of the wheels' path than this / track is
/// a real turn.
pub const MAX_CIRCUMFERENCE_MISMATCH: f64 = 0.03;
/// Distance a wheel must roll before its partner's standstill, or the
/// drive's direction, counts as evidence, m.
pub const EVIDENCE_DISTANCE_M: f64 = 20.0;
/// Turning (by the wheels) that a constant gyro cannot have missed, rad.
pub const EVIDENCE_TURN_RAD: f64 = FRAC_PI_2;

/// A track from the wheels and the gyro this far (relative) from
/// `vehicle.toml`'s contradicts it: tyre slip and scrub make the effective
/// track differ from the physical one by 1-3 %, a MEMS gyro's scale error is
/// a few per cent, and an uncorrected circumference mismatch adds a little;
/// 15 % is beyond all of them together (the calibrator itself does not
/// believe a fitted track more than 10 % from the nominal).
pub const TRACK_CONTRADICTION_REL: f64 = 0.15;
/// ... and this many standard errors of the fitted track from it (so that a
/// drive with little turning cannot raise it by noise).
pub const TRACK_CONTRADICTION_SIGMAS: f64 = 5.0;
/// A window turns when the gyro's mean rate (bias removed) is this many of
/// its own noise sigmas from zero: the gyro noise then biases the fitted
/// ratio by at most 1 / (1 + 1/25), 4 % (errors in the regressor).
pub const TURN_NOISE_SIGMAS: f64 = 5.0;
/// Standard errors between the wheels-to-gyro turn ratios +1 (signs
/// right) and -1 (signs wrong) before the gyro decides which.
pub const SIGN_SIGMAS: f64 = 10.0;
/// The wheels' and the gyro's heading changes must correlate at least this
/// well (in absolute value) before the gyro decides a sign.
pub const MIN_SIGN_CORRELATION: f64 = 0.5;
/// Standard errors from zero the GNSS course's turns per wheel turn must
/// lie before their sign counts (one-sided, about 3e-5 by chance; GNSS
/// jumps are taken out first).
pub const COURSE_SIGN_SIGMAS: f64 = 4.0;
/// Turning by the wheels that a gyro exactly constant meanwhile cannot
/// have missed, rad (20 degrees: a MEMS gyro resolves thousandths of a
/// degree per second, and real ones never hold a value for more than a few
/// samples while a car drives).
pub const STUCK_EVIDENCE_TURN_RAD: f64 = 0.35;
/// Windows of the gentle-turning evidence, s.
pub const VARYING_TURN_WINDOW_S: f64 = 2.0;
/// Windows of the track comparison and the noise estimate, s.
pub const TRACK_WINDOW_S: f64 = 1.0;
/// A gyro whose noise over a [`TRACK_WINDOW_S`] window is below this is taken
/// as this noisy, rad/s (0.006 deg/s, far below any vehicle gyro; keeps a
/// noise-free simulated gyro from making every window a turn).
pub const GYRO_NOISE_FLOOR_RAD_S: f64 = 1e-4;
/// A gap in the wheel stream longer than this many median sample intervals
/// (and [`PAUSE_MIN_S`]) is a pause of the drive.
pub const PAUSE_FACTOR: f64 = 100.0;
/// A pause lasts at least this long, s (a sample lost or late is no pause).
pub const PAUSE_MIN_S: f64 = 5.0;

/// How serious a [`Finding`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Severity {
    /// The data cannot be used as it is (a calibration must refuse it).
    Error,
    /// The data are usable; a user should know.
    Warning,
}

/// Something physically impossible or broken in a drive.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Finding {
    /// A wheel turns faster than any car's wheel can.
    #[error(
        "wheels.{}: at t = {t_s} s the value {} ({}) means {rev_per_s:.4e} rev/s, beyond any car \
         (limit {limit_rev_per_s:.0} rev/s); {samples} sample(s) like it",
        wheel.prefix(),
        num(*value),
        unit.suffix()
    )]
    ImpossibleWheelRate {
        /// The wheel.
        wheel: Wheel,
        /// Time of the first offending sample, s.
        t_s: f64,
        /// Its value as given (in `unit`).
        value: f64,
        /// The wheel's unit.
        unit: WheelUnit,
        /// The wheel rate it implies (for counts: its step over the step's time), rev/s.
        rev_per_s: f64,
        /// The limit, rev/s.
        limit_rev_per_s: f64,
        /// Samples over the limit.
        samples: usize,
    },
    /// Wheel values beyond any car (a logger glitch) set aside
    /// ([`set_aside_impossible`]): the rest of the channel is used.
    #[error(
        "wheels.{}: {} beyond any car (limit {limit_rev_per_s:.0} rev/s; the first at t = {t_s} s: {} ({}) \
         means {rev_per_s:.4e} rev/s){}{}",
        wheel.prefix(),
        set_aside_text(*set_aside, *jumps, *samples),
        num(*value),
        unit.suffix(),
        if *jumps > 0 {
            "; the counter continues from its last good value after each jump"
        } else {
            ""
        },
        match wheel {
            Wheel::Rl | Wheel::Rr => "; the rest of the channel is used",
            _ => "; the rear-wheel model does not read this channel",
        }
    )]
    WheelSamplesSetAside {
        /// The wheel.
        wheel: Wheel,
        /// Time of the first offending sample, s.
        t_s: f64,
        /// Its value as given (in `unit`).
        value: f64,
        /// The wheel's unit.
        unit: WheelUnit,
        /// The wheel rate it implies, rev/s.
        rev_per_s: f64,
        /// The limit, rev/s.
        limit_rev_per_s: f64,
        /// Samples set aside (impossible rates, counter spikes).
        set_aside: usize,
        /// Counter jumps that stayed, re-referenced.
        jumps: usize,
        /// Samples of the wheel with a value.
        samples: usize,
    },
    /// An encoder counter wraps around; the values were unwrapped.
    #[error(
        "wheels.{}: the tick counter wraps {wraps} time(s) as a {bits}-bit counter (first at t = {first_t_s} s); \
         unwrapped",
        wheel.prefix()
    )]
    CounterWrapped {
        /// The wheel.
        wheel: Wheel,
        /// Counter width, bits.
        bits: u32,
        /// Wraps found.
        wraps: usize,
        /// Time of the first, s.
        first_t_s: f64,
    },
    /// The rear wheels turn in opposite directions over the drive: one
    /// wheel's sign is reversed.
    #[error(
        "wheels: rl turns {rl_revs:+.1} and rr {rr_revs:+.1} revolutions over the drive, in opposite directions; \
         a car cannot turn about a point between its rear wheels: one wheel's sign is reversed"
    )]
    WheelsOpposed {
        /// Net rear-left revolutions.
        rl_revs: f64,
        /// Net rear-right revolutions.
        rr_revs: f64,
    },
    /// Both rear wheels count down while the car drives forward: their
    /// turns are opposite to the gyro's (or, without a gyro, the GNSS
    /// course's).
    #[error(
        "wheels: both rear wheels count backward ({backward_percent:.0} % of their distance) while the car \
         drives forward (the wheels' turns are {ratio:+.2} times {against}'s turns over {turned_rad:.1} rad of \
         turning): both wheel signs are reversed"
    )]
    WheelsReversed {
        /// Share of the wheel distance driven backward, %.
        backward_percent: f64,
        /// Wheel heading change per heading change of `against` (about -1).
        ratio: f64,
        /// Turning compared, rad.
        turned_rad: f64,
        /// What the wheels were compared with: "the gyro" or "the GNSS course".
        against: &'static str,
    },
    /// The rear wheels turn the wrong way round in curves while the car
    /// drives forward: rl and rr are exchanged.
    #[error(
        "wheels: the wheels' turns are {ratio:+.2} times {against}'s turns over {turned_rad:.1} rad of \
         turning while the car drives forward: rl and rr are exchanged{}",
        if *against == "the gyro" {
            ""
        } else {
            " (or the GNSS track is mirrored, lat_deg and lon_deg or x_m and y_m exchanged: without a gyro \
             the drive cannot tell which)"
        }
    )]
    WheelsSwapped {
        /// Wheel heading change per heading change of `against` (about -1).
        ratio: f64,
        /// Turning compared, rad.
        turned_rad: f64,
        /// What the wheels were compared with: "the gyro" or "the GNSS course".
        against: &'static str,
    },
    /// The GNSS track turns the other way round than the gyro and the
    /// wheels, which agree: the track is mirrored (latitude and longitude,
    /// or east and north, exchanged).
    #[error(
        "gnss: the GNSS course turns {ratio:+.2} times as the gyro and the wheels do (they agree with each \
         other) over {turned_rad:.1} rad of turning: the GNSS track is mirrored; are {} exchanged?",
        if *lat_lon { "lat_deg and lon_deg" } else { "x_m and y_m" }
    )]
    GnssMirrored {
        /// GNSS course change per wheel heading change (about -1).
        ratio: f64,
        /// GNSS course turning compared, rad.
        turned_rad: f64,
        /// The fixes were given as latitude and longitude.
        lat_lon: bool,
    },
    /// An IMU value is exactly constant while the wheels show the motion it
    /// should measure (a dead or stuck sensor).
    #[error(
        "imu.{field}: {samples} samples from t = {t_start_s} to {t_end_s} s are all exactly {} while the \
         wheels show {evidence}: the sensor is dead or stuck{}",
        num(*value),
        if *whole_drive { " for the whole drive" } else { "" }
    )]
    ImuStuck {
        /// `gz_rad_s`, `ax_m_s2` or `ay_m_s2`.
        field: &'static str,
        /// The constant value.
        value: f64,
        /// Samples in the stuck stretch.
        samples: usize,
        /// Start of the stretch, s.
        t_start_s: f64,
        /// End of the stretch, s.
        t_end_s: f64,
        /// What the wheels show meanwhile.
        evidence: String,
        /// The stretch holds (nearly) every sample of the field.
        whole_drive: bool,
    },
    /// One rear wheel's value stays exactly constant while the other rolls on.
    #[error(
        "wheels.{}: stays exactly at {} from t = {t_start_s} to {t_end_s} s while wheels.{} rolls \
         {other_distance_m:.0} m{}: the {} wheel is stuck or its channel broken",
        wheel.prefix(),
        num(*value),
        other.prefix(),
        if *changing_speed { " and changes speed" } else { "" },
        wheel.prefix()
    )]
    WheelStuck {
        /// The stuck wheel.
        wheel: Wheel,
        /// The other rear wheel.
        other: Wheel,
        /// The constant value.
        value: f64,
        /// Start of the stretch, s.
        t_start_s: f64,
        /// End of the stretch, s.
        t_end_s: f64,
        /// Distance the other wheel rolls meanwhile (nominal circumference), m.
        other_distance_m: f64,
        /// The other wheel's speed changes meanwhile (rate units).
        changing_speed: bool,
        /// The stretch is a large part (a fifth or more) of the drive's distance.
        major: bool,
    },
    /// `vehicle.toml`'s track width contradicts the drive: the wheels' yaw
    /// rate `c (n_rr' - n_rl') / B_nominal` is `s` times the gyro's over the
    /// turning windows, so the effective track is `s B_nominal`.
    ///
    /// Method: [`TRACK_WINDOW_S`] windows of the rear wheels (nominal
    /// circumference) and the IMU's `gz` (trapezoidal integral), none across
    /// a pause of either stream. The gyro's bias and noise come from the
    /// drive's standstill windows (median and MAD of the mean rate; at least
    /// 3), else the bias from the windows where the wheels bend less than a
    /// circumference mismatch explains and the noise from the gyro's
    /// sample-to-sample scatter (white noise scaled to the window). A window
    /// turns when its gyro rate is [`TURN_NOISE_SIGMAS`] noise sigmas from
    /// zero. Over those windows a least-squares fit `dpsi_wheels = s
    /// dpsi_gyro + mu ds` (`mu`: a circumference mismatch bends the wheels'
    /// path in proportion to distance; left out where the drive cannot tell
    /// it from the turning), one pass of 5-MAD outlier removal, standard
    /// error from the residuals (windows taken as independent). Reported when
    /// `s` is more than [`TRACK_CONTRADICTION_REL`] and more than
    /// [`TRACK_CONTRADICTION_SIGMAS`] standard errors from 1, with at least
    /// 10 turning windows and [`EVIDENCE_TURN_RAD`] of turning.
    ///
    /// A gyro with a scale error `k` confounds this (it reads `(1 + k)` times
    /// the yaw rate, and the track comes out `1 / (1 + k)` times the true
    /// one), so this is only a warning: the calibrator can fit the track.
    #[error(
        "vehicle.toml's track_width_m = {nominal_m} m contradicts the drive: the wheels and the gyro agree on \
         {effective_m:.3} ± {sigma_m:.3} m ({:+.0} %, over {windows} turning windows, {:.0} deg of turning); \
         check track_width_m (a gyro scale error would also show this way)",
        100.0 * (effective_m / nominal_m - 1.0),
        turned_rad.to_degrees()
    )]
    TrackWidthContradicted {
        /// `vehicle.toml`'s track width, m.
        nominal_m: f64,
        /// The effective track the wheels and the gyro agree on, m.
        effective_m: f64,
        /// Its standard error, m.
        sigma_m: f64,
        /// Turning windows used.
        windows: usize,
        /// The gyro's turning over them, rad.
        turned_rad: f64,
    },
    /// The wheel stream pauses: no wheel sample for far longer than its own
    /// sample interval (more than [`PAUSE_FACTOR`] median intervals and
    /// [`PAUSE_MIN_S`]).
    #[error(
        "wheels: the stream pauses for {duration_s:.1} s at t = {t_s} s ({:.0} times its median sample \
         interval of {median_interval_s:.3e} s): the drive has a hole there",
        duration_s / median_interval_s
    )]
    WheelPause {
        /// Last wheel sample before the pause, s.
        t_s: f64,
        /// Length of the pause, s.
        duration_s: f64,
        /// The wheel stream's median sample interval, s.
        median_interval_s: f64,
    },
    /// GNSS stamps that jitter about the receiver's regular epochs, the
    /// fixes read at their epochs ([`gnss_on_epochs`]).
    #[error(
        "gnss: the stamps jitter by {:.1} ms RMS about the receiver's regular epochs; {fixes} fixes \
         are read at their epochs (each fix's distance from its neighbours' line: {scatter_stamps_m:.3} m \
         at the stamps, {scatter_epochs_m:.3} m at the epochs)",
        1000.0 * jitter_rms_s
    )]
    GnssStampsOnEpochs {
        /// The stamps' jitter about the epochs, RMS, s.
        jitter_rms_s: f64,
        /// Fixes moved to their epochs.
        fixes: usize,
        /// The fixes' RMS distance from their neighbours' line at the stamps, m.
        scatter_stamps_m: f64,
        /// The same at the epochs, m.
        scatter_epochs_m: f64,
    },
}

impl Finding {
    /// Whether the finding makes the drive unusable as it is.
    pub fn severity(&self) -> Severity {
        match self {
            Finding::ImpossibleWheelRate { .. }
            | Finding::WheelsOpposed { .. }
            | Finding::WheelsReversed { .. }
            | Finding::WheelsSwapped { .. }
            | Finding::GnssMirrored { .. } => Severity::Error,
            Finding::WheelStuck { major, .. } if *major => Severity::Error,
            Finding::CounterWrapped { .. }
            | Finding::WheelSamplesSetAside { .. }
            | Finding::ImuStuck { .. }
            | Finding::WheelStuck { .. }
            | Finding::TrackWidthContradicted { .. }
            | Finding::WheelPause { .. }
            | Finding::GnssStampsOnEpochs { .. } => Severity::Warning,
        }
    }

    /// True for [`Severity::Error`].
    pub fn is_error(&self) -> bool {
        self.severity() == Severity::Error
    }

    /// The severity and the message, as `info` shows (and serialises) it.
    pub fn summary(&self) -> FindingSummary {
        FindingSummary {
            severity: self.severity(),
            message: self.to_string(),
        }
    }
}

/// A [`Finding`] as text with its [`Severity`] (for summaries and JSON).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FindingSummary {
    /// `error` (a calibration refuses the drive) or `warning`.
    pub severity: Severity,
    /// The finding's message (names the stream, the time and the value).
    pub message: String,
}

/// "2 of 60000 samples set aside", "1 counter jump", or both.
fn set_aside_text(set_aside: usize, jumps: usize, samples: usize) -> String {
    let mut parts = Vec::new();
    if set_aside > 0 {
        parts.push(format!("{set_aside} of {samples} samples set aside"));
    }
    if jumps > 0 {
        parts.push(format!(
            "{jumps} counter jump{} re-referenced",
            if jumps == 1 { "" } else { "s" }
        ));
    }
    parts.join(" and ")
}

/// A value as text: plain, or in exponent form when very large or small
/// (`1e308`, not 309 digits).
fn num(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && !(1e-4..1e15).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

fn value_of(s: &WheelSample, w: Wheel) -> Option<f64> {
    match w {
        Wheel::Rl => Some(s.rl),
        Wheel::Rr => Some(s.rr),
        Wheel::Fl => s.fl,
        Wheel::Fr => s.fr,
    }
}

fn set_value(s: &mut WheelSample, w: Wheel, v: f64) {
    match w {
        Wheel::Rl => s.rl = v,
        Wheel::Rr => s.rr = v,
        Wheel::Fl => s.fl = Some(v),
        Wheel::Fr => s.fr = Some(v),
    }
}

/// Revolutions per unit (per unit·s for rates); `None` when the unit cannot
/// be converted (ticks without a positive `ticks_per_rev`, ...).
fn rev_scale(drive: &Drive, unit: WheelUnit) -> Option<f64> {
    let c = drive.vehicle.nominal_circumference_m;
    match unit {
        WheelUnit::Rev => Some(1.0),
        WheelUnit::Ticks => drive
            .vehicle
            .ticks_per_rev
            .filter(|t| t.is_finite() && *t > 0.0)
            .map(|t| 1.0 / t),
        WheelUnit::RadS => Some(1.0 / TAU),
        WheelUnit::MS => (c.is_finite() && c > 0.0).then(|| 1.0 / c),
    }
}

/// The wheel-rate limit of this drive, rev/s.
pub fn wheel_rate_limit(drive: &Drive) -> f64 {
    let c = drive.vehicle.nominal_circumference_m;
    if c.is_finite() && c > 0.0 {
        MAX_WHEEL_REV_PER_S.max(MAX_CAR_SPEED_M_S / c)
    } else {
        MAX_WHEEL_REV_PER_S
    }
}

// ------------------------------------------------------------ counter wraps

/// Counter widths tried, smallest first.
const COUNTER_BITS: [u32; 3] = [8, 16, 32];

/// Unwrap the `_ticks` wheel counters that wrap around (8, 16 or 32 bit,
/// signed or unsigned): a step of about minus the counter's modulus (plus,
/// driving backward) while the neighbouring steps are normal. Returns the
/// corrected drive and a [`Finding::CounterWrapped`] per wheel, or `None`
/// when no counter wraps.
pub fn unwrap_wheel_counters(drive: &Drive) -> Option<(Drive, Vec<Finding>)> {
    let mut out: Option<Drive> = None;
    let mut findings = Vec::new();
    for wheel in Wheel::ALL {
        if drive.wheels.units.of(wheel) != Some(WheelUnit::Ticks) {
            continue;
        }
        let samples = &drive.wheels.samples;
        let Some((bits, wraps)) = counter_wraps(samples, wheel) else {
            continue;
        };
        let modulus = 2f64.powi(bits as i32);
        let d = out.get_or_insert_with(|| drive.clone());
        let mut offset = 0.0;
        let mut next = wraps.iter().peekable();
        for (i, s) in d.wheels.samples.iter_mut().enumerate() {
            if let Some(&&(k, sign)) = next.peek() {
                if k == i {
                    offset -= sign * modulus;
                    next.next();
                }
            }
            if let Some(v) = value_of(s, wheel).filter(|v| v.is_finite()) {
                set_value(s, wheel, v + offset);
            }
        }
        findings.push(Finding::CounterWrapped {
            wheel,
            bits,
            wraps: wraps.len(),
            first_t_s: wraps.first().map_or(f64::NAN, |&(k, _)| samples[k].t_s),
        });
    }
    out.map(|d| (d, findings))
}

/// The counter width and the wraps (sample index, sign of the raw step) of
/// one wheel's counter, when it wraps.
fn counter_wraps(samples: &[WheelSample], wheel: Wheel) -> Option<(u32, Vec<(usize, f64)>)> {
    // (sample index, value) of the finite values.
    let values: Vec<(usize, f64)> = samples
        .iter()
        .enumerate()
        .filter_map(|(i, s)| value_of(s, wheel).filter(|v| v.is_finite()).map(|v| (i, v)))
        .collect();
    if values.len() < 3 {
        return None;
    }
    let (lo, hi) = values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &(_, v)| {
            (a.min(v), b.max(v))
        });
    // The narrowest counter that holds every value.
    let bits = COUNTER_BITS
        .into_iter()
        .find(|&b| hi - lo < 2f64.powi(b as i32))?;
    let modulus = 2f64.powi(bits as i32);
    let steps: Vec<f64> = values.windows(2).map(|w| w[1].1 - w[0].1).collect();
    let big = |s: f64| s.abs() > 0.5 * modulus;
    let mut wraps = Vec::new();
    for (j, &s) in steps.iter().enumerate() {
        if !big(s) {
            continue;
        }
        // Neighbouring steps (up to 5 each side) that are not wraps themselves.
        let lo_j = j.saturating_sub(5);
        let hi_j = (j + 6).min(steps.len());
        let scale = steps[lo_j..hi_j]
            .iter()
            .enumerate()
            .filter(|&(k, s)| lo_j + k != j && !big(*s))
            .map(|(_, s)| s.abs())
            .fold(0.0, f64::max);
        let corrected = s - s.signum() * modulus;
        // Normal: like its neighbours, give or take a few counts.
        if corrected.abs() <= 2.0 * scale + 2.0 {
            wraps.push((values[j + 1].0, s.signum()));
        }
    }
    (!wraps.is_empty()).then_some((bits, wraps))
}

// ------------------------------------------------------------ the checks

/// The drive as the models read it: counters that wrap unwrapped
/// ([`unwrap_wheel_counters`]), then wheel values beyond any car set aside
/// ([`set_aside_impossible`]), then GNSS stamps that jitter read at the
/// receiver's epochs ([`gnss_on_epochs`]), with a finding for each repair (and
/// [`Finding::ImpossibleWheelRate`], an error, for a rear wheel that is
/// impossible throughout). The drive is borrowed when nothing was repaired.
pub fn repaired(drive: &Drive) -> (Cow<'_, Drive>, Vec<Finding>) {
    let mut findings = Vec::new();
    let mut current = Cow::Borrowed(drive);
    if let Some((d, f)) = unwrap_wheel_counters(&current) {
        findings.extend(f);
        current = Cow::Owned(d);
    }
    if let Some((d, f)) = set_aside_impossible(&current) {
        findings.extend(f);
        current = Cow::Owned(d);
    }
    if let Some((d, f)) = gnss_on_epochs(&current) {
        findings.push(f);
        current = Cow::Owned(d);
    }
    (current, findings)
}

/// Every [`Finding`] about `drive` as it is read: the repairs
/// ([`repaired`]) and then [`check`] on the repaired drive (what the
/// calibrator sees; `info` and `convert` print these).
pub fn findings(drive: &Drive) -> Vec<Finding> {
    let (d, mut out) = repaired(drive);
    out.extend(check(&d));
    out
}

/// Every [`Finding`] about `drive` except its repairs (run [`repaired`]
/// first: a wrap or a glitch otherwise looks like an impossible wheel rate,
/// an error).
pub fn check(drive: &Drive) -> Vec<Finding> {
    let mut out = Vec::new();
    for wheel in Wheel::ALL {
        out.extend(impossible_rate(drive, wheel));
    }
    out.extend(wheel_pauses(drive));
    let Some(rear) = Rear::of(drive) else {
        return out;
    };
    out.extend(rear.opposed());
    let stuck_imu = imu_stuck(drive, &rear);
    // A gyro stuck anywhere is no witness of the wheels' turns.
    let gyro = if stuck_imu.iter().any(|f| {
        matches!(
            f,
            Finding::ImuStuck {
                field: "gz_rad_s",
                ..
            }
        )
    }) {
        None
    } else {
        wheel_gyro_fit(drive, &rear)
    };
    let signs = rear.reversed(drive, gyro.as_ref());
    let signs_wrong = signs.is_some();
    out.extend(signs);
    out.extend(rear.stuck(Wheel::Rl));
    out.extend(rear.stuck(Wheel::Rr));
    out.extend(stuck_imu);
    // A rate beyond any car's would dominate the fit, and wrong signs make
    // the track negative: no track comparison then.
    if !signs_wrong
        && !out
            .iter()
            .any(|f| matches!(f, Finding::ImpossibleWheelRate { .. }))
    {
        out.extend(gyro.as_ref().and_then(|g| track_contradicted(g, &rear)));
    }
    out
}

/// Pauses of the wheel stream.
fn wheel_pauses(drive: &Drive) -> Vec<Finding> {
    let t: Vec<f64> = drive
        .wheels
        .samples
        .iter()
        .map(|s| s.t_s)
        .filter(|t| t.is_finite())
        .collect();
    let mut dts: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    let Some(med) = stats::upper_median(&mut dts) else {
        return Vec::new();
    };
    let limit = (PAUSE_FACTOR * med).max(PAUSE_MIN_S);
    t.windows(2)
        .filter(|w| w[1] - w[0] > limit)
        .map(|w| Finding::WheelPause {
            t_s: w[0],
            duration_s: w[1] - w[0],
            median_interval_s: med,
        })
        .collect()
}

/// The gyro's trapezoidal integral at its own (finite, increasing) times.
struct GyroIntegral {
    t: Vec<f64>,
    cum: Vec<f64>,
    rate: Vec<f64>,
    /// An interval longer than this is a pause of the IMU stream, s.
    gap: f64,
    /// Median sample interval, s.
    dt: f64,
}

impl GyroIntegral {
    fn of(rows: &[ImuSample]) -> Option<GyroIntegral> {
        let (mut t, mut cum, mut rate) = (Vec::new(), Vec::new(), Vec::new());
        let mut acc = 0.0;
        for s in rows {
            if !(s.t_s.is_finite() && s.gz_rad_s.is_finite()) {
                continue;
            }
            if let (Some(&t0), Some(&w0)) = (t.last(), rate.last()) {
                if s.t_s <= t0 {
                    continue;
                }
                acc += 0.5 * (w0 + s.gz_rad_s) * (s.t_s - t0);
            }
            t.push(s.t_s);
            cum.push(acc);
            rate.push(s.gz_rad_s);
        }
        if t.len() < 10 {
            return None;
        }
        let mut dts: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
        let dt = stats::upper_median(&mut dts)?;
        Some(GyroIntegral {
            t,
            cum,
            rate,
            gap: 10.0 * dt,
            dt,
        })
    }

    /// The integral from `a` to `b`, `None` when the IMU does not cover it
    /// or pauses within.
    fn change(&self, a: f64, b: f64) -> Option<f64> {
        let n = self.t.len();
        if !(a >= self.t[0] && b <= self.t[n - 1] && b > a) {
            return None;
        }
        // Samples bracketing a and b.
        let i0 = self.t.partition_point(|&x| x <= a).clamp(1, n - 1) - 1;
        let i1 = self.t.partition_point(|&x| x < b).clamp(1, n - 1);
        if self.t[i0..=i1].windows(2).any(|w| w[1] - w[0] > self.gap) {
            return None;
        }
        let at = |t: f64, i: usize| {
            let (t0, t1) = (self.t[i], self.t[i + 1]);
            let f = (t - t0) / (t1 - t0);
            // Trapezoid with the rate interpolated linearly inside the interval.
            let (w0, w1) = (self.rate[i], self.rate[i + 1]);
            let w = w0 + f * (w1 - w0);
            self.cum[i] + 0.5 * (w0 + w) * (t - t0)
        };
        Some(at(b, i1 - 1) - at(a, i0))
    }

    /// The noise of the mean rate over a window of `secs`, from the
    /// sample-to-sample scatter (white noise), rad/s.
    fn window_noise(&self, secs: f64) -> Option<f64> {
        let steps: Vec<f64> = self
            .t
            .windows(2)
            .zip(self.rate.windows(2))
            .filter(|(t, _)| t[1] - t[0] <= self.gap)
            .map(|(_, w)| w[1] - w[0])
            .collect();
        let (_, s) = stats::upper_median_and_sigma(&steps)?;
        let per_sample = s / std::f64::consts::SQRT_2;
        Some(per_sample / (secs / self.dt).max(1.0).sqrt())
    }
}

/// A window of the track comparison.
#[derive(Clone, Copy)]
struct TrackWindow {
    dt: f64,
    /// Distance of the axle centre, m (signed).
    ds: f64,
    /// Heading change by the wheels with the nominal track, rad.
    dpsi_w: f64,
    /// Heading change by the gyro (bias not removed), rad.
    dpsi_g: f64,
}

/// Least squares `y = s x1 (+ mu x2)` through the origin: (s, standard
/// error of s, residuals). `x2` is left out where it cannot be told from
/// `x1` (squared correlation above 0.9) or is absent.
fn fit_track(rows: &[(f64, f64, f64)]) -> Option<(f64, f64, Vec<f64>)> {
    let (mut s11, mut s12, mut s22, mut s1y, mut s2y) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(y, x1, x2) in rows {
        s11 += x1 * x1;
        s12 += x1 * x2;
        s22 += x2 * x2;
        s1y += x1 * y;
        s2y += x2 * y;
    }
    if s11 <= 0.0 {
        return None;
    }
    let det = s11 * s22 - s12 * s12;
    let two = s22 > 0.0 && s12 * s12 < 0.9 * s11 * s22 && rows.len() > 3;
    let (s, mu, inv11, p) = if two {
        (
            (s22 * s1y - s12 * s2y) / det,
            (s11 * s2y - s12 * s1y) / det,
            s22 / det,
            2.0,
        )
    } else {
        (s1y / s11, 0.0, 1.0 / s11, 1.0)
    };
    let res: Vec<f64> = rows
        .iter()
        .map(|&(y, x1, x2)| y - s * x1 - mu * x2)
        .collect();
    let dof = rows.len() as f64 - p;
    if dof < 1.0 {
        return None;
    }
    let var = res.iter().map(|r| r * r).sum::<f64>() / dof;
    Some((s, (var * inv11).sqrt(), res))
}

/// The wheels' heading changes against the gyro's over the turning windows
/// (the method of [`Finding::TrackWidthContradicted`]): `s` is about 1 for
/// a consistent drive, about -1 when the wheels' turns are mirrored.
#[derive(Debug, Clone, Copy, PartialEq)]
struct WheelGyroFit {
    /// Wheel heading change per gyro heading change.
    s: f64,
    /// Its standard error.
    se: f64,
    /// Turning windows used.
    windows: usize,
    /// The gyro's turning over them, rad.
    turned: f64,
    /// Correlation of the wheels' and the gyro's heading changes over the
    /// windows: near +1 or -1 where they see the same turns, near zero
    /// where the clocks disagree (a stream seconds late).
    corr: f64,
}

/// Fit the wheels' heading changes to the gyro's (see [`WheelGyroFit`]);
/// `None` without a gyro or with too little turning.
fn wheel_gyro_fit(drive: &Drive, rear: &Rear) -> Option<WheelGyroFit> {
    let gyro = GyroIntegral::of(drive.imu.as_deref()?)?;
    let n = rear.t.len();
    let mut wheel_dts: Vec<f64> = rear.t.windows(2).map(|w| w[1] - w[0]).collect();
    let wheel_gap = 10.0 * stats::upper_median(&mut wheel_dts)?;
    let mut windows = Vec::new();
    let mut i = 0;
    for j in 1..n {
        if rear.t[j] - rear.t[j - 1] > wheel_gap {
            i = j;
            continue;
        }
        if rear.t[j] - rear.t[i] < TRACK_WINDOW_S {
            continue;
        }
        if let Some(dpsi_g) = gyro.change(rear.t[i], rear.t[j]) {
            windows.push(TrackWindow {
                dt: rear.t[j] - rear.t[i],
                ds: rear.s(j) - rear.s(i),
                dpsi_w: rear.psi(j) - rear.psi(i),
                dpsi_g,
            });
        }
        i = j;
    }
    let still = |w: &TrackWindow| w.ds.abs() < 0.05 * w.dt;
    let standstill: Vec<f64> = windows
        .iter()
        .filter(|w| still(w))
        .map(|w| w.dpsi_g / w.dt)
        .collect();
    let (bias, noise) = if standstill.len() >= 3 {
        stats::upper_median_and_sigma(&standstill)?
    } else {
        let kappa_min = MAX_CIRCUMFERENCE_MISMATCH / rear.track;
        let straight: Vec<f64> = windows
            .iter()
            .filter(|w| !still(w) && w.dpsi_w.abs() < kappa_min * w.ds.abs())
            .map(|w| w.dpsi_g / w.dt)
            .collect();
        let bias = if straight.len() >= 3 {
            stats::upper_median_and_sigma(&straight)?.0
        } else {
            0.0
        };
        (bias, gyro.window_noise(TRACK_WINDOW_S)?)
    };
    let noise = noise.max(GYRO_NOISE_FLOOR_RAD_S);
    let turning: Vec<(f64, f64, f64)> = windows
        .iter()
        .filter(|w| !still(w))
        .map(|w| (w.dpsi_w, w.dpsi_g - bias * w.dt, w.ds))
        .filter(|&(_, g, _)| g.abs() > TURN_NOISE_SIGMAS * noise * TRACK_WINDOW_S)
        .collect();
    if turning.len() < 10 {
        return None;
    }
    // One pass of outlier removal (a wheel spinning, a pothole).
    let (_, _, res) = fit_track(&turning)?;
    let (_, spread) = stats::upper_median_and_sigma(&res)?;
    let kept: Vec<(f64, f64, f64)> = if spread > 0.0 {
        turning
            .iter()
            .zip(&res)
            .filter(|(_, r)| r.abs() <= 5.0 * spread)
            .map(|(w, _)| *w)
            .collect()
    } else {
        turning
    };
    let turned: f64 = kept.iter().map(|w| w.1.abs()).sum();
    if kept.len() < 10 {
        return None;
    }
    let (s, se, _) = fit_track(&kept)?;
    let (sxy, sxx, syy) = kept.iter().fold((0.0, 0.0, 0.0), |(a, b, c), &(w, g, _)| {
        (a + w * g, b + g * g, c + w * w)
    });
    let corr = sxy / (sxx * syy).sqrt();
    (s.is_finite() && corr.is_finite()).then_some(WheelGyroFit {
        s,
        se,
        windows: kept.len(),
        turned,
        corr,
    })
}

/// `vehicle.toml`'s track against the track the wheels and the gyro agree
/// on (see [`Finding::TrackWidthContradicted`]).
fn track_contradicted(fit: &WheelGyroFit, rear: &Rear) -> Option<Finding> {
    let WheelGyroFit {
        s,
        se,
        windows,
        turned,
        ..
    } = *fit;
    let off = (s - 1.0).abs();
    (turned >= EVIDENCE_TURN_RAD
        && s > 0.0
        && off > TRACK_CONTRADICTION_REL
        && off > TRACK_CONTRADICTION_SIGMAS * se)
        .then_some(Finding::TrackWidthContradicted {
            nominal_m: rear.track,
            effective_m: s * rear.track,
            sigma_m: se * rear.track,
            windows,
            turned_rad: turned,
        })
}

/// The first sample of `wheel` whose rate is beyond any car's.
fn impossible_rate(drive: &Drive, wheel: Wheel) -> Option<Finding> {
    let unit = drive.wheels.units.of(wheel)?;
    let k = rev_scale(drive, unit)?;
    let limit = wheel_rate_limit(drive);
    let samples = &drive.wheels.samples;
    let mut first: Option<(f64, f64, f64)> = None;
    let mut count = 0usize;
    let mut flag = |t: f64, v: f64, r: f64| {
        count += 1;
        first.get_or_insert((t, v, r));
    };
    if unit.is_rate() {
        for s in samples {
            if let Some(v) = value_of(s, wheel).filter(|v| v.is_finite()) {
                let r = (v * k).abs();
                if r > limit {
                    flag(s.t_s, v, r);
                }
            }
        }
    } else {
        let values: Vec<(f64, f64)> = samples
            .iter()
            .filter_map(|s| value_of(s, wheel).map(|v| (s.t_s, v)))
            .filter(|(t, v)| t.is_finite() && v.is_finite())
            .collect();
        // The counter's resolution (its smallest step) is allowed on top.
        let quantum = count_quantum(values.iter().map(|v| v.1), k);
        for w in values.windows(2) {
            let dt = w[1].0 - w[0].0;
            let d = ((w[1].1 - w[0].1) * k).abs();
            if dt > 0.0 && d - quantum > limit * dt {
                flag(w[1].0, w[1].1, d / dt);
            }
        }
    }
    let (t_s, value, rev_per_s) = first?;
    Some(Finding::ImpossibleWheelRate {
        wheel,
        t_s,
        value,
        unit,
        rev_per_s,
        limit_rev_per_s: limit,
        samples: count,
    })
}

/// The rear wheels as cumulative revolutions at the rows where both are
/// finite, with the vehicle's nominal values.
struct Rear {
    t: Vec<f64>,
    /// Cumulative revolutions.
    l: Vec<f64>,
    r: Vec<f64>,
    /// Raw values (for the stuck check).
    raw_l: Vec<f64>,
    raw_r: Vec<f64>,
    c: f64,
    track: f64,
    rate: [bool; 2],
}

impl Rear {
    fn of(drive: &Drive) -> Option<Rear> {
        let units = drive.wheels.units;
        let (kl, kr) = (rev_scale(drive, units.rl)?, rev_scale(drive, units.rr)?);
        let c = drive.vehicle.nominal_circumference_m;
        let track = drive.vehicle.track_width_m;
        if !(c.is_finite() && c > 0.0 && track.is_finite() && track > 0.0) {
            return None;
        }
        let rows: Vec<&WheelSample> = drive
            .wheels
            .samples
            .iter()
            .filter(|s| s.t_s.is_finite() && s.rl.is_finite() && s.rr.is_finite())
            .collect();
        if rows.len() < 3 {
            return None;
        }
        let cumulate = |unit: WheelUnit, k: f64, pick: fn(&WheelSample) -> f64| {
            let mut out = Vec::with_capacity(rows.len());
            let mut acc = 0.0;
            for (i, s) in rows.iter().enumerate() {
                if unit.is_rate() {
                    if i > 0 {
                        let p = rows[i - 1];
                        acc += 0.5 * (pick(p) + pick(s)) * k * (s.t_s - p.t_s);
                    }
                    out.push(acc);
                } else {
                    out.push(pick(s) * k);
                }
            }
            out
        };
        Some(Rear {
            t: rows.iter().map(|s| s.t_s).collect(),
            l: cumulate(units.rl, kl, |s| s.rl),
            r: cumulate(units.rr, kr, |s| s.rr),
            raw_l: rows.iter().map(|s| s.rl).collect(),
            raw_r: rows.iter().map(|s| s.rr).collect(),
            c,
            track,
            rate: [units.rl.is_rate(), units.rr.is_rate()],
        })
    }

    /// Distance of the axle centre (signed, cumulative), m.
    fn s(&self, i: usize) -> f64 {
        0.5 * self.c * (self.l[i] + self.r[i])
    }

    /// Heading by the wheels (cumulative), rad.
    fn psi(&self, i: usize) -> f64 {
        self.c * (self.r[i] - self.l[i]) / self.track
    }

    /// Path length of a cumulative series between samples `a..=b`, revolutions.
    fn path(x: &[f64], a: usize, b: usize) -> f64 {
        x[a..=b].windows(2).map(|w| (w[1] - w[0]).abs()).sum()
    }

    /// One wheel counts forward and the other backward over the drive.
    fn opposed(&self) -> Option<Finding> {
        let n = self.t.len() - 1;
        let (dl, dr) = (self.l[n] - self.l[0], self.r[n] - self.r[0]);
        let big = dl.abs().max(dr.abs());
        (dl * dr < 0.0
            && dl.abs().min(dr.abs()) >= 0.5 * big
            && big * self.c >= EVIDENCE_DISTANCE_M)
            .then_some(Finding::WheelsOpposed {
                rl_revs: dl,
                rr_revs: dr,
            })
    }

    /// Index of the wheel sample at or before `t`.
    fn at(&self, t: f64) -> Option<usize> {
        let i = self.t.partition_point(|&x| x <= t);
        (i > 0).then(|| i - 1)
    }

    /// Index of the first wheel sample at or after `t`.
    fn at_or_after(&self, t: f64) -> Option<usize> {
        let i = self.t.partition_point(|&x| x < t);
        (i < self.t.len()).then_some(i)
    }

    /// Turning by the wheels between samples `a..=b` that no constant
    /// curvature explains: over windows of about [`VARYING_TURN_WINDOW_S`],
    /// each window's heading change less the median curvature times its
    /// distance (a circumference mismatch bends the wheels' path at a
    /// constant curvature), counted where it exceeds four times the heading
    /// change one count of each encoder makes, rad.
    fn varying_turning(&self, a: usize, b: usize) -> f64 {
        let mut windows = Vec::new();
        let mut i = a;
        for j in a + 1..=b {
            if self.t[j] - self.t[i] < VARYING_TURN_WINDOW_S && j < b {
                continue;
            }
            let ds = self.s(j) - self.s(i);
            if ds.abs() >= 1.0 {
                windows.push((ds, self.psi(j) - self.psi(i)));
            }
            i = j;
        }
        let mut curvatures: Vec<f64> = windows.iter().map(|(ds, dpsi)| dpsi / ds).collect();
        let Some(kappa) = stats::upper_median(&mut curvatures) else {
            return 0.0;
        };
        let quantum = self.c * (resolution(&self.l, a, b) + resolution(&self.r, a, b)) / self.track;
        windows
            .iter()
            .map(|(ds, dpsi)| (dpsi - kappa * ds).abs())
            .filter(|x| *x > 4.0 * quantum)
            .sum()
    }

    /// Turning by the wheels over windows of about 1 s between samples
    /// `a..=b`, counting only bends sharper than a circumference mismatch
    /// explains, rad.
    fn turning(&self, a: usize, b: usize) -> f64 {
        let kappa_min = MAX_CIRCUMFERENCE_MISMATCH / self.track;
        let mut total = 0.0;
        let mut i = a;
        for j in a + 1..=b {
            if self.t[j] - self.t[i] < 1.0 && j < b {
                continue;
            }
            let ds = self.s(j) - self.s(i);
            let dpsi = self.psi(j) - self.psi(i);
            if ds.abs() >= 0.5 && (dpsi / ds).abs() >= kappa_min {
                total += dpsi.abs();
            }
            i = j;
        }
        total
    }

    /// Speeds over windows of about 1 s between samples `a..=b`: (min, max), m/s.
    fn speed_range(&self, a: usize, b: usize) -> (f64, f64) {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut i = a;
        for j in a + 1..=b {
            let dt = self.t[j] - self.t[i];
            if dt < 1.0 {
                continue;
            }
            let v = (self.s(j) - self.s(i)) / dt;
            lo = lo.min(v);
            hi = hi.max(v);
            i = j;
        }
        (lo, hi)
    }

    /// Both wheels reversed, rl and rr exchanged, or the GNSS track
    /// mirrored: of the three witnesses of the car's turns (the wheels, the
    /// gyro, the GNSS course), the one that turns the other way round is
    /// wrong. Without a gyro, wheels against GNSS course cannot tell the
    /// wheels from the track (the message says so).
    fn reversed(&self, drive: &Drive, gyro: Option<&WheelGyroFit>) -> Option<Finding> {
        // The gyro decides where its turns tell +1 from -1 beyond doubt
        // (ten standard errors between them) and the two see the same turns
        // (a clock seconds off decorrelates them: that is no mirror).
        let gyro =
            gyro.filter(|g| 2.0 > SIGN_SIGMAS * g.se && g.corr.abs() >= MIN_SIGN_CORRELATION);
        let course = self.course_ratio(drive);
        let (ratio, turned, against) = match (gyro, course) {
            (Some(g), _) if g.s < -0.5 => (g.s, g.turned, "the gyro"),
            (Some(g), Some((c, turned))) if g.s > 0.5 && c < -0.5 => {
                return Some(Finding::GnssMirrored {
                    ratio: 1.0 / c,
                    turned_rad: turned,
                    lat_lon: drive.vehicle.gnss.origin_lat_deg.is_some(),
                });
            }
            (None, Some((c, turned))) if c < -0.5 => (c, turned, "the GNSS course"),
            _ => return None,
        };
        let n = self.t.len() - 1;
        let (mut fwd, mut back) = (0.0, 0.0);
        for k in 1..=n {
            let ds = self.s(k) - self.s(k - 1);
            if ds >= 0.0 {
                fwd += ds;
            } else {
                back -= ds;
            }
        }
        let backward_percent = 100.0 * back / (fwd + back).max(f64::MIN_POSITIVE);
        Some(if backward_percent > 50.0 {
            Finding::WheelsReversed {
                backward_percent,
                ratio,
                turned_rad: turned,
                against,
            }
        } else {
            Finding::WheelsSwapped {
                ratio,
                turned_rad: turned,
                against,
            }
        })
    }

    /// The wheels' heading changes per GNSS course change over the drive
    /// and the course's turning, rad; `None` without enough turning.
    fn course_ratio(&self, drive: &Drive) -> Option<(f64, f64)> {
        let fixes = drive.gnss.as_deref()?;
        let mut sigmas: Vec<f64> = fixes
            .iter()
            .filter_map(|f| f.sigma_m)
            .filter(|s| s.is_finite() && *s > 0.0)
            .collect();
        sigmas.sort_by(f64::total_cmp);
        let sigma = sigmas.get(sigmas.len() / 2).copied().unwrap_or(0.0);
        // Fixes far enough apart for a course well above the GNSS noise.
        let spacing = (5.0f64).max(5.0 * sigma);
        let mut picked: Vec<(f64, f64, f64)> = Vec::new();
        for f in fixes {
            if !(f.t_s.is_finite() && f.x_m.is_finite() && f.y_m.is_finite()) {
                continue;
            }
            if self.at(f.t_s).is_none() || f.t_s > self.t[self.t.len() - 1] {
                continue;
            }
            match picked.last() {
                Some(&(_, x, y)) if (f.x_m - x).hypot(f.y_m - y) < spacing => {}
                _ => picked.push((f.t_s, f.x_m, f.y_m)),
            }
        }
        // Course and wheel heading of each segment (at its mid-time).
        let segs: Vec<(f64, f64)> = picked
            .windows(2)
            .filter_map(|w| {
                let course = (w[1].2 - w[0].2).atan2(w[1].1 - w[0].1);
                let i = self.at(0.5 * (w[0].0 + w[1].0))?;
                Some((course, self.psi(i)))
            })
            .collect();
        // (wheel heading change, course change) of consecutive segments; a
        // cusp (the course flips when the car changes direction) says nothing.
        let pairs: Vec<(f64, f64)> = segs
            .windows(2)
            .map(|w| (w[1].1 - w[0].1, stats::wrap_angle(w[1].0 - w[0].0)))
            .filter(|(_, dc)| dc.abs() <= 2.0)
            .collect();
        let turned: f64 = pairs.iter().map(|p| p.1.abs()).sum();
        let wheel_turned: f64 = pairs.iter().map(|p| p.0.abs()).sum();
        if pairs.len() < 10 || wheel_turned < EVIDENCE_TURN_RAD {
            return None;
        }
        // The course regressed on the wheels' heading (the precise one of
        // the two: the course's noise then biases nothing), with one pass of
        // 5-MAD outlier removal (a GNSS jump bends two chords).
        let (r, residuals, _) = slope(&pairs)?;
        let (_, spread) = stats::upper_median_and_sigma(&residuals)?;
        let kept: Vec<(f64, f64)> = pairs
            .iter()
            .zip(&residuals)
            .filter(|(_, e)| spread <= 0.0 || e.abs() <= 5.0 * spread)
            .map(|(p, _)| *p)
            .collect();
        let (r, _, se) = if kept.len() >= 10 {
            slope(&kept)?
        } else {
            let (_, res, se) = slope(&pairs)?;
            (r, res, se)
        };
        // Reported as the wheels' turns per course turn, where the sign is
        // beyond doubt.
        (r.abs() > COURSE_SIGN_SIGMAS * se).then(|| (1.0 / r, turned))
    }

    /// The longest stretch where `wheel` stays exactly constant while the
    /// other rear wheel rolls on (and, for rates, changes speed).
    fn stuck(&self, wheel: Wheel) -> Option<Finding> {
        let (raw, other_cum, is_rate, other_wheel) = match wheel {
            Wheel::Rl => (&self.raw_l, &self.r, self.rate[0], Wheel::Rr),
            _ => (&self.raw_r, &self.l, self.rate[1], Wheel::Rl),
        };
        let total = Self::path(other_cum, 0, self.t.len() - 1) * self.c;
        let mut best: Option<(usize, usize, f64, bool)> = None;
        let mut a = 0;
        let n = raw.len();
        while a < n {
            let mut b = a;
            while b + 1 < n && raw[b + 1].to_bits() == raw[a].to_bits() {
                b += 1;
            }
            if b > a {
                let dist = Self::path(other_cum, a, b) * self.c;
                let quantum = self.c * min_step(other_cum, a, b);
                let (lo, hi) = self.other_speed_range(other_cum, a, b);
                let changing = hi - lo >= 1.0;
                let evidence =
                    dist >= EVIDENCE_DISTANCE_M.max(20.0 * quantum) && (!is_rate || changing);
                if evidence && best.is_none_or(|(_, _, d, _)| dist > d) {
                    best = Some((a, b, dist, changing));
                }
            }
            a = b + 1;
        }
        let (a, b, dist, changing) = best?;
        Some(Finding::WheelStuck {
            wheel,
            other: other_wheel,
            value: raw[a],
            t_start_s: self.t[a],
            t_end_s: self.t[b],
            other_distance_m: dist,
            changing_speed: is_rate && changing,
            major: dist >= 0.2 * total,
        })
    }

    /// The speed range of one wheel (cumulative revolutions `x`) over
    /// windows of about 1 s between samples `a..=b`, m/s.
    fn other_speed_range(&self, x: &[f64], a: usize, b: usize) -> (f64, f64) {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut i = a;
        for j in a + 1..=b {
            let dt = self.t[j] - self.t[i];
            if dt < 1.0 {
                continue;
            }
            let v = self.c * (x[j] - x[i]) / dt;
            lo = lo.min(v);
            hi = hi.max(v);
            i = j;
        }
        if lo > hi {
            (0.0, 0.0)
        } else {
            (lo, hi)
        }
    }
}

/// A counter's resolution in revolutions: the smallest nonzero step
/// between its consecutive values (`k` revolutions per unit); 0 without one.
fn count_quantum(values: impl Iterator<Item = f64>, k: f64) -> f64 {
    let mut prev: Option<f64> = None;
    let mut q = f64::INFINITY;
    for v in values {
        if let Some(v0) = prev {
            let d = ((v - v0) * k).abs();
            if d > 0.0 {
                q = q.min(d);
            }
        }
        prev = Some(v);
    }
    if q.is_finite() {
        q
    } else {
        0.0
    }
}

/// The resolution of a cumulative series between samples `a..=b`: the
/// smallest nonzero change between consecutive steps (a counter's steps
/// differ by whole counts), ignoring differences at the level of rounding.
fn resolution(x: &[f64], a: usize, b: usize) -> f64 {
    let steps: Vec<f64> = x[a..=b].windows(2).map(|w| w[1] - w[0]).collect();
    let scale = steps.iter().fold(0.0f64, |m, s| m.max(s.abs()));
    let m = steps
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| *d > 1e-9 * scale)
        .fold(f64::INFINITY, f64::min);
    if m.is_finite() {
        m
    } else {
        0.0
    }
}

/// Least squares `y = r x` through the origin over `(x, y)` pairs: the
/// slope, the residuals and the slope's standard error.
fn slope(pairs: &[(f64, f64)]) -> Option<(f64, Vec<f64>, f64)> {
    let b: f64 = pairs.iter().map(|p| p.0 * p.0).sum();
    if b <= 0.0 || pairs.len() < 2 {
        return None;
    }
    let r = pairs.iter().map(|p| p.0 * p.1).sum::<f64>() / b;
    let residuals: Vec<f64> = pairs.iter().map(|p| p.1 - r * p.0).collect();
    let var = residuals.iter().map(|e| e * e).sum::<f64>() / (pairs.len() - 1) as f64;
    Some((r, residuals, (var / b).sqrt()))
}

/// Smallest nonzero step of a cumulative series between samples `a..=b`.
fn min_step(x: &[f64], a: usize, b: usize) -> f64 {
    let m = x[a..=b]
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    if m.is_finite() {
        m
    } else {
        0.0
    }
}

/// Reads one value of an IMU sample.
type ImuField = fn(&ImuSample) -> Option<f64>;

/// IMU fields that stay exactly constant while the wheels show motion.
fn imu_stuck(drive: &Drive, rear: &Rear) -> Vec<Finding> {
    let Some(rows) = drive.imu.as_deref() else {
        return Vec::new();
    };
    let fields: [(&'static str, ImuField); 3] = [
        ("gz_rad_s", |s| Some(s.gz_rad_s)),
        ("ax_m_s2", |s| s.ax_m_s2),
        ("ay_m_s2", |s| s.ay_m_s2),
    ];
    let mut out = Vec::new();
    for (field, get) in fields {
        let values: Vec<(f64, f64)> = rows
            .iter()
            .filter_map(|s| get(s).map(|v| (s.t_s, v)))
            .filter(|(t, v)| t.is_finite() && v.is_finite())
            .collect();
        if values.len() < 10 {
            continue;
        }
        // The longest run of bit-identical values.
        let (mut best_a, mut best_b, mut a) = (0usize, 0usize, 0usize);
        for i in 1..=values.len() {
            if i == values.len() || values[i].1.to_bits() != values[a].1.to_bits() {
                if i - 1 - a > best_b - best_a {
                    (best_a, best_b) = (a, i - 1);
                }
                a = i;
            }
        }
        let samples = best_b - best_a + 1;
        if samples < 10 {
            continue;
        }
        let (t0, t1) = (values[best_a].0, values[best_b].0);
        // The wheels over the part of the stretch they cover (the IMU may
        // start before the wheels or end after them).
        let (Some(i0), Some(i1)) = (rear.at_or_after(t0), rear.at(t1)) else {
            continue;
        };
        if i1 <= i0 {
            continue;
        }
        let evidence = match field {
            "ax_m_s2" => {
                let (lo, hi) = rear.speed_range(i0, i1);
                (hi - lo >= 2.0).then(|| format!("the speed change by {:.1} m/s", hi - lo))
            }
            _ => {
                // Sharp bends, or gentle ones beyond what the encoders'
                // resolution and a circumference mismatch explain: a gyro
                // reads either (real ones never hold a value for long).
                let turned = rear.turning(i0, i1).max(rear.varying_turning(i0, i1));
                (turned >= STUCK_EVIDENCE_TURN_RAD).then(|| {
                    format!(
                        "the car turn {turned:.1} rad ({:.0} deg)",
                        turned.to_degrees()
                    )
                })
            }
        };
        let Some(evidence) = evidence else {
            continue;
        };
        out.push(Finding::ImuStuck {
            field,
            value: values[best_a].1,
            samples,
            t_start_s: t0,
            t_end_s: t1,
            evidence,
            whole_drive: samples as f64 >= 0.9 * values.len() as f64,
        });
    }
    out
}
