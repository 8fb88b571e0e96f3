//! Closed-form blocks substituted at generation time (`codegen::symbolic::substitute`): the
//! R-S-S-R's generated system keeps 5 of the 7 unknowns of its S-S loop, and its 15 substituted
//! coordinates (the crank's position and Euler parameters, the coupler's and the rocker's
//! positions, the rocker's e2 and e3, zero as it turns about x) must move as the mechanism does: their rates and accelerations against central
//! differences of their positions along the motion, and the whole solution against the generic
//! engine over full revolutions from other starting angles.

use codegen::generic::Equations;
use codegen::symbolic::Symbolic;
use codegen::testing::{
    build_generated, load_toml, relative_differences, run_generated, run_generic,
};

/// `benches/rssr_revolution.toml`: one crank revolution in 1000 steps at tolerance 1e-12.
fn revolution() -> String {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../benches/rssr_revolution.toml");
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {path}: {e}"))
}

/// The revolution with the crank's law starting at `angle` and turning at `velocity` rad/s.
fn revolution_from(angle: f64, velocity: f64) -> String {
    let law = "law = { start = 0.0, velocity = 146.6, acceleration = 0.0 }";
    let text = revolution();
    assert!(text.contains(law), "the benchmark's crank law");
    text.replace(law, &format!("law = {{ start = {angle:?}, velocity = {velocity:?} }}"))
}

#[test]
fn the_rssr_solves_five_unknowns_and_its_substituted_coordinates_move_as_their_positions() {
    let mech = load_toml(&revolution());
    let sys = Symbolic::build(&mech).expect("the system builds");
    let names: Vec<String> = sys
        .unknowns
        .iter()
        .map(|&(b, c)| {
            format!("{}.{}", mech.bodies[b.0].name, ["x", "y", "z", "e0", "e1", "e2", "e3"][c])
        })
        .collect();
    assert_eq!(names, ["coupler.e0", "coupler.e1", "coupler.e3", "rocker.e0", "rocker.e1"]);
    // The crank's 7 coordinates, the coupler's and the rocker's positions, the rocker's e2, e3.
    assert_eq!(sys.derived.len(), 15);
    let built = build_generated(&mech);
    let run = run_generated(&mech, &built);
    assert!(run.failure.is_none(), "{:?}", run.failure);
    let f = &run.frames;
    assert_eq!(f.len(), 1001);
    // Every row holds at the expanded coordinates, the substituted rows included.
    let eq = Equations::new(&mech);
    for frame in f {
        let phi = eq.evaluate(&frame.q, &frame.qd, frame.t).phi.amax();
        // Newton's tolerance 1e-12 on the loop's rows; the substituted ones hold to round-off.
        assert!(phi <= 1e-12, "t = {}: max |Φ| = {phi:e}", frame.t);
    }
    // Central differences over h = 4.3e-5 s of a crank turning at ω = 146.6 rad/s, on
    // coordinates of at most 0.5 (positions in m, Euler parameters): the truncation errors
    // h² ω³/6 · 0.5 ≈ 2.5e-5 of the rate (scale 0.5 ω ≈ 73) and h² ω⁴/12 · 0.5 ≈ 7e-2 of the
    // acceleration (scale 0.5 ω² ≈ 1.1e4), and round-off of 1e-12/h² ≈ 5e-4 in the second
    // difference: 1e-5 and 1e-4 of those scales hold them with margin, while a wrong term in a
    // rate or an acceleration is of the order of the scale.
    let h = mech.time.step;
    let (rate_scale, acceleration_scale) = (0.5 * 146.6, 0.5 * 146.6 * 146.6);
    let mut checked = 0;
    for d in &sys.derived {
        let k = eq.offset(d.body).expect("a moving body") + d.coordinate;
        for i in 1..f.len() - 1 {
            let rate = (f[i + 1].q[k] - f[i - 1].q[k]) / (2.0 * h);
            let acceleration = (f[i + 1].q[k] - 2.0 * f[i].q[k] + f[i - 1].q[k]) / (h * h);
            let context = format!(
                "{} coordinate {} at t = {}",
                mech.bodies[d.body.0].name, d.coordinate, f[i].t
            );
            assert!(
                (rate - f[i].qd[k]).abs() <= 1e-5 * rate_scale,
                "{context}: {rate} against {}",
                f[i].qd[k]
            );
            assert!(
                (acceleration - f[i].qdd[k]).abs() <= 1e-4 * acceleration_scale,
                "{context}: {acceleration} against {}",
                f[i].qdd[k]
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 15 * 999);
}

#[test]
fn full_revolutions_from_other_starting_angles_match_the_generic_engine() {
    // Starting angles on both sides of a half and a whole turn, one turning backwards: the
    // crank's closed form takes its sign σ from the assembled configuration (beyond a whole turn
    // the estimates' e0 > 0 assemble the crank as −(cos s/2, 0, sin s/2, 0)) and follows e
    // through its sign change over every turn as the generic engine's Newton does. Near half a
    // turn (3.0 rad) the estimates, made for the crank at 0, do not assemble (the generic
    // engine stops there at once) and the generator's own assembly leaves the crank off the
    // family of orientations its rotation block was recognised on: the closed form is declined
    // and two of the crank's Euler parameters stay unknowns (e0 and e2; e1 and e3 vanish as it
    // turns about y): 7 of them.
    let cases = [
        (1.0, 146.6, 5),
        (2.0, 146.6, 5),
        (3.0, 146.6, 7),
        (4.5, 146.6, 5),
        (7.0, 146.6, 5),
        (-2.0, -146.6, 5),
    ];
    for (angle, velocity, unknowns) in cases {
        let mech = load_toml(&revolution_from(angle, velocity));
        let sys = Symbolic::build(&mech).expect("the system builds");
        assert_eq!(sys.unknowns.len(), unknowns, "start {angle}");
        let generic = run_generic(&mech);
        if unknowns == 7 {
            let failure = generic.failure.expect("the estimates do not assemble");
            assert_eq!(failure.t, mech.time.start);
            continue;
        }
        assert!(generic.failure.is_none(), "start {angle}: generic: {:?}", generic.failure);
        let built = build_generated(&mech);
        let generated = run_generated(&mech, &built);
        assert!(generated.failure.is_none(), "start {angle}: generated: {:?}", generated.failure);
        // Both converge to 1e-12 on the same branch; their differences are that tolerance
        // amplified by the loop's conditioning, far below 1e-10 of each quantity's scale.
        for (rel, place) in relative_differences(&generic.frames, &generated.frames) {
            assert!(rel <= 1e-10, "start {angle}, velocity {velocity}: {place}");
        }
    }
}

#[test]
fn ten_driven_arms_are_wholly_explicit_and_their_coordinates_move_as_their_positions() {
    // Ten 6R arms, 70 bodies' worth of unknowns beyond the block-by-block bound of 64: every
    // block is closed form, so nothing is left to Newton. 2000 steps over 0.02 s: h = 1e-5 s.
    let mech = load_toml(&codegen::scale::arms(10, 6, 2000));
    let sys = Symbolic::build(&mech).expect("the system builds");
    assert!(sys.unknowns.is_empty(), "{} unknowns left", sys.unknowns.len());
    assert_eq!(sys.derived.len(), 10 * 6 * 7);
    let built = build_generated(&mech);
    let run = run_generated(&mech, &built);
    assert!(run.failure.is_none(), "{:?}", run.failure);
    let f = &run.frames;
    assert_eq!(f.len(), 2001);
    // Every row holds at the expanded coordinates: the closed forms are exact.
    let eq = Equations::new(&mech);
    for frame in f {
        let phi = eq.evaluate(&frame.q, &frame.qd, frame.t).phi.amax();
        // Round-off of sums along an arm of coordinates of at most 3 (m).
        assert!(phi <= 1e-12, "t = {}: max |Φ| = {phi:e}", frame.t);
    }
    // The scales of the rates and accelerations over the run (joint laws 0.3 sin(ω t), ω ≤ 16
    // rad/s, arms 3 m long: about 10 m/s and 200 m/s²). Central differences over h = 1e-5 s:
    // truncation h² ω³/6 · 3 ≈ 2e-7 of a rate and h² ω⁴/12 · 3 ≈ 2e-6 of an acceleration, and
    // round-off of 3e-16 · 3/h² ≈ 1e-5 in the second difference; 1e-6 and 1e-6 of the scales
    // hold them with margin, while a wrong term is of the order of the scale.
    let rate_scale = f.iter().map(|fr| fr.qd.amax()).fold(0.0, f64::max);
    let acceleration_scale = f.iter().map(|fr| fr.qdd.amax()).fold(0.0, f64::max);
    assert!(rate_scale > 1.0 && acceleration_scale > 10.0, "{rate_scale} {acceleration_scale}");
    let h = mech.time.step;
    for k in 0..f[0].q.len() {
        for i in 1..f.len() - 1 {
            let rate = (f[i + 1].q[k] - f[i - 1].q[k]) / (2.0 * h);
            let acceleration = (f[i + 1].q[k] - 2.0 * f[i].q[k] + f[i - 1].q[k]) / (h * h);
            assert!(
                (rate - f[i].qd[k]).abs() <= 1e-6 * rate_scale,
                "coordinate {k} at t = {}: {rate} against {}",
                f[i].t,
                f[i].qd[k]
            );
            assert!(
                (acceleration - f[i].qdd[k]).abs() <= 1e-6 * acceleration_scale,
                "coordinate {k} at t = {}: {acceleration} against {}",
                f[i].t,
                f[i].qdd[k]
            );
        }
    }
}
