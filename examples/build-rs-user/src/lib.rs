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

/// The rocker's angle ψ from global x (continuous across turns, from `previous`) and its
/// rate: the angle of joint D, whose references are global x and the rocker's x, read through
/// the generated accessor by its index constant.
fn rocker(
    solver: &Solver<planar_four_bar::PlanarFourBar, { planar_four_bar::N }>,
    t: f64,
    previous: Option<f64>,
) -> (f64, f64) {
    const D: usize = planar_four_bar::joint_coordinate("D.angle");
    let mut joints = [[0.0; 3]; planar_four_bar::JOINT_COORDINATES];
    planar_four_bar::joint_coordinates(solver.q(), solver.qd(), solver.qdd(), t, &mut joints);
    let [angle, rate, _] = joints[D];
    (previous.map_or(angle, |p| runtime::outputs::unwrap_angle(p, angle)), rate)
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
    let mut previous = None;
    for k in 0..periods {
        let t = k as f64 * dt;
        let report = solver.position(t).map_err(Stopped::Position)?;
        solver.velocity().map_err(Stopped::Velocity)?;
        let (rocker_angle, rocker_rate) = rocker(&solver, t, previous);
        previous = Some(rocker_angle);
        each(Sample { t, rocker_angle, rocker_rate, iterations: report.iterations });
    }
    Ok(())
}

#[cfg(test)]
mod tests;
