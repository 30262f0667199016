//! The in-memory drive: one time series per sensor plus the vehicle parameters.
//!
//! This is the plain-data twin of a drive folder (`shared/design/drive-format.md`)
//! and of an MCAP recording. Values are kept as the source gave them (wheel
//! units included) so that converting between the two formats loses nothing;
//! [`Drive::wheel_revolutions`] turns any wheel unit into cumulative revolutions
//! for the algorithms. Positions are local ENU metres; lat/lon input is
//! converted on reading and its origin kept in [`GnssAntenna`]/[`VehicleParams`].
//!
//! Times are seconds on the drive's one clock; within a series they strictly
//! increase (the readers enforce it).

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The fastest a road car's wheel turns, revolutions per second (a 2 m
/// circumference at 200 m/s, a 1 m one at 100 m/s): a wheel step beyond it
/// is a glitch, a jump or a unit mix-up, not motion. The one limit the
/// file checks (`drive_io::plausibility`), the calibrator's collector
/// ([`crate::collect`]) and the odometer share.
pub const MAX_WHEEL_REV_PER_S: f64 = 100.0;

/// Parameters of `vehicle.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VehicleParams {
    /// Free text.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Rear track t_R, metres.
    pub track_width_m: f64,
    /// Initial guess for every wheel's circumference; also the scale behind
    /// `_m_s` wheel columns.
    pub nominal_circumference_m: f64,
    /// Wheelbase, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wheelbase_m: Option<f64>,
    /// Encoder ticks per wheel revolution (needed by `_ticks` columns).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ticks_per_rev: Option<f64>,
    /// The `[gnss]` table.
    #[serde(default, skip_serializing_if = "GnssAntenna::is_empty")]
    pub gnss: GnssAntenna,
}

impl VehicleParams {
    /// Whether the values can be a road car's: a rear track of 0.1-5 m, a
    /// nominal circumference of 0.1-10 m, an antenna (when given) within
    /// 20 m of the rear axle, a wheelbase (when given) of 0.3-20 m, and
    /// ticks per revolution (when given) of 1-1e6. Every service checks
    /// `vehicle.toml` with this; the message names the field and its value.
    pub fn check_plausible(&self) -> Result<(), String> {
        let within = |field: &str, v: f64, lo: f64, hi: f64, what: &str| {
            if v.is_finite() && v > lo && v < hi {
                Ok(())
            } else {
                Err(format!(
                    "{field} = {v} is not a plausible {what} ({lo}..{hi})"
                ))
            }
        };
        within(
            "track_width_m",
            self.track_width_m,
            0.1,
            5.0,
            "rear track, m",
        )?;
        within(
            "nominal_circumference_m",
            self.nominal_circumference_m,
            0.1,
            10.0,
            "circumference, m",
        )?;
        if let Some(w) = self.wheelbase_m {
            within("wheelbase_m", w, 0.3, 20.0, "wheelbase, m")?;
        }
        if let Some(n) = self.ticks_per_rev {
            within(
                "ticks_per_rev",
                n,
                0.999,
                1e6,
                "number of ticks per revolution",
            )?;
        }
        for (field, v) in [
            ("[gnss] antenna_x_m", self.gnss.antenna_x_m),
            ("[gnss] antenna_y_m", self.gnss.antenna_y_m),
        ] {
            if let Some(v) = v {
                within(field, v, -20.0, 20.0, "antenna position, m")?;
            }
        }
        Ok(())
    }
}

/// The `[gnss]` table of `vehicle.toml`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GnssAntenna {
    /// Antenna position, body x (forward) from the rear-axle centre, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub antenna_x_m: Option<f64>,
    /// Antenna position, body y (left) from the rear-axle centre, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub antenna_y_m: Option<f64>,
    /// Latitude of the local ENU origin, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub origin_lat_deg: Option<f64>,
    /// Longitude of the local ENU origin, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub origin_lon_deg: Option<f64>,
}

impl GnssAntenna {
    /// True when no key of the table is set.
    pub fn is_empty(&self) -> bool {
        self == &GnssAntenna::default()
    }
}

/// Unit of one wheel column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WheelUnit {
    /// `_rev`: cumulative revolutions since an arbitrary start.
    Rev,
    /// `_ticks`: cumulative encoder ticks (needs `ticks_per_rev`).
    Ticks,
    /// `_rad_s`: wheel angular speed.
    RadS,
    /// `_m_s`: wheel speed as the vehicle reports it, scaled by the nominal circumference.
    MS,
}

impl WheelUnit {
    /// Every unit.
    pub const ALL: [WheelUnit; 4] = [
        WheelUnit::Rev,
        WheelUnit::Ticks,
        WheelUnit::RadS,
        WheelUnit::MS,
    ];

    /// Column suffix in `wheels.csv`, e.g. `"rad_s"` for `rl_rad_s`.
    pub fn suffix(self) -> &'static str {
        match self {
            WheelUnit::Rev => "rev",
            WheelUnit::Ticks => "ticks",
            WheelUnit::RadS => "rad_s",
            WheelUnit::MS => "m_s",
        }
    }

    /// True for rates (integrated to get revolutions), false for cumulative counts.
    pub fn is_rate(self) -> bool {
        matches!(self, WheelUnit::RadS | WheelUnit::MS)
    }
}

/// One wheel position.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Wheel {
    /// Rear left.
    Rl,
    /// Rear right.
    Rr,
    /// Front left.
    Fl,
    /// Front right.
    Fr,
}

impl Wheel {
    /// All four, rear first.
    pub const ALL: [Wheel; 4] = [Wheel::Rl, Wheel::Rr, Wheel::Fl, Wheel::Fr];

    /// Column prefix: `rl`, `rr`, `fl`, `fr`.
    pub fn prefix(self) -> &'static str {
        match self {
            Wheel::Rl => "rl",
            Wheel::Rr => "rr",
            Wheel::Fl => "fl",
            Wheel::Fr => "fr",
        }
    }
}

/// One row of `wheels.csv`, in the units of [`WheelSeries::units`].
///
/// A front value is `None` when the wheel is absent or its cell was empty.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WheelSample {
    /// Time, s.
    pub t_s: f64,
    /// Rear left.
    pub rl: f64,
    /// Rear right.
    pub rr: f64,
    /// Front left.
    pub fl: Option<f64>,
    /// Front right.
    pub fr: Option<f64>,
}

/// Units of the wheel columns present.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WheelUnits {
    /// Unit of the rear-left column.
    pub rl: WheelUnit,
    /// Unit of the rear-right column.
    pub rr: WheelUnit,
    /// Unit of the front-left column, `None` when absent.
    pub fl: Option<WheelUnit>,
    /// Unit of the front-right column, `None` when absent.
    pub fr: Option<WheelUnit>,
}

impl WheelUnits {
    /// The same unit for both rear wheels, no front wheels.
    pub fn rear(unit: WheelUnit) -> WheelUnits {
        WheelUnits {
            rl: unit,
            rr: unit,
            fl: None,
            fr: None,
        }
    }

    /// The same unit for all four wheels.
    pub fn all(unit: WheelUnit) -> WheelUnits {
        WheelUnits {
            rl: unit,
            rr: unit,
            fl: Some(unit),
            fr: Some(unit),
        }
    }

    /// Unit of a wheel, `None` when it is absent.
    pub fn of(&self, wheel: Wheel) -> Option<WheelUnit> {
        match wheel {
            Wheel::Rl => Some(self.rl),
            Wheel::Rr => Some(self.rr),
            Wheel::Fl => self.fl,
            Wheel::Fr => self.fr,
        }
    }
}

/// The wheel time series.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WheelSeries {
    /// Unit of every column present.
    pub units: WheelUnits,
    /// Rows in time order.
    pub samples: Vec<WheelSample>,
}

/// A GNSS fix in local ENU.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GnssSample {
    /// Time, s.
    pub t_s: f64,
    /// East, m.
    pub x_m: f64,
    /// North, m.
    pub y_m: f64,
    /// Horizontal 1-sigma, m, when given.
    pub sigma_m: Option<f64>,
}

/// An IMU row.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ImuSample {
    /// Time, s.
    pub t_s: f64,
    /// Yaw rate, rad/s, positive turning left.
    pub gz_rad_s: f64,
    /// Longitudinal acceleration, m/s^2.
    pub ax_m_s2: Option<f64>,
    /// Lateral acceleration, m/s^2.
    pub ay_m_s2: Option<f64>,
    /// Vertical acceleration, m/s^2.
    pub az_m_s2: Option<f64>,
    /// Roll rate, rad/s.
    pub gx_rad_s: Option<f64>,
    /// Pitch rate, rad/s.
    pub gy_rad_s: Option<f64>,
}

/// An absolute heading.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HeadingSample {
    /// Time, s.
    pub t_s: f64,
    /// Yaw, rad, 0 = east, counter-clockwise positive.
    pub yaw_rad: f64,
    /// 1-sigma, rad, when given.
    pub sigma_rad: Option<f64>,
}

/// A true pose of the rear-axle centre (scoring only: no estimator reads it).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TruthSample {
    /// Time, s.
    pub t_s: f64,
    /// East, m.
    pub x_m: f64,
    /// North, m.
    pub y_m: f64,
    /// Yaw, rad, when given.
    pub yaw_rad: Option<f64>,
}

/// True circumference of each wheel (`[circumference_m]` of `truth.toml`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WheelCircumferences {
    /// Rear left, m.
    pub rl: f64,
    /// Rear right, m.
    pub rr: f64,
    /// Front left, m.
    pub fl: f64,
    /// Front right, m.
    pub fr: f64,
}

/// `truth.toml`: the true parameters of a simulated drive.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthParams {
    /// The true effective rear track, m.
    pub track_width_m: f64,
    /// True effective circumference of each wheel.
    pub circumference_m: WheelCircumferences,
    /// Every effect switched on, by catalogue id, with its parameters.
    #[serde(default)]
    pub effects: BTreeMap<String, BTreeMap<String, f64>>,
    /// Other keys (scenario, seed, vehicle, sensor settings), kept as they are.
    #[serde(flatten)]
    pub extra: BTreeMap<String, toml_value::Value>,
}

impl TruthParams {
    /// One simulated effect parameter as `truth.toml` records it (under
    /// its effect's id and its name; in its reported unit), if that effect
    /// was on.
    pub fn effect_param(&self, param: crate::effects::Param) -> Option<f64> {
        let spec = param.spec();
        self.effects
            .get(spec.effect.id())
            .and_then(|p| p.get(spec.name))
            .copied()
    }
}

/// A self-contained value type for the free-form keys of `truth.toml`, so
/// this crate needs no TOML dependency.
pub mod toml_value {
    use serde::{Deserialize, Serialize};
    use std::collections::BTreeMap;

    /// A TOML-compatible value.
    #[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
    #[serde(untagged)]
    pub enum Value {
        /// A boolean.
        Bool(bool),
        /// An integer.
        Integer(i64),
        /// A float.
        Float(f64),
        /// A string.
        String(String),
        /// An array.
        Array(Vec<Value>),
        /// A table.
        Table(BTreeMap<String, Value>),
    }
}

/// A whole drive.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Drive {
    /// `vehicle.toml`.
    pub vehicle: VehicleParams,
    /// `wheels.csv` (required).
    pub wheels: WheelSeries,
    /// `gnss.csv`: required to calibrate, optional to dead-reckon.
    pub gnss: Option<Vec<GnssSample>>,
    /// `imu.csv`.
    pub imu: Option<Vec<ImuSample>>,
    /// `heading.csv`.
    pub heading: Option<Vec<HeadingSample>>,
    /// `truth.csv` (scoring only).
    pub truth: Option<Vec<TruthSample>>,
    /// `truth.toml` (simulated drives).
    pub truth_params: Option<TruthParams>,
}

/// Cumulative revolutions of the wheels at one wheel sample time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelRevs {
    /// Time, s.
    pub t_s: f64,
    /// Rear-left cumulative revolutions.
    pub rl: f64,
    /// Rear-right cumulative revolutions.
    pub rr: f64,
    /// Front-left cumulative revolutions, when present.
    pub fl: Option<f64>,
    /// Front-right cumulative revolutions, when present.
    pub fr: Option<f64>,
}

/// Why wheel values cannot be turned into revolutions.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WheelConversionError {
    /// `_ticks` columns without `ticks_per_rev` in `vehicle.toml`.
    #[error("wheels.csv has _ticks columns but vehicle.toml has no ticks_per_rev")]
    MissingTicksPerRev,
    /// `_m_s` columns need a positive `nominal_circumference_m`.
    #[error("wheels.csv has _m_s columns but nominal_circumference_m = {0} is not positive")]
    BadNominalCircumference(f64),
}

impl Drive {
    /// Duration from the first to the last wheel sample, s.
    pub fn wheel_duration_s(&self) -> f64 {
        match (self.wheels.samples.first(), self.wheels.samples.last()) {
            (Some(a), Some(b)) => b.t_s - a.t_s,
            _ => 0.0,
        }
    }

    /// Every wheel value as cumulative revolutions (0 at the first sample for
    /// rates; as given for counts, ticks divided by `ticks_per_rev`).
    ///
    /// Rates are integrated with the trapezoidal rule; `_m_s` speeds are first
    /// divided by the nominal circumference they were computed with.
    pub fn wheel_revolutions(&self) -> Result<Vec<WheelRevs>, WheelConversionError> {
        let samples = &self.wheels.samples;
        let units = self.wheels.units;
        let ticks = self.vehicle.ticks_per_rev;
        let nominal = self.vehicle.nominal_circumference_m;
        let scale = |unit: WheelUnit| -> Result<f64, WheelConversionError> {
            match unit {
                WheelUnit::Rev => Ok(1.0),
                WheelUnit::Ticks => match ticks {
                    Some(t) if t > 0.0 => Ok(1.0 / t),
                    _ => Err(WheelConversionError::MissingTicksPerRev),
                },
                WheelUnit::RadS => Ok(1.0 / std::f64::consts::TAU),
                WheelUnit::MS => {
                    if nominal > 0.0 {
                        Ok(1.0 / nominal)
                    } else {
                        Err(WheelConversionError::BadNominalCircumference(nominal))
                    }
                }
            }
        };
        let channel = |wheel: Wheel, pick: &dyn Fn(&WheelSample) -> Option<f64>| {
            let Some(unit) = units.of(wheel) else {
                return Ok(vec![None; samples.len()]);
            };
            let k = scale(unit)?;
            let mut out = Vec::with_capacity(samples.len());
            if unit.is_rate() {
                let mut acc = 0.0;
                let mut prev: Option<(f64, f64)> = None;
                for s in samples {
                    match pick(s) {
                        Some(rate) => {
                            if let Some((t0, r0)) = prev {
                                acc += 0.5 * (rate + r0) * k * (s.t_s - t0);
                            }
                            prev = Some((s.t_s, rate));
                            out.push(Some(acc));
                        }
                        None => out.push(None),
                    }
                }
            } else {
                out.extend(samples.iter().map(|s| pick(s).map(|v| v * k)));
            }
            Ok::<_, WheelConversionError>(out)
        };
        let rl = channel(Wheel::Rl, &|s| Some(s.rl))?;
        let rr = channel(Wheel::Rr, &|s| Some(s.rr))?;
        let fl = channel(Wheel::Fl, &|s| s.fl)?;
        let fr = channel(Wheel::Fr, &|s| s.fr)?;
        Ok(samples
            .iter()
            .enumerate()
            .map(|(i, s)| WheelRevs {
                t_s: s.t_s,
                rl: rl[i].unwrap_or(f64::NAN),
                rr: rr[i].unwrap_or(f64::NAN),
                fl: fl[i],
                fr: fr[i],
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drive(units: WheelUnits, samples: Vec<WheelSample>) -> Drive {
        Drive {
            vehicle: VehicleParams {
                name: None,
                track_width_m: 1.5,
                nominal_circumference_m: 2.0,
                wheelbase_m: None,
                ticks_per_rev: Some(100.0),
                gnss: GnssAntenna::default(),
            },
            wheels: WheelSeries { units, samples },
            gnss: None,
            imu: None,
            heading: None,
            truth: None,
            truth_params: None,
        }
    }

    #[test]
    fn implausible_vehicle_values_are_named() {
        let good = drive(WheelUnits::rear(WheelUnit::Rev), Vec::new()).vehicle;
        assert_eq!(good.check_plausible(), Ok(()));
        let huge = VehicleParams {
            nominal_circumference_m: 1e6,
            ..good.clone()
        };
        let e = huge.check_plausible().unwrap_err();
        assert!(e.contains("nominal_circumference_m = 1000000"), "{e}");
        let nan_track = VehicleParams {
            track_width_m: f64::NAN,
            ..good.clone()
        };
        assert!(nan_track
            .check_plausible()
            .unwrap_err()
            .contains("track_width_m"));
        let mut far = good.clone();
        far.gnss.antenna_x_m = Some(150.0);
        assert!(far.check_plausible().unwrap_err().contains("antenna_x_m"));
        let zero_ticks = VehicleParams {
            ticks_per_rev: Some(0.0),
            ..good
        };
        assert!(zero_ticks.check_plausible().is_err());
    }

    fn row(t_s: f64, rl: f64, rr: f64) -> WheelSample {
        WheelSample {
            t_s,
            rl,
            rr,
            fl: None,
            fr: None,
        }
    }

    #[test]
    fn rates_integrate_to_revolutions() {
        let tau = std::f64::consts::TAU;
        let d = drive(
            WheelUnits::rear(WheelUnit::RadS),
            vec![
                row(0.0, tau, 2.0 * tau),
                row(1.0, tau, 2.0 * tau),
                row(3.0, tau, 2.0 * tau),
            ],
        );
        let revs = d.wheel_revolutions().unwrap();
        assert!((revs[2].rl - 3.0).abs() < 1e-12);
        assert!((revs[2].rr - 6.0).abs() < 1e-12);
    }

    #[test]
    fn speeds_use_the_nominal_circumference_and_ticks_their_count() {
        let d = drive(
            WheelUnits::rear(WheelUnit::MS),
            vec![row(0.0, 4.0, 4.0), row(1.0, 4.0, 4.0)],
        );
        assert!((d.wheel_revolutions().unwrap()[1].rl - 2.0).abs() < 1e-12);
        let mut d = drive(
            WheelUnits::rear(WheelUnit::Ticks),
            vec![row(0.0, 50.0, 0.0)],
        );
        assert!((d.wheel_revolutions().unwrap()[0].rl - 0.5).abs() < 1e-12);
        d.vehicle.ticks_per_rev = None;
        let err = d.wheel_revolutions().unwrap_err();
        assert!(err.to_string().contains("ticks_per_rev"), "{err}");
    }
}
