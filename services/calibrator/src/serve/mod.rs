//! `calibrator serve`: the live calibrator of the process graph.
//!
//! It subscribes to the sensor topics and collects the drive. Once enough has
//! been collected (distance, turning and GNSS fixes, all configurable) it runs
//! a [`calibrator::live::attempt`] on a worker thread while collection goes
//! on. A result is published on the estimate topic (history of one: a late
//! subscriber gets it) only when it passes the quality gate
//! ([`calibrator::live::gate`]):
//!
//! 1. both circumference sigmas are at most [`ServeConfig::max_sigma_m`];
//! 2. on held-out data (the last [`ServeConfig::holdout_fraction`] of what was
//!    collected, which the fit never saw) its dead-reckoning error is lower
//!    than that of the estimate in use (or the nominal values).
//!
//! Memory is bounded: only the last [`ServeConfig::window_s`] of the drive
//! is kept (default [`DEFAULT_WINDOW_S`], 30 minutes: at most about 32 MB of
//! samples at 100 Hz wheels and IMU, see [`DEFAULT_WINDOW_S`] for the
//! numbers), and attempts calibrate on that window. The collector checks
//! what comes over the bus ([`interfaces::collect`]): a sample whose time or
//! revolutions jump is refused, and a wheel stream that restarts starts a new
//! drive (logged; distance and turning are counted again from there).
//!
//! The held-out error is the mean position error at the end of
//! [`ServeConfig::holdout_window_s`]-long 2W dead-reckoning windows, each
//! started from the GNSS/IMU reference pose: the situation of a GNSS outage.
//!
//! Every accepted estimate is written to [`ServeConfig::state_file`] (see
//! [`state`]); after a restart the service starts from it and publishes it at
//! once.
//!
//! The decisions are the library's ([`calibrator::live`]); this module is the
//! I/O loop around them: the bus, the worker thread, the state file.

mod state;

use calibrator::diagnose::DiagnoseConfig;
use calibrator::live::{
    attempt, gate, keep_window, sample_bytes, Candidate, Coverage, Verdict, DEFAULT_WINDOW_S,
};
use calibrator::{CalibrationConfig, CalibrationError};
use iceoryx2::prelude::CallbackProgression;
use interfaces::bus::{self, Bus, BusError, TopicPublisher};
use interfaces::collect::DriveBuilder;
use interfaces::drive::VehicleParams;
use interfaces::sensors::SensorSubscribers;
use interfaces::wire::CircumferenceEstimate;
use state::{load_state, save_state, Accepted, StateError};
use std::path::PathBuf;
use std::sync::mpsc;
use std::time::Duration;
use vehicle_model::two_wheel::TwoWheelParams;

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
    /// Length of the drive kept and calibrated on: the last this many
    /// seconds (of wheel time), s. Bounds the memory of the service; see
    /// [`DEFAULT_WINDOW_S`] for what the default costs.
    pub window_s: f64,
    /// Also diagnose each attempt's drive ([`calibrator::diagnose`]) and
    /// send the wheel-side terms of the effects it accepts with the estimate.
    pub diagnose: bool,
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
            window_s: DEFAULT_WINDOW_S,
            diagnose: false,
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
        if !(self.window_s.is_finite() && self.window_s >= 60.0) {
            return bad("window_s", self.window_s);
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
    #[error(transparent)]
    State(#[from] StateError),
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
    /// Wheel samples of the drive collected now: since the last time the
    /// wheel stream restarted (which starts a new drive), also those dropped
    /// since out of the window.
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
    let mut current = start_from_state(cfg, &mut publisher)?;

    let waitset = bus.waitset()?;
    let _guards = subs.wake_on_all(&waitset)?;
    // The tick delivers the history to late subscribers, collects finished
    // attempts and notices signals taken by the worker thread.
    let _tick = bus::tick_every(&waitset, Duration::from_millis(100))?;

    let mut drive = Collection::new(cfg);
    let mut running: Option<Running> = None;
    let mut ended = false;

    loop {
        let result = bus::wait_once(&waitset, None, |_| CallbackProgression::Continue)?;
        let outcome = subs.drain_into(&mut drive.builder)?;
        drive.take_resets(cfg);
        drive.count_new_wheels(cfg);
        publisher.update_connections()?;
        if outcome.end_of_stream() && !ended {
            ended = true;
            drive.report_end(cfg);
        }

        // A finished attempt?
        collect_finished(
            &mut running,
            cfg,
            &mut current,
            &mut publisher,
            &mut summary,
        )?;

        // Enough for a (new) attempt?
        if drive.enough(cfg)
            && running.is_none()
            && drive.coverage.distance_m - drive.last_attempt_distance >= cfg.recalibrate_distance_m
        {
            let params = current.map_or(nominal, |a| a.estimate.two_wheel());
            running = Some(drive.start_attempt(cfg, params, summary.attempts + 1)?);
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
    summary.wheel_samples = drive.wheel_samples;
    // What the collector refused (the resets were logged as they happened).
    let builder = &drive.builder;
    for warning in builder.warnings() {
        if !builder.reset_log().contains(&warning) {
            tracing::warn!("calibrator: {warning}");
        }
    }
    summary.lost = subs.lost();
    Ok(summary)
}

/// The estimate kept in the state file (if any), published at the start;
/// logs what the service starts from.
fn start_from_state(
    cfg: &ServeConfig,
    publisher: &mut TopicPublisher<CircumferenceEstimate>,
) -> Result<Option<Accepted>, ServeError> {
    let current: Option<Accepted> = match &cfg.state_file {
        Some(path) => load_state(path)?,
        None => None,
    };
    if let Some(a) = &current {
        tracing::info!(
            "calibrator: starting from the persisted estimate v{} (c_rl = {:.4} m, c_rr = {:.4} m, \
             held-out error {:.2} m); publishing it",
            a.version,
            a.estimate.circumference_m.rl,
            a.estimate.circumference_m.rr,
            a.estimate.quality_m
        );
        publisher.publish(a.to_wire())?;
    } else {
        tracing::info!(
            "calibrator: no accepted estimate yet; nominal c = {:.4} m on both rear wheels",
            cfg.vehicle.nominal_circumference_m
        );
    }
    Ok(current)
}

/// A finished attempt, if the running one has finished: counted, judged
/// and (when accepted) published; an attempt that ended without a result
/// is logged and forgotten.
fn collect_finished(
    running: &mut Option<Running>,
    cfg: &ServeConfig,
    current: &mut Option<Accepted>,
    publisher: &mut TopicPublisher<CircumferenceEstimate>,
    summary: &mut ServeSummary,
) -> Result<(), ServeError> {
    if let Some(run) = running {
        match run.rx.try_recv() {
            Ok(outcome) => {
                let number = run.number;
                *running = None;
                summary.attempts += 1;
                handle_attempt(number, outcome, cfg, current, publisher, summary)?;
            }
            Err(mpsc::TryRecvError::Empty) => {}
            Err(mpsc::TryRecvError::Disconnected) => {
                tracing::warn!("calibrator: attempt #{} ended without a result", run.number);
                *running = None;
            }
        }
    }
    Ok(())
}

/// The drive being collected, and what the loop has counted of it.
struct Collection {
    builder: DriveBuilder,
    coverage: Coverage,
    /// Time of the last wheel sample counted into `coverage`.
    seen_t: Option<f64>,
    /// The collector's resets seen so far.
    resets_seen: u64,
    wheel_samples: usize,
    /// The coverage's distance at the last attempt started, m.
    last_attempt_distance: f64,
    /// Whether "enough data" has been logged for this drive.
    announced_ready: bool,
}

impl Collection {
    /// Nothing collected yet.
    fn new(cfg: &ServeConfig) -> Collection {
        Collection {
            builder: DriveBuilder::new(cfg.vehicle.clone()),
            coverage: Coverage::new(&cfg.vehicle),
            seen_t: None,
            resets_seen: 0,
            wheel_samples: 0,
            last_attempt_distance: f64::NEG_INFINITY,
            announced_ready: false,
        }
    }

    /// When the collector reset (a new drive): log why and set what was
    /// counted before aside.
    fn take_resets(&mut self, cfg: &ServeConfig) {
        let builder = &self.builder;
        if builder.resets() > self.resets_seen {
            // A new drive: what was collected before is set aside.
            let new = (builder.resets() - self.resets_seen) as usize;
            let log = builder.reset_log();
            for line in &log[log.len().saturating_sub(new)..] {
                tracing::warn!("calibrator: {line}");
            }
            self.resets_seen = builder.resets();
            self.coverage = Coverage::new(&cfg.vehicle);
            self.seen_t = None;
            self.wheel_samples = 0;
            self.last_attempt_distance = f64::NEG_INFINITY;
            self.announced_ready = false;
        }
    }

    /// Count the wheel samples new since the last call into the coverage,
    /// then keep only the last `window_s` of the drive.
    fn count_new_wheels(&mut self, cfg: &ServeConfig) {
        let wheels = self.builder.wheels();
        let from = self
            .seen_t
            .map_or(0, |t| wheels.partition_point(|w| w.t_s <= t));
        for s in &wheels[from..] {
            self.coverage.add(s.t_s, s.rl, s.rr);
        }
        self.wheel_samples += wheels.len() - from;
        self.seen_t = wheels.last().map(|w| w.t_s).or(self.seen_t);
        if keep_window(&mut self.builder, cfg.window_s) > 0 {
            tracing::debug!(
                "calibrator: keeping the last {:.0} s of the drive ({:.1} MB of samples)",
                cfg.window_s,
                sample_bytes(self.builder.sample_counts()) as f64 / 1e6
            );
        }
    }

    /// Log the end of the sensor stream, and, when the drive never had
    /// enough for an attempt, which threshold it fell short of.
    fn report_end(&self, cfg: &ServeConfig) {
        let coverage = &self.coverage;
        let builder = &self.builder;
        tracing::info!(
            "calibrator: sensor stream ended after {:.0} m, {:.0} deg of turning",
            coverage.distance_m,
            coverage.turn_deg()
        );
        if !self.announced_ready {
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

    /// Whether the drive has enough distance, turning and GNSS fixes for an
    /// attempt; logs it the first time.
    fn enough(&mut self, cfg: &ServeConfig) -> bool {
        let coverage = &self.coverage;
        let enough = coverage.distance_m >= cfg.min_distance_m
            && coverage.turn_deg() >= cfg.min_turn_deg
            && self.builder.gnss_count() >= cfg.min_gnss_fixes;
        if enough && !self.announced_ready {
            self.announced_ready = true;
            tracing::info!(
                "calibrator: enough data: {:.0} m, {:.0} deg of turning, {} GNSS fixes",
                coverage.distance_m,
                coverage.turn_deg(),
                self.builder.gnss_count()
            );
        }
        enough
    }

    /// Start attempt `number` on a snapshot of the drive, from `params`, on
    /// a worker thread.
    fn start_attempt(
        &mut self,
        cfg: &ServeConfig,
        params: TwoWheelParams,
        number: usize,
    ) -> Result<Running, ServeError> {
        self.last_attempt_distance = self.coverage.distance_m;
        let drive = self.builder.snapshot();
        let span_s = drive.wheel_duration_s();
        let worker_cfg = cfg.clone();
        let (tx, rx) = mpsc::channel();
        tracing::info!(
            "calibrator: attempt #{number} on {span_s:.0} s of drive ({:.0} m), {:.0} % held out",
            self.coverage.distance_m,
            cfg.holdout_fraction * 100.0
        );
        std::thread::Builder::new()
            .name(format!("calibration-{number}"))
            .spawn(move || {
                let diagnose = DiagnoseConfig::default();
                let _ = tx.send(attempt(
                    &drive,
                    &params,
                    &worker_cfg.calibration,
                    worker_cfg.holdout_fraction,
                    worker_cfg.holdout_window_s,
                    worker_cfg.diagnose.then_some(&diagnose),
                ));
            })
            .map_err(|e| StateError {
                path: PathBuf::from("<worker thread>"),
                detail: e.to_string(),
            })?;
        Ok(Running { rx, number, span_s })
    }
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
    match &cand.diagnosis {
        Some(Ok(found)) if found.is_empty() => {
            tracing::info!("calibrator: attempt #{number}: diagnosis: no effect beyond the noise");
        }
        Some(Ok(found)) => tracing::info!(
            "calibrator: attempt #{number}: diagnosis found {} (their terms go with the estimate)",
            found.iter().map(|f| f.id()).collect::<Vec<_>>().join(", ")
        ),
        Some(Err(why)) => tracing::warn!(
            "calibrator: attempt #{number}: no diagnosis, the estimate carries no effect terms: {why}"
        ),
        None => {}
    }
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
                estimate: *e,
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
                accepted.estimate.circumference_m.rl,
                accepted.estimate.circumference_m.rr,
                accepted.estimate.track_width_m,
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
