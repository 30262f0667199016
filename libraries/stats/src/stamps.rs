//! The stamps of a regular series: a receiver's epochs and a logger's
//! jitter about them ([`stamp_jitter`]). Used by the readers (the fixes
//! read at their epochs) and the simulator's twin (the jitter copied).

/// The median of the intervals between successive times, s (the upper of
/// the two middle ones for an even count; `None` for fewer than two times).
pub fn median_interval(t: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    crate::upper_median(&mut d)
}

/// Fixes either side of a fix whose stamps' median makes the slow part of
/// the stamp error (an offset, a drifting clock) that the jitter is
/// measured from. 100, not fewer: a logger's arrival delay can come in two
/// modes (comma2k19's about 9 ms apart), and a short median flips between
/// them, moving whole stretches of epochs by the difference. Against
/// comma2k19's own fused pose (a latency and a drifting clock fitted
/// out), the fixes' time error is 10.9 ms RMS at the stamps, 7.0 ms with
/// 25 fixes either side, 6.1 ms with 100 (the test
/// `the_service_reads_jittered_fixes_at_the_epochs_the_calibrator_reads`).
const STAMP_SLOW_HALF_FIXES: usize = 100;

/// A run of fewer fixes between long gaps keeps its stamps: too few to
/// tell a jitter from the slow part.
const MIN_RUN_FIXES: usize = 51;

/// The jitter of a recording's GNSS time stamps: per fix, the receiver's
/// regular epoch (the stamp less its jitter) and the jitter, s.
///
/// A logger that stamps a fix when it arrives puts the arrival's jitter on
/// a position the receiver took on its regular epoch: the intervals read
/// 0.19, 0.20, 0.21 s at 5 Hz (wid-trial02: 3.4 ms RMS), and a speed over
/// one interval is off by the two stamps' difference over the interval
/// (about 1 % here). The epochs are counted off the median interval
/// (gaps as whole intervals); the stamp's departure from its count, less
/// the running median over 201 fixes (an offset, a latency, a clock's
/// drift), is the jitter. A fix whose jitter reaches half an interval is
/// left out (wid-trial02's first two fixes are 0.04 s apart); empty when
/// the fixes are too few or more than a tenth are left out (the stamps
/// are not a regular receiver's).
pub fn stamp_jitter(stamps: &[f64]) -> Vec<(f64, f64)> {
    let Some(dt) = median_interval(stamps) else {
        return Vec::new();
    };
    if stamps.len() < MIN_RUN_FIXES || dt <= 0.0 {
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
    if stamps.len() < MIN_RUN_FIXES {
        return Vec::new();
    }
    // Epochs counted off the interval, then the interval from the count
    // over the whole run ([`grid`]: the median interval of jittered stamps
    // is off by a part of the jitter), and counted again.
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
    let Some((dt, _)) = grid(&first, stamps) else {
        return Vec::new();
    };
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
        let mid = window.len() / 2;
        let (_, median, _) = window.select_nth_unstable_by(mid, f64::total_cmp);
        let jitter = e[i] - *median;
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
    on_epochs_given(stamps, &stamp_jitter(stamps), x, y)
}

/// [`on_epochs`] with the stamps' [`stamp_jitter`] already measured
/// (`jitter`), for a caller that needs the jitter whatever the decision
/// (the twin copies it onto its own stamps).
pub fn on_epochs_given(
    stamps: &[f64],
    jitter: &[(f64, f64)],
    x: &[f64],
    y: &[f64],
) -> Option<OnEpochs> {
    let rms = stamp_jitter_rms(jitter);
    if jitter.is_empty() || rms.is_nan() || rms < MIN_JITTER_S {
        return None;
    }
    let epochs = epochs_of(stamps, jitter);
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

/// Fixes a [`LiveEpochs`] decides on: the newest this many.
pub const LIVE_WINDOW_FIXES: usize = 200;

/// A [`LiveEpochs`] decides first once it holds this many fixes of one run.
pub const LIVE_FIRST_DECISION_FIXES: usize = 100;

/// A [`LiveEpochs`] decides again after this many fixes.
pub const LIVE_DECIDE_EVERY: usize = 20;

/// The receiver's epochs of fixes as they come, for a live reader: the
/// causal counterpart of [`on_epochs`], which needs the whole drive.
///
/// It keeps the newest [`LIVE_WINDOW_FIXES`] fixes of the current run and,
/// every [`LIVE_DECIDE_EVERY`] fixes, takes [`on_epochs`]' decision on
/// them: where the epochs would bring the fixes closer to a smooth motion,
/// the grid through the window's epochs (its interval and phase medians,
/// as the whole drive's) gives each new fix its epoch, the nearest grid
/// time after the previous one; a fix that falls half an interval or more
/// off the grid keeps its stamp. Until the first decision, where the
/// decision says no, after a gap of more than [`MAX_COUNTED_GAP`]
/// intervals and after a stamp that does not increase (a clock reset),
/// fixes keep their stamps; the last two start a new run. The window's
/// epochs keep the stamps' slow part ([`stamp_jitter`]), so a constant
/// latency of the logger is kept: only the jitter about it goes.
#[derive(Debug, Clone, Default)]
pub struct LiveEpochs {
    window: std::collections::VecDeque<(f64, f64, f64)>,
    grid: Option<(f64, f64)>,
    since_decision: usize,
    last_stamp: Option<f64>,
    last_time: Option<f64>,
    moved: u64,
    seen: u64,
    jitter_sq: f64,
}

impl LiveEpochs {
    /// A tracker with no fixes yet.
    pub fn new() -> LiveEpochs {
        LiveEpochs::default()
    }

    /// The time to read a fix stamped `t_s` at position `x_m`, `y_m` (m) at:
    /// its epoch, or its stamp (see [`LiveEpochs`]).
    pub fn push(&mut self, t_s: f64, x_m: f64, y_m: f64) -> f64 {
        self.seen += 1;
        if !(t_s.is_finite() && x_m.is_finite() && y_m.is_finite()) {
            return t_s;
        }
        if let Some(prev) = self.last_stamp {
            let gap_limit = self.grid.map_or(f64::INFINITY, |g| MAX_COUNTED_GAP * g.1);
            let dt = self.typical_interval();
            let too_long =
                t_s - prev > gap_limit || dt.is_some_and(|dt| t_s - prev > MAX_COUNTED_GAP * dt);
            if t_s <= prev || too_long {
                self.new_run();
            }
        }
        self.last_stamp = Some(t_s);
        self.window.push_back((t_s, x_m, y_m));
        if self.window.len() > LIVE_WINDOW_FIXES {
            self.window.pop_front();
        }
        self.since_decision += 1;
        let due = if self.grid.is_none() && self.window.len() == LIVE_FIRST_DECISION_FIXES {
            true
        } else {
            self.window.len() >= LIVE_FIRST_DECISION_FIXES
                && self.since_decision >= LIVE_DECIDE_EVERY
        };
        if due {
            self.decide();
        }
        let time = self.on_grid(t_s).unwrap_or(t_s);
        if time != t_s {
            self.moved += 1;
            self.jitter_sq += (t_s - time) * (t_s - time);
        }
        self.last_time = Some(time);
        time
    }

    /// Fixes read at an epoch so far.
    pub fn moved(&self) -> u64 {
        self.moved
    }

    /// Fixes pushed so far.
    pub fn seen(&self) -> u64 {
        self.seen
    }

    /// The RMS of the stamps' departures from the epochs the moved fixes
    /// were read at, s (0 for none).
    pub fn jitter_rms_s(&self) -> f64 {
        if self.moved == 0 {
            0.0
        } else {
            (self.jitter_sq / self.moved as f64).sqrt()
        }
    }

    /// Whether the newest decision reads fixes at their epochs.
    pub fn on_epochs(&self) -> bool {
        self.grid.is_some()
    }

    fn new_run(&mut self) {
        self.window.clear();
        self.grid = None;
        self.since_decision = 0;
        self.last_time = None;
    }

    /// The median interval of the newest 11 stamps (`None` for fewer).
    fn typical_interval(&self) -> Option<f64> {
        let n = self.window.len();
        if n < 11 {
            return None;
        }
        let t: Vec<f64> = self.window.range(n - 11..).map(|w| w.0).collect();
        median_interval(&t)
    }

    /// [`on_epochs`] on the window; the grid of its newest epoch.
    fn decide(&mut self) {
        self.since_decision = 0;
        let (mut t, mut x, mut y) = (Vec::new(), Vec::new(), Vec::new());
        for w in &self.window {
            t.push(w.0);
            x.push(w.1);
            y.push(w.2);
        }
        let jitter = stamp_jitter(&t);
        self.grid = on_epochs_given(&t, &jitter, &x, &y).and_then(|_| grid_of(&jitter));
    }

    /// The epoch of a fix stamped `t_s` on the current grid, if it has one
    /// within half an interval, after the previous fix's time.
    fn on_grid(&self, t_s: f64) -> Option<f64> {
        let (anchor, dt) = self.grid?;
        let epoch = anchor + ((t_s - anchor) / dt).round() * dt;
        let after_previous = self.last_time.is_none_or(|p| epoch > p + 0.5 * dt);
        ((t_s - epoch).abs() < 0.5 * dt && after_previous).then_some(epoch)
    }
}

/// The grid through epochs (`jitter`'s first members), as its newest epoch
/// and its interval, s ([`grid`] on their counts of intervals).
fn grid_of(jitter: &[(f64, f64)]) -> Option<(f64, f64)> {
    let e: Vec<f64> = jitter.iter().map(|j| j.0).collect();
    let dt0 = median_interval(&e).filter(|d| *d > 0.0)?;
    let first = *e.first()?;
    let n: Vec<f64> = e.iter().map(|t| ((t - first) / dt0).round()).collect();
    let (dt, phase) = grid(&n, &e)?;
    Some((phase + n.last()? * dt, dt))
}

/// The regular grid times `t` are counted on (`n`: each time's count of
/// intervals): its interval, the median of the slopes between times a
/// quarter to three quarters of the series apart, and its phase, the
/// median of the times less their counts of intervals, s. Medians, not
/// least squares or the two end times: a logger's stamps come with
/// clusters a tick early or late (wid-trial02: 56 of 609 fixes 10 ms off)
/// and with end stamps as jittered as any, each of which tilts a line; the
/// slopes' median puts wid-trial02's and wid-trial04's receivers at 0.2 s
/// to 1e-15, where the end stamps said 0.20006 and 0.20015 s (a drift of
/// 18 and 50 ms over the drive). Many distances, not one: a jitter that
/// repeats (a logger's tick beating against the fixes' interval) gives one
/// distance's slopes a bias the others do not share. `None` for fewer than
/// four times or a grid that does not advance.
fn grid(n: &[f64], t: &[f64]) -> Option<(f64, f64)> {
    let len = n.len().min(t.len());
    if len < 4 {
        return None;
    }
    let step = (len / 32).max(1);
    let mut slopes = Vec::new();
    for gap in (len / 4..=3 * len / 4).step_by(step) {
        for i in 0..len.saturating_sub(gap) {
            if n[i + gap] > n[i] {
                slopes.push((t[i + gap] - t[i]) / (n[i + gap] - n[i]));
            }
        }
    }
    let dt = crate::upper_median(&mut slopes).filter(|d| *d > 0.0)?;
    let mut phase: Vec<f64> = (0..len).map(|i| t[i] - n[i] * dt).collect();
    Some((dt, crate::upper_median(&mut phase)?))
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

    /// A 10 Hz receiver on a car at 17 m/s round a 200 m circle, its fixes
    /// with 1 cm of noise and stamped when they arrive (about 6 ms of
    /// jitter); `at_stamps` puts each position where the car was at its
    /// stamp instead.
    fn jittered_drive(at_stamps: bool) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
        let jit = |k: usize| 0.01 * (((k * 7919) % 11) as f64 / 5.0 - 1.0);
        let noise = |k: usize| 0.01 * (((k * 104_729) % 13) as f64 / 6.0 - 1.0);
        let (mut epochs, mut stamps, mut x, mut y) = (vec![], vec![], vec![], vec![]);
        for k in 0..1500 {
            let epoch = 0.05 + k as f64 * 0.1;
            let stamp = epoch + 0.03 + jit(k);
            let at = if at_stamps { stamp } else { epoch };
            let a = 17.0 * at / 200.0;
            epochs.push(epoch + 0.03);
            stamps.push(stamp);
            x.push(200.0 * a.cos() + noise(k));
            y.push(200.0 * a.sin() + noise(k + 7));
        }
        (epochs, stamps, x, y)
    }

    #[test]
    fn live_epochs_follow_the_receiver_as_the_fixes_come() {
        let (epochs, stamps, x, y) = jittered_drive(false);
        let batch = on_epochs(&stamps, &x, &y).expect("the drive's epochs");
        let mut live = LiveEpochs::new();
        let times: Vec<f64> = (0..stamps.len())
            .map(|i| live.push(stamps[i], x[i], y[i]))
            .collect();
        assert!(times.windows(2).all(|w| w[1] > w[0]));
        // Stamps until the first decision, epochs after it: within 2 ms of
        // the receiver's (less the logger's constant latency, kept), within
        // 3 ms of what the whole drive reads.
        assert!(times[..LIVE_FIRST_DECISION_FIXES - 1]
            .iter()
            .zip(&stamps)
            .all(|(t, s)| t == s));
        assert!(
            live.moved() as usize > stamps.len() * 9 / 10,
            "{}",
            live.moved()
        );
        let mean_offset = (LIVE_FIRST_DECISION_FIXES..stamps.len())
            .map(|i| times[i] - epochs[i])
            .sum::<f64>()
            / (stamps.len() - LIVE_FIRST_DECISION_FIXES) as f64;
        for i in LIVE_FIRST_DECISION_FIXES..stamps.len() {
            assert!(
                (times[i] - epochs[i] - mean_offset).abs() < 2e-3,
                "fix {i}: {} against {}",
                times[i],
                epochs[i]
            );
            assert!(
                (times[i] - batch.epochs[i]).abs() < 3e-3,
                "fix {i}: {} against {}",
                times[i],
                batch.epochs[i]
            );
        }
        assert!(mean_offset.abs() < 2e-3, "{mean_offset}");
        assert!((live.jitter_rms_s() - batch.jitter_rms_s).abs() < 1e-3);
        // A clock reset starts again: stamps until the run is long enough.
        let t_reset = live.push(3.0, x[0], y[0]);
        assert_eq!(t_reset, 3.0);
        assert!(!live.on_epochs());
    }

    #[test]
    fn live_epochs_keep_stamps_the_positions_belong_to() {
        // The same jitter, but each position is where the car was at its
        // stamp: the epochs would move the fixes off the motion.
        let (_, stamps, x, y) = jittered_drive(true);
        let mut live = LiveEpochs::new();
        for i in 0..stamps.len() {
            assert_eq!(live.push(stamps[i], x[i], y[i]), stamps[i]);
        }
        assert_eq!(live.moved(), 0);
        // Regular stamps: nothing to move.
        let mut live = LiveEpochs::new();
        for k in 0..500 {
            let t = k as f64 * 0.2;
            assert_eq!(live.push(t, t * 10.0, 0.0), t);
        }
        assert_eq!(live.moved(), 0);
    }

    #[test]
    fn live_epochs_start_again_after_a_long_gap() {
        let (_, stamps, x, y) = jittered_drive(false);
        let mut live = LiveEpochs::new();
        for i in 0..600 {
            live.push(stamps[i], x[i], y[i]);
        }
        assert!(live.on_epochs());
        // A minute without fixes: the grid is not carried across it.
        let after = live.push(stamps[600] + 60.0, x[600], y[600]);
        assert_eq!(after, stamps[600] + 60.0);
        assert!(!live.on_epochs());
    }
}
