//! A user's crate whose mechanism solver is generated at build time: `build.rs` calls
//! `codegen::build::Builder` on `planar_four_bar.toml`, and this file includes the result.
//! The generated module depends only on `runtime`; nothing here allocates.

include!(concat!(env!("OUT_DIR"), "/mechgen.rs"));

use core::fmt;

use runtime::{NewtonError, NewtonOptions, SolveError, Solver};

/// Why the control loop stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stopped {
    /// Newton's method failed on the position (singular Φ_q, no convergence).
    Position(NewtonError),
    /// The velocity solve failed.
    Velocity(SolveError),
}

impl fmt::Display for Stopped {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Position(e) => write!(f, "position: {e}"),
            Self::Velocity(e) => write!(f, "velocity: {e}"),
        }
    }
}

impl core::error::Error for Stopped {}

/// What one control period observed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Time (s).
    pub t: f64,
    /// The rocker's angle from global x (rad), read from its Euler parameters.
    pub rocker_angle: f64,
    /// The rocker's angular velocity about z (rad/s).
    pub rocker_rate: f64,
    /// Newton iterations this period.
    pub iterations: u32,
}

/// The rocker's angle ψ about z and its rate ψ̇ from the unknowns: a rotation about z by ψ
/// has p = [cos ψ/2, 0, 0, sin ψ/2], so ψ = 2 atan2(e3, e0) and ψ̇ = 2 (e0 ė3 − e3 ė0) for a
/// unit p.
fn rocker(q: &[f64; planar_four_bar::N], qd: &[f64; planar_four_bar::N]) -> (f64, f64) {
    let index = |name: &str| planar_four_bar::UNKNOWNS.iter().position(|u| *u == name);
    let (Some(e0), Some(e3)) = (index("rocker.e0"), index("rocker.e3")) else {
        unreachable!("the description has a moving body named rocker")
    };
    let angle = 2.0 * q[e3].atan2(q[e0]);
    (angle, 2.0 * (q[e0] * qd[e3] - q[e3] * qd[e0]))
}

/// A control loop: every `dt` seconds the crank angle advances, the solver returns the
/// position and velocity (no acceleration is computed) and `each` receives the rocker's
/// angle and rate, as a controller would.
///
/// ```
/// let mut last = None;
/// build_rs_user::control_loop(10, 0.01, |s| last = Some(s)).expect("the four-bar follows");
/// let s = last.unwrap();
/// assert!((s.t - 0.09).abs() < 1e-12);
/// ```
///
/// # Errors
///
/// The solver's failure, if the mechanism cannot follow the crank.
pub fn control_loop(periods: usize, dt: f64, mut each: impl FnMut(Sample)) -> Result<(), Stopped> {
    let mut solver = Solver::new(planar_four_bar::PlanarFourBar, planar_four_bar::Q0);
    solver.set_options(NewtonOptions { tolerance: 1e-12, ..NewtonOptions::DEFAULT });
    for k in 0..periods {
        let t = k as f64 * dt;
        let report = solver.position(t).map_err(Stopped::Position)?;
        solver.velocity().map_err(Stopped::Velocity)?;
        let (rocker_angle, rocker_rate) = rocker(solver.q(), solver.qd());
        each(Sample { t, rocker_angle, rocker_rate, iterations: report.iterations });
    }
    Ok(())
}

#[cfg(test)]
mod tests;
