//! Publishing a drive over iceoryx2: every stream on its service, with the
//! recorded timestamps, in time order.
//!
//! [`to_wire`] turns a [`Drive`] into wire samples (pure); [`replay`] publishes
//! them paced at a multiple of real time, or as fast as the subscribers take
//! them ([`Pacing::Max`]: the sensor topics never overflow, the publisher waits
//! for the slowest subscriber, so nothing is lost).
//!
//! Order: by time; at equal times IMU, GNSS, heading, then wheels, so a wheel
//! sample comes after every other sample of its instant (the order the
//! odometry processes its inputs in). With a [`DeliveryLatency`], a stream is
//! published that much after its time stamps, as a sensor whose driver
//! delivers late (a GNSS receiver: 50-200 ms): by delivery time, the same ties.

use interfaces::bus::{self, Bus, BusError, TopicPublisher};
use interfaces::drive::{Drive, WheelConversionError};
use interfaces::wire::{GnssFix, Header, Heading, Imu, WheelRotations};
use std::time::{Duration, Instant};

/// How fast to publish.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pacing {
    /// `factor` times real time (1.0 = as recorded).
    Speed(f64),
    /// As fast as the subscribers take the samples, losing none.
    Max,
}

/// Options of [`replay`].
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayOptions {
    /// Pace.
    pub pacing: Pacing,
    /// Before the first sample, wait until every topic the drive has counts at
    /// least this many subscribers (so that none misses the start).
    pub wait_subscribers: usize,
    /// Give up waiting for subscribers after this long (`None`: wait forever,
    /// until Ctrl-C).
    pub wait_timeout: Option<Duration>,
    /// After announcing the publishers, wait this long before the first
    /// sample, so that every subscriber attaches (see `interfaces::bus`).
    pub settle: Duration,
    /// After the last sample, keep the publishers alive this long so that
    /// slow subscribers can still take what is in their buffers.
    pub linger: Duration,
    /// Log progress every this many seconds of drive time (0 = never).
    pub progress_every_s: f64,
    /// Publish each stream this long after its time stamps.
    pub latency: DeliveryLatency,
}

/// How long after its time stamp each stream's samples are delivered, s
/// (`--deliver-late gnss=0.15,imu=0.01`). The time stamps stay as recorded.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DeliveryLatency {
    /// IMU samples.
    pub imu_s: f64,
    /// GNSS fixes.
    pub gnss_s: f64,
    /// Headings.
    pub heading_s: f64,
    /// Wheel samples.
    pub wheels_s: f64,
}

impl DeliveryLatency {
    /// Parse `STREAM=SECONDS[,STREAM=SECONDS...]` (streams imu, gnss,
    /// heading, wheels; seconds zero or more).
    pub fn parse(text: &str) -> Result<DeliveryLatency, String> {
        let mut out = DeliveryLatency::default();
        for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (name, value) = part
                .split_once('=')
                .ok_or_else(|| format!("`{part}`: expected STREAM=SECONDS"))?;
            let seconds: f64 = value
                .trim()
                .parse()
                .map_err(|_| format!("`{part}`: `{value}` is not a number of seconds"))?;
            if !(seconds.is_finite() && seconds >= 0.0) {
                return Err(format!(
                    "`{part}`: the latency must be zero or more seconds"
                ));
            }
            let slot = match name.trim() {
                "imu" => &mut out.imu_s,
                "gnss" => &mut out.gnss_s,
                "heading" => &mut out.heading_s,
                "wheels" => &mut out.wheels_s,
                other => {
                    return Err(format!(
                        "`{part}`: unknown stream `{other}` (imu, gnss, heading, wheels)"
                    ))
                }
            };
            *slot = seconds;
        }
        Ok(out)
    }

    /// The latency of `stream`, ns.
    pub fn of_ns(&self, stream: Stream) -> i64 {
        let s = match stream {
            Stream::Imu => self.imu_s,
            Stream::Gnss => self.gnss_s,
            Stream::Heading => self.heading_s,
            Stream::Wheels => self.wheels_s,
        };
        interfaces::wire::seconds_to_ns(s)
    }
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            pacing: Pacing::Speed(1.0),
            wait_subscribers: 0,
            wait_timeout: None,
            settle: Duration::from_millis(300),
            linger: Duration::from_secs(1),
            progress_every_s: 30.0,
            latency: DeliveryLatency::default(),
        }
    }
}

impl ReplayOptions {
    /// The defaults for `pacing`; with [`Pacing::Max`] the replay waits for
    /// one subscriber per topic (a flood into no subscriber is lost).
    pub fn for_pacing(pacing: Pacing) -> ReplayOptions {
        ReplayOptions {
            pacing,
            wait_subscribers: usize::from(pacing == Pacing::Max),
            ..ReplayOptions::default()
        }
    }
}

/// Why a replay failed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The wheel values cannot be turned into revolutions.
    #[error("wheels: {0}")]
    Wheels(#[from] WheelConversionError),
    /// The drive has no wheel sample to publish.
    #[error("the drive has no wheel samples")]
    NoWheels,
    /// A speed factor that is not a positive number.
    #[error("--speed {0} is not a positive number")]
    BadSpeed(f64),
    /// An iceoryx2 operation failed.
    #[error(transparent)]
    Bus(#[from] BusError),
}

/// A drive as wire samples, one vector per topic (sequence numbers are set
/// when published).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WireDrive {
    /// Rear (and front) wheels as cumulative revolutions.
    pub wheels: Vec<WheelRotations>,
    /// GNSS fixes (all with `fix = 1`: a drive's outage is a stretch without rows).
    pub gnss: Vec<GnssFix>,
    /// IMU samples.
    pub imu: Vec<Imu>,
    /// Absolute headings.
    pub heading: Vec<Heading>,
    /// What could not be put on the wire, and why.
    pub warnings: Vec<String>,
}

/// Which topic a merged sample belongs to, in the order of equal-time ties.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Stream {
    /// [`Imu`].
    Imu,
    /// [`GnssFix`].
    Gnss,
    /// [`Heading`].
    Heading,
    /// [`WheelRotations`].
    Wheels,
}

impl WireDrive {
    /// Every sample as `(stream, index)` in time order, ties broken IMU,
    /// GNSS, heading, wheels: the publishing order without latencies.
    pub fn merged(&self) -> Vec<(Stream, usize)> {
        self.delivery_order(&DeliveryLatency::default())
    }

    /// Time stamp of sample `i` of `stream`, ns.
    pub fn time_ns(&self, stream: Stream, i: usize) -> i64 {
        match stream {
            Stream::Wheels => self.wheels[i].header.t_ns,
            Stream::Gnss => self.gnss[i].header.t_ns,
            Stream::Imu => self.imu[i].header.t_ns,
            Stream::Heading => self.heading[i].header.t_ns,
        }
    }

    /// Every sample as `(stream, index)` in publishing order: by time plus
    /// its stream's `latency`, ties broken IMU, GNSS, heading, wheels.
    pub fn delivery_order(&self, latency: &DeliveryLatency) -> Vec<(Stream, usize)> {
        // Delivery times per stream, in the order of equal-time ties.
        let delivered = |stream: Stream, len: usize| -> (Stream, Vec<i64>) {
            let late = latency.of_ns(stream);
            let times = (0..len).map(|i| self.time_ns(stream, i) + late).collect();
            (stream, times)
        };
        let streams: [(Stream, Vec<i64>); 4] = [
            delivered(Stream::Imu, self.imu.len()),
            delivered(Stream::Gnss, self.gnss.len()),
            delivered(Stream::Heading, self.heading.len()),
            delivered(Stream::Wheels, self.wheels.len()),
        ];
        let total = streams.iter().map(|(_, t)| t.len()).sum();
        let mut out = Vec::with_capacity(total);
        let mut cursor = [0usize; 4];
        loop {
            let mut best: Option<(i64, usize)> = None;
            for (k, (_, times)) in streams.iter().enumerate() {
                if let Some(&t) = times.get(cursor[k]) {
                    // Strict `<` keeps the earlier stream (the tie order) on ties.
                    if best.is_none_or(|(bt, _)| t < bt) {
                        best = Some((t, k));
                    }
                }
            }
            let Some((_, k)) = best else { break };
            out.push((streams[k].0, cursor[k]));
            cursor[k] += 1;
        }
        out
    }

    /// Time of the first and last sample of any stream, ns.
    pub fn time_span_ns(&self) -> Option<(i64, i64)> {
        let firsts = [
            self.wheels.first().map(|s| s.header.t_ns),
            self.gnss.first().map(|s| s.header.t_ns),
            self.imu.first().map(|s| s.header.t_ns),
            self.heading.first().map(|s| s.header.t_ns),
        ];
        let lasts = [
            self.wheels.last().map(|s| s.header.t_ns),
            self.gnss.last().map(|s| s.header.t_ns),
            self.imu.last().map(|s| s.header.t_ns),
            self.heading.last().map(|s| s.header.t_ns),
        ];
        Some((
            firsts.into_iter().flatten().min()?,
            lasts.into_iter().flatten().max()?,
        ))
    }
}

/// Convert a drive into wire samples. Values that the wire types cannot carry
/// are listed in [`WireDrive::warnings`] (never dropped silently).
pub fn to_wire(drive: &Drive) -> Result<WireDrive, ReplayError> {
    let mut out = WireDrive::default();
    let revs = drive.wheel_revolutions()?;
    if revs.is_empty() {
        return Err(ReplayError::NoWheels);
    }
    let mut skipped_wheels = 0usize;
    let mut partial_front = 0usize;
    for r in &revs {
        if !(r.rl.is_finite() && r.rr.is_finite()) {
            skipped_wheels += 1;
            continue;
        }
        let (front, fl, fr) = match (r.fl, r.fr) {
            (Some(fl), Some(fr)) if fl.is_finite() && fr.is_finite() => {
                (WheelRotations::FRONT_VALID, fl, fr)
            }
            (None, None) => (0, 0.0, 0.0),
            _ => {
                partial_front += 1;
                (0, 0.0, 0.0)
            }
        };
        out.wheels.push(WheelRotations {
            header: Header::from_seconds(r.t_s, 0),
            rl_rev: r.rl,
            rr_rev: r.rr,
            fl_rev: fl,
            fr_rev: fr,
            valid: front,
            _pad: 0,
        });
    }
    if skipped_wheels > 0 {
        out.warnings.push(format!(
            "wheels.csv: {skipped_wheels} rows without a finite rear-wheel value were not published"
        ));
    }
    if partial_front > 0 {
        out.warnings.push(format!(
            "wheels.csv: {partial_front} rows with only one front wheel: their front values were not \
             published (the wire carries both front wheels or none)"
        ));
    }
    if let Some(gnss) = &drive.gnss {
        out.gnss = gnss
            .iter()
            .map(|g| GnssFix {
                header: Header::from_seconds(g.t_s, 0),
                x_m: g.x_m,
                y_m: g.y_m,
                sigma_m: g.sigma_m.unwrap_or(0.0),
                fix: 1,
                _pad: [0; 7],
            })
            .collect();
    }
    if let Some(imu) = &drive.imu {
        let mut partial_accel = 0usize;
        let mut partial_rates = 0usize;
        for s in imu {
            let mut m = Imu {
                header: Header::from_seconds(s.t_s, 0),
                gz_rad_s: s.gz_rad_s,
                ..Imu::default()
            };
            match (s.ax_m_s2, s.ay_m_s2, s.az_m_s2) {
                (Some(ax), Some(ay), Some(az)) => {
                    m.ax_m_s2 = ax;
                    m.ay_m_s2 = ay;
                    m.az_m_s2 = az;
                    m.valid |= Imu::ACCEL_VALID;
                }
                (None, None, None) => {}
                _ => partial_accel += 1,
            }
            match (s.gx_rad_s, s.gy_rad_s) {
                (Some(gx), Some(gy)) => {
                    m.gx_rad_s = gx;
                    m.gy_rad_s = gy;
                    m.valid |= Imu::ROLL_PITCH_RATE_VALID;
                }
                (None, None) => {}
                _ => partial_rates += 1,
            }
            out.imu.push(m);
        }
        if partial_accel > 0 {
            out.warnings.push(format!(
                "imu.csv: {partial_accel} rows with some but not all of ax, ay, az: their \
                 accelerations were not published (the wire carries all three or none)"
            ));
        }
        if partial_rates > 0 {
            out.warnings.push(format!(
                "imu.csv: {partial_rates} rows have only one of gx_rad_s, gy_rad_s (the \
                 simulator, for one, writes the pitch rate only): the wire Imu flags roll and \
                 pitch rate together (ROLL_PITCH_RATE_VALID), so neither is published for these \
                 rows (their yaw rate and accelerations are); a recording of the replay has no \
                 gx/gy"
            ));
        }
    }
    if let Some(heading) = &drive.heading {
        out.heading = heading
            .iter()
            .map(|h| Heading {
                header: Header::from_seconds(h.t_s, 0),
                yaw_rad: h.yaw_rad,
                sigma_rad: h.sigma_rad.unwrap_or(0.0),
            })
            .collect();
    }
    if drive.truth.is_some() {
        out.warnings.push(
            "truth.csv is not published (scoring only: no estimator may read it)".to_string(),
        );
    }
    Ok(out)
}

/// What a replay published.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReplayStats {
    /// Wheel samples published.
    pub wheels: u64,
    /// GNSS fixes published.
    pub gnss: u64,
    /// IMU samples published.
    pub imu: u64,
    /// Headings published.
    pub heading: u64,
    /// Wall-clock seconds from the first to the last sample.
    pub wall_s: f64,
    /// Drive seconds from the first to the last sample.
    pub drive_s: f64,
    /// Stopped early by Ctrl-C / SIGTERM.
    pub interrupted: bool,
    /// Per topic with a stalled reader: the topic's service name, the waits
    /// that ran out the whole budget and the samples then dropped at once
    /// for that reader (the others lost nothing).
    pub stalled: Vec<(&'static str, u64, u64)>,
}

impl ReplayStats {
    /// Samples published, all topics.
    pub fn total(&self) -> u64 {
        self.wheels + self.gnss + self.imu + self.heading
    }
}

/// GNSS gaps longer than this are announced in the log as outages.
const OUTAGE_LOG_S: f64 = 2.0;

/// Publish `wire` on `bus` (see the module doc). Returns early, with
/// `interrupted` set, on Ctrl-C or SIGTERM.
pub fn replay(
    bus: &Bus,
    wire: &WireDrive,
    opts: &ReplayOptions,
) -> Result<ReplayStats, ReplayError> {
    if let Pacing::Speed(f) = opts.pacing {
        if !(f.is_finite() && f > 0.0) {
            return Err(ReplayError::BadSpeed(f));
        }
    }
    if wire.wheels.is_empty() {
        return Err(ReplayError::NoWheels);
    }
    let mut publishers = Publishers::open(bus, wire, opts.pacing)?;
    if opts.wait_subscribers > 0 {
        publishers.wait_for(opts.wait_subscribers, opts.wait_timeout)?;
    }
    publishers.announce()?;
    if !bus::sleep_unless_shutdown(opts.settle) {
        return Ok(ReplayStats {
            interrupted: true,
            ..ReplayStats::default()
        });
    }
    let (t0, t_end) = wire.time_span_ns().ok_or(ReplayError::NoWheels)?;
    let mut stats = ReplayStats {
        drive_s: (t_end - t0) as f64 * 1e-9,
        ..ReplayStats::default()
    };
    log_start(wire, opts, stats.drive_s);
    let start = Instant::now();
    let mut next_progress_s = opts.progress_every_s;
    let mut outages = OutageLog::default();
    for (stream, i) in wire.delivery_order(&opts.latency) {
        let t_ns = wire.time_ns(stream, i);
        let drive_elapsed_s = (t_ns + opts.latency.of_ns(stream) - t0) as f64 * 1e-9;
        if !wait_until_due(opts.pacing, start, drive_elapsed_s) || bus::shutdown_requested() {
            stats.interrupted = true;
            break;
        }
        publishers.publish(wire, stream, i, &mut stats)?;
        if !wire.gnss.is_empty() {
            outages.saw(stream, t_ns);
        }
        if opts.progress_every_s > 0.0 && drive_elapsed_s >= next_progress_s {
            next_progress_s += opts.progress_every_s;
            tracing::info!(
                "bridge: t = {:.0} s of {:.0} s, {} samples published, {} subscriber(s) on wheels",
                drive_elapsed_s,
                stats.drive_s,
                stats.total(),
                publishers.wheels.subscriber_count()
            );
        }
    }
    stats.wall_s = start.elapsed().as_secs_f64();
    stats.stalled = publishers.stalled();
    if !stats.interrupted {
        publishers.end_of_stream()?;
        tracing::info!(
            "bridge: published {} samples in {:.2} s ({:.0} samples/s); end of stream",
            stats.total(),
            stats.wall_s,
            stats.total() as f64 / stats.wall_s.max(1e-9)
        );
        bus::sleep_unless_shutdown(opts.linger);
    }
    Ok(stats)
}

/// Sleep until a sample `drive_elapsed_s` into the drive is due at this
/// pace (at once with `--max`); false when a shutdown came first.
fn wait_until_due(pacing: Pacing, start: Instant, drive_elapsed_s: f64) -> bool {
    let Pacing::Speed(f) = pacing else {
        return true;
    };
    let due = Duration::from_secs_f64(drive_elapsed_s / f);
    let now = start.elapsed();
    due <= now || bus::sleep_unless_shutdown(due - now)
}

/// What the replay is about to do, in the log.
fn log_start(wire: &WireDrive, opts: &ReplayOptions, drive_s: f64) {
    tracing::info!(
        "replaying {:.1} s of drive: {} wheel, {} GNSS, {} IMU, {} heading samples, {}",
        drive_s,
        wire.wheels.len(),
        wire.gnss.len(),
        wire.imu.len(),
        wire.heading.len(),
        match opts.pacing {
            Pacing::Speed(f) => format!("at {f}x real time"),
            Pacing::Max => "as fast as the subscribers take it".to_string(),
        }
    );
    if opts.latency != DeliveryLatency::default() {
        let l = opts.latency;
        tracing::info!(
            "delivering late, time stamps as recorded: IMU {} s, GNSS {} s, heading {} s, wheels {} s",
            l.imu_s,
            l.gnss_s,
            l.heading_s,
            l.wheels_s
        );
    }
}

/// GNSS silence announced in the log: when the wheels pass a gap of more
/// than [`OUTAGE_LOG_S`] after the last fix, and when a fix comes back.
#[derive(Default)]
struct OutageLog {
    last_gnss_ns: Option<i64>,
    in_outage: bool,
}

impl OutageLog {
    fn saw(&mut self, stream: Stream, t_ns: i64) {
        match stream {
            Stream::Wheels => {
                if let Some(last) = self.last_gnss_ns {
                    let silent_s = (t_ns - last) as f64 * 1e-9;
                    if !self.in_outage && silent_s > OUTAGE_LOG_S {
                        self.in_outage = true;
                        tracing::info!(
                            "bridge: t = {:.1} s: GNSS silent for {:.1} s (outage in the drive)",
                            t_ns as f64 * 1e-9,
                            silent_s
                        );
                    }
                }
            }
            Stream::Gnss => {
                if self.in_outage {
                    self.in_outage = false;
                    tracing::info!(
                        "bridge: t = {:.1} s: GNSS back after {:.1} s",
                        t_ns as f64 * 1e-9,
                        self.last_gnss_ns.map_or(0.0, |l| (t_ns - l) as f64 * 1e-9)
                    );
                }
                self.last_gnss_ns = Some(t_ns);
            }
            Stream::Imu | Stream::Heading => {}
        }
    }
}

/// The replay's publishers, one per stream the drive has.
struct Publishers {
    wheels: TopicPublisher<WheelRotations>,
    gnss: Option<TopicPublisher<interfaces::wire::GnssFix>>,
    imu: Option<TopicPublisher<interfaces::wire::Imu>>,
    heading: Option<TopicPublisher<interfaces::wire::Heading>>,
}

impl Publishers {
    /// Paced, the streams are live: a reader whose buffer is full is
    /// already seconds late and must not hold the others back beyond a few
    /// milliseconds (`Bus::live_publisher`). At `--max` nothing is lost: the
    /// publishers wait on the slowest reader up to the stall timeout.
    fn open(bus: &Bus, wire: &WireDrive, pacing: Pacing) -> Result<Publishers, BusError> {
        let live = matches!(pacing, Pacing::Speed(_));
        Ok(Publishers {
            wheels: open(bus, live)?,
            gnss: open_if(bus, !wire.gnss.is_empty(), live)?,
            imu: open_if(bus, !wire.imu.is_empty(), live)?,
            heading: open_if(bus, !wire.heading.is_empty(), live)?,
        })
    }

    /// Wait until every topic counts `want` subscribers (or `timeout`).
    fn wait_for(&self, want: usize, timeout: Option<Duration>) -> Result<(), BusError> {
        tracing::info!("waiting for {want} subscriber(s) on every published topic");
        bus::wait_until(
            || {
                let mut v = vec![(
                    self.wheels.service_name(),
                    self.wheels.subscriber_count(),
                    want,
                )];
                let mut add = |name: &'static str, count: Option<usize>| {
                    if let Some(c) = count {
                        v.push((name, c, want));
                    }
                };
                add(
                    interfaces::wire::GNSS_SERVICE,
                    self.gnss.as_ref().map(|p| p.subscriber_count()),
                );
                add(
                    interfaces::wire::IMU_SERVICE,
                    self.imu.as_ref().map(|p| p.subscriber_count()),
                );
                add(
                    interfaces::wire::HEADING_SERVICE,
                    self.heading.as_ref().map(|p| p.subscriber_count()),
                );
                v
            },
            timeout,
        )
    }

    /// Let the subscribers attach (see `interfaces::bus`).
    fn announce(&self) -> Result<(), BusError> {
        self.wheels.announce()?;
        for r in [
            self.gnss.as_ref().map(|p| p.announce()),
            self.imu.as_ref().map(|p| p.announce()),
            self.heading.as_ref().map(|p| p.announce()),
        ]
        .into_iter()
        .flatten()
        {
            r?;
        }
        Ok(())
    }

    /// Publish sample `i` of `stream`, counted in `stats`.
    fn publish(
        &mut self,
        wire: &WireDrive,
        stream: Stream,
        i: usize,
        stats: &mut ReplayStats,
    ) -> Result<(), BusError> {
        match stream {
            Stream::Wheels => {
                self.wheels.publish(wire.wheels[i])?;
                stats.wheels += 1;
            }
            Stream::Gnss => {
                if let Some(p) = self.gnss.as_mut() {
                    p.publish(wire.gnss[i])?;
                    stats.gnss += 1;
                }
            }
            Stream::Imu => {
                if let Some(p) = self.imu.as_mut() {
                    p.publish(wire.imu[i])?;
                    stats.imu += 1;
                }
            }
            Stream::Heading => {
                if let Some(p) = self.heading.as_mut() {
                    p.publish(wire.heading[i])?;
                    stats.heading += 1;
                }
            }
        }
        Ok(())
    }

    /// The topics with a reader that stopped taking samples, warned about.
    fn stalled(&self) -> Vec<(&'static str, u64, u64)> {
        let stalls = [
            Some((self.wheels.service_name(), self.wheels.stalls())),
            self.gnss.as_ref().map(|p| (p.service_name(), p.stalls())),
            self.imu.as_ref().map(|p| (p.service_name(), p.stalls())),
            self.heading
                .as_ref()
                .map(|p| (p.service_name(), p.stalls())),
        ];
        let mut out = Vec::new();
        for (name, (timed_out, at_once)) in stalls.into_iter().flatten() {
            if timed_out + at_once > 0 {
                tracing::warn!(
                    "bridge: a reader of {name} stopped taking samples: {} sample(s) not \
                     delivered to it ({timed_out} after a full wait, {at_once} at once); other \
                     readers lost nothing",
                    timed_out + at_once
                );
                out.push((name, timed_out, at_once));
            }
        }
        out
    }

    /// Tell every subscriber the streams ended.
    fn end_of_stream(&self) -> Result<(), BusError> {
        self.wheels.end_of_stream()?;
        for r in [
            self.gnss.as_ref().map(|p| p.end_of_stream()),
            self.imu.as_ref().map(|p| p.end_of_stream()),
            self.heading.as_ref().map(|p| p.end_of_stream()),
        ]
        .into_iter()
        .flatten()
        {
            r?;
        }
        Ok(())
    }
}

/// Publish `drive` on the graph named by the environment (see
/// [`Bus::from_env`]) as node `node`: [`to_wire`], its warnings logged, then
/// [`replay`]. What `sensor-bridge replay` and `simulate --publish` run.
pub fn publish_drive(
    drive: &Drive,
    opts: &ReplayOptions,
    node: &str,
) -> Result<ReplayStats, ReplayError> {
    let wire = to_wire(drive)?;
    for w in &wire.warnings {
        tracing::warn!("{w}");
    }
    let bus = Bus::from_env(node)?;
    let stats = replay(&bus, &wire, opts)?;
    if stats.interrupted {
        tracing::info!("replay interrupted after {} samples", stats.total());
    }
    Ok(stats)
}

fn open<T: bus::Topic>(bus: &Bus, live: bool) -> Result<TopicPublisher<T>, BusError> {
    if live {
        bus.live_publisher::<T>()
    } else {
        bus.publisher::<T>()
    }
}

fn open_if<T: bus::Topic>(
    bus: &Bus,
    wanted: bool,
    live: bool,
) -> Result<Option<TopicPublisher<T>>, BusError> {
    if wanted {
        open(bus, live).map(Some)
    } else {
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::drive::{
        GnssAntenna, GnssSample, ImuSample, VehicleParams, WheelSample, WheelSeries, WheelUnit,
        WheelUnits,
    };

    fn drive() -> Drive {
        Drive {
            vehicle: VehicleParams {
                name: None,
                track_width_m: 1.5,
                nominal_circumference_m: 2.0,
                wheelbase_m: None,
                ticks_per_rev: None,
                gnss: GnssAntenna::default(),
            },
            wheels: WheelSeries {
                units: WheelUnits::rear(WheelUnit::Rev),
                samples: (0..5)
                    .map(|i| WheelSample {
                        t_s: i as f64 * 0.1,
                        rl: i as f64,
                        rr: 2.0 * i as f64,
                        fl: None,
                        fr: None,
                    })
                    .collect(),
            },
            gnss: Some(vec![
                GnssSample {
                    t_s: 0.0,
                    x_m: 1.0,
                    y_m: 2.0,
                    sigma_m: None,
                },
                GnssSample {
                    t_s: 0.2,
                    x_m: 3.0,
                    y_m: 4.0,
                    sigma_m: Some(0.5),
                },
            ]),
            imu: Some(vec![ImuSample {
                t_s: 0.2,
                gz_rad_s: 0.1,
                ax_m_s2: Some(1.0),
                ay_m_s2: None,
                az_m_s2: None,
                gx_rad_s: None,
                gy_rad_s: Some(0.01),
            }]),
            heading: None,
            truth: None,
            truth_params: None,
        }
    }

    #[test]
    fn samples_convert_and_merge_in_time_order_with_wheels_last_on_ties() {
        let w = to_wire(&drive()).unwrap();
        assert_eq!(w.wheels.len(), 5);
        assert_eq!(w.wheels[3].rr_rev, 6.0);
        assert_eq!(w.gnss[0].sigma_m, 0.0);
        assert_eq!(w.gnss[1].sigma_m, 0.5);
        assert_eq!(w.gnss[1].fix, 1);
        assert_eq!(
            w.imu[0].valid, 0,
            "partial accelerations are not flagged valid"
        );
        assert!(
            w.warnings.iter().any(|m| m.contains("ax, ay, az")),
            "{:?}",
            w.warnings
        );
        assert!(
            w.warnings
                .iter()
                .any(|m| m.contains("only one of gx_rad_s, gy_rad_s")),
            "{:?}",
            w.warnings
        );
        let order = w.merged();
        assert_eq!(order.len(), 8);
        // t = 0: GNSS before wheels; t = 0.2: IMU, GNSS, wheels.
        assert_eq!(order[0], (Stream::Gnss, 0));
        assert_eq!(order[1], (Stream::Wheels, 0));
        assert_eq!(order[2], (Stream::Wheels, 1));
        assert_eq!(
            &order[3..6],
            &[(Stream::Imu, 0), (Stream::Gnss, 1), (Stream::Wheels, 2)]
        );
        let times: Vec<i64> = order.iter().map(|&(s, i)| w.time_ns(s, i)).collect();
        assert!(times.windows(2).all(|p| p[0] <= p[1]));
    }

    #[test]
    fn a_late_stream_is_published_after_the_samples_of_its_delivery_time() {
        let w = to_wire(&drive()).unwrap();
        let late = DeliveryLatency::parse("gnss=0.25").unwrap();
        let order = w.delivery_order(&late);
        assert_eq!(order.len(), w.merged().len());
        // The fix of t = 0 comes at 0.25 s: after the wheels of 0, 0.1 and
        // 0.2 s, before those of 0.3 s.
        let delivered: Vec<i64> = order
            .iter()
            .map(|&(s, i)| w.time_ns(s, i) + late.of_ns(s))
            .collect();
        assert!(delivered.windows(2).all(|p| p[0] <= p[1]), "{delivered:?}");
        let first_fix = order.iter().position(|o| *o == (Stream::Gnss, 0)).unwrap();
        let wheels_before = order[..first_fix]
            .iter()
            .filter(|(s, _)| *s == Stream::Wheels)
            .count();
        assert_eq!(wheels_before, 3, "{order:?}");
        // Each stream keeps its own order.
        let fixes: Vec<usize> = order
            .iter()
            .filter(|(s, _)| *s == Stream::Gnss)
            .map(|(_, i)| *i)
            .collect();
        assert_eq!(fixes, (0..w.gnss.len()).collect::<Vec<_>>());
    }

    #[test]
    fn a_delivery_latency_is_read_or_named_in_its_error() {
        let l = DeliveryLatency::parse("gnss=0.15, imu=0.01").unwrap();
        assert_eq!(
            (l.gnss_s, l.imu_s, l.heading_s, l.wheels_s),
            (0.15, 0.01, 0.0, 0.0)
        );
        assert_eq!(
            DeliveryLatency::parse("").unwrap(),
            DeliveryLatency::default()
        );
        let err = |t: &str| DeliveryLatency::parse(t).unwrap_err();
        assert!(
            err("gps=0.1").contains("unknown stream `gps`"),
            "{}",
            err("gps=0.1")
        );
        assert!(err("gnss").contains("STREAM=SECONDS"));
        assert!(err("gnss=soon").contains("`soon` is not a number"));
        assert!(err("gnss=-0.1").contains("zero or more"));
    }

    #[test]
    fn a_bad_speed_is_refused_before_anything_is_opened() {
        let root = tempfile::tempdir().unwrap();
        let settings = interfaces::bus::BusSettings::isolated("badspeed", root.path());
        let bus = Bus::open(&settings, "t").unwrap();
        let w = to_wire(&drive()).unwrap();
        let opts = ReplayOptions {
            pacing: Pacing::Speed(0.0),
            ..ReplayOptions::default()
        };
        let err = replay(&bus, &w, &opts).unwrap_err();
        assert!(err.to_string().contains("--speed 0"), "{err}");
        drop(bus);
        settings.remove_leftovers();
    }
}
