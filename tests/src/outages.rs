//! What the fault suite bench and the clock-fault tests share: a
//! calibration read back as the odometry reads it, and the median error at
//! the end of 30 s GNSS outages with its clock offsets applied.

use calibrator::Calibration;
use interfaces::drive::Drive;
use odometry::evaluate::{evaluate, EvaluateConfig, TruthPoint};
use vehicle_model::estimate::Estimate;

/// `cal` as `calibrator calibrate --json` writes it and the odometry reads
/// it (`name` names it in errors).
pub fn as_estimate(cal: &Calibration, name: &str) -> Result<Estimate, String> {
    let text = serde_json::to_string(cal).map_err(|e| format!("{name}: encoding: {e}"))?;
    Estimate::from_json_str(&text, name).map_err(|e| e.to_string())
}

/// The errors (m, sorted) at the end of the outages starting at or after
/// `from_s`, scored at `point` (chosen once on the clean drive with its
/// estimate, so that every fault is scored at the same body point: a fault
/// in the GNSS must not change where truth.csv is taken to be), the
/// estimate's clock offsets applied.
pub fn outage_errors(
    drive: &Drive,
    est: &Estimate,
    point: TruthPoint,
    from_s: f64,
) -> Result<Vec<f64>, String> {
    let config = EvaluateConfig {
        truth_point: point,
        clocks: est.clocks,
        ..EvaluateConfig::default()
    };
    let report = evaluate(drive, &est.params, &config).map_err(|e| e.to_string())?;
    let mut e: Vec<f64> = report
        .outages
        .iter()
        .filter(|o| o.t_start_s >= from_s - 1e-6)
        .map(|o| o.error_m)
        .collect();
    e.sort_by(f64::total_cmp);
    Ok(e)
}

/// The median of [`outage_errors`]; an error where no outage is scored.
pub fn outage_median(
    drive: &Drive,
    est: &Estimate,
    point: TruthPoint,
    from_s: f64,
) -> Result<f64, String> {
    let e = outage_errors(drive, est, point, from_s)?;
    e.get(e.len() / 2)
        .copied()
        .ok_or_else(|| "no outage scored".to_string())
}
