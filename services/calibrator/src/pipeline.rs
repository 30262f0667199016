//! The calibration from end to end: [`calibrate`] runs the stages in order
//! (prepare, reference, the methods, gyro, uncertainty) and puts their
//! results together into a [`Calibration`].

use crate::config::CalibrationConfig;
use crate::error::CalibrationError;
use crate::fit::{batch, lm, paper};
use crate::method::Method;
use crate::reference::Reference;
use crate::result::{
    Calibration, Diagnostics, MethodResult, MethodSummary, Nominal, RearPair, RearSigma, Tracks,
    TRACK_POINTS,
};
use crate::series::Series;
use crate::sigmas::uncertainty::observability;
use crate::warnings::{Warning, WarningCode};
use crate::{check, clocks, reference};
use interfaces::drive::Drive;
use serde::{Deserialize, Serialize};

/// Stage of a running calibration, for progress reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    /// Checking and converting the input.
    Prepare,
    /// Layer 1: the GNSS/IMU reference.
    Reference,
    /// The paper's iterations.
    Paper,
    /// The batch fit.
    Batch,
    /// Gyro bias and scale.
    Gyro,
    /// Sigmas and observability.
    Uncertainty,
    /// Finished.
    Done,
}

/// A progress report: the stage and the overall fraction done (0..=1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Current stage.
    pub stage: Stage,
    /// Overall fraction done, 0..=1.
    pub fraction: f64,
}

/// Calibrate the rear wheel circumferences of `drive`.
pub fn calibrate(
    drive: &Drive,
    config: &CalibrationConfig,
) -> Result<Calibration, CalibrationError> {
    calibrate_with_progress(drive, config, &mut |_| {})
}

/// [`calibrate`], reporting progress through `progress`.
pub fn calibrate_with_progress(
    drive: &Drive,
    config: &CalibrationConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<Calibration, CalibrationError> {
    config.validate()?;
    progress(Progress {
        stage: Stage::Prepare,
        fraction: 0.0,
    });
    let checked = check::drive(drive, config)?;
    let mut aligned = clocks::align(checked, config)?;
    let mut warnings = std::mem::take(&mut aligned.warnings);
    progress(Progress {
        stage: Stage::Reference,
        fraction: 0.1,
    });
    let reference = reference::build(&aligned, config, &mut warnings)?;
    let prepared = &aligned.series;
    let drifts = &aligned.drifts;
    let (paper_share, batch_share) = match (config.method, config.compare) {
        (_, true) => (0.35, 0.35),
        (Method::Paper, false) => (0.7, 0.0),
        (Method::Batch, false) => (0.0, 0.7),
    };
    let mut done = 0.2;
    let mut paper_result = None;
    if config.method == Method::Paper || config.compare {
        let start = done;
        let r = paper::run(prepared, &reference, config, &mut warnings, &mut |f| {
            progress(Progress {
                stage: Stage::Paper,
                fraction: start + paper_share * f,
            })
        })?;
        done += paper_share;
        paper_result = Some(r);
    }
    let mut batch_result = None;
    if config.method == Method::Batch || config.compare {
        let start = done;
        let r = batch::run(prepared, &reference, config, &mut warnings, &mut |f| {
            progress(Progress {
                stage: Stage::Batch,
                fraction: start + batch_share * f,
            })
        })?;
        batch_result = Some(r);
    }
    progress(Progress {
        stage: Stage::Gyro,
        fraction: 0.9,
    });
    let mut cal = assemble(
        prepared,
        &aligned.imu_clock,
        &reference,
        config,
        paper_result,
        batch_result,
        warnings,
    )?;
    cal.vehicle = Some(drive.vehicle.clone());
    cal.clock_offsets.gnss_s.drift = drifts.gnss.clone();
    cal.clock_offsets.imu_s.drift = drifts.imu.clone();
    if let Some(q) = cal
        .fit_quality
        .as_ref()
        .filter(|q| q.ratio > crate::result::FIT_WARN_RATIO && q.ratio <= q.limit)
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
    progress(Progress {
        stage: Stage::Done,
        fraction: 1.0,
    });
    Ok(cal)
}

/// The fit quality of the model the estimate came from: the wheel + gyro
/// model where its scale was taken, else the batch (2W) fit.
fn fit_quality(
    two_wheel_rms: Option<f64>,
    gyro: Option<&crate::fit::gyro::GyroEstimate>,
    r: &crate::reference::Reference,
    config: &CalibrationConfig,
) -> Option<crate::result::FitQuality> {
    let (rms, model) = match gyro {
        Some(g) if crate::fit::gyro::prefer_distance_factor(g, two_wheel_rms) => {
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
    Some(crate::result::FitQuality {
        residual_rms_m: rms,
        model: model.to_string(),
        gnss_noise_m: noise,
        gnss_noise_source: source,
        ratio: rms / noise,
        limit: config.max_fit_ratio,
    })
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

/// Put the result together: primary method, gyro, warnings, diagnostics.
fn assemble(
    p: &Series,
    imu_clock: &crate::clocks::offsets::StreamOffset,
    r: &Reference,
    config: &CalibrationConfig,
    mut paper: Option<MethodResult>,
    mut batch: Option<MethodResult>,
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
    let mut primary = match config.method {
        Method::Paper => paper.take(),
        Method::Batch => batch.take(),
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
        crate::fit::gyro::estimate(
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
    if let Some(g) =
        gyro.filter(|g| crate::fit::gyro::prefer_distance_factor(g, primary.residual_rms_m))
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
    // The model the estimate came from, for the report: the batch fit's
    // own segments, or the paper's estimate on segments of the same length
    // started from the reference.
    let (model, model_fitted) = match primary.model_track.take() {
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
    };
    let n = p.len();
    let reference = thin((0..n).map(|k| [r.x[k], r.y[k]]), n, TRACK_POINTS);
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
        vehicle: None,
        diagnostics: Diagnostics {
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
        },
        fit_quality: fit_quality(primary.residual_rms_m, gyro.as_ref(), r, config),
        clock_offsets: crate::clocks::offsets::ClockOffsets {
            gnss_s: r.gnss_clock.clone(),
            imu_s: imu_clock.clone(),
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
    })
}
