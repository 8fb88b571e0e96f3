//! The time terms of generated modules (`runtime::Mechanism::TIME_TERMS`): the R-S-S-R's
//! against its driver law's closed form, every module's `_at` functions against the plain ones
//! they stand in for, and a solver that reads them against one that does not, over the
//! R-S-S-R's revolution; `expand_at` against `expand` and the R-S-S-R's crank against its
//! closed form; and the generated `normalize_moved` against `normalize` and the runtime's
//! round-off test.

use runtime::lu::PivotInfo;
use runtime::{Mechanism, NewtonOptions, Solver};

/// A mechanism with its time terms hidden: the solver then calls the plain functions, each of
/// which computes the terms itself.
struct Plain<M>(M);

impl<M: Mechanism<N>, const N: usize> Mechanism<N> for Plain<M> {
    const PIVOT_ORDERS: usize = M::PIVOT_ORDERS;
    fn residual(&self, q: &[f64; N], t: f64, phi: &mut [f64; N]) {
        self.0.residual(q, t, phi);
    }
    fn jacobian(&self, q: &[f64; N], t: f64, jac: &mut [[f64; N]; N]) {
        self.0.jacobian(q, t, jac);
    }
    fn residual_jacobian(&self, q: &[f64; N], t: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
        self.0.residual_jacobian(q, t, phi, jac);
    }
    fn velocity_rhs(&self, q: &[f64; N], t: f64, nu: &mut [f64; N]) {
        self.0.velocity_rhs(q, t, nu);
    }
    fn acceleration_rhs(&self, q: &[f64; N], qd: &[f64; N], t: f64, gamma: &mut [f64; N]) {
        self.0.acceleration_rhs(q, qd, t, gamma);
    }
    fn normalize(&self, q: &mut [f64; N]) {
        self.0.normalize(q);
    }
    fn residual_jacobian_structural(
        &self,
        q: &[f64; N],
        t: f64,
        phi: &mut [f64; N],
        jac: &mut [[f64; N]; N],
    ) {
        self.0.residual_jacobian_structural(q, t, phi, jac);
    }
    fn factor_structured(&self, order: usize, jac: &mut [[f64; N]; N]) -> Option<PivotInfo> {
        self.0.factor_structured(order, jac)
    }
    fn solve_structured(&self, order: usize, lu: &[[f64; N]; N], b: &mut [f64; N]) {
        self.0.solve_structured(order, lu, b);
    }
}

#[test]
fn rssr_time_terms_are_the_sine_and_cosine_of_half_the_crank_angle() {
    use generated::rssr::{Rssr, TIME_TERMS, time_terms};
    assert_eq!(TIME_TERMS, 2);
    assert_eq!(<Rssr as Mechanism<{ generated::rssr::N }>>::TIME_TERMS, 2);
    for k in 0..=100 {
        let t = 0.05 * f64::from(k) / 100.0;
        // The crank's Euler parameters, substituted by their closed form, are linear in the
        // sine and cosine of s/2 with the law s = 146.6 t.
        let half = 146.6 * t / 2.0;
        let mut terms = [0.0; 2];
        time_terms(t, &mut terms);
        // Values of at most 1; the runtime's libm and the platform's may differ by an ulp.
        assert!((terms[0] - half.sin()).abs() <= 1e-15, "t = {t}: {terms:?}");
        assert!((terms[1] - half.cos()).abs() <= 1e-15, "t = {t}: {terms:?}");
        let mut through_trait = [0.0; 3];
        Rssr.time_terms(t, &mut through_trait);
        assert_eq!(through_trait[..2], terms);
    }
}

/// The `_at` functions of `m` against the plain ones at configurations and times spread
/// around `q0`: the same values, bit for bit.
fn same_as_plain<M: Mechanism<N>, const N: usize>(name: &str, m: &M, q0: &[f64; N]) {
    assert!(M::TIME_TERMS > 0 && M::TIME_TERMS <= runtime::MAX_TIME_TERMS, "{name}");
    for k in 0..50 {
        let x = f64::from(k);
        let t = 0.37 * x - 3.0;
        let q: [f64; N] = std::array::from_fn(|i| q0[i] + 0.1 * (x + 1.7 * i as f64).sin());
        let qd: [f64; N] = std::array::from_fn(|i| (0.3 * x - i as f64).cos());
        let mut terms = [f64::NAN; runtime::MAX_TIME_TERMS];
        m.time_terms(t, &mut terms);
        let terms = &terms[..M::TIME_TERMS];
        let (mut a, mut b) = ([0.0; N], [0.0; N]);
        let (mut ja, mut jb) = (vec![[0.0; N]; N], vec![[0.0; N]; N]);
        let (ja, jb): (&mut [[f64; N]; N], &mut [[f64; N]; N]) =
            (ja.as_mut_slice().try_into().unwrap(), jb.as_mut_slice().try_into().unwrap());
        m.residual(&q, t, &mut a);
        m.residual_at(&q, t, terms, &mut b);
        assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "{name} residual, t = {t}");
        m.residual_jacobian_structural(&q, t, &mut a, ja);
        m.residual_jacobian_structural_at(&q, t, terms, &mut b, jb);
        assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "{name} Φ, t = {t}");
        assert!(
            ja.iter().flatten().zip(jb.iter().flatten()).all(|(x, y)| x.to_bits() == y.to_bits())
        );
        m.velocity_rhs(&q, t, &mut a);
        m.velocity_rhs_at(&q, t, terms, &mut b);
        assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "{name} ν, t = {t}");
        m.acceleration_rhs(&q, &qd, t, &mut a);
        m.acceleration_rhs_at(&q, &qd, t, terms, &mut b);
        assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "{name} γ, t = {t}");
    }
}

#[test]
fn every_at_function_matches_its_plain_function_bit_for_bit() {
    use generated::*;
    same_as_plain("rssr", &rssr::Rssr, &rssr::Q0);
    same_as_plain("four_bar", &four_bar::FourBar, &four_bar::Q0);
    same_as_plain(
        "slider_crank_5body",
        &slider_crank_5body::SliderCrank5body,
        &slider_crank_5body::Q0,
    );
    // revolute_joint has no unknowns left (its blocks are all closed form): no equations.
    same_as_plain("screw_joint", &screw_joint::ScrewJoint, &screw_joint::Q0);
    same_as_plain("universal_joint", &universal_joint::UniversalJoint, &universal_joint::Q0);
    same_as_plain("spherical_joint", &spherical_joint::SphericalJoint, &spherical_joint::Q0);
    same_as_plain("rotation_about_x", &rotation_about_x::RotationAboutX, &rotation_about_x::Q0);
}

/// A module's `expand` with N unknowns and B moving bodies.
type Expand<const N: usize, const B: usize> =
    fn(&[f64; N], &[f64; N], &[f64; N], f64, &mut [[[f64; 7]; 3]; B]);

/// `expand_at` of `m` (through `runtime::Mechanism`, with the terms, without them, and into
/// too short an array) against the module's `expand` at configurations and times spread
/// around `q0`: the same values, bit for bit.
fn expand_same_as_plain<M: Mechanism<N>, const N: usize, const B: usize>(
    name: &str,
    m: &M,
    q0: &[f64; N],
    expand: Expand<N, B>,
) {
    assert!(B > 0, "{name}");
    for k in 0..50 {
        let x = f64::from(k);
        let t = 0.37 * x - 3.0;
        let q: [f64; N] = std::array::from_fn(|i| q0[i] + 0.1 * (x + 1.7 * i as f64).sin());
        let qd: [f64; N] = std::array::from_fn(|i| (0.3 * x - i as f64).cos());
        let qdd: [f64; N] = std::array::from_fn(|i| (0.7 * x + i as f64).sin());
        let mut terms = [f64::NAN; runtime::MAX_TIME_TERMS];
        m.time_terms(t, &mut terms);
        let mut plain = [[[f64::NAN; 7]; 3]; B];
        expand(&q, &qd, &qdd, t, &mut plain);
        let bits = |out: &[[[f64; 7]; 3]; B]| out.map(|b| b.map(|d| d.map(f64::to_bits)));
        for terms in [&terms[..M::TIME_TERMS], &[]] {
            let mut at = [[[f64::NAN; 7]; 3]; B];
            assert!(m.expand_at(&q, &qd, &qdd, t, terms, &mut at), "{name}");
            assert!(bits(&at) == bits(&plain), "{name} expand_at, t = {t}, {} terms", terms.len());
        }
        // Too short an array is refused untouched.
        let mut short = vec![[[1.0; 7]; 3]; B - 1];
        assert!(!m.expand_at(&q, &qd, &qdd, t, &terms[..M::TIME_TERMS], &mut short), "{name}");
        assert!(short.iter().flatten().flatten().all(|&v| v == 1.0), "{name}");
    }
}

#[test]
fn every_expand_at_matches_expand_bit_for_bit() {
    use generated::*;
    expand_same_as_plain("rssr", &rssr::Rssr, &rssr::Q0, rssr::expand);
    expand_same_as_plain("four_bar", &four_bar::FourBar, &four_bar::Q0, four_bar::expand);
    expand_same_as_plain(
        "slider_crank_5body",
        &slider_crank_5body::SliderCrank5body,
        &slider_crank_5body::Q0,
        slider_crank_5body::expand,
    );
    // A mechanism that does not override it, the runtime's default: nothing written.
    let mut out = [[[1.0; 7]; 3]; rssr::BODIES];
    let q = rssr::Q0;
    assert!(!Plain(rssr::Rssr).expand_at(&q, &q, &q, 0.0, &[], &mut out));
    assert_eq!(out, [[[1.0; 7]; 3]; rssr::BODIES]);
}

#[test]
fn rssr_expand_at_with_the_solvers_terms_gives_the_crank_closed_form() {
    use generated::rssr::{BODIES, BODY_NAMES, Q0, Rssr, expand};
    assert_eq!(BODY_NAMES[0], "crank");
    let mut solver = Solver::new(Rssr, Q0);
    solver.set_options(NewtonOptions { tolerance: 1e-12, ..NewtonOptions::DEFAULT });
    let end = 2.0 * std::f64::consts::PI / 146.6;
    for k in 0..=100 {
        let t = end * f64::from(k) / 100.0;
        assert!(solver.time_terms(t).is_none() || k == 0, "no position at t = {t} yet");
        solver.position(t).unwrap_or_else(|e| panic!("t = {t}: {e}"));
        solver.velocity().unwrap();
        solver.acceleration().unwrap();
        let terms = solver.time_terms(t).expect("computed by the position at t");
        assert_eq!(terms.len(), 2);
        assert!(solver.time_terms(t + 1e-9).is_none(), "terms of another time");
        let (q, qd, qdd) = (solver.q(), solver.qd(), solver.qdd());
        let mut at = [[[0.0; 7]; 3]; BODIES];
        assert!(Rssr.expand_at(q, qd, qdd, t, terms, &mut at));
        let mut plain = [[[0.0; 7]; 3]; BODIES];
        expand(q, qd, qdd, t, &mut plain);
        assert!(
            at.map(|b| b.map(|d| d.map(f64::to_bits)))
                == plain.map(|b| b.map(|d| d.map(f64::to_bits)))
        );
        // The crank turns about y at s = 146.6 t: e0 = cos(s/2), e2 = sin(s/2), and their
        // rates and accelerations by the chain rule. Values up to 73.3² ≈ 5373; the runtime's
        // libm and the platform's sine may differ by an ulp, scaled by the rates' factors.
        let (h, w) = (73.3 * t, 73.3);
        let crank = at[0];
        let expected =
            [[h.cos(), h.sin()], [-w * h.sin(), w * h.cos()], [-w * w * h.cos(), -w * w * h.sin()]];
        for d in 0..3 {
            let tol = 1e-15 * [1.0, w, w * w][d];
            assert!((crank[d][3] - expected[d][0]).abs() <= tol, "t = {t}, e0 d{d}");
            assert!((crank[d][5] - expected[d][1]).abs() <= tol, "t = {t}, e2 d{d}");
            assert_eq!([crank[d][4], crank[d][6]], [0.0, 0.0], "t = {t}, e1 e3 d{d}");
        }
    }
}

/// q, q̇ and q̈ at each of the 1001 points of the R-S-S-R's revolution, as bits.
fn revolution<M: Mechanism<{ generated::rssr::N }>>(m: M) -> Vec<[[u64; generated::rssr::N]; 3]> {
    let mut solver = Solver::new(m, generated::rssr::Q0);
    solver.set_options(NewtonOptions { tolerance: 1e-12, ..NewtonOptions::DEFAULT });
    solver.set_predictor(true);
    let end = 2.0 * std::f64::consts::PI / 146.6;
    (0..=1000)
        .map(|k| {
            let t = end * f64::from(k) / 1000.0;
            solver.position(t).unwrap_or_else(|e| panic!("t = {t}: {e}"));
            solver.velocity().unwrap();
            solver.acceleration().unwrap();
            [solver.q(), solver.qd(), solver.qdd()].map(|v| v.map(f64::to_bits))
        })
        .collect()
}

#[test]
fn rssr_revolution_with_time_terms_is_bit_identical_to_the_plain_functions() {
    use generated::rssr::Rssr;
    // The terms are the nodes the plain functions compute, so every evaluation, and so every
    // step, is the same to the bit.
    assert!(revolution(Rssr) == revolution(Plain(Rssr)));
}

#[test]
fn normalize_moved_rescales_as_normalize_and_reports_moves_beyond_round_off() {
    use generated::rssr::{Q0, Rssr, normalize, normalize_moved};
    // The coupler's and the rocker's Euler parameters (e2 of the coupler is fixed at 0, the
    // crank's are substituted by their closed form, the rocker's e2 and e3 are 0 as it turns
    // about x), at values of norm 1 exactly.
    use generated::rssr::unknown;
    let coupler = [("coupler.e0", 1.0), ("coupler.e1", 0.0), ("coupler.e3", 0.0)];
    let rocker = [("rocker.e0", 0.0), ("rocker.e1", 1.0)];
    let euler: Vec<(usize, f64)> =
        coupler.into_iter().chain(rocker).map(|(name, v)| (unknown(name), v)).collect();
    let mut seen = [false; 2];
    for k in 0..40 {
        // Each body's |p| off 1 by about k/4 ulps: below about 3.5 ε a rescaling moves each
        // parameter by at most 4 ulps of itself (newton::ROUND_OFF_MOVE), above it not.
        let mut q = Q0;
        for &(i, v) in &euler {
            q[i] = v * (1.0 + 0.25 * f64::from(k) * f64::EPSILON);
        }
        let (mut by_normalize, mut moved) = (q, q);
        normalize(&mut by_normalize);
        let expected = !runtime::newton::moved_by_round_off(&q, &by_normalize);
        assert_eq!(normalize_moved(&mut moved), expected, "k = {k}");
        assert_eq!(moved.map(f64::to_bits), by_normalize.map(f64::to_bits), "k = {k}");
        let mut through_trait = q;
        assert_eq!(Rssr.normalize_moved(&mut through_trait), expected);
        seen[usize::from(expected)] = true;
    }
    // Both verdicts occur, so the comparison above tested each.
    assert_eq!(seen, [true, true]);
}
