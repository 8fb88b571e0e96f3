//! The analysis over the time grid: Newton–Raphson with LU and partial pivoting for the
//! positions, then Φ_q q̇ = ν and Φ_q q̈ = γ with the same factorisation (thesis ch. 5.2), and
//! the rank analysis that `check` reports.
//!
//! Redundant equations are solved with the others at every step: when Φ_q has more rows than
//! columns, its LU with row pivoting over all the rows picks, at each configuration, the rows
//! that the triangular solves use, so the factorisation degenerates only when the whole Φ_q
//! loses column rank (the Bennett linkage at θ1 = 0, where any set of rows chosen once at the
//! start becomes singular, is regular here). The rows the pivoting leaves aside are checked:
//! a step is accepted only when every row meets the tolerance and the velocity and
//! acceleration equations of every row hold ([`CONSISTENCY`]); otherwise it is rejected as
//! `inconsistent`.

use std::sync::Arc;

use nalgebra::{DMatrix, DVector, SVD, Vector4};

use super::scaling::balanced;
use super::sparse::{Pattern, SPARSE_FROM_UNKNOWNS, SparseLu};
use super::{Equations, angle_alignment};
use crate::model::{DriverTarget, JointKind, Motion, RowLabel};
use crate::stepping::{self, Engine, Point, Rejection, Stop, Trouble};

/// A pivot smaller than this fraction of the largest pivot of the LU factorisation marks
/// Φ_q as singular: with partial pivoting the pivots bound the conditioning from below, and
/// 1e-12 leaves four orders of magnitude above f64 round-off before a step is refused. Φ_q is
/// factored in balanced units ([`super::scaling`]), so the ratio does not depend on the unit of
/// length.
const SINGULAR_PIVOT_RATIO: f64 = 1e-12;

/// Singular values below this fraction of the largest count as zero in rank decisions: an
/// exact dependency shows up at round-off level (≈1e-16 relative), a genuine but poorly
/// conditioned configuration far above it. Every rank decision looks at Φ_q in balanced units
/// ([`super::scaling`]), so that this holds whatever the unit of length.
pub(super) const RANK_TOLERANCE: f64 = 1e-10;

/// The velocity and acceleration equations of every row must hold to this fraction of the
/// step's scale: |Φ_q,i x − b_i| ≤ CONSISTENCY · max_k (Σ_j |Φ_q,kj x_j| + |b_k|), every row
/// in balanced units, for x = q̇, b = ν and x = q̈, b = γ. The rows of a consistent redundant
/// system agree exactly only on the constraint manifold; at a configuration that meets Φ to
/// the tolerance τ (1e-10) the dependency between them is off by about κ·τ/ℓ (κ the
/// condition of Φ_q in balanced units, ℓ the characteristic length), and the solve adds about
/// κ·ε: below 1e-6 for the condition numbers (up to 1e4) of the configurations a step is
/// accepted at in practice. Two drivers that contradict each other differ by their own
/// scale (1 rad/s against 1.1 rad/s: 5e-2), far above it.
const CONSISTENCY: f64 = 1e-6;

/// Newton iterations allowed in a row while the rows the factorisation uses meet the tolerance
/// and others do not: in a consistent system the others follow within one iteration (they depend
/// on the used rows, to first order); an inconsistent one stays where it is.
const STALLED_ITERATIONS: u32 = 2;

/// One analysed time point.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Index of the time point in the grid.
    pub index: usize,
    /// Time.
    pub t: f64,
    /// Newton iterations taken.
    pub iterations: u32,
    /// max |Φ_i| at the reported q.
    pub residual: f64,
    /// κ̂, the estimate of the condition number of Φ_q at q that the digits rule reads
    /// ([`runtime::step::suspect`]): 1/ρ of the engine's LU in balanced units (generic), or
    /// `runtime::Solver::condition` (generated).
    pub condition: f64,
    /// Positions.
    pub q: DVector<f64>,
    /// Velocities.
    pub qd: DVector<f64>,
    /// Accelerations.
    pub qdd: DVector<f64>,
    /// The rows named redundant here ([`super::redundancy`]), when they differ from those of
    /// the previous frame (for the first frame: from those named at the initial
    /// configuration, [`Preparation::redundant`]); `None` when they are the same.
    pub redundant: Option<Vec<usize>>,
}

/// Why the analysis stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FailureKind {
    /// Newton did not reach the tolerance within `max_iterations`.
    NoConvergence,
    /// Φ_q is singular to working precision.
    Singular,
    /// A driven angle converged on the wrong branch.
    BranchJump,
    /// Equations that cannot hold together: two drivers that contradict each other, a
    /// constraint that conflicts with a driver.
    Inconsistent,
}

impl FailureKind {
    /// The contract's `error.kind`.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Self::NoConvergence => "no_convergence",
            Self::Singular => "singular",
            Self::BranchJump => "branch_jump",
            Self::Inconsistent => "inconsistent",
        }
    }
}

/// A numerical failure, with the time and the equations involved.
#[derive(Clone, Debug, PartialEq)]
pub struct Failure {
    /// What happened.
    pub kind: FailureKind,
    /// The time point at which it happened.
    pub t: f64,
    /// A sentence for the user.
    pub message: String,
    /// The entities involved, e.g. `joint O4`.
    pub constraints: Vec<String>,
}

/// What `check` reports, computed at the initial configuration.
#[derive(Clone, Debug)]
pub struct Preparation {
    /// Whether the initial estimates could be assembled at the first time point (the rank
    /// analysis then uses the assembled configuration, else the estimates).
    pub assembled: bool,
    /// The configuration used.
    pub q: DVector<f64>,
    /// Numeric rank of Φ_q.
    pub rank: usize,
    /// Unknowns minus the rank of Φ_q without the driver rows.
    pub mobility: usize,
    /// Rows named redundant at the configuration used ([`super::redundancy`]), in row order.
    pub redundant: Vec<usize>,
    /// Bodies that can still move when Φ_q has lower column rank than the unknowns.
    pub free_bodies: Vec<String>,
}

/// The outcome of [`Analysis::run`].
#[derive(Clone, Debug)]
pub struct StepReport {
    /// Time points analysed successfully.
    pub steps: usize,
    /// Total Newton iterations.
    pub iterations: u64,
    /// Why the analysis stopped early, if it did.
    pub failure: Option<Failure>,
}

impl Equations<'_> {
    /// Assembles the mechanism at the first time point (Gauss–Newton with the SVD, which
    /// also handles redundant equations), then finds the rank of Φ_q, the mobility, the
    /// redundant rows and, for a rank-deficient Φ_q, the bodies that can still move.
    ///
    /// A square Φ_q of at least [`SPARSE_FROM_UNKNOWNS`] unknowns is first assembled by Newton
    /// with the sparse LU instead ([`Equations::prepare_sparse`]); only when that LU is not
    /// clearly regular do the dense SVDs decide.
    #[must_use]
    pub fn prepare(&self) -> Preparation {
        if self.unknowns() >= SPARSE_FROM_UNKNOWNS
            && let Some(prep) = self.prepare_sparse()
        {
            return prep;
        }
        self.prepare_dense()
    }

    /// [`Equations::prepare`] with the dense SVDs, whatever the size.
    #[must_use]
    pub fn prepare_dense(&self) -> Preparation {
        let mech = self.mechanism();
        let n = self.unknowns();
        let t0 = mech.time.start;
        let zero = DVector::zeros(n);
        let mut q = self.initial_estimate();
        let mut assembled = false;
        let iterations = mech.solver.max_iterations.max(50);
        let columns = self.column_scales();
        for _ in 0..iterations {
            let sys = self.evaluate(&q, &zero, t0);
            if !all_finite(&sys.phi) || !all_finite(&sys.jac) {
                break;
            }
            if max_abs(&sys.phi) <= mech.solver.tolerance {
                assembled = true;
                break;
            }
            // The least-squares step in balanced units: (R Φ_q C) y = R Φ, Δq = C y.
            let (jac, rows) = balanced(sys.jac, &columns);
            let svd = SVD::new(jac, true, true);
            let eps = RANK_TOLERANCE * svd.singular_values.max();
            match svd.solve(&sys.phi.component_mul(&rows), eps) {
                Ok(y) => q -= y.component_mul(&columns),
                Err(_) => break,
            }
        }
        if !assembled || !all_finite(&q) {
            q = self.initial_estimate();
        }
        let (jac, _) = balanced(self.evaluate(&q, &zero, t0).jac, &columns);
        let svd = SVD::new(jac.clone(), false, true);
        let smax = svd.singular_values.max();
        let rank = svd.singular_values.iter().filter(|&&s| s > RANK_TOLERANCE * smax).count();
        let mut free_bodies = Vec::new();
        if rank < n {
            let v_t = svd.v_t.as_ref().expect("requested V");
            let mut moving = vec![false; mech.bodies.len()];
            for (k, s) in svd.singular_values.iter().enumerate() {
                if *s > RANK_TOLERANCE * smax {
                    continue;
                }
                mark_moving(self, &v_t.row(k).transpose(), &mut moving);
            }
            // With more unknowns than singular values (never after validation) every
            // direction outside the row space is free as well.
            for (b, m) in mech.bodies.iter().zip(&moving) {
                if *m {
                    free_bodies.push(b.name.clone());
                }
            }
        }
        let driver_rows: Vec<usize> = self
            .labels()
            .iter()
            .enumerate()
            .filter(|(_, l)| l.kind == RowLabel::DRIVER)
            .map(|(k, _)| k)
            .collect();
        let kept: Vec<usize> = (0..self.equations()).filter(|k| !driver_rows.contains(k)).collect();
        let rank_nd = numeric_rank(&jac.select_rows(kept.iter()));
        let redundant = self.redundant_rows(&q, t0);
        Preparation { assembled, q, rank, mobility: n - rank_nd.min(n), redundant, free_bodies }
    }
}

/// Marks the bodies with a noticeable share of the null vector `v` (in balanced units).
fn mark_moving(eq: &Equations<'_>, v: &DVector<f64>, moving: &mut [bool]) {
    for (b, flag) in moving.iter_mut().enumerate() {
        if let Some(o) = eq.offset(crate::model::BodyId(b)) {
            // A unit null vector spread over at most 7·bodies entries: 1e-6 separates a
            // body that takes part in the motion from round-off.
            if v.rows(o, 7).norm() > 1e-6 {
                *flag = true;
            }
        }
    }
}

/// The numeric rank of a matrix (see [`RANK_TOLERANCE`]), in the units it is given in.
fn numeric_rank(m: &DMatrix<f64>) -> usize {
    if m.nrows() == 0 {
        return 0;
    }
    let s = SVD::new(m.clone(), false, false).singular_values;
    let smax = s.max();
    s.iter().filter(|&&x| x > RANK_TOLERANCE * smax).count()
}

fn max_abs(v: &DVector<f64>) -> f64 {
    v.iter().fold(0.0_f64, |m, x| m.max(x.abs()))
}

fn all_finite<R: nalgebra::Dim, C: nalgebra::Dim, S: nalgebra::RawStorage<f64, R, C>>(
    m: &nalgebra::Matrix<f64, R, C, S>,
) -> bool {
    m.iter().all(|x| x.is_finite())
}

/// The kinematic analysis of one mechanism over its time grid.
#[derive(Clone, Debug)]
pub struct Analysis<'e, 'm> {
    eq: &'e Equations<'m>,
    /// Rows named redundant at the initial configuration ([`Preparation::redundant`]).
    redundant: Vec<usize>,
    /// Where Newton starts at the first time point.
    start: DVector<f64>,
    tolerance: f64,
    max_iterations: u32,
    /// Whether Newton starts from the Taylor predictor (else from the previous q).
    predictor: bool,
    /// The column factors of Φ_q in balanced units ([`Equations::column_scales`]).
    columns: DVector<f64>,
    /// The pattern and symbolic analysis of Φ_q when it is factored sparse
    /// ([`super::sparse`]), `None` for the dense LU.
    sparse: Option<Arc<Pattern>>,
}

impl<'e, 'm> Analysis<'e, 'm> {
    /// An analysis of the equations `eq`, starting from the configuration `prep` assembled when
    /// it found redundant equations (from the initial estimates otherwise, as the generated
    /// solver does).
    #[must_use]
    pub fn new(eq: &'e Equations<'m>, prep: &Preparation) -> Self {
        let mech = eq.mechanism();
        let redundant = !prep.redundant.is_empty();
        Self {
            eq,
            redundant: prep.redundant.clone(),
            start: if redundant && prep.assembled { prep.q.clone() } else { eq.initial_estimate() },
            tolerance: mech.solver.tolerance,
            max_iterations: mech.solver.max_iterations,
            predictor: true,
            columns: eq.column_scales(),
            sparse: (eq.unknowns() >= SPARSE_FROM_UNKNOWNS)
                .then(|| Pattern::new(eq).map(Arc::new))
                .flatten(),
        }
    }

    /// Chooses the factorisation of Φ_q: sparse (faer's LU, [`super::sparse`]) when `on` and
    /// Φ_q is square, dense otherwise. By default a square Φ_q of at least
    /// [`SPARSE_FROM_UNKNOWNS`] unknowns is factored sparse.
    #[must_use]
    pub fn with_sparse(mut self, on: bool) -> Self {
        self.sparse = if on { Pattern::new(self.eq).map(Arc::new) } else { None };
        self
    }

    /// Whether Φ_q is factored sparse.
    #[must_use]
    pub fn is_sparse(&self) -> bool {
        self.sparse.is_some()
    }

    /// Turns the Taylor predictor off (Newton then starts from the previous positions).
    #[must_use]
    pub fn with_predictor(mut self, on: bool) -> Self {
        self.predictor = on;
        self
    }

    /// Times `repeats` whole passes over the grid: (min, median) ns per time point and
    /// Newton iterations per time point.
    ///
    /// The passes step straight from one grid time to the next with the predictor, as the
    /// generated solver's benchmark does: the step control of [`Analysis::run`] (continuity
    /// check, subdivision) is not timed.
    ///
    /// # Errors
    /// The grid time of the first step that fails, with its kind and reason.
    pub fn time(&self, repeats: usize) -> Result<(f64, f64, f64), TimedStop> {
        let grid = &self.eq.mechanism().time;
        let mut times = Vec::with_capacity(repeats.max(1));
        let mut iterations = 0.0;
        for _ in 0..repeats.max(1) {
            let start = std::time::Instant::now();
            let mut prev: Option<Point> = None;
            let mut total = 0_u64;
            for k in 0..grid.count {
                let t = grid.at(k);
                let p = self.step(t, self.guess(prev.as_ref(), t)).map_err(|r| TimedStop {
                    t,
                    kind: r.trouble.as_str(),
                    message: r.message,
                })?;
                total += u64::from(p.iterations);
                std::hint::black_box(&p.qdd);
                prev = Some(p);
            }
            times.push(start.elapsed().as_nanos() as f64 / grid.count as f64);
            iterations = total as f64 / grid.count as f64;
        }
        times.sort_by(f64::total_cmp);
        Ok((times[0], times[times.len() / 2], iterations))
    }

    /// Overrides the Newton tolerance (benchmarks and accuracy charts).
    #[must_use]
    pub fn with_tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = tolerance;
        self
    }

    /// Runs over the whole grid, handing every frame to `sink` as soon as it is computed,
    /// so that output can be streamed. Each step is taken under the step control of
    /// [`crate::stepping`] (subdivision, continuity check); the analysis stops at the first
    /// step that cannot be taken.
    ///
    /// # Errors
    /// Returns the first error of `sink`.
    pub fn run<E>(&self, mut sink: impl FnMut(&Frame) -> Result<(), E>) -> Result<StepReport, E> {
        let grid = &self.eq.mechanism().time;
        let mut report = StepReport { steps: 0, iterations: 0, failure: None };
        let mut engine = GenericEngine { analysis: self, prev: None };
        let mut last: Option<Point> = None;
        let mut named = self.redundant.clone();
        for k in 0..grid.count {
            let t = grid.at(k);
            let outcome = match &last {
                None => stepping::first(&mut engine, t).map(|p| {
                    let n = p.iterations;
                    (p, n)
                }),
                Some(a) => stepping::advance(&mut engine, a, t),
            };
            match outcome {
                Ok((point, iterations)) => {
                    report.steps += 1;
                    report.iterations += u64::from(iterations);
                    let q = DVector::from_column_slice(&point.q);
                    let redundant = self.redundant_change(&mut named, &q, t);
                    let frame = Frame {
                        index: k,
                        t,
                        iterations,
                        residual: point.residual,
                        condition: 1.0 / point.pivot_ratio,
                        q,
                        qd: DVector::from_column_slice(&point.qd),
                        qdd: DVector::from_column_slice(&point.qdd),
                        redundant,
                    };
                    sink(&frame)?;
                    last = Some(point);
                }
                Err(stop) => {
                    report.failure = Some(self.failure_of(&stop));
                    break;
                }
            }
        }
        Ok(report)
    }

    /// The rows named redundant at the frame (q, t) ([`super::redundancy`]) when they differ
    /// from `named`, the set in force before it (which becomes theirs); `None` when they are
    /// the same. Both engines report a frame's `redundant` this way: `named` starts as the set
    /// of the initial configuration ([`Preparation::redundant`]).
    #[must_use]
    pub fn redundant_change(
        &self,
        named: &mut Vec<usize>,
        q: &DVector<f64>,
        t: f64,
    ) -> Option<Vec<usize>> {
        // Only a system with more rows than unknowns can have redundant rows at a regular
        // configuration.
        if self.eq.equations() <= self.eq.unknowns() {
            return None;
        }
        let now = self.eq.redundant_rows(q, t);
        if now == *named {
            return None;
        }
        named.clone_from(&now);
        Some(now)
    }

    /// The rows named redundant at the initial configuration ([`Preparation::redundant`]).
    #[must_use]
    pub fn initially_redundant(&self) -> &[usize] {
        &self.redundant
    }

    /// The failure of the first time point alone, if the analysis stops there: what `check`
    /// reports when the equations contradict each other at the initial configuration.
    #[must_use]
    pub fn first_failure(&self) -> Option<Failure> {
        let t = self.eq.mechanism().time.start;
        let mut engine = GenericEngine { analysis: self, prev: None };
        stepping::first(&mut engine, t).err().map(|stop| self.failure_of(&stop))
    }

    /// The number of unknowns (7 per moving body).
    #[must_use]
    pub fn unknowns(&self) -> usize {
        self.eq.unknowns()
    }

    /// The contract's failure for a step control [`Stop`], naming the equations involved
    /// (see [`Analysis::involved`]).
    #[must_use]
    pub fn failure_of(&self, stop: &Stop) -> Failure {
        let kind = match stop.trouble {
            Trouble::Singular => FailureKind::Singular,
            Trouble::NoConvergence => FailureKind::NoConvergence,
            Trouble::BranchJump => FailureKind::BranchJump,
            Trouble::Inconsistent => FailureKind::Inconsistent,
        };
        let constraints = match (kind, stop.near.as_deref()) {
            (FailureKind::Inconsistent, Some(p)) => self.conflicting(p),
            _ => {
                let near = stop.near.as_ref().map(|p| (DVector::from_column_slice(&p.q), p.t));
                self.involved(kind, near.as_ref().map(|(q, t)| (q, *t)), stop.t, stop.body)
            }
        };
        let mut message = stop.message.clone();
        if let Some(b) = stop.body {
            let name = self
                .eq
                .mechanism()
                .moving_bodies()
                .nth(b)
                .map(|id| &self.eq.mechanism().bodies[id.0].name);
            if let Some(name) = name {
                message.push_str(&format!(" (body {name})"));
            }
        }
        self.failure(kind, stop.t, message, constraints)
    }

    /// The equations involved in a failure, by entity:
    /// - singular: those with a share of at least 0.1 of the largest in the left singular
    ///   vector of the smallest singular value of Φ_q at the configuration `near` (the one
    ///   closest to the failure; the initial estimates when there is none), the combination of
    ///   rows that has become dependent;
    /// - branch jump: the joints, constraints and drivers acting on the moving body `body`
    ///   that jumped;
    /// - no convergence: the (at most four) equations with the largest |Φ_i| above the
    ///   tolerance at `near` and the failing time `t`;
    /// - inconsistent: the equations that do not hold at `near` and the failing time `t`
    ///   (the conflict itself is named from the whole point by [`Analysis::failure_of`]).
    #[must_use]
    pub fn involved(
        &self,
        kind: FailureKind,
        near: Option<(&DVector<f64>, f64)>,
        t: f64,
        body: Option<usize>,
    ) -> Vec<String> {
        let start = self.start.clone();
        let (q, t_near) = near.map_or((&start, t), |(q, tn)| (q, tn));
        let zero = DVector::zeros(q.len());
        match kind {
            FailureKind::Singular => {
                let jac = self.eq.evaluate(q, &zero, t_near).jac;
                if !all_finite(&jac) {
                    return Vec::new();
                }
                let (jac, _) = balanced(jac, &self.columns);
                let svd = SVD::new(jac, true, false);
                let u = svd.u.as_ref().expect("requested U");
                let (kmin, _) = svd.singular_values.iter().enumerate().fold(
                    (0, f64::INFINITY),
                    |(bk, bv), (k, &s)| if s < bv { (k, s) } else { (bk, bv) },
                );
                let col = u.column(kmin);
                let big = col.amax();
                // Shares below 0.1 of the largest are the rows that merely take part in the
                // configuration's scaling, not in the dependency.
                (0..col.len())
                    .filter(|&k| col[k].abs() >= 0.1 * big)
                    .map(|k| self.label(k))
                    .collect()
            }
            FailureKind::BranchJump => {
                let mech = self.eq.mechanism();
                let Some(id) = body.and_then(|b| mech.moving_bodies().nth(b)) else {
                    return Vec::new();
                };
                self.eq
                    .labels()
                    .iter()
                    .enumerate()
                    .filter(|(k, l)| l.kind != "body" && self.eq.row_bodies(*k).contains(&id))
                    .map(|(_, l)| l.entity())
                    .collect()
            }
            FailureKind::NoConvergence | FailureKind::Inconsistent => {
                let phi = self.eq.evaluate(q, &zero, t).phi;
                let mut worst: Vec<usize> = (0..phi.len()).collect();
                worst.sort_by(|&a, &b| phi[b].abs().total_cmp(&phi[a].abs()));
                worst
                    .iter()
                    .take_while(|&&k| phi[k].abs() > self.tolerance)
                    .take(4)
                    .map(|&k| self.label(k))
                    .collect()
            }
        }
    }

    /// The Taylor prediction from `prev` to `t`, or the start.
    fn guess(&self, prev: Option<&Point>, t: f64) -> DVector<f64> {
        match prev {
            None => self.start.clone(),
            Some(p) => {
                let q = DVector::from_column_slice(&p.q);
                if !self.predictor {
                    return q;
                }
                // Taylor predictor q + h q̇ + h²/2 q̈ from the previous time point.
                let h = t - p.t;
                q + DVector::from_column_slice(&p.qd) * h
                    + DVector::from_column_slice(&p.qdd) * (0.5 * h * h)
            }
        }
    }

    /// The entity of row `k` (`joint O4`).
    fn label(&self, k: usize) -> String {
        self.eq.labels()[k].entity()
    }

    /// Positions by Newton–Raphson from `q`, then velocities and accelerations, at time `t`.
    ///
    /// Every row takes part: Newton stops when every |Φ_i| meets the tolerance, and the
    /// velocity and acceleration equations of every row are checked ([`CONSISTENCY`]) when Φ_q
    /// has more rows than columns (a square regular Φ_q satisfies them all by construction).
    fn step(&self, t: f64, mut q: DVector<f64>) -> Result<Point, Rejection> {
        let n = self.eq.unknowns();
        let zero = DVector::zeros(n);
        let mut iterations = 0;
        // Newton converges on a configuration whose Euler parameters are then renormalised
        // exactly (|p| − 1 ≤ 1e-14 whatever the tolerance); only a normalised configuration
        // that still meets the tolerance is accepted, otherwise Newton goes on from it.
        let mut normalised = false;
        let mut stalled = 0;
        let (sys, residual) = loop {
            let sys = self.evaluate(&q, &zero, t);
            if !all_finite(&sys.phi) || !sys.jac.is_finite() {
                return Err(rejection(
                    Trouble::NoConvergence,
                    format!("Newton produced non-finite values after {iterations} iterations"),
                ));
            }
            let res = max_abs(&sys.phi);
            if res <= self.tolerance {
                if normalised {
                    break (sys, res);
                }
                self.normalise(&mut q);
                normalised = true;
                continue;
            }
            if iterations >= self.max_iterations {
                return Err(rejection(
                    Trouble::NoConvergence,
                    format!(
                        "Newton did not converge in {iterations} iterations (max |Φ| = {res:e}, \
                         tolerance {:e})",
                        self.tolerance
                    ),
                ));
            }
            let lu = self.factor(&sys.jac)?;
            let used_met = lu
                .used()
                .is_some_and(|used| used.iter().all(|&k| sys.phi[k].abs() <= self.tolerance));
            stalled = if used_met { stalled + 1 } else { 0 };
            if stalled > STALLED_ITERATIONS {
                let worst = (0..sys.phi.len())
                    .max_by(|&a, &b| sys.phi[a].abs().total_cmp(&sys.phi[b].abs()))
                    .unwrap_or(0);
                let message = format!(
                    "equation {} cannot hold with the others: |Φ| = {res:e} where the \
                     equations the solve uses meet the tolerance {:e}",
                    self.eq.labels()[worst].equation(),
                    self.tolerance
                );
                let point = Self::point(t, [&q, &zero, &zero], iterations, res, &lu);
                return Err(Rejection {
                    trouble: Trouble::Inconsistent,
                    message,
                    point: Some(Box::new(point)),
                    body: None,
                });
            }
            let dq = lu.solve(&(-&sys.phi));
            q += dq;
            normalised = false;
            iterations += 1;
        };
        let lu = self.factor(&sys.jac)?;
        let qd = lu.solve(&sys.nu);
        let gamma = self.evaluate(&q, &qd, t).gamma;
        let qdd = lu.solve(&gamma);
        if !all_finite(&qd) || !all_finite(&qdd) {
            return Err(rejection(
                Trouble::Singular,
                "velocities or accelerations are not finite".to_owned(),
            ));
        }
        let point = Self::point(t, [&q, &qd, &qdd], iterations, residual, &lu);
        if let (Some(_), Jacobian::Dense(jac)) = (lu.used(), &sys.jac) {
            let levels = [("velocity", &qd, &sys.nu), ("acceleration", &qdd, &gamma)];
            for (what, x, b) in levels {
                let (ratio, row) = inconsistency(jac, &lu.rows, x, b);
                // NaN misses too.
                if ratio.is_nan() || ratio > CONSISTENCY {
                    return Err(Rejection {
                        trouble: Trouble::Inconsistent,
                        message: format!(
                            "the {what} equation of {} cannot hold with the others: it misses \
                             by {ratio:.3e} of the {what} terms' scale (at most {CONSISTENCY:e})",
                            self.eq.labels()[row].equation()
                        ),
                        point: Some(Box::new(point)),
                        body: None,
                    });
                }
            }
        }
        self.check_branch(&q, t).map_err(|mut r| {
            r.point = Some(Box::new(point.clone()));
            r
        })?;
        Ok(point)
    }

    /// The point of a solved attempt at `t`, with positions, rates and accelerations `q`,
    /// its Newton `iterations` and `residual`, and the pivot ratio of `lu`.
    fn point(t: f64, q: [&DVector<f64>; 3], iterations: u32, residual: f64, lu: &Factors) -> Point {
        let (min, max) = lu.pivot_extremes();
        let [q, qd, qdd] = q;
        Point {
            t,
            q: q.as_slice().to_vec(),
            qd: qd.as_slice().to_vec(),
            qdd: qdd.as_slice().to_vec(),
            iterations,
            residual,
            pivot_ratio: min / max,
        }
    }

    /// The equations of an inconsistency at the point `p` (of a rejected attempt, or the last
    /// accepted one): at each level (positions Φ, velocities Φ_q q̇ = ν and, when `p` has
    /// rates, accelerations Φ_q q̈ = γ) the residual of the least-squares solution of the
    /// linearised rows in balanced units is the part of the right-hand side that no motion can
    /// meet; the level where it is largest against its allowance (the tolerance,
    /// [`CONSISTENCY`] of the scale) names the rows with a share of at least 0.1 of its largest
    /// entry, the equations that contradict each other.
    fn conflicting(&self, p: &Point) -> Vec<String> {
        let q = DVector::from_column_slice(&p.q);
        let n = q.len();
        let rates = p.qd.len() == n && p.qdd.len() == n;
        let qd = if rates { DVector::from_column_slice(&p.qd) } else { DVector::zeros(n) };
        let sys = self.eq.evaluate(&q, &qd, p.t);
        if !all_finite(&sys.jac) || !all_finite(&sys.phi) {
            return Vec::new();
        }
        let (jac, rows) = balanced(sys.jac.clone(), &self.columns);
        let svd = SVD::new(jac, true, false);
        let u = svd.u.as_ref().expect("requested U");
        // The part of b outside the range of Φ_q (full column rank: the range is U's span).
        let outside = |b: &DVector<f64>| {
            let b = b.component_mul(&rows);
            &b - u * (u.transpose() * &b)
        };
        let mut levels = vec![(outside(&sys.phi), self.tolerance, true)];
        if rates {
            for (x, b) in [(&qd, &sys.nu), (&DVector::from_column_slice(&p.qdd), &sys.gamma)] {
                let (_, scale) = residual_and_scale(&sys.jac, &rows, x, b);
                levels.push((outside(b), CONSISTENCY * scale, false));
            }
        }
        // Position residuals compare with the tolerance in the rows' own units.
        let ratio = |(r, allowed, unscaled): &(DVector<f64>, f64, bool)| {
            let big = if *unscaled { r.component_div(&rows).amax() } else { r.amax() };
            big / allowed
        };
        let Some(worst) = levels.iter().max_by(|a, b| ratio(a).total_cmp(&ratio(b))) else {
            return Vec::new();
        };
        let r = &worst.0;
        let big = r.amax();
        if big.is_nan() || big <= 0.0 {
            return Vec::new();
        }
        let named: Vec<String> =
            (0..r.len()).filter(|&k| r[k].abs() >= 0.1 * big).map(|k| self.label(k)).collect();
        let mut seen = std::collections::BTreeSet::new();
        named.into_iter().filter(|c| seen.insert(c.clone())).collect()
    }

    /// Φ, ν, γ and Φ_q at `(q, t)` with rates `qd`, Φ_q sparse when the analysis factors it
    /// sparse.
    fn evaluate(&self, q: &DVector<f64>, qd: &DVector<f64>, t: f64) -> Evaluated {
        match &self.sparse {
            Some(pattern) => {
                let s = self.eq.evaluate_sparse(pattern, q, qd, t);
                Evaluated { phi: s.phi, nu: s.nu, gamma: s.gamma, jac: Jacobian::Sparse(s.values) }
            }
            None => {
                let s = self.eq.evaluate(q, qd, t);
                Evaluated { phi: s.phi, nu: s.nu, gamma: s.gamma, jac: Jacobian::Dense(s.jac) }
            }
        }
    }

    /// Scales every body's Euler parameters to unit norm.
    fn normalise(&self, q: &mut DVector<f64>) {
        for body in self.eq.mechanism().moving_bodies() {
            let o = self.eq.offset(body).expect("moving body has columns");
            let p: Vector4<f64> = q.fixed_rows::<4>(o + 3).into();
            q.fixed_rows_mut::<4>(o + 3).copy_from(&p.normalize());
        }
    }

    /// Refuses a converged configuration where a driven joint angle or a screw sits on the
    /// branch θ = s + π of its equation x sin s − y cos s = 0.
    fn check_branch(&self, q: &DVector<f64>, t: f64) -> Result<(), Rejection> {
        let mech = self.eq.mechanism();
        let states = self.eq.states(q, &DVector::zeros(q.len()));
        let moving = |b: crate::model::BodyId| mech.moving_bodies().position(|m| m == b);
        for (k, d) in mech.drivers.iter().enumerate() {
            if let DriverTarget::Joint { joint, motion: Motion::Rotation } = d.target {
                let jt = &mech.joints[joint.0];
                let s = self.eq.driver_value(k, t).0;
                if angle_alignment(jt, &states[jt.body_i.0], &states[jt.body_j.0], s) <= 0.0 {
                    return Err(Rejection {
                        trouble: Trouble::BranchJump,
                        message: format!(
                            "the angle of joint {} converged half a turn away from the value \
                             driver {} prescribes",
                            jt.name, d.name
                        ),
                        point: None,
                        body: moving(jt.body_j).or_else(|| moving(jt.body_i)),
                    });
                }
            }
        }
        for jt in &mech.joints {
            if let JointKind::Screw { lead, d0, theta0 } = jt.kind {
                let (bi, bj) = (&states[jt.body_i.0], &states[jt.body_j.0]);
                let d = super::axial_position(jt, bi, bj).v;
                let phi = theta0 + 2.0 * std::f64::consts::PI * (d - d0) / lead;
                if angle_alignment(jt, bi, bj, phi) <= 0.0 {
                    return Err(Rejection {
                        trouble: Trouble::BranchJump,
                        message: format!(
                            "screw joint {} converged half a turn away from its helix",
                            jt.name
                        ),
                        point: None,
                        body: moving(jt.body_j).or_else(|| moving(jt.body_i)),
                    });
                }
            }
        }
        Ok(())
    }

    fn failure(
        &self,
        kind: FailureKind,
        t: f64,
        message: String,
        mut constraints: Vec<String>,
    ) -> Failure {
        let mut seen = std::collections::BTreeSet::new();
        constraints.retain(|c| seen.insert(c.clone()));
        Failure { kind, t, message, constraints }
    }
}

/// A rejection without a point or a body.
fn rejection(trouble: Trouble, message: String) -> Rejection {
    Rejection { trouble, message, point: None, body: None }
}

/// The largest |Φ_q,i x − b_i| over the rows relative to the scale max_k (Σ_j |Φ_q,kj x_j| +
/// |b_k|), both in balanced rows (`rows`), and the row where it is.
fn inconsistency(
    jac: &DMatrix<f64>,
    rows: &DVector<f64>,
    x: &DVector<f64>,
    b: &DVector<f64>,
) -> (f64, usize) {
    let (r, scale) = residual_and_scale(jac, rows, x, b);
    let (row, big) = r
        .iter()
        .enumerate()
        .fold((0, 0.0_f64), |m, (k, v)| if v.abs() > m.1 { (k, v.abs()) } else { m });
    if scale > 0.0 { (big / scale, row) } else { (big, row) }
}

/// R (Φ_q x − b) and max_k R_k (Σ_j |Φ_q,kj x_j| + |b_k|) for the row factors R of the
/// balanced units.
fn residual_and_scale(
    jac: &DMatrix<f64>,
    rows: &DVector<f64>,
    x: &DVector<f64>,
    b: &DVector<f64>,
) -> (DVector<f64>, f64) {
    // One pass over the (column-major) matrix for both sums.
    let mut r = -b;
    let mut terms = b.abs();
    for (j, column) in jac.column_iter().enumerate() {
        for (i, a) in column.iter().enumerate() {
            let v = a * x[j];
            r[i] += v;
            terms[i] += v.abs();
        }
    }
    let scale = terms.component_mul(rows).iter().fold(0.0_f64, |m, v| m.max(*v));
    (r.component_mul(rows), scale)
}

/// Φ, ν, γ and Φ_q at one evaluation.
struct Evaluated {
    phi: DVector<f64>,
    nu: DVector<f64>,
    gamma: DVector<f64>,
    jac: Jacobian,
}

/// Φ_q, dense or as the values of the analysis' sparse pattern.
enum Jacobian {
    Dense(DMatrix<f64>),
    Sparse(Vec<f64>),
}

impl Jacobian {
    fn is_finite(&self) -> bool {
        match self {
            Self::Dense(m) => all_finite(m),
            Self::Sparse(v) => v.iter().all(|x| x.is_finite()),
        }
    }
}

/// The LU factors of R Φ_q C (Φ_q in balanced units) with the scales, to solve Φ_q x = b.
struct Factors<'p> {
    lu: Lu<'p>,
    rows: DVector<f64>,
    columns: DVector<f64>,
}

/// LU with row pivoting of a square Φ_q, dense or sparse, or of one with more rows than
/// columns.
enum Lu<'p> {
    /// P A = L U.
    Square(nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>),
    /// P A Q = L U, sparse, Q the pattern's fill-reducing column order.
    Sparse(SparseLu<'p>),
    /// P A = [L1; L2] U for A with m > n rows: the solves use the n rows that row pivoting
    /// brought to the top, `used`, and L1 (unit lower triangular, the top of `l`) and U, both
    /// n × n.
    Tall {
        p: nalgebra::PermutationSequence<nalgebra::Dyn>,
        l: DMatrix<f64>,
        u: DMatrix<f64>,
        used: Vec<usize>,
    },
}

impl Factors<'_> {
    /// x = C (R Φ_q C)⁻¹ R b, using the rows of [`Factors::used`] when Φ_q has more rows than
    /// columns; exact scalings, the factors being powers of two.
    fn solve(&self, b: &DVector<f64>) -> DVector<f64> {
        let mut y = b.component_mul(&self.rows);
        let y = match &self.lu {
            Lu::Square(lu) => {
                assert!(lu.solve_mut(&mut y), "checked non-singular");
                y
            }
            Lu::Sparse(lu) => {
                lu.solve_mut(&mut y);
                y
            }
            Lu::Tall { p, l, u, .. } => {
                p.permute_rows(&mut y);
                let n = u.nrows();
                let mut z = y.rows(0, n).into_owned();
                l.view((0, 0), (n, n)).solve_lower_triangular_with_diag_mut(&mut z, 1.0);
                assert!(u.solve_upper_triangular_mut(&mut z), "checked non-singular");
                z
            }
        };
        y.component_mul(&self.columns)
    }

    /// The rows the solves use when Φ_q has more rows than columns, `None` for a square Φ_q.
    fn used(&self) -> Option<&[usize]> {
        match &self.lu {
            Lu::Square(_) | Lu::Sparse(_) => None,
            Lu::Tall { used, .. } => Some(used),
        }
    }

    /// The smallest and largest |u_kk|.
    fn pivot_extremes(&self) -> (f64, f64) {
        let diagonal = match &self.lu {
            Lu::Square(lu) => lu.u().diagonal(),
            Lu::Sparse(lu) => return lu.pivot_extremes(),
            Lu::Tall { u, .. } => u.diagonal(),
        };
        diagonal
            .iter()
            .fold((f64::INFINITY, 0.0_f64), |(lo, hi), x| (lo.min(x.abs()), hi.max(x.abs())))
    }
}

impl Analysis<'_, '_> {
    /// LU with row pivoting of the Jacobian in balanced units (over all its rows when it has
    /// more rows than columns), refused when a pivot is at most [`SINGULAR_PIVOT_RATIO`] of
    /// the largest.
    fn factor(&self, jac: &Jacobian) -> Result<Factors<'_>, Rejection> {
        let jac = match (jac, &self.sparse) {
            (Jacobian::Sparse(values), Some(pattern)) => {
                let mut values = values.clone();
                let rows = pattern.balance(&mut values, &self.columns);
                let lu = pattern.factor(&values).map_err(|e| {
                    rejection(
                        Trouble::Singular,
                        format!("the Jacobian is singular (sparse LU: {e})"),
                    )
                })?;
                return self.checked(Factors {
                    lu: Lu::Sparse(lu),
                    rows,
                    columns: self.columns.clone(),
                });
            }
            (Jacobian::Dense(jac), _) => jac.clone(),
            (Jacobian::Sparse(_), None) => unreachable!("sparse values come from the pattern"),
        };
        let (m, n) = jac.shape();
        let (jac, rows) = balanced(jac, &self.columns);
        let lu = if m == n {
            Lu::Square(jac.lu())
        } else {
            let (p, l, u) = nalgebra::LU::new(jac).unpack();
            let mut order = DVector::from_iterator(m, 0..m);
            p.permute_rows(&mut order);
            let used = order.iter().take(n).copied().collect();
            Lu::Tall { p, l, u, used }
        };
        self.checked(Factors { lu, rows, columns: self.columns.clone() })
    }

    /// `factors`, refused when a pivot is at most [`SINGULAR_PIVOT_RATIO`] of the largest.
    fn checked<'p>(&self, factors: Factors<'p>) -> Result<Factors<'p>, Rejection> {
        let (min, max) = factors.pivot_extremes();
        if min.is_nan() || min <= SINGULAR_PIVOT_RATIO * max {
            return Err(rejection(
                Trouble::Singular,
                format!(
                    "the Jacobian is singular (smallest LU pivot {min:e}, largest {max:e}, in \
                     balanced units)"
                ),
            ));
        }
        Ok(factors)
    }
}

/// The generic engine under the step control of [`crate::stepping`].
struct GenericEngine<'a, 'e, 'm> {
    analysis: &'a Analysis<'e, 'm>,
    /// The last accepted point.
    prev: Option<Point>,
}

impl Engine for GenericEngine<'_, '_, '_> {
    fn attempt(&mut self, t: f64) -> Result<Point, Rejection> {
        let guess = self.analysis.guess(self.prev.as_ref(), t);
        self.analysis.step(t, guess)
    }

    fn accept(&mut self, p: &Point) {
        if self.prev.as_ref() != Some(p) {
            self.prev = Some(p.clone());
        }
    }
}

/// Where and why a timed pass of [`Analysis::time`] stopped.
#[derive(Clone, Debug, PartialEq)]
pub struct TimedStop {
    /// The grid time of the step that failed.
    pub t: f64,
    /// The contract's `error.kind`: `singular`, `no_convergence` or `inconsistent`.
    pub kind: &'static str,
    /// Why, for the user.
    pub message: String,
}
