//! The dead-reckoning flags `odometry serve` and `odometry evaluate` share.

use odometry::dead_reckoning::{HeadingMode, OdometerConfig};

/// The dead-reckoning flags `odometry serve` and `odometry evaluate` share.
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct OdometerArgs {
    /// Heading source while dead-reckoning: `gyro` (default, see the README for
    /// why) or `wheels` (the paper's 2W model).
    #[arg(long, default_value = "gyro")]
    pub(crate) heading: HeadingMode,
    /// Do not learn the rear wheels' zero offsets at standstill (see the README).
    #[arg(long)]
    pub(crate) no_wheel_offsets: bool,
    /// Keep the calibrated gyro bias: do not measure it at standstill (see the README).
    #[arg(long)]
    pub(crate) no_standstill_gyro_bias: bool,
}

impl OdometerArgs {
    /// The odometer configuration these flags ask for.
    pub(crate) fn config(&self) -> OdometerConfig {
        OdometerConfig {
            heading: self.heading,
            learn_wheel_offsets: !self.no_wheel_offsets,
            learn_gyro_bias: !self.no_standstill_gyro_bias,
            ..OdometerConfig::default()
        }
    }
}
