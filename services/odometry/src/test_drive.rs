//! A simulated drive for the unit tests of the filter: a car on a smooth
//! curve, its wheels and gyro at 100 Hz and GNSS fixes at 5 Hz.

use crate::inputs::{sort_inputs, Input};
use vehicle_model::two_wheel::{step, Pose2};

/// Circumference of both rear wheels, m.
pub const C: f64 = 2.0;
/// Rear track, m.
pub const TRACK: f64 = 1.5;

/// What to simulate.
pub struct Curve {
    /// Length, s.
    pub seconds: f64,
    /// Speed, m/s.
    pub speed_m_s: f64,
    /// Yaw rate at time t, rad/s.
    pub yaw_rate: fn(f64) -> f64,
    /// Pose at t = 0.
    pub start: Pose2,
    /// Gyro bias, rad/s.
    pub gyro_bias: f64,
    /// A fix every 0.2 s is stamped this long after its wheel instant (and
    /// placed where the car is then), s.
    pub fix_offset_s: f64,
    /// Amplitude of the fixes' error (a fixed pattern, not random), m.
    pub fix_error_m: f64,
    /// The fixes' 1-sigma, m.
    pub fix_sigma_m: f64,
}

/// The inputs in processing order, and the true pose at each wheel instant;
/// fixes only at the times `gnss` lets through.
pub fn simulate(curve: &Curve, gnss: &dyn Fn(f64) -> bool) -> (Vec<Input>, Vec<(f64, Pose2)>) {
    let dt = 0.01;
    let v = curve.speed_m_s;
    let mut pose = curve.start;
    let (mut rl, mut rr) = (0.0, 0.0);
    let (mut inputs, mut truth) = (Vec::new(), Vec::new());
    for i in 0..=(curve.seconds / dt).round() as usize {
        let t = i as f64 * dt;
        if i > 0 {
            let dyaw = (curve.yaw_rate)(t - dt / 2.0) * dt;
            let ds = v * dt;
            pose = step(pose, ds, dyaw, 0.0);
            rl += (ds - dyaw * TRACK / 2.0) / C;
            rr += (ds + dyaw * TRACK / 2.0) / C;
        }
        inputs.push(Input::Imu {
            t_s: t,
            gz_rad_s: (curve.yaw_rate)(t) + curve.gyro_bias,
        });
        if i % 20 == 0 && gnss(t) {
            let (k, ahead) = (i as f64, curve.fix_offset_s * v);
            inputs.push(Input::Gnss {
                t_s: t + curve.fix_offset_s,
                x_m: pose.x + ahead * pose.yaw.cos() + curve.fix_error_m * (1.7 * k).sin(),
                y_m: pose.y + ahead * pose.yaw.sin() + curve.fix_error_m * (2.3 * k).cos(),
                sigma_m: Some(curve.fix_sigma_m),
            });
        }
        inputs.push(Input::Wheels {
            t_s: t,
            rl_rev: rl,
            rr_rev: rr,
        });
        truth.push((t, pose));
    }
    sort_inputs(&mut inputs);
    (inputs, truth)
}
