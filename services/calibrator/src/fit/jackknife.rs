//! The block jackknife the fits take their sigmas from where no error
//! model could be fitted: the estimate recomputed without each block of the
//! drive, and the spread of those estimates as the covariance.

use crate::fit::ekf::{EkfPass, NormalBlock};
use crate::products::Sigmas;
use nalgebra::{DMatrix, DVector};

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
