//! The RSSR against Appendix C of the thesis (`rssr-reference.json`): Prof. Tarcisio
//! Coelho's program, checked with ADAMS, gives point A (the coupler origin) and point B (the
//! coupler's local (0, 0.4812, 0)) with their velocities and accelerations at 12 times, one
//! crank revolution in 30° steps.
//!
//! Appendix C's parameters are the float32 values of the deck's inputs (its O2 y is
//! float32(−0.06567) = −0.06566999852657318, its ω2 float32(146.6) = 146.6000061035156): that
//! program computed in double precision from single-precision inputs. The deck's decimal
//! values would move the crank by up to (146.6000061 − 146.6)·0.039 s = 2.4e-7 rad by the last
//! step, 5e-4 m/s² in AA, far above Appendix C's own accuracy for A (1e-12 relative). So the
//! description here is the imported rssr deck with Appendix C's geometry, crank speed and time
//! grid put in; the test first checks that each of those is the deck's value rounded to
//! float32, so nothing else changes.

use codegen::desc::{JointDesc, JointType, MechanismDesc, TimeDesc};
use nalgebra::Vector3;
use serde_json::Value;

use crate::harness::{self, Comparison, Place, Quantity, num};

/// A reference 3-vector.
fn vec3(v: &Value) -> Vector3<f64> {
    let a = v.as_array().expect("a 3-vector");
    Vector3::new(num(&a[0]), num(&a[1]), num(&a[2]))
}

fn arr(v: Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// The float32 number that Appendix C prints (with 16 significant digits) as `printed`,
/// after checking that the deck's `deck` rounds to the same float32.
fn float32_of(what: &str, deck: f64, printed: f64) -> f64 {
    #[expect(clippy::cast_possible_truncation, reason = "rounding to float32 is the point")]
    let (deck32, printed32) = (deck as f32, printed as f32);
    let exact = f64::from(printed32);
    // 16 significant digits leave at most half a unit of the 16th: 5e-16 relative.
    assert!((exact - printed).abs() <= 5e-16 * exact.abs(), "{what}: {printed} is not a float32");
    assert_eq!(deck32, printed32, "{what}: the deck's {deck} does not round to Appendix C's");
    exact
}

fn vec_float32_of(what: &str, deck: Vector3<f64>, printed: Vector3<f64>) -> Vector3<f64> {
    Vector3::from_fn(|c, _| float32_of(&format!("{what}[{c}]"), deck[c], printed[c]))
}

/// The deck's joint of `kind` between bodies `i` and `j` (deck numbers).
fn joint_mut(desc: &mut MechanismDesc, kind: JointType, i: usize, j: usize) -> &mut JointDesc {
    let (bi, bj) = (format!("body{i}"), format!("body{j}"));
    desc.joints
        .iter_mut()
        .find(|jt| jt.kind == kind && jt.body_i == bi && jt.body_j == bj)
        .unwrap_or_else(|| panic!("the rssr deck has no {} joint {bi}–{bj}", kind.as_str()))
}

/// The rssr deck with Appendix C's parameters and time grid.
///
/// Deck bodies: 1 ground, 2 crank (frame at O2, revolute to ground about y), 3 coupler
/// (frame at A, spherical to the crank at A and to the rocker at B), 4 rocker (frame at O4,
/// revolute to ground about x). All body frames start parallel to the global frame, so local
/// offsets are differences of global points.
fn appendix_c_description(reference: &Value) -> MechanismDesc {
    let mut desc = harness::import_deck("rssr");
    let par = &reference["parameters"];
    let (o2, o4, a, b) = (vec3(&par["O2"]), vec3(&par["O4"]), vec3(&par["A"]), vec3(&par["B"]));
    let omega2 = num(&par["omega2"]);
    assert_eq!(num(&par["omega2p"]), 0.0, "Appendix C's crank turns at constant speed");
    assert_eq!(vec3(&par["q2"]), Vector3::y(), "crank axis");
    assert_eq!(vec3(&par["q4"]), Vector3::x(), "rocker axis");

    let body_r = |desc: &MechanismDesc, k: usize| {
        Vector3::from(desc.bodies[k - 1].r.expect("the deck gives every body an r"))
    };
    for k in 2..=4 {
        let p = desc.bodies[k - 1].p.expect("the deck gives every body a p");
        assert_eq!(p, [1.0, 0.0, 0.0, 0.0], "body {k} starts parallel to the global frame");
    }
    let b_local = Vector3::from(desc.points[1].local);
    assert_eq!(desc.points[1].body, "body3", "point B is on the coupler");
    assert_eq!(desc.points[0].local, [0.0; 3], "point A is the coupler origin");
    let deck_omega2 = desc.drivers[0].law.velocity.expect("the crank driver has a velocity");
    let omega2 = float32_of("ω2", deck_omega2, omega2);
    let o2 = vec_float32_of("O2", body_r(&desc, 2), o2);
    let o4 = vec_float32_of("O4", body_r(&desc, 4), o4);
    let a = vec_float32_of("A", body_r(&desc, 3), a);
    let b = vec_float32_of("B", body_r(&desc, 3) + b_local, b);

    desc.drivers[0].law.velocity = Some(omega2);
    desc.bodies[1].r = Some(arr(o2));
    desc.bodies[2].r = Some(arr(a));
    desc.bodies[3].r = Some(arr(o4));
    desc.points[1].local = arr(b - a);
    let o2_joint = joint_mut(&mut desc, JointType::Revolute, 1, 2);
    o2_joint.point_i = Some(arr(o2));
    o2_joint.point_j = Some([0.0; 3]);
    let o4_joint = joint_mut(&mut desc, JointType::Revolute, 4, 1);
    o4_joint.point_i = Some([0.0; 3]);
    o4_joint.point_j = Some(arr(o4));
    let a_joint = joint_mut(&mut desc, JointType::Spherical, 2, 3);
    a_joint.point_i = Some(arr(a - o2));
    a_joint.point_j = Some([0.0; 3]);
    let b_joint = joint_mut(&mut desc, JointType::Spherical, 3, 4);
    b_joint.point_i = Some(arr(b - a));
    b_joint.point_j = Some(arr(b - o4));

    let tempos: Vec<f64> = steps(reference).iter().map(|s| num(&s["tempo"])).collect();
    let (first, last) = (tempos[0], tempos[tempos.len() - 1]);
    desc.time =
        TimeDesc { start: first, end: last, step: None, steps: Some(tempos.len() as u64 - 1) };
    desc
}

fn steps(reference: &Value) -> &Vec<Value> {
    reference["steps"].as_array().expect("`steps` is an array")
}

/// Tolerance of each compared vector, as a function of the reference vector's length.
///
/// A, VA, AA: Appendix C matches their closed form to about 1e-12 relative
/// (README-complex); ours carry our Newton tolerance, 1e-10 on max |Φ| over lengths of
/// 0.1–0.5 m, i.e. ≈1e-9 relative: 1e-9 of the vector's length.
///
/// B, VB, AB: Appendix C's own solver noise against the closed form of its single-precision
/// inputs is up to 5.3e-8 m, 1.6e-6 m/s and 1.3e-4 m/s² (README-complex, "Sanity
/// analysis"), plus the same 1e-9 relative for ours. This also covers the two digit-count
/// doubts of `notes` (VB y 3.71707348524490e-5, closed form 3.7170736e-5; AB z
/// 172.82144174888268, closed form 172.82144240).
fn tolerance(point_b: bool, quantity: Quantity, length: f64) -> f64 {
    let noise = if point_b { [5.3e-8, 1.6e-6, 1.3e-4][quantity.order()] } else { 0.0 };
    noise + 1e-9 * length
}

#[test]
fn rssr_points_match_appendix_c_at_its_own_times() {
    let reference = harness::read_json("rssr-reference.json");
    let desc = appendix_c_description(&reference);
    matches_appendix_c(&reference, &harness::solve("rssr (Appendix C)", &desc));
}

#[test]
fn rssr_points_of_the_generated_solver_match_appendix_c() {
    // The generated solver runs Newton on 5 unknowns of the S-S loop, with the crank's
    // orientation, the bodies' positions and the rocker's e2 and e3 substituted by their
    // closed forms (`symbolic::substitute`).
    let reference = harness::read_json("rssr-reference.json");
    let desc = appendix_c_description(&reference);
    let run = harness::solve_generated("rssr (Appendix C, generated)", &desc);
    let sys = codegen::symbolic::Symbolic::build(&run.mechanism).expect("the system builds");
    assert_eq!((sys.unknowns.len(), sys.derived.len()), (5, 15));
    matches_appendix_c(&reference, &run);
}

/// Points A and B of `run` against Appendix C at each of its times.
fn matches_appendix_c(reference: &Value, run: &harness::Run) {
    let times: Vec<f64> = steps(reference).iter().map(|s| num(&s["tempo"])).collect();
    run.assert_covers(times.iter().copied());
    assert_eq!(run.steps.len(), times.len(), "one analysed step per Appendix C time");

    let mut cmp_a = Comparison::new("rssr point A", "Appendix C (Tarcisio Coelho, ADAMS-checked)");
    let mut cmp_b = Comparison::new("rssr point B", "Appendix C (Tarcisio Coelho, ADAMS-checked)");
    let fields = [
        ("A", Quantity::R),
        ("VA", Quantity::Rd),
        ("AA", Quantity::Rdd),
        ("B", Quantity::R),
        ("VB", Quantity::Rd),
        ("AB", Quantity::Rdd),
    ];
    for (entry, &t) in steps(reference).iter().zip(&times) {
        let step = run.step_at(t).expect("covered above");
        for (key, quantity) in fields {
            let point_b = key.ends_with('B');
            // AB of the last step is null: the OCR text ends after AA (`notes`).
            if entry[key].is_null() {
                continue;
            }
            let expected = vec3(&entry[key]);
            let ours = &step.points[usize::from(point_b)];
            let ours = Vector3::from(match quantity.order() {
                0 => ours.r,
                1 => ours.v,
                _ => ours.a,
            });
            let tol = tolerance(point_b, quantity, expected.norm());
            for c in 0..3 {
                let number = 1 + usize::from(point_b);
                let place = Place { t, point: true, number, quantity, component: c };
                let cmp = if point_b { &mut cmp_b } else { &mut cmp_a };
                cmp.value(place, ours[c], expected[c], tol);
            }
        }
    }
    cmp_a.finish();
    cmp_b.finish();
}
