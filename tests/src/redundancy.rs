//! Redundancy over the whole motion (contract §1, "Redundancy over the whole motion"), on the
//! generic engine, with the descriptions in `tests/redundancy/` (each file says what it is;
//! `bennett.py` there writes the Bennett ones):
//!
//! | case | expected | why |
//! |---|---|---|
//! | `bennett_{a,b}_{m149,0,90,1rad,180}` | a full turn of the crank from −149°, 0, 90°, 1 rad and 180°, predictor on and off, every row holding and every joint on the Bennett closed form, grid points on θ1 = 0 and π included; the redundant set named there changes and changes back | the whole Φ_q keeps column rank 21 over the cycle; only rows chosen once at the start would become singular at θ1 = 0 and π |
//! | the same, started 1e-6 rad before θ1 = 0 | the closed form, accelerations included | no digits lost next to the configuration where a fixed choice of rows degenerates |
//! | `parallelogram_landing`, `parallelogram_over` | a named `singular` at the grid time on the flat configuration; stepping over it, every step on the parallelogram branch | the flat configuration is a bifurcation: the whole Φ_q loses rank there, and a step must never switch branches |
//! | `four_bar_conflict` | `inconsistent` at t = 0 naming both drivers, from `solve` and from `check` (exit status 2) | the drivers agree on the angle at t = 0 but not on its rate |
//! | `four_bar_conflict_later` | `check` consistent, naming `driver push`; `solve` stops with `inconsistent` at the first grid time, naming both drivers | the drivers agree to second order at t = 0 and part at once in acceleration |
//! | `four_bar_fix_conflict` | `inconsistent` at t = 0 naming joint O and the constraint, from `solve` and `check` | the `fix` holds the crank 0.05 above the joint that holds it at 0 |
//! | `bennett_a_90` with b rounded to 0.683 | `inconsistent` at t = 0 | a / sin α1 ≠ b / sin α2 (by 1.9e-5 relative): the loop is a rigid structure that the driver cannot turn |
//! | `four_bar_flat` | `check`, the generic engine and the symbolic layer (generated engine) all name `constraint flat`; both engines run the whole grid with every row holding | one naming rule (`codegen::generic::redundancy`) |
//! | `four_bar_conflict`, `four_bar_conflict_later`, `four_bar_fix_conflict` on the generated engine | the generic engine's `inconsistent`, at the same time, naming the same equations | the generated solver checks the rows its reduced system leaves out after every attempt (`dropped_residuals`) and refuses a step where one does not hold |
//! | `bennett_*` on the generated engine, predictor on and off | with the predictor on, the generic engine's result: full turns on the closed form, every row holding, the redundant set changing at the same frames (JSON `redundant` too, grids landing on θ1 = 0 and π); with it off, the same or a `singular` stop next to θ1 = π, every written step checked (a known gap) | the rows kept at the start degenerate at θ1 = 0 or π (225° for geometry b from 180°) while the whole Φ_q does not; the runtime then solves with the rows the row-pivoted LU of the whole stack picks (`runtime::rows`) |

use std::f64::consts::PI;
use std::path::Path;

use codegen::emit::Scalar;
use codegen::engine::{self, Settings};
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
    run_generated_in(mech, predictor, Scalar::F64, None)
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
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    let analysis = Analysis::new(&eq, &prep);
    let layout = report::layout(mech);
    let (mut frames, mut steps) = (Vec::new(), Vec::new());
    let settings = Settings { predictor, ..Settings::DEFAULT };
    let report = engine::run_with(&built, &analysis, tolerance, settings, |f| {
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

/// Checks every step of a Bennett run against the closed form: J1 at the driven θ1, J2 at
/// θ2(θ1), J3 at −θ1 and J4 at −θ2, with their rates and accelerations (θ̇1 = 1, θ̈1 = 0).
fn assert_on_the_closed_form(name: &str, mech: &Mechanism, steps: &[StepResult]) {
    let (alpha1, alpha2) = twists(name);
    let start = match mech.drivers[0].law {
        codegen::model::Law::Polynomial { start, .. } => start,
        _ => unreachable!("the Bennett descriptions drive J1 at a constant rate"),
    };
    for s in steps {
        let theta1 = start + s.t;
        let [theta2, d1, d2] = bennett(theta1, alpha1, alpha2);
        let expected =
            [[theta1, 1.0, 0.0], [theta2, d1, d2], [-theta1, -1.0, 0.0], [-theta2, -d1, -d2]];
        for (j, e) in s.joints.iter().zip(expected) {
            let [a, ad, add] = j.angle.expect("every joint has references");
            // Positions: Newton meets max |Φ| ≤ 1e-10 on links of unit size where Φ_q has a
            // pivot ratio above 0.17 (balanced units) over the whole cycle, so angles are
            // within about 1e-9 of the solution; rates and accelerations come from linear
            // solves at that configuration, with |dθ2/dθ1| ≤ 4 and |d²θ2/dθ1²| ≤ 10 here, so
            // their error is that position error times the slope of the curve: 1e-7 and 1e-6
            // leave two orders of margin.
            let errors = [angle_diff(a, e[0]).abs(), (ad - e[1]).abs(), (add - e[2]).abs()];
            assert!(
                errors[0] < 1e-7 && errors[1] < 1e-7 && errors[2] < 1e-6,
                "{name} t = {} θ1 = {theta1}: joint {} (θ, θ̇, θ̈) = ({a}, {ad}, {add}), closed \
                 form {e:?}",
                s.t,
                j.name
            );
        }
    }
}

#[test]
fn bennett_linkages_turn_full_cycles_from_any_start_on_the_closed_form() {
    for geometry in ["a", "b"] {
        for start in ["m149", "0", "90", "1rad", "180"] {
            let name = format!("bennett_{geometry}_{start}");
            let mech = load(&name);
            for predictor in [true, false] {
                let r = run(&mech, predictor);
                assert!(r.failure.is_none(), "{name} (predictor {predictor}): {:?}", r.failure);
                assert_eq!(r.frames.len(), mech.time.count, "{name}");
                // Every row holds at every step, the three named redundant included.
                let worst = worst_row(&mech, &r.frames);
                assert!(worst <= TOLERANCE, "{name}: max |Φ| = {worst:e}");
                assert_on_the_closed_form(&name, &mech, &r.steps);
            }
        }
    }
}

#[test]
fn the_redundant_rows_named_change_exactly_where_theta1_is_zero_or_pi() {
    // The observation, which the rule reproduces: the rows named at a general
    // configuration are J4's rows 3 to 5; at θ1 = 0 and π (where those rows together with the
    // others lose rank) they are rows 1, 4 and 5.
    let general = ["joint J4 row 3", "joint J4 row 4", "joint J4 row 5"].map(String::from);
    let special = ["joint J4 row 1", "joint J4 row 4", "joint J4 row 5"].map(String::from);
    for name in ["bennett_a_m149", "bennett_b_90", "bennett_a_0"] {
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
        let name = format!("bennett_{geometry}_0");
        let text = std::fs::read_to_string(path(&name)).expect("description");
        let text = text.replace("law = { start = 0.0,", "law = { start = -1e-6,");
        assert!(text.contains("start = -1e-6"), "the law was rewritten");
        let mech = testing::load_toml(&text);
        let r = run(&mech, true);
        assert!(r.failure.is_none(), "{name}: {:?}", r.failure);
        assert_on_the_closed_form(&name, &mech, &r.steps);
    }
}

#[test]
fn a_parallelogram_stops_singular_on_its_flat_configuration_and_never_switches_branch() {
    // On the parallelogram branch the rocker's angle is the crank's and the coupler keeps
    // its orientation (identity Euler parameters); the antiparallelogram branch has neither.
    let on_branch = |name: &str, s: &StepResult| {
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
    };
    for predictor in [true, false] {
        let mech = load("parallelogram_landing");
        let r = run(&mech, predictor);
        let f = r.failure.as_ref().expect("the flat configuration is singular");
        assert_eq!(f.kind, FailureKind::Singular, "{f:?}");
        // The grid lands on θ = π at t = π/2.
        assert!((f.t - PI / 2.0).abs() < 1e-12, "stopped at {}", f.t);
        for joint in ["joint O", "joint D"] {
            assert!(f.constraints.iter().any(|c| c == joint), "{joint} in {:?}", f.constraints);
        }
        assert_eq!(r.steps.len(), 18, "every step before π/2");
        r.steps.iter().for_each(|s| on_branch("parallelogram_landing", s));

        let mech = load("parallelogram_over");
        let r = run(&mech, predictor);
        assert!(r.failure.is_none(), "{:?}", r.failure);
        assert_eq!(r.steps.len(), mech.time.count);
        r.steps.iter().for_each(|s| on_branch("parallelogram_over", s));
        let worst = worst_row(&mech, &r.frames);
        assert!(worst <= TOLERANCE, "max |Φ| = {worst:e}");
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
    let text = std::fs::read_to_string(path("bennett_a_90")).expect("description");
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
    // generic engine does: every step on the closed form (the generic test's tolerances and
    // reasons), every row of the description holding, the left-out ones included, and the
    // redundant set reported where it changes, frame by frame as the generic engine reports it.
    //
    // Not yet with the predictor off: Newton from the previous grid point leaves a position
    // error that the rows in force next to θ1 = π amplify, and the acceleration equation of a
    // row left aside then misses the consistency check (bennett_a_90: by 1.3e-6 of its scale
    // at 1.7e-4 rad before π), so such a run may stop there with `singular` (its steps before
    // are checked all the same); the runs that do not stop are checked in full.
    let mut stops = Vec::new();
    for geometry in ["a", "b"] {
        for start in ["m149", "0", "90", "1rad", "180"] {
            let name = format!("bennett_{geometry}_{start}");
            let mech = load(&name);
            for predictor in [true, false] {
                let r = run_generated(&mech, predictor);
                let worst = worst_row(&mech, &r.frames);
                assert!(worst <= TOLERANCE, "{name} (predictor {predictor}): max |Φ| = {worst:e}");
                assert_on_the_closed_form(&name, &mech, &r.steps);
                if let (false, Some(f)) = (predictor, &r.failure) {
                    assert_eq!(f.kind, FailureKind::Singular, "{name}: {f:?}");
                    stops.push(format!("{name}: t = {}", f.t));
                    continue;
                }
                assert!(r.failure.is_none(), "{name} (predictor {predictor}): {:?}", r.failure);
                assert_eq!(r.frames.len(), mech.time.count, "{name} (predictor {predictor})");
                let generic = run(&mech, predictor);
                let changes = |run: &Run| -> Vec<(usize, Vec<usize>)> {
                    let f = run.frames.iter().filter_map(|f| Some((f.index, f.redundant.clone()?)));
                    f.collect()
                };
                assert_eq!(changes(&r), changes(&generic), "{name} (predictor {predictor})");
            }
        }
    }
    eprintln!("generated Bennett stops with the predictor off: {stops:#?}");
}

#[test]
fn the_generated_engine_lands_on_theta1_zero_and_pi_and_reports_the_redundant_set() {
    // The grids land exactly on θ1 = 0 and π (steps of 20° or 5° from 0, 90° and 180°), where the
    // rows kept at a general configuration are singular; the JSON of `solve` reports the
    // changes of the redundant set there as the generic engine's does.
    for name in ["bennett_a_0", "bennett_a_90", "bennett_b_180"] {
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
