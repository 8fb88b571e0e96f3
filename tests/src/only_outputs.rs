//! Only what is asked (`generate --outputs`, `codegen::build::Builder::file_with_outputs`,
//! `solve --select` on the generated engine): the blocks no requested output depends on are
//! left out, and what is kept has the values of the whole mechanism.

use codegen::blocks::outputs::only;
use codegen::symbolic::Symbolic;
use codegen::testing::{build_generated, load_toml, run_generated, run_generic};

/// The kept part and the whole agree to this fraction of each quantity's scale: the kept
/// blocks are the same equations in both, and with Newton asked for max |Φ| ≤ 1e-12 each run
/// stops within 1e-12 times the conditioning of where the other stops; 1e-10 leaves a factor
/// of 100 (as `block_solver`).
const AGREEMENT: f64 = 1e-10;

/// One quantity of a frame: q, q̇ or q̈.
type Quantity = fn(&codegen::generic::Frame) -> &nalgebra::DVector<f64>;

/// The names of the moving bodies of a mechanism, in file order.
fn moving(mech: &codegen::model::Mechanism) -> Vec<String> {
    mech.bodies.iter().filter(|b| !b.ground).map(|b| b.name.clone()).collect()
}

#[test]
fn one_arm_of_ten_is_all_its_tool_point_needs_and_has_the_whole_mechanisms_values() {
    let text = codegen::scale::arms(10, 6, 20);
    let tool = "[[points]]\nname = \"tool\"\nbody = \"arm3_link6\"\nlocal = [0.25, 0.0, 0.0]\n";
    let mech = load_toml(&format!("{text}\n{tool}\n[solver]\ntolerance = 1e-12\n"));
    let sys = Symbolic::build(&mech).expect("the system builds");
    let part = only(&mech, &sys, &["tool".to_owned()]).expect("the point exists");
    // The arms are independent: the third one's six links, nothing of the others.
    let expected: Vec<String> = (1..=6).map(|k| format!("arm3_link{k}")).collect();
    assert_eq!(moving(&part), expected);
    let joints: Vec<&str> = part.joints.iter().map(|j| j.name.as_str()).collect();
    assert_eq!(joints, (1..=6).map(|k| format!("arm3_joint{k}")).collect::<Vec<_>>());
    assert_eq!(part.drivers.len(), 6);
    assert_eq!(part.points.len(), 1);
    // Before its closed forms are substituted (all of them: a driven arm has no loop).
    assert_eq!(Symbolic::build_full(&part).unwrap().unknowns.len(), 42, "7 unknowns per link");
    assert_eq!(Symbolic::build(&part).unwrap().unknowns.len(), 0, "every block closed form");

    // Its generated solver against the generic engine on all ten arms: the third arm's
    // coordinates, rates and accelerations (7 per link; arm 3 is links 13 to 18 of 60).
    let whole = run_generic(&mech);
    assert!(whole.failure.is_none(), "{:?}", whole.failure);
    let kept = run_generated(&part, &build_generated(&part));
    assert!(kept.failure.is_none(), "{:?}", kept.failure);
    assert_eq!(kept.frames.len(), whole.frames.len());
    let quantities: [(&str, Quantity); 3] =
        [("q", |f| &f.q), ("qd", |f| &f.qd), ("qdd", |f| &f.qdd)];
    for (label, get) in quantities {
        let scale =
            whole.frames.iter().flat_map(|f| get(f).iter()).fold(0.0, |m, x| x.abs().max(m));
        for (a, b) in whole.frames.iter().zip(&kept.frames) {
            assert_eq!(get(b).len(), 42);
            for k in 0..42 {
                let diff = (get(a)[7 * 12 + k] - get(b)[k]).abs() / scale;
                assert!(diff <= AGREEMENT, "{label}[{k}] at t = {}: {diff:e}", a.t);
            }
        }
    }
}

#[test]
fn an_output_at_link_three_of_a_hundred_keeps_links_one_to_three() {
    let mech = load_toml(&codegen::scale::chain(100, 5));
    let sys = Symbolic::build(&mech).expect("the system builds");
    // Every link is placed by its driven hinge: the whole chain is substituted in closed form.
    assert_eq!(sys.unknowns.len(), 0);
    assert_eq!(Symbolic::build_full(&mech).unwrap().unknowns.len(), 700);
    let part = only(&mech, &sys, &["link3".to_owned()]).expect("the body exists");
    assert_eq!(moving(&part), ["link1", "link2", "link3"]);
    let drivers: Vec<&str> = part.drivers.iter().map(|d| d.name.as_str()).collect();
    assert_eq!(drivers, ["motor1", "motor2", "motor3"]);
    assert_eq!(Symbolic::build_full(&part).unwrap().unknowns.len(), 21);
    // A joint asks for both its bodies: hinge 5 needs links 1 to 5.
    let part = only(&mech, &sys, &["hinge5".to_owned()]).expect("the joint exists");
    assert_eq!(moving(&part), ["link1", "link2", "link3", "link4", "link5"]);
    // The last link needs the whole chain.
    assert_eq!(only(&mech, &sys, &["link100".to_owned()]).unwrap(), mech);
}

#[test]
fn an_unknown_output_is_named_with_the_outputs_that_exist() {
    let mech = load_toml(&codegen::scale::chain(3, 5));
    let sys = Symbolic::build(&mech).expect("the system builds");
    let e = only(&mech, &sys, &["link2".to_owned(), "lnk3".to_owned()]).unwrap_err();
    let message = e.to_string();
    assert!(message.contains("\"lnk3\""), "{message}");
    assert!(message.contains("did you mean \"link3\""), "{message}");
    assert!(message.contains("link1, link2, link3, hinge1, hinge2, hinge3"), "{message}");
}

/// The step cost of the generated solver with and without the pruning, on ten arms asked for
/// one tool point (BENCHMARKS.md, "Only what is asked"): run with
/// `cargo test -p tests only_outputs::step_cost -- --ignored --nocapture` (the solvers are built
/// by the cache in its release profile whatever the test profile).
#[test]
#[ignore = "a measurement: it prints the costs"]
fn step_cost_with_and_without_pruning() {
    let text = codegen::scale::arms(10, 6, 200);
    let tool = "[[points]]\nname = \"tool\"\nbody = \"arm3_link6\"\nlocal = [0.25, 0.0, 0.0]\n";
    let mech = load_toml(&format!("{text}\n{tool}"));
    let sys = Symbolic::build(&mech).expect("the system builds");
    let part = only(&mech, &sys, &["tool".to_owned()]).expect("the point exists");
    for (label, m) in [("whole (10 arms)", &mech), ("pruned (1 arm)", &part)] {
        let built = build_generated(m);
        let (min, median, iterations) =
            codegen::engine::bench(&built, 1e-10, 20).expect("the timed passes run");
        println!(
            "{label}: {} unknowns, {min:.0} / {median:.0} ns per step (min / median), \
             {iterations:.2} iterations",
            built.unknowns
        );
        assert!(min > 0.0);
    }
}
