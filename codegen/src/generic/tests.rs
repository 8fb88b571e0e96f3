//! Finite-difference checks of every row kind: Φ_q against central differences of Φ at
//! random configurations, ν and γ against differences of Φ along random smooth trajectories.

use nalgebra::{DVector, Vector3, Vector4};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use super::Equations;
use crate::model::{
    Body, BodyId, Constraint, ConstraintKind, CoordinateName, Driver, DriverCoordinate,
    DriverTarget, Joint, JointId, JointKind, Law, Mechanism, Motion, Point, PointId, SolverOptions,
    TimeGrid,
};

fn unit(rng: &mut StdRng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if v.norm() > 0.3 {
            return v.normalize();
        }
    }
}

fn vec3(rng: &mut StdRng) -> Vector3<f64> {
    Vector3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    )
}

fn quat(rng: &mut StdRng) -> Vector4<f64> {
    Vector4::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    )
    .normalize()
}

/// A unit vector ⟂ `a`.
fn perpendicular(rng: &mut StdRng, a: &Vector3<f64>) -> Vector3<f64> {
    let v = unit(rng);
    (v - a * a.dot(&v)).normalize()
}

/// A joint of `kind` between bodies `i` and `j` with random geometry and references.
fn joint(rng: &mut StdRng, name: &str, i: usize, j: usize, kind: JointKind) -> Joint {
    let (ai, aj) = (unit(rng), unit(rng));
    Joint {
        name: name.to_owned(),
        body_i: BodyId(i),
        body_j: BodyId(j),
        point_i: vec3(rng),
        point_j: vec3(rng),
        axis: Some((ai, aj)),
        reference: Some((perpendicular(rng, &ai), perpendicular(rng, &aj))),
        kind,
    }
}

/// Every row kind at once: a ground body with a non-identity placement, two moving bodies,
/// one joint of each type, both constraint kinds and every driver kind with both laws.
/// The equation count is irrelevant here: only Φ and its derivatives are evaluated.
fn zoo(seed: u64) -> Mechanism {
    let mut rng = StdRng::seed_from_u64(seed);
    let body = |rng: &mut StdRng, name: &str, ground| Body {
        name: name.to_owned(),
        ground,
        r: vec3(rng),
        p: quat(rng),
    };
    let bodies =
        vec![body(&mut rng, "g", true), body(&mut rng, "a", false), body(&mut rng, "b", false)];
    let lead = rng.random_range(0.5..2.0);
    let joints = vec![
        joint(&mut rng, "sph", 1, 2, JointKind::Spherical),
        joint(&mut rng, "uni", 2, 1, JointKind::Universal),
        joint(&mut rng, "rev", 0, 1, JointKind::Revolute),
        joint(&mut rng, "rev2", 1, 2, JointKind::Revolute),
        joint(&mut rng, "cyl", 1, 2, JointKind::Cylindrical),
        joint(&mut rng, "pri", 2, 0, JointKind::Prismatic),
        joint(&mut rng, "scr", 1, 2, JointKind::Screw { lead, d0: 0.3, theta0: 0.4 }),
        joint(&mut rng, "dst", 1, 2, JointKind::Distance { length: 1.3 }),
    ];
    let poly = Law::Polynomial { start: 0.3, velocity: 1.7, acceleration: -2.1 };
    let harm = Law::Harmonic { offset: 0.2, amplitude: 0.9, frequency: 2.3, phase: 0.4 };
    let driver = |name: &str, target, law| Driver { name: name.to_owned(), target, law };
    let absolute = |c| DriverTarget::Absolute { body: BodyId(2), coordinate: c };
    let drivers = vec![
        driver("d_rev", DriverTarget::Joint { joint: JointId(3), motion: Motion::Rotation }, harm),
        driver(
            "d_cyl_r",
            DriverTarget::Joint { joint: JointId(4), motion: Motion::Rotation },
            poly,
        ),
        driver(
            "d_cyl_t",
            DriverTarget::Joint { joint: JointId(4), motion: Motion::Translation },
            harm,
        ),
        driver(
            "d_pri",
            DriverTarget::Joint { joint: JointId(5), motion: Motion::Translation },
            poly,
        ),
        driver("d_scr", DriverTarget::Joint { joint: JointId(6), motion: Motion::Rotation }, harm),
        driver("d_x", absolute(DriverCoordinate::X), poly),
        driver("d_y", absolute(DriverCoordinate::Y), harm),
        driver("d_z", absolute(DriverCoordinate::Z), poly),
        driver("d_rx", absolute(DriverCoordinate::Rx), harm),
        driver("d_ry", absolute(DriverCoordinate::Ry), poly),
        driver("d_rz", absolute(DriverCoordinate::Rz), harm),
        driver(
            "d_e1",
            DriverTarget::Absolute { body: BodyId(1), coordinate: DriverCoordinate::E1 },
            poly,
        ),
        driver("d_e2", absolute(DriverCoordinate::E2), harm),
        driver("d_e3", absolute(DriverCoordinate::E3), poly),
        driver("d_px", DriverTarget::Point { point: PointId(0), axis: 0 }, harm),
        driver("d_py", DriverTarget::Point { point: PointId(1), axis: 1 }, poly),
        driver("d_pz", DriverTarget::Point { point: PointId(0), axis: 2 }, harm),
    ];
    let points = vec![
        Point { name: "pa".to_owned(), body: BodyId(1), local: vec3(&mut rng) },
        Point { name: "pb".to_owned(), body: BodyId(2), local: vec3(&mut rng) },
    ];
    let constraints = vec![
        Constraint {
            name: "fix".to_owned(),
            kind: ConstraintKind::Fix {
                body: BodyId(1),
                coordinate: CoordinateName::E2,
                value: 0.1,
            },
        },
        Constraint {
            name: "diff".to_owned(),
            kind: ConstraintKind::CoordinateDifference {
                body_i: BodyId(2),
                body_j: BodyId(1),
                coordinate: CoordinateName::Y,
                value: 0.5,
            },
        },
        Constraint {
            name: "diff_ground".to_owned(),
            kind: ConstraintKind::CoordinateDifference {
                body_i: BodyId(0),
                body_j: BodyId(2),
                coordinate: CoordinateName::E3,
                value: 0.5,
            },
        },
    ];
    Mechanism {
        name: "zoo".to_owned(),
        description: None,
        time: TimeGrid::uniform(0.0, 0.1, 2),
        solver: SolverOptions::default(),
        bodies,
        joints,
        constraints,
        drivers,
        points,
    }
}

/// A random configuration near unit Euler parameters (off the manifold on purpose: the
/// derivatives must be those of Φ as written, everywhere).
fn random_q(rng: &mut StdRng, n: usize) -> DVector<f64> {
    DVector::from_fn(n, |_, _| rng.random_range(-1.0..1.0))
}

#[test]
fn jacobian_matches_central_differences_for_every_row_kind() {
    for seed in 0..20 {
        let mech = zoo(seed);
        let eq = Equations::new(&mech);
        let mut rng = StdRng::seed_from_u64(100 + seed);
        let n = eq.unknowns();
        let q = random_q(&mut rng, n);
        let t = rng.random_range(-1.0..1.0);
        let zero = DVector::zeros(n);
        let jac = eq.evaluate(&q, &zero, t).jac;
        // Central differences have truncation error ~h² and round-off ~ε/h; h = 1e-6 puts
        // both near 1e-10 for these O(1) quantities, so 1e-7 leaves a wide margin.
        let h = 1e-6;
        for c in 0..n {
            let mut qp = q.clone();
            let mut qm = q.clone();
            qp[c] += h;
            qm[c] -= h;
            let fd = (eq.evaluate(&qp, &zero, t).phi - eq.evaluate(&qm, &zero, t).phi) / (2.0 * h);
            for r in 0..eq.equations() {
                let err = (fd[r] - jac[(r, c)]).abs();
                assert!(
                    err <= 1e-7 * (1.0 + fd[r].abs()),
                    "seed {seed}: ∂Φ/∂q of {} column {c}: analytic {}, differences {}",
                    eq.labels()[r].equation(),
                    jac[(r, c)],
                    fd[r]
                );
            }
        }
    }
}

#[test]
fn nu_and_gamma_match_differences_along_smooth_trajectories() {
    for seed in 0..20 {
        let mech = zoo(seed);
        let eq = Equations::new(&mech);
        let mut rng = StdRng::seed_from_u64(200 + seed);
        let n = eq.unknowns();
        // Rates of order 0.3 keep the fast screw phase 2π·d/lead within reach of the differences.
        let q0 = random_q(&mut rng, n);
        let v = random_q(&mut rng, n) * 0.3;
        let a = random_q(&mut rng, n) * 0.3;
        let t0 = rng.random_range(-1.0..1.0);
        let zero = DVector::zeros(n);
        // Along q(τ) = q0 + vτ + aτ²/2, t = t0 + τ: Φ̇ = Φ_q v − ν and Φ̈ = Φ_q a − γ.
        let phi_at =
            |tau: f64| eq.evaluate(&(&q0 + &v * tau + &a * (0.5 * tau * tau)), &zero, t0 + tau).phi;
        let sys = eq.evaluate(&q0, &v, t0);
        // Second differences: truncation ~h², round-off ~ε/h²; h = 1e-4 gives ~1e-8 each.
        let h = 1e-4;
        let (p, z, m) = (phi_at(h), phi_at(0.0), phi_at(-h));
        // First differences with a smaller step: truncation ~1e-10, round-off ~1e-11.
        let h1 = 1e-5;
        let d1 = (phi_at(h1) - phi_at(-h1)) / (2.0 * h1);
        let d2 = (&p - &z * 2.0 + &m) / (h * h);
        let nu = &sys.jac * &v - &d1;
        let gamma = &sys.jac * &a - &d2;
        for r in 0..eq.equations() {
            let label = eq.labels()[r].equation();
            // ν: the first differences are accurate to ~1e-9 on these rows.
            assert!(
                (nu[r] - sys.nu[r]).abs() <= 1e-6 * (1.0 + nu[r].abs()),
                "seed {seed}: ν of {label}: analytic {}, differences {}",
                sys.nu[r],
                nu[r]
            );
            // γ: second differences are accurate to ~1e-7 here; 1e-5 relative is the bound.
            assert!(
                (gamma[r] - sys.gamma[r]).abs() <= 1e-5 * (1.0 + gamma[r].abs()),
                "seed {seed}: γ of {label}: analytic {}, differences {}",
                sys.gamma[r],
                gamma[r]
            );
        }
    }
}

/// Closed-form motions of one body jointed to a ground body that is placed and turned off
/// the global frame: each joint type driven through its joint drivers, over several turns.
mod driven_joints {
    use nalgebra::{Matrix3, Unit, UnitQuaternion, Vector3};

    use crate::generic::{Analysis, Equations};
    use crate::report::{self, StepResult};
    use crate::validate::{Format, load_str};

    /// The ground's placement, its local joint axis and reference, and the joint point.
    struct Setup {
        r_g: Vector3<f64>,
        a_g: Matrix3<f64>,
        p_g: [f64; 4],
        axis: Vector3<f64>,
        reference: Vector3<f64>,
        point_i: Vector3<f64>,
        point_j: Vector3<f64>,
    }

    fn setup() -> Setup {
        let q = UnitQuaternion::from_axis_angle(
            &Unit::new_normalize(Vector3::new(0.2, -0.3, 0.25)),
            0.9,
        );
        let axis = Vector3::new(0.3, 0.5, 0.8).normalize();
        let reference = axis.cross(&Vector3::new(1.0, -0.2, 0.1)).normalize();
        Setup {
            r_g: Vector3::new(0.4, -1.2, 0.7),
            a_g: *q.to_rotation_matrix().matrix(),
            p_g: [q.w, q.i, q.j, q.k],
            axis,
            reference,
            point_i: Vector3::new(0.1, 0.2, -0.3),
            point_j: Vector3::new(-0.5, 0.25, 0.6),
        }
    }

    fn v(x: &Vector3<f64>) -> String {
        format!("[{:?}, {:?}, {:?}]", x.x, x.y, x.z)
    }

    /// A description of the ground, the body (assembled at θ = d = 0 with the identity
    /// orientation, then perturbed) and one joint with the given drivers.
    fn description(s: &Setup, kind: &str, extra_joint: &str, drivers: &str) -> String {
        let axis_g = s.a_g * s.axis;
        let ref_g = s.a_g * s.reference;
        let joint_point = s.r_g + s.a_g * s.point_i;
        let r_j = joint_point - s.point_j;
        // For a prismatic joint ref_i ⟂ ref_j is the equation.
        let ref_j = if kind == "prismatic" { axis_g.cross(&ref_g) } else { ref_g };
        // The screw measures d0 and θ0 at the initial estimates, so its estimates are exact;
        // the other joints start Newton from perturbed ones.
        let (perturbed, p_j) = if kind == "screw" {
            (r_j, "[1.0, 0.0, 0.0, 0.0]")
        } else {
            (r_j + Vector3::new(0.01, -0.02, 0.015), "[0.999, 0.01, -0.02, 0.015]")
        };
        format!(
            r#"
name = "driven"
[time]
start = 0.0
end = 3.0
step = 0.05
[solver]
tolerance = 1e-12
[[bodies]]
name = "ground"
ground = true
r = {rg}
p = [{:?}, {:?}, {:?}, {:?}]
[[bodies]]
name = "body"
r = {perturbed}
p = {p_j}
[[joints]]
name = "j"
type = "{kind}"
body_i = "ground"
body_j = "body"
point_i = {pi}
point_j = {pj}
axis_i = {ai}
axis_j = {aj}
ref_i = {ri}
ref_j = {rj}
{extra_joint}
{drivers}
"#,
            s.p_g[0],
            s.p_g[1],
            s.p_g[2],
            s.p_g[3],
            rg = v(&s.r_g),
            perturbed = v(&perturbed),
            pi = v(&s.point_i),
            pj = v(&s.point_j),
            ai = v(&s.axis),
            aj = v(&axis_g),
            ri = v(&s.reference),
            rj = v(&ref_j),
        )
    }

    fn solve(text: &str) -> Vec<StepResult> {
        let loaded = load_str(text, Format::Toml, None).expect("valid description");
        let mech = &loaded.mechanism;
        let eq = Equations::new(mech);
        let prep = eq.prepare();
        let layout = report::layout(mech);
        let mut steps = Vec::new();
        let r = Analysis::new(&eq, &prep)
            .run(|f| {
                steps.push(report::step_result(mech, &layout, f));
                Ok::<(), ()>(())
            })
            .unwrap();
        assert!(r.failure.is_none(), "{:?}", r.failure);
        steps
    }

    /// Compares every step with the screw motion θ(t), d(t) about and along the joint axis.
    fn check(s: &Setup, steps: &[StepResult], motion: impl Fn(f64) -> [(f64, f64, f64); 2]) {
        let axis_g = s.a_g * s.axis;
        let joint_point = s.r_g + s.a_g * s.point_i;
        for st in steps {
            let [(th, thd, thdd), (d, dd, ddd)] = motion(st.t);
            let rot = UnitQuaternion::from_axis_angle(&Unit::new_unchecked(axis_g), th);
            let rho = rot * (-s.point_j);
            let omega = axis_g * thd;
            let alpha = axis_g * thdd;
            let r = joint_point + axis_g * d + rho;
            let rd = axis_g * dd + omega.cross(&rho);
            let rdd = axis_g * ddd + alpha.cross(&rho) + omega.cross(&omega.cross(&rho));
            let b = &st.bodies[0];
            let sign = if b.p[0] * rot.w + b.p[1] * rot.i + b.p[2] * rot.j + b.p[3] * rot.k < 0.0 {
                -1.0
            } else {
                1.0
            };
            let p = [rot.w, rot.i, rot.j, rot.k].map(|x| sign * x);
            let pairs: [(&str, &[f64], &[f64]); 6] = [
                ("r", &b.r, r.as_slice()),
                ("p", &b.p, &p),
                ("r_dot", &b.r_dot, rd.as_slice()),
                ("omega", &b.omega, omega.as_slice()),
                ("r_ddot", &b.r_ddot, rdd.as_slice()),
                ("alpha", &b.alpha, alpha.as_slice()),
            ];
            for (name, ours, exact) in pairs {
                for (k, (o, e)) in ours.iter().zip(exact).enumerate() {
                    // Newton stops at max |Φ| ≤ 1e-12; rates up to ~30 and accelerations up
                    // to ~300 scale that error, so 1e-9 relative to the magnitude is the bound.
                    assert!(
                        (o - e).abs() <= 1e-9 * (1.0 + e.abs()),
                        "t = {}: {name}[{k}] = {o}, closed form {e}",
                        st.t
                    );
                }
            }
        }
    }

    const SPIN: &str = "law = { start = 0.0, velocity = 10.0, acceleration = -1.5 }";

    fn spin(t: f64) -> (f64, f64, f64) {
        (10.0 * t - 0.75 * t * t, 10.0 - 1.5 * t, -1.5)
    }

    #[test]
    fn a_revolute_driven_in_rotation_turns_about_its_axis_for_several_turns() {
        let s = setup();
        let drivers = format!(
            "[[drivers]]\nname = \"motor\"\njoint = \"j\"\nmotion = \"rotation\"\n{SPIN}\n"
        );
        let steps = solve(&description(&s, "revolute", "", &drivers));
        check(&s, &steps, |t| [spin(t), (0.0, 0.0, 0.0)]);
    }

    #[test]
    fn a_prismatic_driven_in_translation_slides_along_its_axis() {
        let s = setup();
        let drivers = "[[drivers]]\nname = \"ram\"\njoint = \"j\"\nmotion = \"translation\"\nlaw = { offset = 0.0, amplitude = 0.8, frequency = 2.0, phase = 0.0 }\n";
        let steps = solve(&description(&s, "prismatic", "", drivers));
        check(&s, &steps, |t| {
            let (sn, cs) = (2.0 * t).sin_cos();
            [(0.0, 0.0, 0.0), (0.8 * sn, 1.6 * cs, -3.2 * sn)]
        });
    }

    #[test]
    fn a_cylindrical_driven_in_rotation_and_translation_follows_both_laws() {
        let s = setup();
        let drivers = format!(
            "[[drivers]]\nname = \"turn\"\njoint = \"j\"\nmotion = \"rotation\"\n{SPIN}\n\
             [[drivers]]\nname = \"push\"\njoint = \"j\"\nmotion = \"translation\"\n\
             law = {{ start = 0.0, velocity = 0.3, acceleration = 0.2 }}\n"
        );
        let steps = solve(&description(&s, "cylindrical", "", &drivers));
        check(&s, &steps, |t| [spin(t), (0.3 * t + 0.1 * t * t, 0.3 + 0.2 * t, 0.2)]);
    }

    #[test]
    fn a_screw_driven_in_rotation_advances_one_lead_per_turn_across_turns() {
        let s = setup();
        let drivers =
            format!("[[drivers]]\nname = \"turn\"\njoint = \"j\"\nmotion = \"rotation\"\n{SPIN}\n");
        let lead = 0.25;
        let steps = solve(&description(&s, "screw", &format!("lead = {lead:?}"), &drivers));
        let k = lead / (2.0 * std::f64::consts::PI);
        // θ reaches 23 rad (3.7 turns) by t = 3.
        check(&s, &steps, |t| {
            let (th, thd, thdd) = spin(t);
            [(th, thd, thdd), (k * th, k * thd, k * thdd)]
        });
    }
}

/// Inverse kinematics as a description: a spatial 3R arm whose tool point's x, y and z are
/// driven, its joint angles read back and checked by forward kinematics written here.
mod inverse_kinematics {
    use nalgebra::DVector;

    use crate::generic::{Analysis, Equations};
    use crate::report::{self, Unwrap};
    use crate::symbolic::Symbolic;
    use crate::validate::{Format, load_str};

    /// Base yaw J1 about z at the origin, shoulder J2 and elbow J3 about y; upper arm 1 along x
    /// from (0, 0, 1), forearm 0.8 pointing down from the elbow at zero angles (bent, away from
    /// the stretched-arm singularity). Every frame is the global one at zero angles.
    const ARM: &str = r#"
name = "arm3r"
[time]
start = 0.0
end = 2.0
step = 0.02
[[bodies]]
name = "ground"
ground = true
[[bodies]]
name = "base"
[[bodies]]
name = "upper"
[[bodies]]
name = "fore"
[[joints]]
name = "J1"
type = "revolute"
body_i = "ground"
body_j = "base"
point_i = [0.0, 0.0, 0.0]
point_j = [0.0, 0.0, 0.0]
axis_i = [0.0, 0.0, 1.0]
axis_j = [0.0, 0.0, 1.0]
ref_i = [1.0, 0.0, 0.0]
ref_j = [1.0, 0.0, 0.0]
[[joints]]
name = "J2"
type = "revolute"
body_i = "base"
body_j = "upper"
point_i = [0.0, 0.0, 1.0]
point_j = [0.0, 0.0, 1.0]
axis_i = [0.0, 1.0, 0.0]
axis_j = [0.0, 1.0, 0.0]
ref_i = [1.0, 0.0, 0.0]
ref_j = [1.0, 0.0, 0.0]
[[joints]]
name = "J3"
type = "revolute"
body_i = "upper"
body_j = "fore"
point_i = [1.0, 0.0, 1.0]
point_j = [1.0, 0.0, 1.0]
axis_i = [0.0, 1.0, 0.0]
axis_j = [0.0, 1.0, 0.0]
ref_i = [1.0, 0.0, 0.0]
ref_j = [1.0, 0.0, 0.0]
[[points]]
name = "tool"
body = "fore"
local = [1.0, 0.0, 0.2]
[[drivers]]
name = "tool_x"
point = "tool"
coordinate = "x"
law = { offset = 1.0, amplitude = 0.2, frequency = 2.0 }
[[drivers]]
name = "tool_y"
point = "tool"
coordinate = "y"
law = { offset = 0.0, amplitude = 0.3, frequency = 1.5 }
[[drivers]]
name = "tool_z"
point = "tool"
coordinate = "z"
law = { offset = 0.2, amplitude = 0.1, frequency = 3.0 }
"#;

    /// The tool point for joint angles θ1 (yaw about z), θ2 and θ3 (about y, which turns x
    /// towards −z): (0, 0, 1) + R_z(θ1) [u (cos θ2, 0, −sin θ2) + f (−sin φ, 0, −cos φ)],
    /// φ = θ2 + θ3, upper arm u = 1, forearm f = 0.8.
    fn forward(t1: f64, t2: f64, t3: f64) -> [f64; 3] {
        let (u, f, phi) = (1.0, 0.8, t2 + t3);
        let reach = u * t2.cos() - f * phi.sin();
        let z = 1.0 - u * t2.sin() - f * phi.cos();
        [reach * t1.cos(), reach * t1.sin(), z]
    }

    #[test]
    fn the_joint_angles_of_a_driven_tool_point_reproduce_it_by_forward_kinematics() {
        let mech = load_str(ARM, Format::Toml, None).expect("valid").mechanism;
        let eq = Equations::new(&mech);
        let prep = eq.prepare();
        assert_eq!(prep.rank, eq.unknowns(), "the three point drivers fix the arm");
        let sys = Symbolic::build(&mech).expect("the generator takes point drivers");
        let layout = report::layout(&mech);
        let mut unwrap = Unwrap::default();
        let mut steps = 0;
        let law = |t: f64| {
            [1.0 + 0.2 * (2.0 * t).sin(), 0.3 * (1.5 * t).sin(), 0.2 + 0.1 * (3.0 * t).sin()]
        };
        let r = Analysis::new(&eq, &prep)
            .run(|frame| {
                let mut s = report::step_result(&mech, &layout, frame);
                unwrap.apply(&mut s);
                let angle = |k: usize| s.joints[k].angle.expect("revolute with refs")[0];
                let (tool, want) = (forward(angle(0), angle(1), angle(2)), law(frame.t));
                for c in 0..3 {
                    // The Newton tolerance (1e-10) on unit links bounds the tool's error.
                    assert!(
                        (tool[c] - want[c]).abs() < 1e-9,
                        "t {}: tool {tool:?} for {want:?}",
                        frame.t
                    );
                }
                // The symbolic rows of the point drivers agree with the generic solution:
                // Φ = 0, Φ_q q̇ = ν and Φ_q q̈ = γ (differentiated symbolically there, by
                // hand-written product rules here).
                let q = sys.reduce(&eq, &frame.q);
                let (qd, qdd) = (sys.reduce(&eq, &frame.qd), sys.reduce(&eq, &frame.qdd));
                let phi = sys.pool.eval(&sys.phi, q.as_slice(), qd.as_slice(), frame.t);
                let nu = sys.pool.eval(&sys.nu, q.as_slice(), qd.as_slice(), frame.t);
                let gamma = sys.pool.eval(&sys.gamma, q.as_slice(), qd.as_slice(), frame.t);
                for (row, entries) in sys.jac.iter().enumerate() {
                    let values: Vec<f64> = {
                        let ids: Vec<_> = entries.iter().map(|e| e.1).collect();
                        sys.pool.eval(&ids, q.as_slice(), qd.as_slice(), frame.t)
                    };
                    let dot = |v: &DVector<f64>| {
                        entries.iter().zip(&values).map(|((c, _), x)| x * v[*c]).sum::<f64>()
                    };
                    // Residuals of a converged step: tolerance 1e-10 on Φ; ν and γ are O(1)
                    // here, solved by LU to about 1e-12.
                    assert!(phi[row].abs() < 1e-9, "t {}: Φ {row} = {}", frame.t, phi[row]);
                    assert!((dot(&qd) - nu[row]).abs() < 1e-8, "t {}: ν row {row}", frame.t);
                    assert!((dot(&qdd) - gamma[row]).abs() < 1e-7, "t {}: γ row {row}", frame.t);
                }
                steps += 1;
                Ok::<(), ()>(())
            })
            .expect("the sink never fails");
        assert!(r.failure.is_none(), "{:?}", r.failure);
        assert_eq!(steps, mech.time.count);
    }
}

mod redundancy {
    use crate::generic::redundancy::independent;

    #[test]
    fn the_row_that_closes_a_dependency_is_named_never_a_normalisation() {
        // Rows over three columns: a = e0, b = e1, c = a + b, and a "normalisation" n = 2 e0
        // marked to come first. Order n, a, b, c: a depends on n, c on n and b.
        let rows = vec![
            vec![(0, 1.0)],
            vec![(1, 1.0)],
            vec![(0, 1.0), (1, 1.0)],
            vec![(0, 2.0)],
            vec![(2, 1.0)],
        ];
        let first = [false, false, false, true, false];
        let kept: Vec<usize> = independent(&rows, 3, &first).into_iter().collect();
        assert_eq!(kept, [1, 3, 4]);
        // Without the normalisation first, the later of the two equal directions goes.
        let kept: Vec<usize> = independent(&rows, 3, &[]).into_iter().collect();
        assert_eq!(kept, [0, 1, 4]);
    }

    #[test]
    fn the_test_is_relative_to_each_row() {
        // A row of size 1e-12 is kept when its direction is new; a row of size 1 that an
        // earlier row matches to 1e-12 of its size (below the 1e-8 bound) is named, although
        // the three rows have full rank.
        let rows = vec![
            vec![(0, 1.0), (1, 1.0)],
            vec![(0, 1e-12), (1, -1e-12)],
            vec![(0, 1.0), (1, 1.0), (2, 1e-12)],
        ];
        let kept: Vec<usize> = independent(&rows, 3, &[]).into_iter().collect();
        assert_eq!(kept, [0, 1]);
    }
}
