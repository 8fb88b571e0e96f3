//! The drawing shared by [`crate::chart`] and [`crate::plot`]: an SVG written all at once,
//! the colours, the legend box, tick labels and padded axis ranges (plotters).
//!
//! It runs nothing: no analysis, no engine, no build. The modules that compute what is
//! drawn sit on top of it.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

/// Why a chart could not be drawn or written.
#[derive(Debug, thiserror::Error)]
pub enum DrawError {
    /// A speed-against-accuracy or conditioning chart without a single mark.
    #[error("nothing to draw")]
    NoMarks,
    /// A plot of an analysis that stopped before its first time point.
    #[error("nothing to draw: the analysis computed no time point")]
    NoTimePoints,
    /// The drawing backend failed (plotters' own words).
    #[error("{0}")]
    Backend(String),
    /// The SVG could not be written (the message names the file).
    #[error(transparent)]
    Write(#[from] std::io::Error),
}

/// A drawing backend's error as a [`DrawError`], for `map_err`.
pub(crate) fn backend(e: impl std::fmt::Display) -> DrawError {
    DrawError::Backend(e.to_string())
}

/// Series colours in order (the common Tableau 10 palette).
pub(crate) const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// Draws with `draw` on an SVG drawing area of `size` pixels, then writes the SVG to `path`
/// all at once ([`crate::output::write_file`]): a failed drawing leaves the previous file.
///
/// # Errors
/// The drawing's error, or the I/O error naming `path`.
pub(crate) fn write_svg(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(DrawingArea<SVGBackend<'_>, Shift>) -> Result<(), DrawError>,
) -> Result<(), DrawError> {
    let mut svg = String::new();
    draw(SVGBackend::with_string(&mut svg, size).into_drawing_area())?;
    Ok(crate::output::write_file(path, svg.as_bytes())?)
}

/// Draws a chart's series labels in its upper right corner, on a translucent white box.
///
/// # Errors
/// The drawing backend's error.
pub(crate) fn legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
) -> Result<(), DrawError> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(backend)
}

/// The legend key of a line series: a short line `length` pixels long in `color`.
pub(crate) fn line_key(
    color: RGBColor,
    length: i32,
) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new([(x, y), (x + length, y)], color.stroke_width(2))
}

/// A tick label: plain decimals with four significant digits from 1e-3 to 1e5, scientific
/// notation beyond.
pub(crate) fn tick(v: f64) -> String {
    let a = v.abs();
    if a < 1e-12 {
        "0".to_owned()
    } else if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        let text = format!("{v:.decimals$}");
        if text.contains('.') {
            text.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            text
        }
    } else {
        format!("{v:.2e}")
    }
}

/// The range of `values` with 5% room on each side (one unit around a constant).
pub(crate) fn padded(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values.fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if lo > hi {
        return -1.0..1.0;
    }
    let room = if hi - lo > 1e-12 * hi.abs().max(lo.abs()) { 0.05 * (hi - lo) } else { 1.0 };
    lo - room..hi + room
}
