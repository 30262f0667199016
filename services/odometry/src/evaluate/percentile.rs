//! Percentiles of the scores: the median of an even count is the mean of
//! the two middle values, and any other percentile interpolates linearly
//! between order statistics (rank p (n - 1), as numpy's default).

/// Median and linearly interpolated percentile of unsorted values.
pub fn percentile(values: &[f64], p: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let rank = p.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let lo = rank.floor() as usize;
    let hi = rank.ceil() as usize;
    Some(v[lo] + (rank - lo as f64) * (v[hi] - v[lo]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_interpolate() {
        assert_eq!(percentile(&[3.0, 1.0, 2.0, 4.0], 0.5), Some(2.5));
        let p90 = percentile(&(1..=11).map(f64::from).collect::<Vec<_>>(), 0.9).unwrap();
        assert!((p90 - 10.0).abs() < 1e-12);
        assert_eq!(percentile(&[], 0.5), None);
    }
}
