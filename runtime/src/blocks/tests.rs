extern crate std;

use std::boxed::Box;
use std::vec::Vec;

use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};

use super::*;

const N: usize = 14;

/// A random block-lower-triangular matrix of size N with its rows and columns shuffled, and its
/// layout: diagonal blocks dense with entries in [−1, 1) (almost surely regular), and a third of
/// the entries below them non-zero.
fn random(seed: u64, sizes: &[usize]) -> ([[f64; N]; N], Layout) {
    let mut rng = StdRng::seed_from_u64(seed);
    assert_eq!(sizes.iter().sum::<usize>(), N);
    let mut rows: Vec<usize> = (0..N).collect();
    let mut columns: Vec<usize> = (0..N).collect();
    rows.shuffle(&mut rng);
    columns.shuffle(&mut rng);
    let mut starts = std::vec![0];
    for s in sizes {
        starts.push(starts.last().unwrap() + s);
    }
    let mut a = [[0.0; N]; N];
    let mut lower = std::vec![Vec::new(); N];
    for b in 0..sizes.len() {
        for i in starts[b]..starts[b + 1] {
            for j in starts[b]..starts[b + 1] {
                a[rows[i]][columns[j]] = rng.random_range(-1.0..1.0);
            }
            for j in 0..starts[b] {
                if rng.random_bool(0.33) {
                    a[rows[i]][columns[j]] = rng.random_range(-3.0..3.0);
                    lower[rows[i]].push(columns[j]);
                }
            }
        }
    }
    let mut lower_starts = std::vec![0];
    for l in &lower {
        lower_starts.push(lower_starts.last().unwrap() + l.len());
    }
    let layout = Layout {
        rows: Box::leak(rows.into_boxed_slice()),
        columns: Box::leak(columns.into_boxed_slice()),
        starts: Box::leak(starts.into_boxed_slice()),
        lower: Box::leak(lower.concat().into_boxed_slice()),
        lower_starts: Box::leak(lower_starts.into_boxed_slice()),
        solve: &[],
    };
    (a, layout)
}

#[test]
fn block_solutions_match_nalgebra_on_shuffled_block_triangular_matrices() {
    let partitions: [&[usize]; 4] = [&[14], &[1; 14], &[4, 1, 1, 1, 4, 1, 1, 1], &[3, 5, 2, 4]];
    for (seed, sizes) in (0..40).zip(partitions.iter().cycle()) {
        let (a, layout) = random(seed, sizes);
        let x_true: [f64; N] = core::array::from_fn(|k| (k as f64 - 6.5) / 3.0);
        let b: [f64; N] = core::array::from_fn(|i| (0..N).map(|j| a[i][j] * x_true[j]).sum());
        let mut lu = a;
        let mut perm = [0; N];
        let pivots = factor(&layout, &mut lu, &mut perm).expect("regular");
        let mut x = b;
        solve(&layout, &lu, &perm, &mut x);
        let reference = DMatrix::from_fn(N, N, |i, j| a[i][j])
            .lu()
            .solve(&DVector::from_column_slice(&b))
            .expect("regular");
        // Both solve the same regular system with partial pivoting; random blocks of size up
        // to 14 have condition numbers up to about 1e4, so the answers agree to about 1e-11.
        for k in 0..N {
            assert!(
                (x[k] - reference[k]).abs() <= 1e-9 * (1.0 + reference[k].abs()),
                "seed {seed}"
            );
        }
        assert!(pivots.smallest > 0.0 && pivots.smallest <= pivots.largest);
        // The entries below the diagonal blocks are read, not changed.
        for r in 0..N {
            for &c in &layout.lower[layout.lower_starts[r]..layout.lower_starts[r + 1]] {
                assert_eq!(lu[r][c], a[r][c]);
            }
        }
    }
}

#[test]
fn a_zero_pivot_in_a_block_is_refused() {
    let (mut a, layout) = random(7, &[1; 14]);
    // The first block's only entry.
    a[layout.rows[0]][layout.columns[0]] = 0.0;
    let mut perm = [0; N];
    assert_eq!(factor(&layout, &mut a, &mut perm), None);
    let (mut a, layout) = random(8, &[3, 5, 2, 4]);
    a[layout.rows[4]][layout.columns[3]] = f64::NAN;
    assert_eq!(factor(&layout, &mut a, &mut perm), None);
}
