//! Newton–Raphson on Φ(q, t) = 0 at a fixed time, bounded and allocation-free.
//!
//! Each iteration evaluates Φ and Φ_q at q, stops if max |Φ_i| ≤ tolerance, and otherwise
//! factors Φ_q ([`Factors`]: the mechanism's static pivot orders, else dense LU), solves
//! Φ_q Δ = −Φ and sets q ← q + Δ.
//! Once converged, [`Mechanism::normalize_moved`] projects q and, if that moved q by more than
//! round-off ([`moved_by_round_off`]), Φ and Φ_q are evaluated again, so the reported residual
//! and the factored Jacobian left in the caller's storage belong to the final q (the velocity
//! and acceleration solves reuse that factorisation).
//! If the projection pushed the residual above the tolerance, the iteration simply goes on.
//! A step that lands within the tolerance ends the iteration only when its estimated remaining
//! error is at round-off ([`CHORD_ROUND_OFF`]); otherwise one more Newton step follows.
//! [`solve_with_chord`] first corrects a start that already meets the tolerance (a good
//! prediction) by one chord step with factors kept from a nearby configuration.
//! When to stop is decided by [`status`] alone, which is tested on its own.
//! A mechanism with [`Mechanism::BLOCK_NEWTON`] is solved block by block instead, each block
//! of its block-lower-triangular form iterating on its own (see `by_block`).

mod by_block;
#[cfg(test)]
mod tests;

pub use by_block::MAX_BLOCK;

use core::fmt;

use crate::factors::Factors;
use crate::lu::{PivotInfo, Singular};
use crate::{Mechanism, Real};

/// Stopping rule and pivot test of a Newton solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonOptions<R = f64> {
    /// Converged when max |Φ_i| ≤ `tolerance`, in the units of each row of Φ.
    pub tolerance: R,
    /// The most Newton steps (factor, solve, update) that one solve may take.
    pub max_iterations: u32,
    /// The Jacobian is singular when its smallest |pivot| ≤ `pivot_ratio` · its largest
    /// (see [`lu::factor_with_ratio`](crate::lu::factor_with_ratio)).
    pub pivot_ratio: R,
}

impl<R: Real> NewtonOptions<R> {
    /// `tolerance` 1e-10, `max_iterations` 25, `pivot_ratio` 1e-12 ([`lu::DEFAULT_PIVOT_RATIO`](crate::lu::DEFAULT_PIVOT_RATIO))
    /// in `f64`; in `f32` `tolerance` 1e-4 and `pivot_ratio` 1e-5 ([`Real::DEFAULT_TOLERANCE`],
    /// [`Real::DEFAULT_PIVOT_RATIO`]).
    ///
    /// A tolerance of 1e-10 is about a million times the rounding error of residuals of unit
    /// size, and a well-posed problem started within the region of quadratic convergence takes
    /// 3 to 6 steps, so 25 leaves room for poor starting estimates without looping for long on
    /// hopeless ones.
    pub const DEFAULT: NewtonOptions<R> = NewtonOptions {
        tolerance: R::DEFAULT_TOLERANCE,
        max_iterations: 25,
        pivot_ratio: R::DEFAULT_PIVOT_RATIO,
    };
}

impl<R: Real> Default for NewtonOptions<R> {
    /// Returns [`NewtonOptions::DEFAULT`].
    fn default() -> Self {
        NewtonOptions::DEFAULT
    }
}

/// What a converged solve did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonReport<R = f64> {
    /// Newton steps taken; 0 when the starting estimate already satisfied the tolerance.
    pub iterations: u32,
    /// max |Φ_i| at the final, normalised q.
    pub residual: R,
    /// The smallest and largest |pivot| of the factors of Φ_q at the final q that the solve
    /// leaves in the caller's storage (a static pivot order's, or dense LU's).
    pub pivots: PivotInfo<R>,
}

/// Why a Newton solve failed.
///
/// `iteration` counts the Newton steps completed before the failure: 0 means at the starting
/// estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NewtonError<R = f64> {
    /// Φ_q could not be factored: its smallest |pivot| ≤ `pivot_ratio` · `largest`.
    ///
    /// For example a slider-crank at a dead centre, or a circle met tangentially by a line.
    Singular {
        /// Newton steps completed before the singular Jacobian was met.
        iteration: u32,
        /// The elimination step (column) with the small pivot.
        column: usize,
        /// That |pivot|.
        pivot: R,
        /// The largest |pivot| it was compared with.
        largest: R,
    },
    /// `max_iterations` steps did not bring max |Φ_i| down to the tolerance.
    ///
    /// For example a start far from any solution, or a mechanism that cannot be assembled.
    NotConverged {
        /// Newton steps taken, equal to `max_iterations`.
        iterations: u32,
        /// max |Φ_i| after the last step.
        residual: R,
    },
    /// Φ, Φ_q or the Newton step contained a NaN or an infinity.
    ///
    /// For example t = NaN, or a Newton step so large that it overflowed.
    NonFinite {
        /// Newton steps completed before the non-finite value was met.
        iteration: u32,
    },
}

impl<R: Real> fmt::Display for NewtonError<R> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            NewtonError::Singular { iteration, column, pivot, largest } => write!(
                f,
                "singular Jacobian after {iteration} Newton steps: pivot {pivot:e} in column \
                 {column} against largest pivot {largest:e}"
            ),
            NewtonError::NotConverged { iterations, residual } => write!(
                f,
                "Newton did not converge in {iterations} steps: max residual {residual:e}"
            ),
            NewtonError::NonFinite { iteration } => {
                write!(f, "non-finite residual, Jacobian or step after {iteration} Newton steps")
            }
        }
    }
}

impl<R: Real> core::error::Error for NewtonError<R> {}

/// The verdict of the stopping rule on one evaluation of Φ.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// max |Φ_i| ≤ tolerance: stop with success.
    Converged,
    /// Not yet converged and steps are left: take another Newton step.
    Continue,
    /// Not converged and `max_iterations` steps are spent: stop with
    /// [`NewtonError::NotConverged`].
    Exhausted,
    /// The residual is NaN or infinite: stop with [`NewtonError::NonFinite`].
    NonFinite,
}

/// The stopping rule: the verdict on `residual` = max |Φ_i| after `iterations` steps.
///
/// Convergence wins over exhaustion, so a solve whose last allowed step lands within the
/// tolerance succeeds.
#[must_use]
pub fn status<R: Real>(residual: R, iterations: u32, options: &NewtonOptions<R>) -> Status {
    if !residual.is_finite() {
        Status::NonFinite
    } else if residual <= options.tolerance {
        Status::Converged
    } else if iterations >= options.max_iterations {
        Status::Exhausted
    } else {
        Status::Continue
    }
}

/// max |x_i|, or NaN if some x_i is NaN (a plain `f64::max` fold would drop it).
///
/// Inlined: it runs several times per time step, over all N unknowns or rows. On long slices
/// four independent running maxima (lanes) let the compiler vectorise it: one running maximum
/// is a chain of dependent selects the compiler keeps scalar (on 34 R-S-S-R loops, 680
/// unknowns, the lanes save 1.6 % of a step's instructions; below 64 entries they cost more
/// than they save: 2 % on one loop). The maximum does not depend on the order it is taken in,
/// so the result is the same.
///
/// Below 64 entries each entry is read on its own, behind a test for NaN (a branch that is
/// always taken the same way): x was usually written entry by entry just before (Φ by the
/// generated code, a solution by its substitutions), and a 16-byte load of two entries, which
/// branch-free code invites the compiler to use, cannot take them from the processor's store
/// buffer (store-to-load forwarding needs one store to cover the load) and waits until both
/// stores reach the cache, on the step's critical path. Reading entry by entry saved about 8 ns
/// of the R-S-S-R's 176 ns step (BENCHMARKS.md, "R-S-S-R step"), more than the branch-free sum
/// test for NaN it replaces saved in instructions.
#[inline]
pub(crate) fn max_abs<R: Real>(x: &[R]) -> R {
    const LANES: usize = 4;
    if x.len() < 64 {
        let mut m = R::ZERO;
        for &v in x {
            let a = v.abs();
            if a.is_nan() {
                return R::NAN;
            }
            m = if a > m { a } else { m };
        }
        return m;
    }
    let (mut m, mut nan) = ([R::ZERO; LANES], [false; LANES]);
    let chunks = x.chunks_exact(LANES);
    let rest = chunks.remainder();
    for c in chunks {
        for i in 0..LANES {
            let a = c[i].abs();
            nan[i] |= a.is_nan();
            m[i] = if a > m[i] { a } else { m[i] };
        }
    }
    for (i, &v) in rest.iter().enumerate() {
        let a = v.abs();
        nan[i] |= a.is_nan();
        m[i] = if a > m[i] { a } else { m[i] };
    }
    let top = m[0].max(m[1]).max(m[2].max(m[3]));
    if nan.iter().any(|&n| n) { R::NAN } else { top }
}

/// Whether every x_i is finite.
///
/// Branch-free and inlined, so that the compiler can vectorise it: it runs after the step
/// control's velocity and acceleration solves (`Solver::solve_derivatives`; a plain
/// [`Solver::velocity`](crate::Solver::velocity) tests entry by entry as it copies).
#[inline]
pub(crate) fn all_finite<R: Real>(x: &[R]) -> bool {
    let mut finite = true;
    for &v in x {
        finite &= v.is_finite();
    }
    finite
}

/// Solves Φ(q, t) = 0 for q by Newton's method, starting from `q`.
///
/// A step Δ that brings max |Φ_i| from r₀ down to r₁ ≤ tolerance ends the iteration only when
/// its estimated remaining error (r₁ / r₀) |Δ| is below [`CHORD_ROUND_OFF`] ε |q|; otherwise
/// one more Newton step follows, and its result is accepted if it meets the tolerance.
/// Meeting the tolerance alone would leave the position off by up to κ r₁ / |Φ_q| (κ the
/// condition number of Φ_q), which the velocity and acceleration solves amplify by κ and κ²
/// again: one step from a good start (the predictor's) typically lands at r₁ ≈ 1e-13 with a
/// tolerance of 1e-10, three orders above round-off.
/// The remaining error is e₁ = Φ_q⁻¹ Φ(q₁) and |Δ| ≥ r₀ / |Φ_q|, so e₁ ≤ κ (r₁ / r₀) |Δ|: the
/// test bounds the position's error by κ times round-off, the accuracy the digits rule
/// (`step::suspect`) assumes. A start that already meets the tolerance is accepted as it is.
///
/// `phi`, `jac` and `factors` are scratch storage owned by the caller (so `jac`, the only `N × N`
/// array, never lives on this function's stack).
/// On success `q` is the normalised solution, `phi` holds Φ at it, and `jac` and `factors` hold
/// the factors of Φ_q at it, ready for [`Factors::solve`] (when the normalisation moved q by
/// round-off only, Φ and Φ_q are those of q before that move: see [`moved_by_round_off`]).
///
/// # Errors
///
/// [`NewtonError::Singular`], [`NewtonError::NotConverged`] or [`NewtonError::NonFinite`], as
/// documented on each variant.
/// On error `q` holds the last iterate, the contents of `phi` and `jac` are unspecified, and
/// `factors` holds no factors.
pub fn solve<R: Real, M: Mechanism<N, R>, const N: usize>(
    mechanism: &M,
    q: &mut [R; N],
    t: R,
    options: &NewtonOptions<R>,
    phi: &mut [R; N],
    jac: &mut [[R; N]; N],
    factors: &mut Factors<N>,
) -> Result<NewtonReport<R>, NewtonError<R>> {
    if let Some(layout) = M::BLOCKS.filter(|_| M::BLOCK_NEWTON) {
        return by_block::solve(mechanism, layout, q, t, options, phi, jac, factors, false);
    }
    iterate(mechanism, q, t, options, Scratch { phi, jac, factors }, None)
}

/// [`solve`] for a start that is a prediction: when q already meets the tolerance, `jac` and
/// `factors` hold factors (of Φ_q at a nearby configuration, such as the converged position of
/// the previous time step) and `max_iterations` allows a step, q is corrected by one chord
/// step with those factors, q ← q − Φ_q(q_old)⁻¹ Φ(q), instead of being accepted as it is.
///
/// A prediction that meets the tolerance may still be off by up to the tolerance over the
/// smallest singular value of Φ_q, where Newton from a worse start would have landed within
/// round-off; the chord step closes that gap for an evaluation of Φ alone and a solve, where a
/// Newton step costs an evaluation of Φ and Φ_q and a factorisation. From an error e it lands
/// within about ρ e of the solution, ρ = |Φ_q(q_old)⁻¹ (Φ_q(q) − Φ_q(q_old))|.
/// It ends the iteration only when its estimated remaining error (r₁ / r₀) |Δ| is below
/// [`CHORD_ROUND_OFF`] ε |q| (r₀ and r₁ the max |Φ_i| before and after it, Δ the step), as
/// every step of [`solve`] does; otherwise a Newton step follows, with the Φ_q evaluated after
/// the chord step.
/// A chord step that does not reduce max |Φ_i| is undone, and Newton proceeds from the start.
/// Either way it counts as one step.
/// A start that does not meet the tolerance is solved by [`solve`] from the start.
///
/// # Errors
///
/// As [`solve`].
pub fn solve_with_chord<R: Real, M: Mechanism<N, R>, const N: usize>(
    mechanism: &M,
    q: &mut [R; N],
    t: R,
    options: &NewtonOptions<R>,
    phi: &mut [R; N],
    jac: &mut [[R; N]; N],
    factors: &mut Factors<N>,
) -> Result<NewtonReport<R>, NewtonError<R>> {
    if let Some(layout) = M::BLOCKS.filter(|_| M::BLOCK_NEWTON) {
        return by_block::solve(mechanism, layout, q, t, options, phi, jac, factors, true);
    }
    let mut chord = None;
    // A module with no unknowns left (every coordinate explicit) has nothing to step: no chord
    // step is taken or counted.
    if N > 0 && factors.holds_factors() && options.max_iterations > 0 {
        mechanism.residual(q, t, phi);
        let before = max_abs(phi);
        if before <= options.tolerance {
            // Φ_q⁻¹ Φ rather than Φ_q⁻¹ (−Φ): negation is exact and the solve's rounding
            // symmetric, so subtracting it is the same step, bit for bit, for one pass less.
            factors.solve(mechanism, jac, phi);
            // max |Δ_k| is NaN or infinite exactly when some Δ_k is.
            let step = max_abs(phi);
            if step.is_finite() {
                chord = Some(Chord { start: *q, before, step });
                for (qi, d) in q.iter_mut().zip(phi.iter()) {
                    *qi -= *d;
                }
            }
        }
    }
    iterate(mechanism, q, t, options, Scratch { phi, jac, factors }, chord)
}

/// The estimated remaining error a step (Newton's or the chord step) may leave and still end
/// the iteration, in units of the machine epsilon times max |q_k| (see [`solve`] and
/// [`solve_with_chord`]).
///
/// 32 ε ≈ 7e-15 relative: the level of the rounding errors of the Newton step itself, so that
/// the answer agrees with full Newton's to round-off.
pub const CHORD_ROUND_OFF: f64 = 32.0;

/// The caller's storage for one solve.
struct Scratch<'a, R, const N: usize> {
    phi: &'a mut [R; N],
    jac: &'a mut [[R; N]; N],
    factors: &'a mut Factors<N>,
}

/// A chord step taken, awaiting its verdict at the first evaluation after it.
struct Chord<R, const N: usize> {
    /// Where it started.
    start: [R; N],
    /// max |Φ_i| at the start.
    before: R,
    /// max |Δ_k| of the step.
    step: R,
}

/// The last step taken, for the stopping test at the evaluation after it.
#[derive(Clone, Copy)]
struct Step<R> {
    /// max |Φ_i| where it started.
    before: R,
    /// max |Δ_k|.
    size: R,
}

/// Newton's iteration, after a chord step when `chord` is set.
fn iterate<R: Real, M: Mechanism<N, R>, const N: usize>(
    mechanism: &M,
    q: &mut [R; N],
    t: R,
    options: &NewtonOptions<R>,
    scratch: Scratch<'_, R, N>,
    mut chord: Option<Chord<R, N>>,
) -> Result<NewtonReport<R>, NewtonError<R>> {
    let Scratch { phi, jac, factors } = scratch;
    let mut iterations = u32::from(chord.is_some());
    let mut last = chord.as_ref().map(|c| Step { before: c.before, size: c.step });
    // Whether a step was already taken because the one before it left more than round-off: at
    // most one is, so that residuals at the rounding level, which no step reduces, end it.
    let mut refined = false;
    // Whether q was just projected by `normalize`; a second projection in a row is skipped so
    // that a projection that keeps moving the last bits cannot loop forever.
    let mut normalized = false;
    loop {
        factors.evaluate(mechanism, q, t, phi, jac);
        let residual = max_abs(phi);
        let mut verdict = status(residual, iterations, options);
        if let Some(c) = chord.take()
            && (residual.is_nan() || residual > c.before)
        {
            *q = c.start;
            last = None;
            continue;
        }
        if let Some(s) = last {
            let scale = R::from_f64(CHORD_ROUND_OFF) * R::EPSILON * max_abs(q);
            if verdict == Status::Converged
                && !refined
                && residual * s.size > s.before * scale
                && iterations < options.max_iterations
            {
                verdict = Status::Continue;
                refined = true;
            }
        }
        match verdict {
            Status::Converged => {
                if !normalized {
                    normalized = true;
                    if mechanism.normalize_moved(q) {
                        continue;
                    }
                }
                let pivots = factor(mechanism, q, t, jac, factors, options, iterations)?;
                return Ok(NewtonReport { iterations, residual, pivots });
            }
            Status::Continue => {}
            Status::Exhausted => return Err(NewtonError::NotConverged { iterations, residual }),
            Status::NonFinite => return Err(NewtonError::NonFinite { iteration: iterations }),
        }
        factor(mechanism, q, t, jac, factors, options, iterations)?;
        // Δ = −Φ_q⁻¹ Φ, subtracted (see the chord step in `solve_with_chord`).
        factors.solve(mechanism, jac, phi);
        // max |Δ_k| is NaN or infinite exactly when some Δ_k is.
        let size = max_abs(phi);
        if !size.is_finite() {
            return Err(NewtonError::NonFinite { iteration: iterations });
        }
        for (qi, d) in q.iter_mut().zip(phi.iter()) {
            *qi -= *d;
        }
        last = Some(Step { before: residual, size });
        iterations += 1;
        normalized = false;
    }
}

/// Whether the projection moved every coordinate by at most [`ROUND_OFF_MOVE`] ulps of itself.
///
/// Newton converges quadratically, so the normalisation rows are satisfied to about the square
/// of the last step when it stops, and projecting then typically rescales the Euler parameters
/// by 1 ± 1e-16: a move of an ulp or two. Φ and Φ_q at the projected q then differ from their
/// values before the projection by less than the rounding error of evaluating them, and
/// evaluating them again would only repeat that rounding error.
#[must_use]
pub fn moved_by_round_off<R: Real, const N: usize>(before: &[R; N], after: &[R; N]) -> bool {
    let bound = round_off_move_bound::<R>();
    // Branch-free, so that the compiler vectorises it: it runs once per time step.
    let mut within = true;
    for (&b, &a) in before.iter().zip(after) {
        within &= (a - b).abs() <= bound * b.abs();
    }
    within
}

/// [`ROUND_OFF_MOVE`] ε in the type `R`: the largest move of a coordinate x, relative to |x|,
/// that [`moved_by_round_off`] counts as round-off (generated `normalize_moved` functions use it
/// too).
#[inline]
#[must_use]
pub fn round_off_move_bound<R: Real>() -> R {
    R::from_f64(ROUND_OFF_MOVE) * R::EPSILON
}

/// A projection that moves each coordinate by at most this many units of its own last place
/// (machine epsilon relative) counts as round-off (see [`moved_by_round_off`]).
///
/// Scaling a coordinate by 1 + δ moves it by |δ| of itself plus at most half an ulp of
/// rounding, so a bound of 4 ε accepts scale factors within about 3.5 ε of 1, that is
/// normalisation residuals |p|² − 1 below about 7 ε ≈ 1.6e-15, and evaluates again after
/// anything larger.
pub const ROUND_OFF_MOVE: f64 = 4.0;

/// [`Factors::factor`] with its error turned into a [`NewtonError`].
fn factor<R: Real, M: Mechanism<N, R>, const N: usize>(
    mechanism: &M,
    q: &[R; N],
    t: R,
    jac: &mut [[R; N]; N],
    factors: &mut Factors<N>,
    options: &NewtonOptions<R>,
    iteration: u32,
) -> Result<PivotInfo<R>, NewtonError<R>> {
    match factors.factor(mechanism, q, t, jac, options.pivot_ratio) {
        Ok(pivots) => Ok(pivots),
        Err(Singular::SmallPivot { column, pivot, largest }) => {
            Err(NewtonError::Singular { iteration, column, pivot, largest })
        }
        Err(Singular::NonFinite { .. }) => Err(NewtonError::NonFinite { iteration }),
    }
}
