use approx::assert_relative_eq;

use super::*;
use crate::fixtures::CircleLine;

/// The outcome of one Newton solve together with its storage.
struct Run {
    result: Result<NewtonReport, NewtonError>,
    q: [f64; 2],
    phi: [f64; 2],
    jac: [[f64; 2]; 2],
    factors: Factors<2>,
}

fn run(mechanism: &CircleLine, q: [f64; 2], t: f64, options: &NewtonOptions) -> Run {
    let mut run = Run { q, ..BLANK };
    run.result =
        solve(mechanism, &mut run.q, t, options, &mut run.phi, &mut run.jac, &mut run.factors);
    run
}

const BLANK: Run = Run {
    result: Ok(NewtonReport {
        iterations: 0,
        residual: 0.0,
        pivots: crate::lu::PivotInfo { smallest: 0.0, largest: 0.0 },
    }),
    q: [0.0; 2],
    phi: [f64::NAN; 2],
    jac: [[f64::NAN; 2]; 2],
    factors: Factors::new(),
};

fn check_status(residual: f64, iterations: u32, expected: Status) {
    let options = NewtonOptions { tolerance: 1e-10, max_iterations: 3, pivot_ratio: 1e-12 };
    assert_eq!(status(residual, iterations, &options), expected, "{residual:e} after {iterations}");
}

#[test]
fn status_converges_at_and_below_the_tolerance() {
    check_status(0.0, 0, Status::Converged);
    check_status(1e-10, 1, Status::Converged);
    check_status(1e-11, 2, Status::Converged);
}

#[test]
fn status_continues_above_the_tolerance_while_steps_are_left() {
    check_status(1.0000001e-10, 0, Status::Continue);
    check_status(1e3, 2, Status::Continue);
}

#[test]
fn status_is_exhausted_after_max_iterations_unless_converged() {
    check_status(2e-10, 3, Status::Exhausted);
    check_status(2e-10, 4, Status::Exhausted);
    check_status(1e-10, 3, Status::Converged);
}

#[test]
fn status_flags_nan_and_infinity_first() {
    check_status(f64::NAN, 0, Status::NonFinite);
    check_status(f64::INFINITY, 3, Status::NonFinite);
}

#[test]
fn default_options_are_the_documented_values() {
    let options = NewtonOptions::default();
    assert_eq!(options, NewtonOptions { tolerance: 1e-10, max_iterations: 25, pivot_ratio: 1e-12 });
}

#[test]
fn max_abs_keeps_nan() {
    assert_eq!(max_abs(&[1.0, -3.0, 2.0]), 3.0);
    assert!(max_abs(&[1.0, f64::NAN, 2.0]).is_nan());
    assert_eq!(max_abs::<f64>(&[]), 0.0);
}

/// The short path detects NaN by the sum of the |x_i|: a sum that overflows, or infinite
/// entries of both signs, must give the largest |x_i| and not NaN, and a NaN anywhere must
/// give NaN, in both precisions and on both sides of the 64-entry switch.
#[test]
fn max_abs_tells_overflow_and_infinities_from_nan() {
    assert_eq!(max_abs(&[f64::MAX, -f64::MAX, 1.0]), f64::MAX);
    assert_eq!(max_abs(&[f64::INFINITY, f64::NEG_INFINITY, 2.0]), f64::INFINITY);
    assert_eq!(max_abs(&[f32::MAX, f32::MAX, -f32::MAX]), f32::MAX);
    assert!(max_abs(&[f64::INFINITY, f64::NAN]).is_nan());
    assert!(max_abs(&[-f32::NAN, 1.0]).is_nan());
    let mut x = [-1.5; 100];
    for v in x.iter_mut().step_by(2) {
        *v = f64::MAX;
    }
    for n in [1, 5, 63, 64, 100] {
        assert_eq!(max_abs(&x[..n]), f64::MAX, "{n} entries");
        for k in [0, n / 2, n - 1] {
            let mut y = x;
            y[k] = f64::NAN;
            assert!(max_abs(&y[..n]).is_nan(), "NaN at {k} of {n}");
        }
    }
}

#[test]
fn converges_from_perturbed_starts_to_the_closed_form() {
    let options = NewtonOptions::default();
    for t in [0.3, 0.8, 1.5, 2.2, 2.8] {
        let [exact, _, _] = CircleLine::exact(t);
        for (dx, dy) in [(0.1, -0.2), (-0.15, 0.1), (0.02, 0.3)] {
            let m = CircleLine::default();
            let run = run(&m, [exact[0] + dx, exact[1] + dy], t, &options);
            let report = run.result.unwrap();
            // Quadratic convergence from within 0.3 of the root takes a handful of steps.
            assert!((1..=6).contains(&report.iterations), "t = {t}: {report:?}");
            assert!(report.residual <= options.tolerance);
            // |Δq| ≲ |Φ| / σ_min(Φ_q) ≤ 1e-10 / 0.3 here; after the last quadratic step the
            // error is far smaller still.
            assert_relative_eq!(run.q[0], exact[0], epsilon = 1e-9);
            assert_relative_eq!(run.q[1], exact[1], epsilon = 1e-9);
            // One joint evaluation per step, one at the converged q, none for normalize (a no-op
            // here, so q does not move).
            assert_eq!(m.jacobians.get(), report.iterations + 1);
            assert_eq!(m.normalizations.get(), 1);
        }
    }
}

#[test]
fn converged_start_takes_no_step_even_with_max_iterations_0() {
    let t = 1.0;
    let [exact, _, _] = CircleLine::exact(t);
    let options = NewtonOptions { max_iterations: 0, ..NewtonOptions::default() };
    let run = run(&CircleLine::default(), exact, t, &options);
    let report = run.result.unwrap();
    assert_eq!(report.iterations, 0);
    assert!(report.residual <= 1e-15, "{report:?}");
    assert_eq!(run.q, exact);
}

#[test]
fn one_iteration_from_far_away_is_not_converged() {
    let options = NewtonOptions { max_iterations: 1, ..NewtonOptions::default() };
    let run = run(&CircleLine::default(), [3.0, 3.0], 1.0, &options);
    let Err(NewtonError::NotConverged { iterations, residual }) = run.result else {
        panic!("expected NotConverged, got {:?}", run.result);
    };
    assert_eq!(iterations, 1);
    // One step puts x on the line (that row is linear) but leaves y ≈ 2.63, so the circle
    // residual is still about 6.
    assert!(residual > 1.0 && residual.is_finite(), "{residual}");
    assert_eq!(residual, max_abs(&run.phi));
}

#[test]
fn start_on_the_x_axis_is_singular_at_iteration_0() {
    // Φ_q = [[2x, 0], [1, 0]] has a zero second column.
    let run = run(&CircleLine::default(), [1.2, 0.0], 0.5, &NewtonOptions::default());
    assert_eq!(
        run.result,
        Err(NewtonError::Singular { iteration: 0, column: 1, pivot: 0.0, largest: 2.4 })
    );
}

#[test]
fn pivot_ratio_option_decides_singularity() {
    // Φ_q = [[2, 2e-7], [1, 0]] has pivots 2 and 1e-7, a ratio of 5e-8.
    let start = [1.0, 1e-7];
    let strict = NewtonOptions { pivot_ratio: 1e-6, max_iterations: 1, ..NewtonOptions::default() };
    assert!(matches!(
        run(&CircleLine::default(), start, 0.5, &strict).result,
        Err(NewtonError::Singular { iteration: 0, column: 1, .. })
    ));
    // The default ratio accepts the Jacobian; the one allowed step, of length about 1e6, then
    // lands far from the circle.
    let lax = NewtonOptions { max_iterations: 1, ..NewtonOptions::default() };
    assert!(matches!(
        run(&CircleLine::default(), start, 0.5, &lax).result,
        Err(NewtonError::NotConverged { iterations: 1, .. })
    ));
}

#[test]
fn nan_time_is_non_finite_at_iteration_0() {
    let run = run(&CircleLine::default(), [0.5, 0.5], f64::NAN, &NewtonOptions::default());
    assert_eq!(run.result, Err(NewtonError::NonFinite { iteration: 0 }));
}

#[test]
fn infinite_start_is_non_finite_at_iteration_0() {
    let run = run(&CircleLine::default(), [f64::INFINITY, 0.5], 1.0, &NewtonOptions::default());
    assert_eq!(run.result, Err(NewtonError::NonFinite { iteration: 0 }));
}

#[test]
fn after_normalize_residual_and_factors_belong_to_the_final_q() {
    let t = 1.0;
    // A loose tolerance leaves q off the circle when Newton stops, so the projection moves it.
    let options = NewtonOptions { tolerance: 1e-3, ..NewtonOptions::default() };
    let m = CircleLine::projected();
    let run = run(&m, [0.6, 0.9], t, &options);
    let report = run.result.unwrap();
    assert_eq!(m.normalizations.get(), 1);
    // One evaluation per step, one where Newton stopped, one again after the projection.
    assert_eq!(m.jacobians.get(), report.iterations + 2);
    // The projection put q on the circle, to rounding.
    assert_relative_eq!(run.q[0].hypot(run.q[1]), 1.0, epsilon = 1e-15);

    let mut phi = [0.0; 2];
    m.residual(&run.q, t, &mut phi);
    assert_eq!(run.phi, phi);
    assert_eq!(report.residual, max_abs(&phi));

    // The factors left in `jac` and `factors` are those of Φ_q at the final q.
    let mut jac = [[0.0; 2]; 2];
    m.jacobian(&run.q, t, &mut jac);
    let mut x = [1.0, 2.0];
    run.factors.solve(&m, &run.jac, &mut x);
    let back = [jac[0][0] * x[0] + jac[0][1] * x[1], jac[1][0] * x[0] + jac[1][1] * x[1]];
    assert_relative_eq!(back[0], 1.0, epsilon = 1e-14);
    assert_relative_eq!(back[1], 2.0, epsilon = 1e-14);
}

/// [`CircleLine`] with its line row scaled by 1e8, so that the small move of x made by the
/// radial projection shows up as a line residual far above the tolerance.
struct StiffLine(CircleLine);

const STIFFNESS: f64 = 1e8;

impl Mechanism<2> for StiffLine {
    fn residual(&self, q: &[f64; 2], t: f64, phi: &mut [f64; 2]) {
        self.0.residual(q, t, phi);
        phi[1] *= STIFFNESS;
    }

    fn jacobian(&self, q: &[f64; 2], t: f64, jac: &mut [[f64; 2]; 2]) {
        self.0.jacobian(q, t, jac);
        jac[1] = jac[1].map(|d| d * STIFFNESS);
    }

    fn velocity_rhs(&self, q: &[f64; 2], t: f64, nu: &mut [f64; 2]) {
        self.0.velocity_rhs(q, t, nu);
        nu[1] *= STIFFNESS;
    }

    fn acceleration_rhs(&self, q: &[f64; 2], qd: &[f64; 2], t: f64, gamma: &mut [f64; 2]) {
        self.0.acceleration_rhs(q, qd, t, gamma);
        gamma[1] *= STIFFNESS;
    }

    fn normalize(&self, q: &mut [f64; 2]) {
        self.0.normalize(q);
    }
}

#[test]
fn a_projection_that_breaks_the_tolerance_is_followed_by_more_steps() {
    let t = 1.0;
    // After two steps the line row is exact and the circle residual 1.5e-5 ≤ 1e-4, three
    // steps leave it at about (1.5e-5)² ≈ 2e-10 (the stopping test asks for round-off, and
    // takes one more step at most); projecting then moves x by about x · 1e-10 ≈ 5e-11,
    // which the stiff line row turns into a residual of about 5e-3 > 1e-4, so Newton must
    // step again.
    let options = NewtonOptions { tolerance: 1e-4, ..NewtonOptions::default() };
    let m = StiffLine(CircleLine::projected());
    let mut run = BLANK;
    run.q = [0.6, 0.9];
    let report =
        solve(&m, &mut run.q, t, &options, &mut run.phi, &mut run.jac, &mut run.factors).unwrap();
    assert_eq!(m.0.normalizations.get(), 2);
    assert_eq!(report.iterations, 4);
    assert!(report.residual <= options.tolerance);
    let mut phi = [0.0; 2];
    m.residual(&run.q, t, &mut phi);
    assert_eq!(report.residual, max_abs(&phi));
    // The last thing done to q was the projection.
    assert_relative_eq!(run.q[0].hypot(run.q[1]), 1.0, epsilon = 1e-15);
}

#[test]
fn moves_of_a_few_ulps_are_round_off() {
    let e = f64::EPSILON;
    let before = [1.0, 0.0, -2.0, 0.5];
    assert!(moved_by_round_off(&before, &before));
    assert!(moved_by_round_off(&before, &[1.0 + 2.0 * e, 0.0, -2.0 * (1.0 + e), 0.5 * (1.0 - e)]));
    assert!(!moved_by_round_off(&before, &[1.0 + 8.0 * e, 0.0, -2.0, 0.5]));
    // A zero coordinate may not move at all.
    assert!(!moved_by_round_off(&before, &[1.0, 1e-300, -2.0, 0.5]));
    assert!(!moved_by_round_off(&before, &[1.0, 0.0, f64::NAN, 0.5]));
}

#[test]
fn a_projection_by_round_off_is_not_followed_by_another_evaluation() {
    let t = 1.0;
    let [exact, _, _] = CircleLine::exact(t);
    // A tight tolerance makes Newton step until the circle row is exact to rounding, so the
    // projection then moves q by an ulp at most.
    let options = NewtonOptions { tolerance: 1e-14, ..NewtonOptions::default() };
    let m = CircleLine::projected();
    let run = run(&m, [exact[0] + 1e-3, exact[1] - 1e-3], t, &options);
    let report = run.result.unwrap();
    assert_eq!(m.normalizations.get(), 1);
    assert_eq!(m.jacobians.get(), report.iterations + 1);
    assert!(report.residual <= options.tolerance);
    let mut phi = [0.0; 2];
    m.residual(&run.q, t, &mut phi);
    // The reported residual is that of q before its round-off move; Φ at the final q is as
    // small, to rounding.
    assert!(max_abs(&phi) <= options.tolerance, "{phi:?}");
}

/// Converges at `t_old` from its exact solution (leaving the factors of Φ_q there in the run's
/// storage), then solves at `t` from `start` with a chord step first.
fn chord_run(m: &CircleLine, t_old: f64, t: f64, start: [f64; 2], options: &NewtonOptions) -> Run {
    let mut run = run(m, CircleLine::exact(t_old)[0], t_old, options);
    run.result.unwrap();
    run.q = start;
    m.jacobians.set(0);
    run.result =
        solve_with_chord(m, &mut run.q, t, options, &mut run.phi, &mut run.jac, &mut run.factors);
    run
}

#[test]
fn a_chord_step_corrects_only_starts_that_meet_the_tolerance() {
    let options = NewtonOptions { tolerance: 1e-8, ..NewtonOptions::default() };
    let (t_old, t) = (1.0, 1.01);
    let exact = CircleLine::exact(t)[0];
    // 1e-7 off, the start does not meet the tolerance: plain Newton, Φ_q evaluated at every
    // step and at the end.
    let m = CircleLine::default();
    let run = chord_run(&m, t_old, t, [exact[0] + 1e-7, exact[1] - 1e-7], &options);
    let report = run.result.unwrap();
    assert_eq!(m.jacobians.get(), report.iterations + 1);
    // An exact start is corrected by one chord step (which does no harm) ...
    let run = chord_run(&CircleLine::default(), t_old, t, exact, &options);
    assert_eq!(run.result.unwrap().iterations, 1);
    assert_eq!(run.q, exact);
    // ... but not when no step is allowed.
    let none = NewtonOptions { max_iterations: 0, ..options };
    let run = chord_run(&CircleLine::default(), t_old, t, exact, &none);
    assert_eq!(run.result.unwrap().iterations, 0);
}

#[test]
fn a_chord_step_that_does_not_reduce_the_residual_is_undone() {
    // Factors from the lower half of the circle (t = −0.5, y < 0) point the chord step the
    // wrong way at t = 0.5: from 1e-4 above the solution, where the circle row is off by about
    // 1e-4 (within the tolerance 1e-3), it moves y up by as much again. The start is then
    // accepted as plain Newton accepts it, after the one (undone) step.
    let options = NewtonOptions { tolerance: 1e-3, ..NewtonOptions::default() };
    let exact = CircleLine::exact(0.5)[0];
    let start = [exact[0], exact[1] + 1e-4];
    let chord = chord_run(&CircleLine::default(), -0.5, 0.5, start, &options);
    let plain = run(&CircleLine::default(), start, 0.5, &options);
    let (c, p) = (chord.result.unwrap(), plain.result.unwrap());
    assert_eq!((c.iterations, p.iterations), (1, 0));
    assert_eq!(chord.q, start);
    assert_eq!(chord.q, plain.q);
}

#[test]
fn a_chord_step_ends_the_iteration_only_when_it_leaves_round_off() {
    let (t_old, t) = (1.0, 1.01);
    let exact = CircleLine::exact(t)[0];
    let options = NewtonOptions { tolerance: 1e-8, ..NewtonOptions::default() };
    // The chord step contracts the error by about |ΔΦ_q| ≈ 0.01 per step here. From 1e-13 off
    // it leaves about 1e-15 < 32 ε: done, with Φ_q evaluated and factored once.
    let m = CircleLine::default();
    let run = chord_run(&m, t_old, t, [exact[0] + 1e-13, exact[1] - 1e-13], &options);
    assert_eq!(run.result.unwrap().iterations, 1);
    assert_eq!(m.jacobians.get(), 1);
    // From 1e-9 off it leaves about 1e-11: within the tolerance, but not round-off, so a Newton
    // step follows.
    let m = CircleLine::default();
    let run = chord_run(&m, t_old, t, [exact[0] + 1e-9, exact[1] - 1e-9], &options);
    assert_eq!(run.result.unwrap().iterations, 2);
    assert_eq!(m.jacobians.get(), 2);
    assert_relative_eq!(run.q[0], exact[0], epsilon = 1e-15);
    assert_relative_eq!(run.q[1], exact[1], epsilon = 1e-15);
}

#[test]
fn a_step_that_meets_the_tolerance_but_leaves_more_than_round_off_is_followed_by_another() {
    // Near the x axis Φ_q is ill-conditioned (σ_min ≈ y = sin t = 0.01). From y off by
    // δ = 1e-5 (max |Φ_i| ≈ 2 y δ = 2e-7 above the tolerance 1e-8), a Newton step leaves
    // y off by e₁ = δ² / 2y = 5e-9 with a circle residual of only about δ² = 1e-10: the
    // tolerance is met, with an error 50 times the residual. One more step leaves
    // e₁² / 2y ≈ 1e-15 plus the rounding of the solve, ε / 2y ≈ 1e-14.
    let t = 0.01;
    let exact = CircleLine::exact(t)[0];
    let start = [exact[0], exact[1] + 1e-5];
    let options = NewtonOptions { tolerance: 1e-8, ..NewtonOptions::default() };
    let m = CircleLine::default();
    let two = run(&m, start, t, &options);
    assert_eq!(two.result.unwrap().iterations, 2);
    // A few times the rounding of the last solve (1e-14, above).
    assert!((two.q[1] - exact[1]).abs() < 1e-13, "{:e}", two.q[1] - exact[1]);
    assert!((two.q[0] - exact[0]).abs() < 1e-15, "{:e}", two.q[0] - exact[0]);
    // Φ_q evaluated at each of the three iterates, none again at the end (normalize is a no-op).
    assert_eq!(m.jacobians.get(), 3);
    // Allowed one step only, Newton stops at the tolerance, 5e-9 off as computed above
    // (within 10 %, the δ³ terms left out).
    let one = NewtonOptions { max_iterations: 1, ..options };
    let first = run(&CircleLine::default(), start, t, &one);
    assert_eq!(first.result.unwrap().iterations, 1);
    assert_relative_eq!(first.q[1] - exact[1], 5e-9, max_relative = 0.1);
}
