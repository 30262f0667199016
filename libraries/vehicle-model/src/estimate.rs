//! Odometry parameters and where they come from.
//!
//! Three sources give the same [`OdometryParams`]:
//! - the nominal values of `vehicle.toml` ([`OdometryParams::nominal`]): both
//!   rear circumferences equal to `nominal_circumference_m`, the given track,
//!   an ideal gyro;
//! - the JSON that `calibrator calibrate --json` writes, the estimate file
//!   ([`crate::estimate_file::EstimateFile`], [`Estimate::from_json_str`]; `drive_io::read_estimate`
//!   reads the file): `circumference_m.{rl,rr}`, `track_width_m`, and when
//!   the calibrator estimated them `gyro_bias_rad_s` and `gyro_scale`; the
//!   fields the odometry does not use are carried, not read;
//! - the wire type [`CircumferenceEstimate`] ([`Estimate::from_wire`],
//!   [`Estimate::to_wire`]); the calibrated GNSS antenna position travels in
//!   it as a `gnss_lever_arm` model extension (x, y), the sensor clocks as
//!   clock extensions (offset, drift, reference time; [`StreamClocks`]).
//!
//! Gyro convention (the same as the wire type): the gyro measures
//! `gz = (1 + gyro_scale) * w + gyro_bias_rad_s`, so the corrected yaw rate is
//! `w = (gz - gyro_bias_rad_s) / (1 + gyro_scale)`.

use crate::effects::{EffectTerms, WheelEffects};
use crate::two_wheel::TwoWheelParams;
use interfaces::drive::VehicleParams;
use interfaces::effects::{Effect, GNSS_CLOCK_EXTENSION, IMU_CLOCK_EXTENSION};
use interfaces::wire::{CircumferenceEstimate, Header, ModelExtension};
use std::path::PathBuf;

/// Everything the dead-reckoner needs to turn wheel revolutions and gyro
/// readings into motion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryParams {
    /// Rear circumferences and effective track of the 2W model.
    pub two_wheel: TwoWheelParams,
    /// Yaw-rate gyro bias, rad/s (subtracted from the measurement).
    pub gyro_bias_rad_s: f64,
    /// Yaw-rate gyro scale error s in `gz = (1 + s) w + bias`.
    pub gyro_scale: f64,
}

impl OdometryParams {
    /// The values a user starts from: `vehicle.toml`'s nominal circumference on
    /// both rear wheels, its track width, and a gyro taken as ideal.
    pub fn nominal(vehicle: &VehicleParams) -> OdometryParams {
        OdometryParams {
            two_wheel: TwoWheelParams {
                c_rl: vehicle.nominal_circumference_m,
                c_rr: vehicle.nominal_circumference_m,
                track_width: vehicle.track_width_m,
            },
            gyro_bias_rad_s: 0.0,
            gyro_scale: 0.0,
        }
    }

    /// The yaw rate, rad/s, that a raw gyro reading stands for.
    pub fn corrected_yaw_rate(&self, gz_rad_s: f64) -> f64 {
        (gz_rad_s - self.gyro_bias_rad_s) / (1.0 + self.gyro_scale)
    }

    /// Check that every value is usable; `source` names where they came from.
    pub fn validate(&self, source: &str) -> Result<(), ParamsError> {
        let positive = |field: &'static str, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(ParamsError::Invalid {
                    source_name: source.to_string(),
                    field,
                    value,
                    reason: "must be a positive finite number",
                })
            }
        };
        positive("circumference_m.rl", self.two_wheel.c_rl)?;
        positive("circumference_m.rr", self.two_wheel.c_rr)?;
        positive("track_width_m", self.two_wheel.track_width)?;
        if !self.gyro_bias_rad_s.is_finite() {
            return Err(ParamsError::Invalid {
                source_name: source.to_string(),
                field: "gyro_bias_rad_s",
                value: self.gyro_bias_rad_s,
                reason: "must be finite",
            });
        }
        // A scale error beyond +-50 % is a broken gyro or a unit mix-up.
        if !(self.gyro_scale.is_finite() && self.gyro_scale.abs() < 0.5) {
            return Err(ParamsError::Invalid {
                source_name: source.to_string(),
                field: "gyro_scale",
                value: self.gyro_scale,
                reason: "must be finite and within (-0.5, 0.5)",
            });
        }
        Ok(())
    }
}

impl std::fmt::Display for OdometryParams {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "c_rl={:.5} m c_rr={:.5} m track={:.4} m gyro_bias={:.6} rad/s gyro_scale={:.5}",
            self.two_wheel.c_rl,
            self.two_wheel.c_rr,
            self.two_wheel.track_width,
            self.gyro_bias_rad_s,
            self.gyro_scale
        )
    }
}

/// A calibration result: the parameters plus what is known about their quality.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// The parameters.
    pub params: OdometryParams,
    /// 1-sigma of the rear-left and rear-right circumferences, m, when known.
    pub sigma_m: Option<(f64, f64)>,
    /// Mean dead-reckoning error on held-out data, m, when known.
    pub quality_m: Option<f64>,
    /// GNSS antenna position the calibration found (body x forward, y left,
    /// from the rear-axle centre), m, when it has one: `gyro.antenna_m`, else
    /// `gnss_antenna_m` of the calibrator's JSON.
    pub antenna_m: Option<[f64; 2]>,
    /// Its 1-sigma (x, y), m, when given (`gyro.sigma_antenna_m`, else
    /// `sigma_gnss_antenna_m`).
    pub antenna_sigma_m: Option<[f64; 2]>,
    /// The effect terms a diagnosis found (`effects` in the JSON, effect
    /// model extensions on the wire); all zero: the plain 2W model.
    pub effects: WheelEffects,
    /// The sensor clock offsets and drifts the calibration found and applied
    /// (`clock_offsets` in the JSON; on the wire the clock model extensions,
    /// [`StreamClocks::to_extensions`]): the odometry puts the drive's
    /// streams on the GNSS clock with them.
    pub clocks: StreamClocks,
}

/// The clock offsets of a drive's streams against its wheels, as the
/// calibrator applied them: a stream's stamp is `t_wheels + offset` for the
/// same instant, and where a drift is applied the offset changes along the
/// drive: `offset(t) = late_s + drift_ppm 1e-6 (t - ref_t_s)` (exactly: the
/// stream's stamp is `ref + (1 + drift) (t_wheels + late - ref)`, the
/// calibrator's restamping inverted). Zero: the stream is on the wheels'
/// clock.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StreamClocks {
    /// GNSS stamps late against the wheels' (at `gnss_ref_t_s`), s.
    pub gnss_late_s: f64,
    /// IMU stamps late against the wheels' (at `imu_ref_t_s`), s.
    pub imu_late_s: f64,
    /// The GNSS clock's drift against the wheels', ppm (0: none applied).
    pub gnss_drift_ppm: f64,
    /// The IMU clock's drift against the wheels', ppm (0: none applied).
    pub imu_drift_ppm: f64,
    /// Wheel time the GNSS offset holds at, s (only used with a drift).
    pub gnss_ref_t_s: f64,
    /// Wheel time the IMU offset holds at, s (only used with a drift).
    pub imu_ref_t_s: f64,
}

impl StreamClocks {
    /// True when every offset and drift is zero.
    pub fn is_zero(&self) -> bool {
        self.gnss_late_s == 0.0
            && self.imu_late_s == 0.0
            && self.gnss_drift_ppm == 0.0
            && self.imu_drift_ppm == 0.0
    }

    /// The largest amount, s, by which putting a sample on the GNSS clock
    /// moves it later than the stamps of the other streams' samples of the
    /// same instant, over wheel times `t0..=t1`: how late the other streams'
    /// samples come for a wheel sample on the GNSS clock (0 when the
    /// wheels move earlier).
    pub fn max_lateness_s(&self, t0: f64, t1: f64) -> f64 {
        [t0, t1]
            .iter()
            .flat_map(|&t| {
                let g = self.wheel_time_on_gnss_clock(t) - t;
                // An IMU sample stamped `t` moves by this.
                let i = self.imu_time_on_gnss_clock(t) - t;
                [g, g - i]
            })
            .fold(0.0, f64::max)
    }

    /// A wheel stamp on the GNSS clock.
    pub fn wheel_time_on_gnss_clock(&self, t_wheels: f64) -> f64 {
        let d = self.gnss_drift_ppm * 1e-6;
        if d == 0.0 {
            return t_wheels + self.gnss_late_s;
        }
        let r = self.gnss_ref_t_s;
        r + (1.0 + d) * (t_wheels + self.gnss_late_s - r)
    }

    /// An IMU stamp on the wheels' clock.
    pub fn imu_time_on_wheel_clock(&self, t_imu: f64) -> f64 {
        let d = self.imu_drift_ppm * 1e-6;
        if d == 0.0 {
            return t_imu - self.imu_late_s;
        }
        let r = self.imu_ref_t_s;
        r + (t_imu - r) / (1.0 + d) - self.imu_late_s
    }

    /// An IMU stamp on the GNSS clock.
    pub fn imu_time_on_gnss_clock(&self, t_imu: f64) -> f64 {
        self.wheel_time_on_gnss_clock(self.imu_time_on_wheel_clock(t_imu))
    }

    /// Put every stream of `drive` on the GNSS clock (the clock of
    /// `truth.csv` and of the world): the wheels by
    /// [`StreamClocks::wheel_time_on_gnss_clock`], the IMU by
    /// [`StreamClocks::imu_time_on_gnss_clock`]; GNSS, heading and truth
    /// stay.
    pub fn align(&self, drive: &mut interfaces::drive::Drive) {
        if self.is_zero() {
            return;
        }
        for w in &mut drive.wheels.samples {
            w.t_s = self.wheel_time_on_gnss_clock(w.t_s);
        }
        for i in drive.imu.iter_mut().flatten() {
            i.t_s = self.imu_time_on_gnss_clock(i.t_s);
        }
    }

    /// The clocks as wire model extensions (one per stream with a non-zero
    /// offset or drift): [`GNSS_CLOCK_EXTENSION`], [`IMU_CLOCK_EXTENSION`]
    /// with (offset s, drift ppm, reference wheel time s).
    pub fn to_extensions(&self) -> Vec<ModelExtension> {
        let one = |code: u32, late: f64, ppm: f64, r: f64| ModelExtension {
            effect_code: code,
            param_count: 3,
            params: [late, ppm, r, 0.0],
        };
        let mut out = Vec::new();
        if self.gnss_late_s != 0.0 || self.gnss_drift_ppm != 0.0 {
            out.push(one(
                GNSS_CLOCK_EXTENSION,
                self.gnss_late_s,
                self.gnss_drift_ppm,
                self.gnss_ref_t_s,
            ));
        }
        if self.imu_late_s != 0.0 || self.imu_drift_ppm != 0.0 {
            out.push(one(
                IMU_CLOCK_EXTENSION,
                self.imu_late_s,
                self.imu_drift_ppm,
                self.imu_ref_t_s,
            ));
        }
        out
    }

    /// The clocks of wire model extensions (others are ignored; a clock
    /// extension with fewer than 3 or non-finite parameters is refused).
    pub fn from_extensions(
        xs: &[ModelExtension],
        source: &str,
    ) -> Result<StreamClocks, ParamsError> {
        let mut c = StreamClocks::default();
        for x in xs {
            if x.effect_code != GNSS_CLOCK_EXTENSION && x.effect_code != IMU_CLOCK_EXTENSION {
                continue;
            }
            let n = (x.param_count as usize).min(x.params.len());
            let bad = x.params[..n].iter().find(|v| !v.is_finite()).copied();
            // A clock more than a minute off, or drifting by more than 1 %,
            // is no sensor clock the calibrator finds.
            let implausible =
                n < 3 || bad.is_some() || x.params[0].abs() > 60.0 || x.params[1].abs() > 10_000.0;
            if implausible {
                return Err(ParamsError::Invalid {
                    source_name: source.to_string(),
                    field: "clock extension",
                    value: bad.unwrap_or(if n < 3 { n as f64 } else { x.params[0] }),
                    reason:
                        "must have 3 finite parameters: offset within 60 s, drift within 10000 ppm",
                });
            }
            let [late, ppm, r, _] = x.params;
            if x.effect_code == GNSS_CLOCK_EXTENSION {
                (c.gnss_late_s, c.gnss_drift_ppm, c.gnss_ref_t_s) = (late, ppm, r);
            } else {
                (c.imu_late_s, c.imu_drift_ppm, c.imu_ref_t_s) = (late, ppm, r);
            }
        }
        Ok(c)
    }
}

/// An antenna position whose 1-sigma is larger than this in either axis is
/// not used as the filter's lever arm ([`Estimate::fusable_antenna`]): the
/// calibrator's `antenna_unobservable` threshold. A drive that turns little,
/// or a consumer-grade GNSS, leaves it undetermined, and a wrong arm does
/// more harm than none.
pub const MAX_FUSED_ANTENNA_SIGMA_M: f64 = 0.1;

/// Why parameters could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ParamsError {
    /// The estimate file could not be read.
    #[error("cannot read estimate file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The JSON is malformed or misses a required field.
    #[error("{source_name}: line {line}, column {column}: {message}")]
    Json {
        /// File name or other description of the input.
        source_name: String,
        /// 1-based line of the error.
        line: usize,
        /// 1-based column of the error.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A value is out of range.
    #[error("{source_name}: {field} = {value} {reason}")]
    Invalid {
        /// File name or other description of the input.
        source_name: String,
        /// The offending field.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What is wrong with it.
        reason: &'static str,
    },
}

impl Estimate {
    /// The estimate received on the wire, validated.
    pub fn from_wire(wire: &CircumferenceEstimate) -> Result<Estimate, ParamsError> {
        let params = OdometryParams {
            two_wheel: TwoWheelParams {
                c_rl: wire.c_rl_m,
                c_rr: wire.c_rr_m,
                track_width: wire.track_width_m,
            },
            gyro_bias_rad_s: wire.gyro_bias_rad_s,
            gyro_scale: wire.gyro_scale,
        };
        let source = format!("estimate version {} on the wire", wire.version);
        params.validate(&source)?;
        let used = (wire.extension_count as usize).min(wire.extensions.len());
        let antenna = wire.extensions[..used]
            .iter()
            .find(|x| x.effect_code == Effect::GnssLeverArm.code() && x.param_count >= 2);
        let antenna_m = antenna
            .map(|x| validate_antenna([x.params[0], x.params[1]], &source))
            .transpose()?;
        let antenna_sigma_m = antenna
            .filter(|x| x.param_count >= 4)
            .map(|x| [x.params[2], x.params[3]]);
        Ok(Estimate {
            params,
            sigma_m: Some((wire.sigma_rl_m, wire.sigma_rr_m)),
            quality_m: Some(wire.quality_m),
            antenna_m,
            antenna_sigma_m,
            effects: EffectTerms::from_extensions(&wire.extensions[..used]).into(),
            clocks: StreamClocks::from_extensions(&wire.extensions[..used], &source)?,
        })
    }

    /// The estimate as the wire type: the GNSS antenna (`gnss_lever_arm`),
    /// when known, the sensor clocks ([`StreamClocks::to_extensions`]) and
    /// the effect terms (one extension per wheel-side effect,
    /// [`EffectTerms::to_extensions`]), in that order as far as the
    /// [`interfaces::wire::MAX_EXTENSIONS`] slots go. Unknown sigmas and
    /// quality are sent as 0 (the wire type has no validity flag for them).
    pub fn to_wire(&self, header: Header, version: u64) -> CircumferenceEstimate {
        let (sigma_rl_m, sigma_rr_m) = self.sigma_m.unwrap_or((0.0, 0.0));
        let mut wire = CircumferenceEstimate {
            header,
            version,
            c_rl_m: self.params.two_wheel.c_rl,
            c_rr_m: self.params.two_wheel.c_rr,
            sigma_rl_m,
            sigma_rr_m,
            track_width_m: self.params.two_wheel.track_width,
            gyro_bias_rad_s: self.params.gyro_bias_rad_s,
            gyro_scale: self.params.gyro_scale,
            quality_m: self.quality_m.unwrap_or(0.0),
            ..CircumferenceEstimate::default()
        };
        let mut n = 0;
        if let Some(a) = self.antenna_m {
            wire.extensions[0] = antenna_extension(a, self.antenna_sigma_m);
            n = 1;
        }
        let clocks = self.clocks.to_extensions();
        for x in clocks
            .into_iter()
            .chain(EffectTerms::from(self.effects).to_extensions())
        {
            if n < wire.extensions.len() {
                wire.extensions[n] = x;
                n += 1;
            }
        }
        wire.extension_count = n as u32;
        wire
    }

    /// The antenna position to use as the filter's GNSS lever arm: the
    /// calibrated one when its sigma is at most [`MAX_FUSED_ANTENNA_SIGMA_M`]
    /// in both axes, or when no sigma is given (a position written by hand).
    pub fn fusable_antenna(&self) -> Option<[f64; 2]> {
        let determined = self
            .antenna_sigma_m
            .is_none_or(|s| s.iter().all(|v| *v <= MAX_FUSED_ANTENNA_SIGMA_M));
        self.antenna_m.filter(|_| determined)
    }
}

/// The wire form of a GNSS antenna position: the `gnss_lever_arm` model
/// extension with parameters (x, y) and, when known, their 1-sigma
/// (`param_count` 4), m.
pub fn antenna_extension(antenna_m: [f64; 2], sigma_m: Option<[f64; 2]>) -> ModelExtension {
    let [sx, sy] = sigma_m.unwrap_or([0.0, 0.0]);
    ModelExtension {
        effect_code: Effect::GnssLeverArm.code(),
        param_count: if sigma_m.is_some() { 4 } else { 2 },
        params: [antenna_m[0], antenna_m[1], sx, sy],
    }
}

/// An antenna position must be finite and within 20 m of the rear axle
/// (the calibrator's own plausibility limit for `vehicle.toml`).
pub(crate) fn validate_antenna(antenna_m: [f64; 2], source: &str) -> Result<[f64; 2], ParamsError> {
    match antenna_m
        .iter()
        .find(|v| !(v.is_finite() && v.abs() < 20.0))
    {
        None => Ok(antenna_m),
        Some(&value) => Err(ParamsError::Invalid {
            source_name: source.to_string(),
            field: "gnss antenna position",
            value,
            reason: "must be finite and within 20 m of the rear axle",
        }),
    }
}

/// The GNSS antenna position to start with, and whether it was measured
/// (`vehicle.toml`'s `[gnss]`, which then wins over any estimate's);
/// otherwise the initial estimate's calibrated one, else the rear axle.
pub fn gnss_lever_arm(vehicle: &VehicleParams, initial: Option<&Estimate>) -> ([f64; 2], bool) {
    let (x, y) = (vehicle.gnss.antenna_x_m, vehicle.gnss.antenna_y_m);
    if x.is_some() || y.is_some() {
        ([x.unwrap_or(0.0), y.unwrap_or(0.0)], true)
    } else {
        (
            initial
                .and_then(Estimate::fusable_antenna)
                .unwrap_or([0.0, 0.0]),
            false,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::drive::GnssAntenna;

    const CALIBRATOR_JSON: &str = r#"{
        "circumference_m": {"rl": 2.1631, "rr": 2.1597},
        "sigma_m": {"rl": 0.0004, "rr": 0.0005},
        "track_width_m": 1.52,
        "gyro_bias_rad_s": 0.0004,
        "method": "paper",
        "selected_iteration": 4,
        "iterations": [ {"n": 1, "circumference_m": {"rl": 2.2, "rr": 2.2},
                         "dr_error_mean_m": 3.0, "dr_error_max_m": 9.0} ],
        "warnings": []
    }"#;

    #[test]
    fn calibrator_json_is_read_and_extra_fields_ignored() {
        let e = Estimate::from_json_str(CALIBRATOR_JSON, "est.json").unwrap();
        assert_eq!(e.params.two_wheel.c_rl, 2.1631);
        assert_eq!(e.params.two_wheel.c_rr, 2.1597);
        assert_eq!(e.params.two_wheel.track_width, 1.52);
        assert_eq!(e.params.gyro_bias_rad_s, 0.0004);
        assert_eq!(e.params.gyro_scale, 0.0, "absent scale means an ideal gyro");
        assert_eq!(e.sigma_m, Some((0.0004, 0.0005)));
    }

    #[test]
    fn missing_field_names_source_and_line() {
        let err = Estimate::from_json_str(
            "{\n \"circumference_m\": {\"rl\": 2.0, \"rr\": 2.0}\n}",
            "cal.json",
        )
        .unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains("cal.json") && msg.contains("track_width_m") && msg.contains("line 3"),
            "{msg}"
        );
    }

    #[test]
    fn nonsense_values_are_rejected_with_the_field() {
        let text = r#"{"circumference_m": {"rl": -2.0, "rr": 2.0}, "track_width_m": 1.5}"#;
        let msg = Estimate::from_json_str(text, "x.json")
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("circumference_m.rl") && msg.contains("-2"),
            "{msg}"
        );
        let text = r#"{"circumference_m": {"rl": 2.0, "rr": 2.0}, "track_width_m": 1.5, "gyro_scale": 3.0}"#;
        let msg = Estimate::from_json_str(text, "x.json")
            .unwrap_err()
            .to_string();
        assert!(msg.contains("gyro_scale"), "{msg}");
    }

    #[test]
    fn effect_terms_travel_in_the_json_and_on_the_wire() {
        let text = r#"{"circumference_m": {"rl": 2.0, "rr": 2.0}, "track_width_m": 1.5,
            "effects": {"track_rel": 0.02, "k_z": 5e-5, "gnss_latency_s": 0.08}}"#;
        let e = Estimate::from_json_str(text, "est.json").unwrap();
        assert_eq!(e.effects.track_rel, 0.02);
        assert_eq!(e.effects.k_z, 5e-5);
        let back = Estimate::from_wire(&e.to_wire(Header::from_seconds(1.0, 0), 3)).unwrap();
        assert_eq!(back.effects, e.effects);
        // Without `effects`: the plain model.
        let plain = Estimate::from_json_str(CALIBRATOR_JSON, "est.json").unwrap();
        assert_eq!(plain.effects, WheelEffects::default());
    }

    #[test]
    fn clock_offsets_and_drifts_travel_in_the_json_and_on_the_wire() {
        let text = r#"{"circumference_m": {"rl": 2.0, "rr": 2.0}, "track_width_m": 1.5,
            "clock_offsets": {
              "gnss_s": {"offset_s": -0.18, "applied": true,
                         "drift": {"drift_ppm": -200.0, "ref_t_s": 900.0, "applied": true}},
              "imu_s": {"offset_s": 0.3, "applied": true,
                        "drift": {"drift_ppm": 50.0, "ref_t_s": 900.0, "applied": false}}}}"#;
        let e = Estimate::from_json_str(text, "est.json").unwrap();
        let c = e.clocks;
        assert_eq!(
            (c.gnss_late_s, c.gnss_drift_ppm, c.gnss_ref_t_s),
            (-0.18, -200.0, 900.0)
        );
        // A drift not applied is not used.
        assert_eq!((c.imu_late_s, c.imu_drift_ppm), (0.3, 0.0));
        // An IMU moved by another shift than its own offset (the GNSS's,
        // where the wheels' clock moved): that shift is what is applied.
        let moved = text.replace(
            r#""offset_s": 0.3, "applied": true"#,
            r#""offset_s": 0.3, "applied": true, "applied_s": 0.32"#,
        );
        let m = Estimate::from_json_str(&moved, "est.json").unwrap();
        assert_eq!(m.clocks.imu_late_s, 0.32);
        let wire = e.to_wire(Header::from_seconds(1.0, 0), 4);
        assert_eq!(wire.extension_count, 2);
        assert_eq!(wire.extensions[0].effect_code, GNSS_CLOCK_EXTENSION);
        assert_eq!(Estimate::from_wire(&wire).unwrap().clocks, e.clocks);
        // The old layout still reads: no clock extension, no clocks.
        let plain = Estimate::from_json_str(CALIBRATOR_JSON, "est.json").unwrap();
        let back = Estimate::from_wire(&plain.to_wire(Header::from_seconds(1.0, 0), 1)).unwrap();
        assert!(back.clocks.is_zero());
        // A clock no sensor has is refused, naming it.
        let mut bad = wire;
        bad.extensions[0].params[1] = f64::NAN;
        let msg = Estimate::from_wire(&bad).unwrap_err().to_string();
        assert!(msg.contains("clock extension"), "{msg}");
    }

    #[test]
    fn align_inverts_the_calibrator_s_restamping() {
        // Wheels 200 ppm fast from 0 s, then 0.5 s late; the IMU on the GNSS clock.
        let c = StreamClocks {
            gnss_late_s: -(0.5 + 900.0 * 200e-6),
            imu_late_s: -(0.5 + 900.0 * 200e-6),
            gnss_drift_ppm: -200.0 / (1.0 + 200e-6),
            imu_drift_ppm: -200.0 / (1.0 + 200e-6),
            gnss_ref_t_s: 900.0,
            imu_ref_t_s: 900.0,
        };
        for t in [0.0, 450.0, 1800.0] {
            let t_wheels = t * (1.0 + 200e-6) + 0.5;
            assert!(
                (c.wheel_time_on_gnss_clock(t_wheels) - t).abs() < 1e-6,
                "{t}"
            );
            assert!((c.imu_time_on_gnss_clock(t) - t).abs() < 1e-6, "{t}");
        }
        // The wheels move earlier (by 0.5-0.86 s): nothing comes late for them.
        assert_eq!(c.max_lateness_s(0.0, 1800.0), 0.0);
        let early = StreamClocks {
            gnss_late_s: 0.7,
            imu_late_s: 0.7,
            ..StreamClocks::default()
        };
        assert!((early.max_lateness_s(0.0, 10.0) - 0.7).abs() < 1e-12);
    }

    #[test]
    fn wire_round_trip_keeps_every_value() {
        let mut e = Estimate::from_json_str(CALIBRATOR_JSON, "est.json").unwrap();
        e.params.gyro_scale = -0.012;
        e.quality_m = Some(0.7);
        let wire = e.to_wire(Header::from_seconds(12.5, 3), 7);
        assert_eq!(wire.version, 7);
        assert_eq!(wire.header.seq, 3);
        assert_eq!(Estimate::from_wire(&wire).unwrap(), e);
        let mut broken = wire;
        broken.track_width_m = f64::NAN;
        let msg = Estimate::from_wire(&broken).unwrap_err().to_string();
        assert!(
            msg.contains("version 7") && msg.contains("track_width_m"),
            "{msg}"
        );
    }

    #[test]
    fn the_antenna_travels_on_the_wire_as_a_gnss_lever_arm_extension() {
        let mut e = Estimate::from_json_str(CALIBRATOR_JSON, "est.json").unwrap();
        e.antenna_m = Some([0.51, -0.31]);
        e.antenna_sigma_m = Some([0.03, 0.04]);
        e.quality_m = Some(0.7);
        let wire = e.to_wire(Header::from_seconds(1.0, 0), 2);
        assert_eq!(wire.extension_count, 1);
        assert_eq!(wire.extensions[0].effect_code, Effect::GnssLeverArm.code());
        assert_eq!(Estimate::from_wire(&wire).unwrap(), e);
        let mut no_sigma = e;
        no_sigma.antenna_sigma_m = None;
        let wire2 = no_sigma.to_wire(Header::from_seconds(1.0, 0), 2);
        assert_eq!(wire2.extensions[0].param_count, 2);
        assert_eq!(Estimate::from_wire(&wire2).unwrap(), no_sigma);
        // Another extension before it (the calibrator's side slip) is skipped.
        let mut two = wire;
        two.extensions[1] = two.extensions[0];
        two.extensions[0] = ModelExtension {
            effect_code: Effect::SideSlip.code(),
            param_count: 1,
            params: [0.004, 0.0, 0.0, 0.0],
        };
        two.extension_count = 2;
        assert_eq!(
            Estimate::from_wire(&two).unwrap().antenna_m,
            Some([0.51, -0.31])
        );
        // A slot beyond extension_count is not read.
        two.extension_count = 1;
        assert_eq!(Estimate::from_wire(&two).unwrap().antenna_m, None);
        // An implausible antenna rejects the estimate, naming it.
        let mut far = wire;
        far.extensions[0].params[1] = f64::INFINITY;
        let msg = Estimate::from_wire(&far).unwrap_err().to_string();
        assert!(
            msg.contains("version 2") && msg.contains("antenna"),
            "{msg}"
        );
        let text = r#"{"circumference_m": {"rl": 2.0, "rr": 2.0}, "track_width_m": 1.5, "gnss_antenna_m": [35.0, 0.0]}"#;
        let msg = Estimate::from_json_str(text, "x.json")
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("x.json") && msg.contains("antenna") && msg.contains("35"),
            "{msg}"
        );
    }

    #[test]
    fn nominal_uses_vehicle_toml_and_gyro_correction_inverts_the_model() {
        let vehicle = VehicleParams {
            name: None,
            track_width_m: 1.45,
            nominal_circumference_m: 1.85,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: GnssAntenna::default(),
        };
        let p = OdometryParams::nominal(&vehicle);
        assert_eq!(
            (p.two_wheel.c_rl, p.two_wheel.c_rr, p.two_wheel.track_width),
            (1.85, 1.85, 1.45)
        );
        let p = OdometryParams {
            gyro_bias_rad_s: 0.01,
            gyro_scale: 0.02,
            ..p
        };
        let w = 0.3;
        assert!((p.corrected_yaw_rate((1.0 + 0.02) * w + 0.01) - w).abs() < 1e-15);
    }

    #[test]
    fn the_antenna_comes_from_the_gyro_object_else_the_top_level() {
        let base = r#""circumference_m": {"rl": 1.83, "rr": 1.83}, "track_width_m": 1.45"#;
        let gyro = format!(
            r#"{{{base}, "gyro": {{"antenna_m": [0.5, -0.3]}}, "gnss_antenna_m": [1.0, 0.0]}}"#
        );
        let top = format!(r#"{{{base}, "gnss_antenna_m": [1.0, 0.0]}}"#);
        let none = format!("{{{base}}}");
        let a = |t: &str| Estimate::from_json_str(t, "test").unwrap().antenna_m;
        assert_eq!(a(&gyro), Some([0.5, -0.3]));
        assert_eq!(a(&top), Some([1.0, 0.0]));
        assert_eq!(a(&none), None);
    }

    #[test]
    fn only_a_determined_antenna_is_fused() {
        let base = r#""circumference_m": {"rl": 1.83, "rr": 1.83}, "track_width_m": 1.45"#;
        let est = |gyro: &str| {
            Estimate::from_json_str(&format!(r#"{{{base}, "gyro": {gyro}}}"#), "test").unwrap()
        };
        let sharp = est(r#"{"antenna_m": [0.5, -0.3], "sigma_antenna_m": [0.03, 0.04]}"#);
        assert_eq!(sharp.antenna_sigma_m, Some([0.03, 0.04]));
        assert_eq!(sharp.fusable_antenna(), Some([0.5, -0.3]));
        // wid-trial04's case: the lateral position is not determined.
        let vague = est(r#"{"antenna_m": [0.62, -0.04], "sigma_antenna_m": [0.05, 0.15]}"#);
        assert_eq!(vague.antenna_m, Some([0.62, -0.04]), "still reported");
        assert_eq!(vague.fusable_antenna(), None);
        let by_hand = est(r#"{"antenna_m": [1.1, 0.0]}"#);
        assert_eq!(by_hand.fusable_antenna(), Some([1.1, 0.0]));
        // The top-level pair goes with its own sigma.
        let top = format!(
            r#"{{{base}, "gnss_antenna_m": [1.0, 0.0], "sigma_gnss_antenna_m": [0.2, 0.2]}}"#
        );
        let top = Estimate::from_json_str(&top, "test").unwrap();
        assert_eq!(top.antenna_sigma_m, Some([0.2, 0.2]));
        assert_eq!(top.fusable_antenna(), None);
    }
}
