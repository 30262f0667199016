//! What no catalogue effect names in the wheels' speed against the GNSS:
//! a map of the relative speed residual over the car's speed and
//! longitudinal acceleration, measured by `calibrator compare` where a
//! recording's speed channel parts from its simulated twin's and carried
//! by the twin (`sensor-bridge simulate --like`) as its wheels' reading.
//!
//! The map is additive and piecewise constant: `m(v, a_x) = f(v) + g(a_x)`
//! with `f` constant between speed edges and `g` between acceleration
//! edges (a value beyond the outer edges takes the outer bin's). `m` is
//! the relative amount by which the wheels read slow against the ground
//! (`v_gnss / v_wheels - 1`, the speed channel's residual): a twin
//! carrying it turns its wheels `1 / (1 + m)` times as fast.

use serde::{Deserialize, Serialize};

/// The bin `x` falls in on ascending inner `edges`: 0 below the first,
/// `edges.len()` at or above the last.
pub fn bin_of(edges: &[f64], x: f64) -> usize {
    edges.iter().take_while(|&&e| x >= e).count()
}

/// One piecewise-constant function of a signal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Steps {
    /// Inner edges, ascending (`values.len() - 1` of them).
    pub edges: Vec<f64>,
    /// The value in each bin: below the first edge, between edges, above
    /// the last.
    pub values: Vec<f64>,
}

impl Steps {
    /// Zero everywhere.
    pub fn zero() -> Steps {
        Steps {
            edges: Vec::new(),
            values: vec![0.0],
        }
    }

    /// The bin `x` falls in.
    pub fn bin(&self, x: f64) -> usize {
        bin_of(&self.edges, x)
    }

    /// The value at `x` (0 where the steps are malformed).
    pub fn at(&self, x: f64) -> f64 {
        self.values.get(self.bin(x)).copied().unwrap_or(0.0)
    }

    /// Whether the edges ascend and there is one value more than edges,
    /// all finite.
    pub fn is_valid(&self) -> bool {
        self.values.len() == self.edges.len() + 1
            && self.edges.windows(2).all(|w| w[0] < w[1])
            && self.edges.iter().chain(&self.values).all(|x| x.is_finite())
    }

    /// The sum of two step functions, on the union of their edges.
    pub fn plus(&self, other: &Steps) -> Steps {
        let mut edges: Vec<f64> = self.edges.iter().chain(&other.edges).copied().collect();
        edges.sort_by(f64::total_cmp);
        edges.dedup();
        // A point inside each bin of the union.
        let mut probes = Vec::with_capacity(edges.len() + 1);
        match (edges.first(), edges.last()) {
            (Some(&lo), Some(&hi)) => {
                probes.push(lo - 1.0);
                probes.extend(edges.windows(2).map(|w| 0.5 * (w[0] + w[1])));
                probes.push(hi + 1.0);
            }
            _ => probes.push(0.0),
        }
        let values = probes.iter().map(|&x| self.at(x) + other.at(x)).collect();
        Steps { edges, values }
    }
}

/// The wheels' speed reading beyond the catalogue, over speed and
/// longitudinal acceleration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpeedMap {
    /// Over the speed, m/s.
    pub speed_m_s: Steps,
    /// Over the longitudinal acceleration, m/s^2.
    pub accel_m_s2: Steps,
}

impl SpeedMap {
    /// Zero everywhere.
    pub fn zero() -> SpeedMap {
        SpeedMap {
            speed_m_s: Steps::zero(),
            accel_m_s2: Steps::zero(),
        }
    }

    /// `m(v, a_x)`: how much slower than the ground the wheels read,
    /// relative.
    pub fn at(&self, v_m_s: f64, a_x_m_s2: f64) -> f64 {
        self.speed_m_s.at(v_m_s) + self.accel_m_s2.at(a_x_m_s2)
    }

    /// Both step functions well formed.
    pub fn is_valid(&self) -> bool {
        self.speed_m_s.is_valid() && self.accel_m_s2.is_valid()
    }

    /// The sum of two maps.
    pub fn plus(&self, other: &SpeedMap) -> SpeedMap {
        SpeedMap {
            speed_m_s: self.speed_m_s.plus(&other.speed_m_s),
            accel_m_s2: self.accel_m_s2.plus(&other.accel_m_s2),
        }
    }

    /// The largest `|m|` over the bins' combinations.
    pub fn max_abs(&self) -> f64 {
        let mut m: f64 = 0.0;
        for f in &self.speed_m_s.values {
            for g in &self.accel_m_s2.values {
                m = m.max((f + g).abs());
            }
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_take_the_bin_a_value_falls_in_and_add_on_the_union_of_edges() {
        let a = Steps {
            edges: vec![4.0, 10.0],
            values: vec![0.01, 0.0, -0.002],
        };
        assert_eq!(a.at(3.9), 0.01);
        assert_eq!(a.at(4.0), 0.0);
        assert_eq!(a.at(30.0), -0.002);
        let b = Steps {
            edges: vec![7.0],
            values: vec![0.001, 0.003],
        };
        let s = a.plus(&b);
        assert_eq!(s.edges, vec![4.0, 7.0, 10.0]);
        for x in [0.0, 5.0, 8.0, 12.0] {
            assert!((s.at(x) - a.at(x) - b.at(x)).abs() < 1e-15, "{x}");
        }
        assert!(s.is_valid());
        let m = SpeedMap {
            speed_m_s: a,
            accel_m_s2: b,
        };
        assert!((m.at(3.0, 8.0) - 0.013).abs() < 1e-15);
        assert!((m.max_abs() - 0.013).abs() < 1e-15);
        assert_eq!(SpeedMap::zero().plus(&m).at(5.0, 0.0), m.at(5.0, 0.0));
        let bad = Steps {
            edges: vec![2.0, 1.0],
            values: vec![0.0, 0.0, 0.0],
        };
        assert!(!bad.is_valid());
    }
}
