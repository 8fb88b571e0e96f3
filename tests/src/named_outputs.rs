//! The generated modules' named outputs (issue 14, point 5): the accessors of the four-bar
//! and the R-S-S-R in `generated/` against the report the generic engine writes from the same
//! state, a finite-difference check of a point's velocity, the index constants and lookups, and
//! a joint angle against its driver law.

use std::path::Path;

use codegen::generic::{Analysis, Equations};
use codegen::model::Mechanism;
use codegen::report;
use codegen::symbolic::{JointCoordinate, Symbolic};
use codegen::validate::{Format, load_file, load_str};
use generated::{four_bar, rssr};
use nalgebra::DVector;
use runtime::{NewtonOptions, Solver};

fn example(name: &str) -> Mechanism {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples").join(name);
    match load_file(&path) {
        Ok(l) => l.mechanism,
        Err(d) => panic!("{}: {d:?}", path.display()),
    }
}

/// Largest |a_i − b_i| over the largest |b_i| seen for that quantity.
#[derive(Default)]
struct Relative {
    diff: f64,
    scale: f64,
}

impl Relative {
    fn add(&mut self, a: &[f64], b: &[f64]) {
        for (x, y) in a.iter().zip(b) {
            self.diff = self.diff.max((x - y).abs());
            self.scale = self.scale.max(y.abs());
        }
    }
    fn check(&self, what: &str) {
        // The two sides compute the same quantity with different operation orders (the
        // report's v = ṙ + ω × A s' and a = r̈ + α × s + ω × (ω × s) against the chain rule of
        // r + A(p) s' emitted from the symbolic layer): equal when |p| = 1 and pᵀṗ = 0, which
        // the solver holds to rounding, so they agree to a few hundred ulps of the quantity's
        // magnitude, well inside 1e-12.
        assert!(self.scale > 0.0, "{what}: nothing compared");
        assert!(self.diff <= 1e-12 * self.scale, "{what}: {:e} of {:e}", self.diff, self.scale);
    }
}

/// The generated accessors and `codegen::report` on one state, for a module `$m`.
macro_rules! compare {
    ($m:ident, $ty:ident, $mech:expr, $times:expr) => {{
        let mech: &Mechanism = $mech;
        let layout = report::layout(mech);
        let mut solver = Solver::new($m::$ty, $m::Q0);
        solver.set_options(NewtonOptions { tolerance: 1e-12, ..NewtonOptions::DEFAULT });
        let names = ["r", "v", "a", "body r", "body p", "omega", "alpha"];
        let mut rel: Vec<Relative> = names.iter().map(|_| Relative::default()).collect();
        for t in $times {
            solver.position(t).expect("converges");
            solver.velocity().expect("velocity");
            solver.acceleration().expect("acceleration");
            let (q, qd, qdd) = (solver.q(), solver.qd(), solver.qdd());
            let mut full = [[[0.0; 7]; 3]; $m::BODIES];
            $m::expand(q, qd, qdd, t, &mut full);
            let vec =
                |d: usize| DVector::from_iterator(7 * $m::BODIES, full.iter().flat_map(|b| b[d]));
            let step =
                report::from_coordinates(mech, &layout, t, 0, 0.0, &vec(0), &vec(1), &vec(2));
            let mut p = [[[0.0; 3]; $m::POINTS]; 3];
            $m::point_positions(q, t, &mut p[0]);
            $m::point_velocities(q, qd, t, &mut p[1]);
            $m::point_accelerations(q, qd, qdd, t, &mut p[2]);
            for (k, pt) in step.points.iter().enumerate() {
                rel[0].add(&p[0][k], &pt.r);
                rel[1].add(&p[1][k], &pt.v);
                rel[2].add(&p[2][k], &pt.a);
            }
            let (mut poses, mut w, mut al) =
                ([[0.0; 7]; $m::BODIES], [[0.0; 3]; $m::BODIES], [[0.0; 3]; $m::BODIES]);
            $m::poses(q, t, &mut poses);
            $m::angular_velocities(q, qd, t, &mut w);
            $m::angular_accelerations(q, qd, qdd, t, &mut al);
            for (k, b) in step.bodies.iter().enumerate() {
                rel[3].add(&poses[k][..3], &b.r);
                rel[4].add(&poses[k][3..], &b.p);
                rel[5].add(&w[k], &b.omega);
                rel[6].add(&al[k], &b.alpha);
            }
        }
        for (r, name) in rel.iter().zip(names) {
            r.check(&format!("{} {name}", mech.name));
        }
    }};
}

#[test]
fn four_bar_accessors_agree_with_the_report_over_a_revolution() {
    let mech = example("four_bar.toml");
    // The crank turns at π rad/s: 2 s per revolution, 40 points.
    let times = (0..=40).map(|k| f64::from(k) * 0.05);
    compare!(four_bar, FourBar, &mech, times);
}

#[test]
fn rssr_accessors_agree_with_the_report_over_a_revolution() {
    let mech = example("rssr.toml");
    let period = std::f64::consts::TAU / 146.6;
    let times = (0..=60).map(|k| f64::from(k) * period / 60.0);
    compare!(rssr, Rssr, &mech, times);
}

#[test]
fn point_velocity_is_the_derivative_of_its_position() {
    // Central differences of r over ±h against v at the R-S-S-R's coupler point B.
    const B: usize = rssr::point("B");
    let mut solver = Solver::new(rssr::Rssr, rssr::Q0);
    solver.set_options(NewtonOptions { tolerance: 1e-13, ..NewtonOptions::DEFAULT });
    let (t, h) = (0.01, 1e-5);
    let mut r = [[[0.0; 3]; rssr::POINTS]; 2];
    for (k, s) in [-h, h].into_iter().enumerate() {
        solver.position(t + s).expect("converges");
        rssr::point_positions(solver.q(), t + s, &mut r[k]);
    }
    solver.position(t).expect("converges");
    solver.velocity().expect("velocity");
    let mut v = [[0.0; 3]; rssr::POINTS];
    rssr::point_velocities(solver.q(), solver.qd(), t, &mut v);
    let speed = v[B].iter().map(|x| x * x).sum::<f64>().sqrt();
    assert!(speed > 1.0, "the point moves: {speed}");
    for c in 0..3 {
        let fd = (r[1][B][c] - r[0][B][c]) / (2.0 * h);
        // Truncation h²/6 times the third derivative (about 0.5 m · 146.6³ s⁻³ ≈ 1.6e6 m/s³):
        // 3e-5 m/s, and the Newton tolerance over 2h, 5e-9 m/s; 1e-5 of the speed (≈ 15 m/s)
        // bounds both, while a wrong velocity formula is off by O(1) of it.
        assert!((fd - v[B][c]).abs() < 1e-5 * speed, "{c}: {fd} vs {}", v[B][c]);
    }
}

#[test]
fn names_resolve_to_the_tables() {
    // The index constants and the const lookups agree with the string tables.
    const ROCKER: usize = rssr::body("rocker");
    assert_eq!(ROCKER, rssr::body::ROCKER);
    assert_eq!(rssr::BODY_NAMES[ROCKER], "rocker");
    assert_eq!(rssr::UNKNOWNS[rssr::unknown::ROCKER_E1], "rocker.e1");
    assert_eq!(rssr::unknown("rocker.e1"), rssr::unknown::ROCKER_E1);
    assert_eq!(rssr::POINT_NAMES[rssr::point::B], "B");
    assert_eq!(four_bar::JOINT_NAMES[four_bar::joint::D], "D");
    assert_eq!(runtime::outputs::find(&four_bar::POINT_NAMES, "nowhere"), None);
}

/// Reduced q, q̇, q̈ of the symbolic system from a generic frame.
fn reduced(sys: &Symbolic, eq: &Equations<'_>, f: &codegen::generic::Frame) -> [Vec<f64>; 3] {
    [&f.q, &f.qd, &f.qdd].map(|v| sys.reduce(eq, v).as_slice().to_vec())
}

#[test]
fn rssr_crank_angle_follows_its_driver_law() {
    // The R-S-S-R with references on its crank joint O2: axis_i is −y on ground and the crank
    // turns by s = 146.6 t about +y (its `ry` driver), so θ from ref_i = x to ref_j = x about
    // axis_i is −s.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/rssr.toml");
    let text = std::fs::read_to_string(&path).expect("rssr example");
    let text = text.replacen(
        "axis_j = [0.0, 0.1, 0.0]",
        "axis_j = [0.0, 0.1, 0.0]\nref_i = [1.0, 0.0, 0.0]\nref_j = [1.0, 0.0, 0.0]",
        1,
    );
    let mech = load_str(&text, Format::Toml, None).expect("valid").mechanism;
    let mut sys = Symbolic::build(&mech).expect("reduced system");
    let outputs = sys.outputs(&mech);
    let o2 = mech.joints.iter().position(|j| j.name == "O2").expect("O2");
    let Some(&(_, what, JointCoordinate::Angle { x, y })) =
        outputs.joints.iter().find(|(j, _, _)| *j == o2)
    else {
        panic!("O2 has an angle")
    };
    assert_eq!(what, "angle");
    let eq = Equations::new(&mech);
    let prep = eq.prepare();
    let (mut checked, mut previous) = (0, None);
    let roots: Vec<_> = x.into_iter().chain(y).collect();
    Analysis::new(&eq, &prep)
        .run(|f| {
            let [q, qd, qdd] = reduced(&sys, &eq, f);
            let v = sys.pool.eval_with(&roots, [&q, &qd, &qdd], f.t);
            let [th, thd, thdd] = runtime::outputs::angle([v[0], v[1], v[2]], [v[3], v[4], v[5]]);
            let th = previous.map_or(th, |p| runtime::outputs::unwrap_angle(p, th));
            previous = Some(th);
            let s = 146.6 * f.t;
            // Positions to the Newton tolerance (1e-10) through unit reference vectors; the
            // rates carry the same relative error times the crank speed and its square.
            assert!((th + s).abs() < 1e-8, "t = {}: θ = {th}, s = {s}", f.t);
            assert!((thd + 146.6).abs() < 1e-8 * 146.6, "θ̇ = {thd}");
            assert!(thdd.abs() < 1e-8 * 146.6 * 146.6, "θ̈ = {thdd}");
            checked += 1;
            Ok::<(), ()>(())
        })
        .expect("the sink does not fail");
    assert!(checked > 10, "{checked} frames");
}
