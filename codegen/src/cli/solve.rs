//! `mechgen solve`: the analysis over the time grid, on either engine, streamed to the output.

use std::io::{self, BufWriter, Write};
use std::path::Path;

use super::args::{Engine, SolveFormat};
use super::common::{
    EXIT_OK, EXIT_STOPPED, Sink, build_generated, engine_unavailable, report_invalid,
};
use super::term;
use crate::diag::{Diagnostic, printable};
use crate::emit::Scalar;
use crate::generic::{Analysis, Equations};
use crate::model::Mechanism;
use crate::report::{self, Writer};

/// The files of `solve`: the description, `-o` and `--inputs`.
pub(super) struct Files<'a> {
    pub(super) file: &'a Path,
    pub(super) output: Option<&'a Path>,
    pub(super) inputs: Option<&'a Path>,
}

pub(super) fn solve(
    files: Files<'_>,
    engine: Option<Engine>,
    format: SolveFormat,
    select: Option<&[String]>,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let Files { file, output, inputs } = files;
    let json = format == SolveFormat::Json;
    let loaded = match super::common::load_replayed(file, inputs, json, out, err)? {
        Ok(l) => l,
        Err(code) => return Ok(code),
    };
    let mech = &loaded.mechanism;
    let selection = match select {
        None => report::Selection::all(mech),
        Some(names) => match report::Selection::named(mech, names) {
            Ok(s) => s,
            Err(unknown) => {
                let d =
                    Diagnostic::error(unknown.to_string()).entity("command line").field("--select");
                return Ok(report_invalid(&[d], json, out, err));
            }
        },
    };
    let (eq, prep) = match super::common::prepared(mech, json, out, err) {
        Ok(p) => p,
        Err(code) => return Ok(code),
    };
    // With `--select`, the generated solver solves only the blocks the selected outputs
    // depend on (the names were checked above).
    let only = match (engine, select) {
        (Some(Engine::Generic), _) | (_, None) => None,
        (_, Some(names)) => {
            super::common::only_outputs(mech, names, "--select", out, err)?.unwrap_or(None)
        }
    };
    let generated = only.as_ref().unwrap_or(mech);
    // The default engine is the generated one when it can be built, else the generic one.
    let built = match engine {
        Some(Engine::Generic) => None,
        Some(Engine::Generated) => match build_generated(generated, Scalar::F64, err)? {
            Ok(b) => Some(b),
            Err(e) => return engine_unavailable(&e, mech, json, out, err),
        },
        None => match build_generated(generated, Scalar::F64, err)? {
            Ok(b) => Some(b),
            Err(e @ crate::engine::EngineError::Config(_)) => {
                return engine_unavailable(&e, mech, json, out, err);
            }
            Err(e) => {
                log::info!("falling back to the generic engine: {e}");
                writeln!(err, "warning: using the generic engine: {e}")?;
                None
            }
        },
    };
    // The part the generated solver solves, with its own equations to name failures by.
    let part = match (&only, &built, select) {
        (Some(only), Some(_), Some(names)) => {
            let eq = Equations::new(only);
            let prep = eq.prepare();
            let selection = report::Selection::named(only, names).expect("kept with its outputs");
            Some((only, eq, prep, selection))
        }
        _ => None,
    };
    let fmt = match format {
        SolveFormat::Table => report::Format::Table,
        SolveFormat::Csv => report::Format::Csv,
        SolveFormat::Json => report::Format::Json,
    };
    let sink = match output {
        Some(path) => match crate::output::OutputFile::create(path) {
            Ok(file) => Sink::File(file),
            Err(e) => {
                let d = Diagnostic::error(e.to_string()).entity("command line").field("--output");
                return Ok(report_invalid(&[d], json, out, err));
            }
        },
        None => Sink::Out(BufWriter::new(out)),
    };
    let name = if built.is_some() { "generated" } else { "generic" };
    // The redundant equations, named by one rule for both engines, said in the output
    // itself and on standard error; the generic engine solves them with the others, the
    // generated one leaves them out of its reduced system.
    let removed: Vec<String> = match &built {
        Some(b) => b.removed.clone(),
        None => prep.redundant.iter().map(|&k| eq.labels()[k].equation()).collect(),
    };
    let fate = if built.is_some() {
        "is left out of the analysis"
    } else {
        "is solved with them and checked at every step"
    };
    for r in &removed {
        writeln!(
            err,
            "warning: equation {} depends on the ones before it at the initial configuration \
             and {fate}",
            printable(r)
        )?;
    }
    match part {
        Some((only, eq, prep, selection)) => {
            let writer = Writer::begin_selected(sink, fmt, only, name, &removed, selection)?;
            stream(only, &Analysis::new(&eq, &prep), built.as_ref(), writer, err)
        }
        None => {
            let writer = Writer::begin_selected(sink, fmt, mech, name, &removed, selection)?;
            stream(mech, &Analysis::new(&eq, &prep), built.as_ref(), writer, err)
        }
    }
}

/// Runs the analysis on the generated solver `built`, or on the generic engine, writing each
/// time point as it comes, and ends the output with the error if the run stopped; returns
/// the exit status.
pub(super) fn stream(
    mech: &Mechanism,
    analysis: &Analysis<'_, '_>,
    built: Option<&crate::engine::Built>,
    mut writer: Writer<Sink<'_>>,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let layout = report::layout(mech);
    let bar = term::bar(mech.time.count as u64, "analysis");
    // The writer's own error, kept whatever the engine makes of it: a closed pipe ends the
    // command quietly on either engine.
    let mut sink_error: Option<io::Error> = None;
    let mut suspects = [Suspects::default(), Suspects::default()];
    // One step, refilled by every frame.
    let mut step = report::StepResult::empty();
    let mut sink = |frame: &crate::generic::Frame| {
        bar.inc(1);
        report::step_result_into(mech, &layout, frame, &mut step);
        for (flag, seen) in
            [step.suspect.velocity, step.suspect.acceleration].iter().zip(&mut suspects)
        {
            if *flag {
                seen.add(step.t, step.condition);
            }
        }
        writer.step(&step).inspect_err(|e| {
            sink_error = Some(io::Error::new(e.kind(), e.to_string()));
        })
    };
    let failure = match built {
        None => analysis.run(&mut sink)?.failure,
        Some(b) => match crate::engine::run(b, analysis, None, &mut sink) {
            Ok(r) => r.failure,
            Err(e) => {
                bar.finish_and_clear();
                if let Some(e) = sink_error {
                    return Err(e);
                }
                // The solver broke off without a verdict: the output still ends as a whole
                // document, with the error.
                let message = e.to_string();
                writer.finish_broken("solver_failed", &message)?.close()?;
                writeln!(err, "error: {}", printable(&message))?;
                return Ok(EXIT_STOPPED);
            }
        },
    };
    bar.finish_and_clear();
    writer.finish(failure.as_ref())?.close()?;
    for (quantity, seen) in ["velocity", "acceleration"].iter().zip(&suspects) {
        seen.warn(quantity, err)?;
    }
    if let Some(f) = &failure {
        writeln!(err, "error: {}", report::failure_text(f))?;
        return Ok(EXIT_STOPPED);
    }
    Ok(EXIT_OK)
}

/// The steps at which one derivative was flagged by the digits rule, for one warning: how
/// many, the first few times and the largest condition estimate (memory independent of the
/// number of steps).
#[derive(Default)]
struct Suspects {
    count: usize,
    first: Vec<f64>,
    largest: f64,
}

impl Suspects {
    /// The times a warning lists before it says how many more there are.
    const LISTED: usize = 5;

    fn add(&mut self, t: f64, condition: f64) {
        self.count += 1;
        if self.first.len() < Self::LISTED {
            self.first.push(t);
        }
        // NaN (a condition that could not be estimated) is the largest.
        if condition.is_nan() || condition > self.largest {
            self.largest = condition;
        }
    }

    /// `warning: the acceleration at t = 1 cannot be trusted to 6 significant digits …`.
    fn warn(&self, quantity: &str, err: &mut dyn Write) -> io::Result<()> {
        if self.count == 0 {
            return Ok(());
        }
        let times: Vec<String> = self.first.iter().map(|t| t.to_string()).collect();
        let more = self.count - self.first.len();
        let more = if more > 0 { format!(" and {more} more") } else { String::new() };
        let (s, are) = if self.count == 1 { ("", "is") } else { ("s", "are") };
        writeln!(
            err,
            "warning: the {quantity} at {} step{s} (t = {}{more}) {are} suspect: the condition \
             estimate of Φ_q (up to {:.1e}) cannot vouch for 6 significant digits",
            self.count,
            times.join(", "),
            self.largest
        )
    }
}
