//! The two-wheel (2W) odometry model of the paper, eq. (1)-(2).
//!
//! The pose is the rear-axle centre in local ENU; the rear wheels' travelled
//! distances d = n * c drive it:
//!
//! ```text
//! v dt = (d_RL + d_RR) / 2          w dt = (d_RR - d_RL) / t_R
//! x += v dt cos(theta + w dt / 2 + beta)
//! y += v dt sin(theta + w dt / 2 + beta)
//! theta += w dt
//! ```
//!
//! Everything here is pure: no clock, no I/O; times come in with the data.

use interfaces::drive::WheelRevs;

/// A planar pose of the rear-axle centre.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose2 {
    /// East, m.
    pub x: f64,
    /// North, m.
    pub y: f64,
    /// Yaw, rad, 0 = east, counter-clockwise positive (not wrapped).
    pub yaw: f64,
}

impl Pose2 {
    /// Where the body point `arm` (x forward, y left from the rear-axle
    /// centre, m) is in the world: a GNSS antenna, a truth point.
    pub fn point_at(&self, arm: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.yaw.sin_cos();
        [
            self.x + arm[0] * c - arm[1] * s,
            self.y + arm[0] * s + arm[1] * c,
        ]
    }
}

/// Parameters of the 2W model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoWheelParams {
    /// Rear-left effective circumference, m.
    pub c_rl: f64,
    /// Rear-right effective circumference, m.
    pub c_rr: f64,
    /// Effective rear track, m.
    pub track_width: f64,
}

impl TwoWheelParams {
    /// Distance travelled (centre) and heading change for revolution increments.
    pub fn increments(&self, dn_rl: f64, dn_rr: f64) -> (f64, f64) {
        let d_rl = dn_rl * self.c_rl;
        let d_rr = dn_rr * self.c_rr;
        (0.5 * (d_rl + d_rr), (d_rr - d_rl) / self.track_width)
    }
}

/// One step of eq. (1): advance `pose` by centre distance `ds` and heading
/// change `dyaw`, with side-slip angle `beta` (0 for the paper's first results).
pub fn step(pose: Pose2, ds: f64, dyaw: f64, beta: f64) -> Pose2 {
    let course = pose.yaw + 0.5 * dyaw + beta;
    Pose2 {
        x: pose.x + ds * course.cos(),
        y: pose.y + ds * course.sin(),
        yaw: pose.yaw + dyaw,
    }
}

/// Dead-reckon with the pure 2W model (heading from the wheel difference) over
/// `revs`, starting at `start` at the time of `revs[0]`. Returns one pose per
/// sample. Samples with a non-finite rear value are held (no motion).
pub fn dead_reckon(start: Pose2, revs: &[WheelRevs], params: &TwoWheelParams) -> Vec<Pose2> {
    let mut out = Vec::with_capacity(revs.len());
    let mut pose = start;
    let mut prev: Option<&WheelRevs> = None;
    for r in revs {
        if let Some(p) = prev {
            let dn_rl = r.rl - p.rl;
            let dn_rr = r.rr - p.rr;
            if dn_rl.is_finite() && dn_rr.is_finite() {
                let (ds, dyaw) = params.increments(dn_rl, dn_rr);
                pose = step(pose, ds, dyaw, 0.0);
            }
        }
        out.push(pose);
        prev = Some(r);
    }
    out
}

/// Wrap an angle to (-pi, pi] (one home: [`stats::wrap_angle`]).
pub use stats::wrap_angle;

#[cfg(test)]
mod tests {
    use super::*;

    fn revs(t_s: f64, rl: f64, rr: f64) -> WheelRevs {
        WheelRevs {
            t_s,
            rl,
            rr,
            fl: None,
            fr: None,
        }
    }

    #[test]
    fn equal_wheels_drive_straight() {
        let p = TwoWheelParams {
            c_rl: 2.0,
            c_rr: 2.0,
            track_width: 1.5,
        };
        let track = dead_reckon(
            Pose2::default(),
            &[revs(0.0, 0.0, 0.0), revs(1.0, 5.0, 5.0)],
            &p,
        );
        assert!((track[1].x - 10.0).abs() < 1e-12);
        assert!(track[1].y.abs() < 1e-12);
        assert!(track[1].yaw.abs() < 1e-12);
    }

    #[test]
    fn a_full_circle_closes() {
        // Radius R: outer wheel travels 2 pi (R + t/2), inner 2 pi (R - t/2).
        let (r, t, c) = (10.0, 1.5, 2.0);
        let p = TwoWheelParams {
            c_rl: c,
            c_rr: c,
            track_width: t,
        };
        let n = 2000;
        let samples: Vec<_> = (0..=n)
            .map(|i| {
                let f = i as f64 / n as f64 * std::f64::consts::TAU;
                revs(i as f64, f * (r - t / 2.0) / c, f * (r + t / 2.0) / c)
            })
            .collect();
        let track = dead_reckon(Pose2::default(), &samples, &p);
        let end = track[n];
        assert!(end.x.abs() < 1e-9 && end.y.abs() < 1e-9, "{end:?}");
        assert!((end.yaw - std::f64::consts::TAU).abs() < 1e-9);
        // Turning left from heading east: the centre of the circle is north.
        let max_y = track.iter().map(|p| p.y).fold(f64::MIN, f64::max);
        assert!((max_y - 2.0 * r).abs() < 1e-3, "{max_y}");
    }

    #[test]
    fn wrap_angle_stays_in_range() {
        assert!((wrap_angle(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap_angle(-0.5) + 0.5).abs() < 1e-12);
    }
}
