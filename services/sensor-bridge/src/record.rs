//! Recording the sensor topics into a [`Drive`] (written as MCAP or a drive
//! folder by `drive_io::write_drive`), so the calibrator can read it offline.
//!
//! [`record`] subscribes to every sensor topic ([`SensorSubscribers`]) and
//! collects the samples with a [`DriveBuilder`] until Ctrl-C/SIGTERM or, with
//! [`RecordOptions::until_end_of_stream`], until the publisher announces the
//! end of its stream.
//!
//! It also records what the services serve meanwhile, when they run: the
//! odometry's poses and the calibrator's estimates
//! ([`Recording::poses`], [`Recording::estimates`]; written beside the
//! drive, see `drive_io::WriteOptions::poses`).
//!
//! The wire carries no vehicle parameters: they come from the caller
//! (`--vehicle`). Wheels are recorded as cumulative revolutions (`_rev`).

use drive_io::{ServedEstimate, ServedPose};
use iceoryx2::prelude::CallbackProgression;
use interfaces::bus::TopicSubscriber;
use interfaces::bus::{self, Bus, BusError};
use interfaces::collect::{DriveBuilder, NAMES};
use interfaces::drive::{Drive, VehicleParams};
use interfaces::sensors::SensorSubscribers;
use interfaces::wire::{CircumferenceEstimate, Pose};
use std::time::{Duration, Instant};

/// Options of [`record`].
#[derive(Debug, Clone, PartialEq)]
pub struct RecordOptions {
    /// Vehicle parameters written into the recording.
    pub vehicle: VehicleParams,
    /// Stop when the wheel publisher announces the end of its stream (or goes
    /// away) and every other topic's publisher has ended its stream too, or
    /// gone, or [`END_OF_STREAM_GRACE`] has passed since the wheels ended.
    pub until_end_of_stream: bool,
    /// Log progress every this long (zero = never).
    pub progress_every: Duration,
}

/// How long `record --until-end` waits, after the wheel stream ended, for the
/// other topics' publishers to end theirs: a driver of its own (a GNSS
/// receiver) may still deliver the samples of the drive's last instants.
pub const END_OF_STREAM_GRACE: Duration = Duration::from_secs(2);

/// Why a recording failed.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// An iceoryx2 operation failed.
    #[error(transparent)]
    Bus(#[from] BusError),
    /// Nothing arrived on the wheel topic.
    #[error("no wheel sample was received on {0}: nothing to record")]
    NoWheels(&'static str),
}

/// A finished recording.
#[derive(Debug, Clone)]
pub struct Recording {
    /// The drive.
    pub drive: Drive,
    /// What was not recorded, and why.
    pub warnings: Vec<String>,
    /// Samples missing by sequence number: wheels, gnss, imu, heading.
    pub lost: [u64; 4],
    /// Samples received: wheels, gnss, imu, heading.
    pub received: [u64; 4],
    /// The poses the odometry served meanwhile, in the order received.
    pub poses: Vec<ServedPose>,
    /// The estimates the calibrator served meanwhile.
    pub estimates: Vec<ServedEstimate>,
}

/// The served topics, drained beside the sensors.
struct Served {
    poses: TopicSubscriber<Pose>,
    estimates: TopicSubscriber<CircumferenceEstimate>,
    pose_samples: Vec<ServedPose>,
    estimate_samples: Vec<ServedEstimate>,
}

impl Served {
    fn open(bus: &Bus) -> Result<Served, BusError> {
        Ok(Served {
            poses: bus.subscriber()?,
            estimates: bus.subscriber()?,
            pose_samples: Vec::new(),
            estimate_samples: Vec::new(),
        })
    }

    fn drain(&mut self) -> Result<(), BusError> {
        // Connect new publishers (and take the estimate's history).
        self.poses.take_events()?;
        self.estimates.take_events()?;
        while let Some(p) = self.poses.receive()? {
            self.pose_samples.push(ServedPose {
                t_s: p.header.t_s(),
                x_m: p.x_m,
                y_m: p.y_m,
                yaw_rad: p.yaw_rad,
                covariance: p.covariance,
                mode: p.mode,
                estimate_version: p.estimate_version,
            });
        }
        while let Some(e) = self.estimates.receive()? {
            self.estimate_samples.push(ServedEstimate {
                t_s: e.header.t_s(),
                version: e.version,
                c_rl_m: e.c_rl_m,
                c_rr_m: e.c_rr_m,
                sigma_rl_m: e.sigma_rl_m,
                sigma_rr_m: e.sigma_rr_m,
                track_width_m: e.track_width_m,
                gyro_bias_rad_s: e.gyro_bias_rad_s,
                gyro_scale: e.gyro_scale,
                quality_m: e.quality_m,
            });
        }
        Ok(())
    }
}

/// Subscribe to every sensor topic and record until Ctrl-C/SIGTERM (or the
/// end of the stream, see [`RecordOptions`]).
pub fn record(bus: &Bus, opts: &RecordOptions) -> Result<Recording, RecordError> {
    let subs = SensorSubscribers::open(bus)?;
    let mut served = Served::open(bus)?;
    let waitset = bus.waitset()?;
    let _guards = subs.wake_on_all(&waitset)?;
    // A tick, so that a signal taken by another thread is noticed.
    let _tick = bus::tick_every(&waitset, Duration::from_millis(100))?;
    let mut builder = DriveBuilder::new(opts.vehicle.clone());
    let mut last_progress = Instant::now();
    // Topics whose publisher ended its stream; when the wheel stream ended.
    let mut ended = [false; 4];
    let mut wheels_ended_at: Option<Instant> = None;
    tracing::info!("recording every sensor topic; Ctrl-C ends the recording");
    loop {
        let result = bus::wait_once(&waitset, None, |_| CallbackProgression::Continue)?;
        let outcome = subs.drain_into(&mut builder)?;
        served.drain()?;
        if !opts.progress_every.is_zero() && last_progress.elapsed() >= opts.progress_every {
            last_progress = Instant::now();
            tracing::info!(
                "record: {} wheel samples, {} GNSS fixes so far",
                builder.wheel_count(),
                builder.gnss_count()
            );
        }
        if bus::stop_requested_by(result) {
            break;
        }
        for (e, now) in ended.iter_mut().zip(outcome.ended) {
            *e |= now;
        }
        if !opts.until_end_of_stream {
            continue;
        }
        if wheels_ended_at.is_none()
            && (ended[0] || outcome.publisher_gone && subs.wheels.publisher_count() == 0)
        {
            if !ended[0] {
                tracing::warn!("record: the wheel publisher went away without ending its stream");
            }
            wheels_ended_at = Some(Instant::now());
        }
        let Some(at) = wheels_ended_at else {
            continue;
        };
        // The other topics are done when their publisher ended its stream or
        // is gone (or never was).
        let publishers = subs.publisher_counts();
        let open: Vec<&str> = (1..4)
            .filter(|&k| !ended[k] && publishers[k] > 0)
            .map(|k| NAMES[k])
            .collect();
        if open.is_empty() || at.elapsed() >= END_OF_STREAM_GRACE {
            if !open.is_empty() {
                tracing::warn!(
                    "record: the wheel stream ended {:.1} s ago and {} did not end theirs; recording stops",
                    at.elapsed().as_secs_f64(),
                    open.join(", ")
                );
            }
            // One more drain for anything that raced with the event.
            subs.drain_into(&mut builder)?;
            served.drain()?;
            break;
        }
    }
    if builder.wheel_count() == 0 {
        return Err(RecordError::NoWheels(interfaces::wire::WHEELS_SERVICE));
    }
    let mut warnings = builder.warnings();
    let lost = subs.lost();
    for (k, n) in lost.iter().enumerate() {
        if *n > 0 {
            warnings.push(format!(
                "{}: {n} samples lost on the bus (gaps in the sequence numbers)",
                NAMES[k]
            ));
        }
    }
    Ok(Recording {
        drive: builder.finish(),
        warnings,
        lost,
        received: subs.received(),
        poses: served.pose_samples,
        estimates: served.estimate_samples,
    })
}
