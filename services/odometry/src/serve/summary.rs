//! What a service run did: its counters, and the log lines that report them.

use odometry::fusion::FusionStats;
use odometry::inputs::Sequencer;
use odometry::rewind::RewindStats;

/// What a service run did.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct ServeSummary {
    /// Wheel samples processed.
    pub(crate) wheel_samples: u64,
    /// Poses published.
    pub(crate) poses: u64,
    /// Estimates switched to.
    pub(crate) estimate_switches: u64,
    /// Estimates dropped because the GNSS fixes contradicted them
    /// (`odometry::fusion::Contradiction`).
    pub(crate) estimates_dropped: u64,
    /// Pose readers that took nothing for the pose budget (waits that ran
    /// out), and poses dropped at once for such a reader while its buffer
    /// stayed full (`TopicPublisher::stalls`).
    pub(crate) pose_reader_stalls: (u64, u64),
    /// Times the inputs went stale.
    pub(crate) stale_events: u64,
    /// Early wakeups before a wheel sample ([`odometry::cadence`]).
    pub(crate) early_wakeups: u64,
    /// Samples missing in the sequence numbers, per input topic
    /// (wheels, gnss, imu, heading, estimate).
    pub(crate) lost: [u64; 5],
    /// Input samples skipped as unusable (each logged).
    pub(crate) skipped: u64,
    /// Version of the estimate in use at the end.
    pub(crate) estimate_version: u64,
    /// What taking late samples in order did ([`odometry::rewind`]).
    pub(crate) rewind: RewindStats,
    /// The filter's counters at the end.
    pub(crate) fusion: FusionStats,
    /// GNSS fixes read at the receiver's epochs, fixes seen, and the RMS of
    /// the stamps' departures from the epochs, s
    /// ([`odometry::inputs::GnssEpochs::counts`]).
    pub(crate) gnss_epochs: (u64, u64, f64),
}

/// Warn about samples the sequencer dropped since the last report (and count them as skipped).
pub(crate) fn report_dropped(
    sequencer: &Sequencer,
    reported: &mut (u64, u64),
    summary: &mut ServeSummary,
) {
    let now = (sequencer.dropped_full(), sequencer.dropped_on_restart());
    if now.0 > reported.0 {
        summary.skipped += now.0 - reported.0;
        tracing::warn!(
            "odometry: {} samples dropped: more than {} waited for a wheel sample (the wheel stream \
             is missing); {} so far",
            now.0 - reported.0,
            odometry::inputs::MAX_HELD,
            now.0
        );
    }
    if now.1 > reported.1 {
        summary.skipped += now.1 - reported.1;
        tracing::warn!(
            "odometry: {} held samples of a publisher's earlier run dropped (it restarted)",
            now.1 - reported.1
        );
    }
    *reported = now;
}

/// The run's summary in the log: a warning when estimates were dropped or
/// pose readers stalled, then one line of counters. `gyro_bias_rad_s`: the
/// bias in use at the end; `window_s`: the rewind window set.
pub(crate) fn log_summary(summary: &ServeSummary, gyro_bias_rad_s: f64, window_s: f64) {
    let stats = &summary.fusion;
    if summary.pose_reader_stalls.0 > 0 || summary.estimates_dropped > 0 {
        tracing::warn!(
            "odometry: {} estimate(s) dropped as contradicted by the fixes; pose readers stalled \
             {} time(s), {} pose(s) dropped for them",
            summary.estimates_dropped,
            summary.pose_reader_stalls.0,
            summary.pose_reader_stalls.1
        );
    }
    tracing::info!(
        "odometry: {} wheel samples, {} poses published, {} estimate switch(es), {} samples lost on the bus; \
         GNSS {} accepted / {} gated out ({} of {} read at the receiver's epochs, their stamps {:.1} ms RMS off), \
         headings {} / {}; gyro bias {:.3e} rad/s ({} standstill measurement(s)); \
         {} late sample(s) taken in order ({} inputs processed again), {} later than the {} s window; \
         {} early wakeup(s) before a wheel sample",
        summary.wheel_samples,
        summary.poses,
        summary.estimate_switches,
        summary.lost.iter().sum::<u64>(),
        stats.gnss_accepted,
        stats.gnss_rejected,
        summary.gnss_epochs.0,
        summary.gnss_epochs.1,
        summary.gnss_epochs.2 * 1e3,
        stats.heading_accepted,
        stats.heading_rejected,
        gyro_bias_rad_s,
        stats.gyro_bias_standstills,
        summary.rewind.rewinds,
        summary.rewind.reprocessed,
        summary.rewind.beyond_window,
        window_s,
        summary.early_wakeups,
    );
}
