//! Layer 3 and the loop: the paper's iterative estimation (eq. 3-11).
//!
//! ```text
//! c_0 = nominal
//! for i = 1..N:
//!     P, M        = schedule(i)                       eq. (10)
//!     x^_k        = EKF(2W model with c_{i-1}, r_k)   eq. (3)-(7)
//!     c_opt       = (Phi^T W Phi)^-1 Phi^T W Y        eq. (8)-(9), W = diag(1, 1, 10)
//!     c_i         = c_{i-1} + alpha (c_opt - c_{i-1}) eq. (11)
//!     deviation_i = 2W model with c_i, integrated over the whole drive
//!                   without fusion, against the reference (mean, max)
//! keep the iteration with the smallest mean deviation
//! ```
//!
//! With the track width estimated (beyond the paper), eq. (8)-(9) get a third
//! column for `t_R` (the heading row linearised at the current values, see
//! [`crate::fit::ekf::run_pass`]) and eq. (11) steps it like the circumferences.

use crate::config::{CalibrationConfig, TrackWidthMode};
use crate::error::CalibrationError;
use crate::fit::ekf::{dr_deviation, grid, run_pass, schedule, Slip};
use crate::fit::jackknife::jackknife_ls;
use crate::fit::track_width::{decide_track, implausible_track};
use crate::fit::MethodResult;
use crate::method::Method;
use crate::products::Sigmas;
use crate::products::{IterationRecord, RearPair, TRACK_POINTS};
use crate::reference::Reference;
use crate::series::Series;
use crate::warnings::Warning;
use vehicle_model::two_wheel::TwoWheelParams;

/// Number of time blocks for the jackknife of the least squares.
const JACKKNIFE_BLOCKS: usize = 20;

/// Run the paper's loop. `progress` gets the fraction done (0..=1).
pub fn run(
    p: &Series,
    r: &Reference,
    config: &CalibrationConfig,
    warnings: &mut Vec<Warning>,
    progress: &mut dyn FnMut(f64),
) -> Result<MethodResult, CalibrationError> {
    let estimate_track = decide_track(p, r, config, warnings)?;
    let result = run_once(p, r, config, estimate_track, progress)?;
    if result.track_estimated {
        if let Some(w) = implausible_track(result.track, p.track, config.track_width) {
            warnings.push(w);
            if config.track_width == TrackWidthMode::Auto {
                return run_once(p, r, config, false, progress);
            }
        }
    }
    Ok(result)
}

fn run_once(
    p: &Series,
    r: &Reference,
    config: &CalibrationConfig,
    estimate_track: bool,
    progress: &mut dyn FnMut(f64),
) -> Result<MethodResult, CalibrationError> {
    let mut track = p.track;
    let slip = if config.side_slip && p.gyro.is_some() {
        Slip::Series(&r.beta)
    } else {
        Slip::None
    };
    let side_slip = matches!(slip, Slip::Series(_));
    let mut c = config
        .initial_circumference_m
        .unwrap_or([p.nominal_c, p.nominal_c]);
    let params = |c: [f64; 2], track: f64| TwoWheelParams {
        c_rl: c[0],
        c_rr: c[1],
        track_width: track,
    };
    let dev0 = dr_deviation(p, r, &params(c, track), slip, TRACK_POINTS);
    let mut iterations = vec![IterationRecord {
        n: 0,
        circumference_m: RearPair { rl: c[0], rr: c[1] },
        track_width_m: track,
        dr_error_mean_m: dev0.mean_m,
        dr_error_max_m: dev0.max_m,
    }];
    let grid = grid(p, config.paper_rate_hz);
    let mut best: Option<Best> = None;
    for i in 1..=config.iterations {
        let cov = schedule(i, config.q_m, config.q_p);
        let pass = run_pass(
            p,
            r,
            &grid,
            c,
            track,
            &cov,
            side_slip,
            estimate_track,
            JACKKNIFE_BLOCKS,
        )?;
        let opt = pass.solve()?;
        // Eq. (11).
        let next = [
            c[0] + config.alpha * (opt[0] - c[0]),
            c[1] + config.alpha * (opt[1] - c[1]),
        ];
        check_plausible(next, p.nominal_c, i)?;
        if estimate_track {
            track += config.alpha * (opt[2] - track);
            if !(track.is_finite() && track > 0.5 * p.track && track < 1.5 * p.track) {
                return Err(CalibrationError::Implausible {
                    method: Method::Paper,
                    detail: format!(
                        "track width {track:.3} m at iteration {i}, more than 50 % from the nominal {:.3} m",
                        p.track
                    ),
                });
            }
        }
        // Sigma of this iteration's least-squares solution (block jackknife).
        let sig = jackknife_ls(&pass);
        c = next;
        let dev = dr_deviation(p, r, &params(c, track), slip, TRACK_POINTS);
        iterations.push(IterationRecord {
            n: i,
            circumference_m: RearPair { rl: c[0], rr: c[1] },
            track_width_m: track,
            dr_error_mean_m: dev.mean_m,
            dr_error_max_m: dev.max_m,
        });
        let better = best.as_ref().is_none_or(|b| dev.mean_m < b.2);
        if better && dev.mean_m.is_finite() {
            best = Some((i, c, dev.mean_m, track, sig, dev.track));
        }
        progress(i as f64 / config.iterations as f64);
    }
    let Some((selected, c_best, _, track, sigmas, track_after)) = best else {
        return Err(CalibrationError::Numerical {
            stage: "paper iterations",
            detail: "no iteration produced a finite dead-reckoning deviation".to_string(),
        });
    };
    Ok(MethodResult {
        method: Method::Paper,
        c: c_best,
        track,
        track_estimated: estimate_track,
        side_slip_gain: None,
        side_slip,
        lever_arm: None,
        sigmas,
        iterations,
        selected_iteration: selected,
        residual_rms_m: None,
        segments: 0,
        sigma_basis: Some(crate::products::SigmaBasis {
            method: "block jackknife over time blocks of the paper's least squares".to_string(),
            error_model: None,
        }),
        track_before: dev0.track,
        track_after,
        model_track: None,
        notes: Vec::new(),
    })
}

/// The best iteration so far: number, circumferences, mean deviation,
/// track, sigmas, dead-reckoned track.
type Best = (usize, [f64; 2], f64, f64, Sigmas, Vec<[f64; 2]>);

/// An iteration that leaves the plausible range is an error, not a result.
pub fn check_plausible(
    c: [f64; 2],
    nominal: f64,
    iteration: usize,
) -> Result<(), CalibrationError> {
    for (name, v) in [("c_RL", c[0]), ("c_RR", c[1])] {
        if !(v.is_finite() && v > 0.5 * nominal && v < 1.5 * nominal) {
            return Err(CalibrationError::Implausible {
                method: Method::Paper,
                detail: format!(
                    "{name} = {v:.4} m at iteration {iteration}, more than 50 % from the nominal {nominal:.4} m \
                     (the wheel data and the GNSS do not describe the same motion)"
                ),
            });
        }
    }
    Ok(())
}
