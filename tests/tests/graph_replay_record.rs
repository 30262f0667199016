//! `sensor-bridge replay` (and `simulate --publish`) into `sensor-bridge
//! record`, as real processes over iceoryx2: the recording holds every sample
//! of the drive, value for value.

use drive_io::{read_drive, write_drive};
use integration_tests::graph::{Bin, Graph, ProcId};
use interfaces::drive::Drive;
use simulator::{simulate, Scenario, SimConfig};
use std::path::PathBuf;

/// Simulate the paper drive (seed 3), write it, and start `record --until-end`
/// on it; returns the drive, its folder, the recording path and the recorder.
fn simulate_and_start_recording(g: &mut Graph) -> (Drive, PathBuf, PathBuf, ProcId) {
    let drive = simulate(&SimConfig::new(Scenario::Paper, 3)).expect("simulate");
    let folder = g.path("drive");
    write_drive(&drive, &folder).expect("write drive");
    let out = g.path("recording.mcap");
    let record = g.spawn(
        "record",
        Bin::SensorBridge,
        &[
            "record",
            out.to_str().expect("utf-8 path"),
            "--vehicle",
            folder.to_str().expect("utf-8 path"),
            "--until-end",
        ],
    );
    g.wait_log(record, "recording every sensor topic");
    (drive, folder, out, record)
}

#[test]
fn replay_at_max_speed_into_record_loses_nothing() {
    replay_into_record("reprec", &[]);
}

/// Streams delivered out of order across topics, as separate drivers deliver
/// them (GNSS fixes 0.15 s and IMU samples 0.03 s after their time stamps):
/// the recorder keeps each stream's own order and still gets every sample.
#[test]
fn replay_delivering_streams_late_into_record_loses_nothing() {
    replay_into_record("replate", &["--deliver-late", "gnss=0.15,imu=0.03"]);
}

/// `sensor-bridge replay DRIVE --max EXTRA...` into `record`: every sample of
/// the drive is in the recording.
fn replay_into_record(name: &str, extra: &[&str]) {
    let mut g = Graph::new(name);
    let (drive, folder, out, record) = simulate_and_start_recording(&mut g);
    let folder_s = folder.to_str().expect("utf-8 path");
    let mut args = vec![
        "replay",
        folder_s,
        "--max",
        "--wait-subscribers",
        "1",
        "--linger",
        "0.2",
    ];
    args.extend_from_slice(extra);
    let replay = g.spawn("replay", Bin::SensorBridge, &args);
    assert!(
        g.wait_exit(replay).success(),
        "replay failed:\n{}",
        g.log(replay)
    );
    if !extra.is_empty() {
        assert!(
            g.log(replay).contains("delivering late"),
            "{}",
            g.log(replay)
        );
    }
    let rec = finish_recording(&mut g, record, &out);
    assert_recording_matches(&drive, &rec);
}

/// `simulate --publish --max` publishes the drive the simulator makes, every
/// sample of it, as `replay` would publish the written drive.
#[test]
fn simulate_publish_at_max_speed_into_record_loses_nothing() {
    let mut g = Graph::new("simpub");
    // The same drive in-process (the simulator is deterministic per seed); its
    // folder gives `record` the vehicle parameters.
    let (drive, _folder, out, record) = simulate_and_start_recording(&mut g);
    let sim = g.spawn(
        "simulate",
        Bin::SensorBridge,
        &[
            "simulate",
            "--scenario",
            "paper",
            "--seed",
            "3",
            "--publish",
            "--max",
        ],
    );
    assert!(
        g.wait_exit(sim).success(),
        "simulate --publish failed:\n{}",
        g.log(sim)
    );
    let sim_log = g.log(sim);
    assert!(sim_log.contains("end of stream"), "{sim_log}");
    let rec = finish_recording(&mut g, record, &out);
    assert_recording_matches(&drive, &rec);
}

/// Wait for `record` to end cleanly with no sample lost; read what it wrote.
fn finish_recording(g: &mut Graph, record: ProcId, out: &std::path::Path) -> Drive {
    assert!(
        g.wait_exit(record).success(),
        "record failed:\n{}",
        g.log(record)
    );
    let log = g.log(record);
    assert!(log.contains("lost 0 (by sequence numbers)"), "{log}");
    read_drive(out).expect("read recording").drive
}

/// Every sample of `drive` is in `rec`, value for value (wheels as
/// cumulative revolutions; truth never).
fn assert_recording_matches(drive: &Drive, rec: &Drive) {
    assert_eq!(rec.vehicle, drive.vehicle);
    // Wheels: recorded as cumulative revolutions, exactly the drive's.
    let revs = drive.wheel_revolutions().expect("revolutions");
    assert_eq!(rec.wheels.samples.len(), revs.len());
    for (r, w) in rec.wheels.samples.iter().zip(&revs) {
        assert!((r.t_s - w.t_s).abs() < 1e-9, "{} vs {}", r.t_s, w.t_s);
        assert_eq!((r.rl, r.rr), (w.rl, w.rr));
        assert_eq!((r.fl, r.fr), (w.fl, w.fr));
    }
    let gnss = drive.gnss.as_ref().expect("gnss");
    let rg = rec.gnss.as_ref().expect("recorded gnss");
    assert_eq!(rg.len(), gnss.len());
    for (r, s) in rg.iter().zip(gnss) {
        assert!((r.t_s - s.t_s).abs() < 1e-9);
        assert_eq!((r.x_m, r.y_m, r.sigma_m), (s.x_m, s.y_m, s.sigma_m));
    }
    let imu = drive.imu.as_ref().expect("imu");
    let ri = rec.imu.as_ref().expect("recorded imu");
    assert_eq!(ri.len(), imu.len());
    for (r, s) in ri.iter().zip(imu) {
        assert!((r.t_s - s.t_s).abs() < 1e-9);
        assert_eq!(
            (r.gz_rad_s, r.ax_m_s2, r.ay_m_s2, r.az_m_s2),
            (s.gz_rad_s, s.ax_m_s2, s.ay_m_s2, s.az_m_s2)
        );
    }
    match (&drive.heading, &rec.heading) {
        (Some(h), Some(rh)) => {
            assert_eq!(h.len(), rh.len());
            for (r, s) in rh.iter().zip(h) {
                assert_eq!((r.yaw_rad, r.sigma_rad), (s.yaw_rad, s.sigma_rad));
            }
        }
        (None, None) => {}
        (a, b) => panic!(
            "heading: drive {} vs recording {}",
            a.is_some(),
            b.is_some()
        ),
    }
    assert!(rec.truth.is_none(), "truth is never on the bus");
}
