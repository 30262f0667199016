//! The accepted estimate of `calibrator serve`: the version the service
//! gives it, its state file and its wire form.
//!
//! The state file is JSON: the fields of `calibrate --json` the odometry reads
//! (those of [`LiveEstimate`]) plus `version`, `quality_m` and `t_s`. It is
//! written atomically (a temporary file renamed over it).

use calibrator::live::LiveEstimate;
use interfaces::effects::Effect;
use interfaces::wire::{CircumferenceEstimate, Header, ModelExtension, MAX_EXTENSIONS};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use vehicle_model::effects::EffectTerms;
use vehicle_model::estimate::antenna_extension;

/// An accepted estimate, as published and as kept in the state file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Accepted {
    /// Increases with every accepted estimate (1 = the first).
    pub version: u64,
    /// The estimate; its fields sit beside `version` in the JSON.
    #[serde(flatten)]
    pub estimate: LiveEstimate,
}

/// The state file could not be read or written.
#[derive(Debug, thiserror::Error)]
#[error("state file {path}: {detail}")]
pub struct StateError {
    /// The file.
    pub path: PathBuf,
    /// What went wrong.
    pub detail: String,
}

impl Accepted {
    /// The wire form.
    pub fn to_wire(self) -> CircumferenceEstimate {
        let e = &self.estimate;
        let mut extensions = [ModelExtension::default(); MAX_EXTENSIONS];
        let mut count = 0;
        // A side-slip gain the diagnosis accepted goes with its other terms.
        if let Some(k) = e
            .side_slip_gain_rad_per_m_s2
            .filter(|_| e.effects.k_beta == 0.0)
        {
            extensions[0] = ModelExtension {
                effect_code: Effect::SideSlip.code(),
                param_count: 1,
                params: [k, 0.0, 0.0, 0.0],
            };
            count = 1;
        }
        if let Some(a) = e.gnss_antenna_m {
            extensions[count] = antenna_extension(a, e.sigma_gnss_antenna_m);
            count += 1;
        }
        // The clocks before the effect terms: a clock left out would put
        // every pose off by its offset.
        for x in e
            .clock_offsets
            .stream_clocks()
            .to_extensions()
            .into_iter()
            .chain(EffectTerms::from(e.effects).to_extensions())
        {
            if count < MAX_EXTENSIONS {
                extensions[count] = x;
                count += 1;
            }
        }
        CircumferenceEstimate {
            header: Header::from_seconds(e.t_s, 0),
            version: self.version,
            c_rl_m: e.circumference_m.rl,
            c_rr_m: e.circumference_m.rr,
            sigma_rl_m: e.sigma_m.rl,
            sigma_rr_m: e.sigma_m.rr,
            track_width_m: e.track_width_m,
            gyro_bias_rad_s: e.gyro_bias_rad_s,
            gyro_scale: e.gyro_scale,
            quality_m: e.quality_m,
            extension_count: count as u32,
            _pad: 0,
            extensions,
        }
    }

    fn is_usable(&self) -> bool {
        let e = &self.estimate;
        let pos = |v: f64| v.is_finite() && v > 0.0;
        pos(e.circumference_m.rl)
            && pos(e.circumference_m.rr)
            && pos(e.track_width_m)
            && e.gyro_bias_rad_s.is_finite()
            && e.gyro_scale.is_finite()
    }
}

/// Read the state file; `Ok(None)` when it does not exist.
pub fn load_state(path: &Path) -> Result<Option<Accepted>, StateError> {
    let text = match drive_io::read_state_text(path, MAX_STATE_BYTES) {
        Ok(Some(t)) => t,
        Ok(None) => return Ok(None),
        Err(e) => {
            return Err(StateError {
                path: path.to_path_buf(),
                detail: e.to_string(),
            })
        }
    };
    let a: Accepted = serde_json::from_str(&text).map_err(|e| StateError {
        path: path.to_path_buf(),
        detail: format!("line {}, column {}: {e}", e.line(), e.column()),
    })?;
    if !a.is_usable() {
        return Err(StateError {
            path: path.to_path_buf(),
            detail: "circumferences and track must be positive, gyro values finite".to_string(),
        });
    }
    Ok(Some(a))
}

/// The largest state file read, bytes (an accepted estimate is under 1 kB).
pub const MAX_STATE_BYTES: u64 = 64 * 1024;

/// Write the state file durably ([`drive_io::write_durably`]: a fresh 0600
/// temporary file, fsynced, renamed over `path`, the directory fsynced), so
/// that an accepted estimate survives a power loss and a planted link is
/// never followed.
pub fn save_state(path: &Path, a: &Accepted) -> Result<(), StateError> {
    let err = |e: std::io::Error| StateError {
        path: path.to_path_buf(),
        detail: e.to_string(),
    };
    let text = serde_json::to_string_pretty(a).map_err(|e| StateError {
        path: path.to_path_buf(),
        detail: e.to_string(),
    })?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(err)?;
    }
    drive_io::write_durably(path, (text + "\n").as_bytes()).map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;
    use calibrator::RearPair;

    fn accepted() -> Accepted {
        Accepted {
            version: 3,
            estimate: LiveEstimate {
                t_s: 12.5,
                circumference_m: RearPair { rl: 1.98, rr: 1.99 },
                sigma_m: RearPair { rl: 1e-3, rr: 2e-3 },
                track_width_m: 1.52,
                gyro_bias_rad_s: 0.001,
                gyro_scale: -0.01,
                side_slip_gain_rad_per_m_s2: Some(0.004),
                gnss_antenna_m: Some([0.5, -0.3]),
                sigma_gnss_antenna_m: Some([0.02, 0.03]),
                quality_m: 0.8,
                effects: Default::default(),
                clock_offsets: calibrator::live::LiveClocks {
                    gnss_s: calibrator::live::LiveClock {
                        offset_s: Some(-0.4),
                        applied: true,
                        drift: calibrator::live::LiveDrift {
                            drift_ppm: Some(-150.0),
                            ref_t_s: Some(600.0),
                            applied: true,
                        },
                    },
                    imu_s: Default::default(),
                },
            },
        }
    }

    #[test]
    fn the_state_file_round_trips_and_reads_as_a_calibration_json() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub/state.json");
        assert_eq!(load_state(&path).unwrap(), None);
        save_state(&path, &accepted()).unwrap();
        assert_eq!(load_state(&path).unwrap(), Some(accepted()));
        // The odometry reads it like `calibrate --json` output.
        let text = std::fs::read_to_string(&path).unwrap();
        let est = vehicle_model::estimate::Estimate::from_json_str(&text, "state").unwrap();
        assert_eq!(est.params.two_wheel.c_rr, 1.99);
        assert_eq!(est.params.gyro_scale, -0.01);
        assert_eq!(est.antenna_m, Some([0.5, -0.3]));
        assert_eq!(est.antenna_sigma_m, Some([0.02, 0.03]));
        // A state file from before the antenna field still loads.
        let old = text
            .replace("\"gnss_antenna_m\"", "\"unknown_field\"")
            .replace("\"sigma_gnss_antenna_m\"", "\"unknown_field_2\"");
        std::fs::write(&path, old).unwrap();
        assert_eq!(
            load_state(&path).unwrap().unwrap().estimate.gnss_antenna_m,
            None
        );
        std::fs::write(&path, "{\"version\": 1}").unwrap();
        let err = load_state(&path).unwrap_err().to_string();
        assert!(
            err.contains("state.json") && err.contains("missing field"),
            "{err}"
        );
    }

    /// The state file is written through a fresh private temporary file
    /// (a link planted at the old fixed temporary name is not followed), and
    /// only a small regular file is read.
    #[test]
    fn the_state_file_is_written_safely_and_read_with_bounds() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("state.json");
        let victim = dir.path().join("victim");
        std::fs::write(&victim, "keep me").unwrap();
        std::os::unix::fs::symlink(&victim, dir.path().join("state.json.tmp")).unwrap();
        save_state(&path, &accepted()).unwrap();
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep me");
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o600);
        assert_eq!(load_state(&path).unwrap(), Some(accepted()));
        let zero = dir.path().join("zero.json");
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        let e = load_state(&zero).unwrap_err().to_string();
        assert!(e.contains("character device"), "{e}");
        let big = dir.path().join("big.json");
        std::fs::write(&big, vec![b' '; MAX_STATE_BYTES as usize + 1]).unwrap();
        assert!(load_state(&big)
            .unwrap_err()
            .to_string()
            .contains("bytes allowed"));
    }

    #[test]
    fn the_wire_form_carries_every_value() {
        let w = accepted().to_wire();
        assert_eq!(w.version, 3);
        assert_eq!((w.c_rl_m, w.c_rr_m, w.sigma_rr_m), (1.98, 1.99, 2e-3));
        assert_eq!(w.quality_m, 0.8);
        assert_eq!(w.extension_count, 3);
        assert_eq!(w.extensions[0].effect_code, Effect::SideSlip.code());
        assert_eq!(w.extensions[0].params[0], 0.004);
        // The odometry reads the antenna back from the second extension.
        let est = vehicle_model::estimate::Estimate::from_wire(&w).unwrap();
        assert_eq!(est.antenna_m, Some([0.5, -0.3]));
        assert_eq!(est.fusable_antenna(), Some([0.5, -0.3]));
        // The clocks the calibration applied, as the file's reader sees them.
        let c = est.clocks;
        assert_eq!(
            (c.gnss_late_s, c.gnss_drift_ppm, c.gnss_ref_t_s),
            (-0.4, -150.0, 600.0)
        );
        assert_eq!(c.imu_late_s, 0.0);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("state.json");
        save_state(&path, &accepted()).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let from_file = vehicle_model::estimate::Estimate::from_json_str(&text, "state").unwrap();
        assert_eq!(from_file.clocks, c);
        assert_eq!(w.header.t_ns, 12_500_000_000);
    }

    #[test]
    fn a_diagnosis_s_terms_travel_on_the_wire_and_in_the_state_file() {
        let mut a = accepted();
        a.estimate.effects = vehicle_model::effects::WheelEffects {
            track_rel: 0.02,
            k_beta: 0.005,
            ..Default::default()
        };
        let w = a.to_wire();
        let est = vehicle_model::estimate::Estimate::from_wire(&w).unwrap();
        assert_eq!(est.effects.track_rel, 0.02);
        // The diagnosis's side-slip replaces the calibration's gain: one extension.
        assert_eq!(est.effects.k_beta, 0.005);
        let slips = w.extensions[..w.extension_count as usize]
            .iter()
            .filter(|x| x.effect_code == Effect::SideSlip.code())
            .count();
        assert_eq!(slips, 1);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("state.json");
        save_state(&path, &a).unwrap();
        assert_eq!(load_state(&path).unwrap(), Some(a));
        // A state file without terms (written before they existed) reads as plain.
        save_state(&path, &accepted()).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(!text.contains("effects"), "{text}");
        assert!(load_state(&path)
            .unwrap()
            .unwrap()
            .estimate
            .effects
            .is_plain());
    }
}
