//! The generated engine for any description: generate the module, build it against the
//! `runtime` crate's sources embedded in mechgen (in a verified cache, [`cache`]), run it,
//! and read its frames back. The solver process never outlives the reading: it is killed
//! when the reader stops, and it stops by itself when its output is closed.
//!
//! The built program prints one line per time point: `step t iterations residual` followed
//! by q, q̇ and q̈ of every moving body (7 each, body by body) in shortest round-trip form,
//! or, when the analysis stops, `near t q…` (the configuration closest to the failure, if
//! any) and `error kind t body message`. Run mode takes each step under the step control of
//! [`runtime::step`], which the program links with the solver. In `bench` mode it times whole passes
//! over the grid and prints `bench min_ns median_ns iterations_per_step`.

use std::io::{BufRead, BufReader, Read};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

use nalgebra::DVector;

use crate::emit::{self, Scalar};
use crate::generic::{Analysis, Failure, FailureKind, Frame};
use crate::model::Mechanism;
use crate::stepping::{Point, Stop, Trouble};
use crate::symbolic::Symbolic;

pub mod cache;

/// The driver program compiled with each generated module.
const DRIVER: &str = r#"//! Runs one generated mechanism over its time grid (written by mechgen; do not edit).
//!
//! Usage: `run|bench [tolerance] [repeats] [no-predictor] [dense]`, or `key` to print the
//! key of the cache entry it was built for.

mod key;
mod mechanism;

use std::io::Write;

use runtime::step::{self, Coordinates, Groups, Rejection, Sample, Stepper, Trouble};
use runtime::{AttemptError, Mechanism, NewtonError, NewtonOptions, Solver};

/// The floating-point type the module was generated in.
type Real = __REAL__;

const N: usize = mechanism::N;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mode = args.get(1).map_or("run", String::as_str);
    if mode == "key" {
        println!("key {}", key::KEY);
        return;
    }
    let tolerance = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(mechanism::TOLERANCE);
    let repeats: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1);
    let flag = |name: &str| args.iter().skip(2).any(|a| a == name);
    let predictor = !flag("no-predictor");
    if flag("dense") {
        // Static pivot orders hidden: every factorisation is dense LU with partial pivoting.
        drive(runtime::factors::DenseOnly(mechanism::__TYPE__), mode, tolerance, repeats, predictor);
    } else {
        drive(mechanism::__TYPE__, mode, tolerance, repeats, predictor);
    }
}

fn drive<M: Mechanism<N, Real>>(m: M, mode: &str, tolerance: Real, repeats: usize, predictor: bool) {
    let options = NewtonOptions {
        tolerance,
        max_iterations: mechanism::MAX_ITERATIONS,
        ..NewtonOptions::DEFAULT
    };
    let mut solver = Solver::with_storage(m, mechanism::Q0, jacobian());
    solver.set_options(options);
    solver.set_predictor(predictor);
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    if mode == "bench" {
        let mut times = Vec::with_capacity(repeats);
        let mut iterations = 0u64;
        for _ in 0..repeats.max(1) {
            solver.set_q(mechanism::Q0);
            iterations = 0;
            let start = std::time::Instant::now();
            for k in 0..mechanism::T_COUNT {
                let t = mechanism::T_START + k as Real * mechanism::T_STEP;
                match solver.position(t) {
                    Ok(r) => iterations += u64::from(r.iterations),
                    Err(e) => {
                        check(writeln!(out, "error bench {:?} {e}", f64::from(t)));
                        std::process::exit(2);
                    }
                }
                let _ = solver.velocity();
                let _ = solver.acceleration();
            }
            times.push(start.elapsed().as_nanos() as f64 / mechanism::T_COUNT as f64);
            std::hint::black_box(solver.qdd());
        }
        times.sort_by(f64::total_cmp);
        check(writeln!(
            out,
            "bench {:?} {:?} {:?}",
            times[0],
            times[times.len() / 2],
            iterations as f64 / mechanism::T_COUNT as f64
        ));
        return;
    }
    let mut engine = Engine {
        solver,
        dense: jacobian(),
        perm: [0; N],
        expanded: Box::new([[[0.0; 7]; 3]; mechanism::BODIES]),
        accepted: None,
        full: Full::default(),
        candidate: Full::default(),
    };
    let mut last: Option<Sample<f64>> = None;
    for k in 0..mechanism::T_COUNT {
        let t = mechanism::T_START + k as Real * mechanism::T_STEP;
        let outcome = match last {
            None => step::first(&mut engine, f64::from(t)).map(|p| (p, p.iterations)),
            Some(a) => step::advance(&mut engine, a, f64::from(t)),
        };
        match outcome {
            Ok((p, iterations)) => {
                check(write!(out, "step {:?} {iterations} {:?}", f64::from(t), p.residual));
                for v in [&engine.full.q, &engine.full.qd, &engine.full.qdd] {
                    for x in v {
                        check(write!(out, " {x:?}"));
                    }
                }
                check(writeln!(out));
                last = Some(p);
            }
            Err(stop) => {
                if let Some(near) = stop.near {
                    check(write!(out, "near {:?}", near.sample.t));
                    let q = if near.rejected { &engine.candidate.q } else { &engine.full.q };
                    for x in q {
                        check(write!(out, " {x:?}"));
                    }
                    check(writeln!(out));
                }
                let body = stop.body.map_or_else(|| "-".to_owned(), |b| b.to_string());
                let message = stop.to_string().replace('\n', " ");
                check(writeln!(out, "error {} {:?} {body} {message}", stop.trouble.as_str(), stop.t));
                check(out.flush());
                std::process::exit(2);
            }
        }
    }
}

/// Ends the process when standard output cannot be written: nobody reads the results any
/// more (mechgen stopped or its own output was closed), so computing on would be wasted.
fn check(written: std::io::Result<()>) {
    if written.is_err() {
        std::process::exit(3);
    }
}

/// The Jacobian of `N` rows, on the heap: large mechanisms would overflow the stack.
type Jacobian = Box<[[Real; N]; N]>;

fn jacobian() -> Jacobian {
    match vec![[0.0; N]; N].into_boxed_slice().try_into() {
        Ok(b) => b,
        Err(_) => unreachable!("the vector has N rows"),
    }
}

/// q, q̇ and q̈ of every moving body (7 each, body by body), as the step control reads them.
#[derive(Clone, Default)]
struct Full {
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
}

/// The generated solver under the step control of `runtime::step`, which checks continuity
/// on the full coordinates of every body (position and Euler parameters).
struct Engine<M> {
    solver: Solver<M, N, Real, Jacobian>,
    /// Φ_q at the last result, factored for its pivot ratio.
    dense: Jacobian,
    perm: [usize; N],
    expanded: Box<[[[Real; 7]; 3]; mechanism::BODIES]>,
    /// The last accepted (t, reduced q).
    accepted: Option<(Real, [Real; N])>,
    /// The last accepted point and the last attempt, in full coordinates.
    full: Full,
    candidate: Full,
}

impl<M: Mechanism<N, Real>> Stepper<f64> for Engine<M> {
    type Cause = AttemptError<Real>;

    fn attempt(&mut self, t: f64) -> Result<Sample<f64>, Rejection<f64, AttemptError<Real>>> {
        let t = t as Real;
        let report = self.solver.position(t).map_err(|e| {
            let trouble = match e {
                NewtonError::Singular { .. } => Trouble::Singular,
                _ => Trouble::NoConvergence,
            };
            Rejection::engine(trouble, AttemptError::Newton(e))
        })?;
        if let Err(e) = self.solver.velocity().and_then(|()| self.solver.acceleration()) {
            return Err(Rejection::engine(Trouble::Singular, AttemptError::Solve(e)));
        }
        self.solver.mechanism().jacobian(self.solver.q(), t, &mut self.dense);
        let pivot_ratio = match runtime::lu::factor_with_ratio(&mut self.dense, &mut self.perm, 0.0) {
            Ok(p) => f64::from(p.smallest) / f64::from(p.largest),
            Err(runtime::lu::Singular::SmallPivot { pivot, largest, .. }) => f64::from(pivot) / f64::from(largest),
            Err(_) => f64::NAN,
        };
        mechanism::expand(self.solver.q(), self.solver.qd(), self.solver.qdd(), t, &mut self.expanded);
        let c = &mut self.candidate;
        for (d, v) in [&mut c.q, &mut c.qd, &mut c.qdd].into_iter().enumerate() {
            v.clear();
            v.extend(self.expanded.iter().flat_map(|b| b[d]).map(f64::from));
        }
        Ok(Sample {
            t: f64::from(t),
            iterations: report.iterations,
            residual: f64::from(report.residual),
            pivot_ratio,
        })
    }

    fn accepted(&self) -> Coordinates<'_, f64> {
        Coordinates { q: &self.full.q, qd: &self.full.qd, qdd: &self.full.qdd }
    }

    fn candidate(&self) -> Coordinates<'_, f64> {
        Coordinates { q: &self.candidate.q, qd: &self.candidate.qd, qdd: &self.candidate.qdd }
    }

    fn groups(&self) -> Groups<'_> {
        Groups::Bodies
    }

    fn accept(&mut self) {
        self.accepted = Some((self.solver.t(), *self.solver.q()));
        self.full.clone_from(&self.candidate);
    }

    fn reject(&mut self) {
        if let Some((t, q)) = self.accepted {
            // Back to the accepted point: Newton converges at once from it.
            self.solver.set_q(q);
            let _ = self.solver.position(t);
            let _ = self.solver.velocity().and_then(|()| self.solver.acceleration());
        }
    }

    fn epsilon(&self) -> f64 {
        f64::from(Real::EPSILON)
    }
}
"#;

/// Why the generated engine could not run.
#[derive(Debug)]
pub enum EngineError {
    /// The description cannot be generated (e.g. an undriven degree of freedom).
    Generate(String),
    /// The environment names no usable cache directory (e.g. `MECHGEN_CACHE` set but empty).
    Config(String),
    /// The generated crate could not be built.
    Build(BuildFailure),
    /// Running it failed or printed something unexpected.
    Run(String),
    /// The sink could not write a frame (e.g. standard output was closed): the solver was
    /// stopped and the sink's error is handed back as it came.
    Output(std::io::Error),
}

/// Why a generated solver could not be built, and what to do about it.
#[derive(Clone, Debug)]
pub struct BuildFailure {
    /// What failed, with cargo's own words where cargo failed.
    pub reason: String,
    /// What the user can do.
    pub fix: String,
}

impl std::fmt::Display for EngineError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Generate(m) => write!(f, "cannot generate: {m}"),
            Self::Config(m) => f.write_str(m),
            Self::Build(b) => {
                write!(f, "the generated solver could not be built: {}\nfix: {}", b.reason, b.fix)
            }
            Self::Run(m) => write!(f, "cannot run the generated solver: {m}"),
            Self::Output(e) => write!(f, "cannot write the results: {e}"),
        }
    }
}

impl std::error::Error for EngineError {}

/// A generated solver, built and ready to run.
#[derive(Clone, Debug)]
pub struct Built {
    /// The program.
    pub binary: PathBuf,
    /// Size of the reduced system.
    pub unknowns: usize,
    /// The equations the generator left out as redundant (`joint O4 row 2`).
    pub removed: Vec<String>,
    /// What was found wrong in the cache and repaired on the way (a corrupt lock file, a
    /// binary that did not match its record), one sentence each.
    pub notes: Vec<String>,
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
    // Until the generated module takes its inputs at run time, it runs its own [time] grid
    // with laws only: input drivers and replayed time points are the generic engine's.
    let inputs = mech.input_drivers();
    if !inputs.is_empty() || mech.time.replay.is_some() {
        let reason = if inputs.is_empty() {
            "replayed time points (--inputs) are not supported by the generated engine yet"
                .to_owned()
        } else {
            format!(
                "{} (driver {})",
                crate::symbolic::INPUTS_NOT_SUPPORTED,
                inputs.join(", driver ")
            )
        };
        let fix = "use --engine generic (the default engine falls back to it)".to_owned();
        return Err(EngineError::Build(BuildFailure { reason, fix }));
    }
    let sys = Symbolic::build(mech).map_err(|e| EngineError::Generate(e.message))?;
    let module = emit::module_in(mech, &sys, &format!("the description \"{}\"", mech.name), scalar);
    let mut built = build_module(mech, &module, sys.unknowns.len(), scalar)?;
    built.removed = sys.redundant.iter().map(crate::generic::RowLabel::equation).collect();
    Ok(built)
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
    unknowns: usize,
    scalar: Scalar,
) -> Result<Built, EngineError> {
    let driver =
        DRIVER.replace("__TYPE__", &emit::type_name(&mech.name)).replace("__REAL__", scalar.name());
    let recipe = cache::Recipe::new(cache_dir()?, module, &driver, scalar.name());
    let mut notes = Vec::new();
    recipe.ensure(&mut notes)?;
    Ok(Built { binary: recipe.binary(), unknowns, removed: Vec::new(), notes })
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
    let child = cmd
        .stdout(Stdio::piped())
        .stdin(Stdio::null())
        .spawn()
        .map_err(|e| EngineError::Run(format!("{}: {e}", built.binary.display())))?;
    // Every return below, early or not, ends the solver.
    let mut child = SolverProcess(child);
    let stdout = child.0.stdout.take().expect("piped");
    let mut report = RunReport { steps: 0, failure: None };
    let mut near: Option<Point> = None;
    for line in BufReader::new(stdout).lines() {
        let line = line.map_err(|e| EngineError::Run(e.to_string()))?;
        let mut words = line.split(' ');
        match words.next() {
            Some("step") => {
                let nums: Vec<&str> = words.collect();
                let bad = || EngineError::Run(format!("malformed line: {line}"));
                let parse = |s: &str| s.parse::<f64>().map_err(|_| bad());
                if nums.len() < 3 || !(nums.len() - 3).is_multiple_of(21) {
                    return Err(bad());
                }
                let m = (nums.len() - 3) / 3;
                let values: Vec<f64> =
                    nums[3..].iter().map(|s| parse(s)).collect::<Result<_, _>>()?;
                if let Some(bad) = values.iter().chain(&[parse(nums[2])?]).find(|v| !v.is_finite())
                {
                    // Never written: the analysis stops here, saying why.
                    let message = format!(
                        "the generated solver produced the non-finite value {bad} (the steps \
                         before this one are kept)"
                    );
                    let t = parse(nums[0]).unwrap_or(f64::NAN);
                    report.failure = Some(Failure {
                        kind: FailureKind::NoConvergence,
                        t,
                        message,
                        constraints: Vec::new(),
                    });
                    return Ok(report);
                }
                let frame = Frame {
                    index: report.steps,
                    t: parse(nums[0])?,
                    iterations: nums[1].parse().map_err(|_| bad())?,
                    residual: parse(nums[2])?,
                    q: DVector::from_column_slice(&values[..m]),
                    qd: DVector::from_column_slice(&values[m..2 * m]),
                    qdd: DVector::from_column_slice(&values[2 * m..]),
                };
                sink(&frame).map_err(EngineError::Output)?;
                report.steps += 1;
            }
            Some("near") => {
                let bad = || EngineError::Run(format!("malformed line: {line}"));
                let nums: Vec<f64> =
                    words.map(|s| s.parse::<f64>().map_err(|_| bad())).collect::<Result<_, _>>()?;
                let (&t, q) = nums.split_first().ok_or_else(bad)?;
                near = Some(Point {
                    t,
                    q: q.to_vec(),
                    qd: Vec::new(),
                    qdd: Vec::new(),
                    iterations: 0,
                    residual: f64::NAN,
                    pivot_ratio: f64::NAN,
                });
            }
            Some("error") => {
                let trouble = match words.next() {
                    Some("singular") => Trouble::Singular,
                    Some("branch_jump") => Trouble::BranchJump,
                    Some("inconsistent") => Trouble::Inconsistent,
                    _ => Trouble::NoConvergence,
                };
                let t = words.next().and_then(|s| s.parse().ok()).unwrap_or(f64::NAN);
                let body = words.next().and_then(|s| s.parse().ok());
                let message = words.collect::<Vec<_>>().join(" ");
                let stop = Stop { trouble, t, message, near: near.take().map(Box::new), body };
                report.failure = Some(analysis.failure_of(&stop));
            }
            _ => return Err(EngineError::Run(format!("unexpected output: {line}"))),
        }
    }
    let status = child.0.wait().map_err(|e| EngineError::Run(e.to_string()))?;
    if !status.success() && report.failure.is_none() {
        return Err(EngineError::Run(format!("the solver exited with {status}")));
    }
    Ok(report)
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
    let child = Command::new(&built.binary)
        .args(["bench", &format!("{tolerance:?}"), &repeats.to_string()])
        .args(settings.flags())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .map_err(|e| EngineError::Run(format!("{}: {e}", built.binary.display())))?;
    let mut child = SolverProcess(child);
    let mut output = Vec::new();
    child
        .0
        .stdout
        .take()
        .expect("piped")
        .read_to_end(&mut output)
        .map_err(|e| EngineError::Run(e.to_string()))?;
    drop(child);
    let text = String::from_utf8_lossy(&output);
    let words: Vec<&str> = text.split_whitespace().collect();
    match words.as_slice() {
        ["bench", min, median, iters] => {
            let p = |s: &str| s.parse::<f64>().map_err(|_| EngineError::Run(text.to_string()));
            Ok((p(min)?, p(median)?, p(iters)?))
        }
        _ => Err(EngineError::Run(format!("unexpected benchmark output: {text}"))),
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    #[test]
    fn a_non_finite_value_from_a_solver_stops_the_run_instead_of_being_written() {
        use std::os::unix::fs::PermissionsExt;
        // A stand-in solver: one good step of one body, then a step whose q̇ holds NaN.
        let good = format!("step 0.0 1 1e-12{}", " 0.5".repeat(21));
        let bad = format!("step 0.1 1 1e-12{} NaN{}", " 0.5".repeat(8), " 0.5".repeat(12));
        let script = format!("#!/bin/sh\necho '{good}'\necho '{bad}'\necho '{good}'\n");
        let path = std::env::temp_dir().join(format!("mechgen-fake-solver-{}", std::process::id()));
        std::fs::write(&path, script).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
        let built =
            Built { binary: path.clone(), unknowns: 7, removed: Vec::new(), notes: Vec::new() };
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
        let step = format!("step 0.0 1 1e-12{}", " 0.5".repeat(21));
        let script = format!(
            "#!/bin/sh\necho $$ > '{}'\nwhile :; do echo '{step}'; done\n",
            pid_file.display()
        );
        let path = dir.join("solver");
        std::fs::write(&path, script).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
        let built = Built { binary: path, unknowns: 7, removed: Vec::new(), notes: Vec::new() };
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
