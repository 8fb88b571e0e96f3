//! The `no_std`, allocation-free runtime that generated mechanism solvers are compiled against.
//!
//! It holds the [`Mechanism`] trait that generated code implements, an in-place LU
//! factorisation with partial pivoting ([`lu`]), the choice between a mechanism's own
//! structured factorisation and that dense one ([`factors`]), a bounded Newton iteration
//! ([`newton`]), the
//! step-by-step [`Solver`] for positions, velocities and accelerations, the step control that
//! keeps a step on its assembly branch ([`step`], [`Solver::advance_to`]), and a slice-based
//! view of mechanisms ([`dynamic`]).
//! It knows nothing about symbols, descriptions or bodies: a mechanism is a square system of
//! `N` equations in `N` unknowns, with `N` from 1 to several hundred.
//! Non-goals: dynamics (forces, mass matrices), redundant or rectangular systems (those are
//! reduced before code generation), sparse storage and time integration.
//!
//! The crate has no dependencies and uses neither `alloc` nor `unsafe`, so nothing here
//! allocates, by construction.
//! All storage is fixed-size arrays owned by the caller; the only `N × N` array, the Jacobian,
//! is never put on the stack by this crate's functions (see [`Solver`] for where to keep it).
//! Numerical failure (singular Jacobian, no convergence, NaN or infinity) is returned as an
//! error value, never a panic.
//!
//! # Notation
//!
//! | Symbol | Rust name | Meaning |
//! | --- | --- | --- |
//! | q, q̇, q̈ | `q`, `qd`, `qdd` | generalized coordinates and their time derivatives, length N |
//! | t | `t` | time |
//! | Φ(q, t) | `phi` / [`residual`](Mechanism::residual) | constraint residuals, length N |
//! | Φ_q | `jac` / [`jacobian`](Mechanism::jacobian) | ∂Φ/∂q, N × N, row-major: `jac[i][j] = ∂Φ_i/∂q_j` |
//! | ν | `nu` / [`velocity_rhs`](Mechanism::velocity_rhs) | −Φ_t |
//! | γ | `gamma` / [`acceleration_rhs`](Mechanism::acceleration_rhs) | −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt |
//!
//! # Equations
//!
//! Kinematic analysis at time t solves, in order (thesis, ch. 5.2):
//!
//! - positions: Φ(q, t) = 0, by Newton steps Φ_q Δ = −Φ, q ← q + Δ, until max |Φ_i| ≤ tolerance;
//! - velocities: Φ_q q̇ = ν, from Φ̇ = Φ_q q̇ + Φ_t = 0;
//! - accelerations: Φ_q q̈ = γ, from Φ̈ = 0.
//!
//! All three share the matrix Φ_q at the converged q, so it is factored once per time step.
//!
//! # Example
//!
//! A point (x, y) on the unit circle whose x is driven as cos t:
//! Φ = (x² + y² − 1, x − cos t), with the solution q = (cos t, sin t) for 0 < t < π.
//!
//! ```
//! use runtime::{Mechanism, Solver};
//!
//! struct CircleLine;
//!
//! impl Mechanism<2> for CircleLine {
//!     fn residual(&self, q: &[f64; 2], t: f64, phi: &mut [f64; 2]) {
//!         let [x, y] = *q;
//!         *phi = [x * x + y * y - 1.0, x - t.cos()];
//!     }
//!     fn jacobian(&self, q: &[f64; 2], _t: f64, jac: &mut [[f64; 2]; 2]) {
//!         let [x, y] = *q;
//!         *jac = [[2.0 * x, 2.0 * y], [1.0, 0.0]];
//!     }
//!     fn velocity_rhs(&self, _q: &[f64; 2], t: f64, nu: &mut [f64; 2]) {
//!         // Φ_t = (0, sin t).
//!         *nu = [0.0, -t.sin()];
//!     }
//!     fn acceleration_rhs(&self, _q: &[f64; 2], qd: &[f64; 2], t: f64, gamma: &mut [f64; 2]) {
//!         // (Φ_q q̇)_q q̇ = (2ẋ² + 2ẏ², 0), Φ_qt = 0, Φ_tt = (0, cos t).
//!         let [xd, yd] = *qd;
//!         *gamma = [-2.0 * (xd * xd + yd * yd), -t.cos()];
//!     }
//! }
//!
//! let mut solver = Solver::new(CircleLine, [0.9, 0.5]);
//! solver.set_predictor(true);
//! for step in 1..=10 {
//!     let t = 0.1 * f64::from(step);
//!     // A control loop that needs positions only stops here.
//!     let report = solver.position(t)?;
//!     assert!(report.residual <= 1e-10);
//!     let [x, y] = *solver.q();
//!     assert!((x - t.cos()).abs() < 1e-9 && (y - t.sin()).abs() < 1e-9);
//!
//!     // Velocities reuse the factorisation of the converged position.
//!     solver.velocity()?;
//!     let [xd, yd] = *solver.qd();
//!     assert!((xd + t.sin()).abs() < 1e-9 && (yd - t.cos()).abs() < 1e-9);
//!
//!     // So do accelerations, which need the velocities.
//!     solver.acceleration()?;
//!     let [xdd, ydd] = *solver.qdd();
//!     assert!((xdd + t.cos()).abs() < 1e-9 && (ydd + t.sin()).abs() < 1e-9);
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Failures are values: at t = 0 the line x = 1 touches the circle, Φ_q is singular there, and
//! a start on the x axis meets that singular Jacobian at once.
//!
//! ```
//! # use runtime::{Mechanism, NewtonError, Solver};
//! # struct CircleLine;
//! # impl Mechanism<2> for CircleLine {
//! #     fn residual(&self, q: &[f64; 2], t: f64, phi: &mut [f64; 2]) {
//! #         *phi = [q[0] * q[0] + q[1] * q[1] - 1.0, q[0] - t.cos()];
//! #     }
//! #     fn jacobian(&self, q: &[f64; 2], _t: f64, jac: &mut [[f64; 2]; 2]) {
//! #         *jac = [[2.0 * q[0], 2.0 * q[1]], [1.0, 0.0]];
//! #     }
//! #     fn velocity_rhs(&self, _q: &[f64; 2], t: f64, nu: &mut [f64; 2]) {
//! #         *nu = [0.0, -t.sin()];
//! #     }
//! #     fn acceleration_rhs(&self, _q: &[f64; 2], qd: &[f64; 2], t: f64, g: &mut [f64; 2]) {
//! #         *g = [-2.0 * (qd[0] * qd[0] + qd[1] * qd[1]), -t.cos()];
//! #     }
//! # }
//! let mut solver = Solver::new(CircleLine, [1.2, 0.0]);
//! let error = solver.position(0.5).unwrap_err();
//! assert!(matches!(error, NewtonError::Singular { iteration: 0, column: 1, .. }));
//! // The estimate is kept, and there is no position to take velocities at.
//! assert_eq!(solver.q(), &[1.2, 0.0]);
//! assert!(solver.velocity().is_err());
//! ```

#![no_std]

pub mod blocks;
pub mod dynamic;
pub mod factors;
pub mod input;
pub mod lu;
pub mod math;
mod mechanism;
pub mod newton;
pub mod outputs;
mod real;
pub mod rotation;
pub mod rows;
mod solver;
pub mod step;

#[cfg(test)]
mod fixtures;

pub use mechanism::{MAX_TIME_TERMS, Mechanism};
pub use newton::{NewtonError, NewtonOptions, NewtonReport};
pub use outputs::{Outcome, Status};
pub use real::Real;
pub use solver::{AttemptError, InputsError, SolveError, Solver, StepReport};
