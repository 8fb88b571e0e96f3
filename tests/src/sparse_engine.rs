//! The generic engine's sparse LU (`codegen::generic`, faer) against its dense LU on chains,
//! trees and multi-loop mechanisms of 20 to 100 bodies, and against the closed-form forward
//! kinematics of a driven spatial chain of 100 links.

use codegen::generic::{Analysis, Equations, Frame};
use codegen::model::Mechanism;
use codegen::validate::{Format, load_str};
use nalgebra::{DVector, Matrix3, Rotation3, Unit, Vector3};

/// How far the sparse and dense runs may differ, relative to each quantity's largest
/// magnitude over the run. Both factor the same balanced Φ_q (bit for bit) and Newton takes
/// the same iterations; only the elimination order differs, whose round-off (κ ε, κ ≤ 1e3 on
/// these mechanisms) reaches q, q̇ and q̈ through the last Newton update and the rate solves:
/// 1e-12 leaves a margin above that.
const AGREEMENT: f64 = 1e-12;

fn load(text: &str) -> Mechanism {
    load_str(text, Format::Toml, None).expect("valid description").mechanism
}

/// The frames of the generic analysis of `mech`, sparse or dense.
fn run(mech: &Mechanism, sparse: bool) -> Vec<Frame> {
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    let analysis = Analysis::new(&eq, &prep).with_sparse(sparse);
    assert_eq!(analysis.is_sparse(), sparse, "{}: the factorisation asked for", mech.name);
    let mut frames = Vec::new();
    let report = analysis
        .run(|f| {
            frames.push(f.clone());
            Ok::<_, ()>(())
        })
        .expect("the sink never fails");
    assert!(report.failure.is_none(), "{}: {:?}", mech.name, report.failure);
    frames
}

/// The largest difference between the two runs' q, q̇ and q̈, each relative to the largest
/// magnitude of that quantity over the dense run, and the ratio range of their κ̂.
fn compare(mech: &Mechanism) -> ([f64; 3], (f64, f64)) {
    let (sparse, dense) = (run(mech, true), run(mech, false));
    assert_eq!(sparse.len(), dense.len(), "{}: frames", mech.name);
    let pick: [fn(&Frame) -> &DVector<f64>; 3] = [|f| &f.q, |f| &f.qd, |f| &f.qdd];
    let mut worst = [0.0; 3];
    for (k, get) in pick.iter().enumerate() {
        let scale = dense.iter().map(|f| get(f).amax()).fold(0.0, f64::max);
        let diff =
            sparse.iter().zip(&dense).map(|(s, d)| (get(s) - get(d)).amax()).fold(0.0, f64::max);
        worst[k] = diff / scale;
    }
    let ratios = sparse.iter().zip(&dense).map(|(s, d)| s.condition / d.condition);
    let range = ratios.fold((f64::INFINITY, 0.0_f64), |(lo, hi), r| (lo.min(r), hi.max(r)));
    (worst, range)
}

#[test]
fn sparse_and_dense_agree_on_chains_trees_and_loops() {
    // Few steps keep the dense runs (714 unknowns at most) within a few seconds; the chain of
    // 100 links runs sparse only, against its closed form (below).
    let cases = [
        codegen::scale::chain(20, 4),
        codegen::scale::chain(50, 3),
        codegen::scale::arms(4, 6, 4),
        codegen::scale::tree(63, 4),
        codegen::scale::rssr_loops(7, 4),
        codegen::scale::rssr_loops(34, 3),
    ];
    for text in cases {
        let mech = load(&text);
        let start = std::time::Instant::now();
        let eq = Equations::new(&mech);
        let (sparse, dense) = (eq.prepare(), eq.prepare_dense());
        assert_eq!(
            (sparse.rank, sparse.mobility, &sparse.redundant, &sparse.free_bodies),
            (dense.rank, dense.mobility, &dense.redundant, &dense.free_bodies),
            "{}: what check reports",
            mech.name
        );
        let (worst, (lo, hi)) = compare(&mech);
        println!(
            "{}: q, q̇, q̈ differ by {worst:?} their scale, κ̂ sparse / dense in [{lo:.3}, \
             {hi:.3}] ({:.2} s)",
            mech.name,
            start.elapsed().as_secs_f64()
        );
        for (what, w) in ["q", "q̇", "q̈"].iter().zip(worst) {
            assert!(w <= AGREEMENT, "{}: {what} differs by {w:e} of its scale", mech.name);
        }
        // κ̂ = 1/ρ of two partial-pivoting LUs of the same matrix that eliminate each body's
        // columns in the same order, the bodies in different orders: the pivots agree up to
        // ties broken otherwise and the bodies' order (measured: within 0.1 %); a factor of
        // 2 would already change the digits rule's verdicts noticeably.
        assert!(lo >= 0.5 && hi <= 2.0, "{}: κ̂ sparse / dense in [{lo}, {hi}]", mech.name);
    }
}

/// The positions of the links of `codegen::scale::arms(1, links, _)` at time `t`: link k
/// (1-based) turns by θ_k = 0.3 sin((10 + k + 0.1) t) relative to link k − 1 about its z axis
/// (odd k) or y axis (even k), all links 0.5 long along their x axis and starting at rest
/// along the global x axis, so its orientation is R_k = R_{k−1} Rot(axis_k, θ_k) and its
/// centre r_k = r_{k−1} + R_{k−1} (0.25, 0, 0) + R_k (0.25, 0, 0) (r_0 + R_0 (0.25, 0, 0) =
/// the origin, the first joint).
fn arm_closed_form(links: usize, t: f64) -> Vec<(Vector3<f64>, Matrix3<f64>)> {
    let half = Vector3::new(0.25, 0.0, 0.0);
    let mut joint = Vector3::zeros();
    let mut rotation = Matrix3::identity();
    let mut out = Vec::with_capacity(links);
    for k in 1..=links {
        let axis = if k % 2 == 1 { Vector3::z() } else { Vector3::y() };
        let theta = 0.3 * ((10.0 + k as f64 + 0.1) * t).sin();
        rotation *= Rotation3::from_axis_angle(&Unit::new_normalize(axis), theta).matrix();
        let centre = joint + rotation * half;
        joint = centre + rotation * half;
        out.push((centre, rotation));
    }
    out
}

#[test]
fn sparse_engine_matches_the_closed_form_of_a_driven_chain() {
    let links = 100;
    let mech = load(&codegen::scale::arms(1, links, 4));
    let frames = run(&mech, true);
    let mut worst: f64 = 0.0;
    for f in &frames {
        for (k, (centre, rotation)) in arm_closed_form(links, f.t).iter().enumerate() {
            let o = 7 * k;
            let r = f.q.fixed_rows::<3>(o);
            let p = f.q.fixed_rows::<4>(o + 3);
            // A(p) of the thesis (eq. 2.39) from the Euler parameters.
            let (e0, e) = (p[0], Vector3::new(p[1], p[2], p[3]));
            let a = (2.0 * e0 * e0 - 1.0) * Matrix3::identity()
                + 2.0 * (e * e.transpose() + e0 * e.cross_matrix());
            worst = worst.max((r - centre).amax()).max((a - rotation).amax());
        }
    }
    // Newton meets max |Φ| ≤ 1e-10 in every row; the error a row's residual leaves in the
    // positions grows along the chain with the lever arms (at most 50 m) and the number of
    // joints (100): 1e-7 m and 1e-7 in A bound it with a margin, far below the effect of
    // any wrong angle (0.3 rad amplitude).
    assert!(worst <= 1e-7, "the chain departs from its closed form by {worst:e}");
}

/// Writes the driven chains of the benchmark (`codegen::scale::chain(n, steps)` for n = 100,
/// 200 and 500, or the sizes in `MECHGEN_CHAINS`, with max(20, n²/500) steps over the same
/// 0.02 s: link k turns at up to 0.3 (10 + k) rad/s relative to link k − 1, so the last link
/// turns by about 1.6 rad a step at every size, as chain_100 does with 20 steps) into
/// `MECHGEN_CHAIN_DIR` (default `/tmp/chains`), and prints the generic engine's ns per step
/// on each, sparse, and dense on the first `MECHGEN_DENSE_STEPS` (default 3) of those steps
/// (`Analysis::time`, as `mechgen bench` times it: the median of `MECHGEN_REPEATS` passes,
/// default 3; `MECHGEN_DENSE=0` skips the dense passes). BENCHMARKS.md, "The generic engine, sparse".
#[test]
#[ignore = "benchmark: minutes of dense LU at 500 bodies"]
fn generic_sparse_timing() {
    let dir = std::env::var("MECHGEN_CHAIN_DIR").unwrap_or_else(|_| "/tmp/chains".to_owned());
    let sizes: Vec<usize> = std::env::var("MECHGEN_CHAINS")
        .map(|s| s.split(',').map(|n| n.trim().parse().expect("a size")).collect())
        .unwrap_or_else(|_| vec![100, 200, 500]);
    let dense = std::env::var("MECHGEN_DENSE").map_or(true, |v| v != "0");
    let repeats = std::env::var("MECHGEN_REPEATS").map_or(3, |v| v.parse().expect("a count"));
    let dense_steps: usize =
        std::env::var("MECHGEN_DENSE_STEPS").map_or(3, |v| v.parse().expect("a count"));
    std::fs::create_dir_all(&dir).expect("chain directory");
    for n in sizes {
        let steps = (n * n / 500).max(20);
        let text = codegen::scale::chain(n, steps);
        std::fs::write(format!("{dir}/chain_{n}.toml"), &text).expect("chain written");
        let time = |text: &str, sparse: bool| {
            let mech = load(text);
            let eq = Equations::new(&mech);
            let start = std::time::Instant::now();
            // The dense pass starts from the same preparation: `prepare_dense`'s SVDs alone
            // take minutes at 500 bodies.
            let prep = eq.prepare();
            let prepare = start.elapsed().as_secs_f64();
            let a = Analysis::new(&eq, &prep).with_sparse(sparse).with_tolerance(1e-10);
            let (_, median, iterations) = a.time(repeats).expect("the chain runs");
            (prepare, median, iterations)
        };
        let (p, s, si) = time(&text, true);
        println!("chain_{n}: sparse: prepare {p:.2} s, {s:.0} ns/step ({si:.2} iterations)");
        if dense {
            // The same time step, fewer of them.
            let end = 0.02 * dense_steps as f64 / steps as f64;
            let short = text.replacen(
                &format!("end = 0.02\nsteps = {steps}\n"),
                &format!("end = {end:?}\nsteps = {dense_steps}\n"),
                1,
            );
            assert_ne!(short, text, "the grid is shortened");
            let (p, d, di) = time(&short, false);
            println!("chain_{n}: dense: prepare {p:.2} s, {d:.0} ns/step ({di:.2} iterations)");
        }
    }
}
