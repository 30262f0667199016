//! The wheels' yaw wander: a slow error of the yaw rate the rear wheels
//! read (their speed difference over the track) against the gyro's, beyond
//! the catalogue's forms, as `calibrator compare` measures it where a
//! recording's course against the wheels parts from its simulated twin's,
//! and as a twin (`sensor-bridge simulate --like`) carries it.
//!
//! It is a first-order Gauss-Markov process `w(t)` (stationary standard
//! deviation `sigma_rad_s`, correlation time `tau_s`); a twin carrying it
//! turns its right rear wheel faster and its left slower by
//! `w track / 2` of surface speed while the car moves.

use serde::{Deserialize, Serialize};

/// A Gauss-Markov yaw-rate error of the wheels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct YawWander {
    /// Stationary standard deviation, rad/s.
    pub sigma_rad_s: f64,
    /// Correlation time, s.
    pub tau_s: f64,
}

impl YawWander {
    /// Finite, a sigma of at most 0.1 rad/s (beyond that the wheels are
    /// not measuring yaw at all) and not negative, a correlation time
    /// within 0.01-10000 s.
    pub fn is_valid(&self) -> bool {
        (0.0..=0.1).contains(&self.sigma_rad_s) && (0.01..=1.0e4).contains(&self.tau_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wander_is_valid_only_within_its_ranges() {
        let ok = YawWander {
            sigma_rad_s: 0.004,
            tau_s: 3.0,
        };
        assert!(ok.is_valid());
        for bad in [
            YawWander {
                sigma_rad_s: -0.001,
                ..ok
            },
            YawWander {
                sigma_rad_s: 0.5,
                ..ok
            },
            YawWander { tau_s: 0.0, ..ok },
            YawWander {
                tau_s: f64::NAN,
                ..ok
            },
        ] {
            assert!(!bad.is_valid(), "{bad:?}");
        }
    }
}
