//! What the services served while a drive was recorded, written beside it
//! by `sensor-bridge record`: the odometry's poses and the calibrator's
//! estimates, each in our own schema (everything the wire carries), and the
//! poses also in Foxglove's ([`super::foxglove`]). The reader leaves these
//! channels out (schema names [`SERVED_SCHEMA_PREFIX`]`*`): a drive is its
//! sensors, and reads back the same with or without them.

use super::outgoing::Outgoing;
use serde::Serialize;
use serde_json::json;

/// Channel of the served poses (our schema [`POSE_SCHEMA`]).
pub const POSE_TOPIC: &str = interfaces::wire::POSE_SERVICE;
/// Channel of the served estimates (our schema [`ESTIMATE_SCHEMA`]).
pub const ESTIMATE_TOPIC: &str = interfaces::wire::ESTIMATE_SERVICE;
/// Every served channel's schema name starts with this.
pub const SERVED_SCHEMA_PREFIX: &str = "wheelcal.served.";
/// Schema name of [`POSE_TOPIC`].
pub const POSE_SCHEMA: &str = "wheelcal.served.Pose";
/// Schema name of [`ESTIMATE_TOPIC`].
pub const ESTIMATE_SCHEMA: &str = "wheelcal.served.Estimate";

/// One pose the odometry served (`interfaces::wire::Pose`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ServedPose {
    /// Time of the wheel sample it belongs to, s (the drive's clock).
    pub t_s: f64,
    /// Rear-axle centre east, m.
    pub x_m: f64,
    /// Rear-axle centre north, m.
    pub y_m: f64,
    /// Yaw, rad (0 = east, counter-clockwise).
    pub yaw_rad: f64,
    /// Covariance of (x, y, yaw), row-major.
    pub covariance: [f64; 9],
    /// Mode code (`interfaces::wire::PoseMode`).
    pub mode: u8,
    /// Version of the estimate in use (0: nominal).
    pub estimate_version: u64,
}

/// One estimate the calibrator served (`interfaces::wire::CircumferenceEstimate`,
/// without its model extensions).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ServedEstimate {
    /// Time of the last sample it used, s.
    pub t_s: f64,
    /// Version.
    pub version: u64,
    /// Rear-left circumference, m.
    pub c_rl_m: f64,
    /// Rear-right circumference, m.
    pub c_rr_m: f64,
    /// Their 1-sigma, m.
    pub sigma_rl_m: f64,
    /// Their 1-sigma, m.
    pub sigma_rr_m: f64,
    /// Track width, m.
    pub track_width_m: f64,
    /// Gyro bias, rad/s.
    pub gyro_bias_rad_s: f64,
    /// Gyro scale error.
    pub gyro_scale: f64,
    /// Mean dead-reckoning error on held-out data, m.
    pub quality_m: f64,
}

fn schema(title: &str, description: &str, fields: &[(&str, &str, &str)]) -> Vec<u8> {
    let properties: serde_json::Map<String, serde_json::Value> = fields
        .iter()
        .map(|(name, ty, d)| (name.to_string(), json!({ "type": ty, "description": d })))
        .collect();
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": title,
        "description": description,
        "type": "object",
        "properties": properties,
    })
    .to_string()
    .into_bytes()
}

/// The served poses in our schema.
pub(super) struct PoseOut<'a>(pub &'a [ServedPose]);

impl Outgoing for PoseOut<'_> {
    fn name(&self) -> &'static str {
        "served poses"
    }
    fn topic(&self) -> &'static str {
        POSE_TOPIC
    }
    fn schema_name(&self) -> &'static str {
        POSE_SCHEMA
    }
    fn schema(&self) -> Vec<u8> {
        schema(
            POSE_SCHEMA,
            "A pose the odometry served: the rear-axle centre in the drive's local ENU frame",
            &[
                ("t_s", "number", "Time of its wheel sample, s"),
                ("x_m", "number", "East, m"),
                ("y_m", "number", "North, m"),
                ("yaw_rad", "number", "Yaw, rad, 0 = east, counter-clockwise"),
                (
                    "covariance",
                    "array",
                    "Covariance of (x, y, yaw), row-major 3x3",
                ),
                ("mode", "integer", "0 no fix, 1 fused, 2 dead-reckoning"),
                (
                    "estimate_version",
                    "integer",
                    "Estimate in use (0: nominal)",
                ),
            ],
        )
    }
    fn times(&self) -> Box<dyn Iterator<Item = f64> + '_> {
        Box::new(self.0.iter().map(|s| s.t_s))
    }
    fn encode(&self, i: usize, buf: &mut Vec<u8>) -> Option<serde_json::Result<()>> {
        let s = self.0.get(i)?;
        Some(serde_json::to_writer(buf, s))
    }
}

/// The served estimates in our schema.
pub(super) struct EstimateOut<'a>(pub &'a [ServedEstimate]);

impl Outgoing for EstimateOut<'_> {
    fn name(&self) -> &'static str {
        "served estimates"
    }
    fn topic(&self) -> &'static str {
        ESTIMATE_TOPIC
    }
    fn schema_name(&self) -> &'static str {
        ESTIMATE_SCHEMA
    }
    fn schema(&self) -> Vec<u8> {
        schema(
            ESTIMATE_SCHEMA,
            "A circumference estimate the calibrator served",
            &[
                ("t_s", "number", "Time of the last sample it used, s"),
                ("version", "integer", "Version"),
                ("c_rl_m", "number", "Rear-left circumference, m"),
                ("c_rr_m", "number", "Rear-right circumference, m"),
                ("sigma_rl_m", "number", "1-sigma of c_rl_m, m"),
                ("sigma_rr_m", "number", "1-sigma of c_rr_m, m"),
                ("track_width_m", "number", "Track width, m"),
                ("gyro_bias_rad_s", "number", "Gyro bias, rad/s"),
                ("gyro_scale", "number", "Gyro scale error"),
                ("quality_m", "number", "Held-out dead-reckoning error, m"),
            ],
        )
    }
    fn times(&self) -> Box<dyn Iterator<Item = f64> + '_> {
        Box::new(self.0.iter().map(|s| s.t_s))
    }
    fn encode(&self, i: usize, buf: &mut Vec<u8>) -> Option<serde_json::Result<()>> {
        let s = self.0.get(i)?;
        Some(serde_json::to_writer(buf, s))
    }
}
