//! Foxglove's well-known message schemas, written beside our own channels so
//! that Foxglove's panels show a recording: the GNSS fixes in latitude and
//! longitude (`foxglove.LocationFix`, Map panel), the true poses
//! (`foxglove.PoseInFrame`) and the transform they give the vehicle
//! (`foxglove.FrameTransform`, 3D panel), and the loading warnings
//! (`foxglove.Log`, Log panel).
//!
//! Messages are JSON described by JSON schemas (Foxglove reads
//! `jsonschema` + `json` for these types when the schema name is exactly
//! the type's). The schemas here are written from the field lists Foxglove
//! documents (docs.foxglove.dev, "Message schemas"); the optional fields
//! we have nothing for (a fix's colour and metadata) are left out.
//!
//! These channels are derived from the drive's own and carry less: the
//! reader ignores every channel whose schema is `foxglove.*`.
//!
//! Time stamps are the messages' log times (see the module above: the
//! drive's `t_s` in nanoseconds plus `log_time_offset_ns`). A drive whose
//! `t_s` are UNIX seconds therefore shows at its real date; a drive on a
//! clock starting near 0 shows in January 1970.

use super::outgoing::{log_time_ns, Outgoing};
use super::served::ServedPose;
use crate::geodesy::LocalFrame;
use interfaces::drive::{GnssSample, TruthSample};
use serde::Serialize;
use serde_json::{json, Value};

/// Channel of the GNSS fixes as `foxglove.LocationFix` (Map panel).
pub const LOCATION_TOPIC: &str = "/gnss/location";
/// Channel of the true poses as `foxglove.PoseInFrame` (3D panel).
pub const TRUTH_POSE_TOPIC: &str = "/truth/pose";
/// Channel of the `foxglove.FrameTransform`s placing the vehicle frame
/// ([`BODY_FRAME`]) in the local ENU frame ([`WORLD_FRAME`]), one per true pose.
pub const TF_TOPIC: &str = "/tf";
/// Channel of the odometry's served poses as `foxglove.PoseInFrame` (3D panel).
pub const SERVED_POSE_TOPIC: &str = "/odometry/pose";
/// Channel of the odometry's served poses as `foxglove.LocationFix` (Map
/// panel; only where the drive has a geodetic origin).
pub const SERVED_LOCATION_TOPIC: &str = "/odometry/location";
/// Channel of the drive's warnings as `foxglove.Log` (Log panel).
pub const LOG_TOPIC: &str = "/log";
/// Frame id of the drive's local ENU frame (x east, y north; origin at the
/// drive's geodetic origin).
pub const WORLD_FRAME: &str = "enu";
/// Frame id of the vehicle (rear-axle centre, x forward, y left).
pub const BODY_FRAME: &str = "base_link";
/// Frame id of the GNSS fixes.
pub const GNSS_FRAME: &str = "gnss";

/// Schema name of [`LOCATION_TOPIC`].
pub const LOCATION_FIX: &str = "foxglove.LocationFix";
/// Schema name of [`TRUTH_POSE_TOPIC`].
pub const POSE_IN_FRAME: &str = "foxglove.PoseInFrame";
/// Schema name of [`TF_TOPIC`].
pub const FRAME_TRANSFORM: &str = "foxglove.FrameTransform";
/// Schema name of [`LOG_TOPIC`].
pub const LOG: &str = "foxglove.Log";

/// `position_covariance_type` when the fix has a sigma: per-axis variances
/// on the diagonal (DIAGONAL_KNOWN).
const COVARIANCE_DIAGONAL_KNOWN: u8 = 2;
/// `position_covariance_type` without a sigma (UNKNOWN).
const COVARIANCE_UNKNOWN: u8 = 0;
/// `foxglove.Log` level WARNING.
const LEVEL_WARNING: u8 = 3;

// ------------------------------------------------------------- messages

/// Foxglove's time: whole seconds and nanoseconds.
#[derive(Serialize)]
struct Time {
    sec: u64,
    nsec: u32,
}

impl Time {
    fn from_ns(ns: u64) -> Time {
        Time {
            sec: ns / 1_000_000_000,
            nsec: (ns % 1_000_000_000) as u32,
        }
    }
}

#[derive(Serialize)]
struct Vector3 {
    x: f64,
    y: f64,
    z: f64,
}

#[derive(Serialize)]
struct Quaternion {
    x: f64,
    y: f64,
    z: f64,
    w: f64,
}

impl Quaternion {
    /// A rotation by `yaw` about z (identity when the yaw is unknown).
    fn yaw(yaw: Option<f64>) -> Quaternion {
        let (s, c) = yaw.map_or((0.0, 1.0), |y| (0.5 * y).sin_cos());
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: s,
            w: c,
        }
    }
}

#[derive(Serialize)]
struct Pose {
    position: Vector3,
    orientation: Quaternion,
}

#[derive(Serialize)]
struct LocationFix<'a> {
    timestamp: Time,
    frame_id: &'a str,
    latitude: f64,
    longitude: f64,
    altitude: f64,
    position_covariance: [f64; 9],
    position_covariance_type: u8,
}

#[derive(Serialize)]
struct PoseInFrame<'a> {
    timestamp: Time,
    frame_id: &'a str,
    pose: Pose,
}

#[derive(Serialize)]
struct FrameTransform<'a> {
    timestamp: Time,
    parent_frame_id: &'a str,
    child_frame_id: &'a str,
    translation: Vector3,
    rotation: Quaternion,
}

#[derive(Serialize)]
struct Log<'a> {
    timestamp: Time,
    level: u8,
    message: &'a str,
    name: &'a str,
    file: &'a str,
    line: u32,
}

/// The pose of a true sample in the ENU frame (z = 0: drives are planar).
fn truth_pose(s: &TruthSample) -> Pose {
    Pose {
        position: Vector3 {
            x: s.x_m,
            y: s.y_m,
            z: 0.0,
        },
        orientation: Quaternion::yaw(s.yaw_rad),
    }
}

// ------------------------------------------------------------- schemas

fn time_schema() -> Value {
    json!({
        "type": "object",
        "title": "time",
        "properties": {
            "sec": { "type": "integer", "minimum": 0 },
            "nsec": { "type": "integer", "minimum": 0, "maximum": 999_999_999 }
        }
    })
}

fn vector3_schema(description: &str) -> Value {
    let n = json!({ "type": "number" });
    json!({
        "type": "object",
        "description": description,
        "properties": { "x": n, "y": n, "z": n }
    })
}

fn quaternion_schema(description: &str) -> Value {
    let n = json!({ "type": "number" });
    json!({
        "type": "object",
        "description": description,
        "properties": { "x": n, "y": n, "z": n, "w": n }
    })
}

fn string(description: &str) -> Value {
    json!({ "type": "string", "description": description })
}

fn number(description: &str) -> Value {
    json!({ "type": "number", "description": description })
}

/// An enumeration of integers (value, name).
fn integer_enum(description: &str, values: &[(u8, &str)]) -> Value {
    let one_of: Vec<Value> = values
        .iter()
        .map(|(v, name)| json!({ "title": name, "const": v }))
        .collect();
    json!({ "type": "integer", "description": description, "oneOf": one_of })
}

fn object_schema(title: &str, description: &str, properties: Value) -> Vec<u8> {
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

fn location_fix_schema() -> Vec<u8> {
    object_schema(
        LOCATION_FIX,
        "A GNSS fix in WGS84 latitude and longitude",
        json!({
            "timestamp": time_schema(),
            "frame_id": string("Frame of the sensor"),
            "latitude": number("Latitude, degrees"),
            "longitude": number("Longitude, degrees"),
            "altitude": number("Altitude, m (0: the drive carries no height; on the ellipsoid)"),
            "position_covariance": {
                "type": "array",
                "description": "Position covariance, m^2, east-north-up, row-major",
                "items": { "type": "number" },
                "minItems": 9,
                "maxItems": 9
            },
            "position_covariance_type": integer_enum(
                "Kind of position_covariance",
                &[(0, "UNKNOWN"), (1, "APPROXIMATED"), (2, "DIAGONAL_KNOWN"), (3, "KNOWN")],
            ),
        }),
    )
}

fn pose_in_frame_schema() -> Vec<u8> {
    object_schema(
        POSE_IN_FRAME,
        "A timestamped pose in a named frame",
        json!({
            "timestamp": time_schema(),
            "frame_id": string("Frame of the pose"),
            "pose": {
                "type": "object",
                "description": "Position and orientation",
                "properties": {
                    "position": vector3_schema("Position, m"),
                    "orientation": quaternion_schema("Orientation"),
                }
            },
        }),
    )
}

fn frame_transform_schema() -> Vec<u8> {
    object_schema(
        FRAME_TRANSFORM,
        "The pose of a child frame in its parent frame",
        json!({
            "timestamp": time_schema(),
            "parent_frame_id": string("Parent frame"),
            "child_frame_id": string("Child frame"),
            "translation": vector3_schema("Child origin in the parent frame, m"),
            "rotation": quaternion_schema("Child orientation in the parent frame"),
        }),
    )
}

fn log_schema() -> Vec<u8> {
    object_schema(
        LOG,
        "A log message",
        json!({
            "timestamp": time_schema(),
            "level": integer_enum(
                "Severity",
                &[(0, "UNKNOWN"), (1, "DEBUG"), (2, "INFO"), (3, "WARNING"), (4, "ERROR"), (5, "FATAL")],
            ),
            "message": string("Message"),
            "name": string("Process or node that logged it"),
            "file": string("Source file"),
            "line": { "type": "integer", "minimum": 0, "description": "Source line" },
        }),
    )
}

// ------------------------------------------------------------- channels

/// The GNSS fixes in latitude and longitude, from the local ENU positions
/// and the drive's geodetic origin.
pub(super) struct LocationOut<'a> {
    /// The fixes.
    pub samples: &'a [GnssSample],
    /// The drive's ENU frame.
    pub frame: LocalFrame,
    /// The recording's log-time offset, ns.
    pub offset_ns: u64,
}

impl Outgoing for LocationOut<'_> {
    fn name(&self) -> &'static str {
        "gnss (foxglove.LocationFix)"
    }
    fn topic(&self) -> &'static str {
        LOCATION_TOPIC
    }
    fn schema_name(&self) -> &'static str {
        LOCATION_FIX
    }
    fn schema(&self) -> Vec<u8> {
        location_fix_schema()
    }
    fn times(&self) -> Box<dyn Iterator<Item = f64> + '_> {
        Box::new(self.samples.iter().map(|s| s.t_s))
    }
    fn encode(&self, i: usize, buf: &mut Vec<u8>) -> Option<serde_json::Result<()>> {
        let s = self.samples.get(i)?;
        let (latitude, longitude) = self.frame.from_en(s.x_m, s.y_m);
        // Our sigma is horizontal: east and north; up is unknown (0).
        let (position_covariance, position_covariance_type) = match s.sigma_m {
            Some(sigma) => {
                let v = sigma * sigma;
                (
                    [v, 0.0, 0.0, 0.0, v, 0.0, 0.0, 0.0, 0.0],
                    COVARIANCE_DIAGONAL_KNOWN,
                )
            }
            None => ([0.0; 9], COVARIANCE_UNKNOWN),
        };
        let msg = LocationFix {
            timestamp: Time::from_ns(log_time_ns(s.t_s, self.offset_ns)),
            frame_id: GNSS_FRAME,
            latitude,
            longitude,
            altitude: 0.0,
            position_covariance,
            position_covariance_type,
        };
        Some(serde_json::to_writer(buf, &msg))
    }
}

/// The true poses as `foxglove.PoseInFrame` in [`WORLD_FRAME`].
pub(super) struct TruthPoseOut<'a> {
    /// The true poses.
    pub samples: &'a [TruthSample],
    /// The recording's log-time offset, ns.
    pub offset_ns: u64,
}

impl Outgoing for TruthPoseOut<'_> {
    fn name(&self) -> &'static str {
        "truth (foxglove.PoseInFrame)"
    }
    fn topic(&self) -> &'static str {
        TRUTH_POSE_TOPIC
    }
    fn schema_name(&self) -> &'static str {
        POSE_IN_FRAME
    }
    fn schema(&self) -> Vec<u8> {
        pose_in_frame_schema()
    }
    fn times(&self) -> Box<dyn Iterator<Item = f64> + '_> {
        Box::new(self.samples.iter().map(|s| s.t_s))
    }
    fn encode(&self, i: usize, buf: &mut Vec<u8>) -> Option<serde_json::Result<()>> {
        let s = self.samples.get(i)?;
        let msg = PoseInFrame {
            timestamp: Time::from_ns(log_time_ns(s.t_s, self.offset_ns)),
            frame_id: WORLD_FRAME,
            pose: truth_pose(s),
        };
        Some(serde_json::to_writer(buf, &msg))
    }
}

/// The vehicle frame placed by the true poses: [`WORLD_FRAME`] ->
/// [`BODY_FRAME`], one `foxglove.FrameTransform` per true pose.
pub(super) struct TruthTransformOut<'a> {
    /// The true poses.
    pub samples: &'a [TruthSample],
    /// The recording's log-time offset, ns.
    pub offset_ns: u64,
}

impl Outgoing for TruthTransformOut<'_> {
    fn name(&self) -> &'static str {
        "truth (foxglove.FrameTransform)"
    }
    fn topic(&self) -> &'static str {
        TF_TOPIC
    }
    fn schema_name(&self) -> &'static str {
        FRAME_TRANSFORM
    }
    fn schema(&self) -> Vec<u8> {
        frame_transform_schema()
    }
    fn times(&self) -> Box<dyn Iterator<Item = f64> + '_> {
        Box::new(self.samples.iter().map(|s| s.t_s))
    }
    fn encode(&self, i: usize, buf: &mut Vec<u8>) -> Option<serde_json::Result<()>> {
        let s = self.samples.get(i)?;
        let pose = truth_pose(s);
        let msg = FrameTransform {
            timestamp: Time::from_ns(log_time_ns(s.t_s, self.offset_ns)),
            parent_frame_id: WORLD_FRAME,
            child_frame_id: BODY_FRAME,
            translation: pose.position,
            rotation: pose.orientation,
        };
        Some(serde_json::to_writer(buf, &msg))
    }
}

/// Warnings as `foxglove.Log` messages, all at one time (the drive's start).
pub(super) struct LogOut<'a> {
    /// The warnings.
    pub messages: &'a [String],
    /// Their time on the drive's clock, s.
    pub t_s: f64,
    /// The recording's log-time offset, ns.
    pub offset_ns: u64,
}

impl Outgoing for LogOut<'_> {
    fn name(&self) -> &'static str {
        "warnings (foxglove.Log)"
    }
    fn topic(&self) -> &'static str {
        LOG_TOPIC
    }
    fn schema_name(&self) -> &'static str {
        LOG
    }
    fn schema(&self) -> Vec<u8> {
        log_schema()
    }
    fn times(&self) -> Box<dyn Iterator<Item = f64> + '_> {
        Box::new(self.messages.iter().map(|_| self.t_s))
    }
    fn encode(&self, i: usize, buf: &mut Vec<u8>) -> Option<serde_json::Result<()>> {
        let message = self.messages.get(i)?;
        let msg = Log {
            timestamp: Time::from_ns(log_time_ns(self.t_s, self.offset_ns)),
            level: LEVEL_WARNING,
            message,
            name: "wheelcal",
            file: "",
            line: 0,
        };
        Some(serde_json::to_writer(buf, &msg))
    }
}

/// The odometry's served poses as `foxglove.PoseInFrame` in [`WORLD_FRAME`].
pub(super) struct ServedPoseOut<'a> {
    /// The poses.
    pub samples: &'a [ServedPose],
    /// The recording's log-time offset, ns.
    pub offset_ns: u64,
}

impl Outgoing for ServedPoseOut<'_> {
    fn name(&self) -> &'static str {
        "served poses (foxglove.PoseInFrame)"
    }
    fn topic(&self) -> &'static str {
        SERVED_POSE_TOPIC
    }
    fn schema_name(&self) -> &'static str {
        POSE_IN_FRAME
    }
    fn schema(&self) -> Vec<u8> {
        pose_in_frame_schema()
    }
    fn times(&self) -> Box<dyn Iterator<Item = f64> + '_> {
        Box::new(self.samples.iter().map(|s| s.t_s))
    }
    fn encode(&self, i: usize, buf: &mut Vec<u8>) -> Option<serde_json::Result<()>> {
        let s = self.samples.get(i)?;
        let msg = PoseInFrame {
            timestamp: Time::from_ns(log_time_ns(s.t_s, self.offset_ns)),
            frame_id: WORLD_FRAME,
            pose: Pose {
                position: Vector3 {
                    x: s.x_m,
                    y: s.y_m,
                    z: 0.0,
                },
                orientation: Quaternion::yaw(Some(s.yaw_rad)),
            },
        };
        Some(serde_json::to_writer(buf, &msg))
    }
}

/// The odometry's served poses in latitude and longitude, from the local
/// ENU positions and the drive's geodetic origin; the position covariance
/// from the pose's (east, north; up unknown).
pub(super) struct ServedLocationOut<'a> {
    /// The poses.
    pub samples: &'a [ServedPose],
    /// The drive's ENU frame.
    pub frame: LocalFrame,
    /// The recording's log-time offset, ns.
    pub offset_ns: u64,
}

/// `position_covariance_type` with the full covariance (KNOWN).
const COVARIANCE_KNOWN: u8 = 3;

impl Outgoing for ServedLocationOut<'_> {
    fn name(&self) -> &'static str {
        "served poses (foxglove.LocationFix)"
    }
    fn topic(&self) -> &'static str {
        SERVED_LOCATION_TOPIC
    }
    fn schema_name(&self) -> &'static str {
        LOCATION_FIX
    }
    fn schema(&self) -> Vec<u8> {
        location_fix_schema()
    }
    fn times(&self) -> Box<dyn Iterator<Item = f64> + '_> {
        Box::new(self.samples.iter().map(|s| s.t_s))
    }
    fn encode(&self, i: usize, buf: &mut Vec<u8>) -> Option<serde_json::Result<()>> {
        let s = self.samples.get(i)?;
        let (latitude, longitude) = self.frame.from_en(s.x_m, s.y_m);
        let c = &s.covariance;
        let msg = LocationFix {
            timestamp: Time::from_ns(log_time_ns(s.t_s, self.offset_ns)),
            frame_id: BODY_FRAME,
            latitude,
            longitude,
            altitude: 0.0,
            position_covariance: [c[0], c[1], 0.0, c[3], c[4], 0.0, 0.0, 0.0, 0.0],
            position_covariance_type: COVARIANCE_KNOWN,
        };
        Some(serde_json::to_writer(buf, &msg))
    }
}
