//! What the service runs with: the flags checked, the vehicle and the
//! initial estimate read.

use super::{ServeArgs, ServeError, RESTART_BACKSTEP_S};
use interfaces::bus::BusSettings;
use interfaces::drive::VehicleParams;
use odometry::fusion::FusionConfig;
use odometry::rewind::RewindConfig;
use std::path::{Path, PathBuf};
use std::time::Duration;
use vehicle_model::estimate::{gnss_lever_arm, Estimate};

/// Everything the service runs with, files already read.
#[derive(Debug, Clone)]
pub(crate) struct ServeConfig {
    /// Where the graph's iceoryx2 resources live.
    pub(crate) bus: BusSettings,
    /// The vehicle (nominal parameters, antenna).
    pub(crate) vehicle: VehicleParams,
    /// The estimate to start from (`None`: nominal), version 0.
    pub(crate) initial: Option<Estimate>,
    /// Take estimates from the bus.
    pub(crate) bus_estimates: bool,
    /// Filter settings.
    pub(crate) fusion: FusionConfig,
    /// How far back late samples are taken in order.
    pub(crate) rewind: RewindConfig,
    /// Wall-clock time without wheel samples after which the inputs are stale.
    pub(crate) stale_after: Duration,
    /// How long before the next wheel sample the loop wakes (zero: not early).
    pub(crate) early_wakeup: Duration,
    /// Drive-time period of the status line, s (0 = none).
    pub(crate) status_every_s: f64,
    /// Stop when the wheel stream ends.
    pub(crate) exit_on_end: bool,
    /// Where to write the publish-time trace at exit (see [`ServeArgs::latency_trace`]).
    pub(crate) latency_trace: Option<PathBuf>,
    /// Where the last pose is kept, and started from (see [`ServeArgs::pose_state`]).
    pub(crate) pose_state: Option<PathBuf>,
}

impl ServeConfig {
    /// The settings of `args`, reading the vehicle and estimate files.
    pub(crate) fn from_args(args: &ServeArgs) -> Result<ServeConfig, ServeError> {
        let vehicle = load_vehicle(&args.vehicle)?;
        let initial = match args.estimate.as_deref() {
            Some(path) => {
                let (estimate, made_for) = drive_io::read_estimate_with_vehicle(path)?;
                if let Some(w) = made_for.and_then(|v| {
                    vehicle_model::estimate_vehicle::other_vehicle_warning(
                        &v,
                        &vehicle,
                        &path.display().to_string(),
                        &format!("the vehicle file {}", args.vehicle.display()),
                    )
                }) {
                    tracing::warn!("{w}");
                }
                Some(estimate)
            }
            None => None,
        };
        let positive = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(v)
            } else {
                Err(ServeError::Config(format!(
                    "{name} {v} must be a positive number of seconds"
                )))
            }
        };
        // Beyond RESTART_BACKSTEP_S a late sample means a restarted publisher.
        let rewind_window = |v: f64| {
            if v.is_finite() && (0.0..=RESTART_BACKSTEP_S).contains(&v) {
                Ok(v)
            } else {
                Err(ServeError::Config(format!(
                    "--rewind-window {v} must be 0 to {RESTART_BACKSTEP_S} s: a sample older \
                     than that means its publisher restarted, and the filter starts over"
                )))
            }
        };
        let mut settings = BusSettings::from_env();
        if let Some(p) = &args.iox_prefix {
            settings.prefix = Some(p.clone());
        }
        if let Some(r) = &args.iox_root {
            settings.root = Some(r.clone());
        }
        let (lever_arm_m, measured) = gnss_lever_arm(&vehicle, initial.as_ref());
        let fusion = FusionConfig {
            odometer: args.odometer.config(),
            lever_arm_m,
            lever_arm_from_estimates: !measured,
            gnss_timeout_s: positive("--gnss-timeout", args.gnss_timeout)?,
            ..FusionConfig::default()
        };
        Ok(ServeConfig {
            bus: settings,
            vehicle,
            initial,
            bus_estimates: !args.no_bus_estimate,
            fusion,
            rewind: RewindConfig {
                window_s: rewind_window(args.rewind_window)?,
                ..RewindConfig::default()
            },
            stale_after: Duration::from_secs_f64(positive("--stale-after", args.stale_after)?),
            early_wakeup: Duration::from_millis(args.early_wakeup_ms),
            status_every_s: args.status_every.max(0.0),
            exit_on_end: args.exit_on_end,
            latency_trace: args.latency_trace.clone(),
            pose_state: args.pose_state.clone(),
        })
    }
}

/// Read vehicle parameters from a vehicle.toml or a drive
/// ([`drive_io::read_vehicle`]); its warnings go to the log.
pub(crate) fn load_vehicle(path: &Path) -> Result<VehicleParams, ServeError> {
    let loaded = drive_io::read_vehicle(path).map_err(|e| ServeError::Vehicle {
        path: path.to_path_buf(),
        detail: e.to_string(),
    })?;
    for warning in &loaded.warnings {
        tracing::warn!("odometry: {warning}");
    }
    loaded
        .vehicle
        .check_plausible()
        .map_err(|detail| ServeError::Vehicle {
            path: path.to_path_buf(),
            detail,
        })?;
    Ok(loaded.vehicle)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;
    use vehicle_model::estimate::OdometryParams;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        serve: ServeArgs,
    }

    #[test]
    fn the_rewind_window_is_read_and_one_beyond_a_restart_is_refused() {
        let vehicle = tempfile::tempdir().expect("tempdir");
        let toml = vehicle.path().join("vehicle.toml");
        std::fs::write(
            &toml,
            "track_width_m = 1.5\nnominal_circumference_m = 2.0\n",
        )
        .expect("write");
        let config = |window: &str| {
            let cli = Cli::try_parse_from([
                "serve",
                "--vehicle",
                toml.to_str().expect("utf-8"),
                &format!("--rewind-window={window}"),
            ])
            .expect("arguments");
            ServeConfig::from_args(&cli.serve)
        };
        assert_eq!(config("0.3").expect("valid").rewind.window_s, 0.3);
        assert_eq!(config("0").expect("off").rewind.window_s, 0.0);
        for bad in ["1.5", "-0.1", "NaN"] {
            let err = config(bad).expect_err(bad).to_string();
            assert!(
                err.contains("--rewind-window") && err.contains("restarted"),
                "{err}"
            );
        }
    }

    #[test]
    fn a_measured_antenna_wins_over_the_initial_estimates() {
        let mut vehicle = VehicleParams {
            name: None,
            track_width_m: 1.5,
            nominal_circumference_m: 2.0,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: Default::default(),
        };
        let estimate = Estimate {
            params: OdometryParams::nominal(&vehicle),
            sigma_m: None,
            quality_m: None,
            antenna_m: Some([0.5, -0.3]),
            antenna_sigma_m: None,
            effects: vehicle_model::effects::WheelEffects::default(),
            clocks: Default::default(),
        };
        assert_eq!(gnss_lever_arm(&vehicle, None), ([0.0, 0.0], false));
        assert_eq!(
            gnss_lever_arm(&vehicle, Some(&estimate)),
            ([0.5, -0.3], false)
        );
        vehicle.gnss.antenna_x_m = Some(1.1);
        assert_eq!(
            gnss_lever_arm(&vehicle, Some(&estimate)),
            ([1.1, 0.0], true)
        );
    }
}
