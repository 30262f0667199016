//! Collecting wire samples into a [`Drive`]: [`DriveBuilder`], pure (no bus,
//! no clock), used by `sensor-bridge record` and by the calibrator's service.
//!
//! The wire carries no vehicle parameters: they come from the caller.
//! Wheels are collected as cumulative revolutions (`_rev`).
//!
//! # What comes over the bus is checked
//!
//! Any process can publish on the sensor topics, and a publisher can restart
//! or step its clock, so a sample is not taken at its word ([`CollectLimits`]
//! holds the numbers):
//!
//! - **Non-finite values** are refused (counted).
//! - **Time not after the previous sample** of its stream by at most
//!   [`CollectLimits::max_backstep_s`] (a duplicate, jitter): skipped, counted.
//! - **A jump** (a step ahead by more than [`CollectLimits::jump_intervals`]
//!   typical intervals of the stream, at least [`CollectLimits::min_jump_s`]
//!   and at most [`CollectLimits::max_forward_gap_s`]; for the wheels also a
//!   step back by more than the backstep, or a revolution step faster than
//!   [`CollectLimits::max_wheel_rev_per_s`]) is *held* as a candidate until the
//!   next sample of its stream decides:
//!   - the next sample goes on from before the jump: the held one was an
//!     outlier (one sample stamped t = 1e6 s, one +1e6 revolution reading);
//!     it is refused and counted, and collection goes on;
//!   - the next sample goes on from the held one: the jump is real. A gap in a
//!     stream (a GNSS outage in a tunnel, lost wheel samples) is kept as a
//!     gap. A wheel stream whose time went back, jumped ahead by more than
//!     [`CollectLimits::max_forward_gap_s`], or whose revolutions jumped,
//!     cannot continue the drive: the collector **resets**, it sets the
//!     drive collected so far aside and starts a new one at the held sample
//!     ([`DriveBuilder::resets`], [`DriveBuilder::reset_log`], and a warning
//!     naming the stream and the times).
//! - **The wheels set the drive's time line**: a GNSS, IMU or heading sample
//!   more than [`CollectLimits::max_forward_gap_s`] from the last wheel
//!   sample, or (after the wheels went back in time) one still on the old
//!   time line, is not recorded (counted); after a reset these streams join
//!   the new drive with their first sample on the wheels' new time line.
//!
//! So one bad sample costs that sample, a genuine restart costs the drive
//! before it (kept counts say how much), and nothing makes the collector
//! silently drop everything after it. The one sample held at the end of a
//! stream, if any, is not in the drive ([`DriveBuilder::warnings`] says so).

use crate::drive::{
    Drive, GnssSample, HeadingSample, ImuSample, VehicleParams, WheelSample, WheelSeries,
    WheelUnit, WheelUnits,
};
use crate::wire::{GnssFix, Heading, Imu, WheelRotations};

/// What a sample may do relative to the previous ones (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CollectLimits {
    /// A wheel stream whose time jumps ahead by more than this, and goes on
    /// from there, starts a new drive; a GNSS, IMU or heading sample farther
    /// than this from the wheels' time is not recorded, s. Default 60 s.
    pub max_forward_gap_s: f64,
    /// A sample at most this much before the previous one of its stream is
    /// only skipped; a wheel sample farther back is a jump, s. Default 1 s.
    pub max_backstep_s: f64,
    /// A step ahead of more than this many typical intervals of a stream is
    /// a jump (held until the next sample confirms it). Default 10.
    pub jump_intervals: f64,
    /// ... but a step of at most this is never a jump, s. Default 2 s.
    pub min_jump_s: f64,
    /// A wheel turning faster than this is beyond any car: such a revolution
    /// step is a jump, rev/s. Default 100 rev/s (720 km/h on a 2 m tyre).
    pub max_wheel_rev_per_s: f64,
    /// Allowance on top of [`CollectLimits::max_wheel_rev_per_s`] for time
    /// stamp jitter, rev. Default 1 rev.
    pub wheel_step_slack_rev: f64,
}

impl Default for CollectLimits {
    fn default() -> CollectLimits {
        CollectLimits {
            max_forward_gap_s: 60.0,
            max_backstep_s: 1.0,
            jump_intervals: 10.0,
            min_jump_s: 2.0,
            max_wheel_rev_per_s: crate::drive::MAX_WHEEL_REV_PER_S,
            wheel_step_slack_rev: 1.0,
        }
    }
}

impl CollectLimits {
    /// The largest step ahead that is not a jump, given the stream's typical
    /// interval (unknown: [`CollectLimits::max_forward_gap_s`]).
    fn jump_after(&self, interval: Option<f64>) -> f64 {
        match interval {
            Some(i) => (self.jump_intervals * i)
                .max(self.min_jump_s)
                .min(self.max_forward_gap_s),
            None => self.max_forward_gap_s,
        }
    }

    /// Largest revolution step of any wheel present in both, and whether it
    /// is within the limit for their time difference.
    fn revolutions_ok(&self, a: &WheelSample, b: &WheelSample) -> (bool, f64) {
        let pairs = [
            (Some(a.rl), Some(b.rl)),
            (Some(a.rr), Some(b.rr)),
            (a.fl, b.fl),
            (a.fr, b.fr),
        ];
        let step = pairs
            .iter()
            .filter_map(|p| match p {
                (Some(x), Some(y)) => Some((y - x).abs()),
                _ => None,
            })
            .fold(0.0, f64::max);
        let dt = (b.t_s - a.t_s).abs();
        (
            step <= self.max_wheel_rev_per_s * dt + self.wheel_step_slack_rev,
            step,
        )
    }
}

/// How many reset descriptions [`DriveBuilder::reset_log`] keeps (the newest).
pub const RESET_LOG_LEN: usize = 16;

/// Per-stream bookkeeping.
#[derive(Debug, Clone, Copy, Default)]
struct StreamStats {
    /// Typical interval: the last step, decaying slowly from larger ones.
    interval: Option<f64>,
    /// Time of the stream's last sample in the drive set aside by the last
    /// reset, until the stream joins the new drive.
    before_reset: Option<f64>,
    skipped_time: u64,
    skipped_nonfinite: u64,
    /// Held samples that the next one did not confirm (time jumps).
    outliers: u64,
    /// (time of the last sample before it, its time) of the last outlier.
    last_outlier: Option<(f64, f64)>,
    /// Samples off the wheels' time line.
    off_timeline: u64,
    /// (wheel time, its time) of the last one.
    last_off: Option<(f64, f64)>,
    /// Samples set aside by resets.
    set_aside: u64,
    /// Samples dropped by [`DriveBuilder::forget_before`].
    forgotten: u64,
}

impl StreamStats {
    fn stepped(&mut self, dt: f64) {
        self.interval = Some(match self.interval {
            Some(i) => dt.max(0.9 * i),
            None => dt,
        });
    }
}

/// A sample with a time.
trait Timed: Copy {
    fn t(&self) -> f64;
}

impl Timed for WheelSample {
    fn t(&self) -> f64 {
        self.t_s
    }
}
impl Timed for GnssSample {
    fn t(&self) -> f64 {
        self.t_s
    }
}
impl Timed for ImuSample {
    fn t(&self) -> f64 {
        self.t_s
    }
}
impl Timed for HeadingSample {
    fn t(&self) -> f64 {
        self.t_s
    }
}

/// Append `s`, learning the stream's interval.
fn push<T: Timed>(samples: &mut Vec<T>, st: &mut StreamStats, s: T) {
    if let Some(prev) = samples.last() {
        st.stepped(s.t() - prev.t());
    }
    samples.push(s);
}

/// The time rules for a GNSS, IMU or heading sample (module doc); `clock`
/// is the time of the last wheel sample.
fn admit<T: Timed>(
    samples: &mut Vec<T>,
    pending: &mut Option<T>,
    st: &mut StreamStats,
    clock: Option<f64>,
    lim: &CollectLimits,
    s: T,
) {
    let t = s.t();
    if let Some(c) = clock {
        let stale = samples.is_empty()
            && st
                .before_reset
                .is_some_and(|o| t > o - lim.max_backstep_s && c < o - lim.max_backstep_s);
        if stale || (t - c).abs() > lim.max_forward_gap_s {
            st.off_timeline += 1;
            st.last_off = Some((c, t));
            return;
        }
    }
    let Some(last) = samples.last().map(Timed::t) else {
        *pending = None;
        st.before_reset = None;
        samples.push(s);
        return;
    };
    let jump = lim.jump_after(st.interval);
    let fits = |from: f64| t > from && t - from <= jump;
    let refuse = |st: &mut StreamStats, p: &T| {
        st.outliers += 1;
        st.last_outlier = Some((last, p.t()));
    };
    match pending.take() {
        None if fits(last) => push(samples, st, s),
        None if t <= last => st.skipped_time += 1,
        None => *pending = Some(s),
        Some(p) if fits(last) => {
            refuse(st, &p);
            push(samples, st, s);
        }
        Some(p) if t <= last => {
            refuse(st, &p);
            st.skipped_time += 1;
        }
        // A gap: kept as a gap.
        Some(p) if fits(p.t()) => {
            samples.push(p);
            push(samples, st, s);
        }
        Some(p) => {
            refuse(st, &p);
            *pending = Some(s);
        }
    }
}

/// Collects wire samples into a [`Drive`]. Samples that a drive cannot hold
/// (time not increasing, GNSS without fix, non-finite values, jumps) are
/// counted and reported by [`DriveBuilder::warnings`]; see the module doc for
/// the rules.
#[derive(Debug, Clone)]
pub struct DriveBuilder {
    vehicle: VehicleParams,
    limits: CollectLimits,
    wheels: Vec<WheelSample>,
    any_front: bool,
    gnss: Vec<GnssSample>,
    imu: Vec<ImuSample>,
    heading: Vec<HeadingSample>,
    pending_wheels: Option<WheelSample>,
    pending_gnss: Option<GnssSample>,
    pending_imu: Option<ImuSample>,
    pending_heading: Option<HeadingSample>,
    stats: [StreamStats; 4],
    skipped_no_fix: u64,
    /// Wheel samples refused for a revolution step.
    wheel_steps: u64,
    /// (time, revolution step, time step) of the last one.
    last_wheel_step: Option<(f64, f64, f64)>,
    resets: u64,
    reset_log: Vec<String>,
}

/// The sensor streams in the order of every per-stream array here:
/// wheels, GNSS, IMU, heading.
pub const NAMES: [&str; 4] = ["wheels", "gnss", "imu", "heading"];

impl DriveBuilder {
    /// An empty drive of this vehicle, with the default [`CollectLimits`].
    pub fn new(vehicle: VehicleParams) -> DriveBuilder {
        DriveBuilder::with_limits(vehicle, CollectLimits::default())
    }

    /// An empty drive of this vehicle, with these limits.
    pub fn with_limits(vehicle: VehicleParams, limits: CollectLimits) -> DriveBuilder {
        DriveBuilder {
            vehicle,
            limits,
            wheels: Vec::new(),
            any_front: false,
            gnss: Vec::new(),
            imu: Vec::new(),
            heading: Vec::new(),
            pending_wheels: None,
            pending_gnss: None,
            pending_imu: None,
            pending_heading: None,
            stats: [StreamStats::default(); 4],
            skipped_no_fix: 0,
            wheel_steps: 0,
            last_wheel_step: None,
            resets: 0,
            reset_log: Vec::new(),
        }
    }

    /// The limits in use.
    pub fn limits(&self) -> &CollectLimits {
        &self.limits
    }

    /// Add a wheel sample.
    pub fn push_wheels(&mut self, s: &WheelRotations) {
        let front = s.valid & WheelRotations::FRONT_VALID != 0;
        let finite = s.rl_rev.is_finite()
            && s.rr_rev.is_finite()
            && (!front || (s.fl_rev.is_finite() && s.fr_rev.is_finite()));
        let t = s.header.t_s();
        if !finite {
            self.stats[0].skipped_nonfinite += 1;
            return;
        }
        let w = WheelSample {
            t_s: t,
            rl: s.rl_rev,
            rr: s.rr_rev,
            fl: front.then_some(s.fl_rev),
            fr: front.then_some(s.fr_rev),
        };
        let Some(last) = self.wheels.last().copied() else {
            self.first_wheels(w);
            return;
        };
        let lim = self.limits;
        let jump = lim.jump_after(self.stats[0].interval);
        let fits = |from: &WheelSample| {
            w.t_s > from.t_s && w.t_s - from.t_s <= jump && lim.revolutions_ok(from, &w).0
        };
        let small_back = w.t_s <= last.t_s && last.t_s - w.t_s <= lim.max_backstep_s;
        match self.pending_wheels.take() {
            None if fits(&last) => self.push_wheel(w),
            None if small_back => self.stats[0].skipped_time += 1,
            None => self.pending_wheels = Some(w),
            Some(p) if fits(&last) => {
                self.refuse_wheel(&last, &p, jump);
                self.push_wheel(w);
            }
            Some(p) if small_back => {
                self.refuse_wheel(&last, &p, jump);
                self.stats[0].skipped_time += 1;
            }
            Some(p) if fits(&p) => {
                let gap_only = p.t_s > last.t_s
                    && p.t_s - last.t_s <= lim.max_forward_gap_s
                    && lim.revolutions_ok(&last, &p).0;
                if gap_only {
                    self.any_front |= p.fl.is_some();
                    self.wheels.push(p);
                    self.push_wheel(w);
                } else {
                    self.reset(&last, p, w);
                }
            }
            Some(p) => {
                self.refuse_wheel(&last, &p, jump);
                self.pending_wheels = Some(w);
            }
        }
    }

    fn push_wheel(&mut self, w: WheelSample) {
        self.any_front |= w.fl.is_some();
        push(&mut self.wheels, &mut self.stats[0], w);
    }

    /// The first wheel sample of a drive: other streams' samples far from
    /// its time are not on its time line.
    fn first_wheels(&mut self, w: WheelSample) {
        let (c, gap) = (w.t_s, self.limits.max_forward_gap_s);
        fn prune<T: Timed>(v: &mut Vec<T>, st: &mut StreamStats, c: f64, gap: f64) {
            let before = v.len();
            let mut last_off = None;
            v.retain(|s| {
                let keep = (s.t() - c).abs() <= gap;
                if !keep {
                    last_off = Some((c, s.t()));
                }
                keep
            });
            st.off_timeline += (before - v.len()) as u64;
            st.last_off = last_off.or(st.last_off);
        }
        prune(&mut self.gnss, &mut self.stats[1], c, gap);
        prune(&mut self.imu, &mut self.stats[2], c, gap);
        prune(&mut self.heading, &mut self.stats[3], c, gap);
        self.push_wheel(w);
    }

    /// A held wheel sample that the next one did not confirm.
    fn refuse_wheel(&mut self, last: &WheelSample, p: &WheelSample, jump: f64) {
        let time_ok = p.t_s > last.t_s && p.t_s - last.t_s <= jump;
        if time_ok {
            self.wheel_steps += 1;
            let (_, step) = self.limits.revolutions_ok(last, p);
            self.last_wheel_step = Some((p.t_s, step, p.t_s - last.t_s));
        } else {
            self.stats[0].outliers += 1;
            self.stats[0].last_outlier = Some((last.t_s, p.t_s));
        }
    }

    /// The wheels went on from a jump: set the drive aside, start a new one
    /// at `p`.
    fn reset(&mut self, last: &WheelSample, p: WheelSample, w: WheelSample) {
        let what = if p.t_s <= last.t_s {
            format!("time went back from {:.3} s to {:.3} s", last.t_s, p.t_s)
        } else if p.t_s - last.t_s > self.limits.max_forward_gap_s {
            format!("time jumped ahead from {:.3} s to {:.3} s", last.t_s, p.t_s)
        } else {
            let (_, step) = self.limits.revolutions_ok(last, &p);
            format!(
                "revolutions jumped by {step:.1} rev in {:.3} s at t = {:.3} s",
                p.t_s - last.t_s,
                p.t_s
            )
        };
        let counts = [
            self.wheels.len(),
            self.gnss.len(),
            self.imu.len(),
            self.heading.len(),
        ];
        let lasts = [
            None,
            self.gnss.last().map(|s| s.t_s),
            self.imu.last().map(|s| s.t_s),
            self.heading.last().map(|s| s.t_s),
        ];
        for ((st, n), last_t) in self.stats.iter_mut().zip(counts).zip(lasts) {
            st.set_aside += n as u64;
            st.before_reset = last_t.or(st.before_reset);
        }
        self.stats[0].before_reset = None;
        self.stats[0].interval = None;
        self.wheels.clear();
        self.gnss.clear();
        self.imu.clear();
        self.heading.clear();
        self.pending_gnss = None;
        self.pending_imu = None;
        self.pending_heading = None;
        self.resets += 1;
        if self.reset_log.len() == RESET_LOG_LEN {
            self.reset_log.remove(0);
        }
        self.reset_log.push(format!(
            "wheels: {what} and went on from there (a publisher restarted, or its clock or \
             counter stepped): reset #{}, a new drive starts at t = {:.3} s; set aside {} wheel, \
             {} GNSS, {} IMU and {} heading samples of the drive before",
            self.resets, p.t_s, counts[0], counts[1], counts[2], counts[3]
        ));
        self.any_front = p.fl.is_some();
        self.wheels.push(p);
        self.push_wheel(w);
    }

    /// Add a GNSS fix (a message without fix is not a row of a drive).
    pub fn push_gnss(&mut self, s: &GnssFix) {
        if s.fix == 0 {
            self.skipped_no_fix += 1;
        } else if !(s.x_m.is_finite() && s.y_m.is_finite() && s.sigma_m.is_finite()) {
            self.stats[1].skipped_nonfinite += 1;
        } else {
            let clock = self.wheels.last().map(|w| w.t_s);
            let g = GnssSample {
                t_s: s.header.t_s(),
                x_m: s.x_m,
                y_m: s.y_m,
                sigma_m: (s.sigma_m > 0.0).then_some(s.sigma_m),
            };
            admit(
                &mut self.gnss,
                &mut self.pending_gnss,
                &mut self.stats[1],
                clock,
                &self.limits,
                g,
            );
        }
    }

    /// Add an IMU sample.
    pub fn push_imu(&mut self, s: &Imu) {
        let accel = s.valid & Imu::ACCEL_VALID != 0;
        let rates = s.valid & Imu::ROLL_PITCH_RATE_VALID != 0;
        let values = [
            Some(s.gz_rad_s),
            accel.then_some(s.ax_m_s2),
            accel.then_some(s.ay_m_s2),
            accel.then_some(s.az_m_s2),
            rates.then_some(s.gx_rad_s),
            rates.then_some(s.gy_rad_s),
        ];
        if values.iter().flatten().any(|v| !v.is_finite()) {
            self.stats[2].skipped_nonfinite += 1;
        } else {
            let clock = self.wheels.last().map(|w| w.t_s);
            let i = ImuSample {
                t_s: s.header.t_s(),
                gz_rad_s: s.gz_rad_s,
                ax_m_s2: values[1],
                ay_m_s2: values[2],
                az_m_s2: values[3],
                gx_rad_s: values[4],
                gy_rad_s: values[5],
            };
            admit(
                &mut self.imu,
                &mut self.pending_imu,
                &mut self.stats[2],
                clock,
                &self.limits,
                i,
            );
        }
    }

    /// Add a heading.
    pub fn push_heading(&mut self, s: &Heading) {
        if !(s.yaw_rad.is_finite() && s.sigma_rad.is_finite()) {
            self.stats[3].skipped_nonfinite += 1;
        } else {
            let clock = self.wheels.last().map(|w| w.t_s);
            let h = HeadingSample {
                t_s: s.header.t_s(),
                yaw_rad: s.yaw_rad,
                sigma_rad: (s.sigma_rad > 0.0).then_some(s.sigma_rad),
            };
            admit(
                &mut self.heading,
                &mut self.pending_heading,
                &mut self.stats[3],
                clock,
                &self.limits,
                h,
            );
        }
    }

    /// Wheel samples collected (in the current drive, since the last reset,
    /// and not forgotten).
    pub fn wheel_count(&self) -> usize {
        self.wheels.len()
    }

    /// GNSS fixes collected.
    pub fn gnss_count(&self) -> usize {
        self.gnss.len()
    }

    /// Samples held now: wheels, gnss, imu, heading.
    pub fn sample_counts(&self) -> [usize; 4] {
        [
            self.wheels.len(),
            self.gnss.len(),
            self.imu.len(),
            self.heading.len(),
        ]
    }

    /// Wheel samples collected so far, in time order.
    pub fn wheels(&self) -> &[WheelSample] {
        &self.wheels
    }

    /// GNSS fixes collected so far, in time order.
    pub fn gnss(&self) -> &[GnssSample] {
        &self.gnss
    }

    /// How many times the wheels jumped for good and a new drive started
    /// (module doc); the drive before each was set aside.
    pub fn resets(&self) -> u64 {
        self.resets
    }

    /// What each reset was (stream, times, samples set aside): the newest
    /// [`RESET_LOG_LEN`], oldest first.
    pub fn reset_log(&self) -> &[String] {
        &self.reset_log
    }

    /// Drop every sample (of every stream) older than `t_s`: a service that
    /// keeps a window of the drive calls it to bound its memory. Returns how
    /// many samples were dropped.
    pub fn forget_before(&mut self, t_s: f64) -> usize {
        fn cut<T: Timed>(v: &mut Vec<T>, st: &mut StreamStats, t_s: f64) -> usize {
            let n = v.partition_point(|s| s.t() < t_s);
            v.drain(..n);
            st.forgotten += n as u64;
            n
        }
        cut(&mut self.wheels, &mut self.stats[0], t_s)
            + cut(&mut self.gnss, &mut self.stats[1], t_s)
            + cut(&mut self.imu, &mut self.stats[2], t_s)
            + cut(&mut self.heading, &mut self.stats[3], t_s)
    }

    /// Samples dropped by [`DriveBuilder::forget_before`] so far: wheels,
    /// gnss, imu, heading.
    pub fn forgotten(&self) -> [u64; 4] {
        self.stats.map(|s| s.forgotten)
    }

    /// What was not recorded, and why.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (name, st) in NAMES.iter().zip(&self.stats) {
            if st.skipped_time > 0 {
                out.push(format!(
                    "{name}: {} samples not recorded: time not after the previous sample \
                     (a publisher restarted?)",
                    st.skipped_time
                ));
            }
            if st.skipped_nonfinite > 0 {
                out.push(format!(
                    "{name}: {} samples not recorded: non-finite values",
                    st.skipped_nonfinite
                ));
            }
        }
        if self.skipped_no_fix > 0 {
            out.push(format!(
                "gnss: {} messages without fix not recorded (a drive has no row for them)",
                self.skipped_no_fix
            ));
        }
        for (name, st) in NAMES.iter().zip(&self.stats) {
            if let (n @ 1.., Some((before, t))) = (st.outliers, st.last_outlier) {
                out.push(format!(
                    "{name}: {n} samples refused: their time jumped and the next sample went on \
                     from before the jump (an outlier time stamp; the last: t = {t:.3} s after \
                     {before:.3} s)"
                ));
            }
            if let (n @ 1.., Some((clock, t))) = (st.off_timeline, st.last_off) {
                out.push(format!(
                    "{name}: {n} samples not recorded: not on the wheels' time line (more than \
                     {:.0} s from it, or from before the wheels' reset; the last: t = {t:.3} s \
                     with the wheels at {clock:.3} s)",
                    self.limits.max_forward_gap_s
                ));
            }
        }
        if let (n @ 1.., Some((t, step, dt))) = (self.wheel_steps, self.last_wheel_step) {
            out.push(format!(
                "wheels: {n} samples refused: revolutions stepped faster than {:.0} rev/s and \
                 the next sample went on from before (the last: {step:.1} rev in {dt:.3} s at \
                 t = {t:.3} s)",
                self.limits.max_wheel_rev_per_s
            ));
        }
        let held = [
            self.pending_wheels.map(|s| s.t_s),
            self.pending_gnss.map(|s| s.t_s),
            self.pending_imu.map(|s| s.t_s),
            self.pending_heading.map(|s| s.t_s),
        ];
        for (name, t) in NAMES.iter().zip(held) {
            if let Some(t) = t {
                out.push(format!(
                    "{name}: the last sample (t = {t:.3} s) is not recorded: it jumped and no \
                     sample came after it to confirm the jump"
                ));
            }
        }
        if self.resets > 0 {
            let set_aside = self.stats.map(|s| s.set_aside);
            out.push(format!(
                "{} resets: the wheels jumped for good and a new drive started; set aside {} \
                 wheel, {} GNSS, {} IMU and {} heading samples in all",
                self.resets, set_aside[0], set_aside[1], set_aside[2], set_aside[3]
            ));
            out.extend(self.reset_log.iter().cloned());
        }
        out
    }

    /// The drive collected so far (a copy; collection can go on).
    pub fn snapshot(&self) -> Drive {
        self.clone().finish()
    }

    /// The drive.
    pub fn finish(self) -> Drive {
        let units = if self.any_front {
            WheelUnits::all(WheelUnit::Rev)
        } else {
            WheelUnits::rear(WheelUnit::Rev)
        };
        Drive {
            vehicle: self.vehicle,
            wheels: WheelSeries {
                units,
                samples: self.wheels,
            },
            gnss: non_empty(self.gnss),
            imu: non_empty(self.imu),
            heading: non_empty(self.heading),
            truth: None,
            truth_params: None,
        }
    }
}

fn non_empty<T>(v: Vec<T>) -> Option<Vec<T>> {
    if v.is_empty() {
        None
    } else {
        Some(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::GnssAntenna;
    use crate::wire::Header;

    fn vehicle() -> VehicleParams {
        VehicleParams {
            name: Some("t".into()),
            track_width_m: 1.5,
            nominal_circumference_m: 2.0,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: GnssAntenna::default(),
        }
    }

    #[test]
    fn builder_keeps_values_and_reports_what_it_skips() {
        let mut b = DriveBuilder::new(vehicle());
        let w = |t: f64, rl: f64| WheelRotations {
            header: Header::from_seconds(t, 0),
            rl_rev: rl,
            rr_rev: rl + 1.0,
            ..WheelRotations::default()
        };
        b.push_wheels(&w(0.0, 1.0));
        b.push_wheels(&w(0.1, 2.0));
        b.push_wheels(&w(0.1, 3.0)); // time not increasing
        b.push_wheels(&w(0.2, f64::NAN));
        b.push_gnss(&GnssFix {
            header: Header::from_seconds(0.0, 0),
            x_m: 1.0,
            y_m: 2.0,
            sigma_m: 0.0,
            fix: 1,
            _pad: [0; 7],
        });
        b.push_gnss(&GnssFix {
            header: Header::from_seconds(1.0, 0),
            fix: 0,
            ..GnssFix::default()
        });
        let warnings = b.warnings();
        assert_eq!(warnings.len(), 3, "{warnings:?}");
        assert!(warnings[0].contains("wheels: 1 samples not recorded: time"));
        assert!(warnings[2].contains("without fix"));
        let d = b.finish();
        assert_eq!(d.wheels.samples.len(), 2);
        assert_eq!(d.wheels.samples[1].rr, 3.0);
        assert_eq!(d.wheels.units, WheelUnits::rear(WheelUnit::Rev));
        assert_eq!(d.gnss.as_ref().unwrap()[0].sigma_m, None);
        assert!(d.imu.is_none());
    }

    /// A drive at 100 Hz (wheels and IMU) and 1 Hz (GNSS) from `t0`, fed in
    /// the order `SensorSubscribers::drain_into` feeds it (GNSS, IMU, then
    /// wheels), 0.1 s at a time. `rev0` is the wheels' count at `t0`; the car
    /// goes 10 m/s on 2 m wheels (5 rev/s).
    struct Feed {
        seq: u64,
    }

    impl Feed {
        fn wheels(&mut self, b: &mut DriveBuilder, t: f64, rev: f64) {
            self.seq += 1;
            b.push_wheels(&WheelRotations {
                header: Header::from_seconds(t, self.seq),
                rl_rev: rev,
                rr_rev: rev + 0.1,
                ..WheelRotations::default()
            });
        }

        fn imu(&mut self, b: &mut DriveBuilder, t: f64) {
            b.push_imu(&Imu {
                header: Header::from_seconds(t, 0),
                gz_rad_s: 0.01,
                ..Imu::default()
            });
        }

        fn gnss(&mut self, b: &mut DriveBuilder, t: f64) {
            b.push_gnss(&GnssFix {
                header: Header::from_seconds(t, 0),
                x_m: t * 10.0,
                y_m: 0.0,
                sigma_m: 0.5,
                fix: 1,
                _pad: [0; 7],
            });
        }

        /// `seconds` of drive from `t0` (exclusive of its end).
        fn drive(&mut self, b: &mut DriveBuilder, t0: f64, rev0: f64, seconds: f64) {
            let n = (seconds * 100.0).round() as usize;
            for batch in (0..n).step_by(10) {
                let k = batch..(batch + 10).min(n);
                for i in k.clone() {
                    if i % 100 == 0 {
                        self.gnss(b, t0 + i as f64 * 0.01);
                    }
                }
                for i in k.clone() {
                    self.imu(b, t0 + i as f64 * 0.01);
                }
                for i in k {
                    self.wheels(b, t0 + i as f64 * 0.01, rev0 + i as f64 * 0.05);
                }
            }
        }
    }

    fn joined(b: &DriveBuilder) -> String {
        b.warnings().join("\n")
    }

    #[test]
    fn one_wheel_sample_stamped_far_ahead_is_refused_and_the_following_kept() {
        let mut b = DriveBuilder::new(vehicle());
        let mut f = Feed { seq: 0 };
        f.drive(&mut b, 0.0, 0.0, 10.0);
        f.wheels(&mut b, 1e6, 50.0); // one bad time stamp
        f.drive(&mut b, 10.0, 50.0, 400.0);
        assert_eq!(b.wheel_count(), 41_000, "only the outlier is missing");
        assert_eq!(b.resets(), 0);
        let w = joined(&b);
        assert!(
            w.contains("wheels: 1 samples refused: their time jumped")
                && w.contains("t = 1000000.000 s after 9.990 s"),
            "{w}"
        );
        // The same, a bad sample only 30 s ahead (within the 60 s gap).
        f.wheels(&mut b, 440.0, 2050.0);
        f.drive(&mut b, 410.0, 2050.0, 1.0);
        assert_eq!(b.wheel_count(), 41_100);
        assert_eq!(b.sample_counts()[2], 41_100, "the IMU kept everything");
        assert!(joined(&b).contains("wheels: 2 samples refused"));
    }

    #[test]
    fn one_gnss_or_imu_sample_off_the_time_line_is_refused_and_the_following_kept() {
        let mut b = DriveBuilder::new(vehicle());
        let mut f = Feed { seq: 0 };
        f.drive(&mut b, 0.0, 0.0, 10.0);
        f.gnss(&mut b, 1e6); // far from the wheels: refused at once
        f.imu(&mut b, 40.0); // 30 s ahead: held, then refused
        f.drive(&mut b, 10.0, 50.0, 20.0);
        assert_eq!(b.sample_counts(), [3000, 30, 3000, 0]);
        let w = joined(&b);
        assert!(
            w.contains("gnss: 1 samples not recorded: not on the wheels' time line")
                && w.contains("t = 1000000.000 s with the wheels at 9.990 s"),
            "{w}"
        );
        assert!(w.contains("imu: 1 samples refused"), "{w}");
    }

    #[test]
    fn a_gap_in_a_stream_is_kept_as_a_gap() {
        let mut b = DriveBuilder::new(vehicle());
        let mut f = Feed { seq: 0 };
        f.drive(&mut b, 0.0, 0.0, 10.0);
        // Every stream lost for 30 s (the car went on): a gap, no reset.
        f.drive(&mut b, 40.0, 200.0, 100.0);
        assert_eq!(b.wheel_count(), 11_000);
        assert_eq!(b.resets(), 0);
        // GNSS in a 120 s tunnel while the wheels go on.
        let mut b2 = DriveBuilder::new(vehicle());
        for i in 0..30_000 {
            let t = i as f64 * 0.01;
            if i % 100 == 0 && !(6_000..18_000).contains(&i) {
                f.gnss(&mut b2, t);
            }
            f.wheels(&mut b2, t, i as f64 * 0.05);
        }
        assert_eq!(b2.gnss_count(), 300 - 120, "{:?}", b2.warnings());
        assert!(b2.warnings().is_empty(), "{:?}", b2.warnings());
    }

    #[test]
    fn a_genuine_restart_starts_a_new_drive_with_a_warning() {
        let mut b = DriveBuilder::new(vehicle());
        let mut f = Feed { seq: 0 };
        f.drive(&mut b, 0.0, 0.0, 100.0);
        // The publisher restarts: time and counters from 0 again.
        f.drive(&mut b, 0.0, 0.0, 50.0);
        assert_eq!(b.resets(), 1);
        let d = b.snapshot();
        assert_eq!(d.wheels.samples.len(), 5000, "the new drive, whole");
        assert_eq!(d.wheels.samples[0].t_s, 0.0);
        let gnss = d.gnss.as_ref().unwrap();
        assert!(gnss.iter().all(|g| g.t_s < 50.0), "only the new time line");
        assert!(gnss.len() >= 49, "{}", gnss.len());
        assert!(d.imu.as_ref().unwrap().len() >= 4990);
        let w = joined(&b);
        assert!(
            w.contains("wheels: time went back from 99.990 s to 0.000 s")
                && w.contains("reset #1")
                && w.contains("set aside 10000 wheel, 100 GNSS, 10000 IMU and 0 heading"),
            "{w}"
        );
        assert_eq!(b.reset_log().len(), 1);
        // A clock step ahead by an hour: a reset too, the drive from there.
        f.drive(&mut b, 3650.0, 250.0, 20.0);
        assert_eq!(b.resets(), 2);
        assert_eq!(b.wheel_count(), 2000);
        assert!(joined(&b).contains("time jumped ahead from 49.990 s to 3650.000 s"));
    }

    #[test]
    fn a_revolution_jump_is_refused_and_counted_a_lasting_one_resets() {
        let mut b = DriveBuilder::new(vehicle());
        let mut f = Feed { seq: 0 };
        f.drive(&mut b, 0.0, 0.0, 10.0);
        f.wheels(&mut b, 10.0, 50.0 + 1e6); // +1e6 revolutions
        f.drive(&mut b, 10.01, 50.05, 10.0);
        assert_eq!(b.wheel_count(), 2000);
        assert_eq!(b.resets(), 0);
        assert!(b.wheels().iter().all(|w| w.rl < 200.0));
        let w = joined(&b);
        assert!(
            w.contains("wheels: 1 samples refused: revolutions stepped faster than 100 rev/s")
                && w.contains("1000000.1 rev in 0.010 s at t = 10.000 s"),
            "{w}"
        );
        // A counter that jumps and goes on from there: a new drive.
        f.drive(&mut b, 20.01, 5e6, 5.0);
        assert_eq!(b.resets(), 1);
        assert_eq!(b.wheel_count(), 500);
        assert!(joined(&b).contains("revolutions jumped by"));
    }

    #[test]
    fn non_finite_values_are_refused_and_the_following_kept() {
        let mut b = DriveBuilder::new(vehicle());
        let mut f = Feed { seq: 0 };
        f.drive(&mut b, 0.0, 0.0, 1.0);
        b.push_wheels(&WheelRotations {
            header: Header::from_seconds(1.0, 0),
            rl_rev: 5.0,
            rr_rev: f64::INFINITY,
            ..WheelRotations::default()
        });
        b.push_wheels(&WheelRotations {
            header: Header::from_seconds(1.0, 0),
            rl_rev: 5.0,
            rr_rev: 5.0,
            fl_rev: f64::NAN,
            valid: WheelRotations::FRONT_VALID,
            ..WheelRotations::default()
        });
        b.push_imu(&Imu {
            header: Header::from_seconds(1.0, 0),
            gz_rad_s: f64::NAN,
            ..Imu::default()
        });
        b.push_heading(&Heading {
            header: Header::from_seconds(1.0, 0),
            yaw_rad: f64::NEG_INFINITY,
            sigma_rad: 0.0,
        });
        f.drive(&mut b, 1.0, 5.0, 1.0);
        assert_eq!(b.sample_counts(), [200, 2, 200, 0]);
        let w = b.warnings();
        assert_eq!(
            w,
            [
                "wheels: 2 samples not recorded: non-finite values",
                "imu: 1 samples not recorded: non-finite values",
                "heading: 1 samples not recorded: non-finite values",
            ]
        );
    }

    #[test]
    fn forget_before_drops_the_old_part_of_every_stream() {
        let mut b = DriveBuilder::new(vehicle());
        let mut f = Feed { seq: 0 };
        f.drive(&mut b, 0.0, 0.0, 20.0);
        assert_eq!(b.forget_before(15.0), 1500 + 15 + 1500);
        assert_eq!(b.sample_counts(), [500, 5, 500, 0]);
        assert_eq!(b.forgotten(), [1500, 15, 1500, 0]);
        assert!((b.wheels()[0].t_s - 15.0).abs() < 1e-9);
        f.drive(&mut b, 20.0, 100.0, 1.0);
        assert_eq!(b.wheel_count(), 600);
        assert!(b.warnings().is_empty());
    }
}
