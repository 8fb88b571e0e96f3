//! Row re-selection for mechanisms whose square system leaves rows out as redundant
//! ([`Mechanism::LEFT_OUT`]): which rows the solvers solve with.
//!
//! A redundant mechanism's generated system keeps N of its N + L rows, chosen at one
//! configuration; which rows depend on the others can change along the motion (the Bennett
//! linkage at θ1 = 0 and π), where the kept rows lose rank while the whole stack does not.
//! [`select`] then factors the whole (N + L) × N stack by LU with row pivoting, equilibrated
//! by powers of two (columns, then rows, as [`Factors::factor_dense_equilibrated`] scales),
//! and keeps the N rows it pivots on: a kept row stays while its pivot is at least
//! [`PREFERENCE`] of the column's largest candidate (threshold pivoting that prefers the kept
//! rows, in their order, then the left-out rows in theirs). The [`Selection`] it
//! returns says which left-out row stands in for which kept row, and [`Swapped`] is the
//! mechanism with those rows substituted: a square system like any other, factored by dense
//! LU with partial pivoting. Only a stack that loses column rank is refused as singular.
//! The solvers choose again where the rows in force degenerate ([`RESELECT_DROP`]).
//!
//! [`Factors::factor_dense_equilibrated`]: crate::factors::Factors::factor_dense_equilibrated

#[cfg(test)]
mod tests;

use crate::factors::reciprocal_power_of_two;
use crate::lu::Singular;
use crate::{Mechanism, Real};

/// The most left-out rows that can stand in for kept ones: the solvers keep the
/// [`Selection`] in fixed storage and substitute rows through arrays of this many rows.
pub const MAX_LEFT_OUT: usize = 8;

/// The solvers choose their rows again when the pivot ratio of the rows in force falls below
/// this fraction of the largest it had since they were chosen (or to within
/// [`crate::step::STRUCTURED_MARGIN`] of the singularity bound): a tenfold fall, the step
/// control's sign of a configuration where a matrix loses rank ([`crate::step::SINGULAR_DROP`]).
/// Rows that lose rank while the stack does not would otherwise be kept up to a condition the
/// consistency check of the rows left aside cannot afford (a rate equation of the Bennett
/// linkage next to θ1 = 0 missed by 2.9e-6 of its scale at a ratio 26 times below the step's
/// start); rows that stay the stack's choice cost one more factorisation per tenfold fall.
pub const RESELECT_DROP: f64 = 0.1;

/// A candidate pivot of an earlier row of the stack (the kept rows first) is taken when it is
/// at least this fraction of the column's largest: the solvers choose rows where those in force
/// degenerate, and a kept row that is within a factor of 2 of the best costs at most that
/// factor in condition, while 0.1 (the static orders' threshold, [`crate::lu::MAX_MULTIPLIER`]) kept
/// rows of the Bennett linkage next to θ1 = π whose rate equations then missed the consistency
/// check of the rows left aside (by 1.3e-6 of their scale, predictor off).
pub const PREFERENCE: f64 = 0.5;

/// No kept row: the left-out row is not used.
const UNUSED: usize = usize::MAX;

/// Which left-out rows replace which kept rows of a square system.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Selection {
    /// For left-out row k, the kept row it stands in for, or [`UNUSED`].
    replaces: [usize; MAX_LEFT_OUT],
}

impl Default for Selection {
    fn default() -> Self {
        Selection::KEPT
    }
}

impl Selection {
    /// The kept rows, as generated.
    pub const KEPT: Selection = Selection { replaces: [UNUSED; MAX_LEFT_OUT] };

    /// Whether some left-out row stands in for a kept one.
    #[must_use]
    pub fn is_swapped(&self) -> bool {
        self.replaces.iter().any(|&r| r != UNUSED)
    }

    /// The kept row that left-out row `k` stands in for, if any.
    #[must_use]
    pub fn replaces(&self, k: usize) -> Option<usize> {
        self.replaces.get(k).copied().filter(|&r| r != UNUSED)
    }
}

/// The number of left-out rows of `M` that a [`Selection`] can use.
const fn usable<const N: usize, R: Real, M: Mechanism<N, R>>() -> usize {
    if M::LEFT_OUT < MAX_LEFT_OUT { M::LEFT_OUT } else { MAX_LEFT_OUT }
}

/// Row `i` of the stack: kept rows in `jac`, left-out ones after them in `extra`.
fn row<'a, R, const N: usize>(
    jac: &'a mut [[R; N]; N],
    extra: &'a mut [[R; N]; MAX_LEFT_OUT],
    i: usize,
) -> &'a mut [R; N] {
    if i < N { &mut jac[i] } else { &mut extra[i - N] }
}

/// Swaps rows `a` < `b` of the stack.
fn swap_rows<R, const N: usize>(
    jac: &mut [[R; N]; N],
    extra: &mut [[R; N]; MAX_LEFT_OUT],
    a: usize,
    b: usize,
) {
    match (a < N, b < N) {
        (true, true) => jac.swap(a, b),
        (true, false) => core::mem::swap(&mut jac[a], &mut extra[b - N]),
        _ => extra.swap(a - N, b - N),
    }
}

/// The rows to solve with at (q, t): the N pivot rows of the row-pivoted LU of the whole
/// equilibrated stack (see the module docs). `jac` is scratch: it holds no factors afterwards.
///
/// # Errors
///
/// [`Singular::SmallPivot`] when the smallest pivot of the stack's LU is at most `ratio` times
/// its largest (the whole stack loses column rank), [`Singular::NonFinite`] for a NaN or an
/// infinity.
pub fn select<R: Real, M: Mechanism<N, R>, const N: usize>(
    mechanism: &M,
    q: &[R; N],
    t: R,
    jac: &mut [[R; N]; N],
    ratio: R,
) -> Result<Selection, Singular<R>> {
    let left = usable::<N, R, M>();
    let m = N + left;
    mechanism.jacobian(q, t, jac);
    let mut extra = [[R::ZERO; N]; MAX_LEFT_OUT];
    let mut phi = [R::ZERO; MAX_LEFT_OUT];
    mechanism.left_out_residual_jacobian(q, t, &mut phi[..left], &mut extra[..left]);
    // Equilibration by powers of two: columns to a largest entry near 1, then rows.
    let mut cols = [R::ONE; N];
    for (j, c) in cols.iter_mut().enumerate() {
        let big = (0..m).fold(R::ZERO, |b, i| b.max(row(jac, &mut extra, i)[j].abs()));
        *c = reciprocal_power_of_two(big);
    }
    for i in 0..m {
        let r = row(jac, &mut extra, i);
        let big = r.iter().zip(&cols).fold(R::ZERO, |b, (&a, &c)| b.max((a * c).abs()));
        let s = reciprocal_power_of_two(big);
        for (a, &c) in r.iter_mut().zip(&cols) {
            *a = *a * c * s;
        }
    }
    // Which row of the stack sits at each position.
    let mut origin = [0usize; N];
    let mut extra_origin = [0usize; MAX_LEFT_OUT];
    for (k, o) in origin.iter_mut().enumerate() {
        *o = k;
    }
    for (k, o) in extra_origin.iter_mut().enumerate() {
        *o = N + k;
    }
    let origin_of = |origin: &[usize; N], extra_origin: &[usize; MAX_LEFT_OUT], i: usize| {
        if i < N { origin[i] } else { extra_origin[i - N] }
    };
    let threshold = R::from_f64(PREFERENCE);
    let (mut smallest, mut largest) = (R::INFINITY, R::ZERO);
    let mut small_column = 0;
    for c in 0..N {
        let mut big = R::ZERO;
        for i in c..m {
            let a = row(jac, &mut extra, i)[c].abs();
            if !a.is_finite() {
                return Err(Singular::NonFinite { column: c });
            }
            big = big.max(a);
        }
        // The candidate of the earliest row of the stack among those within the threshold.
        let mut pick = c;
        let mut pick_origin = usize::MAX;
        for i in c..m {
            let a = row(jac, &mut extra, i)[c].abs();
            let o = origin_of(&origin, &extra_origin, i);
            if a > R::ZERO && a >= threshold * big && o < pick_origin {
                (pick, pick_origin) = (i, o);
            }
        }
        if pick != c {
            swap_rows(jac, &mut extra, c, pick);
            let (a, b) = (origin_of(&origin, &extra_origin, c), pick_origin);
            let mut set = |i: usize, v: usize| {
                if i < N { origin[i] = v } else { extra_origin[i - N] = v }
            };
            set(c, b);
            set(pick, a);
        }
        let pivot_row = *row(jac, &mut extra, c);
        let pivot = pivot_row[c];
        if pivot.abs() < smallest {
            (smallest, small_column) = (pivot.abs(), c);
        }
        largest = largest.max(pivot.abs());
        if pivot == R::ZERO {
            continue;
        }
        for i in c + 1..m {
            let r = row(jac, &mut extra, i);
            let l = r[c] / pivot;
            if l != R::ZERO {
                for (a, &p) in r[c + 1..].iter_mut().zip(&pivot_row[c + 1..]) {
                    *a -= l * p;
                }
            }
        }
    }
    if N > 0 && (smallest <= ratio * largest || smallest.is_nan()) {
        return Err(Singular::SmallPivot { column: small_column, pivot: smallest, largest });
    }
    // Kept rows left aside, each replaced by a selected left-out row, both in row order.
    let (mut aside, mut chosen) = ([UNUSED; MAX_LEFT_OUT], [UNUSED; MAX_LEFT_OUT]);
    for (slot, o) in aside.iter_mut().zip(extra_origin[..left].iter().filter(|&&o| o < N)) {
        *slot = *o;
    }
    for (slot, o) in chosen.iter_mut().zip(origin.iter().filter(|&&o| o >= N)) {
        *slot = *o - N;
    }
    aside.sort_unstable();
    chosen.sort_unstable();
    let mut selection = Selection::KEPT;
    for (&k, &r) in chosen.iter().zip(&aside) {
        if k != UNUSED && r != UNUSED {
            selection.replaces[k] = r;
        }
    }
    Ok(selection)
}

/// A mechanism with the left-out rows of a [`Selection`] in place of the kept rows they stand
/// in for: every evaluation writes the kept rows, then overwrites the replaced ones. It has no
/// static pivot orders and no blocks (those belong to the kept rows), so the solvers factor it
/// by dense LU with partial pivoting.
pub struct Swapped<'a, M> {
    /// The mechanism.
    pub mechanism: &'a M,
    /// The rows in force.
    pub selection: &'a Selection,
}

impl<M> Swapped<'_, M> {
    /// Overwrites the replaced rows of `phi` (Φ) and `jac` (Φ_q).
    fn patch<R: Real, const N: usize>(
        &self,
        q: &[R; N],
        t: R,
        phi: Option<&mut [R; N]>,
        jac: Option<&mut [[R; N]; N]>,
    ) where
        M: Mechanism<N, R>,
    {
        let left = usable::<N, R, M>();
        let mut p = [R::ZERO; MAX_LEFT_OUT];
        let mut j = [[R::ZERO; N]; MAX_LEFT_OUT];
        self.mechanism.left_out_residual_jacobian(q, t, &mut p[..left], &mut j[..left]);
        let (mut phi, mut jac) = (phi, jac);
        for k in 0..left {
            if let Some(r) = self.selection.replaces(k) {
                if let Some(phi) = phi.as_deref_mut() {
                    phi[r] = p[k];
                }
                if let Some(jac) = jac.as_deref_mut() {
                    jac[r] = j[k];
                }
            }
        }
    }

    /// Overwrites the replaced entries of `b` with those of the left-out rows in `x`.
    fn patch_vector<R: Real, const N: usize>(&self, x: &[R; MAX_LEFT_OUT], b: &mut [R; N])
    where
        M: Mechanism<N, R>,
    {
        for (k, &v) in x.iter().enumerate().take(usable::<N, R, M>()) {
            if let Some(r) = self.selection.replaces(k) {
                b[r] = v;
            }
        }
    }
}

impl<M: Mechanism<N, R>, const N: usize, R: Real> Mechanism<N, R> for Swapped<'_, M> {
    fn residual(&self, q: &[R; N], t: R, phi: &mut [R; N]) {
        self.mechanism.residual(q, t, phi);
        self.patch(q, t, Some(phi), None);
    }
    fn jacobian(&self, q: &[R; N], t: R, jac: &mut [[R; N]; N]) {
        self.mechanism.jacobian(q, t, jac);
        self.patch(q, t, None, Some(jac));
    }
    fn residual_jacobian(&self, q: &[R; N], t: R, phi: &mut [R; N], jac: &mut [[R; N]; N]) {
        self.mechanism.residual_jacobian(q, t, phi, jac);
        self.patch(q, t, Some(phi), Some(jac));
    }
    fn velocity_rhs(&self, q: &[R; N], t: R, nu: &mut [R; N]) {
        self.mechanism.velocity_rhs(q, t, nu);
        let mut x = [R::ZERO; MAX_LEFT_OUT];
        self.mechanism.left_out_velocity_rhs(q, t, &mut x[..usable::<N, R, M>()]);
        self.patch_vector(&x, nu);
    }
    fn acceleration_rhs(&self, q: &[R; N], qd: &[R; N], t: R, gamma: &mut [R; N]) {
        self.mechanism.acceleration_rhs(q, qd, t, gamma);
        let mut x = [R::ZERO; MAX_LEFT_OUT];
        self.mechanism.left_out_acceleration_rhs(q, qd, t, &mut x[..usable::<N, R, M>()]);
        self.patch_vector(&x, gamma);
    }
    fn normalize(&self, q: &mut [R; N]) {
        self.mechanism.normalize(q);
    }
}
