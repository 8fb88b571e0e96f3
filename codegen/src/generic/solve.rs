//! The analysis over the time grid: Newton–Raphson with LU and partial pivoting for the
//! positions, then Φ_q q̇ = ν and Φ_q q̈ = γ with the same factorisation (thesis ch. 5.2), and
//! the rank analysis that `check` reports.

use nalgebra::{DMatrix, DVector, SVD, Vector4};

use super::{Equations, angle_alignment};
use crate::model::{DriverTarget, JointKind, Motion};

/// A pivot smaller than this fraction of the largest pivot of the LU factorisation marks
/// Φ_q as singular: with partial pivoting the pivots bound the conditioning from below, and
/// 1e-12 leaves four orders of magnitude above f64 round-off before a step is refused.
const SINGULAR_PIVOT_RATIO: f64 = 1e-12;

/// Singular values below this fraction of the largest count as zero in rank decisions: an
/// exact dependency shows up at round-off level (≈1e-16 relative), a genuine but poorly
/// conditioned configuration far above it.
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
        for _ in 0..iterations {
            let sys = self.evaluate(&q, &zero, t0);
            if !all_finite(&sys.phi) || !all_finite(&sys.jac) {
                break;
            }
            if max_abs(&sys.phi) <= mech.solver.tolerance {
                assembled = true;
                break;
            }
            let svd = SVD::new(sys.jac, true, true);
            let eps = RANK_TOLERANCE * svd.singular_values.max();
            match svd.solve(&sys.phi, eps) {
                Ok(dq) => q -= dq,
                Err(_) => break,
            }
        }
        if !assembled || !all_finite(&q) {
            q = self.initial_estimate();
        }
        let jac = self.evaluate(&q, &zero, t0).jac;
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
            .filter(|(_, l)| l.kind == "driver")
            .map(|(k, _)| k)
            .collect();
        let kept: Vec<usize> = (0..self.equations()).filter(|k| !driver_rows.contains(k)).collect();
        let rank_nd = numeric_rank(&jac.select_rows(kept.iter()));
        let (active, redundant) = independent_rows(&jac);
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

/// Marks the bodies with a noticeable share of the null vector `v`.
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

/// The numeric rank of a matrix (see [`RANK_TOLERANCE`]).
fn numeric_rank(m: &DMatrix<f64>) -> usize {
    if m.nrows() == 0 {
        return 0;
    }
    let s = SVD::new(m.clone(), false, false).singular_values;
    let smax = s.max();
    s.iter().filter(|&&x| x > RANK_TOLERANCE * smax).count()
}

/// Splits the rows into a maximal independent set, greedily in row order (modified
/// Gram–Schmidt), and the rows that depend on earlier ones.
pub(crate) fn independent_rows(jac: &DMatrix<f64>) -> (Vec<usize>, Vec<usize>) {
    let mut basis: Vec<DVector<f64>> = Vec::new();
    let (mut active, mut redundant) = (Vec::new(), Vec::new());
    for k in 0..jac.nrows() {
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
        }
    }

    /// Turns the Taylor predictor off (Newton then starts from the previous positions).
    #[must_use]
    pub fn with_predictor(mut self, on: bool) -> Self {
        self.predictor = on;
        self
    }

    /// Times `repeats` whole passes over the grid: (min, median) ns per time point and
    /// Newton iterations per time point; `None` when the analysis fails.
    #[must_use]
    pub fn time(&self, repeats: usize) -> Option<(f64, f64, f64)> {
        let mut times = Vec::with_capacity(repeats.max(1));
        let mut iterations = 0.0;
        for _ in 0..repeats.max(1) {
            let start = std::time::Instant::now();
            let r = self.run(|f| {
                std::hint::black_box(&f.qdd);
                Ok::<(), ()>(())
            });
            let elapsed = start.elapsed().as_nanos() as f64;
            let r = r.ok()?;
            if r.failure.is_some() || r.steps == 0 {
                return None;
            }
            times.push(elapsed / r.steps as f64);
            iterations = r.iterations as f64 / r.steps as f64;
        }
        times.sort_by(f64::total_cmp);
        Some((times[0], times[times.len() / 2], iterations))
    }

    /// Overrides the Newton tolerance (benchmarks and accuracy charts).
    #[must_use]
    pub fn with_tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = tolerance;
        self
    }

    /// Runs over the whole grid, handing every frame to `sink` as soon as it is computed,
    /// so that output can be streamed. Stops at the first numerical failure.
    ///
    /// # Errors
    /// Returns the first error of `sink`.
    pub fn run<E>(&self, mut sink: impl FnMut(&Frame) -> Result<(), E>) -> Result<StepReport, E> {
        let grid = self.eq.mechanism().time;
        let mut report = StepReport { steps: 0, iterations: 0, failure: None };
        let mut prev: Option<Frame> = None;
        for k in 0..grid.count {
            let t = grid.at(k);
            let guess = match &prev {
                Some(f) if !self.predictor => f.q.clone(),
                // Taylor predictor q + h q̇ + h²/2 q̈ from the previous time point.
                Some(f) => {
                    let h = t - f.t;
                    &f.q + &f.qd * h + &f.qdd * (0.5 * h * h)
                }
                None => self.start.clone(),
            };
            match self.step(k, t, guess) {
                Ok(frame) => {
                    report.steps += 1;
                    report.iterations += u64::from(frame.iterations);
                    sink(&frame)?;
                    prev = Some(frame);
                }
                Err(failure) => {
                    report.failure = Some(failure);
                    break;
                }
            }
        }
        Ok(report)
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

    /// Positions by Newton–Raphson, then velocities and accelerations, at one time point.
    fn step(&self, index: usize, t: f64, mut q: DVector<f64>) -> Result<Frame, Failure> {
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
                return Err(self.failure(
                    FailureKind::NoConvergence,
                    t,
                    format!("Newton produced non-finite values after {iterations} iterations"),
                    Vec::new(),
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
                let mut worst: Vec<usize> = (0..phi.len()).collect();
                worst.sort_by(|&a, &b| phi[b].abs().total_cmp(&phi[a].abs()));
                let names = worst
                    .iter()
                    .take_while(|&&k| phi[k].abs() > self.tolerance)
                    .take(4)
                    .map(|&k| self.active_label(k))
                    .collect();
                return Err(self.failure(
                    FailureKind::NoConvergence,
                    t,
                    format!(
                        "Newton did not converge in {iterations} iterations (max |Φ| = {res:e}, \
                         tolerance {:e})",
                        self.tolerance
                    ),
                    names,
                ));
            }
            let jac = self.restrict_mat(sys.jac);
            let dq = self.factor(&jac, t)?.solve(&(-phi)).expect("checked non-singular");
            q += dq;
            normalised = false;
            iterations += 1;
        };
        // Redundant rows left out of the analysis are satisfied too when they are consistent;
        // the reported residual covers every row.
        let residual = residual.max(max_abs(&sys.phi));
        self.check_branch(&q, t)?;
        let lu = self.factor(&self.restrict_mat(sys.jac), t)?;
        let qd = lu.solve(&self.restrict_vec(sys.nu)).expect("checked non-singular");
        let gamma = self.restrict_vec(self.eq.evaluate(&q, &qd, t).gamma);
        let qdd = lu.solve(&gamma).expect("checked non-singular");
        if !all_finite(&qd) || !all_finite(&qdd) {
            return Err(self.failure(
                FailureKind::Singular,
                t,
                "velocities or accelerations are not finite".to_owned(),
                Vec::new(),
            ));
        }
        Ok(Frame { index, t, iterations, residual, q, qd, qdd })
    }

    /// Scales every body's Euler parameters to unit norm.
    fn normalise(&self, q: &mut DVector<f64>) {
        for body in self.eq.mechanism().moving_bodies() {
            let o = self.eq.offset(body).expect("moving body has columns");
            let p: Vector4<f64> = q.fixed_rows::<4>(o + 3).into();
            q.fixed_rows_mut::<4>(o + 3).copy_from(&p.normalize());
        }
    }

    /// LU with partial pivoting of the (square) Jacobian, refused when a pivot is below
    /// [`SINGULAR_PIVOT_RATIO`] of the largest.
    fn factor(
        &self,
        jac: &DMatrix<f64>,
        t: f64,
    ) -> Result<nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>, Failure> {
        let lu = jac.clone().lu();
        let u = lu.u();
        let diag = u.diagonal();
        let (min, max) = diag
            .iter()
            .fold((f64::INFINITY, 0.0_f64), |(lo, hi), x| (lo.min(x.abs()), hi.max(x.abs())));
        if min.is_nan() || min <= SINGULAR_PIVOT_RATIO * max {
            let svd = SVD::new(jac.clone(), true, false);
            let u = svd.u.as_ref().expect("requested U");
            let (kmin, _) = svd.singular_values.iter().enumerate().fold(
                (0, f64::INFINITY),
                |(bk, bv), (k, &s)| if s < bv { (k, s) } else { (bk, bv) },
            );
            let col = u.column(kmin);
            let big = col.amax();
            let names = (0..col.len())
                .filter(|&k| col[k].abs() >= 0.1 * big)
                .map(|k| self.active_label(k))
                .collect();
            return Err(self.failure(
                FailureKind::Singular,
                t,
                format!(
                    "the Jacobian is singular (smallest LU pivot {min:e}, largest {max:e}): \
                     the mechanism is at a singular configuration or its constraints are \
                     dependent"
                ),
                names,
            ));
        }
        Ok(lu)
    }

    /// Refuses a converged configuration where a driven joint angle or a screw sits on the
    /// branch θ = s + π of its equation x sin s − y cos s = 0.
    fn check_branch(&self, q: &DVector<f64>, t: f64) -> Result<(), Failure> {
        let mech = self.eq.mechanism();
        let states = self.eq.states(q, &DVector::zeros(q.len()));
        for d in &mech.drivers {
            if let DriverTarget::Joint { joint, motion: Motion::Rotation } = d.target {
                let jt = &mech.joints[joint.0];
                let s = d.law.eval(t).0;
                if angle_alignment(jt, &states[jt.body_i.0], &states[jt.body_j.0], s) <= 0.0 {
                    return Err(self.failure(
                        FailureKind::BranchJump,
                        t,
                        format!(
                            "the angle of joint {} converged half a turn away from the value \
                             driver {} prescribes",
                            jt.name, d.name
                        ),
                        vec![format!("driver {}", d.name), format!("joint {}", jt.name)],
                    ));
                }
            }
        }
        for jt in &mech.joints {
            if let JointKind::Screw { lead, d0, theta0 } = jt.kind {
                let (bi, bj) = (&states[jt.body_i.0], &states[jt.body_j.0]);
                let d = super::axial_position(jt, bi, bj).v;
                let phi = theta0 + 2.0 * std::f64::consts::PI * (d - d0) / lead;
                if angle_alignment(jt, bi, bj, phi) <= 0.0 {
                    return Err(self.failure(
                        FailureKind::BranchJump,
                        t,
                        format!(
                            "screw joint {} converged half a turn away from its helix",
                            jt.name
                        ),
                        vec![format!("joint {}", jt.name)],
                    ));
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
