//! Vehicle parameter sets and the tyre model.

use super::SimError;

/// Gravity, m/s^2.
pub const G: f64 = 9.81;
/// Air density, kg/m^3.
const RHO_AIR: f64 = 1.2;

/// Which vehicle parameter set to simulate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum VehicleKind {
    /// A front-driven compact hatchback (Golf class).
    Compact,
    /// A rear-driven executive saloon (E-class, the paper's CarSim vehicle).
    Saloon,
    /// A front-driven panel van.
    Van,
}

impl VehicleKind {
    /// Every kind.
    pub const ALL: [VehicleKind; 3] = [VehicleKind::Compact, VehicleKind::Saloon, VehicleKind::Van];

    /// The name used on the command line and in `truth.toml`.
    pub fn name(self) -> &'static str {
        match self {
            VehicleKind::Compact => "compact",
            VehicleKind::Saloon => "saloon",
            VehicleKind::Van => "van",
        }
    }

    /// The kind with this name.
    pub fn from_name(name: &str) -> Result<VehicleKind, SimError> {
        VehicleKind::ALL
            .into_iter()
            .find(|k| k.name() == name.trim().to_ascii_lowercase())
            .ok_or_else(|| SimError::UnknownVehicle(name.to_string()))
    }

    /// Its parameter set.
    pub fn spec(self) -> VehicleSpec {
        match self {
            VehicleKind::Compact => VehicleSpec {
                kind: self,
                mass_kg: 1350.0,
                yaw_inertia_kg_m2: 1950.0,
                wheelbase_m: 2.64,
                cg_to_front_m: 1.03,
                cg_height_m: 0.52,
                track_front_m: 1.54,
                track_rear_m: 1.51,
                unworn_circumference_m: 1.95,
                rear_roll_share: 0.42,
                understeer_rad_per_m_s2: 0.0035,
                mu: 1.0,
                drag_area_m2: 0.66,
                rolling_resistance: 0.011,
                max_steer_rad: 0.62,
                max_steer_rate_rad_s: 0.7,
                rear_wheel_drive: false,
                rear_brake_share: 0.32,
                max_drive_accel_m_s2: 3.5,
            },
            VehicleKind::Saloon => VehicleSpec {
                kind: self,
                mass_kg: 1750.0,
                yaw_inertia_kg_m2: 3050.0,
                wheelbase_m: 2.94,
                cg_to_front_m: 1.41,
                cg_height_m: 0.55,
                track_front_m: 1.60,
                track_rear_m: 1.58,
                unworn_circumference_m: 2.05,
                rear_roll_share: 0.45,
                understeer_rad_per_m_s2: 0.0025,
                mu: 1.0,
                drag_area_m2: 0.62,
                rolling_resistance: 0.010,
                max_steer_rad: 0.6,
                max_steer_rate_rad_s: 0.7,
                rear_wheel_drive: true,
                rear_brake_share: 0.36,
                max_drive_accel_m_s2: 4.5,
            },
            VehicleKind::Van => VehicleSpec {
                kind: self,
                mass_kg: 2600.0,
                yaw_inertia_kg_m2: 5400.0,
                wheelbase_m: 3.30,
                cg_to_front_m: 1.45,
                cg_height_m: 0.78,
                track_front_m: 1.72,
                track_rear_m: 1.70,
                unworn_circumference_m: 2.20,
                rear_roll_share: 0.40,
                understeer_rad_per_m_s2: 0.0045,
                mu: 0.95,
                drag_area_m2: 2.1,
                rolling_resistance: 0.012,
                max_steer_rad: 0.6,
                max_steer_rate_rad_s: 0.6,
                rear_wheel_drive: false,
                rear_brake_share: 0.30,
                max_drive_accel_m_s2: 2.8,
            },
        }
    }
}

/// One vehicle parameter set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleSpec {
    /// Which set this is.
    pub kind: VehicleKind,
    /// Mass, kg.
    pub mass_kg: f64,
    /// Yaw moment of inertia, kg m^2.
    pub yaw_inertia_kg_m2: f64,
    /// Wheelbase L, m.
    pub wheelbase_m: f64,
    /// Centre of gravity to front axle, m (to the rear axle: L minus this).
    pub cg_to_front_m: f64,
    /// Centre-of-gravity height, m.
    pub cg_height_m: f64,
    /// Front track, m.
    pub track_front_m: f64,
    /// Nominal rear track (vehicle.toml `track_width_m`), m.
    pub track_rear_m: f64,
    /// Effective rolling circumference of a new tyre at static load, m.
    pub unworn_circumference_m: f64,
    /// Share of the lateral load transfer carried by the rear axle (roll stiffness split).
    pub rear_roll_share: f64,
    /// Understeer gradient, rad of steer per m/s^2 of lateral acceleration
    /// (sets the front cornering stiffness from the rear one).
    pub understeer_rad_per_m_s2: f64,
    /// Tyre-road friction coefficient.
    pub mu: f64,
    /// Drag coefficient times frontal area, m^2.
    pub drag_area_m2: f64,
    /// Rolling-resistance coefficient.
    pub rolling_resistance: f64,
    /// Largest road-wheel steer angle, rad.
    pub max_steer_rad: f64,
    /// Steering rate limit at the road wheels, rad/s.
    pub max_steer_rate_rad_s: f64,
    /// True for rear-wheel drive (traction slip on the rear wheels the 2W model uses).
    pub rear_wheel_drive: bool,
    /// Share of the braking force on the rear axle.
    pub rear_brake_share: f64,
    /// Largest acceleration the powertrain gives, m/s^2.
    pub max_drive_accel_m_s2: f64,
}

impl VehicleSpec {
    /// CG to rear axle, m.
    pub fn cg_to_rear_m(&self) -> f64 {
        self.wheelbase_m - self.cg_to_front_m
    }

    /// Static vertical load of one front wheel, N.
    pub fn static_load_front(&self) -> f64 {
        0.5 * self.mass_kg * G * self.cg_to_rear_m() / self.wheelbase_m
    }

    /// Static vertical load of one rear wheel, N.
    pub fn static_load_rear(&self) -> f64 {
        0.5 * self.mass_kg * G * self.cg_to_front_m / self.wheelbase_m
    }

    /// Relative load change of a rear wheel per m/s^2 of lateral acceleration.
    pub fn rear_load_gain(&self) -> f64 {
        self.mass_kg * self.cg_height_m * self.rear_roll_share
            / self.track_rear_m
            / self.static_load_rear()
    }

    /// Relative load change of a front wheel per m/s^2 of lateral acceleration.
    pub fn front_load_gain(&self) -> f64 {
        self.mass_kg * self.cg_height_m * (1.0 - self.rear_roll_share)
            / self.track_front_m
            / self.static_load_front()
    }

    /// Aerodynamic drag plus rolling resistance at speed `v`, N (resisting motion).
    pub fn resistance_n(&self, v: f64) -> f64 {
        if v <= 0.0 {
            return 0.0;
        }
        let rolling = self.rolling_resistance * self.mass_kg * G * (v / 0.5).min(1.0);
        rolling + 0.5 * RHO_AIR * self.drag_area_m2 * v * v
    }
}

/// Shape factor of the lateral Magic-Formula curve.
pub const LATERAL_SHAPE: f64 = 1.3;
/// Shape factor of the longitudinal Magic-Formula curve.
pub const LONGITUDINAL_SHAPE: f64 = 1.65;
/// Degressive load sensitivity of the cornering stiffness (0 = linear in load).
pub const LOAD_SENSITIVITY: f64 = 0.2;

/// Simplified Magic Formula, lateral: force (N) for slip angle `alpha` (rad),
/// vertical load `fz` (N), peak friction `mu` and cornering stiffness `c_alpha`
/// (N/rad) at this load. Saturates at `mu * fz`.
pub fn lateral_force(alpha: f64, fz: f64, mu: f64, c_alpha: f64) -> f64 {
    let d = mu * fz.max(0.0);
    if d <= 0.0 {
        return 0.0;
    }
    let b = c_alpha / (LATERAL_SHAPE * d);
    // Beyond the peak the curve would fall; hold it at the peak (no spin-out
    // physics is wanted here, the driver stays inside the friction limit).
    let peak = (std::f64::consts::FRAC_PI_2 / LATERAL_SHAPE).tan();
    let x = (b * alpha).clamp(-peak, peak);
    d * (LATERAL_SHAPE * x.atan()).sin()
}

/// Cornering stiffness of one wheel at load `fz`, given the stiffness at the
/// static load `fz0` (degressive in load).
pub fn cornering_stiffness(c_static: f64, fz: f64, fz0: f64) -> f64 {
    let q = (fz / fz0).max(0.0);
    c_static * q * (1.0 + LOAD_SENSITIVITY * (1.0 - q)).max(0.0)
}

/// Inverse of the longitudinal Magic Formula: the slip ratio that carries
/// force `fx` (N) at load `fz` (N), friction `mu` and slip stiffness `c_x`
/// (N per unit slip). Forces beyond 98 % of the peak take the slip at that point.
pub fn longitudinal_slip_for_force(fx: f64, fz: f64, mu: f64, c_x: f64) -> f64 {
    let d = mu * fz.max(1.0);
    let b = c_x / (LONGITUDINAL_SHAPE * d);
    let ratio = (fx / d).clamp(-0.98, 0.98);
    (ratio.asin() / LONGITUDINAL_SHAPE).tan() / b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tyre_curves_are_linear_at_small_slip_and_saturate() {
        let (fz, mu, c) = (4000.0, 1.0, 60_000.0);
        let small = lateral_force(1e-4, fz, mu, c);
        assert!((small / 1e-4 - c).abs() / c < 1e-3, "{small}");
        let big = lateral_force(0.5, fz, mu, c);
        assert!(big <= mu * fz + 1e-9 && big > 0.95 * mu * fz, "{big}");
        let s = longitudinal_slip_for_force(100.0, fz, mu, 80_000.0);
        assert!((s - 100.0 / 80_000.0).abs() < 1e-6, "{s}");
        assert!(longitudinal_slip_for_force(-100.0, fz, mu, 80_000.0) < 0.0);
        assert!(longitudinal_slip_for_force(1e9, fz, mu, 80_000.0).is_finite());
    }

    #[test]
    fn vehicle_sets_are_plausible() {
        for kind in VehicleKind::ALL {
            let v = kind.spec();
            assert_eq!(VehicleKind::from_name(kind.name()).unwrap(), kind);
            let total = 2.0 * (v.static_load_front() + v.static_load_rear());
            assert!((total - v.mass_kg * G).abs() < 1e-6);
            // Lateral load transfer of 0.3-1.1 of static load per g: a passenger car.
            let per_g = v.rear_load_gain() * G;
            assert!((0.2..1.2).contains(&per_g), "{kind:?} {per_g}");
        }
        assert!(VehicleKind::from_name("tractor").is_err());
    }
}
