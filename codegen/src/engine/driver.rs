//! Runs one generated mechanism over its time grid: the driver of every generated solver
//! mechgen builds (`codegen::engine`).
//!
//! Usage: `run|bench [tolerance] [repeats] [no-predictor] [dense] [series]`, or `key` to print
//! the key of the cache entry it was built for. With `series`, the time points and the inputs
//! come from standard input instead of the module's grid: one line per time point,
//! `t s0 ṡ0 s̈0 s1 …` (the `[s, ṡ, s̈]` of every input driver, in the module's input order).
//!
//! It is the same text for every mechanism. What varies is read from its sibling modules,
//! which the generated crate's `main.rs` declares: `mechanism` (the generated module, its
//! constants under fixed names), `config` (`Real`, the module's floating-point type,
//! `Generated`, its mechanism, `INPUTS`, the number of its input drivers, and the functions
//! that make the mechanism at given inputs, aim its inputs and expand its coordinates) and
//! `key` (the cache entry's `KEY`). The workspace
//! compiles it against the committed `generated::rssr` (`generated/examples/driver.rs`), so
//! that rustc, clippy and rustfmt check it.

use std::io::Write;

use runtime::factors::DenseOnly;
use runtime::step::{self, Coordinates, Groups, Reason, Rejection, Sample, Stepper, Trouble};
use runtime::{AttemptError, Mechanism, NewtonError, NewtonOptions, Solver};

use super::config::{self, Real};
use super::{key, mechanism};

const N: usize = mechanism::N;

/// Runs the mode the first argument names.
pub(crate) fn main() {
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
    let series = if flag("series") { read_series() } else { Series::grid() };
    let (t0, u0) = series.sample(0);
    let m = config::generated(t0, &u0);
    if flag("dense") {
        // Static pivot orders hidden: every factorisation is dense LU with partial pivoting.
        drive(DenseOnly(m), &series, mode, tolerance, repeats, predictor);
    } else {
        drive(m, &series, mode, tolerance, repeats, predictor);
    }
}

/// The inputs of every input driver at one time point.
type Inputs = [[Real; 3]; config::INPUTS];

/// The time points of a run, and the inputs at each: the module's own grid (computed, so that
/// a long grid costs no memory), or a recorded series.
struct Series {
    recorded: Option<(Vec<Real>, Vec<Inputs>)>,
}

impl Series {
    /// The module's own grid.
    const fn grid() -> Series {
        Series { recorded: None }
    }

    fn len(&self) -> usize {
        self.recorded.as_ref().map_or(mechanism::T_COUNT, |(t, _)| t.len())
    }

    /// Time point `k`.
    fn time(&self, k: usize) -> Real {
        match &self.recorded {
            Some((t, _)) => t[k],
            None => mechanism::T_START + k as Real * mechanism::T_STEP,
        }
    }

    /// Time point `k` and the inputs there.
    fn sample(&self, k: usize) -> (Real, Inputs) {
        match &self.recorded {
            Some((t, u)) => (t[k], u[k]),
            None => (self.time(k), [[0.0; 3]; config::INPUTS]),
        }
    }

    /// Aims `m`'s inputs from time point `k − 1` (or `k` itself for the first) to `k`.
    fn aim<M: Generated>(&self, m: &mut M, k: usize) {
        let (t1, u1) = self.sample(k);
        let (t0, u0) = self.sample(k.saturating_sub(1));
        config::aim(m.module_mut(), t0, &u0, t1, &u1);
    }
}

/// Reads the time points and inputs from standard input (see the module docs); a line that
/// does not hold 1 + 3 · INPUTS numbers ends the process with status 3, as mechgen wrote it.
fn read_series() -> Series {
    use std::io::BufRead;
    let (mut times, mut inputs) = (Vec::new(), Vec::new());
    for line in std::io::stdin().lock().lines() {
        let Ok(line) = line else { std::process::exit(3) };
        let values: Vec<Real> = line.split(' ').filter_map(|w| w.parse().ok()).collect();
        if values.len() != 1 + 3 * config::INPUTS {
            eprintln!("a line of the series has {} numbers", values.len());
            std::process::exit(3);
        }
        let mut u = [[0.0; 3]; config::INPUTS];
        for (k, x) in u.iter_mut().enumerate() {
            x.copy_from_slice(&values[1 + 3 * k..4 + 3 * k]);
        }
        times.push(values[0]);
        inputs.push(u);
    }
    if times.is_empty() {
        std::process::exit(3);
    }
    Series { recorded: Some((times, inputs)) }
}

/// The generated mechanism, plain or behind [`DenseOnly`]: the driver reaches the module's
/// own functions (`config::aim`, `config::expand`, `config::dropped`) through it.
trait Generated: Mechanism<N, Real> {
    /// The module's mechanism.
    fn module(&self) -> &config::Generated;
    /// The module's mechanism, to aim its inputs.
    fn module_mut(&mut self) -> &mut config::Generated;
}

impl Generated for config::Generated {
    fn module(&self) -> &config::Generated {
        self
    }
    fn module_mut(&mut self) -> &mut config::Generated {
        self
    }
}

impl Generated for DenseOnly<config::Generated> {
    fn module(&self) -> &config::Generated {
        &self.0
    }
    fn module_mut(&mut self) -> &mut config::Generated {
        &mut self.0
    }
}

/// The solver of `m` with the module's settings, in `mode` (`bench` or `run`) over `series`.
fn drive<M: Generated>(
    m: M,
    series: &Series,
    mode: &str,
    tolerance: Real,
    repeats: usize,
    predictor: bool,
) {
    let options = NewtonOptions {
        tolerance,
        max_iterations: mechanism::MAX_ITERATIONS,
        ..NewtonOptions::DEFAULT
    };
    let mut solver = Solver::with_storage(m, mechanism::Q0, jacobian());
    solver.set_options(options);
    solver.set_predictor(predictor);
    let stdout = std::io::stdout();
    // 64 KiB, a whole pipe buffer, a write: an eighth of the system calls and of the reader's
    // wake-ups of the default 8 KiB (a step record of the R-S-S-R is 537 bytes).
    let mut out = std::io::BufWriter::with_capacity(1 << 16, stdout.lock());
    if mode == "bench" {
        bench(solver, series, repeats, &mut out);
    } else {
        run(solver, series, &mut out);
    }
}

/// Times `repeats` whole passes of plain stepping (no step control), each step the position,
/// velocity and acceleration solves and the module's `expand` (the full coordinates of every
/// body, with those the module substituted or fixed: the state a step hands its caller), and
/// prints `bench min_ns median_ns iterations_per_step`, or `error bench t kind message` and exit
/// status 2 when a step fails (`kind` is the contract's `error.kind`).
fn bench<M: Generated>(
    mut solver: Solver<M, N, Real, Jacobian>,
    series: &Series,
    repeats: usize,
    out: &mut impl Write,
) {
    let mut times = Vec::with_capacity(repeats);
    let mut iterations = 0u64;
    let mut expanded = Box::new([[[0.0; 7]; 3]; mechanism::BODIES]);
    let count = series.len();
    for _ in 0..repeats.max(1) {
        solver.set_q(mechanism::Q0);
        iterations = 0;
        let start = std::time::Instant::now();
        for k in 0..count {
            series.aim(solver.mechanism_mut(), k);
            let t = series.time(k);
            let stop = |kind: Trouble, message: String, out: &mut dyn Write| -> ! {
                let message = message.replace('\n', " ");
                check(writeln!(out, "error bench {:?} {} {message}", wide(t), kind.as_str()));
                // `exit` runs no destructor: the buffered line must leave now.
                check(out.flush());
                std::process::exit(2);
            };
            match solver.position(t) {
                Ok(r) => iterations += u64::from(r.iterations),
                Err(e) => {
                    let kind = match e {
                        NewtonError::Singular { .. } => Trouble::Singular,
                        _ => Trouble::NoConvergence,
                    };
                    stop(kind, e.to_string(), out);
                }
            }
            // A non-finite rate or acceleration is reported as the step control reports it
            // (`Engine::attempt`), not timed on.
            if let Err(e) = solver.velocity().and_then(|()| solver.acceleration()) {
                stop(Trouble::Singular, e.to_string(), out);
            }
            expand(&solver, t, &mut expanded);
            std::hint::black_box(&mut *expanded);
        }
        times.push(start.elapsed().as_nanos() as f64 / count as f64);
        std::hint::black_box(solver.qdd());
    }
    times.sort_by(f64::total_cmp);
    check(writeln!(
        out,
        "bench {:?} {:?} {:?}",
        times[0],
        times[times.len() / 2],
        iterations as f64 / count as f64
    ));
}

/// The module's `expand` of the solver's q, q̇ and q̈ at `t` into `out`, reading the time
/// terms the solver computed at t where the module can (`Mechanism::expand_at`, the same values
/// bit for bit), else computing them again (`config::expand`).
fn expand<M: Generated>(
    solver: &Solver<M, N, Real, Jacobian>,
    t: Real,
    out: &mut [[[Real; 7]; 3]; mechanism::BODIES],
) {
    let (q, qd, qdd) = (solver.q(), solver.qd(), solver.qdd());
    let terms = solver.time_terms(t).unwrap_or_default();
    if !solver.mechanism().expand_at(q, qd, qdd, t, terms, out) {
        config::expand(solver.mechanism().module(), q, qd, qdd, t, out);
    }
}

/// Steps over the grid under the step control, writing a step record per time point, or
/// `near` and `error` lines and exit status 2 when the analysis stops.
fn run<M: Generated>(solver: Solver<M, N, Real, Jacobian>, series: &Series, out: &mut impl Write) {
    let mut engine = Engine {
        solver,
        expanded: Box::new([[[0.0; 7]; 3]; mechanism::BODIES]),
        accepted: None,
        full: Full::default(),
        candidate: Full::default(),
    };
    let mut last: Option<Sample<f64>> = None;
    let mut record = Vec::new();
    for k in 0..series.len() {
        series.aim(engine.solver.mechanism_mut(), k);
        let t = wide(series.time(k));
        let outcome = match last {
            None => step::first(&mut engine, t).map(|p| (p, p.iterations)),
            Some(a) => step::advance(&mut engine, a, t),
        };
        match outcome {
            Ok((p, iterations)) => {
                // κ̂ of Φ_q at the step, for the digits rule (runtime::step::suspect).
                let condition = wide(engine.solver.condition());
                step_record(&mut record, t, iterations, p.residual, condition, &engine.full);
                check(out.write_all(&record));
                last = Some(p);
            }
            Err(stop) => {
                if let Some(near) = &stop.near {
                    check(write!(out, "near {:?}", near.sample.t));
                    let at = if near.rejected { &engine.candidate } else { &engine.full };
                    for v in [&at.q, &at.qd, &at.qdd] {
                        numbers(out, v);
                    }
                    check(writeln!(out));
                }
                let body = stop.body.map_or_else(|| "-".to_owned(), |b| b.to_string());
                let message = stop.to_string().replace('\n', " ");
                let kind = stop.trouble.as_str();
                check(writeln!(out, "error {kind} {:?} {body} {message}", stop.t));
                check(out.flush());
                std::process::exit(2);
            }
        }
    }
}

/// The binary record of one step (`codegen::engine` reads it back): the byte 0, the number m
/// of coordinates and the Newton iterations as little-endian u32, then t, the residual and
/// the condition estimate, then m values each of q, q̇ and q̈, as little-endian f64. Raw
/// bits need neither formatting nor parsing and carry every value exactly.
fn step_record(
    record: &mut Vec<u8>,
    t: f64,
    iterations: u32,
    residual: f64,
    condition: f64,
    full: &Full,
) {
    record.clear();
    record.push(0);
    let m = u32::try_from(full.q.len()).unwrap_or(u32::MAX);
    record.extend_from_slice(&m.to_le_bytes());
    record.extend_from_slice(&iterations.to_le_bytes());
    let values = [t, residual, condition].into_iter().chain(full.q.iter().copied());
    let values = values.chain(full.qd.iter().copied()).chain(full.qdd.iter().copied());
    for x in values {
        record.extend_from_slice(&x.to_le_bytes());
    }
}

/// Writes each of `values` after a space, in shortest round-trip form.
fn numbers(out: &mut impl Write, values: &[f64]) {
    for x in values {
        check(write!(out, " {x:?}"));
    }
}

/// A value of the module's floating-point type in double precision, as the step control and
/// the output take it.
// `Real` is `f64` or `f32` as the module was generated: the conversion is needed for `f32`
// and useless only in the `f64` instance.
#[allow(clippy::useless_conversion)]
fn wide(x: Real) -> f64 {
    f64::from(x)
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
    expanded: Box<[[[Real; 7]; 3]; mechanism::BODIES]>,
    /// The last accepted (t, reduced q).
    accepted: Option<(Real, [Real; N])>,
    /// The last accepted point and the last attempt, in full coordinates.
    full: Full,
    candidate: Full,
}

impl<M: Generated> Stepper<f64> for Engine<M> {
    type Cause = Cause;

    fn attempt(&mut self, t: f64) -> Result<Sample<f64>, Rejection<f64, Cause>> {
        let t = t as Real;
        let report = self.solver.position(t).map_err(|e| {
            let trouble = match e {
                NewtonError::Singular { .. } => Trouble::Singular,
                _ => Trouble::NoConvergence,
            };
            Rejection::engine(trouble, Cause::Attempt(AttemptError::Newton(e)))
        })?;
        if let Err(e) = self.solver.velocity().and_then(|()| self.solver.acceleration()) {
            return Err(Rejection::engine(
                Trouble::Singular,
                Cause::Attempt(AttemptError::Solve(e)),
            ));
        }
        // The pivots of the factorisation the solve kept, dense only near the singularity bound.
        let pivot_ratio = wide(self.solver.pivot_ratio());
        expand(&self.solver, t, &mut self.expanded);
        let c = &mut self.candidate;
        for (d, v) in [&mut c.q, &mut c.qd, &mut c.qdd].into_iter().enumerate() {
            v.clear();
            v.extend(self.expanded.iter().flat_map(|b| b[d]).map(wide));
        }
        let sample = Sample {
            t: wide(t),
            iterations: report.iterations,
            residual: wide(report.residual),
            pivot_ratio,
        };
        if let Some(message) = inconsistency(&self.solver, t) {
            return Err(Rejection {
                trouble: Trouble::Inconsistent,
                reason: Reason::Engine(Cause::Inconsistent(message)),
                converged: Some(sample),
                body: None,
            });
        }
        Ok(sample)
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
        wide(Real::EPSILON)
    }
}

/// Why an attempt was rejected: the solver's own failure, or a row the module left out as
/// redundant that does not hold ([`inconsistency`]).
#[derive(Debug)]
enum Cause {
    Attempt(AttemptError<Real>),
    Inconsistent(String),
}

impl std::fmt::Display for Cause {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Cause::Attempt(e) => e.fmt(f),
            Cause::Inconsistent(message) => f.write_str(message),
        }
    }
}

/// The velocity and acceleration equations of every row must hold to this fraction of the
/// step's scale, as in the generic engine (`codegen::generic::solve`'s `CONSISTENCY`, whose
/// docs give the reasoning): |Φ_q,i x − b_i| ≤ CONSISTENCY · max_k (Σ_j |Φ_q,kj x_j| + |b_k|),
/// rows in balanced units, for x = q̇, b = ν and x = q̈, b = γ. In single precision the
/// solves themselves err by κ·ε, so the allowance is at least [`CONDITION`] · ε of `Real`.
const CONSISTENCY: f64 = 1e-6;

/// The condition of Φ_q (balanced units) up to which consistent rows must pass the check: the
/// generic engine's reasoning for [`CONSISTENCY`], 1e4.
const CONDITION: f64 = 1e4;

/// Why the solved point of `solver` at `t` is refused, when a row of the description does not
/// hold with the others: |Φ_i| above the Newton tolerance (as the generic engine requires of
/// every row), or its velocity or acceleration equation missing by more than [`CONSISTENCY`]
/// of the scale, which is taken over the kept rows (the left-out ones are combinations of
/// them). Every row is checked, the kept ones too: where the solver re-selected its rows
/// (`runtime::rows`), some kept rows are not among those it solved with. `None` when every row
/// holds, or the module left none out.
fn inconsistency<M: Generated>(solver: &Solver<M, N, Real, Jacobian>, t: Real) -> Option<String> {
    if config::DROPPED == 0 {
        return None;
    }
    let m = solver.mechanism();
    let (q, qd, qdd) = (solver.q(), solver.qd(), solver.qdd());
    let mut residuals = [[0.0; 3]; config::DROPPED];
    config::dropped(m.module(), q, qd, qdd, t, &mut residuals);
    let mut phi = [0.0; N];
    m.residual(q, t, &mut phi);
    let tolerance = wide(solver.options().tolerance);
    let positions = phi.iter().zip(mechanism::EQUATIONS);
    let positions = positions.chain(residuals.iter().map(|r| &r[0]).zip(config::DROPPED_EQUATIONS));
    for (&r, equation) in positions {
        let phi = wide(r).abs();
        // NaN misses too.
        if phi.is_nan() || phi > tolerance {
            return Some(format!(
                "equation {equation} cannot hold with the others: |Φ| = {phi:e} where the \
                 equations the solve uses meet the tolerance {tolerance:e}"
            ));
        }
    }
    let floor = CONSISTENCY.max(CONDITION * wide(Real::EPSILON));
    // Where the rows solved with are ill-conditioned (κ̂ from their factors' pivots), consistent
    // rows miss by the round-off the digits rule ascribes to the quantity, κ̂²ε for velocities
    // and κ̂³ε for accelerations (README "Digits"): the allowance is at least that, so round-off
    // is not taken for a conflict. A step where it exceeds 1e-6 is flagged suspect anyway, and
    // a real conflict misses by far more (5e-2 for 1 against 1.1 rad/s).
    let kappa = solver.pivots().map_or(1.0, |p| wide(p.largest) / wide(p.smallest));
    let mut jac = jacobian();
    m.jacobian(q, t, &mut jac);
    let (mut nu, mut gamma) = ([0.0; N], [0.0; N]);
    m.velocity_rhs(q, t, &mut nu);
    m.acceleration_rhs(q, qd, t, &mut gamma);
    for (level, (what, x, b)) in
        [("velocity", qd, &nu), ("acceleration", qdd, &gamma)].into_iter().enumerate()
    {
        let allowed = floor.max(kappa.powi(level as i32 + 2) * wide(Real::EPSILON));
        let scale = (0..N).fold(0.0_f64, |s, i| {
            let terms = (0..N).fold(wide(b[i]).abs(), |a, j| a + wide(jac[i][j] * x[j]).abs());
            s.max(wide(config::ROW_FACTORS[i]) * terms)
        });
        // The kept rows evaluated here, then the left-out ones from `dropped_residuals`.
        let kept = (0..N).map(|i| {
            let rate = (0..N).fold(-wide(b[i]), |a, j| a + wide(jac[i][j] * x[j]));
            (wide(config::ROW_FACTORS[i]) * rate.abs(), mechanism::EQUATIONS[i])
        });
        let left_out = residuals.iter().enumerate().map(|(k, r)| {
            let miss = wide(config::DROPPED_ROW_FACTORS[k]) * wide(r[level + 1]).abs();
            (miss, config::DROPPED_EQUATIONS[k])
        });
        for (miss, equation) in kept.chain(left_out) {
            let ratio = if scale > 0.0 { miss / scale } else { miss };
            if ratio.is_nan() || ratio > allowed {
                return Some(format!(
                    "the {what} equation of {equation} cannot hold with the others: it misses \
                     by {ratio:.3e} of the {what} terms' scale (at most {allowed:e})"
                ));
            }
        }
    }
    None
}
