//! Speed against accuracy: every engine and setting of one mechanism as a mark on a log–log
//! chart of ns per time point against the error to a reference solution.
//!
//! The reference is the description solved in double-double arithmetic (`crate::reference`:
//! about 32 digits, its residual near 1e-30), independent of both engines' double-precision
//! arithmetic, so every mark, the generic engine's at its tightest tolerance included, shows
//! its own error. The error of a run is the largest difference from the reference over the
//! compared time points, taken separately for positions, velocities and accelerations, each
//! relative to the largest magnitude of that quantity in the reference there, and then the
//! largest of the three. The compared points are every point of a grid of at most
//! [`ERROR_SAMPLES`] points, else that many evenly spaced ones (the first and last among them):
//! only they are kept from the reference, so memory does not grow with the grid, and runs are
//! compared as their frames arrive.

use std::path::Path;

use plotters::prelude::*;

use crate::draw::{self, DrawError, PALETTE, backend};
use crate::emit::Scalar;
use crate::engine::{EngineError, Settings};
use crate::generic::{Analysis, Equations, Frame};
use crate::model::Mechanism;
use crate::reference::{self, Error, ReferenceError, ReferenceFrame};

/// Tolerances swept for every engine in double precision.
pub const TOLERANCES: [f64; 6] = [1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14];

/// Tolerances swept for the single-precision generated solver: single precision carries 7
/// digits, so residuals of unit size stop near 1e-7 and tighter tolerances cannot be met.
pub const F32_TOLERANCES: [f64; 3] = [1e-3, 1e-4, 1e-5];

/// Tolerance of the generic run the reference starts from at every compared time point: any
/// double-precision solution on the branch serves, Newton in double-double converging from it
/// in two or three iterations to the same point.
const START_TOLERANCE: f64 = 1e-12;

/// Why a chart's runs could not be measured.
#[derive(Debug, thiserror::Error)]
pub enum ChartError {
    /// The reference failed (see `crate::reference`).
    #[error(transparent)]
    Reference(#[from] ReferenceError),
    /// The conditioning chart needs as many equations as unknowns.
    #[error("the chart needs a square Φ_q (no redundant equations)")]
    NotSquare,
    /// The generic analysis stopped before the end of the grid.
    #[error("the generic analysis stopped")]
    GenericStopped,
    /// The generated engine stopped before the end of the grid, with its failure's message.
    #[error("the generated engine stopped: {0}")]
    GeneratedStopped(String),
    /// The generated engine could not run.
    #[error(transparent)]
    Engine(#[from] EngineError),
}

/// One engine and setting.
#[derive(Clone, Debug, PartialEq)]
pub struct Mark {
    /// The series it belongs to: engine and options, e.g. `generic, no predictor`.
    pub series: String,
    /// The Newton tolerance.
    pub tolerance: f64,
    /// Median ns per time point.
    pub ns_per_step: f64,
    /// Newton iterations per time point.
    pub iterations: f64,
    /// Largest relative error to the reference (see the module docs).
    pub error: f64,
}

/// The most time points a run is compared with the reference at (see the module docs): every
/// shipped example and benchmark has fewer.
pub const ERROR_SAMPLES: usize = reference::SAMPLES;

/// The error of one generic run against `reference`, `None` if it fails.
fn generic_error(
    analysis: &Analysis<'_, '_>,
    reference: &[ReferenceFrame],
    count: usize,
) -> Option<f64> {
    let mut error = Error::new(reference);
    let r = analysis
        .run(|f| {
            error.add(f);
            Ok::<(), ()>(())
        })
        .ok()?;
    r.failure.is_none().then_some(())?;
    error.finish(count)
}

/// Measures every mark of `mech`: the generic engine with and without its predictor, and
/// the generated engine (when it can be built) with and without the predictor, with its
/// static pivot orders or dense LU only, at every tolerance of [`TOLERANCES`], and in single
/// precision at [`F32_TOLERANCES`]. Runs that fail (no convergence at a tolerance below
/// round-off, say) are left out and named in the second list.
///
/// # Errors
/// When the reference run itself fails.
pub fn measure(mech: &Mechanism, repeats: usize) -> Result<(Vec<Mark>, Vec<String>), ChartError> {
    measure_with(mech, repeats, &mut |_, _| {})
}

/// A floating-point type of the generated solver, its series (name and settings) and their
/// tolerances.
type Variant = (Scalar, &'static [(&'static str, Settings)], &'static [f64]);

/// The generated solver's series: in double precision with and without the predictor and
/// with dense LU only, at [`TOLERANCES`]; in single precision at [`F32_TOLERANCES`].
const GENERATED: [Variant; 2] = [
    (
        Scalar::F64,
        &[
            ("generated", Settings::DEFAULT),
            ("generated, no predictor", Settings { predictor: false, ..Settings::DEFAULT }),
            ("generated, dense LU", Settings { dense_lu: true, ..Settings::DEFAULT }),
        ],
        &TOLERANCES,
    ),
    (Scalar::F32, &[("generated, f32", Settings::DEFAULT)], &F32_TOLERANCES),
];

/// The number of marks [`measure`] attempts: the generic engine with and without its
/// predictor at every tolerance of [`TOLERANCES`], and every series of [`GENERATED`] at its
/// tolerances.
#[must_use]
pub fn mark_count() -> usize {
    2 * TOLERANCES.len()
        + GENERATED
            .iter()
            .map(|(_, series, tolerances)| series.len() * tolerances.len())
            .sum::<usize>()
}

/// As [`measure`], calling `done(series, tolerance)` after each mark is attempted (for
/// progress reports).
///
/// # Errors
/// When the reference run itself fails.
pub fn measure_with(
    mech: &Mechanism,
    repeats: usize,
    done: &mut dyn FnMut(&str, f64),
) -> Result<(Vec<Mark>, Vec<String>), ChartError> {
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    let count = mech.time.count;
    let analysis = Analysis::new(&eq, &prep).with_tolerance(START_TOLERANCE);
    let reference = reference::frames(&eq, &analysis, ERROR_SAMPLES)?;
    let mut marks = Vec::new();
    let mut skipped = Vec::new();
    for predictor in [true, false] {
        let series =
            if predictor { "generic".to_owned() } else { "generic, no predictor".to_owned() };
        for &tolerance in &TOLERANCES {
            let analysis =
                Analysis::new(&eq, &prep).with_tolerance(tolerance).with_predictor(predictor);
            match (generic_error(&analysis, &reference, count), analysis.time(repeats).ok()) {
                (Some(error), Some((_, median, iterations))) => marks.push(Mark {
                    series: series.clone(),
                    tolerance,
                    ns_per_step: median,
                    iterations,
                    error,
                }),
                _ => skipped.push(format!("{series} at tolerance {tolerance:e}")),
            }
            done(&series, tolerance);
        }
    }
    for (scalar, series, tolerances) in GENERATED {
        let built = match crate::engine::build_in(mech, scalar) {
            Ok(b) => b,
            Err(e) => {
                skipped.push(format!("generated in {}: {e}", scalar.name()));
                continue;
            }
        };
        for &(name, settings) in series {
            for &tolerance in tolerances {
                let mut error = Error::new(&reference);
                let namer = Analysis::new(&eq, &prep);
                let run = crate::engine::run_with(&built, &namer, Some(tolerance), settings, |f| {
                    error.add(f);
                    Ok(())
                });
                let timing = crate::engine::bench_with(&built, tolerance, repeats, settings);
                match (run, timing, error.finish(count)) {
                    (Ok(r), Ok((_, median, iterations)), Some(error)) if r.failure.is_none() => {
                        marks.push(Mark {
                            series: name.to_owned(),
                            tolerance,
                            ns_per_step: median,
                            iterations,
                            error,
                        });
                    }
                    _ => skipped.push(format!("{name} at tolerance {tolerance:e}")),
                }
                done(name, tolerance);
            }
        }
    }
    Ok((marks, skipped))
}

/// Draws the marks as an SVG chart at `path`.
///
/// # Errors
/// Drawing or I/O failures.
pub fn draw(marks: &[Mark], title: &str, path: &Path) -> Result<(), DrawError> {
    let floor = 1e-17;
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for m in marks {
        x0 = x0.min(m.ns_per_step);
        x1 = x1.max(m.ns_per_step);
        y0 = y0.min(m.error.max(floor));
        y1 = y1.max(m.error.max(floor));
    }
    if marks.is_empty() {
        return Err(DrawError::NoMarks);
    }
    // Headroom above the highest mark, a third of the decades spanned, so the legend in the
    // upper right corner covers no mark.
    let top = y1 * 10.0 * ((y1 * 10.0) / (y0 / 10.0)).powf(1.0 / 3.0);
    draw::write_svg(path, (900, 600), |root| {
        root.fill(&WHITE).map_err(backend)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(15)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d((x0 / 1.5..x1 * 1.5).log_scale(), (y0 / 10.0..top).log_scale())
            .map_err(backend)?;
        chart
            .configure_mesh()
            .x_labels(12)
            .y_labels(12)
            .x_desc("time per step (ns, median; log scale)")
            .y_desc("max relative error vs double-double reference (log; below 1e-17 at 1e-17)")
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .x_label_formatter(&|v| format!("{v:.0}"))
            .draw()
            .map_err(backend)?;
        let mut series: Vec<&str> = marks.iter().map(|m| m.series.as_str()).collect();
        series.dedup();
        for (k, name) in series.iter().enumerate() {
            let color = PALETTE[k % PALETTE.len()];
            let of_series: Vec<&Mark> = marks.iter().filter(|m| m.series == *name).collect();
            let points: Vec<(f64, f64)> =
                of_series.iter().map(|m| (m.ns_per_step, m.error.max(floor))).collect();
            // The tolerances go in the legend, not beside every mark (they overlapped where
            // marks crowd): the loosest is the open circle, the line runs to the tightest.
            let label = match (of_series.first(), of_series.last()) {
                (Some(a), Some(b)) if of_series.len() > 1 => {
                    format!("{name}: tolerance {:.0e} (open) to {:.0e}", a.tolerance, b.tolerance)
                }
                (Some(a), _) => format!("{name}: tolerance {:.0e}", a.tolerance),
                _ => (*name).to_owned(),
            };
            chart
                .draw_series(LineSeries::new(points.clone(), color.stroke_width(1)))
                .map_err(backend)?
                .label(label)
                .legend(move |(x, y)| Circle::new((x + 10, y), 4, color.filled()));
            chart
                .draw_series(points.iter().enumerate().map(|(j, &p)| {
                    if j == 0 {
                        Circle::new(p, 6, color.stroke_width(2))
                    } else {
                        Circle::new(p, 4, color.filled())
                    }
                }))
                .map_err(backend)?;
        }
        draw::legend(&mut chart)?;
        root.present().map_err(backend)?;
        Ok(())
    })
}

/// The conditioning of one analysed time point (see [`conditioning`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Conditioning {
    /// Time.
    pub t: f64,
    /// κ₂(Φ_q) = σ_max / σ_min of the generic engine's Φ_q at the configuration.
    pub condition: f64,
    /// 1/ρ, ρ the pivot ratio of the LU with partial pivoting of the same Φ_q: the estimate
    /// the step control uses (see `crate::stepping`).
    pub pivot_estimate: f64,
    /// Newton iterations of the generic engine for this grid step (sub-steps included).
    pub generic_iterations: u32,
    /// The same for the generated engine, when it could be built.
    pub generated_iterations: Option<u32>,
}

/// Frames of one generic run at every time point, `None` if it fails.
fn all_frames(eq: &Equations<'_>, analysis: &Analysis<'_, '_>) -> Option<Vec<Frame>> {
    let mut frames = Vec::new();
    let r = analysis
        .run(|f| {
            frames.push(f.clone());
            Ok::<(), ()>(())
        })
        .ok()?;
    (r.failure.is_none() && frames.len() == eq.mechanism().time.count).then_some(frames)
}

/// Runs both engines over the grid of `mech` (a description without redundant equations)
/// and returns, per time point, the condition of Φ_q and the Newton iterations each took.
/// Its result, and the frames it is computed from, grow with the grid: it draws every point
/// of a chart (`examples/conditioning_chart`) and is meant for grids of hundreds of points.
///
/// # Errors
/// When Φ_q is not square (redundant equations) or an engine stops.
pub fn conditioning(mech: &Mechanism) -> Result<Vec<Conditioning>, ChartError> {
    let eq = Equations::new(mech);
    if eq.equations() != eq.unknowns() {
        return Err(ChartError::NotSquare);
    }
    let prep = eq.prepare();
    let analysis = Analysis::new(&eq, &prep);
    let frames = all_frames(&eq, &analysis).ok_or(ChartError::GenericStopped)?;
    let generated: Option<Vec<u32>> = match crate::engine::build(mech) {
        Ok(built) => {
            let mut its = Vec::new();
            let r = crate::engine::run(&built, &analysis, None, |f| {
                its.push(f.iterations);
                Ok(())
            })?;
            if let Some(f) = r.failure {
                return Err(ChartError::GeneratedStopped(f.message));
            }
            Some(its)
        }
        Err(_) => None,
    };
    let zero = nalgebra::DVector::zeros(eq.unknowns());
    Ok(frames
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let jac = eq.evaluate(&f.q, &zero, f.t).jac;
            let s = nalgebra::SVD::new(jac.clone(), false, false).singular_values;
            let lu = jac.lu();
            let d = lu.u().diagonal().abs();
            Conditioning {
                t: f.t,
                condition: s.max() / s.min(),
                pivot_estimate: d.max() / d.min(),
                generic_iterations: f.iterations,
                generated_iterations: generated.as_ref().and_then(|g| g.get(k).copied()),
            }
        })
        .collect())
}

/// Draws [`conditioning`]'s points as an SVG at `path`: the condition (log scale) above, the
/// Newton iterations per grid step below, against time.
///
/// # Errors
/// Drawing or I/O failures.
pub fn draw_conditioning(
    points: &[Conditioning],
    title: &str,
    path: &Path,
) -> Result<(), DrawError> {
    let (Some(first), Some(last)) = (points.first(), points.last()) else {
        return Err(DrawError::NoMarks);
    };
    let (t0, t1) = (first.t, last.t);
    draw::write_svg(path, (900, 700), |root| {
        root.fill(&WHITE).map_err(backend)?;
        let root = root.titled(title, ("sans-serif", 22)).map_err(backend)?;
        let (upper, lower) = root.split_vertically(420);
        condition_panel(&upper, points, t0..t1)?;
        iterations_panel(&lower, points, t0..t1)?;
        root.present().map_err(backend)?;
        Ok(())
    })
}

/// The conditioning chart's upper panel: κ₂ and the pivot estimate against time.
fn condition_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    points: &[Conditioning],
    time: std::ops::Range<f64>,
) -> Result<(), DrawError> {
    let (t0, t1) = (time.start, time.end);
    let (mut c0, mut c1) = (f64::MAX, f64::MIN);
    for p in points {
        for c in [p.condition, p.pivot_estimate] {
            c0 = c0.min(c);
            c1 = c1.max(c);
        }
    }
    let [blue, orange, ..] = PALETTE;
    let mut chart = ChartBuilder::on(area)
        .margin(15)
        .x_label_area_size(35)
        .y_label_area_size(80)
        .build_cartesian_2d(t0..t1, (c0 / 2.0..c1 * 2.0).log_scale())
        .map_err(backend)?;
    chart
        .configure_mesh()
        .x_desc("t")
        .y_desc("condition of Φ_q (log scale)")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(backend)?;
    chart
        .draw_series(LineSeries::new(
            points.iter().map(|p| (p.t, p.condition)),
            blue.stroke_width(2),
        ))
        .map_err(backend)?
        .label("κ₂ = σ_max / σ_min (SVD)")
        .legend(draw::line_key(blue, 20));
    chart
        .draw_series(LineSeries::new(
            points.iter().map(|p| (p.t, p.pivot_estimate)),
            orange.stroke_width(2),
        ))
        .map_err(backend)?
        .label("1/ρ: max / min LU pivot (the step control's estimate)")
        .legend(draw::line_key(orange, 20));
    draw::legend(&mut chart)?;
    Ok(())
}

/// The conditioning chart's lower panel: Newton iterations per grid step of each engine.
fn iterations_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    points: &[Conditioning],
    time: std::ops::Range<f64>,
) -> Result<(), DrawError> {
    let (t0, t1) = (time.start, time.end);
    let most = points
        .iter()
        .map(|p| p.generic_iterations.max(p.generated_iterations.unwrap_or(0)))
        .max()
        .unwrap_or(1);
    let [blue, _, green, ..] = PALETTE;
    let mut chart = ChartBuilder::on(area)
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(80)
        .build_cartesian_2d(t0..t1, 0.0..f64::from(most) + 1.0)
        .map_err(backend)?;
    chart
        .configure_mesh()
        .x_desc("t")
        .y_desc("Newton iterations per step")
        .draw()
        .map_err(backend)?;
    chart
        .draw_series(LineSeries::new(
            points.iter().map(|p| (p.t, f64::from(p.generic_iterations))),
            blue.stroke_width(2),
        ))
        .map_err(backend)?
        .label("generic")
        .legend(draw::line_key(blue, 20));
    if points.iter().all(|p| p.generated_iterations.is_some()) {
        chart
            .draw_series(LineSeries::new(
                points.iter().map(|p| (p.t, f64::from(p.generated_iterations.unwrap_or(0)))),
                green.stroke_width(2),
            ))
            .map_err(backend)?
            .label("generated")
            .legend(draw::line_key(green, 20));
    }
    draw::legend(&mut chart)?;
    Ok(())
}
