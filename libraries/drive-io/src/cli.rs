//! The command-line options of every command that reads a drive
//! (`calibrator calibrate`/`diagnose`, `odometry evaluate`, `sensor-bridge
//! convert`/`info`/`replay`): one group flattened into each, turned into
//! [`ReadOptions`] by [`ReadOptions::from_sources`]. Built with the `cli`
//! feature (it needs `clap`).

use crate::{read_drive_with, DriveError, LoadedDrive, ReadOptions};
use clap::Args;
use std::path::{Path, PathBuf};

/// What a drive may lack: vehicle parameters and, for a ROS 2 bag, which
/// topic is which stream.
#[derive(Args, Debug, Clone, Default)]
pub struct DriveInput {
    /// Vehicle parameters (a vehicle.toml, or a drive to take them from):
    /// required for a ROS 2 bag; for a drive folder or recording they
    /// replace its own.
    #[arg(long, value_name = "PATH")]
    pub vehicle: Option<PathBuf>,
    /// ROS 2 bag: read TOPIC as ROLE (gnss, imu, wheels), or name a wheel
    /// joint of a JointState topic (joints.rl=NAME, rr, fl, fr). Repeatable;
    /// a role not given is chosen by message type.
    #[arg(long = "topic", value_name = "ROLE=TOPIC")]
    pub topic: Vec<String>,
    /// ROS 2 bag: a TOML file of `role = "topic"` lines (and a [joints]
    /// table); --topic refines it.
    #[arg(long, value_name = "FILE")]
    pub topics: Option<PathBuf>,
}

impl DriveInput {
    /// The read options these arguments ask for (the vehicle file's
    /// warnings go to the log).
    pub fn options(&self, skip_corrupt_chunks: bool) -> Result<ReadOptions, DriveError> {
        let (options, warnings) = ReadOptions::from_sources(
            skip_corrupt_chunks,
            self.vehicle.as_deref(),
            self.topics.as_deref(),
            &self.topic,
            "--topic",
        )?;
        for w in &warnings {
            tracing::warn!("{w}");
        }
        Ok(options)
    }

    /// Read the drive at `path` with these arguments: the outer error is
    /// the options' (a --vehicle or --topics file), the inner the drive's.
    pub fn read(
        &self,
        path: &Path,
        skip_corrupt_chunks: bool,
    ) -> Result<Result<LoadedDrive, DriveError>, DriveError> {
        Ok(read_drive_with(path, self.options(skip_corrupt_chunks)?))
    }
}

/// A read drive, or with `allow_truncated` what a truncated MCAP recording
/// held before its damage (a warning in the drive's own warnings names the
/// damage); a truncated recording without `allow_truncated` is an error that
/// says the option exists.
pub fn accept_truncated(
    read: Result<LoadedDrive, DriveError>,
    allow_truncated: bool,
) -> anyhow::Result<LoadedDrive> {
    match read {
        Err(DriveError::TruncatedMcap {
            partial: Some(partial),
            path,
            offset,
            file_len,
            record,
            messages_read,
        }) => {
            let damage = DriveError::TruncatedMcap {
                path,
                offset,
                file_len,
                record,
                messages_read,
                partial: None,
            };
            if allow_truncated {
                let mut loaded = *partial;
                loaded.warnings.push(format!(
                    "{damage}: --allow-truncated: only what was read before the damage is used"
                ));
                Ok(loaded)
            } else {
                Err(anyhow::Error::new(damage).context(
                    "the recording is truncated; --allow-truncated uses what was read before the damage",
                ))
            }
        }
        other => Ok(other?),
    }
}
