//! Clock offsets of the streams against the wheels' clock: one home for
//! stream-offset estimation.
//!
//! Wheel speeds, IMU and GNSS are often logged by different devices whose
//! clocks disagree by half a second or more. Every stream's offset is
//! estimated against the wheels (the calibration's time base) over
//! +-[`CLOCK_SEARCH_S`] by [`fit_lag`]: least squares of the stream's signal
//! `y(t)` against a gain (and optionally an intercept) times a wheel-derived
//! signal `x(t - lag)`, first on a coarse lag grid over the whole range, then
//! on a fine grid near the coarse minimum with a parabola through the
//! minimum. Its sigma is the larger of the curvature bound and a block
//! jackknife (which sees correlated residuals).
//!
//! - GNSS: the speed of the smoothed GNSS track against the wheel speed, and
//!   where the speed hardly changes the GNSS course rate against the wheels'
//!   yaw rate `(v_r - v_l) / B` (see `reference`).
//! - IMU: [`imu_offset`], the yaw rate against the wheels' yaw rate, and
//!   where the drive has too few turns the longitudinal acceleration against
//!   the wheel speed's derivative (when the IMU has accelerations).
//!
//! Everything here is pure: arrays in, estimates out.

use serde::{Deserialize, Serialize};

/// Half-width of the offset search, s: offsets up to this size are found;
/// beyond it the estimate is "not determined" and says so.
pub const CLOCK_SEARCH_S: f64 = 3.0;
/// An offset with a larger sigma than this is "not determined", s.
pub const MAX_OFFSET_SIGMA_S: f64 = 0.1;
/// The lagged wheel signal must explain at least this share of the stream
/// signal's variance (the rest is the drive's own noise) for a determined
/// offset.
pub const MIN_EXPLAINED: f64 = 0.5;
/// A fit that does not determine an offset alone is kept as a weak pair
/// (`StreamOffset::weak`) up to this sigma, s.
pub const WEAK_MAX_SIGMA_S: f64 = 3.0 * MAX_OFFSET_SIGMA_S;
/// Coarse grid step, s.
const COARSE_STEP_S: f64 = 0.1;
/// Observations the coarse grid looks at, at most (evenly spread).
const COARSE_SAMPLES: usize = 4000;
/// Fine grid step, s.
const FINE_STEP_S: f64 = 0.01;
/// Fine grid half-width in steps (+-0.5 s).
const FINE_STEPS: i64 = 50;
/// Parabola half-width in fine steps (+-0.15 s).
const PARABOLA_STEPS: usize = 15;
/// Blocks of the jackknife.
const JACKKNIFE_BLOCKS: usize = 8;
/// IMU samples are averaged over bins of this length, s.
const IMU_BIN_S: f64 = 0.1;
/// Half-width of the window of the wheel signals compared with the IMU, s.
const IMU_WHEEL_HALF_WINDOW_S: f64 = 0.1;

/// Whether an offset was determined.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OffsetStatus {
    /// Estimated, with a sigma.
    Determined,
    /// Looked for, not found (the reason says which manoeuvre would find it).
    NotDetermined,
    /// Not looked for (switched off, or no such stream).
    NotChecked,
}

/// The offset of one stream's clock against the wheels'.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StreamOffset {
    /// Determined or not.
    pub status: OffsetStatus,
    /// The stream's time stamps are late by this much relative to the
    /// wheels' (`t_stream = t_wheels + offset`), s.
    pub offset_s: Option<f64>,
    /// Its 1-sigma, s.
    pub sigma_s: Option<f64>,
    /// The signals compared (e.g. "speed", "course rate", "yaw rate").
    pub from: Option<String>,
    /// Whether the stream's time stamps were shifted by it.
    pub applied: bool,
    /// Where the stamps were shifted by another value than `offset_s`, that
    /// value, s: the IMU moved with the GNSS where both show that the
    /// wheels' clock moved (`crate::clocks::imu_follows_gnss`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub applied_s: Option<f64>,
    /// Why not determined / not checked.
    pub reason: Option<String>,
    /// The slow drift of the stream's clock against the wheels'
    /// (`crate::clocks::drift`). When it is applied, `offset_s` is the offset
    /// at [`ClockDrift::ref_t_s`].
    #[serde(default)]
    pub drift: ClockDrift,
    /// When not determined: the best fit that still explains at least
    /// [`MIN_EXPLAINED`] of the variance with a sigma within
    /// [`WEAK_MAX_SIGMA_S`], as (offset, sigma), s. Too uncertain alone, it
    /// is weighted into the joint solution over the pairs of streams
    /// ([`solve_offsets`]), where other pairs may make it determined.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weak: Option<[f64; 2]>,
}

/// One window's offset, for the drift's line fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WindowOffset {
    /// Middle of the window on the wheels' clock, s.
    pub t_s: f64,
    /// The offset found in the window, s.
    pub offset_s: f64,
    /// Its 1-sigma, s.
    pub sigma_s: f64,
}

/// The slow drift of a stream's clock against the wheels': the offset at
/// wheel time `t` is `offset_s + drift_ppm * 1e-6 * (t - ref_t_s)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClockDrift {
    /// Determined (a line through the window offsets) or not, and why.
    pub status: OffsetStatus,
    /// The drift, parts per million (the stream's clock gains this many
    /// microseconds per second against the wheels').
    pub drift_ppm: Option<f64>,
    /// Its 1-sigma (inflated by the line fit's chi-square per degree of
    /// freedom where that exceeds 1), ppm.
    pub sigma_ppm: Option<f64>,
    /// The smallest drift this drive can show: 3 sigma, ppm (from the
    /// measured window sigmas, or from the whole drive's offset sigma when
    /// the windows do not determine it).
    pub detectable_ppm: Option<f64>,
    /// Wheel time the line is taken about (the middle of the wheels' span), s.
    pub ref_t_s: Option<f64>,
    /// Chi-square per degree of freedom of the line fit.
    pub chi2_dof: Option<f64>,
    /// The window offsets the line went through.
    pub windows: Vec<WindowOffset>,
    /// Whether the stream's time stamps were corrected for it (only a
    /// significant drift is: beyond 3 sigma, and moving the offset across
    /// the drive by more than 3 sigma of the offset).
    pub applied: bool,
    /// Why not determined, not significant or not checked.
    pub reason: Option<String>,
}

impl ClockDrift {
    /// Not looked for, because `reason`.
    pub fn not_checked(reason: &str) -> ClockDrift {
        ClockDrift {
            status: OffsetStatus::NotChecked,
            drift_ppm: None,
            sigma_ppm: None,
            detectable_ppm: None,
            ref_t_s: None,
            chi2_dof: None,
            windows: Vec::new(),
            applied: false,
            reason: Some(reason.to_string()),
        }
    }

    /// The drift as a rate (ppm * 1e-6) when it was applied.
    pub fn applied_rate(&self) -> Option<f64> {
        self.drift_ppm
            .filter(|_| self.applied && self.status == OffsetStatus::Determined)
            .map(|p| p * 1e-6)
    }
}

impl std::fmt::Display for ClockDrift {
    /// One line: the drift with its sigma and whether it was applied, or
    /// why it was not determined / not significant / not checked.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match (self.status, self.drift_ppm, self.sigma_ppm) {
            (OffsetStatus::Determined, Some(p), Some(s)) if self.reason.is_none() => write!(
                f,
                "{p:+.0} ppm +- {s:.0} ppm from {} windows{}",
                self.windows.len(),
                if self.applied {
                    ", applied"
                } else {
                    ", not applied"
                }
            ),
            (OffsetStatus::Determined, ..) => {
                write!(f, "{}", self.reason.as_deref().unwrap_or("not significant"))
            }
            (OffsetStatus::NotChecked, ..) => write!(
                f,
                "not checked: {}",
                self.reason.as_deref().unwrap_or("no reason given")
            ),
            _ => write!(
                f,
                "not determined: {}",
                self.reason.as_deref().unwrap_or("no reason given")
            ),
        }
    }
}

impl Default for ClockDrift {
    fn default() -> Self {
        ClockDrift::not_checked("not checked")
    }
}

impl StreamOffset {
    /// Not looked for, because `reason`.
    pub fn not_checked(reason: &str) -> StreamOffset {
        StreamOffset {
            status: OffsetStatus::NotChecked,
            offset_s: None,
            sigma_s: None,
            from: None,
            applied: false,
            applied_s: None,
            reason: Some(reason.to_string()),
            drift: ClockDrift::default(),
            weak: None,
        }
    }

    /// Looked for, not determined, because `reason`.
    pub fn not_determined(reason: String) -> StreamOffset {
        StreamOffset {
            status: OffsetStatus::NotDetermined,
            offset_s: None,
            sigma_s: None,
            from: None,
            applied: false,
            applied_s: None,
            reason: Some(reason),
            drift: ClockDrift::default(),
            weak: None,
        }
    }

    /// Determined from the fit of the signals `from`.
    pub fn determined(fit: &LagFit, from: &str) -> StreamOffset {
        StreamOffset {
            status: OffsetStatus::Determined,
            offset_s: Some(fit.lag_s),
            sigma_s: Some(fit.sigma_s),
            from: Some(from.to_string()),
            applied: false,
            applied_s: None,
            reason: None,
            drift: ClockDrift::default(),
            weak: None,
        }
    }

    /// A determined offset of `o` +- `sigma` s from the signals `from`,
    /// applied or not: what the clock rules' tests start from.
    #[cfg(test)]
    pub(crate) fn for_test(o: f64, sigma: f64, from: &str, applied: bool) -> StreamOffset {
        let mut s = StreamOffset::not_checked("test");
        s.status = OffsetStatus::Determined;
        s.offset_s = Some(o);
        s.sigma_s = Some(sigma);
        s.from = Some(from.to_string());
        s.applied = applied;
        s
    }

    /// The shift taken off the stream's stamps: `applied_s`, else
    /// `offset_s`, where applied; 0 where not.
    pub fn applied_shift_s(&self) -> f64 {
        if !self.applied {
            return 0.0;
        }
        self.applied_s
            .or(self.offset_s)
            .filter(|v| v.is_finite())
            .unwrap_or(0.0)
    }

    /// The offset when it is determined and significant: beyond 3 sigma and
    /// beyond `resolution_s` (e.g. one sample interval of the stream).
    pub fn significant(&self, resolution_s: f64) -> Option<f64> {
        match (self.status, self.offset_s, self.sigma_s) {
            (OffsetStatus::Determined, Some(o), Some(s))
                if o.abs() > 3.0 * s && o.abs() > resolution_s =>
            {
                Some(o)
            }
            _ => None,
        }
    }
}

impl Default for StreamOffset {
    fn default() -> Self {
        StreamOffset::not_checked("not checked")
    }
}

/// The clock offsets of every stream against the wheels.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ClockOffsets {
    /// GNSS against the wheels.
    pub gnss_s: StreamOffset,
    /// IMU against the wheels.
    pub imu_s: StreamOffset,
    /// Every pair of streams compared (each determined with its sigma, or
    /// why not): the measurements [`solve_offsets`] combined into `gnss_s`.
    #[serde(default)]
    pub pairs: Vec<PairOffset>,
}

/// A stream with its own clock: a node of the graph of pairwise offsets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClockStream {
    /// The wheels (the calibration's time base).
    Wheels,
    /// The GNSS fixes.
    Gnss,
    /// The IMU.
    Imu,
}

impl ClockStream {
    /// Lower-case name for messages.
    pub fn name(self) -> &'static str {
        match self {
            ClockStream::Wheels => "wheels",
            ClockStream::Gnss => "gnss",
            ClockStream::Imu => "imu",
        }
    }
}

/// One pairwise measurement: `later`'s stamps are late against `base`'s by
/// `offset.offset_s` (`t_later = t_base + offset`), or not determined.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairOffset {
    /// The stream the offset is measured against.
    pub base: ClockStream,
    /// The stream whose offset it is.
    pub later: ClockStream,
    /// The measurement (its sigma includes the systematic lags of the
    /// signals compared, see [`solve_offsets`]).
    pub offset: StreamOffset,
}

/// A stream's offset against the wheels from [`solve_offsets`].
#[derive(Debug, Clone, PartialEq)]
pub struct JointOffset {
    /// `t_stream = t_wheels + offset_s`, s.
    pub offset_s: f64,
    /// Its 1-sigma (inflated by the loop's chi-square per degree of
    /// freedom where that exceeds 1), s.
    pub sigma_s: f64,
    /// The determined pairs it came from, e.g. "gnss-imu (course rate) +
    /// wheels-imu (yaw rate)".
    pub path: String,
    /// True when it rests on the direct pair with the wheels alone.
    pub direct: bool,
}

/// Chi-square per degree of freedom of a loop of pairs beyond which they
/// contradict each other (3 sigma for one loop): the pairs are then not
/// combined, each stream keeps its direct pair with the wheels.
const LOOP_CHI2_LIMIT: f64 = 9.0;

/// The offset of `stream` against the wheels by weighted least squares over
/// every determined pair of `pairs` (the wheels' offset held at 0): one
/// determined pair closes the chain for the others (wheels-IMU and GNSS-IMU
/// give wheels-GNSS). `Err` says why not: no chain of determined pairs
/// reaches `stream`, or the pairs of a loop contradict each other and the
/// direct pair is not determined.
pub fn solve_offsets(pairs: &[PairOffset], stream: ClockStream) -> Result<JointOffset, String> {
    let edges = offset_edges(pairs);
    let target = node_index(stream);
    if target == 0 {
        return Ok(JointOffset {
            offset_s: 0.0,
            sigma_s: 0.0,
            path: "the time base".to_string(),
            direct: true,
        });
    }
    let reached = reached(&edges);
    if !reached[target] {
        return Err(format!(
            "no chain of determined pairs links the {} to the wheels",
            stream.name()
        ));
    }
    let used: Vec<_> = edges
        .iter()
        .filter(|e| reached[e.0] && reached[e.1])
        .collect();
    // Unknowns: the reached streams other than the wheels.
    let unknowns: Vec<usize> = (1..CLOCK_NODES.len()).filter(|&i| reached[i]).collect();
    let col = |i: usize| unknowns.iter().position(|&u| u == i);
    let n = unknowns.len();
    let (normal, rhs) = normal_equations(&used, &unknowns);
    let cov = normal
        .try_inverse()
        .ok_or_else(|| "the pairs do not determine the offsets".to_string())?;
    let x = &cov * &rhs;
    let value = |i: usize| col(i).map_or(0.0, |c| x[c]);
    let dof = used.len().saturating_sub(n);
    let chi2: f64 = used
        .iter()
        .map(|&&(a, b, o, s, _)| {
            let r = (value(b) - value(a) - o) / s;
            r * r
        })
        .sum();
    let describe = |e: &&Edge<'_>| describe_edge(e);
    let direct = used
        .iter()
        .find(|e| (e.0 == 0 && e.1 == target) || (e.1 == 0 && e.0 == target));
    if dof > 0 && chi2 / dof as f64 > LOOP_CHI2_LIMIT {
        // The loop contradicts itself: no combination, the direct pair alone.
        let why = format!(
            "the pairs {} contradict each other (chi-square {:.1} over {dof} loop(s))",
            used.iter().map(describe).collect::<Vec<_>>().join(", "),
            chi2
        );
        return match direct {
            Some(e) => Ok(JointOffset {
                offset_s: if e.0 == 0 { e.2 } else { -e.2 },
                sigma_s: e.3,
                path: format!("{}; {why}: the direct pair alone", describe(e)),
                direct: true,
            }),
            None => Err(why),
        };
    }
    let inflate = if dof > 0 {
        (chi2 / dof as f64).max(1.0).sqrt()
    } else {
        1.0
    };
    let c = col(target).unwrap_or(0);
    // The pairs the target's offset depends on: d x / d o_e = cov r_e w_e.
    let moves = |e: &&&Edge<'_>| {
        let r = |i: usize| col(i).map_or(0.0, |k| cov[(c, k)]);
        (r(e.1) - r(e.0)).abs() > 1e-9 * cov[(c, c)].abs()
    };
    let from: Vec<_> = used.iter().filter(moves).collect();
    Ok(JointOffset {
        offset_s: x[c],
        sigma_s: cov[(c, c)].max(0.0).sqrt() * inflate,
        path: from
            .iter()
            .map(|e| describe(e))
            .collect::<Vec<_>>()
            .join(" + "),
        direct: from.len() == 1 && direct.is_some(),
    })
}

/// The streams of the joint solution, the time base (the wheels) first.
const CLOCK_NODES: [ClockStream; 3] = [ClockStream::Wheels, ClockStream::Gnss, ClockStream::Imu];

/// A pair as an edge of the joint solution: base and later stream (their
/// [`node_index`]), offset and sigma (s), the pair.
type Edge<'a> = (usize, usize, f64, f64, &'a PairOffset);

/// `s`'s place in [`CLOCK_NODES`].
fn node_index(s: ClockStream) -> usize {
    CLOCK_NODES.iter().position(|n| *n == s).unwrap_or(0)
}

/// The pairs usable in the joint solution: determined, or with a weak fit;
/// a positive sigma, between two different streams.
fn offset_edges(pairs: &[PairOffset]) -> Vec<Edge<'_>> {
    let idx = node_index;
    pairs
        .iter()
        .filter_map(|p| {
            let (o, s) = match (
                p.offset.status,
                p.offset.offset_s,
                p.offset.sigma_s,
                p.offset.weak,
            ) {
                (OffsetStatus::Determined, Some(o), Some(s), _) => (o, s),
                (OffsetStatus::NotDetermined, _, _, Some([o, s])) => (o, s),
                _ => return None,
            };
            (s > 0.0 && idx(p.base) != idx(p.later)).then(|| (idx(p.base), idx(p.later), o, s, p))
        })
        .collect()
}

/// The streams a chain of edges links to the wheels.
fn reached(edges: &[Edge<'_>]) -> [bool; 3] {
    let mut reached = [true, false, false];
    loop {
        let mut grew = false;
        for &(a, b, ..) in edges {
            if reached[a] != reached[b] {
                reached[a] = true;
                reached[b] = true;
                grew = true;
            }
        }
        if !grew {
            return reached;
        }
    }
}

/// The weighted least-squares normal equations of the edges `used`
/// (o = x_b - x_a, weight 1 / s^2) in the `unknowns` (the streams' offsets
/// against the wheels).
fn normal_equations(
    used: &[&Edge<'_>],
    unknowns: &[usize],
) -> (nalgebra::DMatrix<f64>, nalgebra::DVector<f64>) {
    let col = |i: usize| unknowns.iter().position(|&u| u == i);
    let n = unknowns.len();
    let mut normal = nalgebra::DMatrix::<f64>::zeros(n, n);
    let mut rhs = nalgebra::DVector::<f64>::zeros(n);
    for &&(a, b, o, s, _) in used {
        // o = x_b - x_a, weight 1 / s^2.
        let w = 1.0 / (s * s);
        let mut row: Vec<(usize, f64)> = Vec::with_capacity(2);
        if let Some(c) = col(b) {
            row.push((c, 1.0));
        }
        if let Some(c) = col(a) {
            row.push((c, -1.0));
        }
        for &(i, ri) in &row {
            rhs[i] += w * ri * o;
            for &(j, rj) in &row {
                normal[(i, j)] += w * ri * rj;
            }
        }
    }
    (normal, rhs)
}

/// An edge in words: the streams, where its offset came from, and a weak
/// fit's value.
fn describe_edge(e: &Edge<'_>) -> String {
    format!(
        "{}-{} ({}{})",
        e.4.base.name(),
        e.4.later.name(),
        e.4.offset.from.as_deref().unwrap_or("?"),
        if e.4.offset.status == OffsetStatus::Determined {
            String::new()
        } else {
            format!(", weak: {:+.3} +- {:.3} s", e.2, e.3)
        }
    )
}

/// A signal sampled at increasing times, linear between samples.
#[derive(Debug, Clone, Copy)]
pub struct Sampled<'a> {
    /// Times, s, increasing.
    pub t: &'a [f64],
    /// Values (f32 to keep a long drive small).
    pub v: &'a [f32],
}

impl Sampled<'_> {
    /// The value at `t` by a forward `cursor` (calls with increasing `t`);
    /// `None` outside the samples.
    pub fn at(&self, t: f64, cursor: &mut usize) -> Option<f64> {
        let n = self.t.len().min(self.v.len());
        if n < 2 || !(t >= self.t[0] && t <= self.t[n - 1]) {
            return None;
        }
        while *cursor + 1 < n - 1 && self.t[*cursor + 1] <= t {
            *cursor += 1;
        }
        let i = *cursor;
        let (t0, t1) = (self.t[i], self.t[i + 1]);
        let f = if t1 > t0 {
            ((t - t0) / (t1 - t0)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (a, b) = (f64::from(self.v[i]), f64::from(self.v[i + 1]));
        Some(a + f * (b - a))
    }
}

/// The mean rate of a cumulative quantity over `+-h` around every time
/// (`inc[k]` the increment from `t[k-1]` to `t[k]`; running window sums).
pub fn windowed_rate(t: &[f64], inc: &[f64], h: f64) -> Vec<f32> {
    let n = t.len().min(inc.len());
    let mut out: Vec<f32> = Vec::with_capacity(n);
    let (mut j0, mut j1) = (0usize, 0usize);
    let mut sum = 0.0;
    for k in 0..n {
        while j1 + 1 < n && t[j1 + 1] - t[k] <= h + TIME_SLACK_S {
            j1 += 1;
            sum += inc[j1];
        }
        while t[k] - t[j0] > h + TIME_SLACK_S {
            j0 += 1;
            sum -= inc[j0];
        }
        let dt = t[j1] - t[j0];
        out.push(if dt > 0.0 { (sum / dt) as f32 } else { 0.0 });
    }
    out
}

/// A found lag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LagFit {
    /// `y(t)` matches `x(t - lag)`: the stream is late by this much, s.
    pub lag_s: f64,
    /// 1-sigma: the larger of `sigma_curvature_s` and `sigma_jackknife_s`, s.
    pub sigma_s: f64,
    /// From the curvature of the sum of squares at its minimum, s.
    pub sigma_curvature_s: f64,
    /// Block jackknife, s.
    pub sigma_jackknife_s: f64,
    /// Share of the stream signal's variance explained at the lag (0..1).
    pub explained: f64,
    /// Samples compared.
    pub samples: usize,
}

/// Why no lag was found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LagFailure {
    /// Fewer than 20 samples inside the search range.
    TooFew,
    /// The wheel signal does not vary (or the sum of squares has no minimum).
    Flat,
    /// The best lag is at the edge of the search: the offset is larger
    /// than the search range (or the signals do not match).
    BeyondSearch,
}

#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    n: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
}

impl Sums {
    fn add(&mut self, x: f64, y: f64) {
        self.n += 1.0;
        self.sx += x;
        self.sy += y;
        self.sxx += x * x;
        self.sxy += x * y;
        self.syy += y * y;
    }

    fn minus(&self, o: &Sums) -> Sums {
        Sums {
            n: self.n - o.n,
            sx: self.sx - o.sx,
            sy: self.sy - o.sy,
            sxx: self.sxx - o.sxx,
            sxy: self.sxy - o.sxy,
            syy: self.syy - o.syy,
        }
    }

    /// Total and residual sum of squares of `y ~ k x (+ b)`.
    fn sst_sse(&self, intercept: bool) -> Option<(f64, f64)> {
        let (sxx, sxy, syy) = if intercept {
            if self.n < 2.0 {
                return None;
            }
            (
                self.sxx - self.sx * self.sx / self.n,
                self.sxy - self.sx * self.sy / self.n,
                self.syy - self.sy * self.sy / self.n,
            )
        } else {
            (self.sxx, self.sxy, self.syy)
        };
        if sxx <= 0.0 || sxx.is_nan() {
            return None;
        }
        Some((syy, (syy - sxy * sxy / sxx).max(0.0)))
    }
}

/// Vertex of the least-squares parabola through `sse` around `i_min`:
/// (lag, curvature coefficient c2 of `sse ~ c0 + c1 x + c2 x^2`).
fn parabola(lags: &[f64], sse: &[f64], i_min: usize) -> Option<(f64, f64)> {
    if i_min < PARABOLA_STEPS || i_min + PARABOLA_STEPS >= sse.len() {
        return None;
    }
    let (mut m, mut v) = ([[0.0f64; 3]; 3], [0.0f64; 3]);
    for i in i_min - PARABOLA_STEPS..=i_min + PARABOLA_STEPS {
        let x = lags[i] - lags[i_min];
        let basis = [1.0, x, x * x];
        for r in 0..3 {
            v[r] += basis[r] * sse[i];
            for c in 0..3 {
                m[r][c] += basis[r] * basis[c];
            }
        }
    }
    let mat = nalgebra::Matrix3::from_fn(|r, c| m[r][c]);
    let coef = mat.try_inverse()? * nalgebra::Vector3::new(v[0], v[1], v[2]);
    if coef[2].is_nan() || coef[2] <= 0.0 {
        return None;
    }
    Some((lags[i_min] - coef[1] / (2.0 * coef[2]), coef[2]))
}

fn argmin(v: &[f64]) -> Option<usize> {
    (0..v.len()).min_by(|&a, &b| v[a].total_cmp(&v[b]))
}

/// Find the lag of `obs` (time, value; increasing times) against `x` over
/// `+-search_s`: the minimum of `sum (y(t) - k x(t - lag) [- b])^2` (gain k
/// and, with `intercept`, b fitted at every lag), on a coarse grid (0.1 s)
/// over the whole range, then on a 0.01 s grid over +-0.5 s around the
/// coarse minimum, refined with a parabola over +-0.15 s. Only samples whose
/// shifted times stay `pad_s` inside `x` for every lag are compared.
pub fn fit_lag(
    obs: &[(f64, f64)],
    x: &Sampled<'_>,
    search_s: f64,
    pad_s: f64,
    intercept: bool,
) -> Result<LagFit, LagFailure> {
    let n = x.t.len().min(x.v.len());
    if n < 3 {
        return Err(LagFailure::TooFew);
    }
    let reach = search_s + FINE_STEPS as f64 * FINE_STEP_S;
    let (lo, hi) = (x.t[0] + pad_s + reach, x.t[n - 1] - pad_s - reach);
    let obs: Vec<(f64, f64)> = obs
        .iter()
        .copied()
        .filter(|(t, y)| *t >= lo && *t <= hi && y.is_finite())
        .collect();
    if obs.len() < 20 {
        return Err(LagFailure::TooFew);
    }
    let centre = coarse_centre(&obs, x, search_s, intercept)?;
    let grid = FineGrid::around(&obs, x, centre, intercept)?;
    let (lags, sse, sst) = (&grid.lags, &grid.sse, grid.sst);
    let i_min = argmin(sse).ok_or(LagFailure::Flat)?;
    let (tau, c2) = parabola(lags, sse, i_min).ok_or(LagFailure::Flat)?;
    if tau.abs() > search_s {
        return Err(LagFailure::BeyondSearch);
    }
    let m = obs.len() as f64;
    let params = if intercept { 3.0 } else { 2.0 };
    let s2 = sse[i_min] / (m - params).max(1.0);
    let var_curv = s2 / c2;
    let var_jk = grid.jackknife_variance(intercept);
    let explained = if sst > 0.0 {
        (1.0 - sse[i_min] / sst).clamp(0.0, 1.0)
    } else {
        0.0
    };
    Ok(LagFit {
        lag_s: tau,
        sigma_s: var_curv.max(var_jk).sqrt(),
        sigma_curvature_s: var_curv.sqrt(),
        sigma_jackknife_s: var_jk.sqrt(),
        explained,
        samples: obs.len(),
    })
}

/// The sums of all blocks.
fn total(s: &[Sums]) -> Sums {
    let mut a = Sums::default();
    for b in s {
        a.n += b.n;
        a.sx += b.sx;
        a.sy += b.sy;
        a.sxx += b.sxx;
        a.sxy += b.sxy;
        a.syy += b.syy;
    }
    a
}

/// The coarse search's best lag, s: on at most about COARSE_SAMPLES of the
/// observations (evenly spread), it only has to find the neighbourhood of
/// the minimum, which the fine grid then resolves with every observation.
/// A minimum at the edge of the search is beyond it.
fn coarse_centre(
    obs: &[(f64, f64)],
    x: &Sampled<'_>,
    search_s: f64,
    intercept: bool,
) -> Result<f64, LagFailure> {
    let stride = obs.len().div_ceil(COARSE_SAMPLES).max(1);
    let eval_coarse = |lag: f64| -> Option<Sums> {
        let mut s = Sums::default();
        let t_first = obs[0].0 - lag;
        let mut cursor = x.t.partition_point(|&t| t <= t_first).saturating_sub(1);
        for &(t, y) in obs.iter().step_by(stride) {
            s.add(x.at(t - lag, &mut cursor)?, y);
        }
        Some(s)
    };
    let nc = (search_s / COARSE_STEP_S).round() as i64;
    let mut coarse = Vec::with_capacity((2 * nc + 1) as usize);
    for i in -nc..=nc {
        let s = eval_coarse(i as f64 * COARSE_STEP_S).ok_or(LagFailure::TooFew)?;
        coarse.push(s.sst_sse(intercept).ok_or(LagFailure::Flat)?.1);
    }
    let ic = argmin(&coarse).ok_or(LagFailure::Flat)?;
    if ic == 0 || ic + 1 == coarse.len() {
        return Err(LagFailure::BeyondSearch);
    }
    Ok((ic as i64 - nc) as f64 * COARSE_STEP_S)
}

/// The fine grid of lags around the coarse centre, with the per-block
/// sums kept for the jackknife.
struct FineGrid {
    lags: Vec<f64>,
    /// Per lag, the sums of each of the [`JACKKNIFE_BLOCKS`] blocks.
    per_block: Vec<Vec<Sums>>,
    /// Per lag, the residual sum of squares.
    sse: Vec<f64>,
    /// The total sum of squares at the centre.
    sst: f64,
}

impl FineGrid {
    /// Every observation at each fine lag around `centre`.
    fn around(
        obs: &[(f64, f64)],
        x: &Sampled<'_>,
        centre: f64,
        intercept: bool,
    ) -> Result<FineGrid, LagFailure> {
        let blocks = JACKKNIFE_BLOCKS;
        let block_of = |i: usize| i * blocks / obs.len();
        // Per-block sums at one lag.
        let eval = |lag: f64| -> Option<Vec<Sums>> {
            let mut s = vec![Sums::default(); blocks];
            let t_first = obs[0].0 - lag;
            let mut cursor = x.t.partition_point(|&t| t <= t_first).saturating_sub(1);
            for (i, &(t, y)) in obs.iter().enumerate() {
                let v = x.at(t - lag, &mut cursor)?;
                s[block_of(i)].add(v, y);
            }
            Some(s)
        };
        let mut lags = Vec::with_capacity((2 * FINE_STEPS + 1) as usize);
        let mut per_block = Vec::with_capacity(lags.capacity());
        let mut sse = Vec::with_capacity(lags.capacity());
        let mut sst = 0.0;
        for k in -FINE_STEPS..=FINE_STEPS {
            let lag = centre + k as f64 * FINE_STEP_S;
            let s = eval(lag).ok_or(LagFailure::TooFew)?;
            let (tt, e) = total(&s).sst_sse(intercept).ok_or(LagFailure::Flat)?;
            if k == 0 {
                sst = tt;
            }
            lags.push(lag);
            sse.push(e);
            per_block.push(s);
        }
        Ok(FineGrid {
            lags,
            per_block,
            sse,
            sst,
        })
    }

    /// The block jackknife's variance of the lag, s^2 (infinite with fewer
    /// than three blocks' estimates).
    fn jackknife_variance(&self, intercept: bool) -> f64 {
        let lags = &self.lags;
        let mut taus = Vec::with_capacity(JACKKNIFE_BLOCKS);
        for b in 0..JACKKNIFE_BLOCKS {
            let e: Option<Vec<f64>> = self
                .per_block
                .iter()
                .map(|s| total(s).minus(&s[b]).sst_sse(intercept).map(|(_, e)| e))
                .collect();
            let Some(e) = e else { continue };
            let Some(i) = argmin(&e) else { continue };
            taus.push(parabola(lags, &e, i).map_or(lags[i], |(t, _)| t));
        }
        if taus.len() >= 3 {
            let k = taus.len() as f64;
            let mean = taus.iter().sum::<f64>() / k;
            (k - 1.0) / k * taus.iter().map(|t| (t - mean) * (t - mean)).sum::<f64>()
        } else {
            f64::INFINITY
        }
    }
}

/// Whether a fit determines the offset, else why not.
pub(crate) fn judge(fit: Result<LagFit, LagFailure>, search_s: f64) -> Result<LagFit, String> {
    match fit {
        Ok(f) if f.sigma_s <= MAX_OFFSET_SIGMA_S && f.explained >= MIN_EXPLAINED => Ok(f),
        Ok(f) => Err(format!(
            "the signals hardly vary: the best match at {:+.2} s has sigma {:.2} s and explains {:.0} % of the variance",
            f.lag_s,
            f.sigma_s,
            100.0 * f.explained
        )),
        Err(LagFailure::TooFew) => Err("too few samples overlap".to_string()),
        Err(LagFailure::Flat) => Err("the signals do not vary".to_string()),
        Err(LagFailure::BeyondSearch) => Err(format!(
            "the best match is at the edge of the +-{search_s:.1} s search: the offset may be larger"
        )),
    }
}

/// Determined from the first signal pair that determines it, else "not
/// determined" naming every failure and `needs` (the manoeuvre that would
/// determine it).
pub fn first_determined<'a>(
    tries: impl IntoIterator<Item = (&'a str, Result<LagFit, LagFailure>)>,
    search_s: f64,
    needs: &str,
) -> StreamOffset {
    let mut why = Vec::new();
    let mut weak: Option<(LagFit, &str)> = None;
    for (from, fit) in tries {
        match judge(fit, search_s) {
            Ok(f) => return StreamOffset::determined(&f, from),
            Err(e) => why.push(format!("{from}: {e}")),
        }
        if let Ok(f) = fit {
            if f.explained >= MIN_EXPLAINED
                && f.sigma_s <= WEAK_MAX_SIGMA_S
                && weak.is_none_or(|(w, _)| f.sigma_s < w.sigma_s)
            {
                weak = Some((f, from));
            }
        }
    }
    let mut o = StreamOffset::not_determined(format!("{}; needs {needs}", why.join("; ")));
    if let Some((f, from)) = weak {
        o.weak = Some([f.lag_s, f.sigma_s]);
        o.from = Some(from.to_string());
    }
    o
}

pub use crate::series::median_interval;

/// Times closer than this are the same instant (a double holds UNIX seconds
/// to about 0.2 us): a sample exactly one window length away is in the
/// window whatever the clock's epoch rounded it to.
const TIME_SLACK_S: f64 = 1e-6;

/// Where the bin boundaries sit, as a fraction of a bin after the first
/// sample: between the instants of any regular rate up to 1 kHz (never on
/// one, where a clock's rounding would flip samples between bins).
const BIN_PHASE: f64 = 0.37;

/// Averages of `(t, v)` (increasing finite `t`) over bins of `bin_s`: (mean
/// time, mean value) per non-empty bin. The bins start at the first sample,
/// so the result does not depend on the clock's epoch (a drive stamped from
/// 0 s and the same drive in UNIX seconds bin alike).
fn binned(samples: impl Iterator<Item = (f64, f64)>, bin_s: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut cur: Option<(i64, f64, f64, f64)> = None; // bin, sum t, sum v, n
    let mut first: Option<f64> = None;
    for (t, v) in samples {
        let t0 = *first.get_or_insert(t);
        let b = ((t - t0) / bin_s + BIN_PHASE).floor() as i64;
        match cur.as_mut() {
            Some(c) if c.0 == b => {
                c.1 += t;
                c.2 += v;
                c.3 += 1.0;
            }
            _ => {
                if let Some(c) = cur {
                    out.push((c.1 / c.3, c.2 / c.3));
                }
                cur = Some((b, t, v, 1.0));
            }
        }
    }
    if let Some(c) = cur {
        out.push((c.1 / c.3, c.2 / c.3));
    }
    out
}

/// The wheels as [`imu_offset`] sees them.
#[derive(Debug, Clone, Copy)]
pub struct WheelTrack<'a> {
    /// Wheel times, s (increasing).
    pub t: &'a [f64],
    /// Rear-left revolutions since the previous sample.
    pub dn_rl: &'a [f64],
    /// Rear-right revolutions since the previous sample.
    pub dn_rr: &'a [f64],
    /// Circumference, m.
    pub circumference_m: f64,
    /// Rear track, m.
    pub track_m: f64,
}

/// One IMU row as [`imu_offset`] reads it: time, yaw rate, longitudinal
/// acceleration (when present).
pub type ImuRow = (f64, f64, Option<f64>);

/// The IMU's clock offset against the wheels over `+-search_s`: the IMU
/// yaw rate (averaged over 0.1 s bins) against the wheels' yaw rate
/// `(v_r - v_l) / B`; where that does not determine it and the IMU has
/// longitudinal accelerations, those against the wheel speed's derivative.
/// Rows with a non-finite value or out of time order are skipped.
pub fn imu_offset(wheels: &WheelTrack<'_>, imu: &[ImuRow], search_s: f64) -> StreamOffset {
    let n = wheels
        .t
        .len()
        .min(wheels.dn_rl.len())
        .min(wheels.dn_rr.len());
    if n < 3 {
        return StreamOffset::not_determined("too few wheel samples".to_string());
    }
    let t = &wheels.t[..n];
    let c = wheels.circumference_m;
    let mut last = f64::NEG_INFINITY;
    let rows: Vec<ImuRow> = imu
        .iter()
        .copied()
        .filter(|r| {
            let ok = r.0.is_finite() && r.1.is_finite() && r.0 > last;
            if ok {
                last = r.0;
            }
            ok
        })
        .collect();
    let h = IMU_WHEEL_HALF_WINDOW_S;
    let yaw_inc: Vec<f64> = (0..n)
        .map(|k| (wheels.dn_rr[k] - wheels.dn_rl[k]) * c / wheels.track_m)
        .collect();
    let yaw = windowed_rate(t, &yaw_inc, h);
    let obs = binned(rows.iter().map(|r| (r.0, r.1)), IMU_BIN_S);
    let by_yaw = fit_lag(&obs, &Sampled { t, v: &yaw }, search_s, 2.0 * h, true);
    if let Ok(f) = judge(by_yaw, search_s) {
        // Determined: the acceleration is not needed.
        return StreamOffset::determined(&f, "yaw rate");
    }
    let mut tries = vec![("yaw rate", by_yaw)];
    let accel: Vec<(f64, f64)> = rows
        .iter()
        .filter_map(|r| r.2.filter(|a| a.is_finite()).map(|a| (r.0, a)))
        .collect();
    if accel.len() >= 20 {
        let dist_inc: Vec<f64> = (0..n)
            .map(|k| 0.5 * (wheels.dn_rl[k] + wheels.dn_rr[k]) * c)
            .collect();
        let speed = windowed_rate(t, &dist_inc, h);
        // Central difference over +-h of the windowed speed.
        let mut cursor = (0usize, 0usize);
        let s = Sampled { t, v: &speed };
        let acc: Vec<f32> = t
            .iter()
            .map(
                |&tk| match (s.at(tk - h, &mut cursor.0), s.at(tk + h, &mut cursor.1)) {
                    (Some(a), Some(b)) => ((b - a) / (2.0 * h)) as f32,
                    _ => 0.0,
                },
            )
            .collect();
        let obs = binned(accel.into_iter(), IMU_BIN_S);
        tries.push((
            "longitudinal acceleration",
            fit_lag(&obs, &Sampled { t, v: &acc }, search_s, 4.0 * h, true),
        ));
    }
    first_determined(tries, search_s, "turns (left and right, with GNSS or not) for the IMU's yaw rate, or speed changes for its acceleration")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn weave(t: f64) -> f64 {
        0.3 * (0.4 * t).sin() + 0.2 * (0.13 * t + 1.0).sin()
    }

    #[test]
    fn a_lag_of_two_and_a_half_seconds_is_found() {
        let t: Vec<f64> = (0..12_000).map(|k| k as f64 * 0.01).collect();
        let v: Vec<f32> = t.iter().map(|&t| weave(t) as f32).collect();
        let obs: Vec<(f64, f64)> = (0..1200)
            .map(|k| {
                let tk = k as f64 * 0.1;
                (tk, 2.0 * weave(tk - 2.5) + 0.1)
            })
            .collect();
        let f = fit_lag(&obs, &Sampled { t: &t, v: &v }, CLOCK_SEARCH_S, 0.0, true).unwrap();
        assert!((f.lag_s - 2.5).abs() < 0.005, "{f:?}");
        assert!(f.explained > 0.99);
        let far: Vec<(f64, f64)> = obs.iter().map(|&(t, _)| (t, weave(t - 3.6))).collect();
        let e = fit_lag(&far, &Sampled { t: &t, v: &v }, CLOCK_SEARCH_S, 0.0, true);
        assert!(!matches!(e, Ok(f) if (f.lag_s - 3.6).abs() < 0.05), "{e:?}");
    }

    #[test]
    fn the_imu_offset_does_not_depend_on_the_clock_s_epoch() {
        // Weaving at 5 m/s, the IMU 0.2 s late and noisy. The same drive
        // stamped from 0 s and in UNIX seconds (as ROS 2 bags and NMEA logs
        // are) must give the same offset and sigma.
        let n = 20_000;
        let (c, track) = (2.0, 1.5);
        let yaw = |t: f64| 0.3 * (0.5 * t).sin() + 0.1 * (0.17 * t).sin();
        let run = |t0: f64| {
            let t: Vec<f64> = (0..n).map(|k| t0 + k as f64 * 0.01).collect();
            let (mut rl, mut rr) = (Vec::with_capacity(n), Vec::with_capacity(n));
            for k in 0..n {
                let w = yaw(k as f64 * 0.01);
                rl.push((5.0 - 0.5 * w * track) * 0.01 / c);
                rr.push((5.0 + 0.5 * w * track) * 0.01 / c);
            }
            let imu: Vec<ImuRow> = (0..n)
                .map(|k| {
                    let tk = k as f64 * 0.01;
                    // A gyro's noise, 0.02 rad/s (deterministic).
                    let noise = 0.02 * (((k * 7919 + 13) % 101) as f64 / 50.0 - 1.0);
                    (t0 + tk, yaw(tk - 0.2) + noise, None)
                })
                .collect();
            let w = WheelTrack {
                t: &t,
                dn_rl: &rl,
                dn_rr: &rr,
                circumference_m: c,
                track_m: track,
            };
            imu_offset(&w, &imu, CLOCK_SEARCH_S)
        };
        let (a, b) = (run(0.0), run(1_700_000_000.037));
        let (la, lb) = (a.offset_s.unwrap(), b.offset_s.unwrap());
        assert!((la - 0.2).abs() < 0.01, "{a:?}");
        assert!((la - lb).abs() < 1e-4, "{a:?} vs {b:?}");
        let (sa, sb) = (a.sigma_s.unwrap(), b.sigma_s.unwrap());
        assert!((sa - sb).abs() < 0.1 * sa + 1e-6, "{a:?} vs {b:?}");
    }

    fn pair(base: ClockStream, later: ClockStream, v: Option<(f64, f64)>) -> PairOffset {
        let offset = match v {
            Some((o, s)) => StreamOffset {
                status: OffsetStatus::Determined,
                offset_s: Some(o),
                sigma_s: Some(s),
                from: Some("test".to_string()),
                ..StreamOffset::default()
            },
            None => StreamOffset::not_determined("flat".to_string()),
        };
        PairOffset {
            base,
            later,
            offset,
        }
    }

    #[test]
    fn one_determined_pair_closes_the_chain_for_the_others() {
        use ClockStream::{Gnss, Imu, Wheels};
        // Wheels-IMU +0.5 (0.03), IMU-GNSS -0.1 (0.04), wheels-GNSS not
        // determined: wheels-GNSS = +0.4 with sigma hypot(0.03, 0.04).
        let pairs = [
            pair(Wheels, Gnss, None),
            pair(Wheels, Imu, Some((0.5, 0.03))),
            pair(Imu, Gnss, Some((-0.1, 0.04))),
        ];
        let j = solve_offsets(&pairs, Gnss).unwrap();
        assert!((j.offset_s - 0.4).abs() < 1e-12, "{j:?}");
        assert!((j.sigma_s - 0.05).abs() < 1e-12, "{j:?}");
        assert!(!j.direct && j.path.contains("wheels-imu") && j.path.contains("imu-gnss"));
        // Without the IMU-GNSS pair nothing links the GNSS to the wheels.
        let e = solve_offsets(&pairs[..2], Gnss).unwrap_err();
        assert!(e.contains("no chain"), "{e}");
        // The IMU's own offset rests on its direct pair alone.
        let i = solve_offsets(&pairs, Imu).unwrap();
        assert!((i.offset_s - 0.5).abs() < 1e-12 && i.direct, "{i:?}");
    }

    #[test]
    fn a_loop_is_weighted_and_a_contradicting_loop_is_not_combined() {
        use ClockStream::{Gnss, Imu, Wheels};
        // Direct 0.40 (0.04); chain 0.5 - 0.1 = 0.40 too: the same value, a
        // smaller sigma (1 / (1/0.04^2 + 1/0.05^2)).
        let agree = [
            pair(Wheels, Gnss, Some((0.4, 0.04))),
            pair(Wheels, Imu, Some((0.5, 0.03))),
            pair(Imu, Gnss, Some((-0.1, 0.04))),
        ];
        let j = solve_offsets(&agree, Gnss).unwrap();
        let expected = (1.0f64 / (1.0 / 0.0016 + 1.0 / 0.0025)).sqrt();
        assert!((j.offset_s - 0.4).abs() < 1e-12 && (j.sigma_s - expected).abs() < 1e-12);
        // The chain says +0.9: 8 sigma from the direct pair.
        let contradict = [
            pair(Wheels, Gnss, Some((0.4, 0.04))),
            pair(Wheels, Imu, Some((0.5, 0.03))),
            pair(Imu, Gnss, Some((0.4, 0.04))),
        ];
        let j = solve_offsets(&contradict, Gnss).unwrap();
        assert!((j.offset_s - 0.4).abs() < 1e-12 && j.direct, "{j:?}");
        assert!(j.path.contains("contradict"), "{j:?}");
    }

    #[test]
    fn a_straight_drive_does_not_determine_the_imu_offset() {
        let n = 10_000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.01).collect();
        let dn = vec![0.1; n];
        let imu: Vec<ImuRow> = t
            .iter()
            .enumerate()
            .map(|(k, &t)| (t, 0.001 * ((k * 7919 % 13) as f64 - 6.0), None))
            .collect();
        let w = WheelTrack {
            t: &t,
            dn_rl: &dn,
            dn_rr: &dn,
            circumference_m: 2.0,
            track_m: 1.5,
        };
        let o = imu_offset(&w, &imu, CLOCK_SEARCH_S);
        assert_eq!(o.status, OffsetStatus::NotDetermined);
        assert!(o.reason.unwrap().contains("needs turns"));
    }
}
