//! Whether a pose kept by an earlier run may be started from, and with what
//! uncertainty: a restart never lies.
//!
//! `odometry serve --pose-state FILE` keeps its last pose together with what
//! it takes to tell, at the next start, whether the car moved since: the
//! rear wheels' revolution counts and the drive time at the pose, the speed
//! there, how often the file is written, and whether it was the service's
//! last word (a clean stop) or a periodic write that a crash or a power loss
//! may have overtaken. [`judge_restart`] takes that record and the first
//! wheel sample of the new run and decides:
//!
//! - **The wheel stream went on** (the odometry alone restarted: the first
//!   sample's time is not before the kept pose's): the counts since the pose
//!   say how far each rear wheel turned. The yaw changed by their difference
//!   over the track (the 2W model's heading, whatever the path), and the
//!   position moved by the arc's chord; the chord assumes a constant
//!   curvature, so the position variance grows by `(distance / 2)^2` per axis
//!   (an error up to the distance itself stays inside 2 sigma) and the yaw's
//!   by the wheel heading's noise. Over a long gap the wheel heading, and
//!   with it the chord's direction, is not known (beyond
//!   [`RestartConfig::chord_yaw_known_rad`]): a chord the wrong way would
//!   be up to twice the distance off, so the kept position stays the centre
//!   and the distance the doubt. Counts that imply a speed beyond any car
//!   are a counter reset or another source: refused.
//! - **The clock went back but the counters went on** (the new run's clock
//!   is earlier than the kept pose's, the bridge or the car restarted its
//!   clock but not its counters): the counts are compared all the same. Time
//!   cannot bound the distance, so no speed check: the counts say how far
//!   the car went (hundreds of revolutions are hundreds of metres, not a
//!   parked car), and the pose is carried over as above with the doubt of
//!   the path in its covariance. Counts that went down by more than
//!   [`RestartConfig::max_reverse_m`] are no counter that went on nor one
//!   that started over: refused.
//! - **The stream started over** (time back, and the counters restarted from
//!   about zero, within [`RestartConfig::restarted_counter_m`], or the file
//!   does not keep the counts): the counts cannot be compared. A pose kept at a
//!   standstill is used: as it is when it was the service's last word, and
//!   widened by how far a car starting off could have gone before the next
//!   periodic write when it was not. A pose kept while the car moved, or one
//!   from a file that does not say, is refused with the reason.
//! - **A kept pose no car can have** (a coordinate beyond
//!   [`RestartConfig::max_coordinate_m`], a covariance that is not finite,
//!   not symmetric or not positive definite, counts or a speed that are not
//!   finite) is refused with the reason, whatever the wheels say.
//!
//! What no record can tell: a car moved while powered off (towed, on a
//! ferry) that powers on where no GNSS reaches. With GNSS, three fixes that
//! disagree with a resumed pose start the filter again from the fixes
//! (`fusion`, `Fusion::resume`).
//!
//! Pure: numbers in, a decision out.

use vehicle_model::two_wheel::{step, wrap_angle, Pose2, TwoWheelParams};

/// The rear wheels' cumulative revolutions at a time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelMark {
    /// Drive time, s.
    pub t_s: f64,
    /// Rear-left cumulative revolutions.
    pub rl_rev: f64,
    /// Rear-right cumulative revolutions.
    pub rr_rev: f64,
}

impl WheelMark {
    /// Speed of the rear-axle centre between `earlier` and `self`, m/s
    /// (signed: negative when reversing); `None` without a time step.
    pub fn speed_since(&self, earlier: &WheelMark, params: &TwoWheelParams) -> Option<f64> {
        let dt = self.t_s - earlier.t_s;
        if !(dt > 0.0 && dt.is_finite()) {
            return None;
        }
        let (ds, _) = params.increments(self.rl_rev - earlier.rl_rev, self.rr_rev - earlier.rr_rev);
        let v = ds / dt;
        v.is_finite().then_some(v)
    }
}

/// A kept pose and what it takes to judge it at a restart.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KeptRecord {
    /// The pose (rear-axle centre, ENU, yaw).
    pub pose: Pose2,
    /// Covariance of (x, y, yaw), row-major.
    pub covariance: [f64; 9],
    /// The wheel counts and drive time at the pose; `None` in a file
    /// written before they were kept.
    pub wheels: Option<WheelMark>,
    /// Speed at the pose, m/s; `None` when not known.
    pub speed_m_s: Option<f64>,
    /// Written when the service stopped (a clean stop or stale inputs), not
    /// by a periodic write.
    pub last_word: bool,
    /// How often the service writes the file while it runs, s.
    pub write_every_s: f64,
}

/// Limits of the judgement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RestartConfig {
    /// Below this speed the car stood still, m/s.
    pub standstill_m_s: f64,
    /// No car drives faster: wheel counts implying more are not the same
    /// counters, m/s.
    pub max_speed_m_s: f64,
    /// The strongest acceleration from a standstill, m/s^2: how far a car
    /// can have gone between a periodic write at a standstill and a crash.
    pub max_accel_m_s2: f64,
    /// Yaw 1-sigma of the wheel heading per metre of the gap, rad/m.
    pub yaw_sigma_per_m: f64,
    /// Yaw 1-sigma as a fraction of the wheel heading's change over the
    /// gap (track width and slip errors scale with it).
    pub yaw_sigma_per_rad: f64,
    /// A counter within this distance of zero at the first sample of a run
    /// whose clock went back has started over with its stream, m: a car
    /// that starts off when its stream does is a few metres from where the
    /// counting began by the time the odometry sees the first sample.
    pub restarted_counter_m: f64,
    /// The farthest a car reverses, m: counts that went down by more, under
    /// a clock that went back, are not the same counters.
    pub max_reverse_m: f64,
    /// The largest |x| or |y| of a kept pose, m: the local ENU frame of a
    /// drive is anchored near it, and no point on Earth is farther than half
    /// its circumference (2.0e7 m) from the anchor along the surface.
    pub max_coordinate_m: f64,
    /// The wheel heading's 1-sigma over a gap up to which the chord of the
    /// arc gives the direction the car went, rad; beyond it the kept
    /// position is carried over with the distance as its doubt.
    pub chord_yaw_known_rad: f64,
}

impl Default for RestartConfig {
    fn default() -> Self {
        RestartConfig {
            standstill_m_s: 0.05,
            max_speed_m_s: 70.0,
            max_accel_m_s2: 5.0,
            yaw_sigma_per_m: 0.003,
            yaw_sigma_per_rad: 0.05,
            restarted_counter_m: 10.0,
            max_reverse_m: 100.0,
            max_coordinate_m: 2.0e7,
            chord_yaw_known_rad: 0.5,
        }
    }
}

/// What to start from.
#[derive(Debug, Clone, PartialEq)]
pub enum Restart {
    /// Start from this pose with this covariance (x, y, yaw row-major).
    Resume {
        /// The pose at the first wheel sample of the new run.
        pose: Pose2,
        /// Its covariance.
        covariance: [f64; 9],
        /// How far the wheels say the car went since the kept pose, m.
        moved_m: f64,
        /// Why the pose is trusted this far, for the log.
        why: String,
    },
    /// Do not start from the kept pose (`NoFix` until GNSS).
    Refuse {
        /// Why, for the log.
        why: String,
    },
}

/// Judge a kept pose against the first wheel sample of the new run (see the
/// module docs).
pub fn judge_restart(
    kept: &KeptRecord,
    first: &WheelMark,
    params: &TwoWheelParams,
    config: &RestartConfig,
) -> Restart {
    if let Err(why) = plausible(kept, config) {
        return Restart::Refuse { why };
    }
    match kept.wheels {
        Some(mark) if first.t_s >= mark.t_s => bridge(kept, &mark, first, params, config, true),
        Some(mark) => clock_back(kept, &mark, first, params, config),
        None => started_over(kept, config),
    }
}

/// Whether the kept record is one a car can have: finite numbers, a position
/// on Earth, a covariance that is a covariance.
fn plausible(kept: &KeptRecord, config: &RestartConfig) -> Result<(), String> {
    let finite = [kept.pose.x, kept.pose.y, kept.pose.yaw]
        .iter()
        .chain(&kept.covariance)
        .all(|v| v.is_finite());
    if !finite {
        return Err("the kept pose is not finite".into());
    }
    let limit = config.max_coordinate_m;
    if kept.pose.x.abs() > limit || kept.pose.y.abs() > limit {
        return Err(format!(
            "the kept pose ({:.3e}, {:.3e}) m lies beyond {limit:.1e} m of the frame's origin: \
             no place on Earth",
            kept.pose.x, kept.pose.y
        ));
    }
    let c = &kept.covariance;
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        let (a, b) = (c[3 * i + j], c[3 * j + i]);
        if (a - b).abs() > 1e-9 * (c[4 * i] * c[4 * j]).sqrt().max(f64::MIN_POSITIVE) {
            return Err(format!(
                "the kept covariance is not symmetric: [{i}][{j}] = {a:e}, [{j}][{i}] = {b:e}"
            ));
        }
    }
    let m = nalgebra::Matrix3::from_row_slice(c);
    if m.cholesky().is_none() {
        return Err(format!(
            "the kept covariance is not positive definite (diagonal {:e}, {:e}, {:e})",
            c[0], c[4], c[8]
        ));
    }
    if let Some(w) = kept.wheels {
        if !(w.t_s.is_finite() && w.rl_rev.is_finite() && w.rr_rev.is_finite()) {
            return Err("the kept wheel counts or their time are not finite".into());
        }
    }
    if kept.speed_m_s.is_some_and(|v| !v.is_finite()) {
        return Err("the kept speed is not finite".into());
    }
    if !(kept.write_every_s.is_finite() && kept.write_every_s > 0.0) {
        return Err(format!(
            "the kept write interval {} s is not a positive number",
            kept.write_every_s
        ));
    }
    Ok(())
}

/// The new run's clock is earlier than the kept pose's: compare the counts
/// unless they started over from about zero.
fn clock_back(
    kept: &KeptRecord,
    mark: &WheelMark,
    first: &WheelMark,
    params: &TwoWheelParams,
    config: &RestartConfig,
) -> Restart {
    let near_zero = |rl: f64, rr: f64| {
        (rl * params.c_rl).abs() <= config.restarted_counter_m
            && (rr * params.c_rr).abs() <= config.restarted_counter_m
    };
    if near_zero(first.rl_rev, first.rr_rev) && !near_zero(mark.rl_rev, mark.rr_rev) {
        return started_over(kept, config);
    }
    let (d_l, d_r) = (
        (first.rl_rev - mark.rl_rev) * params.c_rl,
        (first.rr_rev - mark.rr_rev) * params.c_rr,
    );
    if d_l.min(d_r) < -config.max_reverse_m {
        return Restart::Refuse {
            why: format!(
                "the clock went back {:.2} s and the wheel counts went down by {:.1} / {:.1} \
                 revolutions since the kept pose: neither the same counters nor ones that \
                 started over",
                mark.t_s - first.t_s,
                mark.rl_rev - first.rl_rev,
                mark.rr_rev - first.rr_rev
            ),
        };
    }
    match bridge(kept, mark, first, params, config, false) {
        Restart::Resume {
            pose,
            covariance,
            moved_m,
            ..
        } => Restart::Resume {
            pose,
            covariance,
            moved_m,
            why: format!(
                "the clock went back {:.2} s but the wheel counts went on: {moved_m:.2} m \
                 driven since the kept pose, carried over with the wheel counts",
                mark.t_s - first.t_s
            ),
        },
        refused => refused,
    }
}

/// The wheel counts went on: carry the pose over the gap with them (with
/// `time_bound`, counts beyond any car in the time between are refused).
fn bridge(
    kept: &KeptRecord,
    mark: &WheelMark,
    first: &WheelMark,
    params: &TwoWheelParams,
    config: &RestartConfig,
    time_bound: bool,
) -> Restart {
    let (dn_l, dn_r) = (first.rl_rev - mark.rl_rev, first.rr_rev - mark.rr_rev);
    let (d_l, d_r) = (dn_l * params.c_rl, dn_r * params.c_rr);
    let longest = d_l.abs().max(d_r.abs());
    let dt = first.t_s - mark.t_s;
    // Half a second of slack for the time stamps of two samples.
    let reach = if time_bound {
        config.max_speed_m_s * (dt + 0.5)
    } else {
        f64::INFINITY
    };
    if !longest.is_finite() || longest > reach {
        return Restart::Refuse {
            why: format!(
                "the wheel counts moved by {dn_l:.1} / {dn_r:.1} revolutions in {dt:.2} s \
                 since the kept pose, beyond any car: not the same counters"
            ),
        };
    }
    let (ds, dyaw) = params.increments(dn_l, dn_r);
    // The chord of an arc of length ds turning by dyaw.
    let half = 0.5 * dyaw;
    let chord = if half.abs() < 1e-6 {
        ds
    } else {
        ds * half.sin() / half
    };
    let yaw_sigma = config.yaw_sigma_per_m * longest + config.yaw_sigma_per_rad * dyaw.abs();
    let moved = step(kept.pose, chord, dyaw, 0.0);
    // The chord points where the wheel heading says; once that heading is
    // uncertain by more than `chord_yaw_known_rad`, so is the chord's
    // direction, and a chord the wrong way is up to twice the distance off.
    // The car is then anywhere within `longest` of the kept position: the
    // kept position is the centre, and (longest / 2)^2 per axis holds every
    // such place inside 2 sigma.
    let position = if yaw_sigma > config.chord_yaw_known_rad {
        (kept.pose.x, kept.pose.y)
    } else {
        (moved.x, moved.y)
    };
    let pose = Pose2 {
        x: position.0,
        y: position.1,
        yaw: wrap_angle(moved.yaw),
    };
    let mut covariance = kept.covariance;
    let position_var = (0.5 * longest).powi(2);
    covariance[0] += position_var;
    covariance[4] += position_var;
    covariance[8] += yaw_sigma * yaw_sigma;
    Restart::Resume {
        pose,
        covariance,
        moved_m: longest,
        why: format!(
            "the wheel stream went on: {longest:.2} m driven and {:.1} deg turned in the \
             {dt:.2} s since the kept pose, carried over with the wheel counts",
            dyaw.to_degrees()
        ),
    }
}

/// The stream started over: only a pose kept at a standstill is used.
fn started_over(kept: &KeptRecord, config: &RestartConfig) -> Restart {
    let Some(speed) = kept.speed_m_s else {
        return Restart::Refuse {
            why: "the wheel counts started over and the kept pose does not say whether the \
                  car stood still there (a file from an older version)"
                .into(),
        };
    };
    if speed.is_nan() || speed.abs() > config.standstill_m_s {
        return Restart::Refuse {
            why: format!(
                "the kept pose was taken at {speed:.1} m/s and the wheel counts started over: \
                 how far the car went since cannot be told"
            ),
        };
    }
    let mut covariance = kept.covariance;
    let (moved, why) = if kept.last_word {
        (
            0.0,
            "parked: kept at a standstill when the service stopped".to_string(),
        )
    } else {
        // A periodic write at a standstill; the car may have started off
        // before the next one was due.
        let reach = 0.5 * config.max_accel_m_s2 * kept.write_every_s.powi(2);
        (
            reach,
            format!(
                "kept at a standstill by a periodic write (the service did not stop cleanly): \
                 up to {reach:.1} m may have been driven before the next write"
            ),
        )
    };
    covariance[0] += moved * moved;
    covariance[4] += moved * moved;
    Restart::Resume {
        pose: kept.pose,
        covariance,
        moved_m: moved,
        why,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> TwoWheelParams {
        TwoWheelParams {
            c_rl: 2.0,
            c_rr: 2.0,
            track_width: 1.6,
        }
    }

    fn kept(wheels: Option<WheelMark>, speed: Option<f64>, last_word: bool) -> KeptRecord {
        KeptRecord {
            pose: Pose2 {
                x: 100.0,
                y: 50.0,
                yaw: 0.0,
            },
            covariance: [0.01, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 1e-4],
            wheels,
            speed_m_s: speed,
            last_word,
            write_every_s: 1.0,
        }
    }

    fn mark(t_s: f64, rl_rev: f64, rr_rev: f64) -> WheelMark {
        WheelMark {
            t_s,
            rl_rev,
            rr_rev,
        }
    }

    #[test]
    fn a_long_unseen_drive_keeps_the_kept_position_as_the_centre_of_its_doubt() {
        // 2 km under a clock that went back, turning one and a half times
        // round (the wheel heading over 2 km is not known to a radian): a
        // chord along that heading may point anywhere. Every place within
        // 2 km of the kept position, wherever the path went, must lie
        // inside 2 sigma of the carried pose.
        let p = params();
        let turns = 1.5 * std::f64::consts::TAU;
        let ds = 2000.0;
        let (d_l, d_r) = (
            ds - 0.5 * p.track_width * turns,
            ds + 0.5 * p.track_width * turns,
        );
        let kept = kept(Some(mark(500.0, 1000.0, 1000.0)), Some(20.0), true);
        let first = mark(3.0, 1000.0 + d_l / p.c_rl, 1000.0 + d_r / p.c_rr);
        let Restart::Resume {
            pose, covariance, ..
        } = judge_restart(&kept, &first, &p, &RestartConfig::default())
        else {
            panic!("a counter that went on is carried over");
        };
        assert_eq!((pose.x, pose.y), (kept.pose.x, kept.pose.y));
        let sigma = covariance[0].sqrt().min(covariance[4].sqrt());
        for k in 0..16 {
            let a = k as f64 * std::f64::consts::TAU / 16.0;
            let (x, y) = (kept.pose.x + d_r * a.cos(), kept.pose.y + d_r * a.sin());
            let err = (x - pose.x).hypot(y - pose.y);
            assert!(err <= 2.0 * sigma + 1e-9, "{err} m against sigma {sigma} m");
        }
    }

    #[test]
    fn a_stream_that_went_on_carries_the_pose_over_the_gap_honestly() {
        // Kept at t = 10 s, 500 revolutions; the new run's first sample is
        // 2.5 s later after a quarter circle of radius 20 m (31.4 m at the
        // centre), left turn.
        let (r, b) = (20.0, 1.6);
        let arc = 0.5 * std::f64::consts::PI * r;
        let (d_l, d_r) = (
            0.5 * std::f64::consts::PI * (r - b / 2.0),
            0.5 * std::f64::consts::PI * (r + b / 2.0),
        );
        let k = kept(Some(mark(10.0, 500.0, 500.0)), Some(12.0), false);
        let first = mark(12.5, 500.0 + d_l / 2.0, 500.0 + d_r / 2.0);
        let Restart::Resume {
            pose,
            covariance,
            moved_m,
            ..
        } = judge_restart(&k, &first, &params(), &RestartConfig::default())
        else {
            panic!("resumed")
        };
        // Truth: the quarter circle ends at (+r, +r) facing north.
        let truth = (100.0 + r, 50.0 + r, std::f64::consts::FRAC_PI_2);
        let error = (pose.x - truth.0).hypot(pose.y - truth.1);
        assert!(error < 1e-6, "a constant-curvature arc is exact: {error}");
        assert!((pose.yaw - truth.2).abs() < 1e-9);
        assert!((moved_m - d_r).abs() < 1e-9 && moved_m > arc);
        // The covariance says the path could have been another: half the
        // distance per axis, and the yaw by its change and the distance.
        assert!((covariance[0] - 0.01 - (0.5 * d_r).powi(2)).abs() < 1e-9);
        let yaw_sigma = (covariance[8] - 1e-4).sqrt();
        assert!(
            yaw_sigma > 0.05 * std::f64::consts::FRAC_PI_2,
            "{yaw_sigma}"
        );

        // A straight gap of 30 m along an S-curve that ends 3 m aside: the
        // error lies inside the ellipse's 3 sigma.
        let straight = mark(12.5, 515.0, 515.0);
        let Restart::Resume {
            pose, covariance, ..
        } = judge_restart(&k, &straight, &params(), &RestartConfig::default())
        else {
            panic!("resumed")
        };
        assert!((pose.x - 130.0).abs() < 1e-9 && (pose.y - 50.0).abs() < 1e-9);
        let s_curve_end = (129.8, 53.0);
        let e = (pose.x - s_curve_end.0).hypot(pose.y - s_curve_end.1);
        assert!(e < 3.0 * covariance[4].sqrt());
        // Not moved at all: the pose as kept.
        let still = judge_restart(
            &k,
            &mark(11.0, 500.0, 500.0),
            &params(),
            &RestartConfig::default(),
        );
        assert!(matches!(still, Restart::Resume { moved_m, covariance, .. }
            if moved_m == 0.0 && covariance == k.covariance));
    }

    #[test]
    fn counts_beyond_any_car_or_a_restarted_stream_while_moving_are_refused() {
        let k = kept(Some(mark(10.0, 500.0, 500.0)), Some(12.0), false);
        // 1000 revolutions in 1 s is 2 km/s.
        let jump = judge_restart(
            &k,
            &mark(11.0, 1500.0, 1500.0),
            &params(),
            &RestartConfig::default(),
        );
        assert!(matches!(&jump, Restart::Refuse { why } if why.contains("beyond any car")));
        // Counters reset (time back): the pose was kept while moving.
        let over = judge_restart(
            &k,
            &mark(0.0, 0.0, 0.0),
            &params(),
            &RestartConfig::default(),
        );
        assert!(matches!(&over, Restart::Refuse { why } if why.contains("12.0 m/s")));
        // An old file says nothing of the speed.
        let old = kept(None, None, true);
        assert!(matches!(
            judge_restart(
                &old,
                &mark(0.0, 0.0, 0.0),
                &params(),
                &RestartConfig::default()
            ),
            Restart::Refuse { .. }
        ));
        // Not finite.
        let mut nan = kept(None, Some(0.0), true);
        nan.pose.x = f64::NAN;
        assert!(matches!(
            judge_restart(
                &nan,
                &mark(0.0, 0.0, 0.0),
                &params(),
                &RestartConfig::default()
            ),
            Restart::Refuse { .. }
        ));
    }

    #[test]
    fn a_parked_car_resumes_and_a_crash_while_parked_widens_the_pose() {
        let parked = kept(Some(mark(300.0, 900.0, 901.0)), Some(0.0), true);
        let first = mark(0.0, 0.0, 0.0);
        let config = RestartConfig::default();
        let Restart::Resume {
            pose, covariance, ..
        } = judge_restart(&parked, &first, &params(), &config)
        else {
            panic!("resumed")
        };
        assert_eq!((pose, covariance), (parked.pose, parked.covariance));
        // The same from a periodic write: a car may have started off within
        // the write interval (1 s at 5 m/s^2: 2.5 m).
        let crashed = KeptRecord {
            last_word: false,
            ..parked
        };
        let Restart::Resume {
            covariance,
            moved_m,
            ..
        } = judge_restart(&crashed, &first, &params(), &config)
        else {
            panic!("resumed")
        };
        assert_eq!(moved_m, 2.5);
        assert!((covariance[0] - parked.covariance[0] - 6.25).abs() < 1e-12);
    }

    #[test]
    fn a_clock_reset_compares_the_counts_when_they_went_on() {
        // Parked at t = 300 s with 900 / 901 revolutions, the service's last
        // word. The new run's clock starts over at 5 s, but the counters went
        // on: 388 revolutions (776 m) more. Not a parked car.
        let parked = kept(Some(mark(300.0, 900.0, 901.0)), Some(0.0), true);
        let config = RestartConfig::default();
        let moved = judge_restart(&parked, &mark(5.0, 1288.0, 1289.0), &params(), &config);
        let Restart::Resume {
            pose,
            covariance,
            moved_m,
            why,
        } = moved
        else {
            panic!("carried over: {moved:?}")
        };
        assert!((moved_m - 776.0).abs() < 1e-9, "{moved_m}");
        assert!(why.contains("clock went back"), "{why}");
        // Equal counts, but over 776 m the wheel heading is uncertain by
        // 2.3 rad (0.003 rad/m): which way the chord points is not known, so
        // the kept position is the centre and the covariance admits any path
        // of that length (half of it per axis, 1 sigma).
        assert!((pose.x - 100.0).abs() < 1e-6 && (pose.y - 50.0).abs() < 1e-6);
        assert!(covariance[0].sqrt() >= 0.5 * 776.0 && covariance[4].sqrt() >= 0.5 * 776.0);
        // The same counts, unmoved: the parked pose as it is.
        let still = judge_restart(&parked, &mark(5.0, 900.0, 901.0), &params(), &config);
        assert!(matches!(still, Restart::Resume { moved_m, covariance, .. }
            if moved_m == 0.0 && covariance == parked.covariance));
        // Counts that went down by hundreds of revolutions (neither on nor
        // from zero) are refused.
        let down = judge_restart(&parked, &mark(5.0, 512.0, 513.0), &params(), &config);
        assert!(
            matches!(&down, Restart::Refuse { why } if why.contains("went down by 388.0")),
            "{down:?}"
        );
        // Counters that started over from about zero: the parked rule.
        let zero = judge_restart(&parked, &mark(5.0, 1.0, 1.0), &params(), &config);
        assert!(
            matches!(zero, Restart::Resume { moved_m, .. } if moved_m == 0.0),
            "{zero:?}"
        );
    }

    #[test]
    fn a_kept_pose_no_car_can_have_is_refused_with_the_reason() {
        let config = RestartConfig::default();
        let first = mark(0.0, 0.0, 0.0);
        let good = kept(None, Some(0.0), true);
        assert!(matches!(
            judge_restart(&good, &first, &params(), &config),
            Restart::Resume { .. }
        ));
        let refused = |k: KeptRecord| match judge_restart(&k, &first, &params(), &config) {
            Restart::Refuse { why } => why,
            other => panic!("resumed from {k:?}: {other:?}"),
        };
        let mut far = good;
        far.pose.x = 1e300;
        assert!(refused(far).contains("no place on Earth"));
        let mut far_y = good;
        far_y.pose.y = -3.0e7;
        assert!(refused(far_y).contains("no place on Earth"));
        let mut negative = good;
        negative.covariance[4] = -0.01;
        assert!(refused(negative).contains("not positive definite"));
        let mut zero = good;
        zero.covariance = [0.0; 9];
        assert!(refused(zero).contains("not positive definite"));
        let mut skew = good;
        skew.covariance[1] = 0.005;
        assert!(refused(skew).contains("not symmetric"));
        let mut inf = good;
        inf.covariance[8] = f64::INFINITY;
        assert!(refused(inf).contains("not finite"));
        let mut counts = kept(Some(mark(10.0, f64::NAN, 1.0)), Some(0.0), true);
        assert!(refused(counts).contains("wheel counts"));
        counts.wheels = None;
        counts.write_every_s = 0.0;
        assert!(refused(counts).contains("write interval"));
    }

    #[test]
    fn speed_between_two_marks() {
        let a = mark(1.0, 10.0, 10.0);
        let b = mark(1.5, 12.0, 12.5);
        let v = b.speed_since(&a, &params()).expect("a time step");
        assert!((v - 0.5 * (4.0 + 5.0) / 0.5).abs() < 1e-12);
        assert_eq!(a.speed_since(&a, &params()), None);
    }
}
