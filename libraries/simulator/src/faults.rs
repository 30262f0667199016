//! Faults of real recordings, put into any drive (simulated or recorded):
//! sensor clocks that disagree or drift, GNSS that jumps or wanders, a drive
//! that starts with a standstill or a reversing manoeuvre, a stream that
//! starts late. The clean drive stays the reference a benchmark compares
//! against: a fault changes what the sensors report, never `truth.csv`
//! (a time shift moves a sensor's stamps, not the world).
//!
//! Pure: a drive in, a drive out; every random draw comes from the seed.
//!
//! ```no_run
//! use simulator::faults::{apply, Fault};
//! # let drive: interfaces::drive::Drive = unimplemented!();
//! let late = apply(&drive, &Fault::WheelClockShift { s: 1.0 }, 7).unwrap();
//! ```

use crate::SimError;
use interfaces::drive::{
    Drive, GnssSample, HeadingSample, ImuSample, TruthSample, WheelRevs, WheelSample, WheelUnit,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A sensor stream of a drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    /// `wheels.csv`.
    Wheels,
    /// `gnss.csv`.
    Gnss,
    /// `imu.csv`.
    Imu,
    /// `heading.csv`.
    Heading,
}

/// One fault of a real recording.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fault {
    /// Every wheel stamp later by `s` seconds (the wheels' logger runs late).
    WheelClockShift {
        /// Shift, s.
        s: f64,
    },
    /// Every IMU stamp later by `s` seconds.
    ImuClockShift {
        /// Shift, s.
        s: f64,
    },
    /// The wheels' clock runs fast by `ppm` parts per million against the
    /// others, from the drive's first wheel sample on.
    WheelClockDrift {
        /// Rate error, parts per million.
        ppm: f64,
    },
    /// `count` GNSS jumps at random times, each a constant offset of
    /// `min_m..max_m` in a random direction lasting `min_s..max_s` (an RTK
    /// receiver dropping to a float or DGPS fix). The reported sigma is left
    /// as it was: the receiver does not know.
    GnssJumps {
        /// Number of jumps.
        count: usize,
        /// Smallest offset, m.
        min_m: f64,
        /// Largest offset, m.
        max_m: f64,
        /// Shortest jump, s.
        min_s: f64,
        /// Longest jump, s.
        max_s: f64,
    },
    /// Consumer-grade GNSS: white noise plus a first-order Gauss-Markov
    /// error per axis, added to the fixes; the reported sigma becomes the
    /// combined 1-sigma where the drive reports one.
    ConsumerGnss {
        /// White noise per axis, m.
        white_m: f64,
        /// Gauss-Markov stationary sigma per axis, m.
        gm_m: f64,
        /// Gauss-Markov correlation time, s.
        tau_s: f64,
    },
    /// A standstill of `duration_s` before the drive: every sensor reports
    /// the car at rest at its start pose, with noise measured on the drive
    /// (a drive that starts moving gets a straight start from rest to its
    /// first speed at 1.5 m/s^2 after it, ending at its start pose).
    StandstillAtStart {
        /// Length, s.
        duration_s: f64,
        /// Rear-left circumference for the straight start, m.
        c_rl_m: f64,
        /// Rear-right circumference for the straight start, m.
        c_rr_m: f64,
    },
    /// Before the drive, the car backs up `distance_m` along its start
    /// heading and drives forward to its start pose again (straight,
    /// `speed_m_s` at most, 1 m/s^2), with noise measured on the drive. The
    /// wheels turn by the distance over `c_rl_m` / `c_rr_m`, the wheels'
    /// circumferences (the clean drive's calibration, or the simulator's).
    /// A drive that starts moving gets a straight start as for a standstill.
    ReversingAtStart {
        /// Distance backed up, m.
        distance_m: f64,
        /// Largest speed, m/s.
        speed_m_s: f64,
        /// Rear-left circumference, m.
        c_rl_m: f64,
        /// Rear-right circumference, m.
        c_rr_m: f64,
    },
    /// One stream starts `delay_s` later than the drive (its first samples
    /// are missing).
    LateStart {
        /// The stream.
        stream: Stream,
        /// Delay, s.
        delay_s: f64,
    },
}

impl Fault {
    /// A short name for tables.
    pub fn label(&self) -> String {
        match self {
            Fault::WheelClockShift { s } => format!("wheel clock {s:+.1} s"),
            Fault::ImuClockShift { s } => format!("IMU clock {s:+.1} s"),
            Fault::WheelClockDrift { ppm } => format!("wheel clock drift {ppm:+.0} ppm"),
            Fault::GnssJumps {
                count,
                min_m,
                max_m,
                min_s,
                max_s,
            } => format!("{count} GNSS jumps {min_m}-{max_m} m, {min_s}-{max_s} s"),
            Fault::ConsumerGnss {
                white_m,
                gm_m,
                tau_s,
            } => format!("consumer GNSS ({white_m} m white, {gm_m} m GM {tau_s} s)"),
            Fault::StandstillAtStart { duration_s, .. } => {
                format!("{:.0} min standstill at start", duration_s / 60.0)
            }
            Fault::ReversingAtStart { distance_m, .. } => {
                format!("reversing {distance_m:.0} m at start")
            }
            Fault::LateStart { stream, delay_s } => {
                format!("{stream:?} starts {delay_s:.0} s late")
            }
        }
    }

    /// The stream's clock offset against the GNSS this fault makes, in the
    /// calibrator's sign (a stream late by `s` has offset `+s` for the IMU;
    /// the GNSS is late by `-s` against wheels late by `s`), when it is a
    /// constant clock shift.
    pub fn applied_offset_s(&self) -> Option<(Stream, f64)> {
        match self {
            Fault::WheelClockShift { s } => Some((Stream::Wheels, *s)),
            Fault::ImuClockShift { s } => Some((Stream::Imu, *s)),
            _ => None,
        }
    }
}

/// The drive with `fault` put in; `seed` draws its random parts.
pub fn apply(drive: &Drive, fault: &Fault, seed: u64) -> Result<Drive, SimError> {
    let mut d = drive.clone();
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6661_756c_7473);
    match *fault {
        Fault::WheelClockShift { s } => {
            for w in &mut d.wheels.samples {
                w.t_s += s;
            }
        }
        Fault::ImuClockShift { s } => {
            for i in d.imu.iter_mut().flatten() {
                i.t_s += s;
            }
        }
        Fault::WheelClockDrift { ppm } => {
            let t0 = d.wheels.samples.first().map_or(0.0, |w| w.t_s);
            for w in &mut d.wheels.samples {
                w.t_s = t0 + (w.t_s - t0) * (1.0 + ppm * 1e-6);
            }
        }
        Fault::GnssJumps {
            count,
            min_m,
            max_m,
            min_s,
            max_s,
        } => gnss_jumps(&mut d, &mut rng, count, (min_m, max_m), (min_s, max_s))?,
        Fault::ConsumerGnss {
            white_m,
            gm_m,
            tau_s,
        } => consumer_gnss(&mut d, &mut rng, white_m, gm_m, tau_s)?,
        Fault::StandstillAtStart {
            duration_s,
            c_rl_m,
            c_rr_m,
        } => {
            let profile = Profile::standstill(duration_s)?;
            prepend(&mut d, &mut rng, &profile, (c_rl_m, c_rr_m))?;
        }
        Fault::ReversingAtStart {
            distance_m,
            speed_m_s,
            c_rl_m,
            c_rr_m,
        } => {
            let profile = Profile::reversing(distance_m, speed_m_s)?;
            prepend(&mut d, &mut rng, &profile, (c_rl_m, c_rr_m))?;
        }
        Fault::LateStart { stream, delay_s } => late_start(&mut d, stream, delay_s)?,
    }
    Ok(d)
}

fn invalid(what: impl Into<String>) -> SimError {
    SimError::InvalidConfig(what.into())
}

fn normal(sigma: f64) -> Result<Normal<f64>, SimError> {
    Normal::new(0.0, sigma.max(0.0)).map_err(|e| invalid(format!("noise sigma {sigma}: {e}")))
}

fn gnss_jumps(
    d: &mut Drive,
    rng: &mut ChaCha8Rng,
    count: usize,
    size_m: (f64, f64),
    length_s: (f64, f64),
) -> Result<(), SimError> {
    let fixes = d
        .gnss
        .as_mut()
        .filter(|g| g.len() >= 2)
        .ok_or_else(|| invalid("GNSS jumps: the drive has no GNSS"))?;
    if !(size_m.0 >= 0.0 && size_m.1 >= size_m.0 && length_s.0 > 0.0 && length_s.1 >= length_s.0) {
        return Err(invalid("GNSS jumps: bad size or length range"));
    }
    let (t0, t1) = (fixes[0].t_s, fixes[fixes.len() - 1].t_s);
    // Non-overlapping: each jump gets its own slot of the drive.
    let slot = (t1 - t0) / count.max(1) as f64;
    for k in 0..count {
        let len = rng.random_range(length_s.0..=length_s.1).min(0.8 * slot);
        let start = t0 + k as f64 * slot + rng.random_range(0.0..=(slot - len).max(0.0));
        let size = rng.random_range(size_m.0..=size_m.1);
        let dir = rng.random_range(0.0..std::f64::consts::TAU);
        for f in fixes
            .iter_mut()
            .filter(|f| f.t_s >= start && f.t_s < start + len)
        {
            f.x_m += size * dir.cos();
            f.y_m += size * dir.sin();
        }
    }
    Ok(())
}

fn consumer_gnss(
    d: &mut Drive,
    rng: &mut ChaCha8Rng,
    white_m: f64,
    gm_m: f64,
    tau_s: f64,
) -> Result<(), SimError> {
    if tau_s.is_nan() || tau_s <= 0.0 {
        return Err(invalid("consumer GNSS: tau must be positive"));
    }
    let fixes = d
        .gnss
        .as_mut()
        .filter(|g| !g.is_empty())
        .ok_or_else(|| invalid("consumer GNSS: the drive has no GNSS"))?;
    let white = normal(white_m)?;
    let unit = normal(1.0)?;
    let mut e = [gm_m * unit.sample(rng), gm_m * unit.sample(rng)];
    let mut t_prev = fixes[0].t_s;
    let combined = (white_m * white_m + gm_m * gm_m).sqrt();
    for f in fixes.iter_mut() {
        let a = (-(f.t_s - t_prev).max(0.0) / tau_s).exp();
        let q = gm_m * (1.0 - a * a).sqrt();
        for ei in &mut e {
            *ei = a * *ei + q * unit.sample(rng);
        }
        t_prev = f.t_s;
        f.x_m += e[0] + white.sample(rng);
        f.y_m += e[1] + white.sample(rng);
        if let Some(s) = f.sigma_m.as_mut() {
            *s = (*s * *s + combined * combined).sqrt();
        }
    }
    Ok(())
}

fn late_start(d: &mut Drive, stream: Stream, delay_s: f64) -> Result<(), SimError> {
    let start = d
        .wheels
        .samples
        .first()
        .map(|w| w.t_s)
        .ok_or_else(|| invalid("late start: the drive has no wheel samples"))?;
    let cut = start + delay_s;
    match stream {
        Stream::Wheels => d.wheels.samples.retain(|w| w.t_s >= cut),
        Stream::Gnss => d
            .gnss
            .as_mut()
            .ok_or_else(|| invalid("late start: no GNSS"))?
            .retain(|g| g.t_s >= cut),
        Stream::Imu => d
            .imu
            .as_mut()
            .ok_or_else(|| invalid("late start: no IMU"))?
            .retain(|i| i.t_s >= cut),
        Stream::Heading => d
            .heading
            .as_mut()
            .ok_or_else(|| invalid("late start: no heading"))?
            .retain(|h| h.t_s >= cut),
    }
    Ok(())
}

/// A straight motion along the start heading ending at rest at the start
/// pose: the signed distance from it, its speed and acceleration.
struct Profile {
    duration_s: f64,
    /// `(t from the profile's start, s, v, a)` at 1 ms.
    step: Vec<(f64, f64, f64, f64)>,
}

impl Profile {
    const DT: f64 = 0.001;

    fn standstill(duration_s: f64) -> Result<Profile, SimError> {
        if duration_s.is_nan() || duration_s <= 0.0 {
            return Err(invalid("standstill: duration must be positive"));
        }
        let n = (duration_s / Self::DT).ceil() as usize;
        Ok(Profile {
            duration_s,
            step: (0..=n)
                .map(|i| (i as f64 * Self::DT, 0.0, 0.0, 0.0))
                .collect(),
        })
    }

    /// Rest 2 s, back up `distance` (trapezoidal speed, 1 m/s^2), rest 2 s,
    /// forward the same, rest 2 s.
    fn reversing(distance: f64, v_max: f64) -> Result<Profile, SimError> {
        if !(distance > 0.0 && v_max > 0.0) {
            return Err(invalid("reversing: distance and speed must be positive"));
        }
        let a_max = 1.0f64;
        // Trapezoid (or triangle) covering `distance`.
        let v_top = v_max.min((distance * a_max).sqrt());
        let t_acc = v_top / a_max;
        let t_cruise = (distance - v_top * t_acc) / v_top;
        let leg = 2.0 * t_acc + t_cruise;
        let rest = 2.0;
        let duration_s = 3.0 * rest + 2.0 * leg;
        let speed = |tau: f64| -> (f64, f64) {
            // Unsigned speed and acceleration within one leg.
            if tau < t_acc {
                (a_max * tau, a_max)
            } else if tau < t_acc + t_cruise {
                (v_top, 0.0)
            } else if tau < leg {
                (v_top - a_max * (tau - t_acc - t_cruise), -a_max)
            } else {
                (0.0, 0.0)
            }
        };
        let n = (duration_s / Self::DT).ceil() as usize;
        let mut step = Vec::with_capacity(n + 1);
        let mut s = 0.0;
        for i in 0..=n {
            let t = i as f64 * Self::DT;
            let (v, a) = if t < rest {
                (0.0, 0.0)
            } else if t < rest + leg {
                let (v, a) = speed(t - rest);
                (-v, -a)
            } else if t < 2.0 * rest + leg {
                (0.0, 0.0)
            } else if t < 2.0 * rest + 2.0 * leg {
                speed(t - 2.0 * rest - leg)
            } else {
                (0.0, 0.0)
            };
            step.push((t, s, v, a));
            s += v * Self::DT;
        }
        // End exactly at the start pose: spread the integration's residue.
        let end = s;
        let last = step.len().max(1) as f64;
        for (i, p) in step.iter_mut().enumerate() {
            p.1 -= end * i as f64 / last;
        }
        Ok(Profile { duration_s, step })
    }

    /// The profile followed by a straight start from rest to `v0` at 1.5
    /// m/s^2 (for a drive that starts moving), shifted so that it still
    /// ends at the start pose.
    fn ramped_to(mut self, v0: f64) -> Profile {
        if v0.abs() < 1e-6 {
            return self;
        }
        let a = 1.5 * v0.signum();
        let t_r = v0 / a;
        let d_r = 0.5 * v0 * t_r;
        for p in &mut self.step {
            p.1 -= d_r;
        }
        let n = (t_r / Self::DT).ceil() as usize;
        let t_main = self.duration_s;
        for i in 1..=n {
            let tau = (i as f64 * Self::DT).min(t_r);
            self.step.push((
                t_main + tau,
                -d_r + 0.5 * a * tau * tau,
                a * tau,
                if tau < t_r { a } else { 0.0 },
            ));
        }
        self.duration_s = t_main + t_r;
        self
    }

    /// `(s, v, a)` at `t` seconds from the profile's start.
    fn at(&self, t: f64) -> (f64, f64, f64) {
        let i = ((t / Self::DT).round().max(0.0) as usize).min(self.step.len() - 1);
        let p = self.step[i];
        (p.1, p.2, p.3)
    }
}

/// Median interval of a time series, s.
fn median_dt(t: impl Iterator<Item = f64>) -> Option<f64> {
    let t: Vec<f64> = t.collect();
    let mut d: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|v| *v > 0.0)
        .collect();
    if d.is_empty() {
        return None;
    }
    d.sort_by(f64::total_cmp);
    Some(d[d.len() / 2])
}

/// White-noise sigma of a series from its first differences (robust: MAD).
fn noise_of(v: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = v.collect();
    let mut d: Vec<f64> = v.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    if d.is_empty() {
        return 0.0;
    }
    d.sort_by(f64::total_cmp);
    1.4826 * d[d.len() / 2] / 2f64.sqrt()
}

fn sample_times(start: f64, duration: f64, dt: f64) -> Vec<f64> {
    let n = (duration / dt).floor() as usize;
    (1..=n).rev().map(|k| start - k as f64 * dt).collect()
}

/// Put `profile` before the drive: the car moves along its start heading
/// and is at its start pose when the wheels' first sample comes (samples of
/// other streams before it are dropped).
fn prepend(
    d: &mut Drive,
    rng: &mut ChaCha8Rng,
    profile: &Profile,
    (c_rl, c_rr): (f64, f64),
) -> Result<(), SimError> {
    if !(c_rl > 0.0 && c_rr > 0.0) {
        return Err(invalid("circumferences must be positive"));
    }
    let revs = d
        .wheel_revolutions()
        .map_err(|e| invalid(format!("wheels: {e}")))?;
    if revs.len() < 3 {
        return Err(invalid("the drive has too few wheel samples"));
    }
    let ramped = ramp_for_a_moving_start(profile, &revs, (c_rl, c_rr));
    let profile = ramped.as_ref().unwrap_or(profile);
    // The other streams from the wheels' first sample on, so that every
    // stream's prepended samples end at the same pose at the same time.
    let t_start = d.wheels.samples[0].t_s;
    drop_samples_before(d, t_start);
    let lead = Lead {
        profile,
        t_begin: t_start - profile.duration_s,
    };
    let yaw0 = start_heading(d)?;
    let dir = (yaw0.cos(), yaw0.sin());
    prepend_wheels(d, rng, &lead, &revs, (c_rl, c_rr))?;
    prepend_gnss(d, rng, &lead, dir)?;
    prepend_imu(d, rng, &lead)?;
    prepend_heading(d, rng, &lead)?;
    prepend_truth(d, &lead, dir);
    Ok(())
}

/// The profile as it is placed before a drive: its motion at wheel time
/// `t` (`t_begin` is the wheel time of its start).
struct Lead<'a> {
    profile: &'a Profile,
    t_begin: f64,
}

impl Lead<'_> {
    /// `(s, v, a)` at wheel time `t`.
    fn at(&self, t: f64) -> (f64, f64, f64) {
        self.profile.at(t - self.t_begin)
    }

    /// The sample times, `dt` apart, of a stream whose first sample is at
    /// `first`, over the profile's duration before it.
    fn times(&self, first: f64, dt: f64) -> Vec<f64> {
        sample_times(first, self.profile.duration_s, dt)
    }
}

/// A drive that starts moving gets a straight start from rest to its first
/// speed after the profile (`None`: it starts at rest, the profile as is).
fn ramp_for_a_moving_start(
    profile: &Profile,
    revs: &[WheelRevs],
    (c_rl, c_rr): (f64, f64),
) -> Option<Profile> {
    // The drive must start at rest for a motion to end there.
    let k = revs.len().min(20);
    let dt0 = revs[k - 1].t_s - revs[0].t_s;
    let v0 = if dt0 > 0.0 {
        0.5 * ((revs[k - 1].rl - revs[0].rl) * c_rl + (revs[k - 1].rr - revs[0].rr) * c_rr) / dt0
    } else {
        0.0
    };
    (v0.abs() > 0.5).then(|| {
        Profile {
            duration_s: profile.duration_s,
            step: profile.step.clone(),
        }
        .ramped_to(v0)
    })
}

/// Drop the GNSS, IMU, heading and truth samples before `t_start`.
fn drop_samples_before(d: &mut Drive, t_start: f64) {
    if let Some(g) = d.gnss.as_mut() {
        g.retain(|f| f.t_s >= t_start);
    }
    if let Some(i) = d.imu.as_mut() {
        i.retain(|f| f.t_s >= t_start);
    }
    if let Some(h) = d.heading.as_mut() {
        h.retain(|f| f.t_s >= t_start);
    }
    if let Some(tr) = d.truth.as_mut() {
        tr.retain(|f| f.t_s >= t_start);
    }
}

/// Start heading: the truth's yaw, else the direction to the first point
/// 3 m away (truth, else GNSS).
fn start_heading(d: &Drive) -> Result<f64, SimError> {
    let positions: Vec<(f64, f64)> = match (&d.truth, &d.gnss) {
        (Some(tr), _) if !tr.is_empty() => tr.iter().map(|s| (s.x_m, s.y_m)).collect(),
        (_, Some(g)) if !g.is_empty() => g.iter().map(|s| (s.x_m, s.y_m)).collect(),
        _ => Vec::new(),
    };
    d.truth
        .as_ref()
        .and_then(|t| t.first())
        .and_then(|t| t.yaw_rad)
        .or_else(|| {
            let p0 = *positions.first()?;
            positions
                .iter()
                .find(|p| (p.0 - p0.0).hypot(p.1 - p0.1) > 3.0)
                .map(|p| (p.1 - p0.1).atan2(p.0 - p0.0))
        })
        .ok_or_else(|| invalid("no start heading: the drive has no truth or GNSS that moves"))
}

/// The mean and standard deviation of each wheel channel (rl, rr, fl, fr)
/// at rest, as the drive's samples show them: a rate sensor reads its own
/// offset and noise (zeros where the drive never stands).
fn wheel_rest_levels(d: &Drive, revs: &[WheelRevs], (c_rl, c_rr): (f64, f64)) -> [(f64, f64); 4] {
    let at_rest: Vec<&WheelSample> = d
        .wheels
        .samples
        .iter()
        .zip(revs.windows(2))
        .filter(|(_, r)| {
            let dt = r[1].t_s - r[0].t_s;
            dt > 0.0
                && ((r[1].rl - r[0].rl) * c_rl / dt).abs() < 0.03
                && ((r[1].rr - r[0].rr) * c_rr / dt).abs() < 0.03
        })
        .map(|(s, _)| s)
        .collect();
    let rest_stats = |pick: &dyn Fn(&WheelSample) -> Option<f64>| -> (f64, f64) {
        let v: Vec<f64> = at_rest.iter().filter_map(|s| pick(s)).collect();
        if v.len() < 10 {
            return (0.0, 0.0);
        }
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64;
        (m, var.sqrt())
    };
    [
        rest_stats(&|s| Some(s.rl)),
        rest_stats(&|s| Some(s.rr)),
        rest_stats(&|s| s.fl),
        rest_stats(&|s| s.fr),
    ]
}

/// Wheels, in the drive's units, before its first wheel sample.
fn prepend_wheels(
    d: &mut Drive,
    rng: &mut ChaCha8Rng,
    lead: &Lead,
    revs: &[WheelRevs],
    (c_rl, c_rr): (f64, f64),
) -> Result<(), SimError> {
    let c_nom = d.vehicle.nominal_circumference_m;
    let ticks_per_rev = d.vehicle.ticks_per_rev.unwrap_or(1.0);
    let wheel_dt = median_dt(d.wheels.samples.iter().map(|w| w.t_s)).unwrap_or(0.01);
    let units = d.wheels.units;
    let first = d.wheels.samples[0];
    let rest = wheel_rest_levels(d, revs, (c_rl, c_rr));
    let rest_noise = rest
        .iter()
        .map(|(_, sd)| normal(*sd))
        .collect::<Result<Vec<_>, _>>()?;
    let mut value =
        |ch: usize, unit: WheelUnit, rev_offset: f64, rev_rate: f64, first_value: f64| -> f64 {
            match unit {
                WheelUnit::Rev => first_value + rev_offset,
                WheelUnit::Ticks => first_value + rev_offset * ticks_per_rev,
                WheelUnit::RadS => {
                    rev_rate * std::f64::consts::TAU + rest[ch].0 + rest_noise[ch].sample(rng)
                }
                WheelUnit::MS => rev_rate * c_nom + rest[ch].0 + rest_noise[ch].sample(rng),
            }
        };
    let mut wheels = Vec::new();
    for t in lead.times(first.t_s, wheel_dt) {
        let (s, v, _) = lead.at(t);
        let rl = value(0, units.rl, s / c_rl, v / c_rl, first.rl);
        let rr = value(1, units.rr, s / c_rr, v / c_rr, first.rr);
        let fl = match (units.fl, first.fl) {
            (Some(u), Some(f)) => Some(value(2, u, s / c_rl, v / c_rl, f)),
            _ => None,
        };
        let fr = match (units.fr, first.fr) {
            (Some(u), Some(f)) => Some(value(3, u, s / c_rr, v / c_rr, f)),
            _ => None,
        };
        wheels.push(WheelSample {
            t_s: t,
            rl,
            rr,
            fl,
            fr,
        });
    }
    wheels.append(&mut d.wheels.samples);
    d.wheels.samples = wheels;
    Ok(())
}

/// The white-noise sigma of GNSS fixes: the median `sigma_m` they give,
/// else from their second differences (6 sigma^2 for white noise).
fn gnss_white_sigma(g: &[GnssSample]) -> f64 {
    let mut s: Vec<f64> = g.iter().filter_map(|f| f.sigma_m).collect();
    s.sort_by(f64::total_cmp);
    s.get(s.len() / 2).copied().unwrap_or_else(|| {
        let mut dd: Vec<f64> = g
            .windows(3)
            .flat_map(|w| {
                [
                    (w[2].x_m - 2.0 * w[1].x_m + w[0].x_m).abs(),
                    (w[2].y_m - 2.0 * w[1].y_m + w[0].y_m).abs(),
                ]
            })
            .collect();
        dd.sort_by(f64::total_cmp);
        1.4826 * dd[dd.len() / 2] / 6f64.sqrt()
    })
}

/// GNSS: the first fix's position moved along the heading, with white
/// noise of the drive's own size.
fn prepend_gnss(
    d: &mut Drive,
    rng: &mut ChaCha8Rng,
    lead: &Lead,
    dir: (f64, f64),
) -> Result<(), SimError> {
    let Some(g) = d.gnss.as_mut().filter(|g| g.len() >= 3) else {
        return Ok(());
    };
    let dt = median_dt(g.iter().map(|f| f.t_s)).unwrap_or(0.1);
    let noise = normal(gnss_white_sigma(g))?;
    let f0 = g[0];
    let mut pre: Vec<GnssSample> = lead
        .times(f0.t_s, dt)
        .into_iter()
        .map(|t| {
            let (s, _, _) = lead.at(t);
            GnssSample {
                t_s: t,
                x_m: f0.x_m + s * dir.0 + noise.sample(rng),
                y_m: f0.y_m + s * dir.1 + noise.sample(rng),
                sigma_m: f0.sigma_m,
            }
        })
        .collect();
    pre.append(g);
    *g = pre;
    Ok(())
}

/// IMU: no turn, the profile's acceleration, noise and bias of the drive.
fn prepend_imu(d: &mut Drive, rng: &mut ChaCha8Rng, lead: &Lead) -> Result<(), SimError> {
    let truth = d.truth.as_deref();
    let Some(imu) = d.imu.as_mut().filter(|i| i.len() >= 3) else {
        return Ok(());
    };
    let dt = median_dt(imu.iter().map(|i| i.t_s)).unwrap_or(0.01);
    let gz_noise = normal(noise_of(imu.iter().map(|i| i.gz_rad_s)))?;
    let ax_noise = normal(noise_of(imu.iter().filter_map(|i| i.ax_m_s2)))?;
    let ay_noise = normal(noise_of(imu.iter().filter_map(|i| i.ay_m_s2)))?;
    let bias = gyro_bias(imu, truth);
    let i0 = imu[0];
    let mut pre: Vec<ImuSample> = lead
        .times(i0.t_s, dt)
        .into_iter()
        .map(|t| {
            let (_, _, a) = lead.at(t);
            ImuSample {
                t_s: t,
                gz_rad_s: bias + gz_noise.sample(rng),
                ax_m_s2: i0.ax_m_s2.map(|_| a + ax_noise.sample(rng)),
                ay_m_s2: i0.ay_m_s2.map(|_| ay_noise.sample(rng)),
                az_m_s2: i0.az_m_s2,
                gx_rad_s: i0.gx_rad_s.map(|_| 0.0),
                gy_rad_s: i0.gy_rad_s.map(|_| 0.0),
            }
        })
        .collect();
    pre.append(imu);
    *imu = pre;
    Ok(())
}

/// Heading: the first reading with its own noise.
fn prepend_heading(d: &mut Drive, rng: &mut ChaCha8Rng, lead: &Lead) -> Result<(), SimError> {
    let Some(h) = d.heading.as_mut().filter(|h| h.len() >= 3) else {
        return Ok(());
    };
    let dt = median_dt(h.iter().map(|s| s.t_s)).unwrap_or(0.1);
    let h0 = h[0];
    let noise = normal(h0.sigma_rad.unwrap_or(0.0))?;
    let mut pre: Vec<HeadingSample> = lead
        .times(h0.t_s, dt)
        .into_iter()
        .map(|t| HeadingSample {
            t_s: t,
            yaw_rad: h0.yaw_rad + noise.sample(rng),
            sigma_rad: h0.sigma_rad,
        })
        .collect();
    pre.append(h);
    *h = pre;
    Ok(())
}

/// Truth: the first pose moved along the heading.
fn prepend_truth(d: &mut Drive, lead: &Lead, dir: (f64, f64)) {
    let Some(tr) = d.truth.as_mut().filter(|t| !t.is_empty()) else {
        return;
    };
    let dt = median_dt(tr.iter().map(|s| s.t_s)).unwrap_or(0.01);
    let s0 = tr[0];
    let mut pre: Vec<TruthSample> = lead
        .times(s0.t_s, dt)
        .into_iter()
        .map(|t| {
            let (s, _, _) = lead.at(t);
            TruthSample {
                t_s: t,
                x_m: s0.x_m + s * dir.0,
                y_m: s0.y_m + s * dir.1,
                yaw_rad: s0.yaw_rad,
            }
        })
        .collect();
    pre.append(tr);
    *tr = pre;
}

/// The gyro's bias as the drive shows it: the median of the yaw rate less
/// the truth's yaw rate where the truth has a yaw, else the median of the
/// first second's readings (the car at rest).
fn gyro_bias(imu: &[ImuSample], truth: Option<&[TruthSample]>) -> f64 {
    let median = |mut v: Vec<f64>| -> Option<f64> {
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        Some(v[v.len() / 2])
    };
    if let Some(tr) = truth.filter(|t| t.len() > 10 && t.iter().all(|s| s.yaw_rad.is_some())) {
        let mut j = 0;
        let mut diffs = Vec::new();
        for i in imu.iter().step_by(10) {
            while j + 1 < tr.len() && tr[j + 1].t_s <= i.t_s {
                j += 1;
            }
            if j + 1 >= tr.len() || tr[j].t_s > i.t_s {
                continue;
            }
            let (a, b) = (tr[j], tr[j + 1]);
            let (Some(ya), Some(yb)) = (a.yaw_rad, b.yaw_rad) else {
                continue;
            };
            let h = b.t_s - a.t_s;
            if h <= 0.0 || h > 0.5 {
                continue;
            }
            let dy = (yb - ya + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            diffs.push(i.gz_rad_s - dy / h);
        }
        if let Some(b) = median(diffs) {
            return b;
        }
    }
    let t0 = imu.first().map_or(0.0, |i| i.t_s);
    median(
        imu.iter()
            .take_while(|i| i.t_s < t0 + 1.0)
            .map(|i| i.gz_rad_s)
            .collect(),
    )
    .unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use crate::{simulate, Scenario, SimConfig};

    fn drive() -> Drive {
        let mut cfg = SimConfig::new(Scenario::Paper, 3);
        cfg.duration_s = Some(120.0);
        simulate(&cfg).expect("simulate")
    }

    #[test]
    fn a_clock_shift_moves_only_that_stream() {
        let d = drive();
        let f = apply(&d, &Fault::WheelClockShift { s: 1.5 }, 1).unwrap();
        assert_eq!(f.gnss, d.gnss);
        assert_eq!(f.truth, d.truth);
        let (a, b) = (&d.wheels.samples[10], &f.wheels.samples[10]);
        assert!((b.t_s - a.t_s - 1.5).abs() < 1e-12);
        assert_eq!(a.rl, b.rl);
    }

    #[test]
    fn gnss_jumps_move_some_fixes_by_their_size_and_leave_the_rest() {
        let d = drive();
        let fault = Fault::GnssJumps {
            count: 3,
            min_m: 0.5,
            max_m: 3.0,
            min_s: 2.0,
            max_s: 20.0,
        };
        let f = apply(&d, &fault, 9).unwrap();
        let (g0, g1) = (d.gnss.as_ref().unwrap(), f.gnss.as_ref().unwrap());
        let moved: Vec<f64> = g0
            .iter()
            .zip(g1)
            .map(|(a, b)| (b.x_m - a.x_m).hypot(b.y_m - a.y_m))
            .collect();
        let n_moved = moved.iter().filter(|m| **m > 1e-9).count();
        assert!(n_moved > 0 && n_moved < moved.len() / 2, "{n_moved}");
        assert!(moved
            .iter()
            .all(|m| *m < 1e-9 || (0.5..=3.0 + 1e-9).contains(m)));
        // Same seed, same drive.
        assert_eq!(apply(&d, &fault, 9).unwrap(), f);
    }

    #[test]
    fn a_reversing_manoeuvre_ends_at_the_start_pose_with_the_wheels_where_they_began() {
        let d = drive();
        let c = d.vehicle.nominal_circumference_m;
        let fault = Fault::ReversingAtStart {
            distance_m: 10.0,
            speed_m_s: 2.0,
            c_rl_m: c,
            c_rr_m: c,
        };
        let f = apply(&d, &fault, 2).unwrap();
        assert!(f.wheels.samples.len() > d.wheels.samples.len());
        let revs = f.wheel_revolutions().unwrap();
        let n_pre = f.wheels.samples.len() - d.wheels.samples.len();
        let r_start = revs[n_pre].rl;
        let r_min = revs[..n_pre]
            .iter()
            .map(|r| r.rl)
            .fold(f64::INFINITY, f64::min);
        let tr = f.truth.as_ref().unwrap();
        let tr0 = d.truth.as_ref().unwrap()[0];
        let n_tr = tr.len() - d.truth.as_ref().unwrap().len();
        let far = tr[..n_tr]
            .iter()
            .map(|s| (s.x_m - tr0.x_m).hypot(s.y_m - tr0.y_m))
            .fold(0.0, f64::max);
        // The simulated drive starts moving: 10 m back from where the
        // straight start from rest begins, which lies v0^2 / 3 before the start.
        assert!(far > 10.0, "{far}");
        // The wheels turned back by that distance (to the integration's
        // step for rate units), and the truth ends where the drive begins.
        assert!(
            ((r_start - r_min) * c - far).abs() < 0.15,
            "{} vs {far}",
            (r_start - r_min) * c
        );
        let seam = tr[n_tr - 1];
        assert!((seam.x_m - tr0.x_m).hypot(seam.y_m - tr0.y_m) < 0.5);
        // Times stay increasing across the seam.
        assert!(f.wheels.samples.windows(2).all(|w| w[1].t_s > w[0].t_s));
        assert!(f
            .imu
            .as_ref()
            .unwrap()
            .windows(2)
            .all(|w| w[1].t_s > w[0].t_s));
    }

    #[test]
    fn a_late_stream_loses_its_first_seconds_only() {
        let d = drive();
        let f = apply(
            &d,
            &Fault::LateStart {
                stream: Stream::Gnss,
                delay_s: 20.0,
            },
            1,
        )
        .unwrap();
        let t0 = d.wheels.samples[0].t_s;
        assert!(f.gnss.as_ref().unwrap()[0].t_s >= t0 + 20.0);
        assert_eq!(f.wheels, d.wheels);
    }
}
