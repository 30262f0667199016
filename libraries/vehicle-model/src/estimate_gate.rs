//! What an estimate that arrives on the bus must satisfy before the
//! odometry applies it: [`EstimateGate`].
//!
//! Any process of the same user can publish on the estimate topic, so the
//! odometry cannot take an estimate at its word: a circumference of 0.1 m or
//! 1e6 m, or a gyro bias of 10 rad/s, all pass [`Estimate::from_wire`] (which
//! only checks that values are usable numbers) and would make the
//! dead-reckoning wrong by any amount. The gate checks, in this order:
//!
//! 1. **Every value finite**: parameters, sigmas, quality, antenna, effect terms.
//! 2. **Sigmas**, when known, finite and positive. The wire has no validity
//!    flag for them and sends unknown sigmas as 0 ([`Estimate::to_wire`]), so
//!    a pair of exact zeros counts as unknown; one zero, a negative or a
//!    non-finite sigma is refused.
//! 3. **Circumferences near the nominal** one of `vehicle.toml`: within
//!    [`GateLimits::circumference_rel`] (default ±15 %). Tyre wear takes a
//!    few millimetres of radius (≈1 % of the circumference over a tyre's
//!    life), pressure and temperature change the rolling radius by 1-2 %, and
//!    a wrong tyre size on the rim by about 10 %; anything beyond 15 % is not
//!    this car's wheel but a wrong unit, a wrong vehicle file or a forged value.
//! 4. **Rear wheels alike**: the two rear circumferences within
//!    [`GateLimits::rear_pair_rel`] (default 3 %) of each other. Two tyres of
//!    the same size on one axle differ by wear and pressure only (well under
//!    1 % in practice); 3 % would already make a straight drive curve by
//!    several degrees per 100 m.
//! 5. **Track width** within [`GateLimits::track_rel`] (default ±25 %) of
//!    `vehicle.toml`'s: the calibrated track is an *effective* track (it
//!    absorbs tyre scrub and side-slip), which differs from the measured one
//!    by some percent, not by a quarter.
//! 6. **Gyro bias** below [`GateLimits::max_gyro_bias_rad_s`] (default
//!    0.1 rad/s ≈ 5.7 °/s) in magnitude: automotive MEMS yaw gyros have
//!    turn-on biases of a few tenths of a degree per second, at most about
//!    1-2 °/s over temperature; 5.7 °/s is a broken sensor or a unit mix-up.
//! 7. **Gyro scale** error below [`GateLimits::max_gyro_scale`] (default 0.1)
//!    in magnitude: MEMS scale factors are good to about 1 %.
//! 8. **One publisher**: the first accepted estimate with a known publisher
//!    id pins that publisher; an estimate from another one is refused until
//!    the service calls [`EstimateGate::forget_publisher`] (it knows the
//!    pinned publisher left the bus). An estimate whose publisher is not known
//!    (`None`) is not checked against the pin and does not set it.
//! 9. **Versions strictly increasing** per publisher: a version below the
//!    current one of the same publisher (or when either publisher is not
//!    known), or the current one with other values, is refused. Another
//!    publisher's version numbers are its own (it can only come after the
//!    pin was released). The current version with
//!    the very same values (a late subscriber gets the history sample again,
//!    or the publisher re-sends it after a restart) is accepted idempotently:
//!    [`EstimateGate::check_outcome`] tells it apart as
//!    [`GateOutcome::Repeat`], [`EstimateGate::check`] returns `Ok(())`.
//! 10. **Bounded step** from the current accepted estimate: a circumference
//!     that moves by more than [`GateLimits::step_rel`] (default 5 %) is
//!     refused. A recalibration follows tyre wear, pressure and temperature,
//!     which move a circumference by 1-2 % between two calibrations; a 5 %
//!     step is a wrong fit or a forged value. The limit is relative, not in
//!     sigmas: a good calibration has a sigma well under a millimetre, so
//!     "10 sigma" would be about 0.2 % and would refuse the genuine change
//!     after a tyre-pressure change, locking the odometry on a stale estimate
//!     with no way back.
//! 11. **Not contradicted**: an estimate the odometry dropped because the
//!     data contradicted it ([`EstimateGate::drop_contradicted`]) is refused
//!     when it is sent again (same version and values).
//!
//! A dropped estimate blocks nothing: after
//! [`EstimateGate::drop_contradicted`] the current estimate is the one
//! accepted before it (or none), its publisher is pinned again (or none),
//! and the version and step rules compare with that one.
//!
//! The gate is pure: the service owns the bus and decides what to log.

use crate::estimate::Estimate;
use interfaces::drive::VehicleParams;

/// The limits of the gate (see the module doc for the reasoning behind each
/// default).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GateLimits {
    /// Largest relative difference of a rear circumference from the nominal one.
    pub circumference_rel: f64,
    /// Largest relative difference of the two rear circumferences (to their mean).
    pub rear_pair_rel: f64,
    /// Largest relative difference of the track width from the nominal one.
    pub track_rel: f64,
    /// Largest |gyro bias|, rad/s.
    pub max_gyro_bias_rad_s: f64,
    /// Largest |gyro scale error|.
    pub max_gyro_scale: f64,
    /// Largest relative step of a circumference from the current accepted estimate.
    pub step_rel: f64,
}

impl Default for GateLimits {
    fn default() -> GateLimits {
        GateLimits {
            circumference_rel: 0.15,
            rear_pair_rel: 0.03,
            track_rel: 0.25,
            max_gyro_bias_rad_s: 0.1,
            max_gyro_scale: 0.1,
            step_rel: 0.05,
        }
    }
}

/// Why an estimate was refused; the message gives the numbers.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EstimateRejected {
    /// A value is NaN or infinite.
    #[error("estimate refused: {field} = {value} is not finite")]
    NonFinite {
        /// The field.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// A known sigma is not positive.
    #[error("estimate refused: {field} = {value} m must be positive (or both sigmas 0: unknown)")]
    BadSigma {
        /// The field.
        field: &'static str,
        /// Its value, m.
        value: f64,
    },
    /// A circumference is too far from the nominal one.
    #[error(
        "estimate refused: {field} = {value} m is outside {min:.4}..{max:.4} m \
         (nominal {nominal} m +-{limit_pct:.0} %)"
    )]
    Circumference {
        /// The field.
        field: &'static str,
        /// Its value, m.
        value: f64,
        /// `vehicle.toml`'s nominal circumference, m.
        nominal: f64,
        /// Smallest accepted value, m.
        min: f64,
        /// Largest accepted value, m.
        max: f64,
        /// The limit, percent of the nominal.
        limit_pct: f64,
    },
    /// The two rear circumferences differ too much.
    #[error(
        "estimate refused: rear circumferences {c_rl} m and {c_rr} m differ by {diff_pct:.2} % \
         (at most {limit_pct:.1} %)"
    )]
    RearMismatch {
        /// Rear left, m.
        c_rl: f64,
        /// Rear right, m.
        c_rr: f64,
        /// Their difference, percent of their mean.
        diff_pct: f64,
        /// The limit, percent.
        limit_pct: f64,
    },
    /// The track width is too far from the nominal one.
    #[error(
        "estimate refused: track_width_m = {value} m is outside {min:.4}..{max:.4} m \
         (vehicle.toml {nominal} m +-{limit_pct:.0} %)"
    )]
    Track {
        /// Its value, m.
        value: f64,
        /// `vehicle.toml`'s track width, m.
        nominal: f64,
        /// Smallest accepted value, m.
        min: f64,
        /// Largest accepted value, m.
        max: f64,
        /// The limit, percent of the nominal.
        limit_pct: f64,
    },
    /// The gyro bias is beyond what a yaw gyro has.
    #[error("estimate refused: |gyro_bias_rad_s| = {value} rad/s is above {limit} rad/s")]
    GyroBias {
        /// Its value, rad/s.
        value: f64,
        /// The limit, rad/s.
        limit: f64,
    },
    /// The gyro scale error is beyond what a yaw gyro has.
    #[error("estimate refused: |gyro_scale| = {value} is above {limit}")]
    GyroScale {
        /// Its value.
        value: f64,
        /// The limit.
        limit: f64,
    },
    /// Another publisher than the pinned one sent it.
    #[error(
        "estimate refused: publisher {publisher:#x} is not the estimate's publisher \
         {pinned:#x} (still on the bus)"
    )]
    OtherPublisher {
        /// Who sent it.
        publisher: u128,
        /// The pinned publisher.
        pinned: u128,
    },
    /// The version is below the current one.
    #[error("estimate refused: version {version} is not above the current version {current}")]
    VersionNotIncreasing {
        /// The version received.
        version: u64,
        /// The current accepted version.
        current: u64,
    },
    /// The current version again, with other values.
    #[error("estimate refused: version {version} is the current version but with other values")]
    ChangedRepeat {
        /// The version received.
        version: u64,
    },
    /// The odometry dropped this estimate: the data contradicted it.
    #[error(
        "estimate refused: version {version} with these values was dropped, the data \
         contradicted it"
    )]
    Contradicted {
        /// The version received.
        version: u64,
    },
    /// A circumference moved too far from the current accepted estimate.
    #[error(
        "estimate refused: {field} steps from {from} m to {to} m ({step_pct:+.2} %), more than \
         a recalibration moves it (at most {limit_pct:.1} %)"
    )]
    Step {
        /// The field.
        field: &'static str,
        /// The current accepted value, m.
        from: f64,
        /// The value received, m.
        to: f64,
        /// The step, percent of the current value.
        step_pct: f64,
        /// The limit, percent.
        limit_pct: f64,
    },
}

/// What [`EstimateGate::check_outcome`] made of an acceptable estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GateOutcome {
    /// A new estimate: it is now the current one.
    Accepted,
    /// The current version with the same values, received again: nothing changes.
    Repeat,
}

/// The estimate accepted last.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Current {
    version: u64,
    estimate: Estimate,
    publisher: Option<u128>,
}

/// How many accepted estimates the gate remembers to fall back on.
const HISTORY: usize = 8;

/// Checks estimates from the bus before they are applied (see the module doc
/// for the rules) and remembers the one accepted last.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimateGate {
    nominal_circumference_m: f64,
    nominal_track_m: f64,
    limits: GateLimits,
    current: Option<Current>,
    /// The estimates accepted before the current one, oldest first.
    before: Vec<Current>,
    /// Estimates dropped as contradicted by the data.
    contradicted: Vec<(u64, Estimate)>,
    /// Set by [`EstimateGate::forget_publisher`]: the next accepted estimate
    /// starts a new version sequence.
    new_sequence: bool,
    publisher: Option<u128>,
}

impl EstimateGate {
    /// A gate for this vehicle with the default [`GateLimits`]. A vehicle
    /// whose nominal circumference or track is not a positive number makes
    /// every range empty: every estimate is refused.
    pub fn new(vehicle: &VehicleParams) -> EstimateGate {
        EstimateGate::with_limits(vehicle, GateLimits::default())
    }

    /// A gate for this vehicle with other limits.
    pub fn with_limits(vehicle: &VehicleParams, limits: GateLimits) -> EstimateGate {
        EstimateGate {
            nominal_circumference_m: vehicle.nominal_circumference_m,
            nominal_track_m: vehicle.track_width_m,
            limits,
            current: None,
            before: Vec::new(),
            contradicted: Vec::new(),
            new_sequence: false,
            publisher: None,
        }
    }

    /// The limits in use.
    pub fn limits(&self) -> &GateLimits {
        &self.limits
    }

    /// Check an estimate received with this `version` from this `publisher`
    /// (its id when the transport gives it). On `Ok` the estimate is the
    /// current one (a repeat of the current version with the same values is
    /// accepted idempotently: see [`EstimateGate::check_outcome`] to tell it
    /// apart). On `Err` nothing changes.
    pub fn check(
        &mut self,
        version: u64,
        publisher: Option<u128>,
        estimate: &Estimate,
    ) -> Result<(), EstimateRejected> {
        self.check_outcome(version, publisher, estimate).map(|_| ())
    }

    /// [`EstimateGate::check`], telling a new estimate from a repeat of the
    /// current one.
    pub fn check_outcome(
        &mut self,
        version: u64,
        publisher: Option<u128>,
        estimate: &Estimate,
    ) -> Result<GateOutcome, EstimateRejected> {
        check_values(
            estimate,
            self.nominal_circumference_m,
            self.nominal_track_m,
            &self.limits,
        )?;
        if let (Some(p), Some(pinned)) = (publisher, self.publisher) {
            if p != pinned {
                return Err(EstimateRejected::OtherPublisher {
                    publisher: p,
                    pinned,
                });
            }
        }
        if self
            .contradicted
            .iter()
            .any(|(v, e)| *v == version && e == estimate)
        {
            return Err(EstimateRejected::Contradicted { version });
        }
        if let Some(cur) = &self.current {
            let same_sequence = match (publisher, cur.publisher) {
                (Some(a), Some(b)) => a == b,
                _ => true,
            };
            if !self.new_sequence && same_sequence {
                if version == cur.version {
                    return if *estimate == cur.estimate {
                        Ok(GateOutcome::Repeat)
                    } else {
                        Err(EstimateRejected::ChangedRepeat { version })
                    };
                }
                if version < cur.version {
                    return Err(EstimateRejected::VersionNotIncreasing {
                        version,
                        current: cur.version,
                    });
                }
            }
            check_step(&cur.estimate, estimate, self.limits.step_rel)?;
        }
        if let Some(previous) = self.current.replace(Current {
            version,
            estimate: *estimate,
            publisher,
        }) {
            if self.before.len() == HISTORY {
                self.before.remove(0);
            }
            self.before.push(previous);
        }
        self.new_sequence = false;
        if publisher.is_some() {
            self.publisher = publisher;
        }
        Ok(GateOutcome::Accepted)
    }

    /// The version of the current accepted estimate, if any.
    pub fn current_version(&self) -> Option<u64> {
        self.current.map(|c| c.version)
    }

    /// The current accepted estimate, if any.
    pub fn current_estimate(&self) -> Option<&Estimate> {
        self.current.as_ref().map(|c| &c.estimate)
    }

    /// The odometry dropped estimate `version`: the data contradict it. It is
    /// refused if sent again; when it is the current estimate, the one
    /// accepted before it becomes current again (its publisher pinned, or
    /// none) and is returned with its version, to fall back on (`None`:
    /// back to the nominal values). When it is not the current one (a newer
    /// estimate was accepted since), nothing else changes and `None` is
    /// returned with `false`.
    ///
    /// Returns (the estimate to fall back on, whether to fall back).
    pub fn drop_contradicted(&mut self, version: u64) -> (Option<(u64, Estimate)>, bool) {
        let Some(cur) = self.current else {
            return (None, false);
        };
        if cur.version != version {
            if let Some(i) = self.before.iter().rposition(|c| c.version == version) {
                let dropped = self.before.remove(i);
                self.contradicted.push((dropped.version, dropped.estimate));
            }
            return (None, false);
        }
        self.contradicted.push((cur.version, cur.estimate));
        self.current = self.before.pop();
        self.publisher = self.current.and_then(|c| c.publisher);
        self.new_sequence = false;
        (self.current.map(|c| (c.version, c.estimate)), true)
    }

    /// The pinned publisher, if any.
    pub fn publisher(&self) -> Option<u128> {
        self.publisher
    }

    /// The pinned publisher left the bus: the next estimate may come from any
    /// publisher (which it then pins) and starts a new version sequence (a
    /// restarted calibrator without its state file counts from 1 again). The
    /// value checks, and the step from the current estimate, still apply.
    pub fn forget_publisher(&mut self) {
        self.publisher = None;
        self.new_sequence = self.current.is_some();
    }
}

/// `value <= limit`, false when either is NaN (a refusal).
fn at_most(value: f64, limit: f64) -> bool {
    value <= limit
}

/// Rules 1-7 of the module doc.
fn check_values(
    e: &Estimate,
    nominal_c: f64,
    nominal_track: f64,
    limits: &GateLimits,
) -> Result<(), EstimateRejected> {
    let p = &e.params;
    let fx = &e.effects;
    let [ax, ay] = e.antenna_m.unwrap_or([0.0; 2]);
    let [sax, say] = e.antenna_sigma_m.unwrap_or([0.0; 2]);
    let (s_rl, s_rr) = e.sigma_m.unwrap_or((0.0, 0.0));
    let values: [(&'static str, f64); 18] = [
        ("circumference_m.rl", p.two_wheel.c_rl),
        ("circumference_m.rr", p.two_wheel.c_rr),
        ("track_width_m", p.two_wheel.track_width),
        ("gyro_bias_rad_s", p.gyro_bias_rad_s),
        ("gyro_scale", p.gyro_scale),
        ("sigma_m.rl", s_rl),
        ("sigma_m.rr", s_rr),
        ("quality_m", e.quality_m.unwrap_or(0.0)),
        ("antenna_m.x", ax),
        ("antenna_m.y", ay),
        ("antenna_sigma_m.x", sax),
        ("antenna_sigma_m.y", say),
        ("effects.k_beta", fx.k_beta),
        ("effects.k_z", fx.k_z),
        ("effects.k_v", fx.k_v),
        ("effects.k_s", fx.k_s),
        ("effects.track_rel", fx.track_rel),
        ("effects.drift_d", fx.drift_d),
    ];
    let extra = [("effects.drift_time_constant_s", fx.drift_time_constant_s)];
    if let Some(&(field, value)) = values
        .iter()
        .chain(extra.iter())
        .find(|(_, v)| !v.is_finite())
    {
        return Err(EstimateRejected::NonFinite { field, value });
    }
    if e.sigma_m.is_some() && !(s_rl == 0.0 && s_rr == 0.0) {
        for (field, value) in [("sigma_m.rl", s_rl), ("sigma_m.rr", s_rr)] {
            if value <= 0.0 {
                return Err(EstimateRejected::BadSigma { field, value });
            }
        }
    }
    let rel = limits.circumference_rel;
    let (min, max) = (nominal_c * (1.0 - rel), nominal_c * (1.0 + rel));
    for (field, value) in [
        ("circumference_m.rl", p.two_wheel.c_rl),
        ("circumference_m.rr", p.two_wheel.c_rr),
    ] {
        if !(value >= min && value <= max) {
            return Err(EstimateRejected::Circumference {
                field,
                value,
                nominal: nominal_c,
                min,
                max,
                limit_pct: rel * 100.0,
            });
        }
    }
    let (c_rl, c_rr) = (p.two_wheel.c_rl, p.two_wheel.c_rr);
    let diff = (c_rl - c_rr).abs() / (0.5 * (c_rl + c_rr));
    if !at_most(diff, limits.rear_pair_rel) {
        return Err(EstimateRejected::RearMismatch {
            c_rl,
            c_rr,
            diff_pct: diff * 100.0,
            limit_pct: limits.rear_pair_rel * 100.0,
        });
    }
    let rel = limits.track_rel;
    let (min, max) = (nominal_track * (1.0 - rel), nominal_track * (1.0 + rel));
    let track = p.two_wheel.track_width;
    if !(track >= min && track <= max) {
        return Err(EstimateRejected::Track {
            value: track,
            nominal: nominal_track,
            min,
            max,
            limit_pct: rel * 100.0,
        });
    }
    if !at_most(p.gyro_bias_rad_s.abs(), limits.max_gyro_bias_rad_s) {
        return Err(EstimateRejected::GyroBias {
            value: p.gyro_bias_rad_s.abs(),
            limit: limits.max_gyro_bias_rad_s,
        });
    }
    if !at_most(p.gyro_scale.abs(), limits.max_gyro_scale) {
        return Err(EstimateRejected::GyroScale {
            value: p.gyro_scale.abs(),
            limit: limits.max_gyro_scale,
        });
    }
    Ok(())
}

/// Rule 10 of the module doc.
fn check_step(from: &Estimate, to: &Estimate, step_rel: f64) -> Result<(), EstimateRejected> {
    let (a, b) = (&from.params.two_wheel, &to.params.two_wheel);
    for (field, from, to) in [
        ("circumference_m.rl", a.c_rl, b.c_rl),
        ("circumference_m.rr", a.c_rr, b.c_rr),
    ] {
        let step = to / from - 1.0;
        if !at_most(step.abs(), step_rel) {
            return Err(EstimateRejected::Step {
                field,
                from,
                to,
                step_pct: step * 100.0,
                limit_pct: step_rel * 100.0,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::WheelEffects;
    use crate::estimate::OdometryParams;
    use crate::two_wheel::TwoWheelParams;
    use interfaces::drive::GnssAntenna;
    use interfaces::wire::{CircumferenceEstimate, Header, ModelExtension, MAX_EXTENSIONS};
    use proptest::prelude::*;

    fn vehicle() -> VehicleParams {
        VehicleParams {
            name: None,
            track_width_m: 1.5,
            nominal_circumference_m: 2.0,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: GnssAntenna::default(),
        }
    }

    fn est(c_rl: f64, c_rr: f64) -> Estimate {
        Estimate {
            params: OdometryParams {
                two_wheel: TwoWheelParams {
                    c_rl,
                    c_rr,
                    track_width: 1.52,
                },
                gyro_bias_rad_s: 0.002,
                gyro_scale: -0.004,
            },
            sigma_m: Some((4e-4, 5e-4)),
            quality_m: Some(0.6),
            antenna_m: None,
            antenna_sigma_m: None,
            effects: WheelEffects::default(),
            clocks: Default::default(),
        }
    }

    #[test]
    fn a_contradicted_lie_is_dropped_and_blocks_nothing() {
        // Issue 35 item 3: a same-user process publishes version 99 with
        // circumferences 7 % too large (inside every gate) before the
        // calibrator's first estimate, and it is taken.
        let (liar, calibrator) = (Some(0xbad_u128), Some(0xca1_u128));
        let mut g = EstimateGate::new(&vehicle());
        g.check(99, liar, &est(2.14, 2.14)).expect("plausible");
        // Today the calibrator's v1 is then refused for good.
        assert!(g.check(1, calibrator, &est(2.0, 2.0)).is_err());
        // The odometry finds v99 contradicted by the fixes and drops it:
        // nothing before it, back to nominal.
        assert_eq!(g.drop_contradicted(99), (None, true));
        assert_eq!(g.current_version(), None);
        assert_eq!(g.publisher(), None);
        // Sent again, it is refused with the reason.
        let m = g.check(99, liar, &est(2.14, 2.14)).unwrap_err().to_string();
        assert!(m.contains("contradicted"), "{m}");
        // The calibrator's v1 and v2 are taken: its versions are its own,
        // the step is from the estimate in use.
        g.check(1, calibrator, &est(2.0, 2.0))
            .expect("v1 after the drop");
        g.check(2, calibrator, &est(2.01, 2.01)).expect("v2");
        assert_eq!(g.publisher(), calibrator);
        // A lie later, after the calibrator left: dropped, back to the
        // calibrator's v2 (pinned again), whose v3 is then taken, stepping
        // from v2, not from the lie.
        g.forget_publisher();
        g.check(100, liar, &est(2.1, 2.1))
            .expect("a step under 5 %");
        let (back, fall) = g.drop_contradicted(100);
        assert!(fall);
        assert_eq!(back, Some((2, est(2.01, 2.01))));
        assert_eq!((g.current_version(), g.publisher()), (Some(2), calibrator));
        assert!(g.check(3, liar, &est(2.0, 2.0)).is_err(), "pinned again");
        g.check(3, calibrator, &est(2.02, 2.02)).expect("v3");
        // Dropping a version that is no longer current changes nothing else.
        assert_eq!(g.drop_contradicted(2), (None, false));
        assert_eq!(g.current_version(), Some(3));
    }

    #[test]
    fn the_reported_attacks_are_refused_with_the_numbers() {
        let mut g = EstimateGate::new(&vehicle());
        let msg = |r: Result<(), EstimateRejected>| r.unwrap_err().to_string();
        let m = msg(g.check(1, None, &est(0.1, 0.1)));
        assert!(
            m.contains("0.1") && m.contains("1.7000") && m.contains("15 %"),
            "{m}"
        );
        let m = msg(g.check(1, None, &est(1e6, 1e6)));
        assert!(m.contains("1000000"), "{m}");
        let mut e = est(2.0, 2.0);
        e.params.gyro_bias_rad_s = 10.0;
        let m = msg(g.check(1, None, &e));
        assert!(
            m.contains("gyro_bias") && m.contains("10") && m.contains("0.1"),
            "{m}"
        );
        e.params.gyro_bias_rad_s = 0.0;
        e.params.gyro_scale = -0.3;
        assert!(msg(g.check(1, None, &e)).contains("gyro_scale"));
        let m = msg(g.check(1, None, &est(2.0, 2.1)));
        assert!(m.contains("differ by 4.88 %"), "{m}");
        let mut e = est(2.0, 2.0);
        e.params.two_wheel.track_width = 2.0;
        let m = msg(g.check(1, None, &e));
        assert!(
            m.contains("track_width_m = 2") && m.contains("1.8750"),
            "{m}"
        );
        e.params.two_wheel.track_width = 1.5;
        e.sigma_m = Some((1e-3, -1e-3));
        assert!(msg(g.check(1, None, &e)).contains("sigma_m.rr = -0.001"));
        e.sigma_m = Some((0.0, 1e-3));
        assert!(msg(g.check(1, None, &e)).contains("sigma_m.rl"));
        e.sigma_m = Some((0.0, 0.0));
        assert_eq!(
            g.check(1, None, &e),
            Ok(()),
            "both 0: unknown (the wire's convention)"
        );
        e.effects.k_z = f64::NAN;
        assert!(msg(g.check(2, None, &e)).contains("effects.k_z = NaN"));
    }

    #[test]
    fn versions_must_increase_and_a_repeat_is_idempotent() {
        let mut g = EstimateGate::new(&vehicle());
        assert_eq!(g.current_version(), None);
        g.check(99, None, &est(2.0, 2.0)).unwrap();
        assert_eq!(g.current_version(), Some(99));
        let m = g.check(1, None, &est(2.01, 2.01)).unwrap_err().to_string();
        assert!(
            m.contains("version 1 is not above the current version 99"),
            "{m}"
        );
        assert_eq!(
            g.check_outcome(99, None, &est(2.0, 2.0)),
            Ok(GateOutcome::Repeat)
        );
        assert_eq!(
            g.check(99, None, &est(2.01, 2.01)),
            Err(EstimateRejected::ChangedRepeat { version: 99 })
        );
        assert_eq!(
            g.check_outcome(100, None, &est(2.01, 2.01)),
            Ok(GateOutcome::Accepted)
        );
        assert_eq!(g.current_version(), Some(100));
        assert_eq!(g.current_estimate(), Some(&est(2.01, 2.01)));
    }

    #[test]
    fn a_step_beyond_a_recalibration_is_refused() {
        let mut g = EstimateGate::new(&vehicle());
        g.check(1, None, &est(1.8, 1.8)).unwrap();
        // 2.0 / 1.8 = +11 %: both inside the +-15 % range, but not one step.
        let m = g.check(2, None, &est(2.0, 2.0)).unwrap_err().to_string();
        assert!(m.contains("+11.11 %") && m.contains("5.0 %"), "{m}");
        // In two steps of < 5 % it gets there: a recalibration can follow.
        g.check(2, None, &est(1.88, 1.88)).unwrap();
        g.check(3, None, &est(1.96, 1.96)).unwrap();
        g.check(4, None, &est(2.0, 2.0)).unwrap();
    }

    #[test]
    fn one_publisher_until_it_is_forgotten() {
        let mut g = EstimateGate::new(&vehicle());
        g.check(5, Some(0xa), &est(2.0, 2.0)).unwrap();
        assert_eq!(g.publisher(), Some(0xa));
        let m = g
            .check(6, Some(0xb), &est(2.0, 2.0))
            .unwrap_err()
            .to_string();
        assert!(m.contains("0xb") && m.contains("0xa"), "{m}");
        // Unknown publisher: no pin check.
        g.check(6, None, &est(2.0, 2.0)).unwrap();
        g.forget_publisher();
        // The new publisher starts its own sequence and pins itself...
        g.check(1, Some(0xb), &est(2.01, 2.01)).unwrap();
        assert_eq!((g.publisher(), g.current_version()), (Some(0xb), Some(1)));
        assert!(g.check(2, Some(0xa), &est(2.0, 2.0)).is_err());
        // ...but cannot step away from the current values.
        g.forget_publisher();
        assert!(matches!(
            g.check(1, Some(0xc), &est(1.75, 1.75)),
            Err(EstimateRejected::Step { .. })
        ));
        // And after a forget, versions increase again from the accepted one.
        g.check(7, Some(0xc), &est(2.0, 2.0)).unwrap();
        assert!(g.check(3, Some(0xc), &est(2.0, 2.0)).is_err());
    }

    #[test]
    fn a_vehicle_without_a_usable_nominal_refuses_everything() {
        let mut v = vehicle();
        v.nominal_circumference_m = f64::NAN;
        let mut g = EstimateGate::new(&v);
        assert!(g.check(1, None, &est(2.0, 2.0)).is_err());
    }

    // ---- property tests ----

    /// A valid estimate near the test vehicle: inside every range.
    fn valid_estimate() -> impl Strategy<Value = Estimate> {
        (
            (1.75f64..2.25, -0.01f64..0.01, 1.2f64..1.8),
            (-0.09f64..0.09, -0.09f64..0.09),
            (1e-5f64..0.01, 1e-5f64..0.01, 0.0f64..100.0),
            proptest::option::of((-19.0f64..19.0, -19.0f64..19.0, 0.0f64..1.0, 0.0f64..1.0)),
            any::<bool>(),
            (-0.01f64..0.01, -1e-3f64..1e-3, -0.05f64..0.05),
        )
            .prop_map(
                |((c, d, track), (bias, scale), (srl, srr, q), ant, ant_sigma, (k, kz, tr))| {
                    Estimate {
                        params: OdometryParams {
                            two_wheel: TwoWheelParams {
                                c_rl: c,
                                c_rr: c * (1.0 + d),
                                track_width: track,
                            },
                            gyro_bias_rad_s: bias,
                            gyro_scale: scale,
                        },
                        sigma_m: Some((srl, srr)),
                        quality_m: Some(q),
                        antenna_m: ant.map(|a| [a.0, a.1]),
                        antenna_sigma_m: ant.filter(|_| ant_sigma).map(|a| [a.2, a.3]),
                        effects: WheelEffects {
                            k_beta: k,
                            k_z: kz,
                            track_rel: tr,
                            ..WheelEffects::default()
                        },
                        clocks: Default::default(),
                    }
                },
            )
    }

    /// Any f64 bit pattern: NaN, infinities, subnormals, huge values.
    fn any_f64() -> impl Strategy<Value = f64> {
        prop_oneof![
            any::<u64>().prop_map(f64::from_bits),
            Just(f64::NAN),
            Just(f64::INFINITY),
            Just(f64::NEG_INFINITY),
            Just(0.0),
            -10.0f64..10.0,
        ]
    }

    fn any_extension() -> impl Strategy<Value = ModelExtension> {
        (
            prop_oneof![0u32..16, any::<u32>()],
            any::<u32>(),
            proptest::array::uniform4(any_f64()),
        )
            .prop_map(|(effect_code, param_count, params)| ModelExtension {
                effect_code,
                param_count,
                params,
            })
    }

    fn any_wire() -> impl Strategy<Value = CircumferenceEstimate> {
        (
            any::<(i64, u64, u64)>(),
            proptest::array::uniform9(any_f64()),
            any::<u32>(),
            proptest::array::uniform8(any_extension()),
        )
            .prop_map(|((t_ns, seq, version), f, extension_count, extensions)| {
                CircumferenceEstimate {
                    header: Header { t_ns, seq },
                    version,
                    c_rl_m: f[0],
                    c_rr_m: f[1],
                    sigma_rl_m: f[2],
                    sigma_rr_m: f[3],
                    track_width_m: f[4],
                    gyro_bias_rad_s: f[5],
                    gyro_scale: f[6],
                    quality_m: f[7],
                    extension_count,
                    _pad: 0,
                    extensions,
                }
            })
    }

    /// A field of an estimate set to an arbitrary (often invalid) value.
    fn spoil(mut e: Estimate, field: usize, v: f64) -> Estimate {
        match field % 9 {
            0 => e.params.two_wheel.c_rl = v,
            1 => e.params.two_wheel.c_rr = v,
            2 => e.params.two_wheel.track_width = v,
            3 => e.params.gyro_bias_rad_s = v,
            4 => e.params.gyro_scale = v,
            5 => e.sigma_m = e.sigma_m.map(|(_, r)| (v, r)),
            6 => e.quality_m = Some(v),
            7 => e.effects.k_s = v,
            _ => e.antenna_m = Some([v, 0.0]),
        }
        e
    }

    /// What every accepted estimate must satisfy, whatever the history.
    fn within_bounds(e: &Estimate) -> bool {
        let p = &e.params;
        let finite = [
            p.two_wheel.c_rl,
            p.two_wheel.c_rr,
            p.two_wheel.track_width,
            p.gyro_bias_rad_s,
            p.gyro_scale,
            e.quality_m.unwrap_or(0.0),
            e.effects.k_s,
            e.antenna_m.map_or(0.0, |a| a[0]),
        ]
        .iter()
        .all(|v| v.is_finite());
        let sig_ok = e
            .sigma_m
            .is_none_or(|(a, b)| (a == 0.0 && b == 0.0) || (a > 0.0 && b > 0.0));
        finite
            && sig_ok
            && (1.7..=2.3).contains(&p.two_wheel.c_rl)
            && (1.7..=2.3).contains(&p.two_wheel.c_rr)
            && (1.125..=1.875).contains(&p.two_wheel.track_width)
            && p.gyro_bias_rad_s.abs() <= 0.1
            && p.gyro_scale.abs() <= 0.1
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        #[test]
        fn wire_round_trip_keeps_a_valid_estimate(e in valid_estimate(), version in any::<u64>(),
                                                  t in -1e9f64..1e9, seq in any::<u64>()) {
            let wire = e.to_wire(Header::from_seconds(t, seq), version);
            prop_assert_eq!(wire.version, version);
            prop_assert_eq!(Estimate::from_wire(&wire).unwrap(), e);
        }

        #[test]
        fn from_wire_never_panics_and_never_yields_non_finite_parameters(w in any_wire()) {
            if let Ok(e) = Estimate::from_wire(&w) {
                let p = e.params;
                prop_assert!(p.two_wheel.c_rl.is_finite() && p.two_wheel.c_rl > 0.0);
                prop_assert!(p.two_wheel.c_rr.is_finite() && p.two_wheel.c_rr > 0.0);
                prop_assert!(p.two_wheel.track_width.is_finite());
                prop_assert!(p.gyro_bias_rad_s.is_finite() && p.gyro_scale.is_finite());
                if let Some(a) = e.antenna_m {
                    prop_assert!(a.iter().all(|v| v.is_finite()));
                }
                let ws = e.effects;
                for v in [ws.k_beta, ws.k_z, ws.k_v, ws.k_s, ws.track_rel, ws.drift_d] {
                    prop_assert!(v.is_finite());
                }
            }
            // The gate never panics on whatever from_wire let through.
            if let Ok(e) = Estimate::from_wire(&w) {
                let mut g = EstimateGate::new(&vehicle());
                if g.check(w.version, None, &e).is_ok() {
                    prop_assert!(within_bounds(&e));
                }
            }
        }

        #[test]
        fn the_gate_never_accepts_a_bad_value_or_an_old_version(
            steps in proptest::collection::vec(
                (valid_estimate(), any::<bool>(), 0usize..9, any_f64(), 0u64..40, 0u8..3),
                1..40,
            )
        ) {
            let mut g = EstimateGate::new(&vehicle());
            for (e, spoiled, field, v, version, who) in steps {
                let e = if spoiled { spoil(e, field, v) } else { e };
                let publisher = (who > 0).then_some(u128::from(who));
                let before = g.clone();
                match g.check_outcome(version, publisher, &e) {
                    Ok(outcome) => {
                        prop_assert!(within_bounds(&e), "accepted {e:?}");
                        if let Some(cur) = before.current_version() {
                            match outcome {
                                GateOutcome::Repeat => {
                                    prop_assert_eq!(version, cur);
                                    prop_assert_eq!(before.current_estimate(), Some(&e));
                                }
                                GateOutcome::Accepted => prop_assert!(version > cur),
                            }
                            let c0 = before.current_estimate().unwrap().params.two_wheel;
                            prop_assert!((e.params.two_wheel.c_rl / c0.c_rl - 1.0).abs() <= 0.05);
                        }
                        if let (Some(p), Some(q)) = (before.publisher(), publisher) {
                            prop_assert_eq!(p, q);
                        }
                        prop_assert_eq!(g.current_version(), Some(version));
                    }
                    Err(_) => prop_assert_eq!(&g, &before, "a refusal changes nothing"),
                }
            }
        }
    }

    #[test]
    fn a_wire_estimate_with_every_wheel_effect_round_trips() {
        // The round trip also holds with the extension array full.
        let mut e = est(2.0, 2.0);
        e.antenna_m = Some([0.5, -0.2]);
        e.effects = WheelEffects {
            k_beta: 0.004,
            k_z: 5e-5,
            k_v: 2e-6,
            k_s: 0.002,
            track_rel: 0.01,
            drift_d: 0.003,
            drift_time_constant_s: 600.0,
        };
        let w = e.to_wire(Header::default(), 1);
        assert_eq!(w.extension_count as usize, 7);
        assert!(w.extension_count as usize <= MAX_EXTENSIONS);
        assert_eq!(Estimate::from_wire(&w).unwrap(), e);
    }
}
