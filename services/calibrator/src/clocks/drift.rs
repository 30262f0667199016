//! Slow clock drift of the streams against the wheels' clock.
//!
//! A logger whose oscillator is off by 100 ppm gains 0.36 s an hour against
//! the others: one constant offset ([`crate::clocks`]) then fits no part of
//! a long drive well. Here every stream's offset is estimated again in
//! [`MIN_WINDOWS`]..=[`MAX_WINDOWS`] windows of at least [`MIN_WINDOW_S`]
//! along the drive with [`clocks::fit_lag`] (the same signals as the whole
//! drive's offset: the GNSS speed, here from a light smoother of the fixes,
//! and the IMU yaw rate), and a straight line `offset(t) = offset0 + drift
//! (t - t_ref)` is fitted through the window offsets by weighted least
//! squares with their sigmas. The drift's sigma is the fit's, inflated by
//! the chi-square per degree of freedom where that exceeds 1 (windows that
//! scatter more than their sigmas say).
//!
//! A drift counts (and is applied by the calibration) only where this drive
//! shows it: beyond [`SIGNIFICANCE`] sigma, and moving the offset across
//! the drive by more than [`SIGNIFICANCE`] sigma of the offset itself. Both
//! thresholds come from the sigmas measured on the drive; nothing is tuned
//! to a simulator. Otherwise the drift is reported as not determined or not
//! significant, with the smallest drift the drive could have shown.
//!
//! Pure: arrays in, estimates out.

use crate::clocks::offsets::{
    self as clocks, ClockDrift, ImuRow, OffsetStatus, Sampled, StreamOffset, WheelTrack,
    WindowOffset, CLOCK_SEARCH_S,
};

/// Shortest window, s: enough speed changes and turns for an offset.
pub const MIN_WINDOW_S: f64 = 60.0;
/// Most windows (longer drives get longer windows).
pub const MAX_WINDOWS: usize = 8;
/// Fewest windows with a determined offset for a drift.
pub const MIN_WINDOWS: usize = 3;
/// A drift is significant beyond this many sigma.
pub const SIGNIFICANCE: f64 = 3.0;
/// Half-width of a window's offset search about the whole drive's offset,
/// s: a drift moves a window's offset by less than this from the whole
/// drive's unless it exceeds 1 s over half the drive (140 ppm over a 4 h
/// drive, far beyond a crystal's); beyond it the window says so.
const WINDOW_SEARCH_S: f64 = 1.0;
/// Half-width of the wheel speed's window compared with the GNSS speed, s.
const SPEED_HALF_WINDOW_S: f64 = 0.25;
/// Process noise (white acceleration) of the GNSS velocity smoother, m^2/s^3.
const SMOOTHER_Q: f64 = 4.0;
/// A GNSS gap longer than this restarts the smoother, s.
const SMOOTHER_GAP_S: f64 = 2.0;
/// GNSS speeds below this are not compared (the course is noise), m/s.
const MIN_GNSS_SPEED: f64 = 1.0;

/// The windows over the wheels' span `[t0, t1]`: as many as fit
/// [`MIN_WINDOW_S`], at most [`MAX_WINDOWS`], of equal length.
pub fn windows(t0: f64, t1: f64) -> Vec<(f64, f64)> {
    let len = t1 - t0;
    if len.is_nan() || len <= 0.0 {
        return Vec::new();
    }
    let n = ((len / MIN_WINDOW_S).floor() as usize).min(MAX_WINDOWS);
    (0..n)
        .map(|k| {
            (
                t0 + len * k as f64 / n as f64,
                t0 + len * (k + 1) as f64 / n as f64,
            )
        })
        .collect()
}

/// A weighted straight line through window offsets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineFit {
    /// The offset at `t_ref`, s.
    pub offset_s: f64,
    /// Its 1-sigma (inflated like the drift's), s.
    pub sigma_offset_s: f64,
    /// The slope, s per s.
    pub drift: f64,
    /// Its 1-sigma, inflated by `chi2_dof` where that exceeds 1.
    pub sigma_drift: f64,
    /// Chi-square per degree of freedom.
    pub chi2_dof: f64,
}

/// Weighted least squares of `offset = a + b (t - t_ref)` with weights
/// `1 / sigma^2`; `None` with fewer than three windows or no spread in time.
pub fn fit_line(w: &[WindowOffset], t_ref: f64) -> Option<LineFit> {
    if w.len() < 3 {
        return None;
    }
    let (mut s, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for o in w {
        if !(o.sigma_s > 0.0 && o.offset_s.is_finite() && o.t_s.is_finite()) {
            return None;
        }
        let wt = 1.0 / (o.sigma_s * o.sigma_s);
        let x = o.t_s - t_ref;
        s += wt;
        sx += wt * x;
        sy += wt * o.offset_s;
        sxx += wt * x * x;
        sxy += wt * x * o.offset_s;
    }
    let d = s * sxx - sx * sx;
    if d.is_nan() || d <= 0.0 {
        return None;
    }
    let b = (s * sxy - sx * sy) / d;
    let a = (sxx * sy - sx * sxy) / d;
    let chi2: f64 = w
        .iter()
        .map(|o| ((o.offset_s - a - b * (o.t_s - t_ref)) / o.sigma_s).powi(2))
        .sum();
    let chi2_dof = chi2 / (w.len() - 2) as f64;
    let inflate = chi2_dof.max(1.0);
    Some(LineFit {
        offset_s: a,
        sigma_offset_s: (inflate * sxx / d).sqrt(),
        drift: b,
        sigma_drift: (inflate * s / d).sqrt(),
        chi2_dof,
    })
}

/// The smallest drift a drive of `span_s` can show when the whole drive
/// gives the offset to `sigma_offset_s`: the information spread evenly over
/// the span gives a slope sigma of `sqrt(12) sigma / span`; 3 of those, ppm.
pub fn detectable_ppm(sigma_offset_s: f64, span_s: f64) -> Option<f64> {
    (sigma_offset_s > 0.0 && span_s > 0.0)
        .then(|| SIGNIFICANCE * 12f64.sqrt() * sigma_offset_s / span_s * 1e6)
}

/// The drift from the window offsets (`Err`: why a window does not
/// determine its offset) over the wheels' span `(t0, t1)`, taken about
/// `t_ref`. `whole` is the whole drive's offset (its sigma says what a
/// short drive could have shown).
pub fn judge(
    tries: Vec<Result<WindowOffset, String>>,
    span: (f64, f64),
    t_ref: f64,
    whole: &StreamOffset,
) -> ClockDrift {
    let span_s = span.1 - span.0;
    let minutes = span_s / 60.0;
    let mut d = ClockDrift {
        ref_t_s: Some(t_ref),
        detectable_ppm: whole.sigma_s.and_then(|s| detectable_ppm(s, span_s)),
        ..ClockDrift::default()
    };
    let below = |p: Option<f64>| {
        p.map_or(String::new(), |p| {
            format!("; a drift below {p:.0} ppm cannot be seen")
        })
    };
    if tries.len() < MIN_WINDOWS {
        d.status = OffsetStatus::NotDetermined;
        d.reason = Some(format!(
            "the drive is {minutes:.1} min long: a drift needs at least {MIN_WINDOWS} windows of {MIN_WINDOW_S:.0} s{}",
            below(d.detectable_ppm)
        ));
        return d;
    }
    let n = tries.len();
    let mut why = Vec::new();
    for (k, t) in tries.into_iter().enumerate() {
        match t {
            Ok(w) => d.windows.push(w),
            Err(e) => why.push(format!("window {}: {e}", k + 1)),
        }
    }
    let Some(fit) = fit_line(&d.windows, t_ref) else {
        d.status = OffsetStatus::NotDetermined;
        d.reason = Some(format!(
            "only {} of {n} windows determine the offset ({}){}",
            d.windows.len(),
            why.join("; "),
            below(d.detectable_ppm)
        ));
        return d;
    };
    let (ppm, sigma_ppm) = (fit.drift * 1e6, fit.sigma_drift * 1e6);
    d.status = OffsetStatus::Determined;
    d.drift_ppm = Some(ppm);
    d.sigma_ppm = Some(sigma_ppm);
    d.chi2_dof = Some(fit.chi2_dof);
    d.detectable_ppm = Some(SIGNIFICANCE * sigma_ppm);
    // The drift moves the offset across the drive by this much.
    let moved_s = (fit.drift * span_s).abs();
    d.reason = if ppm.abs() <= SIGNIFICANCE * sigma_ppm {
        Some(format!(
            "not significant: {ppm:+.0} +- {sigma_ppm:.0} ppm from {} windows; the drive is {minutes:.1} min long: a drift below {:.0} ppm cannot be seen",
            d.windows.len(),
            SIGNIFICANCE * sigma_ppm
        ))
    } else if moved_s <= SIGNIFICANCE * fit.sigma_offset_s {
        Some(format!(
            "not significant: {ppm:+.0} +- {sigma_ppm:.0} ppm moves the offset by {:.0} ms over the {minutes:.1} min drive, within 3 sigma of the offset ({:.0} ms)",
            1000.0 * moved_s,
            3000.0 * fit.sigma_offset_s
        ))
    } else {
        None
    };
    d
}

/// Whether a determined drift is significant (see [`judge`]).
pub fn significant(d: &ClockDrift) -> bool {
    d.status == OffsetStatus::Determined && d.reason.is_none() && d.drift_ppm.is_some()
}

/// Per-axis constant-velocity Rauch-Tung-Striebel smoother of positions
/// `p` at times `t` (one piece, increasing times): smoothed velocities.
fn smooth_velocity(t: &[f64], p: &[f64], r: f64, q: f64) -> Vec<f64> {
    let n = t.len();
    let mut xf = Vec::with_capacity(n); // filtered [pos, vel]
    let mut pf = Vec::with_capacity(n); // filtered cov [p00, p01, p11]
    let mut xp = Vec::with_capacity(n); // predicted
    let mut pp = Vec::with_capacity(n);
    let (mut x, mut c) = ([p[0], 0.0], [r, 0.0, 100.0]);
    for k in 0..n {
        if k > 0 {
            let h = t[k] - t[k - 1];
            x = [x[0] + h * x[1], x[1]];
            c = [
                c[0] + 2.0 * h * c[1] + h * h * c[2] + q * h * h * h / 3.0,
                c[1] + h * c[2] + q * h * h / 2.0,
                c[2] + q * h,
            ];
        }
        xp.push(x);
        pp.push(c);
        let s = c[0] + r;
        let (k0, k1) = (c[0] / s, c[1] / s);
        let e = p[k] - x[0];
        x = [x[0] + k0 * e, x[1] + k1 * e];
        c = [(1.0 - k0) * c[0], (1.0 - k0) * c[1], c[2] - k1 * c[1]];
        xf.push(x);
        pf.push(c);
    }
    let mut v = vec![0.0; n];
    let mut xs = xf[n - 1];
    v[n - 1] = xs[1];
    for k in (0..n - 1).rev() {
        let h = t[k + 1] - t[k];
        let (f, pk, pn) = (pf[k], pp[k + 1], xp[k + 1]);
        // G = Pf F^T Pp^-1 (2x2).
        let fp = [f[0] + h * f[1], f[1], f[1] + h * f[2], f[2]]; // Pf F^T: rows [a b; c d]
        let det = pk[0] * pk[2] - pk[1] * pk[1];
        if det.is_nan() || det <= 0.0 {
            v[k] = xf[k][1];
            xs = xf[k];
            continue;
        }
        let inv = [pk[2] / det, -pk[1] / det, pk[0] / det];
        let g = [
            fp[0] * inv[0] + fp[1] * inv[1],
            fp[0] * inv[1] + fp[1] * inv[2],
            fp[2] * inv[0] + fp[3] * inv[1],
            fp[2] * inv[1] + fp[3] * inv[2],
        ];
        let dx = [xs[0] - pn[0], xs[1] - pn[1]];
        let x_new = [
            xf[k][0] + g[0] * dx[0] + g[1] * dx[1],
            xf[k][1] + g[2] * dx[0] + g[3] * dx[1],
        ];
        // Only the mean is needed (no smoothed covariance).
        xs = x_new;
        v[k] = x_new[1];
    }
    v
}

/// The GNSS motion along the drive from a constant-velocity smoother of
/// the fixes `(t, x, y)` (increasing times) with the position noise
/// `sigma_m` (measured from the fixes when `None`): the speeds, m/s, where
/// faster than 1 m/s, and the course rates, rad/s, where faster than 2 m/s.
pub fn gnss_motion(fixes: &[(f64, f64, f64)], sigma_m: Option<f64>) -> GnssMotion {
    let mut out = GnssMotion::default();
    let measured = crate::series::gnss_scatter_sigma(fixes);
    let Some(sigma) = measured.or(sigma_m).map(|s| s.max(0.005)) else {
        return out;
    };
    let r = sigma * sigma;
    let mut start = 0;
    for k in 1..=fixes.len() {
        let end_piece = k == fixes.len() || fixes[k].0 - fixes[k - 1].0 > SMOOTHER_GAP_S;
        if !end_piece {
            continue;
        }
        let piece = &fixes[start..k];
        start = k;
        if piece.len() < 5 {
            continue;
        }
        let t: Vec<f64> = piece.iter().map(|f| f.0).collect();
        let x: Vec<f64> = piece.iter().map(|f| f.1).collect();
        let y: Vec<f64> = piece.iter().map(|f| f.2).collect();
        let vx = smooth_velocity(&t, &x, r, SMOOTHER_Q);
        let vy = smooth_velocity(&t, &y, r, SMOOTHER_Q);
        let speed = |i: usize| vx[i].hypot(vy[i]);
        for i in 0..t.len() {
            let v = speed(i);
            if v > MIN_GNSS_SPEED && v.is_finite() {
                out.speeds.push((t[i], v));
            }
            if i > 0 && i + 1 < t.len() && speed(i - 1) > 2.0 && speed(i + 1) > 2.0 {
                let d = vy[i + 1].atan2(vx[i + 1]) - vy[i - 1].atan2(vx[i - 1]);
                let d = (d + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI;
                let rate = d / (t[i + 1] - t[i - 1]);
                if rate.is_finite() {
                    out.course_rates.push((t[i], rate));
                }
            }
        }
    }
    out
}

/// What [`gnss_motion`] finds.
#[derive(Debug, Clone, Default)]
pub struct GnssMotion {
    /// `(t, speed)`, m/s.
    pub speeds: Vec<(f64, f64)>,
    /// `(t, course rate)`, rad/s.
    pub course_rates: Vec<(f64, f64)>,
}

/// The unsigned wheel speed over +-0.25 s at every wheel time, m/s.
pub fn wheel_speed(w: &WheelTrack<'_>) -> Vec<f32> {
    let n = w.t.len().min(w.dn_rl.len()).min(w.dn_rr.len());
    let inc: Vec<f64> = (0..n)
        .map(|k| 0.5 * (w.dn_rl[k] + w.dn_rr[k]) * w.circumference_m)
        .collect();
    clocks::windowed_rate(&w.t[..n], &inc, SPEED_HALF_WINDOW_S)
        .into_iter()
        .map(f32::abs)
        .collect()
}

/// Observations `(t, y)` in `[a, b)`, their times moved by `-centre_s`.
fn in_window<T: Copy>(obs: &[(f64, T)], a: f64, b: f64, centre_s: f64) -> Vec<(f64, T)> {
    let i0 = obs.partition_point(|o| o.0 < a);
    let i1 = obs.partition_point(|o| o.0 < b);
    obs[i0..i1]
        .iter()
        .map(|&(t, y)| (t - centre_s, y))
        .collect()
}

/// The GNSS's offset against the wheels over the whole drive and in every
/// window of `spans`: the speed against the wheel speed, else the course
/// rate against the wheels' yaw rate; window searches are centred on the
/// whole drive's offset.
pub fn gnss_windows(
    wheels: &WheelTrack<'_>,
    motion: &GnssMotion,
    spans: &[(f64, f64)],
) -> (StreamOffset, Vec<Result<WindowOffset, String>>) {
    let v = wheel_speed(wheels);
    let n = v.len();
    let t = &wheels.t[..n];
    let yaw_inc: Vec<f64> = (0..n)
        .map(|k| (wheels.dn_rr[k] - wheels.dn_rl[k]) * wheels.circumference_m / wheels.track_m)
        .collect();
    let yaw = clocks::windowed_rate(t, &yaw_inc, SPEED_HALF_WINDOW_S);
    let (xs, xy) = (Sampled { t, v: &v }, Sampled { t, v: &yaw });
    let pad = 2.0 * SPEED_HALF_WINDOW_S;
    let needs = "speed changes (accelerating and braking) or turns with GNSS";
    let whole = clocks::first_determined(
        lazy_fits(
            &motion.speeds,
            &motion.course_rates,
            (&xs, &xy),
            pad,
            CLOCK_SEARCH_S,
        ),
        CLOCK_SEARCH_S,
        needs,
    );
    let centre = whole.offset_s.unwrap_or(0.0);
    let tries = spans
        .iter()
        .map(|&(a, b)| {
            // Observation times are the stream's: the window on the wheels'
            // clock sits `centre` later on the GNSS's.
            let s = in_window(&motion.speeds, a + centre, b + centre, centre);
            let r = in_window(&motion.course_rates, a + centre, b + centre, centre);
            let fits = lazy_fits(&s, &r, (&xs, &xy), pad, WINDOW_SEARCH_S);
            let o = clocks::first_determined(fits, WINDOW_SEARCH_S, needs);
            match (o.offset_s, o.sigma_s) {
                (Some(off), Some(sigma)) => Ok(WindowOffset {
                    t_s: 0.5 * (a + b),
                    offset_s: centre + off,
                    sigma_s: sigma,
                }),
                _ => Err(o.reason.unwrap_or_else(|| "not determined".to_string())),
            }
        })
        .collect();
    (whole, tries)
}

/// The GNSS offset's tries, lazily: the speed against the wheel speed,
/// then (only where that does not determine it) the course rate against
/// the wheels' yaw rate.
fn lazy_fits<'a>(
    speeds: &'a [(f64, f64)],
    rates: &'a [(f64, f64)],
    wheels: (&'a Sampled<'a>, &'a Sampled<'a>),
    pad: f64,
    search_s: f64,
) -> impl Iterator<Item = (&'static str, Result<clocks::LagFit, clocks::LagFailure>)> + 'a {
    [("speed", false), ("course rate", true)]
        .into_iter()
        .map(move |(name, by_course)| {
            let fit = if by_course {
                clocks::fit_lag(rates, wheels.1, search_s, pad, true)
            } else {
                clocks::fit_lag(speeds, wheels.0, search_s, pad, false)
            };
            (name, fit)
        })
}

/// The IMU's offset in every window of `spans` ([`clocks::imu_offset`] on
/// the IMU rows of the window), centred on the whole drive's `centre_s`.
/// `imu`: rows with finite times, in time order.
pub fn imu_windows(
    wheels: &WheelTrack<'_>,
    imu: &[ImuRow],
    spans: &[(f64, f64)],
    centre_s: f64,
) -> Vec<Result<WindowOffset, String>> {
    spans
        .iter()
        .map(|&(a, b)| {
            let i0 = imu.partition_point(|r| r.0 < a + centre_s);
            let i1 = imu.partition_point(|r| r.0 < b + centre_s);
            let rows: Vec<ImuRow> = imu[i0..i1]
                .iter()
                .map(|r| (r.0 - centre_s, r.1, r.2))
                .collect();
            let o = clocks::imu_offset(wheels, &rows, WINDOW_SEARCH_S);
            match (o.status, o.offset_s, o.sigma_s) {
                (OffsetStatus::Determined, Some(off), Some(s)) => Ok(WindowOffset {
                    t_s: 0.5 * (a + b),
                    offset_s: centre_s + off,
                    sigma_s: s,
                }),
                _ => Err(o.reason.unwrap_or_else(|| "not determined".to_string())),
            }
        })
        .collect()
}

/// Put a stream's stamp `t` on a clock without the drift `rate` (s per s)
/// about `ref_t_s`: `ref_t_s + (t - ref_t_s) / (1 + rate)`.
pub fn undrift(t: f64, rate: f64, ref_t_s: f64) -> f64 {
    ref_t_s + (t - ref_t_s) / (1.0 + rate)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_through_window_offsets_finds_the_slope_and_its_sigma() {
        let w: Vec<WindowOffset> = (0..8)
            .map(|k| {
                let t = 100.0 + 200.0 * k as f64;
                // 150 ppm, +-5 ms alternating scatter.
                let e = if k % 2 == 0 { 0.005 } else { -0.005 };
                WindowOffset {
                    t_s: t,
                    offset_s: 0.3 + 150e-6 * (t - 800.0) + e,
                    sigma_s: 0.005,
                }
            })
            .collect();
        let f = fit_line(&w, 800.0).unwrap();
        assert!((f.drift - 150e-6).abs() < 3.0 * f.sigma_drift, "{f:?}");
        assert!((f.offset_s - 0.3).abs() < 0.005, "{f:?}");
        assert!(f.sigma_drift > 0.0 && f.sigma_drift < 20e-6, "{f:?}");
        // Ten times the scatter with the same sigmas: chi2 inflates the sigma.
        let wide: Vec<WindowOffset> = w
            .iter()
            .map(|o| WindowOffset {
                offset_s: 0.3
                    + 150e-6 * (o.t_s - 800.0)
                    + 10.0 * (o.offset_s - 0.3 - 150e-6 * (o.t_s - 800.0)),
                ..*o
            })
            .collect();
        let g = fit_line(&wide, 800.0).unwrap();
        assert!(
            g.chi2_dof > 10.0 && g.sigma_drift > 3.0 * f.sigma_drift,
            "{g:?}"
        );
    }

    #[test]
    fn a_short_drive_says_which_drift_it_cannot_see() {
        let whole = StreamOffset {
            sigma_s: Some(0.01),
            ..StreamOffset::default()
        };
        let d = judge(vec![Err("x".into()); 2], (0.0, 240.0), 120.0, &whole);
        assert_eq!(d.status, OffsetStatus::NotDetermined);
        let r = d.reason.unwrap();
        assert!(r.contains("4.0 min") && r.contains("cannot be seen"), "{r}");
        // 3 sqrt(12) 0.01 / 240 s = 433 ppm.
        assert!((d.detectable_ppm.unwrap() - 433.0).abs() < 1.0);
    }

    #[test]
    fn the_smoother_gives_the_speed_of_a_noisy_track() {
        let fixes: Vec<(f64, f64, f64)> = (0..600)
            .map(|k| {
                let t = 0.1 * k as f64;
                // White-ish noise of +-2 cm.
                let n = 0.04 * (((k as f64 * 12.9898).sin() * 43_758.545).fract() - 0.5);
                (t, 10.0 * t + n, 5.0 - n)
            })
            .collect();
        let s = gnss_motion(&fixes, None).speeds;
        // Unbiased: the mean over the middle is the speed.
        let mid = s[100..500].iter().map(|v| v.1).sum::<f64>() / 400.0;
        assert!((mid - 10.0).abs() < 0.02, "{mid}");
        assert!(s.iter().all(|v| (v.1 - 10.0).abs() < 0.5), "{s:?}");
    }
}
