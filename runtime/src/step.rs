//! Step control: step subdivision, the continuity check and the classification of a step that
//! cannot be taken (singular, branch jump, no convergence).
//!
//! These rules are the one implementation every caller runs: [`Solver::advance_to`] for
//! embedded callers, the driver of every generated solver that the command line builds, and the
//! generic engine (through the [`Stepper`] trait, which works on slices so that an engine with
//! run-time sizes implements it as well as one with fixed-size arrays).
//! Nothing here allocates: the coordinates stay with the stepper, and the rules see them as
//! slices and the scalars of each point as a [`Sample`].
//!
//! From the last accepted point (t_a, q_a, q̇_a, q̈_a) the stepper is asked for the point at the
//! requested time t_b, starting Newton from its predictor. An attempt is rejected when
//! - Newton fails (no convergence, a pivot of Φ_q at most 1e-12 of the largest, NaN), or
//! - Newton converged but the pivot ratio ρ = min |u_kk| / max |u_kk| of the LU of Φ_q at the
//!   result (a cheap estimate of 1/κ(Φ_q): the factors the solve kept, dense LU with partial
//!   pivoting whenever a static pivot order's ratio is within [`STRUCTURED_MARGIN`] of the
//!   bound) is at most [`SINGULAR_RATIO`], or
//! - the stepper's own check fails (the generic engine's joint-angle branch test), or
//! - the continuity check fails: the Hermite defect of the step,
//!   E = q_b − q_a − h/2 (q̇_a + q̇_b) − h²/12 (q̈_a − q̈_b),
//!   exceeds [`CONTINUITY`] times the displacement q_b − q_a, plus [`FLOOR`], in some group of
//!   coordinates ([`Groups`]: the position or the Euler parameters of a body).
//!   Along a smooth motion E = O(h⁵): for q = sin ωt it is (ωh)⁴/720 of the displacement, so
//!   0.05 admits steps up to ωh ≈ 2.4 rad; a step that lands on another assembly branch, or on
//!   a singular configuration whose velocities are unbounded, has a defect of the order of the
//!   displacement itself.
//!
//! A rejected attempt is retried from the last accepted point with half the sub-step, down to
//! 2⁻[`MAX_HALVINGS`] of the requested step; accepted sub-steps become the new start (they are
//! not reported) and after two in a row the sub-step doubles again.
//! When even the smallest sub-step is rejected, the step stops at the requested time t_b, and
//! the failure is classified with ρ:
//! - `singular` when the last rejection was singular (Newton's pivots, or ρ ≤
//!   [`SINGULAR_RATIO`] at the result), or when ρ at the configuration closest
//!   to the failure (the last accepted sub-step, or the rejected attempt if it converged) is
//!   below [`SINGULAR_DROP`] times ρ at t_a. A step of 2⁻²⁰ of the requested step moves q by
//!   about that fraction, so, unless Φ_q is becoming singular, it changes ρ by as little;
//!   approaching a limit (turning) point, σ_min(Φ_q) ∝ √(t* − t), so ρ falls by about 2¹⁰ over
//!   the sub-steps. By the implicit function theorem Newton can always advance a small enough
//!   step from a configuration where Φ_q is regular, so a failure at the smallest sub-step with
//!   a falling ρ is a singular configuration, not a convergence problem;
//! - `branch_jump` when the last rejection was the continuity or branch check while ρ stayed;
//! - `no_convergence` otherwise.
//!
//! Every loop terminates: a sub-step that no longer changes t in floating point (t_a + h = t_a,
//! as on a grid at t = 1e17) stops the step at once, `singular` by the same rule on ρ, else
//! `no_convergence`, instead of halving and doubling forever.
//!
//! The stepped parameter is the time t. A stepper whose drivers are run-time inputs rather
//! than laws of t interpolates its inputs between the start and the end of the requested step
//! at the sub-step times it is asked for, so the rules stay the same.
//!
//! [`Solver::advance_to`]: crate::Solver::advance_to

#[cfg(test)]
mod tests;

use core::fmt;

use crate::Real;

/// Rejected attempts halve the sub-step at most this many times (2⁻²⁰ ≈ 1e-6 of the requested
/// step).
pub const MAX_HALVINGS: u32 = 20;

/// The Hermite defect may be this fraction of the displacement (see the module docs).
pub const CONTINUITY: f64 = 0.05;

/// Absolute allowance of the continuity check (in f64; it grows as √ε, see [`floor`]), per
/// unit of max(1, |q|) of the group: a converged q is only known to about
/// tolerance · ‖Φ_q⁻¹‖, 1e-6 covers a condition of 1e4 at the default tolerance 1e-10, and any
/// branch jump moves a body by much more than that.
pub const FLOOR: f64 = 1e-6;

/// A converged attempt whose pivot ratio ρ is at most this (in f64; √ε in general, see
/// [`singular_ratio`]) is rejected as singular: κ(Φ_q) ≥ 1/ρ ≈ 1/√ε, so the velocity and
/// acceleration solves keep less than half the digits of double precision, and the position
/// itself is only known to about tolerance / ρ. Newton converging onto a singular
/// configuration (a requested time that lands exactly on it) stops within about the tolerance
/// of it, with ρ of the order of the tolerance.
pub const SINGULAR_RATIO: f64 = 1.5e-8;

/// A converged attempt whose factors of Φ_q come from one of the mechanism's static pivot
/// orders and whose pivot ratio is at most this multiple of [`SINGULAR_RATIO`] takes its ratio
/// from dense LU with partial pivoting instead ([`crate::Solver::pivot_ratio`]).
///
/// A static order pivots by threshold (|l| ≤ 10, [`crate::lu::MAX_MULTIPLIER`]), so its
/// pivots differ from partial pivoting's: its ratio lies between 0.025 and 1 times the dense
/// one along the motions of the shipped four-bar, R-S-S-R and slider-crank. Within a factor
/// of 100 of the bound (four times the largest gap seen), where the two could fall on either
/// side of it, the dense ratio decides, so the verdict on [`SINGULAR_RATIO`] is dense LU's;
/// above, the static order's ratio is reported as it is, and no second factorisation is paid.
pub const STRUCTURED_MARGIN: f64 = 100.0;

/// A failure at the smallest sub-step is singular when the pivot ratio closest to it fell
/// below this fraction of the ratio at the start of the step (see the module docs).
pub const SINGULAR_DROP: f64 = 0.1;

/// [`SINGULAR_RATIO`] for an arithmetic of machine epsilon `eps`: √eps.
#[must_use]
pub fn singular_ratio<R: Real>(eps: R) -> R {
    R::from_f64(SINGULAR_RATIO / libm::sqrt(f64::EPSILON) * libm::sqrt(eps.to_f64()))
}

/// The pivot ratio above which the factors of a static pivot order of one diagonal block are
/// kept (Newton block by block, `Mechanism::factor_block`): [`STRUCTURED_MARGIN`] times
/// [`singular_ratio`], or `ratio` when larger. At or below it the block's dense LU with partial
/// pivoting decides, so the pivots the step control sees near a singular configuration are
/// those of partial pivoting, as with the whole system's static orders.
#[must_use]
#[inline]
pub fn structured_bound<R: Real>(ratio: R) -> R {
    ratio.max(structured_floor())
}

/// [`STRUCTURED_MARGIN`] times [`singular_ratio`] in the arithmetic `R`: the pivot ratio at or
/// below which factors of a static pivot order are confirmed by dense LU with partial pivoting.
#[must_use]
#[inline]
pub fn structured_floor<R: Real>() -> R {
    // In double precision a constant (the comparison folds); else computed from ε.
    if R::EPSILON.to_f64() == f64::EPSILON {
        R::from_f64(STRUCTURED_MARGIN * SINGULAR_RATIO)
    } else {
        R::from_f64(STRUCTURED_MARGIN) * singular_ratio(R::EPSILON)
    }
}

/// [`FLOOR`] for an arithmetic of machine epsilon `eps`: it grows as √eps.
#[must_use]
pub fn floor<R: Real>(eps: R) -> R {
    R::from_f64(FLOOR / libm::sqrt(f64::EPSILON) * libm::sqrt(eps.to_f64()))
}

/// The relative error a reported velocity or acceleration may have and still count as trusted:
/// six significant digits.
pub const DIGITS: f64 = 1e-6;

/// Which of a step's derivatives the condition estimate κ̂ of Φ_q cannot vouch for to
/// [`DIGITS`] (see [`suspect`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Suspect {
    /// q̇: κ̂² ε > [`DIGITS`].
    pub velocity: bool,
    /// q̈: κ̂³ ε > [`DIGITS`].
    pub acceleration: bool,
}

impl Suspect {
    /// Whether any derivative is suspect.
    #[must_use]
    pub const fn any(self) -> bool {
        self.velocity || self.acceleration
    }

    /// The names of the suspect quantities, in the order of the contract's `"suspect"` list.
    pub fn names(self) -> impl Iterator<Item = &'static str> {
        [("velocity", self.velocity), ("acceleration", self.acceleration)]
            .into_iter()
            .filter_map(|(name, on)| on.then_some(name))
    }
}

/// The digits rule: which derivatives of a step whose Φ_q has the condition estimate
/// `condition` (κ̂ = 1/ρ, the reciprocal of a pivot ratio) may have lost more than all but six
/// significant digits in an arithmetic of machine epsilon `eps`.
///
/// Newton leaves the residual at the rounding error of evaluating Φ, about ε in relative terms,
/// so the position is known to about κ ε. Velocities solve Φ_q(q) q̇ = ν(q): the solve adds
/// κ ε, and the position's error moves Φ_q and ν by that much, which Φ_q⁻¹ amplifies again, so
/// q̇ is known to about κ² ε. Accelerations solve Φ_q q̈ = γ(q, q̇), and γ carries q̇'s error,
/// amplified once more: κ³ ε. These are the first-order worst cases; they are met near a
/// bifurcation, where the error of each stage lies along the direction the next one amplifies
/// (README, "Where the methods fail", has the measurements). NaN counts as suspect.
#[must_use]
pub fn suspect<R: Real>(condition: R, eps: R) -> Suspect {
    let (k, e) = (condition.to_f64(), eps.to_f64());
    let over = |x: f64| {
        !matches!(
            x.partial_cmp(&DIGITS),
            Some(core::cmp::Ordering::Less | core::cmp::Ordering::Equal)
        )
    };
    Suspect { velocity: over(k * k * e), acceleration: over(k * k * k * e) }
}

/// A cheap condition estimate (that of the factors the solve kept) at least
/// [`suspect_condition`] / `CONDITION_MARGIN` is replaced by that of a dense LU of Φ_q
/// equilibrated by powers of two ([`crate::Solver::condition`]).
///
/// The cheap one is of Φ_q in the description's units and, for static pivot orders, by
/// threshold pivoting; it was up to 8 times below the equilibrated one (the parallelogram
/// four-bar 1e-3 rad past its flat configuration: 500 against 4,000), so below 1/16 of the
/// bound it cannot hide a flag.
pub const CONDITION_MARGIN: f64 = 16.0;

/// The smallest condition estimate at which [`suspect`] flags an acceleration:
/// (DIGITS / ε)^⅓, 1651 in f64.
#[must_use]
pub fn suspect_condition<R: Real>(eps: R) -> R {
    R::from_f64(libm::cbrt(DIGITS / eps.to_f64()))
}

/// Why an attempt was rejected or a step stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Trouble {
    /// Φ_q is singular.
    Singular,
    /// Newton did not converge.
    NoConvergence,
    /// The step left the assembly branch it started on.
    BranchJump,
    /// An equation that cannot hold together with the others (two drivers that contradict
    /// each other). The rules here never produce it; a stepper's own check may.
    Inconsistent,
}

impl Trouble {
    /// The contract's `error.kind`.
    #[must_use]
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::Singular => "singular",
            Self::NoConvergence => "no_convergence",
            Self::BranchJump => "branch_jump",
            Self::Inconsistent => "inconsistent",
        }
    }
}

impl fmt::Display for Trouble {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The scalars of one solved point; its coordinates stay with the [`Stepper`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample<R = f64> {
    /// Time.
    pub t: R,
    /// Newton iterations of the attempt that solved it.
    pub iterations: u32,
    /// max |Φ_i| at the point.
    pub residual: R,
    /// ρ = min |u_kk| / max |u_kk| of the LU of Φ_q at the point (0 for an exactly singular
    /// Φ_q): the engine's own factorisation, by partial pivoting near the bound (see
    /// [`STRUCTURED_MARGIN`]).
    pub pivot_ratio: R,
}

/// The coordinates of one point, as slices of equal length.
#[derive(Clone, Copy, Debug)]
pub struct Coordinates<'a, R = f64> {
    /// Positions q.
    pub q: &'a [R],
    /// Velocities q̇.
    pub qd: &'a [R],
    /// Accelerations q̈.
    pub qdd: &'a [R],
}

/// How the continuity check groups the coordinates: the defect and the displacement of a
/// group are Euclidean norms over its coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Groups<'a> {
    /// Bodies of 7 coordinates each (x, y, z, e0, e1, e2, e3): two groups per body, its
    /// position and its Euler parameters. The group's number is the body's index.
    Bodies,
    /// Every coordinate on its own (the strictest check): for a reduced system whose unknowns
    /// are not whole bodies. The group's number is the coordinate's index.
    Each,
    /// Group k holds coordinates `ends[k − 1]..ends[k]` (from 0 for k = 0), with `ends`
    /// increasing and its last entry the number of coordinates.
    Ends(&'a [usize]),
}

/// Why the stepper's last attempt was rejected.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reason<R, C> {
    /// The stepper's own: a Newton failure or one of its checks, with its cause.
    Engine(C),
    /// Newton converged at `t`, but ρ = `ratio` is at most `bound` ([`singular_ratio`]).
    Singular {
        /// Time of the attempt.
        t: R,
        /// Its pivot ratio.
        ratio: R,
        /// The bound.
        bound: R,
    },
    /// The step from `from` to `to` failed the continuity check: its Hermite defect is `ratio`
    /// times the allowance.
    Discontinuous {
        /// Start of the step.
        from: R,
        /// End of the step.
        to: R,
        /// Defect over allowance in the worst group.
        ratio: R,
    },
}

impl<R: Real, C: fmt::Display> fmt::Display for Reason<R, C> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Engine(cause) => cause.fmt(f),
            Self::Singular { t, ratio, bound } => write!(
                f,
                "Φ_q is singular at t = {t}: the pivot ratio of its LU is {ratio:.3e} (at most \
                 {bound:.1e})"
            ),
            Self::Discontinuous { from, to, ratio } => write!(
                f,
                "the step from t = {from} to t = {to} is not continuous: its Hermite defect is \
                 {ratio:.3e} times the allowance"
            ),
        }
    }
}

/// A rejected attempt.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rejection<R, C> {
    /// What went wrong.
    pub trouble: Trouble,
    /// Why, for the user.
    pub reason: Reason<R, C>,
    /// The converged point, when Newton converged but a check refused it; the stepper keeps its
    /// coordinates as [`Stepper::candidate`].
    pub converged: Option<Sample<R>>,
    /// The group (a moving body, see [`Groups`]) that jumped, if one is known.
    pub body: Option<usize>,
}

impl<R, C> Rejection<R, C> {
    /// A rejection by the stepper itself, without a converged point or a body.
    pub const fn engine(trouble: Trouble, cause: C) -> Self {
        Rejection { trouble, reason: Reason::Engine(cause), converged: None, body: None }
    }
}

/// The configuration closest to a failure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Near<R> {
    /// Its scalars (time, pivot ratio, …).
    pub sample: Sample<R>,
    /// `true`: the rejected attempt, whose coordinates the stepper keeps as
    /// [`Stepper::candidate`]; `false`: the last accepted (sub-)step, [`Stepper::accepted`].
    pub rejected: bool,
}

/// How a step came to stop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Verdict<R> {
    /// The first point ([`first`]) was refused.
    First,
    /// Even the smallest sub-step was rejected; `start` is the point the step started from.
    Halved {
        /// The start of the step.
        start: Sample<R>,
        /// The last accepted (sub-)step.
        last: Sample<R>,
    },
    /// A sub-step of `h` no longer changed the time of the last accepted (sub-)step.
    Stalled {
        /// The start of the step.
        start: Sample<R>,
        /// The last accepted (sub-)step.
        last: Sample<R>,
        /// The sub-step.
        h: R,
    },
}

/// Why a step stopped at the requested time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stop<R, C> {
    /// The failure's kind.
    pub trouble: Trouble,
    /// The requested time that could not be reached.
    pub t: R,
    /// The configuration closest to the failure: the rejected attempt if it converged (and its
    /// ρ is not above the last accepted point's), else the last accepted (sub-)step, else, at
    /// the first point, `None`.
    pub near: Option<Near<R>>,
    /// The group (a moving body) that jumped, for branch jumps found by the continuity check.
    pub body: Option<usize>,
    /// How it stopped.
    pub verdict: Verdict<R>,
    /// The last rejection.
    pub rejection: Rejection<R, C>,
}

impl<R: Real, C: fmt::Display> fmt::Display for Stop<R, C> {
    /// A sentence for the user.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = &self.rejection.reason;
        let near_t = self.near.map_or(self.t, |n| n.sample.t);
        let ratio = self.near.map_or(R::NAN, |n| n.sample.pivot_ratio);
        match self.verdict {
            Verdict::First => r.fmt(f),
            Verdict::Halved { start, .. } if self.trouble == Trouble::Singular => write!(
                f,
                "Φ_q is singular near t = {near_t}: the pivot ratio of its LU fell from {:.3e} at \
                 t = {} to {ratio:.3e}, and no sub-step down to 2^-{MAX_HALVINGS} of the grid \
                 step could pass (last rejection: {r})",
                start.pivot_ratio, start.t
            ),
            Verdict::Halved { last, .. } => write!(
                f,
                "no sub-step down to 2^-{MAX_HALVINGS} of the grid step could pass near t = {}: \
                 {r}",
                last.t
            ),
            Verdict::Stalled { start, last, h } => write!(
                f,
                "the step from t = {} to t = {} cannot be subdivided further: a sub-step of {h:e} \
                 no longer changes t = {} in floating point (pivot ratio {:.3e} at the start, \
                 {ratio:.3e} near t = {near_t}; last rejection: {r})",
                start.t, self.t, last.t, start.pivot_ratio
            ),
        }
    }
}

impl<R: Real, C: fmt::Display + fmt::Debug> core::error::Error for Stop<R, C> {}

/// What an engine provides to the step control.
///
/// It holds two points: the last accepted one and the candidate, the result of the last
/// attempt. The rules read their coordinates as slices and never copy them.
pub trait Stepper<R: Real> {
    /// The cause of a rejection by the stepper itself (a Newton failure, …).
    type Cause;

    /// Solves positions, velocities and accelerations at `t`, starting Newton from the
    /// predictor at the last accepted point (or from the initial estimates before the first),
    /// and keeps the result as the candidate.
    ///
    /// # Errors
    /// The rejection, when Newton fails or the stepper's own checks refuse the result (then
    /// with the converged point's [`Sample`], the candidate holding its coordinates).
    fn attempt(&mut self, t: R) -> Result<Sample<R>, Rejection<R, Self::Cause>>;

    /// The coordinates of the last accepted point (only read once a point was accepted).
    fn accepted(&self) -> Coordinates<'_, R>;

    /// The coordinates of the candidate.
    fn candidate(&self) -> Coordinates<'_, R>;

    /// How the continuity check groups the coordinates.
    fn groups(&self) -> Groups<'_>;

    /// Makes the candidate the last accepted point.
    fn accept(&mut self);

    /// Returns to the last accepted point after a rejected attempt (to the initial estimates
    /// before the first), keeping the candidate's coordinates for the caller's report.
    fn reject(&mut self);

    /// The machine epsilon of the stepper's arithmetic, which scales [`singular_ratio`] and
    /// [`floor`]; `R::EPSILON` unless the engine computes in a narrower type than `R`.
    fn epsilon(&self) -> R {
        R::EPSILON
    }
}

/// The group and the ratio of defect to allowance where the continuity check fails worst, or
/// `None` when the step of length `h` from `a` to `b` passes (see the module docs).
#[must_use]
pub fn discontinuity<R: Real>(
    groups: Groups<'_>,
    h: R,
    a: &Coordinates<'_, R>,
    b: &Coordinates<'_, R>,
    eps: R,
) -> Option<(usize, R)> {
    let (half, twelve) = (R::from_f64(0.5), R::from_f64(12.0));
    let (continuity, floor) = (R::from_f64(CONTINUITY), floor(eps));
    let (h_half, h2_twelfth) = (half * h, h * h / twelve);
    let mut worst: Option<(usize, R)> = None;
    // A group that fails (its defect above its allowance, or NaN): the ratio is worked out only
    // then, so that a passing step costs no division.
    let mut fail = |group: usize, defect: R, allowed: R| {
        let ratio = defect / allowed;
        if worst.is_none_or(|(_, r)| ratio.is_nan() || ratio > r) {
            worst = Some((group, ratio));
        }
    };
    let mut check = |group: usize, range: core::ops::Range<usize>| {
        let (mut defect, mut moved, mut size) = (R::ZERO, R::ZERO, R::ZERO);
        for k in range {
            let dq = b.q[k] - a.q[k];
            let e = dq - h_half * (a.qd[k] + b.qd[k]) - h2_twelfth * (a.qdd[k] - b.qdd[k]);
            defect += e * e;
            moved += dq * dq;
            size = size.max(b.q[k].abs());
        }
        let allowed = continuity * moved.sqrt() + floor * size.max(R::ONE);
        if exceeds(defect, allowed * allowed) {
            fail(group, defect.sqrt(), allowed);
        }
    };
    let n = a.q.len().min(b.q.len());
    match groups {
        Groups::Bodies => {
            for body in 0..n / 7 {
                check(body, 7 * body..7 * body + 3);
                check(body, 7 * body + 3..7 * body + 7);
            }
        }
        Groups::Each => {
            // The same test for groups of one coordinate, without square roots: a first pass
            // without branches (which the compiler unrolls), then, only when it fails, a second
            // that finds the worst coordinate.
            let test = |aq: R, aqd: R, aqdd: R, bq: R, bqd: R, bqdd: R| {
                let dq = bq - aq;
                let e = dq - h_half * (aqd + bqd) - h2_twelfth * (aqdd - bqdd);
                (e.abs(), continuity * dq.abs() + floor * bq.abs().max(R::ONE))
            };
            let points = || {
                let pairs = a.q.iter().zip(a.qd).zip(a.qdd).zip(b.q.iter().zip(b.qd).zip(b.qdd));
                pairs.map(|(((&aq, &aqd), &aqdd), ((&bq, &bqd), &bqdd))| {
                    test(aq, aqd, aqdd, bq, bqd, bqdd)
                })
            };
            // Written so that NaN fails too.
            if !points().fold(true, |pass, (e, allowed)| pass & (e <= allowed)) {
                for (k, (e, allowed)) in points().enumerate() {
                    if exceeds(e, allowed) {
                        fail(k, e, allowed);
                    }
                }
            }
        }
        Groups::Ends(ends) => {
            let mut lo = 0;
            for (group, &hi) in ends.iter().enumerate() {
                check(group, lo..hi.min(n).max(lo));
                lo = hi.min(n).max(lo);
            }
        }
    }
    worst
}

/// Whether `x` exceeds `bound`, or either is NaN.
fn exceeds<R: Real>(x: R, bound: R) -> bool {
    !matches!(x.partial_cmp(&bound), Some(core::cmp::Ordering::Less | core::cmp::Ordering::Equal))
}

/// Whether the pivot ratio of a converged point is at most [`SINGULAR_RATIO`] (or NaN).
fn singular<R: Real>(p: &Sample<R>, eps: R) -> bool {
    p.pivot_ratio.is_nan() || p.pivot_ratio <= singular_ratio(eps)
}

/// The rejection of a converged point whose pivot ratio is at most [`SINGULAR_RATIO`].
fn singular_point<R: Real, C>(b: Sample<R>, eps: R) -> Rejection<R, C> {
    Rejection {
        trouble: Trouble::Singular,
        reason: Reason::Singular { t: b.t, ratio: b.pivot_ratio, bound: singular_ratio(eps) },
        converged: Some(b),
        body: None,
    }
}

/// One attempt from the last accepted point `a` to `t` with every check: the stepper's, then
/// the pivot ratio, then continuity.
fn try_step<R: Real, S: Stepper<R>>(
    stepper: &mut S,
    a: &Sample<R>,
    t: R,
) -> Result<Sample<R>, Rejection<R, S::Cause>> {
    let b = stepper.attempt(t)?;
    let eps = stepper.epsilon();
    if singular(&b, eps) {
        return Err(singular_point(b, eps));
    }
    let jump =
        discontinuity(stepper.groups(), b.t - a.t, &stepper.accepted(), &stepper.candidate(), eps);
    match jump {
        None => Ok(b),
        Some((body, ratio)) => Err(Rejection {
            trouble: Trouble::BranchJump,
            reason: Reason::Discontinuous { from: a.t, to: b.t, ratio },
            converged: Some(b),
            body: Some(body),
        }),
    }
}

/// Solves the first point (no continuity to check) and accepts it.
///
/// # Errors
/// [`Stop`] at `t` with the trouble of the attempt; the stepper is back at its estimates.
pub fn first<R: Real, S: Stepper<R>>(
    stepper: &mut S,
    t: R,
) -> Result<Sample<R>, Stop<R, S::Cause>> {
    let eps = stepper.epsilon();
    let attempt = stepper
        .attempt(t)
        .and_then(|p| if singular(&p, eps) { Err(singular_point(p, eps)) } else { Ok(p) });
    match attempt {
        Ok(p) => {
            stepper.accept();
            Ok(p)
        }
        Err(r) => {
            stepper.reject();
            Err(Stop {
                trouble: r.trouble,
                t,
                near: r.converged.map(|sample| Near { sample, rejected: true }),
                body: r.body,
                verdict: Verdict::First,
                rejection: r,
            })
        }
    }
}

/// Advances from the last accepted point `start` to the time `t`, subdividing the step when an
/// attempt is rejected. Returns the point at `t`, accepted, and the Newton iterations spent on
/// the way (sub-steps and rejected attempts included).
///
/// # Errors
/// [`Stop`] when even the smallest sub-step is rejected, or a sub-step no longer changes t
/// (see the module docs); the stepper is then at the last accepted (sub-)step.
pub fn advance<R: Real, S: Stepper<R>>(
    stepper: &mut S,
    start: Sample<R>,
    t: R,
) -> Result<(Sample<R>, u32), Stop<R, S::Cause>> {
    let step = t - start.t;
    let forward = step >= R::ZERO;
    let (one_and_half, two) = (R::from_f64(1.5), R::from_f64(2.0));
    let mut current = start;
    let mut level = 0_u32;
    let mut streak = 0_u32;
    let mut iterations = 0_u32;
    let mut divisor = R::ONE;
    let mut last: Option<Rejection<R, S::Cause>> = None;
    loop {
        let h = step / divisor;
        // The last sub-step lands exactly on the requested time.
        let end = current.t + one_and_half * h;
        let reaches = if forward { end >= t } else { end <= t };
        let target = if level == 0 || reaches { t } else { current.t + h };
        if target != t
            && target == current.t
            && let Some(r) = last
        {
            return Err(classify(start, current, t, r, Some(h)));
        }
        match try_step(stepper, &current, target) {
            Ok(b) => {
                iterations += b.iterations;
                stepper.accept();
                if target == t {
                    return Ok((b, iterations));
                }
                // An engine that rounds t (a single-precision solver) can accept a sub-step
                // that leaves t where it was: no progress, so the step stalls here.
                if b.t == current.t
                    && let Some(r) = last
                {
                    return Err(classify(start, current, t, r, Some(h)));
                }
                current = b;
                streak += 1;
                if streak == 2 && level > 0 {
                    level -= 1;
                    divisor /= two;
                    streak = 0;
                }
            }
            Err(r) => {
                iterations += r.converged.map_or(0, |p| p.iterations);
                stepper.reject();
                streak = 0;
                if level < MAX_HALVINGS {
                    level += 1;
                    divisor *= two;
                    last = Some(r);
                    continue;
                }
                return Err(classify(start, current, t, r, None));
            }
        }
    }
}

/// The verdict on a step rejected at the smallest sub-step, or whose sub-step `stalled` no
/// longer changes t (see the module docs).
fn classify<R: Real, C>(
    start: Sample<R>,
    last: Sample<R>,
    t: R,
    r: Rejection<R, C>,
    stalled: Option<R>,
) -> Stop<R, C> {
    let near = match r.converged {
        Some(p) if p.pivot_ratio <= last.pivot_ratio => Near { sample: p, rejected: true },
        _ => Near { sample: last, rejected: false },
    };
    let fell = near.sample.pivot_ratio < R::from_f64(SINGULAR_DROP) * start.pivot_ratio;
    let trouble = match r.trouble {
        Trouble::Singular => Trouble::Singular,
        _ if fell => Trouble::Singular,
        _ if stalled.is_some() => Trouble::NoConvergence,
        other => other,
    };
    let body = if trouble == Trouble::BranchJump { r.body } else { None };
    let verdict = match stalled {
        Some(h) => Verdict::Stalled { start, last, h },
        None => Verdict::Halved { start, last },
    };
    Stop { trouble, t, near: Some(near), body, verdict, rejection: r }
}
