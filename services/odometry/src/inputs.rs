//! The odometry's inputs as one time-ordered stream.
//!
//! The service and the offline tools process samples in the same order:
//! by time, and at equal times IMU, GNSS, heading and estimate before the
//! wheels, so that a wheel sample sees every other sample of its instant.
//! A publisher that sends in that order (the bridge's replay does) therefore
//! gives the same result whatever the scheduling of the processes, provided
//! the service processes exactly that order: [`Sequencer`] sees to it when
//! the samples arrive in batches (wakeups) that cut through an instant.

use interfaces::drive::{Drive, WheelConversionError};
use vehicle_model::estimate::Estimate;

/// One input sample of the odometry.
// The estimate (with its sensor clocks) makes one variant large; estimates
// are rare and `Input` is `Copy` in the filter's log, so it stays unboxed.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Input {
    /// A yaw-rate sample.
    Imu {
        /// Time, s.
        t_s: f64,
        /// Raw yaw rate, rad/s.
        gz_rad_s: f64,
    },
    /// A GNSS fix in local ENU (of the antenna).
    Gnss {
        /// Time, s.
        t_s: f64,
        /// East, m.
        x_m: f64,
        /// North, m.
        y_m: f64,
        /// Horizontal 1-sigma, m, when given.
        sigma_m: Option<f64>,
    },
    /// An absolute heading.
    Heading {
        /// Time, s.
        t_s: f64,
        /// Yaw, rad.
        yaw_rad: f64,
        /// 1-sigma, rad, when given.
        sigma_rad: Option<f64>,
    },
    /// A new calibration to use from now on.
    Estimate {
        /// Time it arrived at, s on the drive clock.
        t_s: f64,
        /// Its version (increases with every accepted estimate).
        version: u64,
        /// The estimate.
        estimate: Estimate,
    },
    /// Cumulative revolutions of the rear wheels.
    Wheels {
        /// Time, s.
        t_s: f64,
        /// Rear-left cumulative revolutions.
        rl_rev: f64,
        /// Rear-right cumulative revolutions.
        rr_rev: f64,
    },
}

impl Input {
    /// Time of the sample, s.
    pub fn t_s(&self) -> f64 {
        match *self {
            Input::Imu { t_s, .. }
            | Input::Gnss { t_s, .. }
            | Input::Heading { t_s, .. }
            | Input::Estimate { t_s, .. }
            | Input::Wheels { t_s, .. } => t_s,
        }
    }

    /// Order among samples of the same time (wheels last).
    pub fn rank(&self) -> u8 {
        match self {
            Input::Imu { .. } => 0,
            Input::Gnss { .. } => 1,
            Input::Heading { .. } => 2,
            Input::Estimate { .. } => 3,
            Input::Wheels { .. } => 4,
        }
    }
}

/// Sort inputs into processing order (stable: equal keys keep their order).
pub fn sort_inputs(inputs: &mut [Input]) {
    inputs.sort_by(|a, b| a.t_s().total_cmp(&b.t_s()).then(a.rank().cmp(&b.rank())));
}

/// Sort inputs that are in processing order into the order they are
/// delivered in when each comes `late(input)` seconds after its time (a GNSS
/// receiver's latency, say). Stable: equal delivery times keep the
/// processing order. What [`crate::rewind`] puts back in order.
pub fn sort_by_delivery(inputs: &mut [Input], late: impl Fn(&Input) -> f64) {
    inputs.sort_by(|a, b| (a.t_s() + late(a)).total_cmp(&(b.t_s() + late(b))));
}

/// Every fix `gnss_late_s` late, every other sample on time: a `late` for
/// [`sort_by_delivery`].
pub fn gnss_late(gnss_late_s: f64) -> impl Fn(&Input) -> f64 {
    move |input: &Input| match input {
        Input::Gnss { .. } => gnss_late_s,
        _ => 0.0,
    }
}

/// Samples a [`Sequencer`] holds at most; beyond it the oldest are dropped
/// (and counted). Far more than one wakeup brings (the bus buffers 1024
/// samples per topic), so it only bites when the wheel stream is gone while
/// the other streams go on.
pub const MAX_HELD: usize = 16_384;

/// Index of a sample's stream (IMU, GNSS, heading, wheels; estimates have none).
fn stream_of(input: &Input) -> Option<usize> {
    match input {
        Input::Imu { .. } => Some(0),
        Input::Gnss { .. } => Some(1),
        Input::Heading { .. } => Some(2),
        Input::Wheels { .. } => Some(3),
        Input::Estimate { .. } => None,
    }
}

/// Puts samples that arrive in batches into processing order, so that the
/// order never depends on how the arrivals were grouped.
///
/// A batch (one wakeup) may end in the middle of an instant: a heading of
/// time t can arrive in one batch and the fix of the same t (which is
/// processed before it) in the next, both ahead of the wheel sample of t.
/// Processing each batch on its own would then apply them in arrival order.
/// The sequencer releases samples only up to and including the newest wheel
/// sample it holds, sorted ([`sort_inputs`]); later samples are held until a
/// wheel sample passes them. Wheel samples are never held back, so the pose
/// comes as early as before and a missing, ended or dead stream stalls
/// nothing.
///
/// Exactness condition: every sample is published before any wheel sample
/// later than it (a single publisher sending in time order, as the bridge's
/// replay does, with wheels drained first in each wakeup). A sample that
/// comes after its wheel sample was released (separate publishers with
/// different latencies) is released with the next one; the filter applies it
/// late or drops it (`FusionConfig::max_measurement_delay_s`).
///
/// A stream whose time goes back by more than `restart_backstep_s` (its
/// publisher restarted) makes the held samples of the old run go: those of
/// that stream, and for the wheels every sample held beyond the new time.
#[derive(Debug, Clone)]
pub struct Sequencer {
    held: Vec<Input>,
    newest: [Option<f64>; 4],
    restart_backstep_s: f64,
    dropped_full: u64,
    dropped_restart: u64,
}

impl Sequencer {
    /// An empty sequencer; see the type doc for `restart_backstep_s`.
    pub fn new(restart_backstep_s: f64) -> Sequencer {
        Sequencer {
            held: Vec::new(),
            newest: [None; 4],
            restart_backstep_s,
            dropped_full: 0,
            dropped_restart: 0,
        }
    }

    /// Take one sample that arrived.
    pub fn push(&mut self, input: Input) {
        if let Some(k) = stream_of(&input) {
            let t = input.t_s();
            if let Some(newest) = self.newest[k] {
                if t < newest - self.restart_backstep_s {
                    let before = self.held.len();
                    if k == 3 {
                        let limit = t + self.restart_backstep_s;
                        self.held.retain(|h| h.t_s() <= limit);
                    } else {
                        self.held.retain(|h| stream_of(h) != Some(k));
                    }
                    self.dropped_restart += (before - self.held.len()) as u64;
                    self.newest[k] = Some(t);
                }
            }
            self.newest[k] = Some(self.newest[k].map_or(t, |n| n.max(t)));
        }
        self.held.push(input);
    }

    /// Append to `out`, in processing order, every held sample up to and
    /// including the newest wheel sample; keep the rest. Estimates (taken
    /// between two samples, whenever they come: time -inf) are released at
    /// once, also without a wheel sample. Returns how many were appended.
    pub fn release(&mut self, out: &mut Vec<Input>) -> usize {
        sort_inputs(&mut self.held);
        let estimates = self
            .held
            .iter()
            .take_while(|i| matches!(i, Input::Estimate { .. }))
            .count();
        let ready = self
            .held
            .iter()
            .rposition(|i| matches!(i, Input::Wheels { .. }))
            .map_or(estimates, |last| (last + 1).max(estimates));
        out.extend(self.held.drain(..ready));
        if self.held.len() > MAX_HELD {
            let excess = self.held.len() - MAX_HELD;
            self.held.drain(..excess);
            self.dropped_full += excess as u64;
        }
        ready
    }

    /// Samples held (waiting for a wheel sample).
    pub fn held(&self) -> usize {
        self.held.len()
    }

    /// Samples dropped because more than [`MAX_HELD`] waited for a wheel sample.
    pub fn dropped_full(&self) -> u64 {
        self.dropped_full
    }

    /// Held samples of a publisher's earlier run dropped when it restarted.
    pub fn dropped_on_restart(&self) -> u64 {
        self.dropped_restart
    }
}

/// Every sample of a drive that the odometry reads (never `truth`), in
/// processing order, as the service reads them: wheel values become
/// cumulative revolutions, and GNSS fixes a logger stamped when they
/// arrived are read at the receiver's epochs as they come
/// ([`GnssEpochs`]).
pub fn drive_inputs(drive: &Drive) -> Result<Vec<Input>, WheelConversionError> {
    drive_inputs_with(drive, true)
}

/// [`drive_inputs`] with every GNSS fix at its stamp (what the service read
/// before it took the epochs; for comparisons).
pub fn drive_inputs_at_stamps(drive: &Drive) -> Result<Vec<Input>, WheelConversionError> {
    drive_inputs_with(drive, false)
}

/// GNSS fixes read at the receiver's epochs as they come, in the odometry's
/// terms: [`stats::stamps::LiveEpochs`] on each fix's stamp and position.
/// The service and [`drive_inputs`] put every fix through one, in the
/// order of its stamps, before the fix is sequenced.
#[derive(Debug, Clone, Default)]
pub struct GnssEpochs(stats::stamps::LiveEpochs);

impl GnssEpochs {
    /// No fix seen yet.
    pub fn new() -> GnssEpochs {
        GnssEpochs::default()
    }

    /// `input` with its time at the fix's epoch where it is read there; any
    /// other input as it is.
    pub fn read(&mut self, mut input: Input) -> Input {
        if let Input::Gnss { t_s, x_m, y_m, .. } = &mut input {
            *t_s = self.0.push(*t_s, *x_m, *y_m);
        }
        input
    }

    /// Fixes read at an epoch, fixes seen, and the RMS of the stamps'
    /// departures from the epochs, s.
    pub fn counts(&self) -> (u64, u64, f64) {
        (self.0.moved(), self.0.seen(), self.0.jitter_rms_s())
    }
}

fn drive_inputs_with(drive: &Drive, epochs: bool) -> Result<Vec<Input>, WheelConversionError> {
    let revs = drive.wheel_revolutions()?;
    let mut inputs: Vec<Input> = Vec::with_capacity(
        revs.len()
            + drive.imu.as_ref().map_or(0, Vec::len)
            + drive.gnss.as_ref().map_or(0, Vec::len)
            + drive.heading.as_ref().map_or(0, Vec::len),
    );
    inputs.extend(revs.iter().map(|r| Input::Wheels {
        t_s: r.t_s,
        rl_rev: r.rl,
        rr_rev: r.rr,
    }));
    for s in drive.imu.iter().flatten() {
        inputs.push(Input::Imu {
            t_s: s.t_s,
            gz_rad_s: s.gz_rad_s,
        });
    }
    let mut reader = GnssEpochs::new();
    for s in drive.gnss.iter().flatten() {
        let fix = Input::Gnss {
            t_s: s.t_s,
            x_m: s.x_m,
            y_m: s.y_m,
            sigma_m: s.sigma_m,
        };
        inputs.push(if epochs { reader.read(fix) } else { fix });
    }
    for s in drive.heading.iter().flatten() {
        inputs.push(Input::Heading {
            t_s: s.t_s,
            yaw_rad: s.yaw_rad,
            sigma_rad: s.sigma_rad,
        });
    }
    sort_inputs(&mut inputs);
    Ok(inputs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_times_put_wheels_last() {
        let mut v = vec![
            Input::Wheels {
                t_s: 1.0,
                rl_rev: 0.0,
                rr_rev: 0.0,
            },
            Input::Imu {
                t_s: 1.0,
                gz_rad_s: 0.0,
            },
            Input::Gnss {
                t_s: 0.5,
                x_m: 0.0,
                y_m: 0.0,
                sigma_m: None,
            },
        ];
        sort_inputs(&mut v);
        let ranks: Vec<u8> = v.iter().map(Input::rank).collect();
        assert_eq!(ranks, vec![1, 0, 4]);
    }

    /// A drive's worth of samples in publishing order: per 10 ms wheels,
    /// IMU, and every 100 ms a fix and a heading of the wheel's instant (ties
    /// published heading first, to show that arrival order does not matter).
    fn published() -> Vec<Input> {
        let mut v = Vec::new();
        for i in 0..300 {
            let t = i as f64 * 0.01;
            v.push(Input::Imu {
                t_s: t + 0.003,
                gz_rad_s: 0.01 * i as f64,
            });
            if i % 10 == 0 {
                v.push(Input::Heading {
                    t_s: t,
                    yaw_rad: 0.1,
                    sigma_rad: None,
                });
                v.push(Input::Gnss {
                    t_s: t,
                    x_m: i as f64,
                    y_m: 0.0,
                    sigma_m: None,
                });
            }
            v.push(Input::Wheels {
                t_s: t,
                rl_rev: i as f64,
                rr_rev: i as f64,
            });
        }
        v
    }

    #[test]
    fn sequencer_order_does_not_depend_on_the_batching() {
        let arrivals = published();
        let mut expected = arrivals.clone();
        sort_inputs(&mut expected);
        // Batches of every size from 1 to 40, and an irregular pattern.
        let mut patterns: Vec<Vec<usize>> = (1..=40).map(|n| vec![n]).collect();
        patterns.push(vec![1, 7, 2, 13, 3, 1, 1, 29]);
        for pattern in patterns {
            let mut seq = Sequencer::new(1.0);
            let mut out = Vec::new();
            let mut rest = arrivals.as_slice();
            let mut k = 0;
            while !rest.is_empty() {
                let n = pattern[k % pattern.len()].min(rest.len());
                k += 1;
                for input in &rest[..n] {
                    seq.push(*input);
                }
                rest = &rest[n..];
                seq.release(&mut out);
                // Nothing released may lie beyond the newest wheel sample.
                let last_wheel = out.iter().rev().find(|i| i.rank() == 4).map(Input::t_s);
                assert!(out.last().map(Input::t_s) <= last_wheel);
            }
            // The last wheel sample ends the drive; the IMU sample after it stays held.
            assert_eq!(seq.held(), 1, "pattern {pattern:?}");
            assert_eq!(out, expected[..expected.len() - 1], "pattern {pattern:?}");
        }
    }

    #[test]
    fn sequencer_drops_held_samples_of_a_restarted_publisher_and_caps_its_size() {
        let wheels = |t_s: f64| Input::Wheels {
            t_s,
            rl_rev: 0.0,
            rr_rev: 0.0,
        };
        let imu = |t_s: f64| Input::Imu { t_s, gz_rad_s: 0.0 };
        let mut seq = Sequencer::new(1.0);
        let mut out = Vec::new();
        for input in [imu(99.0), wheels(99.0), imu(99.5), imu(99.6)] {
            seq.push(input);
        }
        assert_eq!(seq.release(&mut out), 2);
        assert_eq!(seq.held(), 2);
        // A new run: the IMU starts again (its old held samples go), then the wheels.
        seq.push(imu(0.0));
        assert_eq!((seq.held(), seq.dropped_on_restart()), (1, 2));
        seq.push(wheels(0.0));
        assert_eq!(seq.release(&mut out), 2);
        assert_eq!(out[2..], [imu(0.0), wheels(0.0)]);
        // Without wheel samples the held samples are capped.
        for i in 0..MAX_HELD + 10 {
            seq.push(imu(1.0 + i as f64 * 1e-3));
        }
        assert_eq!(seq.release(&mut out), 0);
        assert_eq!((seq.held(), seq.dropped_full()), (MAX_HELD, 10));
        // An estimate is released at once, without a wheel sample.
        let estimate = Input::Estimate {
            t_s: f64::NEG_INFINITY,
            version: 1,
            estimate: vehicle_model::estimate::Estimate {
                params: vehicle_model::estimate::OdometryParams {
                    two_wheel: vehicle_model::two_wheel::TwoWheelParams {
                        c_rl: 2.0,
                        c_rr: 2.0,
                        track_width: 1.5,
                    },
                    gyro_bias_rad_s: 0.0,
                    gyro_scale: 0.0,
                },
                sigma_m: None,
                quality_m: None,
                antenna_m: None,
                antenna_sigma_m: None,
                effects: vehicle_model::effects::WheelEffects::default(),
                clocks: Default::default(),
            },
        };
        seq.push(estimate);
        assert_eq!(seq.release(&mut out), 1);
        assert_eq!(out.last(), Some(&estimate));
        assert_eq!(seq.held(), MAX_HELD);
    }
}
