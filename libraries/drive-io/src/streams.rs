//! One description per sensor stream, used by both formats: the drive
//! folder's CSV columns, the recording's JSON keys (the same names), the
//! recording's schema titles and descriptions, and the conversion between a
//! sample of `interfaces::drive` and its values.
//!
//! The four streams with fixed columns (GNSS, IMU, heading, truth) implement
//! [`Stream`]; the wheels, whose columns depend on their units, are described
//! by the functions at the end.

use super::recording::{GNSS_TOPIC, HEADING_TOPIC, IMU_TOPIC, TRUTH_TOPIC};
use interfaces::drive::{
    Drive, GnssSample, HeadingSample, ImuSample, TruthSample, Wheel, WheelSample, WheelUnit,
    WheelUnits,
};

/// One value of a stream: its CSV column and JSON key, whether every sample
/// has it, and its description in the recording's schema.
pub(super) struct Field {
    /// Column name (CSV) and key (JSON).
    pub name: &'static str,
    /// True when every sample has the value.
    pub required: bool,
    /// What the value is, with its unit.
    pub description: &'static str,
}

impl Field {
    const fn required(name: &'static str, description: &'static str) -> Field {
        Field {
            name,
            required: true,
            description,
        }
    }

    const fn optional(name: &'static str, description: &'static str) -> Field {
        Field {
            name,
            required: false,
            description,
        }
    }
}

/// The time of every stream, its first field.
pub(super) const T_S: Field = Field::required("t_s", "time on the drive clock, s (exact)");

/// The names of `fields`, in order.
const fn names<const N: usize>(fields: &[Field; N]) -> [&'static str; N] {
    let mut out = [""; N];
    let mut i = 0;
    while i < N {
        out[i] = fields[i].name;
        i += 1;
    }
    out
}

/// The most fields a stream has ([`T_S`] included).
pub(super) const MAX_FIELDS: usize = 8;

/// A sensor stream with fixed columns.
pub(super) trait Stream: Sized {
    /// Name in messages (`gnss`, `imu`, ...).
    const NAME: &'static str;
    /// File of the drive folder.
    const CSV_FILE: &'static str;
    /// Channel of the recording.
    const TOPIC: &'static str;
    /// Schema name (and title) of the recording's channel.
    const SCHEMA_TITLE: &'static str;
    /// Schema description of the recording's channel.
    const SCHEMA_DESCRIPTION: &'static str;
    /// Name of the message type in JSON error messages (`struct GnssMsg`).
    const MESSAGE: &'static str;
    /// The values: [`T_S`] first, then the required, then the optional ones.
    const FIELDS: &'static [Field];
    /// The names of [`Stream::FIELDS`].
    const KEYS: &'static [&'static str];
    /// The second and third fields are `x_m,y_m`, which a CSV file may give
    /// as `lat_deg,lon_deg` instead.
    const LAT_LON: bool = false;
    /// The CSV file may have a `fix` column; rows with `fix = 0` are skipped.
    const FIX_COLUMN: bool = false;

    /// The stream of a drive, when it has one.
    fn of(drive: &Drive) -> Option<&[Self]>;
    /// Field `k`'s value (`None` when absent or `k` is out of range).
    fn value(&self, k: usize) -> Option<f64>;
    /// A sample from its values, in [`Stream::FIELDS`] order; `None` when a
    /// required one is missing.
    fn from_values(values: &[Option<f64>]) -> Option<Self>;

    /// The time, s.
    fn t_s(&self) -> f64 {
        self.value(0).unwrap_or(f64::NAN)
    }
}

const GNSS_FIELDS: [Field; 4] = [
    T_S,
    Field::required("x_m", "east, m"),
    Field::required("y_m", "north, m"),
    Field::optional("sigma_m", "horizontal 1-sigma, m"),
];

impl Stream for GnssSample {
    const NAME: &'static str = "gnss";
    const CSV_FILE: &'static str = "gnss.csv";
    const TOPIC: &'static str = GNSS_TOPIC;
    const SCHEMA_TITLE: &'static str = "wheelcal.GnssFix";
    const SCHEMA_DESCRIPTION: &'static str =
        "GNSS fix in local ENU (x east, y north); origin in vehicle.toml [gnss]";
    const MESSAGE: &'static str = "GnssMsg";
    const FIELDS: &'static [Field] = &GNSS_FIELDS;
    const KEYS: &'static [&'static str] = &names(&GNSS_FIELDS);
    const LAT_LON: bool = true;
    const FIX_COLUMN: bool = true;

    fn of(drive: &Drive) -> Option<&[Self]> {
        drive.gnss.as_deref()
    }

    fn value(&self, k: usize) -> Option<f64> {
        match k {
            0 => Some(self.t_s),
            1 => Some(self.x_m),
            2 => Some(self.y_m),
            3 => self.sigma_m,
            _ => None,
        }
    }

    fn from_values(v: &[Option<f64>]) -> Option<Self> {
        Some(GnssSample {
            t_s: v[0]?,
            x_m: v[1]?,
            y_m: v[2]?,
            sigma_m: v[3],
        })
    }
}

const IMU_FIELDS: [Field; 7] = [
    T_S,
    Field::required("gz_rad_s", "yaw rate, rad/s, positive turning left"),
    Field::optional("ax_m_s2", "longitudinal acceleration, m/s^2"),
    Field::optional("ay_m_s2", "lateral acceleration, m/s^2"),
    Field::optional("az_m_s2", "vertical acceleration, m/s^2"),
    Field::optional("gx_rad_s", "roll rate, rad/s"),
    Field::optional("gy_rad_s", "pitch rate, rad/s"),
];

impl Stream for ImuSample {
    const NAME: &'static str = "imu";
    const CSV_FILE: &'static str = "imu.csv";
    const TOPIC: &'static str = IMU_TOPIC;
    const SCHEMA_TITLE: &'static str = "wheelcal.Imu";
    const SCHEMA_DESCRIPTION: &'static str = "IMU, body frame x forward, y left, z up";
    const MESSAGE: &'static str = "ImuMsg";
    const FIELDS: &'static [Field] = &IMU_FIELDS;
    const KEYS: &'static [&'static str] = &names(&IMU_FIELDS);

    fn of(drive: &Drive) -> Option<&[Self]> {
        drive.imu.as_deref()
    }

    fn value(&self, k: usize) -> Option<f64> {
        match k {
            0 => Some(self.t_s),
            1 => Some(self.gz_rad_s),
            2 => self.ax_m_s2,
            3 => self.ay_m_s2,
            4 => self.az_m_s2,
            5 => self.gx_rad_s,
            6 => self.gy_rad_s,
            _ => None,
        }
    }

    fn from_values(v: &[Option<f64>]) -> Option<Self> {
        Some(ImuSample {
            t_s: v[0]?,
            gz_rad_s: v[1]?,
            ax_m_s2: v[2],
            ay_m_s2: v[3],
            az_m_s2: v[4],
            gx_rad_s: v[5],
            gy_rad_s: v[6],
        })
    }
}

const HEADING_FIELDS: [Field; 3] = [
    T_S,
    Field::required("yaw_rad", "yaw, rad"),
    Field::optional("sigma_rad", "1-sigma, rad"),
];

impl Stream for HeadingSample {
    const NAME: &'static str = "heading";
    const CSV_FILE: &'static str = "heading.csv";
    const TOPIC: &'static str = HEADING_TOPIC;
    const SCHEMA_TITLE: &'static str = "wheelcal.Heading";
    const SCHEMA_DESCRIPTION: &'static str =
        "Absolute heading, yaw 0 = east, counter-clockwise positive";
    const MESSAGE: &'static str = "HeadingMsg";
    const FIELDS: &'static [Field] = &HEADING_FIELDS;
    const KEYS: &'static [&'static str] = &names(&HEADING_FIELDS);

    fn of(drive: &Drive) -> Option<&[Self]> {
        drive.heading.as_deref()
    }

    fn value(&self, k: usize) -> Option<f64> {
        match k {
            0 => Some(self.t_s),
            1 => Some(self.yaw_rad),
            2 => self.sigma_rad,
            _ => None,
        }
    }

    fn from_values(v: &[Option<f64>]) -> Option<Self> {
        Some(HeadingSample {
            t_s: v[0]?,
            yaw_rad: v[1]?,
            sigma_rad: v[2],
        })
    }
}

const TRUTH_FIELDS: [Field; 4] = [
    T_S,
    Field::required("x_m", "east, m"),
    Field::required("y_m", "north, m"),
    Field::optional("yaw_rad", "yaw, rad"),
];

impl Stream for TruthSample {
    const NAME: &'static str = "truth";
    const CSV_FILE: &'static str = "truth.csv";
    const TOPIC: &'static str = TRUTH_TOPIC;
    const SCHEMA_TITLE: &'static str = "wheelcal.TruthPose";
    const SCHEMA_DESCRIPTION: &'static str =
        "True pose of the rear-axle centre in local ENU (scoring only)";
    const MESSAGE: &'static str = "TruthMsg";
    const FIELDS: &'static [Field] = &TRUTH_FIELDS;
    const KEYS: &'static [&'static str] = &names(&TRUTH_FIELDS);
    const LAT_LON: bool = true;

    fn of(drive: &Drive) -> Option<&[Self]> {
        drive.truth.as_deref()
    }

    fn value(&self, k: usize) -> Option<f64> {
        match k {
            0 => Some(self.t_s),
            1 => Some(self.x_m),
            2 => Some(self.y_m),
            3 => self.yaw_rad,
            _ => None,
        }
    }

    fn from_values(v: &[Option<f64>]) -> Option<Self> {
        Some(TruthSample {
            t_s: v[0]?,
            x_m: v[1]?,
            y_m: v[2]?,
            yaw_rad: v[3],
        })
    }
}

// ------------------------------------------------------------- wheels

/// Name of the wheel stream in messages.
pub(super) const WHEELS_NAME: &str = "wheels";
/// File of the wheel stream in a drive folder.
pub(super) const WHEELS_CSV: &str = "wheels.csv";
/// Schema name (and title) of the wheel channel.
pub(super) const WHEELS_SCHEMA_TITLE: &str = "wheelcal.Wheels";
/// Schema description of the wheel channel.
pub(super) const WHEELS_SCHEMA_DESCRIPTION: &str =
    "Wheel rotations (rear left/right required, front optional)";

/// The wheel column names for `units` (`rl_rad_s`, ...), in `Wheel::ALL` order.
pub(super) fn wheel_column_names(units: &WheelUnits) -> Vec<(Wheel, String)> {
    Wheel::ALL
        .iter()
        .filter_map(|&w| {
            units
                .of(w)
                .map(|u| (w, format!("{}_{}", w.prefix(), u.suffix())))
        })
        .collect()
}

/// The value of wheel `w` in a sample.
pub(super) fn wheel_value(s: &WheelSample, w: Wheel) -> Option<f64> {
    match w {
        Wheel::Rl => Some(s.rl),
        Wheel::Rr => Some(s.rr),
        Wheel::Fl => s.fl,
        Wheel::Fr => s.fr,
    }
}

/// What a wheel value in `unit` is (schema description).
pub(super) fn wheel_unit_description(unit: WheelUnit) -> &'static str {
    match unit {
        WheelUnit::Rev => "cumulative revolutions since an arbitrary start",
        WheelUnit::Ticks => "cumulative encoder ticks (see ticks_per_rev in vehicle.toml)",
        WheelUnit::RadS => "wheel angular speed, rad/s",
        WheelUnit::MS => {
            "wheel speed as the vehicle reports it, m/s (scaled by nominal_circumference_m)"
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check<S: Stream>() {
        assert!(S::FIELDS.len() <= MAX_FIELDS, "{}", S::NAME);
        assert_eq!(S::FIELDS[0].name, "t_s");
        assert_eq!(S::KEYS.len(), S::FIELDS.len());
        // Required fields first, so a CSV header lists them first.
        let first_optional = S::FIELDS.iter().position(|f| !f.required);
        if let Some(k) = first_optional {
            assert!(S::FIELDS[k..].iter().all(|f| !f.required), "{}", S::NAME);
        }
        if S::LAT_LON {
            assert_eq!((S::FIELDS[1].name, S::FIELDS[2].name), ("x_m", "y_m"));
        }
        // Values round trip through from_values, field by field.
        let values: Vec<Option<f64>> = (0..S::FIELDS.len()).map(|k| Some(k as f64)).collect();
        let s = S::from_values(&values).expect("all values given");
        for (k, v) in values.iter().enumerate() {
            assert_eq!(s.value(k), *v, "{} field {k}", S::NAME);
        }
        assert_eq!(s.value(S::FIELDS.len()), None);
    }

    #[test]
    fn stream_tables_agree_with_their_conversions() {
        check::<GnssSample>();
        check::<ImuSample>();
        check::<HeadingSample>();
        check::<TruthSample>();
    }
}
