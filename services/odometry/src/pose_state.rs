//! The last pose, kept across power cycles (`odometry serve --pose-state FILE`).
//!
//! A car parked in a garage powers on where it was switched off, without
//! GNSS. The service writes its last pose with a position (`Fused` or
//! `DeadReckoning`) to a small JSON file, and a new service starts from it
//! ([`odometry::fusion::Fusion::resume`]). The file is replaced atomically (a
//! temporary file renamed over it), so a crash never leaves half a pose.

use interfaces::wire::PoseMode;
use odometry::fusion::FusedPose;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
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
        })
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

/// A state file that cannot be read or written.
#[derive(Debug, thiserror::Error)]
pub enum PoseStateError {
    /// Reading or writing failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Not a kept pose (JSON cannot hold NaN or infinity, so every number
    /// that parses is finite).
    #[error("{path}: {detail}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// What is wrong, with its line and column.
        detail: String,
    },
}

/// Read the kept pose; `Ok(None)` when the file does not exist yet.
pub fn load(path: &Path) -> Result<Option<SavedPose>, PoseStateError> {
    let text = match std::fs::read_to_string(path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(source) => {
            return Err(PoseStateError::Io {
                path: path.to_path_buf(),
                source,
            })
        }
    };
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| PoseStateError::Parse {
            path: path.to_path_buf(),
            detail: e.to_string(),
        })
}

/// Write the kept pose: to `FILE.tmp`, then renamed over `FILE`.
pub fn save(path: &Path, saved: &SavedPose) -> Result<(), PoseStateError> {
    let io = |source| PoseStateError::Io {
        path: path.to_path_buf(),
        source,
    };
    let text = serde_json::to_string_pretty(saved)
        .map_err(|e| io(std::io::Error::new(std::io::ErrorKind::InvalidData, e)))?;
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    std::fs::write(&tmp, text + "\n").map_err(io)?;
    std::fs::rename(&tmp, path).map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fused(mode: PoseMode) -> FusedPose {
        FusedPose {
            t_s: 12.5,
            pose: Pose2 {
                x: 10.0,
                y: -2.0,
                yaw: 0.5,
            },
            covariance: [0.01, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 1e-4],
            mode,
            estimate_version: 3,
        }
    }

    #[test]
    fn a_kept_pose_reads_back_and_a_missing_file_is_none() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("pose.json");
        assert_eq!(load(&path).unwrap(), None);
        assert_eq!(
            SavedPose::from_fused(&fused(PoseMode::NoFix), [0.0; 2]),
            None
        );
        let saved = SavedPose::from_fused(&fused(PoseMode::DeadReckoning), [0.5, -0.3]).unwrap();
        save(&path, &saved).unwrap();
        assert_eq!(load(&path).unwrap(), Some(saved.clone()));
        assert_eq!(saved.mode, "DeadReckoning");
        assert_eq!(saved.pose().yaw, 0.5);
        // Replaced whole, no temporary file left.
        let newer = SavedPose { x_m: 11.0, ..saved };
        save(&path, &newer).unwrap();
        assert_eq!(load(&path).unwrap().unwrap().x_m, 11.0);
        assert!(!dir.path().join("pose.json.tmp").exists());
        assert_eq!(
            load(&path).unwrap().unwrap().gnss_antenna_m,
            Some([0.5, -0.3])
        );
        // A file from before the antenna field reads without it.
        let old = serde_json::to_string(&newer)
            .unwrap()
            .replace("\"gnss_antenna_m\"", "\"unknown\"");
        std::fs::write(&path, old).unwrap();
        assert_eq!(load(&path).unwrap().unwrap().gnss_antenna_m, None);
    }

    #[test]
    fn a_bad_state_file_is_named_with_its_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("pose.json");
        std::fs::write(&path, "{\n  \"t_s\": 1.0,\n  \"x_m\": \"east\"\n}\n").unwrap();
        let e = load(&path).unwrap_err().to_string();
        assert!(e.contains("pose.json: invalid type"), "{e}");
        assert!(e.contains("line 3"), "{e}");
        // A number too large for a float is not taken as infinity.
        let saved = SavedPose::from_fused(&fused(PoseMode::Fused), [0.0; 2]).unwrap();
        let text = serde_json::to_string(&saved)
            .unwrap()
            .replace("\"y_m\":-2.0", "\"y_m\":1e999");
        std::fs::write(&path, text).unwrap();
        let e = load(&path).unwrap_err().to_string();
        assert!(e.contains("pose.json: number out of range"), "{e}");
    }
}
