//! The odometry's inputs as one time-ordered stream.
//!
//! The service and the offline tools process samples in the same order:
//! by time, and at equal times IMU, GNSS, heading and estimate before the
//! wheels, so that a wheel sample sees every other sample of its instant.
//! A publisher that sends in that order (the bridge's replay does) therefore
//! gives the same result whatever the scheduling of the processes.

use crate::estimate_file::Estimate;
use interfaces::drive::{Drive, WheelConversionError};

/// One input sample of the odometry.
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

/// Every sample of a drive that the odometry reads (never `truth`), in
/// processing order. Wheel values become cumulative revolutions.
pub fn drive_inputs(drive: &Drive) -> Result<Vec<Input>, WheelConversionError> {
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
    for s in drive.gnss.iter().flatten() {
        inputs.push(Input::Gnss {
            t_s: s.t_s,
            x_m: s.x_m,
            y_m: s.y_m,
            sigma_m: s.sigma_m,
        });
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
}
