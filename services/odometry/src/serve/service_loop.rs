//! The service loop: open the inputs and the pose publisher, wait on the
//! WaitSet, and per wakeup take the samples to their poses, then the work
//! off that path (notifications, estimates, the kept pose, the stream's end,
//! stale inputs); at the end, the summary.

use super::clocks::{describe_clocks, ClockWindow};
use super::estimates::{announce_switch, drop_contradicted};
use super::inputs::Inputs;
use super::kept_pose::{load_kept_pose, resume_if_trusted, KeptPose};
use super::log::{log_mode_change, log_status};
use super::pose_state::SavedPose;
use super::stream_end::StreamEnd;
use super::summary::{log_summary, report_dropped};
use super::{
    ServeConfig, ServeError, ServeSummary, Shutdown, RESTART_BACKSTEP_S, SIDE_EVENTS_EVERY,
};
use iceoryx2::prelude::CallbackProgression;
use interfaces::bus::{self, Bus, TopicPublisher};
use interfaces::latency_trace::{wall_clock_ns, write_latency_trace};
use interfaces::wire::{Header, Pose, PoseMode};
use odometry::cadence::WheelCadence;
use odometry::fusion::{FusedPose, Fusion, ProcessError};
use odometry::inputs::{Input, Sequencer};
use odometry::restart::WheelMark;
use odometry::rewind::RewindingFusion;
use std::time::{Duration, Instant};
use vehicle_model::estimate::Estimate;
use vehicle_model::estimate_gate::EstimateGate;

/// The service loop on an open bus; returns when stopped (signal, `shutdown`,
/// or the end of the wheel stream with `exit_on_end`).
pub(crate) fn serve(
    bus: &Bus,
    config: &ServeConfig,
    shutdown: &Shutdown,
) -> Result<ServeSummary, ServeError> {
    let filter = initial_filter(config)?;
    // Judged at the first wheel sample, which says whether the car moved.
    let kept_to_judge = config.pose_state.as_deref().and_then(load_kept_pose);
    let inputs = open_inputs(bus, config)?;
    let poses: TopicPublisher<Pose> = bus.publisher()?;
    log_start(config, &filter, &poses);
    let mut serving = Serving::new(config, filter, poses, kept_to_judge);

    let waitset = bus.waitset()?;
    let _g_wheels = bus::wake_on(&waitset, "attach wheels", inputs.wheels.listener())?;
    let g_estimate = bus::wake_on(&waitset, "attach estimate", inputs.estimate.listener())?;
    // The tick notices stale inputs and stop requests; it does no work otherwise.
    let tick = config
        .stale_after
        .div_f64(4.0)
        .min(Duration::from_millis(100));
    let _g_tick = bus::tick_every(&waitset, tick)?;

    loop {
        let mut estimate_event = false;
        let result = bus::wait_once(&waitset, serving.timeout(), |id| {
            estimate_event |= id.has_event_from(&g_estimate);
            CallbackProgression::Continue
        })?;
        let wheels_ended = serving.wakeup(&inputs, estimate_event)?;
        if bus::stop_requested_by(result) || shutdown.is_requested() {
            tracing::info!("odometry: stop requested");
            break;
        }
        if config.exit_on_end && wheels_ended {
            // Take what is still buffered, then stop.
            tracing::info!("odometry: the wheel stream ended");
            break;
        }
    }
    serving.finish(&inputs)
}

/// The filter the service starts with: the initial estimate's, else the
/// vehicle's nominal values, behind the log that lets it take late samples
/// in order (`fusion()` to read it).
fn initial_filter(config: &ServeConfig) -> Result<RewindingFusion, ServeError> {
    let fusion = match config.initial {
        Some(e) => {
            let mut f = Fusion::new(e.params, 0, config.fusion);
            f.set_effects(e.effects.into());
            f
        }
        None => Fusion::nominal(&config.vehicle, config.fusion),
    };
    fusion.params().validate("vehicle parameters")?;
    Ok(RewindingFusion::new(fusion, config.rewind))
}

/// The subscribers, with the gate the estimates must pass (the initial one
/// first) and the initial estimate's sensor clocks.
fn open_inputs(bus: &Bus, config: &ServeConfig) -> Result<Inputs, ServeError> {
    let mut gate = EstimateGate::new(&config.vehicle);
    if let Some(initial) = &config.initial {
        gate.check(0, None, initial)
            .map_err(|e| ServeError::ImplausibleEstimate(format!("the initial estimate: {e}")))?;
    }
    let inputs = Inputs::open(bus, gate)?;
    if let Some(initial) = &config.initial {
        inputs.clocks.set(initial.clocks);
        if !initial.clocks.is_zero() {
            tracing::info!(
                "odometry: sensor clocks from the initial estimate: {}",
                describe_clocks(&initial.clocks)
            );
        }
    }
    Ok(inputs)
}

/// What the service starts with, in the log: the pose topic, the heading
/// source, the parameters and where the GNSS antenna is taken to be.
fn log_start(config: &ServeConfig, filter: &RewindingFusion, poses: &TopicPublisher<Pose>) {
    tracing::info!(
        "odometry: serving poses on {} ({} heading, {} parameters: {})",
        poses.service_name(),
        config.fusion.odometer.heading,
        if config.initial.is_some() {
            "initial estimate"
        } else {
            "nominal"
        },
        filter.fusion().params(),
    );
    let [ax, ay] = filter.fusion().lever_arm();
    let antenna_source = match (
        config.fusion.lever_arm_from_estimates,
        config.initial.as_ref().and_then(Estimate::fusable_antenna),
    ) {
        (false, _) => "vehicle.toml [gnss], measured: estimates do not change it",
        (true, Some(_)) => "calibrated, from the initial estimate",
        (true, None) => "not known: the pose is the antenna's track until an estimate brings it",
    };
    tracing::info!(
        "odometry: GNSS antenna at ({ax:+.3}, {ay:+.3}) m from the rear axle ({antenna_source})"
    );
}

/// The loop's state between wakeups.
struct Serving<'a> {
    config: &'a ServeConfig,
    /// The filter, behind the log that lets it take late samples in order.
    filter: RewindingFusion,
    poses: TopicPublisher<Pose>,
    pose_stream_ended: bool,
    /// (pose time, wall clock at the wakeup that brought its wheel sample,
    /// wall clock when handed to the publisher), all ns: only with
    /// --latency-trace.
    trace: Vec<(i64, i128, i128)>,
    summary: ServeSummary,
    sequencer: Sequencer,
    /// The inputs a wakeup releases, in order (kept for its capacity).
    batch: Vec<Input>,
    dropped_reported: (u64, u64),
    /// The rewind window the clocks need, last set for these clocks.
    window: ClockWindow,
    last_wheel_wall: Option<Instant>,
    last_side_events: Instant,
    last_wheel_t: Option<f64>,
    stale: bool,
    mode: PoseMode,
    bias_standstills: u64,
    next_status_t: Option<f64>,
    /// A wheel sample is known to be waiting: the next wait returns at once.
    wheel_sample_waiting: bool,
    wheel_stream: StreamEnd,
    /// The pose kept by an earlier run, judged at the first wheel sample.
    kept_to_judge: Option<SavedPose>,
    /// With --pose-state: the last pose with a position, and when it is next written.
    kept: KeptPose,
    /// Newest time seen per input stream (wheels, IMU, GNSS, heading).
    latest_t: [Option<f64>; 4],
    cadence: WheelCadence,
}

const STREAM_NAMES: [&str; 4] = ["wheels", "imu", "gnss", "heading"];

/// Index of an input's stream in [`STREAM_NAMES`] (estimates have none).
fn stream_index(input: &Input) -> Option<usize> {
    match input {
        Input::Wheels { .. } => Some(0),
        Input::Imu { .. } => Some(1),
        Input::Gnss { .. } => Some(2),
        Input::Heading { .. } => Some(3),
        Input::Estimate { .. } => None,
    }
}

fn to_wire(pose: &FusedPose) -> Pose {
    Pose {
        header: Header::from_seconds(pose.t_s, 0),
        x_m: pose.pose.x,
        y_m: pose.pose.y,
        yaw_rad: pose.pose.yaw,
        covariance: pose.covariance,
        estimate_version: pose.estimate_version,
        mode: pose.mode as u8,
        _pad: [0; 7],
    }
}

impl<'a> Serving<'a> {
    fn new(
        config: &'a ServeConfig,
        filter: RewindingFusion,
        poses: TopicPublisher<Pose>,
        kept_to_judge: Option<SavedPose>,
    ) -> Serving<'a> {
        Serving {
            config,
            filter,
            poses,
            pose_stream_ended: false,
            trace: Vec::new(),
            summary: ServeSummary::default(),
            sequencer: Sequencer::new(RESTART_BACKSTEP_S),
            batch: Vec::with_capacity(4096),
            dropped_reported: (0, 0),
            window: ClockWindow::default(),
            last_wheel_wall: None,
            last_side_events: Instant::now(),
            last_wheel_t: None,
            stale: false,
            mode: PoseMode::NoFix,
            bias_standstills: 0,
            next_status_t: None,
            wheel_sample_waiting: false,
            wheel_stream: StreamEnd::default(),
            kept_to_judge,
            kept: KeptPose::default(),
            latest_t: [None; 4],
            cadence: WheelCadence::new(config.early_wakeup),
        }
    }

    /// How long the next wait may block: not at all when a wheel sample is
    /// waiting, else until the early wakeup before the next one is due.
    fn timeout(&self) -> Option<Duration> {
        if self.wheel_sample_waiting {
            Some(Duration::ZERO)
        } else {
            self.cadence.wait_for_early_wakeup(Instant::now())
        }
    }

    /// One wakeup: the samples to their poses, then the work off that path.
    /// Returns whether the wheel stream has ended.
    fn wakeup(&mut self, inputs: &Inputs, estimate_event: bool) -> Result<bool, ServeError> {
        let woke_wall_ns = if self.config.latency_trace.is_some() {
            wall_clock_ns()
        } else {
            0
        };
        self.batch.clear();
        self.window.fit(
            &mut self.filter,
            inputs.clocks.get(),
            self.config.rewind.window_s,
            self.last_wheel_t,
        );
        inputs.drain(&mut self.sequencer)?;
        self.sequencer.release(&mut self.batch);
        report_dropped(
            &self.sequencer,
            &mut self.dropped_reported,
            &mut self.summary,
        );
        let batch = std::mem::take(&mut self.batch);
        for input in &batch {
            self.take(input, inputs, woke_wall_ns)?;
        }
        let got_wheels = batch.iter().any(|i| matches!(i, Input::Wheels { .. }));
        self.batch = batch;
        self.early_pass(got_wheels)?;
        self.housekeeping(inputs, estimate_event)?;
        let wheels_ended = self.wheel_stream_end(inputs, got_wheels)?;
        self.check_stale(wheels_ended)?;
        Ok(wheels_ended)
    }

    /// One input through the filter, and its pose out.
    fn take(
        &mut self,
        input: &Input,
        inputs: &Inputs,
        woke_wall_ns: i128,
    ) -> Result<(), ServeError> {
        if let Input::Estimate {
            version, estimate, ..
        } = input
        {
            if !announce_switch(&self.filter, *version, estimate) {
                return Ok(()); // the same estimate again (history on a reconnect)
            }
            self.summary.estimate_switches += 1;
        }
        self.note_stream_time(input);
        if let Input::Wheels {
            t_s,
            rl_rev,
            rr_rev,
        } = *input
        {
            self.wheel_sample(WheelMark {
                t_s,
                rl_rev,
                rr_rev,
            });
        }
        match self.filter.process(input) {
            Ok(Some(pose)) => self.publish(&pose, inputs, woke_wall_ns)?,
            Ok(None) => {}
            Err(ProcessError::Input(e)) => {
                self.summary.skipped += 1;
                // The first ten, then every thousandth: a broken stream must not flood the log.
                if self.summary.skipped <= 10 || self.summary.skipped.is_multiple_of(1000) {
                    tracing::warn!("odometry: {e} ({} skipped so far)", self.summary.skipped);
                }
            }
            Err(e @ ProcessError::Numerical(_)) => {
                self.summary.skipped += 1;
                tracing::error!("odometry: {e}");
            }
        }
        if let Some(contradiction) = self.filter.take_contradiction() {
            drop_contradicted(
                &mut self.filter,
                inputs,
                &self.config.vehicle,
                &contradiction,
            );
            self.summary.estimates_dropped += 1;
        }
        Ok(())
    }

    /// A stream's time going back by more than [`RESTART_BACKSTEP_S`]: its
    /// publisher restarted, the filter starts over.
    fn note_stream_time(&mut self, input: &Input) {
        let Some(k) = stream_index(input) else {
            return;
        };
        let t = input.t_s();
        if let Some(previous) = self.latest_t[k].filter(|p| t < p - RESTART_BACKSTEP_S) {
            tracing::warn!(
                "odometry: {} time went back from {previous:.2} s to {t:.2} s: a publisher \
                 restarted; the filter starts over (NoFix until GNSS)",
                STREAM_NAMES[k]
            );
            self.filter.fusion_mut().reset();
            self.latest_t = [None; 4];
        }
        self.latest_t[k] = Some(self.latest_t[k].map_or(t, |l| l.max(t)));
    }

    /// Before a wheel sample is processed: the kept pose judged (the first
    /// one), the wheel counts noted for the pose to keep, stale inputs over.
    fn wheel_sample(&mut self, mark: WheelMark) {
        if let Some(saved) = self.kept_to_judge.take() {
            resume_if_trusted(self.filter.fusion_mut(), &saved, &mark);
        }
        if self.config.pose_state.is_some() {
            self.kept
                .wheels_at(mark, &self.filter.fusion().params().two_wheel);
        }
        if self.stale {
            self.stale = false;
            tracing::info!(
                "odometry: wheel samples again at t = {:.2} s; starting over (NoFix until GNSS)",
                mark.t_s
            );
        }
        self.last_wheel_wall = Some(Instant::now());
        self.summary.wheel_samples += 1;
    }

    /// A pose out, then (off its path) what it changes: the pose to keep,
    /// the mode and gyro bias log lines, the status line.
    fn publish(
        &mut self,
        pose: &FusedPose,
        inputs: &Inputs,
        woke_wall_ns: i128,
    ) -> Result<(), ServeError> {
        let wire = to_wire(pose);
        if self.config.latency_trace.is_some() {
            self.trace
                .push((wire.header.t_ns, woke_wall_ns, wall_clock_ns()));
        }
        self.poses.publish(wire)?;
        self.summary.poses += 1;
        if self.config.pose_state.is_some() {
            self.kept.update(pose, self.filter.fusion().lever_arm());
        }
        // Logged after the pose is out: a log line is not worth its latency.
        if pose.mode != self.mode {
            log_mode_change(self.mode, pose);
            self.mode = pose.mode;
        }
        let standstills = self.filter.fusion().stats().gyro_bias_standstills;
        if standstills != self.bias_standstills {
            self.bias_standstills = standstills;
            tracing::info!(
                "odometry: t = {:.2} s: gyro bias measured at standstill; in use now {:.3e} rad/s",
                pose.t_s,
                self.filter.fusion().gyro_bias()
            );
        }
        self.last_wheel_t = Some(pose.t_s);
        if self.config.status_every_s > 0.0 {
            let due = self.next_status_t.get_or_insert(pose.t_s);
            if pose.t_s >= *due {
                *due = pose.t_s + self.config.status_every_s;
                log_status(pose, self.filter.fusion(), inputs);
            }
        }
        Ok(())
    }

    /// The early pass (1-2 ms before the sample is due, as a rule woken
    /// for it): this pass found no sample and warms what the sample's
    /// pass will touch: the receives above, then the filter's step on a
    /// copy, the pose's conversion, a loan from the pose publisher.
    fn early_pass(&mut self, got_wheels: bool) -> Result<(), ServeError> {
        if !got_wheels && self.cadence.take_early_pass(Instant::now()) {
            self.summary.early_wakeups += 1;
            if let Some(pose) = self.filter.rehearse() {
                std::hint::black_box(to_wire(&pose));
            }
            self.poses.warm_up()?;
        }
        Ok(())
    }

    /// Off the path from a wheel sample to its pose: the side topics'
    /// notifications and the estimates, then the kept pose when due.
    fn housekeeping(&mut self, inputs: &Inputs, estimate_event: bool) -> Result<(), ServeError> {
        // The estimate topic is also read with the side events: a new
        // subscriber gets the latest estimate (history) without a
        // notification.
        let side_events = self.last_side_events.elapsed() >= SIDE_EVENTS_EVERY;
        if side_events {
            self.last_side_events = Instant::now();
        }
        self.summary.skipped += inputs.housekeeping(
            &mut self.sequencer,
            self.config.bus_estimates,
            estimate_event || side_events,
            side_events,
        )?;
        if let Some(path) = &self.config.pose_state {
            self.kept.write_if_due(path);
        }
        Ok(())
    }

    /// The wheel topic's notifications (taken here, not before receiving:
    /// they cost a few syscalls on the path to a pose), and whether the
    /// wheel stream ended; the pose stream ends with it.
    fn wheel_stream_end(&mut self, inputs: &Inputs, got_wheels: bool) -> Result<bool, ServeError> {
        let (end_taken, waiting) = inputs.wheel_notifications()?;
        self.wheel_sample_waiting = waiting;
        if let (true, Some(seen)) = (got_wheels, self.last_wheel_wall) {
            self.cadence.wheels_at(seen);
        }
        self.wheel_stream
            .after_wakeup(got_wheels, end_taken, waiting);
        let wheels_ended = self.wheel_stream.ended();
        // No wheel sample, no pose: the pose stream ends with the wheels'
        // (once per run of the wheel stream; a new run starts it again).
        if wheels_ended && !self.pose_stream_ended {
            self.poses.end_of_stream()?;
            self.pose_stream_ended = true;
        } else if !wheels_ended {
            self.pose_stream_ended = false;
        }
        Ok(wheels_ended)
    }

    /// Stale inputs: the wheels stopped coming. Said once, the filter
    /// forgets its pose, and one `NoFix` pose tells the subscribers.
    fn check_stale(&mut self, wheels_ended: bool) -> Result<(), ServeError> {
        let (Some(seen), false) = (self.last_wheel_wall, self.stale) else {
            return Ok(());
        };
        let quiet = seen.elapsed();
        if quiet < self.config.stale_after || wheels_ended {
            return Ok(());
        }
        self.stale = true;
        self.summary.stale_events += 1;
        tracing::warn!(
            "odometry: inputs stale: no wheel sample for {:.1} s (last at t = {:.2} s); \
             the pose is withheld until wheel samples come again",
            quiet.as_secs_f64(),
            self.last_wheel_t.unwrap_or(f64::NAN)
        );
        self.filter.fusion_mut().mark_stale();
        self.mode = PoseMode::NoFix;
        if let Some(path) = &self.config.pose_state {
            self.kept.write(path, true);
        }
        if let Some(t) = self.last_wheel_t {
            let marker = FusedPose {
                t_s: t,
                pose: Default::default(),
                covariance: [0.0; 9],
                mode: PoseMode::NoFix,
                estimate_version: self.filter.fusion().estimate_version(),
            };
            self.poses.publish(to_wire(&marker))?;
            self.summary.poses += 1;
        }
        Ok(())
    }

    /// Stopping: the pose stream's end, the latency trace and the kept pose
    /// written, the summary counted and logged.
    fn finish(mut self, inputs: &Inputs) -> Result<ServeSummary, ServeError> {
        if !self.pose_stream_ended {
            // Stopping: no pose follows. Subscribers learn it without waiting
            // for the publisher to be found gone.
            self.poses.end_of_stream()?;
        }
        let mut summary = self.summary;
        summary.lost = inputs.lost();
        summary.gnss_epochs = inputs.gnss_epochs.borrow().counts();
        summary.estimate_version = self.filter.fusion().estimate_version();
        if let Some(path) = &self.config.latency_trace {
            write_latency_trace(path, &self.trace)?;
        }
        if let Some(path) = &self.config.pose_state {
            self.kept.write(path, true);
        }
        summary.fusion = self.filter.fusion().stats();
        summary.rewind = self.filter.stats();
        summary.pose_reader_stalls = self.poses.stalls();
        log_summary(
            &summary,
            self.filter.fusion().gyro_bias(),
            self.config.rewind.window_s,
        );
        Ok(summary)
    }
}
