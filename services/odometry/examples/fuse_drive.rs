//! Run the service's filter offline over a drive and summarise it: modes,
//! gated fixes, and the position error against truth.csv where there is one.
//!
//! ```text
//! cargo run --release -p odometry --example fuse_drive -- DRIVE [gyro|wheels] [EST.json]
//! ```
//!
//! The GNSS antenna is chosen as `odometry serve` does
//! ([`vehicle_model::estimate::gnss_lever_arm`]): `vehicle.toml`'s, else the
//! estimate's; `FUSION_NO_ANTENNA=1` leaves the estimate's out.
//! `FUSION_TRUTH_POINT=antenna` scores the antenna point of each pose (for
//! drives whose truth is the GNSS track, e.g. WID) instead of the rear axle.
//! `FUSION_OUTAGE=SECONDS` also runs the filter once per GNSS outage of that
//! length, placed every 10 s from 20 s after the first fix, the fixes inside
//! it (its end included) left out, and prints the error at each outage end:
//! the served pose through an outage, started from the filter's own pose.
//! `FUSION_GNSS_LATE=SECONDS` delivers every fix that long after its time
//! stamp, as a GNSS receiver does, to the filter behind the service's
//! [`odometry::rewind::RewindingFusion`]; `FUSION_REWIND_WINDOW=SECONDS`
//! sets its window (default 1 s; 0: late fixes applied when they come).
//! `FUSION_AT_STAMPS=1` reads every fix at its stamp, as the service did
//! before it read jittered fixes at the receiver's epochs
//! ([`odometry::inputs::GnssEpochs`]).

use anyhow::{bail, Result};
use interfaces::drive::{Drive, TruthSample};
use interfaces::wire::PoseMode;
use odometry::dead_reckoning::{HeadingMode, OdometerConfig};
use odometry::fused_outages::{fused_outages, inside_95, median_error, FusedOutageConfig};
use odometry::fusion::{Fusion, FusionConfig};
use odometry::inputs::{drive_inputs, drive_inputs_at_stamps, gnss_late, sort_by_delivery, Input};
use odometry::rewind::{RewindConfig, RewindingFusion};
use std::path::PathBuf;
use vehicle_model::estimate::gnss_lever_arm;
use vehicle_model::two_wheel::Pose2;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        bail!("usage: fuse_drive DRIVE [gyro|wheels] [EST.json]");
    };
    let drive = drive_io::read_drive(&PathBuf::from(path))?.drive;
    let heading: HeadingMode = match args.get(1) {
        Some(h) => h.parse().map_err(anyhow::Error::msg)?,
        None => HeadingMode::Gyro,
    };
    let estimate = args
        .get(2)
        .map(|p| drive_io::read_estimate(&PathBuf::from(p)))
        .transpose()?
        .map(|mut e| {
            if std::env::var("FUSION_NO_ANTENNA").is_ok_and(|v| v == "1") {
                e.antenna_m = None;
            }
            e
        });
    let (lever_arm_m, measured) = gnss_lever_arm(&drive.vehicle, estimate.as_ref());
    let at_antenna = match std::env::var("FUSION_TRUTH_POINT").as_deref() {
        Ok("antenna") => true,
        Ok("axle") | Err(_) => false,
        Ok(other) => bail!("FUSION_TRUTH_POINT={other}: expected axle or antenna"),
    };
    let config = fusion_config(heading, lever_arm_m, measured);
    let new_fusion = || match &estimate {
        Some(e) => Fusion::new(e.params, 0, config),
        None => Fusion::nominal(&drive.vehicle, config),
    };
    let rewind = RewindConfig {
        window_s: env("FUSION_REWIND_WINDOW").unwrap_or(RewindConfig::default().window_s),
        ..RewindConfig::default()
    };
    let gnss_late_s = env("FUSION_GNSS_LATE").unwrap_or(0.0);
    let mut filter = RewindingFusion::new(new_fusion(), rewind);
    println!(
        "GNSS antenna ({:+.3}, {:+.3}) m ({}), scored at the {}",
        lever_arm_m[0],
        lever_arm_m[1],
        if measured {
            "vehicle.toml"
        } else {
            "estimate or none"
        },
        if at_antenna { "antenna" } else { "rear axle" }
    );
    let params = *filter.fusion().params();
    let truth = drive.truth.clone().unwrap_or_default();
    let (counts, errors) = run_filter(&mut filter, &drive, &truth, gnss_late_s, at_antenna)?;
    let s = filter.fusion().stats();
    println!("heading {heading}, parameters {params}");
    if gnss_late_s > 0.0 {
        println!(
            "fixes delivered {gnss_late_s} s late, rewind window {} s: {:?}",
            rewind.window_s,
            filter.stats()
        );
    }
    println!(
        "poses: NoFix {}, Fused {}, DeadReckoning {}",
        counts[0], counts[1], counts[2]
    );
    println!("{s:?}");
    print_errors(&errors);
    if let Some(length) = env("FUSION_OUTAGE") {
        print_outages(&drive, &truth, &new_fusion, length, at_antenna)?;
    }
    Ok(())
}

/// A number from the environment variable `k`, when set and a number.
fn env(k: &str) -> Option<f64> {
    std::env::var(k).ok().and_then(|v| v.parse::<f64>().ok())
}

/// The filter's configuration: `heading`, the GNSS antenna (`measured`:
/// from `vehicle.toml`, else estimates may bring theirs), and the tuning
/// experiments of the environment: FUSION_DS (distance white noise
/// fraction), FUSION_MINSIG (smallest GNSS sigma, m), FUSION_GYRO (angle
/// random walk, rad/sqrt(s)), FUSION_SCALE_SIGMA (1-sigma of the distance
/// scale error of calibrated wheels, the filter's consider state),
/// FUSION_WHEEL_DIFF_SIGMA (of their relative circumference error).
fn fusion_config(heading: HeadingMode, lever_arm_m: [f64; 2], measured: bool) -> FusionConfig {
    let mut config = FusionConfig {
        odometer: OdometerConfig {
            heading,
            ..OdometerConfig::default()
        },
        lever_arm_m,
        lever_arm_from_estimates: !measured,
        ..FusionConfig::default()
    };
    if let Some(v) = env("FUSION_DS") {
        config.distance_noise_frac = v;
    }
    if let Some(v) = env("FUSION_MINSIG") {
        config.min_gnss_sigma_m = v;
    }
    if let Some(v) = env("FUSION_GYRO") {
        config.gyro_noise_rad_per_sqrt_s = v;
    }
    if let Some(v) = env("FUSION_SCALE_SIGMA") {
        config.distance_scale_sigma = v;
    }
    if let Some(v) = env("FUSION_WHEEL_DIFF_SIGMA") {
        config.wheel_difference_sigma = v;
    }
    config
}

/// The point of a pose that the truth describes: the antenna's
/// (`at_antenna`) or the rear axle's.
fn scored(fusion: &Fusion, pose: &Pose2, at_antenna: bool) -> [f64; 2] {
    let arm = if at_antenna {
        fusion.lever_arm()
    } else {
        [0.0, 0.0]
    };
    pose.point_at(arm)
}

/// The poses of each mode and the errors at the truth rows.
type FilterRun = ([usize; 3], Vec<(PoseMode, f64)>);

/// Every input of `drive` through `filter`, in the order they are
/// delivered (the fixes `gnss_late_s` after their time): the poses of
/// each mode, and the error of each pose at a truth row (nearest wheel
/// sample within 5 ms), with its mode.
fn run_filter(
    filter: &mut RewindingFusion,
    drive: &Drive,
    truth: &[TruthSample],
    gnss_late_s: f64,
    at_antenna: bool,
) -> Result<FilterRun> {
    let mut counts = [0usize; 3];
    let mut errors = Vec::new();
    let mut ti = 0usize;
    let verbose = std::env::var("FUSION_VERBOSE").is_ok();
    // In the order they are delivered: the fixes `gnss_late_s` after their time.
    let mut delivered = inputs_of(drive)?;
    sort_by_delivery(&mut delivered, gnss_late(gnss_late_s));
    for input in delivered {
        let before = filter.fusion().stats();
        let out = filter.process(&input)?;
        let after = filter.fusion().stats();
        if verbose
            && (after.gnss_rejected > before.gnss_rejected
                || after.position_resets > before.position_resets)
        {
            println!(
                "t = {:.2}: fix rejected (resets {})",
                input.t_s(),
                after.position_resets
            );
        }
        if let Some(pose) = out {
            counts[pose.mode as usize] += 1;
            // Error at truth rows (nearest wheel sample within 5 ms).
            while ti < truth.len() && truth[ti].t_s < pose.t_s - 0.005 {
                ti += 1;
            }
            if let Some(r) = truth.get(ti) {
                if (r.t_s - pose.t_s).abs() <= 0.005 && pose.mode != PoseMode::NoFix {
                    let [x, y] = scored(filter.fusion(), &pose.pose, at_antenna);
                    errors.push((pose.mode, (x - r.x_m).hypot(y - r.y_m)));
                }
            }
        }
    }
    Ok((counts, errors))
}

/// The median, p90 and largest error of the fused and the dead-reckoned
/// poses.
fn print_errors(errors: &[(PoseMode, f64)]) {
    for mode in [PoseMode::Fused, PoseMode::DeadReckoning] {
        let mut e: Vec<f64> = errors
            .iter()
            .filter(|(m, _)| *m == mode)
            .map(|(_, e)| *e)
            .collect();
        e.sort_by(f64::total_cmp);
        if !e.is_empty() {
            println!(
                "{mode:?}: error vs truth median {:.3} m, p90 {:.3} m, max {:.3} m ({} points)",
                e[e.len() / 2],
                e[(e.len() * 9) / 10],
                e[e.len() - 1],
                e.len()
            );
        }
    }
}

/// The filter run once per GNSS outage of `length` s: the error at each
/// outage's end, their median, and how many end inside the pose's own
/// 95 % ellipse.
fn print_outages(
    drive: &Drive,
    truth: &[TruthSample],
    new_fusion: &dyn Fn() -> Fusion,
    length: f64,
    at_antenna: bool,
) -> Result<()> {
    let config = FusedOutageConfig {
        length_s: length,
        at_antenna,
        ..FusedOutageConfig::default()
    };
    let outages = fused_outages(&inputs_of(drive)?, truth, new_fusion, &config)?;
    for o in &outages {
        let end = o.t_start_s + length;
        match o.error_m {
            Some(e) if o.counted() => println!(
                "outage {:.1}-{end:.1} s: error {e:.3} m at its end (chi-square {})",
                o.t_start_s,
                o.error_chi2.map_or("-".to_string(), |c| format!("{c:.2}"))
            ),
            Some(e) => println!(
                "outage {:.1}-{end:.1} s: error {e:.3} m at its end; not counted: the filter was \
                 already dead-reckoning at its start (fixes gated out before it)",
                o.t_start_s
            ),
            None => println!(
                "outage {:.1}-{end:.1} s: not counted (the filter was {:?} at its start, or no truth at its end)",
                o.t_start_s, o.mode_at_start
            ),
        }
    }
    if let Some(m) = median_error(&outages) {
        let n = outages.iter().filter(|o| o.counted()).count();
        println!(
            "{length} s outages in the filter: median error at the end {m:.3} m ({n} outages)"
        );
        let (inside, counted) = inside_95(&outages);
        println!("{inside} of {counted} end inside the 95 % ellipse of the pose's own covariance");
    }
    Ok(())
}

/// The drive's inputs as the service reads them, or at the stamps with
/// `FUSION_AT_STAMPS=1`.
fn inputs_of(drive: &Drive) -> Result<Vec<Input>> {
    Ok(
        if std::env::var("FUSION_AT_STAMPS").is_ok_and(|v| v == "1") {
            drive_inputs_at_stamps(drive)?
        } else {
            drive_inputs(drive)?
        },
    )
}
