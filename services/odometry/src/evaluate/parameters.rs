//! The parameters an evaluation dead-reckons with: an estimate's (checked
//! against the drive's vehicle, with a warning when it was made for
//! another vehicle), or the vehicle's nominal values. `odometry evaluate`
//! and the Python package take them from here.

use interfaces::drive::Drive;
use vehicle_model::effects::EffectTerms;
use vehicle_model::estimate::{Estimate, OdometryParams, StreamClocks};
use vehicle_model::estimate_gate::EstimateGate;
use vehicle_model::estimate_vehicle::{other_vehicle_warning, EstimateVehicle};

/// What the evaluation dead-reckons with, and where it comes from.
#[derive(Debug, Clone)]
pub struct Parameters {
    /// The 2W model's parameters.
    pub params: OdometryParams,
    /// Where they come from, as the report names it (the estimate's name,
    /// or `nominal (vehicle.toml)`).
    pub source: String,
    /// The estimate's GNSS antenna position, m.
    pub antenna: Option<[f64; 2]>,
    /// Its 1-sigma, m.
    pub antenna_sigma: Option<[f64; 2]>,
    /// The effect terms the estimate carries.
    pub effects: EffectTerms,
    /// The estimate's sensor clocks.
    pub clocks: StreamClocks,
    /// A warning when the estimate was made for another vehicle.
    pub other_vehicle: Option<String>,
}

/// An estimate that is not one of the drive's vehicle.
#[derive(Debug, thiserror::Error)]
#[error("{source_name}: not an estimate of the vehicle of {drive}: {reason}")]
pub struct NotThisVehicle {
    /// The estimate's name (its path).
    pub source_name: String,
    /// The drive's name (its path).
    pub drive: String,
    /// Why the estimate gate refused it.
    pub reason: String,
}

impl Parameters {
    /// The vehicle's nominal values (no estimate).
    pub fn nominal(drive: &Drive) -> Parameters {
        Parameters {
            params: OdometryParams::nominal(&drive.vehicle),
            source: "nominal (vehicle.toml)".to_string(),
            antenna: None,
            antenna_sigma: None,
            effects: EffectTerms::default(),
            clocks: StreamClocks::default(),
            other_vehicle: None,
        }
    }

    /// `estimate`, named `source_name`, made for `made_for` (when the file
    /// says), checked against the vehicle of `drive` (named `drive_name`)
    /// by the estimate gate.
    pub fn of_estimate(
        estimate: Estimate,
        made_for: Option<EstimateVehicle>,
        source_name: &str,
        drive: &Drive,
        drive_name: &str,
    ) -> Result<Parameters, NotThisVehicle> {
        let other_vehicle = made_for
            .and_then(|v| other_vehicle_warning(&v, &drive.vehicle, source_name, drive_name));
        EstimateGate::new(&drive.vehicle)
            .check(0, None, &estimate)
            .map_err(|e| NotThisVehicle {
                source_name: source_name.to_string(),
                drive: drive_name.to_string(),
                reason: e.to_string(),
            })?;
        Ok(Parameters {
            params: estimate.params,
            source: source_name.to_string(),
            antenna: estimate.antenna_m,
            antenna_sigma: estimate.antenna_sigma_m,
            effects: estimate.effects.into(),
            clocks: estimate.clocks,
            other_vehicle,
        })
    }
}
