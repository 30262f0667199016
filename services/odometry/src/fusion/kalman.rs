//! The Kalman maths of the filter, on its state layout: the predicted
//! covariance (`F P F^T + Q`, written out for the structure of `F`), the
//! update with the consider states' rows of the gain zeroed (the Joseph
//! form, written out), symmetrising, and the chi-square quantiles and
//! statistic that test an innovation or an error against its covariance.

use super::state::{StateMat, StateVec, N, SCALE, WHEEL_DIFF};
use nalgebra::{SMatrix, SVector};

/// 99.9 % quantile of chi-square with 2 degrees of freedom.
pub const CHI2_2DOF_999: f64 = 13.816;
/// 99.9 % quantile of chi-square with 1 degree of freedom.
pub const CHI2_1DOF_999: f64 = 10.828;
/// 95 % quantile of chi-square with 2 degrees of freedom.
pub const CHI2_2DOF_95: f64 = 5.991;

/// e^T P^-1 e for a position error `e` and its 2x2 covariance `p`
/// (row-major): chi-square with 2 degrees of freedom when the covariance is
/// honest. `None` when `p` cannot be inverted.
pub fn position_chi2(e: [f64; 2], p: [f64; 4]) -> Option<f64> {
    let det = p[0] * p[3] - p[1] * p[2];
    if !(det.is_finite() && det > 0.0) {
        return None;
    }
    let v = (e[0] * (p[3] * e[0] - p[1] * e[1]) + e[1] * (p[0] * e[1] - p[2] * e[0])) / det;
    v.is_finite().then_some(v)
}

/// The predicted covariance `F P F^T + Q` for `F = I + E`, where `e` holds
/// E's only non-zero block (rows x, y, yaw; columns yaw to WHEEL_DIFF), and Q
/// is zero outside the pose block `q_pose` and the bias variance `q_bias`.
/// The same as the dense product up to rounding, in about a quarter of its
/// multiplications (it runs at every wheel sample, on the path to the pose),
/// and symmetric by construction.
pub(super) fn propagate_covariance(
    p: &StateMat,
    e: &[[f64; 4]; 3],
    q_pose: &[[f64; 3]; 3],
    q_bias: f64,
) -> StateMat {
    // A = F P differs from P in rows 0-2 only.
    let fp: [[f64; N]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| p[(i, j)] + (0..4).map(|k| e[i][k] * p[(2 + k, j)]).sum::<f64>())
    });
    // A F^T differs from A in columns 0-2 only; outside the pose block it is
    // A's rows 0-2 mirrored, and rows and columns 3-5 keep P's values.
    let mut out = *p;
    for (i, row) in fp.iter().enumerate() {
        for j in 3..N {
            out[(i, j)] = row[j];
            out[(j, i)] = row[j];
        }
        for j in i..3 {
            let v = row[j] + (0..4).map(|k| row[2 + k] * e[j][k]).sum::<f64>() + q_pose[i][j];
            out[(i, j)] = v;
            out[(j, i)] = v;
        }
    }
    out[(3, 3)] += q_bias;
    out
}

/// Make `p` exactly symmetric: the mean of it and its transpose.
pub(super) fn symmetrise(p: &mut StateMat) {
    let t = p.transpose();
    *p = (*p + t) * 0.5;
}

/// Kalman update with gain `K = P H^T S^-1`, where `ph` is `P H^T` and `s`
/// is `H P H^T + R`. The distance scale and the wheel difference are consider
/// states (Schmidt-Kalman): their rows of the gain are zeroed, so they are
/// never estimated and keep their variances, and only widen the pose
/// covariance through the cross terms.
///
/// The covariance is the Joseph form `(I - K H) P (I - K H)^T + K R K^T`,
/// which holds for any gain (so also for the zeroed rows), written out as
/// `P - K B^T - B K^T + K S K^T` with `B = P H^T`: the same up to rounding in
/// under a third of the dense products' multiplications (a wakeup with a GNSS
/// fix and a heading runs two updates on the path to its pose), and symmetric
/// by construction.
pub(super) fn kalman_update<const M: usize>(
    x: StateVec,
    p: &StateMat,
    ph: &SMatrix<f64, N, M>,
    s: &SMatrix<f64, M, M>,
    s_inverse: &SMatrix<f64, M, M>,
    nu: &SVector<f64, M>,
) -> (StateVec, StateMat) {
    let mut gain = ph * s_inverse;
    gain.row_mut(SCALE).fill(0.0);
    gain.row_mut(WHEEL_DIFF).fill(0.0);
    let x = x + gain * nu;
    let ks = gain * s;
    let mut out = *p;
    for i in 0..N {
        for j in i..N {
            let change: f64 = (0..M)
                .map(|m| (ks[(i, m)] - ph[(i, m)]) * gain[(j, m)] - gain[(i, m)] * ph[(j, m)])
                .sum();
            out[(i, j)] += change;
            out[(j, i)] = out[(i, j)];
        }
    }
    (x, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The structured prediction equals the dense `F P F^T + Q` (to
    /// rounding) for a full covariance with every correlation non-zero.
    #[test]
    fn the_structured_prediction_is_the_dense_product() {
        // A symmetric positive definite P = L L^T with L full lower-triangular.
        let l = StateMat::from_fn(|i, j| {
            if j <= i {
                0.3 + 0.1 * (i as f64) - 0.07 * (j as f64) + if i == j { 1.0 } else { 0.0 }
            } else {
                0.0
            }
        });
        let p = l * l.transpose();
        let e = [
            [-0.31, 0.02, 0.95, -0.004],
            [0.95, -0.03, 0.31, 0.006],
            [0.0, -0.01, 0.002, 0.66],
        ];
        let q_pose = [[2e-4, 1e-5, -3e-6], [1e-5, 3e-4, 4e-6], [-3e-6, 4e-6, 5e-6]];
        let q_bias = 7e-9;
        let mut f = StateMat::identity();
        let mut q = StateMat::zeros();
        for i in 0..3 {
            for k in 0..4 {
                f[(i, 2 + k)] += e[i][k];
            }
            for j in 0..3 {
                q[(i, j)] = q_pose[i][j];
            }
        }
        q[(3, 3)] = q_bias;
        let dense = f * p * f.transpose() + q;
        let structured = propagate_covariance(&p, &e, &q_pose, q_bias);
        assert_symmetric_and_equal(&structured, &dense, "the dense product");
    }

    /// `fast` is symmetric and equals `dense` to 1e-12 of its largest entry.
    fn assert_symmetric_and_equal(fast: &StateMat, dense: &StateMat, what: &str) {
        for i in 0..N {
            for j in 0..N {
                let (a, b) = (fast[(i, j)], dense[(i, j)]);
                assert!(
                    (a - b).abs() <= 1e-12 * dense.amax(),
                    "({i}, {j}): {a} against {b} from {what}"
                );
                assert_eq!(a, fast[(j, i)], "not symmetric at ({i}, {j})");
            }
        }
    }

    /// The expanded update equals the dense Joseph form
    /// `(I - K H) P (I - K H)^T + K R K^T` (to rounding) with the consider
    /// rows of the gain zeroed, for a GNSS fix with a lever arm and for a
    /// heading, on a full covariance with every correlation non-zero; the
    /// consider states keep their variances and covariance.
    #[test]
    fn the_expanded_update_is_the_joseph_form() {
        fn check<const M: usize>(p: &StateMat, h: SMatrix<f64, M, N>, r: SMatrix<f64, M, M>) {
            let x = StateVec::from_fn(|i, _| 0.1 * i as f64);
            let nu = SVector::<f64, M>::from_fn(|i, _| 0.3 - 0.5 * i as f64);
            let ph = p * h.transpose();
            let s = h * ph + r;
            let s_inverse = s.try_inverse().expect("S is invertible");
            let (x_new, p_new) = kalman_update(x, p, &ph, &s, &s_inverse, &nu);

            let mut gain = ph * s_inverse;
            gain.row_mut(SCALE).fill(0.0);
            gain.row_mut(WHEEL_DIFF).fill(0.0);
            let i_kh = StateMat::identity() - gain * h;
            let joseph = i_kh * p * i_kh.transpose() + gain * r * gain.transpose();
            assert!((x_new - (x + gain * nu)).amax() <= 1e-12);
            assert_symmetric_and_equal(&p_new, &joseph, "the Joseph form");
            for (i, j) in [
                (SCALE, SCALE),
                (SCALE, WHEEL_DIFF),
                (WHEEL_DIFF, WHEEL_DIFF),
            ] {
                assert_eq!(p_new[(i, j)], p[(i, j)], "consider covariance ({i}, {j})");
            }
            // The update took something off the pose's variance.
            assert!(p_new[(0, 0)] < p[(0, 0)] || p_new[(2, 2)] < p[(2, 2)]);
        }
        let l = StateMat::from_fn(|i, j| {
            if j <= i {
                0.2 - 0.05 * (i as f64) + 0.09 * (j as f64) + if i == j { 0.8 } else { 0.0 }
            } else {
                0.0
            }
        });
        let p = l * l.transpose();
        let (s, c) = 0.7f64.sin_cos();
        let (lx, ly) = (1.3, -0.4);
        let mut gnss = SMatrix::<f64, 2, N>::zeros();
        gnss[(0, 0)] = 1.0;
        gnss[(1, 1)] = 1.0;
        gnss[(0, 2)] = -lx * s - ly * c;
        gnss[(1, 2)] = lx * c - ly * s;
        check(&p, gnss, SMatrix::<f64, 2, 2>::identity() * 0.04);
        let mut heading = SMatrix::<f64, 1, N>::zeros();
        heading[(0, 2)] = 1.0;
        check(&p, heading, SMatrix::<f64, 1, 1>::new(1e-3));
    }
}
