//! Samples that arrive late: the filter goes back and takes them in order.
//!
//! In a vehicle each sensor has its own driver, and they deliver with their
//! own latency: a GNSS receiver hands a fix over 50-200 ms after the instant
//! it describes, when the wheel samples of that instant have long been
//! processed. Applied when it arrives, a fix 0.15 s old at 15 m/s is 2 m
//! behind the car; it is gated out, or it pulls the pose back.
//!
//! [`RewindingFusion`] keeps the inputs of the last
//! [`RewindConfig::window_s`] of drive time and copies of the filter taken
//! along the way ([`RewindConfig::checkpoint_every_s`]). A sample older than
//! what the filter has processed goes into that log at its place in
//! processing order ([`crate::inputs`]); the filter returns to the newest copy
//! before it and processes the log again from there. After that, the filter
//! is bit for bit what it would be had every sample come in order: a pose
//! published once every sample up to its time has arrived equals the
//! in-order pose exactly, whatever the delivery latencies and however the
//! samples were grouped into wakeups. (Poses published while a sample was
//! still on its way could not include it; they are what the filter knew.)
//!
//! A sample older than the window is handed to the filter as before, which
//! applies it late or drops it ([`FusionConfig::max_measurement_delay_s`]),
//! and is counted in [`RewindStats::beyond_window`].
//!
//! Pure: no clock, no I/O.
//!
//! [`FusionConfig::max_measurement_delay_s`]: crate::fusion::FusionConfig::max_measurement_delay_s

use crate::fusion::{FusedPose, Fusion, ProcessError};
use crate::inputs::Input;
use std::collections::VecDeque;

/// How far back [`RewindingFusion`] can go.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RewindConfig {
    /// Drive time kept for going back, s (0 = never go back: late samples go
    /// to the filter as they come).
    pub window_s: f64,
    /// A copy of the filter is kept at the first wheel sample after this
    /// much drive time since the previous copy, s. Going back processes at
    /// most this much more than the late sample's own lateness.
    pub checkpoint_every_s: f64,
}

impl Default for RewindConfig {
    fn default() -> Self {
        RewindConfig {
            // GNSS receivers deliver within a few hundred ms; 1 s covers
            // them with room, for about 200 logged inputs at 100 Hz.
            window_s: 1.0,
            checkpoint_every_s: 0.1,
        }
    }
}

/// What going back did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RewindStats {
    /// Late samples taken in order by going back.
    pub rewinds: u64,
    /// Inputs processed again while going back.
    pub reprocessed: u64,
    /// Late samples older than the window, handed to the filter as they came.
    pub beyond_window: u64,
}

/// A copy of the filter before the input with log position `at`.
#[derive(Debug, Clone)]
struct Checkpoint {
    /// Position in the log (counted from the first input ever logged).
    at: u64,
    /// Drive time of the wheel sample the copy was taken before, s.
    t_s: f64,
    fusion: Fusion,
}

/// A [`Fusion`] that takes late samples in processing order; see the module
/// docs. Feed it every input with [`RewindingFusion::process`].
#[derive(Debug, Clone)]
pub struct RewindingFusion {
    fusion: Fusion,
    config: RewindConfig,
    /// Inputs processed since the oldest checkpoint, in processing order.
    log: VecDeque<Input>,
    /// Log position of `log[0]`.
    log_start: u64,
    /// The log holds every input the filter has taken since it was made (or
    /// changed by [`RewindingFusion::fusion_mut`]), so a sample older than
    /// all of them can go first.
    log_is_complete: bool,
    /// Oldest first; the first is at or before `log_start`.
    checkpoints: VecDeque<Checkpoint>,
    /// Copies no longer needed, kept for their allocations.
    spare: Vec<Fusion>,
    /// The inputs being processed again (kept for its allocation).
    again: Vec<Input>,
    /// Processing-order key (time, rank) of the newest sample processed.
    newest: Option<(f64, u8)>,
    stats: RewindStats,
}

/// Processing-order key of a sample (estimates have none: they are taken
/// where they arrive).
fn key(input: &Input) -> Option<(f64, u8)> {
    match input {
        Input::Estimate { .. } => None,
        _ => Some((input.t_s(), input.rank())),
    }
}

fn before(a: (f64, u8), b: (f64, u8)) -> bool {
    a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).is_lt()
}

impl RewindingFusion {
    /// Wrap `fusion`, with nothing logged yet.
    pub fn new(fusion: Fusion, config: RewindConfig) -> RewindingFusion {
        RewindingFusion {
            fusion,
            config,
            log: VecDeque::new(),
            log_start: 0,
            log_is_complete: true,
            checkpoints: VecDeque::new(),
            spare: Vec::new(),
            again: Vec::new(),
            newest: None,
            stats: RewindStats::default(),
        }
    }

    /// Go back up to `window_s` of drive time from now on (the sensor clocks
    /// of a new estimate can make samples come later than before; a shorter
    /// window takes effect as the log is trimmed).
    pub fn set_window_s(&mut self, window_s: f64) {
        self.config.window_s = window_s.max(0.0);
    }

    /// How far back it goes, s.
    pub fn window_s(&self) -> f64 {
        self.config.window_s
    }

    /// The filter (its pose, parameters, counters).
    pub fn fusion(&self) -> &Fusion {
        &self.fusion
    }

    /// The filter, to change it outside [`RewindingFusion::process`] (reset,
    /// resume, stale inputs). Such a change cannot be processed again, so
    /// the log is forgotten: a sample older than now is then beyond the window.
    pub fn fusion_mut(&mut self) -> &mut Fusion {
        self.forget();
        &mut self.fusion
    }

    /// The filter's [`Fusion::take_contradiction`], without forgetting the
    /// log (the caller that acts on it changes the filter through
    /// [`RewindingFusion::fusion_mut`], which does).
    pub fn take_contradiction(&mut self) -> Option<crate::fusion::Contradiction> {
        self.fusion.take_contradiction()
    }

    /// What going back did so far.
    pub fn stats(&self) -> RewindStats {
        self.stats
    }

    /// Inputs in the log now.
    pub fn logged(&self) -> usize {
        self.log.len()
    }

    /// Take one input, as [`Fusion::process`]: the pose after a wheel sample
    /// that is not late, `None` otherwise. A late sample's own result is
    /// returned (an unusable one is an error as it would have been in order).
    pub fn process(&mut self, input: &Input) -> Result<Option<FusedPose>, ProcessError> {
        let late = match (key(input), self.newest) {
            (Some(k), Some(newest)) => before(k, newest),
            _ => false,
        };
        // Wheels are never taken back: a wheel sample older than the newest
        // is out of order in its own stream, which the filter reports.
        if late && !matches!(input, Input::Wheels { .. }) && self.config.window_s > 0.0 {
            if let Some(result) = self.rewind(input) {
                return result;
            }
            self.stats.beyond_window += 1;
            // The filter takes it now, out of order, which the log cannot
            // repeat: going back past this point would lose it.
            let newest = self.newest;
            self.forget();
            self.newest = newest;
            self.log_is_complete = false;
        }
        if late || self.config.window_s <= 0.0 {
            return self.fusion.process(input);
        }
        self.take_in_order(input)
    }

    /// Log `input`, keep a checkpoint before it when one is due, process it.
    fn take_in_order(&mut self, input: &Input) -> Result<Option<FusedPose>, ProcessError> {
        if let Some(k) = key(input) {
            self.newest = Some(k);
        }
        let at = self.log_start + self.log.len() as u64;
        // The first checkpoint before the first input, the others before a
        // wheel sample.
        let t_s = input.t_s();
        let due = match self.checkpoints.back() {
            None => true,
            Some(c) => {
                matches!(input, Input::Wheels { .. })
                    && t_s - c.t_s >= self.config.checkpoint_every_s
            }
        };
        if due {
            let copy = self.copy_of_filter();
            self.checkpoints.push_back(Checkpoint {
                at,
                t_s,
                fusion: copy,
            });
            self.trim(t_s);
        }
        self.log.push_back(*input);
        self.fusion.process(input)
    }

    /// A copy of the filter, in a spare one's place when there is one.
    fn copy_of_filter(&mut self) -> Fusion {
        match self.spare.pop() {
            Some(mut spare) => {
                spare.clone_from(&self.fusion);
                spare
            }
            None => self.fusion.clone(),
        }
    }

    /// Process a made-up wheel sample (1 ms after the last, driving straight
    /// on, with a fix and a heading where the filter is) on a copy of the
    /// filter, and return its pose; the filter is left as it was. Run
    /// shortly before a wheel sample is due, it brings the step's code and
    /// data into the caches after a sleep, so that the sample's own step
    /// does not wait for them (`odometry serve --early-wakeup-ms`). `None`
    /// before the first wheel sample.
    pub fn rehearse(&mut self) -> Option<FusedPose> {
        let mut copy = self.copy_of_filter();
        let pose = copy.rehearse_wheel_sample();
        self.spare.push(copy);
        pose
    }

    /// Drop the checkpoints (and the inputs before them) that the window no
    /// longer needs: the oldest one kept is the newest at or before `t_s -
    /// window`.
    fn trim(&mut self, t_s: f64) {
        let horizon = t_s - self.config.window_s;
        while self.checkpoints.len() >= 2 && self.checkpoints[1].t_s <= horizon {
            if let Some(old) = self.checkpoints.pop_front() {
                self.spare.push(old.fusion);
            }
        }
        if let Some(first) = self.checkpoints.front() {
            let drop = (first.at.saturating_sub(self.log_start) as usize).min(self.log.len());
            if drop > 0 {
                self.log.drain(..drop);
                self.log_start += drop as u64;
                self.log_is_complete = false;
            }
        }
    }

    /// Put the late `input` into the log at its place and process the log
    /// again from the newest checkpoint before it. `None` when the window
    /// does not reach back that far.
    fn rewind(&mut self, input: &Input) -> Option<Result<Option<FusedPose>, ProcessError>> {
        let k = key(input)?;
        // After the last logged sample that comes before it (estimates stay
        // where they arrived). With none, first if the log holds every input
        // so far; else it may be older than inputs already dropped: too late.
        let place = match self
            .log
            .iter()
            .rposition(|logged| key(logged).is_some_and(|lk| !before(k, lk)))
        {
            Some(i) => i + 1,
            None if self.log_is_complete => 0,
            None => return None,
        };
        let at = self.log_start + place as u64;
        let cp = self.checkpoints.iter().rposition(|c| c.at <= at)?;
        while self.checkpoints.len() > cp + 1 {
            if let Some(later) = self.checkpoints.pop_back() {
                self.spare.push(later.fusion);
            }
        }
        let restored = self.checkpoints.pop_back()?;
        self.stats.rewinds += 1;
        self.fusion.clone_from(&restored.fusion);
        self.spare.push(restored.fusion);
        self.log.insert(place, *input);
        // Process the log again from the checkpoint; the checkpoints on the
        // way are taken anew, where they were taken the first time.
        let start = (restored.at - self.log_start) as usize;
        let mut again = std::mem::take(&mut self.again);
        again.clear();
        again.extend(self.log.drain(start..));
        let newest = self.newest;
        let mut own = Ok(None);
        for (i, logged) in again.iter().enumerate() {
            let result = self.take_in_order(logged);
            if start + i == place {
                own = result.map(|_| None);
            }
        }
        // The late sample itself is not processed "again".
        self.stats.reprocessed += again.len() as u64 - 1;
        self.again = again;
        // The newest key is what it was: the late sample is older.
        self.newest = newest;
        Some(own)
    }

    /// Forget the log and the checkpoints.
    fn forget(&mut self) {
        self.log_start += self.log.len() as u64;
        self.log_is_complete = true;
        self.log.clear();
        while let Some(c) = self.checkpoints.pop_back() {
            self.spare.push(c.fusion);
        }
        self.newest = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fusion::FusionConfig;
    use interfaces::wire::PoseMode;
    use vehicle_model::estimate::{Estimate, OdometryParams};
    use vehicle_model::two_wheel::{Pose2, TwoWheelParams};

    use crate::test_drive::{C, TRACK};

    fn params(c: f64) -> OdometryParams {
        OdometryParams {
            two_wheel: TwoWheelParams {
                c_rl: c,
                c_rr: c,
                track_width: TRACK,
            },
            gyro_bias_rad_s: 0.0,
            gyro_scale: 0.0,
        }
    }

    fn fusion() -> Fusion {
        Fusion::new(params(C), 1, FusionConfig::default())
    }

    /// A drive at 15 m/s on a weaving road: wheels and gyro at 100 Hz, fixes
    /// at 5 Hz with a few centimetres of error (so that every fix moves the
    /// filter). Inputs in processing order, and the true positions.
    fn drive(seconds: f64) -> (Vec<Input>, Vec<(f64, Pose2)>) {
        let curve = crate::test_drive::Curve {
            seconds,
            speed_m_s: 15.0,
            yaw_rate: |t| 0.15 * (0.4 * t).sin(),
            start: Pose2::default(),
            gyro_bias: 0.0,
            fix_offset_s: 0.0,
            fix_error_m: 0.03,
            fix_sigma_m: 0.05,
        };
        crate::test_drive::simulate(&curve, &|_| true)
    }

    /// The order the inputs arrive in when each is delivered `late(input)`
    /// seconds after its time: by delivery time, ties in processing order.
    fn arrival(inputs: &[Input], late: impl Fn(&Input) -> f64) -> Vec<Input> {
        let mut out = inputs.to_vec();
        crate::inputs::sort_by_delivery(&mut out, late);
        out
    }

    /// Fixes `gnss_s` late; every seventh gyro sample 30 ms late (jitter).
    fn late_fixes(gnss_s: f64) -> impl Fn(&Input) -> f64 {
        move |i: &Input| match *i {
            Input::Gnss { .. } => gnss_s,
            Input::Imu { t_s, .. } if (t_s / 0.01).round() as i64 % 7 == 3 => 0.03,
            _ => 0.0,
        }
    }

    fn poses(f: &mut impl FnMut(&Input) -> Option<FusedPose>, inputs: &[Input]) -> Vec<FusedPose> {
        inputs.iter().filter_map(f).collect()
    }

    fn in_order_poses(inputs: &[Input]) -> (Vec<FusedPose>, Fusion) {
        let mut f = fusion();
        let out = poses(&mut |i| f.process(i).expect("in order"), inputs);
        (out, f)
    }

    #[test]
    fn late_fixes_and_gyro_samples_give_the_in_order_poses_bit_for_bit() {
        let (inputs, _) = drive(30.0);
        let (reference, in_order) = in_order_poses(&inputs);
        let late = late_fixes(0.15);
        let arrived = arrival(&inputs, &late);
        // A wheel pose is complete when every sample up to its time had
        // arrived before its wheel sample: the latest delivery among the
        // inputs up to it (in processing order) is its own.
        let mut complete = Vec::new();
        let mut latest_delivery = f64::NEG_INFINITY;
        for input in &inputs {
            let delivery = input.t_s() + late(input);
            if let Input::Wheels { .. } = input {
                complete.push(latest_delivery <= delivery);
            }
            latest_delivery = latest_delivery.max(delivery);
        }
        let mut rewinding = RewindingFusion::new(fusion(), RewindConfig::default());
        let out = poses(
            &mut |i| rewinding.process(i).expect("every sample is usable"),
            &arrived,
        );
        assert_eq!(out.len(), reference.len());
        let n_complete = complete.iter().filter(|c| **c).count();
        // With fixes 0.15 s late at 5 Hz, a quarter of the poses come after
        // every sample of their time, fewer with the gyro's jitter; the
        // others lack a fix or a gyro sample.
        assert!(n_complete > reference.len() / 8, "{n_complete} complete");
        let mut differing_incomplete = 0;
        for ((got, want), c) in out.iter().zip(&reference).zip(&complete) {
            if *c {
                assert_eq!(got, want, "pose at t = {} s", want.t_s);
            } else if got != want {
                differing_incomplete += 1;
            }
        }
        // The others really were computed without the late samples.
        assert!(differing_incomplete > 100, "{differing_incomplete}");
        assert_eq!(rewinding.fusion().stats(), in_order.stats());
        let stats = rewinding.stats();
        assert_eq!(stats.beyond_window, 0);
        // Every late sample (151 fixes, 429 gyro samples) went back once.
        let late_samples = inputs.iter().filter(|i| late(i) > 0.0).count();
        assert_eq!(stats.rewinds, late_samples as u64, "{stats:?}");
        // The log holds about the window, not the drive.
        assert!(rewinding.logged() < 300, "{}", rewinding.logged());
    }

    #[test]
    fn a_rehearsal_before_each_wheel_sample_changes_no_pose() {
        let (inputs, _) = drive(30.0);
        // Late fixes, so that the rehearsals' copies share the spare
        // filters with checkpoints and rewinds.
        let arrived = arrival(&inputs, late_fixes(0.15));
        let mut plain = RewindingFusion::new(fusion(), RewindConfig::default());
        let mut rehearsing = RewindingFusion::new(fusion(), RewindConfig::default());
        let (mut rehearsals, mut wheel_samples, mut moving) = (0, 0, 0);
        let mut last_pose: Option<FusedPose> = None;
        let mut rewinds_at_last = 0;
        for input in &arrived {
            if let Input::Wheels { t_s, .. } = *input {
                wheel_samples += 1;
                if let Some(rehearsed) = rehearsing.rehearse() {
                    rehearsals += 1;
                    // The made-up sample: 1 ms after the last, a thousandth
                    // of a turn further on both wheels (the made-up fix, 1 ms
                    // behind, pulls it back by under a percent).
                    let last = last_pose.expect("a pose before");
                    assert!((rehearsed.t_s - (last.t_s + 1e-3)).abs() < 1e-9);
                    assert!(rehearsed.t_s < t_s);
                    // (A rewind since that pose has moved the filter.)
                    if last.mode != PoseMode::NoFix && rewinds_at_last == rehearsing.stats().rewinds
                    {
                        let moved =
                            (rehearsed.pose.x - last.pose.x).hypot(rehearsed.pose.y - last.pose.y);
                        assert!((moved / (1e-3 * C) - 1.0).abs() < 0.02, "moved {moved} m");
                        moving += 1;
                    }
                }
            }
            let want = plain.process(input).expect("usable");
            let got = rehearsing.process(input).expect("usable");
            assert_eq!(got, want);
            if got.is_some() {
                last_pose = got;
                rewinds_at_last = rehearsing.stats().rewinds;
            }
        }
        assert_eq!(rehearsals, wheel_samples - 1);
        assert!(moving > rehearsals * 3 / 4, "{moving} of {rehearsals}");
        assert_eq!(rehearsing.fusion().stats(), plain.fusion().stats());
        assert_eq!(rehearsing.stats(), plain.stats());
        assert!(plain.stats().rewinds > 100, "{:?}", plain.stats());
    }

    #[test]
    fn without_going_back_late_fixes_pull_the_pose_back() {
        let (inputs, truth) = drive(30.0);
        let arrived = arrival(&inputs, late_fixes(0.15));
        let error = |poses: &[FusedPose]| {
            let mut e: Vec<f64> = poses
                .iter()
                .filter(|p| p.t_s > 5.0)
                .map(|p| {
                    let i = (p.t_s / 0.01).round() as usize;
                    let t = truth[i].1;
                    (p.pose.x - t.x).hypot(p.pose.y - t.y)
                })
                .collect();
            e.sort_by(f64::total_cmp);
            e[e.len() / 2]
        };
        let mut plain = fusion();
        let plain_poses = poses(&mut |i| plain.process(i).ok().flatten(), &arrived);
        let mut rewinding = RewindingFusion::new(fusion(), RewindConfig::default());
        let rewound = poses(&mut |i| rewinding.process(i).expect("usable"), &arrived);
        let (plain_m, rewound_m) = (error(&plain_poses), error(&rewound));
        eprintln!("median error: applied on arrival {plain_m:.3} m, going back {rewound_m:.3} m");
        // 0.15 s at 15 m/s is 2.25 m: each fix applied on arrival is that far
        // behind the car.
        assert!(plain_m > 1.0, "plain {plain_m:.3} m");
        assert!(rewound_m < 0.05, "rewinding {rewound_m:.3} m");
    }

    #[test]
    fn a_sample_older_than_the_window_goes_to_the_filter_as_it_came() {
        let (inputs, _) = drive(5.0);
        let arrived = arrival(&inputs, crate::inputs::gnss_late(0.5));
        let config = RewindConfig {
            window_s: 0.3,
            ..RewindConfig::default()
        };
        let mut rewinding = RewindingFusion::new(fusion(), config);
        let mut plain = fusion();
        // Up to the last wheel sample (after it, nothing is too old).
        let last_wheel = arrived
            .iter()
            .rposition(|i| matches!(i, Input::Wheels { .. }))
            .expect("wheels");
        let arrived = &arrived[..=last_wheel];
        for input in arrived {
            let got = rewinding.process(input).ok().flatten();
            assert_eq!(got, plain.process(input).ok().flatten());
        }
        let stats = rewinding.stats();
        assert_eq!(stats.rewinds, 0);
        let fixes = arrived
            .iter()
            .filter(|i| matches!(i, Input::Gnss { .. }))
            .count();
        assert_eq!(stats.beyond_window, fixes as u64, "{stats:?}");
        assert_eq!(rewinding.fusion().stats(), plain.stats());
    }

    #[test]
    fn an_estimate_stays_where_it_arrived_and_a_change_outside_forgets_the_log() {
        let (inputs, _) = drive(6.0);
        let arrived = arrival(&inputs, late_fixes(0.15));
        let estimate = Input::Estimate {
            t_s: 3.0,
            version: 2,
            estimate: Estimate {
                params: params(2.01),
                sigma_m: None,
                quality_m: None,
                antenna_m: None,
                antenna_sigma_m: None,
                effects: vehicle_model::effects::WheelEffects::default(),
                clocks: Default::default(),
            },
        };
        // The estimate arrives right after the wheel sample of 3.0 s; the fix
        // of 2.9 s comes later and is taken before it.
        let at = arrived
            .iter()
            .position(|i| matches!(i, Input::Wheels { t_s, .. } if *t_s >= 3.0))
            .expect("a wheel sample at 3 s");
        let mut with_estimate = arrived.clone();
        with_estimate.insert(at + 1, estimate);
        let mut rewinding = RewindingFusion::new(fusion(), RewindConfig::default());
        for input in &with_estimate {
            rewinding.process(input).expect("usable");
        }
        assert!(rewinding.stats().rewinds > 0);
        assert_eq!(rewinding.fusion().estimate_version(), 2);
        assert_eq!(rewinding.fusion().params().two_wheel.c_rl, 2.01);
        assert!(rewinding.logged() > 0);
        rewinding.fusion_mut().reset();
        assert_eq!(rewinding.logged(), 0);
    }
}
