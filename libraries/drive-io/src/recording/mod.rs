//! The native recording: an MCAP file with JSON messages described by JSON
//! schemas, one channel per sensor stream named after its iceoryx2 service,
//! so that Foxglove and PlotJuggler open it as it is.
//!
//! Layout (see the crate README for the user-facing description):
//! - metadata `wheelcal.drive`: `format` = [`FORMAT_MAGIC`], `format_version`
//!   = [`FORMAT_VERSION`], `tool`, `tool_version`, `wheel_units`,
//!   `log_time_offset_ns`; metadata `wheelcal.vehicle` (`vehicle.toml`);
//!   metadata `wheelcal.truth` (`truth.toml`, simulated drives only). They
//!   come first in the file so that a truncated recording still has them.
//! - channels [`WHEELS_TOPIC`], [`GNSS_TOPIC`], [`IMU_TOPIC`],
//!   [`HEADING_TOPIC`], [`TRUTH_TOPIC`], present exactly when the drive has
//!   the stream (possibly with zero messages).
//! - every message is a JSON object holding the exact `t_s` (shortest
//!   round-trip float text) and the values under their drive-folder column
//!   names; a missing optional value is an absent key.
//! - `log_time` = `publish_time` = round(t_s · 1e9) + `log_time_offset_ns`,
//!   where the offset is the smallest whole number of nanoseconds that makes
//!   the earliest time of the drive non-negative (0 when no time is
//!   negative). Readers use `t_s`; `log_time` only orders the playback.
//! - optionally ([`crate::WriteOptions::foxglove`]), channels in Foxglove's
//!   well-known schemas derived from the above ([`foxglove`]): GNSS in
//!   lat/lon, true poses and transforms, warnings. Readers ignore every
//!   channel whose schema name starts with `foxglove.`.
//! - chunks are uncompressed, so a truncated file can be read up to the
//!   damage, chunk contents included. The reader also takes `zstd` and
//!   `lz4` chunks (the same recording compressed by another tool reads the
//!   same), and ROS 2 bags ([`ros2`]).
//!
//! Jobs: [`messages`] (the JSON messages and schemas, from the stream
//! descriptions of [`crate::streams`]), [`foxglove`] (Foxglove's schemas), [`write`], [`scan`] (the record walk
//! that survives truncation and decompresses chunks), [`read`] and [`ros2`]
//! (a rosbag2 MCAP read as a drive).

mod crc;
mod foxglove;
mod layout;
mod messages;
mod outgoing;
mod read;
mod ros2;
mod scan;
mod served;
mod write;

pub use foxglove::{
    BODY_FRAME as FOXGLOVE_BODY_FRAME, GNSS_FRAME as FOXGLOVE_GNSS_FRAME,
    LOCATION_TOPIC as FOXGLOVE_LOCATION_TOPIC, LOG_TOPIC as FOXGLOVE_LOG_TOPIC,
    SERVED_LOCATION_TOPIC as FOXGLOVE_SERVED_LOCATION_TOPIC,
    SERVED_POSE_TOPIC as FOXGLOVE_SERVED_POSE_TOPIC, TF_TOPIC as FOXGLOVE_TF_TOPIC,
    TRUTH_POSE_TOPIC as FOXGLOVE_TRUTH_POSE_TOPIC, WORLD_FRAME as FOXGLOVE_WORLD_FRAME,
};
pub(super) use read::read_mcap_bytes;
pub use scan::MAX_CHUNK_RECORDS_BYTES;
pub use served::{
    ServedEstimate, ServedPose, ESTIMATE_SCHEMA, ESTIMATE_TOPIC, POSE_SCHEMA, POSE_TOPIC,
    SERVED_SCHEMA_PREFIX,
};
pub(super) use write::write_mcap;

use interfaces::drive::{Wheel, WheelUnit, WheelUnits};
use interfaces::wire;

/// Channel of the wheel rotations.
pub const WHEELS_TOPIC: &str = wire::WHEELS_SERVICE;
/// Channel of the GNSS fixes.
pub const GNSS_TOPIC: &str = wire::GNSS_SERVICE;
/// Channel of the IMU samples.
pub const IMU_TOPIC: &str = wire::IMU_SERVICE;
/// Channel of the absolute headings.
pub const HEADING_TOPIC: &str = wire::HEADING_SERVICE;
/// Channel of the true poses (scoring only; not an iceoryx2 service).
pub const TRUTH_TOPIC: &str = "wheelcal/truth/pose";

/// Value of the `format` key of the `wheelcal.drive` metadata.
pub const FORMAT_MAGIC: &str = "wheelcal-drive";
/// Value of the `format_version` key; readers refuse newer versions.
pub const FORMAT_VERSION: u32 = 1;

/// Schema names of Foxglove's well-known types, which readers ignore.
const FOXGLOVE_SCHEMA_PREFIX: &str = "foxglove.";
const DRIVE_METADATA: &str = "wheelcal.drive";
const VEHICLE_METADATA: &str = "wheelcal.vehicle";
const TRUTH_METADATA: &str = "wheelcal.truth";
const VEHICLE_KEY: &str = "vehicle.toml";
const TRUTH_KEY: &str = "truth.toml";
const WHEEL_UNITS_KEY: &str = "wheel_units";

/// `rl=rad_s,rr=rad_s,fl=rad_s,fr=rad_s` (absent wheels left out).
fn wheel_units_text(units: &WheelUnits) -> String {
    Wheel::ALL
        .iter()
        .filter_map(|&w| {
            units
                .of(w)
                .map(|u| format!("{}={}", w.prefix(), u.suffix()))
        })
        .collect::<Vec<_>>()
        .join(",")
}

/// The wheel units from `wheel_units_text`, `None` when they do not parse.
fn parse_wheel_units(text: &str) -> Option<WheelUnits> {
    let mut found: [Option<WheelUnit>; 4] = [None; 4];
    for part in text.split(',').filter(|p| !p.is_empty()) {
        let (w, u) = part.split_once('=')?;
        let wheel = Wheel::ALL.into_iter().find(|x| x.prefix() == w.trim())?;
        let unit = WheelUnit::ALL
            .into_iter()
            .find(|x| x.suffix() == u.trim())?;
        found[wheel as usize] = Some(unit);
    }
    Some(WheelUnits {
        rl: found[0]?,
        rr: found[1]?,
        fl: found[2],
        fr: found[3],
    })
}
