//! Synthetic drives for the tests: exact 2W kinematics (the model the
//! calibrator fits), GNSS with seeded white noise, a yaw-rate gyro with bias
//! and scale. Small and fast; the simulator covers the physics.

#![allow(dead_code)]
// Test helpers: a failure here is a broken test set-up, a panic is the right answer.
#![allow(clippy::expect_used, clippy::unwrap_used)]

use interfaces::drive::{
    Drive, GnssAntenna, GnssSample, ImuSample, TruthSample, VehicleParams, WheelSample,
    WheelSeries, WheelUnit, WheelUnits,
};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// One piece of the route.
#[derive(Debug, Clone, Copy)]
pub enum Leg {
    /// Straight, length m, speed from v0 to v1 (m/s).
    Straight(f64, f64, f64),
    /// Turn by `deg` (positive left) on radius `r` at speed `v`.
    Turn(f64, f64, f64),
    /// Stand still for `s` seconds.
    Stop(f64),
}

/// What to generate.
#[derive(Debug, Clone)]
pub struct Synth {
    pub c_rl: f64,
    pub c_rr: f64,
    pub track: f64,
    pub nominal_c: f64,
    pub nominal_track: f64,
    pub lever: [f64; 2],
    pub lever_in_vehicle_toml: bool,
    pub gyro_bias: f64,
    pub gyro_scale: f64,
    pub gyro_noise: f64,
    pub gnss_sigma: f64,
    pub gnss_late_s: f64,
    pub seed: u64,
    pub legs: Vec<Leg>,
    pub imu: bool,
}

impl Default for Synth {
    fn default() -> Self {
        Synth {
            c_rl: 1.9962,
            c_rr: 1.9991,
            track: 1.55,
            nominal_c: 2.0,
            nominal_track: 1.55,
            lever: [0.0, 0.0],
            lever_in_vehicle_toml: true,
            gyro_bias: 0.002,
            gyro_scale: 0.01,
            gyro_noise: 0.002,
            gnss_sigma: 0.5,
            gnss_late_s: 0.0,
            seed: 1,
            legs: route(),
            imu: true,
        }
    }
}

/// A 2.5 km loop with turns both ways, speed changes and two stops.
pub fn route() -> Vec<Leg> {
    vec![
        Leg::Stop(3.0),
        Leg::Straight(60.0, 0.0, 12.0),
        Leg::Straight(200.0, 12.0, 15.0),
        Leg::Turn(90.0, 50.0, 12.0),
        Leg::Straight(150.0, 12.0, 16.0),
        Leg::Turn(-120.0, 40.0, 11.0),
        Leg::Straight(120.0, 11.0, 6.0),
        Leg::Straight(120.0, 6.0, 14.0),
        Leg::Turn(180.0, 30.0, 9.0),
        Leg::Straight(250.0, 9.0, 16.0),
        Leg::Turn(-90.0, 60.0, 13.0),
        Leg::Straight(100.0, 13.0, 13.0),
        Leg::Turn(45.0, 80.0, 14.0),
        Leg::Straight(300.0, 14.0, 17.0),
        Leg::Turn(-60.0, 70.0, 13.0),
        Leg::Straight(200.0, 13.0, 8.0),
        Leg::Turn(135.0, 35.0, 8.0),
        Leg::Straight(150.0, 8.0, 0.0),
        Leg::Stop(4.0),
    ]
}

/// A nearly straight drive (no turn).
pub fn straight_route() -> Vec<Leg> {
    vec![
        Leg::Straight(50.0, 0.0, 15.0),
        Leg::Straight(1500.0, 15.0, 15.0),
        Leg::Turn(3.0, 500.0, 15.0),
        Leg::Straight(500.0, 15.0, 15.0),
    ]
}

impl Synth {
    /// Generate the drive.
    pub fn drive(&self) -> Drive {
        let dt = 0.01;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(self.seed);
        let gnss_noise = Normal::new(0.0, self.gnss_sigma.max(1e-12)).expect("normal");
        let gyro_noise = Normal::new(0.0, self.gyro_noise.max(1e-12)).expect("normal");
        let (mut x, mut y, mut th) = (0.0f64, 0.0f64, 0.3f64);
        let (mut n_rl, mut n_rr) = (0.0f64, 0.0f64);
        let mut t = 0.0f64;
        let mut wheels = Vec::new();
        let mut gnss = Vec::new();
        let mut imu = Vec::new();
        let mut truth = Vec::new();
        let mut k = 0usize;
        let mut record = |t: f64,
                          x: f64,
                          y: f64,
                          th: f64,
                          n_rl: f64,
                          n_rr: f64,
                          w: f64,
                          k: usize,
                          rng: &mut rand_chacha::ChaCha8Rng| {
            wheels.push(WheelSample {
                t_s: t,
                rl: n_rl,
                rr: n_rr,
                fl: None,
                fr: None,
            });
            truth.push(TruthSample {
                t_s: t,
                x_m: x,
                y_m: y,
                yaw_rad: Some(th),
            });
            imu.push(ImuSample {
                t_s: t,
                gz_rad_s: (1.0 + self.gyro_scale) * w + self.gyro_bias + gyro_noise.sample(rng),
                ax_m_s2: None,
                ay_m_s2: None,
                az_m_s2: None,
                gx_rad_s: None,
                gy_rad_s: None,
            });
            if k.is_multiple_of(10) {
                let (s, c) = th.sin_cos();
                gnss.push(GnssSample {
                    t_s: t + self.gnss_late_s,
                    x_m: x + c * self.lever[0] - s * self.lever[1] + gnss_noise.sample(rng),
                    y_m: y + s * self.lever[0] + c * self.lever[1] + gnss_noise.sample(rng),
                    sigma_m: None,
                });
            }
        };
        record(t, x, y, th, n_rl, n_rr, 0.0, k, &mut rng);
        for leg in &self.legs {
            // (duration, speed at fraction f, curvature)
            let (dur, v_at, kappa): (f64, Box<dyn Fn(f64) -> f64>, f64) = match *leg {
                Leg::Straight(len, v0, v1) => {
                    let vm = 0.5 * (v0 + v1);
                    (len / vm, Box::new(move |f| v0 + f * (v1 - v0)), 0.0)
                }
                Leg::Turn(deg, r, v) => {
                    let len = deg.to_radians().abs() * r;
                    (len / v, Box::new(move |_| v), deg.signum() / r)
                }
                Leg::Stop(s) => (s, Box::new(|_| 0.0), 0.0),
            };
            let steps = (dur / dt).round().max(1.0) as usize;
            for i in 0..steps {
                let f = (i as f64 + 0.5) / steps as f64;
                let v = v_at(f);
                let ds = v * dt;
                let dth = kappa * ds;
                let course = th + 0.5 * dth;
                x += ds * course.cos();
                y += ds * course.sin();
                th += dth;
                n_rl += ds * (1.0 - kappa * self.track / 2.0) / self.c_rl;
                n_rr += ds * (1.0 + kappa * self.track / 2.0) / self.c_rr;
                t += dt;
                k += 1;
                record(t, x, y, th, n_rl, n_rr, dth / dt, k, &mut rng);
            }
        }
        Drive {
            vehicle: VehicleParams {
                name: Some("synthetic".to_string()),
                track_width_m: self.nominal_track,
                nominal_circumference_m: self.nominal_c,
                wheelbase_m: None,
                ticks_per_rev: None,
                gnss: if self.lever_in_vehicle_toml && self.lever != [0.0, 0.0] {
                    GnssAntenna {
                        antenna_x_m: Some(self.lever[0]),
                        antenna_y_m: Some(self.lever[1]),
                        ..GnssAntenna::default()
                    }
                } else {
                    GnssAntenna::default()
                },
            },
            wheels: WheelSeries {
                units: WheelUnits::rear(WheelUnit::Rev),
                samples: wheels,
            },
            gnss: Some(gnss),
            imu: self.imu.then_some(imu),
            heading: None,
            truth: Some(truth),
            truth_params: None,
        }
    }
}

/// Both circumference errors of `cal` against `s`, mm.
pub fn errors_mm(cal: &calibrator::Calibration, s: &Synth) -> (f64, f64) {
    (
        1000.0 * (cal.circumference_m.rl - s.c_rl),
        1000.0 * (cal.circumference_m.rr - s.c_rr),
    )
}
