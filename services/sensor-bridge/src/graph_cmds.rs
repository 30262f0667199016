//! The `replay` and `record` subcommands: thin wrappers around
//! [`sensor_bridge::replay`] and [`sensor_bridge::record`].
//!
//! Both join the graph named by `WHEELCAL_IOX_PREFIX` / `WHEELCAL_IOX_ROOT`
//! (unset: iceoryx2's defaults).

use crate::drive_input::DriveInput;
use anyhow::{bail, Context, Result};
use clap::Args;
use drive_io::{read_vehicle, write_drive_with};
use interfaces::bus::Bus;
use interfaces::drive::VehicleParams;
use sensor_bridge::record::{record, RecordOptions};
use sensor_bridge::replay::{publish_drive, DeliveryLatency, Pacing, ReplayOptions};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Arguments of `sensor-bridge replay`.
#[derive(Args, Debug)]
pub struct ReplayArgs {
    /// A drive folder or an .mcap recording (ours, compressed or not, or a
    /// ROS 2 bag with --vehicle).
    pub drive: PathBuf,
    #[command(flatten)]
    pub input: DriveInput,
    /// Pace at FACTOR times real time.
    #[arg(
        long,
        value_name = "FACTOR",
        default_value_t = 1.0,
        conflicts_with = "max"
    )]
    pub speed: f64,
    /// As fast as the subscribers take the samples, losing none.
    #[arg(long)]
    pub max: bool,
    /// Wait until every published topic has N subscribers before the first
    /// sample (default: 1 with --max, 0 otherwise).
    #[arg(long, value_name = "N")]
    pub wait_subscribers: Option<usize>,
    /// Give up waiting for subscribers after SECONDS (default: wait until Ctrl-C).
    #[arg(long, value_name = "SECONDS")]
    pub wait_timeout: Option<f64>,
    /// Wait SECONDS between announcing the publishers and the first sample,
    /// so that every subscriber attaches.
    #[arg(long, value_name = "SECONDS", default_value_t = 0.3)]
    pub settle: f64,
    /// Keep the publishers alive SECONDS after the last sample.
    #[arg(long, value_name = "SECONDS", default_value_t = 1.0)]
    pub linger: f64,
    /// Log progress every SECONDS of drive time (0: never).
    #[arg(long, value_name = "SECONDS", default_value_t = 30.0)]
    pub progress: f64,
    /// Publish streams this long after their time stamps, as sensors whose
    /// drivers deliver late: `gnss=0.15[,imu=0.01,heading=..,wheels=..]`, s.
    #[arg(long, value_name = "STREAM=S,...")]
    pub deliver_late: Option<String>,
}

/// Arguments of `sensor-bridge record`.
#[derive(Args, Debug)]
pub struct RecordArgs {
    /// Output: an .mcap file (or a folder, written as a drive folder).
    pub out: PathBuf,
    /// Vehicle parameters for the recording: a vehicle.toml, or a drive
    /// (folder or .mcap) to take them from. The bus does not carry them.
    #[arg(long, value_name = "PATH")]
    pub vehicle: PathBuf,
    /// Stop when the publishers announce the end of their streams: the wheels',
    /// then every other topic's (or it is gone, or 2 s passed) (default: at
    /// Ctrl-C).
    #[arg(long)]
    pub until_end: bool,
    #[command(flatten)]
    pub foxglove: crate::FoxgloveArgs,
}

fn positive_seconds(name: &str, v: f64) -> Result<Duration> {
    if !(v.is_finite() && v >= 0.0) {
        bail!("--{name} {v} is not a non-negative number of seconds");
    }
    Ok(Duration::from_secs_f64(v))
}

/// `sensor-bridge replay`.
pub fn run_replay(args: &ReplayArgs) -> Result<()> {
    let loaded = match args.input.read(&args.drive, false)? {
        Ok(l) => l,
        Err(e) => return Err(e).with_context(|| format!("reading {}", args.drive.display())),
    };
    for w in &loaded.warnings {
        tracing::warn!("{w}");
    }
    let defaults = ReplayOptions::for_pacing(if args.max {
        Pacing::Max
    } else {
        Pacing::Speed(args.speed)
    });
    let opts = ReplayOptions {
        wait_subscribers: args.wait_subscribers.unwrap_or(defaults.wait_subscribers),
        wait_timeout: args
            .wait_timeout
            .map(|s| positive_seconds("wait-timeout", s))
            .transpose()?,
        settle: positive_seconds("settle", args.settle)?,
        linger: positive_seconds("linger", args.linger)?,
        progress_every_s: args.progress,
        latency: args
            .deliver_late
            .as_deref()
            .map(DeliveryLatency::parse)
            .transpose()
            .map_err(|e| anyhow::anyhow!("--deliver-late {e}"))?
            .unwrap_or_default(),
        ..defaults
    };
    publish_drive(&loaded.drive, &opts, "sensor-bridge")
        .with_context(|| format!("replaying {}", args.drive.display()))?;
    Ok(())
}

/// Vehicle parameters from a vehicle.toml or a drive; warnings to the log.
fn load_vehicle(path: &Path) -> Result<VehicleParams> {
    let loaded = read_vehicle(path)
        .with_context(|| format!("reading vehicle parameters from {}", path.display()))?;
    for warning in &loaded.warnings {
        tracing::warn!("sensor-bridge: {warning}");
    }
    Ok(loaded.vehicle)
}

/// `sensor-bridge record`.
pub fn run_record(args: &RecordArgs) -> Result<()> {
    let vehicle = load_vehicle(&args.vehicle)?;
    let bus = Bus::from_env("sensor-bridge-record").context("joining the iceoryx2 graph")?;
    let rec = record(
        &bus,
        &RecordOptions {
            vehicle,
            until_end_of_stream: args.until_end,
            progress_every: Duration::from_secs(10),
        },
    )
    .context("recording")?;
    for w in &rec.warnings {
        tracing::warn!("{w}");
    }
    let mut options = args
        .foxglove
        .write_options(&rec.drive, &args.out, rec.warnings.clone());
    if !(rec.poses.is_empty() && rec.estimates.is_empty()) {
        if drive_io::is_mcap_path(&args.out) {
            tracing::info!(
                "record: {} served poses and {} estimates go beside the drive",
                rec.poses.len(),
                rec.estimates.len()
            );
        } else {
            tracing::warn!(
                "record: {} served poses and {} estimates are not kept: a drive folder has no \
                 place for them (record into a .mcap file to keep them)",
                rec.poses.len(),
                rec.estimates.len()
            );
        }
    }
    options.poses = rec.poses.clone();
    options.estimates = rec.estimates.clone();
    write_drive_with(&rec.drive, &args.out, &options)
        .with_context(|| format!("writing {}", args.out.display()))?;
    let [w, g, i, h] = rec.received;
    tracing::info!(
        "wrote {}: received {w} wheel, {g} GNSS, {i} IMU, {h} heading samples; lost {} (by sequence numbers)",
        args.out.display(),
        rec.lost.iter().sum::<u64>()
    );
    Ok(())
}
