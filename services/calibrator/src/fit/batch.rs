//! The batch method: a Levenberg-Marquardt fit ([`crate::fit::lm`]) of the 2W
//! model to the GNSS fixes over the whole drive.
//!
//! The drive is cut into segments (default 120 s, and at every break of the
//! wheel data); each segment has its own initial pose `(x0, y0, theta0)`, all
//! share the model parameters. The per-segment poses absorb what the model
//! cannot carry for ever (a heading that slowly drifts through unmodelled
//! physics), while every segment still constrains the parameters through its
//! whole shape: a wrong `c_RR/c_RL` bends the segment, a wrong mean scale
//! stretches it, a wrong track width over- or under-turns its corners.
//!
//! The parameters enter through [`TwoWheelModel`] (the 2W model: `c_RL`,
//! `c_RR`, optionally the track width, a side-slip gain `k` in
//! `beta = -k a_y` and the GNSS antenna position). The result carries the
//! per-stage parameters as its iteration table, each with the deviation of
//! the 2W dead-reckoning from the reference.

use crate::config::{CalibrationConfig, TrackWidthMode};
use crate::error::CalibrationError;
use crate::fit::ekf::{dr_deviation, DrDeviation, Slip};
use crate::fit::lm::{fit, stages, Fit, SlipGain, StepModel, MAX_GLOBAL};
use crate::fit::track_width::{decide_track, implausible_track};
use crate::fit::MethodResult;
use crate::method::Method;
use crate::products::{IterationRecord, RearPair, TRACK_POINTS};
use crate::reference::Reference;
use crate::series::Series;
use crate::warnings::{Warning, WarningCode};
use vehicle_model::two_wheel::TwoWheelParams;

/// The 2W model with `c_RL`, `c_RR` and optionally the track width, the
/// side-slip gain and the GNSS antenna position; parameters in that order.
pub struct TwoWheelModel<'a> {
    p: &'a Series,
    /// Index of the track width in the parameters, or the fixed value.
    track: Result<usize, f64>,
    slip: SlipGain,
    lever: Option<usize>,
    n: usize,
}

impl<'a> TwoWheelModel<'a> {
    /// The model over `p`; `track` `None` estimates it, `Some(t)` keeps `t`.
    pub fn new(
        p: &'a Series,
        track: Option<f64>,
        slip_gain: bool,
        lever_arm: bool,
    ) -> TwoWheelModel<'a> {
        let mut n = 2;
        let track = match track {
            Some(t) => Err(t),
            None => {
                n += 1;
                Ok(n - 1)
            }
        };
        let slip = if slip_gain {
            n += 1;
            SlipGain::Parameter(n - 1)
        } else {
            SlipGain::Off
        };
        let lever = lever_arm.then(|| {
            n += 2;
            n - 2
        });
        TwoWheelModel {
            p,
            track,
            slip,
            lever,
            n,
        }
    }
}

impl StepModel for TwoWheelModel<'_> {
    fn n_global(&self) -> usize {
        self.n
    }

    fn increments(
        &self,
        k: usize,
        g: &[f64],
        d_ds: &mut [f64; MAX_GLOBAL],
        d_dyaw: &mut [f64; MAX_GLOBAL],
    ) -> Option<(f64, f64)> {
        let (a, b) = (self.p.dn_rl[k], self.p.dn_rr[k]);
        let t = match self.track {
            Ok(i) => g[i],
            Err(t) => t,
        };
        let (ds, dyaw) = TwoWheelParams {
            c_rl: g[0],
            c_rr: g[1],
            track_width: t,
        }
        .increments(a, b);
        *d_ds = [0.0; MAX_GLOBAL];
        *d_dyaw = [0.0; MAX_GLOBAL];
        d_ds[0] = 0.5 * a;
        d_ds[1] = 0.5 * b;
        d_dyaw[0] = -a / t;
        d_dyaw[1] = b / t;
        if let Ok(i) = self.track {
            d_dyaw[i] = -dyaw / t;
        }
        Some((ds, dyaw))
    }

    fn slip(&self) -> SlipGain {
        self.slip
    }

    fn lever_index(&self) -> Option<usize> {
        self.lever
    }
}

/// Run the batch method.
pub fn run(
    p: &Series,
    r: &Reference,
    config: &CalibrationConfig,
    warnings: &mut Vec<Warning>,
    progress: &mut dyn FnMut(f64),
) -> Result<MethodResult, CalibrationError> {
    let mut estimate_track = decide_track(p, r, config, warnings)?;
    let (model, g0, fit) =
        fit_deciding_track(p, r, config, warnings, progress, &mut estimate_track)?;
    let slip_gain = config.side_slip;
    let track = if estimate_track { fit.g[2] } else { p.track };
    let slip_index = 2 + usize::from(estimate_track);
    let slip_value = slip_gain.then(|| fit.g[slip_index]);
    let lever_value = model.lever_index().map(|i| {
        (
            [fit.g[i], fit.g[i + 1]],
            [fit.variance(i).sqrt(), fit.variance(i + 1).sqrt()],
        )
    });
    let c = [fit.g[0], fit.g[1]];
    check_plausible(p, c, track, estimate_track)?;
    let slip = slip_value.map_or(Slip::None, |k| Slip::Gain(k, &p.lateral_accel));
    let params = |g: &[f64]| TwoWheelParams {
        c_rl: g[0],
        c_rr: g[1],
        track_width: if estimate_track { g[2] } else { p.track },
    };
    let before = dr_deviation(p, r, &params(&g0), Slip::None, TRACK_POINTS);
    let iterations = iteration_records(
        p, r, &g0, &before, &fit.steps, &params, slip_index, slip_gain,
    );
    let after = dr_deviation(p, r, &params(&fit.g), slip, TRACK_POINTS);
    let mut notes = Vec::new();
    if fit.dropped_segments > 0 {
        notes.push(Warning::new(
            WarningCode::SegmentsDropped,
            format!(
                "batch: {} segment(s) with fewer than 8 GNSS fixes or under 20 m were left out of the fit",
                fit.dropped_segments
            ),
        ));
    }
    Ok(MethodResult {
        method: Method::Batch,
        c,
        track,
        track_estimated: estimate_track,
        side_slip_gain: slip_value,
        side_slip: slip_gain,
        lever_arm: lever_value,
        sigmas: fit.sigmas(),
        sigma_basis: Some(fit.sigma_basis()),
        selected_iteration: iterations.len() - 1,
        iterations,
        residual_rms_m: Some(fit.residual_rms_m),
        segments: fit.segments,
        track_before: before.track,
        track_after: after.track,
        model_track: Some(fit.model_track),
        notes,
    })
}

/// The batch fit from the nominal start (track width, side-slip gain and
/// lever arm appended as estimated), with the track width's decision: in
/// auto mode, an implausible estimate is warned of and the fit run again
/// with the nominal track (`estimate_track` set false). The model, the
/// start and the fit.
fn fit_deciding_track<'a>(
    p: &'a Series,
    r: &Reference,
    config: &CalibrationConfig,
    warnings: &mut Vec<Warning>,
    progress: &mut dyn FnMut(f64),
    estimate_track: &mut bool,
) -> Result<(TwoWheelModel<'a>, Vec<f64>, Fit), CalibrationError> {
    let slip_gain = config.side_slip;
    let lever = config.estimate_lever_arm;
    let lengths = stages(config.segment_length_s);
    loop {
        let model = TwoWheelModel::new(p, (!*estimate_track).then_some(p.track), slip_gain, lever);
        let start = config
            .initial_circumference_m
            .unwrap_or([p.nominal_c, p.nominal_c]);
        let mut g0 = start.to_vec();
        if *estimate_track {
            g0.push(p.track);
        }
        if slip_gain {
            g0.push(0.0);
        }
        if lever {
            g0.extend_from_slice(&p.lever_arm);
        }
        let fit = fit(&model, p, r, &g0, &lengths, &|_| false, progress)?;
        if *estimate_track {
            let t = fit.g[2];
            if let Some(w) = implausible_track(t, p.track, config.track_width) {
                warnings.push(w);
                if config.track_width == TrackWidthMode::Auto {
                    *estimate_track = false;
                    continue;
                }
            }
        }
        break Ok((model, g0, fit));
    }
}

/// Refuse circumferences (or an estimated track width) more than 50 % from
/// the nominal.
fn check_plausible(
    p: &Series,
    c: [f64; 2],
    track: f64,
    estimate_track: bool,
) -> Result<(), CalibrationError> {
    for (name, v) in [("c_RL", c[0]), ("c_RR", c[1])] {
        if !(v.is_finite() && v > 0.5 * p.nominal_c && v < 1.5 * p.nominal_c) {
            return Err(CalibrationError::Implausible {
                method: Method::Batch,
                detail: format!(
                    "{name} = {v:.4} m, more than 50 % from the nominal {:.4} m (the wheel data and the GNSS do not describe the same motion)",
                    p.nominal_c
                ),
            });
        }
    }
    if estimate_track && !(track > 0.5 * p.track && track < 1.5 * p.track) {
        return Err(CalibrationError::Implausible {
            method: Method::Batch,
            detail: format!(
                "track width {track:.3} m, more than 50 % from the nominal {:.3} m",
                p.track
            ),
        });
    }
    Ok(())
}

/// The per-iteration records: the start (`before`, its deviation) and each
/// fit step's dead-reckoning deviation.
#[allow(clippy::too_many_arguments)]
fn iteration_records(
    p: &Series,
    r: &Reference,
    g0: &[f64],
    before: &DrDeviation,
    steps: &[(f64, Vec<f64>)],
    params: &dyn Fn(&[f64]) -> TwoWheelParams,
    slip_index: usize,
    slip_gain: bool,
) -> Vec<IterationRecord> {
    let mut iterations = vec![IterationRecord {
        n: 0,
        circumference_m: RearPair {
            rl: g0[0],
            rr: g0[1],
        },
        track_width_m: p.track,
        dr_error_mean_m: before.mean_m,
        dr_error_max_m: before.max_m,
    }];
    for (i, (_, g)) in steps.iter().enumerate() {
        let s = slip_gain
            .then(|| g[slip_index])
            .map_or(Slip::None, |k| Slip::Gain(k, &p.lateral_accel));
        let d = dr_deviation(p, r, &params(g), s, 0);
        iterations.push(IterationRecord {
            n: i + 1,
            circumference_m: RearPair { rl: g[0], rr: g[1] },
            track_width_m: params(g).track_width,
            dr_error_mean_m: d.mean_m,
            dr_error_max_m: d.max_m,
        });
    }
    iterations
}
