//! What the fits hand on and the result shows, as plain types: a value per
//! rear wheel, the per-iteration table, a method's summary, the sigmas and
//! what they rest on. Beside the stages: the fits fill them, the sigmas
//! stage and the result read them (the result re-exports them).

use crate::method::Method;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// Points kept of the dead-reckoned tracks for the plots.
pub const TRACK_POINTS: usize = 3000;

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
