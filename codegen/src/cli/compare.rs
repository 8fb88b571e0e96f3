//! `mechgen compare`: both engines side by side, their largest differences and their speed.

use std::io::{self, Write};
use std::path::Path;

use super::args::CheckFormat;
use super::common::{
    EXIT_OK, EXIT_STOPPED, build_generated, engine_unavailable, report_invalid, time_generic,
    undriven,
};
use super::term;
use crate::diag::printable;
use indicatif::ProgressBar;

use crate::engine::{Built, EngineError, RunReport};
use crate::generic::{Analysis, Equations, Preparation, StepReport};
use crate::model::Mechanism;
use crate::report;

pub(super) fn compare(
    file: &Path,
    format: CheckFormat,
    inputs: Option<&Path>,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let json = format == CheckFormat::Json;
    let loaded = match super::common::load_replayed(file, inputs, json, out, err)? {
        Ok(l) => l,
        Err(code) => return Ok(code),
    };
    let mech = &loaded.mechanism;
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    if let Some(d) = undriven(&eq, &prep) {
        return Ok(report_invalid(&[d], json, out, err));
    }
    let built = match build_generated(mech, crate::emit::Scalar::F64, err)? {
        Ok(b) => b,
        Err(e) => return engine_unavailable(&e, mech, json, out, err),
    };
    let layout = report::layout(mech);
    let mut diffs = report::Differences::default();
    let bar = term::bar(mech.time.count as u64, "both engines");
    let (generic, generated) = run_both(&eq, &prep, &built, &layout, &mut diffs, &bar);
    bar.finish_and_clear();
    let steps = match verdict(generic, generated, err)? {
        Ok(steps) => steps,
        Err(code) => return Ok(code),
    };
    let repeats = 10;
    let spinner = term::spinner("timing both engines");
    let tg =
        time_generic(&eq, &prep, mech.solver.tolerance, repeats, true).map_or(f64::NAN, |r| r.1);
    let td = crate::engine::bench(&built, mech.solver.tolerance, repeats).map_or(f64::NAN, |r| r.1);
    spinner.finish_and_clear();
    write(mech, steps, &diffs.finish(), (tg, td), json, out)?;
    Ok(EXIT_OK)
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
    diffs: &mut report::Differences,
    bar: &ProgressBar,
) -> (GenericRun, Result<RunReport, EngineError>) {
    let mech = eq.mechanism();
    std::thread::scope(|scope| {
        let (send, receive) = std::sync::mpsc::sync_channel(64);
        let generic = scope.spawn(move || {
            let mut steps = 0usize;
            // A closed queue (the generated run stopped) ends the generic run too.
            let r = Analysis::new(eq, prep).run(|f| {
                steps += 1;
                send.send(report::step_result(mech, layout, f)).map_err(|_| ())
            });
            (r.ok(), steps)
        });
        let generated = crate::engine::run(built, &Analysis::new(eq, prep), None, |f| {
            bar.inc(1);
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

/// Writes the differences and the times per step `(generic, generated)`, as JSON or text.
fn write(
    mech: &Mechanism,
    steps: usize,
    diffs: &[(&'static str, f64, f64)],
    (tg, td): (f64, f64),
    json: bool,
    out: &mut dyn Write,
) -> io::Result<()> {
    if json {
        let v = serde_json::json!({
            "mechanism": mech.name,
            "steps": steps,
            "max_abs_diff": diffs.iter().map(|d| (d.0.to_owned(), serde_json::json!(d.1))).collect::<serde_json::Map<_, _>>(),
            "max_rel_diff": diffs.iter().map(|d| (d.0.to_owned(), serde_json::json!(d.2))).collect::<serde_json::Map<_, _>>(),
            "ns_per_step": { "generic": tg, "generated": td },
            "speedup": tg / td,
        });
        return writeln!(out, "{}", serde_json::to_string_pretty(&v)?);
    }
    writeln!(out, "{}: {} time points, generic vs generated", printable(&mech.name), steps)?;
    writeln!(out, "{:>8} {:>14} {:>14}", "quantity", "max abs diff", "max rel diff")?;
    for (name, abs, rel) in diffs {
        writeln!(out, "{name:>8} {abs:>14.3e} {rel:>14.3e}")?;
    }
    writeln!(out, "ns per step: generic {tg:.0}, generated {td:.0}; speedup {:.1}x", tg / td)
}
