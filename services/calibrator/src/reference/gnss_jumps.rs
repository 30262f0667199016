//! GNSS jumps: stretches where the fixes sit off by a constant offset (an
//! RTK receiver dropping to a float or DGPS fix, a multipath jump), found
//! against the wheels' dead-reckoning and set aside before the reference
//! is smoothed.
//!
//! Between two consecutive fixes the car moved by what the wheels and the
//! heading say; the fixes' own displacement differs from it by the GNSS
//! noise of two fixes and the dead-reckoning's small error over a fraction
//! of a second. Its spread is measured on the drive itself (robust), along
//! the travel and across it apart: time-stamp jitter and the wheels' scale
//! err along it, the heading across it. A jump shows as one displacement far outside that spread when it
//! starts and an opposite one when it ends: an edge beyond
//! [`EDGE_SIGMAS`] sigma_e followed by an edge that cancels it (within the
//! noise of two differences and a quarter of the jump, so a jump that moves
//! a little while it lasts still pairs), with every fix between sitting off
//! by the jump (three quarters of them within half its size), so two noise
//! edges that happen to cancel do not make a jump. The fixes between the
//! two edges are set aside. An edge that nothing cancels (a wheel spike, a lasting
//! shift of the GNSS datum) is counted, not acted on: the per-segment poses
//! and the robust weights of the fit absorb it.
//!
//! Pure: fixes, a dead-reckoned track and a spread in; decisions out.

/// An edge is a fix-to-fix displacement this many sigmas (along and
/// across the travel) off the dead-reckoning's (a Rayleigh tail of exp(-18): about one false edge in
/// 10^8 differences of Gaussian noise).
pub const EDGE_SIGMAS: f64 = 6.0;

/// Longest jump looked for, s: a longer offset is a datum shift or the
/// wheels' own drift, which the dead-reckoning cannot tell apart from a
/// jump over that long.
pub const MAX_JUMP_S: f64 = 30.0;
/// Edges looked at for the end of one jump (noise edges and smaller jumps
/// may lie inside a long one).
const MAX_EDGES_INSIDE: usize = 50;
/// Fix pairs further apart than this are not compared, s.
const MAX_PAIR_DT_S: f64 = 1.5;

/// A displacement pair: the later fix's index, the GNSS displacement and
/// the dead-reckoned one, m.
type Pair = (usize, [f64; 2], [f64; 2]);

/// A pair's residual displacement, m, with the wheels' unit direction of
/// travel (where they moved).
type Residual = (usize, [f64; 2], Option<[f64; 2]>);

/// One jump found and set aside.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Jump {
    /// Time of the first fix set aside, s.
    #[serde(rename = "t_start_s")]
    pub t_start: f64,
    /// Time of the first fix back on the track, s.
    #[serde(rename = "t_end_s")]
    pub t_end: f64,
    /// Size of the jump (mean of the two edges), m.
    pub size_m: f64,
    /// Fixes set aside.
    pub fixes: usize,
}

/// What the search found.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct JumpSearch {
    /// Per fix: true where it lies inside a jump.
    pub set_aside: Vec<bool>,
    /// The jumps.
    pub jumps: Vec<Jump>,
    /// Edges nothing cancelled.
    pub unpaired_edges: usize,
    /// Robust 1-sigma per axis of the fix-to-fix displacement against the
    /// dead-reckoning, m (`None`: too few pairs to measure it).
    pub sigma_e_m: Option<f64>,
}

/// Find jumps. `fix_t`/`fix_xy`: the fixes (antenna, time order);
/// `dr_at(t)`: the dead-reckoned antenna position at `t`, `None` where the
/// wheels do not cover `t` or a wheel piece starts in between (pairs across
/// it are skipped by comparing both ends' piece: the closure returns the
/// piece index with the position).
pub fn find(
    fix_t: &[f64],
    fix_xy: &[[f64; 2]],
    dr_at: &dyn Fn(f64) -> Option<(usize, [f64; 2])>,
) -> JumpSearch {
    let n = fix_t.len();
    let mut out = JumpSearch {
        set_aside: vec![false; n],
        ..JumpSearch::default()
    };
    if n < 20 {
        return out;
    }
    let dr: Vec<Option<(usize, [f64; 2])>> = fix_t.iter().map(|&t| dr_at(t)).collect();
    let pairs = displacement_pairs(fix_t, fix_xy, &dr);
    if pairs.len() < 20 {
        return out;
    }
    let scale = wheel_scale(&pairs);
    let e = residuals(&pairs, scale);
    let Some(noise) = Noise::of(&e) else {
        return out;
    };
    out.sigma_e_m = Some(noise.e);
    let edges: Vec<(usize, [f64; 2])> = e
        .into_iter()
        .filter(|(_, v, u)| noise.sigmas(*v, *u) > EDGE_SIGMAS)
        .map(|(j, v, _)| (j, v))
        .collect();
    let track = Track {
        fix_t,
        fix_xy,
        dr: &dr,
        scale,
        sigma_max: noise.max(),
    };
    track.pair_edges(&edges, &mut out);
    out
}

/// Displacement pairs (j-1, j) of fixes at most [`MAX_PAIR_DT_S`] apart on
/// one wheel piece: (j, GNSS displacement, dead-reckoned displacement).
fn displacement_pairs(
    fix_t: &[f64],
    fix_xy: &[[f64; 2]],
    dr: &[Option<(usize, [f64; 2])>],
) -> Vec<Pair> {
    let mut pairs: Vec<Pair> = Vec::new();
    for j in 1..fix_t.len() {
        let dt = fix_t[j] - fix_t[j - 1];
        if !(dt > 0.0 && dt <= MAX_PAIR_DT_S) {
            continue;
        }
        let (Some((pa, a)), Some((pb, b))) = (dr[j - 1], dr[j]) else {
            continue;
        };
        if pa != pb {
            continue;
        }
        let dz = [
            fix_xy[j][0] - fix_xy[j - 1][0],
            fix_xy[j][1] - fix_xy[j - 1][1],
        ];
        let dd = [b[0] - a[0], b[1] - a[1]];
        pairs.push((j, dz, dd));
    }
    pairs
}

/// The wheels' scale against the GNSS (the nominal circumference is a
/// percent off): a robust ratio of the longer displacements.
fn wheel_scale(pairs: &[Pair]) -> f64 {
    let mut ratios: Vec<f64> = pairs
        .iter()
        .filter_map(|(_, dz, dd)| {
            let l = dd[0].hypot(dd[1]);
            (l > 0.3).then(|| (dz[0] * dd[0] + dz[1] * dd[1]) / (l * l))
        })
        .collect();
    stats::upper_median(&mut ratios).unwrap_or(1.0)
}

/// Residual displacement per pair, and the wheels' direction of travel
/// (where they moved): stamp jitter and the wheels' scale err along it,
/// the heading across it, so each has its own spread.
fn residuals(pairs: &[Pair], scale: f64) -> Vec<Residual> {
    pairs
        .iter()
        .map(|(j, dz, dd)| {
            let l = dd[0].hypot(dd[1]);
            let u = (l > 0.05).then(|| [dd[0] / l, dd[1] / l]);
            (*j, [dz[0] - scale * dd[0], dz[1] - scale * dd[1]], u)
        })
        .collect()
}

/// `v` along and across the unit direction `u`.
fn split(v: [f64; 2], u: [f64; 2]) -> (f64, f64) {
    (v[0] * u[0] + v[1] * u[1], -v[0] * u[1] + v[1] * u[0])
}

/// The robust 1-sigmas of the residual displacements, m.
struct Noise {
    /// Per axis.
    e: f64,
    /// Along the travel.
    along: f64,
    /// Across the travel.
    across: f64,
}

impl Noise {
    /// From the residuals (`None` when there are none); along and across
    /// the travel apart when at least 20 residuals have a direction.
    fn of(e: &[Residual]) -> Option<Noise> {
        let mut along: Vec<f64> = Vec::new();
        let mut across: Vec<f64> = Vec::new();
        let mut comps: Vec<f64> = Vec::new();
        for (_, v, u) in e {
            comps.extend([v[0].abs(), v[1].abs()]);
            if let Some(u) = u {
                let (a, c) = split(*v, *u);
                along.push(a.abs());
                across.push(c.abs());
            }
        }
        let mad = stats::upper_median(&mut comps)?;
        // A floor of 1 mm: fixes rounded to the millimetre have no finer noise.
        let sigma_e = (1.4826 * mad).max(1e-3);
        let (sigma_al, sigma_cr) = if along.len() >= 20 {
            (
                stats::upper_median(&mut along).map_or(sigma_e, |m| (1.4826 * m).max(1e-3)),
                stats::upper_median(&mut across).map_or(sigma_e, |m| (1.4826 * m).max(1e-3)),
            )
        } else {
            (sigma_e, sigma_e)
        };
        Some(Noise {
            e: sigma_e,
            along: sigma_al,
            across: sigma_cr,
        })
    }

    /// The larger of the along and across sigmas.
    fn max(&self) -> f64 {
        self.along.max(self.across)
    }

    /// Size of a residual in sigmas: along and across the travel apart.
    fn sigmas(&self, v: [f64; 2], u: Option<[f64; 2]>) -> f64 {
        match u {
            Some(u) => {
                let (a, c) = split(v, u);
                (a / self.along).hypot(c / self.across)
            }
            None => v[0].hypot(v[1]) / self.e,
        }
    }
}

/// The fixes against the wheels' track, for pairing edges into jumps.
struct Track<'a> {
    fix_t: &'a [f64],
    fix_xy: &'a [[f64; 2]],
    dr: &'a [Option<(usize, [f64; 2])>],
    /// The wheels' scale against the GNSS.
    scale: f64,
    /// [`Noise::max`].
    sigma_max: f64,
}

impl Track<'_> {
    /// The fixes of a candidate jump from `a` (first fix off) to `b` (first
    /// fix back) must sit off by the jump, not return after the edge: each
    /// fix's offset against the track through fixes a-1 and b (the wheels'
    /// shape between, their slow drift spread linearly) within half the
    /// jump plus 3 sigma_e of it, for at least three quarters of them.
    fn holds(&self, a: usize, b: usize, jump: [f64; 2]) -> bool {
        let (fix_t, fix_xy, dr, scale) = (self.fix_t, self.fix_xy, self.dr, self.scale);
        let (Some((_, d0)), Some((_, d1))) = (dr[a - 1], dr[b]) else {
            return false;
        };
        let z0 = fix_xy[a - 1];
        let span = fix_t[b] - fix_t[a - 1];
        let drift = [
            fix_xy[b][0] - z0[0] - scale * (d1[0] - d0[0]),
            fix_xy[b][1] - z0[1] - scale * (d1[1] - d0[1]),
        ];
        let tol = 0.5 * jump[0].hypot(jump[1]) + 3.0 * self.sigma_max;
        let mut good = 0usize;
        for j in a..b {
            let Some((_, dj)) = dr[j] else {
                return false;
            };
            let w = (fix_t[j] - fix_t[a - 1]) / span;
            let r = [
                fix_xy[j][0] - z0[0] - scale * (dj[0] - d0[0]) - w * drift[0],
                fix_xy[j][1] - z0[1] - scale * (dj[1] - d0[1]) - w * drift[1],
            ];
            if (r[0] - jump[0]).hypot(r[1] - jump[1]) <= tol {
                good += 1;
            }
        }
        4 * good >= 3 * (b - a)
    }

    /// Pair the edges (in time order) into jumps: set their fixes aside in
    /// `out`, count the edges left unpaired.
    fn pair_edges(&self, edges: &[(usize, [f64; 2])], out: &mut JumpSearch) {
        let (fix_t, sigma_max) = (self.fix_t, self.sigma_max);
        let mut i = 0;
        while i < edges.len() {
            let (ja, ea) = edges[i];
            // The first later edge (within the longest jump, and the next
            // MAX_EDGES_INSIDE edges) that cancels this one and whose fixes
            // between hold the offset; smaller jumps and noise edges may lie
            // between.
            let closing = (i + 1..edges.len().min(i + 1 + MAX_EDGES_INSIDE)).find(|&m| {
                let (jb, eb) = edges[m];
                let (la, lb) = (ea[0].hypot(ea[1]), eb[0].hypot(eb[1]));
                let rest = (ea[0] + eb[0]).hypot(ea[1] + eb[1]);
                let tol = (4.0 * std::f64::consts::SQRT_2 * sigma_max + 0.25 * la.min(lb))
                    .min(0.5 * la.min(lb));
                let jump = [0.5 * (ea[0] - eb[0]), 0.5 * (ea[1] - eb[1])];
                rest <= tol
                    && fix_t[jb] - fix_t[ja] <= MAX_JUMP_S
                    && ja >= 1
                    && self.holds(ja, jb, jump)
            });
            match closing {
                Some(m) => {
                    let (jb, eb) = edges[m];
                    for s in &mut out.set_aside[ja..jb] {
                        *s = true;
                    }
                    out.jumps.push(Jump {
                        t_start: fix_t[ja],
                        t_end: fix_t[jb],
                        size_m: 0.5 * (ea[0].hypot(ea[1]) + eb[0].hypot(eb[1])),
                        fixes: jb - ja,
                    });
                    out.unpaired_edges += m - i - 1;
                    i = m + 1;
                }
                None => {
                    out.unpaired_edges += 1;
                    i += 1;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A car driving a circle at 10 m/s, fixes at 10 Hz with 2 cm noise
    /// (a fixed pseudo-random sequence).
    fn drive(jumps: &[(f64, f64, [f64; 2])]) -> (Vec<f64>, Vec<[f64; 2]>) {
        let mut state = 12345u64;
        let mut noise = || {
            // Sum of 12 uniforms - 6: close to a standard normal.
            let mut s = 0.0;
            for _ in 0..12 {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                s += (state >> 11) as f64 / (1u64 << 53) as f64;
            }
            s - 6.0
        };
        let t: Vec<f64> = (0..3000).map(|k| k as f64 * 0.1).collect();
        let xy = t
            .iter()
            .map(|&t| {
                let (x, y) = (100.0 * (t / 10.0).sin(), 100.0 * (1.0 - (t / 10.0).cos()));
                let (mut ox, mut oy) = (0.0, 0.0);
                for (a, b, o) in jumps {
                    if t >= *a && t < *b {
                        ox += o[0];
                        oy += o[1];
                    }
                }
                [x + ox + 0.02 * noise(), y + oy + 0.02 * noise()]
            })
            .collect();
        (t, xy)
    }

    fn dr(t: f64) -> Option<(usize, [f64; 2])> {
        // The wheels 0.5 % long: the scale is found from the drive.
        let k = 1.005;
        Some((
            0,
            [
                k * 100.0 * (t / 10.0).sin(),
                k * 100.0 * (1.0 - (t / 10.0).cos()),
            ],
        ))
    }

    #[test]
    fn clean_fixes_have_no_jump() {
        let (t, xy) = drive(&[]);
        let s = find(&t, &xy, &dr);
        assert!(s.jumps.is_empty(), "{:?}", s.jumps);
        assert!(s.set_aside.iter().all(|a| !a));
        let sigma = s.sigma_e_m.unwrap();
        // Two fixes of 2 cm noise differ by 2.8 cm per axis.
        assert!((0.02..0.04).contains(&sigma), "{sigma}");
    }

    #[test]
    fn jumps_are_set_aside_exactly_and_the_rest_kept() {
        let jumps = [
            (20.0, 25.0, [0.5, 0.0]),
            (100.0, 118.0, [-2.0, 2.0]),
            (200.0, 202.0, [0.0, 3.0]),
        ];
        let (t, xy) = drive(&jumps);
        let s = find(&t, &xy, &dr);
        assert_eq!(s.jumps.len(), 3, "{:?}", s.jumps);
        for (k, &tk) in t.iter().enumerate() {
            let inside = jumps.iter().any(|(a, b, _)| tk >= *a && tk < *b);
            assert_eq!(s.set_aside[k], inside, "t = {tk}");
        }
        assert!((s.jumps[1].size_m - 8f64.sqrt()).abs() < 0.1);
    }

    #[test]
    fn a_lasting_shift_is_counted_not_set_aside() {
        let (t, xy) = drive(&[(150.0, 1e9, [1.0, 0.0])]);
        let s = find(&t, &xy, &dr);
        assert!(s.jumps.is_empty());
        assert_eq!(s.unpaired_edges, 1);
        assert!(s.set_aside.iter().all(|a| !a));
    }
}
