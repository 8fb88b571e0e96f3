//! Forward kinematics of the Stewart platform written the way a motion-control engineer writes
//! them, as the baseline the generated solver is measured against (issue 14, BENCHMARKS.md).
//!
//! The unknowns are the six pose parameters x = (p, φ, θ, ψ): the platform's position and its
//! ZYX angles ([`super::zyx`]). Newton solves l(x) = l_measured with the analytic Jacobian
//! ∂l/∂x = J T(x), where J is the leg lengths' Jacobian with respect to the twist (rows
//! [n_kᵀ, (r_k × n_k)ᵀ], module docs of [`super`]) and T = diag(I, E) maps the rates of x to
//! the twist. At the converged pose J is factored once; velocities are then the twist
//! [v; ω] = J⁻¹ l̇ and accelerations [a; α] = J⁻¹ (l̈ − c) with
//! c_k = n_k·(ω × (ω × r_k)) + (|ṡ_k|² − l̇_k²) / l_k, the terms of l̈_k that do not depend on
//! (a, α). Everything is a fixed-size nalgebra matrix on the stack: nothing allocates.
//!
//! Like `runtime::Solver` with its predictor on, [`ForwardKinematics::position`] starts Newton
//! from a Taylor prediction x + h ẋ + h²/2 ẍ when the last step solved velocities and
//! accelerations, else from the last pose.

use std::fmt;

use nalgebra::{Const, LU, Matrix3, Matrix6, Vector3, Vector6};

use super::{LEGS, base_point, platform_point, zyx};

/// Newton's defaults: the benchmarks' tolerance (max |l_k(x) − l_k| in m) and an iteration cap
/// that a converging step never reaches (it takes one to three iterations at 1 kHz).
const TOLERANCE: f64 = 1e-12;
/// The iteration cap.
const MAX_ITERATIONS: u32 = 25;

/// Why a call failed. The solver then keeps its last converged pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Error {
    /// A leg length, rate or acceleration was NaN or infinite.
    NotFinite,
    /// Newton did not reach the tolerance within the iteration cap.
    NoConvergence {
        /// Iterations taken.
        iterations: u32,
        /// max |l_k(x) − l_k| at the last iterate (m).
        residual: f64,
    },
    /// The Jacobian was singular: the platform is at (or Newton passed) a singular pose.
    Singular,
    /// Velocities need a converged position, accelerations a solved velocity.
    Order,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotFinite => write!(f, "a leg input is not finite"),
            Self::NoConvergence { iterations, residual } => {
                write!(f, "no convergence after {iterations} iterations (residual {residual:e} m)")
            }
            Self::Singular => write!(f, "singular Jacobian"),
            Self::Order => write!(f, "position, velocity and acceleration must be called in order"),
        }
    }
}

impl std::error::Error for Error {}

/// What a converged position step reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Report {
    /// Newton iterations (Jacobian factorisations) taken; 0 when the start met the tolerance.
    pub iterations: u32,
    /// max |l_k(x) − l_k| at the result (m).
    pub residual: f64,
}

/// How far a step has got: each call needs the one before it at the same pose.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Known {
    Nothing,
    Position,
    Velocity,
    Acceleration,
}

/// Newton on the six pose parameters with the analytic Jacobian of the leg lengths.
#[derive(Clone, Debug)]
pub struct ForwardKinematics {
    /// Base attachments a_k (global).
    base: [Vector3<f64>; LEGS],
    /// Platform attachments b_k (platform frame).
    platform: [Vector3<f64>; LEGS],
    /// Newton's tolerance on max |l_k(x) − l_k| (m).
    tolerance: f64,
    /// Time of the last converged pose.
    t: f64,
    /// Pose parameters (p, φ, θ, ψ) of the last converged pose.
    x: Vector6<f64>,
    /// Their rates and second derivatives, when solved at that pose.
    x_dot: Vector6<f64>,
    /// Second derivatives of the pose parameters.
    x_ddot: Vector6<f64>,
    /// R and E at the converged pose.
    rotation: Matrix3<f64>,
    /// The columns of E: the ZYX rotation axes (global).
    axes: Matrix3<f64>,
    /// r_k = R b_k, n_k and l_k at the converged pose.
    legs: [(Vector3<f64>, Vector3<f64>, f64); LEGS],
    /// The LU factors of J at the converged pose.
    factors: Option<LU<f64, Const<6>, Const<6>>>,
    /// l̇ given to the last velocity call.
    rates: Vector6<f64>,
    /// Twist (v, ω) and its derivative (a, α) solved at the converged pose.
    twist: Vector6<f64>,
    /// (a, α).
    twist_dot: Vector6<f64>,
    /// What has been solved at the converged pose.
    known: Known,
}

impl ForwardKinematics {
    /// A solver starting from the pose `position`, ZYX `angles` at time `t`, tolerance 1e-12 m.
    #[must_use]
    pub fn new(t: f64, position: Vector3<f64>, angles: Vector3<f64>) -> Self {
        let (rotation, axes) = zyx(&angles);
        Self {
            base: std::array::from_fn(base_point),
            platform: std::array::from_fn(platform_point),
            tolerance: TOLERANCE,
            t,
            x: Vector6::new(position.x, position.y, position.z, angles.x, angles.y, angles.z),
            x_dot: Vector6::zeros(),
            x_ddot: Vector6::zeros(),
            rotation,
            axes,
            legs: [(Vector3::zeros(), Vector3::zeros(), 0.0); LEGS],
            factors: None,
            rates: Vector6::zeros(),
            twist: Vector6::zeros(),
            twist_dot: Vector6::zeros(),
            known: Known::Nothing,
        }
    }

    /// Sets Newton's tolerance on max |l_k(x) − l_k| (m).
    pub const fn set_tolerance(&mut self, tolerance: f64) {
        self.tolerance = tolerance;
    }

    /// The platform's position p (m).
    #[must_use]
    pub fn platform_position(&self) -> Vector3<f64> {
        self.x.fixed_rows::<3>(0).into_owned()
    }

    /// The platform's orientation R at the converged pose.
    #[must_use]
    pub const fn rotation(&self) -> &Matrix3<f64> {
        &self.rotation
    }

    /// The twist (v, ω) solved by [`Self::velocity`] (m/s, rad/s).
    #[must_use]
    pub const fn twist(&self) -> &Vector6<f64> {
        &self.twist
    }

    /// (a, α) solved by [`Self::acceleration`] (m/s², rad/s²).
    #[must_use]
    pub const fn twist_dot(&self) -> &Vector6<f64> {
        &self.twist_dot
    }

    /// Solves the pose whose leg lengths are `lengths` (m) at time t by Newton, from the Taylor
    /// prediction when the last step solved velocities and accelerations, and factors J there.
    ///
    /// # Errors
    /// [`Error::NotFinite`], [`Error::Singular`] or [`Error::NoConvergence`]; the solver then
    /// keeps its last converged pose, and velocities need a new position.
    pub fn position(&mut self, t: f64, lengths: &[f64; LEGS]) -> Result<Report, Error> {
        let start = self.x;
        let known = self.known;
        self.known = Known::Nothing;
        if !t.is_finite() || lengths.iter().any(|l| !l.is_finite()) {
            return Err(Error::NotFinite);
        }
        if known == Known::Acceleration {
            let h = t - self.t;
            self.x += self.x_dot * h + self.x_ddot * (0.5 * h * h);
        }
        let target = Vector6::from_column_slice(lengths);
        for iterations in 0..=MAX_ITERATIONS {
            let (rotation, axes) = zyx(&self.x.fixed_rows::<3>(3).into_owned());
            let position = self.x.fixed_rows::<3>(0).into_owned();
            let mut jacobian = Matrix6::zeros();
            let mut error = Vector6::zeros();
            for k in 0..LEGS {
                let r = rotation * self.platform[k];
                let s = position + r - self.base[k];
                let l = s.norm();
                let n = s / l;
                error[k] = l - target[k];
                jacobian.fixed_view_mut::<1, 3>(k, 0).copy_from(&n.transpose());
                jacobian.fixed_view_mut::<1, 3>(k, 3).copy_from(&r.cross(&n).transpose());
                self.legs[k] = (r, n, l);
            }
            let residual = error.iter().fold(0.0, |m: f64, e| m.max(e.abs()));
            // NaN compares false: a NaN residual never counts as converged.
            if error.iter().all(|e| e.abs() <= self.tolerance) {
                let factors = jacobian.lu();
                if !factors.is_invertible() {
                    break;
                }
                (self.rotation, self.axes, self.factors) = (rotation, axes, Some(factors));
                (self.t, self.known) = (t, Known::Position);
                return Ok(Report { iterations, residual });
            }
            if iterations == MAX_ITERATIONS {
                self.x = start;
                return Err(Error::NoConvergence { iterations, residual });
            }
            // ∂l/∂x = J diag(I, E): the angular columns of J times E.
            let angular = jacobian.fixed_view::<6, 3>(0, 3) * axes;
            jacobian.fixed_view_mut::<6, 3>(0, 3).copy_from(&angular);
            match jacobian.lu().solve(&error) {
                Some(step) => self.x -= step,
                None => break,
            }
        }
        self.x = start;
        Err(Error::Singular)
    }

    /// Solves the twist [v; ω] = J⁻¹ l̇ for the leg rates `rates` (m/s) at the converged pose.
    ///
    /// # Errors
    /// [`Error::Order`] without a converged position, [`Error::NotFinite`] for a non-finite
    /// rate.
    pub fn velocity(&mut self, rates: &[f64; LEGS]) -> Result<&Vector6<f64>, Error> {
        let Some(factors) = self.factors.as_ref().filter(|_| self.known >= Known::Position) else {
            return Err(Error::Order);
        };
        if rates.iter().any(|r| !r.is_finite()) {
            return Err(Error::NotFinite);
        }
        self.rates = Vector6::from_column_slice(rates);
        self.twist = factors.solve(&self.rates).ok_or(Error::Singular)?;
        // ẋ = diag(I, E⁻¹) [v; ω], for the predictor.
        let omega = self.twist.fixed_rows::<3>(3).into_owned();
        let angle_rates = self.axes.lu().solve(&omega).ok_or(Error::Singular)?;
        self.x_dot.fixed_rows_mut::<3>(0).copy_from(&self.twist.fixed_rows::<3>(0));
        self.x_dot.fixed_rows_mut::<3>(3).copy_from(&angle_rates);
        self.known = Known::Velocity;
        Ok(&self.twist)
    }

    /// Solves [a; α] = J⁻¹ (l̈ − c) for the leg accelerations `accelerations` (m/s²) at the
    /// converged pose, with the twist of the last [`Self::velocity`].
    ///
    /// # Errors
    /// [`Error::Order`] without a solved velocity, [`Error::NotFinite`] for a non-finite input.
    pub fn acceleration(&mut self, accelerations: &[f64; LEGS]) -> Result<&Vector6<f64>, Error> {
        let Some(factors) = self.factors.as_ref().filter(|_| self.known >= Known::Velocity) else {
            return Err(Error::Order);
        };
        if accelerations.iter().any(|a| !a.is_finite()) {
            return Err(Error::NotFinite);
        }
        let v = self.twist.fixed_rows::<3>(0).into_owned();
        let omega = self.twist.fixed_rows::<3>(3).into_owned();
        let rhs = Vector6::from_fn(|k, _| {
            let (r, n, l) = self.legs[k];
            let s_dot = v + omega.cross(&r);
            let l_dot = self.rates[k];
            accelerations[k]
                - n.dot(&omega.cross(&omega.cross(&r)))
                - (s_dot.norm_squared() - l_dot * l_dot) / l
        });
        self.twist_dot = factors.solve(&rhs).ok_or(Error::Singular)?;
        // ẍ = diag(I, E⁻¹) ([a; α] − [0; Ė ẋ_angles]), Ė's columns u̇_x = (ψ̇ ẑ + θ̇ u_y) × u_x,
        // u̇_y = ψ̇ ẑ × u_y and u̇_z = 0.
        let (ux, uy) = (self.axes.column(0).into_owned(), self.axes.column(1).into_owned());
        let (roll, pitch, yaw) = (self.x_dot[3], self.x_dot[4], self.x_dot[5]);
        let yaw_axis = Vector3::z() * yaw;
        let axes_dot_rates =
            (yaw_axis + uy * pitch).cross(&ux) * roll + yaw_axis.cross(&uy) * pitch;
        let alpha = self.twist_dot.fixed_rows::<3>(3) - axes_dot_rates;
        let angle_accelerations = self.axes.lu().solve(&alpha).ok_or(Error::Singular)?;
        self.x_ddot.fixed_rows_mut::<3>(0).copy_from(&self.twist_dot.fixed_rows::<3>(0));
        self.x_ddot.fixed_rows_mut::<3>(3).copy_from(&angle_accelerations);
        self.known = Known::Acceleration;
        Ok(&self.twist_dot)
    }
}
