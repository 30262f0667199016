//! The calibration in the forms other stacks take: an Autoware-style ROS 2
//! parameter file (the speed scale factor of its vehicle velocity converter
//! and the yaw-rate offset of its IMU corrector) and the 2W parameters as
//! TOML. Pure: the functions return the text; the binary writes the files.
//! Each file says in a comment which drive, which wheelcal version and
//! which method it came from.

use crate::result::Calibration;
use std::fmt::Write as _;

/// Where a calibration came from, for the files' comments.
#[derive(Debug, Clone, PartialEq)]
pub struct Provenance {
    /// The drive (its path or name).
    pub drive: String,
    /// The wheelcal version that calibrated it.
    pub version: String,
}

/// The common scale of the wheel speeds: the mean estimated circumference
/// over the nominal one (a speed computed with the nominal circumference,
/// times this, is the true speed).
pub fn speed_scale_factor(c: &Calibration) -> f64 {
    0.5 * (c.circumference_m.rl + c.circumference_m.rr) / c.nominal.circumference_m
}

fn header(s: &mut String, c: &Calibration, p: &Provenance, comment: &str) {
    let _ = writeln!(
        s,
        "{comment} Wheel calibration of the drive {} by wheelcal {} ({} method).",
        p.drive, p.version, c.method
    );
    if let Some(name) = c.vehicle.as_ref().and_then(|v| v.name.as_deref()) {
        let _ = writeln!(s, "{comment} Vehicle: {name}.");
    }
    if !c.warnings.is_empty() {
        let _ = writeln!(
            s,
            "{comment} The calibration raised {} warning(s); read its report before use.",
            c.warnings.len()
        );
    }
}

/// An Autoware-style ROS 2 parameter file: `speed_scale_factor` (the
/// vehicle velocity converter's: the reported speed is multiplied by it)
/// and `angular_velocity_offset_z` (the IMU corrector's: subtracted from
/// the measured yaw rate), with their sigmas in comments. The gyro scale
/// error, which those nodes do not take, is given in a comment.
pub fn autoware_yaml(c: &Calibration, p: &Provenance) -> String {
    let mut s = String::new();
    header(&mut s, c, p, "#");
    let factor = speed_scale_factor(c);
    let _ = writeln!(
        s,
        "# speed_scale_factor = mean(c_RL, c_RR) / nominal circumference = ({:.6} + {:.6}) / 2 / {:.6} m;",
        c.circumference_m.rl, c.circumference_m.rr, c.nominal.circumference_m
    );
    let _ = writeln!(
        s,
        "# it assumes the vehicle reports its speed with the nominal circumference."
    );
    if let Some(sm) = c.sigma_m.mean {
        let _ = writeln!(
            s,
            "# 1-sigma of the factor: {:.6}.",
            sm / c.nominal.circumference_m
        );
    }
    let _ = writeln!(s, "/**:\n  ros__parameters:");
    let _ = writeln!(s, "    speed_scale_factor: {factor:.6}");
    match &c.gyro {
        Some(g) => {
            let _ = writeln!(
                s,
                "    # yaw-rate offset, rad/s (1-sigma {:.2e}); gyro scale error {:+.5} not applied by this parameter",
                g.sigma_bias_rad_s, g.scale
            );
            let _ = writeln!(s, "    angular_velocity_offset_z: {:.8}", g.bias_rad_s);
        }
        None => {
            let _ = writeln!(
                s,
                "    # the gyro was not calibrated (no IMU or --no-gyro): no angular_velocity_offset_z"
            );
        }
    }
    s
}

/// The 2W model's parameters as TOML: the circumferences, the track width,
/// the gyro bias and scale, with their sigmas.
pub fn two_wheel_toml(c: &Calibration, p: &Provenance) -> String {
    let mut s = String::new();
    header(&mut s, c, p, "#");
    let _ = writeln!(s, "[two_wheel]");
    let _ = writeln!(s, "c_rl_m = {:.6}", c.circumference_m.rl);
    let _ = writeln!(s, "c_rr_m = {:.6}", c.circumference_m.rr);
    let _ = writeln!(s, "track_width_m = {:.5}", c.track_width_m);
    let _ = writeln!(s, "track_width_estimated = {}", c.track_width_estimated);
    let _ = writeln!(
        s,
        "nominal_circumference_m = {:.6}",
        c.nominal.circumference_m
    );
    if let Some(g) = &c.gyro {
        let _ = writeln!(s, "gyro_bias_rad_s = {:.8}", g.bias_rad_s);
        let _ = writeln!(s, "gyro_scale = {:.6}", g.scale);
    }
    let sig: Vec<String> = [
        ("c_rl_m", c.sigma_m.rl),
        ("c_rr_m", c.sigma_m.rr),
        ("difference_m", c.sigma_m.difference),
        ("mean_m", c.sigma_m.mean),
        ("track_width_m", c.sigma_track_width_m),
        (
            "gyro_bias_rad_s",
            c.gyro.as_ref().map(|g| g.sigma_bias_rad_s),
        ),
        ("gyro_scale", c.gyro.as_ref().and_then(|g| g.sigma_scale)),
    ]
    .iter()
    .filter_map(|(k, v)| v.map(|v| format!("{k} = {v:.3e}")))
    .collect();
    if !sig.is_empty() {
        let _ = writeln!(s, "\n[two_wheel.sigma]");
        for line in sig {
            let _ = writeln!(s, "{line}");
        }
    }
    s
}
