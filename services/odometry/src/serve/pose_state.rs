//! The last pose, kept across power cycles (`odometry serve --pose-state FILE`).
//!
//! A car parked in a garage powers on where it was switched off, without
//! GNSS. The service writes its last pose with a position (`Fused` or
//! `DeadReckoning`) to a small JSON file, and a new service starts from it
//! ([`odometry::fusion::Fusion::resume`]) when [`odometry::restart`] judges
//! it can: the file keeps the rear wheels' counts, the drive time and the
//! speed at the pose, and whether it was the service's last word, so that a
//! car that moved while the service was down is not placed where it was.
//!
//! Written the way a power loss cannot corrupt and another local user cannot
//! redirect: a fresh temporary file beside it (created exclusively, so an
//! existing file or a planted symlink of that name is never followed or
//! overwritten; readable by the owner only), fsynced, renamed over the file,
//! and the directory fsynced. Read only when it is a regular file of at most
//! [`MAX_STATE_BYTES`].

pub use odometry::kept_pose::SavedPose;
use std::path::{Path, PathBuf};

/// The largest state file read, bytes (a kept pose is about 600).
pub const MAX_STATE_BYTES: u64 = 64 * 1024;

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

/// Read the kept pose; `Ok(None)` when the file does not exist yet. Anything
/// but a regular file, or one larger than [`MAX_STATE_BYTES`], is an error
/// naming it (a FIFO is never opened: that would block).
pub fn load(path: &Path) -> Result<Option<SavedPose>, PoseStateError> {
    let text =
        drive_io::read_state_text(path, MAX_STATE_BYTES).map_err(|e| PoseStateError::Parse {
            path: path.to_path_buf(),
            detail: e.to_string(),
        })?;
    let Some(text) = text else {
        return Ok(None);
    };
    SavedPose::from_json(&text)
        .map(Some)
        .map_err(|detail| PoseStateError::Parse {
            path: path.to_path_buf(),
            detail,
        })
}

/// Write the kept pose durably ([`drive_io::write_durably`]: a fresh 0600
/// temporary file, fsynced, renamed over `path`, the directory fsynced).
pub fn save(path: &Path, saved: &SavedPose) -> Result<(), PoseStateError> {
    let io = |source| PoseStateError::Io {
        path: path.to_path_buf(),
        source,
    };
    let text = serde_json::to_string_pretty(saved)
        .map_err(|e| io(std::io::Error::new(std::io::ErrorKind::InvalidData, e)))?;
    drive_io::write_durably(path, (text + "\n").as_bytes()).map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::wire::PoseMode;
    use odometry::fusion::FusedPose;
    use vehicle_model::two_wheel::Pose2;

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
        let leftovers: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(leftovers, vec![std::ffi::OsString::from("pose.json")]);
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

    #[test]
    fn the_file_is_replaced_safely_and_only_a_small_regular_file_is_read() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("pose.json");
        let saved = SavedPose::from_fused(&fused(PoseMode::Fused), [0.0; 2]).unwrap();
        // A symlink planted where the old fixed temporary name was, and one
        // at the file itself: neither target is written through.
        let victim = dir.path().join("victim");
        std::fs::write(&victim, "keep me").unwrap();
        std::os::unix::fs::symlink(&victim, dir.path().join("pose.json.tmp")).unwrap();
        std::os::unix::fs::symlink(&victim, &path).unwrap();
        save(&path, &saved).unwrap();
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep me");
        let meta = std::fs::symlink_metadata(&path).unwrap();
        assert!(
            meta.file_type().is_file(),
            "the link is replaced, not followed"
        );
        assert_eq!(meta.permissions().mode() & 0o777, 0o600);
        assert_eq!(load(&path).unwrap(), Some(saved.clone()));
        // A directory, a device and an oversized file are named as such.
        let sub = dir.path().join("sub");
        std::fs::create_dir(&sub).unwrap();
        let e = load(&sub).unwrap_err().to_string();
        assert!(
            e.contains("sub: expected a regular file, found a directory"),
            "{e}"
        );
        let zero = dir.path().join("zero");
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        let e = load(&zero).unwrap_err().to_string();
        assert!(
            e.contains("a symbolic link to /dev/zero (a character device)"),
            "{e}"
        );
        let big = dir.path().join("big.json");
        std::fs::write(&big, vec![b' '; MAX_STATE_BYTES as usize + 1]).unwrap();
        let e = load(&big).unwrap_err().to_string();
        assert!(e.contains("more than the 65536 bytes allowed"), "{e}");
        // A write into a directory that does not exist fails and leaves nothing.
        let nowhere = dir.path().join("missing").join("pose.json");
        assert!(save(&nowhere, &saved).is_err());
    }
}
