//! A picture of the demo's tracks, drawn by the report library (axes in
//! metres at equal scale, a legend).
//!
//! Truth in grey, GNSS fixes in green, the live odometry in blue (fused) and
//! vermillion (dead-reckoning), and through the outage the same-start
//! dead-reckoning with the nominal (orange) and the calibrated (purple)
//! circumferences; the outage's ends circled in black.

use super::report::OutageReport;
use ::report::{Axis, Colour, Figure, FigureError, Mark, Series};
use interfaces::drive::Drive;
use interfaces::wire::{Pose, PoseMode};

/// The SVG text.
pub fn tracks_svg(
    drive: &Drive,
    outage: (f64, f64),
    poses: &[Pose],
    report: &OutageReport,
) -> Result<String, FigureError> {
    let truth_rows = drive.truth.as_deref().unwrap_or_default();
    let truth: Vec<[f64; 2]> = truth_rows
        .iter()
        .step_by(10)
        .map(|s| [s.x_m, s.y_m])
        .collect();
    let fixes: Vec<[f64; 2]> = drive
        .gnss
        .as_deref()
        .unwrap_or_default()
        .iter()
        .step_by(5)
        .map(|f| [f.x_m, f.y_m])
        .collect();
    // Live poses, split into runs of one mode (NoFix poses carry no
    // position and are left out), each run joined to the one before.
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
    let (dr_runs, fused_runs): (Vec<_>, Vec<_>) = runs.into_iter().partition(|(m, _)| *m == dr);
    let ends: Vec<[f64; 2]> = [outage.0, outage.1]
        .into_iter()
        .filter_map(|t| super::report::truth_at(truth_rows, t).map(|(x, y)| [x, y]))
        .collect();
    let nominal = report.filter.first().map(|r| r.end_error_m);
    let title = format!(
        "wheelcal demo: {:.0} s GNSS outage ({:.0} m); error at its end: nominal c {}, calibrated c {} (live)",
        outage.1 - outage.0,
        report.outage_distance_m,
        nominal.map_or("-".to_string(), |e| format!("{e:.1} m")),
        report
            .live
            .map_or("-".to_string(), |l| format!("{:.1} m", l.end_error_m))
    );
    Figure::new(
        &title,
        Axis::linear("east", "m"),
        Axis::linear("north", "m"),
    )
    .map((1000, 800))
    .describe(
        "The drive's tracks in the local east-north frame at equal scale; the GNSS outage's \
             start and end are circled.",
    )
    .with(
        Series::line("truth", truth, Colour::GREY)
            .with_mark(Mark::Line { width: 4 })
            .with_opacity(0.5),
    )
    .with(Series::dots("GNSS fixes", fixes, Colour::GREEN).with_mark(Mark::Dots { radius: 1 }))
    .with(Series::lines(
        "odometry, fused",
        fused_runs.into_iter().map(|(_, p)| p).collect(),
        Colour::BLUE,
    ))
    .with(
        Series::lines(
            "odometry, dead-reckoning",
            dr_runs.into_iter().map(|(_, p)| p).collect(),
            Colour::VERMILLION,
        )
        .with_mark(Mark::Line { width: 3 }),
    )
    .with(
        Series::line(
            "pure DR, nominal c",
            report.tracks[0].clone(),
            Colour::ORANGE,
        )
        .with_mark(Mark::Line { width: 2 }),
    )
    .with(
        Series::line(
            "pure DR, calibrated c",
            report.tracks[1].clone(),
            Colour::PURPLE,
        )
        .with_mark(Mark::Line { width: 2 }),
    )
    .with(
        Series::dots("outage start and end", ends, Colour::BLACK)
            .with_mark(Mark::Dots { radius: 5 }),
    )
    .svg()
}
