//! `record` with `until_end_of_stream` over iceoryx2, in process: the wheels
//! end first, and a GNSS publisher of its own (a receiver's driver) still
//! delivers the fixes of the drive's last instants. Nothing it sends before
//! it ends its stream is lost; one that never ends holds the recording up
//! for [`END_OF_STREAM_GRACE`] only.

use interfaces::bus::{Bus, BusSettings, TopicPublisher};
use interfaces::drive::{GnssAntenna, VehicleParams};
use interfaces::wire::{GnssFix, Header, WheelRotations};
use sensor_bridge::record::{record, RecordOptions, Recording, END_OF_STREAM_GRACE};
use std::time::{Duration, Instant};

fn options() -> RecordOptions {
    RecordOptions {
        vehicle: VehicleParams {
            name: Some("test".into()),
            track_width_m: 1.5,
            nominal_circumference_m: 2.0,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: GnssAntenna::default(),
        },
        until_end_of_stream: true,
        progress_every: Duration::ZERO,
    }
}

fn wheel(i: u64) -> WheelRotations {
    let t = i as f64 * 0.01;
    WheelRotations {
        header: Header::from_seconds(t, i),
        rl_rev: t,
        rr_rev: t,
        ..Default::default()
    }
}

fn fix(i: u64) -> GnssFix {
    GnssFix {
        header: Header::from_seconds(i as f64 * 0.1, i),
        x_m: i as f64,
        y_m: 0.0,
        sigma_m: 0.02,
        fix: 1,
        ..Default::default()
    }
}

/// Start `record` on its own thread; returns it once it subscribed to the
/// wheel and GNSS topics, with the two publishers (each its own node, as two
/// drivers would be).
fn start(
    settings: &BusSettings,
) -> (
    std::thread::JoinHandle<Recording>,
    TopicPublisher<WheelRotations>,
    TopicPublisher<GnssFix>,
) {
    let recorder_settings = settings.clone();
    let recorder = std::thread::spawn(move || {
        let bus = Bus::open(&recorder_settings, "recorder").expect("recorder bus");
        record(&bus, &options()).expect("record")
    });
    let wheel_bus = Bus::open(settings, "wheel-driver").expect("wheel bus");
    let gnss_bus = Bus::open(settings, "gnss-driver").expect("gnss bus");
    let wheels: TopicPublisher<WheelRotations> = wheel_bus.publisher().expect("wheels");
    let gnss: TopicPublisher<GnssFix> = gnss_bus.publisher().expect("gnss");
    let start = Instant::now();
    while wheels.subscriber_count() < 1 || gnss.subscriber_count() < 1 {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "record did not subscribe"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(Duration::from_millis(200));
    (recorder, wheels, gnss)
}

#[test]
fn fixes_a_gnss_driver_delivers_after_the_wheels_ended_are_recorded() {
    let root = tempfile::tempdir().expect("tempdir");
    let settings = BusSettings::isolated("recend", root.path());
    let (recorder, mut wheels, mut gnss) = start(&settings);
    // One second of drive: wheels at 100 Hz, fixes at 10 Hz, each fix
    // delivered 0.15 s after its time (every 15th wheel sample later).
    for i in 0..100 {
        wheels.publish(wheel(i)).expect("wheel");
        if i >= 15 && (i - 15) % 10 == 0 {
            gnss.publish(fix((i - 15) / 10)).expect("fix");
        }
    }
    wheels.end_of_stream().expect("end wheels");
    // The last fix (t = 0.9 s) comes after the wheels ended.
    std::thread::sleep(Duration::from_millis(300));
    gnss.publish(fix(9)).expect("last fix");
    gnss.end_of_stream().expect("end gnss");
    let recording = recorder.join().expect("recorder thread");
    assert_eq!(recording.received, [100, 10, 0, 0]);
    let fixes = recording.drive.gnss.expect("gnss recorded");
    assert_eq!(fixes.len(), 10);
    assert!((fixes[9].t_s - 0.9).abs() < 1e-9);
}

#[test]
fn a_gnss_driver_that_never_ends_holds_the_recording_up_for_the_grace_only() {
    let root = tempfile::tempdir().expect("tempdir");
    let settings = BusSettings::isolated("recgrace", root.path());
    let (recorder, mut wheels, mut gnss) = start(&settings);
    for i in 0..50 {
        wheels.publish(wheel(i)).expect("wheel");
        if i % 10 == 0 {
            gnss.publish(fix(i / 10)).expect("fix");
        }
    }
    wheels.end_of_stream().expect("end wheels");
    let ended = Instant::now();
    let recording = recorder.join().expect("recorder thread");
    let waited = ended.elapsed();
    // It ended (the join returned) although the GNSS publisher is still
    // alive, and not before the grace it gives that publisher.
    assert!(waited >= END_OF_STREAM_GRACE, "{waited:?}");
    assert_eq!(recording.received, [50, 5, 0, 0]);
    drop(gnss);
}
