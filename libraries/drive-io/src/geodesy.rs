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

/// Geodetic (lat, lon in degrees, height in metres) of an ECEF position:
/// the inverse of [`geodetic_to_ecef`]. Longitude from `atan2`, latitude
/// by the fixed-point iteration tan(lat) = (z + e^2 N sin(lat)) / p, which
/// contracts by about e^2 per step (converged to the last bit within ten
/// steps anywhere near the surface), height from the closed form
/// p cos(lat) + z sin(lat) - a^2 / N, which holds at the poles too.
pub fn ecef_to_geodetic(ecef: [f64; 3]) -> (f64, f64, f64) {
    let [x, y, z] = ecef;
    let p = x.hypot(y);
    let lon = y.atan2(x);
    let mut lat = z.atan2(p * (1.0 - E2));
    for _ in 0..20 {
        let s = lat.sin();
        let n = WGS84_A / (1.0 - E2 * s * s).sqrt();
        let next = (z + E2 * n * s).atan2(p);
        let done = (next - lat).abs() < 1e-15;
        lat = next;
        if done {
            break;
        }
    }
    let (s, c) = lat.sin_cos();
    let height = p * c + z * s - WGS84_A * (1.0 - E2 * s * s).sqrt();
    (lat.to_degrees(), lon.to_degrees(), height)
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

    /// Geodetic (lat, lon in degrees, height in metres) of a point given in
    /// this frame: the inverse of [`LocalFrame::to_enu`].
    pub fn to_geodetic(&self, east: f64, north: f64, up: f64) -> (f64, f64, f64) {
        // The transpose of the rotation in `to_enu`.
        let (sl, cl, so, co) = (self.sin_lat, self.cos_lat, self.sin_lon, self.cos_lon);
        let dx = -so * east - sl * co * north + cl * co * up;
        let dy = co * east - sl * so * north + cl * so * up;
        let dz = cl * north + sl * up;
        ecef_to_geodetic([
            self.origin_ecef[0] + dx,
            self.origin_ecef[1] + dy,
            self.origin_ecef[2] + dz,
        ])
    }

    /// (lat, lon) in degrees of the point on the ellipsoid surface (height
    /// 0) whose (east, north) in this frame are these: the inverse of
    /// [`LocalFrame::to_en`]. The surface curves away from the origin's
    /// tangent plane, so the up coordinate is solved for: Newton steps on
    /// the point's height, whose derivative along up is the cosine of the
    /// angle between the two verticals (about 1 for any drive).
    pub fn from_en(&self, east: f64, north: f64) -> (f64, f64) {
        let mut up = 0.0;
        let (mut lat, mut lon, mut height) = self.to_geodetic(east, north, up);
        for _ in 0..10 {
            if height.abs() < 1e-10 {
                break;
            }
            // Cosine of the angle between the origin's and the point's verticals.
            let (sl, cl) = lat.to_radians().sin_cos();
            let dlon = (lon - self.origin_lon_deg).to_radians();
            let cos_angle = (sl * self.sin_lat + cl * self.cos_lat * dlon.cos()).max(0.1);
            up -= height / cos_angle;
            (lat, lon, height) = self.to_geodetic(east, north, up);
        }
        (lat, lon)
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

    /// The published CartConvert example above read backwards: its printed
    /// ENU (rounded to 0.01 m, about 1e-7 degrees) gives back 33.3, 44.4,
    /// 6000 m.
    #[test]
    fn inverse_matches_the_published_example() {
        let f = LocalFrame::new(33.0, 44.0, 20.0);
        let (lat, lon, h) = f.to_geodetic(37288.97, 33374.29, 5783.64);
        assert!((lat - 33.3).abs() < 2e-7, "lat {lat}");
        assert!((lon - 44.4).abs() < 2e-7, "lon {lon}");
        assert!((h - 6000.0).abs() < 0.02, "height {h}");
    }

    /// ECEF to geodetic and back, near the equator, at mid latitudes, near
    /// the poles and at altitude.
    #[test]
    fn ecef_round_trips() {
        for (lat, lon, h) in [
            (0.0, 0.0, 0.0),
            (45.0, -120.0, 350.0),
            (-33.9, 151.2, -30.0),
            (89.9999, 10.0, 2000.0),
            (-89.99, -170.0, 0.0),
            (32.7655346, 35.0136362, 0.0),
        ] {
            let (la, lo, hh) = ecef_to_geodetic(geodetic_to_ecef(lat, lon, h));
            assert!((la - lat).abs() < 1e-11, "lat {lat}: {la}");
            assert!(
                (lo - lon).abs() < 1e-11 || lat.abs() > 89.99,
                "lon {lon}: {lo}"
            );
            assert!((hh - h).abs() < 1e-6, "h {h}: {hh}");
        }
    }

    /// Surface points far from the origin (100 km and more, where the
    /// surface is 800 m below the tangent plane) come back to 1e-11 degrees
    /// (about a micrometre).
    #[test]
    fn from_en_inverts_to_en_far_from_the_origin() {
        let f = LocalFrame::new(48.1, 11.5, 0.0);
        for (lat, lon) in [
            (48.1, 11.5),
            (48.1000001, 11.4999999),
            (49.0, 12.5),
            (47.2, 10.1),
            (50.3, 15.0),
        ] {
            let (e, n) = f.to_en(lat, lon);
            let (la, lo) = f.from_en(e, n);
            assert!((la - lat).abs() < 1e-11, "lat {lat}: {la}");
            assert!((lo - lon).abs() < 1e-11, "lon {lon}: {lo}");
        }
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
