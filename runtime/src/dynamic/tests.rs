extern crate std;

use std::vec;

use approx::assert_relative_eq;

use super::*;
use crate::fixtures::{CircleLine, Empty};

const Q: [f64; 2] = [0.6, 0.8];
const T: f64 = 0.9;

#[test]
fn n_is_the_const_size() {
    assert_eq!(Fixed(CircleLine::default()).n(), 2);
}

#[test]
fn flat_jacobian_is_row_major() {
    let mut jac = [0.0; 4];
    Fixed(CircleLine::default()).jacobian_into(&Q, T, &mut jac);
    // ∂Φ₀/∂y = 2y = 1.6 sits at [0 * 2 + 1] and ∂Φ₁/∂x = 1 at [1 * 2 + 0]; a transposed
    // layout would swap them.
    assert_eq!(jac, [1.2, 1.6, 1.0, 0.0]);
}

#[test]
fn every_method_forwards_to_the_fixed_mechanism() {
    let m = CircleLine::projected();
    let dynamic = Fixed(CircleLine::projected());
    let qd = [-0.8, 0.6];

    let (mut fixed, mut flat) = ([0.0; 2], [0.0; 2]);
    m.residual(&Q, T, &mut fixed);
    dynamic.residual_into(&Q, T, &mut flat);
    assert_eq!(fixed, flat);

    m.velocity_rhs(&Q, T, &mut fixed);
    dynamic.velocity_rhs_into(&Q, T, &mut flat);
    assert_eq!(fixed, flat);

    m.acceleration_rhs(&Q, &qd, T, &mut fixed);
    dynamic.acceleration_rhs_into(&Q, &qd, T, &mut flat);
    assert_eq!(fixed, flat);

    let (mut fixed, mut flat) = ([3.0, 4.0], [3.0, 4.0]);
    m.normalize(&mut fixed);
    dynamic.normalize(&mut flat);
    assert_eq!(fixed, flat);
    assert_eq!(flat, [0.6, 0.8]);
}

/// Central differences of `residual_into` against `jacobian_into`, through the slice view,
/// so the same check serves generated and interpreted mechanisms.
fn check_jacobian_by_central_differences(m: &dyn DynMechanism, q: &[f64], t: f64) {
    // h = 1e-6 balances truncation (h² times third derivatives of order one) against rounding
    // (1e-16 / h); both stay below 1e-8, so 1e-7 is a safe tolerance.
    const H: f64 = 1e-6;
    let n = m.n();
    let mut jac = vec![0.0; n * n];
    m.jacobian_into(q, t, &mut jac);
    let (mut plus, mut minus) = (vec![0.0; n], vec![0.0; n]);
    for j in 0..n {
        let mut q_step = q.to_vec();
        q_step[j] = q[j] + H;
        m.residual_into(&q_step, t, &mut plus);
        q_step[j] = q[j] - H;
        m.residual_into(&q_step, t, &mut minus);
        for i in 0..n {
            let difference = (plus[i] - minus[i]) / (2.0 * H);
            assert_relative_eq!(jac[i * n + j], difference, epsilon = 1e-7);
        }
    }
}

#[test]
fn jacobian_matches_central_differences() {
    check_jacobian_by_central_differences(&Fixed(CircleLine::default()), &Q, T);
    check_jacobian_by_central_differences(&Fixed(CircleLine::default()), &[-0.3, 1.7], 2.0);
}

#[test]
fn empty_mechanism_has_an_empty_jacobian() {
    let m = Fixed(Empty);
    assert_eq!(m.n(), 0);
    m.jacobian_into(&[], 0.0, &mut []);
}
