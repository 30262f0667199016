//! The calibration page: one self-contained HTML document (the
//! [`report`] library's [`Page`]) with the result, the warnings in plain
//! words, the numbers, the iterations and the figures of [`crate::result::plots`].
//! Pure: returns the text; the binary writes `index.html`.

use crate::result::plots::NamedFigure;
use crate::result::Calibration;
use report::{Cell, Page};

fn mm(v: Option<f64>) -> String {
    v.map_or("not determined".to_string(), |v| {
        format!("{:.2} mm", 1000.0 * v)
    })
}

/// The page of calibration `c` of the drive named `drive`, with `figures`
/// and the warnings of reading the drive (`reading`).
pub fn calibration_html(
    c: &Calibration,
    drive: &str,
    figures: &[NamedFigure],
    reading: &[String],
) -> String {
    let mut page = Page::new(&format!("Calibration of {drive}"));
    headline(&mut page, c, reading);
    warnings(&mut page, c, reading);
    page.heading("Result");
    page.numbers(&result_rows(c));
    comparison(&mut page, c);
    iterations(&mut page, c);
    page.heading("Figures");
    for f in figures {
        page.figure(&f.name, &f.svg, &f.caption);
    }
    page.render()
}

/// The headline (the circumferences, the method, how many warnings) and
/// the note of the drive's facts.
fn headline(page: &mut Page, c: &Calibration, reading: &[String]) {
    let d = &c.diagnostics;
    page.headline(
        &format!(
            "Rear-left circumference {:.5} m (sigma {}), rear-right {:.5} m (sigma {}), \
             by the {} method; {}.",
            c.circumference_m.rl,
            mm(c.sigma_m.rl),
            c.circumference_m.rr,
            mm(c.sigma_m.rr),
            c.method,
            match c.warnings.len() + reading.len() {
                0 => "no warnings".to_string(),
                1 => "1 warning below".to_string(),
                n => format!("{n} warnings below"),
            }
        ),
        Some(c.warnings.is_empty() && reading.is_empty()),
    );
    page.note(&format!(
        "Drive: {:.1} s, {:.0} m with a GNSS reference, turning {:.0} degrees in total, \
         {:.0} s standing still; {} GNSS fixes, {} rejected as outliers.",
        d.duration_s, d.distance_m, d.total_turn_deg, d.standstill_s, d.gnss_fixes, d.gnss_outliers
    ));
}

/// The warnings in plain words, the calibration's and those of reading
/// the drive.
fn warnings(page: &mut Page, c: &Calibration, reading: &[String]) {
    page.heading("Warnings");
    let mut warnings: Vec<String> = c.warnings.iter().map(|w| w.message.clone()).collect();
    warnings.extend(reading.iter().map(|w| format!("reading the drive: {w}")));
    page.warnings(
        &warnings,
        "None: the drive determines every estimated value, and nothing was skipped or assumed.",
    );
}

/// The result's numbers: circumferences, sigmas, track width, gyro,
/// side-slip, antenna, residual and GNSS sigma (label, value).
fn result_rows(c: &Calibration) -> Vec<(String, String)> {
    let d = &c.diagnostics;
    let mut rows = vec![
        (
            "rear-left circumference c_RL, m".to_string(),
            format!("{:.5}", c.circumference_m.rl),
        ),
        ("its 1-sigma".to_string(), mm(c.sigma_m.rl)),
        (
            "rear-right circumference c_RR, m".to_string(),
            format!("{:.5}", c.circumference_m.rr),
        ),
        ("its 1-sigma".to_string(), mm(c.sigma_m.rr)),
        (
            "difference c_RR - c_RL, mm".to_string(),
            format!(
                "{:+.2}",
                1000.0 * (c.circumference_m.rr - c.circumference_m.rl)
            ),
        ),
        ("its 1-sigma".to_string(), mm(c.sigma_m.difference)),
        (
            format!(
                "track width, m ({})",
                if c.track_width_estimated {
                    "estimated"
                } else {
                    "nominal, not estimated"
                }
            ),
            format!("{:.4}", c.track_width_m),
        ),
        (
            "nominal circumference, m".to_string(),
            format!("{:.5}", c.nominal.circumference_m),
        ),
    ];
    if let Some(g) = &c.gyro {
        rows.push((
            "gyro bias, deg/h".to_string(),
            format!(
                "{:+.1} (sigma {:.1})",
                g.bias_rad_s.to_degrees() * 3600.0,
                g.sigma_bias_rad_s.to_degrees() * 3600.0
            ),
        ));
        rows.push((
            "gyro scale error".to_string(),
            match g.sigma_scale {
                Some(s) => format!("{:+.5} (sigma {s:.5})", g.scale),
                None => format!("{:+.5} (held, not estimated)", g.scale),
            },
        ));
    }
    if let Some(k) = c.side_slip_gain_rad_per_m_s2 {
        rows.push((
            "side-slip gain k, rad per m/s²".to_string(),
            format!("{k:.5}"),
        ));
    }
    if let (Some(l), Some(s)) = (c.gnss_antenna_m, c.sigma_gnss_antenna_m) {
        rows.push((
            "GNSS antenna from the rear-axle centre (x, y), m".to_string(),
            format!("({:+.3}, {:+.3}) ± ({:.3}, {:.3})", l[0], l[1], s[0], s[1]),
        ));
    }
    if let Some(rms) = d.residual_rms_m {
        rows.push((
            format!("GNSS residual RMS of the fit, m ({} segments)", d.segments),
            format!("{rms:.3}"),
        ));
    }
    rows.push((
        format!(
            "GNSS sigma, m ({})",
            if d.gnss_sigma_estimated {
                "estimated"
            } else {
                "given"
            }
        ),
        format!("{:.3}", d.gnss_sigma_m),
    ));
    rows
}

/// The table of both methods (nothing when there is no comparison).
fn comparison(page: &mut Page, c: &Calibration) {
    if !c.comparison.is_empty() {
        page.heading("Both methods");
        let rows: Vec<Vec<Cell>> = c
            .comparison
            .iter()
            .map(|m| {
                vec![
                    Cell::Text(m.method.name().to_string()),
                    Cell::Number(format!("{:.5}", m.circumference_m.rl)),
                    Cell::Number(mm(m.sigma_m.rl)),
                    Cell::Number(format!("{:.5}", m.circumference_m.rr)),
                    Cell::Number(mm(m.sigma_m.rr)),
                    Cell::Number(format!("{:.4}", m.track_width_m)),
                ]
            })
            .collect();
        page.table(
            &[
                "method",
                "c_RL, m",
                "sigma",
                "c_RR, m",
                "sigma",
                "track width, m",
            ],
            &rows,
        );
    }
}

/// The per-iteration table (the kept one marked).
fn iterations(page: &mut Page, c: &Calibration) {
    page.heading("Iterations");
    let rows: Vec<Vec<Cell>> = c
        .iterations
        .iter()
        .map(|i| {
            vec![
                Cell::Number(format!(
                    "{}{}",
                    i.n,
                    if i.n == c.selected_iteration {
                        " (kept)"
                    } else {
                        ""
                    }
                )),
                Cell::Number(format!("{:.6}", i.circumference_m.rl)),
                Cell::Number(format!("{:.6}", i.circumference_m.rr)),
                Cell::Number(format!("{:.4}", i.track_width_m)),
                Cell::Number(format!("{:.2}", i.dr_error_mean_m)),
                Cell::Number(format!("{:.2}", i.dr_error_max_m)),
            ]
        })
        .collect();
    page.table(
        &[
            "iteration",
            "c_RL, m",
            "c_RR, m",
            "track width, m",
            "whole-drive DR deviation, mean, m",
            "max, m",
        ],
        &rows,
    );
}
