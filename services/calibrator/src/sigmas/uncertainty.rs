//! Sigmas of the estimate and the observability warnings.
//!
//! GNSS errors are correlated in time, so a formal least-squares covariance
//! over thousands of samples is far too optimistic. The batch fit (and the
//! gyro fit) take their sigmas from an error model of the drive's own
//! residuals ([`crate::error_model`], described in the result by
//! [`SigmaBasis`]). The paper's least squares uses a *block jackknife*
//! ([`crate::fit::jackknife`], which the fits run as they go): the drive is
//! cut into contiguous time blocks, the estimate is recomputed without
//! each, and the spread of those estimates gives the covariance.

use crate::reference::Reference;
use crate::warnings::{Warning, WarningCode};

pub use crate::fit::jackknife::{infinite, jackknife_covariance, jackknife_ls};
pub use crate::fit::track_width::NO_TURN_DEG;
pub use crate::products::{AxisNoise, SigmaBasis, Sigmas};

impl SigmaBasis {
    /// Sigmas from the error model `m` (east, north).
    pub fn error_model(m: &[crate::error_model::ErrorModel; 2]) -> SigmaBasis {
        SigmaBasis {
            method: "GNSS error model of the fit residuals (white + correlated, per axis)"
                .to_string(),
            error_model: Some(m.map(|a| AxisNoise {
                white_sigma_m: a.white_var_m2.sqrt(),
                correlated_sigma_m: a.gm_var_m2.sqrt(),
                correlation_time_s: a.tau_s,
                resolved: a.tau_s <= a.max_lag_s,
            })),
        }
    }
}

/// Limits above which a parameter is reported as not determined.
pub const DIFFERENCE_SIGMA_LIMIT_M: f64 = 0.001;
/// Limit on the sigma of the common scale, m.
pub const MEAN_SIGMA_LIMIT_M: f64 = 0.002;
/// Limit on the sigma of the track width, m.
pub const TRACK_SIGMA_LIMIT_M: f64 = 0.02;

/// Observability warnings for an estimate with `sigmas` on the drive
/// described by `r`. Each names the parameter and the reason.
pub fn observability(
    r: &Reference,
    sigmas: &Sigmas,
    track_estimated: bool,
    residual_rms_m: Option<f64>,
) -> Vec<Warning> {
    let mut out = Vec::new();
    let turn_deg = r.total_turn_rad.to_degrees();
    let used = r.fixes.iter().filter(|f| f.accepted).count();
    let mut causes = Vec::new();
    if turn_deg < 90.0 {
        causes.push(format!("the drive turns only {turn_deg:.0} deg in total"));
    }
    if r.distance_m < 500.0 {
        causes.push(format!("it covers only {:.0} m with GNSS", r.distance_m));
    }
    if r.gnss_sigma_m > 2.0 {
        causes.push(format!("the GNSS noise is {:.1} m", r.gnss_sigma_m));
    }
    if let Some(rms) = residual_rms_m {
        if rms > 3.0 * r.gnss_sigma_m.max(0.05) {
            causes.push(format!(
                "the 2W model fits the GNSS only to {rms:.2} m RMS (GNSS noise {:.2} m): physics the model leaves out",
                r.gnss_sigma_m
            ));
        }
    }
    if used < 100 {
        causes.push(format!("only {used} GNSS fixes are usable"));
    }
    let because = |default: &str| {
        if causes.is_empty() {
            default.to_string()
        } else {
            causes.join(", ")
        }
    };
    if turn_deg < NO_TURN_DEG {
        out.push(Warning::new(
            WarningCode::NoTurn,
            format!(
                "no turn: the drive turns only {turn_deg:.0} deg in total; c_RR - c_RL is pinned only by how straight \
                 the path runs: its sigma is for this road (its camber, crosswind and load act the same way throughout \
                 and are in the estimate; another road's may differ by more), and the track width cannot be estimated"
            ),
        ));
    }
    if sigmas.difference.is_nan() || sigmas.difference > DIFFERENCE_SIGMA_LIMIT_M {
        out.push(Warning::new(
            WarningCode::DifferenceUnobservable,
            format!(
                "c_RL and c_RR are not separated: sigma of c_RR - c_RL is {} (limit {:.1} mm) because {}; \
                 only their mean (sigma {}) is determined — drive more turns and longer straights",
                fmt_mm(sigmas.difference),
                1000.0 * DIFFERENCE_SIGMA_LIMIT_M,
                because("the heading information is weak"),
                fmt_mm(sigmas.mean)
            ),
        ));
    }
    if sigmas.mean.is_nan() || sigmas.mean > MEAN_SIGMA_LIMIT_M {
        out.push(Warning::new(
            WarningCode::ScaleUnobservable,
            format!(
                "the common scale (c_RL + c_RR)/2 is poorly determined: sigma {} (limit {:.1} mm) because {}",
                fmt_mm(sigmas.mean),
                1000.0 * MEAN_SIGMA_LIMIT_M,
                because("the distance information is weak")
            ),
        ));
    }
    if track_estimated {
        if let Some(st) = sigmas.track {
            let corr = sigmas.corr_difference_track.unwrap_or(0.0);
            if st.is_nan() || st > TRACK_SIGMA_LIMIT_M || corr.abs() > 0.95 {
                out.push(Warning::new(
                    WarningCode::TrackWidthUnobservable,
                    format!(
                        "the track width is poorly determined: sigma {:.1} mm, correlation with c_RR - c_RL {corr:.2}; \
                         it needs both turns (to scale it) and straights (to fix c_RR/c_RL)",
                        1000.0 * st
                    ),
                ));
            }
        }
    }
    out
}

fn fmt_mm(v: f64) -> String {
    if v.is_finite() {
        format!("{:.2} mm", 1000.0 * v)
    } else {
        "not determined".to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    #[test]
    fn sigmas_of_a_covariance() {
        let c = DMatrix::from_row_slice(2, 2, &[4e-6, 3e-6, 3e-6, 4e-6]);
        let s = Sigmas::from_covariance(&c);
        assert!((s.rl - 2e-3).abs() < 1e-12);
        assert!((s.difference - (2e-6f64).sqrt()).abs() < 1e-12);
        assert!((s.mean - (3.5e-6f64).sqrt()).abs() < 1e-12);
        assert!(s.track.is_none());
    }

    #[test]
    fn jackknife_of_constant_estimates_is_zero() {
        let e: Vec<DVector<f64>> = (0..5).map(|_| DVector::from_vec(vec![1.0, 2.0])).collect();
        let c = jackknife_covariance(&e).expect("enough");
        assert!(c.iter().all(|v| v.abs() < 1e-15));
        assert!(jackknife_covariance(&e[..2]).is_none());
    }
}
