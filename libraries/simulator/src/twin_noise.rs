//! The numbers a twin copies from a recorded drive: its sensors' rates, the
//! gyro's bias and noise and the accelerometers' noise at standstill, the
//! compass's noise, the GNSS outages and the wheels' distance over time.
//! Pure functions on a [`Drive`]; the GNSS noise against the smoothed track
//! is in [`super::twin`] (it needs the track).

use super::SimError;
use interfaces::drive::{Drive, WheelUnit};
pub use stats::stamps::{median_interval, stamp_jitter, stamp_jitter_rms};

/// Wheels slower than this count as standing, m/s.
pub const STANDSTILL_M_S: f64 = 0.05;
/// A standstill shorter than this does not count for the gyro, s.
const MIN_STANDSTILL_S: f64 = 2.0;
/// A GNSS gap longer than this many fix periods is an outage.
pub const GAP_PERIODS: f64 = 3.0;
/// Half-width of the window the wheel distance is smoothed and
/// differentiated over, s.
const SPEED_HALF_WINDOW_S: f64 = 0.1;

/// The wheels' distance over time: the mean of the rear wheels'
/// revolutions times the nominal circumference, smoothed over +-0.1 s and
/// never decreasing (the simulator does not reverse).
#[derive(Debug, Clone, PartialEq)]
pub struct Odometer {
    /// Times, s (the wheel samples').
    pub t_s: Vec<f64>,
    /// Distance since the first sample, m.
    pub s_m: Vec<f64>,
    /// Speed, m/s (the distance's central difference over +-0.1 s).
    pub v_m_s: Vec<f64>,
}

impl Odometer {
    /// The odometer of `drive`'s wheels (an error naming wheels.csv when
    /// the values cannot be turned into revolutions or are too few).
    pub fn from_drive(drive: &Drive) -> Result<Odometer, SimError> {
        let revs = drive
            .wheel_revolutions()
            .map_err(|e| SimError::InvalidConfig(format!("wheels.csv: {e}")))?;
        if revs.len() < 10 {
            return Err(SimError::InvalidConfig(format!(
                "wheels.csv: {} samples are too few for a twin",
                revs.len()
            )));
        }
        let c = drive.vehicle.nominal_circumference_m;
        let t: Vec<f64> = revs.iter().map(|r| r.t_s).collect();
        let raw: Vec<f64> = revs
            .iter()
            .map(|r| 0.5 * ((r.rl - revs[0].rl) + (r.rr - revs[0].rr)) * c)
            .collect();
        if raw.iter().chain(&t).any(|v| !v.is_finite()) {
            return Err(SimError::InvalidConfig(
                "wheels.csv: a value is not finite".into(),
            ));
        }
        let n = t.len();
        // Symmetric windows (in samples) within +-0.1 s, so that the mean
        // of a steady ramp is its centre value.
        let halves = symmetric_halves(&t, SPEED_HALF_WINDOW_S);
        let mut s_m = running_max(window_means(&raw, |i| (i - halves[i], i + halves[i])));
        let s0 = s_m[0];
        for s in &mut s_m {
            *s -= s0;
        }
        let v_m_s = (0..n)
            .map(|i| {
                let k = halves[i].max(1);
                let (a, b) = (i.saturating_sub(k), (i + k).min(n - 1));
                let span = t[b] - t[a];
                if span > 0.0 {
                    (s_m[b] - s_m[a]) / span
                } else {
                    0.0
                }
            })
            .collect();
        Ok(Odometer { t_s: t, s_m, v_m_s })
    }

    /// Distance at `t` (linear between samples, clamped at the ends).
    pub fn distance_at(&self, t: f64) -> f64 {
        interp(&self.t_s, &self.s_m, t)
    }

    /// Speed at `t` (linear between samples, clamped at the ends).
    pub fn speed_at(&self, t: f64) -> f64 {
        interp(&self.t_s, &self.v_m_s, t)
    }

    /// Whether the wheels stand at sample `i`.
    fn standing(&self, i: usize) -> bool {
        self.v_m_s.get(i).is_some_and(|v| *v < STANDSTILL_M_S)
    }

    /// The standstill stretches of at least `min_s` seconds, (start, end) s.
    pub fn standstills(&self, min_s: f64) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        let mut start: Option<usize> = None;
        for i in 0..=self.t_s.len() {
            let standing = i < self.t_s.len() && self.standing(i);
            match (standing, start) {
                (true, None) => start = Some(i),
                (false, Some(a)) => {
                    let (t0, t1) = (self.t_s[a], self.t_s[i - 1]);
                    if t1 - t0 >= min_s {
                        out.push((t0, t1));
                    }
                    start = None;
                }
                _ => {}
            }
        }
        out
    }
}

/// For each sample, the largest k such that samples i-k..=i+k lie within
/// +-`half` s of it (a hair of tolerance for rounded times).
/// The mean of `v` over each sample's window, `bounds(i)` = (first, last)
/// index, both included (a prefix sum: linear in the length).
pub(crate) fn window_means(v: &[f64], bounds: impl Fn(usize) -> (usize, usize)) -> Vec<f64> {
    let mut prefix = Vec::with_capacity(v.len() + 1);
    prefix.push(0.0);
    for x in v {
        let last = prefix.last().copied().unwrap_or(0.0);
        prefix.push(last + x);
    }
    (0..v.len())
        .map(|i| {
            let (a, b) = bounds(i);
            (prefix[b + 1] - prefix[a]) / (b + 1 - a) as f64
        })
        .collect()
}

/// `v` made non-decreasing: each value the largest so far.
pub(crate) fn running_max(mut v: Vec<f64>) -> Vec<f64> {
    let mut top = f64::NEG_INFINITY;
    for x in &mut v {
        top = top.max(*x);
        *x = top;
    }
    v
}

fn symmetric_halves(t: &[f64], half: f64) -> Vec<usize> {
    let n = t.len();
    let tol = half + 1e-6;
    let (mut a, mut b) = (0usize, 0usize);
    (0..n)
        .map(|i| {
            while t[a] < t[i] - tol {
                a += 1;
            }
            b = b.max(i);
            while b + 1 < n && t[b + 1] <= t[i] + tol {
                b += 1;
            }
            (i - a).min(b - i)
        })
        .collect()
}

/// Linear interpolation of `y(x)` at `x0` (`x` increasing; clamped).
pub(crate) fn interp(x: &[f64], y: &[f64], x0: f64) -> f64 {
    let n = x.len().min(y.len());
    if n == 0 {
        return 0.0;
    }
    if x0 <= x[0] {
        return y[0];
    }
    if x0 >= x[n - 1] {
        return y[n - 1];
    }
    let j = x[..n].partition_point(|v| *v <= x0).clamp(1, n - 1);
    let i = j - 1;
    let dx = x[j] - x[i];
    if dx <= 0.0 {
        return y[j];
    }
    y[i] + (x0 - x[i]) / dx * (y[j] - y[i])
}

/// The rate whose period is `interval` rounded to a whole number of
/// simulation steps `step_s` (at least one), Hz.
pub fn rate_on_step(interval: f64, step_s: f64) -> f64 {
    let steps = (interval / step_s).round().max(1.0);
    1.0 / (steps * step_s)
}

/// Mean and standard deviation.
fn mean_sd(v: &[f64]) -> Option<(f64, f64)> {
    if v.len() < 2 {
        return None;
    }
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
    Some((m, var.sqrt()))
}

/// What a drive's own samples say of its sensors.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveNumbers {
    /// Wheel rate, Hz (median interval, on the simulation's step).
    pub wheel_rate_hz: f64,
    /// Encoder ticks per revolution, when the wheels are `_ticks`.
    pub ticks_per_rev: Option<u32>,
    /// GNSS fix rate, Hz.
    pub gnss_rate_hz: f64,
    /// IMU rate, Hz, when the drive has an IMU.
    pub imu_rate_hz: Option<f64>,
    /// Compass rate, Hz, when the drive has heading.csv.
    pub heading_rate_hz: Option<f64>,
    /// Gyro bias at standstill, rad/s (`None`: no IMU or no standstill).
    pub gyro_bias_rad_s: Option<f64>,
    /// Gyro white noise at standstill (1-sigma per sample), rad/s.
    pub gyro_sigma_rad_s: Option<f64>,
    /// Accelerometer noise at standstill (ax, 1-sigma per sample), m/s^2.
    pub accel_sigma_m_s2: Option<f64>,
    /// Compass noise (1-sigma), degrees, against its own +-5-sample mean.
    pub heading_sigma_deg: Option<f64>,
    /// Seconds of standstill the gyro numbers come from.
    pub standstill_s: f64,
    /// GNSS outages: gaps between fixes longer than
    /// [`GAP_PERIODS`] fix periods, and the stretches before the first and
    /// after the last fix (drive clock), s.
    pub gnss_gaps: Vec<(f64, f64)>,
    /// The rear wheels' speed noise (rl, rr), revolutions per second, where
    /// the drive's wheels are speeds (rad/s or m/s; counted ticks and
    /// revolutions have their own quantisation, which the twin copies):
    /// [`wheel_speed_noise`].
    pub wheel_speed_sigma_rev_s: Option<[f64; 2]>,
}

/// The numbers of `drive` for a simulation at step `step_s`; an error
/// naming the file when the drive has no GNSS fixes (a twin follows them).
pub fn drive_numbers(
    drive: &Drive,
    odometer: &Odometer,
    step_s: f64,
) -> Result<DriveNumbers, SimError> {
    let gnss = drive
        .gnss
        .as_deref()
        .filter(|g| g.len() >= 10)
        .ok_or_else(|| {
            SimError::InvalidConfig(
                "gnss.csv: a twin follows the drive's GNSS track, and the drive has fewer than 10 fixes"
                    .into(),
            )
        })?;
    let wheel_t: Vec<f64> = drive.wheels.samples.iter().map(|w| w.t_s).collect();
    let wheel_dt = median_interval(&wheel_t)
        .ok_or_else(|| SimError::InvalidConfig("wheels.csv: fewer than two samples".into()))?;
    let gnss_t: Vec<f64> = gnss.iter().map(|g| g.t_s).collect();
    let gnss_dt = median_interval(&gnss_t)
        .ok_or_else(|| SimError::InvalidConfig("gnss.csv: fewer than two fixes".into()))?;
    let ticks_per_rev = if drive.wheels.units.rl == WheelUnit::Ticks {
        drive
            .vehicle
            .ticks_per_rev
            .map(|t| t.round().clamp(1.0, 1e6) as u32)
    } else {
        None
    };

    // GNSS outages, on the drive's clock.
    let mut gnss_gaps = Vec::new();
    let limit = GAP_PERIODS * gnss_dt;
    let (w0, w1) = (
        wheel_t.first().copied().unwrap_or(0.0),
        wheel_t.last().copied().unwrap_or(0.0),
    );
    if let (Some(first), Some(last)) = (gnss_t.first(), gnss_t.last()) {
        if first - w0 > limit {
            gnss_gaps.push((w0, *first));
        }
        for w in gnss_t.windows(2) {
            if w[1] - w[0] > limit {
                gnss_gaps.push((w[0], w[1]));
            }
        }
        if w1 - last > limit {
            gnss_gaps.push((*last, w1));
        }
    }

    // The gyro and accelerometers at standstill.
    let stands = odometer.standstills(MIN_STANDSTILL_S);
    // Leave the ends of each standstill out (the car settling).
    let inside = |t: f64| stands.iter().any(|&(a, b)| t >= a + 0.5 && t <= b - 0.5);
    let standstill_s = stands.iter().map(|(a, b)| (b - a - 1.0).max(0.0)).sum();
    let (mut imu_rate_hz, mut gyro, mut accel) = (None, None, None);
    if let Some(imu) = drive.imu.as_deref() {
        let t: Vec<f64> = imu.iter().map(|s| s.t_s).collect();
        imu_rate_hz = median_interval(&t).map(|d| rate_on_step(d, step_s));
        let gz: Vec<f64> = imu
            .iter()
            .filter(|s| inside(s.t_s))
            .map(|s| s.gz_rad_s)
            .collect();
        gyro = mean_sd(&gz).filter(|_| gz.len() >= 20);
        let ax: Vec<f64> = imu
            .iter()
            .filter(|s| inside(s.t_s))
            .filter_map(|s| s.ax_m_s2)
            .collect();
        accel = mean_sd(&ax).filter(|_| ax.len() >= 20).map(|(_, sd)| sd);
    }
    let (mut heading_rate_hz, mut heading_sigma_deg) = (None, None);
    if let Some(h) = drive.heading.as_deref() {
        let t: Vec<f64> = h.iter().map(|s| s.t_s).collect();
        heading_rate_hz = median_interval(&t).map(|d| rate_on_step(d, step_s));
        heading_sigma_deg = compass_sigma(&h.iter().map(|s| s.yaw_rad).collect::<Vec<_>>());
    }
    Ok(DriveNumbers {
        wheel_rate_hz: rate_on_step(wheel_dt, step_s),
        ticks_per_rev,
        gnss_rate_hz: rate_on_step(gnss_dt, step_s),
        imu_rate_hz,
        heading_rate_hz,
        gyro_bias_rad_s: gyro.map(|g| g.0),
        gyro_sigma_rad_s: gyro.map(|g| g.1),
        accel_sigma_m_s2: accel,
        heading_sigma_deg,
        standstill_s,
        gnss_gaps,
        wheel_speed_sigma_rev_s: wheel_speed_noise(drive),
    })
}

/// Rows of the wheel speed needed for its noise.
const MIN_NOISE_ROWS: usize = 200;

/// The rear wheels' white speed noise, revolutions per second, where the
/// drive's wheels are speeds: the robust spread of the speed's second
/// difference over 100 Hz-ish samples while moving (above 1 rev/s), over
/// the square root of 6 (what white noise gives; the car's own
/// acceleration changes hardly show in a second difference). `None` for
/// ticks and revolutions, or too few moving rows.
pub fn wheel_speed_noise(drive: &Drive) -> Option<[f64; 2]> {
    let to_rev_s = match drive.wheels.units.rl {
        WheelUnit::RadS => 1.0 / std::f64::consts::TAU,
        WheelUnit::MS => 1.0 / drive.vehicle.nominal_circumference_m,
        WheelUnit::Rev | WheelUnit::Ticks => return None,
    };
    if drive.wheels.units.rr != drive.wheels.units.rl || !to_rev_s.is_finite() {
        return None;
    }
    let w = &drive.wheels.samples;
    let sigma = |f: &dyn Fn(&interfaces::drive::WheelSample) -> f64| -> Option<f64> {
        let mut d: Vec<f64> = w
            .windows(3)
            .filter(|s| s.iter().all(|x| f(x) * to_rev_s > 1.0))
            .map(|s| (f(&s[2]) - 2.0 * f(&s[1]) + f(&s[0])) * to_rev_s)
            .collect();
        if d.len() < MIN_NOISE_ROWS {
            return None;
        }
        d.sort_by(f64::total_cmp);
        let med = d[d.len() / 2];
        let mut dev: Vec<f64> = d.iter().map(|x| (x - med).abs()).collect();
        dev.sort_by(f64::total_cmp);
        Some(1.4826 * dev[dev.len() / 2] / 6f64.sqrt())
    };
    Some([sigma(&|s| s.rl)?, sigma(&|s| s.rr)?])
}

/// The compass's white noise: the robust spread of each yaw about the
/// circular mean of its +-5 neighbours, degrees.
fn compass_sigma(yaw: &[f64]) -> Option<f64> {
    const K: usize = 5;
    if yaw.len() < 2 * K + 1 {
        return None;
    }
    let mut res: Vec<f64> = (K..yaw.len() - K)
        .map(|i| {
            let (s, c) = yaw[i - K..=i + K]
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != K)
                .fold((0.0, 0.0), |(s, c), (_, y)| (s + y.sin(), c + y.cos()));
            stats::wrap_angle(yaw[i] - s.atan2(c)).abs()
        })
        .collect();
    res.sort_by(f64::total_cmp);
    let mad = res[res.len() / 2];
    // The median absolute deviation of a normal is 0.6745 sigma; the
    // neighbours' mean adds 1/(2K) of the variance.
    let sigma = mad / 0.6745 / (1.0 + 1.0 / (2 * K) as f64).sqrt();
    Some(sigma.to_degrees())
}

/// Put a recording's stamp jitter (`stamp_jitter`) on the twin's fixes: a
/// fix within half an interval of a recorded epoch takes that epoch's
/// jitter, as long as the stamps stay increasing. Returns how many fixes
/// were restamped.
pub fn restamp(fixes: &mut [interfaces::drive::GnssSample], jitter: &[(f64, f64)]) -> usize {
    let Some(dt) = median_interval(&jitter.iter().map(|j| j.0).collect::<Vec<_>>()) else {
        return 0;
    };
    let mut moved = 0;
    let mut last = f64::NEG_INFINITY;
    for i in 0..fixes.len() {
        let t = fixes[i].t_s;
        let k = jitter.partition_point(|j| j.0 < t);
        let nearest = [k.checked_sub(1), Some(k)]
            .into_iter()
            .flatten()
            .filter_map(|k| jitter.get(k))
            .min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs()));
        if let Some(&(epoch, j)) = nearest {
            let next = fixes.get(i + 1).map_or(f64::INFINITY, |f| f.t_s);
            let s = t + j;
            if (epoch - t).abs() <= 0.5 * dt + 1e-9 && s > last && s < next {
                fixes[i].t_s = s;
                moved += 1;
            }
        }
        last = fixes[i].t_s;
    }
    moved
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::drive::GnssSample;

    /// Wheels reported as speeds with white noise: the noise comes back
    /// from the moving rows; counted revolutions have none to copy.
    #[test]
    fn a_speed_wheels_white_noise_is_measured_while_moving() {
        use rand::{Rng, SeedableRng};
        let mut c = crate::SimConfig::new(crate::Scenario::Mixed, 3);
        c.duration_s = Some(180.0);
        c.effects = crate::EffectSettings::none();
        c.sensors.wheels.ticks_per_rev = None;
        let mut d = crate::simulate(&c).unwrap();
        assert!(
            wheel_speed_noise(&d).is_none(),
            "revolutions have no speed noise"
        );
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let sigma = 0.05; // rad/s
        let revs: Vec<(f64, f64, f64)> = d
            .wheels
            .samples
            .iter()
            .map(|w| (w.t_s, w.rl, w.rr))
            .collect();
        for (k, w) in d.wheels.samples.iter_mut().enumerate() {
            let (a, b) = (revs[k.saturating_sub(1)], revs[(k + 1).min(revs.len() - 1)]);
            let dt = (b.0 - a.0).max(1e-9);
            let n: [f64; 2] = [
                rng.sample(rand_distr::StandardNormal),
                rng.sample(rand_distr::StandardNormal),
            ];
            w.rl = (b.1 - a.1) / dt * std::f64::consts::TAU + sigma * n[0];
            w.rr = (b.2 - a.2) / dt * std::f64::consts::TAU + sigma * n[1];
        }
        d.wheels.units.rl = WheelUnit::RadS;
        d.wheels.units.rr = WheelUnit::RadS;
        let [l, r] = wheel_speed_noise(&d).expect("speeds with noise");
        for x in [l, r] {
            let rad = x * std::f64::consts::TAU;
            assert!(
                (rad / sigma - 1.0).abs() < 0.15,
                "{rad} rad/s against {sigma}"
            );
        }
    }

    /// A twin's regular fixes take the jitter of the recording's epoch
    /// they match (a 5 Hz receiver whose clock runs 0.3 s late and drifts,
    /// with a gap); the fixes in the gap keep their stamps.
    #[test]
    fn a_twins_regular_fixes_take_the_jitter_of_the_epoch_they_match() {
        let jit = |k: usize| 0.01 * (((k * 7919) % 11) as f64 / 5.0 - 1.0);
        let stamps: Vec<f64> = (0..600)
            .filter(|k| !(200..215).contains(k))
            .map(|k| 0.3 + k as f64 * 0.2 * (1.0 + 2e-5) + jit(k))
            .collect();
        let j = stamp_jitter(&stamps);
        // The twin's fixes on the regular epochs (the recording's clock).
        let mut fixes: Vec<GnssSample> = (0..600)
            .map(|k| GnssSample {
                t_s: 0.3 + k as f64 * 0.2 * (1.0 + 2e-5),
                x_m: 0.0,
                y_m: 0.0,
                sigma_m: None,
            })
            .collect();
        let moved = restamp(&mut fixes, &j);
        assert_eq!(
            moved, 585,
            "the fixes in the recording's gap keep their stamps"
        );
        assert!(fixes.windows(2).all(|w| w[1].t_s > w[0].t_s));
        let d = fixes[100].t_s - (0.3 + 100.0 * 0.2 * (1.0 + 2e-5));
        assert!((d - jit(100)).abs() < 3e-3, "{d} against {}", jit(100));
    }
}
