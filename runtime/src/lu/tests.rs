extern crate std;

use approx::assert_relative_eq;
use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use super::*;

/// Random matrices per size; entries are uniform in [−1, 1), which is almost surely regular.
const TRIALS: u64 = 20;

fn random_matrix<const N: usize>(rng: &mut StdRng) -> [[f64; N]; N] {
    core::array::from_fn(|_| core::array::from_fn(|_| rng.random_range(-1.0..1.0)))
}

/// Row-major conversion (rule J2: never `SMatrix::from`, which reads the inner arrays as
/// columns).
fn to_nalgebra<const N: usize>(a: &[[f64; N]; N]) -> DMatrix<f64> {
    DMatrix::from_fn(N, N, |i, j| a[i][j])
}

/// Factors seeded random matrices of size `N` and checks them against nalgebra's LU: the same
/// pivots and factors, P·A = L·U, and the same solution of A x = b.
fn check_random<const N: usize>(seed: u64) {
    let mut rng = StdRng::seed_from_u64(seed);
    for _ in 0..TRIALS {
        let a = random_matrix::<N>(&mut rng);
        let b: [f64; N] = core::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let mut lu = a;
        let mut perm = [0; N];
        let info = factor(&mut lu, &mut perm).expect("random matrices are regular");

        let oracle = to_nalgebra(&a).lu();
        let (p, l_oracle, u_oracle) = oracle.clone().unpack();
        let l = DMatrix::from_fn(N, N, |i, j| match i.cmp(&j) {
            core::cmp::Ordering::Greater => lu[i][j],
            core::cmp::Ordering::Equal => 1.0,
            core::cmp::Ordering::Less => 0.0,
        });
        let u = DMatrix::from_fn(N, N, |i, j| if i <= j { lu[i][j] } else { 0.0 });
        let pa = DMatrix::from_fn(N, N, |i, j| a[perm[i]][j]);
        let mut pa_oracle = to_nalgebra(&a);
        p.permute_rows(&mut pa_oracle);

        // Same algorithm and pivot rule: the factors agree up to rounding in the updates, which
        // grows mildly with N; 1e-10 leaves a wide margin for entries of order one.
        assert_eq!(pa, pa_oracle, "N = {N}: different pivot rows");
        assert_relative_eq!(l, l_oracle, epsilon = 1e-10);
        assert_relative_eq!(u, u_oracle, epsilon = 1e-10);
        // Reconstruction P·A = L·U, to a few ulps of the entries times N.
        assert_relative_eq!(&l * &u, pa, epsilon = 1e-13);

        let diagonal = (0..N).map(|k| lu[k][k].abs());
        assert_eq!(info.smallest, diagonal.clone().fold(f64::INFINITY, f64::min));
        assert_eq!(info.largest, diagonal.fold(0.0, f64::max));

        let mut x = b;
        solve(&lu, &perm, &mut x);
        let x_oracle = oracle.solve(&DVector::from_row_slice(&b)).expect("regular");
        // The solutions can be as large as the condition number; compare relatively, and check
        // the residual, which backward stability keeps near rounding level.
        assert_relative_eq!(DVector::from_row_slice(&x), x_oracle, max_relative = 1e-8);
        let residual = to_nalgebra(&a) * DVector::from_row_slice(&x) - DVector::from_row_slice(&b);
        assert!(residual.amax() < 1e-10 * (1.0 + x_oracle.amax()), "N = {N}: {residual}");
    }
}

#[test]
fn random_matrices_match_nalgebra_for_sizes_1_to_12() {
    check_random::<1>(1);
    check_random::<2>(2);
    check_random::<3>(3);
    check_random::<4>(4);
    check_random::<5>(5);
    check_random::<6>(6);
    check_random::<7>(7);
    check_random::<8>(8);
    check_random::<9>(9);
    check_random::<10>(10);
    check_random::<11>(11);
    check_random::<12>(12);
}

/// Seeded random matrices of size `N` whose last row is a random combination of the others
/// are refused with a small pivot.
fn check_rank_deficient<const N: usize>(seed: u64) {
    let mut rng = StdRng::seed_from_u64(seed);
    for _ in 0..TRIALS {
        let mut a = random_matrix::<N>(&mut rng);
        let weights: [f64; N] = core::array::from_fn(|_| rng.random_range(-1.0..1.0));
        a[N - 1] = core::array::from_fn(|j| (0..N - 1).map(|i| weights[i] * a[i][j]).sum());
        let mut perm = [0; N];
        let result = factor(&mut a, &mut perm);
        assert!(matches!(result, Err(Singular::SmallPivot { .. })), "N = {N}: {result:?}");
    }
}

#[test]
fn random_rank_deficient_matrices_are_singular() {
    check_rank_deficient::<2>(102);
    check_rank_deficient::<3>(103);
    check_rank_deficient::<5>(105);
    check_rank_deficient::<8>(108);
    check_rank_deficient::<12>(112);
}

#[test]
fn permutation_maps_rows_of_pa_to_rows_of_a() {
    #[rustfmt::skip]
    let a = [
        [0.0, 1.0, 2.0],
        [1.0, 0.0, 0.0],
        [3.0, 0.0, 1.0],
    ];
    let mut lu = a;
    let mut perm = [0; 3];
    factor(&mut lu, &mut perm).unwrap();
    // Column 0 pivots on row 2; then, of rows 1 and 0, only row 0 has a nonzero in column 1.
    assert_eq!(perm, [2, 0, 1]);
}

#[test]
fn solve_handles_an_asymmetric_system_exactly() {
    // x + 2y = 5, 3x + 4y = 11 ⇒ x = 1, y = 2; a transposed matrix would give x = 2, y = 1.5.
    let mut a = [[1.0, 2.0], [3.0, 4.0]];
    let mut perm = [0; 2];
    factor(&mut a, &mut perm).unwrap();
    let mut b = [5.0, 11.0];
    solve(&a, &perm, &mut b);
    assert_relative_eq!(b[0], 1.0, epsilon = 1e-15);
    assert_relative_eq!(b[1], 2.0, epsilon = 1e-15);
}

#[test]
fn zero_matrix_is_singular_in_column_0() {
    let mut a = [[0.0; 3]; 3];
    let mut perm = [0; 3];
    assert_eq!(
        factor(&mut a, &mut perm),
        Err(Singular::SmallPivot { column: 0, pivot: 0.0, largest: 0.0 })
    );
}

#[test]
fn dependent_row_is_singular_in_the_last_column() {
    // Row 2 = row 0 + row 1: elimination leaves an exact zero (up to rounding) in column 2.
    #[rustfmt::skip]
    let mut a = [
        [2.0, 1.0, 1.0],
        [1.0, 3.0, 2.0],
        [3.0, 4.0, 3.0],
    ];
    let mut perm = [0; 3];
    let error = factor(&mut a, &mut perm).unwrap_err();
    let Singular::SmallPivot { column, pivot, largest } = error else {
        panic!("expected a small pivot, got {error:?}");
    };
    assert_eq!(column, 2);
    assert!(pivot <= 1e-12 * largest, "pivot {pivot:e}, largest {largest:e}");
}

#[test]
fn near_singular_matrix_is_refused_below_the_ratio_and_accepted_above() {
    let mut perm = [0; 2];
    // Pivots 1 and 1e-14: below the default ratio 1e-12.
    let mut a = [[1.0, 1.0], [1.0, 1.0 + 1e-14]];
    assert_eq!(factor(&mut a, &mut perm).unwrap_err().column(), 1);
    // Pivots 1 and 1e-10: accepted, and reported.
    let mut a = [[1.0, 1.0], [1.0, 1.0 + 1e-10]];
    let info = factor(&mut a, &mut perm).unwrap();
    assert_eq!(info.largest, 1.0);
    assert_relative_eq!(info.smallest, 1e-10, max_relative = 1e-6);
    // A stricter ratio refuses the same matrix.
    let mut a = [[1.0, 1.0], [1.0, 1.0 + 1e-10]];
    assert!(matches!(
        factor_with_ratio(&mut a, &mut perm, 1e-8),
        Err(Singular::SmallPivot { column: 1, .. })
    ));
}

#[test]
fn small_first_pivot_is_caught_once_the_largest_is_known() {
    // Column 0 alone looks fine; only the later pivot 1 shows that 1e-13 is relatively tiny.
    let mut a = [[1e-13, 0.0], [0.0, 1.0]];
    let mut perm = [0; 2];
    assert_eq!(
        factor(&mut a, &mut perm),
        Err(Singular::SmallPivot { column: 0, pivot: 1e-13, largest: 1.0 })
    );
}

#[test]
fn the_verdict_does_not_depend_on_scale() {
    let mut perm = [0; 2];
    for scale in [1e-200, 1e-8, 1.0, 1e8, 1e200] {
        // Pivots 2 and 3 − 1/2 = 2.5, times the scale.
        let mut a = [[2.0 * scale, scale], [scale, 3.0 * scale]];
        let info = factor(&mut a, &mut perm).unwrap();
        assert_relative_eq!(info.smallest / info.largest, 0.8, max_relative = 1e-14);
        // Pivots 1 and 1e-14, times the scale.
        let mut a = [[scale, scale], [scale, (1.0 + 1e-14) * scale]];
        assert_eq!(factor(&mut a, &mut perm).unwrap_err().column(), 1, "scale {scale:e}");
    }
}

#[test]
fn non_finite_entries_are_refused_with_their_step() {
    let mut perm = [0; 3];
    // In the pivot column at the first step.
    let mut a = [[1.0, 0.0, 0.0], [f64::NAN, 1.0, 0.0], [0.0, 0.0, 1.0]];
    assert_eq!(factor(&mut a, &mut perm), Err(Singular::NonFinite { column: 0 }));
    // In the pivot row, to the right of the pivot.
    let mut a = [[1.0, 0.0, f64::INFINITY], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    assert_eq!(factor(&mut a, &mut perm), Err(Singular::NonFinite { column: 0 }));
    // Below the diagonal in a later column, skipped by a zero multiplier until then.
    let mut a = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, f64::NEG_INFINITY]];
    assert_eq!(factor(&mut a, &mut perm), Err(Singular::NonFinite { column: 2 }));
}

#[test]
fn overflow_during_elimination_is_refused() {
    // 1e308 − (−1)·1e308 overflows to infinity in row 1, column 1.
    let mut a = [[1.0, 1e308], [-1.0, 1e308]];
    let mut perm = [0; 2];
    assert_eq!(factor(&mut a, &mut perm), Err(Singular::NonFinite { column: 1 }));
}
