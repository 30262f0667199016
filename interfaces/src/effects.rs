//! The physics the two-wheel (2W) model leaves out: one typed table.
//!
//! Every fact about an effect of `shared/design/physics-catalogue.md` lives
//! in [`EFFECTS`] (one [`EffectSpec`] per [`Effect`], in catalogue order) and
//! [`PARAMS`] (one [`ParamSpec`] per [`Param`]): its id (reports, JSON,
//! `truth.toml`), its wire code, its parameters as typed ids with their
//! names, units, display scale, typical size and plausible range, how an
//! estimate carries it, the signal that gives it away, what a drive needs to
//! show it and the manoeuvre that separates it from the effects it is
//! confused with. The simulator, the effect-aware model
//! (`vehicle_model::effects`), the diagnosis, the wire, the report and the
//! diagnosis suite read it; none of them names a parameter by a string.
//!
//! Adding an effect: a variant of [`Effect`] (and of [`Param`] for each of
//! its parameters), one entry in [`EFFECTS`] and in [`PARAMS`], and its
//! model terms (the effect-aware model and the simulator); see
//! `docs/design/effects.md`.

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// One effect of the physics catalogue.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    /// Side-slip angle proportional to lateral acceleration.
    SideSlip,
    /// Effective radius changes with vertical load in corners.
    LoadTransferRadius,
    /// Tyre radius grows with speed (centrifugal growth).
    SpeedRadiusGrowth,
    /// Longitudinal slip of the driven axle under acceleration.
    LongitudinalSlip,
    /// Effective rear track differs from the nominal.
    TrackWidth,
    /// Constant yaw-rate gyro bias.
    GyroBias,
    /// Yaw-rate gyro scale factor error.
    GyroScale,
    /// GNSS fixes stamped late.
    GnssLatency,
    /// GNSS antenna away from the rear-axle centre.
    GnssLeverArm,
    /// Tyre radius drifting with time (warm-up, pressure).
    RadiusDrift,
    /// Wheels measure along the slope, GNSS the horizontal.
    RoadGrade,
    /// Magnetometer heading error periodic in heading.
    HeadingBias,
}

/// One parameter of one effect: a typed id (never a string key).
///
/// The model value of a parameter is in SI units (what the effect-aware
/// model and the diagnosis's fit hold); its reported value, in
/// [`ParamSpec::unit`], is [`ParamSpec::display_scale`] times that.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Param {
    /// `side_slip` k_beta.
    SideSlipGain,
    /// `load_transfer_radius` k_z.
    LoadTransferGain,
    /// `speed_radius_growth` k_v.
    SpeedGrowthGain,
    /// `longitudinal_slip` k_s.
    LongitudinalSlipGain,
    /// `track_width` rel.
    TrackRel,
    /// `gyro_bias` b.
    GyroBias,
    /// `gyro_scale` s.
    GyroScale,
    /// `gnss_latency` tau.
    GnssLatency,
    /// `gnss_lever_arm` x (forward).
    LeverArmX,
    /// `gnss_lever_arm` y (left).
    LeverArmY,
    /// `radius_drift` d.
    DriftFraction,
    /// `radius_drift` T.
    DriftTimeConstant,
    /// `road_grade`: the simulated road's largest grade.
    Grade,
    /// `road_grade`: the model's gain on the IMU's grade.
    GradeGain,
    /// `heading_bias` A (constant).
    HeadingA,
    /// `heading_bias` B (times sin psi).
    HeadingB,
    /// `heading_bias` C (times cos psi).
    HeadingC,
    /// `heading_bias` D (soft iron, times sin 2 psi; simulated only).
    HeadingD,
    /// `heading_bias` E (soft iron, times cos 2 psi; simulated only).
    HeadingE,
}

/// How an estimate carries an effect's terms to the odometry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Carried {
    /// A wheel-side term: a [`crate::wire::ModelExtension`] with the
    /// effect's [`Effect::code`] and its [`EffectSpec::model`] parameters
    /// in order.
    Extension,
    /// The antenna position: its own extension, written by the estimate.
    Antenna,
    /// The estimate's own fields (the gyro terms).
    EstimateField,
    /// Not carried: the terms stay with the diagnosis.
    DiagnosisOnly,
}

/// Whose an effect is: what several drives of one car share.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Scope {
    /// The car's: its tyres, geometry and sensors' mounting, the same on
    /// every drive of the car (side-slip, load transfer, track, antenna,
    /// latency, gyro scale, compass).
    Car,
    /// The drive's: a term of the day (the gyro's bias after power-up,
    /// the tyres' warm-up, the road's grade).
    Drive,
}

/// Everything about one parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamSpec {
    /// The typed id.
    pub param: Param,
    /// The effect it belongs to.
    pub effect: Effect,
    /// Its name in reports, JSON, `truth.toml` and `--effect ID.NAME=VALUE`.
    pub name: &'static str,
    /// The unit of the reported (and simulated) value.
    pub unit: &'static str,
    /// The name of the model (SI) coefficient, where the diagnosis speaks of
    /// the coefficient it fits (`b` for a gyro bias in rad/s).
    pub model_name: &'static str,
    /// The unit of the model coefficient.
    pub model_unit: &'static str,
    /// Reported value = `display_scale` * model value.
    pub display_scale: f64,
    /// The catalogue's typical size, in model units: what the detectable
    /// size a drive reports is compared with.
    pub typical: f64,
    /// The simulator's default when the effect is switched on, in the
    /// reported unit (`truth.toml`'s value).
    pub simulated: f64,
    /// The smallest and largest model value a passenger car plausibly has
    /// (the catalogue's typical size with a wide margin: other cars differ).
    pub plausible: (f64, f64),
}

/// Everything about one effect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffectSpec {
    /// The effect.
    pub effect: Effect,
    /// The catalogue id (`side_slip`).
    pub id: &'static str,
    /// The wire code (1-based; 0 means "no effect").
    pub code: u32,
    /// The extended model, in a line.
    pub form: &'static str,
    /// The simulator's parameters, the main one (a bare `ID=VALUE`) first.
    pub simulated: &'static [Param],
    /// The effect-aware model's parameters, in the order of the wire
    /// extension.
    pub model: &'static [Param],
    /// The coefficients the diagnosis fits, the main one first (a subset
    /// of [`EffectSpec::model`]; the rest come from the fit's variant).
    pub fitted: &'static [Param],
    /// How an estimate carries it.
    pub carried: Carried,
    /// Whether it belongs to the car (the same on every drive) or to the
    /// drive (a term of the day).
    pub scope: Scope,
    /// The signal that gives it away, briefly.
    pub fingerprint: &'static str,
    /// What a drive needs to show it.
    pub needs: &'static str,
    /// Effects it is confused with and the manoeuvre that separates them
    /// (each pair listed once, on either effect).
    pub partners: &'static [(Effect, &'static str)],
}

impl Effect {
    /// Every effect, in catalogue order.
    pub const ALL: [Effect; 12] = [
        Effect::SideSlip,
        Effect::LoadTransferRadius,
        Effect::SpeedRadiusGrowth,
        Effect::LongitudinalSlip,
        Effect::TrackWidth,
        Effect::GyroBias,
        Effect::GyroScale,
        Effect::GnssLatency,
        Effect::GnssLeverArm,
        Effect::RadiusDrift,
        Effect::RoadGrade,
        Effect::HeadingBias,
    ];

    /// Its entry of [`EFFECTS`].
    pub fn spec(self) -> &'static EffectSpec {
        &EFFECTS[self as usize]
    }

    /// The catalogue id, e.g. `"side_slip"`.
    pub fn id(self) -> &'static str {
        self.spec().id
    }

    /// The effect with this catalogue id.
    pub fn from_id(id: &str) -> Option<Effect> {
        Effect::ALL.into_iter().find(|e| e.id() == id)
    }

    /// Numeric code used on the wire (1-based; 0 means "no effect").
    pub fn code(self) -> u32 {
        self.spec().code
    }

    /// The effect with this wire code.
    pub fn from_code(code: u32) -> Option<Effect> {
        Effect::ALL
            .into_iter()
            .find(|e| code != 0 && e.code() == code)
    }

    /// The main parameter the diagnosis fits and reports (its detectable
    /// size is given in it).
    pub fn main_fitted(self) -> Param {
        self.spec().fitted[0]
    }

    /// Whether the physics fixes the sign of the effect's main fitted
    /// parameter: its plausible range starts at zero or above (a rear
    /// axle's side-slip points out of the turn, the outer wheel is the
    /// loaded one, a fix is stamped after it was taken). A fit that puts it
    /// below zero says the data holds none of it.
    pub fn sign_known(self) -> bool {
        self.main_fitted().spec().plausible.0 >= 0.0
    }

    /// The simulator's main parameter (what a bare `ID=VALUE` sets).
    pub fn main_simulated(self) -> Param {
        self.spec().simulated[0]
    }

    /// The simulator's parameter of this effect named `name`.
    pub fn simulated_param(self, name: &str) -> Option<Param> {
        self.spec()
            .simulated
            .iter()
            .copied()
            .find(|p| p.spec().name == name)
    }

    /// The catalogue's manoeuvre that tells `self` and `other` apart, where
    /// either lists the other among its partners (the effects it is
    /// confusable with); `None` for a pair the catalogue does not list.
    pub fn partner_manoeuvre(self, other: Effect) -> Option<&'static str> {
        let listed = |a: Effect, b: Effect| {
            a.spec()
                .partners
                .iter()
                .find(|(p, _)| *p == b)
                .map(|(_, how)| *how)
        };
        listed(self, other).or_else(|| listed(other, self))
    }

    /// How to tell `self` and `other` apart: the catalogue's manoeuvre for
    /// a known pair, otherwise more of what each needs.
    pub fn separate_from(self, other: Effect) -> String {
        match self.partner_manoeuvre(other) {
            Some(how) => how.to_string(),
            None => format!(
                "a drive with more of: {}; and {}",
                self.spec().needs,
                other.spec().needs
            ),
        }
    }
}

impl Param {
    /// Its entry of [`PARAMS`].
    pub fn spec(self) -> &'static ParamSpec {
        &PARAMS[self as usize]
    }

    /// A model (SI) value in the reported unit.
    pub fn to_display(self, model_value: f64) -> f64 {
        model_value * self.spec().display_scale
    }
}

/// 180 / pi: radians to degrees (as `f64::to_degrees`).
const DEG_PER_RAD: f64 = 180.0 / PI;
/// rad/s to deg/h.
const DEG_H_PER_RAD_S: f64 = 180.0 / PI * 3600.0;

/// A parameter whose reported and model values agree (scale 1, the same
/// name and unit).
const fn si(
    param: Param,
    effect: Effect,
    name: &'static str,
    unit: &'static str,
    typical: f64,
    simulated: f64,
    plausible: (f64, f64),
) -> ParamSpec {
    ParamSpec {
        param,
        effect,
        name,
        unit,
        model_name: name,
        model_unit: unit,
        display_scale: 1.0,
        typical,
        simulated,
        plausible,
    }
}

/// A heading-bias term: reported in degrees, fitted in radians.
const fn heading(
    param: Param,
    name: &'static str,
    model_name: &'static str,
    simulated: f64,
) -> ParamSpec {
    ParamSpec {
        param,
        effect: Effect::HeadingBias,
        name,
        unit: "deg",
        model_name,
        model_unit: "rad",
        display_scale: DEG_PER_RAD,
        // 2 degrees.
        typical: 2.0_f64.to_radians(),
        simulated,
        plausible: (-0.5, 0.5),
    }
}

/// Every parameter, in the order of [`Param`].
pub const PARAMS: [ParamSpec; 19] = [
    si(
        Param::SideSlipGain,
        Effect::SideSlip,
        "k_beta",
        "rad/(m/s^2)",
        0.004,
        0.004,
        (0.0, 0.02),
    ),
    // The catalogue gives "up to ~1e-3".
    si(
        Param::LoadTransferGain,
        Effect::LoadTransferRadius,
        "k_z",
        "1/(m/s^2)",
        2e-4,
        5e-5,
        (0.0, 5e-3),
    ),
    // 0.2 % at 30 m/s.
    si(
        Param::SpeedGrowthGain,
        Effect::SpeedRadiusGrowth,
        "k_v",
        "1/(m/s)^2",
        0.002 / 900.0,
        2.5e-6,
        (0.0, 2e-5),
    ),
    // 0.75 % at 3 m/s^2.
    si(
        Param::LongitudinalSlipGain,
        Effect::LongitudinalSlip,
        "k_s",
        "1/(m/s^2)",
        0.0025,
        0.002,
        (0.0, 0.05),
    ),
    si(
        Param::TrackRel,
        Effect::TrackWidth,
        "rel",
        "1",
        0.02,
        0.02,
        (-0.15, 0.15),
    ),
    ParamSpec {
        param: Param::GyroBias,
        effect: Effect::GyroBias,
        name: "b_deg_h",
        unit: "deg/h",
        model_name: "b",
        model_unit: "rad/s",
        display_scale: DEG_H_PER_RAD_S,
        // 100 deg/h.
        typical: 100.0_f64.to_radians() / 3600.0,
        simulated: 200.0,
        plausible: (-0.05, 0.05),
    },
    si(
        Param::GyroScale,
        Effect::GyroScale,
        "s",
        "1",
        0.005,
        0.005,
        (-0.05, 0.05),
    ),
    si(
        Param::GnssLatency,
        Effect::GnssLatency,
        "tau_s",
        "s",
        0.08,
        0.08,
        (0.0, 1.0),
    ),
    si(
        Param::LeverArmX,
        Effect::GnssLeverArm,
        "x_m",
        "m",
        0.5,
        1.2,
        (-5.0, 5.0),
    ),
    si(
        Param::LeverArmY,
        Effect::GnssLeverArm,
        "y_m",
        "m",
        0.5,
        0.0,
        (-3.0, 3.0),
    ),
    si(
        Param::DriftFraction,
        Effect::RadiusDrift,
        "d",
        "1",
        0.003,
        0.003,
        (-0.03, 0.03),
    ),
    // The model's time constant when a fit does not say (the diagnosis
    // tries a grid of them).
    si(
        Param::DriftTimeConstant,
        Effect::RadiusDrift,
        "time_constant_s",
        "s",
        600.0,
        600.0,
        (0.0, f64::INFINITY),
    ),
    // The simulated road's largest grade (rise over run): open roads get
    // rolling hills of this amplitude, the garage's ramps this grade.
    si(
        Param::Grade,
        Effect::RoadGrade,
        "grade",
        "1",
        0.06,
        0.06,
        (0.0, 0.3),
    ),
    // The gain on the measured slope, 1 when the slope acts as it is (its
    // size on a drive is the drive's slopes); plausible from sqrt(0.1) to
    // sqrt(10) (the diagnosis fits its square, from 0.1 to 10).
    si(
        Param::GradeGain,
        Effect::RoadGrade,
        "gain",
        "1",
        1.0,
        1.0,
        (0.316_227_766_016_837_94, 3.162_277_660_168_379_5),
    ),
    heading(Param::HeadingA, "a_deg", "a_rad", 0.0),
    heading(Param::HeadingB, "b_deg", "b_rad", 3.0),
    heading(Param::HeadingC, "c_deg", "c_rad", 0.0),
    heading(Param::HeadingD, "d_deg", "d_rad", 0.0),
    heading(Param::HeadingE, "e_deg", "e_rad", 0.0),
];

/// Every effect, in catalogue order (the order of [`Effect::ALL`]).
pub const EFFECTS: [EffectSpec; 12] = [
    EffectSpec {
        effect: Effect::SideSlip,
        id: "side_slip",
        code: 1,
        form: "beta = -k_beta a_y in eq. (1)",
        simulated: &[Param::SideSlipGain],
        model: &[Param::SideSlipGain],
        fitted: &[Param::SideSlipGain],
        carried: Carried::Extension,
        scope: Scope::Car,
        fingerprint: "course offset proportional to v w, outward of the turn",
        needs: "corners at several speeds (lateral acceleration of 2 m/s^2 or more)",
        partners: &[
            (
                Effect::GnssLeverArm,
                "corners taken at clearly different speeds: side-slip grows with v w, the lever arm's course offset with w / v",
            ),
            (Effect::GnssLatency, SEPARATE_LATENCY),
        ],
    },
    EffectSpec {
        effect: Effect::LoadTransferRadius,
        id: "load_transfer_radius",
        code: 2,
        form: "c_RL,RR = c (1 +/- k_z a_y): the outer wheel rolls on a smaller radius",
        simulated: &[Param::LoadTransferGain],
        model: &[Param::LoadTransferGain],
        fitted: &[Param::LoadTransferGain],
        carried: Carried::Extension,
        scope: Scope::Car,
        fingerprint: "heading error growing with v^2 w",
        needs: "corners at several speeds",
        partners: &[(
            Effect::TrackWidth,
            "the same corners driven slowly and fast: load transfer grows with v^2 w, the track error with w only",
        )],
    },
    EffectSpec {
        effect: Effect::SpeedRadiusGrowth,
        id: "speed_radius_growth",
        code: 3,
        form: "c = c0 (1 + k_v v^2)",
        simulated: &[Param::SpeedGrowthGain],
        model: &[Param::SpeedGrowthGain],
        fitted: &[Param::SpeedGrowthGain],
        carried: Carried::Extension,
        scope: Scope::Car,
        fingerprint: "speed ratio growing with v^2, on straights too",
        needs: "driving at several speeds, up to 25 m/s or more",
        partners: &[
            (
                Effect::RadiusDrift,
                "a drive whose speed does not follow the time: high and low speed both early and late",
            ),
            (Effect::RoadGrade, "slopes driven at several speeds"),
        ],
    },
    EffectSpec {
        effect: Effect::LongitudinalSlip,
        id: "longitudinal_slip",
        code: 4,
        form: "the wheels turn as if the car went v (1 + k_s a_x)",
        simulated: &[Param::LongitudinalSlipGain],
        model: &[Param::LongitudinalSlipGain],
        fitted: &[Param::LongitudinalSlipGain],
        carried: Carried::Extension,
        scope: Scope::Car,
        fingerprint: "speed ratio proportional to a_x",
        needs: "hard acceleration and braking",
        partners: &[(
            Effect::GnssLatency,
            "corners (latency moves the course, slip does not) and acceleration at several speeds",
        )],
    },
    EffectSpec {
        effect: Effect::TrackWidth,
        id: "track_width",
        code: 5,
        form: "the effective track is nominal (1 + rel)",
        simulated: &[Param::TrackRel],
        model: &[Param::TrackRel],
        fitted: &[Param::TrackRel],
        carried: Carried::Extension,
        scope: Scope::Car,
        fingerprint: "heading error proportional to the heading change",
        needs: "turns, a few hundred degrees of heading change",
        partners: &[(Effect::GyroScale, "full loops with GNSS course (absolute heading)")],
    },
    EffectSpec {
        effect: Effect::GyroBias,
        id: "gyro_bias",
        code: 6,
        form: "w_gyro = w + b",
        simulated: &[Param::GyroBias],
        model: &[Param::GyroBias],
        fitted: &[Param::GyroBias],
        carried: Carried::EstimateField,
        scope: Scope::Drive,
        fingerprint: "gyro heading drifting with time; rate at standstill",
        needs: "a standstill, or a long drive with GNSS course",
        partners: &[],
    },
    EffectSpec {
        effect: Effect::GyroScale,
        id: "gyro_scale",
        code: 7,
        form: "w_gyro = (1 + s) w",
        simulated: &[Param::GyroScale],
        model: &[Param::GyroScale],
        fitted: &[Param::GyroScale],
        carried: Carried::EstimateField,
        scope: Scope::Car,
        fingerprint: "gyro heading error proportional to the heading change",
        needs: "turns, a few hundred degrees of heading change",
        partners: &[],
    },
    EffectSpec {
        effect: Effect::GnssLatency,
        id: "gnss_latency",
        code: 8,
        form: "a fix stamped t is the antenna position at t - tau",
        simulated: &[Param::GnssLatency],
        model: &[Param::GnssLatency],
        fitted: &[Param::GnssLatency],
        carried: Carried::DiagnosisOnly,
        scope: Scope::Car,
        fingerprint: "speed error ~ tau a_x and course lag ~ tau w at once",
        needs: "acceleration and braking, and corners",
        partners: &[(Effect::GnssLeverArm, SEPARATE_LATENCY)],
    },
    EffectSpec {
        effect: Effect::GnssLeverArm,
        id: "gnss_lever_arm",
        code: 9,
        form: "p_antenna = p + R(theta) (x, y)",
        simulated: &[Param::LeverArmX, Param::LeverArmY],
        model: &[Param::LeverArmX, Param::LeverArmY],
        fitted: &[Param::LeverArmX, Param::LeverArmY],
        carried: Carried::Antenna,
        scope: Scope::Car,
        fingerprint: "course offset ~ l_x w / v, speed ~ l_y w / v",
        needs: "corners at several speeds",
        partners: &[],
    },
    EffectSpec {
        effect: Effect::RadiusDrift,
        id: "radius_drift",
        code: 10,
        form: "c(t) = c0 (1 + d (1 - exp(-t / T))), t from the drive's start",
        simulated: &[Param::DriftFraction, Param::DriftTimeConstant],
        model: &[Param::DriftFraction, Param::DriftTimeConstant],
        fitted: &[Param::DriftFraction],
        carried: Carried::Extension,
        scope: Scope::Drive,
        fingerprint: "speed ratio trending with time since the start",
        needs: "a drive of 20 minutes or more",
        partners: &[],
    },
    EffectSpec {
        effect: Effect::RoadGrade,
        id: "road_grade",
        code: 11,
        form: "ds_horizontal = ds_wheel cos(atan(gain grade)), grade from the IMU's pitch",
        simulated: &[Param::Grade],
        model: &[Param::GradeGain],
        fitted: &[Param::GradeGain],
        carried: Carried::DiagnosisOnly,
        scope: Scope::Drive,
        fingerprint: "speed ratio following the squared IMU grade",
        needs: "slopes and a forward accelerometer",
        partners: &[],
    },
    EffectSpec {
        effect: Effect::HeadingBias,
        id: "heading_bias",
        code: 12,
        form: "heading error A + B sin(psi) + C cos(psi) (+ D sin(2 psi) + E cos(2 psi) simulated)",
        simulated: &[
            Param::HeadingB,
            Param::HeadingA,
            Param::HeadingC,
            Param::HeadingD,
            Param::HeadingE,
        ],
        model: &[Param::HeadingA, Param::HeadingB, Param::HeadingC],
        fitted: &[Param::HeadingA, Param::HeadingB, Param::HeadingC],
        carried: Carried::DiagnosisOnly,
        scope: Scope::Car,
        fingerprint: "heading residual periodic in heading",
        needs: "an absolute heading sensor and full heading coverage",
        partners: &[],
    },
];

/// How latency is told from side-slip and from the antenna.
const SEPARATE_LATENCY: &str = "corners at several speeds and hard acceleration or braking on a straight: only latency shows in the speed then";

/// Wire code of the GNSS clock model extension (not a physics-catalogue
/// effect: codes from 101 on are sensor clocks, outside the catalogue's
/// 1..=12, so [`Effect::from_code`] knows none of them). Parameters: the
/// GNSS stamps' offset against the wheels' (late, s), its drift (ppm) and
/// the wheel time the offset holds at (s); `param_count` 3.
pub const GNSS_CLOCK_EXTENSION: u32 = 101;
/// Wire code of the IMU clock model extension: as
/// [`GNSS_CLOCK_EXTENSION`], for the IMU's stamps.
pub const IMU_CLOCK_EXTENSION: u32 = 102;

impl std::fmt::Display for Effect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.id())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_codes_and_serde_names_agree() {
        for e in Effect::ALL {
            assert_eq!(Effect::from_id(e.id()), Some(e));
            assert_eq!(Effect::from_code(e.code()), Some(e));
            assert_eq!(
                serde_json::to_string(&e).unwrap(),
                format!("\"{}\"", e.id())
            );
        }
        assert_eq!(Effect::from_code(0), None);
        for code in [GNSS_CLOCK_EXTENSION, IMU_CLOCK_EXTENSION] {
            assert_eq!(Effect::from_code(code), None, "a clock is not an effect");
        }
        assert_eq!(Effect::from_id("flux_capacitor"), None);
    }

    #[test]
    fn the_signs_the_physics_fixes_are_the_catalogues() {
        // Side-slip out of the turn, the loaded outer wheel, the tyre's
        // growth with speed, the slip of a driven or braked wheel, a fix
        // stamped after it was taken, a slope's squared gain: never below
        // zero. The rest may take either sign.
        let signed: Vec<Effect> = Effect::ALL.into_iter().filter(|e| e.sign_known()).collect();
        assert_eq!(
            signed,
            vec![
                Effect::SideSlip,
                Effect::LoadTransferRadius,
                Effect::SpeedRadiusGrowth,
                Effect::LongitudinalSlip,
                Effect::GnssLatency,
                Effect::RoadGrade,
            ]
        );
    }

    #[test]
    fn the_tables_are_in_order_and_consistent() {
        for (i, e) in Effect::ALL.into_iter().enumerate() {
            let s = e.spec();
            assert_eq!(s.effect, e);
            // The wire codes are 1-based catalogue positions.
            assert_eq!(s.code as usize, i + 1);
            assert!(!s.simulated.is_empty() && !s.model.is_empty() && !s.fitted.is_empty());
            for p in s.simulated.iter().chain(s.model).chain(s.fitted) {
                assert_eq!(p.spec().effect, e, "{p:?}");
            }
            for p in s.fitted {
                assert!(s.model.contains(p), "{p:?}");
            }
            assert!(s.model.len() <= crate::wire::MAX_EXTENSION_PARAMS);
            for (other, _) in s.partners {
                assert_ne!(*other, e);
            }
        }
        for (i, p) in PARAMS.iter().enumerate() {
            assert_eq!(p.param as usize, i, "{p:?}");
            assert!(p.plausible.0 < p.plausible.1, "{p:?}");
            let s = p.effect.spec();
            assert!(
                s.simulated.contains(&p.param) || s.model.contains(&p.param),
                "{p:?} belongs to no list of its effect"
            );
        }
        assert_eq!(
            Effect::RoadGrade.simulated_param("grade"),
            Some(Param::Grade)
        );
        assert_eq!(Effect::RoadGrade.simulated_param("gain"), None);
        assert_eq!(
            Param::GyroBias.to_display(1e-4),
            1e-4 * (180.0 / PI * 3600.0)
        );
        assert_eq!(Param::HeadingB.to_display(0.1), 0.1_f64.to_degrees());
    }
}
