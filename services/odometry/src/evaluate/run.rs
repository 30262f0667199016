//! The evaluation of a drive: its checks, the truth's yaw judged, the
//! outages placed, one odometer pass copied at their starts, every outage
//! scored, and the summary.

use super::alignment::aligned_start;
use super::config::EvaluateConfig;
use super::dead_reckon::{snapshots, Snapshot};
use super::error::EvaluateError;
use super::outage::{place_outages, run_outage, PlacedOutage};
use super::report::{EvaluationReport, OutageResult, ParamsReport};
use super::truth_point::truth_is_the_gnss_track;
use super::truth_track::{
    truth_yaw_offset, TruthTrack, TRUTH_YAW_OFFSET_LIMIT_RAD, YAW_CHECK_STRETCH_M,
};
use super::wheel_clock;
use crate::dead_reckoning::HeadingMode;
use crate::inputs::{drive_inputs, Input};
use drive_io::plausibility::{self, Finding};
use interfaces::drive::{Drive, TruthSample, WheelRevs};
use stats::percentile;
use std::borrow::Cow;
use vehicle_model::estimate::OdometryParams;

/// Run the outage evaluation of `drive` with `params`.
pub fn evaluate(
    drive: &Drive,
    params: &OdometryParams,
    config: &EvaluateConfig,
) -> Result<EvaluationReport, EvaluateError> {
    let truth_rows = check_request(drive, params, config)?;
    // The streams on the GNSS clock (truth.csv's), as the calibration found them.
    let drive = on_the_gnss_clock(drive, config);
    // The drive as the calibrator reads it: glitches set aside, what is
    // impossible refused, what is doubtful said (the same checks and words).
    let mut warnings = Vec::new();
    let (repaired, pauses, stuck_gyro) = checked(&drive, &mut warnings)?;
    let holes = holes(&pauses, &stuck_gyro, config)?;
    let mut truth = TruthTrack::new(truth_rows, config.max_truth_gap_s);
    let (drive, revs) = on_the_truth_clock(&repaired, &truth, params, &mut warnings)?;
    let inputs = drive_inputs(&drive)?;
    let yaw_offset = truth_yaw_offset(truth_rows, config.max_truth_gap_s);
    judge_truth_yaw(yaw_offset, &mut truth, &mut warnings);
    let (t_from, t_to) = scored_span(&revs, truth_rows, config)?;
    let windows = place_outages(&truth, config, t_from, t_to);
    let starts = StartStates::new(&revs, &inputs, params, config, &windows);
    if starts.skipped > 0 {
        warnings.push(format!(
            "{} wheel or IMU samples with bad values or times skipped",
            starts.skipped
        ));
    }
    let scoring = Scoring {
        truth: &truth,
        revs: &revs,
        inputs: &inputs,
        config,
        starts: &starts,
    };
    let outages = scoring.score(&windows, &holes, &mut warnings);
    if outages.is_empty() {
        return Err(EvaluateError::NothingScored(warnings.join("; ")));
    }
    let errors: Vec<f64> = outages.iter().map(|o| o.error_m).collect();
    let pcts: Vec<f64> = outages.iter().filter_map(|o| o.error_pct).collect();
    Ok(EvaluationReport {
        median_error_m: percentile(&errors, 0.5).unwrap_or(f64::NAN),
        p90_error_m: percentile(&errors, 0.9).unwrap_or(f64::NAN),
        median_error_pct: percentile(&pcts, 0.5),
        outages,
        heading: config.odometer.heading.name(),
        params: ParamsReport::from(params),
        truth_yaw_offset_rad: yaw_offset.map(|(offset, _)| offset),
        truth_yaw_used: truth.use_yaw && truth_rows.iter().any(|r| r.yaw_rad.is_some()),
        truth_point: config.truth_point,
        truth_is_gnss_track: truth_is_the_gnss_track(&drive),
        warnings,
    })
}

/// What an evaluation needs before it looks at the drive: positive outage
/// and spacing, valid parameters, a truth track, and an IMU when the gyro
/// heads; returns the truth's rows.
fn check_request<'a>(
    drive: &'a Drive,
    params: &OdometryParams,
    config: &EvaluateConfig,
) -> Result<&'a [TruthSample], EvaluateError> {
    if !(config.outage_s > 0.0 && config.spacing_s > 0.0) {
        return Err(EvaluateError::Config(format!(
            "outage ({} s) and spacing ({} s) must be positive",
            config.outage_s, config.spacing_s
        )));
    }
    params
        .validate("odometry parameters")
        .map_err(|e| EvaluateError::Config(e.to_string()))?;
    let truth_rows = drive
        .truth
        .as_deref()
        .filter(|t| !t.is_empty())
        .ok_or(EvaluateError::NoTruth)?;
    if config.odometer.heading == HeadingMode::Gyro && drive.imu.as_ref().is_none_or(Vec::is_empty)
    {
        return Err(EvaluateError::NoImu);
    }
    Ok(truth_rows)
}

/// The drive with its streams on the GNSS clock by the estimate's clocks
/// (`config.clocks`; as it is when they are zero).
fn on_the_gnss_clock<'a>(drive: &'a Drive, config: &EvaluateConfig) -> Cow<'a, Drive> {
    if config.clocks.is_zero() {
        Cow::Borrowed(drive)
    } else {
        let mut d = drive.clone();
        config.clocks.align(&mut d);
        Cow::Owned(d)
    }
}

/// A stretch no outage may cross: start, end, s, and what is wrong there.
type Hole = (f64, f64, &'static str);

/// Where nothing dead-reckons: the pauses of the wheel stream and, in gyro
/// heading mode, where the gyro is stuck. A dead gyro heads nothing: the
/// evaluation is refused in gyro heading mode when it is dead for the
/// whole drive.
fn holes(
    pauses: &Stretches,
    stuck_gyro: &StuckGyro,
    config: &EvaluateConfig,
) -> Result<Vec<Hole>, EvaluateError> {
    let gyro_heading = config.odometer.heading == HeadingMode::Gyro;
    if gyro_heading {
        if let Some(f) = stuck_gyro.iter().find_map(|(_, _, whole)| whole.as_ref()) {
            return Err(EvaluateError::DeadGyro(f.clone()));
        }
    }
    Ok(pauses
        .iter()
        .map(|&(a, b)| (a, b, "the wheel stream pauses"))
        .chain(
            stuck_gyro
                .iter()
                .filter(|_| gyro_heading)
                .map(|&(a, b, _)| (a, b, "the gyro is stuck (imu.gz_rad_s)")),
        )
        .collect())
}

/// The wheels on the truth's clock, and their revolutions: a lag the
/// speeds show beyond doubt is taken out of the wheel time stamps, and
/// said (the estimate's clocks are already applied).
fn on_the_truth_clock<'a>(
    drive: &'a Drive,
    truth: &TruthTrack<'_>,
    params: &OdometryParams,
    warnings: &mut Vec<String>,
) -> Result<(Cow<'a, Drive>, Vec<WheelRevs>), EvaluateError> {
    let revs = drive.wheel_revolutions()?;
    let Some(lag) = wheel_lag(&revs, truth, params) else {
        return Ok((Cow::Borrowed(drive), revs));
    };
    let mut d = drive.clone();
    for s in &mut d.wheels.samples {
        s.t_s -= lag;
    }
    warnings.push(format!(
        "wheels.csv: the wheels' time stamps are {:+.0} ms off truth.csv's (from the speeds of the \
         wheels and of the truth track); the wheel times were shifted by {:+.0} ms for the scoring \
         (calibrate the drive to find every stream's clock offset)",
        lag * 1e3,
        -lag * 1e3
    ));
    let revs = d.wheel_revolutions()?;
    Ok((Cow::Owned(d), revs))
}

/// The truth's yaw is not used for the start poses when it is off the
/// course of its own positions beyond [`TRUTH_YAW_OFFSET_LIMIT_RAD`]
/// (`yaw_offset`: the offset and the straight stretches it is from), and
/// that is said.
fn judge_truth_yaw(
    yaw_offset: Option<(f64, usize)>,
    truth: &mut TruthTrack<'_>,
    warnings: &mut Vec<String>,
) {
    if let Some((offset, stretches)) = yaw_offset {
        if offset.abs() > TRUTH_YAW_OFFSET_LIMIT_RAD {
            truth.use_yaw = false;
            warnings.push(format!(
                "truth.csv: yaw_rad is {:+.1} mrad off the course of its own positions (median over \
                 {stretches} straight stretches of {YAW_CHECK_STRETCH_M} m), more than {:.1} mrad: \
                 it is not the vehicle's yaw (a device mounted at an angle?); the start poses come \
                 from the truth track instead",
                offset * 1e3,
                TRUTH_YAW_OFFSET_LIMIT_RAD * 1e3
            ));
        }
    }
}

/// The span both the wheels and the truth cover, s; an error when it
/// holds no outage.
fn scored_span(
    revs: &[WheelRevs],
    truth_rows: &[TruthSample],
    config: &EvaluateConfig,
) -> Result<(f64, f64), EvaluateError> {
    let (Some(w0), Some(w1)) = (revs.first(), revs.last()) else {
        return Err(EvaluateError::TooShort {
            outage_s: config.outage_s,
            from_s: 0.0,
            to_s: 0.0,
        });
    };
    let t_from = w0.t_s.max(truth_rows[0].t_s);
    let t_to = w1.t_s.min(truth_rows[truth_rows.len() - 1].t_s);
    if t_from + config.outage_s > t_to {
        return Err(EvaluateError::TooShort {
            outage_s: config.outage_s,
            from_s: t_from,
            to_s: t_to,
        });
    }
    Ok((t_from, t_to))
}

/// One pass of the odometer over the whole drive, as the service runs it,
/// copied at every outage (and alignment) start.
struct StartStates {
    /// The start times, sorted, without duplicates.
    times: Vec<f64>,
    /// The odometer's state at each, or why there is none.
    snapshots: Vec<Result<Snapshot, String>>,
    /// Wheel or IMU samples the pass skipped (bad values or times).
    skipped: usize,
}

impl StartStates {
    fn new(
        revs: &[WheelRevs],
        inputs: &[Input],
        params: &OdometryParams,
        config: &EvaluateConfig,
        windows: &[PlacedOutage],
    ) -> StartStates {
        let mut times: Vec<f64> = windows
            .iter()
            .flat_map(|w| std::iter::once(w.0).chain(w.2.map(|a| a.0)))
            .collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        let (snapshots, skipped) = snapshots(
            revs,
            inputs,
            params,
            config.odometer,
            config.effects,
            &times,
        );
        StartStates {
            times,
            snapshots,
            skipped,
        }
    }

    /// The odometer's state at start time `t`.
    fn at(&self, t: f64) -> Result<&Snapshot, String> {
        let i = self.times.partition_point(|s| *s < t);
        match self.snapshots.get(i) {
            Some(Ok(snap)) if self.times[i] == t => Ok(snap),
            Some(Err(e)) => Err(e.clone()),
            _ => Err(format!("no odometer state at {t} s")),
        }
    }
}

/// What scoring an outage reads.
struct Scoring<'a> {
    truth: &'a TruthTrack<'a>,
    revs: &'a [WheelRevs],
    inputs: &'a [Input],
    config: &'a EvaluateConfig,
    starts: &'a StartStates,
}

impl Scoring<'_> {
    /// Every outage of `windows` scored; one that crosses a hole, or cannot
    /// be scored, is skipped with a warning that says why.
    fn score(
        &self,
        windows: &[PlacedOutage],
        holes: &[Hole],
        warnings: &mut Vec<String>,
    ) -> Vec<OutageResult> {
        let mut outages = Vec::new();
        for &(t0, t1, align) in windows {
            // Nothing dead-reckons across a hole in the wheels or a stuck gyro.
            let from = align.map_or(t0, |(ta, _)| ta.min(t0));
            if let Some((p0, p1, what)) = holes.iter().find(|(p0, p1, _)| *p0 < t1 && *p1 > from) {
                warnings.push(format!(
                    "outage at {t0:.2} s skipped: {what} from {p0:.2} to {p1:.2} s within it"
                ));
                continue;
            }
            match self.one(t0, t1, align) {
                Ok(result) => outages.push(result),
                Err(reason) => warnings.push(format!("outage at {t0:.2} s skipped: {reason}")),
            }
        }
        outages
    }

    /// The outage `t0..t1`, started from the truth (aligned on the truth
    /// track over `align` when it has one).
    fn one(&self, t0: f64, t1: f64, align: Option<(f64, f64)>) -> Result<OutageResult, String> {
        let start = self.starts.at(t0)?;
        let aligned = align.and_then(|(ta, tb)| {
            let from = self.starts.at(ta).ok()?;
            aligned_start(
                self.truth,
                self.revs,
                self.inputs,
                from,
                self.config.truth_point.point_m,
                ta,
                tb,
                t0,
            )
        });
        run_outage(
            self.truth,
            self.revs,
            self.inputs,
            self.config,
            start,
            aligned,
            t0,
            t1,
        )
    }
}

/// The wheels' clock lag against the truth, when it is beyond doubt
/// ([`wheel_clock::wheel_clock_lag`]).
fn wheel_lag(revs: &[WheelRevs], truth: &TruthTrack<'_>, params: &OdometryParams) -> Option<f64> {
    let (w0, w1) = (revs.first()?.t_s, revs.last()?.t_s);
    let rows = truth.rows;
    let (from, to) = (w0.max(rows.first()?.t_s), w1.min(rows.last()?.t_s));
    let c = 0.5 * (params.two_wheel.c_rl + params.two_wheel.c_rr);
    wheel_clock::wheel_clock_lag(revs, truth, c, from, to)
}

/// Stretches of the drive (start, end), s.
type Stretches = Vec<(f64, f64)>;
/// Stretches where the gyro is stuck, with the finding when it is stuck
/// for the whole drive.
type StuckGyro = Vec<(f64, f64, Option<Finding>)>;

/// The drive with its wheel glitches set aside
/// ([`plausibility::repaired`]) and checked ([`plausibility::check`]): an
/// error refuses the evaluation, a warning is said; returns the repaired
/// drive, the pauses of the wheel stream and the stretches where the gyro
/// is stuck.
fn checked<'a>(
    drive: &'a Drive,
    warnings: &mut Vec<String>,
) -> Result<(Cow<'a, Drive>, Stretches, StuckGyro), EvaluateError> {
    let (repaired, repairs) = plausibility::repaired(drive);
    let findings: Vec<Finding> = repairs
        .into_iter()
        .chain(plausibility::check(&repaired))
        .collect();
    if let Some(f) = findings.iter().find(|f| f.is_error()) {
        return Err(EvaluateError::Implausible(f.clone()));
    }
    let (mut pauses, mut stuck) = (Vec::new(), Vec::new());
    for f in findings {
        match &f {
            Finding::WheelPause {
                t_s, duration_s, ..
            } => pauses.push((*t_s, t_s + duration_s)),
            Finding::ImuStuck {
                field: "gz_rad_s",
                t_start_s,
                t_end_s,
                whole_drive,
                ..
            } => stuck.push((*t_start_s, *t_end_s, whole_drive.then(|| f.clone()))),
            _ => {}
        }
        warnings.push(f.to_string());
    }
    Ok((repaired, pauses, stuck))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dead_reckoning::OdometerConfig;
    use crate::evaluate::test_drives::{
        antenna_truth_drive, drive_with_yaw_rate, true_params, winding_drive, ANTENNA,
    };
    use crate::evaluate::truth_point::{
        choose_truth_point, truth_gnss_coincidence, TruthPoint, TruthPointChoice, TruthPointSource,
    };

    fn config(heading: HeadingMode, outage_s: f64) -> EvaluateConfig {
        EvaluateConfig {
            outage_s,
            odometer: OdometerConfig {
                heading,
                ..OdometerConfig::default()
            },
            ..EvaluateConfig::default()
        }
    }

    #[test]
    fn true_parameters_give_small_errors_in_both_heading_modes() {
        let drive = winding_drive(100.0);
        for heading in [HeadingMode::WheelDifference, HeadingMode::Gyro] {
            let report = evaluate(&drive, &true_params(), &config(heading, 30.0)).unwrap();
            // Starts 0, 10, ..., 70: eight outages of 240 m each.
            assert_eq!(report.outages.len(), 8, "{heading}");
            assert!(report.warnings.is_empty(), "{:?}", report.warnings);
            for o in &report.outages {
                // No driving before the first outage: aligned on the track after its start.
                let expected = if o.t_start_s == 0.0 {
                    "truth_track_alignment_after"
                } else {
                    "truth_track_alignment"
                };
                assert_eq!(o.start_yaw_source, expected);
                assert!((o.distance_m - 240.0).abs() < 1.0, "{o:?}");
                assert_eq!(o.gyro_fallbacks, 0);
            }
            // Only the course fit and discretisation separate the model from the truth.
            assert!(report.p90_error_m < 0.05, "{heading}: {report:?}");
        }
    }

    #[test]
    fn wrong_circumferences_are_worse_than_right_ones() {
        let drive = winding_drive(70.0);
        let good = evaluate(
            &drive,
            &true_params(),
            &config(HeadingMode::WheelDifference, 30.0),
        )
        .unwrap();
        let nominal = OdometryParams::nominal(&drive.vehicle);
        let bad = evaluate(
            &drive,
            &nominal,
            &config(HeadingMode::WheelDifference, 30.0),
        )
        .unwrap();
        // 1 % scale error alone is 2.4 m after 240 m.
        assert!(bad.median_error_m > 2.0, "{bad:?}");
        assert!(
            bad.median_error_m > 10.0 * good.median_error_m,
            "{good:?} {bad:?}"
        );
        let pct = bad.median_error_pct.unwrap();
        assert!(
            (pct - 100.0 * bad.median_error_m / 240.0).abs() < 0.5,
            "{pct}"
        );
    }

    #[test]
    fn alignment_start_pose_shrugs_off_truth_noise_and_jumps() {
        // Truth with +-3 cm of deterministic jitter and, just before every
        // outage start, a 0.8 m sideways jump for two rows (an RTK glitch).
        let mut drive = winding_drive(100.0);
        for (k, r) in drive.truth.as_mut().unwrap().iter_mut().enumerate() {
            let jitter = 0.03 * ((k as f64 * 1.7).sin());
            r.x_m += jitter;
            r.y_m -= jitter;
            let phase = r.t_s % 10.0;
            if (9.5..9.9).contains(&phase) {
                r.y_m += 0.8;
            }
        }
        let report = evaluate(&drive, &true_params(), &config(HeadingMode::Gyro, 30.0)).unwrap();
        for o in &report.outages {
            // A course from the raw points would be off by a few hundredths of
            // a radian here: metres after 240 m.
            assert!(o.error_m < 0.3, "{o:?}");
        }
    }

    #[test]
    fn truth_yaw_is_used_when_present() {
        // Winding all the time: too few straight stretches to check the
        // yaw, so it is taken as it is.
        let drive = drive_with_yaw_rate(40.0, |t| 0.25 * (0.2 * t).sin());
        let report = evaluate(&drive, &true_params(), &config(HeadingMode::Gyro, 30.0)).unwrap();
        assert_eq!(report.truth_yaw_offset_rad, None);
        assert!(report.truth_yaw_used);
        assert_eq!(report.outages[0].start_yaw_source, "truth_yaw");
        assert_eq!(report.outages[0].start_yaw_rad, 0.3);
        // A yaw that does not follow the track at all: found out.
        let mut fixed = drive.clone();
        for r in fixed.truth.as_mut().unwrap() {
            r.yaw_rad = Some(1.0);
        }
        let report = evaluate(&fixed, &true_params(), &config(HeadingMode::Gyro, 30.0)).unwrap();
        assert!(!report.truth_yaw_used);
        assert!(report.truth_yaw_offset_rad.unwrap().abs() > 0.1);
    }

    /// Straight for 10 s, then a 0.2 rad/s turn for 10 s, and again.
    fn straights_and_turns(seconds: f64) -> Drive {
        drive_with_yaw_rate(seconds, |t| if t % 20.0 < 10.0 { 0.0 } else { 0.2 })
    }

    #[test]
    fn a_truth_yaw_off_the_truth_course_is_found_and_not_used() {
        // The vehicle's own yaw: about 0 off, used.
        let drive = straights_and_turns(60.0);
        let rows = drive.truth.as_deref().unwrap();
        let (offset, stretches) = truth_yaw_offset(rows, 2.0).unwrap();
        assert!(offset.abs() < 1e-3, "{offset}");
        // 30 s of straights at 8 m/s: 24 stretches of 10 m, the turns left out.
        assert!((20..=24).contains(&stretches), "{stretches}");
        let report = evaluate(&drive, &true_params(), &config(HeadingMode::Gyro, 30.0)).unwrap();
        assert!(report.truth_yaw_used);
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        assert_eq!(report.outages[0].start_yaw_source, "truth_yaw");
        assert!(report.median_error_m < 0.15, "{}", report.median_error_m);

        // A yaw 15 mrad off (a device mounted at an angle): found, named and
        // replaced by the truth track, so the error stays small (taken as
        // it is, it would put the end of a 240 m outage 3.6 m off).
        let mut skewed = drive.clone();
        for r in skewed.truth.as_mut().unwrap() {
            r.yaw_rad = r.yaw_rad.map(|y| y + 0.015);
        }
        let rows = skewed.truth.as_deref().unwrap();
        let (offset, _) = truth_yaw_offset(rows, 2.0).unwrap();
        assert!((offset - 0.015).abs() < 1e-3, "{offset}");
        let report = evaluate(&skewed, &true_params(), &config(HeadingMode::Gyro, 30.0)).unwrap();
        assert!(!report.truth_yaw_used);
        assert!(
            report
                .warnings
                .iter()
                .any(|w| w.contains("truth.csv: yaw_rad is +15.0 mrad off")),
            "{:?}",
            report.warnings
        );
        assert!(report
            .outages
            .iter()
            .all(|o| o.start_yaw_source.starts_with("truth_track_alignment")));
        assert!(report.median_error_m < 0.15, "{}", report.median_error_m);
    }

    #[test]
    fn missing_truth_imu_or_length_are_clear_errors() {
        let mut drive = winding_drive(20.0);
        let msg = evaluate(&drive, &true_params(), &config(HeadingMode::Gyro, 30.0))
            .unwrap_err()
            .to_string();
        assert!(msg.contains("no 30 s outage fits"), "{msg}");
        drive.imu = None;
        let msg = evaluate(&drive, &true_params(), &config(HeadingMode::Gyro, 10.0))
            .unwrap_err()
            .to_string();
        assert!(msg.contains("imu.csv"), "{msg}");
        drive.truth = None;
        let msg = evaluate(
            &drive,
            &true_params(),
            &config(HeadingMode::WheelDifference, 10.0),
        )
        .unwrap_err()
        .to_string();
        assert!(msg.contains("truth.csv"), "{msg}");
    }

    #[test]
    fn truth_gap_skips_the_outage_with_a_warning() {
        let mut drive = winding_drive(70.0);
        // Remove truth between 48 s and 52 s: the outage 20-50 s loses its end.
        drive
            .truth
            .as_mut()
            .unwrap()
            .retain(|r| !(r.t_s > 48.0 && r.t_s < 52.0));
        let report = evaluate(
            &drive,
            &true_params(),
            &config(HeadingMode::WheelDifference, 30.0),
        )
        .unwrap();
        assert_eq!(report.outages.len(), 4, "{report:?}");
        assert_eq!(report.warnings.len(), 1);
        assert!(
            report.warnings[0].contains("20.00 s") && report.warnings[0].contains("end"),
            "{:?}",
            report.warnings
        );
    }

    #[test]
    fn a_truth_that_is_the_gnss_track_is_scored_at_the_antenna() {
        let drive = antenna_truth_drive(0.0);
        assert_eq!(truth_gnss_coincidence(&drive), (601, 601));
        assert!(truth_is_the_gnss_track(&drive));
        // Auto: the estimate's antenna, since vehicle.toml measures none.
        let point = choose_truth_point(&drive, TruthPointChoice::Auto, Some(ANTENNA)).unwrap();
        assert_eq!(
            point,
            TruthPoint {
                point_m: ANTENNA,
                source: TruthPointSource::EstimatedAntenna
            }
        );
        let at = |truth_point| {
            evaluate(
                &drive,
                &true_params(),
                &EvaluateConfig {
                    truth_point,
                    ..config(HeadingMode::Gyro, 30.0)
                },
            )
            .unwrap()
        };
        let antenna = at(point);
        let axle = at(TruthPoint::AXLE);
        assert!(antenna.truth_is_gnss_track && axle.truth_is_gnss_track);
        assert_eq!(antenna.truth_point, point);
        // The true parameters at the point the truth follows: only the
        // integration's own error. At the rear axle: the lever arm, turned by
        // the heading change of each outage.
        assert!(antenna.median_error_m < 0.05, "{}", antenna.median_error_m);
        assert!(
            axle.median_error_m > 10.0 * antenna.median_error_m.max(0.01),
            "axle {} antenna {}",
            axle.median_error_m,
            antenna.median_error_m
        );
        // No antenna known: Auto falls back to the axle; Antenna is an error.
        assert_eq!(
            choose_truth_point(&drive, TruthPointChoice::Auto, None).unwrap(),
            TruthPoint::AXLE
        );
        let err = choose_truth_point(&drive, TruthPointChoice::Antenna, None).unwrap_err();
        assert!(err.to_string().contains("[gnss]"), "{err}");
    }
}
