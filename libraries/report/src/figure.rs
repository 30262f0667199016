//! A figure: series of lines or dots and shaded bands on two axes with
//! their units, drawn as SVG by `plotters` with ticks, a grid, the axis
//! titles and a legend. Axes are linear or logarithmic; a map (a track in
//! metres) is drawn at equal scale on both axes.

use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// Largest number of points drawn of one part of a line series (more are
/// thinned evenly; the figure stays a few hundred kB at most).
pub const MAX_LINE_POINTS: usize = 4000;
/// Largest number of dots drawn of one series.
pub const MAX_DOTS: usize = 3000;

const FONT: &str = "sans-serif";
const MARGIN: u32 = 14;
const X_LABEL_AREA: u32 = 48;
const Y_LABEL_AREA: u32 = 78;
const CAPTION_AREA: u32 = 34;

/// Why a figure could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum FigureError {
    /// `plotters` refused a drawing operation.
    #[error("cannot draw the figure `{title}`: {detail}")]
    Draw {
        /// The figure's title.
        title: String,
        /// What plotters said.
        detail: String,
    },
}

/// A colour, 8-bit sRGB.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Colour(pub u8, pub u8, pub u8);

impl Colour {
    /// Blue (the estimate, "after"; Okabe-Ito, readable by the colour-blind).
    pub const BLUE: Colour = Colour(0x00, 0x72, 0xB2);
    /// Vermillion (the nominal values, "before").
    pub const VERMILLION: Colour = Colour(0xD5, 0x5E, 0x00);
    /// Bluish green.
    pub const GREEN: Colour = Colour(0x00, 0x9E, 0x73);
    /// Orange.
    pub const ORANGE: Colour = Colour(0xE6, 0x9F, 0x00);
    /// Reddish purple.
    pub const PURPLE: Colour = Colour(0xCC, 0x79, 0xA7);
    /// Black (the reference, the truth).
    pub const BLACK: Colour = Colour(0, 0, 0);
    /// Grey (raw measurements, GNSS fixes).
    pub const GREY: Colour = Colour(0x8a, 0x8a, 0x8a);

    fn rgb(self) -> RGBColor {
        RGBColor(self.0, self.1, self.2)
    }
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mark {
    /// A line through the points, `width` px wide.
    Line {
        /// Stroke width, px.
        width: u32,
    },
    /// A dot at every point, `radius` px.
    Dots {
        /// Dot radius, px.
        radius: u32,
    },
    /// A line with a dot at every point (few points: iterations).
    LineAndDots {
        /// Stroke width, px.
        width: u32,
        /// Dot radius, px.
        radius: u32,
    },
}

/// One series: points in parts (a line is broken between parts), how they
/// are drawn, and the legend entry (none when `label` is empty).
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text; empty: not in the legend.
    pub label: String,
    /// The points `[x, y]`, in parts; non-finite points are left out.
    pub parts: Vec<Vec<[f64; 2]>>,
    /// Line or dots.
    pub mark: Mark,
    /// Colour.
    pub colour: Colour,
    /// Opacity, 0..=1.
    pub opacity: f64,
}

impl Series {
    /// A line through `points`.
    pub fn line(label: &str, points: Vec<[f64; 2]>, colour: Colour) -> Series {
        Series {
            label: label.to_string(),
            parts: vec![points],
            mark: Mark::Line { width: 2 },
            colour,
            opacity: 1.0,
        }
    }

    /// Dots at `points`.
    pub fn dots(label: &str, points: Vec<[f64; 2]>, colour: Colour) -> Series {
        Series {
            label: label.to_string(),
            parts: vec![points],
            mark: Mark::Dots { radius: 2 },
            colour,
            opacity: 0.7,
        }
    }

    /// A line per part (broken between them).
    pub fn lines(label: &str, parts: Vec<Vec<[f64; 2]>>, colour: Colour) -> Series {
        Series {
            label: label.to_string(),
            parts,
            mark: Mark::Line { width: 2 },
            colour,
            opacity: 1.0,
        }
    }

    /// The same series drawn with `mark`.
    pub fn with_mark(mut self, mark: Mark) -> Series {
        self.mark = mark;
        self
    }

    /// The same series at `opacity`.
    pub fn with_opacity(mut self, opacity: f64) -> Series {
        self.opacity = opacity;
        self
    }
}

/// A shaded band between a lower and an upper value at each x (a sigma
/// band).
#[derive(Debug, Clone, PartialEq)]
pub struct Band {
    /// Legend text; empty: not in the legend.
    pub label: String,
    /// `[x, lower, upper]`, in x order.
    pub points: Vec<[f64; 3]>,
    /// Colour (drawn translucent).
    pub colour: Colour,
}

/// One axis: its title and unit (shown as "title, unit"), linear or
/// logarithmic, and optionally a fixed range.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// What the axis shows, e.g. "time since the drive's start".
    pub title: String,
    /// Its unit, e.g. "s"; empty for a ratio.
    pub unit: String,
    /// Logarithmic (only positive values are drawn).
    pub log: bool,
    /// The range drawn; `None`: from the data.
    pub range: Option<(f64, f64)>,
}

impl Axis {
    /// A linear axis.
    pub fn linear(title: &str, unit: &str) -> Axis {
        Axis {
            title: title.to_string(),
            unit: unit.to_string(),
            log: false,
            range: None,
        }
    }

    /// A logarithmic axis.
    pub fn log(title: &str, unit: &str) -> Axis {
        Axis {
            log: true,
            ..Axis::linear(title, unit)
        }
    }

    /// The axis title as drawn: "title, unit" (or the title alone).
    pub fn description(&self) -> String {
        if self.unit.is_empty() {
            self.title.clone()
        } else {
            format!("{}, {}", self.title, self.unit)
        }
    }
}

/// A figure: title, axes, series and bands.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Title drawn above the plot.
    pub title: String,
    /// The horizontal axis.
    pub x: Axis,
    /// The vertical axis.
    pub y: Axis,
    /// Drawn in order (the last on top).
    pub series: Vec<Series>,
    /// Drawn below the series.
    pub bands: Vec<Band>,
    /// Equal scale on both axes (a map): one metre is as long across as up.
    pub equal_scale: bool,
    /// Size, px.
    pub size: (u32, u32),
    /// What the figure shows, in words: its SVG `<desc>` (with the title as
    /// `<title>`), read by screen readers and taken as the caption by pages
    /// that have no other; empty: none.
    pub description: String,
}

impl Figure {
    /// An empty figure of the default size (900 x 520 px).
    pub fn new(title: &str, x: Axis, y: Axis) -> Figure {
        Figure {
            title: title.to_string(),
            x,
            y,
            series: Vec::new(),
            bands: Vec::new(),
            equal_scale: false,
            size: (900, 520),
            description: String::new(),
        }
    }

    /// The same figure at `size` px.
    pub fn sized(mut self, size: (u32, u32)) -> Figure {
        self.size = size;
        self
    }

    /// The same figure with its description (the SVG's `<desc>`).
    pub fn describe(mut self, description: &str) -> Figure {
        self.description = description.to_string();
        self
    }

    /// Add a series.
    pub fn with(mut self, series: Series) -> Figure {
        self.series.push(series);
        self
    }

    /// Add a band.
    pub fn with_band(mut self, band: Band) -> Figure {
        self.bands.push(band);
        self
    }

    /// Draw at equal scale on both axes, `size` px.
    pub fn map(mut self, size: (u32, u32)) -> Figure {
        self.equal_scale = true;
        self.size = size;
        self
    }

    /// The figure as an SVG document. Without any drawable point it shows
    /// its axes and says "no data".
    pub fn svg(&self) -> Result<String, FigureError> {
        let mut out = String::new();
        {
            let root = SVGBackend::with_string(&mut out, self.size).into_drawing_area();
            self.draw_on(&root).map_err(|detail| FigureError::Draw {
                title: self.title.clone(),
                detail,
            })?;
        }
        if !self.description.is_empty() {
            if let Some(end) = out.find('>') {
                let meta = format!(
                    "\n<title>{}</title>\n<desc>{}</desc>",
                    crate::page::escape(&self.title),
                    crate::page::escape(&self.description)
                );
                out.insert_str(end + 1, &meta);
            }
        }
        Ok(out)
    }

    fn draw_on(&self, root: &DrawingArea<SVGBackend, Shift>) -> Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let (xr, yr, empty) = self.ranges();
        let view = Some((xr, yr)).filter(|_| !empty);
        match (self.x.log, self.y.log) {
            (false, false) => self.draw(root, xr.0..xr.1, yr.0..yr.1, view),
            (false, true) => self.draw(root, xr.0..xr.1, (yr.0..yr.1).log_scale(), view),
            (true, false) => self.draw(root, (xr.0..xr.1).log_scale(), yr.0..yr.1, view),
            (true, true) => self.draw(
                root,
                (xr.0..xr.1).log_scale(),
                (yr.0..yr.1).log_scale(),
                view,
            ),
        }?;
        root.present().map_err(|e| e.to_string())
    }

    /// The finite points of every series and band that the axes can show.
    fn drawable(&self) -> (Vec<f64>, Vec<f64>) {
        let ok_x = |v: f64| v.is_finite() && (!self.x.log || v > 0.0);
        let ok_y = |v: f64| v.is_finite() && (!self.y.log || v > 0.0);
        let mut xs = Vec::new();
        let mut ys = Vec::new();
        for s in &self.series {
            for p in s.parts.iter().flatten() {
                if ok_x(p[0]) && ok_y(p[1]) {
                    xs.push(p[0]);
                    ys.push(p[1]);
                }
            }
        }
        for b in &self.bands {
            for p in &b.points {
                if ok_x(p[0]) {
                    for v in [p[1], p[2]] {
                        if ok_y(v) {
                            xs.push(p[0]);
                            ys.push(v);
                        }
                    }
                }
            }
        }
        (xs, ys)
    }

    /// The ranges drawn, and whether there is no data.
    fn ranges(&self) -> ((f64, f64), (f64, f64), bool) {
        let (xs, ys) = self.drawable();
        let empty = xs.is_empty();
        let span = |v: &[f64], axis: &Axis| -> (f64, f64) {
            if let Some(r) = axis.range {
                return r;
            }
            let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            if !(lo.is_finite() && hi.is_finite()) {
                return if axis.log { (1.0, 10.0) } else { (0.0, 1.0) };
            }
            pad(lo, hi, axis.log)
        };
        let mut xr = span(&xs, &self.x);
        let mut yr = span(&ys, &self.y);
        if self.equal_scale && !self.x.log && !self.y.log {
            let (pw, ph) = self.plot_px();
            let per_px = ((xr.1 - xr.0) / pw).max((yr.1 - yr.0) / ph);
            let (cx, cy) = (0.5 * (xr.0 + xr.1), 0.5 * (yr.0 + yr.1));
            xr = (cx - 0.5 * per_px * pw, cx + 0.5 * per_px * pw);
            yr = (cy - 0.5 * per_px * ph, cy + 0.5 * per_px * ph);
        }
        (xr, yr, empty)
    }

    /// The plot area's size, px.
    fn plot_px(&self) -> (f64, f64) {
        let w = self
            .size
            .0
            .saturating_sub(2 * MARGIN + Y_LABEL_AREA)
            .max(10);
        let h = self
            .size
            .1
            .saturating_sub(2 * MARGIN + X_LABEL_AREA + CAPTION_AREA)
            .max(10);
        (f64::from(w), f64::from(h))
    }

    fn draw<X, Y>(
        &self,
        root: &DrawingArea<SVGBackend, Shift>,
        x: X,
        y: Y,
        view: Option<((f64, f64), (f64, f64))>,
    ) -> Result<(), String>
    where
        X: AsRangedCoord<Value = f64>,
        Y: AsRangedCoord<Value = f64>,
        X::CoordDescType: ValueFormatter<f64>,
        Y::CoordDescType: ValueFormatter<f64>,
    {
        let mut chart = self.chart(root, x, y)?;
        let Some((vx, vy)) = view else {
            return no_data(root);
        };
        let (px, py) = chart.plotting_area().get_pixel_range();
        let view = View {
            vx,
            vy,
            xlog: self.x.log,
            ylog: self.y.log,
            px,
            py,
        };
        let bands_labelled = self.draw_bands(&mut chart, &view)?;
        let series_labelled = self.draw_series(&mut chart, &view)?;
        if bands_labelled || series_labelled {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .background_style(WHITE.mix(0.6))
                .border_style(RGBColor(0x99, 0x99, 0x99))
                .label_font((FONT, 16))
                .draw()
                .map_err(draw_error)?;
        }
        Ok(())
    }

    /// The chart on `root`: the caption, the axes and the mesh.
    fn chart<'a, 'b, X, Y>(
        &self,
        root: &'a DrawingArea<SVGBackend<'b>, Shift>,
        x: X,
        y: Y,
    ) -> Result<Chart<'a, 'b, X::CoordDescType, Y::CoordDescType>, String>
    where
        X: AsRangedCoord<Value = f64>,
        Y: AsRangedCoord<Value = f64>,
        X::CoordDescType: ValueFormatter<f64>,
        Y::CoordDescType: ValueFormatter<f64>,
    {
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, (FONT, 22))
            .margin(MARGIN)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(x, y)
            .map_err(draw_error)?;
        let (xr, yr) = (chart.x_range(), chart.y_range());
        let x_fmt = formatter(xr.start, xr.end, self.x.log);
        let y_fmt = formatter(yr.start, yr.end, self.y.log);
        chart
            .configure_mesh()
            .x_desc(self.x.description())
            .y_desc(self.y.description())
            .x_label_formatter(&x_fmt)
            .y_label_formatter(&y_fmt)
            .x_labels(10)
            .y_labels(8)
            .label_style((FONT, 16))
            .axis_desc_style((FONT, 17))
            .light_line_style(RGBColor(0xee, 0xee, 0xee))
            .bold_line_style(RGBColor(0xd8, 0xd8, 0xd8))
            .draw()
            .map_err(draw_error)?;
        Ok(chart)
    }

    /// The bands, filled; whether one went into the legend.
    fn draw_bands<'a, 'b: 'a, XC, YC>(
        &self,
        chart: &mut Chart<'a, 'b, XC, YC>,
        view: &View,
    ) -> Result<bool, String>
    where
        XC: Ranged<ValueType = f64>,
        YC: Ranged<ValueType = f64>,
    {
        let mut labelled = false;
        for b in &self.bands {
            let colour = b.colour.rgb().mix(0.18);
            let lower = b.points.iter().map(|p| (p[0], p[1]));
            let upper = b.points.iter().rev().map(|p| (p[0], p[2]));
            let outline: Vec<(f64, f64)> = lower
                .chain(upper)
                .filter(|p| view.shows(&[p.0, p.1]))
                .collect();
            if outline.len() < 3 {
                continue;
            }
            let anno = chart
                .draw_series(std::iter::once(Polygon::new(outline, colour.filled())))
                .map_err(draw_error)?;
            if !b.label.is_empty() {
                labelled = true;
                anno.label(b.label.as_str()).legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 20, y + 5)], colour.filled())
                });
            }
        }
        Ok(labelled)
    }

    /// The series, as lines and dots, one point per pixel; whether one
    /// went into the legend.
    fn draw_series<'a, 'b: 'a, XC, YC>(
        &self,
        chart: &mut Chart<'a, 'b, XC, YC>,
        view: &View,
    ) -> Result<bool, String>
    where
        XC: Ranged<ValueType = f64>,
        YC: Ranged<ValueType = f64>,
    {
        let pixel = |p: (f64, f64)| view.pixel(p);
        let mut labelled = false;
        for s in &self.series {
            let colour = s.colour.rgb().mix(s.opacity.clamp(0.0, 1.0));
            let (width, radius) = match s.mark {
                Mark::Line { width } => (Some(width), None),
                Mark::Dots { radius } => (None, Some(radius)),
                Mark::LineAndDots { width, radius } => (Some(width), Some(radius)),
            };
            let mut first = true;
            for pts in view.runs(&s.parts) {
                let label_here = first && !s.label.is_empty();
                let legend_w = width.unwrap_or(0);
                let dot = radius.unwrap_or(0).max(3);
                let legend = move |(x, y): (i32, i32)| {
                    if legend_w > 0 {
                        PathElement::new(
                            vec![(x, y), (x + 20, y)],
                            colour.stroke_width(legend_w.max(2)),
                        )
                        .into_dyn()
                    } else {
                        Circle::new((x + 10, y), dot, colour.filled()).into_dyn()
                    }
                };
                if let Some(w) = width {
                    let line = thin(&one_per_pixel(pts.clone(), &pixel, true), MAX_LINE_POINTS);
                    let anno = chart
                        .draw_series(LineSeries::new(line, colour.stroke_width(w)))
                        .map_err(draw_error)?;
                    if label_here && radius.is_none() {
                        labelled = true;
                        anno.label(s.label.as_str()).legend(legend);
                    }
                }
                if let Some(r) = radius {
                    let dots = thin(&one_per_pixel(pts.clone(), &pixel, false), MAX_DOTS);
                    let anno = chart
                        .draw_series(dots.into_iter().map(|p| Circle::new(p, r, colour.filled())))
                        .map_err(draw_error)?;
                    if label_here {
                        labelled = true;
                        anno.label(s.label.as_str()).legend(legend);
                    }
                }
                first = false;
            }
        }
        Ok(labelled)
    }
}

/// A chart of the SVG backend on two f64 axes.
type Chart<'a, 'b, XC, YC> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<XC, YC>>;

/// A drawing error as text.
fn draw_error(e: DrawingAreaErrorKind<std::io::Error>) -> String {
    e.to_string()
}

/// "no data" in the middle of `root` (a figure without a finite point).
fn no_data(root: &DrawingArea<SVGBackend, Shift>) -> Result<(), String> {
    let (w, h) = root.dim_in_pixel();
    let style = TextStyle::from((FONT, 18).into_font())
        .color(&RGBColor(0x66, 0x66, 0x66))
        .pos(Pos::new(HPos::Center, VPos::Center));
    root.draw_text("no data", &style, ((w / 2) as i32, (h / 2) as i32))
        .map_err(draw_error)
}

/// The visible ranges of a chart and where they land in pixels.
struct View {
    vx: (f64, f64),
    vy: (f64, f64),
    xlog: bool,
    ylog: bool,
    px: std::ops::Range<i32>,
    py: std::ops::Range<i32>,
}

impl View {
    /// Drawn: finite points inside the view (a fixed range clips: a line
    /// is broken where it leaves it).
    fn shows(&self, p: &[f64; 2]) -> bool {
        let within = |v: f64, r: (f64, f64)| v >= r.0.min(r.1) && v <= r.0.max(r.1);
        p[0].is_finite()
            && p[1].is_finite()
            && (!self.xlog || p[0] > 0.0)
            && (!self.ylog || p[1] > 0.0)
            && within(p[0], self.vx)
            && within(p[1], self.vy)
    }

    /// The pixel a point lands on: points on the same pixel draw nothing new.
    fn pixel(&self, p: (f64, f64)) -> (i32, i32) {
        let axis_px = |v: f64, r: (f64, f64), log: bool, a: i32, b: i32| -> i32 {
            let f = |v: f64| if log { v.ln() } else { v };
            let u = (f(v) - f(r.0)) / (f(r.1) - f(r.0));
            (f64::from(a) + u * f64::from(b - a)).round() as i32
        };
        (
            axis_px(p.0, self.vx, self.xlog, self.px.start, self.px.end),
            axis_px(p.1, self.vy, self.ylog, self.py.end, self.py.start),
        )
    }

    /// The runs of consecutive shown points of `parts`: a line is broken
    /// where a point is not shown.
    fn runs(&self, parts: &[Vec<[f64; 2]>]) -> Vec<Vec<(f64, f64)>> {
        let mut runs = Vec::new();
        for part in parts {
            let mut run = Vec::new();
            for p in part {
                if self.shows(p) {
                    run.push((p[0], p[1]));
                } else if !run.is_empty() {
                    runs.push(std::mem::take(&mut run));
                }
            }
            if !run.is_empty() {
                runs.push(run);
            }
        }
        runs
    }
}

/// `lo..hi` with a little room at both ends (multiplicative on a log
/// axis), never empty.
fn pad(lo: f64, hi: f64, log: bool) -> (f64, f64) {
    if log {
        let (a, b) = (lo.ln(), hi.ln());
        let (a, b) = if b - a < 1e-9 {
            (a - 0.5, b + 0.5)
        } else {
            (a, b)
        };
        let m = 0.04 * (b - a);
        return ((a - m).exp(), (b + m).exp());
    }
    let (lo, hi) = if hi - lo <= 1e-12 * lo.abs().max(1.0) {
        let d = 0.5 * lo.abs().max(1e-3);
        (lo - d, hi + d)
    } else {
        (lo, hi)
    };
    let m = 0.04 * (hi - lo);
    (lo - m, hi + m)
}

/// `pts` without the points that land on the pixel of one drawn before:
/// with `consecutive`, only the previous point counts (a line keeps its
/// path), else every one drawn so far (dots).
fn one_per_pixel(
    pts: Vec<(f64, f64)>,
    pixel: &dyn Fn((f64, f64)) -> (i32, i32),
    consecutive: bool,
) -> Vec<(f64, f64)> {
    let mut seen = std::collections::HashSet::new();
    let mut last = None;
    let mut out = Vec::with_capacity(pts.len());
    let n = pts.len();
    for (i, p) in pts.into_iter().enumerate() {
        let px = pixel(p);
        let new = if consecutive {
            last != Some(px) || i + 1 == n
        } else {
            seen.insert(px)
        };
        if new {
            out.push(p);
        }
        last = Some(px);
    }
    out
}

/// Every `n / max`-th point, the last one kept.
fn thin(pts: &[(f64, f64)], max: usize) -> Vec<(f64, f64)> {
    if pts.len() <= max {
        return pts.to_vec();
    }
    let stride = pts.len().div_ceil(max);
    let mut out: Vec<(f64, f64)> = pts.iter().copied().step_by(stride).collect();
    if let Some(last) = pts.last() {
        if out.last() != Some(last) {
            out.push(*last);
        }
    }
    out
}

/// Tick labels with as many decimals as the range needs (scientific
/// notation for very small or large values).
fn formatter(lo: f64, hi: f64, log: bool) -> impl Fn(&f64) -> String {
    let span = (hi - lo).abs();
    let decimals = if span > 0.0 {
        (-(span / 10.0).log10().floor()).clamp(0.0, 9.0) as usize
    } else {
        3
    };
    move |v: &f64| {
        let v = *v;
        // A tick at zero computed as 1e-16 is zero.
        if v == 0.0 || (!log && v.abs() < 1e-9 * span) {
            return "0".to_string();
        }
        let a = v.abs();
        if log || !(1e-4..1e6).contains(&a) {
            if (1e-3..1e5).contains(&a) {
                return trim(format!("{v:.6}"));
            }
            return format!("{v:.0e}");
        }
        trim(format!("{v:.decimals$}"))
    }
}

/// "1.2500" -> "1.25", "3.000" -> "3".
fn trim(s: String) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The text of every `<text>` element.
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

    fn sine() -> Vec<[f64; 2]> {
        (0..200)
            .map(|i| {
                let t = f64::from(i) * 0.1;
                [t, t.sin()]
            })
            .collect()
    }

    #[test]
    fn a_figure_has_its_axis_titles_units_ticks_and_legend() {
        let svg = Figure::new(
            "A sine",
            Axis::linear("time", "s"),
            Axis::linear("residual", "m"),
        )
        .with(Series::line("the sine", sine(), Colour::BLUE))
        .svg()
        .expect("drawn");
        assert!(svg.starts_with("<svg"), "{}", &svg[..80]);
        let t = texts(&svg);
        for text in ["A sine", "time, s", "residual, m", "the sine"] {
            assert!(t.iter().any(|s| s == text), "no `{text}` in {t:?}");
        }
        // Ticks: labels at round values on both axes.
        for tick in ["-0.5", "0.5", "5", "10"] {
            assert!(t.iter().any(|s| s == tick), "no tick {tick} in {t:?}");
        }
    }

    #[test]
    fn a_log_axis_draws_only_positive_values_and_labels_decades() {
        let pts = vec![
            [0.0, 1000.0],
            [1.0, 10.0],
            [2.0, 0.1],
            [3.0, 0.0],
            [4.0, -1.0],
        ];
        let fig = Figure::new(
            "log",
            Axis::linear("iteration", ""),
            Axis::log("error", "m"),
        )
        .with(Series::line("e", pts, Colour::BLUE));
        let (_, ys) = fig.drawable();
        assert_eq!(ys, vec![1000.0, 10.0, 0.1]);
        let svg = fig.svg().expect("drawn");
        let t = texts(&svg);
        for tick in ["0.1", "1", "10", "100", "1000"] {
            assert!(t.iter().any(|s| s == tick), "no decade {tick} in {t:?}");
        }
    }

    #[test]
    fn a_map_has_equal_metres_per_pixel_on_both_axes() {
        let fig = Figure::new("map", Axis::linear("east", "m"), Axis::linear("north", "m"))
            .with(Series::line(
                "track",
                vec![[0.0, 0.0], [1000.0, 10.0]],
                Colour::BLACK,
            ))
            .map((800, 800));
        let (xr, yr, _) = fig.ranges();
        let (pw, ph) = fig.plot_px();
        let (sx, sy) = ((xr.1 - xr.0) / pw, (yr.1 - yr.0) / ph);
        assert!((sx / sy - 1.0).abs() < 1e-9, "{sx} vs {sy} m/px");
        assert!(xr.0 <= 0.0 && xr.1 >= 1000.0);
    }

    #[test]
    fn no_data_is_said_not_drawn_as_an_error() {
        let svg = Figure::new("empty", Axis::linear("x", "s"), Axis::linear("y", "m"))
            .with(Series::line("nothing", vec![[f64::NAN, 1.0]], Colour::BLUE))
            .svg()
            .expect("drawn");
        assert!(svg.contains("no data"));
    }

    #[test]
    fn a_band_is_drawn_below_its_line() {
        let band = Band {
            label: "1 sigma".to_string(),
            points: (0..10).map(|i| [f64::from(i), -1.0, 1.0]).collect(),
            colour: Colour::BLUE,
        };
        let svg = Figure::new("band", Axis::linear("t", "s"), Axis::linear("e", "m"))
            .with_band(band)
            .with(Series::line("e", sine(), Colour::BLUE))
            .svg()
            .expect("drawn");
        let poly = svg.find("<polygon").expect("a polygon");
        // The grid lines come first, the series' line last.
        let line = svg.rfind("<polyline").expect("a line");
        assert!(poly < line, "the band is drawn over the line");
        assert!(svg.contains("1 sigma"));
    }

    #[test]
    fn a_fixed_range_clips_and_breaks_the_line_and_the_description_is_its_desc() {
        let mut y = Axis::linear("y", "m");
        y.range = Some((-1.0, 1.0));
        let pts = vec![[0.0, 0.0], [1.0, 0.5], [2.0, 5.0], [3.0, 0.5], [4.0, 0.0]];
        let svg = Figure::new("clip & cut", Axis::linear("x", "s"), y)
            .with(Series::line("", pts, Colour::BLUE))
            .describe("a <line> cut in two")
            .svg()
            .expect("drawn");
        assert!(svg.contains("<title>clip &amp; cut</title>"));
        assert!(svg.contains("<desc>a &lt;line&gt; cut in two</desc>"));
        let lines = svg
            .split("<polyline")
            .filter(|p| p.contains("stroke=\"#0072B2\""))
            .count();
        assert_eq!(lines, 2, "the line is broken where it leaves the range");
    }

    #[test]
    fn dots_on_one_pixel_are_drawn_once() {
        let mut pts = vec![[0.0, 0.0], [10.0, 10.0]];
        pts.extend((0..5000).map(|i| [5.0 + 1e-6 * f64::from(i), 5.0]));
        let svg = Figure::new("dense", Axis::linear("x", "s"), Axis::linear("y", "m"))
            .with(Series::dots("", pts, Colour::BLUE))
            .svg()
            .expect("drawn");
        assert_eq!(svg.matches("<circle").count(), 3);
    }

    #[test]
    fn tick_labels_have_the_decimals_the_range_needs() {
        let f = formatter(3.15, 3.17, false);
        assert_eq!(f(&3.155), "3.155");
        let f = formatter(0.0, 1000.0, false);
        assert_eq!(f(&200.0), "200");
        let f = formatter(-0.6, 0.8, false);
        assert_eq!(f(&-1.1e-16), "0");
        let f = formatter(1e-3, 1e3, true);
        assert_eq!(f(&0.01), "0.01");
        assert_eq!(f(&1e-5), "1e-5");
    }
}
