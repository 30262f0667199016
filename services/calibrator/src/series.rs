//! The drive as the stages' arrays and their look-ups (shared by the
//! stages): [`Series`], every stream on the wheels' clock at the wheel
//! sample times, with the gyro look-ups the later stages read
//! ([`Series::gyro_cum_at`], [`Series::gyro_mean_rate`],
//! [`Series::gyro_at_cursor`]), and the GNSS noise measured on fixes.
//! Pure data and functions on it: a later stage reading an earlier
//! product calls these, not the earlier stage's code.

use interfaces::drive::HeadingSample;

/// A GNSS fix in local ENU (antenna position).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fix {
    /// Time, s.
    pub t: f64,
    /// East, m.
    pub x: f64,
    /// North, m.
    pub y: f64,
    /// 1-sigma from the data, when given.
    pub sigma: Option<f64>,
}

/// The drive in the form the layers use: built by the clocks stage
/// ([`crate::clocks::align`]) from the checked drive ([`crate::check`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Wheel sample times, s.
    pub t: Vec<f64>,
    /// Rear-left revolutions since the previous sample (0 at a piece start).
    pub dn_rl: Vec<f64>,
    /// Rear-right revolutions since the previous sample (0 at a piece start).
    pub dn_rr: Vec<f64>,
    /// Indices where a continuous piece of wheel data starts (0 first).
    pub piece_starts: Vec<usize>,
    /// Median wheel sample interval, s.
    pub wheel_dt: f64,
    /// Finite GNSS fixes in time order.
    pub fixes: Vec<Fix>,
    /// The yaw-rate gyro's trapezoidal integral at each wheel time, rad (NaN
    /// where the IMU does not cover it); `None` without a usable IMU.
    pub gyro: Option<Vec<f64>>,
    /// True when the IMU has both horizontal accelerations.
    pub has_accel: bool,
    /// Finite absolute headings.
    pub headings: Vec<HeadingSample>,
    /// GNSS antenna position in the body frame (x forward, y left) from the rear-axle centre, m.
    pub lever_arm: [f64; 2],
    /// Whether `vehicle.toml` gives each coordinate of `lever_arm` (measured),
    /// or it is the axle-centre default.
    pub lever_arm_given: [bool; 2],
    /// Nominal circumference, m.
    pub nominal_c: f64,
    /// Nominal rear track, m.
    pub track: f64,
    /// Standstill intervals (start, end), s, at least 1 s long.
    pub standstill: Vec<(f64, f64)>,
    /// Lateral acceleration `v omega` from the wheels with the nominal
    /// values, averaged over 0.5 s (per-step increments of a quantised
    /// encoder are far too noisy for a side-slip model), m/s^2.
    pub lateral_accel: Vec<f32>,
    /// Offsets subtracted from rate-type wheel channels (rl, rr in the
    /// channel's unit) and the standstill seconds they come from.
    pub wheel_offsets: Option<(f64, f64, f64)>,
    /// Subtracted from the IMU time stamps before use (the IMU offset when
    /// it is compensated, else 0; the clocks stage's `imu_clock`), s. The
    /// reference subtracts it from the accelerations' times too.
    pub imu_shift_s: f64,
}

impl Series {
    /// True when sample `k` starts a piece (its increment is not a motion).
    pub fn is_piece_start(&self, k: usize) -> bool {
        self.piece_starts.binary_search(&k).is_ok()
    }

    /// Number of wheel samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when there is no wheel sample.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// The gyro's cumulative angle at `t` (linear between wheel times),
    /// `None` without gyro, outside the data or across an IMU pause.
    pub fn gyro_cum_at(&self, t: f64) -> Option<f64> {
        let g = self.gyro.as_ref()?;
        let n = self.t.len();
        if n < 2 || !(t >= self.t[0] && t <= self.t[n - 1]) {
            return None;
        }
        let i = self.t.partition_point(|&s| s <= t).clamp(1, n - 1);
        let (t0, t1) = (self.t[i - 1], self.t[i]);
        let f = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
        let v = g[i - 1] + f * (g[i] - g[i - 1]);
        v.is_finite().then_some(v)
    }

    /// Mean gyro rate between `t0` and `t1`, `None` when not covered.
    pub fn gyro_mean_rate(&self, t0: f64, t1: f64) -> Option<f64> {
        if t1 <= t0 {
            return None;
        }
        let g = self.gyro.as_ref()?;
        let i0 = self.t.partition_point(|&s| s < t0);
        let i1 = self.t.partition_point(|&s| s <= t1);
        if g[i0.min(g.len() - 1)..i1.min(g.len())]
            .iter()
            .any(|v| !v.is_finite())
        {
            return None;
        }
        Some((self.gyro_cum_at(t1)? - self.gyro_cum_at(t0)?) / (t1 - t0))
    }

    /// The gyro integral at `t` (increasing between calls), by a forward
    /// cursor; NaN without gyro or outside the wheel times.
    pub fn gyro_at_cursor(&self, t: f64, cursor: &mut usize) -> f64 {
        let Some(g) = self.gyro.as_ref() else {
            return f64::NAN;
        };
        let n = self.t.len();
        if n < 2 || !(t >= self.t[0] && t <= self.t[n - 1]) {
            return f64::NAN;
        }
        while *cursor + 2 < n && self.t[*cursor + 1] <= t {
            *cursor += 1;
        }
        let i = *cursor;
        let (t0, t1) = (self.t[i], self.t[i + 1]);
        let f = if t1 > t0 {
            ((t - t0) / (t1 - t0)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        g[i] + f * (g[i + 1] - g[i])
    }
}

/// The GNSS position noise measured on the fixes `(t, x, y)` (increasing
/// times), m: the MAD of the second differences of equally spaced fixes
/// (variance 6 sigma^2 for white noise), both axes pooled. `None` with
/// fewer than ten differences.
pub(crate) fn gnss_scatter_sigma(fixes: &[(f64, f64, f64)]) -> Option<f64> {
    let mut d = Vec::new();
    for w in fixes.windows(3) {
        let (h0, h1) = (w[1].0 - w[0].0, w[2].0 - w[1].0);
        if h0 <= 0.0 || h1 <= 0.0 || h0 > 1.5 || h1 > 1.5 || (h0 - h1).abs() > 0.25 * h0.max(h1) {
            continue;
        }
        d.push((w[2].1 - 2.0 * w[1].1 + w[0].1).abs());
        d.push((w[2].2 - 2.0 * w[1].2 + w[0].2).abs());
    }
    if d.len() < 10 {
        return None;
    }
    Some(1.4826 * stats::upper_median(&mut d)? / 6f64.sqrt())
}

/// The GNSS position noise measured on the fixes `(t, x, y)` (increasing
/// times) without the drive's dynamics, m: the MAD of the fourth
/// differences of five equally spaced fixes (variance 70 sigma^2 for white
/// noise; any cubic motion, so every constant jerk, cancels), both axes
/// pooled, with how many differences it rests on. `None` with fewer than
/// ten differences. Receivers filter their output, so this short-term
/// scatter is a lower bound of their error, never an overstatement.
pub(crate) fn gnss_scatter_sigma_robust(fixes: &[(f64, f64, f64)]) -> Option<(f64, usize)> {
    let mut d = Vec::new();
    for w in fixes.windows(5) {
        let h: Vec<f64> = w.windows(2).map(|p| p[1].0 - p[0].0).collect();
        let (lo, hi) = h
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
        if lo <= 0.0 || hi > 1.5 || hi - lo > 0.25 * hi {
            continue;
        }
        let diff4 = |k: fn(&(f64, f64, f64)) -> f64| {
            k(&w[0]) - 4.0 * k(&w[1]) + 6.0 * k(&w[2]) - 4.0 * k(&w[3]) + k(&w[4])
        };
        d.push(diff4(|f| f.1).abs());
        d.push(diff4(|f| f.2).abs());
    }
    if d.len() < 10 {
        return None;
    }
    let n = d.len();
    Some((1.4826 * stats::upper_median(&mut d)? / 70f64.sqrt(), n))
}

/// Median sample interval of increasing times, s.
pub fn median_interval(t: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = t
        .windows(2)
        .take(10_000)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    stats::upper_median(&mut d)
}

/// Mean gyro rate over the standstill intervals: (bias, standard error, seconds).
pub fn standstill_gyro_bias(p: &Series) -> Option<(f64, f64, f64)> {
    p.gyro.as_ref()?;
    let (mut sum_angle, mut sum_t) = (0.0, 0.0);
    let mut rates = Vec::new();
    for &(a, b) in &p.standstill {
        // Stay clear of the moments the car starts and stops.
        let (a, b) = (a + 0.3, b - 0.3);
        if b - a < 0.5 {
            continue;
        }
        if let Some(rate) = p.gyro_mean_rate(a, b) {
            let (ga, gb) = (0.0, rate * (b - a));
            sum_angle += gb - ga;
            sum_t += b - a;
            rates.push((gb - ga) / (b - a));
        }
    }
    if sum_t < 2.0 {
        return None;
    }
    let mean = sum_angle / sum_t;
    // Standard error from the spread of the intervals, with a floor for white noise.
    let spread = if rates.len() > 1 {
        let m = rates.iter().sum::<f64>() / rates.len() as f64;
        (rates.iter().map(|r| (r - m).powi(2)).sum::<f64>()
            / (rates.len() - 1) as f64
            / rates.len() as f64)
            .sqrt()
    } else {
        0.0
    };
    Some((mean, spread.max(2e-4 / sum_t.sqrt()), sum_t))
}
