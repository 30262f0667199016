//! Layer 1: the reference poses `r_k = [x~, y~, theta~]` and the side-slip
//! estimate (paper section 3.1).
//!
//! - Position: a Kalman filter on `p'' = a` per axis (white-noise
//!   acceleration; the IMU's accelerations rotated into ENU as the input in the
//!   second pass), GNSS fixes as measurements with an innovation gate, then a
//!   Rauch-Tung-Striebel smoother (the method is off-line, so the reference
//!   may use the future too). Between fixes the smoothed states are joined by
//!   cubic Hermite curves (the smoothed mean of that model). The antenna lever
//!   arm is removed with the reference heading.
//! - Heading: an extended Kalman filter on `[theta, gyro bias, gyro scale]`
//!   driven by the yaw-rate gyro,
//!   corrected by the GNSS course (from the smoothed velocity, corrected for
//!   the lever arm; weighted down in corners where side-slip separates course
//!   and heading) and by an absolute heading when the drive has one; smoothed.
//! - Side-slip: beta = course - heading, filtered as a first-order Markov
//!   process (Bevly et al.); also summarised as a gain beta = -k a_y.
//! - The wheel/GNSS time offset comes with the aligned streams
//!   ([`crate::clocks::gnss`]: the fixes' noise, the fixes smoothed alone,
//!   the offset found and optionally compensated); the reference starts
//!   from those fixes and that smoothed track.
//!
//! Everything is produced at the wheel sample times, with a validity flag
//! that is false in GNSS outages longer than `max_gnss_gap_s`.

pub mod gnss_jumps;

use crate::clocks::offsets::{PairOffset, StreamOffset};
use crate::clocks::Aligned;
use crate::config::CalibrationConfig;
use crate::error::CalibrationError;
use crate::series::Series;
use crate::smoother::{
    smooth_positions, Input, PosTrack, COURSE_MIN_SPEED, Q_ACCEL_FREE, Q_ACCEL_IMU,
};
use crate::warnings::{Warning, WarningCode};
use gnss_jumps::{Jump, JumpSearch};
use interfaces::drive::{Drive, ImuSample};
use nalgebra::{Matrix3, Vector3};
use vehicle_model::two_wheel::wrap_angle;

pub use crate::clocks::gnss::{SigmaClaim, TimeOffset, CLAIM_FACTOR, CLAIM_MIN_DIFFERENCES};
pub use crate::smoother::RefFix;

/// The least distance with GNSS reference a calibration needs, m (the
/// fits' own minimum, `lm`).
const MIN_REFERENCE_M: f64 = 50.0;
/// Largest variance of a usable GNSS course, rad^2 (0.2 rad).
const COURSE_MAX_VAR: f64 = 0.04;

/// The layer-1 output at the wheel sample times.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// Rear-axle centre east, m.
    pub x: Vec<f64>,
    /// Rear-axle centre north, m.
    pub y: Vec<f64>,
    /// Heading, rad, unwrapped (continuous).
    pub yaw: Vec<f64>,
    /// Side-slip angle, rad (0 where not estimated); empty unless side-slip
    /// is switched on and the drive has a gyro.
    pub beta: Vec<f64>,
    /// True where a GNSS fix is close enough for the reference to be trusted.
    pub valid: Vec<bool>,
    /// The GNSS fixes with their sigma and gate decision.
    pub fixes: Vec<RefFix>,
    /// The GNSS 1-sigma used for fixes without their own, m.
    pub gnss_sigma_m: f64,
    /// True when `gnss_sigma_m` was estimated from the fixes.
    pub gnss_sigma_estimated: bool,
    /// The receiver's claimed sigma when the fixes' scatter refuted it
    /// (then `gnss_sigma_m` is the scatter).
    pub gnss_sigma_claim: Option<SigmaClaim>,
    /// Fixes rejected by the gate.
    pub outliers: usize,
    /// GNSS jumps found against the wheels and set aside.
    pub jumps: Vec<gnss_jumps::Jump>,
    /// The wheel/GNSS time offset, when checked and determinable.
    pub time_offset: Option<TimeOffset>,
    /// The GNSS clock offset against the wheels, determined or not (and
    /// why): every pair of streams combined ([`crate::clocks::offsets::solve_offsets`]).
    pub gnss_clock: StreamOffset,
    /// The pairs of streams compared for it.
    pub clock_pairs: Vec<PairOffset>,
    /// Side-slip gain k in beta = -k a_y, rad per m/s^2, when estimated.
    pub side_slip_gain: Option<f64>,
    /// Mean gyro bias of the heading filter, rad/s.
    pub heading_filter_gyro_bias: Option<f64>,
    /// Distance driven where the reference is valid (nominal circumference), m.
    pub distance_m: f64,
    /// Total absolute heading change where valid, rad.
    pub total_turn_rad: f64,
    /// Number of GNSS outages (gaps longer than `max_gnss_gap_s` inside the drive).
    pub outages: usize,
}

/// The heading reference at the epochs and between them.
struct HeadingTrack {
    t: Vec<f64>,
    yaw: Vec<f64>,
    bias: Vec<f64>,
    /// Gyro scale error s (`omega_gyro = (1 + s) omega + b`).
    scale: Vec<f64>,
    /// The gyro's cumulative angle at each epoch (NaN where not covered).
    gyro: Vec<f64>,
}

/// One heading measurement: time, value (rad), variance (rad^2).
#[derive(Clone, Copy)]
struct HeadingMeas {
    t: f64,
    z: f64,
    var: f64,
}

/// Heading transition over one interval: the gyro's angle increment `dg`
/// (None: no gyro there) turned into heading with the bias and scale states.
fn heading_step(x: &Vector3<f64>, dg: Option<f64>, tt: f64) -> (Vector3<f64>, Matrix3<f64>) {
    match dg {
        Some(dg) => {
            let (b, s) = (x[1], x[2]);
            let num = dg - b * tt;
            let mut f = Matrix3::identity();
            f[(0, 1)] = -tt / (1.0 + s);
            f[(0, 2)] = -num / ((1.0 + s) * (1.0 + s));
            (Vector3::new(x[0] + num / (1.0 + s), b, s), f)
        }
        None => (*x, Matrix3::identity()),
    }
}

/// Extended Kalman filter + RTS smoother on `[theta, gyro bias, gyro scale]`,
/// driven by the gyro, corrected by the heading measurements.
fn heading_filter(
    meas: &[HeadingMeas],
    p: &Series,
    bias0: f64,
) -> Result<HeadingTrack, CalibrationError> {
    let n = meas.len();
    let q_theta = 2.5e-7; // (5e-4 rad/sqrt(s))^2, gyro angle random walk
    let q_bias = 1e-10; // bias random walk, (rad/s)^2/s
    let q_scale = 1e-9; // scale random walk, 1/s
    let q_free = 0.25; // heading random walk without gyro, rad^2/s
    let mut xf: Vec<Vector3<f64>> = Vec::with_capacity(n);
    let mut pf: Vec<Matrix3<f64>> = Vec::with_capacity(n);
    let mut pp: Vec<Matrix3<f64>> = Vec::with_capacity(n);
    let mut inc: Vec<Option<f64>> = Vec::with_capacity(n);
    for j in 0..n {
        if j == 0 {
            xf.push(Vector3::new(meas[0].z, bias0, 0.0));
            let c = Matrix3::from_diagonal(&Vector3::new(meas[0].var, 1e-4, 4e-4));
            pf.push(c);
            pp.push(c);
            inc.push(None);
            continue;
        }
        let tt = meas[j].t - meas[j - 1].t;
        let dg = p.gyro_mean_rate(meas[j - 1].t, meas[j].t).map(|w| w * tt);
        inc.push(dg);
        let (xp, f) = heading_step(&xf[j - 1], dg, tt);
        let q = Matrix3::from_diagonal(&Vector3::new(
            if dg.is_some() {
                q_theta * tt
            } else {
                q_free * tt
            },
            q_bias * tt,
            q_scale * tt,
        ));
        let pred = f * pf[j - 1] * f.transpose() + q;
        pp.push(pred);
        let m = meas[j];
        let nu = wrap_angle(m.z - xp[0]);
        let s = pred[(0, 0)] + m.var;
        if nu * nu / s > 25.0 {
            xf.push(xp);
            pf.push(pred);
            continue;
        }
        let k = pred.column(0) / s;
        xf.push(xp + k * nu);
        let upd = pred - k * pred.row(0);
        pf.push(0.5 * (upd + upd.transpose()));
    }
    // Rauch-Tung-Striebel, in place: step j reads the filtered values at j
    // before overwriting them.
    let mut xs = xf;
    let mut ps = pf;
    for j in (0..n.saturating_sub(1)).rev() {
        let tt = meas[j + 1].t - meas[j].t;
        let (xp, f) = heading_step(&xs[j], inc[j + 1], tt);
        let Some(inv) = pp[j + 1].try_inverse() else {
            return Err(CalibrationError::Numerical {
                stage: "reference heading smoother",
                detail: format!(
                    "predicted covariance singular at t = {:.3} s",
                    meas[j + 1].t
                ),
            });
        };
        let c = ps[j] * f.transpose() * inv;
        let x_next = xs[j + 1];
        let p_next = ps[j + 1];
        xs[j] += c * (x_next - xp);
        ps[j] += c * (p_next - pp[j + 1]) * c.transpose();
    }
    if xs.iter().any(|s| !s.iter().all(|v| v.is_finite())) {
        return Err(CalibrationError::Numerical {
            stage: "reference heading smoother",
            detail: "non-finite smoothed heading".to_string(),
        });
    }
    Ok(HeadingTrack {
        t: meas.iter().map(|m| m.t).collect(),
        yaw: xs.iter().map(|s| s[0]).collect(),
        bias: xs.iter().map(|s| s[1]).collect(),
        scale: xs.iter().map(|s| s[2]).collect(),
        gyro: meas
            .iter()
            .map(|m| p.gyro_cum_at(m.t).unwrap_or(f64::NAN))
            .collect(),
    })
}

impl HeadingTrack {
    /// Heading change from the gyro between epoch `j` and a point with gyro
    /// angle `g`, `dt` later, corrected by epoch j's bias and scale.
    fn turned(&self, j: usize, g: f64, dt: f64) -> f64 {
        ((g - self.gyro[j]) - self.bias[j] * dt) / (1.0 + self.scale[j])
    }

    /// Heading at `t` given the gyro's cumulative angle `g_t` there (NaN when
    /// not covered), with the closing error between epochs spread linearly.
    fn at(&self, t: f64, g_t: f64, cursor: &mut usize) -> f64 {
        let n = self.t.len();
        if n == 1 {
            return self.yaw[0];
        }
        while *cursor + 1 < n && self.t[*cursor + 1] <= t {
            *cursor += 1;
        }
        let j = *cursor;
        let has = |j: usize| self.gyro[j].is_finite() && g_t.is_finite();
        if t <= self.t[0] {
            return if has(0) {
                self.yaw[0] + self.turned(0, g_t, t - self.t[0])
            } else {
                self.yaw[0]
            };
        }
        if j + 1 >= n {
            return if has(n - 1) {
                self.yaw[n - 1] + self.turned(n - 1, g_t, t - self.t[n - 1])
            } else {
                self.yaw[n - 1]
            };
        }
        let (t0, t1) = (self.t[j], self.t[j + 1]);
        let f = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
        if has(j) && self.gyro[j + 1].is_finite() {
            let part = self.turned(j, g_t, t - t0);
            let whole = self.turned(j, self.gyro[j + 1], t1 - t0);
            let closure = self.yaw[j + 1] - self.yaw[j] - whole;
            self.yaw[j] + part + f * closure
        } else {
            self.yaw[j] + f * (self.yaw[j + 1] - self.yaw[j])
        }
    }
}

/// The GNSS course measurements (with the speed) from the smoothed track
/// and the heading filter run on them (plus any absolute heading).
#[allow(clippy::type_complexity)]
fn course_and_heading(
    p: &Series,
    pass1: &PosTrack,
) -> Result<(Vec<(HeadingMeas, f64)>, HeadingTrack), CalibrationError> {
    let omega_at = |t: f64| p.gyro_mean_rate(t - 0.1, t + 0.1);
    let [lx, ly] = p.lever_arm;
    let mut course_meas: Vec<(HeadingMeas, f64)> = Vec::new(); // with speed
                                                               // Fixes whose course is not used: rejected, slow, uncertain, reversing.
    let mut skipped = [0usize; 4];
    for j in 0..pass1.t.len() {
        if !pass1.accepted[j] {
            skipped[0] += 1;
            continue;
        }
        let s = pass1.s[j];
        let v = (s[2] * s[2] + s[3] * s[3]).sqrt();
        if v < COURSE_MIN_SPEED {
            skipped[1] += 1;
            continue;
        }
        let var_c = pass1.cov[j].vv / (v * v);
        if var_c > COURSE_MAX_VAR {
            skipped[2] += 1;
            continue;
        }
        if reversing(p, pass1.t[j]) {
            // Reversing, the course points backwards: not a heading.
            skipped[3] += 1;
            continue;
        }
        let w = omega_at(pass1.t[j]).unwrap_or(0.0);
        let lever = (w * lx).atan2(v - w * ly);
        let ay = v * w;
        let sig_beta = 0.002 + 0.004 * ay.abs();
        course_meas.push((
            HeadingMeas {
                t: pass1.t[j],
                z: s[3].atan2(s[2]) - lever,
                var: var_c + sig_beta * sig_beta,
            },
            v,
        ));
    }
    let mut meas: Vec<HeadingMeas> = course_meas.iter().map(|m| m.0).collect();
    for h in &p.headings {
        let s = h.sigma_rad.unwrap_or(0.05);
        meas.push(HeadingMeas {
            t: h.t_s,
            z: h.yaw_rad,
            var: s * s,
        });
    }
    meas.sort_by(|a, b| a.t.total_cmp(&b.t));
    meas.dedup_by(|b, a| b.t <= a.t);
    if meas.len() < 2 {
        let speed_sigma = |j: usize| pass1.cov[j].vv.max(0.0).sqrt();
        let mut sv: Vec<f64> = (0..pass1.t.len())
            .filter(|&j| pass1.accepted[j])
            .map(speed_sigma)
            .collect();
        let median_sv = stats::upper_median(&mut sv).unwrap_or(f64::NAN);
        return Err(CalibrationError::NoCourse {
            detail: format!(
                "of {} GNSS fixes, {} were rejected as outliers, {} are slower than {COURSE_MIN_SPEED:.1} m/s, {} have a course sigma above {:.2} rad (the smoothed GNSS velocity's sigma, median {median_sv:.2} m/s, is too large against the speed: noisy fixes or gaps), {} are while reversing; {} course(s) and {} absolute heading(s) are left, at least 2 are needed",
                pass1.t.len(),
                skipped[0],
                skipped[1],
                skipped[2],
                COURSE_MAX_VAR.sqrt(),
                skipped[3],
                course_meas.len(),
                p.headings.len(),
            ),
        });
    }
    let bias0 = crate::series::standstill_gyro_bias(p).map_or(0.0, |b| b.0);
    let heading = heading_filter(&meas, p, bias0)?;
    Ok((course_meas, heading))
}

/// True when the wheels turn backwards around `t` (+-0.1 s).
fn reversing(p: &Series, t: f64) -> bool {
    let (a, b) = (
        p.t.partition_point(|&s| s < t - 0.1),
        p.t.partition_point(|&s| s <= t + 0.1),
    );
    let sum: f64 = (a..b.min(p.len()))
        .filter(|&k| !p.is_piece_start(k))
        .map(|k| p.dn_rl[k] + p.dn_rr[k])
        .sum();
    sum < 0.0
}

/// [`gnss_jumps::find`] on the fixes against the wheels' dead-reckoning
/// (nominal circumference, the reference heading, the lever arm).
fn find_jumps(p: &Series, fixes: &[RefFix], heading: &HeadingTrack) -> JumpSearch {
    let n = p.len();
    if n < 2 {
        return JumpSearch::default();
    }
    let mut cursor = 0usize;
    let yaw: Vec<f64> = (0..n)
        .map(|k| {
            let g = p.gyro.as_ref().map_or(f64::NAN, |g| g[k]);
            heading.at(p.t[k], g, &mut cursor)
        })
        .collect();
    let [lx, ly] = p.lever_arm;
    let mut piece = vec![0usize; n];
    let mut ant = vec![[0.0; 2]; n];
    let mut pos = [0.0f64; 2];
    for k in 0..n {
        if k > 0 {
            piece[k] = piece[k - 1] + usize::from(p.is_piece_start(k));
            if !p.is_piece_start(k) {
                let ds = 0.5 * (p.dn_rl[k] + p.dn_rr[k]) * p.nominal_c;
                let th = 0.5 * (yaw[k - 1] + yaw[k]);
                pos[0] += ds * th.cos();
                pos[1] += ds * th.sin();
            }
        }
        let (s, c) = yaw[k].sin_cos();
        ant[k] = [pos[0] + c * lx - s * ly, pos[1] + s * lx + c * ly];
    }
    let dr_at = |t: f64| -> Option<(usize, [f64; 2])> {
        if !(t >= p.t[0] && t <= p.t[n - 1]) {
            return None;
        }
        let i = p.t.partition_point(|&s| s <= t).clamp(1, n - 1);
        if piece[i] != piece[i - 1] {
            return None;
        }
        let h = p.t[i] - p.t[i - 1];
        let w = if h > 0.0 { (t - p.t[i - 1]) / h } else { 0.0 };
        let (a, b) = (ant[i - 1], ant[i]);
        Some((
            piece[i],
            [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1])],
        ))
    };
    let t: Vec<f64> = fixes.iter().map(|f| f.t).collect();
    let xy: Vec<[f64; 2]> = fixes.iter().map(|f| [f.x, f.y]).collect();
    gnss_jumps::find(&t, &xy, &dr_at)
}

/// Build the reference for the aligned drive (its drive is read only for
/// the IMU accelerations, which are not copied).
pub fn build(
    a: &Aligned<'_>,
    config: &CalibrationConfig,
    warnings: &mut Vec<Warning>,
) -> Result<Reference, CalibrationError> {
    let p = &a.series;
    let drive: &Drive = &a.drive;
    // The GNSS on the wheels' clock (stage 2): its noise, the fixes with
    // their sigmas, smoothed alone, the clock offset applied.
    let g = &a.gnss;
    let (gnss_sigma_m, estimated, claim) = (g.sigma_m, g.sigma_estimated, g.claim);
    let mut fixes = g.fixes.clone();
    let gate = config.outlier_gate_sigma;
    let gyro = p.gyro.as_ref();
    let Screened {
        course_meas,
        heading,
        jumps,
        outliers,
        set_aside_count,
    } = screen_fixes(p, &mut fixes, &g.antenna, g.alone.clone(), gate, warnings)?;
    let (side_slip_gain, beta_track) = side_slip(p, &course_meas, &heading, config, warnings);
    let pass2 = smooth_axle(p, drive, &fixes, &heading, &jumps, config)?;

    // Everything at the wheel times.
    let acc_t: Vec<f64> = fixes.iter().filter(|f| f.accepted).map(|f| f.t).collect();
    let want_beta = config.side_slip && gyro.is_some();
    let AtWheels {
        x,
        y,
        yaw,
        beta,
        valid,
    } = at_wheel_times(
        p,
        &pass2,
        &heading,
        beta_track.as_ref(),
        &acc_t,
        want_beta,
        config.max_gnss_gap_s,
    )?;
    let outages = warn_outages(&acc_t, config.max_gnss_gap_s, warnings);
    let bridged = bridged(&p.t, &valid, &jumps.jumps);
    let (distance_m, total_turn_rad) = motion_summary(p, &yaw, &bridged);
    check_distance(
        p,
        distance_m,
        &acc_t,
        config.max_gnss_gap_s,
        fixes.len(),
        outliers,
        set_aside_count,
    )?;
    let heading_filter_gyro_bias =
        gyro.map(|_| heading.bias.iter().sum::<f64>() / heading.bias.len() as f64);
    Ok(Reference {
        x,
        y,
        yaw,
        beta,
        valid,
        fixes,
        gnss_sigma_m,
        gnss_sigma_estimated: estimated,
        gnss_sigma_claim: claim,
        outliers,
        jumps: jumps.jumps,
        time_offset: g.time_offset,
        gnss_clock: g.clock.clone(),
        clock_pairs: g.pairs.clone(),
        side_slip_gain,
        heading_filter_gyro_bias,
        distance_m,
        total_turn_rad,
        outages,
    })
}

/// The GNSS fixes screened: the course measurements and the heading on
/// them, the jumps found against the wheels, the outliers.
struct Screened {
    /// The GNSS course measurements with the speed.
    course_meas: Vec<(HeadingMeas, f64)>,
    /// The heading filter's track.
    heading: HeadingTrack,
    /// The jumps of more than one fix, and the fixes set aside.
    jumps: JumpSearch,
    /// Fixes rejected as outliers (not counting those set aside in jumps).
    outliers: usize,
    /// Fixes set aside in jumps of more than one fix.
    set_aside_count: usize,
}

/// Screen the fixes: the course and heading on the fixes smoothed alone
/// (`pass1`), the GNSS jumps against the wheels' dead-reckoning on that
/// heading set aside (then the course and the heading again without them),
/// each fix's `accepted` set, too few usable fixes refused, and the jump
/// and outlier warnings.
fn screen_fixes(
    p: &Series,
    fixes: &mut [RefFix],
    antenna: &[[f64; 2]],
    mut pass1: PosTrack,
    gate: f64,
    warnings: &mut Vec<Warning>,
) -> Result<Screened, CalibrationError> {
    // Heading: gyro + GNSS course (+ absolute heading).
    let (mut course_meas, mut heading) = course_and_heading(p, &pass1)?;

    // GNSS jumps, against the wheels' dead-reckoning on that heading: set
    // aside, then the course and the heading again without them.
    let mut jumps = find_jumps(p, fixes, &heading);
    // A jump of one fix is an outlier (counted with the gate's).
    let single_fix = jumps.jumps.iter().filter(|j| j.fixes == 1).count();
    jumps.jumps.retain(|j| j.fixes > 1);
    if jumps.set_aside.iter().any(|a| *a) {
        pass1 = smooth_positions(
            fixes,
            antenna,
            Q_ACCEL_FREE,
            gate,
            None,
            Some(&jumps.set_aside),
        )?;
        (course_meas, heading) = course_and_heading(p, &pass1)?;
    }
    if !jumps.jumps.is_empty() {
        let total: usize = jumps.jumps.iter().map(|j| j.fixes).sum();
        let largest = jumps.jumps.iter().map(|j| j.size_m).fold(0.0, f64::max);
        let first = jumps.jumps[0];
        warnings.push(Warning::new(
            WarningCode::GnssJumps,
            format!(
                "gnss: {} jump(s) set aside ({total} fixes; largest {largest:.2} m; first from t = {:.1} to {:.1} s): the fixes stepped off the wheels' track by more than {:.0} sigma ({:.3} m measured on this drive) and back",
                jumps.jumps.len(),
                first.t_start,
                first.t_end,
                crate::reference::gnss_jumps::EDGE_SIGMAS,
                jumps.sigma_e_m.unwrap_or(f64::NAN),
            ),
        ));
    }

    let set_aside_count = jumps.set_aside.iter().filter(|a| **a).count() - single_fix;
    let outliers = pass1.accepted.iter().filter(|a| !**a).count() - set_aside_count;
    for (f, a) in fixes.iter_mut().zip(&pass1.accepted) {
        f.accepted = *a;
    }
    let usable = fixes.iter().filter(|f| f.accepted).count();
    if usable < 10 {
        return Err(CalibrationError::TooFewGnss {
            usable,
            total: p.fixes.len(),
            detail: format!(
                ", {outliers} rejected as outliers, {set_aside_count} set aside in jumps"
            ),
            needed: 10,
        });
    }
    if outliers > 0 {
        let first = fixes.iter().find(|f| !f.accepted).map_or(f64::NAN, |f| f.t);
        warnings.push(Warning::new(
            WarningCode::GnssOutliers,
            format!(
                "gnss: {outliers} of {} fixes rejected as outliers (innovation beyond {gate:.1} sigma, or alone off the wheels' track; first at t = {first:.2} s)",
                fixes.len()
            ),
        ));
    }
    Ok(Screened {
        course_meas,
        heading,
        jumps,
        outliers,
        set_aside_count,
    })
}

/// Side-slip at the course epochs: course - heading, Markov-filtered
/// (nothing without a gyro), and the side-slip gain against the lateral
/// acceleration (when it was excited enough). Warns when side-slip is
/// asked for without a gyro.
fn side_slip(
    p: &Series,
    course_meas: &[(HeadingMeas, f64)],
    heading: &HeadingTrack,
    config: &CalibrationConfig,
    warnings: &mut Vec<Warning>,
) -> (Option<f64>, Option<SlipTrack>) {
    let gyro = p.gyro.as_ref();
    let omega_at = |t: f64| p.gyro_mean_rate(t - 0.1, t + 0.1);
    let mut slip_t = Vec::new();
    let mut slip_z = Vec::new();
    let mut slip_var = Vec::new();
    let mut cursor = 0usize;
    let (mut s_aa, mut s_ab) = (0.0, 0.0);
    if gyro.is_some() {
        for (m, v) in course_meas {
            let g_t = p.gyro_cum_at(m.t).unwrap_or(f64::NAN);
            let th = heading.at(m.t, g_t, &mut cursor);
            let b = wrap_angle(m.z - th);
            slip_t.push(m.t);
            slip_z.push(b);
            slip_var.push(m.var.min(0.01));
            if let Some(w) = omega_at(m.t) {
                let ay = v * w;
                s_aa += ay * ay;
                s_ab += ay * b;
            }
        }
    }
    let side_slip_gain = (s_aa > 50.0).then(|| -s_ab / s_aa);
    let beta_track = smooth_side_slip(&slip_t, &slip_z, &slip_var);
    if config.side_slip && gyro.is_none() {
        warnings.push(Warning::new(
            WarningCode::SideSlipUnavailable,
            "side-slip needs a yaw-rate gyro (imu.csv gz_rad_s): running with beta = 0".to_string(),
        ));
    }
    (side_slip_gain, beta_track)
}

/// Pass 2 of the position smoother: the lever arm removed with the
/// heading, the IMU accelerations as input (when used), the jumps' fixes
/// set aside.
fn smooth_axle(
    p: &Series,
    drive: &Drive,
    fixes: &[RefFix],
    heading: &HeadingTrack,
    jumps: &JumpSearch,
    config: &CalibrationConfig,
) -> Result<PosTrack, CalibrationError> {
    let [lx, ly] = p.lever_arm;
    let mut hcur = 0usize;
    let axle: Vec<[f64; 2]> = fixes
        .iter()
        .map(|f| {
            let g_t = p.gyro_cum_at(f.t).unwrap_or(f64::NAN);
            let th = heading.at(f.t, g_t, &mut hcur);
            let (s, c) = th.sin_cos();
            [f.x - (c * lx - s * ly), f.y - (s * lx + c * ly)]
        })
        .collect();
    let use_accel = config.use_imu_acceleration && p.has_accel;
    let inputs = if use_accel {
        Some(accel_inputs(fixes, p, drive, heading))
    } else {
        None
    };
    smooth_positions(
        fixes,
        &axle,
        if use_accel { Q_ACCEL_IMU } else { Q_ACCEL_FREE },
        config.outlier_gate_sigma,
        inputs.as_deref(),
        jumps
            .set_aside
            .iter()
            .any(|a| *a)
            .then_some(jumps.set_aside.as_slice()),
    )
}

/// The reference sampled at the wheel times.
struct AtWheels {
    x: Vec<f64>,
    y: Vec<f64>,
    yaw: Vec<f64>,
    beta: Vec<f64>,
    valid: Vec<bool>,
}

/// Sample the smoothed position, the heading and (when wanted) the
/// side-slip at each wheel time, and mark where the accepted fixes
/// (`acc_t`) are close enough for a reference. Refuses a non-finite pose.
fn at_wheel_times(
    p: &Series,
    pass2: &PosTrack,
    heading: &HeadingTrack,
    beta_track: Option<&SlipTrack>,
    acc_t: &[f64],
    want_beta: bool,
    max_gnss_gap_s: f64,
) -> Result<AtWheels, CalibrationError> {
    let n = p.len();
    let mut x = Vec::with_capacity(n);
    let mut y = Vec::with_capacity(n);
    let mut yaw = Vec::with_capacity(n);
    let mut beta = Vec::with_capacity(if want_beta { n } else { 0 });
    let mut valid = Vec::with_capacity(n);
    let mut j = 0usize;
    let mut a = 0usize;
    let mut hc = 0usize;
    let mut bc = 0usize;
    let half = 0.5 * max_gnss_gap_s;
    for k in 0..n {
        let t = p.t[k];
        while j + 1 < pass2.t.len() && pass2.t[j + 1] <= t {
            j += 1;
        }
        let s = pass2.at(j, t);
        x.push(s[0]);
        y.push(s[1]);
        let g_t = p.gyro.as_ref().map_or(f64::NAN, |g| g[k]);
        yaw.push(heading.at(t, g_t, &mut hc));
        if want_beta {
            beta.push(beta_track.map_or(0.0, |b| b.at(t, &mut bc)));
        }
        while a + 1 < acc_t.len() && acc_t[a + 1] <= t {
            a += 1;
        }
        let ok = if t < acc_t[0] {
            acc_t[0] - t <= half.min(0.5)
        } else if a + 1 >= acc_t.len() {
            t - acc_t[a] <= half.min(0.5)
        } else {
            acc_t[a + 1] - acc_t[a] <= max_gnss_gap_s
        };
        valid.push(ok);
    }
    if yaw.iter().any(|v| !v.is_finite()) || x.iter().any(|v| !v.is_finite()) {
        return Err(CalibrationError::Numerical {
            stage: "reference interpolation",
            detail: "non-finite reference pose".to_string(),
        });
    }
    Ok(AtWheels {
        x,
        y,
        yaw,
        beta,
        valid,
    })
}

/// The GNSS outages (gaps between accepted fixes longer than
/// `max_gnss_gap_s`), counted; warns of them with the longest.
fn warn_outages(acc_t: &[f64], max_gnss_gap_s: f64, warnings: &mut Vec<Warning>) -> usize {
    let outages = acc_t
        .windows(2)
        .filter(|w| w[1] - w[0] > max_gnss_gap_s)
        .count();
    if outages > 0 {
        let longest = acc_t
            .windows(2)
            .map(|w| (w[1] - w[0], w[0]))
            .fold((0.0, 0.0), |m, v| if v.0 > m.0 { v } else { m });
        warnings.push(Warning::new(
            WarningCode::GnssOutage,
            format!(
                "gnss: {outages} outage(s) longer than {:.1} s (longest {:.1} s at t = {:.1} s): no reference there, the model bridges them",
                max_gnss_gap_s, longest.0, longest.1
            ),
        ));
    }
    outages
}

/// Where the motion counts as observed: the valid reference, and the jumps
/// set aside, which are bridged by fixes on both sides (the fits' segments
/// run through them), unlike an outage.
fn bridged(t: &[f64], valid: &[bool], jumps: &[Jump]) -> Vec<bool> {
    if jumps.is_empty() {
        valid.to_vec()
    } else {
        let mut j = 0usize;
        t.iter()
            .zip(valid)
            .map(|(&t, &v)| {
                while j < jumps.len() && jumps[j].t_end < t {
                    j += 1;
                }
                v || jumps
                    .get(j)
                    .is_some_and(|jp| t >= jp.t_start && t <= jp.t_end)
            })
            .collect()
    }
}

/// Refuse a reference shorter than [`MIN_REFERENCE_M`] when the wheels
/// went that far, with why: of the `fixes` GNSS fixes, how many were
/// rejected as outliers, set aside in jumps, and left (`acc_t`).
fn check_distance(
    p: &Series,
    distance_m: f64,
    acc_t: &[f64],
    max_gnss_gap_s: f64,
    fixes: usize,
    outliers: usize,
    set_aside_count: usize,
) -> Result<(), CalibrationError> {
    let n = p.len();
    let wheel_distance_m: f64 = (0..n)
        .map(|k| 0.5 * (p.dn_rl[k] + p.dn_rr[k]).abs() * p.nominal_c)
        .sum();
    if distance_m < MIN_REFERENCE_M && wheel_distance_m >= MIN_REFERENCE_M {
        let mut gaps: Vec<f64> = acc_t.windows(2).map(|w| w[1] - w[0]).collect();
        let median_gap = stats::upper_median(&mut gaps).unwrap_or(f64::NAN);
        let hint = if median_gap > max_gnss_gap_s {
            format!(
                "the accepted fixes are a median {median_gap:.1} s apart, more than max_gnss_gap_s ({:.1} s): every interval counts as an outage (raise max_gnss_gap_s if the receiver logs this slowly)",
                max_gnss_gap_s
            )
        } else {
            format!(
                "the accepted fixes are a median {median_gap:.1} s apart, but not where the car moves"
            )
        };
        return Err(CalibrationError::ReferenceTooShort {
            distance_m,
            wheel_distance_m,
            needed_m: MIN_REFERENCE_M,
            detail: format!(
                "of {fixes} GNSS fixes, {outliers} were rejected as outliers and {set_aside_count} set aside in jumps; {} are left and {hint}",
                acc_t.len()
            ),
        });
    }
    Ok(())
}

/// Distance and absolute turning where the reference is valid (heading
/// sampled once per second so that noise does not add up).
fn motion_summary(p: &Series, yaw: &[f64], valid: &[bool]) -> (f64, f64) {
    let mut dist = 0.0;
    let mut turn = 0.0;
    let mut last: Option<(f64, f64)> = None;
    for k in 0..p.len() {
        if !valid[k] {
            last = None;
            continue;
        }
        dist += 0.5 * (p.dn_rl[k] + p.dn_rr[k]).abs() * p.nominal_c;
        match last {
            None => last = Some((p.t[k], yaw[k])),
            Some((t0, y0)) if p.t[k] - t0 >= 1.0 => {
                turn += (yaw[k] - y0).abs();
                last = Some((p.t[k], yaw[k]));
            }
            _ => {}
        }
    }
    (dist, turn)
}

/// Smoothed side-slip angle at the course epochs.
struct SlipTrack {
    t: Vec<f64>,
    beta: Vec<f64>,
}

impl SlipTrack {
    fn at(&self, t: f64, cursor: &mut usize) -> f64 {
        let n = self.t.len();
        if n == 0 || t < self.t[0] - 0.5 || t > self.t[n - 1] + 0.5 {
            return 0.0;
        }
        while *cursor + 1 < n && self.t[*cursor + 1] <= t {
            *cursor += 1;
        }
        let j = *cursor;
        if t <= self.t[0] {
            return self.beta[0];
        }
        if j + 1 >= n {
            return self.beta[n - 1];
        }
        let (t0, t1) = (self.t[j], self.t[j + 1]);
        if t1 - t0 > 2.0 {
            return 0.0;
        }
        let f = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
        self.beta[j] + f * (self.beta[j + 1] - self.beta[j])
    }
}

/// First-order Markov side-slip filter with RTS smoothing.
fn smooth_side_slip(t: &[f64], z: &[f64], var: &[f64]) -> Option<SlipTrack> {
    let n = t.len();
    if n < 5 {
        return None;
    }
    let tau = 2.0;
    let stat_var = 0.02f64 * 0.02;
    let mut xf = Vec::with_capacity(n);
    let mut pf = Vec::with_capacity(n);
    let mut pp = Vec::with_capacity(n);
    let mut phis = Vec::with_capacity(n);
    let (mut x, mut p) = (0.0, stat_var);
    for j in 0..n {
        let phi = if j == 0 {
            1.0
        } else {
            (-(t[j] - t[j - 1]) / tau).exp()
        };
        let xp = phi * x;
        let ppred = if j == 0 {
            p
        } else {
            phi * phi * p + stat_var * (1.0 - phi * phi)
        };
        let k = ppred / (ppred + var[j]);
        x = xp + k * (z[j] - xp);
        p = (1.0 - k) * ppred;
        xf.push(x);
        pf.push(p);
        pp.push(ppred);
        phis.push(phi);
    }
    let mut xs = xf.clone();
    for j in (0..n - 1).rev() {
        let c = pf[j] * phis[j + 1] / pp[j + 1];
        xs[j] = xf[j] + c * (xs[j + 1] - phis[j + 1] * xf[j]);
    }
    Some(SlipTrack {
        t: t.to_vec(),
        beta: xs,
    })
}

/// Position/velocity change from the IMU accelerations rotated by the
/// heading, for each interval ending at fix j (entry 0 unused). The IMU rows
/// are read from the drive (rows without finite accelerations skipped).
fn accel_inputs(fixes: &[RefFix], p: &Series, drive: &Drive, heading: &HeadingTrack) -> Vec<Input> {
    let mut out = vec![[0.0; 4]; fixes.len()];
    let Some(rows) = drive.imu.as_deref() else {
        return out;
    };
    let usable = |r: &ImuSample| {
        r.t_s.is_finite()
            && r.ax_m_s2.is_some_and(f64::is_finite)
            && r.ay_m_s2.is_some_and(f64::is_finite)
    };
    // IMU times on the wheels' clock.
    let shift = p.imu_shift_s;
    let t_start = fixes.first().map_or(0.0, |f| f.t);
    let mut i = rows.partition_point(|r| r.t_s.is_nan() || r.t_s - shift < t_start);
    let mut hc = 0usize;
    let mut gc = 0usize;
    for j in 1..fixes.len() {
        let (t0, t1) = (fixes[j - 1].t, fixes[j].t);
        let (mut dvx, mut dvy, mut dpx, mut dpy) = (0.0, 0.0, 0.0, 0.0);
        let mut tprev = t0;
        let mut aprev: Option<[f64; 2]> = None;
        while i < rows.len() && (rows[i].t_s.is_nan() || rows[i].t_s - shift <= t1) {
            let s = &rows[i];
            i += 1;
            let st = s.t_s - shift;
            if !usable(s) || st < tprev {
                continue;
            }
            let (ax, ay) = (s.ax_m_s2.unwrap_or(0.0), s.ay_m_s2.unwrap_or(0.0));
            let g_t = p.gyro_at_cursor(st, &mut gc);
            let th = heading.at(st, g_t, &mut hc);
            let (sn, cs) = th.sin_cos();
            let a = [cs * ax - sn * ay, sn * ax + cs * ay];
            let a0 = aprev.unwrap_or(a);
            let h = st - tprev;
            let am = [0.5 * (a0[0] + a[0]), 0.5 * (a0[1] + a[1])];
            dpx += dvx * h + 0.5 * am[0] * h * h;
            dpy += dvy * h + 0.5 * am[1] * h * h;
            dvx += am[0] * h;
            dvy += am[1] * h;
            tprev = st;
            aprev = Some(a);
        }
        if let Some(a) = aprev {
            let h = t1 - tprev;
            dpx += dvx * h + 0.5 * a[0] * h * h;
            dpy += dvy * h + 0.5 * a[1] * h * h;
            dvx += a[0] * h;
            dvy += a[1] * h;
        }
        // Long gaps without accelerations: no input (the process noise covers it).
        if t1 - t0 > 5.0 && aprev.is_none() {
            continue;
        }
        out[j] = [dpx, dpy, dvx, dvy];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clocks::gnss::estimate_gnss_sigma;
    use crate::series::Fix;

    #[test]
    fn smoother_follows_a_constant_velocity_track_and_gates_an_outlier() {
        let n = 200;
        let mut fixes = Vec::new();
        let mut z = Vec::new();
        for j in 0..n {
            let t = j as f64 * 0.1;
            let mut p = [10.0 * t, 5.0];
            if j == 100 {
                p[0] += 30.0;
            }
            fixes.push(RefFix {
                t,
                x: p[0],
                y: p[1],
                sigma: 0.5,
                accepted: true,
            });
            z.push(p);
        }
        let tr = smooth_positions(&fixes, &z, 4.0, 5.0, None, None).expect("smoother");
        assert!(!tr.accepted[100]);
        assert_eq!(tr.accepted.iter().filter(|a| !**a).count(), 1);
        let mid = tr.at(100, 10.0);
        assert!((mid[0] - 100.0).abs() < 0.2, "{mid:?}");
        assert!((mid[2] - 10.0).abs() < 0.2, "{mid:?}");
        let between = tr.at(50, 5.05);
        assert!((between[0] - 50.5).abs() < 0.1, "{between:?}");
    }

    #[test]
    fn gnss_sigma_is_recovered_from_second_differences() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let noise = Normal::new(0.0, 0.8).expect("normal");
        let fixes: Vec<Fix> = (0..2000)
            .map(|j| {
                let t = j as f64 * 0.1;
                Fix {
                    t,
                    x: 15.0 * t + noise.sample(&mut rng),
                    y: noise.sample(&mut rng),
                    sigma: None,
                }
            })
            .collect();
        let s = estimate_gnss_sigma(&fixes).expect("sigma");
        assert!((s - 0.8).abs() < 0.08, "{s}");
    }
}
