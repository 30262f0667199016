//! Live calibration: when a drive collected so far supports publishing an
//! estimate.
//!
//! A live service collects the sensor streams and, once the drive covers
//! enough distance and turning ([`Coverage`]), makes an [`attempt`]: it
//! calibrates on all but the last part of what was collected and scores the
//! result, and the estimate in use, on that held-out tail
//! ([`crate::fit::holdout`]). The quality gate ([`gate`]) then accepts the result
//! only when
//!
//! 1. both circumference sigmas are at most a limit;
//! 2. enough held-out windows judged it;
//! 3. its held-out dead-reckoning error is lower than that of the estimate in
//!    use (or the nominal values).
//!
//! A live service keeps only a window of the drive ([`keep_window`]), so that
//! its memory does not grow with the length of the drive.
//!
//! Everything here is pure; the service binary owns the bus, the worker
//! thread and the state file.

use crate::config::CalibrationConfig;
use crate::diagnose::DiagnoseConfig;
use crate::error::CalibrationError;
use crate::fit::holdout::{holdout_errors, split_drive};
use crate::pipeline::calibrate;
use crate::result::RearPair;
use interfaces::collect::DriveBuilder;
use interfaces::drive::{Drive, GnssSample, HeadingSample, ImuSample, VehicleParams, WheelSample};
use interfaces::effects::Effect;
use serde::{Deserialize, Serialize};
use vehicle_model::effects::WheelEffects;
use vehicle_model::two_wheel::TwoWheelParams;

/// Distance and turning of the collected wheel data (nominal circumference).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coverage {
    c: f64,
    track: f64,
    last: Option<(f64, f64, f64)>,
    block_start_t: f64,
    block_yaw: f64,
    /// Distance, m.
    pub distance_m: f64,
    /// Sum of the absolute heading change over 1 s blocks, rad.
    pub turn_rad: f64,
}

impl Coverage {
    /// Nothing collected yet.
    pub fn new(vehicle: &VehicleParams) -> Coverage {
        Coverage {
            c: vehicle.nominal_circumference_m,
            track: vehicle.track_width_m,
            last: None,
            block_start_t: f64::NAN,
            block_yaw: 0.0,
            distance_m: 0.0,
            turn_rad: 0.0,
        }
    }

    /// Add a wheel sample (time, cumulative revolutions).
    pub fn add(&mut self, t_s: f64, rl_rev: f64, rr_rev: f64) {
        if let Some((_, rl, rr)) = self.last {
            let (dl, dr) = ((rl_rev - rl) * self.c, (rr_rev - rr) * self.c);
            if dl.is_finite() && dr.is_finite() {
                self.distance_m += 0.5 * (dl + dr).abs();
                self.block_yaw += (dr - dl) / self.track;
            }
        } else {
            self.block_start_t = t_s;
        }
        // Turning counted per second, so that encoder noise does not add up.
        if t_s - self.block_start_t >= 1.0 {
            self.turn_rad += self.block_yaw.abs();
            self.block_yaw = 0.0;
            self.block_start_t = t_s;
        }
        self.last = Some((t_s, rl_rev, rr_rev));
    }

    /// Turning so far, degrees.
    pub fn turn_deg(&self) -> f64 {
        self.turn_rad.to_degrees()
    }
}

/// A calibration result in the form a live service publishes it (without
/// the version number the service gives it). The field names are those of
/// `calibrate --json` (what the odometry reads).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LiveEstimate {
    /// Drive time of the last sample the fit used, s.
    pub t_s: f64,
    /// Rear circumferences, m.
    pub circumference_m: RearPair,
    /// Their 1-sigma, m.
    pub sigma_m: RearPair,
    /// Effective rear track, m.
    pub track_width_m: f64,
    /// Yaw-rate gyro bias, rad/s.
    pub gyro_bias_rad_s: f64,
    /// Yaw-rate gyro scale error.
    pub gyro_scale: f64,
    /// Side-slip gain, rad per m/s^2, when fitted.
    pub side_slip_gain_rad_per_m_s2: Option<f64>,
    /// GNSS antenna position the fit found (body x forward, y left, from the
    /// rear-axle centre), m: `gyro.antenna_m` of the calibration, else its
    /// `gnss_antenna_m`. On the wire the `gnss_lever_arm` extension; the
    /// odometry uses it unless `vehicle.toml` gives a measured one. Absent in
    /// state files written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gnss_antenna_m: Option<[f64; 2]>,
    /// Its 1-sigma (x, y), m: the odometry uses the antenna only when both
    /// are small enough (`vehicle_model::estimate::MAX_FUSED_ANTENNA_SIGMA_M`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_gnss_antenna_m: Option<[f64; 2]>,
    /// Held-out dead-reckoning error, m.
    pub quality_m: f64,
    /// The wheel-side effect terms a diagnosis of the same drive accepted
    /// (`serve --diagnose`; the `effects` of `calibrate --diagnose --json`);
    /// all zero: the plain 2W model. On the wire one model extension per term.
    #[serde(default, skip_serializing_if = "WheelEffects::is_plain")]
    pub effects: WheelEffects,
    /// The sensor clock offsets and drifts the calibration applied (the
    /// `clock_offsets` of `calibrate --json`, the fields the odometry
    /// reads). On the wire the clock model extensions. Absent in state
    /// files written before it existed: no offsets.
    #[serde(default)]
    pub clock_offsets: LiveClocks,
}

/// The applied clock offsets of a [`LiveEstimate`], in the JSON form of
/// `calibrate --json`'s `clock_offsets` (what the odometry reads).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct LiveClocks {
    /// GNSS against the wheels.
    pub gnss_s: LiveClock,
    /// IMU against the wheels.
    pub imu_s: LiveClock,
}

/// One stream's applied offset and drift.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct LiveClock {
    /// The offset, s (late against the wheels), when determined.
    pub offset_s: Option<f64>,
    /// Whether the calibration applied it.
    pub applied: bool,
    /// The drift.
    pub drift: LiveDrift,
}

/// One stream's drift.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct LiveDrift {
    /// The drift, ppm, when determined.
    pub drift_ppm: Option<f64>,
    /// Wheel time the offset holds at, s.
    pub ref_t_s: Option<f64>,
    /// Whether the calibration applied it.
    pub applied: bool,
}

impl From<&crate::clocks::offsets::StreamOffset> for LiveClock {
    fn from(o: &crate::clocks::offsets::StreamOffset) -> LiveClock {
        LiveClock {
            // The shift the calibration applied (the IMU's may be the
            // GNSS's: `StreamOffset::applied_s`).
            offset_s: if o.applied {
                o.applied_s.or(o.offset_s)
            } else {
                o.offset_s
            },
            applied: o.applied,
            drift: LiveDrift {
                drift_ppm: o.drift.drift_ppm,
                ref_t_s: o.drift.ref_t_s,
                applied: o.drift.applied,
            },
        }
    }
}

impl LiveClocks {
    /// What the odometry applies: the applied offsets and drifts.
    pub fn stream_clocks(&self) -> vehicle_model::estimate::StreamClocks {
        let offset = |c: &LiveClock| c.offset_s.filter(|_| c.applied).unwrap_or(0.0);
        let drift = |c: &LiveClock| match (c.drift.applied, c.drift.drift_ppm, c.drift.ref_t_s) {
            (true, Some(p), Some(r)) => (p, r),
            _ => (0.0, 0.0),
        };
        let ((gp, gr), (ip, ir)) = (drift(&self.gnss_s), drift(&self.imu_s));
        vehicle_model::estimate::StreamClocks {
            gnss_late_s: offset(&self.gnss_s),
            imu_late_s: offset(&self.imu_s),
            gnss_drift_ppm: gp,
            imu_drift_ppm: ip,
            gnss_ref_t_s: gr,
            imu_ref_t_s: ir,
        }
    }
}

impl LiveEstimate {
    /// The 2W parameters.
    pub fn two_wheel(&self) -> TwoWheelParams {
        TwoWheelParams {
            c_rl: self.circumference_m.rl,
            c_rr: self.circumference_m.rr,
            track_width: self.track_width_m,
        }
    }
}

/// A calibration result with its held-out score.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// The result, as it would be published.
    pub estimate: LiveEstimate,
    /// Held-out error of the estimate in use (or the nominal values), m.
    pub current_error_m: f64,
    /// Held-out windows.
    pub windows: usize,
    /// What the diagnosis said, when one was asked for: the effects it
    /// accepted (their terms are in the estimate), or why it could not
    /// decide (the estimate then carries no terms).
    pub diagnosis: Option<Result<Vec<Effect>, String>>,
}

/// The gate's verdict.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// Publish it.
    Accept,
    /// Keep the current estimate, for this reason.
    Reject(String),
}

/// The quality gate (see the module doc).
pub fn gate(c: &Candidate, max_sigma_m: f64, min_windows: usize) -> Verdict {
    let e = &c.estimate;
    let sigma = e.sigma_m.rl.max(e.sigma_m.rr);
    if !(sigma.is_finite() && sigma <= max_sigma_m) {
        return Verdict::Reject(format!(
            "sigma {:.2} mm is above the limit {:.2} mm",
            sigma * 1e3,
            max_sigma_m * 1e3
        ));
    }
    if c.windows < min_windows {
        return Verdict::Reject(format!(
            "only {} held-out windows (need {min_windows})",
            c.windows
        ));
    }
    if !e.quality_m.is_finite() {
        return Verdict::Reject("held-out error is not finite".to_string());
    }
    if c.current_error_m.is_finite() && e.quality_m >= c.current_error_m {
        return Verdict::Reject(format!(
            "held-out error {:.3} m is not below the current estimate's {:.3} m",
            e.quality_m, c.current_error_m
        ));
    }
    Verdict::Accept
}

/// Calibrate with `calibration` on all but the held-out tail of `drive` (the
/// last `holdout_fraction` of its wheel time), then score the result and
/// `current` on the tail with `holdout_window_s`-long dead-reckoning windows.
/// With `diagnose`, the same part of the drive is also diagnosed
/// ([`crate::diagnose`]) and the wheel-side terms of the effects it accepts
/// travel with the estimate; the held-out score stays that of the plain
/// 2W model (the gate compares like with like).
pub fn attempt(
    drive: &Drive,
    current: &TwoWheelParams,
    calibration: &CalibrationConfig,
    holdout_fraction: f64,
    holdout_window_s: f64,
    diagnose: Option<&DiagnoseConfig>,
) -> Result<Candidate, CalibrationError> {
    let (t0, t1) = match (drive.wheels.samples.first(), drive.wheels.samples.last()) {
        (Some(a), Some(b)) => (a.t_s, b.t_s),
        _ => return Err(CalibrationError::NoWheelData),
    };
    let t_split = t0 + (1.0 - holdout_fraction) * (t1 - t0);
    let (fit, held) = split_drive(drive, t_split);
    let cal = calibrate(&fit, calibration)?;
    let (track_estimated, side_slip_fitted) = (cal.track_width_estimated, cal.side_slip);
    let estimate = LiveEstimate {
        t_s: fit.wheels.samples.last().map_or(t0, |s| s.t_s),
        circumference_m: RearPair {
            rl: cal.circumference_m.rl,
            rr: cal.circumference_m.rr,
        },
        sigma_m: RearPair {
            rl: cal.sigma_m.rl.unwrap_or(f64::INFINITY),
            rr: cal.sigma_m.rr.unwrap_or(f64::INFINITY),
        },
        track_width_m: cal.track_width_m,
        gyro_bias_rad_s: cal.gyro_bias_rad_s.unwrap_or(0.0),
        gyro_scale: cal.gyro_scale.unwrap_or(0.0),
        side_slip_gain_rad_per_m_s2: cal.side_slip_gain_rad_per_m_s2,
        // The antenna and its sigma from the same fit: the gyro model's, else the 2W one's.
        gnss_antenna_m: cal.gyro.map(|g| g.antenna_m).or(cal.gnss_antenna_m),
        sigma_gnss_antenna_m: cal
            .gyro
            .map(|g| g.sigma_antenna_m)
            .or(cal.sigma_gnss_antenna_m),
        quality_m: f64::NAN,
        effects: WheelEffects::default(),
        clock_offsets: LiveClocks {
            gnss_s: (&cal.clock_offsets.gnss_s).into(),
            imu_s: (&cal.clock_offsets.imu_s).into(),
        },
    };
    let diagnosis = diagnose.map(|dc| {
        crate::diagnose::diagnose(&fit, dc)
            .map(|d| {
                (
                    d.findings.iter().map(|f| f.effect).collect::<Vec<_>>(),
                    WheelEffects::from(crate::diagnose::terms_beside(
                        &d.terms,
                        track_estimated,
                        side_slip_fitted,
                    )),
                )
            })
            .map_err(|e| e.to_string())
    });
    let effects = match &diagnosis {
        Some(Ok((_, terms))) => *terms,
        _ => WheelEffects::default(),
    };
    let score = holdout_errors(
        &held,
        &[estimate.two_wheel(), *current],
        calibration,
        holdout_window_s,
    )?;
    Ok(Candidate {
        estimate: LiveEstimate {
            quality_m: score.mean_error_m[0],
            effects,
            ..estimate
        },
        current_error_m: score.mean_error_m[1],
        windows: score.windows,
        diagnosis: diagnosis.map(|d| d.map(|(found, _)| found)),
    })
}

/// The drive window a live service keeps by default: the last 30 minutes.
///
/// Memory: a collected sample takes [`SAMPLE_BYTES`] bytes (wheels 56, GNSS
/// 40, IMU 96, heading 32). At the simulator's and a typical car's rates
/// (wheels and IMU at 100 Hz, GNSS and heading at 10 Hz) that is 15.9 kB per
/// second of drive, 57 MB per hour. [`keep_window`] lets the window grow to
/// [`WINDOW_SLACK`] more (33 minutes) before it cuts it back, so at most
/// 1980 s x 15.9 kB = 31.5 MB of samples are held, and at most twice that of
/// vector capacity (63 MB), whatever the length of the drive. A running
/// attempt works on a copy of the window (one more 31.5 MB, plus the fit and
/// held-out parts it splits it into). 30 minutes is plenty: the default
/// thresholds ask for 1.5 km and a full turn before an attempt, which a
/// drive covers in a few minutes.
pub const DEFAULT_WINDOW_S: f64 = 1800.0;

/// How far beyond its length a window grows before [`keep_window`] cuts it
/// back, as a fraction of the length: cutting moves the whole window in
/// memory, so it is done once per this much new drive, not on every sample.
pub const WINDOW_SLACK: f64 = 0.1;

/// Bytes of one collected sample: wheels, GNSS, IMU, heading.
pub const SAMPLE_BYTES: [usize; 4] = [
    std::mem::size_of::<WheelSample>(),
    std::mem::size_of::<GnssSample>(),
    std::mem::size_of::<ImuSample>(),
    std::mem::size_of::<HeadingSample>(),
];

/// Bytes taken by these many samples (wheels, GNSS, IMU, heading) of a drive.
pub fn sample_bytes(counts: [usize; 4]) -> usize {
    counts.iter().zip(SAMPLE_BYTES).map(|(n, b)| n * b).sum()
}

/// Keep the last `window_s` of the drive in `builder`: once its wheel data
/// spans more than `window_s` (1 + [`WINDOW_SLACK`]), drop every sample older
/// than `window_s` before the last wheel sample. Returns the samples dropped
/// (0 most of the time).
pub fn keep_window(builder: &mut DriveBuilder, window_s: f64) -> usize {
    let (first, last) = match (builder.wheels().first(), builder.wheels().last()) {
        (Some(a), Some(b)) => (a.t_s, b.t_s),
        _ => return 0,
    };
    if last - first > window_s * (1.0 + WINDOW_SLACK) {
        builder.forget_before(last - window_s)
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::drive::GnssAntenna;

    fn vehicle() -> VehicleParams {
        VehicleParams {
            name: None,
            track_width_m: 1.5,
            nominal_circumference_m: 2.0,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: GnssAntenna::default(),
        }
    }

    fn estimate() -> LiveEstimate {
        LiveEstimate {
            t_s: 12.5,
            circumference_m: RearPair { rl: 1.98, rr: 1.99 },
            sigma_m: RearPair { rl: 1e-3, rr: 2e-3 },
            track_width_m: 1.52,
            gyro_bias_rad_s: 0.001,
            gyro_scale: -0.01,
            side_slip_gain_rad_per_m_s2: Some(0.004),
            gnss_antenna_m: Some([0.5, -0.3]),
            sigma_gnss_antenna_m: Some([0.02, 0.03]),
            quality_m: 0.8,
            effects: WheelEffects::default(),
            clock_offsets: LiveClocks::default(),
        }
    }

    #[test]
    fn coverage_counts_distance_and_turning() {
        let mut c = Coverage::new(&vehicle());
        // A quarter circle of radius 10 m in 10 s, then 10 s straight.
        let (r, t, cn) = (10.0, 1.5, 2.0);
        let quarter = std::f64::consts::FRAC_PI_2;
        for i in 0..=100 {
            let f = i as f64 / 100.0 * quarter;
            c.add(
                i as f64 * 0.1,
                f * (r - t / 2.0) / cn,
                f * (r + t / 2.0) / cn,
            );
        }
        assert!((c.turn_deg() - 90.0).abs() < 1.0, "{}", c.turn_deg());
        let (rl0, rr0) = (quarter * (r - t / 2.0) / cn, quarter * (r + t / 2.0) / cn);
        for i in 1..=100 {
            c.add(
                10.0 + i as f64 * 0.1,
                rl0 + i as f64 * 0.05,
                rr0 + i as f64 * 0.05,
            );
        }
        assert!(
            (c.distance_m - (quarter * r + 10.0)).abs() < 1e-6,
            "{}",
            c.distance_m
        );
        assert!((c.turn_deg() - 90.0).abs() < 1.0);
    }

    #[test]
    fn the_gate_checks_sigma_windows_and_improvement() {
        let mut cand = Candidate {
            estimate: estimate(),
            current_error_m: 2.0,
            windows: 5,
            diagnosis: None,
        };
        assert_eq!(gate(&cand, 0.005, 3), Verdict::Accept);
        cand.estimate.sigma_m.rr = 0.01;
        assert!(matches!(gate(&cand, 0.005, 3), Verdict::Reject(m) if m.contains("sigma")));
        cand.estimate.sigma_m.rr = 0.001;
        cand.windows = 2;
        assert!(matches!(gate(&cand, 0.005, 3), Verdict::Reject(m) if m.contains("windows")));
        cand.windows = 5;
        cand.current_error_m = 0.5;
        assert!(matches!(gate(&cand, 0.005, 3), Verdict::Reject(m) if m.contains("not below")));
    }

    #[test]
    fn the_window_bounds_what_is_kept_of_a_long_drive() {
        use interfaces::wire::{GnssFix, Header, Heading, Imu, WheelRotations};
        // The documented per-sample sizes.
        assert_eq!(SAMPLE_BYTES, [56, 40, 96, 32]);
        let window_s = DEFAULT_WINDOW_S;
        let mut b = DriveBuilder::new(vehicle());
        // Two hours at 100 Hz (wheels, IMU) and 10 Hz (GNSS, heading), fed
        // 0.1 s at a time as the service drains the bus, windowed after each.
        let rates = [100.0, 10.0, 100.0, 10.0];
        let bound = rates.map(|r| (r * window_s * (1.0 + WINDOW_SLACK)) as usize + 1);
        let mut most = [0usize; 4];
        for i in 0..720_000u64 {
            let t = i as f64 * 0.01;
            if i % 10 == 0 {
                b.push_gnss(&GnssFix {
                    header: Header::from_seconds(t, i),
                    x_m: t,
                    fix: 1,
                    ..GnssFix::default()
                });
                b.push_heading(&Heading {
                    header: Header::from_seconds(t, i),
                    ..Heading::default()
                });
            }
            b.push_imu(&Imu {
                header: Header::from_seconds(t, i),
                ..Imu::default()
            });
            b.push_wheels(&WheelRotations {
                header: Header::from_seconds(t, i),
                rl_rev: t * 5.0,
                rr_rev: t * 5.0,
                ..WheelRotations::default()
            });
            if i % 10 == 9 {
                keep_window(&mut b, window_s);
                let n = b.sample_counts();
                for k in 0..4 {
                    most[k] = most[k].max(n[k]);
                    assert!(n[k] <= bound[k], "t = {t}: {n:?} above {bound:?}");
                }
            }
        }
        // Everything was collected (nothing refused), the old part dropped.
        assert!(b.warnings().is_empty(), "{:?}", b.warnings());
        assert_eq!(b.forgotten()[0] as usize + b.wheel_count(), 720_000);
        // The window is kept whole.
        let d = b.snapshot();
        assert!(d.wheel_duration_s() >= window_s - 0.02);
        // The documented bound: 31.5 MB of samples.
        let bytes = sample_bytes(most);
        assert!(bytes <= 31_600_000, "{bytes} bytes");
        assert!(bytes >= 31_000_000, "{bytes} bytes: the window fills");
    }
}
