extern crate std;

use std::string::ToString;

use super::*;
use crate::{Mechanism, Solver};

/// A unit crank (x, y) driven to the angle s = ω t: Φ = (x² + y² − 1, x sin s − y cos s).
///
/// The second row holds on both branches (cos s, sin s) and (−cos s, −sin s), the θ and θ + π
/// of a crank whose driver equation is written without an arccos, so a large step can converge
/// on the wrong one; Φ_q = [[2x, 2y], [sin s, −cos s]] has determinant −2 on both, so neither
/// is singular.
struct Crank {
    omega: f64,
}

impl Mechanism<2> for Crank {
    fn residual(&self, q: &[f64; 2], t: f64, phi: &mut [f64; 2]) {
        let [x, y] = *q;
        let (s, c) = (self.omega * t).sin_cos();
        *phi = [x * x + y * y - 1.0, x * s - y * c];
    }
    fn jacobian(&self, q: &[f64; 2], t: f64, jac: &mut [[f64; 2]; 2]) {
        let [x, y] = *q;
        let (s, c) = (self.omega * t).sin_cos();
        *jac = [[2.0 * x, 2.0 * y], [s, -c]];
    }
    fn velocity_rhs(&self, q: &[f64; 2], t: f64, nu: &mut [f64; 2]) {
        let [x, y] = *q;
        let (s, c) = (self.omega * t).sin_cos();
        *nu = [0.0, -self.omega * (x * c + y * s)];
    }
    fn acceleration_rhs(&self, q: &[f64; 2], qd: &[f64; 2], t: f64, gamma: &mut [f64; 2]) {
        let ([x, y], [xd, yd], w) = (*q, *qd, self.omega);
        let (s, c) = (w * t).sin_cos();
        *gamma =
            [-2.0 * (xd * xd + yd * yd), -2.0 * w * (c * xd + s * yd) + w * w * (x * s - y * c)];
    }
}

/// The branch the crank starts on: (q, q̇, q̈) at t for ω.
fn exact(omega: f64, t: f64) -> [[f64; 2]; 3] {
    let (s, c) = (omega * t).sin_cos();
    [[c, s], [-omega * s, omega * c], [-omega * omega * c, -omega * omega * s]]
}

/// Newton stops at max |Φ| ≤ 1e-10 on rows of unit size, and Φ_q has singular values of about
/// 1 and 2, so q is within a few 1e-10 of the closed form and q̇, q̈ (ω ≤ 1) as well.
const CLOSE: f64 = 1e-8;

fn assert_on_branch(solver: &Solver<Crank, 2>, omega: f64, t: f64) {
    let want = exact(omega, t);
    for (got, want) in [solver.q(), solver.qd(), solver.qdd()].into_iter().zip(want) {
        for k in 0..2 {
            assert!((got[k] - want[k]).abs() < CLOSE, "t = {t}: {got:?} against {want:?}");
        }
    }
}

#[test]
fn advance_to_stays_on_the_starting_branch_for_any_jump() {
    for jump in [10.0_f64, 90.0, 120.0, 179.0].map(f64::to_radians) {
        for predictor in [false, true] {
            let mut solver = Solver::new(Crank { omega: 1.0 }, [0.9, 0.1]);
            solver.set_predictor(predictor);
            solver.advance_to(0.0).expect("the start is regular");
            assert_on_branch(&solver, 1.0, 0.0);
            for k in 1..=12 {
                let t = jump * f64::from(k);
                let report = solver.advance_to(t).expect("the crank turns smoothly");
                assert!(report.residual <= 1e-10 && report.pivot_ratio > 0.1);
                assert_on_branch(&solver, 1.0, t);
            }
        }
    }
}

#[test]
fn plain_position_jumps_branch_where_advance_to_does_not() {
    let t = 179.0_f64.to_radians();
    let mut plain = Solver::new(Crank { omega: 1.0 }, [1.0, 0.0]);
    plain.position(0.0).expect("the start is regular");
    plain.position(t).expect("Newton converges, on the wrong branch");
    let [c, s] = exact(1.0, t)[0];
    // The θ + π branch, to Newton's tolerance (see `CLOSE`).
    assert!((plain.q()[0] + c).abs() < CLOSE && (plain.q()[1] + s).abs() < CLOSE);

    let mut controlled = Solver::new(Crank { omega: 1.0 }, [1.0, 0.0]);
    controlled.advance_to(0.0).expect("the start is regular");
    let report = controlled.advance_to(t).expect("sub-steps keep the branch");
    assert_on_branch(&controlled, 1.0, t);
    // More than one attempt was needed.
    assert!(report.iterations > 3, "{report:?}");
}

#[test]
fn advance_to_continues_after_plain_steps_and_backwards() {
    let mut solver = Solver::new(Crank { omega: 1.0 }, [1.0, 0.0]);
    solver.set_predictor(true);
    for k in 0..=3 {
        let t = 0.1 * f64::from(k);
        solver.position(t).expect("small steps");
        solver.velocity().expect("regular");
        solver.acceleration().expect("regular");
    }
    solver.advance_to(2.9).expect("forward");
    assert_on_branch(&solver, 1.0, 2.9);
    solver.advance_to(-2.9).expect("backward");
    assert_on_branch(&solver, 1.0, -2.9);
}

#[test]
fn a_step_whose_sub_steps_no_longer_change_t_stops() {
    // At t = 1e17 the spacing of f64 is 16 and the crank turns 16 rad between neighbours, so
    // every representable sub-step is a jump: the halving must stop rather than cycle.
    let t0 = 1e17;
    let mut solver = Solver::new(Crank { omega: 1.0 }, [1.0, 0.0]);
    let s0 = exact(1.0, t0)[0];
    solver.set_q(s0);
    solver.advance_to(t0).expect("the start is on the circle");
    let t1 = t0 + 64.0 * 16.0;
    let stop = solver.advance_to(t1).unwrap_err();
    assert!(matches!(stop.verdict, Verdict::Stalled { .. }), "{stop:?}");
    assert_eq!(stop.trouble, Trouble::NoConvergence);
    assert_eq!(stop.t, t1);
    assert!(stop.to_string().contains("no longer changes t"), "{stop}");
    // The solver is back at the last accepted point, still on the circle.
    assert_eq!(solver.t(), stop.near.map(|n| n.sample.t).unwrap_or(f64::NAN));
    let [x, y] = *solver.q();
    assert!((x * x + y * y - 1.0).abs() < 1e-9);
}

#[test]
fn a_nan_time_is_an_error_value() {
    let mut solver = Solver::new(Crank { omega: 1.0 }, [1.0, 0.0]);
    solver.advance_to(0.0).expect("regular");
    let stop = solver.advance_to(f64::NAN).unwrap_err();
    assert_eq!(stop.trouble, Trouble::NoConvergence);
    assert_on_branch(&solver, 1.0, 0.0);
}

/// x² + t = 0 and y = 1: the branch x = √(−t) ends at the limit point t = 0, where
/// Φ_q = diag(2x, 1) becomes singular (its pivot ratio 2x falls as √(−t)).
struct Fold;

impl Mechanism<2> for Fold {
    fn residual(&self, q: &[f64; 2], t: f64, phi: &mut [f64; 2]) {
        *phi = [q[0] * q[0] + t, q[1] - 1.0];
    }
    fn jacobian(&self, q: &[f64; 2], _t: f64, jac: &mut [[f64; 2]; 2]) {
        *jac = [[2.0 * q[0], 0.0], [0.0, 1.0]];
    }
    fn velocity_rhs(&self, _q: &[f64; 2], _t: f64, nu: &mut [f64; 2]) {
        *nu = [-1.0, 0.0];
    }
    fn acceleration_rhs(&self, _q: &[f64; 2], qd: &[f64; 2], _t: f64, gamma: &mut [f64; 2]) {
        *gamma = [-2.0 * qd[0] * qd[0], 0.0];
    }
}

#[test]
fn a_limit_point_is_singular_near_it() {
    let mut solver = Solver::new(Fold, [1.0, 1.0]);
    solver.advance_to(-1.0).expect("x = 1");
    // Past the limit point t = 0 there is no solution; Φ_q = 2x falls as √(−t) on the way.
    let stop = solver.advance_to(1.0).unwrap_err();
    assert_eq!(stop.trouble, Trouble::Singular, "{stop}");
    let near = stop.near.expect("sub-steps were accepted").sample.t;
    // The last accepted sub-step is within 2⁻²⁰ of the step (2) of the limit point, and the
    // rejected attempt, if nearer, within a few tolerances of it.
    assert!((-1e-5..=1e-5).contains(&near), "{near}");
    assert!(solver.t() < 0.0 && solver.t() > -1e-5);
}

fn coordinates<'a>(q: &'a [f64], qd: &'a [f64], qdd: &'a [f64]) -> Coordinates<'a, f64> {
    Coordinates { q, qd, qdd }
}

#[test]
fn continuity_passes_smooth_motion_and_flags_the_jumping_group() {
    // Two "bodies" of 7 coordinates moving as sin(ωt + k) each, over h with ωh = 1 rad, where
    // the defect is (ωh)⁴/720 ≈ 1.4e-3 of the displacement.
    let (omega, h) = (1.0_f64, 1.0_f64);
    let at = |t: f64, d: usize| -> std::vec::Vec<f64> {
        (0..14)
            .map(|k| {
                let phase = omega * t + k as f64;
                [phase.sin(), omega * phase.cos(), -omega * omega * phase.sin()][d]
            })
            .collect()
    };
    let (a, b) = ([at(0.0, 0), at(0.0, 1), at(0.0, 2)], [at(h, 0), at(h, 1), at(h, 2)]);
    let (ca, cb) = (coordinates(&a[0], &a[1], &a[2]), coordinates(&b[0], &b[1], &b[2]));
    for groups in [Groups::Bodies, Groups::Each, Groups::Ends(&[3, 7, 14])] {
        assert_eq!(discontinuity(groups, h, &ca, &cb, f64::EPSILON), None, "{groups:?}");
    }
    // The Euler parameters of body 1 jump to their negatives, as on another branch.
    let mut q = b[0].clone();
    for v in &mut q[10..14] {
        *v = -*v;
    }
    let jumped = coordinates(&q, &b[1], &b[2]);
    assert_eq!(discontinuity(Groups::Bodies, h, &ca, &jumped, f64::EPSILON).map(|j| j.0), Some(1));
    let each = discontinuity(Groups::Each, h, &ca, &jumped, f64::EPSILON).map(|j| j.0);
    assert!(each.is_some_and(|k| (10..14).contains(&k)), "{each:?}");
    assert_eq!(
        discontinuity(Groups::Ends(&[3, 7, 14]), h, &ca, &jumped, f64::EPSILON).map(|j| j.0),
        Some(2)
    );
    // A NaN is a failure.
    q[0] = f64::NAN;
    let nan = coordinates(&q, &b[1], &b[2]);
    assert!(discontinuity(Groups::Bodies, h, &ca, &nan, f64::EPSILON).is_some());
}

#[test]
fn the_thresholds_scale_as_the_square_root_of_epsilon() {
    assert_eq!(singular_ratio(f64::EPSILON), SINGULAR_RATIO);
    assert_eq!(floor(f64::EPSILON), FLOOR);
    let ratio = f64::from(singular_ratio(f32::EPSILON)) / SINGULAR_RATIO;
    // √(ε_f32 / ε_f64) = 2^14.5 ≈ 23170; f32 rounding of the result is 6e-8 relative.
    assert!((ratio - 2f64.powf(14.5)).abs() < 1e-3 * ratio, "{ratio}");
    assert_eq!(Trouble::Inconsistent.as_str(), "inconsistent");
}

#[test]
fn the_digits_rule_flags_where_the_error_bounds_pass_six_digits() {
    // κ² ε and κ³ ε against 1e-6 in f64 (ε = 2.2e-16): accelerations from κ = (1e-6/ε)^⅓ =
    // 1651, velocities from (1e-6/ε)^½ = 67,109.
    let eps = f64::EPSILON;
    let bound = suspect_condition(eps);
    assert!(
        (bound - (1e-6 / eps).cbrt()).abs() < 1e-9 * bound && (1650.0..1652.0).contains(&bound)
    );
    assert_eq!(suspect(1650.0, eps), Suspect::default());
    assert_eq!(suspect(1652.0, eps), Suspect { velocity: false, acceleration: true });
    assert_eq!(suspect(67_108.0, eps), Suspect { velocity: false, acceleration: true });
    assert_eq!(suspect(67_110.0, eps), Suspect { velocity: true, acceleration: true });
    assert_eq!(suspect(f64::NAN, eps), Suspect { velocity: true, acceleration: true });
    assert_eq!(suspect(f64::INFINITY, eps), Suspect { velocity: true, acceleration: true });
    // In single precision (ε = 1.2e-7) six digits are out of reach from κ = 2.03 on.
    assert_eq!(suspect(2.0_f32, f32::EPSILON), Suspect::default());
    assert!(suspect(2.1_f32, f32::EPSILON).acceleration);
    assert_eq!(
        Suspect { velocity: true, acceleration: true }.names().collect::<std::vec::Vec<_>>(),
        ["velocity", "acceleration"]
    );
}
