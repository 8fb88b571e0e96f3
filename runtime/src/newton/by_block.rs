//! Newton block by block on a block-lower-triangular system ([`Mechanism::BLOCK_NEWTON`]).
//!
//! The blocks are solved in their order, each for its own unknowns with those of the blocks
//! before it fixed at their converged values, so each block iterates only as long as it
//! needs: a block whose prediction is good stops after one chord step while a fast-turning
//! one takes two Newton steps, where one iteration over the whole system would have every
//! block wait for the worst.
//!
//! - A block of one equation affine in its one unknown ([`Solve::Affine`]) is solved in
//!   closed form, q_k ← q_k − Φ_r / (∂Φ_r/∂q_k): one evaluation, no iteration.
//! - A block the mechanism solves in closed form itself ([`Solve::Explicit`], a body's
//!   orientation about a driven axis: [`crate::rotation`]) is straight-line code, then one
//!   evaluation of its rows and its factorisation; when that code finds no real solution the
//!   block is solved by Newton as below.
//! - Any other block follows [`super::solve_with_chord`] on its own rows: a prediction that
//!   meets the tolerance is corrected by one chord step with the block's factors kept from
//!   the last position, then Newton steps until max |Φ_i| over its rows ≤ tolerance, and its
//!   diagonal block is factored at the final q ([`Mechanism::factor_block`]: a generated
//!   module's static pivot orders for the block, else partial pivoting inside it).
//!
//! The factors of all blocks, with the entries below them evaluated at the final q, are then
//! those of Φ_q at the solution, for the velocity and acceleration solves by block forward
//! substitution ([`crate::blocks::solve`]). A last evaluation of Φ over all rows checks the
//! result. Euler parameters are not projected ([`Mechanism::normalize`]): their normalisation
//! rows belong to their blocks, which Newton solves to round-off.

use super::{CHORD_ROUND_OFF, NewtonError, NewtonOptions, NewtonReport, Status, max_abs, status};
use crate::blocks::{Layout, Solve};
use crate::factors::Factors;
use crate::lu::{PivotInfo, Singular};
use crate::{Mechanism, Real};

/// The largest block Newton block by block solves: the size of its stack buffers.
pub const MAX_BLOCK: usize = 32;

/// Solves Φ(q, t) = 0 block by block from `q`, with a chord step first in every block whose
/// prediction meets the tolerance when `chord` and `factors` hold block factors.
///
/// # Errors
///
/// As [`super::solve`]: a block's singular factors (the column of the small pivot), its
/// exhausted iterations (its own count and residual), or a non-finite value; q then holds the
/// iterate reached.
#[allow(clippy::too_many_arguments)]
pub(super) fn solve<R: Real, M: Mechanism<N, R>, const N: usize>(
    mechanism: &M,
    layout: &Layout,
    q: &mut [R; N],
    t: R,
    options: &NewtonOptions<R>,
    phi: &mut [R; N],
    jac: &mut [[R; N]; N],
    factors: &mut Factors<N>,
    chord: bool,
) -> Result<NewtonReport<R>, NewtonError<R>> {
    let chord = chord && factors.holds_blocks() && options.max_iterations > 0;
    factors.set_blocks_held(false);
    let (perm, counts) = factors.blocks_mut();
    let round_off = R::from_f64(CHORD_ROUND_OFF) * R::EPSILON * max_abs(q);
    let mut most = 0;
    let (mut smallest, mut largest) = (R::INFINITY, R::ZERO);
    for b in 0..layout.starts.len() - 1 {
        let (start, end) = (layout.starts[b], layout.starts[b + 1]);
        let solve = layout.solve.get(b).copied().unwrap_or(Solve::Newton);
        // Built only for the blocks that iterate or factor: the affine ones, most of the
        // blocks of a chain or a row of loops, need none of it.
        let block = || Block {
            mechanism,
            b,
            rows: &layout.rows[start..end],
            columns: &layout.columns[start..end],
            options,
            round_off,
            size: core::marker::PhantomData,
        };
        let pivots = match solve {
            Solve::Affine => {
                counts.closed_form += 1;
                closed_form(mechanism, layout, b, q, t, phi, jac, perm)?
            }
            Solve::Explicit if mechanism.closed_form_block(b, q, t) => {
                // The block's rows and its factors at the closed form, for the velocity and
                // acceleration solves.
                counts.closed_form += 1;
                mechanism.block_residual(b, true, q, t, phi, jac);
                block().factor(jac, perm, 0)?
            }
            Solve::Newton | Solve::Explicit => {
                counts.implicit += 1;
                let (iterations, pivots) = block().newton(q, t, phi, jac, perm, chord)?;
                counts.iterations += u64::from(iterations);
                most = most.max(iterations);
                pivots
            }
        };
        if pivots.smallest < smallest {
            smallest = pivots.smallest;
        }
        largest = largest.max(pivots.largest);
    }
    mechanism.residual(q, t, phi);
    let residual = max_abs(phi);
    match status(residual, 0, options) {
        Status::Converged => {}
        Status::NonFinite => return Err(NewtonError::NonFinite { iteration: most }),
        _ => return Err(NewtonError::NotConverged { iterations: most, residual }),
    }
    factors.set_blocks_held(true);
    Ok(NewtonReport { iterations: most, residual, pivots: PivotInfo { smallest, largest } })
}

/// Block `b`, one equation affine in one unknown: q_k ← q_k − Φ_r / (∂Φ_r/∂q_k), which
/// leaves Φ_r at round-off since ∂Φ_r/∂q_k does not depend on q_k; its |∂Φ_r/∂q_k| is its
/// pivot, and the entries of row r below the blocks are those at the final q. With
/// [`Mechanism::PACKED_BLOCKS`], ∂Φ_r/∂q_k is the block's first entry in the flat storage.
#[allow(clippy::too_many_arguments)]
fn closed_form<R: Real, M: Mechanism<N, R>, const N: usize>(
    mechanism: &M,
    layout: &Layout,
    b: usize,
    q: &mut [R; N],
    t: R,
    phi: &mut [R; N],
    jac: &mut [[R; N]; N],
    perm: &mut [usize; N],
) -> Result<PivotInfo<R>, NewtonError<R>> {
    let at = layout.starts[b];
    let (r, k) = (layout.rows[at], layout.columns[at]);
    mechanism.block_residual(b, true, q, t, phi, jac);
    let d = match M::PACKED_BLOCKS {
        Some(starts) => jac.as_flattened()[starts[b]],
        None => jac[r][k],
    };
    let step = phi[r] / d;
    if !step.is_finite() {
        return Err(if d == R::ZERO && phi[r].is_finite() {
            NewtonError::Singular { iteration: 0, column: k, pivot: R::ZERO, largest: R::ZERO }
        } else {
            NewtonError::NonFinite { iteration: 0 }
        });
    }
    q[k] -= step;
    perm[at] = r;
    let v = d.abs();
    Ok(PivotInfo { smallest: v, largest: v })
}

/// One implicit block and what its Newton iteration reads.
struct Block<'a, M, R, const N: usize> {
    mechanism: &'a M,
    b: usize,
    rows: &'a [usize],
    columns: &'a [usize],
    options: &'a NewtonOptions<R>,
    /// The remaining error a chord step may leave, [`CHORD_ROUND_OFF`] ε max |q_k| over all
    /// unknowns at the start, as for the whole system.
    round_off: R,
    size: core::marker::PhantomData<[R; N]>,
}

impl<M: Mechanism<N, R>, R: Real, const N: usize> Block<'_, M, R, N> {
    /// max |Φ_i| over the block's rows, NaN when one is NaN.
    fn residual(&self, phi: &[R; N]) -> R {
        let (mut m, mut nan) = (R::ZERO, false);
        for &r in self.rows {
            let a = phi[r].abs();
            nan |= a.is_nan();
            m = if a > m { a } else { m };
        }
        if nan { R::NAN } else { m }
    }

    /// Solves the block with its factors in `jac` and `perm` for the step −D⁻¹ Φ, into `x`;
    /// false when the step is not finite.
    fn step(
        &self,
        jac: &[[R; N]; N],
        perm: &[usize; N],
        phi: &[R; N],
        x: &mut [R; MAX_BLOCK],
    ) -> bool {
        let s = self.columns.len();
        self.mechanism.solve_block(self.b, jac, perm, phi, &mut x[..s]);
        let mut finite = true;
        for v in &mut x[..s] {
            *v = -*v;
            finite &= v.is_finite();
        }
        finite
    }

    /// Moves the block's unknowns by `x`.
    fn add(&self, q: &mut [R; N], x: &[R; MAX_BLOCK]) {
        for (&k, &d) in self.columns.iter().zip(x) {
            q[k] += d;
        }
    }
}

impl<M: Mechanism<N, R>, R: Real, const N: usize> Block<'_, M, R, N> {
    /// Newton on the block (see the module docs): its iterations and the pivots of its factors
    /// at the final q.
    fn newton(
        &mut self,
        q: &mut [R; N],
        t: R,
        phi: &mut [R; N],
        jac: &mut [[R; N]; N],
        perm: &mut [usize; N],
        chord: bool,
    ) -> Result<(u32, PivotInfo<R>), NewtonError<R>> {
        let options = self.options;
        let mut x = [R::ZERO; MAX_BLOCK];
        let mut start = [R::ZERO; MAX_BLOCK];
        // The chord step's (residual before, max |Δ|), awaiting its verdict.
        let mut pending = None;
        let mut iterations = 0;
        if chord {
            self.mechanism.block_residual(self.b, false, q, t, phi, jac);
            let before = self.residual(phi);
            if before <= options.tolerance && self.step(jac, perm, phi, &mut x) {
                for (s, &k) in start.iter_mut().zip(self.columns) {
                    *s = q[k];
                }
                let s = self.columns.len();
                pending = Some((before, max_abs(&x[..s])));
                self.add(q, &x);
                iterations = 1;
            }
        }
        loop {
            self.mechanism.block_residual(self.b, true, q, t, phi, jac);
            let residual = self.residual(phi);
            let mut verdict = status(residual, iterations, options);
            if let Some((before, step)) = pending.take() {
                if residual.is_nan() || residual > before {
                    // The chord step made things worse: Newton from the start.
                    for (&s, &k) in start.iter().zip(self.columns) {
                        q[k] = s;
                    }
                    continue;
                }
                if verdict == Status::Converged
                    && residual * step > before * self.round_off
                    && iterations < options.max_iterations
                {
                    verdict = Status::Continue;
                }
            }
            match verdict {
                Status::Converged => {
                    let pivots = self.factor(jac, perm, iterations)?;
                    return Ok((iterations, pivots));
                }
                Status::Continue => {}
                Status::Exhausted => {
                    return Err(NewtonError::NotConverged { iterations, residual });
                }
                Status::NonFinite => return Err(NewtonError::NonFinite { iteration: iterations }),
            }
            self.factor(jac, perm, iterations)?;
            if !self.step(jac, perm, phi, &mut x) {
                return Err(NewtonError::NonFinite { iteration: iterations });
            }
            self.add(q, &x);
            iterations += 1;
        }
    }

    /// Factors the block's diagonal block, refusing it as singular when its smallest |pivot|
    /// is at most the pivot ratio times its largest.
    fn factor(
        &self,
        jac: &mut [[R; N]; N],
        perm: &mut [usize; N],
        iteration: u32,
    ) -> Result<PivotInfo<R>, NewtonError<R>> {
        match self.mechanism.factor_block(self.b, jac, perm, self.options.pivot_ratio) {
            Ok(p) => Ok(p),
            Err(Singular::SmallPivot { column, pivot, largest }) => Err(NewtonError::Singular {
                iteration,
                column: self.columns.get(column).copied().unwrap_or(0),
                pivot,
                largest,
            }),
            Err(Singular::NonFinite { .. }) => Err(NewtonError::NonFinite { iteration }),
        }
    }
}

#[cfg(test)]
mod tests;
