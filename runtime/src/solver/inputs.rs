//! [`Solver::advance_with`]: a step of a mechanism with input drivers towards new input
//! values, under the step control of [`Solver::advance_to`].

use core::borrow::BorrowMut;
use core::fmt;

use super::{AttemptError, Solver, StepReport};
use crate::input::{Driven, first_non_finite};
use crate::step::Stop;
use crate::{Mechanism, Real};

/// Why [`Solver::advance_with`] failed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InputsError<R = f64> {
    /// An input is NaN or infinite; nothing was solved and the solver is unchanged.
    NonFinite {
        /// Index of the input driver (the generated module's `input::NAME`).
        input: usize,
        /// 0 for s, 1 for ṡ, 2 for s̈.
        derivative: usize,
    },
    /// The step control stopped: `branch_jump`, `singular` or `no_convergence`
    /// ([`Stop::trouble`]), as [`Solver::advance_to`] reports it.
    Stop(Stop<R, AttemptError<R>>),
}

impl<R: Real> fmt::Display for InputsError<R> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite { input, derivative } => {
                let what = ["value", "rate", "acceleration"][(*derivative).min(2)];
                write!(f, "the {what} of input {input} is not finite")
            }
            Self::Stop(stop) => stop.fmt(f),
        }
    }
}

impl<R: Real> core::error::Error for InputsError<R> {}

impl<M, const N: usize, R: Real, J: BorrowMut<[[R; N]; N]>> Solver<M, N, R, J>
where
    M: Mechanism<N, R>,
{
    /// The mechanism, to change what it holds (the inputs' segment of a mechanism with input
    /// drivers, see [`Driven`]). The solver's state stays as it is: call
    /// [`Solver::advance_with`] or [`Solver::position`] next.
    pub const fn mechanism_mut(&mut self) -> &mut M {
        // The time terms may depend on the mechanism's state: computed again at the next
        // position.
        self.terms_valid = false;
        &mut self.mechanism
    }

    /// Solves positions, velocities and accelerations at time `t`, where the mechanism's `K`
    /// input drivers take the values `inputs` (`[s, ṡ, s̈]` each, in the generated module's
    /// input order), under the step control of [`Solver::advance_to`].
    ///
    /// Between the point the solver stands on and `t`, each input follows the quintic Hermite
    /// interpolant of its two samples ([`crate::input::Segment`]), so a step whose inputs move
    /// the mechanism far is taken in sub-steps along a smooth path and lands on the branch it
    /// started from, or fails with an error value; it never returns `Ok` on another assembly
    /// branch. The first call solves `t` directly from the solver's estimate.
    ///
    /// # Errors
    ///
    /// [`InputsError::NonFinite`] when an input is NaN or infinite (nothing is solved), else
    /// [`InputsError::Stop`] as [`Solver::advance_to`]. After a stop the solver holds the last
    /// accepted sub-step and the inputs the segment gives there, and the next call continues
    /// from that point towards its own inputs.
    pub fn advance_with<const K: usize>(
        &mut self,
        t: R,
        inputs: &[[R; 3]; K],
    ) -> Result<StepReport<R>, InputsError<R>>
    where
        M: Driven<K, R>,
    {
        if let Some((input, derivative)) = first_non_finite(inputs) {
            return Err(InputsError::NonFinite { input, derivative });
        }
        if !t.is_finite() {
            return Err(InputsError::NonFinite { input: K, derivative: 0 });
        }
        self.mechanism.segment_mut().aim(t, *inputs);
        self.terms_valid = false;
        let result = self.advance_to(t);
        // The segment now starts where the solver stands: at `t` after a success, at the last
        // accepted sub-step (with the inputs it was solved for) after a stop.
        let reached = self.t;
        self.mechanism.segment_mut().settle(reached);
        self.terms_valid = false;
        result.map_err(InputsError::Stop)
    }
}
