//! Dead-reckoning fed sample by sample: the code the service and `odometry
//! evaluate` share.
//!
//! [`Odometer`] turns wheel revolutions (and, in [`HeadingMode::Gyro`], yaw
//! rates) into increments of travelled distance and heading between two wheel
//! samples; [`DeadReckoner`] adds those increments to a pose with the 2W
//! step of the paper's eq. (1) (side-slip 0).
//!
//! Heading modes:
//! - [`HeadingMode::WheelDifference`]: the paper's pure 2W model, heading change
//!   `(d_RR - d_RL) / t_R` from the rear wheels.
//! - [`HeadingMode::Gyro`]: distance from the rear wheels, heading change from
//!   the calibrated gyro, `w = (gz - bias) / (1 + scale)` integrated over the
//!   wheel interval. The gyro is integrated with the trapezoidal rule between
//!   its own samples; at a wheel time the integral uses only the gyro samples
//!   at or before that time (the last rate held after it), so an increment
//!   depends only on samples up to its end, never on whether a later sample
//!   has arrived yet (the service's poses are the same however the samples
//!   are grouped into wakeups). The part taken with a held rate is corrected
//!   in the next increment: the total heading change equals the gyro integral.
//!   While the gyro is missing or older than [`OdometerConfig::max_gyro_gap_s`]
//!   the increment falls back to the wheel difference and is counted.
//!
//! Wheel zero offsets: wheel-rate sensors (the WID drives' hub gyros, for
//! one) read a small non-zero rate at standstill, different on the two
//! wheels, which the wheel difference turns into a steady heading drift
//! (0.0155 rad/s of rear rate difference is 0.003 rad/s of yaw, 0.1 rad in
//! 30 s). When [`OdometerConfig::learn_wheel_offsets`] is on, the odometer
//! learns each rear wheel's rate offset while the vehicle stands (both rear
//! rates below [`OdometerConfig::standstill_rate_rev_s`], and the gyro, when
//! there is one, below [`OdometerConfig::standstill_gyro_rad_s`], for at least
//! [`OdometerConfig::standstill_min_s`]) and subtracts it from every increment.
//! With encoders the learned offset is simply zero. While standing, the
//! increments are zero (no distance, no heading change, whatever the gyro
//! bias), a zero-velocity update.
//!
//! Gyro bias at standstill: a gyro's bias changes from one power-on to the
//! next (the catalogue's `gyro_bias`, 10-1000 deg/h), so the bias calibrated
//! on an earlier drive is only a prior for this one. A standing car does not
//! turn, so the mean gyro rate over a standstill is a direct measurement of
//! today's bias (a zero angular rate update), with no GNSS needed. When
//! [`OdometerConfig::learn_gyro_bias`] is on, each standstill of at least
//! [`OdometerConfig::standstill_min_s`] with a fresh gyro is such a
//! measurement, taken when the car moves off: its variance is the spread of
//! the gyro samples over their count (at least
//! [`OdometerConfig::standstill_bias_floor_rad_s`] squared), and the bias used
//! from then on is the inverse-variance mean of the calibrated bias (1-sigma
//! [`OdometerConfig::gyro_bias_prior_sigma_rad_s`]) and every standstill so
//! far. [`Odometer::take_bias_observation`] hands each measurement to a
//! filter that keeps its own bias state (the service's fusion).
//!
//! Parameters can change between two samples ([`Odometer::set_params`]): the
//! pose stays where it is and only the next increments use the new values.
//!
//! Pure: no clock, no I/O. Times are seconds on the drive's clock.

use std::collections::VecDeque;
use vehicle_model::effects::{
    lateral_acceleration_from_wheels, EffectTerms, StepSignals, WheelEffects,
};
use vehicle_model::estimate::OdometryParams;
use vehicle_model::two_wheel::{step, Pose2};

/// Where the heading change of the dead-reckoning comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HeadingMode {
    /// The paper's 2W model: heading from the rear wheel difference.
    WheelDifference,
    /// Heading from the calibrated yaw-rate gyro, distance from the rear wheels.
    Gyro,
}

impl HeadingMode {
    /// Short name used on the command line and in reports: `wheels` or `gyro`.
    pub fn name(self) -> &'static str {
        match self {
            HeadingMode::WheelDifference => "wheels",
            HeadingMode::Gyro => "gyro",
        }
    }
}

impl std::fmt::Display for HeadingMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for HeadingMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "wheels" | "wheel" | "wheel-difference" | "2w" => Ok(HeadingMode::WheelDifference),
            "gyro" => Ok(HeadingMode::Gyro),
            other => Err(format!(
                "unknown heading mode `{other}` (expected `wheels` or `gyro`)"
            )),
        }
    }
}

/// Which source gave the heading change of one increment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeadingSource {
    /// The rear wheel difference.
    Wheels,
    /// The gyro.
    Gyro,
    /// None: the vehicle stands (standstill learning on), the pose is held.
    Standstill,
}

/// Motion between two consecutive wheel samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Increment {
    /// Time of the earlier wheel sample, s.
    pub t0_s: f64,
    /// Time of the later wheel sample, s.
    pub t1_s: f64,
    /// Distance travelled by the rear-axle centre, m (negative when reversing).
    pub ds_m: f64,
    /// Heading change, rad.
    pub dyaw_rad: f64,
    /// Source of `dyaw_rad`.
    pub heading_source: HeadingSource,
    /// Side-slip angle of the step, rad (0 unless the effect terms model it).
    pub beta_rad: f64,
}

/// A sample the odometer cannot use.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InputError {
    /// A timestamp that does not increase within its stream.
    #[error(
        "{stream} sample at t = {t_s} s is not after the previous one at {previous_t_s} s; skipped"
    )]
    OutOfOrder {
        /// `wheels` or `imu`.
        stream: &'static str,
        /// Its time.
        t_s: f64,
        /// The previous time of that stream.
        previous_t_s: f64,
    },
    /// A NaN or infinite value.
    #[error("{stream} sample at t = {t_s} s has a non-finite value; skipped")]
    NonFinite {
        /// `wheels` or `imu`.
        stream: &'static str,
        /// Its time.
        t_s: f64,
    },
    /// Wheel counts that moved further than any car's wheel turns
    /// ([`MAX_WHEEL_REV_PER_S`]) since the previous sample: held; the next
    /// sample tells a glitch (refused) from counters that jumped (taken as
    /// the new reference, [`InputError::CounterJump`]).
    #[error(
        "wheel sample at t = {t_s} s moved the counts by {dn_rl:.4e} / {dn_rr:.4e} revolutions \
         in {dt_s:.4} s, beyond any car; skipped"
    )]
    ImplausibleStep {
        /// Its time.
        t_s: f64,
        /// Rear-left step, revolutions.
        dn_rl: f64,
        /// Rear-right step, revolutions.
        dn_rr: f64,
        /// Time since the previous sample, s.
        dt_s: f64,
    },
    /// The wheel counters jumped and stayed (two samples agree on the new
    /// counts): they are the new reference; the motion over the jump is lost.
    #[error(
        "wheel counters jumped at t = {t_s} s and stayed there: taken as the new reference \
         (the motion of that step is lost)"
    )]
    CounterJump {
        /// Time of the sample that confirmed the jump.
        t_s: f64,
    },
}

/// A step beyond this (plus one revolution of slack for a coarse counter)
/// is a glitch or a jump, not motion.
pub use interfaces::drive::MAX_WHEEL_REV_PER_S;

/// Tuning of the [`Odometer`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometerConfig {
    /// Heading mode.
    pub heading: HeadingMode,
    /// In gyro mode, the newest gyro sample may be at most this old at the end
    /// of an increment (and one must exist at its start), else the wheel
    /// difference is used for that increment. Seconds.
    pub max_gyro_gap_s: f64,
    /// Learn and subtract the rear wheels' rate offsets at standstill.
    pub learn_wheel_offsets: bool,
    /// Rear wheel rate below which the vehicle may be standing, rev/s.
    pub standstill_rate_rev_s: f64,
    /// Gyro yaw rate below which the vehicle may be standing, rad/s.
    pub standstill_gyro_rad_s: f64,
    /// Standing time needed before offsets (and the gyro bias) are learned, s.
    pub standstill_min_s: f64,
    /// Measure the gyro bias at standstill and use it (see the module docs).
    pub learn_gyro_bias: bool,
    /// 1-sigma of the calibrated gyro bias as a prior for this drive, rad/s:
    /// how far a gyro's bias moves between power-ons.
    pub gyro_bias_prior_sigma_rad_s: f64,
    /// Smallest 1-sigma granted to one standstill's bias measurement, rad/s
    /// (the spread of the samples over their count assumes white noise).
    pub standstill_bias_floor_rad_s: f64,
}

impl Default for OdometerConfig {
    fn default() -> Self {
        OdometerConfig {
            heading: HeadingMode::Gyro,
            max_gyro_gap_s: 0.25,
            learn_wheel_offsets: true,
            // 0.01 rev/s is under 2 cm/s: no car creeps that slowly for a second.
            standstill_rate_rev_s: 0.01,
            standstill_gyro_rad_s: 0.02,
            standstill_min_s: 1.0,
            learn_gyro_bias: true,
            // About 100 deg/h, the middle of the catalogue's gyro_bias range:
            // a standstill of a few seconds outweighs it, a short noisy one
            // does not (BENCHMARKS.md compares it with 10 deg/h).
            gyro_bias_prior_sigma_rad_s: 5e-4,
            standstill_bias_floor_rad_s: 5e-6,
        }
    }
}

/// One gyro sample with the raw integral of the yaw rate up to it.
#[derive(Debug, Clone, Copy)]
struct GyroPoint {
    t_s: f64,
    gz_rad_s: f64,
    integral_rad: f64,
}

/// The raw (uncorrected) gyro integral as a function of time.
#[derive(Debug, Clone, Default)]
struct GyroIntegral {
    history: VecDeque<GyroPoint>,
}

impl GyroIntegral {
    fn push(&mut self, t_s: f64, gz_rad_s: f64) -> Result<(), InputError> {
        if !(t_s.is_finite() && gz_rad_s.is_finite()) {
            return Err(InputError::NonFinite { stream: "imu", t_s });
        }
        let integral_rad = match self.history.back() {
            None => 0.0,
            Some(last) if t_s <= last.t_s => {
                return Err(InputError::OutOfOrder {
                    stream: "imu",
                    t_s,
                    previous_t_s: last.t_s,
                })
            }
            Some(last) => last.integral_rad + 0.5 * (last.gz_rad_s + gz_rad_s) * (t_s - last.t_s),
        };
        self.history.push_back(GyroPoint {
            t_s,
            gz_rad_s,
            integral_rad,
        });
        Ok(())
    }

    /// The newest sample at or before `t_s`.
    fn last_at_or_before(&self, t_s: f64) -> Option<&GyroPoint> {
        let i = self.history.partition_point(|p| p.t_s <= t_s);
        i.checked_sub(1).and_then(|i| self.history.get(i))
    }

    /// The gyro at `t_s` from the samples at or before `t_s` only (the last
    /// rate held after them), so that it does not depend on whether later
    /// samples have arrived yet; `None` without such a sample. Fresh when
    /// that sample is at most `max_gap_s` old.
    fn seen_at(&self, t_s: f64, max_gap_s: f64) -> Option<GyroAt> {
        let p = self.last_at_or_before(t_s)?;
        Some(GyroAt {
            rate_rad_s: p.gz_rad_s,
            integral_rad: p.integral_rad + p.gz_rad_s * (t_s - p.t_s),
            fresh: t_s - p.t_s <= max_gap_s,
        })
    }

    /// Forget samples no longer needed for times at or after `t_s`.
    fn prune_before(&mut self, t_s: f64) {
        while self.history.len() > 1 && self.history[1].t_s <= t_s {
            self.history.pop_front();
        }
    }
}

/// The gyro as seen from one wheel instant ([`GyroIntegral::seen_at`]): one
/// lookup serves the standstill watch, the increment and the next mark.
#[derive(Debug, Clone, Copy)]
struct GyroAt {
    /// Raw rate of the last sample at or before the instant, rad/s.
    rate_rad_s: f64,
    /// Raw integral at the instant, rad.
    integral_rad: f64,
    /// The last sample is at most `max_gyro_gap_s` old.
    fresh: bool,
}

impl GyroAt {
    /// The integral when the gyro is fresh.
    fn fresh_integral(gyro: Option<GyroAt>) -> Option<f64> {
        gyro.filter(|g| g.fresh).map(|g| g.integral_rad)
    }
}

/// Counters of what the odometer did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct OdometerStats {
    /// Increments produced.
    pub increments: u64,
    /// Increments in gyro mode that used the wheel difference because the gyro was missing.
    pub gyro_fallbacks: u64,
    /// Standstill stretches the wheel offsets were learned from.
    pub standstills: u64,
    /// Standstills whose gyro mean went into the gyro bias.
    pub gyro_bias_updates: u64,
    /// Wheel samples refused for a step beyond any car.
    pub implausible_steps: u64,
    /// Counter jumps taken as a new reference.
    pub counter_jumps: u64,
}

/// The gyro bias measured over one standstill, as
/// [`Odometer::take_bias_observation`] hands it on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasObservation {
    /// Time the car moved off, s.
    pub t_s: f64,
    /// Mean raw gyro rate over the standstill, rad/s.
    pub mean_rad_s: f64,
    /// Variance of that mean, (rad/s)^2.
    pub variance: f64,
    /// The odometer's bias before this measurement, rad/s.
    pub bias_before_rad_s: f64,
    /// The odometer's bias after it (used from this increment on), rad/s.
    pub bias_after_rad_s: f64,
}

/// What the standstills have said about the gyro bias, in information form.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct BiasLearning {
    /// Sum of 1 / variance over the measurements.
    information: f64,
    /// Sum of mean / variance.
    weighted_sum: f64,
}

/// Rear-wheel rate offsets learned at standstill.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WheelOffsets {
    /// Rear-left offset, rev/s.
    pub rl_rev_s: f64,
    /// Rear-right offset, rev/s.
    pub rr_rev_s: f64,
}

/// The standstill being observed: its duration and revolutions.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Standstill {
    duration_s: f64,
    rl_rev: f64,
    rr_rev: f64,
    counted: bool,
    /// Gyro over the standstill: time covered, raw integral, and the sum of
    /// squares and count of the per-increment mean rates.
    gyro_s: f64,
    gyro_rad: f64,
    gyro_sq: f64,
    gyro_n: u32,
}

/// Turns wheel samples (and gyro samples) into [`Increment`]s.
#[derive(Debug, Clone)]
pub struct Odometer {
    params: OdometryParams,
    config: OdometerConfig,
    last_wheels: Option<(f64, f64, f64)>,
    gyro: GyroIntegral,
    /// Raw gyro integral at the last wheel time, when the gyro was fresh then.
    gyro_mark: Option<f64>,
    offsets: WheelOffsets,
    standstill: Standstill,
    bias: BiasLearning,
    bias_observation: Option<BiasObservation>,
    stats: OdometerStats,
    /// Wheel-side effect terms of the extended 2W model ([`Odometer::set_effects`]).
    effects: WheelEffects,
    /// With effect terms: the first wheel time, the smoothed speed and
    /// longitudinal acceleration they read.
    effect_state: EffectState,
    /// A wheel sample held because it jumped from the reference (t, rl, rr).
    jump_candidate: Option<(f64, f64, f64)>,
}

/// What the effect terms read that one wheel step does not give.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct EffectState {
    t_first_s: Option<f64>,
    v_m_s: f64,
    a_x_m_s2: f64,
    w_rad_s: f64,
}

/// Smoothing time of the speed, yaw rate and accelerations the effect terms
/// read, s (encoder quantisation makes one 10 ms step's speed and yaw rate
/// too coarse: a side-slip angle from their raw product swings by tenths of
/// a radian from step to step and shortens the track).
const EFFECT_SMOOTHING_S: f64 = 0.5;

impl Odometer {
    /// A new odometer; the first wheel sample only sets the reference.
    pub fn new(params: OdometryParams, config: OdometerConfig) -> Odometer {
        Odometer {
            params,
            config,
            last_wheels: None,
            gyro: GyroIntegral::default(),
            gyro_mark: None,
            offsets: WheelOffsets::default(),
            standstill: Standstill::default(),
            bias: BiasLearning::default(),
            bias_observation: None,
            stats: OdometerStats::default(),
            effects: WheelEffects::default(),
            effect_state: EffectState::default(),
            jump_candidate: None,
        }
    }

    /// Dead-reckon with the 2W model extended by these effect terms (the
    /// diagnosis's findings): the wheel-side terms (side-slip, load transfer,
    /// speed growth, longitudinal slip, track width, tyre warm-up) act on the
    /// increments; road grade needs a slope signal the odometer does not
    /// have and is left out; the gyro and GNSS terms are the estimate's and
    /// the filter's business. All zero (the default) is the plain model,
    /// bit for bit.
    pub fn set_effects(&mut self, effects: EffectTerms) {
        self.effects = effects.into();
    }

    /// The plain 2W increments, or the extended model's when effect terms are set.
    fn wheel_increments(&mut self, t_s: f64, dt: f64, dn_rl: f64, dn_rr: f64) -> (f64, f64, f64) {
        if self.effects.is_plain() {
            let (ds, dyaw) = self.params.two_wheel.increments(dn_rl, dn_rr);
            return (ds, dyaw, 0.0);
        }
        let tw = self.params.two_wheel;
        let (ds0, dyaw0) = tw.increments(dn_rl, dn_rr);
        let st = &mut self.effect_state;
        let t_first = *st.t_first_s.get_or_insert(t_s - dt);
        if dt > 0.0 {
            let k = (dt / EFFECT_SMOOTHING_S).min(1.0);
            let v_new = st.v_m_s + k * (ds0 / dt - st.v_m_s);
            let a_new = (v_new - st.v_m_s) / dt;
            st.a_x_m_s2 += k * (a_new - st.a_x_m_s2);
            st.v_m_s = v_new;
            st.w_rad_s += k * (dyaw0 / dt - st.w_rad_s);
        }
        let terms = EffectTerms::from(self.effects);
        let signals = StepSignals {
            v_m_s: st.v_m_s,
            a_x_m_s2: st.a_x_m_s2,
            // The plain yaw rate carries the load transfer: read through it,
            // as the diagnosis that estimated k_z did.
            a_y_m_s2: lateral_acceleration_from_wheels(
                st.v_m_s,
                st.w_rad_s,
                terms.k_z,
                tw.track_width,
            ),
            grade: 0.0,
            t_since_start_s: t_s - t_first,
        };
        terms.increments(tw.c_rl, tw.c_rr, tw.track_width, dn_rl, dn_rr, &signals)
    }

    /// The gyro bias in use, rad/s: the calibrated one, combined with what
    /// the standstills measured when [`OdometerConfig::learn_gyro_bias`] is on.
    pub fn gyro_bias(&self) -> f64 {
        let prior = self.params.gyro_bias_rad_s;
        if self.bias.information <= 0.0 {
            return prior;
        }
        let prior_information = self.config.gyro_bias_prior_sigma_rad_s.powi(-2);
        (prior * prior_information + self.bias.weighted_sum)
            / (prior_information + self.bias.information)
    }

    /// Variance of [`Odometer::gyro_bias`], (rad/s)^2: the calibrated bias's
    /// prior ([`OdometerConfig::gyro_bias_prior_sigma_rad_s`]) combined with
    /// every standstill so far. A filter that keeps a residual bias on top of
    /// this one starts it with this variance.
    pub fn gyro_bias_variance(&self) -> f64 {
        1.0 / (self.config.gyro_bias_prior_sigma_rad_s.powi(-2) + self.bias.information)
    }

    /// The last standstill's gyro bias measurement, once (`None` if there was
    /// none since the last call).
    pub fn take_bias_observation(&mut self) -> Option<BiasObservation> {
        self.bias_observation.take()
    }

    /// The car moved off after `standstill`: its gyro mean becomes a bias
    /// measurement when it lasted long enough.
    fn learn_bias_from(&mut self, t_s: f64, standstill: &Standstill) {
        let s = standstill;
        let c = &self.config;
        if !c.learn_gyro_bias || s.gyro_s < c.standstill_min_s || s.gyro_n < 2 {
            return;
        }
        let mean = s.gyro_rad / s.gyro_s;
        let n = f64::from(s.gyro_n);
        let spread = ((s.gyro_sq - n * mean * mean) / (n - 1.0)).max(0.0);
        let variance = (spread / n).max(c.standstill_bias_floor_rad_s.powi(2));
        if !(mean.is_finite() && variance.is_finite() && variance > 0.0) {
            return;
        }
        let before = self.gyro_bias();
        self.bias.information += 1.0 / variance;
        self.bias.weighted_sum += mean / variance;
        self.stats.gyro_bias_updates += 1;
        self.bias_observation = Some(BiasObservation {
            t_s,
            mean_rad_s: mean,
            variance,
            bias_before_rad_s: before,
            bias_after_rad_s: self.gyro_bias(),
        });
    }

    /// The wheel rate offsets learned so far (zero before the first standstill).
    pub fn wheel_offsets(&self) -> WheelOffsets {
        self.offsets
    }

    /// Watch for standstill over the raw increment and learn the offsets.
    /// Returns true while the vehicle stands.
    fn watch_standstill(
        &mut self,
        t_s: f64,
        dt: f64,
        dn_rl: f64,
        dn_rr: f64,
        gyro: Option<GyroAt>,
    ) -> bool {
        let c = &self.config;
        let bias = self.gyro_bias();
        let gyro_still = gyro.is_none_or(|g| (g.rate_rad_s - bias).abs() < c.standstill_gyro_rad_s);
        let still = dn_rl.abs() < c.standstill_rate_rev_s * dt
            && dn_rr.abs() < c.standstill_rate_rev_s * dt
            && gyro_still;
        if !still {
            let ended = std::mem::take(&mut self.standstill);
            self.learn_bias_from(t_s, &ended);
            return false;
        }
        // The gyro over this increment, when it covers the whole of it.
        let gyro_rad = self
            .gyro_mark
            .zip(GyroAt::fresh_integral(gyro))
            .map(|(mark, now)| now - mark);
        let s = &mut self.standstill;
        s.duration_s += dt;
        s.rl_rev += dn_rl;
        s.rr_rev += dn_rr;
        if let Some(d) = gyro_rad {
            s.gyro_s += dt;
            s.gyro_rad += d;
            s.gyro_sq += (d / dt) * (d / dt);
            s.gyro_n += 1;
        }
        if c.learn_wheel_offsets && s.duration_s >= c.standstill_min_s {
            self.offsets = WheelOffsets {
                rl_rev_s: s.rl_rev / s.duration_s,
                rr_rev_s: s.rr_rev / s.duration_s,
            };
            if !s.counted {
                s.counted = true;
                self.stats.standstills += 1;
            }
        }
        true
    }

    /// The parameters in use.
    pub fn params(&self) -> &OdometryParams {
        &self.params
    }

    /// The configuration.
    pub fn config(&self) -> &OdometerConfig {
        &self.config
    }

    /// What has happened so far.
    pub fn stats(&self) -> OdometerStats {
        self.stats
    }

    /// Use new parameters from the next increment on (nothing already
    /// integrated changes).
    pub fn set_params(&mut self, params: OdometryParams) {
        self.params = params;
    }

    /// Time of the last wheel sample taken, s.
    pub fn last_wheel_time(&self) -> Option<f64> {
        self.last_wheels.map(|(t, _, _)| t)
    }

    /// Forget the wheel reference and the gyro history (after the inputs went
    /// stale, or a publisher restarted): the next samples start afresh, even
    /// with earlier times, and the next wheel sample yields no increment. The
    /// learned wheel offsets are kept.
    pub fn restart(&mut self) {
        self.last_wheels = None;
        self.jump_candidate = None;
        self.gyro_mark = None;
        self.gyro = GyroIntegral::default();
        self.standstill = Standstill::default();
    }

    /// Take a yaw-rate sample (raw, as measured).
    pub fn gyro(&mut self, t_s: f64, gz_rad_s: f64) -> Result<(), InputError> {
        self.gyro.push(t_s, gz_rad_s)
    }

    /// Take a wheel sample (cumulative revolutions of the rear wheels). Returns
    /// the increment since the previous wheel sample, or `None` for the first.
    pub fn wheels(
        &mut self,
        t_s: f64,
        rl_rev: f64,
        rr_rev: f64,
    ) -> Result<Option<Increment>, InputError> {
        if !(t_s.is_finite() && rl_rev.is_finite() && rr_rev.is_finite()) {
            return Err(InputError::NonFinite {
                stream: "wheels",
                t_s,
            });
        }
        let gyro = self.gyro.seen_at(t_s, self.config.max_gyro_gap_s);
        let increment = match self.last_wheels {
            Some((t0, _, _)) if t_s <= t0 => {
                return Err(InputError::OutOfOrder {
                    stream: "wheels",
                    t_s,
                    previous_t_s: t0,
                })
            }
            None => None,
            Some((t0, rl0, rr0)) => {
                let dt = t_s - t0;
                let (mut dn_rl, mut dn_rr) = (rl_rev - rl0, rr_rev - rr0);
                let possible = |dn: f64, dt: f64| dn.abs() <= MAX_WHEEL_REV_PER_S * dt + 1.0;
                if !(possible(dn_rl, dt) && possible(dn_rr, dt)) {
                    let confirmed = self.jump_candidate.is_some_and(|(tc, rlc, rrc)| {
                        t_s > tc
                            && possible(rl_rev - rlc, t_s - tc)
                            && possible(rr_rev - rrc, t_s - tc)
                    });
                    if confirmed {
                        self.jump_candidate = None;
                        self.last_wheels = Some((t_s, rl_rev, rr_rev));
                        self.gyro_mark = GyroAt::fresh_integral(gyro);
                        self.gyro.prune_before(t_s);
                        self.stats.counter_jumps += 1;
                        return Err(InputError::CounterJump { t_s });
                    }
                    self.jump_candidate = Some((t_s, rl_rev, rr_rev));
                    self.stats.implausible_steps += 1;
                    return Err(InputError::ImplausibleStep {
                        t_s,
                        dn_rl,
                        dn_rr,
                        dt_s: dt,
                    });
                }
                self.jump_candidate = None;
                let mut standing = false;
                if self.config.learn_wheel_offsets || self.config.learn_gyro_bias {
                    standing = self.watch_standstill(t_s, dt, dn_rl, dn_rr, gyro);
                    dn_rl -= self.offsets.rl_rev_s * dt;
                    dn_rr -= self.offsets.rr_rev_s * dt;
                }
                let (ds_m, dyaw_wheels, beta_rad) = self.wheel_increments(t_s, dt, dn_rl, dn_rr);
                let gyro_dyaw = match (self.config.heading, self.gyro_mark) {
                    (HeadingMode::Gyro, Some(mark)) => GyroAt::fresh_integral(gyro).map(|now| {
                        (now - mark - self.gyro_bias() * (t_s - t0))
                            / (1.0 + self.params.gyro_scale)
                    }),
                    _ => None,
                };
                let (ds_m, dyaw_rad, heading_source) = match gyro_dyaw {
                    // A standing car neither moves nor turns: hold the pose.
                    _ if standing => (0.0, 0.0, HeadingSource::Standstill),
                    Some(d) => (ds_m, d, HeadingSource::Gyro),
                    None => {
                        if self.config.heading == HeadingMode::Gyro {
                            self.stats.gyro_fallbacks += 1;
                        }
                        (ds_m, dyaw_wheels, HeadingSource::Wheels)
                    }
                };
                self.stats.increments += 1;
                Some(Increment {
                    t0_s: t0,
                    t1_s: t_s,
                    ds_m,
                    dyaw_rad,
                    heading_source,
                    beta_rad,
                })
            }
        };
        self.last_wheels = Some((t_s, rl_rev, rr_rev));
        self.gyro_mark = GyroAt::fresh_integral(gyro);
        self.gyro.prune_before(t_s);
        Ok(increment)
    }
}

/// A pose dead-reckoned with an [`Odometer`].
#[derive(Debug, Clone)]
pub struct DeadReckoner {
    odometer: Odometer,
    pose: Pose2,
}

impl DeadReckoner {
    /// Start at `pose`; the first wheel sample sets the wheel reference.
    pub fn new(params: OdometryParams, config: OdometerConfig, pose: Pose2) -> DeadReckoner {
        DeadReckoner {
            odometer: Odometer::new(params, config),
            pose,
        }
    }

    /// The current pose (at the last wheel sample).
    pub fn pose(&self) -> Pose2 {
        self.pose
    }

    /// Put the pose somewhere else (e.g. at the truth at an outage start).
    pub fn set_pose(&mut self, pose: Pose2) {
        self.pose = pose;
    }

    /// The odometer inside.
    pub fn odometer(&self) -> &Odometer {
        &self.odometer
    }

    /// Use new parameters from the next increment on; the pose does not move.
    pub fn set_params(&mut self, params: OdometryParams) {
        self.odometer.set_params(params);
    }

    /// Dead-reckon with these effect terms ([`Odometer::set_effects`]).
    pub fn set_effects(&mut self, effects: EffectTerms) {
        self.odometer.set_effects(effects);
    }

    /// Take a yaw-rate sample.
    pub fn gyro(&mut self, t_s: f64, gz_rad_s: f64) -> Result<(), InputError> {
        self.odometer.gyro(t_s, gz_rad_s)
    }

    /// Take a wheel sample and advance the pose; returns the new pose.
    pub fn wheels(&mut self, t_s: f64, rl_rev: f64, rr_rev: f64) -> Result<Pose2, InputError> {
        if let Some(inc) = self.odometer.wheels(t_s, rl_rev, rr_rev)? {
            self.pose = step(self.pose, inc.ds_m, inc.dyaw_rad, inc.beta_rad);
        }
        Ok(self.pose)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vehicle_model::two_wheel::TwoWheelParams;

    fn params(c_rl: f64, c_rr: f64, track: f64) -> OdometryParams {
        OdometryParams {
            two_wheel: TwoWheelParams {
                c_rl,
                c_rr,
                track_width: track,
            },
            gyro_bias_rad_s: 0.0,
            gyro_scale: 0.0,
        }
    }

    fn config(heading: HeadingMode) -> OdometerConfig {
        OdometerConfig {
            heading,
            learn_wheel_offsets: false,
            learn_gyro_bias: false,
            ..OdometerConfig::default()
        }
    }

    /// Straight at 10 m/s with 2 m wheels (5 rev/s), wheels at 100 Hz: a
    /// single sample 1e6 revolutions off is refused and the distance goes on
    /// from the sample before; counters that jump by 1e6 and stay are taken
    /// as the new reference after one more sample, losing only that step.
    #[test]
    fn a_wheel_glitch_is_refused_and_a_lasting_jump_becomes_the_reference() {
        let mut odo = Odometer::new(params(2.0, 2.0, 1.5), config(HeadingMode::WheelDifference));
        let mut distance = 0.0;
        let mut errors = Vec::new();
        for k in 0..=300 {
            let t = k as f64 * 0.01;
            let mut rev = 0.05 * k as f64;
            if k == 100 {
                rev += 1e6; // one glitch
            }
            if k >= 200 {
                rev += 1e6; // a jump that stays
            }
            match odo.wheels(t, rev, rev) {
                Ok(Some(inc)) => distance += inc.ds_m,
                Ok(None) => {}
                Err(e) => errors.push((k, e)),
            }
        }
        assert_eq!(errors.len(), 3, "{errors:?}");
        assert!(matches!(
            errors[0],
            (100, InputError::ImplausibleStep { .. })
        ));
        assert!(matches!(
            errors[1],
            (200, InputError::ImplausibleStep { .. })
        ));
        assert!(matches!(errors[2], (201, InputError::CounterJump { .. })));
        // 3 s at 10 m/s, less the two steps lost over the jump.
        assert!((distance - (30.0 - 0.2)).abs() < 1e-9, "{distance}");
        let stats = odo.stats();
        assert_eq!((stats.implausible_steps, stats.counter_jumps), (2, 1));
        // A fast but possible car (70 m/s: 35 rev/s) is not refused.
        let mut fast = Odometer::new(params(2.0, 2.0, 1.5), config(HeadingMode::WheelDifference));
        for k in 0..100 {
            assert!(fast
                .wheels(k as f64 * 0.01, 0.35 * k as f64, 0.35 * k as f64)
                .is_ok());
        }
    }

    /// A circle of radius `r` at speed `v`, rear wheels with circumference `c`,
    /// track `t`, wheels and gyro at 100 Hz (gyro offset by 3 ms).
    struct Circle {
        r: f64,
        v: f64,
        c: f64,
        t: f64,
    }

    impl Circle {
        fn revs(&self, time: f64) -> (f64, f64) {
            let angle = self.v * time / self.r;
            (
                angle * (self.r - self.t / 2.0) / self.c,
                angle * (self.r + self.t / 2.0) / self.c,
            )
        }
        fn yaw_rate(&self) -> f64 {
            self.v / self.r
        }
    }

    #[test]
    fn effect_terms_extend_the_model_and_zero_terms_change_nothing() {
        let p = params(2.0, 2.0, 1.5);
        let drive = |dr: &mut DeadReckoner| {
            for k in 0..=500 {
                let t = k as f64 * 0.01;
                // A left turn: the right wheel turns faster.
                dr.wheels(t, 0.05 * k as f64, 0.051 * k as f64).unwrap();
            }
            dr.pose()
        };
        let plain = drive(&mut DeadReckoner::new(
            p,
            config(HeadingMode::WheelDifference),
            Pose2::default(),
        ));
        let mut zero = DeadReckoner::new(p, config(HeadingMode::WheelDifference), Pose2::default());
        zero.set_effects(EffectTerms::default());
        assert_eq!(drive(&mut zero), plain);
        let mut wide = DeadReckoner::new(p, config(HeadingMode::WheelDifference), Pose2::default());
        wide.set_effects(EffectTerms {
            track_rel: 0.02,
            ..EffectTerms::default()
        });
        let pose = drive(&mut wide);
        // A track 2 % wider turns 2 % less for the same wheel difference.
        assert!(
            (pose.yaw - plain.yaw / 1.02).abs() < 1e-12,
            "{} {}",
            pose.yaw,
            plain.yaw
        );
        let mut slip = DeadReckoner::new(p, config(HeadingMode::WheelDifference), Pose2::default());
        slip.set_effects(EffectTerms {
            k_beta: 0.004,
            ..EffectTerms::default()
        });
        let pose = drive(&mut slip);
        // The same heading, the track bent outward of the (left) turn.
        assert_eq!(pose.yaw, plain.yaw);
        assert!(pose.x != plain.x || pose.y != plain.y);
    }

    #[test]
    fn wheel_difference_matches_the_two_wheel_model() {
        let p = params(2.0, 2.0, 1.5);
        let mut dr = DeadReckoner::new(p, config(HeadingMode::WheelDifference), Pose2::default());
        dr.wheels(0.0, 0.0, 0.0).unwrap();
        let pose = dr.wheels(1.0, 5.0, 5.0).unwrap();
        assert!((pose.x - 10.0).abs() < 1e-12 && pose.y.abs() < 1e-12);
        let pose = dr.wheels(2.0, 5.0, 5.0 + 1.5 / 2.0 * 0.1).unwrap();
        assert!((pose.yaw - 0.1).abs() < 1e-12, "{pose:?}");
    }

    #[test]
    fn gyro_mode_closes_a_circle_with_a_biased_scaled_gyro() {
        let circle = Circle {
            r: 20.0,
            v: 10.0,
            c: 2.0,
            t: 1.5,
        };
        let (bias, scale) = (0.01, 0.03);
        let mut p = params(2.0, 2.0, 1.5);
        p.gyro_bias_rad_s = bias;
        p.gyro_scale = scale;
        let mut dr = DeadReckoner::new(p, config(HeadingMode::Gyro), Pose2::default());
        let period = std::f64::consts::TAU * circle.r / circle.v;
        let n = (period * 100.0).round() as usize;
        let mut pose = Pose2::default();
        for i in 0..=n {
            let tw = i as f64 * period / n as f64;
            // Gyro samples on their own clock, 3 ms before each wheel sample.
            dr.gyro(tw - 0.003, (1.0 + scale) * circle.yaw_rate() + bias)
                .unwrap();
            let (rl, rr) = circle.revs(tw);
            pose = dr.wheels(tw, rl, rr).unwrap();
        }
        assert_eq!(dr.odometer().stats().gyro_fallbacks, 0);
        assert!((pose.yaw - std::f64::consts::TAU).abs() < 1e-9, "{pose:?}");
        assert!(pose.x.abs() < 1e-6 && pose.y.abs() < 1e-6, "{pose:?}");
    }

    #[test]
    fn gyro_arriving_late_is_corrected_in_the_next_increment() {
        // Rate steps from 0 to 1 rad/s at t = 0.5; the sample at 0.5 arrives
        // only after the wheel sample at 0.55 was processed.
        let p = params(1.0, 1.0, 1.0);
        let mut odo = Odometer::new(p, config(HeadingMode::Gyro));
        odo.gyro(0.0, 0.0).unwrap();
        odo.wheels(0.0, 0.0, 0.0).unwrap();
        odo.gyro(0.4, 0.0).unwrap();
        let a = odo.wheels(0.55, 0.1, 0.1).unwrap().unwrap();
        assert!(
            a.dyaw_rad.abs() < 1e-15,
            "held rate 0 until the new sample arrives"
        );
        odo.gyro(0.5, 1.0).unwrap();
        odo.gyro(0.6, 1.0).unwrap();
        let b = odo.wheels(0.6, 0.2, 0.2).unwrap().unwrap();
        // Exact integral over [0, 0.6] of the piecewise-linear rate: 0.5*0.1*1 + 0.1*1 = 0.15.
        assert!(
            (a.dyaw_rad + b.dyaw_rad - 0.15).abs() < 1e-12,
            "{a:?} {b:?}"
        );
    }

    #[test]
    fn gyro_missing_falls_back_to_wheels_and_is_counted() {
        let p = params(1.0, 1.0, 1.0);
        let mut odo = Odometer::new(p, config(HeadingMode::Gyro));
        odo.wheels(0.0, 0.0, 0.0).unwrap();
        let inc = odo.wheels(0.1, 0.0, 0.1).unwrap().unwrap();
        assert_eq!(inc.heading_source, HeadingSource::Wheels);
        assert!((inc.dyaw_rad - 0.1).abs() < 1e-12);
        odo.gyro(0.15, 0.0).unwrap();
        // Gyro now fresh at 0.2 but there was none at 0.1: still the wheels.
        assert_eq!(
            odo.wheels(0.2, 0.0, 0.2).unwrap().unwrap().heading_source,
            HeadingSource::Wheels
        );
        odo.gyro(0.25, 0.0).unwrap();
        assert_eq!(
            odo.wheels(0.3, 0.0, 0.3).unwrap().unwrap().heading_source,
            HeadingSource::Gyro
        );
        // Gyro goes silent for longer than max_gyro_gap_s.
        assert_eq!(
            odo.wheels(0.9, 0.0, 0.4).unwrap().unwrap().heading_source,
            HeadingSource::Wheels
        );
        assert_eq!(odo.stats().gyro_fallbacks, 3);
    }

    #[test]
    fn estimate_switch_keeps_the_pose_and_changes_the_next_increments() {
        let mut dr = DeadReckoner::new(
            params(2.0, 2.0, 1.5),
            config(HeadingMode::WheelDifference),
            Pose2::default(),
        );
        dr.wheels(0.0, 0.0, 0.0).unwrap();
        let before = dr.wheels(1.0, 1.0, 1.0).unwrap();
        dr.set_params(params(2.2, 2.2, 1.5));
        assert_eq!(dr.pose(), before, "switching moves nothing");
        let after = dr.wheels(2.0, 2.0, 2.0).unwrap();
        assert!(
            (after.x - before.x - 2.2).abs() < 1e-12,
            "{before:?} {after:?}"
        );
    }

    #[test]
    fn bad_samples_are_rejected_without_touching_the_state() {
        let mut dr = DeadReckoner::new(
            params(2.0, 2.0, 1.5),
            config(HeadingMode::WheelDifference),
            Pose2::default(),
        );
        dr.wheels(0.0, 0.0, 0.0).unwrap();
        let err = dr.wheels(0.0, 1.0, 1.0).unwrap_err();
        assert!(err.to_string().contains("not after"), "{err}");
        let err = dr.wheels(0.5, f64::NAN, 1.0).unwrap_err();
        assert!(err.to_string().contains("non-finite"), "{err}");
        let pose = dr.wheels(1.0, 1.0, 1.0).unwrap();
        assert!((pose.x - 2.0).abs() < 1e-12);
        dr.gyro(1.0, 0.0).unwrap();
        assert!(matches!(
            dr.gyro(0.9, 0.0),
            Err(InputError::OutOfOrder { stream: "imu", .. })
        ));
    }

    /// 5 s standing, then 20 s straight at 10 m/s (5 rev/s of a 2 m wheel),
    /// wheels and gyro at 100 Hz; the gyro reads `bias` plus a +-`jitter`
    /// alternating noise. Returns the final pose.
    fn stand_then_drive(dr: &mut DeadReckoner, bias: f64, jitter: f64) -> Pose2 {
        for i in 0..=2500 {
            let t = f64::from(i) * 0.01;
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            dr.gyro(t - 0.003, bias + sign * jitter).unwrap();
            let rev = 5.0 * (t - 5.0).max(0.0);
            dr.wheels(t, rev, rev).unwrap();
        }
        dr.pose()
    }

    #[test]
    fn gyro_bias_is_measured_at_standstill_and_used_when_driving_off() {
        // The calibrated bias (0) is from an earlier power-on; today it is 1e-3 rad/s.
        let p = params(2.0, 2.0, 1.5);
        let bias = 1e-3;
        let learning = OdometerConfig {
            heading: HeadingMode::Gyro,
            learn_wheel_offsets: false,
            gyro_bias_prior_sigma_rad_s: 5e-5,
            ..OdometerConfig::default()
        };
        let mut dr = DeadReckoner::new(p, learning, Pose2::default());
        let pose = stand_then_drive(&mut dr, bias, 2e-3);
        let mut odo = dr.odometer().clone();
        assert_eq!(odo.stats().gyro_bias_updates, 1);
        let obs = odo.take_bias_observation().expect("one measurement");
        assert!((obs.mean_rad_s - bias).abs() < 1e-6, "{obs:?}");
        // The jitter's spread over 500 increments, at most 2e-3 / sqrt(500).
        assert!(
            obs.variance > 0.0 && obs.variance <= 4e-6 / 500.0,
            "{obs:?}"
        );
        // Inverse-variance mean with the calibrated bias (0, sigma 5e-5).
        let w = 5e-5_f64.powi(2) / (5e-5_f64.powi(2) + obs.variance);
        assert!(w > 0.2 && w < 0.9, "the prior still counts: {w}");
        assert!((odo.gyro_bias() - w * obs.mean_rad_s).abs() < 1e-12);
        // The standing part adds no heading; the drive only the unlearned part.
        let expected_yaw = (bias - odo.gyro_bias()) * 20.0;
        assert!(
            (pose.yaw - expected_yaw).abs() < 1e-4,
            "{pose:?} {expected_yaw}"
        );

        // A quiet gyro: the measurement outweighs the prior, the heading stays.
        let mut quiet = DeadReckoner::new(p, learning, Pose2::default());
        let pose = stand_then_drive(&mut quiet, bias, 0.0);
        assert!((quiet.odometer().gyro_bias() - bias).abs() < 1e-5);
        assert!(pose.yaw.abs() < 2e-4, "{pose:?}");
        let mut odo = quiet.odometer().clone();
        let obs = odo.take_bias_observation().expect("one measurement");
        assert!((obs.mean_rad_s - bias).abs() < 1e-9 && obs.bias_before_rad_s == 0.0);
        assert_eq!(obs.bias_after_rad_s, quiet.odometer().gyro_bias());
        assert!(odo.take_bias_observation().is_none(), "handed on once");

        // Switched off: the calibrated bias stays, the heading drifts by 0.02 rad.
        let mut plain = DeadReckoner::new(p, config(HeadingMode::Gyro), Pose2::default());
        let pose = stand_then_drive(&mut plain, bias, 0.0);
        assert_eq!(plain.odometer().stats().gyro_bias_updates, 0);
        assert!((pose.yaw - bias * 25.0).abs() < 1e-6, "{pose:?}");
    }

    #[test]
    fn wheel_offsets_are_learned_at_standstill_and_removed() {
        // Offsets 0.001 and 0.003 rev/s on a 2 m wheel, track 1.5 m: 0.004 rad/s of yaw drift.
        let p = params(2.0, 2.0, 1.5);
        let offsets = (0.001, 0.003);
        let cfg = OdometerConfig {
            heading: HeadingMode::WheelDifference,
            ..OdometerConfig::default()
        };
        let mut dr = DeadReckoner::new(p, cfg, Pose2::default());
        let mut plain =
            DeadReckoner::new(p, config(HeadingMode::WheelDifference), Pose2::default());
        // 3 s standing, then 20 s straight at 10 m/s (5 rev/s).
        for i in 0..=2300 {
            let t = i as f64 * 0.01;
            let moving = (t - 3.0).max(0.0);
            let (rl, rr) = (5.0 * moving + offsets.0 * t, 5.0 * moving + offsets.1 * t);
            dr.wheels(t, rl, rr).unwrap();
            plain.wheels(t, rl, rr).unwrap();
        }
        let learned = dr.odometer().wheel_offsets();
        assert!(
            (learned.rl_rev_s - offsets.0).abs() < 1e-9
                && (learned.rr_rev_s - offsets.1).abs() < 1e-9
        );
        assert_eq!(dr.odometer().stats().standstills, 1);
        // Standing increments are zero, moving ones corrected.
        assert!(
            dr.pose().yaw.abs() < 1e-9 && dr.pose().y.abs() < 1e-6,
            "{:?}",
            dr.pose()
        );
        assert!((dr.pose().x - 200.0).abs() < 1e-6);
        // Without learning: 0.002 rev/s * 2 m / 1.5 m = 0.00267 rad/s over 23 s.
        assert!(
            (plain.pose().yaw - 0.002 * 2.0 / 1.5 * 23.0).abs() < 1e-9,
            "{:?}",
            plain.pose()
        );
    }

    #[test]
    fn heading_mode_parses_its_names() {
        assert_eq!(
            "wheels".parse::<HeadingMode>(),
            Ok(HeadingMode::WheelDifference)
        );
        assert_eq!("gyro".parse::<HeadingMode>(), Ok(HeadingMode::Gyro));
        assert!("compass".parse::<HeadingMode>().is_err());
        assert_eq!(HeadingMode::Gyro.to_string(), "gyro");
    }
}
