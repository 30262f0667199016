//! The service's subscribers, and what is drained from them: the sensor
//! samples (restamped by the sensor clocks) and the estimates that pass the
//! gate, into the [`Sequencer`].

use super::clocks::describe_clocks;
use interfaces::bus::{Bus, BusError, TopicSubscriber};
use interfaces::wire::{CircumferenceEstimate, GnssFix, Heading, Imu, WheelRotations};
use odometry::inputs::{GnssEpochs, Input, Sequencer};
use std::cell::{Cell, RefCell};
use vehicle_model::estimate::{Estimate, StreamClocks};
use vehicle_model::estimate_gate::EstimateGate;

/// The subscribers of the service, and what taking an estimate keeps.
pub(crate) struct Inputs {
    pub(crate) wheels: TopicSubscriber<WheelRotations>,
    pub(crate) gnss: TopicSubscriber<GnssFix>,
    pub(crate) imu: TopicSubscriber<Imu>,
    pub(crate) heading: TopicSubscriber<Heading>,
    pub(crate) estimate: TopicSubscriber<CircumferenceEstimate>,
    /// What an estimate from the bus must pass before it is used.
    pub(crate) gate: RefCell<EstimateGate>,
    /// The sensor clocks of the estimate in use: the wheel and IMU stamps
    /// are put on the GNSS clock with them as they are drained.
    pub(crate) clocks: Cell<StreamClocks>,
    /// The fixes read at the receiver's epochs as they come.
    pub(crate) gnss_epochs: RefCell<GnssEpochs>,
}

impl Inputs {
    pub(crate) fn open(bus: &Bus, gate: EstimateGate) -> Result<Inputs, BusError> {
        Ok(Inputs {
            wheels: bus.subscriber()?,
            gnss: bus.subscriber()?,
            imu: bus.subscriber()?,
            heading: bus.subscriber()?,
            estimate: bus.subscriber()?,
            gate: RefCell::new(gate),
            clocks: Cell::new(StreamClocks::default()),
            gnss_epochs: RefCell::new(GnssEpochs::new()),
        })
    }

    pub(crate) fn lost(&self) -> [u64; 5] {
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
    pub(crate) fn drain(&self, sequencer: &mut Sequencer) -> Result<(), BusError> {
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
            sequencer.push(self.gnss_epochs.borrow_mut().read(Input::Gnss {
                t_s: s.header.t_s(),
                x_m: s.x_m,
                y_m: s.y_m,
                sigma_m: (s.sigma_m > 0.0).then_some(s.sigma_m),
            }));
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
    pub(crate) fn wheel_notifications(&self) -> Result<(bool, bool), BusError> {
        let ended = self.wheels.take_notifications()?.end_of_stream;
        Ok((ended, self.wheels.has_samples()?))
    }

    /// After the poses: with `estimate`, the estimate topic's notifications
    /// and samples (into `sequencer`, taken at the next release, between two
    /// wheel samples); with `side_events`, the notifications of the IMU, GNSS
    /// and heading topics. Returns how many estimates were rejected.
    pub(crate) fn housekeeping(
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
