//! The generated Stewart solver (`generated::stewart`) in a control loop: every period the six
//! leg lengths, with their rates and accelerations, go to [`Solver::advance_with`], and the
//! platform's pose, twist and its derivative are read from the solution through the module's
//! named unknowns and accessors. `examples/stewart_control_loop.rs` runs it at 1 kHz.

use generated::stewart::{self as gs, Inputs, Stewart};
use nalgebra::{Matrix3, Vector3};
use runtime::input::{Driven, Input};
use runtime::{AttemptError, InputsError, Mechanism, NewtonOptions, Solver};

use super::{LEGS, Motion, Trajectory, leg_lengths};

/// The generated solver of the platform.
pub type PlatformSolver = Solver<Stewart, { gs::N }>;

/// The inputs of the generated module for six `[l, l̇, l̈]`.
#[must_use]
pub fn inputs(legs: &[[f64; 3]; LEGS]) -> Inputs {
    let leg = |k: usize| Input { value: legs[k][0], rate: legs[k][1], acceleration: legs[k][2] };
    Inputs { leg1: leg(0), leg2: leg(1), leg3: leg(2), leg4: leg(3), leg5: leg(4), leg6: leg(5) }
}

/// A generated solver standing at the trajectory's pose at `t`, with the description's Newton
/// tolerance (1e-12) and its Taylor predictor on. The solver's first call solves from the
/// description's initial estimates (the home pose).
#[must_use]
pub fn solver(trajectory: &Trajectory, t: f64) -> PlatformSolver {
    let start = inputs(&leg_lengths(&trajectory.at(t)));
    let mut solver = Solver::new(Stewart::new(t, &start), gs::Q0);
    solver.set_options(NewtonOptions { tolerance: gs::TOLERANCE, ..NewtonOptions::DEFAULT });
    solver.set_predictor(true);
    solver
}

/// One step without the step control: the inputs `u` at `t` go to the mechanism, then plain
/// [`Solver::position`], [`Solver::velocity`] and [`Solver::acceleration`] calls, which trust
/// the caller's step (a step that is large for the motion may converge on another assembly
/// branch and still succeed). The benchmarks' lower bound on a period's cost; it serves the
/// whole module and the platform's alone ([`super::pose`]).
///
/// # Errors
/// The Newton or solve failure; the solver then stands where it was.
pub fn plain_step<M: Mechanism<N> + Driven<LEGS>, const N: usize>(
    solver: &mut Solver<M, N>,
    t: f64,
    u: &[[f64; 3]; LEGS],
) -> Result<(), AttemptError> {
    solver.mechanism_mut().segment_mut().aim(t, *u);
    let result = solver.position(t).map_err(AttemptError::Newton).and_then(|_| {
        solver.velocity().and_then(|()| solver.acceleration()).map_err(AttemptError::Solve)
    });
    let reached = solver.t();
    solver.mechanism_mut().segment_mut().settle(reached);
    result
}

/// The rotation matrix A(p) of Euler parameters p = [e0, e1, e2, e3] (thesis eq. 3.17):
/// A = (2 e0² − 1) I + 2 (e eᵀ + e0 ẽ).
#[must_use]
pub fn rotation(p: [f64; 4]) -> Matrix3<f64> {
    let [e0, e1, e2, e3] = p;
    let e = Vector3::new(e1, e2, e3);
    Matrix3::identity() * (2.0 * e0 * e0 - 1.0) + (e * e.transpose() + e.cross_matrix() * e0) * 2.0
}

/// The platform's motion in the solver's current solution: r, ṙ and r̈ are unknowns of the
/// module (`unknown::PLATFORM_X`, …), A(p) comes from its Euler parameters, ω and α from the
/// module's accessors.
#[must_use]
pub fn platform(solver: &PlatformSolver, t: f64, inputs: &Inputs) -> Motion {
    let (q, qd, qdd) = (solver.q(), solver.qd(), solver.qdd());
    let x = gs::unknown::PLATFORM_X;
    let three = |v: &[f64; gs::N]| Vector3::new(v[x], v[x + 1], v[x + 2]);
    let e0 = gs::unknown::PLATFORM_E0;
    let mut omega = [[0.0; 3]; gs::BODIES];
    let mut alpha = [[0.0; 3]; gs::BODIES];
    gs::angular_velocities(q, qd, t, inputs, &mut omega);
    gs::angular_accelerations(q, qd, qdd, t, inputs, &mut alpha);
    Motion {
        position: three(q),
        rotation: rotation([q[e0], q[e0 + 1], q[e0 + 2], q[e0 + 3]]),
        velocity: three(qd),
        angular_velocity: Vector3::from(omega[gs::body::PLATFORM]),
        acceleration: three(qdd),
        angular_acceleration: Vector3::from(alpha[gs::body::PLATFORM]),
    }
}

/// The largest differences between what a control loop recovered and the trajectory.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tracking {
    /// Periods run.
    pub periods: usize,
    /// Newton iterations over all periods (sub-steps included).
    pub iterations: u64,
    /// max |p − p_true| (m), entrywise.
    pub position: f64,
    /// max |R − R_true|, entrywise.
    pub rotation: f64,
    /// max |v − v_true| (m/s).
    pub velocity: f64,
    /// max |ω − ω_true| (rad/s).
    pub angular_velocity: f64,
    /// max |a − a_true| (m/s²).
    pub acceleration: f64,
    /// max |α − α_true| (rad/s²).
    pub angular_acceleration: f64,
}

impl Tracking {
    /// Takes the differences of one period into the maxima.
    fn add(&mut self, got: &Motion, want: &Motion) {
        let largest =
            |a: &[f64], b: &[f64]| a.iter().zip(b).fold(0.0, |m: f64, (x, y)| m.max((x - y).abs()));
        self.position =
            self.position.max(largest(got.position.as_slice(), want.position.as_slice()));
        self.rotation =
            self.rotation.max(largest(got.rotation.as_slice(), want.rotation.as_slice()));
        self.velocity =
            self.velocity.max(largest(got.velocity.as_slice(), want.velocity.as_slice()));
        self.angular_velocity = self
            .angular_velocity
            .max(largest(got.angular_velocity.as_slice(), want.angular_velocity.as_slice()));
        self.acceleration = self
            .acceleration
            .max(largest(got.acceleration.as_slice(), want.acceleration.as_slice()));
        self.angular_acceleration = self.angular_acceleration.max(largest(
            got.angular_acceleration.as_slice(),
            want.angular_acceleration.as_slice(),
        ));
    }
}

/// A control loop of `periods` periods of `dt` seconds on `solver` (made by [`solver`] at
/// t = 0): each period computes the leg lengths of `trajectory` by closed-form inverse
/// kinematics, as the machine's sensors would report them, solves the platform's forward
/// kinematics with [`Solver::advance_with`] and compares the recovered motion with the
/// trajectory. Nothing here allocates.
///
/// # Errors
/// The solver's error, as the machine's controller would get it: a non-finite leg input or a
/// stop of the step control (`branch_jump`, `singular`, `no_convergence`); boxed, as it is
/// large (about 250 bytes) and returned once, when the loop ends.
pub fn control_loop(
    solver: &mut PlatformSolver,
    trajectory: &Trajectory,
    periods: usize,
    dt: f64,
) -> Result<Tracking, Box<InputsError>> {
    let mut tracking = Tracking::default();
    for k in 0..periods {
        let t = k as f64 * dt;
        let want = trajectory.at(t);
        let u = inputs(&leg_lengths(&want));
        let report = solver.advance_with(t, &u.to_array()).map_err(Box::new)?;
        tracking.add(&platform(solver, t, &u), &want);
        tracking.iterations += u64::from(report.iterations);
        tracking.periods += 1;
    }
    Ok(tracking)
}
