use approx::assert_relative_eq;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use super::{COEFFICIENTS, about_axis};

/// The Hamilton product a ⊗ b.
fn product(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

fn unit(rng: &mut StdRng) -> [f64; 4] {
    let e: [f64; 4] = core::array::from_fn(|_| rng.random_range(-1.0..1.0));
    let n = e.iter().map(|v| v * v).sum::<f64>().sqrt();
    e.map(|v| v / n)
}

fn dot(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    (0..4).map(|i| a[i] * b[i]).sum()
}

/// A random orthonormal pair (u, w) = (e ⊗ g, e ⊗ g ⊗ k), as the joint family makes them.
fn family(rng: &mut StdRng) -> ([f64; 4], [f64; 4]) {
    let (e, g) = (unit(rng), unit(rng));
    let u = product(e, g);
    (u, product(u, [0.0, 0.0, 0.0, 1.0]))
}

/// The coefficients `about_axis` reads for the row `f`.
fn coefficients(u: &[f64; 4], w: &[f64; 4], f: &dyn Fn(&[f64; 4]) -> f64) -> [f64; COEFFICIENTS] {
    let mid: [f64; 4] = core::array::from_fn(|i| (u[i] + w[i]) * core::f64::consts::FRAC_1_SQRT_2);
    let mut k = [0.0; COEFFICIENTS];
    k[..4].copy_from_slice(u);
    k[4..8].copy_from_slice(w);
    k[8] = f(u);
    k[9] = f(w);
    k[10] = f(&mid);
    k
}

#[test]
fn quadratic_rows_are_zeroed_on_the_family_nearest_the_prediction() {
    let mut rng = StdRng::seed_from_u64(16);
    for _ in 0..200 {
        let (u, w) = family(&mut rng);
        // A homogeneous quadratic form with real zeros on the family: eᵀ M e with a random
        // symmetric M, shifted by −λ |e|² for a λ between the form's extremes on the family.
        // A random symmetric M: the upper triangle drawn, mirrored below.
        let upper: [[f64; 4]; 4] =
            core::array::from_fn(|_| core::array::from_fn(|_| rng.random_range(-1.0..1.0)));
        let m: [[f64; 4]; 4] =
            core::array::from_fn(|i| core::array::from_fn(|j| upper[i.min(j)][i.max(j)]));
        let form = |e: &[f64; 4]| {
            (0..4).map(|i| (0..4).map(|j| e[i] * m[i][j] * e[j]).sum::<f64>()).sum::<f64>()
        };
        let (fu, fw) = (form(&u), form(&w));
        let lambda = fu + rng.random_range(0.05..0.95) * (fw - fu);
        let f = |e: &[f64; 4]| form(e) - lambda * dot(e, e);
        let k = coefficients(&u, &w, &f);
        let previous = unit(&mut rng);
        let e = about_axis(&k, false, &previous).expect("the row changes sign on the family");
        // The row, the norm and the family, against the definitions (round-off of a few
        // products of unit quantities).
        assert!(f(&e).abs() < 1e-14, "row {}", f(&e));
        assert_relative_eq!(dot(&e, &e), 1.0, epsilon = 1e-15);
        let (c, s) = (dot(&e, &u), dot(&e, &w));
        assert_relative_eq!(c * c + s * s, 1.0, epsilon = 1e-14);
        // No other zero of the row on the family is nearer the prediction: sample the circle.
        let near = dot(&e, &previous);
        assert!(near >= 0.0);
        for step in 0..720 {
            let phi = f64::from(step) * core::f64::consts::PI / 360.0;
            let (s2, c2) = phi.sin_cos();
            let x: [f64; 4] = core::array::from_fn(|i| c2 * u[i] + s2 * w[i]);
            if f(&x).abs() < 1e-6 * (fu.abs() + fw.abs()) {
                assert!(dot(&x, &previous).abs() <= near + 1e-3, "a nearer zero at {phi}");
            }
        }
    }
}

#[test]
fn linear_rows_are_zeroed_and_a_full_turn_flips_the_sign() {
    let mut rng = StdRng::seed_from_u64(4);
    let (u, w) = family(&mut rng);
    // e_1 cos(s/2) − e_0 sin(s/2) along a slow sweep of s over a full turn, each answer the
    // prediction of the next: e follows continuously and ends at −e(0).
    let mut previous = [0.0; 4];
    let mut first = None;
    for step in 0..=400 {
        let s = f64::from(step) * 2.0 * core::f64::consts::PI / 400.0;
        let (sin, cos) = (0.5 * s).sin_cos();
        let f = |e: &[f64; 4]| e[1] * cos - e[0] * sin;
        let e = about_axis(&coefficients(&u, &w, &f), true, &previous).expect("a zero");
        assert!(f(&e).abs() < 1e-15, "row {}", f(&e));
        if step > 0 {
            assert!(dot(&e, &previous) > 0.99, "continuous at step {step}");
        }
        first.get_or_insert(e);
        previous = e;
    }
    let first = first.expect("a first");
    for i in 0..4 {
        // A full turn of an absolute rotation flips the Euler parameters (round-off).
        assert_relative_eq!(previous[i], -first[i], epsilon = 1e-12);
    }
}

#[test]
fn a_row_without_zero_on_the_family_is_none() {
    let mut rng = StdRng::seed_from_u64(7);
    let (u, w) = family(&mut rng);
    // |e|² + 0.1 (e·u)² has no zero on the unit circle.
    let f = |e: &[f64; 4]| dot(e, e) + 0.1 * dot(e, &u).powi(2);
    assert_eq!(about_axis(&coefficients(&u, &w, &f), false, &u), None);
}
