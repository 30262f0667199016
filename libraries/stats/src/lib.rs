//! Small statistics in one home: medians, the MAD sigma, percentiles,
//! angle wrapping, the 2-D rigid fit of one track on another ([`rigid`]) and the tests' distributions ([`distributions`]), used by the readers, the simulator, the calibration, the
//! diagnosis and the odometry alike.
//!
//! Two medians, because the code base uses both on purpose:
//! - [`median`]: the mean of the two middle values of an even count (the
//!   textbook median, what the scores and summaries report);
//! - [`upper_median`]: the sample at rank `n / 2` (for an even count, the
//!   upper of the two middle values): always one of the values, used where a
//!   robust scale or a threshold is taken from the data.
//!
//! Every function orders with [`f64::total_cmp`] (NaN sorts last), so the
//! results are deterministic whatever the input; none allocates unless it
//! says so. Pure: numbers in, numbers out.

pub mod distributions;
pub mod rigid;
pub mod stamps;

use std::f64::consts::{PI, TAU};

/// The factor that makes the median absolute deviation of Gaussian samples
/// an estimate of their standard deviation (1 / Phi^-1(3/4)).
pub const MAD_TO_SIGMA: f64 = 1.4826;

/// The median of `values`, sorting them in place: the middle value, or the
/// mean of the two middle values of an even count. `None` when empty.
pub fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_unstable_by(f64::total_cmp);
    let n = values.len();
    Some(if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    })
}

/// The median of the finite values of `values` (copied), as [`median`];
/// NaN when none is finite.
pub fn median_of_finite(values: &[f64]) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    median(&mut v).unwrap_or(f64::NAN)
}

/// The value of rank `n / 2` of `values` (reordered in place): the median
/// of an odd count, the upper of the two middle values of an even one; always
/// one of the values. `None` when empty.
pub fn upper_median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mid = values.len() / 2;
    let (_, m, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*m)
}

/// [`upper_median`] and [`MAD_TO_SIGMA`] times the upper median of the
/// absolute deviations from it (a Gaussian sigma), of a copy of `values`.
/// `None` when empty.
pub fn upper_median_and_sigma(values: &[f64]) -> Option<(f64, f64)> {
    let mut v = values.to_vec();
    let m = upper_median(&mut v)?;
    for x in &mut v {
        *x = (*x - m).abs();
    }
    Some((m, MAD_TO_SIGMA * upper_median(&mut v)?))
}

/// [`MAD_TO_SIGMA`] times the median absolute deviation from the median
/// ([`median_of_finite`] both times): a robust standard deviation; NaN when
/// no value is finite.
pub fn mad_sigma(values: &[f64]) -> f64 {
    let m = median_of_finite(values);
    let dev: Vec<f64> = values.iter().map(|x| (x - m).abs()).collect();
    MAD_TO_SIGMA * median_of_finite(&dev)
}

/// The `q` quantile (0..=1, clamped) of sorted values, interpolated linearly
/// between order statistics at rank `q (n - 1)` (numpy's default). `None`
/// when empty.
pub fn percentile_sorted(sorted: &[f64], q: f64) -> Option<f64> {
    match sorted.len() {
        0 => None,
        1 => Some(sorted[0]),
        n => {
            let pos = q.clamp(0.0, 1.0) * (n - 1) as f64;
            let i = (pos.floor() as usize).min(n - 2);
            let u = pos - i as f64;
            Some(sorted[i] + u * (sorted[i + 1] - sorted[i]))
        }
    }
}

/// [`percentile_sorted`] of unsorted values (sorted in a copy).
pub fn percentile(values: &[f64], q: f64) -> Option<f64> {
    let mut v = values.to_vec();
    v.sort_unstable_by(f64::total_cmp);
    percentile_sorted(&v, q)
}

/// The `q` quantile (0..=1) of sorted values by nearest rank
/// (`round(q (n - 1))`): always one of the values. NaN when empty.
pub fn nearest_rank(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize]
}

/// An angle wrapped to (-pi, pi], rad.
pub fn wrap_angle(a: f64) -> f64 {
    let w = a.rem_euclid(TAU);
    if w > PI {
        w - TAU
    } else {
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn medians_of_odd_and_even_counts() {
        assert_eq!(median(&mut []), None);
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(upper_median(&mut [4.0, 1.0, 3.0, 2.0]), Some(3.0));
        assert_eq!(upper_median(&mut [5.0, 1.0, 3.0]), Some(3.0));
        assert_eq!(upper_median(&mut []), None);
        assert_eq!(median_of_finite(&[f64::NAN, 1.0, 3.0]), 2.0);
        assert!(median_of_finite(&[f64::NAN]).is_nan());
    }

    #[test]
    fn a_nan_sorts_last_and_does_not_panic() {
        let mut v = [2.0, f64::NAN, 1.0];
        assert_eq!(median(&mut v), Some(2.0));
        assert!(v[2].is_nan());
    }

    #[test]
    fn the_mad_sigma_of_gaussian_quantiles_is_their_sigma() {
        // The quartiles of N(0, 2^2) sit at +-2 * 0.6745: their median
        // absolute deviation times 1.4826 is 2.
        let q = 2.0 * 0.674_489_75;
        let v = [-q, -q, 0.0, q, q];
        assert!((mad_sigma(&v) - 2.0).abs() < 1e-4, "{}", mad_sigma(&v));
        let (m, s) = upper_median_and_sigma(&v).unwrap();
        assert_eq!(m, 0.0);
        assert!((s - 2.0).abs() < 1e-4);
        assert_eq!(upper_median_and_sigma(&[]), None);
    }

    #[test]
    fn percentiles_interpolate_and_nearest_rank_picks_a_value() {
        let v = [0.0, 10.0, 20.0, 30.0, 40.0];
        assert_eq!(percentile_sorted(&v, 0.5), Some(20.0));
        assert_eq!(percentile_sorted(&v, 0.9), Some(36.0));
        assert_eq!(percentile_sorted(&v, 2.0), Some(40.0));
        assert_eq!(percentile(&[40.0, 0.0, 20.0, 10.0, 30.0], 0.25), Some(10.0));
        assert_eq!(percentile_sorted(&[], 0.5), None);
        // (moved here with the function from the odometry's evaluation)
        assert_eq!(percentile(&[3.0, 1.0, 2.0, 4.0], 0.5), Some(2.5));
        let p90 = percentile(&(1..=11).map(f64::from).collect::<Vec<_>>(), 0.9).unwrap();
        assert!((p90 - 10.0).abs() < 1e-12);
        assert_eq!(percentile(&[], 0.5), None);
        assert_eq!(percentile_sorted(&[7.0], 0.3), Some(7.0));
        assert_eq!(nearest_rank(&v, 0.9), 40.0);
        assert_eq!(nearest_rank(&v, 0.5), 20.0);
        assert!(nearest_rank(&[], 0.5).is_nan());
    }

    #[test]
    fn angles_wrap_to_minus_pi_exclusive_pi_inclusive() {
        assert_eq!(wrap_angle(PI), PI);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
        assert!((wrap_angle(-7.0) - (-7.0 + TAU)).abs() < 1e-12);
        // (moved here with the function from drive-io's plausibility checks)
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-0.1) + 0.1).abs() < 1e-12);
        for k in -50..50 {
            let w = wrap_angle(0.37 * k as f64);
            assert!(w > -PI && w <= PI);
        }
    }
}
