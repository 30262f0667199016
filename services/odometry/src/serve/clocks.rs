//! The sensor clocks of the estimate in use: how they read in the log, and
//! how far back the filter must go for the samples they make late.

use odometry::rewind::RewindingFusion;
use vehicle_model::estimate::StreamClocks;

/// The sensor clocks' lateness is taken over this much drive time ahead, s
/// (a drift makes it grow slowly).
const CLOCK_LATENESS_HORIZON_S: f64 = 3600.0;

/// The clocks for a log line.
pub(crate) fn describe_clocks(c: &StreamClocks) -> String {
    format!(
        "GNSS {:+.3} s {:+.0} ppm, IMU {:+.3} s {:+.0} ppm against the wheels; wheel and IMU stamps \
         are put on the GNSS clock",
        c.gnss_late_s, c.gnss_drift_ppm, c.imu_late_s, c.imu_drift_ppm
    )
}

/// The rewind window set for the sensor clocks last seen.
#[derive(Debug, Default)]
pub(crate) struct ClockWindow {
    /// The clocks the window was last set for.
    set_for: Option<StreamClocks>,
}

impl ClockWindow {
    /// Before a wakeup's samples are taken: when the clocks changed, widen
    /// (or narrow) the filter's window (`window_s` without clocks) by the
    /// lateness they give a stream from `last_wheel_t` on.
    pub(crate) fn fit(
        &mut self,
        filter: &mut RewindingFusion,
        clocks: StreamClocks,
        window_s: f64,
        last_wheel_t: Option<f64>,
    ) {
        if self.set_for == Some(clocks) {
            return;
        }
        // Restamped onto the GNSS clock, a stream's samples may come
        // later than the wheel samples of their instant: the filter goes
        // back that much further for them (a sample beyond it is counted
        // in the rewind stats, never dropped silently).
        let t = last_wheel_t.unwrap_or(0.0);
        let window = window_s + clocks.max_lateness_s(t, t + CLOCK_LATENESS_HORIZON_S);
        if window_s > 0.0 && window != filter.window_s() {
            tracing::info!(
                "odometry: going back up to {window:.2} s for samples the sensor clocks make late"
            );
            filter.set_window_s(window);
        }
        self.set_for = Some(clocks);
    }
}
