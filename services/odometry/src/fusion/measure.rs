//! The measurement updates: GNSS positions of the antenna and absolute
//! headings, each tested against its chi-square gate, and the reset of the
//! position when fixes have been rejected for too long (the filter has lost
//! itself).

use super::error::FusionError;
use super::filter::Fusion;
use super::kalman::kalman_update;
use super::queue::Measurement;
use super::state::{State, N};
use nalgebra::{SMatrix, SVector};
use vehicle_model::two_wheel::{wrap_angle, Pose2};

impl Fusion {
    /// Apply a measurement at its time (the filter has been predicted to it).
    pub(super) fn measure(&mut self, m: &Measurement) -> Result<(), FusionError> {
        if let Measurement::Gnss {
            t_s,
            x_m,
            y_m,
            sigma_m,
        } = *m
        {
            let estimate = (!self.nominal).then(|| {
                (
                    self.estimate_version,
                    self.fresh_consider_variances()[0].sqrt(),
                )
            });
            self.scale_check
                .fix(t_s, x_m, y_m, sigma_m, self.config.lever_arm_m, estimate);
        }
        match (*m, self.state) {
            (
                Measurement::Gnss {
                    t_s,
                    x_m,
                    y_m,
                    sigma_m,
                },
                State::Uninitialised { anchor, local },
            ) => {
                self.initialise_from_fix(t_s, x_m, y_m, sigma_m, anchor, local);
                Ok(())
            }
            (Measurement::Heading { .. }, State::Uninitialised { .. }) => Ok(()),
            (
                Measurement::Gnss {
                    t_s,
                    x_m,
                    y_m,
                    sigma_m,
                },
                State::Running { .. },
            ) => self.update_gnss(t_s, x_m, y_m, sigma_m),
            (
                Measurement::Heading {
                    t_s,
                    yaw_rad,
                    sigma_rad,
                },
                State::Running { .. },
            ) => self.update_heading(t_s, yaw_rad, sigma_rad),
        }
    }

    fn update_gnss(
        &mut self,
        t_s: f64,
        x_m: f64,
        y_m: f64,
        sigma_m: f64,
    ) -> Result<(), FusionError> {
        let State::Running { x, p } = self.state else {
            return Ok(());
        };
        let [lx, ly] = self.config.lever_arm_m;
        let (s, c) = x[2].sin_cos();
        let predicted = [x[0] + lx * c - ly * s, x[1] + lx * s + ly * c];
        let nu = SVector::<f64, 2>::new(x_m - predicted[0], y_m - predicted[1]);
        let mut h = SMatrix::<f64, 2, N>::zeros();
        h[(0, 0)] = 1.0;
        h[(1, 1)] = 1.0;
        h[(0, 2)] = -lx * s - ly * c;
        h[(1, 2)] = lx * c - ly * s;
        let r = SMatrix::<f64, 2, 2>::identity() * sigma_m * sigma_m;
        let ph = p * h.transpose();
        let s_mat = h * ph + r;
        let chol = s_mat
            .cholesky()
            .ok_or(FusionError::NotPositiveDefinite { what: "gnss", t_s })?;
        let nis = nu.dot(&chol.solve(&nu));
        if !nis.is_finite() {
            return Err(FusionError::NonFinite {
                t_s,
                after: "gnss innovation",
            });
        }
        if nis > self.config.gnss_gate {
            self.stats.gnss_rejected += 1;
            self.rejected_in_a_row += 1;
            let first = *self.first_rejected_fix_s.get_or_insert(t_s);
            let lost = self.rejected_in_a_row >= 3
                && (self.resumed_unconfirmed || t_s - first >= self.config.reset_after_rejected_s);
            if lost {
                self.start_again_from_fix(t_s, x_m, y_m, sigma_m);
            }
            return Ok(());
        }
        let (x, p) = kalman_update(x, &p, &ph, &s_mat, &chol.inverse(), &nu);
        self.set_running(x, p, t_s, "gnss update")?;
        self.stats.gnss_accepted += 1;
        self.accept_fix(t_s);
        Ok(())
    }

    /// The fixes have been rejected in a row for long enough (or, after a
    /// resumed pose, three of them): the filter has lost itself, and its yaw
    /// is as suspect as its position (a wrong yaw makes every fix after it
    /// look wrong). Start again from the fix: at once with a recent heading,
    /// else `NoFix` until the GNSS track gives the yaw over a baseline.
    fn start_again_from_fix(&mut self, t_s: f64, x_m: f64, y_m: f64, sigma_m: f64) {
        let State::Running { x, .. } = self.state else {
            return;
        };
        let local = Pose2 {
            x: x[0],
            y: x[1],
            yaw: x[2],
        };
        self.state = State::Uninitialised {
            anchor: None,
            local,
        };
        self.last_accepted_fix_s = None;
        self.first_rejected_fix_s = None;
        self.rejected_in_a_row = 0;
        self.resumed_unconfirmed = false;
        self.stats.position_resets += 1;
        self.initialise_from_fix(t_s, x_m, y_m, sigma_m, None, local);
    }

    fn update_heading(
        &mut self,
        t_s: f64,
        yaw_rad: f64,
        sigma_rad: f64,
    ) -> Result<(), FusionError> {
        let State::Running { x, p } = self.state else {
            return Ok(());
        };
        let nu = SVector::<f64, 1>::new(wrap_angle(yaw_rad - x[2]));
        let mut h = SMatrix::<f64, 1, N>::zeros();
        h[(0, 2)] = 1.0;
        let r = SMatrix::<f64, 1, 1>::new(sigma_rad * sigma_rad);
        let ph = p * h.transpose();
        let s_mat = h * ph + r;
        let s = s_mat[(0, 0)];
        if !(s.is_finite() && s > 0.0) {
            return Err(FusionError::NotPositiveDefinite {
                what: "heading",
                t_s,
            });
        }
        if nu[0] * nu[0] / s > self.config.heading_gate {
            self.stats.heading_rejected += 1;
            self.headings_rejected_in_a_row += 1;
            let first = *self.first_rejected_heading_s.get_or_insert_with(|| {
                self.travelled_at_rejected_heading_m = self.travelled_m;
                t_s
            });
            // No fix accepted since the headings turned against the filter:
            // nothing says the yaw is right and they wrong.
            let fixes_agree = self.last_accepted_fix_s.is_some_and(|tf| tf >= first);
            if self.headings_rejected_in_a_row >= 5
                && t_s - first >= self.config.reset_after_rejected_s
                && !fixes_agree
            {
                self.take_yaw_from_heading(yaw_rad, sigma_rad, x, p);
            }
            return Ok(());
        }
        self.headings_rejected_in_a_row = 0;
        self.first_rejected_heading_s = None;
        let s_inverse = SMatrix::<f64, 1, 1>::new(1.0 / s);
        let (x, p) = kalman_update(x, &p, &ph, &s_mat, &s_inverse, &nu);
        self.set_running(x, p, t_s, "heading update")?;
        self.stats.heading_accepted += 1;
        Ok(())
    }

    /// The headings have been rejected in a row for long enough with no fix
    /// to back the filter's yaw: take the yaw from the heading. The
    /// position was dead-reckoned on the wrong yaw since the first rejected
    /// heading: its variance grows by the distance since then times the yaw
    /// change, squared (the chord that error can have swept).
    fn take_yaw_from_heading(
        &mut self,
        yaw_rad: f64,
        sigma_rad: f64,
        mut x: super::state::StateVec,
        mut p: super::state::StateMat,
    ) {
        let change = wrap_angle(yaw_rad - x[2]).abs();
        let distance = self.travelled_m - self.travelled_at_rejected_heading_m;
        let swept = (distance * change.min(std::f64::consts::PI)).powi(2);
        x[2] = wrap_angle(yaw_rad);
        for i in 0..N {
            p[(i, 2)] = 0.0;
            p[(2, i)] = 0.0;
        }
        p[(2, 2)] = sigma_rad * sigma_rad;
        p[(0, 0)] += swept;
        p[(1, 1)] += swept;
        self.state = State::Running { x, p };
        self.headings_rejected_in_a_row = 0;
        self.first_rejected_heading_s = None;
        self.stats.yaw_resets += 1;
    }
}

#[cfg(test)]
mod tests {
    use crate::dead_reckoning::HeadingMode;
    use crate::fusion::filter::Fusion;
    use crate::fusion::test_support::{config, params, run, simulate, Sim};
    use crate::inputs::Input;
    use interfaces::wire::PoseMode;
    use vehicle_model::two_wheel::wrap_angle;

    #[test]
    fn outlier_fixes_are_gated_and_a_lost_filter_resets() {
        let mut sim = simulate(40.0, &|_| true, 0.0, 0.0);
        // One wild fix at 15 s.
        for i in sim.inputs.iter_mut() {
            if let Input::Gnss { t_s, x_m, .. } = i {
                if (*t_s - 15.005).abs() < 1e-9 {
                    *x_m += 50.0;
                }
            }
        }
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let poses = run(&mut fusion, &sim.inputs);
        assert_eq!(fusion.stats().gnss_rejected, 1);
        assert!(poses.iter().all(|p| p.mode != PoseMode::DeadReckoning));
        // Now every fix after 20 s is shifted 30 m: gated at first, then a reset.
        let mut shifted = simulate(50.0, &|_| true, 0.0, 0.0);
        for i in shifted.inputs.iter_mut() {
            if let Input::Gnss { t_s, y_m, .. } = i {
                if *t_s > 20.0 {
                    *y_m += 30.0;
                }
            }
        }
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let poses = run(&mut fusion, &shifted.inputs);
        let s = fusion.stats();
        assert_eq!(s.position_resets, 1, "{s:?}");
        assert!(
            poses[2500].mode == PoseMode::DeadReckoning,
            "fixes gated out: dead-reckoning"
        );
        let last = poses.last().unwrap();
        let truth = shifted.truth.last().unwrap().1;
        assert!(
            (last.pose.y - truth.y - 30.0).abs() < 0.5,
            "follows the fixes after the reset"
        );
        assert_eq!(last.mode, PoseMode::Fused);
    }

    #[test]
    fn heading_initialises_at_the_first_fix_and_wrong_headings_are_gated() {
        let mut sim = simulate(20.0, &|_| true, 0.0, 2.5);
        let heading_at = |t: f64, sim: &Sim| sim.truth[(t / 0.01).round() as usize].1.yaw;
        let mut headings: Vec<Input> = (0..200)
            .map(|k| {
                let t = k as f64 * 0.1;
                let wrong = if k == 100 { 1.0 } else { 0.0 };
                Input::Heading {
                    t_s: t,
                    yaw_rad: wrap_angle(heading_at(t, &sim) + wrong),
                    sigma_rad: Some(0.02),
                }
            })
            .collect();
        sim.inputs.append(&mut headings);
        crate::inputs::sort_inputs(&mut sim.inputs);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let poses = run(&mut fusion, &sim.inputs);
        assert_eq!(poses[0].mode, PoseMode::NoFix, "before the first fix");
        assert_eq!(
            poses[1].mode,
            PoseMode::Fused,
            "heading + fix: initialised at the first fix"
        );
        assert_eq!(fusion.stats().heading_rejected, 1);
        assert!(fusion.stats().heading_accepted > 150);
    }

    /// A resumed pose with the yaw 2.9 rad off and the position 800 m off
    /// (a car powered on somewhere else): three rejected fixes start the
    /// filter again from the fixes, and it never publishes a pose further
    /// from the truth than its own 3-sigma once GNSS has been judged.
    #[test]
    fn a_wrong_resumed_pose_is_given_up_for_the_fixes() {
        let sim = simulate(60.0, &|_| true, 0.0, 0.3);
        for heading in [HeadingMode::WheelDifference, HeadingMode::Gyro] {
            let mut fusion = Fusion::new(params(), 0, config(heading));
            let start = sim.truth[0].1;
            let wrong = vehicle_model::two_wheel::Pose2 {
                x: start.x + 600.0,
                y: start.y - 530.0,
                yaw: wrap_angle(start.yaw + 2.9),
            };
            let tight = [0.25, 0.0, 0.0, 0.0, 0.25, 0.0, 0.0, 0.0, 4e-4];
            fusion.resume(wrong, &tight).expect("resume");
            let poses = run(&mut fusion, &sim.inputs);
            let s = fusion.stats();
            assert_eq!(s.position_resets, 1, "{heading:?}: {s:?}");
            // Fixes at 5 Hz: the third rejected one is at 0.4 s; the GNSS
            // baseline of 5 m takes half a second more.
            for (pose, (t, truth)) in poses.iter().zip(&sim.truth) {
                if *t > 1.5 {
                    assert_eq!(pose.mode, PoseMode::Fused, "{heading:?} t = {t}");
                    let e = (pose.pose.x - truth.x).hypot(pose.pose.y - truth.y);
                    let sigma = pose.covariance[0].max(pose.covariance[4]).sqrt();
                    assert!(
                        e < 3.0 * sigma.max(0.1) && e < 1.0,
                        "{heading:?} t = {t}: {e} m"
                    );
                    assert!(wrap_angle(pose.pose.yaw - truth.yaw).abs() < 0.05);
                }
            }
        }
    }

    /// Without GNSS, a compass that keeps disagreeing with the yaw (a resumed
    /// pose turned round) wins after `reset_after_rejected_s`, and the
    /// position's covariance grows by what the wrong yaw may have swept.
    #[test]
    fn headings_rejected_in_a_row_without_fixes_take_over_the_yaw() {
        let mut sim = simulate(40.0, &|_| false, 0.0, 0.2);
        let heading_at = |t: f64, sim: &Sim| sim.truth[(t / 0.01).round() as usize].1.yaw;
        let mut headings: Vec<Input> = (1..400)
            .map(|k| {
                let t = k as f64 * 0.1;
                Input::Heading {
                    t_s: t,
                    yaw_rad: wrap_angle(heading_at(t, &sim)),
                    sigma_rad: Some(0.02),
                }
            })
            .collect();
        sim.inputs.append(&mut headings);
        crate::inputs::sort_inputs(&mut sim.inputs);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let start = sim.truth[0].1;
        let turned = vehicle_model::two_wheel::Pose2 {
            yaw: wrap_angle(start.yaw + 3.0),
            ..start
        };
        let tight = [0.25, 0.0, 0.0, 0.0, 0.25, 0.0, 0.0, 0.0, 4e-4];
        fusion.resume(turned, &tight).expect("resume");
        let poses = run(&mut fusion, &sim.inputs);
        let s = fusion.stats();
        assert_eq!(s.yaw_resets, 1, "{s:?}");
        let at = |t: f64| ((t / 0.01).round()) as usize;
        let after = &poses[at(12.0)];
        let truth = sim.truth[at(12.0)].1;
        assert!(wrap_angle(after.pose.yaw - truth.yaw).abs() < 0.05);
        // About 100 m driven on a yaw 3 rad off: the position is that far
        // off, and its covariance says so.
        let e = (after.pose.x - truth.x).hypot(after.pose.y - truth.y);
        let sigma = after.covariance[0].max(after.covariance[4]).sqrt();
        assert!(e > 50.0 && e < 3.0 * sigma, "{e} m against sigma {sigma} m");
    }
}
