//! The result ([`Calibration`], serialised as the calibration JSON) and the
//! readable text report.
//!
//! JSON field names are a contract with the odometry and the live service:
//! `circumference_m.rl/.rr`, `sigma_m`, `track_width_m`, `gyro_bias_rad_s`,
//! `gyro_scale`, `method`, `selected_iteration`, `iterations`, `warnings`.

use crate::gyro::GyroEstimate;
use crate::prep::Prepared;
use crate::reference::{Reference, TimeOffset};
use crate::uncertainty::{observability, Sigmas};
use crate::{CalibrationConfig, CalibrationError, Method};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;

/// A value per rear wheel.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RearPair {
    /// Rear left.
    pub rl: f64,
    /// Rear right.
    pub rr: f64,
}

/// 1-sigma of the circumferences; `None` where not determined.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RearSigma {
    /// c_RL, m.
    pub rl: Option<f64>,
    /// c_RR, m.
    pub rr: Option<f64>,
    /// c_RR - c_RL, m.
    pub difference: Option<f64>,
    /// (c_RL + c_RR) / 2, m.
    pub mean: Option<f64>,
}

impl From<&Sigmas> for RearSigma {
    fn from(s: &Sigmas) -> Self {
        let f = |v: f64| v.is_finite().then_some(v);
        RearSigma {
            rl: f(s.rl),
            rr: f(s.rr),
            difference: f(s.difference),
            mean: f(s.mean),
        }
    }
}

/// What a warning is about (stable, for programs and tests).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WarningCode {
    /// Rows with NaN/inf values were skipped.
    NonFiniteSamples,
    /// A stream pauses.
    StreamGap,
    /// A stream starts late or stops early.
    StreamStops,
    /// No IMU.
    NoImu,
    /// GNSS fixes rejected as outliers.
    GnssOutliers,
    /// GNSS outages (bridged).
    GnssOutage,
    /// The wheel/GNSS time offset.
    TimeOffset,
    /// Side-slip requested but not available.
    SideSlipUnavailable,
    /// The drive has no turn.
    NoTurn,
    /// c_RL and c_RR are not separated.
    DifferenceUnobservable,
    /// The common scale is poorly determined.
    ScaleUnobservable,
    /// The track width is poorly determined.
    TrackWidthUnobservable,
    /// The track width was kept at the nominal value.
    TrackWidthFixed,
    /// The estimated track width is implausible.
    TrackWidthImplausible,
    /// The gyro bias/scale could not be estimated.
    GyroUnobservable,
    /// The gyro scale was held at 0.
    GyroScaleUnobservable,
    /// The paper's loop was still improving at its last iteration.
    NotConverged,
    /// The methods compared disagree beyond their sigmas.
    MethodsDisagree,
    /// Batch segments were left out.
    SegmentsDropped,
    /// The common scale comes from the wheel + gyro model, not the 2W fit.
    ScaleFromGyroModel,
    /// The GNSS antenna position is poorly determined by the drive.
    AntennaUnobservable,
}

/// A warning: a stable code and a message naming the cause.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Warning {
    /// What it is about.
    pub code: WarningCode,
    /// Human-readable, names the channel/parameter and the cause.
    pub message: String,
}

impl Warning {
    /// A warning.
    pub fn new(code: WarningCode, message: String) -> Warning {
        Warning { code, message }
    }
}

/// One row of the per-iteration table (the paper's Fig. 6).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IterationRecord {
    /// Iteration (0 = the nominal start).
    pub n: usize,
    /// Circumferences after it.
    pub circumference_m: RearPair,
    /// Track width used, m.
    pub track_width_m: f64,
    /// Mean deviation of the pure 2W dead-reckoning from the reference, m.
    pub dr_error_mean_m: f64,
    /// Largest deviation, m.
    pub dr_error_max_m: f64,
}

/// The output of one method (internal to the library, public for the report).
#[derive(Debug, Clone, PartialEq)]
pub struct MethodResult {
    /// Which method.
    pub method: Method,
    /// [c_RL, c_RR], m.
    pub c: [f64; 2],
    /// Track width used or estimated, m.
    pub track: f64,
    /// Whether the track width was estimated.
    pub track_estimated: bool,
    /// Fitted side-slip gain (batch with side-slip on).
    pub side_slip_gain: Option<f64>,
    /// Whether side-slip was in the model.
    pub side_slip: bool,
    /// Estimated GNSS antenna position (body x, y from the rear-axle centre)
    /// and its sigmas, m (batch with the lever arm estimated).
    pub lever_arm: Option<([f64; 2], [f64; 2])>,
    /// Uncertainty.
    pub sigmas: Sigmas,
    /// Per-iteration table.
    pub iterations: Vec<IterationRecord>,
    /// The kept iteration.
    pub selected_iteration: usize,
    /// RMS of the GNSS residuals (batch), m.
    pub residual_rms_m: Option<f64>,
    /// Segments (batch).
    pub segments: usize,
    /// Dead-reckoned track with the nominal values (thinned).
    pub track_before: Vec<[f64; 2]>,
    /// Dead-reckoned track with the estimate (thinned).
    pub track_after: Vec<[f64; 2]>,
    /// Method-specific warnings.
    pub notes: Vec<Warning>,
}

/// One method's result in a side-by-side comparison.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodSummary {
    /// Method.
    pub method: Method,
    /// Estimate.
    pub circumference_m: RearPair,
    /// Its sigmas.
    pub sigma_m: RearSigma,
    /// Track width used or estimated, m.
    pub track_width_m: f64,
    /// Kept iteration.
    pub selected_iteration: usize,
    /// Mean deviation of the pure 2W dead-reckoning from the reference, m.
    pub dr_error_mean_m: f64,
    /// Largest deviation, m.
    pub dr_error_max_m: f64,
}

/// Facts about the drive and the reference.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Diagnostics {
    /// Wheel data duration, s.
    pub duration_s: f64,
    /// Distance with a valid reference (nominal circumference), m.
    pub distance_m: f64,
    /// Total absolute heading change, degrees.
    pub total_turn_deg: f64,
    /// GNSS fixes in the drive (finite).
    pub gnss_fixes: usize,
    /// Fixes rejected as outliers.
    pub gnss_outliers: usize,
    /// GNSS outages bridged.
    pub gnss_outages: usize,
    /// GNSS 1-sigma used, m.
    pub gnss_sigma_m: f64,
    /// Whether it was estimated from the fixes.
    pub gnss_sigma_estimated: bool,
    /// Wheel/GNSS time offset, when checked.
    pub time_offset: Option<TimeOffset>,
    /// GNSS antenna position used, body frame from the rear-axle centre, m.
    pub lever_arm_m: [f64; 2],
    /// Layer-1 side-slip gain k (beta = -k a_y), rad per m/s^2.
    pub reference_side_slip_gain: Option<f64>,
    /// Standstill time, s.
    pub standstill_s: f64,
    /// RMS of the GNSS residuals of the batch fit, m.
    pub residual_rms_m: Option<f64>,
    /// Batch segments.
    pub segments: usize,
    /// Offsets subtracted from rate-type wheel channels (rl, rr, in the
    /// channel's unit), measured at standstill.
    pub wheel_rate_offsets: Option<[f64; 2]>,
}

/// The nominal values the calibration started from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Nominal {
    /// Circumference of every wheel, m.
    pub circumference_m: f64,
    /// Rear track, m.
    pub track_width_m: f64,
}

/// Thinned tracks for the plots (not serialised).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Tracks {
    /// The reference (rear-axle centre).
    pub reference: Vec<[f64; 2]>,
    /// 2W dead-reckoning with the nominal values.
    pub before: Vec<[f64; 2]>,
    /// 2W dead-reckoning with the estimate.
    pub after: Vec<[f64; 2]>,
    /// Accepted GNSS fixes (antenna).
    pub gnss: Vec<[f64; 2]>,
}

/// The calibration result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Effective rear circumferences, m.
    pub circumference_m: RearPair,
    /// Their 1-sigma, m.
    pub sigma_m: RearSigma,
    /// Effective rear track used with them (estimated or nominal), m.
    pub track_width_m: f64,
    /// Whether the track width was estimated.
    pub track_width_estimated: bool,
    /// 1-sigma of the track width, m, when estimated.
    pub sigma_track_width_m: Option<f64>,
    /// Yaw-rate gyro bias, rad/s (`omega_gyro = (1 + gyro_scale) omega + bias`).
    pub gyro_bias_rad_s: Option<f64>,
    /// Yaw-rate gyro scale error (0 = perfect).
    pub gyro_scale: Option<f64>,
    /// The gyro calibration in full.
    pub gyro: Option<GyroEstimate>,
    /// Whether side-slip was in the model.
    pub side_slip: bool,
    /// Side-slip gain k (beta = -k a_y), rad per m/s^2, when fitted.
    pub side_slip_gain_rad_per_m_s2: Option<f64>,
    /// Estimated GNSS antenna position, body frame from the rear-axle centre, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gnss_antenna_m: Option<[f64; 2]>,
    /// Its 1-sigma, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_gnss_antenna_m: Option<[f64; 2]>,
    /// The method that produced the values.
    pub method: Method,
    /// The kept iteration.
    pub selected_iteration: usize,
    /// Per-iteration table (the paper's Fig. 6).
    pub iterations: Vec<IterationRecord>,
    /// Everything skipped, assumed or not determined.
    pub warnings: Vec<Warning>,
    /// Starting values.
    pub nominal: Nominal,
    /// Facts about the drive.
    pub diagnostics: Diagnostics,
    /// Every method run, side by side (when comparing).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub comparison: Vec<MethodSummary>,
    /// Tracks for the plots.
    #[serde(skip)]
    pub tracks: Tracks,
}

impl Calibration {
    /// True when a warning with `code` was raised.
    pub fn has_warning(&self, code: WarningCode) -> bool {
        self.warnings.iter().any(|w| w.code == code)
    }
}

fn summary(m: &MethodResult) -> MethodSummary {
    let sel = m
        .iterations
        .iter()
        .find(|i| i.n == m.selected_iteration)
        .copied()
        .or_else(|| m.iterations.last().copied());
    MethodSummary {
        method: m.method,
        circumference_m: RearPair {
            rl: m.c[0],
            rr: m.c[1],
        },
        sigma_m: RearSigma::from(&m.sigmas),
        track_width_m: m.track,
        selected_iteration: m.selected_iteration,
        dr_error_mean_m: sel.map_or(f64::NAN, |i| i.dr_error_mean_m),
        dr_error_max_m: sel.map_or(f64::NAN, |i| i.dr_error_max_m),
    }
}

fn thin(v: impl Iterator<Item = [f64; 2]>, n: usize, keep: usize) -> Vec<[f64; 2]> {
    let stride = n.div_ceil(keep.max(1)).max(1);
    v.step_by(stride).collect()
}

/// Put the result together: primary method, gyro, warnings, diagnostics.
pub fn assemble(
    p: &Prepared,
    r: &Reference,
    config: &CalibrationConfig,
    paper: Option<MethodResult>,
    batch: Option<MethodResult>,
    mut warnings: Vec<Warning>,
) -> Result<Calibration, CalibrationError> {
    let comparison: Vec<MethodSummary> = if config.compare {
        paper.iter().chain(batch.iter()).map(summary).collect()
    } else {
        Vec::new()
    };
    if let (true, Some(a), Some(b)) = (config.compare, paper.as_ref(), batch.as_ref()) {
        for (name, i) in [("c_RL", 0usize), ("c_RR", 1)] {
            let sa = if i == 0 { a.sigmas.rl } else { a.sigmas.rr };
            let sb = if i == 0 { b.sigmas.rl } else { b.sigmas.rr };
            let d = (a.c[i] - b.c[i]).abs();
            let s = (sa * sa + sb * sb).sqrt();
            if d > 3.0 * s && d > 2e-4 {
                warnings.push(Warning::new(
                    WarningCode::MethodsDisagree,
                    format!(
                        "paper and batch disagree on {name} by {:.2} mm (combined sigma {:.2} mm)",
                        1000.0 * d,
                        1000.0 * s
                    ),
                ));
            }
        }
    }
    let primary = match config.method {
        Method::Paper => paper,
        Method::Batch => batch,
    }
    .ok_or(CalibrationError::InvalidConfig {
        field: "method",
        reason: "the selected method did not run".to_string(),
    })?;
    warnings.extend(primary.notes.iter().cloned());
    warnings.extend(observability(
        r,
        &primary.sigmas,
        primary.track_estimated,
        primary.residual_rms_m,
    ));
    if primary.method == Method::Paper
        && primary.selected_iteration == config.iterations
        && config.iterations > 1
    {
        warnings.push(Warning::new(
            WarningCode::NotConverged,
            format!(
                "paper: the dead-reckoning deviation still decreases at the last iteration ({}); more iterations may help",
                config.iterations
            ),
        ));
    }
    let gyro = if config.estimate_gyro {
        crate::gyro::estimate(
            p,
            r,
            primary.c,
            primary.side_slip_gain,
            config.segment_length_s,
            &mut warnings,
        )?
    } else {
        None
    };
    // Where the wheel + gyro model fits the GNSS far better than the 2W model,
    // its common distance factor is the better measure of the scale.
    let mut c = primary.c;
    let mut sigma_m = RearSigma::from(&primary.sigmas);
    if let Some(g) = gyro.filter(|g| crate::gyro::prefer_distance_factor(g, primary.residual_rms_m))
    {
        c = [c[0] * g.distance_factor, c[1] * g.distance_factor];
        let mean = 0.5 * (c[0] + c[1]);
        let s_mean = mean * g.sigma_distance_factor;
        let with_mean = |s: Option<f64>| {
            let d = sigma_m.difference.unwrap_or(0.0);
            s.map(|_| (s_mean * s_mean + 0.25 * d * d).sqrt())
        };
        sigma_m = RearSigma {
            rl: with_mean(sigma_m.rl),
            rr: with_mean(sigma_m.rr),
            difference: sigma_m.difference,
            mean: Some(s_mean),
        };
        warnings.retain(|w| w.code != WarningCode::ScaleUnobservable);
        warnings.push(Warning::new(
            WarningCode::ScaleFromGyroModel,
            format!(
                "common scale taken from the wheel + gyro model: it fits the GNSS to {:.3} m RMS against {:.3} m for the 2W model, whose scale absorbs the wheels' heading errors; both circumferences x {:.5} (sigma {:.5})",
                g.residual_rms_m,
                primary.residual_rms_m.unwrap_or(f64::NAN),
                g.distance_factor,
                g.sigma_distance_factor
            ),
        ));
        if s_mean > 0.002 {
            warnings.push(Warning::new(
                WarningCode::ScaleUnobservable,
                format!(
                    "the common scale (c_RL + c_RR)/2 is poorly determined: sigma {:.2} mm (limit 2.0 mm) from the wheel + gyro model",
                    1000.0 * s_mean
                ),
            ));
        }
    }
    let n = p.len();
    let reference = thin(
        (0..n).map(|k| [r.x[k], r.y[k]]),
        n,
        crate::paper::TRACK_POINTS,
    );
    let gnss: Vec<[f64; 2]> = r
        .fixes
        .iter()
        .filter(|f| f.accepted)
        .map(|f| [f.x, f.y])
        .collect();
    // fold from +0.0: an empty f64 `sum()` is -0.0, which prints as "-0".
    let standstill_s = p.standstill.iter().fold(0.0, |acc, (a, b)| acc + (b - a));
    Ok(Calibration {
        circumference_m: RearPair { rl: c[0], rr: c[1] },
        sigma_m,
        track_width_m: primary.track,
        track_width_estimated: primary.track_estimated,
        sigma_track_width_m: if primary.track_estimated {
            primary.sigmas.track
        } else {
            None
        },
        gyro_bias_rad_s: gyro.map(|g| g.bias_rad_s),
        gyro_scale: gyro.map(|g| g.scale),
        gyro,
        side_slip: primary.side_slip,
        side_slip_gain_rad_per_m_s2: primary.side_slip_gain,
        gnss_antenna_m: primary.lever_arm.map(|l| l.0),
        sigma_gnss_antenna_m: primary.lever_arm.map(|l| l.1),
        method: primary.method,
        selected_iteration: primary.selected_iteration,
        iterations: primary.iterations,
        warnings,
        nominal: Nominal {
            circumference_m: p.nominal_c,
            track_width_m: p.track,
        },
        diagnostics: Diagnostics {
            duration_s: p.t.last().copied().unwrap_or(0.0) - p.t.first().copied().unwrap_or(0.0),
            distance_m: r.distance_m,
            total_turn_deg: r.total_turn_rad.to_degrees(),
            gnss_fixes: r.fixes.len(),
            gnss_outliers: r.outliers,
            gnss_outages: r.outages,
            gnss_sigma_m: r.gnss_sigma_m,
            gnss_sigma_estimated: r.gnss_sigma_estimated,
            time_offset: r.time_offset,
            lever_arm_m: p.lever_arm,
            reference_side_slip_gain: r.side_slip_gain,
            standstill_s,
            residual_rms_m: primary.residual_rms_m,
            segments: primary.segments,
            wheel_rate_offsets: p.wheel_offsets.map(|o| [o.0, o.1]),
        },
        comparison,
        tracks: Tracks {
            reference,
            before: primary.track_before,
            after: primary.track_after,
            gnss,
        },
    })
}

fn mm(v: Option<f64>) -> String {
    v.map_or("not determined".to_string(), |v| {
        format!("{:.2} mm", 1000.0 * v)
    })
}

/// The readable report: drive facts, the per-iteration table, the result
/// with sigmas, the comparison and the warnings.
pub fn render_text(c: &Calibration) -> String {
    let mut s = String::new();
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
        "gnss: {} fixes, {} outliers rejected, {} outages bridged, sigma {:.3} m ({}), antenna at ({:.2}, {:.2}) m",
        d.gnss_fixes,
        d.gnss_outliers,
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
    if let Some(t) = d.time_offset {
        let _ = writeln!(
            s,
            "time offset: GNSS {:+.0} ms relative to the wheels (sigma {:.0} ms){}",
            1000.0 * t.gnss_late_s,
            1000.0 * t.sigma_s,
            if t.compensated { ", compensated" } else { "" }
        );
    }
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
    s
}
