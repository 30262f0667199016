//! Whether the fixes contradict the estimate in use: its wheels' distance
//! scale, checked against what GNSS measures while the filter has it.
//!
//! The filter never estimates the wheels' scale (a consider state, see
//! `fusion`): it trusts the estimate to
//! [`FusionConfig::distance_scale_sigma`](super::FusionConfig::distance_scale_sigma).
//! An estimate whose circumferences are wrong by more than that (a wrong
//! fit, or any process of the same user publishing a plausible lie) would
//! be used for the rest of the drive, with GNSS correcting it fix by fix and
//! every outage going wrong by the error. This check measures the scale
//! instead of assuming it.
//!
//! Between two fixes at least [`WINDOW_M`] apart along the predicted path
//! (every fix, whether the filter's gate took it or not: a wrong estimate
//! makes the filter refuse the very fixes that show it), the length of the
//! antenna's displacement that the odometer's increments give (dead-reckoned
//! by the check in a frame of its own, so that the filter's resets do not
//! break a window; the lever arm turned by the yaw change) is compared with
//! the length of the fixes' displacement: `z = |d_gnss| - L` with
//! `L = |d_pred|`. A window whose `z` no wheel of this car explains (beyond
//! the estimate gate's circumference range plus the 1e-6 quantile of the
//! noise) is a GNSS jump and not used. With wheels whose
//! true distance is `(1 + e)` times what the estimate makes of them,
//! `z = e L` plus noise of variance `v = sigma_1^2 + sigma_2^2 +
//! sum (distance_noise_frac ds)^2` (the two fixes' own sigmas, as the filter
//! takes them, and the wheels' distance noise of each increment, as the
//! filter's prediction takes it). A time offset `delta` between the wheel
//! and the GNSS stamps (an estimate's clocks wrong, or none) adds
//! `delta dv`, with `dv` the change of speed over the window: the windows'
//! weighted least squares fit both, `z = e L + delta dv`, and the test
//! takes `e_hat` with its marginal variance, `delta` having a prior of zero
//! with a 1-sigma of a second (at a constant speed `delta` is not seen and
//! the fit is `e_hat = sum(z L / v) / sum(L^2 / v)` with variance
//! `1 / sum(L^2 / v)`). So a wrong clock is not taken for a wrong wheel.
//!
//! An estimate claims its scale to `sigma_s` (the filter's consider sigma for
//! a calibration). It is contradicted when
//! `e_hat^2 / (var(e_hat) + sigma_s^2)` exceeds the chi-square quantile of
//! one degree of freedom at a false-alarm probability of 1e-6 per test
//! ([`CHI2_1DOF_1E6`]): the statistic comes from the fixes' sigmas and the
//! estimate's, not from a tuned margin. The nominal `vehicle.toml` guess is
//! never dropped (there is nothing to fall back to).
//!
//! A window longer than [`MAX_WINDOW_M`] (fixes rejected or missing for that
//! long) is not used: the predicted yaw may have turned away by then. The
//! sums start again with every estimate switch, and the windows with every
//! reset of the filter.

use vehicle_model::estimate_gate::GateLimits;
use vehicle_model::two_wheel::wrap_angle;

/// The chi-square quantile of one degree of freedom at 1 - 1e-6.
pub const CHI2_1DOF_1E6: f64 = 23.928;

/// A window closes at the first accepted fix this far along the predicted
/// path from its first fix, m.
pub const WINDOW_M: f64 = 50.0;

/// A window longer than this is dropped, m.
pub const MAX_WINDOW_M: f64 = 300.0;

/// The fixes contradict the estimate in use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contradiction {
    /// Time of the fix that closed the last window, s.
    pub t_s: f64,
    /// Version of the estimate contradicted.
    pub version: u64,
    /// The wheels' distance scale the fixes measure, relative to the
    /// estimate's (1 = the estimate is right).
    pub measured_scale: f64,
    /// 1-sigma of `measured_scale` from the fixes.
    pub measured_sigma: f64,
    /// 1-sigma the estimate claims for its scale.
    pub applied_sigma: f64,
    /// The test statistic (chi-square, one degree of freedom).
    pub chi2: f64,
    /// Predicted distance over the windows used, m.
    pub distance_m: f64,
    /// Windows used.
    pub windows: u32,
    /// Windows left out as GNSS jumps.
    pub outliers: u32,
}

/// The start of a window: the fix, its sigma, and the check's own
/// dead-reckoned pose there.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Start {
    x: f64,
    y: f64,
    sigma: f64,
    dr: [f64; 3],
    speed: f64,
}

/// The prior 1-sigma of the time offset between the wheel and the GNSS
/// stamps, s: sensor latencies and unsynchronised clocks are fractions of a
/// second (`StreamClocks`); a second leaves the offset to the data.
const CLOCK_OFFSET_SIGMA_S: f64 = 1.0;

/// The speed is smoothed over this time constant, s (wheel counts are
/// quantised at each 10 ms sample).
const SPEED_TAU_S: f64 = 0.2;

/// The running check (see the module doc).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct ScaleCheck {
    start: Option<Start>,
    /// The check's own dead reckoning of the rear axle (x, y, yaw) in a
    /// frame of its own: the filter's frame changes when it initialises or
    /// starts again from the fixes, lengths do not.
    dr: [f64; 3],
    /// Path length predicted since the window's start, m.
    path: f64,
    /// Variance of that length from the wheels' distance noise, m^2.
    path_var: f64,
    /// Speed along the path, smoothed over [`SPEED_TAU_S`], m/s.
    speed: f64,
    /// The normal equations of `z = e L + delta dv`: sum(L^2 / v),
    /// sum(L dv / v), sum(dv^2 / v).
    info: [f64; 3],
    /// sum(z L / v), sum(z dv / v).
    weighted: [f64; 2],
    distance: f64,
    windows: u32,
    /// Windows whose fixes disagree with any wheel this car can have.
    outliers: u32,
    /// Found contradicted (and not yet taken, or taken: no more tests until
    /// the next estimate).
    found: Option<Contradiction>,
    decided: bool,
}

impl ScaleCheck {
    /// A new estimate: the sums start again (the dead reckoning goes on).
    pub(super) fn clear(&mut self) {
        *self = ScaleCheck {
            dr: self.dr,
            speed: self.speed,
            ..ScaleCheck::default()
        };
    }

    /// The wheel stream starts over: the open window is dropped, the sums
    /// kept.
    pub(super) fn restart_window(&mut self) {
        self.start = None;
        self.path = 0.0;
        self.path_var = 0.0;
    }

    /// An increment of the odometer: distance, yaw change, side-slip and
    /// time step, and the 1-sigma of the distance's noise, m.
    pub(super) fn predicted(&mut self, ds: f64, dyaw: f64, beta: f64, dt: f64, sigma_ds: f64) {
        if dt > 0.0 {
            let v = ds / dt;
            if v.is_finite() {
                self.speed += (v - self.speed) * (dt / SPEED_TAU_S).min(1.0);
            }
        }
        let course = self.dr[2] + 0.5 * dyaw + beta;
        self.dr[0] += ds * course.cos();
        self.dr[1] += ds * course.sin();
        self.dr[2] = wrap_angle(self.dr[2] + dyaw);
        self.path += ds.abs();
        self.path_var += sigma_ds * sigma_ds;
    }

    /// A fix (accepted by the filter's gate or not: a wrong estimate makes
    /// the filter refuse the fixes that show it), with its sigma as the
    /// filter takes it, the lever arm, and the
    /// estimate's version and scale sigma (`None` for the nominal guess,
    /// which is measured but not tested).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn fix(
        &mut self,
        t_s: f64,
        x_m: f64,
        y_m: f64,
        sigma_m: f64,
        lever: [f64; 2],
        estimate: Option<(u64, f64)>,
    ) {
        let here = Start {
            x: x_m,
            y: y_m,
            sigma: sigma_m,
            dr: self.dr,
            speed: self.speed,
        };
        let Some(start) = self.start else {
            self.restart_window();
            self.start = Some(here);
            return;
        };
        if self.path < WINDOW_M {
            return;
        }
        let (path, path_var) = (self.path, self.path_var);
        self.restart_window();
        self.start = Some(here);
        if path > MAX_WINDOW_M {
            return;
        }
        // The antenna's predicted displacement: the axle's plus the lever
        // arm turned from the start's yaw to this one.
        let antenna = |dr: [f64; 3]| {
            let (s, c) = dr[2].sin_cos();
            [
                dr[0] + lever[0] * c - lever[1] * s,
                dr[1] + lever[0] * s + lever[1] * c,
            ]
        };
        let (a0, a1) = (antenna(start.dr), antenna(self.dr));
        let length = (a1[0] - a0[0]).hypot(a1[1] - a0[1]);
        if length.is_nan() || length <= 0.5 * WINDOW_M {
            return; // turned on the spot or reversed back: little to compare
        }
        let z = (x_m - start.x).hypot(y_m - start.y) - length;
        let v = start.sigma.powi(2) + sigma_m.powi(2) + path_var;
        if !(z.is_finite() && v > 0.0) {
            return;
        }
        // Fixes that no wheel of this car explains (beyond the estimate
        // gate's circumference range, by more than the 1e-6 quantile of
        // their noise) are a GNSS jump, not a scale: not used.
        let band = GateLimits::default().circumference_rel * length + (CHI2_1DOF_1E6 * v).sqrt();
        if z.abs() > band {
            self.outliers += 1;
            return;
        }
        let dv = self.speed - start.speed;
        self.info[0] += length * length / v;
        self.info[1] += length * dv / v;
        self.info[2] += dv * dv / v;
        self.weighted[0] += z * length / v;
        self.weighted[1] += z * dv / v;
        self.distance += length;
        self.windows += 1;
        let Some((version, sigma_s)) = estimate else {
            return;
        };
        if self.decided {
            return;
        }
        let Some((e, var)) = self.fit() else {
            return;
        };
        let chi2 = e * e / (var + sigma_s * sigma_s);
        if chi2 > CHI2_1DOF_1E6 {
            self.decided = true;
            self.found = Some(Contradiction {
                t_s,
                version,
                measured_scale: 1.0 + e,
                measured_sigma: var.sqrt(),
                applied_sigma: sigma_s,
                chi2,
                distance_m: self.distance,
                windows: self.windows,
                outliers: self.outliers,
            });
        }
    }

    /// The contradiction found, once.
    pub(super) fn take(&mut self) -> Option<Contradiction> {
        self.found.take()
    }

    /// The scale measured so far relative to the estimate's and its 1-sigma,
    /// with the distance behind it; `None` before a window closed.
    pub(super) fn measured(&self) -> Option<(f64, f64, f64)> {
        self.fit()
            .map(|(e, var)| (1.0 + e, var.sqrt(), self.distance))
    }

    /// The scale error and its marginal variance from the windows so far.
    fn fit(&self) -> Option<(f64, f64)> {
        let [a00, a01, a11] = self.info;
        let [b0, b1] = self.weighted;
        if a00 <= 0.0 {
            return None;
        }
        // The offset's prior: zero, with CLOCK_OFFSET_SIGMA_S.
        let a11 = a11 + CLOCK_OFFSET_SIGMA_S.powi(-2);
        let det = a00 * a11 - a01 * a01;
        if det <= 0.0 {
            return None;
        }
        let fit = ((a11 * b0 - a01 * b1) / det, a11 / det);
        (fit.0.is_finite() && fit.1.is_finite()).then_some(fit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dead_reckoning::HeadingMode;
    use crate::fusion::filter::Fusion;
    use crate::fusion::test_support::{config, params, simulate};
    use crate::inputs::Input;

    /// Gaussian noise of 1-sigma `sigma` on every fix (xorshift and
    /// Box-Muller, seeded): the fixes scatter as their sigma says.
    fn noisy(inputs: &[Input], sigma: f64, seed: u64) -> Vec<Input> {
        let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let mut gauss = move || {
            let (u, v) = (uniform(), uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        inputs
            .iter()
            .map(|i| match *i {
                Input::Gnss { t_s, x_m, y_m, .. } => Input::Gnss {
                    t_s,
                    x_m: x_m + sigma * gauss(),
                    y_m: y_m + sigma * gauss(),
                    sigma_m: Some(sigma),
                },
                other => other,
            })
            .collect()
    }

    /// Runs the inputs with the estimate `scale` times the true
    /// circumferences switched to (version 99) at `switch_s`; returns the
    /// contradiction found, if any.
    fn run_with(
        inputs: &[Input],
        heading: HeadingMode,
        scale: f64,
        switch_s: f64,
    ) -> (Option<Contradiction>, Fusion) {
        let mut fusion = Fusion::new(params(), 1, config(heading));
        let mut switched = false;
        let mut found = None;
        for input in inputs {
            if !switched && input.t_s() >= switch_s {
                let mut lie = params();
                lie.two_wheel.c_rl *= scale;
                lie.two_wheel.c_rr *= scale;
                fusion.set_estimate(lie, 99);
                switched = true;
            }
            fusion.process(input).expect("input accepted");
            if let Some(c) = fusion.take_contradiction() {
                assert!(found.is_none(), "reported once: {c:?}");
                found = Some(c);
            }
        }
        (found, fusion)
    }

    #[test]
    fn wheels_seven_percent_off_are_contradicted_within_seconds() {
        // A plausible lie: circumferences 7 % larger than the wheels are
        // (inside every gate), taken at 20 s; the fixes scatter by 0.3 m.
        for (seed, heading) in [(1, HeadingMode::Gyro), (2, HeadingMode::WheelDifference)] {
            let sim = simulate(90.0, &|_| true, 0.0, 0.3);
            let inputs = noisy(&sim.inputs, 0.3, seed);
            let (found, fusion) = run_with(&inputs, heading, 1.07, 20.0);
            let c = found.unwrap_or_else(|| {
                panic!(
                    "not found: {:?} {:?}",
                    fusion.measured_scale(),
                    fusion.stats()
                )
            });
            println!(
                "{heading:?}: v{} contradicted {:.1} s after the switch: measured scale \
                 {:.4} +- {:.4} against 1 +- {:.4} over {:.0} m ({} windows, chi2 {:.0})",
                c.version,
                c.t_s - 20.0,
                c.measured_scale,
                c.measured_sigma,
                c.applied_sigma,
                c.distance_m,
                c.windows,
                c.chi2
            );
            assert_eq!(c.version, 99);
            // The truth is 1 / 1.07 of what the estimate makes of the wheels.
            let truth = 1.0 / 1.07;
            assert!(
                (c.measured_scale - truth).abs() < 4.0 * c.measured_sigma + 0.002,
                "{c:?}"
            );
            assert!(c.t_s - 20.0 < 10.0, "found late: {c:?}");
        }
    }

    #[test]
    fn dropping_the_lie_keeps_a_tunnel_after_it_honest() {
        // The lie (7 %) at 10 s, a 30 s tunnel from 60 s: the error at its
        // end with the lie dropped (back to the true estimate, as the
        // service falls back on the one before) and kept.
        let sim = simulate(95.0, &|t| !(60.0..90.0).contains(&t), 0.0, 0.3);
        let inputs = noisy(&sim.inputs, 0.3, 11);
        let end = inputs
            .iter()
            .filter(|i| matches!(i, Input::Wheels { .. }))
            .position(|i| i.t_s() >= 89.99)
            .expect("the tunnel's end");
        let mut errors = Vec::new();
        for act in [true, false] {
            let mut fusion = Fusion::new(params(), 1, config(HeadingMode::Gyro));
            let mut poses = Vec::new();
            let mut switched = false;
            let mut dropped_at = None;
            for input in &inputs {
                if !switched && input.t_s() >= 10.0 {
                    let mut lie = params();
                    lie.two_wheel.c_rl *= 1.07;
                    lie.two_wheel.c_rr *= 1.07;
                    fusion.set_estimate(lie, 99);
                    switched = true;
                }
                poses.extend(fusion.process(input).expect("input accepted"));
                if let Some(c) = fusion.take_contradiction() {
                    if act {
                        fusion.set_estimate(params(), 1);
                        dropped_at = Some(c.t_s);
                    }
                }
            }
            let (p, truth) = (poses[end].pose, sim.truth[end].1);
            let error = (p.x - truth.x).hypot(p.y - truth.y);
            println!(
                "lie {}: error at the end of the 30 s tunnel {error:.2} m{}",
                if act { "dropped" } else { "kept" },
                dropped_at.map_or(String::new(), |t| format!(" (dropped at {t:.1} s)"))
            );
            errors.push(error);
        }
        // Kept, the tunnel is driven 7 % long: about 21 m at its end.
        assert!(errors[1] > 15.0, "{errors:?}");
        assert!(errors[0] < 2.0, "{errors:?}");
    }

    #[test]
    fn the_true_estimate_and_a_recalibration_sized_error_are_not_contradicted() {
        for seed in 1..=6 {
            let heading = if seed % 2 == 0 {
                HeadingMode::Gyro
            } else {
                HeadingMode::WheelDifference
            };
            let sim = simulate(120.0, &|t| !(50.0..70.0).contains(&t), 0.0, 0.3);
            let inputs = noisy(&sim.inputs, 0.3, seed);
            // The true circumferences, and ones 0.5 % off (the filter's
            // sigma for a calibration): kept.
            for scale in [1.0, 1.005] {
                let (found, fusion) = run_with(&inputs, heading, scale, 5.0);
                let (measured, sigma, distance) = fusion.measured_scale().expect("measured");
                assert!(
                    found.is_none(),
                    "seed {seed} scale {scale}: {found:?} (measured {measured:.4} +- {sigma:.4})"
                );
                assert!(distance > 800.0, "{distance}");
                assert!(
                    (measured - 1.0 / scale).abs() < 5.0 * sigma,
                    "{measured} {sigma}"
                );
            }
        }
    }

    #[test]
    fn the_nominal_guess_is_measured_but_never_contradicted() {
        let sim = simulate(60.0, &|_| true, 0.0, 0.3);
        let inputs = noisy(&sim.inputs, 0.3, 7);
        let mut vehicle = interfaces::drive::VehicleParams {
            name: None,
            track_width_m: crate::test_drive::TRACK,
            nominal_circumference_m: 2.14,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: Default::default(),
        };
        let mut fusion = Fusion::nominal(&vehicle, config(HeadingMode::Gyro));
        for input in &inputs {
            fusion.process(input).expect("input accepted");
            assert_eq!(fusion.take_contradiction(), None);
        }
        let (measured, sigma, _) = fusion.measured_scale().expect("measured");
        assert!((measured - 2.0 / 2.14).abs() < 5.0 * sigma, "{measured}");
        // Back to nominal from an estimate: the nominal trust again.
        vehicle.nominal_circumference_m = 2.0;
        fusion.set_estimate(params(), 4);
        fusion.set_nominal(&vehicle);
        assert_eq!(fusion.estimate_version(), 0);
        assert_eq!(fusion.measured_scale(), None);
    }
}
