//! LU of a block-lower-triangular Φ_q: partial pivoting inside each diagonal block, block
//! forward substitution across them.
//!
//! A generated mechanism whose Φ_q is block lower triangular (see `codegen::blocks`) describes
//! its blocks by a [`Layout`]: the rows and columns of every diagonal block, in solve order,
//! and for every row the columns of earlier blocks it involves. [`factor`] factors each
//! diagonal block in place by LU with partial pivoting within the block, so a block's pivots
//! never depend on another block's configuration, and leaves the entries below the diagonal
//! blocks as they are; [`solve`] solves block after block, moving the known unknowns of earlier
//! blocks to the right-hand side. The cost is the sum of the blocks' cubes plus the entries
//! below them, linear in the size of a chain of bodies.
//!
//! # Packed storage
//!
//! The functions of this module keep Φ_q at `jac[i][j]` in the solver's `N × N` storage.
//! A mechanism with [`Mechanism::PACKED_BLOCKS`] keeps what its block methods write and read
//! at the front of that storage instead, read as one flat array of N² entries row after row
//! (`jac.as_flattened()`): position after position of the layout (blocks in solve order),
//! the entries of the row at position p are the columns of its diagonal block in the
//! layout's order, then its columns of earlier blocks ([`Layout::lower`], in that order).
//! Block b's entries are contiguous, from the sum of [`packed_block_len`] over the blocks
//! before it, and the whole form takes [`packed_len`] entries: a step touches those, a few
//! pages, instead of a few entries in each of N rows of N spread over N² entries (1.4 MB for
//! ten 6R arms). The rest of the storage is only written by the dense fallbacks, which
//! evaluate Φ_q in full.
//!
//! [`Mechanism::PACKED_BLOCKS`]: crate::Mechanism::PACKED_BLOCKS

#[cfg(test)]
mod tests;

use crate::Real;
use crate::lu::{PivotInfo, Singular};

/// The block-lower-triangular form of a Jacobian, as index tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// The row at each position, blocks in solve order.
    pub rows: &'static [usize],
    /// The column at each position, blocks in solve order.
    pub columns: &'static [usize],
    /// Block b holds the positions `starts[b]..starts[b + 1]`.
    pub starts: &'static [usize],
    /// Row r involves, outside its own block, the columns `lower[lower_starts[r]..lower_starts[r + 1]]`
    /// (all of earlier blocks).
    pub lower: &'static [usize],
    /// See [`Layout::lower`]; one entry per row, and one more.
    pub lower_starts: &'static [usize],
    /// For every block, how Newton block by block ([`crate::newton`]) solves it. Empty when
    /// the solvers do not run Newton block by block.
    pub solve: &'static [Solve],
}

/// The entries of block `b`'s rows in packed storage (see the module docs): per row, the
/// size of the block and its entries below the blocks.
#[must_use]
pub fn packed_block_len(layout: &Layout, b: usize) -> usize {
    let (start, end) = (layout.starts[b], layout.starts[b + 1]);
    let below = |r: usize| layout.lower_starts[r + 1] - layout.lower_starts[r];
    layout.rows[start..end].iter().map(|&r| end - start + below(r)).sum()
}

/// The entries of Φ_q in packed storage (see the module docs): the sum of
/// [`packed_block_len`] over the blocks.
#[must_use]
pub fn packed_len(layout: &Layout) -> usize {
    (0..layout.starts.len().saturating_sub(1)).map(|b| packed_block_len(layout, b)).sum()
}

/// How Newton block by block solves one block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Solve {
    /// Newton on the block's own unknowns (a closed loop).
    Newton,
    /// One equation affine in its one unknown (a body's x held by a joint to a known point):
    /// q_k ← q_k − Φ_r / (∂Φ_r/∂q_k), one evaluation, no iteration.
    Affine,
    /// Straight-line code of the mechanism's own, [`Mechanism::closed_form_block`]
    /// (the Euler parameters of a body turned by a driven revolute about a known body,
    /// [`crate::rotation`]), no iteration; Newton only when it finds no real solution.
    ///
    /// [`Mechanism::closed_form_block`]: crate::Mechanism::closed_form_block
    Explicit,
}

/// Factors the diagonal blocks of `jac` in place (see the module docs); `perm[i]` becomes the
/// row whose factors sit at position i.
///
/// Reads every entry of the diagonal blocks (the structural zeros in them must be 0) and none
/// elsewhere. Returns the smallest and largest |pivot|, or `None` when a pivot is 0 or an entry
/// is not finite; `jac` then holds a partial factorisation.
pub fn factor<R: Real, const N: usize>(
    layout: &Layout,
    jac: &mut [[R; N]; N],
    perm: &mut [usize; N],
) -> Option<PivotInfo<R>> {
    let (mut smallest, mut largest) = (R::INFINITY, R::ZERO);
    for b in 0..layout.starts.len() - 1 {
        let p = factor_block(layout, b, jac, perm, R::ZERO).ok()?;
        if p.smallest < smallest {
            smallest = p.smallest;
        }
        largest = largest.max(p.largest);
    }
    Some(PivotInfo { smallest, largest })
}

/// Factors diagonal block `b` of `jac` in place by LU with partial pivoting inside the block,
/// its row order into `perm` at the block's positions, as [`factor`] does for every block.
///
/// # Errors
///
/// [`Singular::SmallPivot`] when a pivot is 0 or the smallest |pivot| ≤ `ratio` · the
/// largest, or [`Singular::NonFinite`], the column counted within the block; `jac` then holds
/// a partial factorisation.
pub fn factor_block<R: Real, const N: usize>(
    layout: &Layout,
    b: usize,
    jac: &mut [[R; N]; N],
    perm: &mut [usize; N],
    ratio: R,
) -> Result<PivotInfo<R>, Singular<R>> {
    let (mut smallest, mut largest, mut smallest_at) = (R::INFINITY, R::ZERO, 0);
    let (start, end) = (layout.starts[b], layout.starts[b + 1]);
    perm[start..end].copy_from_slice(&layout.rows[start..end]);
    for k in start..end {
        let ck = layout.columns[k];
        let mut at = k;
        let mut pivot = R::ZERO;
        for i in k..end {
            let v = jac[perm[i]][ck].abs();
            if !v.is_finite() {
                return Err(Singular::NonFinite { column: k - start });
            }
            if v > pivot {
                pivot = v;
                at = i;
            }
        }
        if pivot == R::ZERO {
            return Err(Singular::SmallPivot { column: k - start, pivot, largest });
        }
        perm.swap(k, at);
        if pivot < smallest {
            smallest = pivot;
            smallest_at = k - start;
        }
        largest = largest.max(pivot);
        let rk = perm[k];
        let inverse = R::ONE / jac[rk][ck];
        for &ri in &perm[k + 1..end] {
            let l = jac[ri][ck] * inverse;
            jac[ri][ck] = l;
            if l != R::ZERO {
                for &cj in &layout.columns[k + 1..end] {
                    let u = jac[rk][cj];
                    jac[ri][cj] -= l * u;
                }
            }
        }
    }
    if smallest <= ratio * largest {
        return Err(Singular::SmallPivot { column: smallest_at, pivot: smallest, largest });
    }
    Ok(PivotInfo { smallest, largest })
}

/// Solves diagonal block `b` alone, D_b x = r, with the factors [`factor_block`] left in `lu`
/// and `perm`: r is read by row from `rhs`, x written in the order of the block's columns
/// into `x` (at least as long as the block).
pub fn solve_block<R: Real, const N: usize>(
    layout: &Layout,
    b: usize,
    lu: &[[R; N]; N],
    perm: &[usize; N],
    rhs: &[R; N],
    x: &mut [R],
) {
    let (start, end) = (layout.starts[b], layout.starts[b + 1]);
    let columns = &layout.columns[start..end];
    for i in 0..columns.len() {
        let r = perm[start + i];
        let mut y = rhs[r];
        for (j, &cj) in columns[..i].iter().enumerate() {
            y -= lu[r][cj] * x[j];
        }
        x[i] = y;
    }
    for i in (0..columns.len()).rev() {
        let r = perm[start + i];
        let mut v = x[i];
        for (j, &cj) in columns.iter().enumerate().skip(i + 1) {
            v -= lu[r][cj] * x[j];
        }
        x[i] = v / lu[r][columns[i]];
    }
}

/// Solves Φ_q x = b in place (b by row in, x by column out) with the factors [`factor`] left in
/// `lu` and `perm`, and the entries below the diagonal blocks of Φ_q, which it did not touch.
pub fn solve<R: Real, const N: usize>(
    layout: &Layout,
    lu: &[[R; N]; N],
    perm: &[usize; N],
    b: &mut [R; N],
) {
    let rhs = *b;
    for bounds in layout.starts.windows(2) {
        let (start, end) = (bounds[0], bounds[1]);
        let columns = &layout.columns[start..end];
        // y = L⁻¹ P (b − Φ_q,lower x_earlier), kept in the block's own columns of b.
        for (i, &ci) in columns.iter().enumerate() {
            let r = perm[start + i];
            let mut y = rhs[r];
            for &c in &layout.lower[layout.lower_starts[r]..layout.lower_starts[r + 1]] {
                y -= lu[r][c] * b[c];
            }
            for &cj in &columns[..i] {
                y -= lu[r][cj] * b[cj];
            }
            b[ci] = y;
        }
        // x = U⁻¹ y.
        for (i, &ci) in columns.iter().enumerate().rev() {
            let r = perm[start + i];
            let mut x = b[ci];
            for &cj in &columns[i + 1..] {
                x -= lu[r][cj] * b[cj];
            }
            b[ci] = x / lu[r][ci];
        }
    }
}
