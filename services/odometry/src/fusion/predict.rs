//! The prediction: the odometer's increment (distance, yaw change and,
//! with a side-slip term, the slip angle between heading and motion)
//! stepped with the 2W model, the residual gyro bias taken off gyro
//! increments, and the covariance grown by the increment's noise, the bias
//! walk and the two consider states.

use super::error::FusionError;
use super::filter::Fusion;
use super::kalman::propagate_covariance;
use super::state::{all_finite, State};
use crate::dead_reckoning::{HeadingMode, HeadingSource, Increment};

impl Fusion {
    /// Step the state with an increment of the odometer.
    pub(super) fn predict(&mut self, inc: &Increment) -> Result<(), FusionError> {
        let config = self.config;
        let scale = 1.0 + self.odometer.params().gyro_scale;
        let track = self.odometer.params().two_wheel.track_width;
        self.travelled_m += inc.ds_m.abs();
        if let State::Uninitialised { .. } = self.state {
            self.scale_check.predicted(
                inc.ds_m,
                inc.dyaw_rad,
                inc.beta_rad,
                inc.t1_s - inc.t0_s,
                config.distance_noise_frac * inc.ds_m.abs(),
            );
        }
        match &mut self.state {
            State::Uninitialised { local, .. } => {
                *local =
                    vehicle_model::two_wheel::step(*local, inc.ds_m, inc.dyaw_rad, inc.beta_rad);
                Ok(())
            }
            State::Running { x, p } => {
                let dt = inc.t1_s - inc.t0_s;
                let gyro = inc.heading_source == HeadingSource::Gyro;
                // d(dyaw)/d(b): the residual bias is subtracted from gyro increments only.
                let dyaw_db = if gyro { -dt / scale } else { 0.0 };
                let dyaw = inc.dyaw_rad + dyaw_db * x[3];
                self.scale_check.predicted(
                    inc.ds_m,
                    dyaw,
                    inc.beta_rad,
                    inc.t1_s - inc.t0_s,
                    config.distance_noise_frac * inc.ds_m.abs(),
                );
                // The car moves along its heading plus the side-slip angle
                // (0 unless the estimate carries a side-slip term).
                let course = x[2] + 0.5 * dyaw + inc.beta_rad;
                let (s, c) = course.sin_cos();
                let ds = inc.ds_m;
                // The scale state is always 0 (never estimated): ds as measured.
                x[0] += ds * c;
                x[1] += ds * s;
                x[2] += dyaw;
                // The Jacobian F = I + E: E's rows x, y, yaw over the
                // columns yaw, bias, scale, wheel difference.
                let mut e = [[0.0; 4]; 3];
                e[0][0] = -ds * s;
                e[1][0] = ds * c;
                e[0][1] = -ds * s * 0.5 * dyaw_db;
                e[1][1] = ds * c * 0.5 * dyaw_db;
                e[2][1] = dyaw_db;
                e[0][2] = ds * c;
                e[1][2] = ds * s;
                // A common scale error of both wheels scales their heading
                // difference too; the gyro's heading does not see it.
                e[2][2] = if gyro { 0.0 } else { inc.dyaw_rad };
                // A relative circumference error e turns the wheel-difference
                // heading by e ds / track (and the course of this step by half).
                if !gyro {
                    let dyaw_de = ds / track;
                    e[0][3] = -ds * s * 0.5 * dyaw_de;
                    e[1][3] = ds * c * 0.5 * dyaw_de;
                    e[2][3] = dyaw_de;
                }
                // Noise of (ds, dyaw) mapped into the pose, G diag(.) G^T with
                // G's rows (c, -ds s / 2), (s, ds c / 2), (0, 1); plus the bias walk.
                let sigma_ds = config.distance_noise_frac * ds.abs();
                let sigma_dyaw = if gyro {
                    config.gyro_noise_rad_per_sqrt_s * dt.max(0.0).sqrt()
                } else {
                    config.wheel_yaw_noise_rad_per_m * ds.abs()
                };
                let g = [[c, -0.5 * ds * s], [s, 0.5 * ds * c], [0.0, 1.0]];
                let (var_ds, var_dyaw) = (sigma_ds * sigma_ds, sigma_dyaw * sigma_dyaw);
                let q_pose = std::array::from_fn(|i| {
                    std::array::from_fn(|j| {
                        g[i][0] * g[j][0] * var_ds + g[i][1] * g[j][1] * var_dyaw
                    })
                });
                let q_bias = if config.odometer.heading == HeadingMode::Gyro {
                    config.gyro_bias_walk.powi(2) * dt.max(0.0)
                } else {
                    0.0
                };
                *p = propagate_covariance(p, &e, &q_pose, q_bias);
                if !all_finite(x, p) {
                    return Err(FusionError::NonFinite {
                        t_s: inc.t1_s,
                        after: "prediction",
                    });
                }
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::dead_reckoning::HeadingMode;
    use crate::fusion::config::FusionConfig;
    use crate::fusion::filter::Fusion;
    use crate::fusion::kalman::{position_chi2, CHI2_2DOF_95};
    use crate::fusion::test_support::{config, params, run, simulate};
    use crate::inputs::Input;
    use interfaces::wire::PoseMode;
    use vehicle_model::two_wheel::Pose2;

    /// `inputs` with the rear-left and rear-right revolutions divided by
    /// `rl` and `rr`: wheels larger than the parameters say by those factors.
    fn with_larger_wheels(inputs: &[Input], rl: f64, rr: f64) -> Vec<Input> {
        inputs
            .iter()
            .map(|i| match *i {
                Input::Wheels {
                    t_s,
                    rl_rev,
                    rr_rev,
                } => Input::Wheels {
                    t_s,
                    rl_rev: rl_rev / rl,
                    rr_rev: rr_rev / rr,
                },
                other => other,
            })
            .collect()
    }

    #[test]
    fn after_an_outage_on_wheels_half_a_percent_off_the_first_fixes_are_taken() {
        // The calibration says 2.0 m; the wheels are 2.01 m (0.5 %, a scale
        // the WID drives move by between stretches). Gyro heading, 30 s
        // without GNSS: 1.5 m behind along the track at the end. With white
        // distance noise alone (no scale state) the filter claimed about
        // 0.1 m there and gated out every fix for 10 s (52 fixes; 2.8 m off
        // at 65 s) until it reset its position.
        let sim = simulate(80.0, &|t| !(30.0..60.0).contains(&t), 0.0, 0.3);
        let long = with_larger_wheels(&sim.inputs, 1.005, 1.005);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        let poses = run(&mut fusion, &long);
        let at = |t: f64| ((t / 0.01).round()) as usize;
        let err = |t: f64| {
            let (p, truth) = (poses[at(t)].pose, sim.truth[at(t)].1);
            (p.x - truth.x).hypot(p.y - truth.y)
        };
        assert!((1.0..2.0).contains(&err(59.99)), "{}", err(59.99));
        assert_eq!(poses[at(59.99)].mode, PoseMode::DeadReckoning);
        assert_eq!(poses[at(61.0)].mode, PoseMode::Fused);
        assert!(err(61.0) < 0.5, "{}", err(61.0));
        let s = fusion.stats();
        assert_eq!((s.gnss_rejected, s.position_resets), (0, 0), "{s:?}");
    }

    #[test]
    fn a_wheel_heading_through_an_outage_knows_its_wheels_may_differ() {
        // The right wheel is 0.1 % larger than calibrated: in wheel heading
        // the yaw turns by 0.001 ds / track, 0.2 rad over 300 m, and a 30 s
        // outage ends 32 m off. That end is inside the 95 % ellipse of the
        // pose's covariance with the relative circumference error considered
        // (1-sigma 0.1 %; chi-square 3.0), far outside it with white heading
        // noise alone (121).
        let sim = simulate(60.0, &|t| t < 30.0, 0.0, 0.3);
        let uneven = with_larger_wheels(&sim.inputs, 1.0, 1.001);
        let truth = sim.truth.last().expect("truth").1;
        let chi2_at_end = |config: FusionConfig| {
            let mut fusion = Fusion::new(params(), 0, config);
            let end = *run(&mut fusion, &uneven).last().expect("poses");
            assert_eq!(end.mode, PoseMode::DeadReckoning);
            let e = [end.pose.x - truth.x, end.pose.y - truth.y];
            let c = end.covariance;
            let chi2 = position_chi2(e, [c[0], c[1], c[3], c[4]]);
            (e[0].hypot(e[1]), chi2.expect("invertible"))
        };
        let (err, chi2) = chi2_at_end(config(HeadingMode::WheelDifference));
        assert!(err > 20.0, "{err} m");
        assert!(chi2 < CHI2_2DOF_95, "{chi2} ({err} m)");
        let (_, white) = chi2_at_end(FusionConfig {
            wheel_difference_sigma: 0.0,
            ..config(HeadingMode::WheelDifference)
        });
        assert!(white > 10.0 * CHI2_2DOF_95, "{white}");
    }

    #[test]
    fn dead_reckoning_mean_equals_the_dead_reckoner() {
        dead_reckoning_mean_follows(vehicle_model::effects::EffectTerms::default());
    }

    #[test]
    fn with_a_side_slip_term_the_filter_moves_as_the_dead_reckoner_does() {
        // The side-slip angle turns the direction of motion away from the
        // heading: the filter's prediction must use it as the dead-reckoner
        // does, and on this curve it moves the track.
        let slip = vehicle_model::effects::EffectTerms {
            k_beta: 0.01,
            ..Default::default()
        };
        let (plain, slipped) = (
            dead_reckoning_mean_follows(Default::default()),
            dead_reckoning_mean_follows(slip),
        );
        let moved = (plain.x - slipped.x).hypot(plain.y - slipped.y);
        assert!(moved > 0.5, "{moved} m");
    }

    /// Fixes only for the first 10 s; afterwards the filter mean must follow
    /// exactly the dead-reckoner started from the same pose, both with
    /// `effects`. With effect terms the dead-reckoner's smoothed speed and
    /// yaw rate start from rest at 12 s while the filter's ran from 0 s, so
    /// the motion is compared from 15 s on, once both have settled.
    /// Returns the last pose.
    fn dead_reckoning_mean_follows(effects: vehicle_model::effects::EffectTerms) -> Pose2 {
        let plain = effects == Default::default();
        let mut origin: Option<(Pose2, Pose2)> = None;
        let sim = simulate(40.0, &|t| t < 10.0, 0.0, 0.2);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        fusion.set_effects(effects);
        let split = sim.inputs.iter().position(|i| i.t_s() > 12.0).unwrap();
        let poses = run(&mut fusion, &sim.inputs[..split]);
        let start = poses.last().unwrap();
        let mut dr = crate::dead_reckoning::DeadReckoner::new(
            params(),
            config(HeadingMode::WheelDifference).odometer,
            start.pose,
        );
        dr.set_effects(effects);
        // Re-feed the gyro history so that both start from the same state.
        for i in &sim.inputs[..split] {
            match *i {
                Input::Imu { t_s, gz_rad_s } if t_s > 11.0 => dr.gyro(t_s, gz_rad_s).unwrap(),
                Input::Wheels {
                    t_s,
                    rl_rev,
                    rr_rev,
                } if t_s == start.t_s => {
                    dr.wheels(t_s, rl_rev, rr_rev).unwrap();
                }
                _ => {}
            }
        }
        let mut last = None;
        for i in &sim.inputs[split..] {
            let out = fusion.process(i).unwrap();
            let dr_pose = match *i {
                Input::Imu { t_s, gz_rad_s } => {
                    dr.gyro(t_s, gz_rad_s).unwrap();
                    None
                }
                Input::Wheels {
                    t_s,
                    rl_rev,
                    rr_rev,
                } => Some(dr.wheels(t_s, rl_rev, rr_rev).unwrap()),
                _ => None,
            };
            if let (Some(f), Some(d)) = (out, dr_pose) {
                assert_eq!(f.mode, PoseMode::DeadReckoning);
                let (f0, d0) = if plain {
                    (Pose2::default(), Pose2::default())
                } else if f.t_s >= 15.0 {
                    *origin.get_or_insert((f.pose, d))
                } else {
                    continue;
                };
                let (fx, fy) = (f.pose.x - f0.x, f.pose.y - f0.y);
                let (dx, dy) = (d.x - d0.x, d.y - d0.y);
                // 1 cm with effect terms: what is left of the smoothers'
                // different starts (e^-6 of it at 15 s).
                let tolerance = if plain { 1e-6 } else { 0.01 };
                assert!((fx - dx).hypot(fy - dy) < tolerance, "{f:?} vs {d:?}");
                last = Some(f.pose);
            }
        }
        last.expect("poses after the fixes")
    }
}
