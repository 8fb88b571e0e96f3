//! [`Solver`]: position, velocity and acceleration steps for a control loop.
//!
//! A step is up to three calls, each paying only for itself:
//! [`Solver::position`] runs Newton at time t and keeps the LU factors of Φ_q at the converged q;
//! [`Solver::velocity`] solves Φ_q q̇ = ν with those factors;
//! [`Solver::acceleration`] solves Φ_q q̈ = γ with the same factors.
//! Neither of the last two evaluates or factors Φ_q again.
//!
//! The solver owns the state q, q̇, q̈ and the time of the last converged position.
//! With the predictor on, [`Solver::position`] starts Newton from the Taylor expansion
//! q + h q̇ + h²/2 q̈ + h³/6 b + h⁴/12 c (h the time since the last step), using whichever of q̇
//! and q̈ were solved at that step; b and c are the coefficients of q̈(t + τ) ≈ q̈ + b τ + c τ²,
//! the parabola through the accelerations solved at the last three steps (the line through
//! two, or nothing, when fewer are known), so the predictor's error falls from O(h³) to O(h⁵).
//! On smooth motions sampled finely, as a control loop does, the prediction often meets the
//! tolerance already; it is then corrected by one chord step with the factors of Φ_q kept
//! from the last position ([`newton::solve_with_chord`]), which needs neither Φ_q nor a
//! factorisation and brings it to within round-off of the solution, as a Newton step would.
//! The factorisation at the converged q, which velocities and accelerations need anyway, is
//! then the only one of the time step.
//!
//! [`Solver::advance_to`] takes a step under the step control of [`crate::step`]: from the last
//! point whose velocities and accelerations were solved it sub-steps towards the requested time
//! as the continuity, branch-jump and singularity rules require, and either lands on the branch
//! it started from or returns the failure as an error value. [`Solver::position`] alone trusts
//! the caller's step: a step that is large for the motion may converge on another assembly
//! branch and still succeed.

mod inputs;
#[cfg(test)]
mod tests;

use core::borrow::BorrowMut;
use core::fmt;

use crate::factors::{BlockCounts, FactorCounts, Factors};
use crate::lu::{PivotInfo, Singular};
use crate::mechanism::{MAX_TIME_TERMS, Timed};
use crate::newton::{self, NewtonError, NewtonOptions, NewtonReport};
use crate::rows::{self, Selection, Swapped};
use crate::step::{self, Coordinates, Groups, Rejection, Sample, Stepper, Stop, Suspect, Trouble};
use crate::{Mechanism, Real};

pub use inputs::InputsError;

/// Kinematic analysis of one mechanism, one time step at a time, without allocation.
///
/// `R` is the floating-point type (`f64`, or `f32` for a module generated in single precision)
/// and `J` the storage of the `N × N` Jacobian and its LU factors.
/// With the default, an owned array, the solver is self-contained: keep it in a local for small
/// `N`, and in a `Box` or a `static` for large `N` (the constructors are `const fn`, so it can
/// be built at compile time).
/// [`Solver::with_storage`] takes any `J: BorrowMut<[[R; N]; N]>` instead, such as a
/// `&mut [[R; N]; N]` or a `Box<[[R; N]; N]>` built without passing through the stack.
///
/// # Example
///
/// A slider whose position x follows s(t) = sin t: Φ = x − sin t, so ν = cos t and
/// γ = −sin t. Each step asks for what it needs; velocity and acceleration reuse the factors
/// of the converged position.
///
/// ```
/// use runtime::{Mechanism, Solver};
///
/// struct Slider;
///
/// impl Mechanism<1> for Slider {
///     fn residual(&self, q: &[f64; 1], t: f64, phi: &mut [f64; 1]) {
///         phi[0] = q[0] - t.sin();
///     }
///     fn jacobian(&self, _q: &[f64; 1], _t: f64, jac: &mut [[f64; 1]; 1]) {
///         jac[0][0] = 1.0;
///     }
///     fn velocity_rhs(&self, _q: &[f64; 1], t: f64, nu: &mut [f64; 1]) {
///         nu[0] = t.cos();
///     }
///     fn acceleration_rhs(&self, _q: &[f64; 1], _qd: &[f64; 1], t: f64, gamma: &mut [f64; 1]) {
///         gamma[0] = -t.sin();
///     }
/// }
///
/// let mut solver = Solver::new(Slider, [0.0]);
/// for k in 0..=10 {
///     let t = 0.1 * f64::from(k);
///     solver.position(t).expect("a linear system converges");
///     solver.velocity().expect("Φ_q is regular");
///     solver.acceleration().expect("q̇ is known");
///     // The solver stops at max |Φ| ≤ 1e-10 by default, and Φ is linear here: one Newton
///     // step is exact up to round-off, so 1e-12 is loose.
///     assert!((solver.q()[0] - t.sin()).abs() < 1e-12);
///     assert!((solver.qd()[0] - t.cos()).abs() < 1e-12);
///     assert!((solver.qdd()[0] + t.sin()).abs() < 1e-12);
/// }
/// ```
#[derive(Clone, Debug)]
pub struct Solver<M, const N: usize, R = f64, J = [[R; N]; N]> {
    mechanism: M,
    options: NewtonOptions<R>,
    predictor: bool,
    t: R,
    q: [R; N],
    qd: [R; N],
    qdd: [R; N],
    /// Φ during Newton, then ν or γ and the solutions before they are accepted.
    scratch: [R; N],
    jac: J,
    /// How `jac` was factored.
    factors: Factors<N>,
    /// `jac` and `factors` hold the factors of Φ_q at (`q`, `t`).
    factored: bool,
    /// The smallest and largest |pivot| of those factors, when `factored`.
    pivots: PivotInfo<R>,
    /// Which time derivatives were solved at (`q`, `t`).
    known: Known,
    /// (t, q̈) at the two converged positions before the current one, the later first, where q̈
    /// was solved there.
    history: History<R, N>,
    /// The last point accepted by [`Solver::advance_to`]'s step control, to return to after a
    /// rejected attempt.
    accepted: Accepted<R, N>,
    /// How the continuity check groups the unknowns.
    groups: Groups<'static>,
    /// The rows solved with, for a mechanism with left-out rows ([`crate::rows`]).
    selection: Selection,
    /// The largest pivot ratio of the rows in force since they were chosen (0 before a first
    /// position): a fall below [`rows::RESELECT_DROP`] of it chooses the rows again.
    baseline: R,
    /// The mechanism's time terms ([`Mechanism::TIME_TERMS`]) at `terms_t`, computed once per
    /// position for its evaluations at that time.
    terms: [R; MAX_TIME_TERMS],
    /// The time of `terms`.
    terms_t: R,
    /// `terms` holds the time terms at `terms_t` of the mechanism as it is.
    terms_valid: bool,
}

/// A point accepted by the step control: everything [`Solver::position`] reads or changes.
#[derive(Clone, Debug)]
struct Accepted<R, const N: usize> {
    sample: Sample<R>,
    q: [R; N],
    qd: [R; N],
    qdd: [R; N],
    history: History<R, N>,
    known: Known,
    /// `sample` belongs to (`q`, `sample.t`).
    valid: bool,
    /// The solver's state is this point: nothing changed q, q̇, q̈ or the history since it was
    /// accepted or returned to.
    current: bool,
}

/// The (t, q̈) of the two converged positions before the current one, kept as a ring so
/// that a new entry costs one copy of q̈ and no shifting.
#[derive(Clone, Debug)]
struct History<R, const N: usize> {
    t: [R; 2],
    qdd: [[R; N]; 2],
    /// How many entries are valid (0, 1 or 2).
    len: u8,
    /// The slot of the later entry.
    latest: usize,
}

impl<R: Real, const N: usize> History<R, N> {
    const EMPTY: Self = History { t: [R::ZERO; 2], qdd: [[R::ZERO; N]; 2], len: 0, latest: 0 };

    /// Makes (t, q̈) the later entry; the former later entry becomes the earlier one.
    fn push(&mut self, t: R, qdd: &[R; N]) {
        self.latest ^= 1;
        self.t[self.latest] = t;
        self.qdd[self.latest] = *qdd;
        self.len = (self.len + 1).min(2);
    }

    /// Entry `k`: 0 the later, 1 the earlier.
    fn get(&self, k: usize) -> Option<(R, &[R; N])> {
        let slot = self.latest ^ k;
        (k < usize::from(self.len)).then(|| (self.t[slot], &self.qdd[slot]))
    }
}

/// The time derivatives solved at the solver's current (q, t).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Known {
    Nothing,
    Velocity,
    Acceleration,
}

/// Why [`Solver::velocity`] or [`Solver::acceleration`] failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolveError {
    /// There is no converged position to reuse the factors of: [`Solver::position`] was not
    /// called since [`Solver::new`] or [`Solver::set_q`], or its last call failed.
    NoPosition,
    /// [`Solver::acceleration`] needs q̇ at the current position: call [`Solver::velocity`]
    /// first.
    NoVelocity,
    /// ν, γ or the solution contained a NaN or an infinity; q̇ or q̈ is left unchanged.
    NonFinite,
}

impl fmt::Display for SolveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            SolveError::NoPosition => "no converged position to reuse the factorisation of",
            SolveError::NoVelocity => "acceleration needs the velocity at the current position",
            SolveError::NonFinite => "non-finite right-hand side or solution",
        })
    }
}

impl core::error::Error for SolveError {}

impl<M, const N: usize, R: Real> Solver<M, N, R> {
    /// A solver for `mechanism` that owns its Jacobian storage, with `q` as the first estimate,
    /// t = 0, [`NewtonOptions::DEFAULT`] and the predictor off.
    ///
    /// The solver holds an `N × N` array by value: for large `N`, place it in a `static` or see
    /// [`Solver::with_storage`].
    pub const fn new(mechanism: M, q: [R; N]) -> Self {
        Solver::with_storage(mechanism, q, [[R::ZERO; N]; N])
    }
}

impl<M, const N: usize, R: Real, J> Solver<M, N, R, J> {
    /// A solver for `mechanism` that keeps Φ_q and its factors in `jac`, with `q` as the first
    /// estimate, t = 0, [`NewtonOptions::DEFAULT`] and the predictor off.
    ///
    /// The contents of `jac` are irrelevant; it is overwritten before it is read.
    pub const fn with_storage(mechanism: M, q: [R; N], jac: J) -> Self {
        Solver {
            mechanism,
            options: NewtonOptions::DEFAULT,
            predictor: false,
            t: R::ZERO,
            q,
            qd: [R::ZERO; N],
            qdd: [R::ZERO; N],
            scratch: [R::ZERO; N],
            jac,
            factors: Factors::new(),
            factored: false,
            pivots: PivotInfo { smallest: R::ZERO, largest: R::ZERO },
            known: Known::Nothing,
            history: History::EMPTY,
            accepted: Accepted {
                sample: Sample {
                    t: R::ZERO,
                    iterations: 0,
                    residual: R::ZERO,
                    pivot_ratio: R::ZERO,
                },
                q: [R::ZERO; N],
                qd: [R::ZERO; N],
                qdd: [R::ZERO; N],
                history: History::EMPTY,
                known: Known::Nothing,
                valid: false,
                current: false,
            },
            groups: Groups::Each,
            selection: Selection::KEPT,
            baseline: R::ZERO,
            terms: [R::ZERO; MAX_TIME_TERMS],
            terms_t: R::ZERO,
            terms_valid: false,
        }
    }

    /// The mechanism.
    pub const fn mechanism(&self) -> &M {
        &self.mechanism
    }

    /// The Newton options used by [`Solver::position`].
    pub const fn options(&self) -> &NewtonOptions<R> {
        &self.options
    }

    /// Replaces the Newton options used by [`Solver::position`].
    pub const fn set_options(&mut self, options: NewtonOptions<R>) {
        self.options = options;
    }

    /// Sets how [`Solver::advance_to`]'s continuity check groups the unknowns: by default
    /// ([`Groups::Each`]) every unknown on its own, the strictest check, since the unknowns of a
    /// reduced system need not be whole bodies; [`Groups::Ends`] names groups such as the
    /// position and the Euler parameters of each body.
    pub const fn set_continuity_groups(&mut self, groups: Groups<'static>) {
        self.groups = groups;
    }

    /// Turns the Taylor predictor of [`Solver::position`] on or off (off by default).
    pub const fn set_predictor(&mut self, on: bool) {
        self.predictor = on;
    }

    /// The time of the last converged position (0 before the first).
    pub const fn t(&self) -> R {
        self.t
    }

    /// The coordinates q: the last converged position, or the estimate given to
    /// [`Solver::new`] or [`Solver::set_q`].
    pub const fn q(&self) -> &[R; N] {
        &self.q
    }

    /// The velocities q̇ from the last successful [`Solver::velocity`] (zeros before the first).
    ///
    /// They belong to the current q only if [`Solver::velocity`] was called after the last
    /// [`Solver::position`].
    pub const fn qd(&self) -> &[R; N] {
        &self.qd
    }

    /// The accelerations q̈ from the last successful [`Solver::acceleration`] (zeros before the
    /// first), with the same caveat as [`Solver::qd`].
    pub const fn qdd(&self) -> &[R; N] {
        &self.qdd
    }

    /// The smallest and largest |pivot| of the factors of Φ_q the solver holds at the last
    /// converged position (a static pivot order's, or dense LU's), or `None` when it holds none
    /// (before the first position, after [`Solver::set_q`] or a failed [`Solver::position`]).
    ///
    /// They cost nothing: [`Solver::position`] factors Φ_q at the converged q anyway.
    pub const fn pivots(&self) -> Option<PivotInfo<R>> {
        if self.factored { Some(self.pivots) } else { None }
    }

    /// How many factorisations of Φ_q used a static pivot order of the mechanism, how many fell
    /// back to dense LU, and how many static orders were refused on the way.
    pub const fn factor_counts(&self) -> FactorCounts {
        self.factors.counts()
    }

    /// What Newton block by block did ([`Mechanism::BLOCK_NEWTON`]): blocks solved in closed
    /// form, blocks solved by Newton and their Newton steps; all 0 for other mechanisms.
    pub const fn block_counts(&self) -> BlockCounts {
        self.factors.block_counts()
    }

    /// Sets the estimate of q that the next [`Solver::position`] starts from.
    ///
    /// This forgets the factorisation and the solved q̇ and q̈, so the next step uses no
    /// predictor, and [`Solver::velocity`] fails until a position has converged.
    pub const fn set_q(&mut self, q: [R; N]) {
        self.q = q;
        self.factored = false;
        self.known = Known::Nothing;
        self.history = History::EMPTY;
        self.accepted.current = false;
        self.selection = Selection::KEPT;
        self.baseline = R::ZERO;
    }

    /// Whether rows left out of the mechanism's square system ([`Mechanism::LEFT_OUT`]) stand
    /// in for some of its rows at the last position ([`crate::rows`]): where the kept rows
    /// degenerate while the whole stack of rows does not.
    pub fn rows_swapped(&self) -> bool {
        self.selection.is_swapped()
    }
}

/// Evaluates `$body` with `$m` the mechanism whose rows are in force for the solver `$s`:
/// its own, or [`Swapped`] while left-out rows stand in for kept ones.
macro_rules! in_force {
    ($s:expr, $m:ident => $body:expr) => {
        if M::LEFT_OUT > 0 && $s.selection.is_swapped() {
            let $m = &Swapped { mechanism: &$s.mechanism, selection: &$s.selection };
            $body
        } else if M::TIME_TERMS > 0 && M::TIME_TERMS <= MAX_TIME_TERMS {
            // Evaluations at the time of the terms read them instead of computing them again.
            let terms = $s.terms_valid.then(|| &$s.terms[..M::TIME_TERMS]);
            let $m = &Timed { mechanism: &$s.mechanism, t: $s.terms_t, terms };
            $body
        } else {
            let $m = &$s.mechanism;
            $body
        }
    };
}

impl<M: Mechanism<N, R>, const N: usize, R: Real, J: BorrowMut<[[R; N]; N]>> Solver<M, N, R, J> {
    /// Solves Φ(q, t) = 0 by Newton from the current q (or from the predictor, see the module
    /// docs, when it is on and q̇ was solved at the last step), then normalises q.
    ///
    /// Keeps the LU factors of Φ_q at the converged q for [`Solver::velocity`] and
    /// [`Solver::acceleration`].
    ///
    /// # Errors
    ///
    /// Returns the [`NewtonError`] of the failed solve.
    /// q, q̇, q̈ and t are then left as they were before the call (the predictor's history
    /// included), so the caller can retry, for example with a shorter step or after
    /// [`Solver::set_q`]; velocity and acceleration fail until a position converges.
    pub fn position(&mut self, t: R) -> Result<NewtonReport<R>, NewtonError<R>> {
        let start = self.q;
        let result = self.solve_position(t);
        if result.is_err() {
            self.q = start;
        }
        result
    }

    /// [`Solver::position`], except that a failed solve leaves q at Newton's last iterate.
    fn solve_position(&mut self, t: R) -> Result<NewtonReport<R>, NewtonError<R>> {
        self.accepted.current = false;
        // Only a mechanism with left-out rows tries again, from the same start, when the
        // stack's choice of rows at Newton's last iterate differs from the rows in force: a
        // singular Jacobian, or the slow convergence of Newton onto a configuration where the
        // rows in force degenerate.
        if M::LEFT_OUT == 0 {
            let report = self.newton(t)?;
            self.converged(t, report.pivots);
            return Ok(report);
        }
        let start = self.q;
        let mut result = self.newton(t);
        if M::LEFT_OUT > 0
            && matches!(
                result,
                Err(NewtonError::Singular { .. } | NewtonError::NotConverged { .. })
            )
            && self.reselect(t)
        {
            self.q = start;
            result = self.newton(t);
        }
        let mut report = result?;
        if M::LEFT_OUT > 0 {
            let ratio = report.pivots.smallest / report.pivots.largest;
            let bound = step::structured_floor::<R>();
            let fell = ratio < self.baseline * R::from_f64(rows::RESELECT_DROP);
            if fell || ratio <= bound || ratio.is_nan() {
                // The rows in force degenerate here: the stack's own choice at the converged q,
                // factored again (the choice used the storage of the factors).
                self.reselect(t);
                let pivots = in_force!(self, m => {
                    let jac = self.jac.borrow_mut();
                    self.factors.evaluate(m, &self.q, t, &mut self.scratch, jac);
                    self.factors.factor(m, &self.q, t, jac, self.options.pivot_ratio)
                });
                report.pivots = pivots.map_err(|e| match e {
                    crate::lu::Singular::SmallPivot { column, pivot, largest } => {
                        NewtonError::Singular {
                            iteration: report.iterations,
                            column,
                            pivot,
                            largest,
                        }
                    }
                    crate::lu::Singular::NonFinite { .. } => {
                        NewtonError::NonFinite { iteration: report.iterations }
                    }
                })?;
                self.baseline = report.pivots.smallest / report.pivots.largest;
            } else {
                self.baseline = self.baseline.max(ratio);
            }
        }
        self.converged(t, report.pivots);
        Ok(report)
    }

    /// Keeps a converged position at `t` whose factors have `pivots`.
    fn converged(&mut self, t: R, pivots: PivotInfo<R>) {
        self.pivots = pivots;
        if self.known == Known::Acceleration {
            self.history.push(self.t, &self.qdd);
        } else {
            self.history.len = 0;
        }
        self.t = t;
        self.factored = true;
        self.known = Known::Nothing;
    }

    /// The prediction (when the predictor is on) and Newton's iteration from it, with the rows
    /// in force; the solver's state other than q and the factors is left to the caller.
    fn newton(&mut self, t: R) -> Result<NewtonReport<R>, NewtonError<R>> {
        if self.predictor && self.known >= Known::Velocity {
            self.predict(t - self.t);
        }
        if M::TIME_TERMS > 0 && M::TIME_TERMS <= MAX_TIME_TERMS {
            self.mechanism.time_terms(t, &mut self.terms[..M::TIME_TERMS]);
            self.terms_t = t;
            self.terms_valid = true;
        }
        // With the predictor, the factors of the last position correct the prediction first.
        let chord = self.predictor && self.factored;
        self.factored = false;
        let jac = self.jac.borrow_mut();
        in_force!(self, m => {
            let solve = if chord { newton::solve_with_chord } else { newton::solve };
            solve(m, &mut self.q, t, &self.options, &mut self.scratch, jac, &mut self.factors)
        })
    }

    /// The mechanism's time terms at `t` ([`Mechanism::TIME_TERMS`] values, see
    /// [`Mechanism::time_terms`]) when the solver holds them: computed by the last
    /// [`Solver::position`] at `t` (converged or not), for the mechanism as it is. A caller
    /// passes them to [`Mechanism::expand_at`] rather than computing them again.
    pub fn time_terms(&self, t: R) -> Option<&[R]> {
        let held = M::TIME_TERMS > 0 && M::TIME_TERMS <= MAX_TIME_TERMS;
        (held && self.terms_valid && self.terms_t == t).then(|| &self.terms[..M::TIME_TERMS])
    }

    /// Chooses the rows to solve with at (q, t) from the whole stack ([`rows::select`]),
    /// forgetting the factors (the choice uses their storage); whether the choice changed.
    /// A stack that loses column rank keeps the rows in force.
    fn reselect(&mut self, t: R) -> bool {
        self.factors.forget();
        self.factored = false;
        let chosen = rows::select(
            &self.mechanism,
            &self.q,
            t,
            self.jac.borrow_mut(),
            self.options.pivot_ratio,
        );
        match chosen {
            Ok(selection) if selection != self.selection => {
                self.selection = selection;
                true
            }
            _ => false,
        }
    }

    /// Moves q by the predictor over the step h (see the module docs): q + h q̇ alone when q̈
    /// was not solved at the current position, else q + h q̇ + c₀ q̈ + c₁ q̈₁ + c₂ q̈₂ with the
    /// weights of [`acceleration_weights`] for the history q̈₁, q̈₂ at hand, in one pass.
    fn predict(&mut self, h: R) {
        if self.known != Known::Acceleration {
            for (q, &qd) in self.q.iter_mut().zip(&self.qd) {
                *q += h * qd;
            }
            return;
        }
        // A history entry that is missing or unusable gets the weight 0; q̈ then stands in for
        // it so that the pass stays the same (q̈ is finite: it was solved and checked).
        let (tau1, a1) = match self.history.get(0) {
            Some((t1, a1)) => (t1 - self.t, a1),
            None => (R::ZERO, &self.qdd),
        };
        let (tau2, a2) = match self.history.get(1) {
            Some((t2, a2)) => (t2 - self.t, a2),
            None => (tau1, &self.qdd),
        };
        let [c0, c1, c2] = acceleration_weights(h, tau1, tau2);
        for ((((q, &qd), &a0), &a1), &a2) in
            self.q.iter_mut().zip(&self.qd).zip(&self.qdd).zip(a1).zip(a2)
        {
            *q += h * qd + c0 * a0 + c1 * a1 + c2 * a2;
        }
    }

    /// Solves Φ_q q̇ = ν at the converged position, with the factors kept by
    /// [`Solver::position`].
    ///
    /// Evaluates ν only: no Jacobian, no factorisation.
    ///
    /// # Errors
    ///
    /// [`SolveError::NoPosition`] without a converged position, [`SolveError::NonFinite`] if ν
    /// or q̇ is not finite (q̇ then keeps its previous value).
    pub fn velocity(&mut self) -> Result<(), SolveError> {
        if !self.factored {
            return Err(SolveError::NoPosition);
        }
        self.accepted.current = false;
        in_force!(self, m => m.velocity_rhs(&self.q, self.t, &mut self.scratch));
        self.solve_scratch();
        if !accept_finite(&mut self.qd, &self.scratch) {
            return Err(SolveError::NonFinite);
        }
        self.known = Known::Velocity;
        Ok(())
    }

    /// Solves Φ_q q̈ = γ at the converged position and velocity, with the factors kept by
    /// [`Solver::position`].
    ///
    /// Evaluates γ only: no Jacobian, no factorisation.
    ///
    /// # Errors
    ///
    /// [`SolveError::NoPosition`] without a converged position, [`SolveError::NoVelocity`] if
    /// [`Solver::velocity`] has not succeeded since, [`SolveError::NonFinite`] if γ or q̈ is not
    /// finite (q̈ then keeps its previous value).
    pub fn acceleration(&mut self) -> Result<(), SolveError> {
        if !self.factored {
            return Err(SolveError::NoPosition);
        }
        if self.known < Known::Velocity {
            return Err(SolveError::NoVelocity);
        }
        self.accepted.current = false;
        in_force!(self, m => m.acceleration_rhs(&self.q, &self.qd, self.t, &mut self.scratch));
        self.solve_scratch();
        if !accept_finite(&mut self.qdd, &self.scratch) {
            return Err(SolveError::NonFinite);
        }
        self.known = Known::Acceleration;
        Ok(())
    }

    /// [`Solver::velocity`] and [`Solver::acceleration`] right after a successful
    /// [`Solver::position`], solving in place: q̇ and q̈ hold no usable values after a failure,
    /// which the step control then undoes ([`Stepper::reject`]). This saves the copies that
    /// keep the previous values for a plain caller.
    fn solve_derivatives(&mut self) -> Result<(), SolveError> {
        in_force!(self, m => {
            m.velocity_rhs(&self.q, self.t, &mut self.qd);
            self.factors.solve(m, self.jac.borrow(), &mut self.qd);
        });
        if !newton::all_finite(&self.qd) {
            return Err(SolveError::NonFinite);
        }
        self.known = Known::Velocity;
        in_force!(self, m => {
            m.acceleration_rhs(&self.q, &self.qd, self.t, &mut self.qdd);
            self.factors.solve(m, self.jac.borrow(), &mut self.qdd);
        });
        if !newton::all_finite(&self.qdd) {
            return Err(SolveError::NonFinite);
        }
        self.known = Known::Acceleration;
        Ok(())
    }

    /// Overwrites the right-hand side in `scratch` with the solution of Φ_q x = scratch.
    ///
    /// A NaN or an infinity in the right-hand side reaches the solution (substitution carries
    /// it through the row that holds it), so checking the solution alone catches both
    /// ([`accept_finite`]).
    fn solve_scratch(&mut self) {
        in_force!(self, m => self.factors.solve(m, self.jac.borrow(), &mut self.scratch));
    }
}

/// Copies the solution `x` into `dst` and returns true when every entry is finite; otherwise
/// leaves `dst` as it was and returns false.
///
/// Entry by entry, each behind its test (a branch always taken the same way): `x` was just
/// written entry by entry by the solve, and the 16-byte loads of two entries that a copy or a
/// branch-free test of the whole array compiles to cannot take them from the processor's store
/// buffer (store-to-load forwarding needs one store to cover the load), so they wait until the
/// stores reach the cache, on the step's critical path (about 6 ns of the R-S-S-R's 183 ns
/// step; BENCHMARKS.md, "R-S-S-R step").
fn accept_finite<R: Real, const N: usize>(dst: &mut [R; N], x: &[R; N]) -> bool {
    let before = *dst;
    for i in 0..N {
        let v = x[i];
        if !v.is_finite() {
            *dst = before;
            return false;
        }
        dst[i] = v;
    }
    true
}

/// The weights [c₀, c₁, c₂] of the accelerations q̈ at τ = 0 (the current position), τ₁ and
/// τ₂ (the two before it, times relative to the current one) in the predictor's
/// q(h) ≈ q + h q̇ + c₀ q̈ + c₁ q̈(τ₁) + c₂ q̈(τ₂).
///
/// With q̈(τ) ≈ q̈ + b τ + c τ², the parabola through the three accelerations, the predictor
/// is q + h q̇ + h²/2 q̈ + h³/6 b + h⁴/12 c; b and c are linear in the three accelerations
/// through the divided differences f₀₁ = (q̈ − q̈₁)/(0 − τ₁) and
/// f₀₁₂ = (f₀₁ − (q̈₁ − q̈₂)/(τ₁ − τ₂))/(0 − τ₂) (b = f₀₁ − τ₁ f₀₁₂, c = f₀₁₂), so the whole
/// predictor is one linear combination whose weights are computed once per step.
/// With τ₂ equal to τ₁ or 0 (no usable second entry) the line through two accelerations is
/// used (c = 0, c₂ = 0); with τ₁ = 0 (no usable history) q̈ alone (c₀ = h²/2, c₁ = c₂ = 0).
fn acceleration_weights<R: Real>(h: R, tau1: R, tau2: R) -> [R; 3] {
    let h2 = R::from_f64(0.5) * h * h;
    if tau1 == R::ZERO {
        return [h2, R::ZERO, R::ZERO];
    }
    let h3 = h * h * h / R::from_f64(6.0);
    let r01 = R::ONE / -tau1;
    if tau2 == tau1 || tau2 == R::ZERO {
        // h³/6 f₀₁ with f₀₁ = r₀₁ (q̈ − q̈₁).
        return [h2 + h3 * r01, -(h3 * r01), R::ZERO];
    }
    // h³/6 b + h⁴/12 c = h³/6 f₀₁ + (h⁴/12 − h³/6 τ₁) f₀₁₂, with
    // f₀₁₂ = r₀₂ (r₀₁ q̈ − (r₀₁ + r₁₂) q̈₁ + r₁₂ q̈₂).
    let h4 = h * h * h * h / R::from_f64(12.0);
    let (r12, r02) = (R::ONE / (tau1 - tau2), R::ONE / -tau2);
    let w = (h4 - h3 * tau1) * r02;
    [h2 + (h3 + w) * r01, -(h3 * r01 + w * (r01 + r12)), w * r12]
}

/// What [`Solver::advance_to`] did to reach the requested time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport<R = f64> {
    /// Newton steps spent on the way: sub-steps and rejected attempts included.
    pub iterations: u32,
    /// max |Φ_i| at the final q.
    pub residual: R,
    /// ρ = min |u_kk| / max |u_kk| of the LU of Φ_q at the final q ([`Solver::pivot_ratio`]), a
    /// cheap estimate of 1/κ(Φ_q).
    pub pivot_ratio: R,
    /// κ̂, the estimate of the condition number of Φ_q at the final q that the digits rule
    /// reads ([`Solver::condition`]).
    pub condition: R,
    /// The derivatives κ̂ cannot vouch for to six significant digits ([`step::suspect`]).
    pub suspect: Suspect,
}

/// Why one attempt of [`Solver::advance_to`] failed before the step control's own checks: the
/// cause of a [`Rejection`] and of a [`Stop`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AttemptError<R = f64> {
    /// Newton failed.
    Newton(NewtonError<R>),
    /// The velocity or acceleration solve failed.
    Solve(SolveError),
}

impl<R: Real> fmt::Display for AttemptError<R> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AttemptError::Newton(e) => e.fmt(f),
            AttemptError::Solve(e) => write!(f, "velocities or accelerations: {e}"),
        }
    }
}

impl<R: Real> core::error::Error for AttemptError<R> {}

impl<M: Mechanism<N, R>, const N: usize, R: Real, J: BorrowMut<[[R; N]; N]>> Solver<M, N, R, J> {
    /// Solves positions, velocities and accelerations at `t` under the step control of
    /// [`crate::step`], starting from the last point whose velocities and accelerations were
    /// solved (by this call or by [`Solver::velocity`] and [`Solver::acceleration`]).
    ///
    /// A step that is too large for the motion is taken in sub-steps, halved down to 2⁻²⁰ of
    /// the step while an attempt fails Newton, has a pivot ratio of Φ_q at most 1.5e-8 (√ε) or
    /// fails the Hermite continuity check, which a jump to another assembly branch fails. So
    /// `Ok` always means q, q̇ and q̈ at `t` on the branch the step started from. Before any
    /// such point (a new solver, or after [`Solver::set_q`]) the call solves `t` directly from
    /// the estimate, refusing only a singular result.
    ///
    /// An attempt costs what [`Solver::position`], [`Solver::velocity`] and
    /// [`Solver::acceleration`] cost, plus copies of the state and the continuity check: the
    /// pivot ratio is that of the factorisation [`Solver::position`] kept
    /// ([`Solver::pivot_ratio`]), refactored densely only within
    /// [`step::STRUCTURED_MARGIN`] of the singularity bound.
    ///
    /// # Errors
    ///
    /// The [`Stop`]: `branch_jump`, `singular` or `no_convergence` ([`Stop::trouble`]), at the
    /// requested time ([`Stop::t`]), with the time of the configuration closest to the failure
    /// ([`Stop::near`]). The solver then holds the last accepted sub-step ([`Solver::t`] tells
    /// when), on the starting branch with its q̇ and q̈, or its estimate before the first point,
    /// and a later call continues from there.
    ///
    /// # Example
    ///
    /// A unit crank driven to the angle t, Φ = (x² + y² − 1, x sin t − y cos t): the second
    /// row also holds half a turn away, at −(cos t, sin t), where Newton from (1, 0) converges
    /// after a jump of 179°. Step control sub-steps and stays on the crank's own branch.
    ///
    /// ```
    /// use runtime::{Mechanism, Solver};
    ///
    /// struct Crank;
    ///
    /// impl Mechanism<2> for Crank {
    ///     fn residual(&self, q: &[f64; 2], t: f64, phi: &mut [f64; 2]) {
    ///         *phi = [q[0] * q[0] + q[1] * q[1] - 1.0, q[0] * t.sin() - q[1] * t.cos()];
    ///     }
    ///     fn jacobian(&self, q: &[f64; 2], t: f64, jac: &mut [[f64; 2]; 2]) {
    ///         *jac = [[2.0 * q[0], 2.0 * q[1]], [t.sin(), -t.cos()]];
    ///     }
    ///     fn velocity_rhs(&self, q: &[f64; 2], t: f64, nu: &mut [f64; 2]) {
    ///         *nu = [0.0, -(q[0] * t.cos() + q[1] * t.sin())];
    ///     }
    ///     fn acceleration_rhs(&self, q: &[f64; 2], qd: &[f64; 2], t: f64, g: &mut [f64; 2]) {
    ///         let (s, c) = t.sin_cos();
    ///         let ([x, y], [xd, yd]) = (*q, *qd);
    ///         *g = [-2.0 * (xd * xd + yd * yd), -2.0 * (c * xd + s * yd) + x * s - y * c];
    ///     }
    /// }
    ///
    /// let t = 179f64.to_radians();
    /// let mut plain = Solver::new(Crank, [1.0, 0.0]);
    /// plain.position(0.0)?;
    /// plain.position(t)?; // Ok, but half a turn off
    /// assert!((plain.q()[0] + t.cos()).abs() < 1e-9);
    ///
    /// let mut solver = Solver::new(Crank, [1.0, 0.0]);
    /// solver.advance_to(0.0)?;
    /// solver.advance_to(t)?; // on the branch it started from
    /// assert!((solver.q()[0] - t.cos()).abs() < 1e-9 && (solver.q()[1] - t.sin()).abs() < 1e-9);
    /// assert!((solver.qd()[0] + t.sin()).abs() < 1e-9);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn advance_to(&mut self, t: R) -> Result<StepReport<R>, Stop<R, AttemptError<R>>> {
        let start = self.start_sample();
        let current = self.accepted.current;
        let reached = self.advance_from(start, current, t)?;
        let condition = self.condition();
        Ok(StepReport { condition, suspect: step::suspect(condition, R::EPSILON), ..reached })
    }

    /// [`Solver::advance_to`] without the condition estimate, from the sample `start` of the
    /// current point (`current`: the copy of it is already kept).
    fn advance_from(
        &mut self,
        start: Option<Sample<R>>,
        current: bool,
        t: R,
    ) -> Result<StepReport<R>, Stop<R, AttemptError<R>>> {
        let mut control = Controlled { solver: self, candidate: start };
        // The copy of the start point is already there when the last call ended on it.
        if !current {
            control.accept();
        }
        let report = |s: Sample<R>, iterations| StepReport {
            iterations,
            residual: s.residual,
            pivot_ratio: s.pivot_ratio,
            condition: R::NAN,
            suspect: Suspect::default(),
        };
        match start {
            None => step::first(&mut control, t).map(|s| report(s, s.iterations)),
            Some(a) => step::advance(&mut control, a, t).map(|(s, n)| report(s, n)),
        }
    }

    /// The sample of the current point, when its q̇ and q̈ are known: the one the step control
    /// accepted there, or, after plain [`Solver::position`] steps, a new one.
    fn start_sample(&mut self) -> Option<Sample<R>> {
        if self.known != Known::Acceleration {
            return None;
        }
        let a = &self.accepted;
        if a.valid && a.current {
            return Some(a.sample);
        }
        in_force!(self, m => m.residual(&self.q, self.t, &mut self.scratch));
        let residual = newton::max_abs(&self.scratch);
        let pivot_ratio = self.pivot_ratio();
        Some(Sample { t: self.t, iterations: 0, residual, pivot_ratio })
    }

    /// ρ = min |u_kk| / max |u_kk| of Φ_q at the current (q, t), as the step control reads it
    /// ([`crate::step`]): that of the factors [`Solver::position`] kept, unless they come from a
    /// static pivot order and ρ is at most [`step::STRUCTURED_MARGIN`] times the singularity
    /// bound ([`step::singular_ratio`]), or no factors are held: then Φ_q is evaluated in full
    /// and factored by dense LU with partial pivoting, whose ratio is returned and whose
    /// factors the solver keeps (so [`Solver::velocity`] still works). NaN when that
    /// factorisation meets a non-finite entry.
    ///
    /// Away from singular configurations this costs nothing: the ratio of a static order lies
    /// within a small factor of dense LU's (see [`step::STRUCTURED_MARGIN`]), and both estimate
    /// 1/κ(Φ_q).
    pub fn pivot_ratio(&mut self) -> R {
        if self.factored {
            let ratio = self.pivots.smallest / self.pivots.largest;
            let confirm = step::structured_floor::<R>();
            if !self.factors.holds_structured() || ratio > confirm {
                return ratio;
            }
        }
        self.dense_pivot_ratio()
    }

    /// κ̂, the estimate of the condition number κ(Φ_q) at the current (q, t) that the digits
    /// rule reads ([`step::suspect`]): max |u_kk| / min |u_kk| of the factors
    /// [`Solver::position`] kept while that is below [`step::suspect_condition`] /
    /// [`step::CONDITION_MARGIN`] (103 in f64), and
    /// from there on (or when no factors are held) that of the dense LU of Φ_q equilibrated by
    /// powers of two ([`Factors::factor_dense_equilibrated`], whose factors the solver then
    /// keeps). Infinite when Φ_q has an exactly zero pivot, NaN when it holds a NaN.
    ///
    /// The factors a static pivot order or plain dense LU leaves are those of Φ_q in the
    /// description's units, whose pivots spread with the length of the links (by about L for
    /// links of length L); the equilibrated ones do not, so a step is flagged for what Φ_q is,
    /// not for the unit it is written in. Below the margin the cheap estimate cannot hide a
    /// flag (see [`step::CONDITION_MARGIN`]), and a regular step pays nothing for it.
    pub fn condition(&mut self) -> R {
        if N == 0 {
            // No unknowns: Φ_q is empty, as well conditioned as the identity.
            return R::ONE;
        }
        if self.factored {
            let cheap = self.pivots.largest / self.pivots.smallest;
            // cheap < suspect_condition / CONDITION_MARGIN, without the cube root.
            let k = cheap.to_f64() * step::CONDITION_MARGIN;
            if k * k * k * R::EPSILON.to_f64() < step::DIGITS {
                return cheap;
            }
        }
        let jac = self.jac.borrow_mut();
        let result = in_force!(self, m => {
            self.factors.factor_dense_equilibrated(m, &self.q, self.t, jac)
        });
        self.factored = result.is_ok();
        match result {
            Ok([plain, equilibrated]) => {
                self.pivots = plain;
                equilibrated.largest / equilibrated.smallest
            }
            Err(Singular::SmallPivot { .. }) => R::INFINITY,
            Err(_) => R::NAN,
        }
    }

    /// ρ of the dense LU with partial pivoting of Φ_q at the current (q, t), whose factors the
    /// solver keeps.
    fn dense_pivot_ratio(&mut self) -> R {
        let jac = self.jac.borrow_mut();
        let result =
            in_force!(self, m => self.factors.factor_dense(m, &self.q, self.t, jac, R::ZERO));
        self.factored = result.is_ok();
        match result {
            Ok(p) => {
                self.pivots = p;
                p.smallest / p.largest
            }
            Err(Singular::SmallPivot { pivot, largest, .. }) => pivot / largest,
            Err(_) => R::NAN,
        }
    }
}

/// A [`Solver`] under the step control: the candidate is the solver's own state, the accepted
/// point its copy in [`Accepted`].
struct Controlled<'s, M, const N: usize, R, J> {
    solver: &'s mut Solver<M, N, R, J>,
    /// The sample of the solver's state, when it is a solved point.
    candidate: Option<Sample<R>>,
}

impl<M: Mechanism<N, R>, const N: usize, R: Real, J: BorrowMut<[[R; N]; N]>> Stepper<R>
    for Controlled<'_, M, N, R, J>
{
    type Cause = AttemptError<R>;

    fn attempt(&mut self, t: R) -> Result<Sample<R>, Rejection<R, AttemptError<R>>> {
        self.candidate = None;
        let s = &mut *self.solver;
        // A failure here is undone by `reject`, which restores the accepted point: no copies.
        let report = s.solve_position(t).map_err(|e| {
            let trouble = match e {
                NewtonError::Singular { .. } => Trouble::Singular,
                _ => Trouble::NoConvergence,
            };
            Rejection::engine(trouble, AttemptError::Newton(e))
        })?;
        if let Err(e) = s.solve_derivatives() {
            return Err(Rejection::engine(Trouble::Singular, AttemptError::Solve(e)));
        }
        let pivot_ratio = s.pivot_ratio();
        let sample =
            Sample { t, iterations: report.iterations, residual: report.residual, pivot_ratio };
        self.candidate = Some(sample);
        Ok(sample)
    }

    fn accepted(&self) -> Coordinates<'_, R> {
        let a = &self.solver.accepted;
        Coordinates { q: &a.q, qd: &a.qd, qdd: &a.qdd }
    }

    fn candidate(&self) -> Coordinates<'_, R> {
        let s = &self.solver;
        Coordinates { q: &s.q, qd: &s.qd, qdd: &s.qdd }
    }

    fn groups(&self) -> Groups<'_> {
        self.solver.groups
    }

    fn accept(&mut self) {
        let s = &mut *self.solver;
        let a = &mut s.accepted;
        a.q = s.q;
        a.qd = s.qd;
        a.qdd = s.qdd;
        a.history = s.history.clone();
        a.known = s.known;
        a.valid = self.candidate.is_some();
        a.sample = self.candidate.unwrap_or(Sample { t: s.t, ..a.sample });
        a.current = true;
    }

    fn reject(&mut self) {
        let s = &mut *self.solver;
        let a = &s.accepted;
        s.q = a.q;
        s.qd = a.qd;
        s.qdd = a.qdd;
        s.history = a.history.clone();
        s.known = a.known;
        s.t = a.sample.t;
        s.factored = false;
        s.factors.forget();
        s.accepted.current = true;
    }
}
