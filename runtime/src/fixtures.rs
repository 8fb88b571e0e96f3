//! Small hand-written mechanisms with closed-form answers, shared by the unit tests.

use core::cell::Cell;

use crate::Mechanism;

/// A point (x, y) on the unit circle whose x is driven as cos t:
/// Φ = (x² + y² − 1, x − cos t).
///
/// For 0 < t < π the upper solution is q = (cos t, sin t), q̇ = (−sin t, cos t),
/// q̈ = (−cos t, −sin t).
/// Φ_q = [[2x, 2y], [1, 0]] is singular on the x axis (y = 0), where the line touches the
/// circle.
/// With `project` set, [`Mechanism::normalize`] projects (x, y) radially onto the circle.
#[derive(Default)]
pub(crate) struct CircleLine {
    pub(crate) project: bool,
    /// Calls of `residual_jacobian`, `jacobian` and `normalize`, to check what each step costs.
    pub(crate) jacobians: Cell<u32>,
    pub(crate) normalizations: Cell<u32>,
}

impl CircleLine {
    /// The circle-line system whose `normalize` projects onto the circle.
    pub(crate) fn projected() -> Self {
        CircleLine { project: true, ..CircleLine::default() }
    }

    /// The upper solution (q, q̇, q̈) at time t.
    pub(crate) fn exact(t: f64) -> [[f64; 2]; 3] {
        let (s, c) = t.sin_cos();
        [[c, s], [-s, c], [-c, -s]]
    }
}

impl Mechanism<2> for CircleLine {
    fn residual(&self, q: &[f64; 2], t: f64, phi: &mut [f64; 2]) {
        let [x, y] = *q;
        *phi = [x * x + y * y - 1.0, x - t.cos()];
    }

    fn jacobian(&self, q: &[f64; 2], _t: f64, jac: &mut [[f64; 2]; 2]) {
        self.jacobians.set(self.jacobians.get() + 1);
        let [x, y] = *q;
        *jac = [[2.0 * x, 2.0 * y], [1.0, 0.0]];
    }

    fn velocity_rhs(&self, _q: &[f64; 2], t: f64, nu: &mut [f64; 2]) {
        *nu = [0.0, -t.sin()];
    }

    fn acceleration_rhs(&self, _q: &[f64; 2], qd: &[f64; 2], t: f64, gamma: &mut [f64; 2]) {
        let [xd, yd] = *qd;
        *gamma = [-2.0 * (xd * xd + yd * yd), -t.cos()];
    }

    fn normalize(&self, q: &mut [f64; 2]) {
        self.normalizations.set(self.normalizations.get() + 1);
        if self.project {
            let r = q[0].hypot(q[1]);
            q[0] /= r;
            q[1] /= r;
        }
    }
}

/// A mechanism without unknowns, as a description with only ground bodies would give.
pub(crate) struct Empty;

impl Mechanism<0> for Empty {
    fn residual(&self, _q: &[f64; 0], _t: f64, _phi: &mut [f64; 0]) {}
    fn jacobian(&self, _q: &[f64; 0], _t: f64, _jac: &mut [[f64; 0]; 0]) {}
    fn velocity_rhs(&self, _q: &[f64; 0], _t: f64, _nu: &mut [f64; 0]) {}
    fn acceleration_rhs(&self, _q: &[f64; 0], _qd: &[f64; 0], _t: f64, _gamma: &mut [f64; 0]) {}
}

/// [`CircleLine`] in single precision, without projection or counters.
pub(crate) struct CircleLineF32;

impl Mechanism<2, f32> for CircleLineF32 {
    fn residual(&self, q: &[f32; 2], t: f32, phi: &mut [f32; 2]) {
        let [x, y] = *q;
        *phi = [x * x + y * y - 1.0, x - crate::math::cos(t)];
    }

    fn jacobian(&self, q: &[f32; 2], _t: f32, jac: &mut [[f32; 2]; 2]) {
        let [x, y] = *q;
        *jac = [[2.0 * x, 2.0 * y], [1.0, 0.0]];
    }

    fn velocity_rhs(&self, _q: &[f32; 2], t: f32, nu: &mut [f32; 2]) {
        *nu = [0.0, -crate::math::sin(t)];
    }

    fn acceleration_rhs(&self, _q: &[f32; 2], qd: &[f32; 2], t: f32, gamma: &mut [f32; 2]) {
        let [xd, yd] = *qd;
        *gamma = [-2.0 * (xd * xd + yd * yd), -crate::math::cos(t)];
    }
}
