//! The rehearsal: the work of a wheel sample while driving, done on a
//! made-up sample, which the rewinding filter runs on a copy of the filter
//! shortly before a real sample is due (it brings the step's code and data
//! into the caches).

use super::filter::{FusedPose, Fusion};
use super::state::State;
use crate::inputs::Input;

impl Fusion {
    /// The step of a made-up wheel sample 1 ms after the last one, both
    /// wheels a thousandth of a turn further (straight on at 1 rev/s), with
    /// a fix where the filter's antenna is and, once headings have come, a
    /// heading along its yaw: the work of a wheel sample while driving, its
    /// updates included, for `RewindingFusion::rehearse`, which runs it on a
    /// copy. `None` before the first wheel sample, or when the step fails.
    pub(crate) fn rehearse_wheel_sample(&mut self) -> Option<FusedPose> {
        let (t_s, rl_rev, rr_rev) = self.last_wheels?;
        let t_s = t_s + 1e-3;
        if let State::Running { x, .. } = self.state {
            let [ax, ay] = self.lever_arm_world(x[2]);
            let fix = Input::Gnss {
                t_s,
                x_m: x[0] + ax,
                y_m: x[1] + ay,
                sigma_m: None,
            };
            self.process(&fix).ok()?;
            if self.last_heading.is_some() {
                let heading = Input::Heading {
                    t_s,
                    yaw_rad: x[2],
                    sigma_rad: None,
                };
                self.process(&heading).ok()?;
            }
        }
        let sample = Input::Wheels {
            t_s,
            rl_rev: rl_rev + 1e-3,
            rr_rev: rr_rev + 1e-3,
        };
        self.process(&sample).ok().flatten()
    }
}
