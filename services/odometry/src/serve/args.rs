//! The flags of `odometry serve`.

use crate::odometer_args::OdometerArgs;
use odometry::rewind::RewindConfig;
use std::path::PathBuf;

/// Arguments of `odometry serve`.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct ServeArgs {
    /// Vehicle parameters: a vehicle.toml, or a drive (folder or .mcap) to take
    /// them from (nominal circumference, track, GNSS antenna position).
    #[arg(long, value_name = "PATH")]
    pub(crate) vehicle: PathBuf,
    /// Start from this estimate (`calibrator calibrate --json`) instead of the
    /// nominal values; an estimate on the bus still replaces it.
    #[arg(long, value_name = "EST.json")]
    pub(crate) estimate: Option<PathBuf>,
    /// Ignore estimates on the bus (keep the nominal or --estimate values).
    #[arg(long)]
    pub(crate) no_bus_estimate: bool,
    /// Dead-reckoning settings.
    #[command(flatten)]
    pub(crate) odometer: OdometerArgs,
    /// Without an accepted GNSS fix for this long, the mode is DeadReckoning, s.
    #[arg(long, value_name = "S", default_value_t = 1.0)]
    pub(crate) gnss_timeout: f64,
    /// Without a wheel sample for this long (wall clock), the inputs are stale, s.
    #[arg(long, value_name = "S", default_value_t = 1.0)]
    pub(crate) stale_after: f64,
    /// A sample that arrives up to this much drive time after newer ones (a
    /// GNSS receiver's delivery latency, a separate publisher) is taken in
    /// its place: the filter goes back and processes again, s (0 = apply
    /// late samples when they come).
    #[arg(long, value_name = "S", default_value_t = RewindConfig::default().window_s)]
    pub(crate) rewind_window: f64,
    /// Wake this many ms (to one more) before the next wheel sample is due and
    /// pass once through the serving loop without it, so that the sample's own
    /// pass runs on warm caches (0 = only wake for samples; see the README).
    #[arg(long, value_name = "MS", default_value_t = 1)]
    pub(crate) early_wakeup_ms: u64,
    /// Log a status line every this many seconds of drive time (0 = never).
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    pub(crate) status_every: f64,
    /// Stop when the wheel stream ends (its publisher says so) instead of
    /// waiting for more.
    #[arg(long)]
    pub(crate) exit_on_end: bool,
    /// At exit, write one line per pose published for a wheel sample to FILE: its wheel time and
    /// the wall-clock time at which it was handed to the publisher (both ns), so latency
    /// can be measured across processes (the clock is the machine's one).
    #[arg(long, value_name = "FILE")]
    pub(crate) latency_trace: Option<PathBuf>,
    /// Keep the last pose in this JSON file (every second of drive time while
    /// the car moves, when the inputs go stale, at exit) and start from it
    /// when the wheel counts or a clean stop at a standstill say the car is
    /// still there: a car parked in a garage powers on without GNSS and
    /// dead-reckons from where it stood (README, "Deploying in a vehicle").
    #[arg(long, value_name = "FILE")]
    pub(crate) pose_state: Option<PathBuf>,
    /// iceoryx2 prefix of the graph (default: $WHEELCAL_IOX_PREFIX, else iceoryx2's).
    #[arg(long, value_name = "PREFIX")]
    pub(crate) iox_prefix: Option<String>,
    /// iceoryx2 root path of the graph (default: $WHEELCAL_IOX_ROOT, else iceoryx2's).
    #[arg(long, value_name = "DIR")]
    pub(crate) iox_root: Option<PathBuf>,
}
