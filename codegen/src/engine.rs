//! The generated engine for any description: generate the module, build it against the
//! `runtime` crate's sources embedded in mechgen (in a verified cache, [`cache`]), run it,
//! and read its frames back. The solver process never outlives the reading: it is killed
//! when the reader stops, and it stops by itself when its output is closed.
//!
//! The built program writes one binary record per time point ([`step_record`]: t, the Newton
//! iterations, the residual, the condition estimate and q, q̇ and q̈ of every moving body, 7
//! each, body by body, as raw little-endian doubles, so that nothing is formatted or parsed),
//! or, when the analysis stops, the text lines `near t q…` (the configuration closest to the
//! failure, if any) and `error kind t body message`. A text line
//! `step t iterations residual condition q… q̇… q̈…` (shortest round-trip numbers) is read as a
//! step too. Run mode takes each step under the step control of
//! [`runtime::step`], which the program links with the solver. In `bench` mode it times whole passes
//! over the grid and prints `bench min_ns median_ns iterations_per_step`.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

use nalgebra::DVector;

use crate::emit::{self, Scalar};
use crate::generic::{Analysis, Failure, FailureKind, Frame};
use crate::model::Mechanism;
use crate::stepping::{Point, Stop, Trouble};
use crate::symbolic::{GenerateError, Symbolic};

pub mod cache;

/// Why the generated engine could not run.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    /// The description cannot be generated (e.g. an undriven degree of freedom).
    #[error("cannot generate: {0}")]
    Generate(#[from] GenerateError),
    /// The environment names no usable cache directory (e.g. `MECHGEN_CACHE` set but empty).
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The generated crate could not be built.
    #[error("the generated solver could not be built: {}\nfix: {}", .0.reason, .0.fix)]
    Build(BuildFailure),
    /// Running it failed or printed something unexpected.
    #[error("cannot run the generated solver: {0}")]
    Run(#[from] RunError),
    /// The sink could not write a frame (e.g. standard output was closed): the solver was
    /// stopped and the sink's error is handed back as it came.
    #[error("cannot write the results: {0}")]
    Output(#[source] std::io::Error),
}

/// Why no directory for built solvers can be used: the user sets `MECHGEN_CACHE`.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// `MECHGEN_CACHE` is set to the empty string.
    #[error(
        "MECHGEN_CACHE is set but empty: set it to the directory where mechgen should keep \
         built solvers, or unset it to use the default"
    )]
    EmptyCache,
    /// `MECHGEN_CACHE` names a directory that cannot be made absolute.
    #[error("MECHGEN_CACHE={}: {source}", .dir.display())]
    BadCache {
        /// The value of `MECHGEN_CACHE`.
        dir: PathBuf,
        /// Why it cannot be used.
        source: std::io::Error,
    },
    /// The checkout mechgen was built from is gone and the environment names no user cache.
    #[error(
        "no directory for built solvers: the checkout mechgen was built from ({}) is gone and \
         the environment names no cache directory (XDG_CACHE_HOME, HOME); set MECHGEN_CACHE \
         to a writable directory",
        .checkout.display()
    )]
    NoCacheDir {
        /// Where the checkout was.
        checkout: PathBuf,
    },
}

/// Why a built solver could not be run or read.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The program could not be started.
    #[error("{}: {source}", .binary.display())]
    Start {
        /// The solver's program.
        binary: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// Its output could not be read.
    #[error(transparent)]
    Read(std::io::Error),
    /// A line of the expected kind whose numbers do not parse.
    #[error("malformed line: {0}")]
    Malformed(String),
    /// A line the protocol does not have (see the module docs).
    #[error("unexpected output: {0}")]
    Unexpected(String),
    /// `bench` printed something else than its one line.
    #[error("unexpected benchmark output: {}", if .0.trim().is_empty() { "nothing (the solver stopped without a word)" } else { .0.trim() })]
    Benchmark(String),
    /// A timed pass stopped: Newton failed at `t` (the timed passes run plain stepping, without
    /// the step control `solve` uses).
    #[error(
        "the timed pass stopped at t = {t} ({kind}): {message} (bench times plain steps without \
         the step control of solve; `mechgen solve` shows where and why the analysis itself \
         stops)"
    )]
    BenchmarkStopped {
        /// The grid time of the failed step.
        t: f64,
        /// The contract's `error.kind`: `singular` or `no_convergence`.
        kind: String,
        /// The runtime's reason.
        message: String,
    },
    /// The solver exited with a failure status without reporting a failure.
    #[error("the solver exited with {0}")]
    Exit(std::process::ExitStatus),
}

/// Why a generated solver could not be built, and what to do about it.
#[derive(Clone, Debug)]
pub struct BuildFailure {
    /// What failed, with cargo's own words where cargo failed.
    pub reason: String,
    /// What the user can do.
    pub fix: String,
}

/// A generated solver, built and ready to run.
#[derive(Clone, Debug)]
pub struct Built {
    /// The program.
    pub binary: PathBuf,
    /// Size of the reduced system.
    pub unknowns: usize,
    /// The equations the generator left out as redundant (`joint O4 row 2`).
    pub removed: Vec<String>,
    /// The driver indices of the module's input drivers, in its input order.
    pub inputs: Vec<usize>,
    /// The replayed series (`--inputs`) the runs feed the solver on its standard input, one
    /// line per time point, `t` and `[s, ṡ, s̈]` of every input driver; `None` runs the
    /// module's own grid.
    pub series: Option<std::sync::Arc<String>>,
    /// What was found wrong in the cache and repaired on the way (a corrupt lock file, a
    /// binary that did not match its record), one sentence each.
    pub notes: Vec<String>,
    /// Whether the module was generated for this call: false when the cache's description
    /// index named a verified entry for the same model, setting and mechgen.
    pub generated: bool,
}

pub use cache::cache_dir;

/// Generates, writes and builds the solver of `mech` (a no-op build when the cache holds it).
///
/// # Errors
/// [`EngineError::Generate`], [`EngineError::Config`] or [`EngineError::Build`].
pub fn build(mech: &Mechanism) -> Result<Built, EngineError> {
    build_in(mech, Scalar::F64)
}

/// [`build`] with the module generated in the floating-point type `scalar`.
///
/// # Errors
/// [`EngineError::Generate`], [`EngineError::Config`] or [`EngineError::Build`].
pub fn build_in(mech: &Mechanism, scalar: Scalar) -> Result<Built, EngineError> {
    build_as(mech, scalar, cache::fingerprint())
}

/// [`build_in`] for a mechgen of fingerprint `fingerprint` (its description index entries
/// are its own; see [`cache`]).
fn build_as(mech: &Mechanism, scalar: Scalar, fingerprint: &str) -> Result<Built, EngineError> {
    let start = std::time::Instant::now();
    // The solver is built for the description's own grid, whatever series a run replays
    // (which it reads at run time): one cache entry serves every series.
    let replayed = mech.time.replay.clone();
    let declared;
    let mech = if mech.time.replay.is_some() {
        declared = Mechanism { time: mech.time.declared(), ..mech.clone() };
        &declared
    } else {
        mech
    };
    let index = cache::Index::new(cache_dir()?, &format!("{mech:?}"), scalar.name(), fingerprint);
    let mut built = match index.lookup() {
        Some((described, binary)) => Built {
            binary,
            unknowns: described.unknowns,
            removed: described.removed,
            inputs: described.inputs,
            series: None,
            notes: Vec::new(),
            generated: false,
        },
        None => {
            let sys = Symbolic::build(mech)?;
            let module =
                emit::module_in(mech, &sys, &format!("the description \"{}\"", mech.name), scalar);
            log::debug!(
                "generated {} in {} ({} unknowns, {} lines) in {:.3} s",
                mech.name,
                scalar.name(),
                sys.unknowns.len(),
                module.lines().count(),
                start.elapsed().as_secs_f64()
            );
            let (mut built, key) = build_keyed(mech, &module, &sys, scalar)?;
            built.inputs = sys.inputs.iter().map(|d| d.driver).collect();
            built.removed = sys.redundant.iter().map(crate::generic::RowLabel::equation).collect();
            index.record(&cache::Described {
                key,
                unknowns: built.unknowns,
                removed: built.removed.clone(),
                inputs: built.inputs.clone(),
            });
            built
        }
    };
    built.series = replayed.map(|r| std::sync::Arc::new(series_text(&r, &built.inputs)));
    Ok(built)
}

/// The text a solver reads with `series`: per time point of `replay`, `t` and the `[s, ṡ, s̈]`
/// of every driver of `inputs`, in shortest round-trip form.
fn series_text(replay: &crate::inputs::Replay, inputs: &[usize]) -> String {
    use std::fmt::Write as _;
    let mut text = String::with_capacity(replay.t.len() * (1 + 3 * inputs.len()) * 20);
    for (k, t) in replay.t.iter().enumerate() {
        let _ = write!(text, "{t:?}");
        for &d in inputs {
            let u = replay.series(d).map_or([f64::NAN; 3], |s| s[k]);
            let _ = write!(text, " {:?} {:?} {:?}", u[0], u[1], u[2]);
        }
        text.push('\n');
    }
    text
}

/// Starts `cmd` with its standard output piped and, when `series` is given, the `series`
/// flag and the series written to its standard input (which the solver reads whole before it
/// writes anything, so writing it all first cannot deadlock).
fn spawn(mut cmd: Command, built: &Built) -> Result<SolverProcess, EngineError> {
    if built.series.is_some() {
        cmd.arg("series");
    }
    let stdin = if built.series.is_some() { Stdio::piped() } else { Stdio::null() };
    let child = cmd
        .stdout(Stdio::piped())
        .stdin(stdin)
        .spawn()
        .map_err(|source| RunError::Start { binary: built.binary.clone(), source })?;
    let mut child = SolverProcess(child);
    if let (Some(series), Some(mut input)) = (&built.series, child.0.stdin.take()) {
        // A solver that stops reading early (it exits on a bad line) shows in its output and
        // exit status, which the caller reads: a failed write is not an error by itself.
        let _ = input.write_all(series.as_bytes());
    }
    Ok(child)
}

/// Writes and builds a module generated for `mech` (with `unknowns` unknowns) in the
/// floating-point type `scalar`, as [`build_in`] does after generating it. The cache entry
/// is used when it verifies, and rebuilt otherwise (see [`cache`]).
///
/// # Errors
/// [`EngineError::Config`] or [`EngineError::Build`].
pub fn build_module(
    mech: &Mechanism,
    module: &str,
    sys: &Symbolic,
    scalar: Scalar,
) -> Result<Built, EngineError> {
    build_keyed(mech, module, sys, scalar).map(|(built, _)| built)
}

/// [`build_module`], with the KEY of the module's cache entry.
fn build_keyed(
    mech: &Mechanism,
    module: &str,
    sys: &Symbolic,
    scalar: Scalar,
) -> Result<(Built, String), EngineError> {
    let unknowns = sys.unknowns.len();
    let inputs = mech.drivers.iter().any(|d| d.law == crate::model::Law::Input);
    let recipe = cache::Recipe::new(
        cache_dir()?,
        module,
        &emit::type_name(&mech.name),
        scalar.name(),
        cache::Shape { inputs, dropped: !sys.dropped.is_empty() },
    );
    let mut notes = Vec::new();
    recipe.ensure(&mut notes)?;
    let built = Built {
        binary: recipe.binary(),
        unknowns,
        removed: Vec::new(),
        inputs: Vec::new(),
        series: None,
        notes,
        generated: true,
    };
    Ok((built, recipe.key().to_owned()))
}

/// A running solver, killed and reaped when dropped: no solver outlives the reading side,
/// whether it stopped at the end, on an error, on a closed pipe or on a panic.
struct SolverProcess(Child);

impl Drop for SolverProcess {
    fn drop(&mut self) {
        // Both are no-ops once the process was waited for.
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The outcome of a generated run: frames were handed to the sink as they came.
#[derive(Clone, Debug)]
pub struct RunReport {
    /// Time points analysed.
    pub steps: usize,
    /// Why the analysis stopped early, if it did.
    pub failure: Option<Failure>,
}

/// Runs a built solver over the grid, handing each frame (full coordinates, generic layout)
/// to `sink`. A failure is named by `analysis` (the generic engine of the same mechanism) at
/// the configuration the solver reports closest to it, as the generic engine names its own.
///
/// # Errors
/// [`EngineError::Run`] for an unexpected output; [`EngineError::Output`] with the sink's
/// own error when it fails (the solver is stopped).
pub fn run(
    built: &Built,
    analysis: &Analysis<'_, '_>,
    tolerance: Option<f64>,
    sink: impl FnMut(&Frame) -> std::io::Result<()>,
) -> Result<RunReport, EngineError> {
    run_with(built, analysis, tolerance, Settings::default(), sink)
}

/// How a built solver runs: the runtime's predictor, and its static pivot orders or dense LU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Settings {
    /// Start Newton from the runtime's Taylor predictor (on by default).
    pub predictor: bool,
    /// Factor Φ_q by dense LU with partial pivoting only, hiding the module's static pivot
    /// orders (off by default).
    pub dense_lu: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings::DEFAULT
    }
}

impl Settings {
    /// Predictor on, structured LU: what `run` and `bench` use.
    pub const DEFAULT: Settings = Settings { predictor: true, dense_lu: false };

    /// The driver's flags for these settings.
    fn flags(self) -> impl Iterator<Item = &'static str> {
        [(!self.predictor).then_some("no-predictor"), self.dense_lu.then_some("dense")]
            .into_iter()
            .flatten()
    }
}

/// [`run`] with the given [`Settings`].
///
/// # Errors
/// As [`run`].
pub fn run_with(
    built: &Built,
    analysis: &Analysis<'_, '_>,
    tolerance: Option<f64>,
    settings: Settings,
    mut sink: impl FnMut(&Frame) -> std::io::Result<()>,
) -> Result<RunReport, EngineError> {
    let mut cmd = Command::new(&built.binary);
    cmd.arg("run");
    if let Some(t) = tolerance {
        cmd.arg(format!("{t:?}"));
    } else {
        cmd.arg("-");
    }
    cmd.args(settings.flags());
    log::debug!("running {} {:?}", built.binary.display(), settings);
    // Every return below, early or not, ends the solver.
    let mut child = spawn(cmd, built)?;
    let stdout = child.0.stdout.take().expect("piped");
    let mut report = RunReport { steps: 0, failure: None };
    let mut near: Option<Point> = None;
    let mut reader = BufReader::with_capacity(1 << 16, stdout);
    let (mut bytes, mut record) = (Vec::new(), Vec::new());
    // One frame, refilled by every record: no allocation per step.
    let mut frame = Frame {
        index: 0,
        t: f64::NAN,
        iterations: 0,
        residual: f64::NAN,
        condition: f64::NAN,
        q: DVector::zeros(0),
        qd: DVector::zeros(0),
        qdd: DVector::zeros(0),
        redundant: None,
    };
    let mut named = analysis.initially_redundant().to_vec();
    loop {
        let first = reader.fill_buf().map_err(RunError::Read)?.first().copied();
        let step = match first {
            None => break,
            Some(STEP_RECORD) => {
                match step_record(&mut reader, &mut record, report.steps, &mut frame)? {
                    Some(failure) => Err(failure),
                    None => {
                        frame.redundant = analysis.redundant_change(&mut named, &frame.q, frame.t);
                        sink(&frame).map_err(EngineError::Output)?;
                        report.steps += 1;
                        continue;
                    }
                }
            }
            Some(_) => {
                bytes.clear();
                reader.read_until(b'\n', &mut bytes).map_err(RunError::Read)?;
                let text = String::from_utf8_lossy(&bytes);
                let line = text.strip_suffix('\n').unwrap_or(&text).to_owned();
                let mut words = line.split(' ');
                match words.next() {
                    Some("step") => step_line(&line, report.steps)?,
                    Some("near") => {
                        near = Some(near_line(&line, analysis.unknowns())?);
                        continue;
                    }
                    Some("error") => {
                        let stop = error_line(&line, near.take());
                        report.failure = Some(analysis.failure_of(&stop));
                        continue;
                    }
                    _ => return Err(RunError::Unexpected(line).into()),
                }
            }
        };
        match step {
            Ok(mut frame) => {
                // The redundant rows by the generic engine's rule on the whole Φ_q, reported
                // where they change as it reports them.
                frame.redundant = analysis.redundant_change(&mut named, &frame.q, frame.t);
                sink(&frame).map_err(EngineError::Output)?;
                report.steps += 1;
            }
            Err(failure) => {
                report.failure = Some(failure);
                return Ok(report);
            }
        }
    }
    let status = child.0.wait().map_err(RunError::Read)?;
    if !status.success() && report.failure.is_none() {
        return Err(RunError::Exit(status).into());
    }
    Ok(report)
}

/// The first byte of a binary step record (see [`step_record`]); text lines start with a
/// letter.
const STEP_RECORD: u8 = 0;

/// The most coordinates a step record may announce: 7 per moving body at the bodies' limit,
/// with room to spare; more is a malformed record, not an allocation.
const MAX_RECORD_COORDINATES: usize = 1 << 16;

/// Reads the binary step record at the start of `reader` (the `index`-th) into `frame`, or
/// returns the failure it is when it holds a non-finite value other than the condition
/// estimate: the byte [`STEP_RECORD`], the number m of coordinates and the Newton iterations
/// as little-endian u32, then t, the residual, the condition estimate and m values each of q,
/// q̇ and q̈ as little-endian f64 (the driver's `step_record`). `record` is reused storage.
fn step_record(
    reader: &mut impl Read,
    record: &mut Vec<u8>,
    index: usize,
    frame: &mut Frame,
) -> Result<Option<Failure>, RunError> {
    let mut head = [0u8; 9];
    reader.read_exact(&mut head).map_err(RunError::Read)?;
    let word = |k: usize| u32::from_le_bytes([head[k], head[k + 1], head[k + 2], head[k + 3]]);
    let (m, iterations) = (word(1) as usize, word(5));
    if m > MAX_RECORD_COORDINATES {
        return Err(RunError::Malformed(format!("a step record of {m} coordinates")));
    }
    record.resize(8 * (3 + 3 * m), 0);
    reader.read_exact(record).map_err(RunError::Read)?;
    let mut values = record
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().expect("chunks of 8 bytes")));
    let mut next = || values.next().expect("3 + 3m values were read");
    let (t, residual, condition) = (next(), next(), next());
    // Straight into the frame, then checked: one pass over the record when all is well.
    let mut finite = residual.is_finite();
    for v in [&mut frame.q, &mut frame.qd, &mut frame.qdd] {
        if v.len() != m {
            *v = DVector::zeros(m);
        }
        for x in v.iter_mut() {
            *x = next();
            finite &= x.is_finite();
        }
    }
    if !finite {
        let mut read = frame.q.iter().chain(&frame.qd).chain(&frame.qdd).chain([&residual]);
        let bad = read.find(|v| !v.is_finite()).copied().unwrap_or(f64::NAN);
        return Ok(Some(non_finite(bad, t)));
    }
    (frame.index, frame.t, frame.iterations) = (index, t, iterations);
    (frame.residual, frame.condition, frame.redundant) = (residual, condition, None);
    Ok(None)
}

/// The failure of a step whose value `bad` is not finite, at time `t`.
fn non_finite(bad: f64, t: f64) -> Failure {
    let message = format!(
        "the generated solver produced the non-finite value {bad} (the steps before this one are \
         kept)"
    );
    Failure { kind: FailureKind::NoConvergence, t, message, constraints: Vec::new() }
}

/// The frame of a `step t iterations residual condition q… q̇… q̈…` line (the `index`-th),
/// or the failure it is when it holds a non-finite value other than the condition estimate
/// (never written: the analysis stops there, saying why).
fn step_line(line: &str, index: usize) -> Result<Result<Frame, Failure>, RunError> {
    let nums: Vec<&str> = line.split(' ').skip(1).collect();
    let bad = || RunError::Malformed(line.to_owned());
    let parse = |s: &str| s.parse::<f64>().map_err(|_| bad());
    if nums.len() < 4 || !(nums.len() - 4).is_multiple_of(21) {
        return Err(bad());
    }
    let m = (nums.len() - 4) / 3;
    let values: Vec<f64> = nums[4..].iter().map(|s| parse(s)).collect::<Result<_, _>>()?;
    if let Some(bad) = values.iter().chain(&[parse(nums[2])?]).find(|v| !v.is_finite()) {
        return Ok(Err(non_finite(*bad, parse(nums[0]).unwrap_or(f64::NAN))));
    }
    Ok(Ok(Frame {
        index,
        t: parse(nums[0])?,
        iterations: nums[1].parse().map_err(|_| bad())?,
        residual: parse(nums[2])?,
        condition: parse(nums[3])?,
        q: DVector::from_column_slice(&values[..m]),
        qd: DVector::from_column_slice(&values[m..2 * m]),
        qdd: DVector::from_column_slice(&values[2 * m..]),
        redundant: None,
    }))
}

/// The configuration of a `near t q… q̇… q̈…` line (`n` values each; the rates may be
/// missing): the one closest to the failure that follows.
fn near_line(line: &str, n: usize) -> Result<Point, RunError> {
    let bad = || RunError::Malformed(line.to_owned());
    let nums: Vec<f64> = line
        .split(' ')
        .skip(1)
        .map(|s| s.parse::<f64>().map_err(|_| bad()))
        .collect::<Result<_, _>>()?;
    let (&t, values) = nums.split_first().ok_or_else(bad)?;
    let (q, qd, qdd) = if n > 0 && values.len() == 3 * n {
        (&values[..n], &values[n..2 * n], &values[2 * n..])
    } else {
        (values, &[][..], &[][..])
    };
    Ok(Point {
        t,
        q: q.to_vec(),
        qd: qd.to_vec(),
        qdd: qdd.to_vec(),
        iterations: 0,
        residual: f64::NAN,
        pivot_ratio: f64::NAN,
    })
}

/// The stop of an `error kind t body message` line, at the configuration `near`.
fn error_line(line: &str, near: Option<Point>) -> Stop {
    let mut words = line.split(' ').skip(1);
    let trouble = match words.next() {
        Some("singular") => Trouble::Singular,
        Some("branch_jump") => Trouble::BranchJump,
        Some("inconsistent") => Trouble::Inconsistent,
        _ => Trouble::NoConvergence,
    };
    let t = words.next().and_then(|s| s.parse().ok()).unwrap_or(f64::NAN);
    let body = words.next().and_then(|s| s.parse().ok());
    let message = words.collect::<Vec<_>>().join(" ");
    Stop { trouble, t, message, near: near.map(Box::new), body }
}

/// Times whole passes over the grid: (min ns per step, median ns per step, Newton
/// iterations per step).
///
/// # Errors
/// [`EngineError::Run`] when the solver fails or prints something unexpected.
pub fn bench(
    built: &Built,
    tolerance: f64,
    repeats: usize,
) -> Result<(f64, f64, f64), EngineError> {
    bench_with(built, tolerance, repeats, Settings::default())
}

/// [`bench()`] with the given [`Settings`].
///
/// # Errors
/// As [`bench()`].
pub fn bench_with(
    built: &Built,
    tolerance: f64,
    repeats: usize,
    settings: Settings,
) -> Result<(f64, f64, f64), EngineError> {
    let mut cmd = Command::new(&built.binary);
    cmd.args(["bench", &format!("{tolerance:?}"), &repeats.to_string()]).args(settings.flags());
    let mut child = spawn(cmd, built)?;
    let mut output = Vec::new();
    child.0.stdout.take().expect("piped").read_to_end(&mut output).map_err(RunError::Read)?;
    drop(child);
    let text = String::from_utf8_lossy(&output);
    let words: Vec<&str> = text.split_whitespace().collect();
    match words.as_slice() {
        ["bench", min, median, iters] => {
            let p = |s: &str| s.parse::<f64>().map_err(|_| RunError::Benchmark(text.to_string()));
            Ok((p(min)?, p(median)?, p(iters)?))
        }
        ["error", "bench", t, kind, ..] => {
            let message = text.splitn(5, ' ').nth(4).unwrap_or_default().trim().to_owned();
            let t = t.parse::<f64>().map_err(|_| RunError::Benchmark(text.to_string()))?;
            Err(RunError::BenchmarkStopped { t, kind: (*kind).to_owned(), message }.into())
        }
        _ => Err(RunError::Benchmark(text.to_string()).into()),
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    /// A step record as the driver writes it, by the layout [`step_record`] documents.
    fn record(t: f64, iterations: u32, residual: f64, condition: f64, values: &[f64]) -> Vec<u8> {
        let m = u32::try_from(values.len() / 3).unwrap();
        let mut r = vec![STEP_RECORD];
        r.extend_from_slice(&m.to_le_bytes());
        r.extend_from_slice(&iterations.to_le_bytes());
        for x in [t, residual, condition].iter().chain(values) {
            r.extend_from_slice(&x.to_le_bytes());
        }
        r
    }

    /// The revolute example with its driver's velocity written as `velocity`.
    fn revolute(velocity: &str) -> Mechanism {
        let path = crate::sync::workspace_root().join("examples/revolute_joint.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        let text = text.replace("velocity = 1.047", &format!("velocity = {velocity}"));
        let format = crate::validate::Format::Toml;
        crate::validate::load_str(&text, format, None).unwrap().mechanism
    }

    #[test]
    fn a_described_module_is_generated_once_and_never_served_for_another() {
        // A mechgen of its own for this run, so that the index starts empty whatever earlier
        // runs left in the shared cache (the modules' own entries are shared and reused).
        let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap();
        let me = format!("test {} {}", std::process::id(), nanos.as_nanos());
        let other = format!("{me} other");
        let first = build_as(&revolute("1.047"), Scalar::F64, &me).unwrap();
        assert!(first.generated, "an empty index served a module");
        // The same model again, even written differently (another spelling of the same
        // number), finds its entry without generating.
        let again = build_as(&revolute("1.0470"), Scalar::F64, &me).unwrap();
        assert!(!again.generated, "the same description was generated again");
        assert_eq!((&again.binary, again.unknowns), (&first.binary, first.unknowns));
        // One number changed: a new module, generated and built.
        let changed = build_as(&revolute("1.048"), Scalar::F64, &me).unwrap();
        assert!(changed.generated, "a changed description was served a cached module");
        assert_ne!(changed.binary, first.binary);
        // Another precision is another module.
        let single = build_as(&revolute("1.047"), Scalar::F32, &me).unwrap();
        assert!(single.generated);
        assert_ne!(single.binary, first.binary);
        // Another mechgen never reads this one's index, even for the same description.
        let theirs = build_as(&revolute("1.047"), Scalar::F64, &other).unwrap();
        assert!(theirs.generated, "another mechgen's index entry was used");
        // The run's own index files are removed; the modules stay cached for the next run.
        for (velocity, scalar, fingerprint) in [
            ("1.047", Scalar::F64, &me),
            ("1.048", Scalar::F64, &me),
            ("1.047", Scalar::F32, &me),
            ("1.047", Scalar::F64, &other),
        ] {
            let model = format!("{:?}", revolute(velocity));
            cache::Index::new(cache_dir().unwrap(), &model, scalar.name(), fingerprint).forget();
        }
    }

    #[test]
    fn a_step_record_reads_back_every_value_exactly() {
        // 7 coordinates: values whose text would need 17 digits, a subnormal, −0.
        let values: Vec<f64> = (0..21)
            .map(|k| match k {
                0 => 0.1 + 0.2,
                1 => 5e-324,
                2 => -0.0,
                _ => std::f64::consts::PI * f64::from(k) * 1e-3,
            })
            .collect();
        let bytes = record(0.25, 3, 1.5e-17, 2.5e3, &values);
        let mut reader = std::io::Cursor::new(bytes);
        let mut frame = Frame {
            index: 0,
            t: 0.0,
            iterations: 0,
            residual: 0.0,
            condition: 0.0,
            q: DVector::zeros(0),
            qd: DVector::zeros(0),
            qdd: DVector::zeros(0),
            redundant: None,
        };
        assert!(step_record(&mut reader, &mut Vec::new(), 4, &mut frame).unwrap().is_none());
        assert_eq!((frame.index, frame.t, frame.iterations), (4, 0.25, 3));
        assert_eq!((frame.residual, frame.condition), (1.5e-17, 2.5e3));
        let read: Vec<f64> = frame.q.iter().chain(&frame.qd).chain(&frame.qdd).copied().collect();
        let bits = |xs: &[f64]| xs.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&read), bits(&values));
        // A NaN among the coordinates is a failure at the record's time, never a frame.
        let mut nan = values;
        nan[9] = f64::NAN;
        let mut reader = std::io::Cursor::new(record(0.5, 1, 0.0, 1.0, &nan));
        let failure = step_record(&mut reader, &mut Vec::new(), 0, &mut frame).unwrap().unwrap();
        assert_eq!((failure.kind, failure.t), (FailureKind::NoConvergence, 0.5));
        // A record that announces an absurd size is refused before anything is allocated.
        let mut huge = record(0.0, 0, 0.0, 1.0, &[]);
        huge[1..5].copy_from_slice(&u32::MAX.to_le_bytes());
        let err = step_record(&mut std::io::Cursor::new(huge), &mut Vec::new(), 0, &mut frame)
            .unwrap_err();
        assert!(matches!(err, RunError::Malformed(_)), "{err:?}");
    }

    #[test]
    fn a_non_finite_value_from_a_solver_stops_the_run_instead_of_being_written() {
        use std::os::unix::fs::PermissionsExt;
        // A stand-in solver: one good step of one body, then a step whose q̇ holds NaN.
        let good = format!("step 0.0 1 1e-12 2.0{}", " 0.5".repeat(21));
        let bad = format!("step 0.1 1 1e-12 2.0{} NaN{}", " 0.5".repeat(8), " 0.5".repeat(12));
        let script = format!("#!/bin/sh\necho '{good}'\necho '{bad}'\necho '{good}'\n");
        let path = std::env::temp_dir().join(format!("mechgen-fake-solver-{}", std::process::id()));
        std::fs::write(&path, script).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
        let built = Built {
            binary: path.clone(),
            unknowns: 7,
            removed: Vec::new(),
            inputs: Vec::new(),
            series: None,
            notes: Vec::new(),
            generated: true,
        };
        // The one-body revolute example names failures; the stand-in's output has its size.
        let loaded = crate::validate::load_file(
            &crate::sync::workspace_root().join("examples/revolute_joint.toml"),
        )
        .unwrap();
        let eq = crate::generic::Equations::new(&loaded.mechanism);
        let prep = eq.prepare();
        let analysis = Analysis::new(&eq, &prep);
        let mut written = Vec::new();
        let report = run(&built, &analysis, None, |f| {
            written.push(f.t);
            Ok(())
        })
        .unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(written, [0.0]);
        assert_eq!(report.steps, 1);
        let failure = report.failure.expect("the NaN is reported");
        assert_eq!(failure.t, 0.1);
        assert!(failure.message.contains("non-finite value NaN"), "{}", failure.message);
    }

    #[test]
    fn the_solver_is_killed_when_the_sink_stops_reading() {
        use std::os::unix::fs::PermissionsExt;
        // A stand-in solver that writes its process id, then steps of one body without end.
        let dir =
            std::env::temp_dir().join(format!("mechgen-endless-solver-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let pid_file = dir.join("pid");
        let step = format!("step 0.0 1 1e-12 2.0{}", " 0.5".repeat(21));
        let script = format!(
            "#!/bin/sh\necho $$ > '{}'\nwhile :; do echo '{step}'; done\n",
            pid_file.display()
        );
        let path = dir.join("solver");
        std::fs::write(&path, script).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
        let built = Built {
            binary: path,
            unknowns: 7,
            removed: Vec::new(),
            inputs: Vec::new(),
            series: None,
            notes: Vec::new(),
            generated: true,
        };
        let loaded = crate::validate::load_file(
            &crate::sync::workspace_root().join("examples/revolute_joint.toml"),
        )
        .unwrap();
        let eq = crate::generic::Equations::new(&loaded.mechanism);
        let prep = eq.prepare();
        let analysis = Analysis::new(&eq, &prep);
        let mut frames = 0;
        let result = run(&built, &analysis, None, |_| {
            frames += 1;
            if frames == 3 {
                Err(std::io::Error::from(std::io::ErrorKind::BrokenPipe))
            } else {
                Ok(())
            }
        });
        match result {
            Err(EngineError::Output(e)) => assert_eq!(e.kind(), std::io::ErrorKind::BrokenPipe),
            other => panic!("the sink's error is handed back as it came: {other:?}"),
        }
        let pid = std::fs::read_to_string(&pid_file).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        // `kill -0` fails for a process that no longer exists (it was killed and reaped).
        let alive = Command::new("kill").args(["-0", pid.trim()]).status().unwrap().success();
        assert!(!alive, "the solver {pid} still runs after the reader stopped");
    }
}
