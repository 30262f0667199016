//! SVG pictures of a calibration, written by hand (no dependency): the track
//! with the reference and the 2W model before and after (the paper's Fig. 7)
//! and the dead-reckoning deviation per iteration (Fig. 6). Pure: the
//! functions return the SVG text; the binary writes the files.

use crate::result::Calibration;
use std::fmt::Write as _;

const W: f64 = 900.0;
const H: f64 = 700.0;
const MARGIN: f64 = 60.0;

fn polyline(
    points: &[[f64; 2]],
    map: &dyn Fn([f64; 2]) -> (f64, f64),
    colour: &str,
    width: f64,
) -> String {
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<polyline fill="none" stroke="{colour}" stroke-width="{width}" points=""#
    );
    for p in points
        .iter()
        .filter(|p| p[0].is_finite() && p[1].is_finite())
    {
        let (x, y) = map(*p);
        let _ = write!(s, "{x:.1},{y:.1} ");
    }
    s.push_str("\"/>\n");
    s
}

fn legend(items: &[(&str, &str)]) -> String {
    let mut s = String::new();
    for (i, (label, colour)) in items.iter().enumerate() {
        let y = MARGIN + 18.0 * i as f64;
        let _ = writeln!(
            s,
            r#"<line x1="{:.0}" y1="{y:.0}" x2="{:.0}" y2="{y:.0}" stroke="{colour}" stroke-width="3"/><text x="{:.0}" y="{:.0}" font-size="13" font-family="sans-serif">{label}</text>"#,
            W - 260.0,
            W - 230.0,
            W - 222.0,
            y + 4.0
        );
    }
    s
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The track: GNSS fixes, reference, 2W dead-reckoning with the nominal and
/// with the estimated values (equal scale on both axes, metres).
pub fn track_svg(c: &Calibration) -> String {
    let t = &c.tracks;
    let all = t.reference.iter().chain(&t.after).chain(&t.gnss);
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in all.filter(|p| p[0].is_finite() && p[1].is_finite()) {
        x0 = x0.min(p[0]);
        x1 = x1.max(p[0]);
        y0 = y0.min(p[1]);
        y1 = y1.max(p[1]);
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    let span = (x1 - x0).max(y1 - y0).max(1.0);
    let scale = ((W - 2.0 * MARGIN) / span).min((H - 2.0 * MARGIN) / span);
    let map = move |p: [f64; 2]| {
        (
            MARGIN + (p[0] - x0) * scale,
            H - MARGIN - (p[1] - y0) * scale,
        )
    };
    // The nominal track may run far away: clip it to a generous box.
    let clip = |v: &[[f64; 2]]| -> Vec<[f64; 2]> {
        v.iter()
            .copied()
            .filter(|p| {
                p[0] > x0 - span && p[0] < x1 + span && p[1] > y0 - span && p[1] < y1 + span
            })
            .collect()
    };
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}"><rect width="100%" height="100%" fill="white"/>"#
    );
    let _ = writeln!(
        s,
        r#"<text x="{MARGIN}" y="30" font-size="16" font-family="sans-serif">Track ({} method): c_RL = {:.4} m, c_RR = {:.4} m</text>"#,
        c.method, c.circumference_m.rl, c.circumference_m.rr
    );
    for p in &t.gnss {
        let (x, y) = map(*p);
        let _ = writeln!(
            s,
            r##"<circle cx="{x:.1}" cy="{y:.1}" r="1.2" fill="#bbbbbb"/>"##
        );
    }
    s.push_str(&polyline(&t.reference, &map, "black", 2.0));
    s.push_str(&polyline(&clip(&t.before), &map, "#d62728", 1.5));
    s.push_str(&polyline(&t.after, &map, "#1f77b4", 1.5));
    s.push_str(&legend(&[
        ("GNSS fixes", "#bbbbbb"),
        ("reference", "black"),
        ("2W model, nominal", "#d62728"),
        ("2W model, estimated", "#1f77b4"),
    ]));
    let bar = 10f64.powf((span / 5.0).log10().floor());
    let _ = writeln!(
        s,
        r#"<line x1="{MARGIN}" y1="{:.0}" x2="{:.1}" y2="{:.0}" stroke="black" stroke-width="2"/><text x="{MARGIN}" y="{:.0}" font-size="12" font-family="sans-serif">{bar} m</text>"#,
        H - 25.0,
        MARGIN + bar * scale,
        H - 25.0,
        H - 10.0
    );
    s.push_str("</svg>\n");
    s
}

/// Mean and max dead-reckoning deviation per iteration, with the
/// circumferences (the paper's Fig. 6).
pub fn iterations_svg(c: &Calibration) -> String {
    let it = &c.iterations;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}"><rect width="100%" height="100%" fill="white"/>"#
    );
    let _ = writeln!(
        s,
        r#"<text x="{MARGIN}" y="30" font-size="16" font-family="sans-serif">{}</text>"#,
        escape(&format!("Iterations ({} method): circumferences (top), DR deviation from the reference (bottom)", c.method))
    );
    if it.is_empty() {
        s.push_str("</svg>\n");
        return s;
    }
    let n_max = it.iter().map(|i| i.n).max().unwrap_or(1).max(1) as f64;
    let x_of = |n: usize| MARGIN + (W - 2.0 * MARGIN) * n as f64 / n_max;
    let panel = |top: f64,
                 bottom: f64,
                 series: &[(&str, &str, Vec<f64>)],
                 unit: &str,
                 s: &mut String| {
        let vals: Vec<f64> = series
            .iter()
            .flat_map(|x| x.2.iter().copied())
            .filter(|v| v.is_finite())
            .collect();
        let (lo, hi) = vals
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(*v), b.max(*v)));
        let (lo, hi) = if lo < hi {
            (lo, hi)
        } else {
            (lo - 1.0, hi + 1.0)
        };
        let y_of = |v: f64| bottom - (bottom - top) * (v - lo) / (hi - lo);
        let _ = writeln!(
            s,
            r##"<rect x="{MARGIN}" y="{top}" width="{}" height="{}" fill="none" stroke="#888"/>"##,
            W - 2.0 * MARGIN,
            bottom - top
        );
        let _ = writeln!(
            s,
            r#"<text x="5" y="{:.0}" font-size="11" font-family="sans-serif">{hi:.4}</text><text x="5" y="{bottom:.0}" font-size="11" font-family="sans-serif">{lo:.4}</text><text x="5" y="{:.0}" font-size="11" font-family="sans-serif">{unit}</text>"#,
            top + 10.0,
            0.5 * (top + bottom)
        );
        for (label, colour, v) in series {
            let pts: Vec<[f64; 2]> = it
                .iter()
                .zip(v)
                .map(|(i, v)| [x_of(i.n), y_of(*v)])
                .collect();
            s.push_str(&polyline(&pts, &|p| (p[0], p[1]), colour, 2.0));
            for p in &pts {
                let _ = writeln!(
                    s,
                    r#"<circle cx="{:.1}" cy="{:.1}" r="3" fill="{colour}"/>"#,
                    p[0], p[1]
                );
            }
            let _ = label;
        }
    };
    let top_series = [
        (
            "c_RL",
            "#1f77b4",
            it.iter().map(|i| i.circumference_m.rl).collect(),
        ),
        (
            "c_RR",
            "#d62728",
            it.iter().map(|i| i.circumference_m.rr).collect(),
        ),
    ];
    panel(60.0, 320.0, &top_series, "m", &mut s);
    let bottom_series = [
        (
            "mean",
            "#2ca02c",
            it.iter().map(|i| i.dr_error_mean_m).collect(),
        ),
        (
            "max",
            "#ff7f0e",
            it.iter().map(|i| i.dr_error_max_m).collect(),
        ),
    ];
    panel(360.0, 640.0, &bottom_series, "m", &mut s);
    let x = x_of(c.selected_iteration);
    let _ = writeln!(
        s,
        r#"<line x1="{x:.1}" y1="60" x2="{x:.1}" y2="640" stroke="black" stroke-dasharray="4 4"/>"#
    );
    for i in it {
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="660" font-size="11" font-family="sans-serif" text-anchor="middle">{}</text>"#,
            x_of(i.n),
            i.n
        );
    }
    s.push_str(&legend(&[
        ("c_RL", "#1f77b4"),
        ("c_RR", "#d62728"),
        ("DR deviation, mean", "#2ca02c"),
        ("DR deviation, max", "#ff7f0e"),
    ]));
    s.push_str("</svg>\n");
    s
}
