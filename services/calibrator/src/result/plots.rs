//! The figures of a calibration, drawn by the [`report`] library: the GNSS
//! residuals over time, the track of the model the estimate came from
//! against the reference, the wheel-speed ratio against the turn rate, and
//! the iterations. Pure: the functions return SVG text; the binary writes
//! the files.

use crate::result::Calibration;
use report::{Axis, Band, Colour, Figure, FigureError, Mark, Series};

/// A figure of the calibration page: its file name, heading, SVG and
/// caption.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedFigure {
    /// File name (`residuals.svg`, ...).
    pub file: &'static str,
    /// Heading on the page.
    pub name: String,
    /// The SVG document.
    pub svg: String,
    /// What it shows and how to read it.
    pub caption: String,
}

/// Every figure of the calibration page, in page order.
pub fn figures(c: &Calibration) -> Result<Vec<NamedFigure>, FigureError> {
    Ok(vec![
        residuals(c)?,
        track(c)?,
        wheel_ratio(c)?,
        iteration_errors(c)?,
        iteration_circumferences(c)?,
    ])
}

fn model_name(c: &Calibration) -> &'static str {
    if c.tracks.model_fitted {
        "the fitted 2W model"
    } else {
        "the 2W model with the estimate"
    }
}

fn segments_text(c: &Calibration) -> String {
    if c.tracks.model_fitted {
        "each segment of the batch fit dead-reckoned from its fitted initial pose".to_string()
    } else {
        "each segment (as long as the batch fit's) dead-reckoned from the reference pose at its start"
            .to_string()
    }
}

/// The GNSS residuals of the model over time.
pub fn residuals(c: &Calibration) -> Result<NamedFigure, FigureError> {
    let t0 = c.tracks.start_s;
    let r = &c.tracks.model.residuals;
    let east: Vec<[f64; 2]> = r.iter().map(|v| [v[0] - t0, v[1]]).collect();
    let north: Vec<[f64; 2]> = r.iter().map(|v| [v[0] - t0, v[2]]).collect();
    let sigma = c.diagnostics.gnss_sigma_m;
    let (a, b) = r
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v[0] - t0), b.max(v[0] - t0))
        });
    let mut fig = Figure::new(
        &format!("GNSS residuals of {}", model_name(c)),
        Axis::linear("time since the start of the drive", "s"),
        Axis::linear("GNSS fix minus model (antenna)", "m"),
    );
    if a < b {
        fig = fig.with_band(Band {
            label: format!("±2 sigma of a fix ({:.2} m)", 2.0 * sigma),
            points: vec![
                [a, -2.0 * sigma, 2.0 * sigma],
                [b, -2.0 * sigma, 2.0 * sigma],
            ],
            colour: Colour::GREY,
        });
    }
    let svg = fig
        .with(Series::dots("east", east, Colour::BLUE).with_mark(Mark::Dots { radius: 1 }))
        .with(Series::dots("north", north, Colour::VERMILLION).with_mark(Mark::Dots { radius: 1 }))
        .svg()?;
    let rms = c.tracks.model.residual_rms_m();
    Ok(NamedFigure {
        file: "residuals.svg",
        name: "GNSS residuals over time".to_string(),
        svg,
        caption: format!(
            "Every accepted GNSS fix minus the antenna position of {} ({}), east and north. \
             RMS {}; the band is twice the GNSS sigma used ({:.3} m, {}). Residuals that \
             drift together over a segment show what the model does not carry (heading \
             drift, slip); a step at one time shows a GNSS jump.",
            model_name(c),
            segments_text(c),
            rms.map_or("not determined".to_string(), |v| format!("{v:.3} m")),
            sigma,
            if c.diagnostics.gnss_sigma_estimated {
                "estimated from the fixes"
            } else {
                "given"
            }
        ),
    })
}

/// The model's track against the reference and the GNSS fixes (a map).
pub fn track(c: &Calibration) -> Result<NamedFigure, FigureError> {
    let t = &c.tracks;
    let svg = Figure::new(
        &format!("Track: {} against the reference", model_name(c)),
        Axis::linear("east", "m"),
        Axis::linear("north", "m"),
    )
    .with(
        Series::dots("GNSS fixes (antenna)", t.gnss.clone(), Colour::GREY)
            .with_mark(Mark::Dots { radius: 1 })
            .with_opacity(0.5),
    )
    .with(Series::line(
        "reference (GNSS/IMU fusion)",
        t.reference.clone(),
        Colour::BLACK,
    ))
    .with(
        Series::lines(model_name(c), t.model.parts.clone(), Colour::BLUE)
            .with_mark(Mark::Line { width: 1 }),
    )
    .map((900, 800))
    .svg()?;
    Ok(NamedFigure {
        file: "track.svg",
        name: "Track".to_string(),
        svg,
        caption: format!(
            "The rear-axle centre of {} ({}; {} segments) over the reference the calibration \
             used, with the accepted GNSS fixes; equal scale on both axes. This is the model \
             the estimate came from; the whole drive dead-reckoned without the GNSS drifts \
             away through the heading whatever the circumferences (see the iterations).",
            model_name(c),
            segments_text(c),
            t.model.parts.len()
        ),
    })
}

/// The wheel-speed ratio against the turn rate per metre, with the
/// nominal and the estimated circumferences, against the 2W model's ratio.
pub fn wheel_ratio(c: &Calibration) -> Result<NamedFigure, FigureError> {
    let (rl, rr) = (c.circumference_m.rl, c.circumference_m.rr);
    let nominal = c.nominal.circumference_m;
    let b = c.track_width_m;
    // The 2W model's ratio v_RR / v_RL at curvature k (turn rate / speed).
    let model = |k: f64| (1.0 + 0.5 * k * b) / (1.0 - 0.5 * k * b);
    let points = |c_rl: f64, c_rr: f64| -> Vec<[f64; 2]> {
        c.tracks
            .wheel_windows
            .iter()
            .map(|w| {
                let (dl, dr) = (c_rl * w[1], c_rr * w[2]);
                let k = w[0] / (0.5 * (dl + dr));
                [k, 100.0 * (dr / dl / model(k) - 1.0)]
            })
            .collect()
    };
    let est = points(rl, rr);
    let nom = points(nominal, nominal);
    let median = |v: &[[f64; 2]]| -> f64 {
        let mut y: Vec<f64> = v.iter().map(|p| p[1]).filter(|y| y.is_finite()).collect();
        stats::upper_median(&mut y).unwrap_or(f64::NAN)
    };
    let (lo, hi) = est
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, z), p| {
            (a.min(p[0]), z.max(p[0]))
        });
    let zero = if lo < hi {
        vec![[lo, 0.0], [hi, 0.0]]
    } else {
        Vec::new()
    };
    let svg = Figure::new(
        "Wheel-speed ratio against turn rate per metre driven",
        Axis::linear(
            "yaw rate / speed (reference heading change per metre)",
            "1/m",
        ),
        Axis::linear(
            "wheel-speed ratio v_RR/v_RL over the 2W model ratio, minus 1",
            "%",
        ),
    )
    .with(
        Series::dots(
            &format!("nominal circumferences (median {:+.3} %)", median(&nom)),
            nom,
            Colour::VERMILLION,
        )
        .with_opacity(0.5),
    )
    .with(
        Series::dots(
            &format!("estimated circumferences (median {:+.3} %)", median(&est)),
            est,
            Colour::BLUE,
        )
        .with_opacity(0.6),
    )
    .with(Series::line(
        &format!("2W model, track {b:.3} m"),
        zero,
        Colour::BLACK,
    ))
    .svg()?;
    Ok(NamedFigure {
        file: "wheel_ratio.svg",
        name: "Wheel-speed ratio against turn rate".to_string(),
        svg,
        caption: format!(
            "{} windows of about 1 s above 2 m/s: the rear wheels' speed ratio v_RR/v_RL \
             (revolutions times circumference) over the ratio the 2W model gives at the \
             reference's heading change per metre, (1 + kb/2)/(1 - kb/2) with the track width \
             b, in percent. The estimated circumferences (blue) should centre on zero at every \
             turn rate; the nominal ones (vermillion) sit off it by the ratio of the true \
             circumferences. A slope shows a wrong track width, spread is wheel quantisation, \
             slip and reference noise.",
            c.tracks.wheel_windows.len()
        ),
    })
}

/// The dead-reckoning deviation per iteration (log scale).
pub fn iteration_errors(c: &Calibration) -> Result<NamedFigure, FigureError> {
    let it = &c.iterations;
    let pts = |f: &dyn Fn(&crate::result::IterationRecord) -> f64| -> Vec<[f64; 2]> {
        it.iter().map(|i| [i.n as f64, f(i)]).collect()
    };
    let marks = Mark::LineAndDots {
        width: 2,
        radius: 4,
    };
    let kept: Vec<[f64; 2]> = it
        .iter()
        .filter(|i| i.n == c.selected_iteration)
        .map(|i| [i.n as f64, i.dr_error_mean_m])
        .collect();
    let svg = Figure::new(
        "Whole-drive dead-reckoning deviation per iteration",
        Axis::linear("iteration (0 = nominal values)", ""),
        Axis::log("deviation from the reference", "m"),
    )
    .with(Series::line("mean", pts(&|i| i.dr_error_mean_m), Colour::GREEN).with_mark(marks))
    .with(Series::line("max", pts(&|i| i.dr_error_max_m), Colour::ORANGE).with_mark(marks))
    .with(Series::dots("kept", kept, Colour::BLACK).with_mark(Mark::Dots { radius: 7 }))
    .svg()?;
    Ok(NamedFigure {
        file: "iterations.svg",
        name: "Iterations: dead-reckoning deviation".to_string(),
        svg,
        caption: "The 2W model integrated over the whole drive without any GNSS, against the \
                  reference, after each iteration (batch: each fit stage), on a logarithmic \
                  scale. It measures the heading drift over the drive as much as the \
                  circumferences: it shows that the iterations converge, not how good the \
                  result is (the residuals above do)."
            .to_string(),
    })
}

/// The circumferences per iteration, in mm from the nominal value.
pub fn iteration_circumferences(c: &Calibration) -> Result<NamedFigure, FigureError> {
    let nominal = c.nominal.circumference_m;
    let mm = |v: f64| 1000.0 * (v - nominal);
    let marks = Mark::LineAndDots {
        width: 2,
        radius: 4,
    };
    let svg = Figure::new(
        "Circumferences per iteration",
        Axis::linear("iteration (0 = nominal values)", ""),
        Axis::linear(&format!("circumference minus nominal {nominal:.4} m"), "mm"),
    )
    .with(
        Series::line(
            "c_RL",
            c.iterations
                .iter()
                .map(|i| [i.n as f64, mm(i.circumference_m.rl)])
                .collect(),
            Colour::BLUE,
        )
        .with_mark(marks),
    )
    .with(
        Series::line(
            "c_RR",
            c.iterations
                .iter()
                .map(|i| [i.n as f64, mm(i.circumference_m.rr)])
                .collect(),
            Colour::VERMILLION,
        )
        .with_mark(marks),
    )
    .svg()?;
    Ok(NamedFigure {
        file: "iterations_circumference.svg",
        name: "Iterations: circumferences".to_string(),
        svg,
        caption: format!(
            "The rear circumferences after each iteration, in millimetres from the nominal \
             {nominal:.4} m; iteration {} is kept. The final values can differ from the last \
             iteration's where the wheel + gyro model set the common scale (see the warnings).",
            c.selected_iteration
        ),
    })
}
