//! The stamps of a regular series: a receiver's epochs and a logger's
//! jitter about them ([`stamp_jitter`]). Used by the readers (the fixes
//! read at their epochs) and the simulator's twin (the jitter copied).

/// The median of the positive intervals between successive times, s.
fn median_interval(t: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    crate::upper_median(&mut d)
}

/// Fixes either side of a fix whose stamps' median makes the slow part of
/// the stamp error (an offset, a drifting clock) that the jitter is
/// measured from.
const STAMP_SLOW_HALF_FIXES: usize = 25;

/// The jitter of a recording's GNSS time stamps: per fix, the receiver's
/// regular epoch (the stamp less its jitter) and the jitter, s.
///
/// A logger that stamps a fix when it arrives puts the arrival's jitter on
/// a position the receiver took on its regular epoch: the intervals read
/// 0.19, 0.20, 0.21 s at 5 Hz (wid-trial02: 3.4 ms RMS), and a speed over
/// one interval is off by the two stamps' difference over the interval
/// (about 1 % here). The epochs are counted off the median interval
/// (gaps as whole intervals); the stamp's departure from its count, less
/// the running median over 51 fixes (an offset, a latency, a clock's
/// drift), is the jitter. A fix whose jitter reaches half an interval is
/// left out (wid-trial02's first two fixes are 0.04 s apart); empty when
/// the fixes are too few or more than a tenth are left out (the stamps
/// are not a regular receiver's).
pub fn stamp_jitter(stamps: &[f64]) -> Vec<(f64, f64)> {
    let Some(dt) = median_interval(stamps) else {
        return Vec::new();
    };
    if stamps.len() < 2 * STAMP_SLOW_HALF_FIXES + 1 || dt <= 0.0 {
        return Vec::new();
    }
    // Runs between long gaps, each on its own grid.
    let mut out = Vec::with_capacity(stamps.len());
    let mut start = 0;
    for i in 1..=stamps.len() {
        if i == stamps.len() || stamps[i] - stamps[i - 1] > MAX_COUNTED_GAP * dt {
            out.extend(run_jitter(&stamps[start..i], dt));
            start = i;
        }
    }
    // Stamps mostly off a regular grid are not a receiver's jitter.
    if out.len() * 10 < stamps.len() * 9 {
        return Vec::new();
    }
    out
}

/// A gap of more than this many intervals ends a run of counted epochs:
/// over a long gap the count of intervals loses the grid (a logger paused
/// for 600 s comes back a fraction of an interval off it, and the fixes
/// whose running median spans the gap would read that fraction as
/// jitter), so each run is counted on its own.
pub const MAX_COUNTED_GAP: f64 = 10.0;

/// [`stamp_jitter`] of one run without long gaps (`dt`: the drive's
/// median interval); empty for a run too short for the running median.
fn run_jitter(stamps: &[f64], dt: f64) -> Vec<(f64, f64)> {
    if stamps.len() < 2 * STAMP_SLOW_HALF_FIXES + 1 {
        return Vec::new();
    }
    // Epochs counted off the interval, then the interval from the count
    // over the whole run (the median interval of jittered stamps is off
    // by a part of the jitter), and counted again.
    let count = |dt: f64| -> Vec<f64> {
        let mut n = vec![0.0];
        for w in stamps.windows(2) {
            let last = n[n.len() - 1];
            n.push(last + ((w[1] - w[0]) / dt).round());
        }
        n
    };
    let first = count(dt);
    let total = first[first.len() - 1];
    if total <= 0.0 {
        return Vec::new();
    }
    let dt = (stamps[stamps.len() - 1] - stamps[0]) / total;
    let n = count(dt);
    let e: Vec<f64> = stamps
        .iter()
        .zip(&n)
        .map(|(s, n)| s - stamps[0] - n * dt)
        .collect();
    let k = STAMP_SLOW_HALF_FIXES;
    let mut out = Vec::with_capacity(stamps.len());
    for i in 0..e.len() {
        let mut window: Vec<f64> = e[i.saturating_sub(k)..(i + k + 1).min(e.len())].to_vec();
        window.sort_by(f64::total_cmp);
        let jitter = e[i] - window[window.len() / 2];
        // A fix off the receiver's epochs is left out, and so are both
        // fixes that count to one epoch (wid-trial02's first two, 0.04 s
        // apart): which of the two is the epoch's cannot be told, and
        // moving either puts two fixes milliseconds apart.
        let shared = (i > 0 && n[i] == n[i - 1]) || (i + 1 < n.len() && n[i] == n[i + 1]);
        if jitter.abs() < 0.5 * dt && !shared {
            out.push((stamps[i] - jitter, jitter));
        }
    }
    out
}

/// The RMS of a [`stamp_jitter`], s (0 for none).
pub fn stamp_jitter_rms(jitter: &[(f64, f64)]) -> f64 {
    if jitter.is_empty() {
        return 0.0;
    }
    (jitter.iter().map(|j| j.1 * j.1).sum::<f64>() / jitter.len() as f64).sqrt()
}

/// Each stamp's receiver epoch from its [`stamp_jitter`] (`jitter`, in
/// stamp order): the stamp less its jitter, or the stamp itself for a fix
/// the jitter left out.
pub fn epochs_of(stamps: &[f64], jitter: &[(f64, f64)]) -> Vec<f64> {
    let mut epochs = stamps.to_vec();
    let mut k = 0;
    for (i, s) in stamps.iter().enumerate() {
        while k < jitter.len() && jitter[k].0 + jitter[k].1 < s - 1e-9 {
            k += 1;
        }
        if k < jitter.len() && (jitter[k].0 + jitter[k].1 - s).abs() <= 1e-9 {
            epochs[i] = jitter[k].0;
            k += 1;
        }
    }
    epochs
}

/// Below this RMS jitter, s, the stamps are left as they are (3 mm at
/// 30 m/s: below any receiver's noise).
pub const MIN_JITTER_S: f64 = 1e-4;

/// The epochs must take at least this share of the fixes' scatter about
/// their neighbours' line (its square: a fifth of the variance) for the
/// stamps to be moved: a jitter lost in the fixes' own noise changes
/// nothing the models could use, and every detector downstream would
/// re-measure the noise from a few per cent of difference (wid-trial04:
/// 0.114 m at the stamps, 0.110 m at the epochs, kept).
pub const MIN_SCATTER_GAIN: f64 = 0.1;

/// The RMS distance of each fix from the line between its neighbours at
/// times `t` (a fix with a neighbour more than 1.5 intervals away is left
/// out), m, and how many fixes it was taken over.
fn scatter(t: &[f64], x: &[f64], y: &[f64], dt: f64) -> (f64, usize) {
    let (mut sum, mut n) = (0.0, 0usize);
    for i in 1..t.len().saturating_sub(1) {
        let (a, b) = (t[i] - t[i - 1], t[i + 1] - t[i]);
        if a <= 0.0 || b <= 0.0 || a > 1.5 * dt || b > 1.5 * dt {
            continue;
        }
        let w = a / (a + b);
        let ex = x[i] - (x[i - 1] + w * (x[i + 1] - x[i - 1]));
        let ey = y[i] - (y[i - 1] + w * (y[i + 1] - y[i - 1]));
        sum += ex * ex + ey * ey;
        n += 1;
    }
    if n == 0 {
        (f64::NAN, 0)
    } else {
        ((sum / n as f64).sqrt(), n)
    }
}

/// Fixes read at the receiver's epochs ([`on_epochs`]).
#[derive(Debug, Clone, PartialEq)]
pub struct OnEpochs {
    /// Each fix's epoch (its stamp where the jitter left it out), s.
    pub epochs: Vec<f64>,
    /// The stamps' jitter about the epochs, RMS, s.
    pub jitter_rms_s: f64,
    /// The fixes' RMS distance from their neighbours' line at the stamps, m.
    pub scatter_stamps_m: f64,
    /// The same at the epochs, m.
    pub scatter_epochs_m: f64,
}

/// Whether fixes at `x`, `y` (m) stamped at `stamps` are to be read at the
/// receiver's epochs, and the epochs: `None` when the stamps are regular
/// ([`MIN_JITTER_S`]), too few, not a receiver's, or when the epochs do not
/// bring the fixes closer to a smooth motion than the stamps by
/// [`MIN_SCATTER_GAIN`]. One decision for the readers and the twin, so
/// that a recording and its twin are read alike.
pub fn on_epochs(stamps: &[f64], x: &[f64], y: &[f64]) -> Option<OnEpochs> {
    let jitter = stamp_jitter(stamps);
    let rms = stamp_jitter_rms(&jitter);
    if jitter.is_empty() || rms.is_nan() || rms < MIN_JITTER_S {
        return None;
    }
    let epochs = epochs_of(stamps, &jitter);
    if !epochs.windows(2).all(|w| w[1] > w[0]) {
        return None;
    }
    let mut d: Vec<f64> = epochs.windows(2).map(|w| w[1] - w[0]).collect();
    let dt = crate::upper_median(&mut d)?;
    let (at_stamps, n) = scatter(stamps, x, y, dt);
    let (at_epochs, _) = scatter(&epochs, x, y, dt);
    let gained = at_epochs <= (1.0 - MIN_SCATTER_GAIN) * at_stamps;
    if n < 30 || !gained {
        return None;
    }
    Some(OnEpochs {
        epochs,
        jitter_rms_s: rms,
        scatter_stamps_m: at_stamps,
        scatter_epochs_m: at_epochs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A logger's jitter on a 5 Hz receiver whose clock runs 0.3 s late
    /// and drifts: the jitter comes back, the offset and drift do not.
    #[test]
    fn the_stamps_jitter_is_measured_without_offset_or_drift() {
        let jit = |k: usize| 0.01 * (((k * 7919) % 11) as f64 / 5.0 - 1.0);
        let stamps: Vec<f64> = (0..600)
            .filter(|k| !(200..215).contains(k))
            .map(|k| 0.3 + k as f64 * 0.2 * (1.0 + 2e-5) + jit(k))
            .collect();
        let j = stamp_jitter(&stamps);
        assert_eq!(j.len(), stamps.len());
        // An odd fix on the first fix's epoch: both are left out (which is
        // the epoch's cannot be told), the rest kept.
        let mut odd = stamps.clone();
        odd.insert(1, stamps[0] + 0.04);
        assert_eq!(stamp_jitter(&odd).len(), stamps.len() - 1);
        let (mut worst, mut sum) = (0.0_f64, 0.0);
        for (i, k) in (0..600).filter(|k| !(200..215).contains(k)).enumerate() {
            worst = worst.max((j[i].1 - jit(k)).abs());
            sum += j[i].1;
        }
        assert!(worst < 3e-3, "{worst}");
        assert!((sum / j.len() as f64).abs() < 1e-3);
        assert!(
            (stamp_jitter_rms(&j) - 0.0063).abs() < 1.5e-3,
            "{}",
            stamp_jitter_rms(&j)
        );
        // Each stamp's epoch, the two on one epoch keeping their stamps.
        let e = epochs_of(&odd, &stamp_jitter(&odd));
        assert_eq!((e[0], e[1]), (odd[0], odd[1]));
        for (i, k) in (0..600)
            .filter(|k| !(200..215).contains(k))
            .enumerate()
            .skip(1)
        {
            let want = 0.3 + k as f64 * 0.2 * (1.0 + 2e-5);
            assert!(
                (e[i + 1] - want).abs() < 3e-3,
                "{} against {want}",
                e[i + 1]
            );
        }
        // A logger paused for 600 s comes back 0.37 intervals off the
        // grid: each side is counted on its own, no fix reads the fraction.
        let paused: Vec<f64> = stamps
            .iter()
            .map(|t| if *t > 60.0 { t + 600.074 } else { *t })
            .collect();
        let jp = stamp_jitter(&paused);
        assert_eq!(jp.len(), paused.len());
        let worst = jp
            .iter()
            .zip((0..600).filter(|k| !(200..215).contains(k)))
            .map(|(j, k)| (j.1 - jit(k)).abs())
            .fold(0.0_f64, f64::max);
        assert!(worst < 3e-3, "{worst}");
        // Regular stamps have no jitter; irregular ones are not a receiver's.
        let regular: Vec<f64> = (0..300).map(|k| k as f64 * 0.1).collect();
        assert!(stamp_jitter(&regular).iter().all(|j| j.1.abs() < 1e-9));
        let wild: Vec<f64> = (0..300)
            .map(|k| (k as f64 * 0.1) + 0.06 * ((k % 2) as f64))
            .collect();
        assert!(stamp_jitter(&wild).is_empty());
    }
}
