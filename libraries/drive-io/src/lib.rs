//! Drives in and out: the drive folder (`shared/design/drive-format.md`), the
//! native MCAP recording, and the `info` summary.
//!
//! Other tools' recordings read as drives too: an MCAP with `zstd` or `lz4`
//! chunks, a ROS 2 bag (rosbag2's MCAP; [`ReadOptions::vehicle`] and
//! [`ReadOptions::topics`] say what it lacks), and an NMEA 0183 log as the
//! GNSS stream of a drive folder (`gnss.nmea` in place of `gnss.csv`).
//! `docs/drive-format.md` ("Recordings from other tools") says how each maps onto a drive.
//!
//! [`read_drive`] takes any of them (auto-detected); [`write_drive`] picks the
//! format from the path (`*.mcap` is MCAP, anything else a folder). Both keep
//! every value bit-identical, so a round trip through either format gives back
//! an equal [`Drive`].
//!
//! [`read_estimate`] reads the calibrator's estimate file; [`dev_data`] locates the real drives beside the repository for tests and
//! benchmarks.

#[cfg(feature = "cli")]
pub mod cli;
mod csv;
pub mod dev_data;
mod error;
mod estimate_file;
mod files;
mod folder;
pub mod geodesy;
mod info;
mod nmea;
pub mod plausibility;
mod recording;
mod streams;
mod topic_map;

pub use csv::MAX_CSV_LINE_BYTES;
pub use error::DriveError;
pub use estimate_file::{read_estimate, read_estimate_with_vehicle};
pub use files::{read_state_text, write_durably, MAX_TEXT_FILE_BYTES};
pub use info::{summarize, DriveSummary, GapSummary, StreamSummary, GAP_FACTOR, GNSS_OUTAGE_MIN_S};
pub use nmea::{parse_nmea, read_nmea, NmeaFix, NmeaLog, NMEA_FILE};
pub use recording::{
    ServedEstimate, ServedPose, ESTIMATE_SCHEMA, ESTIMATE_TOPIC, FORMAT_MAGIC, FORMAT_VERSION,
    FOXGLOVE_BODY_FRAME, FOXGLOVE_GNSS_FRAME, FOXGLOVE_LOCATION_TOPIC, FOXGLOVE_LOG_TOPIC,
    FOXGLOVE_SERVED_LOCATION_TOPIC, FOXGLOVE_SERVED_POSE_TOPIC, FOXGLOVE_TF_TOPIC,
    FOXGLOVE_TRUTH_POSE_TOPIC, FOXGLOVE_WORLD_FRAME, GNSS_TOPIC, HEADING_TOPIC, IMU_TOPIC,
    MAX_CHUNK_RECORDS_BYTES, POSE_SCHEMA, POSE_TOPIC, SERVED_SCHEMA_PREFIX, TRUTH_TOPIC,
    WHEELS_TOPIC,
};
pub use topic_map::{Role, TopicMap};

use interfaces::drive::{Drive, VehicleParams};
use std::path::Path;

/// A drive read from disk, with the warnings its reading produced (skipped
/// rows, ignored columns, ...). Nothing is dropped without a warning here.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadedDrive {
    /// The drive.
    pub drive: Drive,
    /// Human-readable warnings, each naming the file or channel.
    pub warnings: Vec<String>,
}

/// Read a drive folder or an MCAP recording (detected from what `path` is:
/// a directory is a drive folder, a file starting with the MCAP magic is a
/// recording: ours, compressed or not, or a ROS 2 bag, which needs
/// [`read_drive_with`] and a vehicle; a rosbag2 folder, with its
/// `metadata.yaml` and one `.mcap` file, is read as that file).
///
/// A truncated MCAP gives [`DriveError::TruncatedMcap`], which carries the
/// drive as far as it could be read. An MCAP chunk whose records fail
/// their CRC is [`DriveError::ChunkCrc`] (see [`read_drive_with`] to skip
/// it instead). Anything that is neither a directory nor a regular file
/// (a FIFO, a device, a broken link) is [`DriveError::NotAFile`].
pub fn read_drive(path: &Path) -> Result<LoadedDrive, DriveError> {
    read_drive_with(path, ReadOptions::default())
}

/// How [`read_drive_with`] treats a damaged recording, and what it gives
/// a recording that lacks it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReadOptions {
    /// Recovery: leave out an MCAP chunk whose records fail their CRC (a
    /// warning names each one, its index and byte offset) and accept a
    /// data section CRC mismatch with a warning, instead of failing with
    /// [`DriveError::ChunkCrc`] / [`DriveError::DataSectionCrc`]. Off by
    /// default: a changed byte is never read silently.
    pub skip_corrupt_chunks: bool,
    /// Vehicle parameters: required for a ROS 2 bag (it has none,
    /// [`DriveError::NoVehicle`]); for a drive folder they stand in for
    /// its `vehicle.toml` (which then need not exist), for our recording
    /// they replace the recorded ones (its ENU origin kept when these have
    /// none). Either replacement is a warning.
    pub vehicle: Option<VehicleParams>,
    /// ROS 2 bag: which topic is which stream (empty: chosen by type).
    pub topics: TopicMap,
}

impl ReadOptions {
    /// Options from what a command line gives: recovery, a vehicle file
    /// (a `vehicle.toml`, or a drive to take it from, as [`read_vehicle`]
    /// reads it), a topic-map TOML file and `role=topic` assignments over
    /// it (`origin` names them in errors, e.g. `--topic`). The vehicle's
    /// warnings are returned.
    pub fn from_sources(
        skip_corrupt_chunks: bool,
        vehicle: Option<&Path>,
        topics_file: Option<&Path>,
        topic_assignments: &[String],
        origin: &str,
    ) -> Result<(ReadOptions, Vec<String>), DriveError> {
        let (vehicle, warnings) = match vehicle {
            Some(p) => {
                let loaded = read_vehicle(p)?;
                (Some(loaded.vehicle), loaded.warnings)
            }
            None => (None, Vec::new()),
        };
        let topics = TopicMap::from_sources(topics_file, topic_assignments, origin)?;
        Ok((
            ReadOptions {
                skip_corrupt_chunks,
                vehicle,
                topics,
            },
            warnings,
        ))
    }
}

/// Put `given` in place of a loaded drive's vehicle, keeping the drive's
/// ENU origin when `given` has none (its positions are relative to it).
pub(crate) fn replace_vehicle(path: &Path, loaded: &mut LoadedDrive, given: &VehicleParams) {
    let old = &loaded.drive.vehicle;
    let mut vehicle = given.clone();
    if vehicle.gnss.origin_lat_deg.is_none() {
        vehicle.gnss.origin_lat_deg = old.gnss.origin_lat_deg;
        vehicle.gnss.origin_lon_deg = old.gnss.origin_lon_deg;
    }
    if vehicle != *old {
        loaded.warnings.push(format!(
            "{}: the vehicle parameters given replace the drive's own",
            path.display()
        ));
    }
    loaded.drive.vehicle = vehicle;
}

/// [`read_drive`] with explicit [`ReadOptions`].
pub fn read_drive_with(path: &Path, options: ReadOptions) -> Result<LoadedDrive, DriveError> {
    let meta = std::fs::metadata(path).map_err(|e| match e.kind() {
        // A broken symbolic link: say so rather than "not found".
        std::io::ErrorKind::NotFound if std::fs::symlink_metadata(path).is_ok() => {
            DriveError::NotAFile {
                path: path.to_path_buf(),
                what: files::describe(path),
            }
        }
        _ => DriveError::io(path, e),
    })?;
    if meta.is_dir() {
        if let Some(bag) = rosbag2_file(path)? {
            let bytes = files::read_regular(&bag)?;
            return recording::read_mcap_bytes(&bag, &bytes, &options);
        }
        return folder::read_folder(path, options.vehicle.as_ref());
    }
    let bytes = files::read_regular(path)?;
    if bytes.starts_with(mcap::MAGIC) {
        recording::read_mcap_bytes(path, &bytes, &options)
    } else {
        Err(DriveError::UnknownFormat {
            path: path.to_path_buf(),
            reason: "a file without the MCAP magic bytes".to_string(),
        })
    }
}

/// The MCAP file of a rosbag2 folder (`metadata.yaml` and one `*.mcap`,
/// no `wheels.csv`); `None` for any other folder. A bag split into several
/// files is refused.
fn rosbag2_file(dir: &Path) -> Result<Option<std::path::PathBuf>, DriveError> {
    if !dir.join("metadata.yaml").is_file() || dir.join("wheels.csv").exists() {
        return Ok(None);
    }
    let mut found: Vec<std::path::PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| DriveError::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| is_mcap_path(p))
        .collect();
    found.sort();
    match found.len() {
        0 => Ok(None),
        1 => Ok(found.pop()),
        n => Err(DriveError::UnknownFormat {
            path: dir.to_path_buf(),
            reason: format!(
                "a rosbag2 folder split into {n} MCAP files; give one file (a drive is read from one)"
            ),
        }),
    }
}

/// Vehicle parameters read for a service, with the warnings their reading
/// produced (unknown keys, rows skipped in the drive).
#[derive(Debug, Clone, PartialEq)]
pub struct LoadedVehicle {
    /// The parameters.
    pub vehicle: VehicleParams,
    /// Human-readable warnings, each naming the file.
    pub warnings: Vec<String>,
}

/// Vehicle parameters from a `vehicle.toml` file (any `*.toml`), or from a
/// drive folder or recording (what [`read_drive`] gives as the drive's
/// vehicle, the ENU origin derived from the first fix included; a truncated
/// recording's vehicle is as good as a whole one's). A `*.toml` is checked
/// as a drive's `vehicle.toml` is: unknown keys are a warning, a non-finite
/// value is an error naming the key; it must be a regular file of at most
/// [`MAX_TEXT_FILE_BYTES`].
pub fn read_vehicle(path: &Path) -> Result<LoadedVehicle, DriveError> {
    let is_toml = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    if is_toml && !path.is_dir() {
        let text = files::read_text_limited(path, MAX_TEXT_FILE_BYTES)?;
        let mut warnings = Vec::new();
        let vehicle = folder::parse_vehicle_toml(path, &text, &mut warnings)?;
        return Ok(LoadedVehicle { vehicle, warnings });
    }
    let loaded = match read_drive(path) {
        Ok(loaded) => loaded,
        Err(DriveError::TruncatedMcap {
            partial: Some(partial),
            ..
        }) => *partial,
        Err(e) => return Err(e),
    };
    Ok(LoadedVehicle {
        vehicle: loaded.drive.vehicle,
        warnings: loaded.warnings,
    })
}

/// Write a drive: as an MCAP recording when `path` ends in `.mcap` (any case),
/// otherwise as a drive folder (created if needed).
///
/// Writing a folder replaces the drive-format files in it and removes those
/// of them the drive does not have (e.g. a stale `heading.csv`), so the folder
/// reads back as exactly this drive. Other files are left alone.
///
/// The drive is checked first: every value finite, times strictly increasing,
/// `ticks_per_rev` present for `_ticks` wheels; otherwise
/// [`DriveError::InvalidDrive`] and nothing is written.
pub fn write_drive(drive: &Drive, path: &Path) -> Result<(), DriveError> {
    write_drive_with(drive, path, &WriteOptions::default())
}

/// What [`write_drive_with`] adds to an MCAP recording (a drive folder
/// ignores these). The default adds nothing: [`write_drive`]'s recording.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WriteOptions {
    /// Also write channels in Foxglove's well-known schemas, derived from
    /// the drive's own, so that Foxglove's panels show the recording:
    /// [`FOXGLOVE_LOCATION_TOPIC`] (`foxglove.LocationFix`, the GNSS fixes
    /// in lat/lon; only when the drive has a geodetic origin, i.e. came
    /// from lat/lon), [`FOXGLOVE_TRUTH_POSE_TOPIC`] (`foxglove.PoseInFrame`
    /// in [`FOXGLOVE_WORLD_FRAME`]) and [`FOXGLOVE_TF_TOPIC`]
    /// (`foxglove.FrameTransform` to [`FOXGLOVE_BODY_FRAME`]) from the
    /// truth, and [`FOXGLOVE_LOG_TOPIC`] (`foxglove.Log`) from
    /// [`WriteOptions::warnings`]. Their time stamps are the log times. The
    /// reader ignores them: the drive reads back the same either way.
    pub foxglove: bool,
    /// Warnings to record as `foxglove.Log` messages (level WARNING, at the
    /// drive's earliest time), e.g. those of loading the drive; only with
    /// [`WriteOptions::foxglove`].
    pub warnings: Vec<String>,
    /// Poses the odometry served while the drive was recorded, written on
    /// [`POSE_TOPIC`] (and, with [`WriteOptions::foxglove`], as
    /// `foxglove.PoseInFrame` on [`FOXGLOVE_SERVED_POSE_TOPIC`] and, where
    /// the drive has a geodetic origin, `foxglove.LocationFix` on
    /// [`FOXGLOVE_SERVED_LOCATION_TOPIC`]). The reader leaves them out.
    pub poses: Vec<ServedPose>,
    /// Estimates the calibrator served, written on [`ESTIMATE_TOPIC`]. The
    /// reader leaves them out.
    pub estimates: Vec<ServedEstimate>,
}

/// [`write_drive`] with [`WriteOptions`].
pub fn write_drive_with(
    drive: &Drive,
    path: &Path,
    options: &WriteOptions,
) -> Result<(), DriveError> {
    validate(drive)?;
    if is_mcap_path(path) {
        recording::write_mcap(drive, path, options)
    } else {
        folder::write_folder(drive, path)
    }
}

/// True when `path` names an MCAP file (extension `mcap`, any case).
pub fn is_mcap_path(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap"))
}

/// Check that a drive can be written and read back unchanged.
pub fn validate(drive: &Drive) -> Result<(), DriveError> {
    validate::drive(drive)
}

mod validate;

/// [`read_drive_with`] on an MCAP recording already in memory (the fuzz
/// targets' entry): `path` only names the input in errors and warnings.
pub fn read_mcap_from_bytes(
    path: &Path,
    bytes: &[u8],
    options: ReadOptions,
) -> Result<LoadedDrive, DriveError> {
    recording::read_mcap_bytes(path, bytes, &options)
}

/// [`read_vehicle`] on `vehicle.toml` text already in memory (the fuzz
/// targets' entry): `path` only names the input in errors and warnings.
pub fn vehicle_from_toml_str(path: &Path, text: &str) -> Result<LoadedVehicle, DriveError> {
    let mut warnings = Vec::new();
    let vehicle = folder::parse_vehicle_toml(path, text, &mut warnings)?;
    Ok(LoadedVehicle { vehicle, warnings })
}

/// `truth.toml` text parsed as a drive folder's is (the fuzz targets'
/// entry): `path` only names the input in errors.
pub fn truth_from_toml_str(
    path: &Path,
    text: &str,
) -> Result<interfaces::drive::TruthParams, DriveError> {
    folder::parse_truth_toml(path, text)
}
