//! Plots of one result quantity against time, and of a point's path in a 3D projection (SVG).
//!
//! A [`Trace`] collects one body's or one point's quantity from the analysis' results, step
//! by step, keeping at most [`MAX_SAMPLES`] evenly spaced time points so that the SVG stays
//! small whatever the grid; [`draw`] writes the chart. Units are SI, as the description
//! format assumes: lengths in m, angles in rad, time in s.

use std::path::Path;

use plotters::prelude::*;

use crate::draw::{self, DrawError, PALETTE, backend, padded, tick};
use crate::report::StepResult;

/// The most time points a trace keeps; longer runs are sampled evenly (every k-th step,
/// always including the first and the last computed).
pub const MAX_SAMPLES: usize = 2000;

/// What is plotted: a point of interest or a body, by name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Target {
    /// A point of interest (`[[points]]`).
    Point(String),
    /// A body's frame (`[[bodies]]`, not ground).
    Body(String),
}

/// The quantity plotted against time (global components).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// Position: r_P of a point, the origin r of a body (m).
    R,
    /// Velocity: v_P of a point, ṙ of a body (m/s).
    V,
    /// Acceleration: a_P of a point, r̈ of a body (m/s²).
    A,
    /// A body's Euler parameters p = [e0, e1, e2, e3] (dimensionless).
    P,
    /// A body's angular velocity ω = 2 G(p) ṗ (rad/s; thesis eq. 3.34).
    Omega,
    /// A body's angular acceleration α = 2 G(p) p̈ (rad/s²).
    Alpha,
}

impl Quantity {
    /// The symbol and unit for the axis label.
    fn label(self, target: &Target) -> (&'static str, &'static str) {
        let point = matches!(target, Target::Point(_));
        match self {
            Self::R => (if point { "r_P" } else { "r" }, "m"),
            Self::V => (if point { "v_P" } else { "ṙ" }, "m/s"),
            Self::A => (if point { "a_P" } else { "r̈" }, "m/s²"),
            Self::P => ("p", "1"),
            Self::Omega => ("ω", "rad/s"),
            Self::Alpha => ("α", "rad/s²"),
        }
    }

    /// The names of its components.
    fn components(self) -> &'static [&'static str] {
        match self {
            Self::P => &["e0", "e1", "e2", "e3"],
            _ => &["x", "y", "z"],
        }
    }
}

/// Why a step holds no value of the quantity for the target.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TraceError {
    /// The step has no point of interest of this name.
    #[error("no point \"{0}\"")]
    NoPoint(String),
    /// The step has no moving body of this name (it does not exist or is ground).
    #[error("no moving body \"{0}\"")]
    NoBody(String),
    /// `p`, `omega` or `alpha` was asked of this point.
    #[error("a point has no orientation: use --quantity r, v or a for point \"{0}\"")]
    NoOrientation(String),
}

/// One quantity of one body or point over time, and the path of its position.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    /// Time of each sample (s).
    pub t: Vec<f64>,
    /// The quantity's components at each sample (3, or 4 for Euler parameters).
    pub values: Vec<Vec<f64>>,
    /// The position of the point (or body origin) at each sample, for the 3D path.
    pub path: Vec<[f64; 3]>,
    /// Steps seen so far.
    seen: usize,
    /// Keep every `stride`-th step.
    stride: usize,
    /// The last step seen, kept so that the final time point is always drawn.
    last: Option<(f64, Vec<f64>, [f64; 3])>,
}

impl Trace {
    /// An empty trace for a grid of `steps` time points.
    #[must_use]
    pub fn new(steps: usize) -> Self {
        Self { stride: steps.div_ceil(MAX_SAMPLES - 1).max(1), ..Self::default() }
    }

    /// Records one step's value of `quantity` for `target`.
    ///
    /// # Errors
    ///
    /// The target is not in the step (no such point, or a ground body), or the quantity does
    /// not apply to a point (`p`, `omega`, `alpha`).
    pub fn push(
        &mut self,
        step: &StepResult,
        target: &Target,
        quantity: Quantity,
    ) -> Result<(), TraceError> {
        let (value, position) = extract(step, target, quantity)?;
        if self.seen.is_multiple_of(self.stride) {
            self.t.push(step.t);
            self.values.push(value);
            self.path.push(position);
            self.last = None;
        } else {
            self.last = Some((step.t, value, position));
        }
        self.seen += 1;
        Ok(())
    }

    /// Adds the last step seen if sampling skipped it; call once after the last [`push`].
    ///
    /// [`push`]: Self::push
    pub fn close(&mut self) {
        if let Some((t, value, position)) = self.last.take() {
            self.t.push(t);
            self.values.push(value);
            self.path.push(position);
        }
    }
}

/// The value of `quantity` and the position for `target` at one step.
fn extract(
    step: &StepResult,
    target: &Target,
    quantity: Quantity,
) -> Result<(Vec<f64>, [f64; 3]), TraceError> {
    match target {
        Target::Point(name) => {
            let p = step
                .points
                .iter()
                .find(|p| p.name == *name)
                .ok_or_else(|| TraceError::NoPoint(name.clone()))?;
            let value = match quantity {
                Quantity::R => p.r,
                Quantity::V => p.v,
                Quantity::A => p.a,
                Quantity::P | Quantity::Omega | Quantity::Alpha => {
                    return Err(TraceError::NoOrientation(name.clone()));
                }
            };
            Ok((value.to_vec(), p.r))
        }
        Target::Body(name) => {
            let b = step
                .bodies
                .iter()
                .find(|b| b.name == *name)
                .ok_or_else(|| TraceError::NoBody(name.clone()))?;
            let value = match quantity {
                Quantity::R => b.r.to_vec(),
                Quantity::V => b.r_dot.to_vec(),
                Quantity::A => b.r_ddot.to_vec(),
                Quantity::P => b.p.to_vec(),
                Quantity::Omega => b.omega.to_vec(),
                Quantity::Alpha => b.alpha.to_vec(),
            };
            Ok((value, b.r))
        }
    }
}

/// Writes the chart of `trace` as SVG at `path`: the quantity's components against time and,
/// when `with_path` is set, the path of the position in a 3D projection beside it.
///
/// # Errors
///
/// An empty trace, or a drawing or I/O failure.
pub fn draw(
    trace: &Trace,
    target: &Target,
    quantity: Quantity,
    title: &str,
    with_path: bool,
    path: &Path,
) -> Result<(), DrawError> {
    if trace.t.is_empty() {
        return Err(DrawError::NoTimePoints);
    }
    let size = if with_path { (1200, 480) } else { (720, 480) };
    draw::write_svg(path, size, |root| {
        root.fill(&WHITE).map_err(backend)?;
        let root = root.titled(title, ("sans-serif", 20)).map_err(backend)?;
        let (left, right) =
            if with_path { root.split_horizontally(720) } else { (root.clone(), root) };

        let (symbol, unit) = quantity.label(target);
        let names = quantity.components();
        let t_range = padded(trace.t.iter().copied());
        let t_range =
            if trace.t.len() == 1 { t_range } else { trace.t[0]..trace.t[trace.t.len() - 1] };
        let v_range = padded(trace.values.iter().flatten().copied());
        let mut chart = ChartBuilder::on(&left)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(t_range, v_range)
            .map_err(backend)?;
        chart
            .configure_mesh()
            .max_light_lines(0)
            .axis_desc_style(("sans-serif", 15))
            .x_desc("t (s)")
            .y_desc(format!("{symbol} ({unit})"))
            .x_label_formatter(&|v| tick(*v))
            .y_label_formatter(&|v| tick(*v))
            .draw()
            .map_err(backend)?;
        for (k, name) in names.iter().enumerate() {
            let color = PALETTE[k % PALETTE.len()];
            let points = trace.t.iter().zip(&trace.values).map(|(&t, v)| (t, v[k]));
            chart
                .draw_series(LineSeries::new(points, color.stroke_width(2)))
                .map_err(backend)?
                .label(format!("{symbol}.{name}"))
                .legend(draw::line_key(color, 18));
        }
        draw::legend(&mut chart)?;

        if with_path {
            draw_path(&right, &trace.path)?;
        }
        left.present().map_err(backend)?;
        Ok(())
    })
}

/// The path in a 3D projection, every tick labelled with its axis (metres, as the caption
/// says); the start is a filled circle.
fn draw_path<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    path: &[[f64; 3]],
) -> Result<(), DrawError> {
    // One cube around the path, so that the projection does not distort its shape.
    let ranges: Vec<std::ops::Range<f64>> = (0..3)
        .map(|k| {
            let (lo, hi) =
                path.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| (lo.min(p[k]), hi.max(p[k])));
            lo..hi
        })
        .collect();
    // Half the largest extent with 5% room; a path that does not move gets a unit cube.
    let half = 1.05 * ranges.iter().map(|r| (r.end - r.start) / 2.0).fold(0.0, f64::max);
    let half = if half > 0.0 { half } else { 1.0 };
    let cube: Vec<std::ops::Range<f64>> = ranges
        .iter()
        .map(|r| {
            let mid = (r.start + r.end) / 2.0;
            mid - half..mid + half
        })
        .collect();
    let mut chart = ChartBuilder::on(area)
        .margin(20)
        .caption("path (m)", ("sans-serif", 16))
        .build_cartesian_3d(cube[0].clone(), cube[1].clone(), cube[2].clone())
        .map_err(backend)?;
    chart.with_projection(|mut p| {
        p.yaw = 0.6;
        p.pitch = 0.35;
        p.scale = 0.8;
        p.into_matrix()
    });
    // Each tick names its axis, so that the projection cannot be misread.
    let (fx, fy, fz) = (
        |v: &f64| format!("x {}", tick(*v)),
        |v: &f64| format!("y {}", tick(*v)),
        |v: &f64| format!("z {}", tick(*v)),
    );
    chart
        .configure_axes()
        .light_grid_style(BLACK.mix(0.08))
        .max_light_lines(3)
        .x_labels(4)
        .y_labels(4)
        .z_labels(4)
        .x_formatter(&fx)
        .y_formatter(&fy)
        .z_formatter(&fz)
        .draw()
        .map_err(backend)?;
    let points = path.iter().map(|p| (p[0], p[1], p[2]));
    chart.draw_series(LineSeries::new(points, PALETTE[0].stroke_width(2))).map_err(backend)?;
    if let Some(p) = path.first() {
        chart
            .draw_series([Circle::new((p[0], p[1], p[2]), 4, PALETTE[3].filled())])
            .map_err(backend)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests;
