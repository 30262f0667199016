//! The drive seen at the GNSS fixes: for every fix with a neighbour on each
//! side, what GNSS says (speed, course) and what the calibrated 2W model says
//! over the same interval (speed, yaw rate, heading), with the signals the
//! effect fingerprints read (accelerations, grade, gyro, heading sensor).
//!
//! Differences are taken over the same interval for both, from the fix
//! before to the fix after, so that the two sides see the same smoothing.

use interfaces::drive::{Drive, GnssSample, ImuSample, WheelRevs};
use vehicle_model::effects::lateral_acceleration_from_wheels;
use vehicle_model::two_wheel::wrap_angle;

/// Gravity, m/s^2.
const G: f64 = 9.80665;

/// One epoch: a GNSS fix and the model over the interval around it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Epoch {
    /// Time of the fix, s.
    pub t_s: f64,
    /// Time since the first wheel sample, s.
    pub t_rel_s: f64,
    /// GNSS position, m (local ENU).
    pub x_m: f64,
    /// GNSS position, m.
    pub y_m: f64,
    /// GNSS speed over the interval, m/s.
    pub v_gnss: f64,
    /// GNSS course over the interval, rad.
    pub course_gnss: f64,
    /// 2W speed over the interval, m/s.
    pub v_odo: f64,
    /// Length of the 2W model's displacement over the interval (its chord)
    /// over the interval's duration, m/s: what the GNSS speed over the same
    /// interval measures (in a corner the chord is shorter than the arc by
    /// about (w T)^2 / 6, T the half interval).
    pub v_chord: f64,
    /// 2W yaw rate over the interval, rad/s.
    pub w_odo: f64,
    /// 2W heading at the fix (cumulative, not wrapped), rad.
    pub psi_odo: f64,
    /// Direction of the 2W model's displacement over the interval (the
    /// wheels' track from the fix before to the fix after), near
    /// `psi_odo`, rad: what the GNSS course over the same interval
    /// measures (a chord, not the heading at the middle fix).
    pub course_odo: f64,
    /// Distance travelled since the start at the fix, m.
    pub s_m: f64,
    /// Integral of a_y over distance since the start, m^2/s^2 (load transfer).
    pub int_ay_ds: f64,
    /// Gyro heading at the fix (cumulative integral of gz), rad; NaN without IMU.
    pub psi_gyro: f64,
    /// Direction of the displacement over the interval with the gyro's
    /// heading and the wheels' distance, near `psi_gyro`, rad; NaN
    /// without IMU.
    pub course_gyro: f64,
    /// Mean gyro rate over the interval, rad/s; NaN without IMU.
    pub gz: f64,
    /// Longitudinal acceleration from the 2W speed, m/s^2.
    pub a_x: f64,
    /// Lateral acceleration v w, m/s^2, the yaw rate read through the load
    /// transfer the epochs were built with.
    pub a_y: f64,
    /// Yaw acceleration, rad/s^2.
    pub w_dot: f64,
    /// Road grade from the IMU's forward accelerometer against the wheels'
    /// acceleration (drive median removed); NaN without it.
    pub grade: f64,
    /// Absolute heading sensor at the fix, rad; NaN without one.
    pub heading: f64,
    /// The car stands (no wheel motion over the interval).
    pub standstill: bool,
    /// Interval length, s.
    pub dt_s: f64,
    /// GNSS step residual: how far this fix lies from where the previous fix
    /// plus the 2W motion puts it, m (a jump detector).
    pub gnss_step_m: f64,
}

/// The epochs of a drive and what they were made from.
#[derive(Debug, Clone)]
pub struct Epochs {
    /// One per usable fix, in time order.
    pub epochs: Vec<Epoch>,
    /// The drive has an IMU yaw rate.
    pub has_gyro: bool,
    /// The drive has a forward accelerometer that follows the wheels (the
    /// grade signal is usable).
    pub has_grade: bool,
    /// The drive has an absolute heading sensor.
    pub has_heading: bool,
    /// GNSS noise, 1 sigma, m: from the fixes' own scatter about a smooth
    /// track, or their `sigma_m` column when it is larger.
    pub gnss_sigma_m: f64,
    /// Half-width of the differencing interval, in fixes.
    pub half_width: usize,
    /// The white part of the GNSS noise alone (from second differences), m.
    pub gnss_white_sigma_m: f64,
    /// IMU times, s.
    pub gyro_t: Vec<f64>,
    /// The gyro heading (cumulative integral of gz) at the IMU times, rad.
    pub gyro_psi: Vec<f64>,
}

/// Linear interpolation of a cumulative series at `t` (times increasing).
pub fn interp(ts: &[f64], vs: &[f64], t: f64) -> Option<f64> {
    if ts.is_empty() || t < ts[0] || t > ts[ts.len() - 1] {
        return None;
    }
    let i = ts.partition_point(|&x| x < t);
    if i == 0 {
        return Some(vs[0]);
    }
    let (t0, t1) = (ts[i - 1], ts[i]);
    let f = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
    Some(vs[i - 1] + f * (vs[i] - vs[i - 1]))
}

/// The GNSS noise from the fixes themselves: the scatter of second
/// differences of position over fixes at regular spacing (a smooth track's
/// second difference is nearly zero at 5-10 Hz), 1 sigma per axis.
fn gnss_noise(gnss: &[GnssSample]) -> f64 {
    let mut d2 = Vec::with_capacity(gnss.len());
    for w in gnss.windows(3) {
        let (a, b, c) = (&w[0], &w[1], &w[2]);
        let (h1, h2) = (b.t_s - a.t_s, c.t_s - b.t_s);
        if h1 <= 0.0 || h2 <= 0.0 || (h1 - h2).abs() > 0.2 * h1.max(h2) {
            continue;
        }
        d2.push(a.x_m - 2.0 * b.x_m + c.x_m);
        d2.push(a.y_m - 2.0 * b.y_m + c.y_m);
    }
    // Var(second difference of white noise) = 6 sigma^2.
    stats::mad_sigma(&d2) / 6f64.sqrt()
}

/// Build the epochs. `c_rl`, `c_rr`, `track` are the calibrated 2W model's;
/// `k_z` is the load transfer the lateral acceleration is read through
/// ([`lateral_acceleration_from_wheels`]; 0: the plain v w).
pub fn build(
    drive: &Drive,
    revs: &[WheelRevs],
    c_rl: f64,
    c_rr: f64,
    track: f64,
    standstill_speed_m_s: f64,
    k_z: f64,
) -> Epochs {
    let gnss: &[GnssSample] = drive.gnss.as_deref().unwrap_or(&[]);
    let white = gnss_noise(gnss);
    let mut sigma = white;
    let col = stats::median_of_finite(&gnss.iter().filter_map(|g| g.sigma_m).collect::<Vec<_>>());
    if col.is_finite() && col > sigma {
        sigma = col;
    }
    if !(sigma.is_finite() && sigma > 0.0) {
        sigma = 1.0;
    }
    let t_start = revs.first().map_or(0.0, |r| r.t_s);
    // Cumulative wheel distances and 2W heading at the wheel samples.
    let wt: Vec<f64> = revs.iter().map(|r| r.t_s).collect();
    let dl: Vec<f64> = revs.iter().map(|r| r.rl * c_rl).collect();
    let dr: Vec<f64> = revs.iter().map(|r| r.rr * c_rr).collect();
    // The integral of a_y ds = v w ds = v dpsi ds/dt... per wheel step.
    let mut int_ay = Vec::with_capacity(revs.len());
    let mut acc = 0.0;
    for i in 0..revs.len() {
        if i > 0 {
            let dt = wt[i] - wt[i - 1];
            let ds = 0.5 * ((dl[i] - dl[i - 1]) + (dr[i] - dr[i - 1]));
            let dpsi = ((dr[i] - dr[i - 1]) - (dl[i] - dl[i - 1])) / track;
            if dt > 0.0 && ds.is_finite() && dpsi.is_finite() {
                let v = ds / dt;
                let w = dpsi / dt;
                acc += lateral_acceleration_from_wheels(v, w, k_z, track) * ds;
            }
        }
        int_ay.push(acc);
    }
    // Gyro heading: trapezoidal integral of gz.
    let imu: &[ImuSample] = drive.imu.as_deref().unwrap_or(&[]);
    let it: Vec<f64> = imu.iter().map(|s| s.t_s).collect();
    let mut psi_g = Vec::with_capacity(imu.len());
    let mut acc = 0.0;
    for i in 0..imu.len() {
        if i > 0 {
            acc += 0.5 * (imu[i].gz_rad_s + imu[i - 1].gz_rad_s) * (it[i] - it[i - 1]);
        }
        psi_g.push(acc);
    }
    // Forward accelerometer, integrated so that a mean over an interval is a difference.
    let has_ax = imu.iter().filter(|s| s.ax_m_s2.is_some()).count() > imu.len() / 2;
    let mut int_ax = Vec::with_capacity(imu.len());
    let mut acc = 0.0;
    for i in 0..imu.len() {
        if i > 0 {
            let a0 = imu[i - 1].ax_m_s2.unwrap_or(0.0);
            let a1 = imu[i].ax_m_s2.unwrap_or(0.0);
            acc += 0.5 * (a0 + a1) * (it[i] - it[i - 1]);
        }
        int_ax.push(acc);
    }
    // The displacement over distance under each heading (cumulative east
    // and north per wheel step): the course the GNSS sees over an
    // interval is the direction of the displacement, which in a corner
    // being entered or left differs from the heading at the middle fix by
    // about w_dot T^2 / 6 (T the half interval); read against the heading
    // it correlates with the heading change within a corner, whichever the
    // turn, and looks like a track error.
    let displacement = |psi_at: &dyn Fn(usize) -> Option<f64>| -> [Vec<f64>; 2] {
        let mut out = [Vec::with_capacity(wt.len()), Vec::with_capacity(wt.len())];
        let (mut east, mut north) = (0.0, 0.0);
        let mut last: Option<f64> = None;
        for i in 0..wt.len() {
            let now = psi_at(i);
            if i > 0 {
                let ds = 0.5 * ((dl[i] - dl[i - 1]) + (dr[i] - dr[i - 1]));
                if let (Some(p0), Some(p1)) = (last, now) {
                    let p = 0.5 * (p0 + p1);
                    if ds.is_finite() && p.is_finite() {
                        east += ds * p.cos();
                        north += ds * p.sin();
                    }
                }
            }
            last = now;
            out[0].push(east);
            out[1].push(north);
        }
        out
    };
    let disp_odo = displacement(&|i| Some((dr[i] - dl[i]) / track));
    let disp_gyro = (!imu.is_empty()).then(|| displacement(&|i| interp(&it, &psi_g, wt[i])));
    let heading: Vec<(f64, f64)> = drive
        .heading
        .as_deref()
        .unwrap_or(&[])
        .iter()
        .map(|h| (h.t_s, h.yaw_rad))
        .collect();

    let median_dt = {
        let d: Vec<f64> = gnss.windows(2).map(|w| w[1].t_s - w[0].t_s).collect();
        stats::median_of_finite(&d)
    };
    let max_gap = if median_dt.is_finite() {
        2.5 * median_dt
    } else {
        0.0
    };
    // Half-width of the differencing interval, in fixes: wide enough that
    // the GNSS noise gives a course sigma under 0.05 rad at 5 m/s.
    let half = if median_dt.is_finite() && median_dt > 0.0 {
        let need_s = 2f64.sqrt() * sigma / (0.05 * 5.0);
        ((need_s / (2.0 * median_dt)).ceil() as usize).clamp(1, 10)
    } else {
        1
    };
    let mut epochs = Vec::new();
    for k in half..gnss.len().saturating_sub(half) {
        let (a, b, c) = (&gnss[k - half], &gnss[k], &gnss[k + half]);
        let dt = c.t_s - a.t_s;
        if dt.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
            || dt > 2.0 * half as f64 * max_gap
        {
            continue;
        }
        let at = |series: &[f64], t: f64| interp(&wt, series, t);
        let (Some(l0), Some(l1), Some(r0), Some(r1), Some(lb), Some(rb), Some(ay_b)) = (
            at(&dl, a.t_s),
            at(&dl, c.t_s),
            at(&dr, a.t_s),
            at(&dr, c.t_s),
            at(&dl, b.t_s),
            at(&dr, b.t_s),
            at(&int_ay, b.t_s),
        ) else {
            continue;
        };
        let v_odo = 0.5 * ((l1 - l0) + (r1 - r0)) / dt;
        let w_odo = ((r1 - r0) - (l1 - l0)) / (track * dt);
        let (vx, vy) = ((c.x_m - a.x_m) / dt, (c.y_m - a.y_m) / dt);
        let gz = match (interp(&it, &psi_g, a.t_s), interp(&it, &psi_g, c.t_s)) {
            (Some(g0), Some(g1)) => (g1 - g0) / dt,
            _ => f64::NAN,
        };
        let ax_imu = match (interp(&it, &int_ax, a.t_s), interp(&it, &int_ax, c.t_s)) {
            (Some(g0), Some(g1)) if has_ax => (g1 - g0) / dt,
            _ => f64::NAN,
        };
        // The displacement's direction over [a, c], near `near` (the
        // heading at the middle fix where the car barely moves).
        let displaced = |disp: &[Vec<f64>; 2]| -> Option<(f64, f64)> {
            Some((
                interp(&wt, &disp[0], c.t_s)? - interp(&wt, &disp[0], a.t_s)?,
                interp(&wt, &disp[1], c.t_s)? - interp(&wt, &disp[1], a.t_s)?,
            ))
        };
        let chord = |disp: &[Vec<f64>; 2], near: f64| -> f64 {
            match displaced(disp) {
                Some((dx, dy)) if dx.hypot(dy) > 0.0 && near.is_finite() => {
                    near + wrap_angle(dy.atan2(dx) - near)
                }
                _ => near,
            }
        };
        let psi_b = (rb - lb) / track;
        let psi_gyro_b = interp(&it, &psi_g, b.t_s).unwrap_or(f64::NAN);
        let course_odo = chord(&disp_odo, psi_b);
        let v_chord = displaced(&disp_odo).map_or(v_odo, |(dx, dy)| dx.hypot(dy) / dt);
        let course_gyro = disp_gyro
            .as_ref()
            .map_or(f64::NAN, |d| chord(d, psi_gyro_b));
        let heading_at = {
            let i = heading.partition_point(|h| h.0 < b.t_s);
            if i > 0 && i < heading.len() && heading[i].0 - heading[i - 1].0 < max_gap.max(0.5) {
                let (h0, h1) = (heading[i - 1], heading[i]);
                let f = (b.t_s - h0.0) / (h1.0 - h0.0);
                h0.1 + f * wrap_angle(h1.1 - h0.1)
            } else {
                f64::NAN
            }
        };
        epochs.push(Epoch {
            t_s: b.t_s,
            t_rel_s: b.t_s - t_start,
            x_m: b.x_m,
            y_m: b.y_m,
            v_gnss: vx.hypot(vy),
            course_gnss: vy.atan2(vx),
            v_odo,
            v_chord,
            w_odo,
            psi_odo: psi_b,
            course_odo,
            s_m: 0.5 * (lb + rb),
            int_ay_ds: ay_b,
            psi_gyro: psi_gyro_b,
            course_gyro,
            gz,
            a_x: 0.0,
            a_y: lateral_acceleration_from_wheels(v_odo, w_odo, k_z, track),
            w_dot: 0.0,
            grade: ax_imu,
            heading: heading_at,
            standstill: v_odo.abs() < standstill_speed_m_s,
            dt_s: dt,
            gnss_step_m: 0.0,
        });
    }
    // Accelerations by central differences over neighbouring epochs.
    let n = epochs.len();
    for k in 0..n {
        let (i, j) = (k.saturating_sub(1), (k + 1).min(n.saturating_sub(1)));
        let dt = epochs[j].t_s - epochs[i].t_s;
        if dt > 0.0 && dt < 4.0 * max_gap.max(0.2) {
            epochs[k].a_x = (epochs[j].v_odo - epochs[i].v_odo) / dt;
            epochs[k].w_dot = (epochs[j].w_odo - epochs[i].w_odo) / dt;
        }
        if k > 0 && epochs[k].t_s - epochs[k - 1].t_s <= max_gap {
            let (p, q) = (&epochs[k - 1], &epochs[k]);
            let ds = q.s_m - p.s_m;
            let psi = 0.5 * (p.psi_odo + q.psi_odo);
            // Heading of the motion from GNSS at the previous epoch when moving.
            let course = if p.v_gnss > 1.0 { p.course_gnss } else { psi };
            let ex = q.x_m - (p.x_m + ds * course.cos());
            let ey = q.y_m - (p.y_m + ds * course.sin());
            epochs[k].gnss_step_m = ex.hypot(ey);
        }
    }
    // Grade: the forward accelerometer minus the wheels' acceleration is
    // gravity along the slope (plus the mounting pitch: its median is removed).
    let grade_raw: Vec<f64> = epochs.iter().map(|e| (e.grade - e.a_x) / G).collect();
    let ax_pairs: Vec<(f64, f64)> = epochs
        .iter()
        .filter(|e| e.grade.is_finite() && !e.standstill)
        .map(|e| (e.grade, e.a_x))
        .collect();
    // The accelerometer must follow the wheels' acceleration, else its axis
    // is not the car's forward one and the grade cannot be read from it.
    let has_grade = ax_pairs.len() > 20 && correlation(&ax_pairs) > 0.7;
    let m = stats::median_of_finite(&grade_raw);
    for (e, g) in epochs.iter_mut().zip(&grade_raw) {
        e.grade = if has_grade { g - m } else { f64::NAN };
    }
    Epochs {
        has_gyro: !imu.is_empty(),
        has_grade,
        has_heading: !heading.is_empty(),
        epochs,
        gnss_sigma_m: sigma,
        half_width: half,
        gnss_white_sigma_m: if white.is_finite() { white } else { sigma },
        gyro_t: it,
        gyro_psi: psi_g,
    }
}

/// Least moving epochs for the gyro's agreement with the wheels.
const MIN_GYRO_EPOCHS: usize = 50;
/// Least correlation of the gyro's rate with the wheels' yaw rate.
const MIN_GYRO_CORRELATION: f64 = 0.9;
/// Speed above which an epoch counts as moving for that check, m/s.
const GYRO_CHECK_SPEED_M_S: f64 = 2.0;
/// Wheel steps on each side over which the speed of a step is taken for
/// the gyro's a_y integral (one step's distance swings with the encoder's
/// quantisation).
const GYRO_AY_SPEED_HALF_STEPS: usize = 5;

/// The same epochs with the lateral acceleration read from the gyro instead
/// of the wheels: a_y = v (gz - bias) and its integral over distance v^2
/// dpsi_gyro per wheel step. A second reading of a_y that no wheel-radius
/// effect bends; where the two readings give different estimates of an
/// effect that reads a_y, the effect's linear form does not hold exactly
/// (the diagnosis reports the difference as a model-form uncertainty).
/// `None` where the drive has no gyro that follows the wheels' yaw rate
/// (same sign, a slope within a factor of two, correlation at least
/// [`MIN_GYRO_CORRELATION`] on moving epochs). `revs`, `c_rl`, `c_rr` and
/// `track` as the epochs were built with.
pub fn with_gyro_lateral(
    ep: &Epochs,
    revs: &[WheelRevs],
    c_rl: f64,
    c_rr: f64,
    track: f64,
) -> Option<Epochs> {
    let bias = gyro_bias_if_it_follows(&ep.epochs)?;
    let wt: Vec<f64> = revs.iter().map(|r| r.t_s).collect();
    let dl: Vec<f64> = revs.iter().map(|r| r.rl * c_rl).collect();
    let dr: Vec<f64> = revs.iter().map(|r| r.rr * c_rr).collect();
    let int_g = int_ay_gyro(&wt, &dl, &dr, track, &ep.gyro_t, &ep.gyro_psi, bias);
    let mut out = ep.clone();
    for e in out.epochs.iter_mut() {
        if e.gz.is_finite() {
            e.a_y = e.v_odo * (e.gz - bias);
        }
        if let Some(v) = interp(&wt, &int_g, e.t_s) {
            e.int_ay_ds = v;
        }
    }
    Some(out)
}

/// The gyro's bias when its rate follows the wheels' yaw rate, else
/// `None`. The bias is the median rate at standstill, or the median
/// difference from the wheels when the drive has too little standstill.
fn gyro_bias_if_it_follows(epochs: &[Epoch]) -> Option<f64> {
    let still: Vec<f64> = epochs
        .iter()
        .filter(|e| e.standstill && e.gz.is_finite())
        .map(|e| e.gz)
        .collect();
    let moving: Vec<&Epoch> = epochs
        .iter()
        .filter(|e| e.gz.is_finite() && e.w_odo.is_finite() && e.v_odo > GYRO_CHECK_SPEED_M_S)
        .collect();
    if moving.len() < MIN_GYRO_EPOCHS {
        return None;
    }
    let bias = if still.len() >= 10 {
        stats::median_of_finite(&still)
    } else {
        stats::median_of_finite(&moving.iter().map(|e| e.gz - e.w_odo).collect::<Vec<_>>())
    };
    if !bias.is_finite() {
        return None;
    }
    let pairs: Vec<(f64, f64)> = moving.iter().map(|e| (e.w_odo, e.gz - bias)).collect();
    let (sxy, sxx) = pairs
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x * y, b + x * x));
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    (correlation(&pairs) >= MIN_GYRO_CORRELATION && (0.5..=2.0).contains(&slope)).then_some(bias)
}

/// The integral of a_y over distance, v^2 dpsi per wheel step, the heading
/// increment from the gyro (less `bias`) and the speed from the wheels'
/// distance over [`GYRO_AY_SPEED_HALF_STEPS`] steps each side; the wheels'
/// heading where the gyro has no sample.
fn int_ay_gyro(
    wt: &[f64],
    dl: &[f64],
    dr: &[f64],
    track: f64,
    it: &[f64],
    psi_g: &[f64],
    bias: f64,
) -> Vec<f64> {
    let n = wt.len();
    let s = |i: usize| 0.5 * (dl[i] + dr[i]);
    let mut out = Vec::with_capacity(n);
    let mut acc = 0.0;
    let mut last_g = wt.first().and_then(|&t| interp(it, psi_g, t));
    for i in 0..n {
        let now_g = interp(it, psi_g, wt[i]);
        if i > 0 {
            let dt = wt[i] - wt[i - 1];
            let (a, b) = (
                i.saturating_sub(GYRO_AY_SPEED_HALF_STEPS),
                (i + GYRO_AY_SPEED_HALF_STEPS).min(n - 1),
            );
            let span = wt[b] - wt[a];
            let v = if span > 0.0 {
                (s(b) - s(a)) / span
            } else {
                0.0
            };
            let dpsi = match (last_g, now_g) {
                (Some(g0), Some(g1)) => g1 - g0 - bias * dt,
                _ => ((dr[i] - dr[i - 1]) - (dl[i] - dl[i - 1])) / track,
            };
            if dt > 0.0 && v.is_finite() && dpsi.is_finite() {
                acc += v * v * dpsi;
            }
        }
        last_g = now_g;
        out.push(acc);
    }
    out
}

/// Pearson correlation of pairs (0 when undefined).
pub fn correlation(pairs: &[(f64, f64)]) -> f64 {
    let n = pairs.len() as f64;
    if n < 3.0 {
        return 0.0;
    }
    let (mx, my) = pairs
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for (x, y) in pairs {
        sxx += (x - mx) * (x - mx);
        syy += (y - my) * (y - my);
        sxy += (x - mx) * (y - my);
    }
    if sxx > 0.0 && syy > 0.0 {
        sxy / (sxx * syy).sqrt()
    } else {
        0.0
    }
}
