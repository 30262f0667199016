//! The 2W model extended with the physics-catalogue effects
//! (`shared/design/physics-catalogue.md`): one home for the effect terms that
//! the diagnosis fits, that travel with an estimate and that the odometry
//! applies when it dead-reckons.
//!
//! [`EffectTerms`] holds one coefficient per effect, zero when the effect is
//! not modelled, so `EffectTerms::default()` is the paper's plain 2W model.
//! [`EffectTerms::increments`] turns the rear wheels' revolution increments
//! into the centre distance, heading change and side-slip angle of one step
//! of eq. (1), given the few signals the terms read ([`StepSignals`]).
//!
//! Sign conventions (body x forward, y left, positive yaw rate turns left,
//! a_y = v w positive in a left turn):
//! - `side_slip`: beta = -k_beta a_y (the rear axle slips outward of the turn);
//! - `load_transfer_radius`: c_RL = c (1 + k_z a_y), c_RR = c (1 - k_z a_y)
//!   (the outer wheel carries more load and rolls on a smaller radius);
//! - `speed_radius_growth`: c (1 + k_v v^2);
//! - `longitudinal_slip`: the rear wheels turn as if the car went
//!   v (1 + k_s a_x);
//! - `track_width`: the effective track is nominal (1 + track_rel);
//! - `radius_drift`: c (1 + d (1 - exp(-t / T))), t from the drive's start;
//! - `road_grade`: the wheels roll along the slope, the horizontal distance is
//!   ds cos(gain * grade), grade from the IMU's pitch;
//! - `gnss_latency`, `gnss_lever_arm`, `gyro_bias`, `gyro_scale`,
//!   `heading_bias` act on the sensors, not on the wheels: they are carried
//!   here so that the model that scores a fix or a heading uses them.

use interfaces::effects::{Carried, Effect, Param};
use interfaces::wire::{ModelExtension, MAX_EXTENSION_PARAMS};
use serde::{Deserialize, Serialize};

/// One coefficient per catalogue effect; zero = not modelled.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct EffectTerms {
    /// `side_slip`: k_beta, rad per m/s^2 of lateral acceleration.
    pub k_beta: f64,
    /// `load_transfer_radius`: k_z, relative radius change per m/s^2.
    pub k_z: f64,
    /// `speed_radius_growth`: k_v, relative growth per (m/s)^2.
    pub k_v: f64,
    /// `longitudinal_slip`: k_s, relative wheel-speed excess per m/s^2.
    pub k_s: f64,
    /// `track_width`: relative difference of the effective from the nominal track.
    pub track_rel: f64,
    /// `radius_drift`: final relative change d.
    pub drift_d: f64,
    /// `radius_drift`: time constant T, s (0 when not modelled).
    pub drift_time_constant_s: f64,
    /// `road_grade`: gain on the IMU grade signal (1 = the grade as measured).
    pub grade_gain: f64,
    /// `gnss_latency`: fixes describe the instant this much before their stamp, s.
    pub gnss_latency_s: f64,
    /// `gnss_lever_arm`: antenna from the rear-axle centre, body x, y, m.
    pub lever_arm_m: [f64; 2],
    /// `gyro_bias`: rad/s added to the true yaw rate.
    pub gyro_bias_rad_s: f64,
    /// `gyro_scale`: the gyro reads (1 + s) times the true yaw rate.
    pub gyro_scale: f64,
    /// `heading_bias`: A, B, C of A + B sin(psi) + C cos(psi), rad.
    pub heading_bias_rad: [f64; 3],
}

/// The wheel-side terms alone (what an estimate carries to the odometer):
/// side-slip, load transfer, speed growth, longitudinal slip, track width,
/// radius drift. Small enough to travel in every estimate.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct WheelEffects {
    /// `side_slip` k_beta.
    pub k_beta: f64,
    /// `load_transfer_radius` k_z.
    pub k_z: f64,
    /// `speed_radius_growth` k_v.
    pub k_v: f64,
    /// `longitudinal_slip` k_s.
    pub k_s: f64,
    /// `track_width` rel.
    pub track_rel: f64,
    /// `radius_drift` d.
    pub drift_d: f64,
    /// `radius_drift` T, s.
    pub drift_time_constant_s: f64,
}

impl WheelEffects {
    /// No term acts on the wheels: the plain 2W model (a warm-up without
    /// its time constant does not act).
    pub fn is_plain(&self) -> bool {
        self.k_beta == 0.0
            && self.k_z == 0.0
            && self.k_v == 0.0
            && self.k_s == 0.0
            && self.track_rel == 0.0
            && (self.drift_d == 0.0
                || self.drift_time_constant_s.is_nan()
                || self.drift_time_constant_s <= 0.0)
    }
}

impl From<EffectTerms> for WheelEffects {
    fn from(t: EffectTerms) -> WheelEffects {
        WheelEffects {
            k_beta: t.k_beta,
            k_z: t.k_z,
            k_v: t.k_v,
            k_s: t.k_s,
            track_rel: t.track_rel,
            drift_d: t.drift_d,
            drift_time_constant_s: t.drift_time_constant_s,
        }
    }
}

impl From<WheelEffects> for EffectTerms {
    fn from(w: WheelEffects) -> EffectTerms {
        EffectTerms {
            k_beta: w.k_beta,
            k_z: w.k_z,
            k_v: w.k_v,
            k_s: w.k_s,
            track_rel: w.track_rel,
            drift_d: w.drift_d,
            drift_time_constant_s: w.drift_time_constant_s,
            ..EffectTerms::default()
        }
    }
}

/// The signals an effect term reads besides the wheels, at one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepSignals {
    /// Speed, m/s.
    pub v_m_s: f64,
    /// Longitudinal acceleration, m/s^2.
    pub a_x_m_s2: f64,
    /// Lateral acceleration v w, m/s^2 (positive in a left turn).
    pub a_y_m_s2: f64,
    /// Road grade (rise over run), from the IMU; 0 when unknown.
    pub grade: f64,
    /// Time since the drive's start, s.
    pub t_since_start_s: f64,
}

/// The terms whose step in [`EffectTerms::increments`] reads the lateral
/// acceleration [`StepSignals::a_y_m_s2`]: a model that reads a_y anew
/// (through a load transfer's estimate, [`lateral_acceleration_from_wheels`])
/// changes what these terms do and nothing else.
pub const READS_LATERAL_ACCELERATION: [Param; 2] = [Param::SideSlipGain, Param::LoadTransferGain];

/// The lateral acceleration a_y = v w from the rear wheels' own speed and yaw
/// rate, with the load transfer `k_z` taken out of the yaw rate.
///
/// The term under `load_transfer_radius` bends the very yaw rate a_y is read
/// from: the outer wheel rolls on a smaller radius, so the plain model's
/// yaw rate is w (1 + 2 k_z v^2 / t) (to first order in k_z a_y; t the
/// track). Read plainly, a_y is too large by that factor (15 % at 15 m/s and
/// 73 % at 33 m/s for k_z = 5e-4 on a 1.58 m track), and a fit that reads
/// it so finds k_z / (1 + 2 k_z v^2 / t): confidently low. Every consumer
/// that has only the wheels (the diagnosis's epochs, the odometer) reads
/// a_y through this function with the k_z it applies, so that the term is
/// the same everywhere. `k_z = 0` is the plain v w. The divisor is kept
/// above 0.25 (a k_z of the wrong sign and far beyond its plausible range
/// cannot turn a_y over).
pub fn lateral_acceleration_from_wheels(
    v_m_s: f64,
    w_wheels_rad_s: f64,
    k_z: f64,
    track_m: f64,
) -> f64 {
    let bend = 1.0 + 2.0 * k_z * v_m_s * v_m_s / track_m;
    v_m_s * w_wheels_rad_s / bend.max(0.25)
}

impl EffectTerms {
    /// The effects with a non-zero term, in catalogue order.
    pub fn active(&self) -> Vec<Effect> {
        Effect::ALL
            .into_iter()
            .filter(|e| self.is_active(*e))
            .collect()
    }

    /// Whether `effect` acts: one of its fitted coefficients is non-zero
    /// and every other parameter of its model (the drift's time constant)
    /// lies in its plausible range, open at the bottom.
    pub fn is_active(&self, effect: Effect) -> bool {
        let spec = effect.spec();
        spec.fitted.iter().any(|&p| self.get(p) != 0.0)
            && spec
                .model
                .iter()
                .filter(|p| !spec.fitted.contains(p))
                .all(|&p| {
                    let (lo, hi) = p.spec().plausible;
                    let v = self.get(p);
                    v > lo && v <= hi
                })
    }

    /// The model value of one parameter (SI units, as
    /// [`interfaces::effects::ParamSpec`] says); 0 for a parameter the model
    /// does not hold (the simulated road's grade, the soft-iron terms).
    pub fn get(&self, param: Param) -> f64 {
        match param {
            Param::SideSlipGain => self.k_beta,
            Param::LoadTransferGain => self.k_z,
            Param::SpeedGrowthGain => self.k_v,
            Param::LongitudinalSlipGain => self.k_s,
            Param::TrackRel => self.track_rel,
            Param::GyroBias => self.gyro_bias_rad_s,
            Param::GyroScale => self.gyro_scale,
            Param::GnssLatency => self.gnss_latency_s,
            Param::LeverArmX => self.lever_arm_m[0],
            Param::LeverArmY => self.lever_arm_m[1],
            Param::DriftFraction => self.drift_d,
            Param::DriftTimeConstant => self.drift_time_constant_s,
            Param::GradeGain => self.grade_gain,
            Param::HeadingA => self.heading_bias_rad[0],
            Param::HeadingB => self.heading_bias_rad[1],
            Param::HeadingC => self.heading_bias_rad[2],
            Param::Grade | Param::HeadingD | Param::HeadingE => 0.0,
        }
    }

    /// Set the model value of one parameter (SI units); a parameter the
    /// model does not hold is ignored.
    pub fn set(&mut self, param: Param, value: f64) {
        let slot = match param {
            Param::SideSlipGain => &mut self.k_beta,
            Param::LoadTransferGain => &mut self.k_z,
            Param::SpeedGrowthGain => &mut self.k_v,
            Param::LongitudinalSlipGain => &mut self.k_s,
            Param::TrackRel => &mut self.track_rel,
            Param::GyroBias => &mut self.gyro_bias_rad_s,
            Param::GyroScale => &mut self.gyro_scale,
            Param::GnssLatency => &mut self.gnss_latency_s,
            Param::LeverArmX => &mut self.lever_arm_m[0],
            Param::LeverArmY => &mut self.lever_arm_m[1],
            Param::DriftFraction => &mut self.drift_d,
            Param::DriftTimeConstant => &mut self.drift_time_constant_s,
            Param::GradeGain => &mut self.grade_gain,
            Param::HeadingA => &mut self.heading_bias_rad[0],
            Param::HeadingB => &mut self.heading_bias_rad[1],
            Param::HeadingC => &mut self.heading_bias_rad[2],
            Param::Grade | Param::HeadingD | Param::HeadingE => return,
        };
        *slot = value;
    }

    /// The relative change of both rear circumferences common to the
    /// speed, drift and slip terms at this step (0 for the plain model).
    pub fn common_scale(&self, s: &StepSignals) -> f64 {
        let mut k = self.k_v * s.v_m_s * s.v_m_s;
        if self.drift_time_constant_s > 0.0 {
            k += self.drift_d * (1.0 - (-s.t_since_start_s / self.drift_time_constant_s).exp());
        }
        // The wheels turn as if the car went v (1 + k_s a_x): the distance
        // they stand for is smaller by that factor.
        (1.0 + k) / (1.0 + self.k_s * s.a_x_m_s2) - 1.0
    }

    /// Centre distance (horizontal), heading change and side-slip angle of
    /// one step from the rear wheels' revolution increments, with the plain
    /// model's circumferences `c_rl`, `c_rr` and nominal `track_m`.
    pub fn increments(
        &self,
        c_rl: f64,
        c_rr: f64,
        track_m: f64,
        dn_rl: f64,
        dn_rr: f64,
        s: &StepSignals,
    ) -> (f64, f64, f64) {
        let scale = 1.0 + self.common_scale(s);
        let d_rl = dn_rl * c_rl * scale * (1.0 + self.k_z * s.a_y_m_s2);
        let d_rr = dn_rr * c_rr * scale * (1.0 - self.k_z * s.a_y_m_s2);
        let track = track_m * (1.0 + self.track_rel);
        let along = 0.5 * (d_rl + d_rr);
        let horizontal = along * (self.grade_gain * s.grade).atan().cos();
        let beta = -self.k_beta * s.a_y_m_s2;
        (horizontal, (d_rr - d_rl) / track, beta)
    }

    /// The wheel-side terms as wire model extensions: every active effect
    /// the table carries as [`Carried::Extension`] (side-slip k_beta; load
    /// transfer k_z; speed growth k_v; longitudinal slip k_s; track width
    /// rel; radius drift d, T), with its code and its model parameters in
    /// order. The antenna travels as its own extension, the gyro terms in
    /// the estimate's own fields, GNSS latency and grade stay with the
    /// diagnosis.
    pub fn to_extensions(&self) -> Vec<ModelExtension> {
        Effect::ALL
            .into_iter()
            .filter(|&e| e.spec().carried == Carried::Extension && self.is_active(e))
            .map(|e| {
                let model = e.spec().model;
                let mut params = [0.0; MAX_EXTENSION_PARAMS];
                for (slot, &p) in params.iter_mut().zip(model) {
                    *slot = self.get(p);
                }
                ModelExtension {
                    effect_code: e.code(),
                    param_count: model.len().min(MAX_EXTENSION_PARAMS) as u32,
                    params,
                }
            })
            .collect()
    }

    /// The wheel-side terms of wire model extensions (others are ignored;
    /// an extension with a non-finite parameter or fewer parameters than
    /// its model has leaves its terms at zero).
    pub fn from_extensions(xs: &[ModelExtension]) -> EffectTerms {
        let mut t = EffectTerms::default();
        for x in xs {
            let n = (x.param_count as usize).min(MAX_EXTENSION_PARAMS);
            let p = &x.params[..n];
            if p.iter().any(|v| !v.is_finite()) || p.is_empty() {
                continue;
            }
            let Some(spec) = Effect::from_code(x.effect_code).map(Effect::spec) else {
                continue;
            };
            if spec.carried != Carried::Extension || n < spec.model.len() {
                continue;
            }
            for (&param, &v) in spec.model.iter().zip(p) {
                t.set(param, v);
            }
        }
        t
    }

    /// The true yaw rate from a gyro reading, with the gyro terms.
    pub fn corrected_gyro(&self, gz_rad_s: f64) -> f64 {
        (gz_rad_s - self.gyro_bias_rad_s) / (1.0 + self.gyro_scale)
    }

    /// The error of an absolute heading sensor at true heading `psi`, rad.
    pub fn heading_error(&self, psi: f64) -> f64 {
        let [a, b, c] = self.heading_bias_rad;
        a + b * psi.sin() + c * psi.cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exactly_the_terms_said_to_read_the_lateral_acceleration_do() {
        // Every parameter of every effect, set to its typical size: its
        // increments move with a_y iff it is listed.
        let at = |a_y: f64| StepSignals {
            v_m_s: 12.0,
            a_x_m_s2: 0.8,
            a_y_m_s2: a_y,
            grade: 0.04,
            t_since_start_s: 300.0,
        };
        let mut checked = 0;
        for e in Effect::ALL {
            for &p in e.spec().model {
                let mut t = EffectTerms::default();
                for &q in e.spec().model {
                    t.set(q, q.spec().typical);
                }
                let mut plain = t;
                plain.set(p, 0.0);
                let moves = |terms: &EffectTerms| {
                    let a = terms.increments(2.0, 2.0, 1.5, 1.0, 1.02, &at(0.0));
                    let b = terms.increments(2.0, 2.0, 1.5, 1.0, 1.02, &at(3.0));
                    [b.0 - a.0, b.1 - a.1, b.2 - a.2]
                };
                let (with, without) = (moves(&t), moves(&plain));
                let reads = with
                    .iter()
                    .zip(&without)
                    .any(|(x, y)| (x - y).abs() > 1e-12);
                assert_eq!(
                    reads,
                    READS_LATERAL_ACCELERATION.contains(&p),
                    "{e:?} {p:?}"
                );
                checked += 1;
            }
        }
        assert!(checked >= 12, "{checked}");
    }

    #[test]
    fn the_plain_model_is_eq_1_2() {
        let t = EffectTerms::default();
        let s = StepSignals {
            v_m_s: 10.0,
            a_x_m_s2: 1.0,
            a_y_m_s2: 2.0,
            grade: 0.05,
            t_since_start_s: 100.0,
        };
        let (ds, dyaw, beta) = t.increments(2.0, 2.1, 1.5, 1.0, 1.0, &s);
        assert!((ds - 2.05).abs() < 1e-12);
        assert!((dyaw - 0.1 / 1.5).abs() < 1e-12);
        assert_eq!(beta, 0.0);
        assert!(t.active().is_empty());
    }

    #[test]
    fn the_lateral_acceleration_read_from_the_wheels_undoes_the_bend_of_the_load_transfer() {
        // A car in a steady left turn with a load transfer: the wheels'
        // increments from the model's own (true) yaw rate, read back.
        let (c, track, k_z) = (2.0, 1.6, 5e-4);
        let (v, w_true, dt) = (25.0, 0.1, 0.01);
        let a_true = v * w_true;
        // Distances each wheel really covers, and the revolutions the
        // radius change makes them count.
        let (d_l, d_r) = (
            (v - w_true * track / 2.0) * dt,
            (v + w_true * track / 2.0) * dt,
        );
        let (dn_l, dn_r) = (
            d_l / (c * (1.0 + k_z * a_true)),
            d_r / (c * (1.0 - k_z * a_true)),
        );
        let w_plain = (dn_r - dn_l) * c / (track * dt);
        let v_plain = 0.5 * (dn_r + dn_l) * c / dt;
        assert!(
            w_plain > 1.3 * w_true,
            "the plain yaw rate is bent: {w_plain}"
        );
        let a = lateral_acceleration_from_wheels(v_plain, w_plain, k_z, track);
        assert!((a - a_true).abs() < 0.01 * a_true, "{a} against {a_true}");
        // The model fed that a_y turns the car at the true rate.
        let terms = EffectTerms {
            k_z,
            ..EffectTerms::default()
        };
        let s = StepSignals {
            v_m_s: v_plain,
            a_y_m_s2: a,
            ..StepSignals::default()
        };
        let (_, dyaw, _) = terms.increments(c, c, track, dn_l, dn_r, &s);
        assert!(
            (dyaw / dt - w_true).abs() < 0.01 * w_true,
            "{} against {w_true}",
            dyaw / dt
        );
        // Plain: v w.
        assert_eq!(
            lateral_acceleration_from_wheels(v, w_true, 0.0, track),
            a_true
        );
    }

    #[test]
    fn each_term_moves_the_step_the_documented_way() {
        let s = StepSignals {
            v_m_s: 20.0,
            a_x_m_s2: 2.0,
            a_y_m_s2: 3.0,
            grade: 0.1,
            t_since_start_s: 1e6,
        };
        let step = |t: EffectTerms| t.increments(2.0, 2.0, 1.5, 1.0, 1.0, &s);
        let (ds0, _, _) = step(EffectTerms::default());
        let (ds, dyaw, _) = step(EffectTerms {
            k_z: 1e-3,
            ..EffectTerms::default()
        });
        assert!((ds - ds0).abs() < 1e-12);
        // A left turn: the right (outer) wheel rolls on a smaller radius.
        assert!(dyaw < 0.0);
        let (ds, _, _) = step(EffectTerms {
            k_v: 2.5e-6,
            ..EffectTerms::default()
        });
        assert!((ds / ds0 - (1.0 + 2.5e-6 * 400.0)).abs() < 1e-12);
        let (ds, _, _) = step(EffectTerms {
            k_s: 0.005,
            ..EffectTerms::default()
        });
        assert!((ds / ds0 - 1.0 / 1.01).abs() < 1e-12);
        let (ds, _, _) = step(EffectTerms {
            drift_d: 0.003,
            drift_time_constant_s: 600.0,
            ..EffectTerms::default()
        });
        assert!((ds / ds0 - 1.003).abs() < 1e-9);
        let (ds, _, _) = step(EffectTerms {
            grade_gain: 1.0,
            ..EffectTerms::default()
        });
        assert!((ds / ds0 - 0.1f64.atan().cos()).abs() < 1e-12);
        let (_, _, beta) = step(EffectTerms {
            k_beta: 0.004,
            ..EffectTerms::default()
        });
        assert!((beta + 0.012).abs() < 1e-12);
        let t = EffectTerms {
            gyro_bias_rad_s: 0.01,
            gyro_scale: 0.01,
            ..EffectTerms::default()
        };
        assert!((t.corrected_gyro(1.01 * 0.5 + 0.01) - 0.5).abs() < 1e-12);
        assert_eq!(t.active(), vec![Effect::GyroBias, Effect::GyroScale]);
    }

    #[test]
    fn wheel_terms_survive_the_wire() {
        let t = EffectTerms {
            k_beta: 0.004,
            k_z: 5e-5,
            k_v: 2.5e-6,
            k_s: 0.002,
            track_rel: 0.02,
            drift_d: 0.003,
            drift_time_constant_s: 600.0,
            gnss_latency_s: 0.08,
            ..EffectTerms::default()
        };
        let back = EffectTerms::from_extensions(&t.to_extensions());
        assert_eq!(
            back,
            EffectTerms {
                gnss_latency_s: 0.0,
                ..t
            }
        );
        assert_eq!(t.to_extensions().len(), 6);
        assert_eq!(EffectTerms::from_extensions(&[]), EffectTerms::default());
    }
}
