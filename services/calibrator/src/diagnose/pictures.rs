//! Pictures of a diagnosis, written as SVG here, and one self-contained
//! HTML page that shows them with the findings, built with the `report`
//! library's page (the calibration and evaluation pages use the same).
//!
//! - [`residual_svg`]: for one finding, its channel's residual against the
//!   signal that reveals the effect, before and after its term entered;
//! - [`tracks_svg`]: the blocks dead-reckoned with the plain 2W model and
//!   with the extended model, laid onto the GNSS fixes;
//! - [`block_errors_svg`]: the position error of both per block;
//! - [`index_html`]: the page a calibration engineer reads.
//!
//! Pure: strings in, strings out; the binary writes the files. Every SVG
//! carries its caption in its `<desc>`, which [`index_html`] shows under it.

use super::{Diagnosis, FitMetrics, ResidualPlot, TrackPlot};
use report::{Cell, Page};
use std::fmt::Write as _;

/// "Before" (the plain model, or the residual without the term): vermillion.
const BEFORE_COLOUR: &str = "#D55E00";
/// "After" (the extended model, or the residual with the term): blue.
const AFTER_COLOUR: &str = "#0072B2";
/// GNSS fixes.
const GNSS_COLOUR: &str = "#7a7a7a";
/// Most points drawn per series of a residual plot.
const MAX_SERIES_POINTS: usize = 3000;
/// Most points drawn per series of the track picture.
const MAX_TRACK_POINTS: usize = 5000;
/// Estimated width of one character of 12 px sans-serif text, px.
const CHAR_W: f64 = 6.6;

// ---------------------------------------------------------------- numbers

/// A tick step of the 1-2-5 family: `mant * 10^exp`, `mant` in {1, 2, 5}.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Step {
    mant: i64,
    exp: i32,
}

fn pow10(e: i32) -> f64 {
    10f64.powi(e)
}

/// `n * 10^e`, correctly rounded (so that `0.3` prints as `0.3`).
fn scaled(n: i64, e: i32) -> f64 {
    if e >= 0 {
        n as f64 * pow10(e)
    } else {
        n as f64 / pow10(-e)
    }
}

impl Step {
    /// The 1-2-5 step nearest to `span / target`.
    fn nice(span: f64, target: usize) -> Step {
        let raw = span.abs() / target.max(1) as f64;
        if !raw.is_finite() || raw <= 0.0 {
            return Step { mant: 1, exp: 0 };
        }
        let exp = raw.log10().floor() as i32;
        let f = raw / pow10(exp);
        let (mant, exp) = if f < 1.5 {
            (1, exp)
        } else if f < 3.0 {
            (2, exp)
        } else if f < 7.0 {
            (5, exp)
        } else {
            (1, exp + 1)
        };
        Step { mant, exp }
    }

    /// The largest 1-2-5 value not above `v`.
    fn floor_of(v: f64) -> Step {
        if !v.is_finite() || v <= 0.0 {
            return Step { mant: 1, exp: 0 };
        }
        let exp = v.log10().floor() as i32;
        let f = v / pow10(exp);
        let mant = if f >= 5.0 {
            5
        } else if f >= 2.0 {
            2
        } else {
            1
        };
        Step { mant, exp }
    }

    /// `k` steps.
    fn value(self, k: i64) -> f64 {
        scaled(k.saturating_mul(self.mant), self.exp)
    }

    /// One step.
    fn size(self) -> f64 {
        self.value(1)
    }

    /// The multiples of the step in `[lo, hi]` (none if absurdly many).
    fn ticks(self, lo: f64, hi: f64) -> Vec<f64> {
        let s = self.size();
        if !(lo.is_finite() && hi.is_finite()) || hi < lo || s <= 0.0 {
            return Vec::new();
        }
        let k0 = (lo / s - 1e-9).ceil();
        let k1 = (hi / s + 1e-9).floor();
        if k1 - k0 > 200.0 || k1 < k0 {
            return Vec::new();
        }
        (k0 as i64..=k1 as i64).map(|k| self.value(k)).collect()
    }

    /// A tick value as text: plain decimals, or exponent form when tiny or huge.
    fn label(self, v: f64) -> String {
        if self.exp < -4 || self.exp > 6 {
            format!("{v:e}")
        } else {
            format!("{v}")
        }
    }
}

/// Drop trailing zeros of a mantissa: `4.10e-3` to `4.1e-3`.
fn trim_exp(s: &str) -> String {
    match s.split_once('e') {
        Some((m, e)) if m.contains('.') => {
            let m = m.trim_end_matches('0').trim_end_matches('.');
            format!("{m}e{e}")
        }
        _ => s.to_string(),
    }
}

/// A value to three significant digits; "n/a" when not finite.
fn num(v: f64) -> String {
    if !v.is_finite() {
        return "n/a".to_string();
    }
    let a = v.abs();
    if a == 0.0 {
        return "0".to_string();
    }
    if !(1e-3..1e5).contains(&a) {
        return trim_exp(&format!("{v:.2e}"));
    }
    let digits = (2 - a.log10().floor() as i32).max(0) as usize;
    format!("{v:.digits$}")
}

/// A value with its 1-sigma, the value to the sigma's second significant
/// digit: `0.00410 ± 0.00030`, `1.000e-5 ± 2.0e-7`.
fn with_sigma(v: f64, sigma: f64) -> String {
    if !(v.is_finite() && sigma.is_finite() && sigma > 0.0) {
        return format!("{} ± {}", num(v), num(sigma));
    }
    let sig_exp = sigma.log10().floor() as i32;
    let decimals = 1 - sig_exp;
    if (0..=6).contains(&decimals) && v.abs() < 1e6 {
        let d = decimals as usize;
        format!("{v:.d$} ± {sigma:.d$}")
    } else {
        let v_exp = if v.abs() > 0.0 {
            v.abs().log10().floor() as i32
        } else {
            sig_exp
        };
        let p = (v_exp - sig_exp + 1).clamp(1, 4) as usize;
        format!("{v:.p$e} ± {sigma:.1e}")
    }
}

/// Linear-interpolated quantile `q` of sorted values.
fn percentile(sorted: &[f64], q: f64) -> f64 {
    match sorted.len() {
        0 => f64::NAN,
        1 => sorted[0],
        n => {
            let pos = q.clamp(0.0, 1.0) * (n - 1) as f64;
            let i = (pos.floor() as usize).min(n - 2);
            let u = pos - i as f64;
            sorted[i] + u * (sorted[i + 1] - sorted[i])
        }
    }
}

fn median_of(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    percentile(v, 0.5)
}

/// A range that is finite and not empty.
fn widen(lo: f64, hi: f64) -> (f64, f64) {
    if !(lo.is_finite() && hi.is_finite()) {
        (0.0, 1.0)
    } else if hi > lo {
        (lo, hi)
    } else {
        let d = if lo.abs() > 0.0 { 0.1 * lo.abs() } else { 1.0 };
        (lo - d, hi + d)
    }
}

/// A range widened by `f` of its length on both sides.
fn pad(lo: f64, hi: f64, f: f64) -> (f64, f64) {
    let (lo, hi) = widen(lo, hi);
    let d = f * (hi - lo);
    (lo - d, hi + d)
}

/// Escape text for HTML and SVG (element content and quoted attributes).
fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

// ---------------------------------------------------------------- frames

/// One axis: its data range and tick step.
#[derive(Debug, Clone, Copy)]
struct Axis {
    lo: f64,
    hi: f64,
    step: Step,
}

impl Axis {
    fn new(lo: f64, hi: f64, target: usize) -> Axis {
        let (lo, hi) = widen(lo, hi);
        Axis {
            lo,
            hi,
            step: Step::nice(hi - lo, target),
        }
    }

    fn frac(&self, v: f64) -> f64 {
        (v - self.lo) / (self.hi - self.lo)
    }

    fn contains(&self, v: f64) -> bool {
        v >= self.lo && v <= self.hi
    }
}

/// A plot area (px, in the picture) with its two axes.
#[derive(Debug, Clone, Copy)]
struct Plot {
    left: f64,
    top: f64,
    w: f64,
    h: f64,
    x: Axis,
    y: Axis,
}

impl Plot {
    /// x in the plot area's own coordinates, px.
    fn px(&self, v: f64) -> f64 {
        self.x.frac(v) * self.w
    }

    /// y in the plot area's own coordinates, px (up is up).
    fn py(&self, v: f64) -> f64 {
        (1.0 - self.y.frac(v)) * self.h
    }

    /// Background, grid, ticks with labels, frame and axis titles; a
    /// darker line at y = 0 with `zero_line`.
    fn axes(&self, s: &mut String, x_title: &str, y_title: &str, x_grid: bool, zero_line: bool) {
        let (l, t, w, h) = (self.left, self.top, self.w, self.h);
        let _ = writeln!(
            s,
            r##"<rect x="{l:.1}" y="{t:.1}" width="{w:.1}" height="{h:.1}" fill="#fbfbfb"/>"##
        );
        let mut grid = String::new();
        let mut labels = String::new();
        for v in self.y.step.ticks(self.y.lo, self.y.hi) {
            let y = t + self.py(v);
            let _ = write!(grid, "M{l:.1} {y:.1}h{w:.1}");
            let _ = writeln!(
                labels,
                r#"<text x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"#,
                l - 6.0,
                y + 4.0,
                escape(&self.y.step.label(v))
            );
        }
        for v in self.x.step.ticks(self.x.lo, self.x.hi) {
            let x = l + self.px(v);
            if x_grid {
                let _ = write!(grid, "M{x:.1} {t:.1}v{h:.1}");
            }
            let _ = write!(grid, "M{x:.1} {:.1}v5", t + h);
            let _ = writeln!(
                labels,
                r#"<text x="{x:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
                t + h + 18.0,
                escape(&self.x.step.label(v))
            );
        }
        if !grid.is_empty() {
            let _ = writeln!(
                s,
                r##"<path d="{grid}" stroke="#dedede" stroke-width="1" fill="none"/>"##
            );
        }
        if zero_line && self.y.contains(0.0) && self.y.lo < 0.0 {
            let y = t + self.py(0.0);
            let _ = writeln!(
                s,
                r##"<path d="M{l:.1} {y:.1}h{w:.1}" stroke="#9a9a9a" stroke-width="1.2" fill="none"/>"##
            );
        }
        s.push_str(&labels);
        let _ = writeln!(
            s,
            r##"<rect x="{l:.1}" y="{t:.1}" width="{w:.1}" height="{h:.1}" fill="none" stroke="#888888"/>"##
        );
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="13">{}</text>"#,
            l + w / 2.0,
            t + h + 40.0,
            escape(x_title)
        );
        let _ = writeln!(
            s,
            r#"<text transform="translate({:.1},{:.1}) rotate(-90)" text-anchor="middle" font-size="13">{}</text>"#,
            18.0,
            t + h / 2.0,
            escape(y_title)
        );
    }

    /// Open the clipping viewport of the plot area; close with `</svg>`.
    fn open_inner(&self, s: &mut String) {
        let _ = writeln!(
            s,
            r#"<svg x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}" viewBox="0 0 {:.1} {:.1}" overflow="hidden">"#,
            self.left, self.top, self.w, self.h, self.w, self.h
        );
    }
}

/// The picture's root element, its title (as text and as `<title>`) and
/// its caption (`<desc>`).
fn open_svg(w: f64, h: f64, title: &str, desc: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}" viewBox="0 0 {w:.0} {h:.0}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, "<title>{}</title>", escape(title));
    let _ = writeln!(s, "<desc>{}</desc>", escape(desc));
    let _ = writeln!(s, r#"<rect width="{w:.0}" height="{h:.0}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="16" y="24" font-size="15" font-weight="bold">{}</text>"#,
        escape(title)
    );
    s
}

/// A picture that says there is nothing to draw.
fn no_data_svg(w: f64, h: f64, title: &str, what: &str) -> String {
    let mut s = open_svg(w, h, title, &format!("no data: {what}"));
    let _ = writeln!(
        s,
        r##"<text x="{:.0}" y="{:.0}" text-anchor="middle" font-size="16" fill="#555555">no data: {}</text>"##,
        w / 2.0,
        h / 2.0,
        escape(what)
    );
    s.push_str("</svg>\n");
    s
}

/// How a legend item is drawn.
#[derive(Debug, Clone, Copy)]
enum Mark {
    Dot,
    Line,
    Bar,
}

/// A legend in one row, starting at (x, y) (text baseline).
fn legend(s: &mut String, x: f64, y: f64, items: &[(Mark, &str, String)]) {
    let mut cx = x;
    for (mark, colour, label) in items {
        match mark {
            Mark::Dot => {
                let _ = writeln!(
                    s,
                    r#"<circle cx="{:.1}" cy="{:.1}" r="4" fill="{colour}"/>"#,
                    cx + 8.0,
                    y - 4.0
                );
            }
            Mark::Line => {
                let _ = writeln!(
                    s,
                    r#"<path d="M{cx:.1} {:.1}h20" stroke="{colour}" stroke-width="2.5" fill="none"/>"#,
                    y - 4.0
                );
            }
            Mark::Bar => {
                let _ = writeln!(
                    s,
                    r#"<rect x="{:.1}" y="{:.1}" width="12" height="10" fill="{colour}"/>"#,
                    cx + 2.0,
                    y - 9.0
                );
            }
        }
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{y:.1}">{}</text>"#,
            cx + 26.0,
            escape(label)
        );
        cx += 26.0 + label.chars().count() as f64 * CHAR_W + 22.0;
    }
}

/// A polyline in plot-area coordinates (nothing for fewer than 2 points).
fn polyline(s: &mut String, pts: &[(f64, f64)], colour: &str, width: f64) {
    if pts.len() < 2 {
        return;
    }
    let mut p = String::new();
    for (x, y) in pts {
        let _ = write!(p, "{x:.1},{y:.1} ");
    }
    let _ = writeln!(
        s,
        r#"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="{width}" stroke-linejoin="round"/>"#,
        p.trim_end()
    );
}

/// Dots as zero-length round-capped path segments (light: ~15 bytes each).
fn dots(s: &mut String, pts: &[(f64, f64)], colour: &str, size: f64, opacity: f64) {
    if pts.is_empty() {
        return;
    }
    let mut d = String::new();
    for (x, y) in pts {
        let _ = write!(d, "M{x:.1} {y:.1}h0");
    }
    let _ = writeln!(
        s,
        r#"<path d="{d}" fill="none" stroke="{colour}" stroke-width="{size}" stroke-linecap="round" stroke-opacity="{opacity}"/>"#
    );
}

fn finite2(p: &[f64; 2]) -> bool {
    p[0].is_finite() && p[1].is_finite()
}

/// Every `step`-th point and the last one.
fn decimate(v: &[[f64; 2]], step: usize) -> Vec<[f64; 2]> {
    let step = step.max(1);
    let mut out: Vec<[f64; 2]> = v.iter().step_by(step).copied().collect();
    if let Some(last) = v.last() {
        if !(v.len() - 1).is_multiple_of(step) {
            out.push(*last);
        }
    }
    out
}

// ---------------------------------------------------------------- residuals

/// The residual of one finding's channel against its revealing signal:
/// before (without the effect's term) and after (with it), each point one
/// GNSS epoch, with the median per bin of the signal as a line. The y range
/// is the 1st-99th percentile of both series (x: 0.5th-99.5th), so that a
/// few outliers do not flatten the picture; a note says how many points lie
/// outside. At most 3000 points are drawn per series.
pub fn residual_svg(p: &ResidualPlot) -> String {
    const W: f64 = 760.0;
    const H: f64 = 510.0;
    let title = format!("{}: residual against {}", p.effect, p.signal);
    let desc = format!(
        "Each dot is one GNSS epoch: the {ch} against {sig}. Before (orange): the held-out \
         residual without the {eff} term, the other accepted effects in; after (blue): with it. \
         Lines: the median in bins of the signal. A slope or offset before that is flat after \
         is the effect's fingerprint, removed by its term.",
        ch = p.channel,
        sig = p.signal,
        eff = p.effect
    );
    let series = |k: usize| -> Vec<[f64; 2]> {
        p.points
            .iter()
            .map(|q| [q.0, if k == 0 { q.1 } else { q.2 }])
            .filter(finite2)
            .collect()
    };
    let (before, after) = (series(0), series(1));
    if before.is_empty() && after.is_empty() {
        return no_data_svg(W, H, &title, "no residual points");
    }
    let mut xs: Vec<f64> = before.iter().chain(&after).map(|q| q[0]).collect();
    let mut ys: Vec<f64> = before.iter().chain(&after).map(|q| q[1]).collect();
    xs.sort_by(f64::total_cmp);
    ys.sort_by(f64::total_cmp);
    let (x_lo, x_hi) = pad(percentile(&xs, 0.005), percentile(&xs, 0.995), 0.03);
    let (y_lo, y_hi) = pad(
        percentile(&ys, 0.01).min(0.0),
        percentile(&ys, 0.99).max(0.0),
        0.06,
    );
    let (left, top, right, bottom) = (84.0, 64.0, 24.0, 84.0);
    let plot = Plot {
        left,
        top,
        w: W - left - right,
        h: H - top - bottom,
        x: Axis::new(x_lo, x_hi, 8),
        y: Axis::new(y_lo, y_hi, 6),
    };
    let inside = |q: &[f64; 2]| plot.x.contains(q[0]) && plot.y.contains(q[1]);
    let rms = |v: &[[f64; 2]]| {
        (v.iter().map(|q| q[1] * q[1]).sum::<f64>() / v.len().max(1) as f64).sqrt()
    };
    let n = p.points.len();
    let mut s = open_svg(W, H, &title, &desc);
    legend(
        &mut s,
        left,
        48.0,
        &[
            (
                Mark::Dot,
                BEFORE_COLOUR,
                format!(
                    "before: without the {} term (RMS {})",
                    p.effect,
                    num(rms(&before))
                ),
            ),
            (
                Mark::Dot,
                AFTER_COLOUR,
                format!("after: with it (RMS {})", num(rms(&after))),
            ),
        ],
    );
    plot.axes(&mut s, &p.signal, &p.channel, true, true);
    plot.open_inner(&mut s);
    let mut subsampled = false;
    for (pts, colour) in [(&before, BEFORE_COLOUR), (&after, AFTER_COLOUR)] {
        let step = pts.len().div_ceil(MAX_SERIES_POINTS).max(1);
        subsampled |= step > 1;
        let drawn: Vec<(f64, f64)> = pts
            .iter()
            .step_by(step)
            .filter(|q| inside(q))
            .map(|q| (plot.px(q[0]), plot.py(q[1])))
            .collect();
        dots(&mut s, &drawn, colour, 3.4, 0.45);
    }
    // The median per bin: the trend the dots hide.
    let total = before.len().max(after.len());
    let bins = (total / 20).clamp(4, 24);
    let width = (plot.x.hi - plot.x.lo) / bins as f64;
    for (pts, colour) in [(&before, BEFORE_COLOUR), (&after, AFTER_COLOUR)] {
        let mut per_bin: Vec<Vec<f64>> = vec![Vec::new(); bins];
        for q in pts.iter() {
            let b = ((q[0] - plot.x.lo) / width).floor();
            if b >= 0.0 && (b as usize) < bins {
                per_bin[b as usize].push(q[1]);
            }
        }
        let line: Vec<(f64, f64)> = per_bin
            .iter_mut()
            .enumerate()
            .filter(|(_, v)| v.len() >= 5)
            .map(|(b, v)| {
                let x = plot.x.lo + (b as f64 + 0.5) * width;
                (plot.px(x), plot.py(median_of(v)))
            })
            .filter(|q| q.1.is_finite())
            .collect();
        polyline(&mut s, &line, "white", 5.0);
        polyline(&mut s, &line, colour, 2.5);
    }
    s.push_str("</svg>\n");
    let out_b = before.iter().filter(|q| !inside(q)).count();
    let out_a = after.iter().filter(|q| !inside(q)).count();
    let mut first = format!("{n} epochs");
    if subsampled {
        first.push_str(&format!(", at most {MAX_SERIES_POINTS} drawn per series"));
    }
    first.push_str("; plotted: 1st-99th percentile of the residuals, 0.5th-99.5th of the signal");
    let second = if out_b + out_a == 0 {
        "No point lies outside it.".to_string()
    } else {
        format!("Outside it, not drawn: {out_b} points before, {out_a} after.")
    };
    for (k, line) in [first, second].iter().enumerate() {
        let _ = writeln!(
            s,
            r##"<text x="{left:.0}" y="{:.0}" font-size="11" fill="#555555">{}</text>"##,
            H - 20.0 + 13.0 * k as f64,
            escape(line)
        );
    }
    s.push_str("</svg>\n");
    s
}

// ---------------------------------------------------------------- tracks

/// RMS distance between a block's GNSS fixes and a model track, m.
fn block_rmse(gnss: &[[f64; 2]], model: &[[f64; 2]]) -> Option<f64> {
    let (ss, n) = sum_sq(gnss, model);
    (n > 0).then(|| (ss / n as f64).sqrt())
}

fn sum_sq(gnss: &[[f64; 2]], model: &[[f64; 2]]) -> (f64, usize) {
    gnss.iter()
        .zip(model)
        .filter(|(g, m)| finite2(g) && finite2(m))
        .fold((0.0, 0), |(ss, n), (g, m)| {
            let (dx, dy) = (g[0] - m[0], g[1] - m[1]);
            (ss + dx * dx + dy * dy, n + 1)
        })
}

/// RMS over all blocks of the plain and the extended model, m.
fn overall_rmse(t: &TrackPlot) -> (f64, f64) {
    let (mut a, mut b) = ((0.0, 0), (0.0, 0));
    for (g, plain, ext) in &t.blocks {
        let (ss, n) = sum_sq(g, plain);
        a = (a.0 + ss, a.1 + n);
        let (ss, n) = sum_sq(g, ext);
        b = (b.0 + ss, b.1 + n);
    }
    let r = |(ss, n): (f64, usize)| {
        if n > 0 {
            (ss / n as f64).sqrt()
        } else {
            f64::NAN
        }
    };
    (r(a), r(b))
}

const TRACK_W: f64 = 900.0;
const TRACK_H: f64 = 740.0;

/// The track picture's plot area: equal scale on both axes, the GNSS fixes
/// in view, model tracks that run far off clipped. `None` without points.
fn track_plot(t: &TrackPlot) -> Option<Plot> {
    let bounds = |pts: &mut dyn Iterator<Item = &[f64; 2]>| {
        pts.filter(|p| finite2(p))
            .fold(None, |b: Option<[f64; 4]>, p| {
                Some(b.map_or([p[0], p[0], p[1], p[1]], |b| {
                    [
                        b[0].min(p[0]),
                        b[1].max(p[0]),
                        b[2].min(p[1]),
                        b[3].max(p[1]),
                    ]
                }))
            })
    };
    let gnss = bounds(&mut t.blocks.iter().flat_map(|b| b.0.iter()));
    let models = bounds(&mut t.blocks.iter().flat_map(|b| b.1.iter().chain(b.2.iter())));
    let [mut x0, mut x1, mut y0, mut y1] = match (gnss, models) {
        (Some(g), Some(m)) => {
            // Models may leave the fixes: follow them a quarter span at most.
            let lim = 0.25 * (g[1] - g[0]).max(g[3] - g[2]).max(1.0);
            [
                g[0].min(m[0].max(g[0] - lim)),
                g[1].max(m[1].min(g[1] + lim)),
                g[2].min(m[2].max(g[2] - lim)),
                g[3].max(m[3].min(g[3] + lim)),
            ]
        }
        (Some(b), None) | (None, Some(b)) => b,
        (None, None) => return None,
    };
    let span = (x1 - x0).max(y1 - y0).max(1.0);
    let margin = 0.04 * span;
    (x0, x1, y0, y1) = (x0 - margin, x1 + margin, y0 - margin, y1 + margin);
    let (left, top, right, bottom) = (84.0, 64.0, 24.0, 64.0);
    let (w, h) = (TRACK_W - left - right, TRACK_H - top - bottom);
    // Equal scale: widen the narrower range about its centre.
    let (sx, sy) = ((x1 - x0).max(1e-9), (y1 - y0).max(1e-9));
    if sx / sy > w / h {
        let c = 0.5 * (y0 + y1);
        let half = 0.5 * sx * h / w;
        (y0, y1) = (c - half, c + half);
    } else {
        let c = 0.5 * (x0 + x1);
        let half = 0.5 * sy * w / h;
        (x0, x1) = (c - half, c + half);
    }
    let step = Step::nice(x1 - x0, 8);
    Some(Plot {
        left,
        top,
        w,
        h,
        x: Axis {
            lo: x0,
            hi: x1,
            step,
        },
        y: Axis {
            lo: y0,
            hi: y1,
            step,
        },
    })
}

/// The whole drive in metres (east, north; equal scale): per block the GNSS
/// fixes, the plain 2W model and the extended model, each block
/// dead-reckoned from the wheels and laid onto its fixes; blocks numbered
/// as in [`block_errors_svg`]; a scale bar.
pub fn tracks_svg(t: &TrackPlot) -> String {
    let title = "Blocks dead-reckoned, laid onto GNSS: plain 2W model and extended model";
    let desc = "Each block is dead-reckoned from the wheels alone with the plain 2W model \
                (orange) and with the model extended by the accepted effects (blue), each \
                laid onto the block's GNSS fixes (grey dots) by the rigid motion that fits \
                best. Equal scale on both axes; the numbers mark where each block starts. \
                The effect terms are fitted on all blocks here; the held-out figures are in \
                the fit table.";
    let Some(plot) = track_plot(t) else {
        return no_data_svg(TRACK_W, TRACK_H, title, "no track points");
    };
    let (rms_plain, rms_ext) = overall_rmse(t);
    let mut s = open_svg(TRACK_W, TRACK_H, title, desc);
    legend(
        &mut s,
        plot.left,
        48.0,
        &[
            (Mark::Dot, GNSS_COLOUR, "GNSS fixes".to_string()),
            (
                Mark::Line,
                BEFORE_COLOUR,
                format!("plain 2W model (RMSE {} m)", num(rms_plain)),
            ),
            (
                Mark::Line,
                AFTER_COLOUR,
                format!("extended model (RMSE {} m)", num(rms_ext)),
            ),
        ],
    );
    plot.axes(&mut s, "east, m", "north, m", true, false);
    plot.open_inner(&mut s);
    let to_px = |v: &[[f64; 2]]| -> Vec<(f64, f64)> {
        v.iter()
            .filter(|p| finite2(p))
            .map(|p| (plot.px(p[0]), plot.py(p[1])))
            .collect()
    };
    let n_gnss: usize = t.blocks.iter().map(|b| b.0.len()).sum();
    let n_model: usize = t.blocks.iter().map(|b| b.1.len().max(b.2.len())).sum();
    let step_g = n_gnss.div_ceil(MAX_TRACK_POINTS).max(1);
    let step_m = n_model.div_ceil(MAX_TRACK_POINTS).max(1);
    let fixes: Vec<(f64, f64)> = t
        .blocks
        .iter()
        .flat_map(|b| to_px(&decimate(&b.0, step_g)))
        .collect();
    dots(&mut s, &fixes, GNSS_COLOUR, 3.0, 0.8);
    for (_, plain, _) in &t.blocks {
        polyline(&mut s, &to_px(&decimate(plain, step_m)), BEFORE_COLOUR, 1.6);
    }
    for (_, _, ext) in &t.blocks {
        polyline(&mut s, &to_px(&decimate(ext, step_m)), AFTER_COLOUR, 1.6);
    }
    if t.blocks.len() <= 80 {
        for (i, (g, _, _)) in t.blocks.iter().enumerate() {
            if let Some(p) = g.iter().find(|p| finite2(p)) {
                let _ = writeln!(
                    s,
                    r##"<text x="{:.1}" y="{:.1}" font-size="10" fill="#333333">{}</text>"##,
                    plot.px(p[0]) + 4.0,
                    plot.py(p[1]) - 4.0,
                    i + 1
                );
            }
        }
    }
    s.push_str("</svg>\n");
    // Scale bar, bottom left inside the plot area.
    let per_m = plot.w / (plot.x.hi - plot.x.lo);
    let bar = Step::floor_of((plot.x.hi - plot.x.lo) / 5.0);
    let len_m = bar.size();
    let len_px = len_m * per_m;
    let (bx, by) = (plot.left + 16.0, plot.top + plot.h - 18.0);
    let text = if len_m >= 1000.0 {
        format!("{} km", bar.label(len_m / 1000.0))
    } else {
        format!("{} m", bar.label(len_m))
    };
    let _ = writeln!(
        s,
        r##"<rect x="{:.1}" y="{:.1}" width="{:.1}" height="30" fill="white" fill-opacity="0.85"/>"##,
        bx - 6.0,
        by - 20.0,
        len_px + 12.0
    );
    let _ = writeln!(
        s,
        r##"<path d="M{bx:.1} {:.1}v6h{len_px:.1}v-6" stroke="#000000" stroke-width="1.5" fill="none"/>"##,
        by - 2.0
    );
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="11">{}</text>"#,
        bx + len_px / 2.0,
        by - 6.0,
        escape(&text)
    );
    s.push_str("</svg>\n");
    s
}

/// Per block (x = block index, numbered as on [`tracks_svg`]): the RMS
/// distance of the plain 2W model and of the extended model from the GNSS
/// fixes, as bars; dashed lines: over all blocks.
pub fn block_errors_svg(t: &TrackPlot) -> String {
    const W: f64 = 900.0;
    const H: f64 = 440.0;
    let title = "Position RMSE per block against GNSS: plain 2W model and extended model";
    let desc = "Per block (numbered as on the track picture, in time order): the RMS distance \
                between the GNSS fixes and the block dead-reckoned with the plain 2W model \
                (orange) and with the extended model (blue), each laid onto the fixes by the \
                best rigid motion. Dashed: over all blocks. The effect terms are fitted on all \
                blocks here; the held-out figures are in the fit table.";
    let errs: Vec<(Option<f64>, Option<f64>)> = t
        .blocks
        .iter()
        .map(|(g, p, e)| (block_rmse(g, p), block_rmse(g, e)))
        .collect();
    let max = errs
        .iter()
        .flat_map(|(a, b)| [*a, *b])
        .flatten()
        .filter(|v| v.is_finite())
        .fold(f64::NAN, f64::max);
    if !max.is_finite() {
        return no_data_svg(W, H, title, "no block with both GNSS and model positions");
    }
    let n = errs.len();
    let (rms_plain, rms_ext) = overall_rmse(t);
    let mut x_step = Step::nice(n as f64, 12);
    if x_step.exp < 0 {
        x_step = Step { mant: 1, exp: 0 };
    }
    let (left, top, right, bottom) = (84.0, 64.0, 24.0, 64.0);
    let plot = Plot {
        left,
        top,
        w: W - left - right,
        h: H - top - bottom,
        x: Axis {
            lo: 0.5,
            hi: n as f64 + 0.5,
            step: x_step,
        },
        y: Axis::new(0.0, max * 1.08, 6),
    };
    let mut s = open_svg(W, H, title, desc);
    legend(
        &mut s,
        left,
        48.0,
        &[
            (
                Mark::Bar,
                BEFORE_COLOUR,
                format!("plain 2W model (all blocks {} m)", num(rms_plain)),
            ),
            (
                Mark::Bar,
                AFTER_COLOUR,
                format!("extended model (all blocks {} m)", num(rms_ext)),
            ),
        ],
    );
    plot.axes(&mut s, "block index", "position RMSE, m", false, false);
    plot.open_inner(&mut s);
    let group = plot.w / n.max(1) as f64;
    let bw = (0.38 * group).clamp(1.0, 28.0);
    let y0 = plot.py(0.0);
    for (i, (a, b)) in errs.iter().enumerate() {
        let c = plot.px(i as f64 + 1.0);
        for (v, x, colour) in [(a, c - bw, BEFORE_COLOUR), (b, c, AFTER_COLOUR)] {
            if let Some(v) = v.filter(|v| v.is_finite()) {
                let y = plot.py(v);
                let _ = writeln!(
                    s,
                    r#"<rect x="{x:.1}" y="{y:.1}" width="{bw:.1}" height="{:.1}" fill="{colour}"><title>block {}: {} m</title></rect>"#,
                    (y0 - y).max(0.0),
                    i + 1,
                    num(v)
                );
            }
        }
    }
    for (v, colour) in [(rms_plain, BEFORE_COLOUR), (rms_ext, AFTER_COLOUR)] {
        if v.is_finite() {
            let _ = writeln!(
                s,
                r#"<path d="M0 {:.1}h{:.1}" stroke="{colour}" stroke-width="1.3" stroke-dasharray="6 4" fill="none"/>"#,
                plot.py(v),
                plot.w
            );
        }
    }
    s.push_str("</svg>\n</svg>\n");
    s
}

// ---------------------------------------------------------------- page

/// An SVG's caption: the text of its `<desc>` (already escaped).
fn caption_of(svg: &str) -> Option<&str> {
    let a = svg.find("<desc>")? + "<desc>".len();
    let b = svg[a..].find("</desc>")? + a;
    Some(&svg[a..b])
}

/// Percent change, or "n/a".
fn change_pct(before: f64, after: f64) -> String {
    if before.is_finite() && after.is_finite() && before.abs() > 0.0 {
        format!("{:+.0} %", 100.0 * (after - before) / before)
    } else {
        "n/a".to_string()
    }
}

fn time_span(t0: f64, t1: f64) -> String {
    format!("{t0:.1} – {t1:.1}")
}

fn plural(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

fn table(s: &mut Page, head: &[&str], rows: &[Vec<(bool, String)>]) {
    // Cells are already escaped HTML.
    let rows: Vec<Vec<Cell>> = rows
        .iter()
        .map(|r| {
            r.iter()
                .map(|(numeric, cell)| {
                    if *numeric {
                        Cell::HtmlNumber(cell.clone())
                    } else {
                        Cell::Html(cell.clone())
                    }
                })
                .collect()
        })
        .collect();
    s.table(head, &rows);
}

fn none_para(s: &mut Page, text: &str) {
    s.note(text);
}

/// The text of escaped HTML (a `<desc>` caption) back.
fn unescape(s: &str) -> String {
    s.replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&#39;", "'")
        .replace("&amp;", "&")
}

fn fit_rows(before: &FitMetrics, after: &FitMetrics) -> Vec<Vec<(bool, String)>> {
    let row = |name: &str, b: f64, a: f64, change: String| {
        vec![
            (false, escape(name)),
            (true, num(b)),
            (true, num(a)),
            (true, escape(&change)),
        ]
    };
    let diff = |b: f64, a: f64| {
        if b.is_finite() && a.is_finite() {
            format!("{:+.2}", a - b)
        } else {
            "n/a".to_string()
        }
    };
    vec![
        row(
            "position RMSE, m",
            before.holdout_position_rmse_m,
            after.holdout_position_rmse_m,
            change_pct(
                before.holdout_position_rmse_m,
                after.holdout_position_rmse_m,
            ),
        ),
        row(
            "heading (course) RMSE, rad",
            before.holdout_heading_rmse_rad,
            after.holdout_heading_rmse_rad,
            change_pct(
                before.holdout_heading_rmse_rad,
                after.holdout_heading_rmse_rad,
            ),
        ),
        row(
            "speed RMSE, relative",
            before.holdout_speed_rmse_rel,
            after.holdout_speed_rmse_rel,
            change_pct(before.holdout_speed_rmse_rel, after.holdout_speed_rmse_rel),
        ),
        row(
            "lag-1 autocorrelation of the course residual (0 = white)",
            before.residual_lag1_autocorr,
            after.residual_lag1_autocorr,
            diff(before.residual_lag1_autocorr, after.residual_lag1_autocorr),
        ),
    ]
}

/// One self-contained HTML page (inline CSS, the SVGs inlined, nothing
/// fetched) for a calibration engineer: the headline, the findings with
/// their parameters, held-out gain and evidence, the ambiguous and the
/// unexplained, the mismatch segments, the held-out fit before and after,
/// what was rejected or could not be tested, the noise the thresholds came
/// from, and then every picture of `pictures` (name, SVG text) under its
/// name, captioned with the SVG's `<desc>`.
pub fn index_html(d: &Diagnosis, pictures: &[(String, String)]) -> String {
    let mut s = Page::new("Diagnosis: the physics the 2W model leaves out");
    let b = &d.base_model;
    let _ = writeln!(
        s,
        "<p class=\"muted\">Calibrated plain 2W model: rear-left circumference {} m, rear-right \
         {} m, track width {} m. Judged on {} of {} s; every threshold comes from the \
         drive's own noise.</p>",
        num(b.c_rl_m),
        num(b.c_rr_m),
        num(b.track_width_m),
        plural(d.noise.blocks, "block", "blocks"),
        num(d.noise.block_s)
    );

    // Headline.
    let counts = format!(
        "{}, {} ambiguous, {} unexplained",
        plural(d.findings.len(), "finding", "findings"),
        d.ambiguous.len(),
        d.unexplained.len()
    );
    let (fb, fa) = (
        d.fit.before.holdout_position_rmse_m,
        d.fit.after.holdout_position_rmse_m,
    );
    if d.findings.is_empty() && d.ambiguous.is_empty() && d.unexplained.is_empty() {
        let _ = writeln!(
            s,
            "<p class=\"headline good\">{}: no effect beyond the noise: the plain 2W model \
             explains this drive (held-out position RMSE {} m).</p>",
            escape(&counts),
            num(fb)
        );
    } else {
        let found = if d.findings.is_empty() {
            "No catalogue effect accepted".to_string()
        } else {
            let ids: Vec<String> = d.findings.iter().map(|f| f.effect.to_string()).collect();
            format!(
                "Accepted: {}; held-out position RMSE {} m → {} m ({})",
                ids.join(", "),
                num(fb),
                num(fa),
                change_pct(fb, fa)
            )
        };
        let _ = writeln!(
            s,
            "<p class=\"headline\">{}. {}.</p>",
            escape(&counts),
            escape(&found)
        );
    }

    // Findings.
    s.heading("Findings");
    if d.findings.is_empty() {
        none_para(
            &mut s,
            "None: no catalogue effect lowers the error on held-out blocks beyond the noise.",
        );
    } else {
        let rows: Vec<Vec<(bool, String)>> = d
            .findings
            .iter()
            .map(|f| {
                let mut effect = format!("<code>{}</code>", escape(f.effect.id()));
                if !f.variant.is_empty() {
                    let _ = write!(effect, " ({})", escape(&f.variant));
                }
                let params: Vec<String> = f
                    .parameters
                    .iter()
                    .map(|(name, v)| {
                        let value = match f.sigmas.get(name) {
                            Some(sig) => with_sigma(*v, *sig),
                            None => num(*v),
                        };
                        let mut p = format!("{} = {value}", escape(name));
                        if let Some(u) = f.units.get(name).filter(|u| u.as_str() != "1") {
                            let _ = write!(p, " {}", escape(u));
                        }
                        p
                    })
                    .collect();
                vec![
                    (false, effect),
                    (false, params.join("<br>")),
                    (
                        true,
                        format!(
                            "{} → {} ({})",
                            num(f.holdout_rmse_before_m),
                            num(f.holdout_rmse_after_m),
                            escape(&change_pct(f.holdout_rmse_before_m, f.holdout_rmse_after_m))
                        ),
                    ),
                    (true, format!("{:.1} %", 100.0 * f.holdout_channel_gain)),
                    (true, num(f.holdout_gain_z)),
                    (false, escape(&f.evidence)),
                ]
            })
            .collect();
        table(
            &mut s,
            &[
                "effect",
                "parameters (± 1 sigma)",
                "held-out position RMSE, m: before → after",
                "held-out channel gain",
                "gain t",
                "evidence",
            ],
            &rows,
        );
    }

    // Ambiguous.
    s.heading("Ambiguous: effects this drive cannot tell apart");
    if d.ambiguous.is_empty() {
        none_para(&mut s, "None.");
    } else {
        let rows: Vec<Vec<(bool, String)>> = d
            .ambiguous
            .iter()
            .map(|a| {
                let ids: Vec<String> = a
                    .effects
                    .iter()
                    .map(|e| format!("<code>{}</code>", escape(e.id())))
                    .collect();
                vec![
                    (false, ids.join(", ")),
                    (true, num(a.vif)),
                    (false, escape(&a.separate_by)),
                ]
            })
            .collect();
        table(
            &mut s,
            &[
                "effects",
                "variance inflation",
                "the manoeuvre that would separate them",
            ],
            &rows,
        );
    }

    // Unexplained.
    s.heading("Unexplained: structure no catalogue effect explains");
    if d.unexplained.is_empty() {
        none_para(&mut s, "None.");
    } else {
        let rows: Vec<Vec<(bool, String)>> = d
            .unexplained
            .iter()
            .map(|u| {
                vec![
                    (true, escape(&time_span(u.t_start_s, u.t_end_s))),
                    (true, format!("({}, {})", num(u.x_m), num(u.y_m))),
                    (false, escape(&u.channel)),
                    (true, num(u.rms_m)),
                    (false, escape(&u.correlates_with)),
                ]
            })
            .collect();
        table(
            &mut s,
            &[
                "time span, s",
                "where (east, north), m",
                "channel",
                "RMS, m",
                "correlates with",
            ],
            &rows,
        );
    }

    // Mismatch segments.
    s.heading("Where the plain model leaves the recording");
    if d.mismatch_segments.is_empty() {
        none_para(
            &mut s,
            "Nowhere beyond the noise: no block's plain-model error exceeds three times the noise floor.",
        );
    } else {
        let rows: Vec<Vec<(bool, String)>> = d
            .mismatch_segments
            .iter()
            .map(|m| {
                vec![
                    (true, escape(&time_span(m.t_start_s, m.t_end_s))),
                    (true, format!("({}, {})", num(m.x_m), num(m.y_m))),
                    (true, num(m.rms_m)),
                    (false, escape(&m.manoeuvre)),
                ]
            })
            .collect();
        table(
            &mut s,
            &[
                "time span, s",
                "where (east, north), m",
                "position RMS, m",
                "manoeuvre",
            ],
            &rows,
        );
    }

    // Fit.
    s.heading("Fit on held-out blocks");
    none_para(
        &mut s,
        "Each block is predicted with coefficients fitted on the other blocks.",
    );
    table(
        &mut s,
        &["", "before (plain 2W)", "after (extended)", "change"],
        &fit_rows(&d.fit.before, &d.fit.after),
    );

    // Rejected and untestable.
    s.heading("Rejected");
    if d.rejected.is_empty() {
        none_para(&mut s, "None.");
    } else {
        s.html("<ul>\n");
        for r in &d.rejected {
            let _ = writeln!(
                s,
                "<li><code>{}</code>: {}</li>",
                escape(r.effect.id()),
                escape(&r.reason)
            );
        }
        s.html("</ul>\n");
    }
    s.heading("Tested, not accepted (the last round of the selection)");
    if d.not_accepted.is_empty() {
        none_para(&mut s, "None.");
    } else {
        s.html("<ul>\n");
        for n in &d.not_accepted {
            let _ = writeln!(
                s,
                "<li><code>{}</code>: held-out gain {:+.1} %, signed-rank z {:.2} (needed {:.2}); this drive {}</li>",
                escape(n.effect.id()),
                100.0 * n.holdout_gain,
                n.z,
                n.z_threshold,
                escape(&n.detectable_text())
            );
        }
        s.html("</ul>\n");
    }
    s.heading("Not testable on this drive");
    if d.untestable.is_empty() {
        none_para(&mut s, "None: every catalogue effect was tested.");
    } else {
        s.html("<ul>\n");
        for u in &d.untestable {
            let _ = writeln!(
                s,
                "<li><code>{}</code>: needs {}</li>",
                escape(u.effect.id()),
                escape(&u.needs)
            );
        }
        s.html("</ul>\n");
    }

    // Noise.
    s.heading("Noise levels (the thresholds come from these)");
    let n = &d.noise;
    let mut rows = vec![
        vec![
            (false, "GNSS position noise, 1 sigma, m".to_string()),
            (true, num(n.gnss_sigma_m)),
        ],
        vec![
            (false, "block length, s".to_string()),
            (true, num(n.block_s)),
        ],
        vec![
            (false, "blocks with data".to_string()),
            (true, n.blocks.to_string()),
        ],
        vec![
            (false, "GNSS fixes set aside as jumps".to_string()),
            (true, n.gnss_jumps.to_string()),
        ],
    ];
    for (ch, sigma) in &n.channel_sigma {
        let unit = n
            .channel_units
            .get(ch)
            .filter(|u| u.as_str() != "1")
            .map(|u| format!(", {u}"))
            .unwrap_or_default();
        rows.push(vec![
            (false, escape(&format!("{ch} residual noise{unit}"))),
            (true, num(*sigma)),
        ]);
    }
    table(&mut s, &["", "value"], &rows);

    // Pictures.
    s.heading("Pictures");
    if pictures.is_empty() {
        none_para(&mut s, "No pictures.");
    }
    for (name, svg) in pictures {
        let caption = caption_of(svg).map_or_else(|| name.clone(), unescape);
        s.figure(name, svg, &caption);
    }
    s.render()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::{
        Ambiguous, BaseModel, Finding, Fit, MismatchSegment, NoiseLevels, Rejected, Unexplained,
        Untestable,
    };
    use interfaces::effects::Effect;
    use std::collections::BTreeMap;
    use vehicle_model::effects::EffectTerms;

    /// Tags balance, entities are entities, and no NaN or inf leaked.
    fn assert_well_formed(svg: &str) {
        assert!(svg.starts_with("<svg"), "{}", &svg[..svg.len().min(80)]);
        assert_eq!(svg.matches("<svg").count(), svg.matches("</svg>").count());
        for bad in ["NaN", "\"inf", "-inf", " inf", ",inf", ">inf"] {
            assert!(!svg.contains(bad), "non-finite number: {bad}");
        }
        let mut stack: Vec<&str> = Vec::new();
        let mut rest = svg;
        while let Some(i) = rest.find('<') {
            rest = &rest[i + 1..];
            let end = rest.find('>').expect("unclosed tag");
            let tag = &rest[..end];
            if let Some(name) = tag.strip_prefix('/') {
                assert_eq!(stack.pop(), Some(name.trim()), "mismatched </{name}>");
            } else if !tag.ends_with('/') {
                let name = tag.split_whitespace().next().expect("tag name");
                stack.push(name);
            }
            assert_eq!(
                tag.matches('"').count() % 2,
                0,
                "unbalanced quotes in <{tag}>"
            );
            rest = &rest[end + 1..];
        }
        assert!(stack.is_empty(), "unclosed: {stack:?}");
        for (i, _) in svg.match_indices('&') {
            let t = &svg[i..];
            assert!(
                ["&amp;", "&lt;", "&gt;", "&quot;", "&#"]
                    .iter()
                    .any(|e| t.starts_with(e)),
                "raw & at {i}"
            );
        }
    }

    fn is_nice(step: f64) -> bool {
        let e = step.log10().floor();
        let m = step / 10f64.powf(e);
        [1.0, 2.0, 5.0, 10.0].iter().any(|x| (m - x).abs() < 1e-9)
    }

    #[test]
    fn ticks_are_nice() {
        let ranges = [
            (0.0, 1.0),
            (-0.0123, 0.0456),
            (3.0, 3.7),
            (0.0, 3600.0),
            (-2.5e-5, 1.1e-5),
            (123456.0, 987654.0),
            (-7.3, -1.2),
            (0.0, 0.3),
        ];
        for (lo, hi) in ranges {
            let a = Axis::new(lo, hi, 6);
            let step = a.step.size();
            assert!(is_nice(step), "step {step} for {lo}..{hi}");
            let t = a.step.ticks(lo, hi);
            assert!(
                (3..=14).contains(&t.len()),
                "{} ticks for {lo}..{hi}",
                t.len()
            );
            for v in &t {
                assert!(
                    *v >= lo - 1e-12 && *v <= hi + 1e-12,
                    "{v} outside {lo}..{hi}"
                );
                let k = v / step;
                assert!((k - k.round()).abs() < 1e-9, "{v} not a multiple of {step}");
                // Labels are short: no float noise like 0.30000000000000004.
                assert!(a.step.label(*v).len() <= 8, "label {}", a.step.label(*v));
            }
        }
        assert_eq!(Step::nice(1.0, 10).label(0.3), "0.3");
        assert_eq!(Step::nice(1.0, 10).value(3), 0.3);
        assert!(is_nice(Step::floor_of(437.0).size()));
        assert_eq!(Step::floor_of(437.0).size(), 200.0);
        assert_eq!(num(0.0041), "0.00410");
        assert_eq!(num(3.2), "3.20");
        assert_eq!(num(f64::NAN), "n/a");
        assert_eq!(num(1.234e-5), "1.23e-5");
        assert_eq!(with_sigma(0.0041, 0.0003), "0.00410 ± 0.00030");
        assert_eq!(with_sigma(3.2, 0.15), "3.20 ± 0.15");
        assert_eq!(with_sigma(1.0e-5, 2.0e-7), "1.000e-5 ± 2.0e-7");
    }

    fn plot(n: usize) -> ResidualPlot {
        ResidualPlot {
            effect: "side_slip".into(),
            signal: "lateral acceleration a_y, m/s^2".into(),
            channel: "course_wheel residual, rad <test>".into(),
            points: (0..n)
                .map(|i| {
                    let x = (i as f64 * 0.37).sin() * 4.0;
                    let noise = (i as f64 * 1.7).cos() * 0.002;
                    let outlier = if i % 500 == 7 { 1.0 } else { 0.0 };
                    (x, 0.004 * x + noise + outlier, noise)
                })
                .collect(),
        }
    }

    #[test]
    fn residual_svg_has_axes_legend_and_stays_light() {
        let svg = residual_svg(&plot(10_000));
        assert_well_formed(&svg);
        assert!(svg.contains("side_slip: residual against lateral acceleration a_y, m/s^2"));
        assert!(svg.contains("lateral acceleration a_y, m/s^2"));
        assert!(svg.contains("course_wheel residual, rad &lt;test&gt;"));
        assert!(!svg.contains("<test>"));
        assert!(svg.contains("before: without the side_slip term"));
        assert!(svg.contains("after: with it"));
        assert!(svg.contains("Outside it, not drawn"));
        // Subsampled to at most 3000 per series.
        assert!(svg.matches("h0").count() <= 2 * MAX_SERIES_POINTS);
        assert!(svg.len() < 250_000, "{} bytes", svg.len());
        // The outliers (1.0) do not set the y range.
        assert!(!svg.contains(r#"text-anchor="end">1<"#));
        assert!(!svg.contains(r#"text-anchor="end">0.8<"#));
    }

    #[test]
    fn residual_svg_degenerate_inputs() {
        let empty = residual_svg(&ResidualPlot::default());
        assert_well_formed(&empty);
        assert!(empty.contains("no data"));
        let mut one = plot(1);
        one.points = vec![(2.0, 0.0, 0.0)];
        assert_well_formed(&residual_svg(&one));
        let mut bad = plot(3);
        bad.points = vec![(f64::NAN, 1.0, 1.0), (1.0, f64::INFINITY, 0.5)];
        assert_well_formed(&residual_svg(&bad));
    }

    fn track(blocks: usize, offset_plain: f64, offset_ext: f64) -> TrackPlot {
        TrackPlot {
            blocks: (0..blocks)
                .map(|b| {
                    let g: Vec<[f64; 2]> = (0..50)
                        .map(|i| {
                            let a = (b * 50 + i) as f64 * 0.01;
                            [300.0 * a.cos(), 120.0 * a.sin()]
                        })
                        .collect();
                    let shift = |d: f64| g.iter().map(|p| [p[0] + d, p[1]]).collect::<Vec<_>>();
                    (g.clone(), shift(offset_plain), shift(offset_ext))
                })
                .collect(),
        }
    }

    #[test]
    fn tracks_svg_has_equal_scale_axes_legend_and_scale_bar() {
        let t = track(8, 3.0, 0.5);
        let svg = tracks_svg(&t);
        assert_well_formed(&svg);
        assert!(
            svg.contains("Blocks dead-reckoned, laid onto GNSS: plain 2W model and extended model")
        );
        for label in [
            "east, m",
            "north, m",
            "GNSS fixes",
            "plain 2W model",
            "extended model",
        ] {
            assert!(svg.contains(label), "{label}");
        }
        assert!(svg.contains("RMSE 3.00 m") && svg.contains("RMSE 0.500 m"));
        assert!(svg.contains(" m</text>"), "scale bar");
        let p = track_plot(&t).expect("plot");
        let (sx, sy) = (p.w / (p.x.hi - p.x.lo), p.h / (p.y.hi - p.y.lo));
        assert!((sx - sy).abs() < 1e-9 * sx, "{sx} vs {sy}");
        assert!(is_nice(p.x.step.size()));
        let empty = tracks_svg(&TrackPlot::default());
        assert_well_formed(&empty);
        assert!(empty.contains("no data"));
    }

    #[test]
    fn block_errors_svg_shows_rmse_per_block() {
        let t = track(5, 3.0, 0.5);
        let svg = block_errors_svg(&t);
        assert_well_formed(&svg);
        assert!(svg.contains("position RMSE, m"));
        assert!(svg.contains("block index"));
        assert!(svg.contains("plain 2W model") && svg.contains("extended model"));
        // Two frame rects, two legend swatches, then two bars per block.
        assert_eq!(
            svg.matches("<rect x=").count() - 4,
            10,
            "two bars per block"
        );
        assert_eq!(block_rmse(&t.blocks[0].0, &t.blocks[0].1), Some(3.0));
        let empty = block_errors_svg(&TrackPlot::default());
        assert_well_formed(&empty);
        assert!(empty.contains("no data"));
    }

    fn metrics(p: f64) -> FitMetrics {
        FitMetrics {
            holdout_position_rmse_m: p,
            holdout_heading_rmse_rad: 0.01 * p,
            holdout_speed_rmse_rel: 0.001,
            residual_lag1_autocorr: 0.5,
        }
    }

    fn diagnosis(findings: Vec<Finding>) -> Diagnosis {
        Diagnosis {
            findings,
            ambiguous: Vec::new(),
            unexplained: Vec::new(),
            mismatch_segments: Vec::new(),
            fit: Fit {
                before: metrics(3.2),
                after: metrics(1.1),
            },
            rejected: Vec::new(),
            untestable: Vec::new(),
            not_accepted: Vec::new(),
            noise: NoiseLevels {
                gnss_sigma_m: 0.3,
                block_s: 30.0,
                blocks: 12,
                channel_sigma: BTreeMap::from([("speed".to_string(), 0.004)]),
                channel_units: BTreeMap::from([("speed".to_string(), "1".to_string())]),
                gnss_jumps: 0,
            },
            base_model: BaseModel {
                c_rl_m: 1.95,
                c_rr_m: 1.96,
                track_width_m: 1.55,
            },
            terms: EffectTerms::default(),
            residual_plots: Vec::new(),
            tracks: TrackPlot::default(),
        }
    }

    fn finding(effect: Effect, evidence: &str) -> Finding {
        Finding {
            effect,
            variant: String::new(),
            parameters: BTreeMap::from([("k".to_string(), 0.0041)]),
            sigmas: BTreeMap::from([("k".to_string(), 0.0003)]),
            units: BTreeMap::from([("k".to_string(), "rad/(m/s^2)".to_string())]),
            holdout_rmse_before_m: 3.2,
            holdout_rmse_after_m: 1.1,
            holdout_channel_gain: 0.4,
            holdout_gain_z: 7.5,
            evidence: evidence.to_string(),
        }
    }

    #[test]
    fn index_html_shows_everything_escaped() {
        let mut d = diagnosis(vec![
            finding(Effect::SideSlip, "t < 3 & still <b>believed</b>"),
            finding(Effect::GnssLeverArm, "course offset"),
        ]);
        d.ambiguous.push(Ambiguous {
            effects: vec![Effect::LoadTransferRadius, Effect::TrackWidth],
            vif: 14.0,
            separate_by: "corners at <several> speeds".into(),
        });
        d.unexplained.push(Unexplained {
            t_start_s: 812.0,
            t_end_s: 840.5,
            x_m: 10.0,
            y_m: -4.0,
            correlates_with: "a GNSS jump".into(),
            rms_m: 2.4,
            channel: "position".into(),
        });
        d.mismatch_segments.push(MismatchSegment {
            t_start_s: 100.0,
            t_end_s: 130.0,
            rms_m: 3.1,
            manoeuvre: "left corner, 7 m/s".into(),
            x_m: 0.0,
            y_m: 0.0,
        });
        d.rejected.push(Rejected {
            effect: Effect::GyroScale,
            reason: "implausible".into(),
        });
        d.untestable.push(Untestable {
            effect: Effect::RoadGrade,
            needs: "an IMU pitch".into(),
        });
        let svg = residual_svg(&plot(200));
        let html = index_html(&d, &[("residual <side_slip>".to_string(), svg.clone())]);
        assert!(html.starts_with("<!DOCTYPE html>"));
        for f in &d.findings {
            assert!(html.contains(f.effect.id()), "{}", f.effect);
        }
        assert!(html.contains("t &lt; 3 &amp; still &lt;b&gt;believed&lt;/b&gt;"));
        assert!(!html.contains("<b>believed"));
        assert!(html.contains("corners at &lt;several&gt; speeds"));
        assert!(html.contains("residual &lt;side_slip&gt;"));
        assert!(html.contains("k = 0.00410 ± 0.00030 rad/(m/s^2)"));
        assert!(html.contains("2 findings, 1 ambiguous, 1 unexplained"));
        assert!(html.contains("812.0 – 840.5"));
        assert!(html.contains("left corner, 7 m/s"));
        assert!(html.contains("gyro_scale") && html.contains("an IMU pitch"));
        assert!(html.contains("lag-1 autocorrelation"));
        assert!(html.contains(svg.trim()), "the SVG inlined");
        assert!(html.contains("<figcaption>Each dot is one GNSS epoch"));
        assert!(!html.contains("<link") && !html.contains("src=") && !html.contains("<script"));
        assert!(!html.contains("no effect beyond the noise"));
    }

    #[test]
    fn index_html_says_plainly_when_nothing_is_found() {
        let mut d = diagnosis(Vec::new());
        d.fit.after = d.fit.before;
        let html = index_html(&d, &[]);
        assert!(html.contains("no effect beyond the noise: the plain 2W model explains this drive"));
        assert!(html.contains("0 findings, 0 ambiguous, 0 unexplained"));
    }
}
