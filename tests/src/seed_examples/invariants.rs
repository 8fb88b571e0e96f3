//! Invariants every analysis of the seed examples must keep (young-program.md §10), several
//! of which YOUNG breaks: unit Euler parameters and a converged residual at every step,
//! rates independent of the sign of p, no angular acceleration of a body driven at constant
//! speed about a fixed axis, no rotation of a body on a prismatic joint to ground, and no axial
//! acceleration of a screw turned at constant speed.

use codegen::desc::{JointType, MechanismDesc, TimeDesc};
use codegen::model::{BodyId, DriverCoordinate, DriverTarget};
use codegen::report::{BodyResult, StepResult};

use super::{COMPLEX, all_examples, solve_deck};
use crate::harness::{self, Run};

/// The results of the body named `name` at `step`.
fn body<'s>(step: &'s StepResult, name: &str) -> &'s BodyResult {
    step.bodies.iter().find(|b| b.name == name).unwrap_or_else(|| panic!("no body {name}"))
}

/// Largest absolute component.
fn amax(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// Largest absolute difference, component by component.
fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

#[test]
fn euler_parameters_have_unit_norm_at_every_step_of_every_example() {
    for example in all_examples() {
        let run = solve_deck(example);
        run.assert_covers([]);
        for step in &run.steps {
            for b in &step.bodies {
                let norm = b.p.iter().map(|e| e * e).sum::<f64>().sqrt();
                // The engine normalises p after Newton (promising |p| − 1 ≤ 1e-14 in
                // `generic/solve.rs`); a normalised f64 4-vector is 1 within a few ulps
                // (≈4e-16), so 1e-14 is that promise with room to spare.
                assert!(
                    (norm - 1.0).abs() <= 1e-14,
                    "{example}: t = {}, body {}: |p| − 1 = {:e}",
                    step.t,
                    b.name,
                    norm - 1.0
                );
            }
        }
    }
}

#[test]
fn every_step_of_every_example_is_converged_within_the_solver_tolerance() {
    for example in all_examples() {
        let run = solve_deck(example);
        run.assert_covers([]);
        assert_eq!(run.frames.len(), run.mechanism.time.count, "{example}: the whole grid");
        let tolerance = run.mechanism.solver.tolerance;
        for frame in &run.frames {
            assert!(
                frame.residual <= tolerance,
                "{example}: t = {}: max |Φ| = {:e} > tolerance {tolerance:e}",
                frame.t,
                frame.residual
            );
        }
    }
}

/// The 4-bar's crank (deck body 1) turns at constant speed; one period T = 2π/ṡ later the
/// mechanism is in the same configuration with the crank's Euler parameters negated:
/// (cos θ/2, sin θ/2, 0, 0) at θ = 2π is −(1, 0, 0, 0). YOUNG prints a different coupler ω at
/// t = 0 and t = 2 (young-program.md B1). The deck's t = 2 is 7.2e-9 rad short of a turn
/// (ṡ = 3.14159265), so the grid here runs from 0 to T exactly, in the deck's 20 steps per
/// turn so that Newton follows the motion.
#[test]
fn four_bar_repeats_every_rate_after_one_crank_turn_with_negated_euler_parameters() {
    let mut desc = harness::import_deck("4-bar");
    let rate = desc.drivers[0].law.velocity.expect("the crank turns at a constant rate");
    let period = std::f64::consts::TAU / rate;
    desc.time = TimeDesc { start: 0.0, end: period, step: None, steps: Some(20) };
    let run = harness::solve("4-bar", &desc);
    run.assert_covers([0.0, period]);
    let (first, turned) = (&run.steps[0], &run.steps[20]);
    for (a, b) in first.bodies.iter().zip(&turned.bodies) {
        let scale = amax(&a.r_ddot).max(amax(&a.alpha)).max(1.0);
        // Both ends solve the same equations at the same crank angle up to round-off of
        // 2π/ṡ·ṡ (≈1e-16 rad) and to where Newton stopped (1e-10 on max |Φ|): 1e-8 of the
        // body's largest acceleration bounds what that moves.
        let tolerance = 1e-8 * scale;
        let dot: f64 = a.p.iter().zip(&b.p).map(|(x, y)| x * y).sum();
        let flip = |v: &[f64; 4]| v.map(|x| dot.signum() * x);
        let pairs: [(&str, &[f64], &[f64]); 8] = [
            ("r", &a.r, &b.r),
            ("p", &a.p, &flip(&b.p)),
            ("r_dot", &a.r_dot, &b.r_dot),
            ("p_dot", &a.p_dot, &flip(&b.p_dot)),
            ("omega", &a.omega, &b.omega),
            ("r_ddot", &a.r_ddot, &b.r_ddot),
            ("p_ddot", &a.p_ddot, &flip(&b.p_ddot)),
            ("alpha", &a.alpha, &b.alpha),
        ];
        for (what, x, y) in pairs {
            let d = max_diff(x, y);
            assert!(d <= tolerance, "4-bar {}: {what} at t = 0 and T differ by {d:e}", a.name);
        }
    }
    let crank = &run.mechanism.bodies[0].name;
    let dot: f64 = body(first, crank).p.iter().zip(body(turned, crank).p).map(|(x, y)| x * y).sum();
    assert!(dot < -0.999, "the crank's p at T is −p(0), so the sign flip is exercised");
}

/// Negating every initial estimate of p makes the engine track −p throughout; velocities,
/// ω, accelerations and α must not change (YOUNG's do: young-program.md B1).
#[test]
fn negated_euler_parameters_leave_every_rate_unchanged() {
    for example in COMPLEX {
        let desc = harness::import_deck(example);
        let mut negated: MechanismDesc = desc.clone();
        for b in negated.bodies.iter_mut().filter(|b| !b.ground) {
            b.p = b.p.map(|p| p.map(|e| -e));
        }
        let (plain, negated) = (harness::solve(example, &desc), harness::solve(example, &negated));
        plain.assert_covers([]);
        negated.assert_covers([]);
        for (s, n) in plain.steps.iter().zip(&negated.steps) {
            for (a, b) in s.bodies.iter().zip(&n.bodies) {
                let scale = amax(&a.r_ddot).max(amax(&a.alpha)).max(1.0);
                // Both runs solve the same equations up to signs, so they differ by round-off
                // and by where Newton stopped within 1e-10 on max |Φ|: 1e-8 of the largest
                // acceleration covers both.
                let tolerance = 1e-8 * scale;
                let neg = |v: &[f64; 4]| v.map(|x| -x);
                let pairs: [(&str, &[f64], &[f64]); 8] = [
                    ("r", &a.r, &b.r),
                    ("-p", &a.p, &neg(&b.p)),
                    ("r_dot", &a.r_dot, &b.r_dot),
                    ("-p_dot", &a.p_dot, &neg(&b.p_dot)),
                    ("omega", &a.omega, &b.omega),
                    ("r_ddot", &a.r_ddot, &b.r_ddot),
                    ("-p_ddot", &a.p_ddot, &neg(&b.p_ddot)),
                    ("alpha", &a.alpha, &b.alpha),
                ];
                for (what, x, y) in pairs {
                    let d = max_diff(x, y);
                    assert!(
                        d <= tolerance,
                        "{example} t = {}, {}: {what} differs by {d:e} with p negated",
                        s.t,
                        a.name
                    );
                }
            }
        }
    }
}

/// Requires `|v| ≤ tolerance` at every step for body `name`'s quantity `what`.
fn assert_zero_throughout(
    run: &Run,
    name: &str,
    what: &str,
    tolerance: f64,
    pick: impl Fn(&BodyResult) -> Vec<f64>,
) {
    for step in &run.steps {
        let v = pick(body(step, name));
        assert!(
            amax(&v) <= tolerance,
            "{}: t = {}, {name}: {what} = {v:?}, not 0 within {tolerance:e}",
            run.example,
            step.t
        );
    }
}

#[test]
fn four_bar_crank_driven_at_constant_speed_about_x_has_no_angular_acceleration() {
    let run = solve_deck("4-bar");
    run.assert_covers([]);
    let crank = &run.mechanism.bodies[0].name;
    let driver = &run.mechanism.drivers[0];
    let about_x = DriverTarget::Absolute { body: BodyId(0), coordinate: DriverCoordinate::Rx };
    assert_eq!(driver.target, about_x, "the 4-bar's driver turns the crank about x");
    let law = driver.law.eval(0.0);
    assert_eq!(law.2, 0.0, "the crank driver has no acceleration term");
    // α is exactly 0; it comes from p̈ solved by LU against accelerations of up to 46 m/s²,
    // so round-off is ≈1e-14 of that, and 1e-11 leaves room for the conditioning.
    assert_zero_throughout(&run, crank, "α", 1e-11, |b| b.alpha.to_vec());
    // YOUNG's B2 bug shows here: α = (0, 1.786, −1.786) at t = 0.1 (young-program.md §9).
    for step in &run.steps {
        let omega = body(step, crank).omega;
        // ω = (ṡ, 0, 0) exactly, up to round-off of ṗ solved from ν (≈1e-15 of 3.14).
        assert!(max_diff(&omega, &[law.1, 0.0, 0.0]) <= 1e-12, "t = {}: ω = {omega:?}", step.t);
    }
}

#[test]
fn five_body_slider_on_a_prismatic_joint_to_ground_does_not_rotate() {
    let run = solve_deck("5body");
    run.assert_covers([]);
    let desc = harness::import_deck("5body");
    let ground = &desc.bodies.iter().find(|b| b.ground).expect("5body has a ground").name;
    let slider = "body4";
    let prismatic = desc.joints.iter().any(|j| {
        j.kind == JointType::Prismatic
            && [&j.body_i, &j.body_j].contains(&&slider.to_owned())
            && [&j.body_i, &j.body_j].contains(&ground)
    });
    assert!(prismatic, "deck body 4 is joined to the ground by a prismatic joint");
    // Exactly 0 in both: the prismatic rows fix the slider's orientation, so ṗ and p̈ vanish
    // up to round-off of the LU solves (≈1e-15 of the crank's 6.28 rad/s and ≈40 rad/s²);
    // YOUNG prints α = (9.117, 3.058, −4.387) at t = 0 (young-program.md B2).
    assert_zero_throughout(&run, slider, "ω", 1e-12, |b| b.omega.to_vec());
    assert_zero_throughout(&run, slider, "α", 1e-11, |b| b.alpha.to_vec());
}

#[test]
fn screw_turned_at_constant_speed_has_no_axial_acceleration() {
    let run = solve_deck("2-6-1");
    run.assert_covers([]);
    let law = run.mechanism.drivers[0].law.eval(0.0);
    assert_eq!(law.2, 0.0, "the screw's driver has no acceleration term");
    // ÿ = lead/(2π)·θ̈ = 0 exactly; round-off of the LU solve against the body's
    // accelerations (≈0.3) is ≈1e-16, and 1e-12 leaves room for the conditioning. YOUNG
    // prints ÿ = 3.015, 2.392, −3.680, −930.673 (README-basic §1).
    assert_zero_throughout(&run, "body2", "ÿ", 1e-12, |b| vec![b.r_ddot[1]]);
}
