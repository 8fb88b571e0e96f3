extern crate std;

use std::boxed::Box;
use std::vec;

use approx::assert_relative_eq;

use super::*;
use crate::fixtures::{CircleLine, CircleLineF32, Empty};

/// Newton's tolerance is 1e-10 on residuals of unit size and Φ_q is well conditioned away from
/// the x axis (σ_min ≥ 0.3 for the times below), so positions, and the velocities and
/// accelerations solved at them, are within a few 1e-10 of the closed form.
const EPSILON: f64 = 1e-9;

/// Steps the circle-line system through `times` as a control loop would, checking q, q̇ and q̈
/// against the closed form, and returns the total number of Newton steps.
fn check_sweep(predictor: bool, times: impl Iterator<Item = f64>) -> u32 {
    let mut solver = Solver::new(CircleLine::default(), [0.9, 0.5]);
    solver.set_predictor(predictor);
    let mut steps = 0;
    for t in times {
        let report = solver.position(t).unwrap_or_else(|e| panic!("t = {t}: {e}"));
        steps += report.iterations;
        assert_eq!(solver.t(), t);
        solver.velocity().unwrap();
        solver.acceleration().unwrap();
        let [q, qd, qdd] = CircleLine::exact(t);
        for (name, got, want) in
            [("q", solver.q(), q), ("qd", solver.qd(), qd), ("qdd", solver.qdd(), qdd)]
        {
            assert_relative_eq!(got[0], want[0], epsilon = EPSILON);
            assert_relative_eq!(got[1], want[1], epsilon = EPSILON);
            assert!(got.iter().all(|v| v.is_finite()), "{name} at t = {t}");
        }
    }
    steps
}

/// 0.3, 0.35, …, 2.8: the upper half circle, away from the singular ends t = 0 and t = π.
fn sweep() -> impl Iterator<Item = f64> {
    (0..=50).map(|k| 0.3 + 0.05 * f64::from(k))
}

#[test]
fn sweep_matches_the_closed_form_without_predictor() {
    check_sweep(false, sweep());
}

#[test]
fn sweep_matches_the_closed_form_with_predictor() {
    check_sweep(true, sweep());
}

#[test]
fn predictor_saves_newton_steps() {
    let without = check_sweep(false, sweep());
    let with = check_sweep(true, sweep());
    // The predictor's error is O(h³) ≈ 1e-4 against O(h) ≈ 5e-2 for the previous q, which is
    // about one Newton step per time step.
    assert!(with + 40 <= without, "with {with}, without {without}");
}

/// Steps the circle-line system at the times `times` with the predictor on and Newton allowed no
/// step at all, so a position succeeds only where the predictor alone meets the tolerance;
/// returns the indices of the times where it did not.
fn misses_without_newton(tolerance: f64, times: &[f64]) -> std::vec::Vec<usize> {
    let mut solver = Solver::new(CircleLine::default(), CircleLine::exact(times[0])[0]);
    solver.set_predictor(true);
    let mut misses = vec![];
    for (k, &t) in times.iter().enumerate() {
        solver.set_options(NewtonOptions {
            tolerance,
            max_iterations: 0,
            ..NewtonOptions::DEFAULT
        });
        if solver.position(t).is_err() {
            misses.push(k);
            // Converge properly, so the next step starts from the solution again.
            solver.set_options(NewtonOptions { tolerance: 1e-15, ..NewtonOptions::DEFAULT });
            solver.position(t).unwrap();
        }
        solver.velocity().unwrap();
        solver.acceleration().unwrap();
    }
    misses
}

#[test]
fn predictor_order_grows_with_the_accelerations_solved() {
    // With h = 0.01 and derivatives of order 1, the residual at the predictor is about 8e-8
    // with q, q̇ and q̈ alone (error O(h³)), 2.5e-9 with the line through two accelerations
    // (O(h⁴)) and 5e-12 with the parabola through three (O(h⁵): 1.6e-13 at h = 0.005).
    let times: std::vec::Vec<f64> = (0..40).map(|k| 0.5 + 0.01 * f64::from(k)).collect();
    // Below the parabola's error, Newton is needed at every step after the start.
    assert_eq!(misses_without_newton(1e-12, &times).len(), times.len() - 1);
    // Above it, only at step 1 (one acceleration behind it) and step 2 (two), and at a few
    // steps where the errors left by uncorrected predictions have added up.
    let misses = misses_without_newton(1e-10, &times);
    assert_eq!(misses[..2], [1, 2]);
    assert!(misses.len() <= 6, "{misses:?}");
    // Above the line's error, step 2 is met too.
    let misses = misses_without_newton(1e-8, &times);
    assert_eq!(misses[0], 1);
    assert!(misses.len() <= 5 && !misses.contains(&2), "{misses:?}");
}

#[test]
fn predictor_handles_uneven_and_repeated_times() {
    // Alternating steps of 0.01 and 0.02: the divided differences take the spacing into
    // account, so the predictor alone still meets 1e-8 after the first two steps (its error is
    // about 2e-10 after a step of 0.02).
    let mut times: std::vec::Vec<f64> = vec![0.5];
    for k in 0..30 {
        let h = if k % 2 == 0 { 0.01 } else { 0.02 };
        times.push(times[k] + h);
    }
    assert_eq!(misses_without_newton(1e-8, &times), [1, 2]);
    // A repeated time has no usable spacing behind it; the predictor then drops the history
    // terms rather than dividing by zero.
    let repeated = [0.5, 0.51, 0.52, 0.52, 0.53, 0.54];
    let mut solver = Solver::new(CircleLine::default(), CircleLine::exact(0.5)[0]);
    solver.set_predictor(true);
    for t in repeated {
        solver.position(t).unwrap();
        solver.velocity().unwrap();
        solver.acceleration().unwrap();
        assert!(solver.q().iter().all(|x| x.is_finite()));
    }
}

#[test]
fn predictor_without_solved_velocities_starts_from_the_last_q() {
    let mut plain = Solver::new(CircleLine::default(), [0.9, 0.5]);
    let mut predicted = Solver::new(CircleLine::default(), [0.9, 0.5]);
    predicted.set_predictor(true);
    for t in sweep() {
        assert_eq!(plain.position(t), predicted.position(t));
        assert_eq!(plain.q(), predicted.q());
    }
}

#[test]
fn velocity_and_acceleration_reuse_the_factorisation() {
    let mut solver = Solver::new(CircleLine::default(), [0.9, 0.5]);
    let report = solver.position(0.7).unwrap();
    let jacobians = solver.mechanism().jacobians.get();
    assert_eq!(jacobians, report.iterations + 1);
    solver.velocity().unwrap();
    solver.acceleration().unwrap();
    assert_eq!(solver.mechanism().jacobians.get(), jacobians);
}

#[test]
fn velocity_needs_a_converged_position() {
    let mut solver = Solver::new(CircleLine::default(), [0.9, 0.5]);
    assert_eq!(solver.velocity(), Err(SolveError::NoPosition));
    assert_eq!(solver.acceleration(), Err(SolveError::NoPosition));
    solver.position(0.7).unwrap();
    solver.velocity().unwrap();
    solver.set_q([0.8, 0.6]);
    assert_eq!(solver.velocity(), Err(SolveError::NoPosition));
}

#[test]
fn acceleration_needs_the_velocity_at_the_current_position() {
    let mut solver = Solver::new(CircleLine::default(), [0.9, 0.5]);
    solver.position(0.7).unwrap();
    assert_eq!(solver.acceleration(), Err(SolveError::NoVelocity));
    solver.velocity().unwrap();
    solver.acceleration().unwrap();
    // A new position makes the old velocity stale.
    solver.position(0.8).unwrap();
    assert_eq!(solver.acceleration(), Err(SolveError::NoVelocity));
}

#[test]
fn failed_position_leaves_the_state_as_it_was() {
    let mut solver = Solver::new(CircleLine::default(), [0.9, 0.5]);
    solver.set_predictor(true);
    solver.position(0.7).unwrap();
    solver.velocity().unwrap();
    solver.acceleration().unwrap();
    let before = (*solver.q(), *solver.qd(), *solver.qdd(), solver.t());

    // t = NaN makes Φ NaN, and the predictor's step h = NaN makes the start NaN too.
    assert_eq!(solver.position(f64::NAN), Err(NewtonError::NonFinite { iteration: 0 }));
    assert_eq!(before, (*solver.q(), *solver.qd(), *solver.qdd(), solver.t()));
    assert_eq!(solver.velocity(), Err(SolveError::NoPosition));

    // The predictor's history survives, so a retry at a nearby time starts close.
    let report = solver.position(0.75).unwrap();
    assert!(report.iterations <= 3, "{report:?}");
}

/// [`CircleLine`] whose velocity right-hand side is NaN, as a bad driver would give.
struct NanVelocity(CircleLine);

impl Mechanism<2> for NanVelocity {
    fn residual(&self, q: &[f64; 2], t: f64, phi: &mut [f64; 2]) {
        self.0.residual(q, t, phi);
    }

    fn jacobian(&self, q: &[f64; 2], t: f64, jac: &mut [[f64; 2]; 2]) {
        self.0.jacobian(q, t, jac);
    }

    fn velocity_rhs(&self, _q: &[f64; 2], _t: f64, nu: &mut [f64; 2]) {
        *nu = [0.0, f64::NAN];
    }

    fn acceleration_rhs(&self, q: &[f64; 2], qd: &[f64; 2], t: f64, gamma: &mut [f64; 2]) {
        self.0.acceleration_rhs(q, qd, t, gamma);
    }
}

#[test]
fn non_finite_velocity_rhs_is_an_error_and_keeps_qd() {
    let mut solver = Solver::new(NanVelocity(CircleLine::default()), [0.9, 0.5]);
    solver.position(0.7).unwrap();
    assert_eq!(solver.velocity(), Err(SolveError::NonFinite));
    assert_eq!(solver.qd(), &[0.0, 0.0]);
    assert_eq!(solver.acceleration(), Err(SolveError::NoVelocity));
}

/// A chain of `N` unknowns: q₀ = cos t and q_i² + q_{i−1}² = 1, so for 0 < t < π/2 the
/// solution near the start below is cos t at even i and sin t at odd i.
/// Φ_q is lower bidiagonal, so LU meets one nonzero multiplier per column.
struct Chain<const N: usize>;

impl<const N: usize> Chain<N> {
    fn exact(t: f64) -> [[f64; N]; 3] {
        let (s, c) = t.sin_cos();
        let alternate =
            |even: f64, odd: f64| core::array::from_fn(|i| if i % 2 == 0 { even } else { odd });
        [alternate(c, s), alternate(-s, c), alternate(-c, -s)]
    }
}

impl<const N: usize> Mechanism<N> for Chain<N> {
    fn residual(&self, q: &[f64; N], t: f64, phi: &mut [f64; N]) {
        phi[0] = q[0] - t.cos();
        for i in 1..N {
            phi[i] = q[i] * q[i] + q[i - 1] * q[i - 1] - 1.0;
        }
    }

    fn jacobian(&self, q: &[f64; N], _t: f64, jac: &mut [[f64; N]; N]) {
        for row in jac.iter_mut() {
            row.fill(0.0);
        }
        jac[0][0] = 1.0;
        for i in 1..N {
            jac[i][i - 1] = 2.0 * q[i - 1];
            jac[i][i] = 2.0 * q[i];
        }
    }

    fn velocity_rhs(&self, _q: &[f64; N], t: f64, nu: &mut [f64; N]) {
        nu.fill(0.0);
        nu[0] = -t.sin();
    }

    fn acceleration_rhs(&self, _q: &[f64; N], qd: &[f64; N], t: f64, gamma: &mut [f64; N]) {
        gamma[0] = -t.cos();
        for i in 1..N {
            gamma[i] = -2.0 * (qd[i] * qd[i] + qd[i - 1] * qd[i - 1]);
        }
    }
}

/// The constructors are `const fn`, so a solver can be built at compile time.
const SMALL_CHAIN: Solver<Chain<3>, 3> = Solver::new(Chain, [0.9, 0.5, 0.9]);

#[test]
fn const_solver_runs() {
    let mut solver = SMALL_CHAIN;
    solver.position(0.6).unwrap();
    let [q, _, _] = Chain::<3>::exact(0.6);
    for (got, want) in solver.q().iter().zip(q) {
        assert_relative_eq!(*got, want, epsilon = EPSILON);
    }
}

#[test]
fn borrowed_storage_gives_the_same_answers_as_owned_storage() {
    let mut storage = [[0.0; 2]; 2];
    let mut borrowed = Solver::with_storage(CircleLine::default(), [0.9, 0.5], &mut storage);
    let mut owned = Solver::new(CircleLine::default(), [0.9, 0.5]);
    for t in sweep() {
        assert_eq!(borrowed.position(t), owned.position(t));
        borrowed.velocity().unwrap();
        owned.velocity().unwrap();
        assert_eq!((borrowed.q(), borrowed.qd()), (owned.q(), owned.qd()));
    }
}

#[test]
fn a_700_unknown_chain_solves_with_heap_storage() {
    const N: usize = 700;
    // Built on the heap directly: the 3.9 MB Jacobian never passes through this thread's stack.
    let jac: Box<[[f64; N]; N]> = vec![[0.0; N]; N].into_boxed_slice().try_into().unwrap();
    let start = core::array::from_fn(|i| if i % 2 == 0 { 0.8 } else { 0.6 });
    let mut solver = Box::new(Solver::with_storage(Chain::<N>, start, jac));
    solver.set_predictor(true);
    for t in [0.5, 0.55, 0.6] {
        solver.position(t).unwrap();
        solver.velocity().unwrap();
        solver.acceleration().unwrap();
        let [q, qd, qdd] = Chain::<N>::exact(t);
        // Errors propagate along the chain but do not grow: each link maps (cos, sin) to
        // (sin, cos) with Jacobian entries of order one.
        for (got, want) in [(solver.q(), q), (solver.qd(), qd), (solver.qdd(), qdd)] {
            for (g, w) in got.iter().zip(want) {
                assert_relative_eq!(*g, w, epsilon = EPSILON);
            }
        }
    }
}

#[test]
fn a_mechanism_without_unknowns_is_trivially_solved() {
    let mut solver = Solver::new(Empty, []);
    let report = solver.position(1.0).unwrap();
    assert_eq!((report.iterations, report.residual), (0, 0.0));
    solver.velocity().unwrap();
    solver.acceleration().unwrap();
}

#[test]
fn single_precision_sweep_matches_the_closed_form() {
    // The same sweep in f32, with the f32 defaults (tolerance 1e-4, pivot ratio 1e-5).
    let mut solver: Solver<CircleLineF32, 2, f32> = Solver::new(CircleLineF32, [0.9, 0.5]);
    solver.set_predictor(true);
    let mut worst = [0.0_f64; 3];
    for step in 50..=250 {
        let t = 0.01 * f64::from(step);
        let report = solver.position(t as f32).unwrap();
        assert!(report.residual <= 1e-4);
        solver.velocity().unwrap();
        solver.acceleration().unwrap();
        // Compare with the closed form at the f32 time actually solved for.
        let exact = CircleLine::exact(f64::from(solver.t()));
        for (w, (got, want)) in
            worst.iter_mut().zip([solver.q(), solver.qd(), solver.qdd()].iter().zip(&exact))
        {
            for (g, e) in got.iter().zip(want) {
                *w = w.max((f64::from(*g) - e).abs());
            }
        }
    }
    // Newton stops at max |Φ| ≤ 1e-4, which leaves the position off by up to about 1e-4 over
    // the smallest singular value of Φ_q (≥ 0.43 over t ∈ [0.5, 2.5], away from the tangency
    // at y = 0), and q̇, q̈ follow from that q with f32 round-off (6e-8 relative) amplified by
    // the same conditioning.
    assert!(worst[0] < 1e-3, "positions off by {worst:?}");
    assert!(worst[1] < 2e-3 && worst[2] < 5e-3, "rates off by {worst:?}");
}

/// Φ = (q0 − t, d q1 − t): Φ_q = diag(1, d), whose LU by any pivoting has the pivots 1 and d, so
/// its pivot ratio is d (for d ≤ 1). One static order, the identity, as generated code would
/// write it (reciprocal pivots on the diagonal).
struct Diagonal {
    d: f64,
}

impl Mechanism<2> for Diagonal {
    const PIVOT_ORDERS: usize = 1;

    fn residual(&self, q: &[f64; 2], t: f64, phi: &mut [f64; 2]) {
        *phi = [q[0] - t, self.d * q[1] - t];
    }
    fn jacobian(&self, _q: &[f64; 2], _t: f64, jac: &mut [[f64; 2]; 2]) {
        *jac = [[1.0, 0.0], [0.0, self.d]];
    }
    fn velocity_rhs(&self, _q: &[f64; 2], _t: f64, nu: &mut [f64; 2]) {
        *nu = [1.0, 1.0];
    }
    fn acceleration_rhs(&self, _q: &[f64; 2], _qd: &[f64; 2], _t: f64, gamma: &mut [f64; 2]) {
        *gamma = [0.0; 2];
    }
    fn factor_structured(&self, order: usize, jac: &mut [[f64; 2]; 2]) -> Option<PivotInfo> {
        let (p0, p1) = (jac[0][0], jac[1][1]);
        if order != 0 || !(p0.is_finite() && p1.is_finite()) {
            return None;
        }
        (jac[0][0], jac[1][1]) = (1.0 / p0, 1.0 / p1);
        Some(PivotInfo { smallest: p0.abs().min(p1.abs()), largest: p0.abs().max(p1.abs()) })
    }
    fn solve_structured(&self, _order: usize, lu: &[[f64; 2]; 2], b: &mut [f64; 2]) {
        *b = [b[0] * lu[0][0], b[1] * lu[1][1]];
    }
}

/// [`Diagonal`] with d = 0.5 whose velocity (`velocity`) or acceleration right-hand side turns
/// non-finite in its last row after t = 1, so that a solve there gives a finite first entry,
/// other than before, and a non-finite last one.
struct LastRowBlowsUp {
    velocity: bool,
}

impl Mechanism<2> for LastRowBlowsUp {
    const PIVOT_ORDERS: usize = 1;

    fn residual(&self, q: &[f64; 2], t: f64, phi: &mut [f64; 2]) {
        Diagonal { d: 0.5 }.residual(q, t, phi);
    }
    fn jacobian(&self, q: &[f64; 2], t: f64, jac: &mut [[f64; 2]; 2]) {
        Diagonal { d: 0.5 }.jacobian(q, t, jac);
    }
    fn velocity_rhs(&self, _q: &[f64; 2], t: f64, nu: &mut [f64; 2]) {
        let blown = self.velocity && t > 1.0;
        *nu = if blown { [4.0, f64::INFINITY] } else { [1.0; 2] };
    }
    fn acceleration_rhs(&self, _q: &[f64; 2], _qd: &[f64; 2], t: f64, gamma: &mut [f64; 2]) {
        let blown = !self.velocity && t > 1.0;
        *gamma = if blown { [5.0, f64::NAN] } else { [2.0, 3.0] };
    }
    fn factor_structured(&self, order: usize, jac: &mut [[f64; 2]; 2]) -> Option<PivotInfo> {
        Diagonal { d: 0.5 }.factor_structured(order, jac)
    }
    fn solve_structured(&self, order: usize, lu: &[[f64; 2]; 2], b: &mut [f64; 2]) {
        Diagonal { d: 0.5 }.solve_structured(order, lu, b);
    }
}

#[test]
fn a_solution_non_finite_in_its_last_entry_leaves_every_entry_of_qd_and_qdd_as_it_was() {
    for velocity in [true, false] {
        let mut solver = Solver::new(LastRowBlowsUp { velocity }, [0.0; 2]);
        solver.position(0.5).unwrap();
        solver.velocity().unwrap();
        solver.acceleration().unwrap();
        // Φ_q = diag(1, 0.5): q̇ = (1, 2), q̈ = (2, 6).
        assert_eq!((solver.qd(), solver.qdd()), (&[1.0, 2.0], &[2.0, 6.0]));
        solver.position(1.5).unwrap();
        // The first entry of the solution, (4, ∞) or (5, NaN), is finite and copied before the
        // second is found non-finite: the copy is undone.
        if velocity {
            assert_eq!(solver.velocity(), Err(SolveError::NonFinite));
        } else {
            solver.velocity().unwrap();
            assert_eq!(solver.acceleration(), Err(SolveError::NonFinite));
        }
        assert_eq!((solver.qd(), solver.qdd()), (&[1.0, 2.0], &[2.0, 6.0]), "{velocity}");
    }
}

/// Steps `Diagonal { d }` under the step control and returns the last report and the counts.
fn diagonal_steps(d: f64) -> (StepReport, FactorCounts) {
    let mut solver = Solver::new(Diagonal { d }, [0.0; 2]);
    solver.set_predictor(true);
    let mut report = solver.advance_to(0.0).unwrap();
    for k in 1..=4 {
        report = solver.advance_to(0.1 * f64::from(k)).unwrap();
        // q1 = t / d exactly solves the linear system; one Newton step lands within round-off.
        assert_relative_eq!(solver.q()[1], 0.1 * f64::from(k) / d, max_relative = 1e-12);
    }
    (report, solver.factor_counts())
}

#[test]
fn the_step_control_reads_the_pivots_of_the_factors_it_kept() {
    // Far from the singularity bound the static order's pivots are the answer: no dense LU.
    let (report, counts) = diagonal_steps(0.5);
    assert_eq!(report.pivot_ratio, 0.5);
    assert_eq!(counts.dense, 0);
    assert!(counts.structured >= 5, "{counts:?}");
}

#[test]
fn near_the_singularity_bound_dense_lu_decides() {
    // ρ = 1e-7 is above the bound 1.5e-8 but within STRUCTURED_MARGIN (100) of it: every
    // accepted point is factored densely once more, and its ratio, d, is reported.
    const { assert!(1e-7 <= step::STRUCTURED_MARGIN * step::SINGULAR_RATIO) };
    let (report, counts) = diagonal_steps(1e-7);
    assert_eq!(report.pivot_ratio, 1e-7);
    assert!(counts.dense >= 5, "{counts:?}");
}

#[test]
fn the_condition_estimate_does_not_depend_on_units() {
    // diag(1, 1e-7) is diag(1, 1) in other units of q1: the pivots of Φ_q differ by 1e7, but
    // scaling its columns by powers of two makes both pivots equal within a factor of √2 each
    // (the nearest power of two), so κ̂ ≤ 2 and nothing is suspect. The step control's pivot
    // ratio stays that of Φ_q as written.
    let mut solver = Solver::new(Diagonal { d: 1e-7 }, [0.0; 2]);
    solver.advance_to(0.0).unwrap();
    let report = solver.advance_to(0.1).unwrap();
    assert_eq!(report.pivot_ratio, 1e-7);
    assert!((1.0..=2.0).contains(&report.condition), "{report:?}");
    assert_eq!(report.suspect, step::Suspect::default());
    // Where the cheap estimate is small, it is reported as it is: diag(1, 0.5) has κ = 2.
    let mut solver = Solver::new(Diagonal { d: 0.5 }, [0.0; 2]);
    let report = solver.advance_to(0.0).unwrap();
    assert_eq!(report.condition, 2.0);
}

/// q(t) = 1 + 2t − 3t² + 5t³ − 7t⁴ and its derivatives: a quartic, which the predictor with
/// the parabola through three accelerations reproduces exactly (its q̈ is a parabola).
fn quartic(t: f64) -> [f64; 3] {
    let q = 1.0 + t * (2.0 + t * (-3.0 + t * (5.0 - 7.0 * t)));
    let qd = 2.0 + t * (-6.0 + t * (15.0 - 28.0 * t));
    let qdd = -6.0 + t * (30.0 - 84.0 * t);
    [q, qd, qdd]
}

#[test]
fn acceleration_weights_reproduce_polynomial_motion() {
    // Uneven times: the current one at 0.3, the two before at 0.27 and 0.22, a step of 0.04.
    let (t0, t1, t2, h) = (0.3, 0.27, 0.22, 0.04);
    let [q, qd, a0] = quartic(t0);
    let (a1, a2) = (quartic(t1)[2], quartic(t2)[2]);
    let [c0, c1, c2] = acceleration_weights(h, t1 - t0, t2 - t0);
    let predicted = q + h * qd + c0 * a0 + c1 * a1 + c2 * a2;
    // Exact in exact arithmetic; the terms are of order 1, so a few ulps of 1 remain.
    assert_relative_eq!(predicted, quartic(t0 + h)[0], max_relative = 1e-14);

    // The line through two accelerations is exact for a cubic, q̈ alone for a parabola.
    let cubic = |t: f64| [t * t * t - t, 3.0 * t * t - 1.0, 6.0 * t];
    let [c0, c1, c2] = acceleration_weights(h, t1 - t0, t1 - t0);
    assert_eq!(c2, 0.0);
    let [q, qd, a0] = cubic(t0);
    let predicted = q + h * qd + c0 * a0 + c1 * cubic(t1)[2];
    // As above: terms of order 1, round-off of a few ulps.
    assert_relative_eq!(predicted, cubic(t0 + h)[0], max_relative = 1e-14);
    assert_eq!(acceleration_weights(h, 0.0, 0.0), [0.5 * h * h, 0.0, 0.0]);
    // A second entry at the current time is unusable: the line through two again.
    assert_eq!(acceleration_weights(h, t1 - t0, 0.0), acceleration_weights(h, t1 - t0, t1 - t0));
}

/// Φ(q, t) = q − p(t) with p the quartic above: the solver must follow p exactly.
struct Quartic;

impl Mechanism<1> for Quartic {
    fn residual(&self, q: &[f64; 1], t: f64, phi: &mut [f64; 1]) {
        phi[0] = q[0] - quartic(t)[0];
    }
    fn jacobian(&self, _q: &[f64; 1], _t: f64, jac: &mut [[f64; 1]; 1]) {
        jac[0][0] = 1.0;
    }
    fn velocity_rhs(&self, _q: &[f64; 1], t: f64, nu: &mut [f64; 1]) {
        nu[0] = quartic(t)[1];
    }
    fn acceleration_rhs(&self, _q: &[f64; 1], _qd: &[f64; 1], t: f64, gamma: &mut [f64; 1]) {
        gamma[0] = quartic(t)[2];
    }
}

#[test]
fn predictor_lands_on_a_quartic_motion_without_newton() {
    // Newton allowed no step (no chord step either): a position succeeds only where the
    // prediction alone meets the tolerance. From the fourth time on, the parabola through three
    // accelerations makes the prediction exact up to round-off, on steps of uneven size.
    let mut solver = Solver::new(Quartic, [quartic(0.1)[0]]);
    solver.set_predictor(true);
    solver.set_options(NewtonOptions { tolerance: 1e-13, ..NewtonOptions::DEFAULT });
    let mut t = 0.1;
    for k in 0..12 {
        if k == 3 {
            // Three accelerations are known from here on (those at the last three times).
            solver.set_options(NewtonOptions { max_iterations: 0, ..*solver.options() });
        }
        let report = solver.position(t).unwrap();
        if k >= 3 {
            assert_eq!(report.iterations, 0);
        }
        solver.velocity().unwrap();
        solver.acceleration().unwrap();
        // Values of order 1: 1e-13 is a few hundred ulps, far below the O(h⁵) ≈ 1e-7 of a
        // truncated predictor, so only an exact one meets it.
        assert_relative_eq!(solver.q()[0], quartic(t)[0], max_relative = 1e-13);
        t += if k % 2 == 0 { 0.03 } else { 0.05 };
    }
}

/// x = sin t (Φ = x − sin t) with the time terms [sin t, cos t], counting how often the terms
/// are computed and how often a plain evaluation computes them again.
#[derive(Default)]
struct TimedSlider {
    terms_computed: core::cell::Cell<u32>,
    plain: core::cell::Cell<u32>,
}

impl TimedSlider {
    fn count(&self, counter: &core::cell::Cell<u32>) {
        counter.set(counter.get() + 1);
    }
}

impl Mechanism<1> for TimedSlider {
    const TIME_TERMS: usize = 2;
    // One static order, so that the solvers evaluate Φ and Φ_q by
    // `residual_jacobian_structural`, as generated modules with time terms do.
    const PIVOT_ORDERS: usize = 1;
    fn factor_structured(&self, order: usize, jac: &mut [[f64; 1]; 1]) -> Option<PivotInfo> {
        let pivot = jac[0][0].abs();
        (order == 0).then_some(PivotInfo { smallest: pivot, largest: pivot })
    }
    fn solve_structured(&self, _order: usize, lu: &[[f64; 1]; 1], b: &mut [f64; 1]) {
        b[0] /= lu[0][0];
    }
    fn time_terms(&self, t: f64, terms: &mut [f64]) {
        self.count(&self.terms_computed);
        terms[..2].copy_from_slice(&[t.sin(), t.cos()]);
    }
    fn residual(&self, q: &[f64; 1], t: f64, phi: &mut [f64; 1]) {
        self.count(&self.plain);
        phi[0] = q[0] - t.sin();
    }
    fn residual_at(&self, q: &[f64; 1], _t: f64, terms: &[f64], phi: &mut [f64; 1]) {
        phi[0] = q[0] - terms[0];
    }
    fn jacobian(&self, _q: &[f64; 1], _t: f64, jac: &mut [[f64; 1]; 1]) {
        jac[0][0] = 1.0;
    }
    fn residual_jacobian_structural_at(
        &self,
        q: &[f64; 1],
        t: f64,
        terms: &[f64],
        phi: &mut [f64; 1],
        jac: &mut [[f64; 1]; 1],
    ) {
        self.residual_at(q, t, terms, phi);
        self.jacobian(q, t, jac);
    }
    fn velocity_rhs(&self, _q: &[f64; 1], t: f64, nu: &mut [f64; 1]) {
        self.count(&self.plain);
        nu[0] = t.cos();
    }
    fn velocity_rhs_at(&self, _q: &[f64; 1], _t: f64, terms: &[f64], nu: &mut [f64; 1]) {
        nu[0] = terms[1];
    }
    fn acceleration_rhs(&self, _q: &[f64; 1], _qd: &[f64; 1], t: f64, gamma: &mut [f64; 1]) {
        self.count(&self.plain);
        gamma[0] = -t.sin();
    }
    fn acceleration_rhs_at(
        &self,
        _q: &[f64; 1],
        _qd: &[f64; 1],
        _t: f64,
        terms: &[f64],
        gamma: &mut [f64; 1],
    ) {
        gamma[0] = -terms[0];
    }
}

#[test]
fn time_terms_are_computed_once_per_position_and_read_by_every_evaluation_at_its_time() {
    let mut solver = Solver::new(TimedSlider::default(), [0.0]);
    solver.set_predictor(true);
    for k in 0..=20 {
        let t = 0.05 * f64::from(k);
        solver.position(t).unwrap();
        solver.velocity().unwrap();
        solver.acceleration().unwrap();
        // Φ is linear in x: Newton (or the chord step) lands within round-off of sin t.
        assert_relative_eq!(solver.q()[0], t.sin(), epsilon = 1e-15);
        assert_relative_eq!(solver.qd()[0], t.cos(), epsilon = 1e-15);
        assert_relative_eq!(solver.qdd()[0], -t.sin(), epsilon = 1e-15);
        assert_eq!(solver.mechanism().terms_computed.get(), k + 1);
    }
    assert_eq!(solver.mechanism().plain.get(), 0);
    // After the mechanism may have changed, the terms are not trusted until the next position.
    let _ = solver.mechanism_mut();
    solver.velocity().unwrap();
    assert_eq!(solver.mechanism().plain.get(), 1);
    assert_relative_eq!(solver.qd()[0], 1.0f64.cos(), epsilon = 1e-15);
}
