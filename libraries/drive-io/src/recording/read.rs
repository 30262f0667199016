//! Reading an MCAP recording into a drive.

use super::messages::{MsgIn, WheelMsgIn};
use super::scan::{ChannelInfo, RawMessage, Scan};
use super::{
    parse_wheel_units, DRIVE_METADATA, FORMAT_MAGIC, FORMAT_VERSION, FOXGLOVE_SCHEMA_PREFIX,
    TRUTH_KEY, TRUTH_METADATA, VEHICLE_KEY, VEHICLE_METADATA, WHEELS_TOPIC, WHEEL_UNITS_KEY,
};
use crate::folder::{parse_truth_toml, parse_vehicle_toml};
use crate::streams::{wheel_column_names, Stream};
use crate::{DriveError, LoadedDrive, ReadOptions};
use interfaces::drive::{
    Drive, GnssSample, HeadingSample, ImuSample, TruthSample, Wheel, WheelSeries, WheelUnit,
    WheelUnits,
};
use serde::de::DeserializeSeed;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Read an MCAP drive recording (ours, or a ROS 2 bag) from its bytes.
/// Chunk and data section CRCs (when the file gives them) are checked;
/// with `skip_corrupt_chunks` a chunk that fails its CRC is left out with a
/// warning naming it, and a data section CRC mismatch is a warning,
/// instead of an error.
pub(crate) fn read_mcap_bytes(
    path: &Path,
    bytes: &[u8],
    options: &ReadOptions,
) -> Result<LoadedDrive, DriveError> {
    let skip_corrupt_chunks = options.skip_corrupt_chunks;
    if !bytes.starts_with(mcap::MAGIC) {
        return Err(DriveError::UnknownFormat {
            path: path.to_path_buf(),
            reason: "no MCAP magic at the start".to_string(),
        });
    }
    let mut scan = Scan::default();
    scan.skip_corrupt_chunks = skip_corrupt_chunks;
    scan.walk_file(path, bytes, mcap::MAGIC.len())?;
    let file_len = bytes.len() as u64;
    let messages_read = scan.messages.len();
    let mut warnings = Vec::new();
    for c in &scan.corrupt_chunks {
        warnings.push(format!(
            "{}: chunk {} (Chunk record at byte {}) fails its CRC (file says {:#010x}, records give {:#010x}): \
             skipped with every message in it (recovery requested)",
            path.display(),
            c.index,
            c.offset,
            c.expected,
            c.actual
        ));
    }
    if let Some(c) = &scan.data_crc_mismatch {
        warnings.push(format!(
            "{}: the data section fails its CRC (DataEnd record at byte {}: file says {:#010x}, data gives {:#010x}){}: \
             read anyway (recovery requested)",
            path.display(),
            c.offset,
            c.expected,
            c.actual,
            if scan.corrupt_chunks.is_empty() {
                ""
            } else {
                " (the skipped chunks are part of it)"
            }
        ));
    }
    match scan.damage.take() {
        // Damage after the data section: every message was read.
        Some(d) if scan.data_end_seen => {
            warnings.push(format!(
                "{}: summary section damaged ({}); every message was read",
                path.display(),
                d.record
            ));
            assemble_any(path, &scan, options, warnings)
        }
        Some(d) => {
            warnings.push(format!(
                "{}: truncated ({file_len} bytes): {}; read {messages_read} messages before the damage",
                path.display(),
                d.record
            ));
            let partial = assemble_any(path, &scan, options, warnings)
                .ok()
                .map(Box::new);
            Err(DriveError::TruncatedMcap {
                path: path.to_path_buf(),
                offset: d.offset,
                file_len,
                record: d.record,
                messages_read,
                partial,
            })
        }
        None => assemble_any(path, &scan, options, warnings),
    }
}

/// Our recording (it has the drive metadata) or a ROS 2 bag; the vehicle
/// of `options`, when given, replaces our recording's own.
fn assemble_any(
    path: &Path,
    scan: &Scan<'_>,
    options: &ReadOptions,
    warnings: Vec<String>,
) -> Result<LoadedDrive, DriveError> {
    if !scan.metadata.contains_key(DRIVE_METADATA) && super::ros2::is_ros2(scan) {
        return super::ros2::assemble(path, scan, options, warnings);
    }
    let mut loaded = assemble(path, scan, warnings)?;
    if let Some(given) = &options.vehicle {
        crate::replace_vehicle(path, &mut loaded, given);
    }
    Ok(loaded)
}

/// "file.mcap [metadata wheelcal.vehicle]" as a path for TOML errors.
fn metadata_path(path: &Path, name: &str) -> PathBuf {
    PathBuf::from(format!("{} [metadata {name}]", path.display()))
}

fn assemble(
    path: &Path,
    scan: &Scan<'_>,
    mut warnings: Vec<String>,
) -> Result<LoadedDrive, DriveError> {
    let merr = |location: &str, message: String| mcap_error(path, location, message);
    let meta = drive_metadata(path, scan)?;
    let vehicle_text = scan
        .metadata
        .get(VEHICLE_METADATA)
        .and_then(|m| m.get(VEHICLE_KEY))
        .ok_or_else(|| {
            merr(
                "metadata",
                format!("no `{VEHICLE_METADATA}` metadata with key `{VEHICLE_KEY}`"),
            )
        })?;
    let vehicle = parse_vehicle_toml(
        &metadata_path(path, VEHICLE_METADATA),
        vehicle_text,
        &mut warnings,
    )?;
    let truth_params = match scan
        .metadata
        .get(TRUTH_METADATA)
        .and_then(|m| m.get(TRUTH_KEY))
    {
        Some(text) => Some(parse_truth_toml(
            &metadata_path(path, TRUTH_METADATA),
            text,
        )?),
        None => None,
    };
    let streams = Streams::sort(path, scan, &mut warnings)?;
    let Some(wheel_msgs) = streams.messages(WHEELS_TOPIC) else {
        return Err(merr(
            "channels",
            format!("no `{WHEELS_TOPIC}` channel (wheels are required)"),
        ));
    };
    let units = wheel_units(path, scan, &streams, meta)?;
    let has_ticks = Wheel::ALL
        .iter()
        .any(|&w| units.of(w) == Some(WheelUnit::Ticks));
    if has_ticks && vehicle.ticks_per_rev.is_none() {
        return Err(merr(
            &format!("channel {WHEELS_TOPIC}"),
            "wheels in ticks but vehicle.toml has no ticks_per_rev".to_string(),
        ));
    }
    let columns = wheel_column_names(&units);
    let wheel_samples = decode(path, WHEELS_TOPIC, wheel_msgs, |data| {
        let mut de = serde_json::Deserializer::from_slice(data);
        let s = WheelMsgIn { columns: &columns }.deserialize(&mut de)?;
        de.end()?;
        let finite = [Some(s.t_s), Some(s.rl), Some(s.rr), s.fl, s.fr]
            .into_iter()
            .flatten()
            .all(f64::is_finite);
        Ok((s.t_s, s, finite))
    })?;
    let gnss = decode_stream::<GnssSample>(path, streams.messages(GnssSample::TOPIC))?;
    let imu = decode_stream::<ImuSample>(path, streams.messages(ImuSample::TOPIC))?;
    let heading = decode_stream::<HeadingSample>(path, streams.messages(HeadingSample::TOPIC))?;
    let truth = decode_stream::<TruthSample>(path, streams.messages(TruthSample::TOPIC))?;

    Ok(LoadedDrive {
        drive: Drive {
            vehicle,
            wheels: WheelSeries {
                units,
                samples: wheel_samples,
            },
            gnss,
            imu,
            heading,
            truth,
            truth_params,
        },
        warnings,
    })
}

/// An error in the recording at `path`, at `location`.
fn mcap_error(path: &Path, location: &str, message: String) -> DriveError {
    DriveError::Mcap {
        path: path.to_path_buf(),
        location: location.to_string(),
        message,
    }
}

/// The drive metadata record, checked: our format, a version we read.
fn drive_metadata<'s>(
    path: &Path,
    scan: &'s Scan<'_>,
) -> Result<&'s BTreeMap<String, String>, DriveError> {
    let merr = |location: &str, message: String| mcap_error(path, location, message);
    let Some(meta) = scan.metadata.get(DRIVE_METADATA) else {
        return Err(merr(
            "metadata",
            format!("no `{DRIVE_METADATA}` metadata record: not a drive recording written by sensor-bridge"),
        ));
    };
    if meta.get("format").map(String::as_str) != Some(FORMAT_MAGIC) {
        return Err(merr(
            &format!("metadata {DRIVE_METADATA}"),
            format!(
                "`format` is {:?}, expected {FORMAT_MAGIC:?}",
                meta.get("format")
            ),
        ));
    }
    let version = meta
        .get("format_version")
        .and_then(|v| v.parse::<u32>().ok());
    match version {
        Some(v) if v <= FORMAT_VERSION => Ok(meta),
        _ => Err(merr(
            &format!("metadata {DRIVE_METADATA}"),
            format!(
                "format_version {:?} is not supported (this tool reads up to {FORMAT_VERSION})",
                meta.get("format_version")
            ),
        )),
    }
}

/// The drive streams' topics.
const KNOWN_TOPICS: [&str; 5] = [
    WHEELS_TOPIC,
    GnssSample::TOPIC,
    ImuSample::TOPIC,
    HeadingSample::TOPIC,
    TruthSample::TOPIC,
];

/// The messages of the drive's own channels, by topic; what else the
/// recording holds is reported in the warnings.
struct Streams<'a, 's> {
    by_topic: BTreeMap<&'s str, u16>,
    per_channel: BTreeMap<u16, Vec<&'s RawMessage<'a>>>,
    empty: Vec<&'s RawMessage<'a>>,
}

impl<'a, 's> Streams<'a, 's> {
    fn sort(
        path: &Path,
        scan: &'s Scan<'a>,
        warnings: &mut Vec<String>,
    ) -> Result<Streams<'a, 's>, DriveError> {
        let merr = |location: &str, message: String| mcap_error(path, location, message);
        let known = KNOWN_TOPICS;
        // Channels by topic; others are reported.
        let mut by_topic: BTreeMap<&str, u16> = BTreeMap::new();
        for (id, c) in &scan.channels {
            if known.contains(&c.topic.as_str()) {
                if c.encoding != "json" {
                    return Err(merr(
                        &format!("channel {}", c.topic),
                        format!("message encoding `{}`, expected `json`", c.encoding),
                    ));
                }
                if by_topic.insert(c.topic.as_str(), *id).is_some() {
                    return Err(merr(
                        &format!("channel {}", c.topic),
                        "appears twice".to_string(),
                    ));
                }
            }
        }
        // Channels in Foxglove's schemas are derived from the drive's own
        // (written with `WriteOptions::foxglove`), and the served ones are not
        // the drive's (`WriteOptions::poses`, `estimates`): left out without a
        // word.
        let derived = |c: &ChannelInfo| {
            !known.contains(&c.topic.as_str())
                && scan.schemas.get(&c.schema_id).is_some_and(|s| {
                    s.name.starts_with(FOXGLOVE_SCHEMA_PREFIX)
                        || s.name.starts_with(super::served::SERVED_SCHEMA_PREFIX)
                })
        };
        let mut per_channel: BTreeMap<u16, Vec<&RawMessage<'_>>> = BTreeMap::new();
        let mut unknown_channel_messages = 0usize;
        for m in &scan.messages {
            match scan.channels.get(&m.channel_id) {
                Some(c) if by_topic.get(c.topic.as_str()) == Some(&m.channel_id) => {
                    per_channel.entry(m.channel_id).or_default().push(m)
                }
                Some(c) if known.contains(&c.topic.as_str()) || derived(c) => {}
                _ => unknown_channel_messages += 1,
            }
        }
        let others: Vec<&str> = scan
            .channels
            .values()
            .filter(|c| !derived(c))
            .map(|c| c.topic.as_str())
            .filter(|t| !known.contains(t))
            .collect();
        if !others.is_empty() || unknown_channel_messages > 0 {
            warnings.push(format!(
                "{}: ignored {unknown_channel_messages} message(s) on channel(s) that are not drive streams: {}",
                path.display(),
                if others.is_empty() { "(unknown channel ids)".to_string() } else { others.join(", ") }
            ));
        }
        Ok(Streams {
            by_topic,
            per_channel,
            empty: Vec::new(),
        })
    }

    /// The messages of `topic`, `None` when the recording has no such channel.
    fn messages(&self, topic: &str) -> Option<&Vec<&'s RawMessage<'a>>> {
        self.by_topic
            .get(topic)
            .map(|id| self.per_channel.get(id).unwrap_or(&self.empty))
    }
}

/// The wheel channel's units: from its own metadata, else the drive's.
fn wheel_units(
    path: &Path,
    scan: &Scan<'_>,
    streams: &Streams<'_, '_>,
    meta: &BTreeMap<String, String>,
) -> Result<WheelUnits, DriveError> {
    let merr = |location: &str, message: String| mcap_error(path, location, message);
    let wheels_channel = streams
        .by_topic
        .get(WHEELS_TOPIC)
        .and_then(|id| scan.channels.get(id));
    let units_text = wheels_channel
        .and_then(|c| c.metadata.get(WHEEL_UNITS_KEY))
        .or_else(|| meta.get(WHEEL_UNITS_KEY))
        .ok_or_else(|| {
            merr(
                &format!("channel {WHEELS_TOPIC}"),
                format!("no `{WHEEL_UNITS_KEY}` metadata"),
            )
        })?;
    parse_wheel_units(units_text).ok_or_else(|| {
        merr(
            &format!("channel {WHEELS_TOPIC}"),
            format!("cannot parse wheel_units `{units_text}` (expected e.g. rl=rad_s,rr=rad_s)"),
        )
    })
}

/// Decode every message of one channel, checking that `t_s` strictly
/// increases and (JSON having no NaN) that every value is finite (`parse`
/// gives the time, the sample and whether all its values are finite).
fn decode<T>(
    path: &Path,
    topic: &str,
    messages: &[&RawMessage<'_>],
    parse: impl Fn(&[u8]) -> Result<(f64, T, bool), serde_json::Error>,
) -> Result<Vec<T>, DriveError> {
    let mut out = Vec::with_capacity(messages.len());
    let mut previous: Option<f64> = None;
    for (i, m) in messages.iter().enumerate() {
        let location = || format!("channel {topic}, message {i} ({})", m.location());
        let (t, sample, finite) = parse(&m.data).map_err(|e| DriveError::Mcap {
            path: path.to_path_buf(),
            location: location(),
            message: format!("bad JSON message: {e}"),
        })?;
        if !finite {
            return Err(DriveError::Mcap {
                path: path.to_path_buf(),
                location: location(),
                message: "a value is not finite".to_string(),
            });
        }
        if let Some(p) = previous {
            if t <= p {
                return Err(DriveError::Mcap {
                    path: path.to_path_buf(),
                    location: location(),
                    message: format!(
                        "t_s = {t} does not increase (previous message has t_s = {p})"
                    ),
                });
            }
        }
        previous = Some(t);
        out.push(sample);
    }
    Ok(out)
}

/// Decode the channel of stream `S`, when the recording has it.
fn decode_stream<S: Stream>(
    path: &Path,
    messages: Option<&Vec<&RawMessage<'_>>>,
) -> Result<Option<Vec<S>>, DriveError> {
    let Some(messages) = messages else {
        return Ok(None);
    };
    let samples = decode(path, S::TOPIC, messages, |data| {
        let mut de = serde_json::Deserializer::from_slice(data);
        let s = MsgIn::<S>::new().deserialize(&mut de)?;
        de.end()?;
        let finite = (0..S::FIELDS.len())
            .filter_map(|k| s.value(k))
            .all(f64::is_finite);
        Ok((s.t_s(), s, finite))
    })?;
    Ok(Some(samples))
}
