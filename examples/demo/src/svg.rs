//! A picture of the demo's tracks (plain SVG, no dependency).
//!
//! Truth in grey, GNSS fixes in green, the live odometry in blue (fused) and
//! red (dead-reckoning), and through the outage the same-start dead-reckoning
//! with the nominal (orange) and the calibrated (purple) circumferences.

use super::report::OutageReport;
use interfaces::drive::Drive;
use interfaces::wire::{Pose, PoseMode};
use std::fmt::Write as _;

const W: f64 = 1000.0;
const H: f64 = 800.0;
const MARGIN: f64 = 40.0;
const TOP: f64 = 90.0;

struct Frame {
    x0: f64,
    y1: f64,
    scale: f64,
    height: f64,
}

impl Frame {
    fn fit(points: impl Iterator<Item = [f64; 2]>) -> Frame {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for [x, y] in points {
            if x.is_finite() && y.is_finite() {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
        if x0 > x1 {
            (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
        }
        let scale =
            ((W - 2.0 * MARGIN) / (x1 - x0).max(1.0)).min((H - TOP - MARGIN) / (y1 - y0).max(1.0));
        let height = TOP + (y1 - y0) * scale + MARGIN;
        Frame {
            x0,
            y1,
            scale,
            height,
        }
    }

    fn px(&self, [x, y]: [f64; 2]) -> (f64, f64) {
        (
            MARGIN + (x - self.x0) * self.scale,
            TOP + (self.y1 - y) * self.scale,
        )
    }
}

fn polyline(out: &mut String, f: &Frame, pts: &[[f64; 2]], style: &str) {
    if pts.len() < 2 {
        return;
    }
    let mut d = String::new();
    for p in pts {
        let (x, y) = f.px(*p);
        let _ = write!(d, "{x:.1},{y:.1} ");
    }
    let _ = writeln!(
        out,
        r#"<polyline fill="none" {style} points="{}"/>"#,
        d.trim_end()
    );
}

/// The SVG text.
pub fn tracks_svg(
    drive: &Drive,
    outage: (f64, f64),
    poses: &[Pose],
    report: &OutageReport,
) -> String {
    let truth: Vec<[f64; 2]> = drive
        .truth
        .as_deref()
        .unwrap_or_default()
        .iter()
        .step_by(10)
        .map(|s| [s.x_m, s.y_m])
        .collect();
    let frame = Frame::fit(
        truth
            .iter()
            .copied()
            .chain(poses.iter().map(|p| [p.x_m, p.y_m])),
    );
    let mut out = String::new();
    let h = frame.height.round();
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{h}" viewBox="0 0 {W} {h}" font-family="sans-serif" font-size="13">"#
    );
    let _ = writeln!(out, r#"<rect width="100%" height="100%" fill="white"/>"#);
    polyline(
        &mut out,
        &frame,
        &truth,
        r##"stroke="#999" stroke-width="4" stroke-opacity="0.5""##,
    );
    if let Some(g) = &drive.gnss {
        for f in g.iter().step_by(5) {
            let (x, y) = frame.px([f.x_m, f.y_m]);
            let _ = writeln!(
                out,
                r##"<circle cx="{x:.1}" cy="{y:.1}" r="1.2" fill="#2a2"/>"##
            );
        }
    }
    // Live poses, split into runs of one mode (NoFix poses carry no
    // position and are left out); dead-reckoning drawn last, on top.
    let dr = PoseMode::DeadReckoning as u8;
    let mut runs: Vec<(u8, Vec<[f64; 2]>)> = Vec::new();
    for p in poses.iter().step_by(5) {
        if p.mode == PoseMode::NoFix as u8 {
            continue;
        }
        match runs.last_mut() {
            Some((mode, pts)) if *mode == p.mode => pts.push([p.x_m, p.y_m]),
            last => {
                let joint = last.and_then(|(_, pts)| pts.last().copied());
                let mut pts: Vec<[f64; 2]> = joint.into_iter().collect();
                pts.push([p.x_m, p.y_m]);
                runs.push((p.mode, pts));
            }
        }
    }
    for top in [false, true] {
        for (mode, pts) in runs.iter().filter(|(m, _)| (*m == dr) == top) {
            let color = if *mode == dr { "#d22" } else { "#24c" };
            let width = if *mode == dr { "2.5" } else { "1.5" };
            polyline(
                &mut out,
                &frame,
                pts,
                &format!(r#"stroke="{color}" stroke-width="{width}""#),
            );
        }
    }
    polyline(
        &mut out,
        &frame,
        &report.tracks[0],
        r##"stroke="#f80" stroke-width="2" stroke-dasharray="6 3""##,
    );
    polyline(
        &mut out,
        &frame,
        &report.tracks[1],
        r##"stroke="#819" stroke-width="2" stroke-dasharray="2 2""##,
    );
    for t in [outage.0, outage.1] {
        if let Some((x, y)) = super::report::truth_at(drive.truth.as_deref().unwrap_or_default(), t)
        {
            let (px, py) = frame.px([x, y]);
            let _ = writeln!(
                out,
                r#"<circle cx="{px:.1}" cy="{py:.1}" r="5" fill="none" stroke="black"/>"#
            );
        }
    }
    let nominal = report.filter.first().map(|r| r.end_error_m);
    let numbers = format!(
        "odometry error at the outage end: nominal c {}, calibrated c {} (live)",
        nominal.map_or("-".to_string(), |e| format!("{e:.1} m")),
        report
            .live
            .map_or("-".to_string(), |l| format!("{:.1} m", l.end_error_m))
    );
    let _ = writeln!(
        out,
        r#"<text x="{MARGIN}" y="24" font-size="14">wheelcal demo: {:.0} s GNSS outage ({:.0} m). {numbers}</text>"#,
        outage.1 - outage.0,
        report.outage_distance_m
    );
    let legend = [
        ("#999", "truth"),
        ("#2a2", "GNSS fixes"),
        ("#24c", "odometry, fused"),
        ("#d22", "odometry, DR"),
        ("#f80", "pure DR, nominal c"),
        ("#819", "pure DR, calibrated c"),
    ];
    for (i, (color, label)) in legend.iter().enumerate() {
        let x = MARGIN + 158.0 * i as f64;
        let _ = writeln!(
            out,
            r#"<rect x="{x}" y="44" width="14" height="4" fill="{color}"/><text x="{}" y="52">{label}</text>"#,
            x + 18.0
        );
    }
    let _ = writeln!(out, "</svg>");
    out
}
