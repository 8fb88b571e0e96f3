use super::*;
use crate::Solver;
use crate::step::Trouble;

/// The point (cos t, sin t) held by x − cos t = 0 and (y − sin t)(1 − cos t) = 0, whose second
/// row vanishes to second order at t = 0 (its Jacobian row is (0, 1 − cos t)), with the
/// left-out row y − sin t = 0, regular everywhere. `left_out` says whether the mechanism
/// declares that row.
struct Circle {
    left_out: bool,
}

impl Mechanism<2> for Circle {
    fn residual(&self, q: &[f64; 2], t: f64, phi: &mut [f64; 2]) {
        let (s, c) = t.sin_cos();
        *phi = [q[0] - c, (q[1] - s) * (1.0 - c)];
    }
    fn jacobian(&self, _q: &[f64; 2], t: f64, jac: &mut [[f64; 2]; 2]) {
        *jac = [[1.0, 0.0], [0.0, 1.0 - t.cos()]];
    }
    fn velocity_rhs(&self, q: &[f64; 2], t: f64, nu: &mut [f64; 2]) {
        let (s, c) = t.sin_cos();
        // ν = −Φ_t.
        *nu = [-s, c * (1.0 - c) - (q[1] - s) * s];
    }
    fn acceleration_rhs(&self, q: &[f64; 2], qd: &[f64; 2], t: f64, gamma: &mut [f64; 2]) {
        let (s, c) = t.sin_cos();
        // γ = −Φ̈ at q̈ = 0: Φ̈ = (ÿ + s)(1 − c) + 2 (ẏ − c) s + (y − s) c for the second row.
        *gamma = [-c, -(s * (1.0 - c) + 2.0 * (qd[1] - c) * s + (q[1] - s) * c)];
    }
    const LEFT_OUT: usize = 1;
    fn left_out_residual_jacobian(
        &self,
        q: &[f64; 2],
        t: f64,
        phi: &mut [f64],
        jac: &mut [[f64; 2]],
    ) {
        if self.left_out {
            phi[0] = q[1] - t.sin();
            jac[0] = [0.0, 1.0];
        } else {
            // A mechanism that leaves the row out and cannot give it: the stack is the kept rows
            // and a zero row.
            phi[0] = 0.0;
            jac[0] = [0.0, 0.0];
        }
    }
    fn left_out_velocity_rhs(&self, _q: &[f64; 2], t: f64, nu: &mut [f64]) {
        nu[0] = if self.left_out { t.cos() } else { 0.0 };
    }
    fn left_out_acceleration_rhs(&self, _q: &[f64; 2], _qd: &[f64; 2], t: f64, gamma: &mut [f64]) {
        gamma[0] = if self.left_out { -t.sin() } else { 0.0 };
    }
}

#[test]
fn the_stack_picks_the_left_out_row_where_a_kept_one_vanishes_and_keeps_the_kept_ones_elsewhere() {
    let mut jac = [[0.0; 2]; 2];
    let circle = Circle { left_out: true };
    // At t = 1 the kept rows are regular (pivots 1 and 1 − cos 1 = 0.46 before scaling): kept.
    let kept = select(&circle, &[1.0_f64.cos(), 1.0_f64.sin()], 1.0, &mut jac, 1e-12);
    assert_eq!(kept, Ok(Selection::KEPT));
    // At t = 0 the second kept row is zero: the left-out row stands in for it.
    let swapped = select(&circle, &[1.0, 0.0], 0.0, &mut jac, 1e-12).expect("regular stack");
    assert_eq!(swapped.replaces(0), Some(1));
    // Without the left-out row the stack is singular there.
    let none = select(&Circle { left_out: false }, &[1.0, 0.0], 0.0, &mut jac, 1e-12);
    assert!(matches!(none, Err(Singular::SmallPivot { column: 1, .. })), "{none:?}");
}

#[test]
fn the_solver_passes_where_the_kept_rows_degenerate_on_the_closed_form() {
    // Steps of 0.1 from −0.5 to 0.5, landing on t = 0 exactly, predictor on and off.
    for predictor in [true, false] {
        let mut solver = Solver::new(Circle { left_out: true }, [0.5_f64.cos(), -0.5_f64.sin()]);
        solver.set_predictor(predictor);
        let mut swapped = false;
        for k in 0..=10 {
            let t = (f64::from(k) - 5.0) / 10.0;
            solver.advance_to(t).expect("the whole stack is regular");
            swapped |= solver.rows_swapped();
            let (s, c) = t.sin_cos();
            let expected = [[c, s], [-s, c], [-c, -s]];
            for (got, want) in [solver.q(), solver.qd(), solver.qdd()].into_iter().zip(expected) {
                // Newton's tolerance 1e-10 on rows of unit slope, and solves with pivots of
                // at least 1e-3 (the rows in force): 1e-8 leaves margin.
                for (g, w) in got.iter().zip(want) {
                    assert!(
                        (g - w).abs() < 1e-8,
                        "t = {t} (predictor {predictor}): {got:?}, {want:?}"
                    );
                }
            }
        }
        assert!(swapped, "the left-out row stood in at t = 0 (predictor {predictor})");
    }
}

#[test]
fn without_the_left_out_row_the_solver_stops_singular_where_the_kept_rows_do() {
    let mut solver = Solver::new(Circle { left_out: false }, [0.5_f64.cos(), -0.5_f64.sin()]);
    let mut stop = None;
    for k in 0..=10 {
        let t = (f64::from(k) - 5.0) / 10.0;
        if let Err(e) = solver.advance_to(t) {
            stop = Some((t, e.trouble));
            break;
        }
    }
    assert_eq!(stop, Some((0.0, Trouble::Singular)));
}
