//! The readable text report of a [`Calibration`]: drive facts, the
//! per-iteration table, the result with sigmas, the comparison and the
//! warnings.

use crate::clocks::offsets::{OffsetStatus, StreamOffset};
use crate::result::Calibration;
use std::fmt::Write as _;

fn mm(v: Option<f64>) -> String {
    v.map_or("not determined".to_string(), |v| {
        format!("{:.2} mm", 1000.0 * v)
    })
}

fn clock_offset(o: &StreamOffset) -> String {
    match (o.status, o.offset_s, o.sigma_s) {
        (OffsetStatus::Determined, Some(v), Some(sd)) => format!(
            "{:+.0} ms relative to the wheels (sigma {:.0} ms, from the {}){}",
            1000.0 * v,
            1000.0 * sd,
            o.from.as_deref().unwrap_or("signals"),
            match (o.applied, o.applied_s) {
                (true, Some(a)) => format!(", compensated by {:+.0} ms (the GNSS's)", 1000.0 * a),
                (true, None) => ", compensated".to_string(),
                _ => ", not applied".to_string(),
            }
        ),
        (OffsetStatus::NotChecked, _, _) => format!(
            "not checked ({})",
            o.reason.as_deref().unwrap_or("no reason")
        ),
        _ => format!(
            "not determined ({})",
            o.reason.as_deref().unwrap_or("no reason")
        ),
    }
}

/// The readable report: drive facts, the per-iteration table, the result
/// with sigmas, the comparison and the warnings.
pub fn render_text(c: &Calibration) -> String {
    let mut s = String::new();
    write_drive(&mut s, c);
    write_iterations(&mut s, c);
    write_result(&mut s, c);
    write_comparison(&mut s, c);
    write_warnings(&mut s, c);
    s
}

/// The drive facts: the method, the drive, the GNSS, the wheels' rate
/// offsets and the clocks' offsets and drifts.
fn write_drive(s: &mut String, c: &Calibration) {
    let d = &c.diagnostics;
    let _ = writeln!(
        s,
        "calibration: method {} (side-slip {})",
        c.method,
        if c.side_slip { "on" } else { "off" }
    );
    let _ = writeln!(
        s,
        "drive: {:.1} s, {:.0} m with GNSS reference, turning {:.0} deg in total, standstill {:.0} s",
        d.duration_s, d.distance_m, d.total_turn_deg, d.standstill_s
    );
    let _ = writeln!(
        s,
        "gnss: {} fixes, {} outliers rejected, {} jumps set aside ({} fixes), {} outages bridged, sigma {:.3} m ({}), antenna at ({:.2}, {:.2}) m",
        d.gnss_fixes,
        d.gnss_outliers,
        d.gnss_jumps.len(),
        d.gnss_jumps.iter().map(|j| j.fixes).sum::<usize>(),
        d.gnss_outages,
        d.gnss_sigma_m,
        if d.gnss_sigma_estimated { "estimated" } else { "given" },
        d.lever_arm_m[0],
        d.lever_arm_m[1]
    );
    if let Some(o) = d.wheel_rate_offsets {
        let _ = writeln!(
            s,
            "wheels: rate offsets at standstill subtracted: rl {:+.5}, rr {:+.5} (channel units)",
            o[0], o[1]
        );
    }
    for (name, o) in [
        ("GNSS", &c.clock_offsets.gnss_s),
        ("IMU", &c.clock_offsets.imu_s),
    ] {
        let _ = writeln!(s, "clock offset: {name} {}", clock_offset(o));
        let _ = writeln!(s, "clock drift: {name} {}", o.drift);
    }
    for p in &c.clock_offsets.pairs {
        let weak = match (p.offset.status, p.offset.weak) {
            (OffsetStatus::NotDetermined, Some([v, sd])) => format!(
                "; weak fit {:+.0} ms (sigma {:.0} ms) used in the combination",
                1000.0 * v,
                1000.0 * sd
            ),
            _ => String::new(),
        };
        let _ = writeln!(
            s,
            "clock pair: {} against {} {}{weak}",
            p.later.name(),
            p.base.name(),
            clock_offset(&p.offset).replace("relative to the wheels ", "")
        );
    }
}

/// The per-iteration table (the kept one starred).
fn write_iterations(s: &mut String, c: &Calibration) {
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "  iter    c_RL [m]    c_RR [m]   track [m]   DR mean [m]   DR max [m]"
    );
    for it in &c.iterations {
        let _ = writeln!(
            s,
            "{} {:4}   {:9.6}   {:9.6}   {:9.4}   {:11.2}   {:10.2}",
            if it.n == c.selected_iteration {
                "*"
            } else {
                " "
            },
            it.n,
            it.circumference_m.rl,
            it.circumference_m.rr,
            it.track_width_m,
            it.dr_error_mean_m,
            it.dr_error_max_m
        );
    }
    let _ = writeln!(s, "(* = kept; DR = the 2W model integrated over the whole drive without fusion, against the reference)");
}

/// The result with sigmas, the fit's residual and quality.
fn write_result(s: &mut String, c: &Calibration) {
    let d = &c.diagnostics;
    let _ = writeln!(s);
    let _ = writeln!(s, "result:");
    let _ = writeln!(
        s,
        "  c_RL         = {:.5} m  (sigma {})",
        c.circumference_m.rl,
        mm(c.sigma_m.rl)
    );
    let _ = writeln!(
        s,
        "  c_RR         = {:.5} m  (sigma {})",
        c.circumference_m.rr,
        mm(c.sigma_m.rr)
    );
    let _ = writeln!(
        s,
        "  c_RR - c_RL  = {:+.2} mm  (sigma {})",
        1000.0 * (c.circumference_m.rr - c.circumference_m.rl),
        mm(c.sigma_m.difference)
    );
    let _ = writeln!(
        s,
        "  track width  = {:.4} m  ({})",
        c.track_width_m,
        if c.track_width_estimated {
            format!("estimated, sigma {}", mm(c.sigma_track_width_m))
        } else {
            "nominal, not estimated".to_string()
        }
    );
    if let Some(k) = c.side_slip_gain_rad_per_m_s2 {
        let _ = writeln!(s, "  side-slip k  = {:.5} rad per m/s^2", k);
    }
    if let (Some(l), Some(sl)) = (c.gnss_antenna_m, c.sigma_gnss_antenna_m) {
        let _ = writeln!(
            s,
            "  GNSS antenna = ({:+.3}, {:+.3}) m body x, y from the rear-axle centre (sigma {:.3}, {:.3} m)",
            l[0], l[1], sl[0], sl[1]
        );
    }
    if let Some(g) = &c.gyro {
        let _ = writeln!(
            s,
            "  gyro bias    = {:+.6} rad/s ({:+.1} deg/h, sigma {:.1} deg/h){}",
            g.bias_rad_s,
            g.bias_rad_s.to_degrees() * 3600.0,
            g.sigma_bias_rad_s.to_degrees() * 3600.0,
            g.standstill_bias_rad_s.map_or(String::new(), |b| format!(
                "; at standstill {:+.1} deg/h",
                b.to_degrees() * 3600.0
            ))
        );
        let _ = writeln!(
            s,
            "  gyro scale   = {:+.5}{}",
            g.scale,
            g.sigma_scale
                .map_or(" (held, not estimated)".to_string(), |v| format!(
                    " (sigma {v:.5})"
                ))
        );
    }
    if let Some(rms) = d.residual_rms_m {
        let _ = writeln!(
            s,
            "  GNSS residual RMS of the fit: {rms:.3} m over {} segments",
            d.segments
        );
    }
    if let Some(b) = &d.sigma_basis {
        let _ = writeln!(s, "  sigmas from: {}", b.describe());
    }
    if let Some(q) = &c.fit_quality {
        let _ = writeln!(
            s,
            "  fit quality: the {} model fits the GNSS to {:.3} m RMS, {:.1} x the GNSS noise of {:.3} m ({}); refused beyond {:.0} x",
            q.model, q.residual_rms_m, q.ratio, q.gnss_noise_m, q.gnss_noise_source, q.limit
        );
    }
}

/// The comparison of the methods (nothing when there is none).
fn write_comparison(s: &mut String, c: &Calibration) {
    if !c.comparison.is_empty() {
        let _ = writeln!(s);
        let _ = writeln!(s, "comparison:");
        let _ = writeln!(
            s,
            "  method   c_RL [m]   sigma     c_RR [m]   sigma     track [m]   DR mean [m]   DR max [m]"
        );
        for m in &c.comparison {
            let _ = writeln!(
                s,
                "  {:6}  {:9.5}  {:>8}  {:9.5}  {:>8}  {:9.4}   {:11.2}   {:10.2}",
                m.method.name(),
                m.circumference_m.rl,
                m.sigma_m
                    .rl
                    .map_or("-".to_string(), |v| format!("{:.2}mm", 1000.0 * v)),
                m.circumference_m.rr,
                m.sigma_m
                    .rr
                    .map_or("-".to_string(), |v| format!("{:.2}mm", 1000.0 * v)),
                m.track_width_m,
                m.dr_error_mean_m,
                m.dr_error_max_m
            );
        }
    }
}

/// The warnings with their codes.
fn write_warnings(s: &mut String, c: &Calibration) {
    let _ = writeln!(s);
    if c.warnings.is_empty() {
        let _ = writeln!(s, "warnings: none");
    } else {
        let _ = writeln!(s, "warnings:");
        for w in &c.warnings {
            let code = serde_json::to_string(&w.code).unwrap_or_default();
            let _ = writeln!(s, "  - [{}] {}", code.trim_matches('"'), w.message);
        }
    }
}
