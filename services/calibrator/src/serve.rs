//! `calibrator serve`: the live calibrator of the process graph.
//!
//! It subscribes to the sensor topics and collects the drive. Once enough has
//! been collected (distance, turning and GNSS fixes, all configurable) it runs
//! [`crate::calibrate`] on a worker thread while collection goes on. A result is
//! published on the estimate topic (history of one: a late subscriber gets
//! it) only when it passes the quality gate:
//!
//! 1. both circumference sigmas are at most [`ServeConfig::max_sigma_m`];
//! 2. on held-out data (the last [`ServeConfig::holdout_fraction`] of what was
//!    collected, which the fit never saw) its dead-reckoning error is lower
//!    than that of the estimate in use (or the nominal values).
//!
//! The held-out error is the mean position error at the end of
//! [`ServeConfig::holdout_window_s`]-long 2W dead-reckoning windows, each
//! started from the GNSS/IMU reference pose: the situation of a GNSS outage.
//!
//! Every accepted estimate is written to [`ServeConfig::state_file`] (JSON, the
//! fields of `calibrate --json` the odometry reads plus `version`,
//! `quality_m`, `t_s`); after a restart the service starts from it and
//! publishes it at once.
//!
//! The pieces that decide ([`Coverage`], [`split_drive`], [`holdout_errors`],
//! [`gate`]) are pure; [`run`] is the I/O loop around them.

use crate::prep::prepare;
use crate::reference::{build as build_reference, Reference};
use crate::{calibrate, CalibrationConfig, CalibrationError};
use iceoryx2::prelude::CallbackProgression;
use interfaces::bus::{self, Bus, BusError, TopicPublisher};
use interfaces::drive::{Drive, VehicleParams};
use interfaces::effects::Effect;
use interfaces::wire::{CircumferenceEstimate, Header, ModelExtension, MAX_EXTENSIONS};
use odometry::estimate_file::antenna_extension;
use odometry::two_wheel::{step, Pose2, TwoWheelParams};
use sensor_bridge::record::{DriveBuilder, SensorSubscribers};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

/// Settings of the service.
#[derive(Debug, Clone, PartialEq)]
pub struct ServeConfig {
    /// Vehicle parameters (the bus does not carry them).
    pub vehicle: VehicleParams,
    /// Calibration settings.
    pub calibration: CalibrationConfig,
    /// Distance (nominal circumference) collected before the first attempt, m.
    pub min_distance_m: f64,
    /// Total absolute heading change (from the wheels) before the first attempt, degrees.
    pub min_turn_deg: f64,
    /// GNSS fixes collected before the first attempt.
    pub min_gnss_fixes: usize,
    /// New distance between two attempts, m.
    pub recalibrate_distance_m: f64,
    /// Fraction (by time) at the end of the collected drive kept out of the
    /// fit and used to judge the result.
    pub holdout_fraction: f64,
    /// Length of the dead-reckoning windows on the held-out data, s.
    pub holdout_window_s: f64,
    /// Held-out windows needed to judge a result.
    pub min_holdout_windows: usize,
    /// Largest accepted 1-sigma of either circumference, m.
    pub max_sigma_m: f64,
    /// Where the last accepted estimate is kept (`None`: not kept).
    pub state_file: Option<PathBuf>,
    /// Stop after the sensor stream ended and no attempt is running.
    pub exit_on_end: bool,
}

impl ServeConfig {
    /// Defaults for a vehicle.
    pub fn new(vehicle: VehicleParams) -> ServeConfig {
        ServeConfig {
            vehicle,
            calibration: CalibrationConfig::default(),
            min_distance_m: 1500.0,
            min_turn_deg: 360.0,
            min_gnss_fixes: 100,
            recalibrate_distance_m: 1500.0,
            holdout_fraction: 0.3,
            holdout_window_s: 15.0,
            min_holdout_windows: 3,
            max_sigma_m: 0.005,
            state_file: None,
            exit_on_end: false,
        }
    }

    /// Check the ranges; the error names the setting.
    pub fn validate(&self) -> Result<(), ServeError> {
        let bad = |field: &'static str, value: f64| Err(ServeError::InvalidConfig { field, value });
        if !(self.min_distance_m.is_finite() && self.min_distance_m >= 0.0) {
            return bad("min_distance_m", self.min_distance_m);
        }
        if !(self.min_turn_deg.is_finite() && self.min_turn_deg >= 0.0) {
            return bad("min_turn_deg", self.min_turn_deg);
        }
        if !(self.recalibrate_distance_m.is_finite() && self.recalibrate_distance_m > 0.0) {
            return bad("recalibrate_distance_m", self.recalibrate_distance_m);
        }
        if !(self.holdout_fraction > 0.0 && self.holdout_fraction < 0.9) {
            return bad("holdout_fraction", self.holdout_fraction);
        }
        if !(self.holdout_window_s.is_finite() && self.holdout_window_s >= 1.0) {
            return bad("holdout_window_s", self.holdout_window_s);
        }
        if !(self.max_sigma_m.is_finite() && self.max_sigma_m > 0.0) {
            return bad("max_sigma_m", self.max_sigma_m);
        }
        self.calibration.validate().map_err(ServeError::Calibration)
    }
}

/// Errors of the service.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// A setting out of range.
    #[error("invalid setting {field} = {value}")]
    InvalidConfig {
        /// The setting.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// The calibration settings are invalid.
    #[error(transparent)]
    Calibration(CalibrationError),
    /// An iceoryx2 operation failed.
    #[error(transparent)]
    Bus(#[from] BusError),
    /// The state file could not be read or written.
    #[error("state file {path}: {detail}")]
    State {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        detail: String,
    },
}

// ---------------------------------------------------------------------------
// The persisted estimate

/// A rear-wheel pair in the state file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pair {
    /// Rear left.
    pub rl: f64,
    /// Rear right.
    pub rr: f64,
}

/// An accepted estimate, as published and as kept in the state file. The
/// field names are those of `calibrate --json` (what the odometry reads).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Accepted {
    /// Increases with every accepted estimate (1 = the first).
    pub version: u64,
    /// Drive time of the last sample the fit used, s.
    pub t_s: f64,
    /// Rear circumferences, m.
    pub circumference_m: Pair,
    /// Their 1-sigma, m.
    pub sigma_m: Pair,
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
    /// are small enough (`odometry::estimate_file::MAX_FUSED_ANTENNA_SIGMA_M`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_gnss_antenna_m: Option<[f64; 2]>,
    /// Held-out dead-reckoning error, m.
    pub quality_m: f64,
}

impl Accepted {
    /// The wire form.
    pub fn to_wire(&self) -> CircumferenceEstimate {
        let mut extensions = [ModelExtension::default(); MAX_EXTENSIONS];
        let mut count = 0;
        if let Some(k) = self.side_slip_gain_rad_per_m_s2 {
            extensions[0] = ModelExtension {
                effect_code: Effect::SideSlip.code(),
                param_count: 1,
                params: [k, 0.0, 0.0, 0.0],
            };
            count = 1;
        }
        if let Some(a) = self.gnss_antenna_m {
            extensions[count] = antenna_extension(a, self.sigma_gnss_antenna_m);
            count += 1;
        }
        CircumferenceEstimate {
            header: Header::from_seconds(self.t_s, 0),
            version: self.version,
            c_rl_m: self.circumference_m.rl,
            c_rr_m: self.circumference_m.rr,
            sigma_rl_m: self.sigma_m.rl,
            sigma_rr_m: self.sigma_m.rr,
            track_width_m: self.track_width_m,
            gyro_bias_rad_s: self.gyro_bias_rad_s,
            gyro_scale: self.gyro_scale,
            quality_m: self.quality_m,
            extension_count: count as u32,
            _pad: 0,
            extensions,
        }
    }

    /// The 2W parameters.
    pub fn two_wheel(&self) -> TwoWheelParams {
        TwoWheelParams {
            c_rl: self.circumference_m.rl,
            c_rr: self.circumference_m.rr,
            track_width: self.track_width_m,
        }
    }

    fn is_usable(&self) -> bool {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        pos(self.circumference_m.rl)
            && pos(self.circumference_m.rr)
            && pos(self.track_width_m)
            && self.gyro_bias_rad_s.is_finite()
            && self.gyro_scale.is_finite()
    }
}

/// Read the state file; `Ok(None)` when it does not exist.
pub fn load_state(path: &Path) -> Result<Option<Accepted>, ServeError> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => {
            return Err(ServeError::State {
                path: path.to_path_buf(),
                detail: e.to_string(),
            })
        }
    };
    let a: Accepted = serde_json::from_str(&text).map_err(|e| ServeError::State {
        path: path.to_path_buf(),
        detail: format!("line {}, column {}: {e}", e.line(), e.column()),
    })?;
    if !a.is_usable() {
        return Err(ServeError::State {
            path: path.to_path_buf(),
            detail: "circumferences and track must be positive, gyro values finite".to_string(),
        });
    }
    Ok(Some(a))
}

/// Write the state file atomically (a temporary file renamed over it).
pub fn save_state(path: &Path, a: &Accepted) -> Result<(), ServeError> {
    let err = |e: std::io::Error| ServeError::State {
        path: path.to_path_buf(),
        detail: e.to_string(),
    };
    let text = serde_json::to_string_pretty(a).map_err(|e| ServeError::State {
        path: path.to_path_buf(),
        detail: e.to_string(),
    })?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(err)?;
    }
    let tmp = path.with_extension("json.tmp");
    std::fs::write(&tmp, text + "\n").map_err(err)?;
    std::fs::rename(&tmp, path).map_err(err)
}

// ---------------------------------------------------------------------------
// Pure decisions

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

/// The part of `drive` before `t_split` (fit) and from it on (held out).
pub fn split_drive(drive: &Drive, t_split: f64) -> (Drive, Drive) {
    fn part<T: Clone>(
        v: &Option<Vec<T>>,
        t: impl Fn(&T) -> f64,
        before: bool,
        ts: f64,
    ) -> Option<Vec<T>> {
        v.as_ref().map(|v| {
            v.iter()
                .filter(|s| (t(s) < ts) == before)
                .cloned()
                .collect()
        })
    }
    let mut fit = drive.clone();
    let mut held = drive.clone();
    fit.wheels.samples.retain(|s| s.t_s < t_split);
    held.wheels.samples.retain(|s| s.t_s >= t_split);
    fit.gnss = part(&drive.gnss, |s| s.t_s, true, t_split);
    held.gnss = part(&drive.gnss, |s| s.t_s, false, t_split);
    fit.imu = part(&drive.imu, |s| s.t_s, true, t_split);
    held.imu = part(&drive.imu, |s| s.t_s, false, t_split);
    fit.heading = part(&drive.heading, |s| s.t_s, true, t_split);
    held.heading = part(&drive.heading, |s| s.t_s, false, t_split);
    fit.truth = part(&drive.truth, |s| s.t_s, true, t_split);
    held.truth = part(&drive.truth, |s| s.t_s, false, t_split);
    (fit, held)
}

/// Dead-reckoning errors of several parameter sets on the same held-out data.
#[derive(Debug, Clone, PartialEq)]
pub struct HoldoutScore {
    /// Mean end-of-window position error per parameter set, m.
    pub mean_error_m: Vec<f64>,
    /// Windows evaluated.
    pub windows: usize,
}

/// Dead-reckon `window_s`-long windows (started every `window_s / 2` from the
/// reference pose) over `held` with each parameter set; the error of a window
/// is the distance to the reference at its end.
pub fn holdout_errors(
    held: &Drive,
    params: &[TwoWheelParams],
    config: &CalibrationConfig,
    window_s: f64,
) -> Result<HoldoutScore, CalibrationError> {
    let mut warnings = Vec::new();
    let p = prepare(held, config, &mut warnings)?;
    let r = build_reference(&p, held, config, &mut warnings)?;
    let track = RefTrack::of(&r);
    Ok(score_windows(
        &p.t,
        &p.dn_rl,
        &p.dn_rr,
        &p.piece_starts,
        &track,
        params,
        window_s,
    ))
}

/// The reference poses at the wheel sample times.
struct RefTrack<'a> {
    x: &'a [f64],
    y: &'a [f64],
    yaw: &'a [f64],
    valid: &'a [bool],
}

impl<'a> RefTrack<'a> {
    fn of(r: &'a Reference) -> RefTrack<'a> {
        RefTrack {
            x: &r.x,
            y: &r.y,
            yaw: &r.yaw,
            valid: &r.valid,
        }
    }
}

fn score_windows(
    t: &[f64],
    dn_rl: &[f64],
    dn_rr: &[f64],
    piece_starts: &[usize],
    r: &RefTrack,
    params: &[TwoWheelParams],
    window_s: f64,
) -> HoldoutScore {
    let n = t.len();
    let mut sums = vec![0.0; params.len()];
    let mut windows = 0;
    let mut k0 = 0;
    while k0 < n {
        // A window starts at a sample with a valid reference.
        if !r.valid[k0] {
            k0 += 1;
            continue;
        }
        let t_end = t[k0] + window_s;
        let mut poses: Vec<Pose2> = params
            .iter()
            .map(|_| Pose2 {
                x: r.x[k0],
                y: r.y[k0],
                yaw: r.yaw[k0],
            })
            .collect();
        let mut end: Option<(usize, Vec<Pose2>)> = None;
        let mut k = k0 + 1;
        while k < n && t[k] <= t_end {
            if piece_starts.binary_search(&k).is_ok() {
                break; // a break in the wheel data ends the window
            }
            for (pose, prm) in poses.iter_mut().zip(params) {
                let (ds, dyaw) = prm.increments(dn_rl[k], dn_rr[k]);
                *pose = step(*pose, ds, dyaw, 0.0);
            }
            if r.valid[k] {
                end = Some((k, poses.clone()));
            }
            k += 1;
        }
        if let Some((ke, end_poses)) = end {
            if t[ke] - t[k0] >= 0.8 * window_s {
                for (s, pose) in sums.iter_mut().zip(&end_poses) {
                    *s += (pose.x - r.x[ke]).hypot(pose.y - r.y[ke]);
                }
                windows += 1;
            }
        }
        // Next window half a window later.
        let t_next = t[k0] + 0.5 * window_s;
        while k0 < n && t[k0] < t_next {
            k0 += 1;
        }
    }
    HoldoutScore {
        mean_error_m: sums
            .iter()
            .map(|s| {
                if windows > 0 {
                    s / windows as f64
                } else {
                    f64::NAN
                }
            })
            .collect(),
        windows,
    }
}

/// A calibration result with its held-out score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// The result, as it would be published (version still 0).
    pub estimate: Accepted,
    /// Held-out error of the estimate in use (or the nominal values), m.
    pub current_error_m: f64,
    /// Held-out windows.
    pub windows: usize,
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

/// Calibrate on all but the held-out tail of `drive`, then score the result
/// and `current` on the tail.
pub fn attempt(
    drive: &Drive,
    current: &TwoWheelParams,
    cfg: &ServeConfig,
) -> Result<Candidate, CalibrationError> {
    let (t0, t1) = match (drive.wheels.samples.first(), drive.wheels.samples.last()) {
        (Some(a), Some(b)) => (a.t_s, b.t_s),
        _ => return Err(CalibrationError::NoWheelData),
    };
    let t_split = t0 + (1.0 - cfg.holdout_fraction) * (t1 - t0);
    let (fit, held) = split_drive(drive, t_split);
    let cal = calibrate(&fit, &cfg.calibration)?;
    let estimate = Accepted {
        version: 0,
        t_s: fit.wheels.samples.last().map_or(t0, |s| s.t_s),
        circumference_m: Pair {
            rl: cal.circumference_m.rl,
            rr: cal.circumference_m.rr,
        },
        sigma_m: Pair {
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
    };
    let score = holdout_errors(
        &held,
        &[estimate.two_wheel(), *current],
        &cfg.calibration,
        cfg.holdout_window_s,
    )?;
    Ok(Candidate {
        estimate: Accepted {
            quality_m: score.mean_error_m[0],
            ..estimate
        },
        current_error_m: score.mean_error_m[1],
        windows: score.windows,
    })
}

// ---------------------------------------------------------------------------
// The service loop

/// What the service did, returned when it stops.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ServeSummary {
    /// Calibration attempts finished.
    pub attempts: usize,
    /// Estimates accepted and published.
    pub accepted: usize,
    /// The estimate in use at the end.
    pub current: Option<Accepted>,
    /// Wheel samples collected.
    pub wheel_samples: usize,
    /// Sensor samples lost on the bus (sequence gaps): wheels, gnss, imu, heading.
    pub lost: [u64; 4],
}

struct Running {
    rx: mpsc::Receiver<Result<Candidate, CalibrationError>>,
    number: usize,
    span_s: f64,
}

/// Run the service on `bus` until Ctrl-C/SIGTERM (or the end of the stream,
/// with [`ServeConfig::exit_on_end`]).
pub fn run(bus: &Bus, cfg: &ServeConfig) -> Result<ServeSummary, ServeError> {
    cfg.validate()?;
    let subs = SensorSubscribers::open(bus)?;
    let mut publisher: TopicPublisher<CircumferenceEstimate> = bus.publisher()?;
    let mut summary = ServeSummary::default();
    let nominal = TwoWheelParams {
        c_rl: cfg.vehicle.nominal_circumference_m,
        c_rr: cfg.vehicle.nominal_circumference_m,
        track_width: cfg.vehicle.track_width_m,
    };
    let mut current: Option<Accepted> = match &cfg.state_file {
        Some(path) => load_state(path)?,
        None => None,
    };
    if let Some(a) = &current {
        tracing::info!(
            "calibrator: starting from the persisted estimate v{} (c_rl = {:.4} m, c_rr = {:.4} m, \
             held-out error {:.2} m); publishing it",
            a.version,
            a.circumference_m.rl,
            a.circumference_m.rr,
            a.quality_m
        );
        publisher.publish(a.to_wire())?;
    } else {
        tracing::info!(
            "calibrator: no accepted estimate yet; nominal c = {:.4} m on both rear wheels",
            cfg.vehicle.nominal_circumference_m
        );
    }

    let waitset = bus.waitset()?;
    let ws_err = |action: &'static str, e: &dyn std::fmt::Debug| BusError::Service {
        service: "waitset".to_string(),
        action,
        detail: format!("{e:?}"),
    };
    let _g1 = waitset
        .attach_notification(subs.wheels.listener())
        .map_err(|e| ws_err("attach", &e))?;
    let _g2 = waitset
        .attach_notification(subs.gnss.listener())
        .map_err(|e| ws_err("attach", &e))?;
    let _g3 = waitset
        .attach_notification(subs.imu.listener())
        .map_err(|e| ws_err("attach", &e))?;
    let _g4 = waitset
        .attach_notification(subs.heading.listener())
        .map_err(|e| ws_err("attach", &e))?;
    // The tick delivers the history to late subscribers, collects finished
    // attempts and notices signals taken by the worker thread.
    let _tick = waitset
        .attach_interval(Duration::from_millis(100))
        .map_err(|e| ws_err("attach interval", &e))?;

    let mut builder = DriveBuilder::new(cfg.vehicle.clone());
    let mut coverage = Coverage::new(&cfg.vehicle);
    let mut seen = 0usize;
    let mut last_attempt_distance = f64::NEG_INFINITY;
    let mut running: Option<Running> = None;
    let mut ended = false;
    let mut announced_ready = false;

    loop {
        let result = waitset
            .wait_and_process_once(|_| CallbackProgression::Continue)
            .map_err(|e| ws_err("wait", &e))?;
        let outcome = subs.drain_into(&mut builder)?;
        for s in &builder.wheels()[seen..] {
            coverage.add(s.t_s, s.rl, s.rr);
        }
        seen = builder.wheel_count();
        publisher.update_connections()?;
        if outcome.end_of_stream() && !ended {
            ended = true;
            tracing::info!(
                "calibrator: sensor stream ended after {:.0} m, {:.0} deg of turning",
                coverage.distance_m,
                coverage.turn_deg()
            );
            if !announced_ready {
                let mut short = Vec::new();
                if coverage.distance_m < cfg.min_distance_m {
                    short.push(format!(
                        "{:.0} m of the {:.0} m (--min-distance)",
                        coverage.distance_m, cfg.min_distance_m
                    ));
                }
                if coverage.turn_deg() < cfg.min_turn_deg {
                    short.push(format!(
                        "{:.0} deg of turning of the {:.0} (--min-turn)",
                        coverage.turn_deg(),
                        cfg.min_turn_deg
                    ));
                }
                if builder.gnss_count() < cfg.min_gnss_fixes {
                    short.push(format!(
                        "{} GNSS fixes of the {} (--min-fixes)",
                        builder.gnss_count(),
                        cfg.min_gnss_fixes
                    ));
                }
                tracing::warn!(
                    "calibrator: the drive is too short for an attempt: {}; lower the thresholds \
                     for short drives",
                    short.join(", ")
                );
            }
        }

        // A finished attempt?
        if let Some(run) = &running {
            match run.rx.try_recv() {
                Ok(outcome) => {
                    let number = run.number;
                    running = None;
                    summary.attempts += 1;
                    handle_attempt(
                        number,
                        outcome,
                        cfg,
                        &mut current,
                        &mut publisher,
                        &mut summary,
                    )?;
                }
                Err(mpsc::TryRecvError::Empty) => {}
                Err(mpsc::TryRecvError::Disconnected) => {
                    tracing::warn!("calibrator: attempt #{} ended without a result", run.number);
                    running = None;
                }
            }
        }

        // Enough for a (new) attempt?
        let enough = coverage.distance_m >= cfg.min_distance_m
            && coverage.turn_deg() >= cfg.min_turn_deg
            && builder.gnss_count() >= cfg.min_gnss_fixes;
        if enough && !announced_ready {
            announced_ready = true;
            tracing::info!(
                "calibrator: enough data: {:.0} m, {:.0} deg of turning, {} GNSS fixes",
                coverage.distance_m,
                coverage.turn_deg(),
                builder.gnss_count()
            );
        }
        if running.is_none()
            && enough
            && coverage.distance_m - last_attempt_distance >= cfg.recalibrate_distance_m
        {
            last_attempt_distance = coverage.distance_m;
            let drive = builder.snapshot();
            let span_s = drive.wheel_duration_s();
            let params = current.map_or(nominal, |a| a.two_wheel());
            let worker_cfg = cfg.clone();
            let (tx, rx) = mpsc::channel();
            let number = summary.attempts + 1;
            tracing::info!(
                "calibrator: attempt #{number} on {span_s:.0} s of drive ({:.0} m), {:.0} % held out",
                coverage.distance_m,
                cfg.holdout_fraction * 100.0
            );
            std::thread::Builder::new()
                .name(format!("calibration-{number}"))
                .spawn(move || {
                    let _ = tx.send(attempt(&drive, &params, &worker_cfg));
                })
                .map_err(|e| ServeError::State {
                    path: PathBuf::from("<worker thread>"),
                    detail: e.to_string(),
                })?;
            running = Some(Running { rx, number, span_s });
        }

        if bus::stop_requested_by(result) {
            if let Some(run) = &running {
                tracing::info!(
                    "calibrator: stopping; attempt #{} on {:.0} s of drive abandoned",
                    run.number,
                    run.span_s
                );
            }
            break;
        }
        if cfg.exit_on_end && ended && running.is_none() {
            break;
        }
    }
    summary.current = current;
    summary.wheel_samples = builder.wheel_count();
    summary.lost = subs.lost();
    Ok(summary)
}

fn handle_attempt(
    number: usize,
    outcome: Result<Candidate, CalibrationError>,
    cfg: &ServeConfig,
    current: &mut Option<Accepted>,
    publisher: &mut TopicPublisher<CircumferenceEstimate>,
    summary: &mut ServeSummary,
) -> Result<(), ServeError> {
    let cand = match outcome {
        Ok(c) => c,
        Err(e) => {
            tracing::warn!("calibrator: attempt #{number} failed: {e}");
            return Ok(());
        }
    };
    let e = &cand.estimate;
    let verdict = gate(&cand, cfg.max_sigma_m, cfg.min_holdout_windows);
    tracing::info!(
        "calibrator: attempt #{number}: c_rl = {:.4} m, c_rr = {:.4} m (sigma {:.2}/{:.2} mm), \
         held-out error {:.3} m vs {:.3} m in use ({} windows of {:.0} s)",
        e.circumference_m.rl,
        e.circumference_m.rr,
        e.sigma_m.rl * 1e3,
        e.sigma_m.rr * 1e3,
        e.quality_m,
        cand.current_error_m,
        cand.windows,
        cfg.holdout_window_s
    );
    match verdict {
        Verdict::Reject(why) => {
            tracing::info!("calibrator: attempt #{number} rejected: {why}");
        }
        Verdict::Accept => {
            let accepted = Accepted {
                version: current.map_or(0, |a| a.version) + 1,
                ..*e
            };
            // Persisted before it is published: whoever sees it can rely on
            // a restart starting from it.
            if let Some(path) = &cfg.state_file {
                save_state(path, &accepted)?;
            }
            publisher.publish(accepted.to_wire())?;
            tracing::info!(
                "calibrator: PUBLISHED estimate v{}: c_rl = {:.4} m, c_rr = {:.4} m, track {:.4} m{}",
                accepted.version,
                accepted.circumference_m.rl,
                accepted.circumference_m.rr,
                accepted.track_width_m,
                cfg.state_file
                    .as_ref()
                    .map(|p| format!(", saved to {}", p.display()))
                    .unwrap_or_default()
            );
            *current = Some(accepted);
            summary.accepted += 1;
        }
    }
    Ok(())
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

    fn accepted() -> Accepted {
        Accepted {
            version: 3,
            t_s: 12.5,
            circumference_m: Pair { rl: 1.98, rr: 1.99 },
            sigma_m: Pair { rl: 1e-3, rr: 2e-3 },
            track_width_m: 1.52,
            gyro_bias_rad_s: 0.001,
            gyro_scale: -0.01,
            side_slip_gain_rad_per_m_s2: Some(0.004),
            gnss_antenna_m: Some([0.5, -0.3]),
            sigma_gnss_antenna_m: Some([0.02, 0.03]),
            quality_m: 0.8,
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
            estimate: accepted(),
            current_error_m: 2.0,
            windows: 5,
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
    fn the_state_file_round_trips_and_reads_as_a_calibration_json() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub/state.json");
        assert_eq!(load_state(&path).unwrap(), None);
        save_state(&path, &accepted()).unwrap();
        assert_eq!(load_state(&path).unwrap(), Some(accepted()));
        // The odometry reads it like `calibrate --json` output.
        let text = std::fs::read_to_string(&path).unwrap();
        let est = odometry::estimate_file::Estimate::from_json_str(&text, "state").unwrap();
        assert_eq!(est.params.two_wheel.c_rr, 1.99);
        assert_eq!(est.params.gyro_scale, -0.01);
        assert_eq!(est.antenna_m, Some([0.5, -0.3]));
        assert_eq!(est.antenna_sigma_m, Some([0.02, 0.03]));
        // A state file from before the antenna field still loads.
        let old = text
            .replace("\"gnss_antenna_m\"", "\"unknown_field\"")
            .replace("\"sigma_gnss_antenna_m\"", "\"unknown_field_2\"");
        std::fs::write(&path, old).unwrap();
        assert_eq!(load_state(&path).unwrap().unwrap().gnss_antenna_m, None);
        std::fs::write(&path, "{\"version\": 1}").unwrap();
        let err = load_state(&path).unwrap_err().to_string();
        assert!(
            err.contains("state.json") && err.contains("missing field"),
            "{err}"
        );
    }

    #[test]
    fn the_wire_form_carries_every_value() {
        let w = accepted().to_wire();
        assert_eq!(w.version, 3);
        assert_eq!((w.c_rl_m, w.c_rr_m, w.sigma_rr_m), (1.98, 1.99, 2e-3));
        assert_eq!(w.quality_m, 0.8);
        assert_eq!(w.extension_count, 2);
        assert_eq!(w.extensions[0].effect_code, Effect::SideSlip.code());
        assert_eq!(w.extensions[0].params[0], 0.004);
        // The odometry reads the antenna back from the second extension.
        let est = odometry::estimate_file::Estimate::from_wire(&w).unwrap();
        assert_eq!(est.antenna_m, Some([0.5, -0.3]));
        assert_eq!(est.fusable_antenna(), Some([0.5, -0.3]));
        assert_eq!(w.header.t_ns, 12_500_000_000);
    }

    #[test]
    fn windows_score_the_right_parameters_best() {
        // Straight line at 10 m/s sampled at 10 Hz; true c = 2.0.
        let n = 400;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.1).collect();
        let dn = vec![0.5; n];
        let x: Vec<f64> = t.iter().map(|&t| 10.0 * t).collect();
        let zeros = vec![0.0; n];
        let valid = vec![true; n];
        let r = RefTrack {
            x: &x,
            y: &zeros,
            yaw: &zeros,
            valid: &valid,
        };
        let p = |c: f64| TwoWheelParams {
            c_rl: c,
            c_rr: c,
            track_width: 1.5,
        };
        let s = score_windows(&t, &dn, &dn, &[0], &r, &[p(2.0), p(2.2)], 10.0);
        assert!(s.windows >= 6, "{}", s.windows);
        assert!(s.mean_error_m[0] < 1e-9);
        // 10 % too large: 10 m over a 100 m window.
        assert!(
            (s.mean_error_m[1] - 10.0).abs() < 0.2,
            "{:?}",
            s.mean_error_m
        );
    }
}
