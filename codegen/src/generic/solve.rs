//! The analysis over the time grid: Newton–Raphson with LU and partial pivoting for the
//! positions, then Φ_q q̇ = ν and Φ_q q̈ = γ with the same factorisation (thesis ch. 5.2), and
//! the rank analysis that `check` reports.

use nalgebra::{DMatrix, DVector, SVD, Vector4};

use super::scaling::balanced;
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
const RANK_TOLERANCE: f64 = 1e-10;

/// A row whose component outside the span of the rows before it is below this fraction of
/// its own norm is named redundant (same reasoning as [`RANK_TOLERANCE`], per row).
const REDUNDANT_ROW_TOLERANCE: f64 = 1e-8;

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
}

impl FailureKind {
    /// The contract's `error.kind`.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Self::NoConvergence => "no_convergence",
            Self::Singular => "singular",
            Self::BranchJump => "branch_jump",
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
    /// Rows kept for the analysis (all when there is no redundancy).
    pub active: Vec<usize>,
    /// Rows that depend on the rows before them, in row order.
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
    #[must_use]
    pub fn prepare(&self) -> Preparation {
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
        let normalisation: Vec<bool> =
            self.labels().iter().map(RowLabel::is_normalisation).collect();
        let (active, redundant) = independent_rows(&jac, &normalisation);
        Preparation {
            assembled,
            q,
            rank,
            mobility: n - rank_nd.min(n),
            active,
            redundant,
            free_bodies,
        }
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

/// Splits the rows into a maximal independent set, greedily (modified Gram–Schmidt), and the
/// rows that depend on the ones taken before them; both lists in row order. The test is
/// relative to each row's norm, so only the columns' units matter: pass Φ_q with balanced
/// columns ([`super::scaling`]).
///
/// The rows marked in `first` (the Euler-parameter normalisations) are taken first and the
/// others in row order, so that a dependency is blamed on the joint, constraint or driver
/// equations that close it, never on a normalisation, which holds by construction.
pub(crate) fn independent_rows(jac: &DMatrix<f64>, first: &[bool]) -> (Vec<usize>, Vec<usize>) {
    let mut basis: Vec<DVector<f64>> = Vec::new();
    let (mut active, mut redundant) = (Vec::new(), Vec::new());
    let order =
        (0..jac.nrows()).filter(|&k| first[k]).chain((0..jac.nrows()).filter(|&k| !first[k]));
    for k in order {
        let row = jac.row(k).transpose();
        let norm = row.norm();
        let mut w = row.clone();
        for b in &basis {
            let c = b.dot(&w);
            w -= b * c;
        }
        if norm > 0.0 && w.norm() > REDUNDANT_ROW_TOLERANCE * norm {
            basis.push(w.normalize());
            active.push(k);
        } else {
            redundant.push(k);
        }
    }
    active.sort_unstable();
    redundant.sort_unstable();
    (active, redundant)
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
    /// Rows used: all, or the independent ones when the system is redundant.
    active: Option<Vec<usize>>,
    /// Where Newton starts at the first time point.
    start: DVector<f64>,
    tolerance: f64,
    max_iterations: u32,
    /// Whether Newton starts from the Taylor predictor (else from the previous q).
    predictor: bool,
    /// The column factors of Φ_q in balanced units ([`Equations::column_scales`]).
    columns: DVector<f64>,
}

impl<'e, 'm> Analysis<'e, 'm> {
    /// An analysis that drops the redundant rows found by `prep`, if any.
    #[must_use]
    pub fn new(eq: &'e Equations<'m>, prep: &Preparation) -> Self {
        let mech = eq.mechanism();
        let redundant = !prep.redundant.is_empty();
        Self {
            eq,
            active: redundant.then(|| prep.active.clone()),
            start: if redundant && prep.assembled { prep.q.clone() } else { eq.initial_estimate() },
            tolerance: mech.solver.tolerance,
            max_iterations: mech.solver.max_iterations,
            predictor: true,
            columns: eq.column_scales(),
        }
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
    /// The grid time of the first step that fails, with the reason.
    pub fn time(&self, repeats: usize) -> Result<(f64, f64, f64), (f64, String)> {
        let grid = &self.eq.mechanism().time;
        let mut times = Vec::with_capacity(repeats.max(1));
        let mut iterations = 0.0;
        for _ in 0..repeats.max(1) {
            let start = std::time::Instant::now();
            let mut prev: Option<Point> = None;
            let mut total = 0_u64;
            for k in 0..grid.count {
                let t = grid.at(k);
                let p = self.step(t, self.guess(prev.as_ref(), t)).map_err(|r| (t, r.message))?;
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
                    let frame = Frame {
                        index: k,
                        t,
                        iterations,
                        residual: point.residual,
                        condition: 1.0 / point.pivot_ratio,
                        q: DVector::from_column_slice(&point.q),
                        qd: DVector::from_column_slice(&point.qd),
                        qdd: DVector::from_column_slice(&point.qdd),
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

    /// The contract's failure for a step control [`Stop`], naming the equations involved
    /// (see [`Analysis::involved`]).
    #[must_use]
    pub fn failure_of(&self, stop: &Stop) -> Failure {
        let kind = match stop.trouble {
            Trouble::Singular => FailureKind::Singular,
            Trouble::NoConvergence => FailureKind::NoConvergence,
            Trouble::BranchJump => FailureKind::BranchJump,
            // No engine rejects a step as inconsistent yet (the rules never do): until one
            // does, it is reported as the failure to converge that it is.
            Trouble::Inconsistent => FailureKind::NoConvergence,
        };
        let near = stop.near.as_ref().map(|p| (DVector::from_column_slice(&p.q), p.t));
        let constraints =
            self.involved(kind, near.as_ref().map(|(q, t)| (q, *t)), stop.t, stop.body);
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
    ///   tolerance at `near` and the failing time `t`.
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
                let jac = self.restrict_mat(self.eq.evaluate(q, &zero, t_near).jac);
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
                    .map(|k| self.active_label(k))
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
            FailureKind::NoConvergence => {
                let phi = self.restrict_vec(self.eq.evaluate(q, &zero, t).phi);
                let mut worst: Vec<usize> = (0..phi.len()).collect();
                worst.sort_by(|&a, &b| phi[b].abs().total_cmp(&phi[a].abs()));
                worst
                    .iter()
                    .take_while(|&&k| phi[k].abs() > self.tolerance)
                    .take(4)
                    .map(|&k| self.active_label(k))
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

    /// Rows of `sys` restricted to the active ones.
    fn restrict_vec(&self, v: DVector<f64>) -> DVector<f64> {
        match &self.active {
            Some(rows) => v.select_rows(rows.iter()),
            None => v,
        }
    }

    fn restrict_mat(&self, m: DMatrix<f64>) -> DMatrix<f64> {
        match &self.active {
            Some(rows) => m.select_rows(rows.iter()),
            None => m,
        }
    }

    /// Labels of the active rows.
    fn active_label(&self, k: usize) -> String {
        let row = self.active.as_ref().map_or(k, |a| a[k]);
        self.eq.labels()[row].entity()
    }

    /// Positions by Newton–Raphson from `q`, then velocities and accelerations, at time `t`.
    fn step(&self, t: f64, mut q: DVector<f64>) -> Result<Point, Rejection> {
        let n = self.eq.unknowns();
        let zero = DVector::zeros(n);
        let mut iterations = 0;
        // Newton converges on a configuration whose Euler parameters are then renormalised
        // exactly (|p| − 1 ≤ 1e-14 whatever the tolerance); only a normalised configuration
        // that still meets the tolerance is accepted, otherwise Newton goes on from it.
        let mut normalised = false;
        let (sys, residual) = loop {
            let sys = self.eq.evaluate(&q, &zero, t);
            let phi = self.restrict_vec(sys.phi.clone());
            if !all_finite(&phi) || !all_finite(&sys.jac) {
                return Err(rejection(
                    Trouble::NoConvergence,
                    format!("Newton produced non-finite values after {iterations} iterations"),
                ));
            }
            let res = max_abs(&phi);
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
            let jac = self.restrict_mat(sys.jac);
            let dq = self.factor(jac)?.solve(&(-phi));
            q += dq;
            normalised = false;
            iterations += 1;
        };
        // Redundant rows left out of the analysis are satisfied too when they are consistent;
        // the reported residual covers every row.
        let residual = residual.max(max_abs(&sys.phi));
        let lu = self.factor(self.restrict_mat(sys.jac))?;
        let qd = lu.solve(&self.restrict_vec(sys.nu));
        let gamma = self.restrict_vec(self.eq.evaluate(&q, &qd, t).gamma);
        let qdd = lu.solve(&gamma);
        if !all_finite(&qd) || !all_finite(&qdd) {
            return Err(rejection(
                Trouble::Singular,
                "velocities or accelerations are not finite".to_owned(),
            ));
        }
        let (min, max) = pivot_extremes(&lu.lu);
        let point = Point {
            t,
            q: q.as_slice().to_vec(),
            qd: qd.as_slice().to_vec(),
            qdd: qdd.as_slice().to_vec(),
            iterations,
            residual,
            pivot_ratio: min / max,
        };
        self.check_branch(&q, t).map_err(|mut r| {
            r.point = Some(Box::new(point.clone()));
            r
        })?;
        Ok(point)
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

/// The smallest and largest |u_kk| of an LU factorisation.
fn pivot_extremes(lu: &nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>) -> (f64, f64) {
    lu.u()
        .diagonal()
        .iter()
        .fold((f64::INFINITY, 0.0_f64), |(lo, hi), x| (lo.min(x.abs()), hi.max(x.abs())))
}

/// The LU factors of R Φ_q C (Φ_q in balanced units) with the scales, to solve Φ_q x = b.
struct Factors {
    lu: nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>,
    rows: DVector<f64>,
    columns: DVector<f64>,
}

impl Factors {
    /// x = C (R Φ_q C)⁻¹ R b; exact scalings, the factors being powers of two.
    fn solve(&self, b: &DVector<f64>) -> DVector<f64> {
        let y = self.lu.solve(&b.component_mul(&self.rows)).expect("checked non-singular");
        y.component_mul(&self.columns)
    }
}

impl Analysis<'_, '_> {
    /// LU with partial pivoting of the (square) Jacobian in balanced units, refused when a
    /// pivot is at most [`SINGULAR_PIVOT_RATIO`] of the largest.
    fn factor(&self, jac: DMatrix<f64>) -> Result<Factors, Rejection> {
        let (jac, rows) = balanced(jac, &self.columns);
        let lu = jac.lu();
        let (min, max) = pivot_extremes(&lu);
        if min.is_nan() || min <= SINGULAR_PIVOT_RATIO * max {
            return Err(rejection(
                Trouble::Singular,
                format!(
                    "the Jacobian is singular (smallest LU pivot {min:e}, largest {max:e}, in \
                     balanced units)"
                ),
            ));
        }
        Ok(Factors { lu, rows, columns: self.columns.clone() })
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
