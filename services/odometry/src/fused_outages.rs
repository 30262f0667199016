//! GNSS outages through the filter: the served pose, not the dead-reckoner
//! alone.
//!
//! `odometry evaluate` starts each outage from the truth pose, which measures
//! the dead-reckoning and nothing else. Here the whole [`Fusion`] runs over
//! the drive once per outage with the fixes inside the outage (its end
//! included) left out, so the outage starts from the filter's own pose,
//! heading and gyro bias, as `odometry serve` would live. Each outage is
//! scored at its end against the truth, at the body point the truth follows,
//! and against the pose's own covariance ([`FusedOutage::error_chi2`]).

// The chi-square statistic of an error against its covariance and its 95 %
// quantile are the filter's Kalman maths; they are named here too, where
// the outages are scored with them.
pub use crate::fusion::{position_chi2, CHI2_2DOF_95};

use crate::fusion::{FusedPose, Fusion, FusionError, ProcessError};
use crate::inputs::Input;
use interfaces::drive::TruthSample;
use interfaces::wire::PoseMode;

/// Where the outages go and how they are scored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FusedOutageConfig {
    /// Length of each outage, s.
    pub length_s: f64,
    /// Time between outage starts, s.
    pub spacing_s: f64,
    /// The first outage starts this long after the first fix, s.
    pub first_after_fix_s: f64,
    /// Score the antenna point of the pose (the filter's lever arm), for
    /// drives whose truth is the GNSS track; else the rear-axle centre.
    pub at_antenna: bool,
    /// A truth row farther than this from the outage end does not score it, s.
    pub max_truth_gap_s: f64,
}

impl Default for FusedOutageConfig {
    fn default() -> Self {
        FusedOutageConfig {
            length_s: 30.0,
            spacing_s: 10.0,
            first_after_fix_s: 20.0,
            at_antenna: false,
            max_truth_gap_s: 0.2,
        }
    }
}

/// One outage through the filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FusedOutage {
    /// Start, s.
    pub t_start_s: f64,
    /// The filter's mode at the last pose before the outage.
    pub mode_at_start: PoseMode,
    /// Position error at the outage end, m; `None` when the filter had no
    /// pose at the start (`NoFix`: it claims nothing to carry through) or no
    /// truth is near the end. An outage that starts in `DeadReckoning` (the
    /// fixes just before it were gated out) is scored too, but
    /// [`median_error`] leaves it out: it is longer than `length_s`.
    pub error_m: Option<f64>,
    /// That error against the pose's own position covariance at the scored
    /// point, e^T P^-1 e: chi-square with 2 degrees of freedom when the
    /// published covariance is honest (at most [`CHI2_2DOF_95`] in 95 % of
    /// outages). `None` when `error_m` is, or the covariance is singular.
    pub error_chi2: Option<f64>,
}

impl FusedOutage {
    /// Whether it counts in [`median_error`]: scored and started `Fused`.
    pub fn counted(&self) -> bool {
        self.error_m.is_some() && self.mode_at_start == PoseMode::Fused
    }
}

/// Run a fresh filter from `new_fusion` over `inputs` (processing order) once
/// per outage. Outages start `first_after_fix_s` after the first fix and every
/// `spacing_s` after it, as long as they end within the inputs.
pub fn fused_outages(
    inputs: &[Input],
    truth: &[TruthSample],
    new_fusion: &dyn Fn() -> Fusion,
    config: &FusedOutageConfig,
) -> Result<Vec<FusedOutage>, FusionError> {
    let first_fix = inputs
        .iter()
        .find(|i| matches!(i, Input::Gnss { .. }))
        .map(Input::t_s);
    let (Some(first_fix), Some(last)) = (first_fix, inputs.last().map(Input::t_s)) else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    let mut start = first_fix + config.first_after_fix_s;
    while start + config.length_s <= last {
        let end_t = start + config.length_s;
        let mut fusion = new_fusion();
        let (mut mode_at_start, mut end) = (PoseMode::NoFix, None);
        for input in inputs {
            let t = input.t_s();
            if matches!(input, Input::Gnss { .. }) && (start..=end_t).contains(&t) {
                continue;
            }
            match fusion.process(input) {
                Ok(Some(pose)) => {
                    if pose.t_s < start {
                        mode_at_start = pose.mode;
                    }
                    if pose.t_s <= end_t {
                        let [lx, ly] = if config.at_antenna {
                            fusion.lever_arm()
                        } else {
                            [0.0, 0.0]
                        };
                        end = Some(scored_point(&pose, [lx, ly]));
                    }
                }
                Ok(None) | Err(ProcessError::Input(_)) => {}
                Err(ProcessError::Numerical(e)) => return Err(e),
            }
        }
        let truth_end = truth
            .iter()
            .min_by(|a, b| (a.t_s - end_t).abs().total_cmp(&(b.t_s - end_t).abs()))
            .filter(|r| (r.t_s - end_t).abs() <= config.max_truth_gap_s);
        let (error_m, error_chi2) = match (mode_at_start, end, truth_end) {
            (PoseMode::Fused | PoseMode::DeadReckoning, Some(([x, y], cov)), Some(r)) => {
                let e = [x - r.x_m, y - r.y_m];
                (Some(e[0].hypot(e[1])), position_chi2(e, cov))
            }
            _ => (None, None),
        };
        out.push(FusedOutage {
            t_start_s: start,
            mode_at_start,
            error_m,
            error_chi2,
        });
        start += config.spacing_s;
    }
    Ok(out)
}

/// The point of `pose` at `arm` (body frame, m) from the rear-axle centre,
/// and that point's position covariance (the pose's, with the yaw's share
/// through the arm).
fn scored_point(pose: &FusedPose, arm: [f64; 2]) -> ([f64; 2], [f64; 4]) {
    let [lx, ly] = arm;
    let (s, c) = pose.pose.yaw.sin_cos();
    let point = pose.pose.point_at(arm);
    // d(point)/d(x, y, yaw), rows x and y.
    let a = [[1.0, 0.0, -lx * s - ly * c], [0.0, 1.0, lx * c - ly * s]];
    let p = &pose.covariance;
    let mut cov = [0.0; 4];
    for i in 0..2 {
        for j in 0..2 {
            let mut sum = 0.0;
            for k in 0..3 {
                for l in 0..3 {
                    sum += a[i][k] * p[3 * k + l] * a[j][l];
                }
            }
            cov[2 * i + j] = sum;
        }
    }
    (point, cov)
}

/// Of the outages that count, how many end inside the 95 % ellipse of the
/// pose's own covariance, and how many count: an honest covariance holds
/// about 95 % of them (fewer: the served pose claims more than it knows).
pub fn inside_95(outages: &[FusedOutage]) -> (usize, usize) {
    let counted: Vec<&FusedOutage> = outages.iter().filter(|o| o.counted()).collect();
    let inside = counted
        .iter()
        .filter(|o| o.error_chi2.is_some_and(|c| c <= CHI2_2DOF_95))
        .count();
    (inside, counted.len())
}

/// Median of the errors of the outages that count ([`FusedOutage::counted`]),
/// m (`None` when none does).
pub fn median_error(outages: &[FusedOutage]) -> Option<f64> {
    let mut e: Vec<f64> = outages
        .iter()
        .filter(|o| o.counted())
        .filter_map(|o| o.error_m)
        .collect();
    if e.is_empty() {
        return None;
    }
    e.sort_by(f64::total_cmp);
    Some((e[(e.len() - 1) / 2] + e[e.len() / 2]) / 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dead_reckoning::{HeadingMode, OdometerConfig};
    use crate::fusion::FusionConfig;
    use vehicle_model::estimate::OdometryParams;
    use vehicle_model::two_wheel::TwoWheelParams;

    /// Straight east at 10 m/s for 100 s: wheels and gyro at 100 Hz, fixes at
    /// 5 Hz of an antenna 1 m ahead of the axle; the wheels read 1 % long.
    fn drive() -> (Vec<Input>, Vec<TruthSample>) {
        let mut inputs = Vec::new();
        let mut truth = Vec::new();
        for k in 0..=10_000 {
            let t = k as f64 * 0.01;
            inputs.push(Input::Imu {
                t_s: t,
                gz_rad_s: 0.0,
            });
            if k % 20 == 0 {
                inputs.push(Input::Gnss {
                    t_s: t,
                    x_m: 10.0 * t + 1.0,
                    y_m: 0.0,
                    sigma_m: Some(0.05),
                });
                inputs.push(Input::Heading {
                    t_s: t,
                    yaw_rad: 0.0,
                    sigma_rad: Some(0.01),
                });
            }
            let rev = 10.0 * t * 1.01 / 2.0;
            inputs.push(Input::Wheels {
                t_s: t,
                rl_rev: rev,
                rr_rev: rev,
            });
            truth.push(TruthSample {
                t_s: t,
                x_m: 10.0 * t,
                y_m: 0.0,
                yaw_rad: Some(0.0),
            });
        }
        (inputs, truth)
    }

    #[test]
    fn outages_are_placed_scored_at_the_chosen_point_and_start_from_the_filter() {
        let (inputs, truth) = drive();
        let params = OdometryParams {
            two_wheel: TwoWheelParams {
                c_rl: 2.0,
                c_rr: 2.0,
                track_width: 1.5,
            },
            gyro_bias_rad_s: 0.0,
            gyro_scale: 0.0,
        };
        let config = FusionConfig {
            odometer: OdometerConfig {
                heading: HeadingMode::Gyro,
                ..OdometerConfig::default()
            },
            lever_arm_m: [1.0, 0.0],
            ..FusionConfig::default()
        };
        let new_fusion = || Fusion::new(params, 0, config);
        let at_axle = FusedOutageConfig::default();
        let outages = fused_outages(&inputs, &truth, &new_fusion, &at_axle).unwrap();
        // Starts at 20, 30, ..., 70 s (the last ends at 100 s).
        let starts: Vec<f64> = outages.iter().map(|o| o.t_start_s).collect();
        assert_eq!(starts, vec![20.0, 30.0, 40.0, 50.0, 60.0, 70.0]);
        // 300 m dead-reckoned on wheels that read 1 % long: 3 m at the end,
        // plus the few decimetres the filter leads its fixes by with them.
        for o in &outages {
            assert_eq!(o.mode_at_start, PoseMode::Fused);
            let e = o.error_m.unwrap();
            assert!((2.9..3.5).contains(&e), "{o:?}");
            // The covariance knows it: a 1 % scale error is 2 sigma of the
            // filter's 0.5 % distance scale, inside the 95 % ellipse (with
            // white distance noise alone the along-track sigma after 300 m
            // was about 0.1 m: chi-square 818).
            let chi2 = o.error_chi2.unwrap();
            assert!((1.0..CHI2_2DOF_95).contains(&chi2), "{o:?}");
        }
        assert_eq!(inside_95(&outages), (6, 6));
        let axle = median_error(&outages).unwrap();
        // Scored at the antenna, 1 m ahead, against a truth that is the axle's: 1 m more.
        let at_antenna = FusedOutageConfig {
            at_antenna: true,
            ..at_axle
        };
        let outages = fused_outages(&inputs, &truth, &new_fusion, &at_antenna).unwrap();
        let m = median_error(&outages).unwrap();
        assert!((m - axle - 1.0).abs() < 0.01, "{m} vs {axle}");
        // An outage that starts before the first fix has no fused pose to carry.
        let early = FusedOutageConfig {
            first_after_fix_s: -10.0,
            ..at_axle
        };
        let outages = fused_outages(&inputs, &truth, &new_fusion, &early).unwrap();
        assert_eq!(outages[0].t_start_s, -10.0);
        assert_eq!(outages[0].error_m, None);
        assert_eq!(median_error(&[]), None);

        // No fixes from 35 s to 40 s: the outage from 40 s starts in
        // DeadReckoning. It is scored (its error has grown for 5 s longer)
        // but left out of the median.
        let gap: Vec<Input> = inputs
            .iter()
            .filter(|i| !(matches!(i, Input::Gnss { .. }) && (35.0..40.0).contains(&i.t_s())))
            .copied()
            .collect();
        let outages = fused_outages(&gap, &truth, &new_fusion, &at_axle).unwrap();
        let late = outages.iter().find(|o| o.t_start_s == 40.0).unwrap();
        assert_eq!(late.mode_at_start, PoseMode::DeadReckoning);
        let e = late.error_m.unwrap();
        assert!((3.2..4.2).contains(&e), "{late:?}");
        assert!(!late.counted());
        for o in &outages {
            assert_eq!(o.counted(), o.mode_at_start == PoseMode::Fused, "{o:?}");
        }
    }
}
