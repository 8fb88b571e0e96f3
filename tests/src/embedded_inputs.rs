//! A generated module with an input driver embedded as a control loop would: the planar
//! four-bar of `examples/inputs/four_bar_input.toml`, its crank angle an input, driven through
//! `runtime::Solver::advance_with` with jumps of 10°, 90°, 120° and 179° per call, against the
//! closed form of its coupler-rocker pin B written here; and a non-finite input refused as an
//! error value.

use generated::four_bar_input::{self as fb, FourBarInput, Inputs};
use runtime::input::Input;
use runtime::{InputsError, Solver};

/// B at crank angle θ: A = (cos θ, sin θ) on the unit crank, B at 3 from A and 2.5 from
/// O4 = (3, 0), on the side of the line from A to O4 the description assembles on (left of
/// it, B above the ground line at θ = 0).
fn pin_b(theta: f64) -> [f64; 2] {
    let a = [theta.cos(), theta.sin()];
    let d = [3.0 - a[0], -a[1]];
    let dist = d[0].hypot(d[1]);
    let along = (9.0 - 6.25 + dist * dist) / (2.0 * dist);
    let height = (9.0 - along * along).sqrt();
    let (ux, uy) = (d[0] / dist, d[1] / dist);
    [a[0] + along * ux - height * uy, a[1] + along * uy + height * ux]
}

/// dB/dθ and d²B/dθ² by central differences of step `h`.
fn pin_b_derivatives(theta: f64, h: f64) -> [[f64; 2]; 2] {
    let (m, c, p) = (pin_b(theta - h), pin_b(theta), pin_b(theta + h));
    let first = std::array::from_fn(|i| (p[i] - m[i]) / (2.0 * h));
    let second = std::array::from_fn(|i| (p[i] - 2.0 * c[i] + m[i]) / (h * h));
    [first, second]
}

/// The crank's rate and acceleration in these runs (rad/s, rad/s²).
const OMEGA: f64 = 2.0;
const ALPHA: f64 = 0.5;

/// Two crank turns in calls of `jump_deg` each: θ(t) = ω t + α t²/2, the inputs at each call
/// exact, and B (position, velocity, acceleration) checked against the closed form.
fn crank_with_jumps(jump_deg: f64) {
    let mut solver = Solver::new(FourBarInput::new(0.0, &fb::INITIAL_INPUTS), fb::Q0);
    let calls = ((720.0 / jump_deg).ceil() as u32).max(24);
    // Times at which θ has moved by jump_deg from the previous call.
    let mut t = 0.0_f64;
    for k in 0..=calls {
        if k > 0 {
            let target = f64::from(k) * jump_deg.to_radians();
            // Solve ω t + α t²/2 = target for t > 0.
            t = (-OMEGA + (OMEGA * OMEGA + 2.0 * ALPHA * target).sqrt()) / ALPHA;
        }
        let theta = OMEGA * t + 0.5 * ALPHA * t * t;
        let (rate, acceleration) = (OMEGA + ALPHA * t, ALPHA);
        let inputs = Inputs { crank: Input { value: theta, rate, acceleration } };
        solver
            .advance_with(t, &inputs.to_array())
            .unwrap_or_else(|e| panic!("{jump_deg}° per call, θ = {theta}: {e}"));
        let mut r = [[0.0; 3]; fb::POINTS];
        let mut v = [[0.0; 3]; fb::POINTS];
        let mut a = [[0.0; 3]; fb::POINTS];
        fb::point_positions(solver.q(), t, &inputs, &mut r);
        fb::point_velocities(solver.q(), solver.qd(), t, &inputs, &mut v);
        fb::point_accelerations(solver.q(), solver.qd(), solver.qdd(), t, &inputs, &mut a);
        let b = fb::point::B;
        let want = pin_b(theta);
        let [d1, d2] = pin_b_derivatives(theta, 1e-4);
        for i in 0..2 {
            let context = format!("{jump_deg}° per call, θ = {theta}, axis {i}");
            // Newton stops at max |Φ| ≤ 1e-10 (the description's tolerance) on links of about
            // 3 with a Jacobian of condition ≈ 10: 1e-8 bounds the position error.
            assert!((r[b][i] - want[i]).abs() < 1e-8, "{context}: r {} vs {}", r[b][i], want[i]);
            // v = B' θ̇ and a = B'' θ̇² + B' θ̈; the central differences of step 1e-4 are exact
            // to about h² |B'''| ≈ 1e-7 (and rounding 1e-16 / h² ≈ 1e-8 for B''), so 1e-5 of
            // the terms' size (θ̇ up to about 4 rad/s) is a safe bound.
            let v_want = d1[i] * rate;
            let a_want = d2[i] * rate * rate + d1[i] * acceleration;
            assert!((v[b][i] - v_want).abs() < 1e-5 * rate, "{context}: v {} vs {v_want}", v[b][i]);
            assert!(
                (a[b][i] - a_want).abs() < 1e-5 * rate * rate,
                "{context}: a {} vs {a_want}",
                a[b][i]
            );
        }
    }
}

#[test]
fn the_crank_input_stays_on_its_branch_with_any_jump_per_call() {
    for jump in [10.0, 90.0, 120.0, 179.0] {
        crank_with_jumps(jump);
    }
}

#[test]
fn a_non_finite_input_is_an_error_value_and_the_solver_keeps_its_state() {
    let mut solver = Solver::new(FourBarInput::default(), fb::Q0);
    let start = Inputs { crank: Input { value: 0.1, rate: 1.0, acceleration: 0.0 } };
    solver.advance_with(0.0, &start.to_array()).expect("the start assembles");
    let q = *solver.q();
    for (value, rate, derivative) in [(f64::NAN, 1.0, 0), (0.2, f64::INFINITY, 1)] {
        let bad = Inputs { crank: Input { value, rate, acceleration: 0.0 } };
        match solver.advance_with(0.1, &bad.to_array()) {
            Err(InputsError::NonFinite { input, derivative: d }) => {
                assert_eq!((input, d), (fb::input::CRANK, derivative));
            }
            other => panic!("expected a non-finite input error, got {other:?}"),
        }
        assert_eq!(*solver.q(), q, "nothing was solved");
    }
    // The next good call continues from the last accepted point.
    let next = Inputs { crank: Input { value: 0.2, rate: 1.0, acceleration: 0.0 } };
    solver.advance_with(0.1, &next.to_array()).expect("a good input after a bad one");
    let mut r = [[0.0; 3]; fb::POINTS];
    fb::point_positions(solver.q(), 0.1, &next, &mut r);
    let want = pin_b(0.2);
    // As in the runs above.
    assert!(
        (r[fb::point::B][0] - want[0]).abs() < 1e-8 && (r[fb::point::B][1] - want[1]).abs() < 1e-8
    );
}
