//! `sensor-bridge simulate --like DRIVE`: the simulated twin of a recorded
//! drive (its path, timing, vehicle, sensors and outages), with the physics
//! a diagnosis found (`--effects-from`, `calibrator diagnose --json`) or none.

use crate::simulate_cmd::{SimulateArgs, SimulateError};
use drive_io::{read_drive, write_drive};
use simulator::twin::apply_finding;
use simulator::{simulate_twin, EffectForms, EffectSettings, SimError, TwinConfig, TwinOptions};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What the twin reads of a diagnosis's JSON (other keys are ignored).
#[derive(Debug, Clone, Default, serde::Deserialize)]
#[serde(default)]
pub struct EffectsFile {
    /// The accepted effects.
    pub findings: Vec<FindingEntry>,
    /// The information limit, for its GNSS error model (a comparison's
    /// JSON, `calibrator compare --json`, has it as `recording_noise`).
    #[serde(alias = "recording_noise")]
    pub information_limit: Option<InformationLimit>,
    /// The calibrated plain model.
    pub base_model: Option<BaseModel>,
    /// The wheels' speed reading beyond the catalogue that a comparison
    /// measured (`calibrator compare --json`); carried by the twin.
    pub twin_speed_map: Option<interfaces::speed_map::SpeedMap>,
    /// The wheels' yaw wander that a comparison measured (`calibrator
    /// compare --json`); carried by the twin.
    pub twin_yaw_wander: Option<interfaces::yaw_wander::YawWander>,
}

/// One finding: a catalogue id and its parameters in the reported units.
#[derive(Debug, Clone, Default, serde::Deserialize)]
#[serde(default)]
pub struct FindingEntry {
    /// Catalogue id, e.g. `side_slip`.
    pub effect: String,
    /// Parameter name -> value.
    pub parameters: BTreeMap<String, f64>,
}

/// The GNSS error model of a diagnosis: [white m, Gauss-Markov m, tau s].
#[derive(Debug, Clone, Default, serde::Deserialize)]
#[serde(default)]
pub struct InformationLimit {
    /// East axis.
    pub noise_east: Option<[f64; 3]>,
    /// The segments' length the error model was fitted over, s.
    pub segment_s: Option<f64>,
    /// North axis.
    pub noise_north: Option<[f64; 3]>,
}

/// The calibrated plain model of a diagnosis.
#[derive(Debug, Clone, Copy, serde::Deserialize)]
pub struct BaseModel {
    /// Rear-left circumference, m.
    pub c_rl_m: f64,
    /// Rear-right circumference, m.
    pub c_rr_m: f64,
    /// Track width, m.
    pub track_width_m: f64,
}

/// Why the twin failed.
#[derive(Debug, thiserror::Error)]
pub enum TwinError {
    /// The recording could not be read.
    #[error("reading {path}: {source}")]
    Read {
        /// The drive.
        path: PathBuf,
        /// The reader's error.
        source: drive_io::DriveError,
    },
    /// The effects file could not be read or parsed.
    #[error("--effects-from {path}: {reason}")]
    EffectsFile {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A finding the simulator cannot take.
    #[error("--effects-from {path}: findings[{index}] ({effect}): {source}")]
    Finding {
        /// The file.
        path: PathBuf,
        /// The entry's index.
        index: usize,
        /// Its effect id.
        effect: String,
        /// Why.
        source: SimError,
    },
    /// The simulation or writing failed.
    #[error(transparent)]
    Simulate(#[from] SimulateError),
}

impl From<SimError> for TwinError {
    fn from(e: SimError) -> Self {
        TwinError::Simulate(SimulateError::Sim(e))
    }
}

/// Read and parse an effects file.
pub fn read_effects_file(path: &Path) -> Result<EffectsFile, TwinError> {
    let bad = |reason: String| TwinError::EffectsFile {
        path: path.to_path_buf(),
        reason,
    };
    let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
    serde_json::from_str(&text).map_err(|e| bad(format!("not the expected JSON: {e}")))
}

/// The effects of a file's findings (from every effect off), with the
/// notes of the conversion.
pub fn effects_of(
    file: &EffectsFile,
    path: &Path,
) -> Result<(EffectSettings, Vec<String>), TwinError> {
    let mut effects = EffectSettings::none();
    let mut notes = Vec::new();
    for (index, f) in file.findings.iter().enumerate() {
        let n = apply_finding(&mut effects, &f.effect, &f.parameters).map_err(|source| {
            TwinError::Finding {
                path: path.to_path_buf(),
                index,
                effect: f.effect.clone(),
                source,
            }
        })?;
        notes.extend(n);
    }
    Ok((effects, notes))
}

/// The wheels' speed map a comparison's JSON asks the twin to carry
/// (`twin_speed_map`), checked.
pub fn speed_map_of(
    file: &EffectsFile,
    path: &Path,
) -> Result<Option<interfaces::speed_map::SpeedMap>, TwinError> {
    match &file.twin_speed_map {
        Some(m) if !m.is_valid() => Err(TwinError::EffectsFile {
            path: path.to_path_buf(),
            reason: "twin_speed_map: edges must ascend, with one value more than edges, all finite"
                .into(),
        }),
        m => Ok(m.clone()),
    }
}

/// The wheels' yaw wander a comparison's JSON asks the twin to carry
/// (`twin_yaw_wander`), checked.
pub fn yaw_wander_of(
    file: &EffectsFile,
    path: &Path,
) -> Result<Option<interfaces::yaw_wander::YawWander>, TwinError> {
    match file.twin_yaw_wander {
        Some(w) if !w.is_valid() => Err(TwinError::EffectsFile {
            path: path.to_path_buf(),
            reason: format!(
                "twin_yaw_wander: sigma_rad_s must lie within [0, 0.1] and tau_s within [0.01, 10000] (got {} rad/s, {} s)",
                w.sigma_rad_s, w.tau_s
            ),
        }),
        w => Ok(w),
    }
}

/// Build, simulate and write the twin; returns its length in seconds.
pub fn run(args: &SimulateArgs, like: &Path) -> Result<f64, TwinError> {
    let loaded = read_drive(like).map_err(|source| TwinError::Read {
        path: like.to_path_buf(),
        source,
    })?;
    for w in &loaded.warnings {
        tracing::warn!("{}: {w}", like.display());
    }
    let mut options = TwinOptions::new(&like.display().to_string());
    options.seed = args.seed;
    if let Some(f) = &args.effect_forms {
        options.effect_forms = EffectForms::from_name(f)?;
    }
    if let Some(path) = &args.effects_from {
        let file = read_effects_file(path)?;
        let (effects, notes) = effects_of(&file, path)?;
        for n in notes {
            tracing::warn!("{}: {n}", path.display());
        }
        options.effects = effects;
        if let Some(l) = &file.information_limit {
            if let (Some(e), Some(n)) = (l.noise_east, l.noise_north) {
                options.gnss_noise = Some((e, n));
                options.gnss_noise_segment_s = l.segment_s;
            }
        }
        options.base_model = file
            .base_model
            .map(|b| (b.c_rl_m, b.c_rr_m, b.track_width_m));
        options.speed_map = speed_map_of(&file, path)?;
        options.yaw_wander = yaw_wander_of(&file, path)?;
    }
    for spec in &args.effects {
        options.effects.apply_spec(spec)?;
    }
    let mut derived = TwinConfig::from_drive(&loaded.drive, &options)?;
    for spec in &args.sensors {
        derived.config.sensors.apply_spec(spec)?;
    }
    for n in &derived.notes {
        tracing::info!("twin of {}: {n}", like.display());
    }
    let drive = simulate_twin(&derived.config)?;
    if let Some(out) = &args.out {
        write_drive(&drive, out).map_err(|source| {
            TwinError::Simulate(SimulateError::Write {
                path: out.clone(),
                source,
            })
        })?;
    }
    tracing::info!(
        "simulated the twin of {}{}: seed {}, {:.1} s, {} wheel samples, {} fixes",
        like.display(),
        args.out
            .as_ref()
            .map_or(String::new(), |o| format!(" and wrote {}", o.display())),
        args.seed,
        drive.wheel_duration_s(),
        drive.wheels.samples.len(),
        drive.gnss.as_ref().map_or(0, Vec::len),
    );
    if let Some(opts) = args.publish_options() {
        sensor_bridge::replay::publish_drive(&drive, &opts, "sensor-bridge-simulate")
            .map_err(SimulateError::from)?;
    }
    Ok(drive.wheel_duration_s())
}

#[cfg(test)]
mod tests {
    use super::*;
    use simulator::GnssLeverArm;

    #[test]
    fn findings_map_onto_the_simulators_effects_and_unknown_ones_are_errors() {
        let json = r#"{"findings": [
            {"effect": "gnss_lever_arm", "parameters": {"x_m": 0.5, "y_m": -0.1}, "sigmas": {}},
            {"effect": "gyro_bias", "parameters": {"b_deg_h": 150.0}}
        ], "base_model": {"c_rl_m": 1.86, "c_rr_m": 1.87, "track_width_m": 1.45},
        "information_limit": {"noise_east": [0.1, 0.5, 30.0], "noise_north": [0.2, 0.7, 50.0]},
        "other": 3}"#;
        let file: EffectsFile = serde_json::from_str(json).unwrap();
        let (e, notes) = effects_of(&file, Path::new("d.json")).unwrap();
        assert!(notes.is_empty());
        assert_eq!(
            e.gnss_lever_arm,
            Some(GnssLeverArm {
                x_m: 0.5,
                y_m: -0.1
            })
        );
        assert_eq!(e.gyro_bias.map(|b| b.b_deg_h), Some(150.0));
        assert_eq!(file.base_model.map(|b| b.c_rr_m), Some(1.87));

        let bad: EffectsFile =
            serde_json::from_str(r#"{"findings": [{"effect": "warp_drive", "parameters": {}}]}"#)
                .unwrap();
        let err = effects_of(&bad, Path::new("d.json"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("d.json") && err.contains("findings[0]") && err.contains("warp_drive"),
            "{err}"
        );
        let bad: EffectsFile = serde_json::from_str(
            r#"{"findings": [{"effect": "side_slip", "parameters": {"k": 0.004}}]}"#,
        )
        .unwrap();
        let err = effects_of(&bad, Path::new("d.json"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("unknown parameter `k`"), "{err}");
    }

    #[test]
    fn a_comparisons_speed_map_is_carried_and_a_malformed_one_refused() {
        let json = r#"{"findings": [], "twin_speed_map": {
            "speed_m_s": {"edges": [8.0, 16.0], "values": [0.01, 0.0, -0.002]},
            "accel_m_s2": {"edges": [], "values": [0.0]}}}"#;
        let file: EffectsFile = serde_json::from_str(json).unwrap();
        let m = speed_map_of(&file, Path::new("c.json"))
            .unwrap()
            .expect("the map");
        assert_eq!(m.at(5.0, 0.0), 0.01);
        assert_eq!(m.at(20.0, 2.0), -0.002);
        let none: EffectsFile = serde_json::from_str(r#"{"findings": []}"#).unwrap();
        assert!(speed_map_of(&none, Path::new("c.json")).unwrap().is_none());
        let bad: EffectsFile = serde_json::from_str(
            r#"{"twin_speed_map": {"speed_m_s": {"edges": [8.0], "values": [0.01]},
                "accel_m_s2": {"edges": [], "values": [0.0]}}}"#,
        )
        .unwrap();
        let err = speed_map_of(&bad, Path::new("c.json"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("c.json") && err.contains("twin_speed_map"),
            "{err}"
        );
    }

    #[test]
    fn a_comparisons_yaw_wander_is_carried_and_a_malformed_one_refused() {
        let json = r#"{"findings": [], "twin_yaw_wander": {"sigma_rad_s": 0.004, "tau_s": 3.0}}"#;
        let file: EffectsFile = serde_json::from_str(json).unwrap();
        let w = yaw_wander_of(&file, Path::new("c.json"))
            .unwrap()
            .expect("a wander");
        assert_eq!((w.sigma_rad_s, w.tau_s), (0.004, 3.0));
        let none: EffectsFile = serde_json::from_str(r#"{"findings": []}"#).unwrap();
        assert!(yaw_wander_of(&none, Path::new("c.json")).unwrap().is_none());
        let bad: EffectsFile =
            serde_json::from_str(r#"{"twin_yaw_wander": {"sigma_rad_s": 0.004, "tau_s": 0.0}}"#)
                .unwrap();
        let err = yaw_wander_of(&bad, Path::new("c.json"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("c.json") && err.contains("twin_yaw_wander"),
            "{err}"
        );
    }
}
