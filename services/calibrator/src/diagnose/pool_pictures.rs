//! The car's page over several drives ([`super::pool`]): the table of the
//! car's effects, and per effect each drive's own estimate beside the
//! pooled one with their 2-sigma bars and the smallest size the drives
//! together show.
//!
//! Pure: the diagnosis in, SVG and HTML out.

use super::pool::{CarVerdict, PooledEffect};
use super::DrivesDiagnosis;
use report::{escape, Axis, Cell, Colour, Figure, FigureError, Mark, Page, Series};

impl CarVerdict {
    /// In words.
    pub fn describe(self) -> &'static str {
        match self {
            CarVerdict::Found => "found",
            CarVerdict::NotShown => "not shown",
            CarVerdict::Implausible => "significant, implausible size",
            CarVerdict::Inconsistent => "significant, the drives disagree",
            CarVerdict::Guarded => "significant, refused by the held-out guard",
            CarVerdict::Ambiguous => "ambiguous with its partners",
        }
    }
}

/// One car effect: each drive's estimate (x = its number) and the pooled
/// one (x = drives + 1), 2-sigma bars, zero and the size shown.
pub fn effect_svg(p: &PooledEffect, names: &[String]) -> Result<String, FigureError> {
    let l = &p.limit;
    let n = p.per_drive.len();
    let bar = |x: f64, e: f64, s: f64| vec![[x, e - 2.0 * s], [x, e + 2.0 * s]];
    let mut own_bars = Vec::new();
    let mut own = Vec::new();
    for (i, d) in p.per_drive.iter().enumerate() {
        if let Some([e, s]) = d {
            own.push([(i + 1) as f64, *e]);
            own_bars.push(bar((i + 1) as f64, *e, *s));
        }
    }
    let (pe, ps) = l.shown_fit();
    let pooled_x = (n + 1) as f64;
    let span = [0.5, pooled_x + 0.5];
    let mut fig = Figure::new(
        &format!("{}: each drive and all together", l.effect),
        Axis::linear(&format!("drive (1-{n}; {} = all together)", n + 1), ""),
        Axis::linear(&l.estimate_of, l.unit),
    )
    .describe(&format!(
        "{}: {}. Drives: {}.",
        l.effect,
        p.verdict.describe(),
        names.join(", ")
    ))
    .with(Series::line(
        "zero",
        vec![[span[0], 0.0], [span[1], 0.0]],
        Colour::GREY,
    ))
    .with(Series::lines("each drive, 2 sigma", own_bars, Colour::BLUE))
    .with(Series::dots("each drive", own, Colour::BLUE).with_mark(Mark::Dots { radius: 4 }));
    if let (Some(e), Some(s)) = (pe, ps) {
        fig = fig
            .with(Series::lines(
                "all drives, 2 sigma",
                vec![bar(pooled_x, e, s)],
                Colour::VERMILLION,
            ))
            .with(
                Series::dots("all drives", vec![[pooled_x, e]], Colour::VERMILLION)
                    .with_mark(Mark::Dots { radius: 5 }),
            );
    }
    if let Some(v) = l.shown_smallest() {
        fig = fig.with(Series::lines(
            "smallest size the drives together show",
            vec![
                vec![[span[0], v], [span[1], v]],
                vec![[span[0], -v], [span[1], -v]],
            ],
            Colour::GREEN,
        ));
    }
    fig.svg()
}

/// The car's page: the table, a figure per car effect and a link per
/// drive's own page (`links`: folder, drive name).
pub fn car_html(
    d: &DrivesDiagnosis,
    names: &[String],
    links: &[(String, String)],
) -> Result<String, FigureError> {
    let mut page = Page::new(&format!("The car over {} drives", d.drives.len()));
    page.paragraph(
        "Each drive diagnosed on its own (its page linked below) and the car's effects (tyres, \
         geometry, the sensors' mounting) pooled over all of them: each drive's terms of the day \
         (circumference scale, gyro bias, warm-up, road grade, segment poses) profiled out, the \
         information added up, Holm's procedure over the car's effects, then the table's \
         plausible range, the drives' agreement (Cochran's Q) and the held-out guard.",
    );
    let Some(car) = &d.car else {
        page.note(&format!(
            "The car's effects: not known ({}).",
            d.car_missing.as_deref().unwrap_or("no information")
        ));
        links_section(&mut page, links);
        return Ok(page.render());
    };
    let pooled_names: Vec<String> = d
        .pooled
        .iter()
        .map(|&i| names.get(i).cloned().unwrap_or_default())
        .collect();
    let rows: Vec<Vec<Cell>> = car
        .effects
        .iter()
        .map(|p| {
            let l = &p.limit;
            let test = car.wald.iter().find(|t| t.effect == l.effect);
            let (e, s) = l.shown_fit();
            let num = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3e}"));
            vec![
                Cell::Html(format!("<code>{}</code>", escape(l.effect.id()))),
                Cell::Text(p.verdict.describe().to_string()),
                Cell::Number(format!("{} ± {} {}", num(e), num(s), l.unit)),
                Cell::Number(test.map_or("-".into(), |t| {
                    format!("{:+.1} (Holm {:.1})", t.z, t.z_critical)
                })),
                Cell::Number(format!("{} {}", num(l.shown_smallest()), l.unit)),
                Cell::Text(
                    p.information_share
                        .iter()
                        .zip(&pooled_names)
                        .map(|(sh, n)| format!("{n} {:.0} %", 100.0 * sh))
                        .collect::<Vec<_>>()
                        .join(", "),
                ),
            ]
        })
        .collect();
    page.heading("The car's effects");
    page.table(
        &[
            "effect",
            "verdict",
            "estimate ± sigma (every other car effect free)",
            "Wald z",
            "smallest size shown",
            "share of the information",
        ],
        &rows,
    );
    for p in &car.effects {
        let svg = effect_svg(p, &pooled_names)?;
        page.figure(
            p.limit.effect.id(),
            &svg,
            "Each drive's own estimate (blue) and all drives together (vermillion), with 2-sigma \
             bars; green: the smallest size the drives together show with 90 % power.",
        );
    }
    links_section(&mut page, links);
    Ok(page.render())
}

fn links_section(page: &mut Page, links: &[(String, String)]) {
    page.heading("The drives");
    let items: Vec<String> = links
        .iter()
        .map(|(sub, name)| {
            format!(
                "<a href=\"{}/index.html\">{}</a>",
                escape(sub),
                escape(name)
            )
        })
        .collect();
    page.html(&format!("<ul><li>{}</li></ul>", items.join("</li><li>")));
}
