//! Where a recording's speed channel parts from a simulation's, over the
//! signals the wheels' reading depends on, when no catalogue effect names
//! the difference (issue 38).
//!
//! The speed channel's residual (`v_gnss / v_wheels - 1`, chord against
//! chord) is fitted on each drive by weighted least squares as an additive,
//! piecewise-constant function of the wheels' speed and the longitudinal
//! acceleration, `f(v) + g(a_x)` with `g = 0` where the car holds its
//! speed ([`interfaces::speed_map::SpeedMap`]). The speed bins are 4 m/s
//! wide up to 20 m/s, then 5 m/s; the acceleration bins are braking
//! (below -1 m/s^2), mild braking, holding the speed (within 0.3 m/s^2),
//! mild and hard acceleration. A bin is kept only where both drives have
//! enough rows in it, else merged into its neighbour (a speed bin into the
//! one below, an acceleration bin towards holding the speed). Weights are
//! the square of the speed (the GNSS chord's relative noise goes as
//! `1 / v`).
//!
//! Each drive's residuals are taken about its own level (the speed
//! channel's weighted mean: a constant is the circumference's scale, which
//! each drive's calibration sets). Each bin's difference (recording minus
//! simulation) has its sigma from the jackknife over the matched block
//! pairs (the GNSS error is correlated within a block, not across: whole
//! blocks are left out), its p-value from Student's t with one degree of
//! freedom fewer than the blocks that hold the bin; Holm's procedure over
//! the bins at the family's 5 % says which bins differ. (Swapping blocks
//! between the drives, as the channels' distances do, gives valid
//! p-values too, but a difference that every block shows widens the
//! swaps' spread, and with a bin in six blocks no swap test can reach
//! Holm's level.)
//!
//! The speed channel's p-value is the smaller of its distance's and the
//! map's (the least bin's times the bins), doubled: a difference that
//! depends on the speed or the acceleration can leave the pooled
//! distributions nearly alike.
//!
//! A bin is said to differ only where the speed channel differs (the
//! comparison clears the bins' verdicts on an alike channel: the channels'
//! family comes first).
//!
//! The mend: where the speed channel differs, the twin's map moves by the
//! difference, each bin's shrunk towards zero by `max(0, 1 - 1/z^2)` (a
//! bin at the noise moves little, one far beyond it nearly fully), its
//! recording-weighted mean taken out (the calibrated circumference holds
//! that), less what a catalogue knob moving in the same mend carries: the
//! part linear in a_x when the longitudinal slip moves, in v^2 when the
//! speed growth does (on the multibody s2 route the map's acceleration
//! bins and the slip's knob moved together for one difference and drove
//! the knob to zero). Where the channel does not differ the twin keeps its map.
//!
//! Pure: two channel series in, the map's difference out.

use super::limit::FAMILY_ALPHA;
use super::ChannelSeries;
use interfaces::speed_map::{bin_of, SpeedMap, Steps};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use stats::distributions::f_sf;

/// Fewest rows a bin needs in each drive.
const MIN_ROWS: usize = 40;
/// The acceleration edges before merging, m/s^2: braking, mild braking,
/// holding the speed, mild and hard acceleration.
const ACCEL_EDGES: [f64; 4] = [-1.0, -0.3, 0.3, 1.0];
/// The speed edges before merging, m/s.
const SPEED_EDGES: [f64; 7] = [4.0, 8.0, 12.0, 16.0, 20.0, 25.0, 30.0];

/// One bin of the map: what each drive shows there and their difference.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapBin {
    /// `speed` (m/s) or `a_x` (m/s^2).
    pub signal: String,
    /// Lower bound (the data's least value for the first bin).
    pub lo: f64,
    /// Upper bound (the data's largest value for the last bin).
    pub hi: f64,
    /// Rows in the bin: recording, simulation.
    pub rows: [usize; 2],
    /// Matched block pairs holding rows of the bin (in either drive).
    pub blocks: usize,
    /// The recording's level (speed bins) or its departure from holding
    /// the speed (acceleration bins), relative speed.
    pub recording: f64,
    /// The simulation's.
    pub simulation: f64,
    /// Recording minus simulation.
    pub difference: f64,
    /// Its sigma: the jackknife over the matched block pairs.
    pub sigma: f64,
    /// `difference / sigma`.
    pub z: f64,
    /// Two-sided, Student's t with one degree of freedom fewer than
    /// `blocks`.
    pub p_value: f64,
    /// Holm's decision over the bins at the family's 5 %, where the speed
    /// channel differs (false on an alike channel).
    pub differs: bool,
}

/// The speed channel's difference over speed and acceleration, and the
/// map a mended twin should carry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpeedMapDifference {
    /// Speed bins, then acceleration bins (holding the speed is the
    /// reference and has none).
    pub bins: Vec<MapBin>,
    /// The recording's rows where the car holds its speed.
    pub holding_rows: [usize; 2],
    /// The difference as a map: each bin shrunk towards zero by
    /// `max(0, 1 - 1/z^2)`, its recording-weighted mean taken out.
    pub shrunk: SpeedMap,
    /// The parts of `shrunk` the catalogue's forms shape, per bin (not in
    /// the JSON).
    #[serde(skip)]
    pub catalogue_parts: CataloguePart,
    /// What the simulation carried (its truth's `speed_map`), if any.
    pub declared: Option<SpeedMap>,
    /// What the mended simulation should carry: the declared map plus
    /// `shrunk` where the speed channel differs, else the declared map
    /// (set by [`SpeedMapDifference::mend`]).
    pub mended: Option<SpeedMap>,
    /// The effects named between the two drives whose fingerprint is in
    /// the speed channel (filled in by the comparison).
    pub named_in_channel: Vec<String>,
    /// The speed channel differs, bins of it differ, and no named effect
    /// speaks for it: physics the catalogue does not hold.
    pub unexplained: bool,
}

impl SpeedMapDifference {
    /// The bins that differ.
    pub fn differing(&self) -> impl Iterator<Item = &MapBin> {
        self.bins.iter().filter(|b| b.differs)
    }

    /// The map's own p-value for the speed channel: its smallest bin's,
    /// times the bins (Bonferroni), at most 1.
    pub fn p_value(&self) -> f64 {
        let least = self.bins.iter().map(|b| b.p_value).fold(1.0_f64, f64::min);
        (least * self.bins.len() as f64).min(1.0)
    }

    /// Set what the mended simulation carries: where the speed channel
    /// differs, the declared map moved by the shrunk difference, less the
    /// part a knob moving in the same mend carries (`slip_moves`: the
    /// longitudinal slip's, linear in a_x; `growth_moves`: the speed
    /// growth's, linear in v^2), so that one difference does not move both
    /// a knob and the map (on the multibody s2 route the map's acceleration
    /// bins and the slip's knob moved together and drove the knob to zero).
    ///
    /// `latency_move_s`: the GNSS latency's knob moves by this much in the
    /// same mend; the map that move makes in the speed channel (in
    /// `-a_x / v`, not additive in v and a_x) is taken out. On the
    /// multibody s3 route the map's acceleration bins took the recording's
    /// 0.065 s latency while the latency's knob moved by it too; the twin
    /// then showed four times the recording's slip.
    pub fn mend(
        &mut self,
        channel_differs: bool,
        slip_moves: bool,
        growth_moves: bool,
        latency_move_s: Option<f64>,
    ) {
        self.mended = if channel_differs {
            let mut step = self.shrunk.clone();
            if let Some(tau) = latency_move_s.filter(|t| t.is_finite()) {
                let (sp, ac) = &self.catalogue_parts.latency;
                for (x, p) in step.speed_m_s.values.iter_mut().zip(sp) {
                    *x -= tau * p;
                }
                for (x, p) in step.accel_m_s2.values.iter_mut().zip(ac) {
                    *x -= tau * p;
                }
            }
            if slip_moves {
                for (x, p) in step
                    .accel_m_s2
                    .values
                    .iter_mut()
                    .zip(&self.catalogue_parts.accel)
                {
                    *x -= p;
                }
            }
            if growth_moves {
                for (x, p) in step
                    .speed_m_s
                    .values
                    .iter_mut()
                    .zip(&self.catalogue_parts.speed)
                {
                    *x -= p;
                }
            }
            Some(match &self.declared {
                Some(d) => d.plus(&step),
                None => step,
            })
        } else {
            self.declared.clone()
        };
    }
}

/// The parts of a map the catalogue's forms shape, per bin of `shrunk`:
/// linear in a_x (the longitudinal slip) over the acceleration bins and in
/// v^2 (the speed growth) over the speed bins; and the map a second of
/// GNSS latency makes (the fixes describe `t - tau`: `-a_x / v`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CataloguePart {
    /// Per acceleration bin (0 where the car holds its speed).
    pub accel: Vec<f64>,
    /// Per speed bin.
    pub speed: Vec<f64>,
    /// A second of GNSS latency's map: per speed bin, then per
    /// acceleration bin (0 where the car holds its speed).
    pub latency: (Vec<f64>, Vec<f64>),
}

/// The speed channel's level: its mean weighted by the square of the
/// speed (the GNSS chord's relative noise goes as `1 / v`).
pub fn speed_level(s: &super::ChannelSeries) -> f64 {
    let (mut sw, mut swy) = (0.0, 0.0);
    for (r, x) in s.rows.iter().zip(&s.signals) {
        if r.2.is_finite() && x[0].is_finite() {
            let w = x[0] * x[0];
            sw += w;
            swy += w * r.2;
        }
    }
    if sw > 0.0 {
        swy / sw
    } else {
        0.0
    }
}

/// The bins of a signal: inner edges and the data's range.
struct Bins {
    edges: Vec<f64>,
    lo: f64,
    hi: f64,
}

impl Bins {
    fn of(&self, x: f64) -> usize {
        bin_of(&self.edges, x)
    }
    fn count(&self) -> usize {
        self.edges.len() + 1
    }
    fn bounds(&self, k: usize) -> (f64, f64) {
        let lo = if k == 0 { self.lo } else { self.edges[k - 1] };
        let hi = self.edges.get(k).copied().unwrap_or(self.hi);
        (lo, hi)
    }
}

/// Per-group normal equations of one drive.
#[derive(Clone)]
struct Normals {
    n: DMatrix<f64>,
    b: DVector<f64>,
}

impl Normals {
    fn zeros(p: usize) -> Normals {
        Normals {
            n: DMatrix::zeros(p, p),
            b: DVector::zeros(p),
        }
    }
}

type Row = (usize, f64, f64);

/// Bins on `edges` over the data `all`, with every bin holding at least
/// [`MIN_ROWS`] rows of each drive: a sparse bin loses the edge `merge`
/// names (`None`: the bins cannot be made; nothing is fitted).
fn merged(
    mut edges: Vec<f64>,
    all: &[f64],
    rec: &[Row],
    sim: &[Row],
    signal: impl Fn(&Row) -> f64,
    merge: impl Fn(&Bins, usize) -> Option<usize>,
) -> Option<Bins> {
    let lo = all.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = all.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    loop {
        let bins = Bins {
            edges: edges.clone(),
            lo,
            hi,
        };
        let count =
            |rows: &[Row], k: usize| rows.iter().filter(|r| bins.of(signal(r)) == k).count();
        let Some(k) =
            (0..bins.count()).find(|&k| count(rec, k) < MIN_ROWS || count(sim, k) < MIN_ROWS)
        else {
            return Some(bins);
        };
        let edge = merge(&bins, k)?;
        if edge >= edges.len() {
            return None;
        }
        edges.remove(edge);
    }
}

/// The speed channel's map difference between `recording` and
/// `simulation` over their matched blocks (`pairs`: recording block,
/// simulation block). `None` where the drives have too few rows to fit it.
pub fn speed_map_difference(
    recording: &ChannelSeries,
    simulation: &ChannelSeries,
    pairs: &[(usize, usize)],
    declared: Option<&SpeedMap>,
) -> Option<SpeedMapDifference> {
    let usable = |s: &ChannelSeries| -> Vec<(usize, f64, f64)> {
        s.rows
            .iter()
            .zip(&s.signals)
            .filter(|(r, x)| r.2.is_finite() && x[0].is_finite() && x[1].is_finite())
            .map(|(r, x)| (r.0, x[0], x[1]))
            .collect()
    };
    let rec_rows = usable(recording);
    let sim_rows = usable(simulation);
    if rec_rows.len() < 5 * MIN_ROWS || sim_rows.len() < 5 * MIN_ROWS {
        return None;
    }
    // Speed bins: fixed edges, a sparse bin merged into the one below
    // (the first into the one above).
    let v: Vec<f64> = rec_rows.iter().chain(&sim_rows).map(|r| r.1).collect();
    let speed = merged(
        SPEED_EDGES.to_vec(),
        &v,
        &rec_rows,
        &sim_rows,
        |r| r.1,
        |_, k| Some(k.saturating_sub(1)),
    )?;
    // Acceleration bins: a sparse one merged towards holding the speed.
    let a: Vec<f64> = rec_rows.iter().chain(&sim_rows).map(|r| r.2).collect();
    let accel = merged(
        ACCEL_EDGES.to_vec(),
        &a,
        &rec_rows,
        &sim_rows,
        |r| r.2,
        |bins, k| {
            let (lo, hi) = bins.bounds(k);
            if hi <= 0.0 {
                Some(k)
            } else if lo >= 0.0 {
                k.checked_sub(1)
            } else {
                None
            }
        },
    )?;
    let holding = accel.of(0.0);
    // Columns: every speed bin; every acceleration bin but holding.
    let accel_cols: Vec<usize> = (0..accel.count()).filter(|&k| k != holding).collect();
    let p = speed.count() + accel_cols.len();
    let column_of = |v: f64, a: f64| -> (usize, Option<usize>) {
        let ka = accel.of(a);
        (
            speed.of(v),
            accel_cols
                .iter()
                .position(|&k| k == ka)
                .map(|i| speed.count() + i),
        )
    };
    // Per matched pair: each drive's normal equations over its block.
    // Each drive's level once (the fit is about it).
    let (level_rec, level_sim) = (speed_level(recording), speed_level(simulation));
    let normals = |s: &ChannelSeries, block: usize, level: f64| -> Normals {
        let mut out = Normals::zeros(p);
        for (r, x) in s.rows.iter().zip(&s.signals) {
            if r.0 != block || !(r.2.is_finite() && x[0].is_finite() && x[1].is_finite()) {
                continue;
            }
            let w = x[0] * x[0];
            let (cv, ca) = column_of(x[0], x[1]);
            let cols: Vec<usize> = std::iter::once(cv).chain(ca).collect();
            for &i in &cols {
                out.b[i] += w * (r.2 - level);
                for &j in &cols {
                    out.n[(i, j)] += w;
                }
            }
        }
        out
    };
    let groups: Vec<(Normals, Normals)> = pairs
        .iter()
        .map(|&(br, bs)| {
            (
                normals(recording, br, level_rec),
                normals(simulation, bs, level_sim),
            )
        })
        .filter(|(r, s)| r.n.trace() > 0.0 && s.n.trace() > 0.0)
        .collect();
    if groups.len() < 2 {
        return None;
    }
    let solve = |sum: &Normals| -> Option<DVector<f64>> {
        let ridge = 1e-9 * sum.n.trace().max(1e-300);
        let m = &sum.n + DMatrix::identity(p, p) * ridge;
        m.cholesky().map(|c| c.solve(&sum.b))
    };
    let fit = |leave: Option<usize>| -> Option<(DVector<f64>, DVector<f64>)> {
        let mut a = Normals::zeros(p);
        let mut b = Normals::zeros(p);
        for (g, (r, s)) in groups.iter().enumerate() {
            if Some(g) == leave {
                continue;
            }
            a.n += &r.n;
            a.b += &r.b;
            b.n += &s.n;
            b.b += &s.b;
        }
        Some((solve(&a)?, solve(&b)?))
    };
    let (cr, cs) = fit(None)?;
    let d0 = &cr - &cs;
    // Jackknife over the matched block pairs.
    let n = groups.len() as f64;
    let mut leave_one: Vec<DVector<f64>> = Vec::with_capacity(groups.len());
    for g in 0..groups.len() {
        let (a, b) = fit(Some(g))?;
        leave_one.push(a - b);
    }
    let mean: DVector<f64> = leave_one.iter().fold(DVector::zeros(p), |acc, d| acc + d) / n;
    let var: DVector<f64> = leave_one.iter().fold(DVector::zeros(p), |acc, d| {
        let e = d - &mean;
        acc + e.component_mul(&e)
    }) * ((n - 1.0) / n);
    // The blocks that hold a bin, in either drive: its degrees of freedom.
    let held: Vec<usize> = (0..p)
        .map(|k| {
            groups
                .iter()
                .filter(|(r, s)| r.n[(k, k)] > 0.0 || s.n[(k, k)] > 0.0)
                .count()
        })
        .collect();
    let rows_in = |rows: &[(usize, f64, f64)], col: usize| {
        rows.iter()
            .filter(|r| {
                let (cv, ca) = column_of(r.1, r.2);
                cv == col || ca == Some(col)
            })
            .count()
    };
    let mut bins: Vec<MapBin> = (0..p)
        .map(|k| {
            let (signal, (lo, hi)) = if k < speed.count() {
                ("speed", speed.bounds(k))
            } else {
                ("a_x", accel.bounds(accel_cols[k - speed.count()]))
            };
            let sigma = var[k].sqrt();
            let z = if sigma > 0.0 { d0[k] / sigma } else { 0.0 };
            let dof = held[k].saturating_sub(1);
            MapBin {
                signal: signal.to_string(),
                lo,
                hi,
                rows: [rows_in(&rec_rows, k), rows_in(&sim_rows, k)],
                recording: cr[k],
                simulation: cs[k],
                difference: d0[k],
                blocks: held[k],
                sigma,
                z,
                p_value: if dof == 0 || sigma <= 0.0 {
                    1.0
                } else {
                    f_sf(z * z, 1.0, dof as f64)
                },
                differs: false,
            }
        })
        .collect();
    // Holm over the bins.
    let mut order: Vec<usize> = (0..bins.len()).collect();
    order.sort_by(|&i, &j| bins[i].p_value.total_cmp(&bins[j].p_value));
    for (rank, &i) in order.iter().enumerate() {
        if bins[i].p_value <= FAMILY_ALPHA / (bins.len() - rank) as f64 {
            bins[i].differs = true;
        } else {
            break;
        }
    }
    let holding_rows = [
        rec_rows.iter().filter(|r| accel.of(r.2) == holding).count(),
        sim_rows.iter().filter(|r| accel.of(r.2) == holding).count(),
    ];
    let shrink = |b: &MapBin| b.difference * (1.0 - 1.0 / (b.z * b.z).max(1e-12)).max(0.0);
    let mut speed_values: Vec<f64> = bins[..speed.count()].iter().map(shrink).collect();
    let mut accel_values = vec![0.0; accel.count()];
    for (i, &k) in accel_cols.iter().enumerate() {
        accel_values[k] = shrink(&bins[speed.count() + i]);
    }
    // What the catalogue's forms shape: the part of the map linear in
    // a_x (the longitudinal slip) and in v^2 (the speed growth), fitted
    // over the recording's rows, and each bin's rows' mean a_x and v^2
    // (`SpeedMapDifference::mend` takes out what a moving knob carries).
    const FORMS: usize = 3;
    let form = |r: &Row| [1.0, r.2, r.1 * r.1];
    let mut a_mean = vec![(0.0, 0.0); accel.count()];
    let mut v2_mean = vec![(0.0, 0.0); speed.count()];
    let mut nrm = DMatrix::<f64>::zeros(FORMS, FORMS);
    let mut rhs = DVector::<f64>::zeros(FORMS);
    for r in &rec_rows {
        let w = r.1 * r.1;
        let (kv, ka) = (speed.of(r.1), accel.of(r.2));
        a_mean[ka].0 += w * r.2;
        a_mean[ka].1 += w;
        v2_mean[kv].0 += w * r.1 * r.1;
        v2_mean[kv].1 += w;
        let x = form(r);
        let m = speed_values[kv] + accel_values[ka];
        for i in 0..FORMS {
            rhs[i] += w * x[i] * m;
            for j in 0..FORMS {
                nrm[(i, j)] += w * x[i] * x[j];
            }
        }
    }
    let ridge = DMatrix::identity(FORMS, FORMS) * (1e-12 * nrm.trace().max(1e-300));
    let c = (nrm + ridge)
        .cholesky()
        .map_or(DVector::zeros(FORMS), |ch| ch.solve(&rhs));
    let mean_of = |(s, w): (f64, f64)| if w > 0.0 { s / w } else { 0.0 };
    let a_hold = mean_of(a_mean[holding]);
    // A second of latency is not additive in v and a_x: its map is the
    // weighted least-squares projection of -a_x / v onto the map's bins
    // (over the recording's rows; what the knob's move makes there).
    let mut pn = DMatrix::<f64>::zeros(p, p);
    let mut pb = DVector::<f64>::zeros(p);
    for r in &rec_rows {
        let w = r.1 * r.1;
        let (cv, ca) = column_of(r.1, r.2);
        let cols: Vec<usize> = std::iter::once(cv).chain(ca).collect();
        for &i in &cols {
            pb[i] -= w * r.2 / r.1.max(1e-3);
            for &j in &cols {
                pn[(i, j)] += w;
            }
        }
    }
    let pridge = DMatrix::identity(p, p) * (1e-9 * pn.trace().max(1e-300));
    let lat = (pn + pridge)
        .cholesky()
        .map_or(DVector::zeros(p), |ch| ch.solve(&pb));
    let mut lat_accel = vec![0.0; accel.count()];
    for (i, &k) in accel_cols.iter().enumerate() {
        lat_accel[k] = lat[speed.count() + i];
    }
    let catalogue_parts = CataloguePart {
        accel: (0..accel.count())
            .map(|k| {
                if k == holding {
                    0.0
                } else {
                    c[1] * (mean_of(a_mean[k]) - a_hold)
                }
            })
            .collect(),
        speed: (0..speed.count())
            .map(|k| c[2] * mean_of(v2_mean[k]))
            .collect(),
        latency: (
            lat.rows(0, speed.count()).iter().copied().collect(),
            lat_accel,
        ),
    };
    // The recording-weighted mean out: the circumference holds it.
    let (mut sw, mut swm) = (0.0, 0.0);
    for r in &rec_rows {
        let w = r.1 * r.1;
        sw += w;
        swm += w * (speed_values[speed.of(r.1)] + accel_values[accel.of(r.2)]);
    }
    let mean = if sw > 0.0 { swm / sw } else { 0.0 };
    for x in &mut speed_values {
        *x -= mean;
    }
    let shrunk = SpeedMap {
        speed_m_s: Steps {
            edges: speed.edges.clone(),
            values: speed_values,
        },
        accel_m_s2: Steps {
            edges: accel.edges.clone(),
            values: accel_values,
        },
    };
    Some(SpeedMapDifference {
        bins,
        holding_rows,
        shrunk,
        catalogue_parts,
        declared: declared.cloned(),
        mended: declared.cloned(),
        named_in_channel: Vec::new(),
        unexplained: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::design::Channel;

    /// A speed channel of 12 blocks over speeds 4-28 m/s and accelerations
    /// -2..2 m/s^2, its residual `f(v, a_x)` plus white noise of 0.002.
    fn series(f: impl Fn(f64, f64) -> f64, seed: u64) -> ChannelSeries {
        let mut state = seed;
        let mut uniform = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut rows, mut signals) = (Vec::new(), Vec::new());
        for i in 0..6000 {
            let v = 4.0 + 24.0 * uniform();
            let a = -2.0 + 4.0 * uniform();
            let noise = 0.002 * (uniform() + uniform() + uniform() - 1.5) * 2.0;
            rows.push((i / 500, i as f64 * 0.1, f(v, a) + noise));
            signals.push([v, a]);
        }
        ChannelSeries {
            channel: Channel::Speed,
            rows,
            signals,
        }
    }

    #[test]
    fn a_latency_moving_in_the_mend_takes_its_part_out_of_the_map() {
        // The recording's fixes 0.06 s late: its speed residual -tau a_x / v.
        let tau = 0.06;
        let rec = series(|v, a| -tau * a / v, 1);
        let sim = series(|_, _| 0.0, 2);
        let pairs: Vec<(usize, usize)> = (0..12).map(|b| (b, b)).collect();
        let mut m = speed_map_difference(&rec, &sim, &pairs, None).expect("a map");
        let largest = |s: &SpeedMap| {
            s.speed_m_s
                .values
                .iter()
                .chain(&s.accel_m_s2.values)
                .fold(0.0_f64, |x, y| x.max(y.abs()))
        };
        // The map alone takes the latency's signature (about 0.004-0.03
        // at the acceleration bins' ends).
        m.mend(true, false, false, None);
        let alone = largest(m.mended.as_ref().expect("mended"));
        assert!(alone > 0.004, "{alone}");
        // With the latency's knob moving by the 0.06 s, what is left of it
        // is small.
        m.mend(true, false, false, Some(tau));
        let with_knob = largest(m.mended.as_ref().expect("mended"));
        assert!(with_knob < 0.25 * alone, "{with_knob} against {alone}");
        // A slip's knob moving takes the part linear in a_x only: the
        // latency's a_x / v is partly that, not all of it.
        m.mend(true, true, false, None);
        let with_slip = largest(m.mended.as_ref().expect("mended"));
        assert!(with_slip < alone && with_slip > with_knob, "{with_slip}");
    }
}
