//! The evaluation page: one self-contained HTML document (the `report`
//! library's page) with the score, the warnings in plain words, the
//! parameters, the figures (the position error through each outage, the
//! error at each outage end, the track) and the table of the outages.
//! Pure: an [`EvaluationReport`] made with `keep_tracks` and the truth track
//! in, SVG and HTML text out; the binary writes the files.

use crate::evaluate::{percentile, EvaluationReport};
use report::{Axis, Band, Cell, Colour, Figure, FigureError, Mark, Page, Series};

/// Points in time along an outage at which the spread over the outages is
/// drawn.
const SPREAD_POINTS: usize = 61;

/// A figure of the evaluation page: file name, heading, SVG, caption.
#[derive(Debug, Clone, PartialEq)]
pub struct EvaluationFigure {
    /// File name (`outage_errors.svg`, ...).
    pub file: &'static str,
    /// Heading on the page.
    pub name: String,
    /// The SVG document.
    pub svg: String,
    /// What it shows.
    pub caption: String,
}

/// Position error against time since the outage's start, per outage.
fn error_curves(r: &EvaluationReport) -> Vec<Vec<[f64; 2]>> {
    r.outages
        .iter()
        .map(|o| {
            o.track
                .iter()
                .map(|p| {
                    [
                        p.t_s - o.t_start_s,
                        (p.dead_reckoned_m[0] - p.truth_m[0])
                            .hypot(p.dead_reckoned_m[1] - p.truth_m[1]),
                    ]
                })
                .collect()
        })
        .collect()
}

/// `curve` (time-ordered) read at `t` by linear interpolation.
fn at(curve: &[[f64; 2]], t: f64) -> Option<f64> {
    let i = curve.partition_point(|p| p[0] < t);
    match (i.checked_sub(1).and_then(|j| curve.get(j)), curve.get(i)) {
        (_, Some(b)) if b[0] == t => Some(b[1]),
        (Some(a), Some(b)) if b[0] > a[0] => {
            Some(a[1] + (t - a[0]) / (b[0] - a[0]) * (b[1] - a[1]))
        }
        _ => None,
    }
}

/// The figures of the evaluation page. `truth`: the truth track (east,
/// north), m.
pub fn figures(
    r: &EvaluationReport,
    truth: &[[f64; 2]],
) -> Result<Vec<EvaluationFigure>, FigureError> {
    Ok(vec![
        EvaluationFigure {
            file: "outage_errors.svg",
            name: "Position error through each outage".to_string(),
            svg: outage_errors_svg(r)?,
            caption: format!(
                "The distance between the dead-reckoned and the true position of the scored \
                 point inside each of the {} outages (read from the truth rows every 1/{} of the \
                 outage), against the time since the outage's start (the pose taken from the \
                 truth there). Black: the median \
                 over the outages at each time; the band holds the middle 80 % of them. The \
                 dead-reckoning gives no sigma of its own, so the band is the outages' spread, \
                 not a predicted uncertainty.",
                r.outages.len(),
                SPREAD_POINTS - 1
            ),
        },
        EvaluationFigure {
            file: "outage_end_errors.svg",
            name: "Error at each outage's end".to_string(),
            svg: end_errors_svg(r)?,
            caption: "The score of every outage (its position error at the end) at its start \
                      time: a run of large errors points at a stretch of the drive the model \
                      does not carry (slip, a wrong gyro bias, a truth jump)."
                .to_string(),
        },
        EvaluationFigure {
            file: "track.svg",
            name: "Track".to_string(),
            svg: track_svg(r, truth)?,
            caption: "The truth and every outage's dead-reckoned track, at equal scale on both \
                      axes."
                .to_string(),
        },
    ])
}

/// The position error through each outage, against the time since its
/// start: every outage, their median and their 10-90 % band.
fn outage_errors_svg(r: &EvaluationReport) -> Result<String, FigureError> {
    let curves = error_curves(r);
    let length = r.outages.iter().map(|o| o.length_s).fold(0.0, f64::max);
    let (median, band) = spread(&curves, length);
    let mut errors = Figure::new(
        "Position error through each outage",
        Axis::linear("time since the outage start", "s"),
        Axis::linear("position error", "m"),
    )
    .with_band(Band {
        label: "10 - 90 % of the outages".to_string(),
        points: band,
        colour: Colour::BLUE,
    });
    // Each outage read at the same times as the spread (a 1 h drive has
    // hundreds of outages of thousands of truth rows each).
    let sampled: Vec<Vec<[f64; 2]>> = curves
        .iter()
        .map(|c| {
            (0..SPREAD_POINTS)
                .filter_map(|i| {
                    let t = length * i as f64 / (SPREAD_POINTS - 1) as f64;
                    at(c, t).map(|e| [t, e])
                })
                .collect()
        })
        .collect();
    errors = errors.with(
        Series::lines("each outage", sampled, Colour::BLUE)
            .with_mark(Mark::Line { width: 1 })
            .with_opacity(0.35),
    );
    errors
        .with(Series::line(
            "median over the outages",
            median,
            Colour::BLACK,
        ))
        .svg()
}

/// The median `[t, error]` and the 10-90 % band `[t, lo, hi]` of the
/// error `curves` at [`SPREAD_POINTS`] times over `length` s, where at
/// least three outages last.
fn spread(curves: &[Vec<[f64; 2]>], length: f64) -> (Vec<[f64; 2]>, Vec<[f64; 3]>) {
    let mut median = Vec::new();
    let mut band = Vec::new();
    for i in 0..SPREAD_POINTS {
        let t = length * i as f64 / (SPREAD_POINTS - 1) as f64;
        let v: Vec<f64> = curves.iter().filter_map(|c| at(c, t)).collect();
        if v.len() >= 3 {
            if let (Some(m), Some(lo), Some(hi)) = (
                percentile(&v, 0.5),
                percentile(&v, 0.1),
                percentile(&v, 0.9),
            ) {
                median.push([t, m]);
                band.push([t, lo, hi]);
            }
        }
    }
    (median, band)
}

/// The error at each outage's end against its start time, with the median.
fn end_errors_svg(r: &EvaluationReport) -> Result<String, FigureError> {
    let t0 = r.outages.first().map_or(0.0, |o| o.t_start_s);
    let ends: Vec<[f64; 2]> = r
        .outages
        .iter()
        .map(|o| [o.t_start_s - t0, o.error_m])
        .collect();
    Figure::new(
        "Error at each outage's end, along the drive",
        Axis::linear("outage start, time since the first outage", "s"),
        Axis::linear("position error at the outage end", "m"),
    )
    .with(Series::dots("outage", ends, Colour::BLUE).with_mark(Mark::Dots { radius: 3 }))
    .with(Series::line(
        &format!("median {:.3} m", r.median_error_m),
        if r.outages.is_empty() {
            Vec::new()
        } else {
            let last = r.outages.last().map_or(0.0, |o| o.t_start_s - t0);
            vec![[0.0, r.median_error_m], [last, r.median_error_m]]
        },
        Colour::BLACK,
    ))
    .svg()
}

/// The truth track and every outage's dead-reckoned track.
fn track_svg(r: &EvaluationReport, truth: &[[f64; 2]]) -> Result<String, FigureError> {
    let tracks: Vec<Vec<[f64; 2]>> = r
        .outages
        .iter()
        .map(|o| o.track.iter().map(|p| p.dead_reckoned_m).collect())
        .collect();
    Figure::new(
        "Track: dead-reckoned outages on the truth",
        Axis::linear("east", "m"),
        Axis::linear("north", "m"),
    )
    .with(Series::line("truth", truth.to_vec(), Colour::BLACK))
    .with(
        Series::lines(
            "dead-reckoned through an outage",
            tracks,
            Colour::VERMILLION,
        )
        .with_mark(Mark::Line { width: 1 })
        .with_opacity(0.7),
    )
    .map((900, 800))
    .svg()
}

/// The page of evaluation `r` of the drive named `drive`, with the
/// parameters from `source` and `figures`.
pub fn evaluation_html(
    r: &EvaluationReport,
    drive: &str,
    source: &str,
    figures: &[EvaluationFigure],
) -> String {
    let mut page = Page::new(&format!("Dead-reckoning evaluation of {drive}"));
    let length = r.outages.first().map_or(0.0, |o| o.length_s);
    page.headline(
        &format!(
            "Median position error {:.3} m after {length:.0} s without GNSS, 90th percentile \
             {:.3} m{}, over {} outages.",
            r.median_error_m,
            r.p90_error_m,
            r.median_error_pct.map_or(String::new(), |p| format!(
                "; median {p:.2} % of the distance"
            )),
            r.outages.len()
        ),
        None,
    );
    page.note(&format!(
        "Parameters: {source}. Heading from the {}.",
        if r.heading == "gyro" {
            "gyro"
        } else {
            "wheel difference"
        }
    ));
    page.heading("Warnings");
    page.warnings(&r.warnings, "None: every outage was scored.");
    page.heading("Numbers");
    let p = &r.params;
    page.numbers(&[
        (
            "median position error, m".to_string(),
            format!("{:.3}", r.median_error_m),
        ),
        (
            "90th percentile, m".to_string(),
            format!("{:.3}", r.p90_error_m),
        ),
        (
            "median error, % of the distance".to_string(),
            r.median_error_pct
                .map_or("not determined".to_string(), |v| format!("{v:.2}")),
        ),
        ("outages".to_string(), r.outages.len().to_string()),
        ("outage length, s".to_string(), format!("{length:.1}")),
        ("c_RL, m".to_string(), format!("{:.5}", p.c_rl_m)),
        ("c_RR, m".to_string(), format!("{:.5}", p.c_rr_m)),
        (
            "track width, m".to_string(),
            format!("{:.4}", p.track_width_m),
        ),
        (
            "gyro bias, deg/h".to_string(),
            format!("{:+.1}", p.gyro_bias_rad_s.to_degrees() * 3600.0),
        ),
        (
            "gyro scale error".to_string(),
            format!("{:+.5}", p.gyro_scale),
        ),
        (
            "scored point (x forward, y left of the rear-axle centre), m".to_string(),
            format!(
                "({:+.3}, {:+.3})",
                r.truth_point.point_m[0], r.truth_point.point_m[1]
            ),
        ),
    ]);
    page.heading("Figures");
    for f in figures {
        page.figure(&f.name, &f.svg, &f.caption);
    }
    page.heading("Outages");
    let rows: Vec<Vec<Cell>> = r
        .outages
        .iter()
        .map(|o| {
            vec![
                Cell::Number(format!("{:.2}", o.t_start_s)),
                Cell::Number(format!("{:.1}", o.length_s)),
                Cell::Number(format!("{:.1}", o.distance_m)),
                Cell::Number(format!("{:.3}", o.error_m)),
                Cell::Number(o.error_pct.map_or("-".to_string(), |v| format!("{v:.2}"))),
                Cell::Text(o.start_yaw_source.to_string()),
            ]
        })
        .collect();
    page.table(
        &[
            "start, s",
            "length, s",
            "distance, m",
            "error, m",
            "error, %",
            "start pose from",
        ],
        &rows,
    );
    page.render()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_curve_is_read_between_its_points_and_not_outside() {
        let c = [[0.0, 0.0], [1.0, 2.0], [3.0, 4.0]];
        assert_eq!(at(&c, 0.5), Some(1.0));
        assert_eq!(at(&c, 2.0), Some(3.0));
        assert_eq!(at(&c, 0.0), Some(0.0));
        assert_eq!(at(&c, 3.5), None);
        assert_eq!(at(&c, -0.1), None);
    }
}
