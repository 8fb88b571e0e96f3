//! Shipped mechanism descriptions (`examples/*.toml`) and the library side of the example
//! programs, so that tests run exactly what the examples run.

pub mod stewart;

use std::path::PathBuf;

use generated::rssr;
use runtime::{NewtonError, NewtonOptions, Solver};

/// The directory holding the shipped example descriptions.
#[must_use]
pub fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// What a control loop over the R-S-S-R observed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoopSummary {
    /// Control periods run.
    pub periods: usize,
    /// Newton iterations over all periods.
    pub iterations: u64,
    /// Largest |ω| of the rocker (rad/s), from the generated accessor, as a sanity value.
    pub max_rocker_rate: f64,
    /// Largest max |Φ_i| after a period.
    pub max_residual: f64,
}

/// A control loop on the generated R-S-S-R solver: every period of `dt` seconds the crank
/// angle advances, the loop asks for the position and velocity only (no acceleration is
/// computed or paid for) and reads the rocker's rate. Nothing here allocates: the solver,
/// its Jacobian and its factors live on the stack.
///
/// # Errors
/// The Newton failure, if the mechanism cannot follow.
pub fn rssr_control_loop(periods: usize, dt: f64) -> Result<LoopSummary, NewtonError> {
    let mut solver = Solver::new(rssr::Rssr, rssr::Q0);
    solver.set_options(NewtonOptions { tolerance: 1e-12, ..NewtonOptions::DEFAULT });
    solver.set_predictor(true);
    let mut summary =
        LoopSummary { periods: 0, iterations: 0, max_rocker_rate: 0.0, max_residual: 0.0 };
    let mut omega = [[0.0; 3]; rssr::BODIES];
    for k in 0..periods {
        let report = solver.position(k as f64 * dt)?;
        if solver.velocity().is_err() {
            break;
        }
        summary.periods += 1;
        summary.iterations += u64::from(report.iterations);
        summary.max_residual = summary.max_residual.max(report.residual);
        rssr::angular_velocities(solver.q(), solver.qd(), k as f64 * dt, &mut omega);
        let w = omega[rssr::body::ROCKER];
        summary.max_rocker_rate =
            summary.max_rocker_rate.max((w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt());
    }
    Ok(summary)
}

#[cfg(test)]
mod tests;
