//! The graph split over two "hosts": two graphs in separate iceoryx2 roots
//! on this machine, joined only by two `gateway` processes talking Zenoh over
//! loopback TCP (peer mode, explicit listen/connect endpoints, no multicast
//! scouting). Host A runs the sensor bridge and the calibrator, host B the
//! odometry:
//!
//! - gateway A: `--out wheels,gnss,imu,heading,estimate --in pose --listen E`
//! - gateway B: `--in wheels,gnss,imu,heading,estimate --out pose --connect E`
//!
//! Every child is killed and reaped by its [`Graph`] guard.

use drive_io::write_drive;
use gateway::header::{encode, Kind};
use integration_tests::graph::{
    drain, free_tcp_endpoint, seeded_calibrator_state, wait_until, Bin, Graph, ProcId,
};
use interfaces::bus::TopicSubscriber;
use interfaces::drive::Drive;
use interfaces::wire::{Header, Imu, Pose, PoseMode, WheelRotations, WHEELS_SERVICE};
use simulator::{simulate, Scenario, SimConfig};
use std::time::{Duration, Instant};
use zenoh::Wait;

const SENSORS_AND_ESTIMATE: &str = "wheels,gnss,imu,heading,estimate";

fn write(g: &Graph, drive: &Drive, name: &str) -> String {
    let dir = g.path(name);
    write_drive(drive, &dir).expect("write drive");
    dir.to_str().expect("utf-8 path").to_string()
}

fn last_wheel_t_ns(drive: &Drive) -> i64 {
    interfaces::wire::seconds_to_ns(drive.wheels.samples.last().expect("wheels").t_s)
}

/// Gateway of host A (sends the sensors and the estimate, receives poses).
fn gateway_a(a: &mut Graph, label: &str, endpoint: &str) -> ProcId {
    a.spawn(
        label,
        Bin::Gateway,
        &[
            "--out",
            SENSORS_AND_ESTIMATE,
            "--in",
            "pose",
            "--listen",
            endpoint,
        ],
    )
}

/// Gateway of host B (receives the sensors and the estimate, sends poses).
fn gateway_b(b: &mut Graph, label: &str, endpoint: &str) -> ProcId {
    b.spawn(
        label,
        Bin::Gateway,
        &[
            "--in",
            SENSORS_AND_ESTIMATE,
            "--out",
            "pose",
            "--connect",
            endpoint,
        ],
    )
}

fn calibrator(g: &mut Graph, label: &str, folder: &str, state: &str) -> ProcId {
    let vehicle = format!("{folder}/vehicle.toml");
    g.spawn(
        label,
        Bin::Calibrator,
        &[
            "serve",
            "--vehicle",
            &vehicle,
            "--state",
            state,
            "--min-distance",
            "1e9",
        ],
    )
}

fn odometry(g: &mut Graph, folder: &str, extra: &[&str]) -> ProcId {
    let vehicle = format!("{folder}/vehicle.toml");
    let mut args = vec!["serve", "--vehicle", &vehicle];
    args.extend_from_slice(extra);
    g.spawn("odometry", Bin::Odometry, &args)
}

/// `replay --max` on `g`, waiting for `subscribers`; collect the poses of
/// `sub` until the replay ended and the pose of the last wheel sample came.
fn replay_and_collect(
    g: &mut Graph,
    folder: &str,
    subscribers: &str,
    sub: &TopicSubscriber<Pose>,
    last_t_ns: i64,
) -> Vec<Pose> {
    replay_and_collect_with(g, folder, subscribers, sub, last_t_ns, &["--max"])
}

/// [`replay_and_collect`] with these `replay` arguments instead of `--max`.
fn replay_and_collect_with(
    g: &mut Graph,
    folder: &str,
    subscribers: &str,
    sub: &TopicSubscriber<Pose>,
    last_t_ns: i64,
    extra: &[&str],
) -> Vec<Pose> {
    let mut args = vec![
        "replay",
        folder,
        "--wait-subscribers",
        subscribers,
        "--linger",
        "0.5",
    ];
    args.extend_from_slice(extra);
    let replay = g.spawn("replay", Bin::SensorBridge, &args);
    let mut poses = Vec::new();
    let status = g.wait_exit_with(replay, || {
        drain(sub, &mut poses);
    });
    assert!(status.success(), "replay failed:\n{}", g.log(replay));
    wait_until("the pose of the last wheel sample", || {
        drain(sub, &mut poses);
        poses.last().is_some_and(|p| p.header.t_ns >= last_t_ns)
    });
    poses
}

/// Wait (watchdog) until `needle` is in the log of `id` in `g`, draining
/// `sub` meanwhile (a lossless publisher must never wait on the test).
fn wait_log_draining(
    g: &Graph,
    id: ProcId,
    needle: &str,
    sub: &TopicSubscriber<Pose>,
    poses: &mut Vec<Pose>,
) -> String {
    wait_until(needle, || {
        drain(sub, poses);
        g.log(id).contains(needle)
    });
    g.log(id)
}

type PoseBits = (i64, u64, u64, u64, [u64; 9], u8, u64);

fn bits(p: &Pose) -> PoseBits {
    (
        p.header.t_ns,
        p.x_m.to_bits(),
        p.y_m.to_bits(),
        p.yaw_rad.to_bits(),
        p.covariance.map(f64::to_bits),
        p.mode,
        p.estimate_version,
    )
}

/// A replayed drive gives the same poses, bit for bit, whether the odometry
/// runs beside the bridge or on the other side of two gateways and Zenoh
/// (the poses coming back to host A through the gateways too); with late
/// fixes, the rewind window works across the hop as on one host.
#[test]
fn split_graph_gives_the_single_host_poses_bit_for_bit() {
    let drive = simulate(&SimConfig::new(Scenario::Paper, 4)).expect("drive");
    let last = last_wheel_t_ns(&drive);

    // One host.
    let single = {
        let mut g = Graph::new("gwsingle");
        let folder = write(&g, &drive, "drive");
        let state = g.path("state.json");
        seeded_calibrator_state(&state, 7);
        let cal = calibrator(
            &mut g,
            "calibrator",
            &folder,
            state.to_str().expect("utf-8"),
        );
        g.wait_log(cal, "starting from the persisted estimate v7");
        let bus = g.bus("test");
        let sub = bus.subscriber::<Pose>().expect("pose subscriber");
        let odo = odometry(&mut g, &folder, &[]);
        g.wait_log(odo, "switching estimate v0 -> v7");
        let poses = replay_and_collect(&mut g, &folder, "2", &sub, last);
        assert_eq!(sub.lost(), 0, "poses lost on one host");
        poses
    };

    // Two hosts.
    let mut a = Graph::new("gwhosta");
    let mut b = Graph::new("gwhostb");
    let endpoint = free_tcp_endpoint();
    let folder_a = write(&a, &drive, "drive");
    let folder_b = write(&b, &drive, "drive");
    let state = a.path("state.json");
    seeded_calibrator_state(&state, 7);
    let cal = calibrator(
        &mut a,
        "calibrator",
        &folder_a,
        state.to_str().expect("utf-8"),
    );
    a.wait_log(cal, "starting from the persisted estimate v7");
    let bus_a = a.bus("test");
    let sub = bus_a
        .subscriber::<Pose>()
        .expect("pose subscriber on host A");
    let odo = odometry(&mut b, &folder_b, &[]);
    let gw_a = gateway_a(&mut a, "gateway-a", &endpoint);
    let gw_b = gateway_b(&mut b, "gateway-b", &endpoint);
    a.wait_log(gw_a, "forwarding");
    b.wait_log(gw_b, "forwarding");
    // The estimate crossed (asked for when gateway B saw gateway A).
    b.wait_log(odo, "switching estimate v0 -> v7");
    let mut early = Vec::new();
    drain(&sub, &mut early); // attach to gateway A's pose publisher
    assert!(early.is_empty(), "no pose before the drive: {early:?}");
    // The bridge waits for the calibrator and gateway A (which subscribes
    // once gateway B is up).
    let split = replay_and_collect(&mut a, &folder_a, "2", &sub, last);
    assert_eq!(sub.lost(), 0, "poses lost across the gateways");

    assert_eq!(
        single.len(),
        drive.wheels.samples.len(),
        "a pose per wheel sample"
    );
    assert!(single.iter().any(|p| p.mode == PoseMode::Fused as u8));
    assert!(single.iter().all(|p| p.estimate_version == 7));
    assert_eq!(
        split.len(),
        single.len(),
        "as many poses across the gateways"
    );
    for (i, (s, x)) in single.iter().zip(&split).enumerate() {
        assert_eq!(s.header.seq, x.header.seq, "pose {i}");
        assert_eq!(
            bits(s),
            bits(x),
            "pose {i}: one host {s:?}, two hosts {x:?}"
        );
    }

    // Late fixes across the hop: the fixes (10 Hz) delivered 0.05 s after
    // their time stamps, to a fresh odometry on host B, paced (20x) so that
    // the gateways' wakeups do not gather a late fix with the wheel samples
    // it is late for. The rewind window takes them in their place as on
    // one host: a pose published after
    // every fix up to its time had come is the in-order pose bit for bit
    // (as `same_drive_replayed_twice_gives_identical_pose_streams` checks on
    // one host); the others may lack the newest fix.
    b.terminate(odo);
    assert!(b.wait_exit(odo).success(), "{}", b.log(odo));
    let odo = odometry(&mut b, &folder_b, &[]);
    b.wait_log(odo, "switching estimate v0 -> v7");
    const FIX_LATE_NS: i64 = 50_000_000;
    let late = replay_and_collect_with(
        &mut a,
        &folder_a,
        "2",
        &sub,
        last,
        &["--speed", "20", "--deliver-late", "gnss=0.05"],
    );
    assert_eq!(sub.lost(), 0, "poses lost across the gateways");
    b.terminate(odo);
    assert!(b.wait_exit(odo).success(), "{}", b.log(odo));
    let fixes: Vec<i64> = drive
        .gnss
        .as_deref()
        .expect("gnss")
        .iter()
        .map(|f| interfaces::wire::seconds_to_ns(f.t_s))
        .collect();
    let waiting_for_a_fix = |t: i64| fixes.iter().any(|&f| f <= t && t < f + FIX_LATE_NS);
    assert_eq!(late.len(), single.len());
    let mut complete = 0;
    for (i, (s, l)) in single.iter().zip(&late).enumerate() {
        if !waiting_for_a_fix(s.header.t_ns) {
            assert_eq!(
                bits(s),
                bits(l),
                "pose {i}: one host {s:?}, late fixes across {l:?}"
            );
            complete += 1;
        }
    }
    assert!(complete > single.len() / 3, "{complete} complete poses");
    let odo_log = b.log(odo);
    let taken = odo_log
        .lines()
        .find(|l| l.contains("late sample(s) taken in order"))
        .unwrap_or_else(|| panic!("no summary line in the odometry's log:\n{odo_log}"));
    eprintln!(
        "two hosts, late fixes: {complete} of {} poses complete; {taken}",
        single.len()
    );
    assert!(taken.contains(", 0 later than the 1 s window"), "{taken}");
    assert!(
        !taken.contains(" 0 late sample(s) taken in order"),
        "{taken}"
    );

    // Nothing went missing on the way, as the gateways count it.
    a.terminate(gw_a);
    b.terminate(gw_b);
    assert!(a.wait_exit(gw_a).success(), "{}", a.log(gw_a));
    assert!(b.wait_exit(gw_b).success(), "{}", b.log(gw_b));
    for (name, log) in [("A", a.log(gw_a)), ("B", b.log(gw_b))] {
        let line = log
            .lines()
            .find(|l| l.contains("gateway: stopped"))
            .unwrap_or_else(|| panic!("gateway {name} wrote no summary:\n{log}"));
        assert!(line.contains("(0 lost locally"), "gateway {name}: {line}");
        assert!(!log.contains("rejected a frame"), "gateway {name}:\n{log}");
        assert!(!log.contains("never arrived"), "gateway {name}:\n{log}");
    }
}

/// Gateway B (the odometry's side) is killed mid-drive: the odometry reports
/// stale inputs; meanwhile the calibrator on host A starts and publishes its
/// estimate, which nobody on host B is listening for. Gateway B restarted,
/// the estimate arrives (the latest value is asked for), the wheel samples
/// come again and the same odometry process resumes. Then gateway A (the
/// listening side) is killed while a new calibrator publishes a newer
/// estimate; restarted, gateway B reconnects to it by itself and the newer
/// estimate arrives too: no accepted estimate is lost.
#[test]
fn gateways_killed_mid_drive_lose_no_estimate_and_the_gap_is_reported() {
    let drive = simulate(&SimConfig::new(Scenario::Paper, 6)).expect("drive");
    let last = last_wheel_t_ns(&drive);
    let mut a = Graph::new("gwkilla");
    let mut b = Graph::new("gwkillb");
    let endpoint = free_tcp_endpoint();
    let folder_a = write(&a, &drive, "drive");
    let folder_b = write(&b, &drive, "drive");
    let state = a.path("state.json");
    let state_s = state.to_str().expect("utf-8").to_string();
    let bus_b = b.bus("test");
    let sub = bus_b
        .subscriber::<Pose>()
        .expect("pose subscriber on host B");
    let odo = odometry(&mut b, &folder_b, &["--stale-after", "0.3"]);
    let mut gw_a = gateway_a(&mut a, "gateway-a", &endpoint);
    let gw_b = gateway_b(&mut b, "gateway-b", &endpoint);
    a.wait_log(gw_a, "forwarding");
    b.wait_log(gw_b, "forwarding");
    // Paced (about 17 s for the 134 s drive), so that the kills fall mid-drive.
    let replay = a.spawn(
        "replay",
        Bin::SensorBridge,
        &[
            "replay",
            &folder_a,
            "--speed",
            "8",
            "--wait-subscribers",
            "1",
            "--linger",
            "0.5",
        ],
    );
    let mut poses = Vec::new();
    wait_until("fused poses on host B", || {
        drain(&sub, &mut poses);
        poses
            .iter()
            .filter(|p| p.mode == PoseMode::Fused as u8)
            .count()
            > 100
    });

    // 1. Gateway B dies; the odometry says its inputs are stale.
    b.kill(gw_b);
    wait_log_draining(&b, odo, "inputs stale", &sub, &mut poses);
    seeded_calibrator_state(&state, 7);
    let cal = calibrator(&mut a, "calibrator", &folder_a, &state_s);
    wait_log_draining(
        &a,
        cal,
        "starting from the persisted estimate v7",
        &sub,
        &mut poses,
    );
    let published = Instant::now();
    wait_until("a moment after the publication", || {
        drain(&sub, &mut poses);
        published.elapsed() > Duration::from_millis(300) // published, and gone nowhere
    });
    assert!(!b.log(odo).contains("-> v7"), "{}", b.log(odo));
    let gw_b2 = gateway_b(&mut b, "gateway-b-2", &endpoint);
    wait_log_draining(&b, odo, "switching estimate v0 -> v7", &sub, &mut poses);
    wait_log_draining(&b, odo, "wheel samples again", &sub, &mut poses);

    // 2. Gateway A dies; a newer estimate is published meanwhile.
    let before = poses.len();
    wait_until("poses after gateway B came back", || {
        drain(&sub, &mut poses);
        poses[before..]
            .iter()
            .filter(|p| p.estimate_version == 7 && p.mode != PoseMode::NoFix as u8)
            .count()
            > 50
    });
    a.kill(gw_a);
    let stale_2 = {
        let log = b.log(odo);
        log.matches("inputs stale").count()
    };
    wait_until("the second stale report", || {
        drain(&sub, &mut poses);
        b.log(odo).matches("inputs stale").count() > stale_2
    });
    a.terminate(cal);
    let status = a.wait_exit_with(cal, || {
        drain(&sub, &mut poses);
    });
    assert!(status.success(), "{}", a.log(cal));
    seeded_calibrator_state(&state, 8);
    let cal2 = calibrator(&mut a, "calibrator-2", &folder_a, &state_s);
    wait_log_draining(
        &a,
        cal2,
        "starting from the persisted estimate v8",
        &sub,
        &mut poses,
    );
    gw_a = gateway_a(&mut a, "gateway-a-2", &endpoint);
    wait_log_draining(&b, odo, "switching estimate v7 -> v8", &sub, &mut poses);
    wait_log_draining(&a, gw_a, "forwarding", &sub, &mut poses);
    // Gateway B stayed up this time: it counts what the link lost.
    let gap_log = wait_log_draining(&b, gw_b2, "never arrived", &sub, &mut poses);
    assert!(gap_log.contains("gateway: wheels: "), "{gap_log}");

    let status = a.wait_exit_with(replay, || {
        drain(&sub, &mut poses);
    });
    assert!(status.success(), "replay:\n{}", a.log(replay));
    wait_until("the pose of the last wheel sample", || {
        drain(&sub, &mut poses);
        poses.last().is_some_and(|p| p.header.t_ns >= last)
    });
    assert!(b.is_running(odo), "the same odometry process throughout");
    assert_eq!(sub.lost(), 0, "no pose lost on host B");
    let odo_log = b.log(odo);
    assert_eq!(odo_log.matches("inputs stale").count(), 2, "{odo_log}");
    assert_eq!(
        odo_log.matches("wheel samples again").count(),
        2,
        "{odo_log}"
    );
    // The stale markers and nothing between them and the resumption.
    let markers = poses
        .iter()
        .filter(|p| p.mode == PoseMode::NoFix as u8 && p.x_m == 0.0 && p.covariance == [0.0; 9])
        .count();
    assert!(markers >= 2, "NoFix poses: {markers}");
    let last_pose = poses.last().expect("poses");
    assert_eq!(
        last_pose.estimate_version, 8,
        "the newest estimate in use at the end"
    );
    assert_ne!(
        last_pose.mode,
        PoseMode::NoFix as u8,
        "a pose with a position again at the end"
    );
    // Time never went back on host B: the gateways carried a forward stream.
    assert!(poses
        .windows(2)
        .all(|w| w[0].header.t_ns <= w[1].header.t_ns));
}

/// A frame whose header names another type (or another layout of the same
/// type) is refused with an error that names the topic; a correct frame on
/// the same key goes through.
#[test]
fn a_mismatched_type_is_rejected_with_an_error_naming_the_topic() {
    let mut b = Graph::new("gwmismatch");
    let endpoint = free_tcp_endpoint();
    let bus = b.bus("test");
    let sub = bus
        .subscriber::<WheelRotations>()
        .expect("wheel subscriber");
    let gw = b.spawn(
        "gateway",
        Bin::Gateway,
        &["--in", "wheels", "--listen", &endpoint],
    );
    b.wait_log(gw, "out [], in [wheels]");

    // This test is the other host: a Zenoh peer putting frames by hand.
    let mut config = zenoh::Config::default();
    config
        .insert_json5("connect/endpoints", &format!("[\"{endpoint}\"]"))
        .expect("connect");
    config
        .insert_json5("scouting/multicast/enabled", "false")
        .expect("scouting");
    config
        .insert_json5("listen/endpoints", "[]")
        .expect("listen");
    let session = zenoh::open(config).wait().expect("zenoh session");
    let publisher = session
        .declare_publisher(WHEELS_SERVICE)
        .wait()
        .expect("publisher");
    let good = WheelRotations {
        header: Header::from_seconds(12.5, 41),
        rl_rev: 100.25,
        rr_rev: 99.75,
        ..WheelRotations::default()
    };
    let imu = Imu {
        header: Header::from_seconds(12.5, 3),
        ..Imu::default()
    };
    let mut frame = Vec::new();
    let mut received: Vec<WheelRotations> = Vec::new();
    let start = Instant::now();
    // Until the gateway's subscription has reached this peer: bad, bad, good.
    while received.is_empty() {
        assert!(start.elapsed() < Duration::from_secs(60), "watchdog");
        encode(
            &mut frame,
            Kind::Sample,
            (1, 1),
            "wheelcal/Imu/v1",
            bytemuck::bytes_of(&imu),
        )
        .expect("frame");
        publisher.put(frame.clone()).wait().expect("put");
        let v2 = [bytemuck::bytes_of(&good), &[0u8; 8][..]].concat();
        encode(
            &mut frame,
            Kind::Sample,
            (1, 1),
            "wheelcal/WheelRotations/v2",
            &v2,
        )
        .expect("frame");
        publisher.put(frame.clone()).wait().expect("put");
        encode(
            &mut frame,
            Kind::Sample,
            (1, 1),
            "wheelcal/WheelRotations/v1",
            bytemuck::bytes_of(&good),
        )
        .expect("frame");
        publisher.put(frame.clone()).wait().expect("put");
        std::thread::sleep(Duration::from_millis(100));
        drain(&sub, &mut received);
    }
    let log = b.wait_log(gw, "WheelRotations/v2");
    assert!(
        log.contains(
            "wheelcal/sensors/wheels: type mismatch: the sender publishes \"wheelcal/Imu/v1\" \
             (72 bytes), this side expects \"wheelcal/WheelRotations/v1\" (56 bytes)"
        ),
        "{log}"
    );
    assert!(
        log.contains(
            "wheelcal/sensors/wheels: type mismatch: the sender publishes \
             \"wheelcal/WheelRotations/v2\" (64 bytes)"
        ),
        "{log}"
    );
    // Only the good frames came through, value for value.
    for r in &received {
        assert_eq!(
            (r.rl_rev, r.rr_rev, r.header.t_ns),
            (good.rl_rev, good.rr_rev, good.header.t_ns)
        );
    }
    drop(publisher);
    session.close().wait().expect("close");
    b.terminate(gw);
    assert!(b.wait_exit(gw).success(), "{}", b.log(gw));
    let stopped = b.log(gw);
    let line = stopped
        .lines()
        .find(|l| l.contains("gateway: stopped"))
        .expect("summary");
    assert!(
        line.contains(&format!("wheels {}", received.len())),
        "{line}"
    );
}

/// What would let a sample come back is refused at start, with the reason:
/// a topic both ways, and a second gateway in a graph that has one.
#[test]
fn a_topic_both_ways_and_a_second_gateway_are_refused() {
    let mut g = Graph::new("gwrefuse");
    let both = g.spawn(
        "gateway-both-ways",
        Bin::Gateway,
        &[
            "--out",
            "wheels,pose",
            "--in",
            "pose",
            "--listen",
            &free_tcp_endpoint(),
        ],
    );
    assert!(!g.wait_exit(both).success(), "{}", g.log(both));
    assert!(
        g.log(both)
            .contains("topic \"pose\" is both sent (out) and received (in)"),
        "{}",
        g.log(both)
    );
    let first = g.spawn(
        "gateway",
        Bin::Gateway,
        &["--in", "wheels", "--listen", &free_tcp_endpoint()],
    );
    g.wait_log(first, "out [], in [wheels]");
    let second = g.spawn(
        "gateway-2",
        Bin::Gateway,
        &["--out", "wheels", "--listen", &free_tcp_endpoint()],
    );
    assert!(!g.wait_exit(second).success(), "{}", g.log(second));
    assert!(
        g.log(second).contains("another gateway runs in this graph"),
        "{}",
        g.log(second)
    );
    assert!(g.is_running(first), "the first gateway runs on");
}
