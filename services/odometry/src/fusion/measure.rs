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
use vehicle_model::two_wheel::wrap_angle;

impl Fusion {
    /// Apply a measurement at its time (the filter has been predicted to it).
    pub(super) fn measure(&mut self, m: &Measurement) -> Result<(), FusionError> {
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
            if self.rejected_in_a_row >= 3 && t_s - first >= self.config.reset_after_rejected_s {
                self.reset_position(t_s, x_m, y_m, sigma_m);
            }
            return Ok(());
        }
        let (x, p) = kalman_update(x, &p, &ph, &s_mat, &chol.inverse(), &nu);
        self.set_running(x, p, t_s, "gnss update")?;
        self.stats.gnss_accepted += 1;
        self.accept_fix(t_s);
        Ok(())
    }

    fn reset_position(&mut self, t_s: f64, x_m: f64, y_m: f64, sigma_m: f64) {
        if let State::Running { x, p } = &mut self.state {
            let [lx, ly] = self.config.lever_arm_m;
            let (s, c) = x[2].sin_cos();
            x[0] = x_m - (lx * c - ly * s);
            x[1] = y_m - (lx * s + ly * c);
            let var = (sigma_m + 0.5 * lx.hypot(ly)).powi(2);
            for i in 0..N {
                for j in 0..2 {
                    p[(i, j)] = 0.0;
                    p[(j, i)] = 0.0;
                }
            }
            p[(0, 0)] = var;
            p[(1, 1)] = var;
            p[(2, 2)] = p[(2, 2)].max(0.1f64.powi(2));
            self.stats.position_resets += 1;
            self.accept_fix(t_s);
        }
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
            return Ok(());
        }
        let s_inverse = SMatrix::<f64, 1, 1>::new(1.0 / s);
        let (x, p) = kalman_update(x, &p, &ph, &s_mat, &s_inverse, &nu);
        self.set_running(x, p, t_s, "heading update")?;
        self.stats.heading_accepted += 1;
        Ok(())
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
}
