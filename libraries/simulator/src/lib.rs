//! The vehicle simulator: drives with their own truth, richer than the 2W model.
//!
//! A driver (pure pursuit on the path, a speed controller on a speed profile)
//! drives a nonlinear single-track vehicle (Magic-Formula tyres on each wheel
//! with their own vertical load, lateral and longitudinal load transfer,
//! quasi-static longitudinal slip on the driven axle) over a scenario's route.
//! Four wheels roll with their own effective circumference (wear, load,
//! speed, warm-up); sensors sample what a production car would measure.
//!
//! Every effect of the physics catalogue is a knob ([`EffectSettings`]); the
//! drive's `truth` is the rear-axle-centre pose at the wheel rate and its
//! `truth_params` the true circumferences, track, effects, seed and settings.
//!
//! ```no_run
//! use simulator::{simulate, Scenario, SimConfig};
//! let drive = simulate(&SimConfig::new(Scenario::Paper, 1)).unwrap();
//! assert!(drive.truth.is_some());
//! ```
//!
//! Determinism: the same configuration gives the same drive, bit for bit.
//! The vehicle's motion does not depend on the seed; each sensor draws its
//! noise from its own ChaCha8 stream of the seed, so switching one sensor or
//! effect leaves the others' noise unchanged.
//!
//! The integration runs at a fixed internal step ([`SimConfig::step_s`],
//! 1 ms by default); sensor rates must divide into it.

mod effects;
mod engine;
pub mod faults;
mod route;
mod scenarios;
mod sensors;
pub mod twin;
pub mod twin_noise;
mod vehicle;

pub use effects::{
    typical as typical_effect, EffectSettings, GnssLatency, GnssLeverArm, GyroBias, GyroScale,
    HeadingBias, LoadTransferRadius, LongitudinalSlip, RadiusDrift, RoadGrade, SideSlip,
    SpeedRadiusGrowth, TrackWidth,
};
pub use sensors::{
    GnssSettings, HeadingSettings, ImuSettings, SensorSettings, WheelEncoderSettings, SENSOR_KEYS,
};
pub use twin::{simulate_twin, TwinConfig, TwinOptions};
pub use vehicle::{VehicleKind, VehicleSpec};

use interfaces::drive::Drive;

/// Errors of the simulator.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// A scenario name that does not exist.
    #[error("unknown scenario `{0}`; known: paper, garage, mixed, long")]
    UnknownScenario(String),
    /// A vehicle name that does not exist.
    #[error("unknown vehicle `{0}`; known: compact, saloon, van")]
    UnknownVehicle(String),
    /// A bad `--effect` spec or effect value.
    #[error("effect `{spec}`: {reason}")]
    InvalidEffect {
        /// The spec as given.
        spec: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A bad `--sensor` spec.
    #[error("sensor setting `{spec}`: {reason}")]
    InvalidSensor {
        /// The spec as given.
        spec: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A configuration value out of range.
    #[error("invalid simulator configuration: {0}")]
    InvalidConfig(String),
    /// A scenario's route could not be built (a design error).
    #[error("scenario `{scenario}`: route: {reason}")]
    Route {
        /// The scenario.
        scenario: String,
        /// What went wrong.
        reason: String,
    },
    /// The vehicle state stopped being finite.
    #[error("numerical failure at t = {t_s:.3} s: {what}")]
    Numerical {
        /// Simulated time, s.
        t_s: f64,
        /// Which quantity.
        what: String,
    },
    /// The driver did not reach the end of the route in time.
    #[error("the vehicle did not finish scenario `{scenario}` within {limit_s} s (stuck at s = {s_m:.1} m)")]
    Stuck {
        /// The scenario.
        scenario: String,
        /// The time limit, s.
        limit_s: f64,
        /// Arc length reached, m.
        s_m: f64,
    },
}

/// A scenario: a route, how it is driven, and its default settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Scenario {
    /// Paper section 5: a closed 2.23 km course with 13 bends at 60 km/h, one
    /// lap from a flying start; initial circumference guess 2.2 m; white
    /// Gaussian sensor noise.
    Paper,
    /// Paper Fig. 1: a slow, tight parking-garage manoeuvre of about 540 m,
    /// GNSS denied after the first 50 m.
    Garage,
    /// City and highway loop of 9.2 km: stops, corners at several speeds,
    /// hard braking and acceleration, a tunnel, full heading coverage.
    Mixed,
    /// The mixed loop driven round and round; 1 h unless `duration_s` says otherwise.
    Long,
}

impl Scenario {
    /// Every scenario.
    pub const ALL: [Scenario; 4] = [
        Scenario::Paper,
        Scenario::Garage,
        Scenario::Mixed,
        Scenario::Long,
    ];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Scenario::Paper => "paper",
            Scenario::Garage => "garage",
            Scenario::Mixed => "mixed",
            Scenario::Long => "long",
        }
    }

    /// The scenario with this name.
    pub fn from_name(name: &str) -> Result<Scenario, SimError> {
        Scenario::ALL
            .into_iter()
            .find(|s| s.name() == name.trim().to_ascii_lowercase())
            .ok_or_else(|| SimError::UnknownScenario(name.to_string()))
    }
}

/// Tyre wear per wheel: tread depth lost, mm. A worn tyre's effective rolling
/// radius is smaller by this much, its circumference by 2 pi times it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WheelWear {
    /// Rear left, mm.
    pub rl: f64,
    /// Rear right, mm.
    pub rr: f64,
    /// Front left, mm.
    pub fl: f64,
    /// Front right, mm.
    pub fr: f64,
}

/// How the vehicle effects act in the engine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum EffectForms {
    /// Through the vehicle's physics: the load transfer through the
    /// suspension's lagged vertical loads, the longitudinal slip from the
    /// tyre force (resistance and drag included, softer on an unloaded
    /// wheel), the side-slip from load-sensitive, saturating tyres. A knob
    /// then shows in a diagnosis at a gain of its own and beside other
    /// effects (the slip of a driven axle under drag looks like a speed
    /// growth).
    #[default]
    Physical,
    /// Each effect exactly as the catalogue writes it
    /// (../shared/design/physics-catalogue.md), so that a knob means what a
    /// diagnosis's estimate means: the rear wheels' circumferences
    /// c (1 -/+ k_z a_y) at the body's lateral acceleration; the driven
    /// axle's wheel speed v (1 + k_s a_x); linear tyres of the stiffness
    /// the side-slip knob sets, at the static loads.
    Catalogue,
}

impl EffectForms {
    /// The name written to truth.toml (`effect_forms`) and read on the
    /// command line.
    pub fn name(self) -> &'static str {
        match self {
            EffectForms::Physical => "physical",
            EffectForms::Catalogue => "catalogue",
        }
    }

    /// The forms with this name.
    pub fn from_name(name: &str) -> Result<EffectForms, SimError> {
        match name.trim().to_ascii_lowercase().as_str() {
            "physical" => Ok(EffectForms::Physical),
            "catalogue" | "catalog" => Ok(EffectForms::Catalogue),
            other => Err(SimError::InvalidConfig(format!(
                "effect forms {other:?}: expected physical or catalogue"
            ))),
        }
    }
}

/// Everything a simulation needs.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// The route and driving.
    pub scenario: Scenario,
    /// Seed of all sensor noise (ChaCha8).
    pub seed: u64,
    /// Vehicle parameter set.
    pub vehicle: VehicleKind,
    /// Effect knobs.
    pub effects: EffectSettings,
    /// Sensor rates and noise.
    pub sensors: SensorSettings,
    /// Length of the drive, s. `None`: the scenario's default (one pass, or
    /// 1 h for `long`). Longer than the route: loops repeat, the garage
    /// drive stays parked at its end.
    pub duration_s: Option<f64>,
    /// Tyre wear per wheel (true circumference = unworn - 2 pi wear).
    pub wear_mm: WheelWear,
    /// Effective rolling circumference of an unworn tyre, m; `None` = the vehicle's.
    pub unworn_circumference_m: Option<f64>,
    /// The `nominal_circumference_m` written to vehicle.toml (the initial
    /// guess a calibrator starts from), m; `None` = the unworn circumference.
    pub nominal_circumference_m: Option<f64>,
    /// Internal integration step, s (1 ms).
    pub step_s: f64,
    /// How the vehicle effects act ([`EffectForms::Physical`] unless set).
    pub effect_forms: EffectForms,
    /// The wheels' speed reading beyond the catalogue (a comparison's
    /// measured map, `calibrator compare`): every wheel turns
    /// `1 / (1 + m(v, a_x))` times as fast. `None`: none.
    pub speed_map: Option<interfaces::speed_map::SpeedMap>,
    /// The wheels' yaw wander (a comparison's measure of it, `calibrator
    /// compare`): a Gauss-Markov yaw rate the rear wheels read beyond the
    /// body's. `None`: none.
    pub yaw_wander: Option<interfaces::yaw_wander::YawWander>,
}

impl SimConfig {
    /// The scenario's defaults:
    ///
    /// | scenario | vehicle | sensors | wear RL/RR/FL/FR mm | unworn c | nominal c |
    /// |---|---|---|---|---|---|
    /// | paper | saloon | [`SensorSettings::paper`] | 2.2/1.8/1.0/1.2 | 2.19 m | 2.2 m |
    /// | garage | saloon | default | 0/0/0/0 | vehicle's | = unworn |
    /// | mixed, long | saloon | default | 1.0/1.4/2.0/2.2 | vehicle's | = unworn |
    ///
    /// Effects: [`EffectSettings::default`] (vehicle physics on, the rest
    /// off); no duration (one pass; 1 h for `long`); 1 ms step.
    pub fn new(scenario: Scenario, seed: u64) -> SimConfig {
        let mut c = SimConfig {
            scenario,
            seed,
            vehicle: VehicleKind::Saloon,
            effects: EffectSettings::default(),
            sensors: SensorSettings::default(),
            duration_s: None,
            wear_mm: WheelWear::default(),
            unworn_circumference_m: None,
            nominal_circumference_m: None,
            step_s: 0.001,
            effect_forms: EffectForms::Physical,
            speed_map: None,
            yaw_wander: None,
        };
        match scenario {
            Scenario::Paper => {
                c.sensors = SensorSettings::paper();
                c.wear_mm = WheelWear {
                    rl: 2.2,
                    rr: 1.8,
                    fl: 1.0,
                    fr: 1.2,
                };
                c.unworn_circumference_m = Some(2.19);
                c.nominal_circumference_m = Some(2.2);
            }
            Scenario::Garage => {}
            Scenario::Mixed | Scenario::Long => {
                c.wear_mm = WheelWear {
                    rl: 1.0,
                    rr: 1.4,
                    fl: 2.0,
                    fr: 2.2,
                };
            }
        }
        c
    }

    /// The effective rolling circumference of an unworn tyre, m.
    pub fn unworn_circumference(&self) -> f64 {
        self.unworn_circumference_m
            .unwrap_or_else(|| self.vehicle.spec().unworn_circumference_m)
    }

    /// The true static circumference of each wheel (unworn minus 2 pi wear).
    pub fn true_circumferences(&self) -> interfaces::drive::WheelCircumferences {
        let c0 = self.unworn_circumference();
        let worn = |mm: f64| c0 - std::f64::consts::TAU * mm / 1000.0;
        interfaces::drive::WheelCircumferences {
            rl: worn(self.wear_mm.rl),
            rr: worn(self.wear_mm.rr),
            fl: worn(self.wear_mm.fl),
            fr: worn(self.wear_mm.fr),
        }
    }

    /// The nominal circumference written to vehicle.toml, m.
    pub fn nominal_circumference(&self) -> f64 {
        self.nominal_circumference_m
            .unwrap_or_else(|| self.unworn_circumference())
    }

    /// The true effective rear track, m.
    pub fn true_track_width(&self) -> f64 {
        let nominal = self.vehicle.spec().track_rear_m;
        self.effects
            .track_width
            .map_or(nominal, |t| nominal * (1.0 + t.rel))
    }
}

/// Simulate one drive: wheels, GNSS, IMU, heading, truth and truth parameters.
pub fn simulate(config: &SimConfig) -> Result<Drive, SimError> {
    engine::run(config)
}
