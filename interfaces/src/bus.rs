//! iceoryx2 plumbing shared by every service: one place that decides how a
//! topic is opened, so that every process opens it with the same settings.
//!
//! # Conventions
//!
//! - Every publish-subscribe service `NAME` has an **event service of the same
//!   `NAME`**. A publisher notifies it after every sample ([`EVENT_SAMPLE`]) and
//!   once more when its stream ends ([`EVENT_END_OF_STREAM`]); iceoryx2 itself
//!   emits [`EVENT_PUBLISHER_DROPPED`] when a notifier is dropped and
//!   [`EVENT_PUBLISHER_DEAD`] when a dead one is cleaned up. Subscribers attach
//!   [`TopicSubscriber::listener`] to a `WaitSet` and block: no polling.
//! - Streams ([`Delivery::Lossless`]: sensors and poses) do not overflow: the
//!   service is created without safe overflow and the publisher waits while a
//!   subscriber's buffer is full (backpressure), so nothing is lost at replay
//!   speed. A subscriber that does not take a sample for [`BusSettings::stall_timeout`]
//!   loses that sample (with a warning) rather than blocking the whole graph,
//!   and every later one at once while its buffer stays full (a stopped
//!   process costs the publisher one stall timeout, not one per sample; the
//!   others lose nothing); a dead subscriber's resources are cleaned up while
//!   the publisher waits. The pose stream is the graph's output, which a
//!   stopped reader (a viewer under SIGSTOP, a debugger) must not hold back:
//!   its publisher waits at most [`BusSettings::pose_budget`] (default
//!   [`DEFAULT_POSE_BUDGET`]) on a full subscriber, then drops that
//!   subscriber's samples while its buffer stays full, with a warning and
//!   the counters of [`TopicPublisher::stalls`]. The sensor streams keep
//!   lossless delivery at `--max` replay speed (a calibrator busy with a
//!   fit is waited on); paced (live) they are opened with
//!   [`Bus::live_publisher`], which waits at most
//!   [`BusSettings::live_budget`] (default [`DEFAULT_LIVE_BUDGET`]): a
//!   paced reader whose buffer is full is already seconds late, and a
//!   stopped one must not hold the odometry's inputs back.
//! - The estimate ([`Delivery::Latest`]) keeps a history of one, so a subscriber
//!   that starts late gets the latest accepted estimate. The publisher delivers
//!   history when it updates its connections: call
//!   [`TopicPublisher::update_connections`] now and then (e.g. on a WaitSet interval).
//! - Every process of one graph uses the same iceoryx2 prefix and root path
//!   ([`BusSettings`], from `WHEELCAL_IOX_PREFIX` / `WHEELCAL_IOX_ROOT`), so that
//!   several graphs (tests) run side by side without seeing each other.
//! - A subscriber only takes part in backpressure once it has *attached* to
//!   a publisher's connection, which happens when it receives or updates its
//!   connections after the publisher connected. Until then the connection
//!   buffers up to its size and drops the rest. So a publisher that must not
//!   lose anything waits for its subscribers, calls [`TopicPublisher::announce`]
//!   (subscribers wake and attach in [`TopicSubscriber::take_events`]) and
//!   gives them a moment before it floods them.
//! - Sequence numbers: [`TopicPublisher::publish`] numbers every sample from 0;
//!   [`TopicSubscriber`] counts the gaps per publisher ([`TopicSubscriber::lost`])
//!   after the first sample it received from it: what a publisher sent
//!   before a (re)started subscriber connected was never owed to it.
//! - Files: [`Bus::open`] takes the graph's shared-memory files under its
//!   prefix away from other users (iceoryx2 makes its per-prefix management
//!   segment writable by all) and refuses to join a graph whose management
//!   segment another user owns (planted to stop it); an isolated root
//!   directory is created readable by the owner only.
//! - Two iceoryx2 defaults are narrowed because every receive or wait pays for
//!   their size: a subscriber keeps [`EXPIRED_CONNECTIONS`] connections of
//!   publishers gone with samples unread (not 128), and event ids go up to
//!   [`EVENT_ID_MAX`] (not 255). The first took the odometry's path from a
//!   wakeup to its pose from about 10 k to 7 k instructions, the second 2.2 k
//!   off taking a topic's notifications (BENCHMARKS.md).
//!
//! # Termination
//!
//! Creating a [`Bus`] installs iceoryx2's SIGINT/SIGTERM handler: the signals no
//! longer kill the process, every loop must check [`shutdown_requested`] (or
//! the result of a `WaitSet` run, see [`stop_requested_by`]). A signal may be
//! delivered to any thread; a main loop blocked in a WaitSet should attach an
//! interval (e.g. 100 ms) so that it notices a signal taken by another thread.

use crate::wire::{
    CircumferenceEstimate, GnssFix, Header, Heading, Imu, Pose, WheelRotations, ESTIMATE_SERVICE,
    GNSS_SERVICE, HEADING_SERVICE, IMU_SERVICE, POSE_SERVICE, WHEELS_SERVICE,
};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::port::{BackpressureAction, BackpressureInfo};
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;
use iceoryx2::waitset::{WaitSetRunError, WaitSetRunResult};
use std::cell::RefCell;
use std::fmt::Debug;
use std::path::{Path as StdPath, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// The iceoryx2 service flavour used by every process (inter-process, single-threaded ports).
pub type Ipc = ipc::Service;

/// Environment variable holding the iceoryx2 prefix of the graph.
pub const ENV_PREFIX: &str = "WHEELCAL_IOX_PREFIX";
/// Environment variable holding the iceoryx2 root path of the graph.
pub const ENV_ROOT: &str = "WHEELCAL_IOX_ROOT";
/// Environment variable holding the pose stream's wait budget, ms
/// ([`BusSettings::pose_budget`]).
pub const ENV_POSE_BUDGET_MS: &str = "WHEELCAL_POSE_BUDGET_MS";
/// How long a pose publisher waits on a full subscriber by default: a few
/// pose periods at 100 Hz, far below what a stopped reader would cost the
/// graph's output with the sensor streams' stall timeout.
pub const DEFAULT_POSE_BUDGET: Duration = Duration::from_millis(30);
/// Environment variable holding the wait budget of live (paced) sensor
/// publishers, ms ([`BusSettings::live_budget`]).
pub const ENV_LIVE_BUDGET_MS: &str = "WHEELCAL_LIVE_BUDGET_MS";
/// How long a live sensor publisher waits on a full subscriber by default. A
/// paced stream's full buffer ([`STREAM_BUFFER`] samples) means its reader is
/// already seconds behind real time: waiting longer only makes the data late
/// for every other reader (the odometry's poses), so a live publisher gives
/// up after a few sample periods and drops that reader's samples instead.
pub const DEFAULT_LIVE_BUDGET: Duration = Duration::from_millis(100);

/// Event id: a new sample was published.
pub const EVENT_SAMPLE: usize = 1;
/// Event id: the publisher has published its last sample (end of a replay).
pub const EVENT_END_OF_STREAM: usize = 2;
/// Event id emitted by iceoryx2 when a publisher's notifier is dropped.
pub const EVENT_PUBLISHER_DROPPED: usize = 3;
/// Event id emitted by iceoryx2 when a dead publisher's notifier is cleaned up.
pub const EVENT_PUBLISHER_DEAD: usize = 4;
/// Event id: a publisher connected; subscribers attach to it (see
/// [`TopicPublisher::announce`]).
pub const EVENT_CONNECT: usize = 5;
/// The largest event id a topic's event service takes. A listener's wait
/// drains one counter per possible id: iceoryx2's default of 255 made every
/// `take_notifications` walk 256 counters (2.5 k instructions).
pub const EVENT_ID_MAX: usize = 7;
const _: () = assert!(EVENT_CONNECT <= EVENT_ID_MAX && EVENT_PUBLISHER_DEAD <= EVENT_ID_MAX);

/// Subscriber buffer of the lossless streams, samples. At 100 Hz this is 10 s of
/// data: a paced replay never waits, `--max` waits on the slowest subscriber.
pub const STREAM_BUFFER: usize = 1024;
/// Subscriber buffer of the estimate topic.
pub const LATEST_BUFFER: usize = 4;
/// Maximum subscribers per topic (calibrator, odometry, recorder, viewers, tests).
pub const MAX_SUBSCRIBERS: usize = 8;
/// Maximum publishers per topic (2: a restarted publisher beside a dead one not yet cleaned up).
pub const MAX_PUBLISHERS: usize = 2;

/// Connections of publishers gone with samples unread that a subscriber
/// keeps (to read those samples) per topic; see [`BusSettings::iceoryx_config`].
pub const EXPIRED_CONNECTIONS: usize = 4 * MAX_PUBLISHERS;

/// Maximum nodes per service.
pub const MAX_NODES: usize = 32;

/// How a topic delivers its samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Delivery {
    /// Every sample reaches every connected subscriber; the publisher waits
    /// (backpressure) while a subscriber's buffer is full.
    Lossless {
        /// Subscriber buffer size, samples.
        buffer: usize,
    },
    /// Only the latest matters: the buffer overflows (oldest dropped) and a
    /// late subscriber receives the last `history` samples.
    Latest {
        /// Subscriber buffer size, samples.
        buffer: usize,
        /// Samples kept for late subscribers.
        history: usize,
    },
}

/// A wire type with its service and delivery.
pub trait Topic: ZeroCopySend + bytemuck::Pod + Copy + Debug + Default + 'static {
    /// The service name.
    const SERVICE: &'static str;
    /// The versioned type name iceoryx2 matches publishers and subscribers
    /// by (the type's `#[type_name]`; the `/vN` is its layout version).
    const TYPE_NAME: &'static str;
    /// How samples are delivered.
    const DELIVERY: Delivery;
    /// The common header.
    fn header(&self) -> &Header;
    /// The common header, mutable.
    fn header_mut(&mut self) -> &mut Header;
}

macro_rules! topic {
    ($ty:ty, $service:expr, $type_name:expr, $delivery:expr) => {
        impl Topic for $ty {
            const SERVICE: &'static str = $service;
            const TYPE_NAME: &'static str = $type_name;
            const DELIVERY: Delivery = $delivery;
            fn header(&self) -> &Header {
                &self.header
            }
            fn header_mut(&mut self) -> &mut Header {
                &mut self.header
            }
        }
    };
}

const STREAM: Delivery = Delivery::Lossless {
    buffer: STREAM_BUFFER,
};
topic!(
    WheelRotations,
    WHEELS_SERVICE,
    "wheelcal/WheelRotations/v1",
    STREAM
);
topic!(GnssFix, GNSS_SERVICE, "wheelcal/GnssFix/v1", STREAM);
topic!(Imu, IMU_SERVICE, "wheelcal/Imu/v1", STREAM);
topic!(Heading, HEADING_SERVICE, "wheelcal/Heading/v1", STREAM);
topic!(Pose, POSE_SERVICE, "wheelcal/Pose/v1", STREAM);
topic!(
    CircumferenceEstimate,
    ESTIMATE_SERVICE,
    "wheelcal/CircumferenceEstimate/v1",
    Delivery::Latest {
        buffer: LATEST_BUFFER,
        history: 1
    }
);

/// Errors of the bus helpers.
#[derive(Debug, thiserror::Error)]
pub enum BusError {
    /// The prefix or root path is not usable by iceoryx2.
    #[error("invalid iceoryx2 setting {setting} = {value:?}: {detail}")]
    InvalidSetting {
        /// `WHEELCAL_IOX_PREFIX` or `WHEELCAL_IOX_ROOT` (or the node name).
        setting: &'static str,
        /// The value given.
        value: String,
        /// What iceoryx2 said.
        detail: String,
    },
    /// The root directory could not be created.
    #[error("cannot create iceoryx2 root directory {path}: {source}")]
    RootDir {
        /// The directory.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The root directory belongs to another user and others may write in it.
    #[error(
        "iceoryx2 root directory {path} belongs to uid {owner} and is writable by others \
         (mode {mode:o}): another user could plant, replace or remove the graph's files; run \
         the graph with a root directory of its own user (WHEELCAL_IOX_ROOT) or remove it"
    )]
    ForeignRoot {
        /// The directory.
        path: PathBuf,
        /// Its owner's uid.
        owner: u32,
        /// Its permission bits.
        mode: u32,
    },
    /// Node creation failed.
    #[error("cannot create iceoryx2 node {name:?}: {detail}")]
    Node {
        /// Node name.
        name: String,
        /// What iceoryx2 said.
        detail: String,
    },
    /// A service, port or waitset operation failed.
    #[error("iceoryx2 service {service}: {action} failed: {detail}")]
    Service {
        /// Service name.
        service: String,
        /// What was attempted (open, publish, receive, ...).
        action: &'static str,
        /// What iceoryx2 said.
        detail: String,
    },
    /// Waiting for subscribers ended by a termination request.
    #[error("interrupted by a termination request")]
    Interrupted,
    /// The graph's management segment belongs to another user.
    #[error(
        "{path} belongs to uid {owner}, not to this user: another user created the graph's \
         management segment (it could stop or corrupt the graph); run the graph with its own \
         prefix and root (README, \"Deploying in a vehicle\") or remove the file"
    )]
    ForeignSegment {
        /// The file in /dev/shm.
        path: PathBuf,
        /// Its owner's uid.
        owner: u32,
    },
    /// Waiting for subscribers timed out.
    #[error("timed out after {waited_s:.1} s waiting for subscribers: {detail}")]
    Timeout {
        /// Seconds waited.
        waited_s: f64,
        /// Which topics missed how many subscribers.
        detail: String,
    },
}

fn service_err(service: &str, action: &'static str, e: impl std::fmt::Debug) -> BusError {
    BusError::Service {
        service: service.to_string(),
        action,
        detail: format!("{e:?}"),
    }
}

// ---------------------------------------------------------------------------
// Termination

static SHUTDOWN: AtomicBool = AtomicBool::new(false);

/// True once SIGINT or SIGTERM was received (or [`request_shutdown`] called).
///
/// iceoryx2 records the last signal and resets it when asked; this latches it,
/// so every caller in the process sees the request.
pub fn shutdown_requested() -> bool {
    if iceoryx2_bb_posix::signal::SignalHandler::termination_requested() {
        SHUTDOWN.store(true, Ordering::SeqCst);
    }
    SHUTDOWN.load(Ordering::SeqCst)
}

/// Ask every loop of this process to stop.
pub fn request_shutdown() {
    SHUTDOWN.store(true, Ordering::SeqCst);
}

// ---------------------------------------------------------------------------
// The service loop's WaitSet: set up the one way every service does. A loop
// creates it with [`Bus::waitset`], attaches the listeners of the topics that
// wake it ([`wake_on`]) and a tick ([`tick_every`]) that notices signals and
// stale inputs, then calls [`wait_once`] per round.

/// Attach the listener of a topic (`what` names it in errors) to a service
/// loop's WaitSet: every sample published on the topic wakes the loop.
pub fn wake_on<'w, 'a>(
    waitset: &'w WaitSet<Ipc>,
    what: &'static str,
    listener: &'a Listener<Ipc>,
) -> Result<WaitSetGuard<'w, 'a, Ipc>, BusError> {
    waitset
        .attach_notification(listener)
        .map_err(|e| service_err("waitset", what, e))
}

/// Attach the loop's tick: the WaitSet wakes at least every `every`.
pub fn tick_every(
    waitset: &WaitSet<Ipc>,
    every: Duration,
) -> Result<WaitSetGuard<'_, 'static, Ipc>, BusError> {
    waitset
        .attach_interval(every)
        .map_err(|e| service_err("waitset", "attach interval", e))
}

/// One round of `waitset`: block until an attachment fires, or at most
/// `timeout` (`Some(Duration::ZERO)` when a sample is known to be waiting, its
/// notification possibly taken already: handle only what is ready now).
/// Returns what [`WaitSet::wait_and_process_once`] returns.
pub fn wait_once<F: FnMut(WaitSetAttachmentId<Ipc>) -> CallbackProgression>(
    waitset: &WaitSet<Ipc>,
    timeout: Option<Duration>,
    on_event: F,
) -> Result<WaitSetRunResult, BusError> {
    match timeout {
        Some(t) => waitset.wait_and_process_once_with_timeout(on_event, t),
        None => waitset.wait_and_process_once(on_event),
    }
    .map_err(|e: WaitSetRunError| service_err("waitset", "wait", e))
}

/// True when a WaitSet run result means the loop must end (a signal, or a
/// callback that asked to stop); latches signals for [`shutdown_requested`].
pub fn stop_requested_by(result: WaitSetRunResult) -> bool {
    match result {
        WaitSetRunResult::TerminationRequest | WaitSetRunResult::Interrupt => {
            request_shutdown();
            true
        }
        WaitSetRunResult::StopRequest => true,
        WaitSetRunResult::AllEventsHandled => shutdown_requested(),
    }
}

/// Sleep up to `duration` in short steps, returning early (false) on a
/// termination request; true when the whole time passed.
pub fn sleep_unless_shutdown(duration: Duration) -> bool {
    let end = Instant::now() + duration;
    loop {
        if shutdown_requested() {
            return false;
        }
        let now = Instant::now();
        if now >= end {
            return true;
        }
        std::thread::sleep((end - now).min(Duration::from_millis(20)));
    }
}

// ---------------------------------------------------------------------------
// Settings and node

/// Where a graph's iceoryx2 resources live. Every process of one graph must
/// use the same settings; children inherit them through [`BusSettings::env`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BusSettings {
    /// iceoryx2 prefix of every shared-memory object and file (default `iox2_`).
    pub prefix: Option<String>,
    /// iceoryx2 root path for service and node files (default `/tmp/iceoryx2/`).
    pub root: Option<PathBuf>,
    /// How long a publisher waits on one full subscriber before it drops the
    /// sample for that subscriber (default 10 s).
    pub stall_timeout: Option<Duration>,
    /// How long a pose publisher waits on one full subscriber before it
    /// drops the sample for that subscriber (default [`DEFAULT_POSE_BUDGET`],
    /// never more than the stall timeout).
    pub pose_budget: Option<Duration>,
    /// How long a live (paced) sensor publisher ([`Bus::live_publisher`])
    /// waits on one full subscriber (default [`DEFAULT_LIVE_BUDGET`], never
    /// more than the stall timeout).
    pub live_budget: Option<Duration>,
}

impl BusSettings {
    /// Settings from `WHEELCAL_IOX_PREFIX` and `WHEELCAL_IOX_ROOT` (unset or
    /// empty = iceoryx2's defaults).
    pub fn from_env() -> BusSettings {
        let var = |k: &str| std::env::var(k).ok().filter(|v| !v.is_empty());
        BusSettings {
            prefix: var(ENV_PREFIX),
            root: var(ENV_ROOT).map(PathBuf::from),
            stall_timeout: None,
            pose_budget: var(ENV_POSE_BUDGET_MS)
                .and_then(|v| v.parse::<u64>().ok())
                .map(Duration::from_millis),
            live_budget: var(ENV_LIVE_BUDGET_MS)
                .and_then(|v| v.parse::<u64>().ok())
                .map(Duration::from_millis),
        }
    }

    /// Settings isolated from every other graph: prefix `wc<tag>_<pid>_<n>_`
    /// and a root directory of that name under `root_parent`.
    pub fn isolated(tag: &str, root_parent: &StdPath) -> BusSettings {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let tag: String = tag
            .chars()
            .filter(|c| c.is_ascii_alphanumeric())
            .take(16)
            .collect();
        let prefix = format!("wc{tag}_{}_{n}_", std::process::id());
        BusSettings {
            root: Some(root_parent.join(&prefix)),
            prefix: Some(prefix),
            stall_timeout: None,
            pose_budget: None,
            live_budget: None,
        }
    }

    /// The environment variables that hand these settings to a child process.
    pub fn env(&self) -> Vec<(&'static str, String)> {
        let mut out = Vec::new();
        if let Some(p) = &self.prefix {
            out.push((ENV_PREFIX, p.clone()));
        }
        if let Some(r) = &self.root {
            out.push((ENV_ROOT, r.display().to_string()));
        }
        out
    }

    /// The iceoryx2 configuration: iceoryx2's defaults with prefix and root
    /// replaced. No config file is read: every setting the graph depends on
    /// is set in code, so all processes agree whatever files a machine has.
    pub fn iceoryx_config(&self) -> Result<Config, BusError> {
        let mut config = Config::default();
        // A subscriber keeps the connections of publishers that went away
        // with samples still unread in a buffer of this many, and its every
        // receive walks the whole table of connections (this buffer plus the
        // publishers): iceoryx2's 128 made a receive walk 130 slots, most
        // of its instructions, on the path to every pose. A few publishers
        // of one topic gone with unread samples at once is plenty here.
        config
            .defaults
            .publish_subscribe
            .subscriber_expired_connection_buffer = EXPIRED_CONNECTIONS;
        if let Some(prefix) = &self.prefix {
            config.global.prefix =
                FileName::new(prefix.as_bytes()).map_err(|e| BusError::InvalidSetting {
                    setting: ENV_PREFIX,
                    value: prefix.clone(),
                    detail: format!("{e:?}"),
                })?;
        }
        if let Some(root) = &self.root {
            let text = root.display().to_string();
            let mut text_slash = text.clone();
            if !text_slash.ends_with('/') {
                text_slash.push('/');
            }
            let path = Path::new(text_slash.as_bytes()).map_err(|e| BusError::InvalidSetting {
                setting: ENV_ROOT,
                value: text.clone(),
                detail: format!("{e:?}"),
            })?;
            config.global.set_root_path(&path);
        }
        Ok(config)
    }

    /// Remove what a graph with these settings leaves behind once every one of
    /// its processes has exited: iceoryx2 keeps a tiny persistent management
    /// segment per prefix in `/dev/shm`, and the root directory. Does nothing
    /// for the default prefix (other graphs may share it). Returns the number
    /// of shared-memory files removed.
    pub fn remove_leftovers(&self) -> usize {
        let Some(prefix) = self
            .prefix
            .as_deref()
            .filter(|p| !p.is_empty() && *p != "iox2_")
        else {
            return 0;
        };
        let mut removed = 0;
        if let Ok(dir) = std::fs::read_dir("/dev/shm") {
            for entry in dir.flatten() {
                if entry.file_name().to_string_lossy().starts_with(prefix)
                    && std::fs::remove_file(entry.path()).is_ok()
                {
                    removed += 1;
                }
            }
        }
        if let Some(root) = &self.root {
            let _ = std::fs::remove_dir_all(root);
        }
        removed
    }

    /// Stall timeout in effect.
    pub fn stall_timeout(&self) -> Duration {
        self.stall_timeout.unwrap_or(Duration::from_secs(10))
    }

    /// How long a publisher of topic `T` waits on one full subscriber: the
    /// pose budget for the pose stream, the stall timeout for the others.
    pub fn wait_budget<T: Topic>(&self) -> Duration {
        if T::SERVICE == POSE_SERVICE {
            self.pose_budget
                .unwrap_or(DEFAULT_POSE_BUDGET)
                .min(self.stall_timeout())
        } else {
            self.stall_timeout()
        }
    }

    /// How long a live (paced) publisher of topic `T` waits on one full
    /// subscriber: the live budget, or the pose budget if that is shorter.
    pub fn live_wait_budget<T: Topic>(&self) -> Duration {
        self.live_budget
            .unwrap_or(DEFAULT_LIVE_BUDGET)
            .min(self.wait_budget::<T>())
    }
}

/// The publish-subscribe service of a topic and its event service.
type TopicServices<T> = (PubSubFactory<Ipc, T, ()>, EventFactory<Ipc>);

/// One process's connection to the graph: an iceoryx2 node with the graph's
/// settings. Open topics with [`Bus::publisher`] and [`Bus::subscriber`].
#[derive(Debug)]
pub struct Bus {
    node: Node<Ipc>,
    config: Config,
    settings: BusSettings,
}

impl Bus {
    /// Create a node named `name` with the given settings. Dead nodes of
    /// earlier (killed) processes are cleaned up on the way.
    pub fn open(settings: &BusSettings, name: &str) -> Result<Bus, BusError> {
        // Install the signal handler now, so that SIGTERM/SIGINT are caught
        // from here on and every loop sees them through `shutdown_requested`.
        let _ = shutdown_requested();
        let config = settings.iceoryx_config()?;
        if let Some(root) = &settings.root {
            use std::os::unix::fs::DirBuilderExt;
            std::fs::DirBuilder::new()
                .recursive(true)
                .mode(0o700)
                .create(root)
                .map_err(|source| BusError::RootDir {
                    path: root.clone(),
                    source,
                })?;
        }
        let root = settings.root.clone().unwrap_or_else(|| {
            PathBuf::from(String::from_utf8_lossy(config.global.root_path().as_bytes()).as_ref())
        });
        check_root_dir(&root)?;
        let node_name = NodeName::new(name).map_err(|e| BusError::InvalidSetting {
            setting: "node name",
            value: name.to_string(),
            detail: format!("{e:?}"),
        })?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .config(&config)
            .create::<Ipc>()
            .map_err(|e| BusError::Node {
                name: name.to_string(),
                detail: format!("{e:?}"),
            })?;
        keep_shm_private(settings.prefix.as_deref().unwrap_or(DEFAULT_PREFIX))?;
        Ok(Bus {
            node,
            config,
            settings: settings.clone(),
        })
    }

    /// [`Bus::open`] with [`BusSettings::from_env`].
    pub fn from_env(name: &str) -> Result<Bus, BusError> {
        Bus::open(&BusSettings::from_env(), name)
    }

    /// The iceoryx2 node.
    pub fn node(&self) -> &Node<Ipc> {
        &self.node
    }

    /// The iceoryx2 configuration of the node.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The settings the bus was opened with.
    pub fn settings(&self) -> &BusSettings {
        &self.settings
    }

    /// Remove the resources of dead nodes (processes killed without cleanup);
    /// returns how many were cleaned up.
    pub fn cleanup_dead_nodes(&self) -> usize {
        cleanup_dead_nodes(&self.config)
    }

    /// A WaitSet for this process's main loop.
    pub fn waitset(&self) -> Result<WaitSet<Ipc>, BusError> {
        WaitSetBuilder::new()
            .create::<Ipc>()
            .map_err(|e| service_err("waitset", "create", e))
    }

    fn open_services<T: Topic>(&self) -> Result<TopicServices<T>, BusError> {
        let name = ServiceName::new(T::SERVICE).map_err(|e| service_err(T::SERVICE, "name", e))?;
        let (overflow, buffer, history) = match T::DELIVERY {
            Delivery::Lossless { buffer } => (false, buffer, 0),
            Delivery::Latest { buffer, history } => (true, buffer, history),
        };
        // Two processes may create the same service at the same moment; the
        // loser sees a transient error and retries.
        let deadline = Instant::now() + Duration::from_secs(5);
        let pubsub = loop {
            let r = self
                .node
                .service_builder(&name)
                .publish_subscribe::<T>()
                .enable_safe_overflow(overflow)
                .subscriber_max_buffer_size(buffer)
                .history_size(history)
                .subscriber_max_borrowed_samples(2)
                .max_subscribers(MAX_SUBSCRIBERS)
                .max_publishers(MAX_PUBLISHERS)
                .max_nodes(MAX_NODES)
                .open_or_create();
            match r {
                Ok(s) => break s,
                Err(e) if Instant::now() < deadline => {
                    tracing::debug!(service = T::SERVICE, "open_or_create: {e:?}, retrying");
                    std::thread::sleep(Duration::from_millis(20));
                }
                Err(e) => return Err(service_err(T::SERVICE, "open publish-subscribe", e)),
            }
        };
        let event = loop {
            let r = self
                .node
                .service_builder(&name)
                .event()
                .max_notifiers(2 * MAX_PUBLISHERS)
                .max_listeners(2 * MAX_SUBSCRIBERS)
                .max_nodes(MAX_NODES)
                .event_id_max_value(EVENT_ID_MAX)
                .notifier_dropped_event(EventId::new(EVENT_PUBLISHER_DROPPED))
                .notifier_dead_event(EventId::new(EVENT_PUBLISHER_DEAD))
                .open_or_create();
            match r {
                Ok(s) => break s,
                Err(e) if Instant::now() < deadline => {
                    tracing::debug!(
                        service = T::SERVICE,
                        "event open_or_create: {e:?}, retrying"
                    );
                    std::thread::sleep(Duration::from_millis(20));
                }
                Err(e) => return Err(service_err(T::SERVICE, "open event", e)),
            }
        };
        Ok((pubsub, event))
    }

    /// Open topic `T` for publishing. A lossless stream waits on a full
    /// subscriber for [`BusSettings::wait_budget`]: the stall timeout for the
    /// sensor streams (lossless at `--max` replay speed), the pose budget for
    /// the poses.
    pub fn publisher<T: Topic>(&self) -> Result<TopicPublisher<T>, BusError> {
        self.publisher_waiting(self.settings.wait_budget::<T>())
    }

    /// Open topic `T` for publishing a live stream, paced in real time (or a
    /// multiple of it): a full subscriber is waited on for at most
    /// [`BusSettings::live_wait_budget`] (milliseconds), then loses its
    /// samples while its buffer stays full, with a warning and the counters
    /// of [`TopicPublisher::stalls`]. A stopped reader (SIGSTOP, a debugger)
    /// then costs the other readers one budget, not the stall timeout.
    pub fn live_publisher<T: Topic>(&self) -> Result<TopicPublisher<T>, BusError> {
        self.publisher_waiting(self.settings.live_wait_budget::<T>())
    }

    fn publisher_waiting<T: Topic>(&self, stall: Duration) -> Result<TopicPublisher<T>, BusError> {
        let (service, event) = self.open_services::<T>()?;
        let mut builder = service.publisher_builder().max_loaned_samples(2);
        let stalls = std::sync::Arc::new(StallCounters::default());
        if let Delivery::Lossless { .. } = T::DELIVERY {
            let config = self.config.clone();
            let last_cleanup_ms = AtomicU64::new(0);
            let memory = std::sync::Mutex::new(StallMemory::default());
            let counters = stalls.clone();
            builder = builder
                .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
                .set_backpressure_handler(move |info: &BackpressureInfo| {
                    backpressure(info, stall, &config, &last_cleanup_ms, &memory, &counters)
                });
        }
        let publisher = builder.create().map_err(|e| {
            use iceoryx2::service::port_factory::PortFactory as _;
            let in_use = service.dynamic_config().number_of_publishers();
            port_err(
                T::SERVICE,
                ("create publisher", "publisher"),
                e,
                in_use,
                MAX_PUBLISHERS,
            )
        })?;
        let notifier = event
            .notifier_builder()
            .default_event_id(EventId::new(EVENT_SAMPLE))
            .create()
            .map_err(|e| service_err(T::SERVICE, "create notifier", e))?;
        Ok(TopicPublisher {
            service,
            _event: event,
            publisher,
            notifier,
            next_seq: 0,
            notify_failed: false,
            stalls,
        })
    }

    /// Open topic `T` for subscribing (with the history, for [`Delivery::Latest`]).
    pub fn subscriber<T: Topic>(&self) -> Result<TopicSubscriber<T>, BusError> {
        let (service, event) = self.open_services::<T>()?;
        let builder = match T::DELIVERY {
            Delivery::Lossless { buffer } => service.subscriber_builder().buffer_size(buffer),
            Delivery::Latest { buffer, history } => service
                .subscriber_builder()
                .buffer_size(buffer)
                .history_request(history),
        };
        let subscriber = builder.create().map_err(|e| {
            use iceoryx2::service::port_factory::PortFactory as _;
            let in_use = service.dynamic_config().number_of_subscribers();
            port_err(
                T::SERVICE,
                ("create subscriber", "subscriber"),
                e,
                in_use,
                MAX_SUBSCRIBERS,
            )
        })?;
        let listener = event
            .listener_builder()
            .create()
            .map_err(|e| service_err(T::SERVICE, "create listener", e))?;
        Ok(TopicSubscriber {
            _service: service,
            _event: event,
            subscriber,
            listener,
            seq: RefCell::new(SeqTracker::default()),
        })
    }
}

/// A port of `service` could not be created; the error says how many of
/// its `max` slots of that `kind` are in use, and what keeps others out.
fn port_err(
    service: &str,
    (action, kind): (&'static str, &str),
    e: impl Debug,
    in_use: usize,
    max: usize,
) -> BusError {
    BusError::Service {
        service: service.to_string(),
        action,
        detail: format!(
            "{e:?} ({in_use} of {max} {kind} slots in use: another process of this user \
             holds them; a graph under its own user, prefix and root keeps others out, \
             README \"Deploying in a vehicle\")"
        ),
    }
}

/// iceoryx2's prefix when none is set.
const DEFAULT_PREFIX: &str = "iox2_";

/// Take the group and others' write (and read) permission off this user's
/// shared-memory files of the graph with `prefix` (iceoryx2 creates its
/// per-prefix management segment writable by everyone), and refuse a
/// management segment of that prefix owned by another user: it was planted,
/// and joining it would let that user stop or corrupt the graph.
fn keep_shm_private(prefix: &str) -> Result<(), BusError> {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    // The process's own uid, without libc: the owner of /proc/self.
    let Ok(me) = std::fs::metadata("/proc/self").map(|m| m.uid()) else {
        return Ok(());
    };
    let Ok(dir) = std::fs::read_dir("/dev/shm") else {
        return Ok(());
    };
    for entry in dir.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if !name.starts_with(prefix) {
            continue;
        }
        let Ok(meta) = entry.metadata() else {
            continue;
        };
        if meta.uid() != me {
            if name.ends_with(".global_mgmt") {
                return Err(BusError::ForeignSegment {
                    path: entry.path(),
                    owner: meta.uid(),
                });
            }
            continue;
        }
        let mode = meta.permissions().mode();
        if mode & 0o077 != 0 {
            let private = std::fs::Permissions::from_mode(mode & 0o700);
            if let Err(e) = std::fs::set_permissions(entry.path(), private) {
                tracing::warn!("cannot make {} private: {e}", entry.path().display());
            }
        }
    }
    Ok(())
}

/// Refuse an iceoryx2 root directory another user owns that others may
/// write in (group or other write permission): whoever can write there can
/// plant, replace or remove the graph's files. This user's own root with
/// such permissions is made private (with a warning). A root that does not
/// exist yet (iceoryx2 creates its default one) is not checked.
fn check_root_dir(root: &StdPath) -> Result<(), BusError> {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    let Ok(meta) = std::fs::metadata(root) else {
        return Ok(());
    };
    let Ok(me) = std::fs::metadata("/proc/self").map(|m| m.uid()) else {
        return Ok(());
    };
    let mode = meta.permissions().mode() & 0o7777;
    match root_verdict(meta.uid(), mode, me) {
        RootVerdict::Fine => Ok(()),
        RootVerdict::Tighten => {
            let private = std::fs::Permissions::from_mode(mode & !0o022);
            match std::fs::set_permissions(root, private) {
                Ok(()) => tracing::warn!(
                    "iceoryx2 root directory {} was writable by others (mode {mode:o}): made \
                     writable by this user only",
                    root.display()
                ),
                Err(e) => tracing::warn!(
                    "iceoryx2 root directory {} is writable by others (mode {mode:o}) and \
                     cannot be made private: {e}",
                    root.display()
                ),
            }
            Ok(())
        }
        RootVerdict::Refuse => Err(BusError::ForeignRoot {
            path: root.to_path_buf(),
            owner: meta.uid(),
            mode,
        }),
    }
}

/// What [`check_root_dir`] makes of a root directory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RootVerdict {
    /// Used as it is.
    Fine,
    /// This user's, writable by others: made private.
    Tighten,
    /// Another user's, writable by others: refused.
    Refuse,
}

/// The verdict on a root directory owned by `owner` with permission bits
/// `mode`, for the user `me`.
fn root_verdict(owner: u32, mode: u32, me: u32) -> RootVerdict {
    let others_write = mode & 0o022 != 0;
    match (others_write, owner == me) {
        (false, _) => RootVerdict::Fine,
        (true, true) => RootVerdict::Tighten,
        (true, false) => RootVerdict::Refuse,
    }
}

/// Remove the resources of dead nodes under `config`; returns how many.
pub fn cleanup_dead_nodes(config: &Config) -> usize {
    let mut cleaned = 0;
    let r = Node::<Ipc>::list(config, |state| {
        if let NodeState::Dead(view) = state {
            match view.try_remove_stale_resources() {
                Ok(()) => cleaned += 1,
                Err(e) => tracing::debug!("dead node cleanup failed: {e:?}"),
            }
        }
        CallbackProgression::Continue
    });
    if let Err(e) = r {
        tracing::warn!("cannot list iceoryx2 nodes: {e:?}");
    }
    if cleaned > 0 {
        tracing::info!("cleaned up {cleaned} dead iceoryx2 node(s)");
    }
    cleaned
}

/// What a lossless publisher does while a subscriber's buffer is full.
/// The receivers that stalled (took no sample for the stall timeout) and
/// when their buffer was last found full, per publisher.
#[derive(Debug, Default)]
struct StallMemory {
    ports: Vec<(u128, Instant)>,
}

/// What the backpressure handler of a publisher counted.
#[derive(Debug, Default)]
pub struct StallCounters {
    /// Waits that ran for the whole stall timeout before dropping a sample.
    pub timed_out: AtomicU64,
    /// Samples dropped at once for a receiver known to be stalled.
    pub dropped_at_once: AtomicU64,
}

fn backpressure(
    info: &BackpressureInfo,
    stall: Duration,
    config: &Config,
    last_cleanup_ms: &AtomicU64,
    memory: &std::sync::Mutex<StallMemory>,
    counters: &StallCounters,
) -> BackpressureAction {
    if shutdown_requested() {
        return BackpressureAction::DiscardData;
    }
    let now = Instant::now();
    // A receiver that stalled and whose buffer is still full, found so within
    // two stall timeouts: it still takes nothing; drop at once. One that read
    // meanwhile is not found full, and after two timeouts it is forgotten.
    if let Ok(mut m) = memory.lock() {
        m.ports
            .retain(|(_, seen)| now.duration_since(*seen) < 2 * stall);
        if let Some(entry) = m
            .ports
            .iter_mut()
            .find(|(port, _)| *port == info.receiver_port_id)
        {
            entry.1 = now;
            counters.dropped_at_once.fetch_add(1, Ordering::Relaxed);
            return BackpressureAction::DiscardData;
        }
    }
    if info.elapsed_time >= stall {
        counters.timed_out.fetch_add(1, Ordering::Relaxed);
        tracing::warn!(
            "a subscriber (port {:x}) took no sample for {:.3} s: dropping samples for it \
             while its buffer stays full (it will see a gap in the sequence numbers)",
            info.receiver_port_id,
            info.elapsed_time.as_secs_f64()
        );
        if let Ok(mut m) = memory.lock() {
            m.ports.push((info.receiver_port_id, now));
        }
        return BackpressureAction::DiscardData;
    }
    // Every 250 ms of waiting, look for dead subscribers (a SIGKILLed process
    // leaves its full buffer behind); cleaning them up disconnects the
    // channel and ends the wait.
    let ms = info.elapsed_time.as_millis() as u64;
    let last = last_cleanup_ms.load(Ordering::Relaxed);
    if ms >= 250 && (ms < last || ms - last >= 250) {
        last_cleanup_ms.store(ms, Ordering::Relaxed);
        cleanup_dead_nodes(config);
    }
    BackpressureAction::Retry
}

// ---------------------------------------------------------------------------
// Publisher

/// A publisher of topic `T` with its wakeup notifier; numbers every sample.
#[derive(Debug)]
pub struct TopicPublisher<T: Topic> {
    service: PubSubFactory<Ipc, T, ()>,
    _event: EventFactory<Ipc>,
    publisher: Publisher<Ipc, T, ()>,
    notifier: Notifier<Ipc>,
    next_seq: u64,
    notify_failed: bool,
    stalls: std::sync::Arc<StallCounters>,
}

impl<T: Topic> TopicPublisher<T> {
    /// Publish `sample` (its `header.seq` is replaced by the next sequence
    /// number) and wake the subscribers; returns the sequence number used.
    pub fn publish(&mut self, mut sample: T) -> Result<u64, BusError> {
        let seq = self.next_seq;
        sample.header_mut().seq = seq;
        let slot = self
            .publisher
            .loan_uninit()
            .map_err(|e| service_err(T::SERVICE, "loan", e))?;
        slot.write_payload(sample)
            .send()
            .map_err(|e| service_err(T::SERVICE, "send", e))?;
        self.next_seq += 1;
        // The sample is delivered; a failed wakeup only delays the subscriber
        // until its next wakeup, so it is reported, not fatal.
        if let Err(e) = self.notifier.notify() {
            if !self.notify_failed {
                self.notify_failed = true;
                tracing::warn!(service = T::SERVICE, "wakeup notification failed: {e:?}");
            }
        }
        Ok(seq)
    }

    /// Loan a sample and give it back unsent: the subscribers see nothing.
    /// Called shortly before a publish is due, it brings the publish path's
    /// memory into the caches after a sleep.
    pub fn warm_up(&mut self) -> Result<(), BusError> {
        self.publisher
            .loan_uninit()
            .map(drop)
            .map_err(|e| service_err(T::SERVICE, "loan", e))
    }

    /// Connect to every subscriber now and wake them, so that they attach to
    /// the connection (in [`TopicSubscriber::take_events`]) before data flows.
    pub fn announce(&self) -> Result<(), BusError> {
        self.update_connections()?;
        self.notifier
            .notify_with_custom_event_id(EventId::new(EVENT_CONNECT))
            .map(|_| ())
            .map_err(|e| service_err(T::SERVICE, "notify connect", e))
    }

    /// Tell the subscribers that this stream has ended.
    pub fn end_of_stream(&self) -> Result<(), BusError> {
        self.notifier
            .notify_with_custom_event_id(EventId::new(EVENT_END_OF_STREAM))
            .map(|_| ())
            .map_err(|e| service_err(T::SERVICE, "notify end of stream", e))
    }

    /// Connect new subscribers (and hand them the history).
    pub fn update_connections(&self) -> Result<(), BusError> {
        self.publisher
            .update_connections()
            .map_err(|e| service_err(T::SERVICE, "update connections", e))
    }

    /// Number of subscribers of the service (in every process).
    pub fn subscriber_count(&self) -> usize {
        use iceoryx2::service::port_factory::PortFactory as _;
        self.service.dynamic_config().number_of_subscribers()
    }

    /// Number of samples published so far (the next sequence number).
    pub fn published(&self) -> u64 {
        self.next_seq
    }

    /// What the backpressure handler counted: waits that ran for the whole
    /// stall timeout, and samples dropped at once for a stalled receiver.
    pub fn stalls(&self) -> (u64, u64) {
        (
            self.stalls.timed_out.load(Ordering::Relaxed),
            self.stalls.dropped_at_once.load(Ordering::Relaxed),
        )
    }

    /// The service name.
    pub fn service_name(&self) -> &'static str {
        T::SERVICE
    }
}

// ---------------------------------------------------------------------------
// Subscriber

/// What [`TopicSubscriber::take_events`] found.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TopicEvents {
    /// New-sample notifications.
    pub samples: u64,
    /// A publisher announced the end of its stream.
    pub end_of_stream: bool,
    /// A publisher went away (dropped or found dead).
    pub publisher_gone: bool,
    /// A publisher announced itself ([`TopicPublisher::announce`]).
    pub connect: bool,
}

fn tally(ev: &mut TopicEvents, id: usize, count: u64) {
    match id {
        EVENT_SAMPLE => ev.samples += count,
        EVENT_END_OF_STREAM => ev.end_of_stream = true,
        EVENT_PUBLISHER_DROPPED | EVENT_PUBLISHER_DEAD => ev.publisher_gone = true,
        EVENT_CONNECT => ev.connect = true,
        _ => {}
    }
}

/// A subscriber of topic `T` with its wakeup listener and a gap counter.
#[derive(Debug)]
pub struct TopicSubscriber<T: Topic> {
    _service: PubSubFactory<Ipc, T, ()>,
    _event: EventFactory<Ipc>,
    subscriber: Subscriber<Ipc, T, ()>,
    listener: Listener<Ipc>,
    seq: RefCell<SeqTracker>,
}

impl<T: Topic> TopicSubscriber<T> {
    /// The listener to attach to a WaitSet; drain it with [`TopicSubscriber::take_events`].
    pub fn listener(&self) -> &Listener<Ipc> {
        &self.listener
    }

    /// Consume the pending notifications (a WaitSet callback must, or it
    /// spins) and attach to any new publisher.
    pub fn take_events(&self) -> Result<TopicEvents, BusError> {
        let ev = self.take_notifications()?;
        self.connect()?;
        Ok(ev)
    }

    /// Consume the pending notifications only, for a loop that receives
    /// right after (receiving attaches to new publishers itself): one step
    /// less on a latency-critical path than [`TopicSubscriber::take_events`].
    pub fn take_notifications(&self) -> Result<TopicEvents, BusError> {
        let mut ev = TopicEvents::default();
        self.listener
            .try_wait(|a| tally(&mut ev, a.id.as_value(), a.count))
            .map_err(|e| service_err(T::SERVICE, "listener try_wait", e))?;
        Ok(ev)
    }

    /// Attach to the connections of new publishers (receiving does it too).
    pub fn connect(&self) -> Result<(), BusError> {
        self.subscriber
            .update_connections()
            .map_err(|e| service_err(T::SERVICE, "update connections", e))
    }

    /// Block up to `timeout` for a notification, then consume all pending ones.
    pub fn wait_events(&self, timeout: Duration) -> Result<TopicEvents, BusError> {
        let mut ev = TopicEvents::default();
        self.listener
            .timed_wait(|a| tally(&mut ev, a.id.as_value(), a.count), timeout)
            .map_err(|e| service_err(T::SERVICE, "listener timed_wait", e))?;
        let more = self.take_events()?;
        ev.samples += more.samples;
        ev.end_of_stream |= more.end_of_stream;
        ev.publisher_gone |= more.publisher_gone;
        ev.connect |= more.connect;
        Ok(ev)
    }

    /// The next sample, copied out of shared memory, or `None` when the
    /// buffer is empty. Sequence gaps are counted ([`TopicSubscriber::lost`]).
    ///
    /// Takes `&self` so that the listener can stay attached to a WaitSet
    /// (the guard borrows it) while the loop receives.
    pub fn receive(&self) -> Result<Option<T>, BusError> {
        match self.subscriber.receive() {
            Ok(Some(sample)) => {
                let value = *sample.payload();
                self.seq
                    .borrow_mut()
                    .observe(sample.header().publisher_id().value(), value.header().seq);
                Ok(Some(value))
            }
            Ok(None) => Ok(None),
            Err(e) => Err(service_err(T::SERVICE, "receive", e)),
        }
    }

    /// [`TopicSubscriber::receive`], with the id of the publisher that sent
    /// the sample (to tell one publisher from another).
    pub fn receive_with_publisher(&self) -> Result<Option<(T, u128)>, BusError> {
        match self.subscriber.receive() {
            Ok(Some(sample)) => {
                let value = *sample.payload();
                let publisher = sample.header().publisher_id().value();
                self.seq.borrow_mut().observe(publisher, value.header().seq);
                Ok(Some((value, publisher)))
            }
            Ok(None) => Ok(None),
            Err(e) => Err(service_err(T::SERVICE, "receive", e)),
        }
    }

    /// Whether a sample is waiting (without taking it).
    pub fn has_samples(&self) -> Result<bool, BusError> {
        self.subscriber
            .has_samples()
            .map_err(|e| service_err(T::SERVICE, "has_samples", e))
    }

    /// Samples missing in the sequence numbers so far (all publishers).
    pub fn lost(&self) -> u64 {
        self.seq.borrow().lost()
    }

    /// Samples received so far.
    pub fn received(&self) -> u64 {
        self.seq.borrow().received()
    }

    /// Number of publishers of the service right now.
    pub fn publisher_count(&self) -> usize {
        use iceoryx2::service::port_factory::PortFactory as _;
        self._service.dynamic_config().number_of_publishers()
    }

    /// The service name.
    pub fn service_name(&self) -> &'static str {
        T::SERVICE
    }
}

/// Counts sequence gaps per publisher: a sample whose number is above the
/// expected one means samples were lost in between; one below it means the
/// publisher restarted (counted, not a loss).
#[derive(Debug, Clone, Default)]
pub struct SeqTracker {
    /// (publisher id, next expected number), the latest-seen publisher first.
    /// A topic has one or two publishers at a time, so a short list searched
    /// from the front beats a hash map on the receive path (no hashing of
    /// the 128-bit id per sample).
    next: Vec<(u128, u64)>,
    lost: u64,
    received: u64,
    restarts: u64,
}

impl SeqTracker {
    /// Record sequence number `seq` from publisher `publisher`.
    pub fn observe(&mut self, publisher: u128, seq: u64) {
        self.received += 1;
        match self.next.iter().position(|&(id, _)| id == publisher) {
            Some(k) => {
                let expected = self.next[k].1;
                if seq > expected {
                    self.lost += seq - expected;
                } else if seq < expected {
                    self.restarts += 1;
                }
                self.next[k].1 = seq + 1;
                // Keep the publisher being read at the front.
                if k > 0 {
                    self.next.swap(0, k);
                }
            }
            None => {
                // The first sample of this publisher seen: what it sent
                // before was not owed to this subscriber.
                self.next.insert(0, (publisher, seq + 1));
                // Publishers long gone (restarts) are not kept forever.
                self.next.truncate(4 * MAX_PUBLISHERS);
            }
        }
    }

    /// Samples missing so far, between samples of the same publisher.
    pub fn lost(&self) -> u64 {
        self.lost
    }

    /// Samples observed.
    pub fn received(&self) -> u64 {
        self.received
    }

    /// Times a publisher's numbers went backwards.
    pub fn restarts(&self) -> u64 {
        self.restarts
    }
}

/// Wait until every `(topic, count, minimum)` that `counts` returns has
/// `count >= minimum`, polling every 10 ms; ends early on a termination request.
pub fn wait_until<F: FnMut() -> Vec<(&'static str, usize, usize)>>(
    mut counts: F,
    timeout: Option<Duration>,
) -> Result<(), BusError> {
    let start = Instant::now();
    loop {
        let missing: Vec<String> = counts()
            .into_iter()
            .filter(|(_, have, want)| have < want)
            .map(|(name, have, want)| format!("{name}: {have} of {want}"))
            .collect();
        if missing.is_empty() {
            return Ok(());
        }
        if shutdown_requested() {
            return Err(BusError::Interrupted);
        }
        if let Some(t) = timeout {
            if start.elapsed() >= t {
                return Err(BusError::Timeout {
                    waited_s: start.elapsed().as_secs_f64(),
                    detail: missing.join(", "),
                });
            }
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seq_tracker_counts_gaps_and_restarts() {
        let mut t = SeqTracker::default();
        for s in [0, 1, 2, 5, 6] {
            t.observe(7, s);
        }
        assert_eq!(t.lost(), 2);
        t.observe(7, 0);
        assert_eq!(t.restarts(), 1);
        assert_eq!(t.lost(), 2);
        // A publisher first seen at its sample 257035 (this subscriber
        // restarted): nothing it sent before was owed here.
        t.observe(9, 257_035);
        assert_eq!(t.lost(), 2);
        assert_eq!(t.received(), 7);
        // Two publishers read in turns: each keeps its own count.
        for (publisher, s) in [
            (7, 1),
            (9, 257_036),
            (7, 2),
            (9, 257_037),
            (7, 4),
            (9, 257_038),
        ] {
            t.observe(publisher, s);
        }
        assert_eq!((t.lost(), t.restarts(), t.received()), (3, 1, 13));
    }

    /// A subscriber that takes nothing (a stopped process) costs its
    /// publisher one stall timeout, not one per sample, and another
    /// subscriber gets every sample.
    #[test]
    fn a_stalled_subscriber_costs_only_itself_its_samples() {
        let root = tempfile::tempdir().expect("tempdir");
        let mut settings = BusSettings::isolated("stall", root.path());
        settings.stall_timeout = Some(Duration::from_millis(300));
        let bus = Bus::open(&settings, "stall-test").expect("bus");
        let mut publisher: TopicPublisher<Imu> = bus.publisher().expect("publisher");
        let reader: TopicSubscriber<Imu> = bus.subscriber().expect("reader");
        let stalled: TopicSubscriber<Imu> = bus.subscriber().expect("stalled");
        publisher.announce().expect("announce");
        reader.take_events().expect("attach");
        stalled.take_events().expect("attach");
        let Delivery::Lossless { buffer } = Imu::DELIVERY else {
            panic!("the IMU is a stream")
        };
        let n = 3 * buffer + 50;
        let mut got = Vec::new();
        for i in 0..n {
            let sample = Imu {
                header: Header::from_seconds(i as f64 * 0.01, 0),
                ..Imu::default()
            };
            publisher.publish(sample).expect("publish");
            while let Some(s) = reader.receive().expect("receive") {
                got.push(s.header.seq);
            }
        }
        assert_eq!(
            got,
            (0..n as u64).collect::<Vec<_>>(),
            "the reader lost nothing"
        );
        let (timed_out, at_once) = publisher.stalls();
        assert_eq!(timed_out, 1, "one full wait for the stalled subscriber");
        assert_eq!(at_once as usize, n - buffer - 1);
        // The stalled one has its buffer's worth, then a gap it can count.
        let mut seen = 0;
        while stalled.receive().expect("receive").is_some() {
            seen += 1;
        }
        assert_eq!(seen, buffer);
        drop((publisher, reader, stalled));
        drop(bus);
        settings.remove_leftovers();
    }

    /// Issue 35 item 9: a pose subscriber that takes nothing (a stopped
    /// process) holds the pose publisher back by the pose budget once, not
    /// by the sensor streams' stall timeout, and costs a live reader nothing.
    #[test]
    fn a_stopped_pose_reader_holds_the_poses_back_by_the_budget_only() {
        let root = tempfile::tempdir().expect("tempdir");
        let settings = BusSettings::isolated("posebudget", root.path());
        assert_eq!(settings.wait_budget::<Pose>(), DEFAULT_POSE_BUDGET);
        assert_eq!(settings.wait_budget::<Imu>(), settings.stall_timeout());
        let bus = Bus::open(&settings, "pose-budget-test").expect("bus");
        let mut publisher: TopicPublisher<Pose> = bus.publisher().expect("publisher");
        let reader: TopicSubscriber<Pose> = bus.subscriber().expect("reader");
        let stopped: TopicSubscriber<Pose> = bus.subscriber().expect("stopped");
        publisher.announce().expect("announce");
        reader.take_events().expect("attach");
        stopped.take_events().expect("attach");
        let Delivery::Lossless { buffer } = Pose::DELIVERY else {
            panic!("the pose is a stream")
        };
        let n = buffer + 500;
        let mut got = 0u64;
        let mut slowest = Duration::ZERO;
        for i in 0..n {
            let sample = Pose {
                header: Header::from_seconds(i as f64 * 0.01, 0),
                ..Pose::default()
            };
            let start = Instant::now();
            publisher.publish(sample).expect("publish");
            slowest = slowest.max(start.elapsed());
            while reader.receive().expect("receive").is_some() {
                got += 1;
            }
        }
        assert_eq!(got, n as u64, "the live reader lost nothing");
        let (timed_out, at_once) = publisher.stalls();
        println!("slowest publish {slowest:?}; {timed_out} wait(s), {at_once} dropped at once");
        assert_eq!(timed_out, 1, "one wait for the stopped reader");
        assert_eq!(at_once as usize, n - buffer - 1);
        assert!(
            slowest < DEFAULT_POSE_BUDGET + Duration::from_millis(200),
            "a publish waited {slowest:?}"
        );
        drop((publisher, reader, stopped));
        drop(bus);
        settings.remove_leftovers();
    }

    /// The graph's shared-memory files are this user's alone, and a
    /// management segment of the prefix planted by another user is refused.
    #[test]
    fn the_graph_files_are_private_and_a_planted_segment_is_refused() {
        use std::os::unix::fs::{MetadataExt, PermissionsExt};
        let root = tempfile::tempdir().expect("tempdir");
        let settings = BusSettings::isolated("private", root.path());
        let prefix = settings.prefix.clone().expect("prefix");
        let bus = Bus::open(&settings, "private-test").expect("bus");
        let _p: TopicPublisher<Imu> = bus.publisher().expect("publisher");
        let _s: TopicSubscriber<Imu> = bus.subscriber().expect("subscriber");
        drop(Bus::open(&settings, "second").expect("second process's bus"));
        let ours: Vec<_> = std::fs::read_dir("/dev/shm")
            .expect("/dev/shm")
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
            .collect();
        assert!(ours
            .iter()
            .any(|e| e.file_name().to_string_lossy().ends_with(".global_mgmt")));
        for e in &ours {
            let mode = e.metadata().expect("meta").permissions().mode();
            assert_eq!(mode & 0o077, 0, "{}: {mode:o}", e.path().display());
        }
        let root_mode = std::fs::metadata(settings.root.as_ref().expect("root"))
            .expect("root")
            .permissions()
            .mode();
        assert_eq!(root_mode & 0o077, 0, "{root_mode:o}");
        drop((_p, _s));
        drop(bus);
        settings.remove_leftovers();

        // Another user's segment under a prefix (needs root to plant).
        let other = BusSettings::isolated("planted", root.path());
        let planted = PathBuf::from(format!(
            "/dev/shm/{}planted.global_mgmt",
            other.prefix.clone().expect("prefix")
        ));
        std::fs::write(&planted, [0u8; 16]).expect("plant");
        let me = std::fs::metadata("/proc/self").expect("self").uid();
        if me != 0 {
            println!("skipped the planted segment: needs root to give a file to another user");
            let _ = std::fs::remove_file(&planted);
            return;
        }
        std::os::unix::fs::chown(&planted, Some(54_321), None).expect("chown");
        let e = Bus::open(&other, "victim")
            .expect_err("refused")
            .to_string();
        assert!(e.contains("belongs to uid 54321"), "{e}");
        other.remove_leftovers();
        let _ = std::fs::remove_file(&planted);
    }

    /// Issue 35 item 9: an iceoryx2 root created 0777 by another user is
    /// refused with its path; this user's own root writable by others is
    /// made private.
    #[test]
    fn a_root_directory_others_can_write_is_refused_or_made_private() {
        use std::os::unix::fs::{MetadataExt, PermissionsExt};
        assert_eq!(root_verdict(1000, 0o700, 1000), RootVerdict::Fine);
        assert_eq!(root_verdict(0, 0o755, 1000), RootVerdict::Fine);
        assert_eq!(root_verdict(1000, 0o777, 1000), RootVerdict::Tighten);
        assert_eq!(root_verdict(1000, 0o720, 1000), RootVerdict::Tighten);
        assert_eq!(root_verdict(54_321, 0o777, 1000), RootVerdict::Refuse);
        assert_eq!(root_verdict(54_321, 0o1777, 1000), RootVerdict::Refuse);

        let parent = tempfile::tempdir().expect("tempdir");
        let settings = BusSettings::isolated("openroot", parent.path());
        let root = settings.root.clone().expect("root");
        std::fs::create_dir(&root).expect("mkdir");
        std::fs::set_permissions(&root, std::fs::Permissions::from_mode(0o777)).expect("chmod");
        drop(Bus::open(&settings, "own-root").expect("this user's root"));
        let mode = std::fs::metadata(&root).expect("root").permissions().mode();
        assert_eq!(mode & 0o022, 0, "made private: {mode:o}");
        settings.remove_leftovers();

        let me = std::fs::metadata("/proc/self").expect("self").uid();
        if me != 0 {
            println!("skipped the foreign root: needs root to give a directory to another user");
            return;
        }
        let foreign = BusSettings::isolated("foreignroot", parent.path());
        let root = foreign.root.clone().expect("root");
        std::fs::create_dir(&root).expect("mkdir");
        std::fs::set_permissions(&root, std::fs::Permissions::from_mode(0o777)).expect("chmod");
        std::os::unix::fs::chown(&root, Some(54_321), None).expect("chown");
        let e = Bus::open(&foreign, "victim")
            .expect_err("refused")
            .to_string();
        assert!(
            e.contains(&root.display().to_string()) && e.contains("uid 54321"),
            "{e}"
        );
        assert!(e.contains("mode 777"), "{e}");
        foreign.remove_leftovers();
    }

    /// `Topic::TYPE_NAME` is the `#[type_name]` iceoryx2 matches by.
    #[test]
    #[allow(unsafe_code)] // iceoryx2's accessor of the type name is an `unsafe fn`
    fn topic_type_names_are_the_iceoryx2_type_names() {
        fn check<T: Topic>() {
            // SAFETY: only reads the name the derive macro put in.
            let iox = unsafe { <T as ZeroCopySend>::type_name() };
            assert_eq!(T::TYPE_NAME, iox, "{}", T::SERVICE);
        }
        check::<WheelRotations>();
        check::<GnssFix>();
        check::<Imu>();
        check::<Heading>();
        check::<Pose>();
        check::<CircumferenceEstimate>();
    }

    #[test]
    fn settings_round_trip_through_env_pairs() {
        let s = BusSettings::isolated("unit test!", StdPath::new("/tmp/x"));
        let prefix = s.prefix.clone().unwrap();
        assert!(prefix.starts_with("wcunittest_"), "{prefix}");
        let env = s.env();
        assert_eq!(env[0], (ENV_PREFIX, prefix.clone()));
        assert_eq!(env[1].1, format!("/tmp/x/{prefix}"));
        let config = s.iceoryx_config().unwrap();
        assert_eq!(config.global.prefix.as_bytes(), prefix.as_bytes());
        assert!(config
            .global
            .root_path()
            .as_bytes()
            .starts_with(b"/tmp/x/wc"));
    }
}
