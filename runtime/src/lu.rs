//! LU factorisation with partial (row) pivoting, in place on `[[R; N]; N]` (`R` is `f64` or
//! `f32`, see [`Real`]).
//!
//! [`factor`] overwrites a row-major matrix A with its factors and fills a permutation `perm`
//! such that P·A = L·U, where row `i` of P·A is row `perm[i]` of A, L is unit lower triangular
//! (its multipliers are stored below the diagonal, its unit diagonal is implied) and U is upper
//! triangular (stored on and above the diagonal).
//! [`solve`] then solves A x = b in place with the factors, as often as needed.
//!
//! A matrix is refused as [`Singular`] when its smallest pivot is tiny next to its largest one:
//! min |u_kk| ≤ ratio · max |u_kk|, with [`DEFAULT_PIVOT_RATIO`] = 1e-12 in `f64`
//! ([`Real::DEFAULT_PIVOT_RATIO`], 1e-5 in `f32`) unless the caller chooses another ratio
//! through [`factor_with_ratio`].
//! The test is relative, so it does not depend on units: scaling A by any nonzero factor gives
//! the same verdict.
//! A NaN or an infinity met during elimination is refused too.
//!
//! ```
//! use runtime::lu;
//!
//! // x + 2y = 5 and 3x + 4y = 11, so x = 1 and y = 2.
//! let mut a = [[1.0_f64, 2.0], [3.0, 4.0]];
//! let mut perm = [0; 2];
//! let pivots = lu::factor(&mut a, &mut perm)?;
//! assert_eq!((perm, pivots.largest), ([1, 0], 3.0));
//! let mut b = [5.0, 11.0];
//! lu::solve(&a, &perm, &mut b);
//! assert!((b[0] - 1.0).abs() < 1e-15 && (b[1] - 2.0).abs() < 1e-15);
//!
//! let mut twice = [[1.0, 2.0], [2.0, 4.0]];
//! assert_eq!(lu::factor(&mut twice, &mut perm).unwrap_err().column(), 1);
//! # Ok::<(), lu::Singular>(())
//! ```

#[cfg(test)]
mod tests;

use core::fmt;

use crate::Real;

/// The default pivot ratio: a matrix whose smallest |pivot| is at most 1e-12 of its largest is
/// singular.
///
/// Double precision carries about 16 digits, so a solve with such pivots would keep at most
/// about 4 correct digits.
pub const DEFAULT_PIVOT_RATIO: f64 = <f64 as Real>::DEFAULT_PIVOT_RATIO;

/// The largest |multiplier| a static pivot order may produce: threshold partial pivoting with
/// a fraction of 0.1.
///
/// A mechanism's structured factorisation ([`Mechanism::factor_structured`]) accepts a pivot
/// only when its magnitude is at least 0.1 of the largest entry below it in its column of the
/// active submatrix, that is when every multiplier l = a / pivot of that column has |l| ≤ 10.
/// Partial pivoting is the fraction 1 (|l| ≤ 1); 0.1 is the usual default of threshold
/// pivoting in sparse codes (UMFPACK, MA48 use 0.1 and 0.01), which bounds the growth of the
/// entries by 11 per step that touches them and, on mechanism Jacobians of a few dozen rows,
/// keeps solutions within a few units of round-off of partial pivoting's (see the tests of the
/// generated modules), while a fixed order stays valid over a wide range of configurations.
///
/// [`Mechanism::factor_structured`]: crate::Mechanism::factor_structured
pub const MAX_MULTIPLIER: f64 = 10.0;

/// The smallest and largest |pivot| of a successful factorisation.
///
/// Their ratio, `smallest / largest`, is a cheap lower bound on the conditioning: when it is
/// small the matrix is close to singular.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PivotInfo<R = f64> {
    /// The smallest |u_kk|.
    pub smallest: R,
    /// The largest |u_kk|.
    pub largest: R,
}

/// Why a matrix could not be factored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Singular<R = f64> {
    /// The pivot of column `column` is too small: |pivot| ≤ ratio · `largest`.
    ///
    /// Two equal rows, for example, give a zero pivot, and so does the Jacobian of a
    /// mechanism at a dead centre.
    SmallPivot {
        /// The elimination step, which is also the column of the pivot.
        column: usize,
        /// The |pivot| of that column.
        pivot: R,
        /// The largest |pivot| of the columns factored so far, or of the whole matrix when the
        /// small pivot was found only at the end.
        largest: R,
    },
    /// Elimination step `column` met a NaN or an infinity, for example an entry computed as
    /// `sqrt(-1.0)`.
    NonFinite {
        /// The elimination step at which the entry was met.
        column: usize,
    },
}

impl<R> Singular<R> {
    /// The elimination step (and column) at which the matrix was refused.
    #[must_use]
    pub fn column(&self) -> usize {
        match *self {
            Singular::SmallPivot { column, .. } | Singular::NonFinite { column } => column,
        }
    }
}

impl<R: Real> fmt::Display for Singular<R> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Singular::SmallPivot { column, pivot, largest } => write!(
                f,
                "singular matrix: pivot {pivot:e} in column {column} against largest pivot {largest:e}"
            ),
            Singular::NonFinite { column } => {
                write!(f, "non-finite entry met at elimination step {column}")
            }
        }
    }
}

impl<R: Real> core::error::Error for Singular<R> {}

/// Factors `a` in place with partial pivoting, using [`Real::DEFAULT_PIVOT_RATIO`]
/// ([`DEFAULT_PIVOT_RATIO`] for `f64`).
///
/// Same as [`factor_with_ratio`]`(a, perm, R::DEFAULT_PIVOT_RATIO)`.
///
/// # Errors
///
/// Returns [`Singular`] when the smallest |pivot| is at most 1e-12 of the largest (1e-5 in
/// `f32`), or when a NaN or an infinity is met; `a` and `perm` then hold a partial
/// factorisation.
pub fn factor<R: Real, const N: usize>(
    a: &mut [[R; N]; N],
    perm: &mut [usize; N],
) -> Result<PivotInfo<R>, Singular<R>> {
    factor_with_ratio(a, perm, R::DEFAULT_PIVOT_RATIO)
}

/// Factors `a` in place with partial pivoting: afterwards P·A = L·U (see the module docs for
/// the layout), and `perm` describes P.
///
/// At each step the pivot is the entry of largest magnitude in the remaining part of the column
/// (the first one on ties).
/// Rows whose multiplier is exactly zero are skipped, which pays off on the sparse Jacobians of
/// mechanisms.
///
/// # Errors
///
/// Returns [`Singular::SmallPivot`] when min |pivot| ≤ `ratio` · max |pivot| (an exact zero
/// pivot included, whatever `ratio`), and [`Singular::NonFinite`] when a NaN or an infinity is
/// met.
/// On error, `a` and `perm` hold a partial factorisation and must not be passed to [`solve`].
pub fn factor_with_ratio<R: Real, const N: usize>(
    a: &mut [[R; N]; N],
    perm: &mut [usize; N],
    ratio: R,
) -> Result<PivotInfo<R>, Singular<R>> {
    for (i, p) in perm.iter_mut().enumerate() {
        *p = i;
    }
    let mut smallest = R::INFINITY;
    let mut smallest_column = 0;
    let mut largest = R::ZERO;
    for k in 0..N {
        // Choose the pivot row: the largest |a_ik| for i ≥ k.
        // Every entry of the column is checked, so a NaN cannot hide behind a comparison.
        let mut pivot_row = k;
        let mut pivot = R::ZERO;
        for (i, row) in a.iter().enumerate().skip(k) {
            let v = row[k].abs();
            if !v.is_finite() {
                return Err(Singular::NonFinite { column: k });
            }
            if v > pivot {
                pivot = v;
                pivot_row = i;
            }
        }
        if pivot_row != k {
            a.swap(pivot_row, k);
            perm.swap(pivot_row, k);
        }
        // The rest of row k is now final (it is row k of U); elimination below never reads an
        // entry that has not passed one of these two checks.
        if a[k][k + 1..].iter().any(|x| !x.is_finite()) {
            return Err(Singular::NonFinite { column: k });
        }
        largest = largest.max(pivot);
        if pivot == R::ZERO || pivot <= ratio * largest {
            return Err(Singular::SmallPivot { column: k, pivot, largest });
        }
        if pivot < smallest {
            smallest = pivot;
            smallest_column = k;
        }

        let (upper, lower) = a.split_at_mut(k + 1);
        let pivot_row = &upper[k];
        let u_kk = pivot_row[k];
        for row in lower {
            if row[k] == R::ZERO {
                continue;
            }
            // |l| ≤ 1 because the pivot is the largest entry of its column.
            let l = row[k] / u_kk;
            row[k] = l;
            for (x, &u) in row[k + 1..].iter_mut().zip(&pivot_row[k + 1..]) {
                *x -= l * u;
            }
        }
    }
    // A tiny early pivot passes the running test above while the largest pivot is still to come.
    if smallest <= ratio * largest {
        return Err(Singular::SmallPivot { column: smallest_column, pivot: smallest, largest });
    }
    Ok(PivotInfo { smallest, largest })
}

/// Solves A x = b in place, where `lu` and `perm` come from a successful [`factor`] of A.
///
/// On return `b` holds x.
/// Applies the permutation, then forward substitution with L and back substitution with U; each
/// row is one dot product over contiguous slices.
/// Costs N² multiply-adds and one `[R; N]` of stack.
/// A NaN or an infinity in `b` gives NaN or infinity in x.
/// Nothing here panics: an index in `perm` out of range, which [`factor`] never produces, gives
/// NaN in x.
pub fn solve<R: Real, const N: usize>(lu: &[[R; N]; N], perm: &[usize; N], b: &mut [R; N]) {
    let mut x = [R::ZERO; N];
    for (xi, &p) in x.iter_mut().zip(perm) {
        *xi = b.get(p).copied().unwrap_or(R::NAN);
    }
    // Forward: L y = P b, with L's unit diagonal implied.
    for i in 1..N {
        let dot: R = lu[i][..i].iter().zip(&x[..i]).map(|(&l, &y)| l * y).sum();
        x[i] -= dot;
    }
    // Back: U x = y.
    for i in (0..N).rev() {
        let row = &lu[i];
        let dot: R = row[i + 1..].iter().zip(&x[i + 1..]).map(|(&u, &x)| u * x).sum();
        x[i] = (x[i] - dot) / row[i];
    }
    *b = x;
}
