//! The effect knobs: one per id of `shared/design/physics-catalogue.md`.
//!
//! Each effect is `None` (off) or `Some(params)` (on, with its magnitude).
//! Vehicle-physics effects (`side_slip`, `load_transfer_radius`,
//! `longitudinal_slip`) set the size of what the vehicle model produces;
//! the others are applied where they act (a wheel radius, a sensor).
//!
//! Defaults ([`EffectSettings::default`]): the three vehicle-physics effects a
//! CarSim-like vehicle model has are on at a typical magnitude; everything else
//! is off. [`EffectSettings::none`] switches all off.

use super::SimError;
use interfaces::effects::{Effect, Param};
use std::collections::BTreeMap;

/// `side_slip`: rear-axle side-slip angle beta = -k_beta * a_y (linear range).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SideSlip {
    /// Rear-axle slip gain, rad per m/s^2 of lateral acceleration.
    pub k_beta: f64,
}

/// `load_transfer_radius`: c_outer,inner = c0 (1 -/+ k_z a_y) on the rear axle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoadTransferRadius {
    /// Relative radius change of a rear wheel per m/s^2 of lateral acceleration.
    pub k_z: f64,
}

/// `speed_radius_growth`: c = c0 (1 + k_v v^2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeedRadiusGrowth {
    /// Relative growth per (m/s)^2.
    pub k_v: f64,
}

/// `longitudinal_slip`: driven-axle wheel speed = v (1 + k_s a_x) (linear range).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LongitudinalSlip {
    /// Slip per m/s^2 of longitudinal acceleration carried by one axle.
    pub k_s: f64,
}

/// `track_width`: the true effective rear track is nominal * (1 + rel).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackWidth {
    /// Relative difference of the true from the nominal (vehicle.toml) track.
    pub rel: f64,
}

/// `gyro_bias`: w_gyro = w + b.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroBias {
    /// Bias, degrees per hour.
    pub b_deg_h: f64,
}

/// `gyro_scale`: w_gyro = (1 + s) w.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroScale {
    /// Scale-factor error (fraction).
    pub s: f64,
}

/// `gnss_latency`: a fix stamped t is the antenna position at t - tau.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssLatency {
    /// Latency, s.
    pub tau_s: f64,
}

/// `gnss_lever_arm`: p_antenna = p_rear_axle + R(yaw) (x, y); not written to vehicle.toml.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssLeverArm {
    /// Antenna forward of the rear-axle centre, m.
    pub x_m: f64,
    /// Antenna left of the rear-axle centre, m.
    pub y_m: f64,
}

/// `radius_drift`: c(t) = c0 (1 + d (1 - exp(-t / T))).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RadiusDrift {
    /// Final relative change (fraction; positive = the tyre grows as it warms).
    pub d: f64,
    /// Time constant T, s.
    pub time_constant_s: f64,
}

/// `road_grade`: the road has slopes; wheels roll along them, GNSS sees the horizontal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoadGrade {
    /// Largest grade (rise over run, e.g. 0.08 = 8 %). Open roads get rolling
    /// hills of this amplitude, the garage's ramps this grade.
    pub grade: f64,
}

/// `heading_bias`: magnetometer heading error
/// A + B sin(psi) + C cos(psi) (hard iron) + D sin(2 psi) + E cos(2 psi) (soft iron).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingBias {
    /// Constant A, degrees.
    pub a_deg: f64,
    /// Hard-iron B (times sin psi), degrees.
    pub b_deg: f64,
    /// Hard-iron C (times cos psi), degrees.
    pub c_deg: f64,
    /// Soft-iron D (times sin 2 psi), degrees.
    pub d_deg: f64,
    /// Soft-iron E (times cos 2 psi), degrees.
    pub e_deg: f64,
}

impl HeadingBias {
    /// Heading error (rad) at true yaw `psi` (rad).
    pub fn error_rad(&self, psi: f64) -> f64 {
        (self.a_deg
            + self.b_deg * psi.sin()
            + self.c_deg * psi.cos()
            + self.d_deg * (2.0 * psi).sin()
            + self.e_deg * (2.0 * psi).cos())
        .to_radians()
    }
}

/// Every effect knob; `None` = off.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffectSettings {
    /// `side_slip`.
    pub side_slip: Option<SideSlip>,
    /// `load_transfer_radius`.
    pub load_transfer_radius: Option<LoadTransferRadius>,
    /// `speed_radius_growth`.
    pub speed_radius_growth: Option<SpeedRadiusGrowth>,
    /// `longitudinal_slip`.
    pub longitudinal_slip: Option<LongitudinalSlip>,
    /// `track_width`.
    pub track_width: Option<TrackWidth>,
    /// `gyro_bias`.
    pub gyro_bias: Option<GyroBias>,
    /// `gyro_scale`.
    pub gyro_scale: Option<GyroScale>,
    /// `gnss_latency`.
    pub gnss_latency: Option<GnssLatency>,
    /// `gnss_lever_arm`.
    pub gnss_lever_arm: Option<GnssLeverArm>,
    /// `radius_drift`.
    pub radius_drift: Option<RadiusDrift>,
    /// `road_grade`.
    pub road_grade: Option<RoadGrade>,
    /// `heading_bias`.
    pub heading_bias: Option<HeadingBias>,
}

impl Default for EffectSettings {
    /// Vehicle physics on at typical magnitudes (`side_slip`,
    /// `load_transfer_radius`, `longitudinal_slip`), everything else off.
    fn default() -> Self {
        let mut e = EffectSettings::none();
        e.switch_on(Effect::SideSlip);
        e.switch_on(Effect::LoadTransferRadius);
        e.switch_on(Effect::LongitudinalSlip);
        e
    }
}

/// The simulator's parameters of an effect with their defaults (the
/// table's [`interfaces::effects::ParamSpec::simulated`], in the reported
/// unit), the main one (what a bare `ID=VALUE` sets) first.
pub fn typical(effect: Effect) -> Vec<(Param, f64)> {
    effect
        .spec()
        .simulated
        .iter()
        .map(|&p| (p, p.spec().simulated))
        .collect()
}

impl EffectSettings {
    /// Every effect off.
    pub fn none() -> EffectSettings {
        EffectSettings {
            side_slip: None,
            load_transfer_radius: None,
            speed_radius_growth: None,
            longitudinal_slip: None,
            track_width: None,
            gyro_bias: None,
            gyro_scale: None,
            gnss_latency: None,
            gnss_lever_arm: None,
            radius_drift: None,
            road_grade: None,
            heading_bias: None,
        }
    }

    /// Only `effect`, at its typical magnitude.
    pub fn only(effect: Effect) -> EffectSettings {
        let mut e = EffectSettings::none();
        e.switch_on(effect);
        e
    }

    /// Whether `effect` is on.
    pub fn is_on(&self, effect: Effect) -> bool {
        self.get(effect.main_simulated()).is_some()
    }

    /// Switch `effect` off.
    pub fn switch_off(&mut self, effect: Effect) {
        match effect {
            Effect::SideSlip => self.side_slip = None,
            Effect::LoadTransferRadius => self.load_transfer_radius = None,
            Effect::SpeedRadiusGrowth => self.speed_radius_growth = None,
            Effect::LongitudinalSlip => self.longitudinal_slip = None,
            Effect::TrackWidth => self.track_width = None,
            Effect::GyroBias => self.gyro_bias = None,
            Effect::GyroScale => self.gyro_scale = None,
            Effect::GnssLatency => self.gnss_latency = None,
            Effect::GnssLeverArm => self.gnss_lever_arm = None,
            Effect::RadiusDrift => self.radius_drift = None,
            Effect::RoadGrade => self.road_grade = None,
            Effect::HeadingBias => self.heading_bias = None,
        }
    }

    /// Switch `effect` on at its typical magnitude (if it was off; an effect
    /// already on keeps its parameters).
    pub fn switch_on(&mut self, effect: Effect) {
        if self.is_on(effect) {
            return;
        }
        match effect {
            Effect::SideSlip => self.side_slip = Some(SideSlip { k_beta: 0.0 }),
            Effect::LoadTransferRadius => {
                self.load_transfer_radius = Some(LoadTransferRadius { k_z: 0.0 })
            }
            Effect::SpeedRadiusGrowth => {
                self.speed_radius_growth = Some(SpeedRadiusGrowth { k_v: 0.0 })
            }
            Effect::LongitudinalSlip => {
                self.longitudinal_slip = Some(LongitudinalSlip { k_s: 0.0 })
            }
            Effect::TrackWidth => self.track_width = Some(TrackWidth { rel: 0.0 }),
            Effect::GyroBias => self.gyro_bias = Some(GyroBias { b_deg_h: 0.0 }),
            Effect::GyroScale => self.gyro_scale = Some(GyroScale { s: 0.0 }),
            Effect::GnssLatency => self.gnss_latency = Some(GnssLatency { tau_s: 0.0 }),
            Effect::GnssLeverArm => self.gnss_lever_arm = Some(GnssLeverArm { x_m: 0.0, y_m: 0.0 }),
            Effect::RadiusDrift => {
                self.radius_drift = Some(RadiusDrift {
                    d: 0.0,
                    time_constant_s: 0.0,
                })
            }
            Effect::RoadGrade => self.road_grade = Some(RoadGrade { grade: 0.0 }),
            Effect::HeadingBias => {
                self.heading_bias = Some(HeadingBias {
                    a_deg: 0.0,
                    b_deg: 0.0,
                    c_deg: 0.0,
                    d_deg: 0.0,
                    e_deg: 0.0,
                })
            }
        }
        for (p, v) in typical(effect) {
            self.write(p, v);
        }
    }

    /// One simulated parameter's slot, when its effect is on (`None` also
    /// for a parameter the simulator does not have, such as the model's
    /// grade gain).
    fn slot(&mut self, param: Param) -> Option<&mut f64> {
        Some(match param {
            Param::SideSlipGain => &mut self.side_slip.as_mut()?.k_beta,
            Param::LoadTransferGain => &mut self.load_transfer_radius.as_mut()?.k_z,
            Param::SpeedGrowthGain => &mut self.speed_radius_growth.as_mut()?.k_v,
            Param::LongitudinalSlipGain => &mut self.longitudinal_slip.as_mut()?.k_s,
            Param::TrackRel => &mut self.track_width.as_mut()?.rel,
            Param::GyroBias => &mut self.gyro_bias.as_mut()?.b_deg_h,
            Param::GyroScale => &mut self.gyro_scale.as_mut()?.s,
            Param::GnssLatency => &mut self.gnss_latency.as_mut()?.tau_s,
            Param::LeverArmX => &mut self.gnss_lever_arm.as_mut()?.x_m,
            Param::LeverArmY => &mut self.gnss_lever_arm.as_mut()?.y_m,
            Param::DriftFraction => &mut self.radius_drift.as_mut()?.d,
            Param::DriftTimeConstant => &mut self.radius_drift.as_mut()?.time_constant_s,
            Param::Grade => &mut self.road_grade.as_mut()?.grade,
            Param::HeadingA => &mut self.heading_bias.as_mut()?.a_deg,
            Param::HeadingB => &mut self.heading_bias.as_mut()?.b_deg,
            Param::HeadingC => &mut self.heading_bias.as_mut()?.c_deg,
            Param::HeadingD => &mut self.heading_bias.as_mut()?.d_deg,
            Param::HeadingE => &mut self.heading_bias.as_mut()?.e_deg,
            Param::GradeGain => return None,
        })
    }

    fn write(&mut self, param: Param, value: f64) {
        if let Some(slot) = self.slot(param) {
            *slot = value;
        }
    }

    /// One simulated parameter, in its reported unit, when its effect is on.
    pub fn get(&self, param: Param) -> Option<f64> {
        let mut copy = *self;
        copy.slot(param).map(|v| *v)
    }

    /// The simulated parameters of `effect` when it is on, the main one
    /// first.
    pub fn params(&self, effect: Effect) -> Option<Vec<(Param, f64)>> {
        effect
            .spec()
            .simulated
            .iter()
            .map(|&p| self.get(p).map(|v| (p, v)))
            .collect()
    }

    /// Every effect that is on with its parameters by name, keyed by
    /// catalogue id (the `[effects]` table of `truth.toml`).
    pub fn to_truth_map(&self) -> BTreeMap<String, BTreeMap<String, f64>> {
        Effect::ALL
            .into_iter()
            .filter_map(|e| {
                let params = self.params(e)?;
                let named = params
                    .into_iter()
                    .map(|(p, v)| (p.spec().name.to_string(), v))
                    .collect();
                Some((e.id().to_string(), named))
            })
            .collect()
    }

    /// Set one parameter of `effect` (switching it on at its typical values
    /// first if it was off). `param = None` sets the effect's main parameter.
    pub fn set(
        &mut self,
        effect: Effect,
        param: Option<Param>,
        value: f64,
    ) -> Result<(), SimError> {
        let name = param.map(|p| p.spec().name);
        let param = param.unwrap_or(effect.main_simulated());
        if !effect.spec().simulated.contains(&param) {
            return Err(self.unknown(effect, name, value, param.spec().name));
        }
        self.set_checked(effect, name, param, value)
    }

    fn invalid(effect: Effect, name: Option<&str>, value: f64, reason: String) -> SimError {
        SimError::InvalidEffect {
            spec: format!(
                "{}{}={value}",
                effect.id(),
                name.map(|p| format!(".{p}")).unwrap_or_default()
            ),
            reason,
        }
    }

    fn unknown(&self, effect: Effect, name: Option<&str>, value: f64, param: &str) -> SimError {
        let known: Vec<&str> = effect
            .spec()
            .simulated
            .iter()
            .map(|p| p.spec().name)
            .collect();
        if !value.is_finite() {
            return Self::invalid(
                effect,
                name,
                value,
                "the value is not a finite number".into(),
            );
        }
        Self::invalid(
            effect,
            name,
            value,
            format!("unknown parameter `{param}`; known: {}", known.join(", ")),
        )
    }

    /// Set a parameter named on the command line (`None`: the main one).
    fn set_named(
        &mut self,
        effect: Effect,
        name: Option<&str>,
        value: f64,
    ) -> Result<(), SimError> {
        let param = match name {
            None => effect.main_simulated(),
            Some(n) => match effect.simulated_param(n) {
                Some(p) => p,
                None => return Err(self.unknown(effect, name, value, n)),
            },
        };
        self.set_checked(effect, name, param, value)
    }

    /// Set a known simulated parameter of `effect`, within what the
    /// simulator accepts (an effect that was off is switched on first, and
    /// stays on if the value is refused).
    fn set_checked(
        &mut self,
        effect: Effect,
        name: Option<&str>,
        param: Param,
        value: f64,
    ) -> Result<(), SimError> {
        let bad = |reason: String| Self::invalid(effect, name, value, reason);
        if !value.is_finite() {
            return Err(bad("the value is not a finite number".into()));
        }
        let pname = param.spec().name;
        let non_negative = |v: f64| -> Result<f64, SimError> {
            if v < 0.0 {
                Err(bad(format!("`{pname}` must not be negative")))
            } else {
                Ok(v)
            }
        };
        self.switch_on(effect);
        let value = match param {
            Param::SideSlipGain | Param::LoadTransferGain | Param::LongitudinalSlipGain => {
                non_negative(value)?
            }
            Param::TrackRel if value <= -0.5 || value >= 0.5 => {
                return Err(bad(format!("`{pname}` must lie within (-0.5, 0.5)")));
            }
            Param::GyroScale if value <= -0.5 => {
                return Err(bad(format!("`{pname}` must be above -0.5")));
            }
            Param::GnssLatency => {
                let v = non_negative(value)?;
                if v > 5.0 {
                    return Err(bad(format!("`{pname}` above 5 s is not a latency")));
                }
                v
            }
            Param::DriftTimeConstant if value <= 0.0 => {
                return Err(bad(format!("`{pname}` must be positive")));
            }
            Param::Grade => {
                let v = non_negative(value)?;
                if v > 0.3 {
                    return Err(bad(format!("`{pname}` above 0.3 (30 %) is not a road")));
                }
                v
            }
            _ => value,
        };
        self.write(param, value);
        Ok(())
    }

    /// Apply one command-line spec: `ID=VALUE` (the main parameter),
    /// `ID.PARAM=VALUE`, `ID=on` (typical magnitude) or `ID=off`.
    /// A bare `ID=0` also switches the effect off.
    pub fn apply_spec(&mut self, spec: &str) -> Result<(), SimError> {
        let bad = |reason: &str| SimError::InvalidEffect {
            spec: spec.to_string(),
            reason: reason.to_string(),
        };
        let (key, value) = spec
            .split_once('=')
            .ok_or_else(|| bad("expected ID=VALUE or ID.PARAM=VALUE"))?;
        let (id, param) = match key.trim().split_once('.') {
            Some((id, p)) => (id.trim(), Some(p.trim())),
            None => (key.trim(), None),
        };
        let effect = Effect::from_id(id).ok_or_else(|| {
            let ids: Vec<&str> = Effect::ALL.iter().map(|e| e.id()).collect();
            SimError::InvalidEffect {
                spec: spec.to_string(),
                reason: format!("unknown effect id `{id}`; known: {}", ids.join(", ")),
            }
        })?;
        let value = value.trim();
        match (value, param) {
            ("off", None) => {
                self.switch_off(effect);
                Ok(())
            }
            ("on", None) => {
                self.switch_on(effect);
                Ok(())
            }
            _ => {
                let v: f64 = value
                    .parse()
                    .map_err(|_| bad("the value is not a number (nor on/off)"))?;
                if param.is_none() && v == 0.0 {
                    self.switch_off(effect);
                    Ok(())
                } else {
                    self.set_named(effect, param, v)
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_vehicle_physics() {
        let e = EffectSettings::default();
        let on: Vec<String> = e.to_truth_map().into_keys().collect();
        assert_eq!(
            on,
            ["load_transfer_radius", "longitudinal_slip", "side_slip"]
        );
        assert!(EffectSettings::none().to_truth_map().is_empty());
    }

    #[test]
    fn specs_set_switch_and_reject() {
        let mut e = EffectSettings::none();
        e.apply_spec("side_slip=0.006").unwrap();
        assert_eq!(e.side_slip, Some(SideSlip { k_beta: 0.006 }));
        e.apply_spec("gnss_lever_arm.y_m=0.3").unwrap();
        assert_eq!(e.gnss_lever_arm, Some(GnssLeverArm { x_m: 1.2, y_m: 0.3 }));
        e.apply_spec("gnss_latency=on").unwrap();
        assert_eq!(e.get(Param::GnssLatency).unwrap(), 0.08);
        e.apply_spec("side_slip=off").unwrap();
        e.apply_spec("gnss_latency=0").unwrap();
        assert!(!e.is_on(Effect::SideSlip) && !e.is_on(Effect::GnssLatency));
        for bad in [
            "warp=1",
            "side_slip",
            "side_slip=abc",
            "side_slip.k=1",
            "side_slip=-1",
            "gnss_latency=9",
        ] {
            let err = e.apply_spec(bad).unwrap_err().to_string();
            assert!(err.contains(bad.split('=').next().unwrap()), "{bad}: {err}");
        }
        let map = e.to_truth_map();
        assert_eq!(map["gnss_lever_arm"]["y_m"], 0.3);
    }

    #[test]
    fn every_effect_has_a_typical_magnitude() {
        for effect in Effect::ALL {
            let e = EffectSettings::only(effect);
            assert_eq!(e.to_truth_map().len(), 1, "{effect}");
            assert!(!typical(effect).is_empty());
        }
    }
}
