//! WGS84 geodetic coordinates to a local east-north-up (ENU) frame.
//!
//! The exact route: geodetic (lat, lon, height) on the WGS84 ellipsoid ->
//! Earth-centred Earth-fixed (ECEF) -> rotate the difference to the origin
//! into the origin's ENU frame. No flat-earth approximation, so it stays
//! exact over long drives.

/// WGS84 semi-major axis, m.
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;

/// First eccentricity squared, e^2 = f (2 - f).
const E2: f64 = WGS84_F * (2.0 - WGS84_F);

/// ECEF position (x, y, z) in metres of a geodetic point.
pub fn geodetic_to_ecef(lat_deg: f64, lon_deg: f64, height_m: f64) -> [f64; 3] {
    let (sin_lat, cos_lat) = lat_deg.to_radians().sin_cos();
    let (sin_lon, cos_lon) = lon_deg.to_radians().sin_cos();
    // Prime-vertical radius of curvature.
    let n = WGS84_A / (1.0 - E2 * sin_lat * sin_lat).sqrt();
    [
        (n + height_m) * cos_lat * cos_lon,
        (n + height_m) * cos_lat * sin_lon,
        (n * (1.0 - E2) + height_m) * sin_lat,
    ]
}

/// A local ENU frame fixed at an origin on the ellipsoid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFrame {
    origin_lat_deg: f64,
    origin_lon_deg: f64,
    origin_ecef: [f64; 3],
    sin_lat: f64,
    cos_lat: f64,
    sin_lon: f64,
    cos_lon: f64,
}

impl LocalFrame {
    /// The frame at `(lat, lon, height)` of the origin.
    pub fn new(origin_lat_deg: f64, origin_lon_deg: f64, origin_height_m: f64) -> LocalFrame {
        let (sin_lat, cos_lat) = origin_lat_deg.to_radians().sin_cos();
        let (sin_lon, cos_lon) = origin_lon_deg.to_radians().sin_cos();
        LocalFrame {
            origin_lat_deg,
            origin_lon_deg,
            origin_ecef: geodetic_to_ecef(origin_lat_deg, origin_lon_deg, origin_height_m),
            sin_lat,
            cos_lat,
            sin_lon,
            cos_lon,
        }
    }

    /// Origin latitude, degrees.
    pub fn origin_lat_deg(&self) -> f64 {
        self.origin_lat_deg
    }

    /// Origin longitude, degrees.
    pub fn origin_lon_deg(&self) -> f64 {
        self.origin_lon_deg
    }

    /// (east, north, up) in metres of a geodetic point.
    pub fn to_enu(&self, lat_deg: f64, lon_deg: f64, height_m: f64) -> [f64; 3] {
        let p = geodetic_to_ecef(lat_deg, lon_deg, height_m);
        let d = [
            p[0] - self.origin_ecef[0],
            p[1] - self.origin_ecef[1],
            p[2] - self.origin_ecef[2],
        ];
        let east = -self.sin_lon * d[0] + self.cos_lon * d[1];
        let north = -self.sin_lat * self.cos_lon * d[0] - self.sin_lat * self.sin_lon * d[1]
            + self.cos_lat * d[2];
        let up = self.cos_lat * self.cos_lon * d[0]
            + self.cos_lat * self.sin_lon * d[1]
            + self.sin_lat * d[2];
        [east, north, up]
    }

    /// (east, north) in metres of a point on the ellipsoid surface (height 0,
    /// like the origin: drive files carry no height).
    pub fn to_en(&self, lat_deg: f64, lon_deg: f64) -> (f64, f64) {
        let [e, n, _] = self.to_enu(lat_deg, lon_deg, 0.0);
        (e, n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn origin_maps_to_zero() {
        let f = LocalFrame::new(32.7655346, 35.0136362, 0.0);
        let [e, n, u] = f.to_enu(32.7655346, 35.0136362, 0.0);
        assert!(e.abs() < 1e-9 && n.abs() < 1e-9 && u.abs() < 1e-9);
    }

    /// Published examples: GeographicLib's `CartConvert` manual
    /// (`echo 33.3 44.4 6000 | CartConvert -l 33 44 20` prints
    /// `37288.97 33374.29 5783.64`) and GNU Octave mapping's `geodetic2enu`
    /// help (e = 165.72, n = 222.18, u = 799.99).
    #[test]
    fn matches_published_examples() {
        let f = LocalFrame::new(33.0, 44.0, 20.0);
        let [e, n, u] = f.to_enu(33.3, 44.4, 6000.0);
        assert!((e - 37288.97).abs() < 0.01, "east {e}");
        assert!((n - 33374.29).abs() < 0.01, "north {n}");
        assert!((u - 5783.64).abs() < 0.01, "up {u}");
        let f = LocalFrame::new(42.0, -82.0, 200.0);
        let [e, n, u] = f.to_enu(42.002, -81.998, 1000.0);
        assert!((e - 165.72).abs() < 0.01, "east {e}");
        assert!((n - 222.18).abs() < 0.01, "north {n}");
        assert!((u - 799.99).abs() < 0.01, "up {u}");
    }

    /// Small steps follow the ellipsoid's radii of curvature: north = M dphi,
    /// east = N cos(phi) dlambda.
    #[test]
    fn small_steps_follow_the_radii_of_curvature() {
        let lat: f64 = 45.0;
        let s2 = lat.to_radians().sin().powi(2);
        let m = WGS84_A * (1.0 - E2) / (1.0 - E2 * s2).powf(1.5);
        let n = WGS84_A / (1.0 - E2 * s2).sqrt();
        let d = 1e-5_f64;
        let f = LocalFrame::new(lat, 10.0, 0.0);
        let (_, north) = f.to_en(lat + d, 10.0);
        let (east, _) = f.to_en(lat, 10.0 + d);
        assert!((north - m * d.to_radians()).abs() < 1e-6, "{north}");
        assert!(
            (east - n * lat.to_radians().cos() * d.to_radians()).abs() < 1e-6,
            "{east}"
        );
    }
}
