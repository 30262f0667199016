//! The four sensor subscribers (wheels, GNSS, IMU, heading) opened and
//! drained together into a [`DriveBuilder`]: what `sensor-bridge record` and
//! `calibrator serve` both collect a drive with.

use crate::bus::{self, Bus, BusError, Ipc, TopicSubscriber};
use crate::collect::DriveBuilder;
use crate::wire::{GnssFix, Heading, Imu, WheelRotations};
use iceoryx2::prelude::{WaitSet, WaitSetGuard};

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

    /// Attach all four listeners to a service loop's WaitSet: a sample on any
    /// sensor topic wakes the loop. Keep the guards as long as the loop runs.
    pub fn wake_on_all<'w, 'a>(
        &'a self,
        waitset: &'w WaitSet<Ipc>,
    ) -> Result<[WaitSetGuard<'w, 'a, Ipc>; 4], BusError> {
        Ok([
            bus::wake_on(waitset, "attach wheels", self.wheels.listener())?,
            bus::wake_on(waitset, "attach gnss", self.gnss.listener())?,
            bus::wake_on(waitset, "attach imu", self.imu.listener())?,
            bus::wake_on(waitset, "attach heading", self.heading.listener())?,
        ])
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
