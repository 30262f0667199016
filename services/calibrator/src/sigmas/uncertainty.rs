//! Sigmas of the estimate and the observability warnings.
//!
//! GNSS errors are correlated in time, so a formal least-squares covariance
//! over thousands of samples is far too optimistic. The batch fit (and the
//! gyro fit) take their sigmas from an error model of the drive's own
//! residuals ([`crate::sigmas::error_model`], described in the result by
//! [`SigmaBasis`]). The paper's least squares uses a *block jackknife*: the
//! drive is cut into contiguous time blocks, the estimate is recomputed
//! without each, and the spread of those estimates gives the covariance.

use crate::fit::ekf::{EkfPass, NormalBlock};
use crate::reference::Reference;
use crate::warnings::{Warning, WarningCode};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// 1-sigma uncertainties of the estimated parameters.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Sigmas {
    /// c_RL, m.
    pub rl: f64,
    /// c_RR, m.
    pub rr: f64,
    /// c_RR - c_RL, m.
    pub difference: f64,
    /// (c_RL + c_RR) / 2, m.
    pub mean: f64,
    /// Track width, m (when estimated).
    pub track: Option<f64>,
    /// Correlation of (c_RR - c_RL) with the track width (when estimated).
    pub corr_difference_track: Option<f64>,
}

impl Sigmas {
    /// Sigmas from a covariance of `[c_RL, c_RR]` or `[c_RL, c_RR, t_R, ...]`.
    pub fn from_covariance(c: &DMatrix<f64>) -> Sigmas {
        let v = |i: usize, j: usize| c[(i, j)];
        let diff_var = (v(0, 0) + v(1, 1) - 2.0 * v(0, 1)).max(0.0);
        let mean_var = (0.25 * (v(0, 0) + v(1, 1) + 2.0 * v(0, 1))).max(0.0);
        let (track, corr) = if c.nrows() >= 3 {
            let tv = v(2, 2).max(0.0);
            let cov_dt = v(1, 2) - v(0, 2);
            let denom = (diff_var * tv).sqrt();
            (Some(tv.sqrt()), (denom > 0.0).then(|| cov_dt / denom))
        } else {
            (None, None)
        };
        Sigmas {
            rl: v(0, 0).max(0.0).sqrt(),
            rr: v(1, 1).max(0.0).sqrt(),
            difference: diff_var.sqrt(),
            mean: mean_var.sqrt(),
            track,
            corr_difference_track: corr,
        }
    }

    /// The larger of two sigma sets, entry by entry.
    pub fn max(self, other: Sigmas) -> Sigmas {
        let m = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        };
        Sigmas {
            rl: self.rl.max(other.rl),
            rr: self.rr.max(other.rr),
            difference: self.difference.max(other.difference),
            mean: self.mean.max(other.mean),
            track: m(self.track, other.track),
            corr_difference_track: self.corr_difference_track.or(other.corr_difference_track),
        }
    }
}

/// One axis of the GNSS error model the sigmas came from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AxisNoise {
    /// White part, 1-sigma, m.
    pub white_sigma_m: f64,
    /// Correlated (Gauss-Markov) part, 1-sigma, m.
    pub correlated_sigma_m: f64,
    /// Its correlation time, s.
    pub correlation_time_s: f64,
    /// Whether the drive resolved that time (it is within the lags the
    /// residuals showed); if not, the least favourable plausible value was
    /// taken.
    pub resolved: bool,
}

/// What the calibration's sigmas rest on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SigmaBasis {
    /// In words.
    pub method: String,
    /// The error model of the east and north residuals, when one was fitted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error_model: Option<[AxisNoise; 2]>,
}

impl SigmaBasis {
    /// Sigmas from the error model `m` (east, north).
    pub fn error_model(m: &[crate::sigmas::error_model::ErrorModel; 2]) -> SigmaBasis {
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

    /// Sigmas from a jackknife (`true`) or the formal covariance alone.
    pub fn jackknife(jackknife: bool) -> SigmaBasis {
        SigmaBasis {
            method: if jackknife {
                "block jackknife (the residuals showed too few lags for an error model)"
            } else {
                "formal covariance only (too few fixes for an error model or a jackknife)"
            }
            .to_string(),
            error_model: None,
        }
    }

    /// One line for a text report.
    pub fn describe(&self) -> String {
        match &self.error_model {
            Some([e, n]) => {
                let axis = |a: &AxisNoise| {
                    format!(
                        "{:.3} m white + {:.3} m over {:.0} s{}",
                        a.white_sigma_m,
                        a.correlated_sigma_m,
                        a.correlation_time_s,
                        if a.resolved {
                            ""
                        } else {
                            " (not resolved: least favourable)"
                        }
                    )
                };
                format!("{}: east {}, north {}", self.method, axis(e), axis(n))
            }
            None => self.method.clone(),
        }
    }
}

/// Block jackknife of the paper's least squares (exact leave-one-block-out solves).
pub fn jackknife_ls(pass: &EkfPass) -> Sigmas {
    let mut estimates = Vec::new();
    for b in pass.blocks.iter().filter(|b| b.rows > 0) {
        let rest = NormalBlock {
            a: pass.total.a - b.a,
            b: pass.total.b - b.b,
            yy: pass.total.yy - b.yy,
            rows: pass.total.rows - b.rows,
        };
        match rest.solve(pass.dim) {
            Some(x) => estimates.push(DVector::from_iterator(
                pass.dim,
                x.iter().copied().take(pass.dim),
            )),
            None => return infinite(),
        }
    }
    jackknife_covariance(&estimates).map_or_else(infinite, |c| Sigmas::from_covariance(&c))
}

/// Jackknife covariance `(S-1)/S sum (x_s - mean)(x_s - mean)^T`.
pub fn jackknife_covariance(estimates: &[DVector<f64>]) -> Option<DMatrix<f64>> {
    let s = estimates.len();
    if s < 3 {
        return None;
    }
    let dim = estimates[0].len();
    let mut mean = DVector::zeros(dim);
    for e in estimates {
        mean += e;
    }
    mean /= s as f64;
    let mut c = DMatrix::zeros(dim, dim);
    for e in estimates {
        let d = e - &mean;
        c += &d * d.transpose();
    }
    Some(c * ((s as f64 - 1.0) / s as f64))
}

/// Sigmas that say "not determined".
pub fn infinite() -> Sigmas {
    Sigmas {
        rl: f64::INFINITY,
        rr: f64::INFINITY,
        difference: f64::INFINITY,
        mean: f64::INFINITY,
        track: None,
        corr_difference_track: None,
    }
}

/// Limits above which a parameter is reported as not determined.
pub const DIFFERENCE_SIGMA_LIMIT_M: f64 = 0.001;
/// Limit on the sigma of the common scale, m.
pub const MEAN_SIGMA_LIMIT_M: f64 = 0.002;
/// Limit on the sigma of the track width, m.
pub const TRACK_SIGMA_LIMIT_M: f64 = 0.02;
/// Turning below which the drive counts as having no turn, degrees.
pub const NO_TURN_DEG: f64 = 30.0;

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
