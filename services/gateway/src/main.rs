//! `gateway`: carries chosen topics between this host's iceoryx2 graph and
//! other hosts over Zenoh. What goes which way comes from `--out`/`--in` or
//! a TOML file (`--config`); see `gateway --help` and docs/design/gateway.md.
//!
//! Threads: the main thread runs the outbound loop (a WaitSet over the
//! listeners of the `--out` topics: drain, frame, put), a second thread the
//! inbound loop (Zenoh samples, handed over by Zenoh's callbacks through a
//! bounded channel, checked and published into the local graph). Each thread
//! has its own iceoryx2 node: iceoryx2's ports stay in the thread that made
//! them.

mod inbound;
mod outbound;
mod session;

use anyhow::{bail, Context, Result};
use clap::Parser;
use gateway::routes::{parse_list, FileSettings, Routes, TopicId};
use interfaces::bus::{self, Bus, BusSettings};
use std::path::PathBuf;
use std::sync::atomic::AtomicUsize;
use std::sync::Arc;

/// Command line of the gateway.
#[derive(Debug, Parser)]
#[command(
    name = "gateway",
    version,
    about = "Carry wheelcal topics between this host's iceoryx2 graph and other hosts over Zenoh"
)]
struct Cli {
    /// Topics to send from the local graph to Zenoh, comma-separated short
    /// names: wheels, gnss, imu, heading, estimate, pose.
    #[arg(long, value_name = "LIST")]
    out: Option<String>,
    /// Topics to receive from Zenoh into the local graph (the same names;
    /// a topic cannot be both out and in).
    #[arg(long = "in", value_name = "LIST")]
    inbound: Option<String>,
    /// TOML file with `out`, `in`, `namespace`, `listen`, `connect`,
    /// `scouting`; the command line's settings take precedence.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Prefix of every key expression (e.g. the car's name), so that several
    /// graphs share one Zenoh network without mixing their topics.
    #[arg(long, value_name = "NS")]
    namespace: Option<String>,
    /// Zenoh endpoint to listen on (repeatable), e.g. tcp/0.0.0.0:7447.
    #[arg(long, value_name = "ENDPOINT")]
    listen: Vec<String>,
    /// Zenoh endpoint to connect to (repeatable), e.g. tcp/192.168.1.20:7447;
    /// retried until it answers, and again whenever the link drops.
    #[arg(long, value_name = "ENDPOINT")]
    connect: Vec<String>,
    /// Find peers by Zenoh's multicast scouting too (off: only the given
    /// endpoints, as in a vehicle).
    #[arg(long)]
    scouting: bool,
    /// Send every sample on its own at once instead of letting Zenoh batch
    /// the samples that queue up (lower latency, lower sample rate).
    #[arg(long)]
    express: bool,
    /// Subscribe to the `--out` topics at once instead of when the first
    /// peer gateway is up (until then the samples go nowhere).
    #[arg(long)]
    no_wait_peer: bool,
    /// iceoryx2 prefix of the graph (default: $WHEELCAL_IOX_PREFIX, else iceoryx2's).
    #[arg(long, value_name = "PREFIX")]
    iox_prefix: Option<String>,
    /// iceoryx2 root path of the graph (default: $WHEELCAL_IOX_ROOT, else iceoryx2's).
    #[arg(long, value_name = "DIR")]
    iox_root: Option<PathBuf>,
}

/// Everything the gateway runs with.
#[derive(Debug, Clone)]
pub struct GatewaySettings {
    /// The graph.
    pub bus: BusSettings,
    /// What goes which way.
    pub routes: Routes,
    /// Zenoh endpoints to listen on.
    pub listen: Vec<String>,
    /// Zenoh endpoints to connect to.
    pub connect: Vec<String>,
    /// Multicast scouting on.
    pub scouting: bool,
    /// Express puts.
    pub express: bool,
    /// Wait for a peer gateway before subscribing locally.
    pub wait_peer: bool,
}

fn settings(cli: Cli) -> Result<GatewaySettings> {
    let file = match &cli.config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            FileSettings::parse(&path.display().to_string(), &text)?
        }
        None => FileSettings::default(),
    };
    let out: Vec<TopicId> = match &cli.out {
        Some(list) => parse_list(list).context("--out")?,
        None => file.out_topics()?,
    };
    let inbound: Vec<TopicId> = match &cli.inbound {
        Some(list) => parse_list(list).context("--in")?,
        None => file.in_topics()?,
    };
    let namespace = cli
        .namespace
        .clone()
        .or(file.namespace.clone())
        .unwrap_or_default();
    let routes = Routes::new(&out, &inbound, &namespace)?;
    let pick = |cli: Vec<String>, file: Vec<String>| if cli.is_empty() { file } else { cli };
    let mut bus = BusSettings::from_env();
    if let Some(p) = cli.iox_prefix {
        bus.prefix = Some(p);
    }
    if let Some(r) = cli.iox_root {
        bus.root = Some(r);
    }
    Ok(GatewaySettings {
        bus,
        routes,
        listen: pick(cli.listen, file.listen),
        connect: pick(cli.connect, file.connect),
        scouting: cli.scouting || file.scouting.unwrap_or(false),
        express: cli.express,
        wait_peer: !cli.no_wait_peer,
    })
}

/// iceoryx2 node names of a gateway's two threads.
const NODE_OUT: &str = "wheelcal-gateway";
const NODE_IN: &str = "wheelcal-gateway-in";

/// Refuse to join a graph that has a gateway already: with one gateway per
/// graph, whose topics go one way each, nothing received can be sent back.
fn refuse_second_gateway(settings: &BusSettings) -> Result<()> {
    use iceoryx2::node::NodeView;
    use iceoryx2::prelude::*;
    let config = settings.iceoryx_config()?;
    let mut other = None;
    Node::<bus::Ipc>::list(&config, |state| {
        if let NodeState::Alive(view) = state {
            if let Some(details) = view.details() {
                let name = details.name().as_str();
                if name == NODE_OUT || name == NODE_IN {
                    other = Some(format!("{:?}", view.id()));
                }
            }
        }
        CallbackProgression::Continue
    })
    .map_err(|e| anyhow::anyhow!("cannot list the graph's iceoryx2 nodes: {e:?}"))?;
    if let Some(id) = other {
        bail!(
            "another gateway runs in this graph (iceoryx2 node {id}): one gateway per graph, \
             so that a topic it receives can never be sent back; stop it or give this one \
             its topics"
        );
    }
    Ok(())
}

/// A random id for this gateway run (in every frame it sends and in its
/// liveliness token).
fn gateway_id() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u32(std::process::id());
    h.finish()
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    interfaces::logging::init();
    let settings = settings(cli)?;
    bus::cleanup_dead_nodes(&settings.bus.iceoryx_config()?);
    refuse_second_gateway(&settings.bus)?;
    let bus = Bus::open(&settings.bus, NODE_OUT)?;
    let id = gateway_id();
    let session = session::open(&settings)?;
    let names = |ts: &[TopicId]| ts.iter().map(|t| t.short()).collect::<Vec<_>>().join(",");
    tracing::info!(
        "gateway {id:016x}: out [{}], in [{}], namespace {:?}, listen {:?}, connect {:?}, scouting {}",
        names(&settings.routes.out),
        names(&settings.routes.inbound),
        settings.routes.namespace,
        settings.listen,
        settings.connect,
        if settings.scouting { "on" } else { "off" }
    );

    // Inbound first: its subscribers are declared before the liveliness
    // token, so a peer that sees the token knows they are there.
    let peers = Arc::new(AtomicUsize::new(0));
    let latest = outbound::LatestStore::new(&settings.routes.out);
    let _queryables = outbound::declare_queryables(&session, &settings.routes, &latest)?;
    let inbound = inbound::start(&session, &settings, id, peers.clone(), NODE_IN)?;
    let _token = session::declare_token(&session, &settings.routes, id)?;

    let result = outbound::run(&bus, &session, &settings, id, &peers, &latest);
    bus::request_shutdown();
    let in_result = inbound.join();
    drop(_token);
    session::close(session);
    let out_summary = result?;
    let in_summary = in_result?;
    tracing::info!(
        "gateway: stopped; sent {}; received {}",
        out_summary,
        in_summary
    );
    Ok(())
}
