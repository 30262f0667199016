//! The GNSS antenna's position on the body (the lever arm): where it is
//! in the world for a yaw, which one to take from an estimate, and what a
//! new one does to the pose.

use super::error::FusionError;
use super::filter::Fusion;
use super::state::State;

impl Fusion {
    /// The GNSS antenna position in use (body x forward, y left, from the
    /// rear-axle centre), m.
    pub fn lever_arm(&self) -> [f64; 2] {
        self.config.lever_arm_m
    }

    /// The antenna position the filter takes from an estimate or a kept
    /// pose that brings `candidate`: the candidate, unless the antenna is
    /// measured
    /// ([`FusionConfig::lever_arm_from_estimates`](super::config::FusionConfig::lever_arm_from_estimates)
    /// false).
    pub fn antenna_to_take(&self, candidate: Option<[f64; 2]>) -> Option<[f64; 2]> {
        candidate.filter(|_| self.config.lever_arm_from_estimates)
    }

    /// Use a new GNSS antenna position. The filter's belief about where the
    /// antenna is stays as it was, so the rear-axle position moves by the
    /// change of the arm (rotated by the yaw): a pose fused with the antenna
    /// assumed at the axle was the antenna's track, and is now the axle's.
    /// A non-finite position is refused.
    pub fn set_lever_arm(&mut self, lever_arm_m: [f64; 2]) -> Result<(), FusionError> {
        if !lever_arm_m.iter().all(|v| v.is_finite()) {
            return Err(FusionError::LeverArmNotFinite(lever_arm_m));
        }
        let State::Running { x, .. } = self.state else {
            self.config.lever_arm_m = lever_arm_m;
            return Ok(());
        };
        let old = self.lever_arm_world(x[2]);
        self.config.lever_arm_m = lever_arm_m;
        let new = self.lever_arm_world(x[2]);
        if let State::Running { x, .. } = &mut self.state {
            x[0] += old[0] - new[0];
            x[1] += old[1] - new[1];
        }
        Ok(())
    }

    /// The antenna's offset from the rear-axle centre in the world frame at
    /// yaw `yaw`, m.
    pub(super) fn lever_arm_world(&self, yaw: f64) -> [f64; 2] {
        let [lx, ly] = self.config.lever_arm_m;
        let (s, c) = yaw.sin_cos();
        [lx * c - ly * s, lx * s + ly * c]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dead_reckoning::HeadingMode;
    use crate::fusion::filter::FusedPose;
    use crate::fusion::test_support::{config, params, run, simulate, Sim};
    use crate::inputs::Input;
    use vehicle_model::estimate::Estimate;

    /// `sim`'s inputs with its fixes moved to an antenna at `arm` (body x, y).
    fn antenna_fixes(sim: &Sim, arm: [f64; 2]) -> Vec<Input> {
        sim.inputs
            .iter()
            .map(|i| match *i {
                Input::Gnss {
                    t_s,
                    x_m,
                    y_m,
                    sigma_m,
                } => {
                    let k = ((t_s - 0.005) / 0.01).round() as usize;
                    let (s, c) = sim.truth[k].1.yaw.sin_cos();
                    Input::Gnss {
                        t_s,
                        x_m: x_m + arm[0] * c - arm[1] * s,
                        y_m: y_m + arm[0] * s + arm[1] * c,
                        sigma_m,
                    }
                }
                other => other,
            })
            .collect()
    }

    /// Distance of each pose from the truth at its time, m.
    fn errors(sim: &Sim, poses: &[FusedPose]) -> Vec<f64> {
        poses
            .iter()
            .map(|p| {
                let k = (p.t_s / 0.01).round() as usize;
                let truth = sim.truth[k].1;
                (p.pose.x - truth.x).hypot(p.pose.y - truth.y)
            })
            .collect()
    }

    #[test]
    fn lever_arm_is_taken_into_account() {
        // Antenna 1.2 m ahead of the rear axle: fixes are of the antenna.
        let sim = simulate(30.0, &|_| true, 0.0, 0.0);
        let inputs = antenna_fixes(&sim, [1.2, 0.0]);
        let mut cfg = config(HeadingMode::WheelDifference);
        cfg.lever_arm_m = [1.2, 0.0];
        let mut fusion = Fusion::new(params(), 0, cfg);
        let poses = run(&mut fusion, &inputs);
        let (p, truth) = (poses.last().unwrap().pose, sim.truth.last().unwrap().1);
        assert!(
            (p.x - truth.x).hypot(p.y - truth.y) < 0.2,
            "{p:?} vs {truth:?}"
        );
    }

    #[test]
    fn an_estimates_antenna_moves_the_pose_from_the_antenna_track_to_the_axle() {
        // No measured antenna: the filter starts with it at the axle, so its
        // pose is the antenna's track, 1.24 m off. An estimate that carries
        // the calibrated antenna puts the pose on the axle at once.
        let arm = [1.2, 0.3];
        let sim = simulate(30.0, &|_| true, 0.0, 0.0);
        let inputs = antenna_fixes(&sim, arm);
        let split = inputs.iter().position(|i| i.t_s() > 15.0).unwrap();
        let estimate = Input::Estimate {
            t_s: 15.0,
            version: 1,
            estimate: Estimate {
                params: params(),
                sigma_m: None,
                quality_m: None,
                antenna_m: Some(arm),
                antenna_sigma_m: None,
                effects: vehicle_model::effects::WheelEffects::default(),
                clocks: Default::default(),
            },
        };
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        let before = run(&mut fusion, &inputs[..split]);
        let before_err = errors(&sim, &before[before.len() - 100..]);
        assert!(
            before_err.iter().all(|e| (e - 1.237).abs() < 0.1),
            "{before_err:?}"
        );
        run(&mut fusion, &[estimate]);
        assert_eq!(fusion.lever_arm(), arm);
        let after = run(&mut fusion, &inputs[split..]);
        // From 1.24 m to at most 0.2 m at once (the yaw the filter learned
        // from the antenna's track is off by the arm's share of the course
        // in turns, which the next fixes mend), then within 5 cm.
        let after_err = errors(&sim, &after);
        let worst = after_err.iter().cloned().fold(0.0, f64::max);
        let tail = &after_err[after_err.len() / 2..];
        let tail_worst = tail.iter().cloned().fold(0.0, f64::max);
        assert!(
            worst < 0.2 && tail_worst < 0.05,
            "worst {worst} m, in the last half {tail_worst} m"
        );
        assert_eq!(fusion.stats().gnss_rejected, 0, "no fix gated by the move");

        // A measured antenna (vehicle.toml) is never replaced by an estimate's.
        let mut cfg = config(HeadingMode::Gyro);
        cfg.lever_arm_m = arm;
        cfg.lever_arm_from_estimates = false;
        let mut fusion = Fusion::new(params(), 0, cfg);
        run(&mut fusion, &inputs[..split]);
        let Input::Estimate {
            estimate: mut e, ..
        } = estimate
        else {
            unreachable!()
        };
        e.antenna_m = Some([0.0, 0.0]);
        run(
            &mut fusion,
            &[Input::Estimate {
                t_s: 15.0,
                version: 1,
                estimate: e,
            }],
        );
        assert_eq!(fusion.lever_arm(), arm);
        // A non-finite antenna is refused and changes nothing.
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        e.antenna_m = Some([f64::NAN, 0.0]);
        let err = fusion
            .process(&Input::Estimate {
                t_s: 0.0,
                version: 2,
                estimate: e,
            })
            .unwrap_err();
        assert!(err.to_string().contains("antenna"), "{err}");
        assert_eq!(
            (fusion.lever_arm(), fusion.estimate_version()),
            ([0.0, 0.0], 0)
        );
    }
}
