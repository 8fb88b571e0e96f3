use core::cell::Cell;

use super::*;

/// Φ = (q0²/2 + q1, q0), so Φ_q = [[q0, 1], [1, 0]] (regular whatever q0: det = −1), with
/// hand-written static orders (reciprocal pivots on the diagonal, as generated code keeps
/// them; U left unscaled, which generated code scales by the reciprocals: the layout is the
/// mechanism's own):
/// order 0 pivots on (0, 0) then (1, 1): multiplier 1/q0, refused for |q0| < 0.1;
/// order 1 pivots on (1, 0) then (0, 1): multiplier q0, refused for |q0| > 10.
/// `ORDERS` says how many of them the mechanism admits to.
#[derive(Default)]
struct Tilted<const ORDERS: usize> {
    /// Calls of `jacobian`, the full evaluation the dense fallback makes.
    full: Cell<u32>,
}

impl<const ORDERS: usize> Mechanism<2> for Tilted<ORDERS> {
    const PIVOT_ORDERS: usize = ORDERS;

    fn residual(&self, q: &[f64; 2], _t: f64, phi: &mut [f64; 2]) {
        *phi = [0.5 * q[0] * q[0] + q[1], q[0]];
    }

    fn jacobian(&self, q: &[f64; 2], _t: f64, jac: &mut [[f64; 2]; 2]) {
        self.full.set(self.full.get() + 1);
        *jac = [[q[0], 1.0], [1.0, 0.0]];
    }

    fn residual_jacobian_structural(
        &self,
        q: &[f64; 2],
        t: f64,
        phi: &mut [f64; 2],
        jac: &mut [[f64; 2]; 2],
    ) {
        self.residual(q, t, phi);
        // (1, 1) is a structural zero: left as it was.
        jac[0] = [q[0], 1.0];
        jac[1][0] = 1.0;
    }

    fn velocity_rhs(&self, _q: &[f64; 2], _t: f64, nu: &mut [f64; 2]) {
        *nu = [0.0; 2];
    }

    fn acceleration_rhs(&self, _q: &[f64; 2], _qd: &[f64; 2], _t: f64, gamma: &mut [f64; 2]) {
        *gamma = [0.0; 2];
    }

    fn factor_structured(&self, order: usize, jac: &mut [[f64; 2]; 2]) -> Option<PivotInfo> {
        let (p0, l, p1) = match order {
            0 => {
                let p0 = jac[0][0];
                let l = jac[1][0] / p0;
                // (1, 1) is a fill-in: 0 − l·u.
                (p0, l, -(l * jac[0][1]))
            }
            1 => {
                let p0 = jac[1][0];
                let l = jac[0][0] / p0;
                (p0, l, jac[0][1])
            }
            _ => return None,
        };
        if !(p0.is_finite() && p1.is_finite() && l.abs() <= lu::MAX_MULTIPLIER) {
            // A refused order may leave anything behind, as generated ones leave a partial
            // factorisation.
            *jac = [[f64::NAN; 2]; 2];
            return None;
        }
        if order == 0 {
            *jac = [[1.0 / p0, jac[0][1]], [l, 1.0 / p1]];
        } else {
            *jac = [[l, 1.0 / p1], [1.0 / p0, 0.0]];
        }
        let (a, b) = (p0.abs(), p1.abs());
        Some(PivotInfo { smallest: a.min(b), largest: a.max(b) })
    }

    fn solve_structured(&self, order: usize, lu: &[[f64; 2]; 2], b: &mut [f64; 2]) {
        match order {
            0 => {
                let y1 = b[1] - lu[1][0] * b[0];
                let x1 = y1 * lu[1][1];
                let x0 = (b[0] - lu[0][1] * x1) * lu[0][0];
                *b = [x0, x1];
            }
            1 => {
                let y1 = b[0] - lu[0][0] * b[1];
                let x1 = y1 * lu[0][1];
                let x0 = b[1] * lu[1][0];
                *b = [x0, x1];
            }
            _ => {}
        }
    }
}

/// Evaluates and factors `m` at q = (q0, 0), then solves Φ_q x = (1, 2).
fn factor_and_solve<const K: usize>(
    m: &Tilted<K>,
    factors: &mut Factors<2>,
    q0: f64,
) -> Result<[f64; 2], Singular> {
    let q = [q0, 0.0];
    let (mut phi, mut jac) = ([0.0; 2], [[f64::NAN; 2]; 2]);
    factors.evaluate(m, &q, 0.0, &mut phi, &mut jac);
    factors.factor(m, &q, 0.0, &mut jac, lu::DEFAULT_PIVOT_RATIO)?;
    let mut x = [1.0, 2.0];
    factors.solve(m, &jac, &mut x);
    Ok(x)
}

/// The solution of [[q0, 1], [1, 0]] x = (1, 2): x = (2, 1 − 2 q0).
fn exact(q0: f64) -> [f64; 2] {
    [2.0, 1.0 - 2.0 * q0]
}

#[test]
fn a_passing_static_order_is_used_without_a_full_evaluation() {
    let m = Tilted::<2>::default();
    let mut factors = Factors::new();
    assert_eq!(factor_and_solve(&m, &mut factors, 2.0), Ok(exact(2.0)));
    assert_eq!(factors.counts(), FactorCounts { structured: 1, dense: 0, refused: 0 });
    assert_eq!(m.full.get(), 0);
}

#[test]
fn a_refused_order_hands_over_to_the_next_which_is_tried_first_afterwards() {
    let m = Tilted::<2>::default();
    let mut factors = Factors::new();
    // q0 = 0 gives order 0 a zero pivot (an infinite multiplier); order 1 is exact.
    assert_eq!(factor_and_solve(&m, &mut factors, 0.0), Ok(exact(0.0)));
    assert_eq!(factors.counts(), FactorCounts { structured: 1, dense: 0, refused: 1 });
    assert_eq!(factor_and_solve(&m, &mut factors, 0.05), Ok(exact(0.05)));
    assert_eq!(factors.counts(), FactorCounts { structured: 2, dense: 0, refused: 1 });
    // Far from 0 order 1 is refused (|l| = 20) and order 0 takes over again.
    assert_eq!(factor_and_solve(&m, &mut factors, 20.0), Ok(exact(20.0)));
    assert_eq!(factors.counts(), FactorCounts { structured: 3, dense: 0, refused: 2 });
    // Each refusal was followed by a full evaluation for the next order.
    assert_eq!(m.full.get(), 2);
}

#[test]
fn without_a_passing_order_the_full_jacobian_is_factored_densely() {
    let m = Tilted::<1>::default();
    let mut factors = Factors::new();
    assert_eq!(factor_and_solve(&m, &mut factors, 0.0), Ok(exact(0.0)));
    assert_eq!(factors.counts(), FactorCounts { structured: 0, dense: 1, refused: 1 });
    // The refused order left NaNs behind, and the structural evaluation left the NaN in
    // (1, 1) besides; the fallback evaluated in full.
    assert_eq!(m.full.get(), 1);
}

#[test]
fn tiny_pivots_of_a_passing_order_leave_the_verdict_to_dense_lu() {
    // Order 0 at q0 = 1e7 has pivots 1e7 and −1e-7 (ratio 1e-14, below 1e-12) and multiplier
    // 1e-7; dense LU picks the same pivots and refuses too.
    let m = Tilted::<1>::default();
    let mut factors = Factors::new();
    let error = factor_and_solve(&m, &mut factors, 1e7).unwrap_err();
    assert!(matches!(error, Singular::SmallPivot { column: 1, .. }), "{error:?}");
    assert_eq!(factors.counts(), FactorCounts { structured: 0, dense: 1, refused: 1 });
    assert!(!factors.holds_factors());
    let mut x = [1.0, 2.0];
    factors.solve(&m, &[[0.0; 2]; 2], &mut x);
    assert!(x.iter().all(|v| v.is_nan()));
}

#[test]
fn mechanisms_without_orders_evaluate_in_full_and_factor_densely() {
    let m = Tilted::<0>::default();
    let mut factors = Factors::new();
    assert_eq!(factor_and_solve(&m, &mut factors, 2.0), Ok(exact(2.0)));
    assert_eq!(factors.counts(), FactorCounts { structured: 0, dense: 1, refused: 0 });
    // `residual_jacobian` (the default: residual, then jacobian) once, and no second time.
    assert_eq!(m.full.get(), 1);
}
