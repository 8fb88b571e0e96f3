//! The generated structured LU (static pivot orders, see `codegen::pivot`) against dense LU
//! with partial pivoting: on every committed generated module at random configurations near
//! its initial estimates, and over a full revolution of the R-S-S-R, where a single static
//! order meets small pivots and the dense fallback takes over.

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use runtime::factors::{DenseOnly, FactorCounts};
use runtime::lu::{self, PivotInfo};
use runtime::{Mechanism, NewtonOptions, Solver};

/// Structured and dense solutions agree to this fraction of the solution's largest entry.
///
/// Both are backward stable: threshold pivoting bounds the multipliers by 10 instead of 1,
/// which on these 2- to 28-row Jacobians costs a few units of round-off times the condition
/// number. The worst seen at the sampled configurations (the estimates perturbed by up to
/// 0.05) is about 1e-14, on the four-bar; 1e-12 leaves a margin of 100.
const AGREEMENT: f64 = 1e-12;

/// Random configurations per module.
const SAMPLES: usize = 200;

/// A generated mechanism with only its static order `K`.
struct Only<M, const K: usize>(M);

impl<M: Mechanism<N>, const N: usize, const K: usize> Mechanism<N> for Only<M, K> {
    const PIVOT_ORDERS: usize = 1;
    fn residual(&self, q: &[f64; N], t: f64, phi: &mut [f64; N]) {
        self.0.residual(q, t, phi);
    }
    fn jacobian(&self, q: &[f64; N], t: f64, jac: &mut [[f64; N]; N]) {
        self.0.jacobian(q, t, jac);
    }
    fn residual_jacobian(&self, q: &[f64; N], t: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
        self.0.residual_jacobian(q, t, phi, jac);
    }
    fn velocity_rhs(&self, q: &[f64; N], t: f64, nu: &mut [f64; N]) {
        self.0.velocity_rhs(q, t, nu);
    }
    fn acceleration_rhs(&self, q: &[f64; N], qd: &[f64; N], t: f64, gamma: &mut [f64; N]) {
        self.0.acceleration_rhs(q, qd, t, gamma);
    }
    fn normalize(&self, q: &mut [f64; N]) {
        self.0.normalize(q);
    }
    fn residual_jacobian_structural(
        &self,
        q: &[f64; N],
        t: f64,
        phi: &mut [f64; N],
        jac: &mut [[f64; N]; N],
    ) {
        self.0.residual_jacobian_structural(q, t, phi, jac);
    }
    fn factor_structured(&self, order: usize, jac: &mut [[f64; N]; N]) -> Option<PivotInfo> {
        if order == 0 { self.0.factor_structured(K, jac) } else { None }
    }
    fn solve_structured(&self, order: usize, lu: &[[f64; N]; N], b: &mut [f64; N]) {
        if order == 0 {
            self.0.solve_structured(K, lu, b);
        }
    }
}

/// What the random-configuration check saw for one module.
#[derive(Debug, Default)]
struct Seen {
    /// Configurations where dense LU accepted Φ_q.
    regular: usize,
    /// (configuration, order) pairs where the static order passed its guard.
    accepted: usize,
    /// Largest |x_structured − x_dense| / max |x_dense|.
    worst: f64,
}

/// Checks every static order of `m` against dense LU at `SAMPLES` random configurations near
/// `q0` and times in `[t0, t1]`.
fn check_random<M: Mechanism<N>, const N: usize>(m: &M, q0: &[f64; N], t0: f64, t1: f64) -> Seen {
    let mut rng = StdRng::seed_from_u64(N as u64);
    let mut seen = Seen::default();
    for _ in 0..SAMPLES {
        let q: [f64; N] = std::array::from_fn(|k| q0[k] + rng.random_range(-0.05..0.05));
        let t = if t1 > t0 { rng.random_range(t0..t1) } else { t0 };
        let b: [f64; N] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let mut full = Box::new([[0.0; N]; N]);
        m.jacobian(&q, t, &mut full);
        let mut dense = full.clone();
        let mut perm = [0; N];
        if lu::factor(&mut dense, &mut perm).is_err() {
            continue;
        }
        seen.regular += 1;
        let mut x_dense = b;
        lu::solve(&dense, &perm, &mut x_dense);
        let scale = x_dense.iter().fold(0.0_f64, |m, x| m.max(x.abs()));

        // Only the structural entries are written and read: everything else stays NaN.
        let mut structural = Box::new([[f64::NAN; N]; N]);
        let (mut phi, mut phi_full) = ([0.0; N], [0.0; N]);
        m.residual_jacobian_structural(&q, t, &mut phi, &mut structural);
        m.residual(&q, t, &mut phi_full);
        assert_eq!(phi.map(f64::to_bits), phi_full.map(f64::to_bits), "Φ at {q:?}");
        for i in 0..N {
            for j in 0..N {
                let s = structural[i][j];
                assert!(s.is_nan() || s == full[i][j], "Φ_q[{i}][{j}] at {q:?}");
            }
        }
        // `residual_jacobian` (the constant entries, then the structural function) gives Φ and
        // the whole Φ_q of the separately emitted `residual` and `jacobian`, zeros included.
        let (mut both, mut phi_both) = (Box::new([[f64::NAN; N]; N]), [f64::NAN; N]);
        m.residual_jacobian(&q, t, &mut phi_both, &mut both);
        assert_eq!(phi_both.map(f64::to_bits), phi_full.map(f64::to_bits), "Φ at {q:?}");
        for (i, (row, full_row)) in both.iter().zip(full.iter()).enumerate() {
            assert_eq!(row.map(f64::to_bits), full_row.map(f64::to_bits), "Φ_q row {i} at {q:?}");
        }
        for order in 0..M::PIVOT_ORDERS {
            let mut factors = structural.clone();
            let Some(pivots) = m.factor_structured(order, &mut factors) else {
                continue;
            };
            assert!(pivots.smallest > 0.0 && pivots.smallest <= pivots.largest, "{pivots:?}");
            seen.accepted += 1;
            let mut x = b;
            m.solve_structured(order, &factors, &mut x);
            for (a, d) in x.iter().zip(&x_dense) {
                let error = (a - d).abs() / scale;
                assert!(
                    error <= AGREEMENT,
                    "order {order} at {q:?}, t = {t}: {x:?} against {x_dense:?}"
                );
                seen.worst = seen.worst.max(error);
            }
        }
    }
    seen
}

macro_rules! random {
    ($module:ident, $ty:ident) => {{
        use generated::$module as g;
        let t1 = g::T_START + g::T_STEP * (g::T_COUNT.max(1) - 1) as f64;
        let seen = check_random(&g::$ty, &g::Q0, g::T_START, t1);
        (stringify!($module), <g::$ty as Mechanism<{ g::N }>>::PIVOT_ORDERS, seen)
    }};
}

#[test]
fn static_orders_agree_with_dense_lu_on_every_generated_module() {
    let all = [
        random!(cylindrical_joint, CylindricalJoint),
        random!(four_bar, FourBar),
        random!(prismatic_joint, PrismaticJoint),
        // revolute_joint has no unknowns left (its blocks are all closed form): no LU.
        random!(rotation_about_x, RotationAboutX),
        random!(rotation_about_y, RotationAboutY),
        random!(rotation_about_y_short, RotationAboutYShort),
        random!(rssr, Rssr),
        random!(screw_joint, ScrewJoint),
        random!(slider_crank_5body, SliderCrank5body),
        random!(spherical_joint, SphericalJoint),
        random!(static_body, StaticBody),
        random!(static_body_offset, StaticBodyOffset),
        random!(translation_x, TranslationX),
        random!(translation_xy, TranslationXy),
        random!(translation_xyz, TranslationXyz),
        random!(translation_y, TranslationY),
        random!(universal_joint, UniversalJoint),
    ];
    for (name, orders, seen) in &all {
        eprintln!("{name}: {orders} orders, {seen:?}");
        assert!(*orders >= 1, "{name} has no static order");
        // Most random configurations are regular, and some order passes at most of them.
        assert!(seen.regular >= SAMPLES / 2, "{name}: {seen:?}");
        assert!(seen.accepted >= seen.regular / 2, "{name}: {seen:?}");
    }
}

/// One analysed time point.
#[derive(Clone, Copy)]
struct State<const N: usize> {
    q: [f64; N],
    qd: [f64; N],
    qdd: [f64; N],
}

/// One crank revolution of the R-S-S-R in 1000 steps at Newton tolerance 1e-12, as in
/// `benches/rssr_revolution.toml`: the states and how Φ_q was factored.
fn revolution<M: Mechanism<N>, const N: usize>(
    m: M,
    q0: [f64; N],
) -> (Vec<State<N>>, FactorCounts) {
    let mut solver = Solver::new(m, q0);
    solver.set_options(NewtonOptions { tolerance: 1e-12, ..NewtonOptions::DEFAULT });
    solver.set_predictor(true);
    let end = 2.0 * std::f64::consts::PI / 146.6;
    let states = (0..=1000)
        .map(|k| {
            let t = end * f64::from(k) / 1000.0;
            solver.position(t).unwrap_or_else(|e| panic!("t = {t}: {e}"));
            solver.velocity().unwrap();
            solver.acceleration().unwrap();
            State { q: *solver.q(), qd: *solver.qd(), qdd: *solver.qdd() }
        })
        .collect();
    (states, solver.factor_counts())
}

/// The largest difference of q, q̇ and q̈ between two runs, each relative to the quantity's
/// largest magnitude over the run.
fn difference<const N: usize>(a: &[State<N>], b: &[State<N>]) -> [f64; 3] {
    let get = |s: &State<N>, k: usize| match k {
        0 => s.q,
        1 => s.qd,
        _ => s.qdd,
    };
    std::array::from_fn(|k| {
        let scale = b.iter().flat_map(|s| get(s, k)).fold(0.0_f64, |m, x| m.max(x.abs()));
        let worst = a
            .iter()
            .zip(b)
            .flat_map(|(x, y)| get(x, k).into_iter().zip(get(y, k)))
            .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
        worst / scale
    })
}

#[test]
fn rssr_revolution_matches_dense_lu_with_and_without_the_fallback() {
    use generated::rssr::{Q0, Rssr};
    let (dense, dense_counts) = revolution(DenseOnly(Rssr), Q0);
    assert_eq!(dense_counts.structured, 0);
    let (all, all_counts) = revolution(Rssr, Q0);
    // With its closed-form blocks substituted the R-S-S-R solves 5 unknowns of its S-S loop,
    // and its one static order serves the whole revolution without the fallback (the
    // 20-unknown system needed a second order, or the fallback, around half a turn).
    let (only, only_counts) = revolution(Only::<Rssr, 0>(Rssr), Q0);
    eprintln!("dense {dense_counts:?}\nall orders {all_counts:?}\norder 0 only {only_counts:?}");
    assert_eq!(<Rssr as Mechanism<{ generated::rssr::N }>>::PIVOT_ORDERS, 1);
    assert!(all_counts.structured > 0 && all_counts.dense == 0, "{all_counts:?}");
    for (name, run) in [("all orders", &all), ("order 0 and the fallback", &only)] {
        let d = difference(run, &dense);
        eprintln!("{name}: relative differences of q, q̇, q̈: {d:?}");
        // Both runs take the same Newton steps from the same predictor, so they differ by the
        // round-off of their linear solves only (see AGREEMENT).
        assert!(d.iter().all(|&x| x <= AGREEMENT), "{name}: {d:?}");
    }
}
