//! The generated block-by-block LU (`codegen::blocks`, `runtime::blocks`), chosen for systems
//! of 64 unknowns or more with more than one block, against the generic engine on a driven
//! chain, independent spatial arms and independent R-S-S-R loops; and Newton block by block
//! with the closed-form orientation blocks (`codegen::blocks::Rotation`) on chains turning
//! whole turns and on the R-S-S-R over whole revolutions.

use std::fmt::Write;

use codegen::emit::Scalar;
use codegen::testing::{
    load_toml, relative_differences, run_generated, run_generated_with, run_generic,
};

/// Generated and generic runs agree to this fraction of each quantity's scale: with Newton
/// asked for max |Φ| ≤ 1e-12 (below), where each engine stops accounts for 1e-12 times the
/// conditioning, and the accelerations of a chain's last links sum the errors of every link
/// before them; 1e-10 leaves a factor of 100 (as `random_mechanisms`).
const AGREEMENT: f64 = 1e-10;

/// One Newton iteration over the whole system, Φ_q factored block by block.
fn check(text: &str) {
    check_with(text, false);
}

/// [`check`], with Newton block by block as the generator plans when `block_newton`, else one
/// Newton iteration over the whole system factored block by block.
fn check_with(text: &str, block_newton: bool) {
    let mech = load_toml(&format!("{text}\n[solver]\ntolerance = 1e-12\n"));
    let sys = codegen::symbolic::Symbolic::build_full(&mech).expect("the system builds");
    let module = if block_newton {
        codegen::emit::module(&mech, &sys, "block_solver")
    } else {
        codegen::emit::module_with_whole_newton(&mech, &sys, "block_solver", Scalar::F64)
    };
    assert!(
        module.contains("static BLOCKS: runtime::blocks::Layout"),
        "{}: factored by blocks",
        mech.name
    );
    assert!(!module.contains("fn factor_0"), "{}: no static orders", mech.name);
    assert_eq!(
        module.contains("const BLOCK_NEWTON: bool = true;"),
        block_newton,
        "{}: Newton block by block as planned",
        mech.name
    );
    // Newton block by block keeps Φ_q's blocks packed at the front of the storage
    // (`runtime::blocks`, "Packed storage"); one iteration over the whole system keeps it dense.
    assert_eq!(
        module.contains("const PACKED_BLOCKS: Option<&'static [usize]> = Some(&PACKED_BLOCKS);"),
        block_newton,
        "{}: packed storage with Newton block by block",
        mech.name
    );
    agrees_with_generic(&mech, &sys, &module);
}

/// Builds `module` of `mech` and asserts that its run agrees with the generic engine's to
/// [`AGREEMENT`], every frame; the generic run, for further checks.
pub(crate) fn agrees_with_generic(
    mech: &codegen::model::Mechanism,
    sys: &codegen::symbolic::Symbolic,
    module: &str,
) -> codegen::testing::Run {
    let generic = run_generic(mech);
    assert!(generic.failure.is_none(), "{}: {:?}", mech.name, generic.failure);
    let built = codegen::engine::build_module(mech, module, sys, Scalar::F64).expect("builds");
    let generated = run_generated(mech, &built);
    assert!(generated.failure.is_none(), "{}: {:?}", mech.name, generated.failure);
    assert_eq!(generic.frames.len(), generated.frames.len(), "{}: every frame", mech.name);
    for (diff, at) in relative_differences(&generic.frames, &generated.frames) {
        assert!(diff <= AGREEMENT, "{}: {at}", mech.name);
    }
    generic
}

/// Newton block by block on `text` (tolerance 1e-12) with `rotations` orientation blocks in
/// closed form, against the generic engine; the generic run, for further checks.
fn check_closed_form(text: &str, rotations: usize) -> codegen::testing::Run {
    let mech = load_toml(&format!("{text}\n[solver]\ntolerance = 1e-12\n"));
    let sys = codegen::symbolic::Symbolic::build_full(&mech).expect("the system builds");
    let module = codegen::emit::module_with_block_newton(&mech, &sys, "closed_form", Scalar::F64);
    assert!(module.contains("const BLOCK_NEWTON: bool = true;"), "{}", mech.name);
    assert_eq!(
        module.matches("runtime::blocks::Solve::Explicit").count(),
        rotations,
        "{}: the orientation blocks in closed form",
        mech.name
    );
    agrees_with_generic(&mech, &sys, &module)
}

/// A spatial chain of `n` links, all starting at the identity orientation, link k joined to
/// the one before by a revolute about its own oblique axis a_k (the same vector in both
/// bodies, so every joint angle starts at 0), with references at various angles about it;
/// every other joint has its axis_j reversed (the parallel rows hold it antiparallel, the sign
/// σ = −1 of the closed form) and every third names the new link as body_i (the known body
/// as body_j). Joint k turns at 1 + (k − 1)/2 turns per second over one second: link 1 makes
/// exactly one turn, so its Euler parameters end at −(1, 0, 0, 0).
fn turning_chain(n: usize, steps: usize) -> String {
    let mut s = format!(
        "name = \"turning_chain\"\n\n[time]\nstart = 0.0\nend = 1.0\nsteps = {steps}\n\n\
         [[bodies]]\nname = \"ground\"\nground = true\n\n"
    );
    let unit = |v: [f64; 3]| {
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|x| x / n)
    };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    };
    for k in 1..=n {
        let x = 0.5 * (k as f64 - 1.0) + 0.25;
        let _ = write!(s, "[[bodies]]\nname = \"link{k}\"\nr = [{x:?}, 0.0, 0.0]\n\n");
    }
    for k in 1..=n {
        let kf = k as f64;
        let axis = unit([kf.cos(), kf.sin(), 0.4 + 0.3 * kf]);
        let reference = unit(cross(axis, unit([0.3, 1.0 - 0.2 * kf, 0.7])));
        let flipped = if k % 2 == 0 { axis.map(|v| -v) } else { axis };
        let prev = if k == 1 { "ground".to_owned() } else { format!("link{}", k - 1) };
        let prev_point = if k == 1 { [0.0, 0.0, 0.0] } else { [0.25, 0.0, 0.0] };
        let link = format!("link{k}");
        let link_point = [-0.25, 0.0, 0.0];
        let ((bi, pi, ai), (bj, pj, aj)) = if k % 3 == 0 {
            ((link, link_point, flipped), (prev, prev_point, axis))
        } else {
            ((prev, prev_point, axis), (link, link_point, flipped))
        };
        let _ = write!(
            s,
            "[[joints]]\nname = \"hinge{k}\"\ntype = \"revolute\"\nbody_i = \"{bi}\"\n\
             body_j = \"{bj}\"\npoint_i = {pi:?}\npoint_j = {pj:?}\naxis_i = {ai:?}\n\
             axis_j = {aj:?}\nref_i = {reference:?}\nref_j = {reference:?}\n\n\
             [[drivers]]\nname = \"motor{k}\"\njoint = \"hinge{k}\"\nmotion = \"rotation\"\n\
             law = {{ start = 0.0, velocity = {:?} }}\n\n",
            2.0 * std::f64::consts::PI * (1.0 + (kf - 1.0) / 2.0)
        );
    }
    s
}

#[test]
fn a_chain_turning_whole_turns_on_closed_form_orientations_matches_the_generic_engine() {
    let generic = check_closed_form(&turning_chain(6, 400), 6);
    // Link 1 turned exactly once about its joint: its Euler parameters went once round their
    // sign (both engines follow them continuously; the comparison above holds them together).
    let last = generic.frames.last().expect("frames");
    let e: Vec<f64> = (3..7).map(|c| last.q[c]).collect();
    for (c, (v, want)) in e.iter().zip([-1.0, 0.0, 0.0, 0.0]).enumerate() {
        // Newton's tolerance 1e-12 on rows of unit size, and the 400 steps' round-off.
        assert!((v - want).abs() < 1e-9, "link1.e{c} = {v}, expected {want}");
    }
}

#[test]
fn the_driven_chain_on_closed_form_orientations_matches_the_generic_engine() {
    check_closed_form(&codegen::scale::chain(10, 20), 10);
}

#[test]
fn independent_arms_on_closed_form_orientations_match_the_generic_engine() {
    check_closed_form(&codegen::scale::arms(3, 4, 20), 12);
}

#[test]
fn the_rssr_on_a_closed_form_crank_matches_the_generic_engine_over_whole_revolutions() {
    // The crank turns at 146.6 rad/s: one revolution in 200 steps (1.8° each) from several
    // crank angles. The loop closes two ways at every crank angle, so each run starts from the
    // configuration the generic engine reaches by turning the crank there from the example's
    // estimates (at 0), written back as the estimates.
    let text = std::fs::read_to_string(codegen::testing::example("rssr.toml")).expect("example");
    let mut desc: codegen::desc::MechanismDesc = toml::from_str(&text).expect("the example");
    let period = 2.0 * std::f64::consts::PI / 146.6;
    let grid =
        |start: f64, end: f64| codegen::desc::TimeDesc { start, end, step: None, steps: Some(200) };
    for start in [0.0, 1.0, 2.5, 4.0] {
        let t0 = start / 146.6;
        if t0 > 0.0 {
            desc.time = grid(0.0, t0);
            let walk = run_generic(&load_toml(&toml::to_string(&desc).expect("TOML")));
            let q = &walk.frames.last().expect("the walk's frames").q;
            for (k, body) in desc.bodies.iter_mut().filter(|b| !b.ground).enumerate() {
                body.r = Some([q[7 * k], q[7 * k + 1], q[7 * k + 2]]);
                body.p = Some([q[7 * k + 3], q[7 * k + 4], q[7 * k + 5], q[7 * k + 6]]);
            }
        }
        desc.time = grid(t0, t0 + period);
        check_closed_form(&toml::to_string(&desc).expect("TOML"), 1);
    }
}

#[test]
fn a_driven_chain_of_ten_links_solved_block_by_block_matches_the_generic_engine() {
    check(&codegen::scale::chain(10, 20));
}

#[test]
fn independent_arms_solved_block_by_block_match_the_generic_engine() {
    check(&codegen::scale::arms(3, 4, 20));
}

#[test]
fn independent_rssr_loops_solved_block_by_block_match_the_generic_engine() {
    check(&codegen::scale::rssr_loops(4, 20));
}

#[test]
fn independent_rssr_loops_solved_by_newton_block_by_block_match_the_generic_engine() {
    check_with(&codegen::scale::rssr_loops(4, 20), true);
}

/// Two 6R arms (84 unknowns, the arms of `benches/scale/arms_10x6.toml`) through packed
/// storage, as the generator plans them (Newton block by block), against the generic engine to
/// [`AGREEMENT`]: the packing moves where the entries of Φ_q are kept, not what is computed,
/// so the bound of the dense storage holds. The loops are
/// `independent_rssr_loops_solved_by_newton_block_by_block_match_the_generic_engine`.
#[test]
fn six_revolute_arms_through_packed_storage_match_the_generic_engine() {
    check_with(&codegen::scale::arms(2, 6, 20), true);
}

/// A module factored block by block keeps Φ_q in [`runtime::blocks::packed_len`] entries at the
/// front of the solver's `N × N` storage (`runtime::Mechanism::PACKED_BLOCKS`): stepping the
/// committed whole Stewart module (`generated::stewart_whole`, 91 unknowns, Newton block by block) along its shipped trajectory
/// leaves every other entry of a storage filled with NaN as it was, while the solutions satisfy
/// Φ = 0 and Φ_q q̇ = ν with Φ_q evaluated in full apart from the solver. Fails when a
/// block-factored module goes back to touching N rows of N (the memory traffic that made ten
/// arms cost 13× one arm, BENCHMARKS.md "Block-only Jacobian storage").
#[test]
fn a_block_factored_module_touches_only_its_packed_blocks() {
    use examples::stewart::{Trajectory, leg_lengths};
    use generated::stewart_whole::{self as gs, StewartWhole as Stewart};
    use runtime::input::Driven;
    use runtime::{Mechanism, NewtonOptions, Solver};
    const N: usize = gs::N;

    let layout = <Stewart as Mechanism<N>>::BLOCKS.expect("factored by blocks");
    let starts = <Stewart as Mechanism<N>>::PACKED_BLOCKS.expect("packed");
    let packed = runtime::blocks::packed_len(layout);
    // The module's block starts are those of the runtime's packed order.
    assert_eq!(starts.len(), layout.starts.len());
    for b in 0..starts.len() - 1 {
        assert_eq!(starts[b + 1] - starts[b], runtime::blocks::packed_block_len(layout, b));
    }
    assert_eq!(starts[starts.len() - 1], packed);
    // 91 unknowns in blocks of at most 7: the packed form is a small part of N × N.
    assert!(10 * packed < N * N, "{packed} entries packed of {}", N * N);

    let mut storage = Box::new([[f64::NAN; N]; N]);
    let legs = |t: f64| leg_lengths(&Trajectory::SHIPPED.at(t));
    let mut solver = Solver::with_storage(
        Stewart::new(0.0, &gs::Inputs::from_array(legs(0.0))),
        gs::Q0,
        &mut *storage,
    );
    solver.set_options(NewtonOptions { tolerance: gs::TOLERANCE, ..NewtonOptions::DEFAULT });
    solver.set_predictor(true);
    let (mut phi, mut nu, mut jac) = ([0.0; N], [0.0; N], Box::new([[0.0; N]; N]));
    for k in 0..gs::T_COUNT {
        let t = gs::T_START + k as f64 * gs::T_STEP;
        solver.mechanism_mut().segment_mut().aim(t, legs(t));
        solver.position(t).expect("the platform follows");
        solver.velocity().expect("Φ_q is regular");
        solver.acceleration().expect("q̇ is known");
        solver.mechanism_mut().segment_mut().settle(t);
        let (m, q, qd) = (solver.mechanism(), solver.q(), solver.qd());
        m.residual(q, t, &mut phi);
        m.jacobian(q, t, &mut jac);
        m.velocity_rhs(q, t, &mut nu);
        // Newton stops at max |Φ| ≤ 1e-12 (the module's tolerance); Φ_q q̇ − ν sums products of
        // entries of order 1 (lengths in m, rates below 1 m/s) with round-off of 1e-16 each,
        // so 1e-10 leaves a factor of 100 over the 91 terms of a row.
        assert!(phi.iter().all(|v| v.abs() <= 1e-12), "t = {t}: Φ");
        for i in 0..N {
            let rate: f64 = (0..N).map(|j| jac[i][j] * qd[j]).sum();
            assert!((rate - nu[i]).abs() <= 1e-10, "t = {t}: row {i} of Φ_q q̇ = ν");
        }
    }
    let flat = storage.as_flattened();
    assert!(flat[..packed].iter().all(|v| v.is_finite()), "the packed blocks hold Φ_q's factors");
    let touched = flat[packed..].iter().filter(|v| !v.is_nan()).count();
    assert_eq!(touched, 0, "entries written past the {packed} packed ones");
}

#[test]
fn systems_below_64_unknowns_keep_the_static_orders() {
    // One R-S-S-R has 20 unknowns and a chain of nine links 63, below
    // `emit::blocks::MIN_UNKNOWNS`.
    for text in [codegen::scale::rssr_loops(1, 20), codegen::scale::chain(9, 20)] {
        let mech = load_toml(&text);
        let sys = codegen::symbolic::Symbolic::build_full(&mech).expect("the system builds");
        let module = codegen::emit::module(&mech, &sys, "block_solver");
        assert!(!module.contains("static BLOCKS"), "{}: no blocks", mech.name);
        assert!(module.contains("fn factor_0"), "{}: static orders", mech.name);
    }
}

/// The lines of `module` that assign an entry of Φ_q (`jac[r][c] = …`), other than the
/// structural zeros of a diagonal block (`= 0.0`) and the factors scattered back (`= a[i][j]`).
fn jacobian_assignments(module: &str) -> usize {
    module
        .lines()
        .map(str::trim_start)
        .filter(|l| {
            l.strip_prefix("jac[").is_some_and(|rest| {
                rest.split_once(" =").is_some_and(|(at, value)| {
                    let value = value.trim_start();
                    at.ends_with(']') && value != "0.0;" && !value.starts_with("a[")
                })
            })
        })
        .count()
}

#[test]
fn a_module_solved_block_by_block_emits_each_jacobian_entry_once() {
    // `jacobian` and `residual_jacobian` call the blocks' `block_b` functions (emit::from_blocks)
    // instead of repeating every entry's code: a Jacobian emitted three times costed the chain
    // of 100 links a third of its build time (BENCHMARKS.md, "Explicit velocities of
    // closed-form blocks").
    for text in [codegen::scale::chain(10, 20), turning_chain(6, 20)] {
        let mech = load_toml(&text);
        let sys = codegen::symbolic::Symbolic::build_full(&mech).expect("the system builds");
        let module = codegen::emit::module_with_block_newton(&mech, &sys, "once", Scalar::F64);
        // Blocks of one structure share one function (emit::shared), so an entry's code is
        // written once for all the blocks that share it: at most once per entry.
        let nnz: usize = sys.jac.iter().map(Vec::len).sum();
        let assignments = jacobian_assignments(&module);
        assert!(0 < assignments && assignments <= nnz, "{}: each entry once", mech.name);
        let body = module.split("pub fn residual_jacobian(").nth(1).expect("residual_jacobian");
        let body = &body[..body.find("\n}\n").expect("its end")];
        assert_eq!(jacobian_assignments(body), 0, "{}: {body}", mech.name);
        assert!(body.contains("block_0(q, t, phi, jac);"), "{}: {body}", mech.name);
    }
}

#[test]
fn the_jacobian_gathered_from_the_blocks_drives_dense_lu_as_the_generic_engine() {
    // The driver's `dense` mode factors `residual_jacobian` (the blocks' functions called in
    // turn) by dense LU with partial pivoting instead of block by block: the whole Φ_q they
    // write must be the generic engine's, oblique, reversed and swapped axes included.
    let mech = load_toml(&format!("{}\n[solver]\ntolerance = 1e-12\n", turning_chain(6, 100)));
    let sys = codegen::symbolic::Symbolic::build_full(&mech).expect("the system builds");
    let module = codegen::emit::module_with_block_newton(&mech, &sys, "dense", Scalar::F64);
    let built = codegen::engine::build_module(&mech, &module, &sys, Scalar::F64).expect("builds");
    let generic = run_generic(&mech);
    assert!(generic.failure.is_none(), "{:?}", generic.failure);
    let settings = codegen::engine::Settings { predictor: true, dense_lu: true };
    let report = run_generated_with(&mech, &built, None, settings);
    assert!(report.failure.is_none(), "{:?}", report.failure);
    let frames = report.frames;
    assert_eq!(generic.frames.len(), frames.len(), "every frame");
    for (diff, at) in relative_differences(&generic.frames, &frames) {
        assert!(diff <= AGREEMENT, "{at}");
    }
}

#[test]
fn a_single_precision_module_solved_block_by_block_follows_the_generic_engine() {
    // The f32 rewrite of a module solved block by block (the rotation blocks' closed forms,
    // the blocks' functions and the Jacobian gathered from them), run both block by block and
    // by dense LU on that Jacobian, against the double-precision generic engine.
    let mech = load_toml(&turning_chain(6, 100));
    let sys = codegen::symbolic::Symbolic::build_full(&mech).expect("the system builds");
    let module = codegen::emit::module_with_block_newton(&mech, &sys, "f32", Scalar::F32);
    assert!(module.contains("const BLOCK_NEWTON: bool = true;"));
    let built = codegen::engine::build_module(&mech, &module, &sys, Scalar::F32).expect("builds");
    let generic = run_generic(&mech);
    assert!(generic.failure.is_none(), "{:?}", generic.failure);
    for dense_lu in [false, true] {
        let settings = codegen::engine::Settings { predictor: true, dense_lu };
        // 1e-4: the f32 default Newton tolerance (runtime::Real::DEFAULT_TOLERANCE).
        let report = run_generated_with(&mech, &built, Some(1e-4), settings);
        assert!(report.failure.is_none(), "dense {dense_lu}: {:?}", report.failure);
        let frames = report.frames;
        assert_eq!(generic.frames.len(), frames.len(), "every frame");
        for (a, b) in generic.frames.iter().zip(&frames) {
            // The f32 grid times are the f64 ones rounded to f32: within 1 ulp of t ≤ 1 s.
            assert!((a.t - b.t).abs() <= 4.0 * f64::from(f32::EPSILON), "t {} vs {}", a.t, b.t);
        }
        let scale = |get: fn(&codegen::generic::Frame) -> &nalgebra::DVector<f64>| {
            let s = generic.frames.iter().map(|f| get(f).amax()).fold(1.0, f64::max);
            let d = generic.frames.iter().zip(&frames).map(|(a, b)| (get(a) - get(b)).amax());
            d.fold(0.0, f64::max) / s
        };
        let [q, qd, qdd] = [scale(|f| &f.q), scale(|f| &f.qd), scale(|f| &f.qdd)];
        println!("f32 turning chain, dense {dense_lu}: q {q:e}, qd {qd:e}, qdd {qdd:e}");
        // f32 round-off is 6e-8 and six links in series sum their errors: observed 7e-7 (q),
        // 2.5e-6 (q̇) and 3.2e-6 (q̈) relative, both ways. The bounds are about 20× those, so a
        // quantity left in f64 and rounded twice, or a wrong entry, shows.
        assert!(q <= 2e-5 && qd <= 5e-5 && qdd <= 1e-4, "q {q:e}, qd {qd:e}, qdd {qdd:e}");
    }
}

/// `count` independent arms of `links` revolute-driven links, every arm of its own geometry:
/// link k of arm a is `0.4 + 0.05 a + 0.03 k` long and turns about its own oblique axis (no
/// component 0 or ±1, so every copy keeps the same expression structure) at its own speed.
/// The arms have one structure and differ in every constant, not just by a translation, so a
/// shared block function that read another block's constants would move the wrong arm.
fn distinct_arms(count: usize, links: usize, steps: usize) -> String {
    let mut s = format!(
        "name = \"distinct_arms\"\n\n[time]\nstart = 0.0\nend = 0.5\nsteps = {steps}\n\n\
         [[bodies]]\nname = \"ground\"\nground = true\n\n"
    );
    let unit = |v: [f64; 3]| {
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|x| x / n)
    };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    };
    let length = |a: usize, k: usize| 0.4 + 0.05 * a as f64 + 0.03 * k as f64;
    for a in 1..=count {
        let mut x = 0.0;
        for k in 1..=links {
            let l = length(a, k);
            let _ = write!(
                s,
                "[[bodies]]\nname = \"arm{a}_link{k}\"\nr = [{:?}, {:?}, 0.0]\n\n",
                x + 0.5 * l,
                a as f64 - 1.0
            );
            x += l;
        }
    }
    for a in 1..=count {
        for k in 1..=links {
            let (af, kf) = (a as f64, k as f64);
            let l = length(a, k);
            let axis =
                unit([(0.7 * af + kf).cos(), (0.7 * af + kf).sin(), 0.4 + 0.1 * af + 0.2 * kf]);
            let reference = unit(cross(axis, unit([0.3, 1.1 - 0.1 * kf, 0.7 + 0.05 * af])));
            let (prev, point_i) = if k == 1 {
                ("ground".to_owned(), [0.0, af - 1.0, 0.0])
            } else {
                (format!("arm{a}_link{}", k - 1), [0.5 * length(a, k - 1), 0.0, 0.0])
            };
            let _ = write!(
                s,
                "[[joints]]\nname = \"arm{a}_joint{k}\"\ntype = \"revolute\"\nbody_i = \"{prev}\"\n\
                 body_j = \"arm{a}_link{k}\"\npoint_i = {point_i:?}\npoint_j = {:?}\n\
                 axis_i = {axis:?}\naxis_j = {axis:?}\nref_i = {reference:?}\nref_j = {reference:?}\n\n\
                 [[drivers]]\nname = \"arm{a}_motor{k}\"\njoint = \"arm{a}_joint{k}\"\n\
                 motion = \"rotation\"\nlaw = {{ start = 0.0, velocity = {:?} }}\n\n",
                [-0.5 * l, 0.0, 0.0],
                0.8 + 0.3 * af + 0.2 * kf
            );
        }
    }
    s
}

/// The names of the block functions a module defines (`fn block_3(`, `fn rotation_shared_0(`,
/// `fn factor_block_1(` …): the per-block and per-structure functions of Newton block by
/// block, and the per-structure parts of `factor_blocks` and `solve_blocks` (whose numbered
/// parts run every block in turn, and so grow with the system).
fn block_functions(module: &str) -> Vec<String> {
    let numbered = |rest: &str| !rest.is_empty() && rest.chars().all(|c| c.is_ascii_digit());
    let per_block = ["block_", "block_residual_", "rotation_", "factor_block_", "solve_block_"];
    let mut names: Vec<String> = module
        .lines()
        .filter_map(|l| l.trim_start().strip_prefix("fn "))
        .map(|l| l[..l.find('(').unwrap_or(l.len())].to_owned())
        .filter(|name| {
            let shared = ["factor_blocks_", "solve_blocks_"].iter().chain(&per_block).any(|k| {
                name.strip_prefix(k)
                    .and_then(|rest| rest.strip_prefix("shared_"))
                    .is_some_and(numbered)
            });
            shared || per_block.iter().any(|k| name.strip_prefix(k).is_some_and(numbered))
        })
        .collect();
    names.sort();
    names
}

#[test]
fn copies_of_one_structure_run_one_function_per_structure() {
    // Four R-S-S-R loops and thirty-four emit the same functions: every block function is one
    // per structure, its blocks' constants and places in tables (emit::shared).
    let functions = |text: &str| {
        let mech = load_toml(text);
        let sys = codegen::symbolic::Symbolic::build_full(&mech).expect("the system builds");
        let module = codegen::emit::module_with_block_newton(&mech, &sys, "shared", Scalar::F64);
        (block_functions(&module), module)
    };
    let (four, _) = functions(&codegen::scale::rssr_loops(4, 20));
    let (many, module) = functions(&codegen::scale::rssr_loops(34, 20));
    assert_eq!(four.len(), many.len(), "{four:?}\n{many:?}");
    assert!(many.iter().any(|f| f.starts_with("block_shared_")), "{many:?}");
    assert!(many.iter().any(|f| f.starts_with("factor_block_shared_")), "{many:?}");
    // The 34 copies of a loop's residual function are one: its table has 34 rows.
    assert!(module.contains("static BLOCK_RESIDUAL_SHARED_0_AT: [[usize; "), "tables");
    // Arms of distinct geometry share as well. Not all of it: the first link's blocks are
    // relative to ground, whose terms fold to constants, and round-off makes some of them
    // exactly 0 or ±1 in one arm and not in another, which folds them into different code;
    // the links after it share. Without sharing, four arms had four times the functions.
    let (one, _) = functions(&distinct_arms(1, 6, 20));
    let (arms, module) = functions(&distinct_arms(4, 6, 20));
    assert!(2 * arms.len() < 3 * one.len(), "{one:?}\n{arms:?}");
    assert!(module.contains("static BLOCK_SHARED_0_C: [[f64; "), "a table of constants");
}

#[test]
fn arms_of_distinct_geometry_through_shared_functions_match_the_generic_engine() {
    // Every constant of the shared functions differs from arm to arm (lengths, oblique axes,
    // speeds): a wrong row of a table moves the wrong arm far beyond AGREEMENT.
    let mech = load_toml(&format!("{}\n[solver]\ntolerance = 1e-12\n", distinct_arms(4, 6, 50)));
    let sys = codegen::symbolic::Symbolic::build_full(&mech).expect("the system builds");
    let module = codegen::emit::module(&mech, &sys, "distinct_arms");
    assert!(module.contains("const BLOCK_NEWTON: bool = true;"), "Newton block by block");
    assert!(module.contains("fn block_shared_0("), "shared block functions");
    assert!(module.contains("fn factor_blocks_shared_0("), "shared block factors");
    agrees_with_generic(&mech, &sys, &module);
}
