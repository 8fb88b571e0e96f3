//! `mechgen compare`: both engines side by side, their largest differences and their speed.

use std::io::{self, Write};
use std::path::Path;

use super::args::CheckFormat;
use super::common::{EXIT_OK, EXIT_STOPPED, build_generated, engine_unavailable, time_generic};
use super::term;
use crate::diag::printable;
use indicatif::ProgressBar;

use crate::engine::{Built, EngineError, RunReport};
use crate::generic::{Analysis, Equations, Preparation, StepReport};
use crate::model::Mechanism;
use crate::{reference, report};

pub(super) fn compare(
    file: &Path,
    format: CheckFormat,
    inputs: Option<&Path>,
    with_reference: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let json = format == CheckFormat::Json;
    let loaded = match super::common::load_replayed(file, inputs, json, out, err)? {
        Ok(l) => l,
        Err(code) => return Ok(code),
    };
    let mech = &loaded.mechanism;
    let (eq, prep) = match super::common::prepared(mech, json, out, err) {
        Ok(p) => p,
        Err(code) => return Ok(code),
    };
    let built = match build_generated(mech, crate::emit::Scalar::F64, err)? {
        Ok(b) => b,
        Err(e) => return engine_unavailable(&e, mech, json, out, err),
    };
    let frames = if with_reference {
        let spinner = term::spinner("solving the double-double reference");
        let frames = reference::frames(&eq, &Analysis::new(&eq, &prep), reference::SAMPLES);
        spinner.finish_and_clear();
        match frames {
            Ok(f) => Some(f),
            Err(e) => {
                writeln!(err, "error: {e}")?;
                return Ok(EXIT_STOPPED);
            }
        }
    } else {
        None
    };
    let layout = report::layout(mech);
    let mut diffs = report::Differences::default();
    let mut errors =
        frames.as_deref().map(|f| [reference::Error::new(f), reference::Error::new(f)]);
    let bar = term::bar(mech.time.count as u64, "both engines");
    let (generic, generated) =
        run_both(&eq, &prep, &built, &layout, (&mut diffs, errors.as_mut()), &bar);
    bar.finish_and_clear();
    let steps = match verdict(generic, generated, err)? {
        Ok(steps) => steps,
        Err(code) => return Ok(code),
    };
    let repeats = 10;
    let spinner = term::spinner("timing both engines");
    let tg = time_generic(&eq, &prep, mech.solver.tolerance, repeats, true);
    let td = crate::engine::bench(&built, mech.solver.tolerance, repeats);
    spinner.finish_and_clear();
    let tg = match tg {
        Ok(r) => Some(r.1),
        Err(stop) => {
            let message = printable(&stop.message);
            writeln!(
                err,
                "warning: generic engine: the timed pass stopped at t = {} ({}): {message}; no \
                 time per step",
                stop.t, stop.kind
            )?;
            None
        }
    };
    let td = match td {
        Ok(r) => Some(r.1),
        Err(e) => {
            writeln!(
                err,
                "warning: generated engine: the timed passes failed ({e}); no time per step"
            )?;
            None
        }
    };
    let diffs = diffs.finish();
    let disagree = disagreeing(&diffs);
    if !disagree.is_empty() {
        writeln!(
            err,
            "warning: the engines differ by more than {DISAGREE:e} relative in: {}",
            disagree.join(", ")
        )?;
    }
    let errors = errors.map(|[g, d]| [g.levels(), d.levels()]);
    write(mech, steps, (&diffs, &disagree, errors), (tg, td), json, out)?;
    Ok(EXIT_OK)
}

/// Quantities whose largest difference between the engines, relative to the quantity's largest
/// magnitude over the run, exceeds this are flagged: the engines solve the same equations to
/// the same tolerance (1e-10 by default) with round-off well below it on every shipped example
/// (about 1e-15), so a difference of 1e-6 means a different branch or a lost digit, not noise.
const DISAGREE: f64 = 1e-6;

/// The quantities of `diffs` (name, largest absolute, largest relative difference) whose
/// relative difference exceeds [`DISAGREE`] or is not a number.
pub(super) fn disagreeing<'d>(diffs: &[(&'d str, f64, f64)]) -> Vec<&'d str> {
    diffs.iter().filter(|d| d.2 > DISAGREE || d.2.is_nan()).map(|d| d.0).collect()
}

/// The generic run's report (`None` when the generated run stopped first) and its steps.
type GenericRun = (Option<StepReport>, usize);

/// Runs both engines at once, the generic one on a thread of its own sending its steps
/// through a short queue, and takes the differences as the pairs arrive: neither run is
/// kept, so memory does not grow with the grid.
fn run_both(
    eq: &Equations<'_>,
    prep: &Preparation,
    built: &Built,
    layout: &[Option<usize>],
    (diffs, errors): (&mut report::Differences, Option<&mut [reference::Error<'_>; 2]>),
    bar: &ProgressBar,
) -> (GenericRun, Result<RunReport, EngineError>) {
    let mech = eq.mechanism();
    let (mut generic_error, mut generated_error) = match errors {
        Some([g, d]) => (Some(g), Some(d)),
        None => (None, None),
    };
    std::thread::scope(|scope| {
        let (send, receive) = std::sync::mpsc::sync_channel(64);
        let generic = scope.spawn(move || {
            let mut steps = 0usize;
            // A closed queue (the generated run stopped) ends the generic run too.
            let r = Analysis::new(eq, prep).run(|f| {
                steps += 1;
                if let Some(e) = generic_error.as_mut() {
                    e.add(f);
                }
                send.send(report::step_result(mech, layout, f)).map_err(|_| ())
            });
            (r.ok(), steps)
        });
        let generated = crate::engine::run(built, &Analysis::new(eq, prep), None, |f| {
            bar.inc(1);
            if let Some(e) = generated_error.as_mut() {
                e.add(f);
            }
            if let Ok(a) = receive.recv() {
                diffs.add(&a, &report::step_result(mech, layout, f));
            }
            Ok(())
        });
        // Let a generic run still going finish without anyone reading.
        drop(receive);
        let generic = generic.join().unwrap_or_else(|e| std::panic::resume_unwind(e));
        (generic, generated)
    })
}

/// The time points both engines computed, or the exit status after reporting which engine
/// stopped and why.
fn verdict(
    generic: GenericRun,
    generated: Result<RunReport, EngineError>,
    err: &mut dyn Write,
) -> io::Result<Result<usize, i32>> {
    let steps = match generic {
        (Some(r), steps) => {
            if let Some(f) = &r.failure {
                writeln!(err, "error: generic engine: {}", report::failure_text(f))?;
                return Ok(Err(EXIT_STOPPED));
            }
            steps
        }
        // The generated run stopped first; its error is reported below.
        (None, steps) => steps,
    };
    match generated {
        Ok(RunReport { failure: None, .. }) => Ok(Ok(steps)),
        Ok(RunReport { failure: Some(f), .. }) => {
            writeln!(err, "error: generated engine: {}", report::failure_text(&f))?;
            Ok(Err(EXIT_STOPPED))
        }
        Err(e) => {
            writeln!(err, "error: {e}")?;
            Ok(Err(EXIT_STOPPED))
        }
    }
}

/// Each engine's largest relative error in q, q̇ and q̈ against the double-double reference,
/// `[generic, generated]` (`compare --reference`).
type ReferenceErrors = [[f64; 3]; 2];

/// What `compare` found: the differences (name, largest absolute, largest relative), the
/// quantities flagged, and the errors against the reference when asked for.
type Findings<'d> = (&'d [(&'static str, f64, f64)], &'d [&'d str], Option<ReferenceErrors>);

/// Writes the differences, the quantities flagged, the errors against the reference when
/// asked for and the times per step `(generic, generated)`, as JSON or text.
fn write(
    mech: &Mechanism,
    steps: usize,
    (diffs, disagree, errors): Findings<'_>,
    (tg, td): (Option<f64>, Option<f64>),
    json: bool,
    out: &mut dyn Write,
) -> io::Result<()> {
    // No speedup without both times (never a NaN).
    let speedup = tg.zip(td).filter(|&(g, d)| g > 0.0 && d > 0.0).map(|(g, d)| g / d);
    if json {
        let v = serde_json::json!({
            "mechanism": mech.name,
            "steps": steps,
            "max_abs_diff": diffs.iter().map(|d| (d.0.to_owned(), serde_json::json!(d.1))).collect::<serde_json::Map<_, _>>(),
            "max_rel_diff": diffs.iter().map(|d| (d.0.to_owned(), serde_json::json!(d.2))).collect::<serde_json::Map<_, _>>(),
            "ns_per_step": { "generic": tg, "generated": td },
            "speedup": speedup,
            "disagree": disagree,
        });
        let mut v = v;
        if let Some([g, d]) = errors {
            let levels = |e: [f64; 3]| serde_json::json!({ "q": e[0], "qd": e[1], "qdd": e[2] });
            v["reference_error"] =
                serde_json::json!({ "generic": levels(g), "generated": levels(d) });
        }
        return writeln!(out, "{}", serde_json::to_string_pretty(&v)?);
    }
    writeln!(out, "{}: {} time points, generic vs generated", printable(&mech.name), steps)?;
    writeln!(out, "{:>8} {:>14} {:>14}", "quantity", "max abs diff", "max rel diff")?;
    for (name, abs, rel) in diffs {
        writeln!(out, "{name:>8} {abs:>14.3e} {rel:>14.3e}")?;
    }
    let shown = |t: Option<f64>| t.map_or_else(|| "unknown".to_owned(), |t| format!("{t:.0}"));
    let speedup = speedup.map_or_else(|| "unknown".to_owned(), |s| format!("{s:.1}x"));
    if !disagree.is_empty() {
        writeln!(out, "differ by more than {DISAGREE:e} relative: {}", disagree.join(", "))?;
    }
    if let Some(errors) = errors {
        writeln!(out, "largest relative error against the double-double reference:")?;
        writeln!(out, "{:>9} {:>10} {:>10} {:>10}", "engine", "q", "q dot", "q ddot")?;
        for (name, e) in ["generic", "generated"].iter().zip(errors) {
            writeln!(out, "{name:>9} {:>10.2e} {:>10.2e} {:>10.2e}", e[0], e[1], e[2])?;
        }
    }
    writeln!(out, "ns per step: generic {}, generated {}; speedup {speedup}", shown(tg), shown(td))
}
