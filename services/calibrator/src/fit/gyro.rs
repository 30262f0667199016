//! The yaw-rate gyro's bias and scale, estimated beside the circumferences.
//!
//! Convention (the physics catalogue's `gyro_bias`, `gyro_scale`):
//! `omega_gyro = (1 + scale) omega + bias`, so the odometry recovers the yaw
//! rate as `omega = (omega_gyro - bias) / (1 + scale)`.
//!
//! The model is the one the odometry runs through a GNSS outage: distance
//! from the calibrated wheels, heading from the gyro. It is fitted to the GNSS
//! fixes by the Levenberg-Marquardt fitter ([`crate::fit::lm::fit`]) with the ratio of the
//! circumferences held at their estimate. Beside the bias and scale it fits
//! - a common distance factor `k` on both circumferences: where the wheel
//!   difference is a poor heading source (wheel-rate sensors whose difference
//!   drifts, as on the WID drives), the 2W fit trades the scale against its
//!   heading errors, while this model's heading comes from the gyro; the
//!   calibration takes `k` when this model fits the GNSS much better
//!   ([`prefer_distance_factor`]);
//! - the GNSS antenna position in the body frame (a prior of
//!   [`ANTENNA_MEASURED_SIGMA_M`] around `vehicle.toml`'s value where it
//!   gives one, else [`ANTENNA_PRIOR_SIGMA_M`] around the axle centre): an antenna
//!   half a metre ahead of the rear axle moves a metre sideways in a U-turn,
//!   which a model of the rear axle would otherwise put into the gyro scale.
//!
//! The mean gyro rate at standstill, when the drive has some, enters as a
//! prior on the bias. Without enough turning the scale is held at 0 (and a
//! warning says so).

use crate::error::CalibrationError;
use crate::fit::lm::{fit, SlipGain, StepModel, MAX_GLOBAL};
use crate::reference::Reference;
use crate::series::standstill_gyro_bias;
use crate::series::Series;
use crate::warnings::{Warning, WarningCode};
use serde::{Deserialize, Serialize};

/// 1-sigma of the prior on the GNSS antenna position around the axle
/// centre when `vehicle.toml` gives none, m: an antenna is somewhere on the car.
pub const ANTENNA_PRIOR_SIGMA_M: f64 = 1.0;

/// 1-sigma of the prior on a GNSS antenna coordinate `vehicle.toml` gives, m:
/// measured with a tape on the car. A drive that turns round pins the
/// antenna to a few centimetres and still moves it; one that turns little
/// keeps the measured value instead of guessing.
pub const ANTENNA_MEASURED_SIGMA_M: f64 = 0.05;

/// An antenna position whose 1-sigma exceeds this, m, gets the
/// `antenna_unobservable` warning: a tenth of a metre of lateral offset is
/// up to 0.2 m of position error when the car turns round. The same limit
/// decides whether the odometry uses a calibrated antenna as its lever arm.
pub const ANTENNA_WARN_SIGMA_M: f64 = vehicle_model::estimate::MAX_FUSED_ANTENNA_SIGMA_M;

/// 1-sigma of the prior on the gyro scale error around 0: the physics
/// catalogue's typical size of `gyro_scale` (0.1-1 %). It only matters on
/// drives that turn too little to pin the scale down by themselves.
pub const GYRO_SCALE_PRIOR_SIGMA: f64 = 0.01;

/// The gyro calibration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GyroEstimate {
    /// Bias, rad/s (`omega_gyro = (1 + scale) omega + bias`).
    pub bias_rad_s: f64,
    /// 1-sigma of the bias, rad/s.
    pub sigma_bias_rad_s: f64,
    /// Scale error (0 = perfect).
    pub scale: f64,
    /// 1-sigma of the scale; `None` when the scale was held at 0.
    pub sigma_scale: Option<f64>,
    /// Mean gyro rate over the standstill periods, rad/s, when there were some.
    pub standstill_bias_rad_s: Option<f64>,
    /// Seconds of standstill used.
    pub standstill_s: f64,
    /// RMS of the GNSS residuals of the wheel + gyro model, m.
    pub residual_rms_m: f64,
    /// The common factor on both circumferences this model fits (1 = the
    /// circumferences it was given).
    #[serde(default = "one")]
    pub distance_factor: f64,
    /// 1-sigma of `distance_factor`.
    #[serde(default)]
    pub sigma_distance_factor: f64,
    /// Whether that sigma is the spread of the drive fitted without each
    /// third of it, which disagree beyond the other sources
    /// ([`crate::fit::lm::Fit::floored_by_thirds`]).
    #[serde(default)]
    pub distance_floored_by_thirds: bool,
    /// GNSS antenna position (body x forward, y left, from the rear-axle
    /// centre) this model fits, m.
    #[serde(default)]
    pub antenna_m: [f64; 2],
    /// 1-sigma of `antenna_m`, m.
    #[serde(default)]
    pub sigma_antenna_m: [f64; 2],
}

fn one() -> f64 {
    1.0
}

/// Index of the distance factor and of the antenna x (y follows) among the
/// gyro model's parameters (bias and scale are 0 and 1).
const DISTANCE: usize = 2;
const ANTENNA: usize = 3;

/// Whether the calibration should take the gyro model's distance factor:
/// when the wheel + gyro model fits the GNSS at least twice as well as the
/// 2W model (whose scale then absorbs heading errors of the wheels).
pub fn prefer_distance_factor(gyro: &GyroEstimate, two_wheel_residual_rms_m: Option<f64>) -> bool {
    two_wheel_residual_rms_m.is_some_and(|r| gyro.residual_rms_m < 0.5 * r)
        && (gyro.distance_factor - 1.0).abs() < 0.05
}

struct GyroModel<'a> {
    p: &'a Series,
    gyro: &'a [f64],
    c: [f64; 2],
    slip: SlipGain,
    prior_bias: Option<(f64, f64)>,
    hold_scale: bool,
}

impl StepModel for GyroModel<'_> {
    fn scale_params(&self) -> &'static [usize] {
        &[DISTANCE]
    }
    fn n_global(&self) -> usize {
        5
    }

    fn lever_index(&self) -> Option<usize> {
        Some(ANTENNA)
    }

    fn increments(
        &self,
        k: usize,
        g: &[f64],
        d_ds: &mut [f64; MAX_GLOBAL],
        d_dyaw: &mut [f64; MAX_GLOBAL],
    ) -> Option<(f64, f64)> {
        let dg = self.gyro[k] - self.gyro[k - 1];
        if !dg.is_finite() {
            return None;
        }
        let dt = self.p.t[k] - self.p.t[k - 1];
        let ds = 0.5 * (self.p.dn_rl[k] * self.c[0] + self.p.dn_rr[k] * self.c[1]);
        let (b, s) = (g[0], g[1]);
        let num = dg - b * dt;
        *d_ds = [0.0; MAX_GLOBAL];
        *d_dyaw = [0.0; MAX_GLOBAL];
        d_dyaw[0] = -dt / (1.0 + s);
        d_dyaw[1] = -num / ((1.0 + s) * (1.0 + s));
        d_ds[DISTANCE] = ds;
        Some((ds * g[DISTANCE], num / (1.0 + s)))
    }

    fn slip(&self) -> SlipGain {
        self.slip
    }

    fn priors(&self) -> Vec<(usize, f64, f64)> {
        let mut out = Vec::new();
        if let Some((b, s)) = self.prior_bias {
            out.push((0, b, s));
        }
        let scale_sigma = if self.hold_scale {
            1e-6
        } else {
            GYRO_SCALE_PRIOR_SIGMA
        };
        out.push((1, 0.0, scale_sigma));
        for (i, (value, given)) in self
            .p
            .lever_arm
            .iter()
            .zip(self.p.lever_arm_given)
            .enumerate()
        {
            let sigma = if given {
                ANTENNA_MEASURED_SIGMA_M
            } else {
                ANTENNA_PRIOR_SIGMA_M
            };
            out.push((ANTENNA + i, *value, sigma));
        }
        out
    }
}

/// Fit the gyro bias and scale (with the distance factor and the antenna
/// position) on the circumferences `c` (and side-slip gain, if any).
pub fn estimate(
    p: &Series,
    r: &Reference,
    c: [f64; 2],
    side_slip_gain: Option<f64>,
    segment_length_s: f64,
    warnings: &mut Vec<Warning>,
) -> Result<Option<GyroEstimate>, CalibrationError> {
    let Some(gyro) = p.gyro.as_deref() else {
        return Ok(None);
    };
    let standstill = standstill_gyro_bias(p);
    let turn_deg = r.total_turn_rad.to_degrees();
    let hold_scale = turn_deg < 90.0;
    if hold_scale {
        warnings.push(Warning::new(
            WarningCode::GyroScaleUnobservable,
            format!("gyro scale held at 0: the drive turns only {turn_deg:.0} deg (at least 90 needed to estimate it)"),
        ));
    }
    let model = GyroModel {
        p,
        gyro,
        c,
        slip: side_slip_gain.map_or(SlipGain::Off, SlipGain::Fixed),
        prior_bias: standstill.map(|(b, s, _)| (b, s)),
        hold_scale,
    };
    let b0 = standstill
        .map(|s| s.0)
        .or(r.heading_filter_gyro_bias)
        .unwrap_or(0.0);
    let breaks = |k: usize| k > 0 && !(gyro[k] - gyro[k - 1]).is_finite();
    // The gyro starts near its answer (bias from standstill, scale 0): two stages do.
    let lengths = [30.0f64.min(segment_length_s), segment_length_s];
    let lengths = if lengths[0] >= lengths[1] {
        &lengths[1..]
    } else {
        &lengths[..]
    };
    let g0 = [b0, 0.0, 1.0, p.lever_arm[0], p.lever_arm[1]];
    let result = fit(&model, p, r, &g0, lengths, &breaks, &mut |_| {});
    let f = match result {
        Ok(f) => f,
        Err(e) => {
            warnings.push(Warning::new(
                WarningCode::GyroUnobservable,
                format!("gyro bias and scale not estimated: {e}"),
            ));
            return Ok(None);
        }
    };
    // Sigmas of (bias, scale): reuse the generic sigma helper on a 2x2 block.
    let sigma = |i: usize| f.variance(i).sqrt();
    let (sb, ss) = (sigma(0), sigma(1));
    let estimate = GyroEstimate {
        bias_rad_s: f.g[0],
        sigma_bias_rad_s: sb,
        scale: f.g[1],
        sigma_scale: (!hold_scale).then_some(ss),
        standstill_bias_rad_s: standstill.map(|s| s.0),
        standstill_s: standstill.map_or(0.0, |s| s.2),
        residual_rms_m: f.residual_rms_m,
        distance_factor: f.g[DISTANCE],
        sigma_distance_factor: sigma(DISTANCE),
        distance_floored_by_thirds: f.floored_by_thirds(DISTANCE),
        antenna_m: [f.g[ANTENNA], f.g[ANTENNA + 1]],
        // Known no better than one fix: a receiver's errors are correlated
        // over tens of seconds (multipath, atmosphere; a consumer receiver's
        // by metres), which neither the formal sigma nor the jackknife over
        // blocks of one drive sees. Without this floor a consumer-grade drive
        // "determines" an antenna offset of decimetres that is other physics
        // absorbed (side slip: the catalogue's confusion), and the odometry,
        // which fuses a determined antenna, would carry it. A coordinate
        // measured in vehicle.toml keeps its own sigma, never more than the
        // measurement's (its prior): the jackknife's leave-out solves do not
        // carry the prior, and a drive that cannot tell leaves the
        // measured value as it was.
        sigma_antenna_m: [0, 1].map(|i| {
            let s = sigma(ANTENNA + i);
            if p.lever_arm_given[i] {
                s.min(ANTENNA_MEASURED_SIGMA_M)
            } else {
                s.max(r.gnss_sigma_m)
            }
        }),
    };
    if let Some(w) = antenna_warning(&estimate, r.gnss_sigma_m) {
        warnings.push(w);
    }
    Ok(Some(estimate))
}

/// The warning for an antenna position the drive leaves poorly determined
/// (either coordinate's sigma above [`ANTENNA_WARN_SIGMA_M`]): it matters
/// wherever the position is carried between the antenna and the rear axle
/// (fusion, scoring against a GNSS truth), and a drive with little turning
/// cannot tell a lateral antenna offset from a position offset.
fn antenna_warning(g: &GyroEstimate, gnss_sigma_m: f64) -> Option<Warning> {
    let [sx, sy] = g.sigma_antenna_m;
    let why = if gnss_sigma_m > ANTENNA_WARN_SIGMA_M {
        format!("the GNSS fixes, sigma {gnss_sigma_m:.2} m, cannot resolve it")
    } else {
        "the drive turns too little to separate it from a position offset".to_string()
    };
    (sx.max(sy) > ANTENNA_WARN_SIGMA_M).then(|| {
        Warning::new(
            WarningCode::AntennaUnobservable,
            format!(
                "the GNSS antenna position ({:+.2}, {:+.2}) m is poorly determined: sigma {:.2} m forward, {:.2} m left \
                 (limit {:.2} m; {why}); the odometry does not use it; \
                 measure it and put it in vehicle.toml [gnss] antenna_x_m / antenna_y_m",
                g.antenna_m[0], g.antenna_m[1], sx, sy, ANTENNA_WARN_SIGMA_M
            ),
        )
    })
}
