//! The trait that generated code implements.

/// A square kinematic system Φ(q, t) = 0 of `N` equations in `N` unknowns.
///
/// Generated code implements this trait, one struct per mechanism.
/// Every method writes into storage the caller owns, so nothing is allocated and no `N × N`
/// array is returned by value.
/// Methods do not check their inputs: a NaN or an infinity in `q`, `qd` or `t` may come out as
/// NaN in the output, and the solvers in this crate turn that into an error.
pub trait Mechanism<const N: usize> {
    /// Writes the constraint residuals Φ(q, t) into `phi`.
    fn residual(&self, q: &[f64; N], t: f64, phi: &mut [f64; N]);

    /// Writes the Jacobian Φ_q(q, t) into `jac`, row-major: `jac[i][j] = ∂Φ_i/∂q_j`.
    fn jacobian(&self, q: &[f64; N], t: f64, jac: &mut [[f64; N]; N]);

    /// Writes Φ(q, t) into `phi` and Φ_q(q, t) into `jac` in one pass.
    ///
    /// Generated code overrides this to share subexpressions between the two.
    /// The default calls [`Mechanism::residual`] and then [`Mechanism::jacobian`].
    fn residual_jacobian(&self, q: &[f64; N], t: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
        self.residual(q, t, phi);
        self.jacobian(q, t, jac);
    }

    /// Writes the velocity right-hand side ν = −Φ_t into `nu`.
    fn velocity_rhs(&self, q: &[f64; N], t: f64, nu: &mut [f64; N]);

    /// Writes the acceleration right-hand side γ = −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt into `gamma`.
    fn acceleration_rhs(&self, q: &[f64; N], qd: &[f64; N], t: f64, gamma: &mut [f64; N]);

    /// Projects `q` back onto the constraints that have a closed-form projection.
    ///
    /// Generated code renormalises Euler parameters here (p ← p / |p|).
    /// The solvers call it once Newton has converged and then evaluate Φ and Φ_q again, so the
    /// reported residual and the factored Jacobian belong to the projected `q`.
    /// The default does nothing.
    fn normalize(&self, _q: &mut [f64; N]) {}
}
