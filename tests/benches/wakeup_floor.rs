//! The machine's floor under the sample-to-pose latency: how long one blocking
//! wakeup between two processes takes here, with nothing else done.
//!
//! The parent stamps the wall clock and sends a sample every 10 ms; a child
//! process blocked in its wait stamps the wall clock once the wait returned and
//! it has the sample. Four mechanisms, taking turns (four each):
//! - **socket**: a Unix datagram socket, the child blocked in `recv` (the
//!   kernel path under iceoryx2's default event, without iceoryx2);
//! - **iceoryx2 WaitSet**: iceoryx2 publish-subscribe plus its event service,
//!   the child in a WaitSet on the listener: the wakeup of `odometry serve` and
//!   of `graph_latency`'s bare pair;
//! - **iceoryx2 listener**: the same iceoryx2 services, the child blocked in
//!   the listener's own `timed_wait` (100 ms timeout) instead of a
//!   WaitSet: one topic's event and a timeout, no reactor;
//! - **iceoryx2 semaphore**: the same with an event service whose event is a
//!   semaphore in shared memory (a futex), the child in the listener's
//!   `blocking_wait`. A WaitSet cannot wait on it (no file descriptor), so a
//!   service waking on more than one topic, or on a timer, cannot use it.
//!
//! `cargo bench -p integration-tests --bench wakeup_floor [-- SAMPLES] [--cpu-latency-zero]`
//! (default 4000 samples per mechanism, the first 100 of each turn skipped).

use core::fmt::Debug;
use iceoryx2::prelude::*;
use iceoryx2_bb_elementary_traits::testing::abandonable::Abandonable;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
use iceoryx2_cal::shm_allocator::bump_allocator::BumpAllocator;
use iceoryx2_cal::shm_allocator::pool_allocator::PoolAllocator;
use iceoryx2_cal::{
    arc_sync_policy, bag, dynamic_storage, event, hash, monitoring, reactor,
    resizable_shared_memory, serialize, shared_memory, static_storage, zero_copy_connection,
};
use integration_tests::latency::{quantile, CpuLatencyZero};
use std::io::BufRead;
use std::os::unix::net::UnixDatagram;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const PERIOD: Duration = Duration::from_millis(10);
const WARMUP: usize = 100;
/// The sample that tells the child to stop (a real stamp is never 0).
const STOP: u64 = 0;

/// iceoryx2's inter-process service with one change: the event is a
/// semaphore in shared memory instead of a Unix datagram socket.
#[derive(Debug, Clone)]
struct IpcSemaphoreEvent {}

impl iceoryx2::service::Service for IpcSemaphoreEvent {
    type StaticStorage = static_storage::recommended::Ipc;
    type ConfigSerializer = serialize::recommended::Recommended;
    type PersistentDynamicStorage<T: Debug + Send + Sync + ZeroCopySend + 'static> =
        dynamic_storage::recommended::PersistentIpc<T>;
    type Bag = bag::recommended::Recommended;
    type DynamicStorage<T: Debug + Send + Sync + ZeroCopySend + 'static> =
        dynamic_storage::recommended::Ipc<T>;
    type ServiceNameHasher = hash::recommended::Recommended;
    type SharedMemory = shared_memory::recommended::Ipc<PoolAllocator>;
    type ResizableSharedMemory = resizable_shared_memory::recommended::Ipc<PoolAllocator>;
    type Connection = zero_copy_connection::recommended::Ipc;
    type Event = event::SemaphoreShmCountingBitSet;
    type Monitoring = monitoring::recommended::Ipc;
    type Reactor = reactor::recommended::Ipc;
    type ArcThreadSafetyPolicy<T: Send + Debug + Abandonable> =
        arc_sync_policy::single_threaded::SingleThreaded<T>;
    type BlackboardMgmt<KeyType: Send + Sync + Debug + ZeroCopySend + 'static> =
        dynamic_storage::recommended::Ipc<KeyType>;
    type BlackboardPayload = shared_memory::recommended::Ipc<BumpAllocator>;
    type UniqueId = iceoryx2::unique_id_generator::unique_system_id::UniqueSystemId;
}

impl iceoryx2::service::internal::ServiceInternal<IpcSemaphoreEvent> for IpcSemaphoreEvent {}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Mechanism {
    Socket,
    WaitSet,
    Listener,
    Semaphore,
}

impl Mechanism {
    const ALL: [Mechanism; 4] = [
        Mechanism::Socket,
        Mechanism::WaitSet,
        Mechanism::Listener,
        Mechanism::Semaphore,
    ];

    fn arg(self) -> &'static str {
        match self {
            Mechanism::Socket => "socket",
            Mechanism::WaitSet => "waitset",
            Mechanism::Listener => "listener",
            Mechanism::Semaphore => "semaphore",
        }
    }

    fn label(self) -> &'static str {
        match self {
            Mechanism::Socket => "Unix datagram socket, blocking recv",
            Mechanism::WaitSet => "iceoryx2 (socket event), WaitSet",
            Mechanism::Listener => "iceoryx2 (socket event), timed_wait",
            Mechanism::Semaphore => "iceoryx2 (semaphore event), blocking_wait",
        }
    }

    fn from_arg(arg: &str) -> Mechanism {
        Mechanism::ALL
            .into_iter()
            .find(|m| m.arg() == arg)
            .unwrap_or_else(|| panic!("unknown mechanism {arg}"))
    }
}

fn wall_ns() -> u64 {
    let since = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .expect("clock after 1970");
    u64::try_from(since.as_nanos()).expect("fits in u64")
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--child") {
        let kind = Mechanism::from_arg(&args[i + 1]);
        child(kind, &args[i + 2], Path::new(&args[i + 3]));
        return;
    }
    let samples: usize = args
        .iter()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(4000);
    let cpu_latency_zero = args.iter().any(|a| a == "--cpu-latency-zero");
    let _pm_qos = cpu_latency_zero.then(|| {
        CpuLatencyZero::hold()
            .expect("--cpu-latency-zero needs write access to /dev/cpu_dma_latency (root)")
    });
    let dir = tempfile::tempdir().expect("tempdir");
    let rounds = 4;
    let per_turn = samples / rounds;
    let mut pooled: Vec<Vec<f64>> = vec![Vec::new(); Mechanism::ALL.len()];
    for round in 0..rounds {
        for (k, kind) in Mechanism::ALL.into_iter().enumerate() {
            let name = format!("wheelcal-bench/wakeup-floor/{}/{round}", std::process::id());
            let out = dir.path().join(format!("{}-{round}.txt", kind.arg()));
            let mut latencies = turn(kind, &name, &out, dir.path(), per_turn);
            latencies.drain(..WARMUP.min(latencies.len()));
            pooled[k].extend(latencies);
        }
    }
    println!(
        "one blocking wakeup between two processes, a sample every {} ms, {rounds} turns of {per_turn} \
         (first {WARMUP} skipped), PM QoS CPU latency request: {}; microseconds:",
        PERIOD.as_millis(),
        if cpu_latency_zero { "0" } else { "none (default)" }
    );
    println!(
        "{:<44} {:>6} {:>8} {:>8} {:>8} {:>8}",
        "", "n", "p50", "p99", "p99.9", "max"
    );
    for (kind, mut l) in Mechanism::ALL.into_iter().zip(pooled) {
        l.sort_by(f64::total_cmp);
        println!(
            "{:<44} {:>6} {:>8.1} {:>8.1} {:>8.1} {:>8.1}",
            kind.label(),
            l.len(),
            quantile(&l, 0.5),
            quantile(&l, 0.99),
            quantile(&l, 0.999),
            l.last().copied().unwrap_or(f64::NAN)
        );
    }
}

/// One turn: start the child, send `n` stamped samples, collect its latencies (µs).
fn turn(kind: Mechanism, name: &str, out: &Path, dir: &Path, n: usize) -> Vec<f64> {
    let socket_path = dir.join(format!("{}.sock", kind.arg()));
    let _ = std::fs::remove_file(&socket_path);
    let target = match kind {
        Mechanism::Socket => socket_path.to_str().expect("utf-8").to_string(),
        _ => name.to_string(),
    };
    let exe = std::env::current_exe().expect("exe");
    let mut child = Command::new(exe)
        .args(["--child", kind.arg(), &target])
        .arg(out)
        .stdout(Stdio::piped())
        .spawn()
        .expect("spawn child");
    let send: Box<dyn FnMut(u64)> = match kind {
        Mechanism::Socket => {
            wait_ready(&mut child);
            let s = UnixDatagram::unbound().expect("socket");
            Box::new(move |v| {
                s.send_to(&v.to_ne_bytes(), &socket_path).expect("send");
            })
        }
        Mechanism::WaitSet | Mechanism::Listener => {
            iceoryx2_sender::<ipc::Service>(name, &mut child)
        }
        Mechanism::Semaphore => iceoryx2_sender::<IpcSemaphoreEvent>(name, &mut child),
    };
    let mut send = send;
    let start = Instant::now();
    for i in 0..n {
        let due = PERIOD * (i as u32 + 1);
        if let Some(wait) = due.checked_sub(start.elapsed()) {
            std::thread::sleep(wait);
        }
        send(wall_ns());
    }
    send(STOP);
    // The child writes its latencies and exits; a lost sample must not hang the bench.
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        if child.try_wait().expect("wait child").is_some() {
            break;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{} child did not finish", kind.arg());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    std::fs::read_to_string(out)
        .expect("child output")
        .lines()
        .map(|l| l.parse::<f64>().expect("a number") / 1e3)
        .collect()
}

fn wait_ready(child: &mut Child) {
    let stdout = child.stdout.take().expect("child stdout");
    let mut line = String::new();
    std::io::BufReader::new(stdout)
        .read_line(&mut line)
        .expect("child ready line");
    assert_eq!(line.trim(), "ready");
    std::thread::sleep(Duration::from_millis(200));
}

/// The parent's iceoryx2 publisher and notifier on `name`, once the child is ready.
fn iceoryx2_sender<S: iceoryx2::service::Service + 'static>(
    name: &str,
    child: &mut Child,
) -> Box<dyn FnMut(u64)> {
    wait_ready(child);
    let (node, pubsub, event) = open::<S>(name);
    let publisher = pubsub.publisher_builder().create().expect("publisher");
    let notifier = event.notifier_builder().create().expect("notifier");
    std::thread::sleep(Duration::from_millis(200));
    Box::new(move |v| {
        let _keep = (&node, &pubsub, &event);
        let sample = publisher.loan_uninit().expect("loan").write_payload(v);
        sample.send().expect("send");
        notifier.notify().expect("notify");
    })
}

/// The child: wait blockingly, stamp, until the stop sample; write the
/// latencies (ns, one per line) to `out`.
fn child(kind: Mechanism, target: &str, out: &Path) {
    let mut latencies: Vec<u64> = Vec::new();
    let mut record = |stamp: u64| -> bool {
        if stamp == STOP {
            return false;
        }
        latencies.push(wall_ns().saturating_sub(stamp));
        true
    };
    match kind {
        Mechanism::Socket => {
            let socket = UnixDatagram::bind(target).expect("bind");
            println!("ready");
            let mut buf = [0u8; 8];
            loop {
                socket.recv(&mut buf).expect("recv");
                if !record(u64::from_ne_bytes(buf)) {
                    break;
                }
            }
        }
        Mechanism::WaitSet => {
            let (node, pubsub, event) = open::<ipc::Service>(target);
            let subscriber = pubsub.subscriber_builder().create().expect("subscriber");
            let listener = event.listener_builder().create().expect("listener");
            let waitset = WaitSetBuilder::new()
                .create::<ipc::Service>()
                .expect("waitset");
            let _guard = waitset.attach_notification(&listener).expect("attach");
            println!("ready");
            'outer: loop {
                waitset
                    .wait_and_process_once(|_| CallbackProgression::Continue)
                    .expect("wait");
                while let Some(s) = subscriber.receive().expect("receive") {
                    if !record(*s) {
                        break 'outer;
                    }
                }
                listener.try_wait(|_| {}).expect("take events");
            }
            drop(node);
        }
        Mechanism::Listener => {
            let (node, pubsub, event) = open::<ipc::Service>(target);
            let subscriber = pubsub.subscriber_builder().create().expect("subscriber");
            let listener = event.listener_builder().create().expect("listener");
            println!("ready");
            'outer: loop {
                // A timeout, as a service with a tick would wait.
                listener
                    .timed_wait(|_| {}, Duration::from_millis(100))
                    .expect("wait");
                while let Some(s) = subscriber.receive().expect("receive") {
                    if !record(*s) {
                        break 'outer;
                    }
                }
            }
            drop(node);
        }
        Mechanism::Semaphore => {
            let (node, pubsub, event) = open::<IpcSemaphoreEvent>(target);
            let subscriber = pubsub.subscriber_builder().create().expect("subscriber");
            let listener = event.listener_builder().create().expect("listener");
            println!("ready");
            'outer: loop {
                listener.blocking_wait(|_| {}).expect("wait");
                while let Some(s) = subscriber.receive().expect("receive") {
                    if !record(*s) {
                        break 'outer;
                    }
                }
            }
            drop(node);
        }
    }
    let text: String = latencies.iter().map(|l| format!("{l}\n")).collect();
    std::fs::write(PathBuf::from(out), text).expect("write latencies");
}

type Opened<S> = (
    Node<S>,
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<S, u64, ()>,
    iceoryx2::service::port_factory::event::PortFactory<S>,
);

fn open<S: iceoryx2::service::Service>(name: &str) -> Opened<S> {
    let node = NodeBuilder::new().create::<S>().expect("node");
    let service_name: ServiceName = name.try_into().expect("service name");
    let pubsub = node
        .service_builder(&service_name)
        .publish_subscribe::<u64>()
        .open_or_create()
        .expect("pubsub");
    let event = node
        .service_builder(&service_name)
        .event()
        .open_or_create()
        .expect("event");
    (node, pubsub, event)
}
