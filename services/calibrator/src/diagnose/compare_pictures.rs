//! The comparison's page ([`super::compare`]): the two tracks, every
//! effect in both drives with 2-sigma bars, the plain model's error block
//! by block with the spans where the two part, each residual channel's two
//! distributions (quantile against quantile), and, given the comparison
//! before a mend, each channel's distance before and after against its
//! noise level; the speed channel over speed and over the longitudinal
//! acceleration, each drive's level per bin; and the wheels' yaw wander
//! against the gyro in both drives (its structure function, measured and
//! fitted).
//!
//! Pure: the comparison (and the fixes) in, SVG and HTML out.

pub use super::compare::sig3;
use super::compare::{ChannelDistance, Comparison, Summary};
use super::speed_map::SpeedMapDifference;
use super::yaw_wander::WanderDifference;
use super::Diagnosis;
use report::{Axis, Band, Cell, Colour, Figure, FigureError, Mark, Page, Series};

/// The two drives' GNSS fixes, one on the other.
pub fn tracks_svg(recording: &[[f64; 2]], simulation: &[[f64; 2]]) -> Result<String, FigureError> {
    Figure::new(
        "The recording and the simulation: GNSS fixes",
        Axis::linear("east", "m"),
        Axis::linear("north", "m"),
    )
    .map((720, 560))
    .describe(
        "GNSS fixes of the recording (blue) and of the simulation (orange), in the recording's \
         local frame: the simulation should follow the same path.",
    )
    .with(
        Series::dots("recording", recording.to_vec(), Colour::BLUE)
            .with_mark(Mark::Dots { radius: 1 }),
    )
    .with(
        Series::dots("simulation", simulation.to_vec(), Colour::ORANGE)
            .with_mark(Mark::Dots { radius: 1 }),
    )
    .svg()
}

/// Every effect both drives hold information about: the recording's and
/// the simulation's estimates over the catalogue's typical size, with
/// their 2-sigma bars.
pub fn effects_svg(c: &Comparison) -> Result<String, FigureError> {
    let mut rec = Vec::new();
    let mut rec_bars = Vec::new();
    let mut sim = Vec::new();
    let mut sim_bars = Vec::new();
    let mut named = Vec::new();
    let mut names = Vec::new();
    let rows: Vec<_> = c
        .effects
        .iter()
        .filter(|e| e.recording.is_some() && e.simulation.is_some() && e.typical != 0.0)
        .collect();
    for (k, e) in rows.iter().enumerate() {
        let x = (k + 1) as f64;
        let t = e.typical.abs();
        names.push(format!("{} {}", k + 1, e.effect));
        if let Some([v, s]) = e.recording {
            rec.push([x - 0.12, v / t]);
            rec_bars.push(vec![
                [x - 0.12, (v - 2.0 * s) / t],
                [x - 0.12, (v + 2.0 * s) / t],
            ]);
        }
        if let Some([v, s]) = e.simulation {
            sim.push([x + 0.12, v / t]);
            sim_bars.push(vec![
                [x + 0.12, (v - 2.0 * s) / t],
                [x + 0.12, (v + 2.0 * s) / t],
            ]);
        }
        if e.verdict.named() {
            named.push([x, 0.0]);
        }
    }
    let n = rows.len().max(1) as f64;
    // The range the informative estimates need (an effect the drives
    // hardly show has bars many times its typical size).
    let reach = rows
        .iter()
        .flat_map(|e| [e.recording, e.simulation])
        .flatten()
        .zip(rows.iter().flat_map(|e| [e.typical.abs(); 2]))
        .filter(|([_, s], t)| s / t < 1.0)
        .map(|([v, s], t)| (v.abs() + 2.0 * s) / t)
        .fold(1.5_f64, f64::max)
        .min(10.0)
        * 1.15;
    let mut y = Axis::linear("estimate / typical size", "");
    y.range = Some((-reach, reach));
    Figure::new(
        "Each effect in the recording and in the simulation",
        Axis::linear("effect (numbered as in the caption)", ""),
        y,
    )
    .describe(&format!(
        "Estimates over the catalogue's typical size with 2-sigma bars: recording blue (left), \
         simulation orange (right); a vermillion ring marks a named difference; bars beyond \
         the frame are cut. Effects: {}.",
        names.join(", ")
    ))
    .with(Series::line(
        "zero",
        vec![[0.5, 0.0], [n + 0.5, 0.0]],
        Colour::GREY,
    ))
    .with(Series::lines("recording, 2 sigma", rec_bars, Colour::BLUE))
    .with(Series::dots("recording", rec, Colour::BLUE).with_mark(Mark::Dots { radius: 4 }))
    .with(Series::lines(
        "simulation, 2 sigma",
        sim_bars,
        Colour::ORANGE,
    ))
    .with(Series::dots("simulation", sim, Colour::ORANGE).with_mark(Mark::Dots { radius: 4 }))
    .with(
        Series::dots("named difference", named, Colour::VERMILLION)
            .with_mark(Mark::Dots { radius: 7 }),
    )
    .svg()
}

/// The speed channel over one signal (`speed` or `a_x`): each drive's
/// level per bin (a horizontal segment over the bin), the difference's
/// 2-sigma bar at the bin's middle about the simulation's level, and a
/// vermillion ring on a bin that differs.
pub fn speed_map_svg(m: &SpeedMapDifference, signal: &str) -> Result<String, FigureError> {
    let bins: Vec<_> = m.bins.iter().filter(|b| b.signal == signal).collect();
    let (title, axis, unit, what) = if signal == "speed" {
        (
            "The speed channel over the speed",
            "wheels' speed",
            "m/s",
            "each drive's level in each speed bin",
        )
    } else {
        (
            "The speed channel over the longitudinal acceleration",
            "longitudinal acceleration",
            "m/s^2",
            "each drive's departure from its level where the car holds its speed (0 by definition)",
        )
    };
    let seg = |level: f64, lo: f64, hi: f64| vec![[lo, 100.0 * level], [hi, 100.0 * level]];
    let rec: Vec<Vec<[f64; 2]>> = bins.iter().map(|b| seg(b.recording, b.lo, b.hi)).collect();
    let sim: Vec<Vec<[f64; 2]>> = bins.iter().map(|b| seg(b.simulation, b.lo, b.hi)).collect();
    let bars: Vec<Vec<[f64; 2]>> = bins
        .iter()
        .map(|b| {
            let x = 0.5 * (b.lo + b.hi);
            let c = 100.0 * b.simulation + 100.0 * b.difference;
            vec![[x, c - 200.0 * b.sigma], [x, c + 200.0 * b.sigma]]
        })
        .collect();
    let differing: Vec<[f64; 2]> = bins
        .iter()
        .filter(|b| b.differs)
        .map(|b| [0.5 * (b.lo + b.hi), 100.0 * b.recording])
        .collect();
    let (lo, hi) = bins
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), b| {
            (l.min(b.lo), h.max(b.hi))
        });
    let mut fig = Figure::new(
        title,
        Axis::linear(axis, unit),
        Axis::linear("GNSS against the wheels, relative", "%"),
    )
    .describe(&format!(
        "The speed channel's residual (GNSS chord over the wheels' chord, minus 1) about each \
         drive's level, {what}: recording blue, simulation orange; the recording's 2-sigma bar \
         (jackknife over the matched blocks) at each bin's middle; a vermillion ring marks a bin \
         that differs (Holm over the bins, 5 %). Above zero the wheels read slow against the GNSS."
    ));
    if lo.is_finite() && hi.is_finite() {
        fig = fig.with(Series::line(
            "zero",
            vec![[lo, 0.0], [hi, 0.0]],
            Colour::GREY,
        ));
    }
    fig.with(Series::lines("recording", rec, Colour::BLUE))
        .with(Series::lines("simulation", sim, Colour::ORANGE))
        .with(Series::lines(
            "recording, 2 sigma of the difference",
            bars,
            Colour::BLUE,
        ))
        .with(
            Series::dots("bin that differs", differing, Colour::VERMILLION)
                .with_mark(Mark::Dots { radius: 7 }),
        )
        .svg()
}

/// The wheels' heading against the gyro's over lags: each drive's RMS
/// increment measured (dots) and fitted (white + Gauss-Markov, lines).
pub fn yaw_wander_svg(w: &WanderDifference) -> Result<String, FigureError> {
    let pts = |i: usize, m: &super::yaw_wander::WanderMeasure| -> Vec<[f64; 2]> {
        m.structure
            .iter()
            .filter(|x| x[i] > 0.0)
            .map(|x| [x[0], 1000.0 * x[i].sqrt()])
            .collect()
    };
    Figure::new(
        "The wheels' heading against the gyro's",
        Axis::log("lag", "s"),
        Axis::log("RMS change over the lag", "mrad"),
    )
    .describe(&format!(
        "The wheels' yaw rate less the gyro's (the gyro's scale against the track, its bias and \
         the load transfer's v^2 term fitted out), integrated, its RMS change over each lag: \
         measured (dots) and fitted as white noise plus a Gauss-Markov wander (lines); recording \
         blue ({} rad/s at {} s), simulation orange ({} rad/s at {} s). A wander grows as the lag \
         up to its correlation time, white noise as its square root.",
        sig3(w.recording.sigma_rad_s),
        sig3(w.recording.tau_s),
        sig3(w.simulation.sigma_rad_s),
        sig3(w.simulation.tau_s),
    ))
    .with(Series::dots(
        "recording, measured",
        pts(1, &w.recording),
        Colour::BLUE,
    ))
    .with(Series::line(
        "recording, fitted",
        pts(2, &w.recording),
        Colour::BLUE,
    ))
    .with(Series::dots(
        "simulation, measured",
        pts(1, &w.simulation),
        Colour::ORANGE,
    ))
    .with(Series::line(
        "simulation, fitted",
        pts(2, &w.simulation),
        Colour::ORANGE,
    ))
    .svg()
}

/// The plain model's position RMSE block by block in both drives, the
/// spans where they part shaded.
pub fn blocks_svg(
    c: &Comparison,
    recording: &Diagnosis,
    simulation: &Diagnosis,
) -> Result<String, FigureError> {
    let t0 = recording.blocks.first().map_or(0.0, |b| b.t_start_s);
    let points = |d: &Diagnosis| -> Vec<[f64; 2]> {
        d.blocks
            .iter()
            .filter_map(|b| Some([0.5 * (b.t_start_s + b.t_end_s) - t0, b.plain_rms_m?]))
            .collect()
    };
    let top = recording
        .blocks
        .iter()
        .chain(&simulation.blocks)
        .filter_map(|b| b.plain_rms_m)
        .fold(0.0_f64, f64::max);
    let mut fig = Figure::new(
        "Where the recording and the simulation part",
        Axis::linear("time since the recording's first block", "s"),
        Axis::linear("plain model's position RMSE over the block", "m"),
    )
    .describe(&format!(
        "Per block of {:.0} s, the calibrated plain 2W model's position error on the recording \
         (blue) and on the simulation (orange). Shaded: the spans where the recording's error is \
         beyond what the simulation's own block-to-block scatter allows ({} span(s)).",
        c.block_s,
        c.parting.len()
    ))
    .with(
        Series::line("recording", points(recording), Colour::BLUE).with_mark(Mark::LineAndDots {
            width: 2,
            radius: 3,
        }),
    )
    .with(
        Series::line("simulation", points(simulation), Colour::ORANGE).with_mark(
            Mark::LineAndDots {
                width: 2,
                radius: 3,
            },
        ),
    );
    for (k, p) in c.parting.iter().enumerate() {
        fig = fig.with_band(Band {
            label: if k == 0 {
                "they part".into()
            } else {
                String::new()
            },
            points: vec![[p.t_start_s - t0, 0.0, top], [p.t_end_s - t0, 0.0, top]],
            colour: Colour::VERMILLION,
        });
    }
    fig.svg()
}

/// One residual channel: the recording's quantiles against the
/// simulation's (alike distributions lie on the diagonal).
pub fn channel_svg(
    ch: &ChannelDistance,
    recording: &Diagnosis,
    simulation: &Diagnosis,
) -> Result<String, FigureError> {
    let values = |d: &Diagnosis| -> Vec<f64> {
        let mut v: Vec<f64> = d
            .channels
            .iter()
            .filter(|c| c.channel.name() == ch.channel)
            .flat_map(|c| c.rows.iter().map(|r| r.2))
            .filter(|x| x.is_finite())
            .collect();
        v.sort_by(f64::total_cmp);
        v
    };
    let (r, s) = (values(recording), values(simulation));
    let q: Vec<[f64; 2]> = (1..100)
        .filter_map(|k| {
            let p = k as f64 / 100.0;
            Some([
                stats::percentile_sorted(&s, p)?,
                stats::percentile_sorted(&r, p)?,
            ])
        })
        .collect();
    let lo = q
        .iter()
        .flat_map(|p| p.iter())
        .copied()
        .fold(f64::INFINITY, f64::min);
    let hi = q
        .iter()
        .flat_map(|p| p.iter())
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    Figure::new(
        &format!(
            "Residual channel {}: recording against simulation",
            ch.channel
        ),
        Axis::linear("simulation's residual quantile", ch.unit),
        Axis::linear("recording's residual quantile", ch.unit),
    )
    .describe(&format!(
        "Percentiles 1-99 of the plain model's {} residual in the recording against the \
         simulation's; alike distributions lie on the diagonal. Wasserstein distance {} {} \
         against a noise level of {} (95 % of block swaps; p = {:.3}): {}.",
        ch.channel,
        sig3(ch.distance),
        ch.unit,
        sig3(ch.noise_level),
        ch.p_value,
        if ch.within_noise {
            "within the noise"
        } else {
            "beyond the noise"
        }
    ))
    .with(Series::line(
        "alike",
        vec![[lo, lo], [hi, hi]],
        Colour::GREY,
    ))
    .with(
        Series::line("percentiles", q, Colour::BLUE).with_mark(Mark::LineAndDots {
            width: 1,
            radius: 2,
        }),
    )
    .svg()
}

/// Each channel's distance over its noise level, before a mend and now.
pub fn mend_svg(before: &Summary, now: &Comparison) -> Result<String, FigureError> {
    let mut b = Vec::new();
    let mut n = Vec::new();
    let mut names = Vec::new();
    for (k, ch) in now.channels.iter().enumerate() {
        let x = (k + 1) as f64;
        names.push(format!("{} {}", k + 1, ch.channel));
        n.push([x + 0.1, ch.distance / ch.noise_level]);
        if let Some(p) = before.channels.iter().find(|c| c.channel == ch.channel) {
            b.push([x - 0.1, p.distance / p.noise_level]);
        }
    }
    let m = now.channels.len().max(1) as f64;
    Figure::new(
        "Before and after the mend: each channel's distance over its noise level",
        Axis::linear("channel (numbered as in the caption)", ""),
        Axis::log("distance / noise level", ""),
    )
    .describe(&format!(
        "Wasserstein distance of each residual channel over its noise level (95 % of block swaps): \
         before the mend (grey) and now (blue); at or below 1 (the line) the two are alike within \
         the noise. Channels: {}.",
        names.join(", ")
    ))
    .with(Series::line(
        "noise level",
        vec![[0.5, 1.0], [m + 0.5, 1.0]],
        Colour::VERMILLION,
    ))
    .with(Series::dots("before", b, Colour::GREY).with_mark(Mark::Dots { radius: 5 }))
    .with(Series::dots("now", n, Colour::BLUE).with_mark(Mark::Dots { radius: 5 }))
    .svg()
}

/// The page: headline, the effects' table, the spans, the channels, the
/// pictures.
pub fn index_html(
    c: &Comparison,
    names: [&str; 2],
    before: Option<&Summary>,
    pictures: &[(String, String)],
) -> String {
    let mut page = Page::new("A simulation against a recording");
    let named: Vec<String> = c
        .named()
        .map(|e| format!("{} ({})", e.effect, e.verdict.words()))
        .collect();
    page.headline(
        &if named.is_empty() {
            format!(
                "No physics differs; {} of {} residual channels within their noise level, {} differing at the family's 5 %.",
                c.channels_within_noise,
                c.channels.len(),
                c.channels_differing
            )
        } else {
            format!(
                "Differs in: {}; {} of {} residual channels within their noise level, {} differing at the family's 5 %.",
                named.join(", "),
                c.channels_within_noise,
                c.channels.len(),
                c.channels_differing
            )
        },
        Some(c.alike()),
    );
    page.paragraph(&format!(
        "Recording: {}. Simulation: {}. Both diagnosed with blocks of {:.0} s; {} blocks matched in time.",
        names[0],
        names[1],
        c.block_s,
        c.matched_blocks
    ));
    if let Some(b) = before {
        let was: Vec<String> = b.named().map(|e| e.effect.to_string()).collect();
        page.paragraph(&format!(
            "Before the mend: {} named ({}); {} of {} channels within their noise level. Now: {} named; {} of {}.",
            was.len(),
            if was.is_empty() { "none".to_string() } else { was.join(", ") },
            b.channels_within_noise(),
            b.channels.len(),
            c.named().count(),
            c.channels_within_noise,
            c.channels.len()
        ));
    }
    page.heading("Physics: recording against simulation");
    if let Some(why) = &c.effects_missing {
        page.note(&format!("The effects could not be compared: {why}"));
    }
    let fmt = |v: Option<[f64; 2]>| {
        v.map_or("-".to_string(), |[e, s]| {
            format!("{} ± {}", sig3(e), sig3(s))
        })
    };
    let rows: Vec<Vec<Cell>> = c
        .effects
        .iter()
        .map(|e| {
            vec![
                Cell::Text(e.effect.to_string()),
                Cell::Text(format!("{} ({})", e.parameter, e.unit)),
                Cell::Text(fmt(e.recording)),
                Cell::Text(fmt(e.simulation)),
                Cell::Text(e.z.map_or("-".into(), |z| format!("{z:+.1}"))),
                Cell::Text(e.z_critical.map_or("-".into(), |z| format!("{z:.1}"))),
                Cell::Text(e.verdict.words().to_string()),
            ]
        })
        .collect();
    page.table(
        &[
            "effect",
            "parameter",
            "recording",
            "simulation",
            "difference z",
            "Holm's critical",
            "verdict",
        ],
        &rows,
    );
    page.heading("Where they part");
    if c.parting.is_empty() {
        page.paragraph("Nowhere beyond the simulation's own block-to-block scatter.");
    } else {
        let items: Vec<String> = c
            .parting
            .iter()
            .map(|p| {
                format!(
                    "{:.0}-{:.0} s: {:.2} m against {:.2} m (z {:.1}); {}",
                    p.t_start_s, p.t_end_s, p.recording_rms_m, p.simulation_rms_m, p.z, p.manoeuvre
                )
            })
            .collect();
        page.list(&items);
    }
    page.heading("How alike: the residual channels");
    let rows: Vec<Vec<Cell>> = c
        .channels
        .iter()
        .map(|ch| {
            vec![
                Cell::Text(ch.channel.to_string()),
                Cell::Text(format!(
                    "{} / {} {}",
                    sig3(ch.rms[0]),
                    sig3(ch.rms[1]),
                    ch.unit
                )),
                Cell::Number(sig3(ch.distance)),
                Cell::Number(sig3(ch.noise_level)),
                Cell::Text(format!("{:.3}", ch.p_value)),
                Cell::Text(if ch.within_noise { "yes" } else { "no" }.into()),
                Cell::Text(if ch.differs { "yes" } else { "no" }.into()),
            ]
        })
        .collect();
    page.table(
        &[
            "channel",
            "RMS recording / simulation",
            "distance",
            "noise level",
            "p",
            "within noise",
            "differs (Holm, 5 %)",
        ],
        &rows,
    );
    if let Some(m) = &c.speed_map {
        page.heading("The speed channel over speed and acceleration");
        let differing: Vec<_> = m.differing().collect();
        page.paragraph(&if differing.is_empty() {
            "No bin differs (Holm over the bins, 5 %).".to_string()
        } else if m.unexplained {
            format!(
                "{} bins differ, and no effect named speaks for the speed channel: physics the \
                 catalogue does not hold. The mended simulation carries the map.",
                differing.len()
            )
        } else {
            format!(
                "{} bins differ; named in the speed channel: {}.",
                differing.len(),
                if m.named_in_channel.is_empty() {
                    "nothing".to_string()
                } else {
                    m.named_in_channel.join(", ")
                }
            )
        });
        let rows: Vec<Vec<Cell>> = m
            .bins
            .iter()
            .map(|b| {
                vec![
                    Cell::Text(b.signal.clone()),
                    Cell::Text(format!("{:.1} to {:.1}", b.lo, b.hi)),
                    Cell::Text(format!("{} / {}", b.rows[0], b.rows[1])),
                    Cell::Number(format!("{:+.2}", 100.0 * b.difference)),
                    Cell::Number(format!("{:.2}", 100.0 * b.sigma)),
                    Cell::Text(format!("{:.4}", b.p_value)),
                    Cell::Text(if b.differs { "yes" } else { "no" }.into()),
                ]
            })
            .collect();
        page.table(
            &[
                "signal",
                "bin",
                "rows recording / simulation",
                "difference, %",
                "sigma, %",
                "p",
                "differs",
            ],
            &rows,
        );
    }
    if let Some(w) = &c.yaw_wander {
        page.heading("The wheels' yaw wander against the gyro");
        page.paragraph(&format!(
            "Recording {} rad/s at {} s, simulation {} rad/s at {} s (Gauss-Markov part); their \
             variances differ at z {:+.1} against a critical {:.1} (jackknife over the blocks). {}",
            sig3(w.recording.sigma_rad_s),
            sig3(w.recording.tau_s),
            sig3(w.simulation.sigma_rad_s),
            sig3(w.simulation.tau_s),
            w.z,
            w.z_critical,
            if w.explains {
                "The course against the wheels differs with it: the mended simulation's wheels \
                 carry the recording's wander."
            } else {
                "The mend does not move it."
            }
        ));
    }
    for (name, svg) in pictures {
        page.figure(name, svg, "");
    }
    page.render()
}
