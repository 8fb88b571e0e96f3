//! U-P-S legs as distance rows (issue 16 point 2): the generator replaces each leg's driver row
//! by the distance row of the bodies the leg joins, so the platform's pose is a block of 7
//! unknowns and `--outputs platform` solves nothing else. The generic engine does not reduce
//! anything and is the reference: on the shipped Stewart platform (whose closed form
//! `examples::stewart` also gives the pose) and on a second geometry written here (legs
//! offset from their prismatic axes, both orientations of the leg, both orders of the
//! prismatic joint's bodies, a base that moves), the generated solvers, whole and pruned,
//! agree with it.

use std::sync::Arc;

use codegen::blocks::Blocks;
use codegen::blocks::outputs::only;
use codegen::generic::Frame;
use codegen::inputs::Replay;
use codegen::model::{DriverTarget, Mechanism, TimeGrid};
use codegen::symbolic::Symbolic;
use codegen::testing::{build_generated, load_toml, run_generated, run_generic};
use examples::stewart::{LEGS, Trajectory, leg_lengths};
use nalgebra::Vector3;

use crate::harness::mechgen;

/// Both engines stop Newton at max |Φ| ≤ 1e-12 (the descriptions' tolerance) on systems whose
/// Jacobians are well conditioned along these motions (the Stewart platform's leg Jacobian
/// has a condition number below 4.3), so each is within about 1e-11 of the exact solution
/// relative to the quantity's scale, and the two within 2e-11; 1e-10 leaves a margin of 5
/// (as `only_outputs`).
const AGREEMENT: f64 = 1e-10;

/// One quantity of a frame: q, q̇ or q̈.
type Quantity = fn(&Frame) -> &nalgebra::DVector<f64>;

const QUANTITIES: [(&str, Quantity); 3] = [("q", |f| &f.q), ("qd", |f| &f.qd), ("qdd", |f| &f.qdd)];

/// The offset of body `name`'s 7 coordinates in the generic layout of `mech` (moving bodies
/// in file order, 7 each).
fn offset(mech: &Mechanism, name: &str) -> usize {
    let moving: Vec<&str> =
        mech.bodies.iter().filter(|b| !b.ground).map(|b| b.name.as_str()).collect();
    7 * moving.iter().position(|&b| b == name).unwrap_or_else(|| panic!("no body {name}"))
}

/// Asserts that the bodies `names` have the same q, q̇ and q̈ in two runs, to [`AGREEMENT`]
/// of each quantity's largest magnitude over the reference run's bodies.
fn agree(names: &[&str], reference: (&Mechanism, &[Frame]), other: (&Mechanism, &[Frame])) {
    assert_eq!(reference.1.len(), other.1.len(), "both runs reach the end");
    for (label, get) in QUANTITIES {
        let scale = reference.1.iter().flat_map(|f| get(f).iter()).fold(0.0, |m, x| x.abs().max(m));
        let mut worst = 0.0f64;
        for (a, b) in reference.1.iter().zip(other.1) {
            assert_eq!(a.t, b.t);
            for name in names {
                let (oa, ob) = (offset(reference.0, name), offset(other.0, name));
                for k in 0..7 {
                    let diff = (get(a)[oa + k] - get(b)[ob + k]).abs() / scale;
                    worst = worst.max(diff);
                    assert!(diff <= AGREEMENT, "{name} {label}[{k}] at t = {}: {diff:e}", a.t);
                }
            }
        }
        eprintln!("{label}: worst relative difference {worst:e}");
    }
}

/// The block of the platform: 7 unknowns, all of them the platform's.
fn platform_block(mech: &Mechanism, sys: &Symbolic) {
    let blocks = Blocks::of(sys, mech);
    let platform = mech.bodies.iter().position(|b| b.name == "platform").expect("a platform");
    let block = blocks
        .blocks
        .iter()
        .find(|b| b.unknowns.iter().any(|&k| sys.unknowns[k].0.0 == platform))
        .expect("the platform's unknowns are in a block");
    assert_eq!(block.unknowns.len(), 7, "{block:?}");
    assert!(block.unknowns.iter().all(|&k| sys.unknowns[k].0.0 == platform));
}

/// The shipped description replaying the closed-form leg lengths every 10 ms for 1 s.
fn shipped() -> Mechanism {
    let path = codegen::testing::example_arg("inputs/stewart.toml");
    let mut mech = codegen::validate::load_file(path.as_ref()).expect("valid").mechanism;
    let t: Vec<f64> = (0..=100).map(|k| f64::from(k) * 0.01).collect();
    let lengths: Vec<[[f64; 3]; LEGS]> =
        t.iter().map(|&t| leg_lengths(&Trajectory::SHIPPED.at(t))).collect();
    let replay = Replay {
        file: "closed form".into(),
        t: t.clone(),
        series: (0..LEGS).map(|k| Some(lengths.iter().map(|l| l[k]).collect())).collect(),
        declared: (mech.time.start, mech.time.step, mech.time.count),
    };
    mech.time = TimeGrid::replaying(Arc::new(replay));
    mech
}

#[test]
fn check_names_the_reduced_legs_and_the_platform_block_of_seven() {
    let (code, out, err) =
        mechgen(&["check", &codegen::testing::example_arg("inputs/stewart.toml")]);
    assert_eq!(code, 0, "{err}");
    // 6 platform rows and its normalisation; per leg the cylinder's position (3 closed-form
    // blocks), the rod's position (3) and orientations (two blocks of 4).
    for line in [
        "blocks:            49 (36 closed form, 13 implicit, the largest of 7)",
        "block sizes:       36 of 1, 12 of 4, 1 of 7",
        "reduced legs:      6, each driver row replaced by a distance row: leg1 (cylinder1, \
         rod1: ground to platform)",
    ] {
        assert!(out.contains(line), "{line}\n{out}");
    }
    let mech = shipped();
    let sys = Symbolic::build(&mech).expect("builds");
    assert_eq!(sys.legs.len(), 6);
    platform_block(&mech, &sys);
}

#[test]
fn the_platform_only_part_keeps_the_six_inputs_in_order_and_nothing_of_the_legs() {
    let mech = shipped();
    let sys = Symbolic::build(&mech).expect("builds");
    let part = only(&mech, &sys, &["platform".to_owned()]).expect("the body exists");
    let bodies: Vec<&str> = part.bodies.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(bodies, ["ground", "platform"]);
    assert!(part.joints.is_empty());
    let drivers: Vec<&str> = part.drivers.iter().map(|d| d.name.as_str()).collect();
    assert_eq!(drivers, ["leg1", "leg2", "leg3", "leg4", "leg5", "leg6"]);
    assert!(part.drivers.iter().all(|d| matches!(d.target, DriverTarget::Leg(_))));
    let reduced = Symbolic::build(&part).expect("builds");
    assert_eq!(reduced.unknowns.len(), 7);
    let inputs: Vec<usize> = reduced.inputs.iter().map(|i| i.driver).collect();
    assert_eq!(inputs, [0, 1, 2, 3, 4, 5], "the leg lengths are inputs 0 to 5, in order");
    // The committed module is that part (`cargo codegen`, checked by the freshness test).
    assert_eq!(generated::stewart_platform::N, 7);
    assert_eq!(
        generated::stewart_platform::INPUT_NAMES,
        ["leg1", "leg2", "leg3", "leg4", "leg5", "leg6"]
    );
}

/// The generic engine on the pruned part (its distance rows written by hand, independently of
/// the symbolic ones) and on the whole (the legs as they are) give the platform the same
/// motion, and both recover the closed form's pose.
#[test]
fn the_generic_engine_on_the_pruned_part_has_the_whole_platform_motion() {
    let mech = shipped();
    let sys = Symbolic::build(&mech).expect("builds");
    let part = only(&mech, &sys, &["platform".to_owned()]).expect("the body exists");
    let whole = run_generic(&mech);
    assert!(whole.failure.is_none(), "{:?}", whole.failure);
    let pruned = run_generic(&part);
    assert!(pruned.failure.is_none(), "{:?}", pruned.failure);
    agree(&["platform"], (&mech, &whole.frames), (&part, &pruned.frames));
    for f in &pruned.frames {
        let m = Trajectory::SHIPPED.at(f.t);
        let r = Vector3::new(f.q[0], f.q[1], f.q[2]);
        // Newton to 1e-12 with a leg Jacobian of condition below 4.3: the pose within 1e-11.
        assert!((r - m.position).abs().max() < 1e-10, "t = {}: {r} vs {}", f.t, m.position);
    }
}

/// The frames of a committed generated module stepped with plain calls over the grid of `mech`
/// (the closed-form leg lengths at each time point), in the generic layout of the bodies it
/// solves: `step` solves one time point and returns (q, q̇, q̈).
fn stepped(
    mech: &Mechanism,
    mut step: impl FnMut(f64, &[[f64; 3]; LEGS]) -> [Vec<f64>; 3],
) -> Vec<Frame> {
    (0..mech.time.count)
        .map(|k| {
            let t = mech.time.at(k);
            let [q, qd, qdd] = step(t, &leg_lengths(&Trajectory::SHIPPED.at(t)));
            Frame {
                index: k,
                t,
                iterations: 0,
                residual: 0.0,
                condition: 1.0,
                q: q.into(),
                qd: qd.into(),
                qdd: qdd.into(),
                redundant: None,
            }
        })
        .collect()
}

/// q, q̇ and q̈ of every moving body, flattened in the generic layout (moving bodies in file
/// order, which is the order of a module's `expand`, 7 coordinates each), from `expand`'s
/// output: independent of which coordinates the module keeps as unknowns.
fn flat<const B: usize>(out: &[[[f64; 7]; 3]; B]) -> [Vec<f64>; 3] {
    std::array::from_fn(|k| out.iter().flat_map(|body| body[k]).collect())
}

/// The committed modules, whole (`generated::stewart`, 55 unknowns after 36 closed-form
/// coordinates of the legs' bodies are substituted, the legs' orientations solved after the
/// platform) and the platform alone (`generated::stewart_platform`), against the generic engine
/// on the whole description, every body read through the module's `expand`, and the platform
/// against the closed form.
#[test]
fn the_committed_generated_modules_agree_with_the_generic_engine() {
    let mech = shipped();
    let sys = Symbolic::build(&mech).expect("builds");
    let part = only(&mech, &sys, &["platform".to_owned()]).expect("the body exists");
    let whole = run_generic(&mech);
    assert!(whole.failure.is_none(), "{:?}", whole.failure);

    let mut solver = examples::stewart::control::solver(&Trajectory::SHIPPED, 0.0);
    let all = stepped(&mech, |t, u| {
        examples::stewart::control::plain_step(&mut solver, t, u).expect("the platform follows");
        let mut out = [[[0.0; 7]; 3]; generated::stewart::BODIES];
        let inputs = examples::stewart::control::inputs(u);
        generated::stewart::expand(solver.q(), solver.qd(), solver.qdd(), t, &inputs, &mut out);
        flat(&out)
    });
    let names: Vec<&str> =
        mech.bodies.iter().filter(|b| !b.ground).map(|b| b.name.as_str()).collect();
    // Every body, the legs' cylinders and rods with the platform.
    agree(&names, (&mech, &whole.frames), (&mech, &all));

    let mut solver = examples::stewart::pose::solver(&Trajectory::SHIPPED, 0.0);
    let platform = stepped(&part, |t, u| {
        examples::stewart::pose::plain_step(&mut solver, t, u).expect("the platform follows");
        let mut out = [[[0.0; 7]; 3]; generated::stewart_platform::BODIES];
        let inputs = examples::stewart::pose::inputs(u);
        let (q, qd, qdd) = (solver.q(), solver.qd(), solver.qdd());
        generated::stewart_platform::expand(q, qd, qdd, t, &inputs, &mut out);
        flat(&out)
    });
    agree(&["platform"], (&mech, &whole.frames), (&part, &platform));
    for f in &platform {
        let m = Trajectory::SHIPPED.at(f.t);
        let r = Vector3::new(f.q[0], f.q[1], f.q[2]);
        let v = Vector3::new(f.qd[0], f.qd[1], f.qd[2]);
        let a = Vector3::new(f.qdd[0], f.qdd[1], f.qdd[2]);
        // As above: the pose within 1e-11, its rates by the pose error over lever arms ≥ 0.5 m.
        assert!((r - m.position).abs().max() < 1e-10, "t = {}: {r} vs {}", f.t, m.position);
        assert!((v - m.velocity).abs().max() < 1e-10, "t = {}: {v} vs {}", f.t, m.velocity);
        assert!((a - m.acceleration).abs().max() < 1e-10, "t = {}", f.t);
        let rotation = examples::stewart::control::rotation([f.q[3], f.q[4], f.q[5], f.q[6]]);
        assert!((rotation - m.rotation).abs().max() < 1e-10, "t = {}", f.t);
    }
}

/// `[x, y, z]` with round-trip numbers.
fn v(x: Vector3<f64>) -> String {
    format!("[{:?}, {:?}, {:?}]", x.x, x.y, x.z)
}

/// A platform of another geometry: base attachments on a circle of radius 1.2 m, 0.1 m above a
/// base that turns about z (a driven revolute to ground, so the legs join two moving bodies),
/// platform attachments on a circle of 0.6 m, 0.05 m below the platform's centre at
/// (0.05, −0.03, 0.9), pairs at uneven angles. Each leg's platform-side point is offset from
/// its prismatic axis by 3 to 5.5 cm (v0 has a lateral and an axial part). Legs 4 and 6 are
/// S-P-U (universal joint at the platform), legs 2 and 4 list the prismatic joint's bodies rod
/// first, legs 3 and 6 the universal joint's leg body first. Every body frame has the global
/// orientation at home; the lengths follow harmonic laws about their home values.
fn other_geometry() -> String {
    let base_deg = [-12.0_f64, 17.0, 103.0, 137.0, 222.0, 258.0];
    let platform_deg = [-50.0_f64, 40.0, 80.0, 160.0, 200.0, 280.0];
    let centre = Vector3::new(0.05, -0.03, 0.9);
    let z = Vector3::z();
    let mut text = String::from(
        "name = \"legs\"\n[time]\nstart = 0.0\nend = 1.0\nstep = 0.05\n[solver]\ntolerance = 1e-12\n\
         [[bodies]]\nname = \"ground\"\nground = true\n\
         [[bodies]]\nname = \"base\"\nr = [0.0, 0.0, 0.0]\n\
         [[bodies]]\nname = \"platform\"\n",
    );
    text.push_str(&format!("r = {}\n", v(centre)));
    text.push_str(
        "[[joints]]\nname = \"spin\"\ntype = \"revolute\"\nbody_i = \"ground\"\nbody_j = \"base\"\n\
         point_i = [0.0, 0.0, 0.0]\npoint_j = [0.0, 0.0, 0.0]\naxis_i = [0.0, 0.0, 1.0]\n\
         axis_j = [0.0, 0.0, 1.0]\nref_i = [1.0, 0.0, 0.0]\nref_j = [1.0, 0.0, 0.0]\n\
         [[drivers]]\nname = \"turn\"\njoint = \"spin\"\nmotion = \"rotation\"\n\
         law = { offset = 0.0, amplitude = 0.1, frequency = 2.0, phase = 0.0 }\n",
    );
    for k in 0..LEGS {
        let n = k + 1;
        let (b, p) = (base_deg[k].to_radians(), platform_deg[k].to_radians());
        let base_point = Vector3::new(1.2 * b.cos(), 1.2 * b.sin(), 0.1);
        let platform_local = Vector3::new(0.6 * p.cos(), 0.6 * p.sin(), -0.05);
        let d = centre + platform_local - base_point;
        let n1 = d.cross(&z).normalize();
        let n2 = d.cross(&n1).normalize();
        let angle = 0.9 * k as f64;
        let offset = (0.03 + 0.005 * k as f64) * (angle.cos() * n1 + angle.sin() * n2);
        let axis = (d - offset).normalize();
        let s0 = (d - offset).norm();
        let (r1, r2) = (axis.cross(&z).normalize(), axis.cross(&axis.cross(&z).normalize()));
        let lower = format!("lower{n}");
        let upper = format!("upper{n}");
        text.push_str(&format!(
            "[[bodies]]\nname = \"{lower}\"\nr = {}\n[[bodies]]\nname = \"{upper}\"\nr = {}\n",
            v(base_point),
            v(base_point + s0 * axis)
        ));
        let zero = v(Vector3::zeros());
        // The prismatic joint, rod first for legs 2 and 4 (its axis then points down the leg,
        // so that s is the same positive length).
        let (pi, pj, a) =
            if n == 2 || n == 4 { (&upper, &lower, -axis) } else { (&lower, &upper, axis) };
        text.push_str(&format!(
            "[[joints]]\nname = \"P{n}\"\ntype = \"prismatic\"\nbody_i = \"{pi}\"\n\
             body_j = \"{pj}\"\npoint_i = {zero}\npoint_j = {zero}\naxis_i = {}\naxis_j = {}\n\
             ref_i = {}\nref_j = {}\n",
            v(a),
            v(a),
            v(r1),
            v(r2)
        ));
        // The ends: (leg body, its point, other body, its point).
        let base_end = (&lower, Vector3::zeros(), "base", base_point);
        let platform_end = (&upper, offset, "platform", platform_local);
        let (u_end, s_end) =
            if n == 4 || n == 6 { (platform_end, base_end) } else { (base_end, platform_end) };
        let (leg_body, leg_point, other, other_point) = u_end;
        let (bi, pi, bj, pj, ai, aj) = if n == 3 || n == 6 {
            (leg_body.as_str(), leg_point, other, other_point, r2, r1)
        } else {
            (other, other_point, leg_body.as_str(), leg_point, r1, r2)
        };
        text.push_str(&format!(
            "[[joints]]\nname = \"U{n}\"\ntype = \"universal\"\nbody_i = \"{bi}\"\nbody_j = \"{bj}\"\n\
             point_i = {}\npoint_j = {}\naxis_i = {}\naxis_j = {}\n",
            v(pi),
            v(pj),
            v(ai),
            v(aj)
        ));
        let (leg_body, leg_point, other, other_point) = s_end;
        text.push_str(&format!(
            "[[joints]]\nname = \"S{n}\"\ntype = \"spherical\"\nbody_i = \"{leg_body}\"\n\
             body_j = \"{other}\"\npoint_i = {}\npoint_j = {}\n",
            v(leg_point),
            v(other_point)
        ));
        text.push_str(&format!(
            "[[drivers]]\nname = \"len{n}\"\njoint = \"P{n}\"\nmotion = \"translation\"\n\
             law = {{ offset = {s0:?}, amplitude = 0.015, frequency = {:?}, phase = {:?} }}\n",
            2.0 + 0.3 * k as f64,
            0.7 * k as f64
        ));
    }
    text
}

#[test]
fn another_geometry_with_offset_legs_both_orientations_and_a_moving_base_agrees() {
    let mech = load_toml(&other_geometry());
    let sys = Symbolic::build(&mech).expect("builds");
    let reduced: Vec<&str> =
        sys.legs.iter().map(|l| mech.drivers[l.driver].name.as_str()).collect();
    assert_eq!(reduced, ["len1", "len2", "len3", "len4", "len5", "len6"]);
    assert!(
        sys.legs.iter().all(|l| l.leg.base > 0.0 && l.leg.along.abs() > 0.0),
        "v0 has a lateral and an axial part: {:?}",
        sys.legs
    );
    platform_block(&mech, &sys);
    let part = only(&mech, &sys, &["platform".to_owned()]).expect("the body exists");
    let bodies: Vec<&str> = part.bodies.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(bodies, ["ground", "base", "platform"]);
    assert_eq!(Symbolic::build_full(&part).expect("builds").unknowns.len(), 14);

    let whole = run_generic(&mech);
    assert!(whole.failure.is_none(), "{:?}", whole.failure);
    // The platform moves: the laws are not a rest.
    let (first, last) = (&whole.frames[0], &whole.frames[whole.frames.len() - 1]);
    let o = offset(&mech, "platform");
    assert!((first.q[o + 2] - last.q[o + 2]).abs() > 1e-3);

    let generated = run_generated(&mech, &build_generated(&mech));
    assert!(generated.failure.is_none(), "{:?}", generated.failure);
    let names: Vec<&str> =
        mech.bodies.iter().filter(|b| !b.ground).map(|b| b.name.as_str()).collect();
    agree(&names, (&mech, &whole.frames), (&mech, &generated.frames));

    let pruned = run_generated(&part, &build_generated(&part));
    assert!(pruned.failure.is_none(), "{:?}", pruned.failure);
    agree(&["base", "platform"], (&mech, &whole.frames), (&part, &pruned.frames));
    let generic_pruned = run_generic(&part);
    assert!(generic_pruned.failure.is_none(), "{:?}", generic_pruned.failure);
    agree(&["base", "platform"], (&mech, &whole.frames), (&part, &generic_pruned.frames));
}

/// Substituted, the Stewart platform keeps 55 of its 91 unknowns: per leg the cylinder's
/// position (the universal joint at a base point) and the rod's (the spherical joint at a
/// platform point) are closed forms, 6 coordinates a leg. The committed module
/// (`generated::stewart`) is that system; stepped along the shipped motion, every body agrees
/// with the generic engine (above) and each leg keeps its driven length: between the base
/// attachment and the platform attachment placed by the solved platform pose, and between the
/// origins of the leg's substituted cylinder and rod (the joints' points), read through
/// `expand`.
#[test]
fn substitution_keeps_55_of_91_unknowns_and_every_leg_its_driven_length() {
    use examples::stewart::{base_point, control, platform_point};
    use generated::stewart as gs;
    let mech = shipped();
    let whole = Symbolic::build_full(&mech).expect("builds");
    let sys = Symbolic::build(&mech).expect("builds");
    assert_eq!(whole.unknowns.len(), 91);
    assert_eq!(sys.unknowns.len(), 55, "36 leg coordinates substituted");
    assert_eq!(sys.derived.len(), 36);
    assert_eq!(sys.legs.len(), 6, "the legs stay reduced to distance rows");
    assert_eq!(gs::N, 55, "the committed module is the substituted system");

    let body = |name: &str| gs::BODY_NAMES.iter().position(|&b| b == name).expect("a body");
    let mut solver = control::solver(&Trajectory::SHIPPED, 0.0);
    let mut worst = 0.0f64;
    for k in 0..mech.time.count {
        let t = mech.time.at(k);
        let lengths = leg_lengths(&Trajectory::SHIPPED.at(t));
        control::plain_step(&mut solver, t, &lengths).expect("the platform follows");
        let mut out = [[[0.0; 7]; 3]; gs::BODIES];
        gs::expand(solver.q(), solver.qd(), solver.qdd(), t, &control::inputs(&lengths), &mut out);
        let position = |b: usize| Vector3::new(out[b][0][0], out[b][0][1], out[b][0][2]);
        let [e0, e1, e2, e3] = out[body("platform")][0][3..].try_into().expect("4");
        let rotation = control::rotation([e0, e1, e2, e3]);
        for (leg, l) in lengths.iter().enumerate() {
            let n = leg + 1;
            let platform = position(body("platform")) + rotation * platform_point(leg);
            let ends = position(body(&format!("rod{n}"))) - position(body(&format!("cylinder{n}")));
            for length in [(platform - base_point(leg)).norm(), ends.norm()] {
                worst = worst.max((length - l[0]).abs());
                // Newton to 1e-12 with a leg Jacobian of condition below 4.3: each length within
                // about 1e-11 m of the driven one (lengths of about 1 m); 1e-10 leaves a margin.
                assert!((length - l[0]).abs() < 1e-10, "t = {t}, leg {n}: {length} vs {}", l[0]);
            }
        }
    }
    eprintln!("largest leg length error {worst:e} m");
}
