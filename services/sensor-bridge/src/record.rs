//! Recording the sensor topics into a [`Drive`] (written as MCAP or a drive
//! folder by [`crate::write_drive`]), so the calibrator can read it offline.
//!
//! [`DriveBuilder`] collects wire samples into a drive (pure, used by the
//! calibrator's service too); [`record`] subscribes to every sensor topic and
//! feeds it until Ctrl-C/SIGTERM or, with [`RecordOptions::until_end_of_stream`],
//! until the publisher announces the end of its stream.
//!
//! The wire carries no vehicle parameters: they come from the caller
//! (`--vehicle`). Wheels are recorded as cumulative revolutions (`_rev`).

use iceoryx2::prelude::CallbackProgression;
use interfaces::bus::{self, Bus, BusError, TopicSubscriber};
use interfaces::drive::{
    Drive, GnssSample, HeadingSample, ImuSample, VehicleParams, WheelSample, WheelSeries,
    WheelUnit, WheelUnits,
};
use interfaces::wire::{GnssFix, Heading, Imu, WheelRotations};
use std::time::{Duration, Instant};

/// Collects wire samples into a [`Drive`]. Samples that a drive cannot hold
/// (time not increasing, GNSS without fix, non-finite values) are counted and
/// reported by [`DriveBuilder::warnings`].
#[derive(Debug, Clone)]
pub struct DriveBuilder {
    vehicle: VehicleParams,
    wheels: Vec<WheelSample>,
    any_front: bool,
    gnss: Vec<GnssSample>,
    imu: Vec<ImuSample>,
    heading: Vec<HeadingSample>,
    skipped_time: [u64; 4],
    skipped_nonfinite: [u64; 4],
    skipped_no_fix: u64,
}

const NAMES: [&str; 4] = ["wheels", "gnss", "imu", "heading"];

fn increasing(last: Option<f64>, t: f64) -> bool {
    last.is_none_or(|l| t > l)
}

impl DriveBuilder {
    /// An empty drive of this vehicle.
    pub fn new(vehicle: VehicleParams) -> DriveBuilder {
        DriveBuilder {
            vehicle,
            wheels: Vec::new(),
            any_front: false,
            gnss: Vec::new(),
            imu: Vec::new(),
            heading: Vec::new(),
            skipped_time: [0; 4],
            skipped_nonfinite: [0; 4],
            skipped_no_fix: 0,
        }
    }

    /// Add a wheel sample.
    pub fn push_wheels(&mut self, s: &WheelRotations) {
        let t = s.header.t_s();
        let front = s.valid & WheelRotations::FRONT_VALID != 0;
        let finite = s.rl_rev.is_finite()
            && s.rr_rev.is_finite()
            && (!front || (s.fl_rev.is_finite() && s.fr_rev.is_finite()));
        if !finite {
            self.skipped_nonfinite[0] += 1;
        } else if !increasing(self.wheels.last().map(|w| w.t_s), t) {
            self.skipped_time[0] += 1;
        } else {
            self.any_front |= front;
            self.wheels.push(WheelSample {
                t_s: t,
                rl: s.rl_rev,
                rr: s.rr_rev,
                fl: front.then_some(s.fl_rev),
                fr: front.then_some(s.fr_rev),
            });
        }
    }

    /// Add a GNSS fix (a message without fix is not a row of a drive).
    pub fn push_gnss(&mut self, s: &GnssFix) {
        let t = s.header.t_s();
        if s.fix == 0 {
            self.skipped_no_fix += 1;
        } else if !(s.x_m.is_finite() && s.y_m.is_finite() && s.sigma_m.is_finite()) {
            self.skipped_nonfinite[1] += 1;
        } else if !increasing(self.gnss.last().map(|g| g.t_s), t) {
            self.skipped_time[1] += 1;
        } else {
            self.gnss.push(GnssSample {
                t_s: t,
                x_m: s.x_m,
                y_m: s.y_m,
                sigma_m: (s.sigma_m > 0.0).then_some(s.sigma_m),
            });
        }
    }

    /// Add an IMU sample.
    pub fn push_imu(&mut self, s: &Imu) {
        let t = s.header.t_s();
        let accel = s.valid & Imu::ACCEL_VALID != 0;
        let rates = s.valid & Imu::ROLL_PITCH_RATE_VALID != 0;
        let values = [
            Some(s.gz_rad_s),
            accel.then_some(s.ax_m_s2),
            accel.then_some(s.ay_m_s2),
            accel.then_some(s.az_m_s2),
            rates.then_some(s.gx_rad_s),
            rates.then_some(s.gy_rad_s),
        ];
        if values.iter().flatten().any(|v| !v.is_finite()) {
            self.skipped_nonfinite[2] += 1;
        } else if !increasing(self.imu.last().map(|i| i.t_s), t) {
            self.skipped_time[2] += 1;
        } else {
            self.imu.push(ImuSample {
                t_s: t,
                gz_rad_s: s.gz_rad_s,
                ax_m_s2: values[1],
                ay_m_s2: values[2],
                az_m_s2: values[3],
                gx_rad_s: values[4],
                gy_rad_s: values[5],
            });
        }
    }

    /// Add a heading.
    pub fn push_heading(&mut self, s: &Heading) {
        let t = s.header.t_s();
        if !(s.yaw_rad.is_finite() && s.sigma_rad.is_finite()) {
            self.skipped_nonfinite[3] += 1;
        } else if !increasing(self.heading.last().map(|h| h.t_s), t) {
            self.skipped_time[3] += 1;
        } else {
            self.heading.push(HeadingSample {
                t_s: t,
                yaw_rad: s.yaw_rad,
                sigma_rad: (s.sigma_rad > 0.0).then_some(s.sigma_rad),
            });
        }
    }

    /// Wheel samples collected.
    pub fn wheel_count(&self) -> usize {
        self.wheels.len()
    }

    /// GNSS fixes collected.
    pub fn gnss_count(&self) -> usize {
        self.gnss.len()
    }

    /// Wheel samples collected so far, in time order.
    pub fn wheels(&self) -> &[WheelSample] {
        &self.wheels
    }

    /// GNSS fixes collected so far, in time order.
    pub fn gnss(&self) -> &[GnssSample] {
        &self.gnss
    }

    /// What was not recorded, and why.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        for ((name, time), nonfinite) in NAMES
            .iter()
            .zip(self.skipped_time)
            .zip(self.skipped_nonfinite)
        {
            if time > 0 {
                out.push(format!(
                    "{name}: {time} samples not recorded: time not after the previous sample \
                     (a publisher restarted?)"
                ));
            }
            if nonfinite > 0 {
                out.push(format!(
                    "{name}: {nonfinite} samples not recorded: non-finite values"
                ));
            }
        }
        if self.skipped_no_fix > 0 {
            out.push(format!(
                "gnss: {} messages without fix not recorded (a drive has no row for them)",
                self.skipped_no_fix
            ));
        }
        out
    }

    /// The drive collected so far (a copy; collection can go on).
    pub fn snapshot(&self) -> Drive {
        self.clone().finish()
    }

    /// The drive.
    pub fn finish(self) -> Drive {
        let units = if self.any_front {
            WheelUnits::all(WheelUnit::Rev)
        } else {
            WheelUnits::rear(WheelUnit::Rev)
        };
        Drive {
            vehicle: self.vehicle,
            wheels: WheelSeries {
                units,
                samples: self.wheels,
            },
            gnss: non_empty(self.gnss),
            imu: non_empty(self.imu),
            heading: non_empty(self.heading),
            truth: None,
            truth_params: None,
        }
    }
}

fn non_empty<T>(v: Vec<T>) -> Option<Vec<T>> {
    if v.is_empty() {
        None
    } else {
        Some(v)
    }
}

/// The four sensor subscribers, opened together.
#[derive(Debug)]
pub struct SensorSubscribers {
    /// Wheels.
    pub wheels: TopicSubscriber<WheelRotations>,
    /// GNSS.
    pub gnss: TopicSubscriber<GnssFix>,
    /// IMU.
    pub imu: TopicSubscriber<Imu>,
    /// Heading.
    pub heading: TopicSubscriber<Heading>,
}

/// What one drain of the sensor subscribers found.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DrainOutcome {
    /// Samples received, all topics.
    pub received: u64,
    /// A sensor publisher went away (dropped or dead).
    pub publisher_gone: bool,
    /// Per topic (wheels, gnss, imu, heading): its publisher announced the
    /// end of its stream.
    pub ended: [bool; 4],
}

impl DrainOutcome {
    /// The wheel publisher announced the end of its stream.
    pub fn end_of_stream(&self) -> bool {
        self.ended[0]
    }
}

impl SensorSubscribers {
    /// Subscribe to every sensor topic.
    pub fn open(bus: &Bus) -> Result<SensorSubscribers, BusError> {
        // Wheels last: a replay waiting for subscribers then sees every topic ready.
        let gnss = bus.subscriber()?;
        let imu = bus.subscriber()?;
        let heading = bus.subscriber()?;
        let wheels = bus.subscriber()?;
        Ok(SensorSubscribers {
            wheels,
            gnss,
            imu,
            heading,
        })
    }

    /// Consume the notifications and every waiting sample into `builder`.
    pub fn drain_into(&self, builder: &mut DriveBuilder) -> Result<DrainOutcome, BusError> {
        let mut out = DrainOutcome::default();
        let events = [
            self.wheels.take_events()?,
            self.gnss.take_events()?,
            self.imu.take_events()?,
            self.heading.take_events()?,
        ];
        for (k, e) in events.iter().enumerate() {
            out.ended[k] = e.end_of_stream;
            out.publisher_gone |= e.publisher_gone;
        }
        // Everything sent before the end-of-stream event is already in the
        // buffers (delivery happens at send), so one drain after it is complete.
        while let Some(s) = self.gnss.receive()? {
            builder.push_gnss(&s);
            out.received += 1;
        }
        while let Some(s) = self.imu.receive()? {
            builder.push_imu(&s);
            out.received += 1;
        }
        while let Some(s) = self.heading.receive()? {
            builder.push_heading(&s);
            out.received += 1;
        }
        while let Some(s) = self.wheels.receive()? {
            builder.push_wheels(&s);
            out.received += 1;
        }
        Ok(out)
    }

    /// Publishers per topic right now: wheels, gnss, imu, heading.
    pub fn publisher_counts(&self) -> [usize; 4] {
        [
            self.wheels.publisher_count(),
            self.gnss.publisher_count(),
            self.imu.publisher_count(),
            self.heading.publisher_count(),
        ]
    }

    /// Samples missing by sequence number: wheels, gnss, imu, heading.
    pub fn lost(&self) -> [u64; 4] {
        [
            self.wheels.lost(),
            self.gnss.lost(),
            self.imu.lost(),
            self.heading.lost(),
        ]
    }

    /// Samples received: wheels, gnss, imu, heading.
    pub fn received(&self) -> [u64; 4] {
        [
            self.wheels.received(),
            self.gnss.received(),
            self.imu.received(),
            self.heading.received(),
        ]
    }
}

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
}

/// Subscribe to every sensor topic and record until Ctrl-C/SIGTERM (or the
/// end of the stream, see [`RecordOptions`]).
pub fn record(bus: &Bus, opts: &RecordOptions) -> Result<Recording, RecordError> {
    let subs = SensorSubscribers::open(bus)?;
    let waitset = bus.waitset()?;
    let attach = |l| {
        waitset
            .attach_notification(l)
            .map_err(|e| BusError::Service {
                service: "waitset".to_string(),
                action: "attach",
                detail: format!("{e:?}"),
            })
    };
    let _g1 = attach(subs.wheels.listener())?;
    let _g2 = attach(subs.gnss.listener())?;
    let _g3 = attach(subs.imu.listener())?;
    let _g4 = attach(subs.heading.listener())?;
    // A tick, so that a signal taken by another thread is noticed.
    let _tick = waitset
        .attach_interval(Duration::from_millis(100))
        .map_err(|e| BusError::Service {
            service: "waitset".to_string(),
            action: "attach interval",
            detail: format!("{e:?}"),
        })?;
    let mut builder = DriveBuilder::new(opts.vehicle.clone());
    let mut last_progress = Instant::now();
    // Topics whose publisher ended its stream; when the wheel stream ended.
    let mut ended = [false; 4];
    let mut wheels_ended_at: Option<Instant> = None;
    tracing::info!("recording every sensor topic; Ctrl-C ends the recording");
    loop {
        let result = waitset
            .wait_and_process_once(|_| CallbackProgression::Continue)
            .map_err(|e| BusError::Service {
                service: "waitset".to_string(),
                action: "wait",
                detail: format!("{e:?}"),
            })?;
        let outcome = subs.drain_into(&mut builder)?;
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
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::drive::GnssAntenna;
    use interfaces::wire::Header;

    fn vehicle() -> VehicleParams {
        VehicleParams {
            name: Some("t".into()),
            track_width_m: 1.5,
            nominal_circumference_m: 2.0,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: GnssAntenna::default(),
        }
    }

    #[test]
    fn builder_keeps_values_and_reports_what_it_skips() {
        let mut b = DriveBuilder::new(vehicle());
        let w = |t: f64, rl: f64| WheelRotations {
            header: Header::from_seconds(t, 0),
            rl_rev: rl,
            rr_rev: rl + 1.0,
            ..WheelRotations::default()
        };
        b.push_wheels(&w(0.0, 1.0));
        b.push_wheels(&w(0.1, 2.0));
        b.push_wheels(&w(0.1, 3.0)); // time not increasing
        b.push_wheels(&w(0.2, f64::NAN));
        b.push_gnss(&GnssFix {
            header: Header::from_seconds(0.0, 0),
            x_m: 1.0,
            y_m: 2.0,
            sigma_m: 0.0,
            fix: 1,
            _pad: [0; 7],
        });
        b.push_gnss(&GnssFix {
            header: Header::from_seconds(1.0, 0),
            fix: 0,
            ..GnssFix::default()
        });
        let warnings = b.warnings();
        assert_eq!(warnings.len(), 3, "{warnings:?}");
        assert!(warnings[0].contains("wheels: 1 samples not recorded: time"));
        assert!(warnings[2].contains("without fix"));
        let d = b.finish();
        assert_eq!(d.wheels.samples.len(), 2);
        assert_eq!(d.wheels.samples[1].rr, 3.0);
        assert_eq!(d.wheels.units, WheelUnits::rear(WheelUnit::Rev));
        assert_eq!(d.gnss.as_ref().unwrap()[0].sigma_m, None);
        assert!(d.imu.is_none());
    }
}
