//! [`DynMechanism`]: the same equations as [`Mechanism`], sized at run time, on slices.
//!
//! Tests and tools use it to treat generated mechanisms ([`Fixed`]) and interpreted ones alike.
//! The solvers of this crate work on [`Mechanism`]; this trait is the uniform view, not a
//! second solving path.

#[cfg(test)]
mod tests;

use crate::Mechanism;

/// A square kinematic system of `n()` equations in `n()` unknowns, on slices.
///
/// The layouts are those of [`Mechanism`], with the Jacobian flattened row-major:
/// `jac[i * n + j] = ∂Φ_i/∂q_j`.
///
/// # Panics
///
/// Implementations may panic when a slice has the wrong length (`n`, or `n · n` for the
/// Jacobian); [`Fixed`] does.
pub trait DynMechanism {
    /// The number of unknowns, which is also the number of equations.
    fn n(&self) -> usize;

    /// Writes Φ(q, t) into `phi`.
    fn residual_into(&self, q: &[f64], t: f64, phi: &mut [f64]);

    /// Writes Φ_q(q, t) into `jac`, row-major: `jac[i * n + j] = ∂Φ_i/∂q_j`.
    fn jacobian_into(&self, q: &[f64], t: f64, jac: &mut [f64]);

    /// Writes ν = −Φ_t into `nu`.
    fn velocity_rhs_into(&self, q: &[f64], t: f64, nu: &mut [f64]);

    /// Writes γ = −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt into `gamma`.
    fn acceleration_rhs_into(&self, q: &[f64], qd: &[f64], t: f64, gamma: &mut [f64]);

    /// Projects `q` onto the constraints that have a closed-form projection (see
    /// [`Mechanism::normalize`]).
    fn normalize(&self, q: &mut [f64]);
}

/// Puts a fixed-size [`Mechanism<N>`] behind [`DynMechanism`].
///
/// A blanket `impl<M: Mechanism<N>, const N: usize> DynMechanism for M` does not compile
/// (E0207: `N` would be unconstrained), hence the wrapper.
///
/// ```
/// use runtime::dynamic::{DynMechanism, Fixed};
/// # use runtime::Mechanism;
/// # struct Line;
/// # impl Mechanism<1> for Line {
/// #     fn residual(&self, q: &[f64; 1], t: f64, phi: &mut [f64; 1]) { phi[0] = q[0] - t; }
/// #     fn jacobian(&self, _: &[f64; 1], _: f64, jac: &mut [[f64; 1]; 1]) { jac[0][0] = 1.0; }
/// #     fn velocity_rhs(&self, _: &[f64; 1], _: f64, nu: &mut [f64; 1]) { nu[0] = 1.0; }
/// #     fn acceleration_rhs(&self, _: &[f64; 1], _: &[f64; 1], _: f64, g: &mut [f64; 1]) {
/// #         g[0] = 0.0;
/// #     }
/// # }
/// let m: &dyn DynMechanism = &Fixed(Line);
/// let mut phi = [0.0];
/// m.residual_into(&[2.0], 0.5, &mut phi);
/// assert_eq!((m.n(), phi), (1, [1.5]));
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Fixed<M, const N: usize>(pub M);

/// The fixed-size view of a slice of length `N`.
fn array<const N: usize>(x: &[f64]) -> &[f64; N] {
    x.try_into().unwrap_or_else(|_| panic!("slice of length {} where {N} expected", x.len()))
}

/// The fixed-size view of a mutable slice of length `N`.
fn array_mut<const N: usize>(x: &mut [f64]) -> &mut [f64; N] {
    let len = x.len();
    x.try_into().unwrap_or_else(|_| panic!("slice of length {len} where {N} expected"))
}

impl<M: Mechanism<N>, const N: usize> DynMechanism for Fixed<M, N> {
    fn n(&self) -> usize {
        N
    }

    fn residual_into(&self, q: &[f64], t: f64, phi: &mut [f64]) {
        self.0.residual(array(q), t, array_mut(phi));
    }

    fn jacobian_into(&self, q: &[f64], t: f64, jac: &mut [f64]) {
        let len = jac.len();
        if N == 0 {
            // `as_chunks_mut` rejects chunks of length 0; an empty system has an empty Jacobian.
            assert!(len == 0, "Jacobian slice of length {len} where 0 expected");
            self.0.jacobian(array(q), t, &mut [[0.0; N]; N]);
            return;
        }
        let (rows, rest) = jac.as_chunks_mut::<N>();
        let rows: Option<&mut [[f64; N]; N]> =
            if rest.is_empty() { rows.try_into().ok() } else { None };
        let Some(rows) = rows else {
            panic!("Jacobian slice of length {len} where {N}·{N} expected");
        };
        self.0.jacobian(array(q), t, rows);
    }

    fn velocity_rhs_into(&self, q: &[f64], t: f64, nu: &mut [f64]) {
        self.0.velocity_rhs(array(q), t, array_mut(nu));
    }

    fn acceleration_rhs_into(&self, q: &[f64], qd: &[f64], t: f64, gamma: &mut [f64]) {
        self.0.acceleration_rhs(array(q), array(qd), t, array_mut(gamma));
    }

    fn normalize(&self, q: &mut [f64]) {
        self.0.normalize(array_mut(q));
    }
}
