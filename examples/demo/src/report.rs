//! The demo's result: dead-reckoning error at the end of the GNSS outage
//! with the nominal and the calibrated circumferences.
//!
//! Two views of the same outage:
//! - **live**: what the `odometry serve` process published (it dead-reckoned
//!   with the estimate it had taken from the calibrator);
//! - **same start, both parameter sets**: the odometry's own dead-reckoning
//!   code ([`odometry::dead_reckoning::DeadReckoner`]) run from the live pose at
//!   the outage start through the outage, once with the nominal values of
//!   `vehicle.toml` and once with the estimate in use, for both heading modes.
//!
//! Errors are distances to the simulator's truth (rear-axle centre).

use anyhow::Result;
use interfaces::drive::{Drive, TruthSample};
use interfaces::wire::{CircumferenceEstimate, Pose, PoseMode};
use odometry::dead_reckoning::{DeadReckoner, HeadingMode, OdometerConfig};
use odometry::fused_outages::{position_chi2, CHI2_2DOF_95};
use odometry::fusion::{Fusion, FusionConfig};
use odometry::inputs::{drive_inputs, sort_inputs, Input};
use serde::Serialize;
use std::fmt::Write as _;
use vehicle_model::estimate::{Estimate, OdometryParams};
use vehicle_model::two_wheel::Pose2;

/// Truth position at `t` (linear interpolation), `None` outside the truth.
pub fn truth_at(truth: &[TruthSample], t: f64) -> Option<(f64, f64)> {
    let i = truth.partition_point(|s| s.t_s <= t);
    if i == 0 || i > truth.len() {
        return None;
    }
    if i == truth.len() {
        let last = truth[i - 1];
        return (t - last.t_s <= 1e-6).then_some((last.x_m, last.y_m));
    }
    let (a, b) = (truth[i - 1], truth[i]);
    let f = (t - a.t_s) / (b.t_s - a.t_s);
    Some((a.x_m + f * (b.x_m - a.x_m), a.y_m + f * (b.y_m - a.y_m)))
}

/// The estimate the odometry used, as the demo saw it on the bus.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EstimateInfo {
    /// Version.
    pub version: u64,
    /// Rear-left circumference, m.
    pub c_rl_m: f64,
    /// Rear-right circumference, m.
    pub c_rr_m: f64,
    /// Track width, m.
    pub track_width_m: f64,
    /// Gyro bias, rad/s.
    pub gyro_bias_rad_s: f64,
    /// Gyro scale error.
    pub gyro_scale: f64,
    /// Drive time of the last sample the calibrator used, s.
    pub fitted_until_s: f64,
}

/// What the live odometry did through the outage.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LiveResult {
    /// Estimate version in the odometry's poses at the outage end.
    pub estimate_version: u64,
    /// Poses published inside the outage.
    pub poses: usize,
    /// Of them in dead-reckoning mode.
    pub dead_reckoning_poses: usize,
    /// Position error of the last pose of the outage, m.
    pub end_error_m: f64,
    /// Largest position error inside the outage, m.
    pub max_error_m: f64,
    /// The end error against the last pose's own position covariance,
    /// e^T P^-1 e (inside its 95 % ellipse when at most 5.99).
    pub end_chi2: Option<f64>,
    /// Semi-major axis of that pose's 95 % ellipse, m.
    pub end_ellipse_95_m: f64,
}

/// Dead-reckoning through the outage from the same start with both parameter sets.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OfflineRow {
    /// `gyro` or `wheels`.
    pub heading: String,
    /// Error at the outage end with the nominal values, m.
    pub nominal_end_error_m: f64,
    /// Largest error with the nominal values, m.
    pub nominal_max_error_m: f64,
    /// Error at the outage end with the estimate, m (`None` without an estimate).
    pub calibrated_end_error_m: Option<f64>,
    /// Largest error with the estimate, m.
    pub calibrated_max_error_m: Option<f64>,
}

/// The odometry's filter (the service's code) run offline over the drive.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FilterRow {
    /// What parameters it ran with.
    pub parameters: String,
    /// Error of the last pose of the outage, m.
    pub end_error_m: f64,
    /// Largest error inside the outage, m.
    pub max_error_m: f64,
}

/// Run the odometry's fusion filter over `drive` (default settings, as
/// `odometry serve` runs it), taking `estimates` at the given drive times;
/// returns (end error, max error) over the outage.
fn filter_through_outage(
    drive: &Drive,
    estimates: &[(f64, u64, Estimate)],
    outage: (f64, f64),
) -> Result<(f64, f64)> {
    let truth = drive.truth.as_deref().unwrap_or_default();
    let mut inputs = drive_inputs(drive)?;
    for (t_s, version, estimate) in estimates {
        inputs.push(Input::Estimate {
            t_s: *t_s,
            version: *version,
            estimate: *estimate,
        });
    }
    sort_inputs(&mut inputs);
    let config = FusionConfig {
        lever_arm_m: [
            drive.vehicle.gnss.antenna_x_m.unwrap_or(0.0),
            drive.vehicle.gnss.antenna_y_m.unwrap_or(0.0),
        ],
        ..FusionConfig::default()
    };
    let mut fusion = Fusion::nominal(&drive.vehicle, config);
    let (mut end, mut max) = (f64::NAN, 0.0f64);
    for input in &inputs {
        let Ok(Some(p)) = fusion.process(input) else {
            continue;
        };
        if p.t_s > outage.0 && p.t_s <= outage.1 {
            if let Some((x, y)) = truth_at(truth, p.t_s) {
                let e = (p.pose.x - x).hypot(p.pose.y - y);
                max = max.max(e);
                end = e;
            }
        }
    }
    Ok((end, max))
}

/// The demo's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutageReport {
    /// Outage start, s.
    pub outage_start_s: f64,
    /// Outage end, s.
    pub outage_end_s: f64,
    /// Distance driven in the outage (truth), m.
    pub outage_distance_m: f64,
    /// True rear circumferences, m.
    pub true_circumference_m: [f64; 2],
    /// Nominal circumference (vehicle.toml), m.
    pub nominal_circumference_m: f64,
    /// Estimates published by the calibrator, in order (version, c_rl, c_rr).
    pub published: Vec<(u64, f64, f64)>,
    /// The estimate in use when the outage began.
    pub estimate: Option<EstimateInfo>,
    /// Start pose of the comparison (the live pose at the outage start), x, y, yaw.
    pub start_pose: [f64; 3],
    /// The live odometry.
    pub live: Option<LiveResult>,
    /// Same start, nominal against calibrated, per heading mode.
    pub offline: Vec<OfflineRow>,
    /// The odometry's filter offline: nominal throughout, and with the
    /// estimates taken when the live odometry took them.
    pub filter: Vec<FilterRow>,
    /// Offline tracks through the outage, nominal and calibrated (gyro heading), for the picture.
    #[serde(skip)]
    pub tracks: [Vec<[f64; 2]>; 2],
}

/// Dead-reckon over `[t_start, t_end]` from `start`; returns (end error, max error, track).
fn dead_reckon(
    drive: &Drive,
    params: OdometryParams,
    heading: HeadingMode,
    start: Pose2,
    t_start: f64,
    t_end: f64,
) -> Result<(f64, f64, Vec<[f64; 2]>)> {
    let truth = drive.truth.as_deref().unwrap_or_default();
    let revs = drive.wheel_revolutions()?;
    let imu = drive.imu.as_deref().unwrap_or_default();
    let config = OdometerConfig {
        heading,
        ..OdometerConfig::default()
    };
    let mut dr = DeadReckoner::new(params, config, start);
    let mut gi = imu.partition_point(|s| s.t_s < t_start - 1.0);
    let (mut end_err, mut max_err) = (f64::NAN, 0.0f64);
    let mut track = Vec::new();
    let first = revs.partition_point(|r| r.t_s < t_start);
    for (k, r) in revs.iter().enumerate().skip(first) {
        if r.t_s > t_end {
            break;
        }
        while gi < imu.len() && imu[gi].t_s <= r.t_s {
            let _ = dr.gyro(imu[gi].t_s, imu[gi].gz_rad_s);
            gi += 1;
        }
        let pose = dr.wheels(r.t_s, r.rl, r.rr)?;
        if let Some((x, y)) = truth_at(truth, r.t_s) {
            let e = (pose.x - x).hypot(pose.y - y);
            max_err = max_err.max(e);
            end_err = e;
        }
        if k.is_multiple_of(10) {
            track.push([pose.x, pose.y]);
        }
    }
    Ok((end_err, max_err, track))
}

/// Build the report from what the demo saw.
pub fn outage_report(
    drive: &Drive,
    outage: (f64, f64),
    poses: &[Pose],
    estimates: &[CircumferenceEstimate],
) -> Result<OutageReport> {
    let (ta, tb) = outage;
    let truth = drive.truth.as_deref().unwrap_or_default();
    let truth_params = drive.truth_params.as_ref();
    let mut distance = 0.0;
    for w in truth.windows(2) {
        if w[0].t_s >= ta && w[1].t_s <= tb {
            distance += (w[1].x_m - w[0].x_m).hypot(w[1].y_m - w[0].y_m);
        }
    }
    // The live pose at the outage start (else the truth there).
    let before = poses.iter().rev().find(|p| p.header.t_s() <= ta);
    let start = match before {
        Some(p) => (
            p.header.t_s(),
            Pose2 {
                x: p.x_m,
                y: p.y_m,
                yaw: p.yaw_rad,
            },
        ),
        None => {
            let i = truth
                .partition_point(|s| s.t_s < ta)
                .min(truth.len().saturating_sub(1));
            let s = truth
                .get(i)
                .copied()
                .ok_or_else(|| anyhow::anyhow!("no truth"))?;
            (
                s.t_s,
                Pose2 {
                    x: s.x_m,
                    y: s.y_m,
                    yaw: s.yaw_rad.unwrap_or(0.0),
                },
            )
        }
    };
    let version_at_start = before.map_or(0, |p| p.estimate_version);
    let estimate = estimates
        .iter()
        .rev()
        .find(|e| e.version == version_at_start && version_at_start > 0)
        .copied();
    let nominal = OdometryParams::nominal(&drive.vehicle);
    let calibrated = match &estimate {
        Some(e) => Some(Estimate::from_wire(e)?.params),
        None => None,
    };
    let mut offline = Vec::new();
    let mut tracks: [Vec<[f64; 2]>; 2] = [Vec::new(), Vec::new()];
    for heading in [HeadingMode::Gyro, HeadingMode::WheelDifference] {
        let (ne, nm, ntrack) = dead_reckon(drive, nominal, heading, start.1, start.0, tb)?;
        let cal = match calibrated {
            Some(p) => Some(dead_reckon(drive, p, heading, start.1, start.0, tb)?),
            None => None,
        };
        if heading == HeadingMode::Gyro {
            tracks[0] = ntrack;
            if let Some((_, _, t)) = &cal {
                tracks[1] = t.clone();
            }
        }
        offline.push(OfflineRow {
            heading: heading.name().to_string(),
            nominal_end_error_m: ne,
            nominal_max_error_m: nm,
            calibrated_end_error_m: cal.as_ref().map(|c| c.0),
            calibrated_max_error_m: cal.as_ref().map(|c| c.1),
        });
    }
    // When the live odometry switched estimates: its first pose with each version.
    let mut switches = Vec::new();
    let mut version = 0;
    for p in poses {
        if p.estimate_version != version {
            version = p.estimate_version;
            if let Some(e) = estimates.iter().rev().find(|e| e.version == version) {
                switches.push((p.header.t_s() - 1e-6, version, Estimate::from_wire(e)?));
            }
        }
    }
    let (fe_nominal, fm_nominal) = filter_through_outage(drive, &[], outage)?;
    let mut filter = vec![FilterRow {
        parameters: "nominal".to_string(),
        end_error_m: fe_nominal,
        max_error_m: fm_nominal,
    }];
    if !switches.is_empty() {
        let (e, m) = filter_through_outage(drive, &switches, outage)?;
        filter.push(FilterRow {
            parameters: format!(
                "estimates v{} as taken live",
                switches
                    .iter()
                    .map(|s| s.1.to_string())
                    .collect::<Vec<_>>()
                    .join(", v")
            ),
            end_error_m: e,
            max_error_m: m,
        });
    }
    let inside: Vec<&Pose> = poses
        .iter()
        .filter(|p| p.header.t_s() > ta && p.header.t_s() <= tb)
        .collect();
    let live = inside.last().map(|last| {
        let err =
            |p: &Pose| truth_at(truth, p.header.t_s()).map(|(x, y)| (p.x_m - x).hypot(p.y_m - y));
        let c = &last.covariance;
        let cov = [c[0], c[1], c[3], c[4]];
        let end_chi2 = truth_at(truth, last.header.t_s())
            .and_then(|(x, y)| position_chi2([last.x_m - x, last.y_m - y], cov));
        // Largest eigenvalue of the 2x2 position covariance.
        let mean = 0.5 * (cov[0] + cov[3]);
        let largest = mean + (0.25 * (cov[0] - cov[3]).powi(2) + cov[1] * cov[1]).sqrt();
        LiveResult {
            estimate_version: last.estimate_version,
            poses: inside.len(),
            dead_reckoning_poses: inside
                .iter()
                .filter(|p| p.mode == PoseMode::DeadReckoning as u8)
                .count(),
            end_error_m: err(last).unwrap_or(f64::NAN),
            max_error_m: inside.iter().filter_map(|p| err(p)).fold(0.0, f64::max),
            end_chi2,
            end_ellipse_95_m: (CHI2_2DOF_95 * largest.max(0.0)).sqrt(),
        }
    });
    Ok(OutageReport {
        outage_start_s: ta,
        outage_end_s: tb,
        outage_distance_m: distance,
        true_circumference_m: truth_params.map_or([f64::NAN; 2], |t| {
            [t.circumference_m.rl, t.circumference_m.rr]
        }),
        nominal_circumference_m: drive.vehicle.nominal_circumference_m,
        published: estimates
            .iter()
            .map(|e| (e.version, e.c_rl_m, e.c_rr_m))
            .collect(),
        estimate: estimate.map(|e| EstimateInfo {
            version: e.version,
            c_rl_m: e.c_rl_m,
            c_rr_m: e.c_rr_m,
            track_width_m: e.track_width_m,
            gyro_bias_rad_s: e.gyro_bias_rad_s,
            gyro_scale: e.gyro_scale,
            fitted_until_s: e.header.t_s(),
        }),
        start_pose: [start.1.x, start.1.y, start.1.yaw],
        live,
        offline,
        filter,
        tracks,
    })
}

impl OutageReport {
    /// The text shown at the end of the demo.
    pub fn render(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "\n================ wheelcal demo: result ================"
        );
        let _ = writeln!(
            s,
            "GNSS outage: {:.0} s .. {:.0} s ({:.0} s, {:.0} m driven)",
            self.outage_start_s,
            self.outage_end_s,
            self.outage_end_s - self.outage_start_s,
            self.outage_distance_m
        );
        let _ = writeln!(
            s,
            "rear circumferences: true {:.4} / {:.4} m, nominal {:.4} m",
            self.true_circumference_m[0],
            self.true_circumference_m[1],
            self.nominal_circumference_m
        );
        for (v, rl, rr) in &self.published {
            let _ = writeln!(s, "calibrator published v{v}: {rl:.4} / {rr:.4} m");
        }
        match &self.estimate {
            Some(e) => {
                let _ = writeln!(
                    s,
                    "in use at the outage start: v{} ({:.4} / {:.4} m, fitted on data up to t = {:.0} s)",
                    e.version, e.c_rl_m, e.c_rr_m, e.fitted_until_s
                );
            }
            None => {
                let _ = writeln!(
                    s,
                    "no estimate was in use at the outage start (nominal values)"
                );
            }
        }
        let _ = writeln!(
            s,
            "\nodometry filter (GNSS + heading + calibrated gyro, 2W distance) through the outage:"
        );
        for r in &self.filter {
            let _ = writeln!(
                s,
                "  {:<34} {:8.2} m at the end, {:8.2} m max",
                r.parameters, r.end_error_m, r.max_error_m
            );
        }
        match &self.live {
            Some(l) => {
                let _ = writeln!(
                    s,
                    "  {:<34} {:8.2} m at the end, {:8.2} m max ({} of {} poses dead-reckoned)",
                    format!("live process (estimate v{})", l.estimate_version),
                    l.end_error_m,
                    l.max_error_m,
                    l.dead_reckoning_poses,
                    l.poses
                );
                let inside = match l.end_chi2 {
                    Some(c) if c <= CHI2_2DOF_95 => "inside it",
                    Some(_) => "OUTSIDE it",
                    None => "not judged (singular covariance)",
                };
                let _ = writeln!(
                    s,
                    "  {:<34} 95 % ellipse of its own covariance at the end: {:.2} m semi-major, the error {inside}",
                    "", l.end_ellipse_95_m
                );
            }
            None => {
                let _ = writeln!(s, "  live process: no pose inside the outage");
            }
        }
        let _ = writeln!(
            s,
            "\npure 2W dead-reckoning without heading aid, error at the outage end (max inside it):"
        );
        let _ = writeln!(
            s,
            "  heading   nominal c              calibrated c           ratio"
        );
        for r in &self.offline {
            let cal = match (r.calibrated_end_error_m, r.calibrated_max_error_m) {
                (Some(e), Some(m)) => format!("{e:8.2} m ({m:8.2} m)"),
                _ => format!("{:>22}", "-"),
            };
            let ratio = r
                .calibrated_end_error_m
                .filter(|e| *e > 0.0)
                .map_or("-".to_string(), |e| {
                    format!("{:.1}x", r.nominal_end_error_m / e)
                });
            let _ = writeln!(
                s,
                "  {:<8} {:8.2} m ({:8.2} m)  {cal}  {ratio}",
                r.heading, r.nominal_end_error_m, r.nominal_max_error_m
            );
        }
        let _ = writeln!(
            s,
            "  (from the live pose at the outage start, with the odometry's own dead-reckoning code)"
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truth_is_interpolated_inside_and_none_outside() {
        let t = |t_s: f64, x_m: f64| TruthSample {
            t_s,
            x_m,
            y_m: 2.0 * x_m,
            yaw_rad: None,
        };
        let truth = [t(0.0, 0.0), t(1.0, 10.0), t(2.0, 30.0)];
        assert_eq!(truth_at(&truth, 0.5), Some((5.0, 10.0)));
        assert_eq!(truth_at(&truth, 1.5), Some((20.0, 40.0)));
        assert_eq!(truth_at(&truth, 2.0), Some((30.0, 60.0)));
        assert_eq!(truth_at(&truth, -0.1), None);
        assert_eq!(truth_at(&truth, 2.5), None);
    }
}
