//! Static pivot orders inside the diagonal blocks of Newton block by block (`pivot::plan_blocks`,
//! `emit::lu::block`): the emitted factors and solves against nalgebra's dense LU on random
//! values, and the dense fallback where a block's planned orders are refused.

use codegen::emit::Scalar;
use codegen::testing::{load_toml, relative_differences, run_generated, run_generic};
use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use runtime::Mechanism;
use runtime::blocks::Solve;

/// Generated and generic runs agree to this fraction of each quantity's scale, as in
/// `block_solver`: Newton stops at max |Φ| ≤ 1e-12 in both engines, and 1e-10 leaves a factor
/// of 100 for the conditioning.
const AGREEMENT: f64 = 1e-10;

/// ‖x − x_nalgebra‖∞ ≤ this · κ∞(A) · ‖x_nalgebra‖∞: both are LU solves, backward stable with
/// growth bounded by the multiplier guard (|l| ≤ 10 on at most 7 steps) and partial pivoting,
/// so each is within a few hundred ε κ of the exact solution; 1e-13 ≈ 450 ε.
const SOLVE_AGREEMENT: f64 = 1e-13;

/// κ∞ of a small dense matrix, ‖A‖∞ ‖A⁻¹‖∞.
fn condition(a: &DMatrix<f64>) -> f64 {
    let norm = |m: &DMatrix<f64>| {
        m.row_iter().map(|r| r.iter().map(|v| v.abs()).sum::<f64>()).fold(0.0, f64::max)
    };
    a.clone().try_inverse().map_or(f64::INFINITY, |inv| norm(a) * norm(&inv))
}

/// The committed whole Stewart module (`generated::stewart_whole`: no closed form substituted,
/// 91 unknowns, Newton block by block, its rotation blocks and
/// its loop block with static orders): every diagonal block it factors alone, filled with
/// random values on Φ_q's structure (structural zeros 0), is factored by `factor_block` and
/// solved by `solve_block`, and then the whole block-triangular system by `solve_blocks`, each
/// against nalgebra's LU of the same matrix. The values are random, so the planned orders pass
/// their guard on some and are refused on others: both the static orders and the fallback to
/// the block's dense LU are checked, and so is the flag that tells `solve_blocks` which
/// factors a block holds.
#[test]
fn static_block_orders_solve_as_nalgebra_on_random_values() {
    use generated::stewart_whole::{self as gs, StewartWhole};
    const N: usize = gs::N;
    type M = StewartWhole;

    let path = codegen::testing::example("inputs/stewart.toml");
    let mech = codegen::testing::load(&path).mechanism;
    let sys = codegen::symbolic::Symbolic::build_full(&mech).expect("the system builds");
    let layout = <M as Mechanism<N>>::BLOCKS.expect("factored by blocks");
    let packed = <M as Mechanism<N>>::PACKED_BLOCKS.expect("packed");
    // The module's layout is the one the generator finds for the description, so the
    // structure of Φ_q read from the symbolic system is the module's.
    let blocks = codegen::blocks::Blocks::of(&sys, &mech);
    let rows: Vec<usize> = blocks.blocks.iter().flat_map(|b| b.rows.clone()).collect();
    let columns: Vec<usize> = blocks.blocks.iter().flat_map(|b| b.unknowns.clone()).collect();
    assert_eq!((layout.rows, layout.columns), (&rows[..], &columns[..]));
    let structural = |r: usize, c: usize| sys.jac[r].iter().any(|&(j, _)| j == c);

    let module = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../generated/src/stewart_whole.rs"
    ))
    .expect("the committed module");
    assert!(module.contains("'order_0: {"), "the module has static orders in its blocks");

    let mechanism = M::new(0.0, &gs::Inputs::from_array([[0.6, 0.0, 0.0]; 6]));
    let mut rng = StdRng::seed_from_u64(16);
    let (mut static_solves, mut dense_solves, mut worst) = (0, 0, 0.0_f64);
    for _ in 0..200 {
        let mut jac = Box::new([[0.0; N]; N]);
        let mut perm = [0; N];
        // Φ_q in full (dense), and its packed form in the storage, position after position.
        let mut a = DMatrix::<f64>::zeros(N, N);
        {
            let flat = jac.as_flattened_mut();
            let mut at = 0;
            for (b, bounds) in layout.starts.windows(2).enumerate() {
                assert_eq!(at, packed[b], "block {b} starts where the module says");
                let cols = &layout.columns[bounds[0]..bounds[1]];
                for &r in &layout.rows[bounds[0]..bounds[1]] {
                    let below = &layout.lower[layout.lower_starts[r]..layout.lower_starts[r + 1]];
                    for &c in cols.iter().chain(below) {
                        let v = if structural(r, c) {
                            // An affine block's one entry is its pivot: kept away from 0.
                            let v: f64 = rng.random_range(-1.0..1.0);
                            if cols.len() == 1 && c == cols[0] {
                                v.signum() * (0.5 + v.abs())
                            } else {
                                v
                            }
                        } else {
                            0.0
                        };
                        flat[at] = v;
                        a[(r, c)] = v;
                        at += 1;
                    }
                }
            }
        }
        // Each block factored and solved alone.
        for b in 0..layout.starts.len() - 1 {
            if layout.solve[b] == Solve::Affine {
                continue;
            }
            let (start, end) = (layout.starts[b], layout.starts[b + 1]);
            let (r, c) = (&layout.rows[start..end], &layout.columns[start..end]);
            let s = r.len();
            let d = DMatrix::from_fn(s, s, |i, j| a[(r[i], c[j])]);
            let kappa = condition(&d);
            mechanism.factor_block(b, &mut jac, &mut perm, 0.0).expect("a regular block");
            if perm[start] >= s {
                static_solves += 1;
            } else {
                dense_solves += 1;
            }
            let rhs: [f64; N] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let mut x = [0.0; 8];
            mechanism.solve_block(b, &jac, &perm, &rhs, &mut x[..s]);
            let truth = d.lu().solve(&DVector::from_fn(s, |i, _| rhs[r[i]])).expect("regular");
            let error = (0..s).map(|i| (x[i] - truth[i]).abs()).fold(0.0, f64::max);
            let relative = error / (kappa * truth.amax());
            worst = worst.max(relative);
            assert!(relative <= SOLVE_AGREEMENT, "block {b}: {error:e} with κ {kappa:e}");
        }
        // Every block's factors (affine ones are their entry) through the block forward
        // substitution of the velocity and acceleration solves.
        let mut b = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let truth = a.clone().lu().solve(&DVector::from_column_slice(&b)).expect("regular");
        mechanism.solve_blocks(&jac, &perm, &mut b);
        let kappa = condition(&a);
        let error = (0..N).map(|i| (b[i] - truth[i]).abs()).fold(0.0, f64::max);
        let relative = error / (kappa * truth.amax());
        worst = worst.max(relative);
        assert!(relative <= SOLVE_AGREEMENT, "solve_blocks: {error:e} with κ {kappa:e}");
    }
    println!("{static_solves} static and {dense_solves} dense block solves, worst {worst:e} κ");
    // Random values are no motion the orders were planned for, but they pass the guard often
    // enough: both paths are taken many times.
    assert!(static_solves >= 100 && dense_solves >= 100, "{static_solves} / {dense_solves}");
}

/// One R-S-S-R loop solved by Newton block by block over `end` seconds (the crank turns at
/// 146.6 rad/s) in `steps` steps.
fn loop_over(end: f64, steps: usize) -> String {
    codegen::scale::rssr_loops(1, steps).replace("end = 0.02", &format!("end = {end:?}"))
}

/// A module whose blocks' static orders were planned on the first 0.15 rad of the crank's turn
/// and which is then run over a whole revolution: the orders are refused where the loop's
/// geometry has turned far from where they were chosen (checked here on the same orders and
/// the generic engine's configurations, independently of the run), each such block is
/// factored by its dense LU, and the run agrees with the generic engine's everywhere.
#[test]
fn blocks_whose_static_orders_are_refused_fall_back_to_their_dense_lu() {
    let short = load_toml(&format!("{}\n[solver]\ntolerance = 1e-12\n", loop_over(0.001, 10)));
    let long = load_toml(&format!("{}\n[solver]\ntolerance = 1e-12\n", loop_over(0.043, 200)));
    // The whole system: substituted, its closed forms would leave one block (`symbolic::substitute`).
    let sys = codegen::symbolic::Symbolic::build_full(&short).expect("the system builds");
    let module = codegen::emit::module_with_block_newton(&short, &sys, "refused", Scalar::F64);
    assert!(module.contains("'order_0: {"), "static orders in the blocks");
    // With one loop no two blocks share a structure, so each block's orders are those planned
    // for it alone.
    assert!(!module.contains("fn factor_block_shared_"), "no shared block factors");
    let blocks = codegen::blocks::Blocks::of(&sys, &short);
    let planned: Vec<_> = blocks
        .blocks
        .iter()
        .filter(|b| b.kind != codegen::blocks::Kind::ClosedForm)
        .map(|b| {
            let group = vec![(b.rows.clone(), b.unknowns.clone())];
            let orders = codegen::pivot::plan_blocks(&short, &sys, &[group]).remove(0);
            (b, orders)
        })
        .collect();
    assert!(planned.iter().all(|(_, orders)| !orders.is_empty()), "every block has an order");
    let mut refused = 0;
    codegen::pivot::motion(&long, &sys, |t, q| {
        let a = codegen::pivot::numeric(&sys, q, t);
        for (block, orders) in &planned {
            let d: Vec<Vec<f64>> = block
                .rows
                .iter()
                .map(|&r| block.unknowns.iter().map(|&c| a[r][c]).collect())
                .collect();
            let passes = orders.iter().any(|o| {
                codegen::pivot::largest_multiplier(o, &d)
                    .is_some_and(|m| m <= codegen::pivot::RUNTIME_MAX_MULTIPLIER)
            });
            refused += usize::from(!passes);
        }
        true
    });
    println!("{refused} block factorisations refused along the revolution");
    assert!(refused > 0, "the short plan's orders are refused somewhere on the revolution");

    // The short plan's module stepped over the long grid: its grid constants replaced by those
    // the long description's module has.
    let grid = codegen::emit::module_with_block_newton(&long, &sys, "refused", Scalar::F64);
    let constant = |text: &str, name: &str| -> String {
        let line = text.lines().find(|l| l.starts_with(&format!("pub const {name}:")));
        line.expect("the grid constant").to_owned()
    };
    let mut module = module;
    for name in ["T_START", "T_STEP", "T_COUNT"] {
        module = module.replace(&constant(&module, name), &constant(&grid, name));
    }
    let built = codegen::engine::build_module(&long, &module, &sys, Scalar::F64).expect("builds");
    let generic = run_generic(&long);
    assert!(generic.failure.is_none(), "{:?}", generic.failure);
    let generated = run_generated(&long, &built);
    assert!(generated.failure.is_none(), "{:?}", generated.failure);
    assert_eq!(generic.frames.len(), generated.frames.len(), "every frame");
    for (diff, at) in relative_differences(&generic.frames, &generated.frames) {
        assert!(diff <= AGREEMENT, "{at}");
    }
}

/// The crank-rocker of `tests/stability/crank_rocker_toggle.toml` driven by its rocker into the
/// folded toggle, solved by Newton block by block (the rocker's orientation in closed form,
/// the crank and coupler an implicit block with static orders planned along the motion up to
/// the toggle): the generated engine stops `singular` at the same time and names the same
/// equations as the generic engine, the toggle's time coming from the closed form (as in
/// `stability`), and every step before it agrees with the generic engine's.
#[test]
fn a_singular_block_stops_with_the_generic_engines_time_and_equations() {
    let path =
        concat!(env!("CARGO_MANIFEST_DIR"), "/stability/crank_rocker_toggle.toml").to_owned();
    let mech = codegen::testing::load(std::path::Path::new(&path)).mechanism;
    // The whole system: substituted, its closed forms would leave one block (`symbolic::substitute`).
    let sys = codegen::symbolic::Symbolic::build_full(&mech).expect("the system builds");
    let module = codegen::emit::module_with_block_newton(&mech, &sys, "toggle", Scalar::F64);
    assert!(module.contains("const BLOCK_NEWTON: bool = true;"), "Newton block by block");
    assert!(module.contains("'order_0: {"), "static orders in the blocks");
    let built = codegen::engine::build_module(&mech, &module, &sys, Scalar::F64).expect("builds");
    let generic = run_generic(&mech);
    let generated = run_generated(&mech, &built);
    // The toggle (see `stability`): |O2 B| = b − a, the rocker at φ* from 120° at 0.5 rad/s;
    // both engines stop at the first grid time (0.05 apart) at or past it.
    let b = (2.25_f64.powi(2) + (2.1650635094610964_f64 - 1.0).powi(2)).sqrt();
    let phi_star =
        (((b - 1.0).powi(2) - 3.5_f64.powi(2) - 2.5_f64.powi(2)) / (2.0 * 3.5 * 2.5)).acos();
    let t_star = (phi_star - 2.0 * std::f64::consts::FRAC_PI_3) / 0.5;
    let t_fail = (t_star / 0.05).ceil() * 0.05;
    let [g, s] = [&generic, &generated].map(|r| r.failure.clone().expect("a failure"));
    for f in [&g, &s] {
        assert_eq!(f.kind, codegen::generic::FailureKind::Singular, "{f:?}");
        // Grid times are start + k·step: equal to round-off.
        assert!((f.t - t_fail).abs() < 1e-12, "stopped at {} not {t_fail}", f.t);
    }
    assert_eq!((g.t, &g.constraints), (s.t, &s.constraints), "the engines agree");
    assert_eq!(generic.frames.len(), generated.frames.len(), "the same steps before it");
    // The file keeps the default tolerance 1e-10 (not the 1e-12 of `AGREEMENT`), so 1e-8
    // leaves the same factor of 100 for the conditioning, which grows towards the toggle.
    for (diff, at) in relative_differences(&generic.frames, &generated.frames) {
        assert!(diff <= 1e-8, "{at}");
    }
}
