//! Kinematic primitives of one constraint row: vectors and scalars carried together with
//! their Jacobian blocks and time derivatives.
//!
//! Every joint couples at most two bodies, called slot 0 (body i) and slot 1 (body j). A
//! quantity u(q, t) is carried as its value, its Jacobian blocks ∂u/∂q_i and ∂u/∂q_j (one
//! 7-column block per slot, columns `[x, y, z, e0, e1, e2, e3]`), its partial time derivative
//! ∂u/∂t, its total first derivative u̇ = u_q q̇ + u_t, and its total second derivative with
//! q̈ = 0, written ü*. A constraint row Φ then yields Φ, Φ_q, ν = −Φ_t and γ = −Φ̈* directly
//! (thesis eq. 4.5–4.8: Φ_q q̇ = −Φ_t, Φ_q q̈ = −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt).
//!
//! The vector rules are the thesis' (ch. 3, eq. 3.24–3.37; ch. 4, eq. 4.9–4.13):
//! for a body-fixed vector a = A(p) a', ∂a/∂p = B(p, a') (= 2 G(p) ā'), ȧ = B(p, a') ṗ and
//! ä* = B(ṗ, a') ṗ = 2 A(ṗ) a' (the κ term of every γ), because A(p) a' is a homogeneous
//! quadratic form in p. Products follow Leibniz's rule: (u·v)˙˙* = ü*·v + 2 u̇·v̇ + u·v̈*
//! (eq. 4.19), and likewise for the cross product (eq. 4.25).

use nalgebra::{Matrix3, SMatrix, Vector3, Vector4};

use crate::model::frame::{rotation, skew};

/// A 3×7 Jacobian block: rows x, y, z; columns r then p of one body.
pub(crate) type Block3 = SMatrix<f64, 3, 7>;
/// A 1×7 Jacobian block.
pub(crate) type Block1 = SMatrix<f64, 1, 7>;

/// B(p, a') = ∂(A(p) a')/∂p, 3×4: `[2(e0 a' + e × a'), 2((e·a') I + e a'ᵀ − a' eᵀ − e0 ã')]`,
/// equal to 2 G(p) ā' (thesis eq. 3.37 and Table 4.1).
pub(crate) fn b_matrix(p: &Vector4<f64>, a: &Vector3<f64>) -> SMatrix<f64, 3, 4> {
    let e0 = p[0];
    let e = Vector3::new(p[1], p[2], p[3]);
    let col0 = (a * e0 + e.cross(a)) * 2.0;
    let rest =
        (Matrix3::identity() * e.dot(a) + e * a.transpose() - a * e.transpose() - skew(a) * e0)
            * 2.0;
    let mut b = SMatrix::<f64, 3, 4>::zeros();
    b.set_column(0, &col0);
    b.fixed_view_mut::<3, 3>(0, 1).copy_from(&rest);
    b
}

/// The state of one body at one evaluation: coordinates, rates and the matrices every
/// row of that body reuses.
#[derive(Clone, Debug)]
pub(crate) struct BodyState {
    /// Origin, global.
    pub r: Vector3<f64>,
    /// Euler parameters.
    pub p: Vector4<f64>,
    /// ṙ.
    pub rd: Vector3<f64>,
    /// ṗ.
    pub pd: Vector4<f64>,
    /// A(p).
    pub a: Matrix3<f64>,
    /// A(ṗ), the quadratic form at ṗ: ä* = 2 A(ṗ) a'.
    pub a_of_pd: Matrix3<f64>,
}

impl BodyState {
    /// The state of a body with coordinates `q = [r, p]` and rates `qd`.
    pub(crate) fn new(q: &[f64], qd: &[f64]) -> Self {
        let r = Vector3::new(q[0], q[1], q[2]);
        let p = Vector4::new(q[3], q[4], q[5], q[6]);
        let rd = Vector3::new(qd[0], qd[1], qd[2]);
        let pd = Vector4::new(qd[3], qd[4], qd[5], qd[6]);
        Self { r, p, rd, pd, a: rotation(&p), a_of_pd: rotation(&pd) }
    }
}

/// A vector quantity of a row (see the module docs).
#[derive(Clone, Debug)]
pub(crate) struct Vk {
    pub v: Vector3<f64>,
    pub jac: [Block3; 2],
    pub d1: Vector3<f64>,
    pub d2: Vector3<f64>,
}

impl Vk {
    /// The body-fixed vector A a' of the body in `slot`.
    pub(crate) fn vector(slot: usize, b: &BodyState, local: &Vector3<f64>) -> Self {
        let bm = b_matrix(&b.p, local);
        let mut jac = [Block3::zeros(); 2];
        jac[slot].fixed_view_mut::<3, 4>(0, 3).copy_from(&bm);
        Self { v: b.a * local, jac, d1: bm * b.pd, d2: b.a_of_pd * local * 2.0 }
    }

    /// The global position r + A s' of a body-fixed point (thesis eq. 4.9).
    pub(crate) fn point(slot: usize, b: &BodyState, local: &Vector3<f64>) -> Self {
        let mut k = Self::vector(slot, b, local);
        k.v += b.r;
        k.d1 += b.rd;
        k.jac[slot].fixed_view_mut::<3, 3>(0, 0).copy_from(&Matrix3::identity());
        k
    }

    /// u − w.
    pub(crate) fn sub(&self, w: &Self) -> Self {
        Self {
            v: self.v - w.v,
            jac: [self.jac[0] - w.jac[0], self.jac[1] - w.jac[1]],
            d1: self.d1 - w.d1,
            d2: self.d2 - w.d2,
        }
    }

    /// u × w, with (u × w)¨* = ü* × w + 2 u̇ × ẇ + u × ẅ*.
    pub(crate) fn cross(&self, w: &Self) -> Self {
        let (su, sw) = (skew(&self.v), skew(&w.v));
        Self {
            v: self.v.cross(&w.v),
            jac: [su * w.jac[0] - sw * self.jac[0], su * w.jac[1] - sw * self.jac[1]],
            d1: self.d1.cross(&w.v) + self.v.cross(&w.d1),
            d2: self.d2.cross(&w.v) + self.d1.cross(&w.d1) * 2.0 + self.v.cross(&w.d2),
        }
    }

    /// u · w, with (u·w)¨* = ü*·w + 2 u̇·ẇ + u·ẅ* (thesis eq. 4.19).
    pub(crate) fn dot(&self, w: &Self) -> Sk {
        Sk {
            v: self.v.dot(&w.v),
            jac: [
                w.v.transpose() * self.jac[0] + self.v.transpose() * w.jac[0],
                w.v.transpose() * self.jac[1] + self.v.transpose() * w.jac[1],
            ],
            t: 0.0,
            d1: self.d1.dot(&w.v) + self.v.dot(&w.d1),
            d2: self.d2.dot(&w.v) + 2.0 * self.d1.dot(&w.d1) + self.v.dot(&w.d2),
        }
    }

    /// Component `k` as a scalar.
    pub(crate) fn component(&self, k: usize) -> Sk {
        Sk {
            v: self.v[k],
            jac: [self.jac[0].fixed_rows::<1>(k).into(), self.jac[1].fixed_rows::<1>(k).into()],
            t: 0.0,
            d1: self.d1[k],
            d2: self.d2[k],
        }
    }
}

/// A scalar quantity of a row (see the module docs); `t` is ∂/∂t.
#[derive(Clone, Debug)]
pub(crate) struct Sk {
    pub v: f64,
    pub jac: [Block1; 2],
    pub t: f64,
    pub d1: f64,
    pub d2: f64,
}

impl Sk {
    /// A constant.
    pub(crate) fn constant(v: f64) -> Self {
        Self { v, jac: [Block1::zeros(); 2], t: 0.0, d1: 0.0, d2: 0.0 }
    }

    /// A law s(t) with its derivatives `(s, ṡ, s̈)`: a function of time only.
    pub(crate) fn time(s: (f64, f64, f64)) -> Self {
        Self { v: s.0, jac: [Block1::zeros(); 2], t: s.1, d1: s.1, d2: s.2 }
    }

    /// Coordinate `index` (0–6 in `[x, y, z, e0, e1, e2, e3]`) of the body in `slot`.
    pub(crate) fn coordinate(slot: usize, b: &BodyState, index: usize) -> Self {
        let (v, d1) =
            if index < 3 { (b.r[index], b.rd[index]) } else { (b.p[index - 3], b.pd[index - 3]) };
        let mut jac = [Block1::zeros(); 2];
        jac[slot][index] = 1.0;
        Self { v, jac, t: 0.0, d1, d2: 0.0 }
    }

    /// a + b.
    pub(crate) fn add(&self, b: &Self) -> Self {
        Self {
            v: self.v + b.v,
            jac: [self.jac[0] + b.jac[0], self.jac[1] + b.jac[1]],
            t: self.t + b.t,
            d1: self.d1 + b.d1,
            d2: self.d2 + b.d2,
        }
    }

    /// a − b.
    pub(crate) fn sub(&self, b: &Self) -> Self {
        self.add(&b.scale(-1.0))
    }

    /// c·a for a constant c.
    pub(crate) fn scale(&self, c: f64) -> Self {
        Self {
            v: c * self.v,
            jac: [self.jac[0] * c, self.jac[1] * c],
            t: c * self.t,
            d1: c * self.d1,
            d2: c * self.d2,
        }
    }

    /// a·b, with (ab)¨* = ä* b + 2 ȧ ḃ + a b̈*.
    pub(crate) fn mul(&self, b: &Self) -> Self {
        Self {
            v: self.v * b.v,
            jac: [self.jac[0] * b.v + b.jac[0] * self.v, self.jac[1] * b.v + b.jac[1] * self.v],
            t: self.t * b.v + self.v * b.t,
            d1: self.d1 * b.v + self.v * b.d1,
            d2: self.d2 * b.v + 2.0 * self.d1 * b.d1 + self.v * b.d2,
        }
    }

    /// sin a and cos a, with (sin a)¨* = cos a · ä* − sin a · ȧ².
    pub(crate) fn sin_cos(&self) -> (Self, Self) {
        let (s, c) = self.v.sin_cos();
        let sin = Self {
            v: s,
            jac: [self.jac[0] * c, self.jac[1] * c],
            t: c * self.t,
            d1: c * self.d1,
            d2: c * self.d2 - s * self.d1 * self.d1,
        };
        let cos = Self {
            v: c,
            jac: [self.jac[0] * -s, self.jac[1] * -s],
            t: -s * self.t,
            d1: -s * self.d1,
            d2: -s * self.d2 - c * self.d1 * self.d1,
        };
        (sin, cos)
    }
}
