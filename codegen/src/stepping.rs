//! Step control shared by both engines: step subdivision, the continuity check and the
//! classification of a step that cannot be taken (singular, branch jump, no convergence).
//!
//! This file uses `std` only: mechgen compiles it into the generic engine and copies it,
//! unchanged, into the driver of every generated solver, so that both engines take the same
//! decisions from the same rules.
//!
//! From the last accepted point (t_a, q_a, q̇_a, q̈_a) the engine is asked for the point at the
//! next grid time t_b, starting Newton from its predictor. An attempt is rejected when
//! - Newton fails (no convergence, a pivot of Φ_q at most 1e-12 of the largest, NaN), or
//! - Newton converged but the pivot ratio ρ = min |u_kk| / max |u_kk| of the dense LU with
//!   partial pivoting of Φ_q at the result (a cheap estimate of 1/κ(Φ_q)) is at most
//!   [`SINGULAR_RATIO`], or
//! - the engine's own check fails (the generic engine's joint-angle branch test), or
//! - the continuity check fails: the Hermite defect of the step,
//!   E = q_b − q_a − h/2 (q̇_a + q̇_b) − h²/12 (q̈_a − q̈_b),
//!   exceeds [`CONTINUITY`] times the displacement q_b − q_a, plus [`FLOOR`], in the
//!   position or the Euler parameters of some body.
//!   Along a smooth motion E = O(h⁵): for q = sin ωt it is (ωh)⁴/720 of the displacement, so
//!   0.05 admits steps up to ωh ≈ 2.4 rad; a step that lands on another assembly branch, or on
//!   a singular configuration whose velocities are unbounded, has a defect of the order of the
//!   displacement itself.
//!
//! A rejected attempt is retried from the last accepted point with half the sub-step, down to
//! 2⁻[`MAX_HALVINGS`] of the grid step; accepted sub-steps become the new start (they are not
//! reported) and after two in a row the sub-step doubles again.
//! When even the smallest sub-step is rejected, or when sub-steps no longer change t (far
//! from 0 the spacing of floating-point time exceeds 2⁻²⁰ of the grid step: about 1.2e-4 at
//! t = 1e12 and 16 at t = 1e17, so t + h rounds back to t), the analysis stops at the grid
//! time t_b, and the failure is classified with ρ:
//! - `singular` when the last rejection was singular (Newton's pivots, or ρ ≤
//!   [`SINGULAR_RATIO`] at the result), or when ρ at the configuration closest
//!   to the failure (the last accepted sub-step, or the rejected attempt if it converged) is
//!   below [`SINGULAR_DROP`] times ρ at t_a. A step of 2⁻²⁰ of the grid step moves q by about
//!   that fraction, so, unless Φ_q is becoming singular, it changes ρ by as little; approaching
//!   a limit (turning) point, σ_min(Φ_q) ∝ √(t* − t), so ρ falls by about 2¹⁰ over the
//!   sub-steps. By the implicit function theorem Newton can always advance a small enough step
//!   from a configuration where Φ_q is regular, so a failure at the smallest sub-step with a
//!   falling ρ is a singular configuration, not a convergence problem;
//! - `branch_jump` when the last rejection was the continuity or branch check while ρ stayed;
//! - `no_convergence` otherwise.

/// Rejected attempts halve the sub-step at most this many times (2⁻²⁰ ≈ 1e-6 of the grid step).
pub const MAX_HALVINGS: u32 = 20;

/// The Hermite defect may be this fraction of the displacement (see the module docs).
pub const CONTINUITY: f64 = 0.05;

/// Absolute allowance of the continuity check (in f64; it grows as √ε, see [`floor`]), per
/// unit of max(1, |q|) of the group: a
/// converged q is only known to about tolerance · ‖Φ_q⁻¹‖, 1e-6 covers a condition of 1e4 at
/// the default tolerance 1e-10, and any branch jump moves a body by much more than that.
pub const FLOOR: f64 = 1e-6;

/// A converged attempt whose pivot ratio ρ is at most this (in f64; √ε in general, see
/// [`singular_ratio`]) is rejected as singular: κ(Φ_q)
/// ≥ 1/ρ ≈ 1/√ε, so the velocity and acceleration solves keep less than half the digits of
/// double precision, and the position itself is only known to about tolerance / ρ. Newton
/// converging onto a singular configuration (a grid time that lands exactly on it) stops
/// within about the tolerance of it, with ρ of the order of the tolerance.
pub const SINGULAR_RATIO: f64 = 1.5e-8;

/// A failure at the smallest sub-step is singular when the pivot ratio closest to it fell
/// below this fraction of the ratio at the start of the step (see the module docs).
pub const SINGULAR_DROP: f64 = 0.1;

/// One analysed time point, in the coordinates of every moving body (7 each: x, y, z, e0, e1,
/// e2, e3, body by body).
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// Time.
    pub t: f64,
    /// Positions.
    pub q: Vec<f64>,
    /// Velocities.
    pub qd: Vec<f64>,
    /// Accelerations.
    pub qdd: Vec<f64>,
    /// Newton iterations of this attempt.
    pub iterations: u32,
    /// max |Φ_i| at q.
    pub residual: f64,
    /// ρ = min |u_kk| / max |u_kk| of the dense LU with partial pivoting of the engine's Φ_q
    /// at q (0 for an exactly singular Φ_q).
    pub pivot_ratio: f64,
}

/// Why an attempt was rejected or the analysis stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Trouble {
    /// Φ_q is singular.
    Singular,
    /// Newton did not converge.
    NoConvergence,
    /// The step left the assembly branch it started on.
    BranchJump,
}

impl Trouble {
    /// The contract's `error.kind`.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Singular => "singular",
            Self::NoConvergence => "no_convergence",
            Self::BranchJump => "branch_jump",
        }
    }
}

/// A rejected attempt.
#[derive(Clone, Debug, PartialEq)]
pub struct Rejection {
    /// What went wrong.
    pub trouble: Trouble,
    /// A sentence for the user.
    pub message: String,
    /// The converged point, when Newton converged but a check refused it.
    pub point: Option<Box<Point>>,
    /// The moving body (index among the moving bodies) that jumped, if one is known.
    pub body: Option<usize>,
}

/// Why the analysis stopped at a grid time.
#[derive(Clone, Debug, PartialEq)]
pub struct Stop {
    /// The failure's kind.
    pub trouble: Trouble,
    /// The grid time that could not be reached.
    pub t: f64,
    /// A sentence for the user.
    pub message: String,
    /// The configuration closest to the failure: the rejected attempt if it converged, else
    /// the last accepted (sub-)step, else, at the first time point, `None`.
    pub near: Option<Box<Point>>,
    /// The moving body that jumped, for branch jumps found by the continuity check.
    pub body: Option<usize>,
}

/// What an engine provides to the step control.
pub trait Engine {
    /// Solves positions, velocities and accelerations at `t`, starting Newton from the
    /// engine's predictor at the last accepted point (or from the initial estimates before
    /// the first).
    ///
    /// # Errors
    /// The rejection, when Newton fails or the engine's own checks refuse the result.
    fn attempt(&mut self, t: f64) -> Result<Point, Rejection>;

    /// Makes `p` the last accepted point (after an accepted attempt, `p` is that attempt;
    /// after a rejected one, the point before it).
    fn accept(&mut self, p: &Point);

    /// The machine epsilon of the engine's arithmetic (f64 unless it computes in f32), which
    /// scales [`singular_ratio`] and [`floor`].
    fn epsilon(&self) -> f64 {
        f64::EPSILON
    }
}

/// [`SINGULAR_RATIO`] for an arithmetic of machine epsilon `eps`: √eps.
#[must_use]
pub fn singular_ratio(eps: f64) -> f64 {
    SINGULAR_RATIO / f64::EPSILON.sqrt() * eps.sqrt()
}

/// [`FLOOR`] for an arithmetic of machine epsilon `eps`: it grows as √eps.
#[must_use]
pub fn floor(eps: f64) -> f64 {
    FLOOR / f64::EPSILON.sqrt() * eps.sqrt()
}

/// The body and the ratio of defect to allowance where the continuity check fails worst, or
/// `None` when the step from `a` to `b` passes (see the module docs).
#[must_use]
pub fn discontinuity(a: &Point, b: &Point, eps: f64) -> Option<(usize, f64)> {
    let h = b.t - a.t;
    let mut worst: Option<(usize, f64)> = None;
    for body in 0..a.q.len() / 7 {
        for (lo, hi) in [(0, 3), (3, 7)] {
            let (mut defect, mut moved, mut size) = (0.0_f64, 0.0_f64, 0.0_f64);
            for k in 7 * body + lo..7 * body + hi {
                let dq = b.q[k] - a.q[k];
                let e = dq - 0.5 * h * (a.qd[k] + b.qd[k]) - h * h / 12.0 * (a.qdd[k] - b.qdd[k]);
                defect += e * e;
                moved += dq * dq;
                size = size.max(b.q[k].abs());
            }
            let allowed = CONTINUITY * moved.sqrt() + floor(eps) * size.max(1.0);
            // NaN fails too, and counts as the worst.
            let ratio = defect.sqrt() / allowed;
            let fails = ratio.is_nan() || ratio > 1.0;
            if fails && worst.is_none_or(|(_, r)| ratio.is_nan() || ratio > r) {
                worst = Some((body, ratio));
            }
        }
    }
    worst
}

/// One attempt from `a` to `t` with every check: the engine's, then continuity.
fn try_step<E: Engine>(engine: &mut E, a: &Point, t: f64) -> Result<Point, Rejection> {
    let b = engine.attempt(t)?;
    let eps = engine.epsilon();
    if singular(&b, eps) {
        return Err(singular_point(b, eps));
    }
    match discontinuity(a, &b, eps) {
        None => Ok(b),
        Some((body, ratio)) => Err(Rejection {
            trouble: Trouble::BranchJump,
            message: format!(
                "the step from t = {} to t = {} is not continuous: its Hermite defect is {ratio:.3e} \
                 times the allowance",
                a.t, b.t
            ),
            point: Some(Box::new(b)),
            body: Some(body),
        }),
    }
}

/// Whether the pivot ratio of a converged point is at most [`SINGULAR_RATIO`] (or NaN).
fn singular(p: &Point, eps: f64) -> bool {
    p.pivot_ratio.is_nan() || p.pivot_ratio <= singular_ratio(eps)
}

/// The rejection of a converged point whose pivot ratio is at most [`SINGULAR_RATIO`].
fn singular_point(b: Point, eps: f64) -> Rejection {
    Rejection {
        trouble: Trouble::Singular,
        message: format!(
            "Φ_q is singular at t = {}: the pivot ratio of its LU is {:.3e} (at most {:.1e})",
            b.t,
            b.pivot_ratio,
            singular_ratio(eps)
        ),
        point: Some(Box::new(b)),
        body: None,
    }
}

/// Solves the first time point (no continuity to check).
///
/// # Errors
/// [`Stop`] at `t` with the trouble of the attempt.
pub fn first<E: Engine>(engine: &mut E, t: f64) -> Result<Point, Stop> {
    let eps = engine.epsilon();
    let attempt = engine
        .attempt(t)
        .and_then(|p| if singular(&p, eps) { Err(singular_point(p, eps)) } else { Ok(p) });
    match attempt {
        Ok(p) => {
            engine.accept(&p);
            Ok(p)
        }
        Err(r) => {
            Err(Stop { trouble: r.trouble, t, message: r.message, near: r.point, body: r.body })
        }
    }
}

/// Advances from the accepted point `a` to the grid time `t`, subdividing the step when an
/// attempt is rejected. Returns the point at `t` and the Newton iterations spent on the way
/// (sub-steps and rejected attempts included).
///
/// Every pass of the loop either returns, raises the halving level (at most
/// [`MAX_HALVINGS`] times in a row without progress) or accepts a sub-step that moves t
/// forward by at least one sub-step of the deepest level, so the loop ends. A sub-step that
/// no longer changes t (t + h rounds to t in the engine's arithmetic, as it does for grids
/// far from 0, e.g. t ≈ 1e12 with h < 6e-5) cannot make progress: the analysis stops there
/// as if the smallest sub-step had been rejected.
///
/// # Errors
/// [`Stop`] when even the smallest sub-step is rejected, or when sub-steps no longer change
/// t (see the module docs).
pub fn advance<E: Engine>(engine: &mut E, a: &Point, t: f64) -> Result<(Point, u32), Stop> {
    let step = t - a.t;
    let mut current = a.clone();
    let mut level = 0_u32;
    let mut streak = 0_u32;
    let mut iterations = 0_u32;
    // The last rejected attempt: a halving level above 0 always follows one.
    let mut rejected: Option<Rejection> = None;
    loop {
        let h = step / f64::from(1_u32 << level);
        // The last sub-step lands exactly on the grid time.
        let target = if level == 0 || current.t + 1.5 * h >= t { t } else { current.t + h };
        if level > 0 && target <= current.t {
            return Err(stalled(a, &current, t, h, rejected));
        }
        match try_step(engine, &current, target) {
            Ok(b) => {
                iterations = iterations.saturating_add(b.iterations);
                if target == t {
                    engine.accept(&b);
                    return Ok((b, iterations));
                }
                if b.t <= current.t {
                    // The engine rounded the target back onto the start (a coarser time
                    // type than f64): the sub-step changed nothing.
                    engine.accept(&current);
                    return Err(stalled(a, &current, t, h, rejected));
                }
                engine.accept(&b);
                current = b;
                streak += 1;
                if streak == 2 && level > 0 {
                    level -= 1;
                    streak = 0;
                }
            }
            Err(r) => {
                iterations =
                    iterations.saturating_add(r.point.as_ref().map_or(0, |p| p.iterations));
                engine.accept(&current);
                streak = 0;
                if level < MAX_HALVINGS {
                    level += 1;
                    rejected = Some(r);
                    continue;
                }
                return Err(classify(a, &current, t, r, None));
            }
        }
    }
}

/// The stop when a sub-step of length `h` no longer changes t at `current`, classified as a
/// failure at the smallest sub-step from the last rejection (see the module docs).
fn stalled(a: &Point, current: &Point, t: f64, h: f64, rejected: Option<Rejection>) -> Stop {
    let r = rejected.unwrap_or_else(|| Rejection {
        trouble: Trouble::NoConvergence,
        message: "no attempt was rejected".to_owned(),
        point: None,
        body: None,
    });
    let why = format!(
        "sub-steps of {h:.3e} no longer change t = {} (the spacing of floating-point time there \
         is {:.3e})",
        current.t,
        spacing(current.t)
    );
    classify(a, current, t, r, Some(why))
}

/// The distance from `x` to the next floating-point number away from zero.
fn spacing(x: f64) -> f64 {
    let x = x.abs();
    if x.is_finite() { f64::from_bits(x.to_bits() + 1) - x } else { f64::NAN }
}

/// The verdict on a step rejected at the smallest sub-step (see the module docs).
///
/// `stalled` says why sub-stepping ended early, when sub-steps no longer changed t.
fn classify(a: &Point, last: &Point, t: f64, r: Rejection, stalled: Option<String>) -> Stop {
    let start = a.pivot_ratio;
    let (near, ratio) = match r.point {
        Some(p) if p.pivot_ratio <= last.pivot_ratio => {
            let ratio = p.pivot_ratio;
            (p, ratio)
        }
        _ => (Box::new(last.clone()), last.pivot_ratio),
    };
    let fell = ratio < SINGULAR_DROP * start;
    let trouble = match r.trouble {
        Trouble::Singular => Trouble::Singular,
        _ if fell => Trouble::Singular,
        other => other,
    };
    let limit = stalled.map_or_else(
        || format!("no sub-step down to 2^-{MAX_HALVINGS} of the grid step could pass"),
        |why| format!("no sub-step could pass: {why}"),
    );
    let message = match trouble {
        Trouble::Singular => format!(
            "Φ_q is singular near t = {}: the pivot ratio of its LU fell from {:.3e} at t = {} \
             to {:.3e}, and {limit} (last rejection: {})",
            near.t, start, a.t, ratio, r.message
        ),
        _ => format!("{limit} near t = {}: {}", last.t, r.message),
    };
    let body = if trouble == Trouble::BranchJump { r.body } else { None };
    Stop { trouble, t, message, near: Some(near), body }
}

#[cfg(test)]
mod tests;
