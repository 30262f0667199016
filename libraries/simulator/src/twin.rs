//! The twin of a recorded drive: the same path and the same progress over
//! time, the same vehicle numbers, sensor rates and noise, the same GNSS
//! outages, and the physics a list of findings names (or none), driven by
//! the engine so every effect acts as in any other simulated drive.
//!
//! The path: the GNSS fixes smoothed as functions of the wheels' distance
//! (a local quadratic fit with a Gaussian kernel of [`TwinConfig::smoothing_m`]
//! metres, widened across GNSS gaps), so that a standstill is one point
//! and cannot make a heading spike; moved from the antenna to the
//! rear-axle centre; resampled every 0.25 m of arc length. The progress:
//! the wheels' distance over time mapped onto the path's arc length, which
//! the engine's driver follows (`Prescribed`) instead of a speed profile.

use super::engine::{self, Custom, Prescribed};
use super::route::{Attrs, Route, DS};
use super::scenarios::ScenarioRoute;
use super::twin_noise::{
    drive_numbers, interp, restamp, running_max, stamp_jitter, stamp_jitter_rms, window_means,
    DriveNumbers, Odometer,
};
use super::{
    EffectForms, EffectSettings, Scenario, SensorSettings, SimConfig, SimError, VehicleKind,
    VehicleSpec, WheelWear,
};
use interfaces::drive::{toml_value::Value, Drive};
use interfaces::effects::Effect;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::collections::BTreeMap;
use std::f64::consts::TAU;

/// Time step of the prescribed progress, s.
const PROGRESS_DT_S: f64 = 0.01;
/// Half the window, m of wheel distance, over which the twin's path may
/// stretch or shrink against the wheels' distance (applied twice: a
/// triangle of this half-width).
const PROGRESS_SCALE_HALF_M: f64 = 50.0;
/// Half the window of the progress's speed, s: the distance is counted in
/// wheel ticks (2 cm at 96 per revolution), so a shorter window puts their
/// quantisation into the speed the twin is driven at.
const PROGRESS_SPEED_HALF_S: f64 = 0.25;
/// Straight added beyond the path's end so the driver's look-ahead has
/// somewhere to aim, m.
const RUN_OUT_M: f64 = 30.0;
/// Default smoothing of GNSS fixes along the path, m.
pub const DEFAULT_SMOOTHING_M: f64 = 4.0;
/// Gauss-Markov GNSS noise when nothing says otherwise: the same sigma as
/// the white noise estimated from the fixes, with this correlation time, s.
pub const DEFAULT_GM_TAU_S: f64 = 60.0;

/// One position of a recorded track (local ENU).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackPoint {
    /// Time, s.
    pub t_s: f64,
    /// East, m.
    pub x_m: f64,
    /// North, m.
    pub y_m: f64,
}

/// A path and the progress along it over time.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinPath {
    /// Grid spacing, m.
    pub ds: f64,
    /// East of the rear-axle centre every `ds` m, m.
    pub x: Vec<f64>,
    /// North, m.
    pub y: Vec<f64>,
    /// Start of the progress on the drive's clock, s.
    pub t0_s: f64,
    /// Step of the progress, s.
    pub dt_s: f64,
    /// Arc length along the path every `dt_s` from `t0_s`, m.
    pub s: Vec<f64>,
    /// Speed every `dt_s`, m/s.
    pub v: Vec<f64>,
    /// The fixes minus the smoothed track at their distance (east, north), m.
    pub residuals: Vec<(f64, f64)>,
}

impl TwinPath {
    /// The path's length, m.
    pub fn length_m(&self) -> f64 {
        self.x.len().saturating_sub(1) as f64 * self.ds
    }

    /// The distance of (x, y) from the path (the nearest of its segments), m.
    pub fn distance_to(&self, x: f64, y: f64) -> f64 {
        polyline_distance(&self.x, &self.y, x, y)
    }
}

/// The distance of (x, y) from the polyline through `xs`, `ys`, m.
pub fn polyline_distance(xs: &[f64], ys: &[f64], x: f64, y: f64) -> f64 {
    let n = xs.len().min(ys.len());
    if n == 1 {
        return (xs[0] - x).hypot(ys[0] - y);
    }
    (0..n.saturating_sub(1))
        .map(|i| {
            let (ex, ey) = (xs[i + 1] - xs[i], ys[i + 1] - ys[i]);
            let l2 = ex * ex + ey * ey;
            let f = if l2 > 0.0 {
                (((x - xs[i]) * ex + (y - ys[i]) * ey) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (xs[i] + f * ex - x).hypot(ys[i] + f * ey - y)
        })
        .fold(f64::INFINITY, f64::min)
}

/// The arc length along the path at each point of a wheel-distance grid
/// of spacing `du`, with its departure from the wheel distance averaged
/// over +-[`PROGRESS_SCALE_HALF_M`] (a moving average applied twice),
/// never decreasing, starting at 0 and ending at the path's length.
fn progress_arc(arc: &[f64], du: f64) -> Vec<f64> {
    let n = arc.len();
    if n < 3 {
        return arc.to_vec();
    }
    let half = ((PROGRESS_SCALE_HALF_M / du).round() as usize).max(1);
    let bounds = |k: usize| (k.saturating_sub(half), (k + half).min(n - 1));
    let departure: Vec<f64> = arc
        .iter()
        .enumerate()
        .map(|(k, a)| a - k as f64 * du)
        .collect();
    let smooth = window_means(&window_means(&departure, bounds), bounds);
    let (first, last) = (smooth[0], smooth[n - 1] + (n - 1) as f64 * du);
    // Pinned at both ends: the twin starts where the path starts and ends
    // where it ends.
    let stretch = (arc[n - 1] - arc[0]) / (last - first).max(f64::EPSILON);
    running_max(
        smooth
            .iter()
            .enumerate()
            .map(|(k, d)| arc[0] + (k as f64 * du + d - first) * stretch)
            .collect(),
    )
}

/// Local quadratic fit of (d, x) and (d, y) with Gaussian weights of
/// bandwidth `h` around d = 0: the fitted values at 0. Falls back to a
/// local line, then a weighted mean, where the points do not determine
/// a quadratic.
fn local_fit(d: &[f64], x: &[f64], y: &[f64], h: f64) -> Option<(f64, f64)> {
    let mut m = [0.0f64; 5];
    let (mut tx, mut ty) = ([0.0f64; 3], [0.0f64; 3]);
    for ((&di, &xi), &yi) in d.iter().zip(x).zip(y) {
        let u = di / h;
        let w = (-0.5 * u * u).exp();
        let mut p = w;
        for (k, mk) in m.iter_mut().enumerate() {
            *mk += p;
            if k < 3 {
                tx[k] += p * xi;
                ty[k] += p * yi;
            }
            p *= u;
        }
    }
    if m[0] <= 1e-12 {
        return None;
    }
    let det3 = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let a = [[m[0], m[1], m[2]], [m[1], m[2], m[3]], [m[2], m[3], m[4]]];
    let det = det3(a);
    if det.abs() > 1e-9 * m[0].powi(3) {
        let solve = |t: [f64; 3]| {
            let mut b = a;
            for (row, tv) in b.iter_mut().zip(t) {
                row[0] = tv;
            }
            det3(b) / det
        };
        return Some((solve(tx), solve(ty)));
    }
    let det2 = m[0] * m[2] - m[1] * m[1];
    if det2.abs() > 1e-9 * m[0] * m[0] {
        let f = |t: [f64; 3]| (t[0] * m[2] - m[1] * t[1]) / det2;
        return Some((f(tx), f(ty)));
    }
    Some((tx[0] / m[0], ty[0] / m[0]))
}

/// The path and progress of a recorded track.
///
/// `track`: positions (the antenna's) over time; `odometer`: the wheels'
/// distance over time; `smoothing_m`: the kernel's bandwidth along the
/// path (about the fixes' noise times a few; 0.5 m for a noiseless
/// track); `antenna`: the antenna's body position (x forward, y left)
/// from the rear-axle centre, which the path is moved by; `t_start`,
/// `t_end`: the progress's span on the drive's clock.
pub fn path_from_track(
    track: &[TrackPoint],
    odometer: &Odometer,
    smoothing_m: f64,
    antenna: (f64, f64),
    (t_start, t_end): (f64, f64),
) -> Result<TwinPath, SimError> {
    let bad = |reason: String| SimError::Route {
        scenario: "twin".into(),
        reason,
    };
    if track.len() < 4 {
        return Err(bad(format!("{} track points are too few", track.len())));
    }
    if !(smoothing_m > 0.0 && smoothing_m.is_finite()) {
        return Err(bad(format!("smoothing {smoothing_m} m is not positive")));
    }
    if track
        .iter()
        .any(|p| !(p.t_s.is_finite() && p.x_m.is_finite() && p.y_m.is_finite()))
    {
        return Err(bad("a track point is not finite".into()));
    }
    // Each point's wheel distance; sorted by it (it never decreases in time).
    let mut pts: Vec<(f64, f64, f64)> = track
        .iter()
        .map(|p| (odometer.distance_at(p.t_s), p.x_m, p.y_m))
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let d: Vec<f64> = pts.iter().map(|p| p.0).collect();
    let px: Vec<f64> = pts.iter().map(|p| p.1).collect();
    let py: Vec<f64> = pts.iter().map(|p| p.2).collect();
    let (u0, u1) = (d[0], d[d.len() - 1]);
    if u1 - u0 < 2.0 {
        return Err(bad(format!(
            "the wheels cover only {:.1} m while there are fixes",
            u1 - u0
        )));
    }

    // The smoothed track on a grid of wheel distance.
    let nu = ((u1 - u0) / DS).ceil() as usize + 1;
    let du = (u1 - u0) / (nu - 1) as f64;
    let (mut sx, mut sy) = (Vec::with_capacity(nu), Vec::with_capacity(nu));
    let (mut lo, mut hi) = (0usize, 0usize);
    for k in 0..nu {
        let u = u0 + k as f64 * du;
        // Widen the kernel across a gap: to the nearest points on each side.
        let right = d.partition_point(|v| *v < u);
        let left_d = if right > 0 { u - d[right - 1] } else { 0.0 };
        let right_d = if right < d.len() { d[right] - u } else { 0.0 };
        let h = smoothing_m.max(0.75 * left_d.max(right_d));
        let reach = 4.0 * h;
        while lo < d.len() && d[lo] < u - reach {
            lo += 1;
        }
        while hi < d.len() && d[hi] <= u + reach {
            hi += 1;
        }
        let (lo_k, hi_k) = if lo < hi {
            (lo, hi)
        } else {
            let j = right.min(d.len() - 1);
            (j, j + 1)
        };
        let rel: Vec<f64> = d[lo_k..hi_k].iter().map(|v| v - u).collect();
        let (x, y) = local_fit(&rel, &px[lo_k..hi_k], &py[lo_k..hi_k], h)
            .ok_or_else(|| bad(format!("no fix near wheel distance {u:.1} m")))?;
        sx.push(x);
        sy.push(y);
    }
    let residuals = pts
        .iter()
        .map(|&(s, x, y)| {
            let f = ((s - u0) / du).clamp(0.0, (nu - 1) as f64);
            let i = (f.floor() as usize).min(nu - 2);
            let w = f - i as f64;
            (
                x - (sx[i] + w * (sx[i + 1] - sx[i])),
                y - (sy[i] + w * (sy[i + 1] - sy[i])),
            )
        })
        .collect();

    // From the antenna to the rear axle.
    if antenna != (0.0, 0.0) {
        let heading: Vec<f64> = (0..nu)
            .map(|i| {
                let (a, b) = (i.saturating_sub(2), (i + 2).min(nu - 1));
                (sy[b] - sy[a]).atan2(sx[b] - sx[a])
            })
            .collect();
        for ((x, y), h) in sx.iter_mut().zip(sy.iter_mut()).zip(heading) {
            let (s, c) = h.sin_cos();
            *x -= c * antenna.0 - s * antenna.1;
            *y -= s * antenna.0 + c * antenna.1;
        }
    }

    // Arc length of the smoothed path at each wheel distance.
    let mut arc = Vec::with_capacity(nu);
    arc.push(0.0);
    for k in 1..nu {
        let step = (sx[k] - sx[k - 1]).hypot(sy[k] - sy[k - 1]);
        arc.push(arc[k - 1] + step);
    }
    let length = arc[nu - 1];
    let n = ((length / DS).round() as usize).max(8);
    let ds = length / n as f64;
    let mut x = Vec::with_capacity(n + 1);
    let mut y = Vec::with_capacity(n + 1);
    for i in 0..=n {
        let a = i as f64 * ds;
        x.push(interp(&arc, &sx, a));
        y.push(interp(&arc, &sy, a));
    }

    // Progress over time: wheel distance -> arc length. The smoothed
    // track's arc length at a wheel distance carries the fixes' along-track
    // error (a few decimetres over a few metres after the kernel), which as
    // a rate would drive the twin at the wrong speed (+-0.3 m/s at 5 m/s,
    // a 2-3 s oscillation where the recording cruised); the wheels count
    // distance far better over such spans. So the arc length's departure
    // from the wheel distance is taken only over PROGRESS_SCALE_HALF_M.
    let grid_u: Vec<f64> = (0..nu).map(|k| u0 + k as f64 * du).collect();
    let arc = progress_arc(&arc, du);
    let steps = ((t_end - t_start) / PROGRESS_DT_S).round().max(1.0) as usize;
    let s: Vec<f64> = (0..=steps)
        .map(|k| {
            let t = t_start + k as f64 * PROGRESS_DT_S;
            interp(&grid_u, &arc, odometer.distance_at(t))
        })
        .collect();
    let half = (PROGRESS_SPEED_HALF_S / PROGRESS_DT_S).round() as usize;
    let v = (0..s.len())
        .map(|k| {
            let (a, b) = (k.saturating_sub(half), (k + half).min(s.len() - 1));
            if b > a {
                (s[b] - s[a]) / ((b - a) as f64 * PROGRESS_DT_S)
            } else {
                0.0
            }
        })
        .collect();
    Ok(TwinPath {
        ds,
        x,
        y,
        t0_s: t_start,
        dt_s: PROGRESS_DT_S,
        s,
        v,
        residuals,
    })
}

/// The vehicle of a twin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwinVehicle {
    /// True rear-left circumference, m.
    pub c_rl_m: f64,
    /// True rear-right circumference, m.
    pub c_rr_m: f64,
    /// Rear track (vehicle.toml's and the simulated one), m.
    pub track_width_m: f64,
    /// Wheelbase, m (`None`: the saloon's).
    pub wheelbase_m: Option<f64>,
    /// vehicle.toml's nominal circumference, m.
    pub nominal_circumference_m: f64,
    /// vehicle.toml's antenna position (x forward, y left), m.
    pub antenna: Option<(f64, f64)>,
}

/// The GNSS error model per axis: white sigma (m), Gauss-Markov sigma
/// (m), its correlation time (s).
pub type GnssNoise = [f64; 3];

/// Everything a twin needs.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinConfig {
    /// Where the recording came from (written as `twin_of` in truth.toml).
    pub source: String,
    /// The path and progress.
    pub path: TwinPath,
    /// The vehicle.
    pub vehicle: TwinVehicle,
    /// Sensor rates and noise.
    pub sensors: SensorSettings,
    /// GNSS outages on the drive's clock, s.
    pub gnss_gaps: Vec<(f64, f64)>,
    /// The recording's GNSS stamp jitter: per fix, the receiver's regular
    /// epoch and the stamp's jitter about it, s
    /// ([`super::twin_noise::stamp_jitter`]); empty: regular stamps.
    pub gnss_stamp_jitter: Vec<(f64, f64)>,
    /// The recording's rear wheel speed noise (rl, rr), rev/s, where its
    /// wheels are speeds ([`super::twin_noise::wheel_speed_noise`]); added
    /// to the twin's rear wheels as white noise on their speed.
    pub wheel_speed_sigma_rev_s: Option<[f64; 2]>,
    /// The accuracy the recording's receiver claims for its fixes (the
    /// median of `sigma_m`), written with every fix of the twin; `None`
    /// when the recording claims none (the twin then claims none either).
    pub claimed_sigma_m: Option<f64>,
    /// The physics.
    pub effects: EffectSettings,
    /// Seed of the sensor noise.
    pub seed: u64,
    /// Internal integration step, s.
    pub step_s: f64,
    /// How the effects act (the simulator's physical forms unless set;
    /// in the catalogue's forms a knob means what a diagnosis's estimate
    /// means).
    pub effect_forms: EffectForms,
    /// The wheels' speed reading beyond the catalogue (a comparison's
    /// `twin_speed_map`); `None`: none.
    pub speed_map: Option<interfaces::speed_map::SpeedMap>,
    /// The wheels' yaw wander (a comparison's `twin_yaw_wander`); `None`:
    /// none.
    pub yaw_wander: Option<interfaces::yaw_wander::YawWander>,
}

/// What is taken from elsewhere than the drive: a diagnosis's GNSS noise
/// and calibrated plain model, the effects, the seed.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinOptions {
    /// Where the recording came from.
    pub source: String,
    /// GNSS error model (east, north) from a diagnosis; `None`: estimated.
    pub gnss_noise: Option<(GnssNoise, GnssNoise)>,
    /// The length of the segments that error model was fitted over (the
    /// dead-reckoning restarts in each), s: a Gauss-Markov time beyond it
    /// was not resolved by the fixes against the wheels, and its sigma
    /// holds whatever dead-reckoning error the diagnosed model leaves (it
    /// is then not GNSS noise; the white-level default stands in).
    pub gnss_noise_segment_s: Option<f64>,
    /// Calibrated rear circumferences and track (c_rl, c_rr, track), m.
    pub base_model: Option<(f64, f64, f64)>,
    /// The physics.
    pub effects: EffectSettings,
    /// Seed.
    pub seed: u64,
    /// Smoothing of the fixes along the path, m.
    pub smoothing_m: f64,
    /// How the effects act.
    pub effect_forms: EffectForms,
    /// The wheels' speed reading beyond the catalogue.
    pub speed_map: Option<interfaces::speed_map::SpeedMap>,
    /// The wheels' yaw wander.
    pub yaw_wander: Option<interfaces::yaw_wander::YawWander>,
}

impl TwinOptions {
    /// No diagnosis, no effects, seed 1, the default smoothing.
    pub fn new(source: &str) -> TwinOptions {
        TwinOptions {
            source: source.to_string(),
            gnss_noise: None,
            gnss_noise_segment_s: None,
            base_model: None,
            effects: EffectSettings::none(),
            seed: 1,
            smoothing_m: DEFAULT_SMOOTHING_M,
            effect_forms: EffectForms::Physical,
            speed_map: None,
            yaw_wander: None,
        }
    }
}

/// A twin configuration and what was derived, in words (for the log).
#[derive(Debug, Clone, PartialEq)]
pub struct DerivedTwin {
    /// The configuration.
    pub config: TwinConfig,
    /// The drive's numbers.
    pub numbers: DriveNumbers,
    /// One line per derived figure or choice.
    pub notes: Vec<String>,
}

/// Robust sigma (1.4826 median absolute deviation about the median).
fn robust_sigma(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let med = v[v.len() / 2];
    let mut dev: Vec<f64> = v.iter().map(|x| (x - med).abs()).collect();
    dev.sort_by(f64::total_cmp);
    1.4826 * dev[dev.len() / 2]
}

impl TwinConfig {
    /// The twin configuration of `drive`: its path and progress, vehicle,
    /// sensors and outages, with `options`' diagnosis numbers and effects.
    pub fn from_drive(drive: &Drive, options: &TwinOptions) -> Result<DerivedTwin, SimError> {
        let step_s = 0.001;
        let odometer = Odometer::from_drive(drive)?;
        let numbers = drive_numbers(drive, &odometer, step_s)?;
        let mut notes = Vec::new();
        let fixes = drive.gnss.as_deref().unwrap_or_default();
        // The fixes are the antenna's, stamped late by any latency.
        let latency = options.effects.gnss_latency.map_or(0.0, |l| l.tau_s);
        let track: Vec<TrackPoint> = fixes
            .iter()
            .map(|g| TrackPoint {
                t_s: g.t_s - latency,
                x_m: g.x_m,
                y_m: g.y_m,
            })
            .collect();
        // The fixes at the receiver's epochs where the readers take them
        // there (`stats::stamps::on_epochs`, the one decision): a logger's
        // stamp jitter moves a fix along the track by its speed times the
        // jitter, which the twin puts back on its own stamps (`restamp`),
        // so neither the path nor the noise measured about it holds it.
        // Where the readers keep the stamps (the jitter lost in the fixes'
        // own noise: wid-trial04), so does the twin, and the twin is read
        // as its recording is.
        let stamps: Vec<f64> = fixes.iter().map(|f| f.t_s).collect();
        let gnss_stamp_jitter = stamp_jitter(&stamps);
        let xs: Vec<f64> = fixes.iter().map(|f| f.x_m).collect();
        let ys: Vec<f64> = fixes.iter().map(|f| f.y_m).collect();
        let read_at = stats::stamps::on_epochs_given(&stamps, &gnss_stamp_jitter, &xs, &ys);
        let at_epochs: Vec<TrackPoint> = match &read_at {
            Some(r) => r
                .epochs
                .iter()
                .zip(&track)
                .map(|(e, p)| TrackPoint {
                    t_s: e - latency,
                    ..*p
                })
                .collect(),
            None => track.clone(),
        };
        let declared = match (
            drive.vehicle.gnss.antenna_x_m,
            drive.vehicle.gnss.antenna_y_m,
        ) {
            (None, None) => None,
            (x, y) => Some((x.unwrap_or(0.0), y.unwrap_or(0.0))),
        };
        let lever = options
            .effects
            .gnss_lever_arm
            .map_or((0.0, 0.0), |l| (l.x_m, l.y_m));
        let antenna = declared.unwrap_or((0.0, 0.0));
        let physical = (antenna.0 + lever.0, antenna.1 + lever.1);
        let t_start = odometer.t_s[0];
        let t_end = odometer.t_s[odometer.t_s.len() - 1];
        let path = path_from_track(
            &at_epochs,
            &odometer,
            options.smoothing_m,
            physical,
            (t_start, t_end),
        )?;
        // The short-range shape from the gyro where there is one.
        let gyro: Vec<(f64, f64)> = drive
            .imu
            .iter()
            .flatten()
            .map(|s| (s.t_s, s.gz_rad_s))
            .collect();
        let path = match gyro_shaped(&path, &gyro, numbers.gyro_bias_rad_s.unwrap_or(0.0)) {
            Some(p) => {
                notes.push(format!(
                    "path shaped by the gyro over {GYRO_SHAPE_BANDWIDTH_M:.0} m (its heading and position placed on the smoothed fixes)"
                ));
                p
            }
            None => path,
        };
        notes.push(format!(
            "path: {} fixes smoothed over {:.1} m of wheel distance, {:.1} m long, {:.1} s from t = {:.2} s; the wheels' distance {:.1} m",
            fixes.len(),
            options.smoothing_m,
            path.length_m(),
            t_end - t_start,
            t_start,
            odometer.s_m.last().copied().unwrap_or(0.0),
        ));

        // GNSS noise. The white part from the fixes' successive
        // differences against the twin's own path: the differences cancel
        // the slow wander and the path's placement, the path's shape (the
        // gyro's) takes out the motion; an error model refitted to the
        // residuals of the wheels splits white from wander less surely.
        let at = if read_at.is_some() {
            ", at the receiver's epochs"
        } else {
            ""
        };
        // Two measures, each raised by what it does not model: the path's
        // by the wheels' progress it rides on (comma2k19's CAN speeds:
        // 0.019 m where the fixes hold 0.011 m), the local cubic's by the
        // motion and the slow wander within its 3 s (the multibody
        // drives: 0.505 m where the generator put 0.5 m and the path
        // reads 0.495 m). The smaller is the less contaminated.
        let local = white_from_local_fits(&at_epochs);
        let along_path = white_from_differences(&at_epochs, &path, physical);
        let diff_white = match (local, along_path) {
            (Some(l), Some(p)) if l < p => {
                notes.push(format!(
                    "GNSS white noise {l:.3} m from each fix against a cubic through its neighbours within {LOCAL_FIT_HALF_S} s{at} \
                     ({p:.3} m from the successive differences against the twin's path)"
                ));
                Some(l)
            }
            (l, Some(p)) => {
                notes.push(format!(
                    "GNSS white noise {p:.3} m from the fixes' successive differences against the twin's path{at}{}",
                    l.map_or(String::new(), |l| format!(
                        " ({l:.3} m from each fix against a cubic through its neighbours)"
                    ))
                ));
                Some(p)
            }
            (Some(l), None) => {
                notes.push(format!(
                    "GNSS white noise {l:.3} m from each fix against a cubic through its neighbours within {LOCAL_FIT_HALF_S} s{at}"
                ));
                Some(l)
            }
            (None, None) => None,
        };
        let (east, north) = match options.gnss_noise {
            Some(n) => {
                notes.push(format!(
                    "GNSS noise from the diagnosis: east {:?}, north {:?} (white m, Gauss-Markov m, tau s); mean used",
                    n.0, n.1
                ));
                let resolved = |a: GnssNoise| -> GnssNoise {
                    let white = diff_white.unwrap_or(a[0]);
                    match options.gnss_noise_segment_s {
                        Some(seg) if !a[2].is_finite() || a[2] > seg => {
                            [white, white, DEFAULT_GM_TAU_S]
                        }
                        _ => [white, a[1], a[2]],
                    }
                };
                let r = (resolved(n.0), resolved(n.1));
                if r.0[1] != n.0[1] || r.1[1] != n.1[1] {
                    notes.push(format!(
                        "its Gauss-Markov time ({:.0} / {:.0} s) is beyond the {:.0} s segments it was fitted over: \
                         not resolved by the fixes, it holds the diagnosed model's own dead-reckoning error; \
                         the white-level default stands in (sigma = white, tau {DEFAULT_GM_TAU_S} s)",
                        n.0[2],
                        n.1[2],
                        options.gnss_noise_segment_s.unwrap_or(f64::NAN)
                    ));
                }
                r
            }
            None => {
                let w = diff_white.unwrap_or_else(|| {
                    let mut ex: Vec<f64> = path.residuals.iter().map(|r| r.0).collect();
                    let mut ny: Vec<f64> = path.residuals.iter().map(|r| r.1).collect();
                    0.5 * (robust_sigma(&mut ex) + robust_sigma(&mut ny))
                });
                notes.push(format!(
                    "GNSS noise: white {w:.3} m; Gauss-Markov by default: {w:.3} m, tau {DEFAULT_GM_TAU_S} s (no diagnosis given)"
                ));
                ([w, w, DEFAULT_GM_TAU_S], [w, w, DEFAULT_GM_TAU_S])
            }
        };
        let mut sensors = SensorSettings::default();
        sensors.wheels.rate_hz = numbers.wheel_rate_hz;
        sensors.wheels.ticks_per_rev = numbers.ticks_per_rev;
        sensors.gnss.rate_hz = numbers.gnss_rate_hz;
        sensors.gnss.white_sigma_m = 0.5 * (east[0] + north[0]);
        sensors.gnss.gm_sigma_m = 0.5 * (east[1] + north[1]);
        sensors.gnss.gm_tau_s = 0.5 * (east[2] + north[2]);
        sensors.gnss.outage_rate_per_h = 0.0;
        sensors.imu.enabled = numbers.imu_rate_hz.is_some();
        sensors.imu.rate_hz = numbers.imu_rate_hz.unwrap_or(sensors.imu.rate_hz);
        if let Some(g) = numbers.gyro_sigma_rad_s {
            sensors.imu.gz_sigma_rad_s = g;
        }
        if let Some(a) = numbers.accel_sigma_m_s2 {
            sensors.imu.accel_sigma_m_s2 = a;
        }
        sensors.heading.enabled = numbers.heading_rate_hz.is_some();
        sensors.heading.rate_hz = numbers.heading_rate_hz.unwrap_or(sensors.heading.rate_hz);
        if let Some(h) = numbers.heading_sigma_deg {
            sensors.heading.sigma_deg = h;
        }
        notes.push(format!(
            "rates: wheels {:.1} Hz{}, GNSS {:.2} Hz, IMU {}, heading {}",
            numbers.wheel_rate_hz,
            numbers
                .ticks_per_rev
                .map_or(String::new(), |t| format!(" ({t} ticks/rev)")),
            numbers.gnss_rate_hz,
            numbers
                .imu_rate_hz
                .map_or("none".into(), |r| format!("{r:.1} Hz")),
            numbers
                .heading_rate_hz
                .map_or("none".into(), |r| format!("{r:.1} Hz")),
        ));
        let mut effects = options.effects;
        match (numbers.gyro_bias_rad_s, numbers.gyro_sigma_rad_s) {
            (Some(b), Some(s)) => {
                notes.push(format!(
                    "gyro at standstill ({:.0} s): bias {:.1} deg/h, noise {:.4} rad/s{}",
                    numbers.standstill_s,
                    b.to_degrees() * 3600.0,
                    s,
                    if effects.gyro_bias.is_some() {
                        "; the effects' gyro_bias is kept"
                    } else {
                        "; simulated as gyro_bias"
                    }
                ));
                if effects.gyro_bias.is_none() && b != 0.0 {
                    effects.set(Effect::GyroBias, None, b.to_degrees() * 3600.0)?;
                }
            }
            _ if sensors.imu.enabled => notes.push(
                "gyro: no standstill of 2 s or more; the simulator's default noise, no bias".into(),
            ),
            _ => {}
        }
        if let Some(h) = numbers.heading_sigma_deg {
            notes.push(format!("compass noise {h:.2} deg"));
        }
        notes.push(format!(
            "GNSS outages (longer than 3 fix periods): {}",
            if numbers.gnss_gaps.is_empty() {
                "none".to_string()
            } else {
                numbers
                    .gnss_gaps
                    .iter()
                    .map(|(a, b)| format!("{a:.1}-{b:.1} s"))
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        ));
        notes.push(if gnss_stamp_jitter.is_empty() {
            "GNSS time stamps: no regular receiver's jitter measured; the twin's stamps are regular".into()
        } else {
            let rms = stamp_jitter_rms(&gnss_stamp_jitter);
            format!(
                "GNSS time stamps jitter by {:.1} ms RMS about the receiver's regular epochs; the twin's fixes carry the same jitter",
                1000.0 * rms
            )
        });
        if let Some([l, r]) = numbers.wheel_speed_sigma_rev_s {
            notes.push(format!(
                "wheel speed noise (the recording's wheels are speeds): rl {:.4}, rr {:.4} rad/s at {:.0} Hz, added to the twin's rear wheels",
                l * std::f64::consts::TAU,
                r * std::f64::consts::TAU,
                numbers.wheel_rate_hz
            ));
        }
        let v = &drive.vehicle;
        let (c_rl_m, c_rr_m, track_width_m) = match options.base_model {
            Some(b) => {
                notes.push(format!(
                    "vehicle from the diagnosis's base model: c_rl {:.4} m, c_rr {:.4} m, track {:.3} m",
                    b.0, b.1, b.2
                ));
                b
            }
            None => {
                notes.push(format!(
                    "vehicle from vehicle.toml: circumference {:.4} m, track {:.3} m",
                    v.nominal_circumference_m, v.track_width_m
                ));
                (
                    v.nominal_circumference_m,
                    v.nominal_circumference_m,
                    v.track_width_m,
                )
            }
        };
        let on: Vec<String> = effects.to_truth_map().into_keys().collect();
        notes.push(format!(
            "effects on: [{}], in their {} forms",
            on.join(", "),
            options.effect_forms.name()
        ));
        Ok(DerivedTwin {
            config: TwinConfig {
                source: options.source.clone(),
                path,
                vehicle: TwinVehicle {
                    c_rl_m,
                    c_rr_m,
                    track_width_m,
                    wheelbase_m: v.wheelbase_m,
                    nominal_circumference_m: v.nominal_circumference_m,
                    antenna: declared,
                },
                sensors,
                gnss_gaps: numbers.gnss_gaps.clone(),
                gnss_stamp_jitter,
                wheel_speed_sigma_rev_s: numbers.wheel_speed_sigma_rev_s,
                claimed_sigma_m: claimed_sigma(fixes),
                effects,
                seed: options.seed,
                step_s,
                effect_forms: options.effect_forms,
                speed_map: options.speed_map.clone(),
                yaw_wander: options.yaw_wander,
            },
            numbers,
            notes,
        })
    }
}

/// The simulator configuration and vehicle of a twin.
fn sim_config(c: &TwinConfig) -> Result<(SimConfig, VehicleSpec), SimError> {
    let v = &c.vehicle;
    for (name, x) in [
        ("c_rl_m", v.c_rl_m),
        ("c_rr_m", v.c_rr_m),
        ("track_width_m", v.track_width_m),
        ("nominal_circumference_m", v.nominal_circumference_m),
    ] {
        if !(x.is_finite() && x > 0.1 && x < 10.0) {
            return Err(SimError::InvalidConfig(format!(
                "twin vehicle: {name} = {x} is not plausible"
            )));
        }
    }
    let mut spec = VehicleKind::Saloon.spec();
    if let Some(l) = v.wheelbase_m {
        if !(l.is_finite() && (0.5..=10.0).contains(&l)) {
            return Err(SimError::InvalidConfig(format!(
                "twin vehicle: wheelbase_m = {l} is not plausible"
            )));
        }
        spec.cg_to_front_m *= l / spec.wheelbase_m;
        spec.wheelbase_m = l;
    }
    spec.track_rear_m = v.track_width_m;
    spec.track_front_m = v.track_width_m;
    let c0 = 0.5 * (v.c_rl_m + v.c_rr_m);
    spec.unworn_circumference_m = c0;
    let wear = |c: f64| (c0 - c) / TAU * 1000.0;
    let mut config = SimConfig::new(Scenario::Mixed, c.seed);
    config.effects = c.effects;
    config.sensors = c.sensors;
    config.step_s = c.step_s;
    config.effect_forms = c.effect_forms;
    config.speed_map = c.speed_map.clone();
    config.yaw_wander = c.yaw_wander;
    config.unworn_circumference_m = Some(c0);
    config.nominal_circumference_m = Some(v.nominal_circumference_m);
    config.wear_mm = WheelWear {
        rl: wear(v.c_rl_m),
        rr: wear(v.c_rr_m),
        fl: 0.0,
        fr: 0.0,
    };
    config.duration_s = Some(c.path.s.len().saturating_sub(1) as f64 * c.path.dt_s);
    Ok((config, spec))
}

/// Simulate the twin: a drive on the recording's clock with its truth.
pub fn simulate_twin(c: &TwinConfig) -> Result<Drive, SimError> {
    let (config, spec) = sim_config(c)?;
    let p = &c.path;
    let n = p.x.len();
    if n < 2 {
        return Err(SimError::InvalidConfig("twin: empty path".into()));
    }
    // The path with a run-out straight beyond its end.
    let (mut x, mut y) = (p.x.clone(), p.y.clone());
    let h = (y[n - 1] - y[n - 2]).atan2(x[n - 1] - x[n - 2]);
    let extra = (RUN_OUT_M / p.ds).ceil() as usize;
    for k in 1..=extra {
        x.push(p.x[n - 1] + k as f64 * p.ds * h.cos());
        y.push(p.y[n - 1] + k as f64 * p.ds * h.sin());
    }
    // v_ref: the recorded speed where the progress first reaches each point.
    let mut v_ref = vec![0.0; x.len()];
    let mut k = 0usize;
    for (i, v) in v_ref.iter_mut().enumerate() {
        let s_i = i as f64 * p.ds;
        while k + 1 < p.s.len() && p.s[k] < s_i {
            k += 1;
        }
        *v = p.v.get(k).copied().unwrap_or(0.0);
    }
    v_ref[0] = p.v.first().copied().unwrap_or(0.0);
    let attrs = Attrs {
        speed: 70.0,
        accel: 3.0,
        decel: 8.0,
        gnss_denied: false,
        ramp: 0.0,
    };
    let grade_mag = c.effects.road_grade.map_or(0.0, |g| g.grade);
    let route = Route::from_points(x, y, v_ref, p.ds, attrs, grade_mag).map_err(|reason| {
        SimError::Route {
            scenario: "twin".into(),
            reason,
        }
    })?;
    let t0 = p.t0_s;
    let custom = Custom {
        route: ScenarioRoute {
            route,
            start_moving: p.v.first().is_some_and(|v| *v > 0.5),
            default_duration_s: None,
        },
        spec,
        prescribed: Some(Prescribed {
            dt: p.dt_s,
            s: p.s.clone(),
            v: p.v.clone(),
            gnss_denied: c
                .gnss_gaps
                .iter()
                .map(|&(a, b)| (a - t0 + 1e-6, b - t0 - 1e-6))
                .collect(),
        }),
        antenna: c.vehicle.antenna,
        name: format!("twin of {}", c.source),
    };
    let mut drive = engine::run_custom(&config, &custom)?;
    shift_times(&mut drive, t0);
    // The receiver's claim is the recording's, not the simulator's.
    for f in drive.gnss.iter_mut().flatten() {
        f.sigma_m = c.claimed_sigma_m;
    }
    // So is its stamps' jitter.
    let jitter_rms = stamp_jitter_rms(&c.gnss_stamp_jitter);
    if let Some(fixes) = drive.gnss.as_mut() {
        restamp(fixes, &c.gnss_stamp_jitter);
    }
    // And its wheels' speed noise, where its wheels are speeds: white on
    // the speed, so a random walk on the revolutions.
    if let Some([sl, sr]) = c.wheel_speed_sigma_rev_s {
        let mut rng = ChaCha8Rng::seed_from_u64(c.seed ^ 0x3ee1_5eed);
        let (mut el, mut er) = (0.0, 0.0);
        let mut last_t = drive.wheels.samples.first().map_or(0.0, |w| w.t_s);
        for w in &mut drive.wheels.samples {
            let dt = w.t_s - last_t;
            last_t = w.t_s;
            let (nl, nr): (f64, f64) = (rng.sample(StandardNormal), rng.sample(StandardNormal));
            el += sl * nl * dt;
            er += sr * nr * dt;
            w.rl += el;
            w.rr += er;
        }
    }
    if let Some(tp) = drive.truth_params.as_mut() {
        tp.extra.remove("scenario");
        tp.extra.remove("vehicle");
        tp.extra
            .insert("twin_of".into(), Value::String(c.source.clone()));
        tp.extra.insert("t0_s".into(), Value::Float(t0));
        tp.extra
            .insert("gnss_stamp_jitter_rms_s".into(), Value::Float(jitter_rms));
        if let Some([l, r]) = c.wheel_speed_sigma_rev_s {
            tp.extra.insert(
                "wheel_speed_sigma_rev_s".into(),
                Value::Array(vec![Value::Float(l), Value::Float(r)]),
            );
        }
    }
    Ok(drive)
}

/// Half-width of the local fits of [`white_from_local_fits`], s: a car's
/// motion over 3 s is a cubic to millimetres, the receiver's noise is not.
const LOCAL_FIT_HALF_S: f64 = 1.5;

/// The GNSS white noise (1 sigma per axis, m) from the fixes alone: each
/// fix against a cubic in time through the other fixes within
/// [`LOCAL_FIT_HALF_S`] (leave-one-out, its variance corrected by the
/// fit's own at that time), the robust spread of these residuals, the two
/// axes averaged. Nothing of the wheels enters: on comma2k19 the twin's
/// path, placed by wheel speeds read off CAN, left 0.019 m about the fixes
/// where the fixes about their own motion hold 0.011 m, and the twin
/// carried twice the recording's residuals. The twin takes the smaller of
/// this and [`white_from_differences`]. `None` for fixes sparser than
/// 4 Hz (over 3 s a turn is no cubic) or fewer than 30 fits.
fn white_from_local_fits(track: &[TrackPoint]) -> Option<f64> {
    let mut dts: Vec<f64> = track.windows(2).map(|w| w[1].t_s - w[0].t_s).collect();
    let step = stats::upper_median(&mut dts)?;
    if !(step > 0.0 && step <= 0.25) {
        return None;
    }
    let (mut rx, mut ry) = (Vec::new(), Vec::new());
    let mut lo = 0;
    for i in 0..track.len() {
        let ti = track[i].t_s;
        while track[lo].t_s < ti - LOCAL_FIT_HALF_S {
            lo += 1;
        }
        // Normal equations of the cubic in (t - ti) / h.
        let h = LOCAL_FIT_HALF_S;
        let mut a = [[0.0_f64; 4]; 4];
        let (mut bx, mut by) = ([0.0_f64; 4], [0.0_f64; 4]);
        let (mut before, mut after) = (0, 0);
        for (j, p) in track.iter().enumerate().skip(lo) {
            if p.t_s > ti + h {
                break;
            }
            if j == i {
                continue;
            }
            if p.t_s < ti {
                before += 1;
            } else {
                after += 1;
            }
            let u = (p.t_s - ti) / h;
            let f = [1.0, u, u * u, u * u * u];
            for r in 0..4 {
                for c in 0..4 {
                    a[r][c] += f[r] * f[c];
                }
                bx[r] += f[r] * p.x_m;
                by[r] += f[r] * p.y_m;
            }
        }
        if before < 4 || after < 4 {
            continue;
        }
        // The fit at ti is the first coefficient; its variance per unit
        // noise variance is the (0, 0) element of the inverse.
        let (Some(cx), Some(cy), Some(e0)) = (
            solve4(a, bx),
            solve4(a, by),
            solve4(a, [1.0, 0.0, 0.0, 0.0]),
        ) else {
            continue;
        };
        let k = (1.0 + e0[0]).sqrt();
        rx.push((track[i].x_m - cx[0]) / k);
        ry.push((track[i].y_m - cy[0]) / k);
    }
    if rx.len() < 30 {
        return None;
    }
    let w = 0.5 * (robust_sigma(&mut rx) + robust_sigma(&mut ry));
    (w.is_finite() && w > 0.0).then_some(w)
}

/// `a x = b` for a symmetric positive 4 x 4 `a` (Gaussian elimination
/// with partial pivoting); `None` when singular.
fn solve4(mut a: [[f64; 4]; 4], mut b: [f64; 4]) -> Option<[f64; 4]> {
    for c in 0..4 {
        let p = (c..4).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs().is_nan() || a[p][c].abs() <= 1e-12 {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        let pivot = a[c];
        for r in c + 1..4 {
            let f = a[r][c] / pivot[c];
            for (x, p) in a[r].iter_mut().zip(&pivot).skip(c) {
                *x -= f * p;
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; 4];
    for r in (0..4).rev() {
        let s: f64 = (r + 1..4).map(|k| a[r][k] * x[k]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    Some(x)
}

/// The GNSS white noise (1 sigma per axis, m) from the fixes' successive
/// differences against the path (the antenna at `antenna` on it): the
/// robust spread of the differences of consecutive residuals over the
/// square root of 2, the two axes averaged. `None` with fewer than 30
/// consecutive pairs.
fn white_from_differences(
    track: &[TrackPoint],
    path: &TwinPath,
    antenna: (f64, f64),
) -> Option<f64> {
    let n = path.x.len();
    if n < 3 || path.s.is_empty() {
        return None;
    }
    let times: Vec<f64> = (0..path.s.len())
        .map(|k| path.t0_s + k as f64 * path.dt_s)
        .collect();
    let at = |t: f64| -> (f64, f64) {
        let a = interp(&times, &path.s, t) / path.ds;
        let i = (a.floor().max(0.0) as usize).min(n - 2);
        let w = (a - i as f64).clamp(0.0, 1.0);
        let (x, y) = (
            path.x[i] + w * (path.x[i + 1] - path.x[i]),
            path.y[i] + w * (path.y[i + 1] - path.y[i]),
        );
        let h = (path.y[i + 1] - path.y[i]).atan2(path.x[i + 1] - path.x[i]);
        let (sh, ch) = h.sin_cos();
        (
            x + ch * antenna.0 - sh * antenna.1,
            y + sh * antenna.0 + ch * antenna.1,
        )
    };
    let mut dts: Vec<f64> = track.windows(2).map(|w| w[1].t_s - w[0].t_s).collect();
    if dts.len() < 30 {
        return None;
    }
    dts.sort_by(f64::total_cmp);
    let step = dts[dts.len() / 2];
    let resid: Vec<(f64, f64, f64)> = track
        .iter()
        .map(|p| {
            let (x, y) = at(p.t_s);
            (p.t_s, p.x_m - x, p.y_m - y)
        })
        .collect();
    let (mut dx, mut dy) = (Vec::new(), Vec::new());
    for w in resid.windows(2) {
        if w[1].0 - w[0].0 <= 1.5 * step {
            dx.push(w[1].1 - w[0].1);
            dy.push(w[1].2 - w[0].2);
        }
    }
    if dx.len() < 30 {
        return None;
    }
    let w = 0.5 * (robust_sigma(&mut dx) + robust_sigma(&mut dy)) / std::f64::consts::SQRT_2;
    (w.is_finite() && w > 0.0).then_some(w)
}

/// Kernel bandwidth along the path over which the gyro's shape yields to
/// the fixes' (heading offset and position), m: the fixes' white noise
/// averages over it to millimetres of curvature, while the gyro's heading
/// drift over it (seconds of driving) stays far below the fixes' own.
pub const GYRO_SHAPE_BANDWIDTH_M: f64 = 25.0;

/// Gaussian smoothing of `v` sampled every `ds` m with bandwidth `h` m
/// (edges renormalised).
fn gauss_smooth(v: &[f64], ds: f64, h: f64) -> Vec<f64> {
    let n = v.len();
    let half = ((3.0 * h / ds).ceil() as usize).max(1);
    let w: Vec<f64> = (0..=half)
        .map(|k| {
            let u = k as f64 * ds / h;
            (-0.5 * u * u).exp()
        })
        .collect();
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(half), (i + half).min(n - 1));
            let (mut num, mut den) = (0.0, 0.0);
            for (j, vj) in v.iter().enumerate().take(b + 1).skip(a) {
                let wk = w[i.abs_diff(j)];
                num += wk * vj;
                den += wk;
            }
            num / den
        })
        .collect()
}

/// The path's short-range shape from the recorded gyro (a heading-domain
/// complementary filter): the gyro's heading (bias removed), mapped onto
/// the path by the progress, takes the path's heading offset from the
/// smoothed fixes over [`GYRO_SHAPE_BANDWIDTH_M`]; the path is
/// dead-reckoned with it and placed on the smoothed fixes over the same
/// bandwidth. The fixes' smoothing alone leaves their white noise as
/// wiggles of a few metres (degrees of heading) that the car did not
/// drive. `gyro`: (t, yaw rate rad/s); `None` where the gyro does not
/// cover the drive.
pub fn gyro_shaped(path: &TwinPath, gyro: &[(f64, f64)], bias_rad_s: f64) -> Option<TwinPath> {
    let n = path.x.len();
    if n < 8 || gyro.len() < 100 {
        return None;
    }
    // The gyro's heading over time, and the path's arc length then.
    let times: Vec<f64> = (0..path.s.len())
        .map(|k| path.t0_s + k as f64 * path.dt_s)
        .collect();
    let (t_first, t_last) = (times[0], times[times.len() - 1]);
    if gyro[0].0 > t_first + 1.0 || gyro[gyro.len() - 1].0 < t_last - 1.0 {
        return None;
    }
    let mut psi = 0.0;
    let mut prev = gyro[0];
    // Per grid point of the path: the heading when the car was there last.
    let mut psi_at: Vec<Option<f64>> = vec![None; n];
    for &(t, w) in gyro {
        if !(t.is_finite() && w.is_finite()) || t <= prev.0 {
            continue;
        }
        psi += 0.5 * (w + prev.1 - 2.0 * bias_rad_s) * (t - prev.0);
        prev = (t, w);
        let a = interp(&times, &path.s, t);
        let i = ((a / path.ds).round() as usize).min(n - 1);
        psi_at[i] = Some(psi);
    }
    // Fill grid points the gyro skipped (fast driving) by interpolation.
    let known: Vec<(usize, f64)> = psi_at
        .iter()
        .enumerate()
        .filter_map(|(i, p)| p.map(|p| (i, p)))
        .collect();
    if known.len() < n / 4 {
        return None;
    }
    let kx: Vec<f64> = known.iter().map(|k| k.0 as f64).collect();
    let ky: Vec<f64> = known.iter().map(|k| k.1).collect();
    let psi_g: Vec<f64> = (0..n).map(|i| interp(&kx, &ky, i as f64)).collect();
    // The smoothed fixes' heading, unwrapped along the path.
    let mut psi_s = Vec::with_capacity(n);
    for i in 0..n {
        let (a, b) = (i.saturating_sub(2), (i + 2).min(n - 1));
        let h = (path.y[b] - path.y[a]).atan2(path.x[b] - path.x[a]);
        let h = match psi_s.last() {
            Some(&last) => last + stats::wrap_angle(h - last),
            None => h,
        };
        psi_s.push(h);
    }
    // The gyro's heading offset, slowly varying: the fixes' over the bandwidth.
    let offset: Vec<f64> = psi_s.iter().zip(&psi_g).map(|(s, g)| s - g).collect();
    let offset = gauss_smooth(&offset, path.ds, GYRO_SHAPE_BANDWIDTH_M);
    let heading: Vec<f64> = psi_g.iter().zip(&offset).map(|(g, o)| g + o).collect();
    // Dead-reckoned on the grid, then placed on the smoothed fixes.
    let (mut x, mut y) = (vec![path.x[0]; n], vec![path.y[0]; n]);
    for i in 1..n {
        let h = 0.5 * (heading[i - 1] + heading[i]);
        x[i] = x[i - 1] + path.ds * h.cos();
        y[i] = y[i - 1] + path.ds * h.sin();
    }
    let ex: Vec<f64> = path.x.iter().zip(&x).map(|(a, b)| a - b).collect();
    let ey: Vec<f64> = path.y.iter().zip(&y).map(|(a, b)| a - b).collect();
    let ex = gauss_smooth(&ex, path.ds, GYRO_SHAPE_BANDWIDTH_M);
    let ey = gauss_smooth(&ey, path.ds, GYRO_SHAPE_BANDWIDTH_M);
    let mut out = path.clone();
    for i in 0..n {
        out.x[i] = x[i] + ex[i];
        out.y[i] = y[i] + ey[i];
    }
    Some(out)
}

/// The median accuracy the fixes claim, if they claim any.
fn claimed_sigma(fixes: &[interfaces::drive::GnssSample]) -> Option<f64> {
    let mut claims: Vec<f64> = fixes
        .iter()
        .filter_map(|f| f.sigma_m)
        .filter(|s| s.is_finite() && *s > 0.0)
        .collect();
    if claims.is_empty() {
        return None;
    }
    claims.sort_by(f64::total_cmp);
    Some(claims[claims.len() / 2])
}

/// Move every sample of `drive` by `dt` seconds (onto the recording's clock).
fn shift_times(drive: &mut Drive, dt: f64) {
    if dt == 0.0 {
        return;
    }
    for s in &mut drive.wheels.samples {
        s.t_s += dt;
    }
    for s in drive.gnss.iter_mut().flatten() {
        s.t_s += dt;
    }
    for s in drive.imu.iter_mut().flatten() {
        s.t_s += dt;
    }
    for s in drive.heading.iter_mut().flatten() {
        s.t_s += dt;
    }
    for s in drive.truth.iter_mut().flatten() {
        s.t_s += dt;
    }
}

/// Apply one finding of a diagnosis (`effect`: catalogue id;
/// `parameters`: name -> value in the diagnosis's reported unit) to
/// `effects`. The reported units are the simulator's (`b_deg_h` in deg/h,
/// heading terms in degrees, the rest SI; see `interfaces::effects`), so
/// values pass unchanged. `road_grade`'s `gain` (the model's gain on the
/// IMU's slope) has no simulated counterpart on a recorded path: it is
/// left out with a note, the road stays level. Returns the notes; an
/// unknown effect or parameter is an error naming it.
pub fn apply_finding(
    effects: &mut EffectSettings,
    effect: &str,
    parameters: &BTreeMap<String, f64>,
) -> Result<Vec<String>, SimError> {
    let ids = || {
        Effect::ALL
            .iter()
            .map(|e| e.id())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let e = Effect::from_id(effect).ok_or_else(|| SimError::InvalidEffect {
        spec: effect.to_string(),
        reason: format!("unknown effect id `{effect}`; known: {}", ids()),
    })?;
    let mut notes = Vec::new();
    let mut set_any = false;
    for (name, &value) in parameters {
        match e.simulated_param(name) {
            // A tyre's stiffness is the knob's inverse: none is a knob at
            // zero, which the mend's clamp to the physical sign can give.
            Some(_)
                if matches!(e, Effect::SideSlip | Effect::LongitudinalSlip) && value == 0.0 =>
            {
                effects.switch_off(e);
                notes.push(format!("{effect}.{name} = {value}: none, the effect off"));
                return Ok(notes);
            }
            Some(p) => {
                effects.set(e, Some(p), value)?;
                set_any = true;
            }
            None if e == Effect::RoadGrade && name == "gain" => notes.push(format!(
                "road_grade: the diagnosis's gain {value} on the IMU's slope has no simulated counterpart on a recorded path; left out (the twin's road is level)"
            )),
            None => {
                let known: Vec<&str> = e.spec().simulated.iter().map(|p| p.spec().name).collect();
                return Err(SimError::InvalidEffect {
                    spec: format!("{effect}.{name}={value}"),
                    reason: format!("unknown parameter `{name}`; known: {}", known.join(", ")),
                });
            }
        }
    }
    if !set_any && parameters.is_empty() {
        effects.switch_on(e);
        notes.push(format!(
            "{effect}: no parameters given, its typical magnitude"
        ));
    }
    Ok(notes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{simulate, SimConfig};

    fn params(pairs: &[(&str, f64)]) -> BTreeMap<String, f64> {
        pairs.iter().map(|(k, v)| (k.to_string(), *v)).collect()
    }

    #[test]
    fn the_progress_takes_the_path_s_stretch_but_not_its_along_track_noise() {
        // A path 2 % longer than the wheels' distance, with a 0.3 m
        // along-track wiggle over 8 m (what a 4 m kernel leaves of the
        // fixes' error).
        let du = 0.25;
        let arc: Vec<f64> = (0..8001)
            .map(|k| {
                let u = k as f64 * du;
                1.02 * u + 0.3 * (std::f64::consts::TAU * u / 8.0).sin()
            })
            .collect();
        let out = progress_arc(&arc, du);
        assert_eq!(out.len(), arc.len());
        assert!(out[0] == arc[0] && (out[8000] - arc[8000]).abs() < 1e-9);
        assert!(out.windows(2).all(|w| w[1] >= w[0]));
        // Away from the ends, its rate is the stretch within 0.1 %; the
        // raw arc's swings by 24 %.
        let rate = |v: &[f64], k: usize| (v[k + 4] - v[k - 4]) / (8.0 * du);
        for k in (1000..7000).step_by(7) {
            assert!(
                (rate(&out, k) / 1.02 - 1.0).abs() < 1e-3,
                "{k}: {}",
                rate(&out, k)
            );
        }
        let swing = (1000..7000)
            .map(|k| (rate(&arc, k) / 1.02 - 1.0).abs())
            .fold(0.0, f64::max);
        assert!(swing > 0.2, "{swing}");
    }

    #[test]
    fn findings_keep_their_reported_units_which_are_the_simulators() {
        let mut e = EffectSettings::none();
        // The diagnosis reports the gyro bias in deg/h (display scale of
        // rad/s), the heading terms in degrees: the simulator's own units.
        apply_finding(&mut e, "gyro_bias", &params(&[("b_deg_h", 3600.0)])).unwrap();
        apply_finding(
            &mut e,
            "heading_bias",
            &params(&[("a_deg", 2.0), ("b_deg", 0.0)]),
        )
        .unwrap();
        apply_finding(&mut e, "track_width", &params(&[("rel", 0.01)])).unwrap();
        apply_finding(
            &mut e,
            "radius_drift",
            &params(&[("d", 0.002), ("time_constant_s", 300.0)]),
        )
        .unwrap();
        assert_eq!(e.gyro_bias.map(|b| b.b_deg_h), Some(3600.0));
        assert_eq!(e.heading_bias.map(|h| (h.a_deg, h.b_deg)), Some((2.0, 0.0)));
        assert_eq!(e.track_width.map(|t| t.rel), Some(0.01));
        assert_eq!(e.radius_drift.map(|d| d.time_constant_s), Some(300.0));
        // 3600 deg/h is 1 deg/s on the gyro: the IMU at standstill shows it.
        let mut c = SimConfig::new(Scenario::Garage, 1);
        c.duration_s = Some(1.0);
        c.effects = EffectSettings::none();
        c.effects.gyro_bias = e.gyro_bias;
        c.sensors.imu.gz_sigma_rad_s = 0.0;
        let d = simulate(&c).unwrap();
        let gz = d.imu.unwrap()[0].gz_rad_s;
        assert!((gz - 1.0f64.to_radians()).abs() < 1e-9, "{gz}");
        // road_grade's gain has no simulated counterpart: a note, level road.
        let notes = apply_finding(&mut e, "road_grade", &params(&[("gain", 1.2)])).unwrap();
        assert_eq!(notes.len(), 1);
        assert!(e.road_grade.is_none());
        assert!(apply_finding(&mut e, "side_slip", &params(&[("k_beta", -0.01)])).is_err());
        // The mend's clamp at the physical sign gives a slip of zero: off.
        apply_finding(&mut e, "longitudinal_slip", &params(&[("k_s", 0.004)])).unwrap();
        let notes = apply_finding(&mut e, "longitudinal_slip", &params(&[("k_s", 0.0)])).unwrap();
        assert!(e.longitudinal_slip.is_none(), "{notes:?}");
        assert!(notes[0].contains("off"), "{notes:?}");
        assert!(apply_finding(&mut e, "nope", &params(&[])).is_err());
    }
}
