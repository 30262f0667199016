//! Collecting wire samples into a [`Drive`]: [`DriveBuilder`], pure (no bus,
//! no clock), used by `sensor-bridge record` and by the calibrator's service.
//!
//! The wire carries no vehicle parameters: they come from the caller.
//! Wheels are collected as cumulative revolutions (`_rev`).

use crate::drive::{
    Drive, GnssSample, HeadingSample, ImuSample, VehicleParams, WheelSample, WheelSeries,
    WheelUnit, WheelUnits,
};
use crate::wire::{GnssFix, Heading, Imu, WheelRotations};

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

/// The sensor streams in the order of every per-stream array here:
/// wheels, GNSS, IMU, heading.
pub const NAMES: [&str; 4] = ["wheels", "gnss", "imu", "heading"];

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::GnssAntenna;
    use crate::wire::Header;

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
