//! Redundancy over the whole motion (contract §1, "Redundancy over the whole motion") and
//! overconstrained linkages through full cycles from any start (issue 15 point 5), on both
//! engines, against closed forms, with the descriptions in `tests/redundancy/` (each file says
//! what it is; `bennett.py` and `bricard.py` there write the Bennett and Bricard ones):
//!
//! | case | expected | why |
//! |---|---|---|
//! | `bennett_{a,b}_{0,45,90,135,180}_{5,20}`, `bennett_{a,b}_{m149,1rad}` | a full turn of the crank from 0, 45°, 90°, 135° and 180° in steps of 5° and 20°, and from −149° (1°) and 1 rad (5°), predictor on and off, every row holding and every joint on the Bennett closed form; every 5° grid and the 20° grids from 0 and 180° land on θ1 = 0 and π, the others step over them; the redundant set named there changes and changes back | the whole Φ_q keeps column rank 21 over the cycle; only rows chosen once at the start would become singular at θ1 = 0 and π |
//! | `bennett_{a,b}_0_20` started 1e-6 rad before θ1 = 0 | the closed form, accelerations included | no digits lost next to the configuration where a fixed choice of rows degenerates |
//! | `bricard_{0,45,90,135,180}_{5,20}` (line-symmetric Bricard six-bar, `bricard.py`), both engines | the same full turns, every joint on an independent construction of the branch ([`Bricard`]: the loop closes when L1 L2 L3 is a half-turn); the generated engine with the predictor off, and on (ignored: 5.4e-6 off in one acceleration) | one redundant row (`joint J6 row 5`) whose dependency holds over the whole cycle (κ̂ ≤ 11) |
//! | `../stability/planar_four_bar_4r`, both engines, predictor on and off | a full turn of the crank and 5° more on the closed form of the crank-rocker | three redundant rows (out of the plane) over a Grashof crank's whole turn |
//! | `parallelogram_landing`, `parallelogram_over`, both engines, predictor on and off | landing on the flat configuration: a named `singular` (joints O and D) at that grid time; stepping over it: every step on the parallelogram branch (the rocker turning with the crank, the coupler translating) | the flat configuration is a bifurcation: the whole Φ_q loses rank there, so an engine stops there rather than choose a branch, and a step that passes it must never switch branches |
//! | `four_bar_conflict` | `inconsistent` at t = 0 naming both drivers, from `solve` and from `check` (exit status 2) | the drivers agree on the angle at t = 0 but not on its rate |
//! | `four_bar_conflict_later` | `check` consistent, naming `driver push`; `solve` stops with `inconsistent` at the first grid time, naming both drivers | the drivers agree to second order at t = 0 and part at once in acceleration |
//! | `four_bar_fix_conflict` | `inconsistent` at t = 0 naming joint O and the constraint, from `solve` and `check` | the `fix` holds the crank 0.05 above the joint that holds it at 0 |
//! | `bennett_a_90_5` with b rounded to 0.683 | `inconsistent` at t = 0 | a / sin α1 ≠ b / sin α2 (by 1.9e-5 relative): the loop is a rigid structure that the driver cannot turn |
//! | `four_bar_flat` | `check`, the generic engine and the symbolic layer (generated engine) all name `constraint flat`; both engines run the whole grid with every row holding | one naming rule (`codegen::generic::redundancy`) |
//! | `four_bar_conflict`, `four_bar_conflict_later`, `four_bar_fix_conflict` on the generated engine | the generic engine's `inconsistent`, at the same time, naming the same equations | the generated solver checks the rows its reduced system leaves out after every attempt (`dropped_residuals`) and refuses a step where one does not hold |
//! | `bennett_*` on the generated engine, predictor on and off | with the predictor on, the generic engine's result: full turns on the closed form, every row holding, the redundant set changing at the same frames (JSON `redundant` too, grids landing on θ1 = 0 and π), with the predictor on and off | the rows kept at the start degenerate at θ1 = 0 or π (225° for geometry b from 180°) while the whole Φ_q does not; the runtime then solves with the rows the row-pivoted LU of the whole stack picks (`runtime::rows`) |

use std::f64::consts::PI;
use std::path::Path;

use codegen::emit::Scalar;
use codegen::engine::{self, Built, Settings};
use codegen::generic::{Analysis, Equations, Failure, FailureKind, Frame};
use codegen::model::Mechanism;
use codegen::report::{self, StepResult};
use codegen::testing;

/// The descriptions of this suite.
const DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/redundancy");

fn path(name: &str) -> String {
    format!("{DIR}/{name}.toml")
}

fn load(name: &str) -> Mechanism {
    testing::load(Path::new(&path(name))).mechanism
}

/// What the generic engine reported: frames, their results and the failure.
struct Run {
    frames: Vec<Frame>,
    steps: Vec<StepResult>,
    failure: Option<codegen::generic::Failure>,
    /// The equations named redundant at the initial configuration.
    named: Vec<String>,
}

/// What the generated engine reported, as [`run`] for the generic one (`named`: the equations
/// the generator left out).
fn run_generated(mech: &Mechanism, predictor: bool) -> Run {
    let built = engine::build_in(mech, Scalar::F64).expect("the generated solver builds");
    run_built(mech, &built, predictor, None)
}

/// [`run_generated`] in the floating-point type `scalar`, at the Newton tolerance `tolerance`
/// (the description's when `None`).
fn run_generated_in(
    mech: &Mechanism,
    predictor: bool,
    scalar: Scalar,
    tolerance: Option<f64>,
) -> Run {
    let built = engine::build_in(mech, scalar).expect("the generated solver builds");
    run_built(mech, &built, predictor, tolerance)
}

/// A run of the generated solver `built` of `mech` (built once, run with either predictor).
fn run_built(mech: &Mechanism, built: &Built, predictor: bool, tolerance: Option<f64>) -> Run {
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    let analysis = Analysis::new(&eq, &prep);
    let layout = report::layout(mech);
    let (mut frames, mut steps) = (Vec::new(), Vec::new());
    let settings = Settings { predictor, ..Settings::DEFAULT };
    let report = engine::run_with(built, &analysis, tolerance, settings, |f| {
        steps.push(report::step_result(mech, &layout, f));
        frames.push(f.clone());
        Ok(())
    })
    .expect("the generated solver runs");
    Run { frames, steps, failure: report.failure, named: built.removed.clone() }
}

fn run(mech: &Mechanism, predictor: bool) -> Run {
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    let layout = report::layout(mech);
    let (mut frames, mut steps) = (Vec::new(), Vec::new());
    let report = Analysis::new(&eq, &prep)
        .with_predictor(predictor)
        .run(|f| {
            steps.push(report::step_result(mech, &layout, f));
            frames.push(f.clone());
            Ok::<(), ()>(())
        })
        .expect("the sink does not fail");
    let named = prep.redundant.iter().map(|&k| eq.labels()[k].equation()).collect();
    Run { frames, steps, failure: report.failure, named }
}

/// Every row of the description, the redundant ones included, at every reported frame:
/// max |Φ_i| over all rows, evaluated afresh from the frame's q.
fn worst_row(mech: &Mechanism, frames: &[Frame]) -> f64 {
    let eq = Equations::new(mech);
    frames.iter().map(|f| eq.evaluate(&f.q, &f.qd, f.t).phi.amax()).fold(0.0, f64::max)
}

/// The Newton tolerance of the descriptions (the default), which every row must meet.
const TOLERANCE: f64 = 1e-10;

/// The difference of two angles, wrapped to (−π, π].
fn angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(2.0 * PI);
    if d > PI { d - 2.0 * PI } else { d }
}

/// The Bennett linkage's output angle θ2 and its first and second derivatives with respect to
/// θ1, from tan(θ1/2) tan(θ2/2) = k, k = sin((α2 + α1)/2) / sin((α2 − α1)/2): with φ = θ1/2,
/// θ2 = 2 atan2(k cos φ, sin φ), dθ2/dθ1 = −k / D and d²θ2/dθ1² = k (1 − k²) sin φ cos φ / D²,
/// where D = sin²φ + k² cos²φ.
fn bennett(theta1: f64, alpha1: f64, alpha2: f64) -> [f64; 3] {
    let k = ((alpha2 + alpha1) / 2.0).sin() / ((alpha2 - alpha1) / 2.0).sin();
    let (s, c) = (theta1 / 2.0).sin_cos();
    let d = s * s + k * k * c * c;
    [2.0 * (k * c).atan2(s), -k / d, k * (1.0 - k * k) * s * c / (d * d)]
}

/// The twists (α1, α2) of the two geometries (`bennett.py`).
fn twists(name: &str) -> (f64, f64) {
    let deg = PI / 180.0;
    if name.starts_with("bennett_a") { (45.0 * deg, 75.0 * deg) } else { (45.0 * deg, 90.0 * deg) }
}

/// The crank's angle at t = 0 of a description driving J1 at a constant rate.
fn start_angle(mech: &Mechanism) -> f64 {
    match mech.drivers[0].law {
        codegen::model::Law::Polynomial { start, .. } => start,
        _ => unreachable!("the loops of this suite drive J1 at a constant rate"),
    }
}

/// Checks every step of a run of a loop driven by J1 at θ̇1 = 1, θ̈1 = 0 from `start` against
/// `expected`, the (θ, θ̇, θ̈) of every joint in order at θ1, within `tolerances` for the
/// angles, rates and accelerations (θ̇ and θ̈ are derivatives with respect to θ1 and t alike).
fn assert_joints(
    name: &str,
    mech: &Mechanism,
    steps: &[StepResult],
    tolerances: [f64; 3],
    expected: impl Fn(f64) -> Vec<[f64; 3]>,
) {
    let start = start_angle(mech);
    for s in steps {
        let theta1 = start + s.t;
        let expected = expected(theta1);
        assert_eq!(s.joints.len(), expected.len(), "{name}");
        for (j, e) in s.joints.iter().zip(expected) {
            let [a, ad, add] = j.angle.expect("every joint has references");
            let errors = [angle_diff(a, e[0]).abs(), (ad - e[1]).abs(), (add - e[2]).abs()];
            assert!(
                errors.iter().zip(tolerances).all(|(e, t)| *e < t),
                "{name} t = {} θ1 = {theta1}: joint {} (θ, θ̇, θ̈) = ({a}, {ad}, {add}), closed \
                 form {e:?}",
                s.t,
                j.name
            );
        }
    }
}

/// Checks every step of a Bennett run against the closed form: J1 at the driven θ1, J2 at
/// θ2(θ1), J3 at −θ1 and J4 at −θ2, with their rates and accelerations (θ̇1 = 1, θ̈1 = 0).
fn assert_on_the_closed_form(name: &str, mech: &Mechanism, steps: &[StepResult]) {
    let (alpha1, alpha2) = twists(name);
    // Positions: Newton meets max |Φ| ≤ 1e-10 on links of unit size where Φ_q has a pivot
    // ratio above 0.17 (balanced units) over the whole cycle, so angles are within about 1e-9
    // of the solution; rates and accelerations come from linear solves at that configuration,
    // with |dθ2/dθ1| ≤ 4 and |d²θ2/dθ1²| ≤ 10 here, so their error is that position error
    // times the slope of the curve: 1e-7 and 1e-6 leave two orders of margin.
    assert_joints(name, mech, steps, [1e-7, 1e-7, 1e-6], |theta1| {
        let [theta2, d1, d2] = bennett(theta1, alpha1, alpha2);
        vec![[theta1, 1.0, 0.0], [theta2, d1, d2], [-theta1, -1.0, 0.0], [-theta2, -d1, -d2]]
    });
}

/// The starts and steps, in degrees, of the full-cycle grids of issue 15 point 5 (`bennett.py`
/// and `bricard.py` write one description `{prefix}_{start}_{step}` per pair): every 5° grid
/// lands on θ1 = 0 and π (up to the rounding of t), the 20° grids from 0 and 180° too, those
/// from 45°, 90° and 135° step over both.
const STARTS: [u32; 5] = [0, 45, 90, 135, 180];
const STEPS: [u32; 2] = [5, 20];

/// The full-cycle grids of the loop `prefix`.
fn grids(prefix: &str) -> Vec<String> {
    STARTS.iter().flat_map(|a| STEPS.iter().map(move |s| format!("{prefix}_{a}_{s}"))).collect()
}

/// Every Bennett description: the grids of both geometries, and the turns from −149° in steps
/// of 1° and from 1 rad in steps of 5°.
fn bennett_names() -> Vec<String> {
    ["a", "b"]
        .iter()
        .flat_map(|g| {
            let mut names = grids(&format!("bennett_{g}"));
            names.extend(["m149", "1rad"].map(|s| format!("bennett_{g}_{s}")));
            names
        })
        .collect()
}

/// A run that went through the whole grid with every row of the description holding.
fn assert_full_cycle(name: &str, mech: &Mechanism, r: &Run) {
    assert!(r.failure.is_none(), "{name}: {:?}", r.failure);
    assert_eq!(r.frames.len(), mech.time.count, "{name}");
    // Every row holds at every step, the redundant ones included.
    let worst = worst_row(mech, &r.frames);
    assert!(worst <= TOLERANCE, "{name}: max |Φ| = {worst:e}");
}

#[test]
fn bennett_linkages_turn_full_cycles_from_any_start_on_the_closed_form() {
    for name in bennett_names() {
        let mech = load(&name);
        for predictor in [true, false] {
            let r = run(&mech, predictor);
            assert_full_cycle(&format!("{name} (predictor {predictor})"), &mech, &r);
            assert_on_the_closed_form(&name, &mech, &r.steps);
        }
    }
}

/// The line-symmetric Bricard linkage of `bricard.py`: DH links Lk = Rz(θk) Tz(dk) Tx(ak) Rx(αk)
/// with (a, α, d) = (1, 60°, 0.2), (1.2, 100°, −0.3), (0.8, 40°, 0.1) for k = 1, 2, 3 and again
/// for k = 4, 5, 6, and θ4 = θ1, θ5 = θ2, θ6 = θ3.
///
/// No closed form: the configuration at θ1 is an independent numeric construction. By the
/// line symmetry the loop L1 ⋯ L6 = I closes exactly when M = L1 L2 L3 is a half-turn,
/// M² = I, 12 equations of rank 2 in (θ2, θ3), solved here by Gauss–Newton (central-difference
/// Jacobian) to a residual below 1e-13, branch by branch from (θ2, θ3) ≈ (191.8°, 2.1°) at
/// θ1 = 0 in steps of 1°. Nothing of it is shared with either engine: no joint rows, no
/// Euler parameters, no step control. Rates and accelerations are fourth-order central
/// differences along the branch.
struct Bricard {
    /// (θ2, θ3) at θ1 = k°, k = 0 … 360.
    table: Vec<[f64; 2]>,
}

impl Bricard {
    const LINKS: [[f64; 3]; 3] = [[1.0, 60.0, 0.2], [1.2, 100.0, -0.3], [0.8, 40.0, 0.1]];

    fn new() -> Self {
        let deg = PI / 180.0;
        let mut x = [191.8 * deg, 2.1 * deg];
        let table = (0..=360)
            .map(|k| {
                x = Self::solve(f64::from(k) * deg, x);
                x
            })
            .collect();
        Self { table }
    }

    /// The DH link Rz(θ) Tz(d) Tx(a) Rx(α), written out.
    fn link(theta: f64, [a, alpha, d]: [f64; 3]) -> nalgebra::Matrix4<f64> {
        let (s, c) = theta.sin_cos();
        let (sa, ca) = alpha.to_radians().sin_cos();
        nalgebra::Matrix4::new(
            c,
            -s * ca,
            s * sa,
            a * c, //
            s,
            c * ca,
            -c * sa,
            a * s, //
            0.0,
            sa,
            ca,
            d, //
            0.0,
            0.0,
            0.0,
            1.0,
        )
    }

    /// M² − I, its rotation and translation rows, for θ1 and (θ2, θ3) = x.
    fn residual(theta1: f64, x: [f64; 2]) -> nalgebra::SVector<f64, 12> {
        let [l1, l2, l3] = Self::LINKS;
        let m = Self::link(theta1, l1) * Self::link(x[0], l2) * Self::link(x[1], l3);
        let e = m * m - nalgebra::Matrix4::identity();
        nalgebra::SVector::from_iterator(e.fixed_rows::<3>(0).transpose().iter().copied())
    }

    /// Gauss–Newton on M² = I from x.
    fn solve(theta1: f64, mut x: [f64; 2]) -> [f64; 2] {
        for _ in 0..30 {
            let r = Self::residual(theta1, x);
            let h = 1e-6;
            let column = |k: usize| {
                let (mut up, mut down) = (x, x);
                up[k] += h;
                down[k] -= h;
                (Self::residual(theta1, up) - Self::residual(theta1, down)) / (2.0 * h)
            };
            let j = nalgebra::SMatrix::<f64, 12, 2>::from_columns(&[column(0), column(1)]);
            let dx = (j.transpose() * j)
                .lu()
                .solve(&(-j.transpose() * r))
                .expect("M² = I has rank 2 in (θ2, θ3) along the branch");
            x = [x[0] + dx[0], x[1] + dx[1]];
            if dx.amax() < 1e-14 {
                break;
            }
        }
        let r = Self::residual(theta1, x).amax();
        assert!(r < 1e-13, "the Bricard reference at θ1 = {theta1}: |M² − I| = {r:e}");
        x
    }

    /// (θ, dθ/dθ1, d²θ/dθ1²) of J2 and J3 at θ1. Derivatives by fourth-order central
    /// differences with h = 5e-3: truncation h⁴/30 |θ⁽⁵⁾| and h⁴/90 |θ⁽⁶⁾| stay below 1e-8 for
    /// derivatives up to 400, round-off (1e-15 per solution) below 1e-10.
    fn at(&self, theta1: f64) -> [[f64; 3]; 2] {
        let deg = PI / 180.0;
        let reduced = theta1.rem_euclid(2.0 * PI);
        // 0 ≤ k ≤ 359: the floor of a number in [0, 360].
        let k = ((reduced / deg).floor() as usize).min(359);
        let x = Self::solve(reduced, self.table[k]);
        let h = 5e-3;
        let f = |j: f64| Self::solve(reduced + j * h, x);
        let (m2, m1, p1, p2) = (f(-2.0), f(-1.0), f(1.0), f(2.0));
        [0, 1].map(|i| {
            let d1 = (m2[i] - 8.0 * m1[i] + 8.0 * p1[i] - p2[i]) / (12.0 * h);
            let d2 = (-m2[i] + 16.0 * m1[i] - 30.0 * x[i] + 16.0 * p1[i] - p2[i]) / (12.0 * h * h);
            [x[i], d1, d2]
        })
    }
}

/// Checks every step of a Bricard run against [`Bricard`]: J1 and J4 at θ1, J2 and J5 at θ2,
/// J3 and J6 at θ3.
fn assert_on_the_bricard_branch(name: &str, mech: &Mechanism, steps: &[StepResult], b: &Bricard) {
    // As for the Bennett linkage: positions within about 1e-9 of the solution (Newton's 1e-10
    // on unit links, Φ_q's pivot ratio above 0.05 along the branch); |dθ/dθ1| ≤ 3 and
    // |d²θ/dθ1²| ≤ 10 here, and the reference's own error is below 1e-8.
    assert_joints(name, mech, steps, [1e-7, 1e-7, 1e-6], |theta1| {
        let [j2, j3] = b.at(theta1);
        let j1 = [theta1, 1.0, 0.0];
        vec![j1, j2, j3, j1, j2, j3]
    });
}

#[test]
fn the_bricard_reference_closes_the_loop_of_the_descriptions() {
    // The reference at each start against the initial estimates `bricard.py` wrote: the same
    // construction, written twice, must agree on the branch.
    let b = Bricard::new();
    for name in grids("bricard") {
        let mech = load(&name);
        let [j2, j3] = b.at(start_angle(&mech));
        let r = run(&mech, true);
        let s = &r.steps[0];
        for (joint, e) in [(1, j2[0]), (2, j3[0])] {
            let got = s.joints[joint].angle.expect("references")[0];
            // The assembly at t = 0, within Newton's accuracy (see above).
            assert!(
                angle_diff(got, e).abs() < 1e-7,
                "{name}: J{} at {got}, reference {e}",
                joint + 1
            );
        }
    }
}

#[test]
fn line_symmetric_bricard_linkages_turn_full_cycles_from_any_start() {
    let b = Bricard::new();
    for name in grids("bricard") {
        let mech = load(&name);
        for predictor in [true, false] {
            let r = run(&mech, predictor);
            assert_full_cycle(&format!("{name} (predictor {predictor})"), &mech, &r);
            assert_on_the_bricard_branch(&name, &mech, &r.steps, &b);
        }
    }
}

/// The generated engine's runs of every Bricard grid with the predictor on or off, each
/// solver built once, checked against [`Bricard`].
fn generated_bricard_cycles(predictor: bool) {
    let b = Bricard::new();
    for name in grids("bricard") {
        let mech = load(&name);
        let built = engine::build(&mech).expect("the generated solver builds");
        let r = run_built(&mech, &built, predictor, None);
        assert_full_cycle(&format!("{name} generated (predictor {predictor})"), &mech, &r);
        assert_on_the_bricard_branch(&name, &mech, &r.steps, &b);
    }
}

#[test]
fn generated_line_symmetric_bricard_linkages_turn_full_cycles_from_any_start() {
    generated_bricard_cycles(false);
}

#[test]
fn generated_line_symmetric_bricard_linkages_turn_full_cycles_with_the_predictor() {
    // At bricard_90_5's t = 3.316 (θ1 = 280°, κ̂ 786) one Newton step from the prediction
    // used to land within the tolerance (residual 2.7e-13) and stop there, 1.3e-10 off in q,
    // leaving J4's rate 1.8e-8 and its acceleration 5.4e-6 away from θ̇4 = 1, θ̈4 = 0; the
    // stopping test now asks for round-off (runtime::newton::solve), 5e-12 and 1.6e-9.
    generated_bricard_cycles(true);
}

#[test]
fn the_redundant_rows_named_change_exactly_where_theta1_is_zero_or_pi() {
    // The observation, which the rule reproduces: the rows named at a general
    // configuration are J4's rows 3 to 5; at θ1 = 0 and π (where those rows together with the
    // others lose rank) they are rows 1, 4 and 5.
    let general = ["joint J4 row 3", "joint J4 row 4", "joint J4 row 5"].map(String::from);
    let special = ["joint J4 row 1", "joint J4 row 4", "joint J4 row 5"].map(String::from);
    for name in ["bennett_a_m149", "bennett_b_90_5", "bennett_a_0_20"] {
        let mech = load(name);
        let r = run(&mech, true);
        let on_special = |s: &StepResult| {
            let theta1 = s.joints[0].angle.expect("J1 has references")[0];
            // Grid points on 0 or π land there up to the rounding of t (1e-15).
            angle_diff(theta1, 0.0).abs() < 1e-12 || angle_diff(theta1, PI).abs() < 1e-12
        };
        let mut named = r.named.clone();
        let first = if on_special(&r.steps[0]) { &special } else { &general };
        assert_eq!(&named, first.as_slice(), "{name} at the initial configuration");
        let mut changes = 0;
        for s in &r.steps {
            if let Some(now) = &s.redundant {
                named.clone_from(now);
                changes += 1;
            }
            let expected = if on_special(s) { &special } else { &general };
            assert_eq!(&named, expected.as_slice(), "{name} t = {}", s.t);
        }
        assert!(changes >= 2, "{name}: the set changed {changes} times");
    }
}

#[test]
fn a_step_next_to_theta1_zero_keeps_its_accelerations() {
    // Started 1e-6 rad before θ1 = 0: a set of rows chosen at a general configuration is
    // within 1e-6 of singular there, which cost the accelerations 71 % before.
    for geometry in ["a", "b"] {
        let name = format!("bennett_{geometry}_0_20");
        let text = std::fs::read_to_string(path(&name)).expect("description");
        let text = text.replace("law = { start = 0.0,", "law = { start = -1e-6,");
        assert!(text.contains("start = -1e-6"), "the law was rewritten");
        let mech = testing::load_toml(&text);
        let r = run(&mech, true);
        assert!(r.failure.is_none(), "{name}: {:?}", r.failure);
        assert_on_the_closed_form(&name, &mech, &r.steps);
    }
}

/// Checks that a step of a parallelogram run lies on the parallelogram branch: the rocker's
/// angle is the crank's and the coupler keeps its orientation (identity Euler parameters); the
/// antiparallelogram branch has neither.
fn assert_on_the_parallelogram_branch(name: &str, s: &StepResult) {
    let (crank, rocker) = (s.joints[0].angle.expect("O"), s.joints[1].angle.expect("D"));
    let p = s.bodies[1].p;
    // Positions within 1e-9 of the solution (Newton's 1e-10 on unit links).
    assert!(
        angle_diff(crank[0], rocker[0]).abs() < 1e-7
            && (p[0].abs() - 1.0).abs() < 1e-7
            && (crank[1] - rocker[1]).abs() < 1e-6,
        "{name} t = {}: crank {crank:?}, rocker {rocker:?}, coupler p {p:?}",
        s.t
    );
}

/// The parallelogram through its flat configurations, on the engine `engine` (the generic one
/// or the generated solvers `built` of the two descriptions):
/// - landing on it (`parallelogram_landing`, θ = π at t = π/2) stops there with `singular`
///   naming joints O and D, every step before it on the parallelogram branch;
/// - stepping over it (`parallelogram_over`, θ = π and 2π between grid points) runs the whole
///   grid on the parallelogram branch, every row holding.
///
/// Never a step on the antiparallelogram branch: at the flat configuration the branches cross
/// and the whole Φ_q loses column rank, so no engine may land there and go on, and a step that
/// passes it must come out on the branch it started on (the step control's continuity check).
fn assert_parallelogram_behaviour(label: &str, run: impl Fn(&Mechanism, bool) -> Run) {
    for predictor in [true, false] {
        let name = format!("parallelogram_landing {label} (predictor {predictor})");
        let mech = load("parallelogram_landing");
        let r = run(&mech, predictor);
        let f = r.failure.as_ref().unwrap_or_else(|| panic!("{name}: no stop"));
        assert_eq!(f.kind, FailureKind::Singular, "{name}: {f:?}");
        // The grid lands on θ = π at t = π/2.
        assert!((f.t - PI / 2.0).abs() < 1e-12, "{name}: stopped at {}", f.t);
        for joint in ["joint O", "joint D"] {
            assert!(f.constraints.iter().any(|c| c == joint), "{name}: {joint} in {f:?}");
        }
        assert_eq!(r.steps.len(), 18, "{name}: every step before π/2");
        r.steps.iter().for_each(|s| assert_on_the_parallelogram_branch(&name, s));

        let name = format!("parallelogram_over {label} (predictor {predictor})");
        let mech = load("parallelogram_over");
        let r = run(&mech, predictor);
        assert_full_cycle(&name, &mech, &r);
        r.steps.iter().for_each(|s| assert_on_the_parallelogram_branch(&name, s));
    }
}

#[test]
fn a_parallelogram_stops_singular_on_its_flat_configuration_and_never_switches_branch() {
    assert_parallelogram_behaviour("generic", run);
}

#[test]
fn the_generated_parallelogram_stops_singular_on_its_flat_configuration_and_never_switches_branch()
{
    let built: Vec<(String, Built)> = ["parallelogram_landing", "parallelogram_over"]
        .map(|n| (n.to_owned(), engine::build(&load(n)).expect("the generated solver builds")))
        .into();
    assert_parallelogram_behaviour("generated", |mech, predictor| {
        let (_, b) = built.iter().find(|(n, _)| *n == mech.name).expect("built above");
        run_built(mech, b, predictor, None)
    });
}

/// The planar crank-rocker of four revolutes of the stability suite: 20 joint rows of which
/// three (out of the plane) depend on the others.
fn planar_four_bar() -> Mechanism {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/stability/planar_four_bar_4r.toml");
    testing::load(Path::new(file)).mechanism
}

#[test]
fn a_planar_four_bar_of_four_revolutes_turns_full_cycles_on_both_engines() {
    let mech = planar_four_bar();
    // The crank turns at 0.5 rad/s from 90°: more than a full turn over the grid.
    let last = mech.time.at(mech.time.count - 1);
    assert!(0.5 * last > 2.0 * PI, "the grid ends at {last}");
    let built = engine::build(&mech).expect("the generated solver builds");
    for predictor in [true, false] {
        for (engine, r) in [
            ("generic", run(&mech, predictor)),
            ("generated", run_built(&mech, &built, predictor, None)),
        ] {
            let name = format!("planar_four_bar_4r {engine} (predictor {predictor})");
            assert_full_cycle(&name, &mech, &r);
            for s in &r.steps {
                // The crank's joint angle (0 at 90°) and the rocker pin B against the closed
                // form of the crank-rocker (the intersection of two circles).
                let crank = s.joints[0].angle.expect("J1 has references")[0];
                assert!(angle_diff(crank, 0.5 * s.t).abs() < 1e-7, "{name} t = {}", s.t);
                let expected = crate::stability::rocker_pin(PI / 2.0 + 0.5 * s.t);
                let a = crate::stability::angle_z(&s.bodies[2].p);
                // The rocker's frame started at the identity; B is its local (2.25, 2.165)
                // about O4 = (3.5, 0).
                let local = [2.25 - 3.5, 2.1650635094610964];
                let got = [
                    3.5 + a.cos() * local[0] - a.sin() * local[1],
                    a.sin() * local[0] + a.cos() * local[1],
                ];
                let err = (got[0] - expected[0]).hypot(got[1] - expected[1]);
                // Positions within about 1e-9 of the solution (Newton's 1e-10 on links of
                // unit size, Φ_q well conditioned: Grashof, no toggle on the crank's turn).
                assert!(err < 1e-7, "{name} t = {}: B = {got:?}, closed form {expected:?}", s.t);
            }
        }
    }
}

/// Runs mechgen and returns (status, stdout).
fn mechgen(args: &[&str]) -> (i32, String) {
    let mut argv = vec!["mechgen".into()];
    argv.extend(args.iter().map(Into::into));
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = codegen::cli::run(argv, &mut out, &mut err);
    (code, String::from_utf8(out).expect("UTF-8"))
}

/// `check` and `solve` on `name` both exit with status 2 and the `inconsistent` error at
/// t = 0 naming `involved`.
fn assert_inconsistent_at_start(name: &str, involved: &[&str]) {
    let file = path(name);
    for command in ["check", "solve"] {
        let args: Vec<&str> = match command {
            "check" => vec!["check", &file, "--format", "json"],
            _ => vec!["solve", &file, "--engine", "generic", "--format", "json"],
        };
        let (code, out) = mechgen(&args);
        assert_eq!(code, 2, "{command}: {out}");
        let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
        assert_eq!(v["error"]["kind"], "inconsistent", "{command}: {out}");
        assert_eq!(v["error"]["t"], 0.0, "{command}");
        assert_eq!(v["error"]["constraints"], serde_json::json!(involved), "{command}");
        if command == "solve" {
            assert_eq!(v["steps"].as_array().map(Vec::len), Some(0));
        }
    }
}

#[test]
fn equations_that_contradict_each_other_stop_the_analysis_as_inconsistent() {
    let drivers = ["driver motor", "driver push"];
    // Rates 1 and 1.1 rad/s: the velocity equations conflict at t = 0 already.
    assert_inconsistent_at_start("four_bar_conflict", &drivers);
    // A `fix` 0.05 away from where a joint holds the coordinate.
    assert_inconsistent_at_start("four_bar_fix_conflict", &["joint O", "constraint flat"]);
    // s = t against s = sin t: consistent at t = 0 to second order, so `check` names the
    // later driver redundant and exits 0; the accelerations part at once (−sin t against 0),
    // so the analysis stops at the first grid time after t = 0.
    let file = path("four_bar_conflict_later");
    let (code, out) = mechgen(&["check", &file, "--format", "json"]);
    assert_eq!(code, 0, "{out}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(v["redundant"], serde_json::json!(["driver push"]));
    assert!(v.get("error").is_none(), "{out}");
    let mech = load("four_bar_conflict_later");
    for predictor in [true, false] {
        let r = run(&mech, predictor);
        let f = r.failure.as_ref().expect("the drivers part");
        assert_eq!(f.kind, FailureKind::Inconsistent, "{f:?}");
        assert_eq!(f.t, mech.time.at(1), "{f:?}");
        assert_eq!(f.constraints, drivers, "{f:?}");
        assert_eq!(r.frames.len(), 1, "only t = 0 holds");
    }
    // The b = 0.683 is 0.5 sin 75° / sin 45° = 0.68301270… rounded: no longer a
    // Bennett linkage, the loop of four revolutes has no motion, and its rows cannot all hold
    // at the driven angle.
    let text = std::fs::read_to_string(path("bennett_a_90_5")).expect("description");
    let rounded = text.replace("0.6830127018922194", "0.683");
    assert!(rounded.matches("0.683,").count() >= 2, "b was rounded in J3 and J4");
    let mech = testing::load_toml(&rounded);
    let eq = Equations::new(&mech);
    let f = Analysis::new(&eq, &eq.prepare()).first_failure().expect("inconsistent");
    assert_eq!((f.kind, f.t), (FailureKind::Inconsistent, 0.0), "{f:?}");
}

#[test]
fn a_consistent_redundant_fix_is_named_alike_by_check_and_both_engines() {
    let file = path("four_bar_flat");
    let expected = serde_json::json!(["constraint flat"]);
    let (code, out) = mechgen(&["check", &file, "--format", "json"]);
    assert_eq!(code, 0, "{out}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(v["redundant"], expected, "check");
    let mech = load("four_bar_flat");
    let r = run(&mech, true);
    assert_eq!(serde_json::json!(r.named), expected, "generic");
    assert!(r.failure.is_none(), "{:?}", r.failure);
    assert_eq!(r.frames.len(), mech.time.count);
    let worst = worst_row(&mech, &r.frames);
    assert!(worst <= TOLERANCE, "max |Φ| = {worst:e}");
    // The generated engine eliminates the crank's z with `flat`, so its reduced system
    // leaves out joint O's z row instead; it names the equations by the same rule.
    let sys = codegen::symbolic::Symbolic::build(&mech).expect("the reduced system");
    let named: Vec<String> = sys.redundant.iter().map(|l| l.equation()).collect();
    assert_eq!(serde_json::json!(named), expected, "symbolic");
    let (code, out) = mechgen(&["solve", &file, "--engine", "generated", "--format", "json"]);
    assert_eq!(code, 0, "{out}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(v["removed"], expected, "generated");
    assert_eq!(v["steps"].as_array().map(Vec::len), Some(mech.time.count));
    // Every row holds at every step of the generated engine too, joint O's z row (left out
    // of its reduced system and checked at run time) included.
    for predictor in [true, false] {
        let r = run_generated(&mech, predictor);
        assert!(r.failure.is_none(), "{:?}", r.failure);
        assert_eq!(r.frames.len(), mech.time.count);
        let worst = worst_row(&mech, &r.frames);
        assert!(worst <= TOLERANCE, "generated: max |Φ| = {worst:e}");
    }
}

#[test]
fn the_generated_engine_stops_on_contradicting_equations_as_the_generic_one_does() {
    // The generated solver leaves one of the conflicting rows out of its reduced system; it
    // checks that row after every attempt, so it stops where the generic engine stops.
    for name in ["four_bar_conflict", "four_bar_conflict_later", "four_bar_fix_conflict"] {
        let mech = load(name);
        let generic = run(&mech, true);
        let expected: &Failure = generic.failure.as_ref().expect("the generic engine stops");
        assert_eq!(expected.kind, FailureKind::Inconsistent, "{name}: {expected:?}");
        for predictor in [true, false] {
            let r = run_generated(&mech, predictor);
            let f = r.failure.as_ref().expect("the generated engine stops");
            assert_eq!(f.kind, FailureKind::Inconsistent, "{name}: {f:?}");
            assert_eq!(f.t, expected.t, "{name}: {f:?}");
            assert_eq!(f.constraints, expected.constraints, "{name}: {f:?}");
            assert_eq!(r.frames.len(), generic.frames.len(), "{name}: steps written");
        }
        // The command line: status 2 and the same error object.
        let file = path(name);
        let (code, out) = mechgen(&["solve", &file, "--engine", "generated", "--format", "json"]);
        assert_eq!(code, 2, "{name}: {out}");
        let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
        assert_eq!(v["error"]["kind"], "inconsistent", "{name}: {out}");
        assert_eq!(v["error"]["constraints"], serde_json::json!(expected.constraints), "{name}");
    }
}

#[test]
fn the_generated_engine_re_selects_its_rows_and_turns_every_bennett_cycle() {
    // The generated engine keeps the rows chosen at the initial configuration while they are
    // regular; where they degenerate and the whole Φ_q does not (θ1 = 0 and π for the general
    // starts, 225° for geometry b from 180°), its runtime solves with the rows that the
    // row-pivoted LU of the whole stack picks (`runtime::rows`). So it passes where the
    // generic engine does, on every Bennett grid (starts 0°, 45°, 90°, 135°, 180°, −149° and
    // 1 rad, steps of 5° and 20°), predictor on and off: full turns, every step on the closed
    // form (the generic test's tolerances and reasons), every row of the description holding,
    // the left-out ones included, and the redundant set reported where it changes, frame by
    // frame as the generic engine reports it.
    for name in bennett_names() {
        let mech = load(&name);
        let built = engine::build(&mech).expect("the generated solver builds");
        for predictor in [true, false] {
            let r = run_built(&mech, &built, predictor, None);
            assert_full_cycle(&format!("{name} generated (predictor {predictor})"), &mech, &r);
            assert_on_the_closed_form(&name, &mech, &r.steps);
            let generic = run(&mech, predictor);
            let changes = |run: &Run| -> Vec<(usize, Vec<usize>)> {
                let f = run.frames.iter().filter_map(|f| Some((f.index, f.redundant.clone()?)));
                f.collect()
            };
            assert_eq!(changes(&r), changes(&generic), "{name} (predictor {predictor})");
        }
    }
}

#[test]
fn the_generated_engine_lands_on_theta1_zero_and_pi_and_reports_the_redundant_set() {
    // The grids land exactly on θ1 = 0 and π (steps of 20° or 5° from 0, 90° and 180°), where the
    // rows kept at a general configuration are singular; the JSON of `solve` reports the
    // changes of the redundant set there as the generic engine's does.
    for name in ["bennett_a_0_20", "bennett_a_90_5", "bennett_b_180_20"] {
        let file = path(name);
        let json = |engine: &str| {
            let (code, out) = mechgen(&["solve", &file, "--engine", engine, "--format", "json"]);
            assert_eq!(code, 0, "{name} {engine}: {out}");
            let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
            let steps = v["steps"].as_array().expect("steps").clone();
            let changes: Vec<(f64, serde_json::Value)> = steps
                .iter()
                .filter(|s| s.get("redundant").is_some())
                .map(|s| (s["t"].as_f64().expect("t"), s["redundant"].clone()))
                .collect();
            (steps.len(), changes)
        };
        let (generated, generic) = (json("generated"), json("generic"));
        assert_eq!(generated.0, load(name).time.count, "{name}: every grid point");
        assert!(generated.1.len() >= 2, "{name}: the set changes and changes back");
        assert_eq!(generated, generic, "{name}");
    }
}

#[test]
fn the_generated_engine_checks_the_rows_it_leaves_out_in_single_precision_too() {
    // The single-precision tolerance of the runtime (`runtime::Real::DEFAULT_TOLERANCE` for
    // f32).
    let tolerance = 1e-4;
    let mech = load("four_bar_flat");
    let r = run_generated_in(&mech, true, Scalar::F32, Some(tolerance));
    assert!(r.failure.is_none(), "{:?}", r.failure);
    assert_eq!(r.frames.len(), mech.time.count);
    // Every row meets the tolerance in f32; evaluated again in f64 from the coordinates
    // rounded to f32 (relative 6e-8 on unit links), it moves by far less than the margin of 2.
    let worst = worst_row(&mech, &r.frames);
    assert!(worst <= 2.0 * tolerance, "max |Φ| = {worst:e}");
    // Rates of 1 and 1.1 rad/s differ by 5 % of the velocity terms, far above the f32
    // allowance (1e4 ε = 1.2e-3).
    let mech = load("four_bar_conflict");
    let r = run_generated_in(&mech, true, Scalar::F32, Some(tolerance));
    let f = r.failure.as_ref().expect("the drivers conflict");
    assert_eq!((f.kind, f.t), (FailureKind::Inconsistent, 0.0), "{f:?}");
    assert_eq!(f.constraints, ["driver motor", "driver push"], "{f:?}");
}
