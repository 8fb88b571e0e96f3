//! The generated block-by-block LU (`codegen::blocks`, `runtime::blocks`), chosen for systems
//! of 64 unknowns or more with more than one block, against the generic engine on a driven
//! chain, independent spatial arms and independent R-S-S-R loops.

use codegen::emit::Scalar;
use codegen::testing::{
    build_generated, load_toml, relative_differences, run_generated, run_generic,
};

/// Generated and generic runs agree to this fraction of each quantity's scale: with Newton
/// asked for max |Φ| ≤ 1e-12 (below), where each engine stops accounts for 1e-12 times the
/// conditioning, and the accelerations of a chain's last links sum the errors of every link
/// before them; 1e-10 leaves a factor of 100 (as `random_mechanisms`).
const AGREEMENT: f64 = 1e-10;

fn check(text: &str) {
    check_with(text, false);
}

/// [`check`], with Newton block by block when `block_newton` (else as the generator plans).
fn check_with(text: &str, block_newton: bool) {
    let mech = load_toml(&format!("{text}\n[solver]\ntolerance = 1e-12\n"));
    let sys = codegen::symbolic::Symbolic::build(&mech).expect("the system builds");
    let module = if block_newton {
        codegen::emit::module_with_block_newton(&mech, &sys, "block_solver", Scalar::F64)
    } else {
        codegen::emit::module(&mech, &sys, "block_solver")
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
        "{}: Newton block by block only when asked (the chains here are short)",
        mech.name
    );
    let generic = run_generic(&mech);
    assert!(generic.failure.is_none(), "{}: {:?}", mech.name, generic.failure);
    let built = if block_newton {
        codegen::engine::build_module(&mech, &module, &sys, Scalar::F64).expect("it builds")
    } else {
        build_generated(&mech)
    };
    let generated = run_generated(&mech, &built);
    assert!(generated.failure.is_none(), "{}: {:?}", mech.name, generated.failure);
    for (diff, at) in relative_differences(&generic.frames, &generated.frames) {
        assert!(diff <= AGREEMENT, "{}: {at}", mech.name);
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
fn a_driven_chain_solved_by_newton_block_by_block_matches_the_generic_engine() {
    check_with(&codegen::scale::chain(10, 20), true);
}

#[test]
fn independent_arms_solved_by_newton_block_by_block_match_the_generic_engine() {
    check_with(&codegen::scale::arms(3, 4, 20), true);
}

#[test]
fn independent_rssr_loops_solved_by_newton_block_by_block_match_the_generic_engine() {
    check_with(&codegen::scale::rssr_loops(4, 20), true);
}

#[test]
fn systems_below_64_unknowns_keep_the_static_orders() {
    // One R-S-S-R has 20 unknowns and a chain of nine links 63, below
    // `emit::blocks::MIN_UNKNOWNS`.
    for text in [codegen::scale::rssr_loops(1, 20), codegen::scale::chain(9, 20)] {
        let mech = load_toml(&text);
        let sys = codegen::symbolic::Symbolic::build(&mech).expect("the system builds");
        let module = codegen::emit::module(&mech, &sys, "block_solver");
        assert!(!module.contains("static BLOCKS"), "{}: no blocks", mech.name);
        assert!(module.contains("fn factor_0"), "{}: static orders", mech.name);
    }
}
