//! The modes of the filter ([`PoseMode`]): `NoFix` until it is
//! initialised (at a fix, with a recent heading or after a GNSS baseline)
//! or resumed from a kept pose, and again after stale inputs; `Fused` while
//! the last accepted fix is recent; `DeadReckoning` otherwise.

use super::error::FusionError;
use super::filter::Fusion;
use super::state::{State, StateMat, StateVec, SCALE, WHEEL_DIFF};
use interfaces::wire::PoseMode;
use vehicle_model::two_wheel::{wrap_angle, Pose2};

impl Fusion {
    /// The mode the filter is in at time `t_s`.
    pub fn mode_at(&self, t_s: f64) -> PoseMode {
        match self.state {
            State::Uninitialised { .. } => PoseMode::NoFix,
            State::Running { .. } => match self.last_accepted_fix_s {
                Some(tf) if t_s - tf <= self.config.gnss_timeout_s => PoseMode::Fused,
                _ => PoseMode::DeadReckoning,
            },
        }
    }

    /// A fix was accepted at `t_s`: `Fused` from here, and the count of
    /// rejected fixes starts again.
    pub(super) fn accept_fix(&mut self, t_s: f64) {
        self.last_accepted_fix_s = Some(t_s);
        self.first_rejected_fix_s = None;
        self.rejected_in_a_row = 0;
        self.resumed_unconfirmed = false;
    }

    /// The inputs went stale (the service saw no wheel sample for too long):
    /// forget the pose; `NoFix` until the filter is initialised again.
    pub fn mark_stale(&mut self) {
        self.stats.stale += 1;
        self.reset();
    }

    /// Back to `NoFix`, keeping the parameters and counters.
    pub fn reset(&mut self) {
        self.state = State::Uninitialised {
            anchor: None,
            local: Pose2::default(),
        };
        self.odometer.restart();
        self.pending.clear();
        self.scale_check.restart_window();
        self.last_wheels = None;
        self.last_accepted_fix_s = None;
        self.first_rejected_fix_s = None;
        self.rejected_in_a_row = 0;
        self.headings_rejected_in_a_row = 0;
        self.first_rejected_heading_s = None;
        self.resumed_unconfirmed = false;
    }

    /// Start from a pose kept from an earlier run (the car was parked there,
    /// say in a garage, and powers on without GNSS): `Running`, in
    /// `DeadReckoning` until a fix is accepted. The position and yaw
    /// variances are at least
    /// [`FusionConfig::resume_sigma_m`](super::config::FusionConfig::resume_sigma_m)
    /// and
    /// [`FusionConfig::resume_yaw_sigma_rad`](super::config::FusionConfig::resume_yaw_sigma_rad)
    /// squared (what a parked car's
    /// pose may have lost); the residual gyro bias starts from zero.
    pub fn resume(&mut self, pose: Pose2, covariance: &[f64; 9]) -> Result<(), FusionError> {
        let finite = [pose.x, pose.y, pose.yaw]
            .iter()
            .chain(covariance)
            .all(|v| v.is_finite());
        if !finite {
            return Err(FusionError::ResumeNotFinite);
        }
        let mut p = StateMat::zeros();
        for i in 0..3 {
            for j in 0..3 {
                p[(i, j)] = covariance[3 * i + j];
            }
        }
        let floors = [
            self.config.resume_sigma_m.powi(2),
            self.config.resume_sigma_m.powi(2),
            self.config.resume_yaw_sigma_rad.powi(2),
        ];
        for (i, floor) in floors.into_iter().enumerate() {
            p[(i, i)] = p[(i, i)].max(floor);
        }
        p[(3, 3)] = self.config.initial_gyro_bias_sigma.powi(2);
        let [scale_variance, difference_variance] = self.fresh_consider_variances();
        p[(SCALE, SCALE)] = scale_variance;
        p[(WHEEL_DIFF, WHEEL_DIFF)] = difference_variance;
        let x = StateVec::new(pose.x, pose.y, wrap_angle(pose.yaw), 0.0, 0.0, 0.0);
        self.reset();
        self.set_running(x, p, 0.0, "resume")?;
        self.resumed_unconfirmed = true;
        Ok(())
    }

    /// A fix before the filter is initialised: initialise it when a recent
    /// heading or the GNSS baseline since the first fix gives the yaw (see
    /// the module docs of `fusion`), else keep the fix as the anchor.
    pub(super) fn initialise_from_fix(
        &mut self,
        t_s: f64,
        x_m: f64,
        y_m: f64,
        sigma_m: f64,
        anchor: Option<([f64; 3], Pose2)>,
        local: Pose2,
    ) {
        let lever = self.config.lever_arm_m[0].hypot(self.config.lever_arm_m[1]);
        // With a recent absolute heading, start at once.
        let heading = self
            .last_heading
            .filter(|(th, _, _)| (t_s - th).abs() <= 1.0)
            .map(|(_, yaw, sigma)| (yaw, sigma));
        let yaw_and_sigma = match (heading, anchor) {
            (Some(h), _) => Some(h),
            (None, Some((a, local_a))) => {
                let (gx, gy) = (x_m - a[0], y_m - a[1]);
                let (lx, ly) = (local.x - local_a.x, local.y - local_a.y);
                let baseline = gx.hypot(gy);
                if t_s - a[2] > self.config.reset_after_rejected_s {
                    // Too long since the anchor: start the baseline again.
                    self.state = State::Uninitialised {
                        anchor: Some(([x_m, y_m, t_s], local)),
                        local,
                    };
                    return;
                }
                if baseline >= self.config.init_baseline_m
                    && lx.hypot(ly) >= 0.5 * self.config.init_baseline_m
                {
                    let rotation = gy.atan2(gx) - ly.atan2(lx);
                    let sigma = 2.0 * (sigma_m + lever) / baseline + 0.02;
                    Some((wrap_angle(local.yaw + rotation), sigma))
                } else {
                    None
                }
            }
            (None, None) => {
                self.state = State::Uninitialised {
                    anchor: Some(([x_m, y_m, t_s], local)),
                    local,
                };
                return;
            }
        };
        let Some((yaw, sigma_yaw)) = yaw_and_sigma else {
            return;
        };
        let arm = self.lever_arm_world(yaw);
        let x = StateVec::new(x_m - arm[0], y_m - arm[1], yaw, 0.0, 0.0, 0.0);
        let [scale_variance, difference_variance] = self.fresh_consider_variances();
        let sigma_pos = sigma_m + 0.5 * lever;
        let p = StateMat::from_diagonal(&StateVec::new(
            sigma_pos * sigma_pos,
            sigma_pos * sigma_pos,
            sigma_yaw * sigma_yaw,
            self.fresh_bias_variance(t_s),
            scale_variance,
            difference_variance,
        ));
        self.state = State::Running { x, p };
        self.stats.initialisations += 1;
        self.accept_fix(t_s);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dead_reckoning::HeadingMode;
    use crate::fusion::test_support::{config, params, run, simulate};
    use crate::inputs::Input;

    #[test]
    fn a_resumed_pose_dead_reckons_at_once_and_fuses_when_gnss_comes() {
        // The car stood at the start pose; GNSS only from 10 s on.
        let sim = simulate(20.0, &|t| t >= 10.0, 0.0, 0.4);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        let start = sim.truth[0].1;
        let tiny = [1e-6, 0.0, 0.0, 0.0, 1e-6, 0.0, 0.0, 0.0, 1e-8];
        fusion.resume(start, &tiny).expect("resume");
        let poses = run(&mut fusion, &sim.inputs);
        assert_eq!(poses[0].mode, PoseMode::DeadReckoning);
        // The floors: what a parked car's pose may have lost.
        assert_eq!(poses[0].covariance[0], 0.25);
        assert_eq!(poses[0].covariance[8], 0.02f64.powi(2));
        for (pose, (t, truth)) in poses.iter().zip(&sim.truth) {
            if *t < 10.0 {
                assert_eq!(pose.mode, PoseMode::DeadReckoning, "t = {t}");
                let e = (pose.pose.x - truth.x).hypot(pose.pose.y - truth.y);
                assert!(e < 0.05, "t = {t}: {e} m");
            } else if *t > 10.5 {
                assert_eq!(pose.mode, PoseMode::Fused, "t = {t}");
            }
        }
        assert_eq!(fusion.stats().initialisations, 0);
        assert_eq!(fusion.stats().gnss_rejected, 0);

        // A pose that is not finite is refused, and the filter stays as it was.
        let mut fresh = Fusion::new(params(), 0, config(HeadingMode::Gyro));
        let bad = Pose2 {
            x: f64::NAN,
            ..start
        };
        assert_eq!(fresh.resume(bad, &tiny), Err(FusionError::ResumeNotFinite));
        assert_eq!(fresh.mode_at(0.0), PoseMode::NoFix);
    }

    #[test]
    fn no_fix_then_fused_then_dead_reckoning_through_an_outage() {
        let sim = simulate(60.0, &|t| !(30.0..45.0).contains(&t), 0.0, 0.7);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let poses = run(&mut fusion, &sim.inputs);
        assert_eq!(poses.len(), sim.truth.len());
        assert_eq!(poses[0].mode, PoseMode::NoFix);
        let at = |t: f64| ((t / 0.01).round()) as usize;
        // Initialised once the GNSS track moved the baseline (5 m at 10 m/s).
        assert_eq!(poses[at(5.0)].mode, PoseMode::Fused);
        assert_eq!(poses[at(29.0)].mode, PoseMode::Fused);
        assert_eq!(poses[at(31.5)].mode, PoseMode::DeadReckoning);
        assert_eq!(poses[at(44.9)].mode, PoseMode::DeadReckoning);
        assert_eq!(poses[at(46.0)].mode, PoseMode::Fused);
        for &t in &[10.0, 29.0, 44.9, 59.0] {
            let (p, truth) = (poses[at(t)].pose, sim.truth[at(t)].1);
            let err = (p.x - truth.x).hypot(p.y - truth.y);
            assert!(err < 0.5, "t = {t}: error {err} m, {p:?} vs {truth:?}");
            assert!(wrap_angle(p.yaw - truth.yaw).abs() < 0.02, "t = {t}");
        }
        // The covariance grows through the outage and shrinks after it.
        let var = |t: f64| poses[at(t)].covariance[0] + poses[at(t)].covariance[4];
        assert!(
            var(44.9) > 5.0 * var(29.0),
            "{} vs {}",
            var(44.9),
            var(29.0)
        );
        assert!(var(59.0) < var(44.9));
        let s = fusion.stats();
        assert_eq!(s.initialisations, 1);
        assert_eq!(s.gnss_rejected, 0, "{s:?}");
    }

    #[test]
    fn stale_wheels_go_back_to_no_fix() {
        let sim = simulate(20.0, &|_| true, 0.0, 0.0);
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let poses = run(&mut fusion, &sim.inputs[..sim.inputs.len() / 2]);
        assert_eq!(poses.last().unwrap().mode, PoseMode::Fused);
        fusion.mark_stale();
        assert_eq!(fusion.mode_at(10.0), PoseMode::NoFix);
        assert_eq!(fusion.stats().stale, 1);
        // A gap in the wheel samples longer than stale_after_s does the same.
        let mut fusion = Fusion::new(params(), 0, config(HeadingMode::WheelDifference));
        let gap: Vec<Input> = sim
            .inputs
            .iter()
            .copied()
            .filter(|i| !(matches!(i, Input::Wheels { .. }) && (8.0..9.0).contains(&i.t_s())))
            .collect();
        let poses = run(&mut fusion, &gap);
        let after_gap = poses.iter().find(|p| p.t_s >= 9.0).unwrap();
        assert_eq!(after_gap.mode, PoseMode::NoFix);
        assert_eq!(
            poses.last().unwrap().mode,
            PoseMode::Fused,
            "initialises again"
        );
    }
}
