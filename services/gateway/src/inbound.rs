//! Zenoh -> local graph: the `--in` topics, checked and published into the
//! local iceoryx2 graph with the same services and wakeup events as a local
//! publisher, so that the services there run unchanged.
//!
//! Zenoh's callbacks hand every frame to this loop's thread through one
//! bounded channel, in the order they arrive (the order they were sent). A
//! full channel makes the callback wait, which holds Zenoh's reading of the
//! link, and so the sending side: a lossless topic stays lossless across the
//! hop while the link is up. While it is down nothing arrives, and the
//! services here see their inputs stop (the odometry reports stale inputs);
//! when it is back, samples flow again into the same local publishers.
//!
//! Latest-value topics: when a peer gateway's liveliness token appears, its
//! latest sample is asked for (a Zenoh query), and a sample equal to the one
//! published last is not published again.

use crate::GatewaySettings;
use anyhow::{anyhow, Context, Result};
use gateway::header::{decode, Kind};
use gateway::routes::TopicId;
use interfaces::bus::{self, Bus, BusError, SeqTracker, Topic, TopicPublisher};
use interfaces::wire::{CircumferenceEstimate, GnssFix, Heading, Imu, Pose, WheelRotations};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use zenoh::pubsub::Subscriber;
use zenoh::sample::{Locality, Sample, SampleKind};
use zenoh::{Session, Wait};

/// Frames waiting between Zenoh and the local publishers.
const CHANNEL: usize = 4096;

/// What Zenoh hands the inbound loop.
enum InMsg {
    /// A frame on the key of `--in` topic number `index`.
    Frame { index: usize, bytes: Vec<u8> },
    /// A peer gateway's token appeared.
    PeerUp(String),
    /// A peer gateway's token went away (it stopped, or the link is down).
    PeerDown(String),
}

/// The running inbound side: its thread and the Zenoh declarations feeding it.
pub struct Inbound {
    thread: JoinHandle<Result<InSummary>>,
    _subscribers: Vec<Subscriber<()>>,
}

impl Inbound {
    /// Wait for the loop to end (after a termination request).
    pub fn join(self) -> Result<InSummary> {
        self.thread
            .join()
            .map_err(|_| anyhow!("the inbound thread panicked"))?
    }
}

/// Declare the Zenoh subscribers of the `--in` topics and of the peer
/// gateways' tokens, and start the loop (with an iceoryx2 node `node_name`).
pub fn start(
    session: &Session,
    settings: &GatewaySettings,
    id: u64,
    peers: Arc<AtomicUsize>,
    node_name: &'static str,
) -> Result<Inbound> {
    let routes = &settings.routes;
    let (tx, rx) = sync_channel::<InMsg>(CHANNEL);
    let mut subscribers = Vec::new();
    for (index, topic) in routes.inbound.iter().enumerate() {
        let key = topic.key(&routes.namespace);
        let tx = tx.clone();
        let s = session
            .declare_subscriber(&key)
            // Never this session's own puts (the frame's gateway id is checked too).
            .allowed_origin(Locality::Remote)
            .callback(move |sample: Sample| {
                let bytes = sample.payload().to_bytes().into_owned();
                // Waits while the channel is full (backpressure); fails
                // only once the loop has ended.
                let _ = tx.send(InMsg::Frame { index, bytes });
            })
            .wait()
            .map_err(|e| anyhow!("cannot declare the Zenoh subscriber {key}: {e}"))?;
        subscribers.push(s);
    }
    let own_token = routes.gateway_token(id);
    let tokens = routes.gateway_tokens();
    let token_tx = tx.clone();
    let liveliness = session
        .liveliness()
        .declare_subscriber(format!("{tokens}/*"))
        .history(true)
        .callback(move |sample: Sample| {
            let key = sample.key_expr().as_str().to_string();
            if key == own_token {
                return;
            }
            let peer = key.rsplit('/').next().unwrap_or_default().to_string();
            let msg = match sample.kind() {
                SampleKind::Put => {
                    peers.fetch_add(1, Ordering::SeqCst);
                    InMsg::PeerUp(peer)
                }
                SampleKind::Delete => {
                    let _ = peers.fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| {
                        Some(n.saturating_sub(1))
                    });
                    InMsg::PeerDown(peer)
                }
            };
            let _ = token_tx.send(msg);
        })
        .wait()
        .map_err(|e| anyhow!("cannot subscribe to the gateways' tokens {tokens}: {e}"))?;
    subscribers.push(liveliness);

    let session = session.clone();
    let settings = settings.clone();
    let thread = std::thread::Builder::new()
        .name("gateway-in".to_string())
        .spawn(move || {
            let r = run(&session, &settings, id, node_name, tx, rx);
            if r.is_err() {
                bus::request_shutdown();
            }
            r
        })
        .context("cannot start the inbound thread")?;
    Ok(Inbound {
        thread,
        _subscribers: subscribers,
    })
}

/// One `--in` topic: its publisher in the local graph.
trait InPort {
    /// Publish the payload (its size checked); returns the sender's sequence number.
    fn publish(&mut self, payload: &[u8]) -> Result<u64, BusError>;
    fn end_of_stream(&self) -> Result<(), BusError>;
    fn update_connections(&self) -> Result<(), BusError>;
    fn announce(&self) -> Result<(), BusError>;
}

struct Port<T: Topic> {
    publisher: TopicPublisher<T>,
}

impl<T: Topic> InPort for Port<T> {
    fn publish(&mut self, payload: &[u8]) -> Result<u64, BusError> {
        let sample: T = bytemuck::pod_read_unaligned(payload);
        let seq = sample.header().seq;
        self.publisher.publish(sample)?;
        Ok(seq)
    }
    fn end_of_stream(&self) -> Result<(), BusError> {
        self.publisher.end_of_stream()
    }
    fn update_connections(&self) -> Result<(), BusError> {
        self.publisher.update_connections()
    }
    fn announce(&self) -> Result<(), BusError> {
        self.publisher.announce()
    }
}

fn open_port(bus: &Bus, topic: TopicId) -> Result<Box<dyn InPort>, BusError> {
    fn port<T: Topic>(bus: &Bus) -> Result<Box<dyn InPort>, BusError> {
        Ok(Box::new(Port::<T> {
            publisher: bus.publisher()?,
        }))
    }
    match topic {
        TopicId::Wheels => port::<WheelRotations>(bus),
        TopicId::Gnss => port::<GnssFix>(bus),
        TopicId::Imu => port::<Imu>(bus),
        TopicId::Heading => port::<Heading>(bus),
        TopicId::Estimate => port::<CircumferenceEstimate>(bus),
        TopicId::Pose => port::<Pose>(bus),
    }
}

/// What the inbound loop received, per topic.
#[derive(Debug, Default)]
pub struct InSummary {
    published: BTreeMap<TopicId, u64>,
    missing: BTreeMap<TopicId, u64>,
    rejected: BTreeMap<TopicId, u64>,
}

impl std::fmt::Display for InSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let parts: Vec<String> = self
            .published
            .iter()
            .map(|(t, n)| {
                format!(
                    "{} {n} ({} missing in the sender's sequence, {} rejected)",
                    t.short(),
                    self.missing.get(t).copied().unwrap_or(0),
                    self.rejected.get(t).copied().unwrap_or(0)
                )
            })
            .collect();
        write!(f, "[{}]", parts.join(", "))
    }
}

/// Per `--in` topic state of the loop.
struct InTopic {
    topic: TopicId,
    key: String,
    port: Box<dyn InPort>,
    /// The sequence numbers of the publishers in the sending graphs.
    seq: SeqTracker,
    /// The payload published last (latest-value topics).
    last: Option<Vec<u8>>,
    /// The distinct refusals logged so far.
    refusals: Vec<String>,
}

/// Distinct refusals logged per topic (each the first time it occurs).
const MAX_REFUSAL_KINDS: usize = 16;

fn run(
    session: &Session,
    settings: &GatewaySettings,
    id: u64,
    node_name: &str,
    tx: SyncSender<InMsg>,
    rx: Receiver<InMsg>,
) -> Result<InSummary> {
    let routes = &settings.routes;
    let bus = Bus::open(&settings.bus, node_name)?;
    let mut topics = Vec::new();
    for &topic in &routes.inbound {
        let port = open_port(&bus, topic)?;
        port.announce()?;
        topics.push(InTopic {
            topic,
            key: topic.key(&routes.namespace),
            port,
            seq: SeqTracker::default(),
            last: None,
            refusals: Vec::new(),
        });
    }
    let mut summary = InSummary::default();
    for t in &topics {
        summary.published.insert(t.topic, 0);
    }
    let mut last_update = Instant::now();
    loop {
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(InMsg::Frame { index, bytes }) => {
                handle_frame(&mut topics[index], id, &bytes, &mut summary)?;
            }
            Ok(InMsg::PeerUp(peer)) => {
                tracing::info!("gateway: peer gateway {peer} is up");
                for (index, t) in topics.iter().enumerate() {
                    if t.topic.is_latest() {
                        ask_latest(session, &t.key, index, &tx)?;
                    }
                }
            }
            Ok(InMsg::PeerDown(peer)) => {
                tracing::warn!(
                    "gateway: peer gateway {peer} is gone (stopped, or the link is down): \
                     its topics stop until it is back"
                );
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
        if last_update.elapsed() >= Duration::from_millis(100) {
            last_update = Instant::now();
            // New local subscribers connect (and get the estimate's history).
            for t in &topics {
                t.port.update_connections()?;
            }
            if bus::shutdown_requested() {
                break;
            }
        }
    }
    Ok(summary)
}

/// Ask the peers for the latest sample on `key`; the replies come as frames.
fn ask_latest(session: &Session, key: &str, index: usize, tx: &SyncSender<InMsg>) -> Result<()> {
    let tx = tx.clone();
    session
        .get(key)
        .callback(move |reply| {
            if let Ok(sample) = reply.result() {
                let bytes = sample.payload().to_bytes().into_owned();
                let _ = tx.send(InMsg::Frame { index, bytes });
            }
        })
        .wait()
        .map_err(|e| anyhow!("{key}: query for the latest sample failed: {e}"))
}

fn handle_frame(t: &mut InTopic, id: u64, bytes: &[u8], summary: &mut InSummary) -> Result<()> {
    let checked = decode(&t.key, bytes).and_then(|f| {
        f.check(&t.key, t.topic.type_name(), t.topic.size())?;
        Ok(f)
    });
    let frame = match checked {
        Ok(f) => f,
        Err(e) => {
            let n = summary.rejected.entry(t.topic).or_default();
            *n += 1;
            // Each kind of wrong frame once, then every thousandth frame
            // refused: a wrong sender must not flood the log.
            let text = e.to_string();
            let new_kind = t.refusals.len() < MAX_REFUSAL_KINDS && !t.refusals.contains(&text);
            if new_kind || n.is_multiple_of(1000) {
                tracing::error!("gateway: rejected a frame: {text} ({n} rejected on this topic)");
                if new_kind {
                    t.refusals.push(text);
                }
            }
            return Ok(());
        }
    };
    if frame.gateway == id {
        return Ok(()); // its own frame: never taken back
    }
    match frame.kind {
        Kind::EndOfStream => {
            t.port.end_of_stream()?;
            tracing::info!("gateway: {}: end of stream", t.topic.short());
        }
        Kind::Sample => {
            if t.topic.is_latest() {
                if t.last.as_deref() == Some(frame.payload) {
                    return Ok(()); // the same latest value again
                }
                t.last = Some(frame.payload.to_vec());
            }
            let seq = t.port.publish(frame.payload)?;
            *summary.published.entry(t.topic).or_default() += 1;
            if !t.topic.is_latest() {
                let before = t.seq.lost();
                t.seq.observe(u128::from(frame.origin), seq);
                let gap = t.seq.lost() - before;
                if gap > 0 {
                    *summary.missing.entry(t.topic).or_default() += gap;
                    tracing::warn!(
                        "gateway: {}: {gap} sample(s) of the sender's sequence never arrived \
                         (the link was down or the sending gateway restarted)",
                        t.topic.short()
                    );
                }
            }
        }
    }
    Ok(())
}
