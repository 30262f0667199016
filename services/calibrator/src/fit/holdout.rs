//! Held-out scoring: how well parameter sets dead-reckon on data a fit never
//! saw.
//!
//! [`split_drive`] cuts a drive in time into the part a fit uses and the part
//! held out; [`holdout_errors`] dead-reckons windows over the held-out part
//! with each parameter set, each window started from the GNSS/IMU reference
//! pose (the situation of a GNSS outage), and reports the mean position error
//! at the windows' ends.

use crate::config::CalibrationConfig;
use crate::error::CalibrationError;
use crate::reference::{build as build_reference, Reference};
use interfaces::drive::Drive;
use vehicle_model::two_wheel::{step, Pose2, TwoWheelParams};

/// The part of `drive` before `t_split` (fit) and from it on (held out).
pub fn split_drive(drive: &Drive, t_split: f64) -> (Drive, Drive) {
    fn part<T: Clone>(
        v: &Option<Vec<T>>,
        t: impl Fn(&T) -> f64,
        before: bool,
        ts: f64,
    ) -> Option<Vec<T>> {
        v.as_ref().map(|v| {
            v.iter()
                .filter(|s| (t(s) < ts) == before)
                .cloned()
                .collect()
        })
    }
    let mut fit = drive.clone();
    let mut held = drive.clone();
    fit.wheels.samples.retain(|s| s.t_s < t_split);
    held.wheels.samples.retain(|s| s.t_s >= t_split);
    fit.gnss = part(&drive.gnss, |s| s.t_s, true, t_split);
    held.gnss = part(&drive.gnss, |s| s.t_s, false, t_split);
    fit.imu = part(&drive.imu, |s| s.t_s, true, t_split);
    held.imu = part(&drive.imu, |s| s.t_s, false, t_split);
    fit.heading = part(&drive.heading, |s| s.t_s, true, t_split);
    held.heading = part(&drive.heading, |s| s.t_s, false, t_split);
    fit.truth = part(&drive.truth, |s| s.t_s, true, t_split);
    held.truth = part(&drive.truth, |s| s.t_s, false, t_split);
    (fit, held)
}

/// Dead-reckoning errors of several parameter sets on the same held-out data.
#[derive(Debug, Clone, PartialEq)]
pub struct HoldoutScore {
    /// Mean end-of-window position error per parameter set, m.
    pub mean_error_m: Vec<f64>,
    /// Windows evaluated.
    pub windows: usize,
}

/// Dead-reckon `window_s`-long windows (started every `window_s / 2` from the
/// reference pose) over `held` with each parameter set; the error of a window
/// is the distance to the reference at its end.
pub fn holdout_errors(
    held: &Drive,
    params: &[TwoWheelParams],
    config: &CalibrationConfig,
    window_s: f64,
) -> Result<HoldoutScore, CalibrationError> {
    let a = crate::clocks::align_offsets(crate::check::drive(held, config)?, config)?;
    let mut warnings = a.warnings.clone();
    let r = build_reference(&a, config, &mut warnings)?;
    let p = &a.series;
    let track = RefTrack::of(&r);
    Ok(score_windows(
        &p.t,
        &p.dn_rl,
        &p.dn_rr,
        &p.piece_starts,
        &track,
        params,
        window_s,
    ))
}

/// The reference poses at the wheel sample times.
struct RefTrack<'a> {
    x: &'a [f64],
    y: &'a [f64],
    yaw: &'a [f64],
    valid: &'a [bool],
}

impl<'a> RefTrack<'a> {
    fn of(r: &'a Reference) -> RefTrack<'a> {
        RefTrack {
            x: &r.x,
            y: &r.y,
            yaw: &r.yaw,
            valid: &r.valid,
        }
    }
}

fn score_windows(
    t: &[f64],
    dn_rl: &[f64],
    dn_rr: &[f64],
    piece_starts: &[usize],
    r: &RefTrack,
    params: &[TwoWheelParams],
    window_s: f64,
) -> HoldoutScore {
    let n = t.len();
    let mut sums = vec![0.0; params.len()];
    let mut windows = 0;
    let mut k0 = 0;
    while k0 < n {
        // A window starts at a sample with a valid reference.
        if !r.valid[k0] {
            k0 += 1;
            continue;
        }
        let t_end = t[k0] + window_s;
        let mut poses: Vec<Pose2> = params
            .iter()
            .map(|_| Pose2 {
                x: r.x[k0],
                y: r.y[k0],
                yaw: r.yaw[k0],
            })
            .collect();
        let mut end: Option<(usize, Vec<Pose2>)> = None;
        let mut k = k0 + 1;
        while k < n && t[k] <= t_end {
            if piece_starts.binary_search(&k).is_ok() {
                break; // a break in the wheel data ends the window
            }
            for (pose, prm) in poses.iter_mut().zip(params) {
                let (ds, dyaw) = prm.increments(dn_rl[k], dn_rr[k]);
                *pose = step(*pose, ds, dyaw, 0.0);
            }
            if r.valid[k] {
                end = Some((k, poses.clone()));
            }
            k += 1;
        }
        if let Some((ke, end_poses)) = end {
            if t[ke] - t[k0] >= 0.8 * window_s {
                for (s, pose) in sums.iter_mut().zip(&end_poses) {
                    *s += (pose.x - r.x[ke]).hypot(pose.y - r.y[ke]);
                }
                windows += 1;
            }
        }
        // Next window half a window later.
        let t_next = t[k0] + 0.5 * window_s;
        while k0 < n && t[k0] < t_next {
            k0 += 1;
        }
    }
    HoldoutScore {
        mean_error_m: sums
            .iter()
            .map(|s| {
                if windows > 0 {
                    s / windows as f64
                } else {
                    f64::NAN
                }
            })
            .collect(),
        windows,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_score_the_right_parameters_best() {
        // Straight line at 10 m/s sampled at 10 Hz; true c = 2.0.
        let n = 400;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.1).collect();
        let dn = vec![0.5; n];
        let x: Vec<f64> = t.iter().map(|&t| 10.0 * t).collect();
        let zeros = vec![0.0; n];
        let valid = vec![true; n];
        let r = RefTrack {
            x: &x,
            y: &zeros,
            yaw: &zeros,
            valid: &valid,
        };
        let p = |c: f64| TwoWheelParams {
            c_rl: c,
            c_rr: c,
            track_width: 1.5,
        };
        let s = score_windows(&t, &dn, &dn, &[0], &r, &[p(2.0), p(2.2)], 10.0);
        assert!(s.windows >= 6, "{}", s.windows);
        assert!(s.mean_error_m[0] < 1e-9);
        // 10 % too large: 10 m over a 100 m window.
        assert!(
            (s.mean_error_m[1] - 10.0).abs() < 0.2,
            "{:?}",
            s.mean_error_m
        );
    }
}
