//! The loop's log lines about the pose: mode changes and the status line.

use super::inputs::Inputs;
use interfaces::wire::PoseMode;
use odometry::fusion::{FusedPose, Fusion};

/// The mode as the log names it.
fn mode_name(mode: PoseMode) -> &'static str {
    match mode {
        PoseMode::NoFix => "NoFix",
        PoseMode::Fused => "Fused",
        PoseMode::DeadReckoning => "DeadReckoning",
    }
}

/// The mode change `from` -> the pose's mode, in the log.
pub(crate) fn log_mode_change(from: PoseMode, pose: &FusedPose) {
    let t = pose.t_s;
    match (from, pose.mode) {
        (_, PoseMode::Fused) => tracing::info!(
            "odometry: t = {t:.2} s: {} -> Fused (GNSS good) at ({:.1}, {:.1}) m",
            mode_name(from),
            pose.pose.x,
            pose.pose.y
        ),
        (_, PoseMode::DeadReckoning) => tracing::info!(
            "odometry: t = {t:.2} s: {} -> DeadReckoning (no usable GNSS fix): dead-reckoning with estimate v{}",
            mode_name(from),
            pose.estimate_version
        ),
        (_, PoseMode::NoFix) => tracing::info!("odometry: t = {t:.2} s: {} -> NoFix", mode_name(from)),
    }
}

/// The status line (every `--status-every` of drive time).
pub(crate) fn log_status(pose: &FusedPose, fusion: &Fusion, inputs: &Inputs) {
    let sigma = (pose.covariance[0] + pose.covariance[4]).max(0.0).sqrt();
    let stats = fusion.stats();
    tracing::info!(
        "odometry: t = {:.1} s {} pose ({:.1}, {:.1}) m yaw {:.1} deg, sigma {:.2} m, estimate v{}; \
         received {} wheel, {} IMU, {} GNSS samples",
        pose.t_s,
        mode_name(pose.mode),
        pose.pose.x,
        pose.pose.y,
        pose.pose.yaw.to_degrees(),
        sigma,
        pose.estimate_version,
        inputs.wheels.received(),
        inputs.imu.received(),
        stats.gnss_accepted + stats.gnss_rejected,
    );
}
