//! Which effects the drive supports: forward selection on held-out blocks.
//!
//! GNSS errors are correlated in time, so nothing is judged on single
//! samples. The drive is cut into contiguous blocks; a model is fitted on all
//! blocks but one and scored on the one left out, for every block in turn.
//! An effect enters the model when adding it lowers the held-out error of
//! the blocks consistently (a one-sided Wilcoxon signed-rank test of the
//! per-block gains, Bonferroni over the effects still in the race: robust to
//! gains that are large in the few blocks holding the revealing manoeuvre),
//! its coefficient has a plausible sign and size, and no other candidate
//! that passes as well is so collinear with it (variance inflation above
//! [`VIF_AMBIGUOUS`]) that the drive cannot tell the two apart.
//!
//! Everything works on per-block sufficient statistics (X'WX, X'Wy, y'Wy),
//! so a fit is a small solve whatever the drive's length.

use super::design::{Candidate, Design};
use nalgebra::{DMatrix, DVector};

/// Variance inflation above which two effects are reported as ambiguous.
pub const VIF_AMBIGUOUS: f64 = 10.0;

/// Family-wise false-discovery level of one selection step.
pub const ALPHA: f64 = 0.05;

/// Calls `f(block, weight, y, x)` for each row of `d` that counts: a
/// positive weight and a finite y (a non-finite column entry reads as 0).
fn for_each_row(d: &Design, mut f: impl FnMut(usize, f64, f64, &[f64])) {
    let mut x = vec![0.0; d.columns.len()];
    for (r, &(_, _, b)) in d.rows.iter().enumerate() {
        let w = d.w[r];
        if w.is_nan() || w <= 0.0 || !d.y[r].is_finite() {
            continue;
        }
        for (j, col) in d.columns.iter().enumerate() {
            x[j] = if col[r].is_finite() { col[r] } else { 0.0 };
        }
        f(b, w, d.y[r], &x);
    }
}

/// Per-block sufficient statistics over every column.
#[derive(Debug, Clone)]
pub struct BlockStats {
    /// X'WX per block.
    pub xtx: Vec<DMatrix<f64>>,
    /// X'Wy per block.
    pub xty: Vec<DVector<f64>>,
    /// y'Wy per block.
    pub yty: Vec<f64>,
    /// Rows per block.
    pub rows: Vec<usize>,
}

impl BlockStats {
    /// Accumulate the design's rows by block.
    pub fn new(d: &Design) -> BlockStats {
        let p = d.columns.len();
        let mut s = BlockStats {
            xtx: vec![DMatrix::zeros(p, p); d.blocks],
            xty: vec![DVector::zeros(p); d.blocks],
            yty: vec![0.0; d.blocks],
            rows: vec![0; d.blocks],
        };
        for_each_row(d, |b, w, y, x| {
            for i in 0..p {
                if x[i] == 0.0 {
                    continue;
                }
                s.xty[b][i] += w * x[i] * y;
                for j in 0..p {
                    s.xtx[b][(i, j)] += w * x[i] * x[j];
                }
            }
            s.yty[b] += w * y * y;
            s.rows[b] += 1;
        });
        s
    }

    /// The statistics of `d`, a design whose rows, y and weights are those
    /// this was accumulated from and whose columns differ only at
    /// `changed`: those columns' entries are accumulated anew, the rest kept.
    pub fn with_columns_changed(&self, d: &Design, changed: &[usize]) -> BlockStats {
        let p = d.columns.len();
        let mut s = self.clone();
        let mut m = vec![vec![DVector::<f64>::zeros(p); changed.len()]; d.blocks];
        let mut c_y = vec![vec![0.0; changed.len()]; d.blocks];
        for_each_row(d, |b, w, y, x| {
            for (k, &i) in changed.iter().enumerate() {
                if x[i] == 0.0 {
                    continue;
                }
                c_y[b][k] += w * x[i] * y;
                for j in 0..p {
                    m[b][k][j] += w * x[i] * x[j];
                }
            }
        });
        for b in 0..d.blocks.min(s.xtx.len()) {
            for (k, &i) in changed.iter().enumerate() {
                s.xty[b][i] = c_y[b][k];
                for (j, &v) in m[b][k].iter().enumerate() {
                    s.xtx[b][(i, j)] = v;
                    s.xtx[b][(j, i)] = v;
                }
            }
        }
        s
    }

    /// Blocks with rows.
    pub fn used_blocks(&self) -> Vec<usize> {
        (0..self.rows.len()).filter(|&b| self.rows[b] > 0).collect()
    }

    /// Fit the columns `cols` on the blocks for which `keep` is true.
    pub fn fit(&self, cols: &[usize], keep: impl Fn(usize) -> bool) -> Option<DVector<f64>> {
        let k = cols.len();
        let mut a: DMatrix<f64> = DMatrix::zeros(k, k);
        let mut c: DVector<f64> = DVector::zeros(k);
        for b in 0..self.rows.len() {
            if !keep(b) || self.rows[b] == 0 {
                continue;
            }
            for (i, &ci) in cols.iter().enumerate() {
                c[i] += self.xty[b][ci];
                for (j, &cj) in cols.iter().enumerate() {
                    a[(i, j)] += self.xtx[b][(ci, cj)];
                }
            }
        }
        // A whisker of ridge, relative to each column's own scale, keeps a
        // column that is zero on the training blocks from breaking the solve.
        for i in 0..k {
            let d = a[(i, i)];
            a[(i, i)] = d + 1e-9 * d.max(1e-12);
        }
        a.cholesky().map(|ch| ch.solve(&c))
    }

    /// Weighted squared error of `beta` (over `cols`) on block `b`.
    pub fn error(&self, cols: &[usize], beta: &DVector<f64>, b: usize) -> f64 {
        let mut e = self.yty[b];
        for (i, &ci) in cols.iter().enumerate() {
            e -= 2.0 * beta[i] * self.xty[b][ci];
            for (j, &cj) in cols.iter().enumerate() {
                e += beta[i] * beta[j] * self.xtx[b][(ci, cj)];
            }
        }
        e.max(0.0)
    }

    /// Held-out error per used block of the model with columns `cols`.
    pub fn cv_errors(&self, cols: &[usize]) -> Vec<f64> {
        self.used_blocks()
            .into_iter()
            .map(|b| match self.fit(cols, |x| x != b) {
                Some(beta) => self.error(cols, &beta, b),
                None => self.yty[b],
            })
            .collect()
    }

    /// Coefficients on all blocks, and their delete-one-block jackknife sigmas.
    pub fn fit_with_sigmas(&self, cols: &[usize]) -> Option<(DVector<f64>, DVector<f64>)> {
        let full = self.fit(cols, |_| true)?;
        let used = self.used_blocks();
        let n = used.len() as f64;
        let reps: Vec<DVector<f64>> = used
            .iter()
            .filter_map(|&b| self.fit(cols, |x| x != b))
            .collect();
        if reps.len() < 3 {
            return Some((
                full.clone(),
                DVector::from_element(cols.len(), f64::INFINITY),
            ));
        }
        let mean = reps.iter().fold(DVector::zeros(cols.len()), |a, r| a + r) / reps.len() as f64;
        let var = reps.iter().fold(DVector::zeros(cols.len()), |a, r| {
            let d = r - &mean;
            a + d.component_mul(&d)
        }) * ((n - 1.0) / n);
        Some((full, var.map(f64::sqrt)))
    }

    /// The statistics of the drive as they would be with `delta` times
    /// column `c` added to every residual: how a drive would look had it
    /// more (or less) of one effect. Exact for the linear model, cheap (no
    /// rows are touched).
    pub fn shifted(&self, c: usize, delta: f64) -> BlockStats {
        let mut s = self.clone();
        for b in 0..s.rows.len() {
            let xc = self.xtx[b].column(c).clone_owned();
            s.yty[b] += 2.0 * delta * self.xty[b][c] + delta * delta * self.xtx[b][(c, c)];
            s.yty[b] = s.yty[b].max(0.0);
            s.xty[b] += xc * delta;
        }
        s
    }

    /// Variance inflation of the columns of `a` given those of `b` and the
    /// base columns: 1 / (1 - R^2) of the worst column of `a` regressed on
    /// the others, all blocks pooled.
    pub fn vif(&self, base: &[usize], a: &[usize], b: &[usize]) -> f64 {
        let mut pooled_x: DMatrix<f64> = DMatrix::zeros(self.xtx[0].nrows(), self.xtx[0].ncols());
        for m in &self.xtx {
            pooled_x += m;
        }
        let resid = |target: usize, on: &[usize]| -> f64 {
            // Residual sum of squares of column `target` on columns `on`.
            let k = on.len();
            let tt = pooled_x[(target, target)];
            if k == 0 {
                return tt;
            }
            let mut g: DMatrix<f64> = DMatrix::zeros(k, k);
            let mut h: DVector<f64> = DVector::zeros(k);
            for (i, &ci) in on.iter().enumerate() {
                h[i] = pooled_x[(ci, target)];
                for (j, &cj) in on.iter().enumerate() {
                    g[(i, j)] = pooled_x[(ci, cj)];
                }
                g[(i, i)] += 1e-12 * g[(i, i)].max(1e-300);
            }
            match g.cholesky() {
                Some(ch) => {
                    let beta = ch.solve(&h);
                    (tt - beta.dot(&h)).max(0.0)
                }
                None => tt,
            }
        };
        let mut worst: f64 = 1.0;
        for &ca in a {
            let on_base = resid(ca, base);
            let mut others: Vec<usize> = base.to_vec();
            others.extend_from_slice(b);
            let on_all = resid(ca, &others);
            if on_base > 0.0 {
                let r2 = 1.0 - on_all / on_base;
                worst = worst.max(1.0 / (1.0 - r2).max(1e-12));
            }
        }
        worst
    }
}

/// The one-sided test of a held-out gain: per-block gains, their mean, its
/// t statistic, and the fraction of blocks that gained.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gain {
    /// Mean gain per block (weighted squared error).
    pub mean: f64,
    /// t statistic of the mean over blocks.
    pub t: f64,
    /// Relative gain of the total held-out error.
    pub relative: f64,
    /// Wilcoxon signed-rank statistic of the per-block gains, as a standard
    /// normal z (robust to gains that differ from block to block in size:
    /// the blocks that hold the revealing manoeuvre gain most).
    pub z: f64,
}

impl Gain {
    /// The held-out test of the selection: a positive mean gain and a
    /// signed-rank z above `z_crit`.
    pub fn passes(&self, z_crit: f64) -> bool {
        self.mean > 0.0 && self.z > z_crit
    }
}

/// Gains of `with` over `without` (per-block held-out errors).
pub fn gain(without: &[f64], with: &[f64]) -> Gain {
    let d: Vec<f64> = without.iter().zip(with).map(|(a, b)| a - b).collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n.max(1.0);
    let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    let t = if var > 0.0 {
        mean / (var / n).sqrt()
    } else if mean > 0.0 {
        f64::INFINITY
    } else {
        0.0
    };
    let total: f64 = without.iter().sum();
    Gain {
        mean,
        t,
        relative: if total > 0.0 { mean * n / total } else { 0.0 },
        z: signed_rank_z(&d),
    }
}

/// Wilcoxon signed-rank test of "the gains are centred above zero", as a
/// standard normal z (ties share ranks; zero gains are left out).
pub fn signed_rank_z(d: &[f64]) -> f64 {
    let mut v: Vec<f64> = d
        .iter()
        .copied()
        .filter(|x| *x != 0.0 && x.is_finite())
        .collect();
    let n = v.len() as f64;
    if n < 1.0 {
        return 0.0;
    }
    v.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
    let mut w_plus = 0.0;
    let mut i = 0;
    while i < v.len() {
        let mut j = i;
        while j + 1 < v.len() && v[j + 1].abs() == v[i].abs() {
            j += 1;
        }
        let rank = 0.5 * ((i + 1) + (j + 1)) as f64;
        for x in &v[i..=j] {
            if *x > 0.0 {
                w_plus += rank;
            }
        }
        i = j + 1;
    }
    let mean = n * (n + 1.0) / 4.0;
    let sd = (n * (n + 1.0) * (2.0 * n + 1.0) / 24.0).sqrt();
    (w_plus - mean) / sd
}

/// Whether adding `cand` to `base` passes the held-out test: a positive
/// mean gain and a signed-rank z above `z_crit`.
pub fn passes(stats: &BlockStats, base: &[usize], cand: &[usize], z_crit: f64) -> bool {
    let mut cols = base.to_vec();
    cols.extend_from_slice(cand);
    gain(&stats.cv_errors(base), &stats.cv_errors(&cols)).passes(z_crit)
}

/// The smallest size of an effect this drive would show: the residual is
/// cleared of what the candidate explains (its coefficient on column `main`,
/// fitted on all blocks with `base`), then `size` times its column is put
/// back, and the held-out test is run as in the selection, for sizes of
/// `typical` times 1/8 up to 64 (then halved down to within 10 %). `None`
/// when not even 64 times the typical size would pass: the drive lacks the
/// manoeuvre. Uses the drive's own noise and manoeuvres, nothing else.
pub fn detectable_size(
    stats: &BlockStats,
    base: &[usize],
    cand: &[usize],
    main: usize,
    typical: f64,
    z_crit: f64,
) -> Option<f64> {
    let mut cols = base.to_vec();
    cols.extend_from_slice(cand);
    let j = cols.iter().position(|&c| c == main)?;
    let fitted = stats.fit(&cols, |_| true)?[j];
    let ok = |size: f64| passes(&stats.shifted(main, size - fitted), base, cand, z_crit);
    let mut lo = 0.0;
    let mut hi = None;
    let mut m = typical / 8.0;
    while m <= 64.0 * typical.abs() + f64::EPSILON {
        if ok(m) {
            hi = Some(m);
            break;
        }
        lo = m;
        m *= 2.0;
    }
    let mut hi = hi?;
    while hi - lo > 0.1 * hi {
        let mid = 0.5 * (lo + hi);
        if ok(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(hi)
}

/// The columns of a set of candidates.
pub fn columns_of(cands: &[&Candidate]) -> Vec<usize> {
    cands
        .iter()
        .flat_map(|c| c.columns.iter().copied())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signed_ranks_see_a_gain_of_every_block_whatever_its_size() {
        let d = [
            665.0, 650.0, 2358.0, 401.0, 378.0, 2952.0, 316.0, 143.0, 15.0, 244.0, 181.0, 619.0,
        ];
        assert!((signed_rank_z(&d) - 39.0 / 162.5f64.sqrt()).abs() < 1e-12);
        let mixed = [1.0, -2.0, 3.0, -4.0, 5.0, -6.0];
        assert!(signed_rank_z(&mixed).abs() < 1.0);
    }

    #[test]
    fn a_gain_that_every_block_shares_is_significant() {
        let g = gain(&[2.0, 2.1, 1.9, 2.0], &[1.0, 1.1, 0.95, 1.05]);
        assert!(g.t > 10.0 && (g.relative - 0.4875).abs() < 1e-9);
        let g = gain(&[1.0, 1.0, 1.0, 1.0], &[0.5, 1.5, 0.9, 1.1]);
        assert!(g.t.abs() < 1.0);
    }

    /// A small design: `blocks` blocks of `per` rows, three columns (a
    /// constant, a ramp, a sine), weights that vary, and the data
    /// `y = 0.5 + 2 x1 - x2` plus a deterministic wobble.
    fn design(blocks: usize, per: usize) -> Design {
        let n = blocks * per;
        let col = |f: &dyn Fn(usize) -> f64| (0..n).map(f).collect::<Vec<f64>>();
        let c0 = col(&|_| 1.0);
        let c1 = col(&|i| i as f64 / n as f64);
        let c2 = col(&|i| (i as f64 * 0.7).sin());
        let y = col(&|i| 0.5 + 2.0 * c1[i] - c2[i] + 0.05 * (i as f64 * 2.3).cos());
        Design {
            rows: (0..n)
                .map(|i| (crate::diagnose::design::Channel::Speed, i, i / per))
                .collect(),
            y,
            w: col(&|i| 1.0 + (i % 3) as f64),
            columns: vec![c0, c1, c2],
            column_names: vec!["c0".into(), "c1".into(), "c2".into()],
            nuisance: vec![0],
            candidates: Vec::new(),
            untestable: Vec::new(),
            blocks,
            block_s: 10.0,
            channel_sigma: Vec::new(),
            whitening: Vec::new(),
        }
    }

    /// Weighted least squares of `y` on `cols` over the rows `keep` takes,
    /// written out.
    fn wls(d: &Design, cols: &[usize], keep: impl Fn(usize) -> bool) -> DVector<f64> {
        let rows: Vec<usize> = (0..d.y.len()).filter(|&r| keep(d.rows[r].2)).collect();
        let x = DMatrix::from_fn(rows.len(), cols.len(), |i, j| {
            d.columns[cols[j]][rows[i]] * d.w[rows[i]].sqrt()
        });
        let y = DVector::from_fn(rows.len(), |i, _| d.y[rows[i]] * d.w[rows[i]].sqrt());
        (x.transpose() * &x)
            .cholesky()
            .expect("full rank")
            .solve(&(x.transpose() * y))
    }

    #[test]
    fn statistics_updated_at_changed_columns_equal_those_accumulated_anew() {
        let d = design(5, 30);
        let s = BlockStats::new(&d);
        let mut d2 = d.clone();
        d2.columns[1] = d.columns[1].iter().map(|v| 3.0 * v * v - 0.2).collect();
        let fresh = BlockStats::new(&d2);
        let updated = s.with_columns_changed(&d2, &[1]);
        assert_ne!(fresh.xtx, s.xtx);
        for b in 0..5 {
            assert!((&fresh.xtx[b] - &updated.xtx[b]).amax() < 1e-9, "block {b}");
            assert!((&fresh.xty[b] - &updated.xty[b]).amax() < 1e-9, "block {b}");
            assert_eq!(fresh.yty[b], updated.yty[b]);
            assert_eq!(fresh.rows[b], updated.rows[b]);
        }
    }

    #[test]
    fn the_block_sums_give_the_weighted_least_squares_and_its_held_out_errors() {
        let d = design(6, 40);
        let s = BlockStats::new(&d);
        assert_eq!(s.used_blocks(), (0..6).collect::<Vec<_>>());
        let cols = [0, 1, 2];
        let beta = s.fit(&cols, |_| true).expect("fit");
        let direct = wls(&d, &cols, |_| true);
        assert!((beta - &direct).amax() < 1e-6, "{direct}");
        assert!((direct[1] - 2.0).abs() < 0.05 && (direct[2] + 1.0).abs() < 0.05);
        // The held-out error of block 2: fitted on the others, the weighted
        // squared residual on block 2.
        let held = wls(&d, &cols, |b| b != 2);
        let e2: f64 = (0..d.y.len())
            .filter(|&r| d.rows[r].2 == 2)
            .map(|r| {
                let m: f64 = cols.iter().map(|&c| held[c] * d.columns[c][r]).sum();
                d.w[r] * (d.y[r] - m).powi(2)
            })
            .sum();
        let cv = s.cv_errors(&cols);
        assert!((cv[2] - e2).abs() < 1e-6 * e2.max(1e-12), "{} {e2}", cv[2]);
    }

    #[test]
    fn a_shifted_drive_is_the_drive_with_more_of_a_column() {
        let d = design(5, 30);
        let delta = 0.8;
        let mut more = d.clone();
        for (r, y) in more.y.iter_mut().enumerate() {
            *y += delta * d.columns[2][r];
        }
        let (a, b) = (
            BlockStats::new(&d).shifted(2, delta),
            BlockStats::new(&more),
        );
        for k in 0..5 {
            assert!((a.yty[k] - b.yty[k]).abs() < 1e-9 * b.yty[k].max(1.0));
            assert!((&a.xty[k] - &b.xty[k]).amax() < 1e-9);
        }
        let fit = b.fit(&[0, 1, 2], |_| true).expect("fit");
        assert!((fit[2] - (-1.0 + delta)).abs() < 0.05, "{fit}");
    }

    #[test]
    fn collinear_columns_inflate_the_variance_and_orthogonal_ones_do_not() {
        let mut d = design(4, 50);
        // Column 3: a near copy of column 1.
        let copy: Vec<f64> = d.columns[1]
            .iter()
            .enumerate()
            .map(|(i, v)| v + 1e-3 * (i as f64).sin())
            .collect();
        d.columns.push(copy);
        d.column_names.push("c3".into());
        let s = BlockStats::new(&d);
        assert!(s.vif(&[0], &[1], &[3]) > 1e3);
        // The sine against the ramp: nearly orthogonal.
        assert!(s.vif(&[0], &[2], &[1]) < 1.1);
    }

    #[test]
    fn the_block_jackknife_sigma_shrinks_with_more_blocks() {
        let few = BlockStats::new(&design(4, 60));
        let many = BlockStats::new(&design(12, 20));
        let (b1, s1) = few.fit_with_sigmas(&[0, 1, 2]).expect("fit");
        let (b2, s2) = many.fit_with_sigmas(&[0, 1, 2]).expect("fit");
        assert!((b1[1] - b2[1]).abs() < 0.05);
        assert!(s1
            .iter()
            .chain(s2.iter())
            .all(|v| v.is_finite() && *v > 0.0));
        // With fewer than three blocks there is no jackknife.
        let (_, s0) = BlockStats::new(&design(2, 60))
            .fit_with_sigmas(&[0, 1, 2])
            .expect("fit");
        assert!(s0.iter().all(|v| v.is_infinite()));
    }

    #[test]
    fn correlation_and_interpolation_at_their_edges() {
        use crate::diagnose::epochs::{correlation, interp};
        let line: Vec<(f64, f64)> = (0..10).map(|i| (i as f64, 3.0 * i as f64 + 1.0)).collect();
        assert!((correlation(&line) - 1.0).abs() < 1e-12);
        let anti: Vec<(f64, f64)> = line.iter().map(|(x, y)| (*x, -y)).collect();
        assert!((correlation(&anti) + 1.0).abs() < 1e-12);
        assert_eq!(correlation(&[(1.0, 2.0), (2.0, 3.0)]), 0.0);
        assert_eq!(correlation(&[(1.0, 2.0), (1.0, 3.0), (1.0, 4.0)]), 0.0);
        let (ts, vs) = ([0.0, 1.0, 3.0], [0.0, 10.0, 30.0]);
        assert_eq!(interp(&ts, &vs, 2.0), Some(20.0));
        assert_eq!(interp(&ts, &vs, 0.0), Some(0.0));
        assert_eq!(interp(&ts, &vs, 3.0), Some(30.0));
        assert_eq!(interp(&ts, &vs, 3.5), None);
        assert_eq!(interp(&[], &[], 0.0), None);
    }
}
