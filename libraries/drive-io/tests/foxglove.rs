//! Foxglove's channels in a recording (`WriteOptions::foxglove`): their
//! messages have the fields and JSON types Foxglove documents for its
//! well-known schemas, one message per sample, GNSS latitude and longitude
//! within 1e-8 degrees (about 1 mm) of an independent reference, unit
//! quaternions; and the drive reads back exactly as without them.
//!
//! The expected fields are written here from Foxglove's published schema
//! tables (docs.foxglove.dev, "Message schemas": LocationFix, PoseInFrame,
//! FrameTransform, Log; the optional LocationFix `color` and `metadata`
//! are not written), not taken from any schema file.

// Helpers outside #[test] functions unwrap too: a failure is a test failure.
#![allow(clippy::unwrap_used)]

use drive_io::geodesy::LocalFrame;
use drive_io::{
    read_drive, write_drive, write_drive_with, WriteOptions, FOXGLOVE_LOCATION_TOPIC,
    FOXGLOVE_LOG_TOPIC, FOXGLOVE_TF_TOPIC, FOXGLOVE_TRUTH_POSE_TOPIC,
};
use interfaces::drive::{
    Drive, GnssAntenna, GnssSample, TruthSample, VehicleParams, WheelSample, WheelSeries,
    WheelUnit, WheelUnits,
};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;

/// JSON type of a field as Foxglove's JSON encoding gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Json {
    /// `time`: an object `{sec, nsec}` of non-negative integers.
    Time,
    /// `string`.
    Str,
    /// `float64`.
    Number,
    /// An unsigned integer enumeration or `uint32`, at most this value.
    UInt(u64),
    /// `float64[9]`.
    Numbers9,
    /// `Vector3`: `{x, y, z}` numbers.
    Vector3,
    /// `Quaternion`: `{x, y, z, w}` numbers.
    Quaternion,
    /// `Pose`: `{position: Vector3, orientation: Quaternion}`.
    Pose,
}

/// Field names and types of each schema, from Foxglove's documentation.
fn published(schema: &str) -> Vec<(&'static str, Json)> {
    match schema {
        "foxglove.LocationFix" => vec![
            ("timestamp", Json::Time),
            ("frame_id", Json::Str),
            ("latitude", Json::Number),
            ("longitude", Json::Number),
            ("altitude", Json::Number),
            ("position_covariance", Json::Numbers9),
            // PositionCovarianceType: UNKNOWN 0 .. KNOWN 3.
            ("position_covariance_type", Json::UInt(3)),
        ],
        "foxglove.PoseInFrame" => vec![
            ("timestamp", Json::Time),
            ("frame_id", Json::Str),
            ("pose", Json::Pose),
        ],
        "foxglove.FrameTransform" => vec![
            ("timestamp", Json::Time),
            ("parent_frame_id", Json::Str),
            ("child_frame_id", Json::Str),
            ("translation", Json::Vector3),
            ("rotation", Json::Quaternion),
        ],
        "foxglove.Log" => vec![
            ("timestamp", Json::Time),
            // LogLevel: UNKNOWN 0, DEBUG 1, INFO 2, WARNING 3, ERROR 4, FATAL 5.
            ("level", Json::UInt(5)),
            ("message", Json::Str),
            ("name", Json::Str),
            ("file", Json::Str),
            ("line", Json::UInt(u32::MAX as u64)),
        ],
        other => panic!("no published fields for {other}"),
    }
}

fn check_numbers(v: &Value, keys: &[&str], what: &str) {
    let obj = v.as_object().unwrap_or_else(|| panic!("{what}: {v}"));
    let mut got: Vec<&str> = obj.keys().map(String::as_str).collect();
    got.sort();
    let mut want = keys.to_vec();
    want.sort();
    assert_eq!(got, want, "{what}");
    for k in keys {
        assert!(v[k].is_number(), "{what}.{k}: {v}");
    }
}

/// A message has exactly the published fields, each of its JSON type.
fn check_message(schema: &str, msg: &Value) {
    let fields = published(schema);
    let obj = msg.as_object().unwrap();
    let mut got: Vec<&str> = obj.keys().map(String::as_str).collect();
    got.sort();
    let mut want: Vec<&str> = fields.iter().map(|(n, _)| *n).collect();
    want.sort();
    assert_eq!(got, want, "{schema}: {msg}");
    for (name, kind) in fields {
        let v = &msg[name];
        let what = format!("{schema}.{name}");
        match kind {
            Json::Time => {
                check_numbers(v, &["sec", "nsec"], &what);
                assert!(v["sec"].is_u64(), "{what}: {v}");
                assert!(v["nsec"].as_u64().unwrap() < 1_000_000_000, "{what}: {v}");
            }
            Json::Str => assert!(v.is_string(), "{what}: {v}"),
            Json::Number => assert!(v.is_number(), "{what}: {v}"),
            Json::UInt(max) => assert!(v.as_u64().is_some_and(|x| x <= max), "{what}: {v}"),
            Json::Numbers9 => {
                let a = v.as_array().unwrap_or_else(|| panic!("{what}: {v}"));
                assert_eq!(a.len(), 9, "{what}");
                assert!(a.iter().all(Value::is_number), "{what}: {v}");
            }
            Json::Vector3 => check_numbers(v, &["x", "y", "z"], &what),
            Json::Quaternion => check_numbers(v, &["x", "y", "z", "w"], &what),
            Json::Pose => {
                let obj = v.as_object().unwrap();
                assert_eq!(obj.len(), 2, "{what}: {v}");
                check_numbers(&v["position"], &["x", "y", "z"], &what);
                check_numbers(&v["orientation"], &["x", "y", "z", "w"], &what);
            }
        }
    }
}

/// The schema of a channel declares the published fields with matching
/// JSON types.
fn check_schema(name: &str, data: &[u8]) {
    let schema: Value = serde_json::from_slice(data).unwrap();
    assert_eq!(schema["type"], "object", "{name}");
    for (field, kind) in published(name) {
        let p = &schema["properties"][field];
        let want = match kind {
            Json::Time | Json::Vector3 | Json::Quaternion | Json::Pose => "object",
            Json::Str => "string",
            Json::Number => "number",
            Json::UInt(_) => "integer",
            Json::Numbers9 => "array",
        };
        assert_eq!(p["type"], want, "{name}.{field}: {p}");
    }
}

/// A channel's messages: (log time, JSON), in file order.
type Messages = BTreeMap<String, Vec<(u64, Value)>>;

/// Every channel's messages, checking Foxglove's against their schema.
fn read_channels(bytes: &[u8]) -> Messages {
    let summary = mcap::Summary::read(bytes).unwrap().unwrap();
    for c in summary.channels.values() {
        let schema = c.schema.as_ref().unwrap();
        if schema.name.starts_with("foxglove.") {
            assert_eq!(schema.encoding, "jsonschema", "{}", c.topic);
            assert_eq!(c.message_encoding, "json", "{}", c.topic);
            check_schema(&schema.name, &schema.data);
        }
    }
    let mut out = Messages::new();
    for m in mcap::MessageStream::new(bytes).unwrap() {
        let m = m.unwrap();
        let v: Value = serde_json::from_slice(&m.data).unwrap();
        if let Some(schema) = &m.channel.schema {
            if schema.name.starts_with("foxglove.") {
                check_message(&schema.name, &v);
                // The time stamp is the log time.
                let ns = v["timestamp"]["sec"].as_u64().unwrap() * 1_000_000_000
                    + v["timestamp"]["nsec"].as_u64().unwrap();
                assert_eq!(ns, m.log_time, "{}", m.channel.topic);
            }
        }
        out.entry(m.channel.topic.clone())
            .or_default()
            .push((m.log_time, v));
    }
    out
}

fn quaternion_norm(q: &Value) -> f64 {
    ["x", "y", "z", "w"]
        .iter()
        .map(|k| q[k].as_f64().unwrap().powi(2))
        .sum::<f64>()
        .sqrt()
}

/// A drive whose GNSS fixes are the known `points` (converted to ENU about
/// `origin` by our forward conversion), with a truth, some of it without yaw.
fn drive_around(origin: (f64, f64), points: &[(f64, f64)]) -> Drive {
    let frame = LocalFrame::new(origin.0, origin.1, 0.0);
    let gnss = points
        .iter()
        .enumerate()
        .map(|(i, &(lat, lon))| {
            let (x_m, y_m) = frame.to_en(lat, lon);
            GnssSample {
                t_s: i as f64 * 0.2 - 1.0,
                x_m,
                y_m,
                sigma_m: (i % 2 == 0).then_some(0.5 + i as f64),
            }
        })
        .collect();
    let truth = (0..40)
        .map(|i| TruthSample {
            t_s: i as f64 * 0.1 - 1.0,
            x_m: i as f64,
            y_m: -0.5 * i as f64,
            yaw_rad: (i % 3 != 0).then_some(0.37 * i as f64 - 4.0),
        })
        .collect();
    Drive {
        vehicle: VehicleParams {
            name: Some("foxglove test".to_string()),
            track_width_m: 1.5,
            nominal_circumference_m: 2.0,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: GnssAntenna {
                origin_lat_deg: Some(origin.0),
                origin_lon_deg: Some(origin.1),
                ..GnssAntenna::default()
            },
        },
        wheels: WheelSeries {
            units: WheelUnits::rear(WheelUnit::RadS),
            samples: (0..100)
                .map(|i| WheelSample {
                    t_s: i as f64 * 0.05 - 1.0,
                    rl: 10.0,
                    rr: 10.5,
                    fl: None,
                    fr: None,
                })
                .collect(),
        },
        gnss: Some(gnss),
        imu: None,
        heading: None,
        truth: Some(truth),
        truth_params: None,
    }
}

fn foxglove_options(warnings: &[&str]) -> WriteOptions {
    WriteOptions {
        foxglove: true,
        warnings: warnings.iter().map(|w| w.to_string()).collect(),
        ..WriteOptions::default()
    }
}

fn write_and_read(drive: &Drive, path: &Path, options: &WriteOptions) -> Messages {
    write_drive_with(drive, path, options).unwrap();
    read_channels(&std::fs::read(path).unwrap())
}

#[test]
fn channels_follow_the_published_schemas_and_count_the_samples() {
    let origin = (48.1, 11.5);
    let points: Vec<(f64, f64)> = (0..25)
        .map(|i| (48.1 + 0.001 * i as f64, 11.5 - 0.0013 * i as f64))
        .collect();
    let drive = drive_around(origin, &points);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fox.mcap");
    let warnings = ["gnss.csv: ignored 2 row(s)", "imu.csv: unknown column `q`"];
    let channels = write_and_read(&drive, &path, &foxglove_options(&warnings));

    let gnss = drive.gnss.as_ref().unwrap();
    let truth = drive.truth.as_ref().unwrap();
    assert_eq!(channels[FOXGLOVE_LOCATION_TOPIC].len(), gnss.len());
    assert_eq!(channels[FOXGLOVE_TRUTH_POSE_TOPIC].len(), truth.len());
    assert_eq!(channels[FOXGLOVE_TF_TOPIC].len(), truth.len());
    assert_eq!(channels[FOXGLOVE_LOG_TOPIC].len(), warnings.len());

    // Fixes: the known points; covariance from sigma (east, north).
    for ((_, fix), (s, (lat, lon))) in channels[FOXGLOVE_LOCATION_TOPIC]
        .iter()
        .zip(gnss.iter().zip(&points))
    {
        assert!(
            (fix["latitude"].as_f64().unwrap() - lat).abs() < 1e-10,
            "{fix}"
        );
        assert!(
            (fix["longitude"].as_f64().unwrap() - lon).abs() < 1e-10,
            "{fix}"
        );
        let cov: Vec<f64> = fix["position_covariance"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        match s.sigma_m {
            Some(sigma) => {
                assert_eq!(fix["position_covariance_type"], 2);
                assert_eq!(cov[0], sigma * sigma);
                assert_eq!(cov[4], sigma * sigma);
            }
            None => assert_eq!(fix["position_covariance_type"], 0),
        }
    }
    // Poses: the truth, unit quaternions turning by the yaw (identity
    // without one); the transforms say the same.
    for (((_, pose), (_, tf)), s) in channels[FOXGLOVE_TRUTH_POSE_TOPIC]
        .iter()
        .zip(&channels[FOXGLOVE_TF_TOPIC])
        .zip(truth)
    {
        assert_eq!(pose["frame_id"], "enu");
        assert_eq!(tf["parent_frame_id"], "enu");
        assert_eq!(tf["child_frame_id"], "base_link");
        assert_eq!(pose["pose"]["position"]["x"].as_f64(), Some(s.x_m));
        assert_eq!(pose["pose"]["position"]["y"].as_f64(), Some(s.y_m));
        assert_eq!(tf["translation"], pose["pose"]["position"]);
        assert_eq!(tf["rotation"], pose["pose"]["orientation"]);
        let q = &pose["pose"]["orientation"];
        assert!((quaternion_norm(q) - 1.0).abs() < 1e-12, "{q}");
        let yaw = 2.0 * q["z"].as_f64().unwrap().atan2(q["w"].as_f64().unwrap());
        let want = s.yaw_rad.unwrap_or(0.0);
        let diff = (yaw - want).rem_euclid(std::f64::consts::TAU);
        assert!(
            diff.min(std::f64::consts::TAU - diff) < 1e-12,
            "{yaw} {want}"
        );
    }
    // Logs: the warnings, level WARNING, at the drive's first time.
    let first_log_time = channels.values().flatten().map(|(t, _)| *t).min();
    for ((t, log), w) in channels[FOXGLOVE_LOG_TOPIC].iter().zip(warnings) {
        assert_eq!(log["message"], w);
        assert_eq!(log["level"], 3);
        assert_eq!(Some(*t), first_log_time);
    }

    // Our own channels read back exactly, without a warning; and exactly
    // as the recording without Foxglove's channels does.
    let back = read_drive(&path).unwrap();
    assert!(back.warnings.is_empty(), "{:?}", back.warnings);
    assert!(back.drive == drive);
    let plain_path = dir.path().join("plain.mcap");
    write_drive(&drive, &plain_path).unwrap();
    let plain = read_channels(&std::fs::read(&plain_path).unwrap());
    for (topic, messages) in &plain {
        assert_eq!(&channels[topic], messages, "{topic}");
    }
    assert_eq!(channels.len(), plain.len() + 4);
}

/// Fixes 50 to 300 km from the origin, in four directions and across a
/// latitude band where the surface falls kilometres below the origin's
/// tangent plane: latitude and longitude come back within 1e-9 degrees.
#[test]
fn fixes_far_from_the_origin_come_back_in_degrees() {
    let origin = (-33.86, 151.21);
    let points = [
        (-33.86, 151.21),
        (-33.41, 151.21),
        (-34.31, 151.21),
        (-33.86, 151.75),
        (-33.86, 150.67),
        (-31.2, 149.9),
        (-36.0, 153.5),
    ];
    let drive = drive_around(origin, &points);
    let dir = tempfile::tempdir().unwrap();
    let channels = write_and_read(&drive, &dir.path().join("far.mcap"), &foxglove_options(&[]));
    assert!(!channels.contains_key(FOXGLOVE_LOG_TOPIC));
    let fixes = &channels[FOXGLOVE_LOCATION_TOPIC];
    assert_eq!(fixes.len(), points.len());
    for ((_, fix), (lat, lon)) in fixes.iter().zip(points) {
        assert!(
            (fix["latitude"].as_f64().unwrap() - lat).abs() < 1e-9,
            "{fix}"
        );
        assert!(
            (fix["longitude"].as_f64().unwrap() - lon).abs() < 1e-9,
            "{fix}"
        );
    }
}

#[test]
fn a_drive_without_a_geodetic_origin_has_no_location_fixes() {
    let mut drive = drive_around((10.0, 20.0), &[(10.0, 20.0), (10.001, 20.0)]);
    drive.vehicle.gnss = GnssAntenna::default();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("local.mcap");
    let channels = write_and_read(&drive, &path, &foxglove_options(&[]));
    assert!(!channels.contains_key(FOXGLOVE_LOCATION_TOPIC));
    assert_eq!(channels[FOXGLOVE_TRUTH_POSE_TOPIC].len(), 40);
    assert!(read_drive(&path).unwrap().drive == drive);
}

/// The real drive's `gnss.csv` latitudes and longitudes, read here on their
/// own, against the fixes written from the drive as read (local ENU).
#[test]
fn real_drive_fixes_match_its_csv_within_a_millimetre() {
    let Some(dir) = drive_io::dev_data::real_drive("wid-trial02") else {
        eprintln!(
            "SKIPPED: {} has no wid-trial02 (the real drives are not in this checkout)",
            drive_io::dev_data::real_data_dir().display()
        );
        return;
    };
    let text = std::fs::read_to_string(dir.join("gnss.csv")).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (lat_col, lon_col) = (col("lat_deg"), col("lon_deg"));
    let csv: Vec<(f64, f64)> = lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            (
                cells[lat_col].trim().parse().unwrap(),
                cells[lon_col].trim().parse().unwrap(),
            )
        })
        .collect();

    let loaded = read_drive(&dir).unwrap();
    let out = tempfile::tempdir().unwrap();
    let path = out.path().join("trial02.mcap");
    let channels = write_and_read(&loaded.drive, &path, &foxglove_options(&[]));
    let fixes = &channels[FOXGLOVE_LOCATION_TOPIC];
    assert_eq!(fixes.len(), csv.len());
    let mut worst = 0.0f64;
    for ((_, fix), (lat, lon)) in fixes.iter().zip(&csv) {
        let dlat = (fix["latitude"].as_f64().unwrap() - lat).abs();
        let dlon = (fix["longitude"].as_f64().unwrap() - lon).abs();
        worst = worst.max(dlat).max(dlon);
    }
    eprintln!("wid-trial02: worst lat/lon difference {worst:e} degrees");
    assert!(worst < 1e-8, "worst difference {worst} degrees");
    let truth = loaded.drive.truth.as_ref().unwrap();
    assert_eq!(channels[FOXGLOVE_TRUTH_POSE_TOPIC].len(), truth.len());
    let back = read_drive(&path).unwrap();
    assert!(back.warnings.is_empty(), "{:?}", back.warnings);
    assert!(back.drive == loaded.drive);
}

/// A drive whose times are UNIX seconds (ROS bags, NMEA with dates) is
/// stamped at its real date; one on a clock from 0 stays near 1970.
#[test]
fn unix_times_give_absolute_time_stamps() {
    let t0 = 1_700_000_000.25;
    let mut drive = drive_around((10.0, 20.0), &[(10.0, 20.0), (10.001, 20.0)]);
    for s in &mut drive.wheels.samples {
        s.t_s += t0;
    }
    for s in drive.gnss.iter_mut().flatten() {
        s.t_s += t0;
    }
    for s in drive.truth.iter_mut().flatten() {
        s.t_s += t0;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("unix.mcap");
    let channels = write_and_read(&drive, &path, &foxglove_options(&["w"]));
    let first = &channels[FOXGLOVE_LOCATION_TOPIC][0].1;
    let want = (t0 - 1.0) * 1e9;
    let got = first["timestamp"]["sec"].as_f64().unwrap() * 1e9
        + first["timestamp"]["nsec"].as_f64().unwrap();
    assert!((got - want).abs() < 1e3, "{first}");
    assert_eq!(channels[FOXGLOVE_LOG_TOPIC][0].0, first_log_time(&channels));
    assert!(read_drive(&path).unwrap().drive == drive);
}

fn first_log_time(channels: &Messages) -> u64 {
    channels.values().flatten().map(|(t, _)| *t).min().unwrap()
}
