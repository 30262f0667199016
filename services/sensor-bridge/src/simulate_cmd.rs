//! The `simulate` subcommand: arguments and the function the binary calls.

use drive_io::{write_drive, DriveError};
use sensor_bridge::replay::{publish_drive, Pacing, ReplayError, ReplayOptions};
use simulator::{
    simulate, EffectForms, EffectSettings, Scenario, SimConfig, SimError, VehicleKind, WheelWear,
};
use std::path::PathBuf;

/// `sensor-bridge simulate`: write a simulated drive (folder, or MCAP when OUT
/// ends in .mcap), and/or publish it live over iceoryx2 (`--publish`, as `replay`).
#[derive(Debug, Clone, clap::Args)]
pub struct SimulateArgs {
    /// Scenario: paper, garage, mixed or long.
    #[arg(long, required_unless_present = "like", conflicts_with = "like")]
    pub scenario: Option<String>,
    /// The twin of a recorded drive (a drive folder or .mcap): its path and
    /// speed over time, vehicle, sensor rates and noise, GNSS outages; the
    /// physics of --effects-from and --effect only (none by default).
    #[arg(long, value_name = "DRIVE", conflicts_with_all = ["vehicle", "wear", "duration", "unworn_circumference", "nominal_circumference", "no_default_effects"])]
    pub like: Option<PathBuf>,
    /// With --like: a diagnosis's JSON (`calibrator diagnose --json`): its
    /// `findings` become the twin's effects, its `information_limit`'s GNSS
    /// noise and its `base_model`'s circumferences and track are used.
    #[arg(long, value_name = "JSON", requires = "like")]
    pub effects_from: Option<PathBuf>,
    /// Seed of the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output: a drive folder, or an .mcap file (optional with --publish).
    #[arg(long, required_unless_present = "publish")]
    pub out: Option<PathBuf>,
    /// Publish the drive on the sensor topics, as `sensor-bridge replay` does
    /// (after writing it, when --out is given).
    #[arg(long)]
    pub publish: bool,
    /// With --publish: pace at FACTOR times real time (default 1).
    #[arg(
        long,
        value_name = "FACTOR",
        requires = "publish",
        conflicts_with = "max"
    )]
    pub speed: Option<f64>,
    /// With --publish: as fast as the subscribers take the samples, losing none.
    #[arg(long, requires = "publish")]
    pub max: bool,
    /// With --publish: wait until every published topic has N subscribers
    /// before the first sample (default: 1 with --max, 0 otherwise).
    #[arg(long, value_name = "N", requires = "publish")]
    pub wait_subscribers: Option<usize>,
    /// Effect knob, repeatable: ID=VALUE (main parameter), ID.PARAM=VALUE,
    /// ID=on (typical magnitude) or ID=off (also ID=0). E.g. side_slip=0.004,
    /// gnss_latency=0.08, gnss_lever_arm=1.2, gnss_lever_arm.y_m=0.3.
    #[arg(long = "effect", value_name = "ID=VALUE")]
    pub effects: Vec<String>,
    /// Start from every effect off (instead of the defaults: side_slip,
    /// load_transfer_radius and longitudinal_slip on) before applying --effect.
    #[arg(long)]
    pub no_default_effects: bool,
    /// Sensor setting, repeatable: KEY=VALUE, e.g. gnss.rate_hz=5,
    /// wheels.ticks_per_rev=48, gnss.outage_rate_per_h=6, imu.enabled=0.
    #[arg(long = "sensor", value_name = "KEY=VALUE")]
    pub sensors: Vec<String>,
    /// Length of the drive, s (loops repeat; the garage drive stays parked at its end).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Vehicle: compact, saloon or van.
    #[arg(long)]
    pub vehicle: Option<String>,
    /// Tyre wear (tread depth lost) RL,RR,FL,FR in mm, e.g. 3.5,2.5,0,0.
    #[arg(long, value_name = "RL,RR,FL,FR")]
    pub wear: Option<String>,
    /// Circumference of an unworn tyre, m (default: the vehicle's; 2.19 for paper).
    #[arg(long)]
    pub unworn_circumference: Option<f64>,
    /// The nominal circumference written to vehicle.toml (a calibrator's
    /// initial guess), m (default: the unworn circumference; 2.2 for paper).
    #[arg(long)]
    pub nominal_circumference: Option<f64>,
    /// How the vehicle effects act: `physical` (through the suspension's
    /// loads and the tyres' forces, each knob at a gain of its own and
    /// partly seen as other effects) or `catalogue` (each effect exactly
    /// as the physics catalogue writes it, so a knob means what a
    /// diagnosis's estimate means). Default: physical.
    #[arg(long, value_name = "FORMS")]
    pub effect_forms: Option<String>,
}

/// Why `simulate` failed.
#[derive(Debug, thiserror::Error)]
pub enum SimulateError {
    /// Bad arguments or a failed simulation.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// The drive could not be published.
    #[error("publishing the simulated drive: {0}")]
    Publish(#[from] ReplayError),
    /// The drive could not be written.
    #[error("writing {path}: {source}")]
    Write {
        /// The output path.
        path: PathBuf,
        /// The writer's error.
        source: DriveError,
    },
}

impl SimulateArgs {
    /// The simulation configuration these arguments describe.
    pub fn config(&self) -> Result<SimConfig, SimError> {
        let name = self.scenario.as_deref().ok_or_else(|| {
            SimError::InvalidConfig("a scenario is needed (or --like DRIVE)".into())
        })?;
        let mut c = SimConfig::new(Scenario::from_name(name)?, self.seed);
        if let Some(f) = &self.effect_forms {
            c.effect_forms = EffectForms::from_name(f)?;
        }
        if let Some(v) = &self.vehicle {
            c.vehicle = VehicleKind::from_name(v)?;
        }
        if self.no_default_effects {
            c.effects = EffectSettings::none();
        }
        for spec in &self.effects {
            c.effects.apply_spec(spec)?;
        }
        for spec in &self.sensors {
            c.sensors.apply_spec(spec)?;
        }
        c.duration_s = self.duration;
        if let Some(w) = &self.wear {
            let parts: Result<Vec<f64>, _> =
                w.split(',').map(|p| p.trim().parse::<f64>()).collect();
            match parts.as_deref() {
                Ok([rl, rr, fl, fr]) => {
                    c.wear_mm = WheelWear {
                        rl: *rl,
                        rr: *rr,
                        fl: *fl,
                        fr: *fr,
                    }
                }
                _ => {
                    return Err(SimError::InvalidConfig(format!(
                        "--wear `{w}`: expected four numbers RL,RR,FL,FR in mm"
                    )))
                }
            }
        }
        if self.unworn_circumference.is_some() {
            c.unworn_circumference_m = self.unworn_circumference;
        }
        if self.nominal_circumference.is_some() {
            c.nominal_circumference_m = self.nominal_circumference;
        }
        Ok(c)
    }

    /// The replay options of `--publish` (`None` without it).
    pub fn publish_options(&self) -> Option<ReplayOptions> {
        if !self.publish {
            return None;
        }
        let pacing = if self.max {
            Pacing::Max
        } else {
            Pacing::Speed(self.speed.unwrap_or(1.0))
        };
        let defaults = ReplayOptions::for_pacing(pacing);
        Some(ReplayOptions {
            wait_subscribers: self.wait_subscribers.unwrap_or(defaults.wait_subscribers),
            ..defaults
        })
    }
}

/// Simulate the drive, write it (`--out`) and publish it (`--publish`);
/// returns the drive's length in seconds.
pub fn run(args: &SimulateArgs) -> Result<f64, SimulateError> {
    let config = args.config()?;
    let drive = simulate(&config)?;
    if let Some(out) = &args.out {
        write_drive(&drive, out).map_err(|source| SimulateError::Write {
            path: out.clone(),
            source,
        })?;
    }
    let effects: Vec<String> = config.effects.to_truth_map().into_keys().collect();
    tracing::info!(
        "simulated{}: scenario {}, vehicle {}, seed {}, {:.1} s, {} wheel samples, effects on: [{}]",
        args.out
            .as_ref()
            .map_or(String::new(), |o| format!(" and wrote {}", o.display())),
        config.scenario.name(),
        config.vehicle.name(),
        config.seed,
        drive.wheel_duration_s(),
        drive.wheels.samples.len(),
        effects.join(", ")
    );
    if let Some(opts) = args.publish_options() {
        publish_drive(&drive, &opts, "sensor-bridge-simulate")?;
    }
    Ok(drive.wheel_duration_s())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: SimulateArgs,
    }

    #[test]
    fn arguments_make_a_configuration() {
        let cli = Cli::parse_from([
            "x",
            "--scenario",
            "garage",
            "--seed",
            "7",
            "--out",
            "/tmp/never-written",
            "--effect",
            "gnss_latency=0.05",
            "--effect",
            "side_slip=off",
            "--sensor",
            "gnss.rate_hz=5",
            "--vehicle",
            "van",
            "--wear",
            "3.5,2.5,0,0",
            "--duration",
            "30",
        ]);
        let c = cli.args.config().unwrap();
        assert_eq!(
            (c.scenario, c.seed, c.vehicle),
            (Scenario::Garage, 7, VehicleKind::Van)
        );
        assert_eq!(c.effects.gnss_latency.map(|l| l.tau_s), Some(0.05));
        assert!(c.effects.side_slip.is_none() && c.effects.longitudinal_slip.is_some());
        assert_eq!(c.sensors.gnss.rate_hz, 5.0);
        assert_eq!(c.wear_mm.rl, 3.5);
        assert_eq!(c.duration_s, Some(30.0));
        let bad = Cli::parse_from(["x", "--scenario", "moon", "--out", "o"])
            .args
            .config();
        assert!(matches!(bad, Err(SimError::UnknownScenario(_))));
        let bad = Cli::parse_from(["x", "--scenario", "paper", "--out", "o", "--wear", "1,2"])
            .args
            .config();
        assert!(bad.is_err());
        assert!(cli.args.publish_options().is_none());
    }

    #[test]
    fn publish_takes_the_replay_pacing_and_makes_out_optional() {
        let cli = Cli::parse_from(["x", "--scenario", "paper", "--publish", "--max"]);
        assert_eq!(cli.args.out, None);
        let opts = cli.args.publish_options().unwrap();
        assert_eq!((opts.pacing, opts.wait_subscribers), (Pacing::Max, 1));
        let cli = Cli::parse_from(["x", "--scenario", "paper", "--publish", "--speed", "4"]);
        let opts = cli.args.publish_options().unwrap();
        assert_eq!(
            (opts.pacing, opts.wait_subscribers),
            (Pacing::Speed(4.0), 0)
        );
        // Without --publish: --out is required and the pacing flags are refused.
        assert!(Cli::try_parse_from(["x", "--scenario", "paper"]).is_err());
        assert!(Cli::try_parse_from(["x", "--scenario", "paper", "--out", "o", "--max"]).is_err());
        assert!(Cli::try_parse_from([
            "x",
            "--scenario",
            "paper",
            "--publish",
            "--max",
            "--speed",
            "2"
        ])
        .is_err());
    }
}
