//! The trait that generated code implements.

use crate::Real;

/// A square kinematic system Φ(q, t) = 0 of `N` equations in `N` unknowns, in the
/// floating-point type `R` (`f64` unless the module was generated for `f32`).
///
/// Generated code implements this trait, one struct per mechanism.
/// Every method writes into storage the caller owns, so nothing is allocated and no `N × N`
/// array is returned by value.
/// Methods do not check their inputs: a NaN or an infinity in `q`, `qd` or `t` may come out as
/// NaN in the output, and the solvers in this crate turn that into an error.
pub trait Mechanism<const N: usize, R: Real = f64> {
    /// Writes the constraint residuals Φ(q, t) into `phi`.
    fn residual(&self, q: &[R; N], t: R, phi: &mut [R; N]);

    /// Writes the Jacobian Φ_q(q, t) into `jac`, row-major: `jac[i][j] = ∂Φ_i/∂q_j`.
    fn jacobian(&self, q: &[R; N], t: R, jac: &mut [[R; N]; N]);

    /// Writes Φ(q, t) into `phi` and Φ_q(q, t) into `jac` in one pass.
    ///
    /// Generated code overrides this to share subexpressions between the two.
    /// The default calls [`Mechanism::residual`] and then [`Mechanism::jacobian`].
    fn residual_jacobian(&self, q: &[R; N], t: R, phi: &mut [R; N], jac: &mut [[R; N]; N]) {
        self.residual(q, t, phi);
        self.jacobian(q, t, jac);
    }

    /// Writes the velocity right-hand side ν = −Φ_t into `nu`.
    fn velocity_rhs(&self, q: &[R; N], t: R, nu: &mut [R; N]);

    /// Writes the acceleration right-hand side γ = −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt into `gamma`.
    fn acceleration_rhs(&self, q: &[R; N], qd: &[R; N], t: R, gamma: &mut [R; N]);

    /// Projects `q` back onto the constraints that have a closed-form projection.
    ///
    /// Generated code renormalises Euler parameters here (p ← p / |p|).
    /// The solvers call it once Newton has converged and then evaluate Φ and Φ_q again, so the
    /// reported residual and the factored Jacobian belong to the projected `q` (unless it moved
    /// `q` by a few ulps only, see [`newton::moved_by_round_off`](crate::newton::moved_by_round_off)).
    /// The default does nothing.
    fn normalize(&self, _q: &mut [R; N]) {}

    /// [`Mechanism::normalize`], returning whether it moved q by more than round-off, that is
    /// some coordinate by more than [`ROUND_OFF_MOVE`](crate::newton::ROUND_OFF_MOVE) ulps of
    /// itself ([`newton::moved_by_round_off`](crate::newton::moved_by_round_off)); the solvers
    /// then evaluate Φ and Φ_q again.
    /// The default compares a copy of q with the normalised q; generated code tests only the
    /// coordinates it rescales, as it rescales them (the others do not move).
    fn normalize_moved(&self, q: &mut [R; N]) -> bool {
        let before = *q;
        self.normalize(q);
        !crate::newton::moved_by_round_off(&before, q)
    }

    /// The block-lower-triangular form of Φ_q, when the mechanism's solver factors it block by
    /// block ([`blocks`](crate::blocks)); the default, `None`, means it does not.
    ///
    /// With a layout the solvers evaluate Φ_q with [`Mechanism::residual_jacobian_blocks`],
    /// factor it with [`Mechanism::factor_blocks`] and fall back to dense LU only when that
    /// meets a zero or small pivot; the static orders are then not used.
    const BLOCKS: Option<&'static crate::blocks::Layout> = None;

    /// Writes Φ(q, t) into `phi` and, into `jac`, what [`Mechanism::factor_blocks`] and
    /// [`Mechanism::solve_blocks`] read, leaving the other entries as they were.
    /// The default calls [`Mechanism::residual_jacobian`].
    fn residual_jacobian_blocks(&self, q: &[R; N], t: R, phi: &mut [R; N], jac: &mut [[R; N]; N]) {
        self.residual_jacobian(q, t, phi, jac);
    }

    /// Factors Φ_q block by block in place, `perm` holding the pivoting (in a layout of the
    /// mechanism's own, which only [`Mechanism::solve_blocks`] reads); returns the smallest and
    /// largest |pivot|, or `None` when a pivot is 0 or an entry not finite, or the mechanism
    /// has no [`Mechanism::BLOCKS`] (or keeps them packed, [`Mechanism::PACKED_BLOCKS`], and
    /// does not override this).
    /// The default runs [`blocks::factor`](crate::blocks::factor) on the layout; generated
    /// code overrides it with straight-line code per block.
    fn factor_blocks(
        &self,
        jac: &mut [[R; N]; N],
        perm: &mut [usize; N],
    ) -> Option<crate::lu::PivotInfo<R>> {
        Self::BLOCKS
            .filter(|_| Self::PACKED_BLOCKS.is_none())
            .and_then(|layout| crate::blocks::factor(layout, jac, perm))
    }

    /// Solves Φ_q x = b in place (b by row in, x by column out) with what a successful
    /// [`Mechanism::factor_blocks`] left in `lu` and `perm`.
    /// The default runs [`blocks::solve`](crate::blocks::solve) on the layout.
    fn solve_blocks(&self, lu: &[[R; N]; N], perm: &[usize; N], b: &mut [R; N]) {
        if let Some(layout) = Self::BLOCKS {
            crate::blocks::solve(layout, lu, perm, b);
        }
    }

    /// Whether the solvers run Newton block by block on [`Mechanism::BLOCKS`]
    /// ([`newton`](crate::newton)): each diagonal block iterates on its own unknowns, those of
    /// earlier blocks fixed, and a block solved in closed form
    /// ([`Layout::solve`](crate::blocks::Layout::solve)) without iteration.
    /// Requires a layout and [`Mechanism::block_residual`]; the default, `false`, runs one
    /// Newton iteration over the whole system.
    const BLOCK_NEWTON: bool = false;

    /// Where each block of [`Mechanism::BLOCKS`] starts, and its entries end, when the methods
    /// that take `jac` under it
    /// ([`Mechanism::residual_jacobian_blocks`], [`Mechanism::block_residual`],
    /// [`Mechanism::factor_blocks`], [`Mechanism::solve_blocks`], [`Mechanism::factor_block`],
    /// [`Mechanism::solve_block`]) keep Φ_q's block entries packed at the front of the storage
    /// ([`blocks`](crate::blocks), "Packed storage") rather than at `jac[i][j]`: block b's
    /// entries are `jac.as_flattened()[starts[b]..starts[b + 1]]`, one start per block and the
    /// end, [`blocks::packed_len`](crate::blocks::packed_len), last. A step then touches those
    /// entries, not N rows. The other methods, [`Mechanism::jacobian`] and the dense
    /// fallbacks, keep `jac[i][j]`.
    /// Generated code packs with Newton block by block; a mechanism that packs overrides every
    /// one of those methods (their defaults then refuse to factor, so that the solvers fall
    /// back to dense LU or report the block singular). The default, `None`, does not pack.
    const PACKED_BLOCKS: Option<&'static [usize]> = None;

    /// Writes Φ_i(q, t) for the rows i of block `b` of [`Mechanism::BLOCKS`] into `phi` and,
    /// when `jacobian`, the structural non-zeros of those rows of Φ_q(q, t) into `jac` (the
    /// diagonal block's and those below it), leaving every other entry as it was.
    /// Only called when [`Mechanism::BLOCK_NEWTON`]; the default does nothing.
    fn block_residual(
        &self,
        b: usize,
        jacobian: bool,
        q: &[R; N],
        t: R,
        phi: &mut [R; N],
        jac: &mut [[R; N]; N],
    ) {
        let _ = (b, jacobian, q, t, phi, jac);
    }

    /// Solves block `b` of [`Mechanism::BLOCKS`] in closed form, when its
    /// [`Layout::solve`](crate::blocks::Layout::solve) is
    /// [`Solve::Explicit`](crate::blocks::Solve::Explicit): writes the block's unknowns into `q`
    /// from those of earlier blocks and t, choosing among the discrete solutions the one
    /// nearest the block's unknowns in `q` on entry (the prediction). Returns false, `q`
    /// unchanged, when there is no real solution (Newton then tries the block).
    /// Only called when [`Mechanism::BLOCK_NEWTON`]; the default returns false.
    fn closed_form_block(&self, b: usize, q: &mut [R; N], t: R) -> bool {
        let _ = (b, q, t);
        false
    }

    /// Factors diagonal block `b` of [`Mechanism::BLOCKS`] in place by LU with partial
    /// pivoting inside the block, its row order into `perm` at the block's positions (in a
    /// layout of the mechanism's own, which [`Mechanism::solve_block`] and
    /// [`Mechanism::solve_blocks`] read), refusing it when its smallest |pivot| ≤ `ratio` ·
    /// its largest.
    /// The default runs [`blocks::factor_block`](crate::blocks::factor_block); generated code
    /// overrides it with straight-line code per block, which first tries the block's static
    /// pivot orders (planned along the description's motion, guarded by
    /// [`MAX_MULTIPLIER`](crate::lu::MAX_MULTIPLIER) and kept only when their pivot ratio
    /// exceeds [`structured_bound`](crate::step::structured_bound)`(ratio)`) and otherwise
    /// factors by partial pivoting, whose verdict on a singular block is final.
    ///
    /// # Errors
    ///
    /// The [`Singular`](crate::lu::Singular) met, its column counted within the block (0 for
    /// the block's first unknown).
    fn factor_block(
        &self,
        b: usize,
        jac: &mut [[R; N]; N],
        perm: &mut [usize; N],
        ratio: R,
    ) -> Result<crate::lu::PivotInfo<R>, crate::lu::Singular<R>> {
        match Self::BLOCKS {
            Some(layout) if Self::PACKED_BLOCKS.is_none() => {
                crate::blocks::factor_block(layout, b, jac, perm, ratio)
            }
            _ => Err(crate::lu::Singular::NonFinite { column: 0 }),
        }
    }

    /// Solves diagonal block `b` alone, D_b x = r, with the factors a successful
    /// [`Mechanism::factor_block`] left in `lu` and `perm`: r read by row from `rhs`, x written
    /// in the order of the block's unknowns into `x`.
    /// The default runs [`blocks::solve_block`](crate::blocks::solve_block).
    fn solve_block(
        &self,
        b: usize,
        lu: &[[R; N]; N],
        perm: &[usize; N],
        rhs: &[R; N],
        x: &mut [R],
    ) {
        if let Some(layout) = Self::BLOCKS {
            crate::blocks::solve_block(layout, b, lu, perm, rhs, x);
        }
    }

    /// The number of static pivot orders [`Mechanism::factor_structured`] knows.
    ///
    /// The default, 0, means none: the solvers then evaluate Φ_q with
    /// [`Mechanism::residual_jacobian`] and factor it by dense LU with partial pivoting
    /// ([`lu`](crate::lu)).
    const PIVOT_ORDERS: usize = 0;

    /// Writes Φ(q, t) into `phi` and the entries of Φ_q(q, t) that
    /// [`Mechanism::factor_structured`] reads into `jac`, leaving the other entries of `jac` as
    /// they were.
    ///
    /// Generated code writes the entries that depend on q or t: its factorisations know the
    /// constant ones. The solvers call it instead of
    /// [`Mechanism::residual_jacobian`] when [`Mechanism::PIVOT_ORDERS`] is not 0, and call
    /// [`Mechanism::jacobian`] again before falling back to dense LU.
    /// The default calls [`Mechanism::residual_jacobian`].
    fn residual_jacobian_structural(
        &self,
        q: &[R; N],
        t: R,
        phi: &mut [R; N],
        jac: &mut [[R; N]; N],
    ) {
        self.residual_jacobian(q, t, phi, jac);
    }

    /// Factors Φ_q in place with static pivot order `order` (below [`Mechanism::PIVOT_ORDERS`]),
    /// reading only the entries [`Mechanism::residual_jacobian_structural`] writes.
    ///
    /// A pivot is accepted only if it is finite and every multiplier of its column is at most
    /// [`lu::MAX_MULTIPLIER`](crate::lu::MAX_MULTIPLIER) in magnitude (threshold partial
    /// pivoting).
    /// Returns the smallest and largest |pivot|, which the caller compares as for dense LU, or
    /// `None` when a pivot is refused or `order` is out of range; `jac` then holds a partial
    /// factorisation (the factors are stored as soon as they are computed, which keeps the
    /// generated code's registers free), so Φ_q must be evaluated again before it is read.
    /// The layout of the factors in `jac` is the mechanism's own: only
    /// [`Mechanism::solve_structured`] with the same `order` may read them.
    /// The default has no orders and returns `None`.
    fn factor_structured(
        &self,
        order: usize,
        jac: &mut [[R; N]; N],
    ) -> Option<crate::lu::PivotInfo<R>> {
        let _ = (order, jac);
        None
    }

    /// Solves Φ_q x = b in place with the factors a successful
    /// [`Mechanism::factor_structured`]`(order, lu)` left in `lu`.
    ///
    /// The default, for mechanisms without orders, does nothing.
    fn solve_structured(&self, order: usize, lu: &[[R; N]; N], b: &mut [R; N]) {
        let _ = (order, lu, b);
    }

    /// The number of equations of the description left out of this square system as dependent
    /// on its rows at the configuration it was generated at (a redundant mechanism: the Bennett
    /// linkage, a planar loop of four revolutes). The default, 0, means none.
    ///
    /// With left-out rows the solvers re-select the rows they solve with where the rows of the
    /// square system degenerate while the whole stack of N + `LEFT_OUT` rows does not
    /// ([`rows`](crate::rows)); only the first [`rows::MAX_LEFT_OUT`](crate::rows::MAX_LEFT_OUT)
    /// left-out rows can stand in for kept ones.
    const LEFT_OUT: usize = 0;

    /// Writes Φ of the first `phi.len()` left-out rows into `phi` and their whole rows of Φ_q
    /// (every entry, zeros included) into `jac`, which has as many rows; both hold at most
    /// [`Mechanism::LEFT_OUT`] rows. The default, for mechanisms without left-out rows, writes
    /// nothing.
    fn left_out_residual_jacobian(&self, q: &[R; N], t: R, phi: &mut [R], jac: &mut [[R; N]]) {
        let _ = (q, t, phi, jac);
    }

    /// Writes ν = −Φ_t of the first `nu.len()` left-out rows into `nu` (see
    /// [`Mechanism::left_out_residual_jacobian`]).
    fn left_out_velocity_rhs(&self, q: &[R; N], t: R, nu: &mut [R]) {
        let _ = (q, t, nu);
    }

    /// Writes γ of the first `gamma.len()` left-out rows into `gamma` (see
    /// [`Mechanism::left_out_residual_jacobian`]).
    fn left_out_acceleration_rhs(&self, q: &[R; N], qd: &[R; N], t: R, gamma: &mut [R]) {
        let _ = (q, qd, t, gamma);
    }

    /// How many values [`Mechanism::time_terms`] writes: terms of Φ, Φ_q, ν and γ that depend
    /// on t alone (the sines and cosines of driver laws), which [`Solver`](crate::Solver)
    /// computes once per position and passes to [`Mechanism::residual_at`],
    /// [`Mechanism::residual_jacobian_structural_at`], [`Mechanism::velocity_rhs_at`] and
    /// [`Mechanism::acceleration_rhs_at`] at that time, instead of each of them computing the
    /// terms again.
    /// The default, 0, means none; the solvers use at most
    /// [`MAX_TIME_TERMS`](crate::MAX_TIME_TERMS) and call the plain methods for a
    /// mechanism with more.
    const TIME_TERMS: usize = 0;

    /// Writes the time terms at t into the first [`Mechanism::TIME_TERMS`] entries of `terms`,
    /// which has at least that many. They may depend on t and the mechanism's own state (not
    /// on q): a solver computes them again after [`Solver::mechanism_mut`](crate::Solver::mechanism_mut).
    /// The default writes nothing.
    fn time_terms(&self, t: R, terms: &mut [R]) {
        let _ = (t, terms);
    }

    /// [`Mechanism::residual`] with `terms` the time terms at the same t
    /// ([`Mechanism::time_terms`]); the same values, bit for bit.
    /// The default calls [`Mechanism::residual`].
    fn residual_at(&self, q: &[R; N], t: R, terms: &[R], phi: &mut [R; N]) {
        let _ = terms;
        self.residual(q, t, phi);
    }

    /// [`Mechanism::residual_jacobian_structural`] with `terms` the time terms at the same t
    /// (see [`Mechanism::residual_at`]).
    /// The default calls [`Mechanism::residual_jacobian_structural`].
    fn residual_jacobian_structural_at(
        &self,
        q: &[R; N],
        t: R,
        terms: &[R],
        phi: &mut [R; N],
        jac: &mut [[R; N]; N],
    ) {
        let _ = terms;
        self.residual_jacobian_structural(q, t, phi, jac);
    }

    /// [`Mechanism::velocity_rhs`] with `terms` the time terms at the same t
    /// (see [`Mechanism::residual_at`]).
    /// The default calls [`Mechanism::velocity_rhs`].
    fn velocity_rhs_at(&self, q: &[R; N], t: R, terms: &[R], nu: &mut [R; N]) {
        let _ = terms;
        self.velocity_rhs(q, t, nu);
    }

    /// [`Mechanism::acceleration_rhs`] with `terms` the time terms at the same t
    /// (see [`Mechanism::residual_at`]).
    /// The default calls [`Mechanism::acceleration_rhs`].
    fn acceleration_rhs_at(&self, q: &[R; N], qd: &[R; N], t: R, terms: &[R], gamma: &mut [R; N]) {
        let _ = terms;
        self.acceleration_rhs(q, qd, t, gamma);
    }

    /// The generated module's `expand` (the full coordinates of its moving bodies at q, q̇, q̈
    /// and t: `out[b][0]` is `[x, y, z, e0, e1, e2, e3]` of body b, `out[b][1]` their rates,
    /// `out[b][2]` their accelerations) written into `out`, reading the time terms at the same t
    /// from `terms` ([`Mechanism::time_terms`], as [`Solver::time_terms`](crate::Solver::time_terms)
    /// holds them) instead of computing them again, or computing them when `terms` is empty;
    /// the same values as `expand`, bit for bit. Returns whether it wrote `out`.
    /// The default writes nothing and returns false, as does generated code whose `expand`
    /// reads no time terms, or when `out` has fewer entries than the module has moving bodies:
    /// the caller then calls the module's `expand`.
    fn expand_at(
        &self,
        q: &[R; N],
        qd: &[R; N],
        qdd: &[R; N],
        t: R,
        terms: &[R],
        out: &mut [[[R; 7]; 3]],
    ) -> bool {
        let _ = (q, qd, qdd, t, terms, out);
        false
    }
}

/// The most time terms ([`Mechanism::TIME_TERMS`]) the solvers keep; a mechanism with more is
/// evaluated by its plain methods.
pub const MAX_TIME_TERMS: usize = 16;

/// A mechanism whose time terms ([`Mechanism::TIME_TERMS`]) at `t` are at hand: its
/// evaluations at `t` read them ([`Mechanism::residual_at`] and the like), those at any other
/// time (or without terms) call the plain methods. Everything else is the mechanism's own.
pub(crate) struct Timed<'a, M, R> {
    /// The mechanism.
    pub(crate) mechanism: &'a M,
    /// The time of `terms`.
    pub(crate) t: R,
    /// The time terms at `t`, or `None`.
    pub(crate) terms: Option<&'a [R]>,
}

impl<M, R: Real> Timed<'_, M, R> {
    /// The terms, when they belong to `t`.
    #[inline]
    fn at(&self, t: R) -> Option<&[R]> {
        self.terms.filter(|_| t == self.t)
    }
}

impl<M: Mechanism<N, R>, const N: usize, R: Real> Mechanism<N, R> for Timed<'_, M, R> {
    const BLOCKS: Option<&'static crate::blocks::Layout> = M::BLOCKS;
    const BLOCK_NEWTON: bool = M::BLOCK_NEWTON;
    const PACKED_BLOCKS: Option<&'static [usize]> = M::PACKED_BLOCKS;
    const PIVOT_ORDERS: usize = M::PIVOT_ORDERS;
    const LEFT_OUT: usize = M::LEFT_OUT;
    const TIME_TERMS: usize = M::TIME_TERMS;

    fn residual(&self, q: &[R; N], t: R, phi: &mut [R; N]) {
        match self.at(t) {
            Some(terms) => self.mechanism.residual_at(q, t, terms, phi),
            None => self.mechanism.residual(q, t, phi),
        }
    }
    fn jacobian(&self, q: &[R; N], t: R, jac: &mut [[R; N]; N]) {
        self.mechanism.jacobian(q, t, jac);
    }
    fn residual_jacobian(&self, q: &[R; N], t: R, phi: &mut [R; N], jac: &mut [[R; N]; N]) {
        self.mechanism.residual_jacobian(q, t, phi, jac);
    }
    fn velocity_rhs(&self, q: &[R; N], t: R, nu: &mut [R; N]) {
        match self.at(t) {
            Some(terms) => self.mechanism.velocity_rhs_at(q, t, terms, nu),
            None => self.mechanism.velocity_rhs(q, t, nu),
        }
    }
    fn acceleration_rhs(&self, q: &[R; N], qd: &[R; N], t: R, gamma: &mut [R; N]) {
        match self.at(t) {
            Some(terms) => self.mechanism.acceleration_rhs_at(q, qd, t, terms, gamma),
            None => self.mechanism.acceleration_rhs(q, qd, t, gamma),
        }
    }
    fn normalize(&self, q: &mut [R; N]) {
        self.mechanism.normalize(q);
    }
    fn normalize_moved(&self, q: &mut [R; N]) -> bool {
        self.mechanism.normalize_moved(q)
    }
    fn residual_jacobian_blocks(&self, q: &[R; N], t: R, phi: &mut [R; N], jac: &mut [[R; N]; N]) {
        self.mechanism.residual_jacobian_blocks(q, t, phi, jac);
    }
    fn factor_blocks(
        &self,
        jac: &mut [[R; N]; N],
        perm: &mut [usize; N],
    ) -> Option<crate::lu::PivotInfo<R>> {
        self.mechanism.factor_blocks(jac, perm)
    }
    fn solve_blocks(&self, lu: &[[R; N]; N], perm: &[usize; N], b: &mut [R; N]) {
        self.mechanism.solve_blocks(lu, perm, b);
    }
    fn block_residual(
        &self,
        b: usize,
        jacobian: bool,
        q: &[R; N],
        t: R,
        phi: &mut [R; N],
        jac: &mut [[R; N]; N],
    ) {
        self.mechanism.block_residual(b, jacobian, q, t, phi, jac);
    }
    fn closed_form_block(&self, b: usize, q: &mut [R; N], t: R) -> bool {
        self.mechanism.closed_form_block(b, q, t)
    }
    fn factor_block(
        &self,
        b: usize,
        jac: &mut [[R; N]; N],
        perm: &mut [usize; N],
        ratio: R,
    ) -> Result<crate::lu::PivotInfo<R>, crate::lu::Singular<R>> {
        self.mechanism.factor_block(b, jac, perm, ratio)
    }
    fn solve_block(
        &self,
        b: usize,
        lu: &[[R; N]; N],
        perm: &[usize; N],
        rhs: &[R; N],
        x: &mut [R],
    ) {
        self.mechanism.solve_block(b, lu, perm, rhs, x);
    }
    fn residual_jacobian_structural(
        &self,
        q: &[R; N],
        t: R,
        phi: &mut [R; N],
        jac: &mut [[R; N]; N],
    ) {
        match self.at(t) {
            Some(terms) => self.mechanism.residual_jacobian_structural_at(q, t, terms, phi, jac),
            None => self.mechanism.residual_jacobian_structural(q, t, phi, jac),
        }
    }
    fn factor_structured(
        &self,
        order: usize,
        jac: &mut [[R; N]; N],
    ) -> Option<crate::lu::PivotInfo<R>> {
        self.mechanism.factor_structured(order, jac)
    }
    fn solve_structured(&self, order: usize, lu: &[[R; N]; N], b: &mut [R; N]) {
        self.mechanism.solve_structured(order, lu, b);
    }
    fn left_out_residual_jacobian(&self, q: &[R; N], t: R, phi: &mut [R], jac: &mut [[R; N]]) {
        self.mechanism.left_out_residual_jacobian(q, t, phi, jac);
    }
    fn left_out_velocity_rhs(&self, q: &[R; N], t: R, nu: &mut [R]) {
        self.mechanism.left_out_velocity_rhs(q, t, nu);
    }
    fn left_out_acceleration_rhs(&self, q: &[R; N], qd: &[R; N], t: R, gamma: &mut [R]) {
        self.mechanism.left_out_acceleration_rhs(q, qd, t, gamma);
    }
    fn time_terms(&self, t: R, terms: &mut [R]) {
        self.mechanism.time_terms(t, terms);
    }
    fn residual_at(&self, q: &[R; N], t: R, terms: &[R], phi: &mut [R; N]) {
        self.mechanism.residual_at(q, t, terms, phi);
    }
    fn residual_jacobian_structural_at(
        &self,
        q: &[R; N],
        t: R,
        terms: &[R],
        phi: &mut [R; N],
        jac: &mut [[R; N]; N],
    ) {
        self.mechanism.residual_jacobian_structural_at(q, t, terms, phi, jac);
    }
    fn velocity_rhs_at(&self, q: &[R; N], t: R, terms: &[R], nu: &mut [R; N]) {
        self.mechanism.velocity_rhs_at(q, t, terms, nu);
    }
    fn acceleration_rhs_at(&self, q: &[R; N], qd: &[R; N], t: R, terms: &[R], gamma: &mut [R; N]) {
        self.mechanism.acceleration_rhs_at(q, qd, t, terms, gamma);
    }
}
