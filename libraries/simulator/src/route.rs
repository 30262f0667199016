//! Routes: a path built from straights and circular turns (turtle style), its
//! attributes (speed limit, acceleration limits, GNSS cover, ramps) and the
//! speed profile a driver would aim for.
//!
//! Closed routes are closed exactly: two straights are marked free and their
//! lengths solved so that the path returns to its start.

use super::SimError;
use std::f64::consts::TAU;

/// Grid spacing of the sampled path, m.
pub(crate) const DS: f64 = 0.25;
/// Largest lateral acceleration the speed profile allows, m/s^2.
const LATERAL_LIMIT: f64 = 4.0;
/// Wavelength of the rolling hills of `road_grade` on open roads, m.
const HILL_WAVELENGTH_M: f64 = 600.0;
/// Length over which grade changes are smoothed, m.
const GRADE_SMOOTHING_M: f64 = 8.0;

/// What applies to a stretch of road.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Attrs {
    /// Speed limit the driver keeps, m/s.
    pub speed: f64,
    /// Acceleration the driver uses, m/s^2.
    pub accel: f64,
    /// Deceleration the driver uses (before bends and stops), m/s^2.
    pub decel: f64,
    /// No GNSS reception (tunnel, garage).
    pub gnss_denied: bool,
    /// Ramp: -1 down, +1 up (times the `road_grade` magnitude), 0 level.
    pub ramp: f64,
}

#[derive(Debug, Clone, Copy)]
enum Prim {
    Straight { len: f64, free: Option<usize> },
    Turn { angle: f64, radius: f64 },
}

#[derive(Debug, Clone, Copy)]
struct Piece {
    prim: Prim,
    attrs: Attrs,
    stop_after_s: Option<f64>,
}

/// Builds a route piece by piece; attributes apply to the pieces that follow.
#[derive(Debug, Clone)]
pub(crate) struct RouteBuilder {
    pieces: Vec<Piece>,
    attrs: Attrs,
    free_min: [f64; 2],
}

impl RouteBuilder {
    /// Start with the given speed limit (km/h), comfortable accelerations.
    pub(crate) fn new(speed_kmh: f64) -> RouteBuilder {
        RouteBuilder {
            pieces: Vec::new(),
            attrs: Attrs {
                speed: speed_kmh / 3.6,
                accel: 1.5,
                decel: 2.0,
                gnss_denied: false,
                ramp: 0.0,
            },
            free_min: [0.0; 2],
        }
    }

    /// Speed limit for what follows, km/h.
    pub(crate) fn speed(&mut self, kmh: f64) -> &mut Self {
        self.attrs.speed = kmh / 3.6;
        self
    }

    /// Driver acceleration and deceleration for what follows, m/s^2.
    pub(crate) fn accel(&mut self, accel: f64, decel: f64) -> &mut Self {
        self.attrs.accel = accel;
        self.attrs.decel = decel;
        self
    }

    /// GNSS denied (true) or received (false) on what follows.
    pub(crate) fn gnss_denied(&mut self, denied: bool) -> &mut Self {
        self.attrs.gnss_denied = denied;
        self
    }

    /// Ramp direction for what follows (-1 down, 0 level, +1 up).
    pub(crate) fn ramp(&mut self, direction: f64) -> &mut Self {
        self.attrs.ramp = direction;
        self
    }

    /// A straight, m.
    pub(crate) fn straight(&mut self, len: f64) -> &mut Self {
        self.push(Prim::Straight { len, free: None })
    }

    /// A straight whose length closes the loop (`id` 0 or 1), at least `min_len`.
    pub(crate) fn free_straight(&mut self, id: usize, min_len: f64) -> &mut Self {
        if let Some(m) = self.free_min.get_mut(id) {
            *m = min_len;
        }
        self.push(Prim::Straight {
            len: 0.0,
            free: Some(id),
        })
    }

    /// A circular turn, degrees (positive = left) at radius m.
    pub(crate) fn turn(&mut self, angle_deg: f64, radius: f64) -> &mut Self {
        self.push(Prim::Turn {
            angle: angle_deg.to_radians(),
            radius,
        })
    }

    /// Stop at the end of the last piece for `dwell_s` seconds.
    pub(crate) fn stop(&mut self, dwell_s: f64) -> &mut Self {
        if let Some(p) = self.pieces.last_mut() {
            p.stop_after_s = Some(dwell_s);
        }
        self
    }

    fn push(&mut self, prim: Prim) -> &mut Self {
        self.pieces.push(Piece {
            prim,
            attrs: self.attrs,
            stop_after_s: None,
        });
        self
    }

    /// End pose (x, y, heading) and the heading of each free straight.
    fn trace(pieces: &[Piece]) -> ((f64, f64, f64), [Option<f64>; 2]) {
        let (mut x, mut y, mut h) = (0.0f64, 0.0f64, 0.0f64);
        let mut free = [None; 2];
        for p in pieces {
            match p.prim {
                Prim::Straight { len, free: f } => {
                    if let Some(id) = f {
                        if let Some(slot) = free.get_mut(id) {
                            *slot = Some(h);
                        }
                    }
                    x += len * h.cos();
                    y += len * h.sin();
                }
                Prim::Turn { angle, radius } => {
                    let (s0, c0) = h.sin_cos();
                    let h1 = h + angle;
                    let (s1, c1) = h1.sin_cos();
                    let r = radius * angle.signum();
                    x += r * (s1 - s0);
                    y += r * (c0 - c1);
                    h = h1;
                }
            }
        }
        ((x, y, h), free)
    }

    /// Finish the route. A closed route must turn a whole number of times and
    /// have two free straights that are not parallel.
    pub(crate) fn build(&self, name: &str, closed: bool, grade: f64) -> Result<Route, SimError> {
        let bad = |why: String| SimError::Route {
            scenario: name.to_string(),
            reason: why,
        };
        let mut pieces = self.pieces.clone();
        if closed {
            let ((gx, gy, h), free) = RouteBuilder::trace(&pieces);
            let turns = h / TAU;
            if (turns - turns.round()).abs() > 1e-9 || turns.round() == 0.0 {
                return Err(bad(format!(
                    "a closed route must turn whole circles, it turns {turns}"
                )));
            }
            let (Some(h0), Some(h1)) = (free[0], free[1]) else {
                return Err(bad("a closed route needs free straights 0 and 1".into()));
            };
            // Solve l0 u0 + l1 u1 = -(gx, gy).
            let (a, b, c, d) = (h0.cos(), h1.cos(), h0.sin(), h1.sin());
            let det = a * d - b * c;
            if det.abs() < 1e-3 {
                return Err(bad("the free straights are parallel".into()));
            }
            let l0 = (-gx * d + gy * b) / det;
            let l1 = (-gy * a + gx * c) / det;
            for (id, l) in [(0, l0), (1, l1)] {
                if l < self.free_min[id] {
                    return Err(bad(format!(
                        "free straight {id} would be {l:.1} m, below its minimum {:.1} m",
                        self.free_min[id]
                    )));
                }
            }
            for p in pieces.iter_mut() {
                if let Prim::Straight {
                    len,
                    free: Some(id),
                } = &mut p.prim
                {
                    *len = if *id == 0 { l0 } else { l1 };
                }
            }
        }
        Route::sample(&pieces, closed, grade).map_err(bad)
    }
}

/// A stop: the driver halts at `s` for `dwell_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Stop {
    /// Arc length of the stop line (within one lap), m.
    pub s: f64,
    /// Standstill time, s.
    pub dwell_s: f64,
}

/// A point of the path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PathPoint {
    pub x: f64,
    pub y: f64,
    pub v_ref: f64,
    /// d v_ref / ds, 1/s.
    pub dv_ds: f64,
    /// Road grade (rise over run).
    pub grade: f64,
    /// d grade / ds, 1/m.
    pub dgrade_ds: f64,
    pub attrs: Attrs,
}

/// The length of the pieces end to end, m.
fn total_length(pieces: &[Piece]) -> f64 {
    pieces
        .iter()
        .map(|p| match p.prim {
            Prim::Straight { len, .. } => len,
            Prim::Turn { angle, radius } => angle.abs() * radius,
        })
        .sum()
}

/// The pieces laid out on the grid: each point's position, heading,
/// curvature and attributes, and the stops.
struct Grid {
    x: Vec<f64>,
    y: Vec<f64>,
    heading: Vec<f64>,
    kappa: Vec<f64>,
    attr_index: Vec<u16>,
    attrs: Vec<Attrs>,
    stops: Vec<Stop>,
}

impl Grid {
    /// Lay `pieces` (`total` m long) out every `ds` m.
    fn lay_out(pieces: &[Piece], total: f64, ds: f64) -> Result<Grid, String> {
        let mut g = Grid {
            x: vec![0.0],
            y: vec![0.0],
            heading: vec![0.0],
            kappa: vec![0.0],
            attr_index: Vec::new(),
            attrs: Vec::new(),
            stops: Vec::new(),
        };
        let (mut px, mut py, mut ph) = (0.0f64, 0.0f64, 0.0f64);
        let mut s_end = 0.0;
        // Each piece is split into whole grid steps; the remainder is carried on.
        let mut carry = 0.0;
        for p in pieces {
            let ai = g.attribute_index(p.attrs)?;
            if g.attr_index.is_empty() {
                g.attr_index.push(ai);
            }
            let (len, k) = match p.prim {
                Prim::Straight { len, .. } => (len, 0.0),
                Prim::Turn { angle, radius } => {
                    if radius <= 0.0 {
                        return Err(format!("turn radius {radius} m is not positive"));
                    }
                    (angle.abs() * radius, angle.signum() / radius)
                }
            };
            if len < 0.0 {
                return Err(format!("negative piece length {len} m"));
            }
            let mut remaining = len;
            // Fill the rest of the previous grid step first.
            while remaining + carry >= ds - 1e-9 {
                let step = ds - carry;
                // Advance exactly along this piece by `step`.
                advance(&mut px, &mut py, &mut ph, step, k);
                remaining -= step;
                carry = 0.0;
                g.push(px, py, ph, k, ai);
            }
            if remaining > 0.0 {
                advance(&mut px, &mut py, &mut ph, remaining, k);
                carry += remaining;
            }
            s_end += len;
            if let Some(dwell) = p.stop_after_s {
                g.stops.push(Stop {
                    s: s_end,
                    dwell_s: dwell,
                });
            }
        }
        if total < 2.0 || !total.is_finite() {
            return Err(format!("the route is {total} m long"));
        }
        if g.x.len() < (total / ds).round() as usize + 1 {
            // Rounding left the final grid point out: it is the route's end.
            let ai = g.attr_index.last().copied().unwrap_or(0);
            g.push(px, py, ph, 0.0, ai);
        }
        Ok(g)
    }

    /// The index of `attrs` among the distinct attributes (added when new).
    fn attribute_index(&mut self, attrs: Attrs) -> Result<u16, String> {
        let ai = match self.attrs.iter().position(|a| *a == attrs) {
            Some(i) => i,
            None => {
                self.attrs.push(attrs);
                self.attrs.len() - 1
            }
        };
        u16::try_from(ai).map_err(|_| "too many distinct attributes".to_string())
    }

    fn push(&mut self, x: f64, y: f64, heading: f64, kappa: f64, attr_index: u16) {
        self.x.push(x);
        self.y.push(y);
        self.heading.push(heading);
        self.kappa.push(kappa);
        self.attr_index.push(attr_index);
    }

    fn attrs_at(&self, i: usize) -> Attrs {
        self.attrs[self.attr_index[i] as usize]
    }

    /// Speed limits: attribute speed and lateral acceleration in bends (the
    /// curvature is spread over 2 m so that arcs shorter than that still
    /// count), then what braking before and accelerating after allow.
    fn speed_limits(&self, closed: bool, ds: f64) -> Vec<f64> {
        let n = self.x.len();
        let mut v: Vec<f64> = (0..n)
            .map(|i| {
                let a = self.attrs_at(i);
                let k = self.kappa[i.saturating_sub(4)..(i + 5).min(n)]
                    .iter()
                    .fold(0.0f64, |m, k| m.max(k.abs()));
                if k > 1e-9 {
                    a.speed.min((LATERAL_LIMIT / k).sqrt())
                } else {
                    a.speed
                }
            })
            .collect();
        let passes = if closed { 2 } else { 1 };
        for _ in 0..passes {
            for j in (0..n).rev() {
                let next = if j + 1 < n {
                    v[j + 1]
                } else if closed {
                    v[0]
                } else {
                    continue;
                };
                let d = self.attrs_at(j).decel;
                v[j] = v[j].min((next * next + 2.0 * d * ds).sqrt());
            }
        }
        for _ in 0..passes {
            for j in 0..n {
                let prev = if j > 0 {
                    v[j - 1]
                } else if closed {
                    v[n - 1]
                } else {
                    continue;
                };
                let a = self.attrs_at(j).accel;
                v[j] = v[j].min((prev * prev + 2.0 * a * ds).sqrt());
            }
        }
        v
    }

    /// Grade: ramps where the route has them, rolling hills otherwise,
    /// smoothed over [`GRADE_SMOOTHING_M`].
    fn grade(&self, closed: bool, ds: f64, length: f64, grade_mag: f64) -> Vec<f64> {
        let n = self.x.len();
        let has_ramps = self.attrs.iter().any(|a| a.ramp != 0.0);
        let raw: Vec<f64> = (0..n)
            .map(|i| {
                if grade_mag == 0.0 {
                    0.0
                } else if has_ramps {
                    grade_mag * self.attrs_at(i).ramp
                } else {
                    let wavelength = if closed {
                        length / (length / HILL_WAVELENGTH_M).round().max(1.0)
                    } else {
                        HILL_WAVELENGTH_M
                    };
                    grade_mag * (TAU * i as f64 * ds / wavelength).sin()
                }
            })
            .collect();
        let half = (GRADE_SMOOTHING_M / ds / 2.0) as usize;
        (0..n)
            .map(|i| {
                let lo = i.saturating_sub(half);
                let hi = (i + half + 1).min(n);
                raw[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
            })
            .collect()
    }
}

/// A sampled route.
#[derive(Debug, Clone)]
pub(crate) struct Route {
    closed: bool,
    length: f64,
    ds: f64,
    x: Vec<f64>,
    y: Vec<f64>,
    heading: Vec<f64>,
    v_ref: Vec<f64>,
    grade: Vec<f64>,
    attr_index: Vec<u16>,
    attrs: Vec<Attrs>,
    stops: Vec<Stop>,
}

impl Route {
    fn sample(pieces: &[Piece], closed: bool, grade_mag: f64) -> Result<Route, String> {
        let total = total_length(pieces);
        // A grid spacing that divides the route exactly (so a loop's last
        // point is its first).
        let ds = total / (total / DS).round().max(8.0);
        let grid = Grid::lay_out(pieces, total, ds)?;
        let n = grid.x.len();
        let length = (n - 1) as f64 * ds;
        let v_ref = grid.speed_limits(closed, ds);
        let grade = grid.grade(closed, ds, length, grade_mag);
        Ok(Route {
            closed,
            length,
            ds,
            x: grid.x,
            y: grid.y,
            heading: grid.heading,
            v_ref,
            grade,
            attr_index: grid.attr_index,
            attrs: grid.attrs,
            stops: grid.stops,
        })
    }

    /// An open route through points already sampled every `ds` m of arc
    /// length (a recorded track, smoothed and resampled): heading from the
    /// differences, `v_ref` as given, one set of attributes, the rolling
    /// hills of `road_grade` (magnitude `grade_mag`) as on other open
    /// roads, no stops.
    pub(crate) fn from_points(
        x: Vec<f64>,
        y: Vec<f64>,
        v_ref: Vec<f64>,
        ds: f64,
        attrs: Attrs,
        grade_mag: f64,
    ) -> Result<Route, String> {
        let n = x.len();
        if n < 8 || y.len() != n || v_ref.len() != n {
            return Err(format!(
                "a route needs at least 8 points with x, y and v_ref each (got {n})"
            ));
        }
        if !(ds > 0.0 && ds.is_finite()) {
            return Err(format!("grid spacing {ds} m is not positive"));
        }
        if x.iter().chain(&y).chain(&v_ref).any(|v| !v.is_finite()) {
            return Err("a route point is not finite".into());
        }
        let heading: Vec<f64> = (0..n)
            .map(|i| {
                let (a, b) = if i + 1 < n { (i, i + 1) } else { (i - 1, i) };
                (y[b] - y[a]).atan2(x[b] - x[a])
            })
            .collect();
        let half = (GRADE_SMOOTHING_M / ds / 2.0) as usize;
        let raw: Vec<f64> = (0..n)
            .map(|i| grade_mag * (TAU * i as f64 * ds / HILL_WAVELENGTH_M).sin())
            .collect();
        let grade = (0..n)
            .map(|i| {
                let lo = i.saturating_sub(half);
                let hi = (i + half + 1).min(n);
                raw[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
            })
            .collect();
        Ok(Route {
            closed: false,
            length: (n - 1) as f64 * ds,
            ds,
            x,
            y,
            heading,
            v_ref,
            grade,
            attr_index: vec![0; n],
            attrs: vec![attrs],
            stops: Vec::new(),
        })
    }

    /// Length of one lap (closed) or of the whole route (open), m.
    pub(crate) fn length(&self) -> f64 {
        self.length
    }

    /// Whether the route is a loop.
    pub(crate) fn is_closed(&self) -> bool {
        self.closed
    }

    /// Stops within one lap, in order.
    pub(crate) fn stops(&self) -> &[Stop] {
        &self.stops
    }

    /// Start heading, rad.
    pub(crate) fn start_heading(&self) -> f64 {
        self.heading[0]
    }

    /// Grid index and fraction for arc length `s` (wrapped on loops, clamped otherwise).
    fn locate(&self, s: f64) -> (usize, usize, f64) {
        let n = self.x.len();
        let s = if self.closed {
            s.rem_euclid(self.length)
        } else {
            s.clamp(0.0, self.length)
        };
        let f = s / self.ds;
        let i = (f.floor() as usize).min(n - 2);
        (i, i + 1, f - i as f64)
    }

    /// The path at arc length `s`.
    pub(crate) fn at(&self, s: f64) -> PathPoint {
        let (i, j, f) = self.locate(s);
        let lerp = |v: &[f64]| v[i] + f * (v[j] - v[i]);
        PathPoint {
            x: lerp(&self.x),
            y: lerp(&self.y),
            v_ref: lerp(&self.v_ref),
            dv_ds: (self.v_ref[j] - self.v_ref[i]) / self.ds,
            grade: lerp(&self.grade),
            dgrade_ds: (self.grade[j] - self.grade[i]) / self.ds,
            attrs: self.attrs[self.attr_index[if f < 0.5 { i } else { j }] as usize],
        }
    }

    /// The arc length of the path point nearest (x, y), searching `window_m`
    /// around `s_guess` (unwrapped on loops: the answer is near the guess).
    pub(crate) fn nearest_s(&self, x: f64, y: f64, s_guess: f64, window_m: f64) -> f64 {
        let steps = (window_m / self.ds).ceil() as i64;
        let base = (s_guess / self.ds).round() as i64;
        let n = self.x.len() as i64;
        let idx = |k: i64| -> Option<usize> {
            if self.closed {
                // The last grid point repeats the first; use n - 1 points per lap.
                Some(k.rem_euclid(n - 1) as usize)
            } else if (0..n).contains(&k) {
                Some(k as usize)
            } else {
                None
            }
        };
        let mut best = (f64::INFINITY, base);
        for k in base - steps..=base + steps {
            if let Some(i) = idx(k) {
                let d = (self.x[i] - x).powi(2) + (self.y[i] - y).powi(2);
                if d < best.0 {
                    best = (d, k);
                }
            }
        }
        // Refine on the segment to the better neighbour.
        let k = best.1;
        let mut s = k as f64 * self.ds;
        for (k0, k1) in [(k, k + 1), (k - 1, k)] {
            if let (Some(i0), Some(i1)) = (idx(k0), idx(k1)) {
                let (ex, ey) = (self.x[i1] - self.x[i0], self.y[i1] - self.y[i0]);
                let t = ((x - self.x[i0]) * ex + (y - self.y[i0]) * ey)
                    / (ex * ex + ey * ey).max(1e-12);
                if (0.0..=1.0).contains(&t) {
                    s = (k0 as f64 + t) * self.ds;
                    break;
                }
            }
        }
        s
    }
}

fn advance(x: &mut f64, y: &mut f64, h: &mut f64, len: f64, k: f64) {
    if k == 0.0 {
        *x += len * h.cos();
        *y += len * h.sin();
    } else {
        let h1 = *h + k * len;
        *x += (h1.sin() - h.sin()) / k;
        *y += (h.cos() - h1.cos()) / k;
        *h = h1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_closed_route_closes_and_the_lookup_finds_points() {
        let mut b = RouteBuilder::new(50.0);
        b.straight(100.0)
            .turn(90.0, 20.0)
            .free_straight(0, 10.0)
            .turn(90.0, 20.0)
            .free_straight(1, 10.0)
            .turn(90.0, 20.0)
            .straight(40.0)
            .stop(5.0)
            .turn(90.0, 20.0);
        let r = b.build("test", true, 0.0).unwrap();
        let end = r.at(r.length() - 1e-9);
        let start = r.at(0.0);
        assert!(
            (end.x - start.x).abs() < 0.01 && (end.y - start.y).abs() < 0.01,
            "{end:?}"
        );
        // Straights 100, 40, 100, 40 plus four quarter circles.
        let expect = 280.0 + TAU * 20.0;
        assert!(
            (r.length() - expect).abs() < 0.3,
            "{} vs {expect}",
            r.length()
        );
        let p = r.at(50.0);
        assert!((p.x - 50.0).abs() < 1e-9 && p.y.abs() < 1e-9);
        let s = r.nearest_s(50.3, 1.0, 45.0, 10.0);
        assert!((s - 50.3).abs() < 1e-6, "{s}");
        assert_eq!(r.stops().len(), 1);
        // Slower in the bends than on the straights.
        assert!(r.at(100.0 + 15.0).v_ref < 40.0 / 3.6);
    }

    #[test]
    fn bad_routes_are_errors() {
        let mut b = RouteBuilder::new(50.0);
        b.straight(100.0).turn(90.0, 20.0);
        assert!(b.build("t", true, 0.0).is_err());
        let mut b = RouteBuilder::new(50.0);
        b.free_straight(0, 0.0)
            .turn(180.0, 10.0)
            .free_straight(1, 0.0)
            .turn(180.0, 10.0);
        assert!(b.build("t", true, 0.0).is_err());
    }
}
