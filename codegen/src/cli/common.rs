//! What every subcommand shares: exit statuses, loading a description, reporting invalid
//! input, the output file and the generated solver.

use std::io::{self, BufWriter, Write};
use std::path::Path;

use super::term;
use crate::diag::{Diagnostic, printable};
use crate::generic::{Analysis, Equations, Preparation};
use crate::model::Mechanism;
use crate::validate::{self, Loaded};

/// Exit status: success.
pub const EXIT_OK: i32 = 0;
/// Exit status: invalid input, nothing analysed.
pub const EXIT_INVALID: i32 = 1;
/// Exit status: the analysis stopped (no convergence, singular, branch jump).
pub const EXIT_STOPPED: i32 = 2;
/// Exit status: the generated solver could not be built (`--engine generated`, `compare`,
/// `bench`).
pub const EXIT_BUILD: i32 = 3;

/// Whether an error is, or was caused by, a closed pipe: the reader stopped reading
/// (`mechgen solve … | head -3`), which is its choice, not a failure of the command, so the
/// command ends quietly with status 0. Every command and both engines' writers come here; an
/// error that wraps the writer's `io::Error` (as its `source`) is recognised too.
pub fn closed_pipe(e: &(dyn std::error::Error + 'static)) -> bool {
    let mut next = Some(e);
    while let Some(e) = next {
        if let Some(io) = e.downcast_ref::<io::Error>() {
            if io.kind() == io::ErrorKind::BrokenPipe {
                return true;
            }
            // An `io::Error` made from another error hides it from `source`.
            if let Some(inner) = io.get_ref() {
                next = Some(inner);
                continue;
            }
        }
        next = e.source();
    }
    false
}

/// Where `solve` writes its results: a file that appears when complete, or standard output.
pub(super) enum Sink<'a> {
    File(crate::output::OutputFile),
    Out(BufWriter<&'a mut dyn Write>),
}

impl Sink<'_> {
    /// Ends the output: the file is renamed into place, standard output flushed.
    pub(super) fn close(self) -> io::Result<()> {
        match self {
            Self::File(f) => f.commit(),
            Self::Out(mut o) => o.flush(),
        }
    }
}

impl Write for Sink<'_> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self {
            Self::File(f) => f.write(buf),
            Self::Out(o) => o.write(buf),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match self {
            Self::File(f) => f.flush(),
            Self::Out(o) => o.flush(),
        }
    }
}

/// Why `-o OUTPUT` cannot be written, found before any work: its directory is missing, it
/// is a directory, or it is one of the command's input files (the same path once links are
/// resolved, or the same file by device and inode), which writing would destroy.
pub(super) fn output_problem(output: &Path, inputs: &[&Path]) -> Option<Diagnostic> {
    let shown = |p: &Path| printable(&p.display().to_string()).into_owned();
    let problem = |m: String| Diagnostic::error(m).entity("command line").field("--output");
    let dir = crate::output::directory_of(output);
    if !dir.is_dir() {
        let why = if dir.exists() { "is not a directory" } else { "does not exist" };
        return Some(problem(format!(
            "cannot write {}: the directory {} {why}",
            shown(output),
            shown(dir)
        )));
    }
    if output.is_dir() {
        return Some(problem(format!("cannot write {}: it is a directory", shown(output))));
    }
    let input = inputs.iter().find(|input| same_file(output, input))?;
    Some(problem(format!(
        "the output {} is the input file {}: writing it would destroy the input; choose another \
         output file",
        shown(output),
        shown(input)
    )))
}

/// Whether two paths name one existing file.
fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(x), Ok(y)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return x.dev() == y.dev() && x.ino() == y.ino();
        }
    }
    matches!((a.canonicalize(), b.canonicalize()), (Ok(x), Ok(y)) if x == y)
}

/// Prints diagnostics (all on stderr; the first as the JSON error object on stdout).
pub(super) fn report_invalid(
    diags: &[Diagnostic],
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> i32 {
    for d in diags {
        let _ = writeln!(err, "{d}");
    }
    if json {
        let first = diags.first().cloned().unwrap_or_else(|| Diagnostic::error("invalid input"));
        let _ = writeln!(out, "{}", serde_json::json!({ "error": first.to_json() }));
    }
    EXIT_INVALID
}

/// Prints diagnostics found in `source` with their excerpts and carets (all on stderr; the
/// first error also as the JSON error object on stdout when `json`).
pub(super) fn report_in_source(
    diags: &[Diagnostic],
    source: &str,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> i32 {
    let _ = write!(err, "{}", crate::diag::render(diags, Some(source), term::current().color));
    if json {
        let first = diags.first().cloned().unwrap_or_else(|| Diagnostic::error("invalid input"));
        let _ = writeln!(out, "{}", serde_json::json!({ "error": first.to_json() }));
    }
    EXIT_INVALID
}

/// Loads and validates a file, printing warnings; `Err` carries the exit status.
pub(super) fn load(
    file: &Path,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<Loaded, i32> {
    let (text, format) =
        validate::read_file(file).map_err(|d| report_invalid(&d, json, out, err))?;
    match validate::load_str(&text, format, Some(&file.display().to_string())) {
        Ok(loaded) => {
            let color = term::current().color;
            let _ = write!(err, "{}", crate::diag::render(&loaded.warnings, Some(&text), color));
            Ok(loaded)
        }
        Err(diags) => Err(report_in_source(&diags, &text, json, out, err)),
    }
}

/// [`load`], then [`replay`] with `inputs`: the mechanism an analysis runs, or the exit status.
pub(super) fn load_replayed(
    file: &Path,
    inputs: Option<&Path>,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<Result<Loaded, i32>> {
    let mut loaded = match load(file, json, out, err) {
        Ok(l) => l,
        Err(code) => return Ok(Err(code)),
    };
    Ok(replay(&mut loaded.mechanism, inputs, json, out, err)?.map(|()| loaded))
}

/// Applies `--inputs`: reads the recorded series (printing its warnings) and makes its rows
/// the time points of `mech`; without `--inputs`, a description with input drivers is
/// invalid input naming them. `Err` carries the exit status.
pub(super) fn replay(
    mech: &mut Mechanism,
    inputs: Option<&Path>,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<Result<(), i32>> {
    let Some(path) = inputs else {
        let names = mech.input_drivers();
        if names.is_empty() {
            return Ok(Ok(()));
        }
        let message = format!(
            "driver {} has law = \"input\": its values come from a recorded series, which \
             solve, compare and bench take with --inputs FILE.csv (columns t, {})",
            names.join(", driver "),
            names.join(", ")
        );
        let d = Diagnostic::error(message).entity(format!("driver \"{}\"", names[0])).field("law");
        return Ok(Err(report_invalid(&[d], json, out, err)));
    };
    match crate::inputs::read(path, mech) {
        Ok(read) => {
            for w in &read.warnings {
                writeln!(err, "warning: {}", printable(w))?;
            }
            mech.time = crate::model::TimeGrid::replaying(std::sync::Arc::new(read.replay));
            Ok(Ok(()))
        }
        Err(d) => Ok(Err(report_invalid(&[*d], json, out, err))),
    }
}

/// The equations of `mech` assembled at the initial configuration, or the exit status after
/// reporting an undriven degree of freedom (invalid input).
pub(super) fn prepared<'m>(
    mech: &'m Mechanism,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<(Equations<'m>, Preparation), i32> {
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    match undriven(&eq, &prep) {
        Some(d) => Err(report_invalid(&[d], json, out, err)),
        None => Ok((eq, prep)),
    }
}

/// The invalid-input diagnostic for an undriven degree of freedom, if Φ_q has lower column
/// rank than the unknowns.
fn undriven(eq: &Equations<'_>, prep: &Preparation) -> Option<Diagnostic> {
    (prep.rank < eq.unknowns()).then(|| {
        Diagnostic::error(format!(
            "the Jacobian has rank {} for {} unknowns: {} degree(s) of freedom are not driven; \
             bodies that can still move: {}",
            prep.rank,
            eq.unknowns(),
            eq.unknowns() - prep.rank,
            prep.free_bodies.join(", ")
        ))
        .entity("mechanism")
        .field("drivers")
    })
}

/// The part of `mech` that the outputs `names` depend on (`crate::blocks::outputs`), or
/// `None` when that is all of it or the generator refuses the whole (the caller then reports
/// that as it does without `flag`); `Err` carries the exit status after reporting a name
/// that is no output (invalid input on the command line's `flag`).
pub(super) fn only_outputs(
    mech: &Mechanism,
    names: &[String],
    flag: &str,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<Result<Option<Mechanism>, i32>> {
    let Ok(sys) = crate::symbolic::Symbolic::build(mech) else { return Ok(Ok(None)) };
    match crate::blocks::outputs::only(mech, &sys, names) {
        Ok(only) if only == *mech => Ok(Ok(None)),
        Ok(only) => {
            log::info!(
                "{flag}: {} of {} moving bodies are needed",
                only.moving_bodies().count(),
                mech.moving_bodies().count()
            );
            Ok(Ok(Some(only)))
        }
        Err(unknown) => {
            let d = Diagnostic::error(unknown.to_string()).entity("command line").field(flag);
            Ok(Err(report_invalid(&[d], false, out, err)))
        }
    }
}

/// Builds the generated solver, printing what the cache repaired on the way.
pub(super) fn build_generated(
    mech: &Mechanism,
    scalar: crate::emit::Scalar,
    err: &mut dyn Write,
) -> io::Result<Result<crate::engine::Built, crate::engine::EngineError>> {
    let spinner = term::spinner("building the generated solver");
    let built = crate::engine::build_in(mech, scalar);
    spinner.finish_and_clear();
    if let Ok(b) = &built {
        for n in &b.notes {
            writeln!(err, "note: {n}")?;
        }
    }
    Ok(built)
}

/// Reports why the generated solver is not there when it was asked for, with its exit
/// status: 3 when it could not be built, 1 for what the user must correct first.
pub(super) fn engine_unavailable(
    e: &crate::engine::EngineError,
    mech: &Mechanism,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let entity = format!("mechanism \"{}\"", mech.name);
    if let crate::engine::EngineError::Build(b) = e {
        writeln!(err, "error: {e}")?;
        if json {
            let error = serde_json::json!({
                "kind": "build_failed",
                "message": format!("the generated solver could not be built: {}", b.reason),
                "fix": b.fix,
                "entity": entity,
            });
            writeln!(out, "{}", serde_json::json!({ "error": error }))?;
        }
        return Ok(EXIT_BUILD);
    }
    Ok(report_invalid(&[Diagnostic::error(e.to_string()).entity(entity)], json, out, err))
}

/// Times `repeats` whole passes of the generic engine.
pub(super) fn time_generic(
    eq: &Equations<'_>,
    prep: &Preparation,
    tolerance: f64,
    repeats: usize,
    predictor: bool,
) -> Result<(f64, f64, f64), crate::generic::TimedStop> {
    Analysis::new(eq, prep).with_tolerance(tolerance).with_predictor(predictor).time(repeats)
}
