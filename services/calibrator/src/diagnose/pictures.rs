//! Pictures of a diagnosis and one self-contained HTML page that shows them
//! with the findings, both built with the `report` library (the calibration
//! and evaluation pages use the same figures and page).
//!
//! - [`residual_svg`]: for one finding, its channel's residual against the
//!   signal that reveals the effect, before and after its term entered;
//! - [`tracks_svg`]: the blocks dead-reckoned with the plain 2W model and
//!   with the extended model, laid onto the GNSS fixes;
//! - [`block_errors_svg`]: the position error of both per block;
//! - [`index_html`]: the page a calibration engineer reads.
//!
//! Pure: data in, strings out; the binary writes the files. Every SVG
//! carries its caption in its `<desc>`, which [`index_html`] shows under it.

use super::{Diagnosis, FitMetrics, ResidualPlot, TrackPlot};
use report::{escape, Axis, Cell, Colour, Figure, FigureError, Mark, Page, Series};
use std::fmt::Write as _;

/// "Before" (the plain model, or the residual without the term).
const BEFORE_COLOUR: Colour = Colour::VERMILLION;
/// "After" (the extended model, or the residual with the term).
const AFTER_COLOUR: Colour = Colour::BLUE;
/// Most points drawn per series of a residual plot.
const MAX_SERIES_POINTS: usize = 1200;

// ---------------------------------------------------------------- numbers

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

/// Linear-interpolated quantile `q` of sorted values (NaN when empty).
fn percentile(sorted: &[f64], q: f64) -> f64 {
    stats::percentile_sorted(sorted, q).unwrap_or(f64::NAN)
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

// ---------------------------------------------------------------- figures

fn finite2(p: &[f64; 2]) -> bool {
    p[0].is_finite() && p[1].is_finite()
}

/// The residual of one finding's channel against its revealing signal:
/// before (without the effect's term) and after (with it), each point one
/// GNSS epoch, with the median per bin of the signal as a line. The y range
/// is the 1st-99th percentile of both series (x: 0.5th-99.5th), so that a
/// few outliers do not flatten the picture; the caption says how many
/// points lie outside. At most 1200 points are drawn per series.
pub fn residual_svg(p: &ResidualPlot) -> Result<String, FigureError> {
    let title = format!("{}: residual against {}", p.effect, p.signal);
    let mut desc = format!(
        "Each dot is one GNSS epoch: the {ch} against {sig}. Before (vermillion): the held-out \
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
    let mut x = Axis::linear(&p.signal, "");
    let mut y = Axis::linear(&p.channel, "");
    let fig = |x: Axis, y: Axis| Figure::new(&title, x, y).sized((760, 510));
    if before.is_empty() && after.is_empty() {
        return fig(x, y).describe(&desc).svg();
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
    x.range = Some((x_lo, x_hi));
    y.range = Some((y_lo, y_hi));
    let inside = |q: &[f64; 2]| q[0] >= x_lo && q[0] <= x_hi && q[1] >= y_lo && q[1] <= y_hi;
    let rms = |v: &[[f64; 2]]| {
        (v.iter().map(|q| q[1] * q[1]).sum::<f64>() / v.len().max(1) as f64).sqrt()
    };
    // The median per bin: the trend the dots hide.
    let total = before.len().max(after.len());
    let bins = (total / 20).clamp(4, 24);
    let width = (x_hi - x_lo) / bins as f64;
    let medians = |pts: &[[f64; 2]]| -> Vec<[f64; 2]> {
        let mut per_bin: Vec<Vec<f64>> = vec![Vec::new(); bins];
        for q in pts {
            let b = ((q[0] - x_lo) / width).floor();
            if b >= 0.0 && (b as usize) < bins {
                per_bin[b as usize].push(q[1]);
            }
        }
        per_bin
            .iter_mut()
            .enumerate()
            .filter(|(_, v)| v.len() >= 5)
            .map(|(b, v)| {
                [
                    x_lo + (b as f64 + 0.5) * width,
                    stats::median(v).unwrap_or(f64::NAN),
                ]
            })
            .collect()
    };
    let mut subsampled = false;
    let mut drawn = |pts: &[[f64; 2]]| -> Vec<[f64; 2]> {
        let step = pts.len().div_ceil(MAX_SERIES_POINTS).max(1);
        subsampled |= step > 1;
        pts.iter().step_by(step).copied().collect()
    };
    let (dots_before, dots_after) = (drawn(&before), drawn(&after));
    let out_b = before.iter().filter(|q| !inside(q)).count();
    let out_a = after.iter().filter(|q| !inside(q)).count();
    let _ = write!(desc, " {} epochs", p.points.len());
    if subsampled {
        let _ = write!(desc, ", at most {MAX_SERIES_POINTS} drawn per series");
    }
    desc.push_str("; plotted: 1st-99th percentile of the residuals, 0.5th-99.5th of the signal. ");
    if out_b + out_a == 0 {
        desc.push_str("No point lies outside it.");
    } else {
        let _ = write!(
            desc,
            "Outside it, not drawn: {out_b} points before, {out_a} after."
        );
    }
    fig(x, y)
        .with(
            Series::dots(
                &format!(
                    "before: without the {} term (RMS {})",
                    p.effect,
                    num(rms(&before))
                ),
                dots_before,
                BEFORE_COLOUR,
            )
            .with_opacity(0.45),
        )
        .with(
            Series::dots(
                &format!("after: with it (RMS {})", num(rms(&after))),
                dots_after,
                AFTER_COLOUR,
            )
            .with_opacity(0.45),
        )
        .with(Series::line("", medians(&before), BEFORE_COLOUR).with_mark(Mark::Line { width: 3 }))
        .with(Series::line("", medians(&after), AFTER_COLOUR).with_mark(Mark::Line { width: 3 }))
        .describe(&desc)
        .svg()
}

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

/// The range shown of the tracks: the GNSS fixes, and the model tracks a
/// quarter of the fixes' span beyond them at most (a model that runs far
/// off is cut there). `None` without points.
fn track_ranges(t: &TrackPlot) -> Option<((f64, f64), (f64, f64))> {
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
    let [x0, x1, y0, y1] = match (gnss, models) {
        (Some(g), Some(m)) => {
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
    let margin = 0.04 * (x1 - x0).max(y1 - y0).max(1.0);
    Some(((x0 - margin, x1 + margin), (y0 - margin, y1 + margin)))
}

/// The whole drive in metres (east, north; equal scale): per block the GNSS
/// fixes, the plain 2W model and the extended model, each block
/// dead-reckoned from the wheels and laid onto its fixes.
pub fn tracks_svg(t: &TrackPlot) -> Result<String, FigureError> {
    let title = "Blocks dead-reckoned, laid onto GNSS: plain 2W model and extended model";
    let desc = "Each block is dead-reckoned from the wheels alone with the plain 2W model \
                (vermillion) and with the model extended by the accepted effects (blue), each \
                laid onto the block's GNSS fixes (grey dots) by the rigid motion that fits \
                best. Equal scale on both axes. The effect terms are fitted on all blocks \
                here; the held-out figures are in the fit table.";
    let (mut x, mut y) = (Axis::linear("east", "m"), Axis::linear("north", "m"));
    if let Some((xr, yr)) = track_ranges(t) {
        (x.range, y.range) = (Some(xr), Some(yr));
    }
    let (rms_plain, rms_ext) = overall_rmse(t);
    let fixes: Vec<[f64; 2]> = t.blocks.iter().flat_map(|b| b.0.iter().copied()).collect();
    let part = |k: usize| -> Vec<Vec<[f64; 2]>> {
        t.blocks
            .iter()
            .map(|b| if k == 1 { b.1.clone() } else { b.2.clone() })
            .collect()
    };
    Figure::new(title, x, y)
        .with(Series::dots("GNSS fixes", fixes, Colour::GREY).with_opacity(0.6))
        .with(
            Series::lines(
                &format!("plain 2W model (RMSE {} m)", num(rms_plain)),
                part(1),
                BEFORE_COLOUR,
            )
            .with_mark(Mark::Line { width: 2 }),
        )
        .with(
            Series::lines(
                &format!("extended model (RMSE {} m)", num(rms_ext)),
                part(2),
                AFTER_COLOUR,
            )
            .with_mark(Mark::Line { width: 2 }),
        )
        .map((900, 740))
        .describe(desc)
        .svg()
}

/// Per block (x = block index, in time order): the RMS distance of the
/// plain 2W model and of the extended model from the GNSS fixes.
pub fn block_errors_svg(t: &TrackPlot) -> Result<String, FigureError> {
    let title = "Position RMSE per block against GNSS: plain 2W model and extended model";
    let desc = "Per block (in time order): the RMS distance between the GNSS fixes and the \
                block dead-reckoned with the plain 2W model (vermillion) and with the extended \
                model (blue), each laid onto the fixes by the best rigid motion. The effect \
                terms are fitted on all blocks here; the held-out figures are in the fit table.";
    let (rms_plain, rms_ext) = overall_rmse(t);
    let per_block = |k: usize| -> Vec<[f64; 2]> {
        t.blocks
            .iter()
            .enumerate()
            .filter_map(|(i, (g, p, e))| {
                block_rmse(g, if k == 1 { p } else { e }).map(|v| [(i + 1) as f64, v])
            })
            .collect()
    };
    let mut y = Axis::linear("position RMSE", "m");
    let max = per_block(1)
        .iter()
        .chain(&per_block(2))
        .map(|p| p[1])
        .filter(|v| v.is_finite())
        .fold(f64::NAN, f64::max);
    if max.is_finite() {
        y.range = Some((0.0, 1.08 * max.max(1e-6)));
    }
    let marks = Mark::LineAndDots {
        width: 1,
        radius: 4,
    };
    Figure::new(title, Axis::linear("block index", ""), y)
        .with(
            Series::line(
                &format!("plain 2W model (all blocks {} m)", num(rms_plain)),
                per_block(1),
                BEFORE_COLOUR,
            )
            .with_mark(marks),
        )
        .with(
            Series::line(
                &format!("extended model (all blocks {} m)", num(rms_ext)),
                per_block(2),
                AFTER_COLOUR,
            )
            .with_mark(marks),
        )
        .sized((900, 440))
        .describe(desc)
        .svg()
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

/// What the drive could show of each effect: the information limit beside
/// what the held-out test needs.
fn information_section(s: &mut Page, d: &Diagnosis) {
    s.heading("What this drive could show (the information limit)");
    let Some(l) = &d.information_limit else {
        none_para(
            s,
            &format!(
                "Not known: {}",
                d.information_limit_missing
                    .as_deref()
                    .unwrap_or("not computed")
            ),
        );
        return;
    };
    let noise = |n: &[f64; 3]| format!("{:.2} m white + {:.2} m over {:.1} s", n[0], n[1], n[2]);
    let _ = writeln!(
        s,
        "<p>The smallest size of each effect this drive shows with {:.0} % power at a family-wise \
         level of {:.0} % (|z| &gt; {:.2} each), from the Fisher information of its GNSS positions \
         (the heading sensor's for its bias) under the error model refitted with every effect in \
         (east {}, north {}), the sigma raised to the scatter over the {} segments of {:.0} s where \
         that is larger. Sizes are multiples of the catalogue's typical size; the estimate and z \
         are with every other effect of its source free, save those whose sign the physics fixes \
         and whose fit falls below zero: those are held at zero. The power is the decision's \
         test's at the catalogue's typical size, at the strictest critical z of Holm's procedure.</p>",
        100.0 * l.power,
        100.0 * l.family_alpha,
        l.z_critical,
        escape(&noise(&l.noise_east)),
        escape(&noise(&l.noise_north)),
        l.segments,
        l.segment_s
    );
    let times = |v: Option<f64>, typical: f64| {
        v.map_or("-".to_string(), |v| format!("{:.2}x", v / typical))
    };
    let rows: Vec<Vec<(bool, String)>> =
        l.effects
            .iter()
            .map(|e| {
                let joint = e.joint.as_ref();
                let test = d
                    .not_accepted
                    .iter()
                    .find(|n| n.effect == e.effect)
                    .and_then(|n| n.detectable.as_ref())
                    .map_or("-".to_string(), |det| match det.smallest {
                        Some(v) => format!("{:.2}x", v / det.typical),
                        None => "&gt; 64x".to_string(),
                    });
                let estimate = match joint.and_then(|j| Some((j.estimate?, j.sigma?, j.wald_z?))) {
                    Some((v, sg, z)) => format!("{} {} (z {z:.1})", with_sigma(v, sg), e.unit),
                    None => "-".to_string(),
                };
                let verdict = d.wald.iter().find(|w| w.test.effect == e.effect).map_or(
                    "-".to_string(),
                    |w| {
                        format!(
                            "{} (|z| {:.1} against {:.1})",
                            w.outcome.describe(),
                            w.test.z.abs(),
                            w.test.z_critical
                        )
                    },
                );
                vec![
                    (false, format!("<code>{}</code>", escape(e.effect.id()))),
                    (true, times(e.smallest, e.typical)),
                    (true, times(joint.and_then(|j| j.smallest), e.typical)),
                    (
                        true,
                        e.power_at_typical
                            .map_or("-".to_string(), |p| format!("{:.0} %", 100.0 * p)),
                    ),
                    (true, test),
                    (false, escape(&estimate)),
                    (false, escape(&verdict)),
                    (false, escape(e.source.describe())),
                ]
            })
            .collect();
    table(
        s,
        &[
            "effect",
            "shows from (alone)",
            "with every other effect free",
            "a typical one shown (power)",
            "the held-out test needs",
            "estimate ± sigma",
            "Holm's procedure",
            "from",
        ],
        &rows,
    );
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

    information_section(&mut s, d);

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

    /// The text of every `<text>` element, trimmed.
    fn texts(svg: &str) -> Vec<String> {
        svg.split("<text")
            .skip(1)
            .filter_map(|t| {
                let a = t.find('>')? + 1;
                let b = t.find("</text>")?;
                Some(t[a..b].trim().to_string())
            })
            .collect()
    }

    #[test]
    fn numbers_read_well() {
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
        let svg = residual_svg(&plot(10_000)).expect("drawn");
        assert_well_formed(&svg);
        let t = texts(&svg);
        for text in [
            "side_slip: residual against lateral acceleration a_y, m/s^2",
            "lateral acceleration a_y, m/s^2",
            "course_wheel residual, rad &lt;test&gt;",
        ] {
            assert!(t.iter().any(|s| s == text), "no `{text}` in {t:?}");
        }
        assert!(!svg.contains("<test>"));
        assert!(t
            .iter()
            .any(|s| s.starts_with("before: without the side_slip term")));
        assert!(t.iter().any(|s| s.starts_with("after: with it")));
        assert!(
            svg.contains("Outside it, not drawn"),
            "the caption counts the outliers"
        );
        // Subsampled to at most 3000 per series.
        assert!(svg.matches("<circle").count() <= 2 * MAX_SERIES_POINTS + 2);
        assert!(svg.len() < 250_000, "{} bytes", svg.len());
        // The outliers (1.0) do not set the y range: the y ticks (right-aligned)
        // stay near the trend's few hundredths.
        let y_ticks: Vec<f64> = svg
            .split("<text")
            .filter(|t| t.contains("text-anchor=\"end\""))
            .filter_map(|t| {
                let a = t.find('>')? + 1;
                t[a..t.find("</text>")?].trim().parse().ok()
            })
            .collect();
        assert!(y_ticks.len() >= 3, "{y_ticks:?}");
        assert!(y_ticks.iter().all(|v| v.abs() < 0.1), "{y_ticks:?}");
    }

    #[test]
    fn residual_svg_degenerate_inputs() {
        let empty = residual_svg(&ResidualPlot::default()).expect("drawn");
        assert_well_formed(&empty);
        assert!(empty.contains("no data"));
        let mut one = plot(1);
        one.points = vec![(2.0, 0.0, 0.0)];
        assert_well_formed(&residual_svg(&one).expect("drawn"));
        let mut bad = plot(3);
        bad.points = vec![(f64::NAN, 1.0, 1.0), (1.0, f64::INFINITY, 0.5)];
        assert_well_formed(&residual_svg(&bad).expect("drawn"));
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
    fn tracks_svg_has_axes_legend_and_keeps_the_fixes_in_view() {
        let t = track(8, 3.0, 0.5);
        let svg = tracks_svg(&t).expect("drawn");
        assert_well_formed(&svg);
        let texts = texts(&svg);
        for label in [
            "Blocks dead-reckoned, laid onto GNSS: plain 2W model and extended model",
            "east, m",
            "north, m",
            "GNSS fixes",
            "plain 2W model (RMSE 3.00 m)",
            "extended model (RMSE 0.500 m)",
        ] {
            assert!(
                texts.iter().any(|s| s == label),
                "no `{label}` in {texts:?}"
            );
        }
        // A model that runs far off does not push the fixes into a corner.
        let mut far = track(2, 0.0, 0.0);
        far.blocks[1].1 = vec![[1e6, 1e6]];
        let ((x0, x1), _) = track_ranges(&far).expect("ranges");
        assert!(x1 - x0 < 1000.0, "{x0}..{x1}");
        let empty = tracks_svg(&TrackPlot::default()).expect("drawn");
        assert_well_formed(&empty);
        assert!(empty.contains("no data"));
    }

    #[test]
    fn block_errors_svg_shows_rmse_per_block() {
        let t = track(5, 3.0, 0.5);
        let svg = block_errors_svg(&t).expect("drawn");
        assert_well_formed(&svg);
        assert!(svg.contains("position RMSE, m"));
        assert!(svg.contains("block index"));
        assert!(svg.contains("plain 2W model") && svg.contains("extended model"));
        assert_eq!(svg.matches("<circle").count(), 10, "two dots per block");
        assert_eq!(block_rmse(&t.blocks[0].0, &t.blocks[0].1), Some(3.0));
        let empty = block_errors_svg(&TrackPlot::default()).expect("drawn");
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
            warnings: Vec::new(),
            findings,
            ambiguous: Vec::new(),
            unexplained: Vec::new(),
            mismatch_segments: Vec::new(),
            information_limit: None,
            information_limit_missing: None,
            wald: Vec::new(),
            null_false_alarm: None,
            information: None,
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
            blocks: Vec::new(),
            channels: Vec::new(),
            fingerprints: Vec::new(),
            yaw_wander: None,
        }
    }

    fn finding(effect: Effect, evidence: &str) -> Finding {
        Finding {
            effect,
            variant: String::new(),
            parameters: BTreeMap::from([("k".to_string(), 0.0041)]),
            sigmas: BTreeMap::from([("k".to_string(), 0.0003)]),
            form_sigmas: BTreeMap::new(),
            reading_sigmas: BTreeMap::new(),
            units: BTreeMap::from([("k".to_string(), "rad/(m/s^2)".to_string())]),
            holdout_rmse_before_m: 3.2,
            holdout_rmse_after_m: 1.1,
            holdout_channel_gain: 0.4,
            holdout_gain_z: 7.5,
            decided_by: super::super::DecidedBy::HeldOut,
            wald_z: None,
            evidence: evidence.to_string(),
            partners: Vec::new(),
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
        let svg = residual_svg(&plot(200)).expect("drawn");
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
