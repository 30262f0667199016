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
//! - chunks are uncompressed, so a truncated file can be read up to the
//!   damage, chunk contents included.

use super::folder::{
    parse_truth_toml, parse_vehicle_toml, truth_toml, vehicle_toml, wheel_column_names,
};
use super::{DriveError, LoadedDrive};
use interfaces::drive::{
    Drive, GnssSample, HeadingSample, ImuSample, TruthSample, Wheel, WheelSample, WheelSeries,
    WheelUnit, WheelUnits,
};
use interfaces::wire;
use mcap::records::{op, MessageHeader, Metadata, Record};
use serde::de::{DeserializeSeed, Error as _, MapAccess, Visitor};
use serde::{Deserialize, Serialize, Serializer};
use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

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

const DRIVE_METADATA: &str = "wheelcal.drive";
const VEHICLE_METADATA: &str = "wheelcal.vehicle";
const TRUTH_METADATA: &str = "wheelcal.truth";
const VEHICLE_KEY: &str = "vehicle.toml";
const TRUTH_KEY: &str = "truth.toml";
const WHEEL_UNITS_KEY: &str = "wheel_units";

// ------------------------------------------------------------- messages

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct GnssMsg {
    t_s: f64,
    x_m: f64,
    y_m: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sigma_m: Option<f64>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ImuMsg {
    t_s: f64,
    gz_rad_s: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    ax_m_s2: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    ay_m_s2: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    az_m_s2: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gx_rad_s: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gy_rad_s: Option<f64>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct HeadingMsg {
    t_s: f64,
    yaw_rad: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sigma_rad: Option<f64>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct TruthMsg {
    t_s: f64,
    x_m: f64,
    y_m: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    yaw_rad: Option<f64>,
}

/// A wheel sample serialised with its unit-bearing column names
/// (`{"t_s":..,"rl_rad_s":..,...}`).
struct WheelMsgOut<'a> {
    columns: &'a [(Wheel, String)],
    sample: &'a WheelSample,
}

fn wheel_value(s: &WheelSample, w: Wheel) -> Option<f64> {
    match w {
        Wheel::Rl => Some(s.rl),
        Wheel::Rr => Some(s.rr),
        Wheel::Fl => s.fl,
        Wheel::Fr => s.fr,
    }
}

impl Serialize for WheelMsgOut<'_> {
    fn serialize<S: Serializer>(&self, ser: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = ser.serialize_map(None)?;
        m.serialize_entry("t_s", &self.sample.t_s)?;
        for (wheel, name) in self.columns {
            if let Some(v) = wheel_value(self.sample, *wheel) {
                m.serialize_entry(name, &v)?;
            }
        }
        m.end()
    }
}

/// Reads a wheel message whose keys must be `t_s` and the channel's wheel columns.
struct WheelMsgIn<'a> {
    columns: &'a [(Wheel, String)],
}

impl<'de> DeserializeSeed<'de> for WheelMsgIn<'_> {
    type Value = WheelSample;
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<WheelSample, D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for WheelMsgIn<'_> {
    type Value = WheelSample;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a wheel sample object")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<WheelSample, A::Error> {
        let mut t_s = None;
        let mut values: [Option<f64>; 4] = [None; 4];
        while let Some(key) = map.next_key::<String>()? {
            if key == "t_s" {
                t_s = Some(map.next_value::<f64>()?);
            } else if let Some((wheel, _)) = self.columns.iter().find(|(_, n)| *n == key) {
                values[*wheel as usize] = Some(map.next_value::<f64>()?);
            } else {
                let expected: Vec<&str> = self.columns.iter().map(|(_, n)| n.as_str()).collect();
                return Err(A::Error::custom(format!(
                    "unexpected key `{key}` (this channel's keys are t_s, {})",
                    expected.join(", ")
                )));
            }
        }
        let need = |v: Option<f64>, name: &str| {
            v.ok_or_else(|| A::Error::custom(format!("missing `{name}`")))
        };
        let rear = |w: Wheel| {
            let name = self
                .columns
                .iter()
                .find(|(x, _)| *x == w)
                .map_or(w.prefix(), |(_, n)| n.as_str());
            need(values[w as usize], name)
        };
        Ok(WheelSample {
            t_s: need(t_s, "t_s")?,
            rl: rear(Wheel::Rl)?,
            rr: rear(Wheel::Rr)?,
            fl: values[Wheel::Fl as usize],
            fr: values[Wheel::Fr as usize],
        })
    }
}

// ------------------------------------------------------------- schemas

fn number(description: &str) -> serde_json::Value {
    serde_json::json!({ "type": "number", "description": description })
}

fn schema(title: &str, description: &str, fields: &[(&str, &str, bool)]) -> Vec<u8> {
    let mut properties = serde_json::Map::new();
    let mut required = Vec::new();
    for (name, desc, req) in fields {
        properties.insert((*name).to_string(), number(desc));
        if *req {
            required.push(serde_json::Value::String((*name).to_string()));
        }
    }
    let value = serde_json::json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": title,
        "description": description,
        "type": "object",
        "properties": properties,
        "required": required,
        "additionalProperties": false,
    });
    value.to_string().into_bytes()
}

fn unit_description(unit: WheelUnit) -> &'static str {
    match unit {
        WheelUnit::Rev => "cumulative revolutions since an arbitrary start",
        WheelUnit::Ticks => "cumulative encoder ticks (see ticks_per_rev in vehicle.toml)",
        WheelUnit::RadS => "wheel angular speed, rad/s",
        WheelUnit::MS => {
            "wheel speed as the vehicle reports it, m/s (scaled by nominal_circumference_m)"
        }
    }
}

const T_S: (&str, &str, bool) = ("t_s", "time on the drive clock, s (exact)", true);

fn wheels_schema(columns: &[(Wheel, String)], units: &WheelUnits) -> Vec<u8> {
    let descriptions: Vec<(String, String, bool)> = columns
        .iter()
        .map(|(w, n)| {
            let unit = units.of(*w).unwrap_or(WheelUnit::Rev);
            (
                n.clone(),
                format!("{}: {}", w.prefix(), unit_description(unit)),
                matches!(w, Wheel::Rl | Wheel::Rr),
            )
        })
        .collect();
    let mut fields = vec![T_S];
    fields.extend(
        descriptions
            .iter()
            .map(|(n, d, r)| (n.as_str(), d.as_str(), *r)),
    );
    schema(
        "wheelcal.Wheels",
        "Wheel rotations (rear left/right required, front optional)",
        &fields,
    )
}

fn gnss_schema() -> Vec<u8> {
    schema(
        "wheelcal.GnssFix",
        "GNSS fix in local ENU (x east, y north); origin in vehicle.toml [gnss]",
        &[
            T_S,
            ("x_m", "east, m", true),
            ("y_m", "north, m", true),
            ("sigma_m", "horizontal 1-sigma, m", false),
        ],
    )
}

fn imu_schema() -> Vec<u8> {
    schema(
        "wheelcal.Imu",
        "IMU, body frame x forward, y left, z up",
        &[
            T_S,
            ("gz_rad_s", "yaw rate, rad/s, positive turning left", true),
            ("ax_m_s2", "longitudinal acceleration, m/s^2", false),
            ("ay_m_s2", "lateral acceleration, m/s^2", false),
            ("az_m_s2", "vertical acceleration, m/s^2", false),
            ("gx_rad_s", "roll rate, rad/s", false),
            ("gy_rad_s", "pitch rate, rad/s", false),
        ],
    )
}

fn heading_schema() -> Vec<u8> {
    schema(
        "wheelcal.Heading",
        "Absolute heading, yaw 0 = east, counter-clockwise positive",
        &[
            T_S,
            ("yaw_rad", "yaw, rad", true),
            ("sigma_rad", "1-sigma, rad", false),
        ],
    )
}

fn truth_schema() -> Vec<u8> {
    schema(
        "wheelcal.TruthPose",
        "True pose of the rear-axle centre in local ENU (scoring only)",
        &[
            T_S,
            ("x_m", "east, m", true),
            ("y_m", "north, m", true),
            ("yaw_rad", "yaw, rad", false),
        ],
    )
}

// ------------------------------------------------------------- writing

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

/// The earliest sample time of any stream (sets the log-time offset).
fn earliest_time(drive: &Drive) -> Option<f64> {
    let firsts = [
        drive.wheels.samples.first().map(|s| s.t_s),
        drive.gnss.as_ref().and_then(|v| v.first()).map(|s| s.t_s),
        drive.imu.as_ref().and_then(|v| v.first()).map(|s| s.t_s),
        drive
            .heading
            .as_ref()
            .and_then(|v| v.first())
            .map(|s| s.t_s),
        drive.truth.as_ref().and_then(|v| v.first()).map(|s| s.t_s),
    ];
    firsts.into_iter().flatten().reduce(f64::min)
}

/// Write a (validated) drive as an MCAP recording.
pub(super) fn write_mcap(drive: &Drive, path: &Path) -> Result<(), DriveError> {
    let file = std::fs::File::create(path).map_err(|e| DriveError::io(path, e))?;
    let err = |what: &str| {
        let path = path.to_path_buf();
        let what = what.to_string();
        move |e: mcap::McapError| DriveError::Mcap {
            path: path.clone(),
            location: what.clone(),
            message: e.to_string(),
        }
    };
    let mut writer = mcap::WriteOptions::new()
        .compression(None)
        .profile("")
        .create(BufWriter::new(file))
        .map_err(err("writing the header"))?;

    let offset_ns: u64 = match earliest_time(drive) {
        Some(t) if t < 0.0 => (-t * 1e9).ceil() as u64,
        _ => 0,
    };
    let units = drive.wheels.units;
    let mut drive_meta = BTreeMap::new();
    drive_meta.insert("format".to_string(), FORMAT_MAGIC.to_string());
    drive_meta.insert("format_version".to_string(), FORMAT_VERSION.to_string());
    drive_meta.insert("tool".to_string(), "sensor-bridge".to_string());
    drive_meta.insert(
        "tool_version".to_string(),
        env!("CARGO_PKG_VERSION").to_string(),
    );
    drive_meta.insert(WHEEL_UNITS_KEY.to_string(), wheel_units_text(&units));
    drive_meta.insert("log_time_offset_ns".to_string(), offset_ns.to_string());
    writer
        .write_metadata(&Metadata {
            name: DRIVE_METADATA.to_string(),
            metadata: drive_meta,
        })
        .map_err(err("writing metadata"))?;
    writer
        .write_metadata(&Metadata {
            name: VEHICLE_METADATA.to_string(),
            metadata: BTreeMap::from([(VEHICLE_KEY.to_string(), vehicle_toml(&drive.vehicle)?)]),
        })
        .map_err(err("writing metadata"))?;
    if let Some(p) = &drive.truth_params {
        writer
            .write_metadata(&Metadata {
                name: TRUTH_METADATA.to_string(),
                metadata: BTreeMap::from([(TRUTH_KEY.to_string(), truth_toml(p)?)]),
            })
            .map_err(err("writing metadata"))?;
    }

    let columns = wheel_column_names(&units);
    let mut add =
        |topic: &str, schema_name: &str, schema: Vec<u8>, meta: BTreeMap<String, String>| {
            let schema_id = writer
                .add_schema(schema_name, "jsonschema", &schema)
                .map_err(err(topic))?;
            writer
                .add_channel(schema_id, topic, "json", &meta)
                .map_err(err(topic))
        };
    let wheel_meta = BTreeMap::from([(WHEEL_UNITS_KEY.to_string(), wheel_units_text(&units))]);
    let wheels_id = add(
        WHEELS_TOPIC,
        "wheelcal.Wheels",
        wheels_schema(&columns, &units),
        wheel_meta,
    )?;
    let gnss_id = drive
        .gnss
        .as_ref()
        .map(|_| {
            add(
                GNSS_TOPIC,
                "wheelcal.GnssFix",
                gnss_schema(),
                BTreeMap::new(),
            )
        })
        .transpose()?;
    let imu_id = drive
        .imu
        .as_ref()
        .map(|_| add(IMU_TOPIC, "wheelcal.Imu", imu_schema(), BTreeMap::new()))
        .transpose()?;
    let heading_id = drive
        .heading
        .as_ref()
        .map(|_| {
            add(
                HEADING_TOPIC,
                "wheelcal.Heading",
                heading_schema(),
                BTreeMap::new(),
            )
        })
        .transpose()?;
    let truth_id = drive
        .truth
        .as_ref()
        .map(|_| {
            add(
                TRUTH_TOPIC,
                "wheelcal.TruthPose",
                truth_schema(),
                BTreeMap::new(),
            )
        })
        .transpose()?;

    // Every message in time order across channels, for playback.
    // (log time, stream, index within the stream)
    let log_time = |t: f64| (t * 1e9).round() as i64 as i128 + offset_ns as i128;
    let mut order: Vec<(i128, u8, u32)> = Vec::new();
    let mut push = |stream: u8, times: &mut dyn Iterator<Item = f64>| {
        for (i, t) in times.enumerate() {
            order.push((log_time(t), stream, i as u32));
        }
    };
    push(0, &mut drive.wheels.samples.iter().map(|s| s.t_s));
    if let Some(v) = &drive.gnss {
        push(1, &mut v.iter().map(|s| s.t_s));
    }
    if let Some(v) = &drive.imu {
        push(2, &mut v.iter().map(|s| s.t_s));
    }
    if let Some(v) = &drive.heading {
        push(3, &mut v.iter().map(|s| s.t_s));
    }
    if let Some(v) = &drive.truth {
        push(4, &mut v.iter().map(|s| s.t_s));
    }
    order.sort_unstable();

    let channel_ids = [Some(wheels_id), gnss_id, imu_id, heading_id, truth_id];
    let mut sequence = [0u32; 5];
    let mut buf = Vec::with_capacity(256);
    for (time, stream, index) in order {
        let i = index as usize;
        buf.clear();
        let (Some(channel_id), Some(encoded)) = (
            channel_ids[stream as usize],
            encode(drive, &columns, stream, i, &mut buf),
        ) else {
            continue; // never: `order` only holds samples of present streams
        };
        encoded.map_err(|e| DriveError::InvalidDrive {
            stream: STREAM_NAMES[stream as usize].to_string(),
            index: i,
            message: format!("cannot serialise as JSON: {e}"),
        })?;
        let seq = &mut sequence[stream as usize];
        let log_time = time.clamp(0, u64::MAX as i128) as u64;
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
            .map_err(err("writing a message"))?;
        *seq = seq.wrapping_add(1);
    }
    writer.finish().map_err(err("writing the summary"))?;
    Ok(())
}

/// Stream numbers used while writing, in channel order.
const STREAM_NAMES: [&str; 5] = ["wheels", "gnss", "imu", "heading", "truth"];

/// JSON of sample `i` of stream number `stream` into `buf`; `None` when the
/// drive lacks the stream.
fn encode(
    drive: &Drive,
    columns: &[(Wheel, String)],
    stream: u8,
    i: usize,
    buf: &mut Vec<u8>,
) -> Option<serde_json::Result<()>> {
    Some(match stream {
        0 => {
            let sample = drive.wheels.samples.get(i)?;
            serde_json::to_writer(buf, &WheelMsgOut { columns, sample })
        }
        1 => {
            let s = drive.gnss.as_ref()?.get(i)?;
            let m = GnssMsg {
                t_s: s.t_s,
                x_m: s.x_m,
                y_m: s.y_m,
                sigma_m: s.sigma_m,
            };
            serde_json::to_writer(buf, &m)
        }
        2 => {
            let s = drive.imu.as_ref()?.get(i)?;
            let m = ImuMsg {
                t_s: s.t_s,
                gz_rad_s: s.gz_rad_s,
                ax_m_s2: s.ax_m_s2,
                ay_m_s2: s.ay_m_s2,
                az_m_s2: s.az_m_s2,
                gx_rad_s: s.gx_rad_s,
                gy_rad_s: s.gy_rad_s,
            };
            serde_json::to_writer(buf, &m)
        }
        3 => {
            let s = drive.heading.as_ref()?.get(i)?;
            let m = HeadingMsg {
                t_s: s.t_s,
                yaw_rad: s.yaw_rad,
                sigma_rad: s.sigma_rad,
            };
            serde_json::to_writer(buf, &m)
        }
        _ => {
            let s = drive.truth.as_ref()?.get(i)?;
            let m = TruthMsg {
                t_s: s.t_s,
                x_m: s.x_m,
                y_m: s.y_m,
                yaw_rad: s.yaw_rad,
            };
            serde_json::to_writer(buf, &m)
        }
    })
}

// ------------------------------------------------------------- reading

/// A message as found in the file.
struct RawMessage<'a> {
    channel_id: u16,
    /// Byte offset of its record in the file.
    offset: u64,
    data: &'a [u8],
}

struct ChannelInfo {
    topic: String,
    encoding: String,
    metadata: BTreeMap<String, String>,
}

/// Where a file stops making sense.
struct Damage {
    offset: u64,
    record: String,
}

/// Everything a walk over the records found.
#[derive(Default)]
struct Scan<'a> {
    channels: BTreeMap<u16, ChannelInfo>,
    metadata: BTreeMap<String, BTreeMap<String, String>>,
    messages: Vec<RawMessage<'a>>,
    damage: Option<Damage>,
    data_end_seen: bool,
    footer_seen: bool,
}

fn op_name(op: u8) -> String {
    match op {
        op::HEADER => "Header".into(),
        op::FOOTER => "Footer".into(),
        op::SCHEMA => "Schema".into(),
        op::CHANNEL => "Channel".into(),
        op::MESSAGE => "Message".into(),
        op::CHUNK => "Chunk".into(),
        op::MESSAGE_INDEX => "MessageIndex".into(),
        op::CHUNK_INDEX => "ChunkIndex".into(),
        op::ATTACHMENT => "Attachment".into(),
        op::ATTACHMENT_INDEX => "AttachmentIndex".into(),
        op::STATISTICS => "Statistics".into(),
        op::METADATA => "Metadata".into(),
        op::METADATA_INDEX => "MetadataIndex".into(),
        op::SUMMARY_OFFSET => "SummaryOffset".into(),
        op::DATA_END => "DataEnd".into(),
        other => format!("opcode 0x{other:02x}"),
    }
}

fn le_u64(b: &[u8]) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[..8]);
    u64::from_le_bytes(a)
}

fn le_u32(b: &[u8]) -> u32 {
    let mut a = [0u8; 4];
    a.copy_from_slice(&b[..4]);
    u32::from_le_bytes(a)
}

/// One framed record: (opcode, body start, declared body length).
enum Frame {
    Complete {
        op: u8,
        body: std::ops::Range<usize>,
    },
    /// The record runs past the end of the buffer.
    Cut {
        op: Option<u8>,
        declared: u64,
        present: usize,
    },
}

fn frame(buf: &[u8], pos: usize) -> Frame {
    let rest = buf.len() - pos;
    if rest < 9 {
        return Frame::Cut {
            op: buf.get(pos).copied(),
            declared: 0,
            present: rest,
        };
    }
    let op = buf[pos];
    let len = le_u64(&buf[pos + 1..]);
    let start = pos + 9;
    match usize::try_from(len).ok().and_then(|l| start.checked_add(l)) {
        Some(end) if end <= buf.len() => Frame::Complete {
            op,
            body: start..end,
        },
        _ => Frame::Cut {
            op: Some(op),
            declared: len,
            present: rest - 9,
        },
    }
}

/// Byte offset of the records inside a chunk body, and the compression.
fn chunk_records_start(body: &[u8]) -> Option<(usize, String)> {
    // message_start_time u64, message_end_time u64, uncompressed_size u64,
    // uncompressed_crc u32, compression string (u32 length + bytes),
    // records length u64, records.
    let str_len = le_u32(body.get(28..32)?) as usize;
    let compression = body.get(32..32 + str_len)?;
    let start = 32 + str_len + 8;
    if body.len() < start {
        return None;
    }
    Some((start, String::from_utf8_lossy(compression).into_owned()))
}

impl<'a> Scan<'a> {
    fn handle(
        &mut self,
        path: &Path,
        op: u8,
        body: &'a [u8],
        offset: u64,
    ) -> Result<(), DriveError> {
        let record = mcap::parse_record(op, body).map_err(|e| DriveError::Mcap {
            path: path.to_path_buf(),
            location: format!("{} record at byte {offset}", op_name(op)),
            message: e.to_string(),
        })?;
        match record {
            Record::Channel(c) => {
                self.channels.insert(
                    c.id,
                    ChannelInfo {
                        topic: c.topic,
                        encoding: c.message_encoding,
                        metadata: c.metadata,
                    },
                );
            }
            Record::Message { header, data } => {
                let data: &'a [u8] = match data {
                    std::borrow::Cow::Borrowed(d) => d,
                    // parse_record borrows from `body`; an owned copy never happens.
                    std::borrow::Cow::Owned(_) => {
                        return Err(DriveError::Mcap {
                            path: path.to_path_buf(),
                            location: format!("Message record at byte {offset}"),
                            message: "unexpected owned message data".to_string(),
                        })
                    }
                };
                self.messages.push(RawMessage {
                    channel_id: header.channel_id,
                    offset,
                    data,
                });
            }
            Record::Metadata(m) => {
                self.metadata.insert(m.name, m.metadata);
            }
            Record::DataEnd(_) => self.data_end_seen = true,
            Record::Footer(_) => self.footer_seen = true,
            _ => {}
        }
        Ok(())
    }

    /// Walk the records of `buf[start..]` (the whole file, or a chunk's
    /// records); `base` is the file offset of `buf[0]`. Stops at the first
    /// damaged record (recorded in `self.damage`) or the footer.
    fn walk(
        &mut self,
        path: &Path,
        buf: &'a [u8],
        start: usize,
        base: u64,
        in_chunk: bool,
    ) -> Result<(), DriveError> {
        let mut pos = start;
        while pos < buf.len() {
            let offset = base + pos as u64;
            match frame(buf, pos) {
                Frame::Complete { op, body } => {
                    let end = body.end;
                    let body = &buf[body];
                    if op == op::CHUNK && !in_chunk {
                        self.chunk(path, body, offset + 9)?;
                        if self.damage.is_some() {
                            return Ok(());
                        }
                    } else {
                        self.handle(path, op, body, offset)?;
                    }
                    pos = end;
                    if self.footer_seen {
                        return Ok(());
                    }
                }
                Frame::Cut {
                    op,
                    declared,
                    present,
                } => {
                    let rest = buf.len() - pos;
                    let record = match op {
                        Some(op) if rest >= 9 => format!(
                            "the {} record at byte {offset} declares {declared} bytes but only {present} follow",
                            op_name(op)
                        ),
                        _ => format!("the record header at byte {offset} is cut after {rest} of 9 bytes"),
                    };
                    // A cut chunk: its records are uncompressed, so read those that are whole.
                    if op == Some(op::CHUNK) && !in_chunk && rest > 9 {
                        let body = &buf[pos + 9..];
                        if let Some((records_start, compression)) = chunk_records_start(body) {
                            if compression.is_empty() {
                                self.walk(path, body, records_start, offset + 9, true)?;
                            }
                        }
                    }
                    self.damage = Some(Damage { offset, record });
                    return Ok(());
                }
            }
        }
        if !in_chunk && !self.footer_seen {
            self.damage = Some(Damage {
                offset: buf.len() as u64,
                record: format!(
                    "the file ends at byte {} without a Footer record",
                    buf.len()
                ),
            });
        }
        Ok(())
    }

    /// A complete chunk record (body at file offset `base`).
    fn chunk(&mut self, path: &Path, body: &'a [u8], base: u64) -> Result<(), DriveError> {
        let Some((start, compression)) = chunk_records_start(body) else {
            return Err(DriveError::Mcap {
                path: path.to_path_buf(),
                location: format!("Chunk record at byte {}", base - 9),
                message: "malformed chunk header".to_string(),
            });
        };
        if !compression.is_empty() {
            return Err(DriveError::Mcap {
                path: path.to_path_buf(),
                location: format!("Chunk record at byte {}", base - 9),
                message: format!(
                    "chunk compressed with `{compression}`; this build reads uncompressed MCAP only \
                     (re-write it with `mcap recover --compression none`)"
                ),
            });
        }
        let records_len = le_u64(&body[start - 8..]);
        let end = usize::try_from(records_len)
            .ok()
            .and_then(|l| start.checked_add(l))
            .filter(|e| *e <= body.len())
            .ok_or_else(|| DriveError::Mcap {
                path: path.to_path_buf(),
                location: format!("Chunk record at byte {}", base - 9),
                message: format!("records length {records_len} exceeds the chunk"),
            })?;
        let mut inner_damage = None;
        std::mem::swap(&mut inner_damage, &mut self.damage);
        self.walk(path, &body[..end], start, base, true)?;
        if let Some(d) = self.damage.take() {
            // A complete chunk whose records do not frame: corrupt, not truncated.
            return Err(DriveError::Mcap {
                path: path.to_path_buf(),
                location: format!(
                    "Chunk record at byte {}, inner record at byte {}",
                    base - 9,
                    d.offset
                ),
                message: d.record,
            });
        }
        self.damage = inner_damage;
        Ok(())
    }
}

/// Read an MCAP drive recording from its bytes.
pub(super) fn read_mcap_bytes(path: &Path, bytes: &[u8]) -> Result<LoadedDrive, DriveError> {
    if !bytes.starts_with(mcap::MAGIC) {
        return Err(DriveError::UnknownFormat {
            path: path.to_path_buf(),
            reason: "no MCAP magic at the start".to_string(),
        });
    }
    let mut scan = Scan::default();
    scan.walk(path, bytes, mcap::MAGIC.len(), 0, false)?;
    let file_len = bytes.len() as u64;
    let messages_read = scan.messages.len();
    let mut warnings = Vec::new();
    match scan.damage.take() {
        // Damage after the data section: every message was read.
        Some(d) if scan.data_end_seen => {
            warnings.push(format!(
                "{}: summary section damaged ({}); every message was read",
                path.display(),
                d.record
            ));
            assemble(path, &scan, warnings)
        }
        Some(d) => {
            warnings.push(format!(
                "{}: truncated ({file_len} bytes): {}; read {messages_read} messages before the damage",
                path.display(),
                d.record
            ));
            let partial = assemble(path, &scan, warnings).ok().map(Box::new);
            Err(DriveError::TruncatedMcap {
                path: path.to_path_buf(),
                offset: d.offset,
                file_len,
                record: d.record,
                messages_read,
                partial,
            })
        }
        None => assemble(path, &scan, warnings),
    }
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
    let merr = |location: &str, message: String| DriveError::Mcap {
        path: path.to_path_buf(),
        location: location.to_string(),
        message,
    };
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
        Some(v) if v <= FORMAT_VERSION => {}
        _ => {
            return Err(merr(
                &format!("metadata {DRIVE_METADATA}"),
                format!(
                    "format_version {:?} is not supported (this tool reads up to {FORMAT_VERSION})",
                    meta.get("format_version")
                ),
            ))
        }
    }
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

    // Channels by topic; others are reported.
    let mut by_topic: BTreeMap<&str, u16> = BTreeMap::new();
    let known = [
        WHEELS_TOPIC,
        GNSS_TOPIC,
        IMU_TOPIC,
        HEADING_TOPIC,
        TRUTH_TOPIC,
    ];
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
    let mut per_channel: BTreeMap<u16, Vec<&RawMessage<'_>>> = BTreeMap::new();
    let mut unknown_channel_messages = 0usize;
    for m in &scan.messages {
        match scan.channels.get(&m.channel_id) {
            Some(c) if by_topic.get(c.topic.as_str()) == Some(&m.channel_id) => {
                per_channel.entry(m.channel_id).or_default().push(m)
            }
            Some(c) if known.contains(&c.topic.as_str()) => {}
            _ => unknown_channel_messages += 1,
        }
    }
    let others: Vec<&str> = scan
        .channels
        .values()
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

    let empty = Vec::new();
    let messages = |topic: &str| {
        by_topic
            .get(topic)
            .map(|id| per_channel.get(id).unwrap_or(&empty))
    };

    let Some(wheel_msgs) = messages(WHEELS_TOPIC) else {
        return Err(merr(
            "channels",
            format!("no `{WHEELS_TOPIC}` channel (wheels are required)"),
        ));
    };
    let wheels_channel = by_topic
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
    let units = parse_wheel_units(units_text).ok_or_else(|| {
        merr(
            &format!("channel {WHEELS_TOPIC}"),
            format!("cannot parse wheel_units `{units_text}` (expected e.g. rl=rad_s,rr=rad_s)"),
        )
    })?;
    let has_ticks = Wheel::ALL
        .iter()
        .any(|&w| units.of(w) == Some(WheelUnit::Ticks));
    if has_ticks && vehicle.ticks_per_rev.is_none() {
        {
            return Err(merr(
                &format!("channel {WHEELS_TOPIC}"),
                "wheels in ticks but vehicle.toml has no ticks_per_rev".to_string(),
            ));
        }
    }
    let columns = wheel_column_names(&units);
    let wheel_samples = decode(path, WHEELS_TOPIC, wheel_msgs, |data| {
        let mut de = serde_json::Deserializer::from_slice(data);
        let s = WheelMsgIn { columns: &columns }.deserialize(&mut de)?;
        de.end()?;
        Ok((
            s.t_s,
            s,
            vec![s.rl, s.rr, s.fl.unwrap_or(0.0), s.fr.unwrap_or(0.0)],
        ))
    })?;
    let gnss = messages(GNSS_TOPIC)
        .map(|m| {
            decode(path, GNSS_TOPIC, m, |data| {
                let g: GnssMsg = serde_json::from_slice(data)?;
                let s = GnssSample {
                    t_s: g.t_s,
                    x_m: g.x_m,
                    y_m: g.y_m,
                    sigma_m: g.sigma_m,
                };
                Ok((s.t_s, s, vec![s.x_m, s.y_m, s.sigma_m.unwrap_or(0.0)]))
            })
        })
        .transpose()?;
    let imu = messages(IMU_TOPIC)
        .map(|m| {
            decode(path, IMU_TOPIC, m, |data| {
                let g: ImuMsg = serde_json::from_slice(data)?;
                let s = ImuSample {
                    t_s: g.t_s,
                    gz_rad_s: g.gz_rad_s,
                    ax_m_s2: g.ax_m_s2,
                    ay_m_s2: g.ay_m_s2,
                    az_m_s2: g.az_m_s2,
                    gx_rad_s: g.gx_rad_s,
                    gy_rad_s: g.gy_rad_s,
                };
                let opt = [s.ax_m_s2, s.ay_m_s2, s.az_m_s2, s.gx_rad_s, s.gy_rad_s];
                let mut values = vec![s.gz_rad_s];
                values.extend(opt.iter().flatten());
                Ok((s.t_s, s, values))
            })
        })
        .transpose()?;
    let heading = messages(HEADING_TOPIC)
        .map(|m| {
            decode(path, HEADING_TOPIC, m, |data| {
                let g: HeadingMsg = serde_json::from_slice(data)?;
                let s = HeadingSample {
                    t_s: g.t_s,
                    yaw_rad: g.yaw_rad,
                    sigma_rad: g.sigma_rad,
                };
                Ok((s.t_s, s, vec![s.yaw_rad, s.sigma_rad.unwrap_or(0.0)]))
            })
        })
        .transpose()?;
    let truth = messages(TRUTH_TOPIC)
        .map(|m| {
            decode(path, TRUTH_TOPIC, m, |data| {
                let g: TruthMsg = serde_json::from_slice(data)?;
                let s = TruthSample {
                    t_s: g.t_s,
                    x_m: g.x_m,
                    y_m: g.y_m,
                    yaw_rad: g.yaw_rad,
                };
                Ok((s.t_s, s, vec![s.x_m, s.y_m, s.yaw_rad.unwrap_or(0.0)]))
            })
        })
        .transpose()?;

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

/// Decode every message of one channel, checking that `t_s` strictly
/// increases and (JSON having no NaN) that every value is finite.
fn decode<T>(
    path: &Path,
    topic: &str,
    messages: &[&RawMessage<'_>],
    parse: impl Fn(&[u8]) -> Result<(f64, T, Vec<f64>), serde_json::Error>,
) -> Result<Vec<T>, DriveError> {
    let mut out = Vec::with_capacity(messages.len());
    let mut previous: Option<f64> = None;
    for (i, m) in messages.iter().enumerate() {
        let location = || format!("channel {topic}, message {i} (record at byte {})", m.offset);
        let (t, sample, values) = parse(m.data).map_err(|e| DriveError::Mcap {
            path: path.to_path_buf(),
            location: location(),
            message: format!("bad JSON message: {e}"),
        })?;
        if !t.is_finite() || values.iter().any(|v| !v.is_finite()) {
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
