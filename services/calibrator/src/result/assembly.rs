//! Stage 6's entry point: [`assemble`] puts the products of the stages
//! together into a [`Calibration`] and checks the fit's quality against the
//! GNSS noise.

use crate::clocks::offsets::ClockOffsets;
use crate::clocks::Aligned;
use crate::config::CalibrationConfig;
use crate::error::CalibrationError;
use crate::fit::lm::ModelTrack;
use crate::fit::{batch, gyro, lm, Fits, MethodResult};
use crate::reference::Reference;
use crate::result::{Calibration, Diagnostics, FitQuality, Nominal, RearPair, Tracks};
use crate::result::{FIT_WARN_RATIO, TRACK_POINTS};
use crate::series::Series;
use crate::sigmas::Observability;
use crate::warnings::{Warning, WarningCode};
use interfaces::drive::Drive;

/// The calibration of `drive` from the stages' products: the aligned
/// streams `a`, the reference `r`, the fits and the sigmas' observability;
/// `warnings` are those of the stages before the fits and of the methods.
/// A fit far worse than the GNSS noise is a warning, beyond
/// `config.max_fit_ratio` times it an error.
pub fn assemble(
    drive: &Drive,
    a: &Aligned<'_>,
    r: &Reference,
    config: &CalibrationConfig,
    fits: Fits,
    sigmas: Observability,
    mut warnings: Vec<Warning>,
) -> Result<Calibration, CalibrationError> {
    let p = &a.series;
    let Fits {
        mut primary,
        comparison,
        gyro,
        c,
        sigma_m,
        warnings: fit_warnings,
        ..
    } = fits;
    warnings.extend(sigmas.warnings);
    warnings.extend(fit_warnings);
    let (model, model_fitted) = report_model(&mut primary, p, r, config);
    let n = p.len();
    let reference = thin((0..n).map(|k| [r.x[k], r.y[k]]), n, TRACK_POINTS);
    let gnss: Vec<[f64; 2]> = r
        .fixes
        .iter()
        .filter(|f| f.accepted)
        .map(|f| [f.x, f.y])
        .collect();
    let diagnostics = diagnostics(p, r, &primary);
    let mut cal = Calibration {
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
        vehicle: None,
        diagnostics,
        fit_quality: fit_quality(primary.residual_rms_m, gyro.as_ref(), r, config),
        clock_offsets: ClockOffsets {
            gnss_s: r.gnss_clock.clone(),
            imu_s: a.imu_clock.clone(),
            pairs: r.clock_pairs.clone(),
        },
        comparison,
        tracks: Tracks {
            reference,
            before: primary.track_before,
            after: primary.track_after,
            gnss,
            start_s: p.t.first().copied().unwrap_or(0.0),
            model,
            model_fitted,
            wheel_windows: wheel_windows(p, r),
        },
    };
    cal.vehicle = Some(drive.vehicle.clone());
    cal.clock_offsets.gnss_s.drift = a.drifts.gnss.clone();
    cal.clock_offsets.imu_s.drift = a.drifts.imu.clone();
    check_fit_quality(&mut cal)?;
    Ok(cal)
}

/// The model the estimate came from, for the report, and whether it is
/// the fit's own (taken out of `primary`).
fn report_model(
    primary: &mut MethodResult,
    p: &Series,
    r: &Reference,
    config: &CalibrationConfig,
) -> (ModelTrack, bool) {
    // The model the estimate came from, for the report: the batch fit's
    // own segments, or the paper's estimate on segments of the same length
    // started from the reference.
    match primary.model_track.take() {
        Some(m) => (m, true),
        None => (
            lm::anchored_track(
                &batch::TwoWheelModel::new(p, Some(primary.track), false, false),
                &primary.c,
                p,
                r,
                config.segment_length_s,
            ),
            false,
        ),
    }
}

/// The drive's facts and the fit's, for the report.
fn diagnostics(p: &Series, r: &Reference, primary: &MethodResult) -> Diagnostics {
    // fold from +0.0: an empty f64 `sum()` is -0.0, which prints as "-0".
    let standstill_s = p.standstill.iter().fold(0.0, |acc, (a, b)| acc + (b - a));
    Diagnostics {
        duration_s: p.t.last().copied().unwrap_or(0.0) - p.t.first().copied().unwrap_or(0.0),
        distance_m: r.distance_m,
        total_turn_deg: r.total_turn_rad.to_degrees(),
        gnss_fixes: r.fixes.len(),
        gnss_outliers: r.outliers,
        gnss_jumps: r.jumps.clone(),
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
        sigma_basis: primary.sigma_basis.clone(),
    }
}

/// A fit far worse than the GNSS noise is a warning, beyond the limit an
/// error.
fn check_fit_quality(cal: &mut Calibration) -> Result<(), CalibrationError> {
    if let Some(q) = cal
        .fit_quality
        .as_ref()
        .filter(|q| q.ratio > FIT_WARN_RATIO && q.ratio <= q.limit)
    {
        let text = format!(
            "the {} model fits the GNSS to {:.3} m RMS, {:.0} times the GNSS noise of {:.3} m ({}): physics or faults the model leaves out; `calibrator diagnose` looks for them (refused beyond {:.0} times)",
            q.model, q.residual_rms_m, q.ratio, q.gnss_noise_m, q.gnss_noise_source, q.limit
        );
        cal.warnings
            .push(Warning::new(WarningCode::FitWorseThanNoise, text));
    }
    if let Some(q) = cal.fit_quality.as_ref().filter(|q| q.ratio > q.limit) {
        return Err(CalibrationError::PoorFit {
            residual_rms_m: q.residual_rms_m,
            noise_m: q.gnss_noise_m,
            noise_source: q.gnss_noise_source.clone(),
            ratio: q.ratio,
            limit: q.limit,
        });
    }
    Ok(())
}

/// The fit quality of the model the estimate came from: the wheel + gyro
/// model where its scale was taken, else the batch (2W) fit.
fn fit_quality(
    two_wheel_rms: Option<f64>,
    gyro: Option<&gyro::GyroEstimate>,
    r: &Reference,
    config: &CalibrationConfig,
) -> Option<FitQuality> {
    let (rms, model) = match gyro {
        Some(g) if gyro::prefer_distance_factor(g, two_wheel_rms) => {
            (g.residual_rms_m, "wheel + gyro")
        }
        _ => (two_wheel_rms?, "2W"),
    };
    let noise = r.gnss_sigma_m;
    if !(rms.is_finite() && noise > 0.0) {
        return None;
    }
    let source = if config.gnss_sigma_m.is_some() {
        "the configuration (gnss_sigma_m)".to_string()
    } else if r.gnss_sigma_estimated {
        "measured on the drive (the fixes' scatter, at least 0.3 m)".to_string()
    } else if let Some(c) = r.gnss_sigma_claim {
        format!(
            "the fixes' scatter measured on the drive; the receiver's sigma_m claims {:.2} m",
            c.claimed_m
        )
    } else {
        "the receiver's sigma_m (median)".to_string()
    };
    Some(FitQuality {
        residual_rms_m: rms,
        model: model.to_string(),
        gnss_noise_m: noise,
        gnss_noise_source: source,
        ratio: rms / noise,
        limit: config.max_fit_ratio,
    })
}

fn thin<T>(v: impl Iterator<Item = T>, n: usize, keep: usize) -> Vec<T> {
    let stride = n.div_ceil(keep.max(1)).max(1);
    v.step_by(stride).collect()
}

/// Windows of about 1 s above 2 m/s (nominal circumference) inside one
/// piece of wheel data with a valid reference at both ends: the heading
/// change of the reference and the revolutions of each rear wheel, for the
/// report's wheel-speed ratio against turn rate (at most
/// [`TRACK_POINTS`] of them, spread over the drive).
fn wheel_windows(p: &Series, r: &Reference) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    let Some(&t_first) = p.t.first() else {
        return out;
    };
    let (mut k0, mut t0) = (0usize, t_first);
    let (mut a, mut b) = (0.0, 0.0);
    for k in 1..p.len() {
        if p.is_piece_start(k) || !r.valid[k] || !r.valid[k0] {
            (k0, t0, a, b) = (k, p.t[k], 0.0, 0.0);
            continue;
        }
        a += p.dn_rl[k];
        b += p.dn_rr[k];
        let dt = p.t[k] - t0;
        if dt >= 1.0 {
            let dist = 0.5 * (a + b) * p.nominal_c;
            if a > 0.0 && b > 0.0 && dist > 2.0 * dt {
                out.push([r.yaw[k] - r.yaw[k0], a, b]);
            }
            (k0, t0, a, b) = (k, p.t[k], 0.0, 0.0);
        }
    }
    let n = out.len();
    thin(out.into_iter(), n, TRACK_POINTS)
}
