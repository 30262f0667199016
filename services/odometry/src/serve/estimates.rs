//! Estimates from the bus: the switch to a new one (logged with the old and
//! new values) and the drop of one the GNSS fixes contradict.

use super::inputs::Inputs;
use interfaces::drive::VehicleParams;
use odometry::rewind::RewindingFusion;
use vehicle_model::estimate::{Estimate, OdometryParams, StreamClocks};

/// The GNSS fixes contradict the estimate in use: drop it (the gate refuses
/// it from now on) and fall back on the one accepted before it, or on the
/// nominal values, with the reason in the log.
pub(crate) fn drop_contradicted(
    filter: &mut RewindingFusion,
    inputs: &Inputs,
    vehicle: &VehicleParams,
    c: &odometry::fusion::Contradiction,
) {
    let why = format!(
        "the GNSS fixes measure the wheels' distance scale at {:.4} +- {:.4} of what estimate v{} \
         makes of it, which claims 1 +- {:.4} (chi-square {:.1} over {:.0} m in {} windows, {} left out as GNSS jumps; t = {:.2} s)",
        c.measured_scale,
        c.measured_sigma,
        c.version,
        c.applied_sigma,
        c.chi2,
        c.distance_m,
        c.windows,
        c.outliers,
        c.t_s
    );
    let (fallback, fall_back) = inputs.gate.borrow_mut().drop_contradicted(c.version);
    if !fall_back {
        tracing::warn!(
            "odometry: estimate v{} dropped: {why}; a newer estimate is taken next",
            c.version
        );
        return;
    }
    let fusion = filter.fusion_mut();
    match fallback {
        Some((version, estimate)) => {
            tracing::warn!(
                "odometry: estimate v{} dropped: {why}; back to v{version}",
                c.version
            );
            if let Some(antenna) = fusion.antenna_to_take(estimate.fusable_antenna()) {
                if let Err(e) = fusion.set_lever_arm(antenna) {
                    tracing::warn!("odometry: the antenna of v{version}: {e}; kept as it was");
                }
            }
            fusion.set_estimate(estimate.params, version);
            fusion.set_effects(estimate.effects.into());
            inputs.clocks.set(estimate.clocks);
        }
        None => {
            tracing::warn!(
                "odometry: estimate v{} dropped: {why}; back to the nominal values of vehicle.toml",
                c.version
            );
            fusion.set_nominal(vehicle);
            fusion.set_effects(Default::default());
            inputs.clocks.set(StreamClocks::default());
        }
    }
}

pub(crate) fn describe_switch(old: &OdometryParams, new: &OdometryParams) -> String {
    format!(
        "c_rl {:.5} -> {:.5} m, c_rr {:.5} -> {:.5} m, track {:.4} -> {:.4} m, gyro bias {:.6} -> {:.6} rad/s, \
         gyro scale {:.5} -> {:.5}",
        old.two_wheel.c_rl,
        new.two_wheel.c_rl,
        old.two_wheel.c_rr,
        new.two_wheel.c_rr,
        old.two_wheel.track_width,
        new.two_wheel.track_width,
        old.gyro_bias_rad_s,
        new.gyro_bias_rad_s,
        old.gyro_scale,
        new.gyro_scale
    )
}

/// Before estimate `version` is taken: false when it is the one in use
/// already (history on a reconnect); else log the switch and the move of
/// the GNSS antenna it brings.
pub(crate) fn announce_switch(filter: &RewindingFusion, version: u64, estimate: &Estimate) -> bool {
    let old = *filter.fusion().params();
    let old_version = filter.fusion().estimate_version();
    if version == old_version && estimate.params == old {
        return false;
    }
    tracing::info!(
        "odometry: switching estimate v{old_version} -> v{version} between two samples: {}",
        describe_switch(&old, &estimate.params)
    );
    let from = filter.fusion().lever_arm();
    if let Some(to) = filter.fusion().antenna_to_take(estimate.fusable_antenna()) {
        if to != from {
            tracing::info!(
                "odometry: GNSS antenna ({:+.3}, {:+.3}) -> ({:+.3}, {:+.3}) m from estimate v{version}: \
                 the pose moves by {:.3} m onto the rear axle",
                from[0],
                from[1],
                to[0],
                to[1],
                (to[0] - from[0]).hypot(to[1] - from[1])
            );
        }
    }
    true
}
