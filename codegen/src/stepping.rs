//! The step control of [`runtime::step`] for engines that keep their points in `Vec`s: the
//! generic engine ([`crate::generic::Analysis::run`]) and the tests' interpreted engines.
//!
//! The rules (step subdivision, the continuity check and the classification of a step that
//! cannot be taken as singular, branch jump or no convergence, with their constants) live in
//! [`runtime::step`], whose module docs state them; the driver of every generated solver runs
//! them over `runtime::Solver`, and embedded callers through `runtime::Solver::advance_to`.
//! This module adapts an [`Engine`] that returns whole [`Point`]s to [`runtime::step::Stepper`]
//! and turns its [`runtime::step::Stop`] into a [`Stop`] with the message written out.

use runtime::step::{self as rules, Coordinates, Groups, Reason, Sample, Stepper};

pub use runtime::step::{
    CONTINUITY, FLOOR, MAX_HALVINGS, SINGULAR_DROP, SINGULAR_RATIO, Trouble, floor, singular_ratio,
};

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

/// The body and the ratio of defect to allowance where the continuity check fails worst, or
/// `None` when the step from `a` to `b` passes ([`runtime::step::discontinuity`] over bodies of
/// 7 coordinates).
#[must_use]
pub fn discontinuity(a: &Point, b: &Point, eps: f64) -> Option<(usize, f64)> {
    rules::discontinuity(Groups::Bodies, b.t - a.t, &coordinates(a), &coordinates(b), eps)
}

/// The coordinates of `p` as the rules read them.
fn coordinates(p: &Point) -> Coordinates<'_, f64> {
    Coordinates { q: &p.q, qd: &p.qd, qdd: &p.qdd }
}

/// The scalars of `p`.
fn sample(p: &Point) -> Sample<f64> {
    Sample { t: p.t, iterations: p.iterations, residual: p.residual, pivot_ratio: p.pivot_ratio }
}

/// An [`Engine`] under the rules: the last accepted point and the candidate, kept whole.
struct Adapter<'e, E> {
    engine: &'e mut E,
    accepted: Option<Point>,
    candidate: Option<Point>,
}

impl<E: Engine> Stepper<f64> for Adapter<'_, E> {
    type Cause = String;

    fn attempt(&mut self, t: f64) -> Result<Sample<f64>, rules::Rejection<f64, String>> {
        self.candidate = None;
        match self.engine.attempt(t) {
            Ok(p) => {
                let s = sample(&p);
                self.candidate = Some(p);
                Ok(s)
            }
            Err(r) => {
                let converged = r.point.map(|p| {
                    let s = sample(&p);
                    self.candidate = Some(*p);
                    s
                });
                Err(rules::Rejection {
                    trouble: r.trouble,
                    reason: Reason::Engine(r.message),
                    converged,
                    body: r.body,
                })
            }
        }
    }

    fn accepted(&self) -> Coordinates<'_, f64> {
        self.accepted.as_ref().map_or(Coordinates { q: &[], qd: &[], qdd: &[] }, coordinates)
    }

    fn candidate(&self) -> Coordinates<'_, f64> {
        self.candidate.as_ref().map_or(Coordinates { q: &[], qd: &[], qdd: &[] }, coordinates)
    }

    fn groups(&self) -> Groups<'_> {
        Groups::Bodies
    }

    fn accept(&mut self) {
        if let Some(p) = self.candidate.take() {
            self.engine.accept(&p);
            self.accepted = Some(p);
        }
    }

    fn reject(&mut self) {
        if let Some(a) = &self.accepted {
            self.engine.accept(a);
        }
    }

    fn epsilon(&self) -> f64 {
        self.engine.epsilon()
    }
}

impl<E> Adapter<'_, E> {
    /// The [`Stop`] of the rules' `stop`, with the configuration closest to the failure.
    fn stop(&mut self, stop: &rules::Stop<f64, String>) -> Stop {
        let near = stop
            .near
            .and_then(|n| if n.rejected { self.candidate.take() } else { self.accepted.take() });
        Stop {
            trouble: stop.trouble,
            t: stop.t,
            message: stop.to_string(),
            near: near.map(Box::new),
            body: stop.body,
        }
    }
}

/// Solves the first time point (no continuity to check).
///
/// # Errors
/// [`Stop`] at `t` with the trouble of the attempt.
pub fn first<E: Engine>(engine: &mut E, t: f64) -> Result<Point, Stop> {
    let mut adapter = Adapter { engine, accepted: None, candidate: None };
    match rules::first(&mut adapter, t) {
        Ok(_) => Ok(adapter.accepted.take().expect("the rules accepted the point they return")),
        Err(stop) => Err(adapter.stop(&stop)),
    }
}

/// Advances from the accepted point `a` to the grid time `t`, subdividing the step when an
/// attempt is rejected. Returns the point at `t` and the Newton iterations spent on the way
/// (sub-steps and rejected attempts included).
///
/// # Errors
/// [`Stop`] when even the smallest sub-step is rejected, or a sub-step no longer changes t
/// (see [`runtime::step`]).
pub fn advance<E: Engine>(engine: &mut E, a: &Point, t: f64) -> Result<(Point, u32), Stop> {
    let mut adapter = Adapter { engine, accepted: Some(a.clone()), candidate: None };
    match rules::advance(&mut adapter, sample(a), t) {
        Ok((_, iterations)) => Ok((
            adapter.accepted.take().expect("the rules accepted the point they return"),
            iterations,
        )),
        Err(stop) => Err(adapter.stop(&stop)),
    }
}

#[cfg(test)]
mod tests;
