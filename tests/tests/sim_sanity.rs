//! Sanity of the simulator against the 2W model (issue 3, item 7).
//!
//! With the true circumferences and every effect off, the 2W model follows the
//! simulator's truth; each effect switched on alone spoils it in the way the
//! physics catalogue says. Sensor-only effects leave the wheels alone, so for
//! them the sensor stream is checked for the effect's signature instead.
//!
//! Unless a test says otherwise, drives are simulated with noise-free sensors
//! and exact wheel revolutions (`_rev`), so that what is measured is the effect.

// The helpers below are test code too (clippy only exempts `#[test]` fns).
#![allow(clippy::unwrap_used)]

use interfaces::drive::Drive;
use interfaces::effects::Effect;
use simulator::{
    simulate, EffectForms, EffectSettings, Scenario, SensorSettings, SimConfig, VehicleKind,
};
use std::f64::consts::PI;
use vehicle_model::two_wheel::{dead_reckon, wrap_angle, Pose2, TwoWheelParams};

const SEED: u64 = 11;

fn clean_config(scenario: Scenario, effects: EffectSettings) -> SimConfig {
    let mut c = SimConfig::new(scenario, SEED);
    c.effects = effects;
    c.sensors = SensorSettings::noiseless();
    c.sensors.wheels.ticks_per_rev = None;
    c
}

fn only(effect: Effect, spec: &str) -> EffectSettings {
    let mut e = EffectSettings::none();
    e.apply_spec(spec).unwrap();
    assert_eq!(e.to_truth_map().len(), 1, "{effect}");
    assert!(e.is_on(effect));
    e
}

fn run(config: &SimConfig) -> Drive {
    simulate(config).unwrap()
}

/// Truth yaw, unwrapped.
fn truth_yaw(drive: &Drive) -> Vec<f64> {
    let truth = drive.truth.as_ref().unwrap();
    let mut out = Vec::with_capacity(truth.len());
    let mut prev = truth[0].yaw_rad.unwrap();
    let mut acc = prev;
    for t in truth {
        let y = t.yaw_rad.unwrap();
        acc += wrap_angle(y - prev);
        prev = y;
        out.push(acc);
    }
    out
}

/// 2W dead-reckoning from the true start with the TRUE rear circumferences
/// and the NOMINAL track of vehicle.toml.
fn dead_reckon_true(drive: &Drive) -> Vec<Pose2> {
    let truth = drive.truth.as_ref().unwrap();
    let tp = drive.truth_params.as_ref().unwrap();
    let params = TwoWheelParams {
        c_rl: tp.circumference_m.rl,
        c_rr: tp.circumference_m.rr,
        track_width: drive.vehicle.track_width_m,
    };
    let start = Pose2 {
        x: truth[0].x_m,
        y: truth[0].y_m,
        yaw: truth[0].yaw_rad.unwrap(),
    };
    dead_reckon(start, &drive.wheel_revolutions().unwrap(), &params)
}

/// Position and |yaw| errors (m, rad) of the 2W track against the truth.
fn track_errors(drive: &Drive) -> (Vec<f64>, Vec<f64>) {
    let truth = drive.truth.as_ref().unwrap();
    let track = dead_reckon_true(drive);
    let yaw = truth_yaw(drive);
    let pos = track
        .iter()
        .zip(truth)
        .map(|(p, t)| (p.x - t.x_m).hypot(p.y - t.y_m))
        .collect();
    let ang = track
        .iter()
        .zip(&yaw)
        .map(|(p, y)| (p.yaw - y).abs())
        .collect();
    (pos, ang)
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(0.0, f64::max)
}

/// Rates over windows of `k` wheel samples: truth and 2W (true circumferences, nominal track).
#[derive(Debug, Clone, Copy)]
struct Window {
    t: f64,
    /// Truth speed of the rear-axle centre, m/s.
    v: f64,
    /// Truth yaw rate, rad/s.
    w: f64,
    /// 2W speed, m/s.
    v_odo: f64,
    /// 2W yaw rate, rad/s.
    w_odo: f64,
    /// Mean IMU longitudinal and vertical specific force, m/s^2.
    ax: f64,
    az: f64,
}

fn windows(drive: &Drive, k: usize) -> Vec<Window> {
    let truth = drive.truth.as_ref().unwrap();
    let revs = drive.wheel_revolutions().unwrap();
    let yaw = truth_yaw(drive);
    let tp = drive.truth_params.as_ref().unwrap();
    let (c_rl, c_rr) = (tp.circumference_m.rl, tp.circumference_m.rr);
    let track = drive.vehicle.track_width_m;
    let imu = drive.imu.as_ref().unwrap();
    let mut out = Vec::new();
    let mut i = 0;
    let mut imu_i = 0;
    while i + k < truth.len() {
        let j = i + k;
        let dt = truth[j].t_s - truth[i].t_s;
        let dist: f64 = (i..j)
            .map(|n| (truth[n + 1].x_m - truth[n].x_m).hypot(truth[n + 1].y_m - truth[n].y_m))
            .sum();
        let d_rl = (revs[j].rl - revs[i].rl) * c_rl;
        let d_rr = (revs[j].rr - revs[i].rr) * c_rr;
        let (mut ax, mut az, mut n) = (0.0, 0.0, 0.0f64);
        while imu_i < imu.len() && imu[imu_i].t_s < truth[j].t_s {
            if imu[imu_i].t_s >= truth[i].t_s {
                ax += imu[imu_i].ax_m_s2.unwrap();
                az += imu[imu_i].az_m_s2.unwrap();
                n += 1.0;
            }
            imu_i += 1;
        }
        out.push(Window {
            t: 0.5 * (truth[i].t_s + truth[j].t_s),
            v: dist / dt,
            w: (yaw[j] - yaw[i]) / dt,
            v_odo: 0.5 * (d_rl + d_rr) / dt,
            w_odo: (d_rr - d_rl) / track / dt,
            ax: ax / n.max(1.0),
            az: az / n.max(1.0),
        });
        i = j;
    }
    out
}

/// The windows of `k` truth samples in which the car moves faster than
/// 3 m/s.
fn moving_windows(drive: &Drive, k: usize) -> Vec<Window> {
    windows(drive, k)
        .into_iter()
        .filter(|w| w.v > 3.0)
        .collect()
}

/// Least squares y = X b (a handful of regressors), solved by SVD.
fn least_squares(rows: &[Vec<f64>], y: &[f64]) -> Vec<f64> {
    let p = rows[0].len();
    let x = nalgebra::DMatrix::from_fn(rows.len(), p, |r, c| rows[r][c]);
    let y = nalgebra::DVector::from_column_slice(y);
    let b = x.svd(true, true).solve(&y, 1e-12).unwrap();
    b.iter().copied().collect()
}

fn rms_residual(rows: &[Vec<f64>], y: &[f64], b: &[f64]) -> f64 {
    let ss: f64 = rows
        .iter()
        .zip(y)
        .map(|(x, yi)| (yi - x.iter().zip(b).map(|(a, b)| a * b).sum::<f64>()).powi(2))
        .sum();
    (ss / y.len() as f64).sqrt()
}

// ---------------------------------------------------------------- no effects

/// Bound: with exact revolutions, the 2W track stays within 1 cm and 0.001
/// degrees of the truth over every scenario (the simulator integrates the rear
/// axle exactly as eq. (1) does, at a finer step).
#[test]
fn two_wheel_follows_the_truth_with_every_effect_off() {
    for scenario in [Scenario::Paper, Scenario::Garage, Scenario::Mixed] {
        let drive = run(&clean_config(scenario, EffectSettings::none()));
        let (pos, yaw) = track_errors(&drive);
        let (p, y) = (max(&pos), max(&yaw).to_degrees());
        eprintln!(
            "{scenario:?}: 2W vs truth, effects off: position max {p:.5} m, yaw max {y:.6} deg"
        );
        assert!(p < 0.01, "{scenario:?}: position error {p} m");
        assert!(y < 0.001, "{scenario:?}: yaw error {y} deg");
    }
}

/// With the default 96-tick encoders the heading error is bounded by the
/// quantisation: at most 2 ticks of left/right difference, c / (96 t_R) each.
#[test]
fn quantised_ticks_keep_the_heading_within_two_ticks() {
    let mut config = clean_config(Scenario::Paper, EffectSettings::none());
    config.sensors.wheels.ticks_per_rev = Some(96);
    let drive = run(&config);
    let (_, yaw) = track_errors(&drive);
    let tp = drive.truth_params.as_ref().unwrap();
    let bound = 2.0 * tp.circumference_m.rr / 96.0 / drive.vehicle.track_width_m;
    let y = max(&yaw);
    eprintln!(
        "96 ticks: yaw error max {:.3} deg, bound {:.3} deg",
        y.to_degrees(),
        bound.to_degrees()
    );
    assert!(y < bound, "{y} >= {bound}");
    assert!(y > 0.1 * bound, "quantisation should be visible: {y}");
}

// ---------------------------------------------------------- physics effects

/// side_slip: the rear axle's course leaves the heading by beta = -k_beta a_y
/// (outward), which the wheels cannot see: the 2W yaw stays exact while a
/// cross-track error builds up in the corners, and more so with a larger k_beta.
#[test]
fn side_slip_alone_gives_outward_course_error_in_corners() {
    let k_beta = 0.004;
    let drive = run(&clean_config(
        Scenario::Paper,
        only(Effect::SideSlip, "side_slip=0.004"),
    ));
    let truth = drive.truth.as_ref().unwrap();
    let yaw = truth_yaw(&drive);
    // Over 0.2 s: the rear axle's course against its heading, and a_y = v w.
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for i in (0..truth.len() - 20).step_by(20) {
        let (a, b) = (truth[i], truth[i + 20]);
        let dt = b.t_s - a.t_s;
        let v = (b.x_m - a.x_m).hypot(b.y_m - a.y_m) / dt;
        let a_y = v * (yaw[i + 20] - yaw[i]) / dt;
        if v > 5.0 && a_y.abs() < 2.5 {
            let course = (b.y_m - a.y_m).atan2(b.x_m - a.x_m);
            x.push(vec![a_y]);
            y.push(wrap_angle(course - 0.5 * (yaw[i] + yaw[i + 20])));
        }
    }
    let slope = least_squares(&x, &y)[0];
    eprintln!("side slip: beta / a_y = {slope:.5} rad per m/s^2 (set -{k_beta})");
    assert!(slope < 0.0, "the slip must point out of the turn");
    assert!((-slope / k_beta - 1.0).abs() < 0.25, "{slope}");

    let (pos, yaw_err) = track_errors(&drive);
    assert!(
        max(&yaw_err).to_degrees() < 0.001,
        "side slip must not reach the wheels"
    );
    let double = run(&clean_config(
        Scenario::Paper,
        only(Effect::SideSlip, "side_slip=0.008"),
    ));
    let (pos2, _) = track_errors(&double);
    let (m1, m2) = (max(&pos), max(&pos2));
    eprintln!("side slip: 2W position error max {m1:.2} m (k 0.004), {m2:.2} m (k 0.008)");
    assert!(m1 > 0.5, "{m1}");
    assert!(m2 > 1.6 * m1, "{m1} {m2}");
}

/// load_transfer_radius: c_outer,inner = c0 (1 -/+ k_z a_y) so the 2W yaw
/// rate exceeds the truth by 2 k_z v^2 w / t_R; a yaw error that scales with
/// v^2 w, not with w alone (which is what track_width or gyro_scale give).
#[test]
fn load_transfer_radius_alone_gives_yaw_error_scaling_with_v2_w() {
    let k_z = 1e-4;
    let drive = run(&clean_config(
        Scenario::Mixed,
        only(Effect::LoadTransferRadius, "load_transfer_radius=1e-4"),
    ));
    let t_r = drive.vehicle.track_width_m;
    let ws = moving_windows(&drive, 20);
    let r_w: Vec<f64> = ws.iter().map(|w| w.w - w.w_odo).collect();
    let x_v2w: Vec<Vec<f64>> = ws.iter().map(|w| vec![w.v * w.v * w.w / t_r]).collect();
    let x_w: Vec<Vec<f64>> = ws.iter().map(|w| vec![w.w]).collect();
    let b = least_squares(&x_v2w, &r_w);
    let b_w = least_squares(&x_w, &r_w);
    let (res_v2w, res_w) = (
        rms_residual(&x_v2w, &r_w, &b),
        rms_residual(&x_w, &r_w, &b_w),
    );
    eprintln!(
        "load transfer: r_w = {:.3e} v^2 w / t_R (expect {:.3e}); rms residual {res_v2w:.2e} vs {res_w:.2e} for r_w ~ w",
        b[0],
        -2.0 * k_z
    );
    assert!((b[0] / (-2.0 * k_z) - 1.0).abs() < 0.15, "{}", b[0]);
    assert!(
        res_v2w < 0.5 * res_w,
        "v^2 w must explain the yaw error far better than w"
    );
}

/// speed_radius_growth: c = c0 (1 + k_v v^2), so the 2W speed falls short by
/// k_v v^2 relative, on straights as well as in bends.
#[test]
fn speed_radius_growth_alone_gives_speed_error_growing_with_v2() {
    let k_v = 2.5e-6;
    let drive = run(&clean_config(
        Scenario::Mixed,
        only(Effect::SpeedRadiusGrowth, "speed_radius_growth=2.5e-6"),
    ));
    let ws = moving_windows(&drive, 100);
    let y: Vec<f64> = ws.iter().map(|w| (w.v - w.v_odo) / w.v).collect();
    let x: Vec<Vec<f64>> = ws.iter().map(|w| vec![1.0, w.v * w.v]).collect();
    let b = least_squares(&x, &y);
    eprintln!(
        "speed growth: r_v / v = {:.2e} + {:.3e} v^2 (expect {k_v:e} v^2)",
        b[0], b[1]
    );
    assert!((b[1] / k_v - 1.0).abs() < 0.05, "{}", b[1]);
    assert!(b[0].abs() < 2e-5, "{}", b[0]);
    let straight: Vec<&Window> = ws
        .iter()
        .filter(|w| w.w.abs() < 1e-3 && w.v > 30.0)
        .collect();
    assert!(!straight.is_empty());
    for w in straight {
        assert!((w.v - w.v_odo) / w.v > 0.8 * k_v * w.v * w.v, "{w:?}");
    }
}

/// longitudinal_slip: the driven wheels turn faster by k_s a_x when pulling;
/// braking slips every wheel by its share. On the rear-driven saloon the 2W
/// speed error follows a_x with slope about k_s when accelerating and the rear
/// brake share of it when braking; on the front-driven compact the rear wheels
/// hardly see traction.
#[test]
fn longitudinal_slip_alone_scales_with_acceleration_on_the_driven_axle() {
    let k_s = 0.002;
    let slopes = |vehicle: VehicleKind| {
        let mut config = clean_config(
            Scenario::Mixed,
            only(Effect::LongitudinalSlip, "longitudinal_slip=0.002"),
        );
        config.vehicle = vehicle;
        let drive = run(&config);
        let ws = moving_windows(&drive, 20);
        let fit = |keep: &dyn Fn(&Window) -> bool| {
            let sel: Vec<&Window> = ws.iter().filter(|w| keep(w)).collect();
            let y: Vec<f64> = sel.iter().map(|w| (w.v_odo - w.v) / w.v).collect();
            let x: Vec<Vec<f64>> = sel.iter().map(|w| vec![1.0, w.ax, w.v * w.v]).collect();
            least_squares(&x, &y)[1]
        };
        // The linear range of the tyre (the catalogue's form); harder
        // acceleration and braking slip more than linearly. Gentle
        // deceleration is left out: up to the drag and rolling resistance it
        // is coasting, with the driven axle still pulling.
        (
            fit(&|w| (0.3..2.0).contains(&w.ax)),
            fit(&|w| (-2.5..-0.8).contains(&w.ax)),
        )
    };
    let (rwd_pull, rwd_brake) = slopes(VehicleKind::Saloon);
    let (fwd_pull, fwd_brake) = slopes(VehicleKind::Compact);
    eprintln!("longitudinal slip (k_s {k_s}): saloon pull {rwd_pull:.2e} brake {rwd_brake:.2e}; compact pull {fwd_pull:.2e} brake {fwd_brake:.2e}");
    assert!((rwd_pull / k_s - 1.0).abs() < 0.15, "{rwd_pull}");
    let share = VehicleKind::Saloon.spec().rear_brake_share;
    assert!((rwd_brake / (share * k_s) - 1.0).abs() < 0.2, "{rwd_brake}");
    assert!(fwd_pull.abs() < 0.1 * k_s, "{fwd_pull}");
    assert!(
        fwd_brake > 0.5 * VehicleKind::Compact.spec().rear_brake_share * k_s,
        "{fwd_brake}"
    );
}

/// track_width: the true track is the nominal times (1 + rel), so the 2W
/// heading error is rel times the heading turned: zero on straights,
/// proportional to turning.
#[test]
fn track_width_alone_gives_heading_error_proportional_to_turning() {
    let rel = 0.02;
    let drive = run(&clean_config(
        Scenario::Garage,
        only(Effect::TrackWidth, "track_width=0.02"),
    ));
    let track = dead_reckon_true(&drive);
    let yaw = truth_yaw(&drive);
    let mut worst: f64 = 0.0;
    for (p, y) in track.iter().zip(&yaw) {
        let turned = y - yaw[0];
        let expected = rel * turned;
        worst = worst.max((p.yaw - y - expected).abs());
    }
    let total = yaw.last().unwrap() - yaw[0];
    eprintln!(
        "track width: turned {:.0} deg, worst deviation from rel x turned {:.4} deg",
        total.to_degrees(),
        worst.to_degrees()
    );
    assert!(total.abs() > 2.0 * PI);
    assert!(worst.to_degrees() < 0.02, "{}", worst.to_degrees());
}

/// radius_drift: c(t) = c0 (1 + d (1 - exp(-t/T))), so the 2W speed deficit
/// follows time since the start, whatever the speed.
#[test]
fn radius_drift_alone_trends_with_time() {
    let (d, tc) = (0.003, 600.0);
    let drive = run(&clean_config(
        Scenario::Mixed,
        only(Effect::RadiusDrift, "radius_drift=0.003"),
    ));
    let ws = moving_windows(&drive, 500);
    let mut last = 0.0;
    for w in &ws {
        let expected = d * (1.0 - (-w.t / tc).exp());
        let measured = (w.v - w.v_odo) / w.v_odo;
        assert!(
            (measured - expected).abs() < 5e-5,
            "t {}: {measured} vs {expected}",
            w.t
        );
        last = measured;
    }
    eprintln!("radius drift: r_v/v at the end {last:.5} (d {d}, T {tc} s)");
    assert!(last > 0.5 * d);
}

/// road_grade: the wheels roll along the slope, the truth (like GNSS) is
/// horizontal: the 2W speed exceeds the horizontal speed by 1/cos(pitch),
/// uphill and downhill alike, and the IMU sees the pitch.
#[test]
fn road_grade_alone_makes_the_wheels_measure_along_the_slope() {
    let drive = run(&clean_config(
        Scenario::Paper,
        only(Effect::RoadGrade, "road_grade=0.08"),
    ));
    let g = 9.81;
    let ws: Vec<Window> = windows(&drive, 50)
        .into_iter()
        .filter(|w| w.v > 5.0)
        .collect();
    let (mut up, mut down) = (0, 0);
    for w in &ws {
        let cos_pitch = (w.az / g).clamp(-1.0, 1.0);
        let expected = 1.0 / cos_pitch - 1.0;
        let measured = w.v_odo / w.v - 1.0;
        assert!(
            (measured - expected).abs() < 2e-4,
            "t {}: {measured} vs {expected}",
            w.t
        );
        let sin_pitch = (1.0 - cos_pitch * cos_pitch).sqrt();
        if sin_pitch > 0.04 {
            assert!(measured > 5e-4, "{w:?}");
            if w.ax > 0.0 {
                up += 1;
            } else {
                down += 1;
            }
        }
    }
    eprintln!("road grade: {up} uphill and {down} downhill windows, all with wheels > horizontal");
    assert!(up > 5 && down > 5, "{up} {down}");
}

// ----------------------------------------------------------- sensor effects

/// Sensor-only effects leave the wheels (and so the 2W track) unchanged.
#[test]
fn sensor_effects_do_not_touch_the_wheels() {
    let base = run(&clean_config(Scenario::Paper, EffectSettings::none()));
    for (effect, spec) in [
        (Effect::GyroBias, "gyro_bias=200"),
        (Effect::GyroScale, "gyro_scale=0.005"),
        (Effect::GnssLatency, "gnss_latency=0.08"),
        (Effect::GnssLeverArm, "gnss_lever_arm=1.2"),
        (Effect::HeadingBias, "heading_bias=3"),
    ] {
        let drive = run(&clean_config(Scenario::Paper, only(effect, spec)));
        assert_eq!(drive.wheels, base.wheels, "{effect}");
        assert_eq!(drive.truth, base.truth, "{effect}");
    }
}

/// gyro_bias: the yaw-rate mean at standstill is the bias (with the default
/// sensor noise); without the effect it is zero.
#[test]
fn gyro_bias_shows_at_standstill() {
    let standstill_mean = |effects: EffectSettings| {
        let mut config = SimConfig::new(Scenario::Mixed, SEED);
        config.effects = effects;
        let drive = run(&config);
        let truth = drive.truth.as_ref().unwrap();
        let imu = drive.imu.as_ref().unwrap();
        // Standstill: the truth has not moved for 1 s either side.
        let still: Vec<f64> = imu
            .iter()
            .enumerate()
            .filter(|(i, _)| {
                let lo = i.saturating_sub(100);
                let hi = (i + 100).min(truth.len() - 1);
                (truth[lo].x_m - truth[hi].x_m).hypot(truth[lo].y_m - truth[hi].y_m) < 1e-9
            })
            .map(|(_, s)| s.gz_rad_s)
            .collect();
        let n = still.len() as f64;
        let sigma = config.sensors.imu.gz_sigma_rad_s;
        (still.iter().sum::<f64>() / n, sigma / n.sqrt(), still.len())
    };
    let bias = 200f64.to_radians() / 3600.0;
    let (mean, se, n) = standstill_mean(only(Effect::GyroBias, "gyro_bias=200"));
    eprintln!("gyro bias: standstill mean {mean:.3e} rad/s over {n} samples (bias {bias:.3e}, s.e. {se:.1e})");
    assert!(n > 1000, "{n}");
    assert!((mean - bias).abs() < 4.0 * se, "{mean} vs {bias}");
    let (mean0, se0, _) = standstill_mean(EffectSettings::none());
    assert!(mean0.abs() < 4.0 * se0, "{mean0}");
}

/// gyro_scale: the gyro reads (1 + s) times the true yaw rate.
#[test]
fn gyro_scale_scales_the_yaw_rate() {
    let drive = run(&clean_config(
        Scenario::Garage,
        only(Effect::GyroScale, "gyro_scale=0.005"),
    ));
    let ws = windows(&drive, 10);
    let imu = drive.imu.as_ref().unwrap();
    // The gyro at a window's samples against the truth yaw rate over it.
    let x: Vec<Vec<f64>> = ws.iter().map(|w| vec![w.w]).collect();
    let y: Vec<f64> = ws
        .iter()
        .enumerate()
        .map(|(i, _)| {
            imu[i * 10..(i + 1) * 10]
                .iter()
                .map(|s| s.gz_rad_s)
                .sum::<f64>()
                / 10.0
        })
        .collect();
    let b = least_squares(&x, &y)[0];
    eprintln!("gyro scale: gz / w = {b:.5}");
    assert!((b - 1.005).abs() < 5e-4, "{b}");
}

/// gnss_latency: a fix stamped t is where the antenna was at t - tau; the
/// lag fitted against the truth is tau.
#[test]
fn gnss_latency_lags_the_truth_by_tau() {
    let tau = 0.08;
    let drive = run(&clean_config(
        Scenario::Paper,
        only(Effect::GnssLatency, "gnss_latency=0.08"),
    ));
    let truth = drive.truth.as_ref().unwrap();
    let gnss = drive.gnss.as_ref().unwrap();
    let dt = truth[1].t_s - truth[0].t_s;
    let (mut num, mut den) = (0.0, 0.0);
    for g in gnss {
        let i = (g.t_s / dt).round() as usize;
        if i == 0 || i + 1 >= truth.len() {
            continue;
        }
        let (vx, vy) = (
            (truth[i + 1].x_m - truth[i - 1].x_m) / (2.0 * dt),
            (truth[i + 1].y_m - truth[i - 1].y_m) / (2.0 * dt),
        );
        let (ex, ey) = (g.x_m - truth[i].x_m, g.y_m - truth[i].y_m);
        num -= ex * vx + ey * vy;
        den += vx * vx + vy * vy;
    }
    let lag = num / den;
    eprintln!("GNSS latency: fitted lag {lag:.4} s (tau {tau} s)");
    assert!((lag - tau).abs() < 0.003, "{lag}");
    assert!(
        (gnss[0].t_s - tau).abs() < 1e-9,
        "the first fix is stamped tau late"
    );
}

/// gnss_lever_arm: the offset of each fix from the rear-axle truth is the
/// lever arm, fixed in the body frame.
#[test]
fn gnss_lever_arm_is_fixed_in_the_body_frame() {
    let mut effects = only(Effect::GnssLeverArm, "gnss_lever_arm=1.2");
    effects.apply_spec("gnss_lever_arm.y_m=-0.3").unwrap();
    let drive = run(&clean_config(Scenario::Mixed, effects));
    let truth = drive.truth.as_ref().unwrap();
    let dt = truth[1].t_s - truth[0].t_s;
    for g in drive.gnss.as_ref().unwrap() {
        let t = truth[(g.t_s / dt).round() as usize];
        let (s, c) = t.yaw_rad.unwrap().sin_cos();
        let (ex, ey) = (g.x_m - t.x_m, g.y_m - t.y_m);
        let (bx, by) = (c * ex + s * ey, -s * ex + c * ey);
        assert!(
            (bx - 1.2).abs() < 1e-6 && (by + 0.3).abs() < 1e-6,
            "t {}: ({bx}, {by})",
            g.t_s
        );
    }
    assert!(
        drive.vehicle.gnss.antenna_x_m.is_none(),
        "the lever arm is concealed from vehicle.toml"
    );
}

/// heading_bias: the compass error is A + B sin psi + C cos psi + D sin 2psi +
/// E cos 2psi; fitted over the mixed drive (which covers every heading) it
/// returns the coefficients.
#[test]
fn heading_bias_is_periodic_in_heading() {
    let mut effects = EffectSettings::none();
    for spec in [
        "heading_bias.a_deg=0.5",
        "heading_bias.b_deg=3",
        "heading_bias.c_deg=-1.5",
        "heading_bias.d_deg=0.8",
        "heading_bias.e_deg=0",
    ] {
        effects.apply_spec(spec).unwrap();
    }
    let drive = run(&clean_config(Scenario::Mixed, effects));
    let truth = drive.truth.as_ref().unwrap();
    let dt = truth[1].t_s - truth[0].t_s;
    let mut octants = [false; 8];
    let (x, y): (Vec<Vec<f64>>, Vec<f64>) = drive
        .heading
        .as_ref()
        .unwrap()
        .iter()
        .map(|h| {
            let psi = truth[(h.t_s / dt).round() as usize].yaw_rad.unwrap();
            octants[((psi + PI) / (PI / 4.0)).floor().clamp(0.0, 7.0) as usize] = true;
            let row = vec![
                1.0,
                psi.sin(),
                psi.cos(),
                (2.0 * psi).sin(),
                (2.0 * psi).cos(),
            ];
            (row, wrap_angle(h.yaw_rad - psi).to_degrees())
        })
        .unzip();
    assert!(
        octants.iter().all(|o| *o),
        "the mixed drive must cover every heading"
    );
    let b = least_squares(&x, &y);
    eprintln!("heading bias fit (deg): {b:.3?}");
    for (got, want) in b.iter().zip([0.5, 3.0, -1.5, 0.8, 0.0]) {
        assert!((got - want).abs() < 0.01, "{b:?}");
    }
}

// ------------------------------------------------------- drives and defaults

#[test]
fn the_same_seed_gives_the_same_drive_and_another_seed_another() {
    let config = SimConfig::new(Scenario::Paper, 5);
    let (a, b) = (run(&config), run(&config));
    assert_eq!(a, b);
    let c = run(&SimConfig::new(Scenario::Paper, 6));
    assert_ne!(a.gnss, c.gnss);
    assert_ne!(a.imu, c.imu);
    assert_ne!(a.heading, c.heading);
    // The motion itself does not depend on the seed.
    assert_eq!(a.truth, c.truth);
}

#[test]
fn the_paper_scenario_matches_the_paper_setting() {
    let drive = run(&SimConfig::new(Scenario::Paper, 1));
    let truth = drive.truth.as_ref().unwrap();
    let dist: f64 = truth
        .windows(2)
        .map(|w| (w[1].x_m - w[0].x_m).hypot(w[1].y_m - w[0].y_m))
        .sum();
    let end = truth.last().unwrap();
    assert!((2150.0..2300.0).contains(&dist), "{dist}");
    assert!(end.x_m.hypot(end.y_m) < 2.0, "a closed course");
    let speed = dist / drive.wheel_duration_s() * 3.6;
    assert!((57.0..61.0).contains(&speed), "{speed} km/h");
    assert_eq!(drive.vehicle.nominal_circumference_m, 2.2);
    let c = drive.truth_params.as_ref().unwrap().circumference_m;
    for v in [c.rl, c.rr, c.fl, c.fr] {
        assert!((0.01..0.05).contains(&(2.2 - v)), "{v}");
    }
    assert!(drive.gnss.as_ref().unwrap().len() > 1000);
}

#[test]
fn garage_gnss_is_denied_after_the_start() {
    let drive = run(&SimConfig::new(Scenario::Garage, 1));
    let gnss = drive.gnss.as_ref().unwrap();
    let last_fix = gnss.last().unwrap().t_s;
    let end = drive.wheel_duration_s();
    eprintln!(
        "garage: {} fixes, the last at {last_fix:.1} s of {end:.1} s",
        gnss.len()
    );
    assert!(last_fix < 20.0 && end > 120.0, "{last_fix} {end}");
}

/// Every scenario with every vehicle and every effect on finishes with
/// consistent series; the garage stays parked when asked for longer.
#[test]
fn every_scenario_and_vehicle_simulates_with_every_effect() {
    let mut all = EffectSettings::none();
    for e in Effect::ALL {
        all.switch_on(e);
    }
    for vehicle in VehicleKind::ALL {
        for scenario in Scenario::ALL {
            let mut config = SimConfig::new(scenario, 3);
            config.vehicle = vehicle;
            config.effects = all;
            config.sensors.gnss.outage_rate_per_h = 30.0;
            if scenario == Scenario::Long {
                config.duration_s = Some(120.0);
            }
            if scenario == Scenario::Garage {
                config.duration_s = Some(240.0);
            }
            let drive =
                simulate(&config).unwrap_or_else(|e| panic!("{scenario:?} {vehicle:?}: {e}"));
            let truth = drive.truth.as_ref().unwrap();
            assert_eq!(truth.len(), drive.wheels.samples.len());
            let increasing = |t: &mut dyn Iterator<Item = f64>| {
                let v: Vec<f64> = t.collect();
                v.windows(2).all(|w| w[1] > w[0])
            };
            assert!(increasing(&mut drive.wheels.samples.iter().map(|s| s.t_s)));
            assert!(increasing(
                &mut drive.gnss.as_ref().unwrap().iter().map(|s| s.t_s)
            ));
            assert!(increasing(
                &mut drive.imu.as_ref().unwrap().iter().map(|s| s.t_s)
            ));
            assert!(increasing(
                &mut drive.heading.as_ref().unwrap().iter().map(|s| s.t_s)
            ));
            let tp = drive.truth_params.as_ref().unwrap();
            assert_eq!(tp.effects.len(), Effect::ALL.len());
            assert!((tp.track_width_m / drive.vehicle.track_width_m - 1.02).abs() < 1e-12);
            if let Some(d) = config.duration_s {
                assert!((drive.wheel_duration_s() - d).abs() < 1e-6, "{scenario:?}");
            }
            if scenario == Scenario::Garage {
                let tail = &truth[truth.len() - 1000..];
                assert!(
                    tail.iter().all(|t| t.x_m == tail[0].x_m),
                    "parked at the end"
                );
            }
        }
    }
}

/// The catalogue's forms (`EffectForms::Catalogue`, `--effect-forms catalogue`): with
/// the vehicle physics a twin carries on together (side-slip, load transfer,
/// longitudinal slip), each knob shows in the wheels exactly as the
/// catalogue writes it: the yaw error 2 k_z v^2 w / t_R, the speed excess
/// k_s a_x in traction and braking alike. Under the physical forms the
/// same slip knob shows otherwise: the tyre force carries the drag and
/// rolling resistance (a slip without acceleration, which grows with v^2
/// like a speed growth) and the rear brakes take only their share; the
/// slip also softens on an unloaded wheel, which turns the wheels' yaw
/// against the load transfer at highway speeds.
#[test]
fn catalogue_forms_put_each_knob_in_the_wheels_as_the_catalogue_writes_it() {
    let (k_z, k_s) = (5e-4, 0.005);
    let fits = |forms: EffectForms| {
        let mut e = EffectSettings::none();
        for spec in [
            "side_slip=0.004",
            "load_transfer_radius=5e-4",
            "longitudinal_slip=0.005",
        ] {
            e.apply_spec(spec).unwrap();
        }
        let mut config = clean_config(Scenario::Mixed, e);
        config.effect_forms = forms;
        let drive = run(&config);
        let t_r = drive.vehicle.track_width_m;
        let ws = moving_windows(&drive, 20);
        let r_w: Vec<f64> = ws.iter().map(|w| w.w - w.w_odo).collect();
        let x_w: Vec<Vec<f64>> = ws.iter().map(|w| vec![w.v * w.v * w.w / t_r]).collect();
        let lt = least_squares(&x_w, &r_w)[0] / (-2.0 * k_z);
        let r_v: Vec<f64> = ws.iter().map(|w| (w.v_odo - w.v) / w.v).collect();
        let x_v: Vec<Vec<f64>> = ws.iter().map(|w| vec![1.0, w.ax]).collect();
        let b = least_squares(&x_v, &r_v);
        (lt, b[1] / k_s, b[0], drive)
    };
    let (lt_c, ks_c, cruise_c, drive) = fits(EffectForms::Catalogue);
    let (lt_p, ks_p, cruise_p, _) = fits(EffectForms::Physical);
    eprintln!(
        "load transfer seen / knob: catalogue {lt_c:.3}, physical {lt_p:.3}; \
         slip seen / knob: catalogue {ks_c:.3}, physical {ks_p:.3}; \
         slip at a_x = 0: catalogue {cruise_c:.1e}, physical {cruise_p:.1e}"
    );
    assert!((lt_c - 1.0).abs() < 0.05, "{lt_c}");
    assert!((ks_c - 1.0).abs() < 0.05, "{ks_c}");
    assert!(cruise_c.abs() < 2e-4, "{cruise_c}");
    assert!(
        cruise_p > 5e-4,
        "the physical slip carries the drag: {cruise_p}"
    );
    let tp = drive.truth_params.as_ref().unwrap();
    assert_eq!(
        tp.extra.get("effect_forms"),
        Some(&interfaces::drive::toml_value::Value::String(
            "catalogue".into()
        ))
    );
}
