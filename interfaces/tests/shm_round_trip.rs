//! Every wire type makes a round trip through real shared memory: a child
//! process (this test binary, re-run in child mode) publishes it with
//! `interfaces::bus`, the test receives it and compares it field by field.
//! Every test has its own iceoryx2 prefix and root path.

use interfaces::bus::{Bus, BusSettings, Topic, TopicSubscriber};
use interfaces::wire::{
    CircumferenceEstimate, GnssFix, Header, Heading, Imu, ModelExtension, Pose, PoseMode,
    WheelRotations, MAX_EXTENSIONS,
};
use std::io::Read;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

const CHILD_ENV: &str = "WHEELCAL_RT_CHILD";
/// Samples per round trip: the sequence numbers must come out 0, 1, 2.
const COUNT: u64 = 3;
/// Watchdog: a test that receives nothing for this long fails (it never passes on time).
const WATCHDOG: Duration = Duration::from_secs(30);

fn header(i: u64) -> Header {
    // seq is assigned by the publisher; the test expects 0, 1, 2.
    Header {
        t_ns: -1_234_567_890 + 1_000_000_007 * i as i64,
        seq: i,
    }
}

fn wheels(i: u64) -> WheelRotations {
    let k = i as f64;
    WheelRotations {
        header: header(i),
        rl_rev: 1.0e6 + 0.125 + k,
        rr_rev: -2.5e-3 - k,
        fl_rev: 3.0 + k,
        fr_rev: 4.0 + k,
        valid: WheelRotations::FRONT_VALID,
        _pad: 0,
    }
}

fn gnss(i: u64) -> GnssFix {
    let k = i as f64;
    GnssFix {
        header: header(i),
        x_m: -1234.5 + k,
        y_m: 9876.25 - k,
        sigma_m: 0.03 * (k + 1.0),
        fix: (i % 2) as u8,
        _pad: [0; 7],
    }
}

fn imu(i: u64) -> Imu {
    let k = i as f64;
    Imu {
        header: header(i),
        gz_rad_s: 0.1 + k,
        ax_m_s2: -0.2 - k,
        ay_m_s2: 0.3 * k,
        az_m_s2: 9.81,
        gx_rad_s: 1e-3,
        gy_rad_s: -1e-3 * k,
        valid: Imu::ACCEL_VALID | Imu::ROLL_PITCH_RATE_VALID,
        _pad: 0,
    }
}

fn heading(i: u64) -> Heading {
    Heading {
        header: header(i),
        yaw_rad: -3.0 + i as f64,
        sigma_rad: 0.01,
    }
}

fn estimate(i: u64) -> CircumferenceEstimate {
    let k = i as f64;
    let mut extensions = [ModelExtension::default(); MAX_EXTENSIONS];
    for (j, e) in extensions.iter_mut().enumerate() {
        e.effect_code = j as u32 + 1;
        e.param_count = (j % 4) as u32 + 1;
        e.params = [j as f64, -(j as f64), 0.5 * j as f64 + k, 1e-9];
    }
    CircumferenceEstimate {
        header: header(i),
        version: 10 + i,
        c_rl_m: 1.95 + 1e-4 * k,
        c_rr_m: 1.96 - 1e-4 * k,
        sigma_rl_m: 1e-4,
        sigma_rr_m: 2e-4,
        track_width_m: 1.52,
        gyro_bias_rad_s: -0.002,
        gyro_scale: 0.01,
        quality_m: 0.42 + k,
        extension_count: MAX_EXTENSIONS as u32,
        _pad: 0,
        extensions,
    }
}

fn pose(i: u64) -> Pose {
    let mut covariance = [0.0; 9];
    for (j, c) in covariance.iter_mut().enumerate() {
        *c = (j as f64 + 1.0) * 0.1 + i as f64;
    }
    Pose {
        header: header(i),
        x_m: 100.0 + i as f64,
        y_m: -200.0,
        yaw_rad: 1.0,
        covariance,
        estimate_version: 7 + i,
        mode: PoseMode::DeadReckoning as u8,
        _pad: [0; 7],
    }
}

/// Kills and reaps the child on every path, also when an assertion fails.
struct ChildGuard(Option<Child>);

impl ChildGuard {
    /// Close the child's stdin (it may exit now) and wait for its exit status.
    fn finish(mut self) -> std::process::ExitStatus {
        let mut child = self.0.take().expect("child present");
        drop(child.stdin.take());
        let start = Instant::now();
        loop {
            if let Some(status) = child.try_wait().expect("try_wait") {
                return status;
            }
            if start.elapsed() > WATCHDOG {
                let _ = child.kill();
                let _ = child.wait();
                panic!("child did not exit within the watchdog");
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

fn spawn_child(kind: &str, settings: &BusSettings, late: bool) -> ChildGuard {
    let exe = std::env::current_exe().expect("current exe");
    let mut cmd = Command::new(exe);
    cmd.args([
        "child_process",
        "--exact",
        "--nocapture",
        "--test-threads=1",
    ])
    .env(CHILD_ENV, kind)
    .env("WHEELCAL_RT_LATE", if late { "1" } else { "0" })
    .stdin(Stdio::piped())
    .stdout(if late { Stdio::piped() } else { Stdio::null() });
    for (k, v) in settings.env() {
        cmd.env(k, v);
    }
    ChildGuard(Some(cmd.spawn().expect("spawn child")))
}

fn receive_all<T: Topic + PartialEq>(
    sub: &TopicSubscriber<T>,
    want: usize,
    child: &mut ChildGuard,
) -> Vec<T> {
    let start = Instant::now();
    let mut got = Vec::new();
    while got.len() < want {
        assert!(
            start.elapsed() < WATCHDOG,
            "watchdog: received {} of {want} samples of {}",
            got.len(),
            T::SERVICE
        );
        if let Some(c) = child.0.as_mut() {
            if let Ok(Some(status)) = c.try_wait() {
                // Drain what it left, then fail if still short.
                while let Some(s) = sub.receive().expect("receive") {
                    got.push(s);
                }
                assert!(got.len() >= want, "child exited early with {status}");
                break;
            }
        }
        sub.wait_events(Duration::from_millis(100)).expect("wait");
        while let Some(s) = sub.receive().expect("receive") {
            got.push(s);
        }
    }
    got
}

/// Publish `make(0..COUNT)` from a child process and compare what arrives.
fn round_trip<T: Topic + PartialEq>(kind: &str, make: fn(u64) -> T) {
    let root = tempfile::tempdir().expect("tempdir");
    let settings = BusSettings::isolated(kind, root.path());
    let bus = Bus::open(&settings, "round_trip_test").expect("bus");
    let sub = bus.subscriber::<T>().expect("subscriber");
    let mut child = spawn_child(kind, &settings, false);
    let got = receive_all(&sub, COUNT as usize, &mut child);
    assert_eq!(got.len(), COUNT as usize);
    for (i, (received, expected)) in got.iter().zip((0..COUNT).map(make)).enumerate() {
        // Field by field (derived PartialEq), with the header checked first
        // for a clearer message.
        assert_eq!(received.header(), expected.header(), "sample {i} header");
        assert_eq!(*received, expected, "sample {i} of {}", T::SERVICE);
    }
    assert_eq!(sub.lost(), 0);
    let status = child.finish();
    assert!(status.success(), "child failed: {status}");
    drop((sub, bus));
    settings.remove_leftovers();
}

#[test]
fn wheel_rotations_round_trip() {
    round_trip("wheels", wheels);
}

#[test]
fn gnss_fix_round_trip() {
    round_trip("gnss", gnss);
}

#[test]
fn imu_round_trip() {
    round_trip("imu", imu);
}

#[test]
fn heading_round_trip() {
    round_trip("heading", heading);
}

#[test]
fn circumference_estimate_round_trip() {
    round_trip("estimate", estimate);
}

#[test]
fn pose_round_trip() {
    round_trip("pose", pose);
}

/// The estimate keeps a history of one: a subscriber created after the
/// publisher sent three estimates still receives the last one.
#[test]
fn late_estimate_subscriber_gets_the_latest() {
    let root = tempfile::tempdir().expect("tempdir");
    let settings = BusSettings::isolated("late", root.path());
    let bus = Bus::open(&settings, "late_subscriber_test").expect("bus");
    let mut child = spawn_child("estimate", &settings, true);
    // The child says when it has published everything; only then subscribe.
    let stdout = child
        .0
        .as_mut()
        .and_then(|c| c.stdout.take())
        .expect("stdout");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        use std::io::BufRead;
        for line in std::io::BufReader::new(stdout).lines() {
            let Ok(line) = line else { break };
            if line.trim() == "PUBLISHED" {
                let _ = tx.send(());
            }
        }
    });
    rx.recv_timeout(WATCHDOG)
        .expect("watchdog: the child never published");
    let sub = bus
        .subscriber::<CircumferenceEstimate>()
        .expect("subscriber");
    let got = receive_all(&sub, 1, &mut child);
    assert_eq!(got[0], estimate(COUNT - 1), "the latest estimate");
    // Only the latest: nothing older follows.
    std::thread::sleep(Duration::from_millis(100));
    assert!(sub.receive().expect("receive").is_none());
    let status = child.finish();
    assert!(status.success(), "child failed: {status}");
    drop((sub, bus));
    settings.remove_leftovers();
}

/// Samples of the flood test: several times the subscriber buffer.
const FLOOD: u64 = 5 * interfaces::bus::STREAM_BUFFER as u64;

/// A lossless stream makes the publisher wait for a slow subscriber instead
/// of dropping samples: every one of FLOOD samples arrives, in order.
#[test]
fn lossless_stream_loses_nothing_to_a_slow_subscriber() {
    let root = tempfile::tempdir().expect("tempdir");
    let settings = BusSettings::isolated("flood", root.path());
    let bus = Bus::open(&settings, "flood_test").expect("bus");
    let sub = bus.subscriber::<WheelRotations>().expect("subscriber");
    let mut child = spawn_child("flood", &settings, false);
    let start = Instant::now();
    let mut next = 0u64;
    let mut exited = false;
    while next < FLOOD {
        assert!(
            start.elapsed() < 4 * WATCHDOG,
            "watchdog: got {next} of {FLOOD}"
        );
        sub.wait_events(Duration::from_millis(50)).expect("wait");
        let mut batch = 0u32;
        while let Some(s) = sub.receive().expect("receive") {
            assert_eq!(s.header.seq, next, "samples arrive in order, none missing");
            assert_eq!(s.rl_rev, next as f64);
            next += 1;
            batch += 1;
            if batch.is_multiple_of(64) {
                std::thread::sleep(Duration::from_millis(2)); // a slow subscriber
            }
        }
        if exited {
            break;
        }
        if let Some(c) = child.0.as_mut() {
            exited = matches!(c.try_wait(), Ok(Some(_)));
        }
    }
    assert_eq!(next, FLOOD);
    assert_eq!(sub.lost(), 0);
    let status = child.finish();
    assert!(status.success(), "child failed: {status}");
    drop((sub, bus));
    settings.remove_leftovers();
}

/// Publishers that go away with samples unread (a bridge restarted while
/// the consumer was busy): their samples are still received, every one, for
/// as many gone publishers as the bus keeps connections of
/// (`EXPIRED_CONNECTIONS`, which our configuration makes far smaller than
/// iceoryx2's default, to keep every receive short).
#[test]
fn samples_of_publishers_gone_unread_are_still_received() {
    let root = tempfile::tempdir().expect("tempdir");
    let settings = BusSettings::isolated("expired", root.path());
    let bus = Bus::open(&settings, "expired_test").expect("bus");
    let sub = bus.subscriber::<WheelRotations>().expect("subscriber");
    const PER_PUBLISHER: u64 = 5;
    let runs = interfaces::bus::EXPIRED_CONNECTIONS as u64;
    for run in 0..runs {
        let mut publisher = bus.publisher::<WheelRotations>().expect("publisher");
        sub.connect().expect("connect"); // the subscriber sees it, reads nothing
        for i in 0..PER_PUBLISHER {
            publisher.publish(wheels(run * 100 + i)).expect("publish");
        }
    }
    let mut got = Vec::new();
    while let Some(s) = sub.receive().expect("receive") {
        got.push((s.header.seq, s.rl_rev));
    }
    // Each publisher numbers its samples from 0; the values tell them apart.
    let want: Vec<(u64, f64)> = (0..runs)
        .flat_map(|run| (0..PER_PUBLISHER).map(move |i| (i, wheels(run * 100 + i).rl_rev)))
        .collect();
    let mut sorted = got.clone();
    sorted.sort_by(|a, b| a.1.total_cmp(&b.1));
    assert_eq!(sorted, want, "every sample of every gone publisher arrives");
    assert_eq!(sub.lost(), 0);
    drop((sub, bus));
    settings.remove_leftovers();
}

/// Child mode: publish the samples of one type, then stay (updating
/// connections so late subscribers get the history) until stdin closes.
#[test]
fn child_process() {
    let Ok(kind) = std::env::var(CHILD_ENV) else {
        return; // normal run: nothing to do
    };
    let late = std::env::var("WHEELCAL_RT_LATE").as_deref() == Ok("1");
    let bus = Bus::from_env("round_trip_child").expect("child bus");
    match kind.as_str() {
        "wheels" => child_publish(&bus, wheels, late),
        "gnss" => child_publish(&bus, gnss, late),
        "imu" => child_publish(&bus, imu, late),
        "heading" => child_publish(&bus, heading, late),
        "estimate" => child_publish(&bus, estimate, late),
        "pose" => child_publish(&bus, pose, late),
        "flood" => child_flood(&bus),
        other => panic!("unknown kind {other}"),
    }
}

fn child_publish<T: Topic>(bus: &Bus, make: fn(u64) -> T, late: bool) {
    let stdin_closed = Arc::new(AtomicBool::new(false));
    {
        let flag = stdin_closed.clone();
        std::thread::spawn(move || {
            let mut sink = Vec::new();
            let _ = std::io::stdin().read_to_end(&mut sink);
            flag.store(true, Ordering::SeqCst);
        });
    }
    let mut publisher = bus.publisher::<T>().expect("publisher");
    if !late {
        // The parent subscribed before spawning us.
        let start = Instant::now();
        while publisher.subscriber_count() == 0 {
            assert!(start.elapsed() < WATCHDOG, "no subscriber");
            std::thread::sleep(Duration::from_millis(5));
        }
    }
    for i in 0..COUNT {
        let mut s = make(i);
        s.header_mut().seq = 999; // the publisher numbers samples itself
        assert_eq!(publisher.publish(s).expect("publish"), i);
    }
    publisher.end_of_stream().expect("end of stream");
    println!("\nPUBLISHED");
    while !stdin_closed.load(Ordering::SeqCst) {
        publisher.update_connections().expect("update connections");
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn child_flood(bus: &Bus) {
    let stdin_closed = Arc::new(AtomicBool::new(false));
    {
        let flag = stdin_closed.clone();
        std::thread::spawn(move || {
            let mut sink = Vec::new();
            let _ = std::io::stdin().read_to_end(&mut sink);
            flag.store(true, Ordering::SeqCst);
        });
    }
    let mut publisher = bus.publisher::<WheelRotations>().expect("publisher");
    let start = Instant::now();
    while publisher.subscriber_count() == 0 {
        assert!(start.elapsed() < WATCHDOG, "no subscriber");
        std::thread::sleep(Duration::from_millis(5));
    }
    publisher.announce().expect("announce");
    std::thread::sleep(Duration::from_millis(300));
    for i in 0..FLOOD {
        let s = WheelRotations {
            rl_rev: i as f64,
            ..WheelRotations::default()
        };
        publisher.publish(s).expect("publish");
    }
    publisher.end_of_stream().expect("end of stream");
    while !stdin_closed.load(Ordering::SeqCst) {
        std::thread::sleep(Duration::from_millis(5));
    }
}
