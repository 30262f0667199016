//! Checks that a drive obeys the format's rules before it is written, so that
//! what is written always reads back (a NaN would be refused on reading).

use super::DriveError;
use interfaces::drive::{Drive, WheelUnit};

fn invalid(stream: &str, index: usize, message: String) -> DriveError {
    DriveError::InvalidDrive {
        stream: stream.to_string(),
        index,
        message,
    }
}

/// Check one stream: `t_s` finite and strictly increasing, every value finite.
/// `values` lists (field name, value) of one sample.
fn series<T>(
    stream: &str,
    samples: &[T],
    time: impl Fn(&T) -> f64,
    values: impl Fn(&T) -> Vec<(&'static str, Option<f64>)>,
) -> Result<(), DriveError> {
    let mut previous: Option<f64> = None;
    for (i, s) in samples.iter().enumerate() {
        let t = time(s);
        if !t.is_finite() {
            return Err(invalid(stream, i, format!("t_s = {t} is not finite")));
        }
        if let Some(p) = previous {
            if t <= p {
                return Err(invalid(
                    stream,
                    i,
                    format!("t_s = {t} does not increase (previous {p})"),
                ));
            }
        }
        previous = Some(t);
        for (name, v) in values(s) {
            if let Some(v) = v {
                if !v.is_finite() {
                    return Err(invalid(stream, i, format!("{name} = {v} is not finite")));
                }
            }
        }
    }
    Ok(())
}

pub(super) fn drive(d: &Drive) -> Result<(), DriveError> {
    let v = &d.vehicle;
    let vehicle_values = [
        ("track_width_m", Some(v.track_width_m)),
        ("nominal_circumference_m", Some(v.nominal_circumference_m)),
        ("wheelbase_m", v.wheelbase_m),
        ("ticks_per_rev", v.ticks_per_rev),
        ("gnss.antenna_x_m", v.gnss.antenna_x_m),
        ("gnss.antenna_y_m", v.gnss.antenna_y_m),
        ("gnss.origin_lat_deg", v.gnss.origin_lat_deg),
        ("gnss.origin_lon_deg", v.gnss.origin_lon_deg),
    ];
    for (name, value) in vehicle_values {
        if let Some(x) = value {
            if !x.is_finite() {
                return Err(invalid("vehicle", 0, format!("{name} = {x} is not finite")));
            }
        }
    }
    let units = d.wheels.units;
    let has_ticks =
        [Some(units.rl), Some(units.rr), units.fl, units.fr].contains(&Some(WheelUnit::Ticks));
    if has_ticks && v.ticks_per_rev.is_none() {
        return Err(invalid(
            "vehicle",
            0,
            "wheels are in ticks but ticks_per_rev is not set".to_string(),
        ));
    }
    series(
        "wheels",
        &d.wheels.samples,
        |s| s.t_s,
        |s| {
            let mut out = vec![
                ("rl", Some(s.rl)),
                ("rr", Some(s.rr)),
                ("fl", s.fl),
                ("fr", s.fr),
            ];
            // A front value without a front column would be lost on writing.
            if units.fl.is_none() && s.fl.is_some() {
                out.push(("fl (no fl unit set)", Some(f64::NAN)));
            }
            if units.fr.is_none() && s.fr.is_some() {
                out.push(("fr (no fr unit set)", Some(f64::NAN)));
            }
            out
        },
    )?;
    if let Some(g) = &d.gnss {
        series(
            "gnss",
            g,
            |s| s.t_s,
            |s| {
                vec![
                    ("x_m", Some(s.x_m)),
                    ("y_m", Some(s.y_m)),
                    ("sigma_m", s.sigma_m),
                ]
            },
        )?;
    }
    if let Some(imu) = &d.imu {
        series(
            "imu",
            imu,
            |s| s.t_s,
            |s| {
                vec![
                    ("gz_rad_s", Some(s.gz_rad_s)),
                    ("ax_m_s2", s.ax_m_s2),
                    ("ay_m_s2", s.ay_m_s2),
                    ("az_m_s2", s.az_m_s2),
                    ("gx_rad_s", s.gx_rad_s),
                    ("gy_rad_s", s.gy_rad_s),
                ]
            },
        )?;
    }
    if let Some(h) = &d.heading {
        series(
            "heading",
            h,
            |s| s.t_s,
            |s| vec![("yaw_rad", Some(s.yaw_rad)), ("sigma_rad", s.sigma_rad)],
        )?;
    }
    if let Some(t) = &d.truth {
        series(
            "truth",
            t,
            |s| s.t_s,
            |s| {
                vec![
                    ("x_m", Some(s.x_m)),
                    ("y_m", Some(s.y_m)),
                    ("yaw_rad", s.yaw_rad),
                ]
            },
        )?;
    }
    Ok(())
}
