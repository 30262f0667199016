//! Recordings from other tools: our recording re-written with zstd and lz4
//! chunks by the `mcap` crate's writer, ROS 2 bags (CDR messages written
//! here by hand, little and big endian), and NMEA logs in a drive folder.

// Helpers outside #[test] functions unwrap too: a failure is a test failure.
#![allow(clippy::unwrap_used)]

use drive_io::{read_drive, read_drive_with, write_drive, DriveError, ReadOptions, TopicMap};
use interfaces::drive::{
    Drive, GnssAntenna, GnssSample, ImuSample, VehicleParams, WheelSample, WheelSeries, WheelUnit,
    WheelUnits,
};
use mcap::records::{MessageHeader, Metadata, Record};
use std::collections::BTreeMap;
use std::path::Path;

/// A drive of `n` wheel samples at 100 Hz (rad/s), GNSS at 10 Hz (ENU),
/// IMU at 100 Hz, times from -1 s.
fn drive(n: usize) -> Drive {
    let t = |i: usize| -1.0 + i as f64 * 0.01;
    Drive {
        vehicle: VehicleParams {
            name: Some("test car".to_string()),
            track_width_m: 1.5,
            nominal_circumference_m: 2.0,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: GnssAntenna::default(),
        },
        wheels: WheelSeries {
            units: WheelUnits::rear(WheelUnit::RadS),
            samples: (0..n)
                .map(|i| WheelSample {
                    t_s: t(i),
                    rl: 10.0 + (i as f64 * 0.1).sin(),
                    rr: 10.5 + (i as f64 * 0.1).cos() / 3.0,
                    fl: None,
                    fr: None,
                })
                .collect(),
        },
        gnss: Some(
            (0..n / 10)
                .map(|i| GnssSample {
                    t_s: t(10 * i) + 0.003,
                    x_m: i as f64 * 0.3,
                    y_m: (i as f64 * 0.05).sin(),
                    sigma_m: Some(0.5),
                })
                .collect(),
        ),
        imu: Some(
            (0..n)
                .map(|i| ImuSample {
                    t_s: t(i) + 0.001,
                    gz_rad_s: 0.01 * (i as f64).cos(),
                    ax_m_s2: Some(0.1),
                    ay_m_s2: Some(-0.2 + i as f64 * 1e-3),
                    az_m_s2: Some(9.81),
                    gx_rad_s: Some(0.0),
                    gy_rad_s: Some(1.0 / 3.0),
                })
                .collect(),
        ),
        heading: None,
        truth: None,
        truth_params: None,
    }
}

/// Re-write an MCAP with the `mcap` crate's writer: same metadata,
/// schemas, channels and messages, chunks compressed with `compression`.
fn rewrite(bytes: &[u8], compression: Option<mcap::Compression>) -> Vec<u8> {
    let mut out = Vec::new();
    {
        let mut w = mcap::WriteOptions::new()
            .compression(compression)
            .chunk_size(Some(8 * 1024))
            .create(std::io::Cursor::new(&mut out))
            .unwrap();
        let mut schemas = BTreeMap::new();
        let mut channels = BTreeMap::new();
        let mut copy = |w: &mut mcap::Writer<_>, r: Record<'_>| match r {
            Record::Metadata(m) => w.write_metadata(&m).unwrap(),
            Record::Schema { header, data } => {
                let id = w.add_schema(&header.name, &header.encoding, &data).unwrap();
                schemas.insert(header.id, id);
            }
            Record::Channel(c) => {
                let schema = schemas.get(&c.schema_id).copied().unwrap_or(0);
                let id = w
                    .add_channel(schema, &c.topic, &c.message_encoding, &c.metadata)
                    .unwrap();
                channels.insert(c.id, id);
            }
            Record::Message { header, data } => {
                let header = MessageHeader {
                    channel_id: channels[&header.channel_id],
                    ..header
                };
                w.write_to_known_channel(&header, &data).unwrap();
            }
            _ => {}
        };
        for r in mcap::read::LinearReader::new(bytes).unwrap() {
            match r.unwrap() {
                Record::Chunk { header, data } => {
                    assert_eq!(header.compression, "", "our recordings are uncompressed");
                    for inner in mcap::read::LinearReader::sans_magic(&data) {
                        copy(&mut w, inner.unwrap());
                    }
                }
                other => copy(&mut w, other),
            }
        }
        w.finish().unwrap();
    }
    out
}

/// Byte offsets of the top-level Chunk records.
fn chunk_offsets(bytes: &[u8]) -> Vec<usize> {
    let mut pos = 8;
    let mut out = Vec::new();
    while pos + 9 <= bytes.len() {
        let op = bytes[pos];
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        if op == 0x06 {
            out.push(pos);
        }
        if op == 0x02 {
            break;
        }
        pos += 9 + len;
    }
    out
}

#[test]
fn our_recording_compressed_with_zstd_or_lz4_reads_as_uncompressed() {
    let dir = tempfile::tempdir().unwrap();
    let original = drive(3000);
    let plain = dir.path().join("plain.mcap");
    write_drive(&original, &plain).unwrap();
    let expected = read_drive(&plain).unwrap();
    let bytes = std::fs::read(&plain).unwrap();
    for (name, compression) in [
        ("zstd", Some(mcap::Compression::Zstd)),
        ("lz4", Some(mcap::Compression::Lz4)),
        ("none", None),
    ] {
        let path = dir.path().join(format!("{name}.mcap"));
        let rewritten = rewrite(&bytes, compression);
        assert!(
            chunk_offsets(&rewritten).len() > 3,
            "{name}: several chunks"
        );
        std::fs::write(&path, &rewritten).unwrap();
        let loaded = read_drive(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(loaded.drive, expected.drive, "{name}");
        assert_eq!(loaded.drive, original, "{name}");
    }
}

#[test]
fn a_compressed_chunk_must_decompress_to_exactly_its_declared_size() {
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("plain.mcap");
    write_drive(&drive(2000), &plain).unwrap();
    let bytes = rewrite(
        &std::fs::read(&plain).unwrap(),
        Some(mcap::Compression::Zstd),
    );
    let chunk = chunk_offsets(&bytes)[0];
    // Chunk body: start time, end time, uncompressed size (u64 at 16), crc.
    let size_at = chunk + 9 + 16;
    let declared = u64::from_le_bytes(bytes[size_at..size_at + 8].try_into().unwrap());
    for (value, needle) in [
        (declared - 1, "decompress to more than"),
        (declared + 1, "decompress to"),
        (u64::MAX / 2, "more than the"),
    ] {
        let mut b = bytes.clone();
        b[size_at..size_at + 8].copy_from_slice(&value.to_le_bytes());
        let path = dir.path().join("bad.mcap");
        std::fs::write(&path, &b).unwrap();
        let e = read_drive(&path).unwrap_err();
        let text = e.to_string();
        assert!(matches!(e, DriveError::Mcap { .. }), "{text}");
        assert!(text.contains(needle) && text.contains("chunk 0"), "{text}");
    }
    // A changed byte inside the compressed records: the codec or the CRC says so.
    let mut b = bytes.clone();
    let len = u64::from_le_bytes(bytes[chunk + 1..chunk + 9].try_into().unwrap()) as usize;
    b[chunk + 9 + len - 20] ^= 0x55;
    let path = dir.path().join("flipped.mcap");
    std::fs::write(&path, &b).unwrap();
    let e = read_drive(&path).unwrap_err();
    assert!(
        matches!(e, DriveError::ChunkCrc { .. } | DriveError::Mcap { .. }),
        "{e}"
    );
}

// ------------------------------------------------------------ ROS 2 bags

/// A CDR message writer (XCDR1; alignment from after the header).
struct CdrOut {
    buf: Vec<u8>,
    little: bool,
}

impl CdrOut {
    fn new(little: bool) -> Self {
        CdrOut {
            buf: vec![0, u8::from(little), 0, 0],
            little,
        }
    }
    fn align(&mut self, n: usize) {
        while !(self.buf.len() - 4).is_multiple_of(n) {
            self.buf.push(0);
        }
    }
    fn bytes(&mut self, le: &[u8]) {
        self.align(le.len());
        if self.little {
            self.buf.extend_from_slice(le);
        } else {
            self.buf.extend(le.iter().rev());
        }
    }
    fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }
    fn u16(&mut self, v: u16) {
        self.bytes(&v.to_le_bytes());
    }
    fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.bytes(&v.to_le_bytes());
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }
    fn header(&mut self, ns: i64) {
        self.u32(ns.div_euclid(1_000_000_000) as i32 as u32);
        self.u32(ns.rem_euclid(1_000_000_000) as u32);
        self.string("base_link");
    }
}

const EPOCH_NS: i64 = 1_700_000_000_000_000_000;

fn stamp(t_s: f64) -> i64 {
    EPOCH_NS + (t_s * 1e9).round() as i64
}

fn nav_sat_fix(t_s: f64, lat: f64, lon: f64, sigma: f64, little: bool) -> Vec<u8> {
    let mut c = CdrOut::new(little);
    c.header(stamp(t_s));
    c.u8(0);
    c.u16(1);
    c.f64(lat);
    c.f64(lon);
    c.f64(12.0);
    for k in 0..9 {
        c.f64(if k == 0 || k == 4 { sigma * sigma } else { 0.0 });
    }
    c.u8(2);
    c.buf
}

fn imu(s: &ImuSample, little: bool) -> Vec<u8> {
    let mut c = CdrOut::new(little);
    c.header(stamp(s.t_s));
    for v in [0.0, 0.0, 0.0, 1.0] {
        c.f64(v);
    }
    for _ in 0..9 {
        c.f64(0.0);
    }
    for v in [s.gx_rad_s.unwrap(), s.gy_rad_s.unwrap(), s.gz_rad_s] {
        c.f64(v);
    }
    for _ in 0..9 {
        c.f64(0.0);
    }
    for v in [s.ax_m_s2, s.ay_m_s2, s.az_m_s2] {
        c.f64(v.unwrap());
    }
    for _ in 0..9 {
        c.f64(0.0);
    }
    c.buf
}

fn joint_state(s: &WheelSample, little: bool) -> Vec<u8> {
    let mut c = CdrOut::new(little);
    c.header(stamp(s.t_s));
    let names = [
        "steering_joint",
        "rear_left_wheel_joint",
        "rear_right_wheel_joint",
    ];
    c.u32(3);
    for n in names {
        c.string(n);
    }
    c.u32(3);
    for v in [0.1, 100.0, 200.0] {
        c.f64(v);
    }
    c.u32(3);
    for v in [0.0, s.rl, s.rr] {
        c.f64(v);
    }
    c.u32(0);
    c.buf
}

fn twist_stamped(t_s: f64, v: f64, w: f64) -> Vec<u8> {
    let mut c = CdrOut::new(true);
    c.header(stamp(t_s));
    for x in [v, 0.0, 0.0, 0.0, 0.0, w] {
        c.f64(x);
    }
    c.buf
}

/// Messages of one topic: (t_s, CDR).
type Messages = Vec<(f64, Vec<u8>)>;

/// A bag: (topic, type, messages), zstd chunks.
fn bag(topics: &[(&str, &str, Messages)]) -> Vec<u8> {
    let mut out = Vec::new();
    {
        let mut w = mcap::WriteOptions::new()
            .profile("ros2")
            .compression(Some(mcap::Compression::Zstd))
            .chunk_size(Some(16 * 1024))
            .create(std::io::Cursor::new(&mut out))
            .unwrap();
        let mut all = Vec::new();
        for (topic, type_name, messages) in topics {
            let schema = w.add_schema(type_name, "ros2msg", b"# definition").unwrap();
            let channel = w
                .add_channel(schema, topic, "cdr", &BTreeMap::new())
                .unwrap();
            for (t, m) in messages {
                all.push((stamp(*t), channel, m.clone()));
            }
        }
        all.sort_by_key(|(t, c, _)| (*t, *c));
        for (seq, (t, channel, m)) in all.into_iter().enumerate() {
            let header = MessageHeader {
                channel_id: channel,
                sequence: seq as u32,
                log_time: t as u64,
                publish_time: t as u64,
            };
            w.write_to_known_channel(&header, &m).unwrap();
        }
        w.write_metadata(&Metadata {
            name: "rosbag2".to_string(),
            metadata: BTreeMap::new(),
        })
        .unwrap();
        w.finish().unwrap();
    }
    out
}

/// The test drive's fixes as latitude/longitude.
fn fixes_lat_lon(d: &Drive) -> Vec<(f64, f64, f64)> {
    d.gnss
        .as_ref()
        .unwrap()
        .iter()
        .map(|g| (g.t_s, 32.0 + g.y_m * 1e-5, 35.0 + g.x_m * 1e-5))
        .collect()
}

fn the_bag(d: &Drive, big_endian_imu: bool) -> Vec<u8> {
    let fixes = fixes_lat_lon(d)
        .into_iter()
        .map(|(t, lat, lon)| (t, nav_sat_fix(t, lat, lon, 0.5, true)))
        .collect();
    let imus = d
        .imu
        .as_ref()
        .unwrap()
        .iter()
        .map(|s| (s.t_s, imu(s, !big_endian_imu)))
        .collect();
    let wheels = d
        .wheels
        .samples
        .iter()
        .map(|s| (s.t_s, joint_state(s, true)))
        .collect();
    bag(&[
        ("/fix", "sensor_msgs/msg/NavSatFix", fixes),
        ("/imu/data", "sensor_msgs/msg/Imu", imus),
        ("/joint_states", "sensor_msgs/msg/JointState", wheels),
        ("/rosout", "rcl_interfaces/msg/Log", vec![]),
    ])
}

fn with_vehicle(d: &Drive) -> ReadOptions {
    ReadOptions {
        vehicle: Some(d.vehicle.clone()),
        ..ReadOptions::default()
    }
}

#[test]
fn a_ros2_bag_reads_as_the_drive_it_was_made_from() {
    let d = drive(1500);
    let dir = tempfile::tempdir().unwrap();
    for big_endian_imu in [false, true] {
        let path = dir.path().join("bag.mcap");
        std::fs::write(&path, the_bag(&d, big_endian_imu)).unwrap();
        let e = read_drive(&path).unwrap_err();
        assert!(matches!(e, DriveError::NoVehicle { .. }), "{e}");
        let loaded = read_drive_with(&path, with_vehicle(&d)).unwrap();
        let got = &loaded.drive;
        assert!(
            loaded.warnings.iter().any(|w| w.contains("/rosout")),
            "{:?}",
            loaded.warnings
        );
        // Wheels: rad/s as given; times UNIX seconds.
        assert_eq!(got.wheels.units, WheelUnits::rear(WheelUnit::RadS));
        assert_eq!(got.wheels.samples.len(), d.wheels.samples.len());
        for (a, b) in got.wheels.samples.iter().zip(&d.wheels.samples) {
            assert_eq!((a.rl, a.rr), (b.rl, b.rr));
            assert!(
                (a.t_s - (1.7e9 + b.t_s)).abs() < 1e-6,
                "{} {}",
                a.t_s,
                b.t_s
            );
        }
        let imu = got.imu.as_ref().unwrap();
        for (a, b) in imu.iter().zip(d.imu.as_ref().unwrap()) {
            assert_eq!(
                (a.gz_rad_s, a.ax_m_s2, a.ay_m_s2, a.az_m_s2, a.gx_rad_s, a.gy_rad_s),
                (b.gz_rad_s, b.ax_m_s2, b.ay_m_s2, b.az_m_s2, b.gx_rad_s, b.gy_rad_s)
            );
        }
        // GNSS: the same ENU positions as a folder with the same lat/lon.
        let mut csv = String::from("t_s,lat_deg,lon_deg,sigma_m\n");
        for (t, lat, lon) in fixes_lat_lon(&d) {
            csv.push_str(&format!("{},{lat},{lon},0.5\n", 1.7e9 + t));
        }
        let folder = dir.path().join("folder");
        write_drive(&d, &folder).unwrap();
        std::fs::write(folder.join("gnss.csv"), csv).unwrap();
        let from_folder = read_drive(&folder).unwrap().drive;
        let (g, f) = (
            got.gnss.as_ref().unwrap(),
            from_folder.gnss.as_ref().unwrap(),
        );
        assert_eq!(g.len(), f.len());
        for (a, b) in g.iter().zip(f) {
            assert_eq!((a.x_m, a.y_m, a.sigma_m), (b.x_m, b.y_m, b.sigma_m));
            assert!((a.t_s - b.t_s).abs() < 1e-6);
        }
        assert_eq!(
            got.vehicle.gnss.origin_lat_deg,
            from_folder.vehicle.gnss.origin_lat_deg
        );
    }
}

#[test]
fn a_bag_whose_topics_do_not_fit_says_which_and_what_was_expected() {
    let d = drive(300);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bag.mcap");
    std::fs::write(&path, the_bag(&d, false)).unwrap();
    let read = |assignments: &[&str]| {
        let mut options = with_vehicle(&d);
        for a in assignments {
            options.topics.assign(a).unwrap();
        }
        read_drive_with(&path, options)
    };
    let e = read(&["gnss=/imu/data"]).unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, DriveError::Topic { .. }), "{text}");
    assert!(
        text.contains("bag.mcap")
            && text.contains("/imu/data")
            && text.contains("sensor_msgs/msg/NavSatFix"),
        "{text}"
    );
    let e = read(&["wheels=/odom"]).unwrap_err().to_string();
    assert!(
        e.contains("/odom") && e.contains("not in the bag") && e.contains("/joint_states"),
        "{e}"
    );
    let e = read(&["joints.rl=nope"]).unwrap_err().to_string();
    assert!(
        e.contains("nope") && e.contains("rear_left_wheel_joint"),
        "{e}"
    );
    assert!(read(&["joints.rl=rear_left_wheel_joint"]).is_ok());

    // Two NavSatFix topics: ambiguous until one is named.
    let fixes = |t: f64| vec![(t, nav_sat_fix(t, 32.0, 35.0, 1.0, true))];
    let wheels: Vec<(f64, Vec<u8>)> = d
        .wheels
        .samples
        .iter()
        .map(|s| (s.t_s, joint_state(s, true)))
        .collect();
    let two = bag(&[
        ("/gps/fix", "sensor_msgs/msg/NavSatFix", fixes(0.0)),
        ("/rtk/fix", "sensor_msgs/msg/NavSatFix", fixes(0.5)),
        ("/joint_states", "sensor_msgs/msg/JointState", wheels),
    ]);
    std::fs::write(&path, two).unwrap();
    let e = read(&[]).unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, DriveError::AmbiguousTopic { .. }), "{text}");
    assert!(
        text.contains("/gps/fix") && text.contains("/rtk/fix") && text.contains("--topic gnss="),
        "{text}"
    );
    let ok = read(&["gnss=/rtk/fix"]).unwrap();
    assert_eq!(ok.drive.gnss.unwrap().len(), 1);

    // The same map from a TOML file.
    let map = TopicMap::from_toml_str(Path::new("m.toml"), "gnss = \"/gps/fix\"\n").unwrap();
    let options = ReadOptions {
        topics: map,
        ..with_vehicle(&d)
    };
    assert_eq!(
        read_drive_with(&path, options).unwrap().drive.gnss.unwrap()[0].t_s,
        1.7e9
    );
}

#[test]
fn a_body_twist_gives_rear_wheel_speeds_with_the_track_width() {
    let d = drive(200);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("twist.mcap");
    let twists = (0..100)
        .map(|i| (i as f64 * 0.02, twist_stamped(i as f64 * 0.02, 5.0, 0.2)))
        .collect();
    std::fs::write(
        &path,
        bag(&[("/cmd", "geometry_msgs/msg/TwistStamped", twists)]),
    )
    .unwrap();
    let loaded = read_drive_with(&path, with_vehicle(&d)).unwrap();
    let w = &loaded.drive.wheels;
    assert_eq!(w.units, WheelUnits::rear(WheelUnit::MS));
    // Track 1.5 m: 5 ∓ 0.2 · 0.75.
    assert_eq!((w.samples[0].rl, w.samples[0].rr), (5.0 - 0.15, 5.0 + 0.15));
    assert!(loaded.warnings.iter().any(|m| m.contains("track_width_m")));
    assert!(loaded.drive.gnss.is_none());
}

// ------------------------------------------------------------ NMEA

fn sentence(body: &str) -> String {
    let sum = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{sum:02X}")
}

/// `ddmm.mmmmmm` of degrees.
fn nmea_angle(v: f64, deg_digits: usize) -> String {
    let a = v.abs();
    let d = a.floor();
    format!("{:0w$}{:09.6}", d as u32, (a - d) * 60.0, w = deg_digits)
}

#[test]
fn an_nmea_log_is_the_gnss_stream_of_a_drive_folder() {
    let d = drive(1200);
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("drive");
    // Times of day from 2024-03-01 23:59:58 UTC: the log crosses midnight.
    let day0 = 1_709_251_200.0; // 2024-03-01 00:00:00 UTC
    let start = 86_398.0;
    let mut shifted = d.clone();
    for s in &mut shifted.wheels.samples {
        s.t_s += day0 + start + 1.0;
    }
    shifted.imu = None;
    shifted.gnss = None;
    write_drive(&shifted, &folder).unwrap();
    let mut log = String::new();
    let mut expected = Vec::new();
    for (i, (t, lat, lon)) in fixes_lat_lon(&d).into_iter().enumerate() {
        let tod = start + 1.0 + (t * 100.0).round() / 100.0;
        let (day, tod) = if tod >= 86_400.0 {
            (1, tod - 86_400.0)
        } else {
            (0, tod)
        };
        let secs = tod.floor() as u32;
        let time = format!(
            "{:02}{:02}{:02}.{:02}",
            secs / 3600,
            secs / 60 % 60,
            secs % 60,
            ((tod - tod.floor()) * 100.0).round() as u32
        );
        let date = if day == 0 { "010324" } else { "020324" };
        let (ns, ew) = (
            if lat < 0.0 { "S" } else { "N" },
            if lon < 0.0 { "W" } else { "E" },
        );
        let (la, lo) = (nmea_angle(lat, 2), nmea_angle(lon, 3));
        if i % 3 != 1 {
            log.push_str(&sentence(&format!(
                "GNGGA,{time},{la},{ns},{lo},{ew},4,12,0.8,35.1,M,18.0,M,1.0,0000"
            )));
            log.push_str("\r\n");
        }
        if i % 3 != 2 {
            log.push_str(&sentence(&format!(
                "GNRMC,{time},A,{la},{ns},{lo},{ew},10.5,45.0,{date},,,D"
            )));
            log.push_str("\r\n");
        }
        log.push_str(&sentence("GPGSV,1,1,01,01,40,083,46"));
        log.push('\n');
        expected.push((day0 + day as f64 * 86_400.0 + tod, lat, lon));
    }
    std::fs::write(folder.join("gnss.nmea"), &log).unwrap();
    let loaded = read_drive(&folder).unwrap();
    let g = loaded.drive.gnss.as_ref().unwrap();
    assert_eq!(g.len(), expected.len());
    let origin = (expected[0].1, expected[0].2);
    let frame = drive_io::geodesy::LocalFrame::new(origin.0, origin.1, 0.0);
    for (a, (t, lat, lon)) in g.iter().zip(&expected) {
        assert!((a.t_s - t).abs() < 1e-6, "{} {t}", a.t_s);
        let (x, y) = frame.to_en(*lat, *lon);
        // ddmm.mmmmmm keeps about 2 mm.
        assert!((a.x_m - x).abs() < 0.01 && (a.y_m - y).abs() < 0.01);
        assert_eq!(a.sigma_m, None);
    }
    assert!(loaded
        .warnings
        .iter()
        .any(|w| w.contains("other than GGA and RMC")));

    // Bad lines are errors naming the line; both gnss files, too.
    let lines: Vec<&str> = log.lines().collect();
    let mut bad = lines.clone();
    let flipped = bad[1].replacen(",A,", ",V,", 1);
    assert_ne!(flipped, bad[1]);
    bad[1] = &flipped;
    std::fs::write(folder.join("gnss.nmea"), bad.join("\n")).unwrap();
    let e = read_drive(&folder).unwrap_err();
    assert!(matches!(e, DriveError::Nmea { line: 2, .. }), "{e}");
    assert!(
        e.to_string().contains("gnss.nmea:2: checksum mismatch"),
        "{e}"
    );
    let mut garbage = lines.clone();
    garbage.insert(2, "garbage 123");
    std::fs::write(folder.join("gnss.nmea"), garbage.join("\n")).unwrap();
    let e = read_drive(&folder).unwrap_err().to_string();
    assert!(e.contains("gnss.nmea:3: not an NMEA sentence"), "{e}");
    std::fs::write(folder.join("gnss.nmea"), &log).unwrap();
    std::fs::write(folder.join("gnss.csv"), "t_s,x_m,y_m\n").unwrap();
    let e = read_drive(&folder).unwrap_err().to_string();
    assert!(e.contains("also has gnss.csv"), "{e}");
}
