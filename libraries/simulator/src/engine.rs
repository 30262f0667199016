//! The simulation loop: driver, vehicle, wheels and sensors at a fixed step.

use super::route::{PathPoint, Route};
use super::scenarios::{self, ScenarioRoute};
use super::sensors::{gauss, GaussMarkov};
use super::vehicle::{self, VehicleSpec, G};
use super::{EffectForms, EffectSettings, SensorSettings, SimConfig, SimError};
use interfaces::drive::{
    toml_value::Value, Drive, GnssAntenna, GnssSample, HeadingSample, ImuSample, TruthParams,
    TruthSample, VehicleParams, WheelSample, WheelSeries, WheelUnit, WheelUnits,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;

/// The driver acts at 100 Hz.
const DRIVER_RATE_HZ: f64 = 100.0;
/// Lag of the longitudinal force (powertrain and brakes), s.
const FORCE_LAG_S: f64 = 0.12;
/// Lag of the accelerations behind the load transfer (suspension), s.
const SUSPENSION_LAG_S: f64 = 0.1;
/// Below this speed the single-track model blends into the kinematic one, m/s.
const BLEND_LOW_M_S: f64 = 1.5;
/// Above this speed it is fully dynamic, m/s.
const BLEND_HIGH_M_S: f64 = 3.0;
/// Relaxation of the lateral states towards the kinematic ones at low speed, s.
const KINEMATIC_RELAXATION_S: f64 = 0.02;
/// Longest drive without an explicit duration, s.
const DEFAULT_TIME_LIMIT_S: f64 = 7200.0;
/// Longest drive with an explicit duration, s (100 h).
const MAX_DURATION_S: f64 = 360_000.0;

/// Vehicle constants derived from the spec and the effect knobs.
struct Model {
    spec: VehicleSpec,
    a: f64,
    b: f64,
    l: f64,
    m: f64,
    track_rear_true: f64,
    c_static: [f64; 4],
    fz0_front: f64,
    fz0_rear: f64,
    /// Per-wheel cornering stiffness at static load (front, rear), N/rad;
    /// `None`: no side-slip (kinematic single-track model).
    cornering: Option<(f64, f64)>,
    /// Per-wheel longitudinal slip stiffness, N per unit slip; `None`: no slip.
    slip_stiffness: Option<f64>,
    /// Relative radius change per relative lateral load change.
    radius_load_coeff: f64,
    /// The longitudinal slip per m/s^2 of the driven axle (the knob `k_s`;
    /// read in the catalogue's forms only).
    k_s: f64,
    /// How the effects act.
    forms: EffectForms,
    k_v: f64,
    drift: Option<(f64, f64)>,
    /// The wheels' speed reading beyond the catalogue.
    speed_map: Option<interfaces::speed_map::SpeedMap>,
}

/// Wheel order in arrays: rl, rr, fl, fr.
const RL: usize = 0;
const RR: usize = 1;
const FL: usize = 2;
const FR: usize = 3;

#[derive(Debug, Clone, Copy, Default)]
struct State {
    x: f64,
    y: f64,
    psi: f64,
    vx: f64,
    vy: f64,
    r: f64,
    delta: f64,
    force: f64,
    /// Filtered body accelerations for the load transfer.
    ax_f: f64,
    ay_f: f64,
    /// Last body accelerations (for the IMU).
    ax: f64,
    ay: f64,
    /// Last rate of change of the longitudinal speed, m/s^2 (the a_x of
    /// the catalogue's longitudinal slip: the speed's, not the body's).
    dvx: f64,
    revs: [f64; 4],
}

impl Model {
    fn new(config: &SimConfig, spec: VehicleSpec) -> Model {
        let (a, l, m) = (spec.cg_to_front_m, spec.wheelbase_m, spec.mass_kg);
        let b = spec.cg_to_rear_m();
        let c = config.true_circumferences();
        let e = &config.effects;
        // Rear-axle slip angle = m a_y a / (L C_r) in the linear range, so
        // C_r = m a / (L k_beta); the front follows from the understeer gradient.
        let cornering = e.side_slip.map(|s| {
            let c_rear = m * a / (l * s.k_beta);
            let c_front = m * b / (l * (s.k_beta + spec.understeer_rad_per_m_s2));
            (0.5 * c_front, 0.5 * c_rear)
        });
        // Driven-axle slip = m a_x / C_x (both wheels) = k_s a_x.
        let slip_stiffness = e.longitudinal_slip.map(|s| 0.5 * m / s.k_s);
        let radius_load_coeff = e
            .load_transfer_radius
            .map_or(0.0, |k| k.k_z / spec.rear_load_gain());
        Model {
            a,
            b,
            l,
            m,
            track_rear_true: true_track_width(config, &spec),
            c_static: [c.rl, c.rr, c.fl, c.fr],
            fz0_front: spec.static_load_front(),
            fz0_rear: spec.static_load_rear(),
            cornering,
            slip_stiffness,
            radius_load_coeff,
            k_s: e.longitudinal_slip.map_or(0.0, |s| s.k_s),
            forms: config.effect_forms,
            k_v: e.speed_radius_growth.map_or(0.0, |g| g.k_v),
            drift: e.radius_drift.map(|d| (d.d, d.time_constant_s)),
            speed_map: config.speed_map.clone(),
            spec,
        }
    }

    /// One integration step of `dt` with steering and force commands.
    fn step(&self, st: &mut State, t: f64, delta_cmd: f64, force_cmd: f64, grade: f64, dt: f64) {
        self.actuate(st, delta_cmd, force_cmd, dt);
        let loads = self.loads(st);
        let fx = self.axle_forces(st.force, &loads.fz);
        let sec = (1.0 + grade * grade).sqrt();
        let sin_g = grade / sec;
        let resist = self.spec.resistance_n(st.vx) + self.m * G * sin_g;
        let (vx0, vy0) = (st.vx, st.vy);
        self.integrate_velocities(st, &loads.fz, fx, resist, dt);
        // Body accelerations of the CG.
        st.dvx = (st.vx - vx0) / dt;
        st.ax = st.dvx - st.vy * st.r;
        st.ay = (st.vy - vy0) / dt + st.vx * st.r;
        st.ax_f += (st.ax - st.ax_f) * dt / SUSPENSION_LAG_S;
        st.ay_f += (st.ay - st.ay_f) * dt / SUSPENSION_LAG_S;
        self.roll_wheels(st, t, dt, sec, &loads, fx);
        self.move_rear_axle(st, dt);
    }

    /// Actuators: steering rate limit, force lag.
    fn actuate(&self, st: &mut State, delta_cmd: f64, force_cmd: f64, dt: f64) {
        let spec = &self.spec;
        let max_d = spec.max_steer_rate_rad_s * dt;
        st.delta = (st.delta + (delta_cmd - st.delta).clamp(-max_d, max_d))
            .clamp(-spec.max_steer_rad, spec.max_steer_rad);
        st.force += (force_cmd - st.force) * dt / FORCE_LAG_S;
    }

    /// Vertical loads: static, longitudinal and lateral transfer.
    fn loads(&self, st: &State) -> Loads {
        let spec = &self.spec;
        let h = spec.cg_height_m;
        let d_long = self.m * st.ax_f * h / self.l / 2.0;
        let d_lat_f = self.m * st.ay_f * h * (1.0 - spec.rear_roll_share) / spec.track_front_m;
        let d_lat_r = self.m * st.ay_f * h * spec.rear_roll_share / spec.track_rear_m;
        Loads {
            fz: [
                (self.fz0_rear + d_long - d_lat_r).max(0.0),
                (self.fz0_rear + d_long + d_lat_r).max(0.0),
                (self.fz0_front - d_long - d_lat_f).max(0.0),
                (self.fz0_front - d_long + d_lat_f).max(0.0),
            ],
            d_lat_f,
            d_lat_r,
        }
    }

    /// Longitudinal force `f` on the axles (front, rear): traction on the
    /// driven axle, braking split, each within its grip.
    fn axle_forces(&self, f: f64, fz: &[f64; 4]) -> (f64, f64) {
        let spec = &self.spec;
        let (fx_front, fx_rear) = if f >= 0.0 {
            if spec.rear_wheel_drive {
                (0.0, f)
            } else {
                (f, 0.0)
            }
        } else {
            (f * (1.0 - spec.rear_brake_share), f * spec.rear_brake_share)
        };
        let cap_f = 0.9 * spec.mu * (fz[FL] + fz[FR]);
        let cap_r = 0.9 * spec.mu * (fz[RL] + fz[RR]);
        (fx_front.clamp(-cap_f, cap_f), fx_rear.clamp(-cap_r, cap_r))
    }

    /// Speeds and yaw rate after `dt`: the kinematic single-track model
    /// (the rear axle rolls without side-slip), blended into the dynamic
    /// one with tyre forces above walking pace when the tyres slip.
    fn integrate_velocities(
        &self,
        st: &mut State,
        fz: &[f64; 4],
        (fx_front, fx_rear): (f64, f64),
        resist: f64,
        dt: f64,
    ) {
        let (_, cd) = st.delta.sin_cos();
        let (vx0, vy0, r0) = (st.vx, st.vy, st.r);
        // Kinematic single-track derivatives (rear axle rolls without side-slip).
        let dvx_kin = (fx_front * cd + fx_rear - resist) / self.m;
        let Some(cornering) = self.cornering else {
            st.vx = (vx0 + dvx_kin * dt).max(0.0);
            st.r = st.vx * st.delta.tan() / self.l;
            st.vy = self.b * st.r;
            return;
        };
        let r_kin = vx0 * st.delta.tan() / self.l;
        let dvy_kin = (self.b * r_kin - vy0) / KINEMATIC_RELAXATION_S;
        let dr_kin = (r_kin - r0) / KINEMATIC_RELAXATION_S;
        let w = ((vx0 - BLEND_LOW_M_S) / (BLEND_HIGH_M_S - BLEND_LOW_M_S)).clamp(0.0, 1.0);
        let lambda = w * w * (3.0 - 2.0 * w);
        let (dvx, dvy, dr) = if lambda > 0.0 {
            let (dvx_dyn, dvy_dyn, dr_dyn) =
                self.dynamic_derivatives(st, fz, (fx_front, fx_rear), resist, cornering);
            (
                lambda * dvx_dyn + (1.0 - lambda) * dvx_kin,
                lambda * dvy_dyn + (1.0 - lambda) * dvy_kin,
                lambda * dr_dyn + (1.0 - lambda) * dr_kin,
            )
        } else {
            (dvx_kin, dvy_kin, dr_kin)
        };
        st.vx = vx0 + dvx * dt;
        st.vy = vy0 + dvy * dt;
        st.r = r0 + dr * dt;
        if st.vx <= 0.0 {
            st.vx = 0.0;
            st.vy = 0.0;
            st.r = 0.0;
        }
    }

    /// The dynamic single-track model's derivatives of (vx, vy, r) with
    /// the tyres' lateral forces (`(cf, cr)`: cornering stiffnesses).
    fn dynamic_derivatives(
        &self,
        st: &State,
        fz: &[f64; 4],
        (fx_front, fx_rear): (f64, f64),
        resist: f64,
        (cf, cr): (f64, f64),
    ) -> (f64, f64, f64) {
        let spec = &self.spec;
        let (sd, cd) = st.delta.sin_cos();
        let (vx0, vy0, r0) = (st.vx, st.vy, st.r);
        let vx_eff = vx0.max(0.5);
        let alpha_f = st.delta - (vy0 + self.a * r0).atan2(vx_eff);
        let alpha_r = -(vy0 - self.b * r0).atan2(vx_eff);
        let mu = spec.mu;
        let catalogue = self.forms == EffectForms::Catalogue;
        let fy = |alpha: f64, fz: f64, c: f64, fz0: f64| {
            if catalogue {
                // Linear, at the static load: the rear slip angle is the
                // knob's k_beta a_y in steady cornering.
                c * alpha
            } else {
                vehicle::lateral_force(alpha, fz, mu, vehicle::cornering_stiffness(c, fz, fz0))
            }
        };
        let fyf = fy(alpha_f, fz[FL], cf, self.fz0_front) + fy(alpha_f, fz[FR], cf, self.fz0_front);
        let fyr = fy(alpha_r, fz[RL], cr, self.fz0_rear) + fy(alpha_r, fz[RR], cr, self.fz0_rear);
        let front_lat = fyf * cd + fx_front * sd;
        let dvx_dyn = (fx_front * cd - fyf * sd + fx_rear - resist) / self.m + vy0 * r0;
        let dvy_dyn = (front_lat + fyr) / self.m - vx0 * r0;
        let dr_dyn = (self.a * front_lat - self.b * fyr) / spec.yaw_inertia_kg_m2;
        (dvx_dyn, dvy_dyn, dr_dyn)
    }

    /// Wheels: the revolutions of each over `dt`, from the longitudinal
    /// speed of its contact point along it, rolling along the slope (`sec`
    /// of the grade), with the tyre's growth with speed and warm-up, its
    /// slip under `fx` (front, rear) and its radius under its load.
    fn roll_wheels(
        &self,
        st: &mut State,
        t: f64,
        dt: f64,
        sec: f64,
        loads: &Loads,
        (fx_front, fx_rear): (f64, f64),
    ) {
        let spec = &self.spec;
        let (vx, vy, r) = (st.vx, st.vy, st.r);
        let half_r = 0.5 * self.track_rear_true;
        let half_f = 0.5 * spec.track_front_m;
        let tan_d = st.delta.tan();
        let front_dir = |offset: f64| {
            // Ackermann: tan(delta_i) = L tan(delta) / (L - offset tan(delta)).
            let t = self.l * tan_d / (self.l - offset * tan_d);
            let c = 1.0 / (1.0 + t * t).sqrt();
            (c, t * c)
        };
        let (cl, sl) = front_dir(half_f);
        let (cr_, sr) = front_dir(-half_f);
        let v_front_lat = vy + self.a * r;
        let v_long = [
            vx - r * half_r,
            vx + r * half_r,
            (vx - r * half_f) * cl + v_front_lat * sl,
            (vx + r * half_f) * cr_ + v_front_lat * sr,
        ];
        // Wheels roll along the slope (sec of the grade); the tyre grows with
        // speed and warms up over time (a larger circumference turns less).
        let mut growth = 1.0 + self.k_v * vx * vx;
        if let Some((d, tc)) = self.drift {
            growth *= 1.0 + d * (1.0 - (-t / tc).exp());
        }
        let mut common = sec / growth;
        if let Some(m) = &self.speed_map {
            common /= 1.0 + m.at(vx, st.dvx);
        }
        // Lateral load change of each wheel relative to its static load:
        // the suspension's lagged loads, or in the catalogue's forms the
        // body's lateral acceleration now.
        let q = match self.forms {
            EffectForms::Physical => {
                let (d_lat_f, d_lat_r) = (loads.d_lat_f, loads.d_lat_r);
                [
                    -d_lat_r / self.fz0_rear,
                    d_lat_r / self.fz0_rear,
                    -d_lat_f / self.fz0_front,
                    d_lat_f / self.fz0_front,
                ]
            }
            EffectForms::Catalogue => {
                let (g_r, g_f) = (spec.rear_load_gain(), spec.front_load_gain());
                [-g_r * st.ay, g_r * st.ay, -g_f * st.ay, g_f * st.ay]
            }
        };
        for i in 0..4 {
            let driven = (i < 2) == spec.rear_wheel_drive;
            let slip = match (self.forms, self.slip_stiffness) {
                (EffectForms::Catalogue, _) if driven && v_long[i] > 0.0 => self.k_s * st.dvx,
                (EffectForms::Physical, Some(cx)) if v_long[i] > 0.0 => {
                    let fx_wheel = 0.5 * if i < 2 { fx_rear } else { fx_front };
                    vehicle::longitudinal_slip_for_force(fx_wheel, loads.fz[i], spec.mu, cx)
                }
                _ => 0.0,
            };
            let c = self.c_static[i] * (1.0 - self.radius_load_coeff * q[i]);
            st.revs[i] += v_long[i] * (1.0 + slip) * common / c * dt;
        }
    }

    /// Rear-axle pose (midpoint heading, as eq. (1)).
    fn move_rear_axle(&self, st: &mut State, dt: f64) {
        let (vx, vy, r) = (st.vx, st.vy, st.r);
        let v_rear_lat = vy - self.b * r;
        let psi_mid = st.psi + 0.5 * r * dt;
        let (s, c) = psi_mid.sin_cos();
        st.x += (vx * c - v_rear_lat * s) * dt;
        st.y += (vx * s + v_rear_lat * c) * dt;
        st.psi += r * dt;
    }
}

/// The wheels' vertical loads (rl, rr, fl, fr), N, and the lateral load
/// transfer on each axle.
struct Loads {
    fz: [f64; 4],
    d_lat_f: f64,
    d_lat_r: f64,
}

/// Steps between samples of a sensor at `rate_hz`.
fn period_steps(name: &str, rate_hz: f64, dt: f64) -> Result<u64, SimError> {
    let p = 1.0 / (rate_hz * dt);
    let n = p.round();
    if !(n >= 1.0 && (p - n).abs() < 1e-6) {
        return Err(SimError::InvalidConfig(format!(
            "{name} rate {rate_hz} Hz does not divide into the {:.4} s step",
            dt
        )));
    }
    Ok(n as u64)
}

fn validate(config: &SimConfig) -> Result<(), SimError> {
    let bad = |s: String| Err(SimError::InvalidConfig(s));
    if !(1e-4..=0.01).contains(&config.step_s) {
        return bad(format!(
            "step_s = {} must lie within [0.0001, 0.01]",
            config.step_s
        ));
    }
    if let Some(d) = config.duration_s {
        if !(d > 0.0 && d <= MAX_DURATION_S) {
            return bad(format!(
                "duration {d} s must lie within (0, {MAX_DURATION_S}]"
            ));
        }
    }
    let c = config.true_circumferences();
    for (name, v) in [("rl", c.rl), ("rr", c.rr), ("fl", c.fl), ("fr", c.fr)] {
        if !(v.is_finite() && (0.5..=5.0).contains(&v)) {
            return bad(format!("true circumference of {name} = {v} m is out of range (check wear and unworn circumference)"));
        }
    }
    let nominal = config.nominal_circumference();
    if !(nominal.is_finite() && (0.5..=5.0).contains(&nominal)) {
        return bad(format!("nominal circumference {nominal} m is out of range"));
    }
    let e = &config.effects;
    let check = |id: &str, v: f64, lo: f64, hi: f64| -> Result<(), SimError> {
        if v.is_finite() && (lo..=hi).contains(&v) {
            Ok(())
        } else {
            Err(SimError::InvalidEffect {
                spec: format!("{id}={v}"),
                reason: format!("must lie within [{lo}, {hi}] (switch the effect off for none)"),
            })
        }
    };
    if let Some(s) = e.side_slip {
        check("side_slip", s.k_beta, 0.001, 0.05)?;
    }
    if let Some(s) = e.longitudinal_slip {
        check("longitudinal_slip", s.k_s, 1e-5, 0.05)?;
    }
    if let Some(k) = e.load_transfer_radius {
        check("load_transfer_radius", k.k_z, 0.0, 0.01)?;
    }
    if let Some(k) = e.speed_radius_growth {
        check("speed_radius_growth", k.k_v, -1e-4, 1e-4)?;
    }
    if let Some(d) = e.radius_drift {
        check("radius_drift", d.d, -0.1, 0.1)?;
        check("radius_drift.time_constant_s", d.time_constant_s, 1.0, 1e6)?;
    }
    if let Some(g) = e.road_grade {
        check("road_grade", g.grade, 0.0, 0.3)?;
    }
    if let Some(t) = e.gnss_latency {
        check("gnss_latency", t.tau_s, 0.0, 5.0)?;
    }
    if let Some(m) = &config.speed_map {
        // A wheel reading off by a fifth is a different wheel, not physics.
        if !m.is_valid() || m.max_abs() > 0.2 {
            return bad(format!(
                "speed_map must have ascending edges, one value more than edges, finite, and |m| at most 0.2 (largest {:.4})",
                m.max_abs()
            ));
        }
    }
    if let Some(w) = &config.yaw_wander {
        if !w.is_valid() {
            return bad(format!(
                "yaw_wander must have sigma_rad_s within [0, 0.1] and tau_s within [0.01, 10000] (got {} rad/s, {} s)",
                w.sigma_rad_s, w.tau_s
            ));
        }
    }
    let s = &config.sensors;
    for (name, v) in [
        ("gnss.white_sigma_m", s.gnss.white_sigma_m),
        ("gnss.gm_sigma_m", s.gnss.gm_sigma_m),
        ("gnss.outage_rate_per_h", s.gnss.outage_rate_per_h),
        ("imu.gz_sigma_rad_s", s.imu.gz_sigma_rad_s),
        ("imu.accel_sigma_m_s2", s.imu.accel_sigma_m_s2),
        ("heading.sigma_deg", s.heading.sigma_deg),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return bad(format!(
                "sensor setting {name} = {v} must be finite and non-negative"
            ));
        }
    }
    for (name, v) in [
        ("gnss.gm_tau_s", s.gnss.gm_tau_s),
        ("gnss.outage_mean_s", s.gnss.outage_mean_s),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return bad(format!("sensor setting {name} = {v} must be positive"));
        }
    }
    Ok(())
}

/// Random GNSS outages (Poisson starts, exponential lengths), generated lazily.
struct Outages {
    rate_per_s: f64,
    mean_s: f64,
    start: f64,
    end: f64,
}

impl Outages {
    fn new(rate_per_h: f64, mean_s: f64, rng: &mut ChaCha8Rng) -> Outages {
        let mut o = Outages {
            rate_per_s: rate_per_h / 3600.0,
            mean_s,
            start: f64::INFINITY,
            end: f64::INFINITY,
        };
        if o.rate_per_s > 0.0 {
            o.schedule(0.0, rng);
        }
        o
    }

    fn schedule(&mut self, after: f64, rng: &mut ChaCha8Rng) {
        let exp = |rng: &mut ChaCha8Rng, mean: f64| -mean * (1.0 - rng.random::<f64>()).ln();
        self.start = after + exp(rng, 1.0 / self.rate_per_s);
        self.end = self.start + exp(rng, self.mean_s);
    }

    fn active(&mut self, t: f64, rng: &mut ChaCha8Rng) -> bool {
        while t >= self.end {
            let end = self.end;
            self.schedule(end, rng);
        }
        t >= self.start
    }
}

fn rng_stream(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    rng
}

/// Which stop comes next (counting over laps) and the standstill at it.
struct Stops {
    next: usize,
    standing_s: f64,
}

impl Stops {
    /// Position (unwrapped arc length) and dwell of the `next` stop.
    fn upcoming(&self, route: &Route) -> Option<(f64, f64)> {
        let stops = route.stops();
        if stops.is_empty() {
            return None;
        }
        let (lap, i) = (self.next / stops.len(), self.next % stops.len());
        if !route.is_closed() && lap > 0 {
            return None;
        }
        let stop = stops[i];
        Some((stop.s + lap as f64 * route.length(), stop.dwell_s))
    }
}

struct Driver {
    s_along: f64,
    delta_cmd: f64,
    force_cmd: f64,
    parked: bool,
}

impl Driver {
    /// Steering as [`Driver::act`], and the force that keeps the vehicle
    /// on a prescribed progress `(s, v, a)` (arc length, speed and
    /// acceleration now): a position and speed loop around the
    /// acceleration's feed-forward; held on the brakes where the
    /// prescription stands.
    fn follow(
        &mut self,
        model: &Model,
        st: &State,
        route: &Route,
        (s_p, v_p, a_p): (f64, f64, f64),
    ) -> PathPoint {
        let spec = &model.spec;
        self.s_along = route.nearest_s(st.x, st.y, self.s_along, 12.0);
        let here = route.at(self.s_along);
        self.steer(model, st, route);
        let e_s = s_p - self.s_along;
        let grade_force = model.m * G * here.grade / (1.0 + here.grade * here.grade).sqrt();
        let resist = spec.resistance_n(st.vx) + grade_force;
        let hold = v_p < 0.05 && st.vx < 0.3 && e_s < 0.3;
        self.force_cmd = if hold {
            -0.3 * model.m * G
        } else {
            let v_target = (v_p + 1.0 * e_s).max(0.0);
            let a_cmd = (2.0 * (v_target - st.vx) + a_p).clamp(-8.0, spec.max_drive_accel_m_s2);
            model.m * a_cmd + resist
        };
        here
    }

    /// Pure pursuit on the rear axle with understeer feed-forward.
    fn steer(&mut self, model: &Model, st: &State, route: &Route) {
        let spec = &model.spec;
        let lookahead = (3.0 + 0.45 * st.vx).clamp(3.0, 25.0);
        let target = route.at(self.s_along + lookahead);
        let (dx, dy) = (target.x - st.x, target.y - st.y);
        let dist = dx.hypot(dy).max(0.5);
        let alpha = dy.atan2(dx) - st.psi;
        let kappa = 2.0 * alpha.sin() / dist;
        let understeer = if model.cornering.is_some() {
            spec.understeer_rad_per_m_s2 * st.vx * st.vx * kappa
        } else {
            0.0
        };
        self.delta_cmd = (model.l * kappa).atan() + understeer;
    }

    /// Steering (pure pursuit on the rear axle with understeer feed-forward)
    /// and the longitudinal force for the speed profile and stops.
    fn act(
        &mut self,
        model: &Model,
        st: &State,
        route: &Route,
        stops: &mut Stops,
        dt_driver: f64,
    ) -> PathPoint {
        let spec = &model.spec;
        self.s_along = route.nearest_s(st.x, st.y, self.s_along, 12.0);
        let here = route.at(self.s_along);
        self.steer(model, st, route);

        // Speed: the profile, or the approach to the next stop.
        let mut v_ref = here.v_ref;
        let mut a_ff = (st.vx * here.dv_ds).clamp(-here.attrs.decel, here.attrs.accel);
        let mut hold = self.parked;
        if let Some((s_stop, dwell)) = stops.upcoming(route) {
            let to_go = s_stop - self.s_along;
            let decel = here.attrs.decel;
            let v_stop = (2.0 * decel * (to_go - 0.3).max(0.0)).sqrt();
            if v_stop < v_ref {
                v_ref = v_stop;
                a_ff = if to_go > 0.3 { -decel } else { 0.0 };
            }
            if to_go < -2.0 {
                // Overshot: the stop is behind us.
                stops.next += 1;
                stops.standing_s = 0.0;
            } else if to_go < 1.5 && st.vx < 0.05 {
                hold = true;
                stops.standing_s += dt_driver;
                if stops.standing_s >= dwell {
                    stops.next += 1;
                    stops.standing_s = 0.0;
                    if !route.is_closed() && stops.upcoming(route).is_none() {
                        self.parked = true;
                    } else {
                        hold = false;
                    }
                }
            }
        }
        let grade_force = model.m * G * here.grade / (1.0 + here.grade * here.grade).sqrt();
        let resist = spec.resistance_n(st.vx) + grade_force;
        self.force_cmd = if hold {
            -0.3 * model.m * G
        } else {
            let a_cmd = (0.8 * (v_ref - st.vx) + a_ff)
                .clamp(-1.5 * here.attrs.decel.max(2.0), here.attrs.accel);
            let f = model.m * a_cmd + resist;
            f.min(model.m * spec.max_drive_accel_m_s2 + resist)
        };
        here
    }
}

/// The true effective rear track of `spec` under the `track_width` effect.
fn true_track_width(config: &SimConfig, spec: &VehicleSpec) -> f64 {
    config
        .effects
        .track_width
        .map_or(spec.track_rear_m, |t| spec.track_rear_m * (1.0 + t.rel))
}

/// Half the window the prescribed acceleration is taken over, s.
const PRESCRIBED_ACCEL_HALF_S: f64 = 0.25;

/// A prescribed progress along the route over time (the twin of a
/// recording): the driver follows it instead of the route's speed profile.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Prescribed {
    /// Time step of the samples, s (the first is at t = 0).
    pub dt: f64,
    /// Arc length along the route at each sample, m (non-decreasing).
    pub s: Vec<f64>,
    /// Speed at each sample, m/s.
    pub v: Vec<f64>,
    /// Time intervals (simulation time, s) without GNSS fixes.
    pub gnss_denied: Vec<(f64, f64)>,
}

impl Prescribed {
    /// Arc length, speed and acceleration at `t`.
    fn at(&self, t: f64) -> (f64, f64, f64) {
        let n = self.s.len();
        if n == 0 {
            return (0.0, 0.0, 0.0);
        }
        let f = (t / self.dt).max(0.0);
        let i = (f.floor() as usize).min(n.saturating_sub(2));
        let j = (i + 1).min(n - 1);
        let w = (f - i as f64).clamp(0.0, 1.0);
        let s = self.s[i] + w * (self.s[j] - self.s[i]);
        let v = self.v[i] + w * (self.v[j] - self.v[i]);
        // The acceleration's feed-forward over +-PRESCRIBED_ACCEL_HALF_S:
        // the speed comes from counted wheel ticks, and its difference from
        // one sample to the next would feed their quantisation to the force.
        let h = ((PRESCRIBED_ACCEL_HALF_S / self.dt).round() as usize).max(1);
        let (lo, hi) = (i.saturating_sub(h), (j + h).min(n - 1));
        let a = if hi > lo {
            (self.v[hi] - self.v[lo]) / ((hi - lo) as f64 * self.dt)
        } else {
            0.0
        };
        (s, v, a)
    }

    /// Length of the prescribed drive, s.
    pub(crate) fn duration_s(&self) -> f64 {
        self.s.len().saturating_sub(1) as f64 * self.dt
    }
}

/// What a simulation drives besides the configuration's scenario: a
/// route, a vehicle, optionally a prescribed progress over time and an
/// antenna offset (the twin of a recording).
pub(crate) struct Custom {
    /// The route and how the drive starts.
    pub route: ScenarioRoute,
    /// The vehicle.
    pub spec: VehicleSpec,
    /// Progress over time the driver follows (instead of `v_ref`).
    pub prescribed: Option<Prescribed>,
    /// Antenna position (body x, y from the rear-axle centre) declared in
    /// the vehicle.toml written, m; the fixes are taken there (on top of
    /// a `gnss_lever_arm` effect).
    pub antenna: Option<(f64, f64)>,
    /// The vehicle.toml's name.
    pub name: String,
}

/// Run one simulation.
pub(crate) fn run(config: &SimConfig) -> Result<Drive, SimError> {
    let grade_mag = config.effects.road_grade.map_or(0.0, |g| g.grade);
    let route = scenarios::build(config.scenario, grade_mag)?;
    let custom = Custom {
        route,
        spec: config.vehicle.spec(),
        prescribed: None,
        antenna: None,
        name: format!(
            "simulated {} ({} scenario)",
            config.vehicle.name(),
            config.scenario.name()
        ),
    };
    run_custom(config, &custom)
}

/// Run one simulation on a given route and vehicle.
pub(crate) fn run_custom(config: &SimConfig, custom: &Custom) -> Result<Drive, SimError> {
    validate(config)?;
    let ScenarioRoute {
        route,
        start_moving,
        default_duration_s,
    } = &custom.route;
    let (route, start_moving) = (route, *start_moving);
    let prescribed = custom.prescribed.as_ref();
    let model = Model::new(config, custom.spec);
    let dt = config.step_s;
    let periods = Periods::new(&config.sensors, dt)?;
    let duration = config
        .duration_s
        .or(*default_duration_s)
        .or(prescribed.map(Prescribed::duration_s));
    let end_step = duration.map(|d| (d / dt).round() as u64);
    let limit_steps = (DEFAULT_TIME_LIMIT_S / dt) as u64;
    let mut rec = Recorder::new(config, &periods, end_step);
    rec.wander = config.yaw_wander.as_ref().map(|w| {
        Wander::new(
            w,
            model.track_rear_true,
            [model.c_static[RL], model.c_static[RR]],
            config.seed,
        )
    });
    rec.denied = prescribed
        .map(|p| p.gnss_denied.clone())
        .unwrap_or_default();
    if let Some((x, y)) = custom.antenna {
        rec.lever.0 += x;
        rec.lever.1 += y;
    }

    let (mut st, mut driver) = start(&model, route, start_moving);
    let mut stops = Stops {
        next: 0,
        standing_s: 0.0,
    };
    let mut here = route.at(0.0);

    let mut k: u64 = 0;
    loop {
        let t = k as f64 * dt;
        let mut done = false;
        if k.is_multiple_of(periods.driver) {
            here = match prescribed {
                Some(p) => driver.follow(&model, &st, route, p.at(t)),
                None => driver.act(&model, &st, route, &mut stops, periods.driver as f64 * dt),
            };
        }
        if k.is_multiple_of(periods.wheel) {
            rec.wheels_and_truth(t, &st)?;
            done = match end_step {
                Some(end) => k >= end,
                None => route_done(route, &driver, &stops),
            };
            if !done && end_step.is_none() && k >= limit_steps {
                return Err(SimError::Stuck {
                    scenario: config.scenario.name().to_string(),
                    limit_s: DEFAULT_TIME_LIMIT_S,
                    s_m: driver.s_along,
                });
            }
        }
        if config.sensors.imu.enabled && k.is_multiple_of(periods.imu) {
            rec.imu(t, &st, &here);
        }
        if config.sensors.gnss.enabled && k.is_multiple_of(periods.gnss) {
            rec.gnss(t, &st, &here);
        }
        if config.sensors.heading.enabled && k.is_multiple_of(periods.heading) {
            rec.heading(t, &st);
        }
        if done {
            // Every sensor has sampled the final instant too.
            break;
        }
        model.step(
            &mut st,
            t,
            driver.delta_cmd,
            driver.force_cmd,
            here.grade,
            dt,
        );
        k += 1;
    }
    Ok(rec.into_drive(config, &model, route, custom))
}

/// The sampling periods of the sensors and of the driver, in steps.
struct Periods {
    wheel: u64,
    gnss: u64,
    imu: u64,
    heading: u64,
    driver: u64,
}

impl Periods {
    fn new(sensors: &SensorSettings, dt: f64) -> Result<Periods, SimError> {
        Ok(Periods {
            wheel: period_steps("wheel", sensors.wheels.rate_hz, dt)?,
            gnss: period_steps("GNSS", sensors.gnss.rate_hz, dt)?,
            imu: period_steps("IMU", sensors.imu.rate_hz, dt)?,
            heading: period_steps("heading", sensors.heading.rate_hz, dt)?,
            driver: period_steps("driver", DRIVER_RATE_HZ, dt)?,
        })
    }
}

/// The vehicle's state and its driver at the route's start (at rest, or
/// at the route's speed when the scenario starts moving).
fn start(model: &Model, route: &Route, start_moving: bool) -> (State, Driver) {
    let start = route.at(0.0);
    let mut st = State {
        x: start.x,
        y: start.y,
        psi: route.start_heading(),
        ..State::default()
    };
    let driver = Driver {
        s_along: 0.0,
        delta_cmd: 0.0,
        force_cmd: 0.0,
        parked: false,
    };
    if start_moving {
        st.vx = start.v_ref;
        st.vy = 0.0;
        st.force = model.spec.resistance_n(st.vx);
    }
    (st, driver)
}

/// Whether a drive without a set duration is over: a closed route (whose
/// last stop is not at its end) after one lap, any other once the dwell
/// at its final stop is over.
fn route_done(route: &Route, driver: &Driver, stops: &Stops) -> bool {
    if route.is_closed()
        && route
            .stops()
            .last()
            .is_none_or(|s| s.s < route.length() - 1.0)
    {
        driver.s_along >= route.length()
    } else {
        // Ends at its final stop once the dwell is over.
        let n = route.stops().len();
        n > 0 && stops.next >= n
    }
}

/// Slower than this the car stands for the wheels' yaw wander, m/s.
const WANDER_MOVING_M_S: f64 = 0.5;

/// The wheels' yaw wander on the rear wheels' revolutions: a Gauss-Markov
/// yaw rate `w` that turns the right wheel faster and the left slower by
/// `w track / 2` of surface speed while the car moves (its own noise
/// stream, so that no other noise of a seed changes with it).
struct Wander {
    gm: GaussMarkov,
    rng: ChaCha8Rng,
    /// Half the rear track over each rear wheel's circumference, 1/rad.
    gain: [f64; 2],
    /// The revolutions added so far (rl, rr).
    added: [f64; 2],
    last_t: Option<f64>,
}

impl Wander {
    fn new(w: &interfaces::yaw_wander::YawWander, track_m: f64, c: [f64; 2], seed: u64) -> Wander {
        let mut rng = rng_stream(seed, 7);
        Wander {
            gm: GaussMarkov::new(w.sigma_rad_s, w.tau_s, &mut rng),
            rng,
            gain: [0.5 * track_m / c[0], 0.5 * track_m / c[1]],
            added: [0.0; 2],
            last_t: None,
        }
    }

    /// The revolutions added up to `t` (rl, rr), the car at `vx`.
    fn advance(&mut self, t: f64, vx: f64) -> [f64; 2] {
        let dt = self.last_t.map_or(0.0, |last| t - last);
        self.last_t = Some(t);
        if dt > 0.0 {
            let w = self.gm.step(dt, &mut self.rng);
            if vx > WANDER_MOVING_M_S {
                self.added[0] -= w * self.gain[0] * dt;
                self.added[1] += w * self.gain[1] * dt;
            }
        }
        self.added
    }
}

/// The sensors: their noise sources, the effects that act on them, and
/// the samples they have taken.
struct Recorder<'a> {
    sensors: &'a SensorSettings,
    effects: &'a EffectSettings,
    gnss_rng: ChaCha8Rng,
    gm_rng: ChaCha8Rng,
    outage_rng: ChaCha8Rng,
    imu_rng: ChaCha8Rng,
    heading_rng: ChaCha8Rng,
    /// The encoders' tick phases.
    phase: [f64; 4],
    gnss_dt: f64,
    gm: [GaussMarkov; 2],
    outages: Outages,
    gyro_bias: f64,
    gyro_scale: f64,
    latency: f64,
    lever: (f64, f64),
    ticks: Option<f64>,
    /// Time intervals without fixes (a twin's recorded outages).
    denied: Vec<(f64, f64)>,
    /// The wheels' yaw wander, when the configuration carries one.
    wander: Option<Wander>,
    wheels: Vec<WheelSample>,
    truth: Vec<TruthSample>,
    gnss: Vec<GnssSample>,
    imu: Vec<ImuSample>,
    heading: Vec<HeadingSample>,
}

impl<'a> Recorder<'a> {
    fn new(config: &'a SimConfig, periods: &Periods, end_step: Option<u64>) -> Recorder<'a> {
        let sensors = &config.sensors;
        let mut enc_rng = rng_stream(config.seed, 1);
        let gnss_rng = rng_stream(config.seed, 2);
        let mut gm_rng = rng_stream(config.seed, 3);
        let mut outage_rng = rng_stream(config.seed, 4);
        let imu_rng = rng_stream(config.seed, 5);
        let heading_rng = rng_stream(config.seed, 6);
        let phase: [f64; 4] = std::array::from_fn(|_| enc_rng.random::<f64>());
        let gm = [
            GaussMarkov::new(sensors.gnss.gm_sigma_m, sensors.gnss.gm_tau_s, &mut gm_rng),
            GaussMarkov::new(sensors.gnss.gm_sigma_m, sensors.gnss.gm_tau_s, &mut gm_rng),
        ];
        let outages = Outages::new(
            sensors.gnss.outage_rate_per_h,
            sensors.gnss.outage_mean_s,
            &mut outage_rng,
        );
        let e = &config.effects;
        let capacity = |period: u64| {
            let steps = end_step.unwrap_or(300_000);
            (steps / period + 2) as usize
        };
        Recorder {
            sensors,
            effects: e,
            gnss_rng,
            gm_rng,
            outage_rng,
            imu_rng,
            heading_rng,
            phase,
            gnss_dt: 1.0 / sensors.gnss.rate_hz,
            gm,
            outages,
            gyro_bias: e.gyro_bias.map_or(0.0, |b| b.b_deg_h.to_radians() / 3600.0),
            gyro_scale: e.gyro_scale.map_or(0.0, |s| s.s),
            latency: e.gnss_latency.map_or(0.0, |l| l.tau_s),
            lever: e.gnss_lever_arm.map_or((0.0, 0.0), |l| (l.x_m, l.y_m)),
            ticks: sensors.wheels.ticks_per_rev.map(f64::from),
            denied: Vec::new(),
            wander: None,
            wheels: Vec::with_capacity(capacity(periods.wheel)),
            truth: Vec::with_capacity(capacity(periods.wheel)),
            gnss: Vec::with_capacity(capacity(periods.gnss)),
            imu: Vec::with_capacity(capacity(periods.imu)),
            heading: Vec::with_capacity(capacity(periods.heading)),
        }
    }

    /// The wheel encoders and the truth pose at `t`; an error when the
    /// vehicle's state is no longer finite.
    fn wheels_and_truth(&mut self, t: f64, st: &State) -> Result<(), SimError> {
        if !(st.x.is_finite() && st.y.is_finite() && st.psi.is_finite() && st.vx.is_finite()) {
            return Err(SimError::Numerical {
                t_s: t,
                what: "vehicle state".into(),
            });
        }
        let (ticks, phase) = (self.ticks, self.phase);
        let mut revs = st.revs;
        if let Some(w) = self.wander.as_mut() {
            let [l, r] = w.advance(t, st.vx);
            revs[RL] += l;
            revs[RR] += r;
        }
        let value = |i: usize| match ticks {
            Some(n) => (revs[i] * n + phase[i]).floor(),
            None => revs[i],
        };
        self.wheels.push(WheelSample {
            t_s: t,
            rl: value(RL),
            rr: value(RR),
            fl: Some(value(FL)),
            fr: Some(value(FR)),
        });
        self.truth.push(TruthSample {
            t_s: t,
            x_m: st.x,
            y_m: st.y,
            yaw_rad: Some(stats::wrap_angle(st.psi)),
        });
        Ok(())
    }

    /// The IMU at `t`: yaw rate (with the gyro's scale and bias),
    /// accelerations (with gravity along the grade), pitch rate.
    fn imu(&mut self, t: f64, st: &State, here: &PathPoint) {
        let sensors = self.sensors;
        let rng = &mut self.imu_rng;
        let sigma = sensors.imu.gz_sigma_rad_s;
        let sa = sensors.imu.accel_sigma_m_s2;
        let pitch = here.grade.atan();
        let pitch_rate = here.dgrade_ds * st.vx / (1.0 + here.grade * here.grade);
        self.imu.push(ImuSample {
            t_s: t,
            gz_rad_s: (1.0 + self.gyro_scale) * st.r + self.gyro_bias + sigma * gauss(rng),
            ax_m_s2: Some(st.ax + G * pitch.sin() + sa * gauss(rng)),
            ay_m_s2: Some(st.ay + sa * gauss(rng)),
            az_m_s2: Some(G * pitch.cos() + sa * gauss(rng)),
            gx_rad_s: None,
            gy_rad_s: Some(pitch_rate + sigma * gauss(rng)),
        });
    }

    /// A GNSS fix at `t` (stamped late by the latency, at the antenna),
    /// unless the route denies GNSS there or a random outage is on; the
    /// noise runs on either way.
    fn gnss(&mut self, t: f64, st: &State, here: &PathPoint) {
        let noise = [
            self.gm[0].step(self.gnss_dt, &mut self.gm_rng),
            self.gm[1].step(self.gnss_dt, &mut self.gm_rng),
        ];
        let white = self.sensors.gnss.white_sigma_m;
        let wx = white * gauss(&mut self.gnss_rng);
        let wy = white * gauss(&mut self.gnss_rng);
        let out = self.outages.active(t, &mut self.outage_rng);
        let denied = self.denied.iter().any(|&(a, b)| t >= a && t <= b);
        if !here.attrs.gnss_denied && !out && !denied {
            let (s, c) = st.psi.sin_cos();
            let sigma = self.sensors.gnss.sigma_m();
            let lever = self.lever;
            self.gnss.push(GnssSample {
                t_s: t + self.latency,
                x_m: st.x + c * lever.0 - s * lever.1 + noise[0] + wx,
                y_m: st.y + s * lever.0 + c * lever.1 + noise[1] + wy,
                sigma_m: (sigma > 0.0).then_some(sigma),
            });
        }
    }

    /// The absolute heading at `t`, with its bias and noise.
    fn heading(&mut self, t: f64, st: &State) {
        let sigma = self.sensors.heading.sigma_deg.to_radians();
        let bias = self
            .effects
            .heading_bias
            .map_or(0.0, |h| h.error_rad(st.psi));
        self.heading.push(HeadingSample {
            t_s: t,
            yaw_rad: stats::wrap_angle(st.psi + bias + sigma * gauss(&mut self.heading_rng)),
            sigma_rad: (sigma > 0.0).then_some(sigma),
        });
    }

    /// The drive the samples make, with its vehicle.toml and truth.toml.
    fn into_drive(
        mut self,
        config: &SimConfig,
        model: &Model,
        route: &Route,
        custom: &Custom,
    ) -> Drive {
        let t_end = self.wheels.last().map_or(0.0, |w| w.t_s);
        // A late-stamped fix after the recording stopped would not be in the log.
        self.gnss.retain(|g| g.t_s <= t_end + 1e-9);
        self.imu.retain(|s| s.t_s <= t_end + 1e-9);
        self.heading.retain(|s| s.t_s <= t_end + 1e-9);

        let sensors = &config.sensors;
        let spec = &model.spec;
        let unit = if self.ticks.is_some() {
            WheelUnit::Ticks
        } else {
            WheelUnit::Rev
        };
        let truth_params = TruthParams {
            track_width_m: model.track_rear_true,
            circumference_m: config.true_circumferences(),
            effects: config.effects.to_truth_map(),
            extra: extra_keys(config, route, t_end, spec),
        };
        Drive {
            vehicle: VehicleParams {
                name: Some(custom.name.clone()),
                track_width_m: spec.track_rear_m,
                nominal_circumference_m: config.nominal_circumference(),
                wheelbase_m: Some(spec.wheelbase_m),
                ticks_per_rev: self.ticks,
                gnss: GnssAntenna {
                    antenna_x_m: custom.antenna.map(|a| a.0),
                    antenna_y_m: custom.antenna.map(|a| a.1),
                    ..GnssAntenna::default()
                },
            },
            wheels: WheelSeries {
                units: WheelUnits::all(unit),
                samples: self.wheels,
            },
            gnss: sensors.gnss.enabled.then_some(self.gnss),
            imu: sensors.imu.enabled.then_some(self.imu),
            heading: sensors.heading.enabled.then_some(self.heading),
            truth: Some(self.truth),
            truth_params: Some(truth_params),
        }
    }
}

fn extra_keys(
    config: &SimConfig,
    route: &Route,
    t_end: f64,
    spec: &VehicleSpec,
) -> BTreeMap<String, Value> {
    let f = Value::Float;
    let table = |pairs: Vec<(&str, Value)>| {
        Value::Table(pairs.into_iter().map(|(k, v)| (k.to_string(), v)).collect())
    };
    let s = &config.sensors;
    let w = &config.wear_mm;
    let mut extra = BTreeMap::new();
    extra.insert(
        "scenario".into(),
        Value::String(config.scenario.name().into()),
    );
    extra.insert(
        "seed".into(),
        i64::try_from(config.seed)
            .map_or_else(|_| Value::String(config.seed.to_string()), Value::Integer),
    );
    extra.insert(
        "vehicle".into(),
        Value::String(config.vehicle.name().into()),
    );
    extra.insert("duration_s".into(), f(t_end));
    extra.insert("route_length_m".into(), f(route.length()));
    extra.insert("step_s".into(), f(config.step_s));
    extra.insert(
        "unworn_circumference_m".into(),
        f(config.unworn_circumference()),
    );
    extra.insert("nominal_track_width_m".into(), f(spec.track_rear_m));
    if config.effect_forms != EffectForms::Physical {
        extra.insert(
            "effect_forms".into(),
            Value::String(config.effect_forms.name().into()),
        );
    }
    if let Some(m) = &config.speed_map {
        let steps = |s: &interfaces::speed_map::Steps| {
            table(vec![
                (
                    "edges",
                    Value::Array(s.edges.iter().map(|&x| f(x)).collect()),
                ),
                (
                    "values",
                    Value::Array(s.values.iter().map(|&x| f(x)).collect()),
                ),
            ])
        };
        extra.insert(
            "speed_map".into(),
            table(vec![
                ("speed_m_s", steps(&m.speed_m_s)),
                ("accel_m_s2", steps(&m.accel_m_s2)),
            ]),
        );
    }
    if let Some(w) = &config.yaw_wander {
        extra.insert(
            "yaw_wander".into(),
            table(vec![
                ("sigma_rad_s", f(w.sigma_rad_s)),
                ("tau_s", f(w.tau_s)),
            ]),
        );
    }
    extra.insert(
        "driven_axle".into(),
        Value::String(
            if spec.rear_wheel_drive {
                "rear"
            } else {
                "front"
            }
            .into(),
        ),
    );
    extra.insert(
        "wear_mm".into(),
        table(vec![
            ("rl", f(w.rl)),
            ("rr", f(w.rr)),
            ("fl", f(w.fl)),
            ("fr", f(w.fr)),
        ]),
    );
    let mut wheels = vec![("rate_hz", f(s.wheels.rate_hz))];
    if let Some(t) = s.wheels.ticks_per_rev {
        wheels.push(("ticks_per_rev", Value::Integer(i64::from(t))));
    }
    extra.insert(
        "sensors".into(),
        table(vec![
            ("wheels", table(wheels)),
            (
                "gnss",
                table(vec![
                    ("enabled", Value::Bool(s.gnss.enabled)),
                    ("rate_hz", f(s.gnss.rate_hz)),
                    ("white_sigma_m", f(s.gnss.white_sigma_m)),
                    ("gm_sigma_m", f(s.gnss.gm_sigma_m)),
                    ("gm_tau_s", f(s.gnss.gm_tau_s)),
                    ("outage_rate_per_h", f(s.gnss.outage_rate_per_h)),
                    ("outage_mean_s", f(s.gnss.outage_mean_s)),
                ]),
            ),
            (
                "imu",
                table(vec![
                    ("enabled", Value::Bool(s.imu.enabled)),
                    ("rate_hz", f(s.imu.rate_hz)),
                    ("gz_sigma_rad_s", f(s.imu.gz_sigma_rad_s)),
                    ("accel_sigma_m_s2", f(s.imu.accel_sigma_m_s2)),
                ]),
            ),
            (
                "heading",
                table(vec![
                    ("enabled", Value::Bool(s.heading.enabled)),
                    ("rate_hz", f(s.heading.rate_hz)),
                    ("sigma_deg", f(s.heading.sigma_deg)),
                ]),
            ),
        ]),
    );
    extra
}

#[cfg(test)]
mod tests {
    use super::super::{EffectSettings, Scenario, SimConfig};
    use super::*;

    #[test]
    fn bad_configurations_are_typed_errors() {
        let base = SimConfig::new(Scenario::Paper, 1);
        let mut c = base.clone();
        c.step_s = 0.05;
        assert!(matches!(run(&c), Err(SimError::InvalidConfig(_))));
        let mut c = base.clone();
        c.sensors.gnss.rate_hz = 3.0;
        let err = run(&c).unwrap_err().to_string();
        assert!(err.contains("GNSS rate 3 Hz"), "{err}");
        let mut c = base.clone();
        c.effects.apply_spec("side_slip=0.0005").unwrap();
        assert!(matches!(run(&c), Err(SimError::InvalidEffect { .. })));
        let mut c = base.clone();
        c.wear_mm.rl = 400.0;
        assert!(run(&c).unwrap_err().to_string().contains("rl"));
        let mut c = base;
        c.duration_s = Some(-1.0);
        assert!(run(&c).is_err());
    }

    #[test]
    fn a_short_drive_has_every_stream_on_one_clock() {
        let mut c = SimConfig::new(Scenario::Mixed, 2);
        c.duration_s = Some(5.0);
        c.effects = EffectSettings::none();
        c.effects.apply_spec("gnss_latency=0.05").unwrap();
        let d = run(&c).unwrap();
        assert_eq!(d.wheels.samples.len(), 501);
        assert_eq!(d.truth.as_ref().map(Vec::len), Some(501));
        let gnss = d.gnss.as_ref().unwrap();
        assert_eq!(
            gnss.len(),
            50,
            "10 Hz, the last fix stamped after 5 s is not logged"
        );
        assert!((gnss[0].t_s - 0.05).abs() < 1e-12);
        assert_eq!(d.imu.as_ref().map(Vec::len), Some(501));
        assert_eq!(d.heading.as_ref().map(Vec::len), Some(51));
        let tp = d.truth_params.unwrap();
        assert_eq!(tp.effects.len(), 1);
        assert_eq!(tp.extra.get("seed"), Some(&Value::Integer(2)));
    }

    /// A speed map turns the wheels `1 / (1 + m)` times as fast where it
    /// applies and nowhere else, and truth.toml says what was carried.
    #[test]
    fn a_speed_map_slows_the_wheels_where_it_applies() {
        use interfaces::speed_map::{SpeedMap, Steps};
        let mut c = SimConfig::new(Scenario::Mixed, 2);
        c.duration_s = Some(120.0);
        c.effects = EffectSettings::none();
        let plain = run(&c).unwrap();
        let map = SpeedMap {
            speed_m_s: Steps {
                edges: vec![5.0],
                values: vec![0.0, 0.02],
            },
            accel_m_s2: Steps::zero(),
        };
        c.speed_map = Some(map.clone());
        let mapped = run(&c).unwrap();
        // Over 1 s steps, by the truth's speed there: the revolutions'
        // ratio, summed (a tick's quantisation per step averages out).
        let (p, m) = (&plain.wheels.samples, &mapped.wheels.samples);
        let truth = plain.truth.as_ref().unwrap();
        let (mut fast, mut slow) = ([0.0, 0.0], [0.0, 0.0]);
        for k in (100..p.len()).step_by(100) {
            let (dp, dm) = (p[k].rl - p[k - 100].rl, m[k].rl - m[k - 100].rl);
            let dx = truth[k].x_m - truth[k - 100].x_m;
            let dy = truth[k].y_m - truth[k - 100].y_m;
            let v = dx.hypot(dy);
            if v > 6.0 {
                slow[0] += dm;
                slow[1] += dp;
            } else if v < 4.0 {
                fast[0] += dm;
                fast[1] += dp;
            }
        }
        assert!(slow[1] > 500.0 && fast[1] > 50.0, "{slow:?} {fast:?}");
        assert!((slow[0] / slow[1] - 1.0 / 1.02).abs() < 2e-3, "{slow:?}");
        assert!((fast[0] / fast[1] - 1.0).abs() < 0.01, "{fast:?}");
        let tp = mapped.truth_params.unwrap();
        let Some(Value::Table(table)) = tp.extra.get("speed_map") else {
            panic!("no speed_map table in truth.toml: {:?}", tp.extra);
        };
        let values = |signal: &str| match table.get(signal) {
            Some(Value::Table(t)) => t.get("values").cloned(),
            _ => None,
        };
        assert_eq!(
            values("speed_m_s"),
            Some(Value::Array(vec![Value::Float(0.0), Value::Float(0.02)]))
        );
        assert!(!plain.truth_params.unwrap().extra.contains_key("speed_map"));
        // A map beyond a fifth is refused.
        c.speed_map = Some(SpeedMap {
            speed_m_s: Steps {
                edges: vec![],
                values: vec![0.5],
            },
            accel_m_s2: Steps::zero(),
        });
        assert!(matches!(run(&c), Err(SimError::InvalidConfig(_))));
    }

    #[test]
    fn a_yaw_wander_turns_the_rear_wheels_apart_by_a_gauss_markov_yaw_rate() {
        use interfaces::yaw_wander::YawWander;
        let mut c = SimConfig::new(Scenario::Mixed, 3);
        c.duration_s = Some(300.0);
        c.effects = EffectSettings::none();
        c.sensors.wheels.ticks_per_rev = None;
        let plain = run(&c).unwrap();
        let w = YawWander {
            sigma_rad_s: 0.01,
            tau_s: 4.0,
        };
        c.yaw_wander = Some(w);
        let wandered = run(&c).unwrap();
        // Its own noise stream: every other sensor is the same draw.
        assert_eq!(plain.gnss, wandered.gnss);
        assert_eq!(plain.imu, wandered.imu);
        // The yaw rate it adds, over 1 s steps while moving: the rear
        // wheels' added surface distance apart over the track.
        let circ = c.true_circumferences();
        let track = c.vehicle.spec().track_rear_m;
        let (p, m) = (&plain.wheels.samples, &wandered.wheels.samples);
        let added =
            |k: usize| ((m[k].rr - p[k].rr) * circ.rr - (m[k].rl - p[k].rl) * circ.rl) / track;
        let moving = |k: usize| p[k].rl - p[k - 100].rl > 1.0;
        let rates: Vec<f64> = (100..p.len())
            .step_by(100)
            .filter(|&k| moving(k))
            .map(|k| added(k) - added(k - 100))
            .collect();
        assert!(rates.len() > 150, "{}", rates.len());
        let n = rates.len() as f64;
        let mean = rates.iter().sum::<f64>() / n;
        let sd = (rates.iter().map(|r| (r - mean) * (r - mean)).sum::<f64>() / n).sqrt();
        // A 1 s mean of the process keeps most of its variance at tau 4 s
        // (0.92 of sigma); over 300 s it is drawn from about 40 correlation
        // times.
        assert!(sd > 0.6 * w.sigma_rad_s && sd < 1.3 * w.sigma_rad_s, "{sd}");
        let lag1: f64 = rates
            .windows(2)
            .map(|x| (x[0] - mean) * (x[1] - mean))
            .sum::<f64>()
            / (n * sd * sd);
        assert!(lag1 > 0.5, "lag-1 autocorrelation {lag1}");
        // Standing still, nothing is added.
        let still: Vec<usize> = (100..p.len())
            .step_by(100)
            .filter(|&k| p[k].rl == p[k - 100].rl)
            .collect();
        assert!(still.len() > 3, "the drive stands for {} s", still.len());
        for k in still {
            assert_eq!(added(k), added(k - 100), "at sample {k}");
        }
        let tp = wandered.truth_params.unwrap();
        let Some(Value::Table(table)) = tp.extra.get("yaw_wander") else {
            panic!("no yaw_wander table in truth.toml: {:?}", tp.extra);
        };
        assert_eq!(table.get("tau_s"), Some(&Value::Float(4.0)));
        c.yaw_wander = Some(YawWander {
            sigma_rad_s: 0.5,
            tau_s: 4.0,
        });
        assert!(matches!(run(&c), Err(SimError::InvalidConfig(_))));
    }
}
