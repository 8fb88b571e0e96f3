//! `mechgen bench`: ns per time step and Newton iterations per step of either engine or both.

use std::io::{self, Write};
use std::path::Path;

use super::args::{BenchEngine, CheckFormat};
use super::common::{EXIT_OK, EXIT_STOPPED, build_generated, engine_unavailable, time_generic};
use super::term;
use crate::diag::printable;
use crate::generic::{Analysis, Failure};
use crate::model::Mechanism;

/// The timing options of `bench`.
pub(super) struct BenchHow {
    pub(super) tolerance: Option<f64>,
    pub(super) repeats: usize,
    pub(super) float: crate::emit::Scalar,
    pub(super) settings: crate::engine::Settings,
}

/// One engine's timing: its name, (min ns per step, median ns per step, Newton iterations
/// per step).
type Timing = (&'static str, (f64, f64, f64));

pub(super) fn bench(
    file: &Path,
    engine: BenchEngine,
    how: &BenchHow,
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
    let tolerance = how.tolerance.unwrap_or(mech.solver.tolerance);
    let (eq, prep) = match super::common::prepared(mech, json, out, err) {
        Ok(p) => p,
        Err(code) => return Ok(code),
    };
    // Only an analysis that `solve` completes is timed: one pass with solve's step control and
    // checks (sub-steps, continuity, every row of the description) comes first on each engine,
    // and its failure is the benchmark's, named by kind, time and reason.
    let analysis =
        Analysis::new(&eq, &prep).with_tolerance(tolerance).with_predictor(how.settings.predictor);
    let mut results = Vec::new();
    if engine != BenchEngine::Generated {
        if let Some(f) = analysis.run(|_| Ok::<(), io::Error>(()))?.failure {
            return refuse("generic", &f, err);
        }
        let spinner = term::spinner(&format!("timing the generic engine ({} passes)", how.repeats));
        let timed = time_generic(&eq, &prep, tolerance, how.repeats, how.settings.predictor);
        spinner.finish_and_clear();
        match timed {
            Ok(r) => results.push(("generic", r)),
            Err(stop) => {
                writeln!(
                    err,
                    "error: generic engine: the timed pass stopped at t = {} ({}): {} (bench \
                     times plain steps without the step control of solve; `mechgen solve` shows \
                     where and why the analysis itself stops)",
                    stop.t,
                    stop.kind,
                    printable(&stop.message)
                )?;
                return Ok(EXIT_STOPPED);
            }
        }
    }
    if engine != BenchEngine::Generic {
        let built = match build_generated(mech, how.float, err)? {
            Ok(b) => b,
            Err(e) => return engine_unavailable(&e, mech, json, out, err),
        };
        let checked =
            crate::engine::run_with(&built, &analysis, Some(tolerance), how.settings, |_| Ok(()));
        match checked {
            Ok(report) => {
                if let Some(f) = report.failure {
                    return refuse("generated", &f, err);
                }
            }
            Err(e) => {
                writeln!(err, "error: generated engine: {}", printable(&e.to_string()))?;
                return Ok(EXIT_STOPPED);
            }
        }
        let spinner =
            term::spinner(&format!("timing the generated engine ({} passes)", how.repeats));
        let timed = crate::engine::bench_with(&built, tolerance, how.repeats, how.settings);
        spinner.finish_and_clear();
        match timed {
            Ok(r) => results.push(("generated", r)),
            Err(e) => {
                writeln!(err, "error: generated engine: {e}")?;
                return Ok(EXIT_STOPPED);
            }
        }
    }
    if json {
        write_json(mech, how, tolerance, &results, out)?;
    } else {
        write_text(mech, how, tolerance, &results, out)?;
    }
    Ok(EXIT_OK)
}

/// Reports that `engine`'s checked pass stopped, so nothing is timed.
fn refuse(engine: &str, f: &Failure, err: &mut dyn Write) -> io::Result<i32> {
    writeln!(
        err,
        "error: {engine} engine: the analysis stops, so it is not timed: {}",
        printable(&crate::report::failure_text(f))
    )?;
    Ok(EXIT_STOPPED)
}

/// The generic median over the generated median, when both engines were timed.
fn speedup(results: &[Timing]) -> Option<f64> {
    (results.len() == 2).then(|| results[0].1.1 / results[1].1.1)
}

/// The timings as the contract's JSON: one object, or both with the speedup.
fn write_json(
    mech: &Mechanism,
    how: &BenchHow,
    tolerance: f64,
    results: &[Timing],
    out: &mut dyn Write,
) -> io::Result<()> {
    let objects: Vec<serde_json::Value> = results
        .iter()
        .map(|(name, (min, median, iters))| {
            let generated = *name == "generated";
            serde_json::json!({
                "mechanism": mech.name,
                "engine": name,
                "tolerance": tolerance,
                "steps": mech.time.count,
                "repeats": how.repeats.max(1),
                "ns_per_step": { "min": min, "median": median },
                "iterations_per_step": iters,
                "float": if generated { how.float.name() } else { "f64" },
                "predictor": how.settings.predictor,
                "lu": if generated && !how.settings.dense_lu { "structured" } else { "dense" },
            })
        })
        .collect();
    let v = match speedup(results) {
        Some(s) => serde_json::json!({ "results": objects, "speedup": s }),
        None => objects.into_iter().next().unwrap_or_default(),
    };
    writeln!(out, "{}", serde_json::to_string_pretty(&v)?)
}

/// The timings as text: a heading with the settings, one line per engine, the speedup.
fn write_text(
    mech: &Mechanism,
    how: &BenchHow,
    tolerance: f64,
    results: &[Timing],
    out: &mut dyn Write,
) -> io::Result<()> {
    let mut notes = Vec::new();
    if how.float != crate::emit::Scalar::F64 {
        notes.push(format!(", generated in {}", how.float.name()));
    }
    if !how.settings.predictor {
        notes.push(", no predictor".to_owned());
    }
    if how.settings.dense_lu {
        notes.push(", dense LU".to_owned());
    }
    writeln!(
        out,
        "{} ({} time points, tolerance {tolerance:e}, {} repeats{}; timed: plain steps, without the \
         sub-steps, continuity, condition and left-out-row checks of the one checked pass solve \
         runs before them)",
        printable(&mech.name),
        mech.time.count,
        how.repeats.max(1),
        notes.concat()
    )?;
    for (name, (min, median, iters)) in results {
        writeln!(
            out,
            "{name:>10}: {min:>10.0} ns/step min, {median:>10.0} ns/step median, {iters:.2} Newton iterations/step"
        )?;
    }
    if let Some(s) = speedup(results) {
        writeln!(out, "   speedup: {s:.1}x (generic median / generated median)")?;
    }
    Ok(())
}
