//! Stable ids of the physics the two-wheel (2W) model leaves out.
//!
//! The ids are those of `shared/design/physics-catalogue.md`. They appear in
//! reports, JSON, `truth.toml` and, as [`Effect::code`], on the wire.

use serde::{Deserialize, Serialize};

/// One effect of the physics catalogue.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    /// Side-slip angle proportional to lateral acceleration.
    SideSlip,
    /// Effective radius changes with vertical load in corners.
    LoadTransferRadius,
    /// Tyre radius grows with speed (centrifugal growth).
    SpeedRadiusGrowth,
    /// Longitudinal slip of the driven axle under acceleration.
    LongitudinalSlip,
    /// Effective rear track differs from the nominal.
    TrackWidth,
    /// Constant yaw-rate gyro bias.
    GyroBias,
    /// Yaw-rate gyro scale factor error.
    GyroScale,
    /// GNSS fixes stamped late.
    GnssLatency,
    /// GNSS antenna away from the rear-axle centre.
    GnssLeverArm,
    /// Tyre radius drifting with time (warm-up, pressure).
    RadiusDrift,
    /// Wheels measure along the slope, GNSS the horizontal.
    RoadGrade,
    /// Magnetometer heading error periodic in heading.
    HeadingBias,
}

impl Effect {
    /// Every effect, in catalogue order.
    pub const ALL: [Effect; 12] = [
        Effect::SideSlip,
        Effect::LoadTransferRadius,
        Effect::SpeedRadiusGrowth,
        Effect::LongitudinalSlip,
        Effect::TrackWidth,
        Effect::GyroBias,
        Effect::GyroScale,
        Effect::GnssLatency,
        Effect::GnssLeverArm,
        Effect::RadiusDrift,
        Effect::RoadGrade,
        Effect::HeadingBias,
    ];

    /// The catalogue id, e.g. `"side_slip"`.
    pub fn id(self) -> &'static str {
        match self {
            Effect::SideSlip => "side_slip",
            Effect::LoadTransferRadius => "load_transfer_radius",
            Effect::SpeedRadiusGrowth => "speed_radius_growth",
            Effect::LongitudinalSlip => "longitudinal_slip",
            Effect::TrackWidth => "track_width",
            Effect::GyroBias => "gyro_bias",
            Effect::GyroScale => "gyro_scale",
            Effect::GnssLatency => "gnss_latency",
            Effect::GnssLeverArm => "gnss_lever_arm",
            Effect::RadiusDrift => "radius_drift",
            Effect::RoadGrade => "road_grade",
            Effect::HeadingBias => "heading_bias",
        }
    }

    /// The effect with this catalogue id.
    pub fn from_id(id: &str) -> Option<Effect> {
        Effect::ALL.into_iter().find(|e| e.id() == id)
    }

    /// Numeric code used on the wire (1-based; 0 means "no effect").
    pub fn code(self) -> u32 {
        Effect::ALL
            .iter()
            .position(|e| *e == self)
            .map_or(0, |i| i as u32 + 1)
    }

    /// The effect with this wire code.
    pub fn from_code(code: u32) -> Option<Effect> {
        let index = usize::try_from(code).ok()?.checked_sub(1)?;
        Effect::ALL.get(index).copied()
    }
}

/// Wire code of the GNSS clock model extension (not a physics-catalogue
/// effect: codes from 101 on are sensor clocks, outside the catalogue's
/// 1..=12, so [`Effect::from_code`] knows none of them). Parameters: the
/// GNSS stamps' offset against the wheels' (late, s), its drift (ppm) and
/// the wheel time the offset holds at (s); `param_count` 3.
pub const GNSS_CLOCK_EXTENSION: u32 = 101;
/// Wire code of the IMU clock model extension: as
/// [`GNSS_CLOCK_EXTENSION`], for the IMU's stamps.
pub const IMU_CLOCK_EXTENSION: u32 = 102;

impl std::fmt::Display for Effect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.id())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_codes_and_serde_names_agree() {
        for e in Effect::ALL {
            assert_eq!(Effect::from_id(e.id()), Some(e));
            assert_eq!(Effect::from_code(e.code()), Some(e));
            assert_eq!(
                serde_json::to_string(&e).unwrap(),
                format!("\"{}\"", e.id())
            );
        }
        assert_eq!(Effect::from_code(0), None);
        for code in [GNSS_CLOCK_EXTENSION, IMU_CLOCK_EXTENSION] {
            assert_eq!(Effect::from_code(code), None, "a clock is not an effect");
        }
        assert_eq!(Effect::from_id("flux_capacitor"), None);
    }
}
