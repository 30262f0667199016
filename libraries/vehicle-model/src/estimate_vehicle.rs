//! The vehicle an estimate was made for, and how it differs from the
//! vehicle of a drive it is applied to: the calibrator's JSON carries the
//! `vehicle.toml` of its drive (`vehicle`; older files only their `nominal`
//! circumference and track), and an estimate applied to a drive of another
//! vehicle is said plainly, not silently used.

use crate::estimate::ParamsError;
use interfaces::drive::VehicleParams;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

/// Nominal values closer than this are the same, m (the JSON keeps every
/// digit of `vehicle.toml`; a difference is another file).
const SAME_M: f64 = 1e-6;

/// The vehicle an estimate was made for.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimateVehicle {
    /// `name` of its `vehicle.toml`, when given.
    pub name: Option<String>,
    /// Nominal circumference, m.
    pub nominal_circumference_m: f64,
    /// Nominal rear track, m.
    pub track_width_m: f64,
    /// Wheelbase, m, when given.
    pub wheelbase_m: Option<f64>,
    /// Encoder ticks per revolution, when given.
    pub ticks_per_rev: Option<f64>,
}

/// The part of an estimate file that says whom it was made for: the
/// [`EstimateFile`](crate::estimate_file::EstimateFile) fields `vehicle`
/// and `nominal`, read alone (an estimate without circumferences still
/// says its vehicle).
#[derive(Debug, Deserialize)]
struct MadeForFields {
    #[serde(default)]
    vehicle: Option<VehicleParams>,
    #[serde(default)]
    nominal: Option<NominalFields>,
}

impl EstimateVehicle {
    /// The vehicle of the calibrator's JSON `text` (`source` names it in
    /// errors): its `vehicle`, else its `nominal` values; `None` when it
    /// carries neither (a hand-written estimate).
    pub fn from_json_str(text: &str, source: &str) -> Result<Option<EstimateVehicle>, ParamsError> {
        let parsed: MadeForFields =
            serde_json::from_str(text).map_err(|e| json_error(&e, source))?;
        Ok(made_for(parsed.vehicle.as_ref(), parsed.nominal.as_ref()))
    }

    /// The identity of `vehicle`.
    pub fn of(vehicle: &VehicleParams) -> EstimateVehicle {
        EstimateVehicle {
            name: vehicle.name.clone(),
            nominal_circumference_m: vehicle.nominal_circumference_m,
            track_width_m: vehicle.track_width_m,
            wheelbase_m: vehicle.wheelbase_m,
            ticks_per_rev: vehicle.ticks_per_rev,
        }
    }

    /// Every way `drive`'s vehicle differs from this one in what the
    /// odometry uses (nominal circumference, track, wheelbase, encoder), in
    /// plain words; empty: the same vehicle as far as the files tell. A
    /// value only one side gives is not a difference, nor is the name
    /// alone (free text: it often names the drive, not the car).
    pub fn differences(&self, drive: &VehicleParams) -> Vec<String> {
        let mut out = Vec::new();
        let mut metres = |what: &str, a: f64, b: f64| {
            if (a - b).abs() > SAME_M {
                out.push(format!(
                    "{what} {a} m in the estimate, {b} m in the drive's vehicle.toml"
                ));
            }
        };
        metres(
            "the nominal circumference is",
            self.nominal_circumference_m,
            drive.nominal_circumference_m,
        );
        metres("the rear track is", self.track_width_m, drive.track_width_m);
        if let (Some(a), Some(b)) = (self.wheelbase_m, drive.wheelbase_m) {
            metres("the wheelbase is", a, b);
        }
        if let (Some(a), Some(b)) = (self.ticks_per_rev, drive.ticks_per_rev) {
            if a != b {
                out.push(format!(
                    "the encoder has {a} ticks per revolution in the estimate, {b} in the drive's vehicle.toml"
                ));
            }
        }
        out
    }
}

/// The warning to give when an estimate made for `made_for` is applied to
/// a drive of `drive` (named `drive_name`), or `None` when they agree.
pub fn other_vehicle_warning(
    made_for: &EstimateVehicle,
    drive: &VehicleParams,
    estimate_name: &str,
    drive_name: &str,
) -> Option<String> {
    let mut d = made_for.differences(drive);
    if d.is_empty() {
        return None;
    }
    if let (Some(a), Some(b)) = (&made_for.name, &drive.name) {
        if a.trim() != b.trim() {
            d.insert(
                0,
                format!("it names the vehicle \"{a}\", the drive \"{b}\""),
            );
        }
    }
    Some(format!(
        "the estimate {estimate_name} was made for another vehicle than the one of {drive_name}: {}; \
         its circumferences may not fit this car",
        d.join("; ")
    ))
}

/// `nominal`: the values the calibration started from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NominalFields {
    /// The nominal circumference of every wheel, m.
    pub circumference_m: f64,
    /// The nominal rear track, m.
    pub track_width_m: f64,
    /// Any other field.
    #[serde(flatten)]
    pub report: Map<String, Value>,
}

/// A serde_json error as a [`ParamsError`] naming `source`.
pub(crate) fn json_error(e: &serde_json::Error, source: &str) -> ParamsError {
    ParamsError::Json {
        source_name: source.to_string(),
        line: e.line(),
        column: e.column(),
        message: e.to_string(),
    }
}

/// The vehicle of an estimate file's `vehicle`, else of its `nominal`.
pub(crate) fn made_for(
    vehicle: Option<&VehicleParams>,
    nominal: Option<&NominalFields>,
) -> Option<EstimateVehicle> {
    match (vehicle, nominal) {
        (Some(v), _) => Some(EstimateVehicle::of(v)),
        (None, Some(n)) => Some(EstimateVehicle {
            name: None,
            nominal_circumference_m: n.circumference_m,
            track_width_m: n.track_width_m,
            wheelbase_m: None,
            ticks_per_rev: None,
        }),
        (None, None) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vehicle(name: Option<&str>, c: f64, track: f64) -> VehicleParams {
        VehicleParams {
            name: name.map(str::to_string),
            track_width_m: track,
            nominal_circumference_m: c,
            wheelbase_m: Some(2.7),
            ticks_per_rev: None,
            gnss: Default::default(),
        }
    }

    #[test]
    fn the_same_vehicle_has_no_difference() {
        let v = vehicle(Some("saloon"), 1.95, 1.55);
        assert!(EstimateVehicle::of(&v).differences(&v).is_empty());
    }

    #[test]
    fn another_vehicle_is_named_field_by_field() {
        let made = EstimateVehicle::of(&vehicle(Some("saloon"), 1.95, 1.55));
        let other = vehicle(Some("van"), 2.10, 1.70);
        let d = made.differences(&other);
        assert_eq!(d.len(), 2, "{d:?}");
        assert!(d[0].contains("1.95 m in the estimate, 2.1 m"));
        let w = other_vehicle_warning(&made, &other, "est.json", "drive").expect("warned");
        assert!(
            w.contains("est.json") && w.contains("another vehicle"),
            "{w}"
        );
        assert!(w.contains("\"saloon\"") && w.contains("\"van\""), "{w}");
    }

    #[test]
    fn a_name_alone_is_no_other_vehicle() {
        // The WID drives name the trial in vehicle.toml; the car is the same.
        let made = EstimateVehicle::of(&vehicle(Some("Roomster (trial02)"), 1.85, 1.45));
        let drive = vehicle(Some("Roomster (trial04)"), 1.85, 1.45);
        assert_eq!(other_vehicle_warning(&made, &drive, "e", "d"), None);
    }

    #[test]
    fn the_json_carries_the_vehicle_or_at_least_the_nominal_values() {
        let with = r#"{"vehicle": {"name": "saloon", "track_width_m": 1.55, "nominal_circumference_m": 1.95}, "nominal": {"circumference_m": 1.95, "track_width_m": 1.55}}"#;
        let v = EstimateVehicle::from_json_str(with, "a")
            .expect("parsed")
            .expect("some");
        assert_eq!(v.name.as_deref(), Some("saloon"));
        let old = r#"{"nominal": {"circumference_m": 2.0, "track_width_m": 1.5}}"#;
        let v = EstimateVehicle::from_json_str(old, "b")
            .expect("parsed")
            .expect("some");
        assert_eq!((v.nominal_circumference_m, v.name), (2.0, None));
        assert_eq!(
            EstimateVehicle::from_json_str("{}", "c").expect("parsed"),
            None
        );
        let bad = EstimateVehicle::from_json_str("{", "d.json")
            .unwrap_err()
            .to_string();
        assert!(bad.contains("d.json"), "{bad}");
    }
}
