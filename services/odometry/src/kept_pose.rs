//! The pose `odometry serve --pose-state` keeps across power cycles, as its
//! JSON file holds it ([`SavedPose`]); reading and writing the file is the
//! binary's (`pose_state`), judging it at a restart is [`crate::restart`]'s.
//! Pure: text in, a pose out.

use crate::fusion::FusedPose;
use crate::restart::{KeptRecord, WheelMark};
use interfaces::wire::PoseMode;
use serde::{Deserialize, Serialize};
use vehicle_model::two_wheel::Pose2;

/// A pose as the state file keeps it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SavedPose {
    /// Drive time of the pose in the run that saved it, s.
    pub t_s: f64,
    /// East, m.
    pub x_m: f64,
    /// North, m.
    pub y_m: f64,
    /// Yaw, rad (0 = east, counter-clockwise).
    pub yaw_rad: f64,
    /// Covariance of (x, y, yaw), row-major.
    pub covariance: [f64; 9],
    /// What the pose stood on: `Fused` or `DeadReckoning`.
    pub mode: String,
    /// Version of the estimate in use then (0 = nominal).
    pub estimate_version: u64,
    /// The GNSS antenna position the filter used then (body x, y from the
    /// rear-axle centre, m): the pose is the rear axle's for that antenna. A
    /// service that starts from the pose takes this antenna too, unless
    /// `vehicle.toml` gives a measured one. Absent in files written before it.
    #[serde(default)]
    pub gnss_antenna_m: Option<[f64; 2]>,
    /// The rear wheels' cumulative revolutions (left, right) at the pose's
    /// wheel sample. Absent in files written before it.
    #[serde(default)]
    pub wheel_rev: Option<[f64; 2]>,
    /// Speed of the rear-axle centre at the pose, m/s. Absent in files
    /// written before it.
    #[serde(default)]
    pub speed_m_s: Option<f64>,
    /// Written when the service stopped (a clean stop, stale inputs), not
    /// periodically while it ran.
    #[serde(default)]
    pub last_word: bool,
    /// How often the service wrote the file while it ran, s.
    #[serde(default)]
    pub write_every_s: Option<f64>,
}

impl SavedPose {
    /// The pose to keep from a filter output and the antenna position the
    /// filter used for it; `None` for a `NoFix` pose, which has no position.
    pub fn from_fused(pose: &FusedPose, gnss_antenna_m: [f64; 2]) -> Option<SavedPose> {
        let mode = match pose.mode {
            PoseMode::NoFix => return None,
            PoseMode::Fused => "Fused",
            PoseMode::DeadReckoning => "DeadReckoning",
        };
        Some(SavedPose {
            t_s: pose.t_s,
            x_m: pose.pose.x,
            y_m: pose.pose.y,
            yaw_rad: pose.pose.yaw,
            covariance: pose.covariance,
            mode: mode.to_string(),
            estimate_version: pose.estimate_version,
            gnss_antenna_m: Some(gnss_antenna_m),
            wheel_rev: None,
            speed_m_s: None,
            last_word: false,
            write_every_s: None,
        })
    }

    /// What [`odometry::restart::judge_restart`] judges; a file without
    /// `write_every_s` is taken as written every `default_every_s`.
    pub fn record(&self, default_every_s: f64) -> KeptRecord {
        KeptRecord {
            pose: self.pose(),
            covariance: self.covariance,
            wheels: self.wheel_rev.map(|[rl_rev, rr_rev]| WheelMark {
                t_s: self.t_s,
                rl_rev,
                rr_rev,
            }),
            speed_m_s: self.speed_m_s,
            last_word: self.last_word,
            write_every_s: self.write_every_s.unwrap_or(default_every_s),
        }
    }

    /// Position and yaw.
    pub fn pose(&self) -> Pose2 {
        Pose2 {
            x: self.x_m,
            y: self.y_m,
            yaw: self.yaw_rad,
        }
    }
}

impl SavedPose {
    /// Parse the file's text (JSON); the error names the line and column.
    /// JSON cannot hold NaN or infinity, so every number that parses is
    /// finite; a number too large for a float is an error, not infinity.
    pub fn from_json(text: &str) -> Result<SavedPose, String> {
        serde_json::from_str(text).map_err(|e| e.to_string())
    }
}
