//! Generated against generic on mechanisms of about 100 bodies (issue 16 point 6): a driven
//! chain of 100 links, a binary tree of 63 links and 34 independent R-S-S-R loops (102
//! bodies), each solved by the generator's own choice of solver (blocks, Newton block by
//! block or static orders) and by the generic engine's sparse LU.

use codegen::testing::{
    build_generated, load_toml, relative_differences, run_generated, run_generic,
};

/// Generated and generic runs agree to this fraction of each quantity's scale: both engines
/// stop Newton at max |Φ| ≤ 1e-12, so each is off the exact solution by 1e-12 times the
/// conditioning, and the accelerations of a chain's last link sum the errors of the hundred
/// links before it; 1e-10 leaves a factor of 100 (as `random_mechanisms`).
const AGREEMENT: f64 = 1e-10;

fn agree(text: &str) {
    let mech = load_toml(&format!("{text}\n[solver]\ntolerance = 1e-12\n"));
    let generic = run_generic(&mech);
    assert!(generic.failure.is_none(), "{}: generic {:?}", mech.name, generic.failure);
    let generated = run_generated(&mech, &build_generated(&mech));
    assert!(generated.failure.is_none(), "{}: generated {:?}", mech.name, generated.failure);
    assert_eq!(generic.frames.len(), generated.frames.len(), "{}: frames", mech.name);
    for (diff, at) in relative_differences(&generic.frames, &generated.frames) {
        assert!(diff <= AGREEMENT, "{}: {at}", mech.name);
    }
}

#[test]
fn a_driven_chain_of_100_links_matches_the_generic_engine() {
    // The benchmark's grid (benches/scale/chain_100.toml): 20 steps over 0.02 s, the last
    // link turning by up to 1.8 rad a step.
    agree(&codegen::scale::chain(100, 20));
}

#[test]
fn a_tree_of_63_links_matches_the_generic_engine() {
    agree(&codegen::scale::tree(63, 10));
}

#[test]
fn thirty_four_rssr_loops_match_the_generic_engine() {
    agree(&codegen::scale::rssr_loops(34, 10));
}
