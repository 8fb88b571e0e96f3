//! The runtime's step control for embedded callers: the generated spatial four-bar and
//! slider-crank (`generated/src`) driven through `runtime::Solver::advance_to` with crank jumps
//! of 10°, 90°, 120° and 179° per call, against closed forms written here from the geometry of
//! `examples/four_bar.toml` and `examples/slider_crank_5body.toml`.
//!
//! Both cranks are driven by a law of time (θ = θ0 + ω t), so a jump in t is a jump in crank
//! angle. Both mechanisms assemble in two ways at every crank angle, and a large enough jump
//! lets Newton converge on the other one: `advance_to` must never return that.
//! On the R-S-S-R, `advance_to` must cost one factorisation per step, the one its pivot ratio
//! is read from.

use std::f64::consts::PI;

use generated::four_bar::{self as fb, FourBar};
use generated::slider_crank_5body::{self as sc, SliderCrank5body};
use runtime::step::{Groups, Trouble};
use runtime::{Mechanism, Solver};

/// The four-bar's rocker and the slider among the moving bodies: their positions are written
/// from the loop's orientations (torn from it, `symbolic::substitute`), read through `expand`.
const ROCKER: usize = fb::body("rocker");
const SLIDER: usize = sc::body("slider");

/// The full coordinates of the four-bar's bodies at (q, q̇, q̈, t) ([`fb::expand`]).
fn four_bar_bodies(
    q: &[f64; fb::N],
    qd: &[f64; fb::N],
    qdd: &[f64; fb::N],
    t: f64,
) -> [[[f64; 7]; 3]; fb::BODIES] {
    let mut out = [[[0.0; 7]; 3]; fb::BODIES];
    fb::expand(q, qd, qdd, t, &mut out);
    out
}

/// The four-bar's crank law: θ = 3.14159265 t (driver `motor`, coordinate rx).
#[expect(clippy::approx_constant, reason = "the description's law is this literal, not π")]
const FOUR_BAR_OMEGA: f64 = 3.14159265;

/// The slider-crank's crank law: θ = 1.52 − 6.2831852 t (driver `motor`, coordinate rx).
const SLIDER_THETA0: f64 = 1.52;
const SLIDER_OMEGA: f64 = -6.2831852;

/// The four-bar's rocker angle φ at crank angle θ: the angle in the global xz plane of the
/// rocker pin C about the rocker's pivot D.
///
/// The crank turns about global x through the origin, so its pin is B = (0, −2 sin θ, 2 cos θ)
/// (crank point (0, 0, 2)); the rocker turns about global y through D = (−4, −8.5, 0), with its
/// pin C at 7.4 from D (rocker points (0, ±3.7, 0)), C = D + 7.4 (cos φ, 0, sin φ); the coupler
/// holds |C − B| = 12.2 (coupler points (0, ±6.1, 0)). With d = D − B the loop closes when
/// |d|² + 14.8 (d_x cos φ + d_z sin φ) + 7.4² = 12.2², i.e.
/// d_x cos φ + d_z sin φ = k, so φ = atan2(d_z, d_x) ± acos(k / |(d_x, d_z)|); the description's
/// estimates (rocker at (−5.753, −8.5001, 3.2553), φ ≈ 118°) are on the − branch.
fn rocker_angle(theta: f64) -> f64 {
    let (s, c) = theta.sin_cos();
    let (dx, dy, dz) = (-4.0, -8.5 + 2.0 * s, -2.0 * c);
    let k = (12.2_f64.powi(2) - 7.4_f64.powi(2) - (dx * dx + dy * dy + dz * dz)) / 14.8;
    dz.atan2(dx) - (k / dx.hypot(dz)).acos()
}

/// The rocker angle of the solver's state at t, with its first and second time derivatives:
/// C − D is twice the rocker's origin (the midpoint of its pins) minus D, so φ = atan2(Z, X)
/// with X = x_r + 4 and Z = z_r.
fn solver_rocker_angle(
    q: &[f64; fb::N],
    qd: &[f64; fb::N],
    qdd: &[f64; fb::N],
    t: f64,
) -> [f64; 3] {
    let [r, rd, rdd] = four_bar_bodies(q, qd, qdd, t)[ROCKER];
    let (x, z) = (r[0] + 4.0, r[2]);
    let (xd, zd, xdd, zdd) = (rd[0], rd[2], rdd[0], rdd[2]);
    let r2 = x * x + z * z;
    let cross = x * zd - z * xd;
    let phid = cross / r2;
    let phidd = (x * zdd - z * xdd) / r2 - 2.0 * cross * (x * xd + z * zd) / (r2 * r2);
    [z.atan2(x), phid, phidd]
}

/// The slider-crank's slider position at crank angle θ.
///
/// The crank turns about global x through A = (0, 0.1, 0.12), so its pin (crank point
/// (0, 0.08, 0)) is B = (0, 0.1 + 0.08 cos θ, 0.12 + 0.08 sin θ); the slider's origin C slides
/// along the global x axis, C = (x, 0, 0), and the rod (points (±0.15, 0, 0)) holds |C − B| =
/// 0.3. This is the offset slider-crank x = r cos θ' + √(l² − (r sin θ' − e)²) seen along the
/// crank axis, whose pin stays in the plane x = 0: x = ±√(0.3² − B_y² − B_z²), and the
/// description's estimates (x ≈ 0.1996) are on the + branch.
fn slider_x(theta: f64) -> f64 {
    let (s, c) = theta.sin_cos();
    let (by, bz) = (0.1 + 0.08 * c, 0.12 + 0.08 * s);
    (0.09 - by * by - bz * bz).sqrt()
}

/// Value, first and second derivative of `f` at `t` by central differences with step `h`;
/// `minus` is the difference of two values (of angles, wrapped).
fn derivatives(f: impl Fn(f64) -> f64, minus: fn(f64, f64) -> f64, t: f64, h: f64) -> [f64; 3] {
    let (m, z, p) = (f(t - h), f(t), f(t + h));
    [z, minus(p, m) / (2.0 * h), (minus(p, z) - minus(z, m)) / (h * h)]
}

/// The difference of two lengths.
fn length_difference(a: f64, b: f64) -> f64 {
    a - b
}

/// The difference of two angles, wrapped into (−π, π].
fn angle_difference(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(2.0 * PI);
    if d > PI { d - 2.0 * PI } else { d }
}

/// Newton stops at max |Φ| ≤ 1e-10 with Φ_q well conditioned away from the (absent) toggles,
/// so positions are within about 1e-9 of the closed form. The closed forms' derivatives are
/// central differences: step 1e-4 s leaves a truncation error of h²/6 |f'''| ≤ 1e-7 for these
/// cranks (ω ≤ 2π, unit-sized derivatives) and round-off of about 1e-16 / h² ≈ 1e-8 in the
/// second derivative, so 1e-5 relative to the motion's scale (ω and ω² times the amplitude)
/// separates them from the solver's, while another branch is off by order one.
const POSITION: f64 = 1e-8;
const DERIVATIVE: f64 = 1e-5;
const STEP: f64 = 1e-4;

/// Calls of `jump_deg` each: two crank turns, and at least 24 calls.
fn calls(jump_deg: f64) -> u32 {
    ((720.0 / jump_deg).ceil() as u32).max(24)
}

/// The four-bar through at least two crank turns in calls of `jump_deg` each; returns the largest
/// number of Newton iterations one call took.
fn four_bar_with_jumps(jump_deg: f64, groups: Groups<'static>) -> u32 {
    let mut solver = Solver::new(FourBar, fb::Q0);
    solver.set_predictor(true);
    solver.set_continuity_groups(groups);
    let dt = jump_deg.to_radians() / FOUR_BAR_OMEGA;
    let mut most = 0;
    for k in 0..=calls(jump_deg) {
        let t = fb::T_START + f64::from(k) * dt;
        let report = solver
            .advance_to(t)
            .unwrap_or_else(|e| panic!("four-bar, {jump_deg}° per call, t = {t}: {e}"));
        most = most.max(report.iterations);
        let got = solver_rocker_angle(solver.q(), solver.qd(), solver.qdd(), t);
        let want = derivatives(|t| rocker_angle(FOUR_BAR_OMEGA * t), angle_difference, t, STEP);
        let context = format!("four-bar, {jump_deg}° per call, t = {t}: {got:?} against {want:?}");
        assert!(angle_difference(got[0], want[0]).abs() < POSITION, "{context}");
        // φ̇ is of the order of ω = π rad/s and φ̈ of ω² ≈ 10 rad/s².
        assert!((got[1] - want[1]).abs() < DERIVATIVE * FOUR_BAR_OMEGA, "{context}");
        assert!((got[2] - want[2]).abs() < DERIVATIVE * FOUR_BAR_OMEGA.powi(2), "{context}");
        // The rocker's pivot stays at y = −8.5 (the rocker's origin is on its axis).
        let y = four_bar_bodies(solver.q(), solver.qd(), solver.qdd(), t)[ROCKER][0][1];
        assert!((y + 8.5).abs() < POSITION, "{context}");
    }
    most
}

/// The slider-crank through at least two crank turns in calls of `jump_deg` each.
fn slider_crank_with_jumps(jump_deg: f64, groups: Groups<'static>) -> u32 {
    let mut solver = Solver::new(SliderCrank5body, sc::Q0);
    solver.set_predictor(true);
    solver.set_continuity_groups(groups);
    let dt = jump_deg.to_radians() / SLIDER_OMEGA.abs();
    let mut most = 0;
    for k in 0..=calls(jump_deg) {
        let t = sc::T_START + f64::from(k) * dt;
        let report = solver
            .advance_to(t)
            .unwrap_or_else(|e| panic!("slider-crank, {jump_deg}° per call, t = {t}: {e}"));
        most = most.max(report.iterations);
        let mut bodies = [[[0.0; 7]; 3]; sc::BODIES];
        sc::expand(solver.q(), solver.qd(), solver.qdd(), t, &mut bodies);
        let got = bodies[SLIDER].map(|c| c[0]);
        let want =
            derivatives(|t| slider_x(SLIDER_THETA0 + SLIDER_OMEGA * t), length_difference, t, STEP);
        let context =
            format!("slider-crank, {jump_deg}° per call, t = {t}: {got:?} against {want:?}");
        // x is about 0.2 m, ẋ of the order of 0.08 m · 2π rad/s and ẍ of 0.08 m · (2π)².
        assert!((got[0] - want[0]).abs() < POSITION, "{context}");
        assert!((got[1] - want[1]).abs() < DERIVATIVE * SLIDER_OMEGA.abs(), "{context}");
        assert!((got[2] - want[2]).abs() < DERIVATIVE * SLIDER_OMEGA.powi(2), "{context}");
    }
    most
}

#[test]
fn the_four_bar_stays_on_its_branch_with_any_jump_per_call() {
    for jump in [10.0, 90.0, 120.0, 179.0] {
        four_bar_with_jumps(jump, Groups::Each);
    }
    // The unknowns are whole bodies here, so the command line's grouping applies too.
    four_bar_with_jumps(179.0, Groups::Bodies);
}

#[test]
fn the_slider_crank_stays_on_its_branch_with_any_jump_per_call() {
    for jump in [10.0, 90.0, 120.0, 179.0] {
        slider_crank_with_jumps(jump, Groups::Each);
    }
    slider_crank_with_jumps(179.0, Groups::Bodies);
}

/// Plain `position` calls with `jump_deg` of crank per call, as a control loop without step
/// control makes them; returns the first time at which `on_branch` fails, if any.
fn first_branch_jump<M: Mechanism<N>, const N: usize>(
    mut solver: Solver<M, N>,
    dt: f64,
    calls: u32,
    on_branch: impl Fn(&[f64; N], f64) -> bool,
) -> Option<f64> {
    for k in 0..=calls {
        let t = f64::from(k) * dt;
        if solver.position(t).is_ok() && !on_branch(solver.q(), t) {
            return Some(t);
        }
    }
    None
}

#[test]
fn plain_position_jumps_branch_where_advance_to_does_not() {
    // Without step control, calls of 179° of crank each on the four-bar, as a control loop
    // without step control makes them, converge on the other assembly within 24 calls, and
    // `position` still returns `Ok`.
    let dt = 179.0_f64.to_radians() / FOUR_BAR_OMEGA;
    let rocker_ok = |q: &[f64; fb::N], t: f64| {
        let r = four_bar_bodies(q, &[0.0; fb::N], &[0.0; fb::N], t)[ROCKER][0];
        let phi = r[2].atan2(r[0] + 4.0);
        angle_difference(phi, rocker_angle(FOUR_BAR_OMEGA * t)).abs() < POSITION
    };
    let plain = first_branch_jump(Solver::new(FourBar, fb::Q0), dt, calls(179.0), rocker_ok);
    assert!(plain.is_some(), "plain position stayed on the branch: the premise of the test");

    // The slider-crank, whose crank is now an explicit function of t (`symbolic::substitute`),
    // keeps its branch under plain calls too; step control must still hold it there.

    // The same calls under step control stay on the branch, checked against the closed forms
    // at every call.
    four_bar_with_jumps(179.0, Groups::Each);
    slider_crank_with_jumps(170.0, Groups::Each);
}

/// An engine that stands still: an attempt succeeds only at the time of the last accepted
/// point, as one whose every representable sub-step is a jump.
struct StandStill {
    at: f64,
}

impl codegen::stepping::Engine for StandStill {
    fn attempt(
        &mut self,
        t: f64,
    ) -> Result<codegen::stepping::Point, codegen::stepping::Rejection> {
        if t == self.at {
            Ok(codegen::stepping::Point {
                t,
                q: vec![0.0; 7],
                qd: vec![0.0; 7],
                qdd: vec![0.0; 7],
                iterations: 1,
                residual: 0.0,
                pivot_ratio: 1.0,
            })
        } else {
            Err(codegen::stepping::Rejection {
                trouble: Trouble::BranchJump,
                message: format!("no step to t = {t}"),
                point: None,
                body: None,
            })
        }
    }

    fn accept(&mut self, p: &codegen::stepping::Point) {
        self.at = p.t;
    }
}

#[test]
fn the_engines_step_control_ends_where_sub_steps_no_longer_change_t() {
    // At t = 1e17 the spacing of f64 is 16: a sub-step of 4 rounds back onto the start and
    // always "succeeds", so halving and doubling would go on forever without the rule.
    let t0 = 1e17;
    let mut engine = StandStill { at: t0 };
    let start = codegen::stepping::first(&mut engine, t0).expect("the start stands");
    let stop = codegen::stepping::advance(&mut engine, &start, t0 + 64.0).unwrap_err();
    assert_eq!(stop.trouble, Trouble::NoConvergence, "{}", stop.message);
    assert_eq!(stop.t, t0 + 64.0);
    assert!(stop.message.contains("no longer changes t"), "{}", stop.message);
    assert_eq!(stop.near.map(|p| p.t), Some(t0));
}

#[test]
fn advance_to_factors_once_per_step_and_its_ratio_tracks_dense_lu() {
    // The R-S-S-R over one revolution in 1000 steps, as `benches/rssr_revolution.toml`.
    use generated::rssr::{self, Rssr};
    let dt = 2.0 * PI / 146.6 / 1000.0;
    let mut solver = Solver::new(Rssr, rssr::Q0);
    solver.set_predictor(true);
    let (mut lo, mut hi) = (f64::INFINITY, 0.0_f64);
    for k in 0..=1000 {
        let t = f64::from(k) * dt;
        let report = solver.advance_to(t).unwrap_or_else(|e| panic!("t = {t}: {e}"));
        let mut jac = [[0.0; rssr::N]; rssr::N];
        Rssr.jacobian(solver.q(), t, &mut jac);
        let dense = runtime::lu::factor(&mut jac, &mut [0; rssr::N]).expect("regular");
        let gap = report.pivot_ratio / (dense.smallest / dense.largest);
        (lo, hi) = (lo.min(gap), hi.max(gap));
    }
    // One factorisation per step, by a static order: the step control adds none. The first
    // point is solved from the description's estimates by full Newton (three iterations, so
    // two more factorisations); every later one by the predictor's chord step.
    let counts = solver.factor_counts();
    assert_eq!(counts.dense, 0, "{counts:?}");
    assert!((1001..=1003).contains(&counts.structured), "{counts:?}");
    // The static orders' ratio stays within the factor runtime::step::STRUCTURED_MARGIN
    // assumes of partial pivoting's (0.18 to 1 here, measured when the margin was chosen).
    assert!(lo > 1.0 / runtime::step::STRUCTURED_MARGIN && hi <= 1.0 + 1e-12, "{lo} {hi}");
}
