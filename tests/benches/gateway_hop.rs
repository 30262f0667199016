//! What the Zenoh hop between two hosts costs: two graphs in separate
//! iceoryx2 roots on this machine, joined by two `gateway` processes over
//! loopback TCP, against the single-host graph.
//!
//! 1. **Latency.** This process publishes wheel samples in graph A at
//!    `RATE` Hz, each stamped with the wall clock at publish (in its `t_ns`),
//!    and a thread subscribed to the wheel topic (WaitSet wakeup) stamps the
//!    arrival: in graph A itself (**one host**: one iceoryx2 hop), and in
//!    graph B through gateway A -> Zenoh -> gateway B (**two hosts**), with
//!    the gateways batching (default) and with `--express`. The figures are
//!    publish -> receive; the added latency of the hop is the difference.
//! 2. **Throughput.** A 1 h drive replayed with `--max`: the bridge and the
//!    odometry in one graph, then the bridge in graph A and the odometry in
//!    graph B behind the two gateways, this process counting the poses in
//!    the odometry's graph. Reported: sensor samples per second from the
//!    first to the last pose, and every loss counted on the way (poses by
//!    sequence number here, the odometry's inputs, the gateways' counts of
//!    the sender's sequence numbers).
//!
//! `cargo bench -p integration-tests --bench gateway_hop [-- SECONDS]
//! [--samples N]` (drive length, default 3600 s; latency samples per
//! configuration, default 3000 at 200 Hz).

use drive_io::write_drive;
use iceoryx2::prelude::CallbackProgression;
use integration_tests::graph::{drain, free_tcp_endpoint, wait_until, Bin, Graph, ProcId};
use integration_tests::latency::quantile;
use interfaces::bus::{self, Bus, BusSettings};
use interfaces::latency_trace::wall_clock_ns;
use interfaces::wire::{Header, Pose, WheelRotations};
use simulator::{simulate, Scenario, SimConfig};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

const RATE_HZ: f64 = 200.0;
const WARMUP: usize = 200;
const SENSORS: &str = "wheels,gnss,imu,heading";

fn number_after(log: &str, before: &str, after: &str) -> Option<f64> {
    let i = log.rfind(before)? + before.len();
    let rest = &log[i..];
    let j = rest.find(after)?;
    rest[..j].split_whitespace().last()?.parse().ok()
}

/// Receive wheel samples in the graph of `settings` until `n` came or
/// `stop` is set; the latency of each (receive wall clock - the `t_ns`
/// stamped at publish), µs.
fn receiver(
    settings: BusSettings,
    n: usize,
    ready: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<Vec<f64>> {
    std::thread::spawn(move || {
        let bus = Bus::open(&settings, "bench-receiver").expect("bus");
        let sub = bus.subscriber::<WheelRotations>().expect("subscriber");
        let waitset = bus.waitset().expect("waitset");
        let _g = bus::wake_on(&waitset, "wheels", sub.listener()).expect("attach");
        let _t = bus::tick_every(&waitset, Duration::from_millis(100)).expect("tick");
        ready.store(true, Ordering::SeqCst);
        let mut out = Vec::with_capacity(n);
        while out.len() < n && !stop.load(Ordering::SeqCst) {
            bus::wait_once(&waitset, None, |_| CallbackProgression::Continue).expect("wait");
            let _ = sub.take_notifications();
            while let Some(s) = sub.receive().expect("receive") {
                let now = wall_clock_ns();
                out.push((now - i128::from(s.header.t_ns)) as f64 * 1e-3);
            }
        }
        out
    })
}

/// Publish `n` stamped wheel samples in `a` at [`RATE_HZ`], received in
/// the graph of `at`; returns the latencies after the warm-up, sorted.
fn latency_run(a: &Graph, at: &BusSettings, n: usize) -> Vec<f64> {
    let ready = Arc::new(AtomicBool::new(false));
    let stop = Arc::new(AtomicBool::new(false));
    let rx = receiver(at.clone(), n, ready.clone(), stop.clone());
    wait_until("the receiver", || ready.load(Ordering::SeqCst));
    let bus = a.bus("bench-publisher");
    let mut publisher = bus.publisher::<WheelRotations>().expect("publisher");
    // The receiver (directly or through the gateways) is connected.
    wait_until("a subscriber", || publisher.subscriber_count() > 0);
    publisher.announce().expect("announce");
    std::thread::sleep(Duration::from_millis(500));
    let period = Duration::from_secs_f64(1.0 / RATE_HZ);
    let start = Instant::now();
    for i in 0..n {
        let due = start + period * i as u32;
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
        let sample = WheelRotations {
            header: Header {
                t_ns: wall_clock_ns() as i64,
                seq: 0,
            },
            rl_rev: i as f64,
            rr_rev: i as f64,
            ..WheelRotations::default()
        };
        publisher.publish(sample).expect("publish");
    }
    // Time for the last ones to arrive; then the receiver stops waiting.
    std::thread::sleep(Duration::from_secs(3));
    stop.store(true, Ordering::SeqCst);
    let mut lat = rx.join().expect("receiver thread");
    assert_eq!(lat.len(), n, "every stamped sample arrived");
    let mut lat = lat.split_off(WARMUP.min(n));
    lat.sort_by(f64::total_cmp);
    lat
}

fn print_latency(what: &str, lat: &[f64]) {
    println!(
        "  {what:<34} p50 {:8.1} µs  p90 {:8.1} µs  p99 {:8.1} µs  max {:9.1} µs  ({} samples)",
        quantile(lat, 0.5),
        quantile(lat, 0.9),
        quantile(lat, 0.99),
        lat.last().copied().unwrap_or(f64::NAN),
        lat.len()
    );
}

fn gateways(a: &mut Graph, b: &mut Graph, out: &str, extra: &[&str]) -> (ProcId, ProcId) {
    let endpoint = free_tcp_endpoint();
    let mut args_a = vec!["--out", out, "--listen", &endpoint];
    args_a.extend_from_slice(extra);
    let mut args_b = vec!["--in", out, "--connect", &endpoint];
    args_b.extend_from_slice(extra);
    let ga = a.spawn("gateway-a", Bin::Gateway, &args_a);
    let gb = b.spawn("gateway-b", Bin::Gateway, &args_b);
    a.wait_log(ga, "forwarding");
    (ga, gb)
}

fn stop(g: &mut Graph, id: ProcId) -> String {
    g.terminate(id);
    let _ = g.wait_exit(id);
    g.log(id)
}

/// Replay `folder` with `--max` in `graphs[rep]`, the odometry in
/// `graphs[odo]` (the same graph for one host); count the poses there.
/// Prints the sensor samples per second from the first to the last pose
/// and everything lost on the way.
fn throughput_run(
    what: &str,
    graphs: &mut [Graph],
    (rep, odo): (usize, usize),
    folder: &str,
    (drive_samples, wheel_samples, last_wheel_ns): (usize, usize, i64),
) {
    let vehicle = format!("{folder}/vehicle.toml");
    let odometry = graphs[odo].spawn("odometry", Bin::Odometry, &["serve", "--vehicle", &vehicle]);
    let bus = graphs[odo].bus("bench");
    let sub = bus.subscriber::<Pose>().expect("poses");
    graphs[odo].wait_log(odometry, "GNSS antenna");
    let replay = graphs[rep].spawn(
        "replay",
        Bin::SensorBridge,
        &[
            "replay",
            folder,
            "--max",
            "--wait-subscribers",
            "1",
            "--progress",
            "600",
        ],
    );
    let mut poses: Vec<Pose> = Vec::new();
    let mut count = 0usize;
    let mut last_t = i64::MIN;
    let mut first_pose: Option<Instant> = None;
    let mut take = |poses: &mut Vec<Pose>, count: &mut usize, last_t: &mut i64| {
        drain(&sub, poses);
        if !poses.is_empty() && first_pose.is_none() {
            first_pose = Some(Instant::now());
        }
        *count += poses.len();
        if let Some(p) = poses.last() {
            *last_t = p.header.t_ns;
        }
        poses.clear();
    };
    let status = graphs[rep].wait_exit_with(replay, || take(&mut poses, &mut count, &mut last_t));
    assert!(status.success(), "replay:\n{}", graphs[rep].log(replay));
    wait_until("the last pose", || {
        take(&mut poses, &mut count, &mut last_t);
        last_t >= last_wheel_ns
    });
    let end_to_end = first_pose.map_or(f64::NAN, |f| f.elapsed().as_secs_f64());
    let odo_log = stop(&mut graphs[odo], odometry);
    let replay_log = graphs[rep].log(replay);
    let published =
        number_after(&replay_log, "bridge: published", "samples in").unwrap_or(f64::NAN);
    let wall = number_after(&replay_log, "samples in", " s (").unwrap_or(f64::NAN);
    let odo_lost = number_after(&odo_log, "estimate switch(es),", "samples lost on the bus");
    println!("  {what}:");
    println!(
        "    bridge --max: {published:.0} samples in {wall:.2} s = {:.0} samples/s",
        published / wall
    );
    println!(
        "    first to last pose: {end_to_end:.2} s = {:.0} sensor samples/s end to end",
        drive_samples as f64 / end_to_end
    );
    println!(
        "    poses {count} (wheel samples {wheel_samples}), lost by sequence number: poses {}, odometry inputs {}; stale-input reports {}",
        sub.lost(),
        odo_lost.map_or("?".to_string(), |v| format!("{v:.0}")),
        odo_log.matches("inputs stale").count()
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let value_of = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .and_then(|v| v.parse::<f64>().ok())
    };
    let samples = value_of("--samples").map_or(3000, |v| v as usize);
    let seconds: f64 = args
        .iter()
        .skip(1)
        .enumerate()
        .find_map(|(i, a)| {
            let after_flag = i > 0 && args[i] == "--samples";
            if after_flag {
                None
            } else {
                a.parse().ok()
            }
        })
        .unwrap_or(3600.0);

    // 1. Latency.
    println!(
        "gateway hop latency: wheel samples at {RATE_HZ:.0} Hz, publish -> receive (wall clock)"
    );
    let a = Graph::new("hoplata");
    let direct = latency_run(&a, &a.settings, samples);
    print_latency("one host (iceoryx2)", &direct);
    for (label, extra) in [
        ("two hosts (gateways, Zenoh TCP)", &[][..]),
        ("two hosts, gateways --express", &["--express"][..]),
    ] {
        let mut a = Graph::new("hoplatb");
        let mut b = Graph::new("hoplatc");
        let (ga, gb) = gateways(&mut a, &mut b, "wheels", extra);
        b.wait_log(gb, "peer gateway");
        let lat = latency_run(&a, &b.settings, samples);
        print_latency(label, &lat);
        println!(
            "  {:<34} p50 {:+8.1} µs  p99 {:+8.1} µs",
            "  added by the hop",
            quantile(&lat, 0.5) - quantile(&direct, 0.5),
            quantile(&lat, 0.99) - quantile(&direct, 0.99)
        );
        stop(&mut a, ga);
        stop(&mut b, gb);
    }

    // 2. Throughput.
    let mut config = SimConfig::new(Scenario::Long, 1);
    config.duration_s = Some(seconds);
    let drive = simulate(&config).expect("simulate");
    let wheel_samples = drive.wheels.samples.len();
    let drive_samples = wheel_samples
        + drive.gnss.as_ref().map_or(0, Vec::len)
        + drive.imu.as_ref().map_or(0, Vec::len)
        + drive.heading.as_ref().map_or(0, Vec::len);
    let last_wheel_ns =
        interfaces::wire::seconds_to_ns(drive.wheels.samples.last().expect("wheels").t_s);
    println!(
        "gateway hop throughput: {seconds:.0} s drive, {drive_samples} sensor samples ({wheel_samples} wheel), replay --max"
    );
    let figures = (drive_samples, wheel_samples, last_wheel_ns);
    {
        let g = Graph::new("hopthr1");
        let folder = g.path("drive");
        write_drive(&drive, &folder).expect("write");
        let folder = folder.to_str().expect("utf-8").to_string();
        throughput_run("one host", &mut [g], (0, 0), &folder, figures);
    }
    {
        let mut a = Graph::new("hopthra");
        let mut b = Graph::new("hopthrb");
        let folder = a.path("drive");
        write_drive(&drive, &folder).expect("write");
        let folder = folder.to_str().expect("utf-8").to_string();
        let (ga, gb) = gateways(&mut a, &mut b, SENSORS, &[]);
        b.wait_log(gb, "peer gateway");
        let mut graphs = [a, b];
        throughput_run(
            "two hosts (gateways, Zenoh TCP)",
            &mut graphs,
            (0, 1),
            &folder,
            figures,
        );
        let [mut a, mut b] = graphs;
        let log_a = stop(&mut a, ga);
        let log_b = stop(&mut b, gb);
        let line = |log: &str| {
            log.lines()
                .find(|l| l.contains("gateway: stopped"))
                .map(|l| l[l.find("gateway: stopped").unwrap_or(0)..].to_string())
                .unwrap_or_else(|| "no summary".to_string())
        };
        println!("    gateway A: {}", line(&log_a));
        println!("    gateway B: {}", line(&log_b));
    }
}
