//! The calibration from end to end: [`calibrate`] runs the stages in order
//! (prepare, reference, the methods, gyro, uncertainty) and puts their
//! results together into a [`Calibration`].

use crate::clocks::{self, ClockDrift, OffsetStatus};
use crate::config::{CalibrationConfig, TimeOffsetMode};
use crate::error::CalibrationError;
use crate::method::Method;
use crate::prep::Prepared;
use crate::reference::Reference;
use crate::result::{
    Calibration, Diagnostics, MethodResult, MethodSummary, Nominal, RearPair, RearSigma, Tracks,
    TRACK_POINTS,
};
use crate::uncertainty::observability;
use crate::warnings::{Warning, WarningCode};
use crate::{batch, clock_drift, lm, paper, prep, reference};
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
    let mut warnings = Vec::new();
    let mut prepared = prep::prepare(drive, config, &mut warnings)?;
    // The streams' slow clock drift: where it is significant (and the
    // offsets are compensated), the streams are put on the wheels' clock
    // rate and the drive is prepared again (its constant offsets are then
    // those at the drift's reference time).
    let drifts = clock_drifts(&prepared, drive, config);
    let restamped = restamp(drive, &drifts);
    let drive = match &restamped {
        Some(d) => {
            warnings.clear();
            prepared = prep::prepare(d, config, &mut warnings)?;
            d
        }
        None => drive,
    };
    drift_warnings(&drifts, &mut warnings);
    progress(Progress {
        stage: Stage::Reference,
        fraction: 0.1,
    });
    let reference = reference::build(&prepared, drive, config, &mut warnings)?;
    let (paper_share, batch_share) = match (config.method, config.compare) {
        (_, true) => (0.35, 0.35),
        (Method::Paper, false) => (0.7, 0.0),
        (Method::Batch, false) => (0.0, 0.7),
    };
    let mut done = 0.2;
    let mut paper_result = None;
    if config.method == Method::Paper || config.compare {
        let start = done;
        let r = paper::run(&prepared, &reference, config, &mut warnings, &mut |f| {
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
        let r = batch::run(&prepared, &reference, config, &mut warnings, &mut |f| {
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
        &prepared,
        &reference,
        config,
        paper_result,
        batch_result,
        warnings,
    )?;
    cal.vehicle = Some(drive.vehicle.clone());
    cal.clock_offsets.gnss_s.drift = drifts.gnss;
    cal.clock_offsets.imu_s.drift = drifts.imu;
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

/// The GNSS and IMU clock drifts against the wheels.
struct Drifts {
    gnss: ClockDrift,
    imu: ClockDrift,
}

/// A clock drift that could not be looked for, because `reason`.
fn drift_not_determined(reason: String) -> ClockDrift {
    ClockDrift {
        status: OffsetStatus::NotDetermined,
        reason: Some(reason),
        ..ClockDrift::default()
    }
}

/// Every stream's drift ([`clock_drift`]), marked applied where it is
/// significant and `config` compensates the clocks.
fn clock_drifts(p: &Prepared, drive: &Drive, config: &CalibrationConfig) -> Drifts {
    if config.time_offset == TimeOffsetMode::Off {
        let off = ClockDrift::not_checked("time offset check switched off");
        return Drifts {
            gnss: off.clone(),
            imu: off,
        };
    }
    let (Some(&t0), Some(&t1)) = (p.t.first(), p.t.last()) else {
        let none = ClockDrift::not_checked("no wheel samples");
        return Drifts {
            gnss: none.clone(),
            imu: none,
        };
    };
    let t_ref = 0.5 * (t0 + t1);
    let spans = clock_drift::windows(t0, t1);
    let wheels = clocks::WheelTrack {
        t: &p.t,
        dn_rl: &p.dn_rl,
        dn_rr: &p.dn_rr,
        circumference_m: p.nominal_c,
        track_m: p.track,
    };
    let apply = |mut d: ClockDrift| {
        d.applied =
            clock_drift::significant(&d) && config.time_offset == TimeOffsetMode::Compensate;
        d
    };
    let gnss = if p.fixes.is_empty() {
        ClockDrift::not_checked("the drive has no GNSS")
    } else {
        let fixes: Vec<(f64, f64, f64)> = p.fixes.iter().map(|f| (f.t, f.x, f.y)).collect();
        let mut given: Vec<f64> = p.fixes.iter().filter_map(|f| f.sigma).collect();
        let motion = clock_drift::gnss_motion(&fixes, stats::upper_median(&mut given));
        let (whole, tries) = clock_drift::gnss_windows(&wheels, &motion, &spans);
        if whole.status == OffsetStatus::Determined {
            apply(clock_drift::judge(tries, (t0, t1), t_ref, &whole))
        } else {
            drift_not_determined(format!(
                "the offset is not determined over the whole drive ({})",
                whole.reason.as_deref().unwrap_or("no reason")
            ))
        }
    };
    let imu = match (drive.imu.as_deref(), &p.imu_clock) {
        (None | Some([]), _) => ClockDrift::not_checked("the drive has no IMU"),
        (Some(rows), whole) => match (whole.status, whole.offset_s) {
            (OffsetStatus::Determined, Some(centre)) => {
                // One copy, the rows with a finite time (imu_windows
                // takes them so).
                let rows: Vec<clocks::ImuRow> = rows
                    .iter()
                    .filter(|r| r.t_s.is_finite())
                    .map(|r| (r.t_s, r.gz_rad_s, r.ax_m_s2))
                    .collect();
                let tries = clock_drift::imu_windows(&wheels, &rows, &spans, centre);
                apply(clock_drift::judge(tries, (t0, t1), t_ref, whole))
            }
            _ => drift_not_determined(
                "the IMU offset is not determined over the whole drive".to_string(),
            ),
        },
    };
    Drifts { gnss, imu }
}

/// The drive with every stream whose drift is applied put on the wheels'
/// clock rate (GNSS and heading by the GNSS's drift, the IMU by its own);
/// `None` when no drift is applied.
fn restamp(drive: &Drive, d: &Drifts) -> Option<Drive> {
    let (g, i) = (d.gnss.applied_rate(), d.imu.applied_rate());
    if g.is_none() && i.is_none() {
        return None;
    }
    let mut out = drive.clone();
    if let (Some(r), Some(t_ref)) = (g, d.gnss.ref_t_s) {
        for s in out.gnss.iter_mut().flatten() {
            s.t_s = clock_drift::undrift(s.t_s, r, t_ref);
        }
        for s in out.heading.iter_mut().flatten() {
            s.t_s = clock_drift::undrift(s.t_s, r, t_ref);
        }
    }
    if let (Some(r), Some(t_ref)) = (i, d.imu.ref_t_s) {
        for s in out.imu.iter_mut().flatten() {
            s.t_s = clock_drift::undrift(s.t_s, r, t_ref);
        }
    }
    Some(out)
}

/// A warning per significant drift.
fn drift_warnings(d: &Drifts, warnings: &mut Vec<Warning>) {
    for (name, x) in [("gnss", &d.gnss), ("imu", &d.imu)] {
        if let (true, Some(ppm), Some(sigma)) =
            (clock_drift::significant(x), x.drift_ppm, x.sigma_ppm)
        {
            warnings.push(Warning::new(
                WarningCode::TimeOffset,
                format!(
                    "the {name} clock drifts {ppm:+.0} ppm against the wheels' (sigma {sigma:.0} ppm, from {} windows){}",
                    x.windows.len(),
                    if x.applied {
                        "; its times were corrected for it, the offset is the one at the middle of the drive"
                    } else {
                        "; not compensated"
                    }
                ),
            ));
        }
    }
}

/// The fit quality of the model the estimate came from: the wheel + gyro
/// model where its scale was taken, else the batch (2W) fit.
fn fit_quality(
    two_wheel_rms: Option<f64>,
    gyro: Option<&crate::gyro::GyroEstimate>,
    r: &crate::reference::Reference,
    config: &CalibrationConfig,
) -> Option<crate::result::FitQuality> {
    let (rms, model) = match gyro {
        Some(g) if crate::gyro::prefer_distance_factor(g, two_wheel_rms) => {
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
fn wheel_windows(p: &Prepared, r: &Reference) -> Vec<[f64; 3]> {
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
    p: &Prepared,
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
        clock_offsets: crate::clocks::ClockOffsets {
            gnss_s: r.gnss_clock.clone(),
            imu_s: p.imu_clock.clone(),
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
