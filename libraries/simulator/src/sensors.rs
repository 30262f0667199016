//! Sensor settings: rates, noise and quantisation of a production car's sensors.
//!
//! The systematic sensor errors of the catalogue (gyro bias and scale, GNSS
//! latency and lever arm, magnetometer heading bias) are effects
//! ([`super::EffectSettings`]); what is here is what every real sensor has.

use super::SimError;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Wheel encoders (ABS tone wheels).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelEncoderSettings {
    /// Sample rate of `wheels.csv` (and `truth.csv`), Hz.
    pub rate_hz: f64,
    /// Ticks per revolution; the output is cumulative `_ticks` (quantised,
    /// starting at a random phase). `None` writes exact `_rev` (no quantisation).
    pub ticks_per_rev: Option<u32>,
}

/// GNSS receiver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssSettings {
    /// Whether `gnss.csv` is written at all.
    pub enabled: bool,
    /// Fix rate, Hz.
    pub rate_hz: f64,
    /// White noise per axis (1-sigma), m.
    pub white_sigma_m: f64,
    /// Time-correlated (first-order Gauss-Markov) noise per axis, stationary 1-sigma, m.
    pub gm_sigma_m: f64,
    /// Correlation time of the Gauss-Markov noise, s.
    pub gm_tau_s: f64,
    /// Random outages per hour (Poisson), on top of the scenario's denied stretches.
    pub outage_rate_per_h: f64,
    /// Mean length of a random outage (exponential), s.
    pub outage_mean_s: f64,
}

impl GnssSettings {
    /// The 1-sigma horizontal accuracy written in `sigma_m`.
    pub fn sigma_m(&self) -> f64 {
        (self.white_sigma_m.powi(2) + self.gm_sigma_m.powi(2)).sqrt()
    }
}

/// IMU (the yaw-rate sensor and accelerometers of the ESC cluster).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSettings {
    /// Whether `imu.csv` is written at all.
    pub enabled: bool,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Yaw-rate white noise (1-sigma per sample), rad/s.
    pub gz_sigma_rad_s: f64,
    /// Accelerometer white noise (1-sigma per sample), m/s^2.
    pub accel_sigma_m_s2: f64,
}

/// Absolute heading (electronic compass).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingSettings {
    /// Whether `heading.csv` is written at all.
    pub enabled: bool,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// White noise (1-sigma), degrees.
    pub sigma_deg: f64,
}

/// All sensors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorSettings {
    /// Wheel encoders.
    pub wheels: WheelEncoderSettings,
    /// GNSS.
    pub gnss: GnssSettings,
    /// IMU.
    pub imu: ImuSettings,
    /// Absolute heading.
    pub heading: HeadingSettings,
}

impl Default for SensorSettings {
    /// A production car: 96-tick ABS encoders at 100 Hz; a 10 Hz automotive
    /// GNSS receiver with 0.3 m white and 1.0 m Gauss-Markov (60 s) noise; an
    /// ESC yaw-rate sensor at 100 Hz with 0.1 deg/s noise and 0.05 m/s^2
    /// accelerometers; a 10 Hz compass with 2 deg noise.
    fn default() -> Self {
        SensorSettings {
            wheels: WheelEncoderSettings {
                rate_hz: 100.0,
                ticks_per_rev: Some(96),
            },
            gnss: GnssSettings {
                enabled: true,
                rate_hz: 10.0,
                white_sigma_m: 0.3,
                gm_sigma_m: 1.0,
                gm_tau_s: 60.0,
                outage_rate_per_h: 0.0,
                outage_mean_s: 20.0,
            },
            imu: ImuSettings {
                enabled: true,
                rate_hz: 100.0,
                gz_sigma_rad_s: 0.1f64.to_radians(),
                accel_sigma_m_s2: 0.05,
            },
            heading: HeadingSettings {
                enabled: true,
                rate_hz: 10.0,
                sigma_deg: 2.0,
            },
        }
    }
}

/// Names accepted by [`SensorSettings::apply_spec`].
pub const SENSOR_KEYS: [&str; 16] = [
    "wheels.rate_hz",
    "wheels.ticks_per_rev",
    "gnss.enabled",
    "gnss.rate_hz",
    "gnss.white_sigma_m",
    "gnss.gm_sigma_m",
    "gnss.gm_tau_s",
    "gnss.outage_rate_per_h",
    "gnss.outage_mean_s",
    "imu.enabled",
    "imu.rate_hz",
    "imu.gz_sigma_rad_s",
    "imu.accel_sigma_m_s2",
    "heading.enabled",
    "heading.rate_hz",
    "heading.sigma_deg",
];

impl SensorSettings {
    /// The paper's setting (section 5: "Gaussian noise"): white noise only,
    /// GNSS 0.5 m white at 10 Hz, no time-correlated part, no outages.
    pub fn paper() -> SensorSettings {
        let mut s = SensorSettings::default();
        s.gnss.white_sigma_m = 0.5;
        s.gnss.gm_sigma_m = 0.0;
        s
    }

    /// Noise-free sensors (quantisation of the encoders kept): for tests that
    /// look at an effect's signature.
    pub fn noiseless() -> SensorSettings {
        let mut s = SensorSettings::default();
        s.gnss.white_sigma_m = 0.0;
        s.gnss.gm_sigma_m = 0.0;
        s.imu.gz_sigma_rad_s = 0.0;
        s.imu.accel_sigma_m_s2 = 0.0;
        s.heading.sigma_deg = 0.0;
        s
    }

    /// Apply one `KEY=VALUE` (keys: [`SENSOR_KEYS`]; `enabled` takes 0/1 or
    /// true/false; `wheels.ticks_per_rev=0` writes exact revolutions).
    pub fn apply_spec(&mut self, spec: &str) -> Result<(), SimError> {
        let bad = |reason: String| SimError::InvalidSensor {
            spec: spec.to_string(),
            reason,
        };
        let (key, value) = spec
            .split_once('=')
            .ok_or_else(|| bad("expected KEY=VALUE".into()))?;
        let (key, value) = (key.trim(), value.trim());
        let flag = || match value {
            "1" | "true" | "on" => Ok(true),
            "0" | "false" | "off" => Ok(false),
            _ => Err(bad("expected 0/1, true/false or on/off".into())),
        };
        let number = || -> Result<f64, SimError> {
            let v: f64 = value
                .parse()
                .map_err(|_| bad("the value is not a number".into()))?;
            if v.is_finite() && v >= 0.0 {
                Ok(v)
            } else {
                Err(bad("the value must be a finite non-negative number".into()))
            }
        };
        let positive = || -> Result<f64, SimError> {
            let v = number()?;
            if v > 0.0 {
                Ok(v)
            } else {
                Err(bad("the value must be positive".into()))
            }
        };
        match key {
            "wheels.rate_hz" => self.wheels.rate_hz = positive()?,
            "wheels.ticks_per_rev" => {
                let v = number()?;
                if v.fract() != 0.0 || v > 100_000.0 {
                    return Err(bad("ticks per revolution must be a whole number".into()));
                }
                self.wheels.ticks_per_rev = if v == 0.0 { None } else { Some(v as u32) };
            }
            "gnss.enabled" => self.gnss.enabled = flag()?,
            "gnss.rate_hz" => self.gnss.rate_hz = positive()?,
            "gnss.white_sigma_m" => self.gnss.white_sigma_m = number()?,
            "gnss.gm_sigma_m" => self.gnss.gm_sigma_m = number()?,
            "gnss.gm_tau_s" => self.gnss.gm_tau_s = positive()?,
            "gnss.outage_rate_per_h" => self.gnss.outage_rate_per_h = number()?,
            "gnss.outage_mean_s" => self.gnss.outage_mean_s = positive()?,
            "imu.enabled" => self.imu.enabled = flag()?,
            "imu.rate_hz" => self.imu.rate_hz = positive()?,
            "imu.gz_sigma_rad_s" => self.imu.gz_sigma_rad_s = number()?,
            "imu.accel_sigma_m_s2" => self.imu.accel_sigma_m_s2 = number()?,
            "heading.enabled" => self.heading.enabled = flag()?,
            "heading.rate_hz" => self.heading.rate_hz = positive()?,
            "heading.sigma_deg" => self.heading.sigma_deg = number()?,
            _ => {
                return Err(bad(format!(
                    "unknown key; known: {}",
                    SENSOR_KEYS.join(", ")
                )))
            }
        }
        Ok(())
    }
}

/// A standard normal draw.
pub(crate) fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample::<f64, _>(StandardNormal)
}

/// First-order Gauss-Markov process (exact discretisation), one axis.
#[derive(Debug, Clone, Copy)]
pub(crate) struct GaussMarkov {
    value: f64,
    sigma: f64,
    tau: f64,
}

impl GaussMarkov {
    /// Start in the stationary distribution.
    pub(crate) fn new(sigma: f64, tau: f64, rng: &mut ChaCha8Rng) -> GaussMarkov {
        GaussMarkov {
            value: sigma * gauss(rng),
            sigma,
            tau,
        }
    }

    /// Advance by `dt` and return the new value.
    pub(crate) fn step(&mut self, dt: f64, rng: &mut ChaCha8Rng) -> f64 {
        if self.sigma > 0.0 {
            let phi = (-dt / self.tau).exp();
            self.value = phi * self.value + self.sigma * (1.0 - phi * phi).sqrt() * gauss(rng);
        }
        self.value
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn sensor_specs_parse_and_reject() {
        let mut s = SensorSettings::default();
        s.apply_spec("gnss.rate_hz=5").unwrap();
        s.apply_spec("wheels.ticks_per_rev=0").unwrap();
        s.apply_spec("heading.enabled=false").unwrap();
        assert_eq!(s.gnss.rate_hz, 5.0);
        assert_eq!(s.wheels.ticks_per_rev, None);
        assert!(!s.heading.enabled);
        for bad in [
            "gnss.rate_hz=0",
            "gnss.rate=5",
            "imu.enabled=maybe",
            "wheels.ticks_per_rev=4.5",
        ] {
            assert!(s.apply_spec(bad).is_err(), "{bad}");
        }
        for key in SENSOR_KEYS {
            let value = if key.ends_with("enabled") { "1" } else { "2" };
            s.apply_spec(&format!("{key}={value}")).unwrap();
        }
    }

    #[test]
    fn gauss_markov_keeps_its_variance() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut gm = GaussMarkov::new(2.0, 5.0, &mut rng);
        let n = 200_000;
        let var = (0..n).map(|_| gm.step(0.5, &mut rng).powi(2)).sum::<f64>() / n as f64;
        assert!((var.sqrt() - 2.0).abs() < 0.1, "{}", var.sqrt());
    }
}
