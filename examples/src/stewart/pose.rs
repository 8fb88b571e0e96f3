//! The generated solver of the Stewart platform's pose alone (`generated::stewart_platform`,
//! `mechgen generate examples/inputs/stewart.toml --outputs platform`): the generator reduces
//! each U-P-S leg to the distance row of its two end points, so the module solves the
//! platform's 7 unknowns from the six leg lengths (inputs 0 to 5) and computes nothing of the
//! legs. Used as [`super::control`] uses the whole module.

use generated::stewart_platform::{self as sp, Inputs, StewartPlatform};
use runtime::input::Input;
use runtime::{NewtonOptions, Solver};

pub use super::control::plain_step;

use super::{LEGS, Trajectory, leg_lengths};

/// The generated solver of the platform's pose.
pub type PoseSolver = Solver<StewartPlatform, { sp::N }>;

/// The inputs of the generated module for six `[l, l̇, l̈]`.
#[must_use]
pub fn inputs(legs: &[[f64; 3]; LEGS]) -> Inputs {
    let leg = |k: usize| Input { value: legs[k][0], rate: legs[k][1], acceleration: legs[k][2] };
    Inputs { leg1: leg(0), leg2: leg(1), leg3: leg(2), leg4: leg(3), leg5: leg(4), leg6: leg(5) }
}

/// A pose solver standing at the trajectory's pose at `t`, with the description's Newton
/// tolerance (1e-12) and its Taylor predictor on, as [`super::control::solver`].
#[must_use]
pub fn solver(trajectory: &Trajectory, t: f64) -> PoseSolver {
    let start = inputs(&leg_lengths(&trajectory.at(t)));
    let mut solver = Solver::new(StewartPlatform::new(t, &start), sp::Q0);
    solver.set_options(NewtonOptions { tolerance: sp::TOLERANCE, ..NewtonOptions::DEFAULT });
    solver.set_predictor(true);
    solver
}
