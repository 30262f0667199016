//! The serving loop's side of the pose kept across power cycles
//! (`--pose-state`): the pose kept by an earlier run, judged at the first
//! wheel sample ([`odometry::restart`]), and the last pose with a position,
//! written as drive time passes. The file itself is [`super::pose_state`].

use super::pose_state::{self, SavedPose};
use super::POSE_STATE_EVERY_S;
use interfaces::wire::PoseMode;
use odometry::fusion::{FusedPose, Fusion, FusionError};
use odometry::restart::{judge_restart, Restart, RestartConfig, WheelMark};
use std::path::Path;

/// The pose kept in `path`, if there is one. A file that cannot be read is
/// named in a warning and the service starts without it: a broken file must
/// not keep the car from localising.
pub(crate) fn load_kept_pose(path: &Path) -> Option<SavedPose> {
    match pose_state::load(path) {
        Ok(Some(saved)) => Some(saved),
        Ok(None) => {
            tracing::info!(
                "odometry: no pose kept in {} yet; it will be written there",
                path.display()
            );
            None
        }
        Err(e) => {
            tracing::warn!("odometry: {e}; starting without the kept pose");
            None
        }
    }
}

/// At the first wheel sample: start from the kept pose if
/// [`odometry::restart::judge_restart`] trusts it, with the covariance it
/// gives; else say why and start in `NoFix`.
pub(crate) fn resume_if_trusted(fusion: &mut Fusion, saved: &SavedPose, first: &WheelMark) {
    let judged = judge_restart(
        &saved.record(POSE_STATE_EVERY_S),
        first,
        &fusion.params().two_wheel,
        &RestartConfig::default(),
    );
    match judged {
        Restart::Resume {
            pose,
            covariance,
            why,
            ..
        } => {
            let carried = SavedPose {
                x_m: pose.x,
                y_m: pose.y,
                yaw_rad: pose.yaw,
                covariance,
                ..saved.clone()
            };
            match resume(fusion, &carried) {
                Ok(()) => tracing::info!(
                    "odometry: resuming from the kept pose ({why}): ({:.2}, {:.2}) m +- {:.2} m, \
                     yaw {:.1} +- {:.1} deg; DeadReckoning until a GNSS fix is accepted",
                    pose.x,
                    pose.y,
                    covariance[0].max(covariance[4]).sqrt(),
                    pose.yaw.to_degrees(),
                    covariance[8].sqrt().to_degrees(),
                ),
                Err(e) => tracing::warn!("odometry: kept pose: {e}; starting without it"),
            }
        }
        Restart::Refuse { why } => {
            tracing::warn!("odometry: the kept pose is not used: {why}; NoFix until GNSS")
        }
    }
}

/// Resume from `saved` with the antenna it was kept with (the pose is the
/// rear axle's for that antenna), unless the antenna is measured.
fn resume(fusion: &mut Fusion, saved: &SavedPose) -> Result<(), FusionError> {
    if let Some(antenna) = fusion.antenna_to_take(saved.gnss_antenna_m) {
        fusion.set_lever_arm(antenna)?;
    }
    fusion.resume(saved.pose(), &saved.covariance)
}

/// The last pose with a position, for `--pose-state`, with the wheel counts
/// and speed at it.
#[derive(Debug, Default)]
pub(crate) struct KeptPose {
    /// The pose and the GNSS antenna position the filter used for it.
    last: Option<(FusedPose, [f64; 2])>,
    /// The wheel sample of that pose and the speed there.
    last_wheels: Option<(WheelMark, Option<f64>)>,
    /// The newest wheel sample and the speed up to it.
    wheels: Option<(WheelMark, Option<f64>)>,
    written: bool,
    /// The last write was at a standstill, at this position.
    written_standing: Option<[f64; 2]>,
    next_write_t: Option<f64>,
}

impl KeptPose {
    /// Before each wheel sample is processed.
    pub(crate) fn wheels_at(
        &mut self,
        mark: WheelMark,
        params: &vehicle_model::two_wheel::TwoWheelParams,
    ) {
        let speed = self
            .wheels
            .and_then(|(previous, _)| mark.speed_since(&previous, params));
        self.wheels = Some((mark, speed));
    }

    /// After each published pose (a `NoFix` pose keeps the one before).
    pub(crate) fn update(&mut self, pose: &FusedPose, gnss_antenna_m: [f64; 2]) {
        if pose.mode != PoseMode::NoFix {
            self.last = Some((*pose, gnss_antenna_m));
            self.last_wheels = self.wheels.filter(|(m, _)| m.t_s == pose.t_s);
            self.written = false;
        }
    }

    /// Write when [`POSE_STATE_EVERY_S`] of drive time passed since the last
    /// write, unless the car stands where the last write already put it.
    pub(crate) fn write_if_due(&mut self, path: &Path) {
        let Some((pose, _)) = self.last else {
            return;
        };
        let t = pose.t_s;
        let due = *self.next_write_t.get_or_insert(t);
        // A restarted stream (time back) is due at once.
        if t >= due || t < due - POSE_STATE_EVERY_S {
            let standing = self
                .last_wheels
                .and_then(|(_, v)| v)
                .is_some_and(|v| v.abs() <= RestartConfig::default().standstill_m_s);
            let same_place = self
                .written_standing
                .is_some_and(|[x, y]| (pose.pose.x - x).hypot(pose.pose.y - y) < 0.01);
            if standing && same_place {
                self.next_write_t = Some(t + POSE_STATE_EVERY_S);
                return;
            }
            self.write(path, false);
        }
    }

    /// Write the last pose now; `last_word` when the service stops or its
    /// inputs went stale (always written then). A failure is logged, not
    /// fatal: the poses on the bus matter more.
    pub(crate) fn write(&mut self, path: &Path, last_word: bool) {
        let Some(mut saved) = self
            .last
            .filter(|_| last_word || !self.written)
            .and_then(|(p, antenna)| SavedPose::from_fused(&p, antenna))
        else {
            return;
        };
        if let Some((mark, speed)) = self.last_wheels {
            saved.wheel_rev = Some([mark.rl_rev, mark.rr_rev]);
            saved.speed_m_s = speed;
        }
        saved.last_word = last_word;
        saved.write_every_s = Some(POSE_STATE_EVERY_S);
        // Tried again after the same drive time when it fails (no log flood).
        self.next_write_t = Some(saved.t_s + POSE_STATE_EVERY_S);
        match pose_state::save(path, &saved) {
            Ok(()) => {
                self.written = true;
                let standing = saved
                    .speed_m_s
                    .is_some_and(|v| v.abs() <= RestartConfig::default().standstill_m_s);
                self.written_standing = standing.then_some([saved.x_m, saved.y_m]);
            }
            Err(e) => tracing::warn!("odometry: cannot keep the pose: {e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::drive::VehicleParams;
    use odometry::fusion::FusionConfig;
    use odometry::inputs::Input;

    #[test]
    fn a_kept_pose_resumes_with_the_antenna_it_was_kept_with_unless_measured() {
        let vehicle = VehicleParams {
            name: None,
            track_width_m: 1.5,
            nominal_circumference_m: 2.0,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: Default::default(),
        };
        let saved = SavedPose {
            t_s: 12.0,
            x_m: 10.0,
            y_m: -2.0,
            yaw_rad: 0.5,
            covariance: [0.01, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 1e-4],
            mode: "Fused".to_string(),
            estimate_version: 1,
            gnss_antenna_m: Some([0.5, -0.3]),
            wheel_rev: None,
            speed_m_s: None,
            last_word: true,
            write_every_s: None,
        };
        // The antenna it was kept with comes back, and the pose with it: a
        // later estimate with the same antenna then moves nothing.
        let mut fusion = Fusion::nominal(&vehicle, FusionConfig::default());
        resume(&mut fusion, &saved).unwrap();
        assert_eq!(fusion.lever_arm(), [0.5, -0.3]);
        // The pose at a standing wheel sample at `t_s`.
        let standing = |fusion: &mut Fusion, t_s: f64| {
            let pose = fusion
                .process(&Input::Wheels {
                    t_s,
                    rl_rev: 0.0,
                    rr_rev: 0.0,
                })
                .unwrap()
                .unwrap();
            (pose.pose.x, pose.pose.y)
        };
        assert_eq!(standing(&mut fusion, 12.01), (10.0, -2.0));
        fusion.set_lever_arm([0.5, -0.3]).unwrap();
        assert_eq!(standing(&mut fusion, 12.02), (10.0, -2.0));
        // A measured antenna stays.
        let measured = FusionConfig {
            lever_arm_m: [1.0, 0.0],
            lever_arm_from_estimates: false,
            ..FusionConfig::default()
        };
        let mut fusion = Fusion::nominal(&vehicle, measured);
        resume(&mut fusion, &saved).unwrap();
        assert_eq!(fusion.lever_arm(), [1.0, 0.0]);
    }
}
