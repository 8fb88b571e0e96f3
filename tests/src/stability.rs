//! The stability suite: both engines where the methods fail, with the descriptions in
//! `tests/stability/*.toml` (each file says what the mechanism is). For every case the test
//! says what must happen and why, and checks it against a closed form or an independent
//! computation, not against the engines' own output.
//!
//! | case | expected | why |
//! |---|---|---|
//! | `crank_rocker_toggle` | `singular` at the first grid time past the toggle, every earlier step on the closed form | the rocker cannot pass the folded toggle: Φ_q is singular there and there is no assembly beyond |
//! | `slider_crank_dead_centre` | `singular` at t = 0.51 (the grid steps over x = 4 at t = 0.5) | as above: the slider's outer dead centre |
//! | `slider_crank_exact_dead_centre` | `singular` at t = 0.5 exactly, no step with unbounded velocities | the grid lands on the dead centre, where Newton converges (linearly) but q̇ is unbounded |
//! | `hooke_toward_90` | `singular` at t = 1 | the shaft lies along the ground's cross pin: its spin is free (gimbal lock) |
//! | `four_bar_near_toggle` | every step returned, on the closed form | near the change point Φ_q is poorly conditioned (κ ≈ 1.2e3) but regular: no false alarm |
//! | `four_bar_large_steps` | every step at 20° (and 90°) of crank per step on the starting assembly | Grashof crank-rocker: the assembly never changes along the motion |
//! | `planar_four_bar_4r`, `bennett`, `bricard` | mobility 1, the redundant rows named, removed and said in the output, every row (removed ones included) satisfied | consistent redundancy: the true mobility exceeds Grübler's count |
//! | `every_angle` | closed forms through 20 wheel turns, 10 screw turns, 5 rotor turns (e0 = 0) | no joint or driver form may have a singular angle |
//!
//! Both engines must report the same failure kind, time and equations; the generated solvers
//! are built once per case (a few seconds each, cached under `target/mechgen-cache`).

use codegen::generic::{Analysis, Equations, Failure, FailureKind, Frame};
use codegen::model::Mechanism;
use codegen::report::{self, StepResult};
use codegen::testing::{self, build_generated};
use nalgebra::DVector;

/// The descriptions of the suite.
const DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/stability");

/// Positions agree with a closed form to this: Newton stops at max |Φ| ≤ 1e-10 (the default
/// tolerance) on mechanisms of unit size whose Φ_q has a pivot ratio above 1e-2 away from the
/// singular configurations, so positions are within about 1e-8 of the solution.
const POSITION: f64 = 1e-7;

/// One engine's analysis of one case.
struct Outcome {
    engine: &'static str,
    frames: Vec<Frame>,
    steps: Vec<StepResult>,
    failure: Option<Failure>,
    removed: Vec<String>,
}

fn load(name: &str) -> Mechanism {
    testing::load(std::path::Path::new(&format!("{DIR}/{name}.toml"))).mechanism
}

/// Runs both engines on `mech`.
fn both(mech: &Mechanism) -> [Outcome; 2] {
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    let analysis = Analysis::new(&eq, &prep);
    let layout = report::layout(mech);
    let mut generic = Outcome {
        engine: "generic",
        frames: Vec::new(),
        steps: Vec::new(),
        failure: None,
        removed: prep.redundant.iter().map(|&k| eq.labels()[k].equation()).collect(),
    };
    let r = analysis
        .run(|f| {
            generic.steps.push(report::step_result(mech, &layout, f));
            generic.frames.push(f.clone());
            Ok::<(), ()>(())
        })
        .expect("the sink does not fail");
    generic.failure = r.failure;
    let built = build_generated(mech);
    let mut generated = Outcome {
        engine: "generated",
        frames: Vec::new(),
        steps: Vec::new(),
        failure: None,
        removed: built.removed.clone(),
    };
    let r = codegen::engine::run(&built, &analysis, None, |f| {
        generated.steps.push(report::step_result(mech, &layout, f));
        generated.frames.push(f.clone());
        Ok(())
    })
    .unwrap_or_else(|e| panic!("{}: {e}", mech.name));
    generated.failure = r.failure;
    [generic, generated]
}

/// Checks a singular stop of both engines: kind, time (`t_fail`), every reported step before
/// the singular time `t_star`, the equations named (a superset of `involved`, the same for
/// both engines).
fn assert_singular_stop(
    name: &str,
    outcomes: &[Outcome; 2],
    t_star: f64,
    t_fail: f64,
    involved: &[&str],
) {
    for o in outcomes {
        let f = o.failure.as_ref().unwrap_or_else(|| panic!("{name} ({}): no failure", o.engine));
        assert_eq!(f.kind, FailureKind::Singular, "{name} ({}): {f:?}", o.engine);
        // Grid times are computed as start + k·step, so they match to round-off.
        assert!(
            (f.t - t_fail).abs() < 1e-12,
            "{name} ({}): stopped at {} not {t_fail}",
            o.engine,
            f.t
        );
        let last = o.frames.last().expect("steps before the failure").t;
        assert!(
            last < t_star && t_star <= f.t,
            "{name} ({}): last step {last}, t* {t_star}, stop {}",
            o.engine,
            f.t
        );
        for c in involved {
            assert!(
                f.constraints.iter().any(|x| x == c),
                "{name} ({}): {c} not named in {:?}",
                o.engine,
                f.constraints
            );
        }
    }
    let [a, b] = outcomes;
    let (fa, fb) = (a.failure.as_ref().expect("checked"), b.failure.as_ref().expect("checked"));
    assert_eq!(
        (fa.kind, fa.t, &fa.constraints),
        (fb.kind, fb.t, &fb.constraints),
        "{name}: engines disagree"
    );
    assert_eq!(a.frames.len(), b.frames.len(), "{name}: engines stop after different steps");
}

/// The angle of a planar rotation about z from the Euler parameters of a body that started at
/// the identity: 2 atan2(e3, e0), in (−π, π].
pub(crate) fn angle_z(p: &[f64; 4]) -> f64 {
    let a = 2.0 * p[3].atan2(p[0]);
    (a + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI
}

fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI
}

#[test]
fn singular_configurations_stop_with_the_time_and_the_equations_involved() {
    // Crank-rocker (crank a = 1, coupler b, rocker c = 2.5, ground d = 3.5) driven by its
    // rocker from 120° at 0.5 rad/s: the folded toggle is where |O2 B| = b − a, so the rocker
    // angle φ* has cos φ* = ((b − a)² − d² − c²) / (2 d c) (B = O4 + c (cos φ, sin φ)).
    let b = (2.25_f64.powi(2) + (2.1650635094610964_f64 - 1.0).powi(2)).sqrt();
    let phi_star =
        (((b - 1.0).powi(2) - 3.5_f64.powi(2) - 2.5_f64.powi(2)) / (2.0 * 3.5 * 2.5)).acos();
    let t_star = (phi_star - 2.0 * std::f64::consts::FRAC_PI_3) / 0.5;
    let mech = load("crank_rocker_toggle");
    let t_fail = (t_star / 0.05).ceil() * 0.05;
    let out = both(&mech);
    assert_singular_stop(
        "crank_rocker_toggle",
        &out,
        t_star,
        t_fail,
        &["joint O2", "joint A", "joint O4"],
    );

    // Slider-crank (crank 1, rod 3) driven by its slider x = 3.5 + t: the outer dead centre is
    // x = 4 at t = 0.5. Before it, the crank angle θ has cos θ = (x² + 1 − 9) / (2x); the crank
    // started at θ0 = acos(4.25 / 7) with its frame at the identity.
    let theta0 = (4.25_f64 / 7.0).acos();
    for (name, t_fail) in
        [("slider_crank_dead_centre", 0.51), ("slider_crank_exact_dead_centre", 0.5)]
    {
        let mech = load(name);
        let out = both(&mech);
        assert_singular_stop(
            name,
            &out,
            0.5,
            t_fail,
            &["joint O", "joint A", "driver slider_motor"],
        );
        for o in &out {
            for s in &o.steps {
                let x = 3.5 + s.t;
                let theta = ((x * x - 8.0) / (2.0 * x)).acos();
                let got = angle_z(&s.bodies[0].p) + theta0;
                assert!(
                    (wrap(got - theta)).abs() < POSITION,
                    "{name} ({}) t = {}: crank at {got}, closed form {theta}",
                    o.engine,
                    s.t
                );
            }
        }
    }

    // A shaft on a Hooke joint whose tip is driven along x = cos 30° (1 − t): the shaft lies
    // along the ground's cross pin at t = 1. Before it the tip is at z = √(1 − x²).
    let mech = load("hooke_toward_90");
    let out = both(&mech);
    assert_singular_stop("hooke_toward_90", &out, 1.0, 1.0, &["joint cross"]);
    for o in &out {
        for s in &o.steps {
            let x = 0.8660254037844386 * (1.0 - s.t);
            let z = (1.0 - x * x).sqrt();
            assert!((s.bodies[0].r[2] - z).abs() < POSITION, "hooke ({}) t = {}", o.engine, s.t);
        }
    }
}

/// The rocker pin B of the crank-rocker of `four_bar_large_steps` for crank angle θ, on the
/// assembly where B lies to the left of the line from A to O4 (the starting one): the
/// intersection of the circles |B − A| = b and |B − O4| = 2.5.
pub(crate) fn rocker_pin(theta: f64) -> [f64; 2] {
    let b = (2.25_f64.powi(2) + (2.1650635094610964_f64 - 1.0).powi(2)).sqrt();
    pin(theta, b, 2.5)
}

/// B for crank angle θ of a four-bar with crank 1 at the origin, coupler b, rocker c and O4 at
/// (3.5, 0), on the assembly where B lies to the left of the line from A to O4.
fn pin(theta: f64, b: f64, c: f64) -> [f64; 2] {
    let o4 = [3.5, 0.0];
    let a = [theta.cos(), theta.sin()];
    let d = [o4[0] - a[0], o4[1] - a[1]];
    let l = d[0].hypot(d[1]);
    let along = (b * b - c * c + l * l) / (2.0 * l);
    let h = (b * b - along * along).sqrt();
    let (u, n) = ([d[0] / l, d[1] / l], [-d[1] / l, d[0] / l]);
    [a[0] + along * u[0] + h * n[0], a[1] + along * u[1] + h * n[1]]
}

#[test]
fn large_steps_stay_on_the_starting_assembly() {
    // The starting configuration is on the closed form's branch.
    let b0 = rocker_pin(std::f64::consts::FRAC_PI_2);
    assert!((b0[0] - 2.25).abs() < 1e-12 && (b0[1] - 2.1650635094610964).abs() < 1e-12);
    let mech = load("four_bar_large_steps");
    let check = |o: &Outcome, speed: f64, count: usize, label: &str| {
        assert!(o.failure.is_none(), "{label} ({}): {:?}", o.engine, o.failure);
        assert_eq!(o.steps.len(), count, "{label} ({})", o.engine);
        for s in &o.steps {
            let expected = rocker_pin(std::f64::consts::FRAC_PI_2 + speed * s.t);
            let got = s.points[0].r;
            let err = (got[0] - expected[0]).hypot(got[1] - expected[1]);
            assert!(
                err < POSITION,
                "{label} ({}) t = {}: B = {got:?}, closed form {expected:?}",
                o.engine,
                s.t
            );
        }
    };
    // 20° of crank per step, both engines.
    for o in &both(&mech) {
        check(o, 20f64.to_radians(), mech.time.count, "20° per step");
    }
    // 90° per step: the step control subdivides where the continuity check asks for it.
    let mut fast = mech.clone();
    for d in &mut fast.drivers {
        if let codegen::model::Law::Polynomial { velocity, .. } = &mut d.law {
            *velocity = 90f64.to_radians();
        }
    }
    fast.time.count = 13;
    let eq = Equations::new(&fast);
    let prep = eq.prepare();
    let layout = report::layout(&fast);
    let mut o = Outcome {
        engine: "generic",
        frames: Vec::new(),
        steps: Vec::new(),
        failure: None,
        removed: Vec::new(),
    };
    let r = Analysis::new(&eq, &prep)
        .run(|f| {
            o.steps.push(report::step_result(&fast, &layout, f));
            Ok::<(), ()>(())
        })
        .expect("the sink does not fail");
    o.failure = r.failure;
    check(&o, 90f64.to_radians(), fast.time.count, "90° per step");
}

#[test]
fn a_crank_passes_near_its_change_point() {
    // Coupler 2.502 and rocker 2 stretch to 4.502 against |A O4| = 4.5 at crank angle 180°
    // (t = 2.5): Φ_q's condition peaks there (about 1.2e3) but stays regular, so every step
    // is returned, on the closed form.
    let mech = load("four_bar_near_toggle");
    for o in &both(&mech) {
        assert!(o.failure.is_none(), "{}: {:?}", o.engine, o.failure);
        assert_eq!(o.steps.len(), mech.time.count, "{}", o.engine);
        for s in &o.steps {
            let expected =
                pin(std::f64::consts::FRAC_PI_2 + std::f64::consts::PI / 5.0 * s.t, 2.502, 2.0);
            let got = s.points[0].r;
            let err = (got[0] - expected[0]).hypot(got[1] - expected[1]);
            // Near the change point a position error δ in B is amplified by the condition
            // (≈1.2e3): 1e-5 still separates the assembly from its mirror image (≈0.1 apart).
            assert!(err < 1e-5, "{} t = {}: B = {got:?}, closed form {expected:?}", o.engine, s.t);
        }
    }
}

/// Largest |q̇ − (q(t + h) − q(t − h)) / 2h| relative to max |q̇| over the interior frames: the
/// rates against central differences of the positions (an O(h²) estimate).
fn rate_consistency(frames: &[Frame]) -> f64 {
    let scale = frames.iter().map(|f| f.qd.amax()).fold(1.0_f64, f64::max);
    frames
        .windows(3)
        .map(|w| {
            let fd: DVector<f64> = (&w[2].q - &w[0].q) / (w[2].t - w[0].t);
            (&w[1].qd - fd).amax() / scale
        })
        .fold(0.0, f64::max)
}

#[test]
fn redundant_constraints_are_named_removed_and_still_hold() {
    for (name, redundant) in [
        ("planar_four_bar_4r", vec!["joint J4 row 3", "joint J4 row 4", "joint J4 row 5"]),
        ("bennett", vec!["joint J4 row 3", "joint J4 row 4", "joint J4 row 5"]),
        ("bricard", vec!["joint J6 row 5"]),
    ] {
        let mech = load(name);
        let eq = Equations::new(&mech);
        let prep = eq.prepare();
        // What `check` reports: 1 degree of freedom before the driver, Grübler's count
        // (6 per moving body minus the joint rows) notwithstanding.
        assert_eq!(prep.mobility, 1, "{name}");
        let names: Vec<String> =
            prep.redundant.iter().map(|&k| eq.labels()[k].equation()).collect();
        assert_eq!(names, redundant, "{name}");
        let out = both(&mech);
        for o in &out {
            assert!(o.failure.is_none(), "{name} ({}): {:?}", o.engine, o.failure);
            assert_eq!(o.removed, redundant, "{name} ({})", o.engine);
            assert_eq!(o.frames.len(), mech.time.count, "{name} ({})", o.engine);
            for f in &o.frames {
                // Every row, the removed ones included, holds at the reported positions: the
                // removed rows were dependent, not dropped constraints.
                let phi = eq.evaluate(&f.q, &f.qd, f.t).phi;
                assert!(
                    phi.amax() < 1e-9,
                    "{name} ({}) t = {}: max |Φ| = {:e}",
                    o.engine,
                    f.t,
                    phi.amax()
                );
            }
            // Central differences of the positions are O(h²) accurate: with h = 0.25 and
            // rates of order 1, 1e-2 of the largest rate.
            let rates = rate_consistency(&o.frames);
            assert!(
                rates < 1e-2,
                "{name} ({}): rates differ from central differences by {rates:e}",
                o.engine
            );
        }
        if name == "planar_four_bar_4r" {
            // The planar loop against the closed form: crank at 90° + 0.5 t.
            for o in &out {
                for s in &o.steps {
                    let expected = rocker_pin(std::f64::consts::FRAC_PI_2 + 0.5 * s.t);
                    // The rocker's frame started at the identity; B is its local (2.25, 2.165).
                    let p = &s.bodies[2].p;
                    let a = angle_z(p);
                    let local = [2.25 - 3.5, 2.1650635094610964];
                    let got = [
                        3.5 + a.cos() * local[0] - a.sin() * local[1],
                        a.sin() * local[0] + a.cos() * local[1],
                    ];
                    let err = (got[0] - expected[0]).hypot(got[1] - expected[1]);
                    assert!(
                        err < POSITION,
                        "{name} ({}) t = {}: B = {got:?}, closed form {expected:?}",
                        o.engine,
                        s.t
                    );
                }
            }
        }
    }
}

#[test]
fn solve_says_what_it_removed_in_every_format() {
    let file = format!("{DIR}/planar_four_bar_4r.toml");
    let run = |format: &str| {
        let args = ["mechgen", "solve", &file, "--engine", "generic", "--format", format];
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let code = codegen::cli::run(args.iter().map(Into::into).collect(), &mut out, &mut err);
        assert_eq!(code, 0, "{}", String::from_utf8_lossy(&err));
        String::from_utf8(out).expect("UTF-8")
    };
    let json: serde_json::Value = serde_json::from_str(&run("json")).expect("JSON");
    assert_eq!(
        json["removed"],
        serde_json::json!(["joint J4 row 3", "joint J4 row 4", "joint J4 row 5"])
    );
    let table = run("table");
    assert!(
        table.lines().nth(1).is_some_and(|l| l.starts_with("redundant equations (")
            && l.ends_with("joint J4 row 3, joint J4 row 4, joint J4 row 5")),
        "{}",
        &table[..200]
    );
    let csv = run("csv");
    assert!(
        csv.lines()
            .last()
            .is_some_and(|l| l == "# removed: joint J4 row 3, joint J4 row 4, joint J4 row 5")
    );
    // Without redundancy JSON still has the key, empty; the others say nothing.
    let file = format!("{DIR}/every_angle.toml");
    let args = ["mechgen", "solve", &file, "--engine", "generic", "--format", "json"];
    let (mut out, mut err) = (Vec::new(), Vec::new());
    assert_eq!(codegen::cli::run(args.iter().map(Into::into).collect(), &mut out, &mut err), 0);
    let json: serde_json::Value = serde_json::from_slice(&out).expect("JSON");
    assert_eq!(json["removed"], serde_json::json!([]));
}

#[test]
fn joints_and_drivers_hold_through_many_turns() {
    let mech = load("every_angle");
    let (pi, tau) = (std::f64::consts::PI, std::f64::consts::TAU);
    for o in &both(&mech) {
        assert!(o.failure.is_none(), "{}: {:?}", o.engine, o.failure);
        assert_eq!(o.steps.len(), 71, "{}", o.engine);
        for s in &o.steps {
            let t = s.t;
            // Wheel: rim at (cos s, sin s, 0), s = 4π t, ω = (0, 0, 4π).
            let (s_w, rim) = (2.0 * tau * t, s.points[0].r);
            let err = (rim[0] - s_w.cos()).hypot(rim[1] - s_w.sin()).hypot(rim[2]);
            assert!(err < POSITION, "{} t = {t}: rim {rim:?}", o.engine);
            assert!((s.bodies[0].omega[2] - 2.0 * tau).abs() < 1e-6, "{} t = {t}", o.engine);
            // Nut: turned by s = 2π t about the y axis through (2, 0, 0), advanced 0.5 s / 2π:
            // the tooth (3, 0, 0) is at (2 + cos s, 0.5 t, −sin s).
            let (s_n, tooth) = (tau * t, s.points[1].r);
            let expected = [2.0 + s_n.cos(), 0.5 * t, -s_n.sin()];
            let err = (0..3).map(|k| (tooth[k] - expected[k]).abs()).fold(0.0, f64::max);
            assert!(
                err < POSITION,
                "{} t = {t}: tooth {tooth:?}, closed form {expected:?}",
                o.engine
            );
            // Rotor: p = ±(cos(s/2), sin(s/2), 0, 0), s = π t, ω = (π, 0, 0); e0 = 0 at odd t.
            let (s_r, p) = (pi * t, s.bodies[2].p);
            let dot = p[0] * (0.5 * s_r).cos() + p[1] * (0.5 * s_r).sin();
            assert!((dot.abs() - 1.0).abs() < POSITION, "{} t = {t}: p {p:?}", o.engine);
            assert!((s.bodies[2].omega[0] - pi).abs() < 1e-6, "{} t = {t}", o.engine);
        }
        // Steps land within 1/14 s of e0 = 0 (t = 1, 3, ...; grid 1/7): the driver's form has no
        // singular angle there.
        assert!(o.steps.iter().any(|s| s.bodies[2].p[0].abs() < 0.25), "{}", o.engine);
    }
}
