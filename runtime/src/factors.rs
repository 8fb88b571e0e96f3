//! [`Factors`]: the factorisation of Φ_q kept in a solver's Jacobian storage, by a
//! mechanism's static pivot orders when one passes its guard, else by dense LU with partial
//! pivoting.
//!
//! Generated mechanisms know the structure of Φ_q and emit straight-line factor and solve
//! functions for a few static pivot orders ([`Mechanism::factor_structured`]).
//! A static order is refused at a configuration where one of its pivots is small next to the
//! entries below it ([`lu::MAX_MULTIPLIER`]); [`Factors::factor`] then evaluates Φ_q again and
//! tries the mechanism's other orders, starting from the one that last succeeded, and if none
//! passes it evaluates Φ_q in full again and factors it by [`lu::factor_with_ratio`].
//! Either way the factors are refused as singular by the same test as dense LU: the smallest
//! |pivot| must exceed `ratio` times the largest; a static order that fails it falls back to
//! dense LU, whose verdict is final.

#[cfg(test)]
mod tests;

use crate::lu::{self, PivotInfo, Singular};
use crate::{Mechanism, Real};

/// How often each kind of factorisation was used, for tests and benchmarks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FactorCounts {
    /// Factorisations done with a static pivot order.
    pub structured: u64,
    /// Factorisations done by dense LU (all of them for mechanisms without static orders).
    pub dense: u64,
    /// Static orders tried and refused (by the pivot guard or the pivot ratio).
    pub refused: u64,
}

/// What Newton block by block did ([`Mechanism::BLOCK_NEWTON`]), for tests and benchmarks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BlockCounts {
    /// Blocks solved in closed form (one affine equation in one unknown, or a body's
    /// orientation about a driven axis): no iteration.
    pub closed_form: u64,
    /// Blocks solved by Newton on their own unknowns.
    pub implicit: u64,
    /// Newton steps (chord steps included) taken by those blocks, in total.
    pub iterations: u64,
}

/// Which factors the Jacobian storage holds and how to solve with them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Held {
    /// Nothing usable: no factorisation yet, or the last one failed.
    Nothing,
    /// The factors of static order `k`.
    Structured(usize),
    /// Dense LU factors with the row permutation in [`Factors::perm`].
    Dense,
    /// Block factors ([`Mechanism::factor_blocks`]) with their pivoting in [`Factors::perm`].
    Blocks,
}

/// The pivoting side of a factorisation of Φ_q held in a separate `[[R; N]; N]`.
///
/// ```
/// use runtime::Mechanism;
/// use runtime::factors::Factors;
///
/// // Φ = (x + 2y − 5, 3x + 4y − 11): no static orders, so dense LU.
/// struct Pair;
/// impl Mechanism<2> for Pair {
///     fn residual(&self, q: &[f64; 2], _t: f64, phi: &mut [f64; 2]) {
///         *phi = [q[0] + 2.0 * q[1] - 5.0, 3.0 * q[0] + 4.0 * q[1] - 11.0];
///     }
///     fn jacobian(&self, _q: &[f64; 2], _t: f64, jac: &mut [[f64; 2]; 2]) {
///         *jac = [[1.0, 2.0], [3.0, 4.0]];
///     }
///     fn velocity_rhs(&self, _q: &[f64; 2], _t: f64, nu: &mut [f64; 2]) {
///         *nu = [0.0; 2];
///     }
///     fn acceleration_rhs(&self, _q: &[f64; 2], _qd: &[f64; 2], _t: f64, g: &mut [f64; 2]) {
///         *g = [0.0; 2];
///     }
/// }
///
/// let (q, mut phi, mut jac) = ([0.0; 2], [0.0; 2], [[0.0; 2]; 2]);
/// let mut factors = Factors::new();
/// factors.evaluate(&Pair, &q, 0.0, &mut phi, &mut jac);
/// factors.factor(&Pair, &q, 0.0, &mut jac, runtime::lu::DEFAULT_PIVOT_RATIO)?;
/// let mut x = [5.0, 11.0];
/// factors.solve(&Pair, &jac, &mut x);
/// assert!((x[0] - 1.0).abs() < 1e-15 && (x[1] - 2.0).abs() < 1e-15);
/// assert_eq!(factors.counts().dense, 1);
/// # Ok::<(), runtime::lu::Singular>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Factors<const N: usize> {
    held: Held,
    /// The row permutation of dense factors.
    perm: [usize; N],
    /// The static order to try first: the last one that succeeded.
    next: usize,
    counts: FactorCounts,
    block_counts: BlockCounts,
}

impl<const N: usize> Default for Factors<N> {
    fn default() -> Self {
        Factors::new()
    }
}

impl<const N: usize> Factors<N> {
    /// No factors held yet; static order 0 is tried first.
    #[must_use]
    pub const fn new() -> Self {
        Factors {
            held: Held::Nothing,
            perm: [0; N],
            next: 0,
            counts: FactorCounts { structured: 0, dense: 0, refused: 0 },
            block_counts: BlockCounts { closed_form: 0, implicit: 0, iterations: 0 },
        }
    }

    /// How many factorisations of each kind were done, and how many static orders refused.
    #[must_use]
    pub const fn counts(&self) -> FactorCounts {
        self.counts
    }

    /// What Newton block by block did, when the mechanism runs it.
    #[must_use]
    pub const fn block_counts(&self) -> BlockCounts {
        self.block_counts
    }

    /// What Newton block by block works in: the row order of the blocks' factors, and its
    /// counts.
    pub(crate) const fn blocks_mut(&mut self) -> (&mut [usize; N], &mut BlockCounts) {
        (&mut self.perm, &mut self.block_counts)
    }

    /// Records whether the storage holds the factors of every block (after Newton block by
    /// block succeeded) or nothing.
    pub(crate) const fn set_blocks_held(&mut self, held: bool) {
        self.held = if held { Held::Blocks } else { Held::Nothing };
    }

    /// Whether the storage holds block factors that [`blocks::solve_block`](crate::blocks::solve_block)
    /// can read, block by block.
    pub(crate) const fn holds_blocks(&self) -> bool {
        matches!(self.held, Held::Blocks)
    }

    /// Whether the storage holds usable factors (the last [`Factors::factor`] succeeded).
    #[must_use]
    pub const fn holds_factors(&self) -> bool {
        !matches!(self.held, Held::Nothing)
    }

    /// Whether the storage holds the factors of one of the mechanism's static pivot orders
    /// (threshold pivoting) or of its blocks (partial pivoting inside each diagonal block),
    /// rather than dense LU's (partial pivoting over the whole of Φ_q) or nothing: pivots whose
    /// ratio the step control confirms with dense LU near its threshold.
    #[must_use]
    pub const fn holds_structured(&self) -> bool {
        matches!(self.held, Held::Structured(_) | Held::Blocks)
    }

    /// Forgets the factors (the storage is about to be overwritten).
    pub const fn forget(&mut self) {
        self.held = Held::Nothing;
    }

    /// Writes Φ(q, t) into `phi` and Φ_q(q, t) into `jac`, as [`Factors::factor`] reads it:
    /// only the structural non-zeros when the mechanism has static orders, in full otherwise.
    ///
    /// The factors held before are lost.
    pub fn evaluate<R: Real, M: Mechanism<N, R>>(
        &mut self,
        mechanism: &M,
        q: &[R; N],
        t: R,
        phi: &mut [R; N],
        jac: &mut [[R; N]; N],
    ) {
        self.held = Held::Nothing;
        if M::BLOCKS.is_some() {
            mechanism.residual_jacobian_blocks(q, t, phi, jac);
        } else if M::PIVOT_ORDERS > 0 {
            mechanism.residual_jacobian_structural(q, t, phi, jac);
        } else {
            mechanism.residual_jacobian(q, t, phi, jac);
        }
    }

    /// Factors Φ_q(q, t), written into `jac` by [`Factors::evaluate`] at the same (q, t), in
    /// place.
    ///
    /// With a block layout ([`Mechanism::BLOCKS`]), factors block by block ([`Mechanism::factor_blocks`]),
    /// and by dense LU when a pivot is zero or the pivot ratio at most `ratio`. Otherwise tries
    /// the mechanism's static orders, the last successful one first, evaluating Φ_q(q, t)
    /// again after each refusal; when every one is refused, or the smallest |pivot| of the one
    /// that passed is at most `ratio` times the largest, evaluates Φ_q(q, t) in full into `jac`
    /// and factors it by [`lu::factor_with_ratio`].
    ///
    /// # Errors
    ///
    /// The [`Singular`] of the dense factorisation; `jac` then holds no usable factors.
    pub fn factor<R: Real, M: Mechanism<N, R>>(
        &mut self,
        mechanism: &M,
        q: &[R; N],
        t: R,
        jac: &mut [[R; N]; N],
        ratio: R,
    ) -> Result<PivotInfo<R>, Singular<R>> {
        if M::BLOCKS.is_some() {
            match mechanism.factor_blocks(jac, &mut self.perm) {
                Some(p) if p.smallest > ratio * p.largest => {
                    self.held = Held::Blocks;
                    self.counts.structured += 1;
                    return Ok(p);
                }
                // A zero or small pivot: dense LU's own verdict decides.
                _ => {
                    self.counts.refused += 1;
                    return self.factor_dense(mechanism, q, t, jac, ratio);
                }
            }
        }
        let orders = M::PIVOT_ORDERS;
        for attempt in 0..orders {
            let order = (self.next + attempt) % orders;
            match mechanism.factor_structured(order, jac) {
                Some(p) if p.smallest > ratio * p.largest => {
                    self.held = Held::Structured(order);
                    self.next = order;
                    self.counts.structured += 1;
                    return Ok(p);
                }
                Some(_) => {
                    // The order's pivots passed the guard but look singular: dense LU's own
                    // verdict decides.
                    self.counts.refused += 1;
                    break;
                }
                // A refused order leaves a partial factorisation: the next one needs Φ_q again.
                None => {
                    self.counts.refused += 1;
                    if attempt + 1 < orders {
                        mechanism.jacobian(q, t, jac);
                    }
                }
            }
        }
        if orders > 0 {
            // The storage holds factors, a partial factorisation, or a structural evaluation
            // whose other entries are stale: dense LU needs Φ_q in full.
            mechanism.jacobian(q, t, jac);
        }
        self.held = Held::Nothing;
        self.counts.dense += 1;
        let pivots = lu::factor_with_ratio(jac, &mut self.perm, ratio)?;
        self.held = Held::Dense;
        Ok(pivots)
    }

    /// Evaluates Φ_q(q, t) in full into `jac` and factors it by dense LU with partial pivoting
    /// ([`lu::factor_with_ratio`] with `ratio`), whatever static orders the mechanism has: the
    /// factorisation whose pivots estimate the conditioning of Φ_q the same way for every
    /// mechanism (the step control's pivot ratio, [`crate::step`]).
    ///
    /// # Errors
    ///
    /// The [`Singular`] of the factorisation; `jac` then holds no usable factors.
    pub fn factor_dense<R: Real, M: Mechanism<N, R>>(
        &mut self,
        mechanism: &M,
        q: &[R; N],
        t: R,
        jac: &mut [[R; N]; N],
        ratio: R,
    ) -> Result<PivotInfo<R>, Singular<R>> {
        mechanism.jacobian(q, t, jac);
        self.held = Held::Nothing;
        self.counts.dense += 1;
        let pivots = lu::factor_with_ratio(jac, &mut self.perm, ratio)?;
        self.held = Held::Dense;
        Ok(pivots)
    }

    /// [`Factors::factor_dense`], returning the extremes of its pivots, then those of the same
    /// factorisation as the LU of R Φ_q C has them, where R and C are diagonal scales, powers of two, that equilibrate Φ_q: C
    /// brings the largest entry of each column near 1, then R that of each row. Scaling by
    /// powers of two is exact, and a change of the unit of length scales columns and rows
    /// that way, so the ratio of these extremes does not depend on the units of the
    /// description (the pivots of Φ_q itself do: with links of length L the translational and
    /// Euler-parameter columns differ by L). The factors kept are those of Φ_q, ready for
    /// [`Factors::solve`]: partial pivoting chose its rows on Φ_q.
    ///
    /// # Errors
    ///
    /// As [`Factors::factor_dense`] with `ratio` 0: an exactly zero pivot or a non-finite entry.
    pub fn factor_dense_equilibrated<R: Real, M: Mechanism<N, R>>(
        &mut self,
        mechanism: &M,
        q: &[R; N],
        t: R,
        jac: &mut [[R; N]; N],
    ) -> Result<[PivotInfo<R>; 2], Singular<R>> {
        mechanism.jacobian(q, t, jac);
        let (mut rows, mut cols) = ([R::ONE; N], [R::ONE; N]);
        for (j, c) in cols.iter_mut().enumerate() {
            *c = reciprocal_power_of_two(jac.iter().fold(R::ZERO, |m, row| m.max(row[j].abs())));
        }
        for (r, row) in rows.iter_mut().zip(jac.iter()) {
            let big = row.iter().zip(&cols).fold(R::ZERO, |m, (&a, &c)| m.max((a * c).abs()));
            *r = reciprocal_power_of_two(big);
        }
        self.held = Held::Nothing;
        self.counts.dense += 1;
        let plain = lu::factor_with_ratio(jac, &mut self.perm, R::ZERO)?;
        self.held = Held::Dense;
        let (mut smallest, mut largest) = (R::INFINITY, R::ZERO);
        for (k, &p) in self.perm.iter().enumerate() {
            let u = jac[k][k].abs() * rows.get(p).copied().unwrap_or(R::ONE) * cols[k];
            smallest = if u < smallest { u } else { smallest };
            largest = largest.max(u);
        }
        Ok([plain, PivotInfo { smallest, largest }])
    }

    /// Solves Φ_q x = b in place with the factors in `lu` from the last successful
    /// [`Factors::factor`].
    ///
    /// Without usable factors (see [`Factors::holds_factors`]) x is all NaN, so the caller's
    /// finiteness check catches the mistake.
    pub fn solve<R: Real, M: Mechanism<N, R>>(
        &self,
        mechanism: &M,
        lu: &[[R; N]; N],
        b: &mut [R; N],
    ) {
        match self.held {
            Held::Structured(order) => mechanism.solve_structured(order, lu, b),
            Held::Dense => lu::solve(lu, &self.perm, b),
            Held::Blocks => mechanism.solve_blocks(lu, &self.perm, b),
            Held::Nothing => *b = [R::NAN; N],
        }
    }
}

/// 1 / the power of two nearest `x`, or 1 when `x` is 0 or not finite.
pub(crate) fn reciprocal_power_of_two<R: Real>(x: R) -> R {
    let x = x.to_f64();
    if x > 0.0 && x.is_finite() {
        R::from_f64(libm::exp2(-libm::round(libm::log2(x))))
    } else {
        R::ONE
    }
}

/// A mechanism with its static pivot orders hidden, so that every factorisation of Φ_q is
/// dense LU with partial pivoting: the reference the structured factorisations are compared
/// with, in tests and benchmarks.
///
/// ```
/// use runtime::Mechanism;
/// use runtime::factors::DenseOnly;
///
/// struct Line;
/// impl Mechanism<1> for Line {
///     fn residual(&self, q: &[f64; 1], t: f64, phi: &mut [f64; 1]) { phi[0] = q[0] - t; }
///     fn jacobian(&self, _: &[f64; 1], _: f64, jac: &mut [[f64; 1]; 1]) { jac[0][0] = 1.0; }
///     fn velocity_rhs(&self, _: &[f64; 1], _: f64, nu: &mut [f64; 1]) { nu[0] = 1.0; }
///     fn acceleration_rhs(&self, _: &[f64; 1], _: &[f64; 1], _: f64, g: &mut [f64; 1]) {
///         g[0] = 0.0;
///     }
/// }
/// assert_eq!(<DenseOnly<Line> as Mechanism<1>>::PIVOT_ORDERS, 0);
/// let mut phi = [0.0];
/// DenseOnly(Line).residual(&[2.0], 0.5, &mut phi);
/// assert_eq!(phi, [1.5]);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DenseOnly<M>(pub M);

impl<M: Mechanism<N, R>, const N: usize, R: Real> Mechanism<N, R> for DenseOnly<M> {
    fn residual(&self, q: &[R; N], t: R, phi: &mut [R; N]) {
        self.0.residual(q, t, phi);
    }
    fn jacobian(&self, q: &[R; N], t: R, jac: &mut [[R; N]; N]) {
        self.0.jacobian(q, t, jac);
    }
    fn residual_jacobian(&self, q: &[R; N], t: R, phi: &mut [R; N], jac: &mut [[R; N]; N]) {
        self.0.residual_jacobian(q, t, phi, jac);
    }
    fn velocity_rhs(&self, q: &[R; N], t: R, nu: &mut [R; N]) {
        self.0.velocity_rhs(q, t, nu);
    }
    fn acceleration_rhs(&self, q: &[R; N], qd: &[R; N], t: R, gamma: &mut [R; N]) {
        self.0.acceleration_rhs(q, qd, t, gamma);
    }
    fn normalize(&self, q: &mut [R; N]) {
        self.0.normalize(q);
    }
    fn normalize_moved(&self, q: &mut [R; N]) -> bool {
        self.0.normalize_moved(q)
    }
    const LEFT_OUT: usize = M::LEFT_OUT;
    fn left_out_residual_jacobian(&self, q: &[R; N], t: R, phi: &mut [R], jac: &mut [[R; N]]) {
        self.0.left_out_residual_jacobian(q, t, phi, jac);
    }
    fn left_out_velocity_rhs(&self, q: &[R; N], t: R, nu: &mut [R]) {
        self.0.left_out_velocity_rhs(q, t, nu);
    }
    fn left_out_acceleration_rhs(&self, q: &[R; N], qd: &[R; N], t: R, gamma: &mut [R]) {
        self.0.left_out_acceleration_rhs(q, qd, t, gamma);
    }
}
