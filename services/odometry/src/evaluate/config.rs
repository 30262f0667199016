//! The settings of an evaluation.

use super::truth_point::TruthPoint;
use crate::dead_reckoning::OdometerConfig;

/// Settings of an evaluation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EvaluateConfig {
    /// Length of each outage, s.
    pub outage_s: f64,
    /// Time between the starts of two outages, s.
    pub spacing_s: f64,
    /// Heading mode and gyro settings of the dead-reckoner.
    pub odometer: OdometerConfig,
    /// Half length of the truth track used to fit the course, m.
    pub course_half_window_m: f64,
    /// Largest gap between truth rows to interpolate across, s.
    pub max_truth_gap_s: f64,
    /// Outages shorter than this (truth arc length) get no `error_pct`, m.
    pub min_distance_for_pct_m: f64,
    /// Truth track length before the outage that the start yaw is aligned on, m.
    pub align_distance_m: f64,
    /// Longest time before the outage the alignment may reach back, s.
    pub align_max_s: f64,
    /// The body point `truth.csv` follows, scored at the outage ends: the
    /// rear-axle centre unless set
    /// ([`choose_truth_point`](super::truth_point::choose_truth_point) picks
    /// it the way `odometry evaluate` does).
    pub truth_point: TruthPoint,
    /// Keep the dead-reckoned track of every outage in the report.
    pub keep_tracks: bool,
    /// Effect terms of the extended 2W model to dead-reckon with (the
    /// diagnosis's `terms`); all zero: the plain model.
    pub effects: vehicle_model::effects::EffectTerms,
    /// The sensor clock offsets the calibration applied (the estimate's
    /// `clocks`): the drive's streams are put on the GNSS clock, the clock
    /// of `truth.csv`, before dead-reckoning. Zero: as recorded.
    pub clocks: vehicle_model::estimate::StreamClocks,
}

impl Default for EvaluateConfig {
    fn default() -> Self {
        EvaluateConfig {
            outage_s: 30.0,
            spacing_s: 10.0,
            odometer: OdometerConfig::default(),
            course_half_window_m: 5.0,
            max_truth_gap_s: 2.0,
            min_distance_for_pct_m: 5.0,
            align_distance_m: 30.0,
            align_max_s: 30.0,
            truth_point: TruthPoint::AXLE,
            keep_tracks: false,
            effects: vehicle_model::effects::EffectTerms::default(),
            clocks: vehicle_model::estimate::StreamClocks::default(),
        }
    }
}
