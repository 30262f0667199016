//! `record` keeps what the services serve while it records: the odometry's
//! poses and the calibrator's estimates, received over iceoryx2 in process,
//! written beside the drive in our schema and (poses) in Foxglove's
//! `PoseInFrame` and `LocationFix`, which the reader leaves out.

use drive_io::geodesy::LocalFrame;
use drive_io::{
    read_drive, write_drive_with, WriteOptions, ESTIMATE_TOPIC, FOXGLOVE_SERVED_LOCATION_TOPIC,
    FOXGLOVE_SERVED_POSE_TOPIC, POSE_TOPIC,
};
use interfaces::bus::{Bus, BusSettings, TopicPublisher};
use interfaces::drive::{GnssAntenna, VehicleParams};
use interfaces::wire::{CircumferenceEstimate, Header, Pose, PoseMode, WheelRotations};
use sensor_bridge::record::{record, RecordOptions};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

const ORIGIN: (f64, f64) = (47.5, 19.05);

fn vehicle() -> VehicleParams {
    VehicleParams {
        name: Some("test".into()),
        track_width_m: 1.5,
        nominal_circumference_m: 2.0,
        wheelbase_m: None,
        ticks_per_rev: None,
        gnss: GnssAntenna {
            origin_lat_deg: Some(ORIGIN.0),
            origin_lon_deg: Some(ORIGIN.1),
            ..GnssAntenna::default()
        },
    }
}

fn pose(i: u64) -> Pose {
    let t = i as f64 * 0.01;
    let mut covariance = [0.0; 9];
    covariance[0] = 0.04;
    covariance[4] = 0.09;
    covariance[8] = 1e-4;
    Pose {
        header: Header::from_seconds(t, i),
        x_m: 20.0 * t,
        y_m: -5.0 * t,
        yaw_rad: 0.1 * t,
        covariance,
        estimate_version: 1,
        mode: PoseMode::Fused as u8,
        _pad: [0; 7],
    }
}

#[test]
fn served_poses_and_estimates_are_recorded_beside_the_drive() {
    let root = tempfile::tempdir().expect("tempdir");
    let settings = BusSettings::isolated("recserved", root.path());
    let recorder_settings = settings.clone();
    let recorder = std::thread::spawn(move || {
        let bus = Bus::open(&recorder_settings, "recorder").expect("recorder bus");
        record(
            &bus,
            &RecordOptions {
                vehicle: vehicle(),
                until_end_of_stream: true,
                progress_every: Duration::ZERO,
            },
        )
        .expect("record")
    });
    let bus = Bus::open(&settings, "graph").expect("bus");
    let mut wheels: TopicPublisher<WheelRotations> = bus.publisher().expect("wheels");
    let mut poses: TopicPublisher<Pose> = bus.publisher().expect("poses");
    let mut estimates: TopicPublisher<CircumferenceEstimate> = bus.publisher().expect("estimates");
    let start = Instant::now();
    while wheels.subscriber_count() < 1
        || poses.subscriber_count() < 1
        || estimates.subscriber_count() < 1
    {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "record did not subscribe"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    wheels.announce().expect("announce");
    poses.announce().expect("announce");
    estimates.announce().expect("announce");
    std::thread::sleep(Duration::from_millis(200));
    for i in 0..100 {
        let t = i as f64 * 0.01;
        wheels
            .publish(WheelRotations {
                header: Header::from_seconds(t, i),
                rl_rev: t,
                rr_rev: t,
                ..Default::default()
            })
            .expect("wheel");
        poses.publish(pose(i)).expect("pose");
        if i == 50 {
            estimates
                .publish(CircumferenceEstimate {
                    header: Header::from_seconds(t, 0),
                    version: 1,
                    c_rl_m: 1.99,
                    c_rr_m: 2.01,
                    track_width_m: 1.5,
                    ..Default::default()
                })
                .expect("estimate");
        }
    }
    // The poses are published before the wheels' end: all of them are taken.
    std::thread::sleep(Duration::from_millis(200));
    wheels.end_of_stream().expect("end wheels");
    let rec = recorder.join().expect("recorder thread");
    assert_eq!(rec.poses.len(), 100);
    assert_eq!(rec.estimates.len(), 1);
    assert_eq!(
        (rec.estimates[0].version, rec.estimates[0].c_rr_m),
        (1, 2.01)
    );
    assert!((rec.poses[42].x_m - pose(42).x_m).abs() < 1e-12);

    let path = root.path().join("rec.mcap");
    let options = WriteOptions {
        foxglove: true,
        poses: rec.poses.clone(),
        estimates: rec.estimates.clone(),
        ..WriteOptions::default()
    };
    write_drive_with(&rec.drive, &path, &options).expect("write");
    let bytes = std::fs::read(&path).expect("read back");
    let summary = mcap::Summary::read(&bytes)
        .expect("summary")
        .expect("a summary");
    let mut by_topic: BTreeMap<String, Vec<serde_json::Value>> = BTreeMap::new();
    let mut schema_of: BTreeMap<String, String> = BTreeMap::new();
    for c in summary.channels.values() {
        let schema = c.schema.as_ref().map_or(String::new(), |s| s.name.clone());
        schema_of.insert(c.topic.clone(), schema);
    }
    for m in mcap::MessageStream::new(&bytes).expect("messages") {
        let m = m.expect("message");
        by_topic
            .entry(m.channel.topic.clone())
            .or_default()
            .push(serde_json::from_slice(&m.data).expect("JSON"));
    }
    assert_eq!(by_topic[POSE_TOPIC].len(), 100);
    assert_eq!(by_topic[ESTIMATE_TOPIC].len(), 1);
    assert_eq!(by_topic[POSE_TOPIC][7]["estimate_version"], 1);
    assert_eq!(
        schema_of[FOXGLOVE_SERVED_POSE_TOPIC],
        "foxglove.PoseInFrame"
    );
    assert_eq!(
        schema_of[FOXGLOVE_SERVED_LOCATION_TOPIC],
        "foxglove.LocationFix"
    );
    let frame = LocalFrame::new(ORIGIN.0, ORIGIN.1, 0.0);
    for (i, fix) in by_topic[FOXGLOVE_SERVED_LOCATION_TOPIC].iter().enumerate() {
        let p = pose(i as u64);
        let (lat, lon) = frame.from_en(p.x_m, p.y_m);
        assert!(
            (fix["latitude"].as_f64().expect("lat") - lat).abs() < 1e-11,
            "{fix}"
        );
        assert!(
            (fix["longitude"].as_f64().expect("lon") - lon).abs() < 1e-11,
            "{fix}"
        );
        assert_eq!(fix["position_covariance"][4].as_f64(), Some(0.09));
    }
    let framed = &by_topic[FOXGLOVE_SERVED_POSE_TOPIC][10];
    assert_eq!(framed["frame_id"], "enu");
    assert!((framed["pose"]["position"]["x"].as_f64().expect("x") - pose(10).x_m).abs() < 1e-12);

    // The drive reads back without them, and without a word about them.
    let loaded = read_drive(&path).expect("read drive");
    assert_eq!(loaded.drive, rec.drive);
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
}
