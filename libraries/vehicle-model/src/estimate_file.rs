//! The estimate file: the JSON that `calibrator calibrate --json` writes and
//! that the odometry (`odometry evaluate --estimate`, `odometry serve
//! --estimate`) and `calibrator calibrate --initial` read. One serde type,
//! [`EstimateFile`], for both sides.
//!
//! It names the fields the estimate contract consists of (the
//! circumferences, the track, the gyro, the GNSS antenna, the sensor
//! clocks, the effect terms and the vehicle the estimate was made for);
//! everything else the calibrator writes (its method, iterations, warnings,
//! diagnostics, ...) travels beside them untouched, in the `report` maps.
//! Serialized, the file keeps the calibrator's layout: every object's keys
//! in alphabetical order, absent sigmas and gyro values as `null`.
//!
//! The reader's rules ([`EstimateFile::estimate`]): a gyro bias or scale
//! that is absent (or `null`) means an ideal gyro; the antenna comes from
//! `gyro.antenna_m` (with `gyro.sigma_antenna_m`), else from
//! `gnss_antenna_m` (with `sigma_gnss_antenna_m`); a clock offset or drift
//! is used only when `applied`; no `effects` is the plain 2W model.

use crate::effects::EffectTerms;
use crate::estimate::{validate_antenna, Estimate, OdometryParams, ParamsError, StreamClocks};
pub use crate::estimate_vehicle::NominalFields;
use crate::estimate_vehicle::{json_error, made_for, EstimateVehicle};
use crate::two_wheel::TwoWheelParams;
use interfaces::drive::VehicleParams;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

/// The fields of an object that the estimate contract does not name, kept
/// as they are.
pub type Other = Map<String, Value>;

/// The estimate file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EstimateFile {
    /// Effective rear circumferences, m (`circumference_m.{rl,rr}`).
    pub circumference_m: RearCircumferences,
    /// Their 1-sigma, m, when given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_m: Option<RearSigmas>,
    /// The effective rear track the circumferences belong to, m.
    pub track_width_m: f64,
    /// Yaw-rate gyro bias, rad/s (`null` or absent: none).
    #[serde(default)]
    pub gyro_bias_rad_s: Option<f64>,
    /// Yaw-rate gyro scale error (`null` or absent: none).
    #[serde(default)]
    pub gyro_scale: Option<f64>,
    /// The calibrator's gyro model (`null` or absent: none).
    #[serde(default)]
    pub gyro: Option<GyroFields>,
    /// The GNSS antenna position of the 2W fit, m (body x, y).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gnss_antenna_m: Option<[f64; 2]>,
    /// Its 1-sigma, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_gnss_antenna_m: Option<[f64; 2]>,
    /// The effect terms a diagnosis accepted (`calibrate --diagnose`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub effects: Option<EffectTerms>,
    /// The sensor clock offsets and drifts the calibration found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clock_offsets: Option<ClockOffsetsFields>,
    /// The `vehicle.toml` of the calibrated drive.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vehicle: Option<VehicleParams>,
    /// The nominal values the calibration started from (older files carry
    /// these but no `vehicle`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nominal: Option<NominalFields>,
    /// Everything else: the calibration's report.
    #[serde(flatten)]
    pub report: Other,
}

/// `circumference_m`: one value per rear wheel, m.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RearCircumferences {
    /// Rear left.
    pub rl: f64,
    /// Rear right.
    pub rr: f64,
    /// Any other field.
    #[serde(flatten)]
    pub report: Other,
}

/// `sigma_m`: the circumferences' 1-sigma, m (`null`: not determined).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RearSigmas {
    /// Rear left.
    #[serde(default)]
    pub rl: Option<f64>,
    /// Rear right.
    #[serde(default)]
    pub rr: Option<f64>,
    /// Any other field (the calibrator's `difference`, `mean`).
    #[serde(flatten)]
    pub report: Other,
}

/// `gyro`: the part of the calibrator's gyro model the contract names.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GyroFields {
    /// The GNSS antenna position of the gyro model's fit, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub antenna_m: Option<[f64; 2]>,
    /// Its 1-sigma, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_antenna_m: Option<[f64; 2]>,
    /// Any other field (bias, scale and their sigmas, ...).
    #[serde(flatten)]
    pub report: Other,
}

/// `clock_offsets`: one entry per stream against the wheels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClockOffsetsFields {
    /// The GNSS clock.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gnss_s: Option<StreamOffsetFields>,
    /// The IMU clock.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imu_s: Option<StreamOffsetFields>,
    /// Any other field (the pairwise offsets, ...).
    #[serde(flatten)]
    pub report: Other,
}

/// One stream's clock offset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StreamOffsetFields {
    /// Its stamps late against the wheels', s (`null`: not determined).
    #[serde(default)]
    pub offset_s: Option<f64>,
    /// Whether the calibration applied it (only then the odometry does).
    #[serde(default)]
    pub applied: bool,
    /// The shift applied where it is not `offset_s` (the IMU moved with the
    /// GNSS where the wheels' clock moved against both), s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub applied_s: Option<f64>,
    /// Its drift.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drift: Option<ClockDriftFields>,
    /// Any other field (status, sigma, reason, ...).
    #[serde(flatten)]
    pub report: Other,
}

/// One stream's clock drift.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClockDriftFields {
    /// The drift against the wheels' clock, ppm (`null`: not determined).
    #[serde(default)]
    pub drift_ppm: Option<f64>,
    /// The wheel time the offset holds at, s.
    #[serde(default)]
    pub ref_t_s: Option<f64>,
    /// Whether the calibration applied it (only then the odometry does).
    #[serde(default)]
    pub applied: bool,
    /// Any other field (status, sigma, windows, ...).
    #[serde(flatten)]
    pub report: Other,
}

impl Estimate {
    /// Parse the calibrator's JSON (the estimate file, [`EstimateFile`]);
    /// `source` names the input in errors. A gyro bias or scale that is
    /// absent (or `null`) means an ideal gyro.
    pub fn from_json_str(text: &str, source: &str) -> Result<Estimate, ParamsError> {
        EstimateFile::from_json_str(text, source)?.estimate(source)
    }
}

impl EstimateFile {
    /// Parse an estimate file's text; `source` names it in errors (with
    /// the line and column).
    pub fn from_json_str(text: &str, source: &str) -> Result<EstimateFile, ParamsError> {
        serde_json::from_str(text).map_err(|e| json_error(&e, source))
    }

    /// The estimate file of a calibration report (the calibrator's
    /// `Calibration`): its contract fields taken into the named ones, the
    /// rest kept as the report. An error when the report lacks a contract
    /// field or gives it another type.
    pub fn from_report<T: Serialize>(report: &T) -> Result<EstimateFile, serde_json::Error> {
        serde_json::from_value(serde_json::to_value(report)?)
    }

    /// The file's text: pretty-printed JSON with every object's keys in
    /// alphabetical order (the layout the calibrator has always written),
    /// ending in a newline.
    pub fn to_json_string(&self) -> Result<String, serde_json::Error> {
        // Through a `Value`, whose objects are sorted maps.
        let value = serde_json::to_value(self)?;
        Ok(serde_json::to_string_pretty(&value)? + "\n")
    }

    /// The estimate the file holds, validated; `source` names it in errors.
    pub fn estimate(&self, source: &str) -> Result<Estimate, ParamsError> {
        let params = OdometryParams {
            two_wheel: TwoWheelParams {
                c_rl: self.circumference_m.rl,
                c_rr: self.circumference_m.rr,
                track_width: self.track_width_m,
            },
            gyro_bias_rad_s: self.gyro_bias_rad_s.unwrap_or(0.0),
            gyro_scale: self.gyro_scale.unwrap_or(0.0),
        };
        params.validate(source)?;
        let (antenna_m, antenna_sigma_m) = self.antenna();
        Ok(Estimate {
            params,
            sigma_m: self.sigma_m.as_ref().and_then(|s| Some((s.rl?, s.rr?))),
            quality_m: None,
            antenna_m: antenna_m.map(|a| validate_antenna(a, source)).transpose()?,
            antenna_sigma_m,
            effects: self.effects.unwrap_or_default().into(),
            clocks: self
                .clock_offsets
                .as_ref()
                .map(ClockOffsetsFields::clocks)
                .unwrap_or_default(),
        })
    }

    /// The antenna and its sigma from the same fit: the gyro model's, else
    /// the 2W one's.
    fn antenna(&self) -> (Option<[f64; 2]>, Option<[f64; 2]>) {
        match &self.gyro {
            Some(GyroFields {
                antenna_m: Some(a),
                sigma_antenna_m,
                ..
            }) => (Some(*a), *sigma_antenna_m),
            _ => (self.gnss_antenna_m, self.sigma_gnss_antenna_m),
        }
    }

    /// The vehicle the estimate was made for: its `vehicle`, else its
    /// `nominal` values; `None` when it carries neither (a hand-written
    /// estimate).
    pub fn made_for(&self) -> Option<EstimateVehicle> {
        made_for(self.vehicle.as_ref(), self.nominal.as_ref())
    }
}

impl StreamOffsetFields {
    /// The applied offset, s, else 0.
    fn applied_offset(o: Option<&StreamOffsetFields>) -> f64 {
        o.filter(|o| o.applied)
            .and_then(|o| o.applied_s.or(o.offset_s))
            .filter(|v| v.is_finite())
            .unwrap_or(0.0)
    }

    /// The applied drift (ppm) and its reference time, else zeros.
    fn applied_drift(o: Option<&StreamOffsetFields>) -> (f64, f64) {
        o.and_then(|o| o.drift.as_ref())
            .filter(|d| d.applied)
            .and_then(|d| Some((d.drift_ppm?, d.ref_t_s?)))
            .filter(|(p, r)| p.is_finite() && r.is_finite())
            .unwrap_or((0.0, 0.0))
    }
}

impl ClockOffsetsFields {
    /// The clocks the calibration applied.
    fn clocks(&self) -> StreamClocks {
        let (g, i) = (self.gnss_s.as_ref(), self.imu_s.as_ref());
        let ((gnss_drift_ppm, gnss_ref_t_s), (imu_drift_ppm, imu_ref_t_s)) = (
            StreamOffsetFields::applied_drift(g),
            StreamOffsetFields::applied_drift(i),
        );
        StreamClocks {
            gnss_late_s: StreamOffsetFields::applied_offset(g),
            imu_late_s: StreamOffsetFields::applied_offset(i),
            gnss_drift_ppm,
            imu_drift_ppm,
            gnss_ref_t_s,
            imu_ref_t_s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file in the layout `calibrator calibrate --json` writes (shortened).
    const WRITTEN: &str = r#"{
  "circumference_m": {"rl": 1.8312, "rr": 1.82897},
  "clock_offsets": {
    "gnss_s": {"applied": true, "drift": {"applied": false, "drift_ppm": 12.0,
               "ref_t_s": 300.0, "status": "determined", "windows": []},
               "offset_s": -0.12, "reason": null, "sigma_s": 0.01, "status": "determined"},
    "imu_s": {"applied": false, "drift": {"applied": false, "drift_ppm": null, "ref_t_s": null},
              "offset_s": null, "status": "not_checked"},
    "pairs": []
  },
  "diagnostics": {"distance_m": 512.0, "gnss_fixes": 1200},
  "gyro": {"antenna_m": [0.49, -0.3], "bias_rad_s": 2.4e-5, "scale": -0.007,
           "sigma_antenna_m": [0.02, 0.03], "sigma_scale": null},
  "gyro_bias_rad_s": 2.4e-5,
  "gyro_scale": null,
  "iterations": [{"n": 0, "circumference_m": {"rl": 1.85, "rr": 1.85}}],
  "method": "batch",
  "nominal": {"circumference_m": 1.85, "track_width_m": 1.45},
  "selected_iteration": 0,
  "side_slip": false,
  "sigma_m": {"difference": 0.001, "mean": null, "rl": 0.0024, "rr": 0.0022},
  "track_width_m": 1.4323,
  "vehicle": {"name": "Roomster", "nominal_circumference_m": 1.85, "track_width_m": 1.45},
  "warnings": [{"code": "reading", "message": "m"}]
}"#;

    #[test]
    fn a_written_file_reads_and_writes_back_unchanged() {
        let file = EstimateFile::from_json_str(WRITTEN, "est.json").expect("parsed");
        let text = file.to_json_string().expect("encoded");
        let back: Value = serde_json::from_str(&text).expect("json");
        let before: Value = serde_json::from_str(WRITTEN).expect("json");
        assert_eq!(back, before, "{text}");
        assert!(text.ends_with("}\n"));
        let e = file.estimate("est.json").expect("valid");
        assert_eq!(e.params.two_wheel.c_rl, 1.8312);
        assert_eq!(
            (e.params.gyro_bias_rad_s, e.params.gyro_scale),
            (2.4e-5, 0.0)
        );
        assert_eq!(e.sigma_m, Some((0.0024, 0.0022)));
        assert_eq!(e.antenna_m, Some([0.49, -0.3]));
        assert_eq!(e.antenna_sigma_m, Some([0.02, 0.03]));
        // The GNSS offset was applied, its drift not; the IMU's nothing.
        assert_eq!(
            e.clocks,
            StreamClocks {
                gnss_late_s: -0.12,
                ..StreamClocks::default()
            }
        );
        let v = file.made_for().expect("a vehicle");
        assert_eq!(v.name.as_deref(), Some("Roomster"));
        assert_eq!(file.report["method"], Value::from("batch"));
    }

    #[test]
    fn an_undetermined_sigma_is_no_sigma() {
        let text = r#"{"circumference_m": {"rl": 2.0, "rr": 2.0}, "track_width_m": 1.5,
            "sigma_m": {"rl": null, "rr": 0.002}}"#;
        let e = EstimateFile::from_json_str(text, "x.json")
            .and_then(|f| f.estimate("x.json"))
            .expect("read");
        assert_eq!(e.sigma_m, None);
    }

    #[test]
    fn a_report_becomes_a_file_with_its_contract_fields_named() {
        #[derive(Serialize)]
        struct Report {
            circumference_m: [(&'static str, f64); 0],
        }
        // A report without the contract's fields is refused by the writer.
        assert!(EstimateFile::from_report(&Report {
            circumference_m: []
        })
        .is_err());
        let value: Value = serde_json::from_str(WRITTEN).expect("json");
        let file = EstimateFile::from_report(&value).expect("a file");
        assert_eq!(file.track_width_m, 1.4323);
        assert!(!file.report.contains_key("track_width_m"));
        assert_eq!(file.effects, None);
    }
}
