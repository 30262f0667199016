//! The MCAP recording: bit-identical round trips, validity for the `mcap`
//! crate's own reader (channels with JSON schemas), truncated and bad files.

// Helpers outside #[test] functions unwrap too: a failure is a test failure.
#![allow(clippy::unwrap_used)]

use drive_io::{read_drive, write_drive, DriveError};
use drive_io::{FORMAT_MAGIC, TRUTH_TOPIC};
use interfaces::drive::{
    toml_value::Value, Drive, GnssAntenna, GnssSample, HeadingSample, ImuSample, TruthParams,
    TruthSample, VehicleParams, WheelCircumferences, WheelSample, WheelSeries, WheelUnit,
    WheelUnits,
};
use interfaces::wire;
use std::collections::BTreeMap;
use std::path::Path;

/// Awkward floats: shortest-text round trips must keep their bits.
fn awkward(i: usize) -> f64 {
    match i % 7 {
        0 => 0.1 * i as f64,
        1 => 1.0 / 3.0 + i as f64,
        2 => 1e-300 * i as f64,
        3 => -(i as f64).sqrt(),
        4 => 5e-324,
        5 => 1.7976931348623157e308 / (i as f64 + 1.0),
        _ => std::f64::consts::PI * 1e12 + i as f64,
    }
}

/// A drive with every optional stream and column, mixed wheel units
/// (ticks, rev, rad/s), negative times and truth.toml.
fn synthetic_drive(n: usize) -> Drive {
    let t = |i: usize, rate: f64| -3.0 + i as f64 / rate + 1e-7 * (i % 3) as f64;
    let mut extra = BTreeMap::new();
    extra.insert(
        "scenario".to_string(),
        Value::String("figure-eight \"quoted\"".to_string()),
    );
    extra.insert("seed".to_string(), Value::Integer(42));
    extra.insert("gnss_rate_hz".to_string(), Value::Float(0.1 + 0.2));
    extra.insert(
        "flags".to_string(),
        Value::Array(vec![Value::Bool(true), Value::Bool(false)]),
    );
    extra.insert(
        "sensor".to_string(),
        Value::Table(BTreeMap::from([(
            "imu_noise".to_string(),
            Value::Float(1.0 / 3.0),
        )])),
    );
    Drive {
        vehicle: VehicleParams {
            name: Some("synthetic, \"quoted\" ünïcode".to_string()),
            track_width_m: 1.53 + 1e-15,
            nominal_circumference_m: 2.0 / 3.0 + 1.5,
            wheelbase_m: Some(2.7),
            ticks_per_rev: Some(96.0),
            gnss: GnssAntenna {
                antenna_x_m: Some(0.1 + 0.2),
                antenna_y_m: Some(-0.0),
                origin_lat_deg: Some(32.765_534_6),
                origin_lon_deg: Some(35.013_636_2),
            },
        },
        wheels: WheelSeries {
            units: WheelUnits {
                rl: WheelUnit::Ticks,
                rr: WheelUnit::Ticks,
                fl: Some(WheelUnit::Rev),
                fr: Some(WheelUnit::RadS),
            },
            samples: (0..n)
                .map(|i| WheelSample {
                    t_s: t(i, 100.0),
                    rl: (i * 3) as f64,
                    rr: (i * 3 + 1) as f64,
                    fl: (!i.is_multiple_of(5)).then(|| awkward(i)),
                    fr: (!i.is_multiple_of(4)).then(|| awkward(i + 1)),
                })
                .collect(),
        },
        gnss: Some(
            (0..n / 10)
                .map(|i| GnssSample {
                    t_s: t(i, 10.0),
                    x_m: awkward(i),
                    y_m: awkward(i + 3),
                    sigma_m: (i.is_multiple_of(2)).then_some(0.05 * i as f64),
                })
                .collect(),
        ),
        imu: Some(
            (0..n)
                .map(|i| ImuSample {
                    t_s: t(i, 100.0) + 0.001,
                    gz_rad_s: awkward(i + 2),
                    ax_m_s2: Some(awkward(i + 4)),
                    ay_m_s2: (i.is_multiple_of(3)).then(|| awkward(i + 5)),
                    az_m_s2: Some(9.81),
                    gx_rad_s: (i.is_multiple_of(2)).then(|| awkward(i + 6)),
                    gy_rad_s: Some(-1e-5 * i as f64),
                })
                .collect(),
        ),
        heading: Some(
            (0..n / 20)
                .map(|i| HeadingSample {
                    t_s: t(i, 5.0),
                    yaw_rad: awkward(i) % 3.0,
                    sigma_rad: (i % 3 != 1).then_some(0.01),
                })
                .collect(),
        ),
        truth: Some(
            (0..n / 2)
                .map(|i| TruthSample {
                    t_s: t(i, 50.0),
                    x_m: awkward(i + 1),
                    y_m: awkward(i + 2),
                    yaw_rad: (!i.is_multiple_of(10)).then(|| awkward(i + 3) % 3.0),
                })
                .collect(),
        ),
        truth_params: Some(TruthParams {
            track_width_m: 1.5312345678901234,
            circumference_m: WheelCircumferences {
                rl: 2.1612,
                rr: 2.1598,
                fl: 2.1630,
                fr: 2.1625,
            },
            effects: BTreeMap::from([
                (
                    "side_slip".to_string(),
                    BTreeMap::from([("k_beta".to_string(), 0.004)]),
                ),
                (
                    "gnss_latency".to_string(),
                    BTreeMap::from([("tau_s".to_string(), 0.08)]),
                ),
            ]),
            extra,
        }),
    }
}

/// Equal, and equal to the last bit (Debug prints the shortest round-trip
/// text of every float and tells -0.0 from 0.0).
fn assert_identical(a: &Drive, b: &Drive) {
    assert!(a == b, "drives differ");
    assert_eq!(format!("{a:?}"), format!("{b:?}"));
}

#[test]
fn synthetic_drive_round_trips_bit_identical() {
    let drive = synthetic_drive(2000);
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("drive");
    let mcap = dir.path().join("drive.mcap");
    let folder2 = dir.path().join("again");

    write_drive(&drive, &folder).unwrap();
    let from_folder = read_drive(&folder).unwrap();
    assert!(
        from_folder.warnings.is_empty(),
        "{:?}",
        from_folder.warnings
    );
    assert_identical(&from_folder.drive, &drive);

    write_drive(&from_folder.drive, &mcap).unwrap();
    let from_mcap = read_drive(&mcap).unwrap();
    assert!(from_mcap.warnings.is_empty(), "{:?}", from_mcap.warnings);
    assert_identical(&from_mcap.drive, &drive);

    write_drive(&from_mcap.drive, &folder2).unwrap();
    assert_identical(&read_drive(&folder2).unwrap().drive, &drive);

    // The truth.toml keeps effects and free-form keys.
    let toml = std::fs::read_to_string(folder2.join("truth.toml")).unwrap();
    assert!(
        toml.contains("k_beta = 0.004") && toml.contains("seed = 42"),
        "{toml}"
    );
}

#[test]
fn empty_optional_streams_stay_present() {
    let mut drive = synthetic_drive(10);
    drive.gnss = Some(vec![]);
    drive.heading = None;
    drive.truth = None;
    drive.truth_params = None;
    let dir = tempfile::tempdir().unwrap();
    for p in [dir.path().join("d.mcap"), dir.path().join("d")] {
        write_drive(&drive, &p).unwrap();
        assert_identical(&read_drive(&p).unwrap().drive, &drive);
    }
}

#[test]
fn mcap_opens_in_the_mcap_crate_reader_with_json_schemas() {
    let drive = synthetic_drive(500);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("drive.mcap");
    write_drive(&drive, &path).unwrap();
    let bytes = std::fs::read(&path).unwrap();

    let summary = mcap::Summary::read(&bytes)
        .unwrap()
        .expect("a summary section");
    let mut topics: Vec<&str> = summary
        .channels
        .values()
        .map(|c| c.topic.as_str())
        .collect();
    topics.sort();
    let mut expected = vec![
        wire::WHEELS_SERVICE,
        wire::GNSS_SERVICE,
        wire::IMU_SERVICE,
        wire::HEADING_SERVICE,
        TRUTH_TOPIC,
    ];
    expected.sort();
    assert_eq!(topics, expected);
    for channel in summary.channels.values() {
        assert_eq!(channel.message_encoding, "json", "{}", channel.topic);
        let schema = channel.schema.as_ref().expect("every channel has a schema");
        assert_eq!(schema.encoding, "jsonschema", "{}", channel.topic);
        let json: serde_json::Value = serde_json::from_slice(&schema.data).unwrap();
        assert_eq!(json["type"], "object");
        assert_eq!(
            json["properties"]["t_s"]["type"], "number",
            "{}",
            channel.topic
        );
    }
    let wheels = summary
        .channels
        .values()
        .find(|c| c.topic == wire::WHEELS_SERVICE)
        .unwrap();
    let schema: serde_json::Value =
        serde_json::from_slice(&wheels.schema.as_ref().unwrap().data).unwrap();
    for key in ["rl_ticks", "rr_ticks", "fl_rev", "fr_rad_s"] {
        assert_eq!(schema["properties"][key]["type"], "number", "{key}");
    }
    assert_eq!(
        wheels.metadata["wheel_units"],
        "rl=ticks,rr=ticks,fl=rev,fr=rad_s"
    );

    // Every message decodes as JSON with the exact t_s, in time order.
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let mut last_log_time = 0;
    let mut first_wheel: Option<serde_json::Value> = None;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        assert!(m.log_time >= last_log_time);
        last_log_time = m.log_time;
        let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
        assert!(v["t_s"].is_f64(), "{v}");
        if m.channel.topic == wire::WHEELS_SERVICE && first_wheel.is_none() {
            first_wheel = Some(v);
        }
        *counts.entry(m.channel.topic.clone()).or_default() += 1;
    }
    assert_eq!(counts[wire::WHEELS_SERVICE], 500);
    assert_eq!(counts[wire::GNSS_SERVICE], 50);
    assert_eq!(counts[TRUTH_TOPIC], 250);
    let first = first_wheel.unwrap();
    assert_eq!(first["t_s"].as_f64(), Some(-3.0));
    assert_eq!(first["rl_ticks"].as_f64(), Some(0.0));
    assert!(
        first.get("fl_rev").is_none(),
        "a missing value is an absent key: {first}"
    );

    // Metadata: format magic, tool version, vehicle.toml, truth.toml.
    let mut metadata = BTreeMap::new();
    for index in &summary.metadata_indexes {
        let m = mcap::read::metadata(&bytes, index).unwrap();
        metadata.insert(m.name.clone(), m.metadata);
    }
    let drive_meta = &metadata["wheelcal.drive"];
    assert_eq!(drive_meta["format"], FORMAT_MAGIC);
    assert_eq!(drive_meta["format_version"], "1");
    assert_eq!(drive_meta["tool_version"], env!("CARGO_PKG_VERSION"));
    // Times start at -3 s: log times are offset by 3 s.
    assert_eq!(drive_meta["log_time_offset_ns"], "3000000000");
    let vehicle_toml = &metadata["wheelcal.vehicle"]["vehicle.toml"];
    assert!(
        vehicle_toml.contains("ticks_per_rev = 96.0"),
        "{vehicle_toml}"
    );
    assert!(metadata["wheelcal.truth"]["truth.toml"].contains("[effects.side_slip]"));
}

fn truncated_copy(bytes: &[u8], len: usize, dir: &Path) -> std::path::PathBuf {
    let path = dir.join(format!("cut{len}.mcap"));
    std::fs::write(&path, &bytes[..len]).unwrap();
    path
}

#[test]
fn truncated_mcap_is_read_up_to_the_damage() {
    let drive = synthetic_drive(20_000);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("drive.mcap");
    write_drive(&drive, &path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let total = drive.wheels.samples.len();

    let mut previous_count = 0;
    for fraction in [0.3, 0.6, 0.9] {
        let len = (bytes.len() as f64 * fraction) as usize;
        let cut = truncated_copy(&bytes, len, dir.path());
        let err = read_drive(&cut).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains(&format!("truncated ({len} bytes)")) && msg.contains("damage at byte"),
            "{msg}"
        );
        assert!(
            msg.contains("the Chunk record at byte") && msg.contains("only"),
            "{msg}"
        );
        let DriveError::TruncatedMcap {
            offset,
            partial,
            messages_read,
            ..
        } = err
        else {
            panic!("not a TruncatedMcap: {msg}");
        };
        assert!(offset < len as u64 && offset > 8);
        let partial = partial.expect("the metadata comes first, so a partial drive exists");
        assert!(
            partial.warnings.iter().any(|w| w.contains("truncated (")),
            "{:?}",
            partial.warnings
        );
        let wheels = &partial.drive.wheels.samples;
        // What was read is an exact prefix of the drive; it grows with the cut.
        assert!(
            !wheels.is_empty() && wheels.len() < total,
            "{} of {total}",
            wheels.len()
        );
        assert!(wheels.len() > previous_count);
        previous_count = wheels.len();
        assert_eq!(wheels[..], drive.wheels.samples[..wheels.len()]);
        let imu = partial.drive.imu.as_ref().unwrap();
        assert_eq!(imu[..], drive.imu.as_ref().unwrap()[..imu.len()]);
        assert_eq!(partial.drive.vehicle, drive.vehicle);
        assert!(messages_read > wheels.len());
    }

    // Cut inside the first metadata record: nothing usable, but the place is named.
    let cut = truncated_copy(&bytes, 60, dir.path());
    let err = read_drive(&cut).unwrap_err();
    assert!(
        err.to_string().contains("the Metadata record at byte"),
        "{err}"
    );
    assert!(matches!(
        err,
        DriveError::TruncatedMcap { partial: None, .. }
    ));

    // Cut at a record boundary (no footer): still a truncation.
    let cut = truncated_copy(&bytes, 8, dir.path());
    let msg = read_drive(&cut).unwrap_err().to_string();
    assert!(
        msg.contains("truncated (8 bytes)")
            && msg.contains("the file ends at byte 8 without a Footer"),
        "{msg}"
    );

    // Only the end of the summary section lost: every message is there, with a warning.
    let cut = truncated_copy(&bytes, bytes.len() - 20, dir.path());
    let loaded = read_drive(&cut).unwrap();
    assert_eq!(loaded.drive, drive);
    assert!(
        loaded
            .warnings
            .iter()
            .any(|w| w.contains("summary section damaged")),
        "{:?}",
        loaded.warnings
    );
}

/// A hand-written recording with one wheels channel and the given messages.
fn hand_written_mcap(path: &Path, messages: &[&str]) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::WriteOptions::new()
        .compression(None)
        .create(file)
        .unwrap();
    w.write_metadata(&mcap::records::Metadata {
        name: "wheelcal.drive".into(),
        metadata: BTreeMap::from([
            ("format".to_string(), FORMAT_MAGIC.to_string()),
            ("format_version".to_string(), "1".to_string()),
        ]),
    })
    .unwrap();
    w.write_metadata(&mcap::records::Metadata {
        name: "wheelcal.vehicle".into(),
        metadata: BTreeMap::from([(
            "vehicle.toml".to_string(),
            "track_width_m = 1.5\nnominal_circumference_m = 2.0\n".to_string(),
        )]),
    })
    .unwrap();
    let schema = w
        .add_schema("wheelcal.Wheels", "jsonschema", b"{\"type\":\"object\"}")
        .unwrap();
    let meta = BTreeMap::from([("wheel_units".to_string(), "rl=rev,rr=rev".to_string())]);
    let channel = w
        .add_channel(schema, wire::WHEELS_SERVICE, "json", &meta)
        .unwrap();
    let other = w
        .add_channel(0, "/camera/front", "json", &BTreeMap::new())
        .unwrap();
    for (i, m) in messages.iter().enumerate() {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: i as u32,
            log_time: i as u64,
            publish_time: i as u64,
        };
        w.write_to_known_channel(&header, m.as_bytes()).unwrap();
        let header = mcap::records::MessageHeader {
            channel_id: other,
            ..header
        };
        w.write_to_known_channel(&header, b"{}").unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn bad_mcap_messages_name_the_channel() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.mcap");

    hand_written_mcap(
        &path,
        &[
            r#"{"t_s":0,"rl_rev":0,"rr_rev":0}"#,
            r#"{"t_s":1,"rl_rev":1,"rr_rev":2}"#,
        ],
    );
    let loaded = read_drive(&path).unwrap();
    assert_eq!(loaded.drive.wheels.samples.len(), 2);
    assert_eq!(loaded.drive.wheels.samples[1].rr, 2.0);
    assert!(
        loaded
            .warnings
            .iter()
            .any(|w| w.contains("ignored 2 message(s)") && w.contains("/camera/front")),
        "{:?}",
        loaded.warnings
    );

    hand_written_mcap(
        &path,
        &[
            r#"{"t_s":1,"rl_rev":0,"rr_rev":0}"#,
            r#"{"t_s":0.5,"rl_rev":0,"rr_rev":0}"#,
        ],
    );
    let msg = read_drive(&path).unwrap_err().to_string();
    assert!(
        msg.contains("channel wheelcal/sensors/wheels, message 1")
            && msg.contains("t_s = 0.5 does not increase"),
        "{msg}"
    );

    hand_written_mcap(&path, &[r#"{"t_s":"soon","rl_rev":0,"rr_rev":0}"#]);
    let msg = read_drive(&path).unwrap_err().to_string();
    assert!(
        msg.contains("channel wheelcal/sensors/wheels, message 0")
            && msg.contains("bad JSON message"),
        "{msg}"
    );

    hand_written_mcap(&path, &[r#"{"t_s":0,"rl_rad_s":0,"rr_rev":0}"#]);
    let msg = read_drive(&path).unwrap_err().to_string();
    assert!(msg.contains("unexpected key `rl_rad_s`"), "{msg}");

    hand_written_mcap(&path, &[r#"{"t_s":0,"rl_rev":0}"#]);
    let msg = read_drive(&path).unwrap_err().to_string();
    assert!(
        msg.contains("message 0") && msg.contains("missing `rr_rev`"),
        "{msg}"
    );
}

#[test]
fn files_that_are_not_drives_are_refused_with_a_reason() {
    let dir = tempfile::tempdir().unwrap();
    let text = dir.path().join("notes.mcap");
    std::fs::write(&text, "hello").unwrap();
    let msg = read_drive(&text).unwrap_err().to_string();
    assert!(
        msg.contains("notes.mcap") && msg.contains("MCAP magic"),
        "{msg}"
    );

    // A valid MCAP that is not a drive recording.
    let path = dir.path().join("other.mcap");
    let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    let mut w = mcap::WriteOptions::new()
        .compression(None)
        .create(file)
        .unwrap();
    w.finish().unwrap();
    drop(w);
    let msg = read_drive(&path).unwrap_err().to_string();
    assert!(msg.contains("no `wheelcal.drive` metadata"), "{msg}");
}
