//! Writing a drive as an MCAP recording.

use super::foxglove;
use super::messages::{stream_schema, wheels_schema, MsgOut, WheelMsgOut};
use super::outgoing::{log_time_ns, Outgoing};
use super::{
    wheel_units_text, DRIVE_METADATA, FORMAT_MAGIC, FORMAT_VERSION, TRUTH_KEY, TRUTH_METADATA,
    VEHICLE_KEY, VEHICLE_METADATA, WHEELS_TOPIC, WHEEL_UNITS_KEY,
};
use crate::folder::{truth_toml, vehicle_toml};
use crate::geodesy::LocalFrame;
use crate::streams::{wheel_column_names, Stream, WHEELS_NAME, WHEELS_SCHEMA_TITLE};
use crate::{DriveError, WriteOptions};
use interfaces::drive::{
    Drive, GnssSample, HeadingSample, ImuSample, TruthSample, Wheel, WheelSample, WheelUnits,
};
use mcap::records::{MessageHeader, Metadata};
use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::Path;

/// A stream with fixed columns.
struct StreamOut<'a, S>(&'a [S]);

impl<S: Stream> Outgoing for StreamOut<'_, S> {
    fn name(&self) -> &'static str {
        S::NAME
    }
    fn topic(&self) -> &'static str {
        S::TOPIC
    }
    fn schema_name(&self) -> &'static str {
        S::SCHEMA_TITLE
    }
    fn schema(&self) -> Vec<u8> {
        stream_schema::<S>()
    }
    fn times(&self) -> Box<dyn Iterator<Item = f64> + '_> {
        Box::new(self.0.iter().map(Stream::t_s))
    }
    fn encode(&self, i: usize, buf: &mut Vec<u8>) -> Option<serde_json::Result<()>> {
        let sample = self.0.get(i)?;
        Some(serde_json::to_writer(buf, &MsgOut(sample)))
    }
}

/// The wheels, whose keys depend on their units.
struct WheelsOut<'a> {
    units: WheelUnits,
    columns: Vec<(Wheel, String)>,
    samples: &'a [WheelSample],
}

impl Outgoing for WheelsOut<'_> {
    fn name(&self) -> &'static str {
        WHEELS_NAME
    }
    fn topic(&self) -> &'static str {
        WHEELS_TOPIC
    }
    fn schema_name(&self) -> &'static str {
        WHEELS_SCHEMA_TITLE
    }
    fn schema(&self) -> Vec<u8> {
        wheels_schema(&self.columns, &self.units)
    }
    fn metadata(&self) -> BTreeMap<String, String> {
        BTreeMap::from([(WHEEL_UNITS_KEY.to_string(), wheel_units_text(&self.units))])
    }
    fn times(&self) -> Box<dyn Iterator<Item = f64> + '_> {
        Box::new(self.samples.iter().map(|s| s.t_s))
    }
    fn encode(&self, i: usize, buf: &mut Vec<u8>) -> Option<serde_json::Result<()>> {
        let sample = self.samples.get(i)?;
        let columns = &self.columns;
        Some(serde_json::to_writer(buf, &WheelMsgOut { columns, sample }))
    }
}

/// Stream `S` of the drive, when it has it.
fn outgoing<S: Stream + 'static>(drive: &Drive) -> Option<Box<dyn Outgoing + '_>> {
    S::of(drive).map(|s| Box::new(StreamOut(s)) as Box<dyn Outgoing>)
}

/// Foxglove's channels of the drive (see [`super::foxglove`]): the GNSS
/// fixes in lat/lon when the drive has a geodetic origin, the true poses and
/// their transforms, and `warnings` as log messages at the earliest time.
fn foxglove_streams<'a>(
    drive: &'a Drive,
    warnings: &'a [String],
    earliest: Option<f64>,
    offset_ns: u64,
) -> Vec<Box<dyn Outgoing + 'a>> {
    let mut out: Vec<Box<dyn Outgoing + 'a>> = Vec::new();
    let origin = (
        drive.vehicle.gnss.origin_lat_deg,
        drive.vehicle.gnss.origin_lon_deg,
    );
    if let (Some(samples), (Some(lat), Some(lon))) = (&drive.gnss, origin) {
        out.push(Box::new(foxglove::LocationOut {
            samples,
            frame: LocalFrame::new(lat, lon, 0.0),
            offset_ns,
        }));
    }
    if let Some(samples) = &drive.truth {
        out.push(Box::new(foxglove::TruthPoseOut { samples, offset_ns }));
        out.push(Box::new(foxglove::TruthTransformOut { samples, offset_ns }));
    }
    if !warnings.is_empty() {
        out.push(Box::new(foxglove::LogOut {
            messages: warnings,
            t_s: earliest.unwrap_or(0.0),
            offset_ns,
        }));
    }
    out
}

/// Write a (validated) drive as an MCAP recording.
pub(crate) fn write_mcap(
    drive: &Drive,
    path: &Path,
    options: &WriteOptions,
) -> Result<(), DriveError> {
    let file = std::fs::File::create(path).map_err(|e| DriveError::io(path, e))?;
    let mut writer = mcap::WriteOptions::new()
        .compression(None)
        .profile("")
        .create(BufWriter::new(file))
        .map_err(mcap_error(path, "writing the header"))?;
    let (streams, offset_ns) = streams_of(drive, options);
    write_metadata(&mut writer, path, drive, offset_ns)?;
    let channel_ids = add_channels(&mut writer, path, &streams)?;
    write_messages(&mut writer, path, &streams, &channel_ids, offset_ns)?;
    writer
        .finish()
        .map_err(mcap_error(path, "writing the summary"))?;
    Ok(())
}

/// The MCAP writer of a recording file.
type McapWriter = mcap::Writer<BufWriter<std::fs::File>>;

/// An MCAP error while writing `path`, at `what`, as a [`DriveError`].
fn mcap_error(path: &Path, what: &str) -> impl Fn(mcap::McapError) -> DriveError {
    let path = path.to_path_buf();
    let what = what.to_string();
    move |e: mcap::McapError| DriveError::Mcap {
        path: path.clone(),
        location: what.clone(),
        message: e.to_string(),
    }
}

/// The channels to write, in channel order: the drive's streams present,
/// Foxglove's (when asked), and what the services served; and the
/// log-time offset, ns, that the earliest sample time of the drive's
/// streams sets.
fn streams_of<'a>(
    drive: &'a Drive,
    options: &'a WriteOptions,
) -> (Vec<Box<dyn Outgoing + 'a>>, u64) {
    let units = drive.wheels.units;
    let wheels = WheelsOut {
        units,
        columns: wheel_column_names(&units),
        samples: &drive.wheels.samples,
    };
    let mut streams: Vec<Box<dyn Outgoing + '_>> = vec![Box::new(wheels)];
    streams.extend(outgoing::<GnssSample>(drive));
    streams.extend(outgoing::<ImuSample>(drive));
    streams.extend(outgoing::<HeadingSample>(drive));
    streams.extend(outgoing::<TruthSample>(drive));

    // The earliest sample time of any stream sets the log-time offset.
    let earliest = streams
        .iter()
        .filter_map(|s| s.times().next())
        .reduce(f64::min);
    let offset_ns: u64 = match earliest {
        Some(t) if t < 0.0 => (-t * 1e9).ceil() as u64,
        _ => 0,
    };
    if options.foxglove {
        streams.extend(foxglove_streams(
            drive,
            &options.warnings,
            earliest,
            offset_ns,
        ));
    }
    streams.extend(served_streams(drive, options, offset_ns));
    (streams, offset_ns)
}

/// What the services served while the drive was recorded: the poses (also
/// in Foxglove's schemas when asked) and the estimates.
fn served_streams<'a>(
    drive: &'a Drive,
    options: &'a WriteOptions,
    offset_ns: u64,
) -> Vec<Box<dyn Outgoing + 'a>> {
    let mut streams: Vec<Box<dyn Outgoing + 'a>> = Vec::new();
    if !options.poses.is_empty() {
        streams.push(Box::new(super::served::PoseOut(&options.poses)));
        if options.foxglove {
            streams.push(Box::new(foxglove::ServedPoseOut {
                samples: &options.poses,
                offset_ns,
            }));
            let origin = (
                drive.vehicle.gnss.origin_lat_deg,
                drive.vehicle.gnss.origin_lon_deg,
            );
            if let (Some(lat), Some(lon)) = origin {
                streams.push(Box::new(foxglove::ServedLocationOut {
                    samples: &options.poses,
                    frame: LocalFrame::new(lat, lon, 0.0),
                    offset_ns,
                }));
            }
        }
    }
    if !options.estimates.is_empty() {
        streams.push(Box::new(super::served::EstimateOut(&options.estimates)));
    }
    streams
}

/// The recording's metadata: the drive's (format, tool, wheel units,
/// log-time offset), its `vehicle.toml` and, when it has one, its
/// `truth.toml`.
fn write_metadata(
    writer: &mut McapWriter,
    path: &Path,
    drive: &Drive,
    offset_ns: u64,
) -> Result<(), DriveError> {
    let err = || mcap_error(path, "writing metadata");
    let mut drive_meta = BTreeMap::new();
    drive_meta.insert("format".to_string(), FORMAT_MAGIC.to_string());
    drive_meta.insert("format_version".to_string(), FORMAT_VERSION.to_string());
    drive_meta.insert("tool".to_string(), "sensor-bridge".to_string());
    drive_meta.insert(
        "tool_version".to_string(),
        env!("CARGO_PKG_VERSION").to_string(),
    );
    drive_meta.insert(
        WHEEL_UNITS_KEY.to_string(),
        wheel_units_text(&drive.wheels.units),
    );
    drive_meta.insert("log_time_offset_ns".to_string(), offset_ns.to_string());
    writer
        .write_metadata(&Metadata {
            name: DRIVE_METADATA.to_string(),
            metadata: drive_meta,
        })
        .map_err(err())?;
    writer
        .write_metadata(&Metadata {
            name: VEHICLE_METADATA.to_string(),
            metadata: BTreeMap::from([(VEHICLE_KEY.to_string(), vehicle_toml(&drive.vehicle)?)]),
        })
        .map_err(err())?;
    if let Some(p) = &drive.truth_params {
        writer
            .write_metadata(&Metadata {
                name: TRUTH_METADATA.to_string(),
                metadata: BTreeMap::from([(TRUTH_KEY.to_string(), truth_toml(p)?)]),
            })
            .map_err(err())?;
    }
    Ok(())
}

/// One schema and channel per stream; their channel ids, in stream order.
fn add_channels(
    writer: &mut McapWriter,
    path: &Path,
    streams: &[Box<dyn Outgoing + '_>],
) -> Result<Vec<u16>, DriveError> {
    let mut channel_ids = Vec::with_capacity(streams.len());
    for s in streams {
        let topic = s.topic();
        let schema_id = writer
            .add_schema(s.schema_name(), "jsonschema", &s.schema())
            .map_err(mcap_error(path, topic))?;
        let channel_id = writer
            .add_channel(schema_id, topic, "json", &s.metadata())
            .map_err(mcap_error(path, topic))?;
        channel_ids.push(channel_id);
    }
    Ok(channel_ids)
}

/// Every message in time order across channels, for playback.
fn write_messages(
    writer: &mut McapWriter,
    path: &Path,
    streams: &[Box<dyn Outgoing + '_>],
    channel_ids: &[u16],
    offset_ns: u64,
) -> Result<(), DriveError> {
    // (log time, stream, index within the stream)
    let mut order: Vec<(u64, u8, u32)> = Vec::new();
    for (stream, s) in streams.iter().enumerate() {
        for (i, t) in s.times().enumerate() {
            order.push((log_time_ns(t, offset_ns), stream as u8, i as u32));
        }
    }
    order.sort_unstable();

    let mut sequence = vec![0u32; streams.len()];
    let mut buf = Vec::with_capacity(256);
    for (log_time, stream, index) in order {
        let i = index as usize;
        buf.clear();
        let (Some(s), Some(&channel_id), Some(seq)) = (
            streams.get(stream as usize),
            channel_ids.get(stream as usize),
            sequence.get_mut(stream as usize),
        ) else {
            continue; // never: `order` only holds samples of the streams
        };
        let Some(encoded) = s.encode(i, &mut buf) else {
            continue; // never: `order` only holds samples that exist
        };
        encoded.map_err(|e| DriveError::InvalidDrive {
            stream: s.name().to_string(),
            index: i,
            message: format!("cannot serialise as JSON: {e}"),
        })?;
        writer
            .write_to_known_channel(
                &MessageHeader {
                    channel_id,
                    sequence: *seq,
                    log_time,
                    publish_time: log_time,
                },
                &buf,
            )
            .map_err(mcap_error(path, "writing a message"))?;
        *seq = seq.wrapping_add(1);
    }
    Ok(())
}
