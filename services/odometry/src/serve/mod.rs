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
//!
//! One job per file: [`args`] the flags, [`config`] the settings they give
//! (files read), [`error`] why it stops, [`shutdown`] a stop from the same
//! process, [`inputs`] the subscribers and what is drained from them,
//! [`clocks`] the sensor clocks of the estimate in use, [`estimates`]
//! estimates switched to and dropped, [`kept_pose`] and [`pose_state`] the
//! pose kept across power cycles, [`stream_end`] the wheel stream's end,
//! [`service_loop`] the loop itself, [`log`] its log lines and [`summary`]
//! what a run did.

pub(crate) mod args;
pub(crate) mod clocks;
pub(crate) mod config;
pub(crate) mod error;
pub(crate) mod estimates;
#[cfg(test)]
mod in_process;
pub(crate) mod inputs;
pub(crate) mod kept_pose;
pub(crate) mod log;
pub(crate) mod pose_state;
pub(crate) mod service_loop;
pub(crate) mod shutdown;
pub(crate) mod stream_end;
pub(crate) mod summary;

pub(crate) use args::ServeArgs;
pub(crate) use config::ServeConfig;
pub(crate) use error::ServeError;
pub(crate) use service_loop::serve;
pub(crate) use shutdown::Shutdown;
pub(crate) use summary::ServeSummary;

use interfaces::bus::Bus;
use std::time::Duration;

/// How often the notifications of the topics that wake nobody (IMU, GNSS,
/// heading) are taken: they carry nothing the loop needs at once.
pub(crate) const SIDE_EVENTS_EVERY: Duration = Duration::from_millis(100);

/// A sample this much older than the newest one seen means its publisher
/// restarted (a new replay, a restarted bridge): the filter starts over, s.
pub(crate) const RESTART_BACKSTEP_S: f64 = 1.0;

/// Drive time between two writes of the kept pose (`--pose-state`), s. A
/// crash while parked leaves a pose at most this old: a car starting off may
/// have gone `max_accel / 2 * this^2` since (2.5 m at 1 s, 250 m at 10 s), and
/// a restart widens the pose by that ([`odometry::restart`]). While the car
/// stands at the pose already written, nothing is written (no flash wear
/// while parked).
pub(crate) const POSE_STATE_EVERY_S: f64 = 1.0;

/// `odometry serve`: read the files, join the graph, run until stopped.
pub(crate) fn run(args: &ServeArgs, shutdown: &Shutdown) -> Result<ServeSummary, ServeError> {
    let config = ServeConfig::from_args(args)?;
    let bus = Bus::open(&config.bus, "odometry")?;
    serve(&bus, &config, shutdown)
}
