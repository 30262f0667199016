//! One input at a time: samples checked, measurements queued, estimates
//! switched, and at every wheel sample the queued measurements applied at
//! their own times between predictions, and the pose given out.

use super::error::ProcessError;
use super::filter::{FusedPose, Fusion};
use super::queue::Measurement;
use super::state::State;
use crate::dead_reckoning::InputError;
use crate::inputs::Input;
use vehicle_model::two_wheel::{wrap_angle, Pose2};

impl Fusion {
    /// Take one input. Returns the pose after a wheel sample, `None` otherwise.
    /// An [`Input::Estimate`] switches the estimate as [`Fusion::set_estimate`].
    pub fn process(&mut self, input: &Input) -> Result<Option<FusedPose>, ProcessError> {
        match *input {
            Input::Imu { t_s, gz_rad_s } => {
                self.odometer.gyro(t_s, gz_rad_s)?;
                Ok(None)
            }
            Input::Gnss {
                t_s,
                x_m,
                y_m,
                sigma_m,
            } => {
                if !(t_s.is_finite() && x_m.is_finite() && y_m.is_finite()) {
                    return Err(InputError::NonFinite {
                        stream: "gnss",
                        t_s,
                    }
                    .into());
                }
                let sigma = sigma_m
                    .filter(|s| s.is_finite() && *s > 0.0)
                    .unwrap_or(self.config.default_gnss_sigma_m)
                    .max(self.config.min_gnss_sigma_m);
                self.push_pending(Measurement::Gnss {
                    t_s,
                    x_m,
                    y_m,
                    sigma_m: sigma,
                });
                Ok(None)
            }
            Input::Heading {
                t_s,
                yaw_rad,
                sigma_rad,
            } => {
                if !(t_s.is_finite() && yaw_rad.is_finite()) {
                    return Err(InputError::NonFinite {
                        stream: "heading",
                        t_s,
                    }
                    .into());
                }
                let sigma = sigma_rad
                    .filter(|s| s.is_finite() && *s > 0.0)
                    .unwrap_or(self.config.default_heading_sigma_rad);
                self.last_heading = Some((t_s, yaw_rad, sigma));
                self.push_pending(Measurement::Heading {
                    t_s,
                    yaw_rad,
                    sigma_rad: sigma,
                });
                Ok(None)
            }
            Input::Estimate {
                version, estimate, ..
            } => {
                // The antenna first: a bad one leaves the filter as it was.
                if let Some(antenna) = self.antenna_to_take(estimate.fusable_antenna()) {
                    self.set_lever_arm(antenna)?;
                }
                self.set_estimate(estimate.params, version);
                // The effect terms a diagnosis found travel with the estimate.
                self.set_effects(estimate.effects.into());
                Ok(None)
            }
            Input::Wheels {
                t_s,
                rl_rev,
                rr_rev,
            } => match self.wheels(t_s, rl_rev, rr_rev) {
                Ok(pose) => Ok(Some(pose)),
                Err(ProcessError::Numerical(e)) => {
                    self.reset();
                    Err(ProcessError::Numerical(e))
                }
                Err(e) => Err(e),
            },
        }
    }

    /// Queue a measurement until the wheel sample after it; without wheel
    /// samples the queue keeps only the newest
    /// [`MAX_PENDING`](super::queue::MAX_PENDING).
    fn push_pending(&mut self, m: Measurement) {
        if self.pending.push(m) {
            self.stats.dropped_late += 1;
        }
    }

    /// A wheel sample: the measurements queued up to it, each applied at its
    /// own time between predictions, then the prediction to it and its pose.
    fn wheels(&mut self, t1: f64, rl1: f64, rr1: f64) -> Result<FusedPose, ProcessError> {
        if !(t1.is_finite() && rl1.is_finite() && rr1.is_finite()) {
            return Err(InputError::NonFinite {
                stream: "wheels",
                t_s: t1,
            }
            .into());
        }
        if let Some((t0, _, _)) = self.last_wheels {
            if t1 <= t0 {
                return Err(InputError::OutOfOrder {
                    stream: "wheels",
                    t_s: t1,
                    previous_t_s: t0,
                }
                .into());
            }
            if t1 - t0 > self.config.stale_after_s {
                // The wheels stopped for a while: what happened in between is unknown.
                self.stats.stale += 1;
                self.reset();
            }
        }
        // Measurements up to t1, in time order, each at its own time.
        let measurements: Vec<Measurement> = self.pending.take_due(t1);
        for m in measurements {
            let tm = m.t_s();
            match self.last_wheels {
                Some((t0, rl0, rr0)) if tm > t0 => {
                    let f = (tm - t0) / (t1 - t0);
                    if tm < t1 {
                        self.advance(tm, rl0 + f * (rl1 - rl0), rr0 + f * (rr1 - rr0))?;
                    } else {
                        self.advance(t1, rl1, rr1)?;
                    }
                }
                Some((t0, _, _)) if t0 - tm > self.config.max_measurement_delay_s => {
                    self.stats.dropped_late += 1;
                    continue;
                }
                None if t1 - tm > self.config.max_measurement_delay_s => {
                    self.stats.dropped_late += 1;
                    continue;
                }
                None => self.advance(t1, rl1, rr1)?,
                Some(_) => {}
            }
            self.measure(&m)?;
        }
        if self.last_wheels.is_none_or(|(t0, _, _)| t0 < t1) {
            self.advance(t1, rl1, rr1)?;
        }
        Ok(self.output(t1))
    }

    /// Feed a wheel sample to the odometer and predict with its increment.
    fn advance(&mut self, t_s: f64, rl: f64, rr: f64) -> Result<(), ProcessError> {
        let increment = self.odometer.wheels(t_s, rl, rr)?;
        self.last_wheels = Some((t_s, rl, rr));
        if let Some(observation) = self.odometer.take_bias_observation() {
            self.stats.gyro_bias_standstills += 1;
            self.last_standstill_bias_s = Some(observation.t_s);
            self.observe_bias(&observation)?;
        }
        if let Some(inc) = increment {
            self.predict(&inc)?;
        }
        Ok(())
    }

    fn output(&self, t_s: f64) -> FusedPose {
        let mode = self.mode_at(t_s);
        let (pose, covariance) = match self.state {
            State::Running { x, p } => {
                let mut cov = [0.0; 9];
                for i in 0..3 {
                    for j in 0..3 {
                        cov[3 * i + j] = p[(i, j)];
                    }
                }
                (
                    Pose2 {
                        x: x[0],
                        y: x[1],
                        yaw: wrap_angle(x[2]),
                    },
                    cov,
                )
            }
            State::Uninitialised { .. } => (Pose2::default(), [0.0; 9]),
        };
        FusedPose {
            t_s,
            pose,
            covariance,
            mode,
            estimate_version: self.estimate_version,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dead_reckoning::HeadingMode;
    use crate::fusion::state::{StateMat, StateVec};
    use crate::fusion::test_support::{config, params};
    use interfaces::wire::PoseMode;

    #[test]
    fn non_finite_inputs_are_rejected_without_harm() {
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let err = fusion
            .process(&Input::Gnss {
                t_s: 0.0,
                x_m: f64::NAN,
                y_m: 0.0,
                sigma_m: None,
            })
            .unwrap_err();
        assert!(
            err.to_string().contains("gnss") && err.to_string().contains("non-finite"),
            "{err}"
        );
        assert!(matches!(
            fusion.process(&Input::Wheels {
                t_s: 0.0,
                rl_rev: f64::INFINITY,
                rr_rev: 0.0
            }),
            Err(ProcessError::Input(_))
        ));
    }

    #[test]
    fn broken_covariance_is_a_typed_error_not_a_panic() {
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        fusion.state = State::Running {
            x: StateVec::zeros(),
            p: StateMat::from_element(f64::NAN),
        };
        fusion
            .process(&Input::Gnss {
                t_s: 0.0,
                x_m: 0.0,
                y_m: 0.0,
                sigma_m: None,
            })
            .unwrap();
        let err = fusion
            .process(&Input::Wheels {
                t_s: 0.0,
                rl_rev: 0.0,
                rr_rev: 0.0,
            })
            .unwrap_err();
        assert!(matches!(err, ProcessError::Numerical(_)), "{err}");
        assert_eq!(
            fusion.mode_at(0.0),
            PoseMode::NoFix,
            "reset after the failure"
        );
    }
}
