//! The figures and pages of wheelcal's reports, in one home for the
//! calibration page (`calibrator calibrate --plots`), the diagnosis page
//! (`calibrator diagnose`) and the evaluation page (`odometry evaluate
//! --plots`).
//!
//! - [`figure`]: a [`Figure`] (series of points or lines, bands, axes with
//!   their units, linear or logarithmic, optionally at equal scale) drawn
//!   as SVG with `plotters`: axes, ticks, grid, units, legend;
//! - [`page`]: a [`Page`] (headings, paragraphs, the warnings, tables of
//!   numbers, figures with captions) rendered as one self-contained HTML
//!   document (inline CSS and SVG, nothing fetched).
//!
//! Pure: data in, strings out; the binaries write the files.

pub mod figure;
pub mod page;

pub use figure::{Axis, Band, Colour, Figure, FigureError, Mark, Series};
pub use page::{escape, Cell, Page};
