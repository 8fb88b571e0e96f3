//! The `mechgen` command line (contract §3), as a library function so that tests can run it
//! in process: [`run`] takes the arguments and two writers and returns the exit status.

use std::ffi::OsString;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use clap::{Parser, Subcommand, ValueEnum};

use crate::diag::{Diagnostic, printable};
use crate::generic::{Analysis, Equations};
use crate::model::{ConstraintKind, DriverCoordinate, DriverTarget, Mechanism};
use crate::report::{self, Writer};
use crate::validate::{self, Loaded};
use crate::young;

mod plot;
mod term;
#[cfg(test)]
mod tests;

pub use term::Terminal;

/// Exit status: success.
pub const EXIT_OK: i32 = 0;
/// Exit status: invalid input, nothing analysed.
pub const EXIT_INVALID: i32 = 1;
/// Exit status: the analysis stopped (no convergence, singular, branch jump).
pub const EXIT_STOPPED: i32 = 2;
/// Exit status: the generated solver could not be built (`--engine generated`, `compare`,
/// `bench`).
pub const EXIT_BUILD: i32 = 3;

#[derive(Parser, Debug)]
#[command(name = "mechgen", version, about = "Kinematic analysis of spatial mechanisms")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Validate a description; print its size, rank, mobility and redundant equations.
    Check {
        /// The description file (TOML, or JSON by extension).
        file: PathBuf,
        /// Output format.
        #[arg(long, value_enum, default_value_t = CheckFormat::Text)]
        format: CheckFormat,
    },
    /// Kinematic analysis over the time grid.
    Solve {
        /// The description file.
        file: PathBuf,
        /// The engine (default: generated if it can be built, else generic).
        #[arg(long, value_enum)]
        engine: Option<Engine>,
        /// Output format.
        #[arg(long, value_enum, default_value_t = SolveFormat::Table)]
        format: SolveFormat,
        /// Write the results here instead of standard output.
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
    },
    /// Run both engines; report the largest difference of every output quantity and the
    /// time per step of each.
    Compare {
        /// The description file.
        file: PathBuf,
        /// Output format.
        #[arg(long, value_enum, default_value_t = CheckFormat::Text)]
        format: CheckFormat,
    },
    /// Time the analysis: ns per time step (min and median over repeats), Newton
    /// iterations per step.
    Bench {
        /// The description file.
        file: PathBuf,
        /// The engine, or both side by side.
        #[arg(long, value_enum, default_value_t = BenchEngine::Both)]
        engine: BenchEngine,
        /// Newton tolerance on max |Φ_i| (default: the description's).
        #[arg(long, value_parser = tolerance_value)]
        tolerance: Option<f64>,
        /// Whole passes over the grid to time.
        #[arg(long, default_value_t = 20, value_parser = repeats_value)]
        repeats: usize,
        /// Output format.
        #[arg(long, value_enum, default_value_t = CheckFormat::Text)]
        format: CheckFormat,
        /// Floating-point type of the generated solver.
        #[arg(long, value_enum, default_value_t = Float::F64)]
        float: Float,
        /// Start every Newton solve from the last position instead of the Taylor predictor.
        #[arg(long)]
        no_predictor: bool,
        /// Factor the generated solver's Jacobian by dense LU only (no static pivot orders).
        #[arg(long)]
        dense_lu: bool,
    },
    /// Chart speed against accuracy: one mark per engine and setting (SVG).
    Chart {
        /// The description file.
        file: PathBuf,
        /// The SVG file to write.
        #[arg(short = 'o', long = "output")]
        output: PathBuf,
        /// Whole passes over the grid timed per mark.
        #[arg(long, default_value_t = 10, value_parser = repeats_value)]
        repeats: usize,
    },
    /// Scaling study: generation time, generated lines, build time and ns per step for
    /// chains and multi-loop mechanisms of the given sizes (bodies).
    #[command(hide = true)]
    Scaling {
        /// Body counts to measure.
        #[arg(long, value_delimiter = ',', default_value = "5,20,50,100", value_parser = bodies_value)]
        bodies: Vec<usize>,
        /// Whole passes timed per engine.
        #[arg(long, default_value_t = 3, value_parser = repeats_value)]
        repeats: usize,
        /// Also write each description into this directory.
        #[arg(long)]
        write: Option<PathBuf>,
    },
    /// Plot one quantity of a point or a body against time, and the path of a point or of a
    /// body's origin in a 3D projection (SVG; generic engine).
    Plot {
        /// The description file.
        file: PathBuf,
        /// The point of interest to plot.
        #[arg(long, required_unless_present = "body", conflicts_with = "body")]
        point: Option<String>,
        /// The moving body to plot (its frame's origin and orientation).
        #[arg(long)]
        body: Option<String>,
        /// The quantity: r, v, a (points and bodies); p, omega, alpha (bodies).
        #[arg(long, value_enum, default_value_t = plot::PlotQuantity::R)]
        quantity: plot::PlotQuantity,
        /// The SVG file to write.
        #[arg(short = 'o', long = "output")]
        output: PathBuf,
    },
    /// Emit the specialised Rust module of a description.
    Generate {
        /// The description file.
        file: PathBuf,
        /// Floating-point type of the module.
        #[arg(long, value_enum, default_value_t = Float::F64)]
        float: Float,
        /// Write the module here instead of standard output.
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
    },
    /// Regenerate `generated/src` from `examples/*.toml` (`--check`: only compare).
    #[command(hide = true)]
    Codegen {
        /// Report stale files and exit 1 instead of writing.
        #[arg(long)]
        check: bool,
    },
    /// Convert a legacy YOUNG input deck to a description (TOML on standard output).
    ImportYoung {
        /// The deck.
        deck: PathBuf,
        /// Write the description here instead of standard output.
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum CheckFormat {
    Text,
    Json,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum SolveFormat {
    Table,
    Csv,
    Json,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum BenchEngine {
    Generic,
    Generated,
    Both,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Float {
    F64,
    F32,
}

impl Float {
    fn scalar(self) -> crate::emit::Scalar {
        match self {
            Float::F64 => crate::emit::Scalar::F64,
            Float::F32 => crate::emit::Scalar::F32,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Engine {
    Generic,
    Generated,
}

/// The most whole passes over the grid `bench`, `chart` and `scaling` time: the median of
/// 10,000 passes is as good as any, and more only delays the answer.
const MAX_REPEATS: usize = 10_000;

/// A whole number in `range`, or the reason it is not.
fn whole_in(
    text: &str,
    range: std::ops::RangeInclusive<usize>,
    why: &str,
) -> Result<usize, String> {
    let n: usize = text.trim().parse().map_err(|_| {
        format!("`{text}` is not a whole number from {} to {}", range.start(), range.end())
    })?;
    if range.contains(&n) {
        Ok(n)
    } else {
        Err(format!("{n} is not from {} to {}: {why}", range.start(), range.end()))
    }
}

/// `--repeats`: 1 to [`MAX_REPEATS`].
fn repeats_value(text: &str) -> Result<usize, String> {
    whole_in(text, 1..=MAX_REPEATS, "more passes only delay the answer")
}

/// `scaling --bodies`: 1 to the most moving bodies a description may have.
fn bodies_value(text: &str) -> Result<usize, String> {
    whole_in(text, 1..=validate::MAX_BODIES, "descriptions hold at most that many moving bodies")
}

/// `--tolerance`: finite, > 0 and at most the largest number a description may hold, as the
/// description's own `solver.tolerance`.
fn tolerance_value(text: &str) -> Result<f64, String> {
    let max = validate::MAX_MAGNITUDE;
    match text.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 && x <= max => Ok(x),
        Ok(x) => Err(format!("{x} is not a tolerance: it must be finite, > 0 and at most {max:e}")),
        Err(_) => Err(format!("`{text}` is not a number")),
    }
}

/// Whether the user asked for JSON anywhere on the command line (so that even argument
/// errors are reported as the contract's JSON error object).
fn wants_json(args: &[OsString]) -> bool {
    args.windows(2).any(|w| w[0] == "--format" && w[1] == "json")
        || args.iter().any(|a| a == "--format=json")
}

/// Runs `mechgen` with `args` (including the program name) and returns the exit status.
/// Output is plain: no colour, no progress bars (the form for tests and pipes).
pub fn run(args: Vec<OsString>, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    run_with(args, out, err, Terminal::default())
}

/// As [`run`], with diagnostics in colour and progress bars on standard error as `terminal`
/// says (the binary passes [`Terminal::detect`]).
pub fn run_with(
    args: Vec<OsString>,
    out: &mut dyn Write,
    err: &mut dyn Write,
    terminal: Terminal,
) -> i32 {
    term::with(terminal, || dispatch(args, out, err))
}

fn dispatch(args: Vec<OsString>, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    let json = wants_json(&args);
    let cli = match Cli::try_parse_from(&args) {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
                let _ = write!(out, "{e}");
                return EXIT_OK;
            }
            if json {
                let d = Diagnostic::error(e.kind().to_string()).entity("command line");
                let _ = writeln!(out, "{}", serde_json::json!({ "error": d.to_json() }));
            }
            let _ = write!(err, "{}", e.render());
            return EXIT_INVALID;
        }
    };
    if let Some(d) = cli.command.output().and_then(|(o, inputs)| output_problem(o, &inputs)) {
        return report_invalid(&[d], json, out, err);
    }
    let result = match cli.command {
        Command::Check { file, format } => check(&file, format, out, err),
        Command::Solve { file, engine, format, output } => {
            solve(&file, engine, format, output.as_deref(), out, err)
        }
        Command::ImportYoung { deck, output } => import_young(&deck, output.as_deref(), out, err),
        Command::Generate { file, float, output } => {
            generate(&file, float.scalar(), output.as_deref(), out, err)
        }
        Command::Chart { file, output, repeats } => chart(&file, &output, repeats, out, err),
        Command::Scaling { bodies, repeats, write } => {
            scaling(&bodies, repeats, write.as_deref(), out, err)
        }
        Command::Compare { file, format } => compare(&file, format, out, err),
        Command::Bench {
            file,
            engine,
            tolerance,
            repeats,
            format,
            float,
            no_predictor,
            dense_lu,
        } => {
            let settings = crate::engine::Settings { predictor: !no_predictor, dense_lu };
            let how = BenchHow { tolerance, repeats, float: float.scalar(), settings };
            bench(&file, engine, &how, format, out, err)
        }
        Command::Codegen { check } => codegen(check, out, err),
        Command::Plot { file, point, body, quantity, output } => {
            let target = match (point, body) {
                (Some(p), _) => crate::plot::Target::Point(p),
                (None, b) => crate::plot::Target::Body(b.unwrap_or_default()),
            };
            plot::plot(&file, &target, quantity, &output, out, err)
        }
    };
    match result {
        Ok(code) => code,
        Err(e) if closed_pipe(&e) => EXIT_OK,
        Err(e) => {
            let _ = writeln!(err, "error: {}", printable(&e.to_string()));
            EXIT_INVALID
        }
    }
}

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
enum Sink<'a> {
    File(report::OutputFile),
    Out(BufWriter<&'a mut dyn Write>),
}

impl Sink<'_> {
    /// Ends the output: the file is renamed into place, standard output flushed.
    fn close(self) -> io::Result<()> {
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

impl Command {
    /// The `-o` file of the command and the files it reads, when it has one.
    fn output(&self) -> Option<(&Path, Vec<&Path>)> {
        match self {
            Self::Solve { file, output: Some(o), .. }
            | Self::Generate { file, output: Some(o), .. }
            | Self::ImportYoung { deck: file, output: Some(o) } => Some((o, vec![file])),
            Self::Chart { file, output, .. } | Self::Plot { file, output, .. } => {
                Some((output, vec![file]))
            }
            _ => None,
        }
    }
}

/// Why `-o OUTPUT` cannot be written, found before any work: its directory is missing, it
/// is a directory, or it is one of the command's input files (the same path once links are
/// resolved, or the same file by device and inode), which writing would destroy.
fn output_problem(output: &Path, inputs: &[&Path]) -> Option<Diagnostic> {
    let shown = |p: &Path| printable(&p.display().to_string()).into_owned();
    let problem = |m: String| Diagnostic::error(m).entity("command line").field("--output");
    let dir = report::directory_of(output);
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
fn report_invalid(
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
fn report_in_source(
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
fn load(file: &Path, json: bool, out: &mut dyn Write, err: &mut dyn Write) -> Result<Loaded, i32> {
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

/// The number of unknowns left once ground bodies, `fix` constraints, coordinate
/// differences against ground and absolute coordinate drivers are eliminated (each removes
/// one unknown and its equation).
fn reduced_unknowns(mech: &Mechanism) -> usize {
    let fixed = mech
        .constraints
        .iter()
        .filter(|c| match c.kind {
            ConstraintKind::Fix { .. } => true,
            ConstraintKind::CoordinateDifference { body_i, body_j, .. } => {
                mech.bodies[body_i.0].ground || mech.bodies[body_j.0].ground
            }
        })
        .count();
    let driven = mech
        .drivers
        .iter()
        .filter(|d| {
            matches!(
                d.target,
                DriverTarget::Absolute {
                    coordinate: DriverCoordinate::X | DriverCoordinate::Y | DriverCoordinate::Z,
                    ..
                }
            )
        })
        .count();
    mech.unknowns().saturating_sub(fixed + driven)
}

/// The invalid-input diagnostic for an undriven degree of freedom, if Φ_q has lower column
/// rank than the unknowns.
fn undriven(eq: &Equations<'_>, prep: &crate::generic::Preparation) -> Option<Diagnostic> {
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

fn check(
    file: &Path,
    format: CheckFormat,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let json = format == CheckFormat::Json;
    let loaded = match load(file, json, out, err) {
        Ok(l) => l,
        Err(code) => return Ok(code),
    };
    let mech = &loaded.mechanism;
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    if let Some(d) = undriven(&eq, &prep) {
        return Ok(report_invalid(&[d], json, out, err));
    }
    let redundant: Vec<String> =
        prep.redundant.iter().map(|&k| eq.labels()[k].equation()).collect();
    // The generated system's true size; the count of eliminated coordinates when it cannot
    // be built (its diagnostics belong to `generate`).
    let reduced = crate::symbolic::Symbolic::build(mech)
        .map_or_else(|_| reduced_unknowns(mech), |s| s.unknowns.len());
    let bodies = mech.bodies.len();
    let grounds = mech.bodies.iter().filter(|b| b.ground).count();
    if json {
        let v = serde_json::json!({
            "bodies": bodies,
            "unknowns": eq.unknowns(),
            "equations": eq.equations(),
            "reduced_unknowns": reduced,
            "rank": prep.rank,
            "mobility": prep.mobility,
            "drivers": mech.drivers.len(),
            "redundant": redundant,
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
    } else {
        writeln!(out, "mechanism {}: {bodies} bodies ({grounds} ground)", printable(&mech.name))?;
        writeln!(out, "unknowns:          {}", eq.unknowns())?;
        writeln!(out, "equations:         {}", eq.equations())?;
        writeln!(out, "reduced unknowns:  {reduced} (generated system)")?;
        let at = if prep.assembled {
            "assembled at t = start"
        } else {
            "initial estimates, not assembled"
        };
        writeln!(out, "rank of Φ_q:       {} ({at})", prep.rank)?;
        writeln!(
            out,
            "mobility:          {} (degrees of freedom before the drivers)",
            prep.mobility
        )?;
        writeln!(out, "drivers:           {}", mech.drivers.len())?;
        if redundant.is_empty() {
            writeln!(out, "redundant:         none")?;
        } else {
            writeln!(out, "redundant:         {}", printable(&redundant.join(", ")))?;
        }
    }
    Ok(EXIT_OK)
}

/// Builds the generated solver, printing what the cache repaired on the way.
fn build_generated(
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
fn engine_unavailable(
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

fn solve(
    file: &Path,
    engine: Option<Engine>,
    format: SolveFormat,
    output: Option<&Path>,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let json = format == SolveFormat::Json;
    let loaded = match load(file, json, out, err) {
        Ok(l) => l,
        Err(code) => return Ok(code),
    };
    let mech = &loaded.mechanism;
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    if let Some(d) = undriven(&eq, &prep) {
        return Ok(report_invalid(&[d], json, out, err));
    }
    // The default engine is the generated one when it can be built, else the generic one.
    let built = match engine {
        Some(Engine::Generic) => None,
        Some(Engine::Generated) => match build_generated(mech, crate::emit::Scalar::F64, err)? {
            Ok(b) => Some(b),
            Err(e) => return engine_unavailable(&e, mech, json, out, err),
        },
        None => match build_generated(mech, crate::emit::Scalar::F64, err)? {
            Ok(b) => Some(b),
            Err(e @ crate::engine::EngineError::Config(_)) => {
                return engine_unavailable(&e, mech, json, out, err);
            }
            Err(e) => {
                writeln!(err, "warning: using the generic engine: {e}")?;
                None
            }
        },
    };
    let fmt = match format {
        SolveFormat::Table => report::Format::Table,
        SolveFormat::Csv => report::Format::Csv,
        SolveFormat::Json => report::Format::Json,
    };
    let sink = match output {
        Some(path) => match report::OutputFile::create(path) {
            Ok(file) => Sink::File(file),
            Err(e) => {
                let d = Diagnostic::error(e.to_string()).entity("command line").field("--output");
                return Ok(report_invalid(&[d], json, out, err));
            }
        },
        None => Sink::Out(BufWriter::new(out)),
    };
    let name = if built.is_some() { "generated" } else { "generic" };
    // The redundant equations each engine leaves out, said in the output itself and on
    // standard error.
    let removed: Vec<String> = match &built {
        Some(b) => b.removed.clone(),
        None => prep.redundant.iter().map(|&k| eq.labels()[k].equation()).collect(),
    };
    for r in &removed {
        writeln!(
            err,
            "warning: equation {} depends on the others at the initial configuration and is \
             left out of the analysis",
            printable(r)
        )?;
    }
    let writer = Writer::begin(sink, fmt, mech, name, &removed)?;
    stream(mech, &Analysis::new(&eq, &prep), built.as_ref(), writer, err)
}

/// Runs the analysis on the generated solver `built`, or on the generic engine, writing each
/// time point as it comes, and ends the output with the error if the run stopped; returns
/// the exit status.
fn stream(
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
    let mut sink = |frame: &crate::generic::Frame| {
        bar.inc(1);
        writer.step(&report::step_result(mech, &layout, frame)).inspect_err(|e| {
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
    if let Some(f) = &failure {
        writeln!(err, "error: {}", report::failure_text(f))?;
        return Ok(EXIT_STOPPED);
    }
    Ok(EXIT_OK)
}

fn import_young(
    deck: &Path,
    output: Option<&Path>,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let desc = match young::import_file(deck) {
        Ok(d) => d,
        Err(d) => return Ok(report_invalid(&[d], false, out, err)),
    };
    let file_name = deck
        .file_name()
        .map_or_else(|| deck.display().to_string(), |f| f.to_string_lossy().into_owned());
    let toml =
        young::to_toml(&desc, &format!("Imported by mechgen from the YOUNG deck {file_name}."));
    match output {
        Some(path) => report::write_file(path, toml.as_bytes())?,
        None => out.write_all(toml.as_bytes())?,
    }
    Ok(EXIT_OK)
}

fn generate(
    file: &Path,
    scalar: crate::emit::Scalar,
    output: Option<&Path>,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let loaded = match load(file, false, out, err) {
        Ok(l) => l,
        Err(code) => return Ok(code),
    };
    let sys = match crate::symbolic::Symbolic::build(&loaded.mechanism) {
        Ok(s) => s,
        Err(e) => {
            let d = Diagnostic::error(e.message)
                .entity(format!("mechanism \"{}\"", loaded.mechanism.name));
            return Ok(report_invalid(&[d], false, out, err));
        }
    };
    let text = crate::emit::module_in(&loaded.mechanism, &sys, &file.display().to_string(), scalar);
    let tolerance = loaded.mechanism.solver.tolerance;
    if scalar == crate::emit::Scalar::F32 && tolerance < 1e-5 {
        writeln!(
            err,
            "warning: the description's tolerance {tolerance:e} (the module's TOLERANCE) is \
             below what single precision reaches; set NewtonOptions::tolerance to about 1e-4 \
             (runtime::Real::DEFAULT_TOLERANCE for f32)"
        )?;
    }
    match output {
        Some(path) => report::write_file(path, text.as_bytes())?,
        None => out.write_all(text.as_bytes())?,
    }
    Ok(EXIT_OK)
}

fn codegen(check: bool, out: &mut dyn Write, err: &mut dyn Write) -> io::Result<i32> {
    let mode = if check { crate::sync::Mode::Check } else { crate::sync::Mode::Write };
    match crate::sync::sync(&crate::sync::workspace_root(), mode) {
        Ok(stale) => {
            for s in &stale {
                writeln!(out, "{}: {s:?}", if check { "stale" } else { "updated" })?;
            }
            Ok(if check && !stale.is_empty() { EXIT_INVALID } else { EXIT_OK })
        }
        Err(e) => {
            writeln!(err, "error: {e}")?;
            Ok(EXIT_INVALID)
        }
    }
}

/// Times `repeats` whole passes of the generic engine.
fn time_generic(
    eq: &Equations<'_>,
    prep: &crate::generic::Preparation,
    tolerance: f64,
    repeats: usize,
    predictor: bool,
) -> Option<(f64, f64, f64)> {
    Analysis::new(eq, prep).with_tolerance(tolerance).with_predictor(predictor).time(repeats)
}

/// The timing options of `bench`.
struct BenchHow {
    tolerance: Option<f64>,
    repeats: usize,
    float: crate::emit::Scalar,
    settings: crate::engine::Settings,
}

fn bench(
    file: &Path,
    engine: BenchEngine,
    how: &BenchHow,
    format: CheckFormat,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let repeats = how.repeats;
    let json = format == CheckFormat::Json;
    let loaded = match load(file, json, out, err) {
        Ok(l) => l,
        Err(code) => return Ok(code),
    };
    let mech = &loaded.mechanism;
    let tolerance = how.tolerance.unwrap_or(mech.solver.tolerance);
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    if let Some(d) = undriven(&eq, &prep) {
        return Ok(report_invalid(&[d], json, out, err));
    }
    let steps = mech.time.count;
    let mut results = Vec::new();
    if engine != BenchEngine::Generated {
        let spinner = term::spinner(&format!("timing the generic engine ({repeats} passes)"));
        let timed = time_generic(&eq, &prep, tolerance, repeats, how.settings.predictor);
        spinner.finish_and_clear();
        match timed {
            Some(r) => results.push(("generic", r)),
            None => {
                writeln!(err, "error: the generic analysis failed")?;
                return Ok(EXIT_STOPPED);
            }
        }
    }
    if engine != BenchEngine::Generic {
        let built = match build_generated(mech, how.float, err)? {
            Ok(b) => b,
            Err(e) => return engine_unavailable(&e, mech, json, out, err),
        };
        let spinner = term::spinner(&format!("timing the generated engine ({repeats} passes)"));
        let timed = crate::engine::bench_with(&built, tolerance, repeats, how.settings);
        spinner.finish_and_clear();
        match timed {
            Ok(r) => results.push(("generated", r)),
            Err(e) => {
                writeln!(err, "error: {e}")?;
                return Ok(EXIT_STOPPED);
            }
        }
    }
    let objects: Vec<serde_json::Value> = results
        .iter()
        .map(|(name, (min, median, iters))| {
            serde_json::json!({
                "mechanism": mech.name,
                "engine": name,
                "tolerance": tolerance,
                "steps": steps,
                "repeats": repeats.max(1),
                "ns_per_step": { "min": min, "median": median },
                "iterations_per_step": iters,
                "float": if *name == "generated" { how.float.name() } else { "f64" },
                "predictor": how.settings.predictor,
                "lu": if *name == "generated" && !how.settings.dense_lu { "structured" } else { "dense" },
            })
        })
        .collect();
    let speedup = (results.len() == 2).then(|| results[0].1.1 / results[1].1.1);
    if json {
        let v = match speedup {
            Some(s) => serde_json::json!({ "results": objects, "speedup": s }),
            None => objects.into_iter().next().unwrap_or_default(),
        };
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
    } else {
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
            "{} ({steps} time points, tolerance {tolerance:e}, {} repeats{})",
            printable(&mech.name),
            repeats.max(1),
            notes.concat()
        )?;
        for (name, (min, median, iters)) in &results {
            writeln!(
                out,
                "{name:>10}: {min:>10.0} ns/step min, {median:>10.0} ns/step median, {iters:.2} Newton iterations/step"
            )?;
        }
        if let Some(s) = speedup {
            writeln!(out, "   speedup: {s:.1}x (generic median / generated median)")?;
        }
    }
    Ok(EXIT_OK)
}

fn compare(
    file: &Path,
    format: CheckFormat,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let json = format == CheckFormat::Json;
    let loaded = match load(file, json, out, err) {
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
    // Both engines run at once, the generic one on a thread of its own sending its steps
    // through a short queue, and the differences are taken as the pairs arrive: neither run
    // is kept, so memory does not grow with the grid.
    let layout = report::layout(mech);
    let mut diffs = report::Differences::default();
    let bar = term::bar(mech.time.count as u64, "both engines");
    let (generic, generated) = std::thread::scope(|scope| {
        let (send, receive) = std::sync::mpsc::sync_channel(64);
        let (eq, prep, layout) = (&eq, &prep, &layout);
        let generic = scope.spawn(move || {
            let mut steps = 0usize;
            // A closed queue (the generated run stopped) ends the generic run too.
            let r = Analysis::new(eq, prep).run(|f| {
                steps += 1;
                send.send(report::step_result(mech, layout, f)).map_err(|_| ())
            });
            (r.ok(), steps)
        });
        let generated = crate::engine::run(&built, &Analysis::new(eq, prep), None, |f| {
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
    });
    bar.finish_and_clear();
    let steps = match generic {
        (Some(r), steps) => {
            if let Some(f) = &r.failure {
                writeln!(err, "error: generic engine: {}", report::failure_text(f))?;
                return Ok(EXIT_STOPPED);
            }
            steps
        }
        // The generated run stopped first; its error is reported below.
        (None, steps) => steps,
    };
    match generated {
        Ok(r) if r.failure.is_none() => {}
        Ok(r) => {
            let f = r.failure.expect("checked");
            writeln!(err, "error: generated engine: {}", report::failure_text(&f))?;
            return Ok(EXIT_STOPPED);
        }
        Err(e) => {
            writeln!(err, "error: {e}")?;
            return Ok(EXIT_STOPPED);
        }
    }
    let diffs = diffs.finish();
    let repeats = 10;
    let spinner = term::spinner("timing both engines");
    let tg =
        time_generic(&eq, &prep, mech.solver.tolerance, repeats, true).map_or(f64::NAN, |r| r.1);
    let td = crate::engine::bench(&built, mech.solver.tolerance, repeats).map_or(f64::NAN, |r| r.1);
    spinner.finish_and_clear();
    if json {
        let v = serde_json::json!({
            "mechanism": mech.name,
            "steps": steps,
            "max_abs_diff": diffs.iter().map(|d| (d.0.to_owned(), serde_json::json!(d.1))).collect::<serde_json::Map<_, _>>(),
            "max_rel_diff": diffs.iter().map(|d| (d.0.to_owned(), serde_json::json!(d.2))).collect::<serde_json::Map<_, _>>(),
            "ns_per_step": { "generic": tg, "generated": td },
            "speedup": tg / td,
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
    } else {
        writeln!(out, "{}: {} time points, generic vs generated", printable(&mech.name), steps)?;
        writeln!(out, "{:>8} {:>14} {:>14}", "quantity", "max abs diff", "max rel diff")?;
        for (name, abs, rel) in &diffs {
            writeln!(out, "{name:>8} {abs:>14.3e} {rel:>14.3e}")?;
        }
        writeln!(out, "ns per step: generic {tg:.0}, generated {td:.0}; speedup {:.1}x", tg / td)?;
    }
    Ok(EXIT_OK)
}

fn chart(
    file: &Path,
    output: &Path,
    repeats: usize,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let loaded = match load(file, false, out, err) {
        Ok(l) => l,
        Err(code) => return Ok(code),
    };
    let mech = &loaded.mechanism;
    let bar = term::bar(crate::chart::mark_count() as u64, "marks");
    let measured = crate::chart::measure_with(mech, repeats, &mut |series, tolerance| {
        bar.set_message(format!("{series} {tolerance:.0e}"));
        bar.inc(1);
    });
    bar.finish_and_clear();
    let (marks, skipped) = match measured {
        Ok(m) => m,
        Err(e) => {
            writeln!(err, "error: {e}")?;
            return Ok(EXIT_STOPPED);
        }
    };
    writeln!(
        out,
        "{:<24} {:>9} {:>12} {:>10} {:>12}",
        "series", "tolerance", "ns/step", "iter/step", "max rel err"
    )?;
    for m in &marks {
        writeln!(
            out,
            "{:<24} {:>9.0e} {:>12.0} {:>10.2} {:>12.2e}",
            m.series, m.tolerance, m.ns_per_step, m.iterations, m.error
        )?;
    }
    for s in &skipped {
        writeln!(err, "note: no mark for {s} (the run failed)")?;
    }
    let title = format!("{}: speed against accuracy ({} time points)", mech.name, mech.time.count);
    if let Err(e) = crate::chart::draw(&marks, &title, output) {
        writeln!(err, "error: {e}")?;
        return Ok(EXIT_INVALID);
    }
    writeln!(out, "wrote {}", printable(&output.display().to_string()))?;
    Ok(EXIT_OK)
}

fn scaling(
    sizes: &[usize],
    repeats: usize,
    dump: Option<&Path>,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    writeln!(
        out,
        "| mechanism | bodies | unknowns (reduced) | generate (s) | lines | build (s) | generic ns/step | generated ns/step | speedup |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|---|---|")?;
    for &n in sizes {
        for text in [crate::scale::chain(n, 20), crate::scale::rssr_loops(n.div_ceil(3), 20)] {
            let loaded = match validate::load_str(&text, validate::Format::Toml, None) {
                Ok(l) => l,
                Err(d) => return Ok(report_invalid(&d, false, out, err)),
            };
            let mech = &loaded.mechanism;
            if let Some(dir) = dump {
                std::fs::create_dir_all(dir)?;
                std::fs::write(dir.join(format!("{}.toml", mech.name)), &text)?;
            }
            let start = std::time::Instant::now();
            let sys = match crate::symbolic::Symbolic::build(mech) {
                Ok(s) => s,
                Err(e) => {
                    writeln!(err, "{}: {e}", mech.name)?;
                    continue;
                }
            };
            let module = crate::emit::module(mech, &sys, "scaling");
            let generate = start.elapsed().as_secs_f64();
            let lines = module.lines().count();
            let start = std::time::Instant::now();
            let built = match crate::engine::build_module(
                mech,
                &module,
                sys.unknowns.len(),
                crate::emit::Scalar::F64,
            ) {
                Ok(b) => b,
                Err(e) => {
                    writeln!(err, "{}: {e}", mech.name)?;
                    continue;
                }
            };
            let build = start.elapsed().as_secs_f64();
            let eq = Equations::new(mech);
            let prep = eq.prepare();
            let generic = time_generic(&eq, &prep, mech.solver.tolerance, repeats, true)
                .map_or(f64::NAN, |r| r.1);
            let generated = crate::engine::bench(&built, mech.solver.tolerance, repeats)
                .map_or(f64::NAN, |r| r.1);
            writeln!(
                out,
                "| {} | {} | {} ({}) | {generate:.2} | {lines} | {build:.1} | {generic:.0} | {generated:.0} | {:.1} |",
                mech.name,
                mech.bodies.len() - 1,
                eq.unknowns(),
                sys.unknowns.len(),
                generic / generated
            )?;
            out.flush()?;
        }
    }
    Ok(EXIT_OK)
}
