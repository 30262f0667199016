//! Stage 4, the fits: the paper's method ([`paper`] on the [`ekf`]), the
//! batch fit ([`batch`] with [`lm`]), the wheel + gyro model ([`gyro`]),
//! the track width's plausibility ([`track_width`]) and dead-reckoning
//! errors on held-out data ([`holdout`]).
//!
//! [`run`] takes the aligned streams and the reference and gives the
//! [`Fits`]: the method the estimate comes from, the comparison of the
//! methods, the gyro model and the choice of the common scale.

pub(crate) mod batch;
pub mod ekf;
pub(crate) mod gyro;
pub(crate) mod holdout;
pub(crate) mod jackknife;
pub(crate) mod lm;
pub(crate) mod paper;
pub(crate) mod track_width;

use crate::clocks::Aligned;
use crate::config::CalibrationConfig;
use crate::error::CalibrationError;
use crate::method::Method;
use crate::products::{IterationRecord, MethodSummary, RearPair, RearSigma, SigmaBasis, Sigmas};
use crate::reference::Reference;
use crate::warnings::{Warning, WarningCode};
use gyro::GyroEstimate;
use lm::ModelTrack;

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
    /// What the sigmas rest on.
    pub sigma_basis: Option<SigmaBasis>,
    /// Dead-reckoned track with the nominal values (thinned).
    pub track_before: Vec<[f64; 2]>,
    /// Dead-reckoned track with the estimate (thinned).
    pub track_after: Vec<[f64; 2]>,
    /// The fitted model's segment-wise track and GNSS residuals (batch).
    pub model_track: Option<ModelTrack>,
    /// Method-specific warnings.
    pub notes: Vec<Warning>,
}

/// Where the fit stage is, for progress reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    /// The paper's iterations, with the fraction of them done (0..=1).
    Paper(f64),
    /// The batch fit, with the fraction of it done (0..=1).
    Batch(f64),
    /// The methods compared, the wheel + gyro model.
    Gyro,
}

/// The product of the fits.
#[derive(Debug, Clone, PartialEq)]
pub struct Fits {
    /// The result of the method the estimate comes from
    /// (`config.method`).
    pub primary: MethodResult,
    /// Each method that ran, in short, when the methods are compared
    /// (`config.compare`; the paper's first).
    pub comparison: Vec<MethodSummary>,
    /// The wheel + gyro model's fit (`config.estimate_gyro`).
    pub gyro: Option<GyroEstimate>,
    /// Whether the common scale was taken from the wheel + gyro model.
    pub scale_from_gyro: bool,
    /// The estimate: the primary's circumferences, times the wheel + gyro
    /// model's distance factor where its scale was taken, m.
    pub c: [f64; 2],
    /// Their sigmas.
    pub sigma_m: RearSigma,
    /// The fits' warnings that follow the sigmas' observability warnings
    /// in the result (convergence, the gyro model, the scale), in order;
    /// the rest went to the list [`run`] was handed.
    pub warnings: Vec<Warning>,
}

/// Run the fits on the aligned streams `a` and the reference `r`: the
/// paper's method and the batch fit (as configured), the methods compared,
/// the wheel + gyro model on the primary's estimate, and the choice of the
/// common scale. Warnings of the methods go to `warnings`, those that come
/// after the sigmas' to [`Fits::warnings`].
pub fn run(
    a: &Aligned<'_>,
    r: &Reference,
    config: &CalibrationConfig,
    warnings: &mut Vec<Warning>,
    progress: &mut dyn FnMut(Step),
) -> Result<Fits, CalibrationError> {
    let p = &a.series;
    let mut paper_result = None;
    if config.method == Method::Paper || config.compare {
        let r = paper::run(p, r, config, warnings, &mut |f| progress(Step::Paper(f)))?;
        paper_result = Some(r);
    }
    let mut batch_result = None;
    if config.method == Method::Batch || config.compare {
        let r = batch::run(p, r, config, warnings, &mut |f| progress(Step::Batch(f)))?;
        batch_result = Some(r);
    }
    progress(Step::Gyro);
    let (mut paper, mut batch) = (paper_result, batch_result);
    let comparison: Vec<MethodSummary> = if config.compare {
        paper.iter().chain(batch.iter()).map(summary).collect()
    } else {
        Vec::new()
    };
    if let (true, Some(a), Some(b)) = (config.compare, paper.as_ref(), batch.as_ref()) {
        warn_disagreement(a, b, warnings);
    }
    let primary = match config.method {
        Method::Paper => paper.take(),
        Method::Batch => batch.take(),
    }
    .ok_or(CalibrationError::InvalidConfig {
        field: "method",
        reason: "the selected method did not run".to_string(),
    })?;
    warnings.extend(primary.notes.iter().cloned());
    // The sigmas' observability warnings come here in the result; what
    // follows goes to the fits' own list.
    let mut later = Vec::new();
    if primary.method == Method::Paper
        && primary.selected_iteration == config.iterations
        && config.iterations > 1
    {
        later.push(Warning::new(
            WarningCode::NotConverged,
            format!(
                "paper: the dead-reckoning deviation still decreases at the last iteration ({}); more iterations may help",
                config.iterations
            ),
        ));
    }
    let gyro = if config.estimate_gyro {
        gyro::estimate(
            p,
            r,
            primary.c,
            primary.side_slip_gain,
            config.segment_length_s,
            &mut later,
        )?
    } else {
        None
    };
    let (c, sigma_m, scale_from_gyro) = gyro_scale(&primary, gyro, &mut later);
    Ok(Fits {
        primary,
        comparison,
        gyro,
        scale_from_gyro,
        c,
        sigma_m,
        warnings: later,
    })
}

/// Warn where the paper and batch methods disagree on a circumference by
/// more than 3 combined sigmas (and 0.2 mm).
fn warn_disagreement(a: &MethodResult, b: &MethodResult, warnings: &mut Vec<Warning>) {
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

/// The circumferences and their sigmas: the primary's, or, where the
/// wheel + gyro model fits the GNSS far better than the 2W model, scaled by
/// its common distance factor (with its warnings into `later`); and
/// whether the scale came from the gyro model.
fn gyro_scale(
    primary: &MethodResult,
    gyro: Option<GyroEstimate>,
    later: &mut Vec<Warning>,
) -> ([f64; 2], RearSigma, bool) {
    // Where the wheel + gyro model fits the GNSS far better than the 2W model,
    // its common distance factor is the better measure of the scale.
    let mut c = primary.c;
    let mut sigma_m = RearSigma::from(&primary.sigmas);
    let mut scale_from_gyro = false;
    if let Some(g) = gyro.filter(|g| gyro::prefer_distance_factor(g, primary.residual_rms_m)) {
        scale_from_gyro = true;
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
        // (The sigmas stage leaves out its own scale warning then.)
        later.push(Warning::new(
            WarningCode::ScaleFromGyroModel,
            format!(
                "common scale taken from the wheel + gyro model: it fits the GNSS to {:.3} m RMS against {:.3} m for the 2W model, whose scale absorbs the wheels' heading errors; both circumferences x {:.5} (sigma {:.5}{})",
                g.residual_rms_m,
                primary.residual_rms_m.unwrap_or(f64::NAN),
                g.distance_factor,
                g.sigma_distance_factor,
                if g.distance_floored_by_thirds {
                    ": the spread of the drive fitted without each third of it, which disagree beyond the error model"
                } else {
                    ""
                }
            ),
        ));
        if s_mean > 0.002 {
            later.push(Warning::new(
                WarningCode::ScaleUnobservable,
                format!(
                    "the common scale (c_RL + c_RR)/2 is poorly determined: sigma {:.2} mm (limit 2.0 mm) from the wheel + gyro model",
                    1000.0 * s_mean
                ),
            ));
        }
    }
    (c, sigma_m, scale_from_gyro)
}

/// One method's result in short, for the comparison.
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
