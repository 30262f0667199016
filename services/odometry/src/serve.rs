//! `odometry serve`: the pose service of the process graph.
//!
//! Subscribes to the wheels, IMU, GNSS, heading and estimate topics
//! (`interfaces::wire` names them, `interfaces::bus` opens them the same way
//! in every process) and publishes a [`Pose`] on `wheelcal/odometry/pose` for
//! every wheel sample, from the [`Fusion`] filter.
//!
//! - Blocking wakeups: one WaitSet with the listeners of the wheel and
//!   estimate topics (each publish-subscribe service has an event service of
//!   the same name that its publishers notify per sample) and an interval that
//!   checks for stale inputs and termination. No polling loop. The IMU, GNSS
//!   and heading topics wake nobody: a pose is only due with a wheel sample,
//!   and every sample up to its time is in its queue by then, so waking for
//!   them would only add wakeups on the path of the next wheel sample. Their
//!   notifications are taken at most every [`SIDE_EVENTS_EVERY`] (an
//!   untaken notification makes the next ones free for their publisher).
//! - Every wakeup drains all subscribers, the wheels first, into a
//!   [`Sequencer`], which releases the samples up to the newest wheel sample
//!   in time order, wheels last at equal times ([`odometry::inputs`]): the same
//!   order as `odometry evaluate` and the bridge's replay. Samples beyond the
//!   newest wheel sample wait for the next one, so that a wakeup that cuts
//!   through an instant (a heading of time t here, the fix of time t in the
//!   next wakeup) does not change the order. Each pose depends only on the
//!   samples up to its wheel time, all of which a publisher sending in time
//!   order has sent before that wheel sample, so a replayed drive gives the
//!   same poses, bit for bit, however the processes are scheduled and the
//!   samples grouped into wakeups. Wheel samples are never held back: no
//!   stream (ended, absent or dead) can delay a pose.
//! - The wheel topic's notifications are taken after the poses are out, not
//!   before the samples are received: on the path to a pose they cost a few
//!   syscalls. A sample published after the last receive may have had its
//!   notification taken with them, so if a wheel sample is waiting then, the
//!   next wait returns at once instead of blocking.
//! - The loop also wakes 1-2 ms before each wheel sample is due
//!   ([`odometry::cadence`], `--early-wakeup-ms`) and passes through once
//!   without it, rehearsing the filter's step on a copy and loaning a pose
//!   sample unsent, so that the sample's own pass finds caches and TLB warm
//!   after the sleep. Such a pass changes nothing a pose depends on.
//! - A new estimate is taken between two samples: the pose stays where it is,
//!   the next increments use the new values; the switch is logged with the
//!   old and new values.
//! - Sensor clocks: the estimate's clock offsets and drifts (the clock model
//!   extensions, or the initial estimate's `clock_offsets`) put the wheel
//!   and IMU stamps on the GNSS clock as they are drained, as `odometry
//!   evaluate` aligns a drive ([`StreamClocks::align`]); poses carry the
//!   restamped wheel times. A stream restamped later than the wheels makes
//!   its samples come after the wheel samples of their instant: the rewind
//!   window grows by that lateness ([`StreamClocks::max_lateness_s`]) so
//!   that they are taken in their place; one restamped earlier waits in the
//!   sequencer for the wheels. A sample beyond the window is counted
//!   (`rewind.beyond_window`), never dropped silently. A new estimate whose
//!   clocks move the wheels back by more than [`RESTART_BACKSTEP_S`] looks
//!   like a restarted publisher: the filter starts over.
//! - The GNSS antenna position (the lever arm of the fixes) is
//!   `vehicle.toml`'s `[gnss]` when given: measured, it is never replaced.
//!   Otherwise it comes from the estimate (the calibrator fits it: file
//!   `gyro.antenna_m` / `gnss_antenna_m`, on the wire the `gnss_lever_arm`
//!   extension), and until one brings it the antenna is taken to be at the
//!   rear axle: the pose is then the antenna's track. When an estimate brings
//!   a new antenna position the pose moves by the change (logged): the
//!   filter keeps where it believes the antenna is, and the pose is the rear
//!   axle's from then on.
//! - Stale inputs: when no wheel sample arrived for `stale_after` (wall
//!   clock), a warning says so, the filter forgets its pose, and one pose with
//!   mode `NoFix` (zeros, zero covariance) is published at the last wheel time
//!   so that subscribers learn at once. Nothing else is published until
//!   wheel samples come again; the filter then starts over (`NoFix` until its
//!   next GNSS initialisation). A pose is never published for an instant it
//!   cannot stand behind.
//! - Poses in mode `NoFix` (before the first initialisation) are published at
//!   wheel rate with zero position and covariance: they carry no position.
//! - A stream's time going back by more than [`RESTART_BACKSTEP_S`] (a publisher
//!   restarted) makes the filter start over; other unusable samples are
//!   skipped and logged (the first ten, then every thousandth).
//! - SIGINT/SIGTERM end the WaitSet loop; [`Shutdown`] does the same for a
//!   caller in the same process (tests).

use crate::pose_state::{self, SavedPose};
use iceoryx2::prelude::CallbackProgression;
use interfaces::bus::{self, Bus, BusError, BusSettings, TopicPublisher, TopicSubscriber};
use interfaces::drive::VehicleParams;
use interfaces::latency_trace::{wall_clock_ns, write_latency_trace, TraceError};
use interfaces::wire::{
    CircumferenceEstimate, GnssFix, Header, Heading, Imu, Pose, PoseMode, WheelRotations,
};
use odometry::cadence::WheelCadence;
use odometry::dead_reckoning::{HeadingMode, OdometerConfig};
use odometry::fusion::{FusedPose, Fusion, FusionConfig, FusionError, FusionStats, ProcessError};
use odometry::inputs::{Input, Sequencer};
use odometry::restart::{judge_restart, Restart, RestartConfig, WheelMark};
use odometry::rewind::{RewindConfig, RewindStats, RewindingFusion};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use vehicle_model::estimate::{
    gnss_lever_arm, Estimate, OdometryParams, ParamsError, StreamClocks,
};
use vehicle_model::estimate_gate::EstimateGate;

/// How often the notifications of the topics that wake nobody (IMU, GNSS,
/// heading) are taken: they carry nothing the loop needs at once.
pub const SIDE_EVENTS_EVERY: Duration = Duration::from_millis(100);

/// A sample this much older than the newest one seen means its publisher
/// restarted (a new replay, a restarted bridge): the filter starts over, s.
pub const RESTART_BACKSTEP_S: f64 = 1.0;

/// Drive time between two writes of the kept pose (`--pose-state`), s. A
/// crash while parked leaves a pose at most this old: a car starting off may
/// have gone `max_accel / 2 * this^2` since (2.5 m at 1 s, 250 m at 10 s), and
/// a restart widens the pose by that ([`odometry::restart`]). While the car
/// stands at the pose already written, nothing is written (no flash wear
/// while parked).
pub const POSE_STATE_EVERY_S: f64 = 1.0;

/// The dead-reckoning flags `odometry serve` and `odometry evaluate` share.
#[derive(Debug, Clone, clap::Args)]
pub struct OdometerArgs {
    /// Heading source while dead-reckoning: `gyro` (default, see the README for
    /// why) or `wheels` (the paper's 2W model).
    #[arg(long, default_value = "gyro")]
    pub heading: HeadingMode,
    /// Do not learn the rear wheels' zero offsets at standstill (see the README).
    #[arg(long)]
    pub no_wheel_offsets: bool,
    /// Keep the calibrated gyro bias: do not measure it at standstill (see the README).
    #[arg(long)]
    pub no_standstill_gyro_bias: bool,
}

impl OdometerArgs {
    /// The odometer configuration these flags ask for.
    pub fn config(&self) -> OdometerConfig {
        OdometerConfig {
            heading: self.heading,
            learn_wheel_offsets: !self.no_wheel_offsets,
            learn_gyro_bias: !self.no_standstill_gyro_bias,
            ..OdometerConfig::default()
        }
    }
}

/// Arguments of `odometry serve`.
#[derive(Debug, Clone, clap::Args)]
pub struct ServeArgs {
    /// Vehicle parameters: a vehicle.toml, or a drive (folder or .mcap) to take
    /// them from (nominal circumference, track, GNSS antenna position).
    #[arg(long, value_name = "PATH")]
    pub vehicle: PathBuf,
    /// Start from this estimate (`calibrator calibrate --json`) instead of the
    /// nominal values; an estimate on the bus still replaces it.
    #[arg(long, value_name = "EST.json")]
    pub estimate: Option<PathBuf>,
    /// Ignore estimates on the bus (keep the nominal or --estimate values).
    #[arg(long)]
    pub no_bus_estimate: bool,
    /// Dead-reckoning settings.
    #[command(flatten)]
    pub odometer: OdometerArgs,
    /// Without an accepted GNSS fix for this long, the mode is DeadReckoning, s.
    #[arg(long, value_name = "S", default_value_t = 1.0)]
    pub gnss_timeout: f64,
    /// Without a wheel sample for this long (wall clock), the inputs are stale, s.
    #[arg(long, value_name = "S", default_value_t = 1.0)]
    pub stale_after: f64,
    /// A sample that arrives up to this much drive time after newer ones (a
    /// GNSS receiver's delivery latency, a separate publisher) is taken in
    /// its place: the filter goes back and processes again, s (0 = apply
    /// late samples when they come).
    #[arg(long, value_name = "S", default_value_t = RewindConfig::default().window_s)]
    pub rewind_window: f64,
    /// Wake this many ms (to one more) before the next wheel sample is due and
    /// pass once through the serving loop without it, so that the sample's own
    /// pass runs on warm caches (0 = only wake for samples; see the README).
    #[arg(long, value_name = "MS", default_value_t = 1)]
    pub early_wakeup_ms: u64,
    /// Log a status line every this many seconds of drive time (0 = never).
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    pub status_every: f64,
    /// Stop when the wheel stream ends (its publisher says so) instead of
    /// waiting for more.
    #[arg(long)]
    pub exit_on_end: bool,
    /// At exit, write one line per pose published for a wheel sample to FILE: its wheel time and
    /// the wall-clock time at which it was handed to the publisher (both ns), so latency
    /// can be measured across processes (the clock is the machine's one).
    #[arg(long, value_name = "FILE")]
    pub latency_trace: Option<PathBuf>,
    /// Keep the last pose in this JSON file (every second of drive time while
    /// the car moves, when the inputs go stale, at exit) and start from it
    /// when the wheel counts or a clean stop at a standstill say the car is
    /// still there: a car parked in a garage powers on without GNSS and
    /// dead-reckons from where it stood (README, "Deploying in a vehicle").
    #[arg(long, value_name = "FILE")]
    pub pose_state: Option<PathBuf>,
    /// iceoryx2 prefix of the graph (default: $WHEELCAL_IOX_PREFIX, else iceoryx2's).
    #[arg(long, value_name = "PREFIX")]
    pub iox_prefix: Option<String>,
    /// iceoryx2 root path of the graph (default: $WHEELCAL_IOX_ROOT, else iceoryx2's).
    #[arg(long, value_name = "DIR")]
    pub iox_root: Option<PathBuf>,
}

/// Everything the service runs with, files already read.
#[derive(Debug, Clone)]
pub struct ServeConfig {
    /// Where the graph's iceoryx2 resources live.
    pub bus: BusSettings,
    /// The vehicle (nominal parameters, antenna).
    pub vehicle: VehicleParams,
    /// The estimate to start from (`None`: nominal), version 0.
    pub initial: Option<Estimate>,
    /// Take estimates from the bus.
    pub bus_estimates: bool,
    /// Filter settings.
    pub fusion: FusionConfig,
    /// How far back late samples are taken in order.
    pub rewind: RewindConfig,
    /// Wall-clock time without wheel samples after which the inputs are stale.
    pub stale_after: Duration,
    /// How long before the next wheel sample the loop wakes (zero: not early).
    pub early_wakeup: Duration,
    /// Drive-time period of the status line, s (0 = none).
    pub status_every_s: f64,
    /// Stop when the wheel stream ends.
    pub exit_on_end: bool,
    /// Where to write the publish-time trace at exit (see [`ServeArgs::latency_trace`]).
    pub latency_trace: Option<PathBuf>,
    /// Where the last pose is kept, and started from (see [`ServeArgs::pose_state`]).
    pub pose_state: Option<PathBuf>,
}

impl ServeConfig {
    /// The settings of `args`, reading the vehicle and estimate files.
    pub fn from_args(args: &ServeArgs) -> Result<ServeConfig, ServeError> {
        let vehicle = load_vehicle(&args.vehicle)?;
        let initial = match args.estimate.as_deref() {
            Some(path) => {
                let (estimate, made_for) = drive_io::read_estimate_with_vehicle(path)?;
                if let Some(w) = made_for.and_then(|v| {
                    vehicle_model::estimate_vehicle::other_vehicle_warning(
                        &v,
                        &vehicle,
                        &path.display().to_string(),
                        &format!("the vehicle file {}", args.vehicle.display()),
                    )
                }) {
                    tracing::warn!("{w}");
                }
                Some(estimate)
            }
            None => None,
        };
        let positive = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(v)
            } else {
                Err(ServeError::Config(format!(
                    "{name} {v} must be a positive number of seconds"
                )))
            }
        };
        // Beyond RESTART_BACKSTEP_S a late sample means a restarted publisher.
        let rewind_window = |v: f64| {
            if v.is_finite() && (0.0..=RESTART_BACKSTEP_S).contains(&v) {
                Ok(v)
            } else {
                Err(ServeError::Config(format!(
                    "--rewind-window {v} must be 0 to {RESTART_BACKSTEP_S} s: a sample older \
                     than that means its publisher restarted, and the filter starts over"
                )))
            }
        };
        let mut settings = BusSettings::from_env();
        if let Some(p) = &args.iox_prefix {
            settings.prefix = Some(p.clone());
        }
        if let Some(r) = &args.iox_root {
            settings.root = Some(r.clone());
        }
        let (lever_arm_m, measured) = gnss_lever_arm(&vehicle, initial.as_ref());
        let fusion = FusionConfig {
            odometer: args.odometer.config(),
            lever_arm_m,
            lever_arm_from_estimates: !measured,
            gnss_timeout_s: positive("--gnss-timeout", args.gnss_timeout)?,
            ..FusionConfig::default()
        };
        Ok(ServeConfig {
            bus: settings,
            vehicle,
            initial,
            bus_estimates: !args.no_bus_estimate,
            fusion,
            rewind: RewindConfig {
                window_s: rewind_window(args.rewind_window)?,
                ..RewindConfig::default()
            },
            stale_after: Duration::from_secs_f64(positive("--stale-after", args.stale_after)?),
            early_wakeup: Duration::from_millis(args.early_wakeup_ms),
            status_every_s: args.status_every.max(0.0),
            exit_on_end: args.exit_on_end,
            latency_trace: args.latency_trace.clone(),
            pose_state: args.pose_state.clone(),
        })
    }
}

/// Read vehicle parameters from a vehicle.toml or a drive
/// ([`drive_io::read_vehicle`]); its warnings go to the log.
pub fn load_vehicle(path: &Path) -> Result<VehicleParams, ServeError> {
    let loaded = drive_io::read_vehicle(path).map_err(|e| ServeError::Vehicle {
        path: path.to_path_buf(),
        detail: e.to_string(),
    })?;
    for warning in &loaded.warnings {
        tracing::warn!("odometry: {warning}");
    }
    loaded
        .vehicle
        .check_plausible()
        .map_err(|detail| ServeError::Vehicle {
            path: path.to_path_buf(),
            detail,
        })?;
    Ok(loaded.vehicle)
}

/// Why the service could not run.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// An iceoryx2 operation failed.
    #[error(transparent)]
    Bus(#[from] BusError),
    /// The vehicle parameters could not be read.
    #[error("vehicle parameters from {path}: {detail}")]
    Vehicle {
        /// The file or drive.
        path: PathBuf,
        /// What went wrong.
        detail: String,
    },
    /// The initial estimate could not be read.
    #[error(transparent)]
    Estimate(#[from] ParamsError),
    /// The initial estimate is not one this vehicle can have.
    #[error("{0}")]
    ImplausibleEstimate(String),
    /// A setting is out of range.
    #[error("invalid setting: {0}")]
    Config(String),
    /// The latency trace could not be written.
    #[error(transparent)]
    Trace(#[from] TraceError),
}

/// A stop request from the same process (a test, or another thread); signals
/// are handled by the WaitSet.
#[derive(Debug, Clone, Default)]
pub struct Shutdown(Arc<AtomicBool>);

impl Shutdown {
    /// Not requested yet.
    pub fn new() -> Shutdown {
        Shutdown::default()
    }

    /// Ask the service loop to end (it notices within its tick, 100 ms at most).
    /// The binary's own loop ends on signals; the in-process tests call this.
    #[cfg(test)]
    pub fn request(&self) {
        self.0.store(true, Ordering::SeqCst);
    }

    /// True once requested.
    pub fn is_requested(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }
}

/// What a service run did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ServeSummary {
    /// Wheel samples processed.
    pub wheel_samples: u64,
    /// Poses published.
    pub poses: u64,
    /// Estimates switched to.
    pub estimate_switches: u64,
    /// Estimates dropped because the GNSS fixes contradicted them
    /// (`odometry::fusion::Contradiction`).
    pub estimates_dropped: u64,
    /// Pose readers that took nothing for the pose budget (waits that ran
    /// out), and poses dropped at once for such a reader while its buffer
    /// stayed full (`TopicPublisher::stalls`).
    pub pose_reader_stalls: (u64, u64),
    /// Times the inputs went stale.
    pub stale_events: u64,
    /// Early wakeups before a wheel sample ([`odometry::cadence`]).
    pub early_wakeups: u64,
    /// Samples missing in the sequence numbers, per input topic
    /// (wheels, gnss, imu, heading, estimate).
    pub lost: [u64; 5],
    /// Input samples skipped as unusable (each logged).
    pub skipped: u64,
    /// Version of the estimate in use at the end.
    pub estimate_version: u64,
    /// What taking late samples in order did ([`odometry::rewind`]).
    pub rewind: RewindStats,
    /// The filter's counters at the end.
    pub fusion: FusionStats,
}

/// `odometry serve`: read the files, join the graph, run until stopped.
pub fn run(args: &ServeArgs, shutdown: &Shutdown) -> Result<ServeSummary, ServeError> {
    let config = ServeConfig::from_args(args)?;
    let bus = Bus::open(&config.bus, "odometry")?;
    serve(&bus, &config, shutdown)
}

struct Inputs {
    wheels: TopicSubscriber<WheelRotations>,
    gnss: TopicSubscriber<GnssFix>,
    imu: TopicSubscriber<Imu>,
    heading: TopicSubscriber<Heading>,
    estimate: TopicSubscriber<CircumferenceEstimate>,
    /// What an estimate from the bus must pass before it is used.
    gate: std::cell::RefCell<EstimateGate>,
    /// The sensor clocks of the estimate in use: the wheel and IMU stamps
    /// are put on the GNSS clock with them as they are drained.
    clocks: std::cell::Cell<StreamClocks>,
}

impl Inputs {
    fn open(bus: &Bus, gate: EstimateGate) -> Result<Inputs, BusError> {
        Ok(Inputs {
            wheels: bus.subscriber()?,
            gnss: bus.subscriber()?,
            imu: bus.subscriber()?,
            heading: bus.subscriber()?,
            estimate: bus.subscriber()?,
            gate: std::cell::RefCell::new(gate),
            clocks: std::cell::Cell::new(StreamClocks::default()),
        })
    }

    fn lost(&self) -> [u64; 5] {
        [
            self.wheels.lost(),
            self.gnss.lost(),
            self.imu.lost(),
            self.heading.lost(),
            self.estimate.lost(),
        ]
    }

    /// Every sensor sample waiting, into `sequencer`: the work on the path
    /// from a wheel sample to its pose. (The wheel topic's notifications are
    /// taken after the poses, [`Inputs::wheel_notifications`].)
    fn drain(&self, sequencer: &mut Sequencer) -> Result<(), BusError> {
        // Wheels first: every other sample up to the newest wheel time was
        // published before it, so it is in its queue now and lands in this
        // batch too. (Other streams may run ahead of the wheels; the
        // sequencer keeps them until the wheels pass their time.)
        let clocks = self.clocks.get();
        while let Some(s) = self.wheels.receive()? {
            sequencer.push(Input::Wheels {
                t_s: clocks.wheel_time_on_gnss_clock(s.header.t_s()),
                rl_rev: s.rl_rev,
                rr_rev: s.rr_rev,
            });
        }
        while let Some(s) = self.imu.receive()? {
            sequencer.push(Input::Imu {
                t_s: clocks.imu_time_on_gnss_clock(s.header.t_s()),
                gz_rad_s: s.gz_rad_s,
            });
        }
        while let Some(s) = self.gnss.receive()? {
            if s.fix == 0 {
                continue; // "no fix": the position is not usable (wire contract)
            }
            sequencer.push(Input::Gnss {
                t_s: s.header.t_s(),
                x_m: s.x_m,
                y_m: s.y_m,
                sigma_m: (s.sigma_m > 0.0).then_some(s.sigma_m),
            });
        }
        while let Some(s) = self.heading.receive()? {
            sequencer.push(Input::Heading {
                t_s: s.header.t_s(),
                yaw_rad: s.yaw_rad,
                sigma_rad: (s.sigma_rad > 0.0).then_some(s.sigma_rad),
            });
        }
        Ok(())
    }

    /// After the poses of a wakeup: consume the wheel topic's notifications.
    /// Returns whether its publisher said the stream ended, and whether a
    /// wheel sample is waiting: one published after the last receive, whose
    /// notification this may have consumed, so the next wait must not block.
    fn wheel_notifications(&self) -> Result<(bool, bool), BusError> {
        let ended = self.wheels.take_notifications()?.end_of_stream;
        Ok((ended, self.wheels.has_samples()?))
    }

    /// After the poses: with `estimate`, the estimate topic's notifications
    /// and samples (into `sequencer`, taken at the next release, between two
    /// wheel samples); with `side_events`, the notifications of the IMU, GNSS
    /// and heading topics. Returns how many estimates were rejected.
    fn housekeeping(
        &self,
        sequencer: &mut Sequencer,
        bus_estimates: bool,
        estimate: bool,
        side_events: bool,
    ) -> Result<u64, BusError> {
        let mut rejected = 0;
        if side_events {
            self.gnss.take_events()?;
            self.imu.take_events()?;
            self.heading.take_events()?;
        }
        if estimate {
            if self.estimate.take_events()?.publisher_gone {
                // A calibrator restarted without its state numbers from v1
                // again: the next publisher is taken with its own versions.
                self.gate.borrow_mut().forget_publisher();
            }
            rejected = self.drain_estimates(sequencer, bus_estimates)?;
        }
        Ok(rejected)
    }

    /// Every estimate waiting, into `sequencer`; returns how many were rejected.
    fn drain_estimates(
        &self,
        sequencer: &mut Sequencer,
        bus_estimates: bool,
    ) -> Result<u64, BusError> {
        let mut rejected = 0;
        while let Some((s, publisher)) = self.estimate.receive_with_publisher()? {
            if !bus_estimates {
                tracing::info!(
                    "odometry: estimate v{} on the bus ignored (--no-bus-estimate)",
                    s.version
                );
                continue;
            }
            let checked = Estimate::from_wire(&s)
                .map_err(|e| e.to_string())
                .and_then(|estimate| {
                    self.gate
                        .borrow_mut()
                        .check(s.version, Some(publisher), &estimate)
                        .map(|()| estimate)
                        .map_err(|e| format!("v{}: {e}", s.version))
                });
            match checked {
                // Taken between two samples: sorted before the wheels of this batch.
                Ok(estimate) => {
                    if estimate.clocks != self.clocks.get() {
                        tracing::info!(
                            "odometry: sensor clocks from estimate v{}: {}",
                            s.version,
                            describe_clocks(&estimate.clocks)
                        );
                        self.clocks.set(estimate.clocks);
                    }
                    sequencer.push(Input::Estimate {
                        t_s: f64::NEG_INFINITY,
                        version: s.version,
                        estimate,
                    })
                }
                Err(e) => {
                    rejected += 1;
                    tracing::warn!("odometry: estimate rejected: {e}");
                }
            }
        }
        Ok(rejected)
    }
}

/// The sensor clocks' lateness is taken over this much drive time ahead, s
/// (a drift makes it grow slowly).
const CLOCK_LATENESS_HORIZON_S: f64 = 3600.0;

/// The clocks for a log line.
fn describe_clocks(c: &StreamClocks) -> String {
    format!(
        "GNSS {:+.3} s {:+.0} ppm, IMU {:+.3} s {:+.0} ppm against the wheels; wheel and IMU stamps \
         are put on the GNSS clock",
        c.gnss_late_s, c.gnss_drift_ppm, c.imu_late_s, c.imu_drift_ppm
    )
}

/// The GNSS fixes contradict the estimate in use: drop it (the gate refuses
/// it from now on) and fall back on the one accepted before it, or on the
/// nominal values, with the reason in the log.
fn drop_contradicted(
    filter: &mut RewindingFusion,
    inputs: &Inputs,
    vehicle: &VehicleParams,
    c: &odometry::fusion::Contradiction,
) {
    let why = format!(
        "the GNSS fixes measure the wheels' distance scale at {:.4} +- {:.4} of what estimate v{} \
         makes of it, which claims 1 +- {:.4} (chi-square {:.1} over {:.0} m in {} windows, {} left out as GNSS jumps; t = {:.2} s)",
        c.measured_scale,
        c.measured_sigma,
        c.version,
        c.applied_sigma,
        c.chi2,
        c.distance_m,
        c.windows,
        c.outliers,
        c.t_s
    );
    let (fallback, fall_back) = inputs.gate.borrow_mut().drop_contradicted(c.version);
    if !fall_back {
        tracing::warn!(
            "odometry: estimate v{} dropped: {why}; a newer estimate is taken next",
            c.version
        );
        return;
    }
    let fusion = filter.fusion_mut();
    match fallback {
        Some((version, estimate)) => {
            tracing::warn!(
                "odometry: estimate v{} dropped: {why}; back to v{version}",
                c.version
            );
            if let Some(antenna) = fusion.antenna_to_take(estimate.fusable_antenna()) {
                if let Err(e) = fusion.set_lever_arm(antenna) {
                    tracing::warn!("odometry: the antenna of v{version}: {e}; kept as it was");
                }
            }
            fusion.set_estimate(estimate.params, version);
            fusion.set_effects(estimate.effects.into());
            inputs.clocks.set(estimate.clocks);
        }
        None => {
            tracing::warn!(
                "odometry: estimate v{} dropped: {why}; back to the nominal values of vehicle.toml",
                c.version
            );
            fusion.set_nominal(vehicle);
            fusion.set_effects(Default::default());
            inputs.clocks.set(StreamClocks::default());
        }
    }
}

/// The pose kept in `path`, if there is one. A file that cannot be read is
/// named in a warning and the service starts without it: a broken file must
/// not keep the car from localising.
fn load_kept_pose(path: &Path) -> Option<SavedPose> {
    match pose_state::load(path) {
        Ok(Some(saved)) => Some(saved),
        Ok(None) => {
            tracing::info!(
                "odometry: no pose kept in {} yet; it will be written there",
                path.display()
            );
            None
        }
        Err(e) => {
            tracing::warn!("odometry: {e}; starting without the kept pose");
            None
        }
    }
}

/// At the first wheel sample: start from the kept pose if
/// [`odometry::restart::judge_restart`] trusts it, with the covariance it
/// gives; else say why and start in `NoFix`.
fn resume_if_trusted(fusion: &mut Fusion, saved: &SavedPose, first: &WheelMark) {
    let judged = judge_restart(
        &saved.record(POSE_STATE_EVERY_S),
        first,
        &fusion.params().two_wheel,
        &RestartConfig::default(),
    );
    match judged {
        Restart::Resume {
            pose,
            covariance,
            why,
            ..
        } => {
            let carried = SavedPose {
                x_m: pose.x,
                y_m: pose.y,
                yaw_rad: pose.yaw,
                covariance,
                ..saved.clone()
            };
            match resume(fusion, &carried) {
                Ok(()) => tracing::info!(
                    "odometry: resuming from the kept pose ({why}): ({:.2}, {:.2}) m +- {:.2} m, \
                     yaw {:.1} +- {:.1} deg; DeadReckoning until a GNSS fix is accepted",
                    pose.x,
                    pose.y,
                    covariance[0].max(covariance[4]).sqrt(),
                    pose.yaw.to_degrees(),
                    covariance[8].sqrt().to_degrees(),
                ),
                Err(e) => tracing::warn!("odometry: kept pose: {e}; starting without it"),
            }
        }
        Restart::Refuse { why } => {
            tracing::warn!("odometry: the kept pose is not used: {why}; NoFix until GNSS")
        }
    }
}

/// Resume from `saved` with the antenna it was kept with (the pose is the
/// rear axle's for that antenna), unless the antenna is measured.
fn resume(fusion: &mut Fusion, saved: &SavedPose) -> Result<(), FusionError> {
    if let Some(antenna) = fusion.antenna_to_take(saved.gnss_antenna_m) {
        fusion.set_lever_arm(antenna)?;
    }
    fusion.resume(saved.pose(), &saved.covariance)
}

/// The last pose with a position, for `--pose-state`, with the wheel counts
/// and speed at it.
#[derive(Debug, Default)]
struct KeptPose {
    /// The pose and the GNSS antenna position the filter used for it.
    last: Option<(FusedPose, [f64; 2])>,
    /// The wheel sample of that pose and the speed there.
    last_wheels: Option<(WheelMark, Option<f64>)>,
    /// The newest wheel sample and the speed up to it.
    wheels: Option<(WheelMark, Option<f64>)>,
    written: bool,
    /// The last write was at a standstill, at this position.
    written_standing: Option<[f64; 2]>,
    next_write_t: Option<f64>,
}

impl KeptPose {
    /// Before each wheel sample is processed.
    fn wheels_at(&mut self, mark: WheelMark, params: &vehicle_model::two_wheel::TwoWheelParams) {
        let speed = self
            .wheels
            .and_then(|(previous, _)| mark.speed_since(&previous, params));
        self.wheels = Some((mark, speed));
    }

    /// After each published pose (a `NoFix` pose keeps the one before).
    fn update(&mut self, pose: &FusedPose, gnss_antenna_m: [f64; 2]) {
        if pose.mode != PoseMode::NoFix {
            self.last = Some((*pose, gnss_antenna_m));
            self.last_wheels = self.wheels.filter(|(m, _)| m.t_s == pose.t_s);
            self.written = false;
        }
    }

    /// Write when [`POSE_STATE_EVERY_S`] of drive time passed since the last
    /// write, unless the car stands where the last write already put it.
    fn write_if_due(&mut self, path: &Path) {
        let Some((pose, _)) = self.last else {
            return;
        };
        let t = pose.t_s;
        let due = *self.next_write_t.get_or_insert(t);
        // A restarted stream (time back) is due at once.
        if t >= due || t < due - POSE_STATE_EVERY_S {
            let standing = self
                .last_wheels
                .and_then(|(_, v)| v)
                .is_some_and(|v| v.abs() <= RestartConfig::default().standstill_m_s);
            let same_place = self
                .written_standing
                .is_some_and(|[x, y]| (pose.pose.x - x).hypot(pose.pose.y - y) < 0.01);
            if standing && same_place {
                self.next_write_t = Some(t + POSE_STATE_EVERY_S);
                return;
            }
            self.write(path, false);
        }
    }

    /// Write the last pose now; `last_word` when the service stops or its
    /// inputs went stale (always written then). A failure is logged, not
    /// fatal: the poses on the bus matter more.
    fn write(&mut self, path: &Path, last_word: bool) {
        let Some(mut saved) = self
            .last
            .filter(|_| last_word || !self.written)
            .and_then(|(p, antenna)| SavedPose::from_fused(&p, antenna))
        else {
            return;
        };
        if let Some((mark, speed)) = self.last_wheels {
            saved.wheel_rev = Some([mark.rl_rev, mark.rr_rev]);
            saved.speed_m_s = speed;
        }
        saved.last_word = last_word;
        saved.write_every_s = Some(POSE_STATE_EVERY_S);
        // Tried again after the same drive time when it fails (no log flood).
        self.next_write_t = Some(saved.t_s + POSE_STATE_EVERY_S);
        match pose_state::save(path, &saved) {
            Ok(()) => {
                self.written = true;
                let standing = saved
                    .speed_m_s
                    .is_some_and(|v| v.abs() <= RestartConfig::default().standstill_m_s);
                self.written_standing = standing.then_some([saved.x_m, saved.y_m]);
            }
            Err(e) => tracing::warn!("odometry: cannot keep the pose: {e}"),
        }
    }
}

/// Whether the wheel stream has ended, from the end-of-stream notifications
/// taken after each wakeup's poses.
#[derive(Debug, Default)]
struct StreamEnd {
    ended: bool,
    // While wheel samples wait: an end taken, and wheel samples taken, since
    // the end was last judged.
    end_pending: bool,
    got_wheels: bool,
}

impl StreamEnd {
    /// After a wakeup that took wheel samples or not (`got_wheels`), then the
    /// notifications (`end_taken`: one said the stream ended), with a wheel
    /// sample still waiting or not.
    fn after_wakeup(&mut self, got_wheels: bool, end_taken: bool, sample_waiting: bool) {
        self.got_wheels |= got_wheels;
        self.end_pending |= end_taken;
        if sample_waiting {
            // The samples still waiting were sent before that end: judge it
            // after them. Samples came, so an earlier end is over.
            if got_wheels {
                self.ended = false;
            }
            return;
        }
        let end = std::mem::take(&mut self.end_pending);
        if std::mem::take(&mut self.got_wheels) {
            // A stream that ended may start again (a new replay).
            self.ended = end;
        } else {
            self.ended |= end;
        }
    }

    /// The wheel stream's publisher said it ended, and no wheel sample came since.
    fn ended(&self) -> bool {
        self.ended
    }
}

const STREAM_NAMES: [&str; 4] = ["wheels", "imu", "gnss", "heading"];

/// Index of an input's stream in [`STREAM_NAMES`] (estimates have none).
fn stream_index(input: &Input) -> Option<usize> {
    match input {
        Input::Wheels { .. } => Some(0),
        Input::Imu { .. } => Some(1),
        Input::Gnss { .. } => Some(2),
        Input::Heading { .. } => Some(3),
        Input::Estimate { .. } => None,
    }
}

fn mode_name(mode: PoseMode) -> &'static str {
    match mode {
        PoseMode::NoFix => "NoFix",
        PoseMode::Fused => "Fused",
        PoseMode::DeadReckoning => "DeadReckoning",
    }
}

fn to_wire(pose: &FusedPose) -> Pose {
    Pose {
        header: Header::from_seconds(pose.t_s, 0),
        x_m: pose.pose.x,
        y_m: pose.pose.y,
        yaw_rad: pose.pose.yaw,
        covariance: pose.covariance,
        estimate_version: pose.estimate_version,
        mode: pose.mode as u8,
        _pad: [0; 7],
    }
}

fn describe_switch(old: &OdometryParams, new: &OdometryParams) -> String {
    format!(
        "c_rl {:.5} -> {:.5} m, c_rr {:.5} -> {:.5} m, track {:.4} -> {:.4} m, gyro bias {:.6} -> {:.6} rad/s, \
         gyro scale {:.5} -> {:.5}",
        old.two_wheel.c_rl,
        new.two_wheel.c_rl,
        old.two_wheel.c_rr,
        new.two_wheel.c_rr,
        old.two_wheel.track_width,
        new.two_wheel.track_width,
        old.gyro_bias_rad_s,
        new.gyro_bias_rad_s,
        old.gyro_scale,
        new.gyro_scale
    )
}

/// The service loop on an open bus; returns when stopped (signal, `shutdown`,
/// or the end of the wheel stream with `exit_on_end`).
pub fn serve(
    bus: &Bus,
    config: &ServeConfig,
    shutdown: &Shutdown,
) -> Result<ServeSummary, ServeError> {
    let fusion = match config.initial {
        Some(e) => {
            let mut f = Fusion::new(e.params, 0, config.fusion);
            f.set_effects(e.effects.into());
            f
        }
        None => Fusion::nominal(&config.vehicle, config.fusion),
    };
    let params = *fusion.params();
    params.validate("vehicle parameters")?;
    // Judged at the first wheel sample, which says whether the car moved.
    let mut kept_to_judge = config.pose_state.as_deref().and_then(load_kept_pose);
    // The filter, behind the log that lets it take late samples in order;
    // `fusion()` to read it.
    let mut filter = RewindingFusion::new(fusion, config.rewind);
    let mut gate = EstimateGate::new(&config.vehicle);
    if let Some(initial) = &config.initial {
        gate.check(0, None, initial)
            .map_err(|e| ServeError::ImplausibleEstimate(format!("the initial estimate: {e}")))?;
    }
    let inputs = Inputs::open(bus, gate)?;
    if let Some(initial) = &config.initial {
        inputs.clocks.set(initial.clocks);
        if !initial.clocks.is_zero() {
            tracing::info!(
                "odometry: sensor clocks from the initial estimate: {}",
                describe_clocks(&initial.clocks)
            );
        }
    }
    // The rewind window the clocks need, last set for these clocks.
    let mut window_for: Option<StreamClocks> = None;
    let mut poses: TopicPublisher<Pose> = bus.publisher()?;
    let mut pose_stream_ended = false;
    // (pose time, wall clock at the wakeup that brought its wheel sample, wall clock when
    // handed to the publisher), all ns: only with --latency-trace.
    let mut trace: Vec<(i64, i128, i128)> = Vec::new();
    tracing::info!(
        "odometry: serving poses on {} ({} heading, {} parameters: {params})",
        poses.service_name(),
        config.fusion.odometer.heading,
        if config.initial.is_some() {
            "initial estimate"
        } else {
            "nominal"
        },
    );
    let [ax, ay] = filter.fusion().lever_arm();
    let antenna_source = match (
        config.fusion.lever_arm_from_estimates,
        config.initial.as_ref().and_then(Estimate::fusable_antenna),
    ) {
        (false, _) => "vehicle.toml [gnss], measured: estimates do not change it",
        (true, Some(_)) => "calibrated, from the initial estimate",
        (true, None) => "not known: the pose is the antenna's track until an estimate brings it",
    };
    tracing::info!(
        "odometry: GNSS antenna at ({ax:+.3}, {ay:+.3}) m from the rear axle ({antenna_source})"
    );

    let waitset = bus.waitset()?;
    let _g_wheels = bus::wake_on(&waitset, "attach wheels", inputs.wheels.listener())?;
    let g_estimate = bus::wake_on(&waitset, "attach estimate", inputs.estimate.listener())?;
    // The tick notices stale inputs and stop requests; it does no work otherwise.
    let tick = config
        .stale_after
        .div_f64(4.0)
        .min(Duration::from_millis(100));
    let _g_tick = bus::tick_every(&waitset, tick)?;

    let mut summary = ServeSummary::default();
    let mut sequencer = Sequencer::new(RESTART_BACKSTEP_S);
    let mut batch: Vec<Input> = Vec::with_capacity(4096);
    let mut dropped_reported = (0u64, 0u64);
    let mut last_wheel_wall: Option<Instant> = None;
    let mut last_side_events = Instant::now();
    let mut last_wheel_t: Option<f64> = None;
    let mut stale = false;
    let mut mode = PoseMode::NoFix;
    let mut bias_standstills = 0u64;
    let mut next_status_t: Option<f64> = None;
    // A wheel sample is known to be waiting: the next wait returns at once.
    let mut wheel_sample_waiting = false;
    let mut wheel_stream = StreamEnd::default();
    // With --pose-state: the last pose with a position, and when it is next written.
    let mut kept = KeptPose::default();
    // Newest time seen per input stream (wheels, IMU, GNSS, heading).
    let mut latest_t: [Option<f64>; 4] = [None; 4];

    let mut cadence = WheelCadence::new(config.early_wakeup);
    loop {
        let mut estimate_event = false;
        let timeout = if wheel_sample_waiting {
            Some(Duration::ZERO)
        } else {
            cadence.wait_for_early_wakeup(Instant::now())
        };
        let result = bus::wait_once(&waitset, timeout, |id| {
            estimate_event |= id.has_event_from(&g_estimate);
            CallbackProgression::Continue
        })?;
        let woke_wall_ns = if config.latency_trace.is_some() {
            wall_clock_ns()
        } else {
            0
        };
        batch.clear();
        let clocks = inputs.clocks.get();
        if window_for != Some(clocks) {
            // Restamped onto the GNSS clock, a stream's samples may come
            // later than the wheel samples of their instant: the filter goes
            // back that much further for them (a sample beyond it is counted
            // in the rewind stats, never dropped silently).
            let t = last_wheel_t.unwrap_or(0.0);
            let window =
                config.rewind.window_s + clocks.max_lateness_s(t, t + CLOCK_LATENESS_HORIZON_S);
            if config.rewind.window_s > 0.0 && window != filter.window_s() {
                tracing::info!(
                    "odometry: going back up to {window:.2} s for samples the sensor clocks make late"
                );
                filter.set_window_s(window);
            }
            window_for = Some(clocks);
        }
        inputs.drain(&mut sequencer)?;
        sequencer.release(&mut batch);
        report_dropped(&sequencer, &mut dropped_reported, &mut summary);
        for input in &batch {
            if let Input::Estimate {
                version, estimate, ..
            } = input
            {
                let old = *filter.fusion().params();
                let old_version = filter.fusion().estimate_version();
                if *version == old_version && estimate.params == old {
                    continue; // the same estimate again (history on a reconnect)
                }
                tracing::info!(
                    "odometry: switching estimate v{old_version} -> v{version} between two samples: {}",
                    describe_switch(&old, &estimate.params)
                );
                summary.estimate_switches += 1;
                let from = filter.fusion().lever_arm();
                if let Some(to) = filter.fusion().antenna_to_take(estimate.fusable_antenna()) {
                    if to != from {
                        tracing::info!(
                            "odometry: GNSS antenna ({:+.3}, {:+.3}) -> ({:+.3}, {:+.3}) m from estimate v{version}: \
                             the pose moves by {:.3} m onto the rear axle",
                            from[0],
                            from[1],
                            to[0],
                            to[1],
                            (to[0] - from[0]).hypot(to[1] - from[1])
                        );
                    }
                }
            }
            if let Some(k) = stream_index(input) {
                let t = input.t_s();
                if let Some(previous) = latest_t[k].filter(|p| t < p - RESTART_BACKSTEP_S) {
                    tracing::warn!(
                        "odometry: {} time went back from {previous:.2} s to {t:.2} s: a publisher \
                         restarted; the filter starts over (NoFix until GNSS)",
                        STREAM_NAMES[k]
                    );
                    filter.fusion_mut().reset();
                    latest_t = [None; 4];
                }
                latest_t[k] = Some(latest_t[k].map_or(t, |l| l.max(t)));
            }
            if let Input::Wheels {
                t_s,
                rl_rev,
                rr_rev,
            } = *input
            {
                let mark = WheelMark {
                    t_s,
                    rl_rev,
                    rr_rev,
                };
                if let Some(saved) = kept_to_judge.take() {
                    resume_if_trusted(filter.fusion_mut(), &saved, &mark);
                }
                if config.pose_state.is_some() {
                    kept.wheels_at(mark, &filter.fusion().params().two_wheel);
                }
                if stale {
                    stale = false;
                    tracing::info!("odometry: wheel samples again at t = {t_s:.2} s; starting over (NoFix until GNSS)");
                }
                last_wheel_wall = Some(Instant::now());
                summary.wheel_samples += 1;
            }
            match filter.process(input) {
                Ok(Some(pose)) => {
                    let wire = to_wire(&pose);
                    if config.latency_trace.is_some() {
                        trace.push((wire.header.t_ns, woke_wall_ns, wall_clock_ns()));
                    }
                    poses.publish(wire)?;
                    summary.poses += 1;
                    if config.pose_state.is_some() {
                        kept.update(&pose, filter.fusion().lever_arm());
                    }
                    // Logged after the pose is out: a log line is not worth its latency.
                    if pose.mode != mode {
                        log_mode_change(mode, &pose);
                        mode = pose.mode;
                    }
                    let standstills = filter.fusion().stats().gyro_bias_standstills;
                    if standstills != bias_standstills {
                        bias_standstills = standstills;
                        tracing::info!(
                            "odometry: t = {:.2} s: gyro bias measured at standstill; in use now {:.3e} rad/s",
                            pose.t_s,
                            filter.fusion().gyro_bias()
                        );
                    }
                    last_wheel_t = Some(pose.t_s);
                    if config.status_every_s > 0.0 {
                        let due = next_status_t.get_or_insert(pose.t_s);
                        if pose.t_s >= *due {
                            *due = pose.t_s + config.status_every_s;
                            log_status(&pose, filter.fusion(), &inputs);
                        }
                    }
                }
                Ok(None) => {}
                Err(ProcessError::Input(e)) => {
                    summary.skipped += 1;
                    // The first ten, then every thousandth: a broken stream must not flood the log.
                    if summary.skipped <= 10 || summary.skipped.is_multiple_of(1000) {
                        tracing::warn!("odometry: {e} ({} skipped so far)", summary.skipped);
                    }
                }
                Err(e @ ProcessError::Numerical(_)) => {
                    summary.skipped += 1;
                    tracing::error!("odometry: {e}");
                }
            }
            if let Some(contradiction) = filter.take_contradiction() {
                drop_contradicted(&mut filter, &inputs, &config.vehicle, &contradiction);
                summary.estimates_dropped += 1;
            }
        }
        // The early pass (1-2 ms before the sample is due, as a rule woken
        // for it): this pass found no sample and warms what the sample's
        // pass will touch: the receives above, then the filter's step on a
        // copy, the pose's conversion, a loan from the pose publisher.
        let got_wheels = batch.iter().any(|i| matches!(i, Input::Wheels { .. }));
        if !got_wheels && cadence.take_early_pass(Instant::now()) {
            summary.early_wakeups += 1;
            if let Some(pose) = filter.rehearse() {
                std::hint::black_box(to_wire(&pose));
            }
            poses.warm_up()?;
        }
        // Off the path from a wheel sample to its pose. The estimate topic is
        // also read with the side events: a new subscriber gets the latest
        // estimate (history) without a notification.
        let side_events = last_side_events.elapsed() >= SIDE_EVENTS_EVERY;
        if side_events {
            last_side_events = Instant::now();
        }
        summary.skipped += inputs.housekeeping(
            &mut sequencer,
            config.bus_estimates,
            estimate_event || side_events,
            side_events,
        )?;

        if let Some(path) = &config.pose_state {
            kept.write_if_due(path);
        }
        // The wheel topic's notifications: taken here, not before receiving,
        // they cost a few syscalls on the path to a pose.
        let (end_taken, waiting) = inputs.wheel_notifications()?;
        wheel_sample_waiting = waiting;
        if let (true, Some(seen)) = (got_wheels, last_wheel_wall) {
            cadence.wheels_at(seen);
        }
        wheel_stream.after_wakeup(got_wheels, end_taken, waiting);
        let wheels_ended = wheel_stream.ended();
        // No wheel sample, no pose: the pose stream ends with the wheels'
        // (once per run of the wheel stream; a new run starts it again).
        if wheels_ended && !pose_stream_ended {
            poses.end_of_stream()?;
            pose_stream_ended = true;
        } else if !wheels_ended {
            pose_stream_ended = false;
        }

        // Stale inputs: the wheels stopped coming.
        if let (Some(seen), false) = (last_wheel_wall, stale) {
            let quiet = seen.elapsed();
            if quiet >= config.stale_after && !wheels_ended {
                stale = true;
                summary.stale_events += 1;
                tracing::warn!(
                    "odometry: inputs stale: no wheel sample for {:.1} s (last at t = {:.2} s); \
                     the pose is withheld until wheel samples come again",
                    quiet.as_secs_f64(),
                    last_wheel_t.unwrap_or(f64::NAN)
                );
                filter.fusion_mut().mark_stale();
                mode = PoseMode::NoFix;
                if let Some(path) = &config.pose_state {
                    kept.write(path, true);
                }
                if let Some(t) = last_wheel_t {
                    let marker = FusedPose {
                        t_s: t,
                        pose: Default::default(),
                        covariance: [0.0; 9],
                        mode: PoseMode::NoFix,
                        estimate_version: filter.fusion().estimate_version(),
                    };
                    poses.publish(to_wire(&marker))?;
                    summary.poses += 1;
                }
            }
        }

        if bus::stop_requested_by(result) || shutdown.is_requested() {
            tracing::info!("odometry: stop requested");
            break;
        }
        if config.exit_on_end && wheels_ended {
            // Take what is still buffered, then stop.
            tracing::info!("odometry: the wheel stream ended");
            break;
        }
    }
    if !pose_stream_ended {
        // Stopping: no pose follows. Subscribers learn it without waiting
        // for the publisher to be found gone.
        poses.end_of_stream()?;
    }
    summary.lost = inputs.lost();
    summary.estimate_version = filter.fusion().estimate_version();
    if let Some(path) = &config.latency_trace {
        write_latency_trace(path, &trace)?;
    }
    if let Some(path) = &config.pose_state {
        kept.write(path, true);
    }
    let stats = filter.fusion().stats();
    summary.fusion = stats;
    summary.rewind = filter.stats();
    summary.pose_reader_stalls = poses.stalls();
    if summary.pose_reader_stalls.0 > 0 || summary.estimates_dropped > 0 {
        tracing::warn!(
            "odometry: {} estimate(s) dropped as contradicted by the fixes; pose readers stalled \
             {} time(s), {} pose(s) dropped for them",
            summary.estimates_dropped,
            summary.pose_reader_stalls.0,
            summary.pose_reader_stalls.1
        );
    }
    tracing::info!(
        "odometry: {} wheel samples, {} poses published, {} estimate switch(es), {} samples lost on the bus; \
         GNSS {} accepted / {} gated out, headings {} / {}; gyro bias {:.3e} rad/s ({} standstill measurement(s)); \
         {} late sample(s) taken in order ({} inputs processed again), {} later than the {} s window; \
         {} early wakeup(s) before a wheel sample",
        summary.wheel_samples,
        summary.poses,
        summary.estimate_switches,
        summary.lost.iter().sum::<u64>(),
        stats.gnss_accepted,
        stats.gnss_rejected,
        stats.heading_accepted,
        stats.heading_rejected,
        filter.fusion().gyro_bias(),
        stats.gyro_bias_standstills,
        summary.rewind.rewinds,
        summary.rewind.reprocessed,
        summary.rewind.beyond_window,
        config.rewind.window_s,
        summary.early_wakeups,
    );
    Ok(summary)
}

/// Warn about samples the sequencer dropped since the last report (and count them as skipped).
fn report_dropped(sequencer: &Sequencer, reported: &mut (u64, u64), summary: &mut ServeSummary) {
    let now = (sequencer.dropped_full(), sequencer.dropped_on_restart());
    if now.0 > reported.0 {
        summary.skipped += now.0 - reported.0;
        tracing::warn!(
            "odometry: {} samples dropped: more than {} waited for a wheel sample (the wheel stream \
             is missing); {} so far",
            now.0 - reported.0,
            odometry::inputs::MAX_HELD,
            now.0
        );
    }
    if now.1 > reported.1 {
        summary.skipped += now.1 - reported.1;
        tracing::warn!(
            "odometry: {} held samples of a publisher's earlier run dropped (it restarted)",
            now.1 - reported.1
        );
    }
    *reported = now;
}

fn log_mode_change(from: PoseMode, pose: &FusedPose) {
    let t = pose.t_s;
    match (from, pose.mode) {
        (_, PoseMode::Fused) => tracing::info!(
            "odometry: t = {t:.2} s: {} -> Fused (GNSS good) at ({:.1}, {:.1}) m",
            mode_name(from),
            pose.pose.x,
            pose.pose.y
        ),
        (_, PoseMode::DeadReckoning) => tracing::info!(
            "odometry: t = {t:.2} s: {} -> DeadReckoning (no usable GNSS fix): dead-reckoning with estimate v{}",
            mode_name(from),
            pose.estimate_version
        ),
        (_, PoseMode::NoFix) => tracing::info!("odometry: t = {t:.2} s: {} -> NoFix", mode_name(from)),
    }
}

fn log_status(pose: &FusedPose, fusion: &Fusion, inputs: &Inputs) {
    let sigma = (pose.covariance[0] + pose.covariance[4]).max(0.0).sqrt();
    let stats = fusion.stats();
    tracing::info!(
        "odometry: t = {:.1} s {} pose ({:.1}, {:.1}) m yaw {:.1} deg, sigma {:.2} m, estimate v{}; \
         received {} wheel, {} IMU, {} GNSS samples",
        pose.t_s,
        mode_name(pose.mode),
        pose.pose.x,
        pose.pose.y,
        pose.pose.yaw.to_degrees(),
        sigma,
        pose.estimate_version,
        inputs.wheels.received(),
        inputs.imu.received(),
        stats.gnss_accepted + stats.gnss_rejected,
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        serve: ServeArgs,
    }

    #[test]
    fn the_rewind_window_is_read_and_one_beyond_a_restart_is_refused() {
        let vehicle = tempfile::tempdir().expect("tempdir");
        let toml = vehicle.path().join("vehicle.toml");
        std::fs::write(
            &toml,
            "track_width_m = 1.5\nnominal_circumference_m = 2.0\n",
        )
        .expect("write");
        let config = |window: &str| {
            let cli = Cli::try_parse_from([
                "serve",
                "--vehicle",
                toml.to_str().expect("utf-8"),
                &format!("--rewind-window={window}"),
            ])
            .expect("arguments");
            ServeConfig::from_args(&cli.serve)
        };
        assert_eq!(config("0.3").expect("valid").rewind.window_s, 0.3);
        assert_eq!(config("0").expect("off").rewind.window_s, 0.0);
        for bad in ["1.5", "-0.1", "NaN"] {
            let err = config(bad).expect_err(bad).to_string();
            assert!(
                err.contains("--rewind-window") && err.contains("restarted"),
                "{err}"
            );
        }
    }

    #[test]
    fn the_end_of_stream_is_judged_after_the_samples_that_wait_before_it() {
        // The usual end: the last samples' wakeup, then their end.
        let mut end = StreamEnd::default();
        end.after_wakeup(true, false, false);
        assert!(!end.ended());
        end.after_wakeup(false, true, false);
        assert!(end.ended());
        // The end taken with the last sample's notification while that
        // sample still waits: not ended until it is taken (it used to be
        // forgotten when the next wakeup took the sample).
        let mut end = StreamEnd::default();
        end.after_wakeup(true, true, true);
        assert!(!end.ended());
        end.after_wakeup(true, false, false);
        assert!(end.ended());
        // A new run of the stream after its end.
        end.after_wakeup(true, false, false);
        assert!(!end.ended());
        // Wakeups without wheel samples keep the end.
        end.after_wakeup(false, true, false);
        end.after_wakeup(false, false, false);
        assert!(end.ended());
        // A new run whose first wakeup leaves a sample waiting is not ended.
        end.after_wakeup(true, false, true);
        assert!(!end.ended());
    }

    #[test]
    fn a_measured_antenna_wins_over_the_initial_estimates() {
        let mut vehicle = VehicleParams {
            name: None,
            track_width_m: 1.5,
            nominal_circumference_m: 2.0,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: Default::default(),
        };
        let estimate = Estimate {
            params: OdometryParams::nominal(&vehicle),
            sigma_m: None,
            quality_m: None,
            antenna_m: Some([0.5, -0.3]),
            antenna_sigma_m: None,
            effects: vehicle_model::effects::WheelEffects::default(),
            clocks: Default::default(),
        };
        assert_eq!(gnss_lever_arm(&vehicle, None), ([0.0, 0.0], false));
        assert_eq!(
            gnss_lever_arm(&vehicle, Some(&estimate)),
            ([0.5, -0.3], false)
        );
        vehicle.gnss.antenna_x_m = Some(1.1);
        assert_eq!(
            gnss_lever_arm(&vehicle, Some(&estimate)),
            ([1.1, 0.0], true)
        );
    }

    #[test]
    fn a_kept_pose_resumes_with_the_antenna_it_was_kept_with_unless_measured() {
        let vehicle = VehicleParams {
            name: None,
            track_width_m: 1.5,
            nominal_circumference_m: 2.0,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: Default::default(),
        };
        let saved = SavedPose {
            t_s: 12.0,
            x_m: 10.0,
            y_m: -2.0,
            yaw_rad: 0.5,
            covariance: [0.01, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 1e-4],
            mode: "Fused".to_string(),
            estimate_version: 1,
            gnss_antenna_m: Some([0.5, -0.3]),
            wheel_rev: None,
            speed_m_s: None,
            last_word: true,
            write_every_s: None,
        };
        // The antenna it was kept with comes back, and the pose with it: a
        // later estimate with the same antenna then moves nothing.
        let mut fusion = Fusion::nominal(&vehicle, FusionConfig::default());
        resume(&mut fusion, &saved).unwrap();
        assert_eq!(fusion.lever_arm(), [0.5, -0.3]);
        // The pose at a standing wheel sample at `t_s`.
        let standing = |fusion: &mut Fusion, t_s: f64| {
            let pose = fusion
                .process(&Input::Wheels {
                    t_s,
                    rl_rev: 0.0,
                    rr_rev: 0.0,
                })
                .unwrap()
                .unwrap();
            (pose.pose.x, pose.pose.y)
        };
        assert_eq!(standing(&mut fusion, 12.01), (10.0, -2.0));
        fusion.set_lever_arm([0.5, -0.3]).unwrap();
        assert_eq!(standing(&mut fusion, 12.02), (10.0, -2.0));
        // A measured antenna stays.
        let measured = FusionConfig {
            lever_arm_m: [1.0, 0.0],
            lever_arm_from_estimates: false,
            ..FusionConfig::default()
        };
        let mut fusion = Fusion::nominal(&vehicle, measured);
        resume(&mut fusion, &saved).unwrap();
        assert_eq!(fusion.lever_arm(), [1.0, 0.0]);
    }
}
