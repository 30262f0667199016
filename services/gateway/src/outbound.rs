//! Local graph -> Zenoh: the `--out` topics, drained on every wakeup,
//! framed ([`gateway::header`]) and put on their key expressions.
//!
//! Order: each wakeup drains the wheels first, then the other topics, and
//! puts the other topics' samples before the wheels'. A publisher that sends
//! in time order (the bridge) has published every sample up to a wheel
//! sample's time before that wheel sample, so each such sample is drained in
//! the same wakeup or an earlier one, and is put before it. The receiving
//! gateway publishes in the order the puts arrive (one session, one
//! priority, reliable: Zenoh keeps the order), so the odometry on the far
//! side gets the same guarantee as on this host and gives the same poses.
//!
//! Latest-value topics (the estimate) keep their last frame here; a
//! queryable answers with it, so a gateway that (re)joins gets the latest
//! estimate at once (it asks when it sees this gateway's liveliness token).

use crate::GatewaySettings;
use anyhow::{anyhow, Result};
use gateway::header::{encode, Kind};
use gateway::routes::{Routes, TopicId};
use iceoryx2::port::listener::Listener;
use iceoryx2::prelude::CallbackProgression;
use interfaces::bus::{self, Bus, BusError, Ipc, Topic, TopicEvents, TopicSubscriber};
use interfaces::wire::{CircumferenceEstimate, GnssFix, Heading, Imu, Pose, WheelRotations};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::query::Queryable;
use zenoh::sample::Locality;
use zenoh::{Session, Wait};

/// The last frame sent per latest-value topic.
#[derive(Debug, Clone, Default)]
pub struct LatestStore {
    frames: BTreeMap<TopicId, Arc<Mutex<Option<Vec<u8>>>>>,
}

impl LatestStore {
    /// A store for the latest-value topics among `out`.
    pub fn new(out: &[TopicId]) -> LatestStore {
        LatestStore {
            frames: out
                .iter()
                .filter(|t| t.is_latest())
                .map(|&t| (t, Arc::new(Mutex::new(None))))
                .collect(),
        }
    }

    fn keep(&self, topic: TopicId, frame: &[u8]) {
        if let Some(slot) = self.frames.get(&topic) {
            if let Ok(mut s) = slot.lock() {
                *s = Some(frame.to_vec());
            }
        }
    }
}

/// A queryable per latest-value `--out` topic, answering with its last frame.
pub fn declare_queryables(
    session: &Session,
    routes: &Routes,
    latest: &LatestStore,
) -> Result<Vec<Queryable<()>>> {
    let mut out = Vec::new();
    for (&topic, slot) in &latest.frames {
        let key = topic.key(&routes.namespace);
        let slot = slot.clone();
        let reply_key = key.clone();
        let q = session
            .declare_queryable(&key)
            .callback(move |query| {
                let frame = slot.lock().ok().and_then(|s| s.clone());
                if let Some(frame) = frame {
                    if let Err(e) = query.reply(&reply_key, frame).wait() {
                        tracing::warn!("gateway: {reply_key}: reply to a query failed: {e}");
                    }
                }
            })
            .wait()
            .map_err(|e| anyhow!("cannot declare the queryable {key}: {e}"))?;
        out.push(q);
    }
    Ok(out)
}

/// One `--out` topic: its subscriber in the local graph.
trait OutPort {
    fn topic(&self) -> TopicId;
    fn listener(&self) -> &Listener<Ipc>;
    fn take_events(&self) -> Result<TopicEvents, BusError>;
    /// Frame every waiting sample into `frames`.
    fn drain(&self, id: u64, frames: &mut Vec<Vec<u8>>) -> Result<()>;
    fn lost(&self) -> u64;
}

struct Port<T: Topic> {
    topic: TopicId,
    sub: TopicSubscriber<T>,
}

impl<T: Topic> OutPort for Port<T> {
    fn topic(&self) -> TopicId {
        self.topic
    }
    fn listener(&self) -> &Listener<Ipc> {
        self.sub.listener()
    }
    fn take_events(&self) -> Result<TopicEvents, BusError> {
        self.sub.take_events()
    }
    fn drain(&self, id: u64, frames: &mut Vec<Vec<u8>>) -> Result<()> {
        while let Some((sample, publisher)) = self.sub.receive_with_publisher()? {
            let mut frame = Vec::new();
            // The publisher's 128-bit id folded to 64 bits: enough to tell
            // a topic's (at most two) publishers apart.
            let origin = (publisher as u64) ^ ((publisher >> 64) as u64);
            encode(
                &mut frame,
                Kind::Sample,
                (id, origin),
                T::TYPE_NAME,
                bytemuck::bytes_of(&sample),
            )
            .map_err(|e| anyhow!("{}: {e}", T::SERVICE))?;
            frames.push(frame);
        }
        Ok(())
    }
    fn lost(&self) -> u64 {
        self.sub.lost()
    }
}

fn open_port(bus: &Bus, topic: TopicId) -> Result<Box<dyn OutPort>, BusError> {
    fn port<T: Topic>(bus: &Bus, topic: TopicId) -> Result<Box<dyn OutPort>, BusError> {
        Ok(Box::new(Port::<T> {
            topic,
            sub: bus.subscriber()?,
        }))
    }
    match topic {
        TopicId::Wheels => port::<WheelRotations>(bus, topic),
        TopicId::Gnss => port::<GnssFix>(bus, topic),
        TopicId::Imu => port::<Imu>(bus, topic),
        TopicId::Heading => port::<Heading>(bus, topic),
        TopicId::Estimate => port::<CircumferenceEstimate>(bus, topic),
        TopicId::Pose => port::<Pose>(bus, topic),
    }
}

/// What the outbound loop sent.
#[derive(Debug, Default)]
pub struct OutSummary {
    sent: BTreeMap<TopicId, u64>,
    lost: u64,
}

impl std::fmt::Display for OutSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let parts: Vec<String> = self
            .sent
            .iter()
            .map(|(t, n)| format!("{} {n}", t.short()))
            .collect();
        write!(
            f,
            "[{}] ({} lost locally, by sequence numbers)",
            parts.join(", "),
            self.lost
        )
    }
}

/// Run the outbound loop until a termination request.
pub fn run(
    bus: &Bus,
    session: &Session,
    settings: &GatewaySettings,
    id: u64,
    peers: &AtomicUsize,
    latest: &LatestStore,
) -> Result<OutSummary> {
    let routes = &settings.routes;
    let mut summary = OutSummary::default();
    if routes.out.is_empty() {
        while bus::sleep_unless_shutdown(Duration::from_millis(100)) {}
        return Ok(summary);
    }
    if settings.wait_peer && peers.load(Ordering::SeqCst) == 0 {
        tracing::info!("gateway: waiting for a peer gateway before subscribing to the out topics");
        while peers.load(Ordering::SeqCst) == 0 {
            if !bus::sleep_unless_shutdown(Duration::from_millis(10)) {
                return Ok(summary);
            }
        }
    }
    // Wheels first: drained first, put last (module doc).
    let mut ports: Vec<Box<dyn OutPort>> = Vec::new();
    let mut publishers: Vec<Publisher<'static>> = Vec::new();
    for &topic in &routes.out {
        ports.push(open_port(bus, topic)?);
        let key = topic.key(&routes.namespace);
        let publisher = session
            .declare_publisher(key.clone())
            .congestion_control(CongestionControl::Block)
            // Only to other hosts: never to this session's own subscribers.
            .allowed_destination(Locality::Remote)
            .express(settings.express)
            .wait()
            .map_err(|e| anyhow!("cannot declare the Zenoh publisher {key}: {e}"))?;
        publishers.push(publisher);
    }
    let put_order: Vec<usize> = (0..ports.len())
        .filter(|&i| ports[i].topic() != TopicId::Wheels)
        .chain((0..ports.len()).filter(|&i| ports[i].topic() == TopicId::Wheels))
        .collect();
    tracing::info!("gateway: subscribed to the out topics; forwarding");

    let waitset = bus.waitset()?;
    let mut guards = Vec::new();
    for p in &ports {
        guards.push(bus::wake_on(&waitset, "attach out topic", p.listener())?);
    }
    // Also drains what came without a notification (history of the estimate).
    let _tick = bus::tick_every(&waitset, Duration::from_millis(100))?;
    let mut frames: Vec<Vec<Vec<u8>>> = vec![Vec::new(); ports.len()];
    let mut events = vec![TopicEvents::default(); ports.len()];
    let mut eos = Vec::new();
    loop {
        let result = bus::wait_once(&waitset, None, |_| CallbackProgression::Continue)?;
        for (i, p) in ports.iter().enumerate() {
            events[i] = p.take_events()?;
            p.drain(id, &mut frames[i])?;
        }
        for &i in &put_order {
            let topic = ports[i].topic();
            let n = frames[i].len() as u64;
            if let Some(last) = frames[i].last() {
                latest.keep(topic, last);
            }
            for frame in frames[i].drain(..) {
                publishers[i]
                    .put(frame)
                    .wait()
                    .map_err(|e| anyhow!("{}: Zenoh put failed: {e}", topic.service()))?;
            }
            *summary.sent.entry(topic).or_default() += n;
            if events[i].end_of_stream {
                encode(&mut eos, Kind::EndOfStream, (id, 0), topic.type_name(), &[])
                    .map_err(|e| anyhow!("{}: {e}", topic.service()))?;
                publishers[i]
                    .put(eos.clone())
                    .wait()
                    .map_err(|e| anyhow!("{}: Zenoh put failed: {e}", topic.service()))?;
                tracing::info!("gateway: {}: end of stream forwarded", topic.short());
            }
        }
        if bus::stop_requested_by(result) {
            break;
        }
    }
    summary.lost = ports.iter().map(|p| p.lost()).sum();
    drop(guards);
    Ok(summary)
}
