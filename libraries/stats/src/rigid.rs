//! The 2-D rigid motion (a rotation and a translation) that lays one set
//! of points on another best in the weighted least-squares sense, in closed
//! form (2-D Procrustes without scaling): how a dead-reckoned track is
//! placed on GNSS fixes when its start pose is not known.
//!
//! One home for the diagnosis's held-out blocks and the odometry's outage
//! evaluation.

/// A rigid motion: rotate about `from_centroid` by `angle`, then move
/// `from_centroid` onto `to_centroid`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rigid2 {
    /// Rotation, rad (counter-clockwise).
    pub angle: f64,
    /// The weighted centroid of the points moved.
    pub from_centroid: [f64; 2],
    /// The weighted centroid of the points they are laid on.
    pub to_centroid: [f64; 2],
    /// The weighted mean squared distance of the moved points from their
    /// centroid, m^2: how well they fix the rotation (0 for one point).
    pub spread_m2: f64,
}

impl Rigid2 {
    /// `p` moved.
    pub fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.angle.sin_cos();
        let (x, y) = (p[0] - self.from_centroid[0], p[1] - self.from_centroid[1]);
        [
            self.to_centroid[0] + c * x - s * y,
            self.to_centroid[1] + s * x + c * y,
        ]
    }
}

/// The rigid motion laying the points `from` on the points `to`, each pair
/// with a weight (`(weight, from, to)`; unit weights for plain least
/// squares). `None` without a positive total weight or with a non-finite
/// result.
pub fn fit(pairs: impl Iterator<Item = (f64, [f64; 2], [f64; 2])> + Clone) -> Option<Rigid2> {
    let (mut sw, mut fm, mut tm) = (0.0, [0.0; 2], [0.0; 2]);
    for (w, f, t) in pairs.clone() {
        sw += w;
        for j in 0..2 {
            fm[j] += w * f[j];
            tm[j] += w * t[j];
        }
    }
    if sw.is_nan() || sw <= 0.0 {
        return None;
    }
    let (fm, tm) = ([fm[0] / sw, fm[1] / sw], [tm[0] / sw, tm[1] / sw]);
    let (mut dot, mut cross, mut spread) = (0.0, 0.0, 0.0);
    for (w, f, t) in pairs {
        let (fx, fy, tx, ty) = (f[0] - fm[0], f[1] - fm[1], t[0] - tm[0], t[1] - tm[1]);
        dot += w * (fx * tx + fy * ty);
        cross += w * (fx * ty - fy * tx);
        spread += w * (fx * fx + fy * fy);
    }
    let angle = cross.atan2(dot);
    (angle.is_finite() && spread.is_finite()).then_some(Rigid2 {
        angle,
        from_centroid: fm,
        to_centroid: tm,
        spread_m2: spread / sw,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_turned_and_moved_track_is_laid_back() {
        let track: Vec<[f64; 2]> = (0..50)
            .map(|i| {
                let a = i as f64 * 0.05;
                [30.0 * a.cos(), 12.0 * a.sin() + i as f64]
            })
            .collect();
        let (angle, shift) = (0.3f64, [4.0, -7.0]);
        let (s, c) = angle.sin_cos();
        let moved: Vec<[f64; 2]> = track
            .iter()
            .map(|p| {
                [
                    c * p[0] - s * p[1] + shift[0],
                    s * p[0] + c * p[1] + shift[1],
                ]
            })
            .collect();
        let r = fit(track.iter().zip(&moved).map(|(a, b)| (1.0, *a, *b))).expect("fitted");
        assert!((r.angle - angle).abs() < 1e-12, "{}", r.angle);
        for (a, b) in track.iter().zip(&moved) {
            let p = r.apply(*a);
            assert!((p[0] - b[0]).abs() < 1e-9 && (p[1] - b[1]).abs() < 1e-9);
        }
        // A pair with no weight does not pull.
        let mut pairs: Vec<(f64, [f64; 2], [f64; 2])> = track
            .iter()
            .zip(&moved)
            .map(|(a, b)| (1.0, *a, *b))
            .collect();
        pairs.push((0.0, [1e3, 1e3], [-1e3, 5e2]));
        let w = fit(pairs.iter().copied()).expect("fitted");
        assert!((w.angle - angle).abs() < 1e-12);
        // One point fixes no rotation: its spread says so.
        let one = fit([(1.0, [1.0, 2.0], [3.0, 4.0])].into_iter()).expect("fitted");
        assert_eq!(one.spread_m2, 0.0);
        assert!(fit([(0.0, [1.0, 2.0], [3.0, 4.0])].into_iter()).is_none());
    }
}
