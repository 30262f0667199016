//! How much a drive can tell about an effect: the Fisher information of the
//! GNSS positions under their own error model, and the smallest size of the
//! effect a test at a given level finds with a given power (issue 37, the
//! information limit).
//!
//! The GNSS error of each axis is white noise plus a first-order
//! Gauss-Markov wander ([`PositionNoise`], what `crate::error_model` fits to
//! a drive's residuals). Its covariance `sigma_w^2 I + sigma_g^2
//! exp(-|t_i - t_j| / tau)` is whitened exactly in O(n) by the innovations
//! of a scalar Kalman filter on the wander ([`whiten`]): the innovations
//! divided by their standard deviations are `L^-1 a` for the Cholesky factor
//! `L` of that covariance in time order, whatever the spacing of the fixes.
//! An effect's fingerprint (how the positions move per unit of its
//! parameter) and the nuisances (the circumferences, the start pose, a gyro
//! bias: whatever the model fits anyway) are whitened alike, and the
//! nuisances are profiled out ([`profiled_information`]): what is left is
//! the information about the effect that no nuisance can mimic.
//!
//! Pure: numbers in, numbers out.

use nalgebra::{DMatrix, DVector};

/// The GNSS position error of one axis: white plus Gauss-Markov.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionNoise {
    /// White noise, 1-sigma, m.
    pub white_sigma_m: f64,
    /// Stationary 1-sigma of the Gauss-Markov wander, m.
    pub gm_sigma_m: f64,
    /// Its correlation time, s.
    pub gm_tau_s: f64,
}

/// Why an information could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InformationError {
    /// The noise model cannot whiten (no white part, a non-positive or
    /// non-finite sigma or time constant).
    #[error("the noise model cannot whiten: {0}")]
    BadNoise(String),
    /// Times not increasing, or a column of another length.
    #[error("the data cannot be whitened: {0}")]
    BadData(String),
    /// The nuisances alone are singular (a nuisance the data cannot fix).
    #[error("the nuisances are not determined by the data")]
    SingularNuisances,
}

impl PositionNoise {
    fn check(&self) -> Result<(), InformationError> {
        let ok = |v: f64| v.is_finite() && v >= 0.0;
        if !(ok(self.white_sigma_m) && self.white_sigma_m > 0.0) {
            return Err(InformationError::BadNoise(format!(
                "white sigma {} m must be a positive number",
                self.white_sigma_m
            )));
        }
        if !ok(self.gm_sigma_m) {
            return Err(InformationError::BadNoise(format!(
                "Gauss-Markov sigma {} m must be a number >= 0",
                self.gm_sigma_m
            )));
        }
        if self.gm_sigma_m > 0.0 && !(self.gm_tau_s.is_finite() && self.gm_tau_s > 0.0) {
            return Err(InformationError::BadNoise(format!(
                "Gauss-Markov time constant {} s must be a positive number",
                self.gm_tau_s
            )));
        }
        Ok(())
    }

    /// The covariance of the errors at `a` and `b` seconds, m^2.
    pub fn covariance(&self, a: f64, b: f64) -> f64 {
        let white = if a == b {
            self.white_sigma_m.powi(2)
        } else {
            0.0
        };
        let gm = if self.gm_sigma_m > 0.0 {
            self.gm_sigma_m.powi(2) * (-(a - b).abs() / self.gm_tau_s).exp()
        } else {
            0.0
        };
        white + gm
    }
}

/// Whiten `columns` observed at the increasing times `t` (one axis) under
/// `noise`, in place: afterwards `columns[c]` is `L^-1 columns[c]` for the
/// Cholesky factor `L` of the noise covariance, so that the Gram matrix of
/// the whitened columns is the Fisher information of their coefficients.
pub fn whiten(
    t: &[f64],
    noise: &PositionNoise,
    columns: &mut [&mut [f64]],
) -> Result<(), InformationError> {
    noise.check()?;
    let n = t.len();
    if let Some(c) = columns.iter().find(|c| c.len() != n) {
        return Err(InformationError::BadData(format!(
            "a column of {} values for {n} times",
            c.len()
        )));
    }
    if let Some(w) = t
        .windows(2)
        .find(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater))
    {
        return Err(InformationError::BadData(format!(
            "times must increase ({} then {})",
            w[0], w[1]
        )));
    }
    let r = noise.white_sigma_m.powi(2);
    let q_stationary = noise.gm_sigma_m.powi(2);
    // The wander's estimate per column, and its variance (the same for
    // every column: it does not depend on the data).
    let mut g = vec![0.0; columns.len()];
    let mut p = q_stationary;
    for k in 0..n {
        if k > 0 && q_stationary > 0.0 {
            let phi = (-(t[k] - t[k - 1]) / noise.gm_tau_s).exp();
            p = phi * phi * p + q_stationary * (1.0 - phi * phi);
            for gc in &mut g {
                *gc *= phi;
            }
        } else if k > 0 {
            p = 0.0;
        }
        let s = p + r;
        let gain = p / s;
        let scale = s.sqrt();
        for (c, gc) in columns.iter_mut().zip(&mut g) {
            let e = c[k] - *gc;
            *gc += gain * e;
            c[k] = e / scale;
        }
        p *= 1.0 - gain;
    }
    Ok(())
}

/// The information about the coefficient of `target` left after profiling
/// out `nuisances` (all whitened, of one length): `t't - t'N (N'N)^-1 N't`.
pub fn profiled_information(
    target: &[f64],
    nuisances: &[Vec<f64>],
) -> Result<f64, InformationError> {
    let n = target.len();
    if let Some(c) = nuisances.iter().find(|c| c.len() != n) {
        return Err(InformationError::BadData(format!(
            "a nuisance of {} values for a target of {n}",
            c.len()
        )));
    }
    let tt: f64 = target.iter().map(|v| v * v).sum();
    if nuisances.is_empty() {
        return Ok(tt);
    }
    let m = nuisances.len();
    let nn = DMatrix::from_fn(m, m, |i, j| {
        nuisances[i]
            .iter()
            .zip(&nuisances[j])
            .map(|(a, b)| a * b)
            .sum::<f64>()
    });
    let nt = DVector::from_fn(m, |i, _| {
        nuisances[i]
            .iter()
            .zip(target)
            .map(|(a, b)| a * b)
            .sum::<f64>()
    });
    let chol = nn.cholesky().ok_or(InformationError::SingularNuisances)?;
    let explained = nt.dot(&chol.solve(&nt));
    Ok((tt - explained).max(0.0))
}

/// The profiled information of `target` (as [`profiled_information`]) and
/// the coefficient's estimate from the whitened data `y`, the nuisances
/// fitted alongside: `t_perp' y / t_perp' t_perp`, where `t_perp` is the
/// target's part that no nuisance explains. The estimate is 0 without
/// information.
pub fn profiled_estimate(
    target: &[f64],
    nuisances: &[Vec<f64>],
    y: &[f64],
) -> Result<(f64, f64), InformationError> {
    let n = target.len();
    if y.len() != n {
        return Err(InformationError::BadData(format!(
            "data of {} values for a target of {n}",
            y.len()
        )));
    }
    if let Some(c) = nuisances.iter().find(|c| c.len() != n) {
        return Err(InformationError::BadData(format!(
            "a nuisance of {} values for a target of {n}",
            c.len()
        )));
    }
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let (tt, ty) = (dot(target, target), dot(target, y));
    if nuisances.is_empty() {
        return Ok((tt, if tt > 0.0 { ty / tt } else { 0.0 }));
    }
    let m = nuisances.len();
    let nn = DMatrix::from_fn(m, m, |i, j| dot(&nuisances[i], &nuisances[j]));
    let nt = DVector::from_fn(m, |i, _| dot(&nuisances[i], target));
    let ny = DVector::from_fn(m, |i, _| dot(&nuisances[i], y));
    let chol = nn.cholesky().ok_or(InformationError::SingularNuisances)?;
    let nn_inv_nt = chol.solve(&nt);
    let info = (tt - nt.dot(&nn_inv_nt)).max(0.0);
    let cross = ty - ny.dot(&nn_inv_nt);
    Ok((info, if info > 0.0 { cross / info } else { 0.0 }))
}

/// The smallest size of a coefficient with profiled information `info`
/// that a two-sided test at level `alpha` finds with probability `power`:
/// `(z(1 - alpha / 2) + z(power)) / sqrt(info)` (infinite without
/// information).
pub fn detectable_size(info: f64, alpha: f64, power: f64) -> f64 {
    if !(info > 0.0 && info.is_finite()) {
        return f64::INFINITY;
    }
    let z = stats::distributions::normal_quantile;
    (z(1.0 - 0.5 * alpha) + z(power)) / info.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise() -> PositionNoise {
        PositionNoise {
            white_sigma_m: 0.5,
            gm_sigma_m: 1.5,
            gm_tau_s: 30.0,
        }
    }

    /// Irregular times: 10 Hz with gaps.
    fn times(n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| 0.1 * k as f64 + if k > n / 2 { 7.3 } else { 0.0 } + 0.013 * (k % 3) as f64)
            .collect()
    }

    #[test]
    fn the_kalman_whitening_is_the_dense_cholesky_whitening() {
        let t = times(60);
        let nz = noise();
        let a: Vec<f64> = t.iter().map(|x| (0.3 * x).sin() + 0.05 * x).collect();
        let b: Vec<f64> = t.iter().map(|x| 1.0 + 0.0 * x).collect();
        let (mut wa, mut wb) = (a.clone(), b.clone());
        whiten(&t, &nz, &mut [&mut wa, &mut wb]).unwrap();
        // Dense: the Gram matrix a' C^-1 b.
        let n = t.len();
        let c = DMatrix::from_fn(n, n, |i, j| nz.covariance(t[i], t[j]));
        let chol = c.cholesky().unwrap();
        let (va, vb) = (DVector::from_vec(a), DVector::from_vec(b));
        let dense = |x: &DVector<f64>, y: &DVector<f64>| x.dot(&chol.solve(y));
        let fast = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>();
        for (d, f) in [
            (dense(&va, &va), fast(&wa, &wa)),
            (dense(&va, &vb), fast(&wa, &wb)),
            (dense(&vb, &vb), fast(&wb, &wb)),
        ] {
            assert!((d - f).abs() <= 1e-9 * d.abs().max(1.0), "{d} vs {f}");
        }
    }

    #[test]
    fn white_noise_alone_gives_the_textbook_information() {
        let t = times(50);
        let nz = PositionNoise {
            gm_sigma_m: 0.0,
            ..noise()
        };
        let f: Vec<f64> = t.iter().map(|x| x * 0.2).collect();
        let mut w = f.clone();
        whiten(&t, &nz, &mut [&mut w]).unwrap();
        let info = profiled_information(&w, &[]).unwrap();
        let expected: f64 = f.iter().map(|v| v * v / 0.25).sum();
        assert!((info - expected).abs() < 1e-9 * expected);
    }

    #[test]
    fn a_wander_hides_a_constant_offset_but_not_a_fast_signal() {
        // A constant offset looks like the wander over a short stretch; a
        // signal that alternates every fix does not.
        let t: Vec<f64> = (0..200).map(|k| 0.1 * k as f64).collect();
        let constant = vec![1.0; t.len()];
        let alternating: Vec<f64> = (0..t.len())
            .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let info_of = |col: &[f64], nz: &PositionNoise| {
            let mut w = col.to_vec();
            whiten(&t, nz, &mut [&mut w]).unwrap();
            profiled_information(&w, &[]).unwrap()
        };
        let white = PositionNoise {
            gm_sigma_m: 0.0,
            ..noise()
        };
        assert!(info_of(&constant, &noise()) < 0.05 * info_of(&constant, &white));
        assert!(info_of(&alternating, &noise()) > 0.9 * info_of(&alternating, &white));
    }

    #[test]
    fn a_nuisance_that_mimics_the_target_takes_its_information() {
        let target = vec![1.0, 2.0, 3.0, 4.0];
        let same = vec![vec![2.0, 4.0, 6.0, 8.0]];
        assert!(profiled_information(&target, &same).unwrap() < 1e-9);
        let orthogonal = vec![vec![1.0, -1.0, -1.0, 1.0]];
        // (1 - 2 - 3 + 4) = 0: orthogonal, nothing taken.
        assert!((profiled_information(&target, &orthogonal).unwrap() - 30.0).abs() < 1e-9);
        assert_eq!(
            profiled_information(&target, &[vec![0.0; 4]]),
            Err(InformationError::SingularNuisances)
        );
    }

    #[test]
    fn the_detectable_size_at_90_percent_power() {
        // alpha 0.05 two-sided, power 0.9: (1.960 + 1.282) / sqrt(info).
        let d = detectable_size(4.0, 0.05, 0.9);
        assert!((d - (1.959964 + 1.281552) / 2.0).abs() < 1e-5, "{d}");
        assert_eq!(detectable_size(0.0, 0.05, 0.9), f64::INFINITY);
    }

    #[test]
    fn bad_noise_and_bad_times_are_typed_errors() {
        let t = [0.0, 1.0, 1.0];
        let mut c = vec![0.0; 3];
        assert!(matches!(
            whiten(&t, &noise(), &mut [&mut c]),
            Err(InformationError::BadData(_))
        ));
        let bad = PositionNoise {
            white_sigma_m: 0.0,
            ..noise()
        };
        assert!(matches!(
            whiten(&[0.0, 1.0], &bad, &mut [&mut [0.0, 0.0][..]]),
            Err(InformationError::BadNoise(_))
        ));
    }
}
