//! Sample-to-pose latency over iceoryx2, with blocking (WaitSet) wakeups.
//!
//! The benchmark process plays the bridge: it publishes a simulated drive on
//! the sensor topics (the bridge's own `TopicPublisher` code) paced in real
//! time, and stamps each wheel sample's publish instant. A thread of the same
//! process subscribes to the pose topic (WaitSet wakeup) and stamps the
//! arrival of the pose that carries the wheel sample's time. So each figure is
//! bridge publish -> (process) -> pose publish -> pose received: two hops.
//!
//! Measured in the same run, one after the other:
//! - **bare**: a relay process (this executable with `--relay`) that wakes on
//!   the wheel topic's event, receives the sample and publishes it on the
//!   pose topic, doing nothing else: a bare publisher/subscriber pair in each
//!   direction with the same wakeup mechanism;
//! - **odometry**: `odometry serve` doing its real work (fusion, pose).
//!
//! The one-hop figures (bridge publish -> the consumer's pose publish, what
//! the goals are about) compare the bridge's wall clock when it calls publish
//! with the consumer's wall clock when it calls publish for the pose, written by the consumer
//! at exit (`odometry serve --latency-trace`, the relay's `--trace`): the
//! processes share the machine's clock. The consumer also stamps the wakeup
//! that brought the wheel sample, which splits the hop into the wakeup
//! (iceoryx2 and the scheduler) and the consumer's own work.
//!
//! The consumers take turns (`--turns N`, default four each, each turn the
//! drive's first SECONDS / N seconds), so that the machine's drift during a run
//! falls on all alike; more turns even it out more finely. A run of more
//! than 60 s per consumer also prints the one hop's p99 in each 60 s window
//! of it (as many turns as make 60 s), beside the p99 over the whole run.
//!
//! `cargo bench -p integration-tests --bench graph_latency [--profile deploy]
//! [-- SECONDS] [--turns N] [--cpu-latency-zero] [--deliver-late STREAM=S,...]
//! [--baseline-odometry EXE] [--early-relay]` (default 60 s of drive per consumer).
//! `--profile deploy` builds the relay and the odometry as they are built for
//! the vehicle (fat LTO, one codegen unit; without it, the release profile).
//! `--baseline-odometry` adds a third consumer taking turns with the other
//! two: another build of `odometry serve` (a copy of the binary before a
//! change), so that a change is compared with what it replaces in the same
//! run.
//! `--early-relay` adds a consumer taking turns with the others: the bare
//! relay with the odometry's early wakeup (`odometry serve
//! --early-wakeup-ms`, default 1: it wakes 1-2 ms before each wheel sample
//! is due), so that the odometry is also compared with a bare pair that
//! wakes early as it does.
//! `--deliver-late` publishes those streams that long after their time
//! stamps, as `sensor-bridge replay --deliver-late` does: with late GNSS
//! fixes, the odometry goes back in its log at each fix, and the figures
//! include that work. `--cpu-latency-zero` holds the
//! machine's PM QoS CPU latency request at 0 during the run (a deployment
//! setting: idle cores poll instead of halting; needs root).

use drive_io::write_drive;
use iceoryx2::prelude::CallbackProgression;
use integration_tests::graph::{bin, Bin, Graph};
use integration_tests::latency::{quantile, CpuLatencyZero};
use interfaces::bus::{self, Bus, BusSettings, TopicPublisher};
use interfaces::latency_trace::{read_latency_trace, wall_clock_ns, write_latency_trace};
use interfaces::wire::{GnssFix, Heading, Imu, Pose, WheelRotations};
use odometry::cadence::WheelCadence;
use sensor_bridge::replay::{to_wire, DeliveryLatency, Stream, WireDrive};
use simulator::{simulate, Scenario, SimConfig};
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const WARMUP: usize = 300;

/// The flags followed by a value (which is not the SECONDS argument).
const FLAGS_WITH_VALUE: [&str; 5] = [
    "--trace",
    "--early-wakeup-ms",
    "--turns",
    "--deliver-late",
    "--baseline-odometry",
];

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let value_of = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
    };
    if args.iter().any(|a| a == "--relay") {
        let early = value_of("--early-wakeup-ms")
            .map(|v| v.parse().expect("--early-wakeup-ms N"))
            .unwrap_or(0);
        relay(
            value_of("--trace").map(std::path::Path::new),
            Duration::from_millis(early),
        );
        return;
    }
    let turns: usize = value_of("--turns")
        .map(|v| v.parse().expect("--turns N, a whole number"))
        .unwrap_or(4);
    assert!(turns > 0, "--turns must be at least 1");
    // The first plain number that is not the value of a flag.
    let seconds: f64 = args
        .iter()
        .enumerate()
        .skip(1)
        .filter(|(i, _)| !FLAGS_WITH_VALUE.contains(&args[i - 1].as_str()))
        .find_map(|(_, a)| a.parse().ok())
        .unwrap_or(60.0);
    let latency = value_of("--deliver-late")
        .map(|v| DeliveryLatency::parse(v).expect("--deliver-late"))
        .unwrap_or_default();
    let baseline = value_of("--baseline-odometry").map(std::path::PathBuf::from);
    run(
        seconds,
        turns,
        args.iter().any(|a| a == "--cpu-latency-zero"),
        &latency,
        baseline.as_deref(),
        args.iter().any(|a| a == "--early-relay"),
    );
}

/// The bare relay: wheels in, the same header out as a pose, nothing else;
/// the same wakeup as the odometry (a WaitSet on the wheel topic's event and
/// an interval), with `early` the odometry's early wakeup before each sample
/// too (`--early-relay`; zero: none).
fn relay(trace_path: Option<&std::path::Path>, early: Duration) {
    let mut trace: Vec<(i64, i128, i128)> = Vec::new();
    let bus = Bus::from_env("bench-relay").expect("bus");
    let wheels = bus.subscriber::<WheelRotations>().expect("wheels");
    let mut poses: TopicPublisher<Pose> = bus.publisher().expect("poses");
    let waitset = bus.waitset().expect("waitset");
    let _g = bus::wake_on(&waitset, "attach wheels", wheels.listener()).expect("attach");
    let _t = bus::tick_every(&waitset, Duration::from_millis(100)).expect("tick");
    eprintln!("relay ready");
    let mut sample_waiting = false;
    let mut cadence = WheelCadence::new(early);
    loop {
        let timeout = if sample_waiting {
            Some(Duration::ZERO)
        } else {
            cadence.wait_for_early_wakeup(Instant::now())
        };
        let r = bus::wait_once(&waitset, timeout, |_| CallbackProgression::Continue).expect("wait");
        let woke = wall_clock_ns();
        let mut got_wheels = false;
        while let Some(w) = wheels.receive().expect("receive") {
            got_wheels = true;
            trace.push((w.header.t_ns, woke, wall_clock_ns()));
            poses
                .publish(Pose {
                    header: w.header,
                    ..Pose::default()
                })
                .expect("publish");
        }
        if !got_wheels && cadence.take_early_pass(Instant::now()) {
            // As the odometry's early pass: a loan from the pose publisher.
            poses.warm_up().expect("warm up");
        }
        // As the odometry: the notifications after the poses.
        wheels.take_notifications().expect("events");
        sample_waiting = wheels.has_samples().expect("has samples");
        if got_wheels {
            cadence.wheels_at(Instant::now());
        }
        if bus::stop_requested_by(r) {
            break;
        }
    }
    // The same trace format as `odometry serve --latency-trace`.
    if let Some(path) = trace_path {
        write_latency_trace(path, &trace).expect("write trace");
    }
}

/// The consumer's wakeup and pose publish instants (wall clock, ns) by time
/// stamp, from its `--latency-trace` file.
fn read_trace(path: &std::path::Path) -> HashMap<i64, (i128, i128)> {
    read_latency_trace(path)
        .expect("trace file")
        .into_iter()
        .map(|(t, woke, published)| (t, (woke, published)))
        .collect()
}

struct Publishers {
    wheels: TopicPublisher<WheelRotations>,
    gnss: TopicPublisher<GnssFix>,
    imu: TopicPublisher<Imu>,
    heading: TopicPublisher<Heading>,
}

/// Arrival instants of poses by their time stamp.
type Arrivals = Arc<Mutex<HashMap<i64, Instant>>>;

fn receiver(
    settings: BusSettings,
    arrivals: Arrivals,
    stop: Arc<AtomicBool>,
    ready: std::sync::mpsc::Sender<()>,
) {
    let bus = Bus::open(&settings, "bench-receiver").expect("bus");
    let poses = bus.subscriber::<Pose>().expect("poses");
    let waitset = bus.waitset().expect("waitset");
    let _g = bus::wake_on(&waitset, "attach poses", poses.listener()).expect("attach");
    let _t = bus::tick_every(&waitset, Duration::from_millis(50)).expect("tick");
    let _ = ready.send(());
    while !stop.load(Ordering::SeqCst) {
        bus::wait_once(&waitset, None, |_| CallbackProgression::Continue).expect("wait");
        poses.take_events().expect("events");
        while let Some(p) = poses.receive().expect("receive") {
            let now = Instant::now();
            arrivals
                .lock()
                .expect("lock")
                .entry(p.header.t_ns)
                .or_insert(now);
        }
    }
}

/// Publish the first `seconds` of `wire` in real time, each stream
/// `latency` after its time stamps; returns the publish instants of the
/// wheel samples by time stamp.
fn publish(
    p: &mut Publishers,
    wire: &WireDrive,
    seconds: f64,
    latency: &DeliveryLatency,
) -> Vec<Sent> {
    let order = wire.delivery_order(latency);
    let t0 = wire.time_span_ns().expect("span").0;
    let start = Instant::now();
    let mut sent = Vec::new();
    let mut fix_since_wheels = false;
    for (stream, i) in order {
        let t_ns = wire.time_ns(stream, i);
        let due = (t_ns + latency.of_ns(stream) - t0) as f64 * 1e-9;
        if due > seconds {
            break;
        }
        let now = start.elapsed().as_secs_f64();
        if due > now {
            std::thread::sleep(Duration::from_secs_f64(due - now));
        }
        match stream {
            Stream::Wheels => {
                let wall_ns = wall_clock_ns();
                let at = Instant::now();
                p.wheels.publish(wire.wheels[i]).expect("publish");
                sent.push(Sent {
                    t_ns,
                    at,
                    wall_ns,
                    with_fix: std::mem::take(&mut fix_since_wheels),
                });
            }
            Stream::Gnss => {
                p.gnss.publish(wire.gnss[i]).expect("publish");
                fix_since_wheels = true;
            }
            Stream::Imu => {
                p.imu.publish(wire.imu[i]).expect("publish");
            }
            Stream::Heading => {
                p.heading.publish(wire.heading[i]).expect("publish");
            }
        }
    }
    sent
}

/// A wheel sample as the benchmark published it.
struct Sent {
    t_ns: i64,
    /// Just before publishing (monotonic, for the round trip).
    at: Instant,
    /// Just before publishing (wall clock, ns, to compare with the consumer's trace).
    wall_ns: i128,
    /// A GNSS fix was published since the previous wheel sample: the
    /// consumer's wakeup for this one takes it too (late, it makes the
    /// odometry go back in its log).
    with_fix: bool,
}

struct Stats {
    n: usize,
    p50: f64,
    p99: f64,
    p999: f64,
    max: f64,
    missing: usize,
}

/// Latencies in microseconds (`None`: the pose never came), warm-up skipped.
type Latencies = Vec<Option<f64>>;

/// Round trip: bridge publish -> consumer -> pose publish -> pose received.
fn round_trip(sent: &[Sent], arrivals: &Arrivals) -> Latencies {
    let arrivals = arrivals.lock().expect("lock");
    sent.iter()
        .skip(WARMUP)
        .map(|s| {
            arrivals
                .get(&s.t_ns)
                .map(|a| a.duration_since(s.at).as_secs_f64() * 1e6)
        })
        .collect()
}

/// One hop with the work: bridge publish -> the consumer's pose publish
/// (wall clock on both sides: one machine, one clock), and its two parts:
/// bridge publish -> the consumer's wakeup, wakeup -> pose publish.
fn one_hop(sent: &[Sent], trace: &HashMap<i64, (i128, i128)>) -> [Latencies; 3] {
    let part = |f: fn(&Sent, (i128, i128)) -> i128| {
        sent.iter()
            .skip(WARMUP)
            .map(|s| trace.get(&s.t_ns).map(|&w| f(s, w) as f64 * 1e-3))
            .collect()
    };
    [
        part(|s, (_, published)| published - s.wall_ns),
        part(|s, (woke, _)| woke - s.wall_ns),
        part(|_, (woke, published)| published - woke),
    ]
}

fn stats(latencies: &[Option<f64>]) -> Stats {
    let mut lat: Vec<f64> = Vec::new();
    let mut missing = 0;
    for &l in latencies {
        match l {
            Some(v) => lat.push(v),
            None => missing += 1,
        }
    }
    lat.sort_by(f64::total_cmp);
    let q = |p: f64| quantile(&lat, p);
    Stats {
        n: lat.len(),
        p50: q(0.5),
        p99: q(0.99),
        p999: q(0.999),
        max: lat.last().copied().unwrap_or(f64::NAN),
        missing,
    }
}

/// One row of the result table: `name`, then the count and the quantiles.
fn print_row(name: &str, s: &Stats) {
    println!(
        "{name:<44} {:>6} {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>8}",
        s.n, s.p50, s.p99, s.p999, s.max, s.missing
    );
}

/// The rows of `who`'s one hop and its two parts (`published`: what it
/// publishes); returns the one hop's figures.
fn print_one_hop(who: &str, published: &str, pooled: &Pooled) -> Stats {
    let [hop, wake, work] = [&pooled.hop, &pooled.wake, &pooled.work].map(|l| stats(l));
    print_row(&format!("publish -> {who}'s {published} (1 hop)"), &hop);
    print_row(&format!("  of which publish -> {who}'s wakeup"), &wake);
    print_row(&format!("  of which wakeup -> {who}'s {published}"), &work);
    hop
}

/// The rows of an odometry's work after the wakeup, split by whether the
/// wakeup took a GNSS fix too.
fn print_work_by_fix(pooled: &Pooled) {
    for (name, with_fix) in [
        ("  of which wakeups that took a GNSS fix", true),
        ("  of which wakeups without one", false),
    ] {
        let part: Latencies = pooled
            .work
            .iter()
            .zip(&pooled.with_fix)
            .filter(|(_, &f)| f == with_fix)
            .map(|(l, _)| *l)
            .collect();
        print_row(name, &stats(&part));
    }
}

/// The count of late samples `odometry serve` took in their place, from its
/// exit line ("... N late sample(s) taken in order ...").
fn late_samples_taken_in_order(log: &str) -> u64 {
    const MARK: &str = " late sample(s) taken in order";
    log.lines()
        .filter_map(|line| {
            let head = &line[..line.find(MARK)?];
            head.rsplit(' ').next()?.parse::<u64>().ok()
        })
        .sum()
}

/// Wait (watchdog 60 s) until `who` subscribes to IMU, GNSS and heading too.
fn wait_for_sensor_subscribers(p: &Publishers, who: &str) {
    let start = Instant::now();
    while p.imu.subscriber_count() < 1
        || p.heading.subscriber_count() < 1
        || p.gnss.subscriber_count() < 1
    {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "{who} did not subscribe"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// What every turn publishes, and where the poses it brings are stamped.
struct Feed<'a> {
    wire: &'a WireDrive,
    /// Seconds of drive per turn.
    seconds: f64,
    latency: &'a DeliveryLatency,
    arrivals: &'a Arrivals,
}

fn phase(p: &mut Publishers, feed: &Feed) -> (Latencies, Vec<Sent>) {
    // Wait until the consumer subscribes to every sensor topic it reads and
    // attaches (announce + settle, as the bridge does).
    let start = Instant::now();
    while p.wheels.subscriber_count() < 1 {
        assert!(start.elapsed() < Duration::from_secs(60), "no subscriber");
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(Duration::from_millis(300));
    for r in [
        p.wheels.announce(),
        p.gnss.announce(),
        p.imu.announce(),
        p.heading.announce(),
    ] {
        r.expect("announce");
    }
    std::thread::sleep(Duration::from_millis(300));
    feed.arrivals.lock().expect("lock").clear();
    let sent = publish(p, feed.wire, feed.seconds, feed.latency);
    std::thread::sleep(Duration::from_millis(500));
    (round_trip(&sent, feed.arrivals), sent)
}

/// One turn of an `odometry serve` build `exe` with the drive's `vehicle`
/// file: start it, publish, stop it; its latencies go into `into`. Returns
/// the late samples it took in order.
fn odometry_turn(
    g: &mut Graph,
    p: &mut Publishers,
    feed: &Feed,
    exe: &std::path::Path,
    label: &str,
    vehicle: &std::path::Path,
    into: &mut Pooled,
) -> u64 {
    let trace = g.path(&format!("trace-{label}-{}.csv", into.turns()));
    let odo = g.spawn_exe(
        label,
        exe,
        &[
            "serve",
            "--vehicle",
            vehicle.to_str().expect("utf-8"),
            "--no-bus-estimate",
            "--latency-trace",
            trace.to_str().expect("utf-8"),
        ],
    );
    wait_for_sensor_subscribers(p, label);
    let (rt, sent) = phase(p, feed);
    g.terminate(odo);
    g.wait_exit(odo);
    into.add(rt, &sent, one_hop(&sent, &read_trace(&trace)));
    late_samples_taken_in_order(&g.log(odo))
}

/// One turn of the bare relay (this executable with `--relay` and `extra`
/// arguments): start it, publish, stop it; its latencies go into `into`.
fn relay_turn(
    g: &mut Graph,
    p: &mut Publishers,
    feed: &Feed,
    exe: &std::path::Path,
    label: &str,
    extra: &[&str],
    into: &mut Pooled,
) {
    let trace = g.path(&format!("trace-{label}-{}.csv", into.turns()));
    let mut args = vec!["--relay", "--trace", trace.to_str().expect("utf-8")];
    args.extend_from_slice(extra);
    let relay = g.spawn_exe(label, exe, &args);
    let (rt, sent) = phase(p, feed);
    g.terminate(relay);
    g.wait_exit(relay);
    into.add(rt, &sent, one_hop(&sent, &read_trace(&trace)));
}

/// One consumer's latencies, pooled over the rounds.
#[derive(Default)]
struct Pooled {
    round_trip: Latencies,
    hop: Latencies,
    wake: Latencies,
    work: Latencies,
    /// Per entry: the wakeup took a GNSS fix too ([`Sent::with_fix`]).
    with_fix: Vec<bool>,
    /// Per turn added so far: where its entries end in `hop` (and the other lists).
    turn_ends: Vec<usize>,
}

impl Pooled {
    fn add(&mut self, round_trip: Latencies, sent: &[Sent], [hop, wake, work]: [Latencies; 3]) {
        self.with_fix
            .extend(sent.iter().skip(WARMUP).map(|s| s.with_fix));
        self.round_trip.extend(round_trip);
        self.hop.extend(hop);
        self.wake.extend(wake);
        self.work.extend(work);
        self.turn_ends.push(self.hop.len());
    }

    /// Turns added so far.
    fn turns(&self) -> usize {
        self.turn_ends.len()
    }

    /// The one hop's p99 in each window of `turns_per_window` consecutive
    /// turns (a last, shorter window is left out).
    fn hop_p99_by_window(&self, turns_per_window: usize) -> Vec<f64> {
        let bounds: Vec<usize> = std::iter::once(0)
            .chain(self.turn_ends.iter().copied())
            .step_by(turns_per_window)
            .collect();
        bounds
            .windows(2)
            .map(|b| stats(&self.hop[b[0]..b[1]]).p99)
            .collect()
    }
}

/// When a run is longer than the default one (60 s of drive per consumer):
/// the one hop's p99 in each 60 s window of it, per consumer, so that a long
/// run shows both the p99 over the whole run and how it varies from minute
/// to minute, as the default run's does from run to run.
fn print_p99_by_window(per_phase: f64, consumers: &[(&str, &Pooled)]) {
    let turns_per_window = ((60.0 / per_phase).round() as usize).max(1);
    let windows = consumers
        .first()
        .map_or(0, |(_, p)| p.turns() / turns_per_window);
    if windows < 2 {
        return;
    }
    println!(
        "one hop p99 in each window of {turns_per_window} turns ({:.0} s of drive, as a default run), microseconds:",
        turns_per_window as f64 * per_phase
    );
    for (name, pooled) in consumers {
        let p99s = pooled.hop_p99_by_window(turns_per_window);
        let met = p99s.iter().filter(|&&p| p <= 100.0).count();
        let listed: Vec<String> = p99s.iter().map(|p| format!("{p:.1}")).collect();
        println!(
            "  {name:<12} <= 100 us in {met} of {}: {}",
            p99s.len(),
            listed.join(" ")
        );
    }
}

fn run(
    seconds: f64,
    rounds: usize,
    cpu_latency_zero: bool,
    latency: &DeliveryLatency,
    baseline: Option<&std::path::Path>,
    early_relay: bool,
) {
    let _pm_qos = cpu_latency_zero.then(|| {
        CpuLatencyZero::hold()
            .expect("--cpu-latency-zero needs write access to /dev/cpu_dma_latency (root)")
    });
    let mut g = Graph::new("lat");
    let drive = simulate(&SimConfig::new(Scenario::Mixed, 1)).expect("simulate");
    let folder = g.path("drive");
    write_drive(&drive, &folder).expect("write");
    let wire = to_wire(&drive).expect("wire");
    let bus = g.bus("bench-bridge");
    let mut p = Publishers {
        wheels: bus.publisher().expect("p"),
        gnss: bus.publisher().expect("p"),
        imu: bus.publisher().expect("p"),
        heading: bus.publisher().expect("p"),
    };
    let arrivals: Arrivals = Arc::new(Mutex::new(HashMap::new()));
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = std::sync::mpsc::channel();
    let handle = {
        let (s, a, st) = (g.settings.clone(), arrivals.clone(), stop.clone());
        std::thread::spawn(move || receiver(s, a, st, tx))
    };
    rx.recv().expect("receiver ready");

    let exe = std::env::current_exe().expect("exe");
    let vehicle = folder.join("vehicle.toml");
    let per_phase = seconds / rounds as f64;
    let mut rewinds = 0u64;
    let (mut bare, mut odometry) = (Pooled::default(), Pooled::default());
    let mut baseline_odometry = Pooled::default();
    let mut early_bare = Pooled::default();
    // The consumers take turns, so that a drift of the machine's state
    // during the run falls on all alike.
    let feed = Feed {
        wire: &wire,
        seconds: per_phase,
        latency,
        arrivals: &arrivals,
    };
    let odometry_exe = bin(Bin::Odometry);
    for _ in 0..rounds {
        relay_turn(&mut g, &mut p, &feed, &exe, "relay", &[], &mut bare);
        if early_relay {
            relay_turn(
                &mut g,
                &mut p,
                &feed,
                &exe,
                "early-relay",
                &["--early-wakeup-ms", "1"],
                &mut early_bare,
            );
        }

        rewinds += odometry_turn(
            &mut g,
            &mut p,
            &feed,
            &odometry_exe,
            "odometry",
            &vehicle,
            &mut odometry,
        );
        if let Some(baseline) = baseline {
            odometry_turn(
                &mut g,
                &mut p,
                &feed,
                baseline,
                "baseline-odometry",
                &vehicle,
                &mut baseline_odometry,
            );
        }
    }
    stop.store(true, Ordering::SeqCst);
    let _ = handle.join();

    println!(
        "sample-to-pose latency, {seconds:.0} s of drive at 100 Hz per consumer in {rounds} turns \
         (first {WARMUP} samples of each skipped), PM QoS CPU latency request: {}; microseconds:",
        if cpu_latency_zero {
            "0 (--cpu-latency-zero)"
        } else {
            "none (the machine's default)"
        }
    );
    if *latency != DeliveryLatency::default() {
        println!(
            "delivered late (time stamps as recorded): GNSS {} s, IMU {} s, heading {} s, wheels {} s; \
             the odometry went back {rewinds} time(s) for late samples",
            latency.gnss_s, latency.imu_s, latency.heading_s, latency.wheels_s
        );
    }
    let [bare_rt, bare_hop, bare_wake, bare_work] =
        [&bare.round_trip, &bare.hop, &bare.wake, &bare.work].map(|l| stats(l));
    println!(
        "{:<44} {:>6} {:>8} {:>8} {:>8} {:>8} {:>8}",
        "", "n", "p50", "p99", "p99.9", "max", "missing"
    );
    for (name, s) in [
        ("bare relay (2 hops, no work)", &bare_rt),
        (
            "odometry serve (2 hops + fusion)",
            &stats(&odometry.round_trip),
        ),
        ("bare pair: publish -> relay's publish (1 hop)", &bare_hop),
        ("  of which publish -> relay's wakeup", &bare_wake),
        ("  of which wakeup -> relay's publish", &bare_work),
    ] {
        print_row(name, s);
    }
    let odometry_hop = print_one_hop("odometry", "pose publish", &odometry);
    print_work_by_fix(&odometry);
    if let Some(exe) = baseline {
        println!(
            "baseline odometry, {} (--baseline-odometry):",
            exe.display()
        );
        let hop = print_one_hop("baseline", "pose publish", &baseline_odometry);
        print_work_by_fix(&baseline_odometry);
        println!(
            "one hop, baseline odometry / bare pair: p50 {:.2}, p99 {:.2}",
            hop.p50 / bare_hop.p50,
            hop.p99 / bare_hop.p99
        );
    }
    if early_relay {
        println!("bare pair with the odometry's early wakeup, 1 ms (--early-relay):");
        let hop = print_one_hop("early relay", "publish", &early_bare);
        println!(
            "one hop, odometry / bare pair with early wakeup: p50 {:.2}, p99 {:.2}",
            odometry_hop.p50 / hop.p50,
            odometry_hop.p99 / hop.p99
        );
    }
    println!(
        "one hop, odometry / bare pair: p50 {:.2}, p99 {:.2}, p99.9 {:.2}",
        odometry_hop.p50 / bare_hop.p50,
        odometry_hop.p99 / bare_hop.p99,
        odometry_hop.p999 / bare_hop.p999
    );
    let mut consumers = vec![("bare pair", &bare), ("odometry", &odometry)];
    if early_relay {
        consumers.push(("early relay", &early_bare));
    }
    if baseline.is_some() {
        consumers.push(("baseline", &baseline_odometry));
    }
    print_p99_by_window(per_phase, &consumers);
    let verdict = |ok: bool| if ok { "met" } else { "MISSED" };
    println!(
        "goals (one hop, bridge publish -> pose publish): p50 <= 1.5 x bare pair: {}; p99 <= 100 us: {}",
        verdict(odometry_hop.p50 <= 1.5 * bare_hop.p50),
        verdict(odometry_hop.p99 <= 100.0)
    );
}
