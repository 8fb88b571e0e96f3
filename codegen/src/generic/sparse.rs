//! Φ_q of large mechanisms as a sparse matrix, factored by faer's sparse LU.
//!
//! Every row of Φ_q acts on at most two bodies, so it has at most 14 non-zeros whatever the
//! size of the mechanism: the dense LU's n³/3 operations and n² memory (about 100 MB and tens
//! of seconds a step at 500 bodies) buy nothing. Above [`SPARSE_FROM_UNKNOWNS`] unknowns a
//! square Φ_q is assembled straight into compressed columns (never as a dense matrix) and
//! factored by faer's simplicial left-looking LU (Gilbert–Peierls) with partial pivoting:
//!
//! - the pattern is fixed (all 7 columns of every body a row acts on, whatever their values
//!   at a configuration), so the symbolic analysis, COLAMD's fill-reducing column order, is
//!   computed once per analysis ([`Pattern::new`]) and reused by every factorisation;
//! - each factorisation chooses its row pivots by partial pivoting within the column the
//!   order brings next (the largest entry in magnitude, as the dense LU does), so a pivot
//!   never has to suit every configuration of the motion;
//! - Φ_q is balanced exactly as the dense path balances it ([`super::scaling::balanced`]:
//!   translational columns times the characteristic length, each row divided by the power of
//!   two nearest its largest entry), so both paths factor the same matrix bit for bit;
//! - the pivot ratio ρ = min |u_kk| / max |u_kk| is read from the diagonal of U, as the dense
//!   path reads it, and `singular` is decided on it with the same bound. The two ratios differ
//!   only through the column order: the dense LU eliminates the columns in their natural order,
//!   this one in COLAMD's, so the pivots (and κ̂ = 1/ρ) are those of another, equally valid,
//!   partial-pivoting LU of the same matrix. On the chains, trees and loops of the tests they
//!   agree within a factor of a few; both bound the condition number from below in the same
//!   way.
//!
//! A Φ_q with more rows than columns (redundant equations) keeps the dense path: faer's sparse
//! LU is for square matrices, and the dense path's row pivoting over every row is what picks
//! the rows the solves use at each configuration (see [`super::solve`]). Descriptions that
//! large with redundant equations pay the dense cost.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::LuError;
use faer::sparse::linalg::colamd;
use faer::sparse::linalg::lu::simplicial::{self, SimplicialLu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par};
use nalgebra::DVector;

use super::redundancy::independent;
use super::scaling::power_of_two;
use super::solve::RANK_TOLERANCE;
use super::{Equations, Preparation};
use crate::model::RowLabel;

/// A square Φ_q with at least this many unknowns is factored sparse. Measured on driven chains
/// (BENCHMARKS.md, "The generic engine, sparse"): at 10 bodies (70 unknowns) the sparse step
/// already costs about as much as the dense one, and from 20 bodies on it is several times
/// faster; below, the dense LU of a small matrix is as fast and keeps the one code path every
/// seed example has been checked with.
pub const SPARSE_FROM_UNKNOWNS: usize = 140;

/// The fixed sparsity pattern of Φ_q in compressed columns, where each row's Jacobian blocks
/// go in it, and the symbolic analysis (COLAMD's column order) of its LU.
#[derive(Clone, Debug)]
pub(crate) struct Pattern {
    rows: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// For each row and each of its two body slots, the positions in the values of the
    /// entries of the slot's 7 columns (`None` for a ground body or an empty slot).
    slots: Vec<[Option<[usize; 7]>; 2]>,
    /// The column order (forward, inverse): the bodies in COLAMD's order of the body-level
    /// pattern, each body's 7 columns in their natural order.
    order: (Vec<usize>, Vec<usize>),
}

/// Φ, ν, γ and Φ_q's values in the order of a [`Pattern`] at one evaluation.
#[derive(Clone, Debug)]
pub(crate) struct SparseSystem {
    pub(crate) phi: DVector<f64>,
    pub(crate) nu: DVector<f64>,
    pub(crate) gamma: DVector<f64>,
    pub(crate) values: Vec<f64>,
}

impl Pattern {
    /// The pattern of `eq`'s Φ_q (square) and the symbolic analysis of its LU, or `None` when
    /// Φ_q is not square or faer refuses the analysis (the dense path is used then).
    pub(crate) fn new(eq: &Equations<'_>) -> Option<Self> {
        let (m, n) = (eq.equations(), eq.unknowns());
        if m != n || n == 0 {
            return None;
        }
        // The body slots of every row, as `visit_rows` hands them: structural, whatever q.
        let q = eq.initial_estimate();
        let mut offsets = Vec::with_capacity(m);
        eq.visit_rows(&q, &DVector::zeros(n), eq.mechanism().time.start, |_, bodies, _| {
            offsets.push(bodies);
        });
        let mut entries: Vec<(usize, usize)> = Vec::with_capacity(14 * m);
        for (row, bodies) in offsets.iter().enumerate() {
            for o in bodies.iter().flatten() {
                entries.extend((0..7).map(|c| (o + c, row)));
            }
        }
        entries.sort_unstable();
        entries.dedup();
        let mut col_ptr = vec![0; n + 1];
        for &(col, _) in &entries {
            col_ptr[col + 1] += 1;
        }
        for j in 0..n {
            col_ptr[j + 1] += col_ptr[j];
        }
        let row_idx: Vec<usize> = entries.iter().map(|&(_, row)| row).collect();
        let position = |row: usize, col: usize| {
            let range = col_ptr[col]..col_ptr[col + 1];
            col_ptr[col] + row_idx[range].binary_search(&row).expect("entry in the pattern")
        };
        let slots = offsets
            .iter()
            .enumerate()
            .map(|(row, bodies)| {
                bodies.map(|o| o.map(|o| std::array::from_fn(|c| position(row, o + c))))
            })
            .collect();
        let order = body_order(&offsets, n)?;
        Some(Self { rows: m, col_ptr, row_idx, slots, order })
    }

    /// The column order Q of every factorisation.
    fn col_perm(&self) -> PermRef<'_, usize> {
        PermRef::new_checked(&self.order.0, &self.order.1, self.rows)
    }

    /// The number of unknowns (= equations).
    fn dim(&self) -> usize {
        self.rows
    }

    /// `values` with column j times `columns[j]` and then each row divided by the power of two
    /// nearest its largest entry, and those row factors: [`super::scaling::balanced`] on the
    /// compressed columns, with the same exact operations.
    pub(crate) fn balance(&self, values: &mut [f64], columns: &DVector<f64>) -> DVector<f64> {
        let mut big = vec![0.0_f64; self.rows];
        for (j, &c) in columns.iter().enumerate() {
            let range = self.col_ptr[j]..self.col_ptr[j + 1];
            for (v, &i) in values[range.clone()].iter_mut().zip(&self.row_idx[range]) {
                *v *= c;
                big[i] = big[i].max(v.abs());
            }
        }
        let rows = DVector::from_iterator(
            self.rows,
            big.iter().map(|&b| if b > 0.0 { 1.0 / power_of_two(b) } else { 1.0 }),
        );
        for (p, v) in values.iter_mut().enumerate() {
            *v *= rows[self.row_idx[p]];
        }
        rows
    }

    /// The LU with partial pivoting of the matrix with this pattern and `values`, in COLAMD's
    /// column order.
    pub(crate) fn factor(&self, values: &[f64]) -> Result<SparseLu<'_>, LuError> {
        let n = self.dim();
        let a = SparseColMatRef::new(
            SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx),
            values,
        );
        let mut lu = SimplicialLu::new();
        let mut row_fwd = vec![0; n];
        let mut row_inv = vec![0; n];
        let mut buffer =
            MemBuffer::new(simplicial::factorize_simplicial_numeric_lu_scratch::<usize, f64>(n, n));
        simplicial::factorize_simplicial_numeric_lu(
            &mut row_fwd,
            &mut row_inv,
            &mut lu,
            a,
            self.col_perm(),
            MemStack::new(&mut buffer),
        )?;
        Ok(SparseLu { pattern: self, lu, row_fwd, row_inv })
    }
}

/// The sparse LU factors P A Q = L U of one Φ_q.
pub(crate) struct SparseLu<'p> {
    pattern: &'p Pattern,
    lu: SimplicialLu<usize, f64>,
    row_fwd: Vec<usize>,
    row_inv: Vec<usize>,
}

impl SparseLu<'_> {
    /// Solves A x = b in place.
    pub(crate) fn solve_mut(&self, b: &mut DVector<f64>) {
        let n = self.pattern.dim();
        let row_perm = PermRef::new_checked(&self.row_fwd, &self.row_inv, n);
        let mut buffer =
            MemBuffer::new(simplicial::solve_in_place_scratch::<usize, f64>(n, 1, Par::Seq));
        self.lu.solve_in_place_with_conj(
            row_perm,
            self.pattern.col_perm(),
            Conj::No,
            MatMut::from_column_major_slice_mut(b.as_mut_slice(), n, 1),
            Par::Seq,
            MemStack::new(&mut buffer),
        );
    }

    /// The smallest and largest |u_kk|.
    pub(crate) fn pivot_extremes(&self) -> (f64, f64) {
        let u = self.lu.u_factor_unsorted();
        let mut extremes = (f64::INFINITY, 0.0_f64);
        for j in 0..self.pattern.dim() {
            // U's column j holds its diagonal entry (row j) among the others, unsorted.
            let rows = u.row_idx_of_col_raw(j);
            let pivot = rows.iter().position(|&i| i == j).map_or(0.0, |k| u.val_of_col(j)[k].abs());
            // NaN (a zero pivot's reciprocal spreading) counts as zero: singular.
            let pivot = if pivot.is_nan() { 0.0 } else { pivot };
            extremes = (extremes.0.min(pivot), extremes.1.max(pivot));
        }
        extremes
    }
}

/// The column order of the LU: COLAMD's fill-reducing order of the bodies, computed on the
/// body-level pattern (row k touches body b), each body's columns x, y, z, e0 … e3 kept
/// together in their natural order. Ordering whole bodies keeps the pivots of each body's
/// block those of the dense LU, which eliminates the columns body by body in the same
/// order within a body (see the module docs on κ̂); `None` if faer refuses the analysis.
fn body_order(offsets: &[[Option<usize>; 2]], n: usize) -> Option<(Vec<usize>, Vec<usize>)> {
    let bodies = n / 7;
    let mut entries: Vec<(usize, usize)> = offsets
        .iter()
        .enumerate()
        .flat_map(|(row, slots)| slots.iter().flatten().map(move |o| (o / 7, row)))
        .collect();
    entries.sort_unstable();
    entries.dedup();
    let mut col_ptr = vec![0; bodies + 1];
    for &(b, _) in &entries {
        col_ptr[b + 1] += 1;
    }
    for b in 0..bodies {
        col_ptr[b + 1] += col_ptr[b];
    }
    let row_idx: Vec<usize> = entries.iter().map(|&(_, row)| row).collect();
    let m = offsets.len();
    let structure = SymbolicSparseColMatRef::new_checked(m, bodies, &col_ptr, None, &row_idx);
    let mut fwd = vec![0; bodies];
    let mut inv = vec![0; bodies];
    let mut buffer = MemBuffer::new(colamd::order_scratch::<usize>(m, bodies, row_idx.len()));
    colamd::order(
        &mut fwd,
        &mut inv,
        structure,
        colamd::Control::default(),
        MemStack::new(&mut buffer),
    )
    .ok()?;
    let columns: Vec<usize> = fwd.iter().flat_map(|&b| 7 * b..7 * b + 7).collect();
    let mut inverse = vec![0; n];
    for (k, &c) in columns.iter().enumerate() {
        inverse[c] = k;
    }
    Some((columns, inverse))
}

impl Equations<'_> {
    /// Φ, ν, γ and the values of Φ_q in the order of `pattern` at `(q, t)` with rates `qd` (see
    /// [`Equations::evaluate`]), without a dense matrix.
    pub(crate) fn evaluate_sparse(
        &self,
        pattern: &Pattern,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        t: f64,
    ) -> SparseSystem {
        let m = self.equations();
        let mut sys = SparseSystem {
            phi: DVector::zeros(m),
            nu: DVector::zeros(m),
            gamma: DVector::zeros(m),
            values: vec![0.0; pattern.row_idx.len()],
        };
        self.visit_rows(q, qd, t, |row, _, sk| {
            sys.phi[row] = sk.v;
            sys.nu[row] = -sk.t;
            sys.gamma[row] = -sk.d2;
            for (slot, positions) in pattern.slots[row].iter().enumerate() {
                if let Some(positions) = positions {
                    for (c, &p) in positions.iter().enumerate() {
                        sys.values[p] += sk.jac[slot][c];
                    }
                }
            }
        });
        sys
    }
}

impl Equations<'_> {
    /// [`Equations::prepare`] without dense matrices, for a large square Φ_q: Newton with the
    /// sparse LU from the initial estimates at the first time point; at the assembled
    /// configuration, Φ_q has full rank when the pivot ratio of its LU in balanced units is
    /// above [`RANK_TOLERANCE`] (no body free), and the mobility is the unknowns minus the rank
    /// of the rows other than the drivers, counted by the sparse row echelon elimination of
    /// [`super::redundancy`]. `None` when Φ_q is not square, Newton does not assemble the
    /// mechanism or the LU is not clearly regular: the dense SVDs decide then.
    ///
    /// The pivot ratio bounds σ_min/σ_max only approximately, so a Φ_q within a few orders of
    /// magnitude of [`RANK_TOLERANCE`] may be called regular here where the SVD would call it
    /// rank deficient; such a configuration is refused by the analysis all the same
    /// (`singular`) if its pivot ratio falls to 1e-12.
    pub(crate) fn prepare_sparse(&self) -> Option<Preparation> {
        let pattern = Pattern::new(self)?;
        let n = self.unknowns();
        let mech = self.mechanism();
        let t0 = mech.time.start;
        let zero = DVector::zeros(n);
        let columns = self.column_scales();
        let mut q = self.initial_estimate();
        let mut assembled = false;
        for _ in 0..mech.solver.max_iterations.max(50) {
            let sys = self.evaluate_sparse(&pattern, &q, &zero, t0);
            if sys.phi.iter().chain(&sys.values).any(|x| !x.is_finite()) {
                return None;
            }
            if sys.phi.amax() <= mech.solver.tolerance {
                assembled = true;
                break;
            }
            let lu = Self::regular(&pattern, sys.values, &columns)?;
            let mut y = -sys.phi.component_mul(&lu.1);
            lu.0.solve_mut(&mut y);
            q += y.component_mul(&columns);
        }
        if !assembled {
            return None;
        }
        let sys = self.evaluate_sparse(&pattern, &q, &zero, t0);
        Self::regular(&pattern, sys.values, &columns)?;
        let mut rows = self.jacobian_rows(&q, t0);
        for row in &mut rows {
            for (c, x) in row.iter_mut() {
                *x *= columns[*c];
            }
        }
        let labels = self.labels();
        let kept: Vec<usize> =
            (0..rows.len()).filter(|&k| labels[k].kind != RowLabel::DRIVER).collect();
        let first: Vec<bool> = kept.iter().map(|&k| labels[k].is_normalisation()).collect();
        let rows: Vec<Vec<(usize, f64)>> =
            kept.iter().map(|&k| std::mem::take(&mut rows[k])).collect();
        let rank_nd = independent(&rows, n, &first).len();
        let redundant = self.redundant_rows(&q, t0);
        Some(Preparation {
            assembled,
            q,
            rank: n,
            mobility: n - rank_nd.min(n),
            redundant,
            free_bodies: Vec::new(),
        })
    }

    /// The LU of Φ_q (`values` of `pattern`) in balanced units and its row factors, when its
    /// pivot ratio is above [`RANK_TOLERANCE`].
    fn regular<'p>(
        pattern: &'p Pattern,
        mut values: Vec<f64>,
        columns: &DVector<f64>,
    ) -> Option<(SparseLu<'p>, DVector<f64>)> {
        let rows = pattern.balance(&mut values, columns);
        let lu = pattern.factor(&values).ok()?;
        let (min, max) = lu.pivot_extremes();
        (min > RANK_TOLERANCE * max).then_some((lu, rows))
    }
}
