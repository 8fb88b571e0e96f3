use core::cell::Cell;

use crate::blocks::{Layout, Solve};
use crate::{Mechanism, Solver};

/// A crank driven to the angle q0 = t, as two blocks: q0 − t = 0 (affine in q0: closed form),
/// then the crank's end (q1, q2) on the unit circle at angle q0,
/// (q1² + q2² − 1, q1 sin q0 − q2 cos q0) = 0 (Newton). Exact solution (t, cos t, sin t).
/// Counts the evaluations of each block.
#[derive(Default)]
struct Crank {
    evaluations: [Cell<u32>; 2],
}

static LAYOUT: Layout = Layout {
    rows: &[0, 1, 2],
    columns: &[0, 1, 2],
    starts: &[0, 1, 3],
    lower: &[0],
    lower_starts: &[0, 0, 0, 1],
    solve: &[Solve::Affine, Solve::Newton],
};

impl Mechanism<3> for Crank {
    fn residual(&self, q: &[f64; 3], t: f64, phi: &mut [f64; 3]) {
        let (s, c) = q[0].sin_cos();
        *phi = [q[0] - t, q[1] * q[1] + q[2] * q[2] - 1.0, q[1] * s - q[2] * c];
    }
    fn jacobian(&self, q: &[f64; 3], _t: f64, jac: &mut [[f64; 3]; 3]) {
        let (s, c) = q[0].sin_cos();
        *jac = [[1.0, 0.0, 0.0], [0.0, 2.0 * q[1], 2.0 * q[2]], [q[1] * c + q[2] * s, s, -c]];
    }
    fn velocity_rhs(&self, _q: &[f64; 3], _t: f64, nu: &mut [f64; 3]) {
        *nu = [1.0, 0.0, 0.0];
    }
    fn acceleration_rhs(&self, q: &[f64; 3], qd: &[f64; 3], _t: f64, gamma: &mut [f64; 3]) {
        let (s, c) = q[0].sin_cos();
        let along = 2.0 * qd[1] * qd[0] * c + 2.0 * qd[2] * qd[0] * s;
        let turn = qd[0] * qd[0] * (q[2] * c - q[1] * s);
        *gamma = [0.0, -2.0 * (qd[1] * qd[1] + qd[2] * qd[2]), -(along + turn)];
    }
    const BLOCKS: Option<&'static Layout> = Some(&LAYOUT);
    const BLOCK_NEWTON: bool = true;
    fn block_residual(
        &self,
        b: usize,
        jacobian: bool,
        q: &[f64; 3],
        t: f64,
        phi: &mut [f64; 3],
        jac: &mut [[f64; 3]; 3],
    ) {
        self.evaluations[b].set(self.evaluations[b].get() + 1);
        let (s, c) = q[0].sin_cos();
        if b == 0 {
            phi[0] = q[0] - t;
            if jacobian {
                jac[0][0] = 1.0;
            }
        } else {
            phi[1] = q[1] * q[1] + q[2] * q[2] - 1.0;
            phi[2] = q[1] * s - q[2] * c;
            if jacobian {
                jac[1][0] = 0.0;
                jac[1][1] = 2.0 * q[1];
                jac[1][2] = 2.0 * q[2];
                jac[2][0] = q[1] * c + q[2] * s;
                jac[2][1] = s;
                jac[2][2] = -c;
            }
        }
    }
}

#[test]
fn the_affine_block_is_solved_without_iteration_and_the_crank_by_newton() {
    let mut solver = Solver::new(Crank::default(), [0.0, 1.0, 0.0]);
    solver.set_predictor(true);
    solver.set_options(crate::NewtonOptions { tolerance: 1e-12, ..crate::NewtonOptions::DEFAULT });
    let steps = 50;
    for k in 0..steps {
        let t = 0.02 * f64::from(k);
        solver.position(t).expect("a regular crank converges");
        solver.velocity().expect("Φ_q is regular");
        solver.acceleration().expect("q̇ is known");
        let (s, c) = t.sin_cos();
        let exact = [[t, c, s], [1.0, -s, c], [0.0, -c, -s]];
        // Newton stops at max |Φ| ≤ 1e-12 on a unit circle, and the chord step or the last
        // Newton step lands within round-off of it: 1e-12 bounds all three.
        for (got, want) in [solver.q(), solver.qd(), solver.qdd()].into_iter().zip(exact) {
            for (g, w) in got.iter().zip(want) {
                assert!((g - w).abs() <= 1e-12, "t = {t}: {got:?} against {want:?}");
            }
        }
    }
    let counts = solver.block_counts();
    assert_eq!(counts.closed_form, u64::from(steps));
    assert_eq!(counts.implicit, u64::from(steps));
    // One evaluation per position for the affine block: no iteration, no convergence test.
    assert_eq!(solver.mechanism().evaluations[0].get(), steps);
    // The crank iterates: at least one evaluation with Φ_q per position, more for Newton steps.
    assert!(solver.mechanism().evaluations[1].get() > steps);
    assert!(counts.iterations >= u64::from(steps - 1));
}
